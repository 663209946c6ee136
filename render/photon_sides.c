/* photon_sides.c: visibility-checked precomputed irradiance and lookups; see photon_sides.h.
 *
 * The build runs one estimate per chosen photon on OpenMP threads (each with its own neighbour
 * buffer), writes the results by the photon's rank among the chosen ones (so the cache is the
 * same for any thread count), then builds a kd-tree over the chosen photons alone.
 */
#include "photon_sides.h"

#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "photonmap/estimate.h"

#ifdef _OPENMP
#include <omp.h>
#endif

/* Directions of the visible-area probe of an estimate with a hidden neighbour. */
#define SIDE_AREA_DIRS 32
/* Candidates examined by an estimate that meets a wall, as a multiple of k. */
#define SIDE_WIDEN 4
/* Candidates a lookup tests for visibility, nearest first. */
#define SIDE_LOOKUP_CANDIDATES 8

static vec3 v3f(const float f[3]) { return v3(f[0], f[1], f[2]); }

double side_free_height(const scene *s, vec3 p, vec3 np, double cap) {
    if (!(cap > 0)) return 0;
    ray r = {v3_offset(p, np, np), np};
    hit h;
    if (!isfinite(cap)) cap = 1e300;
    if (!scene_intersect(s, r, cap, &h)) return cap;
    return h.t;
}

int side_visible_h(const scene *s, vec3 p, vec3 np, double hp, vec3 q, vec3 nq, double hq) {
    vec3 d = v3_sub(q, p);
    double len = v3_len(d);
    if (!(len > 0)) return 1;
    /* Lift each end off its surface by L/4, on the side its normal points to (the side the
     * photon arrived on, or the side the query looks from), but at most halfway to the first
     * surface above it, so the lifted end stays in the space on that side; see the top of
     * photon_sides.h. */
    vec3 pl = v3_madd(p, np, fmin(0.25 * len, 0.5 * hp)), ql = v3_madd(q, nq, fmin(0.25 * len, 0.5 * hq));
    return scene_visible(s, pl, v3s(0), ql, v3s(0));
}

int side_visible(const scene *s, vec3 p, vec3 np, vec3 q, vec3 nq) {
    double L4 = 0.25 * v3_len(v3_sub(q, p));
    return side_visible_h(s, p, np, side_free_height(s, p, np, L4), q, nq,
                          side_free_height(s, q, nq, L4));
}


/* The fraction of the disc of radius r around the surface point p (normal n, the photon's
 * quantized one) that lies on p's side of every surface: SIDE_AREA_DIRS rays along the
 * surface, just off it, each reaching min(t, r); the area in polar form is the mean of
 * min(t, r)^2 / r^2 over the directions, so a wall at distance w cuts its sector to w. The
 * rays run in the tangent plane of the surface's exact geometric normal, found by one short
 * ray back to the surface: in the plane of the quantized normal (up to 10 degrees off) they
 * would run into the surface itself within a few of its free heights. */
static double visible_disc_fraction(const scene *s, vec3 p, vec3 n, double r) {
    if (!(r > 0) || !isfinite(r)) return 1.0;
    double scale = 1.0 + v3_maxabs(p), delta = 1e-5 * scale;
    ray down = {v3_madd(p, n, delta), v3_neg(n)};
    hit h;
    vec3 base = p, ng = n;
    if (scene_intersect(s, down, 3 * delta, &h)) {
        base = h.p;
        ng = v3_dot(h.ng, n) >= 0 ? h.ng : v3_neg(h.ng);
    }
    vec3 t1, t2;
    v3_basis(ng, &t1, &t2);
    vec3 o = v3_madd(base, ng, 4 * 64e-9 * scale); /* a few times v3_offset's epsilon */
    double sum = 0;
    for (int k = 0; k < SIDE_AREA_DIRS; k++) {
        double a = 2 * M_PI * (k + 0.5) / SIDE_AREA_DIRS;
        vec3 d = v3_add(v3_scale(t1, cos(a)), v3_scale(t2, sin(a)));
        ray ry = {o, d};
        double t = scene_intersect(s, ry, r, &h) ? h.t : r;
        sum += (t / r) * (t / r);
    }
    return sum / SIDE_AREA_DIRS;
}

double side_disc_fraction(const scene *s, vec3 p, vec3 n, double r) {
    double f = visible_disc_fraction(s, p, n, r);
    return f < 1.0 / SIDE_AREA_DIRS ? 1.0 / SIDE_AREA_DIRS : f;
}

/* The disc estimate of irradiance from the photons nb[0..count) over the disc of radius^2
 * r2: with rim = 1 the farthest of them lies on the rim (a k-th nearest), and the area is
 * scaled by k / (k - 0.5) as pm_estimate's PM_BIAS_AREA does; with rim = 0 the whole disc
 * was searched and the area is used as it is. area_fraction: the part of the disc on this
 * side of every wall (1 without walls). */
static void disc_irradiance(const pm_photon *ph, const pm_neighbor *nb, int count, double r2,
                            int rim, double area_fraction, float e[3]) {
    double sum[3] = {0, 0, 0};
    for (int j = 0; j < count; j++) {
        float pw[3];
        pm_rgbe_decode(ph[nb[j].index].power, pw);
        for (int c = 0; c < 3; c++) sum[c] += pw[c];
    }
    double area = M_PI * r2 * area_fraction;
    if (rim && count > 1) area *= (double)count / (count - 0.5);
    for (int c = 0; c < 3; c++) e[c] = area > 0 && isfinite(area) ? (float)(sum[c] / area) : 0.0f;
}

int side_cache_build(side_cache *c, const scene *s, const pm_kdtree *global, const pm_photon *ph,
                     size_t n, unsigned k, float max_dist2, char *err, size_t errcap) {
    memset(c, 0, sizeof *c);
    if (!global || n == 0) return 0;
    /* Which photons: the quarter that pm_irradiance_build precomputes (neither leaves nor
     * parents of leaves), numbered by rank. */
    size_t m = 0;
    uint32_t *which = malloc(n * sizeof *which);
    if (!which) goto nomem;
    for (size_t i = 0; i < n; i++)
        if (pm_kdtree_height(global, (uint32_t)i) >= 2) which[m++] = (uint32_t)i;
    c->recs = calloc(m ? m : 1, sizeof *c->recs);
    c->r2 = malloc((m ? m : 1) * sizeof *c->r2);
    c->hfree = malloc((m ? m : 1) * sizeof *c->hfree);
    float *r2tmp = malloc((m ? 2 * m : 1) * sizeof *r2tmp); /* r2, then free heights */
    uint32_t *perm = malloc((m ? m : 1) * sizeof *perm);
    if (!c->recs || !c->r2 || !c->hfree || !r2tmp || !perm) {
        free(r2tmp);
        free(perm);
        free(which);
        goto nomem;
    }
    /* Every photon's free height along its normal, up to the largest lift an estimate can
     * use (a quarter of the search radius): one ray per photon, so that each visibility test
     * below is a single ray. */
    float *hfree = malloc(n * sizeof *hfree);
    if (!hfree) {
        free(r2tmp);
        free(perm);
        free(which);
        goto nomem;
    }
    double cap = 0.25 * sqrt((double)max_dist2);
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 256)
#endif
    for (size_t i = 0; i < n; i++) {
        float nf[3];
        pm_normal_decode(ph[i].normal, nf);
        hfree[i] = (float)side_free_height(s, v3f(ph[i].pos), v3f(nf), cap);
    }
    unsigned long long rays1 = n, rays2 = 0;
    float *hsel = r2tmp + m; /* the chosen photons' free heights, by rank */
    size_t again = 0;
    int fail = 0;
#ifdef _OPENMP
#pragma omp parallel reduction(+ : rays1, rays2, again) reduction(| : fail)
#endif
    {
        /* SIDE_WIDEN x k candidates for the estimates that meet a wall. */
        pm_neighbor *nb = malloc((size_t)SIDE_WIDEN * k * sizeof *nb);
        if (!nb) fail = 1;
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 64)
#endif
        for (size_t j = 0; j < m; j++) {
            if (!nb) continue;
            const pm_photon *p = &ph[which[j]];
            float nf[3];
            pm_normal_decode(p->normal, nf);
            vec3 pp = v3f(p->pos), pn = v3f(nf);
            double hp = hfree[which[j]];
            pm_knn_options ko = {0};
            ko.filter = pm_filter_front;
            ko.filter_user = nf;
            ko.flags = PM_SORT;
            int found = pm_kdtree_knn_ex(global, p->pos, k, max_dist2, &ko, nb, NULL);
            if (found < 0) found = 0;
            int hidden = 0;
            for (int t = 0; t < found && !hidden; t++) {
                const pm_photon *q = &ph[nb[t].index];
                if (nb[t].dist2 == 0) continue;
                float nq[3];
                pm_normal_decode(q->normal, nq);
                rays1++;
                if (!side_visible_h(s, pp, pn, hp, v3f(q->pos), v3f(nq), hfree[nb[t].index]))
                    hidden = 1;
            }
            float e[3];
            if (!hidden) {
                /* The usual estimate: k photons, the k-th on the rim; or the whole disc. */
                double r2 = (unsigned)found == k ? nb[found - 1].dist2 : (double)max_dist2;
                disc_irradiance(ph, nb, found, r2, (unsigned)found == k, 1.0, e);
                r2tmp[j] = (float)r2;
            } else {
                /* A wall: take SIDE_WIDEN x k candidates in order of distance and keep the
                 * visible ones until k are kept. Every photon closer than the last one tested
                 * was tested, so the estimate covers the disc up to it (the k-th kept on its
                 * rim, or, short of k, the whole disc searched). The disc reaches past the
                 * wall, where no photon of this side can be: divide by the part of the disc on
                 * this side only (a wall leaves this side's photons at their density over a
                 * smaller area). Rays per estimate: at most SIDE_WIDEN x k + SIDE_AREA_DIRS + 1. */
                again++;
                unsigned want = (unsigned)SIDE_WIDEN * k;
                int n2 = pm_kdtree_knn_ex(global, p->pos, want, max_dist2, &ko, nb, NULL);
                if (n2 < 0) n2 = 0;
                int kept = 0;
                double r2 = (double)max_dist2;
                int rim = 0;
                for (int t = 0; t < n2; t++) {
                    const pm_photon *q = &ph[nb[t].index];
                    int vis = 1;
                    if (nb[t].dist2 > 0) {
                        float nq[3];
                        pm_normal_decode(q->normal, nq);
                        rays2++;
                        vis = side_visible_h(s, pp, pn, hp, v3f(q->pos), v3f(nq), hfree[nb[t].index]);
                    }
                    if (vis) {
                        nb[kept++] = nb[t];
                        if ((unsigned)kept == k) {
                            r2 = nb[t].dist2;
                            rim = 1;
                            break;
                        }
                    }
                }
                if (!rim && (unsigned)n2 == want) r2 = nb[n2 - 1].dist2; /* examined up to there */
                double frac = visible_disc_fraction(s, pp, pn, sqrt(r2));
                rays2 += SIDE_AREA_DIRS + 1;
                if (frac < 1.0 / SIDE_AREA_DIRS) frac = 1.0 / SIDE_AREA_DIRS;
                disc_irradiance(ph, nb, kept, r2, rim, frac, e);
                r2tmp[j] = (float)r2;
            }
            c->recs[j] = *p;
            hsel[j] = hfree[which[j]];
            pm_rgbe_encode(e, c->recs[j].power);
        }
        free(nb);
    }
    free(which);
    free(hfree);
    if (fail) {
        free(r2tmp);
        free(perm);
        goto nomem;
    }
    c->n = m;
    c->rays_first = rays1;
    c->rays_second = rays2;
    c->researched = again;
    if (m) {
        pm_kdtree_config kc = pm_kdtree_photon_config(8);
        int rc = pm_kdtree_build(&c->tree, c->recs, m, &kc, perm);
        if (rc < 0) {
            free(r2tmp);
            free(perm);
            side_cache_free(c);
            snprintf(err, errcap, "precomputing irradiance: %s", pm_strerror(rc));
            return rc;
        }
        for (size_t t = 0; t < m; t++) {
            c->r2[t] = r2tmp[perm[t]];
            c->hfree[t] = hsel[perm[t]];
        }
    }
    free(r2tmp);
    free(perm);
    return 0;
nomem:
    side_cache_free(c);
    snprintf(err, errcap, "precomputing irradiance: out of memory");
    return PM_ENOMEM;
}

void side_cache_free(side_cache *c) {
    pm_kdtree_free(c->tree);
    free(c->recs);
    free(c->r2);
    free(c->hfree);
    memset(c, 0, sizeof *c);
}

typedef struct look_ctx {
    const side_cache *c;
    const scene *s;
    vec3 y, n;
    double hy; /* y's free height */
    float nf[3], yf[3];
} look_ctx;

/* A similar normal (within about 45 degrees) and y within the photon's own estimate radius. */
static int lookup_accepts(void *user, const void *record, uint32_t index) {
    const look_ctx *l = user;
    const pm_photon *p = record;
    float pn[3];
    pm_normal_decode(p->normal, pn);
    if (l->nf[0] * pn[0] + l->nf[1] * pn[1] + l->nf[2] * pn[2] < 0.7f) return 0;
    float d[3] = {p->pos[0] - l->yf[0], p->pos[1] - l->yf[1], p->pos[2] - l->yf[2]};
    return d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < l->c->r2[index];
}

int side_cache_lookup(const side_cache *c, const scene *s, vec3 y, vec3 n, float max_dist2,
                      float e[3]) {
    e[0] = e[1] = e[2] = 0;
    if (!c->tree) return 0;
    look_ctx l = {c, s, y, n, side_free_height(s, y, n, 0.25 * sqrt((double)max_dist2)),
                  {(float)n.x, (float)n.y, (float)n.z}, {(float)y.x, (float)y.y, (float)y.z}};
    /* The nearest few that pass the cheap tests, then the first of them that y sees: a
     * bounded number of shadow rays per lookup even beside a wall with many photons behind. */
    pm_neighbor nb[SIDE_LOOKUP_CANDIDATES];
    pm_knn_options ko = {0};
    ko.filter = lookup_accepts;
    ko.filter_user = &l;
    ko.flags = PM_SORT;
    int n2 = pm_kdtree_knn_ex(c->tree, l.yf, SIDE_LOOKUP_CANDIDATES, max_dist2, &ko, nb, NULL);
    for (int t = 0; t < n2; t++) {
        const pm_photon *p = &c->recs[nb[t].index];
        float pn[3];
        pm_normal_decode(p->normal, pn);
        if (side_visible_h(s, y, n, l.hy, v3f(p->pos), v3f(pn), c->hfree[nb[t].index])) {
            pm_rgbe_decode(p->power, e);
            return 1;
        }
    }
    return 0;
}
