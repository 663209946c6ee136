/* bench/experiments/midsplit.c: an experiment, not part of the bench race (the Makefile does
 * not build it; no race section declares it). Question: is the worst cell of the workload race
 * (clustered points, empty-space queries, 1M, k = 10, unlimited radius) slow because of the
 * left-balanced tree's median splits? It races, side by side over the same queries:
 *   ours B     the library's pm_kdtree_knn on its left-balanced median tree (pm_photon records);
 *   mid B      a tree with nanoflann's split rule (the cell box's longest side, ties by the
 *              points' spread; cut at the cell's middle slid into the points' range; a balanced
 *              index when the cut leaves one side empty), explicit children and leaves of at
 *              most B records, searched with our search's ideas: 20-byte records scanned four at
 *              a time by SSE2 in two passes, the same small-k result set (16 slots and an argmax
 *              by SSE2 for k <= 16; blocks of 4 with block maxima for k <= 64), each child's
 *              cell carried as a box in SSE2 registers (cut at the node's divlow / divhigh, the
 *              children's extreme coordinates, as nanoflann keeps them), pruned by its whole
 *              box distance, the closer cell first, an explicit stack, the children prefetched;
 *   nf L       nanoflann (bench/nanoflann_peer.cpp) with its points in its own tree order;
 *   flann L    FLANN's exact single kd-tree (libflann), batches of 250 queries per call, as
 *              bench_knn configures and times it.
 * Rounds of 500-query chunks, every configuration timed on each chunk in a rotated order; CPU
 * time of the thread; medians over the rounds. Every configuration's answers (dist2 sorted) are
 * checked against brute force on the first 200 queries before timing.
 *
 * Build (after `make -j2 all`), from the worktree's root:
 *   cc -std=c11 -D_POSIX_C_SOURCE=200809L -O2 -g -Wall -Wextra -Iphotonmap -Ibench \
 *      -c bench/experiments/midsplit.c -o /tmp/midsplit.o
 *   c++ -o /tmp/midsplit /tmp/midsplit.o build/release/obj/bench/nanoflann_peer.o \
 *      build/release/obj/bench/util.o build/release/libphotonmap.a -lflann -fopenmp -lm
 * Run: /tmp/midsplit WORKLOAD(cluster|uniform) QUERIES(near|empty) K ROUNDS [N] [SPLIT] [race]
 * SPLIT: nf (nanoflann's rule, default), spread (the axis of the points' largest spread cut
 * at the middle of that spread) or median (the control: the axis of the points' largest extent
 * cut at the median rank, our tree's rule, but the same explicit tree and search as nf). */
#include <emmintrin.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <flann/flann.h>

#include "bench.h"
#include "kdtree.h"
#include "nanoflann_peer.h"
#include "photon.h"

typedef struct {
    float p[3];
    uint32_t id, pad;
} rec; /* 20 bytes, as pm_photon: the scan loads 16 bytes at each record's start */

typedef struct {
    float dlo, dhi; /* internal: the left child's largest and the right child's smallest coordinate */
    uint32_t a;     /* internal: the left child (the right one is a + 1); leaf: its first record */
    uint32_t b;     /* internal: the axis (0..2); leaf: (count << 2) | 3 */
} mnode;

typedef struct {
    rec *r;
    mnode *nd;
    uint32_t nn, cap, leaf;
    int spread_rule;
    float lo[3], hi[3];
} mtree;

static double cpu(void) {
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* ---- build ----------------------------------------------------------------------------- */

static void minmax(const rec *r, uint32_t n, int a, float *mn, float *mx) {
    float lo = r[0].p[a], hi = lo;
    for (uint32_t i = 1; i < n; i++) {
        float x = r[i].p[a];
        lo = x < lo ? x : lo;
        hi = x > hi ? x : hi;
    }
    *mn = lo, *mx = hi;
}

/* Records with p[a] < v first, then the rest; returns the count of the first group (or of
 * p[a] <= v with le). */
static uint32_t partition(rec *r, uint32_t n, int a, float v, int le) {
    uint32_t i = 0, j = n;
    while (i < j) {
        float x = r[i].p[a];
        if (le ? x <= v : x < v) i++;
        else {
            rec t = r[i];
            r[i] = r[--j];
            r[j] = t;
        }
    }
    return i;
}

/* Reorders r so that r[m] has rank m on axis a (records before it no larger, after it no
 * smaller); returns its coordinate. */
static float select_rank(rec *r, uint32_t n, int a, uint32_t m) {
    uint32_t l = 0, h = n - 1;
    while (l < h) {
        float pv = r[l + (h - l) / 2].p[a];
        uint32_t i = l, j = h;
        while (i <= j) {
            while (r[i].p[a] < pv) i++;
            while (r[j].p[a] > pv) j--;
            if (i <= j) {
                rec t = r[i];
                r[i] = r[j], r[j] = t;
                i++;
                if (j == 0) break;
                j--;
            }
        }
        if (m <= j) h = j;
        else if (m >= i) l = i;
        else break;
    }
    return r[m].p[a];
}

static void choose_split(const mtree *t, rec *r, uint32_t n, const float clo[3],
                         const float chi[3], int *axis, float *cut) {
    int a = 0;
    float mn, mx;
    if (t->spread_rule == 2) { /* largest extent of the points, cut at the median (ours) */
        float best = -1;
        for (int b = 0; b < 3; b++) {
            minmax(r, n, b, &mn, &mx);
            if (mx - mn > best) best = mx - mn, a = b;
        }
        *axis = a, *cut = select_rank(r, n, a, n / 2);
        return;
    }
    if (t->spread_rule == 1) { /* largest spread of the points, cut at its middle */
        float best = -1;
        for (int b = 0; b < 3; b++) {
            minmax(r, n, b, &mn, &mx);
            if (mx - mn > best) best = mx - mn, a = b;
        }
        minmax(r, n, a, &mn, &mx);
        *axis = a, *cut = (mn + mx) * 0.5f;
        return;
    }
    float ms = chi[0] - clo[0], best = -1;
    for (int b = 1; b < 3; b++) ms = chi[b] - clo[b] > ms ? chi[b] - clo[b] : ms;
    for (int b = 0; b < 3; b++) {
        if (chi[b] - clo[b] > (1 - 0.00001f) * ms) {
            minmax(r, n, b, &mn, &mx);
            if (mx - mn > best) best = mx - mn, a = b;
        }
    }
    float v = (clo[a] + chi[a]) / 2;
    minmax(r, n, a, &mn, &mx);
    *axis = a, *cut = v < mn ? mn : v > mx ? mx : v;
}

/* Node `id` over records [b, b + n) in cell [clo, chi]; writes the records' tight box. */
static void build_node(mtree *t, uint32_t id, uint32_t b, uint32_t n, const float clo[3],
                       const float chi[3], float tlo[3], float thi[3]) {
    rec *r = t->r + b;
    if (n <= t->leaf) {
        t->nd[id].a = b, t->nd[id].b = n << 2 | 3u;
        for (int a = 0; a < 3; a++) minmax(r, n, a, &tlo[a], &thi[a]);
        return;
    }
    int a;
    float cut;
    choose_split(t, r, n, clo, chi, &a, &cut);
    uint32_t idx;
    if (t->spread_rule == 2) {
        idx = n / 2; /* select_rank left the records split at rank n / 2 */
    } else {
        uint32_t l1 = partition(r, n, a, cut, 0);
        uint32_t l2 = l1 + partition(r + l1, n - l1, a, cut, 1);
        idx = l1 > n / 2 ? l1 : l2 < n / 2 ? l2 : n / 2;
        if (idx == 0 || idx == n) idx = n / 2; /* only when every point is equal on a */
    }
    uint32_t c = t->nn;
    t->nn += 2;
    t->nd[id].a = c, t->nd[id].b = (uint32_t)a;
    float llo[3], lhi[3], rlo[3], rhi[3], cl[3], ch[3];
    memcpy(cl, clo, sizeof cl), memcpy(ch, chi, sizeof ch);
    ch[a] = cut;
    build_node(t, c, b, idx, cl, ch, llo, lhi);
    memcpy(ch, chi, sizeof ch);
    cl[a] = cut;
    build_node(t, c + 1, b + idx, n - idx, cl, ch, rlo, rhi);
    t->nd[id].dlo = lhi[a], t->nd[id].dhi = rlo[a];
    for (int k = 0; k < 3; k++) {
        tlo[k] = llo[k] < rlo[k] ? llo[k] : rlo[k];
        thi[k] = lhi[k] > rhi[k] ? lhi[k] : rhi[k];
    }
}

static void mtree_build(mtree *t, const float *xyz, uint32_t n, uint32_t leaf, int spread) {
    t->r = malloc((size_t)n * sizeof *t->r);
    t->cap = 2 * n + 1; /* every leaf holds a record: at most n leaves */
    t->nd = malloc((size_t)t->cap * sizeof *t->nd);
    t->nn = 1, t->leaf = leaf, t->spread_rule = spread;
    for (uint32_t i = 0; i < n; i++) {
        memcpy(t->r[i].p, xyz + 3 * (size_t)i, 12);
        t->r[i].id = i, t->r[i].pad = 0;
    }
    float lo[3], hi[3];
    for (int a = 0; a < 3; a++) minmax(t->r, n, a, &lo[a], &hi[a]);
    build_node(t, 0, 0, n, lo, hi, t->lo, t->hi);
    if (t->nn > t->cap) {
        fprintf(stderr, "node array overflow %u > %u\n", t->nn, t->cap);
        exit(2);
    }
}

/* ---- search: our search's ideas on the explicit tree ------------------------------------- */

typedef struct {
    _Alignas(16) float d[64];
    _Alignas(16) float bm[16];
    uint32_t i[64];
    unsigned k, found, smax;
    float r2;
    uint64_t nodes, evals;
} kset;

static inline __m128 hmax4(__m128 x) {
    x = _mm_max_ps(x, _mm_shuffle_ps(x, x, 0xB1));
    return _mm_max_ps(x, _mm_shuffle_ps(x, x, 0x4E));
}
static inline unsigned eq16(const float *a, __m128 x) {
    return (unsigned)_mm_movemask_ps(_mm_cmpeq_ps(_mm_load_ps(a), x)) |
           (unsigned)_mm_movemask_ps(_mm_cmpeq_ps(_mm_load_ps(a + 4), x)) << 4 |
           (unsigned)_mm_movemask_ps(_mm_cmpeq_ps(_mm_load_ps(a + 8), x)) << 8 |
           (unsigned)_mm_movemask_ps(_mm_cmpeq_ps(_mm_load_ps(a + 12), x)) << 12;
}
static inline __m128 max16(const float *a) {
    return hmax4(_mm_max_ps(_mm_max_ps(_mm_load_ps(a), _mm_load_ps(a + 4)),
                            _mm_max_ps(_mm_load_ps(a + 8), _mm_load_ps(a + 12))));
}
static inline unsigned argmax_small(const kset *m) {
    __m128 x = max16(m->d);
    unsigned mk = eq16(m->d, x), j = (unsigned)__builtin_ctz(mk);
    for (mk &= mk - 1; mk; mk &= mk - 1) {
        unsigned l = (unsigned)__builtin_ctz(mk);
        if (m->i[l] > m->i[j]) j = l;
    }
    return j;
}
static inline unsigned argmax_block(kset *m, unsigned changed) {
    unsigned b = changed >> 2;
    _mm_store_ss(&m->bm[b], hmax4(_mm_load_ps(m->d + 4 * b)));
    __m128 x = max16(m->bm);
    unsigned mb = eq16(m->bm, x), c = (unsigned)__builtin_ctz(mb);
    unsigned ml = (unsigned)_mm_movemask_ps(_mm_cmpeq_ps(_mm_load_ps(m->d + 4 * c), x));
    if (!(mb & (mb - 1)) && !(ml & (ml - 1))) return 4 * c + (unsigned)__builtin_ctz(ml);
    float top = _mm_cvtss_f32(x);
    unsigned j = m->k;
    for (unsigned l = 0; l < m->k; l++)
        if (m->d[l] == top && (j == m->k || m->i[l] > m->i[j])) j = l;
    return j;
}
static inline void offer(kset *m, float d2, uint32_t idx) {
    unsigned f = m->found, j, k = m->k;
    if (f < k) {
        m->d[f] = d2, m->i[f] = idx;
        m->found = ++f;
        if (f < k) return;
        if (k > 16)
            for (unsigned b = 0; b < 16; b++)
                m->bm[b] = 4 * b < k ? _mm_cvtss_f32(hmax4(_mm_load_ps(m->d + 4 * b))) : -1.0f;
        j = f - 1;
    } else {
        j = m->smax;
        if (d2 == m->d[j] && idx > m->i[j]) return;
        m->d[j] = d2, m->i[j] = idx;
    }
    j = k > 16 ? argmax_block(m, j) : argmax_small(m);
    m->smax = j;
    m->r2 = nextafterf(m->d[j], INFINITY);
}

static inline float box_dist2(__m128 q, __m128 lo, __m128 hi) {
    __m128 o = _mm_max_ps(_mm_max_ps(_mm_sub_ps(lo, q), _mm_sub_ps(q, hi)), _mm_setzero_ps());
    __m128 sq = _mm_mul_ps(o, o);
    return _mm_cvtss_f32(sq) + _mm_cvtss_f32(_mm_shuffle_ps(sq, sq, 1)) +
           _mm_cvtss_f32(_mm_shuffle_ps(sq, sq, 2));
}

/* The bucket scan, written as photonmap/kdtree_query.c's two-pass SSE2 scan on purpose (a
 * deliberate duplicate: the experiment races the library's scan on another tree, so it must be
 * the same code; the library's is static and reads its own record layout). */
static inline void scan(kset *s, const rec *r, uint32_t b, uint32_t n, const float q[3]) {
    uint32_t i = b, e = b + n;
    const __m128 qx = _mm_set1_ps(q[0]), qy = _mm_set1_ps(q[1]), qz = _mm_set1_ps(q[2]);
    while (i + 4 <= e) {
        unsigned ng = (e - i) / 4;
        ng = ng > 16 ? 16 : ng;
        _Alignas(16) float dv[64];
        uint64_t M = 0;
        const __m128 rv = _mm_set1_ps(s->r2);
        for (unsigned g = 0; g < ng; g++) {
            const float *p0 = r[i + 4 * g].p;
            __m128 r0 = _mm_loadu_ps(p0), r1 = _mm_loadu_ps(p0 + 5), r2v = _mm_loadu_ps(p0 + 10),
                   r3 = _mm_loadu_ps(p0 + 15);
            _MM_TRANSPOSE4_PS(r0, r1, r2v, r3);
            __m128 dx = _mm_sub_ps(qx, r0), dy = _mm_sub_ps(qy, r1), dz = _mm_sub_ps(qz, r2v);
            __m128 d2 = _mm_add_ps(_mm_add_ps(_mm_mul_ps(dx, dx), _mm_mul_ps(dy, dy)),
                                   _mm_mul_ps(dz, dz));
            _mm_store_ps(dv + 4 * g, d2);
            M |= (uint64_t)_mm_movemask_ps(_mm_cmpnge_ps(d2, rv)) << (4 * g);
        }
        s->evals += 4 * ng;
        while (M) {
            unsigned l = (unsigned)__builtin_ctzll(M);
            M &= M - 1;
            if (!(dv[l] >= s->r2)) offer(s, dv[l], i + l);
        }
        i += 4 * ng;
    }
    for (; i < e; i++) {
        const float *p = r[i].p;
        float dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
        float d2 = dx * dx + dy * dy + dz * dz;
        s->evals++;
        if (!(d2 >= s->r2)) offer(s, d2, i);
    }
}

static inline void prefetch_node(const mtree *t, const mnode *n) {
    if ((n->b & 3u) == 3u) {
        const char *p = (const char *)(t->r + n->a);
        size_t bytes = (size_t)(n->b >> 2) * sizeof(rec);
        bytes = bytes > 1280 ? 1280 : bytes;
        for (size_t o = 0; o < bytes; o += 64) __builtin_prefetch(p + o);
    } else {
        __builtin_prefetch(t->nd + n->a);
    }
}

static inline __m128 setlane(__m128 x, unsigned a, float v) {
    __m128 lane = _mm_castsi128_ps(_mm_cmpeq_epi32(_mm_set1_epi32((int)a), _mm_set_epi32(3, 2, 1, 0)));
    return _mm_or_ps(_mm_and_ps(lane, _mm_set1_ps(v)), _mm_andnot_ps(lane, x));
}

/* The k nearest (unlimited radius when r2 is +inf) into s; out sorted by (dist2, index). */
static unsigned mtree_knn(const mtree *t, const float q[3], unsigned k, float r2, kset *s,
                          float *od, uint32_t *oi) {
    struct {
        __m128 lo, hi;
        float cd;
        uint32_t node;
    } st[128];
    int sp = 0;
    s->k = k, s->found = 0, s->r2 = r2 == INFINITY ? NAN : r2;
    unsigned nd = k <= 16 ? 16 : (k + 3) & ~3u;
    for (unsigned j = 0; j < nd; j++) s->d[j] = -1.0f, s->i[j] = 0;
    const __m128 qv = _mm_set_ps(0, q[2], q[1], q[0]);
    __m128 lo = _mm_set_ps(0, t->lo[2], t->lo[1], t->lo[0]);
    __m128 hi = _mm_set_ps(0, t->hi[2], t->hi[1], t->hi[0]);
    float cd = box_dist2(qv, lo, hi);
    uint32_t node = 0;
    if (!(cd >= s->r2)) {
        for (;;) {
            const mnode *n = t->nd + node;
            s->nodes++;
            if ((n->b & 3u) == 3u) {
                scan(s, t->r, n->a, n->b >> 2, q);
            } else {
                unsigned a = n->b;
                /* left cell: hi[a] = dlo; right cell: lo[a] = dhi */
                __m128 llo = lo, lhi = setlane(hi, a, n->dlo);
                __m128 rlo = setlane(lo, a, n->dhi), rhi = hi;
                float dl = box_dist2(qv, llo, lhi), dr = box_dist2(qv, rlo, rhi);
                int right_first = dr < dl || (dr == dl && q[a] - n->dlo >= n->dhi - q[a]);
                uint32_t c = n->a;
                __m128 nlo = right_first ? rlo : llo, nhi = right_first ? rhi : lhi;
                __m128 flo = right_first ? llo : rlo, fhi = right_first ? lhi : rhi;
                float dn = right_first ? dr : dl, df = right_first ? dl : dr;
                uint32_t cn = c + (uint32_t)right_first, cf = c + 1 - (uint32_t)right_first;
                prefetch_node(t, t->nd + cn);
                if (!(df >= s->r2)) {
                    st[sp].lo = flo, st[sp].hi = fhi, st[sp].cd = df, st[sp].node = cf;
                    sp++;
                }
                if (!(dn >= s->r2)) {
                    lo = nlo, hi = nhi, cd = dn, node = cn;
                    continue;
                }
            }
            for (;;) {
                if (sp == 0) goto done;
                sp--;
                if (st[sp].cd >= s->r2) continue;
                lo = st[sp].lo, hi = st[sp].hi, cd = st[sp].cd, node = st[sp].node;
                break;
            }
        }
    }
done:;
    /* sorted by (dist2, index): insertion (k <= 64) */
    unsigned f = s->found;
    for (unsigned j = 0; j < f; j++) {
        float d = s->d[j];
        uint32_t ix = t->r[s->i[j]].id;
        unsigned p = j;
        while (p > 0 && (od[p - 1] > d || (od[p - 1] == d && oi[p - 1] > ix))) {
            od[p] = od[p - 1], oi[p] = oi[p - 1];
            p--;
        }
        od[p] = d, oi[p] = ix;
    }
    return f;
}

/* ---- the race ---------------------------------------------------------------------------- */

static unsigned long long rng = 88172645463325252ULL;
static double un(void) {
    rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
    return (double)(rng >> 11) * (1.0 / 9007199254740992.0);
}
/* RACE=1: the generator of bench_knn (its seed 1, util.c's bench_rng) instead of this file's:
 * the race's own clustered set and query pool (the first 20000 of its 30000). */
static int race_gen;
static bench_rng race_rng;
static double un_any(void) { return race_gen ? bench_rng_unit(&race_rng) : un(); }
static uint64_t u64_any(uint32_t n) {
    return race_gen ? bench_rng_u64(&race_rng) % n : (uint64_t)(un() * n) % n;
}
static double gauss(void) {
    double u = un_any(), v = un_any();
    return sqrt(-2 * log(1 - u)) * cos(6.283185307179586 * v);
}

enum { OURS, MID, NF, FL };
typedef struct {
    int kind;
    unsigned size;
    char name[32];
    pm_kdtree *ours;
    mtree mid;
    nf_peer *nf;
    flann_index_t fl;
    struct FLANNParameters fp;
    double build_s;
    double *t; /* CPU seconds per round */
    double evals, nodes;
} config;

static unsigned run_one(config *c, const float *q, unsigned k, float *od, uint32_t *oi,
                        pm_neighbor *nb, kset *ks, pm_query_stats *stats) {
    if (c->kind == OURS) {
        int f = pm_kdtree_knn(c->ours, q, k, INFINITY, nb, PM_SORT, stats);
        for (int j = 0; j < f; j++) od[j] = nb[j].dist2, oi[j] = nb[j].index;
        return (unsigned)f;
    }
    if (c->kind == MID) return mtree_knn(&c->mid, q, k, INFINITY, ks, od, oi);
    if (c->kind == FL) {
        int ix[64];
        flann_find_nearest_neighbors_index(c->fl, (float *)q, 1, ix, od, (int)k, &c->fp);
        for (unsigned j = 0; j < k; j++) oi[j] = (uint32_t)ix[j];
        return k;
    }
    return nf_knn(c->nf, q, k, INFINITY, oi, od);
}

/* FLANN as the race times it: batches of up to 250 queries per call (bench_knn: 256). */
static double run_flann_batch(config *c, const float *q, int m, unsigned k) {
    static int ix[250 * 64];
    static float d[250 * 64];
    double s = 0;
    for (int b = 0; b < m; b += 250) {
        int rows = m - b < 250 ? m - b : 250;
        flann_find_nearest_neighbors_index(c->fl, (float *)(q + 3 * (size_t)b), rows, ix, d, (int)k, &c->fp);
        s += d[0];
    }
    return s;
}

static int cmpd(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}
static double median(const double *v, int n) {
    double w[64];
    memcpy(w, v, (size_t)n * sizeof *w);
    qsort(w, (size_t)n, sizeof *w, cmpd);
    return n % 2 ? w[n / 2] : 0.5 * (w[n / 2 - 1] + w[n / 2]);
}

/* The k smallest dist2 from q over every point, ascending. */
static void brute(const float *xyz, uint32_t n, const float q[3], unsigned k, float *bd) {
    unsigned f = 0;
    for (uint32_t i = 0; i < n; i++) {
        const float *p = xyz + 3 * (size_t)i;
        float dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
        float d2 = dx * dx + dy * dy + dz * dz;
        if (f == k && !(d2 < bd[k - 1])) continue;
        unsigned j = f < k ? f++ : k - 1;
        while (j > 0 && bd[j - 1] > d2) bd[j] = bd[j - 1], j--;
        bd[j] = d2;
    }
}

int main(int argc, char **argv) {
    if (argc < 5) {
        fprintf(stderr, "usage: %s cluster|uniform near|empty K ROUNDS [N] [nf|spread|median] [race]\n", argv[0]);
        return 2;
    }
    const char *w = argv[1];
    int empty = !strcmp(argv[2], "empty");
    unsigned k = (unsigned)atoi(argv[3]);
    int rounds = atoi(argv[4]);
    uint32_t n = argc > 5 ? (uint32_t)atof(argv[5]) : 1000000u;
    int spread = argc > 6 && !strcmp(argv[6], "spread") ? 1 : argc > 6 && !strcmp(argv[6], "median") ? 2 : 0;
    if (k < 1 || k > 64 || rounds < 1 || rounds > 64) {
        fprintf(stderr, "K must be 1..64 and ROUNDS 1..64\n");
        return 2;
    }
    race_gen = argc > 7 && !strcmp(argv[7], "race");
    const int nq = 20000, chunk = 500, nv = 200, pool = 30000;
    float *xyz = malloc((size_t)n * 12), *q = malloc((size_t)nq * 12);
    double cc[64][4];
    bench_rng_seed(&race_rng, 1 * 1000003 + (uint64_t)n);
    for (int c = 0; c < 64; c++) {
        for (int a = 0; a < 3; a++) cc[c][a] = 0.1 + 0.8 * un_any();
        cc[c][3] = 0.002 * pow(100.0, c / 63.0);
    }
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < n; i++) {
        float *p = xyz + 3 * (size_t)i;
        const double *c = cc[u64_any(64)];
        for (int a = 0; a < 3; a++) {
            p[a] = !strcmp(w, "cluster") ? (float)(c[a] + c[3] * gauss()) : (float)un_any();
            lo[a] = p[a] < lo[a] ? p[a] : lo[a];
            hi[a] = p[a] > hi[a] ? p[a] : hi[a];
        }
    }
    float ext = 0;
    for (int a = 0; a < 3; a++) ext = hi[a] - lo[a] > ext ? hi[a] - lo[a] : ext;
    bench_rng_seed(&race_rng, 1 * 977 + (uint64_t)n + 13 * (uint64_t)strlen(w));
    for (int s = 0; s < 2; s++) /* as bench_knn: the near pool first, then the empty one */
        for (int i = 0; i < (race_gen ? pool : nq); i++) {
            float qq[3];
            if (s == 0) {
                const float *p = xyz + 3 * u64_any(n);
                for (int a = 0; a < 3; a++) qq[a] = p[a] + 1e-3f * ext * (float)(2.0 * un_any() - 1.0);
            } else {
                for (int a = 0; a < 3; a++) qq[a] = lo[a] + (hi[a] - lo[a]) * (float)un_any();
            }
            if (s == empty && i < nq) memcpy(q + 3 * i, qq, sizeof qq);
        }
    config cf[12];
    int nc = 0;
    unsigned sizes[4][3] = {{16, 32, 0}, {16, 32, 0}, {16, 32, 64}, {16, 32, 64}};
    pm_photon *ph = calloc(n, sizeof *ph);
    for (int kind = 0; kind < 4; kind++)
        for (int j = 0; j < 3 && sizes[kind][j]; j++) {
            config *c = &cf[nc++];
            memset(c, 0, sizeof *c);
            c->kind = kind, c->size = sizes[kind][j];
            snprintf(c->name, sizeof c->name, "%s_%u", kind == OURS ? "ours" : kind == MID ? (spread == 1 ? "midspread" : spread == 2 ? "midmedian" : "midnf") : kind == NF ? "nf_tree_order" : "flann_batch", c->size);
            c->t = calloc((size_t)rounds, sizeof *c->t);
            double t0 = cpu();
            if (kind == OURS) {
                for (uint32_t i = 0; i < n; i++) memcpy(ph[i].pos, xyz + 3 * (size_t)i, 12);
                pm_photon *cp = malloc((size_t)n * sizeof *cp);
                memcpy(cp, ph, (size_t)n * sizeof *cp);
                pm_kdtree_config kc = pm_kdtree_photon_config(c->size);
                if (pm_kdtree_build(&c->ours, cp, n, &kc, NULL)) return 1;
                c->build_s = cpu() - t0;
            } else if (kind == MID) {
                mtree_build(&c->mid, xyz, n, c->size, spread);
                c->build_s = cpu() - t0;
            } else if (kind == NF) {
                c->nf = nf_build(xyz, n, c->size, 1, cpu, &c->build_s);
                if (!c->nf) return 1;
            } else { /* FLANN's exact single kd-tree, as bench_knn configures it */
                float speedup;
                c->fp = DEFAULT_FLANN_PARAMETERS;
                c->fp.algorithm = FLANN_INDEX_KDTREE_SINGLE;
                c->fp.leaf_max_size = (int)c->size;
                c->fp.checks = FLANN_CHECKS_UNLIMITED;
                c->fp.cores = 1, c->fp.sorted = 1, c->fp.max_neighbors = -1, c->fp.eps = 0;
                c->fp.log_level = FLANN_LOG_NONE, c->fp.random_seed = 12345;
                c->fl = flann_build_index(xyz, (int)n, 3, &speedup, &c->fp);
                if (!c->fl) return 1;
                c->build_s = cpu() - t0;
            }
        }
    float od[64], bd[64];
    uint32_t oi[64];
    pm_neighbor nb[64];
    kset ks;
    /* exactness against brute force, then counts over every query */
    long bad = 0;
    for (int i = 0; i < nv; i++) {
        brute(xyz, n, q + 3 * i, k, bd);
        for (int c = 0; c < nc; c++) {
            unsigned f = run_one(&cf[c], q + 3 * i, k, od, oi, nb, &ks, NULL);
            if (f != k || memcmp(od, bd, k * sizeof *od)) bad++, fprintf(stderr, "%s differs at query %d\n", cf[c].name, i);
        }
    }
    for (int c = 0; c < nc; c++) {
        pm_query_stats stt = {0};
        memset(&ks, 0, sizeof ks);
        for (int i = 0; i < nq; i++) run_one(&cf[c], q + 3 * i, k, od, oi, nb, &ks, &stt);
        cf[c].evals = cf[c].kind == OURS ? (double)stt.dist_evals / nq : (double)ks.evals / nq;
        cf[c].nodes = cf[c].kind == OURS ? (double)stt.nodes_visited / nq : (double)ks.nodes / nq;
    }
    double sink = 0;
    for (int r = 0; r < rounds; r++)
        for (int ch = 0; ch < nq / chunk; ch++)
            for (int o = 0; o < nc; o++) {
                config *c = &cf[(o + ch + r) % nc];
                const float *qq = q + 3 * (size_t)ch * chunk;
                double t0 = cpu();
                if (c->kind == FL) sink += run_flann_batch(c, qq, chunk, k);
                else
                    for (int i = 0; i < chunk; i++) sink += run_one(c, qq + 3 * i, k, od, oi, nb, &ks, NULL) + od[0];
                c->t[r] += cpu() - t0;
            }
    printf("# %s%s %s N=%u k=%u unlimited; %d rounds x %d queries; split rule %s; verified %d queries: %ld mismatches; sink %g\n",
           w, race_gen ? " (bench_knn's generator)" : "", argv[2], n, k, rounds, nq, spread == 1 ? "spread" : spread == 2 ? "median" : "nanoflann", nv, bad, sink > 0 ? 1.0 : 0.0);
    double best_nf = 0, best_fl = 0, qs[12];
    for (int c = 0; c < nc; c++) {
        double v[64];
        for (int r = 0; r < rounds; r++) v[r] = nq / cf[c].t[r];
        qs[c] = median(v, rounds);
        if (cf[c].kind == NF && qs[c] > best_nf) best_nf = qs[c];
        if (cf[c].kind == FL && qs[c] > best_fl) best_fl = qs[c];
    }
    for (int c = 0; c < nc; c++) {
        double v[64], mn = 1e30, mx = 0;
        /* per round: this configuration against the fastest nanoflann leaf size of that round */
        for (int r = 0; r < rounds; r++) {
            double b = 1e30;
            for (int d = 0; d < nc; d++) if (cf[d].kind == NF && cf[d].t[r] < b) b = cf[d].t[r];
            v[r] = b / cf[c].t[r];
            mn = v[r] < mn ? v[r] : mn, mx = v[r] > mx ? v[r] : mx;
        }
        printf("%-16s build %.3f s  %9.0f q/s  / nf best %.3fx (rounds %.3f..%.3f; median of rounds %.3f)  / flann best %.3fx", cf[c].name,
               cf[c].build_s, qs[c], qs[c] / best_nf, mn, mx, median(v, rounds), qs[c] / best_fl);
        if (cf[c].kind == OURS || cf[c].kind == MID) printf("  evals %.1f nodes %.1f", cf[c].evals, cf[c].nodes);
        if (cf[c].kind == MID) printf("  tree %.2f B per point", cf[c].mid.nn * (double)sizeof(mnode) / n);
        printf("\n");
    }
    return bad ? 1 : 0;
}
