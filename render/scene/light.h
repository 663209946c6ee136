/* light.h: area, point, spot, directional and infinite lights, and sampling them for next-event estimation.
 *
 * This header is the lights themselves and the spot's profile (light.c); sampling a scene's
 * lights reads its shapes, so light_sample_li, light_sample_le, light_env_radiance and
 * light_emit_weight are declared in scene.h (light_sample.c), which stands on this header.
 *
 * Area lights are the scene's triangles (and quads, as two triangles) whose material emits:
 * the loader makes one light per emissive triangle. They emit Le from the front side (or
 * both, two_sided) and are sampled by a uniform point on the triangle, whose area pdf 1/A is
 * turned into a solid-angle pdf with dist^2 / (cos_light A). Emissive spheres are sphere
 * lights, sampled the same way by a uniform point on the whole sphere (half of the samples
 * land on the far side and carry nothing when it emits outward only; from inside a two-sided
 * sphere, the furnace, every sample counts).
 * Point lights have an intensity I (W/sr); directional lights an irradiance E (W/m^2 on a
 * surface facing them) and a direction of travel.
 * Spot lights are point lights whose intensity falls off away from their axis dir: I f(cos),
 * with f = 1 inside the inner cone (cos >= cos_start), 0 outside the cone (cos < cos_total) and
 * between them a function of delta = (cos - cos_total) / (cos_start - cos_total): smoothstep
 * 3 delta^2 - 2 delta^3 (pbrt-v4's spotlight), or delta^4 (SPOT_QUARTIC, pbrt-v3's).
 * An infinite light is a radiance arriving from every direction at infinity (an environment,
 * pbrt's "infinite", Tungsten's "infinite_sphere"): constant Le, or an image (scene.env_map,
 * envmap.h) sampled by luminance; a ray that leaves the scene sees it (light_env_radiance).
 * At most one per scene (scene.env_light).
 *
 * Each light also carries its total power (W), which the path tracer uses to choose a light
 * in proportion to it and photon emission uses to share photons out:
 *   area and sphere: pi Le A (x2 if two-sided); point: 4 pi I; directional: E pi R^2, where R is the
 *   radius of the scene's bounding sphere (the disc photons are shot from); spot: 2 pi I W with
 *   W = the integral of f over cos in [-1, 1] = (1 - cos_start) + (cos_start - cos_total) k,
 *   k = 1/2 (smoothstep) or 1/5 (quartic); infinite: 4 pi Le pi R^2 (with an image, pi R^2 times
 *   the integral of L over directions: each direction's light crossing the disc of radius R).
 */
#ifndef RENDER_LIGHT_H
#define RENDER_LIGHT_H

#include "base/vec.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { LIGHT_AREA, LIGHT_POINT, LIGHT_DIRECTIONAL, LIGHT_SPHERE, LIGHT_SPOT, LIGHT_INFINITE };
enum { SPOT_SMOOTHSTEP, SPOT_QUARTIC }; /* light.falloff */

typedef struct light {
    int type;
    int tri;        /* area: index into scene.tris */
    int sphere;     /* sphere: index into scene.spheres */
    vec3 pos;       /* point: position */
    vec3 dir;       /* directional: unit direction in which the light travels; spot: its axis */
    rgb Le;         /* area, infinite: emitted radiance */
    rgb intensity;  /* point: radiant intensity, W/sr; spot: on its axis */
    rgb irradiance; /* directional: irradiance on a perpendicular surface, W/m^2 */
    int two_sided;  /* area: emits from both sides */
    rgb power;      /* total emitted power, W (see above) */
    double cos_total, cos_start; /* spot: cosines of the cone's half-angle and of its inner cone */
    int falloff;                 /* spot: SPOT_SMOOTHSTEP or SPOT_QUARTIC */
} light;

/* A light sample seen from a shading point p. */
typedef struct light_sample {
    vec3 wi;     /* unit direction from p toward the light */
    double dist; /* distance to the sampled point; INFINITY for a directional light */
    vec3 p, n;   /* sampled point and its unit normal (area lights); p for point lights */
    rgb L;       /* incident radiance divided by the solid-angle pdf of this sample
                    (area: Le cos_l A / dist^2; point: I / dist^2; spot: I f / dist^2;
                    directional: E; infinite: 4 pi Le, a uniform direction on the sphere,
                    or with an image L / pdf of envmap_sample's direction);
                    zero when the light faces away. Divide by the light's choice probability. */
} light_sample;

/* The spot's falloff f for a unit direction d leaving it (0 outside the cone), and the
 * density per steradian of light_sample_le's direction d (f / (2 pi W)). */
double light_spot_falloff(const light *l, vec3 d);
double light_spot_pdf(const light *l, vec3 d);
/* W of the top of this file: the integral of f over cos in [-1, 1]. */
double light_spot_w(const light *l);
/* The (u[0], u[1]) that light_sample_le maps to the direction d of spot l; 0 if l sends no
 * light along d. */
int light_spot_invert(const light *l, vec3 d, double *u0, double *u1);
/* The direction light_sample_le gives spot l for (u0, u1): u0 the cos by the inverse of its
 * distribution, u1 the angle about dir. */
vec3 light_spot_dir(const light *l, double u0, double u1);

/* The light is at infinity (directional, infinite): its shadow rays never end at a point. */
static inline int light_at_infinity(const light *l) {
    return l->type == LIGHT_DIRECTIONAL || l->type == LIGHT_INFINITE;
}
/* The light is a point in space (point, spot): no area, no normal. */
static inline int light_is_point(const light *l) { return l->type == LIGHT_POINT || l->type == LIGHT_SPOT; }

#ifdef __cplusplus
}
#endif
#endif /* RENDER_LIGHT_H */
