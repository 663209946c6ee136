/* test_render_checkpoint.c: checkpoints and resumed renders.
 *
 * Oracle: an uninterrupted render with the same seed and settings. A render stopped at a
 * checkpoint (at several points) and continued from the file that checkpoint wrote, with
 * another thread count, must give the same film bit for bit (memcmp of the floats, or of the
 * PFM files for the program). Damaged checkpoints (truncated at several lengths, another
 * version, a flipped byte) and checkpoints of another scene or other settings must be
 * refused with a message; for the program that is exit status 2.
 */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "test.h"
#include "../photonmap/common.h"
#include "../render/run/checkpoint.h"
#include "../render/image/film.h"
#include "../render/integrators/integrator.h"
#include "../render/base/output.h"
#include "../render/run/renderer.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"
#include "test_render_run.h"

static int load_scene(scene *s, const char *name, int w, int h, int spp) {
    char path[1024];
    json_err e;
    snprintf(path, sizeof path, "%s/data/scenes/%s", pm_test_source_dir(), name);
    if (scene_load(s, path, &e) < 0) {
        printf("    %s: %s\n", path, e.msg);
        return -1;
    }
    camera_resize(&s->cam, w, h);
    camera_set_spp(&s->cam, spp);
    return 0;
}

typedef struct stopper {
    int calls, stop_after;
    const char *ckpt;
    ckpt_info info;
} stopper;

/* Write a checkpoint at every pause; at the stop_after-th, end the render as a kill would. */
static int on_pause(void *user, const render_state *st, int why) {
    stopper *sp = user;
    (void)why;
    char err[512];
    if (ckpt_write(sp->ckpt, &sp->info, st, err, sizeof err) < 0) {
        printf("    %s\n", err);
        return PM_EIO;
    }
    return ++sp->calls >= sp->stop_after ? PM_EINVAL : 0;
}

/* Oracle: the uninterrupted film (1 thread). Stopped after 1, 3 and 7 periodic checkpoints
 * (a pause after every sample step) and resumed from the file with 2 and 3 threads, the film
 * is bit-identical; the checkpoint read back equals the state written. */
TEST(render_checkpoint_resume_bit_identical) {
    scene s;
    ASSERT(load_scene(&s, "cornell_box.json", 40, 24, 9) == 0); /* tiles cut at the edges */
    integrator it;
    char err[512];
    ASSERT(integrator_create("path", &s, &it, err, sizeof err) == 0);
    film ref;
    render_job job = {1, 1, s.settings.seed, NULL, NULL};
    ASSERT(render_image(&s, &it, &job, &ref) == 0);
    int stops[3] = {1, 3, 7};
    for (int k = 0; k < 3; k++) {
        stopper sp = {0, stops[k], rt_path("a.ckpt"), {0}};
        snprintf(sp.info.settings, sizeof sp.info.settings, "test");
        render_state st;
        ASSERT(render_state_init(&st, 40, 24, 9) == 0);
        render_control ctl = {&st, 1e-9, on_pause, &sp, 0};
        film f;
        render_job j2 = {2, 1, s.settings.seed, NULL, NULL};
        int rc = render_image_ctl(&s, &it, &j2, &ctl, &f);
        EXPECT_EQ_INT(rc, PM_EINVAL);
        uint64_t done = render_state_done(&st);
        EXPECT_MSG(done > 0 && done < 40 * 24 * 9, "stopped with %llu samples done",
                   (unsigned long long)done);
        ckpt_info ci;
        render_state back;
        ASSERT_MSG(ckpt_read(sp.ckpt, &ci, &back, err, sizeof err) == 0, "%s", err);
        EXPECT(memcmp(back.sum, st.sum, sizeof(double) * 3 * 40 * 24) == 0);
        EXPECT(memcmp(back.count, st.count, sizeof(uint32_t) * 40 * 24) == 0);
        EXPECT(strcmp(ci.settings, "test") == 0);
        render_state_free(&st);
        render_control go = {&back, 0, NULL, NULL, 0};
        job.threads = 2 + k % 2;
        ASSERT(render_image_ctl(&s, &it, &job, &go, &f) == 0);
        EXPECT_EQ_INT(render_state_done(&back), 40 * 24 * 9);
        EXPECT_MSG(memcmp(f.px, ref.px, sizeof(float) * 3 * 40 * 24) == 0,
                   "resumed after %d checkpoints with %d threads: film differs", stops[k], job.threads);
        film_free(&f);
        render_state_free(&back);
    }
    film_free(&ref);
    integrator_destroy(&it);
    scene_free(&s);
}

static int raise_int(void *user, const render_state *st, int why) {
    int *calls = user;
    (void)st;
    if (why == RENDER_PAUSE_SIGNAL) return 0;
    if (++*calls == 2) raise(SIGINT);
    return 0;
}

/* Oracle: with the signal deferred (output.h), SIGINT stops the render at a sample boundary
 * with RENDER_INTERRUPTED and a consistent state, and continuing that state gives the
 * uninterrupted film bit for bit. */
TEST(render_checkpoint_signal_stops_cleanly) {
    scene s;
    ASSERT(load_scene(&s, "cornell_box.json", 32, 32, 4) == 0);
    integrator it;
    char err[512];
    ASSERT(integrator_create("path", &s, &it, err, sizeof err) == 0);
    film ref, f;
    render_job job = {2, 1, s.settings.seed, NULL, NULL};
    ASSERT(render_image(&s, &it, &job, &ref) == 0);
    out_signals_install();
    out_defer_begin();
    render_state st;
    ASSERT(render_state_init(&st, 32, 32, 4) == 0);
    int calls = 0;
    render_control ctl = {&st, 1e-9, raise_int, &calls, 1};
    EXPECT_EQ_INT(render_image_ctl(&s, &it, &job, &ctl, &f), RENDER_INTERRUPTED);
    EXPECT_EQ_INT(out_pending_signal(), SIGINT);
    uint64_t done = render_state_done(&st);
    EXPECT(done > 0 && done < 32 * 32 * 4);
    film_free(&f);
    render_control go = {&st, 0, NULL, NULL, 0};
    job.threads = 1;
    ASSERT(render_image_ctl(&s, &it, &job, &go, &f) == 0);
    EXPECT(memcmp(f.px, ref.px, sizeof(float) * 3 * 32 * 32) == 0);
    film_free(&f);
    film_free(&ref);
    render_state_free(&st);
    integrator_destroy(&it);
    scene_free(&s);
}

/* Oracle: the format's own promises: every truncation (header, strings, pixels, checksum) is
 * refused with "truncated", another version with PM_EVERSION, a flipped pixel byte by the
 * checksum, a padded file as "extra data"; the intact file reads. */
TEST(render_checkpoint_damaged_files_refused) {
    render_state st;
    ASSERT(render_state_init(&st, 5, 3, 4) == 0);
    for (int i = 0; i < 15; i++) {
        st.count[i] = (uint32_t)(i % 5);
        for (int c = 0; c < 3; c++) st.sum[3 * i + c] = 0.1 * i + c;
    }
    ckpt_info ci;
    memset(&ci, 0, sizeof ci);
    snprintf(ci.settings, sizeof ci.settings, "mode=path");
    memcpy(ci.args, "--spp\0" "4\0", 8);
    ci.args_len = 8;
    char err[512];
    const char *p = rt_path("good.ckpt");
    ASSERT_MSG(ckpt_write(p, &ci, &st, err, sizeof err) == 0, "%s", err);
    FILE *f = fopen(p, "rb");
    ASSERT(f);
    unsigned char buf[4096];
    size_t n = fread(buf, 1, sizeof buf, f);
    fclose(f);
    ASSERT_EQ_INT(n, 56 + 9 + 8 + 15 * 28 + 8);
    size_t cuts[] = {0, 7, 30, 56, 60, 80, n / 2, n - 9, n - 1};
    const char *q = rt_path("bad.ckpt");
    ckpt_info back;
    render_state bs;
    for (size_t k = 0; k < sizeof cuts / sizeof cuts[0]; k++) {
        f = fopen(q, "wb");
        fwrite(buf, 1, cuts[k], f);
        fclose(f);
        err[0] = 0;
        EXPECT_EQ_INT(ckpt_read(q, &back, &bs, err, sizeof err), PM_EFORMAT);
        EXPECT_MSG(strstr(err, "truncated") || (cuts[k] < 56 && strstr(err, "not a render checkpoint")),
                   "cut at %zu: %s", cuts[k], err);
    }
    unsigned char v[4096];
    memcpy(v, buf, n);
    v[8] = 4; /* versions 2 and 3 are renders in passes (test_render_progressive.c) */
    f = fopen(q, "wb");
    fwrite(v, 1, n, f);
    fclose(f);
    EXPECT_EQ_INT(ckpt_read(q, &back, &bs, err, sizeof err), PM_EVERSION);
    EXPECT_MSG(strstr(err, "version 4"), "%s", err);
    memcpy(v, buf, n);
    v[100] ^= 1;
    f = fopen(q, "wb");
    fwrite(v, 1, n, f);
    fclose(f);
    EXPECT_EQ_INT(ckpt_read(q, &back, &bs, err, sizeof err), PM_EFORMAT);
    EXPECT_MSG(strstr(err, "checksum"), "%s", err);
    f = fopen(q, "wb");
    fwrite(buf, 1, n, f);
    fputc(0, f);
    fclose(f);
    EXPECT_EQ_INT(ckpt_read(q, &back, &bs, err, sizeof err), PM_EFORMAT);
    EXPECT_MSG(strstr(err, "extra data"), "%s", err);
    /* The arguments-only read (st NULL, what --resume replays) checks the checksum too: a
     * flipped byte in the arguments, in the settings or in a pixel is refused, so a damaged
     * file's arguments are never replayed; the intact file reads. */
    size_t flips[] = {56 + 2, 56 + 9 + 3, 56 + 9 + 8 + 40, n - 12};
    for (size_t k = 0; k < sizeof flips / sizeof flips[0]; k++) {
        memcpy(v, buf, n);
        v[flips[k]] ^= 0x20;
        f = fopen(q, "wb");
        fwrite(v, 1, n, f);
        fclose(f);
        err[0] = 0;
        EXPECT_EQ_INT(ckpt_read(q, &back, NULL, err, sizeof err), PM_EFORMAT);
        EXPECT_MSG(strstr(err, "corrupt (checksum mismatch)"), "byte %zu: %s", flips[k], err);
    }
    ASSERT_MSG(ckpt_read(p, &back, NULL, err, sizeof err) == 0, "%s", err);
    EXPECT(back.args_len == 8 && memcmp(back.args, ci.args, 8) == 0);
    ASSERT_MSG(ckpt_read(p, &back, &bs, err, sizeof err) == 0, "%s", err);
    EXPECT(bs.width == 5 && bs.height == 3 && bs.spp == 4);
    EXPECT(memcmp(bs.sum, st.sum, sizeof(double) * 45) == 0);
    EXPECT(memcmp(bs.count, st.count, sizeof(uint32_t) * 15) == 0);
    EXPECT(back.args_len == 8 && memcmp(back.args, ci.args, 8) == 0);
    EXPECT(strcmp(back.settings, "mode=path") == 0);
    render_state_free(&bs);
    render_state_free(&st);
}

/* ---- the render program ------------------------------------------------------------------- */

#define PATH_SCENE "'%s/data/scenes/cornell_box.json' --width 40 --height 24 --spp 16"
#define PM_SCENE                                                                             \
    "'%s/data/scenes/cornell_spheres.json' --mode pm --pm global_photons=8000 --pm "        \
    "caustic_photons=8000 --width 32 --height 32 --spp 9"

/* Oracle: the PFM of an uninterrupted render (2 threads), byte for byte. The render is
 * stopped by SIGINT at 30% and 80% (the program writes a checkpoint and ends by SIGINT,
 * status 130), and by SIGKILL at 60% after periodic checkpoints (every millisecond: whatever
 * the last complete one is); each is resumed with `render SCENE --resume FILE` alone (its
 * options replayed) at 1 or 3 threads. Path tracing and photon mapping (the maps are saved
 * beside the checkpoint and loaded on resume). */
static void resume_cases(const char *scene_fmt) {
    char out[16384];
    ASSERT_MSG(rt_render(scene_fmt, "--threads 2 --hdr ref.pfm -o ref.png --quiet", out, sizeof out) == 0, "%s", out);
    static const struct {
        const char *phase, *sig, *extra;
        int status, threads;
    } cases[] = {{"render:0.3", "INT", "", 130, 1},
                 {"render:0.6", "KILL", "--checkpoint-every 0.001", 137, 3},
                 {"render:0.8", "TERM", "", 143, 3}};
    /* a sanitizer build runs the first two (SIGINT, SIGKILL) only: same oracle, less time */
    size_t ncases = PM_TEST_SANITIZED ? 2 : sizeof cases / sizeof cases[0];
    for (size_t k = 0; k < ncases; k++) {
        char args[1024], sc[2048], cmd[8192];
        rt_run("rm -rf c.ckpt c.ckpt.photons c.pfm c.png", out, sizeof out);
        snprintf(args, sizeof args, "--threads 2 --hdr c.pfm -o c.png --checkpoint c.ckpt %s", cases[k].extra);
        int rc = rt_render_paused(cases[k].phase, cases[k].sig, scene_fmt, args, "", out, sizeof out);
        EXPECT_MSG(rc == cases[k].status, "%s %s: status %d: %s", cases[k].phase, cases[k].sig, rc, out);
        EXPECT_MSG(access(rt_path("c.pfm"), F_OK) != 0, "%s: an image was written", cases[k].phase);
        /* only the scene part of the format: --resume replays the rest */
        snprintf(sc, sizeof sc, scene_fmt, pm_test_source_dir());
        *strchr(sc + 1, '\'') = 0;
        snprintf(cmd, sizeof cmd, "'%s/render' %s' --resume c.ckpt --threads %d", pm_test_build_dir(),
                 sc, cases[k].threads);
        rc = rt_run(cmd, out, sizeof out);
        EXPECT_MSG(rc == 0, "%s: resume failed (%d): %s", cases[k].phase, rc, out);
        EXPECT_MSG(strstr(out, "Resuming: "), "%s: the progress does not show the resumed state: %s",
                   cases[k].phase, out);
        EXPECT_MSG(rt_same_file("c.pfm", "ref.pfm") && rt_same_file("c.png", "ref.png"),
                   "%s %s, resumed at %d threads: the image differs from the uninterrupted one",
                   cases[k].phase, cases[k].sig, cases[k].threads);
    }
    rt_run("ls -A | grep -c tmp", out, sizeof out);
    EXPECT_MSG(atoi(out) == 0, "temporaries left: %s", out);
}

TEST(render_checkpoint_cli_resume_path) { resume_cases(PATH_SCENE); }
TEST(render_checkpoint_cli_resume_pm) { resume_cases(PM_SCENE); }

/* Oracle: the documented refusals, status 2 with a message and no image, quickly: a
 * checkpoint resumed with another scene, with other settings (--spp), with photon maps that
 * changed, and a truncated checkpoint. */
TEST(render_checkpoint_cli_refusals) {
    char out[16384], cmd[8192];
    int rc = rt_render_paused("render:0.5", "INT", PM_SCENE, "--threads 2 --hdr c.pfm --checkpoint c.ckpt",
                              "", out, sizeof out);
    ASSERT_MSG(rc == 130, "status %d: %s", rc, out);
    /* the same scene with one more newline: another file, so another scene hash */
    snprintf(cmd, sizeof cmd, "cp '%s/data/scenes/cornell_spheres.json' other.json && echo >> other.json",
             pm_test_source_dir());
    ASSERT(rt_run(cmd, out, sizeof out) == 0);
    rt_run("head -c 1000 c.ckpt > trunc.ckpt", out, sizeof out);
    static const struct {
        const char *args, *expect;
    } cases[] = {
        {"other.json --resume c.ckpt", "another scene"},
        {"SCENE --resume c.ckpt --spp 4", "other settings"},
        {"SCENE --resume c.ckpt --pm k_global=7", "other settings"},
        {"SCENE --resume trunc.ckpt", "truncated"},
        {"SCENE --resume nosuch.ckpt", "nosuch.ckpt"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        char args[2048];
        if (strncmp(cases[k].args, "SCENE", 5) == 0)
            snprintf(args, sizeof args, "'%s/data/scenes/cornell_spheres.json'%s", pm_test_source_dir(),
                     cases[k].args + 5);
        else
            snprintf(args, sizeof args, "%s", cases[k].args);
        snprintf(cmd, sizeof cmd, "timeout 5 '%s/render' %s", pm_test_build_dir(), args);
        rc = rt_run(cmd, out, sizeof out);
        EXPECT_MSG(rc == 2, "%s: status %d: %s", args, rc, out);
        EXPECT_MSG(strstr(out, cases[k].expect), "%s: expected \"%s\" in: %s", args, cases[k].expect, out);
        EXPECT_MSG(access(rt_path("c.pfm"), F_OK) != 0, "%s: an image was written", args);
    }
    /* A byte of the stored arguments changed ("global_photons" -> "glObal_photons"): refused
     * as corrupt before anything is replayed (it once came back as "--pm glObal_photons:
     * unknown key"). */
    {
        FILE *f = fopen(rt_path("c.ckpt"), "rb");
        ASSERT(f);
        static unsigned char ck[1 << 16];
        size_t n = fread(ck, 1, sizeof ck, f);
        fclose(f);
        unsigned char *at = NULL;
        for (size_t i = 0; i + 14 <= n && !at; i++)
            if (memcmp(ck + i, "global_photons", 14) == 0 && i > 0 && ck[i - 1] == 0) at = ck + i;
        ASSERT_MSG(at != NULL, "no stored argument global_photons=... in c.ckpt (%zu bytes)", n);
        at[2] = 'O';
        f = fopen(rt_path("flip.ckpt"), "wb");
        ASSERT(f);
        fwrite(ck, 1, n, f);
        fclose(f);
        snprintf(cmd, sizeof cmd, "timeout 5 '%s/render' '%s/data/scenes/cornell_spheres.json' --resume flip.ckpt",
                 pm_test_build_dir(), pm_test_source_dir());
        rc = rt_run(cmd, out, sizeof out);
        EXPECT_MSG(rc == 2 && strstr(out, "render: --resume flip.ckpt: corrupt (checksum mismatch)") &&
                       !strstr(out, "glObal"),
                   "status %d: %s", rc, out);
    }
    /* changed photon maps */
    rt_run("cp c.ckpt.photons/caustic.pmap x && head -c 2000 x > c.ckpt.photons/caustic.pmap", out, sizeof out);
    snprintf(cmd, sizeof cmd, "timeout 5 '%s/render' '%s/data/scenes/cornell_spheres.json' --resume c.ckpt",
             pm_test_build_dir(), pm_test_source_dir());
    rc = rt_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 2 && strstr(out, "photon maps"), "status %d: %s", rc, out);
}

/* Oracle: a snapshot is a whole PNG of the image's size while the render is paused half way
 * (PNG signature and IHDR width/height), and after the render the PNG is the one an
 * uninterrupted render writes, byte for byte. */
TEST(render_checkpoint_cli_snapshot) {
    char out[16384];
    ASSERT(rt_render(PATH_SCENE, "--threads 2 -o ref.png --quiet", out, sizeof out) == 0);
    int rc = rt_render_paused("render:0.5", "INT", PATH_SCENE, "--threads 2 -o s.png --snapshot-every 0.001",
                              "cp s.png mid.png", out, sizeof out);
    EXPECT_MSG(rc == 130, "status %d: %s", rc, out);
    EXPECT_MSG(rt_render(PATH_SCENE, "--threads 2 -o s.png --quiet", out, sizeof out) == 0, "%s", out);
    FILE *f = fopen(rt_path("mid.png"), "rb");
    ASSERT_MSG(f, "no snapshot while paused");
    unsigned char b[24];
    size_t n = fread(b, 1, 24, f);
    fclose(f);
    ASSERT_EQ_INT(n, 24);
    EXPECT(memcmp(b, "\x89PNG\r\n\x1a\n", 8) == 0 && memcmp(b + 12, "IHDR", 4) == 0);
    EXPECT_EQ_INT((b[16] << 24) | (b[17] << 16) | (b[18] << 8) | b[19], 40);
    EXPECT_EQ_INT((b[20] << 24) | (b[21] << 16) | (b[22] << 8) | b[23], 24);
    EXPECT(rt_same_file("s.png", "ref.png"));
}

/* ckpt_set_distributed (checkpoint.h). Oracle: the one-process behaviour of the same calls. A
 * process that is not the writer writes nothing: checkpoint_begin of a fresh render and a
 * signal pause (which always writes for the writer) leave no file, while the writer's same
 * calls write it; the extra text ends the settings text, and "" gives the one-process text
 * exactly (so a replicated distributed render's checkpoints are render's). */
TEST(render_checkpoint_distributed_writer_and_settings) {
    scene s;
    ASSERT(load_scene(&s, "cornell_box.json", 8, 8, 4) == 0);
    char one[4096], dist[4096];
    ckpt_settings_text(&s, "path", one, sizeof one);
    ckpt_set_distributed(0, "; distributed partitioned over 3 ranks", 1);
    ckpt_settings_text(&s, "path", dist, sizeof dist);
    size_t n = strlen(one);
    EXPECT(strncmp(one, dist, n) == 0 && strcmp(dist + n, "; distributed partitioned over 3 ranks") == 0);
    render_state st;
    ASSERT(render_state_init(&st, 8, 8, 4) == 0);
    static ckpt_session cs;
    memset(&cs, 0, sizeof cs);
    char *p = strdup(rt_path("dist.ckpt"));
    cs.ckpt_path = p;
    cs.ckpt_every = 600;
    cs.quiet = 1;
    EXPECT(checkpoint_begin(&cs, 0, &st) == 0);
    EXPECT(ckpt_session_pause(&cs, &st, RENDER_PAUSE_SIGNAL) == 0);
    EXPECT_MSG(access(p, F_OK) != 0, "a process that is not the writer wrote %s", p);
    ckpt_set_distributed(1, "", 0);
    ckpt_settings_text(&s, "path", dist, sizeof dist);
    EXPECT(strcmp(one, dist) == 0);
    EXPECT(checkpoint_begin(&cs, 0, &st) == 0);
    EXPECT_MSG(access(p, F_OK) == 0, "the writer's checkpoint_begin wrote no %s", p);
    unlink(p);
    EXPECT(ckpt_session_pause(&cs, &st, RENDER_PAUSE_SIGNAL) == 0);
    EXPECT_MSG(access(p, F_OK) == 0, "the writer's signal pause wrote no %s", p);
    free(p);
    render_state_free(&st);
    scene_free(&s);
}

static void put_file(const char *dir, const char *name, const char *text) {
    char p[1100];
    snprintf(p, sizeof p, "%s/%s", dir, name);
    FILE *f = fopen(p, "wb");
    if (f) {
        fputs(text, f);
        fclose(f);
    }
}

/* ckpt_photon_hash covers the volume maps (checkpoint.h). Oracle: which files the header says
 * it reads. Changing a byte of volume-0.pmap or of volume_caustic-1.pmap (medium 1 has only
 * its caustic map) changes the hash; a volume-3.pmap after a medium with neither map (2) is
 * not read, so changing it leaves the hash as it was. */
TEST(render_checkpoint_photon_hash_volume_maps) {
    char dir[1024];
    snprintf(dir, sizeof dir, "%s", rt_path("maps"));
    ASSERT(mkdir(dir, 0700) == 0);
    put_file(dir, "global.pmap", "g");
    put_file(dir, "volume-0.pmap", "v0");
    put_file(dir, "volume_caustic-1.pmap", "c1");
    put_file(dir, "volume-3.pmap", "v3");
    char err[256];
    uint64_t h0, h1, h2, h3;
    ASSERT(ckpt_photon_hash(dir, &h0, err, sizeof err) == 0);
    put_file(dir, "volume-0.pmap", "v0'");
    ASSERT(ckpt_photon_hash(dir, &h1, err, sizeof err) == 0);
    EXPECT(h1 != h0);
    put_file(dir, "volume_caustic-1.pmap", "c1'");
    ASSERT(ckpt_photon_hash(dir, &h2, err, sizeof err) == 0);
    EXPECT(h2 != h1);
    put_file(dir, "volume-3.pmap", "v3'");
    ASSERT(ckpt_photon_hash(dir, &h3, err, sizeof err) == 0);
    EXPECT(h3 == h2);
}
