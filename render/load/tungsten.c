/* tungsten.c: Tungsten scene files to our scene document; see tungsten.h.
 *
 * One pass over the Tungsten document. Bsdfs are collected by name first (primitives refer to
 * them by name, or hold one inline). Every primitive is turned into plain geometry in world
 * space right here (quads and cubes as vertices, spheres as centre and radius); only meshes
 * stay files, with their matrix, because the mesh loader places them. Each key of each object
 * is checked against the list of keys this file understands, so nothing is dropped silently.
 */
#include "load/tungsten.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common.h"
#include "load/mesh.h"
#include "base/sampling.h"
#include "scene/scene.h"

#define P_MAX 256

#define TRY(x) JSON_TRY(x)

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

/* Is key one of the NULL-terminated list? */
static int in_list(const char *key, const char *const *list) {
    for (; *list; list++)
        if (strcmp(key, *list) == 0) return 1;
    return 0;
}

/* A warning on stderr that names the scene file (NULL: a scene given as text), as render's
 * own warnings do: "render: FILE: warning: ...". */
static void twarn(const char *file, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "render: %s%swarning: ", file ? file : "", file ? ": " : "");
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

/* Check every key of obj: in `ok` (handled by the caller), in `warn` (ignored with a warning
 * naming the file: they do not change the image), else an error naming the key and `what`. */
static int check_keys(const char *file, const cJSON *obj, const char *P, const char *const *ok,
                      const char *const *warn, const char *what, json_err *e) {
    for (const cJSON *it = obj->child; it; it = it->next) {
        const char *k = it->string ? it->string : "?";
        if (in_list(k, ok)) continue;
        if (warn && in_list(k, warn)) {
            twarn(file, "%s.%s: ignored (does not change the image)", P, k);
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
static int tcolor(const cJSON *obj, const char *P, const char *key, rgb *out, json_err *e) {
    const cJSON *it = json_get(obj, key);
    if (it && (cJSON_IsString(it) || cJSON_IsObject(it)))
        return json_fail(e, PM_EINVAL, "%s.%s: textures are not supported (give a number or [r, g, b])", P, key);
    return json_rgb(obj, P, key, 0, out, e);
}

static cJSON *jvec(vec3 v) {
    double a[3] = {v.x, v.y, v.z};
    return cJSON_CreateDoubleArray(a, 3);
}

typedef struct tbsdf {
    char name[64];
    const char *type; /* lambert, dielectric, mirror, null, forward */
    rgb albedo;
    double ior;
    int refract;
} tbsdf;

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
    if (!in_list(o->type, (const char *const[]){"lambert", "dielectric", "mirror", "null", "forward", NULL}))
        return json_fail(e, PM_EINVAL, "%s.type: bsdf type \"%s\" is not supported (lambert, dielectric, mirror, "
                         "null, forward)", P, o->type);
    TRY(check_keys(NULL, b, P, ok, NULL, "a bsdf key outside the supported subset", e));
    TRY(tcolor(b, P, "albedo", &o->albedo, e));
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
        cJSON_AddItemToObject(m, "reflectance", jvec(b->albedo));
    } else if (strcmp(b->type, "mirror") == 0) {
        cJSON_AddStringToObject(m, "type", "mirror");
        cJSON_AddItemToObject(m, "reflectance", jvec(b->albedo));
    } else if (strcmp(b->type, "dielectric") == 0 && b->refract && white) {
        cJSON_AddStringToObject(m, "type", "dielectric");
        cJSON_AddNumberToObject(m, "ior", b->ior);
    } else if (strcmp(b->type, "dielectric") == 0) {
        /* Tungsten's albedo tints both branches; without refraction the transmitted part is lost */
        cJSON_AddStringToObject(m, "type", "mix");
        cJSON_AddStringToObject(m, "specular", "fresnel");
        cJSON_AddNumberToObject(m, "transparency", b->refract ? 1 : 0);
        cJSON_AddNumberToObject(m, "ior", b->ior);
        cJSON_AddItemToObject(m, "specular_tint", jvec(b->albedo));
        cJSON_AddItemToObject(m, "transmit_tint", jvec(b->albedo));
        cJSON_AddItemToObject(m, "diffuse", jvec(v3s(0)));
    } else { /* null or forward that emits: a black emitter */
        cJSON_AddStringToObject(m, "type", "lambert");
        cJSON_AddItemToObject(m, "reflectance", jvec(v3s(0)));
    }
    if (!v3_iszero(Le)) cJSON_AddItemToObject(m, "emission", jvec(Le));
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
    TRY(check_keys(NULL, t, path, ok, NULL, "a primitive's transform takes position, scale and rotation", e));
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
    /* Quads that light passes through with a medium behind them, merged into one mesh per
     * (medium, material) at the end: a box of such quads bounds its medium (tungsten.h). */
    struct qgroup {
        int medium;
        char mat[64];
        cJSON *verts, *tris;
        int nq;
        char first[P_MAX]; /* the first quad's JSON path, for messages */
    } qg[16];
    int nqg;
} conv;

/* One Tungsten medium object at path P into our media under the name `name`; its index in
 * *idx. Homogeneous only: sigma = sigma_a|sigma_s times density, the phase function isotropic
 * or Henyey-Greenstein. */
static int read_medium(conv *c, const cJSON *m, const char *P, const char *name, int *idx, json_err *e) {
    if (!cJSON_IsObject(m)) return json_fail(e, PM_EINVAL, "%s: expected an object or a medium name, got %s", P, json_type_name(m));
    static const char *const ok[] = {"name", "type", "sigma_a", "sigma_s", "density", "phase_function", "max_bounces", NULL};
    const char *type = "homogeneous";
    TRY(json_string(m, P, "type", 1, &type, e));
    if (strcmp(type, "homogeneous") != 0)
        return json_fail(e, PM_EINVAL, "%s.type: medium type \"%s\" is not supported (homogeneous)", P, type);
    TRY(check_keys(NULL, m, P, ok, NULL, "a medium key outside the supported subset", e));
    if (c->nmedia == T_MEDIA) return json_fail(e, PM_EINVAL, "%s: more than %d media", P, T_MEDIA);
    if (strlen(name) >= sizeof c->mnames[0]) return json_fail(e, PM_EINVAL, "%s.name: too long (max 63 characters)", P);
    for (int i = 0; i < c->nmedia; i++)
        if (strcmp(c->mnames[i], name) == 0) return json_fail(e, PM_EINVAL, "%s.name: \"%s\" is used twice", P, name);
    rgb sa = v3s(0), ss = v3s(0);
    double density = 1, g = 0;
    TRY(tcolor(m, P, "sigma_a", &sa, e));
    TRY(tcolor(m, P, "sigma_s", &ss, e));
    TRY(json_number(m, P, "density", 0, &density, e));
    if (sa.x < 0 || sa.y < 0 || sa.z < 0) return json_fail(e, PM_EINVAL, "%s.sigma_a: must not be negative", P);
    if (ss.x < 0 || ss.y < 0 || ss.z < 0) return json_fail(e, PM_EINVAL, "%s.sigma_s: must not be negative", P);
    if (!(density >= 0)) return json_fail(e, PM_EINVAL, "%s.density: must not be negative, got %g", P, density);
    /* Our media's range (scene.h): a coefficient at most 1 / SCENE_LENGTH_MIN per unit length. */
    double smax = fmax(v3_maxabs(sa), v3_maxabs(ss)) * density;
    if (smax > 1 / SCENE_LENGTH_MIN)
        return json_fail(e, PM_EINVAL, "%s: sigma_a or sigma_s times density is %g, outside the supported "
                         "range, 0 to %g per unit length (a mean free path of at least %g)", P, smax,
                         1 / SCENE_LENGTH_MIN, SCENE_LENGTH_MIN);
    const cJSON *ph = json_get(m, "phase_function");
    char pp[P_MAX];
    json_path_key(pp, sizeof pp, P, "phase_function");
    if (ph) {
        const char *pt = NULL;
        if (cJSON_IsString(ph)) {
            pt = ph->valuestring;
        } else if (cJSON_IsObject(ph)) {
            static const char *const pok[] = {"type", "g", NULL};
            TRY(json_string(ph, pp, "type", 1, &pt, e));
            TRY(check_keys(NULL, ph, pp, pok, NULL, "a phase function takes type and g", e));
            TRY(json_number(ph, pp, "g", 0, &g, e));
        } else {
            return json_fail(e, PM_EINVAL, "%s: expected an object or a type name, got %s", pp, json_type_name(ph));
        }
        if (strcmp(pt, "isotropic") == 0) {
            if (g != 0) return json_fail(e, PM_EINVAL, "%s.g: an isotropic phase function has no g", pp);
        } else if (strcmp(pt, "henyey_greenstein") != 0) {
            return json_fail(e, PM_EINVAL, "%s%s: phase function \"%s\" is not supported (isotropic, henyey_greenstein)",
                             pp, cJSON_IsObject(ph) ? ".type" : "", pt);
        }
        if (!(g > -1 && g < 1)) return json_fail(e, PM_EINVAL, "%s.g: must be in (-1, 1), got %g", pp, g);
    }
    long mb = 1024; /* Tungsten's default */
    TRY(json_int(m, P, "max_bounces", 0, 0, 1L << 30, &mb, e));
    if (mb < c->max_depth)
        return json_fail(e, PM_EINVAL, "%s.max_bounces: %ld, below the integrator's max_bounces (%ld): a separate "
                         "limit for scattering in a medium is not supported", P, mb, c->max_depth);
    if (!c->media && !(c->media = cJSON_CreateObject())) return json_fail(e, PM_ENOMEM, "out of memory");
    cJSON *o = cJSON_CreateObject();
    if (!o) return json_fail(e, PM_ENOMEM, "out of memory");
    cJSON_AddItemToObject(o, "sigma_a", jvec(v3_scale(sa, density)));
    cJSON_AddItemToObject(o, "sigma_s", jvec(v3_scale(ss, density)));
    cJSON_AddNumberToObject(o, "g", g);
    cJSON_AddItemToObject(c->media, name, o);
    snprintf(c->mnames[c->nmedia], sizeof c->mnames[0], "%s", name);
    *idx = c->nmedia++;
    return 0;
}

/* A medium reference at path P (Tungsten's fetchMedium): a name from $.media, or an inline
 * medium object (named after its path). *idx = -1 when v is NULL. */
static int medium_ref(conv *c, const cJSON *v, const char *P, int *idx, json_err *e) {
    *idx = -1;
    if (!v) return 0;
    if (cJSON_IsString(v)) {
        for (int i = 0; i < c->nmedia; i++)
            if (strcmp(c->mnames[i], v->valuestring) == 0) {
                *idx = i;
                return 0;
            }
        return json_fail(e, PM_EINVAL, "%s: unknown medium \"%s\"", P, v->valuestring);
    }
    return read_medium(c, v, P, P + (P[0] == '$' && P[1] == '.' ? 2 : 0), idx, e);
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
    cJSON_AddItemToArray(vs, jvec(v0));
    cJSON_AddItemToArray(vs, jvec(v1));
    cJSON_AddItemToArray(vs, jvec(v2));
    cJSON_AddItemToArray(vs, jvec(v3_));
    cJSON_AddItemToObject(o, "vertices", vs);
    cJSON_AddStringToObject(o, "material", mat);
    return o;
}

static int convert_primitive(conv *c, const cJSON *p, const char *P, int index, json_err *e) {
    if (!cJSON_IsObject(p)) return json_fail(e, PM_EINVAL, "%s: expected an object, got %s", P, json_type_name(p));
    const char *type;
    TRY(json_string(p, P, "type", 1, &type, e));
    static const char *const common[] = {"name", "type", "transform", "bsdf", "emission", "power",
                                         "file", "smooth", "recompute_normals", "backface_culling",
                                         "int_medium", "ext_medium", NULL};
    if (json_get(p, "bump")) return json_fail(e, PM_EINVAL, "%s.bump: bump maps are not supported", P);
    int is_mesh = strcmp(type, "mesh") == 0;
    if (!is_mesh && strcmp(type, "quad") != 0 && strcmp(type, "cube") != 0 && strcmp(type, "sphere") != 0)
        return json_fail(e, PM_EINVAL, "%s.type: primitive type \"%s\" is not supported (quad, cube, sphere, mesh)",
                         P, type);
    TRY(check_keys(NULL, p, P, common, NULL, "a primitive key outside the supported subset", e));
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
    TRY(tcolor(p, P, "emission", &Le, e));
    TRY(tcolor(p, P, "power", &power, e));
    if (Le.x < 0 || Le.y < 0 || Le.z < 0 || power.x < 0 || power.y < 0 || power.z < 0)
        return json_fail(e, PM_EINVAL, "%s.%s: must not be negative", P, has_e ? "emission" : "power");
    int emits = !v3_iszero(Le) || !v3_iszero(power);
    int invisible = strcmp(b.type, "null") == 0 || strcmp(b.type, "forward") == 0;
    /* Media (tungsten.h): the outside must be the camera's medium; the inside is int_medium,
     * or, for a surface light passes through that names no medium, the medium around it. */
    const cJSON *im = json_get(p, "int_medium"), *xm = json_get(p, "ext_medium");
    int imed, xmed, inside = -1;
    char mp[P_MAX];
    json_path_key(mp, sizeof mp, P, "int_medium");
    TRY(medium_ref(c, im, mp, &imed, e));
    json_path_key(mp, sizeof mp, P, "ext_medium");
    TRY(medium_ref(c, xm, mp, &xmed, e));
    if (xm && xmed != c->global)
        return json_fail(e, PM_EINVAL, "%s: the medium outside the primitive (\"%s\") must be the camera's (%s%s%s): "
                         "media around objects other than the one the camera is in are not supported", mp,
                         c->mnames[xmed], c->global >= 0 ? "\"" : "", c->global >= 0 ? c->mnames[c->global] : "none",
                         c->global >= 0 ? "\"" : "");
    int passes = invisible || (strcmp(b.type, "dielectric") == 0 && b.refract);
    if (passes) inside = im ? imed : xm ? -1 : c->global;
    json_path_key(mp, sizeof mp, P, im ? "int_medium" : "bsdf");
    if (invisible && emits && (im || xm))
        return json_fail(e, PM_EINVAL, "%s.emission: an emitting \"%s\" medium boundary is not supported", P, b.type);
    if (invisible && !emits && inside == c->global) return 0; /* changes nothing: dropped (tungsten.h) */
    int quad_group = inside >= 0 && strcmp(type, "quad") == 0; /* merged later (tungsten.h) */
    if (invisible && !emits) {
        snprintf(b.name, sizeof b.name, "%s", "boundary");
        b.type = "boundary";
    }
    if (invisible && emits)
        twarn(c->file, "%s.bsdf: a \"%s\" surface that emits becomes an opaque black emitter "
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
        if (quad_group && obj) { /* into its group's mesh; the medium is behind its front */
            int gi = -1;
            for (int k = 0; k < c->nqg; k++)
                if (c->qg[k].medium == inside && strcmp(c->qg[k].mat, mat) == 0) gi = k;
            if (gi < 0) {
                if (c->nqg == 16) {
                    cJSON_Delete(obj);
                    return json_fail(e, PM_EINVAL, "%s: more than 16 groups of quads with a medium behind them", P);
                }
                gi = c->nqg++;
                c->qg[gi].medium = inside;
                snprintf(c->qg[gi].mat, sizeof c->qg[gi].mat, "%s", mat);
                snprintf(c->qg[gi].first, sizeof c->qg[gi].first, "%s", P);
                c->qg[gi].verts = cJSON_CreateArray();
                c->qg[gi].tris = cJSON_CreateArray();
                c->qg[gi].nq = 0;
                if (!c->qg[gi].verts || !c->qg[gi].tris) {
                    cJSON_Delete(obj);
                    return json_fail(e, PM_ENOMEM, "out of memory");
                }
            }
            struct qgroup *q = &c->qg[gi];
            const cJSON *vs = json_get(obj, "vertices");
            for (const cJSON *v = vs->child; v; v = v->next) cJSON_AddItemToArray(q->verts, cJSON_Duplicate(v, 1));
            int b0 = 4 * q->nq++;
            int t1[3] = {b0, b0 + 1, b0 + 2}, t2[3] = {b0, b0 + 2, b0 + 3};
            cJSON_AddItemToArray(q->tris, cJSON_CreateIntArray(t1, 3));
            cJSON_AddItemToArray(q->tris, cJSON_CreateIntArray(t2, 3));
            cJSON_Delete(obj);
            return add_material(c, mat, &b, v3s(0), e);
        }
    } else if (strcmp(type, "cube") == 0) {
        vec3 ctr = xf_point(M, v3s(0)), corner[8];
        for (int i = 0; i < 8; i++)
            corner[i] = xf_point(M, v3(i & 1 ? 0.5 : -0.5, i & 2 ? 0.5 : -0.5, i & 4 ? 0.5 : -0.5));
        static const int face[6][4] = {{0, 2, 6, 4}, {1, 3, 7, 5}, {0, 1, 5, 4}, {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 5, 7, 6}};
        obj = cJSON_CreateObject();
        cJSON *vs = cJSON_CreateArray(), *ts = cJSON_CreateArray();
        cJSON_AddStringToObject(obj, "type", "mesh");
        for (int i = 0; i < 8; i++) cJSON_AddItemToArray(vs, jvec(corner[i]));
        for (int f = 0; f < 6; f++) {
            const int *q = face[f];
            vec3 n = v3_cross(v3_sub(corner[q[1]], corner[q[0]]), v3_sub(corner[q[2]], corner[q[0]]));
            vec3 fc = v3_scale(v3_add(corner[q[0]], corner[q[2]]), 0.5);
            area += v3_len(n);
            int out = v3_dot(n, v3_sub(fc, ctr)) > 0; /* wind so the front faces out */
            int t1[3] = {q[0], out ? q[1] : q[2], out ? q[2] : q[1]};
            int t2[3] = {q[0], out ? q[2] : q[3], out ? q[3] : q[2]};
            cJSON_AddItemToArray(ts, cJSON_CreateIntArray(t1, 3));
            cJSON_AddItemToArray(ts, cJSON_CreateIntArray(t2, 3));
        }
        if (!(area > 0)) {
            cJSON_Delete(vs);
            cJSON_Delete(ts);
            cJSON_Delete(obj);
            return json_fail(e, PM_EINVAL, "%s: the cube has zero area", tp);
        }
        cJSON_AddItemToObject(obj, "vertices", vs);
        cJSON_AddItemToObject(obj, "triangles", ts);
        cJSON_AddStringToObject(obj, "material", mat);
    } else if (strcmp(type, "sphere") == 0) {
        double r = fmax(v3_len(xf_col(M, 0)), fmax(v3_len(xf_col(M, 1)), v3_len(xf_col(M, 2))));
        if (!(r > 0)) return json_fail(e, PM_EINVAL, "%s: the sphere has radius 0", tp);
        area = 4 * M_PI * r * r;
        obj = cJSON_CreateObject();
        cJSON_AddStringToObject(obj, "type", "sphere");
        cJSON_AddItemToObject(obj, "center", jvec(xf_point(M, v3s(0))));
        cJSON_AddNumberToObject(obj, "radius", r);
        cJSON_AddStringToObject(obj, "material", mat);
    } else {
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
            area = mesh_area(&md);
            mesh_free(&md);
        }
        obj = cJSON_CreateObject();
        cJSON_AddStringToObject(obj, "type", "mesh");
        cJSON_AddStringToObject(obj, "file", file); /* scene_import joins it to the directory */
        cJSON_AddStringToObject(obj, "material", mat);
        double a16[16] = {M[0][0], M[0][1], M[0][2], M[0][3], M[1][0], M[1][1], M[1][2], M[1][3],
                          M[2][0], M[2][1], M[2][2], M[2][3], 0, 0, 0, 1};
        cJSON_AddItemToObject(obj, "transform", cJSON_CreateDoubleArray(a16, 16));
        cJSON_AddBoolToObject(obj, "smooth", smooth);
        cJSON_AddBoolToObject(obj, "recompute_normals", recompute);
        cJSON_AddBoolToObject(obj, "usemtl", 0); /* Tungsten reads geometry only from an OBJ */
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
    if (inside >= 0) cJSON_AddStringToObject(obj, "interior_medium", c->mnames[inside]);
    cJSON_AddItemToArray(c->objs, obj);
    return add_material(c, mat, &b, emits ? Le : v3s(0), e);
}

int tungsten_is_scene(const cJSON *root) {
    return cJSON_IsObject(root) && (json_get(root, "bsdfs") || json_get(root, "primitives")) &&
           !json_get(root, "materials") && !json_get(root, "objects");
}

static int convert_camera(const char *file, const cJSON *root, cJSON *out, long spp, json_err *e) {
    const cJSON *c;
    TRY(json_object(root, "$", "camera", 1, &c, e));
    const char *P = "$.camera";
    static const char *const ok[] = {"type", "resolution", "transform", "fov", "medium", NULL};
    static const char *const warn[] = {"tonemap", NULL};
    const cJSON *filt = json_get(c, "reconstruction_filter");
    if (filt) /* a name ("tent", "gaussian", ...) or an object: either way not ours */
        twarn(file, "%s.reconstruction_filter: %s%s%s is not supported: each pixel is the mean of its own "
              "samples (a box filter) instead", P, cJSON_IsString(filt) ? "the filter \"" : "a filter",
              cJSON_IsString(filt) ? filt->valuestring : "", cJSON_IsString(filt) ? "\"" : "");
    static const char *const ok_f[] = {"type", "resolution", "transform", "fov", "medium", "reconstruction_filter", NULL};
    TRY(check_keys(file, c, P, filt ? ok_f : ok, warn, "a camera key outside the supported subset", e));
    const char *type = "pinhole";
    TRY(json_string(c, P, "type", 0, &type, e));
    if (strcmp(type, "pinhole") != 0)
        return json_fail(e, PM_EINVAL, "%s.type: camera type \"%s\" is not supported (pinhole)", P, type);
    double fov = 60;
    TRY(json_number(c, P, "fov", 0, &fov, e));
    long w = 1000, h = 563;
    const cJSON *res = json_get(c, "resolution");
    if (res && cJSON_IsNumber(res)) {
        TRY(json_int(c, P, "resolution", 1, 1, 1 << 14, &w, e));
        h = w;
    } else if (res) {
        if (!cJSON_IsArray(res) || cJSON_GetArraySize(res) != 2 || !cJSON_IsNumber(res->child) ||
            !cJSON_IsNumber(res->child->next))
            return json_fail(e, PM_EINVAL, "%s.resolution: expected a number or [width, height]", P);
        double a = res->child->valuedouble, b = res->child->next->valuedouble;
        if (a != floor(a) || b != floor(b) || a < 1 || b < 1 || a > 1 << 14 || b > 1 << 14)
            return json_fail(e, PM_EINVAL, "%s.resolution: width and height must be integers in [1, 16384]", P);
        w = (long)a;
        h = (long)b;
    }
    const cJSON *t;
    TRY(json_object(c, P, "transform", 1, &t, e));
    const char *TP = "$.camera.transform";
    static const char *const tok[] = {"position", "look_at", "up", NULL};
    TRY(check_keys(NULL, t, TP, tok, NULL, "a camera transform takes position, look_at and up", e));
    vec3 pos = v3s(0), look = v3(0, 0, 1), up = v3(0, 1, 0);
    TRY(json_vec3(t, TP, "position", 0, &pos, e));
    TRY(json_vec3(t, TP, "look_at", 1, &look, e));
    TRY(json_vec3(t, TP, "up", 0, &up, e));
    cJSON *cam = cJSON_CreateObject();
    if (!cam) return json_fail(e, PM_ENOMEM, "out of memory");
    cJSON_AddItemToObject(out, "camera", cam);
    /* Tungsten's image right is forward x up, as ours (it negates the frame's x axis) */
    cJSON_AddItemToObject(cam, "eye", jvec(pos));
    cJSON_AddItemToObject(cam, "look_at", jvec(look));
    cJSON_AddItemToObject(cam, "up", jvec(up));
    cJSON_AddNumberToObject(cam, "fov_deg", fov);
    cJSON_AddNumberToObject(cam, "width", (double)w);
    cJSON_AddNumberToObject(cam, "height", (double)h);
    if (spp > 0) cJSON_AddNumberToObject(cam, "spp", (double)spp);
    return 0;
}

static int convert_settings(const char *file, const cJSON *root, cJSON *out, long *spp, long *max_depth,
                            json_err *e) {
    const cJSON *r, *in;
    TRY(json_object(root, "$", "renderer", 0, &r, e));
    *spp = 0;
    if (r) {
        static const char *const ok[] = {"spp", NULL};
        static const char *const warn[] = {"output_file", "hdr_output_file", "resume_render_file",
                                           "overwrite_output_files", "adaptive_sampling", "enable_resume_render",
                                           "stratified_sampler", "scene_bvh", "spp_step", "checkpoint_interval",
                                           "timeout", NULL};
        TRY(check_keys(file, r, "$.renderer", ok, warn, "a renderer key outside the supported subset", e));
        TRY(json_int(r, "$.renderer", "spp", 0, 1, 1 << 20, spp, e));
    }
    TRY(json_object(root, "$", "integrator", 0, &in, e));
    cJSON *rs = cJSON_CreateObject();
    if (!rs) return json_fail(e, PM_ENOMEM, "out of memory");
    cJSON_AddItemToObject(out, "render", rs);
    *max_depth = 64; /* our render.max_depth default */
    if (!in) return 0;
    const char *P = "$.integrator";
    static const char *const ok[] = {"type", "max_bounces", "min_bounces", "enable_two_sided_shading", NULL};
    static const char *const warn[] = {"enable_consistency_checks", "enable_light_sampling",
                                       "enable_volume_light_sampling", "photon_count", "volume_photon_count",
                                       "gather_photon_count", "gather_radius", "alpha", "fixed_volume_radius",
                                       "volume_gather_radius", "volume_photon_type", "include_surfaces", NULL};
    const char *type = "path_tracer";
    TRY(json_string(in, P, "type", 0, &type, e));
    int known = strcmp(type, "path_tracer") == 0 || strcmp(type, "photon_map") == 0 ||
                strcmp(type, "progressive_photon_map") == 0;
    if (!known) {
        /* An integrator we lack is no reason to refuse the scene (issue 29): the scene is the
         * same, only the method differs. Path tracing renders its expected image; --mode or
         * render.mode chooses another. Its own keys are ignored, each named. */
        twarn(file, "%s.type: integrator \"%s\" is not supported: rendering with \"path\" (path tracing; "
              "--mode chooses another: path, pm, ...)", P, type);
        cJSON_AddStringToObject(rs, "mode", "path");
        for (const cJSON *it = in->child; it; it = it->next) {
            const char *k = it->string ? it->string : "?";
            if (strcmp(k, "type") != 0 && strcmp(k, "max_bounces") != 0)
                twarn(file, "%s.%s: ignored (a setting of the integrator \"%s\", which is not used)", P, k, type);
        }
        long maxb = 64;
        TRY(json_int(in, P, "max_bounces", 0, 1, 100000, &maxb, e));
        cJSON_AddNumberToObject(rs, "max_depth", (double)maxb);
        *max_depth = maxb;
        return 0;
    }
    TRY(check_keys(file, in, P, ok, warn, "an integrator key outside the supported subset", e));
    if (strcmp(type, "path_tracer") == 0)
        cJSON_AddStringToObject(rs, "mode", "path");
    else
        cJSON_AddStringToObject(rs, "mode", "pm");
    long maxb = 64, minb = 0;
    TRY(json_int(in, P, "max_bounces", 0, 1, 100000, &maxb, e));
    TRY(json_int(in, P, "min_bounces", 0, 0, 100000, &minb, e));
    if (minb != 0)
        return json_fail(e, PM_EINVAL, "%s.min_bounces: only 0 is supported (a minimum drops the short paths' light)", P);
    int two = 1;
    TRY(json_bool(in, P, "enable_two_sided_shading", 0, &two, e));
    if (!two) return json_fail(e, PM_EINVAL, "%s.enable_two_sided_shading: false is not supported", P);
    cJSON_AddNumberToObject(rs, "max_depth", (double)maxb);
    *max_depth = maxb;
    return 0;
}

static int convert(const cJSON *root, const char *dir, const char *file, cJSON *out, json_err *e) {
    static const char *const ok[] = {"media", "bsdfs", "primitives", "camera", "integrator", "renderer", NULL};
    TRY(check_keys(NULL, root, "$", ok, NULL, "a top-level key outside the supported subset", e));
    const cJSON *media, *bsdfs, *prims;
    TRY(json_array(root, "$", "media", 0, &media, e));
    TRY(json_array(root, "$", "bsdfs", 0, &bsdfs, e));
    TRY(json_array(root, "$", "primitives", 1, &prims, e));
    conv c = {0};
    c.dir = dir;
    c.file = file;
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
    if (rc == 0) rc = convert_settings(file, root, out, &spp, &c.max_depth, e);
    if (rc == 0) rc = convert_camera(file, root, out, spp, e);
    i = 0;
    for (const cJSON *m = media ? media->child : NULL; m && rc == 0; m = m->next, i++) {
        int idx;
        const char *name = NULL;
        json_path_index(p, sizeof p, "$.media", i);
        rc = cJSON_IsObject(m) ? json_string(m, p, "name", 1, &name, e) : 0;
        if (rc == 0) rc = read_medium(&c, m, p, name ? name : "", &idx, e);
    }
    const cJSON *cam = json_get(root, "camera");
    if (rc == 0 && cam) rc = medium_ref(&c, json_get(cam, "medium"), "$.camera.medium", &c.global, e);
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
    for (int k = 0; k < c.nqg; k++) { /* each group of quads with a medium behind them: one mesh */
        struct qgroup *q = &c.qg[k];
        cJSON *o = rc == 0 ? cJSON_CreateObject() : NULL;
        if (o) {
            char nm[P_MAX + 96];
            snprintf(nm, sizeof nm, "the %d quads with the medium \"%s\" behind them (from %s)", q->nq,
                     c.mnames[q->medium], q->first);
            cJSON_AddStringToObject(o, "type", "mesh");
            cJSON_AddStringToObject(o, "name", nm);
            cJSON_AddItemToObject(o, "vertices", q->verts);
            cJSON_AddItemToObject(o, "triangles", q->tris);
            cJSON_AddStringToObject(o, "material", q->mat);
            cJSON_AddStringToObject(o, "interior_medium", c.mnames[q->medium]);
            cJSON_AddItemToArray(c.objs, o);
        } else {
            cJSON_Delete(q->verts);
            cJSON_Delete(q->tris);
        }
    }
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
