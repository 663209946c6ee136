/* bvh.c: binned-SAH build and stack-based traversal; see bvh.h.
 *
 * The build keeps per-primitive bounds and centroids in scratch arrays and partitions the id
 * array in place. Traversal tests both children's boxes, descends into the nearer one that is
 * hit and stacks the other with its entry distance, dropping it later if a closer hit was found.
 */
#include "scene/bvh.h"

#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "base/stats.h"

#define NBINS 16
#define MAX_DEPTH 96
#define STACK_SIZE (MAX_DEPTH + 8)

typedef struct {
    vec3 *lo, *hi, *cen;
    uint32_t *ids;
    bvh_node *nodes;
    int nnodes, cap, depth;
} builder;

static double area_of(vec3 lo, vec3 hi) {
    vec3 d = v3_sub(hi, lo);
    if (d.x < 0 || d.y < 0 || d.z < 0) return 0;
    return 2.0 * (d.x * d.y + d.y * d.z + d.z * d.x);
}

static int new_node(builder *bd) {
    if (bd->nnodes == bd->cap) {
        int nc = bd->cap ? 2 * bd->cap : 256;
        bvh_node *nn = realloc(bd->nodes, (size_t)nc * sizeof *nn);
        if (!nn) return -1;
        bd->nodes = nn;
        bd->cap = nc;
    }
    return bd->nnodes++;
}

static int build_rec(builder *bd, int first, int count, int depth) {
    int ni = new_node(bd);
    if (ni < 0) return PM_ENOMEM;
    if (depth > bd->depth) bd->depth = depth;
    vec3 lo = v3s(INFINITY), hi = v3s(-INFINITY), clo = v3s(INFINITY), chi = v3s(-INFINITY);
    for (int i = first; i < first + count; i++) {
        uint32_t id = bd->ids[i];
        lo = v3_min(lo, bd->lo[id]);
        hi = v3_max(hi, bd->hi[id]);
        clo = v3_min(clo, bd->cen[id]);
        chi = v3_max(chi, bd->cen[id]);
    }
    bvh_node *n = &bd->nodes[ni];
    n->lo[0] = lo.x, n->lo[1] = lo.y, n->lo[2] = lo.z;
    n->hi[0] = hi.x, n->hi[1] = hi.y, n->hi[2] = hi.z;
    n->first = (uint32_t)first;
    n->count = (uint16_t)count;
    n->axis = 0;

    int best_axis = -1, best_bin = -1;
    double best_cost = INFINITY;
    double leaf_cost = (double)count; /* relative to the SAH with traversal cost 1/8 */
    if (count > 2 && depth < MAX_DEPTH) {
        for (int ax = 0; ax < 3; ax++) {
            double cmin = v3_idx(clo, ax), cmax = v3_idx(chi, ax);
            if (!(cmax > cmin)) continue;
            int bcnt[NBINS] = {0};
            vec3 blo[NBINS], bhi[NBINS];
            for (int k = 0; k < NBINS; k++) blo[k] = v3s(INFINITY), bhi[k] = v3s(-INFINITY);
            double scale = NBINS / (cmax - cmin);
            for (int i = first; i < first + count; i++) {
                uint32_t id = bd->ids[i];
                int k = (int)((v3_idx(bd->cen[id], ax) - cmin) * scale);
                if (k >= NBINS) k = NBINS - 1;
                if (k < 0) k = 0;
                bcnt[k]++;
                blo[k] = v3_min(blo[k], bd->lo[id]);
                bhi[k] = v3_max(bhi[k], bd->hi[id]);
            }
            /* Sweep from the right to get the right-side areas, then from the left. */
            double rarea[NBINS];
            int rcnt[NBINS];
            vec3 rlo = v3s(INFINITY), rhi = v3s(-INFINITY);
            int rc = 0;
            for (int k = NBINS - 1; k > 0; k--) {
                rlo = v3_min(rlo, blo[k]);
                rhi = v3_max(rhi, bhi[k]);
                rc += bcnt[k];
                rarea[k] = area_of(rlo, rhi);
                rcnt[k] = rc;
            }
            vec3 llo = v3s(INFINITY), lhi = v3s(-INFINITY);
            int lc = 0;
            for (int k = 0; k < NBINS - 1; k++) {
                llo = v3_min(llo, blo[k]);
                lhi = v3_max(lhi, bhi[k]);
                lc += bcnt[k];
                if (lc == 0 || rcnt[k + 1] == 0) continue;
                double cost = area_of(llo, lhi) * lc + rarea[k + 1] * rcnt[k + 1];
                if (cost < best_cost) {
                    best_cost = cost;
                    best_axis = ax;
                    best_bin = k;
                }
            }
        }
        double a = area_of(lo, hi);
        if (a > 0) best_cost = 0.125 + best_cost / a;
    }
    if (best_axis < 0 || best_cost >= leaf_cost || count > 65535) {
        if (count <= 65535 && (best_axis < 0 || best_cost >= leaf_cost)) return 0;
        /* Too many for one leaf (it can only hold 65535): split at the median index. */
        if (best_axis < 0) best_axis = 0, best_bin = -1;
    }
    double cmin = v3_idx(clo, best_axis), cmax = v3_idx(chi, best_axis);
    int mid;
    if (best_bin >= 0) {
        double scale = NBINS / (cmax - cmin);
        int i = first, j = first + count - 1;
        while (i <= j) {
            uint32_t id = bd->ids[i];
            int k = (int)((v3_idx(bd->cen[id], best_axis) - cmin) * scale);
            if (k >= NBINS) k = NBINS - 1;
            if (k <= best_bin) {
                i++;
            } else {
                bd->ids[i] = bd->ids[j];
                bd->ids[j--] = id;
            }
        }
        mid = i;
    } else {
        mid = first + count / 2;
    }
    if (mid == first || mid == first + count) mid = first + count / 2;
    int rc = build_rec(bd, first, mid - first, depth + 1);
    if (rc < 0) return rc;
    int right = bd->nnodes;
    rc = build_rec(bd, mid, first + count - mid, depth + 1);
    if (rc < 0) return rc;
    n = &bd->nodes[ni]; /* the array may have moved */
    n->first = (uint32_t)right;
    n->count = 0;
    n->axis = (uint16_t)best_axis;
    return 0;
}

int bvh_build(bvh *b, const triangle *tris, int ntris, const sphere *spheres, int nspheres) {
    memset(b, 0, sizeof *b);
    int n = ntris + nspheres;
    if (n <= 0) return PM_EEMPTY;
    builder bd = {0};
    bd.lo = malloc((size_t)n * sizeof(vec3));
    bd.hi = malloc((size_t)n * sizeof(vec3));
    bd.cen = malloc((size_t)n * sizeof(vec3));
    bd.ids = malloc((size_t)n * sizeof(uint32_t));
    int rc = PM_ENOMEM;
    if (bd.lo && bd.hi && bd.cen && bd.ids) {
        for (int i = 0; i < n; i++) {
            if (i < ntris)
                triangle_bounds(&tris[i], &bd.lo[i], &bd.hi[i]);
            else
                sphere_bounds(&spheres[i - ntris], &bd.lo[i], &bd.hi[i]);
            bd.cen[i] = v3_scale(v3_add(bd.lo[i], bd.hi[i]), 0.5);
            bd.ids[i] = (uint32_t)i;
        }
        rc = build_rec(&bd, 0, n, 0);
    }
    free(bd.lo);
    free(bd.hi);
    free(bd.cen);
    if (rc < 0) {
        free(bd.ids);
        free(bd.nodes);
        return rc;
    }
    b->nodes = bd.nodes;
    b->nnodes = bd.nnodes;
    b->prim_ids = bd.ids;
    b->nprims = n;
    b->depth = bd.depth;
    b->tris = tris;
    b->spheres = spheres;
    b->ntris = ntris;
    b->nspheres = nspheres;
    return 0;
}

void bvh_free(bvh *b) {
    free(b->nodes);
    free(b->prim_ids);
    memset(b, 0, sizeof *b);
}

/* Slab test; returns the entry distance or INFINITY on a miss. The comparisons are written
 * so that a NaN (0 * inf, when the origin lies on a slab plane of an axis the ray is parallel
 * to) leaves the interval unchanged; they compile to minsd/maxsd, where fmin/fmax would be
 * library calls (they were 30% of the render time). */
static inline double slab(const bvh_node *n, const double o[3], const double inv[3], double tmin,
                          double tmax) {
    for (int a = 0; a < 3; a++) {
        double t0 = (n->lo[a] - o[a]) * inv[a], t1 = (n->hi[a] - o[a]) * inv[a];
        double tn = t0 < t1 ? t0 : t1, tf = t0 < t1 ? t1 : t0;
        tmin = tn > tmin ? tn : tmin;
        tmax = tf < tmax ? tf : tmax;
    }
    /* Pad by a few ulps so a primitive lying in a flat box's face is not culled. */
    return tmin <= tmax * (1 + 4e-16) ? tmin : INFINITY;
}

static int traverse(const bvh *b, ray r, double tmin, double tmax, int any, double *t, int *prim,
                    double *u, double *v) {
    double o[3] = {r.o.x, r.o.y, r.o.z};
    double inv[3] = {1.0 / r.d.x, 1.0 / r.d.y, 1.0 / r.d.z};
    /* The stack holds nodes whose boxes were hit, with their entry distances, so a node that
     * became farther than the current hit is dropped when popped without a second slab test. */
    uint32_t stack[STACK_SIZE];
    double stack_t[STACK_SIZE];
    int sp = 0, found = 0;
    uint64_t nodes = 0, ntri = 0, nsph = 0;
    double best = tmax;
    if (slab(&b->nodes[0], o, inv, tmin, best) == INFINITY) goto done;
    uint32_t ni = 0;
    for (;;) {
        const bvh_node *n = &b->nodes[ni];
        nodes++;
        if (n->count) {
            for (uint32_t i = n->first; i < n->first + n->count; i++) {
                uint32_t id = b->prim_ids[i];
                double tt, uu = 0, vv = 0;
                int h;
                if (id < (uint32_t)b->ntris) {
                    ntri++;
                    h = triangle_intersect(&b->tris[id], r, tmin, best, &tt, &uu, &vv);
                } else {
                    nsph++;
                    h = sphere_intersect(&b->spheres[id - (uint32_t)b->ntris], r, tmin, best, &tt);
                }
                if (h) {
                    found = 1;
                    best = tt;
                    if (prim) *prim = (int)id;
                    if (u) *u = uu;
                    if (v) *v = vv;
                    if (any) goto done;
                }
            }
        } else {
            /* Test both children; go to the nearer one that is hit, keep the other. */
            uint32_t c0 = ni + 1, c1 = n->first;
            double t0 = slab(&b->nodes[c0], o, inv, tmin, best);
            double t1 = slab(&b->nodes[c1], o, inv, tmin, best);
            if (t0 != INFINITY || t1 != INFINITY) {
                if (t1 < t0) {
                    uint32_t tc = c0;
                    double tt = t0;
                    c0 = c1, t0 = t1, c1 = tc, t1 = tt;
                }
                if (t1 != INFINITY) {
                    stack[sp] = c1;
                    stack_t[sp++] = t1;
                }
                ni = c0;
                continue;
            }
        }
        for (;;) {
            if (sp == 0) goto done;
            sp--;
            if (stack_t[sp] <= best) break;
        }
        ni = stack[sp];
    }
done:
    stat_add(STAT_BVH_NODES, nodes);
    stat_add(STAT_TRI_TESTS, ntri);
    stat_add(STAT_SPHERE_TESTS, nsph);
    if (found && t) *t = best;
    return found;
}

int bvh_intersect(const bvh *b, ray r, double tmin, double tmax, double *t, int *prim, double *u,
                  double *v) {
    if (!b->nnodes) return 0;
    return traverse(b, r, tmin, tmax, 0, t, prim, u, v);
}

int bvh_occluded(const bvh *b, ray r, double tmin, double tmax) {
    if (!b->nnodes) return 0;
    return traverse(b, r, tmin, tmax, 1, NULL, NULL, NULL, NULL);
}

static int box_overlaps(const double alo[3], const double ahi[3], const double blo[3], const double bhi[3]) {
    for (int a = 0; a < 3; a++)
        if (!(alo[a] <= bhi[a] && blo[a] <= ahi[a])) return 0;
    return 1;
}

static void prim_bounds(const bvh *b, uint32_t id, double lo[3], double hi[3]) {
    if (id < (uint32_t)b->ntris) {
        const triangle *t = &b->tris[id];
        vec3 p[3] = {t->v0, v3_add(t->v0, t->e1), v3_add(t->v0, t->e2)};
        for (int a = 0; a < 3; a++) {
            double c0 = v3_idx(p[0], a), c1 = v3_idx(p[1], a), c2 = v3_idx(p[2], a);
            lo[a] = c0 < c1 ? (c0 < c2 ? c0 : c2) : (c1 < c2 ? c1 : c2);
            hi[a] = c0 > c1 ? (c0 > c2 ? c0 : c2) : (c1 > c2 ? c1 : c2);
        }
        return;
    }
    const sphere *sp = &b->spheres[id - (uint32_t)b->ntris];
    for (int a = 0; a < 3; a++) {
        lo[a] = v3_idx(sp->c, a) - sp->r;
        hi[a] = v3_idx(sp->c, a) + sp->r;
    }
}

int bvh_overlap(const bvh *b, const double lo[3], const double hi[3], uint32_t *out, int cap) {
    if (!b->nnodes) return 0;
    uint32_t stack[STACK_SIZE];
    int sp = 0, n = 0;
    stack[sp++] = 0;
    while (sp) {
        const bvh_node *nd = &b->nodes[stack[--sp]];
        if (!box_overlaps(nd->lo, nd->hi, lo, hi)) continue;
        if (!nd->count) {
            if (sp + 2 > STACK_SIZE) return cap + 1; /* deeper than any built tree: give up */
            stack[sp++] = nd->first;
            stack[sp++] = (uint32_t)(nd - b->nodes) + 1;
            continue;
        }
        for (uint32_t i = nd->first; i < nd->first + nd->count; i++) {
            double plo[3], phi[3];
            prim_bounds(b, b->prim_ids[i], plo, phi);
            if (!box_overlaps(plo, phi, lo, hi)) continue;
            if (n == cap) return cap + 1;
            out[n++] = b->prim_ids[i];
        }
    }
    return n;
}
