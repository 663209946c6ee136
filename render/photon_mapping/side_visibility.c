/* side_visibility.c: whether light could pass between two surface points, and the free
 * heights it is lifted by; see side_visibility.h. The layer under photon_sides.c (the cache and
 * the lookups) and photon_corner.c (an estimate's neighbours on its own surface): both call
 * down into it, and it calls neither.
 */
#include "photon_mapping/side_visibility.h"

#include <float.h>
#include <math.h>

#include "photonmap/common.h"
#include "photonmap/estimate.h"
#include "photonmap/kdtree.h"

#ifdef _OPENMP
#include <omp.h>
#endif

static vec3 v3f(const float f[3]) { return v3(f[0], f[1], f[2]); }

double side_free_height(const scene *s, vec3 p, vec3 np, double cap) {
    if (!(cap > 0)) return 0;
    /* p is a photon's float position: it may lie off its surface by its rounding, a float step
     * in each coordinate, more than a ray offset's epsilon; start past that, or the photon's own
     * surface is taken for a ceiling right above it (a free height of 0 hides the photon from
     * its neighbours: the furnace at 10x its size read +42%). */
    ray r = {v3_madd(p, np, 8 * FLT_EPSILON * (s->offset_floor + v3_maxabs(p))), np};
    hit h;
    if (!isfinite(cap)) cap = 1e300;
    if (!scene_intersect(s, r, cap, &h)) return cap;
    return h.t;
}

void side_free_heights(const scene *s, const pm_photon *ph, size_t n, float max_dist2, float *h) {
    double cap = 0.25 * sqrt((double)max_dist2);
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 256)
#endif
    for (size_t i = 0; i < n; i++) {
        float nf[3];
        pm_normal_decode(ph[i].normal, nf);
        h[i] = (float)side_free_height(s, v3f(ph[i].pos), v3f(nf), cap);
    }
}

int side_filter_shadow(void *user, const void *record, uint32_t index) {
    const float *n = user;
    const pm_photon *p = record;
    if (!pm_filter_front(user, record, index)) return 0;
    float pn[3];
    pm_normal_decode(p->normal, pn);
    return pn[0] * n[0] + pn[1] * n[1] + pn[2] * n[2] >= SIDE_LOOKUP_COS;
}

/* The ends of side_visible_h's segment; 0 when p and q coincide (visible, no segment). */
static int side_lift(vec3 p, vec3 np, double hp, vec3 q, vec3 nq, double hq, vec3 *pl, vec3 *ql) {
    double len = v3_len(v3_sub(q, p));
    if (!(len > 0)) return 0;
    /* Lift each end off its surface by L/4, on the side its normal points to (the side the
     * photon arrived on, or the side the query looks from), but at most halfway to the first
     * surface above it, so the lifted end stays in the space on that side; see the top of
     * photon_sides.h. */
    *pl = v3_madd(p, np, fmin(0.25 * len, 0.5 * hp));
    *ql = v3_madd(q, nq, fmin(0.25 * len, 0.5 * hq));
    return 1;
}

int side_visible_h(const scene *s, vec3 p, vec3 np, double hp, vec3 q, vec3 nq, double hq) {
    vec3 pl, ql;
    if (!side_lift(p, np, hp, q, nq, hq, &pl, &ql)) return 1;
    return scene_visible(s, pl, v3s(0), ql, v3s(0));
}

/* CLEAR SEGMENTS WITHOUT A RAY (side_precomp_neighbours). A precomputed estimate tests up to k
 * segments, all inside a ball around x (an end lifted at most L/4, L at most the disc's
 * radius: within 1.25 radii); in an open stretch of wall the only surfaces near are the
 * photon's own plane and perhaps a corner's. A segment whose two ends lie on the same side of
 * a triangle's plane, each farther from it than SIDE_CLEAR_MARGIN of the scene's scale, does
 * not cross that plane, so no ray along it can meet the triangle (triangle_intersect's t for
 * that plane lies outside [0, 1] by at least margin / length, far beyond its rounding in
 * doubles). So the triangles whose boxes overlap the ball's box (bvh_overlap; at most
 * SIDE_CLEAR_MAX, no sphere: side_planes_near) are listed once per estimate, and a segment
 * clear of all their planes is visible without its ray (side_clear); any other segment
 * traces its ray as before. The answer is the ray's, always: the cache, and the image, are
 * the same bit for bit; only rays are saved. Measured (pinhole_room 8 x 8, 1024 spp, seed 1,
 * one thread, a loaded machine): the precomputation's visibility rays 2,916,474 -> 338,709
 * (100,001 of them the free heights), the whole run 1.71 -> 1.41 CPU-s; what is left of the
 * precomputation is mostly its k-nearest searches. */
void side_planes_near(const scene *s, vec3 x, double r2, side_planes *pl) {
    pl->ok = 0;
    pl->n = 0;
    double scale = s->offset_floor + v3_maxabs(x);
    pl->margin = SIDE_CLEAR_MARGIN * scale;
    double R = 1.3 * sqrt(r2) + 2 * pl->margin;
    if (!isfinite(R)) return;
    double lo[3] = {x.x - R, x.y - R, x.z - R}, hi[3] = {x.x + R, x.y + R, x.z + R};
    uint32_t ids[SIDE_CLEAR_MAX];
    int n = bvh_overlap(&s->accel, lo, hi, ids, SIDE_CLEAR_MAX);
    if (n > SIDE_CLEAR_MAX) return;
    for (int i = 0; i < n; i++) {
        if (ids[i] >= (uint32_t)s->accel.ntris) return;
        const triangle *t = &s->accel.tris[ids[i]];
        vec3 c = v3_cross(t->e1, t->e2);
        double cl = v3_len(c);
        if (!(cl > 1e-9 * v3_len(t->e1) * v3_len(t->e2))) return; /* no trustworthy plane */
        pl->nrm[i] = v3_scale(c, 1.0 / cl);
        pl->d[i] = v3_dot(pl->nrm[i], t->v0);
    }
    pl->n = n;
    pl->ok = 1;
}

int side_clear(const side_planes *pl, vec3 p, vec3 np, double hp, vec3 q, vec3 nq, double hq) {
    if (!pl->ok) return 0;
    vec3 a, b;
    if (!side_lift(p, np, hp, q, nq, hq, &a, &b)) return 1;
    for (int i = 0; i < pl->n; i++) {
        double sa = v3_dot(pl->nrm[i], a) - pl->d[i], sb = v3_dot(pl->nrm[i], b) - pl->d[i];
        if (!((sa > pl->margin && sb > pl->margin) || (sa < -pl->margin && sb < -pl->margin))) return 0;
    }
    return 1;
}

int side_visible(const scene *s, vec3 p, vec3 np, vec3 q, vec3 nq) {
    double L4 = 0.25 * v3_len(v3_sub(q, p));
    return side_visible_h(s, p, np, side_free_height(s, p, np, L4), q, nq,
                          side_free_height(s, q, nq, L4));
}
