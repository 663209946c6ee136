/* pm_beam.c: beam radiance estimates of the volume photon maps; see pm_beam.h. The photons'
 * radii come from the map's kd-tree, the balls go into a bounding-volume hierarchy (median
 * splits on the longest axis of the centres, PMV_BEAM_LEAF photons per leaf), and a segment's
 * estimate is one traversal of it.
 */
#include "photon_mapping/pm_beam.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "photon_mapping/pm_ball.h"
#include "photonmap/common.h"
#include "scene/medium.h"

/* Photons per leaf of the hierarchy. */
#define PMV_BEAM_LEAF 8u
/* The smallest radius, relative to the search limit (photons on top of each other). */
#define PMV_BEAM_MIN_R 1e-3

void pmv_beam_free(pmv_beam *b) {
    if (!b) return;
    free(b->ph);
    free(b->nodes);
    memset(b, 0, sizeof *b);
}

/* Reorder ph[lo, hi) so that ph[mid] has the mid-th smallest coordinate on axis ax, the ones
 * before it no larger and the ones after no smaller (quickselect). */
static void select_axis(pmv_beam_photon *ph, size_t lo, size_t hi, size_t mid, int ax) {
    while (hi - lo > 1) {
        float pv = ph[lo + (hi - lo) / 2].p[ax];
        size_t i = lo, j = hi - 1;
        for (;;) {
            while (ph[i].p[ax] < pv) i++;
            while (ph[j].p[ax] > pv) j--;
            if (i >= j) break;
            pmv_beam_photon t = ph[i];
            ph[i] = ph[j];
            ph[j] = t;
            i++;
            j--;
        }
        /* [lo, j] <= pv <= [i, hi), what lies between equals pv, and i == j holds pv. */
        if (i == j) {
            if (mid == i) return;
            if (mid < i) hi = i;
            else lo = i + 1;
        } else if (mid <= j) hi = j + 1;
        else if (mid >= i) lo = i;
        else return;
    }
}

/* Build the subtree over ph[lo, hi) at node *next; returns its index. */
static uint32_t build_node(pmv_beam *b, size_t lo, size_t hi, size_t *next) {
    uint32_t id = (uint32_t)(*next)++;
    pmv_beam_node *nd = &b->nodes[id];
    float clo[3], chi[3];
    for (int a = 0; a < 3; a++) {
        nd->lo[a] = clo[a] = INFINITY;
        nd->hi[a] = chi[a] = -INFINITY;
    }
    for (size_t i = lo; i < hi; i++) {
        const pmv_beam_photon *p = &b->ph[i];
        float r = sqrtf(p->r2);
        for (int a = 0; a < 3; a++) {
            nd->lo[a] = fminf(nd->lo[a], p->p[a] - r);
            nd->hi[a] = fmaxf(nd->hi[a], p->p[a] + r);
            clo[a] = fminf(clo[a], p->p[a]);
            chi[a] = fmaxf(chi[a], p->p[a]);
        }
    }
    if (hi - lo <= PMV_BEAM_LEAF) {
        nd->first = (uint32_t)lo;
        nd->count = (uint32_t)(hi - lo);
        return id;
    }
    int ax = 0;
    for (int a = 1; a < 3; a++)
        if (chi[a] - clo[a] > chi[ax] - clo[ax]) ax = a;
    size_t mid = lo + (hi - lo) / 2;
    select_axis(b->ph, lo, hi, mid, ax);
    nd->count = 0;
    build_node(b, lo, mid, next);
    uint32_t right = build_node(b, mid, hi, next);
    b->nodes[id].first = right;
    return id;
}

int pmv_beam_build(pmv_beam *b, const scene *s, const pm_kdtree *t, const pm_photon *a, size_t n, unsigned k,
                   float r2max, int boundary) {
    memset(b, 0, sizeof *b);
    if (n == 0 || !t || k == 0) return 0;
    b->ph = malloc(n * sizeof *b->ph);
    /* A node of more than PMV_BEAM_LEAF photons splits in halves, so every leaf holds more
     * than PMV_BEAM_LEAF / 2: at most 2 n / (PMV_BEAM_LEAF / 2) nodes. */
    size_t maxnodes = 2 * (n / (PMV_BEAM_LEAF / 2) + 1);
    b->nodes = malloc(maxnodes * sizeof *b->nodes);
    if (!b->ph || !b->nodes) {
        pmv_beam_free(b);
        return PM_ENOMEM;
    }
    double rmax = isfinite(r2max) ? sqrt((double)r2max) : INFINITY;
    int fail = 0;
    double rsum = 0;
#pragma omp parallel reduction(+ : rsum) reduction(| : fail)
    {
        pm_neighbor *nb = malloc(k * sizeof *nb);
        if (!nb) fail = 1;
#pragma omp for schedule(dynamic, 256)
        for (long i = 0; i < (long)n; i++) {
            if (!nb) continue;
            const pm_photon *ph = &a[i];
            int found = pm_kdtree_knn(t, ph->pos, k, r2max, nb, 0, NULL);
            double r = rmax;
            if (found >= (int)k) {
                float m = 0;
                for (int j = 0; j < found; j++) m = fmaxf(m, nb[j].dist2);
                r = sqrt((double)m);
            }
            if (!isfinite(r)) r = 1; /* a search without a limit that found fewer than k: cannot happen with the trees' r2 */
            if (isfinite(rmax)) r = fmax(r, PMV_BEAM_MIN_R * rmax);
            vec3 x = v3(ph->pos[0], ph->pos[1], ph->pos[2]);
            double f = boundary ? pmv_ball_fraction(s, x, r) : 1;
            float pw[3], d[3];
            pm_rgbe_decode(ph->power, pw);
            pm_dir_decode(ph->theta, ph->phi, d);
            double inv = 1 / (f * 4.0 / 3.0 * M_PI * r * r * r);
            pmv_beam_photon *q = &b->ph[i];
            for (int c = 0; c < 3; c++) {
                q->p[c] = ph->pos[c];
                q->w[c] = (float)(pw[c] * inv);
                q->d[c] = d[c];
            }
            q->r2 = (float)(r * r);
            rsum += r;
        }
        free(nb);
    }
    if (fail) {
        pmv_beam_free(b);
        return PM_ENOMEM;
    }
    b->n = n;
    b->mean_r = rsum / (double)n;
    size_t next = 0;
    build_node(b, 0, n, &next);
    b->nnodes = next;
    return 0;
}

/* exp(-x) for 0 <= x < PMV_BEAM_SERIES_X by its series to x^4 (relative error below
 * x^5 / 120 < 1e-8), else exp. */
#define PMV_BEAM_SERIES_X 0.04
static inline double exp_neg(double x) {
    if (x < PMV_BEAM_SERIES_X) return 1 - x * (1 - x * (0.5 - x * (1.0 / 6 - x * (1.0 / 24))));
    return exp(-x);
}

/* The integral of exp(-s t) over [a, b] divided by exp(-s t_ref) (t_ref <= a, where the
 * caller knows the transmittance): exp(-s (m - t_ref)) 2 sinh(s h) / s, m the chord's middle
 * and h its half length, with sinh(x) / x by its series where x = s h < 0.1 (the next term,
 * x^6 / 5040, is below 2e-10). Within a leaf of the hierarchy s (m - t_ref) is small, so most
 * photons need no exp. */
static inline double tr_integral(double s, double a, double b, double t_ref) {
    double h = 0.5 * (b - a), x = s * h;
    if (x < 0.1) {
        double x2 = x * x;
        return exp_neg(s * (a + h - t_ref)) * 2 * h * (1 + x2 * (1.0 / 6 + x2 * (1.0 / 120)));
    }
    return (exp_neg(s * (a - t_ref)) - exp_neg(s * (b - t_ref))) / s;
}

/* Where r (inverse direction id) enters a node's box within [0, T] (*t_in); 0 if it misses. */
static int box_hit(const pmv_beam_node *nd, const double o[3], const double id[3], double T, double *t_in) {
    double t0 = 0, t1 = T;
    for (int a = 0; a < 3; a++) {
        double ta = ((double)nd->lo[a] - o[a]) * id[a], tb = ((double)nd->hi[a] - o[a]) * id[a];
        if (ta > tb) {
            double x = ta;
            ta = tb;
            tb = x;
        }
        if (ta > t0) t0 = ta;
        if (tb < t1) t1 = tb;
        if (!(t0 <= t1)) return 0;
    }
    *t_in = t0;
    return 1;
}

rgb pmv_beam_segment(const pmv_beam *b, ray r, double T, rgb sigma_t, double g, uint64_t *nphotons) {
    if (!b || b->n == 0 || !(T > 0)) return v3s(0);
    double o[3] = {r.o.x, r.o.y, r.o.z}, dd[3] = {r.d.x, r.d.y, r.d.z}, id[3];
    for (int a = 0; a < 3; a++) id[a] = dd[a] != 0 ? 1 / dd[a] : (signbit(dd[a]) ? -INFINITY : INFINITY);
    double st[3] = {sigma_t.x, sigma_t.y, sigma_t.z}, acc[3] = {0, 0, 0};
    int iso = fabs(g) <= 1e-3, grey = st[0] == st[1] && st[1] == st[2];
    /* HG: (1 - g^2) / (4 pi) / (1 + g^2 - 2 g cos)^(3/2) */
    double hg_k = iso ? 1 / (4 * M_PI) : (1 - g * g) / (4 * M_PI), hg_a = 1 + g * g, hg_b = 2 * g;
    uint32_t stack[64];
    int sp = 0;
    uint64_t hits = 0;
    stack[sp++] = 0;
    while (sp > 0) {
        const pmv_beam_node *nd = &b->nodes[stack[--sp]];
        double t_in;
        if (!box_hit(nd, o, id, T, &t_in)) continue;
        if (nd->count == 0) {
            uint32_t self = (uint32_t)(nd - b->nodes);
            if (sp + 2 > 64) continue; /* cannot happen: the tree is balanced, depth < 40 */
            stack[sp++] = nd->first;
            stack[sp++] = self + 1;
            continue;
        }
        /* the transmittance where the ray enters the leaf's box; its photons' chords start
         * there or later */
        double tr_in[3];
        for (int c = 0; c < 3; c++) tr_in[c] = grey && c ? tr_in[0] : exp(-st[c] * t_in);
        for (uint32_t i = nd->first; i < nd->first + nd->count; i++) {
            const pmv_beam_photon *p = &b->ph[i];
            double v[3] = {p->p[0] - o[0], p->p[1] - o[1], p->p[2] - o[2]};
            double tc = v[0] * dd[0] + v[1] * dd[1] + v[2] * dd[2];
            double d2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2] - tc * tc;
            if (!(d2 < (double)p->r2)) continue;
            double h = sqrt((double)p->r2 - d2), t0 = fmax(t_in, tc - h), t1 = fmin(T, tc + h);
            if (!(t0 < t1)) continue;
            hits++;
            /* the phase toward the eye: the photon travelled along p->d, the light leaves
             * along -r.d */
            double ph = hg_k;
            if (!iso) {
                double den = hg_a + hg_b * (p->d[0] * dd[0] + p->d[1] * dd[1] + p->d[2] * dd[2]);
                ph = hg_k / (den * sqrt(den));
            }
            if (grey) {
                double w = ph * tr_in[0] * tr_integral(st[0], t0, t1, t_in);
                for (int c = 0; c < 3; c++) acc[c] += w * (double)p->w[c];
            } else
                for (int c = 0; c < 3; c++) acc[c] += ph * tr_in[c] * (double)p->w[c] * tr_integral(st[c], t0, t1, t_in);
        }
    }
    if (nphotons) *nphotons += hits;
    return v3(acc[0], acc[1], acc[2]);
}
