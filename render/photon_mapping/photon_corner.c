/* photon_corner.c: the neighbours of a precomputed irradiance estimate on its own surface (the
 * normal and plane rules); see photon_corner.h.
 *
 * The search runs with a filter that applies the rules and remembers the nearest photon it
 * refused (the corner test). The plane rule needs the radius of the k nearest, which the search
 * finds only at its end, so the first search applies the normal rule alone; only when one of
 * its k nearest lies above the slab of that radius does a second search apply the slab too.
 * An estimate away from every other surface is the first search, bit for bit as before.
 */
#include "photon_mapping/photon_corner.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "photon_mapping/side_visibility.h"
#include "photonmap/common.h"
#include "photonmap/estimate.h"

static vec3 v3f(const float f[3]) { return v3(f[0], f[1], f[2]); }

vec3 side_surface_normal(const scene *s, vec3 p, vec3 n, vec3 *at, int *flat) {
    double delta = 1e-5 * (s->offset_floor + v3_maxabs(p));
    ray down = {v3_madd(p, n, delta), v3_neg(n)};
    hit h;
    *at = p;
    *flat = 0;
    if (!scene_intersect(s, down, 3 * delta, &h)) return n;
    *at = h.p;
    *flat = h.prim < s->accel.ntris && v3_dot(h.ns, h.ng) > 1 - 1e-9;
    return v3_dot(h.ng, n) >= 0 ? h.ng : v3_neg(h.ng);
}

/* The search filter: pm_filter_front, the normal rule (side_filter_shadow) and, with a finite
 * slab, the plane rule; bad2 is the dist2 of the nearest photon refused by a rule. */
typedef struct corner_filter {
    const float *n, *x; /* the query's decoded normal and position */
    vec3 ng;            /* the query's exact normal (the plane rule's) */
    double slab;        /* the largest height above the plane that counts (INFINITY: no rule) */
    float bad2;
} corner_filter;

/* The photon's height above the query's tangent plane. */
static double plane_height(const corner_filter *f, const float pos[3]) {
    return fabs((pos[0] - f->x[0]) * f->ng.x + (pos[1] - f->x[1]) * f->ng.y + (pos[2] - f->x[2]) * f->ng.z);
}

static int corner_accepts(void *user, const void *record, uint32_t index) {
    corner_filter *f = user;
    const pm_photon *p = record;
    if (!pm_filter_front((void *)f->n, record, index)) return 0;
    if (side_filter_shadow((void *)f->n, record, index) && !(plane_height(f, p->pos) > f->slab)) return 1;
    float d[3] = {p->pos[0] - f->x[0], p->pos[1] - f->x[1], p->pos[2] - f->x[2]};
    float d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
    if (d2 < f->bad2) f->bad2 = d2;
    return 0;
}

/* The nearest by the rules: the normal rule, then, on a flat surface, if one of the k nearest
 * lies off the slab of their radius, the plane rule too: a second search within four times that
 * radius, taken if it finds k (else the first search's photons stand: a surface too small to
 * hold k photons near x keeps its estimate as before). Sets *wall to SIDE_CORNER if a photon
 * refused by a rule lies inside the disc of those kept. nb: room for 2k. */
static int nearest_on_surface(const scene *s, const pm_kdtree *t, const pm_photon *ph, unsigned k, float max_dist2,
                              corner_filter *cf, pm_knn_options *ko, pm_neighbor *nb, int *wall) {
    int found = pm_kdtree_knn_ex(t, cf->x, k, max_dist2, ko, nb, NULL);
    if (found < 0) found = 0;
    float bad2 = cf->bad2;
    if (found > 0) {
        vec3 at, xv = v3f(cf->x);
        int flat;
        cf->ng = side_surface_normal(s, xv, v3f(cf->n), &at, &flat);
        float r2 = nb[found - 1].dist2;
        double slab = SIDE_PLANE_SLAB * sqrt((double)r2) + 1e-6 * (s->offset_floor + v3_maxabs(xv));
        int off = 0;
        for (int i = 0; i < found && flat && !off; i++) off = plane_height(cf, ph[nb[i].index].pos) > slab;
        if (off) {
            cf->slab = slab;
            cf->bad2 = INFINITY;
            float reach = 16 * r2 < max_dist2 ? 16 * r2 : max_dist2;
            int again = pm_kdtree_knn_ex(t, cf->x, k, reach, ko, nb + k, NULL);
            if (again == (int)k) {
                memcpy(nb, nb + k, k * sizeof *nb);
                *wall = SIDE_CORNER;
                bad2 = cf->bad2;
            } else {
                cf->slab = INFINITY; /* the wall's search below: as before the rule */
            }
        }
    }
    if (bad2 < ((unsigned)found == k ? nb[found - 1].dist2 : max_dist2)) *wall = SIDE_CORNER;
    return found;
}

int side_precomp_neighbours(const scene *s, const pm_kdtree *t, const pm_photon *ph, const float *hfree,
                            const float x[3], const float n[3], double hx, unsigned k, float max_dist2,
                            pm_neighbor *nb, int *wall, float *reach2, unsigned long long rays[2]) {
    *wall = 0;
    *reach2 = max_dist2;
    if (!t) return 0;
    vec3 xv = v3f(x), nv = v3f(n);
    corner_filter cf = {n, x, nv, INFINITY, INFINITY};
    pm_knn_options ko = {0};
    ko.filter = corner_accepts;
    ko.filter_user = &cf;
    ko.flags = PM_SORT;
    int found = nearest_on_surface(s, t, ph, k, max_dist2, &cf, &ko, nb, wall);
    side_planes pl; /* CLEAR SEGMENTS WITHOUT A RAY (side_visibility.c) */
    pl.ok = 0;
    if (found > 0) side_planes_near(s, xv, nb[found - 1].dist2, &pl);
    int hidden = 0;
    for (int i = 0; i < found && !hidden; i++) {
        if (nb[i].dist2 == 0) continue;
        float nq[3];
        pm_normal_decode(ph[nb[i].index].normal, nq);
        vec3 qv = v3f(ph[nb[i].index].pos), nqv = v3f(nq);
        if (side_clear(&pl, xv, nv, hx, qv, nqv, hfree[nb[i].index])) continue;
        if (rays) rays[0]++;
        hidden = !side_visible_h(s, xv, nv, hx, qv, nqv, hfree[nb[i].index]);
    }
    if (!hidden) return found;
    *wall |= SIDE_WALL;
    /* A wall: SIDE_WIDEN x k candidates in order of distance (by the same rules), the visible
     * ones kept until k are. Every photon closer than the last one tested was tested, so the
     * estimate covers the disc up to it (the k-th kept on its rim, or, short of k, the whole
     * disc searched). */
    unsigned want = (unsigned)SIDE_WIDEN * k;
    int n2 = pm_kdtree_knn_ex(t, x, want, max_dist2, &ko, nb, NULL);
    if (n2 < 0) n2 = 0;
    unsigned kept = 0;
    if (n2 > 0) side_planes_near(s, xv, nb[n2 - 1].dist2, &pl);
    for (int i = 0; i < n2 && kept < k; i++) {
        int vis = 1;
        if (nb[i].dist2 > 0) {
            float nq[3];
            pm_normal_decode(ph[nb[i].index].normal, nq);
            vec3 qv = v3f(ph[nb[i].index].pos), nqv = v3f(nq);
            if (!side_clear(&pl, xv, nv, hx, qv, nqv, hfree[nb[i].index])) {
                if (rays) rays[1]++;
                vis = side_visible_h(s, xv, nv, hx, qv, nqv, hfree[nb[i].index]);
            }
        }
        if (vis) nb[kept++] = nb[i];
    }
    if (kept < k && (unsigned)n2 == want) *reach2 = nb[n2 - 1].dist2; /* examined up to there */
    return (int)kept;
}
