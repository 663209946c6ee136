/* direct.h: next-event estimation, the direct light at a point from one light sample. The path
 * tracer (pathtracer.c) and the photon mapper (photonmapper.c) both compute direct light here,
 * so the two modes that are compared with each other sample lights the same way.
 *
 * How: one light chosen in proportion to its power (scene->light_distrib), one point on it
 * (light_sample_li), a shadow test; the estimate is f * Li * cos / (p_light * pdf_omega), the
 * area pdf already turned into a solid-angle one by light.c. Three random numbers per call,
 * always drawn (light choice, then the point's two), so a caller's stream advances the same way
 * whether or not a light is found: images do not depend on which samples found nothing.
 *
 * At a surface (direct_light_surface) the cosine is taken with the shading normal turned to wo's
 * side (material_shading_side); n, the geometric normal on wo's side, decides whether the light
 * is in front at all. Two things differ between the callers and are options:
 *   - bsdf: DIRECT_BSDF_DIFFUSE_LOBE weights the light by material_diffuse_f alone (shading
 *     normal, no branch weight): the path tracer calls it after it chose the diffuse branch,
 *     whose weight/probability ratio is 1. DIRECT_BSDF_FULL weights it by material_f (geometric
 *     normal, times the diffuse branch weight (1-R)(1-T)): the photon mapper adds direct light
 *     at every surface with a diffuse branch without choosing one;
 *   - the shadow test: media = 1 multiplies by the transmittance of the shadow segment through
 *     media and null surfaces (scene_transmittance, starting in the medium on the light's side
 *     of the surface), media = 0 is plain visibility. A hint (the photon mapper's shadow-photon
 *     map) may answer lit (1) or dark (0) before the ray is traced, or -1 to trace it; it is
 *     asked only with media = 0, and only for samples that would contribute.
 * Every traced shadow segment counts in STAT_SHADOW_RAYS.
 *
 * Guided light sampling (direct_light_surface_guided, the photon mapper only): with a guide
 * (guide.h) that holds a table for (h's cell, the side n, the chosen light), the point's two
 * numbers are warped by it (the stratum chosen with the first number, whose remainder and the
 * second number place the point in it: still three numbers per call) and the estimate is
 * divided by the warped pair's density d(u) as well as p_light: unbiased for any table
 * (guide.h). Such a sample never asks the hint (the hint answers for the point, not for the
 * part of the light the guide aims at). With gd NULL, or no table there, it is
 * direct_light_surface exactly: same numbers, same result (the path tracer passes no guide).
 *
 * THROUGH A PORT (direct_light_surface_guided with o->port; the photon mapper). Light through a
 * small opening (pinhole_room: a 10 x 10 hole shows a 33 x 33 part of a 200 x 200 lamp to the
 * floor under it, and the part moves with the point) is found by few light samples, and a
 * guide's table per receiver cell is the union over the cell's points. At a point x on the
 * port's dark side (the port's centre in front of x's surface and ahead of x along port_lit)
 * the call takes two samples: the light sample as above, and a ray from x through a uniform
 * point of the port (two more numbers: five in all there), traced to the first surface; where
 * that is an area or sphere light seen from its front, its light counts. They are combined by
 * Veach's balance heuristic with the counts b = DIRECT_PORT_SHARE and 1 - b: the sum
 * b F_port + (1 - b) F_light, each sample of direction w divided by
 * b p_port(w) + (1 - b) p_light(w), p_port = t^2 / (area cos) at the port crossing (0 off the
 * port), p_light the solid-angle density with which the (guided) light sampling draws that
 * point of that light (its choice, its table's density at the point's (u1, u2), 1 / area, turned
 * into solid angle). A point or directional light's sample (no density; no port ray finds it)
 * keeps its whole weight. Every direction the port sample can draw the light sample can draw
 * too, so the estimate is unbiased for any port: a wrong one costs its rays and no noise.
 * Measured on the hole scene of tests/test_render_guide.c: 4.5x lower standard error than the
 * guide alone, within 0.1% of the quadrature. On pinhole_room (96 x 96, 64 spp, seeds 1-3,
 * against data/reference/et96, with the gathers aimed at the port as well) the lit patch's
 * squared error went from 3.6e-8, 3.2e-8, 3.3e-8 to 1.4e-9, 5.6e-9, 7.7e-9 (the image's from
 * 5.1e-8 to 1.3e-8, 2.8e-8, 1.4e-8, the rest mostly the camera's own view of the lit big room
 * through the hole, four pixels) at about the same CPU time (2.4-3.4 s against 2.9-3.4 s). Elsewhere (b = 0), and with media, the same three
 * numbers and the same result as without a port.
 *
 * In a medium (direct_light_medium) the phase function replaces f * cos, and the shadow segment
 * always carries the transmittance.
 *
 * Thread-safety: reads the scene only; the hint is called on the caller's thread.
 */
#ifndef RENDER_DIRECT_H
#define RENDER_DIRECT_H

#include "base/rng.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum direct_bsdf {
    DIRECT_BSDF_DIFFUSE_LOBE, /* material_diffuse_f(m, shading normal, wo, wi) */
    DIRECT_BSDF_FULL          /* material_f(m, ng, scene ior, wo, wi): with the branch weight */
} direct_bsdf;

/* Shadow shortcut for light sample li seen from h (n: geometric normal on wo's side): 1 lit,
 * 0 dark, -1 trace the shadow ray. */
typedef int (*direct_shadow_hint)(void *user, const scene *s, int li, const hit *h, vec3 n);

struct port;
typedef struct direct_options {
    direct_bsdf bsdf;
    int media;                /* 1: shadow segments carry the media's transmittance */
    direct_shadow_hint hint;  /* NULL: always trace (ignored when media = 1) */
    void *hint_user;
    int med;                  /* with media: the medium the path is in at the surface (a surface
                               * that keeps the ray's medium, medium.h, needs it) */
    const struct port *port;  /* THROUGH A PORT (below): aim a share of the samples through it;
                               * NULL: none (ignored when media = 1) */
    vec3 port_lit;            /* unit: the side of the port its light comes from */
} direct_options;

/* Direct light leaving the surface at h toward wo (material m, n the geometric normal on wo's
 * side), from one light sample: 3 numbers from g. 0 when no light is found, the light is behind
 * the surface, f is 0 or the light is blocked. */
rgb direct_light_surface(const scene *s, const material *m, const hit *h, vec3 n, vec3 wo, rng *g,
                         const direct_options *o);

/* direct_light_surface with the light point guided by gd (NULL: none; see above). */
struct guide;
rgb direct_light_surface_guided(const scene *s, const material *m, const hit *h, vec3 n, vec3 wo, rng *g,
                                const direct_options *o, const struct guide *gd);

/* THROUGH A PORT: the port sample's count b at x (shading normal nsh): DIRECT_PORT_SHARE on the
 * port's dark side, else 0. */
#define DIRECT_PORT_SHARE 0.5
double direct_port_share(const direct_options *o, vec3 x, vec3 nsh);

/* Direct light scattered at p, inside medium med, into a path travelling along d: phase *
 * Li * Tr / p_light, from one light sample: 3 numbers from g. */
rgb direct_light_medium(const scene *s, vec3 p, vec3 d, int med, rng *g);

/* EQUIANGULAR SAMPLING ALONG A SEGMENT. The single scattering of a segment [0, t1] of a ray r in
 * a medium, the integral over t of Tr(t) sigma_s L_direct(r(t)), peaks as 1 / dist^2 where the
 * segment passes close to a light: a point or uniform sampling of t puts few samples there and
 * each carries a large value (fog just under a lamp). It is therefore estimated by two
 * strategies combined by the balance heuristic (multi-sample MIS, Veach 1997):
 *   - the caller's own samples of t (the march's stratified steps, the path tracer's free
 *     flight), with density dens(t) counting all of its samples (n / T for n stratified steps),
 *     each with one light sample (direct_light_medium_mis): weighted dens / (dens + m p_eq);
 *   - m equiangular samples (direct_light_equiangular): one light and one point y on it are
 *     drawn first, exactly as direct_light_medium draws them, then t by
 *     medium_equiangular_sample toward y, stratified in angle with one offset u for all (sample j
 *     at the fraction (j + u) / m of [theta0, theta1], as the march's steps are spaced); each
 *     is weighted m p_eq / (m p_eq + dens) and divided by m p_eq (sample j alone has density
 *     m p_eq on its m-th of the angle, and its light point is its own).
 * The point drawn on a light depends only on its two numbers, not on the point it is seen from
 * (light.h: uniform on the triangle or the sphere), so both strategies have the same density
 * over the light and the weights compare only the densities of t; they sum to 1 for every (t,
 * y), so the sum is unbiased for any m >= 0 (m = 0: the caller's strategy alone, weight 1).
 * Directional lights have no point to aim at: the equiangular samples that choose one add
 * nothing, and the caller's samples of them keep weight 1. */
typedef struct direct_segment {
    ray r;     /* origin and unit direction */
    double t1; /* the segment is [0, t1] of r; t1 may be INFINITY (then Tr bounds it) */
    int med;   /* the medium it runs in (>= 0) */
    int m;     /* equiangular samples of the segment (>= 0) */
} direct_segment;

/* The density of the caller's samples at t (all of them counted). */
typedef double (*direct_density)(const void *user, double t);

/* direct_light_medium at r(t) of seg, times dens / (dens + m p_eq(t | y)) for the light point y
 * it drew: 3 numbers from g. */
rgb direct_light_medium_mis(const scene *s, const direct_segment *seg, double t, double dens, rng *g);

/* The m equiangular samples of seg: the sum over them of w Tr(t) sigma_s phase Li Tr_shadow /
 * (p_light m p_eq(t)), w = m p_eq / (m p_eq + dens(t)): 3 numbers from g per sample (light,
 * point), plus 1 (the angle's offset) if m > 0, always drawn. Not multiplied by any throughput. */
rgb direct_light_equiangular(const scene *s, const direct_segment *seg, direct_density dens, const void *user, rng *g);

#ifdef __cplusplus
}
#endif

#endif
