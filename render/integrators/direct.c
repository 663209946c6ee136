/* direct.c: next-event estimation for the path tracer and the photon mapper (direct.h): one
 * light in proportion to its power, one point on it, one shadow segment; on a port's dark side
 * also one ray through the port (THROUGH A PORT). The random numbers are drawn before anything
 * can end the call, so every caller's stream advances by three (five with the port's ray). */
#include "integrators/direct.h"

#include "guiding/guide.h"
#include "scene/light.h"
#include "scene/material.h"
#include "scene/medium.h"
#include "scene/port.h"
#include "base/sampling.h"
#include "scene/shapes.h"
#include "base/stats.h"

/* One light in proportion to power and one point on it, seen from p: 3 numbers. 0 if none.
 * With a guide (guide.h) that knows the cell of (p, n): the light is chosen with probability
 * p' = alpha p_power + (1 - alpha) w_l (with probability alpha by power, from ulight rescaled,
 * else by the cell's weights w, from what is left of ulight), and the point's (u1, u2) are
 * warped by the light's table there, if it has one; *pl is then p' times the warped pair's
 * density over the unit square, and *guided is 1. p' > 0 for every light with power, and the
 * density > 0 everywhere, so dividing by them keeps every estimate unbiased. */
static int pick_light_with(const scene *s, vec3 p, vec3 n, const guide *gd, double ulight, double u1, double u2,
                           light_sample *ls, double *pl, int *li, int *guided) {
    *guided = 0;
    if (s->nlights == 0 || s->light_distrib.n == 0) return 0;
    long c = gd ? guide_cell_index(gd, p, n) : -1;
    if (c < 0) {
        *li = distrib1d_sample(&s->light_distrib, ulight, pl);
        if (!(*pl > 0)) return 0;
        return light_sample_li(s, *li, p, u1, u2, ls);
    }
    *guided = 1;
    if (gd->stat_id >= 0) stat_inc(gd->stat_id);
    double a = gd->alpha, p0;
    if (ulight < a) {
        double v = ulight / a;
        *li = distrib1d_sample(&s->light_distrib, v < 1 ? v : 0x1.fffffffffffffp-1, &p0);
    } else {
        double v = (ulight - a) / (1 - a);
        *li = guide_pick_slot(gd, c, v < 1 ? v : 0x1.fffffffffffffp-1);
        p0 = distrib1d_prob(&s->light_distrib, *li);
    }
    *pl = a * p0 + (1 - a) * guide_slot_weight(gd, c, *li);
    if (!(*pl > 0)) return 0;
    *pl *= guide_warp(gd, guide_cell_table(gd, c, *li), &u1, &u2);
    return light_sample_li(s, *li, p, u1, u2, ls);
}

static int pick_light_guided(const scene *s, vec3 p, vec3 n, const guide *gd, rng *g, light_sample *ls, double *pl,
                             int *li, int *guided) {
    double ulight = rng_uniform(g), u1 = rng_uniform(g), u2 = rng_uniform(g);
    return pick_light_with(s, p, n, gd, ulight, u1, u2, ls, pl, li, guided);
}

static int pick_light(const scene *s, vec3 p, rng *g, light_sample *ls, double *pl, int *li) {
    int guided;
    return pick_light_guided(s, p, v3s(0), NULL, g, ls, pl, li, &guided);
}

/* Transmittance from p (normal np) to the light sample, starting in medium med. */
static rgb shadow_tr(const scene *s, int li, vec3 p, vec3 np, const light_sample *ls, int med) {
    stat_inc(STAT_SHADOW_RAYS);
    if (light_at_infinity(&s->lights[li])) return scene_transmittance_dir(s, p, np, ls->wi, med);
    return scene_transmittance(s, p, np, ls->p, ls->n, med);
}

rgb direct_light_medium(const scene *s, vec3 p, vec3 d, int med, rng *g) {
    light_sample ls;
    double pl;
    int li;
    if (!pick_light(s, p, g, &ls, &pl, &li) || v3_iszero(ls.L)) return v3s(0);
    double f = hg_phase(s->media[med].g, v3_dot(d, ls.wi));
    rgb tr = shadow_tr(s, li, p, v3s(0), &ls, med);
    return v3_scale(v3_mul(tr, ls.L), f / pl);
}

/* The point that light_sample_li(s, li, any p, u1, u2) samples on light li (light_sample.c: it does
 * not depend on p); 0 for a light at infinity. */
static int light_point(const scene *s, int li, double u1, double u2, vec3 *y) {
    const light *l = &s->lights[li];
    switch (l->type) {
    case LIGHT_AREA: *y = triangle_sample(&s->tris[l->tri], u1, u2); return 1;
    case LIGHT_SPHERE: {
        const sphere *sp = &s->spheres[l->sphere];
        *y = v3_madd(sp->c, sample_uniform_sphere(u1, u2), sp->r);
        return 1;
    }
    case LIGHT_POINT:
    case LIGHT_SPOT: *y = l->pos; return 1;
    default: return 0;
    }
}

rgb direct_light_medium_mis(const scene *s, const direct_segment *seg, double t, double dens, rng *g) {
    light_sample ls;
    double pl;
    int li;
    vec3 p = ray_at(seg->r, t);
    if (!pick_light(s, p, g, &ls, &pl, &li) || v3_iszero(ls.L)) return v3s(0);
    double w = 1;
    if (seg->m > 0 && !light_at_infinity(&s->lights[li])) {
        double pe = seg->m * medium_equiangular_pdf(seg->r.o, seg->r.d, 0, seg->t1, ls.p, t);
        w = dens > 0 ? dens / (dens + pe) : 0;
        if (!(w > 0)) return v3s(0);
    }
    double f = hg_phase(s->media[seg->med].g, v3_dot(seg->r.d, ls.wi));
    rgb tr = shadow_tr(s, li, p, v3s(0), &ls, seg->med);
    return v3_scale(v3_mul(tr, ls.L), w * f / pl);
}

rgb direct_light_equiangular(const scene *s, const direct_segment *seg, direct_density dens, const void *user, rng *g) {
    rgb sum = v3s(0);
    const medium *md = &s->media[seg->med];
    double ut = seg->m > 0 ? rng_uniform(g) : 0;
    for (int j = 0; j < seg->m; j++) {
        double ulight = rng_uniform(g), u1 = rng_uniform(g), u2 = rng_uniform(g);
        if (s->nlights == 0 || s->light_distrib.n == 0) continue;
        double pl;
        int li = distrib1d_sample(&s->light_distrib, ulight, &pl);
        vec3 y;
        if (!(pl > 0) || !light_point(s, li, u1, u2, &y)) continue;
        /* stratum j of the angle: the pdf of t within it is m p_eq(t) */
        double t, pe = medium_equiangular_sample(seg->r.o, seg->r.d, 0, seg->t1, y, (j + ut) / seg->m, &t);
        if (!(pe > 0) || !isfinite(t)) continue;
        rgb tr0 = medium_tr(md, t);
        if (v3_iszero(tr0)) continue;
        vec3 p = ray_at(seg->r, t);
        light_sample ls;
        if (!light_sample_li(s, li, p, u1, u2, &ls) || v3_iszero(ls.L)) continue;
        double mpe = seg->m * pe, od = dens ? dens(user, t) : 0, w = mpe / (mpe + od);
        double f = hg_phase(md->g, v3_dot(seg->r.d, ls.wi));
        rgb tr = shadow_tr(s, li, p, v3s(0), &ls, seg->med);
        sum = v3_add(sum, v3_scale(v3_mul(v3_mul(tr0, md->sigma_s), v3_mul(tr, ls.L)), w * f / (pl * mpe)));
    }
    return sum;
}

rgb direct_light_surface(const scene *s, const material *m, const hit *h, vec3 n, vec3 wo, rng *g,
                         const direct_options *o) {
    return direct_light_surface_guided(s, m, h, n, wo, g, o, NULL);
}

/* ---- THROUGH A PORT (direct.h) ---------------------------------------------------------------- */

double direct_port_share(const direct_options *o, vec3 x, vec3 nsh) {
    if (!o->port || o->media) return 0;
    vec3 toc = v3_sub(o->port->c, x);
    return v3_dot(toc, nsh) > 0 && v3_dot(toc, o->port_lit) > 0 ? DIRECT_PORT_SHARE : 0;
}

/* The (u1, u2) that light_sample_li maps to the point y of an area or sphere light (the inverse
 * of sample_triangle's and sample_uniform_sphere's maps), clamped into [0, 1). */
static void light_point_uv(const scene *s, const light *l, vec3 y, double *u1, double *u2) {
    if (l->type == LIGHT_AREA) {
        const triangle *t = &s->tris[l->tri];
        vec3 d = v3_sub(y, t->v0);
        double a = v3_dot(t->e1, t->e1), b = v3_dot(t->e1, t->e2), c = v3_dot(t->e2, t->e2);
        double p = v3_dot(d, t->e1), q = v3_dot(d, t->e2), det = a * c - b * b;
        double b1 = (c * p - b * q) / det, b2 = (a * q - b * p) / det, sq = 1 - b1;
        *u1 = sq * sq;
        *u2 = sq > 0 ? b2 / sq : 0;
    } else {
        const sphere *sp = &s->spheres[l->sphere];
        vec3 nq = v3_scale(v3_sub(y, sp->c), 1 / sp->r);
        double phi = atan2(nq.y, nq.x);
        *u1 = 0.5 * (1 - nq.z);
        *u2 = (phi < 0 ? phi + 2 * M_PI : phi) / (2 * M_PI);
    }
    *u1 = *u1 < 0 ? 0 : *u1 < 1 ? *u1 : 0x1.fffffffffffffp-1;
    *u2 = *u2 < 0 ? 0 : *u2 < 1 ? *u2 : 0x1.fffffffffffffp-1;
}

/* dist^2 / (cos area) of the point y (normal ny) of area or sphere light li seen from p: what
 * turns a density over the light's (u1, u2) into one over solid angle. 0 when y faces away. */
static double light_point_jacobian(const scene *s, vec3 p, int li, vec3 y, vec3 ny) {
    const light *l = &s->lights[li];
    vec3 d = v3_sub(y, p);
    double dist2 = v3_len2(d), cos_l = -v3_dot(d, ny) / sqrt(dist2);
    if (l->two_sided) cos_l = fabs(cos_l);
    if (!(cos_l > 0) || !(dist2 > 0)) return 0;
    double area = l->type == LIGHT_AREA ? s->tris[l->tri].area
                                        : 4 * M_PI * s->spheres[l->sphere].r * s->spheres[l->sphere].r;
    return dist2 / (cos_l * area);
}

/* The solid-angle density with which pick_light_with draws the point y (normal ny) of area or
 * sphere light li seen from p (geometric normal n on the sample's side): the light's choice
 * (by power, or the guide's mixture there), its table's density at y's (u1, u2), 1 / area,
 * times dist^2 / cos at the light. 0 when y faces away. For the light sample's own point,
 * pick_light_with's pl times light_point_jacobian is the same figure without the inversion. */
static double light_point_pdf(const scene *s, vec3 p, vec3 n, const guide *gd, int li, vec3 y, vec3 ny) {
    const light *l = &s->lights[li];
    double jac = light_point_jacobian(s, p, li, y, ny);
    if (!(jac > 0)) return 0;
    double pc = distrib1d_prob(&s->light_distrib, li);
    long c = gd ? guide_cell_index(gd, p, n) : -1;
    if (c >= 0) {
        double u1, u2;
        light_point_uv(s, l, y, &u1, &u2);
        pc = (gd->alpha * pc + (1 - gd->alpha) * guide_slot_weight(gd, c, li)) *
             guide_pdf(gd, guide_cell_table(gd, c, li), u1, u2);
    }
    return pc * jac;
}

/* The port's density of the unit direction d from x: t^2 / (area cos) where the ray crosses it. */
static double port_dir_pdf(const port *pt, vec3 x, vec3 d) {
    double t, cp;
    return port_cross(pt, x, d, &t, &cp) ? t * t / (pt->area * cp) : 0;
}

/* The port branch: the ray from h through the port point (u1, u2), and the light it first
 * meets, weighted by the mixture (b: the port's share). */
static rgb direct_through_port(const scene *s, const material *m, const hit *h, vec3 n, vec3 nsh, vec3 wo,
                               const direct_options *o, const guide *gd, double b, double u1, double u2) {
    vec3 d = v3_sub(port_sample(o->port, u1, u2), h->p);
    double len = v3_len(d);
    if (!(len > 0)) return v3s(0);
    d = v3_scale(d, 1 / len);
    /* the port's density of d, t^2 / (area cos), from the point itself (port_dir_pdf would
     * find it again, and could miss it at the port's edge by rounding) */
    double cp = fabs(v3_dot(d, o->port->n)), pp = cp > 0 ? len * len / (o->port->area * cp) : 0;
    double cos_s = v3_dot(d, nsh);
    if (cos_s <= 0 || v3_dot(d, n) <= 0 || !(pp > 0)) return v3s(0);
    stat_inc(STAT_SHADOW_RAYS);
    hit y;
    if (!scene_intersect(s, (ray){scene_offset(s, h->p, h->ng, d), d}, INFINITY, &y)) return v3s(0);
    int li = y.prim < s->ntris ? s->tris[y.prim].light : s->spheres[y.prim - s->ntris].light;
    if (li < 0) return v3s(0);
    const light *l = &s->lights[li];
    vec3 ny = l->type == LIGHT_AREA ? s->tris[l->tri].n : v3_norm(v3_sub(y.p, s->spheres[l->sphere].c));
    double pl = light_point_pdf(s, h->p, n, gd, li, y.p, ny);
    if (!(pl > 0)) return v3s(0);
    rgb f = o->bsdf == DIRECT_BSDF_FULL ? material_f(m, h->ng, s->medium_ior, wo, d) : material_diffuse_f(m, nsh, wo, d);
    return v3_scale(v3_mul(f, l->Le), cos_s / (b * pp + (1 - b) * pl));
}

rgb direct_light_surface_guided(const scene *s, const material *m, const hit *h, vec3 n, vec3 wo, rng *g,
                                const direct_options *o, const guide *gd) {
    vec3 nsh = material_shading_side(wo, h->ng, h->ns); /* cosines; n (geometric) keeps the side */
    double ulight = rng_uniform(g), u1 = rng_uniform(g), u2 = rng_uniform(g);
    double b = direct_port_share(o, h->p, nsh);
    rgb Lp = v3s(0); /* THROUGH A PORT: both samples, the port's with two more numbers */
    if (b > 0) {
        double p1 = rng_uniform(g), p2 = rng_uniform(g);
        Lp = v3_scale(direct_through_port(s, m, h, n, nsh, wo, o, gd, b, p1, p2), b);
    }
    light_sample ls;
    double pl;
    int li, guided;
    if (!pick_light_with(s, h->p, n, gd, ulight, u1, u2, &ls, &pl, &li, &guided)) return Lp;
    double cos_s = v3_dot(ls.wi, nsh);
    if (cos_s <= 0 || v3_dot(ls.wi, n) <= 0 || v3_iszero(ls.L)) return Lp;
    rgb f = o->bsdf == DIRECT_BSDF_FULL ? material_f(m, h->ng, s->medium_ior, wo, ls.wi)
                                        : material_diffuse_f(m, nsh, wo, ls.wi);
    if (v3_iszero(f)) return Lp;
    if (o->media) {
        rgb tr = shadow_tr(s, li, h->p, h->ng, &ls, scene_medium_side(s, h, ls.wi, o->med));
        return v3_scale(v3_mul(v3_mul(f, ls.L), tr), cos_s / pl);
    }
    /* The mixture's weight of this sample relative to the light branch alone (THROUGH A PORT). */
    double w = 1;
    if (b > 0) {
        const light *l = &s->lights[li];
        if (l->type == LIGHT_AREA || l->type == LIGHT_SPHERE) {
            double pa = pl * light_point_jacobian(s, h->p, li, ls.p, ls.n);
            w = pa > 0 ? (1 - b) * pa / (b * port_dir_pdf(o->port, h->p, ls.wi) + (1 - b) * pa) : 0;
        }
    }
    /* The hint answers for the point, not for this sample: where the guide aims the samples at
     * the few that pass, "all shadow photons" says nothing about them (each ray is traced). */
    int vis = o->hint && !guided && b == 0 ? o->hint(o->hint_user, s, li, h, n) : -1;
    if (vis < 0) {
        stat_inc(STAT_SHADOW_RAYS);
        if (light_at_infinity(&s->lights[li]))
            vis = scene_visible_dir(s, h->p, h->ng, ls.wi);
        else
            vis = scene_visible(s, h->p, h->ng, ls.p, ls.n);
    }
    if (!vis) return Lp;
    rgb L = v3_scale(v3_mul(f, ls.L), w * cos_s / pl);
    return b > 0 ? v3_add(Lp, L) : L;
}
