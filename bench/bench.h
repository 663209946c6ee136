/* bench.h: helpers shared by the benchmark programs (bench/bench_*.c).
 *
 * Timing, a seeded random generator, the point distributions of the benchmarks (uniform cube;
 * "photon-like": the six inner walls of a box with 30% in a small floor disc; a dumped
 * photon-map file), brute-force ground truth, medians, heap-allocation accounting, CSV output
 * and progress lines on stderr. The code lives in bench/util.c, linked into every bench.
 */
#ifndef PM_BENCH_H
#define PM_BENCH_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include "photon.h"

/* ---- time and randomness ---- */
double bench_now(void); /* monotonic seconds */
typedef struct bench_rng {
    uint64_t s;
} bench_rng;
void bench_rng_seed(bench_rng *r, uint64_t seed);
uint64_t bench_rng_u64(bench_rng *r);
double bench_rng_unit(bench_rng *r); /* [0, 1) */

/* ---- distributions ---- */
enum { BENCH_UNIFORM = 0, BENCH_PHOTON = 1, BENCH_FILE = 2 };
const char *bench_dist_name(int dist);
/* One sample position of distribution dist (UNIFORM or PHOTON) in the unit box. */
void bench_sample(bench_rng *r, int dist, float p[3]);
/* Fill photons with n samples (power, direction and normal fixed; the search needs positions). */
void bench_fill_photons(pm_photon *ph, size_t n, int dist, uint64_t seed);
/* Queries from the same distribution as the photons: for UNIFORM and PHOTON fresh samples;
 * for a file, a random photon's position jittered by up to `jitter` on each axis. */
void bench_make_queries(float *q, size_t m, int dist, const pm_photon *ph, size_t n,
                        float jitter, uint64_t seed);

/* ---- brute-force truth ----
 * For each of m queries, the kmax nearest of n points (sorted ascending dist2, unlimited radius;
 * fewer if n < kmax). The dist2 formula is the same as every index's (dx*dx + dy*dy + dz*dz in
 * float), so exact results compare equal. Runs on all threads. */
typedef struct bench_truth {
    size_t m;
    unsigned kmax;
    unsigned *count; /* per query: min(kmax, n) */
    float *dist2;    /* m * kmax, row per query, ascending */
} bench_truth;
int bench_truth_compute(bench_truth *t, const float *pts, size_t stride_floats, size_t n,
                        const float *q, size_t m, unsigned kmax);
void bench_truth_free(bench_truth *t);
/* The true answer size for (k, r2): how many of the nearest min(k, n) have dist2 < r2. */
unsigned bench_truth_size(const bench_truth *t, size_t qi, unsigned k, float r2);

/* Recall and exactness of one answer: d2[0..got) are the answer's dist2, recomputed by the
 * caller from positions. Adds to *hits the number of returned records no farther than the true
 * t-th nearest (at most t), and returns 1 if the answer is exact (the same sorted multiset as
 * the truth), else 0. d2 is sorted in place. */
int bench_score(const bench_truth *t, size_t qi, unsigned k, float r2, float *d2, unsigned got,
                uint64_t *hits, uint64_t *wanted);

/* ---- statistics ---- */
double bench_median(double *v, int n); /* sorts v */

/* ---- memory: bytes currently allocated by malloc (mallinfo2: all arenas plus mmap) ---- */
size_t bench_heap_bytes(void);

/* ---- output ---- */
/* Open DIR/NAME for writing and write the header line; exits on failure. */
FILE *bench_csv_open(const char *dir, const char *name, const char *header);
/* Progress on stderr, prefixed with the elapsed time since the first call. */
void bench_log(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
/* Number of threads OpenMP would use (1 without OpenMP). */
int bench_max_threads(void);

/* ---- command line ----
 * Strict number parsing for the bench programs' options: the whole string must be a number
 * in [lo, hi] (counts may be written 1e6; they must then be whole). On anything else they
 * print "PROG: OPTION: expected ..., got 'TEXT'" to stderr and return -1 (the caller exits
 * with status 2), so a typo never runs a benchmark with a silently different setting. */
int bench_parse_count(const char *prog, const char *opt, const char *s, double lo, double hi,
                      size_t *out);
int bench_parse_int(const char *prog, const char *opt, const char *s, long lo, long hi, int *out);
int bench_parse_u64(const char *prog, const char *opt, const char *s, uint64_t *out);
int bench_parse_double(const char *prog, const char *opt, const char *s, double lo, double hi,
                       double *out);

#endif /* PM_BENCH_H */
