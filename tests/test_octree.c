/* test_octree.c: the benchmark octree of bench/octree.h against a brute-force scan.
 *
 * Every query result is compared with a linear scan over the same (reordered) records: the
 * k-nearest search must return the same number of records and the same multiset of dist2
 * (exactly: both compute dist2 with the same float expression), and every record strictly
 * closer than the k-th distance; the radius search must return exactly the records with
 * dist2 < r2. Inputs cover uniform points, photon-like clusters, many duplicates, NaN records,
 * tiny and unlimited radii, k = 0, k > n and an empty tree.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "test.h"
#include "bench/octree.h"
#include "photon.h"

static uint64_t rng_state = 88172645463325252ull;
static double urand(void) {
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (double)(rng_state >> 11) * (1.0 / 9007199254740992.0);
}

/* 0: uniform cube; 1: clustered (30% in a tight blob, some exact duplicates); 2: on a plane */
static void make_points(pm_photon *p, size_t n, int kind) {
    memset(p, 0, n * sizeof *p);
    for (size_t i = 0; i < n; i++) {
        float *x = p[i].pos;
        if (kind == 1 && i % 10 < 3) {
            x[0] = (float)(0.5 + 0.001 * urand());
            x[1] = 0.25f;
            x[2] = (float)(0.5 + 0.001 * urand());
            if (i % 7 == 0) x[0] = x[2] = 0.5f; /* exact duplicates */
        } else if (kind == 2) {
            x[0] = (float)urand();
            x[1] = 0.0f;
            x[2] = (float)urand();
        } else {
            for (int a = 0; a < 3; a++) x[a] = (float)urand();
        }
    }
}

static float dist2_to(const float q[3], const float *p) {
    float dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
    return dx * dx + dy * dy + dz * dz;
}

static int cmp_float(const void *a, const void *b) {
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* Compare one k-NN answer with brute force; returns nonzero on mismatch (EXPECTs inside). */
static int check_knn(const bench_octree *t, const pm_photon *rec, size_t n, const float q[3],
                     unsigned k, float r2, unsigned flags) {
    pm_neighbor *out = malloc((k ? k : 1) * sizeof *out);
    float *all = malloc((n ? n : 1) * sizeof *all);
    size_t m = 0;
    int bad = 0;
    int got = bench_octree_knn(t, q, k, r2, out, flags, NULL);
    for (size_t i = 0; i < n; i++) {
        float d2 = dist2_to(q, rec[i].pos);
        if (d2 < r2) all[m++] = d2;
    }
    qsort(all, m, sizeof *all, cmp_float);
    size_t want = m < k ? m : k;
    EXPECT_EQ_INT(got, (long long)want);
    if (got != (int)want) bad = 1;
    if (!bad && got > 0) {
        float *mine = malloc((size_t)got * sizeof *mine);
        for (int i = 0; i < got; i++) {
            /* the reported dist2 must be the record's real dist2 */
            if (out[i].dist2 != dist2_to(q, rec[out[i].index].pos)) bad = 1;
            mine[i] = out[i].dist2;
        }
        if (flags & PM_SORT) {
            for (int i = 1; i < got; i++)
                if (out[i].dist2 < out[i - 1].dist2 ||
                    (out[i].dist2 == out[i - 1].dist2 && out[i].index <= out[i - 1].index))
                    bad = 1;
        }
        qsort(mine, (size_t)got, sizeof *mine, cmp_float);
        for (int i = 0; i < got; i++)
            if (mine[i] != all[i]) bad = 1;
        free(mine);
        EXPECT_MSG(!bad, "k-NN differs from brute force (k=%u r2=%g)", k, (double)r2);
    }
    free(out);
    free(all);
    return bad;
}

static int check_radius(const bench_octree *t, const pm_photon *rec, size_t n, const float q[3],
                        float r2) {
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        if (dist2_to(q, rec[i].pos) < r2) m++;
    pm_neighbor *out = malloc((m + 1) * sizeof *out);
    char *seen = calloc(n ? n : 1, 1);
    long got = bench_octree_radius(t, q, r2, out, m + 1, PM_SORT, NULL);
    int bad = got != (long)m;
    for (long i = 0; !bad && i < got; i++) {
        uint32_t ix = out[i].index;
        if (ix >= n || seen[ix] || !(dist2_to(q, rec[ix].pos) < r2)) bad = 1;
        else seen[ix] = 1;
        if (i > 0 && out[i].dist2 < out[i - 1].dist2) bad = 1;
    }
    /* a pure count (cap 0, out NULL) gives the same total */
    if (bench_octree_radius(t, q, r2, NULL, 0, 0, NULL) != (long)m) bad = 1;
    /* a short buffer: the total is still reported, only cap entries written */
    if (m > 2 && bench_octree_radius(t, q, r2, out, 2, 0, NULL) != (long)m) bad = 1;
    EXPECT_MSG(!bad, "radius search: got %ld, brute force %zu (r2=%g)", got, m, (double)r2);
    free(out);
    free(seen);
    return bad;
}

/* Oracle: brute force over the same records, for every capacity of the benchmark sweep, three
 * distributions, k from 1 to beyond n, radii from tiny to unlimited. Exact float equality. */
TEST(octree_matches_brute_force) {
    const size_t n = PM_TEST_SANITIZED ? 1500 : 6000;
    const unsigned caps[] = {1, 4, 16, 64, 190, 1000, 10000};
    const unsigned ks[] = {1, 5, 50, 200};
    pm_photon *p = malloc(n * sizeof *p);
    for (int kind = 0; kind < 3; kind++) {
        for (size_t ci = 0; ci < sizeof caps / sizeof caps[0]; ci++) {
            bench_octree *t = NULL;
            bench_octree_config cfg = bench_octree_photon_config(caps[ci]);
            make_points(p, n, kind);
            ASSERT_EQ_INT(bench_octree_build(&t, p, n, &cfg, NULL), 0);
            ASSERT_EQ_INT(bench_octree_size(t), n);
            int bad = 0;
            for (int qi = 0; qi < 25 && !bad; qi++) {
                float q[3];
                if (qi % 2) {
                    memcpy(q, p[(size_t)(urand() * n)].pos, sizeof q); /* on a record */
                } else {
                    for (int a = 0; a < 3; a++) q[a] = (float)(urand() * 1.2 - 0.1);
                }
                const float r2s[] = {1e-6f, 0.001f, 0.02f, INFINITY};
                for (size_t ri = 0; ri < 4; ri++) {
                    for (size_t ki = 0; ki < 4; ki++)
                        bad |= check_knn(t, p, n, q, ks[ki], r2s[ri], ki % 2 ? PM_SORT : 0);
                    if (ri < 3) bad |= check_radius(t, p, n, q, r2s[ri]);
                }
            }
            EXPECT_MSG(!bad, "distribution %d capacity %u", kind, caps[ci]);
            bench_octree_free(t);
        }
    }
    free(p);
}

/* Oracle: the definition of the build. perm maps each record back to its original (the
 * multiset of records is preserved), leaves hold at most `capacity` records unless they hold
 * duplicates, and NaN/infinite records go to the tail and are counted. */
TEST(octree_perm_and_nonfinite) {
    const size_t n = 3000;
    pm_photon *p = malloc(n * sizeof *p), *orig = malloc(n * sizeof *orig);
    uint32_t *perm = malloc(n * sizeof *perm);
    bench_octree *t = NULL;
    bench_octree_config cfg = bench_octree_photon_config(4);
    make_points(p, n, 0);
    for (size_t i = 0; i < n; i += 100) p[i].pos[i % 3] = (i % 200) ? NAN : INFINITY;
    for (size_t i = 0; i < n; i++) p[i].normal = (uint8_t)i, p[i].theta = (uint8_t)(i >> 8);
    memcpy(orig, p, n * sizeof *p);
    ASSERT_EQ_INT(bench_octree_build(&t, p, n, &cfg, perm), 0);
    ASSERT_EQ_INT(bench_octree_dropped(t), 30);
    ASSERT_EQ_INT(bench_octree_size(t), n - 30);
    for (size_t i = 0; i < n; i++) {
        ASSERT(perm[i] < n);
        ASSERT(memcmp(&p[i], &orig[perm[i]], sizeof *p) == 0);
    }
    for (size_t i = n - 30; i < n; i++)
        ASSERT(!isfinite(p[i].pos[0]) || !isfinite(p[i].pos[1]) || !isfinite(p[i].pos[2]));
    /* queries never return a dropped record */
    float q[3] = {0.5f, 0.5f, 0.5f};
    ASSERT(!check_knn(t, p, n - 30, q, 100, INFINITY, 0));
    ASSERT(bench_octree_index_bytes(t) >= bench_octree_cells(t) * 12);
    bench_octree_free(t);
    free(p);
    free(orig);
    free(perm);
}

/* Oracle: brute force and the documented edge cases (kdtree.h's rules). 2000 identical points
 * with capacity 1 must build (depth bounded) and answer correctly. */
TEST(octree_duplicates_and_edge_cases) {
    const size_t n = 2000;
    pm_photon *p = calloc(n, sizeof *p);
    bench_octree *t = NULL;
    bench_octree_config cfg = bench_octree_photon_config(1);
    pm_neighbor out[8];
    for (size_t i = 0; i < n; i++) p[i].pos[0] = p[i].pos[1] = p[i].pos[2] = 0.3f;
    p[7].pos[0] = 0.9f;
    ASSERT_EQ_INT(bench_octree_build(&t, p, n, &cfg, NULL), 0);
    ASSERT(bench_octree_depth(t) <= BENCH_OCTREE_MAX_DEPTH);
    float q[3] = {0.3f, 0.3f, 0.3f}, nanq[3] = {NAN, 0, 0};
    ASSERT(!check_knn(t, p, n, q, 8, INFINITY, PM_SORT));
    ASSERT(!check_radius(t, p, n, q, 1e-3f));
    ASSERT_EQ_INT(bench_octree_knn(t, q, 0, INFINITY, out, 0, NULL), 0);
    ASSERT_EQ_INT(bench_octree_knn(t, q, 8, 0.0f, out, 0, NULL), 0);
    ASSERT_EQ_INT(bench_octree_knn(t, q, 8, -1.0f, out, 0, NULL), 0);
    ASSERT_EQ_INT(bench_octree_knn(t, q, 8, NAN, out, 0, NULL), PM_ENONFINITE);
    ASSERT_EQ_INT(bench_octree_knn(t, nanq, 8, 1.0f, out, 0, NULL), PM_ENONFINITE);
    ASSERT_EQ_INT(bench_octree_radius(t, nanq, 1.0f, out, 8, 0, NULL), PM_ENONFINITE);
    bench_octree_free(t);

    /* empty tree, k > n, bad configs */
    ASSERT_EQ_INT(bench_octree_build(&t, p, 0, &cfg, NULL), 0);
    ASSERT_EQ_INT(bench_octree_knn(t, q, 8, INFINITY, out, 0, NULL), 0);
    ASSERT_EQ_INT(bench_octree_radius(t, q, INFINITY, out, 8, 0, NULL), 0);
    bench_octree_free(t);
    ASSERT_EQ_INT(bench_octree_build(&t, p, 3, &cfg, NULL), 0);
    ASSERT_EQ_INT(bench_octree_knn(t, q, 8, INFINITY, out, 0, NULL), 3);
    bench_octree_free(t);
    bench_octree_config bad = cfg;
    bad.capacity = 0;
    ASSERT_EQ_INT(bench_octree_build(&t, p, n, &bad, NULL), PM_EINVAL);
    ASSERT(t == NULL);
    bad = cfg;
    bad.pos_offset = 10;
    ASSERT_EQ_INT(bench_octree_build(&t, p, n, &bad, NULL), PM_EINVAL);

    /* stats count work: at least one cell and one distance per non-empty query */
    pm_query_stats st = {0, 0};
    ASSERT_EQ_INT(bench_octree_build(&t, p, n, &cfg, NULL), 0);
    ASSERT_EQ_INT(bench_octree_knn(t, q, 1, INFINITY, out, 0, &st), 1);
    ASSERT(st.nodes_visited >= 1 && st.dist_evals >= 1);
    bench_octree_free(t);
    free(p);
}

/* Oracle: the kd-tree's definition of "unlimited" (kdtree.h, QUERIES), which the octree shares:
 * r2 = INFINITY accepts every record, even one whose float dist2 overflows to +inf. Records
 * about 1e20 from the query have dist2 = +inf in float, so k-NN must still return
 * min(k, n) of them and the radius search all n, exactly as the kd-tree does on the same data. */
TEST(octree_unlimited_accepts_overflowed_dist2) {
    const size_t n = 6;
    pm_photon p[6], pk[6];
    memset(p, 0, sizeof p);
    for (size_t i = 0; i < n; i++) {
        p[i].pos[0] = (i & 1) ? 1e20f : -1e20f;
        p[i].pos[1] = (float)i * 1e19f;
        p[i].pos[2] = 3e20f;
    }
    memcpy(pk, p, sizeof p);
    bench_octree *t = NULL;
    bench_octree_config cfg = bench_octree_photon_config(2);
    ASSERT_EQ_INT(bench_octree_build(&t, p, n, &cfg, NULL), 0);
    pm_kdtree *kd = NULL;
    pm_kdtree_config kc = pm_kdtree_photon_config(2);
    ASSERT_EQ_INT(pm_kdtree_build(&kd, pk, n, &kc, NULL), 0);
    float q[3] = {0, 0, 0};
    pm_neighbor out[8], ko[8];
    ASSERT_EQ_INT(bench_octree_knn(t, q, 4, INFINITY, out, 0, NULL), 4);
    ASSERT_EQ_INT(pm_kdtree_knn(kd, q, 4, INFINITY, ko, 0, NULL), 4);
    ASSERT_EQ_INT(bench_octree_knn(t, q, 8, INFINITY, out, 0, NULL), 6);
    ASSERT_EQ_INT(pm_kdtree_knn(kd, q, 8, INFINITY, ko, 0, NULL), 6);
    ASSERT_EQ_INT(bench_octree_radius(t, q, INFINITY, out, 8, 0, NULL), 6);
    ASSERT_EQ_INT(pm_kdtree_radius(kd, q, INFINITY, ko, 8, 0, NULL), 6);
    /* a finite radius, however large, rejects them (dist2 = +inf is not < FLT_MAX) */
    ASSERT_EQ_INT(bench_octree_knn(t, q, 4, 3e38f, out, 0, NULL), 0);
    ASSERT_EQ_INT(pm_kdtree_knn(kd, q, 4, 3e38f, ko, 0, NULL), 0);
    bench_octree_free(t);
    pm_kdtree_free(kd);
}
