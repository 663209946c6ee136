/* test_kdtree_ties.c: kdtree.h's tie rule, exactly. Among records at equal dist2 the smaller
 * record index wins, so the k nearest are the k smallest (dist2, index) pairs with
 * dist2 < max_dist2, whatever the traversal. The oracle is a brute-force scan of the tree's
 * records (same float dist2 expression) sorted by (dist2, index) with the C library's qsort;
 * every search must return exactly its first min(k, count) pairs: the same indices, not only
 * the same distances. No tolerance.
 *
 * The data are built to tie: points of an integer lattice, each lattice point repeated one to
 * four times (exact duplicates), plus a block of identical points (a uniform subtree). Queries
 * sit on lattice points, cell centres, face and edge midpoints (8, 4 and 2 lattice points at
 * one distance, times their duplicates), on the identical block, and at random; the radius is
 * unlimited or exactly a lattice distance (strict: the records at that distance are out). k
 * runs across every result set: kdtree_query.c's 16-slot set (k <= 16) and blocked set
 * (16 < k <= 64) and internal.h's heap above (builds without SSE2 use internal.h's sorted
 * array for k <= 16 and its heap above).
 */
#include <stdio.h>

#include "internal.h"
#include "test_kdtree_util.h"

static int tie_cmp(const void *pa, const void *pb) {
    const pm_neighbor *a = pa, *b = pb;
    if (a->dist2 != b->dist2) return a->dist2 < b->dist2 ? -1 : 1;
    return a->index < b->index ? -1 : a->index > b->index;
}

/* The oracle: all records with dist2 < r2 (every one when r2 is +inf), sorted by (dist2,
 * index); an optional predicate on the index (the filter of knn_ex). Returns the count. */
static size_t tie_oracle(const pm_kdtree *t, const float q[3], float r2, int odd_only,
                         pm_neighbor *o) {
    size_t n = pm_kdtree_size(t), c = 0;
    for (size_t i = 0; i < n; i++) {
        if (odd_only && !(i & 1)) continue;
        const float *p = pm_kdtree_pos(t, (uint32_t)i);
        float dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
        float d2 = dx * dx + dy * dy + dz * dz;
        if (isinf(r2) || d2 < r2) {
            o[c].dist2 = d2;
            o[c].index = (uint32_t)i;
            c++;
        }
    }
    qsort(o, c, sizeof *o, tie_cmp);
    return c;
}

static int odd_filter(void *user, const void *record, uint32_t index) {
    (void)user, (void)record;
    return (int)(index & 1);
}

/* got[0..g) (any order unless `sorted`) must be exactly want[0..min(k, c)). */
static int tie_same(const pm_neighbor *got, int g, int sorted, const pm_neighbor *want,
                    size_t c, unsigned k, const char *what) {
    size_t m = c < k ? c : k;
    if (g != (int)m) {
        EXPECT_MSG(0, "%s: %d found, the oracle %zu", what, g, m);
        return 0;
    }
    pm_neighbor s[512];
    memcpy(s, got, m * sizeof *s);
    if (!sorted) qsort(s, m, sizeof *s, tie_cmp);
    for (size_t i = 0; i < m; i++)
        if (s[i].index != want[i].index || s[i].dist2 != want[i].dist2) {
            EXPECT_MSG(0, "%s: entry %zu is (%g, %u), the oracle's (%g, %u)", what, i,
                       (double)s[i].dist2, s[i].index, (double)want[i].dist2, want[i].index);
            return 0;
        }
    return 1;
}

#define TIE_G 6      /* lattice points per axis */
#define TIE_SAME 300 /* identical points */

TEST(kdtree_ties_smallest_index_wins) {
    /* lattice points with 1..4 copies each, then the identical block, shuffled */
    kt_rng r = {4242};
    size_t cap = TIE_G * TIE_G * TIE_G * 4 + TIE_SAME, n = 0;
    pm_photon *ph = calloc(cap, sizeof *ph);
    pm_neighbor *want = malloc(cap * sizeof *want), got[512], got2[512];
    ASSERT(ph && want);
    for (int x = 0; x < TIE_G; x++)
        for (int y = 0; y < TIE_G; y++)
            for (int z = 0; z < TIE_G; z++) {
                int copies = 1 + (int)(kt_next(&r) % 4);
                for (int c = 0; c < copies; c++) {
                    ph[n].pos[0] = (float)x, ph[n].pos[1] = (float)y, ph[n].pos[2] = (float)z;
                    n++;
                }
            }
    for (int i = 0; i < TIE_SAME; i++) {
        ph[n].pos[0] = 2.5f, ph[n].pos[1] = 7.0f, ph[n].pos[2] = 1.0f;
        n++;
    }
    for (size_t i = n - 1; i > 0; i--) {
        size_t j = (size_t)(kt_next(&r) % (i + 1));
        pm_photon t = ph[i];
        ph[i] = ph[j];
        ph[j] = t;
    }
    /* queries: lattice points, cell centres, face and edge midpoints, the identical block,
     * random points */
    enum { NQ = 40 };
    float qs[NQ][3];
    for (int i = 0; i < NQ; i++) {
        int kind = i % 6;
        for (int a = 0; a < 3; a++) {
            float base = (float)(kt_next(&r) % (TIE_G - 1));
            float half = kind == 1 ? 0.5f : kind == 2 ? (a == 0 ? 0.0f : 0.5f)
                         : kind == 3 ? (a == 2 ? 0.5f : 0.0f)
                                     : 0.0f;
            qs[i][a] = base + half;
            if (kind == 5) qs[i][a] = -1.0f + (float)(TIE_G + 1) * kt_uniform(&r);
        }
        if (kind == 4) qs[i][0] = 2.5f, qs[i][1] = 6.0f + (float)(i % 3), qs[i][2] = 1.0f;
    }
    static const unsigned Bs[] = {1, 3, 8, 32};
    static const unsigned ks[] = {1, 2, 5, 10, 16, 17, 50, 64, 65, 100, 301, 400};
    int bad = 0;
    for (size_t bi = 0; bi < sizeof Bs / sizeof Bs[0] && !bad; bi++) {
        pm_photon *rec = malloc(n * sizeof *rec);
        memcpy(rec, ph, n * sizeof *rec);
        pm_kdtree *t = NULL;
        pm_kdtree_config cfg = pm_kdtree_photon_config(Bs[bi]);
        ASSERT_EQ_INT(pm_kdtree_build(&t, rec, n, &cfg, NULL), 0);
        /* the same records under the generic layout (tree-owned axes): its own instance of
         * every search */
        pm_photon *rec2 = malloc(n * sizeof *rec2);
        memcpy(rec2, ph, n * sizeof *rec2);
        pm_kdtree *t2 = NULL;
        pm_kdtree_config cfg2 = cfg;
        cfg2.axis_offset = -1;
        ASSERT_EQ_INT(pm_kdtree_build(&t2, rec2, n, &cfg2, NULL), 0);
        for (int qi = 0; qi < NQ && !bad; qi++) {
            const float *q = qs[qi];
            /* radii: unlimited, and exactly the dist2 of 1, 2 and 3 lattice steps (strict) */
            const float r2s[] = {INFINITY, 1.0f, 2.0f, 3.0f, 1.25f};
            for (size_t ri = 0; ri < sizeof r2s / sizeof r2s[0] && !bad; ri++) {
                float r2 = r2s[ri];
                for (size_t ki = 0; ki < sizeof ks / sizeof ks[0] && !bad; ki++) {
                    unsigned k = ks[ki];
                    char what[160];
                    for (int tt = 0; tt < 2 && !bad; tt++) {
                        const pm_kdtree *tr = tt ? t2 : t;
                        size_t c = tie_oracle(tr, q, r2, 0, want);
                        snprintf(what, sizeof what, "B=%u %s q%d (%g,%g,%g) r2=%g k=%u",
                                 Bs[bi], tt ? "generic" : "photon", qi, (double)q[0],
                                 (double)q[1], (double)q[2], (double)r2, k);
                        int g = pm_kdtree_knn(tr, q, k, r2, got, 0, NULL);
                        bad |= !tie_same(got, g, 0, want, c, k, what);
                        g = pm_kdtree_knn(tr, q, k, r2, got, PM_SORT, NULL);
                        bad |= !tie_same(got, g, 1, want, c, k, what);
                        pm_query_stats st = {0, 0};
                        int g2 = pm_kdtree_knn_recursive(tr, q, k, r2, got2, PM_SORT, &st);
                        bad |= !tie_same(got2, g2, 1, want, c, k, what);
                        if (k == 1) {
                            pm_neighbor nb;
                            int g1 = pm_kdtree_nearest_if(tr, q, r2, NULL, NULL, &nb, NULL);
                            bad |= !tie_same(&nb, g1, 1, want, c, 1, what);
                        }
                        /* a filter (odd indices only) */
                        pm_knn_options o;
                        memset(&o, 0, sizeof o);
                        o.filter = odd_filter;
                        o.flags = PM_SORT;
                        size_t cf = tie_oracle(tr, q, r2, 1, want);
                        g = pm_kdtree_knn_ex(tr, q, k, r2, &o, got, NULL);
                        bad |= !tie_same(got, g, 1, want, cf, k, what);
                    }
                }
            }
        }
        pm_kdtree_free(t);
        pm_kdtree_free(t2);
        free(rec);
        free(rec2);
    }
    free(ph);
    free(want);
}

/* The same answers, array for array, from 1 and from 4 threads querying one tree at once. */
TEST(kdtree_ties_same_for_any_thread_count) {
    kt_rng r = {99};
    const size_t n = 3000;
    enum { NQ = 256, K = 70 };
    pm_photon *ph = calloc(n, sizeof *ph);
    ASSERT(ph);
    for (size_t i = 0; i < n; i++) /* a coarse lattice: nearly every distance ties */
        for (int a = 0; a < 3; a++) ph[i].pos[a] = (float)(kt_next(&r) % 7);
    pm_kdtree *t = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(8);
    ASSERT_EQ_INT(pm_kdtree_build(&t, ph, n, &cfg, NULL), 0);
    static float q[NQ][3];
    static pm_neighbor one[NQ][K], many[NQ][K];
    static int g1[NQ], gm[NQ];
    for (int i = 0; i < NQ; i++)
        for (int a = 0; a < 3; a++) q[i][a] = 0.5f * (float)(kt_next(&r) % 14);
    for (int i = 0; i < NQ; i++)
        g1[i] = pm_kdtree_knn(t, q[i], (unsigned)(1 + i % K), INFINITY, one[i], 0, NULL);
#pragma omp parallel for num_threads(4) schedule(dynamic, 1)
    for (int i = 0; i < NQ; i++)
        gm[i] = pm_kdtree_knn(t, q[i], (unsigned)(1 + i % K), INFINITY, many[i], 0, NULL);
    for (int i = 0; i < NQ; i++) {
        ASSERT_EQ_INT(gm[i], g1[i]);
        ASSERT(memcmp(one[i], many[i], (size_t)g1[i] * sizeof one[i][0]) == 0);
    }
    /* and the same set as the oracle (so the arrays compared above are the right ones) */
    pm_neighbor *want = malloc(n * sizeof *want);
    for (int i = 0; i < NQ; i += 17) {
        size_t c = tie_oracle(t, q[i], INFINITY, 0, want);
        char what[64];
        snprintf(what, sizeof what, "query %d", i);
        EXPECT(tie_same(one[i], g1[i], 0, want, c, (unsigned)(1 + i % K), what));
    }
    free(want);
    pm_kdtree_free(t);
    free(ph);
}

/* pm_kdtree_photon_config(0) is the default bucket size, and that tree answers exactly. */
TEST(kdtree_default_bucket) {
    kt_rng r = {7};
    const size_t n = 5000;
    pm_photon *ph = calloc(n, sizeof *ph);
    ASSERT(ph);
    for (size_t i = 0; i < n; i++)
        for (int a = 0; a < 3; a++) ph[i].pos[a] = (float)(kt_next(&r) % 11);
    pm_kdtree *t = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(0);
    ASSERT_EQ_INT(pm_kdtree_build(&t, ph, n, &cfg, NULL), 0);
    EXPECT_EQ_INT((int)pm_kdtree_bucket(t), (int)PM_KDTREE_BUCKET_DEFAULT);
    pm_neighbor *want = malloc(n * sizeof *want), got[50];
    for (int i = 0; i < 20; i++) {
        float q[3] = {0.5f * (float)(kt_next(&r) % 22), 0.5f * (float)(kt_next(&r) % 22),
                      0.5f * (float)(kt_next(&r) % 22)};
        size_t c = tie_oracle(t, q, INFINITY, 0, want);
        int g = pm_kdtree_knn(t, q, 50, INFINITY, got, 0, NULL);
        EXPECT(tie_same(got, g, 0, want, c, 50, "default bucket"));
    }
    free(want);
    pm_kdtree_free(t);
    free(ph);
}
