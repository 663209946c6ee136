/* test_kdtree.c: the heap kd-tree against a brute-force oracle (tests/test_kdtree_util.h).
 *
 * Covers every distribution of the util header (uniform, clustered caustic disc + walls,
 * identical, line, plane, integer grid with ties on split planes, coordinates ~1e30, spreads
 * ~1e-30, heavy duplicates), sizes around every power of two up to a few thousand, all bucket
 * sizes 1..32, k in {1, 2, 50, 500, N, N+1} with and without a radius, the iterative and
 * recursive searches (identical arrays), radius queries, the structural heap invariant, the
 * permutation, non-finite records and the documented edge cases.
 */
#include "test_kdtree_util.h"

static const unsigned kt_buckets[] = {1, 2, 4, 8, 16, 32};
#define KT_NB (sizeof kt_buckets / sizeof kt_buckets[0])
static const size_t kt_sizes[] = {0,   1,   2,   3,   4,   5,    7,    8,    9,    15,  16,
                                  17,  31,  32,  33,  63,  64,   65,   100,  127,  128, 129,
                                  255, 256, 257, 511, 512, 513, 1000, 1023, 1024, 1025, 3000};
#define KT_NS (sizeof kt_sizes / sizeof kt_sizes[0])

/* Check one built tree with nq queries: k-NN (iterative == recursive, PM_SORT order), radius
 * with enough room. Oracle: brute force, exact (see the util header). */
static void check_tree(const pm_kdtree *t, const pm_photon *ph, int dist, int nq, uint64_t seed,
                       const char *what) {
    size_t n = pm_kdtree_size(t);
    unsigned ks[] = {1, 2, 50, 500, (unsigned)n, (unsigned)n + 1};
    size_t maxk = n + 1 > 500 ? n + 1 : 500;
    float *orc = malloc((n + 1) * sizeof *orc), *mine = malloc((maxk + 1) * sizeof *mine);
    unsigned char *seen = malloc(n + 1);
    pm_neighbor *a = malloc((maxk + 1) * sizeof *a), *b = malloc((maxk + 1) * sizeof *b);
    ASSERT(orc && mine && seen && a && b);
    kt_rng r = {seed};
    for (int qi = 0; qi < nq && !pm_test_failed(); qi++) {
        float q[3];
        kt_query(&r, ph, n, dist, q);
        for (int ri = 0; ri < 2; ri++) {
            float r2 = INFINITY;
            size_t c = kt_brute(t, q, r2, orc);
            if (ri == 1) { /* a radius that cuts inside the data: between two oracle distances */
                if (c == 0) continue;
                r2 = orc[c / 3];
                if (!(r2 > 0)) r2 = orc[c - 1] > 0 ? orc[c - 1] : 1.0f;
                c = kt_brute(t, q, r2, orc);
            }
            for (size_t ki = 0; ki < sizeof ks / sizeof ks[0]; ki++) {
                unsigned k = ks[ki];
                pm_query_stats st1 = {0, 0}, st2 = {0, 0};
                int ga = pm_kdtree_knn(t, q, k, r2, a, 0, &st1);
                int gb = pm_kdtree_knn_recursive(t, q, k, r2, b, 0, &st2);
                if (!kt_check_knn(t, q, k, r2, a, ga, 0, orc, c, mine, seen, what)) goto out;
                EXPECT_EQ_INT(ga, gb);
                if (ga == gb && ga > 0)
                    EXPECT_MSG(memcmp(a, b, (size_t)ga * sizeof *a) == 0,
                               "%s: recursive differs from iterative (k=%u)", what, k);
                EXPECT_EQ_INT(st1.nodes_visited, st2.nodes_visited);
                EXPECT_EQ_INT(st1.dist_evals, st2.dist_evals);
                int gs = pm_kdtree_knn(t, q, k, r2, a, PM_SORT, NULL);
                if (!kt_check_knn(t, q, k, r2, a, gs, 1, orc, c, mine, seen, what)) goto out;
            }
            /* Radius: total equals the oracle count; with room, the same multiset. */
            long tot = pm_kdtree_radius(t, q, r2, a, maxk + 1, PM_SORT, NULL);
            if (tot != (long)c) {
                EXPECT_MSG(0, "%s: radius total %ld, oracle %zu", what, tot, c);
                goto out;
            }
            if (c <= maxk + 1 &&
                !kt_check_knn(t, q, (unsigned)c, r2, a, (int)tot, 1, orc, c, mine, seen, what))
                goto out;
        }
    }
out:
    free(orc), free(mine), free(seen), free(a), free(b);
}

/* The structural invariant, walking the heap: for each internal node with axis a, every record
 * of its left subtree has coordinate <= the split value and every record of the right subtree
 * >= it; a uniform node (axis 3) has all its subtree at one position. Also checks
 * pm_kdtree_height against a bottom-up recount. Oracle: the definition in kdtree.h. */
static void check_structure(const pm_kdtree *t, const pm_photon *rec, const char *what) {
    size_t n = pm_kdtree_size(t);
    unsigned B = pm_kdtree_bucket(t);
    /* Recover the shape the way kdtree.h describes it. */
    int D = 0;
    while ((uint64_t)n + 1 > ((uint64_t)B + 1) << D) D++;
    uint64_t L = (uint64_t)1 << D, I = L - 1;
    uint64_t q = (n - I) / L, extra = (n - I) % L;
    /* Subtree membership: node of every record, then walk up. */
    uint64_t *node_of = malloc((n + 1) * sizeof *node_of);
    int *h = calloc(2 * L + 1, sizeof *h), *has = calloc(2 * L + 1, sizeof *has);
    ASSERT(node_of && h && has);
    for (uint64_t i = 0; i < n; i++) {
        if (i < I) {
            node_of[i] = i + 1;
        } else {
            uint64_t off = i - I, j = 0;
            /* leaf j holds q + (j < extra) records */
            if (off < extra * (q + 1)) j = off / (q + 1);
            else j = extra + (off - extra * (q + 1)) / (q ? q : 1);
            node_of[i] = L + j;
        }
    }
    int uniform_seen = 0;
    for (uint64_t p = 1; p < L && !pm_test_failed(); p++) {
        unsigned a = rec[p - 1].flag & 3u;
        const float *s = rec[p - 1].pos;
        if (a == 3) uniform_seen = 1;
        for (uint64_t i = 0; i < n; i++) {
            uint64_t x = node_of[i];
            int side = -1;
            while (x > p) {
                if (x / 2 == p) side = (int)(x & 1);
                x /= 2;
            }
            if (x != p || side < 0) continue;
            const float *v = rec[i].pos;
            if (a == 3) {
                EXPECT_MSG(v[0] == s[0] && v[1] == s[1] && v[2] == s[2],
                           "%s: uniform node %llu has a different record", what,
                           (unsigned long long)p);
            } else if (side == 0) {
                EXPECT_MSG(v[a] <= s[a], "%s: node %llu left record %g > split %g", what,
                           (unsigned long long)p, v[a], s[a]);
            } else {
                EXPECT_MSG(v[a] >= s[a], "%s: node %llu right record %g < split %g", what,
                           (unsigned long long)p, v[a], s[a]);
            }
        }
    }
    (void)uniform_seen;
    /* Heights: a bucket record is 0; an internal node is 0 without records below it, else
     * 1 + the largest height among its non-empty children (an empty bucket does not count). */
    for (uint64_t i = 0; i < n; i++) has[node_of[i]] = 1;
    for (uint64_t p = L - 1; p >= 1; p--) {
        int best = -1;
        for (uint64_t c = 2 * p; c <= 2 * p + 1; c++)
            if (has[c] && h[c] + 1 > best) best = h[c] + 1;
        h[p] = best < 0 ? 0 : best;
        has[p] = 1;
    }
    for (uint64_t i = 0; i < n && !pm_test_failed(); i++) {
        int want = i < I ? h[i + 1] : 0;
        EXPECT_MSG(pm_kdtree_height(t, (uint32_t)i) == want, "%s: height of %llu is %d, want %d",
                   what, (unsigned long long)i, pm_kdtree_height(t, (uint32_t)i), want);
    }
    free(node_of), free(h), free(has);
}

/* Oracle: brute force over the same records (exact dist2), the heap invariant, and the
 * permutation (record i after the build is record perm[i] before it, all 20 bytes except the
 * two axis bits of the flag). */
TEST(kdtree_matches_brute_force_all_shapes) {
    size_t maxn = PM_TEST_SANITIZED ? 300 : (size_t)-1;
    for (int dist = 0; dist < KT_NDISTS; dist++) {
        for (size_t si = 0; si < KT_NS; si++) {
            size_t n = kt_sizes[si];
            if (n > maxn) continue;
            pm_photon *orig = kt_photons(dist, n, 1000 + 17 * si + dist);
            pm_photon *ph = malloc((n ? n : 1) * sizeof *ph);
            uint32_t *perm = malloc((n ? n : 1) * sizeof *perm);
            ASSERT(orig && ph && perm);
            for (size_t bi = 0; bi < KT_NB; bi++) {
                char what[128];
                snprintf(what, sizeof what, "%s n=%zu B=%u", kt_dist_names[dist], n,
                         kt_buckets[bi]);
                memcpy(ph, orig, n * sizeof *ph);
                pm_kdtree *t = NULL;
                pm_kdtree_config cfg = pm_kdtree_photon_config(kt_buckets[bi]);
                int rc = pm_kdtree_build(&t, ph, n, &cfg, perm);
                ASSERT_MSG(rc == 0 && t, "%s: build failed %d", what, rc);
                ASSERT_EQ_INT(pm_kdtree_size(t), n);
                ASSERT_EQ_INT(pm_kdtree_dropped(t), 0);
                for (size_t i = 0; i < n; i++) {
                    pm_photon x = ph[i], y = orig[perm[i]];
                    x.flag &= (uint8_t)~PM_FLAG_TREE_MASK, y.flag &= (uint8_t)~PM_FLAG_TREE_MASK;
                    if (memcmp(&x, &y, sizeof x) != 0) {
                        EXPECT_MSG(0, "%s: record %zu is not original %u", what, i, perm[i]);
                        break;
                    }
                }
                check_structure(t, ph, what);
                int nq = n < 64 ? 4 : 3;
                check_tree(t, ph, dist, nq, 77 + n * 13 + bi, what);
                pm_kdtree_free(t);
                if (pm_test_failed()) break;
            }
            free(orig), free(ph), free(perm);
            if (pm_test_failed()) return;
        }
    }
}

/* A generic record type: 32-byte records with the position at offset 8 and a tree-owned axis
 * array. Oracle: brute force on the reordered records; perm maps back to the originals. */
typedef struct {
    double id;
    float pos[3];
    int tag;
    char pad[8];
} kt_rec32;

TEST(kdtree_generic_stride_and_owned_axes) {
    size_t n = PM_TEST_SANITIZED ? 700 : 5000;
    kt_rec32 *r = malloc(n * sizeof *r);
    uint32_t *perm = malloc(n * sizeof *perm);
    ASSERT(r && perm);
    kt_rng g = {5};
    for (size_t i = 0; i < n; i++) {
        kt_point(&g, KT_CLUSTERED, i, n, r[i].pos);
        r[i].id = (double)i;
        r[i].tag = (int)i * 3;
        memset(r[i].pad, 0x5A, sizeof r[i].pad);
    }
    for (unsigned bi = 0; bi < KT_NB; bi++) {
        pm_kdtree_config cfg = {sizeof(kt_rec32), offsetof(kt_rec32, pos), -1, kt_buckets[bi]};
        pm_kdtree *t = NULL;
        ASSERT_EQ_INT(pm_kdtree_build(&t, r, n, &cfg, perm), 0);
        for (size_t i = 0; i < n; i++) {
            ASSERT_EQ_INT((long long)r[i].id, perm[i]);
            ASSERT_EQ_INT(r[i].tag, 3 * (int)perm[i]);
            ASSERT(r[i].pad[7] == 0x5A);
        }
        EXPECT(pm_kdtree_index_bytes(t) >= n / (kt_buckets[bi] + 1));
        float *orc = malloc(n * sizeof *orc), *mine = malloc(n * sizeof *mine);
        unsigned char *seen = malloc(n);
        pm_neighbor res[64];
        for (int qi = 0; qi < 20; qi++) {
            float q[3];
            kt_point(&g, KT_UNIFORM, 0, n, q);
            size_t c = kt_brute(t, q, 0.01f, orc);
            int got = pm_kdtree_knn(t, q, 64, 0.01f, res, PM_SORT, NULL);
            EXPECT(kt_check_knn(t, q, 64, 0.01f, res, got, 1, orc, c, mine, seen, "rec32"));
        }
        /* Records were reordered in place; perm relabels them by id in a second build. */
        free(orc), free(mine), free(seen);
        pm_kdtree_free(t);
        for (size_t i = 0; i < n; i++) r[i].id = (double)i, r[i].tag = 3 * (int)i;
    }
    free(r), free(perm);
}

/* Non-finite records are dropped, counted, and moved to the tail in their original order;
 * queries never return them. Oracle: the list of planted NaN/inf indices, brute force. */
TEST(kdtree_drops_nonfinite_records) {
    size_t n = 2000;
    pm_photon *ph = kt_photons(KT_UNIFORM, n, 9);
    uint32_t *perm = malloc(n * sizeof *perm);
    ASSERT(ph && perm);
    size_t bad = 0;
    for (size_t i = 0; i < n; i += 37) {
        ph[i].pos[i % 3] = (i / 37) % 3 == 0 ? NAN : (i / 37) % 3 == 1 ? INFINITY : -INFINITY;
        bad++;
    }
    pm_kdtree *t = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(4);
    ASSERT_EQ_INT(pm_kdtree_build(&t, ph, n, &cfg, perm), 0);
    ASSERT_EQ_INT(pm_kdtree_size(t), n - bad);
    ASSERT_EQ_INT(pm_kdtree_dropped(t), bad);
    for (size_t j = 0; j < bad; j++) {
        EXPECT_EQ_INT(perm[n - bad + j], 37 * j);
        const float *p = ph[n - bad + j].pos;
        EXPECT(!(isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2])));
    }
    float *orc = malloc(n * sizeof *orc), *mine = malloc(n * sizeof *mine);
    unsigned char *seen = malloc(n);
    pm_neighbor res[2001];
    kt_rng g = {3};
    for (int qi = 0; qi < 10; qi++) {
        float q[3];
        kt_point(&g, KT_UNIFORM, 0, n, q);
        size_t c = kt_brute(t, q, INFINITY, orc);
        int got = pm_kdtree_knn(t, q, 2001, INFINITY, res, 0, NULL);
        EXPECT(kt_check_knn(t, q, 2001, INFINITY, res, got, 0, orc, c, mine, seen, "nan"));
        EXPECT_EQ_INT(got, n - bad);
        EXPECT_EQ_INT(pm_kdtree_radius(t, q, INFINITY, NULL, 0, 0, NULL), n - bad);
    }
    free(orc), free(mine), free(seen);
    pm_kdtree_free(t);
    /* All records bad: an empty tree. */
    for (size_t i = 0; i < 10; i++) ph[i].pos[1] = NAN;
    ASSERT_EQ_INT(pm_kdtree_build(&t, ph, 10, &cfg, NULL), 0);
    EXPECT_EQ_INT(pm_kdtree_size(t), 0);
    EXPECT_EQ_INT(pm_kdtree_dropped(t), 10);
    float q[3] = {0, 0, 0};
    EXPECT_EQ_INT(pm_kdtree_knn(t, q, 5, INFINITY, res, 0, NULL), 0);
    pm_kdtree_free(t);
    free(ph), free(perm);
}

/* The documented edge cases of kdtree.h. Oracle: the documented results. */
TEST(kdtree_edge_cases) {
    size_t n = 100;
    pm_photon *ph = kt_photons(KT_UNIFORM, n, 4);
    pm_kdtree *t = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(1);
    ASSERT_EQ_INT(pm_kdtree_build(&t, ph, n, &cfg, NULL), 0);
    pm_neighbor res[200];
    float q[3] = {0.5f, 0.5f, 0.5f}, qn[3] = {0.5f, NAN, 0.5f}, qi[3] = {INFINITY, 0, 0};
    EXPECT_EQ_INT(pm_kdtree_knn(t, q, 0, INFINITY, res, 0, NULL), 0);
    EXPECT_EQ_INT(pm_kdtree_knn(t, q, 150, INFINITY, res, 0, NULL), 100);
    EXPECT_EQ_INT(pm_kdtree_knn(t, q, 5, 0.0f, res, 0, NULL), 0);
    EXPECT_EQ_INT(pm_kdtree_knn(t, q, 5, -1.0f, res, 0, NULL), 0);
    EXPECT_EQ_INT(pm_kdtree_knn(t, q, 5, NAN, res, 0, NULL), PM_ENONFINITE);
    EXPECT_EQ_INT(pm_kdtree_knn(t, qn, 5, INFINITY, res, 0, NULL), PM_ENONFINITE);
    EXPECT_EQ_INT(pm_kdtree_knn(t, qi, 5, INFINITY, res, 0, NULL), PM_ENONFINITE);
    EXPECT_EQ_INT(pm_kdtree_knn_recursive(t, qn, 5, INFINITY, res, 0, NULL), PM_ENONFINITE);
    EXPECT_EQ_INT(pm_kdtree_radius(t, q, 0.0f, res, 200, 0, NULL), 0);
    EXPECT_EQ_INT(pm_kdtree_radius(t, q, -5.0f, res, 200, 0, NULL), 0);
    EXPECT_EQ_INT(pm_kdtree_radius(t, q, NAN, res, 200, 0, NULL), PM_ENONFINITE);
    EXPECT_EQ_INT(pm_kdtree_radius(t, qn, 1.0f, res, 200, 0, NULL), PM_ENONFINITE);
    EXPECT_EQ_INT(pm_kdtree_radius(t, q, INFINITY, NULL, 0, 0, NULL), 100);
    EXPECT_EQ_INT(pm_kdtree_nearest_if(t, qn, 1.0f, NULL, NULL, res, NULL), PM_ENONFINITE);
    EXPECT_EQ_INT(pm_kdtree_nearest_if(t, q, 0.0f, NULL, NULL, res, NULL), 0);
    EXPECT_EQ_INT(pm_kdtree_nearest_if(t, q, INFINITY, NULL, NULL, res, NULL), 1);
    EXPECT_EQ_INT(pm_kdtree_knn(NULL, q, 5, 1.0f, res, 0, NULL), PM_EINVAL);
    EXPECT_EQ_INT(pm_kdtree_knn(t, q, 5, 1.0f, NULL, 0, NULL), PM_EINVAL);
    EXPECT(pm_kdtree_pos(t, 100) == NULL);
    EXPECT(pm_kdtree_pos(t, 99) != NULL);
    pm_kdtree_free(t);
    pm_kdtree_free(NULL);
    /* Bad configs leave *out NULL and the records untouched. */
    pm_photon *copy = malloc(n * sizeof *copy);
    memcpy(copy, ph, n * sizeof *ph);
    pm_kdtree_config bad[4] = {{8, 0, -1, 1}, {20, 10, -1, 1}, {20, 0, 4, 1}, {20, 0, 18, 0}};
    for (int i = 0; i < 4; i++) {
        t = (pm_kdtree *)1;
        EXPECT_EQ_INT(pm_kdtree_build(&t, ph, n, &bad[i], NULL), PM_EINVAL);
        EXPECT(t == NULL);
    }
    EXPECT_EQ_INT(pm_kdtree_build(&t, ph, 0xFFFFFFFFull, &cfg, NULL), PM_ERANGE);
    EXPECT(memcmp(copy, ph, n * sizeof *ph) == 0);
    /* An empty tree. */
    ASSERT_EQ_INT(pm_kdtree_build(&t, NULL, 0, &cfg, NULL), 0);
    EXPECT_EQ_INT(pm_kdtree_knn(t, q, 5, INFINITY, res, 0, NULL), 0);
    EXPECT_EQ_INT(pm_kdtree_radius(t, q, INFINITY, res, 5, 0, NULL), 0);
    EXPECT_EQ_INT(pm_kdtree_nearest_if(t, q, INFINITY, NULL, NULL, res, NULL), 0);
    pm_kdtree_free(t);
    free(copy), free(ph);
}
