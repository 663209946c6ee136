/* test_render_output.c: output files that are safe as root, and bounded input.
 *
 * Oracles: the documented rules of render/base/output.h: a regular file is replaced whole (its
 * new bytes are exactly what was written, its inode changes), a FIFO and a character device
 * are written through and stay what they were (same type, same device number), a symbolic
 * link stays a link and its target gets the bytes, a dangling link, a directory are refused
 * and nothing appears; SIGINT/SIGTERM leave the old outputs and no temporaries. The render
 * program is run as a user would (signals at each phase through the documented test-only
 * PM_RENDER_TEST_PAUSE hook), and bad input (/dev/zero as a scene, a PFM header bigger than
 * its file, a photon-map directory that cannot be made or holds a FIFO where a map goes) must
 * give exit status 2 with a message, quickly, before any photon is traced. Every output path is inside
 * pm_test_tmpdir(); device nodes are made there with mknod, never under /dev.
 */
#define _XOPEN_SOURCE 700 /* mknod, S_IFCHR */
#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "test.h"
#include "../photonmap/common.h"
#include "../render/image/film.h"
#include "../render/base/output.h"
#include "test_render_run.h"

static int write_text(const char *path, const char *text) {
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    fputs(text, f);
    return fclose(f);
}

/* Write text to path through output.h as one output. */
static int out_write_text(const char *path, const char *text, char *err, size_t cap) {
    out_file o;
    int rc = out_open(&o, path, err, cap);
    if (rc < 0) return rc;
    fputs(text, o.fp);
    out_file *l[1] = {&o};
    return out_commit(l, 1, err, cap);
}

/* Oracle: a regular file is replaced by exactly the new bytes (a new inode: it was renamed
 * into place, not rewritten), a new path is created, and no temporary remains. */
TEST(render_output_regular_and_new) {
    const char *p = rt_path("reg.txt"), *q = rt_path("new.txt");
    ASSERT(write_text(p, "old contents") == 0);
    struct stat a, b;
    ASSERT(stat(p, &a) == 0);
    char err[512];
    ASSERT_MSG(out_write_text(p, "new", err, sizeof err) == 0, "%s", err);
    ASSERT_MSG(out_write_text(q, "fresh", err, sizeof err) == 0, "%s", err);
    ASSERT(stat(p, &b) == 0);
    EXPECT(S_ISREG(b.st_mode));
    EXPECT(a.st_ino != b.st_ino);
    char *s = rt_slurp(p, NULL), *t = rt_slurp(q, NULL);
    EXPECT(s && strcmp(s, "new") == 0);
    EXPECT(t && strcmp(t, "fresh") == 0);
    free(s);
    free(t);
    EXPECT_EQ_INT(rt_count_temps(), 0);
}

/* Oracle: the FIFO is still a FIFO afterwards and a reader got exactly the bytes written. */
TEST(render_output_fifo_written_through) {
    const char *fifo = rt_path("fifo"), *got = rt_path("fifo.got");
    ASSERT(mkfifo(fifo, 0600) == 0);
    pid_t pid = fork();
    ASSERT(pid >= 0);
    if (pid == 0) { /* the reader */
        FILE *in = fopen(fifo, "rb"), *out = fopen(got, "wb");
        int c;
        while (in && out && (c = fgetc(in)) != EOF) fputc(c, out);
        _exit(in && out && fclose(out) == 0 ? 0 : 1);
    }
    char err[512];
    int rc = out_write_text(fifo, "through the pipe", err, sizeof err);
    int status;
    waitpid(pid, &status, 0);
    ASSERT_MSG(rc == 0, "%s", err);
    EXPECT(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    struct stat st;
    ASSERT(lstat(fifo, &st) == 0);
    EXPECT(S_ISFIFO(st.st_mode));
    char *s = rt_slurp(got, NULL);
    EXPECT(s && strcmp(s, "through the pipe") == 0);
    free(s);
    EXPECT_EQ_INT(rt_count_temps(), 0);
}

/* Oracle: a character device (a null device made here with mknod c 1 3) keeps its type and
 * device number after being used as an output; the write succeeds (the device discards). */
TEST(render_output_chardev_survives) {
    const char *dev = rt_path("null");
    if (mknod(dev, S_IFCHR | 0666, makedev(1, 3)) != 0) {
        char why[256];
        snprintf(why, sizeof why, "mknod of a character device not permitted here (%s)", strerror(errno));
        SKIP(why);
    }
    char err[512];
    EXPECT_MSG(out_check(dev, err, sizeof err) == 0, "%s", err);
    EXPECT_MSG(out_write_text(dev, "discarded", err, sizeof err) == 0, "%s", err);
    struct stat st;
    ASSERT(lstat(dev, &st) == 0);
    EXPECT(S_ISCHR(st.st_mode));
    EXPECT(major(st.st_rdev) == 1 && minor(st.st_rdev) == 3);
    EXPECT_EQ_INT(rt_count_temps(), 0);
}

/* Oracle: the link stays a link to the same name; the target gets the new bytes; a link to a
 * missing file, and a directory, are refused with a message and nothing is created. */
TEST(render_output_symlink_and_refusals) {
    const char *target = rt_path("target.txt"), *link = rt_path("link.txt");
    ASSERT(write_text(target, "old") == 0);
    ASSERT(symlink("target.txt", link) == 0);
    char err[512];
    ASSERT_MSG(out_write_text(link, "via link", err, sizeof err) == 0, "%s", err);
    struct stat st;
    ASSERT(lstat(link, &st) == 0);
    EXPECT(S_ISLNK(st.st_mode));
    char lt[256];
    ssize_t n = readlink(link, lt, sizeof lt - 1);
    EXPECT(n == 10 && memcmp(lt, "target.txt", 10) == 0);
    char *s = rt_slurp(target, NULL);
    EXPECT(s && strcmp(s, "via link") == 0);
    free(s);

    const char *dangling = rt_path("dangling");
    ASSERT(symlink("nowhere/missing.png", dangling) == 0);
    err[0] = 0;
    EXPECT(out_write_text(dangling, "x", err, sizeof err) == PM_EIO);
    EXPECT_MSG(strstr(err, "symbolic link"), "message: %s", err);
    EXPECT(out_check(dangling, err, sizeof err) == PM_EIO);
    EXPECT(access(rt_path("nowhere"), F_OK) != 0);
    err[0] = 0;
    EXPECT(out_write_text(pm_test_tmpdir(), "x", err, sizeof err) == PM_EIO);
    EXPECT_MSG(strstr(err, "Is a directory"), "message: %s", err);
    EXPECT(out_check_dir(rt_path("target.txt"), err, sizeof err) == PM_EIO);
    EXPECT(out_check_dir(rt_path("no/such/dir"), err, sizeof err) == PM_EIO);
    EXPECT(out_check_dir(rt_path("newdir"), err, sizeof err) == 0);
    EXPECT(access(rt_path("newdir"), F_OK) != 0);
    EXPECT_EQ_INT(rt_count_temps(), 0);
}

/* Oracle: a process that has two complete temporaries but is stopped by SIGINT or SIGTERM
 * before its commit ends by that signal, leaves both old files byte for byte and no
 * temporary; the same process without the signal replaces both. */
TEST(render_output_signal_removes_temporaries) {
    int sigs[2] = {SIGINT, SIGTERM};
    for (int k = 0; k < 3; k++) {
        const char *a = rt_path("sig_a"), *b = rt_path("sig_b");
        ASSERT(write_text(a, "old a") == 0 && write_text(b, "old b") == 0);
        pid_t pid = fork();
        ASSERT(pid >= 0);
        if (pid == 0) {
            out_signals_install();
            char err[512];
            out_file oa, ob;
            if (out_open(&oa, a, err, sizeof err) < 0 || out_open(&ob, b, err, sizeof err) < 0) _exit(3);
            fputs("new a", oa.fp);
            fputs("new b", ob.fp);
            fflush(NULL);
            if (k < 2) raise(sigs[k]);
            out_file *l[2] = {&oa, &ob};
            _exit(out_commit(l, 2, err, sizeof err) == 0 ? 0 : 4);
        }
        int status;
        waitpid(pid, &status, 0);
        char *sa = rt_slurp(a, NULL), *sb = rt_slurp(b, NULL);
        if (k < 2) {
            EXPECT_MSG(WIFSIGNALED(status) && WTERMSIG(status) == sigs[k], "status %d", status);
            EXPECT(sa && strcmp(sa, "old a") == 0 && sb && strcmp(sb, "old b") == 0);
        } else {
            EXPECT(WIFEXITED(status) && WEXITSTATUS(status) == 0);
            EXPECT(sa && strcmp(sa, "new a") == 0 && sb && strcmp(sb, "new b") == 0);
        }
        free(sa);
        free(sb);
        EXPECT_EQ_INT(rt_count_temps(), 0);
    }
}

/* Oracle: a PFM whose header promises more pixels than the file holds is refused
 * (PM_EFORMAT) before any allocation: a 65536 x 65536 header would need 48 GiB, and the
 * read returns at once; a 1-pixel-short file is refused too, and the exact file reads. */
TEST(render_output_pfm_header_bounded) {
    const char *p = rt_path("huge.pfm");
    ASSERT(write_text(p, "PF\n65536 65536\n-1.0\nabcdabcdabcd") == 0);
    film f;
    EXPECT_EQ_INT(film_read_pfm(&f, p), PM_EFORMAT);
    film g;
    ASSERT(film_init(&g, 3, 2) == 0);
    for (int i = 0; i < 18; i++) g.px[i] = (float)i * 0.25f;
    const char *q = rt_path("small.pfm");
    ASSERT(film_write_pfm(&g, q) == 0);
    size_t n;
    char *bytes = rt_slurp(q, &n);
    ASSERT(bytes);
    FILE *t = fopen(rt_path("short.pfm"), "wb");
    ASSERT(t);
    fwrite(bytes, 1, n - 1, t);
    fclose(t);
    free(bytes);
    EXPECT_EQ_INT(film_read_pfm(&f, rt_path("short.pfm")), PM_EFORMAT);
    ASSERT(film_read_pfm(&f, q) == 0);
    EXPECT(f.width == 3 && f.height == 2 && memcmp(f.px, g.px, 18 * sizeof(float)) == 0);
    film_free(&f);
    film_free(&g);
}

/* ---- the render program ------------------------------------------------------------------- */

#define SCENE_ARGS "'%s/data/scenes/cornell_box.json' --width 32 --height 32 --threads 2 --quiet"
#define PM_ARGS                                                                              \
    "'%s/data/scenes/cornell_spheres.json' --mode pm --pm global_photons=8000 --pm "        \
    "caustic_photons=8000 --width 32 --height 32 --threads 2 --quiet"

/* Oracle: the bytes of the same render written to a regular file. A FIFO (read by cat in the
 * background) receives exactly those bytes and stays a FIFO; through a symlink, the target
 * gets those bytes and the link stays a link. (A character device: the next test.) */
TEST(render_output_cli_special_paths) {
    const char *dir = pm_test_tmpdir();
    char out[16384], args[4096];
    ASSERT_MSG(rt_render(SCENE_ARGS, "--spp 4 -o ref.png --hdr ref.pfm", out, sizeof out) == 0, "%s", out);
    ASSERT(mkfifo(rt_path("fifo.png"), 0600) == 0);
    /* the reader in the same directory; timeout: a missed reader must not hang the suite */
    snprintf(args, sizeof args,
             "--spp 4 -o fifo.png --hdr x.pfm & (cd '%s' && timeout 20 cat fifo.png > fifo.got); wait $!",
             dir);
    EXPECT_MSG(rt_render(SCENE_ARGS, args, out, sizeof out) == 0, "%s", out);
    struct stat st;
    ASSERT(lstat(rt_path("fifo.png"), &st) == 0);
    EXPECT(S_ISFIFO(st.st_mode));
    EXPECT(rt_same_file(rt_path("fifo.got"), rt_path("ref.png")));
    EXPECT(rt_same_file(rt_path("x.pfm"), rt_path("ref.pfm")));


    ASSERT(write_text(rt_path("real.png"), "old") == 0);
    ASSERT(symlink("real.png", rt_path("link.png")) == 0);
    EXPECT_MSG(rt_render(SCENE_ARGS, "--spp 4 -o link.png", out, sizeof out) == 0, "%s", out);
    ASSERT(lstat(rt_path("link.png"), &st) == 0);
    EXPECT(S_ISLNK(st.st_mode));
    EXPECT(rt_same_file(rt_path("real.png"), rt_path("ref.png")));
    /* a dangling link is refused before rendering, with a message, and stays dangling */
    ASSERT(symlink("missing/x.png", rt_path("dangling.png")) == 0);
    EXPECT(rt_render(SCENE_ARGS, "--spp 4 -o dangling.png", out, sizeof out) == 2);
    EXPECT_MSG(strstr(out, "symbolic link"), "%s", out);
    EXPECT(lstat(rt_path("dangling.png"), &st) == 0 && S_ISLNK(st.st_mode));
    EXPECT_EQ_INT(rt_count_temps(), 0);
}

/* Oracle: the device's own identity. A character device made with mknod (c 1 3, a null
 * device) given as --hdr is written through: the render succeeds and the path is still that
 * character device, with the same device number, and no temporary is left. */
TEST(render_output_cli_chardev_output) {
    char out[16384];
    struct stat st;
    if (mknod(rt_path("dev.pfm"), S_IFCHR | 0666, makedev(1, 3)) != 0) {
        char why[256];
        snprintf(why, sizeof why, "mknod of a character device not permitted here (%s)", strerror(errno));
        SKIP(why);
    }
    EXPECT_MSG(rt_render(SCENE_ARGS, "--spp 4 --hdr dev.pfm", out, sizeof out) == 0, "%s", out);
    ASSERT(lstat(rt_path("dev.pfm"), &st) == 0);
    EXPECT(S_ISCHR(st.st_mode) && major(st.st_rdev) == 1 && minor(st.st_rdev) == 3);
    EXPECT_EQ_INT(rt_count_temps(), 0);
}

/* Oracle: "all old or all new". Old outputs come from seed 1; a run with seed 2 is stopped by
 * SIGINT at each phase (before the photon pass, in the middle of rendering, after the PFM
 * temporary, after the PNG temporary) and must end by SIGINT (status 130) leaving the old
 * bytes and no temporary; the same run without a signal leaves exactly the bytes of an
 * undisturbed seed-2 render. SIGTERM at the PNG phase too. The photon phase runs in pm mode,
 * the others in path mode. */
TEST(render_output_cli_signal_phases) {
    const char *dir = pm_test_tmpdir();
    char out[16384];
    const char *a1 = "--seed 1 --spp 4 -o old.png --hdr old.pfm";
    const char *a2 = "--seed 2 --spp 4 -o new.png --hdr new.pfm";
    ASSERT_MSG(rt_render(PM_ARGS, a1, out, sizeof out) == 0, "%s", out);
    ASSERT_MSG(rt_render(PM_ARGS, a2, out, sizeof out) == 0, "%s", out);
    /* the photon pass only exists in pm mode; the other phases are the same in path mode,
     * which is faster (sanitizer builds) */
    ASSERT(rt_render(SCENE_ARGS, "--seed 1 --spp 4 -o pold.png --hdr pold.pfm", out, sizeof out) == 0);
    ASSERT(rt_render(SCENE_ARGS, "--seed 2 --spp 4 -o pnew.png --hdr pnew.pfm", out, sizeof out) == 0);
    static const struct {
        const char *phase, *sig;
        int status;
    } cases[] = {{"photons", "INT", 130}, {"render:0.5", "INT", 130}, {"pfm", "INT", 130},
                 {"png", "INT", 130}, {"png", "TERM", 143}};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        ASSERT(system("true") == 0);
        char cmd[4096];
        int pm = k == 0;
        const char *oldp = pm ? "old" : "pold";
        snprintf(cmd, sizeof cmd, "cd '%s' && cp %s.png o.png && cp %s.pfm o.pfm", dir, oldp, oldp);
        ASSERT(pm_test_run(cmd, out, sizeof out) == 0);
        int rc = rt_render_paused(cases[k].phase, cases[k].sig, pm ? PM_ARGS : SCENE_ARGS,
                                  "--seed 2 --spp 4 -o o.png --hdr o.pfm", "", out, sizeof out);
        EXPECT_MSG(rc == cases[k].status, "%s/%s: status %d: %s", cases[k].phase, cases[k].sig, rc, out);
        char op[64], of[64];
        snprintf(op, sizeof op, "%s.png", oldp);
        snprintf(of, sizeof of, "%s.pfm", oldp);
        EXPECT_MSG(rt_same_file(rt_path("o.png"), rt_path(op)) && rt_same_file(rt_path("o.pfm"), rt_path(of)),
                   "%s: the old outputs changed", cases[k].phase);
        EXPECT_MSG(rt_count_temps() == 0, "%s: temporaries left", cases[k].phase);
    }
    ASSERT(rt_render(PM_ARGS, "--seed 2 --spp 4 -o o.png --hdr o.pfm", out, sizeof out) == 0);
    EXPECT(rt_same_file(rt_path("o.png"), rt_path("new.png")) && rt_same_file(rt_path("o.pfm"), rt_path("new.pfm")));
    ASSERT(rt_render(SCENE_ARGS, "--seed 2 --spp 4 -o o.png --hdr o.pfm", out, sizeof out) == 0);
    EXPECT(rt_same_file(rt_path("o.png"), rt_path("pnew.png")) && rt_same_file(rt_path("o.pfm"), rt_path("pnew.pfm")));
    EXPECT_EQ_INT(rt_count_temps(), 0);
}

/* Oracle: status 2 and a message naming the problem, within 5 s (a read to the end of
 * /dev/zero or a 48 GiB allocation would not finish): /dev/zero as the scene (input only),
 * a scene over --max-scene-mb, a PFM whose header is bigger than the file, a photon-map
 * directory that cannot be created (refused before any photon is traced). */
TEST(render_output_cli_bad_input) {
    const char *dir = pm_test_tmpdir();
    char out[16384], cmd[4096];
    FILE *f = fopen(rt_path("big.json"), "wb");
    ASSERT(f);
    for (int i = 0; i < (3 << 20) / 64; i++) fputs("                                                               \n", f);
    fputs("{}", f);
    fclose(f);
    ASSERT(write_text(rt_path("huge.pfm"), "PF\n65536 65536\n-1.0\n0123456789ab") == 0);
    static const struct {
        const char *args, *expect;
    } cases[] = {
        {"/dev/zero -o a.png", "NUL byte"},
        {"big.json --max-scene-mb 2 -o a.png", "larger than the limit of 2 MiB"},
        {"--tonemap huge.pfm a.png", "huge.pfm"},
        {"'%s/data/scenes/cornell_spheres.json' --mode pm --save-photons no/such/dir -o a.png",
         "cannot be created"},
        {"'%s/data/scenes/cornell_spheres.json' --mode pm --save-photons maps -o a.png",
         "maps/caustic.pmap is not a regular file"},
    };
    ASSERT(mkdir(rt_path("maps"), 0755) == 0 && mkfifo(rt_path("maps/caustic.pmap"), 0600) == 0);
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        char args[2048];
        snprintf(args, sizeof args, cases[k].args, pm_test_source_dir());
        snprintf(cmd, sizeof cmd, "cd '%s' && timeout 5 '%s/render' %s", dir, pm_test_build_dir(), args);
        int rc = pm_test_run(cmd, out, sizeof out);
        EXPECT_MSG(rc == 2, "%s: status %d: %s", args, rc, out);
        EXPECT_MSG(strstr(out, cases[k].expect), "%s: expected \"%s\" in: %s", args, cases[k].expect, out);
        EXPECT_MSG(!strstr(out, "Photons:"), "%s: traced photons before failing", args);
        EXPECT(access(rt_path("a.png"), F_OK) != 0);
    }
    struct stat st;
    EXPECT(lstat(rt_path("maps/caustic.pmap"), &st) == 0 && S_ISFIFO(st.st_mode));
    /* the limit can be raised: the same big file is read (and is an empty scene) */
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' big.json --max-scene-mb 4 -o a.png", dir,
             pm_test_build_dir());
    pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(!strstr(out, "larger than the limit"), "%s", out);
}

/* Oracle: the old file's own bytes. An EXR output (--hdr o.exr) goes through the same
 * whole-or-nothing path as PFM and PNG: interrupted (SIGINT) after the EXR is written to its
 * temporary and before the commit, the old o.exr is left byte-identical and no temporary
 * remains; a run that completes replaces it with the new render's file. */
TEST(render_output_exr_whole_or_not_at_all) {
    const char *dir = pm_test_tmpdir();
    char out[16384], cmd[4096];
    ASSERT_MSG(rt_render(SCENE_ARGS, "--seed 1 --spp 4 --hdr old.exr", out, sizeof out) == 0, "%s", out);
    ASSERT_MSG(rt_render(SCENE_ARGS, "--seed 2 --spp 4 --hdr new.exr", out, sizeof out) == 0, "%s", out);
    EXPECT(!rt_same_file(rt_path("old.exr"), rt_path("new.exr")));
    snprintf(cmd, sizeof cmd, "cd '%s' && cp old.exr o.exr", dir);
    ASSERT(pm_test_run(cmd, out, sizeof out) == 0);
    int rc = rt_render_paused("pfm", "INT", SCENE_ARGS, "--seed 2 --spp 4 --hdr o.exr", "", out, sizeof out);
    EXPECT_MSG(rc == 130, "status %d: %s", rc, out);
    EXPECT_MSG(rt_same_file(rt_path("o.exr"), rt_path("old.exr")), "the old EXR changed");
    EXPECT_EQ_INT(rt_count_temps(), 0);
    ASSERT_MSG(rt_render(SCENE_ARGS, "--seed 2 --spp 4 --hdr o.exr", out, sizeof out) == 0, "%s", out);
    EXPECT(rt_same_file(rt_path("o.exr"), rt_path("new.exr")));
    EXPECT_EQ_INT(rt_count_temps(), 0);
}
