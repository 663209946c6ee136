/* side_visibility.h: the visibility rule of photon_sides.h ("side_visible" there: the segment
 * joins the two points lifted off their surfaces), the free heights it lifts by, the segments
 * cleared without a ray, and the shadow-photon filter. photon_sides.c and photon_corner.c
 * build on it; it knows neither.
 *
 * Threads: every function may run on any thread; side_free_heights runs its own OpenMP loop.
 */
#ifndef RENDER_SIDE_VISIBILITY_H
#define RENDER_SIDE_VISIBILITY_H

#include <stddef.h>
#include <stdint.h>

#include "photonmap/photon.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A lookup's normal rule (irradiance.h): the photon's normal within about 45 degrees of y's. */
#define SIDE_LOOKUP_COS 0.7f

/* 1 if the surface point q (normal nq) is on p's side of every surface between them; see above. */
int side_visible(const scene *s, vec3 p, vec3 np, vec3 q, vec3 nq);
/* The distance from p along np to the first surface, at most cap (one ray). */
double side_free_height(const scene *s, vec3 p, vec3 np, double cap);
/* The free heights of photons ph[0..n) along their decoded normals, capped at the largest lift
 * an estimate within radius^2 max_dist2 uses (a quarter of the radius), into h[0..n): one ray
 * each, on OpenMP threads. */
void side_free_heights(const scene *s, const pm_photon *ph, size_t n, float max_dist2, float *h);
/* Segments that side_visible_h would test, cleared without a ray (side_visibility.c, CLEAR
 * SEGMENTS WITHOUT A RAY): side_planes_near lists the planes of the triangles near x (those
 * whose boxes overlap the box of radius 1.3 sqrt(r2) around x; not ok when more than
 * SIDE_CLEAR_MAX or a sphere are there), and side_clear is 1 when both lifted ends of
 * side_visible_h(p, np, hp, q, nq, hq)'s segment lie on one side of each of those planes by
 * more than SIDE_CLEAR_MARGIN of the scene's scale, so the ray would meet nothing and
 * side_visible_h is 1; 0 when only the ray can tell. For p and q within sqrt(r2) of x. */
#define SIDE_CLEAR_MAX 16
#define SIDE_CLEAR_MARGIN 1e-7
typedef struct side_planes {
    int ok; /* 0: not listed (too many surfaces near, or a sphere): side_clear is always 0 */
    int n;
    vec3 nrm[SIDE_CLEAR_MAX];
    double d[SIDE_CLEAR_MAX], margin;
} side_planes;
void side_planes_near(const scene *s, vec3 x, double r2, side_planes *pl);
int side_clear(const side_planes *pl, vec3 p, vec3 np, double hp, vec3 q, vec3 nq, double hq);
/* The shadow-photon map's search filter (the photon mapper's shadow hint; user: the query's
 * unit normal, float[3]): pm_filter_front (the photon travelled toward the query's side),
 * and the photon's surface normal within about 45 degrees of the query's (cos >= 0.7, as
 * side_cache_lookup's normal rule). Why: the hint skips the shadow ray when all the nearest
 * shadow-map photons are DIRECT, and photons on another surface close by, through a single
 * quad, pass the direction test whenever they travel along the query's surface: on
 * pinhole_room's red wall just under the ceiling the 16 nearest were DIRECT photons on the
 * roof's top 2 to 15 units away, going down and toward the wall, so the inside of the wall
 * was taken as lit by the lamp (walls +18%, photon seed 3; +5.5% with this filter). A surface
 * that faces another way is another surface as far as its light is concerned; surfaces that
 * face the same way, one behind the other, are told apart by the shadow photons themselves
 * (every ray that lit the front one leaves one on the one behind). */
int side_filter_shadow(void *user, const void *record, uint32_t index);
/* side_visible with the free heights hp, hq of both ends known: one ray. */
int side_visible_h(const scene *s, vec3 p, vec3 np, double hp, vec3 q, vec3 nq, double hq);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_SIDE_VISIBILITY_H */
