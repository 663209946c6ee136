/* plan.c: the photon-mapping settings and the per-scene plan of effects; see plan.h.
 *
 * The plan is decided by probes, not by material names alone: a glass sphere hidden in a box
 * without light makes no caustics, and a single diffuse sphere under a sun has nothing to
 * interreflect with. Each probe is a fixed number of rays drawn from fixed streams (seed
 * PLAN_SEED), so the decision is deterministic. The probes are cheap (a few thousand rays)
 * next to tracing photons.
 */
#include "plan.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "common.h"
#include "rng.h"
#include "sampling.h"

#define PLAN_SEED 0x706c616eULL /* "plan" */

void pm_config_defaults(pm_config *c) {
    memset(c, 0, sizeof *c);
    c->force_caustics = c->force_global = c->force_shadow = c->force_final_gather = PLAN_AUTO;
    c->global_photons = 200000;
    c->caustic_photons = 500000;
    c->k_global = 100;
    c->k_caustic = 60;
    c->k_shadow = 16;
    c->filter = PM_FILTER_CONE;
    c->gather_rays = 4;
    c->secondary_rays = 2;
    c->split_depth = 2;
    c->caustic_stride = 2;
    c->emission_strata = 2;
    c->max_emitted_factor = 64;
    c->projection_cells = 64;
    c->projection = 1;
    c->progress = 1;
}

const char *pm_filter_name(int filter) {
    switch (filter) {
    case PM_FILTER_NONE: return "none";
    case PM_FILTER_CONE: return "cone";
    case PM_FILTER_GAUSS: return "gauss";
    case PM_FILTER_HULL: return "hull";
    }
    return "?";
}

static int get_force(const cJSON *pm, const char *key, int *out, json_err *e) {
    if (!json_get(pm, key)) return 0;
    int b = 0;
    int rc = json_bool(pm, "$.photon_mapping", key, 1, &b, e);
    if (rc < 0) return rc;
    *out = b ? PLAN_ON : PLAN_OFF;
    return 0;
}

static int get_long(const cJSON *pm, const char *key, long lo, long hi, long *out, json_err *e) {
    return json_int(pm, "$.photon_mapping", key, 0, lo, hi, out, e);
}

static int get_int(const cJSON *pm, const char *key, long lo, long hi, int *out, json_err *e) {
    long v = *out;
    int rc = json_int(pm, "$.photon_mapping", key, 0, lo, hi, &v, e);
    if (rc == 0) *out = (int)v;
    return rc;
}

static int get_nonneg(const cJSON *pm, const char *key, double *out, json_err *e) {
    int rc = json_number(pm, "$.photon_mapping", key, 0, out, e);
    if (rc < 0) return rc;
    if (*out < 0)
        return json_fail(e, PM_EINVAL, "$.photon_mapping.%s: must be >= 0, got %g", key, *out);
    return 0;
}

static int get_dir(const cJSON *pm, const char *key, char *dst, size_t cap, json_err *e) {
    const char *s = NULL;
    int rc = json_string(pm, "$.photon_mapping", key, 0, &s, e);
    if (rc < 0) return rc;
    if (s) {
        if (strlen(s) >= cap)
            return json_fail(e, PM_EINVAL, "$.photon_mapping.%s: path too long", key);
        snprintf(dst, cap, "%s", s);
    }
    return 0;
}

#define TRY(x)                  \
    do {                        \
        int rc_ = (x);          \
        if (rc_ < 0) return rc_; \
    } while (0)

int pm_config_parse(pm_config *c, const cJSON *pm, json_err *e) {
    pm_config_defaults(c);
    if (!pm) return 0;
    static const char *known[] = {
        "caustics", "global", "shadow", "final_gather", "global_photons", "caustic_photons",
        "k_global", "k_caustic", "k_shadow", "max_radius_global", "max_radius_caustic",
        "filter", "gather_rays", "secondary_rays", "split_depth", "caustic_stride", "emission_strata", "secondary_distance", "max_emitted_factor",
        "projection_cells", "projection", "progress", "save_photons", "load_photons", "comment"};
    for (const cJSON *it = pm->child; it; it = it->next) {
        int ok = 0;
        for (size_t k = 0; k < sizeof known / sizeof *known; k++)
            if (it->string && strcmp(it->string, known[k]) == 0) ok = 1;
        if (!ok)
            return json_fail(e, PM_EINVAL, "$.photon_mapping.%s: unknown key",
                             it->string ? it->string : "?");
    }
    TRY(get_force(pm, "caustics", &c->force_caustics, e));
    TRY(get_force(pm, "global", &c->force_global, e));
    TRY(get_force(pm, "shadow", &c->force_shadow, e));
    TRY(get_force(pm, "final_gather", &c->force_final_gather, e));
    TRY(get_long(pm, "global_photons", 0, 100000000L, &c->global_photons, e));
    TRY(get_long(pm, "caustic_photons", 0, 100000000L, &c->caustic_photons, e));
    TRY(get_int(pm, "k_global", 1, 10000, &c->k_global, e));
    TRY(get_int(pm, "k_caustic", 1, 10000, &c->k_caustic, e));
    TRY(get_int(pm, "k_shadow", 1, 1000, &c->k_shadow, e));
    TRY(get_nonneg(pm, "max_radius_global", &c->max_radius_global, e));
    TRY(get_nonneg(pm, "max_radius_caustic", &c->max_radius_caustic, e));
    TRY(get_int(pm, "gather_rays", 0, 100000, &c->gather_rays, e));
    TRY(get_int(pm, "secondary_rays", 0, 100000, &c->secondary_rays, e));
    TRY(get_int(pm, "split_depth", 0, 16, &c->split_depth, e));
    TRY(get_int(pm, "caustic_stride", 1, 64, &c->caustic_stride, e));
    TRY(get_int(pm, "emission_strata", 0, 16, &c->emission_strata, e));
    TRY(get_nonneg(pm, "secondary_distance", &c->secondary_distance, e));
    TRY(get_nonneg(pm, "max_emitted_factor", &c->max_emitted_factor, e));
    if (c->max_emitted_factor < 1)
        return json_fail(e, PM_EINVAL, "$.photon_mapping.max_emitted_factor: must be >= 1, got %g",
                         c->max_emitted_factor);
    TRY(get_int(pm, "projection_cells", 1, 4096, &c->projection_cells, e));
    TRY(json_bool(pm, "$.photon_mapping", "projection", 0, &c->projection, e));
    TRY(json_bool(pm, "$.photon_mapping", "progress", 0, &c->progress, e));
    const char *f = NULL;
    TRY(json_string(pm, "$.photon_mapping", "filter", 0, &f, e));
    if (f) {
        if (strcmp(f, "none") == 0 || strcmp(f, "disc") == 0)
            c->filter = PM_FILTER_NONE;
        else if (strcmp(f, "cone") == 0)
            c->filter = PM_FILTER_CONE;
        else if (strcmp(f, "gauss") == 0 || strcmp(f, "gaussian") == 0)
            c->filter = PM_FILTER_GAUSS;
        else if (strcmp(f, "hull") == 0 || strcmp(f, "convex_hull") == 0)
            c->filter = PM_FILTER_HULL;
        else
            return json_fail(e, PM_EINVAL,
                             "$.photon_mapping.filter: expected \"none\", \"cone\", \"gauss\" or "
                             "\"hull\", got \"%s\"",
                             f);
    }
    TRY(get_dir(pm, "save_photons", c->save_dir, sizeof c->save_dir, e));
    TRY(get_dir(pm, "load_photons", c->load_dir, sizeof c->load_dir, e));
    return 0;
}

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
    for (int i = 0; i < prim_count(s); i++) nspec += material_is_specular(prim_mat(s, i));
    if (!nspec) return set(&p->caustics, 0, "no specular surface%s", "");
    if (!emitting_lights(s)) return set(&p->caustics, 0, "no light emits photons%s", "");
    if (!any_diffuse(s)) return set(&p->caustics, 0, "no diffuse surface to receive them%s", "");
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
                    return set(&p->caustics, 1,
                               "specular surface \"%s\" is lit straight from a light: L S+ D paths",
                               what);
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
    if (!emitting_lights(s))
        return set(&p->global, 0,
                   "no light emits photons%s", "");
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
        if (probe_to_diffuse(s, &r2, &g, &x))
            return set(&p->global, 1,
                       "diffuse surfaces reflect onto each other (\"%s\" sees another): "
                       "indirect diffuse light",
                       scene_material(s, &y)->name);
    }
    set(&p->global, 0, "no diffuse surface reflects onto another%s", "");
}

static void plan_shadow(const scene *s, render_plan *p) {
    int area = 0;
    for (int i = 0; i < s->nlights; i++) area += s->lights[i].type == LIGHT_AREA && v3_maxc(s->lights[i].power) > 0;
    if (!area)
        return set(&p->shadow, 0, "no area light of triangles (point, directional and sphere lights take one shadow ray each)%s", "");
    int ndiff = 0;
    for (int i = 0; i < prim_count(s); i++) ndiff += material_is_diffuse(prim_mat(s, i));
    if (!ndiff) return set(&p->shadow, 0, "no diffuse surface%s", "");
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
        return set(&p->shadow, 1, "area light with occluders (%s probe segments blocked)", buf);
    }
    set(&p->shadow, 0, "nothing occludes the area lights%s", "");
}

/* Apply a forced setting from the scene file (or --pm key=true|false). */
static void force(plan_item *it, int f, const char *key) {
    if (f == PLAN_AUTO) return;
    it->on = f == PLAN_ON;
    snprintf(it->reason, sizeof it->reason, "forced by photon_mapping.%s", key);
}

void plan_make(const scene *s, const pm_config *c, int preview, render_plan *p) {
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

/* ---- command line ------------------------------------------------------------------------ */

int plan_cli_set(cJSON **pm, const char *flag, const char *value, char *err, size_t errcap) {
    char key[64];
    const char *val;
    if (strcmp(flag, "--save-photons") == 0 || strcmp(flag, "--load-photons") == 0) {
        snprintf(key, sizeof key, "%s", flag[2] == 's' ? "save_photons" : "load_photons");
        val = value;
    } else {
        const char *eq = strchr(value, '=');
        if (!eq || eq == value || (size_t)(eq - value) >= sizeof key) {
            snprintf(err, errcap, "%s: expected KEY=VALUE, got '%s'", flag, value);
            return PM_EINVAL;
        }
        memcpy(key, value, (size_t)(eq - value));
        key[eq - value] = 0;
        val = eq + 1;
    }
    if (!*pm) *pm = cJSON_CreateObject();
    if (!*pm) {
        snprintf(err, errcap, "out of memory");
        return PM_ENOMEM;
    }
    cJSON *item;
    char *end;
    errno = 0;
    double num = strtod(val, &end);
    int is_path = strcmp(key, "save_photons") == 0 || strcmp(key, "load_photons") == 0 ||
                  strcmp(key, "filter") == 0;
    if (!is_path && strcmp(val, "true") == 0)
        item = cJSON_CreateBool(1);
    else if (!is_path && strcmp(val, "false") == 0)
        item = cJSON_CreateBool(0);
    else if (!is_path && *val && !*end && !errno)
        item = cJSON_CreateNumber(num);
    else
        item = cJSON_CreateString(val);
    if (!item) {
        snprintf(err, errcap, "out of memory");
        return PM_ENOMEM;
    }
    cJSON_DeleteItemFromObjectCaseSensitive(*pm, key);
    cJSON_AddItemToObject(*pm, key, item);
    return 0;
}
