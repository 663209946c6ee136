/* kdtree_query.c: k-nearest and predicate (nearest_if) queries on the heap kd-tree. Its
 * siblings: kdtree_radius.c (the radius searches) and kdtree_query_internal.h (what both
 * share: the record view, the cell distance and tightening, the split of a cell, the
 * prefetches; its top comment holds the CELL DISTANCE and RADIUS rules used below).
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
 * CELL DISTANCE and RADIUS (r2 = +INFINITY kept as NaN, every test !(x >= r2)):
 * kdtree_query_internal.h.
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

#include "kdtree_query_internal.h"

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
         * after each push, was 0.95-0.97x this on clustered data: experiments.csv.)
         * bench/experiments/midsplit.c holds a copy of this scan on purpose (a standalone
         * experiment on its own tree layout, which must scan as the library does). */
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
/* The eight instances of the counting search, metric and filter chosen per query. The two
 * halves repeat on purpose: the same dispatch written once through an always_inline helper
 * taking ph compiles to a differently laid out function (objdump), a change of the
 * pm_kdtree_knn_ex and nearest_if code that a pure refactor should not make. */
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
