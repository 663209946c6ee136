/* util.c: the shared helpers of bench.h (timing, distributions, brute-force truth, scoring,
 * medians, heap accounting, CSV and progress output).
 *
 * The distributions are deterministic for a given seed, so two programs or two runs measure
 * the same points. Brute-force truth keeps, per query, the kmax nearest of all points in a
 * max-heap and sorts them at the end; every (k, radius) answer is a prefix of that list.
 */
#define _GNU_SOURCE
#include "bench.h"

#include <errno.h>
#include <malloc.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#ifdef _OPENMP
#include <omp.h>
#endif

double bench_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* splitmix64: tiny, and good enough for test points. */
void bench_rng_seed(bench_rng *r, uint64_t seed) { r->s = seed * 0x9E3779B97F4A7C15ull + 1; }
uint64_t bench_rng_u64(bench_rng *r) {
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
double bench_rng_unit(bench_rng *r) { return (double)(bench_rng_u64(r) >> 11) * 0x1.0p-53; }

const char *bench_dist_name(int dist) {
    switch (dist) {
    case BENCH_UNIFORM: return "uniform";
    case BENCH_PHOTON: return "photon";
    default: return "file";
    }
}

/* Photon-like: 30% in a disc of radius 0.08 centred on the floor (a caustic), the rest spread
 * evenly over the six inner walls of the unit box. */
#define DISC_FRACTION 0.3
#define DISC_RADIUS 0.08
void bench_sample(bench_rng *r, int dist, float p[3]) {
    if (dist != BENCH_PHOTON) {
        for (int a = 0; a < 3; a++) p[a] = (float)bench_rng_unit(r);
        return;
    }
    if (bench_rng_unit(r) < DISC_FRACTION) {
        double rad = DISC_RADIUS * sqrt(bench_rng_unit(r)), phi = 6.283185307179586 * bench_rng_unit(r);
        p[0] = (float)(0.5 + rad * cos(phi));
        p[1] = 0.0f;
        p[2] = (float)(0.5 + rad * sin(phi));
        return;
    }
    int face = (int)(bench_rng_unit(r) * 6.0);
    int axis = face % 3;
    for (int a = 0; a < 3; a++) p[a] = (float)bench_rng_unit(r);
    p[axis] = face < 3 ? 0.0f : 1.0f;
}

void bench_fill_photons(pm_photon *ph, size_t n, int dist, uint64_t seed) {
    bench_rng r;
    bench_rng_seed(&r, seed);
    for (size_t i = 0; i < n; i++) {
        memset(&ph[i], 0, sizeof ph[i]);
        bench_sample(&r, dist, ph[i].pos);
        /* A grey RGBE power of 1/n-ish; the search never reads it. */
        ph[i].power[0] = ph[i].power[1] = ph[i].power[2] = 128;
        ph[i].power[3] = 128 - 16;
        ph[i].theta = (uint8_t)(i * 7);
        ph[i].phi = (uint8_t)(i * 13);
    }
}

void bench_make_queries(float *q, size_t m, int dist, const pm_photon *ph, size_t n,
                        float jitter, uint64_t seed) {
    bench_rng r;
    bench_rng_seed(&r, seed ^ 0x5151u);
    for (size_t i = 0; i < m; i++) {
        if (dist == BENCH_FILE && n > 0) {
            const pm_photon *p = &ph[bench_rng_u64(&r) % n];
            for (size_t a = 0; a < 3; a++)
                q[3 * i + a] = p->pos[a] + jitter * (float)(2.0 * bench_rng_unit(&r) - 1.0);
        } else {
            bench_sample(&r, dist, &q[3 * i]);
        }
    }
}

/* ---- brute-force truth ---- */

static void heap_down(float *h, unsigned i, unsigned n) {
    float x = h[i];
    for (;;) {
        unsigned l = 2 * i + 1, m;
        if (l >= n) break;
        m = (l + 1 < n && h[l + 1] > h[l]) ? l + 1 : l;
        if (h[m] <= x) break;
        h[i] = h[m];
        i = m;
    }
    h[i] = x;
}

static int cmp_f(const void *a, const void *b) {
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

int bench_truth_compute(bench_truth *t, const float *pts, size_t stride_floats, size_t n,
                        const float *q, size_t m, unsigned kmax) {
    t->m = m;
    t->kmax = kmax;
    t->count = calloc(m ? m : 1, sizeof *t->count);
    t->dist2 = malloc((m ? m : 1) * kmax * sizeof *t->dist2);
    if (!t->count || !t->dist2) return -1;
#pragma omp parallel for schedule(dynamic, 4)
    for (size_t qi = 0; qi < m; qi++) {
        float *h = &t->dist2[qi * kmax];
        const float *x = &q[3 * qi];
        unsigned c = 0;
        for (size_t i = 0; i < n; i++) {
            const float *p = &pts[i * stride_floats];
            float dx = x[0] - p[0], dy = x[1] - p[1], dz = x[2] - p[2];
            float d2 = dx * dx + dy * dy + dz * dz;
            if (c < kmax) {
                h[c++] = d2;
                if (c == kmax)
                    for (unsigned j = kmax / 2; j-- > 0;) heap_down(h, j, kmax);
            } else if (d2 < h[0]) {
                h[0] = d2;
                heap_down(h, 0, kmax);
            }
        }
        qsort(h, c, sizeof *h, cmp_f);
        t->count[qi] = c;
    }
    return 0;
}

void bench_truth_free(bench_truth *t) {
    free(t->count);
    free(t->dist2);
    memset(t, 0, sizeof *t);
}

unsigned bench_truth_size(const bench_truth *t, size_t qi, unsigned k, float r2) {
    const float *d = &t->dist2[qi * t->kmax];
    unsigned c = t->count[qi] < k ? t->count[qi] : k, s = 0;
    while (s < c && d[s] < r2) s++;
    return s;
}

int bench_score(const bench_truth *t, size_t qi, unsigned k, float r2, float *d2, unsigned got,
                uint64_t *hits, uint64_t *wanted) {
    const float *d = &t->dist2[qi * t->kmax];
    unsigned want = bench_truth_size(t, qi, k, r2), h = 0;
    int exact;
    qsort(d2, got, sizeof *d2, cmp_f);
    if (want > 0)
        for (unsigned i = 0; i < got; i++)
            if (d2[i] <= d[want - 1] && d2[i] < r2) h++;
    if (h > want) h = want;
    *hits += h;
    *wanted += want;
    exact = got == want;
    for (unsigned i = 0; exact && i < got; i++) exact = d2[i] == d[i];
    return exact;
}

/* ---- statistics, memory, output ---- */

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}
double bench_median(double *v, int n) {
    if (n <= 0) return NAN;
    qsort(v, (size_t)n, sizeof *v, cmp_d);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

size_t bench_heap_bytes(void) {
    struct mallinfo2 mi = mallinfo2();
    return mi.uordblks + mi.hblkhd;
}

FILE *bench_csv_open(const char *dir, const char *name, const char *header) {
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    if (!f) {
        perror(path);
        exit(2);
    }
    fprintf(f, "%s\n", header);
    return f;
}

void bench_log(const char *fmt, ...) {
    static double t0 = -1;
    va_list ap;
    if (t0 < 0) t0 = bench_now();
    fprintf(stderr, "[%7.1fs] ", bench_now() - t0);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
}

int bench_max_threads(void) {
#ifdef _OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
}

/* ---- command line ---- */

int bench_parse_double(const char *prog, const char *opt, const char *s, double lo, double hi,
                       double *out) {
    char *end = NULL;
    errno = 0;
    double v = s ? strtod(s, &end) : NAN;
    if (!s || end == s || *end || errno == ERANGE || !(v >= lo && v <= hi)) {
        fprintf(stderr, "%s: %s: expected a number in [%g, %g], got '%s'\n", prog, opt, lo, hi,
                s ? s : "");
        return -1;
    }
    *out = v;
    return 0;
}

int bench_parse_count(const char *prog, const char *opt, const char *s, double lo, double hi,
                      size_t *out) {
    char *end = NULL;
    errno = 0;
    double v = s ? strtod(s, &end) : NAN;
    if (!s || end == s || *end || errno == ERANGE || !(v >= lo && v <= hi) || v != floor(v)) {
        fprintf(stderr, "%s: %s: expected a whole number in [%.0f, %.0f], got '%s'\n", prog, opt,
                lo, hi, s ? s : "");
        return -1;
    }
    *out = (size_t)v;
    return 0;
}

int bench_parse_int(const char *prog, const char *opt, const char *s, long lo, long hi, int *out) {
    char *end = NULL;
    errno = 0;
    long v = s ? strtol(s, &end, 10) : 0;
    if (!s || end == s || *end || errno == ERANGE || v < lo || v > hi) {
        fprintf(stderr, "%s: %s: expected a whole number in [%ld, %ld], got '%s'\n", prog, opt, lo,
                hi, s ? s : "");
        return -1;
    }
    *out = (int)v;
    return 0;
}

int bench_parse_u64(const char *prog, const char *opt, const char *s, uint64_t *out) {
    char *end = NULL;
    errno = 0;
    unsigned long long v = s && *s != '-' ? strtoull(s, &end, 10) : 0;
    if (!s || *s == '-' || end == s || *end || errno == ERANGE) {
        fprintf(stderr, "%s: %s: expected a whole number >= 0, got '%s'\n", prog, opt, s ? s : "");
        return -1;
    }
    *out = (uint64_t)v;
    return 0;
}
