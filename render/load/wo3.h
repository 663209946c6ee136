/* wo3.h: a reader for Tungsten's binary mesh files (.wo3), see mesh.h for what it produces.
 *
 * Layout (little-endian, no header or padding):
 *   uint64 V;  V vertices of 32 bytes: float position[3], float normal[3], float uv[2];
 *   uint64 T;  T triangles of 16 bytes: uint32 v0, v1, v2, int32 material.
 * The per-triangle material index picks one of a Tungsten mesh's bsdfs; the importer accepts
 * one bsdf per mesh, so it is read but not used. uv is not used.
 *
 * Errors (PM_EINVAL, PM_EIO, PM_ENOMEM) name the file and the byte offset: a file shorter than
 * its counts say (truncated), bytes after the last triangle, a NaN or infinite position or
 * normal, a vertex index out of range, no triangle (or only degenerate ones) at all; a
 * degenerate triangle is skipped and counted (mesh.h).
 */
#ifndef RENDER_WO3_H
#define RENDER_WO3_H

#include <stddef.h>
#include <stdint.h>

#include "load/mesh_data.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Parse the bytes of a wo3 file (len of them); name is used in messages. mesh_load() reads a
 * file and calls this. */
int wo3_parse(const unsigned char *buf, size_t len, const char *name, mesh_data *m, char *err,
              size_t cap);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_WO3_H */
