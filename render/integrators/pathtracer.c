/* pathtracer.c: the path-traced reference integrator ("--mode path").
 *
 * This is the ground truth that photon mapping is judged against, so it is plain and
 * unbiased:
 *   - at each hit one material branch is chosen in proportion to its weight R, (1-R)T,
 *     (1-R)(1-T) (material.h), so the weight/probability ratio is 1;
 *   - on the diffuse branch, next-event estimation (direct.h): one light chosen in proportion to its
 *     power, one point on it, a shadow ray; the area pdf becomes a solid-angle pdf through
 *     dist^2 / (cos_light A) (light.c). The continuation is cosine-weighted;
 *   - emission seen directly, or after a specular bounce, is added; after a diffuse bounce
 *     the emission of lights (emissive triangles and spheres) is skipped because next-event
 *     estimation already counted it. A ray that leaves the scene sees the infinite light
 *     (light.h), by the same rule;
 *   - Russian roulette after rr_depth bounces with survival probability min(0.95, max
 *     channel of the throughput), dividing the throughput by it; a hard limit max_depth.
 * Caustics from small lights are therefore found only by paths that happen to hit the light
 * after a specular chain: correct but noisy, which is the point of comparing with photon maps.
 *
 * Random numbers come only from the sample's own stream, in a fixed order per bounce
 * (lobe, direction (2), light choice, light point (2), roulette), so an image does not
 * depend on the thread count.
 *
 * Participating media (medium.h), only in scenes that have a medium or a null surface (the
 * others run the loop above unchanged, bit for bit): the path knows the medium it is in (the
 * camera's, then as each surface's interface says: scene_medium_next, medium.h). In a
 * medium, free-flight sampling draws a distance (channel, distance: 2 numbers); a scattering event before the next surface
 * counts as a bounce: next-event estimation with the HG phase function and the transmittance
 * of the shadow segment, then an HG direction (2 numbers), then roulette. The single scattering
 * of every segment in a medium (while the depth allows a bounce) has a second strategy: one
 * equiangular sample toward a point on a light (direct.h: 4 numbers, drawn after the free-flight
 * pair), combined with the free-flight event's next-event estimate by the balance heuristic
 * against the free-flight density mean(sigma_t Tr(t)); near a light (1 / dist^2) the
 * equiangular sample carries the light, and fog under a lamp no longer gives fireflies. Otherwise the ray
 * reaches the surface with weight Tr / P(reach). Null surfaces are crossed without a bounce
 * (the medium changes); shadow rays from surfaces and media carry the transmittance through
 * media and null surfaces and stop at anything else.
 */
#include <stdlib.h>

#include "integrators/direct.h"
#include "integrators/integrator.h"
#include "scene/medium.h"
#include "base/stats.h"
#include "photonmap/common.h"

typedef struct {
    int max_depth, rr_depth;
} pt_state;

/* No media: the shadow test is plain visibility (the medium-free images stay bit-identical). */
#define NO_MEDIA (-2)

/* Russian roulette after rr_depth bounces; 0 if the path ends. */
static int roulette(const pt_state *st, int depth, rgb *beta, rng *g) {
    double urr = rng_uniform(g);
    if (depth + 1 >= st->rr_depth) {
        double q = fmin(0.95, v3_maxc(*beta));
        if (!(urr < q)) {
            stat_inc(STAT_RR_TERMINATED);
            return 0;
        }
        *beta = v3_scale(*beta, 1.0 / q);
    }
    return 1;
}

/* A path's running sums: radiance, throughput, and whether the next emitter hit counts. */
typedef struct {
    rgb L, beta;
    int count_emission;
} pt_path;

/* The surface event at h for a path arriving along r->d, at bounce depth: emission, the depth
 * limit, one material branch (next-event estimation on the diffuse branch, its shadow test per
 * med: NO_MEDIA or the medium-aware one), roulette; the continuation in *r. 0 when the path
 * ends. */
static int surface_event(const pt_state *st, const scene *s, const hit *h, ray *r, int depth, int med,
                         pt_path *pp, rng *g) {
    stat_inc(STAT_PATH_VERTICES);
    const material *m = scene_material(s, h);
    vec3 wo = v3_neg(r->d);
    if (material_is_emissive(m) && (v3_dot(wo, h->ng) > 0 || m->two_sided) &&
        (pp->count_emission || !scene_prim_is_light(s, h->prim)))
        pp->L = v3_add(pp->L, v3_mul(pp->beta, m->emission));
    if (depth >= st->max_depth) {
        stat_inc(STAT_MAXDEPTH);
        return 0;
    }
    double ul = rng_uniform(g), u1 = rng_uniform(g), u2 = rng_uniform(g);
    bsdf_sample bs;
    int alive = material_sample_ns(m, wo, h->ng, h->ns, s->medium_ior, ul, u1, u2, &bs);
    if (bs.lobe == LOBE_DIFFUSE) {
        vec3 n = v3_dot(wo, h->ng) >= 0 ? h->ng : v3_neg(h->ng);
        direct_options o = {DIRECT_BSDF_DIFFUSE_LOBE, med != NO_MEDIA, NULL, NULL, med, NULL, {0, 0, 0}};
        pp->L = v3_add(pp->L, v3_mul(pp->beta, direct_light_surface(s, m, h, n, wo, g, &o)));
        pp->count_emission = 0;
    } else {
        pp->count_emission = 1;
        stat_inc(STAT_SPECULAR_BOUNCES);
        if (bs.tir) stat_inc(STAT_TIR);
    }
    if (!alive) return 0;
    pp->beta = v3_mul(pp->beta, bs.weight);
    if (!roulette(st, depth, &pp->beta, g)) return 0;
    r->o = scene_offset(s, h->p, h->ng, bs.wi);
    r->d = bs.wi;
    stat_inc(STAT_INDIRECT_RAYS);
    return 1;
}

/* A ray that leaves the scene along d sees the infinite light (light.h), counted as the emission
 * of other lights is: on camera rays and after specular bounces. */
static void escape(const scene *s, vec3 d, pt_path *pp) {
    if (s->env_light && pp->count_emission) pp->L = v3_add(pp->L, v3_mul(pp->beta, light_env_radiance(s, d)));
}

/* The density of medium_sample_distance's scattering distance t (before the surface): the
 * mean over the channels of sigma_t Tr(t). */
static double free_flight_pdf(const void *user, double t) {
    const medium *md = user;
    rgb tr = medium_tr(md, t);
    return (md->sigma_t.x * tr.x + md->sigma_t.y * tr.y + md->sigma_t.z * tr.z) / 3;
}

/* The path loop of a scene with media or null surfaces (the top of the file). */
static rgb pt_li_media(const pt_state *st, const scene *s, ray r, rng *g) {
    pt_path pp = {v3s(0), v3s(1), 1};
    int med = s->camera_medium, crossings = 0;
    for (int depth = 0;; depth++) {
        hit h;
        int got = scene_intersect(s, r, INFINITY, &h);
        if (med >= 0) {
            const medium *md = &s->media[med];
            direct_segment seg = {r, got ? h.t : INFINITY, med, depth < st->max_depth && !v3_iszero(md->sigma_s)};
            double uc = rng_uniform(g), ud = rng_uniform(g), t;
            rgb w;
            int scatter = medium_sample_distance(md, seg.t1, uc, ud, &t, &w);
            /* The segment's equiangular sample (direct.h), weighted against free flight. */
            if (seg.m) pp.L = v3_add(pp.L, v3_mul(pp.beta, direct_light_equiangular(s, &seg, free_flight_pdf, md, g)));
            pp.beta = v3_mul(pp.beta, w);
            if (v3_iszero(pp.beta)) break;
            if (scatter) {
                stat_inc(STAT_PATH_VERTICES);
                if (depth >= st->max_depth) {
                    stat_inc(STAT_MAXDEPTH);
                    break;
                }
                vec3 p = ray_at(r, t);
                pp.L = v3_add(pp.L, v3_mul(pp.beta, direct_light_medium_mis(s, &seg, t, free_flight_pdf(md, t), g)));
                pp.count_emission = 0;
                double u1 = rng_uniform(g), u2 = rng_uniform(g);
                vec3 nd;
                hg_sample(s->media[med].g, r.d, u1, u2, &nd); /* weight phase / pdf = 1 */
                if (!roulette(st, depth, &pp.beta, g)) break;
                r.o = p;
                r.d = nd;
                stat_inc(STAT_INDIRECT_RAYS);
                continue;
            }
        }
        if (!got) {
            escape(s, r.d, &pp);
            break;
        }
        if (scene_material(s, &h)->kind == MAT_NULL) { /* invisible: only the medium changes */
            if (++crossings > 4 * st->max_depth + 1024) break;
            med = scene_medium_next(s, &h, r.d, r.d, med);
            r.o = scene_offset(s, h.p, h.ng, r.d);
            depth--; /* not a bounce */
            continue;
        }
        vec3 din = r.d;
        if (!surface_event(st, s, &h, &r, depth, med, &pp, g)) break;
        med = scene_medium_next(s, &h, din, r.d, med);
    }
    return pp.L;
}

static rgb pt_li(const integrator *self, const scene *s, ray r, rng *g, const sample_id *id,
                 void *scratch) {
    (void)id;
    (void)scratch;
    const pt_state *st = self->data;
    if (scene_has_media(s)) return pt_li_media(st, s, r, g);
    pt_path pp = {v3s(0), v3s(1), 1};
    for (int depth = 0;; depth++) {
        hit h;
        if (!scene_intersect(s, r, INFINITY, &h)) {
            escape(s, r.d, &pp);
            break;
        }
        if (!surface_event(st, s, &h, &r, depth, NO_MEDIA, &pp, g)) break;
    }
    return pp.L;
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
