/* test_mpi.c: the distributed renderer's checks that belong in `make test`.
 *
 * The full suite of render-mpi (every rank count, failures, killed ranks) is
 * scripts/test-mpi.sh (`make MPI=1 test-mpi`, run by .ci/run). Here: the default build stays
 * free of MPI, docs/MPI.md regenerates from its measurements, and, when render-mpi was built
 * into this build directory (make MPI=1), one quick bit-identity check and one quick check
 * of partitioned maps; without it those tests are skipped.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "test.h"

/* Oracle: the promise of the build. No file the default build compiles includes mpi.h (only
 * render/mpi/ does), and the default render binary does not link an MPI library. */
TEST(mpi_default_build_needs_no_mpi) {
    char cmd[4096], out[4096];
    snprintf(cmd, sizeof cmd, "cd '%s' && grep -l '^#include <mpi[.]h>' photonmap/*.c photonmap/*.h "
             "render/*.c render/*.h bench/*.c tests/*.c 2>/dev/null; true", pm_test_source_dir());
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
