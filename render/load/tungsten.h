/* tungsten.h: converting a scene file of the Tungsten renderer (github tunabrain/tungsten) into
 * this renderer's own scene document (data/scenes/README.md has the supported subset).
 *
 * A Tungsten scene lists "bsdfs" and "primitives" where ours has "materials" and "objects".
 * tungsten_convert() builds a new cJSON document in our format from it: quads become our
 * quads, cubes 12-triangle meshes, spheres spheres, meshes {"type": "mesh", "file": ...} with
 * the primitive's transform as a 4x4 matrix, each emissive primitive gets its own material
 * (the bsdf plus the emission; "power" P becomes the radiance P / (pi area)), and the camera,
 * integrator.max_bounces and renderer.spp become "camera" and "render". The document prints
 * with `render --dump-scene`, and loads like any scene of ours.
 *
 * Transforms: {"position", "scale" (number or [x, y, z]), "rotation" ([x, y, z] degrees)} is
 * the matrix T R S: scale first, then rotate, then translate. Tungsten's rotation is
 * R = Ry(-y) Rx(x) Rz(z), where Ra(t) turns by t counter-clockwise about axis a (seen from the
 * axis's tip): the z angle acts first, then x, then y, and the y angle turns the other way
 * (the test "tungsten_rotation_order" proves this order from Tungsten's own Cornell box walls
 * and from axis-angle rotations).
 *
 * An integrator we lack (bidirectional_path_tracer, ...) is a warning naming it, and the scene
 * renders with "path" (--mode chooses another); so is a reconstruction filter (ours is a box).
 * Anything else that would change the image and is not supported is an error naming its JSON path
 * and the feature ("$.primitives[4].bump: bump maps are not supported"). Keys that change only the file output, the noise or the
 * display (camera.tonemap, camera.reconstruction_filter, renderer.output_file, the photon
 * counts of Tungsten's photon mappers, ...) give a warning on stderr that names the file.
 * Emission (or power over the area) and a medium's sigma times density have our ranges
 * (scene.h), checked here so the message names the Tungsten file's JSON path. A "null" bsdf without
 * emission and a "forward" bsdf without a medium are invisible and dropped; a "null" emitter
 * becomes a black emitter (it then blocks light behind it, which Tungsten's does not: a
 * warning says so).
 *
 * Media: "homogeneous" media only (sigma_a and sigma_s, numbers or [r, g, b], times "density";
 * "phase_function" "isotropic" or "henyey_greenstein" with "g"; "max_bounces" only at or above
 * the integrator's). A medium is named in $.media or written inline where it is used (it is then
 * named after its JSON path). The camera's "medium" becomes our global "medium" (the one
 * between objects). Media are interfaces (scene/medium.h): a primitive light passes through
 * (null, forward, refracting glass) that names int_medium or ext_medium gets interior_medium
 * (int; unnamed: none) and exterior_medium (ext; unnamed: the camera's medium); an opaque
 * emitter's ext_medium is the medium on both its sides (Tungsten uses an opaque surface's media
 * only for its emission); every other primitive, in a scene with media, gets "keeps_medium":
 * the ray keeps its medium there, as Tungsten changes the medium only at a surface that names
 * one. The loader checks that the surfaces around each medium close it together (a null quad
 * closing a room of walls does). A null or forward bsdf with a medium becomes our "null"
 * material. Other medium types, phase functions and an emitting boundary are errors.
 *
 * Errors: a negative PM_E* code with the message in json_err. The caller owns *out.
 */
#ifndef RENDER_TUNGSTEN_H
#define RENDER_TUNGSTEN_H

#include <cjson/cJSON.h>

#include "base/json.h"
#include "base/vec.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Is this document a Tungsten scene (it has "bsdfs" or "primitives", and no "materials" or
 * "objects")? */
int tungsten_is_scene(const cJSON *root);

/* Convert. dir is the directory of the scene file (mesh files are relative to it), "" or NULL
 * for the current directory; it is used to read a mesh whose "power" needs its area. file is
 * the scene file's path as the user gave it (NULL for a text): every warning on stderr names
 * it ("render: FILE: warning: $.camera.tonemap: ignored ..."), as errors are named by the
 * caller. Mesh paths in *out are as the file gave them (import.h makes them absolute). */
int tungsten_convert(const cJSON *root, const char *dir, const char *file, cJSON **out, json_err *e);

/* Tungsten's rotation matrix for Euler angles in degrees (see the top of this file). */
void tungsten_rotation(vec3 deg, double R[3][3]);

/* The 3x4 matrix of a Tungsten transform object (position, scale, rotation) at path. */
int tungsten_transform(const cJSON *t, const char *path, double M[3][4], json_err *e);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_TUNGSTEN_H */
