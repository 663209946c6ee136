/* test_kdtree_cells.c: the kd-tree's cell-distance pruning, against brute force and against a
 * work bound.
 *
 * The searches skip a subtree when the squared distance from the query to the subtree's cell
 * is not below the current radius (kdtree_query_internal.h, CELL DISTANCE). That pruning must never
 * lose a record, and it must make a query beside the data cost about what a query among the
 * data costs. Every test here states its oracle: a brute-force scan in the same float
 * arithmetic (test_kdtree_util.h), or, for the work bound, the same tree's work on an
 * on-plane query that finds the same number of photons.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "test_kdtree_util.h"

/* Point sets the pruning is most likely to get wrong: Gaussian clusters whose widths span two
 * decades (and empty space between them), a nearly planar slab, a planar caustic (ring and
 * spot on y = 0), collinear points, and a plane. */
enum { C_CLUSTERS, C_SLAB, C_CAUSTIC, C_LINE, C_PLANE, C_N };
static const char *const c_names[C_N] = {"clusters", "slab", "caustic", "line", "plane"};

static float c_gauss(kt_rng *r) {
    float u = kt_uniform(r), v = kt_uniform(r);
    return sqrtf(-2.0f * logf(1.0f - u)) * cosf(6.2831853f * v);
}

static pm_photon *c_photons(int dist, size_t n, uint64_t seed) {
    kt_rng r = {seed};
    float cen[16][4];
    for (int c = 0; c < 16; c++) {
        for (int a = 0; a < 3; a++) cen[c][a] = 0.1f + 0.8f * kt_uniform(&r);
        cen[c][3] = 0.002f * powf(100.0f, (float)c / 15.0f); /* 0.002 .. 0.2 */
    }
    pm_photon *ph = calloc(n, sizeof *ph);
    for (size_t i = 0; i < n; i++) {
        float *p = ph[i].pos;
        float u = kt_uniform(&r);
        switch (dist) {
        case C_CLUSTERS: {
            const float *c = cen[kt_next(&r) % 16];
            for (int a = 0; a < 3; a++) p[a] = c[a] + c[3] * c_gauss(&r);
            break;
        }
        case C_SLAB:
            p[0] = kt_uniform(&r), p[1] = 0.002f * kt_uniform(&r), p[2] = kt_uniform(&r);
            break;
        case C_CAUSTIC:
            if (u < 0.4f) {
                float phi = 6.2831853f * kt_uniform(&r), rad = 0.25f + 0.004f * c_gauss(&r);
                p[0] = 0.5f + rad * cosf(phi), p[2] = 0.5f + rad * sinf(phi);
            } else if (u < 0.7f) {
                p[0] = 0.5f + 0.01f * c_gauss(&r), p[2] = 0.5f + 0.01f * c_gauss(&r);
            } else {
                p[0] = kt_uniform(&r), p[2] = kt_uniform(&r);
            }
            p[1] = 0.0f;
            break;
        case C_LINE:
            p[0] = u, p[1] = 0.5f * u + 0.1f, p[2] = 0.3f;
            break;
        default:
            p[0] = u, p[1] = 0.25f, p[2] = kt_uniform(&r);
        }
        ph[i].normal = (uint8_t)(i * 7);
        ph[i].theta = (uint8_t)(i >> 3);
    }
    return ph;
}

/* Query sets: 0 = near the data (a record jittered by up to 0.002 per axis), 1 = empty space
 * (uniform in the bounding box grown by 0.1 on each side, so flat sets get queries off their
 * plane or line, and some fall outside the box). */
static void c_query(kt_rng *r, const pm_photon *ph, size_t n, int set, float q[3]) {
    if (set == 0) {
        const float *p = ph[kt_next(r) % n].pos;
        for (int a = 0; a < 3; a++) q[a] = p[a] + 0.004f * (kt_uniform(r) - 0.5f);
    } else {
        for (int a = 0; a < 3; a++) q[a] = -0.1f + 1.2f * kt_uniform(r);
    }
}

/* The ellipsoid metric and the predicate of knn_ex, written out for the oracle. */
static const float c_normal[3] = {0.0f, 0.6f, 0.8f};
static const float c_squash = 5.0f;
static float c_metric_dist2(const float q[3], const float p[3]) {
    float dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
    float d2 = dx * dx + dy * dy + dz * dz;
    float dn = dx * c_normal[0] + dy * c_normal[1] + dz * c_normal[2];
    d2 += (c_squash - 1) * (dn * dn);
    return d2;
}
static int c_accept_rec(const pm_photon *p) { return p->normal % 3 != 0; }
static int c_filter(void *user, const void *record, uint32_t index) {
    (void)user, (void)index;
    return c_accept_rec(record);
}

/* Sorted dist2 of the records within r2, in the chosen metric, optionally filtered. */
static size_t c_brute(const pm_kdtree *t, const float q[3], float r2, int metric, int filter,
                      float *buf) {
    const pm_photon *rec = pm_kdtree_records(t);
    size_t n = pm_kdtree_size(t), c = 0;
    for (size_t i = 0; i < n; i++) {
        if (filter && !c_accept_rec(&rec[i])) continue;
        float d2 = metric ? c_metric_dist2(q, rec[i].pos) : kt_dist2(q, rec[i].pos);
        if (kt_within(d2, r2)) buf[c++] = d2;
    }
    qsort(buf, c, sizeof *buf, kt_cmp_float);
    return c;
}

/* Oracle: brute force, exactly (the same multiset of dist2; indices distinct; reported dist2
 * equal to the recomputed one; PM_SORT order), for every search: iterative and recursive k-NN
 * (which must also return identical arrays and statistics; unsorted: sorted for k <= 16, else a heap), knn_ex with the ellipsoid metric
 * and with a predicate, nearest_if, and the radius search; B in {1, 2, 8, 32, 64}; unlimited
 * and finite radii; near-data and empty-space (off-plane, off-line) queries. */
TEST(kdtree_cell_pruning_matches_brute_force) {
    const size_t n = PM_TEST_SANITIZED ? 1500 : 4000;
    const int nq = PM_TEST_SANITIZED ? 8 : 24;
    const unsigned Bs[] = {1, 2, 8, 32, 64};
    const unsigned ks[] = {1, 10, 50};
    float *orc = malloc(n * sizeof *orc), *mine = malloc(n * sizeof *mine);
    unsigned char *seen = malloc(n);
    pm_neighbor *res = malloc(n * sizeof *res), *res2 = malloc(n * sizeof *res2);
    for (int dist = 0; dist < C_N; dist++) {
        for (size_t bi = 0; bi < sizeof Bs / sizeof Bs[0]; bi++) {
            pm_photon *ph = c_photons(dist, n, 1000 + (uint64_t)dist);
            pm_kdtree *t = NULL;
            pm_kdtree_config cfg = pm_kdtree_photon_config(Bs[bi]);
            ASSERT_EQ_INT(pm_kdtree_build(&t, ph, n, &cfg, NULL), 0);
            char what[96];
            kt_rng r = {77 + (uint64_t)dist * 13 + bi};
            for (int set = 0; set < 2; set++) {
                for (int qi = 0; qi < nq; qi++) {
                    float q[3];
                    c_query(&r, ph, n, set, q);
                    /* a finite radius around the 20th-nearest distance, and unlimited */
                    size_t c0 = c_brute(t, q, INFINITY, 0, 0, orc);
                    float r2s[2] = {INFINITY, orc[c0 > 20 ? 20 : c0 - 1] * 1.0001f};
                    for (int ri = 0; ri < 2; ri++) {
                        float r2 = r2s[ri];
                        snprintf(what, sizeof what, "%s B=%u %s q%d r2=%g", c_names[dist],
                                 Bs[bi], set ? "empty" : "near", qi, r2);
                        size_t c = c_brute(t, q, r2, 0, 0, orc);
                        for (size_t ki = 0; ki < sizeof ks / sizeof ks[0]; ki++) {
                            unsigned k = ks[ki];
                            unsigned fl = (qi & 1) ? PM_SORT : 0;
                            pm_query_stats s1 = {0, 0}, s2 = {0, 0};
                            int g1 = pm_kdtree_knn(t, q, k, r2, res, fl, &s1);
                            int g2 = pm_kdtree_knn_recursive(t, q, k, r2, res2, fl, &s2);
                            if (!kt_check_knn(t, q, k, r2, res, g1, fl != 0, orc, c, mine, seen, what))
                                goto fail;
                            /* unsorted (kdtree.h, TIES): ascending by (dist2, index) anyway
                             * for k <= 16; above, once k were found, a max-heap on that key */
#define KT_LESS(x, y) ((x).dist2 < (y).dist2 || ((x).dist2 == (y).dist2 && (x).index < (y).index))
                            if (!fl && k <= 16)
                                for (int i = 1; i < g1; i++) ASSERT(KT_LESS(res[i - 1], res[i]));
                            if (!fl && k > 16 && g1 == (int)k)
                                for (int i = 1; i < g1; i++) ASSERT(KT_LESS(res[i], res[(i - 1) / 2]));
#undef KT_LESS
                            ASSERT_EQ_INT(g2, g1);
                            ASSERT(memcmp(res, res2, (size_t)g1 * sizeof *res) == 0);
                            ASSERT(s1.nodes_visited == s2.nodes_visited &&
                                   s1.dist_evals == s2.dist_evals);
                        }
                        /* radius: the total and the multiset of dist2 */
                        long got = pm_kdtree_radius(t, q, r2, res, n, PM_SORT, NULL);
                        ASSERT_EQ_INT(got, (long)c);
                        for (long i = 0; i < got; i++) ASSERT(res[i].dist2 == orc[i]);
                        /* knn_ex: ellipsoid metric, then a predicate */
                        pm_knn_options o;
                        memset(&o, 0, sizeof o);
                        o.normal = c_normal;
                        o.squash = c_squash;
                        o.flags = PM_SORT;
                        size_t cm = c_brute(t, q, r2, 1, 0, orc);
                        int gm = pm_kdtree_knn_ex(t, q, 10, r2, &o, res, NULL);
                        ASSERT_EQ_INT(gm, (int)(cm < 10 ? cm : 10));
                        for (int i = 0; i < gm; i++) {
                            ASSERT(res[i].dist2 == orc[i]);
                            ASSERT(res[i].dist2 == c_metric_dist2(q, pm_kdtree_pos(t, res[i].index)));
                        }
                        memset(&o, 0, sizeof o);
                        o.filter = c_filter;
                        o.flags = PM_SORT;
                        size_t cf = c_brute(t, q, r2, 0, 1, orc);
                        int gf = pm_kdtree_knn_ex(t, q, 10, r2, &o, res, NULL);
                        ASSERT_EQ_INT(gf, (int)(cf < 10 ? cf : 10));
                        for (int i = 0; i < gf; i++) {
                            ASSERT(res[i].dist2 == orc[i]);
                            ASSERT(c_accept_rec((const pm_photon *)pm_kdtree_records(t) + res[i].index));
                        }
                        /* nearest_if: the closest accepted record */
                        pm_neighbor nb;
                        int g = pm_kdtree_nearest_if(t, q, r2, c_filter, NULL, &nb, NULL);
                        ASSERT_EQ_INT(g, cf > 0 ? 1 : 0);
                        if (g == 1) ASSERT(nb.dist2 == orc[0]);
                    }
                }
            }
            pm_kdtree_free(t);
            free(ph);
        }
    }
fail:
    free(orc);
    free(mine);
    free(seen);
    free(res);
    free(res2);
}

/* Oracle: the same tree's work on an on-plane query that finds the same number of photons.
 * Photons on y = 0 with x, z uniform in [0, 1). Above the plane at q = (0.5, 0.15, 0.5) with
 * k = 50 and max_dist2 = 0.01 nothing is within reach (0.15^2 > 0.01): the search must find 0
 * after at most twice the distance evaluations of an on-plane query at (0.5, 0, 0.5) whose
 * radius is just below its nearest photon (it too finds 0). Before the cell-distance pruning
 * the off-plane query scanned every photon within 0.1 of (0.5, 0.5) in x and z (about 42,000
 * evaluations at 1M). The same holds for a query that does find photons: k = 50 just above
 * the plane against k = 50 on it. */
TEST(kdtree_off_plane_query_work_is_bounded) {
    const size_t n = PM_TEST_SANITIZED ? 100000 : 1000000;
    kt_rng r = {4242};
    pm_photon *ph = calloc(n, sizeof *ph);
    for (size_t i = 0; i < n; i++) {
        ph[i].pos[0] = kt_uniform(&r);
        ph[i].pos[1] = 0.0f;
        ph[i].pos[2] = kt_uniform(&r);
    }
    const unsigned Bs[] = {1, 8, 32};
    for (size_t bi = 0; bi < sizeof Bs / sizeof Bs[0]; bi++) {
        pm_kdtree *t = NULL;
        pm_kdtree_config cfg = pm_kdtree_photon_config(Bs[bi]);
        ASSERT_EQ_INT(pm_kdtree_build(&t, ph, n, &cfg, NULL), 0);
        pm_neighbor out[50];
        const float off[3] = {0.5f, 0.15f, 0.5f}, on[3] = {0.5f, 0.0f, 0.5f};
        pm_query_stats so = {0, 0}, sn = {0, 0};
        ASSERT_EQ_INT(pm_kdtree_knn(t, off, 50, 0.01f, out, 0, &so), 0);
        ASSERT_EQ_INT(pm_kdtree_knn(t, on, 1, INFINITY, out, 0, NULL), 1);
        float r2 = out[0].dist2; /* strict <: the nearest photon itself is out */
        ASSERT(r2 > 0);
        ASSERT_EQ_INT(pm_kdtree_knn(t, on, 50, r2, out, 0, &sn), 0);
        EXPECT_MSG(so.dist_evals <= 2 * sn.dist_evals,
                   "B=%u: off-plane query evaluated %llu distances, on-plane %llu", Bs[bi],
                   (unsigned long long)so.dist_evals, (unsigned long long)sn.dist_evals);
        /* the same for the radius search */
        pm_query_stats ro = {0, 0}, rn = {0, 0};
        ASSERT_EQ_INT(pm_kdtree_radius(t, off, 0.01f, NULL, 0, 0, &ro), 0);
        ASSERT_EQ_INT(pm_kdtree_radius(t, on, r2, NULL, 0, 0, &rn), 0);
        EXPECT(ro.dist_evals <= 2 * rn.dist_evals);
        /* k = 50 found just above the plane against k = 50 on it */
        pm_query_stats ko = {0, 0}, kn = {0, 0};
        const float above[3] = {0.5f, 0.02f, 0.5f};
        ASSERT_EQ_INT(pm_kdtree_knn(t, above, 50, INFINITY, out, 0, &ko), 50);
        ASSERT_EQ_INT(pm_kdtree_knn(t, on, 50, INFINITY, out, 0, &kn), 50);
        EXPECT_MSG(ko.dist_evals <= 2 * kn.dist_evals,
                   "B=%u: k = 50 above the plane evaluated %llu distances, on it %llu", Bs[bi],
                   (unsigned long long)ko.dist_evals, (unsigned long long)kn.dist_evals);
        printf("    B=%u evals: off-plane %llu / on-plane %llu (0 found); k=50 above %llu / on %llu\n",
                 Bs[bi], (unsigned long long)so.dist_evals, (unsigned long long)sn.dist_evals,
                 (unsigned long long)ko.dist_evals, (unsigned long long)kn.dist_evals);
        pm_kdtree_free(t);
    }
    free(ph);
}

/* ---- tightening codes ---------------------------------------------------------------------- */

#include "kdtree_internal.h"

/* The cell of every node, derived exactly as the queries derive it (the root's box and code,
 * then each child cut at its parent's split and shrunk by its own code), must hold every
 * record of the node's subtree. Checked against the records themselves, node by node.
 * Returns the number of nodes whose code is not 0, or -1 after a failure. */
static long c_check_cells(const pm_kdtree *t, const char *what) {
    const char *rec = pm_kdtree_records(t);
    uint64_t L = t->nleaves;
    if (t->n == 0) return 0;
    struct {
        uint64_t p;
        float lo[3], hi[3];
    } st[2 * PM_KDTREE_MAX_DEPTH + 2];
    int sp = 1;
    long coded = 0;
    st[0].p = 1;
    memcpy(st[0].lo, t->lo, sizeof t->lo);
    memcpy(st[0].hi, t->hi, sizeof t->hi);
    while (sp > 0) {
        sp--;
        uint64_t p = st[sp].p;
        float lo[3], hi[3];
        memcpy(lo, st[sp].lo, sizeof lo);
        memcpy(hi, st[sp].hi, sizeof hi);
        unsigned byte = 0;
        if (p < L) {
            byte = t->axes ? t->axes[p - 1]
                           : ((const uint8_t *)rec)[(p - 1) * t->stride + (size_t)t->axis_offset];
            /* a byte the tree shares keeps the caller's bits there: not a code */
            unsigned c = t->tight ? byte >> PM__CODE_SHIFT : 0;
            coded += c != 0;
            pm__tighten(lo, hi, c);
        }
        pm__range r[PM_KDTREE_MAX_DEPTH + 1];
        int nr = pm__subtree_ranges(t, p, pm__ilog2(p), r);
        for (int g = 0; g < nr; g++) {
            for (uint64_t i = r[g].begin; i < r[g].end; i++) {
                const float *x = (const float *)(rec + i * t->stride + t->pos_offset);
                for (int a = 0; a < 3; a++) {
                    if (!(lo[a] <= x[a] && x[a] <= hi[a])) {
                        EXPECT_MSG(0, "%s: record %llu (%g on axis %d) outside node %llu's cell [%g, %g]",
                                   what, (unsigned long long)i, (double)x[a], a,
                                   (unsigned long long)p, (double)lo[a], (double)hi[a]);
                        return -1;
                    }
                }
            }
        }
        unsigned a = byte & PM__AXIS_MASK;
        if (p >= L || a == PM__AXIS_UNIFORM) continue;
        float split = ((const float *)(rec + (p - 1) * t->stride + t->pos_offset))[a];
        for (int c = 0; c < 2; c++) {
            st[sp].p = 2 * p + (uint64_t)c;
            memcpy(st[sp].lo, lo, sizeof lo);
            memcpy(st[sp].hi, hi, sizeof hi);
            if (c) st[sp].lo[a] = split;
            else st[sp].hi[a] = split;
            sp++;
        }
    }
    return coded;
}

/* Oracle: the records themselves (every one inside the decoded cell of every node above it).
 * On the point sets above plus heavy duplicates, huge coordinates (around 1e30, and extents
 * that overflow to inf near FLT_MAX), tiny spreads (1e-30 around 1) and subnormal spreads;
 * B in {1, 2, 8, 32, 64}; pm_photon records (codes in the flag byte) and a tree-owned axis
 * array (codes there). Also: codes are really written on clustered data and the planar caustic (else
 * this test would check nothing), the queries on the odd sets match brute force, and a
 * record layout whose axis byte the tree shares keeps bits 2-7 untouched and gets no codes. */
TEST(kdtree_tightening_codes_are_conservative) {
    const size_t n = PM_TEST_SANITIZED ? 1500 : 6000;
    const unsigned Bs[] = {1, 2, 8, 32, 64};
    enum { X_DUPS = C_N, X_HUGE, X_OVERFLOW, X_TINY, X_SUBNORMAL, X_N };
    static const char *const xn[] = {"dups", "huge", "overflow", "tiny", "subnormal"};
    float *orc = malloc(n * sizeof *orc), *mine = malloc(n * sizeof *mine);
    pm_neighbor *res = malloc(n * sizeof *res);
    typedef struct {
        float pos[3];
        uint8_t axis, other;
        uint8_t pad[2];
    } rec16;
    rec16 *g = malloc(n * sizeof *g);
    ASSERT(orc && mine && res && g);
    for (int dist = 0; dist < X_N; dist++) {
        const char *name = dist < C_N ? c_names[dist] : xn[dist - C_N];
        pm_photon *base = c_photons(dist < C_N ? dist : C_CLUSTERS, n, 4242 + (uint64_t)dist);
        kt_rng r = {99 + (uint64_t)dist};
        for (size_t i = 0; i < n && dist >= C_N; i++) {
            float *p = base[i].pos;
            if (dist == X_DUPS && i % 3 != 0) p[0] = 0.25f, p[1] = 0.5f, p[2] = 0.75f;
            if (dist == X_HUGE)
                for (int a = 0; a < 3; a++) p[a] = p[a] * 1e30f - 5e29f;
            if (dist == X_OVERFLOW)
                for (int a = 0; a < 3; a++) p[a] = (kt_uniform(&r) < 0.5f ? -3e38f : 3e38f) * p[a];
            if (dist == X_TINY)
                for (int a = 0; a < 3; a++) p[a] = 1.0f + p[a] * 1e-6f;
            if (dist == X_SUBNORMAL)
                for (int a = 0; a < 3; a++) p[a] = p[a] * 1e-38f;
        }
        for (size_t bi = 0; bi < sizeof Bs / sizeof Bs[0]; bi++) {
            char what[96];
            snprintf(what, sizeof what, "%s B=%u", name, Bs[bi]);
            pm_photon *ph = malloc(n * sizeof *ph);
            memcpy(ph, base, n * sizeof *ph);
            pm_kdtree *t = NULL;
            pm_kdtree_config cfg = pm_kdtree_photon_config(Bs[bi]);
            ASSERT_EQ_INT(pm_kdtree_build(&t, ph, n, &cfg, NULL), 0);
            long coded = c_check_cells(t, what);
            if (dist == C_CLUSTERS || dist == C_CAUSTIC)
                EXPECT_MSG(coded > 0, "%s: no node has a code", what);
            /* the searches on these sets against brute force */
            for (int qi = 0; qi < 6 && !pm_test_failed(); qi++) {
                float q[3];
                const float *p = ph[kt_next(&r) % n].pos;
                for (int a = 0; a < 3; a++)
                    q[a] = qi & 1 ? p[a] * (1.0f + 0.01f * (kt_uniform(&r) - 0.5f))
                                  : ph[kt_next(&r) % n].pos[a];
                size_t m = c_brute(t, q, INFINITY, 0, 0, orc);
                unsigned k = qi < 2 ? 1u : qi < 4 ? 10u : 50u;
                int got = pm_kdtree_knn(t, q, k, INFINITY, res, PM_SORT, NULL);
                ASSERT_EQ_INT(got, (int)(m < k ? m : k));
                for (int j = 0; j < got; j++)
                    EXPECT_MSG(res[j].dist2 == orc[j], "%s: k-NN %d-th dist2 %g, brute %g", what,
                               j, (double)res[j].dist2, (double)orc[j]);
                float r2 = orc[(m < k ? m : k) - 1];
                size_t mr = c_brute(t, q, r2, 0, 0, orc);
                long gr = pm_kdtree_radius(t, q, r2, res, n, PM_SORT, NULL);
                ASSERT_EQ_INT(gr, (long)mr);
                for (long j = 0; j < gr; j++) EXPECT(res[j].dist2 == orc[j]);
            }
            pm_kdtree_free(t);
            free(ph);
            /* a tree-owned axis array carries codes too; a shared byte outside pm_photon's
             * layout does not, and keeps its other bits */
            for (int owned = 0; owned < 2; owned++) {
                for (size_t i = 0; i < n; i++) {
                    memcpy(g[i].pos, base[i].pos, sizeof g[i].pos);
                    g[i].axis = (uint8_t)(0xFCu & (i * 37u)), g[i].other = (uint8_t)i;
                }
                pm_kdtree_config gc = {sizeof(rec16), 0, owned ? -1 : (int)offsetof(rec16, axis),
                                       Bs[bi]};
                uint32_t *perm = malloc(n * sizeof *perm);
                ASSERT_EQ_INT(pm_kdtree_build(&t, g, n, &gc, perm), 0);
                char w2[128];
                snprintf(w2, sizeof w2, "%s (%s)", what, owned ? "owned axes" : "shared byte");
                long c2 = c_check_cells(t, w2);
                if (owned && dist == C_CLUSTERS)
                    EXPECT_MSG(c2 > 0, "%s: no node has a code", w2);
                if (!owned) {
                    EXPECT_MSG(!t->tight && c2 == 0, "%s: codes in a byte the tree shares", w2);
                    for (size_t i = 0; i < n; i++) {
                        if ((g[i].axis & 0xFCu) != (0xFCu & (perm[i] * 37u))) {
                            EXPECT_MSG(0, "%s: bits 2-7 of record %zu changed", w2, i);
                            break;
                        }
                    }
                }
                pm_kdtree_free(t);
                free(perm);
            }
            if (pm_test_failed()) break;
        }
        free(base);
        if (pm_test_failed()) break;
    }
    free(orc);
    free(mine);
    free(res);
    free(g);
}
