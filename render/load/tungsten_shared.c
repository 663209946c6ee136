/* tungsten_shared.c: what every file of the Tungsten converter calls (tungsten_internal.h):
 * warnings that name the scene file, the check of an object's keys (and of one key against a
 * list), colours, and vectors for the converted document. Under tungsten.c and the files it
 * hands the media and the settings to, so neither calls back into tungsten.c.
 */
#include "load/tungsten_internal.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "common.h"

/* Is key one of the NULL-terminated list? */
int tg_in_list(const char *key, const char *const *list) {
    for (; *list; list++)
        if (strcmp(key, *list) == 0) return 1;
    return 0;
}

/* A warning on stderr that names the scene file (NULL: a scene given as text), as render's
 * own warnings do: "render: FILE: warning: ...". */
void tg_warn(const char *file, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "render: %s%swarning: ", file ? file : "", file ? ": " : "");
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

/* Check every key of obj: in `ok` (handled by the caller), in `warn` (ignored with a warning
 * naming the file: they do not change the image), else an error naming the key and `what`. */
int tg_check_keys(const char *file, const cJSON *obj, const char *P, const char *const *ok,
                      const char *const *warn, const char *what, json_err *e) {
    for (const cJSON *it = obj->child; it; it = it->next) {
        const char *k = it->string ? it->string : "?";
        if (tg_in_list(k, ok)) continue;
        if (warn && tg_in_list(k, warn)) {
            tg_warn(file, "%s.%s: ignored (does not change the image)", P, k);
            continue;
        }
        /* The nearest key of the subset, as in our own format; worded for a real Tungsten key
         * outside the subset too ("min_bounces" is not a misspelt "max_bounces"). */
        const char *names[64];
        size_t n = 0;
        for (const char *const *l = ok; l && *l && n < 64; l++) names[n++] = *l;
        for (const char *const *l = warn; l && *l && n < 64; l++) names[n++] = *l;
        const char *near = json_nearest_key(k, names, n);
        if (near)
            return json_fail(e, PM_EINVAL, "%s.%s: not supported (%s; the nearest supported key is \"%s\")", P, k, what, near);
        return json_fail(e, PM_EINVAL, "%s.%s: not supported (%s)", P, k, what);
    }
    return 0;
}

/* A colour that must be a number or [r, g, b] (textures are not supported). */
int tg_color(const cJSON *obj, const char *P, const char *key, rgb *out, json_err *e) {
    const cJSON *it = json_get(obj, key);
    if (it && (cJSON_IsString(it) || cJSON_IsObject(it)))
        return json_fail(e, PM_EINVAL, "%s.%s: textures are not supported (give a number or [r, g, b])", P, key);
    return json_rgb(obj, P, key, 0, out, e);
}

cJSON *tg_jvec(vec3 v) {
    double a[3] = {v.x, v.y, v.z};
    return cJSON_CreateDoubleArray(a, 3);
}
