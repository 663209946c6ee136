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
 * pilot uses fixed streams (plan_pilot_seed: PLAN_SEED and the scene's seed), so the plan of a
 * scene and seed is deterministic, and costs about
 * 16384 photon paths. Both pilots' stores are kept (render_plan.pilot) and join the real
 * passes' maps (photon_trace.h, PILOT PHOTONS): the global pilot's the global and shadow
 * maps, the caustic pilot's (aimed by the projection maps the caustic pass will use) the
 * caustic map. The caustics and global lines say how many stores join, or why none do, by
 * the rule photon_trace applies (pilot_photons_joining).
 */
#include "photon_mapping/plan.h"
#include "photon_mapping/plan_internal.h"

#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "guiding/guide.h"
#include "photons/importance.h"
#include "photons/photon_trace.h"
#include "photons/volume.h"
#include "base/rng.h"
#include "base/stats.h"
#include "base/sampling.h"

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

void plan__set(plan_item *it, int on, const char *fmt, const char *arg) {
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
    double g_work, c_work;                /* their counted work (pilot_work) */
} pilot_result;


/* Test hook: PM_PLAN_TEST_ENOMEM=PILOT (global, caustic or volume) makes that pilot pass fail
 * as if photon_trace (vol_trace_pass for volume) had run out of memory, so the tests see the
 * error reach the command line. Read at every call (tests set it per process). */
static int test_enomem(const char *pilot) {
    const char *v = getenv("PM_PLAN_TEST_ENOMEM");
    return v && strcmp(v, pilot) == 0;
}

/* A pilot's budgets. Its paths are capped at PASS_MAX_BOUNCES bounces whatever max_bounces
 * says (a lossless furnace with max_bounces 1e6 otherwise follows each of its 8192 photons
 * for max_depth bounces: minutes, or 8 GiB of stores, before the plan is made; its evidence,
 * what a photon reaches within a few bounces, never needs longer paths). Where max_depth caps
 * the paths first (max_depth <= PASS_MAX_BOUNCES: every shipped scene) the user's max_bounces
 * changes nothing and is kept, so the pilot's photons are traced by the passes' rules and
 * join them; past that the pilot's cap differs from the pass's and pilot_photons_joining
 * keeps them out ("traced with another max_depth or max_bounces"): the pass traces its own.
 * Its memory: the user's max_memory_mb, at most PILOT_MAX_MEMORY_MB (8192 photons of up to
 * 256 bounces need far less). */
#define PILOT_MAX_MEMORY_MB 256
static int pilot_bounces(const scene *s, const photon_settings *cfg) {
    int b = cfg->max_bounces;
    return b > PASS_MAX_BOUNCES && s->settings.max_depth > PASS_MAX_BOUNCES ? PASS_MAX_BOUNCES : b;
}
static size_t pilot_memory(const photon_settings *cfg) {
    long mb = cfg->max_memory_mb < PILOT_MAX_MEMORY_MB ? (long)cfg->max_memory_mb : PILOT_MAX_MEMORY_MB;
    return (size_t)mb << 20;
}

/* A pilot pass's failure: anything but PM_EEMPTY (a pass that stores nothing, which is
 * evidence: a light inside a closed mirror, lights that face nothing) ends the plan, since a
 * pilot cut short by an error would be read as "nothing reaches there". A pilot that stored
 * nothing because a budget stopped it before it emitted its photons (emitted < want: a tiny
 * max_memory_mb) is cut short too. */
static int pilot_failed(int rc, unsigned long long emitted, unsigned long long want, const char *which,
                        const char *why, char *err, size_t errcap) {
    if (rc >= 0 || (rc == PM_EEMPTY && emitted >= want)) return 0;
    if (errcap)
        snprintf(err, errcap, "plan: %s pilot: %s", which, why && why[0] ? why : pm_strerror(rc));
    return rc;
}

/* The pilot: PLAN_PILOT_PHOTONS photons traced exactly as the real passes trace them
 * (same emission, scattering and storage rules; the caustic pilot aimed at the specular
 * objects by the projection maps, so a specular object lit only through a small opening still
 * receives its share of the aimed photons), counting what they do; their stores are kept for
 * the real passes (PILOT PHOTONS in photon_trace.h). 0, or a negative PM_E* code with a message
 * naming the pilot (pilot_failed); then the kept photons are freed. */
static int run_pilot(const scene *s, const photon_settings *cfg, const importance *imp, pilot_result *r,
                     char *err, size_t errcap) {
    memset(r, 0, sizeof *r);
    trace_opts o;
    trace_opts_init(&o, s);
    o.seed = plan_pilot_seed(s);
    o.max_bounces = pilot_bounces(s, cfg); /* the passes' rules where it can (pilot_bounces) */
    o.max_memory_bytes = pilot_memory(cfg);
    o.quiet = 1;
    o.max_emitted = PLAN_PILOT_PHOTONS;
    o.max_emitted_factor = 1e300;
    /* Emission by power (the evidence of uniform emission); with the table the real pass will
     * use, each photon records its rel there, so the global photons can join that pass. */
    o.importance = imp;
    photon_maps m;
    o.pilot = &r->g;
    r->g.keep = 1;
    o.global = o.shadow = 1;
    o.global_target = 1L << 40; /* never reached: the emission budget ends the pilot */
    char why[256] = "";
    uint64_t w0 = stats_trace_work(); /* the work per emitted photon (render_plan.work_emit) */
    int rc = test_enomem("global") ? PM_ENOMEM : photon_trace(s, &o, &m, why, sizeof why);
    r->g_work = (double)(stats_trace_work() - w0);
    if ((rc = pilot_failed(rc, r->g.emitted, PLAN_PILOT_PHOTONS, "global photon", why, err, errcap)) < 0) {
        pilot_photons_free(r->g.kept);
        r->g.kept = NULL;
        return rc;
    }
    r->g_emitted = r->g.emitted;
    r->g_stored = m.nglobal;
    photon_maps_free(&m);
    o.pilot = &r->c;
    o.global = o.shadow = 0;
    o.caustic = 1;
    o.caustic_target = 1L << 40;
    /* Always aimed (the evidence needs it); by the pass's projection maps when it uses them,
     * so the pilot's caustic stores can join the caustic map. */
    o.projection = 1;
    o.projection_cells = cfg->projection ? cfg->projection_cells : 64;
    r->c.keep = 1;
    r->c.kept = r->g.kept; /* its stores are added to the global pilot's kept photons */
    why[0] = 0;
    w0 = stats_trace_work();
    rc = test_enomem("caustic") ? PM_ENOMEM : photon_trace(s, &o, &m, why, sizeof why);
    r->c_work = (double)(stats_trace_work() - w0);
    r->g.kept = r->c.kept; /* created here if the global pilot kept none */
    if ((rc = pilot_failed(rc, r->c.emitted, PLAN_PILOT_PHOTONS, "caustic photon", why, err, errcap)) < 0) {
        pilot_photons_free(r->g.kept);
        r->g.kept = r->c.kept = NULL;
        return rc;
    }
    r->c_emitted = r->c.emitted;
    photon_maps_free(&m);
    return 0;
}

uint64_t plan_pilot_seed(const scene *s) { return rng_mix64(PLAN_SEED ^ rng_mix64(s->settings.seed)); }

static void plan_caustics(const scene *s, const pilot_result *r, render_plan *p) {
    int nspec = 0;
    for (int i = 0; i < prim_count(s); i++)
        nspec += material_is_specular(prim_mat(s, i));
    if (!nspec) {
        plan__set(&p->caustics, 0, "no specular surface%s", "");
        return;
    }
    if (!emitting_lights(s)) {
        plan__set(&p->caustics, 0, "no light emits photons%s", "");
        return;
    }
    if (!any_diffuse(s)) {
        plan__set(&p->caustics, 0, "no diffuse surface to receive them%s", "");
        return;
    }
    char mats[128], buf[300];
    if (r->c.caustic.total > 0) {
        top_mats(s, &r->c.caustic, mats, sizeof mats);
        snprintf(buf, sizeof buf,
                 "L S+ D paths: %llu photons stored through specular surfaces (first %s), from "
                 "%llu pilot photons aimed at them",
                 r->c.caustic.total, mats, (unsigned long long)r->c_emitted);
        plan__set(&p->caustics, 1, "%s", buf);
        return;
    }
    if (r->c_emitted == 0) {
        plan__set(&p->caustics, 0,
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
    plan__set(&p->caustics, 0, "%s", buf);
}

static void plan_global(const scene *s, const pilot_result *r, render_plan *p) {
    if (!emitting_lights(s)) {
        plan__set(&p->global, 0, "no light emits photons%s", "");
        return;
    }
    char mats[128], buf[300];
    if (r->g.diffuse_bounce.total > 0) {
        top_mats(s, &r->g.diffuse_bounce, mats, sizeof mats);
        snprintf(buf, sizeof buf,
                 "diffuse surfaces reflect onto each other: %llu photons stored after a diffuse "
                 "bounce off %s, from %llu pilot photons: indirect diffuse light",
                 r->g.diffuse_bounce.total, mats, (unsigned long long)r->g_emitted);
        plan__set(&p->global, 1, "%s", buf);
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
    plan__set(&p->global, 0, "%s", buf);
}

static void plan_shadow(const scene *s, const photon_settings *cfg, const pilot_result *r, render_plan *p) {
    int area = 0;
    for (int i = 0; i < s->nlights; i++) area += s->lights[i].type == LIGHT_AREA && v3_maxc(s->lights[i].power) > 0;
    if (!area) {
        plan__set(&p->shadow, 0,
            "no area light of triangles (point, directional and sphere lights take one shadow ray each)%s",
            "");
        return;
    }
    int ndiff = 0;
    for (int i = 0; i < prim_count(s); i++)
        ndiff += material_is_diffuse(prim_mat(s, i));
    if (!ndiff) {
        plan__set(&p->shadow, 0, "no diffuse surface%s", "");
        return;
    }
    char mats[128], buf[480];
    if (r->g.occluder.total > 0) {
        /* Occluders, so shadow photons could answer some shadow tests; but the answer costs
         * more than the test it saves (PLAN_SHADOW_HINT_NODES in plan.h): off unless forced. */
        top_mats(s, &r->g.occluder, mats, sizeof mats);
        snprintf(buf, sizeof buf,
                 "area light with occluders (%llu of %llu pilot photons reach a diffuse surface "
                 "behind their first hit; occluders %s), but the hint costs more than the shadow "
                 "rays it saves: its %d-photon search of the shadow map costs about %d BVH node "
                 "visits, a shadow ray far fewer (BVH depth %d, %d primitives); "
                 "photon_mapping.shadow=true forces it",
                 r->g.occluder.total, (unsigned long long)r->g_emitted, mats, cfg->k_shadow,
                 PLAN_SHADOW_HINT_NODES, s->accel.depth, prim_count(s));
        plan__set(&p->shadow, 0, "%s", buf);
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
    plan__set(&p->shadow, 0, "%s", buf);
}

/* ---- scenes with media ------------------------------------------------------------------- */

#define MEDIA_PILOT_PHOTONS (2 * PT_BATCH)

/* The index of the largest of n counts (-1 if all are 0). */
static int argmax(const unsigned long long *c, int n, size_t stride) {
    int best = -1;
    for (int i = 0; i < n; i++)
        if (c[(size_t)i * stride] > 0 && (best < 0 || c[(size_t)i * stride] > c[(size_t)best * stride])) best = i;
    return best;
}

static const char *medium_name(const scene *s, int m) {
    return m >= 0 && m < s->nmedia && m < VOL_PILOT_MEDIA - 1 ? s->media[m].name : "(others)";
}

/* Every decision of a scene with media, from volume.h's pilot (the tracer of its maps). 0, or
 * a negative PM_E* code with a message (pilot_failed). */
static int plan_media(const scene *s, const photon_settings *cfg, render_plan *p, char *err, size_t errcap) {
    vol_pilot pg, pc;
    memset(&pg, 0, sizeof pg);
    memset(&pc, 0, sizeof pc);
    vol_pass_opts o = {0};
    o.max_emitted = MEDIA_PILOT_PHOTONS;
    o.lo = v3s(1);
    o.hi = v3s(-1);
    o.max_depth = s->settings.max_depth;
    o.max_bounces = pilot_bounces(s, cfg); /* the path-length budget, capped (pilot_bounces) */
    o.seed = PLAN_SEED;
    o.pilot = &pg;
    int rc = 0;
    if (emitting_lights(s)) rc = test_enomem("volume") ? PM_ENOMEM : vol_trace_pass(s, &o, &(vol_pass_result){0});
    if ((rc = pilot_failed(rc, 0, 0, "volume photon", NULL, err, errcap)) < 0) return rc;
    o.caustic_pass = 1;
    o.projection_cells = cfg->projection ? cfg->projection_cells : 0; /* aimed, as the pass is */
    o.pilot = &pc;
    if (emitting_lights(s)) rc = vol_trace_pass(s, &o, &(vol_pass_result){0});
    if ((rc = pilot_failed(rc, 0, 0, "volume caustic photon", NULL, err, errcap)) < 0) return rc;
    char buf[300];
    int scatters = 0, nspec = 0;
    for (int m = 0; m < s->nmedia; m++) scatters += v3_maxc(s->media[m].sigma_s) > 0;
    for (int i = 0; i < prim_count(s); i++) /* a null surface is no specular one */
        nspec += prim_mat(s, i)->kind != MAT_NULL && material_is_specular(prim_mat(s, i));
    unsigned long long ev[VOL_PILOT_MEDIA] = {0}, total = 0, direct = 0;
    for (int m = 0; m < VOL_PILOT_MEDIA; m++) {
        for (int k = 0; k < 4; k++) ev[m] += pg.events[m][k];
        total += ev[m];
        direct += pg.events[m][PM_KIND_DIRECT];
    }
    /* volume */
    if (!emitting_lights(s))
        plan__set(&p->volume, 0, "no light emits photons%s", "");
    else if (!s->nmedia)
        plan__set(&p->volume, 0, "no participating medium (only null surfaces): no volume photon map%s", "");
    else if (!scatters)
        plan__set(&p->volume, 0, "no medium scatters light (sigma_s = 0 in every medium): they only attenuate, "
                           "no volume photon map%s", "");
    else if (total == 0) {
        snprintf(buf, sizeof buf, "no medium is lit: 0 of %llu pilot photons scatter in a medium", pg.emitted);
        plan__set(&p->volume, 0, "%s", buf);
    } else {
        int top = argmax(ev, VOL_PILOT_MEDIA, 1);
        snprintf(buf, sizeof buf,
                 "medium \"%s\" is lit by the lights: %llu scattering events of %llu pilot photons in it "
                 "(%llu in all media: %llu straight from a light, %llu after a bounce or an earlier "
                 "event)",
                 medium_name(s, top), ev[top], pg.emitted, total, direct, total - direct);
        plan__set(&p->volume, 1, "%s", buf);
    }
    /* volume caustics */
    unsigned long long vc = 0, vcm[VOL_PILOT_MEDIA];
    for (int m = 0; m < VOL_PILOT_MEDIA; m++) vc += (vcm[m] = pc.events[m][PM_KIND_CAUSTIC]);
    if (!p->volume.on && !(scatters && vc > 0))
        plan__set(&p->volume_caustics, 0, "no volume map%s", "");
    else if (!nspec)
        plan__set(&p->volume_caustics, 0, "no specular surface%s", "");
    else if (vc == 0) {
        snprintf(buf, sizeof buf,
                 "no specular surface sends light into a medium: 0 of %llu pilot photons aimed at "
                 "specular surfaces scatter in a medium after specular bounces only",
                 pc.emitted);
        plan__set(&p->volume_caustics, 0, "%s", buf);
    } else {
        int tm = argmax(vcm, VOL_PILOT_MEDIA, 1), ts = argmax(pc.caustic_by_mat, VOL_PILOT_MATS, 1);
        snprintf(buf, sizeof buf,
                 "\"%s\" sends light into a medium: %llu of %llu pilot photons aimed at specular "
                 "surfaces scatter in \"%s\" after specular bounces only (L S+ V)",
                 ts >= 0 && ts < s->nmats && ts < VOL_PILOT_MATS - 1 ? s->mats[ts].name : "(others)", vc,
                 pc.emitted, medium_name(s, tm));
        plan__set(&p->volume_caustics, 1, "%s", buf);
    }
    /* surface maps */
    if (!nspec)
        plan__set(&p->caustics, 0, "no specular surface%s", "");
    else if (pc.surf_caustic == 0) {
        snprintf(buf, sizeof buf,
                 "no L S+ D path: 0 of %llu pilot photons aimed at specular surfaces reach a diffuse "
                 "surface through specular surfaces only",
                 pc.emitted);
        plan__set(&p->caustics, 0, "%s", buf);
    } else {
        snprintf(buf, sizeof buf,
                 "L S+ D paths: %llu arrivals at diffuse surfaces through specular surfaces only, from "
                 "%llu pilot photons aimed at them",
                 pc.surf_caustic, pc.emitted);
        plan__set(&p->caustics, 1, "%s", buf);
    }
    if (pg.surf_indirect == 0) {
        snprintf(buf, sizeof buf,
                 "no diffuse surface or medium sends light onto a diffuse surface: %llu arrivals "
                 "after a bounce, from %llu pilot photons",
                 pg.surf_indirect, pg.emitted);
        plan__set(&p->global, 0, "%s", buf);
    } else {
        snprintf(buf, sizeof buf,
                 "diffuse surfaces and media send light onto diffuse surfaces: %llu arrivals after a "
                 "bounce (%llu of them after scattering in a medium), from %llu pilot photons",
                 pg.surf_indirect, pg.surf_after_scatter, pg.emitted);
        plan__set(&p->global, 1, "%s", buf);
    }
    plan__set(&p->shadow, 0, "a scene with media: shadow rays carry the transmittance, no shadow photons%s", "");
    return 0;
}

void plan_free(render_plan *p) {
    if (p->imp) importance_free(p->imp);
    free(p->imp);
    p->imp = NULL;
    pilot_photons_free(p->pilot);
    p->pilot = NULL;
    guide_destroy(p->guide);
    p->guide = NULL;
}

/* Append to the caustics and global reasons (the shadow reason for a shadow map without a
 * global map) how many of the pilot's stores join those maps,
 * or why none do, by photon_trace's own rule for the options the pass will have
 * (photonmapper.c: trace_opts_settings, the plan's maps and table). Keeps the pilot's photons
 * only when some join. */
static void plan_joins(const scene *s, const photon_settings *c, render_plan *p) {
    if (!p->pilot) return;
    trace_opts o;
    trace_opts_settings(&o, s, c);
    o.global = p->global.on;
    o.shadow = p->shadow.on;
    o.caustic = p->caustics.on;
    o.importance = p->imp;
    int any = 0;
    for (int caustic = 0; caustic < 2; caustic++) {
        plan_item *it = caustic ? &p->caustics : p->global.on ? &p->global : &p->shadow;
        const char *map = caustic ? "caustic map" : o.global ? "global map" : "shadow map";
        size_t n = 0;
        uint64_t ne = 0;
        const char *why = "";
        int joins = !c->load_dir[0] && pilot_photons_joining(p->pilot, &o, caustic, &n, &ne, &why);
        any |= joins;
        size_t len = strlen(it->reason), cap = sizeof it->reason - len;
        char *at = it->reason + len;
        if (joins)
            snprintf(at, cap, "; the pilot's %zu stores join the %s (its %llu photons counted as emitted)", n,
                     map, (unsigned long long)ne);
        else if (caustic ? !p->caustics.on : !(p->global.on || p->shadow.on))
            continue;
        else if (c->load_dir[0])
            snprintf(at, cap, "; the maps are loaded: no pilot stores join");
        else if (why[0])
            snprintf(at, cap, "; the pilot's stores do not join the %s: %s", map, why);
    }
    if (!any) {
        pilot_photons_free(p->pilot);
        p->pilot = NULL;
    }
}

/* Apply a forced setting from the scene file (or --pm key=true|false). */
static void force(plan_item *it, int f, const char *key) {
    if (f == PLAN_AUTO) return;
    it->on = f == PLAN_ON;
    snprintf(it->reason, sizeof it->reason, "forced by photon_mapping.%s", key);
}

int plan_make(const scene *s, const photon_settings *c, int preview, render_plan *p, char *err, size_t errcap) {
    memset(p, 0, sizeof *p);
    if (errcap) err[0] = 0;
    importance *tab = NULL;
    int rc;
    scene sp; /* s with the ports the probe found (plan__find_ports), when it found some */
    if ((rc = plan__find_ports(s, p, err, errcap)) < 0) return rc;
    s = ports_found_scene(s, &p->found, &sp); /* found ports are used as declared ones */
    if (scene_has_media(s)) {
        if ((rc = plan_media(s, c, p, err, errcap)) < 0) return rc;
        force(&p->volume, c->force_volume, "volume");
        force(&p->volume_caustics, c->force_volume_caustics, "volume_caustics");
    } else {
        pilot_result r;
        tab = plan__make_importance(s, c);
        if ((rc = run_pilot(s, c, tab && tab->on ? tab : NULL, &r, err, errcap)) < 0) {
            if (tab) importance_free(tab);
            free(tab);
            return rc;
        }
        p->pilot = r.g.kept; /* both pilots' stores */
        p->work_emit[0] = r.g_emitted ? r.g_work / (double)r.g_emitted : 0;
        p->work_emit[1] = r.c_emitted ? r.c_work / (double)r.c_emitted : 0;
        plan_caustics(s, &r, p);
        plan_global(s, &r, p);
        plan_shadow(s, c, &r, p);
        plan__set(&p->volume, 0, "no participating medium in the scene: no volume photon map%s", "");
        plan__set(&p->volume_caustics, 0, "no participating medium in the scene%s", "");
    }
    force(&p->caustics, c->force_caustics, "caustics");
    force(&p->global, c->force_global, "global");
    force(&p->shadow, c->force_shadow, "shadow");
    if (preview)
        plan__set(&p->final_gather, 0, "preview mode: the global map is shown directly%s", "");
    else if (!p->global.on)
        plan__set(&p->final_gather, 0, "no global map to gather from%s", "");
    else if (c->force_final_gather == PLAN_OFF)
        plan__set(&p->final_gather, 0, "forced by photon_mapping.final_gather: the global map is shown directly%s", "");
    else if (c->force_final_gather == PLAN_ON)
        plan__set(&p->final_gather, 1, "forced by photon_mapping.final_gather%s", "");
    else
        plan__set(&p->final_gather, 1,
            "indirect diffuse by gather rays reading precomputed irradiance of the global map%s", "");
    plan__emission(s, c, p, tab);
    if ((rc = plan__ports(s, p, err, errcap)) < 0) {
        plan_free(p);
        return rc;
    }
    /* usable: the photon mapper samples lights unless it shows the global map directly */
    p->guide = guide_light_plan(s, c->force_light_guide, !((preview || !p->final_gather.on) && p->global.on),
                                &p->light_guide.on, p->light_guide.reason, sizeof p->light_guide.reason, NULL);
    plan_joins(s, c, p);
    return 0;
}

void plan_print(const render_plan *p, FILE *f) {
    const plan_item *it[] = {&p->caustics, &p->global, &p->shadow, &p->final_gather, &p->volume,
                             &p->volume_caustics, &p->emission, &p->ports, &p->light_guide};
    static const char *name[] = {"caustics", "global", "shadow photons", "final gather", "volume",
                                 "volume caustics", "photon emission", "photon ports", "light guide"};
    fprintf(f, "Plan:\n");
    for (int i = 0; i < 9; i++)
        fprintf(f, "  %s: %s (%s)\n", name[i],
                i == 6 ? (it[i]->on ? "importance" : "by power") : it[i]->on ? "on" : "off", it[i]->reason);
}
