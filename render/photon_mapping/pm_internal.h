/* pm_internal.h: the photon-mapping integrator's state, shared by its files (pm_setup.c,
 * create and destroy; pm_passes.c, the progressive passes; pm_preprocess.c, the maps and
 * pass 0's camera-side decisions; pm_fit.c, pass 0's photons and the passes' radii;
 * photonmapper.c, the camera sample). Not an interface: nothing outside photon_mapping/
 * includes it.
 */
#ifndef RENDER_PM_INTERNAL_H
#define RENDER_PM_INTERNAL_H


#include "base/json.h"
#include "base/rng.h"

#include "photonmap/common.h"
#include "photonmap/estimate.h"
#include "integrators/direct.h"
#include "guiding/gather_guide.h"
#include "guiding/guide.h"
#include "integrators/integrator.h"
#include "photonmap/irradiance.h"
#include "photonmap/kdtree.h"
#include "photonmap/photon.h"
#include "photon_mapping/photon_lookup.h"
#include "photons/photon_maps.h"
#include "photon_mapping/photon_sides.h"
#include "photons/photon_trace.h"
#include "photon_mapping/plan.h"
#include "photon_mapping/pm_sample.h"
#include "photon_mapping/pm_volume.h"
#include "scene/medium.h"
#include "base/stats.h"

typedef struct mapper_state {
    photon_settings cfg;
    render_plan plan;
    int preview, direct_vis;
    int max_depth, rr_depth;
    photon_maps maps;
    pm_kdtree *tg, *tc, *ts; /* global, caustic, shadow trees (NULL when absent/empty) */
    pmv_state vol; /* participating media: volume maps and ray marching (pm_volume.h) */
    side_cache sides; /* precomputed irradiance that keeps to each query's side (photon_sides.h) */
    side_map caus_side; /* the caustic map's estimates keep to the query's side (photon_sides.h) */
    side_map glob_side; /* direct_vis: the global map's estimates keep to the query's side too */
    gather_guide gg; /* the opening the gathers aim a share of their rays at (gather_guide.h) */
    const port *dport; /* the port direct light is also sampled through (direct.h, THROUGH A
                        * PORT), or NULL; dport_lit: the side its light comes from */
    vec3 dport_lit;
    float r2_global, r2_caustic, r2_shadow, r2_lookup;
    size_t nglobal_all, ncaustic_all; /* photons in the whole maps (all processes' parts) */
    double sec_dist;
    pm_estimate_options caus_opt, glob_opt;
    unsigned kmax;
    int st_emission_rays;
    /* Emission-only rays (emission_strata) only where the camera may see an emitter (pm_sample.h;
     * emit.mask NULL: at every pixel). */
    pm_emission_mask emit;
    const scene *scene; /* for pm_sample.c's eye rays (sample_eye), during the preprocess */
    int explicit_gather, explicit_secondary, explicit_stride, explicit_miss; /* set in the scene
                                                                                or by --pm: kept */
    char sample_reason[1024], emit_reason[320]; /* the plan's "sample:" and "emission rays:" lines */
    /* Progressive passes (mapper_begin_pass): the pass whose maps are built, its seed, its
     * squared radii's factor against pass 0's, pass 0's radii and volume radii. */
    int pass, progressive; /* progressive: ppm_radius applies (a render in passes) */
    int made;              /* preprocess ran once: the plan's parts and messages are done */
    uint64_t pass_seed;
    double r2_scale, t_trace, t_trees, t_irr; /* the last pass's times (seconds) */
    map_radii rad0;
    /* Photons per pass (pm_passes.c, PHOTONS PER PASS): the sample pilot's counted work of a
     * camera sample, the settings' targets (global, caustic, volume, volume caustic) and
     * pass 0's counted photon work at them, the fraction later passes trace, and why. */
    double sample_work, sample_caustic, photon_work0, pass_fraction;
    long target0[4];
    int k0[2]; /* the settings' k_global, k_caustic (a later pass reads fewer: pass_targets) */
    int fraction_made;
    char fraction_reason[320];
    float *vol_r2_0; /* 3 per medium: ms, caus, all */
    /* Pass 0's photons fitted to its camera samples (pm_fit.c, PASS 0'S PHOTONS): the
     * settings' counts, stage A running (1), the scale of the targets pass 0 traced, why. */
    long fit_target[4];
    int fit_stage;
    int caustic_cap; /* trace_opts.caustic_cap of the next trace (pm_fit.c, THE CAUSTIC CAP) */
    double fit_scale, fit_scale_c; /* the global (and volume) maps', the caustic map's (THE CAUSTIC FLOOR) */
    char fit_reason[768];
    /* Pass 0's precomputed irradiance fitted to its camera samples (pm_fit.c, PRECOMPUTED POINTS
     * FITTED TO THE RENDER): 1 where the fit applies; the height chosen and why. */
    int irr_fit;
    char irr_reason[320];
    int st_traced, st_saved_lit, st_saved_dark, st_caustic, st_gather, st_secondary, st_lookup,
        st_global_est, st_lookup_miss, st_side_rays, st_side_again;
} mapper_state;

/* A thread's scratch for the camera sample (estimate buffers) and what it is tracing. */
typedef struct mapper_scratch {
    void *est;
    pm_neighbor *nb;
    const sample_id *id; /* the camera sample being traced (for the lookup hook) */
    pm_sample_caustics *pc; /* the sample pilot's tally of camera-level caustics, else NULL */
    double vw; /* the weight of this sample's in-scattering in media (volume_stride), 0: none */
} mapper_scratch;

/* The files below are listed from the bottom up: each calls only files listed before it
 * (pm_fit.c reads photonmapper.c's pm__lookup), and what a file needs from one above it is
 * data in mapper_state, never a call (pm_setup.c's opening comment has the whole order). */

/* photonmapper.c: the integrator's camera sample and its threads' scratch (integrator.h's li,
 * thread_begin, thread_end); an eye ray for pm_sample.c's pilots (emission alone, or the
 * shading alone with the camera path's caustics tallied into pc); the gather guide's two
 * probes (gather_guide.h: a lookup as the gather makes it, a gather ray read as it reads it). */
rgb pm__li(const integrator *self, const scene *s, ray r, rng *g, const sample_id *id, void *scratch);
void *pm__thread_begin(const integrator *self);
mapper_scratch *pm__scratch_new(const mapper_state *st); /* NULL when out of memory */
void pm__thread_end(const integrator *self, void *scratch);
rgb pm__sample_eye(void *user, ray r, int emit, rng *g, void *scratch, pm_sample_caustics *pc);
int pm__gg_found(void *user, const scene *s, const hit *h, vec3 wo);
int pm__gg_read(void *user, const scene *s, const guide_point *pt, vec3 d, rng *g, gather_guide_read *out);

/* A distributed render's lookups (photon_lookup.h); NULL in one process. */
extern const photon_lookup_hook *pm__lookup;

/* pm_fit.c: the radii of the pass being built (pass 0: records them as the start, with
 * ppm_radius applied in a progressive render), the same for each medium's volume maps, and
 * ppm_radius's first radii from pass 0's radii and photon counts (in place). */
void pm__pass_radii(mapper_state *st, map_radii *rad);
int pm__pass_volume_radii(mapper_state *st, const scene *s);
void pm__start_radii(const mapper_state *st, map_radii *rad);
/* pm_fit.c: the counted photon work of st's maps at sg x the settings' targets (sc x for the
 * caustic map), and the counted work of a pass's camera samples (pm_passes.c, PHOTONS PER
 * PASS, has the model). */
double pm__photon_work_at(const mapper_state *st, double sg, double sc);
double pm__camera_work(const mapper_state *st, const scene *s);
/* pm_fit.c: pass 0's photons fitted to its camera samples (PASS 0'S PHOTONS): before the
 * first trace (stage A's targets into st->cfg, or why not), after stage A's sample pilot (1:
 * the maps were dropped and st->cfg holds the targets to trace again), and freeing a pass's
 * maps, trees and readers. */
void pm__fit_begin(mapper_state *st, const scene *s);
/* pm__fit_end's answers: stage A's maps stay, pass 0 is traced again, its caustic map only. */
enum { PM_FIT_KEEP = 0, PM_FIT_AGAIN = 1, PM_FIT_CAUSTIC_AGAIN = 2 };
int pm__fit_end(mapper_state *st, const scene *s);
/* pm_fit.c: the height in the global map's kd-tree above which pass 0's precomputed irradiance
 * is computed (side_cache_build_at), for a global map of n photons; sets st->irr_reason. */
int pm__irr_height(mapper_state *st, const scene *s, size_t n);
void pm__drop_maps(mapper_state *st);

/* pm_preprocess.c: trace the maps of st->pass (pass 0 at first) and build what reads them;
 * on pass 0 also the gather guide and the camera sample, decided once (the integrator's
 * preprocess hook). */
int pm__preprocess(integrator *self, const scene *s, char *err, size_t errcap);
/* pm_preprocess.c: the caustic side map, the estimates' options and the precomputed
 * irradiance of st's maps at the radii rad (the readers; st->sides and st->caus_side empty). */
int pm__build_estimates(mapper_state *st, const scene *s, const map_radii *rad, char *err, size_t errcap);

/* pm_passes.c: the integrator's begin_pass hook (integrator.h). */
int pm__begin_pass(integrator *self, const scene *s, int pass, uint64_t seed, char *err,
                   size_t errcap);

#endif /* RENDER_PM_INTERNAL_H */
