/* internal.h: the one sort and the one max-heap of neighbours that the module's searches and
 * estimates share (the sort, a heapsort, is a macro so that the hull's points use it too). Private: never installed, every name is pm__ and static inline, so each
 * file that includes it gets its own copy and nothing is exported.
 *
 * ORDER. pm__nb_less is the deterministic result order of the whole module: by dist2, then by
 * index. pm__nb_sort sorts by it in place without allocating (glibc's qsort may allocate, and
 * queries promise not to): insertion sort for short arrays, where it is fastest, heapsort
 * otherwise, so the worst case stays O(n log n). Indices are distinct, so every correct sort
 * gives the same array. PM_SORT's sort of up to 256 results is pm__nb_sort_keys below (SIMD
 * ranks on 16-bit keys for 16..96 results, 16..128 under -mavx2, else a 64-bit-key merge sort;
 * the rank loop uses AVX2 whenever the CPU has it: RUNTIME AVX2 below, the one function here
 * that is static but not inline).
 *
 * HEAP. A binary max-heap on the key (dist2, index), in h[0..n): h[0] is the largest, the
 * current k-th neighbour of a k-nearest search with a large k. pm__heap_sift_down places v at
 * slot i and moves it down; the larger child is picked without a branch (the comparison is a
 * coin toss, so a branch would mispredict half the time). Keys are distinct, so which records
 * a search returns does not depend on these choices (kdtree.h, TIES). (A 4-ary heap was
 * measured and gave nothing: docs/BENCHMARKS.md.) Small k keep a sorted array instead: THE
 * K-NEAREST RESULT SET below.
 */
#ifndef PM_INTERNAL_H
#define PM_INTERNAL_H

#include <float.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#if defined(__AVX2__)
#include <immintrin.h>
#elif defined(__SSE2__)
#include <emmintrin.h>
#endif

#include "common.h"

static inline int pm__nb_less(const pm_neighbor *a, const pm_neighbor *b) {
    return a->dist2 < b->dist2 || (a->dist2 == b->dist2 && a->index < b->index);
}

/* PM__HEAPSORT(name, type, less) defines static inline void name(type *a, size_t n): an
 * in-place heapsort of a[0..n), ascending by less(const type *, const type *), that never
 * allocates; and name##_sift, its sift-down in the max-heap a[0..n). This is the module's one
 * comparison sort: the neighbours' (dist2, index) order below and the convex hull's 2-D points
 * (estimate.c, by (u, v)) are its two instances. Not stable: equal keys may come out in any
 * fixed order. */
#define PM__HEAPSORT(name, type, less)                                                       \
    static inline void name##_sift(type *a, size_t n, size_t i) {                            \
        for (;;) {                                                                           \
            size_t c = 2 * i + 1;                                                            \
            if (c >= n) return;                                                              \
            if (c + 1 < n && less(&a[c], &a[c + 1])) c++;                                    \
            if (!less(&a[i], &a[c])) return;                                                 \
            type s_ = a[i];                                                                  \
            a[i] = a[c];                                                                     \
            a[c] = s_;                                                                       \
            i = c;                                                                           \
        }                                                                                    \
    }                                                                                        \
    static inline void name(type *a, size_t n) {                                             \
        for (size_t i = n / 2; i-- > 0;) name##_sift(a, n, i);                               \
        for (size_t e = n; e > 1; e--) {                                                     \
            type s_ = a[0];                                                                  \
            a[0] = a[e - 1];                                                                 \
            a[e - 1] = s_;                                                                   \
            name##_sift(a, e - 1, 0);                                                        \
        }                                                                                    \
    }

PM__HEAPSORT(pm__nb_heapsort, pm_neighbor, pm__nb_less)

/* Sorts a[0..n) by (dist2, index) ascending, in place, without allocating. */
static inline void pm__nb_sort(pm_neighbor *a, size_t n) {
    if (n <= 24) {
        for (size_t i = 1; i < n; i++) {
            pm_neighbor v = a[i];
            size_t j = i;
            while (j > 0 && pm__nb_less(&v, &a[j - 1])) {
                a[j] = a[j - 1];
                j--;
            }
            a[j] = v;
        }
        return;
    }
    pm__nb_heapsort(a, n);
}

/* The (dist2, index) key of a neighbour as one unsigned 64-bit integer: dist2 is never negative
 * (nor NaN), so its bits order like its value, and the index breaks ties. */
static inline uint64_t pm__nb_key(pm_neighbor v) {
    uint32_t b;
    memcpy(&b, &v.dist2, sizeof b);
    return (uint64_t)b << 32 | v.index;
}

/* Max-heap on (dist2, index) in h[0..n): puts v at slot i and sifts it down. */
static inline void pm__heap_sift_down(pm_neighbor *h, unsigned n, unsigned i, pm_neighbor v) {
    const uint64_t kv = pm__nb_key(v);
    for (;;) {
        unsigned c = 2 * i + 1;
        if (c >= n) break;
        if (c + 1 < n) c += pm__nb_key(h[c + 1]) > pm__nb_key(h[c]);
        if (!(pm__nb_key(h[c]) > kv)) break;
        h[i] = h[c];
        i = c;
    }
    h[i] = v;
}

/* Turns h[0..n), in any order, into a max-heap on (dist2, index). */
static inline void pm__heapify(pm_neighbor *h, unsigned n) {
    for (unsigned i = n / 2; i-- > 0;) pm__heap_sift_down(h, n, i, h[i]);
}

/* Replaces the largest entry h[0] by v and restores the heap: exactly
 * pm__heap_sift_down(h, n, 0, v), computed without a data-dependent branch. The sift-down
 * follows the path of larger children from the root (which child is larger does not depend on
 * v) and stops above the first path node that is not > v; along that path the key never grows,
 * so "> v" holds for a prefix of it. Here the whole path is walked first (its length depends on
 * n only, except for the last step), m = the number of path nodes > v is counted, the first m
 * move up one place and v goes to the m-th. The k-nearest searches call this once per record
 * that enters a full heap; the loop that stopped at a data-dependent level mispredicted its
 * exit about once per call. Keys are (dist2, index) (pm__nb_key), all distinct. */
static inline void pm__heap_replace_top(pm_neighbor *h, unsigned n, pm_neighbor v) {
    if (n < 2) {
        h[0] = v;
        return;
    }
    const uint64_t kv = pm__nb_key(v);
    unsigned path[33], D = 31u - (unsigned)__builtin_clz(n), i = 0, m = 0;
    path[0] = 0;
    /* levels 1 .. D-1 are complete: both children exist */
    for (unsigned d = 1; d < D; d++) {
        unsigned c = 2 * i + 1;
        uint64_t k0 = pm__nb_key(h[c]), k1 = pm__nb_key(h[c + 1]);
        c += k1 > k0;
        m += (k1 > k0 ? k1 : k0) > kv;
        path[d] = i = c;
    }
    /* level D: none, one or two children (l, r: i itself where a child is missing) */
    {
        unsigned c = 2 * i + 1;
        unsigned has = c < n, has2 = c + 1 < n;
        unsigned l = i + (has ? c - i : 0u), r = l + (has2 ? 1u : 0u);
        unsigned cc = r + (pm__nb_key(h[r]) > pm__nb_key(h[l]) ? 0u : l - r);
        m += has & (pm__nb_key(h[cc]) > kv);
        path[D] = cc;
    }
    /* the first m path nodes move up: D steps, each a move or a rewrite of the same value */
    for (unsigned d = 1; d <= D; d++) {
        unsigned src = d <= m ? path[d] : path[d - 1];
        h[path[d - 1]] = h[src];
    }
    h[path[m]] = v;
}

/* THE K-NEAREST RESULT SET, shared by every k-nearest search of the module (kdtree.h, TIES):
 * the k records of smallest (dist2, index), among those with dist2 < max_dist2. A search keeps
 * a bound `lim` and offers a record only when !(d2 >= lim) (lim NaN = no bound): lim starts as
 * max_dist2 (NaN for +inf) and, once k are held, becomes the float just above the largest
 * kept dist2 (the next bit pattern up; NaN when that dist2 is +inf), so a record tied with the
 * largest kept one is still offered and wins when its index is smaller. Cells are pruned by
 * the same test on their distance, so a cell at exactly the k-th distance is still searched.
 * Up to PM__KNN_SORTED_MAX results are kept in an array sorted by (dist2, index) ascending
 * (insertion from the end, as short arrays are cheapest that way); above it, a max-heap on the
 * same key. Either way the set is the same for any visiting order. */
#ifndef PM__KNN_SORTED_MAX
#define PM__KNN_SORTED_MAX 16u
#endif

static inline float pm__nextup(float x) {
    uint32_t b;
    memcpy(&b, &x, sizeof b);
    b++;
    memcpy(&x, &b, sizeof x);
    return x;
}

/* The heap half of pm__knn_offer (k > PM__KNN_SORTED_MAX), out of line: it is the rarer and
 * the larger one. */
#if defined(__GNUC__)
__attribute__((noinline, unused))
#endif
static int pm__knn_offer_heap(pm_neighbor *out, unsigned k, unsigned *found, float *lim,
                              pm_neighbor nb) {
    unsigned f = *found;
    if (f < k) {
        out[f++] = nb;
        *found = f;
        if (f == k) {
            pm__heapify(out, k);
            *lim = pm__nextup(out[0].dist2);
        }
        return 1;
    }
    if (nb.dist2 == out[0].dist2 && nb.index > out[0].index) return 0;
    pm__heap_replace_top(out, k, nb);
    *lim = pm__nextup(out[0].dist2);
    return 1;
}

/* Offers (d2, idx) to out[0..*found) of capacity k. The caller has checked !(d2 >= *lim).
 * Returns 1 when the record entered, 0 when it lost a tie to the largest kept one (then so
 * does every record at the same d2 with a larger index). Inlined into each search (the
 * sorted array's insertion is a few instructions per entry moved). */
#if defined(__GNUC__)
__attribute__((always_inline, unused))
#endif
static inline int pm__knn_offer(pm_neighbor *out, unsigned k, unsigned *found, float *lim,
                                float d2, uint32_t idx) {
    pm_neighbor nb;
    nb.dist2 = d2;
    nb.index = idx;
    if (k > PM__KNN_SORTED_MAX) return pm__knn_offer_heap(out, k, found, lim, nb);
    unsigned f = *found, j;
    if (f < k) {
        j = f;
        *found = ++f;
    } else {
        j = k - 1;
        if (d2 == out[j].dist2 && idx > out[j].index) return 0;
    }
    while (j > 0 && (out[j - 1].dist2 > d2 || (out[j - 1].dist2 == d2 && out[j - 1].index > idx))) {
        out[j] = out[j - 1];
        j--;
    }
    out[j] = nb;
    if (f == k) *lim = pm__nextup(out[k - 1].dist2);
    return 1;
}

/* Whether a k-nearest result of k slots is kept sorted (then PM_SORT has nothing to do). */
static inline int pm__knn_is_sorted(unsigned k) { return k <= PM__KNN_SORTED_MAX; }

/* Up to this many results are sorted by pm__nb_sort_keys, on the stack (2 x 8 bytes each). */
#define PM__SORT_KEYS_MAX 256u

#if defined(__SSE2__)
/* pm__nb_sort_keys tries pm__nb_sort_rank first for PM__SORT_RANK_MIN <= n <= PM__SORT_RANK_MAX
 * (below, the merge sort is as fast; above, the O(n^2) ranks cost more than it and their keys
 * tie more often). Measured with the crossovers in bench/results/experiments.csv. */
#define PM__SORT_RANK_MIN 16u
#if defined(__AVX2__)
#define PM__SORT_RANK_MAX 128u
#else
#define PM__SORT_RANK_MAX 96u
#endif
#define PM__SORT_RANK_LANES 64u /* keys per pass of the AVX2 rank loop: 4 vectors of 16 */

/* RUNTIME AVX2. A build without -mavx2 (the default: it must run on any x86-64) still counts
 * the ranks with AVX2 when the CPU has it: the AVX2 loop is compiled for that target alone
 * (a function attribute; GCC and clang) and chosen per call by pm__have_avx2, which asks cpuid
 * once (AVX2, and that the OS saves the AVX state: OSXSAVE and XCR0) and keeps the answer in
 * an atomic flag (__builtin_cpu_supports would need libgcc's __cpu_model, which the shared
 * library does not link). The SSE2 loop stays for CPUs without AVX2. Both count the same
 * ranks, so the results are the same arrays (tests/test_kdtree_sort.c runs both). Define
 * PM_NO_RUNTIME_AVX2 to leave it out. */
#if !defined(__AVX2__) && defined(__GNUC__) && (defined(__x86_64__) || defined(__i386__)) &&     \
    !defined(PM_NO_RUNTIME_AVX2)
#define PM__RANK_RUNTIME_AVX2 1
#define PM__TARGET_AVX2 __attribute__((target("avx2"), noinline, unused))
#include <cpuid.h>
#include <immintrin.h>
#include <stdatomic.h>
static inline int pm__detect_avx2(void) {
    unsigned a, b, c, d;
    if (!__get_cpuid(1, &a, &b, &c, &d)) return 0;
    if (!(c & (1u << 27)) || !(c & (1u << 28))) return 0; /* OSXSAVE, AVX */
    unsigned xlo, xhi;
    __asm__ volatile("xgetbv" : "=a"(xlo), "=d"(xhi) : "c"(0u));
    (void)xhi;
    if ((xlo & 6u) != 6u) return 0; /* the OS saves the SSE and AVX state */
    if (!__get_cpuid_count(7, 0, &a, &b, &c, &d)) return 0;
    return (b >> 5) & 1u; /* AVX2 */
}
static inline int pm__have_avx2(void) {
    static atomic_int have = -1; /* one per file that includes this; each asks once */
    int h = atomic_load_explicit(&have, memory_order_relaxed);
    if (h < 0) {
        h = pm__detect_avx2();
        atomic_store_explicit(&have, h, memory_order_relaxed);
    }
    return h;
}
#else
#define PM__RANK_RUNTIME_AVX2 0
#define PM__TARGET_AVX2 inline
static inline int pm__have_avx2(void) {
#if defined(__AVX2__)
    return 1;
#else
    return 0;
#endif
}
#endif

#if defined(__AVX2__) || PM__RANK_RUNTIME_AVX2
/* The AVX2 rank loop: rank[i] = -#{j < n: key[j] < key[i]} for i < nl (nl: n rounded up to
 * whole passes of PM__SORT_RANK_LANES; key[n..nl) = -32768, so those lanes get rank 0); returns
 * the sum of the n ranks. Four independent counters per pass (one would be a chain of n
 * dependent adds). */
static PM__TARGET_AVX2 unsigned pm__rank_avx2(const int16_t *key, int16_t *rank, unsigned n,
                                              unsigned nl) {
    enum { L = PM__SORT_RANK_LANES };
    __m256i tot = _mm256_setzero_si256();
    for (unsigned g = 0; g < nl; g += L) {
        const __m256i *kv = (const __m256i *)(const void *)&key[g];
        __m256i *rv = (__m256i *)(void *)&rank[g];
        const __m256i A0 = _mm256_loadu_si256(kv), A1 = _mm256_loadu_si256(kv + 1),
                      A2 = _mm256_loadu_si256(kv + 2), A3 = _mm256_loadu_si256(kv + 3);
        __m256i c0 = _mm256_setzero_si256(), c1 = c0, c2 = c0, c3 = c0;
        for (unsigned j = 0; j < n; j++) {
            const __m256i B = _mm256_set1_epi16(key[j]);
            c0 = _mm256_add_epi16(c0, _mm256_cmpgt_epi16(A0, B));
            c1 = _mm256_add_epi16(c1, _mm256_cmpgt_epi16(A1, B));
            c2 = _mm256_add_epi16(c2, _mm256_cmpgt_epi16(A2, B));
            c3 = _mm256_add_epi16(c3, _mm256_cmpgt_epi16(A3, B));
        }
        _mm256_storeu_si256(rv, c0);
        _mm256_storeu_si256(rv + 1, c1);
        _mm256_storeu_si256(rv + 2, c2);
        _mm256_storeu_si256(rv + 3, c3);
        const __m256i c = _mm256_add_epi16(_mm256_add_epi16(c0, c1), _mm256_add_epi16(c2, c3));
        tot = _mm256_add_epi32(tot, _mm256_madd_epi16(c, _mm256_set1_epi16(-1)));
    }
    __m128i s = _mm_add_epi32(_mm256_castsi256_si128(tot), _mm256_extracti128_si256(tot, 1));
    s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0x4e));
    s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0xb1));
    return (unsigned)_mm_cvtsi128_si32(s);
}
#endif

/* The SSE2 rank loop of pm__nb_sort_rank for G (1..8, a constant once inlined) vectors of 8
 * keys A[0..G): out[u] = -(the number of keys kk[0..n) below each of A[u]'s keys). Eight keys
 * are broadcast from one load by an unpack and four shuffles each (one shuffle a key, against
 * three instructions for a _mm_set1_epi16 from memory), and every broadcast serves all G
 * vectors with G independent counters. The repeated lines are deliberate: the eight counters
 * are separate variables (registers, where an array could be spilled) and _mm_shuffle_epi32
 * takes its lane as an immediate, so neither the counters nor the eight broadcasts can be a
 * loop without leaving the unrolling to the compiler on the sort's hot path. */
#define PM__RANK_STEP(b)                                                                         \
    do {                                                                                         \
        c0 = _mm_add_epi16(c0, _mm_cmpgt_epi16(A[0], b));                                        \
        if (G > 1) c1 = _mm_add_epi16(c1, _mm_cmpgt_epi16(A[1], b));                             \
        if (G > 2) c2 = _mm_add_epi16(c2, _mm_cmpgt_epi16(A[2], b));                             \
        if (G > 3) c3 = _mm_add_epi16(c3, _mm_cmpgt_epi16(A[3], b));                             \
        if (G > 4) c4 = _mm_add_epi16(c4, _mm_cmpgt_epi16(A[4], b));                             \
        if (G > 5) c5 = _mm_add_epi16(c5, _mm_cmpgt_epi16(A[5], b));                             \
        if (G > 6) c6 = _mm_add_epi16(c6, _mm_cmpgt_epi16(A[6], b));                             \
        if (G > 7) c7 = _mm_add_epi16(c7, _mm_cmpgt_epi16(A[7], b));                             \
    } while (0)
static inline __attribute__((always_inline)) void pm__rank_group(const unsigned G, const __m128i *A,
                                                                 const int16_t *kk, unsigned n,
                                                                 __m128i *out) {
    __m128i c0 = _mm_setzero_si128(), c1 = c0, c2 = c0, c3 = c0, c4 = c0, c5 = c0, c6 = c0, c7 = c0;
    unsigned j = 0;
    for (; j + 8 <= n; j += 8) {
        const __m128i K = _mm_loadu_si128((const __m128i *)(const void *)&kk[j]);
        const __m128i lo = _mm_unpacklo_epi16(K, K), hi = _mm_unpackhi_epi16(K, K);
        __m128i b;
        b = _mm_shuffle_epi32(lo, 0x00);
        PM__RANK_STEP(b);
        b = _mm_shuffle_epi32(lo, 0x55);
        PM__RANK_STEP(b);
        b = _mm_shuffle_epi32(lo, 0xaa);
        PM__RANK_STEP(b);
        b = _mm_shuffle_epi32(lo, 0xff);
        PM__RANK_STEP(b);
        b = _mm_shuffle_epi32(hi, 0x00);
        PM__RANK_STEP(b);
        b = _mm_shuffle_epi32(hi, 0x55);
        PM__RANK_STEP(b);
        b = _mm_shuffle_epi32(hi, 0xaa);
        PM__RANK_STEP(b);
        b = _mm_shuffle_epi32(hi, 0xff);
        PM__RANK_STEP(b);
    }
    for (; j < n; j++) {
        const __m128i b = _mm_set1_epi16(kk[j]);
        PM__RANK_STEP(b);
    }
    out[0] = c0;
    if (G > 1) out[1] = c1;
    if (G > 2) out[2] = c2;
    if (G > 3) out[3] = c3;
    if (G > 4) out[4] = c4;
    if (G > 5) out[5] = c5;
    if (G > 6) out[6] = c6;
    if (G > 7) out[7] = c7;
}
#undef PM__RANK_STEP

/* The SSE2 rank loop: as pm__rank_avx2 for the nv = ceil(n / 8) vectors of keys. One pass over
 * the keys for up to 8 vectors (64 keys), so that each key's broadcast serves them all; longer
 * arrays take 8 and then the rest. */
static inline unsigned pm__rank_sse2(const __m128i *keyv, const int16_t *key, __m128i *rankv,
                                     unsigned n) {
    const unsigned nv = (n + 7) / 8;
    unsigned g = 0;
    for (; g + 8 <= nv; g += 8) pm__rank_group(8, &keyv[g], key, n, &rankv[g]);
    switch (nv - g) {
    case 7: pm__rank_group(7, &keyv[g], key, n, &rankv[g]); break;
    case 6: pm__rank_group(6, &keyv[g], key, n, &rankv[g]); break;
    case 5: pm__rank_group(5, &keyv[g], key, n, &rankv[g]); break;
    case 4: pm__rank_group(4, &keyv[g], key, n, &rankv[g]); break;
    case 3: pm__rank_group(3, &keyv[g], key, n, &rankv[g]); break;
    case 2: pm__rank_group(2, &keyv[g], key, n, &rankv[g]); break;
    case 1: pm__rank_group(1, &keyv[g], key, n, &rankv[g]); break;
    default: break;
    }
    __m128i s = _mm_setzero_si128();
    for (g = 0; g < nv; g++) s = _mm_add_epi32(s, _mm_madd_epi16(rankv[g], _mm_set1_epi16(-1)));
    s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0x4e));
    s = _mm_add_epi32(s, _mm_shuffle_epi32(s, 0xb1));
    return (unsigned)_mm_cvtsi128_si32(s);
}

/* Sorts a[0..n), 2 <= n <= PM__SORT_RANK_MAX, by (dist2, index) ascending and returns 1, or
 * returns 0 with a unchanged. Each dist2 becomes a 16-bit key, key = trunc((dist2 - lo) * s)
 * - 32768 with [lo, hi] the range of the dist2 and s = 65535 / (hi - lo), then each entry's
 * rank, the number of keys below its own, is counted by SIMD compares of every key against
 * every other (n^2 / 8 compares with SSE2, n^2 / 16 with AVX2, which `avx2` selects; no branch
 * depends on the data), and the entry goes to out[rank]. The key is a non-decreasing function of dist2 (each float
 * operation rounds monotonically, also when denormals flush to zero), so two entries with
 * different keys are in the right order; and the ranks sum to n(n-1)/2 exactly when no two keys
 * are equal (a tie lowers the later ranks of its group), in which case no two dist2 are equal
 * either and the order by keys IS the order by (dist2, index). Otherwise (keys tied: about 2%
 * of k = 50 results; all dist2 equal; a dist2 of +inf, which makes the range infinite) it
 * returns 0 and the merge sort below decides. dist2 is never NaN or negative (see below). */
static inline int pm__nb_sort_rank_with(pm_neighbor *a, unsigned n, int avx2) {
    enum { L = PM__SORT_RANK_LANES };
    union {
        int16_t k[PM__SORT_RANK_MAX + L];
        __m128i v[(PM__SORT_RANK_MAX + L) / 8];
    } key, rank;
    pm_neighbor t[PM__SORT_RANK_MAX + L];
    const unsigned nl = (n + L - 1) / L * L; /* n rounded up to whole passes */
    const unsigned n8 = (n + 7) & ~7u;       /* ... and to whole vectors of keys */
    unsigned i = 0;
    /* copy a to t (the scatter below reads t) and find the range of dist2, 4 at a time */
    __m128 lo = _mm_set1_ps(a[0].dist2), hi = lo;
    for (; i + 4 <= n; i += 4) {
        const __m128 y0 = _mm_loadu_ps(&a[i].dist2), y1 = _mm_loadu_ps(&a[i + 2].dist2);
        _mm_storeu_ps(&t[i].dist2, y0);
        _mm_storeu_ps(&t[i + 2].dist2, y1);
        const __m128 x = _mm_shuffle_ps(y0, y1, 0x88); /* the dist2 of a[i..i+3] */
        lo = _mm_min_ps(lo, x);
        hi = _mm_max_ps(hi, x);
    }
    for (; i < n; i++) {
        const __m128 x = _mm_set1_ps(a[i].dist2);
        t[i] = a[i];
        lo = _mm_min_ps(lo, x);
        hi = _mm_max_ps(hi, x);
    }
    lo = _mm_min_ps(lo, _mm_shuffle_ps(lo, lo, 0x4e));
    lo = _mm_min_ps(lo, _mm_shuffle_ps(lo, lo, 0xb1));
    hi = _mm_max_ps(hi, _mm_shuffle_ps(hi, hi, 0x4e));
    hi = _mm_max_ps(hi, _mm_shuffle_ps(hi, hi, 0xb1));
    const float low = _mm_cvtss_f32(lo), span = _mm_cvtss_f32(hi) - low;
    if (!(span > 0) || !(span <= FLT_MAX)) return 0;
    const float scale = 65535.0f / span;
    if (!(scale <= FLT_MAX)) return 0;
    /* padding entries get the lowest key: rank 0, so they add nothing to the sum */
    for (i = n; i < n8; i++) t[i].dist2 = low, t[i].index = 0;
    {
        const __m128 vlo = _mm_set1_ps(low), vs = _mm_set1_ps(scale);
        const __m128i off = _mm_set1_epi32(32768);
        unsigned b = 0;
        for (; b < n8 / 8; b++) {
            const float *p = &t[8 * b].dist2;
            __m128 x0 = _mm_shuffle_ps(_mm_loadu_ps(p), _mm_loadu_ps(p + 4), 0x88);
            __m128 x1 = _mm_shuffle_ps(_mm_loadu_ps(p + 8), _mm_loadu_ps(p + 12), 0x88);
            __m128i k0 = _mm_sub_epi32(_mm_cvttps_epi32(_mm_mul_ps(_mm_sub_ps(x0, vlo), vs)), off);
            __m128i k1 = _mm_sub_epi32(_mm_cvttps_epi32(_mm_mul_ps(_mm_sub_ps(x1, vlo), vs)), off);
            key.v[b] = _mm_packs_epi32(k0, k1);
        }
        for (; b < nl / 8; b++) key.v[b] = _mm_set1_epi16(-32768);
    }
    /* rank.k[i] = -#{j < n: key[j] < key[i]}: a compare's true lane is -1 */
    unsigned total;
#if defined(__AVX2__) || PM__RANK_RUNTIME_AVX2
    if (avx2)
        total = pm__rank_avx2(key.k, rank.k, n, nl);
    else
#endif
        total = pm__rank_sse2(key.v, key.k, rank.v, n);
    (void)avx2;
    if (total != n * (n - 1) / 2) return 0; /* two keys are equal */
    for (i = 0; i < n; i++) a[-rank.k[i]] = t[i];
    return 1;
}

/* pm__nb_sort_rank_with on this CPU's fastest rank loop. */
static inline int pm__nb_sort_rank(pm_neighbor *a, unsigned n) {
    return pm__nb_sort_rank_with(a, n, pm__have_avx2());
}
#endif /* __SSE2__ */

/* Sorts a[0..n), n <= PM__SORT_KEYS_MAX, by (dist2, index) ascending. Between
 * PM__SORT_RANK_MIN and PM__SORT_RANK_MAX entries pm__nb_sort_rank (above) does it when its keys
 * do not tie (the same array: both sort by the one order), else (and for other n) each entry
 * becomes one 64-bit key, the bits of dist2 above the index: dist2 is never negative or NaN (a sum of
 * squares of finite differences, possibly +inf), and the bits of such floats order as the
 * floats do, so comparing keys compares (dist2, index) in one integer test. The keys are then
 * merge-sorted bottom-up with a branch-free merge step (a data-dependent branch here
 * mispredicts about half the time, which is what makes a comparison sort of k results cost
 * as much as a tenth of the query). */
static inline void pm__nb_sort_keys(pm_neighbor *a, unsigned n) {
#if defined(__SSE2__)
    if (n >= PM__SORT_RANK_MIN && n <= PM__SORT_RANK_MAX && pm__nb_sort_rank(a, n)) return;
#endif
    uint64_t ka[PM__SORT_KEYS_MAX], kb[PM__SORT_KEYS_MAX], *src = ka, *dst = kb;
    for (unsigned i = 0; i < n; i++) {
        uint32_t b;
        memcpy(&b, &a[i].dist2, sizeof b);
        ka[i] = (uint64_t)b << 32 | a[i].index;
    }
    /* runs of 4 by a sorting network of compare-exchanges (branch-free min/max) */
    for (unsigned lo = 0; lo + 4 <= n; lo += 4) {
        uint64_t *r = src + lo;
#define PM__CX(x, y)                                                                             \
    do {                                                                                         \
        uint64_t p_ = r[x], q_ = r[y];                                                           \
        r[x] = p_ < q_ ? p_ : q_;                                                                \
        r[y] = p_ < q_ ? q_ : p_;                                                                \
    } while (0)
        PM__CX(0, 1);
        PM__CX(2, 3);
        PM__CX(0, 2);
        PM__CX(1, 3);
        PM__CX(1, 2);
#undef PM__CX
    }
    for (unsigned i = n & ~3u; i < n; i++) { /* the last, short run */
        uint64_t v = src[i];
        unsigned j = i;
        while (j > (n & ~3u) && src[j - 1] > v) {
            src[j] = src[j - 1];
            j--;
        }
        src[j] = v;
    }
    /* Merges, from both ends at once: the front takes the smaller head, the back the larger
     * tail, two independent chains of loads and compares instead of one (about 2x faster
     * than one chain at k = 50). */
    for (unsigned w = 4; w < n; w *= 2) {
        for (unsigned lo = 0; lo < n; lo += 2 * w) {
            unsigned mid = lo + w < n ? lo + w : n, hi = lo + 2 * w < n ? lo + 2 * w : n;
            if (hi - mid != mid - lo) { /* the last, shorter pair: one chain */
                unsigned i = lo, j = mid, o = lo;
                while (i < mid && j < hi) {
                    uint64_t x = src[i], y = src[j];
                    unsigned t = y < x;
                    dst[o++] = t ? y : x;
                    i += 1 - t;
                    j += t;
                }
                while (i < mid) dst[o++] = src[i++];
                while (j < hi) dst[o++] = src[j++];
                continue;
            }
            /* Two runs of w: w steps from each end; neither end can run past a run, since the
             * w smallest (largest) of the pair fit in either run. */
            unsigned i = lo, j = mid, ie = mid - 1, je = hi - 1, o = lo, oe = hi - 1;
            for (unsigned t0 = 0; t0 < w; t0++) {
                uint64_t x = src[i], y = src[j];
                unsigned t = y < x;
                dst[o++] = t ? y : x;
                i += 1 - t;
                j += t;
                uint64_t xe = src[ie], ye = src[je];
                unsigned te = xe > ye;
                dst[oe--] = te ? xe : ye;
                ie -= te;
                je -= 1 - te;
            }
        }
        uint64_t *sw = src;
        src = dst;
        dst = sw;
    }
    for (unsigned i = 0; i < n; i++) {
        uint32_t b = (uint32_t)(src[i] >> 32);
        memcpy(&a[i].dist2, &b, sizeof b);
        a[i].index = (uint32_t)src[i];
    }
}

#endif /* PM_INTERNAL_H */
