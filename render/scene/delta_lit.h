/* delta_lit.h: what a path-traced reference cannot show, named before it is rendered.
 *
 * The path tracer (pathtracer.c) lights a diffuse surface by next-event estimation: a
 * shadow ray to a point on a light. A point or directional light is a delta function: a path
 * can reach it only by such a shadow ray, never by a bounce. So light that leaves a point or
 * directional light, meets one or more specular surfaces (mirror, glass, a Fresnel coat)
 * and then a diffuse one (an L S+ D path: a caustic) has probability zero in the path
 * tracer: the image lacks it, and everything lit by it (its reflection in other surfaces,
 * the diffuse light it bounces on). Photon mapping renders these paths from the light's
 * side; a path-traced reference of such a scene is wrong in those regions.
 *
 * delta_lit_find() names them. A specular object (a material with a specular reflection or
 * transmission branch, the invisible "null" interface excepted) is DELTA-LIT when some point
 * of its surface is seen by a point or directional light of non-zero power: for a sphere,
 * 256 points spread over it by a Fibonacci lattice; for an object made of triangles, the
 * centroid and the three points halfway between the centroid and each corner of each
 * triangle, with at most 4096 points per object (large meshes: every n-th triangle). The
 * test is a shadow ray from each point to the light. This can miss an object lit through a
 * gap narrower than the spacing of its points (reported as not lit), never the reverse.
 * The FOOTPRINT is the set of diffuse objects such light reaches: from each lit point a ray
 * from the light is followed through the specular surfaces it meets (both the reflected and
 * the refracted ray at a dielectric, at most 8 specular bounces) to its first diffuse
 * surface. The footprint's objects receive the missing caustic; their pixels, and those
 * of the delta-lit objects, are the regions a comparison against a path-traced reference
 * must leave out (`render --compare --mask IDS.pfm --id N`: keep only the other objects).
 *
 * delta_lit_warn() prints the warning of `render --mode path` when anything is delta-lit:
 *   render: warning: SCENE: path tracing cannot render light that point or directional
 *   lights send through specular surfaces onto diffuse ones (L S+ D); lit straight by a
 *   point or directional light: $.objects[2] ("chrome"), ...; their caustics fall on
 *   $.objects[0] ("ground"), ...; those regions are missing or too dark here (use
 *   --mode pm for them)
 * When the footprint is empty (a light shut in a mirror box) the second half says that
 * within 8 specular bounces their light reaches no diffuse surface instead. Object indices
 * are those of $.objects (add 1 for the ids of `--mode objects`), names are the materials'.
 *
 * Reads the scene only; reentrant. Cost: at most (4096 + 256) shadow rays per specular
 * object and delta light, plus the footprint's rays (a few per lit point).
 */
#ifndef RENDER_DELTA_LIT_H
#define RENDER_DELTA_LIT_H

#include <stdio.h>

#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Per object of $.objects (s->nobj entries, allocated by delta_lit_find): */
enum { DELTA_NONE = 0, DELTA_LIT = 1, DELTA_FOOTPRINT = 2 };

/* *flags gets s->nobj entries, each DELTA_NONE or a combination of DELTA_LIT (a specular
 * object a delta light sees) and DELTA_FOOTPRINT (a diffuse object such light reaches after
 * specular bounces). Returns the number of DELTA_LIT objects (0: the reference is complete),
 * or PM_ENOMEM. The caller frees *flags. */
int delta_lit_find(const scene *s, unsigned char **flags);

/* The warning above on f (nothing when no object is delta-lit); scene_name goes first. */
void delta_lit_warn(const scene *s, const char *scene_name, FILE *f);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_DELTA_LIT_H */
