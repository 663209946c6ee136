/* test_common.c: error codes and the test harness itself. */
#include <stdlib.h>
#include <string.h>
#include "test.h"
#include "common.h"

/* Oracle: the documented list of codes; each has its own message, and unknown ones are named so. */
TEST(strerror_names_every_code) {
    const int codes[] = {PM_OK, PM_EINVAL, PM_ENOMEM, PM_ENONFINITE, PM_EIO,
                         PM_EFORMAT, PM_EVERSION, PM_ERANGE, PM_EEMPTY};
    const int n = (int)(sizeof codes / sizeof codes[0]);
    for (int i = 0; i < n; i++) {
        ASSERT(pm_strerror(codes[i]) != NULL);
        ASSERT(strcmp(pm_strerror(codes[i]), "unknown error code") != 0);
        for (int j = 0; j < i; j++) ASSERT(strcmp(pm_strerror(codes[i]), pm_strerror(codes[j])) != 0);
    }
    ASSERT(strcmp(pm_strerror(-999), "unknown error code") == 0);
}

/* The runner must report a failing child as a failure: run ourselves on a test that fails. */
TEST(runner_reports_failures) {
    char out[4096], cmd[1024];
    if (getenv("PM_TEST_INNER")) return;
    snprintf(cmd, sizeof cmd, "PM_TEST_INNER=1 %s/run_tests harness_always_fails_inner", pm_test_build_dir());
    int rc = pm_test_run(cmd, out, sizeof out);
    ASSERT_EQ_INT(rc, 1);
    ASSERT_MSG(strstr(out, "\n0 passed, 1 failed, 0 skipped\n") != NULL, "runner printed: %s", out);
    /* Without PM_TEST_INNER the fixtures are not tests: not run, not listed, not counted. */
    snprintf(cmd, sizeof cmd, "env -u PM_TEST_INNER %s/run_tests harness_", pm_test_build_dir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strcmp(out, "0 passed, 0 failed, 0 skipped\n") == 0, "runner printed: %s", out);
    snprintf(cmd, sizeof cmd, "env -u PM_TEST_INNER %s/run_tests --list harness_", pm_test_build_dir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(out[0] == 0, "--list printed: %s", out);
}

FIXTURE(harness_always_fails_inner) {
    ASSERT_MSG(0, "deliberate failure (inner run)");
}

/* Oracle: the runner's documented output. A test that calls SKIP is counted as skipped (not
 * passed, not failed) and listed with its reason; SKIP after a failure still fails; the exit
 * status is 0 when nothing failed; -x leaves matching tests out. */
TEST(runner_reports_skips) {
    char out[4096], cmd[1024];
    if (getenv("PM_TEST_INNER")) return;
    snprintf(cmd, sizeof cmd, "PM_TEST_INNER=1 %s/run_tests harness_skips_inner strerror_names",
             pm_test_build_dir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "SKIP harness_skips_inner") != NULL, "runner printed: %s", out);
    EXPECT_MSG(strstr(out, "skipped:\n  harness_skips_inner (no such tool here)\n"), "runner printed: %s", out);
    EXPECT_MSG(strstr(out, "\n1 passed, 0 failed, 1 skipped\n") != NULL, "runner printed: %s", out);

    snprintf(cmd, sizeof cmd, "PM_TEST_INNER=1 %s/run_tests harness_fails_then_skips_inner",
             pm_test_build_dir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 1);
    EXPECT_MSG(strstr(out, "\n0 passed, 1 failed, 0 skipped\n") != NULL, "runner printed: %s", out);

    snprintf(cmd, sizeof cmd, "PM_TEST_INNER=1 %s/run_tests -x skips harness_ strerror_names",
             pm_test_build_dir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 1);
    EXPECT_MSG(strstr(out, "\n1 passed, 1 failed, 0 skipped\n") != NULL, "runner printed: %s", out);
    EXPECT_MSG(strstr(out, "harness_skips_inner") == NULL, "-x did not exclude: %s", out);
}

/* Oracle: the documented --times/--quick rules. A test recorded above 1 CPU-second is left
 * out and named; a quick one runs; the file is rewritten with the new measurement beside the
 * old ones it did not replace. */
TEST(runner_quick_leaves_out_recorded_slow_tests) {
    char out[4096], cmd[2048], path[1024];
    if (getenv("PM_TEST_INNER")) return;
    snprintf(path, sizeof path, "%s/times.txt", pm_test_tmpdir());
    FILE *f = fopen(path, "w");
    ASSERT(f != NULL);
    fprintf(f, "strerror_names_every_code 5.000 0.100\nharness_skips_inner 0.010 0.020\n");
    fclose(f);
    snprintf(cmd, sizeof cmd, "PM_TEST_INNER=1 %s/run_tests --times %s --quick strerror_names harness_skips_inner",
             pm_test_build_dir(), path);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "  strerror_names_every_code (5.0 CPU-s, 0.1 s)\n"), "runner printed: %s", out);
    EXPECT_MSG(strstr(out, "\n0 passed, 0 failed, 1 skipped\n") != NULL, "runner printed: %s", out);
    snprintf(cmd, sizeof cmd, "cat %s", path);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "strerror_names_every_code 5.000 0.100\n"), "times file: %s", out);
    EXPECT_MSG(strstr(out, "harness_skips_inner ") && !strstr(out, "harness_skips_inner 0.010 0.020"),
               "times file not updated: %s", out);
}

/* The fixtures of the runner's tests above: run only in their inner runs (PM_TEST_INNER). */
FIXTURE(harness_skips_inner) {
    SKIP("no such tool here");
}

FIXTURE(harness_fails_then_skips_inner) {
    EXPECT_MSG(0, "deliberate failure (inner run)");
    SKIP("too late: it failed already");
}
