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
    ASSERT_MSG(strstr(out, "0 passed, 1 failed") != NULL, "runner printed: %s", out);
}

TEST(harness_always_fails_inner) {
    /* Only meaningful when run by runner_reports_failures; passes when run normally. */
    if (getenv("PM_TEST_INNER")) ASSERT_MSG(0, "deliberate failure (inner run)");
}
