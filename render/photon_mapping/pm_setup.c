/* pm_setup.c: the photon-mapping integrators' life around the camera sample (photonmapper.c
 * renders it): create ("$.photon_mapping" read, the plan made, the counters registered, the
 * integrator's hooks wired) and destroy.
 *
 * Calls run one way among the photon mapper's files, from this file down: pm_setup.c wires
 * the hooks (preprocess, begin_pass, li, thread_begin, thread_end) -> pm_passes.c (the
 * progressive passes) -> pm_preprocess.c (the maps traced or loaded, their trees and readers,
 * pass 0's camera-side decisions) -> pm_fit.c (pass 0's photons fitted, the passes' radii) ->
 * photonmapper.c (the camera sample, its eye rays and the gather guide's probes). Nothing
 * below calls back up: what a lower file needs from a higher one is data in mapper_state.
 */
#include <stdio.h>
#include <stdlib.h>

#include "photon_mapping/pm_internal.h"

#include "base/stats.h"

static void mapper_destroy(integrator *self) {
    mapper_state *st = self->data;
    if (!st) return;
    side_cache_free(&st->sides);
    side_map_free(&st->caus_side);
    side_map_free(&st->glob_side);
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


/* ---- create -------------------------------------------------------------------------------- */

/* The ports the plan aims photons through (declared, or found by its probe), unless
 * photon_mapping.camera_focus is false. */
static int pm__camera_ports(const integrator *self, const scene *s, const port **ports) {
    const mapper_state *st = self->data;
    if (!st->plan.ports.on || !st->cfg.camera_focus) return 0;
    if (st->plan.found.n) {
        *ports = st->plan.found.p;
        return st->plan.found.n;
    }
    *ports = s->ports;
    return s->nports;
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
    st->explicit_gather = json_get(s->photon_mapping, "gather_rays") != NULL;
    st->explicit_secondary = json_get(s->photon_mapping, "secondary_rays") != NULL;
    st->explicit_stride = json_get(s->photon_mapping, "caustic_stride") != NULL;
    st->explicit_miss = json_get(s->photon_mapping, "miss_survival") != NULL;
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
    /* One named counter per line, as pm_volume.c's for media: a table would only move these
     * names away from the fields they fill (a deliberate same-shape run). */
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
    it->camera_ports = pm__camera_ports;
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
