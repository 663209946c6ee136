/* hash.h: 64-bit FNV-1a, the one hash of the renderer's files and fingerprints.
 *
 * Checkpoints (run/checkpoint.h) hash the scene file and their own bytes with it, the photon
 * maps' tags carry a scene fingerprint made of it (scene/scene_hash.h), and photon-map files
 * are named by it. It is a checksum against accidents (another scene, a truncated or edited
 * file), not against an adversary. Start from HASH_FNV_INIT and continue over the bytes.
 */
#ifndef RENDER_HASH_H
#define RENDER_HASH_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define HASH_FNV_INIT 0xcbf29ce484222325ULL

/* h continued over n bytes at p. */
uint64_t hash_fnv1a(uint64_t h, const void *p, size_t n);
/* *h continued over a file's bytes (at most max_bytes; more is an error). 0, or PM_EIO with
 * a message naming the path in err. */
int hash_file(const char *path, uint64_t max_bytes, uint64_t *h, char *err, size_t errcap);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_HASH_H */
