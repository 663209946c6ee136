/* test_alloc.c: "queries never allocate", counted.
 *
 * kdtree.h, estimate.h (README: "nothing allocates"), irradiance.h and combined.h promise that
 * queries and estimates on a built tree never allocate. This file interposes the allocator for
 * the test runner: it defines malloc, calloc, realloc, free, aligned_alloc, posix_memalign and
 * memalign, which forward to glibc's own (__libc_malloc and friends) and, while the calling
 * thread has counting switched on, count each allocation. The library is linked statically
 * into the runner, so its calls come here. Only the thread that switched counting on is
 * counted (other threads, and the runner's own bookkeeping, are not).
 *
 * Under a sanitizer (PM_TEST_SANITIZED) the sanitizer's runtime owns the allocator: nothing is
 * interposed and the count test is a SKIP with that reason. Elsewhere than glibc, likewise.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "combined.h"
#include "estimate.h"
#include "irradiance.h"
#include "kdtree.h"
#include "photon.h"

#if !PM_TEST_SANITIZED && defined(__GLIBC__)
#define ALLOC_COUNTING 1
extern void *__libc_malloc(size_t);
extern void *__libc_calloc(size_t, size_t);
extern void *__libc_realloc(void *, size_t);
extern void *__libc_memalign(size_t, size_t);
extern void __libc_free(void *);

static _Thread_local int t_counting;
static _Thread_local unsigned long t_allocs;

void *malloc(size_t n) {
    if (t_counting) t_allocs++;
    return __libc_malloc(n);
}
void *calloc(size_t a, size_t b) {
    if (t_counting) t_allocs++;
    return __libc_calloc(a, b);
}
void *realloc(void *p, size_t n) {
    if (t_counting) t_allocs++;
    return __libc_realloc(p, n);
}
void free(void *p) { __libc_free(p); }
void *memalign(size_t align, size_t n) {
    if (t_counting) t_allocs++;
    return __libc_memalign(align, n);
}
void *aligned_alloc(size_t align, size_t n) {
    if (t_counting) t_allocs++;
    return __libc_memalign(align, n);
}
int posix_memalign(void **out, size_t align, size_t n) {
    if (t_counting) t_allocs++;
    if (align < sizeof(void *) || (align & (align - 1)) != 0) return EINVAL;
    void *p = __libc_memalign(align, n);
    if (!p) return ENOMEM;
    *out = p;
    return 0;
}
#else
#define ALLOC_COUNTING 0
#endif

static uint64_t rng_next(uint64_t *s) {
    *s += 0x9E3779B97F4A7C15ull;
    uint64_t z = *s;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
static float rng_unit(uint64_t *s) { return (float)(rng_next(s) >> 40) * 0x1p-24f; }

static int accept_even(void *user, const void *record, uint32_t index) {
    (void)user, (void)record;
    return (index & 1) == 0;
}
static int visit_count(void *user, uint32_t index, float dist2) {
    (void)index, (void)dist2;
    ++*(long *)user;
    return 0;
}
static int irr_accept_all(void *user, uint32_t photon, const float pos[3], const float normal[3]) {
    (void)user, (void)photon, (void)pos, (void)normal;
    return 1;
}

/* Oracle: the count of the interposed allocator, which must be 0 across every query and
 * estimate of a built tree: k-nearest (iterative, recursive, with the ellipsoid metric and a
 * filter), radius (listing, counting, with a callback), nearest with a predicate, every surface
 * estimator through pm_estimate and pm_estimate_core, the volume estimate, the combined estimate
 * of two maps and the irradiance lookups, 200 queries each on 20000 photons (k = 50). The
 * interposer is checked first: one deliberate malloc while counting must count exactly 1, so a
 * count of 0 is not an interposer that sees nothing. Exact: a single allocation fails. */
TEST(queries_and_estimates_never_allocate) {
#if !ALLOC_COUNTING
    SKIP("a sanitizer (or a libc other than glibc) owns malloc here: allocations are not counted");
#else
    enum { N = 20000, K = 50, Q = 200 };
    uint64_t s = 2027;
    pm_photon *ph = malloc(sizeof *ph * N), *ph2 = malloc(sizeof *ph2 * N);
    ASSERT(ph && ph2);
    for (int i = 0; i < N; i++) {
        float pos[3] = {rng_unit(&s), rng_unit(&s), 0.02f * rng_unit(&s)}, pw[3] = {1e-4f, 2e-4f, 3e-4f};
        float dir[3] = {0.3f * (rng_unit(&s) - 0.5f), 0.3f * (rng_unit(&s) - 0.5f), -1}, up[3] = {0, 0, 1};
        pm_photon_init(&ph[i], pos, pw, dir, up, PM_KIND_INDIRECT);
        pos[0] = rng_unit(&s), pos[1] = rng_unit(&s);
        pm_photon_init(&ph2[i], pos, pw, dir, up, PM_KIND_DIRECT);
    }
    pm_kdtree *t = NULL, *t2 = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(8);
    ASSERT_EQ_INT(pm_kdtree_build(&t, ph, N, &cfg, NULL), PM_OK);
    ASSERT_EQ_INT(pm_kdtree_build(&t2, ph2, N, &cfg, NULL), PM_OK);
    pm_irradiance *irr = NULL;
    pm_irradiance_options io;
    pm_irradiance_options_init(&io, K);
    io.store_index = 1; /* for pm_irradiance_lookup_if */
    ASSERT_EQ_INT(pm_irradiance_build(&irr, t, &io), PM_OK);
    void *scratch = malloc(pm_estimate_scratch_bytes(K));
    pm_neighbor *nb = malloc(sizeof *nb * 4 * K);
    ASSERT(scratch && nb);
    const pm_kdtree *both[2] = {t, t2};
    const float up[3] = {0, 0, 1};

    /* the interposer sees this thread's allocations */
    void *(*volatile m)(size_t) = malloc;
    t_allocs = 0;
    t_counting = 1;
    void *probe = m(24);
    t_counting = 0;
    free(probe);
    ASSERT_MSG(t_allocs == 1, "the interposed malloc counted %lu of 1 deliberate allocation", t_allocs);

    long calls = 0, total = 0;
    int bad = 0;
    t_allocs = 0;
    t_counting = 1;
    for (int qi = 0; qi < Q; qi++) {
        float q[3] = {rng_unit(&s), rng_unit(&s), 0.01f};
        float nrm[3];
        pm_knn_options ko = {up, 4.0f, accept_even, NULL, PM_SORT};
        pm_estimate_result r;
        bad += pm_kdtree_knn(t, q, K, INFINITY, nb, PM_SORT, NULL) != K;
        bad += pm_kdtree_knn_recursive(t, q, K, 0.01f, nb, 0, NULL) < 0;
        bad += pm_kdtree_knn_ex(t, q, K, INFINITY, &ko, nb, NULL) != K;
        total += pm_kdtree_radius(t, q, 0.001f, nb, 4 * K, PM_SORT, NULL);
        total += pm_kdtree_radius(t, q, 0.004f, NULL, 0, 0, NULL);
        calls += pm_kdtree_radius_cb(t, q, 0.001f, visit_count, &calls, NULL) < 0;
        bad += pm_kdtree_nearest_if(t, q, INFINITY, accept_even, NULL, nb, NULL) != 1;
        for (int kind = 0; kind < PM_EST_COUNT_; kind++) {
            pm_estimate_options o;
            pm_estimate_options_init(&o, (pm_estimator)kind, K);
            o.reject_behind = qi & 1;
            o.squash = qi & 2 ? 8.0f : 1.0f;
            bad += pm_estimate(t, q, up, &o, scratch, &r, NULL) != PM_OK;
            pm_estimate_search_options(&o, up, nrm, &ko);
            int found = pm_kdtree_knn_ex(t, q, K, o.max_dist2, &ko, nb, NULL);
            bad += found < 0 || pm_estimate_core(ph, nb, (unsigned)found, q, up, &o, scratch, &r) != PM_OK;
        }
        pm_estimate_options o;
        pm_estimate_options_init(&o, PM_EST_DISC, K);
        bad += pm_estimate_volume(t, q, 0.5, &o, scratch, &r, NULL) != PM_OK;
        double comb[3], naive[3];
        bad += pm_estimate_combined(both, 2, q, up, &o, scratch, comb, naive, NULL) != PM_OK;
        float rgb[3];
        uint32_t who;
        bad += pm_irradiance_lookup(irr, q, up, INFINITY, 0.9f, rgb, NULL) != 1;
        bad += pm_irradiance_lookup_if(irr, q, up, INFINITY, 0.9f, 4, irr_accept_all, NULL, rgb, &who, NULL) != 1;
    }
    t_counting = 0;
    unsigned long allocs = t_allocs;
    printf("    %d queries of each kind: %lu allocations (radius totals %ld, callbacks %ld)\n", Q, allocs,
           total, calls);
    EXPECT_EQ_INT(bad, 0);
    EXPECT(total > 0 && calls > 0);
    EXPECT_MSG(allocs == 0, "queries and estimates allocated %lu times", allocs);
    free(nb), free(scratch);
    pm_irradiance_free(irr);
    pm_kdtree_free(t), pm_kdtree_free(t2);
    free(ph), free(ph2);
#endif
}
