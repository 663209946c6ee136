/* test_kdtree_sort.c: PM_SORT's sort (internal.h: pm__nb_sort_keys and its rank front end
 * pm__nb_sort_rank) against the C library's qsort by (dist2, index), the order kdtree.h
 * promises. No tolerance: a sorted array must equal the oracle's bit for bit.
 */
#include <float.h>

#include "internal.h"
#include "test_kdtree_util.h"

static int ref_cmp(const void *pa, const void *pb) {
    const pm_neighbor *a = pa, *b = pb;
    if (a->dist2 != b->dist2) return a->dist2 < b->dist2 ? -1 : 1;
    return a->index < b->index ? -1 : a->index > b->index;
}

static int same(const pm_neighbor *a, const pm_neighbor *b, unsigned n) {
    for (unsigned i = 0; i < n; i++) {
        uint32_t x, y;
        memcpy(&x, &a[i].dist2, sizeof x);
        memcpy(&y, &b[i].dist2, sizeof y);
        if (x != y || a[i].index != b[i].index) return 0;
    }
    return 1;
}

enum {
    SD_KNN,      /* the k nearest of uniform points in a ball: dist2 ~ u^(2/3) */
    SD_EMPTY,    /* all within 1% of each other: a query far from the data */
    SD_EQUAL,    /* all equal */
    SD_FEW,      /* 3 distinct values: many ties */
    SD_ULPS,     /* one value and its neighbours 1..3 ulps away: ties after any rounding */
    SD_INF,      /* k-NN values with +inf among them (an overflowed float dist2) */
    SD_ALLINF,   /* all +inf */
    SD_ZEROS,    /* 0, denormals and tiny normals */
    SD_RANGE,    /* 1e-30 .. 1e30 */
    SD_N
};

static void fill(kt_rng *r, int dist, pm_neighbor *a, unsigned n) {
    float base = 1e-3f * (0.5f + kt_uniform(r));
    for (unsigned i = 0; i < n; i++) {
        float u = kt_uniform(r), d;
        switch (dist) {
        default:
        case SD_KNN: d = base * powf(u, 2.0f / 3.0f); break;
        case SD_EMPTY: d = base * (1.0f + 0.01f * u); break;
        case SD_EQUAL: d = base; break;
        case SD_FEW: d = base * (float)(kt_next(r) % 3); break;
        case SD_ULPS: {
            d = base;
            for (uint64_t s = kt_next(r) % 4; s > 0; s--) d = nextafterf(d, INFINITY);
            break;
        }
        case SD_INF: d = kt_next(r) % 8 == 0 ? INFINITY : base * powf(u, 2.0f / 3.0f); break;
        case SD_ALLINF: d = INFINITY; break;
        case SD_ZEROS: {
            uint64_t c = kt_next(r) % 4;
            d = c == 0 ? 0.0f : c == 1 ? FLT_MIN * u : c == 2 ? FLT_MIN * 4.0f * u : FLT_MIN;
            break;
        }
        case SD_RANGE: d = powf(10.0f, -30.0f + 60.0f * u); break;
        }
        a[i].dist2 = d;
        /* distinct indices, the high bit set in some (an unsigned order, not a signed one) */
        a[i].index = (uint32_t)(kt_next(r) & 0xffffff00u) | i;
    }
    if (kt_next(r) & 1) pm__heapify(a, n); /* a full k-NN heap, or traversal order */
}

/* Oracle: qsort by (dist2, index). pm__nb_sort_keys (what PM_SORT runs for up to
 * PM__SORT_KEYS_MAX results) must give the same array for every n from 0 to 256 and every
 * distribution above: random, empty-space, all equal, many ties, 1-ulp near-ties, +inf among
 * them and all +inf, zeros and denormals, a 60-decade range; heap order and arbitrary order. */
TEST(kdtree_sort_matches_qsort) {
    kt_rng r = {20261202};
    pm_neighbor a[256], b[256];
    int reps = PM_TEST_SANITIZED ? 2 : 12, bad = 0;
    for (unsigned n = 0; n <= PM__SORT_KEYS_MAX && !bad; n++)
        for (int dist = 0; dist < SD_N && !bad; dist++)
            for (int rep = 0; rep < reps && !bad; rep++) {
                fill(&r, dist, a, n);
                memcpy(b, a, n * sizeof *a);
                if (n) qsort(b, n, sizeof *b, ref_cmp);
                pm__nb_sort_keys(a, n);
                if (!same(a, b, n)) {
                    EXPECT_MSG(0, "n = %u, distribution %d: differs from qsort", n, dist);
                    bad = 1;
                }
            }
}

#if defined(__SSE2__)
/* Oracle: qsort by (dist2, index), and the contract in internal.h. pm__nb_sort_rank either
 * sorts exactly as qsort does or declines and leaves the array untouched; it must decline
 * when two dist2 are equal, when all are, and when one is +inf, and it must not decline on
 * evenly spaced distinct values (their keys are at least 65535 / (n - 1) apart). On k-NN-like
 * values it must accept most arrays (the speed it exists for: internal.h says about 2% of
 * k = 50 results decline; the test allows 10% at n = 50). */
/* Both rank loops: the SSE2 one, and the AVX2 one where the CPU has it (compiled in by -mavx2
 * or chosen at run time, internal.h: RUNTIME AVX2). */
static void rank_exact_or_declines(int avx2) {
    kt_rng r = {777};
    pm_neighbor a[PM__SORT_RANK_MAX], b[PM__SORT_RANK_MAX], c[PM__SORT_RANK_MAX];
    int reps = PM_TEST_SANITIZED ? 3 : 40, bad = 0;
    long knn50 = 0, knn50_ok = 0;
    for (unsigned n = 2; n <= PM__SORT_RANK_MAX && !bad; n++)
        for (int dist = 0; dist < SD_N && !bad; dist++)
            for (int rep = 0; rep < reps && !bad; rep++) {
                fill(&r, dist, a, n);
                memcpy(c, a, n * sizeof *a);
                memcpy(b, a, n * sizeof *a);
                qsort(b, n, sizeof *b, ref_cmp);
                int ok = pm__nb_sort_rank_with(a, n, avx2);
                int tie = 0, inf = 0;
                for (unsigned i = 0; i < n; i++) {
                    if (i && b[i].dist2 == b[i - 1].dist2) tie = 1;
                    if (isinf(b[i].dist2)) inf = 1;
                }
                if (ok && !same(a, b, n)) {
                    EXPECT_MSG(0, "avx2 %d, n = %u, distribution %d: accepted, differs from qsort",
                               avx2, n, dist);
                    bad = 1;
                } else if (!ok && !same(a, c, n)) {
                    EXPECT_MSG(0, "n = %u, distribution %d: declined and changed the array", n,
                               dist);
                    bad = 1;
                } else if (ok && (tie || inf)) {
                    EXPECT_MSG(0, "n = %u, distribution %d: accepted equal or infinite dist2", n,
                               dist);
                    bad = 1;
                }
                if (dist == SD_KNN && n == 50) knn50++, knn50_ok += ok;
            }
    EXPECT_MSG(knn50_ok >= knn50 * 9 / 10, "avx2 %d: accepted %ld of %ld k-NN arrays at n = 50",
               avx2, knn50_ok, knn50);
    for (unsigned n = 2; n <= PM__SORT_RANK_MAX; n++) {
        for (unsigned i = 0; i < n; i++) { /* evenly spaced, in reverse */
            a[i].dist2 = 1.0f + (float)(n - 1 - i);
            a[i].index = i;
        }
        EXPECT_MSG(pm__nb_sort_rank_with(a, n, avx2),
                   "avx2 %d, n = %u: declined distinct, evenly spaced values", avx2, n);
        for (unsigned i = 0; i < n; i++) EXPECT(a[i].dist2 == 1.0f + (float)i);
    }
}

TEST(kdtree_sort_rank_exact_or_declines) {
    rank_exact_or_declines(0);
    if (pm__have_avx2()) rank_exact_or_declines(1);
    else printf("    this CPU has no AVX2: the SSE2 rank loop only\n");
}
#endif

static pm_kdtree *sort_build(pm_photon *ph, size_t n, unsigned B) {
    pm_kdtree *t = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(B);
    if (pm_kdtree_build(&t, ph, n, &cfg, NULL) != 0) return NULL;
    return t;
}

/* Oracle: qsort by (dist2, index) of the same search's unsorted answer. With PM_SORT the
 * k-nearest (unlimited and with a radius) and the radius search return exactly that array, for
 * k = 1..256, on uniform points, points with duplicated positions (exact ties), and queries
 * so far away that every float dist2 overflows to +inf (then all tie, and the order is by
 * index). Queries at a record's position give dist2 = +0.0, never -0.0. */
TEST(kdtree_sorted_results_are_qsort_of_unsorted) {
    const size_t N = 4000;
    pm_photon *ph = calloc(N, sizeof *ph);
    pm_neighbor *u = malloc(600 * sizeof *u), *s = malloc(600 * sizeof *s);
    ASSERT(ph && u && s);
    kt_rng r = {4242};
    for (int dist = 0; dist < 2; dist++) {
        int kind = dist ? KT_DUPS : KT_UNIFORM;
        for (size_t i = 0; i < N; i++) kt_point(&r, kind, i, N, ph[i].pos);
        pm_kdtree *t = sort_build(ph, N, 8);
        ASSERT(t);
        for (int qi = 0; qi < 60; qi++) {
            float q[3];
            if (qi % 6 == 5) { /* every dist2 overflows */
                q[0] = 3e19f, q[1] = -3e19f, q[2] = 3e19f;
            } else if (qi % 6 == 4) { /* at a record */
                memcpy(q, pm_kdtree_pos(t, (uint32_t)(kt_next(&r) % N)), sizeof q);
            } else {
                q[0] = kt_uniform(&r), q[1] = kt_uniform(&r), q[2] = kt_uniform(&r);
            }
            unsigned k = 1 + (unsigned)(kt_next(&r) % 256);
            float r2 = qi & 1 ? INFINITY : 0.002f + 0.02f * kt_uniform(&r);
            int nu = pm_kdtree_knn(t, q, k, r2, u, 0, NULL);
            int ns = pm_kdtree_knn(t, q, k, r2, s, PM_SORT, NULL);
            ASSERT(nu >= 0 && nu == ns);
            if (nu) qsort(u, (size_t)nu, sizeof *u, ref_cmp);
            EXPECT_MSG(same(u, s, (unsigned)nu), "knn: query %d, k = %u, %d found", qi, k, nu);
            for (int i = 0; i < ns; i++) EXPECT(!signbit(s[i].dist2));
            if (qi % 6 == 5) EXPECT(ns > 0 && isinf(s[0].dist2));
            if (qi % 6 == 5) continue; /* the radius search needs a finite radius */
            float rr = 0.001f + 0.004f * kt_uniform(&r);
            long cu = pm_kdtree_radius(t, q, rr, u, 600, 0, NULL);
            long cs = pm_kdtree_radius(t, q, rr, s, 600, PM_SORT, NULL);
            ASSERT(cu == cs && cu >= 0);
            if (cu > 600) continue; /* not all fit: unsorted by contract */
            if (cu) qsort(u, (size_t)cu, sizeof *u, ref_cmp);
            EXPECT_MSG(same(u, s, (unsigned)cu), "radius: query %d, %ld found", qi, cu);
        }
        pm_kdtree_free(t);
    }
    free(ph);
    free(u);
    free(s);
}
