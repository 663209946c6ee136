/* guide.c: learned primary-sample guiding per receiver cell (see guide.h): the cells, the
 * tables and their hash, sampling by a table, the pilot's points and the learning from probes.
 * The light guide that plans and learns tables for light sampling is light_guide.c.
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
#include "load/photon_settings.h"
#include "base/sampling.h"
#include "base/stats.h"

#ifdef _OPENMP
#include <omp.h>
#endif

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

uint64_t guide_region(uint64_t key) {
    uint64_t m = CELL_MAX, sh = 0;
    while ((1u << sh) < (unsigned)GUIDE_COARSE) sh++;
    return ((key & m) >> sh) | (((key >> CELL_BITS) & m) >> sh) << CELL_BITS |
           (((key >> (2 * CELL_BITS)) & m) >> sh) << (2 * CELL_BITS) | (key >> (3 * CELL_BITS)) << (3 * CELL_BITS);
}

int guide_cell_ref_cmp(const void *a, const void *b) {
    const guide_cell_ref *x = a, *y = b;
    if (x->cell != y->cell) return x->cell < y->cell ? -1 : 1;
    return x->k < y->k ? -1 : x->k > y->k;
}

size_t guide_thin(const size_t *jp, const int *js, size_t n, size_t want, size_t *tp, int *ts) {
    size_t m = n <= want ? n : want;
    for (size_t j = 0; j < m; j++) { /* j n / m >= j: in place reads ahead of what it writes */
        tp[j] = jp[j * n / m];
        ts[j] = js[j * n / m];
    }
    return m;
}

/* ---- building ----------------------------------------------------------------------------- */

typedef struct row_ref {
    uint64_t cell;
    int slot;
    size_t k; /* row number */
} row_ref;

/* A comparator of this struct's keys in order (importance.c's rec_cmp is alike for another). */
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

/* Member by member: the guide's own arrays (other structs' free functions, as in
 * gather_guide.c, photon_maps.c and mpi/lk_tiles.c, look alike by design). */
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

int guide_learn_jobs_spread(guide *g, const scene *s, const guide_grid *grid, int G, double alpha,
                            const guide_point *pts, const size_t *job_point, const int *job_slot, size_t njobs,
                            guide_probe_fn fn, void *user, uint64_t seed, int threads, unsigned long long *probes) {
    return learn_jobs(g, s, grid, G, alpha, pts, job_point, job_slot, njobs, fn, user, seed, threads, probes, 1);
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

