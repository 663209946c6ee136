/* plan.h: which photon-mapping effects a scene needs (the settings are photon_settings.h).
 *
 * Before a photon is traced, plan_make() runs the pilots, then decides from what they found
 * (the three steps below), with a reason for each decision that is printed before rendering:
 *   caustics      a caustic map is built only if a specular or refractive surface can be
 *                 reached straight from a light (L S: the first step of an L S+ D path) and a
 *                 diffuse surface exists to receive it;
 *   global        a global map only if diffuse light can reflect onto other diffuse surfaces
 *                 (found by probe rays that leave the lights like photons, pass specular
 *                 surfaces to a diffuse one, and leave it with a cosine-distributed direction
 *                 on the side they arrived at: does any reach another diffuse surface?);
 *   shadow        shadow photons (the shadow hint of photonmapper.c) are off unless forced:
 *                 with area lights and occluders (pilot photons that reach a diffuse surface
 *                 behind their first hit) they could answer some shadow tests, but the
 *                 answer costs more than the shadow ray it saves (PLAN_SHADOW_HINT_NODES);
 *                 without area lights or occluders they have nothing to answer;
 *   final gather  indirect diffuse by final gathering whenever there is a global map (the
 *                 preview mode shows the global map directly instead);
 *   volume        a volume photon map only in a scene with a participating medium that
 *                 scatters (sigma_s > 0) and is lit: the pilot of volume.h counts photons
 *                 scattering in each medium; without a medium the line says that no volume
 *                 map is built;
 *   volume caustics  a volume caustic map only when a specular surface sends light into a
 *                 medium (pilot photons that scatter in a medium after specular bounces only,
 *                 L S+ V, counted by the first specular surface).
 *   photon emission  the global pass (and its shadow photons) emits toward what the camera
 *                 sees (importance.h) when importance_paths > 0, the map is read through a
 *                 final gather (shown directly, in preview mode, it keeps photons of even
 *                 power) and the camera paths' light connections cover at least
 *                 IMP_MIN_COVERAGE of the lights' power; else by power alone. The line gives the camera paths, the connections that carry
 *                 light, the cells and the coverage. photon_trace builds the same table from
 *                 the same streams, so the pass does what the line says.
 *   light guide  the photon mapper's light samples are guided toward the part of each area
 *                 light a pilot saw pass (guide.h, guide_light_make) when light samples are
 *                 mostly blocked where the camera looks (light through an opening); the line
 *                 gives the pilot's points, pass rate, regions, probes and tables.
 * In a scene with media (or null surfaces) every decision comes from volume.h's pilot (the
 * tracer that builds those maps) instead of photon_trace's: caustics from its L S+ D stores,
 * the global map from stores after a diffuse bounce or a scattering event; shadow photons are
 * off (shadow rays there carry the media's transmittance).
 * The pilots' stores join the real passes' maps (photon_trace.h, PILOT PHOTONS): the caustics
 * and global lines (the shadow photons' line when there is no global map) end with "the
 * pilot's N stores join the caustic map (its M photons counted as emitted)", or with why they
 * do not (pilot_photons_joining's reason, or loaded maps), by the rule photon_trace applies
 * to the options the settings give (trace_opts_settings).
 * Every probe uses fixed random streams (the photon pilot's drawn from the scene's seed,
 * plan_pilot_seed), so the plan of a scene and seed never changes between runs.
 * The scene's "photon_mapping" object may force any of them: "caustics": true/false, and the
 * same for "global", "shadow" and "final_gather"; the reason then says "forced".
 *
 * Plain data, except the importance table (read-only once made, shared by the photon
 * tracer's threads); plan_free frees it.
 */
#ifndef RENDER_PLAN_H
#define RENDER_PLAN_H

#include <cjson/cJSON.h>
#include <stdio.h>

#include "base/json.h"
#include "guiding/guide.h"
#include "load/photon_settings.h"
#include "photons/photon_trace.h"
#include "photons/ports.h"
#include "photons/volume.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The pilot passes' streams and size (plan.c): seed, and photons per pilot pass. */
#define PLAN_SEED 0x706c616eULL /* "plan" */
#define PLAN_PILOT_PHOTONS (2 * PT_BATCH)
/* The seed of the pilot whose photons join the maps: PLAN_SEED mixed with the scene's seed,
 * so the pilot is drawn anew with the seed (its share of the maps averages out over seeds,
 * as the passes' own photons do) and fixed for a given one. volume.h's pilot (scenes with
 * media; it keeps no photons) uses PLAN_SEED itself. */
uint64_t plan_pilot_seed(const scene *s);

/* The shadow hint's cost in BVH node visits: its k_shadow (16) nearest search of the shadow
 * map took about 5 us a lookup (ball_room below: +1.21 s of rendering for 241,456 lookups),
 * and a BVH node visit costs at most 34 ns (the same render without it: 42.3M visits in
 * 1.42 s of rendering, everything included), so a lookup costs at least ~150 visits, while a
 * shadow ray visits few (5.8 on average for the 208,279 it saved there, 159,212 triangles, BVH
 * depth 22). Measured, one thread, 3 alternating runs, median CPU s, shadow=true / false:
 * cornell_box 96x96x16 4.48 / 3.32, water_caustic (5,006 triangles) 64x64x16 6.79 / 6.11,
 * pinhole_room 48x48x64 17.85 / 12.50, ball_room (water_caustic with a 159,212-triangle
 * Lambertian UV sphere for the slab) 64x64x16 3.51 / 2.99: the hint paid in none, so the plan
 * leaves it off and says why; photon_mapping.shadow=true still forces it. */
#define PLAN_SHADOW_HINT_NODES 150

typedef struct plan_item {
    int on;
    char reason[480];
} plan_item;

typedef struct render_plan {
    plan_item caustics, global, shadow, final_gather, volume, volume_caustics;
    plan_item emission; /* on: importance-driven emission of the global pass (importance.h) */
    plan_item ports;    /* on: the global pass aims a share of its photons through the scene's ports (ports.h) */
    port_found found;   /* ports a camera probe found (ports.h): the passes use ports_found_scene */
    struct importance *imp; /* emission on: the table for trace_opts.importance (owned) */
    pilot_photons *pilot;   /* the pilots' photons for trace_opts.reuse (owned; NULL when none
                               join a map the plan traces) */
    plan_item light_guide;  /* on: guided light samples in the photon mapper's direct light */
    struct guide *guide;    /* light_guide on: its tables (guide.h; owned), else NULL */
    /* Counted work (BVH node visits and primitive tests) per photon the global and the
     * caustic pilot emitted, each path whole: what the passes' photons cost in the units of
     * the sample pilot's (pm_sample.h). 0: no surface pilot ran (a scene with media). */
    double work_emit[2];
} render_plan;

/* ---- the three steps of plan_make ----------------------------------------------------------
 *
 * 1. plan_pilots_run (plan_pilots.c) runs every pilot, in this order, and keeps what they
 *    found: the camera probe for photon ports (ports.h, ports_find), the importance table
 *    (importance.h), then either the two photon pilots (photon_trace: global, caustic) or, in
 *    a scene with media, volume.h's two pilots (vol_trace_pass), the ports table (ports_plan)
 *    and the light guide's stage A (guide.h, guide_light_pilot_run). The light guide's pilot
 *    runs only where the photon mapper samples lights, which depends on the global map: the
 *    pilot stage asks plan_samples_lights, the plan's own rule, pure.
 * 2. plan_decide (plan.c) decides every line from those results and nothing else: no tracer,
 *    no pilot, no callback. It takes over what the plan keeps (the importance table, the
 *    pilot's photons) and leaves the rest to plan_pilots_free.
 * 3. The tracers the plan decided: the light guide learns its tables here (guide_light_learn,
 *    when the plan wants them) and plan_light_guide writes its line from what was learned;
 *    the photon passes are traced later by the photon mapper (pm_preprocess.c) as the plan
 *    says. */
typedef struct plan_pilots {
    const scene *s;          /* the scene the pilots saw: the caller's, or &sp */
    scene sp;                /* the caller's scene with the found ports (ports_found_scene) */
    int media;               /* 1: the volume pilots ran (vg, vc); 0: the photon pilots (g, c) */
    port_found found;        /* the camera probe for ports */
    struct importance *imp;  /* the importance table, or NULL (owned until the plan takes it) */
    trace_pilot g, c;        /* the global and the caustic photon pilot's evidence; g.kept: both
                                pilots' stores (owned until the plan takes them) */
    size_t g_stored;         /* photons the global pilot stored */
    double g_work, c_work;   /* their counted work (stats_trace_work) */
    vol_pilot vg, vc;        /* volume.h's global and caustic pilot */
    int ports_on;            /* ports_plan's answer and its words */
    char ports_reason[480];
    const char *guide_skip;  /* why the light guide's pilot did not run, or NULL */
    guide_light_pilot guide; /* the light guide's stage A */
} plan_pilots;

/* Step 1. 0, or a negative PM_E* code with a message naming the pilot (see plan_make); then
 * pl holds nothing to free. pl must not move until plan_pilots_free (pl->s may point into it). */
int plan_pilots_run(const scene *s, const photon_settings *c, int preview, plan_pilots *pl, char *err,
                    size_t errcap);
void plan_pilots_free(plan_pilots *pl);
/* Step 2 (pure): every line of p from pl; the light guide's line says whether it is wanted
 * (on = 1: learn its tables) until plan_light_guide writes it. */
void plan_decide(const photon_settings *c, int preview, plan_pilots *pl, render_plan *p);
/* Whether the photon mapper samples lights, under the plan's global-map decision (pure): the
 * light guide is usable only then. */
int plan_samples_lights(const photon_settings *c, int preview, const plan_pilots *pl);
/* Step 3's line (pure): the light guide's decision and words from its pilot and the guide
 * learned from it (NULL: none); p takes gd when on, else destroys it. */
void plan_light_guide(const photon_settings *c, const plan_pilots *pl, struct guide *gd, render_plan *p);

/* Decide the plan for scene s under config c; preview = 1 turns final gathering off: the
 * three steps above in order (plan_pilots.c). The plan may hold the importance table (imp) and the pilot's photons (pilot): plan_free frees
 * them. Returns 0, or a negative PM_E* code when a pilot pass fails (PM_ENOMEM: its evidence
 * would be a pass cut short, so no plan is made from it) with a message in err that names the
 * pilot ("plan: global photon pilot: out of memory"); then p holds nothing to free.
 * A pilot that stores nothing (PM_EEMPTY) is evidence, not a failure. Test hook:
 * PM_PLAN_TEST_ENOMEM=global|caustic|volume fails that pilot (plan_pilots.c). */
int plan_make(const scene *s, const photon_settings *c, int preview, render_plan *p, char *err, size_t errcap);
void plan_free(render_plan *p);
/* "caustics: off (no specular surface reachable from a light)" and so on, one per line. */
void plan_print(const render_plan *p, FILE *f);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PLAN_H */
