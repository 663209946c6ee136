/* tungsten_internal.h: what the files of the Tungsten converter share (tungsten.c the
 * primitives, bsdfs and the conversion, tungsten_media.c the media and the quads that bound
 * them, tungsten_settings.c the camera, renderer and integrator, tungsten_shared.c what they
 * all call); not for use outside render/load/tungsten*.c.
 */
#ifndef RENDER_TUNGSTEN_INTERNAL_H
#define RENDER_TUNGSTEN_INTERNAL_H

#include <cjson/cJSON.h>

#include "common.h"
#include "base/json.h"
#include "base/vec.h"
#include "load/tungsten.h"

#define P_MAX 256

#define TRY(x) JSON_TRY(x)

typedef struct tbsdf {
    char name[64];
    const char *type; /* lambert, dielectric, mirror, null, forward */
    rgb albedo;
    double ior;
    int refract;
} tbsdf;

#define T_MEDIA 64

typedef struct conv {
    tbsdf *bsdfs;
    int nbsdfs;
    cJSON *mats, *objs;
    cJSON *media;          /* our "media" object (NULL until the first medium) */
    char mnames[T_MEDIA][64]; /* our names of the media, by index */
    int nmedia;
    int global;            /* the camera's medium: the one around every object (-1: none) */
    long max_depth;        /* integrator.max_bounces as converted (a medium's limit below it is an error) */
    const char *dir;
    const char *file;      /* the scene file, for warnings (NULL: a text) */
    int nemit;
    cJSON *out;            /* the converted document (its "lights" made by the first light) */
} conv;

/* ---- tungsten_shared.c --------------------------------------------------------------------- */

/* Is key one of the NULL-terminated list? */
int tg_in_list(const char *key, const char *const *list);
/* A warning on stderr that names the scene file (NULL: a scene given as text), as render's
 * own warnings do: "render: FILE: warning: ...". */
void tg_warn(const char *file, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* Check every key of obj: in `ok` (handled by the caller), in `warn` (ignored with a warning
 * naming the file: they do not change the image), else an error naming the key and `what`. */
int tg_check_keys(const char *file, const cJSON *obj, const char *P, const char *const *ok,
                  const char *const *warn, const char *what, json_err *e);
/* A colour that must be a number or [r, g, b] (textures are not supported). */
int tg_color(const cJSON *obj, const char *P, const char *key, rgb *out, json_err *e);
cJSON *tg_jvec(vec3 v);

/* ---- tungsten_media.c ---------------------------------------------------------------------- */

/* One Tungsten medium object at path P into our media under the name `name`; its index in *idx. */
int tg_read_medium(conv *c, const cJSON *m, const char *P, const char *name, int *idx, json_err *e);
/* A medium reference at path P: a name from $.media, or an inline medium; *idx -1 when v is NULL. */
int tg_medium_ref(conv *c, const cJSON *v, const char *P, int *idx, json_err *e);

/* ---- tungsten_settings.c ------------------------------------------------------------------- */

/* $.camera into our "camera" (spp: $.renderer.spp, 0 when not given). */
int tg_convert_camera(const char *file, const cJSON *root, cJSON *out, long spp, json_err *e);
/* $.renderer and $.integrator into our "render"; *spp and *max_depth as converted. */
int tg_convert_settings(const char *file, const cJSON *root, cJSON *out, long *spp, long *max_depth, json_err *e);

#endif /* RENDER_TUNGSTEN_INTERNAL_H */
