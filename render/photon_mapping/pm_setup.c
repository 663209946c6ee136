/* pm_setup.c: the photon-mapping integrators' life around the camera sample (photonmapper.c
 * renders it): create ("$.photon_mapping" read, the plan made, the counters registered),
 * pass 0's camera-side decisions after its maps (the gather guide's pilot, the emission mask
 * and the sample pilot, through photonmapper.c's eye rays) and destroy. pm_preprocess.c
 * traces and reads the maps in between; pm_passes.c runs the progressive passes.
 */
#include <stdio.h>
#include <stdlib.h>

#include "photon_mapping/pm_internal.h"

#include "base/stats.h"

/* ---- pass 0's camera-side decisions (pm_sample.h, gather_guide.h) ------------------------- */

/* Scratch for the preprocess's own camera rays (the emission mask, the sample pilot). */
static void *sample_scratch_new(void *user) {
    return pm__scratch_new(user);
}

static void sample_scratch_free(void *user, void *scratch) {
    (void)user;
    pm__thread_end(NULL, scratch);
}

rgb pm__eye_medium(const mapper_state *st, const scene *s, ray r, double tmax, int med, int inscatter, rgb beta,
                   rng *g, mapper_scratch *sc, rgb *tr) {
    int in = inscatter && sc->vw > 0;
    pm_sample_caustics *pc = in ? sc->pc : NULL;
    uint64_t w0 = pc ? stats_trace_work() : 0, b0 = pc ? stats_total(st->vol.st_beam_photons) : 0;
    rgb c = v3_scale(v3_mul(beta, pmv_march(&st->vol, s, r, tmax, med, in, g, sc->est, tr)), sc->vw);
    if (pc) {
        pc->Lv = v3_add(pc->Lv, c);
        pc->workv += stats_trace_work() - w0;
        pc->beamv += stats_total(st->vol.st_beam_photons) - b0;
    }
    return c;
}

/* The emission mask and the sample pilot, once (pass 0's preprocess), and their plan lines. */
static int sample_decide(mapper_state *st, const scene *s, char *err, size_t errcap) {
    st->scene = s;
    const char *no_pilot = !st->plan.final_gather.on || st->direct_vis ? "no final gather"
                           : !st->sides.irr ? "no precomputed irradiance to gather from"
                           : pm__lookup ? "partitioned render-mpi: its lookups are shared between processes"
                                      : NULL;
    pm_sample_host h = {s, &st->cfg, st->st_lookup, st->st_caustic, st->ncaustic_all > 0, no_pilot,
                        st->vol.on && !json_get(s->photon_mapping, "volume_stride"),
                        pm__lookup != NULL, st, sample_scratch_new, sample_scratch_free, pm__sample_eye};
    int rc = pm_emission_mask_build(&h, &st->emit, st->emit_reason, sizeof st->emit_reason, err, errcap);
    if (rc < 0) return rc;
    if (st->cfg.emission_strata <= 0)
        snprintf(st->emit_reason, sizeof st->emit_reason, "none (photon_mapping.emission_strata is 0): "
                 "a sample's own path collects emission");
    pm_sample_pilot(&h, st->explicit_gather, st->explicit_secondary, st->explicit_stride, st->emit.var,
                    st->sample_reason, sizeof st->sample_reason, &st->sample_work,
                    &st->sample_caustic);
    return 0;
}

static void mapper_destroy(integrator *self) {
    mapper_state *st = self->data;
    if (!st) return;
    side_cache_free(&st->sides);
    side_map_free(&st->caus_side);
    gather_guide_free(&st->gg);
    pm_emission_mask_free(&st->emit);
    pmv_free(&st->vol);
    pm_kdtree_free(st->tg);
    pm_kdtree_free(st->tc);
    pm_kdtree_free(st->ts);
    photon_maps_free(&st->maps);
    plan_free(&st->plan);
    free(st->vol_r2_0);
    free(st);
}

/* Once, on pass 0: the gather guide (gather_guide.h) and the camera sample (pm_sample.h), both
 * from probes through this file's eye rays, with the plan's lines they print. */
int pm__decide_sample(mapper_state *st, const scene *s, char *err, size_t errcap) {
    int rc;
    double t0;
    t0 = stats_now();
    {
        const char *why = !st->plan.final_gather.on || st->direct_vis ? "no final gather"
                          : !st->sides.irr                             ? "no precomputed irradiance to probe"
                          : st->vol.on ? "participating media: its probes do not march"
                          : pm__lookup   ? "partitioned render-mpi: its probes would read one process's records"
                                       : NULL;
        gather_guide_probe probe = {st, pm__gg_found, pm__gg_read, s->nports > 0 || st->plan.found.n > 0};
        if ((rc = gather_guide_make(&st->gg, s, st->cfg.force_gather_guide, why, &probe, err, errcap)) < 0)
            return rc;
    }
    stats_time_add("Time/Gather guide pilot", stats_now() - t0);
    printf("  gather guide: %s\n", st->gg.reason);
    t0 = stats_now();
    if ((rc = sample_decide(st, s, err, errcap)) < 0) return rc;
    stats_time_add("Time/Sample pilot and emission mask", stats_now() - t0);
    printf("  sample: %s\n", st->sample_reason);
    printf("  emission rays: %s\n", st->emit_reason);
    return 0;
}

/* ---- create -------------------------------------------------------------------------------- */

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
    st->explicit_gather = json_get(s->photon_mapping, "gather_rays") != NULL;
    st->explicit_secondary = json_get(s->photon_mapping, "secondary_rays") != NULL;
    st->explicit_stride = json_get(s->photon_mapping, "caustic_stride") != NULL;
    if ((rc = plan_make(s, &st->cfg, preview, &st->plan, err, errcap)) < 0) {
        free(st);
        return rc;
    }
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
    gather_guide_init(&st->gg); /* its counter of aimed rays */
    st->pass_seed = s->settings.seed;
    st->r2_scale = 1;
    it->data = st;
    it->preprocess = pm__preprocess;
    it->thread_begin = pm__thread_begin;
    it->thread_end = pm__thread_end;
    it->li = pm__li;
    it->destroy = mapper_destroy;
    it->begin_pass = pm__begin_pass;
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
