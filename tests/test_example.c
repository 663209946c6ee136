/* test_example.c: the example program that `make test` builds against the installed library
 * (photonmap/examples/knn_example.c, via pkg-config on a staged `make install`), run.
 *
 * Oracle: the analytic flux density of its scene. It stores N = 100000 photons uniformly on
 * the unit square, each of power (1e-5, 1e-5, 0.8e-5), so the true density is (1, 1, 0.8);
 * a 50-photon disc estimate has a relative noise of about 1/sqrt(50) = 14%, and the program
 * is deterministic, so the printed density must be within 30% of 1 (about 2 sigma), and the
 * third channel 0.8 of the first within the RGBE rounding (2^-8 of each photon, 1% here).
 * Building is checked by the Makefile; this checks that what was built works.
 */
#include <stdio.h>
#include <string.h>

#include "test.h"

TEST(example_program_runs_against_installed_library) {
    char cmd[2048], out[4096];
    snprintf(cmd, sizeof cmd, "%s/example/knn_example", pm_test_build_dir());
    FILE *f = fopen(cmd, "rb");
    ASSERT_MSG(f != NULL, "%s was not built (make example)", cmd);
    fclose(f);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    int found = 0;
    double d[3] = {0, 0, 0};
    const char *p = strstr(out, "found ");
    ASSERT_MSG(p && sscanf(p, "found %d photons", &found) == 1, "%s", out);
    EXPECT_EQ_INT(found, 50);
    p = strstr(out, "flux density ");
    ASSERT_MSG(p && sscanf(p, "flux density %lf %lf %lf", &d[0], &d[1], &d[2]) == 3, "%s", out);
    EXPECT_NEAR(d[0], 1.0, 0.3);
    EXPECT_REL(d[1], d[0], 1e-6);
    EXPECT_REL(d[2], 0.8 * d[0], 0.01);
    snprintf(cmd, sizeof cmd, "%s/example/knn_example --help", pm_test_build_dir());
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "usage: knn_example") != NULL, "%s", out);
}
