/* direct.c: next-event estimation for the path tracer and the photon mapper (direct.h): one
 * light in proportion to its power, one point on it, one shadow segment. The random numbers are
 * drawn before anything can end the call, so every caller's stream advances by three. */
#include "direct.h"

#include "light.h"
#include "material.h"
#include "medium.h"
#include "stats.h"

/* One light in proportion to power and one point on it, seen from p: 3 numbers. 0 if none. */
static int pick_light(const scene *s, vec3 p, rng *g, light_sample *ls, double *pl, int *li) {
    double ulight = rng_uniform(g), u1 = rng_uniform(g), u2 = rng_uniform(g);
    if (s->nlights == 0 || s->light_distrib.n == 0) return 0;
    *li = distrib1d_sample(&s->light_distrib, ulight, pl);
    if (!(*pl > 0)) return 0;
    return light_sample_li(s, *li, p, u1, u2, ls);
}

/* Transmittance from p (normal np) to the light sample, starting in medium med. */
static rgb shadow_tr(const scene *s, int li, vec3 p, vec3 np, const light_sample *ls, int med) {
    stat_inc(STAT_SHADOW_RAYS);
    if (s->lights[li].type == LIGHT_DIRECTIONAL) return scene_transmittance_dir(s, p, np, ls->wi, med);
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

rgb direct_light_surface(const scene *s, const material *m, const hit *h, vec3 n, vec3 wo, rng *g,
                         const direct_options *o) {
    vec3 nsh = material_shading_side(wo, h->ng, h->ns); /* cosines; n (geometric) keeps the side */
    light_sample ls;
    double pl;
    int li;
    if (!pick_light(s, h->p, g, &ls, &pl, &li)) return v3s(0);
    double cos_s = v3_dot(ls.wi, nsh);
    if (cos_s <= 0 || v3_dot(ls.wi, n) <= 0 || v3_iszero(ls.L)) return v3s(0);
    rgb f = o->bsdf == DIRECT_BSDF_FULL ? material_f(m, h->ng, s->medium_ior, wo, ls.wi)
                                        : material_diffuse_f(m, nsh, wo, ls.wi);
    if (v3_iszero(f)) return v3s(0);
    if (o->media) {
        rgb tr = shadow_tr(s, li, h->p, h->ng, &ls, scene_medium_after(s, h, ls.wi));
        return v3_scale(v3_mul(v3_mul(f, ls.L), tr), cos_s / pl);
    }
    int vis = o->hint ? o->hint(o->hint_user, s, li, h, n) : -1;
    if (vis < 0) {
        stat_inc(STAT_SHADOW_RAYS);
        if (s->lights[li].type == LIGHT_DIRECTIONAL)
            vis = scene_visible_dir(s, h->p, h->ng, ls.wi);
        else
            vis = scene_visible(s, h->p, h->ng, ls.p, ls.n);
    }
    if (!vis) return v3s(0);
    return v3_scale(v3_mul(f, ls.L), cos_s / pl);
}
