/* sampling.c: hemisphere, sphere, disc and triangle warps, and a discrete distribution.
 *
 * The cosine hemisphere uses Malley's method (a concentric disc point lifted to the
 * hemisphere), which keeps stratified inputs stratified. The triangle warp is the square-root
 * parametrization. distrib1d keeps a normalized cumulative table and binary-searches it.
 * Halton points are radical inverses in the first six prime bases.
 */
#include "base/sampling.h"

#include <stdlib.h>

#include "photonmap/common.h"

void sample_concentric_disc(double u1, double u2, double *x, double *y) {
    double a = 2.0 * u1 - 1.0, b = 2.0 * u2 - 1.0, r, phi;
    if (a == 0 && b == 0) {
        *x = *y = 0;
        return;
    }
    if (fabs(a) > fabs(b)) {
        r = a;
        phi = (M_PI / 4) * (b / a);
    } else {
        r = b;
        phi = (M_PI / 2) - (M_PI / 4) * (a / b);
    }
    *x = r * cos(phi);
    *y = r * sin(phi);
}

vec3 sample_cosine_hemisphere(double u1, double u2) {
    double x, y;
    sample_concentric_disc(u1, u2, &x, &y);
    return v3(x, y, sqrt(fmax(0.0, 1.0 - x * x - y * y)));
}

vec3 sample_uniform_hemisphere(double u1, double u2) {
    double z = u1, r = sqrt(fmax(0.0, 1.0 - z * z)), phi = 2 * M_PI * u2;
    return v3(r * cos(phi), r * sin(phi), z);
}

vec3 sample_uniform_sphere(double u1, double u2) {
    double z = 1.0 - 2.0 * u1, r = sqrt(fmax(0.0, 1.0 - z * z)), phi = 2 * M_PI * u2;
    return v3(r * cos(phi), r * sin(phi), z);
}

void sample_triangle(double u1, double u2, double *b1, double *b2) {
    double s = sqrt(u1);
    *b1 = 1.0 - s;
    *b2 = u2 * s;
}

vec3 sampling_to_world(vec3 l, vec3 n) {
    vec3 s, t;
    v3_basis(n, &s, &t);
    return v3_add(v3_add(v3_scale(s, l.x), v3_scale(t, l.y)), v3_scale(n, l.z));
}

int distrib1d_init(distrib1d *d, const double *w, int n) {
    d->n = 0;
    d->cdf = NULL;
    d->total = 0;
    if (n <= 0) return PM_EINVAL;
    double total = 0;
    for (int i = 0; i < n; i++) {
        if (!(w[i] >= 0) || !isfinite(w[i])) return PM_EINVAL;
        total += w[i];
    }
    if (!(total > 0)) return PM_EINVAL;
    d->cdf = malloc((size_t)(n + 1) * sizeof *d->cdf);
    if (!d->cdf) return PM_ENOMEM;
    d->cdf[0] = 0;
    double acc = 0;
    for (int i = 0; i < n; i++) {
        acc += w[i];
        d->cdf[i + 1] = acc / total;
    }
    d->cdf[n] = 1.0;
    d->n = n;
    d->total = total;
    return 0;
}

int distrib1d_sample(const distrib1d *d, double u, double *prob) {
    int lo = 0, hi = d->n - 1;
    /* The first i with cdf[i+1] > u; zero-weight entries are never chosen. */
    while (lo < hi) {
        int mid = (lo + hi) / 2;
        if (d->cdf[mid + 1] > u)
            hi = mid;
        else
            lo = mid + 1;
    }
    if (prob) *prob = d->cdf[lo + 1] - d->cdf[lo];
    return lo;
}

double distrib1d_prob(const distrib1d *d, int i) {
    return (i >= 0 && i < d->n) ? d->cdf[i + 1] - d->cdf[i] : 0.0;
}

void distrib1d_free(distrib1d *d) {
    free(d->cdf);
    d->cdf = NULL;
    d->n = 0;
}

static double radical_inverse(uint64_t i, unsigned base) {
    double inv = 1.0 / base, f = inv, r = 0;
    while (i) {
        r += (double)(i % base) * f;
        i /= base;
        f *= inv;
    }
    return r;
}

static const unsigned k_primes[6] = {2, 3, 5, 7, 11, 13};

/* Dimension d of Halton point i, rotated (Cranley-Patterson) by shift[d]. */
double sample_halton(uint64_t i, int d, const double *shift) {
    double v = radical_inverse(i + 1, k_primes[d]) + shift[d];
    v -= floor(v);
    return v < 1.0 ? v : 0x1.fffffffffffffp-1;
}
