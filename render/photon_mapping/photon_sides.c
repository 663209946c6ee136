/* photon_sides.c: visibility-checked precomputed irradiance and lookups; see photon_sides.h.
 *
 * The build runs one estimate per chosen photon on OpenMP threads (each with its own neighbour
 * buffer), writes the results by the photon's rank among the chosen ones (so the cache is the
 * same for any thread count), then builds a kd-tree over the chosen photons alone.
 */
#include "photon_mapping/photon_sides.h"

#include <float.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "photonmap/estimate.h"

#ifdef _OPENMP
#include <omp.h>
#endif

/* Directions of the visible-area probe of an estimate with a hidden neighbour. */
#define SIDE_AREA_DIRS 32
/* Candidates a lookup tests for visibility, nearest first. */
#define SIDE_LOOKUP_CANDIDATES 8u
/* An estimate's neighbour within this fraction of its distance of the query's tangent plane
 * lies on the query's own surface (side_estimate: no ray). */
#define SIDE_PLANE_TOL 1e-3
/* A lookup's plane rule (photon_sides.h, side_cache_lookup): a candidate on a curved surface
 * higher above or below y's tangent plane than this fraction of its distance is on another
 * surface (one on a flat surface: SIDE_PLANE_SLAB of it). */
#define SIDE_LOOKUP_SLOPE 0.1

static vec3 v3f(const float f[3]) { return v3(f[0], f[1], f[2]); }

int side_estimate_readable(unsigned paths) { return paths >= SIDE_MIN_PATHS; }

unsigned side_count_paths(const uint32_t *path, const pm_neighbor *nb, int count, unsigned cap, uint32_t *scratch) {
    /* Without paths every photon counts as its own path (photon_sides.h). */
    if (!path) return (unsigned)count < cap ? (unsigned)count : cap;
    /* Distinct ids by a linear scan of those seen so far: at most cap of them are kept, so an
     * estimate costs count x cap compares, and the first photons (mostly of distinct paths
     * wherever the map is dense) usually end it early. */
    unsigned m = 0;
    for (int j = 0; j < count && m < cap; j++) {
        uint32_t id = path[nb[j].index];
        unsigned q = 0;
        while (q < m && scratch[q] != id) q++;
        if (q == m) scratch[m++] = id;
    }
    return m;
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
    double scale = s->offset_floor + v3_maxabs(p);
    hit h;
    int flat;
    vec3 base, ng = side_surface_normal(s, p, n, &base, &flat);
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
 * scaled by k / (k - 0.5) as pm_estimate's PM_BIAS_AREA does; with rim = 0 the area is used as
 * it is. skip: the map photon the disc is centred on when the whole disc of the cap was
 * searched, left out of the sum ("Fixed-radius estimates" in photon_sides.h); UINT32_MAX: none.
 * area_fraction: the part of the disc on this side of every wall (1 without walls). Direct
 * photons count in the radius but not in the sum: the value is the indirect irradiance (see
 * "Direct light" in photon_sides.h). */
static void disc_irradiance(const pm_photon *ph, const pm_neighbor *nb, int count, double r2,
                            int rim, double area_fraction, uint32_t skip, float e[3]) {
    double sum[3] = {0, 0, 0};
    for (int j = 0; j < count; j++) {
        float pw[3];
        if (pm_photon_kind(&ph[nb[j].index]) == PM_KIND_DIRECT || nb[j].index == skip) continue;
        pm_rgbe_decode(ph[nb[j].index].power, pw);
        for (int c = 0; c < 3; c++) sum[c] += pw[c];
    }
    double area = M_PI * r2 * area_fraction;
    if (rim && count > 1) area *= (double)count / (count - 0.5);
    for (int c = 0; c < 3; c++) e[c] = area > 0 && isfinite(area) ? (float)(sum[c] / area) : 0.0f;
}

/* The estimates at the map photons which[0..m) (map indices), into c->val and c->r2v by map
 * index; the build's counters add up in c. Each estimate depends on the map alone, so an
 * estimate is the same whichever call, thread or order computes it. 0 or PM_ENOMEM. */
static int precompute_at(side_cache *c, const scene *s, const pm_kdtree *global, const pm_photon *ph,
                         const uint32_t *path, const uint32_t *which, size_t m, unsigned k, float max_dist2) {
    const float *hfree = c->hfree;
    float *val = c->val, *r2v = c->r2v;
    unsigned long long rays1 = 0, rays2 = 0;
    size_t again = 0, corners = 0, sparse = 0;
    int fail = 0;
#ifdef _OPENMP
#pragma omp parallel reduction(+ : rays1, rays2, again, corners, sparse) reduction(| : fail)
#endif
    {
        /* SIDE_WIDEN x k candidates for the estimates that meet a wall. */
        pm_neighbor *nb = malloc((size_t)SIDE_WIDEN * k * sizeof *nb);
        uint32_t *ids = malloc(SIDE_MIN_PATHS * sizeof *ids); /* side_count_paths's scratch */
        unsigned long long rays[2] = {0, 0};
        if (!nb || !ids) fail = 1;
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 64)
#endif
        for (size_t j = 0; j < m; j++) {
            if (!nb || !ids) continue;
            const pm_photon *p = &ph[which[j]];
            float nf[3];
            pm_normal_decode(p->normal, nf);
            vec3 pp = v3f(p->pos), pn = v3f(nf);
            double hp = hfree[which[j]];
            vec3 at;
            int flat;
            side_surface_normal(s, pp, pn, &at, &flat);
            c->flat[which[j]] = (uint8_t)flat;
            int wall;
            float reach2;
            int found = side_precomp_neighbours(s, global, ph, hfree, p->pos, nf, hp, k, max_dist2, nb, &wall,
                                                &reach2, rays);
            /* The disc up to the k-th kept on its rim, or, short of k, the disc examined. A wall
             * cuts the disc, where no photon of this side can be: divide by the part of the disc
             * on this side only (a wall leaves this side's photons at their density over a
             * smaller area). Rays per estimate: at most SIDE_WIDEN x k + SIDE_AREA_DIRS + 1. */
            int rim = (unsigned)found == k;
            double r2 = rim ? nb[found - 1].dist2 : (double)reach2, frac = 1.0;
            if (wall) {
                again += (wall & SIDE_WALL) != 0;
                corners += (wall & SIDE_CORNER) != 0;
                frac = visible_disc_fraction(s, pp, pn, sqrt(r2));
                rays[1] += SIDE_AREA_DIRS + 1;
                if (frac < 1.0 / SIDE_AREA_DIRS) frac = 1.0 / SIDE_AREA_DIRS;
            }
            float e[3];
            /* Fewer than k in the whole disc of the cap: a fixed-radius estimate, its centre
             * left out and read whatever its paths ("Fixed-radius estimates" in
             * photon_sides.h). Short of k after a wall, the disc ends at the last candidate
             * examined, which the photons set: the paths rule holds there. */
            int whole = !rim && reach2 >= max_dist2;
            disc_irradiance(ph, nb, found, r2, rim, frac, whole ? which[j] : UINT32_MAX, e);
            int readable = whole || side_estimate_readable(side_count_paths(path, nb, found, SIDE_MIN_PATHS, ids));
            r2v[which[j]] = readable ? (float)r2 : 0.0f;
            sparse += !readable;
            memcpy(&val[3 * (size_t)which[j]], e, sizeof e);
        }
        free(nb);
        free(ids);
        rays1 += rays[0];
        rays2 += rays[1];
    }
    if (fail) return PM_ENOMEM;
    c->n += m;
    c->rays_first += rays1;
    c->rays_second += rays2;
    c->researched += again;
    c->corners += corners;
    c->sparse += sparse;
    return 0;
}

/* The map photons of height in [lo, hi) (hi 0: no bound) in global, by map index, into which
 * (room for n); their count. */
static size_t photons_of_height(const pm_kdtree *global, size_t n, int lo, int hi, uint32_t *which) {
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        int h = pm_kdtree_height(global, (uint32_t)i);
        if (h >= lo && (hi <= 0 || h < hi)) which[m++] = (uint32_t)i;
    }
    return m;
}

/* The lookup structure over the values computed at the photons of height >= c->height. At
 * height SIDE_HEIGHT_QUARTER the module's own choice over the map's tree (the values, radii
 * and lookup of the quarter, as always); above it, a tree over copies of the chosen photons
 * alone (a lookup never walks the photons left out), with the free heights and flat flags the
 * lookup's rule reads copied into that tree's order. */
static int cache_finish(side_cache *c, const pm_kdtree *global, const pm_photon *ph, size_t n, unsigned k) {
    pm_irradiance_options io;
    pm_irradiance_options_init(&io, k);
    io.store_radius = 1;
    io.store_index = 1;
    if (c->height <= SIDE_HEIGHT_QUARTER) {
        c->look_hfree = c->hfree;
        c->look_flat = c->flat;
        io.fraction = PM_PRECOMP_QUARTER;
        return c->n ? pm_irradiance_build_values(&c->irr, global, &io, c->val, c->r2v) : 0;
    }
    size_t m = c->n;
    if (!m) return 0;
    uint32_t *which = malloc(n * sizeof *which), *perm = malloc(m * sizeof *perm);
    pm_photon *recs = malloc(m * sizeof *recs);
    float *val = malloc(3 * m * sizeof *val), *r2 = malloc(m * sizeof *r2);
    c->own_hfree = malloc(m * sizeof *c->own_hfree);
    c->own_flat = malloc(m);
    pm_kdtree *t = NULL;
    int rc = PM_ENOMEM;
    if (!which || !perm || !recs || !val || !r2 || !c->own_hfree || !c->own_flat) goto done;
    photons_of_height(global, n, c->height, 0, which);
    for (size_t j = 0; j < m; j++) recs[j] = ph[which[j]];
    pm_kdtree_config kc = pm_kdtree_photon_config(8);
    if ((rc = pm_kdtree_build(&t, recs, m, &kc, perm)) < 0) goto done;
    for (size_t i = 0; i < m; i++) { /* tree order: record i was which[perm[i]] */
        uint32_t q = which[perm[i]];
        memcpy(&val[3 * i], &c->val[3 * (size_t)q], 3 * sizeof *val);
        r2[i] = c->r2v[q];
        c->own_hfree[i] = c->hfree[q];
        c->own_flat[i] = c->flat[q];
    }
    io.fraction = PM_PRECOMP_ALL;
    rc = pm_irradiance_build_values(&c->irr, t, &io, val, r2);
    c->look_hfree = c->own_hfree;
    c->look_flat = c->own_flat;
done:
    pm_kdtree_free(t);
    free(which);
    free(perm);
    free(recs);
    free(val);
    free(r2);
    return rc;
}

/* A build or refine that failed: nothing half made is left (the cache is emptied). */
static int cache_fail(side_cache *c, uint32_t *which, int rc, char *err, size_t errcap) {
    free(which);
    side_cache_free(c);
    snprintf(err, errcap, "precomputing irradiance: %s", pm_strerror(rc));
    return rc;
}

int side_cache_build_at(side_cache *c, const scene *s, const pm_kdtree *global, const pm_photon *ph,
                        const uint32_t *path, size_t n, unsigned k, float max_dist2, int height, char *err,
                        size_t errcap) {
    memset(c, 0, sizeof *c);
    if (!global || n == 0) return 0;
    c->height = height < SIDE_HEIGHT_QUARTER ? SIDE_HEIGHT_QUARTER : height;
    int rc = PM_ENOMEM;
    uint32_t *which = malloc(n * sizeof *which);
    /* The estimates by map index (read only at the chosen photons), kept for
     * side_cache_refine; every photon's free height along its normal, up to the largest lift
     * an estimate can use (a quarter of the search radius): one ray per photon, so that each
     * visibility test below, and each lookup's, is a single ray. */
    c->val = malloc(n * 3 * sizeof *c->val);
    c->r2v = malloc(n * sizeof *c->r2v);
    c->hfree = malloc(n * sizeof *c->hfree);
    c->flat = calloc(n, 1);
    if (!which || !c->val || !c->r2v || !c->hfree || !c->flat) goto fail;
    side_free_heights(s, ph, n, max_dist2, c->hfree);
    c->rays_first = n;
    c->quarter = photons_of_height(global, n, SIDE_HEIGHT_QUARTER, 0, which);
    size_t m = c->height == SIDE_HEIGHT_QUARTER ? c->quarter : photons_of_height(global, n, c->height, 0, which);
    c->indirect_only = 1;
    if ((rc = precompute_at(c, s, global, ph, path, which, m, k, max_dist2)) < 0) goto fail;
    if ((rc = cache_finish(c, global, ph, n, k)) < 0) goto fail;
    free(which);
    return 0;
fail:
    return cache_fail(c, which, rc, err, errcap);
}

int side_cache_build(side_cache *c, const scene *s, const pm_kdtree *global, const pm_photon *ph,
                     const uint32_t *path, size_t n, unsigned k, float max_dist2, char *err, size_t errcap) {
    return side_cache_build_at(c, s, global, ph, path, n, k, max_dist2, SIDE_HEIGHT_QUARTER, err, errcap);
}

int side_cache_refine(side_cache *c, const scene *s, const pm_kdtree *global, const pm_photon *ph,
                      const uint32_t *path, size_t n, unsigned k, float max_dist2, int height, char *err,
                      size_t errcap) {
    if (height < SIDE_HEIGHT_QUARTER) height = SIDE_HEIGHT_QUARTER;
    if (!c->val || !global || n == 0 || height >= c->height) return 0;
    int rc = PM_ENOMEM;
    uint32_t *which = malloc(n * sizeof *which);
    if (!which) goto fail;
    size_t m = photons_of_height(global, n, height, c->height, which);
    if ((rc = precompute_at(c, s, global, ph, path, which, m, k, max_dist2)) < 0) goto fail;
    free(which);
    which = NULL;
    pm_irradiance_free(c->irr);
    free(c->own_hfree);
    free(c->own_flat);
    c->irr = NULL;
    c->own_hfree = NULL;
    c->own_flat = NULL;
    c->height = height;
    if ((rc = cache_finish(c, global, ph, n, k)) < 0) goto fail;
    return 0;
fail:
    return cache_fail(c, which, rc, err, errcap);
}

int side_cache_from_records(side_cache *c, pm_photon *recs, const float *r2, const float *hfree,
                            size_t m, char *err, size_t errcap) {
    memset(c, 0, sizeof *c);
    if (m == 0) return 0;
    pm_kdtree *t = NULL;
    uint32_t *perm = malloc(m * sizeof *perm);
    float *val = malloc(3 * m * sizeof *val), *r2t = malloc(m * sizeof *r2t);
    c->hfree = malloc(m * sizeof *c->hfree);
    int rc = PM_ENOMEM;
    if (!perm || !val || !r2t || !c->hfree) goto done;
    pm_kdtree_config kc = pm_kdtree_photon_config(8);
    if ((rc = pm_kdtree_build(&t, recs, m, &kc, perm)) < 0) goto done;
    for (size_t i = 0; i < m; i++) { /* tree order: record i was recs' perm[i] */
        pm_rgbe_decode(recs[i].power, &val[3 * i]);
        r2t[i] = r2[perm[i]];
        c->hfree[i] = hfree[perm[i]];
    }
    pm_irradiance_options io;
    pm_irradiance_options_init(&io, 1);
    io.fraction = PM_PRECOMP_ALL;
    io.store_radius = 1;
    io.store_index = 1;
    rc = pm_irradiance_build_values(&c->irr, t, &io, val, r2t);
    c->n = m;
    c->look_hfree = c->hfree;
done:
    pm_kdtree_free(t);
    free(perm);
    free(val);
    free(r2t);
    if (rc < 0) {
        side_cache_free(c);
        snprintf(err, errcap, "precomputed irradiance: %s", pm_strerror(rc));
    }
    return rc < 0 ? rc : 0;
}

void side_cache_free(side_cache *c) {
    pm_irradiance_free(c->irr);
    free(c->hfree);
    free(c->flat);
    free(c->val);
    free(c->r2v);
    free(c->own_hfree);
    free(c->own_flat);
    memset(c, 0, sizeof *c);
}

/* The query's side of every wall, as pm_irradiance_lookup_if's rule: a photon answers only if
 * the lifted segment from y reaches it (its free height from the build). The position of the
 * last photon accepted (the answer: the search stops there) goes to pos. */
typedef struct side_rule {
    const side_cache *c;
    const scene *s;
    vec3 y, n;
    double hy; /* y's free height */
    float pos[3];
    int asked; /* the rule was asked about a candidate */
} side_rule;

static int side_accepts(void *user, uint32_t photon, const float pos[3], const float normal[3]) {
    side_rule *r = user;
    r->asked = 1;
    /* The plane rule's twin (photon_corner.h): a value from another surface nearly parallel
     * to y's (a door beside its wall) lies off y's tangent plane. */
    vec3 d = v3_sub(v3f(pos), r->y);
    double slope = r->c->look_flat && r->c->look_flat[photon] ? SIDE_PLANE_SLAB : SIDE_LOOKUP_SLOPE;
    if (fabs(v3_dot(d, r->n)) > slope * v3_len(d) + 1e-6 * (r->s->offset_floor + v3_maxabs(r->y))) return 0;
    int ok = side_visible_h(r->s, r->y, r->n, r->hy, v3f(pos), v3f(normal), r->c->look_hfree[photon]);
    if (ok) memcpy(r->pos, pos, sizeof r->pos);
    return ok;
}

int side_cache_lookup_local(const side_cache *c, const scene *s, vec3 y, vec3 n, double hy,
                            float max_dist2, float e[3], float pos[3]) {
    e[0] = e[1] = e[2] = 0;
    if (!c->irr) return 0;
    side_rule r = {c, s, y, n, hy, {0, 0, 0}, 0};
    float yf[3] = {(float)y.x, (float)y.y, (float)y.z}, nf[3] = {(float)n.x, (float)n.y, (float)n.z};
    /* The nearest candidate first: it is the answer at almost every lookup, and a search for
     * one record prunes far more of the tree than a search for SIDE_LOOKUP_CANDIDATES (the
     * lookups were 60% of cornell_box's render phase; docs/PROFILE.md). Only when the rule
     * turns it down are the SIDE_LOOKUP_CANDIDATES nearest searched, in order (the first of
     * them is that one again: one visibility ray spent twice); with no candidate at all
     * within reach there is nothing more to find. A bounded number of shadow rays per lookup,
     * even beside a wall with many photons behind. */
    int found = pm_irradiance_lookup_if(c->irr, yf, nf, max_dist2, SIDE_LOOKUP_COS, 1, side_accepts, &r, e,
                                        NULL, NULL) == 1;
    if (!found && r.asked)
        found = pm_irradiance_lookup_if(c->irr, yf, nf, max_dist2, SIDE_LOOKUP_COS, SIDE_LOOKUP_CANDIDATES,
                                        side_accepts, &r, e, NULL, NULL) == 1;
    if (found && pos) memcpy(pos, r.pos, sizeof r.pos);
    return found;
}

int side_cache_lookup(const side_cache *c, const scene *s, vec3 y, vec3 n, float max_dist2,
                      float e[3]) {
    if (c->remote) return c->remote(c->remote_user, s, y, n, max_dist2, e);
    e[0] = e[1] = e[2] = 0;
    if (!c->irr) return 0;
    return side_cache_lookup_local(c, s, y, n, side_free_height(s, y, n, 0.25 * sqrt((double)max_dist2)),
                                   max_dist2, e, NULL);
}

/* ---- estimates of a map that keep to the query's side --------------------------------------- */

int side_map_init(side_map *sm, const scene *s, const pm_kdtree *t, size_t n, float max_dist2, char *err,
                  size_t errcap) {
    memset(sm, 0, sizeof *sm);
    if (!t || n == 0) return 0;
    sm->hfree = malloc(n * sizeof *sm->hfree);
    if (!sm->hfree) {
        snprintf(err, errcap, "side-keeping estimates: out of memory");
        return PM_ENOMEM;
    }
    sm->s = s;
    sm->t = t;
    sm->n = n;
    side_free_heights(s, pm_kdtree_records(t), n, max_dist2, sm->hfree);
    return 0;
}

void side_map_free(side_map *sm) {
    free(sm->hfree);
    memset(sm, 0, sizeof *sm);
}

/* Both points on one plane (normal n): 1 when nothing stands between them just above it (a ray
 * from x to p lifted by a few times the offset epsilon). */
static int side_open_along(const scene *s, vec3 x, vec3 n, vec3 p) {
    double scale = s->offset_floor + fmax(v3_maxabs(x), v3_maxabs(p));
    vec3 lift = v3_scale(n, 4 * 64e-9 * scale * 16);
    vec3 a = v3_add(x, lift), d = v3_sub(v3_add(p, lift), a);
    double len = v3_len(d);
    if (!(len > 0)) return 1;
    ray r = {a, v3_scale(d, 1 / len)};
    hit h;
    return !scene_intersect(s, r, len, &h);
}

/* 1 if the neighbour at p (normal pn, free height hp) is on the query's side: with no ray when
 * it lies in the query's tangent plane (within SIDE_PLANE_TOL of its distance, and a float
 * step), else side_visible_h. *hx: the query's free height, computed at the first ray (< 0:
 * not yet). */
static int side_keeps(const scene *s, vec3 x, vec3 n, double *hx, double cap, vec3 p, vec3 pn, double hp,
                      int in_plane_rays) {
    vec3 d = v3_sub(p, x);
    double off = fabs(v3_dot(d, n)), len = v3_len(d);
    if (off <= SIDE_PLANE_TOL * len + 1e-6 * (s->offset_floor + v3_maxabs(x)))
        return !in_plane_rays || side_open_along(s, x, n, p);
    if (*hx < 0) *hx = side_free_height(s, x, n, cap);
    return side_visible_h(s, x, n, *hx, p, pn, hp);
}

int side_neighbours(const side_map *sm, const float x[3], const float n[3], const pm_knn_options *ko, unsigned k,
                    float max_dist2, pm_neighbor *nb, int found, float *limit) {
    *limit = max_dist2;
    if (!sm->t || found <= 0) return found < 0 ? 0 : found;
    const scene *s = sm->s;
    const pm_photon *ph = pm_kdtree_records(sm->t);
    vec3 xv = v3f(x), nv = v3f(n);
    double hx = -1, cap = 0.25 * sqrt((double)max_dist2);
    int hidden = 0;
    for (int i = 0; i < found && !hidden; i++) {
        if (nb[i].dist2 == 0) continue;
        const pm_photon *p = &ph[nb[i].index];
        float pn[3];
        pm_normal_decode(p->normal, pn);
        hidden = !side_keeps(s, xv, nv, &hx, cap, v3f(p->pos), v3f(pn), sm->hfree[nb[i].index], sm->in_plane_rays);
    }
    if (!hidden) return found;
    /* A neighbour behind a surface: as side_cache_build, take SIDE_WIDEN x k candidates in order
     * of distance and keep the ones on x's side until k are kept; the area is the disc up to
     * the k-th kept, or, short of k, up to the last candidate examined (a wall that cuts the
     * disc leaves it low there, as at any edge of a lit region; never a leak). */
    unsigned want = (unsigned)SIDE_WIDEN * k;
    pm_neighbor *wide = malloc((size_t)want * sizeof *wide);
    if (!wide) return PM_ENOMEM;
    pm_knn_options kw = *ko;
    kw.flags |= PM_SORT;
    int n2 = pm_kdtree_knn_ex(sm->t, x, want, max_dist2, &kw, wide, NULL);
    if (n2 < 0) n2 = 0;
    unsigned kept = 0;
    for (int i = 0; i < n2 && kept < k; i++) {
        int keep = 1;
        if (wide[i].dist2 > 0) {
            const pm_photon *p = &ph[wide[i].index];
            float pn[3];
            pm_normal_decode(p->normal, pn);
            keep = side_keeps(s, xv, nv, &hx, cap, v3f(p->pos), v3f(pn), sm->hfree[wide[i].index], sm->in_plane_rays);
        }
        if (keep) nb[kept++] = wide[i];
    }
    if (kept < k && (unsigned)n2 == want) *limit = wide[n2 - 1].dist2; /* examined up to there */
    free(wide);
    return (int)kept;
}

int side_estimate(const side_map *sm, const float x[3], const float n[3], const pm_estimate_options *o,
                  void *scratch, pm_estimate_result *res) {
    memset(res, 0, sizeof *res);
    if (!sm->t) {
        res->flags = PM_EST_F_EMPTY;
        return PM_OK;
    }
    float nrm[3];
    pm_knn_options ko;
    pm_estimate_search_options(o, n, nrm, &ko);
    /* The wrapper's layout of scratch (estimate.h): k neighbours, then the core's part. */
    pm_neighbor *nb = scratch;
    void *core = (char *)scratch + (((size_t)o->k * sizeof *nb + 7u) & ~(size_t)7u);
    int found = pm_kdtree_knn_ex(sm->t, x, o->k, o->max_dist2, &ko, nb, NULL);
    if (found < 0) return found;
    pm_estimate_options oo = *o;
    found = side_neighbours(sm, x, n, &ko, o->k, o->max_dist2, nb, found, &oo.max_dist2);
    if (found < 0) return found;
    if (found == 0) {
        res->flags = PM_EST_F_EMPTY;
        return PM_OK;
    }
    return pm_estimate_core(pm_kdtree_records(sm->t), nb, (unsigned)found, x, n, &oo, core, res);
}
