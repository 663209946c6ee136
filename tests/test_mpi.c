/* test_mpi.c: the distributed renderer's checks that belong in `make test`.
 *
 * The full suite of render-mpi (every rank count, failures, killed ranks) is
 * scripts/test-mpi.sh (`make MPI=1 test-mpi`, run by .ci/run). Here: the default build stays
 * free of MPI, docs/MPI.md regenerates from its measurements, and, when render-mpi was built
 * into this build directory (make MPI=1), one quick bit-identity check and one quick check
 * of partitioned maps; without it those tests are skipped.
 */
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "test.h"
#include "../photonmap/common.h"
#include "../render/photons/photon_trace.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"
#include "../render/photons/volume.h"

/* Oracle: the promise of the build. No file the default build compiles includes mpi.h (only
 * render/mpi/ does), and the default render binary does not link an MPI library. */
TEST(mpi_default_build_needs_no_mpi) {
    char cmd[4096], out[4096];
    snprintf(cmd, sizeof cmd, "cd '%s' && grep -l '^#include <mpi[.]h>' photonmap/*.c photonmap/*.h "
             "render/*/*.c render/*/*.h bench/*.c tests/*.c 2>/dev/null | grep -v ^render/mpi/; true", pm_test_source_dir());
    pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(out[0] == 0, "files of the default build include mpi.h:\n%s", out);
    snprintf(cmd, sizeof cmd, "ldd '%s/render' | grep -i -c 'libmpi'; true", pm_test_build_dir());
    pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(strncmp(out, "0", 1) == 0, "render links MPI: %s", out);
}

/* Oracle: the committed document itself, byte for byte (as test_docs.c does for the other
 * generated documents): docs/MPI.md from docs/mpi/ through scripts/gen-mpi-md.sh. */
TEST(mpi_docs_regenerate_exactly) {
    char cmd[4096], out[16384], got[1024];
    snprintf(got, sizeof got, "%s/MPI.md", pm_test_tmpdir());
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/gen-mpi-md.sh' --out '%s' '%s/docs/mpi'",
             pm_test_source_dir(), got, pm_test_source_dir());
    int rc = pm_test_run(cmd, out, sizeof out);
    ASSERT_MSG(rc == 0, "generator failed (%d): %s\n%s", rc, cmd, out);
    snprintf(cmd, sizeof cmd, "diff -u '%s/docs/MPI.md' '%s' | head -40", pm_test_source_dir(), got);
    pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(out[0] == 0, "docs/MPI.md does not regenerate exactly from docs/mpi/:\n%s", out);
}

/* Oracle: the one-process render with 2 threads; render-mpi on 2 ranks (1 thread each) must
 * write the same PFM bytes. Skipped unless render-mpi and mpirun are there. In a sanitizer
 * build LeakSanitizer is off for render-mpi: OpenMPI itself keeps allocations until exit. */
TEST(mpi_two_ranks_match_one_process) {
    char mpi[2048], cmd[8192], out[8192];
    struct stat sb;
    snprintf(mpi, sizeof mpi, "%s/render-mpi", pm_test_build_dir());
    if (stat(mpi, &sb) != 0) SKIP("render-mpi not built here (make MPI=1)");
    if (pm_test_run("command -v mpirun", out, sizeof out) != 0) SKIP("mpirun not found");
    const char *d = pm_test_tmpdir();
    const char *args = "data/scenes/cornell_box.json --mode path --width 40 --height 24 --spp 4 --quiet";
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' %s --threads 2 --hdr '%s/one.pfm' && "
             "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 ASAN_OPTIONS=detect_leaks=0 "
             "mpirun --oversubscribe "
             "-np 2 '%s' %s --threads 1 --hdr '%s/two.pfm' && cmp '%s/one.pfm' '%s/two.pfm'",
             pm_test_source_dir(), pm_test_build_dir(), args, d, mpi, args, d, d, d);
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 0, "render-mpi -np 2 differs from render (or failed): %s", out);
}

/* Oracle: the one-process render of the same photons. With partitioned maps (each of 2
 * ranks keeps half of each map; estimates combine the halves, lookup.h) the preview image,
 * the global map's estimates themselves, must have each 16x16 quarter's mean within 1% of
 * the one-process image's (scripts/test-mpi.sh has the full check and why 1% is tight).
 * Skipped unless render-mpi and mpirun are there. */
TEST(mpi_partitioned_two_ranks_close) {
    char mpi[2048], cmd[8192], out[8192];
    struct stat sb;
    snprintf(mpi, sizeof mpi, "%s/render-mpi", pm_test_build_dir());
    if (stat(mpi, &sb) != 0) SKIP("render-mpi not built here (make MPI=1)");
    if (pm_test_run("command -v mpirun", out, sizeof out) != 0) SKIP("mpirun not found");
    const char *d = pm_test_tmpdir();
    const char *args = "data/scenes/cornell_spheres.json --mode preview --width 32 --height 32 "
                       "--spp 4 --pm global_photons=30000 --pm caustic_photons=30000 --quiet";
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' %s --threads 2 --hdr '%s/one.pfm' "
             ">'%s/one.log' 2>&1 && "
             "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 ASAN_OPTIONS=detect_leaks=0 "
             "mpirun --oversubscribe -np 2 '%s' %s --threads 1 --pm distributed=partitioned "
             "--hdr '%s/part.pfm' >'%s/part.log' 2>&1 && for r in '0 0' '16 0' '0 16' '16 16'; do "
             "'%s/render' --compare '%s/part.pfm' '%s/one.pfm' --rect $r 16 16 | "
             "sed -n 's/^rel_mean //p'; done",
             pm_test_source_dir(), pm_test_build_dir(), args, d, d, mpi, args, d, d,
             pm_test_build_dir(), d, d);
    int rc = pm_test_run(cmd, out, sizeof out);
    ASSERT_MSG(rc == 0, "render-mpi partitioned (or render) failed: %s", out);
    int n = 0;
    for (char *p = out, *end; *p; p = end) {
        double v = strtod(p, &end);
        if (end == p) break;
        n++;
        EXPECT_MSG(v > -0.01 && v < 0.01, "a quarter's mean is %.3f%% off the one-process image", 100 * v);
    }
    EXPECT_MSG(n == 4, "expected 4 quarters, got %d: %s", n, out);
}

/* Oracle: render's own pass under the same memory budget (the driver's rules, top of
 * render/photons/photon_rounds.c: a batch past what is left keeps its longest prefix of whole
 * photons that fit, the same for any process count). A lossless furnace (every reflectance 1)
 * with max_bounces 16 and max_memory_mb 16 stops its global pass inside a batch; render-mpi
 * with partitioned maps on 2 ranks must print render's message word for word (the photon where
 * it stopped, the photons stored and emitted) and store as many photons. Until the prefix rule
 * reached the partitioned mode it stopped before the batch (278528 photons against render's
 * 401404). scripts/test-mpi.sh checks more ranks and the runaway case. Skipped unless
 * render-mpi and mpirun are there. */
TEST(mpi_partitioned_memory_budget_keeps_renders_prefix) {
    char mpi[2048], cmd[8192], out[8192], path[2048];
    struct stat sb;
    snprintf(mpi, sizeof mpi, "%s/render-mpi", pm_test_build_dir());
    if (stat(mpi, &sb) != 0) SKIP("render-mpi not built here (make MPI=1)");
    if (pm_test_run("command -v mpirun", out, sizeof out) != 0) SKIP("mpirun not found");
    const char *d = pm_test_tmpdir();
    snprintf(path, sizeof path, "%s/furnace.json", d);
    FILE *f = fopen(path, "w");
    ASSERT_MSG(f != NULL, "cannot write %s", path);
    fputs("{\"camera\": {\"eye\": [5, 5, 1], \"look_at\": [5, 5, 9], \"fov_deg\": 50, \"width\": 8, \"height\": 8, \"spp\": 1},\n"
          " \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 1},\n"
          "   \"lamp\": {\"type\": \"lambert\", \"reflectance\": 1, \"emission\": 10}},\n"
          " \"objects\": [\n"
          "  {\"type\": \"quad\", \"vertices\": [[10,0,0],[0,0,0],[0,0,10],[10,0,10]], \"material\": \"w\"},\n"
          "  {\"type\": \"quad\", \"vertices\": [[10,10,0],[10,10,10],[0,10,10],[0,10,0]], \"material\": \"w\"},\n"
          "  {\"type\": \"quad\", \"vertices\": [[10,0,10],[0,0,10],[0,10,10],[10,10,10]], \"material\": \"w\"},\n"
          "  {\"type\": \"quad\", \"vertices\": [[0,0,10],[0,0,0],[0,10,0],[0,10,10]], \"material\": \"w\"},\n"
          "  {\"type\": \"quad\", \"vertices\": [[10,0,0],[10,0,10],[10,10,10],[10,10,0]], \"material\": \"w\"},\n"
          "  {\"type\": \"quad\", \"vertices\": [[0,0,0],[10,0,0],[10,10,0],[0,10,0]], \"material\": \"w\"},\n"
          "  {\"type\": \"quad\", \"vertices\": [[6,9.99,4],[6,9.99,6],[4,9.99,6],[4,9.99,4]], \"material\": \"lamp\"}],\n"
          " \"render\": {\"max_depth\": 100000}}\n", f);
    fclose(f);
    const char *args = "--mode pm --pm global_photons=100000000 --pm max_memory_mb=16 --pm max_bounces=16 "
                       "--threads 1";
    /* Each run's budget line, without the scene's name, then its count of global photons. */
    const char *pick = "sed -n -e 's/^render: [^:]*: \\(.*max_memory_mb budget.*\\)$/\\1/p' "
                       "-e 's/^ *Global photons stored  *//p'";
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' '%s' %s --hdr '%s/one.pfm' >'%s/one.log' 2>&1 && "
             "OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 ASAN_OPTIONS=detect_leaks=0 "
             "mpirun --oversubscribe -np 2 '%s' '%s' %s --pm distributed=partitioned --hdr '%s/part.pfm' "
             ">'%s/part.log' 2>&1 && %s '%s/one.log' >'%s/one.got' && %s '%s/part.log' >'%s/part.got' && "
             "cat '%s/one.got' && echo == && diff '%s/one.got' '%s/part.got' && test -s '%s/part.pfm'",
             pm_test_source_dir(), pm_test_build_dir(), path, args, d, d, mpi, path, args, d, d, pick, d, d, pick,
             d, d, d, d, d, d);
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 0, "render-mpi partitioned under the memory budget differs from render (or failed):\n%s", out);
    EXPECT_MSG(strstr(out, "stopped by the photon_mapping.max_memory_mb budget (photon ") != NULL,
               "render's pass did not stop inside a batch by the memory budget:\n%s", out);
}

/* Oracle: the documented usage of the MPI scripts: --help prints it with status 0 and does
 * nothing else (no render, no file written). */
TEST(mpi_scripts_have_help) {
    static const char *scripts[] = {"test-mpi.sh", "mpi-scaling.sh", "gen-mpi-md.sh"};
    for (size_t i = 0; i < sizeof scripts / sizeof scripts[0]; i++) {
        char cmd[4096], out[8192];
        snprintf(cmd, sizeof cmd, "cd '%s' && sh '%s/scripts/%s' --help 2>&1", pm_test_tmpdir(),
                 pm_test_source_dir(), scripts[i]);
        EXPECT_MSG(pm_test_run(cmd, out, sizeof out) == 0, "%s --help: %s", scripts[i], out);
        EXPECT_MSG(strstr(out, scripts[i]) && !strstr(out, "PASS") && !strstr(out, " passed, "),
                   "%s --help printed: %s", scripts[i], out);
    }
    char cmd[2048], out[256];
    snprintf(cmd, sizeof cmd, "ls -A '%s' | wc -l", pm_test_tmpdir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strtol(out, NULL, 10) == 0, "--help left files: %s", out);
}

/* ---- the commit stamp of the measurement scripts (scripts/commit-stamp.sh) ---------------- */

/* commit_stamp's output and status ("... rc=N") for a binary in the test's repository. */
static int stamp_of(const char *env, char *out, size_t cap) {
    char cmd[4096];
    const char *d = pm_test_tmpdir();
    snprintf(cmd, sizeof cmd, "src=$(cd '%s' && pwd) && cd '%s/repo' && PM_SRC=$src %s sh -c "
             "'. \"$PM_SRC/scripts/commit-stamp.sh\"; commit_stamp \"%s/repo\" \"%s/bin/render\"; "
             "echo \"rc=$?\"' 2>&1", pm_test_source_dir(), d, env, d, d);
    return pm_test_run(cmd, out, cap);
}

/* Oracle: the binary's commit as the test made it. A repository with sources (photonmap/,
 * render/, the Makefile) and a results file, all committed, and a "binary" whose time is after
 * theirs: the stamp is HEAD exactly, also after the results file changes (results are not
 * sources: the old stamp, taken after writing results, always read "uncommitted"). A source
 * edited before the binary, or a new one: HEAD plus the uncommitted changes, counted. A
 * source newer than the binary: refused (status 1) naming it. PM_BENCH_COMMIT: its text. */
TEST(mpi_measurement_stamp_is_the_binarys_commit) {
    char out[4096], cmd[4096], head[64];
    const char *d = pm_test_tmpdir();
    if (pm_test_run("command -v git", out, sizeof out) != 0) SKIP("git not found");
    snprintf(cmd, sizeof cmd,
             "cd '%s' && mkdir -p repo/photonmap repo/render repo/docs bin && cd repo && "
             "echo a > photonmap/a.c && echo b > render/b.c && echo m > Makefile && echo r > docs/r.csv && "
             "git init -q . && git add . && git -c user.name=t -c user.email=t@example.com commit -q -m x && "
             "touch -d @1600000000 photonmap/a.c render/b.c Makefile docs/r.csv && "
             "printf '#!/bin/sh\\n' > ../bin/render && touch -d @1600000100 ../bin/render && "
             "git rev-parse --short HEAD", d);
    ASSERT_EQ_INT(pm_test_run(cmd, head, sizeof head), 0);
    head[strcspn(head, "\n")] = 0;
    char want[256];
    snprintf(want, sizeof want, "%s\nrc=0\n", head);
    stamp_of("", out, sizeof out);
    EXPECT_MSG(strcmp(out, want) == 0, "clean: got '%s', want '%s'", out, want);
    snprintf(cmd, sizeof cmd, "cd '%s/repo' && echo new >> docs/r.csv", d); /* a result, now */
    pm_test_run(cmd, out, sizeof out);
    stamp_of("", out, sizeof out);
    EXPECT_MSG(strcmp(out, want) == 0, "results changed: got '%s', want '%s'", out, want);
    snprintf(cmd, sizeof cmd, "cd '%s/repo' && echo c >> render/b.c && touch -d @1600000050 render/b.c", d);
    pm_test_run(cmd, out, sizeof out);
    snprintf(want, sizeof want, "%s plus uncommitted changes in the sources (1 file in photonmap/, "
             "render/ or the Makefile)\nrc=0\n", head);
    stamp_of("", out, sizeof out);
    EXPECT_MSG(strcmp(out, want) == 0, "edited source: got '%s', want '%s'", out, want);
    snprintf(cmd, sizeof cmd, "cd '%s/repo' && echo h > render/c.h && touch -d @1600000050 render/c.h", d);
    pm_test_run(cmd, out, sizeof out);
    snprintf(want, sizeof want, "%s plus uncommitted changes in the sources (2 files in photonmap/, "
             "render/ or the Makefile)\nrc=0\n", head);
    stamp_of("", out, sizeof out);
    EXPECT_MSG(strcmp(out, want) == 0, "new source: got '%s', want '%s'", out, want);
    snprintf(cmd, sizeof cmd, "cd '%s/repo' && touch -d @1600000200 photonmap/a.c", d);
    pm_test_run(cmd, out, sizeof out);
    stamp_of("", out, sizeof out);
    EXPECT_MSG(strstr(out, "is older than 1 source file(s) of the checkout (photonmap/a.c)") &&
               strstr(out, "rc=1\n") && !strstr(out, head),
               "a source newer than the binary: got '%s'", out);
    stamp_of("PM_BENCH_COMMIT='c0ffee0 (clean export)'", out, sizeof out);
    EXPECT_MSG(strcmp(out, "c0ffee0 (clean export)\nrc=0\n") == 0, "PM_BENCH_COMMIT: got '%s'", out);
}

/* Oracle: the scripts take the stamp before anything else. Binaries older than every source
 * file of this checkout (a stale build) make mpi-scaling.sh, media-results.sh and
 * media-time-error.sh exit 2 with commit-stamp's reason, before running a binary (these ones
 * would fail) or creating mpi-scaling's output directory. */
TEST(mpi_measurement_scripts_refuse_a_stale_binary) {
    char out[8192], cmd[4096];
    const char *d = pm_test_tmpdir();
    if (pm_test_run("command -v git", out, sizeof out) != 0) SKIP("git not found");
    snprintf(cmd, sizeof cmd, "git -C '%s' rev-parse --short HEAD", pm_test_source_dir());
    if (pm_test_run(cmd, out, sizeof out) != 0) SKIP("the source tree is not a git checkout");
    snprintf(cmd, sizeof cmd,
             "mkdir '%s/old' && for b in render render-mpi; do printf '#!/bin/sh\\nexit 1\\n' > '%s/old/'$b && "
             "chmod +x '%s/old/'$b && touch -d @946684800 '%s/old/'$b; done", d, d, d, d);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    static const char *const runs[] = {"mpi-scaling.sh --memory OUT", "media-results.sh --no-doc",
                                       "media-time-error.sh cornell_fog"};
    for (int i = 0; i < 3; i++) {
        char args[256];
        snprintf(args, sizeof args, "%s", runs[i]);
        char *o = strstr(args, "OUT");
        if (o) snprintf(o, sizeof args - (size_t)(o - args), "'%s/out'", d);
        snprintf(cmd, sizeof cmd, "src=$(cd '%s' && pwd) && cd '%s' && PM_BENCH_COMMIT= "
                 "PM_BUILD_DIR='%s/old' sh \"$src\"/scripts/%s 2>&1", pm_test_source_dir(), d, d, args);
        int rc = pm_test_run(cmd, out, sizeof out);
        EXPECT_MSG(rc == 2 && strstr(out, "commit-stamp: ") && strstr(out, "/old/render is older than"),
                   "%s: status %d: %s", runs[i], rc, out);
    }
    struct stat sb;
    snprintf(cmd, sizeof cmd, "%s/out", d);
    EXPECT_MSG(stat(cmd, &sb) != 0, "mpi-scaling.sh created its output directory");
}

/* ---- the media passes split over processes, without MPI -------------------------------------
 * vol_set_dist (volume.h) runs in this process: each part is a thread with its own setting,
 * and the all-gather is a barrier over shared memory. */
enum { VSPLIT_MAX = 9 };
typedef struct vsplit_world {
    int n;
    pthread_barrier_t bar;
    const void *mine[VSPLIT_MAX];
    size_t nbytes[VSPLIT_MAX];
    long calls;
} vsplit_world;
typedef struct vsplit_part {
    vsplit_world *w;
    trace_dist d;
    const scene *s;
    vol_pass_opts o;
    vol_pass_result r;
    int rc;
} vsplit_part;

static int vsplit_allgather(void *user, const void *mine, size_t nbytes, void **all, size_t *sizes) {
    vsplit_part *p = user;
    vsplit_world *w = p->w;
    w->mine[p->d.part] = mine;
    w->nbytes[p->d.part] = nbytes;
    pthread_barrier_wait(&w->bar);
    size_t total = 0;
    for (int k = 0; k < w->n; k++) total += w->nbytes[k];
    char *buf = malloc(total ? total : 1);
    for (int k = 0, off = 0; buf && k < w->n; off += (int)w->nbytes[k], k++) {
        memcpy(buf + off, w->mine[k], w->nbytes[k]);
        sizes[k] = w->nbytes[k];
    }
    if (p->d.part == 0) w->calls++;
    pthread_barrier_wait(&w->bar); /* every part copied before any frees its bytes */
    *all = buf;
    return buf ? 0 : -1;
}

static void *vsplit_main(void *arg) {
    vsplit_part *p = arg;
    vol_set_dist(&p->d);
    p->rc = vol_trace_pass(p->s, &p->o, &p->r);
    vol_set_dist(NULL);
    return NULL;
}

static int same_result(const vol_pass_result *a, const vol_pass_result *b) {
    return a->nsurface == b->nsurface && a->nvolume == b->nvolume && a->emitted == b->emitted &&
           a->surface_emitted == b->surface_emitted && a->volume_emitted == b->volume_emitted &&
           a->surface_short == b->surface_short && a->volume_short == b->volume_short &&
           a->cut == b->cut &&
           (!a->nsurface || memcmp(a->surface, b->surface, a->nsurface * sizeof *a->surface) == 0) &&
           (!a->nvolume || (memcmp(a->volume, b->volume, a->nvolume * sizeof *a->volume) == 0 &&
                            memcmp(a->volume_medium, b->volume_medium,
                                   a->nvolume * sizeof *a->volume_medium) == 0));
}

/* Oracle: the one-process pass (volume.h: a distributed pass gives its maps bit for bit).
 * cornell_fog's global pass (surface and volume maps) traced by 3 and by 9 parts (more parts
 * than a round has batches: some trace nothing), each with 1 thread, must give every part
 * the one-process result: counts, emitted counts, the short flags and every record. Also under
 * memory budgets that stop the pass (the driver's rules, top of photon_rounds.c: a batch past
 * what is left keeps its longest prefix that fits, the same in every process): at least one
 * budget must end the pass inside a batch (emitted not a multiple of PT_BATCH), and the
 * exchange must have run. */
TEST(mpi_volume_pass_split_matches_one_process) {
    scene s;
    json_err e;
    char path[2048];
    snprintf(path, sizeof path, "%s/data/scenes/cornell_fog.json", pm_test_source_dir());
    ASSERT_MSG(scene_load(&s, path, &e) == 0, "%s", e.msg);
    size_t budgets[] = {0, 3u << 20, 4u << 20, 6u << 20};
    int inside_batch = 0;
    for (size_t bi = 0; bi < sizeof budgets / sizeof budgets[0]; bi++) {
        vol_pass_opts o;
        memset(&o, 0, sizeof o);
        o.surface_target = 20000;
        o.volume_target = 60000;
        o.max_emitted = 1e7;
        o.max_memory_bytes = budgets[bi];
        o.max_depth = s.settings.max_depth;
        o.seed = s.settings.seed;
        o.threads = 1;
        o.lo = (vec3){1, 1, 1};
        o.hi = (vec3){0, 0, 0};
        vol_pass_result one;
        int rc1 = vol_trace_pass(&s, &o, &one);
        ASSERT_MSG(rc1 == 0, "one-process pass failed (%d): %s", rc1, one.msg);
        if (one.emitted % PT_BATCH) inside_batch = 1;
        int counts[] = {3, VSPLIT_MAX};
        for (size_t ci = 0; ci < 2; ci++) {
            int n = counts[ci];
            vsplit_world w;
            memset(&w, 0, sizeof w);
            w.n = n;
            pthread_barrier_init(&w.bar, NULL, (unsigned)n);
            vsplit_part parts[VSPLIT_MAX];
            pthread_t th[VSPLIT_MAX];
            for (int k = 0; k < n; k++) {
                memset(&parts[k], 0, sizeof parts[k]);
                parts[k].w = &w;
                parts[k].d.nparts = n;
                parts[k].d.part = k;
                parts[k].d.allgather = vsplit_allgather;
                parts[k].d.user = &parts[k];
                parts[k].s = &s;
                parts[k].o = o;
                pthread_create(&th[k], NULL, vsplit_main, &parts[k]);
            }
            for (int k = 0; k < n; k++) pthread_join(th[k], NULL);
            pthread_barrier_destroy(&w.bar);
            EXPECT_MSG(w.calls > 0, "budget %zu, %d parts: no exchange", budgets[bi], n);
            for (int k = 0; k < n; k++) {
                EXPECT_MSG(parts[k].rc == 0 && same_result(&one, &parts[k].r),
                           "budget %zu MiB, part %d of %d: rc %d, %zu/%zu photons from %llu emitted; "
                           "one process %zu/%zu from %llu", budgets[bi] >> 20, k, n, parts[k].rc,
                           parts[k].r.nsurface, parts[k].r.nvolume,
                           (unsigned long long)parts[k].r.emitted, one.nsurface, one.nvolume,
                           (unsigned long long)one.emitted);
                vol_pass_free(&parts[k].r);
            }
        }
        printf("    budget %zu MiB: %zu surface, %zu volume photons, %llu emitted%s\n",
               budgets[bi] >> 20, one.nsurface, one.nvolume, (unsigned long long)one.emitted,
               one.volume_short ? " (stopped short)" : "");
        vol_pass_free(&one);
    }
    EXPECT_MSG(inside_batch, "no budget ended the pass inside a batch (the 'over' case is untested)");
    scene_free(&s);
}
