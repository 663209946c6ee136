/* pbrt.h: converting a pbrt-v3 scene file (pbrt.org, "pbrt-v3 File Format") into this
 * renderer's own scene document, as tungsten.h does for Tungsten scenes.
 *
 * The subset (data/scenes/README.md, "pbrt-v3 scenes", has the table):
 *   - LookAt, Camera "perspective" (fov: of the shorter image side, as pbrt's), Film
 *     (xresolution, yresolution), Sampler (pixelsamples, or xsamples x ysamples for
 *     "stratified"), Integrator (maxdepth; "path" renders with path, "sppm" with pm, any other
 *     with path and a warning);
 *   - the transform stack: Identity, Translate, Scale, Rotate, Transform, ConcatTransform,
 *     CoordinateSystem, CoordSysTransform, TransformBegin/End, AttributeBegin/End,
 *     ReverseOrientation;
 *   - Shape "trianglemesh" (P, indices, N: smooth shading, each triangle wound to face its
 *     normals as pbrt's FaceForward does), "plymesh" (a PLY file
 *     through our reader, ply.h; smooth where the file has normals) and "sphere" (full spheres);
 *   - Material and MakeNamedMaterial/NamedMaterial: matte (Kd, sigma: lambert or oren_nayar),
 *     mirror (Kr), glass (eta or index: dielectric), plastic, substrate and uber (Kd under a
 *     smooth Fresnel coat tinted by Ks: a mix; the roughness is lost, a warning says so);
 *   - AreaLightSource "diffuse" (L, scale, twosided): an own emissive material per light;
 *     LightSource "point" (I, from, scale) and "distant" (L, from, to, scale); "spot",
 *     "infinite" and the rest are skipped with a warning (we have no such lights);
 *   - Include (and pbrt-v4's Import) relative to the including file, WorldBegin/End,
 *     ObjectBegin/End/ObjectInstance (an instance is a copy of the object's shapes under the
 *     instance's transform).
 *   - MakeNamedMedium "homogeneous" (sigma_a, sigma_s, scale, g) and MediumInterface as
 *     interfaces (scene/medium.h): the outside medium at Camera is our global "medium"; a shape
 *     whose interface has two different media gets them as interior_medium (inside) and
 *     exterior_medium (outside), whatever its material, as pbrt-v3 does; with media in the
 *     scene, a shape without such an interface keeps the ray's medium ("keeps_medium"). Our
 *     loader checks that the surfaces around each medium close it together.
 * Anything else is warned about with its file and line and skipped: unknown directives (with
 * their parameters), unknown parameters, textures (the material's default value is used),
 * other shapes and materials (matte grey 0.5).
 *
 * Handedness: pbrt's image right is up x forward, ours forward x up (data/scenes/README.md): a
 * pbrt camera built by LookAt alone sees the mirror image of what ours would. The converter
 * keeps pbrt's picture: when the camera's frame is mirrored against ours it mirrors the whole
 * scene (x -> -x: points, transforms, lights, the camera), so the image is pbrt's. Orientation
 * follows pbrt (a triangle's normal is (v1-v0) x (v2-v0), flipped by ReverseOrientation and by
 * a transform that swaps handedness): each triangle is wound, and each PLY mesh given
 * "flip", so that our front is pbrt's normal (emitters emit on that side; glass is entered
 * through it).
 *
 * Errors: a negative PM_E* code, and a message in json_err that starts with the file and line
 * ("cornell.pbrt:12: ..."): unbalanced brackets or an unterminated string, a directive's
 * missing arguments, a parameter of the wrong type or size, an unknown named material or
 * object, a missing Include or PLY file, AttributeEnd without AttributeBegin, a non-finite or
 * singular transform, a vertex index out of range, a non-finite point. Warnings go to stderr as
 * "render: FILE:LINE: warning: ...". The caller owns *out.
 */
#ifndef RENDER_PBRT_H
#define RENDER_PBRT_H

#include <cjson/cJSON.h>

#include "base/json.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Is path a pbrt scene (its name ends in ".pbrt", any case)? */
int pbrt_is_file(const char *path);

/* Convert the pbrt-v3 file at path into our scene document (*out, the caller's). */
int pbrt_convert_file(const char *path, cJSON **out, json_err *e);

/* The same for a text (name is used in messages; Include and plymesh paths are relative to the
 * current directory). */
int pbrt_convert_text(const char *text, const char *name, cJSON **out, json_err *e);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PBRT_H */
