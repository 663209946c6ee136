/* scene_hash.h: a fingerprint of what a scene does to light, for files that depend on it.
 *
 * scene_transport_hash() is a 64-bit FNV-1a hash of every field of a loaded scene that a
 * photon or a light path depends on: the triangles (corners, normal, material, light index)
 * and their shading normals, the spheres, every material's scattering and emission fields,
 * the lights (type, position, direction, radiance, intensity, irradiance, sides, power), the
 * index of refraction between objects and the participating media (coefficients, asymmetry,
 * which medium fills space and each object). It leaves out what only the camera pass reads:
 * the camera and image size, samples, seed, render mode, tone and exposure, the
 * photon_mapping object, and the names of materials and media.
 *
 * It hashes the scene as loaded, not the file's bytes: the same scene with other whitespace,
 * a changed description or camera, or the same mesh read from a moved OBJ file hashes the
 * same, and an edited OBJ file does not. Reordering objects or materials changes it. Doubles are hashed by their IEEE
 * bits in little-endian order, integers as 64-bit little-endian, so the value does not depend
 * on the host or on struct padding.
 *
 * Pure function of the scene; reentrant.
 */
#ifndef RENDER_SCENE_HASH_H
#define RENDER_SCENE_HASH_H

#include <stdint.h>

#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

uint64_t scene_transport_hash(const scene *s);

/* The FNV-1a steps it is made of, for hashing other values the same way (start from
 * HASH_FNV_INIT, base/hash.h). */
uint64_t hash_double(uint64_t h, double v);
uint64_t hash_int(uint64_t h, int64_t v);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_SCENE_HASH_H */
