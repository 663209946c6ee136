/* import.h: what the scene loader needs to read scenes and meshes written elsewhere.
 *
 * scene_import() runs on a parsed scene file before it is loaded: a Tungsten scene is
 * converted into our format (tungsten.h), and the "file" of every mesh object (and the "map"
 * of every light, an infinite light's image) is joined to the scene file's directory, so the document no longer depends on where it came from. The result
 * is what `render --dump-scene` prints.
 *
 * mesh_object_read() reads the mesh of one {"type": "mesh", "file": ...} object (keys in
 * data/scenes/README.md: file, transform, smooth, recompute_normals, usemtl, flip): it loads the
 * file, applies the transform, and, when smooth, makes the corner normals (mesh.h). Errors
 * name the JSON path, and the file with its line or byte offset.
 *
 * Timing: both add their wall-clock time to the statistics timer "Time/Mesh loading", and
 * mesh_object_read its process CPU time to "Time/Mesh loading (CPU)" (stats.h).
 */
#ifndef RENDER_IMPORT_H
#define RENDER_IMPORT_H

#include <cjson/cJSON.h>

#include "base/json.h"
#include "load/mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Replace *root by the document to load (the same one, edited, or a converted one; the old
 * one is freed then). scene_path may be NULL (text scenes: paths stay relative to the current
 * directory). */
int scene_import(cJSON **root, const char *scene_path, json_err *e);

/* Parse a scene file: a pbrt-v3 file (name ending in .pbrt, pbrt.h) is converted into our
 * document, anything else is parsed as JSON (json.h). The caller owns *root. */
int scene_parse_file(const char *path, cJSON **root, json_err *e);

/* Read the mesh of object o at JSON path P. *smooth tells whether m->corner_n is filled;
 * *usemtl whether the OBJ's usemtl names choose materials. */
int mesh_object_read(const cJSON *o, const char *P, mesh_data *m, int *smooth, int *usemtl, json_err *e);


#ifdef __cplusplus
}
#endif
#endif /* RENDER_IMPORT_H */
