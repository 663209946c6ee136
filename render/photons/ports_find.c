/* ports_find.c: photon ports found by a camera probe; see ports.h (ports found by a camera
 * probe). Fixed streams, and the camera paths' carriers kept in path order: the same scene and
 * seed find the same ports on any number of threads. */
#include "photons/ports.h"
#include "photons/importance.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "scene/material.h"
#include "base/rng.h"
#include "base/sampling.h"

#define PF_STREAM 0x706f7274ULL /* "port" */
#define PF_VERTS 8              /* camera path vertices, specular ones included */
#define PF_GROUPS 32            /* groups of crossings kept apart; later ones are dropped */

/* A light path the camera sees: its vertices (the last one on the light, or far along a
 * directional light's direction) and what it carries. */
typedef struct carrier {
    vec3 x[PF_VERTS + 1], n[PF_VERTS + 1]; /* every vertex (straight segments between them); n: its
                                              normal on the side the path leaves toward the light */
    int nx;
    double w;
} carrier;

/* A carrier that threads an opening: where its segment crosses the wall, the wall's normal. */
typedef struct thread_rec {
    vec3 a, d; /* the segment's camera end and direction */
    double len;
    vec3 q, n;
    double w;
    int group;
    int prim; /* the wall's primitive where the segment crosses it */
} thread_rec;

/* The first surface along ry (unit direction) within tmax that is not a null surface (ports.h,
 * MEDIA): 1 with it in *h, 0 when there is none. */
static int solid_hit(const scene *s, ray ry, double tmax, hit *h) {
    if (!s->has_null) return scene_intersect(s, ry, tmax, h);
    for (int k = 0; k < 64; k++) {
        if (!scene_intersect(s, ry, tmax, h)) return 0;
        if (scene_material(s, h)->kind != MAT_NULL) return 1;
        vec3 o = scene_offset(s, h->p, h->ng, ry.d);
        tmax -= v3_dot(v3_sub(o, ry.o), ry.d);
        if (!(tmax > 0)) return 0;
        ry.o = o;
    }
    return 1; /* too many null surfaces: taken as blocked */
}

/* Whether the light sample ls is unblocked from h (a directional light's: along its
 * direction); null surfaces (a medium's invisible boundary) do not block (ports.h, MEDIA). */
static int open_to(const scene *s, const hit *h, int dirl, const light_sample *ls) {
    if (!s->has_null)
        return dirl ? scene_visible_dir(s, h->p, h->ng, ls->wi) : scene_visible(s, h->p, h->ng, ls->p, ls->n);
    hit b;
    if (dirl) return !solid_hit(s, (ray){scene_offset(s, h->p, h->ng, ls->wi), ls->wi}, INFINITY, &b);
    vec3 d = v3_sub(ls->p, h->p);
    vec3 po = scene_offset(s, h->p, h->ng, d);
    vec3 qo = v3_iszero(ls->n) ? ls->p : scene_offset(s, ls->p, ls->n, v3_neg(d));
    vec3 e = v3_sub(qo, po);
    double len = v3_len(e);
    if (!(len > 0)) return 1;
    return !solid_hit(s, (ray){po, v3_scale(e, 1 / len)}, len * (1 - 1e-9), &b);
}

/* One light connection from diffuse vertex h (wo toward the viewer, throughput beta): what it
 * carries (luminance; 0 if blocked or nothing) and the light's point in *y. */
static double connect(const scene *s, const hit *h, const material *m, vec3 wo, rgb beta, rng *g, vec3 *y,
                      int *tried) {
    double pl;
    int li = distrib1d_sample(&s->light_distrib, rng_uniform(g), &pl);
    double u1 = rng_uniform(g), u2 = rng_uniform(g);
    vec3 n = v3_dot(wo, h->ng) >= 0 ? h->ng : v3_neg(h->ng);
    light_sample ls;
    *tried = 0;
    if (!(pl > 0) || !light_sample_li(s, li, h->p, u1, u2, &ls) || v3_iszero(ls.L)) return 0;
    double cs = v3_dot(ls.wi, n);
    if (!(cs > 0)) return 0;
    rgb f = material_f(m, h->ng, s->medium_ior, wo, ls.wi);
    if (v3_iszero(f)) return 0;
    *tried = 1;
    int dirl = s->lights[li].type == LIGHT_DIRECTIONAL;
    if (!open_to(s, h, dirl, &ls)) return 0;
    *y = dirl ? v3_madd(h->p, ls.wi, 2 * (s->bsphere_r > 0 ? s->bsphere_r : 1.0)) : ls.p;
    double w = rgb_lum(v3_mul(v3_mul(beta, f), ls.L)) * cs / pl;
    return w > 0 && isfinite(w) ? w : 0;
}

/* Camera path j: its carriers appended to c (at most PF_DEPTH PF_LIGHTS); how many. A carrier's last
 * segment leaves its last vertex on the viewer's side (the connection's). */
static int camera_path(const scene *s, uint64_t seed, long j, carrier *c, unsigned long long *tried,
                       unsigned long long *passed) {
    rng g = rng_stream(seed, (uint64_t)j, PF_STREAM);
    const camera *cam = &s->cam;
    /* Two draws, named so their order is fixed: as arguments of one call it would be the
     * compiler's (gcc drew the height's first, clang the width's; the images have always been
     * gcc's). */
    double uy = rng_uniform(&g), ux = rng_uniform(&g);
    ray ry = camera_ray(cam, ux * cam->width, uy * cam->height);
    rgb beta = v3s(1);
    carrier path = {0};
    int nc = 0, nd = 0;
    /* camera_walk_hit takes the steps (importance.c's walk declares the same outputs); what this
     * walk keeps at a hit is its own. */
    for (int b = 0; b < PF_VERTS && nd < PF_DEPTH; b++) {
        hit h;
        const material *m;
        vec3 wo, nside;
        int diffuse;
        if (!camera_walk_hit(s, ry, &h, &m, &wo, &diffuse)) break;
        path.x[path.nx] = h.p;
        path.n[path.nx] = v3_dot(wo, h.ng) >= 0 ? h.ng : v3_neg(h.ng);
        path.nx++;
        if (diffuse) {
            nd++;
            for (int k = 0; k < PF_LIGHTS; k++) {
                vec3 y;
                int t;
                double cw = connect(s, &h, m, wo, beta, &g, &y, &t) / PF_LIGHTS;
                *tried += (unsigned long long)t;
                if (!(cw > 0)) continue;
                c[nc] = path;
                c[nc].x[c[nc].nx] = y;
                c[nc].n[c[nc].nx] = v3s(0);
                c[nc].nx++;
                c[nc].w = cw;
                nc++;
                ++*passed;
            }
        }
        if (!camera_walk_next(s, m, &h, wo, &g, &beta, &ry, &nside)) break;
        path.n[path.nx - 1] = nside; /* the side the path leaves from */
    }
    return nc;
}

/* Where the segment a + t d (0 < t < len) crosses the wall of blocker hit h, between the two
 * blockers h and g: 1 with *t, 0 when it does not. */
static int cross_wall(vec3 a, vec3 d, double len, const hit *h, const hit *g, double *t) {
    double dn = v3_dot(d, h->ng);
    *t = dn != 0 ? v3_dot(v3_sub(h->p, a), h->ng) / dn : -1;
    vec3 e = v3_sub(g->p, h->p);
    double along = v3_dot(v3_sub(v3_madd(a, d, *t), h->p), e);
    return *t > 0.01 * len && *t < 0.9 * len && along > 0 && along < v3_len2(e);
}

/* Does the segment a -> b (a on a surface, na its normal on the segment's side) thread an
 * opening (ports.h, THE PROBE)? Then 1 with the crossing in r->q and the wall's normal. Each
 * axis whose two rays are blocked gives its crossing with the farther of the two blockers'
 * walls (the segment crosses it between them); of the two axes, the farther crossing wins: the
 * opening nearest the light, where a slit behind a doorway narrows the light the most. */
static int threads(const scene *s, vec3 a, vec3 na, vec3 b, thread_rec *r) {
    vec3 d = v3_sub(b, a);
    double len = v3_len(d), best = -1;
    if (!(len > 0)) return 0;
    d = v3_scale(d, 1 / len);
    vec3 u, v;
    v3_basis(d, &u, &v);
    const vec3 off[4] = {u, v3_neg(u), v, v3_neg(v)};
    int blocked[4] = {0}, done[2] = {0};
    hit hh[4];
    for (int j = 0; j < PF_LEVELS && !(done[0] && done[1]); j++) {
        double delta = len * (double)(1 << j) / 512;
        for (int k = 0; k < 4; k++) {
            if (blocked[k] || done[k / 2]) continue;
            vec3 tgt = v3_madd(b, off[k], delta), dr = v3_sub(tgt, a);
            double dl = v3_len(dr);
            dr = v3_scale(dr, 1 / dl);
            ray ry = {scene_offset(s, a, na, dr), dr};
            blocked[k] = solid_hit(s, ry, 0.9 * dl, &hh[k]); /* a blocker by the far end is its surface */
        }
        for (int ax = 0; ax < 2; ax++) {
            if (done[ax] || !blocked[2 * ax] || !blocked[2 * ax + 1]) continue;
            done[ax] = 1;
            const hit *h1 = &hh[2 * ax], *h2 = &hh[2 * ax + 1];
            if (fabs(v3_dot(h1->ng, h2->ng)) < 0.7) continue;
            for (int w = 0; w < 2; w++) {
                const hit *h = w ? h2 : h1, *g = w ? h1 : h2;
                double t;
                if (!cross_wall(a, d, len, h, g, &t) || !(t > best)) continue;
                best = t;
                r->q = v3_madd(a, d, t);
                r->n = v3_dot(h->ng, d) < 0 ? v3_neg(h->ng) : h->ng; /* along the way toward the light */
                r->prim = h->prim;
            }
        }
    }
    if (!(best > 0)) return 0;
    r->a = a;
    r->d = d;
    r->len = len;
    return 1;
}

static int dbl_cmp(const void *pa, const void *pb) {
    double x = *(const double *)pa, y = *(const double *)pb;
    return x < y ? -1 : x > y;
}

/* The interval of m points taken as uniform on it, from their order statistics k and m - 1 - k
 * (k = PF_TRIM m: the outermost few are left out): E[x_(j)] = A + (B - A) j / (m + 1). */
static void trimmed(double *v, long m, double *lo, double *hi) {
    qsort(v, (size_t)m, sizeof *v, dbl_cmp);
    long k = (long)(PF_TRIM * (double)m);
    double a = v[k], b = v[m - 1 - k], half = (b - a) * (double)(m + 1) / (double)(m - 1 - 2 * k) / 2;
    *lo = (a + b) / 2 - half;
    *hi = (a + b) / 2 + half;
}

/* The distance from q to the segment from a to a + e. */
static double seg_dist(vec3 q, vec3 a, vec3 e) {
    double l2 = v3_len2(e), u = l2 > 0 ? v3_dot(v3_sub(q, a), e) / l2 : 0;
    u = u < 0 ? 0 : u > 1 ? 1 : u;
    return v3_len(v3_sub(q, v3_madd(a, e, u)));
}

/* The edge (origin *o, direction *e) of crossing t's wall triangle nearest to its crossing, among
 * those in the plane of normal n; its turn from e1 about n in [0, pi/2). -1 when it has none. */
static double rim_edge(const scene *s, const thread_rec *t, vec3 n, vec3 e1, vec3 e2, vec3 *o, vec3 *e) {
    if (t->prim < 0 || t->prim >= s->ntris) return -1;
    const triangle *tr = &s->tris[t->prim];
    vec3 to[3] = {tr->v0, tr->v0, v3_add(tr->v0, tr->e1)}, te[3] = {tr->e1, tr->e2, v3_sub(tr->e2, tr->e1)};
    int best = -1;
    double bd = INFINITY;
    for (int k = 0; k < 3; k++) {
        double l = v3_len(te[k]), d = seg_dist(t->q, to[k], te[k]);
        if (l > 0 && fabs(v3_dot(te[k], n)) <= 0.01 * l && d < bd) bd = d, best = k;
    }
    if (best < 0) return -1;
    *o = to[best], *e = te[best];
    double a = fmod(atan2(v3_dot(*e, e2), v3_dot(*e, e1)), M_PI / 2);
    return a < 0 ? a + M_PI / 2 : a;
}

static int same_turn(double a, double b) {
    return fabs(a - b) < 1e-6 || M_PI / 2 - fabs(a - b) < 1e-6;
}

/* The turn of the opening's rim (ports.h, THE TURN), an angle from e1 about n in [0, pi/2): each
 * of group gi's crossings votes for the turn of the edge of its wall triangle nearest to it (in
 * the port's plane); the turn with the most votes. -1 when no crossing has a wall triangle. */
static double rim_turn(const scene *s, const thread_rec *t, long nt, int gi, vec3 n, vec3 e1, vec3 e2) {
    double turn[PF_TURNS];
    long votes[PF_TURNS];
    int nturn = 0;
    for (long i = 0; i < nt; i++) {
        vec3 o, e;
        double a = t[i].group == gi ? rim_edge(s, &t[i], n, e1, e2, &o, &e) : -1;
        if (a < 0) continue;
        int m = 0;
        while (m < nturn && !same_turn(turn[m], a)) m++;
        if (m == nturn) {
            if (nturn == PF_TURNS) continue;
            turn[nturn] = a, votes[nturn++] = 0;
        }
        votes[m]++;
    }
    int top = -1;
    for (int m = 0; m < nturn; m++)
        if (top < 0 || votes[m] > votes[top]) top = m;
    return top < 0 ? -1 : turn[top];
}

/* The trimmed extents (lo[2], hi[2]) of group gi's crossings with the plane (c, n) along u and v;
 * the number of crossings (xs, ys: room for nt each). */
static long extents(const thread_rec *t, long nt, int gi, vec3 c, vec3 n, vec3 u, vec3 v, double *xs, double *ys,
                    double lo[2], double hi[2]) {
    long m = 0;
    for (long i = 0; i < nt; i++) {
        double dn = v3_dot(t[i].d, n), tt = dn != 0 ? v3_dot(v3_sub(c, t[i].a), n) / dn : -1;
        if (t[i].group != gi || !(tt > 0 && tt < t[i].len)) continue;
        vec3 w = v3_sub(v3_madd(t[i].a, t[i].d, tt), c);
        xs[m] = v3_dot(w, u), ys[m++] = v3_dot(w, v);
    }
    if (m < PF_MIN_THREADS) return m;
    trimmed(xs, m, &lo[0], &hi[0]);
    trimmed(ys, m, &lo[1], &hi[1]);
    return m;
}

/* Is the plane (c, n) open at p: no solid surface within d of it along n, either way? */
static int open_at(const scene *s, vec3 p, vec3 n, double d) {
    hit h;
    return !solid_hit(s, (ray){v3_madd(p, n, -d), n}, 2 * d, &h);
}

/* THE RIM (ports.h): each side of the rectangle bx (lo u, hi u, lo v, hi v about c along u, v)
 * moves to the wall: at PF_RIM_PROBES points along it, the edge between the open middle and the
 * wall at most PF_RIM_REACH of the rectangle's size beyond the side is found by bisection in the
 * plane (c, n), and the side goes to the farthest of them. A side where no probe finds an edge
 * (the middle not open, or no wall within reach) stays. */
static int rim_sides(const scene *s, vec3 c, vec3 n, vec3 u, vec3 v, double bx[4]) {
    const double mid[2] = {(bx[0] + bx[1]) / 2, (bx[2] + bx[3]) / 2}, size[2] = {bx[1] - bx[0], bx[3] - bx[2]};
    const double d = 1e-3 * (size[0] + size[1]);
    double nb[4];
    int found = 0;
    for (int side = 0; side < 4; side++) {
        int ax = side / 2, o = 1 - ax;
        double sg = side % 2 ? 1 : -1, far = -INFINITY;
        for (int k = 0; k < PF_RIM_PROBES; k++) {
            double y = bx[2 * o] + size[o] * (k + 0.5) / PF_RIM_PROBES, in = mid[ax];
            double out = bx[side] + sg * PF_RIM_REACH * size[ax];
#define RIM_AT(x) (ax ? v3_add(c, v3_add(v3_scale(u, y), v3_scale(v, (x)))) \
                      : v3_add(c, v3_add(v3_scale(u, (x)), v3_scale(v, y))))
            if (!open_at(s, RIM_AT(in), n, d) || open_at(s, RIM_AT(out), n, d)) continue;
            for (int it = 0; it < 40; it++) {
                double m = (in + out) / 2;
                if (open_at(s, RIM_AT(m), n, d)) in = m;
                else out = m;
            }
#undef RIM_AT
            if (sg * out > far) far = sg * out; /* the first point of wall: the port holds the opening */
        }
        nb[side] = far > -INFINITY ? sg * far : bx[side];
        if (far > -INFINITY) found |= 1 << side;
    }
    for (int k = 0; k < 4; k++) bx[k] = nb[k];
    return found;
}

/* The rectangle around the crossings of group gi's segments with the plane (c, n), by trimmed
 * (ports.h, THE FIT), turned by THE TURN and grown by PF_GROW: 0 when fewer than PF_MIN_THREADS
 * cross, PM_ENOMEM. */
static int fit_rect(const scene *s, const thread_rec *t, long nt, int gi, vec3 c, vec3 n, port *out) {
    vec3 e1, e2;
    v3_basis(n, &e1, &e2);
    vec3 bu = e1, bv = e2;
    double best = INFINITY, best_wall = INFINITY, bx[4] = {0}, wx[4] = {0}, turn[33];
    vec3 wu = e1, wv = e2;
    double *xs = malloc(2 * (size_t)nt * sizeof *xs), *ys = xs + nt;
    if (!xs) return PM_ENOMEM;
    double wall = rim_turn(s, t, nt, gi, n, e1, e2);
    int nwall = wall >= 0, rim = 0; /* rim: the sides THE RIM gave, a bit each */
    turn[0] = wall;
    for (int r = 0; r < 32; r++) turn[nwall + r] = r * (M_PI / 2) / 32;
    for (int r = 0; r < nwall + 32; r++) {
        double ca = cos(turn[r]), sa = sin(turn[r]), lo[2], hi[2];
        vec3 u = v3_add(v3_scale(e1, ca), v3_scale(e2, sa)), v = v3_add(v3_scale(e1, -sa), v3_scale(e2, ca));
        if (extents(t, nt, gi, c, n, u, v, xs, ys, lo, hi) < PF_MIN_THREADS) {
            free(xs);
            return 0;
        }
        double area = (hi[0] - lo[0]) * (hi[1] - lo[1]);
        double *dst = r < nwall ? wx : bx, *b = r < nwall ? &best_wall : &best;
        if (area < *b) {
            *b = area;
            if (r < nwall) wu = u, wv = v;
            else bu = u, bv = v;
            dst[0] = lo[0], dst[1] = hi[0], dst[2] = lo[1], dst[3] = hi[1];
        }
    }
    if (best_wall <= PF_TURN_SLACK * best) { /* THE TURN in ports.h: the wall's own, when near the best */
        bu = wu, bv = wv;
        for (int k = 0; k < 4; k++) bx[k] = wx[k];
        rim = rim_sides(s, c, n, bu, bv, bx);
    }
    free(xs);
    double sx = bx[1] - bx[0], sy = bx[3] - bx[2];
    if (!(sx > 0 && sy > 0)) return 0;
    for (int k = 0; k < 4; k++) /* THE FIT in ports.h: grown at each edge the rim did not give */
        if (!(rim & 1 << k)) bx[k] += (k % 2 ? 1 : -1) * PF_GROW * (k < 2 ? sx : sy);
    sx = bx[1] - bx[0], sy = bx[3] - bx[2];
    vec3 corner = v3_add(c, v3_add(v3_scale(bu, bx[0]), v3_scale(bv, bx[2])));
    vec3 q1 = v3_scale(bu, sx), q2 = v3_scale(bv, sy);
    if (v3_dot(v3_cross(q1, q2), n) < 0) { /* keep the wall's normal: e1 x e2 along n */
        corner = v3_add(corner, q1);
        q1 = v3_neg(q1);
    }
    *out = port_quad(corner, q1, q2);
    return 1;
}

static long uf_root(long *up, long i) {
    while (up[i] != i) i = up[i] = up[up[i]];
    return i;
}

/* Groups of the threads' crossings (ports.h, THE FIT): linked when within PF_CLUSTER of the
 * scene's bounding radius with normals within 25 degrees, so a long slit is one group. The
 * groups' weighted centres and normals (sums), weights and counts; how many groups (the first
 * PF_GROUPS in thread order; threads of later ones get group -1). 0 with PM_ENOMEM in *rc. */
static int group(const scene *s, thread_rec *t, long nt, vec3 *gc, vec3 *gn, double *gw, int *gcount, int *rc) {
    double link = PF_CLUSTER * (s->bsphere_r > 0 ? s->bsphere_r : 1.0);
    long *up = malloc((size_t)nt * sizeof *up);
    *rc = 0;
    if (!up) {
        *rc = PM_ENOMEM;
        return 0;
    }
    for (long i = 0; i < nt; i++) up[i] = i;
    for (long i = 0; i < nt; i++)
        for (long j = i + 1; j < nt; j++)
            if (v3_len2(v3_sub(t[i].q, t[j].q)) < link * link && fabs(v3_dot(t[i].n, t[j].n)) > 0.9) {
                long a = uf_root(up, i), b = uf_root(up, j);
                if (a != b) up[a > b ? a : b] = a < b ? a : b; /* the root is the smallest index */
            }
    int ng = 0;
    for (long i = 0; i < nt; i++) {
        long r = uf_root(up, i);
        t[i].group = r == i && ng < PF_GROUPS ? ng++ : r == i ? -1 : t[r].group;
        int k = t[i].group;
        if (k < 0) continue;
        if (r == i) gc[k] = v3s(0), gn[k] = v3s(0), gw[k] = 0, gcount[k] = 0;
        vec3 nn = gw[k] > 0 && v3_dot(t[i].n, gn[k]) < 0 ? v3_neg(t[i].n) : t[i].n;
        gc[k] = v3_madd(gc[k], t[i].q, t[i].w);
        gn[k] = v3_madd(gn[k], nn, t[i].w);
        gw[k] += t[i].w;
        gcount[k]++;
    }
    free(up);
    return ng;
}

/* The share of the lights' power ordinary emission sends through port pt (ports_build). */
static int port_flux(const scene *s, const port *pt, double *flux) {
    scene c = *s;
    c.ports = (port *)pt;
    c.nports = 1;
    c.port_fraction = 0.5;
    photon_ports pp;
    int rc = ports_build(&pp, &c);
    if (rc < 0) return rc;
    *flux = pp.flux;
    ports_free(&pp);
    return 0;
}

/* Groups to ports by THE DECISION; the evidence in f->why. */
static int decide(const scene *s, thread_rec *t, long nt, double wsum, port_found *f) {
    vec3 gc[PF_GROUPS], gn[PF_GROUPS];
    double gw[PF_GROUPS];
    int gcount[PF_GROUPS], used[PF_GROUPS] = {0};
    int rc = 0, ng = group(s, t, nt, gc, gn, gw, gcount, &rc);
    if (rc < 0) return rc;
    f->groups = ng;
    size_t len = strlen(f->why);
    for (int r = 0; r < ng && f->n < PF_MAX; r++) {
        int k = -1;
        for (int i = 0; i < ng; i++)
            if (!used[i] && (k < 0 || gw[i] > gw[k])) k = i;
        used[k] = 1;
        double share = gw[k] / wsum, flux = 0;
        port pt;
        const char *no = NULL;
        if (gcount[k] < PF_MIN_THREADS) no = "too few carriers";
        else if (share < PF_MIN_SHARE) no = "too small a share";
        else if ((rc = fit_rect(s, t, nt, k, v3_scale(gc[k], 1 / gw[k]), v3_norm(gn[k]), &pt)) <= 0) {
            if (rc < 0) return rc;
            no = "no rectangle fits";
        } else {
            if ((rc = port_flux(s, &pt, &flux)) < 0) return rc;
            if (flux * PF_MIN_GAIN > share) no = "ordinary emission already sends enough there";
        }
        vec3 c = v3_scale(gc[k], 1 / gw[k]);
        if (len < sizeof f->why && r < 3)
            len += (size_t)snprintf(f->why + len, sizeof f->why - len, "; group at (%.4g, %.4g, %.4g): %d carriers, "
                                    "%.3g%% of the carried light%s%s", c.x, c.y, c.z, gcount[k], 100 * share,
                                    no ? ", not a port: " : "", no ? no : "");
        if (no) {
            if (share < PF_MIN_SHARE) break; /* the rest are smaller still */
            continue;
        }
        f->p[f->n] = pt;
        f->share[f->n] = share;
        f->flux[f->n] = flux;
        f->count[f->n] = gcount[k];
        f->n++;
    }
    return 0;
}

int ports_find(const scene *s, uint64_t seed, port_found *f) {
    memset(f, 0, sizeof *f);
    if (s->nports || !s->find_ports || !s->nlights || s->light_distrib.n == 0) {
        snprintf(f->why, sizeof f->why, "%s", s->nports ? "ports declared" : !s->find_ports ? "$.find_ports is false"
                 : "no light");
        return 0;
    }
    f->ran = 1;
    /* Rounds of PF_ROUND paths on all threads, each path into its own slots, appended in path
     * order: the same carriers for any thread count. */
    const size_t per = (size_t)PF_DEPTH * PF_LIGHTS;
    carrier *c = malloc((size_t)(PF_CARRIERS + PF_ROUND_MAX * per) * sizeof *c);
    carrier *slots = malloc((size_t)PF_ROUND_MAX * per * sizeof *slots);
    int *ns = malloc((size_t)PF_ROUND_MAX * sizeof *ns);
    if (!c || !slots || !ns) {
        free(c), free(slots), free(ns);
        return PM_ENOMEM;
    }
    long nc = 0;
    double pass = 0;
    long round = PF_ROUND;
    for (long j0 = 0; j0 < PF_PATHS_MAX && nc < PF_CARRIERS && pass < PF_MAX_PASS; j0 += round, round *= 2) {
        unsigned long long tried = 0, passed = 0;
        if (round > PF_ROUND_MAX) round = PF_ROUND_MAX;
        if (round > PF_PATHS_MAX - j0) round = PF_PATHS_MAX - j0;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 64) reduction(+ : tried, passed)
#endif
        for (long j = 0; j < round; j++) ns[j] = camera_path(s, seed, j0 + j, slots + (size_t)j * per, &tried, &passed);
        f->connections += tried;
        f->passed += passed;
        f->paths = j0 + round;
        for (long j = 0; j < round; j++) {
            memcpy(c + nc, slots + (size_t)j * per, (size_t)ns[j] * sizeof *c);
            nc += ns[j];
        }
        pass = f->connections ? (double)f->passed / (double)f->connections : 0;
    }
    free(slots);
    free(ns);
    f->carriers = nc;
    int n = snprintf(f->why, sizeof f->why, "%ld camera paths: %llu of %llu light connections pass (%.3g%%)",
                     f->paths, f->passed, f->connections, 100 * pass);
    if (!nc || pass >= PF_MAX_PASS) {
        snprintf(f->why + n, sizeof f->why - (size_t)n, "%s", !nc ? ": no light to follow"
                 : ", so the light is not confined to openings: none looked for");
        free(c);
        return 0;
    }
    thread_rec *t = malloc((size_t)nc * sizeof *t);
    if (!t) {
        free(c);
        return PM_ENOMEM;
    }
    double wsum = 0;
    long nt = 0;
    for (long i = 0; i < nc; i++) {
        wsum += c[i].w;
        for (int k = 0; k + 1 < c[i].nx; k++)
            if (threads(s, c[i].x[k], c[i].n[k], c[i].x[k + 1], &t[nt])) {
                t[nt++].w = c[i].w;
                break;
            }
    }
    f->threaded = nt;
    snprintf(f->why + n, sizeof f->why - (size_t)n, "; %ld carriers, %ld thread an opening", nc, nt);
    int rc = nt ? decide(s, t, nt, wsum, f) : 0;
    free(t);
    free(c);
    return rc;
}

const scene *ports_found_scene(const scene *s, const port_found *f, scene *copy) {
    if (!f->n) return s;
    *copy = *s;
    copy->ports = (port *)f->p;
    copy->nports = f->n;
    return copy;
}
