/* scene_load_internal.h: what the files of the JSON scene loader share (scene_load.c the
 * document, camera, materials, lights and settings; scene_objects.c the objects;
 * scene_media.c the media; scene_lights.c the spot and infinite lights; scene_ports.c the
 * photon ports; scene_shared.c what they all call); not for use outside render/load/scene_*.c.
 */
#ifndef RENDER_SCENE_LOAD_INTERNAL_H
#define RENDER_SCENE_LOAD_INTERNAL_H

#include <cjson/cJSON.h>

#include "base/json.h"
#include "scene/scene.h"

#define P_MAX 256

#define TRY(x) JSON_TRY(x)

/* The known keys of each object of the format (json_check_keys: any other key is an error
 * that suggests the nearest of these). "comment" is allowed everywhere, as free text. */
#define KEYS(obj, path, what, ...)                                                         \
    do {                                                                                    \
        static const char *const k__[] = {__VA_ARGS__, "comment"};                          \
        TRY(json_check_keys(obj, path, k__, sizeof k__ / sizeof *k__, what, e));            \
    } while (0)

typedef struct {
    int tcap, scap, mcap, lcap; /* capacities of tris, spheres, mats, lights */
    int tocap, socap; /* capacities of tri_obj, sphere_obj */
    int obj;          /* index in $.objects of the object being loaded */
} caps;

/* ---- scene_shared.c ------------------------------------------------------------------------ */

/* Append one element of size sz to *arr (count *n, capacity *cap). */
int sl_push(void **arr, int *n, int *cap, size_t sz, const void *elem);
int sl_check_nonneg_rgb(rgb c, const char *path, const char *key, json_err *e);
/* A point (key NULL: path names it): every coordinate within SCENE_LENGTH_MAX. */
int sl_check_point(vec3 v, const char *path, const char *key, json_err *e);
/* Is it a "comment" key with a string (free text, allowed everywhere)? */
int sl_is_comment(const cJSON *it);

/* ---- scene_objects.c ----------------------------------------------------------------------- */

/* One of $.objects (sphere, triangle, quad, inline or file mesh) at path P into the scene. */
int sl_load_object(scene *s, caps *cp, const cJSON *o, const char *P, json_err *e);

/* ---- scene_media.c ------------------------------------------------------------------------- */

/* $.media: named homogeneous media (medium.h). */
int sl_load_media(scene *s, const cJSON *root, json_err *e);
/* The index of the medium named by the string at obj.key, in *out. */
int sl_find_medium(const scene *s, const cJSON *obj, const char *P, const char *key, int *out, json_err *e);
/* An object's "interior_medium", "exterior_medium", "keeps_medium" (medium.h). */
int sl_load_object_media(scene *s, const cJSON *o, const char *P, int obj, json_err *e);
/* Every medium but the global one closed by the surfaces around it together (medium.h). */
int sl_check_media_closed(scene *s, json_err *e);
/* Which medium the camera is in (the rule of medium.h). */
void sl_find_camera_medium(scene *s);

/* ---- scene_lights.c ------------------------------------------------------------------------ */

/* A light of a type that scene_load.c leaves to scene_lights.c (spot, infinite) into *l: 1 if
 * type is one, 0 if not, negative on an error (reported in e). */
int sl_load_light_more(scene *s, light *l, const char *type, const cJSON *o, const char *P, json_err *e);

/* ---- scene_ports.c ------------------------------------------------------------------------- */

/* $.ports and $.port_fraction: the photon ports (port.h). */
int sl_load_ports(scene *s, const cJSON *root, json_err *e);

#endif /* RENDER_SCENE_LOAD_INTERNAL_H */
