/* pm_preprocess.c: the photon mapper's preprocess, for pass 0 and each progressive pass:
 * trace (or load) the maps as the plan says, build their kd-trees, then what reads them at the
 * pass's radii (the caustic side map and the precomputed irradiance); on pass 0 also the
 * camera-side decisions (the gather guide, the emission mask and the sample pilot, through
 * photonmapper.c's eye rays). See photonmapper.c for the integrator these serve, pm_passes.c
 * for the passes.
 *
 * Calls run one way: pm_setup.c wires pm__preprocess and pm_passes.c calls it and
 * pm__build_estimates; this file calls pm_fit.c (pass 0's photons fitted between its traces,
 * the pass's radii) and photonmapper.c (eye rays, scratch, the gather guide's probes), and
 * neither calls back here.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/stats.h"
#include "integrators/direct.h"
#include "photon_mapping/pm_internal.h"
#include "scene/light.h"

enum { BUCKET_GLOBAL = 1, BUCKET_CAUSTIC = 8, BUCKET_SHADOW = 8 };

/* Progressive passes: pm_passes.c (pm__begin_pass), their radii pm_fit.c's (pm__pass_radii). */

/* What reads the maps at the pass's radii: the caustic side map, the estimates' options and
 * the precomputed irradiance (side cache). pm_passes.c calls it again when a progressive
 * render's first radii differ from the plain render's (ppm_radius), without tracing again. */
static int build_readers(mapper_state *st, const scene *s, const map_radii *rad, char *err, size_t errcap) {
    int rc;
    if ((rc = side_map_init(&st->caus_side, s, st->tc, st->maps.ncaustic, rad->r2_caustic, err, errcap)) < 0) return rc;
    /* The global map shown directly (preview, final_gather=false) is read at the camera's hits:
     * there too a disc by a wall must not take the photons of its other side (photon_sides.h;
     * without it door_ajar's preview read +303%, pinhole_room's +2,579%). */
    if (st->direct_vis && st->nglobal_all &&
        (rc = side_map_init(&st->glob_side, s, st->tg, st->maps.nglobal, rad->r2_global, err, errcap)) < 0)
        return rc;
    st->glob_side.in_plane_rays = 1;
    st->r2_global = rad->r2_global;
    st->r2_caustic = rad->r2_caustic;
    st->r2_lookup = rad->r2_lookup;
    st->r2_shadow = rad->r2_shadow;
    st->sec_dist = st->cfg.secondary_distance > 0 ? st->cfg.secondary_distance : rad->typical;

    pm_estimator kinds[] = {PM_EST_DISC, PM_EST_CONE, PM_EST_GAUSS, PM_EST_HULL};
    pm_estimate_options_init(&st->caus_opt, kinds[st->cfg.filter], (unsigned)st->cfg.k_caustic);
    st->caus_opt.max_dist2 = st->r2_caustic;
    st->caus_opt.reject_behind = 1;
    pm_estimate_options_init(&st->glob_opt, PM_EST_DISC, (unsigned)st->cfg.k_global);
    st->glob_opt.max_dist2 = st->r2_global;
    st->glob_opt.reject_behind = 1;
    return 0;
}

int pm__build_estimates(mapper_state *st, const scene *s, const map_radii *rad, char *err, size_t errcap) {
    int rc;
    double t0;
    if ((rc = build_readers(st, s, rad, err, errcap)) < 0) return rc;
    st->t_irr = 0;
    if (st->nglobal_all && !st->direct_vis) {
        t0 = stats_now();
        rc = pm__lookup ? pm__lookup->side_build(pm__lookup->user, &st->sides, s, st->tg,
                                             st->tg ? pm_kdtree_records(st->tg) : NULL, st->maps.nglobal,
                                             (unsigned)st->cfg.k_global, st->r2_global, err, errcap)
                      : side_cache_build_at(&st->sides, s, st->tg, pm_kdtree_records(st->tg), st->maps.global_path,
                                            st->maps.nglobal, (unsigned)st->cfg.k_global, st->r2_global,
                                            pm__irr_height(st, s, st->maps.nglobal), err, errcap);
        if (rc < 0) return rc;
        stat_add(st->st_side_rays, st->sides.rays_first + st->sides.rays_second);
        stat_add(st->st_side_again, st->sides.researched);
        st->t_irr = stats_now() - t0;
        stats_time_add("Time/Precomputed irradiance", st->t_irr);
    }
    return 0;
}

/* PRECOMPUTED POINTS FITTED TO THE RENDER (pm_fit.c): where pass 0 keeps its first stage's
 * global map, the points the fit asks for beyond the first stage's (none when it asks for no
 * more). */
static int refine_estimates(mapper_state *st, const scene *s, char *err, size_t errcap) {
    side_cache *c = &st->sides;
    if (pm__lookup || !c->val) return 0;
    int h = pm__irr_height(st, s, st->maps.nglobal);
    if (h > c->height) { /* fewer than the first stage's: those stay */
        size_t len = strlen(st->irr_reason);
        snprintf(st->irr_reason + len, sizeof st->irr_reason - len, "; the first stage's %zu kept", c->n);
    }
    if (h >= c->height) return 0;
    double t0 = stats_now();
    unsigned long long rays0 = c->rays_first + c->rays_second;
    size_t again0 = c->researched;
    int rc = side_cache_refine(c, s, st->tg, pm_kdtree_records(st->tg), st->maps.global_path, st->maps.nglobal,
                               (unsigned)st->cfg.k_global, st->r2_global, h, err, errcap);
    if (rc < 0) return rc;
    stat_add(st->st_side_rays, c->rays_first + c->rays_second - rays0);
    stat_add(st->st_side_again, c->researched - again0);
    double dt = stats_now() - t0;
    st->t_irr += dt;
    stats_time_add("Time/Precomputed irradiance", dt);
    return 0;
}

/* The surface tracer's options for pass 0's maps: the settings' targets, budgets and projection,
 * as the plan read them (plan_joins); which maps, the importance table and the pilot's photons
 * are the plan's. */
static void plan_trace_opts(const mapper_state *st, const scene *s, trace_opts *o) {
    trace_opts_settings(o, s, &st->cfg);
    o->global = st->plan.global.on;
    o->caustic = st->plan.caustics.on;
    o->shadow = st->plan.shadow.on;
    o->importance = st->plan.imp; /* importance-driven emission, when the plan chose it */
    o->reuse = st->plan.pilot;    /* the plan's pilot photons join the global maps */
    o->caustic_cap = st->caustic_cap;
}

/* THE CAUSTIC PROBE. Pass 0's first stage (pm_fit.c, PASS 0'S PHOTONS) traces its caustic
 * map for the sample pilot to weigh (the share of the camera samples' luminance it carries),
 * under the caustic cap (photon_trace.h CAUSTIC CAP: 4 x the global pass's photons emitted, at
 * least 4194304). That floor is sized for a large render, not for the camera samples the map
 * serves: glass_hole at 32x32 (its glass lit through a 10 x 10 hole: 26 caustic stores from
 * 8192 aimed pilot photons) emitted 4.0M caustic photons in the first stage, about 1.8 of its
 * 2.4 CPU-s at 4 spp and more than a whole 2 CPU-s budget, for a map the sample pilot then
 * found carrying 0.0% of the luminance (and kept, as a map under 10% is). So the first
 * stage's floor is the render's camera samples (width x height x spp) where they are fewer:
 * one emission per camera sample, under a fifth of what the fit gives all photons
 * (PM_FIT_SHARE of the camera samples' counted work; a camera sample counts 64 units or more
 * in the shipped scenes' sample pilots, an emitted photon about 5). The cap still stops only
 * a pass short of its target, so this changes only a map whose light rarely reaches a diffuse
 * surface through specular ones. Where the sample pilot finds it carries 10% or more of the
 * luminance and the fit traces the caustic map again (stage B, or the caustic map alone), that
 * trace goes to the settings' budgets. But on a small render the fit may keep the first
 * stage's caustic map (pm_fit.c, THE CAUSTIC FLOOR: its fitted scale within 1.25 x its floor),
 * and then a map the probe stopped short is the render's map, whatever share it carries
 * (unbiased, with fewer photons): water_caustic at 24x24 and 4 spp keeps 40,034 of 62,500
 * caustic photons and prints the cap's message, which at that size is expected (README.md,
 * "the caustic probe"). A first stage whose caustic pass then stores nothing is traced again
 * at the usual floor (as it was before). */
static double caustic_probe_floor(const mapper_state *st, const scene *s) {
    if (!st->fit_stage || st->pass) return 0;
    double cam = (double)s->cam.width * (double)s->cam.height * (double)s->cam.spp;
    return cam < CAUSTIC_CAP_MIN ? cam : 0;
}

/* Trace (or load) the maps of st->pass at the targets in st->cfg, build their trees and
 * readers. Quiet while pass 0's first stage runs (pm_fit.c, PASS 0'S PHOTONS). */
static int trace_and_build(mapper_state *st, const scene *s, char *err, size_t errcap) {
    photon_maps *m = &st->maps;
    int rc;
    double t0 = stats_now();
    map_stamp stamp; /* what shapes this run's maps: checked on load, written on save */
    map_stamp_make(s, &st->cfg, st->plan.global.on, st->plan.caustics.on, st->plan.shadow.on, &stamp);
    if (st->vol.on) { /* a scene with media: its own tracer, surface and volume maps */
        /* Loaded maps (the volume files too, photon_maps.h) are checked here; pmv_trace then
         * builds its trees from them instead of tracing. */
        map_stamp_volume(s, &st->cfg, st->plan.volume.on, st->plan.volume_caustics.on, &stamp);
        m->nmedia = s->nmedia;
        if (st->cfg.load_dir[0] &&
            (rc = photon_maps_load(m, st->cfg.load_dir, &stamp, st->cfg.force_load, err, errcap)) < 0)
            return rc;
        int loaded = m->loaded;
        /* A later pass traces with its own seed (the scene's copy carries it to pmv_trace). */
        scene sp = *s;
        sp.settings.seed = st->pass_seed;
        st->vol.quiet = st->fit_stage; /* the fit's first stage prints no maps (pm_fit.c) */
        st->vol.caustic_cap_min = caustic_probe_floor(st, s); /* THE CAUSTIC PROBE */
        if ((rc = pmv_trace(&st->vol, &sp, &st->cfg, &st->plan, m, err, errcap)) < 0) return rc;
        if (!loaded) m->stamp = stamp;
        if ((rc = pm__pass_volume_radii(st, s)) < 0) return rc;
    } else if (st->cfg.load_dir[0]) {
        if ((rc = photon_maps_load(m, st->cfg.load_dir, &stamp, st->cfg.force_load, err, errcap)) < 0)
            return rc;
        /* The plan decides which loaded maps are used. */
        if (!st->plan.global.on) m->nglobal = 0;
        if (!st->plan.caustics.on) m->ncaustic = 0;
        if (!st->plan.shadow.on) m->nshadow = 0;
        printf("Loaded photon maps from %s: %zu global, %zu caustic, %zu shadow-map photons\n",
               st->cfg.load_dir, m->nglobal, m->ncaustic, m->nshadow);
    } else {
        trace_opts o;
        plan_trace_opts(st, s, &o);
        if (st->pass) { /* a later pass: its own photons only (the pilot joined pass 0) */
            o.seed = st->pass_seed;
            o.reuse = NULL;
        }
        o.caustic_cap_min = caustic_probe_floor(st, s); /* THE CAUSTIC PROBE */
        scene sp; /* with the ports the plan's probe found (ports.h), if any */
        const scene *ps = ports_found_scene(s, &st->plan.found, &sp);
        rc = photon_trace(ps, &o, m, err, errcap);
        if (rc == PM_EEMPTY && o.caustic_cap_min > 0) {
            o.caustic_cap_min = 0;
            rc = photon_trace(ps, &o, m, err, errcap);
        }
        if (rc < 0) return rc;
        m->stamp = stamp;
    }
    st->t_trace = stats_now() - t0;
    stats_time_add("Time/Photon tracing (or loading)", st->t_trace);
    if (st->vol.on) { /* the beam maps of the eye rays (pm_beam.h), at this pass's radii */
        double tb = stats_now();
        if ((rc = pmv_build_beams(&st->vol, s)) < 0) {
            snprintf(err, errcap, "out of memory building the volume beam maps");
            return rc;
        }
        stats_time_add("Time/Volume beam maps", stats_now() - tb);
    }
    /* Saved before the trees reorder them: loading these files then gives the trees, the
     * precomputed irradiance and the image of this run exactly. */
    if (st->cfg.save_dir[0] && !st->made) {
        if ((rc = photon_maps_save(m, st->cfg.save_dir, err, errcap)) < 0) return rc;
        printf("Saved photon maps to %s\n", st->cfg.save_dir);
    }

    /* The radii of the whole maps, before a distributed render keeps only its part of them. */
    map_radii rad;
    photon_maps_radii(s, m, &st->cfg, &rad);
    st->nglobal_all = m->part ? m->whole_global : m->nglobal;
    st->ncaustic_all = m->part ? m->whole_caustic : m->ncaustic;
    pm__pass_radii(st, &rad); /* progressive passes: pass 0's radii, shrunk */
    if (pm__lookup && (rc = pm__lookup->partition(pm__lookup->user, m, err, errcap)) < 0) return rc;

    t0 = stats_now();
    if ((rc = photon_tree_build_global(&st->tg, m, BUCKET_GLOBAL, err, errcap)) < 0 ||
        (rc = photon_tree_build(&st->tc, m->caustic, m->ncaustic, BUCKET_CAUSTIC, err, errcap)) < 0 ||
        (rc = photon_tree_build(&st->ts, m->shadow, m->nshadow, BUCKET_SHADOW, err, errcap)) < 0)
        return rc;
    st->t_trees = stats_now() - t0;
    stats_time_add("Time/Photon kd-trees", st->t_trees);
    return pm__build_estimates(st, s, &rad, err, errcap);
}

/* THE CAUSTIC FLOOR (pm_fit.c): pass 0's caustic map traced again alone, at the fitted
 * target in st->cfg, with its tree and readers; the global maps, their trees and the
 * precomputed irradiance stay. Its photons are those a trace of every map stores (the caustic
 * pass has its own random streams; the cap scales with the global pass's emitted photons). */
static int retrace_caustic(mapper_state *st, const scene *s, char *err, size_t errcap) {
    photon_maps *m = &st->maps, c;
    double t0 = stats_now();
    trace_opts o;
    plan_trace_opts(st, s, &o);
    o.global = o.shadow = 0;
    o.cap_global_emitted = m->global_emitted;
    scene sp;
    int rc = photon_trace(ports_found_scene(s, &st->plan.found, &sp), &o, &c, err, errcap);
    if (rc < 0) return rc;
    /* The new caustic map replaces the old field by field (the same shape as pm_volume.c's
     * move of the volume tracer's surface maps, deliberately: the result types differ). */
    free(m->caustic);
    m->caustic = c.caustic;
    c.caustic = NULL;
    m->ncaustic = c.ncaustic;
    m->caustic_emitted = c.caustic_emitted;
    m->caustic_fraction = c.caustic_fraction;
    m->caustic_saved = c.caustic_saved;
    m->caustic_first_specular = c.caustic_first_specular;
    m->caustic_runaway = c.caustic_runaway;
    m->pilot_emitted[1] = c.pilot_emitted[1];
    m->pilot_stored[1] = c.pilot_stored[1];
    m->whole_caustic = c.whole_caustic;
    m->whole_max_power[1] = c.whole_max_power[1];
    photon_maps_free(&c);
    double dt = stats_now() - t0;
    st->t_trace += dt;
    stats_time_add("Time/Photon tracing (or loading)", dt);
    map_radii rad;
    photon_maps_radii(s, m, &st->cfg, &rad);
    st->ncaustic_all = m->part ? m->whole_caustic : m->ncaustic;
    pm__pass_radii(st, &rad);
    side_map_free(&st->caus_side);
    side_map_free(&st->glob_side);
    pm_kdtree_free(st->tc);
    st->tc = NULL;
    t0 = stats_now();
    if ((rc = photon_tree_build(&st->tc, m->caustic, m->ncaustic, BUCKET_CAUSTIC, err, errcap)) < 0) return rc;
    dt = stats_now() - t0;
    st->t_trees += dt;
    stats_time_add("Time/Photon kd-trees", dt);
    return build_readers(st, s, &rad, err, errcap);
}

/* Stage A's caustic counters, taken back out when its caustic map is traced again alone. */
static const char *const k_caustic_counters[] = {
    "Photons/Emitted, caustic pass", "Photons/Caustic photons stored",
    "Photons/Caustic emissions saved by the projection map", "Photons/Caustic-pass photons whose first hit is specular",
    "Photons/Pilot photons reused in the caustic map (emitted)", "Photons/Pilot photons reused in the caustic map (stored)"};

/* Pass 0's lines on stdout, once its maps are final: the photons traced (of a scene without
 * media: pmv_trace prints its own), the radii and the precomputed irradiance. */
static void print_maps(const mapper_state *st, const scene *s) {
    const photon_maps *m = &st->maps;
    const map_radii *rad = &st->rad0;
    if (st->vol.on && st->vol.quiet) /* the first stage's maps, kept: their line is not out yet */
        pmv_print_maps(&st->vol, s, m, st->cfg.load_dir[0] ? st->cfg.load_dir : NULL);
    if (!st->vol.on && !st->cfg.load_dir[0])
        printf("Photons: %zu global, %zu shadow-map (from %llu emitted); %zu caustic (from %llu "
               "emitted; projection maps cover %.2f%% of the light's power, saving %llu "
               "emissions)\n",
               m->part ? m->whole_global : m->nglobal, m->part ? m->whole_shadow : m->nshadow,
               (unsigned long long)m->global_emitted, m->part ? m->whole_caustic : m->ncaustic,
               (unsigned long long)m->caustic_emitted, 100 * m->caustic_fraction,
               (unsigned long long)m->caustic_saved);
    printf("Radii: global estimate %.4g, caustic estimate %.4g, secondary gather below %.4g, "
           "shadow-map query %.4g\n",
           rad->global, rad->caustic, st->sec_dist, rad->shadow);
    if (st->nglobal_all && !st->direct_vis)
        printf("Precomputed irradiance at %zu of %zu global photons (%zu estimates searched again "
               "for a hidden neighbour, %zu on their own surface at a corner; %zu of too few photon "
               "paths to be read: the light there is computed)%s%s\n",
               st->sides.n, st->nglobal_all, st->sides.researched, st->sides.corners, st->sides.sparse,
               st->irr_reason[0] ? "; " : "", st->irr_reason);
}

/* ---- pass 0's camera-side decisions (pm_sample.h, gather_guide.h) ------------------------- */


/* Scratch for the preprocess's own camera rays (the emission mask, the sample pilot). */
static void *sample_scratch_new(void *user) {
    return pm__scratch_new(user);
}

static void sample_scratch_free(void *user, void *scratch) {
    (void)user;
    pm__thread_end(NULL, scratch);
}

/* The emission mask and the sample pilot, once (pass 0's preprocess), and their plan lines. */
static int sample_decide(mapper_state *st, const scene *s, char *err, size_t errcap) {
    st->scene = s;
    const char *no_pilot = !st->plan.final_gather.on || st->direct_vis ? "no final gather"
                           : !st->sides.irr ? "no precomputed irradiance to gather from"
                           : pm__lookup ? "partitioned render-mpi: its lookups are shared between processes"
                                      : NULL;
    int area = 0; /* DIRECT STRATA (pm_sample.c): delta lights only */
    for (int i = 0; i < s->nlights; i++)
        area |= !light_is_point(&s->lights[i]) && s->lights[i].type != LIGHT_DIRECTIONAL;
    pm_sample_host h = {s, &st->cfg, st->st_lookup, st->st_caustic, st->ncaustic_all > 0, no_pilot,
                        st->vol.on && !json_get(s->photon_mapping, "volume_stride"),
                        pm__lookup != NULL, st, sample_scratch_new, sample_scratch_free, pm__sample_eye,
                        st->st_lookup_miss, st->explicit_miss,
                        st->direct_vis   ? "the global map shown directly"
                        : pm__lookup     ? "partitioned render-mpi"
                        : area           ? "a light with an area: its samples' own noise, not an edge, would mark pixels"
                                         : NULL};
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

/* The port the gathers and the direct light aim at (gather_guide.h PORTS AS OPENINGS, direct.h
 * THROUGH A PORT): the largest declared port, or the found port that threads the largest share
 * of the carried light (ports.h keeps them in that order); NULL: none. */
static const port *aim_port(const mapper_state *st, const scene *s) {
    const port *aim = st->plan.found.n > 0 ? &st->plan.found.p[0] : NULL;
    for (int i = 0; i < s->nports; i++)
        if (!aim || s->ports[i].area > aim->area) aim = &s->ports[i];
    return aim;
}

/* direct.h, THROUGH A PORT: on where the scene has a port, no media (their shadow segments carry
 * transmittance), a known lit side and area or sphere lights there with at least half the
 * lights' power (a port sample finds only those); photon_mapping.direct_port=false turns it off,
 * true drops the last condition. The words in why. */
static void port_direct_decide(mapper_state *st, const scene *s, char *why, size_t cap) {
    const port *pt = aim_port(st, s);
    int force = st->cfg.force_direct_port;
    const char *forced = force == PLAN_ON ? ", though photon_mapping.direct_port=true" : "";
    st->dport = NULL;
    if (force == PLAN_OFF) {
        snprintf(why, cap, "off (photon_mapping.direct_port=false)");
        return;
    }
    if (!pt) {
        snprintf(why, cap, "off (no photon port%s)", forced);
        return;
    }
    if (st->vol.on) {
        snprintf(why, cap, "off (participating media: a ray through the port does not attenuate%s)", forced);
        return;
    }
    double share, reach = 0, all = 0;
    vec3 lit = gather_guide_port_lit(s, pt, &share);
    for (int i = 0; i < s->nlights; i++) {
        const light *l = &s->lights[i];
        double w = rgb_lum(l->power);
        all += w;
        if ((l->type == LIGHT_AREA || l->type == LIGHT_SPHERE) && w > 0) reach += w;
    }
    if (v3_len2(lit) == 0 || (!(reach >= 0.5 * all) && force != PLAN_ON)) {
        snprintf(why, cap, "off (the port at (%.4g, %.4g, %.4g): %s%s)", pt->c.x, pt->c.y, pt->c.z,
                 v3_len2(lit) == 0 ? "the lights' power is on both of its sides, so it has no dark side" :
                 "area and sphere lights carry under half the lights' power (a ray through the port finds no other)",
                 v3_len2(lit) == 0 ? forced : "");
        return;
    }
    st->dport = pt;
    st->dport_lit = lit;
    snprintf(why, cap, "on (%sthe port at (%.4g, %.4g, %.4g), its light along (%.2f, %.2f, %.2f): at points on its "
             "dark side each light sample is joined by a ray through the port, weighted %.2f : %.2f by the balance "
             "heuristic; area and sphere lights carry %.0f%% of the lights' power)",
             force == PLAN_ON ? "photon_mapping.direct_port=true; " : "", pt->c.x, pt->c.y, pt->c.z, lit.x,
             lit.y, lit.z, DIRECT_PORT_SHARE, 1 - DIRECT_PORT_SHARE, all > 0 ? 100 * reach / all : 0);
}

/* Once, on pass 0: the gather guide (gather_guide.h) and the camera sample (pm_sample.h), both
 * from probes through photonmapper.c's eye rays, with the plan's lines they print. */
static int camera_side_decisions(mapper_state *st, const scene *s, char *err, size_t errcap) {
    int rc;
    double t0;
    /* decided first, printed after the gather guide's line */
    char dwhy[400];
    port_direct_decide(st, s, dwhy, sizeof dwhy);
    t0 = stats_now();
    {
        const char *why = !st->plan.final_gather.on || st->direct_vis ? "no final gather"
                          : !st->sides.irr                             ? "no precomputed irradiance to probe"
                          : st->vol.on ? "participating media: its probes do not march"
                          : pm__lookup   ? "partitioned render-mpi: its probes would read one process's records"
                                       : NULL;
        /* PORTS AS OPENINGS (gather_guide.h): aim_port's port */
        gather_guide_probe probe = {st, pm__gg_found, pm__gg_read, s->nports > 0 || st->plan.found.n > 0,
                                    aim_port(st, s)};
        if ((rc = gather_guide_make(&st->gg, s, st->cfg.force_gather_guide, why, &probe, err, errcap)) < 0)
            return rc;
    }
    stats_time_add("Time/Gather guide pilot", stats_now() - t0);
    printf("  gather guide: %s\n", st->gg.reason);
    printf("  direct light through the port: %s\n", dwhy);
    t0 = stats_now();
    if ((rc = sample_decide(st, s, err, errcap)) < 0) return rc;
    stats_time_add("Time/Sample pilot and emission mask", stats_now() - t0);
    printf("  sample: %s\n", st->sample_reason);
    printf("  emission rays: %s\n", st->emit_reason);
    return 0;
}

/* The counters stage A's trace and readers added (taken back out when it is traced again). */
static void counters_now(uint64_t *v) {
    for (int id = 0; id < STATS_MAX; id++) v[id] = stats_name(id) ? stats_total(id) : 0;
}

int pm__preprocess(integrator *self, const scene *s, char *err, size_t errcap) {
    mapper_state *st = self->data;
    if (!st->made) plan_print(&st->plan, stdout);
    fflush(stdout);
    int rc, first = !st->made && st->pass == 0;
    uint64_t c0[STATS_MAX], c1[STATS_MAX];
    int progress = st->cfg.progress;
    if (first) {
        pm__fit_begin(st, s);
        if (st->fit_stage) st->cfg.progress = 0;
        counters_now(c0);
    }
    rc = trace_and_build(st, s, err, errcap);
    st->cfg.progress = progress;
    if (rc < 0) return rc;
    if (st->made) { /* the gather guide is the plan's: made once, on pass 0 */
        fflush(stdout);
        return 0;
    }
    counters_now(c1);
    if ((rc = camera_side_decisions(st, s, err, errcap)) < 0) return rc;
    int fit = first ? pm__fit_end(st, s) : PM_FIT_KEEP;
    if (fit == PM_FIT_AGAIN) { /* pass 0 again, at the fitted targets */
        for (int id = 0; id < STATS_MAX; id++)
            if (stats_name(id)) stat_add(id, c0[id] - c1[id]); /* mod 2^64 */
        if ((rc = trace_and_build(st, s, err, errcap)) < 0) return rc;
    } else if (fit == PM_FIT_CAUSTIC_AGAIN) { /* its caustic map again (THE CAUSTIC FLOOR) */
        for (size_t i = 0; i < sizeof k_caustic_counters / sizeof *k_caustic_counters; i++) {
            int id = stats_register(k_caustic_counters[i]);
            stat_add(id, c0[id] - c1[id]); /* mod 2^64 */
        }
        if ((rc = retrace_caustic(st, s, err, errcap)) < 0) return rc;
    }
    if (first && fit != PM_FIT_AGAIN && (rc = refine_estimates(st, s, err, errcap)) < 0) return rc;
    if (first) {
        printf("  photons: %s\n", st->fit_reason);
        print_maps(st, s);
    }
    st->made = 1;
    if (pm__lookup) {
        const pm_kdtree *trees[2] = {st->tg, st->tc};
        pm_estimate_options opts[2] = {st->glob_opt, st->caus_opt};
        pm__lookup->ready(pm__lookup->user, trees, opts);
    }
    fflush(stdout);
    return 0;
}

