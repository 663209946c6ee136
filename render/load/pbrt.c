/* pbrt.c: pbrt-v3 scene files to our scene document; see pbrt.h, and pbrt_internal.h for how
 * the converter works. This file: the entry points and the conversion's start and end (pbrt's
 * defaults, the document written from the state); running files is pbrt_directives.c's, the
 * matrices pbrt_matrix.c's.
 */
#define _XOPEN_SOURCE 700
#include "load/pbrt_internal.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int pbrt_is_file(const char *path) {
    size_t n = path ? strlen(path) : 0;
    return n >= 5 && path[n - 5] == '.' && tolower((unsigned char)path[n - 4]) == 'p' &&
           tolower((unsigned char)path[n - 3]) == 'b' && tolower((unsigned char)path[n - 2]) == 'r' &&
           tolower((unsigned char)path[n - 1]) == 't';
}

static int convert(const char *text, const char *path, cJSON **out, json_err *e) {
    conv *c = calloc(1, sizeof *c);
    *out = NULL;
    if (!c) return json_fail(e, PM_ENOMEM, "out of memory");
    c->e = e;
    pb_ident(c->g.m);
    c->width = 1280;
    c->height = 720;
    c->spp = 16;
    c->maxdepth = 5;
    c->fov = 90;
    c->mode = "path";
    c->mats = cJSON_CreateObject();
    c->objs = cJSON_CreateArray();
    c->lights = cJSON_CreateArray();
    c->target = c->objs;
    int rc = c->mats && c->objs && c->lights ? 0 : json_fail(e, PM_ENOMEM, "out of memory");
    /* pbrt's default material: matte, Kd 0.5 */
    cJSON *def = cJSON_CreateObject();
    if (rc == 0 && def) {
        cJSON_AddStringToObject(def, "type", "lambert");
        cJSON_AddNumberToObject(def, "reflectance", 0.5);
        cJSON_AddItemToObject(c->mats, "pbrt:default", def);
        snprintf(c->g.mat, sizeof c->g.mat, "pbrt:default");
    }
    if (rc == 0) rc = text ? pb_run_text(c, text, path) : pb_run_file(c, path, NULL);
    if (rc == 0 && c->depth > 0) {
        rc = json_fail(e, PM_EINVAL, "%s: %d AttributeBegin/TransformBegin/ObjectBegin left open at the end", path, c->depth);
    }
    if (rc == 0 && !c->in_world) rc = json_fail(e, PM_EINVAL, "%s: no WorldBegin", path);
    cJSON *doc = rc == 0 ? cJSON_CreateObject() : NULL;
    if (rc == 0 && !doc) rc = json_fail(e, PM_ENOMEM, "out of memory");
    if (rc == 0) {
        cJSON_AddStringToObject(doc, "description", "converted from a pbrt-v3 scene by render");
        cJSON *cam = cJSON_CreateObject();
        vec3 eye = pb_out(c, pb_point(c->cam2world, v3s(0)));
        vec3 fwd = pb_out(c, pb_dir(c->cam2world, v3(0, 0, 1))), up = pb_out(c, pb_dir(c->cam2world, v3(0, 1, 0)));
        double t = tan(c->fov * M_PI / 360);
        double hfov = c->width >= c->height ? 2 * atan(t * (double)c->width / (double)c->height) * 180 / M_PI : c->fov;
        cJSON_AddItemToObject(cam, "eye", pb_jv(eye));
        cJSON_AddItemToObject(cam, "look_at", pb_jv(v3_add(eye, v3_norm(fwd))));
        cJSON_AddItemToObject(cam, "up", pb_jv(v3_norm(up)));
        cJSON_AddNumberToObject(cam, "fov_deg", hfov);
        cJSON_AddNumberToObject(cam, "width", (double)c->width);
        cJSON_AddNumberToObject(cam, "height", (double)c->height);
        cJSON_AddNumberToObject(cam, "spp", (double)c->spp);
        cJSON_AddItemToObject(doc, "camera", cam);
        cJSON_AddItemToObject(doc, "materials", c->mats);
        /* with media, a shape without a MediumInterface transition keeps the ray's medium */
        for (cJSON *o = c->media && c->media->child ? c->objs->child : NULL; o; o = o->next)
            if (!cJSON_GetObjectItemCaseSensitive(o, "interior_medium")) cJSON_AddBoolToObject(o, "keeps_medium", 1);
        cJSON_AddItemToObject(doc, "objects", c->objs);
        cJSON_AddItemToObject(doc, "lights", c->lights);
        if (c->media) cJSON_AddItemToObject(doc, "media", c->media);
        if (c->cam_medium[0]) cJSON_AddStringToObject(doc, "medium", c->cam_medium);
        c->mats = c->objs = c->lights = c->media = NULL;
        cJSON *r = cJSON_CreateObject();
        cJSON_AddStringToObject(r, "mode", c->mode);
        cJSON_AddNumberToObject(r, "max_depth", (double)c->maxdepth);
        cJSON_AddItemToObject(doc, "render", r);
        *out = doc;
    }
    cJSON_Delete(c->mats);
    cJSON_Delete(c->objs);
    cJSON_Delete(c->lights);
    cJSON_Delete(c->media);
    for (int k = 0; k < c->nnobj; k++) cJSON_Delete(c->nobj[k].objs);
    free(c->nobj);
    for (int k = 0; k < c->nfiles; k++) free(c->files[k]);
    free(c);
    return rc;
}

int pbrt_convert_file(const char *path, cJSON **out, json_err *e) { return convert(NULL, path, out, e); }

int pbrt_convert_text(const char *text, const char *name, cJSON **out, json_err *e) {
    return convert(text, name ? name : "(text)", out, e);
}
