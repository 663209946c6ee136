/* photon_walk.c: the walk of one photon, for both tracers (photon_trace.h over surfaces,
 * volume.h through media); see photon_pass.h (photon_walk) and photon_path.h (its state).
 *
 * One loop: from the emission, each step meets the next surface; in a pass of the media
 * (pass_ctx.media) the photon first flies through the medium it is in (a scattering event
 * stores a volume photon and bounces it by the phase function) and crosses null surfaces
 * (a change of medium, no bounce); at a surface with a diffuse branch it stores a surface
 * photon by its pass's classes, then the material bounces it. Two rule sets stay, by the
 * pass, because each one's images and saved maps depend on its random numbers:
 *   emission   surface passes: a Halton point per photon, importance, projection maps and
 *              ports (emit_surface; photon_trace.h EMISSION); media passes: the photon's own
 *              random stream, the light by power (or by power times active fraction when
 *              aimed; emit_media, volume.h);
 *   bounce     surface passes: Russian roulette over the branches (scatter_surface,
 *              photon_trace.h SCATTERING); media passes: material_sample and roulette on the
 *              throughput (scatter_media, volume.h).
 * The shadow photons (photon_trace.h STORAGE AND CLASSES) belong to the surface passes.
 *
 * A change here that changes any stored photon must bump PHOTON_TRACE_VERSION in
 * photon_maps.h in the same commit (photon_maps.h TRACER VERSION).
 */
#include <math.h>
#include <stdlib.h>

#include "base/rng.h"
#include "base/sampling.h"
#include "photonmap/common.h"
#include "photons/importance.h"
#include "photons/photon_pass.h"
#include "photons/photon_path.h"
#include "photons/ports.h"
#include "photons/projmap.h"
#include "photons/volume.h"
#include "scene/material.h"
#include "scene/medium.h"

/* ---- emission ------------------------------------------------------------------------------ */

/* Where a photon starts: its light, origin, the light's normal there, direction, power (before
 * the pass's division by the number emitted), rel = p(l, u) / p_l, its random stream and first
 * ray. */
typedef struct walk_start {
    rng g;
    int li;
    vec3 p, n, d;
    rgb power;
    double rel;
    ray r;
} walk_start;

/* Surface passes: the light and its point from photon i's Halton point (photon_trace.h). */
static void emit_ordinary(const pass_ctx *c, uint64_t i, walk_start *w) {
    double u0 = sample_halton(i, 0, c->shift);
    double pl;
    double u[4] = {sample_halton(i, 1, c->shift), sample_halton(i, 2, c->shift), sample_halton(i, 3, c->shift),
                   sample_halton(i, 4, c->shift)};
    w->rel = 1;
    if (c->imp && !c->imp_rel_only) { /* the defensive mixture of importance.h */
        double h[4] = {u[0], u[1], u[2], u[3]};
        w->li = importance_sample(c->imp, c->s, u0, h, u, &w->rel);
        light_sample_le(c->s, w->li, u, &w->p, &w->n, &w->d);
        w->power = c->light_scale[w->li];
        return;
    }
    w->li = distrib1d_sample(&c->choose, u0, &pl);
    if (c->imp) w->rel = importance_rel(c->imp, c->s, w->li, u); /* a pilot whose photons join */
    const light *l = &c->s->lights[w->li];
    if (c->caustic_pass && c->proj) projmap_sample(&c->proj[w->li], l, sample_halton(i, 5, c->shift), &w->g, u);
    light_sample_le(c->s, w->li, u, &w->p, &w->n, &w->d);
    w->power = c->light_scale[w->li];
}

/* The pilot's counters: per material, shared by the threads. */
static void pilot_count(pilot_counts *pc, int mat) {
    if (mat < 0 || mat >= PILOT_MAX_MATS) mat = PILOT_MAX_MATS - 1;
#ifdef _OPENMP
#pragma omp atomic
#endif
    pc->by_mat[mat]++;
#ifdef _OPENMP
#pragma omp atomic
#endif
    pc->total++;
}

/* Surface passes: the Halton emission, with a share of the photons aimed through the scene's
 * photon ports (ports.h). 0: the photon carries no power. */
static int emit_surface(const pass_ctx *c, uint64_t i, walk_start *w) {
    w->g = rng_stream(c->o->seed, i, c->caustic_pass ? 2 : 1);
    emit_ordinary(c, i, w);
    if (c->s->env_map) w->power = v3_mul(w->power, light_emit_weight(c->s, w->li, w->d)); /* light.h */
    if (c->ports) ports_mix(c, i, &w->li, &w->p, &w->n, &w->d, &w->power, &w->rel);
    trace_pilot *pl = c->o->pilot;
    if (pl) {
#ifdef _OPENMP
#pragma omp atomic
#endif
        pl->emitted++;
    }
    if (v3_iszero(w->power)) return 0;
    w->r = (ray){scene_offset(c->s, w->p, w->n, w->d), w->d};
    return 1;
}

/* Media passes: the light from the photon's own stream, by c->choose (power, or power times
 * active fraction when aimed through c->proj: a point of an active cell, the power times the
 * light's active fraction), with a share of the photons aimed through the scene's photon ports
 * (ports.h, MEDIA). 0: the photon carries no power. */
static int emit_media(const pass_ctx *c, uint64_t i, walk_out *o, walk_start *w) {
    const scene *s = c->s;
    w->g = rng_stream(c->o->seed, i, c->caustic_pass ? 8 : 7);
    double pl, u[4];
    w->li = distrib1d_sample(&c->choose, rng_uniform(&w->g), &pl);
    for (int k = 0; k < 4; k++) u[k] = rng_uniform(&w->g);
    o->vp->emitted++;
    if (!(pl > 0)) return 0;
    if (c->proj) projmap_sample(&c->proj[w->li], &s->lights[w->li], rng_uniform(&w->g), &w->g, u);
    light_sample_le(s, w->li, u, &w->p, &w->n, &w->d);
    w->power = v3_scale(s->lights[w->li].power, (c->proj ? c->proj[w->li].fraction : 1.0) / pl);
    if (c->ports && !ports_mix_media(c->ports, &w->g, &w->li, &w->p, &w->n, &w->d, &w->power)) return 0; /* ports.h */
    if (s->env_map) w->power = v3_mul(w->power, light_emit_weight(s, w->li, w->d)); /* light.h */
    w->rel = 1;
    if (v3_iszero(w->power)) return 0;
    w->r = (ray){v3_iszero(w->n) ? w->p : scene_offset(s, w->p, w->n, w->d), w->d};
    return 1;
}

/* ---- stores -------------------------------------------------------------------------------- */

/* Store a record, by pass_store (the batch's cap of the memory budget, photon_rounds.c):
 * 0, PASS_OVER_BUDGET or PM_ENOMEM. */
static int walk_store(const pass_ctx *c, walk_out *o, pass_buf *b, const pass_rec *r) {
    (void)o;
    return pass_store(c, b, r);
}

/* Shadow photons (photon_trace.h): the light's ray d, continued from its first hit h straight
 * on through every surface, stores a SHADOW photon at each later diffuse hit. */
static int shadow_photons(const pass_ctx *c, uint64_t i, hit h, vec3 d, double rel, walk_out *o) {
    trace_pilot *pl = c->o->pilot;
    vec3 wo = v3_neg(d);
    int first_mat = h.mat, counted = 0; /* the pilot counts one occluded photon, not each one */
    pass_rec fp;
    for (int k = 0; k < 16; k++) {
        ray r2 = {scene_offset(c->s, h.p, h.ng, d), d};
        if (!scene_intersect(c->s, r2, INFINITY, &h)) break;
        if (!material_is_diffuse(scene_material(c->s, &h))) continue;
        if (pl && !counted++) pilot_count(&pl->occluder, first_mat);
        pass_rec_set(&fp, i, h.p, v3s(0), d, path_arrival_normal(wo, h.ng), PM_KIND_SHADOW, rel);
        int rc = walk_store(c, o, o->sb, &fp);
        if (rc != 0) return rc;
    }
    return 0;
}

/* ---- bounces ------------------------------------------------------------------------------- */

static double maxc_prod(double w, rgb t, rgb P) {
    return w * fmax(t.x * P.x, fmax(t.y * P.y, t.z * P.z));
}

/* Surface passes: Russian roulette over the branches of material m at hit h (the top of
 * photon_trace.h): the new direction in *d and power in *P; 2 for the diffuse branch, 1 for a
 * specular one, 0 when the photon ends here. */
static int scatter_surface(const pass_ctx *c, photon_path *pp, const material *m, const hit *h,
                           const double w[LOBE_COUNT], int diffuse_here, rng *g, vec3 *d, rgb *P) {
    vec3 wo = v3_neg(*d), ns = path_arrival_normal(wo, h->ng);
    vec3 nsh = material_shading_side(wo, h->ng, h->ns); /* bends directions only */
    double pmax = v3_maxc(*P);
    if (!(pmax > 0)) return 0;
    double pd = diffuse_here ? maxc_prod(w[LOBE_DIFFUSE], m->diffuse, *P) / pmax : 0;
    double pr = maxc_prod(w[LOBE_REFLECT], m->specular_tint, *P) / pmax;
    double pt = maxc_prod(w[LOBE_TRANSMIT], m->transmit_tint, *P) / pmax;
    double u = rng_uniform(g), u1 = rng_uniform(g), u2 = rng_uniform(g);
    vec3 nd;
    if (u < pd) {
        if (c->caustic_pass) return 0; /* L S* D D...: not a caustic any more */
        double k = 1; /* a share aimed through the ports (ports.h): k = cosine pdf / mixture's */
        if (c->ports) k = ports_scatter(c->ports, h->p, nsh, g, u1, u2, pp->aim, &nd), pp->aim *= k;
        else nd = sampling_to_world(sample_cosine_hemisphere(u1, u2), nsh);
        if (!(k > 0) || v3_dot(nd, ns) <= 0) return 0; /* below the real surface: absorbed */
        /* f cos / pdf = pi f for cosine sampling; branch weight over its probability. */
        rgb f = material_diffuse_f(m, nsh, wo, nd);
        *P = v3_scale(v3_mul(*P, f), M_PI * k * w[LOBE_DIFFUSE] / pd);
        pp->scattered = 1;
    } else if (u < pd + pr) {
        nd = material_reflect_shaded(*d, ns, nsh);
        *P = v3_scale(v3_mul(*P, m->specular_tint), w[LOBE_REFLECT] / pr);
        pp->specular = 1;
    } else if (u < pd + pr + pt) {
        double n1, n2;
        material_indices(m, wo, h->ng, c->s->medium_ior, &n1, &n2);
        if (!material_refract_shaded(*d, ns, nsh, n1 / n2, &nd)) nd = material_reflect_shaded(*d, ns, nsh);
        else path_refract(pp, n1, n2);
        *P = v3_scale(v3_mul(*P, m->transmit_tint), w[LOBE_TRANSMIT] / pt);
        pp->specular = 1;
    } else {
        return 0; /* absorbed */
    }
    if (v3_iszero(*P) || !v3_isfinite(*P)) return 0;
    *d = nd;
    return u < pd ? 2 : 1;
}

/* Roulette on a throughput factor w: survive with q = min(1, max channel), power * w / q. */
static int survive(rgb *power, rgb w, rng *g) {
    double q = fmin(1.0, v3_maxc(w)), u = rng_uniform(g);
    if (!(q > 0) || !(u < q)) return 0;
    *power = v3_mul(*power, v3_scale(w, 1.0 / q));
    return 1;
}

/* Media passes: material_sample at hit h and roulette on its weight (volume.h); returns as
 * scatter_surface. */
static int scatter_media(const pass_ctx *c, photon_path *pp, const material *m, const hit *h, rng *g, vec3 *d,
                         rgb *P) {
    const scene *s = c->s;
    vec3 wo = v3_neg(*d);
    bsdf_sample bs;
    double ul = rng_uniform(g), u1 = rng_uniform(g), u2 = rng_uniform(g);
    if (!material_sample_ns(m, wo, h->ng, h->ns, s->medium_ior, ul, u1, u2, &bs)) return 0;
    if (bs.lobe == LOBE_TRANSMIT && !bs.tir && m->kind != MAT_NULL) {
        double n1, n2;
        material_indices(m, wo, h->ng, s->medium_ior, &n1, &n2);
        path_refract(pp, n1, n2);
    }
    if (bs.lobe == LOBE_DIFFUSE) {
        if (c->caustic_pass) return 0; /* not L S+ any more */
        pp->scattered = 1;
    } else {
        pp->specular = 1;
    }
    if (!survive(P, bs.weight, g)) return 0;
    *d = bs.wi;
    return bs.lobe == LOBE_DIFFUSE ? 2 : 1;
}

/* ---- the walk ------------------------------------------------------------------------------ */

static int inside(const pass_ctx *c, vec3 x) {
    if (!(c->lo.x <= c->hi.x)) return 1;
    return x.x >= c->lo.x && x.y >= c->lo.y && x.z >= c->lo.z && x.x <= c->hi.x && x.y <= c->hi.y &&
           x.z <= c->hi.z;
}

static int clampi(int v, int n) { return v < 0 || v >= n ? n - 1 : v; }

/* A walk in progress: its start, path state, current medium and the surfaces it met. */
typedef struct walk_state {
    walk_start w;
    photon_path pp;
    int med;        /* the medium the photon is in (-1: none; -2: not known before the first hit) */
    int vscattered; /* a scattering event so far */
    int crossings;  /* null surfaces crossed */
    int first_mat;  /* the surface of the first bounce (the first specular one of an L S+ path) */
    int diffuse_mat; /* the surface of the last diffuse bounce */
} walk_state;

/* Media passes: the flight through the medium the photon is in, up to the surface hit h (got:
 * there is one). 1: it scattered in the medium (a volume photon stored, the ray bounced);
 * 0: it reached the surface (its power attenuated); 2: it ends here, *rc the code of the store
 * that ended it (PASS_OVER_BUDGET, PM_ENOMEM) or 0. */
static int walk_medium(const pass_ctx *c, uint64_t i, walk_state *st, int got, const hit *h, walk_out *o,
                       int *rc) {
    const scene *s = c->s;
    ray *r = &st->w.r;
    if (st->med == -2) /* the emitter's interface, else the side of the first surface facing it */
        st->med = scene_light_medium(s, st->w.li, st->w.p, st->w.n, st->w.d,
                                     got ? scene_medium_side(s, h, v3_neg(r->d), -2) : s->global_medium);
    if (st->med < 0) return 0;
    rng *g = &st->w.g;
    double uc = rng_uniform(g), ud = rng_uniform(g), t;
    rgb w;
    if (!medium_sample_distance(&s->media[st->med], got ? h->t : INFINITY, uc, ud, &t, &w)) {
        st->w.power = v3_mul(st->w.power, w);
        return v3_iszero(st->w.power) ? 2 : 0;
    }
    if (v3_iszero(w)) return 2; /* sigma_s = 0: absorbed, nothing scatters */
    vec3 x = ray_at(*r, t);
    int kind = path_kind(&st->pp);
    o->vp->events[clampi(st->med, VOL_PILOT_MEDIA)][kind]++;
    if (kind == PM_KIND_CAUSTIC) o->vp->caustic_by_mat[clampi(st->first_mat, VOL_PILOT_MATS)]++;
    if (c->keep_volume && (!c->caustic_pass || kind == PM_KIND_CAUSTIC) && inside(c, x)) {
        pass_rec v;
        pass_rec_set(&v, i, x, v3_mul(st->w.power, w), r->d, v3s(0), kind, 1);
        v.medium = (int16_t)st->med;
        if ((*rc = walk_store(c, o, o->sb, &v)) != 0) return 2;
    }
    if (c->caustic_pass) return 2; /* not L S+ any more */
    st->pp.scattered = st->vscattered = 1;
    if (!survive(&st->w.power, w, g)) return 2;
    vec3 nd;
    /* Two draws, named so their order is fixed: as arguments of one call it would be the
     * compiler's (gcc drew u2 first, clang u1; the images have always been gcc's). */
    double u2 = rng_uniform(g), u1 = rng_uniform(g);
    hg_sample(s->media[st->med].g, r->d, u1, u2, &nd);
    r->o = x;
    r->d = nd;
    st->pp.depth++;
    return 1;
}

/* The store at a surface with a diffuse branch (photon_trace.h STORAGE AND CLASSES; volume.h
 * PASSES): the pass's classes, the pilots' counts. 0 or a store's code. */
static int walk_surface_store(const pass_ctx *c, uint64_t i, walk_state *st, const hit *h, int from_area,
                              walk_out *o) {
    const photon_path *pp = &st->pp;
    trace_pilot *pl = c->o->pilot;
    vec3 d = st->w.r.d, ns = path_arrival_normal(v3_neg(d), h->ng);
    int kind = path_kind(pp), rc;
    if (o->vp) {
        if (kind == PM_KIND_DIRECT) o->vp->surf_direct++;
        if (kind == PM_KIND_CAUSTIC) o->vp->surf_caustic++;
        if (kind == PM_KIND_INDIRECT) o->vp->surf_indirect++;
        if (st->vscattered) o->vp->surf_after_scatter++;
    }
    rgb Ps = v3_scale(st->w.power, path_store_scale(pp));
    pass_rec fp;
    if (c->caustic_pass) {
        if (kind != PM_KIND_CAUSTIC) return 0;
        if (pl) pilot_count(&pl->caustic, st->first_mat);
        pass_rec_set(&fp, i, h->p, Ps, d, ns, PM_KIND_CAUSTIC, st->w.rel);
        /* The surface tracer's caustic pass always keeps its map; a media pass, if want_global. */
        return !c->media || c->want_global ? walk_store(c, o, o->gb, &fp) : 0;
    }
    if (pl && pp->scattered) pilot_count(&pl->diffuse_bounce, st->diffuse_mat);
    pass_rec_set(&fp, i, h->p, Ps, d, ns, path_global_kind(pp), st->w.rel);
    if (c->want_global && (rc = walk_store(c, o, o->gb, &fp)) != 0) return rc;
    if (c->want_shadow && from_area && pp->depth == 0 && (rc = walk_store(c, o, o->sb, &fp)) != 0) return rc;
    return 0;
}

int photon_walk(const pass_ctx *c, uint64_t i, walk_out *o) {
    const scene *s = c->s;
    walk_state st = {0};
    if (!(c->media ? emit_media(c, i, o, &st.w) : emit_surface(c, i, &st.w))) return 0;
    int from_area = s->lights[st.w.li].type == LIGHT_AREA;
    trace_pilot *pl = c->o->pilot;
    st.pp = path_start(c->o->max_depth, c->o->max_bounces);
    st.med = c->media ? -2 : -1;
    st.first_mat = st.diffuse_mat = -1;
    ray *r = &st.w.r;
    int rc;
    while (st.pp.depth <= st.pp.max_depth) {
        hit h;
        int got = scene_intersect(s, *r, INFINITY, &h);
        if (c->media) {
            rc = 0;
            int flight = walk_medium(c, i, &st, got, &h, o, &rc);
            if (flight == 1) continue;
            if (flight == 2) return rc;
        }
        if (!got) break;
        const material *m = scene_material(s, &h);
        if (c->media && m->kind == MAT_NULL) { /* only the medium changes */
            if (++st.crossings > 4 * st.pp.max_depth + 1024) return 0;
            st.med = scene_medium_next(s, &h, r->d, r->d, st.med);
            r->o = scene_offset(s, h.p, h.ng, r->d);
            continue;
        }
        double w[LOBE_COUNT];
        material_weights(m, v3_neg(r->d), h.ng, s->medium_ior, w);
        int diffuse_here = w[LOBE_DIFFUSE] > 0 && v3_maxc(m->diffuse) > 0;
        if (c->caustic_pass && st.pp.depth == 0 && !diffuse_here) o->first_specular |= 1;
        if (st.pp.depth == 0) st.first_mat = h.mat; /* an L S+ D path's first surface is specular */
        if (pl && st.pp.depth == 0) pilot_count(&pl->first_hits, h.mat);
        if (diffuse_here && (rc = walk_surface_store(c, i, &st, &h, from_area, o)) != 0) return rc;
        if (c->want_shadow && from_area && st.pp.depth == 0 &&
            (rc = shadow_photons(c, i, h, r->d, st.w.rel, o)) != 0)
            return rc;
        vec3 d = r->d;
        int branch = c->media ? scatter_media(c, &st.pp, m, &h, &st.w.g, &d, &st.w.power)
                              : scatter_surface(c, &st.pp, m, &h, w, diffuse_here, &st.w.g, &d, &st.w.power);
        if (!branch) return 0;
        if (branch == 2) st.diffuse_mat = h.mat;
        if (c->media) st.med = scene_medium_next(s, &h, r->d, d, st.med);
        r->o = scene_offset(s, h.p, h.ng, d);
        r->d = d;
        st.pp.depth++;
    }
    if (path_cut(&st.pp)) o->first_specular |= 2; /* still alive: the path-length budget cut it */
    return 0;
}
