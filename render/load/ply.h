/* ply.h: a reader of PLY meshes (the Stanford polygon format), ASCII and binary of either
 * endianness, for the renderer's meshes (see mesh.h for what it produces).
 *
 * Read: the header (`ply`, `format ascii|binary_little_endian|binary_big_endian 1.0`,
 * `comment` and `obj_info` lines, `element NAME COUNT`, `property TYPE NAME` and `property
 * list COUNT_TYPE ITEM_TYPE NAME`, `end_header`; the types char/int8, uchar/uint8,
 * short/int16, ushort/uint16, int/int32, uint/uint32, float/float32, double/float64), then
 * the elements in the header's order:
 *   - `vertex`: x, y, z, and nx, ny, nz when all three are given (the file's normals); any
 *     other property (colours, confidence, intensity, texture coordinates, lists) is skipped;
 *   - `face`: the list `vertex_indices` (or `vertex_index`): triangles, quads and polygons,
 *     split into a fan (v0 v1 v2, v0 v2 v3, ...); other properties skipped;
 *   - `tristrips`: the list `vertex_indices`, strips separated by -1, each strip's triangles
 *     alternating in winding (v0 v1 v2, v2 v1 v3, v2 v3 v4, ...) so all face one way; a strip
 *     triangle that repeats an index is a stitch between strips and is left out silently;
 *   - any other element is skipped.
 * Indices are 0-based and may point forward (faces may come before vertices in the file).
 *
 * Errors (PM_EINVAL, PM_ENOMEM) name the file and the line (ASCII, "bunny.ply:14: ...") or the
 * byte offset (binary and header, "bunny.ply: byte 1032: ..."): a file that is not PLY, a
 * header without end_header, an unknown format, type or keyword, a property outside an
 * element, a list property with a non-integer count or index type, no vertex element or no
 * x, y or z, counts the data cannot hold (checked against the bytes left before anything is
 * allocated: a lying header cannot ask for terabytes), data that ends early (truncated),
 * bytes after the last element (binary; ASCII allows trailing white space), a token that is
 * not a number, a non-finite coordinate or normal, a vertex index out of range, a face of
 * fewer than 3 corners, no face at all. A degenerate face (zero area) is skipped and counted
 * (mesh.h), named "face N" (N counts the face and tristrips elements from 0).
 *
 * Speed: one pass over the file in memory; binary values are decoded with memcpy and a byte
 * swap where the file's order is not the machine's (docs/IMPORT.md has the times against
 * Debian's libassimp).
 */
#ifndef RENDER_PLY_H
#define RENDER_PLY_H

#include <stddef.h>

#include "load/mesh_data.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Parse the bytes of a PLY file (len bytes; buf[len] must be readable and 0, as
 * mesh_read_file gives it); name is used in messages. mesh_load() reads a file and calls this. */
int ply_parse(const char *buf, size_t len, const char *name, mesh_data *m, char *err, size_t cap);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PLY_H */
