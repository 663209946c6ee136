/* pm_fit.c: how large each pass's maps are and the radii it reads them at: pass 0's photons
 * fitted to the camera samples they serve (PASS 0'S PHOTONS below: stage A, the fit, stage B;
 * THE CAUSTIC CAP and THE CAUSTIC FLOOR), the counted photon work that the fit and
 * pm_passes.c's photons per pass weigh, the radii of a pass (pass 0's, or pass 0's shrunk for
 * a progressive pass), and freeing a pass's maps.
 *
 * Calls run one way among the photon mapper's files: pm_setup.c (create, destroy, the hooks)
 * -> pm_passes.c (begin_pass) -> pm_preprocess.c (trace, build, pass 0's camera-side
 * decisions) -> pm_fit.c (this file) -> photonmapper.c (the camera sample; this file only
 * reads its pm__lookup). pm_preprocess.c calls these between its traces, pm_passes.c the
 * radii, the photon work and pm__drop_maps; nothing here calls back up.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "photon_mapping/pm_internal.h"

/* Pass 0 keeps its radii; a later pass takes them, scaled, in place of its own. The shadow
 * query (a hint that never changes the mean) and the typical radius (which decides where
 * secondary gathers run, an unbiased choice) stay as the pass finds them or as pass 0 had. */
/* ppm_radius: the first radii, f times a k-photon estimate's radius at the map's mean density
 * over the diffuse area: typical^2 = k_g A / (pi n_g) for the global map (from
 * photon_maps_radii), and k_c A / (pi n_c) = typical^2 (k_c n_g) / (k_g n_c) for the caustic
 * map; never above the maximum radii. From pass 0's radii and photon counts. */
void pm__start_radii(const mapper_state *st, map_radii *rad) {
    {
        double f = st->cfg.ppm_radius, t2 = rad->typical * rad->typical;
        double g = f * rad->typical;
        if (isfinite(g) && g < rad->global) rad->global = g;
        if (st->ncaustic_all && st->nglobal_all) {
            double c = f * sqrt(t2 * st->cfg.k_caustic * (double)st->nglobal_all /
                                ((double)st->cfg.k_global * (double)st->ncaustic_all));
            if (isfinite(c) && c < rad->caustic) rad->caustic = c;
        }
        rad->r2_global = (float)(rad->global * rad->global);
        rad->r2_caustic = (float)(rad->caustic * rad->caustic);
        if (rad->r2_lookup > rad->r2_global) rad->r2_lookup = rad->r2_global;
    }
}

void pm__pass_radii(mapper_state *st, map_radii *rad) {
    if (!st->pass) {
        if (st->progressive && st->cfg.ppm_radius > 0) pm__start_radii(st, rad);
        st->rad0 = *rad;
        return;
    }
    double f = st->r2_scale, sf = sqrt(f);
    const map_radii *r0 = &st->rad0;
    rad->global = r0->global * sf;
    rad->caustic = r0->caustic * sf;
    rad->typical = r0->typical;
    rad->r2_global = (float)((double)r0->r2_global * f);
    rad->r2_caustic = (float)((double)r0->r2_caustic * f);
    /* The lookup (photon_sides.h) reads a neighbouring point's estimate: its bias grows with
     * the distance, so its cap shrinks faster than the estimates' (README.md, Progressive
     * photon mapping, "The lookup's radius"). */
    rad->r2_lookup = (float)((double)r0->r2_lookup * pow(f, st->cfg.ppm_lookup_shrink));
}

/* The same for the volume maps of each medium (pm_volume.h): pass 0's r^2 (where pass 0 had
 * photons) times the pass's factor. */
int pm__pass_volume_radii(mapper_state *st, const scene *s) {
    pmv_state *v = &st->vol;
    if (!v->on || s->nmedia <= 0 || !v->ms) return 0;
    pmv_map *maps[3] = {v->ms, v->caus, v->all};
    if (!st->pass) {
        free(st->vol_r2_0);
        st->vol_r2_0 = malloc((size_t)s->nmedia * 3 * sizeof *st->vol_r2_0);
        if (!st->vol_r2_0) return PM_ENOMEM;
        for (int md = 0; md < s->nmedia; md++)
            for (int k = 0; k < 3; k++) st->vol_r2_0[3 * md + k] = maps[k][md].r2;
        return 0;
    }
    for (int md = 0; md < s->nmedia && st->vol_r2_0; md++)
        for (int k = 0; k < 3; k++) {
            float r0 = st->vol_r2_0[3 * md + k];
            if (isfinite(r0)) maps[k][md].r2 = (float)((double)r0 * st->r2_scale);
        }
    return 0;
}

/* The costs of photon work (PHOTONS PER PASS in pm_passes.c, and the fit below) in the sample
 * pilot's units (one BVH node visit or primitive test, about 30 ns of a camera sample's time
 * here), from the pass lines' seconds of pass 0 on cornell_box,
 * cornell_spheres and water_caustic (96x96, one thread): the photon tracing's time beyond its
 * counted work fits about 5 units per emitted photon and 20 per stored one, the kd-trees 10
 * per photon, a precomputed irradiance estimate 640 to 1000 units (19 to 30 us). Within 2x
 * of the seconds on those scenes, which is all the choice needs. */
#define PPM_EMIT_COST 5.0
#define PPM_STORE_COST 30.0
#define PPM_IRR_COST 800.0

/* W_p at the settings' targets (pm_passes.c, PHOTONS PER PASS), in the sample pilot's units,
 * from the maps st holds: the global (and volume) maps at sg x their targets, the caustic map at sc x its own. */
double pm__photon_work_at(const mapper_state *st, double sg, double sc) {
    const photon_maps *m = &st->maps;
    double wg = st->plan.work_emit[0] > 0 ? st->plan.work_emit[0] : st->sample_work;
    double wc = st->plan.work_emit[1] > 0 ? st->plan.work_emit[1] : st->sample_work;
    double nshadow = (double)(m->part ? m->whole_shadow : m->nshadow);
    /* the precomputed irradiance at the quarter of the map a build at the targets takes (the
     * fit's own points, PRECOMPUTED POINTS FITTED TO THE RENDER, are fewer only on small
     * renders: the photons' scale and the passes' fraction stay what they were without it) */
    double nirr = (double)(st->sides.quarter > st->sides.n ? st->sides.quarter : st->sides.n);
    double vol = st->sample_work * (double)(m->volume_emitted + m->volume_caustic_emitted);
    if (sg == sc) { /* one scale for all maps */
        double stored = (double)st->nglobal_all + (double)st->ncaustic_all + nshadow + (double)st->vol.n_all +
                        (double)st->vol.n_caus;
        return ((wg + PPM_EMIT_COST) * (double)m->global_emitted + (wc + PPM_EMIT_COST) * (double)m->caustic_emitted +
                vol + PPM_IRR_COST * nirr + PPM_STORE_COST * stored) / sg;
    }
    double stored_g = (double)st->nglobal_all + nshadow + (double)st->vol.n_all + (double)st->vol.n_caus;
    double g = (wg + PPM_EMIT_COST) * (double)m->global_emitted + vol + PPM_IRR_COST * nirr +
               PPM_STORE_COST * stored_g;
    double c = (wc + PPM_EMIT_COST) * (double)m->caustic_emitted + PPM_STORE_COST * (double)st->ncaustic_all;
    return g / sg + c / sc;
}

/* W_r of one pass (of the whole render when it is not in passes): its camera samples' work. */
double pm__camera_work(const mapper_state *st, const scene *s) {
    return (double)s->cam.width * (double)s->cam.height * (double)s->cam.spp * st->sample_work;
}

/* Free the volume trees of a pass (pmv_trace allocates them anew); the rest of v stays. */
static void drop_volume_maps(pmv_state *v) {
    pmv_map *maps[3] = {v->ms, v->caus, v->all};
    for (int k = 0; k < 3; k++) {
        for (int md = 0; maps[k] && md < v->nmedia; md++) {
            pm_kdtree_free(maps[k][md].t);
            free(maps[k][md].a);
            pmv_beam_free(&maps[k][md].beam);
        }
        free(maps[k]);
    }
    v->ms = v->caus = v->all = NULL;
    v->n_ms = v->n_caus = v->n_all = 0;
}

void pm__drop_maps(mapper_state *st) {
    side_cache_free(&st->sides);
    side_map_free(&st->caus_side);
    side_map_free(&st->glob_side);
    pm_kdtree_free(st->tg);
    pm_kdtree_free(st->tc);
    pm_kdtree_free(st->ts);
    st->tg = st->tc = st->ts = NULL;
    drop_volume_maps(&st->vol);
    int nmedia = st->maps.nmedia;
    photon_maps_free(&st->maps);
    st->maps.nmedia = nmedia;
}

/* PASS 0'S PHOTONS, FITTED TO THE CAMERA SAMPLES THEY SERVE. The settings' photon counts are
 * defaults sized for a large image; a small or short render that traced them all spent most of
 * its time before its first camera sample (cornell_spheres at 96x96 and 4 CPU-s: 3.5 CPU-s of
 * photons, 25 spp). So unless the scene or --pm sets a count, pass 0 is traced in two stages:
 *   stage A: 1/PM_FIT_FIRST of the targets, its trees and readers, then the sample pilot
 *            (pm_preprocess.c, camera_side_decisions), which gives the counted work of a camera sample;
 *   the fit:  s = PM_FIT_SHARE x W_r / W_p(targets), within [1/PM_FIT_FIRST, fit_ceiling],
 *            W_r the render's camera samples' counted work, W_p(targets) = stage A's counted photon work (photon_work)
 *            x PM_FIT_FIRST; the ceiling is PM_FIT_MAX where the caustic map carries much of
 *            the camera samples' luminance, the targets where it carries little (fit_ceiling);
 *   stage B: when s is above 1.25 / PM_FIT_FIRST, the maps are traced again at s x the targets
 *            (same seed) and stage A's are dropped; else stage A's maps are pass 0's.
 * The gather guide, the emission mask and the sample pilot's choices stay stage A's (they
 * choose sampling, never the mean). Counted work, never seconds: the same s for any thread
 * count, for render-mpi's processes and after a resume. PM_FIT_SHARE (README.md, "Photons
 * fitted to the render"): on water_caustic at 96x96 and 729 spp the error at equal CPU time
 * was lowest with maps at 1 to 2 x the targets (fit_ceiling's figures), where the share 0.2
 * puts them (1.8); on cornell_spheres the maps' size did not matter above half the targets,
 * which the ceiling handles. The floor, 1/PM_FIT_FIRST: below half
 * the targets the estimates' bias showed where photons are sparse (door_ajar +10..+17% at a
 * quarter, +6..+8% at a half, +5..+6% at the targets). Not fitted: counts set by the scene or
 * --pm, loaded or saved maps (a saved set must
 * match its targets when loaded), a partitioned
 * render-mpi (its sample pilot does not run), no sample pilot. */
/* THE CAUSTIC CAP (photon_trace.h CAUSTIC CAP). A caustic pass short of its target after
 * emitting 4 x the global pass's photons (at least 4194304) is light that rarely reaches a
 * diffuse surface through specular ones: glass_hole's glass behind a 10 x 10 hole stored 48775
 * of 250000 caustic photons from the whole max_emitted_factor budget (16M emitted, 4.5 of
 * 4.8 s at 64 x 64 x 16 spp) and the camera saw none of them (the sample pilot: 0.0% of its
 * luminance). So stage A traces its caustic map under the cap; the fitted trace (stage B) and
 * the later passes keep the cap where the sample pilot finds the caustic map carries less than
 * PM_FIT_CAUSTIC_LO of the camera samples' luminance, and trace to the settings' budgets where
 * it carries more. Counts set by the scene or --pm (no fit) trace to the settings' budgets. */

/* THE CAUSTIC FLOOR. Where the caustic map carries little of what the camera sees (under
 * PM_FIT_CAUSTIC_LO of the sample pilot's luminance) its size barely moves the error, while
 * its photons are most of the photon time: cornell_spheres (5.6%) at 96x96 and 16 spp spent
 * 1.05M emissions on 250,000 caustic photons against 55,000 on the 100,000 global ones, and at
 * 100 spp read RMSE 0.00790, 0.00794 and 0.00801 (seeds 1-3) with 250,000, 125,000 and 62,500
 * caustic photons. So in a scene without media stage A traces the caustic map at
 * 1/PM_FIT_FIRST_CAUSTIC of its target, and the fit keeps it there (or at the fit's own scale,
 * if larger, up to the global maps') where the map carries less than PM_FIT_CAUSTIC_LO; where it
 * carries more, the fit's scale for it is PM_FIT_CAUSTIC_SHARE / PM_FIT_SHARE x s (its photons
 * at 0.4 of the camera samples' work), within the same floor and ceiling. A caustic map above
 * 1.25 x its floor is traced again, alone (the same photons a trace of every map at that scale
 * stores: the caustic pass has its own random streams). Why 0.4 (by hand, water_caustic, q 28%,
 * 96x96, one thread, seeds 101-103, CPU-s and RMSE against the et96 reference; before, such a
 * map was traced again at the global maps' scale, 0.5 x the target, whatever s): at 25 spp
 * (s = 0.065) keeping the first stage's 62,500 photons took 3.08 CPU-s against 4.46 for RMSE
 * 5.5% higher (30% less MSE x time); at 49 spp 0.255 x the target against 0.5 read RMSE 2-3%
 * higher for 4% less CPU (even, within the loaded machine's noise); at 100 spp s x 0.4/0.2 is
 * 0.5 again. A model of the three runs (MSE = A / spp + B / N_caustic, their measured costs)
 * puts the best caustic photon time at about 0.27 of the camera samples' time. */
#define PM_FIT_SHARE 0.2
#define PM_FIT_FIRST 2.0
#define PM_FIT_FIRST_CAUSTIC 8.0
#define PM_FIT_MAX 4.0

/* The fit's ceiling: photons above the targets pay only where the caustic map is much of what
 * the camera sees (it is read at the camera path's hits, unfiltered, while the global map is
 * read through gathers). Measured at 96x96, 2 threads, seeds 1 and 2, counts set by --pm, on a
 * loaded machine (so the CPU seconds are rough, the errors firm): cornell_spheres (the caustic
 * map carries 10% of the pilot samples' luminance) read the same RMSE at 1 and 4 x the
 * targets at 289 spp (0.00419/0.00369 at 1, 0.00421/0.00369 at 4, after the caustic stride's
 * fix) and 1-3% apart at 1089 spp (0.00307/0.00300 against 0.00298/0.00295, for about 35% more
 * CPU), so maps above the targets were time lost; water_caustic (27%) fell from 0.0138 at
 * 0.5 to 0.0131, 0.0124 and 0.0119 at 1, 2 and 4 x at 729 spp. So the ceiling is PM_FIT_MAX
 * where the caustic share is at least PM_FIT_CAUSTIC_HI, the targets (1) at PM_FIT_CAUSTIC_LO
 * or less, linear between; a scene with volume photon maps keeps PM_FIT_MAX (their estimates
 * are read along the camera rays, unfiltered too, and were not measured apart). */
#define PM_FIT_CAUSTIC_LO 0.10
#define PM_FIT_CAUSTIC_HI 0.25
#define PM_FIT_CAUSTIC_SHARE 0.4
static double fit_ceiling(const mapper_state *st) {
    if (st->vol.on) return PM_FIT_MAX;
    double t = (st->sample_caustic - PM_FIT_CAUSTIC_LO) / (PM_FIT_CAUSTIC_HI - PM_FIT_CAUSTIC_LO);
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    return 1 + (PM_FIT_MAX - 1) * t;
}

static const char *ceiling_why(const mapper_state *st, double hi, char *buf, size_t cap) {
    if (st->vol.on)
        snprintf(buf, cap, "volume photon maps: the ceiling stays %.3g", hi);
    else
        snprintf(buf, cap, "the caustic map carries %.1f%% of the camera samples' luminance: ceiling %.3g, "
                 "from 1 at %.0f%% to %.3g at %.0f%%", 100 * st->sample_caustic, hi, 100 * PM_FIT_CAUSTIC_LO,
                 PM_FIT_MAX, 100 * PM_FIT_CAUSTIC_HI);
    return buf;
}

static long *fit_count(mapper_state *st, int i) {
    long *c[4] = {&st->cfg.global_photons, &st->cfg.caustic_photons, &st->cfg.volume_photons,
                  &st->cfg.volume_caustic_photons};
    return c[i];
}

static const char *const k_fit_keys[4] = {"global_photons", "caustic_photons", "volume_photons",
                                          "volume_caustic_photons"};

static void fit_count_set(mapper_state *st, int i, double f) {
    double t = (double)st->fit_target[i] * f;
    *fit_count(st, i) = st->fit_target[i] > 0 && t < 1 ? 1 : (long)llround(t);
}

static void fit_scale(mapper_state *st, double f) {
    for (int i = 0; i < 4; i++) fit_count_set(st, i, f);
}

/* Before pass 0's first trace: stage A's targets, when the fit applies (st->fit_stage 1), or
 * the reason it does not (st->fit_reason). */
void pm__fit_begin(mapper_state *st, const scene *s) {
    for (int i = 0; i < 4; i++) st->fit_target[i] = *fit_count(st, i);
    st->k0[0] = st->cfg.k_global;
    st->k0[1] = st->cfg.k_caustic;
    st->fit_scale = st->fit_scale_c = 1;
    const char *why = NULL;
    for (int i = 0; i < 4 && !why; i++)
        if (json_get(s->photon_mapping, k_fit_keys[i])) why = k_fit_keys[i];
    if (why)
        snprintf(st->fit_reason, sizeof st->fit_reason, "the targets (photon_mapping.%s is set)", why);
    else if (st->cfg.load_dir[0] || st->cfg.save_dir[0])
        snprintf(st->fit_reason, sizeof st->fit_reason, "the targets (%s photon maps keep them)",
                 st->cfg.load_dir[0] ? "loaded" : "saved");
    else if (pm__lookup)
        snprintf(st->fit_reason, sizeof st->fit_reason,
                 "the targets (partitioned render-mpi: no sample pilot to weigh them by)");
    else {
        st->fit_stage = 1;
        st->irr_fit = 1; /* PRECOMPUTED POINTS FITTED TO THE RENDER */
        st->caustic_cap = 1; /* THE CAUSTIC CAP: until the sample pilot has weighed the map */
        fit_scale(st, 1 / PM_FIT_FIRST);
        st->fit_scale_c = 1 / PM_FIT_FIRST;
        if (!st->vol.on && st->plan.caustics.on && st->fit_target[1] > 0) { /* THE CAUSTIC FLOOR */
            st->fit_scale_c = 1 / PM_FIT_FIRST_CAUSTIC;
            fit_count_set(st, 1, st->fit_scale_c);
        }
    }
}

/* After stage A's sample pilot: 1 when pass 0 must be traced again at the fitted targets (set
 * in st->cfg), 0 when stage A's maps stay (or the fit did not apply). */
int pm__fit_end(mapper_state *st, const scene *s) {
    if (!st->fit_stage) return 0;
    st->fit_stage = 0;
    st->caustic_cap = st->sample_caustic < PM_FIT_CAUSTIC_LO;
    double wp = pm__photon_work_at(st, 1 / PM_FIT_FIRST, st->fit_scale_c), wr = pm__camera_work(st, s);
    double f = wp > 0 && wr > 0 && isfinite(wp) && isfinite(wr) ? PM_FIT_SHARE * wr / wp : 0;
    if (!(wp > 0)) { /* no photons at all (no map on, or none stored): nothing to fit */
        snprintf(st->fit_reason, sizeof st->fit_reason, "no photon work to fit");
        return 0;
    }
    if (!(f > 0)) {
        st->fit_scale = st->fit_scale_c = 1;
        snprintf(st->fit_reason, sizeof st->fit_reason, "the targets (no counted work to weigh: %s)",
                 wr > 0 ? "no photons" : "no sample pilot");
        fit_scale(st, 1);
        pm__drop_maps(st);
        return 1;
    }
    double lo = 1 / PM_FIT_FIRST, hi = fit_ceiling(st), fs = f < lo ? lo : f > hi ? hi : f;
    int again = fs > 1.25 * lo;
    st->fit_scale = again ? fs : lo;
    /* THE CAUSTIC FLOOR: the caustic map's scale, from stage A's c0 */
    double c0 = st->fit_scale_c, cs = st->fit_scale;
    char floor_why[256] = "";
    if (c0 < lo) {
        double fc = st->sample_caustic < PM_FIT_CAUSTIC_LO ? f : PM_FIT_CAUSTIC_SHARE / PM_FIT_SHARE * f;
        cs = fc < c0 ? c0 : fc < cs ? fc : cs;
        if (!again && cs <= 1.25 * c0) cs = c0;
        snprintf(floor_why, sizeof floor_why, "; the caustic map at %.3g x its target (at %.2g of the camera "
                 "samples' work: it carries %s %.0f%% of their luminance; within its floor %.3g and the global "
                 "maps' %.3g)", cs, st->sample_caustic < PM_FIT_CAUSTIC_LO ? PM_FIT_SHARE : PM_FIT_CAUSTIC_SHARE,
                 st->sample_caustic < PM_FIT_CAUSTIC_LO ? "under" : "at least", 100 * PM_FIT_CAUSTIC_LO, c0,
                 st->fit_scale);
    }
    st->fit_scale_c = cs;
    int caus_again = !again && cs != c0;
    if (again) fit_scale(st, fs);
    if (again || caus_again) fit_count_set(st, 1, cs);
    char vol[96] = "", why[128];
    if (st->vol.on)
        snprintf(vol, sizeof vol, ", volume %ld, volume caustic %ld", st->fit_target[2], st->fit_target[3]);
    snprintf(st->fit_reason, sizeof st->fit_reason,
             "%.3g x the targets (global %ld, caustic %ld%s): counted work of the targets' photons "
             "%.3g, of %d x %d x %d camera samples %.3g; photons at %.2g of that, within [%.3g, %.3g] "
             "(%s)%s; %s",
             st->fit_scale, st->fit_target[0], st->fit_target[1], vol, wp, s->cam.width,
             s->cam.height, s->cam.spp, wr, PM_FIT_SHARE, lo, hi, ceiling_why(st, hi, why, sizeof why),
             floor_why, again ? "traced again" : caus_again ? "the caustic map traced again" : "the first stage's maps kept");
    if (caus_again) return PM_FIT_CAUSTIC_AGAIN;
    if (!again) return PM_FIT_KEEP;
    pm__drop_maps(st);
    return PM_FIT_AGAIN;
}

/* PRECOMPUTED POINTS FITTED TO THE RENDER. Precomputed irradiance at a quarter of the global
 * photons costs PPM_IRR_COST units an estimate whatever the render's size: at 32x32 and 4 spp
 * (pass 0's first stage, 100,000 global photons, 25,000 estimates) 0.5 to 1 CPU-s, most of the
 * run, for a few thousand lookups (perf: 30 to 58% of the CPU of cornell_point, cornell_spheres,
 * sun_window, door_ajar, partition_thin and water_caustic there, four fifths of it the
 * estimates' neighbour searches). Points closer than an estimate's radius carry little that
 * their neighbours do not (their discs share most of their photons), so where the fit applies
 * pass 0 computes them at the photons of height >= h in the global map's kd-tree
 * (side_cache_build_at: h 2 the quarter, 3 an eighth, 4 a sixteenth), h the lowest whose
 * estimates' counted work is at most PM_IRR_SHARE of the camera samples' (pixels x spp x the
 * sample pilot's work per sample), within [2, PM_IRR_HEIGHT_MAX] and with at least
 * PM_IRR_PER_DISC points in an estimate's disc (k_global / 2^h: an eighth at k_global 50 and
 * more, a quarter below 48). At a thirty-second the lookups finding no point on their side
 * rose from under 0.03% to 1% (cornell_box and cornell_spheres at 96x96, 64 spp), at a
 * sixty-fourth to 15%. The limit is an eighth, not a sixteenth, for the bias: a lookup reads
 * the nearest point, and points sit where photons are dense, so sparser points read brighter
 * neighbours. cornell_spheres' ceiling at 32x32, 64 spp, one gather ray, seeds 12 to 19, against
 * a 65,536-spp path-traced render: mean +1.62% at the quarter, +2.01% at an eighth, +2.55% at a
 * sixteenth (seed 12: +3.09/+4.11/+4.49%; the sixteenth failed render_pm_agrees_with_path_tracing
 * in the sanitized run). Stage A (before the sample pilot gives the work per sample) takes
 * PM_SAMPLE_WORK_MIN, about the least a shipped scene's sample costs (42 to 2,763 units in the
 * survey's plans, most 60 to 130), so it seldom computes more points than the fit then asks
 * for; where the fit keeps stage A's maps and asks for more, side_cache_refine adds them (the
 * same values as a build there), and where it asks for fewer, stage A's stay. The sample pilot
 * ran on stage A's points, so where they were refined its choice may differ from a pilot on
 * the final ones (it chooses sampling, never the mean). At the render sizes where
 * the quarter's work is under PM_IRR_SHARE of the camera samples' (cornell_box at 96x96 from
 * about 256 spp) nothing changes. Counted work, never seconds: the same points for any thread
 * count. Measured: README.md, "Photons fitted to the render". */
#define PM_IRR_SHARE 0.2
#define PM_IRR_HEIGHT_MAX 3
#define PM_IRR_PER_DISC 6.0
#define PM_SAMPLE_WORK_MIN 64.0

int pm__irr_height(mapper_state *st, const scene *s, size_t n) {
    st->irr_reason[0] = 0;
    double work = st->fit_stage ? PM_SAMPLE_WORK_MIN : st->sample_work;
    if (st->pass || !st->irr_fit || !(work > 0) || n == 0) return SIDE_HEIGHT_QUARTER;
    double wr = (double)s->cam.width * (double)s->cam.height * (double)s->cam.spp * work;
    double points = PM_IRR_SHARE * wr / PPM_IRR_COST; /* the estimates the share pays for */
    int h = SIDE_HEIGHT_QUARTER;
    /* at least PM_IRR_PER_DISC points in an estimate's disc of k_global photons */
    int hmax = PM_IRR_HEIGHT_MAX;
    while (hmax > SIDE_HEIGHT_QUARTER && ldexp((double)st->cfg.k_global, -hmax) < PM_IRR_PER_DISC) hmax--;
    while (h < hmax && ldexp((double)n, -h) > points) h++;
    static const char *const k_part[] = {"all", "half", "a quarter", "an eighth", "a sixteenth"};
    snprintf(st->irr_reason, sizeof st->irr_reason,
             "at %s of them (the photons of height >= %d in the map's kd-tree, %d to %d allowed): estimates "
             "of counted work %.0f each at %.2g of the camera samples' %.3g", k_part[h], h, SIDE_HEIGHT_QUARTER,
             hmax, PPM_IRR_COST, PM_IRR_SHARE, wr);
    return h;
}
