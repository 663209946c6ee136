/* importance.c: importance-driven photon emission; see importance.h.
 *
 * The camera paths write their connections into fixed slots (path j, vertex v: slot
 * j IMP_DEPTH + v), so no thread decides the order of anything; the slots are then reduced in
 * one thread: the mean and the cap, a sort by (light, cell, slot) (a total order, so the sums
 * of equal cells are taken in the same order on every run), the per-cell sums and the
 * cumulative table.
 */
#include "photons/importance.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "scene/envmap.h"
#include "scene/material.h"
#include "base/rng.h"
#include "base/sampling.h"

#ifdef _OPENMP
#include <omp.h>
#endif

#define IMP_STREAM 0x696d70ULL /* "imp" */
#define IMP_MAX_BOUNCES 16     /* camera path segments, specular ones included */

static double clamp01(double u) { return u < 0 ? 0 : u < 1 ? u : 0x1.fffffffffffffp-1; }

/* The inverse of sample_concentric_disc: the (u1, u2) that map to the disc point (x, y). */
static void concentric_inverse(double x, double y, double *u1, double *u2) {
    double r = sqrt(x * x + y * y), a, b;
    if (r == 0) {
        *u1 = *u2 = 0.5;
        return;
    }
    double phi = atan2(y, x); /* (-pi, pi] */
    if (phi < -M_PI / 4) phi += 2 * M_PI; /* [-pi/4, 7pi/4) */
    if (phi < M_PI / 4) { /* a = r > |b| */
        a = r;
        b = r * phi * 4 / M_PI;
    } else if (phi < 3 * M_PI / 4) { /* b = r >= |a| */
        b = r;
        a = r * (M_PI / 2 - phi) * 4 / M_PI;
    } else if (phi < 5 * M_PI / 4) { /* a = -r, angle phi - pi */
        a = -r;
        b = -r * (phi - M_PI) * 4 / M_PI;
    } else { /* b = -r, angle phi - pi */
        b = -r;
        a = -r * (M_PI / 2 - (phi - M_PI)) * 4 / M_PI;
    }
    *u1 = clamp01((a + 1) / 2);
    *u2 = clamp01((b + 1) / 2);
}

/* (u1, u2) of sample_uniform_sphere for the unit vector d. */
static void sphere_inverse(vec3 d, double *u1, double *u2) {
    *u1 = clamp01((1 - d.z) / 2);
    double phi = atan2(d.y, d.x) / (2 * M_PI);
    if (phi < 0) phi += 1;
    *u2 = clamp01(phi);
}

/* (u2, u3) of the cosine-weighted direction d about the normal n (sampling_to_world's frame). */
static int direction_inverse(vec3 d, vec3 n, double *u2, double *u3) {
    vec3 s, t;
    v3_basis(n, &s, &t);
    if (!(v3_dot(d, n) > 0)) return 0;
    concentric_inverse(v3_dot(d, s), v3_dot(d, t), u2, u3);
    return 1;
}

int importance_invert_le(const scene *s, int li, vec3 p, vec3 d, double u[4]) {
    const light *l = &s->lights[li];
    u[0] = u[1] = u[2] = u[3] = 0.5;
    switch (l->type) {
    case LIGHT_AREA:
    case LIGHT_SPHERE: {
        vec3 nf;
        double a0, a1;
        if (l->type == LIGHT_AREA) {
            const triangle *tr = &s->tris[l->tri];
            nf = tr->n;
            /* p = v0 + b1 e1 + b2 e2: the 2 x 2 normal equations. */
            vec3 q = v3_sub(p, tr->v0);
            double e11 = v3_dot(tr->e1, tr->e1), e12 = v3_dot(tr->e1, tr->e2), e22 = v3_dot(tr->e2, tr->e2);
            double q1 = v3_dot(q, tr->e1), q2 = v3_dot(q, tr->e2), det = e11 * e22 - e12 * e12;
            double b1 = det != 0 ? (q1 * e22 - q2 * e12) / det : 0, b2 = det != 0 ? (q2 * e11 - q1 * e12) / det : 0;
            double sq = 1 - b1; /* sample_triangle: b1 = 1 - sqrt(u0), b2 = u1 sqrt(u0) */
            a0 = clamp01(sq * sq);
            a1 = sq > 0 ? clamp01(b2 / sq) : 0.5;
        } else {
            const sphere *sp = &s->spheres[l->sphere];
            nf = v3_norm(v3_sub(p, sp->c));
            sphere_inverse(nf, &a0, &a1);
        }
        int back = v3_dot(d, nf) < 0;
        if (back && !l->two_sided) return 0;
        u[0] = l->two_sided ? clamp01(back ? 0.5 + a0 / 2 : a0 / 2) : a0;
        u[1] = a1;
        return direction_inverse(d, back ? v3_neg(nf) : nf, &u[2], &u[3]);
    }
    case LIGHT_POINT: sphere_inverse(d, &u[0], &u[1]); return 1;
    case LIGHT_SPOT: return light_spot_invert(l, d, &u[0], &u[1]);
    case LIGHT_INFINITE: { /* the direction, then the point on its disc */
        if (s->env_map && !envmap_invert(s->env_map, v3_neg(d), &u[0], &u[1])) return 0;
        vec3 a, b;
        v3_basis(d, &a, &b);
        double R = s->bsphere_r > 0 ? s->bsphere_r : 1.0;
        vec3 c = v3_madd(s->bsphere_c, d, -R);
        double x = v3_dot(v3_sub(p, c), a) / R, y = v3_dot(v3_sub(p, c), b) / R;
        if (x * x + y * y >= 1) return 0;
        if (!s->env_map) sphere_inverse(d, &u[0], &u[1]);
        concentric_inverse(x, y, &u[2], &u[3]);
        return 1;
    }
    default: {
        vec3 a, b;
        v3_basis(l->dir, &a, &b);
        double R = s->bsphere_r > 0 ? s->bsphere_r : 1.0;
        vec3 c = v3_madd(s->bsphere_c, l->dir, -R);
        double x = v3_dot(v3_sub(p, c), a) / R, y = v3_dot(v3_sub(p, c), b) / R;
        if (x * x + y * y >= 1) return 0;
        concentric_inverse(x, y, &u[0], &u[1]);
        return 1;
    }
    }
}

static int four_d(const light *l) { return l->type == LIGHT_AREA || l->type == LIGHT_SPHERE; }

/* Level v's cells per side: over the point (ga) and the direction (gb) of area and sphere
 * lights, over (u[0], u[1]) of the others (g2); each level halves the one before. */
static int lv_ga(int v) { return IMP_GA >> v; }
static int lv_gb(int v) { return IMP_GB >> v; }
static int lv_g2(int v) { return IMP_GA2 >> v; }

static uint64_t ncells_at(const light *l, int v) {
    uint64_t ga = (uint64_t)lv_ga(v), gb = (uint64_t)lv_gb(v), g2 = (uint64_t)lv_g2(v);
    return four_d(l) ? ga * ga * gb * gb : g2 * g2;
}

uint64_t importance_ncells(const light *l) { return ncells_at(l, 0); }

static uint64_t cell_of(int g, double u) {
    int k = (int)(u * g);
    return (uint64_t)(k < 0 ? 0 : k >= g ? g - 1 : k);
}

static uint64_t cell_at(const light *l, int v, const double u[4]) {
    if (!four_d(l)) return cell_of(lv_g2(v), u[1]) * (uint64_t)lv_g2(v) + cell_of(lv_g2(v), u[0]);
    uint64_t ga = (uint64_t)lv_ga(v), gb = (uint64_t)lv_gb(v);
    uint64_t a = cell_of((int)ga, u[1]) * ga + cell_of((int)ga, u[0]);
    uint64_t b = cell_of((int)gb, u[3]) * gb + cell_of((int)gb, u[2]);
    return a * gb * gb + b;
}

uint64_t importance_cell(const light *l, const double u[4]) { return cell_at(l, 0, u); }

/* u[] uniform inside cell c of level v of l's grid, from h[] uniform in [0,1). */
static void cell_point(const light *l, int v, uint64_t c, const double h[4], double u[4]) {
    if (!four_d(l)) {
        uint64_t g = (uint64_t)lv_g2(v);
        u[0] = clamp01(((double)(c % g) + h[0]) / (double)g);
        u[1] = clamp01(((double)(c / g) + h[1]) / (double)g);
        u[2] = h[2];
        u[3] = h[3];
        return;
    }
    uint64_t ga = (uint64_t)lv_ga(v), gb = (uint64_t)lv_gb(v);
    uint64_t a = c / (gb * gb), b = c % (gb * gb);
    u[0] = clamp01(((double)(a % ga) + h[0]) / (double)ga);
    u[1] = clamp01(((double)(a / ga) + h[1]) / (double)ga);
    u[2] = clamp01(((double)(b % gb) + h[2]) / (double)gb);
    u[3] = clamp01(((double)(b / gb) + h[3]) / (double)gb);
}

/* ---- building ---------------------------------------------------------------------------- */

typedef struct conn { /* one unoccluded light connection, in its slot */
    double u[4], w;
    int light; /* -1: an empty slot */
} conn;

typedef struct rec {
    uint64_t cell;
    double w;
    uint32_t light, slot;
} rec;

/* A comparator of this struct's keys in order (guide.c's row_cmp is alike for another). */
static int rec_cmp(const void *pa, const void *pb) {
    const rec *a = pa, *b = pb;
    if (a->light != b->light) return a->light < b->light ? -1 : 1;
    if (a->cell != b->cell) return a->cell < b->cell ? -1 : 1;
    return a->slot < b->slot ? -1 : a->slot > b->slot;
}

static int dbl_desc(const void *pa, const void *pb) {
    double a = *(const double *)pa, b = *(const double *)pb;
    return a > b ? -1 : a < b;
}

/* One light connection from the diffuse vertex h (seen from wo, with path throughput beta):
 * its contribution (luminance; 0 if none) and, in *out, the light and the u of the emission
 * that carries it. *unoccluded: the shadow ray passed. */
static double connect(const scene *s, const hit *h, const material *m, vec3 wo, rgb beta, rng *g, conn *out,
                      int *unoccluded) {
    double pl, ul = rng_uniform(g), a0 = rng_uniform(g), a1 = rng_uniform(g);
    int li = distrib1d_sample(&s->light_distrib, ul, &pl);
    const light *l = &s->lights[li];
    vec3 n = v3_dot(wo, h->ng) >= 0 ? h->ng : v3_neg(h->ng); /* the side of the viewer */
    vec3 x = h->p, y, d;                                      /* d: from the light to x */
    rgb Lw;                                                   /* radiance / pdf, no cosine at x */
    int vis;
    *unoccluded = 0;
    if (!(pl > 0)) return 0;
    if (l->type == LIGHT_AREA || l->type == LIGHT_SPHERE) {
        double ue[4] = {l->two_sided ? a0 / 2 : a0, a1, 0.5, 0.5};
        vec3 nf, dd;
        light_sample_le(s, li, ue, &y, &nf, &dd);
        vec3 v = v3_sub(x, y);
        double r2 = v3_len2(v);
        if (!(r2 > 0)) return 0;
        d = v3_scale(v, 1 / sqrt(r2));
        double cl = v3_dot(d, nf);
        vec3 ny = nf;
        if (cl < 0 && l->two_sided) {
            cl = -cl;
            ny = v3_neg(nf);
        }
        if (!(cl > 0)) return 0;
        double area = l->type == LIGHT_AREA ? s->tris[l->tri].area
                                            : 4 * M_PI * s->spheres[l->sphere].r * s->spheres[l->sphere].r;
        Lw = v3_scale(l->Le, cl * area / r2);
        if (-v3_dot(d, n) <= 0) return 0;
        vis = scene_visible(s, x, n, y, ny);
    } else if (light_is_point(l)) {
        y = l->pos;
        vec3 v = v3_sub(x, y);
        double r2 = v3_len2(v);
        if (!(r2 > 0)) return 0;
        d = v3_scale(v, 1 / sqrt(r2));
        Lw = v3_scale(l->intensity, (l->type == LIGHT_SPOT ? light_spot_falloff(l, d) : 1) / r2);
        if (-v3_dot(d, n) <= 0 || v3_iszero(Lw)) return 0;
        vis = scene_visible(s, x, n, y, v3s(0));
    } else if (l->type == LIGHT_INFINITE) {
        light_sample li_s;
        if (!light_sample_li(s, li, x, a0, a1, &li_s)) return 0;
        d = v3_neg(li_s.wi);
        Lw = li_s.L;
        if (-v3_dot(d, n) <= 0) return 0;
        vis = scene_visible_dir(s, x, n, v3_neg(d));
        /* the emission that carries it: d, from the point of its disc on the line through x */
        double R = s->bsphere_r > 0 ? s->bsphere_r : 1.0;
        vec3 c = v3_madd(s->bsphere_c, d, -R), xc = v3_sub(x, c);
        y = v3_sub(x, v3_scale(d, v3_dot(xc, d)));
    } else {
        d = l->dir;
        y = x;
        Lw = l->irradiance;
        if (-v3_dot(d, n) <= 0) return 0;
        vis = scene_visible_dir(s, x, n, v3_neg(d));
    }
    double cx = -v3_dot(d, n);
    rgb f = material_f(m, h->ng, s->medium_ior, wo, v3_neg(d));
    if (v3_iszero(f) || !vis) return 0;
    *unoccluded = 1;
    if (!importance_invert_le(s, li, y, d, out->u)) return 0;
    double w = rgb_lum(v3_mul(v3_mul(beta, f), Lw)) * cx / pl;
    if (!(w > 0) || !isfinite(w)) return 0;
    out->light = li;
    return w;
}

/* Level v's table from the n connections c (in slot order, weights capped). */
static int build_level(const scene *s, const conn *c, size_t n, int v, imp_level *t) {
    rec *r = malloc((n ? n : 1) * sizeof *r);
    if (!r) return PM_ENOMEM;
    for (size_t k = 0; k < n; k++) {
        r[k].light = (uint32_t)c[k].light;
        r[k].cell = cell_at(&s->lights[c[k].light], v, c[k].u);
        r[k].w = c[k].w;
        r[k].slot = (uint32_t)k;
    }
    qsort(r, n, sizeof *r, rec_cmp);
    size_t m = 0;
    for (size_t k = 0; k < n; k++) {
        if (m > 0 && r[m - 1].light == r[k].light && r[m - 1].cell == r[k].cell)
            r[m - 1].w += r[k].w;
        else
            r[m++] = r[k];
    }
    t->light = malloc((m ? m : 1) * sizeof *t->light);
    t->cell = malloc((m ? m : 1) * sizeof *t->cell);
    t->cdf = malloc((m + 1) * sizeof *t->cdf);
    t->first = calloc((size_t)s->nlights + 1, sizeof *t->first);
    if (!t->light || !t->cell || !t->cdf || !t->first) {
        free(r);
        return PM_ENOMEM;
    }
    double total = 0, acc = 0;
    for (size_t k = 0; k < m; k++) total += r[k].w;
    t->cdf[0] = 0;
    for (size_t k = 0; k < m; k++) {
        t->light[k] = (int)r[k].light;
        t->cell[k] = r[k].cell;
        acc += r[k].w;
        t->cdf[k + 1] = acc / total;
        t->first[r[k].light + 1] = k + 1;
    }
    t->cdf[m] = 1;
    for (int l = 1; l <= s->nlights; l++)
        if (t->first[l] < t->first[l - 1]) t->first[l] = t->first[l - 1];
    t->ncells = m;
    free(r);
    return 0;
}

int camera_walk_hit(const scene *s, ray ry, hit *h, const material **m, vec3 *wo, int *diffuse) {
    if (!scene_intersect(s, ry, INFINITY, h)) return 0;
    *m = scene_material(s, h);
    *wo = v3_neg(ry.d);
    double w[LOBE_COUNT];
    material_weights(*m, *wo, h->ng, s->medium_ior, w);
    *diffuse = w[LOBE_DIFFUSE] > 0 && v3_maxc((*m)->diffuse) > 0;
    return 1;
}

int camera_walk_next(const scene *s, const material *m, const hit *h, vec3 wo, rng *g, rgb *beta, ray *ry,
                     vec3 *nside) {
    bsdf_sample bs;
    double ul = rng_uniform(g), u1 = rng_uniform(g), u2 = rng_uniform(g);
    if (!material_sample_ns(m, wo, h->ng, h->ns, s->medium_ior, ul, u1, u2, &bs)) return 0;
    *beta = v3_mul(*beta, bs.weight);
    *nside = v3_dot(bs.wi, h->ng) >= 0 ? h->ng : v3_neg(h->ng);
    ry->o = scene_offset(s, h->p, *nside, bs.wi);
    ry->d = bs.wi;
    return 1;
}

int importance_build(const scene *s, long paths, double a, uint64_t seed, int threads, importance *imp) {
    memset(imp, 0, sizeof *imp);
    imp->a = a;
    imp->nlights = s->nlights;
    imp->paths = paths;
    if (paths <= 0 || s->nlights == 0 || s->light_distrib.n == 0) return 0;
    size_t per = (size_t)IMP_DEPTH * IMP_LIGHTS, nslots = (size_t)paths * per;
    conn *c = malloc(nslots * sizeof *c);
    if (!c) return PM_ENOMEM;
    int nthreads = 1;
#ifdef _OPENMP
    nthreads = threads > 0 ? threads : omp_get_max_threads();
#endif
    (void)threads;
    (void)nthreads;
    unsigned long long nv = 0, nc = 0, nu = 0;
    const camera *cam = &s->cam;
#ifdef _OPENMP
#pragma omp parallel for num_threads(nthreads) schedule(dynamic, 256) reduction(+ : nv, nc, nu)
#endif
    for (long j = 0; j < paths; j++) {
        conn *cj = &c[(size_t)j * per];
        for (size_t k = 0; k < per; k++) cj[k].light = -1, cj[k].w = 0;
        rng g = rng_stream(seed, (uint64_t)j, IMP_STREAM);
        double px = rng_uniform(&g) * cam->width, py = rng_uniform(&g) * cam->height;
        ray ry = camera_ray(cam, px, py);
        rgb beta = v3s(1);
        int v = 0;
        /* The walk's steps are camera_walk_hit's; ports_find.c's walk declares the same
         * outputs, but what each does at a hit differs. */
        for (int b = 0; b < IMP_MAX_BOUNCES && v < IMP_DEPTH; b++) {
            hit h;
            const material *m;
            vec3 wo, nside;
            int diffuse;
            if (!camera_walk_hit(s, ry, &h, &m, &wo, &diffuse)) break;
            if (diffuse) {
                for (int k = 0; k < IMP_LIGHTS; k++) {
                    int unocc = 0;
                    conn *e = &cj[(size_t)v * IMP_LIGHTS + (size_t)k];
                    e->w = connect(s, &h, m, wo, beta, &g, e, &unocc) / IMP_LIGHTS;
                    if (!(e->w > 0)) e->light = -1;
                    nc++;
                    nu += (unsigned long long)unocc;
                }
                nv++;
                v++;
            }
            if (!camera_walk_next(s, m, &h, wo, &g, &beta, &ry, &nside)) break;
            if (v >= 2) { /* Russian roulette on the throughput */
                double q = fmin(0.95, v3_maxc(beta));
                if (!(rng_uniform(&g) < q)) break;
                beta = v3_scale(beta, 1 / q);
            }
        }
    }
    imp->vertices = nv;
    imp->connections = nc;
    imp->unoccluded = nu;
    /* Compact, in slot order; the mean and the cap. */
    size_t n = 0;
    double sum = 0;
    for (size_t k = 0; k < nslots; k++)
        if (c[k].light >= 0) {
            sum += c[k].w;
            c[n++] = c[k];
        }
    imp->contributing = n;
    if (n == 0 || !(sum > 0)) {
        free(c);
        return 0;
    }
    double cap = IMP_CLAMP * sum / (double)n;
    for (size_t k = 0; k < n; k++)
        if (c[k].w > cap) c[k].w = cap;
    int rc = 0;
    for (int v = 0; rc == 0 && v < IMP_LEVELS; v++) rc = build_level(s, c, n, v, &imp->lv[v]);
    imp->pl = malloc((size_t)s->nlights * sizeof *imp->pl);
    double *ws = malloc((imp->lv[0].ncells ? imp->lv[0].ncells : 1) * sizeof *ws);
    if (rc < 0 || !imp->pl || !ws) {
        free(c);
        free(ws);
        importance_free(imp);
        return PM_ENOMEM;
    }
    for (int l = 0; l < s->nlights; l++) imp->pl[l] = distrib1d_prob(&s->light_distrib, l);
    const imp_level *f = &imp->lv[0];
    for (size_t k = 0; k < f->ncells; k++) ws[k] = f->cdf[k + 1] - f->cdf[k];
    qsort(ws, f->ncells, sizeof *ws, dbl_desc);
    size_t top = (f->ncells + 99) / 100;
    double st = 0;
    for (size_t k = 0; k < top; k++) st += ws[k];
    imp->share_top = st;
    /* The part of the lights' power whose emission cells (coarsest level) have importance. */
    const imp_level *co = &imp->lv[IMP_LEVELS - 1];
    for (size_t k = 0; k < co->ncells; k++)
        imp->coverage += imp->pl[co->light[k]] / (double)ncells_at(&s->lights[co->light[k]], IMP_LEVELS - 1);
    /* Too narrow to steer by (see LIMITS in importance.h): keep the evidence, emit uniformly. */
    imp->on = imp->coverage >= IMP_MIN_COVERAGE;
    free(ws);
    free(c);
    return 0;
}

void importance_free(importance *imp) {
    for (int v = 0; v < IMP_LEVELS; v++) {
        free(imp->lv[v].light);
        free(imp->lv[v].cell);
        free(imp->lv[v].cdf);
        free(imp->lv[v].first);
    }
    free(imp->pl);
    memset(imp, 0, sizeof *imp);
}

/* ---- sampling ---------------------------------------------------------------------------- */

/* Level t's share of the importance in the cell of (l, u) (0 if it has none). */
static double share_at(const imp_level *t, const scene *s, int v, int l, const double u[4]) {
    uint64_t c = cell_at(&s->lights[l], v, u);
    size_t lo = t->first[l], hi = t->first[l + 1];
    while (lo < hi) { /* the first cell >= c */
        size_t mid = lo + (hi - lo) / 2;
        if (t->cell[mid] < c)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < t->first[l + 1] && t->cell[lo] == c ? t->cdf[lo + 1] - t->cdf[lo] : 0;
}

double importance_rel(const importance *imp, const scene *s, int l, const double u[4]) {
    if (!imp || !imp->on) return 1;
    double pl = imp->pl[l];
    if (!(pl > 0)) return imp->a;
    double r = imp->a, b = (1 - imp->a) / IMP_LEVELS;
    for (int v = 0; v < IMP_LEVELS; v++)
        r += b * share_at(&imp->lv[v], s, v, l, u) * (double)ncells_at(&s->lights[l], v) / pl;
    return r;
}

int importance_sample(const importance *imp, const scene *s, double u0, const double h[4], double u[4],
                      double *rel) {
    double pl;
    int li;
    if (!imp || !imp->on || u0 < imp->a) {
        double v = imp && imp->on ? u0 / imp->a : u0;
        li = distrib1d_sample(&s->light_distrib, v < 1 ? v : 0x1.fffffffffffffp-1, &pl);
        memcpy(u, h, 4 * sizeof *u);
    } else {
        /* Level lv, then a cell of it by its importance, with what is left of u0. */
        double x = (u0 - imp->a) / (1 - imp->a) * IMP_LEVELS;
        int lv = (int)x;
        if (lv >= IMP_LEVELS) lv = IMP_LEVELS - 1;
        double v = x - lv;
        const imp_level *t = &imp->lv[lv];
        size_t lo = 0, hi = t->ncells - 1;
        while (lo < hi) { /* the first k with cdf[k + 1] > v */
            size_t mid = lo + (hi - lo) / 2;
            if (t->cdf[mid + 1] > v)
                hi = mid;
            else
                lo = mid + 1;
        }
        li = t->light[lo];
        cell_point(&s->lights[li], lv, t->cell[lo], h, u);
    }
    *rel = importance_rel(imp, s, li, u);
    return li;
}
