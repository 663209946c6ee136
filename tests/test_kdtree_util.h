/* test_kdtree_util.h: point generators and the brute-force oracle shared by the kd-tree tests.
 *
 * The oracle scans every indexed record of a built tree (pm_kdtree_pos), computes dist2 with
 * the same float expression as the tree, keeps those with dist2 < r2 (all of them when r2 is
 * +INFINITY, as kdtree.h documents) and sorts them. A k-NN answer is correct when it has
 * min(k, count) entries, distinct indices, each reported dist2 equals the recomputed one, and
 * its sorted dist2 list equals the oracle's first entries exactly (which of the records tied at
 * the k-th distance are returned is checked by test_kdtree_ties.c, against kdtree.h's rule).
 * No tolerance: both sides compute the same floats.
 */
#ifndef PM_TEST_KDTREE_UTIL_H
#define PM_TEST_KDTREE_UTIL_H

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "kdtree.h"
#include "photon.h"
#include "test.h"

typedef pm_test_rng kt_rng; /* test.h's splitmix64 */

static inline uint64_t kt_next(kt_rng *r) { return pm_test_next(r); }
/* uniform in [0, 1) */
static inline float kt_uniform(kt_rng *r) { return (float)(kt_next(r) >> 40) * (1.0f / 16777216.0f); }

enum {
    KT_UNIFORM,    /* unit cube */
    KT_CLUSTERED,  /* 30% in a small floor disc (a caustic), the rest on box walls */
    KT_IDENTICAL,  /* all at one point */
    KT_LINE,       /* on a line through the cube */
    KT_PLANE,      /* on the plane z = 0.25 */
    KT_GRID,       /* integer grid: exact ties on every split plane */
    KT_HUGE,       /* coordinates around 1e30 */
    KT_TINY,       /* spread around 1e-30 */
    KT_DUPS,       /* half the points on 8 spots, the rest uniform */
    KT_NDISTS
};
static const char *const kt_dist_names[KT_NDISTS] = {
    "uniform", "clustered", "identical", "line", "plane", "grid", "huge", "tiny", "dups"};

static inline void kt_point(kt_rng *r, int dist, size_t i, size_t n, float p[3]) {
    float u = kt_uniform(r), v = kt_uniform(r), w = kt_uniform(r);
    switch (dist) {
    default:
    case KT_UNIFORM:
        p[0] = u, p[1] = v, p[2] = w;
        break;
    case KT_CLUSTERED:
        if (w < 0.3f) { /* disc of radius 0.05 around (0.5, 0, 0.5) */
            float a = 6.2831853f * u, rr = 0.05f * sqrtf(v);
            p[0] = 0.5f + rr * cosf(a), p[1] = 0.0f, p[2] = 0.5f + rr * sinf(a);
        } else {
            int wall = (int)(kt_uniform(r) * 5.0f);
            float s = kt_uniform(r), t = kt_uniform(r);
            if (wall == 0) p[0] = s, p[1] = 0, p[2] = t;      /* floor */
            else if (wall == 1) p[0] = s, p[1] = 1, p[2] = t; /* ceiling */
            else if (wall == 2) p[0] = 0, p[1] = s, p[2] = t; /* left */
            else if (wall == 3) p[0] = 1, p[1] = s, p[2] = t; /* right */
            else p[0] = s, p[1] = t, p[2] = 1;                /* back */
        }
        break;
    case KT_IDENTICAL:
        p[0] = 0.25f, p[1] = -3.0f, p[2] = 7.5f;
        break;
    case KT_LINE:
        p[0] = u, p[1] = 0.5f * u + 0.1f, p[2] = 0.3f;
        break;
    case KT_PLANE:
        p[0] = u, p[1] = v, p[2] = 0.25f;
        break;
    case KT_GRID: {
        size_t side = 1;
        while (side * side * side < n) side++;
        p[0] = (float)(i % side), p[1] = (float)((i / side) % side), p[2] = (float)(i / side / side);
        break;
    }
    case KT_HUGE:
        p[0] = (u - 0.5f) * 2e30f, p[1] = (v - 0.5f) * 2e30f, p[2] = 1e30f + w * 1e30f;
        break;
    case KT_TINY:
        p[0] = u * 1e-30f, p[1] = v * 1e-30f, p[2] = w * 1e-30f;
        break;
    case KT_DUPS:
        if (u < 0.5f) {
            int s = (int)(v * 8);
            p[0] = 0.1f * (float)s, p[1] = 0.5f, p[2] = 0.3f;
        } else {
            p[0] = kt_uniform(r), p[1] = v, p[2] = w;
        }
        break;
    }
}

static inline float kt_dist2(const float q[3], const float p[3]) {
    float dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
    return dx * dx + dy * dy + dz * dz;
}

static int kt_cmp_float(const void *a, const void *b) {
    float x = *(const float *)a, y = *(const float *)b;
    return x < y ? -1 : x > y ? 1 : 0;
}

static inline int kt_within(float d2, float r2) { return r2 == INFINITY ? 1 : d2 < r2; }

/* Sorted dist2 of every indexed record within r2; returns the count. `buf` holds n floats. */
static inline size_t kt_brute(const pm_kdtree *t, const float q[3], float r2, float *buf) {
    size_t n = pm_kdtree_size(t), c = 0;
    for (size_t i = 0; i < n; i++) {
        float d2 = kt_dist2(q, pm_kdtree_pos(t, (uint32_t)i));
        if (kt_within(d2, r2)) buf[c++] = d2;
    }
    qsort(buf, c, sizeof *buf, kt_cmp_float);
    return c;
}

/* Check a k-NN answer (got results in res) against the oracle's sorted list orc[0..c) from
 * kt_brute. Uses EXPECT; returns 0 on a mismatch so the caller can stop early. mine holds
 * min(k, n) floats, seen n bytes. */
static inline int kt_check_knn(const pm_kdtree *t, const float q[3], unsigned k, float r2,
                               const pm_neighbor *res, int got, int sorted, const float *orc,
                               size_t c, float *mine, unsigned char *seen, const char *what) {
    size_t n = pm_kdtree_size(t);
    size_t want = c < k ? c : k;
    if ((size_t)got != want) {
        EXPECT_MSG(0, "%s: k=%u r2=%g got %d results, oracle %zu", what, k, r2, got, want);
        return 0;
    }
    memset(seen, 0, n);
    for (int i = 0; i < got; i++) {
        uint32_t ix = res[i].index;
        if (ix >= n || seen[ix]) {
            EXPECT_MSG(0, "%s: bad or repeated index %u", what, ix);
            return 0;
        }
        seen[ix] = 1;
        float d2 = kt_dist2(q, pm_kdtree_pos(t, ix));
        if (!(d2 == res[i].dist2)) {
            EXPECT_MSG(0, "%s: index %u reported dist2 %g, is %g", what, ix, res[i].dist2, d2);
            return 0;
        }
        if (sorted && i > 0 &&
            (res[i].dist2 < res[i - 1].dist2 ||
             (res[i].dist2 == res[i - 1].dist2 && res[i].index < res[i - 1].index))) {
            EXPECT_MSG(0, "%s: PM_SORT order broken at %d", what, i);
            return 0;
        }
        mine[i] = d2;
    }
    qsort(mine, (size_t)got, sizeof *mine, kt_cmp_float);
    for (int i = 0; i < got; i++) {
        if (!(mine[i] == orc[i])) {
            EXPECT_MSG(0, "%s: k=%u r2=%g: %d-th dist2 %.9g, oracle %.9g", what, k, r2, i,
                       mine[i], orc[i]);
            return 0;
        }
    }
    return 1;
}

/* n photons of the given distribution (power/direction arbitrary but fixed). */
static inline pm_photon *kt_photons(int dist, size_t n, uint64_t seed) {
    kt_rng r = {seed};
    pm_photon *ph = calloc(n ? n : 1, sizeof *ph);
    if (!ph) return NULL;
    for (size_t i = 0; i < n; i++) {
        float p[3];
        kt_point(&r, dist, i, n, p);
        ph[i].pos[0] = p[0], ph[i].pos[1] = p[1], ph[i].pos[2] = p[2];
        ph[i].power[0] = (uint8_t)i;
        ph[i].theta = (uint8_t)(i >> 8);
        ph[i].phi = (uint8_t)(i >> 16);
        ph[i].flag = (uint8_t)((i % 4) << PM_FLAG_KIND_SHIFT);
        ph[i].normal = (uint8_t)(i * 7);
    }
    return ph;
}

/* A query point near the data (half of them exactly on a record, some away from it). */
static inline void kt_query(kt_rng *r, const pm_photon *ph, size_t n, int dist, float q[3]) {
    uint64_t x = kt_next(r);
    if (n > 0 && (x & 1)) {
        const pm_photon *p = &ph[(x >> 8) % n];
        q[0] = p->pos[0], q[1] = p->pos[1], q[2] = p->pos[2];
        if (x & 2) return;
        float s = dist == KT_HUGE ? 1e28f : dist == KT_TINY ? 1e-31f : dist == KT_GRID ? 0.5f : 0.01f;
        q[0] += s * (kt_uniform(r) - 0.5f), q[1] += s * (kt_uniform(r) - 0.5f);
        q[2] += s * (kt_uniform(r) - 0.5f);
    } else {
        kt_point(r, dist == KT_IDENTICAL ? KT_UNIFORM : dist, (size_t)(x % (n + 1)), n, q);
        if (dist == KT_IDENTICAL) q[0] += 0.5f, q[1] -= 3.0f, q[2] += 7.0f;
    }
}

#endif /* PM_TEST_KDTREE_UTIL_H */
