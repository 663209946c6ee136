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
#include "scene/medium.h"

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

/* A directed edge of a face of the closedness check: its 6 rounded coordinates and the
 * triangle it comes from. */
typedef struct {
    double c[6];
    int tri;
} edge_rec;

static int edge_cmp(const void *a, const void *b) {
    const double *x = ((const edge_rec *)a)->c, *y = ((const edge_rec *)b)->c;
    for (int k = 0; k < 6; k++)
        if (x[k] != y[k]) return x[k] < y[k] ? -1 : 1;
    return 0;
}

/* Triangle t's corners (flip: reversed) rounded, as 3 directed edges into ed[0..2]. */
static void tri_edges(const scene *s, int t, int flip, edge_rec *ed) {
    const triangle *tr = &s->tris[t];
    vec3 v[3] = {tr->v0, v3_add(tr->v0, tr->e1), v3_add(tr->v0, tr->e2)};
    if (flip) {
        vec3 w = v[1];
        v[1] = v[2];
        v[2] = w;
    }
    for (int k = 0; k < 3; k++) {
        vec3 a = v[k], b = v[(k + 1) % 3];
        const double c[6] = {a.x, a.y, a.z, b.x, b.y, b.z};
        for (int j = 0; j < 6; j++) ed[k].c[j] = as_float(c[j]);
        ed[k].tri = t;
    }
}

static double tri_volume(const scene *s, int t, int flip) {
    const triangle *tr = &s->tris[t];
    vec3 a = tr->v0, b = v3_add(tr->v0, tr->e1), c = v3_add(tr->v0, tr->e2);
    double v = v3_dot(a, v3_cross(b, c)) / 6;
    return flip ? -v : v;
}

static void reverse_edge(const edge_rec *e, edge_rec *r) {
    for (int j = 0; j < 3; j++) r->c[j] = e->c[j + 3], r->c[j + 3] = e->c[j];
    r->tri = e->tri;
}

/* An undirected key: the smaller end first. */
static void undirected(const edge_rec *e, edge_rec *u) {
    edge_rec r;
    reverse_edge(e, &r);
    *u = edge_cmp(e, &r) <= 0 ? *e : r;
}

typedef struct {
    edge_rec *ed, *ke; /* the medium's directed edges; the keep surfaces' undirected edges */
    int n, cap, nk;
    unsigned char *used; /* per triangle: a keep surface taken into the boundary */
    double vol;
} closure;

static int push_face(closure *c, const scene *s, int t, int flip) {
    if (c->n + 3 > c->cap) {
        int cap = c->cap ? 2 * c->cap : 96;
        edge_rec *n = realloc(c->ed, (size_t)cap * sizeof *n);
        if (!n) return PM_ENOMEM;
        c->ed = n, c->cap = cap;
    }
    tri_edges(s, t, flip, c->ed + c->n);
    c->n += 3;
    c->vol += tri_volume(s, t, flip);
    return 0;
}

/* Close the open edges of c with opaque surfaces and those that keep the medium
 * (MEDIUM_IFACE_KEEP: walls that name no medium) that share them, each turned to continue
 * the boundary's winding, until none is added. */
static int close_with_keep(closure *c, const scene *s) {
    for (int added = c->n > 0; added;) { /* only spheres: no edges */
        added = 0;
        qsort(c->ed, (size_t)c->n, sizeof *c->ed, edge_cmp);
        for (int i = 0, n = c->n; i < n; i++) {
            edge_rec r, u;
            reverse_edge(&c->ed[i], &r);
            if (bsearch(&r, c->ed, (size_t)n, sizeof *c->ed, edge_cmp)) continue;
            undirected(&c->ed[i], &u);
            edge_rec *k = c->nk ? bsearch(&u, c->ke, (size_t)c->nk, sizeof *c->ke, edge_cmp) : NULL;
            while (k && k > c->ke && edge_cmp(k - 1, &u) == 0) k--;
            for (; k && k < c->ke + c->nk && edge_cmp(k, &u) == 0; k++) {
                if (c->used[k->tri]) continue;
                edge_rec te[3];
                tri_edges(s, k->tri, 0, te);
                int as_is = 0;
                for (int j = 0; j < 3; j++) as_is |= edge_cmp(&te[j], &r) == 0;
                c->used[k->tri] = 1;
                if (push_face(c, s, k->tri, !as_is) < 0) return PM_ENOMEM;
                added = 1;
                break;
            }
        }
    }
    return 0;
}

/* T-JUNCTIONS. A boundary whose faces meet at a vertex that lies on another face's edge (a
 * wall split in two beside a whole one) is closed, but its edges do not pair. Each directed
 * edge without a reverse is split at the endpoints of the other such edges that lie on it
 * (within T_JUNCTION_TOL of its length from the line, strictly between its ends), so the
 * pieces pair with the smaller faces' edges; rounding (as_float) stays the only tolerance
 * for positions. Up to T_JUNCTION_MAX unpaired edges (each against all their endpoints);
 * more is an open boundary anyway, refused as before. The volume is the faces' own. */
#define T_JUNCTION_TOL 1e-6
#define T_JUNCTION_MAX 20000

static int has_reverse(const closure *c, const edge_rec *e) {
    edge_rec r;
    reverse_edge(e, &r);
    return bsearch(&r, c->ed, (size_t)c->n, sizeof *c->ed, edge_cmp) != NULL;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* The parameters t in (0, 1) of the points pts (np of them, 3 each) on edge e, sorted, into t. */
static int points_on_edge(const edge_rec *e, const double *pts, int np, double *t) {
    vec3 a = v3(e->c[0], e->c[1], e->c[2]), d = v3_sub(v3(e->c[3], e->c[4], e->c[5]), a);
    double l2 = v3_len2(d), tol = T_JUNCTION_TOL * sqrt(l2);
    int k = 0;
    for (int i = 0; i < np && l2 > 0; i++) {
        vec3 p = v3(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]), ap = v3_sub(p, a);
        double u = v3_dot(ap, d) / l2;
        if (!(u > 0 && u < 1) || v3_len(v3_sub(ap, v3_scale(d, u))) > tol) continue;
        t[k++] = u;
    }
    qsort(t, (size_t)k, sizeof *t, cmp_double);
    return k;
}

static int split_t_junctions(closure *c) {
    int nu = 0;
    for (int i = 0; i < c->n; i++) nu += !has_reverse(c, &c->ed[i]);
    if (nu == 0 || nu > T_JUNCTION_MAX) return 0;
    int *u = malloc((size_t)nu * sizeof *u);
    double *pts = malloc((size_t)nu * 6 * sizeof *pts), *t = malloc((size_t)nu * 2 * sizeof *t);
    int rc = u && pts && t ? 0 : PM_ENOMEM, m = 0;
    for (int i = 0; i < c->n && rc == 0; i++)
        if (!has_reverse(c, &c->ed[i])) {
            memcpy(pts + 6 * m, c->ed[i].c, 6 * sizeof *pts);
            u[m++] = i;
        }
    int n0 = c->n;
    for (int j = 0; j < m && rc == 0; j++) {
        edge_rec e = c->ed[u[j]];
        int k = points_on_edge(&e, pts, 2 * m, t);
        if (k == 0) continue;
        if (c->n + k > c->cap) {
            int cap = 2 * (c->n + k);
            edge_rec *g = realloc(c->ed, (size_t)cap * sizeof *g);
            if (!g) {
                rc = PM_ENOMEM;
                break;
            }
            c->ed = g, c->cap = cap;
        }
        /* e becomes its first piece; the others are appended (t sorted: duplicates skipped) */
        vec3 a = v3(e.c[0], e.c[1], e.c[2]), d = v3_sub(v3(e.c[3], e.c[4], e.c[5]), a);
        double prev[3] = {e.c[0], e.c[1], e.c[2]};
        int first = 1;
        for (int q = 0; q <= k; q++) {
            double next[3];
            if (q < k) {
                /* the piece ends at the listed point itself (its rounded coordinates) */
                vec3 p = v3_add(a, v3_scale(d, t[q]));
                double best = INFINITY;
                for (int i = 0; i < 2 * m; i++) {
                    double dd = v3_len2(v3_sub(v3(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]), p));
                    if (dd < best) best = dd, memcpy(next, pts + 3 * i, sizeof next);
                }
                if (next[0] == prev[0] && next[1] == prev[1] && next[2] == prev[2]) continue;
            } else {
                memcpy(next, e.c + 3, sizeof next);
            }
            edge_rec *dst = first ? &c->ed[u[j]] : &c->ed[c->n++];
            memcpy(dst->c, prev, sizeof prev);
            memcpy(dst->c + 3, next, sizeof next);
            dst->tri = e.tri;
            memcpy(prev, next, sizeof prev);
            first = 0;
        }
    }
    if (rc == 0 && c->n != n0) qsort(c->ed, (size_t)c->n, sizeof *c->ed, edge_cmp);
    free(u);
    free(pts);
    free(t);
    return rc;
}

/* The message for a medium whose boundary is open, crossed or inside out. */
static int closure_fail(const scene *s, int m, const edge_rec *e, int kind, double vol, json_err *err) {
    char P[P_MAX];
    json_path_key(P, sizeof P, "$.media", s->media[m].name);
    if (kind == 0)
        return json_fail(err, PM_EINVAL, "%s: the surfaces around the medium \"%s\" enclose a volume of %g: their "
                         "sides are swapped, or the medium is unbounded (it is interior_medium of surfaces whose "
                         "normals point out of it; a medium around everything is the global \"medium\", the "
                         "camera's in a Tungsten scene)", P, s->media[m].name, vol);
    return json_fail(err, PM_EINVAL, "%s: the surfaces around the medium \"%s\" do not close it: the edge (%g, %g, "
                     "%g)-(%g, %g, %g) of $.objects[%d] %s (a medium needs a closed boundary: every edge shared by "
                     "two of the faces that have it on one side, or by an opaque surface; an opaque object inside the "
                     "medium has it on both sides, or keeps_medium)", P,
                     s->media[m].name, e->c[0], e->c[1], e->c[2], e->c[3], e->c[4], e->c[5], s->tri_obj[e->tri],
                     kind == 1 ? "is shared by two faces that wind the same way around it"
                               : "belongs to one face only: the boundary is open");
}

/* Can light cross this material (so a medium can leak through a gap next to it)? */
static int crossable(const scene *s, int mat) {
    return s->mats[mat].kind == MAT_NULL || s->mats[mat].transparency > 0;
}

/* Medium m's boundary: every surface with m on one side (oriented out of m), plus the opaque
 * surfaces and those that keep the medium that close it (a ray cannot leave through an opaque
 * wall, whatever media it names); then each directed edge once and its reverse once, and a
 * positive enclosed volume. Spheres are closed and only add their volume. */
static int check_medium_closed(const scene *s, int m, closure *c, json_err *err) {
    int any = 0;
    c->n = 0, c->vol = 0;
    memset(c->used, 0, (size_t)(s->ntris > 0 ? s->ntris : 1));
    for (int t = 0; t < s->ntris; t++) {
        int o = s->tri_obj[t], in = scene_object_side_medium(s, o, 0), out = scene_object_side_medium(s, o, 1);
        if (in == -2 || (in == m) == (out == m)) continue;
        if (push_face(c, s, t, out == m) < 0) return json_fail(err, PM_ENOMEM, "out of memory");
        c->used[t] = 1;
        any = 1;
    }
    for (int k = 0; k < s->nspheres; k++) {
        int o = s->sphere_obj[k], in = scene_object_side_medium(s, o, 0), out = scene_object_side_medium(s, o, 1);
        if (in == -2 || (in == m) == (out == m)) continue;
        double r = s->spheres[k].r, v = 4 * M_PI / 3 * r * r * r;
        c->vol += in == m ? v : -v;
        any = 1;
    }
    if (!any) return 0;
    if (close_with_keep(c, s) < 0 || split_t_junctions(c) < 0) return json_fail(err, PM_ENOMEM, "out of memory");
    for (int i = 0; i < c->n; i++) {
        edge_rec r;
        reverse_edge(&c->ed[i], &r);
        if (i + 1 < c->n && edge_cmp(&c->ed[i], &c->ed[i + 1]) == 0) return closure_fail(s, m, &c->ed[i], 1, 0, err);
        if (!bsearch(&r, c->ed, (size_t)c->n, sizeof *c->ed, edge_cmp)) return closure_fail(s, m, &c->ed[i], 2, 0, err);
    }
    if (!(c->vol > 0)) return closure_fail(s, m, NULL, 0, c->vol, err);
    return 0;
}

/* Every medium but the global one (it is the unbounded space between objects) must be closed
 * by the surfaces around it together (medium.h), opaque walls included. */
int sl_check_media_closed(scene *s, json_err *e) {
    if (s->nmedia == 0) return 0;
    closure c = {0};
    c.used = malloc((size_t)(s->ntris > 0 ? s->ntris : 1));
    int rc = c.used ? 0 : json_fail(e, PM_ENOMEM, "out of memory");
    for (int t = 0; t < s->ntris && rc == 0; t++) {
        if (scene_object_side_medium(s, s->tri_obj[t], 0) != -2 && crossable(s, s->tris[t].mat)) continue;
        edge_rec *n = realloc(c.ke, (size_t)(c.nk + 3) * sizeof *n);
        if (!n) {
            rc = json_fail(e, PM_ENOMEM, "out of memory");
            break;
        }
        c.ke = n;
        tri_edges(s, t, 0, c.ke + c.nk);
        for (int j = 0; j < 3; j++) undirected(&c.ke[c.nk + j], &c.ke[c.nk + j]);
        c.nk += 3;
    }
    if (c.nk) qsort(c.ke, (size_t)c.nk, sizeof *c.ke, edge_cmp);
    for (int m = 0; m < s->nmedia && rc == 0; m++)
        if (m != s->global_medium) rc = check_medium_closed(s, m, &c, e);
    free(c.ed);
    free(c.ke);
    free(c.used);
    return rc;
}

/* A medium key of an object: a name from $.media, or null (no medium). */
static int object_medium_key(const scene *s, const cJSON *o, const char *P, const char *key, int *out, json_err *e) {
    const cJSON *v = json_get(o, key);
    if (cJSON_IsNull(v)) {
        *out = -1;
        return 0;
    }
    return sl_find_medium(s, o, P, key, out, e);
}

/* An object's media (medium.h): "interior_medium" and "exterior_medium" (names or null) make
 * it an interface, "keeps_medium": true none. */
int sl_load_object_media(scene *s, const cJSON *o, const char *P, int obj, json_err *e) {
    const cJSON *im = json_get(o, "interior_medium"), *xm = json_get(o, "exterior_medium");
    int keep = 0;
    TRY(json_bool(o, P, "keeps_medium", 0, &keep, e));
    if (keep && (im || xm))
        return json_fail(e, PM_EINVAL, "%s.keeps_medium: an object that keeps the ray's medium names none "
                         "(drop interior_medium and exterior_medium, or keeps_medium)", P);
    if (!im && !xm && !keep) return 0;
    if (!s->obj_iface) {
        s->obj_iface = calloc((size_t)s->nobj, 1);
        s->obj_medium_out = malloc((size_t)s->nobj * sizeof *s->obj_medium_out);
        if (!s->obj_iface || !s->obj_medium_out) return json_fail(e, PM_ENOMEM, "out of memory");
        for (int k = 0; k < s->nobj; k++) s->obj_medium_out[k] = s->global_medium;
    }
    s->obj_iface[obj] = keep ? MEDIUM_IFACE_KEEP : MEDIUM_IFACE_DECLARED;
    if (im) TRY(object_medium_key(s, o, P, "interior_medium", &s->obj_medium[obj], e));
    if (xm) TRY(object_medium_key(s, o, P, "exterior_medium", &s->obj_medium_out[obj], e));
    return 0;
}

/* Which medium the camera is in: scene_medium_ahead along the view axis (medium.h). */
void sl_find_camera_medium(scene *s) {
    s->camera_medium = s->global_medium;
    if (s->nmedia == 0) return;
    ray r = {s->cam.eye, s->cam.forward};
    s->camera_medium = scene_medium_ahead(s, r);
}
