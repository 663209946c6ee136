/* kdtree_query_internal.h: what the queries on the heap kd-tree share, included by
 * kdtree_query.c (k nearest, nearest_if) and kdtree_radius.c (radius searches) alone: the
 * view of the records (positions, axis bytes, tightening codes, buckets), the query checks,
 * the cell as a box of two 4-lane vectors (its distance from q, its tightening, its split),
 * the root cell, and the node helpers of the k-nearest walk (single records, prefetches).
 * kdtree_query.c's top comment describes the walk (TRAVERSAL, K-NN); the cell and radius
 * rules both searches follow are below. Every helper a search loop calls is PM__INLINE
 * (static inline, always_inline under GCC and clang) and the setup helpers are plain static,
 * as when the searches were one file, so each file compiles them into its own loops the
 * same way. Internal: nothing here is part of the public API.
 *
 * CELL DISTANCE (Arya and Mount's). A subtree is pruned by the squared distance from q to its
 * cell, not to one split plane. The query carries the current cell as a box [lo, hi] (two
 * SSE2 registers): the root cell is the tight bounding box of the records, kept in the tree;
 * a child's cell is its parent's cut at the split, then shrunk by the child's tightening code
 * (kdtree_internal.h: 4 bits of its record's axis byte, so still nothing stored beside the
 * records). The squared distance is recomputed from the box each time, never updated by
 * difference, so it is a float lower bound of every record's dist2 in the cell (see
 * box_dist2) and the pruning stays exact. Since a code may move the far cell away from the
 * split plane, the parent's record (which lies in that plane) keeps its own bound, the far
 * cell's distance before the code. The near child is pruned too when its code moves its cell
 * out of reach. This is what makes a query beside a plane of photons, between the walls of a
 * scene, or in the empty space between clusters cost about what a query among them costs.
 * RADIUS. r2 = +INFINITY is stored internally as NaN, and every test is written as
 * !(x >= r2): against NaN that is always true, so an unlimited search also accepts records
 * whose float dist2 overflowed to +inf; against a finite r2 it is the strict x < r2. dist2 and
 * plane distances are never NaN (positions and queries are finite), so no other case arises.
 */
#ifndef PM_KDTREE_QUERY_INTERNAL_H
#define PM_KDTREE_QUERY_INTERNAL_H

#include <math.h>
#include <string.h>
/* The pruning bounds assume one float rounding per operation, like the record distances they
 * bound (GCC in ISO C mode contracts nothing; clang would fuse a * b + c). */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif
#if defined(__AVX2__)
#include <immintrin.h>
#elif defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "internal.h"
#include "kdtree_internal.h"

#if defined(__GNUC__)
#define PM__INLINE static inline __attribute__((always_inline))
#else
#define PM__INLINE static inline
#endif

typedef struct {
    const char *pos;    /* records + pos_offset */
    const char *rec;    /* records */
    size_t stride;
    const uint8_t *axb; /* axis byte of record i at axb[i * axs] */
    size_t axs;
    uint64_t L;         /* leaf nodes start here */
    int tight;          /* the axis bytes carry tightening codes */
    const struct pm_kdtree *t;
} view;

PM__INLINE const float *P(const view *v, uint64_t i) {
    return (const float *)(v->pos + i * v->stride);
}
PM__INLINE unsigned AX(const view *v, uint64_t node) {
    return v->axb[(node - 1) * v->axs] & PM__AXIS_MASK;
}

/* The pm_photon layout (stride 20, position at 0, axis in the flag byte at 18) is compiled
 * as its own instance of each search, so record addresses use a constant stride. */
PM__INLINE const float *PX(const view *v, uint64_t i, int ph) {
    return ph ? (const float *)(v->rec + i * 20) : P(v, i);
}
PM__INLINE unsigned AXX(const view *v, uint64_t node, int ph) {
    return ph ? ((const uint8_t *)v->rec)[(node - 1) * 20 + 18] & PM__AXIS_MASK : AX(v, node);
}
/* The tightening code of internal node `node` (0 when the tree keeps none). The pm_photon
 * layout always has them. */
PM__INLINE unsigned CODEX(const view *v, uint64_t node, int ph) {
    if (ph) return ((const uint8_t *)v->rec)[(node - 1) * 20 + 18] >> PM__CODE_SHIFT;
    return v->tight ? (unsigned)v->axb[(node - 1) * v->axs] >> PM__CODE_SHIFT : 0u;
}
static int is_photon_layout(const pm_kdtree *t) {
    return t->stride == 20 && t->pos_offset == 0 && t->axis_offset == 18;
}

static view make_view(const pm_kdtree *t) {
    view v;
    v.rec = t->rec;
    v.pos = t->rec + t->pos_offset;
    v.stride = t->stride;
    if (t->axis_offset >= 0) {
        v.axb = (const uint8_t *)t->rec + t->axis_offset;
        v.axs = t->stride;
    } else {
        v.axb = t->axes;
        v.axs = 1;
    }
    v.L = t->nleaves;
    v.tight = t->tight;
    v.t = t;
    return v;
}

PM__INLINE void bucket_range(const pm_kdtree *t, uint64_t node, uint64_t *b, uint64_t *e) {
    uint64_t j = node - t->nleaves;
    *b = t->ninternal + pm__cum(t, j);
    *e = *b + t->leaf_q + (j < t->leaf_extra);
}

static int check_query(const pm_kdtree *t, const float q[3], float r2) {
    if (!t || !q) return PM_EINVAL;
    if (isnan(r2)) return PM_ENONFINITE;
    if (!isfinite(q[0]) || !isfinite(q[1]) || !isfinite(q[2])) return PM_ENONFINITE;
    return PM_OK;
}

/* ---- cell distance ----------------------------------------------------------------------- */

/* A cell [lo, hi] is carried as two 4-lane vectors (lane 3 is 0 in q, lo and hi): SSE2
 * registers in the default x86-64 build, a plain struct elsewhere. */
#if defined(__SSE2__)
typedef __m128 v4;
PM__INLINE v4 v4_load3(const float *p) { return _mm_set_ps(0.0f, p[2], p[1], p[0]); }
PM__INLINE float box_dist2(v4 q, v4 lo, v4 hi) {
    v4 o = _mm_max_ps(_mm_max_ps(_mm_sub_ps(lo, q), _mm_sub_ps(q, hi)), _mm_setzero_ps());
    v4 sq = _mm_mul_ps(o, o);
    float s0 = _mm_cvtss_f32(sq), s1 = _mm_cvtss_f32(_mm_shuffle_ps(sq, sq, 1)),
          s2 = _mm_cvtss_f32(_mm_shuffle_ps(sq, sq, 2));
    return s0 + s1 + s2;
}
#else
typedef struct {
    float f[4];
} v4;
PM__INLINE v4 v4_load3(const float *p) {
    v4 x = {{p[0], p[1], p[2], 0.0f}};
    return x;
}
PM__INLINE void v4_store(float *p, v4 x) { memcpy(p, x.f, sizeof x.f); }
PM__INLINE v4 v4_load(const float *p) {
    v4 x;
    memcpy(x.f, p, sizeof x.f);
    return x;
}
PM__INLINE v4 v4_set_lane(v4 x, unsigned a, float s) {
    x.f[a] = s;
    return x;
}
PM__INLINE float box_dist2(v4 q, v4 lo, v4 hi) {
    float o[3];
    for (int b = 0; b < 3; b++) {
        float u = lo.f[b] - q.f[b], w = q.f[b] - hi.f[b];
        float x = u > w ? u : w;
        o[b] = x > 0 ? x : 0;
    }
    return o[0] * o[0] + o[1] * o[1] + o[2] * o[2];
}
#endif
/* box_dist2 is the squared distance from q to the cell [lo, hi], always by this expression in
 * this order: on each axis the offset max(lo - q, q - hi, 0) is at most |q - p| there for
 * every record p of the cell (the float subtraction is monotonic and lo <= p <= hi), so, float
 * rounding being monotonic, the sum (x, then y, then z, as in knn_dist2) is never above the
 * record's dist2, and pruning on it is exact. */

/* Shrink a cell by a tightening code c (1..15): pm__tighten's arithmetic. */
#if defined(__SSE2__)
/* In the registers (not through memory: four 4-byte stores read back as one 16-byte load),
 * from a table per code: the amount m = ext * A - (ext / 8 where the code is a 7/8 one) on
 * every lane, then lo += m on the code's low face lanes and hi -= m on its high face lanes
 * (other lanes add or subtract 0). Per lane these are pm__tighten's own operations
 * (ext * 0.5; ext - ext * 0.125, as ext * 1 is ext; ext * 0.25), so the bits are the same; a
 * masked-out lane never sees its m (which an infinite extent could make NaN). Per code: the
 * factor A per lane, then lane masks (M = all bits set): the 7/8 codes' ext / 8 to
 * subtract, the low faces that move up, the high faces that move down. */
typedef struct {
    float a[4];
    uint32_t e8[4], lo[4], hi[4];
} tighten_row;
#define M 0xFFFFFFFFu
static const tighten_row TT[16] = {
    {{0, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 0, 0}}, /* 0 */
    {{0.5f, 0, 0, 0}, {0, 0, 0, 0}, {M, 0, 0, 0}, {0, 0, 0, 0}}, /* 1 */
    {{1, 0, 0, 0}, {M, 0, 0, 0}, {M, 0, 0, 0}, {0, 0, 0, 0}}, /* 2 */
    {{0.5f, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 0, 0}, {M, 0, 0, 0}}, /* 3 */
    {{1, 0, 0, 0}, {M, 0, 0, 0}, {0, 0, 0, 0}, {M, 0, 0, 0}}, /* 4 */
    {{0, 0.5f, 0, 0}, {0, 0, 0, 0}, {0, M, 0, 0}, {0, 0, 0, 0}}, /* 5 */
    {{0, 1, 0, 0}, {0, M, 0, 0}, {0, M, 0, 0}, {0, 0, 0, 0}}, /* 6 */
    {{0, 0.5f, 0, 0}, {0, 0, 0, 0}, {0, 0, 0, 0}, {0, M, 0, 0}}, /* 7 */
    {{0, 1, 0, 0}, {0, M, 0, 0}, {0, 0, 0, 0}, {0, M, 0, 0}}, /* 8 */
    {{0, 0, 0.5f, 0}, {0, 0, 0, 0}, {0, 0, M, 0}, {0, 0, 0, 0}}, /* 9 */
    {{0, 0, 1, 0}, {0, 0, M, 0}, {0, 0, M, 0}, {0, 0, 0, 0}}, /* 10 */
    {{0, 0, 0.5f, 0}, {0, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, M, 0}}, /* 11 */
    {{0, 0, 1, 0}, {0, 0, M, 0}, {0, 0, 0, 0}, {0, 0, M, 0}}, /* 12 */
    {{0.25f, 0, 0, 0}, {0, 0, 0, 0}, {M, 0, 0, 0}, {M, 0, 0, 0}}, /* 13 */
    {{0, 0.25f, 0, 0}, {0, 0, 0, 0}, {0, M, 0, 0}, {0, M, 0, 0}}, /* 14 */
    {{0, 0, 0.25f, 0}, {0, 0, 0, 0}, {0, 0, M, 0}, {0, 0, M, 0}}, /* 15 */
};
#undef M
PM__INLINE __m128 tt_mask(const uint32_t *m) {
    return _mm_castsi128_ps(_mm_loadu_si128((const __m128i *)m));
}
PM__INLINE void box_tighten(v4 *lo, v4 *hi, unsigned c) {
    const tighten_row *t = &TT[c];
    __m128 ext = _mm_sub_ps(*hi, *lo);
    __m128 e8 = _mm_and_ps(tt_mask(t->e8), _mm_mul_ps(ext, _mm_set1_ps(0.125f)));
    __m128 m = _mm_sub_ps(_mm_mul_ps(ext, _mm_loadu_ps(t->a)), e8);
    *lo = _mm_add_ps(*lo, _mm_and_ps(tt_mask(t->lo), m));
    *hi = _mm_sub_ps(*hi, _mm_and_ps(tt_mask(t->hi), m));
}
#else
static void box_tighten(v4 *lo, v4 *hi, unsigned c) {
    float l[4], h[4];
    v4_store(l, *lo);
    v4_store(h, *hi);
    pm__tighten(l, h, c);
    *lo = v4_load(l);
    *hi = v4_load(h);
}
#endif

/* One split of a descent, the same in every search: node's cell [lo, hi] is cut at 'split'
 * on axis a, q's side being 'near'. Out: the far child's cell (flo, fhi) with its dist2 from
 * q before (*rr) and after (*rf) the far child's own code; [lo, hi] becomes the near child's
 * cell before its own code (near_code applies that one). */
PM__INLINE void split_cell(const view *v, int ph, v4 qv, uint64_t near, unsigned a, float split,
                           v4 *lo, v4 *hi, v4 *flo, v4 *fhi, float *rr, float *rf) {
#if defined(__SSE2__)
    /* Without a branch on q's side (a coin toss at every node): lane a of the far cell's hi
     * (near is the right child) or lo (near is the left one) becomes split, and of the near
     * cell's lo or hi respectively. */
    __m128 lane = _mm_castsi128_ps(
        _mm_cmpeq_epi32(_mm_set1_epi32((int)a), _mm_set_epi32(3, 2, 1, 0)));
    __m128 right = _mm_castsi128_ps(_mm_set1_epi32(-(int)(near & 1)));
    __m128 m_hi = _mm_and_ps(lane, right), m_lo = _mm_andnot_ps(right, lane);
    __m128 sp = _mm_set1_ps(split);
#define PM__SEL(m, x, y) _mm_or_ps(_mm_and_ps((m), (x)), _mm_andnot_ps((m), (y)))
    *flo = PM__SEL(m_lo, sp, *lo);
    *fhi = PM__SEL(m_hi, sp, *hi);
    *lo = PM__SEL(m_hi, sp, *lo);
    *hi = PM__SEL(m_lo, sp, *hi);
#undef PM__SEL
#else
    *flo = *lo, *fhi = *hi;
    if (near & 1) *fhi = v4_set_lane(*hi, a, split), *lo = v4_set_lane(*lo, a, split);
    else *flo = v4_set_lane(*lo, a, split), *hi = v4_set_lane(*hi, a, split);
#endif
    *rr = *rf = box_dist2(qv, *flo, *fhi);
    if ((near ^ 1) < v->L) {
        unsigned c = CODEX(v, near ^ 1, ph);
        if (c) {
            box_tighten(flo, fhi, c);
            *rf = box_dist2(qv, *flo, *fhi);
        }
    }
}

/* The near child's own code: shrinks [lo, hi] and returns its dist2 from q, or -1 when the
 * child has no code (its cell is the parent's on q's side: nothing new to prune on). */
PM__INLINE float near_code(const view *v, int ph, v4 qv, uint64_t near, v4 *lo, v4 *hi) {
    unsigned c = near < v->L ? CODEX(v, near, ph) : 0;
    if (!c) return -1.0f;
    box_tighten(lo, hi, c);
    return box_dist2(qv, *lo, *hi);
}

/* The root cell: the tight bounding box, shrunk by the root's own code (kdtree.c never
 * writes one there today, but the rule is the same for every node). */
static void root_box(const view *v, int ph, float lo[3], float hi[3]) {
    const pm_kdtree *t = v->t;
    for (int b = 0; b < 3; b++) lo[b] = t->lo[b], hi[b] = t->hi[b];
    if (v->L > 1) pm__tighten(lo, hi, CODEX(v, 1, ph));
}

/* ---- the k-nearest walk's node helpers: single records, prefetches ------------------------ */

/* A uniform subtree that is a single record: an internal node just above two empty buckets
 * (common with B = 1, where half the last internal level has no children). Handled inline. */
PM__INLINE int single_record(const view *v, uint64_t node) {
    if (2 * node < v->L) return 0;
    const pm_kdtree *t = v->t;
    return pm__cum(t, 2 * node + 2 - v->L) == pm__cum(t, 2 * node - v->L);
}

/* When near's children are buckets (the two are adjacent in memory), start loading them:
 * the bucket scan is where a query waits for memory most. At most PM__PREFETCH_MAX bytes (1280:
 * both whole buckets up to B = 32; measured in docs/BENCHMARKS.md, "What did not pay off").
 * One level earlier, when near's grandchildren are the buckets, the first two lines of each
 * of the four (the hardware prefetcher follows a stream once it has started): 1.02-1.07x on
 * the race's 1M cells, more lines per bucket gained nothing (experiments.csv). */
PM__INLINE void prefetch_buckets(const view *v, uint64_t near) {
    const uint64_t L = v->L;
    if (near >= (L >> 2) && near < (L >> 1)) {
        const int two = v->t->leaf_q * v->stride > 64; /* r + 64 stays inside every bucket */
        for (uint64_t j = 4 * near - L; j < 4 * near - L + 4; j++) {
            const char *r = v->rec + (v->t->ninternal + pm__cum(v->t, j)) * v->stride;
            __builtin_prefetch(r);
            if (two) __builtin_prefetch(r + 64);
        }
    } else if (near >= (L >> 1) && near < L) {
        uint64_t b = v->t->ninternal + pm__cum(v->t, 2 * near - L);
        const char *r = v->rec + b * v->stride;
        uint64_t bytes = (uint64_t)v->t->bucket * v->stride * 2;
#ifndef PM__PREFETCH_MAX
#define PM__PREFETCH_MAX 1280
#endif
        if (bytes > PM__PREFETCH_MAX) bytes = PM__PREFETCH_MAX;
        for (uint64_t o = 0; o < bytes; o += 64) __builtin_prefetch(r + o);
    }
}

/* Start loading the records two and three levels below internal node p while its own record
 * is compared: the grandchildren (records 4p-1 .. 4p+2, contiguous) and the great-grandchildren
 * (8p-1 .. 8p+6, 160 bytes: the first three of the lines they span), so the misses of the
 * levels below overlap. (The grandchildren alone: 1-5% slower on the race's 1M cells, and
 * a fourth level too gained nothing: docs/BENCHMARKS.md, experiments.csv.) */
PM__INLINE void prefetch_below(const view *v, uint64_t p) {
    const uint64_t L = v->L;
    if (4 * p < L) __builtin_prefetch(v->rec + (4 * p - 1) * v->stride);
    if (8 * p < L) {
        const char *r = v->rec + (8 * p - 1) * v->stride;
        __builtin_prefetch(r);
        __builtin_prefetch(r + 64);
        __builtin_prefetch(r + 128);
    }
}

#endif /* PM_KDTREE_QUERY_INTERNAL_H */
