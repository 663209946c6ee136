/* tungsten.c: Tungsten scene files to our scene document; see tungsten.h.
 *
 * One pass over the Tungsten document. Bsdfs are collected by name first (primitives refer to
 * them by name, or hold one inline). Every primitive is turned into plain geometry in world
 * space right here (quads and cubes as vertices, spheres as centre and radius); only meshes
 * stay files, with their matrix, because the mesh loader places them. Each key of each object
 * is checked against the list of keys this file understands, so nothing is dropped silently.
 */
#include "load/tungsten_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common.h"
#include "load/mesh.h"
#include "base/sampling.h"
#include "scene/scene.h"

void tungsten_rotation(vec3 deg, double R[3][3]) {
    double x = deg.x * M_PI / 180, y = deg.y * M_PI / 180, z = deg.z * M_PI / 180;
    /* Ry(-y) Rx(x) Rz(z), multiplied out */
    double Rz[3][3] = {{cos(z), -sin(z), 0}, {sin(z), cos(z), 0}, {0, 0, 1}};
    double Rx[3][3] = {{1, 0, 0}, {0, cos(x), -sin(x)}, {0, sin(x), cos(x)}};
    double Ry[3][3] = {{cos(y), 0, -sin(y)}, {0, 1, 0}, {sin(y), 0, cos(y)}};
    double A[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            A[i][j] = 0;
            for (int k = 0; k < 3; k++) A[i][j] += Rx[i][k] * Rz[k][j];
        }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            R[i][j] = 0;
            for (int k = 0; k < 3; k++) R[i][j] += Ry[i][k] * A[k][j];
        }
}

static int read_bsdf(const cJSON *b, const char *P, tbsdf *o, json_err *e) {
    memset(o, 0, sizeof *o);
    if (!cJSON_IsObject(b)) return json_fail(e, PM_EINVAL, "%s: expected an object, got %s", P, json_type_name(b));
    static const char *const ok[] = {"name", "type", "albedo", "ior", "enable_refraction", NULL};
    TRY(json_string(b, P, "type", 1, &o->type, e));
    const char *name = "";
    TRY(json_string(b, P, "name", 0, &name, e));
    if (strlen(name) >= sizeof o->name - 12)
        return json_fail(e, PM_EINVAL, "%s.name: too long (max %d characters)", P, (int)sizeof o->name - 13);
    snprintf(o->name, sizeof o->name, "%s", name);
    o->albedo = v3s(1);
    o->ior = 1.5;
    o->refract = 1;
    if (!tg_in_list(o->type, (const char *const[]){"lambert", "dielectric", "mirror", "null", "forward", NULL}))
        return json_fail(e, PM_EINVAL, "%s.type: bsdf type \"%s\" is not supported (lambert, dielectric, mirror, "
                         "null, forward)", P, o->type);
    TRY(tg_check_keys(NULL, b, P, ok, NULL, "a bsdf key outside the supported subset", e));
    TRY(tg_color(b, P, "albedo", &o->albedo, e));
    if (o->albedo.x < 0 || o->albedo.y < 0 || o->albedo.z < 0 || o->albedo.x > 1 || o->albedo.y > 1 ||
        o->albedo.z > 1)
        return json_fail(e, PM_EINVAL, "%s.albedo: each component must be in [0, 1] (got [%g, %g, %g])", P,
                         o->albedo.x, o->albedo.y, o->albedo.z);
    if (strcmp(o->type, "dielectric") == 0) {
        TRY(json_number(b, P, "ior", 0, &o->ior, e));
        if (!(o->ior > 0)) return json_fail(e, PM_EINVAL, "%s.ior: must be positive, got %g", P, o->ior);
        TRY(json_bool(b, P, "enable_refraction", 0, &o->refract, e));
    } else if (json_get(b, "ior") || json_get(b, "enable_refraction")) {
        return json_fail(e, PM_EINVAL, "%s: ior and enable_refraction belong to a dielectric", P);
    }
    return 0;
}

/* Our material for bsdf b, with emission Le (zero: none). */
static cJSON *material_json(const tbsdf *b, rgb Le) {
    cJSON *m = cJSON_CreateObject();
    if (!m) return NULL;
    int white = b->albedo.x == 1 && b->albedo.y == 1 && b->albedo.z == 1;
    if (strcmp(b->type, "boundary") == 0) { /* a null or forward surface between media */
        cJSON_AddStringToObject(m, "type", "null");
        return m;
    }
    if (strcmp(b->type, "lambert") == 0) {
        cJSON_AddStringToObject(m, "type", "lambert");
        cJSON_AddItemToObject(m, "reflectance", tg_jvec(b->albedo));
    } else if (strcmp(b->type, "mirror") == 0) {
        cJSON_AddStringToObject(m, "type", "mirror");
        cJSON_AddItemToObject(m, "reflectance", tg_jvec(b->albedo));
    } else if (strcmp(b->type, "dielectric") == 0 && b->refract && white) {
        cJSON_AddStringToObject(m, "type", "dielectric");
        cJSON_AddNumberToObject(m, "ior", b->ior);
    } else if (strcmp(b->type, "dielectric") == 0) {
        /* Tungsten's albedo tints both branches; without refraction the transmitted part is lost */
        cJSON_AddStringToObject(m, "type", "mix");
        cJSON_AddStringToObject(m, "specular", "fresnel");
        cJSON_AddNumberToObject(m, "transparency", b->refract ? 1 : 0);
        cJSON_AddNumberToObject(m, "ior", b->ior);
        cJSON_AddItemToObject(m, "specular_tint", tg_jvec(b->albedo));
        cJSON_AddItemToObject(m, "transmit_tint", tg_jvec(b->albedo));
        cJSON_AddItemToObject(m, "diffuse", tg_jvec(v3s(0)));
    } else { /* null or forward that emits: a black emitter */
        cJSON_AddStringToObject(m, "type", "lambert");
        cJSON_AddItemToObject(m, "reflectance", tg_jvec(v3s(0)));
    }
    if (!v3_iszero(Le)) cJSON_AddItemToObject(m, "emission", tg_jvec(Le));
    return m;
}

static vec3 xf_point(double M[3][4], vec3 p) {
    return v3(M[0][0] * p.x + M[0][1] * p.y + M[0][2] * p.z + M[0][3],
              M[1][0] * p.x + M[1][1] * p.y + M[1][2] * p.z + M[1][3],
              M[2][0] * p.x + M[2][1] * p.y + M[2][2] * p.z + M[2][3]);
}
static vec3 xf_col(double M[3][4], int c) { return v3(M[0][c], M[1][c], M[2][c]); }

int tungsten_transform(const cJSON *t, const char *path, double M[3][4], json_err *e) {
    memset(M, 0, 12 * sizeof(double));
    M[0][0] = M[1][1] = M[2][2] = 1;
    if (!t) return 0;
    if (cJSON_IsArray(t)) { /* a 4x4 matrix, row by row */
        if (cJSON_GetArraySize(t) != 16)
            return json_fail(e, PM_EINVAL, "%s: a matrix needs 16 numbers, got %d", path, cJSON_GetArraySize(t));
        double a[16];
        int i = 0;
        for (const cJSON *it = t->child; it; it = it->next, i++) {
            if (!cJSON_IsNumber(it) || !isfinite(it->valuedouble))
                return json_fail(e, PM_EINVAL, "%s[%d]: expected a finite number", path, i);
            a[i] = it->valuedouble;
        }
        if (a[12] != 0 || a[13] != 0 || a[14] != 0 || a[15] != 1)
            return json_fail(e, PM_EINVAL, "%s: the last row must be 0 0 0 1 (projective matrices are not supported)", path);
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 4; c++) M[r][c] = a[4 * r + c];
        return 0;
    }
    if (!cJSON_IsObject(t)) return json_fail(e, PM_EINVAL, "%s: expected an object or 16 numbers, got %s", path, json_type_name(t));
    static const char *const ok[] = {"position", "scale", "rotation", NULL};
    TRY(tg_check_keys(NULL, t, path, ok, NULL, "a primitive's transform takes position, scale and rotation", e));
    vec3 pos = v3s(0), scale = v3s(1), rot = v3s(0);
    TRY(json_vec3(t, path, "position", 0, &pos, e));
    const cJSON *s = json_get(t, "scale");
    if (s && cJSON_IsNumber(s)) {
        double k;
        TRY(json_number(t, path, "scale", 1, &k, e));
        scale = v3s(k);
    } else {
        TRY(json_vec3(t, path, "scale", 0, &scale, e));
    }
    TRY(json_vec3(t, path, "rotation", 0, &rot, e));
    double R[3][3];
    tungsten_rotation(rot, R);
    double sc[3] = {scale.x, scale.y, scale.z};
    for (int r = 0; r < 3; r++) {
        for (int c = 0; c < 3; c++) M[r][c] = R[r][c] * sc[c];
    }
    M[0][3] = pos.x;
    M[1][3] = pos.y;
    M[2][3] = pos.z;
    return 0;
}

/* The bsdf of a primitive: a name or an inline object. */
static int prim_bsdf(conv *c, const cJSON *p, const char *P, int index, tbsdf *out, json_err *e) {
    const cJSON *b = json_get(p, "bsdf");
    char bp[P_MAX];
    json_path_key(bp, sizeof bp, P, "bsdf");
    if (!b) return json_fail(e, PM_EINVAL, "%s: missing (required)", bp);
    if (cJSON_IsArray(b)) {
        if (cJSON_GetArraySize(b) != 1)
            return json_fail(e, PM_EINVAL, "%s: one bsdf per primitive is supported (per-triangle bsdf lists are not)", bp);
        b = b->child;
        json_path_index(bp, sizeof bp, bp, 0);
    }
    if (cJSON_IsString(b)) {
        for (int i = 0; i < c->nbsdfs; i++)
            if (strcmp(c->bsdfs[i].name, b->valuestring) == 0) {
                *out = c->bsdfs[i];
                return 0;
            }
        return json_fail(e, PM_EINVAL, "%s: unknown bsdf \"%s\"", bp, b->valuestring);
    }
    TRY(read_bsdf(b, bp, out, e));
    snprintf(out->name, sizeof out->name, "primitive%d", index);
    return 0;
}

static int add_material(conv *c, const char *name, const tbsdf *b, rgb Le, json_err *e) {
    if (cJSON_GetObjectItemCaseSensitive(c->mats, name)) return 0;
    cJSON *m = material_json(b, Le);
    if (!m) return json_fail(e, PM_ENOMEM, "out of memory");
    cJSON_AddItemToObject(c->mats, name, m);
    return 0;
}

static cJSON *quad_json(vec3 v0, vec3 v1, vec3 v2, vec3 v3_, const char *mat) {
    cJSON *o = cJSON_CreateObject(), *vs = cJSON_CreateArray();
    cJSON_AddStringToObject(o, "type", "quad");
    cJSON_AddItemToArray(vs, tg_jvec(v0));
    cJSON_AddItemToArray(vs, tg_jvec(v1));
    cJSON_AddItemToArray(vs, tg_jvec(v2));
    cJSON_AddItemToArray(vs, tg_jvec(v3_));
    cJSON_AddItemToObject(o, "vertices", vs);
    cJSON_AddStringToObject(o, "material", mat);
    return o;
}

/* A cube: the unit cube under M as a closed mesh wound to face out; *area its surface. */
static int cube_obj(double M[3][4], const char *mat, const char *tp, cJSON **made, double *area, json_err *e) {
    vec3 ctr = xf_point(M, v3s(0)), corner[8];
    for (int i = 0; i < 8; i++)
        corner[i] = xf_point(M, v3(i & 1 ? 0.5 : -0.5, i & 2 ? 0.5 : -0.5, i & 4 ? 0.5 : -0.5));
    static const int face[6][4] = {{0, 2, 6, 4}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 5, 7, 6}};
    cJSON *obj = *made = cJSON_CreateObject();
    cJSON *vs = cJSON_CreateArray(), *ts = cJSON_CreateArray();
    cJSON_AddStringToObject(obj, "type", "mesh");
    for (int i = 0; i < 8; i++) cJSON_AddItemToArray(vs, tg_jvec(corner[i]));
    for (int f = 0; f < 6; f++) {
        const int *q = face[f];
        vec3 n = v3_cross(v3_sub(corner[q[1]], corner[q[0]]), v3_sub(corner[q[2]], corner[q[0]]));
        vec3 fc = v3_scale(v3_add(corner[q[0]], corner[q[2]]), 0.5);
        *area += v3_len(n);
        int out = v3_dot(n, v3_sub(fc, ctr)) > 0; /* wind so the front faces out */
        int t1[3] = {q[0], out ? q[1] : q[2], out ? q[2] : q[1]};
        int t2[3] = {q[0], out ? q[2] : q[3], out ? q[3] : q[2]};
        cJSON_AddItemToArray(ts, cJSON_CreateIntArray(t1, 3));
        cJSON_AddItemToArray(ts, cJSON_CreateIntArray(t2, 3));
    }
    if (!(*area > 0)) {
        *made = NULL;
        cJSON_Delete(vs);
        cJSON_Delete(ts);
        cJSON_Delete(obj);
        return json_fail(e, PM_EINVAL, "%s: the cube has zero area", tp);
    }
    cJSON_AddItemToObject(obj, "vertices", vs);
    cJSON_AddItemToObject(obj, "triangles", ts);
    cJSON_AddStringToObject(obj, "material", mat);
    return 0;
}

/* A mesh file with its matrix (the mesh loader places it); with power, *area is its area. */
static int mesh_obj(conv *c, const cJSON *p, const char *P, double M[3][4], const char *mat, int has_p, int smooth,
                    int recompute, cJSON **made, double *area, json_err *e) {
    const char *file;
    TRY(json_string(p, P, "file", 1, &file, e));
    char path[4096];
    if (file[0] == '/' || !c->dir || !c->dir[0])
        snprintf(path, sizeof path, "%s", file);
    else
        snprintf(path, sizeof path, "%s/%s", c->dir, file);
    if (has_p) { /* power needs the area: load the mesh once here */
        mesh_data md;
        char err[400];
        if (mesh_load(path, &md, err, sizeof err) < 0 || mesh_transform(&md, (const double(*)[4])M, path, err, sizeof err) < 0) {
            mesh_free(&md);
            return json_fail(e, PM_EINVAL, "%s.file: %s", P, err);
        }
        *area = mesh_area(&md);
        mesh_free(&md);
    }
    cJSON *obj = *made = cJSON_CreateObject();
    cJSON_AddStringToObject(obj, "type", "mesh");
    cJSON_AddStringToObject(obj, "file", file); /* scene_import joins it to the directory */
    cJSON_AddStringToObject(obj, "material", mat);
    double a16[16] = {M[0][0], M[0][1], M[0][2], M[0][3], M[1][0], M[1][1], M[1][2], M[1][3],
                      M[2][0], M[2][1], M[2][2], M[2][3], 0, 0, 0, 1};
    cJSON_AddItemToObject(obj, "transform", cJSON_CreateDoubleArray(a16, 16));
    cJSON_AddBoolToObject(obj, "smooth", smooth);
    cJSON_AddBoolToObject(obj, "recompute_normals", recompute);
    cJSON_AddBoolToObject(obj, "usemtl", 0); /* Tungsten reads geometry only from an OBJ */
    return 0;
}

/* An infinite_sphere or a point: a light of ours, no object. Both take emission or power,
 * and both turn power into emission by 1 / (4 pi) as Tungsten does: an infinite_sphere's
 * emission is a radiance (our infinite light; its transform turns a constant nothing), a
 * point's a radiant intensity (W/sr: our point light's intensity, at the transform's
 * translation). */
static int light_primitive(conv *c, const cJSON *p, const char *P, int point, json_err *e) {
    static const char *const ok[] = {"name", "type", "transform", "emission", "power", "sample", NULL};
    TRY(tg_check_keys(c->file, p, P, ok, NULL,
                      point ? "a key of a point outside the supported subset" : "a key of an infinite_sphere outside the supported subset", e));
    rgb Le = v3s(0), power = v3s(0);
    if (json_get(p, "emission") && json_get(p, "power")) return json_fail(e, PM_EINVAL, "%s: give emission or power, not both", P);
    TRY(tg_color(p, P, "emission", &Le, e));
    TRY(tg_color(p, P, "power", &power, e));
    if (json_get(p, "power")) Le = v3_scale(power, 1 / (4 * M_PI));
    if (Le.x < 0 || Le.y < 0 || Le.z < 0)
        return json_fail(e, PM_EINVAL, "%s.%s: must not be negative", P, json_get(p, "power") ? "power" : "emission");
    double M[3][4];
    if (point) {
        char tp[P_MAX];
        json_path_key(tp, sizeof tp, P, "transform");
        TRY(tungsten_transform(json_get(p, "transform"), tp, M, e));
    }
    cJSON *ls = cJSON_GetObjectItemCaseSensitive(c->out, "lights"), *l = cJSON_CreateObject();
    if (!ls && (ls = cJSON_CreateArray()) != NULL) cJSON_AddItemToObject(c->out, "lights", ls);
    if (!ls || !l) {
        cJSON_Delete(l);
        return json_fail(e, PM_ENOMEM, "out of memory");
    }
    cJSON_AddStringToObject(l, "type", point ? "point" : "infinite");
    if (point) cJSON_AddItemToObject(l, "position", tg_jvec(xf_point(M, v3s(0))));
    cJSON_AddItemToObject(l, point ? "intensity" : "radiance", tg_jvec(Le));
    cJSON_AddItemToArray(ls, l);
    return 0;
}

static int convert_primitive(conv *c, const cJSON *p, const char *P, int index, json_err *e) {
    if (!cJSON_IsObject(p)) return json_fail(e, PM_EINVAL, "%s: expected an object, got %s", P, json_type_name(p));
    const char *type;
    TRY(json_string(p, P, "type", 1, &type, e));
    if (strcmp(type, "infinite_sphere") == 0 || strcmp(type, "point") == 0)
        return light_primitive(c, p, P, strcmp(type, "point") == 0, e);
    static const char *const common[] = {"name", "type", "transform", "bsdf", "emission", "power",
                                         "file", "smooth", "recompute_normals", "backface_culling",
                                         "int_medium", "ext_medium", NULL};
    if (json_get(p, "bump")) return json_fail(e, PM_EINVAL, "%s.bump: bump maps are not supported", P);
    int is_mesh = strcmp(type, "mesh") == 0;
    if (!is_mesh && strcmp(type, "quad") != 0 && strcmp(type, "cube") != 0 && strcmp(type, "sphere") != 0)
        return json_fail(e, PM_EINVAL, "%s.type: primitive type \"%s\" is not supported (quad, cube, sphere, mesh, infinite_sphere, point)",
                         P, type);
    TRY(tg_check_keys(NULL, p, P, common, NULL, "a primitive key outside the supported subset", e));
    if (!is_mesh)
        for (const char *const *k = (const char *const[]){"file", "smooth", "recompute_normals", "backface_culling", NULL}; *k; k++)
            if (json_get(p, *k)) return json_fail(e, PM_EINVAL, "%s.%s: only a mesh has this key", P, *k);
    char tp[P_MAX];
    json_path_key(tp, sizeof tp, P, "transform");
    double M[3][4];
    TRY(tungsten_transform(json_get(p, "transform"), tp, M, e));
    tbsdf b;
    TRY(prim_bsdf(c, p, P, index, &b, e));
    rgb Le = v3s(0), power = v3s(0);
    int has_e = json_get(p, "emission") != NULL, has_p = json_get(p, "power") != NULL;
    if (has_e && has_p) return json_fail(e, PM_EINVAL, "%s: give emission or power, not both", P);
    TRY(tg_color(p, P, "emission", &Le, e));
    TRY(tg_color(p, P, "power", &power, e));
    if (Le.x < 0 || Le.y < 0 || Le.z < 0 || power.x < 0 || power.y < 0 || power.z < 0)
        return json_fail(e, PM_EINVAL, "%s.%s: must not be negative", P, has_e ? "emission" : "power");
    int emits = !v3_iszero(Le) || !v3_iszero(power);
    int invisible = strcmp(b.type, "null") == 0 || strcmp(b.type, "forward") == 0;
    /* Media (tungsten.h): a primitive that names int_medium or ext_medium is an interface
     * (the one it does not name: no medium); one that names neither keeps the ray's medium. */
    const cJSON *im = json_get(p, "int_medium"), *xm = json_get(p, "ext_medium");
    int imed, xmed, passes = invisible || (strcmp(b.type, "dielectric") == 0 && b.refract);
    int declared = (im || xm) && passes;
    char mp[P_MAX];
    json_path_key(mp, sizeof mp, P, "int_medium");
    TRY(tg_medium_ref(c, im, mp, &imed, e));
    json_path_key(mp, sizeof mp, P, "ext_medium");
    TRY(tg_medium_ref(c, xm, mp, &xmed, e));
    /* Tungsten uses the media of a surface light cannot cross only for what it emits: an
     * emitter's ext_medium is all around it; otherwise such a surface keeps the ray's. */
    if (!passes && emits && xmed >= 0) imed = xmed, declared = 1;
    if (invisible && emits && (im || xm))
        return json_fail(e, PM_EINVAL, "%s.emission: an emitting \"%s\" medium boundary is not supported", P, b.type);
    if (invisible && !emits && !declared) return 0; /* changes nothing: dropped (tungsten.h) */
    if (invisible && !emits) {
        snprintf(b.name, sizeof b.name, "%s", "boundary");
        b.type = "boundary";
    }
    if (invisible && emits)
        tg_warn(c->file, "%s.bsdf: a \"%s\" surface that emits becomes an opaque black emitter "
              "(it blocks the light behind it; in Tungsten light passes through)", P, b.type);
    int smooth = 0, recompute = 0, cull = 0;
    if (is_mesh) {
        TRY(json_bool(p, P, "smooth", 0, &smooth, e));
        TRY(json_bool(p, P, "recompute_normals", 0, &recompute, e));
        TRY(json_bool(p, P, "backface_culling", 0, &cull, e));
        if (cull) return json_fail(e, PM_EINVAL, "%s.backface_culling: true is not supported", P);
    }
    /* Geometry, and its area for power -> radiance. */
    cJSON *obj = NULL;
    double area = 0;
    char mat[64];
    snprintf(mat, sizeof mat, "%s", b.name[0] ? b.name : "unnamed");
    if (emits) snprintf(mat, sizeof mat, "%.40s.emitter%d", b.name[0] ? b.name : "bsdf", c->nemit++ % 100000);
    if (strcmp(type, "quad") == 0) {
        vec3 e0 = xf_col(M, 0), e1 = xf_col(M, 2);
        vec3 base = v3_sub(xf_point(M, v3s(0)), v3_scale(v3_add(e0, e1), 0.5));
        area = v3_len(v3_cross(e1, e0));
        if (!(area > 0)) return json_fail(e, PM_EINVAL, "%s: the quad has zero area", tp);
        /* front = e1 x e0, Tungsten's normal (see shapes.h for ours) */
        obj = quad_json(base, v3_add(base, e1), v3_add(v3_add(base, e0), e1), v3_add(base, e0), mat);
    } else if (strcmp(type, "cube") == 0) {
        TRY(cube_obj(M, mat, tp, &obj, &area, e));
    } else if (strcmp(type, "sphere") == 0) {
        double r = fmax(v3_len(xf_col(M, 0)), fmax(v3_len(xf_col(M, 1)), v3_len(xf_col(M, 2))));
        if (!(r > 0)) return json_fail(e, PM_EINVAL, "%s: the sphere has radius 0", tp);
        area = 4 * M_PI * r * r;
        obj = cJSON_CreateObject();
        cJSON_AddStringToObject(obj, "type", "sphere");
        cJSON_AddItemToObject(obj, "center", tg_jvec(xf_point(M, v3s(0))));
        cJSON_AddNumberToObject(obj, "radius", r);
        cJSON_AddStringToObject(obj, "material", mat);
    } else {
        TRY(mesh_obj(c, p, P, M, mat, has_p, smooth, recompute, &obj, &area, e));
    }
    if (!obj) return json_fail(e, PM_ENOMEM, "out of memory");
    if (has_p) Le = v3_scale(power, 1.0 / (M_PI * area));
    /* Our emission's range (scene.h): a radiance at most SCENE_RADIANCE_MAX. */
    if (!(v3_maxabs(Le) <= SCENE_RADIANCE_MAX)) {
        cJSON_Delete(obj);
        if (has_p)
            return json_fail(e, PM_EINVAL, "%s.power: %g gives the radiance %g (power / (pi area), area "
                             "%g), outside the supported range, 0 to %g (the image is stored in 32-bit "
                             "floats)", P, v3_maxabs(power), v3_maxabs(Le), area, SCENE_RADIANCE_MAX);
        return json_fail(e, PM_EINVAL, "%s.emission: %g is outside the supported range, 0 to %g (the "
                         "image is stored in 32-bit floats)", P, v3_maxabs(Le), SCENE_RADIANCE_MAX);
    }
    const char *pname = NULL;
    if (json_string(p, P, "name", 0, &pname, e) < 0) pname = NULL;
    if (pname) cJSON_AddStringToObject(obj, "name", pname);
    if (declared) {
        cJSON_AddItemToObject(obj, "interior_medium", imed >= 0 ? cJSON_CreateString(c->mnames[imed]) : cJSON_CreateNull());
        if (xmed >= 0) cJSON_AddStringToObject(obj, "exterior_medium", c->mnames[xmed]); /* else the camera's */
    }
    cJSON_AddItemToArray(c->objs, obj);
    return add_material(c, mat, &b, emits ? Le : v3s(0), e);
}

int tungsten_is_scene(const cJSON *root) {
    return cJSON_IsObject(root) && (json_get(root, "bsdfs") || json_get(root, "primitives")) &&
           !json_get(root, "materials") && !json_get(root, "objects");
}

static int convert(const cJSON *root, const char *dir, const char *file, cJSON *out, json_err *e) {
    static const char *const ok[] = {"media", "bsdfs", "primitives", "camera", "integrator", "renderer", NULL};
    TRY(tg_check_keys(NULL, root, "$", ok, NULL, "a top-level key outside the supported subset", e));
    const cJSON *media, *bsdfs, *prims;
    TRY(json_array(root, "$", "media", 0, &media, e));
    TRY(json_array(root, "$", "bsdfs", 0, &bsdfs, e));
    TRY(json_array(root, "$", "primitives", 1, &prims, e));
    conv c = {0};
    c.dir = dir;
    c.file = file;
    c.out = out;
    int rc = 0, i = 0;
    char p[P_MAX];
    c.bsdfs = calloc((size_t)(bsdfs ? cJSON_GetArraySize(bsdfs) : 0) + 1, sizeof *c.bsdfs);
    if (!c.bsdfs) return json_fail(e, PM_ENOMEM, "out of memory");
    for (const cJSON *b = bsdfs ? bsdfs->child : NULL; b && rc == 0; b = b->next, i++) {
        json_path_index(p, sizeof p, "$.bsdfs", i);
        rc = read_bsdf(b, p, &c.bsdfs[c.nbsdfs], e);
        if (rc == 0 && !c.bsdfs[c.nbsdfs].name[0])
            rc = json_fail(e, PM_EINVAL, "%s.name: missing (a bsdf in the list needs a name)", p);
        for (int k = 0; k < c.nbsdfs && rc == 0; k++)
            if (strcmp(c.bsdfs[k].name, c.bsdfs[c.nbsdfs].name) == 0)
                rc = json_fail(e, PM_EINVAL, "%s.name: \"%s\" is used twice", p, c.bsdfs[k].name);
        c.nbsdfs++;
    }
    long spp = 0;
    c.global = -1;
    if (rc == 0) rc = tg_convert_settings(file, root, out, &spp, &c.max_depth, e);
    if (rc == 0) rc = tg_convert_camera(file, root, out, spp, e);
    i = 0;
    for (const cJSON *m = media ? media->child : NULL; m && rc == 0; m = m->next, i++) {
        int idx;
        const char *name = NULL;
        json_path_index(p, sizeof p, "$.media", i);
        rc = cJSON_IsObject(m) ? json_string(m, p, "name", 1, &name, e) : 0;
        if (rc == 0) rc = tg_read_medium(&c, m, p, name ? name : "", &idx, e);
    }
    const cJSON *cam = json_get(root, "camera");
    if (rc == 0 && cam) rc = tg_medium_ref(&c, json_get(cam, "medium"), "$.camera.medium", &c.global, e);
    c.mats = cJSON_CreateObject();
    c.objs = cJSON_CreateArray();
    if (c.mats) cJSON_AddItemToObject(out, "materials", c.mats);
    if (c.objs) cJSON_AddItemToObject(out, "objects", c.objs);
    if (rc == 0 && (!c.mats || !c.objs)) rc = json_fail(e, PM_ENOMEM, "out of memory");
    i = 0;
    for (const cJSON *pr = prims->child; pr && rc == 0; pr = pr->next, i++) {
        json_path_index(p, sizeof p, "$.primitives", i);
        rc = convert_primitive(&c, pr, p, i, e);
    }
    /* With media, a primitive that names none keeps the ray's medium (tungsten.h). */
    for (cJSON *o = c.objs && c.nmedia > 0 ? c.objs->child : NULL; o && rc == 0; o = o->next)
        if (!json_get(o, "interior_medium")) cJSON_AddBoolToObject(o, "keeps_medium", 1);
    free(c.bsdfs);
    if (c.media) cJSON_AddItemToObject(out, "media", c.media); /* owned by out from here */
    if (rc == 0 && c.global >= 0) cJSON_AddStringToObject(out, "medium", c.mnames[c.global]);
    return rc;
}

int tungsten_convert(const cJSON *root, const char *dir, const char *file, cJSON **out, json_err *e) {
    *out = cJSON_CreateObject();
    if (!*out) return json_fail(e, PM_ENOMEM, "out of memory");
    cJSON_AddStringToObject(*out, "description", "converted from a Tungsten scene by render");
    int rc = convert(root, dir, file, *out, e);
    if (rc < 0) {
        cJSON_Delete(*out);
        *out = NULL;
    }
    return rc;
}
