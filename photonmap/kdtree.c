/* kdtree.c: building the left-balanced heap kd-tree of kdtree.h, and its small accessors.
 *
 * SHAPE. For n records and bucket size B the tree has depth D, the smallest D >= 0 with
 * n + 1 <= (B + 1) * 2^D. Heap nodes 1 .. 2^D - 1 are internal and hold one record each, at
 * record index node - 1; heap nodes 2^D .. 2^(D+1) - 1 are the L = 2^D leaf buckets. The
 * remaining n - (2^D - 1) records are spread as evenly as possible over the buckets, the
 * first `extra` buckets holding one record more (q or q + 1 records each), and stored
 * contiguously after the internal records. Leaf j starts at record (2^D - 1) + j*q + min(j,
 * extra). With B = 1 this is exactly Jensen's balanced heap (record i - 1 is node i), and the
 * size of every subtree, hence the rank of every median, follows from (D, q, extra) alone.
 *
 * BUILD. The finite positions are copied with their original indices into a 16-byte work
 * array (the records themselves may be large). An explicit stack walks the heap depth first;
 * each internal node takes the tight bounding box of its range, picks the axis of largest
 * extent (ties: lowest axis) and moves the record of the left subtree's size to its rank with
 * an introselect (pivots from a sample of about m^(2/3) keys placed just beyond the wanted
 * rank, so a median costs about 1.5 passes; a block partition that collects the keys to move
 * without branches; equal keys stop both scans, so runs of them are split down the middle;
 * a heapsort fallback when the pivots keep failing), which leaves every smaller-rank key <=
 * and every larger-rank key >= the median. Each level costs O(n), so the build is O(n log n)
 * with no recursion. The records are then gathered in tree order into the work array's
 * memory (prefetching the random reads) and copied back over the caller's array. Temporary
 * memory: n * (max(16, stride) + 4) bytes. The tight bounding box of the indexed positions is
 * kept in the tree (24 bytes): it is the root cell of the queries' cell-distance pruning.
 *
 * DUPLICATES. A subtree whose records all share one position (zero extent) is marked with
 * axis code 3, "uniform", and is not split further: queries handle it as a single distance
 * (kdtree_query.c, kdtree_radius.c). When a node holds copies of its parent's split record
 * (the median cut a run of identical records), it keeps the parent's axis if it still has
 * extent there: the copies then sit at its boundary along that axis and gather into few
 * uniform subtrees instead of being scattered over many mixed nodes by splits on other
 * axes. This lowers the nodes a query visits next to a heavy duplicate
 * (tests/test_kdtree_queries.c measures it).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "kdtree_internal.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

/* ---- small accessors --------------------------------------------------------------------- */

pm_kdtree_config pm_kdtree_photon_config(unsigned bucket) {
    pm_kdtree_config c;
    c.stride = 20;
    c.pos_offset = 0;
    c.axis_offset = 18; /* pm_photon.flag; see photon.h */
    c.bucket = bucket ? bucket : PM_KDTREE_BUCKET_DEFAULT;
    return c;
}

size_t pm_kdtree_size(const pm_kdtree *t) { return t ? t->n : 0; }
size_t pm_kdtree_dropped(const pm_kdtree *t) { return t ? t->dropped : 0; }
unsigned pm_kdtree_bucket(const pm_kdtree *t) { return t ? t->bucket : 0; }
const void *pm_kdtree_records(const pm_kdtree *t) { return t ? t->rec : NULL; }

size_t pm_kdtree_index_bytes(const pm_kdtree *t) {
    if (!t) return 0;
    return sizeof *t + (t->axes ? (size_t)t->ninternal : 0);
}

const float *pm_kdtree_pos(const pm_kdtree *t, uint32_t i) {
    if (!t || i >= t->n) return NULL;
    return (const float *)(t->rec + (size_t)i * t->stride + t->pos_offset);
}

void pm_kdtree_free(pm_kdtree *t) {
    if (!t) return;
    free(t->axes);
    free(t);
}

int pm_kdtree_height(const pm_kdtree *t, uint32_t i) {
    if (!t || i >= t->n || i >= t->ninternal) return 0;
    uint32_t p = i + 1;
    int level = pm__ilog2(p);
    int below = (int)t->depth - 1 - level; /* internal levels under p */
    /* Records in the buckets under p: p's subtree spans 2^(D - level) buckets. */
    uint64_t span = (uint64_t)1 << (t->depth - (uint32_t)level);
    uint64_t j0 = (uint64_t)p * span - t->nleaves;
    uint64_t inb = pm__cum(t, j0 + span) - pm__cum(t, j0);
    return below + (inb > 0 ? 1 : 0);
}

/* ---- build ------------------------------------------------------------------------------- */

typedef struct {
    float p[3];
    uint32_t idx;
} item;

static inline float key(const item *it, int a) { return it->p[a]; }

static inline void swap_item(item *a, item *b) {
    item t = *a;
    *a = *b;
    *b = t;
}

static void sift(item *a, size_t n, size_t i, int ax) {
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= n) return;
        if (c + 1 < n && key(&a[c + 1], ax) > key(&a[c], ax)) c++;
        if (!(key(&a[c], ax) > key(&a[i], ax))) return;
        swap_item(&a[c], &a[i]);
        i = c;
    }
}

static void heapsort_items(item *a, size_t n, int ax) {
    if (n < 2) return;
    for (size_t i = n / 2; i-- > 0;) sift(a, n, i, ax);
    for (size_t e = n - 1; e > 0; e--) {
        swap_item(&a[0], &a[e]);
        sift(a, e, 0, ax);
    }
}

static void insertion_items(item *a, size_t n, int ax) {
    for (size_t i = 1; i < n; i++) {
        item v = a[i];
        size_t j = i;
        while (j > 0 && key(&a[j - 1], ax) > key(&v, ax)) {
            a[j] = a[j - 1];
            j--;
        }
        a[j] = v;
    }
}

static inline uint64_t xorshift(uint64_t *s) {
    uint64_t x = *s;
    x ^= x << 13;
    x ^= x >> 7;
    x ^= x << 17;
    *s = x;
    return x;
}

/* The key of rank r of f[0..n) (a quickselect on a small float array; f is reordered). */
static float select_float(float *f, size_t n, size_t r) {
    size_t lo = 0, hi = n;
    while (hi - lo > 8) {
        size_t mid = lo + (hi - lo) / 2;
        float x = f[lo], y = f[mid], z = f[hi - 1];
        float piv = x < y ? (y < z ? y : (x < z ? z : x)) : (x < z ? x : (y < z ? z : y));
        size_t i = lo, j = hi - 1;
        for (;;) {
            while (f[i] < piv) i++;
            while (f[j] > piv) j--;
            if (i >= j) break;
            float t = f[i];
            f[i] = f[j], f[j] = t;
            i++, j--;
        }
        if (i == j) {
            if (r < i) hi = i;
            else if (r > i) lo = i + 1;
            else return f[r];
        } else {
            if (r <= j) hi = j + 1;
            else if (r >= i) lo = i;
            else return f[r];
        }
    }
    for (size_t i = lo + 1; i < hi; i++) {
        float v = f[i];
        size_t j = i;
        while (j > lo && f[j - 1] > v) f[j] = f[j - 1], j--;
        f[j] = v;
    }
    return f[r];
}

/* Sampled pivots (Floyd and Rivest's idea) above this many keys; median of 3 below. */
#define SAMPLE_MIN 256u
#define SAMPLE_MAX 4096u
/* Keys per block of the partition (offsets fit a byte). */
#define BLK 64u

/* A pivot for selecting rank k of a[0..m): the key of a random sample of s ~ m^(2/3) keys
 * whose sample rank is k's scaled rank moved about sqrt(s) (two standard deviations of the
 * sample rank) toward the far end. The part holding rank k after the partition is then, with
 * high probability, only a little longer than the shorter of [0, k] and [k, m): a median costs
 * one pass over m and one over m/2 whose pivot lies near its end, instead of about 2.75 passes
 * of coin-toss compares with a median of 3. */
static float sample_pivot(const item *a, size_t m, size_t k, int ax, uint64_t *rng) {
    float f[SAMPLE_MAX];
    size_t s = (size_t)1 << (2 * pm__ilog2(m) / 3);
    if (s > SAMPLE_MAX) s = SAMPLE_MAX;
    for (size_t i = 0; i < s; i++) f[i] = key(&a[xorshift(rng) % m], ax);
    size_t t = (size_t)((double)k * (double)s / (double)m), g = 1;
    while (g * g < s) g++;
    size_t r = 2 * k < m ? (t + g < s ? t + g : s - 1) : (t > g ? t - g : 0);
    return select_float(f, s, r);
}

/* Put the element of rank k of a[0..n) (by coordinate ax) at a[k], smaller-or-equal keys
 * before it and greater-or-equal after. Expected linear; worst case O(n log n). */
static void select_rank(item *a, size_t n, size_t k, int ax, uint64_t *rng) {
    size_t lo = 0, hi = n;
    int budget = 2 * pm__ilog2((uint32_t)(n | 1)) + 16;
    while (hi - lo > 24) {
        if (budget-- <= 0) {
            heapsort_items(a + lo, hi - lo, ax);
            return;
        }
        size_t m = hi - lo;
        float piv;
        if (m >= SAMPLE_MIN) {
            piv = sample_pivot(a + lo, m, k - lo, ax, rng);
        } else {
            float x = key(&a[lo + xorshift(rng) % m], ax);
            float y = key(&a[lo + xorshift(rng) % m], ax);
            float z = key(&a[lo + xorshift(rng) % m], ax);
            piv = x < y ? (y < z ? y : (x < z ? z : x)) : (x < z ? x : (y < z ? z : y));
        }
        /* Hoare's partition, stopping on keys equal to the pivot: runs of equal keys are
         * split down the middle, so duplicates cost no more than distinct keys. Blocks of
         * BLK keys at both ends first (BlockQuicksort, Edelkamp and Weiss): the offsets of
         * the keys that must move are collected without a branch, then swapped in pairs, so
         * the coin-toss compares near a median cost no mispredicted branches. Afterwards
         * [lo, l) <= piv and [r, hi) >= piv; the scalar loop below partitions [l, r). */
        size_t l = lo, r = hi;
        {
            unsigned char ol[BLK], orr[BLK];
            unsigned nl = 0, nr = 0, sl = 0, sr = 0;
            while (r - l >= 2 * BLK) {
                if (nl == 0) {
                    sl = 0;
                    const item *b = a + l;
                    for (unsigned t = 0; t < BLK; t++) {
                        ol[nl] = (unsigned char)t;
                        nl += !(key(&b[t], ax) < piv);
                    }
                }
                if (nr == 0) {
                    sr = 0;
                    const item *b = a + r - 1;
                    for (unsigned t = 0; t < BLK; t++) {
                        orr[nr] = (unsigned char)t;
                        nr += !(key(b - t, ax) > piv);
                    }
                }
                unsigned c = nl < nr ? nl : nr;
                for (unsigned t = 0; t < c; t++)
                    swap_item(&a[l + ol[sl + t]], &a[r - 1 - orr[sr + t]]);
                nl -= c, nr -= c, sl += c, sr += c;
                if (nl == 0) l += BLK;
                if (nr == 0) r -= BLK;
            }
        }
        size_t i = l, j = r;
        for (;;) {
            while (i < j && key(&a[i], ax) < piv) i++;
            while (i < j && key(&a[j - 1], ax) > piv) j--;
            if (j - i <= 1) break;
            swap_item(&a[i], &a[j - 1]);
            i++, j--;
        }
        if (j == i + 1) { /* a[i] equals piv: [lo, i) <= piv <= [i + 1, hi) */
            if (k < i)
                hi = i;
            else if (k > i)
                lo = i + 1;
            else
                return;
        } else { /* [lo, i) <= piv <= [i, hi) */
            if (k < i)
                hi = i;
            else
                lo = i;
        }
    }
    insertion_items(a + lo, hi - lo, ax);
}

static int config_ok(const pm_kdtree_config *c, const void *records) {
    if (c->stride < 12 || c->pos_offset > c->stride - 12 || c->bucket < 1) return 0;
    if (c->stride % 4 != 0 || ((uintptr_t)records + c->pos_offset) % 4 != 0) return 0;
    if (c->axis_offset >= 0) {
        size_t a = (size_t)c->axis_offset;
        if (a >= c->stride) return 0;
        if (a >= c->pos_offset && a < c->pos_offset + 12) return 0;
    } else if (c->axis_offset != -1) {
        return 0;
    }
    return 1;
}

/* The tightening code (kdtree_internal.h) that shrinks the cell [lo, hi] the most while
 * keeping the subtree's bounding box [mn, mx] inside it, as pm__tighten computes it; 0 if none
 * does. The gain is the distance the faces move. Extents too small for the products to stay
 * exact (subnormal) are left alone. */
static unsigned choose_code(const float lo[3], const float hi[3], const float mn[3],
                            const float mx[3]) {
    unsigned best = 0;
    float best_gain = 0;
    /* A quick filter first (most nodes of dense data have no gap of a quarter of their cell):
     * the exact test below decides. */
    int any = 0;
    for (int b = 0; b < 3; b++) {
        float q = 0.24f * (hi[b] - lo[b]);
        any |= (mn[b] - lo[b] >= q) | (hi[b] - mx[b] >= q);
    }
    if (!any) return 0;
    for (unsigned c = 1; c <= PM__CODE_MAX; c++) {
        unsigned b = c <= 12 ? (c - 1) >> 2 : c - 13;
        if (!(hi[b] - lo[b] >= 1e-30f)) continue;
        float l[3] = {lo[0], lo[1], lo[2]}, h[3] = {hi[0], hi[1], hi[2]};
        pm__tighten(l, h, c);
        int ok = 1;
        for (int x = 0; x < 3; x++)
            ok &= isfinite(l[x]) && isfinite(h[x]) && l[x] <= mn[x] && h[x] >= mx[x];
        if (!ok) continue;
        float gain = (l[b] - lo[b]) + (hi[b] - h[b]);
        if (gain > best_gain) best_gain = gain, best = c;
    }
    return best;
}

/* Subtree size of heap node p at the given level. */
static uint64_t subtree_size(const pm_kdtree *t, uint64_t p, int level) {
    uint64_t span = (uint64_t)1 << (t->depth - (uint32_t)level);
    uint64_t j0 = p * span - t->nleaves;
    return (span - 1) + pm__cum(t, j0 + span) - pm__cum(t, j0);
}

/* Write the original indices of w[0..cnt) into the record slots of the subtree of node p
 * (in the order of pm__subtree_ranges). Used for uniform subtrees and leaves. */
static void place_subtree(const pm_kdtree *t, uint32_t *order, uint8_t *ax, uint64_t p,
                          int level, const item *w) {
    pm__range r[PM_KDTREE_MAX_DEPTH + 1];
    int nr = pm__subtree_ranges(t, p, level, r);
    size_t k = 0;
    for (int s = 0; s < nr; s++) {
        for (uint64_t i = r[s].begin; i < r[s].end; i++) {
            order[i] = w[k++].idx;
            if (i < t->ninternal) ax[i] = PM__AXIS_UNIFORM;
        }
    }
}

/* pm_kdtree_build's first step: the finite records of base[0..n) to the work array w (their
 * positions and indices; their bounds into t->lo and t->hi), the non-finite ones to the tail of
 * order, in original order; t->n and t->dropped. Returns the number of finite records. */
static size_t gather_finite(pm_kdtree *t, const char *base, size_t n, const pm_kdtree_config *cfg,
                            item *w, uint32_t *order) {
    size_t m = 0, nd = 0;
    for (size_t i = 0; i < n; i++) {
        const float *p = (const float *)(base + i * cfg->stride + cfg->pos_offset);
        if (isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2])) {
            for (int a = 0; a < 3; a++) {
                if (m == 0 || p[a] < t->lo[a]) t->lo[a] = p[a];
                if (m == 0 || p[a] > t->hi[a]) t->hi[a] = p[a];
            }
            w[m].p[0] = p[0];
            w[m].p[1] = p[1];
            w[m].p[2] = p[2];
            w[m].idx = (uint32_t)i;
            m++;
        } else {
            order[n - 1 - nd++] = (uint32_t)i;
        }
    }
    for (size_t a = 0, b = nd; a < b / 2; a++) {
        uint32_t s = order[m + a];
        order[m + a] = order[n - 1 - a];
        order[n - 1 - a] = s;
    }
    t->n = (uint32_t)m;
    t->dropped = (uint32_t)nd;
    return m;
}

/* The tight bounding box of w[lo..hi) (lo < hi) into mn and mx; 1 when one of the records
 * is at (pm0, pm1, pm2), a copy of the parent's split record. */
static inline int node_box(const item *w, size_t lo, size_t hi, float pm0, float pm1, float pm2,
                           float mn[3], float mx[3]) {
    int dup = 0;
#if defined(__SSE2__)
    { /* an item is one vector (x, y, z, index bits); lane 3 is ignored */
        __m128 vmn = _mm_loadu_ps(w[lo].p), vmx = vmn;
        const __m128 vpm = _mm_setr_ps(pm0, pm1, pm2, 0.0f);
        for (size_t i = lo; i < hi; i++) {
            const __m128 v = _mm_loadu_ps(w[i].p);
            vmn = _mm_min_ps(v, vmn); /* v < vmn ? v : vmn, as the scalar loop below */
            vmx = _mm_max_ps(v, vmx);
            dup |= (_mm_movemask_ps(_mm_cmpeq_ps(v, vpm)) & 7) == 7;
        }
        float t4[4];
        _mm_storeu_ps(t4, vmn);
        mn[0] = t4[0], mn[1] = t4[1], mn[2] = t4[2];
        _mm_storeu_ps(t4, vmx);
        mx[0] = t4[0], mx[1] = t4[1], mx[2] = t4[2];
    }
#else
    for (int a = 0; a < 3; a++) mn[a] = mx[a] = w[lo].p[a];
    for (size_t i = lo; i < hi; i++) {
        float x = w[i].p[0], y = w[i].p[1], z = w[i].p[2];
        mn[0] = x < mn[0] ? x : mn[0], mx[0] = x > mx[0] ? x : mx[0];
        mn[1] = y < mn[1] ? y : mn[1], mx[1] = y > mx[1] ? y : mx[1];
        mn[2] = z < mn[2] ? z : mn[2], mx[2] = z > mx[2] ? z : mx[2];
        dup |= (x == pm0) & (y == pm1) & (z == pm2);
    }
#endif
    return dup;
}

/* pm_kdtree_build's walk over the nodes: each internal node's split record (order) and axis
 * byte (ax: axis, or uniform, and the tightening code), each bucket's records placed; w[0..m)
 * is the work array of finite records, reordered as it goes. */
static void build_nodes(pm_kdtree *t, item *w, size_t m, uint32_t *order, uint8_t *ax) {
    /* Depth-first walk with an explicit stack: (node, range, level, parent's split). */
    struct {
        uint64_t p;
        size_t lo, hi;
        int level, paxis; /* paxis: the parent's split axis, -1 at the root */
        float pmed[3];    /* the parent's split record */
        float clo[3], chi[3]; /* the node's cell before its own tightening code */
    } st[PM_KDTREE_MAX_DEPTH + 2];
    int sp = 0;
    uint64_t rng = 0x9E3779B97F4A7C15ull;
    if (m > 0) {
        memset(&st[0], 0, sizeof st[0]);
        st[0].p = 1, st[0].hi = m, st[0].paxis = -1;
        memcpy(st[0].clo, t->lo, sizeof t->lo);
        memcpy(st[0].chi, t->hi, sizeof t->hi);
        sp = 1;
    }
    while (sp > 0) {
        sp--;
        uint64_t p = st[sp].p;
        size_t lo = st[sp].lo, hi = st[sp].hi;
        int level = st[sp].level, paxis = st[sp].paxis;
        const float pm0 = st[sp].pmed[0], pm1 = st[sp].pmed[1], pm2 = st[sp].pmed[2];
        float clo[3], chi[3];
        memcpy(clo, st[sp].clo, sizeof clo);
        memcpy(chi, st[sp].chi, sizeof chi);
        if (p >= t->nleaves) { /* a bucket: its records in work order */
            place_subtree(t, order, ax, p, level, w + lo);
            continue;
        }
        /* Tight bounding box, and whether this node holds copies of its parent's split. */
        float mn[3], mx[3];
        int dup = node_box(w, lo, hi, pm0, pm1, pm2, mn, mx);
        float ext[3] = {mx[0] - mn[0], mx[1] - mn[1], mx[2] - mn[2]};
        unsigned code = t->tight ? choose_code(clo, chi, mn, mx) : 0;
        pm__tighten(clo, chi, code);
        /* Extents of huge coordinates may overflow to inf; that is still the largest. */
        if (!(ext[0] > 0) && !(ext[1] > 0) && !(ext[2] > 0)) {
            place_subtree(t, order, ax, p, level, w + lo);
            ax[p - 1] = (uint8_t)(PM__AXIS_UNIFORM | code << PM__CODE_SHIFT);
            continue;
        }
        int a = 0;
        if (ext[1] > ext[a]) a = 1;
        if (ext[2] > ext[a]) a = 2;
        /* A node that holds copies of its parent's split record keeps the parent's axis (see
         * DUPLICATES above). */
        if (dup && paxis >= 0 && ext[paxis] > 0) a = paxis;
        size_t r = (size_t)subtree_size(t, 2 * p, level + 1);
        select_rank(w + lo, hi - lo, r, a, &rng);
        const item *med = &w[lo + r];
        order[p - 1] = med->idx;
        ax[p - 1] = (uint8_t)((unsigned)a | code << PM__CODE_SHIFT);
        for (int c = 0; c < 2; c++) { /* right child first, so the left is built first */
            st[sp].p = 2 * p + 1 - (uint64_t)c;
            st[sp].lo = c ? lo : lo + r + 1;
            st[sp].hi = c ? lo + r : hi;
            st[sp].level = level + 1, st[sp].paxis = a;
            memcpy(st[sp].pmed, med->p, sizeof st[sp].pmed);
            /* the children's cells: this node's (tightened) cell cut at the split */
            memcpy(st[sp].clo, clo, sizeof clo);
            memcpy(st[sp].chi, chi, sizeof chi);
            if (c) st[sp].chi[a] = med->p[a];
            else st[sp].clo[a] = med->p[a];
            sp++;
        }
    }
}

/* The records of base[0..n) (stride S) into tree order (slot i gets the record order[i]) through
 * dst (room for n records), with the random reads prefetched well ahead, then copied back in
 * one sweep. */
static void records_to_tree_order(char *base, char *dst, const uint32_t *order, size_t n, size_t S) {
    const size_t ahead = 16;
    for (size_t i = 0; i < n; i++) {
        if (i + ahead < n) __builtin_prefetch(base + (size_t)order[i + ahead] * S);
        if (S == 20) /* pm_photon: a fixed-size copy the compiler inlines */
            memcpy(dst + i * 20, base + (size_t)order[i] * 20, 20);
        else
            memcpy(dst + i * S, base + (size_t)order[i] * S, S);
    }
    if (n > 0) memcpy(base, dst, n * S);
}

/* The axis bytes ax of the internal nodes written into the records' axis bytes (cfg->axis_offset
 * >= 0). */
static void write_axis_bits(const pm_kdtree *t, char *base, size_t m, const pm_kdtree_config *cfg,
                            const uint8_t *ax) {
    /* Axis bits in the records: internal nodes get their axis (or 3, uniform), and their
     * tightening code when the tree owns bits 4-7 too; bucket records get 0 there. The
     * byte's other bits are preserved. */
    unsigned own = t->tight ? PM__AXIS_MASK | PM__CODE_MAX << PM__CODE_SHIFT : PM__AXIS_MASK;
    for (size_t i = 0; i < m; i++) {
        uint8_t *b = (uint8_t *)base + i * cfg->stride + cfg->axis_offset;
        unsigned v = i < t->ninternal ? ax[i] & own : 0;
        *b = (uint8_t)((*b & ~own) | v);
    }
}

int pm_kdtree_build(pm_kdtree **out, void *records, size_t n, const pm_kdtree_config *cfg,
                    uint32_t *perm) {
    if (!out) return PM_EINVAL;
    *out = NULL;
    if (!cfg || (n > 0 && !records) || !config_ok(cfg, records)) return PM_EINVAL;
    if (n >= 0xFFFFFFFFu) return PM_ERANGE;

    pm_kdtree *t = calloc(1, sizeof *t);
    /* The work array is later reused to gather the records in tree order. */
    size_t wsz = cfg->stride > sizeof(item) ? cfg->stride : sizeof(item);
    item *w = malloc((n ? n : 1) * wsz);
    uint32_t *order = malloc((n ? n : 1) * sizeof *order);
    uint8_t *ax = NULL;
    if (!t || !w || !order) goto nomem;

    t->rec = records;
    t->stride = cfg->stride;
    t->pos_offset = cfg->pos_offset;
    t->axis_offset = cfg->axis_offset;
    t->bucket = cfg->bucket;
    /* The tree owns bits 4-7 of the axis byte in its own array and in pm_photon's flag. */
    t->tight = cfg->axis_offset < 0 ||
               (cfg->stride == 20 && cfg->pos_offset == 0 && cfg->axis_offset == 18);

    /* Finite records to the work array; non-finite ones to the tail, in original order. */
    char *base = records;
    size_t m = gather_finite(t, base, n, cfg, w, order);

    /* Shape: smallest D with m + 1 <= (B + 1) * 2^D. */
    int D = 0;
    while ((uint64_t)m + 1 > ((uint64_t)cfg->bucket + 1) << D) D++;
    t->depth = (uint32_t)D;
    t->nleaves = (uint32_t)1 << D;
    t->ninternal = t->nleaves - 1;
    t->leaf_q = (uint32_t)((m - t->ninternal) / t->nleaves);
    t->leaf_extra = (uint32_t)((m - t->ninternal) % t->nleaves);

    ax = malloc(t->ninternal ? t->ninternal : 1);
    if (!ax) goto nomem;

    build_nodes(t, w, m, order, ax);
    /* Gather the records in tree order into the work array's memory (sized for this). */
    records_to_tree_order(base, (char *)w, order, n, cfg->stride);
    free(w);
    w = NULL;
    if (perm) memcpy(perm, order, n * sizeof *perm);

    if (cfg->axis_offset >= 0) {
        /* Axis bits in the records (write_axis_bits); the tree keeps no array of its own. */
        write_axis_bits(t, base, m, cfg, ax);
        free(ax);
        t->axes = NULL;
    } else {
        t->axes = ax;
    }
    free(order);
    *out = t;
    return PM_OK;

nomem:
    free(t);
    free(w);
    free(order);
    free(ax);
    return PM_ENOMEM;
}
