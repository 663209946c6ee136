/* json.h: reading cJSON documents with errors that name the place of the mistake.
 *
 * Every getter takes the parent object, the JSON path of that parent ("$", "$.camera",
 * "$.objects[3]") and a key. On success it returns 0 and writes *out. On failure it returns a
 * negative PM_E* code and writes a message that starts with the full path of the field into
 * the caller's json_err, e.g. "$.objects[3].radius: expected a number, got a string".
 * Optional fields (required = 0) that are absent leave *out untouched and return 0, so set the
 * default before the call. Every number must be finite: cJSON reads 1e999 as infinity, and
 * that is rejected here ("not a finite number").
 *
 * json_parse_file reads and parses a file; a syntax error is reported with its line and
 * column ("line 12, column 5: syntax error at '"eye": [1,2,>}'", where > marks the spot).
 * A number JSON forbids but cJSON reads (a leading zero, "01" or "-00"; "1." or "1.e5") is an
 * error with its line, column and JSON path ("line 3, column 15: $.objects[0].radius: the
 * number 01 has a leading zero (JSON forbids it)").
 * A key repeated within one object, at any depth, is an error too ("$.camera: the key
 * "width" is given more than once"): cJSON would keep both and the getters see the first.
 *
 * The photon-mapping code reads its "photon_mapping" object with the same getters.
 * Nothing here keeps state; the caller owns and frees (cJSON_Delete) the parsed document.
 */
#ifndef RENDER_JSON_H
#define RENDER_JSON_H

#include <cjson/cJSON.h>
#include <stddef.h>

#include "base/vec.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct json_err {
    char msg[512];
} json_err;

/* In a function that returns an int code: evaluate x, and return its value if it is an error
 * (negative). The loaders' one way to pass an error up (scene_load.c, import.c, tungsten.c
 * define TRY as it). */
#define JSON_TRY(x)                \
    do {                           \
        int rc__ = (x);            \
        if (rc__ < 0) return rc__; \
    } while (0)

/* printf into e->msg; returns code (so `return json_fail(e, PM_EINVAL, ...)` works). */
int json_fail(json_err *e, int code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Child paths: "$.camera" + "eye" -> "$.camera.eye"; "$.objects" + 3 -> "$.objects[3]". */
void json_path_key(char *buf, size_t cap, const char *path, const char *key);
void json_path_index(char *buf, size_t cap, const char *path, int index);

int json_parse_file(const char *filename, cJSON **root, json_err *e);
/* json_parse_file refuses a file larger than this (default 256 MiB), checked while reading.
 * Process-wide: set it once at start-up, before any thread parses. */
void json_set_max_file_bytes(size_t n);
/* Parse text (NUL-terminated); errors carry the line and column. */
int json_parse_text(const char *text, cJSON **root, json_err *e);

/* The item at key, or NULL if absent. */
const cJSON *json_get(const cJSON *obj, const char *key);

int json_number(const cJSON *obj, const char *path, const char *key, int required, double *out,
                json_err *e);
/* An integer in [lo, hi]. */
int json_int(const cJSON *obj, const char *path, const char *key, int required, long lo, long hi,
             long *out, json_err *e);
int json_bool(const cJSON *obj, const char *path, const char *key, int required, int *out,
              json_err *e);
/* A string; *out points into the document (valid until cJSON_Delete). */
int json_string(const cJSON *obj, const char *path, const char *key, int required,
                const char **out, json_err *e);
/* [x, y, z] */
int json_vec3(const cJSON *obj, const char *path, const char *key, int required, vec3 *out,
              json_err *e);
/* [r, g, b] or one number for grey. */
int json_rgb(const cJSON *obj, const char *path, const char *key, int required, rgb *out,
             json_err *e);
/* An object or array child; *out = NULL when absent and optional. */
int json_object(const cJSON *obj, const char *path, const char *key, int required,
                const cJSON **out, json_err *e);
int json_array(const cJSON *obj, const char *path, const char *key, int required,
               const cJSON **out, json_err *e);
/* Convert an array item (already fetched) to a vec3; path names the item. */
int json_item_vec3(const cJSON *item, const char *path, vec3 *out, json_err *e);
/* A short name of an item's type for messages ("a string", "an array", ...). */
const char *json_type_name(const cJSON *item);
/* The known key nearest to `key` by edit distance (insertions, deletions, substitutions and
 * swaps of neighbours each count 1; letters compared without case), if it is within
 * max(1, strlen(key) / 3) edits; else NULL. The part of key after its last '.' is tried too
 * (a JSON path typed as a key: "photon_mapping.k_global" -> "k_global"). For "did you mean"
 * in unknown-key errors ("emision" -> "emission"). */
const char *json_nearest_key(const char *key, const char *const *known, size_t n);
/* Every key of obj must be one of the n names in known. Else an error naming the first
 * unknown key's path and the nearest known key, or the known keys when none is near:
 *   $.materials.light.emision: unknown key (did you mean "emission"?)
 *   $.camera.zoom: unknown key of the camera (known: eye, look_at, ...)
 * `what` names the object in the second form ("the camera", "a sphere"); NULL: left out.
 * One rule for every object of the scene format: a misspelt key is an error, not a default. */
int json_check_keys(const cJSON *obj, const char *path, const char *const *known, size_t n,
                    const char *what, json_err *e);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_JSON_H */
