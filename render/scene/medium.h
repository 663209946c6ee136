/* medium.h: homogeneous participating media: transmittance, the Henyey–Greenstein phase
 * function, free-flight sampling, and the scene queries that carry a ray through media and
 * invisible interfaces.
 *
 * A medium has RGB absorption and scattering coefficients sigma_a, sigma_s (per unit length;
 * sigma_t = sigma_a + sigma_s) and an HG asymmetry g in (-1, 1) (0 = isotropic, > 0 forward).
 * Transmittance over a distance d is Tr = exp(-sigma_t d) per channel.
 *
 * Where media are (scene.h; format in data/scenes/README.md): media by interfaces. Each object
 * is one of three kinds (scene.obj_iface):
 *   - MEDIUM_IFACE_LEGACY (an object that names no medium): its front side (dot(d, ng) > 0 for
 *     a direction d leaving the surface) is the global medium, its back side none. A ray
 *     leaving it takes the medium of the side it leaves by, as before interfaces existed.
 *   - MEDIUM_IFACE_DECLARED ("interior_medium" and/or "exterior_medium"): its back side is
 *     the interior medium (default none), its front side the exterior medium (default the
 *     global one). A ray leaving it takes the medium of the side it leaves by; a ray that
 *     reaches it from a side whose medium is not the one the ray carries is an inconsistent
 *     interface, reported once per scene on stderr with the point and the object.
 *   - MEDIUM_IFACE_KEEP ("keeps_medium": true; Tungsten's and pbrt's surfaces that name no
 *     medium): no interface; a ray keeps the medium it carries, reflected or transmitted.
 * The surfaces that bound a medium together (any mix of objects) must close it; the loader
 * checks that over all of them (scene_media.c). A surface with the "null" material is an
 * invisible boundary: rays and shadow rays pass straight through it and only the medium
 * changes.
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

/* scene.obj_iface values (the rule above). */
enum { MEDIUM_IFACE_LEGACY = 0, MEDIUM_IFACE_DECLARED = 1, MEDIUM_IFACE_KEEP = 2 };

/* The medium (index into scene.media, -1 = none) of a ray that reached hit h going along din
 * while in medium cur, and leaves it along dout (dout = din: passing a null surface). Reports
 * an inconsistent interface (above) once per scene. Thread-safe. */
int scene_medium_next(const struct scene *s, const struct hit *h, vec3 din, vec3 dout, int cur);
/* The same without the consistency check (shadow rays, estimates). */
int scene_medium_side(const struct scene *s, const struct hit *h, vec3 dout, int cur);
/* The medium on the side of object obj that its normal points to (front 1) or away from
 * (front 0); -2 for a MEDIUM_IFACE_KEEP object. */
int scene_object_side_medium(const struct scene *s, int obj, int front);

/* The medium at r.o as the surfaces ahead say: the side facing r.o of the first surface along r
 * with an interface (surfaces that keep the medium are passed); the global medium if none. */
int scene_medium_ahead(const struct scene *s, ray r);
/* The index of refraction at r.o as the dielectrics ahead say (RADIANCE INSIDE GLASS in
 * photon_mapping/pm_volume.h): the first surface along r whose material refracts (transparency
 * > 0, not null) gives its ior when r leaves through its back side, else medium_ior (the index
 * between objects); medium_ior when r meets none. Opaque and null surfaces are passed: they
 * bound no region of another index. */
double scene_index_ahead(const struct scene *s, ray r);
/* The medium a photon of light li leaves in from point p (normal nl, zero for a point) along
 * d: the emitting object's side if it declares an interface, else first_hit (the medium of
 * the first surface's side facing the photon, -2 when that surface keeps the medium), else
 * scene_medium_ahead. */
int scene_light_medium(const struct scene *s, int li, vec3 p, vec3 nl, vec3 d, int first_hit);

/* Transmittance of the segment from p (normal np, zero if not on a surface) to q (normal nq),
 * starting in medium med: it passes through null surfaces (changing medium at each by
 * scene_medium_next) and is 0
 * at any other surface. Tr of each medium part per channel. */
rgb scene_transmittance(const struct scene *s, vec3 p, vec3 np, vec3 q, vec3 nq, int med);
/* The same for a ray toward infinity in direction d (directional lights). */
rgb scene_transmittance_dir(const struct scene *s, vec3 p, vec3 np, vec3 d, int med);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_MEDIUM_H */
