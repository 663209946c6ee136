/* pbrt_directives.c: running pbrt's directives against the graphics state (pbrt_internal.h):
 * one function per directive, found by name in a table. A directive either reads its own
 * arguments (the transforms, the blocks, Include, the objects) or has a name and a parameter
 * list, which the dispatcher parses, hands over and frees, warning about what nobody asked for.
 * Running a file's directives is here too (pb_run_file, for the top file and for Include).
 */
#define _XOPEN_SOURCE 700
#include "load/pbrt_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "load/mesh.h"

static int apply(conv *c, const tok *at, double T[4][4]) {
    double r[4][4];
    pb_mul(c->g.m, T, r);
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            if (!isfinite(r[i][j])) return pb_fail(c, at, PM_EINVAL, "the transform is not finite");
    memcpy(c->g.m, r, sizeof r);
    return 0;
}

static int camera_done(conv *c, const tok *at) {
    snprintf(c->cam_medium, sizeof c->cam_medium, "%s", c->g.outside);
    double inv[4][4];
    if (pb_inv(c->g.m, inv) < 0) return pb_fail(c, at, PM_EINVAL, "Camera: the camera transform is singular or not finite");
    memcpy(c->cam2world, inv, sizeof inv);
    c->have_camera = 1;
    if (c->ncs < 16) {
        snprintf(c->cs[c->ncs].name, sizeof c->cs[0].name, "camera");
        memcpy(c->cs[c->ncs++].m, inv, sizeof inv);
    }
    return 0;
}

static int world_begin(conv *c) {
    /* pbrt's image right is the camera's +x; ours is forward x up: mirror when they disagree */
    vec3 fwd = pb_dir(c->cam2world, v3(0, 0, 1)), up = pb_dir(c->cam2world, v3(0, 1, 0)), right = pb_dir(c->cam2world, v3(1, 0, 0));
    c->mirror = v3_dot(v3_cross(fwd, up), right) < 0;
    pb_ident(c->g.m);
    c->in_world = 1;
    return 0;
}

/* ---- transforms, blocks, files, objects ------------------------------------------- */

static int do_look_at(conv *c, const toks *ts, int *i, const tok *at) {
    double v[16];
    TRY(pb_nums(c, ts, i, at, 9, v, "LookAt"));
    vec3 eye = v3(v[0], v[1], v[2]), look = v3(v[3], v[4], v[5]), up = v3(v[6], v[7], v[8]);
    vec3 dir = v3_sub(look, eye);
    if (!(v3_len(dir) > 0)) return pb_fail(c, at, PM_EINVAL, "LookAt: the eye and the point looked at are the same");
    dir = v3_norm(dir);
    vec3 right = v3_cross(v3_norm(up), dir);
    if (!(v3_len(right) > 1e-12)) return pb_fail(c, at, PM_EINVAL, "LookAt: up is parallel to the view direction");
    right = v3_norm(right);
    vec3 nup = v3_cross(dir, right);
    double C[4][4] = {{right.x, nup.x, dir.x, eye.x}, {right.y, nup.y, dir.y, eye.y}, {right.z, nup.z, dir.z, eye.z}, {0, 0, 0, 1}};
    double W[4][4];
    if (pb_inv(C, W) < 0) return pb_fail(c, at, PM_EINVAL, "LookAt: singular");
    return apply(c, at, W);
}

/* Translate (x y z in the last column) or Scale (on the diagonal). */
static int do_translate_scale(conv *c, const toks *ts, int *i, const tok *at) {
    const char *d = at->s;
    double v[16], T[4][4];
    TRY(pb_nums(c, ts, i, at, 3, v, d));
    pb_ident(T);
    for (int k = 0; k < 3; k++) T[k][d[0] == 'T' ? 3 : k] = v[k];
    return apply(c, at, T);
}

static int do_rotate(conv *c, const toks *ts, int *i, const tok *at) {
    double v[16];
    TRY(pb_nums(c, ts, i, at, 4, v, "Rotate"));
    vec3 a = v3(v[1], v[2], v[3]);
    if (!(v3_len(a) > 0)) return pb_fail(c, at, PM_EINVAL, "Rotate: the axis is the zero vector");
    a = v3_norm(a);
    double t = v[0] * M_PI / 180, cs = cos(t), sn = sin(t);
    double T[4][4] = {{a.x * a.x + (1 - a.x * a.x) * cs, a.x * a.y * (1 - cs) - a.z * sn, a.x * a.z * (1 - cs) + a.y * sn, 0},
                      {a.x * a.y * (1 - cs) + a.z * sn, a.y * a.y + (1 - a.y * a.y) * cs, a.y * a.z * (1 - cs) - a.x * sn, 0},
                      {a.x * a.z * (1 - cs) - a.y * sn, a.y * a.z * (1 - cs) + a.x * sn, a.z * a.z + (1 - a.z * a.z) * cs, 0},
                      {0, 0, 0, 1}};
    return apply(c, at, T);
}

static int do_transform(conv *c, const toks *ts, int *i, const tok *at) {
    const char *d = at->s;
    double v[16];
    TRY(pb_nums(c, ts, i, at, 16, v, d));
    double T[4][4];
    for (int r = 0; r < 4; r++)
        for (int k = 0; k < 4; k++) T[r][k] = v[4 * k + r]; /* pbrt gives the columns */
    if (d[0] == 'T') pb_ident(c->g.m);
    return apply(c, at, T);
}

static int do_identity(conv *c, const toks *ts, int *i, const tok *at) {
    (void)ts, (void)i, (void)at;
    pb_ident(c->g.m);
    return 0;
}

static int do_coordsys(conv *c, const toks *ts, int *i, const tok *at) {
    const char *d = at->s;
    const char *s = NULL;
    TRY(pb_one_string(c, ts, i, at, &s, d));
    if (d[5] == 'i') { /* CoordinateSystem */
        if (c->ncs == 16) return pb_fail(c, at, PM_EINVAL, "more than 16 named coordinate systems");
        snprintf(c->cs[c->ncs].name, sizeof c->cs[0].name, "%s", s);
        memcpy(c->cs[c->ncs++].m, c->g.m, sizeof c->g.m);
        return 0;
    }
    for (int k = c->ncs - 1; k >= 0; k--)
        if (strcmp(c->cs[k].name, s) == 0) {
            memcpy(c->g.m, c->cs[k].m, sizeof c->g.m);
            return 0;
        }
    return pb_fail(c, at, PM_EINVAL, "CoordSysTransform: no coordinate system named \"%s\"", s);
}

static int do_reverse(conv *c, const toks *ts, int *i, const tok *at) {
    (void)ts, (void)i, (void)at;
    c->g.revor = !c->g.revor;
    return 0;
}

static int do_begin(conv *c, const toks *ts, int *i, const tok *at) {
    const char *d = at->s;
    (void)ts, (void)i;
    if (c->depth == PB_MAX_STACK) return pb_fail(c, at, PM_EINVAL, "more than %d nested %s", PB_MAX_STACK, d);
    c->stack_kind[c->depth] = d[0] == 'A' ? 1 : 2;
    c->stack[c->depth++] = c->g;
    return 0;
}

static int do_end(conv *c, const toks *ts, int *i, const tok *at) {
    const char *d = at->s;
    (void)ts, (void)i;
    int kind = d[0] == 'A' ? 1 : 2;
    if (c->depth == 0 || c->stack_kind[c->depth - 1] != kind)
        return pb_fail(c, at, PM_EINVAL, "%s without a matching %s", d, kind == 1 ? "AttributeBegin" : "TransformBegin");
    c->depth--;
    if (kind == 1) c->g = c->stack[c->depth];
    else memcpy(c->g.m, c->stack[c->depth].m, sizeof c->g.m);
    return 0;
}

static int do_world_begin(conv *c, const toks *ts, int *i, const tok *at) {
    (void)ts, (void)i;
    if (c->in_world) return pb_fail(c, at, PM_EINVAL, "WorldBegin twice");
    if (!c->have_camera) { /* pbrt's default camera: at the origin, looking down +z */
        pb_ident(c->g.m);
        TRY(camera_done(c, at));
    }
    return world_begin(c);
}

static int do_world_end(conv *c, const toks *ts, int *i, const tok *at) {
    (void)c, (void)ts, (void)i, (void)at;
    return 0;
}

static int do_include(conv *c, const toks *ts, int *i, const tok *at) {
    const char *d = at->s;
    const char *s = NULL;
    TRY(pb_one_string(c, ts, i, at, &s, d));
    char path[8192];
    pb_resolve(pb_file(c, at), s, path, sizeof path);
    return pb_run_file(c, path, at);
}

static int do_object_begin(conv *c, const toks *ts, int *i, const tok *at) {
    const char *d = at->s;
    const char *s = NULL;
    TRY(pb_one_string(c, ts, i, at, &s, d));
    if (c->target != c->objs) return pb_fail(c, at, PM_EINVAL, "ObjectBegin inside ObjectBegin \"%s\"", s);
    if (c->depth == PB_MAX_STACK) return pb_fail(c, at, PM_EINVAL, "more than %d nested blocks", PB_MAX_STACK);
    c->stack_kind[c->depth] = 3;
    c->stack[c->depth++] = c->g;
    named_obj *no = realloc(c->nobj, (size_t)(c->nnobj + 1) * sizeof *no);
    if (!no) return PM_ENOMEM;
    c->nobj = no;
    snprintf(no[c->nnobj].name, sizeof no[0].name, "%s", s);
    no[c->nnobj].objs = cJSON_CreateArray();
    if (!no[c->nnobj].objs) return PM_ENOMEM;
    c->target = no[c->nnobj++].objs;
    return 0;
}

static int do_object_end(conv *c, const toks *ts, int *i, const tok *at) {
    (void)ts, (void)i;
    if (c->target == c->objs || c->depth == 0 || c->stack_kind[c->depth - 1] != 3)
        return pb_fail(c, at, PM_EINVAL, "ObjectEnd without ObjectBegin");
    c->g = c->stack[--c->depth];
    c->target = c->objs;
    return 0;
}

static int do_object_instance(conv *c, const toks *ts, int *i, const tok *at) {
    const char *d = at->s;
    const char *s = NULL;
    TRY(pb_one_string(c, ts, i, at, &s, d));
    if (c->target != c->objs) return pb_fail(c, at, PM_EINVAL, "ObjectInstance inside ObjectBegin");
    for (int k = c->nnobj - 1; k >= 0; k--)
        if (strcmp(c->nobj[k].name, s) == 0) {
            double X[4][4]; /* the instance transform in output coordinates: S ctm S */
            memcpy(X, c->g.m, sizeof X);
            if (c->mirror)
                for (int r = 0; r < 4; r++)
                    for (int q = 0; q < 4; q++)
                        if ((r == 0) != (q == 0)) X[r][q] = -X[r][q];
            for (const cJSON *o = c->nobj[k].objs->child; o; o = o->next) {
                cJSON *n = pb_xform_obj(c, o, X);
                if (!n) return PM_ENOMEM;
                cJSON_AddItemToArray(c->objs, n);
            }
            return 0;
        }
    return pb_fail(c, at, PM_EINVAL, "ObjectInstance: no object named \"%s\"", s);
}

static int do_texture(conv *c, const toks *ts, int *i, const tok *at) {
    const char *d = at->s;
    plist pl;
    pl.n = 0;
    const char *a, *b, *cl;
    TRY(pb_one_string(c, ts, i, at, &a, d));
    TRY(pb_one_string(c, ts, i, at, &b, d));
    TRY(pb_one_string(c, ts, i, at, &cl, d));
    TRY(pb_read_params(c, ts, i, &pl));
    pb_warn(c, at, "Texture \"%s\": textures are not supported: materials that use it get their default value", a);
    pb_plist_free(&pl);
    return 0;
}

/* ---- directives with a name and a parameter list ---------------------------------- */

static int do_camera(conv *c, const tok *at, const char *s, plist *pl, const char *what) {
    int rc = 0;
    if (strcmp(s, "perspective") != 0)
        rc = pb_fail(c, at, PM_EINVAL, "Camera \"%s\" is not supported (perspective)", s);
    if (rc == 0 && (rc = pb_get_floats(c, at, pl, "fov", "float", 1, &c->fov)) > 0) rc = 0;
    double lr = 0, fa = 0, sw[4];
    if (rc == 0 && (rc = pb_get_floats(c, at, pl, "lensradius", "float", 1, &lr)) > 0) rc = 0;
    if (rc == 0 && lr > 0) pb_warn(c, at, "%s: lensradius %g: depth of field is not supported: a pinhole", what, lr);
    if (rc == 0 && (rc = pb_get_floats(c, at, pl, "focaldistance", "float", 1, &fa)) > 0) rc = 0;
    if (rc == 0 && (rc = pb_get_floats(c, at, pl, "frameaspectratio", "float", 1, &fa)) > 0) {
        rc = 0;
        pb_warn(c, at, "%s: frameaspectratio is not supported: the image's own aspect", what);
    }
    if (rc == 0 && (rc = pb_get_floats(c, at, pl, "screenwindow", "float", 4, sw)) > 0) {
        rc = 0;
        pb_warn(c, at, "%s: screenwindow is not supported: the full frame", what);
    }
    if (rc == 0 && !(c->fov > 0 && c->fov < 180)) rc = pb_fail(c, at, PM_EINVAL, "%s: fov %g is not in (0, 180)", what, c->fov);
    if (rc == 0) rc = camera_done(c, at);
    if (rc == 0) pb_warn_unused(c, at, what, pl);
    return rc;
}

static int do_film(conv *c, const tok *at, const char *s, plist *pl, const char *what) {
    int rc = 0;
    (void)s;
    double x = 0;
    if ((rc = pb_get_floats(c, at, pl, "xresolution", "integer", 1, &x)) > 0) c->width = (long)x;
    if (rc >= 0 && (rc = pb_get_floats(c, at, pl, "yresolution", "integer", 1, &x)) > 0) c->height = (long)x;
    const char *fn;
    if (rc >= 0) rc = pb_get_string(c, at, pl, "filename", &fn); /* the output name: not ours to follow */
    double cw[4];
    if (rc >= 0 && (rc = pb_get_floats(c, at, pl, "cropwindow", "float", 4, cw)) > 0)
        pb_warn(c, at, "%s: cropwindow is not supported: the whole image", what);
    if (rc >= 0) rc = 0;
    if (rc == 0 && (c->width < 1 || c->height < 1 || c->width > 16384 || c->height > 16384))
        rc = pb_fail(c, at, PM_EINVAL, "%s: resolution %ld x %ld outside 1..16384", what, c->width, c->height);
    if (rc == 0) pb_warn_unused(c, at, what, pl);
    return rc;
}

static int do_sampler(conv *c, const tok *at, const char *s, plist *pl, const char *what) {
    int rc = 0;
    double x = 0;
    int strat = strcmp(s, "stratified") == 0;
    if ((rc = pb_get_floats(c, at, pl, "pixelsamples", "integer", 1, &x)) > 0) c->spp = (long)x;
    if (rc >= 0 && strat) {
        double xs = 4, ys = 4;
        int a = pb_get_floats(c, at, pl, "xsamples", "integer", 1, &xs), b = pb_get_floats(c, at, pl, "ysamples", "integer", 1, &ys);
        int jit = 1;
        if (a < 0 || b < 0 || pb_get_bool(c, at, pl, "jitter", &jit) < 0) rc = PM_EINVAL;
        else c->spp = (long)(xs * ys);
    }
    if (rc >= 0) rc = 0;
    if (rc == 0 && !strat)
        pb_warn(c, at, "%s is not supported: our stratified sampler is used (%ld samples per pixel)", what, c->spp);
    if (rc == 0 && (c->spp < 1 || c->spp > (1 << 20)))
        rc = pb_fail(c, at, PM_EINVAL, "%s: %ld samples per pixel outside 1..1048576", what, c->spp);
    if (rc == 0) pb_warn_unused(c, at, what, pl);
    return rc;
}

static int do_integrator(conv *c, const tok *at, const char *s, plist *pl, const char *what) {
    int rc = 0;
    double md = 5;
    if ((rc = pb_get_floats(c, at, pl, "maxdepth", "integer", 1, &md)) >= 0) rc = 0;
    c->maxdepth = (long)md;
    if (rc == 0 && (md < 1 || md > 100000)) rc = pb_fail(c, at, PM_EINVAL, "%s: maxdepth %g outside 1..100000", what, md);
    if (rc == 0) {
        if (strcmp(s, "path") == 0) c->mode = "path";
        else if (strcmp(s, "sppm") == 0) c->mode = "pm";
        else {
            c->mode = "path";
            pb_warn(c, at, "%s is not supported: rendering with \"path\" (path tracing; --mode chooses another)", what);
        }
        for (int k = 0; k < pl->n; k++)
            if (!pl->p[k].used && strcmp(s, "path") != 0) pl->p[k].used = 1; /* settings of another method */
        pb_warn_unused(c, at, what, pl);
    }
    return rc;
}

static int do_pixel_filter(conv *c, const tok *at, const char *s, plist *pl, const char *what) {
    int rc = 0;
    if (strcmp(s, "box") != 0)
        pb_warn(c, at, "%s is not supported: each pixel is the mean of its own samples (a box filter) instead", what);
    for (int k = 0; k < pl->n; k++) pl->p[k].used = 1;
    return rc;
}

static int do_ignored(conv *c, const tok *at, const char *s, plist *pl, const char *what) {
    (void)s, (void)pl;
    pb_warn(c, at, "%s: ignored (does not change the image, or not supported)", what);
    return 0;
}

static int do_light(conv *c, const tok *at, const char *s, plist *pl, const char *what) {
    int rc = 0;
    rgb sc = v3s(1);
    if ((rc = pb_get_color(c, at, pl, "scale", &sc)) >= 0) rc = 0;
    if (rc == 0 && strcmp(s, "point") == 0) {
        rgb I = v3s(1);
        double from[3] = {0, 0, 0};
        if ((rc = pb_get_color(c, at, pl, "I", &I)) >= 0 && (rc = pb_get_floats(c, at, pl, "from", "point", 3, from)) >= 0) {
            rc = 0;
            cJSON *l = cJSON_CreateObject();
            if (!l) return PM_ENOMEM;
            cJSON_AddStringToObject(l, "type", "point");
            cJSON_AddItemToObject(l, "position", pb_jv(pb_out(c, pb_point(c->g.m, v3(from[0], from[1], from[2])))));
            cJSON_AddItemToObject(l, "intensity", pb_jv(v3_mul(I, sc)));
            cJSON_AddItemToArray(c->lights, l);
            pb_warn_unused(c, at, what, pl);
        }
    } else if (rc == 0 && strcmp(s, "distant") == 0) {
        rgb L = v3s(1);
        double from[3] = {0, 0, 0}, to[3] = {0, 0, 1};
        if ((rc = pb_get_color(c, at, pl, "L", &L)) >= 0 && (rc = pb_get_floats(c, at, pl, "from", "point", 3, from)) >= 0 &&
            (rc = pb_get_floats(c, at, pl, "to", "point", 3, to)) >= 0) {
            rc = 0;
            vec3 dir = pb_out(c, pb_dir(c->g.m, v3(to[0] - from[0], to[1] - from[1], to[2] - from[2])));
            if (!(v3_len(dir) > 0)) rc = pb_fail(c, at, PM_EINVAL, "%s: from and to are the same point", what);
            cJSON *l = rc == 0 ? cJSON_CreateObject() : NULL;
            if (l) {
                cJSON_AddStringToObject(l, "type", "directional");
                cJSON_AddItemToObject(l, "direction", pb_jv(v3_norm(dir)));
                cJSON_AddItemToObject(l, "irradiance", pb_jv(v3_mul(L, sc)));
                cJSON_AddItemToArray(c->lights, l);
                pb_warn_unused(c, at, what, pl);
            }
        }
    } else if (rc == 0 && strcmp(s, "spot") == 0) {
        rc = pb_spot_light(c, at, pl, sc, what);
    } else if (rc == 0 && strcmp(s, "infinite") == 0) {
        rc = pb_infinite_light(c, at, pl, sc, what);
    } else if (rc == 0) {
        pb_warn(c, at, "%s is not supported (point, spot, distant, infinite): skipped, so its light is missing", what);
    }
    return rc;
}

/* ---- the table -------------------------------------------------------------------- */

typedef int (*plain_fn)(conv *c, const toks *ts, int *i, const tok *at);
typedef int (*named_fn)(conv *c, const tok *at, const char *s, plist *pl, const char *what);

/* Each directive: a function that reads its own arguments, or one given a name and parameters. */
static const struct {
    const char *name;
    plain_fn plain;
    named_fn named;
} k_directives[] = {
    {"LookAt", do_look_at, NULL},
    {"Translate", do_translate_scale, NULL},
    {"Scale", do_translate_scale, NULL},
    {"Rotate", do_rotate, NULL},
    {"Transform", do_transform, NULL},
    {"ConcatTransform", do_transform, NULL},
    {"Identity", do_identity, NULL},
    {"CoordinateSystem", do_coordsys, NULL},
    {"CoordSysTransform", do_coordsys, NULL},
    {"ReverseOrientation", do_reverse, NULL},
    {"AttributeBegin", do_begin, NULL},
    {"TransformBegin", do_begin, NULL},
    {"AttributeEnd", do_end, NULL},
    {"TransformEnd", do_end, NULL},
    {"WorldBegin", do_world_begin, NULL},
    {"WorldEnd", do_world_end, NULL},
    {"Include", do_include, NULL},
    {"Import", do_include, NULL},
    {"ObjectBegin", do_object_begin, NULL},
    {"ObjectEnd", do_object_end, NULL},
    {"ObjectInstance", do_object_instance, NULL},
    {"Texture", do_texture, NULL},
    {"MediumInterface", pb_do_medium_interface, NULL},
    {"Camera", NULL, do_camera},
    {"Film", NULL, do_film},
    {"Sampler", NULL, do_sampler},
    {"Integrator", NULL, do_integrator},
    {"SurfaceIntegrator", NULL, do_integrator},
    {"PixelFilter", NULL, do_pixel_filter},
    {"Accelerator", NULL, do_ignored},
    {"Renderer", NULL, do_ignored},
    {"VolumeIntegrator", NULL, do_ignored},
    {"ColorSpace", NULL, do_ignored},
    {"Option", NULL, do_ignored},
    {"Shape", NULL, pb_do_shape},
    {"Material", NULL, pb_do_material},
    {"MakeNamedMaterial", NULL, pb_do_material},
    {"NamedMaterial", NULL, pb_do_named_material},
    {"AreaLightSource", NULL, pb_do_area_light},
    {"LightSource", NULL, do_light},
    {"MakeNamedMedium", NULL, pb_do_named_medium},
};

/* A directive with a name and a parameter list: both read, the handler run, the list freed. */
static int run_named(conv *c, const toks *ts, int *i, const tok *at, named_fn fn) {
    const char *d = at->s, *s = NULL;
    plist pl;
    pl.n = 0;
    TRY(pb_one_string(c, ts, i, at, &s, d));
    int rc = pb_read_params(c, ts, i, &pl);
    if (rc < 0) {
        pb_plist_free(&pl);
        return rc;
    }
    char what[160];
    snprintf(what, sizeof what, "%s \"%s\"", d, s);
    rc = fn(c, at, s, &pl, what);
    pb_plist_free(&pl);
    return rc < 0 ? rc : 0;
}

int pb_directive(conv *c, const toks *ts, int *i) {
    const tok *at = &ts->t[*i];
    if (at->kind != K_WORD) {
        if (at->kind == K_LB || at->kind == K_RB)
            return pb_fail(c, at, PM_EINVAL, "unbalanced %s outside a parameter list", at->kind == K_LB ? "[" : "]");
        if (at->kind == K_STR)
            return pb_fail(c, at, PM_EINVAL, "a parameter \"%.40s\" without a directive before it", at->s);
        return pb_fail(c, at, PM_EINVAL, "a number (%g) where a directive was expected", at->num);
    }
    const char *d = at->s;
    (*i)++;
    for (size_t k = 0; k < sizeof k_directives / sizeof *k_directives; k++)
        if (strcmp(d, k_directives[k].name) == 0)
            return k_directives[k].plain ? k_directives[k].plain(c, ts, i, at) : run_named(c, ts, i, at, k_directives[k].named);
    pb_warn(c, at, "unknown directive \"%s\": skipped with its arguments", d);
    while (*i < ts->n && !(ts->t[*i].kind == K_WORD && strcmp(ts->t[*i].s, "true") != 0 && strcmp(ts->t[*i].s, "false") != 0))
        (*i)++;
    return 0;
}

/* ---- running files ---------------------------------------------------------------- */

static int run_tokens(conv *c, const toks *ts) {
    int i = 0;
    while (i < ts->n) TRY(pb_directive(c, ts, &i));
    return 0;
}

int pb_run_text(conv *c, const char *text, const char *name) {
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
    rc = pb_run_text(c, buf, path);
    c->include_depth--;
    free(buf);
    return rc;
}
