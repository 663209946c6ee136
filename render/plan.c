/* plan.c: the per-scene plan of photon-mapping effects; see plan.h.
 *
 * The plan is decided from the lights' point of view, not by material names alone: a glass
 * sphere hidden in a box without light makes no caustics, a light inside a closed mirror
 * stores nothing, and a single diffuse sphere under a sun has nothing to interreflect with.
 * A pilot pass traces a few thousand photons with photon_trace itself (so the pilot and the
 * real passes can never disagree about what a photon does) and counts what they do: L S+ D
 * stores (caustic pilot, aimed at the specular objects through the projection maps, so an
 * opening is found whenever a fair share of the aimed photons passes it: an opening that
 * passes fewer than about 1 in 8192 of them can still be missed), stores after a diffuse
 * bounce (global), and photons that pass their first hit and reach a diffuse surface behind
 * it (shadow photons). Each reason prints those counts and the materials involved. The
 * pilot uses fixed streams (seed PLAN_SEED), so the plan is deterministic, and costs about
 * 16384 photon paths. Its photons are not reused by the real passes (those use their own
 * streams and targets).
 */
#include "plan.h"

#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "photon_trace.h"
#include "rng.h"
#include "sampling.h"

#define PLAN_SEED 0x706c616eULL /* "plan" */
#define PILOT_BATCHES 2          /* photons per pilot: 2 x PT_BATCH = 8192 */

/* ---- probes ------------------------------------------------------------------------------ */

static int prim_count(const scene *s) { return s->ntris + s->nspheres; }
static const material *prim_mat(const scene *s, int prim) {
    return &s->mats[prim < s->ntris ? s->tris[prim].mat : s->spheres[prim - s->ntris].mat];
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

static void set(plan_item *it, int on, const char *fmt, const char *arg) {
    it->on = on;
    snprintf(it->reason, sizeof it->reason, fmt, arg);
}

/* ---- the pilot pass ------------------------------------------------------------------------ */

/* "\"white\" 120, \"red\" 31" : the (up to) three materials with the largest counts. */
static void top_mats(const scene *s, const pilot_counts *pc, char *buf, size_t cap) {
    int used[PILOT_MAX_MATS] = {0};
    size_t len = 0;
    buf[0] = 0;
    for (int r = 0; r < 3; r++) {
        int best = -1;
        for (int i = 0; i < PILOT_MAX_MATS; i++)
            if (!used[i] && pc->by_mat[i] > 0 && (best < 0 || pc->by_mat[i] > pc->by_mat[best])) best = i;
        if (best < 0) break;
        used[best] = 1;
        const char *name = best < s->nmats && best < PILOT_MAX_MATS - 1 ? s->mats[best].name : "(others)";
        int w = snprintf(buf + len, cap - len, "%s\"%s\" %llu", r ? ", " : "", name,
                         pc->by_mat[best]);
        if (w < 0 || (size_t)w >= cap - len) break;
        len += (size_t)w;
    }
}

typedef struct pilot_result {
    trace_pilot g, c;                     /* evidence of the global and the caustic pilot */
    uint64_t g_emitted, c_emitted;        /* pilot photons emitted by each */
    size_t g_stored;                      /* photons the global pilot stored */
} pilot_result;

/* The pilot: PILOT_BATCHES batches of photons traced exactly as the real passes trace them
 * (same emission, scattering and storage rules; the caustic pilot aimed at the specular
 * objects by the projection maps, so a specular object lit only through a small opening still
 * receives its share of the aimed photons), counting what they do instead of keeping them. */
static void run_pilot(const scene *s, pilot_result *r) {
    memset(r, 0, sizeof *r);
    trace_opts o;
    trace_opts_init(&o, s);
    o.seed = PLAN_SEED;
    o.quiet = 1;
    o.max_emitted = (double)PILOT_BATCHES * PT_BATCH;
    o.max_emitted_factor = 1e300;
    photon_maps m;
    char err[256];
    o.pilot = &r->g;
    o.global = o.shadow = 1;
    o.global_target = 1L << 40; /* never reached: the emission budget ends the pilot */
    photon_trace(s, &o, &m, err, sizeof err); /* PM_EEMPTY (nothing stored) is evidence too */
    r->g_emitted = r->g.emitted;
    r->g_stored = m.nglobal;
    photon_maps_free(&m);
    o.pilot = &r->c;
    o.global = o.shadow = 0;
    o.caustic = 1;
    o.caustic_target = 1L << 40;
    photon_trace(s, &o, &m, err, sizeof err);
    r->c_emitted = r->c.emitted;
    photon_maps_free(&m);
}

static void plan_caustics(const scene *s, const pilot_result *r, render_plan *p) {
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
    char mats[128], buf[300];
    if (r->c.caustic.total > 0) {
        top_mats(s, &r->c.caustic, mats, sizeof mats);
        snprintf(buf, sizeof buf,
                 "L S+ D paths: %llu photons stored through specular surfaces (first %s), from "
                 "%llu pilot photons aimed at them",
                 r->c.caustic.total, mats, (unsigned long long)r->c_emitted);
        set(&p->caustics, 1, "%s", buf);
        return;
    }
    if (r->c_emitted == 0) {
        set(&p->caustics, 0,
            "no specular surface reachable from a light (no light faces one: the "
            "projection maps are empty)%s",
            "");
        return;
    }
    top_mats(s, &r->c.first_hits, mats, sizeof mats);
    snprintf(buf, sizeof buf,
             "no specular surface reachable from a light leads to a diffuse one: 0 of %llu pilot "
             "photons aimed at the specular surfaces were stored (first hits: %s)",
             (unsigned long long)r->c_emitted, mats[0] ? mats : "none");
    set(&p->caustics, 0, "%s", buf);
}

static void plan_global(const scene *s, const pilot_result *r, render_plan *p) {
    if (!emitting_lights(s)) {
        set(&p->global, 0, "no light emits photons%s", "");
        return;
    }
    char mats[128], buf[300];
    if (r->g.diffuse_bounce.total > 0) {
        top_mats(s, &r->g.diffuse_bounce, mats, sizeof mats);
        snprintf(buf, sizeof buf,
                 "diffuse surfaces reflect onto each other: %llu photons stored after a diffuse "
                 "bounce off %s, from %llu pilot photons: indirect diffuse light",
                 r->g.diffuse_bounce.total, mats, (unsigned long long)r->g_emitted);
        set(&p->global, 1, "%s", buf);
        return;
    }
    top_mats(s, &r->g.first_hits, mats, sizeof mats);
    if (r->g_stored == 0)
        snprintf(buf, sizeof buf,
                 "no diffuse surface reflects onto another: no surface the lights reach stores "
                 "photons, 0 of %llu pilot photons stored (first hits: %s)",
                 (unsigned long long)r->g_emitted, mats[0] ? mats : "none");
    else
        snprintf(buf, sizeof buf,
                 "no diffuse surface reflects onto another: %zu pilot photons stored, none after "
                 "a diffuse bounce (%llu emitted)",
                 r->g_stored, (unsigned long long)r->g_emitted);
    set(&p->global, 0, "%s", buf);
}

static void plan_shadow(const scene *s, const pilot_result *r, render_plan *p) {
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
    char mats[128], buf[300];
    if (r->g.occluder.total > 0) {
        top_mats(s, &r->g.occluder, mats, sizeof mats);
        snprintf(buf, sizeof buf,
                 "area light with occluders: %llu of %llu pilot photons reach a diffuse surface "
                 "behind their first hit; occluders %s",
                 r->g.occluder.total, (unsigned long long)r->g_emitted, mats);
        set(&p->shadow, 1, "%s", buf);
        return;
    }
    top_mats(s, &r->g.first_hits, mats, sizeof mats);
    if (r->g_stored == 0)
        snprintf(buf, sizeof buf,
                 "no surface the lights reach stores photons: 0 of %llu pilot photons stored "
                 "(first hits: %s)",
                 (unsigned long long)r->g_emitted, mats[0] ? mats : "none");
    else
        snprintf(buf, sizeof buf,
                 "nothing occludes the area lights: none of %llu pilot photons reaches a "
                 "diffuse surface behind its first hit (first hits: %s)",
                 (unsigned long long)r->g_emitted, mats);
    set(&p->shadow, 0, "%s", buf);
}

/* Apply a forced setting from the scene file (or --pm key=true|false). */
static void force(plan_item *it, int f, const char *key) {
    if (f == PLAN_AUTO) return;
    it->on = f == PLAN_ON;
    snprintf(it->reason, sizeof it->reason, "forced by photon_mapping.%s", key);
}

void plan_make(const scene *s, const photon_settings *c, int preview, render_plan *p) {
    memset(p, 0, sizeof *p);
    pilot_result r;
    run_pilot(s, &r);
    plan_caustics(s, &r, p);
    plan_global(s, &r, p);
    plan_shadow(s, &r, p);
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
