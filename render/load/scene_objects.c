/* scene_objects.c: the objects of a JSON scene (scene_load_internal.h): spheres, triangles,
 * quads, inline meshes (with their own normals, or smooth ones computed) and mesh files placed
 * by a transform; each point checked against the supported range.
 */
#define _XOPEN_SOURCE 700
#include "load/scene_load_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "load/import.h"

static int find_material(const scene *s, const cJSON *obj, const char *P, int *out, json_err *e) {
    const char *name;
    TRY(json_string(obj, P, "material", 1, &name, e));
    for (int i = 0; i < s->nmats; i++)
        if (strcmp(s->mats[i].name, name) == 0) {
            *out = i;
            return 0;
        }
    return json_fail(e, PM_EINVAL, "%s.material: unknown material \"%s\"", P, name);
}

static int add_tri(scene *s, caps *cp, vec3 a, vec3 b, vec3 c, int mat, const char *P,
                   json_err *e) {
    triangle t;
    TRY(sl_check_point(a, P, NULL, e));
    TRY(sl_check_point(b, P, NULL, e));
    TRY(sl_check_point(c, P, NULL, e));
    double longest = fmax(v3_len(v3_sub(b, a)), fmax(v3_len(v3_sub(c, b)), v3_len(v3_sub(a, c))));
    if (longest > 0 && longest < SCENE_LENGTH_MIN)
        return json_fail(e, PM_EINVAL, "%s: a triangle %g across is below the supported range of "
                         "lengths, %g to %g", P, longest, SCENE_LENGTH_MIN, SCENE_LENGTH_MAX);
    if (triangle_make(&t, a, b, c, mat) < 0)
        return json_fail(e, PM_EINVAL, "%s: degenerate triangle (zero area: repeated or collinear vertices)", P);
    int n = s->ntris;
    if (sl_push((void **)&s->tris, &s->ntris, &cp->tcap, sizeof t, &t) < 0 ||
        sl_push((void **)&s->tri_obj, &n, &cp->tocap, sizeof cp->obj, &cp->obj) < 0)
        return json_fail(e, PM_ENOMEM, "out of memory");
    return 0;
}

/* Read exactly n points from key into v. */
static int read_points(const cJSON *obj, const char *P, const char *key, int n, vec3 *v,
                       json_err *e) {
    const cJSON *arr;
    TRY(json_array(obj, P, key, 1, &arr, e));
    if (cJSON_GetArraySize(arr) != n)
        return json_fail(e, PM_EINVAL, "%s.%s: expected %d points, got %d", P, key, n,
                         cJSON_GetArraySize(arr));
    char p[P_MAX], pk[P_MAX];
    json_path_key(pk, sizeof pk, P, key);
    for (int i = 0; i < n; i++) {
        json_path_index(p, sizeof p, pk, i);
        TRY(json_item_vec3(cJSON_GetArrayItem(arr, i), p, &v[i], e));
    }
    return 0;
}

/* Corner normals of an inline mesh's nt triangles (tv, indices into v; vn: the given normals
 * or NULL), the scene's triangles first.. first+nt-1: mesh_smooth_normals as for mesh files. */
static int inline_smooth(scene *s, int first, vec3 *v, int nv, vec3 *vn, int (*tv)[3], int nt, json_err *e) {
    mesh_data md;
    memset(&md, 0, sizeof md);
    md.pos = v;
    md.npos = nv;
    md.nrm = vn;
    md.nnrm = vn ? nv : 0;
    md.tri = tv;
    md.tri_n = vn ? tv : NULL;
    md.ntris = nt;
    if (mesh_smooth_normals(&md, 0) < 0) return json_fail(e, PM_ENOMEM, "out of memory");
    vec3(*ns)[3] = realloc(s->tri_ns, (size_t)s->ntris * sizeof *ns);
    if (!ns) {
        free(md.corner_n);
        return json_fail(e, PM_ENOMEM, "out of memory");
    }
    s->tri_ns = ns;
    for (int t = s->ntri_ns; t < first; t++) ns[t][0] = ns[t][1] = ns[t][2] = s->tris[t].n;
    memcpy(ns + first, md.corner_n, (size_t)nt * sizeof *ns);
    s->ntri_ns = s->ntris;
    free(md.corner_n);
    return 0;
}

/* A mesh from a file (import.h): its triangles, their materials (usemtl names or "material")
 * and, when smooth, their corner normals in s->tri_ns. */
static int load_mesh_file(scene *s, caps *cp, const cJSON *o, const char *P, json_err *e) {
    mesh_data m;
    int smooth, usemtl, def = -1, rc = 0;
    TRY(mesh_object_read(o, P, &m, &smooth, &usemtl, e));
    if (json_get(o, "material")) rc = find_material(s, o, P, &def, e);
    int *gmat = calloc((size_t)m.ngroups + 1, sizeof *gmat);
    if (!gmat) rc = json_fail(e, PM_ENOMEM, "out of memory");
    for (int g = 0; g < m.ngroups && rc == 0 && usemtl; g++) {
        gmat[g] = -1;
        for (int i = 0; i < s->nmats; i++)
            if (strcmp(s->mats[i].name, m.groups[g]) == 0) gmat[g] = i;
        if (gmat[g] < 0)
            rc = json_fail(e, PM_EINVAL, "%s.file: usemtl \"%s\" names no material in $.materials", P, m.groups[g]);
    }
    int first = s->ntris;
    for (int t = 0; t < m.ntris && rc == 0; t++) {
        int g = m.tri_group[t], mat = usemtl && g >= 0 ? gmat[g] : def;
        if (mat < 0) {
            rc = json_fail(e, PM_EINVAL, "%s.material: missing (required for the faces before any usemtl)", P);
            break;
        }
        rc = add_tri(s, cp, m.pos[m.tri[t][0]], m.pos[m.tri[t][1]], m.pos[m.tri[t][2]], mat, P, e);
    }
    if (rc == 0 && smooth) { /* corner normals for every triangle so far; flat ones get n */
        vec3(*ns)[3] = realloc(s->tri_ns, (size_t)s->ntris * sizeof *ns);
        if (!ns) {
            rc = json_fail(e, PM_ENOMEM, "out of memory");
        } else {
            s->tri_ns = ns;
            for (int t = s->ntri_ns; t < first; t++) ns[t][0] = ns[t][1] = ns[t][2] = s->tris[t].n;
            memcpy(ns + first, m.corner_n, (size_t)m.ntris * sizeof *ns);
            s->ntri_ns = s->ntris;
        }
    }
    free(gmat);
    mesh_free(&m);
    return rc;
}

/* A quad is the fan (0 1 2) (0 2 3): that covers it when it is convex, or when its inner (reflex)
 * corner is vertex 0 or 2, on the fan's diagonal. An inner corner at vertex 1 or 3 would put a
 * triangle outside the quad and leave part of it open: refused, naming the corner to start from. */
static int quad_fan_covers(const vec3 v[4], const char *P, json_err *e) {
    vec3 n = {0, 0, 0};
    for (int k = 0; k < 4; k++) n = v3_add(n, v3_cross(v[k], v[(k + 1) % 4])); /* the area's normal */
    for (int k = 1; k < 4; k += 2) {
        vec3 a = v3_sub(v[k], v[k - 1]), b = v3_sub(v[(k + 1) % 4], v[k]);
        if (v3_dot(v3_cross(a, b), n) < -1e-9 * v3_len(a) * v3_len(b) * v3_len(n))
            return json_fail(e, PM_EINVAL,
                             "%s.vertices: the quad's corner %d turns inward, and a quad is the fan (0 1 2) (0 2 3), "
                             "which would not cover it: list its vertices from that corner, or use two triangles",
                             P, k);
    }
    return 0;
}

int sl_load_object(scene *s, caps *cp, const cJSON *o, const char *P, json_err *e) {
    if (!cJSON_IsObject(o))
        return json_fail(e, PM_EINVAL, "%s: expected an object, got %s", P, json_type_name(o));
    const char *type;
    int mat;
    TRY(json_string(o, P, "type", 1, &type, e));
    if (strcmp(type, "sphere") == 0) {
        KEYS(o, P, "a sphere", "type", "name", "center", "radius", "material", "interior_medium", "exterior_medium",
             "keeps_medium");
        sphere sp;
        TRY(json_vec3(o, P, "center", 1, &sp.c, e));
        TRY(sl_check_point(sp.c, P, "center", e));
        TRY(json_number(o, P, "radius", 1, &sp.r, e));
        if (!(sp.r > 0))
            return json_fail(e, PM_EINVAL, "%s.radius: must be positive, got %g", P, sp.r);
        if (!(sp.r >= SCENE_LENGTH_MIN && sp.r <= SCENE_LENGTH_MAX))
            return json_fail(e, PM_EINVAL, "%s.radius: %g is outside the supported range of "
                             "lengths, %g to %g", P, sp.r, SCENE_LENGTH_MIN, SCENE_LENGTH_MAX);
        TRY(find_material(s, o, P, &mat, e));
        sp.mat = mat;
        sp.light = -1;
        int n = s->nspheres;
        if (sl_push((void **)&s->spheres, &s->nspheres, &cp->scap, sizeof sp, &sp) < 0 ||
            sl_push((void **)&s->sphere_obj, &n, &cp->socap, sizeof cp->obj, &cp->obj) < 0)
            return json_fail(e, PM_ENOMEM, "out of memory");
    } else if (strcmp(type, "triangle") == 0 || strcmp(type, "quad") == 0) {
        int nv = strcmp(type, "quad") == 0 ? 4 : 3; /* a quad is the fan (0 1 2) (0 2 3) */
        KEYS(o, P, nv == 4 ? "a quad" : "a triangle", "type", "name", "vertices", "material",
             "interior_medium", "exterior_medium", "keeps_medium");
        vec3 v[4];
        TRY(read_points(o, P, "vertices", nv, v, e));
        if (nv == 4) TRY(quad_fan_covers(v, P, e));
        TRY(find_material(s, o, P, &mat, e));
        for (int i = 1; i + 1 < nv; i++) TRY(add_tri(s, cp, v[0], v[i], v[i + 1], mat, P, e));
    } else if (strcmp(type, "mesh") == 0 && json_get(o, "file")) {
        KEYS(o, P, "a mesh from a file", "type", "name", "file", "material", "usemtl", "transform", "smooth",
             "recompute_normals", "flip", "interior_medium", "exterior_medium", "keeps_medium", "vertices",
             "triangles"); /* import.c: not both */
        return load_mesh_file(s, cp, o, P, e);
    } else if (strcmp(type, "mesh") == 0) {
        KEYS(o, P, "a mesh", "type", "name", "vertices", "triangles", "normals", "smooth", "material", "interior_medium",
             "exterior_medium", "keeps_medium",
             "file");
        const cJSON *va, *ta;
        TRY(json_array(o, P, "vertices", 1, &va, e));
        TRY(json_array(o, P, "triangles", 1, &ta, e));
        TRY(find_material(s, o, P, &mat, e));
        int nv = cJSON_GetArraySize(va), nt = cJSON_GetArraySize(ta);
        if (nt == 0) return json_fail(e, PM_EINVAL, "%s.triangles: empty mesh", P);
        vec3 *v = malloc((size_t)(nv > 0 ? nv : 1) * sizeof *v);
        if (!v) return json_fail(e, PM_ENOMEM, "out of memory");
        char pk[P_MAX], p[P_MAX];
        int rc = 0, i = 0;
        json_path_key(pk, sizeof pk, P, "vertices");
        for (const cJSON *it = va->child; it && rc == 0; it = it->next, i++) {
            json_path_index(p, sizeof p, pk, i);
            rc = json_item_vec3(it, p, &v[i], e);
        }
        /* smooth shading (the normals given per vertex, else made as for mesh files) */
        int smooth = 0;
        vec3 *vn = NULL;
        if (rc == 0) rc = json_bool(o, P, "smooth", 0, &smooth, e);
        const cJSON *na = json_get(o, "normals");
        if (rc == 0 && na && !smooth)
            rc = json_fail(e, PM_EINVAL, "%s.normals: used only with \"smooth\": true", P);
        if (rc == 0 && na && (!cJSON_IsArray(na) || cJSON_GetArraySize(na) != nv))
            rc = json_fail(e, PM_EINVAL, "%s.normals: expected one normal per vertex (%d)", P, nv);
        if (rc == 0 && na) {
            vn = malloc((size_t)(nv > 0 ? nv : 1) * sizeof *vn);
            if (!vn) rc = json_fail(e, PM_ENOMEM, "out of memory");
            json_path_key(pk, sizeof pk, P, "normals");
            i = 0;
            for (const cJSON *it = na->child; it && rc == 0; it = it->next, i++) {
                json_path_index(p, sizeof p, pk, i);
                rc = json_item_vec3(it, p, &vn[i], e);
                if (rc == 0 && v3_iszero(vn[i])) rc = json_fail(e, PM_EINVAL, "%s: a zero normal", p);
            }
        }
        int (*tv)[3] = smooth && rc == 0 ? malloc((size_t)nt * sizeof *tv) : NULL;
        if (smooth && rc == 0 && !tv) rc = json_fail(e, PM_ENOMEM, "out of memory");
        int first = s->ntris;
        json_path_key(pk, sizeof pk, P, "triangles");
        i = 0;
        for (const cJSON *it = ta->child; it && rc == 0; it = it->next, i++) {
            json_path_index(p, sizeof p, pk, i);
            vec3 idx;
            rc = json_item_vec3(it, p, &idx, e);
            if (rc < 0) break;
            double ix[3] = {idx.x, idx.y, idx.z};
            for (int k = 0; k < 3 && rc == 0; k++)
                if (ix[k] != floor(ix[k]) || ix[k] < 0 || ix[k] >= nv)
                    rc = json_fail(e, PM_EINVAL, "%s[%d]: vertex index %g is not an integer in [0, %d)",
                                   p, k, ix[k], nv);
            if (rc == 0) rc = add_tri(s, cp, v[(int)ix[0]], v[(int)ix[1]], v[(int)ix[2]], mat, p, e);
            if (rc == 0 && tv)
                for (int k = 0; k < 3; k++) tv[i][k] = (int)ix[k];
        }
        if (rc == 0 && smooth) rc = inline_smooth(s, first, v, nv, vn, tv, nt, e);
        free(tv);
        free(vn);
        free(v);
        return rc;
    } else {
        return json_fail(e, PM_EINVAL,
                         "%s.type: unknown object type \"%s\" (sphere, triangle, quad, mesh)", P, type);
    }
    return 0;
}

