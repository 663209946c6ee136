/* envmap.h: the image of an infinite light (light.h), an environment map in latitude-longitude
 * form, and sampling directions from it in proportion to its luminance.
 *
 * Layout: w x h pixels of linear RGB, row 0 at the top. A direction m in the map's frame (z up,
 * as pbrt-v3's infinite light) has theta = acos(m.z) and phi = atan2(m.y, m.x) in [0, 2 pi); its
 * pixel is column floor(w phi / 2 pi), row floor(h theta / pi). A world direction d is taken to
 * the map's frame by the rotation `frame` (m = frame d). The radiance is constant over a pixel.
 *
 * Sampling: a pixel with probability lum(L_j) Omega_j / Sigma (Omega_j its solid angle, (2 pi
 * / w) (cos theta_top - cos theta_bottom); Sigma the sum over pixels of lum(L_j) Omega_j), then
 * a direction uniform in solid angle inside it (phi uniform, cos theta uniform in the row's
 * band): density lum(L_j) / Sigma per steradian, so L / pdf = (L_j / lum(L_j)) Sigma. Two numbers:
 * u1 picks the row by the rows' marginal and, rescaled, cos theta inside it; u2 the column by the
 * row's conditional and, rescaled, phi. envmap_invert undoes it.
 *
 * Ownership: envmap_init takes the pixels (malloc'd); envmap_free frees them. Read-only after
 * init: every query is thread-safe.
 */
#ifndef RENDER_ENVMAP_H
#define RENDER_ENVMAP_H

#include "base/sampling.h"
#include "base/vec.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct envmap {
    int w, h;
    float *px;          /* 3 w h floats, row 0 at the top */
    double frame[3][3]; /* world direction to the map's frame (a rotation) */
    distrib1d rows;     /* over the h rows: their sums of lum Omega */
    distrib1d *cols;    /* per row, over its w pixels (rows of zero sum: n = 0) */
    rgb integral;       /* the sum over pixels of L_j Omega_j: the irradiance integral int L dw */
    double sigma;       /* the sum over pixels of lum(L_j) Omega_j */
} envmap;

/* Take px (3 w h floats, finite, >= 0) and build the sampling tables: 0, or PM_EINVAL (no
 * light at all) / PM_ENOMEM; on failure px is freed too. */
int envmap_init(envmap *m, int w, int h, float *px, const double frame[3][3]);
void envmap_free(envmap *m);

/* The radiance seen along the world direction d (unit). */
rgb envmap_eval(const envmap *m, vec3 d);
/* A world direction from (u1, u2) and its density per steradian (0: none). */
vec3 envmap_sample(const envmap *m, double u1, double u2, double *pdf);
/* The (u1, u2) that envmap_sample maps to d; 0 if d's pixel is never sampled. */
int envmap_invert(const envmap *m, vec3 d, double *u1, double *u2);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_ENVMAP_H */
