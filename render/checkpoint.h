/* checkpoint.h: the render-state file that `render --checkpoint FILE` writes and
 * `render SCENE --resume FILE` continues from.
 *
 * A checkpoint holds what a resumed render needs to finish with the image an uninterrupted
 * render would have given, bit for bit, and what it needs to refuse a mismatch:
 *   - a format version (CKPT_VERSION): a file of another version is refused;
 *   - the image size and samples per pixel;
 *   - the scene hash: 64-bit FNV-1a of the scene file's bytes (another scene, or the same file
 *     edited, is refused);
 *   - the settings text: every setting that changes the image (mode, size, samples, seed,
 *     photon-mapping settings, the renderer's version), as the program prints them; a resumed
 *     run must arrive at the same text;
 *   - the command-line arguments to replay on resume (so `render SCENE --resume FILE` needs
 *     nothing else), each NUL-terminated;
 *   - the photon maps' directory ("" in path mode) and the hash of the map files in it;
 *   - per pixel the render state (renderer.h): the sum of its samples (three doubles) and the
 *     sample count;
 *   - a trailing 64-bit FNV-1a checksum of everything before it.
 * Layout, all integers and doubles little-endian: "PMRCKPT\n", u32 version, u32 width,
 * u32 height, u32 spp, u64 scene hash, u64 photon hash, u32 lengths of the settings, the
 * arguments and the photon directory, u32 0; those bytes; width * height pixels of
 * (3 x f64 sum, u32 count), rows top to bottom; u64 checksum.
 *
 * ckpt_read checks the size the header implies against the file's size before it allocates
 * anything, so a truncated (or padded) file is refused at once with a message, as are a
 * count above spp and a checksum mismatch. It reads regular files only.
 * ckpt_write goes through output.h: the file is replaced atomically (or written through a
 * FIFO or device), and SIGINT/SIGTERM during the write leave the previous checkpoint.
 *
 * Errors: PM_EIO (errno kept), PM_EFORMAT, PM_EVERSION, PM_ENOMEM, with a message in err that
 * names the file. The caller owns the info and the state (render_state_free).
 */
#ifndef RENDER_CHECKPOINT_H
#define RENDER_CHECKPOINT_H

#include <stddef.h>
#include <stdint.h>

#include "renderer.h"

#ifdef __cplusplus
extern "C" {
#endif

#define CKPT_VERSION 1u

typedef struct ckpt_info {
    uint64_t scene_hash, photon_hash;
    char settings[4096];
    char args[8192]; /* NUL-terminated arguments, one after another */
    size_t args_len; /* bytes used in args, the NULs included */
    char photons[1024];
} ckpt_info;

int ckpt_write(const char *path, const ckpt_info *ci, const render_state *st, char *err,
               size_t errcap);
/* st == NULL reads the header and strings only (for the arguments to replay); else st gets
 * a new state (render_state_free it). */
int ckpt_read(const char *path, ckpt_info *ci, render_state *st, char *err, size_t errcap);

/* 64-bit FNV-1a, continued from h (start with CKPT_HASH_INIT). */
#define CKPT_HASH_INIT 0xcbf29ce484222325ULL
uint64_t ckpt_hash(uint64_t h, const void *p, size_t n);
/* Continue h over a file's bytes (at most max_bytes; more is an error). 0 or PM_EIO. */
int ckpt_hash_file(const char *path, uint64_t max_bytes, uint64_t *h, char *err, size_t errcap);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_CHECKPOINT_H */
