/* kdtree_query.c: k-nearest, radius and predicate queries on the heap kd-tree.
 *
 * TRAVERSAL. Christensen's "iteration instead of recursion": walk down, at every split into
 * the child whose cell is closer to q (q's side of the split unless the other child's
 * tightened cell is closer), pushing (bounds, other child, its cell) on a fixed stack of at
 * most D entries; scan the bucket; then pop entries until one has a bound < r2, where r2 is
 * the current search radius. Only then is that node's own record tested, and the walk
 * continues down the other child if its cell is still within reach. The recursive version
 * makes the same decisions in the same order, so both return identical arrays. (Best-first
 * order was measured and lost: bench/results/experiments.csv.)
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
 *
 * K-NN. The result set is internal.h's (THE K-NEAREST RESULT SET): the k smallest
 * (dist2, index) within max_dist2, kept in a max-heap for k > 64; for k <= 64 the same set is
 * kept here in unordered slots (THE SMALL-K RESULT SET below; internal.h's sorted array or
 * heap where SSE2 is missing). The
 * search's bound r2 is that set's `lim`: max_dist2 until k are found, then the float just
 * above the k-th dist2, so that a record or a cell at exactly the k-th distance is still
 * looked at (a tied record with a smaller index must win, wherever it lies). Every test stays
 * !(x >= r2). The answer is thus the same for any visiting order.
 *
 * UNIFORM SUBTREES (axis code 3, all records at one position) are handled as one distance:
 * records are taken from them only while they can still enter the result, so a million
 * identical points cost O(k) instead of a full scan.
 */
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

/* ---- k nearest --------------------------------------------------------------------------- */

typedef struct {
    float q[3];
    float r2;             /* the result set's bound (lim): offer only !(d2 >= r2); NaN = none */
    pm_neighbor *out;
    unsigned k, found;
    const float *nrm;     /* ellipsoid metric normal, or NULL */
    float sq1;            /* squash - 1 */
    pm_filter_fn filter;
    void *user;
    uint64_t nodes, evals;
    float lo[3], hi[3];   /* the root cell */
    float rd;             /* dist2 from q to it */
    struct knn_small *sm; /* the small-k result set (below), or NULL: pm__knn_offer on out */
    unsigned smax;        /* its slot of the largest (dist2, index), once k are held */
} knn_state;

/* THE SMALL-K RESULT SET (k <= PM__KNN_BLOCK_MAX = 64, SSE2). The same set as pm__knn_offer's
 * (the k smallest (dist2, index) offered), kept unordered in slots beside the caller's array:
 * an entering record overwrites the slot of the largest key, and the next largest is found
 * without a data-dependent branch. For k <= 16, by four SSE2 max and compare steps over 16
 * slots (unused ones hold -1, which no dist2 is), instead of an insertion whose loop exit
 * mispredicted about once per entry (perf: 10-13% of a clustered empty-space query at k = 10
 * on one branch; 1.03x). For 16 < k <= 64, in blocks of 4 slots with each block's largest
 * dist2 kept: an entry refreshes its block's, then the largest of the 16 block maxima and its
 * lane are found the same way, instead of the binary heap's sift-down (1.08-1.15x at k = 50).
 * Equal dist2 at the maximum (rare) are settled by index in a scalar loop. knn_finish writes
 * the set to out sorted by (dist2, index) for k <= 16 or with PM_SORT, else as a max-heap, as
 * kdtree.h promises. Measured in bench/results/experiments.csv. */
#if !defined(PM__KNN_SMALL) && defined(__SSE2__)
#define PM__KNN_SMALL 1
#endif
#ifndef PM__KNN_BLOCK_MAX
#define PM__KNN_BLOCK_MAX 64u
#endif
_Static_assert(PM__KNN_BLOCK_MAX >= 16 && PM__KNN_BLOCK_MAX <= 64, "16 blocks of 4 slots at most");
typedef struct knn_small {
    _Alignas(16) float d[PM__KNN_BLOCK_MAX > 16 ? PM__KNN_BLOCK_MAX : 16];
    _Alignas(16) float bm[16]; /* k > 16: the largest dist2 of each block of 4 slots */
    uint32_t i[PM__KNN_BLOCK_MAX > 16 ? PM__KNN_BLOCK_MAX : 16];
} knn_small;

#if defined(__SSE2__) && PM__KNN_SMALL
PM__INLINE __m128 hmax4(__m128 x) {
    x = _mm_max_ps(x, _mm_shuffle_ps(x, x, 0xB1));
    return _mm_max_ps(x, _mm_shuffle_ps(x, x, 0x4E));
}
/* The 16-bit mask of the lanes of a[0..16) equal to the broadcast x. */
PM__INLINE unsigned eq16(const float *a, __m128 x) {
    return (unsigned)_mm_movemask_ps(_mm_cmpeq_ps(_mm_load_ps(a), x)) |
           (unsigned)_mm_movemask_ps(_mm_cmpeq_ps(_mm_load_ps(a + 4), x)) << 4 |
           (unsigned)_mm_movemask_ps(_mm_cmpeq_ps(_mm_load_ps(a + 8), x)) << 8 |
           (unsigned)_mm_movemask_ps(_mm_cmpeq_ps(_mm_load_ps(a + 12), x)) << 12;
}
PM__INLINE __m128 max16(const float *a) {
    return hmax4(_mm_max_ps(_mm_max_ps(_mm_load_ps(a), _mm_load_ps(a + 4)),
                            _mm_max_ps(_mm_load_ps(a + 8), _mm_load_ps(a + 12))));
}
/* The slot of the largest (dist2, index) among the 16 (at least one slot holds a dist2). */
PM__INLINE unsigned small_argmax(const knn_small *m) {
    __m128 x = max16(m->d);
    unsigned mk = eq16(m->d, x);
    unsigned j = (unsigned)__builtin_ctz(mk);
    for (mk &= mk - 1; mk; mk &= mk - 1) { /* equal dist2: the larger index is the larger key */
        unsigned l = (unsigned)__builtin_ctz(mk);
        if (m->i[l] > m->i[j]) j = l;
    }
    return j;
}
/* k > 16: slot `changed` was written; its block's maximum is refreshed, then the largest
 * block, then its lane. Equal dist2 at the maximum: every slot is looked at. */
PM__INLINE unsigned block_argmax(knn_small *m, unsigned changed, unsigned k) {
    unsigned b = changed >> 2;
    _mm_store_ss(&m->bm[b], hmax4(_mm_load_ps(m->d + 4 * b)));
    __m128 x = max16(m->bm);
    unsigned mb = eq16(m->bm, x);
    unsigned c = (unsigned)__builtin_ctz(mb);
    unsigned ml = (unsigned)_mm_movemask_ps(_mm_cmpeq_ps(_mm_load_ps(m->d + 4 * c), x));
    if (!(mb & (mb - 1)) && !(ml & (ml - 1))) return 4 * c + (unsigned)__builtin_ctz(ml);
    float top = _mm_cvtss_f32(x);
    unsigned j = k;
    for (unsigned l = 0; l < k; l++)
        if (m->d[l] == top && (j == k || m->i[l] > m->i[j])) j = l;
    return j;
}

PM__INLINE int small_offer(knn_state *s, float d2, uint32_t idx) {
    knn_small *m = s->sm;
    unsigned f = s->found, j, k = s->k;
    if (f < k) {
        m->d[f] = d2, m->i[f] = idx;
        s->found = ++f;
        if (f < k) return 1;
        if (k > 16) {
            for (unsigned b = 0; b < 16; b++)
                m->bm[b] = 4 * b < k ? _mm_cvtss_f32(hmax4(_mm_load_ps(m->d + 4 * b))) : -1.0f;
        }
        j = f - 1;
    } else {
        j = s->smax;
        if (d2 == m->d[j] && idx > m->i[j]) return 0;
        m->d[j] = d2, m->i[j] = idx;
    }
    j = k > 16 ? block_argmax(m, j, k) : small_argmax(m);
    s->smax = j;
    s->r2 = pm__nextup(m->d[j]);
    return 1;
}
#endif

/* Precondition: !(d2 >= s->r2). Returns 0 when the record lost a tie (pm__knn_offer). */
PM__INLINE int knn_push(knn_state *s, float d2, uint32_t idx) {
#if defined(__SSE2__) && PM__KNN_SMALL
    if (s->sm) return small_offer(s, d2, idx);
#endif
    return pm__knn_offer(s->out, s->k, &s->found, &s->r2, d2, idx);
}

PM__INLINE float knn_dist2(const knn_state *s, const float *p, int metric) {
    float dx = s->q[0] - p[0], dy = s->q[1] - p[1], dz = s->q[2] - p[2];
    float d2 = dx * dx + dy * dy + dz * dz;
    if (metric) {
        float dn = dx * s->nrm[0] + dy * s->nrm[1] + dz * s->nrm[2];
        d2 += s->sq1 * (dn * dn);
    }
    return d2;
}

PM__INLINE void knn_consider(knn_state *s, const view *v, uint64_t i, int metric, int filter,
                             int ph, int cnt) {
    float d2 = knn_dist2(s, PX(v, i, ph), metric);
    if (cnt) s->evals++;
    if (!(d2 >= s->r2)) {
        if (filter && !s->filter(s->user, v->rec + i * v->stride, (uint32_t)i)) return;
        knn_push(s, d2, (uint32_t)i);
    }
}

/* A uniform subtree rooted at internal node `node`: one distance for all its records, offered
 * in increasing index order (pm__subtree_ranges lists its ranges that way). */
static void knn_uniform(knn_state *s, const view *v, uint64_t node, int metric, int filter) {
    float d2 = knn_dist2(s, P(v, node - 1), metric);
    s->evals++;
    if (d2 >= s->r2) return;
    pm__range r[PM_KDTREE_MAX_DEPTH + 1];
    int nr = pm__subtree_ranges(v->t, node, pm__ilog2(node), r);
    for (int g = 0; g < nr; g++) {
        for (uint64_t i = r[g].begin; i < r[g].end; i++) {
            if (d2 >= s->r2) return;
            if (filter && !s->filter(s->user, v->rec + i * v->stride, (uint32_t)i)) continue;
            /* indices only grow from here on, so once one loses the tie all the rest do */
            if (!knn_push(s, d2, (uint32_t)i)) return;
        }
    }
}

PM__INLINE void knn_bucket(knn_state *s, const view *v, uint64_t node, int metric, int filter,
                           int ph, int cnt) {
    uint64_t b, e;
    bucket_range(v->t, node, &b, &e);
    uint64_t i = b;
#if defined(__AVX2__)
    if (ph && !metric) {
        /* SIMD=avx2: eight photons at a time, the same way as the SSE2 loop below (records
         * j and j + 4 share a 256-bit row, the 4x4 transpose works within each half). */
        const __m256 qx = _mm256_set1_ps(s->q[0]), qy = _mm256_set1_ps(s->q[1]),
                     qz = _mm256_set1_ps(s->q[2]);
        for (; i + 8 <= e; i += 8) {
            const float *p0 = PX(v, i, 1);
#define PM__ROW(j) _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p0 + 5 * (j))), \
                                        _mm_loadu_ps(p0 + 5 * ((j) + 4)), 1)
            __m256 r0 = PM__ROW(0), r1 = PM__ROW(1), r2v = PM__ROW(2), r3 = PM__ROW(3);
#undef PM__ROW
            __m256 t0 = _mm256_unpacklo_ps(r0, r1), t1 = _mm256_unpackhi_ps(r0, r1),
                   t2 = _mm256_unpacklo_ps(r2v, r3), t3 = _mm256_unpackhi_ps(r2v, r3);
            __m256 dx = _mm256_sub_ps(qx, _mm256_shuffle_ps(t0, t2, 0x44)),
                   dy = _mm256_sub_ps(qy, _mm256_shuffle_ps(t0, t2, 0xEE)),
                   dz = _mm256_sub_ps(qz, _mm256_shuffle_ps(t1, t3, 0x44));
            __m256 d2 = _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(dx, dx), _mm256_mul_ps(dy, dy)),
                                      _mm256_mul_ps(dz, dz));
            int m = _mm256_movemask_ps(_mm256_cmp_ps(d2, _mm256_set1_ps(s->r2), _CMP_NGE_UQ));
            if (cnt) s->evals += 8;
            if (!m) continue;
            float dv[8];
            _mm256_storeu_ps(dv, d2);
            do { /* lanes in order; a push shrinks r2, so m is narrowed again after it */
                unsigned l = (unsigned)__builtin_ctz((unsigned)m);
                m &= m - 1;
                if (filter && !s->filter(s->user, v->rec + (i + l) * v->stride, (uint32_t)(i + l)))
                    continue;
                knn_push(s, dv[l], (uint32_t)(i + l));
                m &= _mm256_movemask_ps(_mm256_cmp_ps(d2, _mm256_set1_ps(s->r2), _CMP_NGE_UQ));
            } while (m);
        }
    }
#endif
#if defined(__SSE2__)
    if (ph && !metric) {
        /* Four photons at a time: a 16-byte load at each record start (x, y, z and the RGBE
         * bytes, all inside the 20-byte record), a 4x4 transpose, and the same float
         * expression as knn_dist2 (separate multiplies and adds, so bit-identical). In two
         * passes over up to 64 records: first every distance and one bit mask of those below
         * r2 as it was on entry, with no branch; then the records of the mask in order, each
         * tested again against the current r2 (a push shrinks it), exactly as the scalar loop
         * would take them. (One pass, branching on each group of four and narrowing its mask
         * after each push, was 0.95-0.97x this on clustered data: experiments.csv.) */
        const __m128 qx = _mm_set1_ps(s->q[0]), qy = _mm_set1_ps(s->q[1]),
                     qz = _mm_set1_ps(s->q[2]);
        while (i + 4 <= e) {
            unsigned ng = (unsigned)((e - i) / 4);
            if (ng > 16) ng = 16;
            _Alignas(16) float dv[64];
            uint64_t M = 0;
            const __m128 rv = _mm_set1_ps(s->r2);
            for (unsigned g = 0; g < ng; g++) {
                const float *p0 = PX(v, i + 4 * g, 1);
                __m128 r0 = _mm_loadu_ps(p0), r1 = _mm_loadu_ps(p0 + 5),
                       r2v = _mm_loadu_ps(p0 + 10), r3 = _mm_loadu_ps(p0 + 15);
                _MM_TRANSPOSE4_PS(r0, r1, r2v, r3);
                __m128 dx = _mm_sub_ps(qx, r0), dy = _mm_sub_ps(qy, r1), dz = _mm_sub_ps(qz, r2v);
                __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)),
                                       _mm_mul_ps(dz, dz));
                _mm_store_ps(dv + 4 * g, d2);
                M |= (uint64_t)_mm_movemask_ps(_mm_cmpnge_ps(d2, rv)) << (4 * g);
            }
            if (cnt) s->evals += 4 * ng;
            while (M) {
                unsigned l = (unsigned)__builtin_ctzll(M);
                M &= M - 1;
                if (dv[l] >= s->r2) continue;
                if (filter && !s->filter(s->user, v->rec + (i + l) * v->stride, (uint32_t)(i + l)))
                    continue;
                knn_push(s, dv[l], (uint32_t)(i + l));
            }
            i += 4 * ng;
        }
    }
#endif
    for (; i < e; i++) knn_consider(s, v, i, metric, filter, ph, cnt);
}

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

/* Depth first from `node0`, whose cell is [lo0, hi0] at dist2 cd0 from q. */
PM__INLINE void knn_dfs(knn_state *io, const view *v, uint64_t node0, v4 lo0, v4 hi0, float cd0,
                        int metric, int filter, int ph, int cnt) {
    /* Work on a local copy whose address never escapes, so the compiler keeps r2, found and
     * the query in registers; the rare uniform case goes through memory. */
    knn_state ls = *io, *s = &ls;
    /* Far children still to search: the bound of the parent's record (its dist2 from q is at
     * least that of the far cell before the far child's own code shrinks it), the far cell's
     * distance, and the far cell. */
    struct {
        v4 lo, hi;
        float rr, rf;
        uint32_t node;
    } stack[PM_KDTREE_MAX_DEPTH];
    int sp = 0;
    uint64_t node = node0;
    const uint64_t L = v->L;
    const v4 qv = v4_load3(s->q);
    v4 lo = lo0, hi = hi0;
    float cd = cd0; /* dist2 from q to the current cell [lo, hi] */
    if (cd >= s->r2) return; /* out of reach */
    for (;;) {
        while (node < L) {
            prefetch_below(v, node);
            unsigned a = AXX(v, node, ph);
            if (cnt) s->nodes++;
            if (a == PM__AXIS_UNIFORM) {
                if (single_record(v, node)) {
                    knn_consider(s, v, node - 1, metric, filter, ph, cnt);
                } else {
                    *io = ls;
                    knn_uniform(io, v, node, metric, filter);
                    ls = *io;
                }
                goto pop;
            }
            float split = PX(v, node - 1, ph)[a];
            float d = s->q[a] - split;
            uint64_t near = 2 * node + (d >= 0);
            /* The two children's cells and distances: the far one's (rf; rr before its own
             * code, the bound of this node's record, which lies in that cell's boundary
             * plane), and the near one's: this cell on the split axis's near side (the same
             * distance cd), unless its own code moves it away from q. */
            v4 flo, fhi;
            float rr, rf;
            split_cell(v, ph, qv, near, a, split, &lo, &hi, &flo, &fhi, &rr, &rf);
            float dn = near_code(v, ph, qv, near, &lo, &hi);
            if (dn < 0) dn = cd;
            /* VISITING ORDER: the child whose cell is closer first (q's side on a tie); the
             * other waits on the stack with the record's bound rr. r2 only shrinks, so an
             * entry already out of reach (rr, a bound of both the record and that child) is
             * never pushed. The recursive search makes the same decisions. */
            if (rf < dn) {
                stack[sp].lo = lo, stack[sp].hi = hi;
                stack[sp].rf = dn;
                lo = flo, hi = fhi;
                cd = rf;
                near ^= 1;
            } else {
                stack[sp].lo = flo, stack[sp].hi = fhi;
                stack[sp].rf = rf;
                cd = dn;
            }
            stack[sp].rr = rr;
            stack[sp].node = (uint32_t)(near ^ 1);
            sp += !(rr >= s->r2);
            node = near;
            prefetch_buckets(v, near);
            if (cd >= s->r2) goto pop;
        }
        if (cnt) s->nodes++;
        knn_bucket(s, v, node, metric, filter, ph, cnt);
    pop:
        for (;;) {
            if (sp == 0) {
                *io = ls;
                return;
            }
            sp--;
            if (stack[sp].rr >= s->r2) continue;
            /* the parent's record lies in the far cell's boundary plane before the far
             * child's code shrinks the cell: no closer than rr */
            node = stack[sp].node;
            knn_consider(s, v, (node >> 1) - 1, metric, filter, ph, cnt);
            if (stack[sp].rf >= s->r2) continue;
            lo = stack[sp].lo, hi = stack[sp].hi;
            cd = stack[sp].rf;
            break;
        }
    }
}

PM__INLINE void knn_iter(knn_state *s, const view *v, int metric, int filter, int ph, int cnt) {
    knn_dfs(s, v, 1, v4_load3(s->lo), v4_load3(s->hi), s->rd, metric, filter, ph, cnt);
}

#define PM__KNN_REC(name, metric, filter, ph, cnt)                                        \
    static void name(knn_state *s, const view *v, uint64_t node, v4 lo, v4 hi, float cd) { \
        if (cnt) s->nodes++;                                                             \
        if (node >= v->L) {                                                              \
            knn_bucket(s, v, node, metric, filter, ph, cnt);                             \
            return;                                                                      \
        }                                                                                \
        prefetch_below(v, node);                                                         \
        unsigned a = AXX(v, node, ph);                                                   \
        if (a == PM__AXIS_UNIFORM) {                                                     \
            if (single_record(v, node))                                                  \
                knn_consider(s, v, node - 1, metric, filter, ph, cnt);                   \
            else                                                                         \
                knn_uniform(s, v, node, metric, filter);                                 \
            return;                                                                      \
        }                                                                                \
        float split = PX(v, node - 1, ph)[a];                                            \
        float d = s->q[a] - split;                                                       \
        uint64_t near = 2 * node + (d >= 0);                                             \
        const v4 qv = v4_load3(s->q);                                                    \
        v4 flo, fhi, nlo = lo, nhi = hi;                                                 \
        float rr, rf;                                                                    \
        split_cell(v, ph, qv, near, a, split, &nlo, &nhi, &flo, &fhi, &rr, &rf);         \
        float dn = near_code(v, ph, qv, near, &nlo, &nhi);                               \
        if (dn < 0) dn = cd;                                                             \
        if (rf < dn) { /* the closer cell first, as the iterative search */             \
            v4 tlo = nlo, thi = nhi;                                                     \
            float td = dn;                                                               \
            nlo = flo, nhi = fhi, dn = rf;                                               \
            flo = tlo, fhi = thi, rf = td;                                               \
            near ^= 1;                                                                   \
        }                                                                                \
        prefetch_buckets(v, near);                                                       \
        if (!(dn >= s->r2)) name(s, v, near, nlo, nhi, dn);                              \
        if (!(rr >= s->r2)) {                                                            \
            knn_consider(s, v, node - 1, metric, filter, ph, cnt);                       \
            if (!(rf >= s->r2)) name(s, v, near ^ 1, flo, fhi, rf);                      \
        }                                                                                \
    }
/* The recursive search, one instance per layout and counting choice like the iterative one,
 * so that comparing the two compares recursion with iteration and nothing else. */
PM__KNN_REC(knn_rec_gen, 0, 0, 0, 1)
PM__KNN_REC(knn_rec_ph, 0, 0, 1, 0)
PM__KNN_REC(knn_rec_ph_cnt, 0, 0, 1, 1)

static void knn_iter_gen(knn_state *s, const view *v) { knn_iter(s, v, 0, 0, 0, 1); }
static void knn_iter_ph(knn_state *s, const view *v) { knn_iter(s, v, 0, 0, 1, 0); }
static void knn_iter_ph_cnt(knn_state *s, const view *v) { knn_iter(s, v, 0, 0, 1, 1); }
static void knn_iter_general(knn_state *s, const view *v, int ph) {
    int metric = s->nrm != NULL, filter = s->filter != NULL;
    if (ph) {
        if (metric && filter)
            knn_iter(s, v, 1, 1, 1, 1);
        else if (metric)
            knn_iter(s, v, 1, 0, 1, 1);
        else if (filter)
            knn_iter(s, v, 0, 1, 1, 1);
        else
            knn_iter(s, v, 0, 0, 1, 1);
    } else {
        if (metric && filter)
            knn_iter(s, v, 1, 1, 0, 1);
        else if (metric)
            knn_iter(s, v, 1, 0, 0, 1);
        else if (filter)
            knn_iter(s, v, 0, 1, 0, 1);
        else
            knn_iter(s, v, 0, 0, 0, 1);
    }
}

/* Common front end. Returns > 0 to go on with the search, else the final return value. */
static int knn_setup(knn_state *s, knn_small *sm, const pm_kdtree *t, const float q[3],
                     unsigned k, float max_dist2, pm_neighbor *out) {
    int rc = check_query(t, q, max_dist2);
    if (rc < 0) return rc;
    if (k == 0 || t->n == 0 || !(max_dist2 > 0)) return 0;
    if (!out) return PM_EINVAL;
    memset(s, 0, sizeof *s);
    s->q[0] = q[0], s->q[1] = q[1], s->q[2] = q[2];
    s->r2 = max_dist2 == INFINITY ? NAN : max_dist2;
    s->out = out;
    s->k = k;
#if defined(__SSE2__) && PM__KNN_SMALL
    if (k <= PM__KNN_BLOCK_MAX) {
        unsigned nd = k <= 16 ? 16 : (k + 3) & ~3u;
        for (unsigned j = 0; j < nd; j++) sm->d[j] = -1.0f, sm->i[j] = 0;
        s->sm = sm;
    }
#else
    (void)sm;
#endif
    view v = make_view(t);
    root_box(&v, is_photon_layout(t), s->lo, s->hi);
    s->rd = box_dist2(v4_load3(s->q), v4_load3(s->lo), v4_load3(s->hi));
    return 1;
}

static int knn_finish(knn_state *s, unsigned flags, pm_query_stats *stats) {
    if (stats) {
        stats->nodes_visited += s->nodes;
        stats->dist_evals += s->evals;
    }
    if (s->sm) { /* the small-k set to out: sorted for k <= 16 or PM_SORT, else a heap */
        for (unsigned j = 0; j < s->found; j++) {
            s->out[j].dist2 = s->sm->d[j];
            s->out[j].index = s->sm->i[j];
        }
        if (s->k <= 16 || (flags & PM_SORT)) pm__nb_sort_keys(s->out, s->found);
        else pm__heapify(s->out, s->found); /* kdtree.h: a max-heap for k > 16 */
        return (int)s->found;
    }
    if ((flags & PM_SORT) && !pm__knn_is_sorted(s->k)) {
        if (s->found <= PM__SORT_KEYS_MAX) pm__nb_sort_keys(s->out, s->found);
        else pm__nb_sort(s->out, s->found);
    }
    return (int)s->found;
}

int pm_kdtree_knn(const pm_kdtree *tree, const float q[3], unsigned k, float max_dist2,
                  pm_neighbor *out, unsigned flags, pm_query_stats *stats) {
    knn_state s;
    knn_small sm;
    int rc = knn_setup(&s, &sm, tree, q, k, max_dist2, out);
    if (rc <= 0) return rc;
    view v = make_view(tree);
    if (!is_photon_layout(tree))
        knn_iter_gen(&s, &v);
    else if (stats)
        knn_iter_ph_cnt(&s, &v);
    else
        knn_iter_ph(&s, &v);
    return knn_finish(&s, flags, stats);
}

int pm_kdtree_knn_recursive(const pm_kdtree *tree, const float q[3], unsigned k,
                            float max_dist2, pm_neighbor *out, unsigned flags,
                            pm_query_stats *stats) {
    knn_state s;
    knn_small sm;
    int rc = knn_setup(&s, &sm, tree, q, k, max_dist2, out);
    if (rc <= 0) return rc;
    if (s.rd >= s.r2) return 0; /* the whole tree is out of reach */
    view v = make_view(tree);
    if (!is_photon_layout(tree))
        knn_rec_gen(&s, &v, 1, v4_load3(s.lo), v4_load3(s.hi), s.rd);
    else if (stats)
        knn_rec_ph_cnt(&s, &v, 1, v4_load3(s.lo), v4_load3(s.hi), s.rd);
    else
        knn_rec_ph(&s, &v, 1, v4_load3(s.lo), v4_load3(s.hi), s.rd);
    return knn_finish(&s, flags, stats);
}

int pm_kdtree_knn_ex(const pm_kdtree *tree, const float q[3], unsigned k, float max_dist2,
                     const pm_knn_options *opt, pm_neighbor *out, pm_query_stats *stats) {
    knn_state s;
    knn_small sm;
    int rc = knn_setup(&s, &sm, tree, q, k, max_dist2, out);
    if (rc <= 0) return rc;
    unsigned flags = 0;
    if (opt) {
        flags = opt->flags;
        if (opt->normal) {
            if (isnan(opt->squash)) return PM_ENONFINITE;
            if (opt->squash > 1) {
                const float *nm = opt->normal;
                if (!isfinite(nm[0]) || !isfinite(nm[1]) || !isfinite(nm[2]) ||
                    !isfinite(opt->squash))
                    return PM_ENONFINITE;
                s.nrm = nm;
                s.sq1 = opt->squash - 1;
            }
        }
        s.filter = opt->filter;
        s.user = opt->filter_user;
    }
    view v = make_view(tree);
    knn_iter_general(&s, &v, is_photon_layout(tree));
    return knn_finish(&s, flags, stats);
}

int pm_kdtree_nearest_if(const pm_kdtree *tree, const float q[3], float max_dist2,
                         pm_filter_fn pred, void *user, pm_neighbor *out,
                         pm_query_stats *stats) {
    knn_state s;
    knn_small sm;
    int rc = knn_setup(&s, &sm, tree, q, 1, max_dist2, out);
    if (rc <= 0) return rc;
    s.filter = pred;
    s.user = user;
    view v = make_view(tree);
    knn_iter_general(&s, &v, is_photon_layout(tree));
    return knn_finish(&s, 0, stats);
}

/* ---- radius ------------------------------------------------------------------------------ */

typedef struct {
    float q[3];
    float r2; /* NaN = unlimited */
    pm_neighbor *out;
    size_t cap;
    uint64_t total;
    pm_visit_fn fn;
    void *user;
    int stop;
    uint64_t nodes, evals;
    float lo[3], hi[3]; /* the root cell */
} rad_state;

PM__INLINE void rad_take(rad_state *s, uint64_t i, float d2) {
    if (s->fn) {
        s->total++;
        if (s->fn(s->user, (uint32_t)i, d2)) s->stop = 1;
        return;
    }
    if (s->total < s->cap) {
        s->out[s->total].dist2 = d2;
        s->out[s->total].index = (uint32_t)i;
    }
    s->total++;
}

PM__INLINE float rad_dist2(const rad_state *s, const float *p) {
    float dx = s->q[0] - p[0], dy = s->q[1] - p[1], dz = s->q[2] - p[2];
    return dx * dx + dy * dy + dz * dz;
}

PM__INLINE void rad_consider(rad_state *s, const view *v, uint64_t i) {
    float d2 = rad_dist2(s, P(v, i));
    s->evals++;
    if (!(d2 >= s->r2)) rad_take(s, i, d2);
}

static void rad_uniform(rad_state *s, const view *v, uint64_t node) {
    float d2 = rad_dist2(s, P(v, node - 1));
    s->evals++;
    if (d2 >= s->r2) return;
    pm__range r[PM_KDTREE_MAX_DEPTH + 1];
    int nr = pm__subtree_ranges(v->t, node, pm__ilog2(node), r);
    for (int g = 0; g < nr; g++) {
        if (!s->fn && s->total >= s->cap) { /* nothing more to write: just count */
            s->total += r[g].end - r[g].begin;
            continue;
        }
        for (uint64_t i = r[g].begin; i < r[g].end && !s->stop; i++) rad_take(s, i, d2);
        if (s->stop) return;
    }
}

static void rad_iter(rad_state *s, const view *v) {
    struct {
        v4 lo, hi;
        uint32_t node;
        float rf;
    } stack[PM_KDTREE_MAX_DEPTH];
    int sp = 0;
    uint64_t node = 1;
    const uint64_t L = v->L;
    const v4 qv = v4_load3(s->q);
    v4 lo = v4_load3(s->lo), hi = v4_load3(s->hi);
    if (box_dist2(qv, lo, hi) >= s->r2) return; /* the whole tree is out of reach */
    for (;;) {
        while (node < L) {
            unsigned a = AX(v, node);
            s->nodes++;
            if (a == PM__AXIS_UNIFORM) {
                rad_uniform(s, v, node);
                goto pop;
            }
            float split = P(v, node - 1)[a];
            float d = s->q[a] - split;
            uint64_t near = 2 * node + (d >= 0);
            /* r2 is fixed: when the far cell (before the far child's own code) is out of
             * reach, so are the far child and the node's record, which lies in that cell's
             * boundary plane, and the entry is dropped now. */
            v4 flo, fhi;
            float rr, rf;
            split_cell(v, 0, qv, near, a, split, &lo, &hi, &flo, &fhi, &rr, &rf);
            stack[sp].lo = flo, stack[sp].hi = fhi;
            stack[sp].rf = rf;
            stack[sp].node = (uint32_t)(near ^ 1);
            sp += !(rr >= s->r2);
            node = near;
            if (near_code(v, 0, qv, near, &lo, &hi) >= s->r2) goto pop;
        }
        s->nodes++;
        {
            uint64_t b, e;
            bucket_range(v->t, node, &b, &e);
            for (uint64_t i = b; i < e && !s->stop; i++) rad_consider(s, v, i);
        }
    pop:
        for (;;) {
            if (sp == 0 || s->stop) return;
            sp--;
            node = stack[sp].node;
            rad_consider(s, v, (node >> 1) - 1);
            if (s->stop) return;
            if (stack[sp].rf >= s->r2) continue;
            lo = stack[sp].lo, hi = stack[sp].hi;
            break;
        }
    }
}

static int rad_setup(rad_state *s, const pm_kdtree *t, const float q[3], float r2) {
    int rc = check_query(t, q, r2);
    if (rc < 0) return rc;
    if (t->n == 0 || !(r2 > 0)) return 0;
    memset(s, 0, sizeof *s);
    s->q[0] = q[0], s->q[1] = q[1], s->q[2] = q[2];
    s->r2 = r2 == INFINITY ? NAN : r2;
    view v = make_view(t);
    root_box(&v, is_photon_layout(t), s->lo, s->hi);
    return 1;
}

long pm_kdtree_radius(const pm_kdtree *tree, const float q[3], float r2, pm_neighbor *out,
                      size_t cap, unsigned flags, pm_query_stats *stats) {
    rad_state s;
    int rc = rad_setup(&s, tree, q, r2);
    if (rc <= 0) return rc;
    if (!out && cap > 0) return PM_EINVAL;
    s.out = out;
    s.cap = cap;
    view v = make_view(tree);
    rad_iter(&s, &v);
    if (stats) {
        stats->nodes_visited += s.nodes;
        stats->dist_evals += s.evals;
    }
    if ((flags & PM_SORT) && s.total <= cap) {
        if (s.total <= PM__SORT_KEYS_MAX) pm__nb_sort_keys(out, (unsigned)s.total);
        else pm__nb_sort(out, (size_t)s.total);
    }
    return (long)s.total;
}

long pm_kdtree_radius_cb(const pm_kdtree *tree, const float q[3], float r2, pm_visit_fn fn,
                         void *user, pm_query_stats *stats) {
    rad_state s;
    if (!fn) return PM_EINVAL;
    int rc = rad_setup(&s, tree, q, r2);
    if (rc <= 0) return rc;
    s.fn = fn;
    s.user = user;
    view v = make_view(tree);
    rad_iter(&s, &v);
    if (stats) {
        stats->nodes_visited += s.nodes;
        stats->dist_evals += s.evals;
    }
    return (long)s.total;
}
