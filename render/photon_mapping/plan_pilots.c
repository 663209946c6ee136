/* plan_pilots.c: the plan's pilot stage and plan_make (plan.h, "the three steps of plan_make").
 *
 * plan_pilots_run runs every pilot the plan reads, before anything is decided, and keeps what
 * they found in a plan_pilots: the port probe, the importance table, the photon pilots (or the
 * volume pilots of a scene with media), the ports table and the light guide's stage A. Each
 * uses fixed streams (PLAN_SEED, plan_pilot_seed, the scene's seed), so the same scene and
 * seed give the same evidence. plan_decide (plan.c) then decides from it alone, and plan_make
 * runs the one tracer the plan drives itself: the light guide's learning, when wanted.
 *
 * The photon pilot: PLAN_PILOT_PHOTONS photons traced with photon_trace itself (so the pilot
 * and the real passes can never disagree about what a photon does), counting what they do:
 * L S+ D stores (caustic pilot, aimed at the specular objects through the projection maps, so
 * an opening is found whenever a fair share of the aimed photons passes it: an opening that
 * passes fewer than about 1 in 8192 of them can still be missed), stores after a diffuse
 * bounce (global), and photons that pass their first hit and reach a diffuse surface behind
 * it (shadow photons). About 16384 photon paths. Both pilots' stores are kept (g.kept) and
 * may join the real passes' maps (photon_trace.h, PILOT PHOTONS): the global pilot's the
 * global and shadow maps, the caustic pilot's (aimed by the projection maps the caustic pass
 * will use) the caustic map; the plan decides whether they do (plan_joins).
 */
#include "photon_mapping/plan.h"
#include "photon_mapping/plan_internal.h"

#include <stdlib.h>
#include <string.h>

#include "base/rng.h"
#include "base/stats.h"
#include "photonmap/common.h"
#include "photons/importance.h"
#include "scene/medium.h"

uint64_t plan_pilot_seed(const scene *s) { return rng_mix64(PLAN_SEED ^ rng_mix64(s->settings.seed)); }

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

/* The photon pilots: PLAN_PILOT_PHOTONS photons each, traced exactly as the real passes trace
 * them (same emission, scattering and storage rules; the caustic pilot aimed at the specular
 * objects by the projection maps, so a specular object lit only through a small opening still
 * receives its share of the aimed photons), counting what they do into pl->g and pl->c; their
 * stores are kept in pl->g.kept (PILOT PHOTONS in photon_trace.h). 0, or a negative PM_E* code
 * with a message naming the pilot (pilot_failed); then the kept photons are freed. */
static int photon_pilots(const scene *s, const photon_settings *cfg, plan_pilots *pl, char *err, size_t errcap) {
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
    o.importance = pl->imp && pl->imp->on ? pl->imp : NULL;
    photon_maps m;
    o.pilot = &pl->g;
    pl->g.keep = 1;
    o.global = o.shadow = 1;
    o.global_target = 1L << 40; /* never reached: the emission budget ends the pilot */
    char why[256] = "";
    uint64_t w0 = stats_trace_work(); /* the work per emitted photon (render_plan.work_emit) */
    int rc = test_enomem("global") ? PM_ENOMEM : photon_trace(s, &o, &m, why, sizeof why);
    pl->g_work = (double)(stats_trace_work() - w0);
    if ((rc = pilot_failed(rc, pl->g.emitted, PLAN_PILOT_PHOTONS, "global photon", why, err, errcap)) < 0)
        return rc; /* plan_pilots_free frees g.kept */
    pl->g_stored = m.nglobal;
    photon_maps_free(&m);
    o.pilot = &pl->c;
    o.global = o.shadow = 0;
    o.caustic = 1;
    o.caustic_target = 1L << 40;
    /* Always aimed (the evidence needs it); by the pass's projection maps when it uses them,
     * so the pilot's caustic stores can join the caustic map. */
    o.projection = 1;
    o.projection_cells = cfg->projection ? cfg->projection_cells : 64;
    pl->c.keep = 1;
    pl->c.kept = pl->g.kept; /* its stores are added to the global pilot's kept photons */
    why[0] = 0;
    w0 = stats_trace_work();
    rc = test_enomem("caustic") ? PM_ENOMEM : photon_trace(s, &o, &m, why, sizeof why);
    pl->c_work = (double)(stats_trace_work() - w0);
    pl->g.kept = pl->c.kept; /* created here if the global pilot kept none */
    pl->c.kept = NULL;       /* one owner: g.kept */
    if ((rc = pilot_failed(rc, pl->c.emitted, PLAN_PILOT_PHOTONS, "caustic photon", why, err, errcap)) < 0)
        return rc;
    photon_maps_free(&m);
    return 0;
}

#define MEDIA_PILOT_PHOTONS (2 * PT_BATCH)

/* volume.h's pilots (the tracer of a scene with media), global and caustic, into pl->vg and
 * pl->vc; nothing runs when no light emits photons. 0, or a negative PM_E* code with a
 * message (pilot_failed). */
static int volume_pilots(const scene *s, const photon_settings *cfg, plan_pilots *pl, char *err, size_t errcap) {
    vol_pass_opts o = {0};
    o.max_emitted = MEDIA_PILOT_PHOTONS;
    o.lo = v3s(1);
    o.hi = v3s(-1);
    o.max_depth = s->settings.max_depth;
    o.max_bounces = pilot_bounces(s, cfg); /* the path-length budget, capped (pilot_bounces) */
    o.seed = PLAN_SEED;
    o.pilot = &pl->vg;
    int rc = 0, lit = plan__emitting_lights(s);
    if (lit) rc = test_enomem("volume") ? PM_ENOMEM : vol_trace_pass(s, &o, &(vol_pass_result){0});
    if ((rc = pilot_failed(rc, 0, 0, "volume photon", NULL, err, errcap)) < 0) return rc;
    o.caustic_pass = 1;
    o.projection_cells = cfg->projection ? cfg->projection_cells : 0; /* aimed, as the pass is */
    o.pilot = &pl->vc;
    if (lit) rc = vol_trace_pass(s, &o, &(vol_pass_result){0});
    return pilot_failed(rc, 0, 0, "volume caustic photon", NULL, err, errcap);
}

/* The importance table of the scene's settings (importance.h), or NULL: none asked for, maps
 * loaded, media, or out of memory (the emission line says which). */
static importance *make_importance(const scene *s, const photon_settings *c) {
    if (scene_has_media(s) || c->load_dir[0] || c->importance_paths <= 0) return NULL;
    importance *imp = malloc(sizeof *imp);
    if (imp && importance_build(s, c->importance_paths, c->importance_defensive, s->settings.seed, 0, imp) < 0) {
        free(imp);
        imp = NULL;
    }
    return imp;
}

/* The pilots that read the scene before any photon: the port probe (so the photon or volume
 * pilots' photons aim through what it finds as the passes' do; in scenes with media too), the importance table (which the
 * photon pilot's global photons already use), then the photon or volume pilots. */
static int photon_evidence(const scene *s, const photon_settings *c, plan_pilots *pl, char *err, size_t errcap) {
    pl->s = s;
    pl->media = scene_has_media(s);
    int rc = ports_find(s, plan_pilot_seed(s), &pl->found);
    if (rc < 0) {
        snprintf(err, errcap, "plan: photon ports: probe: %s", pm_strerror(rc));
        return rc;
    }
    pl->s = ports_found_scene(s, &pl->found, &pl->sp); /* found ports are used as declared ones */
    if (pl->media) return volume_pilots(pl->s, c, pl, err, errcap);
    pl->imp = make_importance(pl->s, c);
    return photon_pilots(pl->s, c, pl, err, errcap);
}

int plan_pilots_run(const scene *s, const photon_settings *c, int preview, plan_pilots *pl, char *err,
                    size_t errcap) {
    memset(pl, 0, sizeof *pl);
    if (errcap) err[0] = 0;
    int rc = photon_evidence(s, c, pl, err, errcap);
    if (rc >= 0 && (rc = ports_plan(pl->s, pl->ports_reason, sizeof pl->ports_reason)) < 0)
        snprintf(err, errcap, "plan: photon ports: %s", pm_strerror(rc));
    if (rc < 0) {
        plan_pilots_free(pl);
        return rc;
    }
    pl->ports_on = rc;
    /* The light guide's stage A, where the photon mapper will sample lights. */
    pl->guide_skip = guide_light_skip(pl->s, c->force_light_guide, plan_samples_lights(c, preview, pl));
    if (!pl->guide_skip) guide_light_pilot_run(pl->s, &pl->guide);
    return 0;
}

void plan_pilots_free(plan_pilots *pl) {
    if (pl->imp) importance_free(pl->imp);
    free(pl->imp);
    pl->imp = NULL;
    pilot_photons_free(pl->g.kept);
    pl->g.kept = NULL;
    guide_light_pilot_free(&pl->guide);
}

/* ---- plan_make: the three steps ------------------------------------------------------------- */

int plan_make(const scene *s, const photon_settings *c, int preview, render_plan *p, char *err, size_t errcap) {
    memset(p, 0, sizeof *p);
    plan_pilots *pl = malloc(sizeof *pl);
    if (!pl) {
        if (errcap) snprintf(err, errcap, "plan: out of memory");
        return PM_ENOMEM;
    }
    int rc = plan_pilots_run(s, c, preview, pl, err, errcap);
    if (rc < 0) {
        free(pl);
        return rc;
    }
    plan_decide(c, preview, pl, p);
    /* The tracer the plan drives itself: the light guide's tables, when it wants them. */
    guide *gd = p->light_guide.on ? guide_light_learn(pl->s, &pl->guide, guide_light_jobs(pl->s, pl->guide.nj)) : NULL;
    plan_light_guide(c, pl, gd, p);
    plan_pilots_free(pl);
    free(pl);
    return 0;
}
