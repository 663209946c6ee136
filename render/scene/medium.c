/* medium.c: homogeneous media (see medium.h): transmittance, Henyey–Greenstein sampling,
 * free-flight sampling with a per-channel mixture pdf, and the walk of a shadow segment
 * through null interfaces that multiplies the transmittance of each medium it crosses.
 */
#include "scene/medium.h"

#include <float.h>
#include <math.h>
#include <stdio.h>

#include "photonmap/common.h"
#include "base/sampling.h"
#include "scene/scene.h"

/* A shadow segment crossing more invisible interfaces than this is treated as blocked: only a
 * degenerate scene (thousands of stacked null surfaces) gets there, and it must not hang. */
#define MEDIUM_MAX_CROSSINGS 1024

rgb medium_tr(const medium *m, double d) {
    double c[3] = {m->sigma_t.x, m->sigma_t.y, m->sigma_t.z}, o[3];
    for (int k = 0; k < 3; k++) o[k] = c[k] > 0 ? exp(-c[k] * d) : 1.0; /* 0 * inf is not 0 */
    return v3(o[0], o[1], o[2]);
}

double hg_phase(double g, double cos_theta) {
    double den = 1 + g * g - 2 * g * cos_theta;
    return (1 - g * g) / (4 * M_PI * den * sqrt(den));
}

double hg_sample(double g, vec3 a, double u1, double u2, vec3 *b) {
    double c;
    if (fabs(g) < 1e-3) {
        c = 1 - 2 * u1;
    } else { /* inverse of the HG distribution of cos */
        double q = (1 - g * g) / (1 - g + 2 * g * u1);
        c = (1 + g * g - q * q) / (2 * g);
    }
    c = fmax(-1.0, fmin(1.0, c));
    double sn = sqrt(fmax(0.0, 1 - c * c)), phi = 2 * M_PI * u2;
    *b = v3_norm(sampling_to_world(v3(sn * cos(phi), sn * sin(phi), c), a));
    return hg_phase(g, c);
}

int medium_sample_distance(const medium *m, double tmax, double uc, double u, double *t, rgb *weight) {
    double st[3] = {m->sigma_t.x, m->sigma_t.y, m->sigma_t.z};
    int ch = uc < 1.0 / 3 ? 0 : uc < 2.0 / 3 ? 1 : 2;
    double tt = st[ch] > 0 ? -log1p(-u) / st[ch] : INFINITY;
    rgb tr;
    if (tt < tmax) {
        tr = medium_tr(m, tt);
        double pdf = (st[0] * tr.x + st[1] * tr.y + st[2] * tr.z) / 3;
        *t = tt;
        *weight = pdf > 0 ? v3_scale(v3_mul(tr, m->sigma_s), 1.0 / pdf) : v3s(0);
        return 1;
    }
    tr = medium_tr(m, tmax);
    double p_reach = (tr.x + tr.y + tr.z) / 3;
    *t = tmax;
    *weight = p_reach > 0 ? v3_scale(tr, 1.0 / p_reach) : v3s(0);
    return 0;
}

/* The line's closest approach to y (*delta) and distance from it (*D, floored), and the angles
 * of t0 and t1 seen from y. 0 if the interval is empty. */
static int equiangular_setup(vec3 o, vec3 d, double t0, double t1, vec3 y, double *delta, double *D, double *th0,
                             double *th1) {
    if (!(t1 > t0)) return 0;
    vec3 oy = v3_sub(y, o);
    *delta = v3_dot(oy, d);
    double dd = v3_len(v3_sub(oy, v3_scale(d, *delta))), floor_d = 1e-9 * v3_len(oy);
    *D = dd > floor_d ? dd : floor_d > 0 ? floor_d : DBL_MIN;
    *th0 = atan2(t0 - *delta, *D);
    *th1 = isfinite(t1) ? atan2(t1 - *delta, *D) : M_PI / 2;
    return *th1 > *th0;
}

double medium_equiangular_sample(vec3 o, vec3 d, double t0, double t1, vec3 y, double u, double *t) {
    double delta, D, th0, th1;
    if (!equiangular_setup(o, d, t0, t1, y, &delta, &D, &th0, &th1)) return 0;
    double tt = delta + D * tan(th0 + u * (th1 - th0));
    *t = fmin(fmax(tt, t0), t1); /* rounding at the ends */
    double e = *t - delta;
    return D / ((th1 - th0) * (D * D + e * e));
}

double medium_equiangular_pdf(vec3 o, vec3 d, double t0, double t1, vec3 y, double t) {
    double delta, D, th0, th1;
    if (!(t >= t0 && t <= t1) || !equiangular_setup(o, d, t0, t1, y, &delta, &D, &th0, &th1)) return 0;
    double e = t - delta;
    return D / ((th1 - th0) * (D * D + e * e));
}

int scene_has_media(const scene *s) { return s->nmedia > 0 || s->has_null; }

int scene_object_side_medium(const scene *s, int obj, int front) {
    int kind = s->obj_iface && obj < s->nobj ? s->obj_iface[obj] : MEDIUM_IFACE_LEGACY;
    if (kind == MEDIUM_IFACE_KEEP) return -2;
    if (front) return kind == MEDIUM_IFACE_DECLARED && s->obj_medium_out ? s->obj_medium_out[obj] : s->global_medium;
    return s->obj_medium && obj < s->nobj ? s->obj_medium[obj] : -1;
}

int scene_medium_side(const scene *s, const hit *h, vec3 dout, int cur) {
    int m = scene_object_side_medium(s, scene_prim_object(s, h->prim), v3_dot(dout, h->ng) >= 0);
    return m == -2 ? cur : m;
}

static const char *mname(const scene *s, int m) { return m >= 0 ? s->media[m].name : "(none)"; }

/* An inconsistent interface: said once per scene (the flag is the scene's, set atomically). */
static void report_inconsistent(const scene *s, const hit *h, int obj, int front, int cur, int side) {
    if (!s->iface_report || __atomic_exchange_n(s->iface_report, 1, __ATOMIC_RELAXED)) return;
    fprintf(stderr, "render: %s%swarning: inconsistent medium interface: a ray in medium \"%s\" reached "
            "$.objects[%d] at (%.6g, %.6g, %.6g) from its %s side, whose medium is \"%s\" (the surface does not "
            "bound the ray's medium); the ray goes on by the surface's media (reported once)\n",
            s->file, s->file[0] ? ": " : "", mname(s, cur), obj, h->p.x, h->p.y, h->p.z,
            front ? "front (exterior_medium)" : "back (interior_medium)", mname(s, side));
}

int scene_medium_next(const scene *s, const hit *h, vec3 din, vec3 dout, int cur) {
    int obj = scene_prim_object(s, h->prim);
    if (s->obj_iface && obj < s->nobj && s->obj_iface[obj] == MEDIUM_IFACE_DECLARED) {
        int from_front = v3_dot(din, h->ng) < 0, side = scene_object_side_medium(s, obj, from_front);
        if (side != cur) report_inconsistent(s, h, obj, from_front, cur, side);
    }
    return scene_medium_side(s, h, dout, cur);
}

int scene_medium_ahead(const scene *s, ray r) {
    hit h;
    for (int n = 0; n < MEDIUM_MAX_CROSSINGS && scene_intersect(s, r, INFINITY, &h); n++) {
        int m = scene_medium_side(s, &h, v3_neg(r.d), -2);
        if (m != -2) return m;
        r.o = scene_offset(s, h.p, h.ng, r.d);
    }
    return s->global_medium;
}

double scene_index_ahead(const scene *s, ray r) {
    hit h;
    for (int n = 0; n < MEDIUM_MAX_CROSSINGS && scene_intersect(s, r, INFINITY, &h); n++) {
        const material *m = &s->mats[h.mat];
        if (m->kind != MAT_NULL && m->transparency > 0 && m->ior > 0)
            return v3_dot(r.d, h.ng) > 0 ? m->ior : s->medium_ior;
        r.o = scene_offset(s, h.p, h.ng, r.d);
    }
    return s->medium_ior;
}

int scene_light_medium(const scene *s, int li, vec3 p, vec3 nl, vec3 d, int first_hit) {
    const light *l = &s->lights[li];
    int prim = l->type == LIGHT_AREA ? l->tri : l->type == LIGHT_SPHERE ? s->ntris + l->sphere : -1;
    if (prim >= 0 && s->obj_iface && s->obj_iface[scene_prim_object(s, prim)] == MEDIUM_IFACE_DECLARED)
        return scene_object_side_medium(s, scene_prim_object(s, prim), v3_dot(d, nl) >= 0);
    if (first_hit != -2) return first_hit;
    ray r = {v3_iszero(nl) ? p : scene_offset(s, p, nl, d), d};
    return scene_medium_ahead(s, r);
}

/* From o along unit dir for len (INFINITY: to infinity), starting in medium med. */
static rgb walk(const scene *s, vec3 o, vec3 dir, double len, int med) {
    rgb T = v3s(1);
    for (int n = 0; n < MEDIUM_MAX_CROSSINGS; n++) {
        hit h;
        ray r = {o, dir};
        int got = scene_intersect(s, r, len, &h);
        double d = got ? h.t : len;
        if (med >= 0) T = v3_mul(T, medium_tr(&s->media[med], d));
        if (!got) return T;
        if (s->mats[h.mat].kind != MAT_NULL || v3_iszero(T)) return v3s(0);
        med = scene_medium_next(s, &h, dir, dir, med);
        vec3 no = scene_offset(s, h.p, h.ng, dir);
        if (isfinite(len)) len -= v3_dot(v3_sub(no, o), dir);
        if (!(len > 0)) return T;
        o = no;
    }
    return v3s(0);
}

rgb scene_transmittance(const scene *s, vec3 p, vec3 np, vec3 q, vec3 nq, int med) {
    vec3 d = v3_sub(q, p);
    vec3 po = v3_iszero(np) ? p : scene_offset(s, p, np, d);
    vec3 qo = v3_iszero(nq) ? q : scene_offset(s, q, nq, v3_neg(d));
    vec3 e = v3_sub(qo, po);
    double len = v3_len(e);
    if (!(len > 0)) return v3s(1);
    /* Stop just short of q when q is not on a surface (as scene_visible does). */
    return walk(s, po, v3_scale(e, 1.0 / len), v3_iszero(nq) ? len * (1 - 1e-9) : len, med);
}

rgb scene_transmittance_dir(const scene *s, vec3 p, vec3 np, vec3 d, int med) {
    return walk(s, v3_iszero(np) ? p : scene_offset(s, p, np, d), d, INFINITY, med);
}
