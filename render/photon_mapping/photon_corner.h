/* photon_corner.h: which photons a precomputed irradiance estimate keeps, where another
 * surface meets the estimate's own (a corner), or sits beside it at a small angle.
 *
 * A precomputed estimate (photon_sides.h, side_cache_build) searches a ball around its photon
 * x, so near a concave edge it also meets photons on the other surface that travelled toward
 * x's side (down and toward a wall), and a disc estimate counted their power over x's disc.
 * Two rules keep an estimate to x's own surface:
 *
 *   the normal rule  (A CORNER in photon_sides.h) a photon counts only if its normal is within
 *                    about 45 degrees of x's (side_filter_shadow). It cannot tell a surface at
 *                    less than 45 degrees: door_ajar's door, opened 15 degrees, stands in front
 *                    of the wall it hangs in, its lit face facing the way the wall's does, and
 *                    its photons counted on the wall beside the doorway. A tighter angle is no
 *                    cure: the photons' normals are quantised (one byte, up to about 10
 *                    degrees off), so on a curved surface a 10-degree rule refuses the
 *                    surface's own photons.
 *   the plane rule   on a flat surface, a photon counts only if it lies in x's plane: within
 *                    SIDE_PLANE_SLAB (1e-3) of the estimate's radius of it (the radius of the
 *                    k nearest by the normal rule; the plane from x's exact geometric normal,
 *                    one short ray back to the surface, not the quantised one). Why it holds:
 *                    every photon of a flat surface lies on its plane, to the rounding of its
 *                    float position; a photon off it lies on another surface. Why flat only:
 *                    x is on a flat surface when the primitive under it is a triangle whose
 *                    shading normal is its geometric one; on a curved one (a sphere, a smooth
 *                    mesh) the surface's own photons lie off the tangent plane, by L^2/(2R)
 *                    at a chord L on a sphere of radius R, and the disc estimate is exact
 *                    there (the photons within a chord r cover a cap of area pi r^2), so the
 *                    rule leaves curved surfaces alone (tests/test_render_sides_corner.c: a
 *                    sphere reads +0.02% with radii a fifth of R). Why 1e-3 and not a looser
 *                    slab (tried 0.05 to 0.2 of the radius, measured on door_ajar): a slab
 *                    keeps the other surface's photons in a strip along the edge where the
 *                    two meet, the very strip the disc fraction cuts away, so they count at
 *                    their density over an area that leaves them out: with 0.05 the wall by
 *                    a door at 30 degrees read +47%. The second search runs within four times
 *                    the first radius, and stands only if it finds k photons there (else the
 *                    first search's photons stand: a surface too small to hold k photons
 *                    near x is read as before, not over a disc it does not fill).
 *                    LIMIT: a curved object meshed in flat triangles without normals is flat
 *                    to this rule; a neighbouring facet's photons count as another surface's
 *                    (at a convex edge the disc fraction does not see the cut, so the estimate
 *                    reads low there by the share of that facet's photons).
 *   lookups          side_cache_lookup's twin of the rule (photon_sides.c, side_accepts): a
 *                    precomputed value on a flat surface answers y only if it lies in y's
 *                    plane (within SIDE_PLANE_SLAB of its distance); one on a curved surface
 *                    within a tenth of its distance (a sphere of radius 5 or more times the
 *                    distance). Without it, y on the wall by the hinge took the door's value.
 *
 * When either rule refused a photon inside the disc of the photons kept, the estimate met a
 * corner: it divides by the part of its disc on x's side of every surface (side_disc_fraction),
 * as after a wall. An estimate that neither rule touches is the k nearest that travelled
 * toward x's side, bit for bit as before the rules.
 *
 * Threads: reentrant; the search's scratch is the caller's.
 */
#ifndef RENDER_PHOTON_CORNER_H
#define RENDER_PHOTON_CORNER_H

#include "photonmap/kdtree.h"
#include "photonmap/photon.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Candidates examined by a precomputed estimate that meets a wall, as a multiple of its k. */
#define SIDE_WIDEN 4
/* What side_precomp_neighbours met (its *wall, bits; 0: neither): a hidden neighbour, or a
 * neighbour on another surface (a corner: the normal or the plane rule refused it). Either
 * cuts the disc. */
#define SIDE_WALL 1
#define SIDE_CORNER 2
/* The plane rule's slab: the height off x's tangent plane, as a fraction of the radius of the
 * k nearest by the normal rule, that a photon may lie at and count (on a flat surface). */
#define SIDE_PLANE_SLAB 1e-3

/* The exact geometric normal of the surface under the point p (p's quantised normal n, within
 * a few ray offsets of it), turned to n's side: one short ray back along -n; n itself if the
 * ray finds nothing. The surface point found goes to *at (p when none), and *flat is 1 when
 * that surface is flat (a triangle whose shading normal is its geometric one), else 0. */
vec3 side_surface_normal(const scene *s, vec3 p, vec3 n, vec3 *at, int *flat);

/* The neighbours of a precomputed estimate at the photon x (decoded normal n, free height hx)
 * from the tree t (records ph, free heights hfree; t NULL: none), side_cache_build's rule,
 * shared with its distributed twin (render/mpi/lk_irradiance.c, each rank's part): the k
 * nearest photons on x's own surface (the normal rule, and the plane rule above: travelled
 * toward n's side, normal within 45 degrees, on a flat surface within SIDE_PLANE_SLAB of the
 * radius of x's plane) within radius^2 max_dist2, sorted, and a corner if either rule refused a
 * photon inside their disc; if one of them (at a distance > 0) is not side_visible_h from x,
 * a wall: then the SIDE_WIDEN x k nearest (by the same rules), keeping the visible ones,
 * nearest first, until k are kept. Returns how many were kept, in nb[0..) (room for
 * SIDE_WIDEN x k); *wall: SIDE_CORNER | SIDE_WALL as met (0: neither; either cuts the disc,
 * and the caller divides by side_disc_fraction); *reach2 the radius^2 of the disc examined
 * when fewer than k were kept after a wall (up to the last candidate when all SIDE_WIDEN x k
 * were examined), else max_dist2. rays (or NULL) gains the visibility rays traced: [0] the
 * first search's, [1] the widened search's (segments that side_clear clears need none and
 * count in neither; the plane rule's normal ray counts in neither either). */
int side_precomp_neighbours(const scene *s, const pm_kdtree *t, const pm_photon *ph, const float *hfree,
                            const float x[3], const float n[3], double hx, unsigned k, float max_dist2,
                            pm_neighbor *nb, int *wall, float *reach2, unsigned long long rays[2]);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PHOTON_CORNER_H */
