/* sampling.h: warping uniform random numbers into the distributions the renderer samples.
 *
 * Each function maps a point u in [0,1)^2 to a direction or a point and, where a pdf is
 * needed, names its measure: pdfs over directions are per steradian, pdfs over surfaces per
 * unit area. Directions from the hemisphere functions are in a local frame whose z axis is
 * the normal; sampling_to_world() takes them to world space. A discrete distribution
 * (distrib1d) picks an index in proportion to its weights, e.g. a light by its power.
 * sample_halton gives the stratified low-discrepancy points photon emission uses.
 *
 * Stateless, except distrib1d, which owns its arrays (distrib1d_free).
 */
#ifndef RENDER_SAMPLING_H
#define RENDER_SAMPLING_H

#include <stdint.h>

#include "base/vec.h"

#ifdef __cplusplus
extern "C" {
#endif

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* Cosine-weighted direction on the hemisphere around +z; pdf = cos(theta)/pi. */
vec3 sample_cosine_hemisphere(double u1, double u2);
/* Uniform direction on the hemisphere around +z; pdf = 1/(2 pi). */
vec3 sample_uniform_hemisphere(double u1, double u2);
/* Uniform direction on the unit sphere; pdf = 1/(4 pi). */
vec3 sample_uniform_sphere(double u1, double u2);
/* Uniform point in the unit disc (concentric mapping, keeps strata compact). */
void sample_concentric_disc(double u1, double u2, double *x, double *y);
/* Uniform barycentrics (b1, b2) on a triangle: p = v0 + b1 e1 + b2 e2; pdf = 1/area. */
void sample_triangle(double u1, double u2, double *b1, double *b2);
/* Take a local direction (z = normal) to world space around the unit normal n. */
vec3 sampling_to_world(vec3 local, vec3 n);

/* Dimension d (0 to 5: bases 2, 3, 5, 7, 11, 13) of the Halton point with index i + 1,
 * rotated (Cranley-Patterson) by shift[d] and wrapped into [0, 1). */
double sample_halton(uint64_t i, int d, const double *shift);

/* A discrete distribution over n weights (>= 0, finite, sum > 0). */
typedef struct distrib1d {
    int n;
    double *cdf;  /* n+1 entries, cdf[0] = 0, cdf[n] = 1 */
    double total; /* the sum of the weights */
} distrib1d;
int distrib1d_init(distrib1d *d, const double *w, int n); /* 0 or PM_EINVAL / PM_ENOMEM */
/* The index for u in [0,1) and its probability. */
int distrib1d_sample(const distrib1d *d, double u, double *prob);
double distrib1d_prob(const distrib1d *d, int i);
void distrib1d_free(distrib1d *d);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_SAMPLING_H */
