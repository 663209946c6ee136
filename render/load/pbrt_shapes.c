/* pbrt_shapes.c: pbrt's shapes as our objects (pbrt_internal.h): trianglemesh as an inline
 * mesh in world space, plymesh as a file object with its matrix, sphere as a sphere; each wound
 * so that our front is pbrt's normal; and the copies of converted objects that instances are.
 */
#define _XOPEN_SOURCE 700
#include "load/pbrt_internal.h"

#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "scene/shapes.h"

/* Does pbrt's normal point along the winding normal of the world-space vertices (1), or
 * against it (-1: ReverseOrientation xor a handedness-swapping transform)? */
static int pbrt_side(const conv *c) {
    int swap = pb_det3((double(*)[4])c->g.m) < 0;
    return (c->g.revor ^ swap) ? -1 : 1;
}
/* Must our winding be flipped for our front to be pbrt's normal, in output coordinates? */
static int need_flip(const conv *c) { return (c->mirror ? -1 : 1) != pbrt_side(c); }

static int shape_trianglemesh(conv *c, const tok *at, plist *pl, const char *mat) {
    pparam *P, *I, *N;
    TRY(pb_get(c, at, pl, "P", "point", &P));
    TRY(pb_get(c, at, pl, "indices", "integer", &I));
    TRY(pb_get(c, at, pl, "N", "normal", &N));
    pparam *uv;
    TRY(pb_get(c, at, pl, "uv", "float|point2", &uv));
    TRY(pb_get(c, at, pl, "st", "float|point2", &uv));
    pparam *S;
    TRY(pb_get(c, at, pl, "S", "vector", &S));
    if (!P || P->n == 0 || P->n % 3) return pb_fail(c, at, PM_EINVAL, "Shape \"trianglemesh\": \"point P\" needs 3 numbers per vertex");
    int nv = P->n / 3;
    int ni = I ? I->n : (nv == 3 ? 3 : -1);
    if (ni < 0) return pb_fail(c, at, PM_EINVAL, "Shape \"trianglemesh\": \"integer indices\" missing (required unless P has 3 points)");
    if (ni % 3) return pb_fail(c, at, PM_EINVAL, "Shape \"trianglemesh\": %d indices, not a multiple of 3", ni);
    if (N && N->n != P->n) return pb_fail(c, at, PM_EINVAL, "Shape \"trianglemesh\": \"normal N\" has %d numbers, P %d", N->n, P->n);
    vec3 *v = malloc((size_t)nv * sizeof *v), *vn = N ? malloc((size_t)nv * sizeof *vn) : NULL;
    if (!v || (N && !vn)) {
        free(v);
        free(vn);
        return PM_ENOMEM;
    }
    /* normals by the inverse transpose, then the mirror (pbrt.h); pbrt turns the geometric
     * normal toward them (FaceForward), so with N each triangle is wound to face its normals */
    double inv[4][4];
    if (N && pb_inv(c->g.m, inv) < 0) {
        free(v);
        free(vn);
        return pb_fail(c, at, PM_EINVAL, "Shape \"trianglemesh\": the transform is singular");
    }
    for (int i = 0; N && i < nv; i++) {
        vec3 n = v3(N->num[3 * i], N->num[3 * i + 1], N->num[3 * i + 2]);
        vec3 w = v3(inv[0][0] * n.x + inv[1][0] * n.y + inv[2][0] * n.z, inv[0][1] * n.x + inv[1][1] * n.y + inv[2][1] * n.z,
                    inv[0][2] * n.x + inv[1][2] * n.y + inv[2][2] * n.z);
        if (!(v3_len(w) > 0) || !isfinite(w.x + w.y + w.z)) {
            free(v);
            free(vn);
            return pb_fail(c, at, PM_EINVAL, "Shape \"trianglemesh\": normal %d is zero or not finite", i);
        }
        vn[i] = pb_out(c, v3_norm(w));
    }
    for (int i = 0; i < nv; i++) {
        vec3 p = v3(P->num[3 * i], P->num[3 * i + 1], P->num[3 * i + 2]);
        if (!isfinite(p.x) || !isfinite(p.y) || !isfinite(p.z)) {
            free(v);
            free(vn);
            return pb_fail(c, at, PM_EINVAL, "Shape \"trianglemesh\": point %d is not finite", i);
        }
        v[i] = pb_out(c, pb_point(c->g.m, p));
    }
    int flip = need_flip(c);
    cJSON *o = cJSON_CreateObject(), *va = cJSON_CreateArray(), *ta = cJSON_CreateArray(), *na = N ? cJSON_CreateArray() : NULL;
    int rc = o && va && ta && (!N || na) ? 0 : PM_ENOMEM;
    for (int i = 0; i < nv && rc == 0; i++) cJSON_AddItemToArray(va, pb_jv(v[i]));
    long skipped = 0;
    for (int t = 0; t < ni / 3 && rc == 0; t++) {
        int k[3];
        for (int j = 0; j < 3; j++) {
            double x = I ? I->num[3 * t + j] : 3 * t + j;
            if (!(x >= 0 && x < nv && x == floor(x))) {
                rc = pb_fail(c, at, PM_EINVAL, "Shape \"trianglemesh\": index %g (triangle %d) out of range (%d points)", x, t, nv);
                break;
            }
            k[j] = (int)x;
        }
        if (rc) break;
        triangle tr;
        if (triangle_make(&tr, v[k[0]], v[k[1]], v[k[2]], 0) < 0) {
            skipped++;
            continue;
        }
        if (vn ? v3_dot(tr.n, v3_add(vn[k[0]], v3_add(vn[k[1]], vn[k[2]]))) < 0 : flip) {
            int x = k[1];
            k[1] = k[2];
            k[2] = x;
        }
        cJSON_AddItemToArray(ta, cJSON_CreateIntArray(k, 3));
    }
    for (int i = 0; vn && i < nv && rc == 0; i++) cJSON_AddItemToArray(na, pb_jv(vn[i]));
    free(v);
    free(vn);
    if (rc == 0 && skipped)
        pb_warn(c, at, "Shape \"trianglemesh\": skipped %ld degenerate triangle%s (zero area)", skipped, skipped == 1 ? "" : "s");
    if (rc == 0 && cJSON_GetArraySize(ta) == 0) {
        pb_warn(c, at, "Shape \"trianglemesh\": no triangle with an area: skipped");
        rc = 1;
    }
    if (rc != 0) {
        cJSON_Delete(o);
        cJSON_Delete(va);
        cJSON_Delete(ta);
        cJSON_Delete(na);
        return rc < 0 ? rc : 0;
    }
    cJSON_AddStringToObject(o, "type", "mesh");
    cJSON_AddItemToObject(o, "vertices", va);
    cJSON_AddItemToObject(o, "triangles", ta);
    if (na) {
        cJSON_AddItemToObject(o, "normals", na);
        cJSON_AddBoolToObject(o, "smooth", 1);
    }
    cJSON_AddStringToObject(o, "material", mat);
    cJSON_AddItemToArray(c->target, o);
    return 0;
}

/* Does the PLY file's header give vertex normals (property nx)? */
static int ply_has_normals(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    char b[8192];
    size_t n = fread(b, 1, sizeof b - 1, f);
    fclose(f);
    b[n] = 0;
    char *end = strstr(b, "end_header");
    if (end) *end = 0;
    return strstr(b, " nx\n") != NULL || strstr(b, " nx\r\n") != NULL;
}

static void dir_of(const char *path, char *dir, size_t cap) {
    const char *s = strrchr(path, '/');
    if (!s) {
        snprintf(dir, cap, ".");
        return;
    }
    size_t n = (size_t)(s - path);
    if (n == 0) n = 1;
    if (n >= cap) n = cap - 1;
    memcpy(dir, path, n);
    dir[n] = 0;
}

/* path relative to the directory of file, made absolute. */
void pb_resolve(const char *file, const char *name, char *out, size_t cap) {
    char dir[4096], joined[8192], real[PATH_MAX];
    if (name[0] == '/') {
        snprintf(joined, sizeof joined, "%s", name);
    } else {
        dir_of(file, dir, sizeof dir);
        snprintf(joined, sizeof joined, "%s/%s", dir, name);
    }
    if (realpath(joined, real)) {
        snprintf(out, cap, "%s", real);
    } else if (joined[0] != '/') {
        char cwd[4096];
        snprintf(out, cap, "%.4000s/%.4000s", getcwd(cwd, sizeof cwd) ? cwd : ".", joined);
    } else {
        snprintf(out, cap, "%s", joined);
    }
}

static int shape_plymesh(conv *c, const tok *at, plist *pl, const char *mat) {
    const char *fn = NULL;
    TRY(pb_get_string(c, at, pl, "filename", &fn));
    if (!fn) return pb_fail(c, at, PM_EINVAL, "Shape \"plymesh\": \"string filename\" missing");
    char path[8192];
    pb_resolve(pb_file(c, at), fn, path, sizeof path);
    FILE *f = fopen(path, "rb");
    if (!f) return pb_fail(c, at, PM_EIO, "Shape \"plymesh\": cannot open %s: %s", path, strerror(errno));
    fclose(f);
    if (c->g.m[3][0] != 0 || c->g.m[3][1] != 0 || c->g.m[3][2] != 0 || c->g.m[3][3] != 1)
        return pb_fail(c, at, PM_EINVAL, "a projective transform is not supported for shapes");
    double M[16];
    for (int r = 0; r < 3; r++)
        for (int k = 0; k < 4; k++) M[4 * r + k] = (c->mirror && r == 0 ? -1 : 1) * c->g.m[r][k];
    M[12] = M[13] = M[14] = 0;
    M[15] = 1;
    cJSON *o = cJSON_CreateObject();
    if (!o) return PM_ENOMEM;
    cJSON_AddStringToObject(o, "type", "mesh");
    cJSON_AddStringToObject(o, "file", path);
    cJSON_AddItemToObject(o, "transform", cJSON_CreateDoubleArray(M, 16));
    cJSON_AddBoolToObject(o, "smooth", ply_has_normals(path));
    if (need_flip(c)) cJSON_AddBoolToObject(o, "flip", 1);
    cJSON_AddBoolToObject(o, "usemtl", 0);
    cJSON_AddStringToObject(o, "material", mat);
    cJSON_AddItemToArray(c->target, o);
    pparam *d;
    TRY(pb_get(c, at, pl, "displacement", "texture|float", &d));
    if (d) pb_warn(c, at, "Shape \"plymesh\": displacement is not supported: ignored");
    return 0;
}

static int shape_sphere(conv *c, const tok *at, plist *pl, const char *mat) {
    double r = 1, phimax = 360;
    TRY(pb_get_floats(c, at, pl, "radius", "float", 1, &r));
    double zmin = -r, zmax = r; /* pbrt-v3's defaults: the whole sphere of that radius */
    int a = pb_get_floats(c, at, pl, "zmin", "float", 1, &zmin), b = pb_get_floats(c, at, pl, "zmax", "float", 1, &zmax),
        d = pb_get_floats(c, at, pl, "phimax", "float", 1, &phimax);
    if (a < 0 || b < 0 || d < 0) return PM_EINVAL;
    if (!(r > 0)) return pb_fail(c, at, PM_EINVAL, "Shape \"sphere\": radius must be positive, got %g", r);
    if (zmin > -r || zmax < r || phimax < 360)
        pb_warn(c, at, "Shape \"sphere\": a partial sphere (zmin, zmax, phimax) is not supported: the full sphere");
    double s[3];
    for (int k = 0; k < 3; k++) s[k] = v3_len(pb_dir(c->g.m, v3(k == 0, k == 1, k == 2)));
    double smax = fmax(s[0], fmax(s[1], s[2])), smin = fmin(s[0], fmin(s[1], s[2]));
    if (smax - smin > 1e-9 * smax)
        pb_warn(c, at, "Shape \"sphere\": a non-uniform scale (%g %g %g) is not supported: a sphere of the largest", s[0],
              s[1], s[2]);
    if (pbrt_side(c) < 0)
        pb_warn(c, at, "Shape \"sphere\": ReverseOrientation (or a mirroring transform) is not supported for spheres: "
              "its front stays the outside");
    cJSON *o = cJSON_CreateObject();
    if (!o) return PM_ENOMEM;
    cJSON_AddStringToObject(o, "type", "sphere");
    cJSON_AddItemToObject(o, "center", pb_jv(pb_out(c, pb_point(c->g.m, v3s(0)))));
    cJSON_AddNumberToObject(o, "radius", r * smax);
    cJSON_AddStringToObject(o, "material", mat);
    cJSON_AddItemToArray(c->target, o);
    return 0;
}

/* ---- instances ---------------------------------------------------------------------------- */

/* A copy of converted object o under the matrix X (output coordinates). */
cJSON *pb_xform_obj(const conv *c, const cJSON *o, double X[4][4]) {
    cJSON *n = cJSON_Duplicate(o, 1);
    if (!n) return NULL;
    const cJSON *type = cJSON_GetObjectItemCaseSensitive(n, "type");
    const char *t = cJSON_IsString(type) ? type->valuestring : "";
    (void)c;
    if (strcmp(t, "sphere") == 0) {
        cJSON *ce = cJSON_GetObjectItemCaseSensitive(n, "center"), *r = cJSON_GetObjectItemCaseSensitive(n, "radius");
        vec3 p = v3(cJSON_GetArrayItem(ce, 0)->valuedouble, cJSON_GetArrayItem(ce, 1)->valuedouble,
                    cJSON_GetArrayItem(ce, 2)->valuedouble);
        double s = 0;
        for (int k = 0; k < 3; k++) s = fmax(s, v3_len(pb_dir(X, v3(k == 0, k == 1, k == 2))));
        cJSON_ReplaceItemInObjectCaseSensitive(n, "center", pb_jv(pb_point(X, p)));
        cJSON_ReplaceItemInObjectCaseSensitive(n, "radius", cJSON_CreateNumber(r->valuedouble * s));
    } else if (cJSON_GetObjectItemCaseSensitive(n, "file")) {
        cJSON *tr = cJSON_GetObjectItemCaseSensitive(n, "transform");
        double A[4][4], R[4][4], M[16];
        for (int i = 0; i < 16; i++) A[i / 4][i % 4] = cJSON_GetArrayItem(tr, i)->valuedouble;
        pb_mul(X, A, R);
        for (int i = 0; i < 16; i++) M[i] = R[i / 4][i % 4];
        cJSON_ReplaceItemInObjectCaseSensitive(n, "transform", cJSON_CreateDoubleArray(M, 16));
        if (pb_det3(X) < 0) { /* a mirroring instance turns the winding: keep the front */
            cJSON *fl = cJSON_GetObjectItemCaseSensitive(n, "flip");
            int f = cJSON_IsTrue(fl);
            cJSON_DeleteItemFromObjectCaseSensitive(n, "flip");
            if (!f) cJSON_AddBoolToObject(n, "flip", 1);
        }
    } else {
        cJSON *vs = cJSON_GetObjectItemCaseSensitive(n, "vertices");
        for (cJSON *v = vs ? vs->child : NULL; v; v = v->next) {
            vec3 p = v3(cJSON_GetArrayItem(v, 0)->valuedouble, cJSON_GetArrayItem(v, 1)->valuedouble,
                        cJSON_GetArrayItem(v, 2)->valuedouble);
            vec3 q = pb_point(X, p);
            double a[3] = {q.x, q.y, q.z};
            for (int k = 0; k < 3; k++) cJSON_SetNumberValue(cJSON_GetArrayItem(v, k), a[k]);
        }
        if (pb_det3(X) < 0) {
            cJSON *ts = cJSON_GetObjectItemCaseSensitive(n, "triangles");
            for (cJSON *t3 = ts ? ts->child : NULL; t3; t3 = t3->next) {
                cJSON *b = cJSON_GetArrayItem(t3, 1), *d = cJSON_GetArrayItem(t3, 2);
                double x = b->valuedouble;
                cJSON_SetNumberValue(b, d->valuedouble);
                cJSON_SetNumberValue(d, x);
            }
        }
    }
    return n;
}

/* ---- the Shape directive ---------------------------------------------------------- */

int pb_do_shape(conv *c, const tok *at, const char *s, plist *pl, const char *what) {
    int rc = 0;
    char mat[96];
    if (!c->in_world) rc = pb_fail(c, at, PM_EINVAL, "Shape before WorldBegin");
    const cJSON *cur = rc == 0 ? cJSON_GetObjectItemCaseSensitive(c->mats, c->g.mat) : NULL;
    const cJSON *ct = cur ? cJSON_GetObjectItemCaseSensitive(cur, "type") : NULL;
    int is_null = cJSON_IsString(ct) && strcmp(ct->valuestring, "null") == 0;
    /* media (pbrt.h): a shape whose MediumInterface has two different media is an interface
     * (interior_medium inside, exterior_medium outside); one without keeps the ray's medium */
    int transition = strcmp(c->g.inside, c->g.outside) != 0;
    if (rc == 0 && is_null && !transition) {
        pb_warn(c, at, "%s with material \"none\" or \"interface\" and no MediumInterface of two media: skipped", what);
        for (int k = 0; k < pl->n; k++) pl->p[k].used = 1;
    } else if (rc == 0 && (rc = pb_shape_material(c, mat, sizeof mat)) == 0) {
        int before = cJSON_GetArraySize(c->target);
        if (strcmp(s, "trianglemesh") == 0) rc = shape_trianglemesh(c, at, pl, mat);
        else if (strcmp(s, "plymesh") == 0) rc = shape_plymesh(c, at, pl, mat);
        else if (strcmp(s, "sphere") == 0) rc = shape_sphere(c, at, pl, mat);
        else {
            pb_warn(c, at, "%s is not supported (trianglemesh, plymesh, sphere): skipped", what);
            for (int k = 0; k < pl->n; k++) pl->p[k].used = 1;
        }
        cJSON *made = cJSON_GetArraySize(c->target) > before ? cJSON_GetArrayItem(c->target, before) : NULL;
        for (int k = 0; rc == 0 && made && transition && k < 2; k++) {
            const char *m = k ? c->g.outside : c->g.inside;
            cJSON_AddItemToObject(made, k ? "exterior_medium" : "interior_medium",
                                  m[0] ? cJSON_CreateString(m) : cJSON_CreateNull());
        }
        pparam *al;
        if (rc == 0) rc = pb_get(c, at, pl, "alpha", "float|texture", &al);
        if (rc == 0 && al) pb_warn(c, at, "%s: alpha is not supported: opaque", what);
        if (rc == 0) pb_warn_unused(c, at, what, pl);
    }
    return rc;
}

