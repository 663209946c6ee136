/* scene_load.h: the scene loader, a scene file to a scene (scene/scene.h), every field checked.
 *
 * The file is JSON (format: data/scenes/README.md), or a Tungsten or pbrt-v3 scene that
 * import.h converts. scene_load() parses it, converts it when it is not in our format,
 * resolves mesh and map paths against its directory, and reads every field; it turns quads
 * and meshes into triangles and calls scene_prepare() (scene.h), after which the scene is
 * immutable. The loader is scene_load.c and the files of scene_load_internal.h.
 *
 * Errors: a negative PM_E* code and a message in json_err: the line and column of a syntax
 * error, or the JSON path of a missing, mistyped or invalid field ("$.objects[3].radius: must
 * be positive, got -1"). `render` prints it (app/run.c) and exits with 2. On an error the
 * partly built scene is freed: the caller never sees half a scene.
 */
#ifndef RENDER_SCENE_LOAD_H
#define RENDER_SCENE_LOAD_H

#include <cjson/cJSON.h>

#include "base/json.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

int scene_load(scene *s, const char *filename, json_err *e);
/* The same from a JSON text (for tests). */
int scene_load_text(scene *s, const char *text, json_err *e);
/* The same from a parsed document (not consumed). */
int scene_from_json(scene *s, const cJSON *root, json_err *e);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_SCENE_LOAD_H */
