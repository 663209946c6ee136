/* plan.c: the per-scene plan of photon-mapping effects; see plan.h.
 *
 * The plan is decided by probes, not by material names alone: a glass sphere hidden in a box
 * without light makes no caustics, and a single diffuse sphere under a sun has nothing to
 * interreflect with. Each probe is a fixed number of rays drawn from fixed streams (seed
 * PLAN_SEED), so the decision is deterministic. The probes are cheap (a few thousand rays)
 * next to tracing photons.
 */
#include "plan.h"

#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "rng.h"
#include "sampling.h"

#define PLAN_SEED 0x706c616eULL /* "plan" */

/* ---- probes ------------------------------------------------------------------------------ */

static int prim_count(const scene *s) { return s->ntris + s->nspheres; }
static const material *prim_mat(const scene *s, int prim) {
    return &s->mats[prim < s->ntris ? s->tris[prim].mat : s->spheres[prim - s->ntris].mat];
}

/* A uniform point on primitive prim and its outward (front) normal. */
static void prim_point(const scene *s, int prim, rng *g, vec3 *p, vec3 *n) {
    double u1 = rng_uniform(g), u2 = rng_uniform(g);
    if (prim < s->ntris) {
        *p = triangle_sample(&s->tris[prim], u1, u2);
        *n = s->tris[prim].n;
    } else {
        const sphere *sp = &s->spheres[prim - s->ntris];
        *n = sample_uniform_sphere(u1, u2);
        *p = v3_madd(sp->c, *n, sp->r);
    }
}

/* Lights that emit photons: every light in the list with some power. */
static int emitting_lights(const scene *s) {
    int n = 0;
    for (int i = 0; i < s->nlights; i++) n += v3_maxc(s->lights[i].power) > 0;
    return n;
}

static int any_diffuse(const scene *s) {
    for (int i = 0; i < prim_count(s); i++)
        if (material_is_diffuse(prim_mat(s, i))) return 1;
    return 0;
}

/* Is point p (normal n, either side) lit straight by light li for some sample? */
static int lit_by(const scene *s, int li, vec3 p, vec3 n, rng *g) {
    const light *l = &s->lights[li];
    if (l->type == LIGHT_DIRECTIONAL) {
        vec3 w = v3_neg(l->dir);
        vec3 nn = v3_dot(w, n) >= 0 ? n : v3_neg(n);
        return scene_visible_dir(s, p, nn, w);
    }
    light_sample ls;
    if (!light_sample_li(s, li, p, rng_uniform(g), rng_uniform(g), &ls)) return 0;
    if (v3_iszero(ls.L)) return 0;
    vec3 nn = v3_dot(ls.wi, n) >= 0 ? n : v3_neg(n);
    return scene_visible(s, p, nn, ls.p, ls.n);
}

static void set(plan_item *it, int on, const char *fmt, const char *arg) {
    it->on = on;
    snprintf(it->reason, sizeof it->reason, fmt, arg);
}

static void plan_caustics(const scene *s, render_plan *p) {
    int nspec = 0;
    for (int i = 0; i < prim_count(s); i++)
        nspec += material_is_specular(prim_mat(s, i));
    if (!nspec) {
        set(&p->caustics, 0, "no specular surface%s", "");
        return;
    }
    if (!emitting_lights(s)) {
        set(&p->caustics, 0, "no light emits photons%s", "");
        return;
    }
    if (!any_diffuse(s)) {
        set(&p->caustics, 0, "no diffuse surface to receive them%s", "");
        return;
    }
    rng g = rng_stream(PLAN_SEED, 1, 0);
    for (int i = 0; i < prim_count(s); i++) {
        if (!material_is_specular(prim_mat(s, i))) continue;
        for (int k = 0; k < 64; k++) {
            vec3 q, n;
            prim_point(s, i, &g, &q, &n);
            for (int li = 0; li < s->nlights; li++)
                if (lit_by(s, li, q, n, &g)) {
                    char what[96];
                    snprintf(what, sizeof what, "%s", prim_mat(s, i)->name);
                    set(&p->caustics, 1,
                        "specular surface \"%s\" is lit straight from a light: L S+ D paths",
                        what);
                    return;
                }
        }
    }
    set(&p->caustics, 0, "no specular surface reachable from a light%s", "");
}

/* Follow a probe ray through specular surfaces (one branch chosen by weight, as a photon
 * would) to the first surface with a diffuse branch. Returns 1 with the hit in *h and the
 * ray's last direction in r->d; 0 if it escapes, is absorbed or runs out of steps. */
static int probe_to_diffuse(const scene *s, ray *r, rng *g, hit *h) {
    for (int step = 0; step < 16; step++) {
        if (!scene_intersect(s, *r, INFINITY, h)) return 0;
        const material *m = scene_material(s, h);
        vec3 wo = v3_neg(r->d);
        double w[LOBE_COUNT];
        material_weights(m, wo, h->ng, s->medium_ior, w);
        if (w[LOBE_DIFFUSE] > 0 && v3_maxc(m->diffuse) > 0) return 1;
        double wr = v3_iszero(m->specular_tint) ? 0 : w[LOBE_REFLECT];
        double wt = v3_iszero(m->transmit_tint) ? 0 : w[LOBE_TRANSMIT];
        if (!(wr + wt > 0)) return 0;
        vec3 ns = v3_dot(wo, h->ng) >= 0 ? h->ng : v3_neg(h->ng);
        vec3 d;
        if (rng_uniform(g) * (wr + wt) < wr) {
            d = v3_reflect(r->d, ns);
        } else {
            double n1, n2;
            material_indices(m, wo, h->ng, s->medium_ior, &n1, &n2);
            if (!refract_dir(r->d, ns, n1 / n2, &d)) d = v3_reflect(r->d, ns);
        }
        r->o = v3_offset(h->p, h->ng, d);
        r->d = d;
    }
    return 0;
}

/* The probe follows light as photons do: a ray leaves a light (light_sample_le), passes
 * specular surfaces to a diffuse surface y, and leaves y on the side it arrived at with a
 * cosine-distributed direction; if that ray reaches another diffuse surface (again through
 * any specular ones), diffuse light reflects onto diffuse surfaces. Starting from the lights
 * matters: probing both sides of every diffuse primitive would count the unlit inside of a
 * closed sphere or mesh, which always "sees" itself. */
static void plan_global(const scene *s, render_plan *p) {
    if (!emitting_lights(s)) {
        set(&p->global, 0, "no light emits photons%s", "");
        return;
    }
    rng g = rng_stream(PLAN_SEED, 2, 0);
    for (int k = 0; k < 4096; k++) {
        double pl, u[4];
        int li = distrib1d_sample(&s->light_distrib, rng_uniform(&g), &pl);
        if (!(pl > 0)) continue;
        for (int j = 0; j < 4; j++) u[j] = rng_uniform(&g);
        vec3 o, n, d;
        light_sample_le(s, li, u, &o, &n, &d);
        ray r = {v3_offset(o, n, d), d};
        hit y, x;
        if (!probe_to_diffuse(s, &r, &g, &y)) continue;
        vec3 ny = v3_dot(r.d, y.ng) <= 0 ? y.ng : v3_neg(y.ng); /* the side it arrived at */
        vec3 d2 = sampling_to_world(sample_cosine_hemisphere(rng_uniform(&g), rng_uniform(&g)), ny);
        ray r2 = {v3_offset(y.p, y.ng, d2), d2};
        if (probe_to_diffuse(s, &r2, &g, &x)) {
            set(&p->global, 1,
                "diffuse surfaces reflect onto each other (\"%s\" sees another): "
                "indirect diffuse light",
                scene_material(s, &y)->name);
            return;
        }
    }
    set(&p->global, 0, "no diffuse surface reflects onto another%s", "");
}

static void plan_shadow(const scene *s, render_plan *p) {
    int area = 0;
    for (int i = 0; i < s->nlights; i++) area += s->lights[i].type == LIGHT_AREA && v3_maxc(s->lights[i].power) > 0;
    if (!area) {
        set(&p->shadow, 0,
            "no area light of triangles (point, directional and sphere lights take one shadow ray each)%s",
            "");
        return;
    }
    int ndiff = 0;
    for (int i = 0; i < prim_count(s); i++)
        ndiff += material_is_diffuse(prim_mat(s, i));
    if (!ndiff) {
        set(&p->shadow, 0, "no diffuse surface%s", "");
        return;
    }
    rng g = rng_stream(PLAN_SEED, 3, 0);
    int tried = 0, blocked = 0;
    for (int k = 0; k < 8192; k++) {
        int li = (int)(rng_uniform(&g) * s->nlights);
        int pi = (int)(rng_uniform(&g) * prim_count(s));
        if (li >= s->nlights || pi >= prim_count(s)) continue;
        if (s->lights[li].type != LIGHT_AREA || !material_is_diffuse(prim_mat(s, pi))) continue;
        if (pi < s->ntris && s->tris[pi].light == li) continue;
        vec3 q, n;
        prim_point(s, pi, &g, &q, &n);
        light_sample ls;
        if (!light_sample_li(s, li, q, rng_uniform(&g), rng_uniform(&g), &ls) || v3_iszero(ls.L))
            continue;
        /* Only pairs that face each other: a wall behind the light is not "occluded". */
        vec3 nn = v3_dot(ls.wi, n) >= 0 ? n : v3_neg(n);
        if (pi >= s->ntris && v3_dot(ls.wi, n) < 0) continue; /* far side of a sphere: self */
        tried++;
        if (!scene_visible(s, q, nn, ls.p, ls.n)) blocked++;
    }
    if (blocked) {
        char buf[64];
        snprintf(buf, sizeof buf, "%d of %d", blocked, tried);
        set(&p->shadow, 1, "area light with occluders (%s probe segments blocked)", buf);
        return;
    }
    set(&p->shadow, 0, "nothing occludes the area lights%s", "");
}

/* Apply a forced setting from the scene file (or --pm key=true|false). */
static void force(plan_item *it, int f, const char *key) {
    if (f == PLAN_AUTO) return;
    it->on = f == PLAN_ON;
    snprintf(it->reason, sizeof it->reason, "forced by photon_mapping.%s", key);
}

void plan_make(const scene *s, const photon_settings *c, int preview, render_plan *p) {
    memset(p, 0, sizeof *p);
    plan_caustics(s, p);
    plan_global(s, p);
    plan_shadow(s, p);
    force(&p->caustics, c->force_caustics, "caustics");
    force(&p->global, c->force_global, "global");
    force(&p->shadow, c->force_shadow, "shadow");
    if (preview)
        set(&p->final_gather, 0, "preview mode: the global map is shown directly%s", "");
    else if (!p->global.on)
        set(&p->final_gather, 0, "no global map to gather from%s", "");
    else if (c->force_final_gather == PLAN_OFF)
        set(&p->final_gather, 0, "forced by photon_mapping.final_gather: the global map is shown directly%s", "");
    else if (c->force_final_gather == PLAN_ON)
        set(&p->final_gather, 1, "forced by photon_mapping.final_gather%s", "");
    else
        set(&p->final_gather, 1,
            "indirect diffuse by gather rays reading precomputed irradiance of the global map%s", "");
}

void plan_print(const render_plan *p, FILE *f) {
    fprintf(f, "Plan:\n");
    fprintf(f, "  caustics: %s (%s)\n", p->caustics.on ? "on" : "off", p->caustics.reason);
    fprintf(f, "  global: %s (%s)\n", p->global.on ? "on" : "off", p->global.reason);
    fprintf(f, "  shadow photons: %s (%s)\n", p->shadow.on ? "on" : "off", p->shadow.reason);
    fprintf(f, "  final gather: %s (%s)\n", p->final_gather.on ? "on" : "off", p->final_gather.reason);
}
