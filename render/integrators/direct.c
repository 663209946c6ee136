/* direct.c: next-event estimation for the path tracer and the photon mapper (direct.h): one
 * light in proportion to its power, one point on it, one shadow segment. The random numbers are
 * drawn before anything can end the call, so every caller's stream advances by three. */
#include "integrators/direct.h"

#include "guiding/guide.h"
#include "scene/light.h"
#include "scene/material.h"
#include "scene/medium.h"
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
static int pick_light_guided(const scene *s, vec3 p, vec3 n, const guide *gd, rng *g, light_sample *ls, double *pl,
                             int *li, int *guided) {
    double ulight = rng_uniform(g), u1 = rng_uniform(g), u2 = rng_uniform(g);
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

rgb direct_light_surface_guided(const scene *s, const material *m, const hit *h, vec3 n, vec3 wo, rng *g,
                                const direct_options *o, const guide *gd) {
    vec3 nsh = material_shading_side(wo, h->ng, h->ns); /* cosines; n (geometric) keeps the side */
    light_sample ls;
    double pl;
    int li, guided;
    if (!pick_light_guided(s, h->p, n, gd, g, &ls, &pl, &li, &guided)) return v3s(0);
    double cos_s = v3_dot(ls.wi, nsh);
    if (cos_s <= 0 || v3_dot(ls.wi, n) <= 0 || v3_iszero(ls.L)) return v3s(0);
    rgb f = o->bsdf == DIRECT_BSDF_FULL ? material_f(m, h->ng, s->medium_ior, wo, ls.wi)
                                        : material_diffuse_f(m, nsh, wo, ls.wi);
    if (v3_iszero(f)) return v3s(0);
    if (o->media) {
        rgb tr = shadow_tr(s, li, h->p, h->ng, &ls, scene_medium_side(s, h, ls.wi, o->med));
        return v3_scale(v3_mul(v3_mul(f, ls.L), tr), cos_s / pl);
    }
    /* The hint answers for the point, not for this sample: where the guide aims the samples at
     * the few that pass, "all shadow photons" says nothing about them (each ray is traced). */
    int vis = o->hint && !guided ? o->hint(o->hint_user, s, li, h, n) : -1;
    if (vis < 0) {
        stat_inc(STAT_SHADOW_RAYS);
        if (light_at_infinity(&s->lights[li]))
            vis = scene_visible_dir(s, h->p, h->ng, ls.wi);
        else
            vis = scene_visible(s, h->p, h->ng, ls.p, ls.n);
    }
    if (!vis) return v3s(0);
    return v3_scale(v3_mul(f, ls.L), cos_s / pl);
}
