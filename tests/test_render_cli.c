/* test_render_cli.c: the render program's command line, run as a user would run it.
 *
 * Oracle: the documented behaviour (render --help, README "The renderer"): --help prints the
 * usage with status 0 (also after --compare); an impossible or malformed value exits with
 * status 2 and a message that names the option and the range it wanted; a missing scene file
 * and an output path that cannot be written exit non-zero before anything is rendered; in
 * every failing case no output file is left behind, not even the other of two outputs; and
 * the images written get the permissions of the umask, as files made with fopen would.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "test.h"

#define CLI_SCENE                                                                              \
    "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 8, "  \
    "\"height\": 8, \"spp\": 1}, \"materials\": {\"w\": {\"type\": \"lambert\", "              \
    "\"reflectance\": 0.5}, \"e\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": " \
    "1}}, \"objects\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 1, "           \
    "\"material\": \"w\"}, {\"type\": \"quad\", \"vertices\": [[-1,3,-1],[1,3,-1],[1,3,1],"    \
    "[-1,3,1]], \"material\": \"e\"}]}"

static const char *scene_path(void) {
    static char path[1024];
    snprintf(path, sizeof path, "%s/cli.json", pm_test_tmpdir());
    if (access(path, F_OK) != 0) {
        FILE *f = fopen(path, "w");
        if (f) {
            fputs(CLI_SCENE, f);
            fclose(f);
        }
    }
    return path;
}

static int exists(const char *dir, const char *name) {
    char p[2048];
    snprintf(p, sizeof p, "%s/%s", dir, name);
    return access(p, F_OK) == 0;
}

/* Oracle: the usage text, status 0, on stdout; for render and for render --compare (which
 * scripts/imgcmp wraps). */
TEST(render_cli_help) {
    char cmd[2048], out[16384];
    const char *forms[] = {"--help", "-h", "--compare --help", "--compare a.pfm --help"};
    for (size_t i = 0; i < sizeof forms / sizeof forms[0]; i++) {
        snprintf(cmd, sizeof cmd, "%s/render %s 2>/dev/null", pm_test_build_dir(), forms[i]);
        EXPECT_MSG(pm_test_run(cmd, out, sizeof out) == 0, "render %s: %s", forms[i], out);
        EXPECT_MSG(strstr(out, "usage: render") && strstr(out, "--spp N"), "render %s: %s", forms[i], out);
    }
}

/* Oracle: status 2, a message naming the option (and, for numbers, the accepted range), and
 * no image written, for every impossible value. */
TEST(render_cli_rejects_impossible_values) {
    static const struct {
        const char *args, *expect;
    } cases[] = {
        {"--spp 0", "--spp: expected a whole number in [1, "},
        {"--spp -3", "--spp: expected a whole number in [1, "},
        {"--spp many", "--spp: expected a whole number"},
        {"--spp 4.5", "--spp: expected a whole number"},
        {"--width -5", "--width: expected a whole number in [1, 16384], got '-5'"},
        {"--width 0", "--width: expected a whole number in [1, 16384]"},
        {"--height 100000", "--height: expected a whole number in [1, 16384]"},
        {"--width 99999999999999999999", "--width: expected a whole number"},
        {"--threads 0", "--threads: expected a whole number in [1, 1024], got '0'"},
        {"--threads -2", "--threads: expected a whole number in [1, "},
        {"--seed -1", "--seed: expected a whole number in [0, "},
        {"--exposure 0", "--exposure: invalid value '0'"},
        {"--exposure nan", "--exposure: invalid value 'nan'"},
        {"--tone sepia", "--tone: invalid value 'sepia'"},
        {"--mode nosuch", "unknown mode \"nosuch\""},
        {"--bogus", "unknown option --bogus"},
        {"--spp", "--spp needs a value"},
    };
    const char *dir = pm_test_tmpdir(), *scene = scene_path();
    char cmd[4096], out[16384];
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        snprintf(cmd, sizeof cmd, "cd '%s' && %s/render '%s' --quiet --hdr v.pfm -o v.png %s 2>&1", dir,
                 pm_test_build_dir(), scene, cases[i].args);
        int rc = pm_test_run(cmd, out, sizeof out);
        EXPECT_MSG(rc == 2, "%s: exit %d: %s", cases[i].args, rc, out);
        EXPECT_MSG(strstr(out, cases[i].expect) != NULL, "%s: expected \"%s\" in: %s", cases[i].args,
                   cases[i].expect, out);
        EXPECT_MSG(!exists(dir, "v.png") && !exists(dir, "v.pfm"), "%s: an image was written", cases[i].args);
        EXPECT_MSG(!strstr(out, "Rendering"), "%s: it rendered: %s", cases[i].args, out);
    }
    /* One side given: the other follows the scene's aspect (here 10:1) and is range-checked
     * as well, instead of asking for a 20000-pixel-wide image. */
    char wide[1024];
    snprintf(wide, sizeof wide, "%s/wide.json", dir);
    FILE *f = fopen(wide, "w");
    ASSERT(f);
    fputs("{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 100, "
          "\"height\": 10}, \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5}}, "
          "\"objects\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 1, \"material\": \"w\"}]}",
          f);
    fclose(f);
    snprintf(cmd, sizeof cmd, "cd '%s' && %s/render '%s' --quiet --hdr v.pfm --height 2000 2>&1", dir,
             pm_test_build_dir(), wide);
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 2);
    EXPECT_MSG(strstr(out, "--height 2000 gives a width of 20000") && strstr(out, "16384"), "%s", out);
    EXPECT(!exists(dir, "v.pfm"));
    snprintf(cmd, sizeof cmd, "cd '%s' && %s/render '%s' --hdr v.pfm --width 50 2>&1", dir,
             pm_test_build_dir(), wide);
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "Rendering 50x5,") != NULL, "%s", out);
}

/* Oracle: a scene that does not exist or is a directory, and outputs that cannot be written
 * (directory missing, read-only directory, the path is a directory), fail before rendering
 * (no "Rendering" line), name the file, and leave neither output behind. */
TEST(render_cli_bad_paths_fail_before_rendering) {
    const char *dir = pm_test_tmpdir(), *scene = scene_path();
    char cmd[4096], out[16384], ro[1024];
    snprintf(ro, sizeof ro, "%s/readonly", dir);
    ASSERT_EQ_INT(mkdir(ro, 0555), 0);
    /* Root writes into a 0555 directory anyway: that case runs unprivileged (test.h; as root,
     * as nobody through setpriv, with the scratch directory made writable for nobody, as it would
     * be for a user running the test). */
    char why[256] = "";
    const char *unpriv = pm_test_unprivileged_prefix(why, sizeof why);
    if (unpriv && *unpriv) ASSERT_EQ_INT(chmod(dir, 0777), 0);
    static const struct {
        const char *args, *expect;
        int need_nonroot;
    } cases[] = {
        {"'%s/none.json' --hdr ok.pfm", "none.json: cannot open", 0},
        {"'%s/readonly' --hdr ok.pfm", "readonly: cannot read: Is a directory", 0},
        {"SCENE --hdr ok.pfm -o nodir/x.png", "-o nodir/x.png: cannot write there", 0},
        {"SCENE -o ok.png --hdr nodir/x.pfm", "--hdr nodir/x.pfm: cannot write there", 0},
        {"SCENE -o ok.png --hdr readonly", "--hdr readonly: cannot write there: Is a directory", 0},
        {"SCENE --hdr ok.pfm -o readonly/x.png", "-o readonly/x.png: cannot write there", 1},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        if (cases[i].need_nonroot && !unpriv) continue; /* counted as a SKIP below */
        char args[2048];
        if (strncmp(cases[i].args, "SCENE", 5) == 0)
            snprintf(args, sizeof args, "'%s'%s", scene, cases[i].args + 5);
        else
            snprintf(args, sizeof args, cases[i].args, dir);
        snprintf(cmd, sizeof cmd, "cd '%s' && %s%s/render %s --quiet 2>&1", dir,
                 cases[i].need_nonroot ? unpriv : "", pm_test_build_dir(), args);
        int rc = pm_test_run(cmd, out, sizeof out);
        EXPECT_MSG(rc != 0, "%s: exit 0: %s", args, out);
        EXPECT_MSG(strstr(out, cases[i].expect) != NULL, "%s: expected \"%s\" in: %s", args,
                   cases[i].expect, out);
        EXPECT_MSG(!strstr(out, "Rendering"), "%s: it rendered before failing: %s", args, out);
        EXPECT_MSG(!exists(dir, "ok.png") && !exists(dir, "ok.pfm"), "%s: an output was left", args);
    }
    /* and nothing else was left in the directory: no temporary files */
    snprintf(cmd, sizeof cmd, "cd '%s' && ls -A | grep -v -x -e cli.json -e readonly | wc -l", dir);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strtol(out, NULL, 10) == 0, "left behind: %s", out);
    chmod(ro, 0755);
    if (!unpriv) SKIP(why); /* the other cases ran; the read-only directory could not */
}

/* Oracle: fopen's rule, 0666 less the umask, for both images (the writers go through a
 * mkstemp file, which is 0600 unless fixed). */
TEST(render_cli_outputs_follow_umask) {
    const char *dir = pm_test_tmpdir(), *scene = scene_path();
    const struct {
        const char *umask;
        unsigned mode;
    } cases[] = {{"022", 0644}, {"027", 0640}, {"002", 0664}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        char cmd[4096], out[16384], p[2048];
        snprintf(cmd, sizeof cmd, "cd '%s' && umask %s && %s/render '%s' --quiet -o m%zu.png --hdr m%zu.pfm",
                 dir, cases[i].umask, pm_test_build_dir(), scene, i, i);
        ASSERT_MSG(pm_test_run(cmd, out, sizeof out) == 0, "%s", out);
        for (int k = 0; k < 2; k++) {
            struct stat st;
            snprintf(p, sizeof p, "%s/m%zu.%s", dir, i, k ? "pfm" : "png");
            ASSERT_EQ_INT(stat(p, &st), 0);
            EXPECT_MSG((st.st_mode & 0777) == cases[i].mode, "umask %s: %s has mode %o, want %o",
                       cases[i].umask, p, (unsigned)(st.st_mode & 0777), cases[i].mode);
        }
    }
}

/* Oracle: the documented progress output. On a terminal (a pseudo-terminal made by
 * util-linux `script`, part of every Debian install) stderr gets a redrawn bar with an ETA:
 * carriage returns, "[", "ETA"; off a terminal, plain lines and no carriage return (checked
 * in test_render_scene.c); --quiet prints none on either. */
TEST(render_cli_progress_bar_on_a_terminal) {
    char cmd[4096], out[65536];
    if (pm_test_run("command -v script >/dev/null", NULL, 0) != 0)
        SKIP("script(1) not installed: terminal progress not checked");
    const char *dir = pm_test_tmpdir(), *scene = scene_path();
    snprintf(cmd, sizeof cmd, "cd '%s' && script -qec \"%s/render '%s' --spp 4 --hdr t.pfm\" ts.log",
             dir, pm_test_build_dir(), scene);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    const char *bar = strstr(out, "\rRendering [");
    EXPECT_MSG(bar && strstr(bar, "ETA "), "no progress bar with an ETA: %s", out);
    snprintf(cmd, sizeof cmd, "cd '%s' && script -qec \"%s/render '%s' --spp 4 --hdr t.pfm --quiet\" ts.log",
             dir, pm_test_build_dir(), scene);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(!strstr(out, "ETA"), "--quiet still shows progress: %s", out);
}

/* The "Threads that counted (in this process)" line of the statistics, or -1. */
static long threads_counted(const char *out) {
    const char *k = strstr(out, "Threads that counted (in this process)");
    return k ? strtol(k + strlen("Threads that counted (in this process)"), NULL, 10) : -1;
}

/* Oracle: the documented --threads N ("worker threads"): no more than N threads do the run's
 * work, in every phase. The statistics count the threads that traced a ray (stats.h); the plan's
 * pilots run inside integrator_create, which used to run before main.c applied --threads, so a
 * --threads 1 run traced its pilots on OpenMP's default team (2 here, from OMP_NUM_THREADS=2)
 * and counted 2. --threads 2 against OMP_NUM_THREADS=1 checks the other way: the option wins
 * over the environment, and both threads work (each pass hands out thousands of photons in
 * small chunks); it needs two cores to be a fair check, so it is skipped on one. */
TEST(render_cli_threads_govern_every_phase) {
    char cmd[4096], out[65536];
    const char *args = "--mode pm --width 8 --height 8 --spp 1 --pm global_photons=2000 "
                       "--pm caustic_photons=2000 --quiet --hdr th.pfm";
    snprintf(cmd, sizeof cmd, "cd '%s' && OMP_NUM_THREADS=2 %s/render '%s/data/scenes/cornell_spheres.json' "
             "%s --threads 1 2>&1", pm_test_tmpdir(), pm_test_build_dir(), pm_test_source_dir(), args);
    ASSERT_MSG(pm_test_run(cmd, out, sizeof out) == 0, "%s", out);
    EXPECT_MSG(strstr(out, "from 8192 pilot photons"), "the plan ran no pilot: %s", out);
    EXPECT_MSG(threads_counted(out) == 1, "--threads 1: %ld threads counted: %s", threads_counted(out), out);
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    if (cores < 2) SKIP("one core: --threads 2 not checked (only --threads 1)");
#ifndef _OPENMP
    SKIP("built without OpenMP (OPENMP=0): render runs one thread, --threads 2 not checked");
#endif
    snprintf(cmd, sizeof cmd, "cd '%s' && OMP_NUM_THREADS=1 %s/render '%s/data/scenes/cornell_spheres.json' "
             "%s --threads 2 2>&1", pm_test_tmpdir(), pm_test_build_dir(), pm_test_source_dir(), args);
    ASSERT_MSG(pm_test_run(cmd, out, sizeof out) == 0, "%s", out);
    EXPECT_MSG(threads_counted(out) == 2, "--threads 2: %ld threads counted: %s", threads_counted(out), out);
}
