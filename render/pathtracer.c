/* pathtracer.c: the path-traced reference integrator ("--mode path").
 *
 * This is the ground truth that photon mapping is judged against, so it is plain and
 * unbiased:
 *   - at each hit one material branch is chosen in proportion to its weight R, (1-R)T,
 *     (1-R)(1-T) (material.h), so the weight/probability ratio is 1;
 *   - on the diffuse branch, next-event estimation: one light chosen in proportion to its
 *     power, one point on it, a shadow ray; the area pdf becomes a solid-angle pdf through
 *     dist^2 / (cos_light A) (light.c). The continuation is cosine-weighted;
 *   - emission seen directly, or after a specular bounce, is added; after a diffuse bounce
 *     the emission of lights (emissive triangles and spheres) is skipped because next-event
 *     estimation already counted it;
 *   - Russian roulette after rr_depth bounces with survival probability min(0.95, max
 *     channel of the throughput), dividing the throughput by it; a hard limit max_depth.
 * Caustics from small lights are therefore found only by paths that happen to hit the light
 * after a specular chain: correct but noisy, which is the point of comparing with photon maps.
 *
 * Random numbers come only from the sample's own stream, in a fixed order per bounce
 * (lobe, direction (2), light choice, light point (2), roulette), so an image does not
 * depend on the thread count.
 */
#include <stdlib.h>

#include "integrator.h"
#include "stats.h"
#include "photonmap/common.h"

typedef struct {
    int max_depth, rr_depth;
} pt_state;

/* Direct light at a diffuse hit: f * Li * cos / (pdf_omega * p_light). */
static rgb direct_light(const scene *s, const material *m, const hit *h, vec3 n, vec3 wo, rng *g) {
    vec3 nsh = material_shading_side(wo, h->ng, h->ns); /* cosines; n (geometric) keeps the side */
    double ulight = rng_uniform(g), u1 = rng_uniform(g), u2 = rng_uniform(g);
    if (s->nlights == 0 || s->light_distrib.n == 0) return v3s(0);
    double pl;
    int li = distrib1d_sample(&s->light_distrib, ulight, &pl);
    if (!(pl > 0)) return v3s(0);
    light_sample ls;
    if (!light_sample_li(s, li, h->p, u1, u2, &ls)) return v3s(0);
    double cos_s = v3_dot(ls.wi, nsh);
    if (cos_s <= 0 || v3_dot(ls.wi, n) <= 0 || v3_iszero(ls.L)) return v3s(0);
    rgb f = material_diffuse_f(m, nsh, wo, ls.wi);
    if (v3_iszero(f)) return v3s(0);
    stat_inc(STAT_SHADOW_RAYS);
    const light *l = &s->lights[li];
    int vis;
    if (l->type == LIGHT_DIRECTIONAL)
        vis = scene_visible_dir(s, h->p, h->ng, ls.wi);
    else
        vis = scene_visible(s, h->p, h->ng, ls.p, ls.n);
    if (!vis) return v3s(0);
    return v3_scale(v3_mul(f, ls.L), cos_s / pl);
}

static rgb pt_li(const integrator *self, const scene *s, ray r, rng *g, const sample_id *id,
                 void *scratch) {
    (void)id;
    (void)scratch;
    const pt_state *st = self->data;
    rgb L = v3s(0), beta = v3s(1);
    int count_emission = 1;
    for (int depth = 0;; depth++) {
        hit h;
        if (!scene_intersect(s, r, INFINITY, &h)) break;
        stat_inc(STAT_PATH_VERTICES);
        const material *m = scene_material(s, &h);
        vec3 wo = v3_neg(r.d);
        if (material_is_emissive(m) && (v3_dot(wo, h.ng) > 0 || m->two_sided) &&
            (count_emission || !scene_prim_is_light(s, h.prim)))
            L = v3_add(L, v3_mul(beta, m->emission));
        if (depth >= st->max_depth) {
            stat_inc(STAT_MAXDEPTH);
            break;
        }
        double ul = rng_uniform(g), u1 = rng_uniform(g), u2 = rng_uniform(g);
        bsdf_sample bs;
        int alive = material_sample_ns(m, wo, h.ng, h.ns, s->medium_ior, ul, u1, u2, &bs);
        if (bs.lobe == LOBE_DIFFUSE) {
            vec3 n = v3_dot(wo, h.ng) >= 0 ? h.ng : v3_neg(h.ng);
            L = v3_add(L, v3_mul(beta, direct_light(s, m, &h, n, wo, g)));
            count_emission = 0;
        } else {
            count_emission = 1;
            stat_inc(STAT_SPECULAR_BOUNCES);
            if (bs.tir) stat_inc(STAT_TIR);
        }
        if (!alive) break;
        beta = v3_mul(beta, bs.weight);
        double urr = rng_uniform(g);
        if (depth + 1 >= st->rr_depth) {
            double q = fmin(0.95, v3_maxc(beta));
            if (!(urr < q)) {
                stat_inc(STAT_RR_TERMINATED);
                break;
            }
            beta = v3_scale(beta, 1.0 / q);
        }
        r.o = v3_offset(h.p, h.ng, bs.wi);
        r.d = bs.wi;
        stat_inc(STAT_INDIRECT_RAYS);
    }
    return L;
}

static void pt_destroy(integrator *self) { free(self->data); }

static int pt_create(integrator *it, const scene *s, char *err, size_t errcap) {
    pt_state *st = malloc(sizeof *st);
    if (!st) {
        snprintf(err, errcap, "out of memory");
        return PM_ENOMEM;
    }
    st->max_depth = s->settings.max_depth;
    st->rr_depth = s->settings.rr_depth;
    it->data = st;
    it->li = pt_li;
    it->destroy = pt_destroy;
    return 0;
}

INTEGRATOR_REGISTER(path, "path", "path tracing with next-event estimation (the reference)", pt_create)
