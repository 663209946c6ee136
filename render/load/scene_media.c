/* scene_media.c: the media of a JSON scene (scene_load_internal.h): the named homogeneous
 * media, an object's interior medium with the check that its surface is closed, and the medium
 * the camera is in.
 */
#define _XOPEN_SOURCE 700
#include "load/scene_load_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"

/* A medium's coefficient (per unit length): in [0, 1 / SCENE_LENGTH_MIN], a mean free path no
 * shorter than the shortest length the scene may have. */
static int check_sigma_rgb(rgb c, const char *path, const char *key, json_err *e) {
    TRY(sl_check_nonneg_rgb(c, path, key, e));
    if (v3_maxabs(c) > 1 / SCENE_LENGTH_MIN)
        return json_fail(e, PM_EINVAL, "%s.%s: %g is outside the supported range, 0 to %g per unit "
                         "length (a mean free path of at least %g, the shortest supported length)",
                         path, key, v3_maxabs(c), 1 / SCENE_LENGTH_MIN, SCENE_LENGTH_MIN);
    return 0;
}

/* $.media: named homogeneous media (medium.h). */
int sl_load_media(scene *s, const cJSON *root, json_err *e) {
    const cJSON *ms;
    TRY(json_object(root, "$", "media", 0, &ms, e));
    int n = ms ? cJSON_GetArraySize(ms) : 0;
    if (n == 0) return 0;
    s->media = calloc((size_t)n, sizeof *s->media);
    if (!s->media) return json_fail(e, PM_ENOMEM, "out of memory");
    char P[P_MAX];
    for (const cJSON *it = ms->child; it; it = it->next) {
        if (sl_is_comment(it)) continue;
        medium *m = &s->media[s->nmedia];
        json_path_key(P, sizeof P, "$.media", it->string ? it->string : "?");
        if (!cJSON_IsObject(it))
            return json_fail(e, PM_EINVAL, "%s: expected an object, got %s", P, json_type_name(it));
        if (strlen(it->string) >= sizeof m->name)
            return json_fail(e, PM_EINVAL, "%s: medium name too long (max %d characters)", P,
                             (int)sizeof m->name - 1);
        snprintf(m->name, sizeof m->name, "%s", it->string);
        KEYS(it, P, "a medium", "sigma_a", "sigma_s", "g");
        TRY(json_rgb(it, P, "sigma_a", 0, &m->sigma_a, e));
        TRY(check_sigma_rgb(m->sigma_a, P, "sigma_a", e));
        TRY(json_rgb(it, P, "sigma_s", 0, &m->sigma_s, e));
        TRY(check_sigma_rgb(m->sigma_s, P, "sigma_s", e));
        TRY(json_number(it, P, "g", 0, &m->g, e));
        if (!(m->g > -1 && m->g < 1))
            return json_fail(e, PM_EINVAL, "%s.g: must be in (-1, 1), got %g", P, m->g);
        m->sigma_t = v3_add(m->sigma_a, m->sigma_s);
        s->nmedia++;
    }
    return 0;
}

/* The index of the medium named by the string at obj.key, in *out. */
int sl_find_medium(const scene *s, const cJSON *obj, const char *P, const char *key, int *out,
                       json_err *e) {
    const char *name;
    TRY(json_string(obj, P, key, 1, &name, e));
    for (int i = 0; i < s->nmedia; i++)
        if (strcmp(s->media[i].name, name) == 0) {
            *out = i;
            return 0;
        }
    return json_fail(e, PM_EINVAL, "%s.%s: unknown medium \"%s\" (not in $.media)", P, key, name);
}

/* x rounded to float (the closedness check's tolerance, below). */
static double as_float(double x) {
    float f = (float)x;
    return (double)f;
}

/* Edge order for the closedness check: the 6 coordinates of a directed edge. */
static int edge_cmp(const void *a, const void *b) {
    const double *x = a, *y = b;
    for (int k = 0; k < 6; k++)
        if (x[k] != y[k]) return x[k] < y[k] ? -1 : 1;
    return 0;
}

/* Triangles first..s->ntris-1 bound a medium only if they form a closed, consistently wound
 * surface whose normals point out: each directed edge (by vertex position) appears once and
 * its reverse once, and the enclosed signed volume is positive. A triangle keeps v0 and two
 * edge vectors, so its other corners come back as v0 + e, which can miss the loaded vertex by
 * a rounding of the double: positions are compared rounded to float (vertices closer than
 * float precision count as one, which only makes the check more lenient). */
static int check_closed(const scene *s, int first, const char *P, json_err *e) {
    int nt = s->ntris - first;
    if (nt < 4)
        return json_fail(e, PM_EINVAL, "%s.interior_medium: a medium needs a closed surface "
                         "(this one has %d triangles)", P, nt);
    double(*ed)[6] = malloc((size_t)nt * 3 * sizeof *ed);
    if (!ed) return json_fail(e, PM_ENOMEM, "out of memory");
    double vol = 0;
    for (int t = 0; t < nt; t++) {
        const triangle *tr = &s->tris[first + t];
        vec3 v[3] = {tr->v0, v3_add(tr->v0, tr->e1), v3_add(tr->v0, tr->e2)};
        vol += v3_dot(v[0], v3_cross(v[1], v[2])) / 6;
        for (int k = 0; k < 3; k++) {
            vec3 a = v[k], b = v[(k + 1) % 3];
            double *d = ed[3 * t + k];
            const double c[6] = {a.x, a.y, a.z, b.x, b.y, b.z};
            for (int j = 0; j < 6; j++) d[j] = as_float(c[j]);
        }
    }
    int n = 3 * nt, bad = 0;
    qsort(ed, (size_t)n, sizeof *ed, edge_cmp);
    for (int i = 0; i < n && !bad; i++) {
        double rev[6] = {ed[i][3], ed[i][4], ed[i][5], ed[i][0], ed[i][1], ed[i][2]};
        if (i + 1 < n && edge_cmp(ed[i], ed[i + 1]) == 0) bad = 1; /* an edge used twice one way */
        else if (!bsearch(rev, ed, (size_t)n, sizeof *ed, edge_cmp)) bad = 2; /* an open edge */
    }
    free(ed);
    if (bad)
        return json_fail(e, PM_EINVAL, "%s.interior_medium: a medium needs a closed surface, "
                         "consistently wound (%s)", P,
                         bad == 1 ? "an edge is shared by faces of the same winding"
                                  : "an edge belongs to one face only: the mesh is open");
    if (!(vol > 0))
        return json_fail(e, PM_EINVAL, "%s.interior_medium: the surface's normals point inward "
                         "(reverse the winding so the front side is the outside)", P);
    return 0;
}

/* An object's "interior_medium": spheres and closed meshes only. */
int sl_load_interior_medium(scene *s, const cJSON *o, const char *P, int obj, int first_tri,
                                json_err *e) {
    if (!json_get(o, "interior_medium")) return 0;
    int med = -1;
    TRY(sl_find_medium(s, o, P, "interior_medium", &med, e));
    const char *type = json_get(o, "type")->valuestring;
    if (strcmp(type, "triangle") == 0 || strcmp(type, "quad") == 0)
        return json_fail(e, PM_EINVAL, "%s.interior_medium: a %s is open and cannot bound a medium "
                         "(use a sphere or a closed mesh)", P, type);
    if (strcmp(type, "mesh") == 0) TRY(check_closed(s, first_tri, P, e));
    s->obj_medium[obj] = med;
    return 0;
}

/* Which medium the camera is in: the side of the nearest surface a ray from the eye meets
 * (the rule of medium.h); the global medium when it meets nothing. */
void sl_find_camera_medium(scene *s) {
    s->camera_medium = s->global_medium;
    if (s->nmedia == 0) return;
    ray r = {s->cam.eye, s->cam.forward};
    hit h;
    if (scene_intersect(s, r, INFINITY, &h))
        s->camera_medium = scene_medium_after(s, &h, v3_neg(r.d));
}

