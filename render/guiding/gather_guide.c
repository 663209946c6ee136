/* gather_guide.c: the photon mapper's gather guide (see gather_guide.h): the pilot that finds the
 * opening or the bright patch (gather_guide_disc.c has the mixture and the port's disc).
 *
 * The pilot probes each point on its own stream (GG_SEED, point) and writes every probe into a
 * fixed slot before anything is summed, so its answer is the same for any thread count; the
 * caller's probe callbacks read the photon map (gather_guide_probe).
 */
#include "guiding/gather_guide.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "scene/material.h"
#include "load/photon_settings.h"
#include "base/sampling.h"
#include "base/stats.h"

#define GG_G 32
#define GG_RES 16
#define GG_PATHS 4096
#define GG_CELL_POINTS 4
#define GG_MAX_JOBS 768
#define GG_MIN_JOBS 96 /* THE PILOT'S SIZE (gather_guide.h): at least this many points */
#define GG_CLEAR_LINES 64 /* THE PILOT'S SIZE: a smaller pilot's answer stands on this many bright rays */
#define GG_BOUNCES 4
#define GG_OUTLIER 16
#define GG_MIN_LINES 16
#define GG_AP_SPREAD 3.0
#define GG_STARVED 0.75
#define GG_PATCH_SPREAD 2.0  /* a bright patch's disc: this many RMS distances of its hits */
#define GG_PATCH_MAX 0.3     /* a bright patch's disc at most this share of the scene's size */
#define GG_PATCH_SHARE 0.25  /* a bright patch carries at least this share of the probed light */
#define GG_PATCH_THROUGH 0.5 /* A PATCH BEHIND THE PORT: at least this share of its light crosses the port */
#define GG_SEED 0x676174686572ULL /* "gather" */
#define GG_CHEAP_EVERY 4   /* the cheap test (gather_guide.h): every 4th of the pilot's points */
#define GG_CHEAP_G 8       /* with 8 x 8 probes each (the pilot: GG_G x GG_G) */
#define GG_CHEAP_MARGIN 2.0 /* what it finds must miss the pilot's bounds by this factor */

void gather_guide_init(gather_guide *gg) {
    memset(gg, 0, sizeof *gg);
    gg->stat_aimed = stats_register("Photon mapping/Gather rays aimed at the opening (gather guide)");
}

void gather_guide_free(gather_guide *gg) {
    int id = gg->stat_aimed;
    memset(gg, 0, sizeof *gg);
    gg->stat_aimed = id;
}

/* ---- the pilot (THE PILOT, DECISION) ------------------------------------------------------- */

/* One probe: its value as read at the hit (base) and, where the map had nothing there, the
 * weight w that the light gathered in y's cell (ycell, -1: none) is multiplied by. */
typedef struct gg_probe {
    float base, w;
    int ycell;
    int found;   /* the map answered at y */
    float y[3];  /* the hit */
} gg_probe;

/* The probes of the points a pilot probes and the light they gather (gg_cell_light): what the
 * pilot and its cheap test both hold. */
typedef struct gg_light {
    gg_probe *pr;          /* G2 probes a point */
    double *v;             /* their values */
    double *Lc, *Ln, *nc;  /* a cell each: the cells' values; scratch */
} gg_light;

/* Member by member: the light's own arrays (other structs' free functions, guide.c's and
 * projmap.c's, look alike by design). */
static void gg_light_free(gg_light *gl) {
    free(gl->pr);
    free(gl->v);
    free(gl->Lc);
    free(gl->Ln);
    free(gl->nc);
    memset(gl, 0, sizeof *gl);
}

/* Room for nj points of G2 probes and ncell cells (at least one of each), the cells' values 0:
 * 0, or PM_ENOMEM with nothing held. */
static int gg_light_alloc(gg_light *gl, size_t nj, size_t G2, size_t ncell) {
    const size_t nj1 = nj ? nj : 1, nc1 = ncell ? ncell : 1;
    gl->pr = malloc(nj1 * G2 * sizeof *gl->pr);
    gl->v = malloc(nj1 * G2 * sizeof *gl->v);
    gl->Lc = calloc(nc1, sizeof *gl->Lc);
    gl->Ln = calloc(nc1, sizeof *gl->Ln);
    gl->nc = calloc(nc1, sizeof *gl->nc);
    if (gl->pr && gl->v && gl->Lc && gl->Ln && gl->nc) return 0;
    gg_light_free(gl);
    return PM_ENOMEM;
}

static int gg_size_cmp(const void *a, const void *b) {
    size_t x = *(const size_t *)a, y = *(const size_t *)b;
    return x < y ? -1 : x > y;
}

/* The index of key c among the sorted keys ck[0..n), or -1. */
static int gg_cell_index(const uint64_t *ck, size_t n, uint64_t c) {
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (ck[mid] < c)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < n && ck[lo] == c ? (int)lo : -1;
}

/* The probe from pt at (u1, u2): a cosine gather ray, read as the gather reads it (probe->read). */
static gg_probe gg_probe_at(const gather_guide_probe *probe, const scene *s, const guide_grid *grid,
                            const uint64_t *ck, size_t nck, const guide_point *pt, double u1, double u2, rng *g) {
    gg_probe pr = {0, 0, -1, 0, {0, 0, 0}};
    vec3 d = sampling_to_world(sample_cosine_hemisphere(u1, u2), material_shading_side(pt->wo, pt->h.ng, pt->h.ns));
    if (!(v3_dot(d, pt->n) > 0)) return pr;
    gather_guide_read rd;
    if (!probe->read(probe->user, s, pt, d, g, &rd)) return pr;
    double x = rd.value, w = rd.weight;
    pr.base = x > 0 && isfinite(x) ? (float)x : 0;
    pr.found = rd.found;
    pr.y[0] = (float)rd.y.x;
    pr.y[1] = (float)rd.y.y;
    pr.y[2] = (float)rd.y.z;
    if (!rd.found && w > 0 && isfinite(w)) {
        pr.w = (float)w;
        pr.ycell = gg_cell_index(ck, nck, guide_cell(grid, rd.y, rd.ny));
    }
    return pr;
}

/* Point j's probed light: the sum of its G2 probes' values v. */
static double gg_point_light(const double *v, size_t j, size_t G2) {
    double t = 0;
    for (size_t i = 0; i < G2; i++) t += v[j * G2 + i];
    return t;
}

/* The bright rays (gather_guide.h, DECISION): the probes that read the map and carry over 1/GG_OUTLIER
 * of their point's light. From {pr, v, nj, G2}: the next one (its point in j), NULL at the end. */
typedef struct gg_bright {
    const gg_probe *pr;
    const double *v;
    size_t nj, G2, j, i; /* i: the next probe of point j to look at */
    double t;            /* point j's probed light */
} gg_bright;

static const gg_probe *gg_bright_next(gg_bright *b) {
    for (; b->j < b->nj; b->j++, b->i = 0) {
        if (b->i == 0) b->t = gg_point_light(b->v, b->j, b->G2);
        while (b->i < b->G2 && b->t > 0) {
            const gg_probe *p = &b->pr[b->j * b->G2 + b->i++];
            if (p->found && p->base > b->t / GG_OUTLIER) return p;
        }
    }
    return NULL;
}

/* The point nearest the n lines (x[i], unit d[i]) (least squares) into *c; 0 if they are
 * (nearly) parallel. *rms: the lines' RMS distance from it. use[i] = 0 leaves line i out. */
static int gg_nearest_point(const vec3 *x, const vec3 *d, const unsigned char *use, size_t n, vec3 *c, double *rms) {
    double A[9] = {0}, b[3] = {0};
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        if (!use[i]) continue;
        double dd[3] = {d[i].x, d[i].y, d[i].z}, xx[3] = {x[i].x, x[i].y, x[i].z};
        for (int r = 0; r < 3; r++)
            for (int k = 0; k < 3; k++) {
                double e = (r == k) - dd[r] * dd[k]; /* I - d d^T: the distance to the line */
                A[3 * r + k] += e;
                b[r] += e * xx[k];
            }
        m++;
    }
#define GG_DET(M) ((M)[0] * ((M)[4] * (M)[8] - (M)[5] * (M)[7]) - (M)[1] * ((M)[3] * (M)[8] - (M)[5] * (M)[6]) + \
                   (M)[2] * ((M)[3] * (M)[7] - (M)[4] * (M)[6]))
    double det = GG_DET(A);
    if (!(m >= 2) || !(fabs(det) > 1e-9 * (double)m * (double)m * (double)m)) return 0;
    double sol[3];
    for (int k = 0; k < 3; k++) { /* Cramer's rule */
        double M[9];
        memcpy(M, A, sizeof M);
        for (int r = 0; r < 3; r++) M[3 * r + k] = b[r];
        sol[k] = GG_DET(M) / det;
    }
#undef GG_DET
    *c = v3(sol[0], sol[1], sol[2]);
    double s2 = 0;
    for (size_t i = 0; i < n; i++)
        if (use[i]) {
            vec3 e = v3_sub(*c, x[i]);
            s2 += v3_len2(v3_sub(e, v3_scale(d[i], v3_dot(e, d[i]))));
        }
    *rms = sqrt(s2 / (double)m);
    return 1;
}

/* The opening from the pilot's probes (gather_guide.h, THE PILOT): 1 and its centre *c and
 * the lines' RMS distance *rms, 0 if none fits, PM_ENOMEM. *nline: the bright rays that read
 * the map; *all, *bright: the probed light in all, and in those rays. */
static int gg_find_opening(const guide_point *pts, const size_t *jp, size_t nj, const gg_probe *pr, const double *v,
                           size_t G2, size_t *nline, double *all, double *bright, vec3 *c, double *rms, vec3 *lit) {
    size_t cap = (nj ? nj : 1) * 8, n = 0;
    vec3 *lx = calloc(2 * cap, sizeof *lx), *ld = lx ? lx + cap : NULL; /* the lines: points, directions */
    unsigned char *use = lx ? calloc(cap, 1) : NULL;
    if (!use) {
        free(lx);
        return PM_ENOMEM;
    }
    *all = *bright = 0;
    for (size_t j = 0; j < nj; j++) *all += gg_point_light(v, j, G2);
    gg_bright b = {.pr = pr, .v = v, .nj = nj, .G2 = G2};
    for (const gg_probe *p; n < cap && (p = gg_bright_next(&b));) {
        vec3 x = lx[n] = pts[jp[b.j]].h.p;
        ld[n] = v3_norm(v3_sub(v3(p->y[0], p->y[1], p->y[2]), x));
        use[n++] = 1;
        *bright += p->base;
    }
    int fit = gg_nearest_point(lx, ld, use, n, c, rms);
    if (fit) { /* again without the lines far from the first fit (another source of bright rays) */
        for (size_t l = 0; l < n; l++) {
            vec3 e = v3_sub(*c, lx[l]);
            use[l] = v3_len(v3_sub(e, v3_scale(ld[l], v3_dot(e, ld[l])))) <= 3 * *rms;
        }
        fit = gg_nearest_point(lx, ld, use, n, c, rms);
    }
    /* The lit side: the mean direction of the fitted lines, from the starved points through the
     * opening toward the map's light (gather_guide.h, WHO AIMS). */
    vec3 sum = v3s(0);
    for (size_t l = 0; fit && l < n; l++)
        if (use[l]) sum = v3_add(sum, ld[l]);
    *lit = v3_len2(sum) > 0 ? v3_norm(sum) : v3s(0);
    *nline = n;
    free(lx);
    free(use);
    return fit;
}

/* A bright patch (gather_guide.h, BRIGHT PATCHES): the hits of the rays that read the map and
 * carry over 1/GG_OUTLIER of their point's light, weighted by their light: their centre *c and
 * RMS distance *rms from it, again without the hits 3 RMS away (another bright place). 1 when
 * at least GG_MIN_LINES such hits are left; *n: how many; *share: their share of the probed
 * light (all: the probed light in all). */
static int gg_find_patch(const size_t nj, const gg_probe *pr, const double *v, size_t G2, double all, vec3 *c,
                         double *rms, size_t *n, double *share) {
    *n = 0;
    *share = 0;
    *rms = 0;
    for (int pass = 0; pass < 2; pass++) {
        vec3 sum = v3s(0);
        double w = 0, s2 = 0;
        size_t m = 0;
        gg_bright b = {.pr = pr, .v = v, .nj = nj, .G2 = G2};
        for (const gg_probe *p; (p = gg_bright_next(&b));) {
            vec3 y = v3(p->y[0], p->y[1], p->y[2]);
            if (pass && v3_len2(v3_sub(y, *c)) > 9 * *rms * *rms) continue;
            sum = v3_add(sum, v3_scale(y, p->base));
            s2 += p->base * v3_len2(y);
            w += p->base;
            m++;
        }
        if (!(w > 0) || m < GG_MIN_LINES) return 0;
        *c = v3_scale(sum, 1 / w);
        *rms = sqrt(fmax(0, s2 / w - v3_len2(*c)));
        *n = m;
        *share = all > 0 ? w / all : 0;
    }
    return *rms > 0;
}

/* A PATCH BEHIND THE PORT (gather_guide.h): of the light of the bright rays whose hits lie
 * within 3 RMS of the patch's centre c (the hits gg_find_patch kept), the share whose ray from
 * its point to its hit crosses the port pt. */
static double gg_patch_through(const port *pt, const guide_point *pts, const size_t *tp, size_t nj,
                               const gg_probe *pr, const double *v, size_t G2, vec3 c, double rms) {
    double w = 0, thru = 0;
    gg_bright b = {.pr = pr, .v = v, .nj = nj, .G2 = G2};
    for (const gg_probe *p; (p = gg_bright_next(&b));) {
        vec3 y = v3(p->y[0], p->y[1], p->y[2]), x = pts[tp[b.j]].h.p, d = v3_sub(y, x);
        if (v3_len2(v3_sub(y, c)) > 9 * rms * rms) continue;
        double len = v3_len(d), tc, cp;
        w += p->base;
        if (len > 0 && port_cross(pt, x, v3_scale(d, 1 / len), &tc, &cp) && tc < len) thru += p->base;
    }
    return w > 0 ? thru / w : 0;
}

/* BRIGHT PATCHES: when no opening fits in a scene with ports, the patch of the bright rays'
 * hits: 1 with gg's centre, radius and lit set, and its evidence in pw; 0 with why not in pw
 * ("; no bright patch..."). size: the scene's largest side. */
static int gg_patch(gather_guide *gg, const port *pt, const guide_point *pts, const size_t *tp, size_t nj,
                    const gg_probe *pr, const double *v, size_t G2, double all, double size, char *pw, size_t cap,
                    size_t *hits) {
    size_t n = 0;
    double share = 0, rms = 0;
    vec3 c = v3s(0);
    int found = gg_find_patch(nj, pr, v, G2, all, &c, &rms, &n, &share);
    *hits = n;
    if (!found) {
        snprintf(pw, cap, "; no bright patch (too few bright hits)");
        return 0;
    }
    double r = GG_PATCH_SPREAD * rms;
    double thru = pt ? gg_patch_through(pt, pts, tp, nj, pr, v, G2, c, rms) : 0;
    if (thru >= GG_PATCH_THROUGH) {
        snprintf(pw, cap, "; no bright patch: %.0f%% of the light of the bright rays that end within radius %.3g of "
                 "(%.4g, %.4g, %.4g) comes through the photon port (at least %.0f%%: the port is the tighter aim)",
                 100 * thru, r, c.x, c.y, c.z, 100 * GG_PATCH_THROUGH);
        return 0;
    }
    if (!(r <= GG_PATCH_MAX * size && share >= GG_PATCH_SHARE)) {
        snprintf(pw, cap, "; no bright patch: their hits spread over radius %.3g (at most %.3g) with %.1f%% of the "
                 "probed light (at least %.0f%%)", r, GG_PATCH_MAX * size, 100 * share, 100 * GG_PATCH_SHARE);
        return 0;
    }
    gg->centre = c;
    gg->radius = r;
    gg->lit = v3s(0); /* a patch: every point in front of it may aim */
    snprintf(pw, cap, "a bright patch (the scene has photon ports) at (%.4g, %.4g, %.4g), radius %.3g: %zu rays that "
             "read the photon map end there, carrying %.1f%% of the probed light", c.x, c.y, c.z, r, n, 100 * share);
    return 1;
}

/* The pilot's points (jp[0..*nj)) and their cells (jc[j], an index into ck[0..*ncell), the cells
 * in key order): per cell its first GG_CELL_POINTS points; at most GG_MAX_JOBS, evenly in point
 * order. pk: room for npts; ck, jp and jc: room for npts each. */
static void gg_pick_points(const guide_grid *grid, const guide_point *pts, size_t npts, guide_cell_ref *pk,
                           uint64_t *ck, size_t *ncell, size_t *jp, int *jc, size_t *nj) {
    for (size_t k = 0; k < npts; k++) pk[k] = (guide_cell_ref){guide_cell(grid, pts[k].h.p, pts[k].n), k};
    qsort(pk, npts, sizeof *pk, guide_cell_ref_cmp);
    for (size_t a = 0, b; a < npts; a = b) {
        for (b = a; b < npts && pk[b].cell == pk[a].cell; b++)
            if (b - a < GG_CELL_POINTS) jp[(*nj)++] = pk[b].k;
        ck[(*ncell)++] = pk[a].cell;
    }
    qsort(jp, *nj, sizeof *jp, gg_size_cmp);
    if (*nj > GG_MAX_JOBS) {
        for (size_t j = 0; j < GG_MAX_JOBS; j++) jp[j] = jp[j * *nj / GG_MAX_JOBS];
        *nj = GG_MAX_JOBS;
    }
    for (size_t j = 0; j < *nj; j++) jc[j] = gg_cell_index(ck, *ncell, guide_cell(grid, pts[jp[j]].h.p, pts[jp[j]].n));
}

/* THE PILOT'S SIZE (gather_guide.h): the full pilot's points for the render s's camera is set
 * for, at most its camera samples' worth of probes, within [GG_MIN_JOBS, GG_MAX_JOBS]. */
size_t gather_guide_pilot_points(const scene *s) {
    const double n = ceil((double)s->cam.width * (double)s->cam.height * (double)s->cam.spp / ((double)GG_G * GG_G));
    return n >= GG_MAX_JOBS ? GG_MAX_JOBS : n <= GG_MIN_JOBS ? GG_MIN_JOBS : (size_t)n;
}

/* One probe per stratum of each chosen point, jittered, into pr[j GG_G^2 + stratum]; each point on
 * its own stream (thread-count free). */
static void gg_probe_points(const gather_guide_probe *probe, const scene *s, const guide_grid *grid,
                            const uint64_t *ck, size_t ncell, const guide_point *pts, const size_t *jp, size_t nj,
                            gg_probe *pr, int G, uint64_t stream) {
    const size_t G2 = (size_t)G * (size_t)G;
#pragma omp parallel for schedule(dynamic, 4)
    for (long j = 0; j < (long)nj; j++) {
        rng g = rng_stream(GG_SEED, jp[j], stream);
        for (int b = 0; b < G; b++)
            for (int a = 0; a < G; a++) {
                /* Two statements, not two arguments of one call: C leaves the order in which a
                 * call's arguments are evaluated unspecified, so compilers could draw them in
                 * either order and the pilot would depend on the compiler. */
                double v2 = (b + rng_uniform(&g)) / G; /* the order gcc used: images kept */
                double u2 = (a + rng_uniform(&g)) / G;
                pr[(size_t)j * G2 + (size_t)(a + G * b)] =
                    gg_probe_at(probe, s, grid, ck, ncell, &pts[jp[j]], u2, v2, &g);
            }
    }
}

/* The light gathered where the map has nothing, from gl's probes pr of the nj points in cells jc:
 * each round gives every cell the mean of its points' probes, with the last round's cell values
 * at the probes' hits (one more bounce). gl->v: the probes' values of the last round; gl->Lc: the
 * cells' values. */
static void gg_cell_light(gg_light *gl, const int *jc, size_t nj, size_t ncell, size_t G2) {
    const size_t nc1 = ncell ? ncell : 1;
    const gg_probe *pr = gl->pr;
    double *v = gl->v, *Lc = gl->Lc, *Ln = gl->Ln, *nc = gl->nc;
    for (int round = 0; round <= GG_BOUNCES; round++) {
        memset(Ln, 0, nc1 * sizeof *Ln);
        memset(nc, 0, nc1 * sizeof *nc);
        for (size_t j = 0; j < nj; j++) {
            double t = 0;
            for (size_t i = 0; i < G2; i++) {
                const gg_probe *p = &pr[j * G2 + i];
                v[j * G2 + i] = p->base + (p->ycell >= 0 ? p->w * Lc[p->ycell] : 0);
                t += v[j * G2 + i];
            }
            Ln[jc[j]] += t / (double)G2;
            nc[jc[j]] += 1;
        }
        for (size_t c = 0; c < ncell; c++) Lc[c] = nc[c] > 0 ? Ln[c] / nc[c] : 0;
    }
}

/* THE CHEAP TEST (gather_guide.h): the pilot's rules on every GG_CHEAP_EVERY-th of its points
 * (jp, jc: nj of them) with GG_CHEAP_G^2 probes each, on their own streams. 0 when what it finds
 * rules out both an opening and a bright patch by a margin of GG_CHEAP_MARGIN (the full pilot
 * is then skipped, with the evidence in why), 1 when the full pilot may find one, PM_ENOMEM. */
static int gg_may_pay(const gather_guide_probe *probe, const scene *s, const guide_grid *grid, const uint64_t *ck,
                      size_t ncell, const guide_point *pts, const size_t *jp, const int *jc, size_t nj, double size,
                      char *why, size_t cap) {
    const size_t G2 = (size_t)GG_CHEAP_G * GG_CHEAP_G, ns = (nj + GG_CHEAP_EVERY - 1) / GG_CHEAP_EVERY;
    size_t ns1 = ns ? ns : 1, nline = 0, np = 0;
    size_t *sp = malloc(ns1 * sizeof *sp);
    int *sc = malloc(ns1 * sizeof *sc), rc = PM_ENOMEM;
    gg_light gl = {0};
    if (!sp || !sc || gg_light_alloc(&gl, ns, G2, ncell) < 0) goto done;
    const gg_probe *pr = gl.pr;
    const double *v = gl.v;
    for (size_t j = 0; j < ns; j++) sp[j] = jp[j * GG_CHEAP_EVERY], sc[j] = jc[j * GG_CHEAP_EVERY];
    gg_probe_points(probe, s, grid, ck, ncell, pts, sp, ns, gl.pr, GG_CHEAP_G, 2);
    gg_cell_light(&gl, sc, ns, ncell, G2);
    double all = 0, bright = 0, rms = 0, prms = 0, share = 0;
    vec3 c, lit;
    int fit = gg_find_opening(pts, sp, ns, pr, v, G2, &nline, &all, &bright, &c, &rms, &lit);
    if (fit < 0) goto done;
    int patch = gg_find_patch(ns, pr, v, G2, all, &c, &prms, &np, &share);
    /* Ruled out only where the cheap pilot sees enough to say so: a fit too wide by the margin. */
    int no_opening = fit && GG_AP_SPREAD * rms > GG_CHEAP_MARGIN * 0.02 * size;
    int no_patch = patch && (GG_PATCH_SPREAD * prms > GG_CHEAP_MARGIN * GG_PATCH_MAX * size ||
                             share < GG_PATCH_SHARE / GG_CHEAP_MARGIN);
    rc = !(no_opening && no_patch);
    if (!rc)
        snprintf(why, cap, "a cheap pilot (%zu points, %zu probes) rules both out by a factor %g: its bright rays "
                 "meet within %.3g (an opening: at most %.3g), their hits spread over radius %.3g with %.1f%% of the "
                 "probed light (a patch: at most %.3g, at least %.0f%%)", ns, ns * G2, GG_CHEAP_MARGIN,
                 GG_AP_SPREAD * rms, 0.02 * size, GG_PATCH_SPREAD * prms, 100 * share, GG_PATCH_MAX * size,
                 100 * GG_PATCH_SHARE);
done:
    free(sp);
    free(sc);
    gg_light_free(&gl);
    return rc;
}

/* Photon-starved camera points (no precomputed irradiance on their side), of *cam. */
static size_t gg_starved(const gather_guide_probe *probe, const scene *s, const guide_point *pts, size_t npts,
                         size_t *cam) {
    size_t starved = 0;
    *cam = 0;
    for (size_t k = 0; k < npts; k++) {
        if (pts[k].bounce) continue;
        ++*cam;
        starved += !probe->found(probe->user, s, &pts[k].h, pts[k].wo);
    }
    return starved;
}

/* A round of the pilot (THE PILOT'S SIZE): nj points tp (cells tc) probed into gl, and what they fit: an
 * opening, else (patches: the scene has ports) a bright patch (gg's disc; evidence in f->pw). 0, or PM_ENOMEM. */
typedef struct gg_fit {
    size_t nline, hits; /* bright rays; the patch's bright hits (outliers dropped) */
    double all, bright, rms;
    vec3 c, lit;
    int opening, patch;
    char pw[224];
} gg_fit;
static int gg_round(const gather_guide_probe *probe, const scene *s, const guide_grid *grid, const uint64_t *ck,
                    size_t ncell, const guide_point *pts, const size_t *tp, const int *tc, size_t nj, int patches,
                    double size, gather_guide *gg, gg_light *gl, gg_fit *f) {
    const size_t G2 = (size_t)GG_G * GG_G;
    gg_light_free(gl);
    memset(f, 0, sizeof *f);
    if (gg_light_alloc(gl, nj, G2, ncell) < 0) return PM_ENOMEM;
    gg_probe_points(probe, s, grid, ck, ncell, pts, tp, nj, gl->pr, GG_G, 1);
    gg_cell_light(gl, tc, nj, ncell, G2);
    /* The opening: rays that read the map and carry over 1/GG_OUTLIER of their point's light. */
    int fit = gg_find_opening(pts, tp, nj, gl->pr, gl->v, G2, &f->nline, &f->all, &f->bright, &f->c, &f->rms,
                              &f->lit);
    if (fit < 0) return PM_ENOMEM;
    f->opening = fit && f->nline >= GG_MIN_LINES && GG_AP_SPREAD * f->rms <= 0.02 * size && f->rms > 0;
    f->patch = !f->opening && patches &&
               gg_patch(gg, probe->port, pts, tp, nj, gl->pr, gl->v, G2, f->all, size, f->pw, sizeof f->pw, &f->hits);
    return 0;
}

int gather_guide_make(gather_guide *gg, const scene *s, int force, const char *why,
                      const gather_guide_probe *probe, char *err, size_t errcap) {
    gg->on = 0;
    gg->aim = 0;
    if (force == PLAN_OFF) {
        snprintf(gg->reason, sizeof gg->reason, "off (forced)");
        return 0;
    }
    if (why) {
        snprintf(gg->reason, sizeof gg->reason, "off (%s%s)", why, force == PLAN_ON ? "; asked for" : "");
        return 0;
    }
    guide_point *pts = NULL;
    size_t npts = 0;
    int rc = guide_points(s, GG_PATHS, GG_SEED, 0, &pts, &npts);
    if (rc < 0) {
        snprintf(err, errcap, "out of memory (gather guide pilot)");
        return rc;
    }
    size_t cam = 0, starved = gg_starved(probe, s, pts, npts, &cam);
    int starving = (double)starved >= GG_STARVED * (double)cam && starved > 0;
    /* Not starved, but the scene has photon ports: its light comes in through openings and lands
     * in bright patches, so a patch is looked for (BRIGHT PATCHES). */
    int patches = probe->ports;
    if (force != PLAN_ON && !starving && !patches) {
        snprintf(gg->reason, sizeof gg->reason,
                 "off (%zu of %zu camera points find no precomputed irradiance on their side, under "
                 "%.0f%%: the gathers read the photon map, no opening is looked for; no photon ports: no bright "
                 "patch is looked for)",
                 starved, cam, 100 * GG_STARVED);
        free(pts);
        return 0;
    }
    guide_grid grid;
    guide_grid_init(&grid, s, GG_RES);
    const size_t G2 = (size_t)GG_G * GG_G;
    size_t n1 = npts ? npts : 1, nj = 0, ncell = 0;
    guide_cell_ref *pk = malloc(n1 * sizeof *pk);
    uint64_t *ck = malloc(n1 * sizeof *ck);
    size_t *jp = malloc(n1 * sizeof *jp);
    int *jc = malloc(n1 * sizeof *jc), *tc = malloc(n1 * sizeof *tc);
    size_t *tp = malloc(n1 * sizeof *tp); /* the points a round probes */
    gg_light gl = {0};
    if (!pk || !ck || !jp || !jc || !tp || !tc) goto oom;
    gg_pick_points(&grid, pts, npts, pk, ck, &ncell, jp, jc, &nj);
    double size = v3_maxc(v3_sub(s->bounds_hi, s->bounds_lo));
    if (force != PLAN_ON && patches && !starving) { /* THE CHEAP TEST */
        char cheap[400];
        if ((rc = gg_may_pay(probe, s, &grid, ck, ncell, pts, jp, jc, nj, size, cheap, sizeof cheap)) < 0) goto oom;
        if (!rc) { /* rc = 0: done, the guide off or on the port (PORTS AS OPENINGS) */
            char pw[400] = "";
            if (probe->port) gather_guide_port(gg, s, probe->port, pw, sizeof pw);
            snprintf(gg->reason, sizeof gg->reason, "%s (%zu of %zu camera points find no precomputed irradiance, "
                     "under %.0f%%; the scene has photon ports, so an opening or a bright patch is looked for: %s%s)",
                     gg->aim ? "on" : "off", starved, cam, 100 * GG_STARVED, cheap, pw);
            goto done;
        }
    }
    size_t picked = nj, first_n = 0, first_lines = 0; /* first_*: a smaller pilot whose answer was unclear */
    gg_fit f; /* THE PILOT'S SIZE: a patch's pilot as the render pays for, again on all points if unclear */
    for (size_t want = !starving && force != PLAN_ON ? gather_guide_pilot_points(s) : nj;; want = picked) {
        nj = guide_thin(jp, jc, picked, want, tp, tc);
        if (gg_round(probe, s, &grid, ck, ncell, pts, tp, tc, nj, patches, size, gg, &gl, &f) < 0) goto oom;
        size_t clear = f.patch ? f.hits : f.nline; /* the bright rays the answer rests on */
        if (nj >= picked || clear >= GG_CLEAR_LINES) break;
        first_n = nj;
        first_lines = clear;
    }
    if (!f.patch) {
        gg->centre = f.c;
        gg->radius = GG_AP_SPREAD * f.rms;
        gg->lit = f.lit;
    }
    char what[720], sized[224] = "", pw[400] = "";
    if (!f.opening && !f.patch && probe->port) gather_guide_port(gg, s, probe->port, pw, sizeof pw);
    gg->aim = f.opening || f.patch || gg->aim;
    gg->on = gg->aim || force == PLAN_ON;
    if (nj < picked)
        snprintf(sized, sizeof sized, " (of %zu picked: at most the %d x %d x %d camera samples' worth of probes, "
                 "at least %d points)", picked, s->cam.width, s->cam.height, s->cam.spp, GG_MIN_JOBS);
    else if (first_n)
        snprintf(sized, sizeof sized, " (all picked: the %d x %d x %d camera samples' %zu points found %zu bright "
                 "rays, under %d)", s->cam.width, s->cam.height, s->cam.spp, first_n, first_lines, GG_CLEAR_LINES);
    if (f.patch)
        snprintf(what, sizeof what, "no opening, but %s", f.pw);
    else if (f.opening)
        snprintf(what, sizeof what, "an opening at (%.4g, %.4g, %.4g), radius %.3g, its light along (%.2f, %.2f, %.2f): "
                 "%zu rays that read the photon map meet there, carrying %.1f%% of the probed light", f.c.x, f.c.y,
                 f.c.z, gg->radius, f.lit.x, f.lit.y, f.lit.z, f.nline, f.all > 0 ? 100 * f.bright / f.all : 0);
    else
        snprintf(what, sizeof what, "no opening (%zu bright rays that read the photon map, %s)%s%s", f.nline,
                 f.nline < GG_MIN_LINES ? "too few" : "not meeting within 2% of the scene's size", f.pw, pw);
    snprintf(gg->reason, sizeof gg->reason,
             "%s (%zu of %zu camera points find no precomputed irradiance; the pilot probed %zu points in %zu "
             "cells%s, %zu probes: %s)",
             force == PLAN_ON && !gg->aim ? "on (forced; no opening: gathers stay cosine)"
             : force == PLAN_ON           ? "on (forced)"
             : gg->on                     ? "on"
                                          : "off",
             starved, cam, nj, ncell, sized, nj * G2, what);
    rc = 0;
    goto done;
oom:
    rc = PM_ENOMEM;
    snprintf(err, errcap, "out of memory (gather guide pilot)");
done:
    if (rc < 0 || !gg->on) gg->aim = 0;
    free(pts);
    free(pk);
    free(ck);
    free(jp);
    free(jc);
    free(tp);
    free(tc);
    gg_light_free(&gl);
    return rc;
}
