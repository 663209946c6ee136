/* obj.h: a Wavefront OBJ reader for the renderer's meshes (see mesh.h for what it produces).
 *
 * Read: `v x y z` (extra numbers, such as w or vertex colours, are ignored), `vn x y z`, and
 * `f` with any number of corners >= 3 in the forms v, v/t, v//n and v/t/n; a polygon is split
 * into a fan (v0 v1 v2, v0 v2 v3, ...). Indices are 1-based, or negative: -1 is the last
 * vertex (or normal) defined so far. A face may only use vertices defined above it. `usemtl
 * NAME` assigns NAME to the faces that follow (mesh_data.groups). Comments (#), blank lines and
 * `vt`, `mtllib`, `o`, `g`, `s` are skipped (texture coordinates and smoothing groups do not
 * change this renderer's image: shading smoothness is the scene's "smooth" key); any other
 * statement is an error, so nothing in the file is silently dropped.
 *
 * Errors (PM_EINVAL, PM_EIO, PM_ENOMEM) name the file and line: a missing or non-numeric
 * coordinate (or one longer than 63 characters), NaN or infinity, an index of 0 or out of
 * range, a face with fewer than three corners, a file with no face (or only degenerate ones).
 * A degenerate face (zero area, judged as triangle_make does) is skipped and counted (mesh.h).
 * Speed: one pass over the file in memory
 * (docs/IMPORT.md has the time for a 1M-triangle file).
 */
#ifndef RENDER_OBJ_H
#define RENDER_OBJ_H

#include <stddef.h>

#include "load/mesh_data.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Parse the text of an OBJ file (len bytes); name is used in messages. mesh_load() reads a
 * file and calls this. */
int obj_parse(const char *text, size_t len, const char *name, mesh_data *m, char *err, size_t cap);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_OBJ_H */
