/* medium.h: homogeneous participating media: transmittance, the Henyey–Greenstein phase
 * function, free-flight sampling, and the scene queries that carry a ray through media and
 * invisible interfaces.
 *
 * A medium has RGB absorption and scattering coefficients sigma_a, sigma_s (per unit length;
 * sigma_t = sigma_a + sigma_s) and an HG asymmetry g in (-1, 1) (0 = isotropic, > 0 forward).
 * Transmittance over a distance d is Tr = exp(-sigma_t d) per channel.
 *
 * Where media are (scene.h; format in data/scenes/README.md): an object with an
 * "interior_medium" fills its inside, a closed surface whose geometric normals point out;
 * the global "medium" fills the space between objects. Sides follow the same rule as
 * medium_ior: the front side (dot(d, ng) > 0 for a direction d leaving the surface) of any
 * object is the global medium, its back side is the object's interior medium (none if it has
 * none). So media do not nest deeper than one level, like indices of refraction. A surface
 * with the "null" material is an invisible boundary: rays and shadow rays pass straight
 * through it and only the medium changes.
 *
 * Phase function, in terms of propagation directions: light travelling along a scatters into
 * b with density p(cos) where cos = dot(a, b), p(cos) = (1 - g^2) / (4 pi (1 + g^2 - 2 g cos)^1.5),
 * normalized over the sphere of b. A camera path going along d that turns into d' therefore
 * uses cos = dot(d, d') too (both directions reversed).
 *
 * Free flight with RGB coefficients: a channel is chosen uniformly and a distance drawn from
 * its exponential; the pdf is the mean over the three channels (one-sample MIS), so the
 * weights stay bounded when the channels differ. All functions are pure and thread-safe.
 */
#ifndef RENDER_MEDIUM_H
#define RENDER_MEDIUM_H

#include "base/vec.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct medium {
    char name[64];
    rgb sigma_a, sigma_s, sigma_t; /* per unit length; sigma_t = sigma_a + sigma_s */
    double g;                      /* Henyey–Greenstein asymmetry, in (-1, 1) */
} medium;

/* exp(-sigma_t d) per channel; d may be INFINITY (0 where sigma_t > 0, else 1). */
rgb medium_tr(const medium *m, double d);

/* The HG phase function p(cos) for cos = dot(a, b) of two propagation directions. */
double hg_phase(double g, double cos_theta);

/* Sample a new propagation direction b for light (or a camera path) going along unit a, with
 * density hg_phase(g, dot(a, b)); returns that density. */
double hg_sample(double g, vec3 a, double u1, double u2, vec3 *b);

/* Free-flight sampling along a ray in medium m up to a surface at distance tmax (may be
 * INFINITY). Uses uc to choose the channel and u for the distance. Returns 1 for a scattering
 * event at *t < tmax with *weight = Tr(t) sigma_s / pdf(t), or 0 when the ray reaches the
 * surface, with *weight = Tr(tmax) / P(reach); both are per channel and unbiased. */
int medium_sample_distance(const medium *m, double tmax, double uc, double u, double *t, rgb *weight);

/* Equiangular sampling (Kulla and Fajardo, "Importance sampling techniques for path tracing in
 * participating media", 2012): a distance t in [t0, t1] (t1 may be INFINITY; t0 < t1) along
 * the line o + t d (d a unit vector) with density proportional to 1 / |o + t d - y|^2, the
 * inverse-square fall-off of light arriving from the point y. With delta = dot(y - o, d) (the
 * closest approach) and D the distance from y to the line, the angle theta = atan((t - delta) /
 * D) is uniform in [theta0, theta1], so
 *     t = delta + D tan(theta0 + u (theta1 - theta0)),
 *     pdf(t) = D / ((theta1 - theta0) (D^2 + (t - delta)^2)).
 * D is at least 1e-9 |y - o| (a point on the line keeps a finite density). medium_equiangular_sample
 * returns the pdf of the *t it draws (0 if the interval is empty); medium_equiangular_pdf the
 * density of any t (0 outside [t0, t1]). Both pure. */
double medium_equiangular_sample(vec3 o, vec3 d, double t0, double t1, vec3 y, double u, double *t);
double medium_equiangular_pdf(vec3 o, vec3 d, double t0, double t1, vec3 y, double t);

struct scene;
struct hit;

/* Does the scene have any medium or null (interface) surface? When not, the integrators run
 * exactly their medium-free code (same random numbers, same images). */
int scene_has_media(const struct scene *s);

/* The medium index (into scene.media, -1 = none) on the side of hit h that direction d
 * points to (the rule above). */
int scene_medium_after(const struct scene *s, const struct hit *h, vec3 d);

/* Transmittance of the segment from p (normal np, zero if not on a surface) to q (normal nq),
 * starting in medium med: it passes through null surfaces (changing medium at each) and is 0
 * at any other surface. Tr of each medium part per channel. */
rgb scene_transmittance(const struct scene *s, vec3 p, vec3 np, vec3 q, vec3 nq, int med);
/* The same for a ray toward infinity in direction d (directional lights). */
rgb scene_transmittance_dir(const struct scene *s, vec3 p, vec3 np, vec3 d, int med);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_MEDIUM_H */
