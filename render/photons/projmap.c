/* projmap.c: caustic projection maps (Jensen's eq. 2.2); see projmap.h.
 *
 * A cell is tested with nine points (corners, edge midpoints, centre): their directions (or
 * disc positions) bound a cone (or a tube), widened by a quarter for the curvature between
 * the points, and the cell is active when that cone meets the bounding sphere of any
 * specular primitive.
 */
#include "photons/projmap.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "scene/material.h"
#include "base/sampling.h"

/* Bounding spheres of the specular primitives. */
typedef struct bsph {
    vec3 c;
    double r;
} bsph;

static int specular_spheres(const scene *s, bsph **out) {
    int n = 0;
    bsph *v = malloc((size_t)(s->ntris + s->nspheres + 1) * sizeof *v);
    if (!v) return PM_ENOMEM;
    for (int i = 0; i < s->ntris; i++) {
        const triangle *t = &s->tris[i];
        if (!material_is_specular(&s->mats[t->mat])) continue;
        vec3 a = t->v0, b = v3_add(t->v0, t->e1), c = v3_add(t->v0, t->e2);
        vec3 m = v3_scale(v3_add(a, v3_add(b, c)), 1.0 / 3);
        double r = sqrt(fmax(v3_len2(v3_sub(a, m)), fmax(v3_len2(v3_sub(b, m)), v3_len2(v3_sub(c, m)))));
        v[n++] = (bsph){m, r * 1.001};
    }
    for (int i = 0; i < s->nspheres; i++) {
        const sphere *sp = &s->spheres[i];
        if (!material_is_specular(&s->mats[sp->mat])) continue;
        v[n++] = (bsph){sp->c, sp->r * 1.001};
    }
    *out = v;
    return n;
}

/* Which pair of light_sample_le's u[] the projection grid covers: the direction for area
 * (u[2], u[3]) and point lights (u[0], u[1]), the disc position for directional lights. */
int projmap_dim(const light *l) { return l->type == LIGHT_AREA ? 2 : 0; }

/* What a cell's cone test needs of light li, computed once per light rather than once per
 * cell (the cones of area and point lights). Each sphere i seen from the light's centre:
 * ocn[i] its direction, sh[i] = sin and ch[i] = cos of the half angle it subtends, half[i]
 * that angle, asin(R / dist); R is the sphere's radius widened by the light's own. */
typedef struct cone_view {
    vec3 pc, normals[2];
    double rl;
    int nsides;
    int inside; /* the light's centre lies within a widened sphere: every cell is active */
    int last;   /* the sphere that met the previous cell's cone: neighbouring cells' cones
                 * mostly meet the same one, so it is tried first (the answer is the same) */
    vec3 *oc;
    double *dist, *half, *sh, *ch;
} cone_view;

/* Member by member: the view's own arrays (gather_guide.c frees another struct's alike). */
static void cone_view_free(cone_view *v) {
    free(v->oc);
    free(v->dist);
    free(v->half);
    free(v->sh);
    free(v->ch);
}

static int cone_view_init(cone_view *v, const scene *s, int li, const bsph *sph, int nsph) {
    const light *l = &s->lights[li];
    memset(v, 0, sizeof *v);
    v->nsides = 1;
    if (l->type == LIGHT_AREA) {
        const triangle *t = &s->tris[l->tri];
        vec3 a = t->v0, b = v3_add(t->v0, t->e1), c = v3_add(t->v0, t->e2);
        v->pc = v3_scale(v3_add(a, v3_add(b, c)), 1.0 / 3);
        v->rl = sqrt(fmax(v3_len2(v3_sub(a, v->pc)), fmax(v3_len2(v3_sub(b, v->pc)), v3_len2(v3_sub(c, v->pc)))));
        v->normals[0] = t->n;
        v->normals[1] = v3_neg(t->n);
        v->nsides = l->two_sided ? 2 : 1;
    } else {
        v->pc = l->pos;
    }
    size_t n = (size_t)(nsph > 0 ? nsph : 1);
    v->oc = malloc(n * sizeof *v->oc);
    v->dist = malloc(n * sizeof *v->dist);
    v->half = malloc(n * sizeof *v->half);
    v->sh = malloc(n * sizeof *v->sh);
    v->ch = malloc(n * sizeof *v->ch);
    if (!v->oc || !v->dist || !v->half || !v->sh || !v->ch) {
        cone_view_free(v);
        return PM_ENOMEM;
    }
    for (int i = 0; i < nsph; i++) {
        v->oc[i] = v3_sub(sph[i].c, v->pc);
        v->dist[i] = v3_len(v->oc[i]);
        double R = sph[i].r + v->rl;
        if (v->dist[i] <= R) {
            v->inside = 1;
            continue;
        }
        v->sh[i] = R / v->dist[i];
        v->half[i] = asin(v->sh[i]);
        v->ch[i] = sqrt(fmax(0.0, 1 - v->sh[i] * v->sh[i]));
    }
    return 0;
}

/* Does a cone of half angle ang around dc meet sphere i? The exact test compares the angle
 * between dc and the sphere, acos(c), with half[i] + ang. The cosines decide first: cos is
 * 1-Lipschitz and decreasing on [0, pi], so where c differs from cos(half[i] + ang) (from the
 * sum formula with ca = cos ang, sa = sin ang) by more than CONE_MARGIN, far above those few
 * roundings, the exact test gives the same answer; only the cases within the margin pay for
 * the two inverse cosines (the same cells are active as with the trigonometry alone). */
#define CONE_MARGIN 1e-9
static int cone_meets(const cone_view *v, int i, vec3 dc, double ang, double ca, double sa) {
    double c = v3_dot(v->oc[i], dc) / v->dist[i]; /* dist > 0: not NaN */
    if (c > 1) c = 1;
    if (c < -1) c = -1;
    double th = v->half[i] + ang;
    if (th >= M_PI) return 1;
    double cth = v->ch[i] * ca - v->sh[i] * sa;
    if (c > cth + CONE_MARGIN) return 1;
    if (c < cth - CONE_MARGIN) return 0;
    return acos(c) <= th;
}

/* Is cell (cx, cy) of light li's G x G grid able to send a photon into a sphere of sph?
 * cv: the light's cone view (area, point and spot lights; NULL for the others). */
static int cell_active(const scene *s, int li, int G, int cx, int cy, const bsph *sph, int nsph,
                       cone_view *cv) {
    const light *l = &s->lights[li];
    /* A sphere light's normal changes over its surface, so a cell of directions bounds no
     * cone: every cell stays active (no saving, no loss). */
    if (l->type == LIGHT_SPHERE || l->type == LIGHT_INFINITE) return 1; /* infinite: any cell reaches anything */
    /* Nine points of the cell: corners, edge midpoints, centre. */
    double pu[9], pv[9];
    int k = 0;
    for (int a = 0; a <= 2; a++)
        for (int b = 0; b <= 2; b++) {
            pu[k] = (cx + 0.5 * a) / G;
            pv[k] = (cy + 0.5 * b) / G;
            if (pu[k] >= 1) pu[k] = 0x1.fffffffffffffp-1;
            if (pv[k] >= 1) pv[k] = 0x1.fffffffffffffp-1;
            k++;
        }
    if (l->type == LIGHT_DIRECTIONAL) {
        vec3 pts[9], p, n, d;
        for (int j = 0; j < 9; j++) {
            double u[4] = {pu[j], pv[j], 0, 0};
            light_sample_le(s, li, u, &p, &n, &d);
            pts[j] = p;
        }
        vec3 pc = pts[4];
        double pr = 0;
        for (int j = 0; j < 9; j++) pr = fmax(pr, v3_len(v3_sub(pts[j], pc)));
        pr = pr * 1.25 + 1e-9 * s->bsphere_r;
        for (int i = 0; i < nsph; i++) {
            vec3 oc = v3_sub(sph[i].c, pc);
            double t = v3_dot(oc, l->dir);
            double dist2 = v3_len2(oc) - t * t;
            double rr = sph[i].r + pr;
            if (dist2 <= rr * rr && t > -rr) return 1;
        }
        return 0;
    }
    /* Area or point: a cone of directions from the light's centre, widened by the light's
     * own radius (a ray from a point within r_l of the centre hitting a sphere of radius R
     * means the parallel ray from the centre passes within R + r_l of its centre). */
    if (cv->inside) return 1;
    for (int side = 0; side < cv->nsides; side++) {
        vec3 dirs[9];
        for (int j = 0; j < 9; j++)
            if (l->type == LIGHT_SPOT) { /* the spot's own map of (u[0], u[1]) to directions */
                double u[4] = {pu[j], pv[j], 0, 0};
                vec3 p, n;
                light_sample_le(s, li, u, &p, &n, &dirs[j]);
            } else {
                dirs[j] = l->type == LIGHT_AREA
                              ? sampling_to_world(sample_cosine_hemisphere(pu[j], pv[j]), cv->normals[side])
                              : sample_uniform_sphere(pu[j], pv[j]);
            }
        vec3 dc = dirs[4];
        double ang = 0;
        for (int j = 0; j < 9; j++) ang = fmax(ang, acos(fmin(1.0, fmax(-1.0, v3_dot(dirs[j], dc)))));
        ang = ang * 1.25 + 1e-3;
        double ca = cos(ang), sa = sin(ang);
        if (cv->last < nsph && cone_meets(cv, cv->last, dc, ang, ca, sa)) return 1;
        for (int i = 0; i < nsph; i++)
            if (cone_meets(cv, i, dc, ang, ca, sa)) {
                cv->last = i;
                return 1;
            }
    }
    return 0;
}

static int projmap_build(projmap *pm, const scene *s, int li, int G, const bsph *sph, int nsph) {
    pm->G = G;
    pm->nactive = 0;
    pm->active = malloc((size_t)G * (size_t)G * sizeof *pm->active);
    if (!pm->active) return PM_ENOMEM;
    int type = s->lights[li].type;
    int cone = type != LIGHT_SPHERE && type != LIGHT_INFINITE && type != LIGHT_DIRECTIONAL;
    cone_view cv;
    if (cone && cone_view_init(&cv, s, li, sph, nsph) != 0) {
        free(pm->active);
        pm->active = NULL;
        return PM_ENOMEM;
    }
    for (int cy = 0; cy < G; cy++)
        for (int cx = 0; cx < G; cx++)
            if (cell_active(s, li, G, cx, cy, sph, nsph, cone ? &cv : NULL)) pm->active[pm->nactive++] = cy * G + cx;
    if (cone) cone_view_free(&cv);
    pm->fraction = (double)pm->nactive / ((double)G * G);
    return 0;
}

int projmap_cells(const scene *s, int li, int G, unsigned char *active) {
    bsph *sph;
    int nsph = specular_spheres(s, &sph);
    if (nsph < 0) return nsph;
    projmap pm;
    int rc = projmap_build(&pm, s, li, G, sph, nsph);
    if (rc == 0) {
        memset(active, 0, (size_t)G * (size_t)G);
        for (int k = 0; k < pm.nactive; k++) active[pm.active[k]] = 1;
        rc = pm.nactive;
    }
    free(pm.active);
    free(sph);
    return rc;
}

int projmap_build_all(const scene *s, int G, projmap **out) {
    int nl = s->nlights, rc = 0;
    bsph *sph = NULL;
    int nsph = G > 0 ? specular_spheres(s, &sph) : 0;
    projmap *proj = calloc((size_t)(nl > 0 ? nl : 1), sizeof *proj);
    if (nsph < 0 || !proj) rc = PM_ENOMEM;
    for (int i = 0; rc == 0 && i < nl; i++) {
        if (G > 0) {
            rc = projmap_build(&proj[i], s, i, G, sph, nsph);
        } else {
            proj[i].G = 1;
            proj[i].nactive = 1;
            proj[i].active = calloc(1, sizeof(int));
            proj[i].fraction = 1;
            if (!proj[i].active) rc = PM_ENOMEM;
        }
    }
    free(sph);
    if (rc < 0) {
        projmap_free_all(proj, nl);
        proj = NULL;
    }
    *out = proj;
    return rc;
}

void projmap_free_all(projmap *pm, int n) {
    for (int i = 0; pm && i < n; i++) free(pm[i].active);
    free(pm);
}

void projmap_sample(const projmap *pm, const light *l, double uc, rng *g, double u[4]) {
    int dim = projmap_dim(l);
    int cell = pm->active[(int)fmin(pm->nactive - 1, uc * pm->nactive)];
    /* The cell's jitter comes from the photon's own stream: the Halton dimensions that
     * are not used for the cell stay stratified. */
    u[dim] = ((cell % pm->G) + rng_uniform(g)) / pm->G;
    u[dim + 1] = ((cell / pm->G) + rng_uniform(g)) / pm->G;
    if (u[dim] >= 1) u[dim] = 0x1.fffffffffffffp-1;
    if (u[dim + 1] >= 1) u[dim + 1] = 0x1.fffffffffffffp-1;
}
