/* test.h: the small test framework every tests/test_*.c uses.
 *
 * A test is a function declared with TEST(name) { ... }. It registers itself at program start
 * (a constructor), so adding a test means adding a function, nothing else. The runner
 * (tests/runner.c) runs each test in a forked child with a time limit, so a crash or a hang
 * fails that test alone, and prints one line per test and, last,
 * "N passed, N failed, N skipped".
 *
 * Assertions:
 *   ASSERT(cond)                 fail and return from the test if cond is false
 *   ASSERT_EQ_INT(a, b)          integers equal
 *   ASSERT_NEAR(a, b, tol)       |a - b| <= tol (absolute); NaN always fails
 *   ASSERT_REL(a, b, rtol)       |a - b| <= rtol * |b| (relative to the expected b)
 *   EXPECT*(...)                 the same, but record the failure and go on
 *   ASSERT_MSG(cond, fmt, ...)   with a printf-style explanation
 *   SKIP("reason")               this test cannot run here (a tool is missing): return, and
 *                                count it as skipped, not passed (unless it already failed)
 * In a helper function that is not the test body, use EXPECT* (they do not return) and
 * check pm_test_failed() afterwards if needed.
 *
 * Every test checks values against an oracle (brute force, an analytic answer or a long
 * reference) with a stated tolerance: say which in a comment above the test.
 *
 * FIXTURE(name) { ... } declares a body the runner's own tests run in an inner runner (a test
 * that fails or skips on purpose). It is not a test: the runner leaves it out, unlisted and
 * uncounted, unless PM_TEST_INNER is set in the environment.
 *
 * Helpers: pm_test_build_dir() is the build directory (binaries: render, bench_*, the example),
 * pm_test_source_dir() the repository root, pm_test_tmpdir() a fresh directory for this test.
 */
#ifndef PM_TEST_H
#define PM_TEST_H

#include <math.h>
#include <stdio.h>
#include <stdint.h>

/* 1 in a sanitizer build (ASan/UBSan): tests may shrink their problem sizes, keeping the same
 * oracle and tolerance, so that `make test SANITIZE=address,undefined` stays fast. */
#if defined(__SANITIZE_ADDRESS__) || defined(PM_SANITIZED)
#define PM_TEST_SANITIZED 1
#else
#define PM_TEST_SANITIZED 0
#endif

typedef void (*pm_test_fn)(void);
void pm_test_register(const char *name, const char *file, pm_test_fn fn);
void pm_test_register_fixture(const char *name, const char *file, pm_test_fn fn);
void pm_test_fail(const char *file, int line, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
int pm_test_failed(void);
/* What SKIP calls; the child then exits with PM_TEST_SKIP_STATUS (the automake convention). */
void pm_test_skip(const char *reason);
#define PM_TEST_SKIP_STATUS 77
const char *pm_test_build_dir(void);
const char *pm_test_source_dir(void);
const char *pm_test_tmpdir(void);
/* Permission cases (a directory without write permission) mean nothing to root, who writes
 * anyway. pm_test_unprivileged runs fn(arg) in a forked child as this user when it is not root,
 * and as root after dropping to nobody (uid and gid 65534, no supplementary groups); it returns
 * the number of failures the child recorded (0: it passed), or -1 with the reason in why when
 * the privileges cannot be dropped (then SKIP). pm_test_unprivileged_prefix is the same for a
 * shell command: "" when not root, else a setpriv prefix that runs the command as nobody, or
 * NULL with the reason. Files the unprivileged side must reach need o+x on every directory
 * above them (pm_test_tmpdir() is 0700: chmod it). */
#define PM_TEST_NOBODY 65534
int pm_test_unprivileged(void (*fn)(void *), void *arg, char *why, size_t cap);
const char *pm_test_unprivileged_prefix(char *why, size_t cap);
/* Run a shell command, capturing combined stdout+stderr into buf (NUL-terminated, truncated
 * to cap). Returns the exit status (0..255), or -1 if it could not run or was killed. */
int pm_test_run(const char *cmd, char *buf, size_t cap);

#define TEST(name)                                                                   \
    static void name(void);                                                          \
    __attribute__((constructor)) static void name##__register(void) {                \
        pm_test_register(#name, __FILE__, name);                                     \
    }                                                                                \
    static void name(void)

#define FIXTURE(name)                                                                \
    static void name(void);                                                          \
    __attribute__((constructor)) static void name##__register(void) {                \
        pm_test_register_fixture(#name, __FILE__, name);                             \
    }                                                                                \
    static void name(void)

#define PM__CHECK(cond, onfail, ...)                                                 \
    do {                                                                             \
        if (!(cond)) {                                                               \
            pm_test_fail(__FILE__, __LINE__, __VA_ARGS__);                           \
            onfail;                                                                  \
        }                                                                            \
    } while (0)

#define SKIP(reason)                                                                 \
    do {                                                                             \
        pm_test_skip(reason);                                                        \
        return;                                                                      \
    } while (0)

#define ASSERT(cond) PM__CHECK(cond, return, "%s", #cond)
#define EXPECT(cond) PM__CHECK(cond, (void)0, "%s", #cond)
#define ASSERT_MSG(cond, ...) PM__CHECK(cond, return, __VA_ARGS__)
#define EXPECT_MSG(cond, ...) PM__CHECK(cond, (void)0, __VA_ARGS__)

#define PM__EQ_INT(a, b, onfail)                                                     \
    do {                                                                             \
        long long pm__a = (long long)(a), pm__b = (long long)(b);                    \
        PM__CHECK(pm__a == pm__b, onfail, "%s == %s (%lld vs %lld)", #a, #b, pm__a,  \
                  pm__b);                                                            \
    } while (0)
#define ASSERT_EQ_INT(a, b) PM__EQ_INT(a, b, return)
#define EXPECT_EQ_INT(a, b) PM__EQ_INT(a, b, (void)0)

#define PM__NEAR(a, b, tol, onfail)                                                  \
    do {                                                                             \
        double pm__a = (double)(a), pm__b = (double)(b), pm__t = (double)(tol);      \
        PM__CHECK(fabs(pm__a - pm__b) <= pm__t, onfail, "%s ~ %s: %.9g vs %.9g (tol %g)", \
                  #a, #b, pm__a, pm__b, pm__t);                                      \
    } while (0)
#define ASSERT_NEAR(a, b, tol) PM__NEAR(a, b, tol, return)
#define EXPECT_NEAR(a, b, tol) PM__NEAR(a, b, tol, (void)0)

#define PM__REL(a, b, rtol, onfail)                                                  \
    do {                                                                             \
        double pm__a = (double)(a), pm__b = (double)(b), pm__t = (double)(rtol);     \
        PM__CHECK(fabs(pm__a - pm__b) <= pm__t * fabs(pm__b), onfail,                \
                  "%s ~ %s: %.9g vs %.9g (rel err %.3g, tol %g)", #a, #b, pm__a, pm__b, \
                  pm__b != 0 ? fabs(pm__a - pm__b) / fabs(pm__b) : INFINITY, pm__t); \
    } while (0)
#define ASSERT_REL(a, b, rtol) PM__REL(a, b, rtol, return)
#define EXPECT_REL(a, b, rtol) PM__REL(a, b, rtol, (void)0)

/* A tiny deterministic generator of test data (splitmix64), the same stream on every machine:
 * pm_test_rng r = {seed}; pm_test_next(&r) is its next 64 bits, pm_test_unit(&r) uniform in
 * [0, 1) with 53 bits (test_kdtree_util.h's kt_rng draws from the same step). */
typedef struct {
    uint64_t s;
} pm_test_rng;
static inline uint64_t pm_test_next(pm_test_rng *r) {
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
static inline double pm_test_unit(pm_test_rng *r) { return (double)(pm_test_next(r) >> 11) * 0x1p-53; }

#endif /* PM_TEST_H */
