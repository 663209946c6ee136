/* photonmapper.c: the photon-mapping integrators, "--mode pm" (Jensen's two-pass method with
 * final gathering) and "--mode preview" (the global map shown directly).
 *
 * PREPROCESS. Read the settings ("$.photon_mapping", photon_settings.h), decide and print
 * the plan (plan.h), then either trace the maps (photon_trace.h) or load them from a directory (load_photons),
 * optionally save them as traced (save_photons), build a kd-tree over each (the records are
 * reordered into tree order), choose the search radii (map files, trees and radii:
 * photon_maps.h), and precompute irradiance at a quarter of the global photons (Christensen).
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
 *     it, weighted by the mixture's density (see GATHER GUIDE; the plan's "gather guide:" line).
 * Emission seen by the camera (directly or through mirrors and glass) comes from
 * emission_strata^2 extra camera rays per sample that look for nothing else (mapper_li), so the
 * edges of lights are antialiased at a fraction of the cost of full samples.
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
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "photonmap/estimate.h"
#include "direct.h"
#include "guide.h"
#include "integrator.h"
#include "photonmap/irradiance.h"
#include "photonmap/kdtree.h"
#include "photonmap/photon.h"
#include "photon_lookup.h"
#include "photon_maps.h"
#include "photon_sides.h"
#include "photon_trace.h"
#include "plan.h"
#include "pm_volume.h"
#include "stats.h"

typedef struct mapper_state {
    photon_settings cfg;
    render_plan plan;
    int preview, direct_vis;
    int max_depth, rr_depth;
    photon_maps maps;
    pm_kdtree *tg, *tc, *ts; /* global, caustic, shadow trees (NULL when absent/empty) */
    pmv_state vol; /* participating media: volume maps and ray marching (pm_volume.h) */
    side_cache sides; /* precomputed irradiance that keeps to each query's side (photon_sides.h) */
    /* The gather guide (see GATHER GUIDE): the opening the gathers aim a share of their rays at. */
    int gg_ap;         /* 1: an opening was found (gg_apc, gg_apr) */
    vec3 gg_apc;       /* its centre */
    double gg_apr;     /* the radius of the disc aimed at */
    int gg_pilot;      /* 1 while the pilot probes (its lookups are not counted) */
    plan_item gg_item; /* the decision and its evidence */
    float r2_global, r2_caustic, r2_shadow, r2_lookup;
    size_t nglobal_all, ncaustic_all; /* photons in the whole maps (all processes' parts) */
    double sec_dist;
    pm_estimate_options caus_opt, glob_opt;
    unsigned kmax;
    int st_emission_rays, st_gg_aimed;
    int st_traced, st_saved_lit, st_saved_dark, st_caustic, st_gather, st_secondary, st_lookup,
        st_global_est, st_lookup_miss, st_side_rays, st_side_again;
} mapper_state;

typedef struct mapper_scratch {
    void *est;
    pm_neighbor *nb;
    const sample_id *id; /* the camera sample being traced (for the lookup hook) */
} mapper_scratch;

/* A distributed render's lookups (photon_lookup.h); NULL in one process. */
static const photon_lookup_hook *g_lookup;

void photon_lookup_set_hook(const photon_lookup_hook *h) { g_lookup = h; }

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

/* Radiance estimate from a map at x (normal ns, the side the viewer is on). */
static rgb map_estimate(const pm_kdtree *t, const pm_estimate_options *base, vec3 x, vec3 ns,
                        rgb albedo, void *scratch) {
    pm_estimate_options o = *base;
    float xf[3], nf[3], df[3];
    to_f3(x, xf);
    to_f3(ns, nf);
    to_f3(albedo, df);
    o.diffuse = df;
    pm_estimate_result res;
    if (pm_estimate(t, xf, nf, &o, scratch, &res, NULL) < 0) return v3s(0);
    return v3(res.rgb[0], res.rgb[1], res.rgb[2]);
}

/* Radiance estimate from the global or caustic map (a PHOTON_LOOKUP_*): this process's tree,
 * or through the lookup hook (the irradiance of all processes' parts, times the BRDF). */
static rgb estimate_at(const mapper_state *st, int which, vec3 x, vec3 ns, rgb albedo,
                       mapper_scratch *sc) {
    if (!g_lookup)
        return which == PHOTON_LOOKUP_CAUSTIC ? map_estimate(st->tc, &st->caus_opt, x, ns, albedo, sc->est)
                                              : map_estimate(st->tg, &st->glob_opt, x, ns, albedo, sc->est);
    double e[3];
    g_lookup->estimate(g_lookup->user, sc->id, which, x, ns, e);
    return v3(albedo.x * e[0] / M_PI, albedo.y * e[1] / M_PI, albedo.z * e[2] / M_PI);
}

/* -1: trace the shadow ray; 1: the shadow map says lit; 0: it says dark. */
static int shadow_map_says(const mapper_state *st, vec3 x, vec3 ns, pm_neighbor *nb) {
    if (!st->ts) return -1;
    float xf[3], nf[3];
    to_f3(x, xf);
    to_f3(ns, nf);
    pm_knn_options ko = {0};
    ko.filter = pm_filter_front;
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
                        vec3 ns, vec3 wo, rng *g, mapper_scratch *sc) {
    shadow_hint_ctx c = {st, sc, g, 1.0};
    direct_options o = {DIRECT_BSDF_FULL, st->vol.on, shadow_hint, &c}; /* media: transmittance */
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
 * With media (st->vol.on; med: the medium the ray starts in) null surfaces are passed, each
 * segment's transmittance multiplies the throughput and its in-scattered light (pmv_gather,
 * times the throughput) is added to *Lvol. */
static int to_diffuse(const mapper_state *st, const scene *s, ray r, int med, rng *g, hit *h, rgb *beta,
                      vec3 *din, rgb *Lvol, void *vscratch) {
    *beta = v3s(1);
    *din = r.d;
    for (int b = 0, crossings = 0; b < 8; b++) {
        int got = scene_intersect(s, r, INFINITY, h);
        if (st->vol.on) {
            rgb tr, Lm = pmv_gather(&st->vol, s, r, got ? h->t : INFINITY, med, g, vscratch, &tr);
            *Lvol = v3_add(*Lvol, v3_mul(*beta, Lm));
            *beta = v3_mul(*beta, tr);
            if (got && scene_material(s, h)->kind == MAT_NULL && crossings++ < 1024) {
                med = scene_medium_after(s, h, r.d);
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
        if (st->vol.on) med = scene_medium_after(s, h, d);
        r.o = scene_offset(s, h->p, h->ng, d);
        r.d = d;
        stat_inc(STAT_INDIRECT_RAYS);
    }
    return 0;
}

/* Outgoing diffuse radiance at y toward wo from the precomputed irradiance of the nearest
 * precomputed photon with a similar normal that is within its own estimate radius of y and
 * on y's side of every surface (side_cache_lookup: a photon behind a wall holds another
 * room's light). *found = 0 when there is none. */
static rgb lookup_radiance(const mapper_state *st, const scene *s, const hit *h, vec3 wo, int *found) {
    *found = 0;
    if (!st->sides.irr) return v3s(0);
    const material *m = scene_material(s, h);
    vec3 ns = v3_dot(wo, h->ng) >= 0 ? h->ng : v3_neg(h->ng);
    float e[3];
    if (!st->gg_pilot) stat_inc(st->st_lookup);
    /* Within the lookup radius (photon_maps.h), and each candidate within its own estimate
     * radius. A wider search (the global radius) lets lookups beside a wall wade through every
     * photon behind it: 40x the render time on pinhole_room. */
    if (!side_cache_lookup(&st->sides, s, h->p, ns, st->r2_lookup, e)) return v3s(0);
    *found = 1;
    rgb a = diffuse_albedo(s, m, wo, h->ng);
    return v3(a.x * e[0] / M_PI, a.y * e[1] / M_PI, a.z * e[2] / M_PI);
}

/* GATHER GUIDE. In a room lit through an opening (pinhole_room: a 10 x 10 hole in the roof of a
 * closed room, the lit big room above it), about a third of the light the walls gather comes
 * through the hole, which covers 1e-4 to 3.5e-4 of their cosine-weighted hemisphere, and about 4
 * of 200,000 global photons get in, so the lookups inside find nothing and the gathers compute
 * the light themselves, level after level (gather: "Compute its light instead"): a cosine ray
 * finds the hole once in thousands and that light is carried by rare, bright samples. The guide
 * aims a share a = GG_AP_SHARE of the gather rays from every point that faces the opening at a
 * uniform point of a disc of radius gg_apr around its centre, facing the point; the others are
 * cosine-distributed as before.
 * Why the estimate stays unbiased: a direction d is weighted by (cos / pi) / p(d) relative to a
 * cosine sample, p being the mixture's density, what either branch would have drawn d with:
 *     p(d) = a p_disc(d) + (1 - a) cos / pi,
 * p_disc = distance^2 / (disc area x cos at the disc) on the disc, 0 off it. p > 0 wherever the
 * integrand is (the cosine branch keeps a share 1 - a of every direction), so the mean is the
 * same for any disc, right or wrong: a wrong one costs noise only, at most 1 / (1 - a) = 1.25
 * times a cosine ray's weight for the light that does not come through it. Every level of a
 * recursive gather is guided: the room's own light then weighs up to 1.25^level, a cost the
 * hole's light more than pays back (measured below).
 *
 * The pilot (after the precomputed irradiance; fixed streams, each point its own, so the same
 * for any thread count and on every process): guide_points' camera-path points (first diffuse
 * hits and one cosine bounce), at most GG_CELL_POINTS per cell of side (largest side / GG_RES),
 * at most GG_MAX_JOBS in all, one jittered probe per stratum of GG_G x GG_G over the cosine
 * sample's (u1, u2) (1e-3 of the cosine measure each): the value of a gather ray in that
 * direction, pi lum(f beta L(y)), L(y) read from the precomputed irradiance where a lookup finds
 * a record, plus y's light sample, as the gather does; where it finds none, y's light sample plus
 * the light y's own cell gathers (GG_BOUNCES rounds of the cells' mean probe values: a small
 * radiosity solve on the pilot's rays, so the room's own bounced light counts). Probes that read
 * the map and carry over 1/GG_OUTLIER of their point's light are rays through a narrow opening
 * into a lit region: the point nearest all their lines (least squares, then again without the
 * lines 3 spreads away) is its centre, gg_apr = GG_AP_SPREAD times their RMS distance from it.
 *
 * Decision: the camera points must be photon-starved first (at least GG_STARVED of them find
 * no precomputed irradiance on their side; elsewhere the gathers read the map, and the pilot,
 * a few CPU-seconds, is not run); then on when at least GG_MIN_LINES such rays meet within 2%
 * of the scene's size. Forced by photon_mapping.gather_guide.
 *
 * Measured on pinhole_room (8x8, 4096 spp, gather_rays 1, secondary_rays 1, light guide on; a
 * build that splits each sample's light by where it was scored, per-sample variance of the walls'
 * region mean): the light through the hole went from 2.9% (x's own ray) and 3.0% (deeper rays)
 * relative standard error to 0.3% and 0.3%, the room's own light from 1.3% and 1.4% to 2.0% and
 * 2.2%: the gathers' variance 2.4x lower. The camera's own view of the lit room through the
 * hole (a few hundredths of a pixel, a quarter of the walls' light) is not a gather's and is
 * untouched. Per-cell direction tables (guide.h's G x G warp of (u1, u2), learned from these
 * probes) were measured and are not used: one probe per stratum finds a 1e-4 hole a tenth to a
 * third of the time, a cell's table is the sum over points that see the hole in different
 * strata, and the defensive share's weights raised the room's own noise (walls 2.0% -> 2.6%
 * with tables at the first level, 5.0% at every level) more than they took from the hole's.
 *
 * LIMITS. One opening: rays through two are fitted as one, or, if they do not meet, none
 * (unbiased either way). The light samples at the gather hits are the light guide's (guide.h).
 * Off with media (the probes do not march), without a final gather, and in a partitioned
 * render-mpi (the probes would read one process's records). */
#define GG_G 32
#define GG_RES 16
#define GG_PATHS 4096
#define GG_CELL_POINTS 4
#define GG_MAX_JOBS 768
#define GG_BOUNCES 4
#define GG_OUTLIER 16
#define GG_MIN_LINES 16
#define GG_AP_SPREAD 3.0
#define GG_AP_SHARE 0.2
#define GG_STARVED 0.75
#define GG_SEED 0x676174686572ULL /* "gather" */

/* The aimed branch's density per steradian of direction d from x (0 off the disc). */
static double gg_disc_pdf(const mapper_state *st, vec3 x, vec3 d) {
    vec3 toc = v3_sub(st->gg_apc, x);
    double dc = v3_len(toc), cd = v3_dot(d, toc) / dc;
    if (!(cd > 0)) return 0;
    double t = dc / cd, R = st->gg_apr;
    if (v3_len2(v3_sub(v3_add(x, v3_scale(d, t)), st->gg_apc)) > R * R) return 0;
    return t * t / (M_PI * R * R * cd);
}

/* The share of x's gather rays aimed at the opening: GG_AP_SHARE when it is in front of x (side
 * normal ns) and farther than the disc's radius, else 0. */
static double gg_aim_share(const mapper_state *st, vec3 x, vec3 ns) {
    if (!st->gg_ap) return 0;
    vec3 toc = v3_sub(st->gg_apc, x);
    return v3_dot(toc, ns) > 0 && v3_len2(toc) > st->gg_apr * st->gg_apr ? GG_AP_SHARE : 0;
}


/* A guided gather direction from x (shading frame nsh) for the pair (u1, u2): aimed at the
 * opening with probability a, else cosine-distributed. *wk is its weight relative to a cosine
 * sample, (cos / pi) / p(d) (see GATHER GUIDE); 0 when d is below the shading hemisphere. One
 * more number from g. */
static vec3 gg_direction(const mapper_state *st, double a, vec3 x, vec3 nsh, double u1, double u2, rng *g,
                         double *wk) {
    vec3 d;
    if (rng_uniform(g) < a) {
        vec3 toc = v3_sub(st->gg_apc, x), ds, dt;
        double dx, dy;
        v3_basis(v3_norm(toc), &ds, &dt);
        sample_concentric_disc(u1, u2, &dx, &dy);
        vec3 q = v3_add(st->gg_apc, v3_add(v3_scale(ds, st->gg_apr * dx), v3_scale(dt, st->gg_apr * dy)));
        d = v3_norm(v3_sub(q, x));
        stat_inc(st->st_gg_aimed);
    } else
        d = sampling_to_world(sample_cosine_hemisphere(u1, u2), nsh);
    double c = v3_dot(d, nsh);
    double p = (1 - a) * c / M_PI + a * gg_disc_pdf(st, x, d);
    *wk = c > 0 && p > 0 ? c / M_PI / p : 0;
    return d;
}

/* Indirect diffuse at a diffuse point by gathering n rays; level 0 for the gather of a camera
 * path, level >= 1 inside a secondary gather (its rays read the map, or recurse where the map
 * has nothing, see gather). */
static rgb gather(const mapper_state *st, const scene *s, const material *m, const hit *h, vec3 ns,
                  vec3 wo, int n, int level, rng *g, mapper_scratch *sc);

/* Outgoing light at a gather hit y, computed instead of read from the map: y's direct light,
 * caustics and a gather of its own at `level` (secondary_rays rays at level 1, one ray deeper,
 * so a chain of them costs one ray per bounce, like a path). */
static rgb secondary_radiance(const mapper_state *st, const scene *s, const hit *y, vec3 wo, int level,
                              rng *g, mapper_scratch *sc) {
    const material *m = scene_material(s, y);
    vec3 ns = v3_dot(wo, y->ng) >= 0 ? y->ng : v3_neg(y->ng);
    rgb L = direct_light(st, s, m, y, ns, wo, g, sc);
    L = v3_add(L, caustics_at(st, s, m, y, ns, wo, sc));
    int n = level <= 1 ? st->cfg.secondary_rays : 1;
    return v3_add(L, gather(st, s, m, y, ns, wo, n, level, g, sc));
}

static rgb gather(const mapper_state *st, const scene *s, const material *m, const hit *h, vec3 ns,
                  vec3 wo, int n, int level, rng *g, mapper_scratch *sc) {
    if (n <= 0 || !st->sides.irr) return v3s(0);
    rgb sum = v3s(0);
    vec3 nsh = material_shading_side(wo, h->ng, h->ns);
    /* The gather guide (GATHER GUIDE): the share aimed at the opening; 0: cosine sampling, the
     * same numbers drawn as without the guide. */
    double aim = gg_aim_share(st, h->p, ns);
    for (int k = 0; k < n; k++) {
        /* Stratified over the hemisphere: n strata in the first coordinate. */
        double u1 = (k + rng_uniform(g)) / n, u2 = rng_uniform(g), wk = 1;
        vec3 d;
        if (aim > 0) {
            d = gg_direction(st, aim, h->p, nsh, u1, u2, g, &wk);
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
        int steps = to_diffuse(st, s, r, st->vol.on ? scene_medium_after(s, h, d) : -1, g, &y, &beta, &din,
                               &Lvol, sc->est);
        if (st->vol.on) sum = v3_add(sum, v3_scale(v3_mul(f, Lvol), wk));
        if (!steps) continue;
        /* y is seen from -din, the last segment's direction (not d after a mirror). */
        rgb Lo;
        int found = 0;
        if (!level && steps == 1 && y.t < st->sec_dist)
            Lo = secondary_radiance(st, s, &y, v3_neg(din), 1, g, sc);
        else {
            Lo = lookup_radiance(st, s, &y, v3_neg(din), &found);
            /* The cache holds indirect irradiance only (photon_sides.h, "Direct light"): y's
             * direct light comes from a light sample, so shadow edges stay sharp. */
            if (found && st->sides.indirect_only)
                Lo = v3_add(Lo, direct_light(st, s, scene_material(s, &y), &y,
                                             v3_dot(din, y.ng) <= 0 ? y.ng : v3_neg(y.ng), v3_neg(din), g, sc));
            /* No precomputed value on y's side within reach: y is in a photon-starved
             * region (behind a wall from every nearby photon, or a room that light enters
             * through a pinhole, where a map of any practical size holds a handful of
             * photons). Compute its light instead. Inside a secondary gather that recurses:
             * one ray per level, continued by Russian roulette on y's diffuse albedo, so
             * where the map has nothing the gather becomes a path tracer. (Counting such y
             * as dark, as this did, dropped every bounce after the second: -18% on
             * pinhole_room, with the shadow photons off.) */
            if (!found) {
                stat_inc(st->st_lookup_miss);
                if (!level)
                    Lo = secondary_radiance(st, s, &y, v3_neg(din), 1, g, sc);
                else {
                    rgb a = diffuse_albedo(s, scene_material(s, &y), v3_neg(din), y.ng);
                    double q = fmin(0.95, v3_maxc(a));
                    if (level < st->max_depth && rng_uniform(g) < q)
                        Lo = v3_scale(secondary_radiance(st, s, &y, v3_neg(din), level + 1, g, sc),
                                      1.0 / q);
                }
            }
        }
        /* cosine sampling: f cos / pdf = pi f (times wk when guided) */
        rgb c = v3_mul(v3_mul(f, beta), Lo);
        sum = v3_add(sum, wk != 1 ? v3_scale(c, wk) : c);
    }
    return v3_scale(sum, M_PI / n);
}

/* ---- the gather guide's pilot (GATHER GUIDE) ----------------------------------------------- */

/* One probe: its value as read at the hit (base) and, where the map had nothing there, the
 * weight w that the light gathered in y's cell (ycell, -1: none) is multiplied by. */
typedef struct gg_probe {
    float base, w;
    int ycell;
    int found;   /* the map answered at y */
    float y[3];  /* the hit */
} gg_probe;

static int gg_size_cmp(const void *a, const void *b) {
    size_t x = *(const size_t *)a, y = *(const size_t *)b;
    return x < y ? -1 : x > y;
}

/* The index of key c among the sorted keys ck[0..n), or -1. */
static int gg_cell_index(const uint64_t *ck, size_t n, uint64_t c) {
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (ck[mid] < c)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < n && ck[lo] == c ? (int)lo : -1;
}

/* The probe from pt at (u1, u2): a gather ray, read as the gather reads it (one light sample). */
static gg_probe gg_probe_at(const mapper_state *st, const scene *s, const guide_grid *grid, const uint64_t *ck,
                            size_t nck, const guide_point *pt, double u1, double u2, rng *g) {
    gg_probe pr = {0, 0, -1, 0, {0, 0, 0}};
    vec3 d = sampling_to_world(sample_cosine_hemisphere(u1, u2), material_shading_side(pt->wo, pt->h.ng, pt->h.ns));
    if (!(v3_dot(d, pt->n) > 0)) return pr;
    rgb f = material_f(scene_material(s, &pt->h), pt->h.ng, s->medium_ior, pt->wo, d);
    if (v3_iszero(f)) return pr;
    ray r = {scene_offset(s, pt->h.p, pt->h.ng, d), d};
    hit y;
    rgb beta, Lvol = v3s(0);
    vec3 din;
    if (!to_diffuse(st, s, r, -1, g, &y, &beta, &din, &Lvol, NULL)) return pr;
    int found;
    vec3 ny = v3_dot(din, y.ng) <= 0 ? y.ng : v3_neg(y.ng);
    rgb Lo = lookup_radiance(st, s, &y, v3_neg(din), &found);
    if (!found || st->sides.indirect_only) {
        direct_options o = {DIRECT_BSDF_FULL, 0, NULL, NULL};
        Lo = v3_add(Lo, direct_light_surface_guided(s, scene_material(s, &y), &y, ny, v3_neg(din), g, &o,
                                                    st->plan.guide));
    }
    rgb fb = v3_scale(v3_mul(f, beta), M_PI);
    double x = rgb_lum(v3_mul(fb, Lo)), w = rgb_lum(fb);
    pr.base = x > 0 && isfinite(x) ? (float)x : 0;
    pr.found = found;
    to_f3(y.p, pr.y);
    if (!found && w > 0 && isfinite(w)) {
        pr.w = (float)w;
        pr.ycell = gg_cell_index(ck, nck, guide_cell(grid, y.p, ny));
    }
    return pr;
}

/* The point nearest the n lines (x[i], unit d[i]) (least squares) into *c; 0 if they are
 * (nearly) parallel. *rms: the lines' RMS distance from it. use[i] = 0 leaves line i out. */
static int gg_nearest_point(const vec3 *x, const vec3 *d, const unsigned char *use, size_t n, vec3 *c, double *rms) {
    double A[9] = {0}, b[3] = {0};
    size_t m = 0;
    for (size_t i = 0; i < n; i++) {
        if (!use[i]) continue;
        double dd[3] = {d[i].x, d[i].y, d[i].z}, xx[3] = {x[i].x, x[i].y, x[i].z};
        for (int r = 0; r < 3; r++)
            for (int k = 0; k < 3; k++) {
                double e = (r == k) - dd[r] * dd[k]; /* I - d d^T: the distance to the line */
                A[3 * r + k] += e;
                b[r] += e * xx[k];
            }
        m++;
    }
#define GG_DET(M) ((M)[0] * ((M)[4] * (M)[8] - (M)[5] * (M)[7]) - (M)[1] * ((M)[3] * (M)[8] - (M)[5] * (M)[6]) + \
                   (M)[2] * ((M)[3] * (M)[7] - (M)[4] * (M)[6]))
    double det = GG_DET(A);
    if (!(m >= 2) || !(fabs(det) > 1e-9 * (double)m * (double)m * (double)m)) return 0;
    double sol[3];
    for (int k = 0; k < 3; k++) { /* Cramer's rule */
        double M[9];
        memcpy(M, A, sizeof M);
        for (int r = 0; r < 3; r++) M[3 * r + k] = b[r];
        sol[k] = GG_DET(M) / det;
    }
#undef GG_DET
    *c = v3(sol[0], sol[1], sol[2]);
    double s2 = 0;
    for (size_t i = 0; i < n; i++)
        if (use[i]) {
            vec3 e = v3_sub(*c, x[i]);
            s2 += v3_len2(v3_sub(e, v3_scale(d[i], v3_dot(e, d[i]))));
        }
    *rms = sqrt(s2 / (double)m);
    return 1;
}

/* The opening from the pilot's probes (see GATHER GUIDE): 1 and its centre *c and the lines'
 * RMS distance *rms, 0 if none fits, PM_ENOMEM. *nline: the bright rays that read the map;
 * *all, *bright: the probed light in all, and in those rays. */
static int gg_find_opening(const guide_point *pts, const size_t *jp, size_t nj, const gg_probe *pr, const double *v,
                           size_t G2, size_t *nline, double *all, double *bright, vec3 *c, double *rms) {
    size_t cap = (nj ? nj : 1) * 8, n = 0;
    vec3 *lx = calloc(cap, sizeof *lx), *ld = calloc(cap, sizeof *ld);
    unsigned char *use = calloc(cap, 1);
    if (!lx || !ld || !use) {
        free(lx);
        free(ld);
        free(use);
        return PM_ENOMEM;
    }
    *all = *bright = 0;
    for (size_t j = 0; j < nj; j++) {
        double t = 0;
        for (size_t i = 0; i < G2; i++) t += v[j * G2 + i];
        *all += t;
        for (size_t i = 0; i < G2 && t > 0; i++) {
            const gg_probe *p = &pr[j * G2 + i];
            if (!p->found || !(p->base > t / GG_OUTLIER) || n >= cap) continue;
            vec3 x = pts[jp[j]].h.p;
            lx[n] = x;
            ld[n] = v3_norm(v3_sub(v3(p->y[0], p->y[1], p->y[2]), x));
            use[n++] = 1;
            *bright += p->base;
        }
    }
    int fit = gg_nearest_point(lx, ld, use, n, c, rms);
    if (fit) { /* again without the lines far from the first fit (another source of bright rays) */
        for (size_t l = 0; l < n; l++) {
            vec3 e = v3_sub(*c, lx[l]);
            use[l] = v3_len(v3_sub(e, v3_scale(ld[l], v3_dot(e, ld[l])))) <= 3 * *rms;
        }
        fit = gg_nearest_point(lx, ld, use, n, c, rms);
    }
    *nline = n;
    free(lx);
    free(ld);
    free(use);
    return fit;
}

/* Decide the gather guide and find its opening (st->gg_ap, gg_apc, gg_apr, gg_item); see GATHER GUIDE. */
static int gather_guide_plan(mapper_state *st, const scene *s, char *err, size_t errcap) {
    plan_item *it = &st->gg_item;
    int force = st->cfg.force_gather_guide;
    it->on = 0;
    if (force == PLAN_OFF) {
        snprintf(it->reason, sizeof it->reason, "off (forced)");
        return 0;
    }
    const char *why = !st->plan.final_gather.on || st->direct_vis ? "no final gather"
                      : !st->sides.irr                             ? "no precomputed irradiance to probe"
                      : st->vol.on                                 ? "participating media: its probes do not march"
                      : g_lookup ? "partitioned render-mpi: its probes would read one process's records" : NULL;
    if (why) {
        snprintf(it->reason, sizeof it->reason, "off (%s%s)", why, force == PLAN_ON ? "; asked for" : "");
        return 0;
    }
    guide_point *pts = NULL;
    size_t npts = 0;
    int rc = guide_points(s, GG_PATHS, GG_SEED, 0, &pts, &npts);
    if (rc < 0) {
        snprintf(err, errcap, "out of memory (gather guide pilot)");
        return rc;
    }
    /* Photon-starved camera points: no precomputed irradiance on their side. */
    size_t starved = 0, cam = 0;
    st->gg_pilot = 1;
    for (size_t k = 0; k < npts; k++) {
        if (pts[k].bounce) continue;
        int found;
        lookup_radiance(st, s, &pts[k].h, pts[k].wo, &found);
        cam++;
        starved += !found;
    }
    st->gg_pilot = 0;
    if (force != PLAN_ON && !((double)starved >= GG_STARVED * (double)cam && starved > 0)) {
        snprintf(it->reason, sizeof it->reason,
                 "off (%zu of %zu camera points find no precomputed irradiance on their side, under "
                 "%.0f%%: the gathers read the photon map, no opening is looked for)",
                 starved, cam, 100 * GG_STARVED);
        free(pts);
        return 0;
    }
    guide_grid grid;
    guide_grid_init(&grid, s, GG_RES);
    const size_t G2 = (size_t)GG_G * GG_G;
    size_t n1 = npts ? npts : 1, nj = 0, ncell = 0;
    guide_cell_ref *pk = malloc(n1 * sizeof *pk);
    uint64_t *ck = malloc(n1 * sizeof *ck);
    size_t *jp = malloc(n1 * sizeof *jp);
    int *jc = malloc(n1 * sizeof *jc);
    gg_probe *pr = NULL;
    double *v = NULL, *Lc = NULL, *Ln = NULL, *nc = NULL;
    if (!pk || !ck || !jp || !jc) goto oom;
    /* Cells; per cell its first GG_CELL_POINTS points; at most GG_MAX_JOBS, evenly in point order. */
    for (size_t k = 0; k < npts; k++) pk[k] = (guide_cell_ref){guide_cell(&grid, pts[k].h.p, pts[k].n), k};
    qsort(pk, npts, sizeof *pk, guide_cell_ref_cmp);
    for (size_t a = 0, b; a < npts; a = b) {
        for (b = a; b < npts && pk[b].cell == pk[a].cell; b++)
            if (b - a < GG_CELL_POINTS) jp[nj++] = pk[b].k;
        ck[ncell++] = pk[a].cell;
    }
    qsort(jp, nj, sizeof *jp, gg_size_cmp);
    if (nj > GG_MAX_JOBS) {
        for (size_t j = 0; j < GG_MAX_JOBS; j++) jp[j] = jp[j * nj / GG_MAX_JOBS];
        nj = GG_MAX_JOBS;
    }
    for (size_t j = 0; j < nj; j++) jc[j] = gg_cell_index(ck, ncell, guide_cell(&grid, pts[jp[j]].h.p, pts[jp[j]].n));
    size_t nj1 = nj ? nj : 1, nc1 = ncell ? ncell : 1;
    pr = malloc(nj1 * G2 * sizeof *pr);
    v = malloc(nj1 * G2 * sizeof *v);
    Lc = calloc(nc1, sizeof *Lc);
    Ln = calloc(nc1, sizeof *Ln);
    nc = calloc(nc1, sizeof *nc);
    if (!pr || !v || !Lc || !Ln || !nc) goto oom;
    /* One probe per stratum, jittered; each point on its own stream (thread-count free). */
    st->gg_pilot = 1;
#pragma omp parallel for schedule(dynamic, 4)
    for (long j = 0; j < (long)nj; j++) {
        rng g = rng_stream(GG_SEED, jp[j], 1);
        for (int b = 0; b < GG_G; b++)
            for (int a = 0; a < GG_G; a++)
                pr[(size_t)j * G2 + (size_t)(a + GG_G * b)] = gg_probe_at(
                    st, s, &grid, ck, ncell, &pts[jp[j]], (a + rng_uniform(&g)) / GG_G, (b + rng_uniform(&g)) / GG_G, &g);
    }
    st->gg_pilot = 0;
    /* The light gathered where the map has nothing: each round gives every cell the mean of its
     * points' probes, with the last round's cell values at the probes' hits (one more bounce). */
    for (int round = 0; round <= GG_BOUNCES; round++) {
        memset(Ln, 0, nc1 * sizeof *Ln);
        memset(nc, 0, nc1 * sizeof *nc);
        for (size_t j = 0; j < nj; j++) {
            double t = 0;
            for (size_t i = 0; i < G2; i++) {
                const gg_probe *p = &pr[j * G2 + i];
                v[j * G2 + i] = p->base + (p->ycell >= 0 ? p->w * Lc[p->ycell] : 0);
                t += v[j * G2 + i];
            }
            Ln[jc[j]] += t / (double)G2;
            nc[jc[j]] += 1;
        }
        for (size_t c = 0; c < ncell; c++) Lc[c] = nc[c] > 0 ? Ln[c] / nc[c] : 0;
    }
    /* The opening: rays that read the map and carry over 1/GG_OUTLIER of their point's light. */
    size_t nline = 0;
    double all = 0, bright = 0, rms = 0;
    vec3 c = v3s(0);
    int fit = gg_find_opening(pts, jp, nj, pr, v, G2, &nline, &all, &bright, &c, &rms);
    if (fit < 0) goto oom;
    double size = v3_maxc(v3_sub(s->bounds_hi, s->bounds_lo));
    int opening = fit && nline >= GG_MIN_LINES && GG_AP_SPREAD * rms <= 0.02 * size && rms > 0;
    st->gg_ap = opening;
    st->gg_apc = c;
    st->gg_apr = GG_AP_SPREAD * rms;
    it->on = opening || force == PLAN_ON;
    char what[256];
    if (opening)
        snprintf(what, sizeof what, "an opening at (%.4g, %.4g, %.4g), radius %.3g: %zu rays that read the photon map "
                 "meet there, carrying %.1f%% of the probed light",
                 c.x, c.y, c.z, st->gg_apr, nline, all > 0 ? 100 * bright / all : 0);
    else
        snprintf(what, sizeof what, "no opening (%zu bright rays that read the photon map, %s)", nline,
                 nline < GG_MIN_LINES ? "too few" : "not meeting within 2% of the scene's size");
    snprintf(it->reason, sizeof it->reason,
             "%s (%zu of %zu camera points find no precomputed irradiance; the pilot probed %zu points in %zu "
             "cells, %zu probes: %s)",
             force == PLAN_ON && !opening ? "on (forced; no opening: gathers stay cosine)" : force == PLAN_ON ? "on (forced)"
             : it->on ? "on" : "off",
             starved, cam, nj, ncell, nj * G2, what);
    rc = 0;
    goto done;
oom:
    rc = PM_ENOMEM;
    snprintf(err, errcap, "out of memory (gather guide pilot)");
done:
    if (rc < 0 || !it->on) st->gg_ap = 0;
    free(pts);
    free(pk);
    free(ck);
    free(jp);
    free(jc);
    free(pr);
    free(v);
    free(Lc);
    free(Ln);
    free(nc);
    return rc;
}

/* ---- the integrator ----------------------------------------------------------------------- */

/* The weight of this camera sample's caustic estimates. With caustic_stride c > 1 the
 * caustic map is read at one stratum in c x c of the pixel, those whose (sx mod c, sy mod c)
 * equal a random offset drawn per pixel, and weighted c^2; the other samples get weight 0.
 * Each sample is chosen with probability 1/c^2, so the pixel's expected value is unchanged,
 * and the chosen ones are spread evenly over the pixel. The caustic radiance barely changes
 * within a pixel, so this costs little noise and saves most of the estimates' time. */
static double caustic_weight(const mapper_state *st, const sample_id *id) {
    int c = st->cfg.caustic_stride;
    if (c <= 1 || !id || id->strata < c) return 1.0;
    rng g = rng_stream(id->seed, id->pixel, 0x6361757374696373ULL); /* "caustics" */
    int ox = (int)(rng_uniform(&g) * c), oy = (int)(rng_uniform(&g) * c);
    int sx = id->k % id->strata, sy = id->k / id->strata;
    return sx % c == ox && sy % c == oy ? (double)c * c : 0.0;
}

enum { EYE_ALL, EYE_SHADE, EYE_EMIT };

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
            rgb tr, Lm = pmv_march(&st->vol, s, r, got ? h.t : INFINITY, med, what != EYE_EMIT, g, sc->est, &tr);
            L = v3_add(L, v3_mul(beta, Lm));
            beta = v3_mul(beta, tr);
            if (got && scene_material(s, &h)->kind == MAT_NULL) {
                if (++crossings > 1024 || v3_iszero(beta)) break;
                med = scene_medium_after(s, &h, r.d);
                r.o = scene_offset(s, h.p, h.ng, r.d);
                depth--; /* not a bounce */
                continue;
            }
        }
        if (!got) break;
        stat_inc(STAT_PATH_VERTICES);
        const material *m = scene_material(s, &h);
        vec3 wo = v3_neg(r.d);
        if (what != EYE_SHADE && material_is_emissive(m) && (v3_dot(wo, h.ng) > 0 || m->two_sided))
            L = v3_add(L, v3_mul(beta, m->emission));
        vec3 ns = v3_dot(wo, h.ng) >= 0 ? h.ng : v3_neg(h.ng);
        double w[LOBE_COUNT];
        material_weights(m, wo, h.ng, s->medium_ior, w);
        if (what != EYE_EMIT && w[LOBE_DIFFUSE] > 0 && v3_maxc(m->diffuse) > 0) {
            rgb Ld;
            if (st->direct_vis) {
                stat_inc(st->st_global_est);
                Ld = st->nglobal_all ? estimate_at(st, PHOTON_LOOKUP_GLOBAL, h.p, ns,
                                                   diffuse_albedo(s, m, wo, h.ng), sc)
                                     : v3s(0);
            } else {
                Ld = direct_light(st, s, m, &h, ns, wo, g, sc);
                if (cw > 0) Ld = v3_add(Ld, v3_scale(caustics_at(st, s, m, &h, ns, wo, sc), cw));
                if (st->plan.final_gather.on) {
                    double share = fmin(1.0, v3_maxc(beta));
                    int n = (int)ceil(st->cfg.gather_rays * share);
                    if (st->cfg.gather_rays > 0 && n < 1) n = 1;
                    Ld = v3_add(Ld, gather(st, s, m, &h, ns, wo, n, 0, g, sc));
                }
            }
            L = v3_add(L, v3_mul(beta, Ld));
        }
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
                                           st->vol.on ? scene_medium_after(s, &h, dr) : -1, g, sc));
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
        if (st->vol.on) med = scene_medium_after(s, &h, d);
        r.o = scene_offset(s, h.p, h.ng, d);
        r.d = d;
        stat_inc(STAT_INDIRECT_RAYS);
    }
    return L;
}

/* A camera sample. With emission_strata m > 0, the emission the camera sees (directly or in
 * mirrors and glass) is not taken from the sample's own path but from m x m extra camera
 * rays, one in each sub-stratum of the sample's stratum, that look for emission alone. The
 * pixel integral is the same sum of two parts, each estimated without bias, but the bright
 * edges of a light, where the coverage of a pixel is what varies, get m^2 times the camera
 * rays for the price of a few ray casts instead of m^2 full shading samples. */
static rgb mapper_li(const integrator *self, const scene *s, ray r, rng *g, const sample_id *id,
                 void *scratch) {
    const mapper_state *st = self->data;
    if (scratch) ((mapper_scratch *)scratch)->id = id;
    int m = st->cfg.emission_strata;
    if (m <= 0 || !id || id->strata <= 0)
        return eye_radiance(st, s, r, 0, v3s(1), caustic_weight(st, id), EYE_ALL, s->camera_medium, g, scratch);
    rgb L = eye_radiance(st, s, r, 0, v3s(1), caustic_weight(st, id), EYE_SHADE, s->camera_medium, g, scratch);
    rgb E = v3s(0);
    int n = id->strata, W = s->cam.width;
    double x = (double)(id->pixel % (uint64_t)W), y = (double)(id->pixel / (uint64_t)W);
    double sx = id->k % n, sy = id->k / n;
    for (int b = 0; b < m; b++)
        for (int a = 0; a < m; a++) {
            double u = rng_uniform(g), v = rng_uniform(g);
            ray re = camera_ray(&s->cam, x + (sx + (a + u) / m) / n, y + (sy + (b + v) / m) / n);
            stat_inc(st->st_emission_rays);
            E = v3_add(E, eye_radiance(st, s, re, 0, v3s(1), 0, EYE_EMIT, s->camera_medium, g, scratch));
        }
    return v3_add(L, v3_scale(E, 1.0 / (m * m)));
}

static void *mapper_thread_begin(const integrator *self) {
    const mapper_state *st = self->data;
    mapper_scratch *sc = malloc(sizeof *sc);
    if (!sc) return NULL;
    sc->est = malloc(pm_estimate_scratch_bytes(st->kmax));
    sc->nb = malloc((size_t)st->cfg.k_shadow * sizeof *sc->nb);
    return sc;
}

static void mapper_thread_end(const integrator *self, void *scratch) {
    (void)self;
    mapper_scratch *sc = scratch;
    if (!sc) return;
    free(sc->est);
    free(sc->nb);
    free(sc);
}

static void mapper_destroy(integrator *self) {
    mapper_state *st = self->data;
    if (!st) return;
    side_cache_free(&st->sides);
    pmv_free(&st->vol);
    pm_kdtree_free(st->tg);
    pm_kdtree_free(st->tc);
    pm_kdtree_free(st->ts);
    photon_maps_free(&st->maps);
    plan_free(&st->plan);
    free(st);
}

/* ---- preprocess --------------------------------------------------------------------------- */

enum { BUCKET_GLOBAL = 1, BUCKET_CAUSTIC = 8, BUCKET_SHADOW = 8 };

static int mapper_preprocess(integrator *self, const scene *s, char *err, size_t errcap) {
    mapper_state *st = self->data;
    plan_print(&st->plan, stdout);
    fflush(stdout);
    photon_maps *m = &st->maps;
    int rc;
    double t0 = stats_now();
    map_stamp stamp; /* what shapes this run's maps: checked on load, written on save */
    map_stamp_make(s, &st->cfg, st->plan.global.on, st->plan.caustics.on, st->plan.shadow.on, &stamp);
    if (st->vol.on) { /* a scene with media: its own tracer, surface and volume maps */
        /* Loaded maps (the volume files too, photon_maps.h) are checked here; pmv_trace then
         * builds its trees from them instead of tracing. */
        map_stamp_volume(s, &st->cfg, st->plan.volume.on, st->plan.volume_caustics.on, &stamp);
        m->nmedia = s->nmedia;
        if (st->cfg.load_dir[0] &&
            (rc = photon_maps_load(m, st->cfg.load_dir, &stamp, st->cfg.force_load, err, errcap)) < 0)
            return rc;
        int loaded = m->loaded;
        if ((rc = pmv_trace(&st->vol, s, &st->cfg, &st->plan, m, err, errcap)) < 0) return rc;
        if (!loaded) m->stamp = stamp;
    } else if (st->cfg.load_dir[0]) {
        if ((rc = photon_maps_load(m, st->cfg.load_dir, &stamp, st->cfg.force_load, err, errcap)) < 0)
            return rc;
        /* The plan decides which loaded maps are used. */
        if (!st->plan.global.on) m->nglobal = 0;
        if (!st->plan.caustics.on) m->ncaustic = 0;
        if (!st->plan.shadow.on) m->nshadow = 0;
        printf("Loaded photon maps from %s: %zu global, %zu caustic, %zu shadow-map photons\n",
               st->cfg.load_dir, m->nglobal, m->ncaustic, m->nshadow);
    } else {
        trace_opts o;
        trace_opts_init(&o, s);
        o.global = st->plan.global.on;
        o.caustic = st->plan.caustics.on;
        o.shadow = st->plan.shadow.on;
        o.global_target = st->cfg.global_photons;
        o.caustic_target = st->cfg.caustic_photons;
        o.max_emitted_factor = st->cfg.max_emitted_factor;
        o.max_emitted = st->cfg.max_emitted;
        o.max_memory_bytes = (size_t)st->cfg.max_memory_mb << 20;
        o.max_bounces = st->cfg.max_bounces;
        o.projection = st->cfg.projection;
        o.projection_cells = st->cfg.projection_cells;
        o.importance = st->plan.imp; /* importance-driven emission, when the plan chose it */
        o.reuse = st->plan.pilot;     /* the plan's pilot photons join the global maps */
        o.quiet = !st->cfg.progress;
        if ((rc = photon_trace(s, &o, m, err, errcap)) < 0) return rc;
        m->stamp = stamp;
        printf("Photons: %zu global, %zu shadow-map (from %llu emitted); %zu caustic (from %llu "
               "emitted; projection maps cover %.2f%% of the light's power, saving %llu "
               "emissions)\n",
               m->part ? m->whole_global : m->nglobal, m->part ? m->whole_shadow : m->nshadow,
               (unsigned long long)m->global_emitted, m->part ? m->whole_caustic : m->ncaustic,
               (unsigned long long)m->caustic_emitted, 100 * m->caustic_fraction,
               (unsigned long long)m->caustic_saved);
    }
    stats_time_add("Time/Photon tracing (or loading)", stats_now() - t0);
    /* Saved before the trees reorder them: loading these files then gives the trees, the
     * precomputed irradiance and the image of this run exactly. */
    if (st->cfg.save_dir[0]) {
        if ((rc = photon_maps_save(m, st->cfg.save_dir, err, errcap)) < 0) return rc;
        printf("Saved photon maps to %s\n", st->cfg.save_dir);
    }

    /* The radii of the whole maps, before a distributed render keeps only its part of them. */
    map_radii rad;
    photon_maps_radii(s, m, &st->cfg, &rad);
    st->nglobal_all = m->part ? m->whole_global : m->nglobal;
    st->ncaustic_all = m->part ? m->whole_caustic : m->ncaustic;
    if (g_lookup && (rc = g_lookup->partition(g_lookup->user, m, err, errcap)) < 0) return rc;

    t0 = stats_now();
    if ((rc = photon_tree_build(&st->tg, m->global, m->nglobal, BUCKET_GLOBAL, err, errcap)) < 0 ||
        (rc = photon_tree_build(&st->tc, m->caustic, m->ncaustic, BUCKET_CAUSTIC, err, errcap)) < 0 ||
        (rc = photon_tree_build(&st->ts, m->shadow, m->nshadow, BUCKET_SHADOW, err, errcap)) < 0)
        return rc;
    stats_time_add("Time/Photon kd-trees", stats_now() - t0);
    st->r2_global = rad.r2_global;
    st->r2_caustic = rad.r2_caustic;
    st->r2_lookup = rad.r2_lookup;
    st->r2_shadow = rad.r2_shadow;
    st->sec_dist = st->cfg.secondary_distance > 0 ? st->cfg.secondary_distance : rad.typical;
    printf("Radii: global estimate %.4g, caustic estimate %.4g, secondary gather below %.4g, "
           "shadow-map query %.4g\n",
           rad.global, rad.caustic, st->sec_dist, rad.shadow);

    pm_estimator kinds[] = {PM_EST_DISC, PM_EST_CONE, PM_EST_GAUSS, PM_EST_HULL};
    pm_estimate_options_init(&st->caus_opt, kinds[st->cfg.filter], (unsigned)st->cfg.k_caustic);
    st->caus_opt.max_dist2 = st->r2_caustic;
    st->caus_opt.reject_behind = 1;
    pm_estimate_options_init(&st->glob_opt, PM_EST_DISC, (unsigned)st->cfg.k_global);
    st->glob_opt.max_dist2 = st->r2_global;
    st->glob_opt.reject_behind = 1;

    if (st->nglobal_all && !st->direct_vis) {
        t0 = stats_now();
        rc = g_lookup ? g_lookup->side_build(g_lookup->user, &st->sides, s, st->tg,
                                             st->tg ? pm_kdtree_records(st->tg) : NULL, m->nglobal,
                                             (unsigned)st->cfg.k_global, st->r2_global, err, errcap)
                      : side_cache_build(&st->sides, s, st->tg, pm_kdtree_records(st->tg), m->nglobal,
                                         (unsigned)st->cfg.k_global, st->r2_global, err, errcap);
        if (rc < 0) return rc;
        stat_add(st->st_side_rays, st->sides.rays_first + st->sides.rays_second);
        stat_add(st->st_side_again, st->sides.researched);
        stats_time_add("Time/Precomputed irradiance", stats_now() - t0);
        printf("Precomputed irradiance at %zu of %zu global photons (%zu estimates searched again "
               "for a hidden neighbour; %zu of too few photons to be read: the light there is "
               "computed)\n",
               st->sides.n, st->nglobal_all, st->sides.researched, st->sides.sparse);
    }
    t0 = stats_now();
    if ((rc = gather_guide_plan(st, s, err, errcap)) < 0) return rc;
    stats_time_add("Time/Gather guide pilot", stats_now() - t0);
    printf("  gather guide: %s\n", st->gg_item.reason);
    if (g_lookup) {
        const pm_kdtree *trees[2] = {st->tg, st->tc};
        pm_estimate_options opts[2] = {st->glob_opt, st->caus_opt};
        g_lookup->ready(g_lookup->user, trees, opts);
    }
    fflush(stdout);
    return 0;
}

static int create_common(integrator *it, const scene *s, int preview, char *err, size_t errcap) {
    mapper_state *st = calloc(1, sizeof *st);
    if (!st) {
        snprintf(err, errcap, "out of memory");
        return PM_ENOMEM;
    }
    json_err e;
    int rc = photon_settings_parse(&st->cfg, s->photon_mapping, &e);
    if (rc < 0) {
        snprintf(err, errcap, "%s", e.msg);
        free(st);
        return rc;
    }
    st->preview = preview;
    plan_make(s, &st->cfg, preview, &st->plan);
    /* The global map is shown directly in preview mode or with gathering forced off; with no
     * global map at all (the plan found no indirect diffuse light) the surfaces get direct
     * light and caustics, and no indirect term, rather than the estimate of an absent map. */
    st->direct_vis = (preview || !st->plan.final_gather.on) && st->plan.global.on;
    st->max_depth = s->settings.max_depth;
    st->rr_depth = s->settings.rr_depth;
    st->kmax = (unsigned)(st->cfg.k_global > st->cfg.k_caustic ? st->cfg.k_global : st->cfg.k_caustic);
    if ((rc = pmv_init(&st->vol, s, &st->cfg)) < 0) {
        snprintf(err, errcap, "out of memory");
        plan_free(&st->plan);
        free(st);
        return rc;
    }
    if (st->vol.on) { /* the volume estimates share the estimate scratch */
        if ((unsigned)st->cfg.k_volume > st->kmax) st->kmax = (unsigned)st->cfg.k_volume;
        if ((unsigned)st->cfg.k_volume_caustic > st->kmax) st->kmax = (unsigned)st->cfg.k_volume_caustic;
    }
    st->st_traced = stats_register("Photon mapping/Shadow rays traced");
    st->st_saved_lit = stats_register("Photon mapping/Shadow rays saved: all direct photons");
    st->st_saved_dark = stats_register("Photon mapping/Shadow rays saved: all shadow photons");
    st->st_caustic = stats_register("Photon mapping/Caustic estimates");
    st->st_gather = stats_register("Photon mapping/Final gather rays");
    st->st_secondary = stats_register("Photon mapping/Secondary gather rays");
    st->st_lookup = stats_register("Photon mapping/Irradiance lookups");
    st->st_lookup_miss = stats_register("Photon mapping/Irradiance lookups finding nothing on their side");
    st->st_side_rays = stats_register("Photon mapping/Precomputed irradiance: visibility rays");
    st->st_side_again = stats_register("Photon mapping/Precomputed irradiance: searches again (hidden neighbour)");
    st->st_global_est = stats_register("Photon mapping/Global-map estimates (direct view)");
    st->st_emission_rays = stats_register("Photon mapping/Emission-only camera rays");
    st->st_gg_aimed = stats_register("Photon mapping/Gather rays aimed at the opening (gather guide)");
    it->data = st;
    it->preprocess = mapper_preprocess;
    it->thread_begin = mapper_thread_begin;
    it->thread_end = mapper_thread_end;
    it->li = mapper_li;
    it->destroy = mapper_destroy;
    return 0;
}

static int mapper_create(integrator *it, const scene *s, char *err, size_t errcap) {
    return create_common(it, s, 0, err, errcap);
}
static int preview_create(integrator *it, const scene *s, char *err, size_t errcap) {
    return create_common(it, s, 1, err, errcap);
}

INTEGRATOR_REGISTER(pm, "pm", "photon mapping: direct + caustic map + final gathering (Jensen)", mapper_create)
INTEGRATOR_REGISTER(preview, "preview", "photon mapping, fast preview: the global map shown directly",
                    preview_create)
