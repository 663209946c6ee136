/* photonmapper.c: the photon-mapping integrators, "--mode pm" (Jensen's two-pass method with
 * final gathering) and "--mode preview" (the global map shown directly).
 *
 * PREPROCESS: pm_setup.c (settings, plan, hooks), pm_preprocess.c (maps, kd-trees, readers,
 * pass 0's camera-side decisions), pm_fit.c (photons, radii), pm_passes.c; none calls here back.
 *
 * RENDERING: Jensen's split of the rendering equation. A camera ray follows specular
 * reflection and refraction (both branches, weighted, for the first split_depth bounces;
 * after that one branch chosen at random in proportion to its weight, with Russian roulette
 * after rr_depth bounces) and adds emission it sees. At every surface with a
 * diffuse branch it adds
 *   - direct light: one light sample and a shadow ray; for area lights the k_shadow nearest
 *     photons of the shadow map decide first: all DIRECT means lit and the shadow ray is
 *     skipped; all SHADOW means probably dark, and the ray is skipped at random (see
 *     shadow_hint: a dark answer is never trusted outright) (the counts are in the statistics);
 *   - caustics: a radiance estimate from the caustic map with the scene's filter (none, cone,
 *     Gaussian, convex hull), photons from behind the surface rejected; with caustic_stride
 *     c > 1 only at one camera sample in c x c, a stratified subset, weighted c^2 (unbiased);
 *   - indirect diffuse: final gathering. gather_rays cosine-distributed rays (per camera
 *     sample, scaled down by the path's throughput after a weighted split, at least one)
 *     follow specular surfaces to the first diffuse surface y and read the precomputed
 *     irradiance of the photon nearest y with a similar normal, times y's diffuse
 *     reflectance / pi. Emission met by a gather ray is skipped (direct light and
 *     caustics count it). When the first gather hit is closer than secondary_distance (about
 *     the radius of a global-map estimate), the global map is too coarse there (the corner
 *     artefact of the Kilauea notes), so a secondary gather computes y's outgoing light from
 *     its own direct light, caustics and secondary_rays gather rays instead.
 *     Where the camera's points are photon-starved and a pilot finds an opening into a lit
 *     region (a room lit through a hole), gathers at every level aim a share of their rays at
 *     it, weighted by the mixture's density (gather_guide.h; the plan's "gather guide:" line).
 * Emission seen by the camera (directly or through mirrors and glass) comes from
 * emission_strata^2 extra camera rays per sample that look for nothing else (mapper_li), so the
 * edges of lights are antialiased at a fraction of the cost of full samples; where a delta
 * light's edge crosses a pixel, those rays take the first hit's direct light too (pm_sample.c,
 * DIRECT STRATA).
 * In preview mode, or with final gathering forced off, the diffuse surface shows the
 * global map's radiance estimate (k_global photons) plus emission, and nothing else; without
 * a global map it gets direct light and caustics only.
 *
 * Participating media (a scene with a medium or a null surface; pm_volume.h): the maps come
 * from volume.h's tracer instead (pmv_trace; or from load_photons, the volume maps of each
 * medium with them, photon_maps.h), eye rays march each segment through its medium
 * (pmv_march: single scattering by shadow rays, the volume maps' estimates, the segment's
 * transmittance on what lies beyond) and pass null surfaces without a bounce, gather rays take
 * one in-scatter sample per segment and its transmittance (pmv_gather), and direct light at
 * surfaces carries the transmittance of the shadow segment. A scene without media runs none of
 * this and renders the same image as before, bit for bit.
 *
 * Threads: li only reads the maps; each thread has its own scratch (estimate buffers).
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "photon_mapping/pm_internal.h"

const photon_lookup_hook *pm__lookup;

void photon_lookup_set_hook(const photon_lookup_hook *h) { pm__lookup = h; }

/* ---- helpers ------------------------------------------------------------------------------ */

/* w_D times the diffuse reflectance: the Lambertian part of the BSDF times pi. */
static rgb diffuse_albedo(const scene *s, const material *m, vec3 wo, vec3 ng) {
    double w[LOBE_COUNT];
    material_weights(m, wo, ng, s->medium_ior, w);
    return v3_scale(m->diffuse, w[LOBE_DIFFUSE]);
}

static int has_diffuse(const scene *s, const material *m, vec3 wo, vec3 ng) {
    double w[LOBE_COUNT];
    material_weights(m, wo, ng, s->medium_ior, w);
    return w[LOBE_DIFFUSE] > 0 && v3_maxc(m->diffuse) > 0;
}

static void to_f3(vec3 v, float f[3]) {
    f[0] = (float)v.x;
    f[1] = (float)v.y;
    f[2] = (float)v.z;
}

/* Radiance estimate from a map at x (normal ns, the side the viewer is on); through side_estimate
 * when sm is given (photons beyond a surface left out, photon_sides.h). */
static rgb map_estimate(const pm_kdtree *t, const side_map *sm, const pm_estimate_options *base, vec3 x,
                        vec3 ns, rgb albedo, void *scratch) {
    pm_estimate_options o = *base;
    float xf[3], nf[3], df[3];
    to_f3(x, xf);
    to_f3(ns, nf);
    to_f3(albedo, df);
    o.diffuse = df;
    pm_estimate_result res;
    if ((sm ? side_estimate(sm, xf, nf, &o, scratch, &res) : pm_estimate(t, xf, nf, &o, scratch, &res, NULL)) < 0)
        return v3s(0);
    return v3(res.rgb[0], res.rgb[1], res.rgb[2]);
}

/* Radiance estimate from the global or caustic map (a PHOTON_LOOKUP_*): this process's tree,
 * or through the lookup hook (the irradiance of all processes' parts, times the BRDF). */
static rgb estimate_at(const mapper_state *st, int which, vec3 x, vec3 ns, rgb albedo,
                       mapper_scratch *sc) {
    if (!pm__lookup)
        return which == PHOTON_LOOKUP_CAUSTIC
                   ? map_estimate(st->tc, &st->caus_side, &st->caus_opt, x, ns, albedo, sc->est)
                   : map_estimate(st->tg, st->glob_side.t ? &st->glob_side : NULL, &st->glob_opt, x, ns, albedo,
                                  sc->est);
    double e[3];
    pm__lookup->estimate(pm__lookup->user, sc->id, which, x, ns, e);
    return v3(albedo.x * e[0] / M_PI, albedo.y * e[1] / M_PI, albedo.z * e[2] / M_PI);
}

/* -1: trace the shadow ray; 1: the shadow map says lit; 0: it says dark. */
static int shadow_map_says(const mapper_state *st, vec3 x, vec3 ns, pm_neighbor *nb) {
    if (!st->ts) return -1;
    float xf[3], nf[3];
    to_f3(x, xf);
    to_f3(ns, nf);
    pm_knn_options ko = {0};
    ko.filter = side_filter_shadow; /* on the query's surface only (photon_sides.h) */
    ko.filter_user = nf;
    int n = pm_kdtree_knn_ex(st->ts, xf, (unsigned)st->cfg.k_shadow, st->r2_shadow, &ko, nb, NULL);
    if (n < st->cfg.k_shadow) return -1;
    const pm_photon *ph = pm_kdtree_records(st->ts);
    int direct = 0, shadow = 0;
    for (int i = 0; i < n; i++) {
        int k = pm_photon_kind(&ph[nb[i].index]);
        direct += k == PM_KIND_DIRECT;
        shadow += k == PM_KIND_SHADOW;
    }
    if (direct == n) return 1;
    if (shadow == n) return 0;
    return -1;
}

/* Of the samples whose shadow photons all say dark, the share that traces its shadow ray
 * anyway (and weighs a lit answer by its inverse). */
#define SHADOW_DARK_TRACE 0.5

/* The shadow-photon map as direct_light_surface's shadow hint (direct.h): for area lights the
 * k_shadow nearest shadow-map photons decide when they agree; the counters say how often.
 *
 * All DIRECT: lit, no ray. All SHADOW does not prove dark. Where a small opening lets a
 * little light through (a pinhole, a gap under a door), the point sees a small part of the
 * light, so only that small share of the photons arriving there are direct ones: with 1% of
 * the light visible, 16 neighbours are all shadow photons 85% of the time, and trusting them
 * blacked out the whole patch lit through the hole of pinhole_room (-32% of the image).
 * So a dark answer is a Russian roulette decision: the ray is traced at SHADOW_DARK_TRACE of
 * those samples and a lit result weighs 1 / SHADOW_DARK_TRACE, the others count as dark.
 * The expected value is the traced visibility, whatever the map says: the map only decides
 * where rays are saved, never the mean. Where the map is right (truly dark) skipping adds no
 * noise; where it is wrong the variance grows by 1 / SHADOW_DARK_TRACE. One half: the dark
 * answers save few rays (cornell_spheres: 2,616 of 56,258 shadow tests, the same render
 * time with shadow photons off), and at 1/8 the pinhole's lit patch read -64%..+127% over
 * four seeds (16x16, 64 spp) against -38%..+43% over eight when every ray is traced. */
typedef struct shadow_hint_ctx {
    const mapper_state *st;
    mapper_scratch *sc;
    rng *g;
    double weight; /* set by the hint: the factor of this light sample */
} shadow_hint_ctx;

static int shadow_hint(void *user, const scene *s, int li, const hit *h, vec3 n) {
    shadow_hint_ctx *c = user;
    int vis = s->lights[li].type == LIGHT_AREA ? shadow_map_says(c->st, h->p, n, c->sc->nb) : -1;
    if (vis == 0 && rng_uniform(c->g) < SHADOW_DARK_TRACE) {
        c->weight = 1.0 / SHADOW_DARK_TRACE;
        vis = -1;
    }
    if (vis == 1)
        stat_inc(c->st->st_saved_lit);
    else if (vis == 0)
        stat_inc(c->st->st_saved_dark);
    else
        stat_inc(c->st->st_traced);
    return vis;
}

/* Direct light at a diffuse point: one light sample (direct.h), weighted by the full BSDF
 * (the diffuse branch's weight included: no branch is chosen here). */
static rgb direct_light(const mapper_state *st, const scene *s, const material *m, const hit *h,
                        vec3 ns, vec3 wo, int med, rng *g, mapper_scratch *sc) {
    shadow_hint_ctx c = {st, sc, g, 1.0};
    direct_options o = {DIRECT_BSDF_FULL, st->vol.on, shadow_hint, &c, med, /* media: transmittance */
                        st->dport, st->dport_lit}; /* and through the port (direct.h) */
    /* the plan's light guide (guide.h; NULL: light samples as direct_light_surface draws them) */
    rgb L = direct_light_surface_guided(s, m, h, ns, wo, g, &o, st->plan.guide);
    return c.weight == 1.0 ? L : v3_scale(L, c.weight);
}

static rgb caustics_at(const mapper_state *st, const scene *s, const material *m, const hit *h,
                       vec3 ns, vec3 wo, mapper_scratch *sc) {
    if (!st->ncaustic_all) return v3s(0);
    stat_inc(st->st_caustic);
    return estimate_at(st, PHOTON_LOOKUP_CAUSTIC, h->p, ns, diffuse_albedo(s, m, wo, h->ng), sc);
}

/* Follow a ray through specular surfaces to the first diffuse hit. Returns the number of
 * specular bounces + 1 with the hit, the throughput and the direction of the last segment
 * (*din, pointing into the hit), or 0 if it escapes, is absorbed or runs out of bounces.
 * With media (st->vol.on; *medp: the medium at the start, then at the hit) null surfaces are
 * passed (scene_medium_next), each segment's transmittance multiplies the throughput and its
 * in-scattered light (pmv_gather, times the throughput) is added to *Lvol. */
static int to_diffuse(const mapper_state *st, const scene *s, ray r, int *medp, rng *g, hit *h, rgb *beta,
                      vec3 *din, rgb *Lvol, void *vscratch) {
    *beta = v3s(1);
    *din = r.d;
    for (int b = 0, crossings = 0; b < 8; b++) {
        int got = scene_intersect(s, r, INFINITY, h);
        if (st->vol.on) {
            rgb tr, Lm = pmv_gather(&st->vol, s, r, got ? h->t : INFINITY, *medp, g, vscratch, &tr);
            *Lvol = v3_add(*Lvol, v3_mul(*beta, Lm));
            *beta = v3_mul(*beta, tr);
            if (got && scene_material(s, h)->kind == MAT_NULL && crossings++ < 1024) {
                *medp = scene_medium_next(s, h, r.d, r.d, *medp);
                r.o = scene_offset(s, h->p, h->ng, r.d);
                b--;
                continue;
            }
        }
        if (!got) return 0;
        const material *m = scene_material(s, h);
        vec3 wo = v3_neg(r.d);
        *din = r.d;
        if (has_diffuse(s, m, wo, h->ng)) return b + 1;
        double w[LOBE_COUNT];
        material_weights(m, wo, h->ng, s->medium_ior, w);
        double ws = w[LOBE_REFLECT] + w[LOBE_TRANSMIT];
        if (!(ws > 0)) return 0;
        vec3 ns = v3_dot(wo, h->ng) >= 0 ? h->ng : v3_neg(h->ng);
        vec3 nsh = material_shading_side(wo, h->ng, h->ns);
        vec3 d;
        if (rng_uniform(g) * ws < w[LOBE_REFLECT]) {
            d = material_reflect_shaded(r.d, ns, nsh);
            *beta = v3_scale(v3_mul(*beta, m->specular_tint), ws);
        } else {
            double n1, n2;
            material_indices(m, wo, h->ng, s->medium_ior, &n1, &n2);
            if (!material_refract_shaded(r.d, ns, nsh, n1 / n2, &d)) d = material_reflect_shaded(r.d, ns, nsh);
            *beta = v3_scale(v3_mul(*beta, m->transmit_tint), ws);
        }
        if (v3_iszero(*beta)) return 0;
        if (st->vol.on) *medp = scene_medium_next(s, h, r.d, d, *medp);
        r.o = scene_offset(s, h->p, h->ng, d);
        r.d = d;
        stat_inc(STAT_INDIRECT_RAYS);
    }
    return 0;
}

/* Outgoing diffuse radiance at y toward wo from the precomputed irradiance of the nearest
 * precomputed photon with a similar normal that is within its own estimate radius of y and
 * on y's side of every surface (side_cache_lookup: a photon behind a wall holds another
 * room's light). *found = 0 when there is none. count = 0: not counted in the statistics (the
 * gather guide's pilot). */
static rgb lookup_radiance_ex(const mapper_state *st, const scene *s, const hit *h, vec3 wo, int *found,
                              int count) {
    *found = 0;
    if (!st->sides.irr) return v3s(0);
    const material *m = scene_material(s, h);
    vec3 ns = v3_dot(wo, h->ng) >= 0 ? h->ng : v3_neg(h->ng);
    float e[3];
    if (count) stat_inc(st->st_lookup);
    /* Within the lookup radius (photon_maps.h), and each candidate within its own estimate
     * radius. A wider search (the global radius) lets lookups beside a wall wade through every
     * photon behind it: 40x the render time on pinhole_room. */
    if (!side_cache_lookup(&st->sides, s, h->p, ns, st->r2_lookup, e)) return v3s(0);
    *found = 1;
    rgb a = diffuse_albedo(s, m, wo, h->ng);
    return v3(a.x * e[0] / M_PI, a.y * e[1] / M_PI, a.z * e[2] / M_PI);
}

static rgb lookup_radiance(const mapper_state *st, const scene *s, const hit *h, vec3 wo, int *found) {
    return lookup_radiance_ex(st, s, h, wo, found, 1);
}

/* The gather guide (gather_guide.h) reads the map through these, for its pilot: the lookup as the
 * gather makes it (not counted), and a gather ray read as the gather reads it (one light sample).
 * Without the port's join (direct.h), unlike the passes: a probe is bright against its point's
 * total, which the join raises (it reads every room point's direct light), leaving fewer bright
 * rays. With it lamp_shade's small pilot (32 x 32 x 4) found 10, under 64, and the full one ran:
 * 1.87 CPU-s for the render, 0.88 without; same decision, same error (16 x 16, 10 s, seeds 1-3). */
int pm__gg_found(void *user, const scene *s, const hit *h, vec3 wo) {
    int found;
    lookup_radiance_ex(user, s, h, wo, &found, 0);
    return found;
}

int pm__gg_read(void *user, const scene *s, const guide_point *pt, vec3 d, rng *g, gather_guide_read *out) {
    const mapper_state *st = user;
    rgb f = material_f(scene_material(s, &pt->h), pt->h.ng, s->medium_ior, pt->wo, d);
    if (v3_iszero(f)) return 0;
    ray r = {scene_offset(s, pt->h.p, pt->h.ng, d), d};
    hit y;
    rgb beta, Lvol = v3s(0);
    vec3 din;
    if (!to_diffuse(st, s, r, &(int){-1}, g, &y, &beta, &din, &Lvol, NULL)) return 0;
    int found;
    vec3 ny = v3_dot(din, y.ng) <= 0 ? y.ng : v3_neg(y.ng);
    rgb Lo = lookup_radiance_ex(st, s, &y, v3_neg(din), &found, 0);
    if (!found || st->sides.indirect_only) { /* without the port's join: see above */
        direct_options o = {DIRECT_BSDF_FULL, 0, NULL, NULL, -1, NULL, {0, 0, 0}};
        Lo = v3_add(Lo, direct_light_surface_guided(s, scene_material(s, &y), &y, ny, v3_neg(din), g, &o,
                                                    st->plan.guide));
    }
    rgb fb = v3_scale(v3_mul(f, beta), M_PI);
    out->value = rgb_lum(v3_mul(fb, Lo));
    out->weight = rgb_lum(fb);
    out->found = found;
    out->y = y.p;
    out->ny = ny;
    return 1;
}

/* Indirect diffuse at a diffuse point by gathering n rays; level 0 for the gather of a camera
 * path, level >= 1 inside a secondary gather (its rays read the map, or recurse where the map
 * has nothing, see gather). ms: the miss survival this chain has still to apply. */
static rgb gather(const mapper_state *st, const scene *s, const material *m, const hit *h, vec3 ns,
                  vec3 wo, int n, int level, double ms, int med, rng *g, mapper_scratch *sc);

/* Outgoing light at a gather hit y, computed instead of read from the map: y's direct light,
 * caustics and a gather of its own at `level` (secondary_rays rays at level 1, one ray deeper,
 * so a chain of them costs one ray per bounce, like a path). */
static rgb secondary_radiance(const mapper_state *st, const scene *s, const hit *y, vec3 wo, int level,
                              double ms, int med, rng *g, mapper_scratch *sc) {
    const material *m = scene_material(s, y);
    vec3 ns = v3_dot(wo, y->ng) >= 0 ? y->ng : v3_neg(y->ng);
    rgb L = direct_light(st, s, m, y, ns, wo, med, g, sc);
    L = v3_add(L, caustics_at(st, s, m, y, ns, wo, sc));
    int n = level <= 1 ? st->cfg.secondary_rays : 1;
    return v3_add(L, gather(st, s, m, y, ns, wo, n, level, ms, med, g, sc));
}

static rgb gather(const mapper_state *st, const scene *s, const material *m, const hit *h, vec3 ns,
                  vec3 wo, int n, int level, double ms, int med, rng *g, mapper_scratch *sc) {
    if (n <= 0 || !st->sides.irr) return v3s(0);
    rgb sum = v3s(0);
    vec3 nsh = material_shading_side(wo, h->ng, h->ns);
    /* The gather guide (gather_guide.h): the share aimed at the opening; 0: cosine sampling,
     * the same numbers drawn as without the guide. */
    double aim = gather_guide_share(&st->gg, h->p, ns);
    for (int k = 0; k < n; k++) {
        /* Stratified over the hemisphere: n strata in the first coordinate. */
        double u1 = (k + rng_uniform(g)) / n, u2 = rng_uniform(g), wk = 1;
        vec3 d;
        if (aim > 0) {
            d = gather_guide_direction(&st->gg, aim, h->p, nsh, u1, u2, g, &wk);
            if (!(wk > 0)) continue;
        } else
            d = sampling_to_world(sample_cosine_hemisphere(u1, u2), nsh);
        if (v3_dot(d, ns) <= 0) continue;
        rgb f = material_f(m, h->ng, s->medium_ior, wo, d);
        if (v3_iszero(f)) continue;
        stat_inc(level ? st->st_secondary : st->st_gather);
        stat_inc(STAT_INDIRECT_RAYS);
        ray r = {scene_offset(s, h->p, h->ng, d), d};
        hit y;
        rgb beta;
        vec3 din;
        rgb Lvol = v3s(0);
        int ymed = st->vol.on ? scene_medium_side(s, h, d, med) : -1;
        int steps = to_diffuse(st, s, r, &ymed, g, &y, &beta, &din, &Lvol, sc->est);
        if (st->vol.on) sum = v3_add(sum, v3_scale(v3_mul(f, Lvol), wk));
        if (!steps) continue;
        /* y is seen from -din, the last segment's direction (not d after a mirror). */
        rgb Lo;
        int found = 0;
        if (!level && steps == 1 && y.t < st->sec_dist)
            Lo = secondary_radiance(st, s, &y, v3_neg(din), 1, ms, ymed, g, sc);
        else {
            Lo = lookup_radiance(st, s, &y, v3_neg(din), &found);
            /* The cache holds indirect irradiance only (photon_sides.h, "Direct light"): y's
             * direct light comes from a light sample, so shadow edges stay sharp. */
            if (found && st->sides.indirect_only)
                Lo = v3_add(Lo, direct_light(st, s, scene_material(s, &y), &y,
                                             v3_dot(din, y.ng) <= 0 ? y.ng : v3_neg(y.ng), v3_neg(din), ymed, g, sc));
            /* No precomputed value on y's side within reach: y is in a photon-starved
             * region (behind a wall from every nearby photon, or a room that light enters
             * through a pinhole, where a map of any practical size holds a handful of
             * photons). Compute its light instead. Inside a secondary gather that recurses:
             * one ray per level, continued by Russian roulette on y's diffuse albedo, so
             * where the map has nothing the gather becomes a path tracer. (Counting such y
             * as dark, as this did, dropped every bounce after the second: -18% on
             * pinhole_room, with the shadow photons off.) The chain's first miss computes
             * it with chance ms only, weighted 1/ms, and passes 1 down (MISS SURVIVAL,
             * pm_sample.c); ms = 1 draws no number. */
            if (!found) {
                stat_inc(st->st_lookup_miss);
                double q = ms < 1 ? ms : 1; /* the survival: ms, times y's albedo below level 0 */
                if (level) q *= fmin(0.95, v3_maxc(diffuse_albedo(s, scene_material(s, &y), v3_neg(din), y.ng)));
                if ((!level || level < st->max_depth) && (q >= 1 || rng_uniform(g) < q))
                    Lo = v3_scale(secondary_radiance(st, s, &y, v3_neg(din), level + 1, 1, ymed, g, sc), 1.0 / q);
            }
        }
        /* cosine sampling: f cos / pdf = pi f (times wk when guided) */
        rgb c = v3_mul(v3_mul(f, beta), Lo);
        sum = v3_add(sum, wk != 1 ? v3_scale(c, wk) : c);
    }
    return v3_scale(sum, M_PI / n);
}

/* ---- the integrator ----------------------------------------------------------------------- */

/* The weight of this camera sample's caustic estimates (stride caustic_stride, stream
 * "caustics") or of its in-scattering in media (volume_stride, "volume"): with a stride c > 1
 * only some of a pixel's samples read them (pm_caustic_weight, pm_sample.h), at an offset drawn
 * per pixel. */
static double stride_weight(const sample_id *id, int c, uint64_t stream) {
    if (c <= 1 || !id || id->strata < c) return 1.0;
    rng g = rng_stream(id->seed, id->pixel, stream);
    double u = rng_uniform(&g), v = rng_uniform(&g);
    return pm_caustic_weight(id->strata, c, id->k, u, v);
}

/* What an eye path collects (bits): the emission it meets; the direct light at its first hit
 * (a diffuse camera hit, no specular bounce before it); everything else it shades (direct light
 * further on, caustics, gathers, media). A camera sample's parts add up to EYE_ALL. */
enum { EYE_EMIT = 1, EYE_DIRECT0 = 2, EYE_REST = 4, EYE_SHADE = EYE_DIRECT0 | EYE_REST, EYE_ALL = 7 };

/* Russian roulette for an eye path after rr_depth bounces: 0 ends the path. */
static int eye_roulette(const mapper_state *st, int depth, rgb *beta, rng *g) {
    double urr = rng_uniform(g);
    if (depth + 1 < st->rr_depth) return 1;
    double q = fmin(0.95, v3_maxc(*beta));
    if (!(urr < q)) {
        stat_inc(STAT_RR_TERMINATED);
        return 0;
    }
    *beta = v3_scale(*beta, 1.0 / q);
    return 1;
}

/* Radiance along an eye ray r whose throughput so far is beta (the light found is returned
 * already multiplied by beta). Specular surfaces are followed; at the first split_depth
 * bounces a surface with both a reflection and a transmission branch (glass) sends a ray
 * down each, weighted, instead of choosing one at random: a camera ray on the glass sphere
 * then sees the reflected light and the refracted room together, and that choice adds no
 * noise. Gathering spends rays in proportion to the throughput (at least one), so the faint
 * reflection branch of glass costs little. `what` says what the path collects: emission it
 * meets, the shading of diffuse surfaces, or both. */

static rgb eye_radiance(const mapper_state *st, const scene *s, ray r, int depth, rgb beta,
                        double cw, int what, int med, rng *g, mapper_scratch *sc) {
    rgb L = v3s(0);
    int crossings = 0;
    for (;; depth++) {
        hit h;
        int got = scene_intersect(s, r, INFINITY, &h);
        if (st->vol.on) { /* media: march the segment in med; null surfaces are passed */
            rgb tr;
            L = v3_add(L, pmv_march_eye(&st->vol, s, r, got ? h.t : INFINITY, med, (what & EYE_REST) != 0, beta, sc->vw, g,
                                            sc->est, sc->pc, &tr));
            beta = v3_mul(beta, tr);
            if (got && scene_material(s, &h)->kind == MAT_NULL) {
                if (++crossings > 1024 || v3_iszero(beta)) break;
                med = scene_medium_next(s, &h, r.d, r.d, med);
                r.o = scene_offset(s, h.p, h.ng, r.d);
                depth--; /* not a bounce */
                continue;
            }
        }
        if (!got) { if ((what & EYE_EMIT) && s->env_light) L = v3_add(L, v3_mul(beta, light_env_radiance(s, r.d))); break; }
        stat_inc(STAT_PATH_VERTICES);
        const material *m = scene_material(s, &h);
        vec3 wo = v3_neg(r.d);
        if ((what & EYE_EMIT) && material_is_emissive(m) && (v3_dot(wo, h.ng) > 0 || m->two_sided))
            L = v3_add(L, v3_mul(beta, m->emission));
        vec3 ns = v3_dot(wo, h.ng) >= 0 ? h.ng : v3_neg(h.ng);
        double w[LOBE_COUNT];
        material_weights(m, wo, h.ng, s->medium_ior, w);
        int direct = depth == 0 ? (what & EYE_DIRECT0) != 0 : (what & EYE_REST) != 0;
        if ((direct || (what & EYE_REST)) && w[LOBE_DIFFUSE] > 0 && v3_maxc(m->diffuse) > 0) {
            rgb Ld = v3s(0);
            if (st->direct_vis) {
                stat_inc(st->st_global_est);
                Ld = st->nglobal_all ? estimate_at(st, PHOTON_LOOKUP_GLOBAL, h.p, ns,
                                                   diffuse_albedo(s, m, wo, h.ng), sc)
                                     : v3s(0);
            } else {
                if (direct) Ld = direct_light(st, s, m, &h, ns, wo, med, g, sc);
                if (!(what & EYE_REST)) {
                    L = v3_add(L, v3_mul(beta, Ld));
                    if (!(what & EYE_EMIT)) break; /* the first hit's direct light alone */
                    goto next;
                }
                if (cw > 0) {
                    rgb Lc = caustics_at(st, s, m, &h, ns, wo, sc);
                    Ld = v3_add(Ld, v3_scale(Lc, cw));
                    if (sc->pc && st->ncaustic_all) {
                        sc->pc->L = v3_add(sc->pc->L, v3_mul(beta, Lc));
                        sc->pc->n++;
                    }
                }
                if (st->plan.final_gather.on) {
                    double share = fmin(1.0, v3_maxc(beta));
                    int n = (int)ceil(st->cfg.gather_rays * share);
                    if (st->cfg.gather_rays > 0 && n < 1) n = 1;
                    Ld = v3_add(Ld, gather(st, s, m, &h, ns, wo, n, 0, st->cfg.miss_survival, med, g, sc));
                }
            }
            L = v3_add(L, v3_mul(beta, Ld));
        }
    next:;
        if (!(what & (EYE_EMIT | EYE_REST))) break; /* the first hit's direct light was all */
        double ws = w[LOBE_REFLECT] + w[LOBE_TRANSMIT];
        if (!(ws > 0) || depth >= st->max_depth) break;
        vec3 nsh = material_shading_side(wo, h.ng, h.ns);
        vec3 dr = material_reflect_shaded(r.d, ns, nsh), dt;
        double n1, n2;
        material_indices(m, wo, h.ng, s->medium_ior, &n1, &n2);
        int tir = w[LOBE_TRANSMIT] > 0 && !material_refract_shaded(r.d, ns, nsh, n1 / n2, &dt);
        if (tir) stat_inc(STAT_TIR);
        rgb br = v3_scale(v3_mul(beta, m->specular_tint), w[LOBE_REFLECT]);
        rgb bt = v3_scale(v3_mul(beta, m->transmit_tint), w[LOBE_TRANSMIT]);
        if (tir) { /* the transmitted share is reflected instead */
            br = v3_add(br, bt);
            bt = v3s(0);
        }
        if (v3_iszero(br) && v3_iszero(bt)) break;
        stat_inc(STAT_SPECULAR_BOUNCES);
        vec3 d;
        if (depth < st->cfg.split_depth && !v3_iszero(br) && !v3_iszero(bt)) {
            /* Split: the reflection branch recursively, the transmission branch here. */
            if (eye_roulette(st, depth, &br, g)) {
                ray rr = {scene_offset(s, h.p, h.ng, dr), dr};
                stat_inc(STAT_INDIRECT_RAYS);
                L = v3_add(L, eye_radiance(st, s, rr, depth + 1, br, cw, what,
                                           st->vol.on ? scene_medium_next(s, &h, r.d, dr, med) : -1, g, sc));
            }
            beta = bt;
            d = dt;
        } else {
            /* One branch, chosen in proportion to its weight (w / p = the weights' sum). */
            double pr = v3_maxc(br) / (v3_maxc(br) + v3_maxc(bt));
            if (rng_uniform(g) < pr) {
                d = dr;
                beta = v3_scale(br, 1.0 / pr);
            } else {
                d = dt;
                beta = v3_scale(bt, 1.0 / (1.0 - pr));
            }
        }
        if (!eye_roulette(st, depth, &beta, g) || v3_iszero(beta)) break;
        if (st->vol.on) med = scene_medium_next(s, &h, r.d, d, med);
        r.o = scene_offset(s, h.p, h.ng, d);
        r.d = d;
        stat_inc(STAT_INDIRECT_RAYS);
    }
    return L;
}

/* A camera sample. With emission_strata m > 0, the emission the camera sees (directly or in
 * mirrors and glass) is not taken from the sample's own path but from m x m extra camera
 * rays, one in each sub-stratum of the sample's stratum, that look for emission alone (and,
 * at the pixels of emit.direct, for the direct light at their first hit, which the sample's
 * own path then leaves out: pm_sample.c, DIRECT STRATA). The
 * pixel integral is the same sum of two parts, each estimated without bias, but the bright
 * edges of a light, where the coverage of a pixel is what varies, get m^2 times the camera
 * rays for the price of a few ray casts instead of m^2 full shading samples. */
rgb pm__li(const integrator *self, const scene *s, ray r, rng *g, const sample_id *id,
                 void *scratch) {
    const mapper_state *st = self->data;
    mapper_scratch *sc = scratch;
    if (sc) sc->id = id, sc->vw = stride_weight(id, st->cfg.volume_stride, 0x766f6c756d65ULL); /* "volume" */
    int m = st->cfg.emission_strata;
    double cw = stride_weight(id, st->cfg.caustic_stride, 0x6361757374696373ULL); /* "caustics" */
    int split = 0; /* the parts the m x m extra rays take (pm_sample.c, EMISSION and DIRECT STRATA) */
    if (m > 0 && id && id->strata > 0 && !id->focused) { /* a focused sample collects its own */
        int in = id->pixel < st->emit.pixels;
        if (!st->emit.mask || (in && st->emit.mask[id->pixel])) split |= EYE_EMIT;
        if (st->emit.direct && in && st->emit.direct[id->pixel]) split |= EYE_DIRECT0;
    }
    if (!split) return eye_radiance(st, s, r, 0, v3s(1), cw, EYE_ALL, s->camera_medium, g, scratch);
    rgb L = eye_radiance(st, s, r, 0, v3s(1), cw, EYE_ALL & ~split, s->camera_medium, g, scratch);
    rgb E = v3s(0);
    int n = id->strata, W = s->cam.width;
    double x = (double)(id->pixel % (uint64_t)W), y = (double)(id->pixel / (uint64_t)W);
    double sx = id->k % n, sy = id->k / n;
    for (int b = 0; b < m; b++)
        for (int a = 0; a < m; a++) {
            double u = rng_uniform(g), v = rng_uniform(g);
            ray re = camera_ray(&s->cam, x + (sx + (a + u) / m) / n, y + (sy + (b + v) / m) / n);
            stat_inc(st->st_emission_rays);
            E = v3_add(E, eye_radiance(st, s, re, 0, v3s(1), 0, split, s->camera_medium, g, scratch));
        }
    return v3_add(L, v3_scale(E, 1.0 / (m * m)));
}

/* An eye ray for pm_sample.c (pm_internal.h; eye_radiance adds the camera path's caustics to
 * sc->pc). */
rgb pm__sample_eye(void *user, ray r, int emit, rng *g, void *scratch, pm_sample_caustics *pc) {
    const mapper_state *st = user;
    mapper_scratch *sc = scratch;
    const scene *s = st->scene;
    sc->pc = pc;
    sc->vw = 1;
    int what = emit == 2 ? EYE_DIRECT0 : emit ? EYE_EMIT : EYE_SHADE;
    rgb L = eye_radiance(st, s, r, 0, v3s(1), emit ? 0 : 1.0, what, s->camera_medium, g, sc);
    sc->pc = NULL;
    return L;
}
