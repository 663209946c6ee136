/* irradiance_lookup.c: the normal-checked lookups of precomputed irradiance (irradiance.h);
 * the build is irradiance.c, the record and the structure irradiance_internal.h.
 *
 * LOOKUP. pm_kdtree_nearest_if on the compact tree with a predicate that is a table lookup
 * (the 256 decoded normals), a dot product and, with stored radii, one comparison. The lookup
 * with the caller's rule takes the `tries` nearest that pass that predicate (a sorted k-nearest
 * search into a stack buffer) and asks the caller's rule about them in order. With stored
 * radii the search skips subtrees by their reach (REACH in irradiance.c).
 */
/* The reach test compares a cell's distance with records' distances, both rounded once per
 * operation (GCC in ISO C mode contracts nothing; clang would fuse a * b + c). */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif
#include "irradiance.h"
#include "internal.h"
#include "irradiance_internal.h"
#include "kdtree_internal.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

typedef struct lookup_ctx {
    const pm_irradiance *irr;
    const float *n, *q;
    float cos_min;
} lookup_ctx;

/* THE NORMAL RULE of irradiance.h (and the stored radius). */
static int accept_normal(void *user, const void *record, uint32_t index) {
    const lookup_ctx *c = (const lookup_ctx *)user;
    const pm__irr_rec *p = (const pm__irr_rec *)record;
    const float *pn = c->irr->normals[p->ncode];
    if (pn[0] * c->n[0] + pn[1] * c->n[1] + pn[2] * c->n[2] < c->cos_min) return 0;
    if (c->irr->r2) {
        float d[3] = {p->pos[0] - c->q[0], p->pos[1] - c->q[1], p->pos[2] - c->q[2]};
        if (!(d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < c->irr->r2[index])) return 0;
    }
    return 1;
}

/* ---- the search with reach -------------------------------------------------------------
 * The k nearest records (dist2 < max_dist2) that accept_normal passes, by the same traversal
 * as pm_kdtree_knn_ex on this tree (kdtree_query.c: near side first, then the node's record,
 * then the far side; the module's result set, internal.h, whose bound is the radius), so
 * that the same records are offered to the predicate in the same order, plus one more cut: a
 * subtree is skipped when its cell's distance from x is >= its reach (REACH in irradiance.c), as every
 * record in it would fail the radius rule. The cell distance is the same float lower bound as
 * kdtree_query_internal.h's box_dist2 (offset max(lo - x, x - hi, 0) per axis, squares summed x, y, z),
 * never above a record's own dist2 in accept_normal. */
typedef struct reach_state {
    const pm_irradiance *irr;
    lookup_ctx *c;
    float q[3];
    float r2; /* the result set's bound (lim); NaN = none (every test is !(d2 >= r2)) */
    uint8_t qmask; /* the normal buckets that may hold a normal the rule accepts */
    pm_neighbor *out;
    unsigned k, found;
    uint64_t nodes, evals;
} reach_state;

static float cell_dist2(const float q[3], const float lo[3], const float hi[3]) {
    float o[3];
    for (int b = 0; b < 3; b++) {
        float u = lo[b] - q[b], w = q[b] - hi[b];
        float x = u > w ? u : w;
        o[b] = x > 0 ? x : 0;
    }
    return o[0] * o[0] + o[1] * o[1] + o[2] * o[2];
}

static int reach_push(reach_state *s, float d2, uint32_t idx) {
    return pm__knn_offer(s->out, s->k, &s->found, &s->r2, d2, idx);
}

static float rec_dist2(const reach_state *s, const float *p) {
    float dx = s->q[0] - p[0], dy = s->q[1] - p[1], dz = s->q[2] - p[2];
    return dx * dx + dy * dy + dz * dz;
}

static void reach_consider(reach_state *s, uint64_t i) {
    const pm__irr_rec *r = &s->irr->recs[i];
    float d2 = rec_dist2(s, r->pos);
    s->evals++;
    if (!(d2 >= s->r2) && accept_normal(s->c, r, (uint32_t)i)) reach_push(s, d2, (uint32_t)i);
}

/* A uniform subtree (all records at one position): one distance, records in range order. */
static void reach_uniform(reach_state *s, uint64_t node) {
    const struct pm_kdtree *t = s->irr->tree;
    float d2 = rec_dist2(s, s->irr->recs[node - 1].pos);
    s->evals++;
    if (d2 >= s->r2) return;
    pm__range r[PM_KDTREE_MAX_DEPTH + 1];
    int nr = pm__subtree_ranges(t, node, pm__ilog2(node), r);
    for (int g = 0; g < nr; g++)
        for (uint64_t i = r[g].begin; i < r[g].end; i++) {
            if (d2 >= s->r2) return;
            if (!accept_normal(s->c, &s->irr->recs[i], (uint32_t)i)) continue;
            if (!reach_push(s, d2, (uint32_t)i)) return; /* lost a tie: so do the rest */
        }
}

static void reach_knn(reach_state *s) {
    const struct pm_kdtree *t = s->irr->tree;
    const pm__irr_rec *rec = s->irr->recs;
    const float *reach = s->irr->reach;
    const uint64_t L = t->nleaves;
    struct {
        float lo[3], hi[3], rr;
        uint64_t node;
    } stack[PM_KDTREE_MAX_DEPTH];
    int sp = 0;
    uint64_t node = 1;
    float lo[3], hi[3];
    memcpy(lo, t->lo, sizeof lo);
    memcpy(hi, t->hi, sizeof hi);
    float rd = cell_dist2(s->q, lo, hi);
    const uint8_t *nmask = s->irr->nmask, qm = s->qmask;
    if (rd >= s->r2 || rd >= reach[1] || !(nmask[1] & qm)) return;
    for (;;) {
        while (node < L) {
            s->nodes++;
            unsigned a = rec[node - 1].axis & PM__AXIS_MASK;
            if (a == PM__AXIS_UNIFORM) {
                if (2 * node >= L && pm__cum(t, 2 * node + 2 - L) == pm__cum(t, 2 * node - L))
                    reach_consider(s, node - 1); /* a single record above two empty buckets */
                else
                    reach_uniform(s, node);
                goto pop;
            }
            float split = rec[node - 1].pos[a];
            uint64_t near = 2 * node + (s->q[a] - split >= 0);
            memcpy(stack[sp].lo, lo, sizeof lo);
            memcpy(stack[sp].hi, hi, sizeof hi);
            if (near & 1) stack[sp].hi[a] = split;
            else stack[sp].lo[a] = split;
            float rr = cell_dist2(s->q, stack[sp].lo, stack[sp].hi);
            stack[sp].rr = rr;
            stack[sp].node = near ^ 1;
            sp += !(rr >= s->r2);
            if (near & 1) lo[a] = split;
            else hi[a] = split;
            node = near;
            if (cell_dist2(s->q, lo, hi) >= reach[node] || !(nmask[node] & qm)) goto pop;
        }
        s->nodes++;
        {
            uint64_t j = node - L, b = t->ninternal + pm__cum(t, j);
            uint64_t e = b + t->leaf_q + (j < t->leaf_extra);
            for (uint64_t i = b; i < e; i++) reach_consider(s, i);
        }
    pop:
        for (;;) {
            if (sp == 0) return;
            sp--;
            if (stack[sp].rr >= s->r2) continue;
            node = stack[sp].node;
            reach_consider(s, (node >> 1) - 1); /* the parent's record, in the split plane */
            if (stack[sp].rr >= s->r2 || stack[sp].rr >= reach[node] || !(nmask[node] & qm)) continue;
            memcpy(lo, stack[sp].lo, sizeof lo);
            memcpy(hi, stack[sp].hi, sizeof hi);
            break;
        }
    }
}

/* pm_kdtree_knn_ex (or nearest_if, k = 1) with filter accept_normal, through reach when the
 * build has it. Same return values. */
static int irr_knn(const pm_irradiance *irr, lookup_ctx *c, const float q[3], unsigned k,
                   float max_dist2, unsigned flags, pm_neighbor *out, pm_query_stats *stats) {
    if (!irr->reach) {
        if (k == 1 && !(flags & PM_SORT))
            return pm_kdtree_nearest_if(irr->tree, q, max_dist2, accept_normal, c, out, stats);
        pm_knn_options ko = {0};
        ko.filter = accept_normal;
        ko.filter_user = c;
        ko.flags = flags;
        return pm_kdtree_knn_ex(irr->tree, q, k, max_dist2, &ko, out, stats);
    }
    if (isnan(max_dist2) || !isfinite(q[0]) || !isfinite(q[1]) || !isfinite(q[2]))
        return PM_ENONFINITE;
    if (k == 0 || !(max_dist2 > 0)) return 0;
    reach_state s;
    memset(&s, 0, sizeof s);
    s.irr = irr;
    s.c = c;
    memcpy(s.q, q, sizeof s.q);
    s.r2 = max_dist2 == INFINITY ? NAN : max_dist2;
    s.out = out;
    s.k = k;
    s.qmask = pm__normal_query_mask(c->n, c->cos_min);
    reach_knn(&s);
    if (stats) {
        stats->nodes_visited += s.nodes;
        stats->dist_evals += s.evals;
    }
    if ((flags & PM_SORT) && !pm__knn_is_sorted(k)) {
        if (s.found <= PM__SORT_KEYS_MAX) pm__nb_sort_keys(s.out, s.found);
        else pm__nb_sort(s.out, s.found);
    }
    return (int)s.found;
}

/* The argument checks both lookups share (rgb cleared first): a negative code, 0 when there is
 * nothing to search (no precomputed photon), 1 to search. */
static int lookup_begin(const pm_irradiance *irr, const float x[3], const float n[3],
                        float max_dist2, float cos_min, float rgb[3]) {
    if (rgb) rgb[0] = rgb[1] = rgb[2] = 0.0f;
    if (!irr || !x || !n || !rgb) return PM_EINVAL;
    if (!isfinite(n[0]) || !isfinite(n[1]) || !isfinite(n[2]) || isnan(cos_min))
        return PM_ENONFINITE;
    if (!irr->tree) {
        if (!isfinite(x[0]) || !isfinite(x[1]) || !isfinite(x[2]) || isnan(max_dist2))
            return PM_ENONFINITE;
        return 0;
    }
    return 1;
}

int pm_irradiance_lookup(const pm_irradiance *irr, const float x[3], const float n[3],
                         float max_dist2, float cos_min, float rgb[3], pm_query_stats *stats) {
    pm_neighbor nb;
    int go = lookup_begin(irr, x, n, max_dist2, cos_min, rgb);
    if (go <= 0) return go;
    lookup_ctx c = {irr, n, x, cos_min};
    int rc = irr_knn(irr, &c, x, 1, max_dist2, 0, &nb, stats);
    if (rc <= 0) return rc;
    pm_rgbe_decode(irr->recs[nb.index].rgbe, rgb);
    return 1;
}

int pm_irradiance_lookup_if(const pm_irradiance *irr, const float x[3], const float n[3],
                            float max_dist2, float cos_min, unsigned tries,
                            pm_irradiance_accept_fn accept, void *user, float rgb[3],
                            uint32_t *photon, pm_query_stats *stats) {
    int go = lookup_begin(irr, x, n, max_dist2, cos_min, rgb);
    if (go < 0) return go;
    if (!irr->photon || tries == 0 || tries > PM_IRRADIANCE_MAX_TRIES) return PM_EINVAL;
    if (go == 0) return 0;
    /* The `tries` nearest that pass the normal rule, sorted, then the caller's rule in order. */
    lookup_ctx c = {irr, n, x, cos_min};
    pm_neighbor nb[PM_IRRADIANCE_MAX_TRIES];
    int found = irr_knn(irr, &c, x, tries, max_dist2, PM_SORT, nb, stats);
    if (found < 0) return found;
    for (int t = 0; t < found; t++) {
        const pm__irr_rec *p = &irr->recs[nb[t].index];
        uint32_t i = irr->photon[nb[t].index];
        if (accept && !accept(user, i, p->pos, irr->normals[p->ncode])) continue;
        pm_rgbe_decode(p->rgbe, rgb);
        if (photon) *photon = i;
        return 1;
    }
    return 0;
}
