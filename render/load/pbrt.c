/* pbrt.c: pbrt-v3 scene files to our scene document; see pbrt.h, and pbrt_internal.h for how
 * the converter works. This file: the entry points, the conversion's start and end (pbrt's
 * defaults, the document written from the state), running files, and the matrices.
 */
#define _XOPEN_SOURCE 700
#include "load/pbrt_internal.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "load/mesh.h"

/* ---- matrices ----------------------------------------------------------------------------- */

void pb_ident(double m[4][4]) {
    memset(m, 0, 16 * sizeof(double));
    for (int i = 0; i < 4; i++) m[i][i] = 1;
}

void pb_mul(double a[4][4], double b[4][4], double out[4][4]) {
    double r[4][4];
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            r[i][j] = 0;
            for (int k = 0; k < 4; k++) r[i][j] += a[i][k] * b[k][j];
        }
    memcpy(out, r, sizeof r);
}

/* Inverse by Gauss-Jordan with partial pivoting; -1 when singular or not finite. */
int pb_inv(double m[4][4], double out[4][4]) {
    double a[4][8];
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 8; j++) a[i][j] = j < 4 ? m[i][j] : (j - 4 == i);
    for (int col = 0; col < 4; col++) {
        int p = col;
        for (int r = col + 1; r < 4; r++)
            if (fabs(a[r][col]) > fabs(a[p][col])) p = r;
        if (!(fabs(a[p][col]) > 1e-300) || !isfinite(a[p][col])) return -1;
        for (int j = 0; j < 8; j++) {
            double t = a[col][j];
            a[col][j] = a[p][j];
            a[p][j] = t;
        }
        double d = a[col][col];
        for (int j = 0; j < 8; j++) a[col][j] /= d;
        for (int r = 0; r < 4; r++)
            if (r != col) {
                double f = a[r][col];
                for (int j = 0; j < 8; j++) a[r][j] -= f * a[col][j];
            }
    }
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) out[i][j] = a[i][j + 4];
    return 0;
}

double pb_det3(double m[4][4]) {
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

vec3 pb_point(double m[4][4], vec3 p) {
    return v3(m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
              m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
              m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3]);
}
vec3 pb_dir(double m[4][4], vec3 d) {
    return v3(m[0][0] * d.x + m[0][1] * d.y + m[0][2] * d.z, m[1][0] * d.x + m[1][1] * d.y + m[1][2] * d.z,
              m[2][0] * d.x + m[2][1] * d.y + m[2][2] * d.z);
}

/* Output coordinates: the world, mirrored in x when pbrt's camera frame is ours mirrored. */
vec3 pb_out(const conv *c, vec3 p) { return c->mirror ? v3(0.0 - p.x, p.y, p.z) : p; } /* +0, not -0 */

cJSON *pb_jv(vec3 v) {
    double a[3] = {v.x, v.y, v.z};
    return cJSON_CreateDoubleArray(a, 3);
}

/* ---- running files ---------------------------------------------------------------- */

static int run_tokens(conv *c, const toks *ts) {
    int i = 0;
    while (i < ts->n) TRY(pb_directive(c, ts, &i));
    return 0;
}

static int run_text(conv *c, const char *text, const char *name) {
    if (c->nfiles == (int)(sizeof c->files / sizeof *c->files))
        return json_fail(c->e, PM_EINVAL, "%s: more than %d files included", name, (int)(sizeof c->files / sizeof *c->files));
    c->files[c->nfiles] = strdup(name);
    if (!c->files[c->nfiles]) return PM_ENOMEM;
    toks ts = {0};
    int rc = pb_lex(c, text, c->nfiles++, &ts);
    if (rc == PM_ENOMEM) json_fail(c->e, rc, "out of memory");
    if (rc == 0) rc = run_tokens(c, &ts);
    pb_toks_free(&ts);
    return rc;
}

int pb_run_file(conv *c, const char *path, const tok *from) {
    if (c->include_depth >= PB_MAX_INCLUDE)
        return pb_fail(c, from, PM_EINVAL, "Include nested more than %d deep (a file including itself?)", PB_MAX_INCLUDE);
    char *buf;
    size_t len;
    char err[600];
    int rc = mesh_read_file(path, &buf, &len, err, sizeof err);
    if (rc < 0) return from ? pb_fail(c, from, rc, "Include: %s", err) : json_fail(c->e, rc, "%s", err);
    if (strlen(buf) != len) {
        free(buf);
        return from ? pb_fail(c, from, PM_EINVAL, "Include: %s: a NUL byte: not a pbrt text", path)
                    : json_fail(c->e, PM_EINVAL, "a NUL byte: not a pbrt text");
    }
    c->include_depth++;
    rc = run_text(c, buf, path);
    c->include_depth--;
    free(buf);
    return rc;
}

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
    if (rc == 0) rc = text ? run_text(c, text, path) : pb_run_file(c, path, NULL);
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
