/* scene_shared.c: what every file of the JSON scene loader calls (scene_load_internal.h): the
 * array push, the checks of a non-negative colour and of a point, and the comment key. Under
 * scene_load.c and the files it hands the objects, media, lights and ports to, so none of
 * them calls back into scene_load.c.
 */
#include "load/scene_load_internal.h"

#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"

/* Append one element of size sz to *arr (count *n, capacity *cap). */
int sl_push(void **arr, int *n, int *cap, size_t sz, const void *elem) {
    if (*n == *cap) {
        int nc = *cap ? 2 * *cap : 16;
        void *na = realloc(*arr, (size_t)nc * sz);
        if (!na) return PM_ENOMEM;
        *arr = na;
        *cap = nc;
    }
    memcpy((char *)*arr + (size_t)*n * sz, elem, sz);
    (*n)++;
    return 0;
}

int sl_check_nonneg_rgb(rgb c, const char *path, const char *key, json_err *e) {
    if (c.x < 0 || c.y < 0 || c.z < 0)
        return json_fail(e, PM_EINVAL, "%s.%s: must not be negative (got [%g, %g, %g])", path, key,
                         c.x, c.y, c.z);
    return 0;
}

/* A point (key NULL: path names it): every coordinate within SCENE_LENGTH_MAX. */
int sl_check_point(vec3 v, const char *path, const char *key, json_err *e) {
    if (!(v3_maxabs(v) <= SCENE_LENGTH_MAX))
        return json_fail(e, PM_EINVAL, "%s%s%s: [%g, %g, %g] is outside the supported range of "
                         "coordinates, -%g to %g", path, key ? "." : "", key ? key : "", v.x, v.y,
                         v.z, SCENE_LENGTH_MAX, SCENE_LENGTH_MAX);
    return 0;
}


/* "comment" is allowed in every object of the format, also in the maps of named materials
 * and media, where a text under that key is a comment, not a material or medium (an object
 * under it is one named "comment"). */
int sl_is_comment(const cJSON *it) {
    return it->string && strcmp(it->string, "comment") == 0 && cJSON_IsString(it);
}
