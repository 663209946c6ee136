/* guide.c: learned primary-sample guiding per receiver cell; see guide.h.
 *
 * Tables are built from rows sorted by (cell, slot, row number), so a table's sums are taken in
 * one order whatever order the rows came in; the pilot writes each point's results into fixed
 * slots before anything is summed, so no thread decides an order either. Lookups: an
 * open-addressing hash of (cell, slot) with linear probing, read-only once built.
 */
#include "guiding/guide.h"

#include <limits.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "scene/light.h"
#include "scene/material.h"
#include "scene/medium.h"
#include "photons/photon_settings.h"
#include "base/sampling.h"
#include "base/stats.h"

#ifdef _OPENMP
#include <omp.h>
#endif

#define GUIDE_STREAM 0x6775696465ULL /* "guide" */
#define GUIDE_SPECULAR_MAX 8          /* specular bounces a pilot path passes */
#define CELL_BITS 20
#define CELL_MAX ((1 << CELL_BITS) - 1)
#define CELL_SLOT INT_MAX /* the hash entry of a cell (its tables' choice) */

static int nthreads_of(int threads) {
#ifdef _OPENMP
    return threads > 0 ? threads : omp_get_max_threads();
#else
    (void)threads;
    return 1;
#endif
}

/* ---- cells -------------------------------------------------------------------------------- */

void guide_grid_init(guide_grid *gr, const scene *s, int res) {
    vec3 ext = v3_sub(s->bounds_hi, s->bounds_lo);
    double side = v3_maxc(ext);
    if (!(side > 0) || !isfinite(side)) side = s->bsphere_r > 0 ? 2 * s->bsphere_r : 1;
    gr->h = side / (res > 0 ? res : 1);
    gr->lo = v3_sub(s->bounds_lo, v3s(gr->h)); /* a margin: points a ray offset outside */
}

static uint64_t cell_coord(double x, double lo, double h) {
    double c = floor((x - lo) / h);
    if (!(c > 0)) return 0; /* NaN too */
    return c >= CELL_MAX ? CELL_MAX : (uint64_t)c;
}

uint64_t guide_cell(const guide_grid *gr, vec3 p, vec3 n) {
    double ax = fabs(n.x), ay = fabs(n.y), az = fabs(n.z);
    int axis = ax >= ay && ax >= az ? 0 : ay >= az ? 1 : 2;
    int face = 2 * axis + (v3_idx(n, axis) < 0);
    return cell_coord(p.x, gr->lo.x, gr->h) | cell_coord(p.y, gr->lo.y, gr->h) << CELL_BITS |
           cell_coord(p.z, gr->lo.z, gr->h) << (2 * CELL_BITS) | (uint64_t)face << (3 * CELL_BITS);
}

static size_t hash_of(uint64_t cell, int slot, size_t mask) {
    uint64_t k = (uint64_t)(unsigned)slot * UINT64_C(0x9e3779b97f4a7c15);
    return (size_t)(rng_mix64(cell ^ rng_mix64(k)) & (uint64_t)mask);
}

/* ---- building ----------------------------------------------------------------------------- */

typedef struct row_ref {
    uint64_t cell;
    int slot;
    size_t k; /* row number */
} row_ref;

static int row_cmp(const void *a, const void *b) {
    const row_ref *x = a, *y = b;
    if (x->cell != y->cell) return x->cell < y->cell ? -1 : 1;
    if (x->slot != y->slot) return x->slot < y->slot ? -1 : 1;
    return x->k < y->k ? -1 : x->k > y->k;
}

int guide_build(guide *g, const guide_grid *grid, int G, double alpha, const guide_row *rows, size_t n) {
    memset(g, 0, sizeof *g);
    if (G < 1 || G > 1024 || (G & (G - 1)) || !(alpha > 0 && alpha <= 1)) return PM_EINVAL;
    g->grid = *grid;
    g->stat_id = -1;
    g->G = G;
    g->alpha = alpha;
    size_t G2 = (size_t)G * (size_t)G;
    for (size_t k = 0; k < n; k++) {
        if (rows[k].slot < 0 || rows[k].slot >= CELL_SLOT) return PM_EINVAL;
        for (size_t j = 0; j < G2; j++)
            if (!(rows[k].v[j] >= 0) || !isfinite(rows[k].v[j])) return PM_EINVAL;
    }
    row_ref *r = malloc((n ? n : 1) * sizeof *r);
    double *sum = malloc(G2 * sizeof *sum);
    if (!r || !sum) {
        free(r);
        free(sum);
        return PM_ENOMEM;
    }
    for (size_t k = 0; k < n; k++) r[k] = (row_ref){rows[k].cell, rows[k].slot, k};
    qsort(r, n, sizeof *r, row_cmp);
    /* Groups with a positive sum: the tables. */
    size_t ntab = 0;
    for (size_t a = 0, b; a < n; a = b) {
        double t = 0;
        for (b = a; b < n && r[b].cell == r[a].cell && r[b].slot == r[a].slot; b++)
            for (size_t j = 0; j < G2; j++) t += rows[r[b].k].v[j];
        ntab += t > 0;
    }
    size_t ncell = 0;
    uint64_t last = 0;
    size_t cap = 16;
    while (cap < 2 * (2 * ntab)) cap *= 2; /* a table and at most one cell entry each */
    g->cap = cap;
    g->hkey = calloc(cap, sizeof *g->hkey); /* zero in empty slots: two builds compare equal */
    g->hslot = malloc(cap * sizeof *g->hslot);
    g->hidx = calloc(cap, sizeof *g->hidx);
    g->cdf = malloc((ntab ? ntab : 1) * (G2 + 1) * sizeof *g->cdf);
    g->tslot = malloc((ntab ? ntab : 1) * sizeof *g->tslot);
    g->tw = malloc((ntab ? ntab : 1) * sizeof *g->tw);
    g->tcum = malloc((ntab ? ntab : 1) * sizeof *g->tcum);
    g->cfirst = malloc((ntab + 1) * sizeof *g->cfirst);
    if (!g->hkey || !g->hslot || !g->hidx || !g->cdf || !g->tslot || !g->tw || !g->tcum || !g->cfirst) {
        free(r);
        free(sum);
        guide_free(g);
        return PM_ENOMEM;
    }
    for (size_t i = 0; i < cap; i++) g->hslot[i] = -1;
    for (size_t a = 0, b; a < n; a = b) {
        memset(sum, 0, G2 * sizeof *sum);
        double t = 0;
        for (b = a; b < n && r[b].cell == r[a].cell && r[b].slot == r[a].slot; b++)
            for (size_t j = 0; j < G2; j++) sum[j] += rows[r[b].k].v[j];
        for (size_t j = 0; j < G2; j++) t += sum[j];
        if (!(t > 0)) continue;
        double *c = &g->cdf[g->ntables * (G2 + 1)];
        c[0] = 0;
        for (size_t j = 0; j < G2; j++) c[j + 1] = c[j] + alpha / (double)G2 + (1 - alpha) * sum[j] / t;
        for (size_t j = 1; j < G2; j++) c[j] /= c[G2]; /* exactly 1 at the end */
        c[G2] = 1;
        size_t hsl = hash_of(r[a].cell, r[a].slot, cap - 1);
        while (g->hslot[hsl] >= 0) hsl = (hsl + 1) & (cap - 1);
        g->hkey[hsl] = r[a].cell;
        g->hslot[hsl] = r[a].slot;
        g->hidx[hsl] = g->ntables;
        if (g->ntables == 0 || r[a].cell != last) { /* a new cell: its entry */
            g->cfirst[ncell] = g->ntables;
            size_t hc = hash_of(r[a].cell, CELL_SLOT, cap - 1);
            while (g->hslot[hc] >= 0) hc = (hc + 1) & (cap - 1);
            g->hkey[hc] = r[a].cell;
            g->hslot[hc] = CELL_SLOT;
            g->hidx[hc] = ncell++;
        }
        last = r[a].cell;
        g->tslot[g->ntables] = r[a].slot;
        g->tw[g->ntables] = t; /* normalized below, per cell */
        g->ntables++;
    }
    g->ncells = ncell;
    g->cfirst[ncell] = g->ntables;
    for (size_t c = 0; c < ncell; c++) {
        double t = 0, acc = 0;
        for (size_t k = g->cfirst[c]; k < g->cfirst[c + 1]; k++) t += g->tw[k];
        for (size_t k = g->cfirst[c]; k < g->cfirst[c + 1]; k++) {
            g->tw[k] /= t;
            acc += g->tw[k];
            g->tcum[k] = acc;
        }
        g->tcum[g->cfirst[c + 1] - 1] = 1;
    }
    free(r);
    free(sum);
    return 0;
}

void guide_free(guide *g) {
    if (!g) return;
    free(g->hkey);
    free(g->hslot);
    free(g->hidx);
    free(g->cdf);
    free(g->tslot);
    free(g->tw);
    free(g->tcum);
    free(g->cfirst);
    memset(g, 0, sizeof *g);
}

void guide_destroy(guide *g) {
    guide_free(g);
    free(g);
}

/* ---- sampling ----------------------------------------------------------------------------- */

const double *guide_find(const guide *g, vec3 p, vec3 n, int slot) {
    if (!g || g->ntables == 0 || slot < 0) return NULL;
    uint64_t cell = guide_cell(&g->grid, p, n);
    for (size_t h = hash_of(cell, slot, g->cap - 1);; h = (h + 1) & (g->cap - 1)) {
        if (g->hslot[h] < 0) return NULL;
        if (g->hkey[h] == cell && g->hslot[h] == slot)
            return &g->cdf[g->hidx[h] * ((size_t)g->G * (size_t)g->G + 1)];
    }
}

long guide_cell_index(const guide *g, vec3 p, vec3 n) {
    if (!g || g->ntables == 0) return -1;
    uint64_t cell = guide_cell(&g->grid, p, n);
    for (size_t h = hash_of(cell, CELL_SLOT, g->cap - 1);; h = (h + 1) & (g->cap - 1)) {
        if (g->hslot[h] < 0) return -1;
        if (g->hkey[h] == cell && g->hslot[h] == CELL_SLOT) return (long)g->hidx[h];
    }
}

/* The cell's table of slot (binary search: a cell's tables are in slot order), or -1. */
static long cell_table(const guide *g, long c, int slot) {
    size_t lo = g->cfirst[c], hi = g->cfirst[c + 1];
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (g->tslot[mid] < slot)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < g->cfirst[c + 1] && g->tslot[lo] == slot ? (long)lo : -1;
}

const double *guide_cell_table(const guide *g, long c, int slot) {
    long t = c >= 0 ? cell_table(g, c, slot) : -1;
    return t >= 0 ? &g->cdf[(size_t)t * ((size_t)g->G * (size_t)g->G + 1)] : NULL;
}

double guide_slot_weight(const guide *g, long c, int slot) {
    long t = c >= 0 ? cell_table(g, c, slot) : -1;
    return t >= 0 ? g->tw[t] : 0;
}

int guide_pick_slot(const guide *g, long c, double u) {
    size_t lo = g->cfirst[c], hi = g->cfirst[c + 1] - 1;
    while (lo < hi) { /* the first table with tcum > u */
        size_t mid = lo + (hi - lo) / 2;
        if (g->tcum[mid] > u)
            hi = mid;
        else
            lo = mid + 1;
    }
    return g->tslot[lo];
}

/* The largest double below (i + 1) / G, for a point that rounding would push into the next
 * stratum. */
static double in_stratum(double x, int i, int G) {
    double hi = (double)(i + 1) / G;
    return x < hi ? x : nextafter(hi, 0);
}

double guide_warp(const guide *g, const double *t, double *u1, double *u2) {
    if (!g || !t) return 1;
    int G = g->G, G2 = G * G;
    double u = *u1;
    int lo = 0, hi = G2 - 1;
    while (lo < hi) { /* the first k with t[k + 1] > u */
        int mid = lo + (hi - lo) / 2;
        if (t[mid + 1] > u)
            hi = mid;
        else
            lo = mid + 1;
    }
    double w = t[lo + 1] - t[lo];
    double v = (u - t[lo]) / w;
    if (!(v >= 0)) v = 0;
    if (v >= 1) v = 0x1.fffffffffffffp-1;
    int i = lo % G, j = lo / G;
    *u1 = in_stratum((i + v) / G, i, G);
    *u2 = in_stratum((j + *u2) / G, j, G);
    return (double)G2 * w;
}

double guide_pdf(const guide *g, const double *t, double u1, double u2) {
    if (!g || !t) return 1;
    int G = g->G;
    int i = (int)(u1 * G), j = (int)(u2 * G);
    i = i < 0 ? 0 : i >= G ? G - 1 : i;
    j = j < 0 ? 0 : j >= G ? G - 1 : j;
    int k = i + G * j;
    return (double)G * G * (t[k + 1] - t[k]);
}

double guide_sample(const guide *g, vec3 p, vec3 n, int slot, double *u1, double *u2) {
    return guide_warp(g, guide_find(g, p, n, slot), u1, u2);
}

double guide_density(const guide *g, vec3 p, vec3 n, int slot, double u1, double u2) {
    return guide_pdf(g, guide_find(g, p, n, slot), u1, u2);
}

/* ---- pilot points ------------------------------------------------------------------------- */

static int has_diffuse(const scene *s, const material *m, vec3 wo, vec3 ng) {
    double w[LOBE_COUNT];
    material_weights(m, wo, ng, s->medium_ior, w);
    return w[LOBE_DIFFUSE] > 0 && v3_maxc(m->diffuse) > 0;
}

/* Follow r through specular surfaces to the first one with a diffuse branch: 1 and *pt filled
 * (beta multiplied by the specular weights), or 0. */
static int to_point(const scene *s, ray r, rgb beta, rng *g, guide_point *pt) {
    for (int b = 0; b <= GUIDE_SPECULAR_MAX; b++) {
        hit h;
        if (!scene_intersect(s, r, INFINITY, &h)) return 0;
        const material *m = scene_material(s, &h);
        vec3 wo = v3_neg(r.d);
        if (has_diffuse(s, m, wo, h.ng)) {
            pt->h = h;
            pt->wo = wo;
            pt->n = v3_dot(wo, h.ng) >= 0 ? h.ng : v3_neg(h.ng);
            pt->beta = beta;
            return 1;
        }
        bsdf_sample bs;
        double ul = rng_uniform(g), u1 = rng_uniform(g), u2 = rng_uniform(g);
        if (!material_sample_ns(m, wo, h.ng, h.ns, s->medium_ior, ul, u1, u2, &bs)) return 0;
        beta = v3_mul(beta, bs.weight);
        if (v3_iszero(beta)) return 0;
        vec3 side = v3_dot(bs.wi, h.ng) >= 0 ? h.ng : v3_neg(h.ng);
        r.o = scene_offset(s, h.p, side, bs.wi);
        r.d = bs.wi;
    }
    return 0;
}

int guide_points(const scene *s, long paths, uint64_t seed, int threads, guide_point **out, size_t *n) {
    *out = NULL;
    *n = 0;
    if (paths <= 0) return 0;
    guide_point *p = malloc((size_t)paths * 2 * sizeof *p);
    unsigned char *got = calloc((size_t)paths * 2, 1);
    if (!p || !got) {
        free(p);
        free(got);
        return PM_ENOMEM;
    }
    const camera *cam = &s->cam;
    int nt = nthreads_of(threads);
    (void)nt;
#ifdef _OPENMP
#pragma omp parallel for num_threads(nt) schedule(dynamic, 256)
#endif
    for (long j = 0; j < paths; j++) {
        rng g = rng_stream(seed, (uint64_t)j, GUIDE_STREAM);
        double px = rng_uniform(&g) * cam->width, py = rng_uniform(&g) * cam->height;
        guide_point *a = &p[2 * j], *b = &p[2 * j + 1];
        if (!to_point(s, camera_ray(cam, px, py), v3s(1), &g, a)) continue;
        a->bounce = 0;
        got[2 * j] = 1;
        double u1 = rng_uniform(&g), u2 = rng_uniform(&g);
        vec3 nsh = material_shading_side(a->wo, a->h.ng, a->h.ns);
        vec3 d = sampling_to_world(sample_cosine_hemisphere(u1, u2), nsh);
        if (!(v3_dot(d, a->n) > 0)) continue;
        /* cosine sampling: f cos / pdf = pi f */
        rgb f = material_f(scene_material(s, &a->h), a->h.ng, s->medium_ior, a->wo, d);
        rgb beta = v3_scale(f, M_PI);
        if (v3_iszero(beta)) continue;
        ray r = {scene_offset(s, a->h.p, a->h.ng, d), d};
        if (!to_point(s, r, beta, &g, b)) continue;
        b->bounce = 1;
        got[2 * j + 1] = 1;
    }
    size_t m = 0;
    for (size_t k = 0; k < (size_t)paths * 2; k++)
        if (got[k]) p[m++] = p[k];
    free(got);
    *out = p;
    *n = m;
    return 0;
}

/* ---- learning ----------------------------------------------------------------------------- */

int guide_learn(guide *g, const scene *s, const guide_grid *grid, int G, double alpha, const guide_point *pts,
                size_t npts, int nslots, const unsigned char *use, guide_probe_fn fn, void *user, uint64_t seed,
                int threads, unsigned long long *probes) {
    memset(g, 0, sizeof *g);
    if (nslots < 0) return PM_EINVAL;
    size_t nj = 0;
    for (size_t k = 0; k < npts * (size_t)nslots; k++) nj += !use || use[k];
    size_t *jp = malloc((nj ? nj : 1) * sizeof *jp);
    int *js = malloc((nj ? nj : 1) * sizeof *js);
    if (!jp || !js) {
        free(jp);
        free(js);
        return PM_ENOMEM;
    }
    nj = 0;
    for (size_t k = 0; k < npts; k++)
        for (int l = 0; l < nslots; l++)
            if (!use || use[k * (size_t)nslots + (size_t)l]) {
                jp[nj] = k;
                js[nj++] = l;
            }
    int rc = guide_learn_jobs(g, s, grid, G, alpha, pts, jp, js, nj, fn, user, seed, threads, probes);
    free(jp);
    free(js);
    return rc;
}

/* Each row's values become half themselves plus half the largest in their 3 x 3 neighbourhood:
 * a table learned at a few points of a cell then also covers the strata next to what they
 * saw, where the rest of the cell sees it (the window onto a lamp through a hole moves with
 * the receiver). */
static void spread_row(double *v, double *tmp, int G) {
    for (int j = 0; j < G; j++)
        for (int i = 0; i < G; i++) {
            double m = 0;
            for (int dj = -1; dj <= 1; dj++)
                for (int di = -1; di <= 1; di++) {
                    int x = i + di, y = j + dj;
                    if (x >= 0 && x < G && y >= 0 && y < G) m = fmax(m, v[x + G * y]);
                }
            tmp[i + G * j] = 0.5 * v[i + G * j] + 0.5 * m;
        }
    memcpy(v, tmp, (size_t)G * (size_t)G * sizeof *v);
}

static int learn_jobs(guide *g, const scene *s, const guide_grid *grid, int G, double alpha, const guide_point *pts,
                      const size_t *job_point, const int *job_slot, size_t njobs, guide_probe_fn fn, void *user,
                      uint64_t seed, int threads, unsigned long long *probes, int spread);

int guide_learn_jobs(guide *g, const scene *s, const guide_grid *grid, int G, double alpha, const guide_point *pts,
                     const size_t *job_point, const int *job_slot, size_t njobs, guide_probe_fn fn, void *user,
                     uint64_t seed, int threads, unsigned long long *probes) {
    return learn_jobs(g, s, grid, G, alpha, pts, job_point, job_slot, njobs, fn, user, seed, threads, probes, 0);
}

static int learn_jobs(guide *g, const scene *s, const guide_grid *grid, int G, double alpha, const guide_point *pts,
                      const size_t *job_point, const int *job_slot, size_t njobs, guide_probe_fn fn, void *user,
                      uint64_t seed, int threads, unsigned long long *probes, int spread) {
    memset(g, 0, sizeof *g);
    if (probes) *probes = 0;
    if (G < 1 || G > 1024 || (G & (G - 1))) return PM_EINVAL;
    size_t G2 = (size_t)G * (size_t)G;
    double *v = malloc((njobs ? njobs : 1) * G2 * sizeof *v);
    guide_row *rows = malloc((njobs ? njobs : 1) * sizeof *rows);
    size_t *first = malloc((njobs + 1) * sizeof *first); /* job runs of one point */
    if (!v || !rows || !first) {
        free(v);
        free(rows);
        free(first);
        return PM_ENOMEM;
    }
    size_t nruns = 0;
    for (size_t k = 0; k < njobs; k++)
        if (k == 0 || job_point[k] != job_point[k - 1]) first[nruns++] = k;
    first[nruns] = njobs;
    int nt = nthreads_of(threads);
    (void)nt;
#ifdef _OPENMP
#pragma omp parallel for num_threads(nt) schedule(dynamic, 4)
#endif
    for (long run = 0; run < (long)nruns; run++) {
        size_t k0 = first[run], k1 = first[run + 1];
        const guide_point *pt = &pts[job_point[k0]];
        rng rg = rng_stream(seed, (uint64_t)job_point[k0], GUIDE_STREAM + 1);
        for (size_t k = k0; k < k1; k++) {
            double *vk = &v[k * G2];
            for (int j = 0; j < G; j++)
                for (int i = 0; i < G; i++) {
                    double u1 = (i + rng_uniform(&rg)) / G, u2 = (j + rng_uniform(&rg)) / G;
                    double x = fn(user, s, pt, job_slot[k], u1, u2, &rg);
                    vk[(size_t)i + (size_t)G * (size_t)j] = x > 0 && isfinite(x) ? x : 0;
                }
        }
    }
    if (spread) {
        double *tmp = malloc(G2 * sizeof *tmp);
        if (!tmp) {
            free(v);
            free(rows);
            free(first);
            return PM_ENOMEM;
        }
        for (size_t k = 0; k < njobs; k++) spread_row(&v[k * G2], tmp, G);
        free(tmp);
    }
    for (size_t k = 0; k < njobs; k++) {
        const guide_point *pt = &pts[job_point[k]];
        rows[k].cell = guide_cell(grid, pt->h.p, pt->n);
        rows[k].slot = job_slot[k];
        rows[k].v = &v[k * G2];
    }
    if (probes) *probes = (unsigned long long)njobs * G2;
    int rc = guide_build(g, grid, G, alpha, rows, njobs);
    free(v);
    free(rows);
    free(first);
    return rc;
}

/* ---- the light guide ---------------------------------------------------------------------- */

/* Light li sampled from pt with (u1, u2), chosen with probability pl: the luminance it would
 * add unshadowed (f Li cos / pl, times the point's throughput), 0 if none; *ls filled. */
static double light_value(const scene *s, const guide_point *pt, int li, double pl, double u1, double u2,
                          light_sample *ls) {
    if (!light_sample_li(s, li, pt->h.p, u1, u2, ls) || v3_iszero(ls->L)) return 0;
    double c = v3_dot(ls->wi, pt->n);
    if (!(c > 0)) return 0;
    rgb f = material_f(scene_material(s, &pt->h), pt->h.ng, s->medium_ior, pt->wo, ls->wi);
    double x = rgb_lum(v3_mul(pt->beta, v3_mul(f, ls->L))) * c / pl;
    return x > 0 && isfinite(x) ? x : 0;
}

static int light_visible(const scene *s, const guide_point *pt, int li, const light_sample *ls) {
    if (s->lights[li].type == LIGHT_DIRECTIONAL) return scene_visible_dir(s, pt->h.p, pt->h.ng, ls->wi);
    return scene_visible(s, pt->h.p, pt->h.ng, ls->p, ls->n);
}

static int guided_light(const light *l) { return l->type == LIGHT_AREA || l->type == LIGHT_SPHERE; }

/* Stage B's probe: the unoccluded contribution of light `slot` at (u1, u2). */
static double light_probe(void *user, const scene *s, const guide_point *pt, int slot, double u1, double u2,
                          rng *g) {
    (void)user;
    (void)g;
    light_sample ls;
    double x = light_value(s, pt, slot, 1.0, u1, u2, &ls);
    return x > 0 && light_visible(s, pt, slot, &ls) ? x : 0;
}

/* Stage A's record of one point. */
typedef struct point_a {
    double U, V;           /* unshadowed, passed luminance */
    int ns, np;            /* samples that would contribute; that pass */
    int li[GUIDE_PROBES];  /* their lights (-1: none) */
} point_a;

int guide_cell_ref_cmp(const void *a, const void *b) {
    const guide_cell_ref *x = a, *y = b;
    if (x->cell != y->cell) return x->cell < y->cell ? -1 : 1;
    return x->k < y->k ? -1 : x->k > y->k;
}

static int int_cmp(const void *a, const void *b) {
    int x = *(const int *)a, y = *(const int *)b;
    return x < y ? -1 : x > y;
}

/* The coarse cell (GUIDE_COARSE fine cells per side) of a fine cell key, same side. */
static uint64_t coarse_of(uint64_t key) {
    uint64_t m = CELL_MAX, sh = 0;
    while ((1u << sh) < (unsigned)GUIDE_COARSE) sh++;
    return ((key & m) >> sh) | (((key >> CELL_BITS) & m) >> sh) << CELL_BITS |
           (((key >> (2 * CELL_BITS)) & m) >> sh) << (2 * CELL_BITS) | (key >> (3 * CELL_BITS)) << (3 * CELL_BITS);
}

static void say(char *reason, size_t cap, const char *text) { snprintf(reason, cap, "%s", text); }

/* Stage A: at every point, GUIDE_PROBES light samples drawn as next-event estimation draws
 * them (light by power, a uniform point): what they would carry unshadowed and what passes. */
static void stage_a(const scene *s, const guide_point *pts, size_t np, uint64_t seed, point_a *pa) {
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 256)
#endif
    for (long k = 0; k < (long)np; k++) {
        rng g = rng_stream(seed, (uint64_t)k, GUIDE_STREAM + 2);
        point_a *a = &pa[k];
        for (int t = 0; t < GUIDE_PROBES; t++) {
            double ul = rng_uniform(&g), u1 = rng_uniform(&g), u2 = rng_uniform(&g), pl;
            a->li[t] = -1;
            int li = distrib1d_sample(&s->light_distrib, ul, &pl);
            if (!(pl > 0)) continue;
            light_sample ls;
            double x = light_value(s, &pts[k], li, pl, u1, u2, &ls);
            if (!(x > 0)) continue;
            a->U += x;
            a->ns++;
            if (guided_light(&s->lights[li])) a->li[t] = li;
            if (light_visible(s, &pts[k], li, &ls)) {
                a->V += x;
                a->np++;
            }
        }
    }
}

/* Stage B's jobs: in each coarse cell that stage A found blocked (something passes, less than
 * GUIDE_PASS_MAX of the unshadowed light), the first GUIDE_CELL_POINTS points of every fine
 * cell, each with the lights stage A saw contribute in the coarse cell. Jobs sorted by (point,
 * light), as guide_learn_jobs wants. Evidence into e. 0 or PM_ENOMEM. */
static int plan_jobs(const guide_grid *grid, const guide_point *pts, size_t np, const point_a *pa,
                     guide_light_evidence *e, size_t **jp_out, int **js_out, size_t *nj_out) {
    enum { MAXL = 64 };
    guide_cell_ref *cr = malloc((np ? np : 1) * sizeof *cr);
    unsigned char *blocked = calloc(np ? np : 1, 1); /* per point: in a blocked coarse cell */
    size_t *group = malloc((np ? np : 1) * sizeof *group); /* per point: its coarse group */
    int *glights = NULL, *gn = NULL;
    size_t *jp = NULL;
    int *js = NULL;
    int rc = PM_ENOMEM;
    if (!cr || !blocked || !group) goto done;
    for (size_t k = 0; k < np; k++) cr[k] = (guide_cell_ref){coarse_of(guide_cell(grid, pts[k].h.p, pts[k].n)), k};
    qsort(cr, np, sizeof *cr, guide_cell_ref_cmp);
    size_t ngroups = 0;
    for (size_t a = 0, b; a < np; a = b) {
        for (b = a; b < np && cr[b].cell == cr[a].cell; b++) {}
        ngroups++;
    }
    glights = malloc((ngroups ? ngroups : 1) * MAXL * sizeof *glights);
    gn = calloc(ngroups ? ngroups : 1, sizeof *gn);
    if (!glights || !gn) goto done;
    double Vall = 0, Vb = 0, Ub = 0;
    size_t gi = 0;
    for (size_t a = 0, b; a < np; a = b, gi++) {
        double U = 0, V = 0;
        int nsamp = 0;
        for (b = a; b < np && cr[b].cell == cr[a].cell; b++) {
            const point_a *p = &pa[cr[b].k];
            U += p->U;
            V += p->V;
            nsamp += p->ns;
            e->samples += (unsigned long long)p->ns;
            e->passed += (unsigned long long)p->np;
            group[cr[b].k] = gi;
        }
        Vall += V;
        if (nsamp == 0) continue;
        e->cells++;
        if (!(V > 0 && V < GUIDE_PASS_MAX * U)) continue;
        e->blocked++;
        Vb += V;
        Ub += U;
        int *L = &glights[gi * MAXL], nl = 0;
        for (size_t c = a; c < b; c++) {
            blocked[cr[c].k] = 1;
            for (int t = 0; t < GUIDE_PROBES; t++) {
                int li = pa[cr[c].k].li[t], dup = 0;
                if (li < 0) continue;
                for (int q = 0; q < nl; q++) dup |= L[q] == li;
                if (!dup && nl < MAXL) L[nl++] = li;
            }
        }
        qsort(L, (size_t)nl, sizeof *L, int_cmp);
        gn[gi] = nl;
    }
    e->points = np;
    e->blocked_share = Vall > 0 ? Vb / Vall : 0;
    e->blocked_pass = Ub > 0 ? Vb / Ub : 0;
    /* Fine cells of blocked coarse cells: their first points. */
    size_t cnt = 0;
    for (size_t k = 0; k < np; k++) cr[k] = (guide_cell_ref){guide_cell(grid, pts[k].h.p, pts[k].n), k};
    qsort(cr, np, sizeof *cr, guide_cell_ref_cmp);
    for (int pass = 0; pass < 2; pass++) {
        size_t nj = 0;
        for (size_t a = 0, b; a < np; a = b) {
            for (b = a; b < np && cr[b].cell == cr[a].cell; b++) {}
            size_t used = 0;
            for (size_t c = a; c < b && used < GUIDE_CELL_POINTS; c++) {
                size_t k = cr[c].k;
                if (!blocked[k]) continue;
                used++;
                for (int q = 0; q < gn[group[k]]; q++) {
                    if (pass) {
                        jp[nj] = k;
                        js[nj] = glights[group[k] * MAXL + (size_t)q];
                    }
                    nj++;
                }
            }
        }
        if (!pass) {
            cnt = nj;
            jp = malloc((cnt ? cnt : 1) * sizeof *jp);
            js = malloc((cnt ? cnt : 1) * sizeof *js);
            if (!jp || !js) goto done;
        }
    }
    /* Sort the jobs by (point, light). */
    guide_cell_ref *o = malloc((cnt ? cnt : 1) * sizeof *o);
    if (!o) goto done;
    for (size_t k = 0; k < cnt; k++) o[k] = (guide_cell_ref){(uint64_t)jp[k] << 32 | (uint64_t)(unsigned)js[k], k};
    qsort(o, cnt, sizeof *o, guide_cell_ref_cmp);
    for (size_t k = 0; k < cnt; k++) {
        jp[k] = (size_t)(o[k].cell >> 32);
        js[k] = (int)(o[k].cell & 0xffffffffu);
    }
    free(o);
    *jp_out = jp;
    *js_out = js;
    *nj_out = cnt;
    jp = NULL;
    js = NULL;
    rc = 0;
done:
    free(cr);
    free(blocked);
    free(group);
    free(glights);
    free(gn);
    free(jp);
    free(js);
    return rc;
}

guide *guide_light_plan(const scene *s, int force, int usable, int *on, char *reason, size_t cap,
                        guide_light_evidence *ev) {
    guide_light_evidence e;
    memset(&e, 0, sizeof e);
    *on = 0;
    if (ev) *ev = e;
    if (force == PLAN_OFF) {
        say(reason, cap, "forced off by photon_mapping.light_guide");
        return NULL;
    }
    if (!usable) {
        say(reason, cap, "no light samples to guide (the global map is shown directly)");
        return NULL;
    }
    if (scene_has_media(s)) {
        say(reason, cap, "a scene with media: shadow rays carry transmittance, the probes test visibility");
        return NULL;
    }
    int any = 0;
    for (int l = 0; l < s->nlights; l++) any |= guided_light(&s->lights[l]);
    if (!any || s->light_distrib.n == 0) {
        say(reason, cap, "no area or sphere light (a point or directional light has no point to choose)");
        return NULL;
    }
    uint64_t seed = s->settings.seed ^ 0x6c69676874ULL; /* "light" */
    guide_point *pts = NULL;
    size_t np = 0, nj = 0;
    size_t *jp = NULL;
    int *js = NULL;
    point_a *pa = NULL;
    guide *gd = NULL;
    guide_grid grid;
    guide_grid_init(&grid, s, GUIDE_RES);
    if (guide_points(s, GUIDE_PATHS, seed, 0, &pts, &np) < 0 || !(pa = calloc(np ? np : 1, sizeof *pa))) {
        free(pts);
        say(reason, cap, "out of memory for the pilot");
        return NULL;
    }
    stage_a(s, pts, np, seed, pa);
    int rc = plan_jobs(&grid, pts, np, pa, &e, &jp, &js, &nj);
    int want = force == PLAN_ON || (e.blocked > 0 && e.blocked_share >= GUIDE_MIN_SHARE);
    if (rc == 0 && want && nj > 0) {
        gd = malloc(sizeof *gd);
        if (!gd || learn_jobs(gd, s, &grid, GUIDE_G, GUIDE_ALPHA, pts, jp, js, nj, light_probe, NULL, seed, 0,
                              &e.probes, 1) < 0) {
            free(gd);
            gd = NULL;
            rc = PM_ENOMEM;
        }
        if (gd) {
            e.tables = gd->ntables;
            gd->stat_id = stats_register("Integrator/Light samples guided (light guide)");
        }
    }
    free(pts);
    free(pa);
    free(jp);
    free(js);
    if (ev) *ev = e;
    double rate = e.samples ? (double)e.passed / (double)e.samples : 0;
    if (rc < 0) {
        say(reason, cap, "out of memory for the pilot");
        return NULL;
    }
    if (want && (!gd || gd->ntables == 0)) {
        guide_destroy(gd);
        snprintf(reason, cap,
                 "%s, but no cell had light samples that were mostly blocked: nothing to guide (%zu points, "
                 "%llu light samples, %.1f%% pass)",
                 force == PLAN_ON ? "forced on by photon_mapping.light_guide" : "wanted", e.points, e.samples,
                 100 * rate);
        return NULL;
    }
    if (want) {
        *on = 1;
        snprintf(reason, cap,
                 "%s: in %zu of %zu lit regions %.1f%% of the unshadowed light passes, and they carry "
                 "%.0f%% of the light that passes; %llu probes made %zu tables in %zu cells (pilot: "
                 "%zu points, %llu light samples, %.1f%% pass)",
                 force == PLAN_ON ? "forced by photon_mapping.light_guide" : "light samples are mostly blocked",
                 e.blocked, e.cells, 100 * e.blocked_pass, 100 * e.blocked_share, e.probes, gd->ntables, gd->ncells,
                 e.points, e.samples, 100 * rate);
        return gd;
    }
    /* Nothing to learn from: say so, rather than "mostly pass" over evidence of none. */
    if (e.samples == 0)
        snprintf(reason, cap,
                 "no pilot light sample would carry light where the camera looks, shadowed or not (black "
                 "surfaces, or lights facing away): nothing to learn (pilot: %zu points, 0 light samples)",
                 e.points);
    else if (e.passed == 0)
        snprintf(reason, cap,
                 "no pilot light sample passes where the camera looks: nothing to learn (pilot: %zu points, "
                 "%llu light samples, none pass)",
                 e.points, e.samples);
    else
        snprintf(reason, cap,
                 "light samples mostly pass: the regions where they are mostly blocked (%zu of %zu) carry "
                 "%.1f%% of the light that passes, below %.0f%% (pilot: %zu points, %llu light samples, %.1f%% "
                 "pass)",
                 e.blocked, e.cells, 100 * e.blocked_share, 100 * GUIDE_MIN_SHARE, e.points, e.samples,
                 100 * rate);
    return NULL;
}
