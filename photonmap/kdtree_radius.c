/* kdtree_radius.c: the radius searches on the heap kd-tree (pm_kdtree_radius into an array,
 * pm_kdtree_radius_cb through a callback): every record with dist2 < r2, in the walk of
 * kdtree_query.c's top comment (TRAVERSAL) with a fixed r2. Its siblings: kdtree_query.c
 * (k nearest, nearest_if) and kdtree_query_internal.h (what both share, and the CELL
 * DISTANCE and RADIUS rules the search below follows).
 */
#include <math.h>
#include <string.h>

#include "kdtree_query_internal.h"

/* ---- radius ------------------------------------------------------------------------------ */

typedef struct {
    float q[3];
    float r2; /* NaN = unlimited */
    pm_neighbor *out;
    size_t cap;
    uint64_t total;
    pm_visit_fn fn;
    void *user;
    int stop;
    uint64_t nodes, evals;
    float lo[3], hi[3]; /* the root cell */
} rad_state;

PM__INLINE void rad_take(rad_state *s, uint64_t i, float d2) {
    if (s->fn) {
        s->total++;
        if (s->fn(s->user, (uint32_t)i, d2)) s->stop = 1;
        return;
    }
    if (s->total < s->cap) {
        s->out[s->total].dist2 = d2;
        s->out[s->total].index = (uint32_t)i;
    }
    s->total++;
}

PM__INLINE float rad_dist2(const rad_state *s, const float *p) {
    float dx = s->q[0] - p[0], dy = s->q[1] - p[1], dz = s->q[2] - p[2];
    return dx * dx + dy * dy + dz * dz;
}

PM__INLINE void rad_consider(rad_state *s, const view *v, uint64_t i) {
    float d2 = rad_dist2(s, P(v, i));
    s->evals++;
    if (!(d2 >= s->r2)) rad_take(s, i, d2);
}

static void rad_uniform(rad_state *s, const view *v, uint64_t node) {
    float d2 = rad_dist2(s, P(v, node - 1));
    s->evals++;
    if (d2 >= s->r2) return;
    pm__range r[PM_KDTREE_MAX_DEPTH + 1];
    int nr = pm__subtree_ranges(v->t, node, pm__ilog2(node), r);
    for (int g = 0; g < nr; g++) {
        if (!s->fn && s->total >= s->cap) { /* nothing more to write: just count */
            s->total += r[g].end - r[g].begin;
            continue;
        }
        for (uint64_t i = r[g].begin; i < r[g].end && !s->stop; i++) rad_take(s, i, d2);
        if (s->stop) return;
    }
}

static void rad_iter(rad_state *s, const view *v) {
    struct {
        v4 lo, hi;
        uint32_t node;
        float rf;
    } stack[PM_KDTREE_MAX_DEPTH];
    int sp = 0;
    uint64_t node = 1;
    const uint64_t L = v->L;
    const v4 qv = v4_load3(s->q);
    v4 lo = v4_load3(s->lo), hi = v4_load3(s->hi);
    if (box_dist2(qv, lo, hi) >= s->r2) return; /* the whole tree is out of reach */
    for (;;) {
        while (node < L) {
            unsigned a = AX(v, node);
            s->nodes++;
            if (a == PM__AXIS_UNIFORM) {
                rad_uniform(s, v, node);
                goto pop;
            }
            float split = P(v, node - 1)[a];
            float d = s->q[a] - split;
            uint64_t near = 2 * node + (d >= 0);
            /* r2 is fixed: when the far cell (before the far child's own code) is out of
             * reach, so are the far child and the node's record, which lies in that cell's
             * boundary plane, and the entry is dropped now. */
            v4 flo, fhi;
            float rr, rf;
            split_cell(v, 0, qv, near, a, split, &lo, &hi, &flo, &fhi, &rr, &rf);
            stack[sp].lo = flo, stack[sp].hi = fhi;
            stack[sp].rf = rf;
            stack[sp].node = (uint32_t)(near ^ 1);
            sp += !(rr >= s->r2);
            node = near;
            if (near_code(v, 0, qv, near, &lo, &hi) >= s->r2) goto pop;
        }
        s->nodes++;
        {
            uint64_t b, e;
            bucket_range(v->t, node, &b, &e);
            for (uint64_t i = b; i < e && !s->stop; i++) rad_consider(s, v, i);
        }
    pop:
        for (;;) {
            if (sp == 0 || s->stop) return;
            sp--;
            node = stack[sp].node;
            rad_consider(s, v, (node >> 1) - 1);
            if (s->stop) return;
            if (stack[sp].rf >= s->r2) continue;
            lo = stack[sp].lo, hi = stack[sp].hi;
            break;
        }
    }
}

/* The search, and its counts added to stats (when given). */
PM__INLINE void rad_run(rad_state *s, const pm_kdtree *t, pm_query_stats *stats) {
    view v = make_view(t);
    rad_iter(s, &v);
    if (stats) {
        stats->nodes_visited += s->nodes;
        stats->dist_evals += s->evals;
    }
}

static int rad_setup(rad_state *s, const pm_kdtree *t, const float q[3], float r2) {
    int rc = check_query(t, q, r2);
    if (rc < 0) return rc;
    if (t->n == 0 || !(r2 > 0)) return 0;
    memset(s, 0, sizeof *s);
    s->q[0] = q[0], s->q[1] = q[1], s->q[2] = q[2];
    s->r2 = r2 == INFINITY ? NAN : r2;
    view v = make_view(t);
    root_box(&v, is_photon_layout(t), s->lo, s->hi);
    return 1;
}

long pm_kdtree_radius(const pm_kdtree *tree, const float q[3], float r2, pm_neighbor *out,
                      size_t cap, unsigned flags, pm_query_stats *stats) {
    rad_state s;
    int rc = rad_setup(&s, tree, q, r2);
    if (rc <= 0) return rc;
    if (!out && cap > 0) return PM_EINVAL;
    s.out = out;
    s.cap = cap;
    rad_run(&s, tree, stats);
    if ((flags & PM_SORT) && s.total <= cap) {
        if (s.total <= PM__SORT_KEYS_MAX) pm__nb_sort_keys(out, (unsigned)s.total);
        else pm__nb_sort(out, (size_t)s.total);
    }
    return (long)s.total;
}

long pm_kdtree_radius_cb(const pm_kdtree *tree, const float q[3], float r2, pm_visit_fn fn,
                         void *user, pm_query_stats *stats) {
    rad_state s;
    if (!fn) return PM_EINVAL;
    int rc = rad_setup(&s, tree, q, r2);
    if (rc <= 0) return rc;
    s.fn = fn;
    s.user = user;
    rad_run(&s, tree, stats);
    return (long)s.total;
}
