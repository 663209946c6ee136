/* pm_passes.c: progressive photon mapping, the photon mapper's passes (README.md,
 * "Progressive photon mapping"; run/passes.h runs them): the integrator's begin_pass hook, the
 * photons a later pass traces and the radii it reads them at.
 *
 * Calls run one way: pm_setup.c wires pm__begin_pass; this file calls pm_preprocess.c (a
 * pass's trace and readers) and pm_fit.c (the radii, the photon work, dropping a pass's maps),
 * and neither calls back here.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "base/stats.h"
#include "photon_mapping/pm_internal.h"

/* Progressive photon mapping (README.md, "Progressive photon mapping"): a render in passes
 * (run/passes.h) calls pm__begin_pass before pass p >= 1. The pass traces fresh maps with
 * its own seed (global, caustic, shadow, volume; the plan's pilot photons joined pass 0 only),
 * builds its own trees, precomputed irradiance and caustic side map, and caps every estimate
 * at pass 0's radius^2 times ppm_r2_scale(p) (Knaus and Zwicker 2011). The plan, the
 * importance table and the guides are pass 0's. */

/* prod_{j=1..p} (j + alpha) / (j + 1): r^2 of pass p (0-based) over r^2 of pass 0, from
 * r^2_{i+1} = r^2_i (i + alpha) / (i + 1) with the first pass i = 1. */
static double ppm_r2_scale(int pass, double alpha) {
    double f = 1;
    for (int j = 1; j <= pass; j++) f *= (j + alpha) / (j + 1);
    return f;
}

/* PHOTONS PER PASS. Pass 0 traces the settings' targets (it is the plain render, and its
 * radii start the schedule). A later pass traces the fraction f of them that makes its photon
 * work about PPM_PHOTON_SHARE times its camera samples' work, both counted, never timed, so f is
 * the same on every machine, thread count and process (render-mpi) and after a resume:
 *   camera work  W_r = pixels x spp of a pass x the sample pilot's work per sample;
 *   photon work  W_p = (each pilot's work per emitted photon + PPM_EMIT_COST) x pass 0's
 *                      emitted photons (the camera sample's work per photon where no surface
 *                      pilot ran: media)
 *                    + PPM_STORE_COST per stored photon (storing it, its kd-tree)
 *                    + PPM_IRR_COST per precomputed irradiance estimate;
 *   f = PPM_PHOTON_SHARE W_r / W_p, within [1/PPM_MIN_DIV, 1] (PPM_PORT_SHARE where the plan's
 *       photon ports or its light guide are on, below).
 * Why a share and not the targets: the passes' mean has the photons of all passes, so a pass
 * that spends most of its time on photons buys few camera samples, and at the defaults the
 * camera samples' noise is most of the error (cornell_spheres at 96x96, 16 spp a pass: 90% of
 * a pass with the full targets went to photons). PPM_PHOTON_SHARE was chosen by measurement
 * (README.md, Progressive photon mapping, "Photons per pass"): on cornell_spheres the error
 * at equal CPU time fell as f fell down to about 0.02, where the camera samples' noise is all
 * that is left. ppm_photons > 0 sets f. */
/* Its costs (PPM_EMIT_COST, PPM_STORE_COST, PPM_IRR_COST) are pm_fit.c's, with the photon work
 * (pm__photon_work_at) that pass 0's fit weighs too. */
#define PPM_PHOTON_SHARE 0.15
#define PPM_MIN_DIV 64.0
/* Where the plan aims photons through ports (ports.h), the share is PPM_PORT_SHARE: the light the
 * camera sees comes through a small opening, and the error is mostly the maps' noise, which a
 * pass's camera samples do not reduce. Measured at --time 10 (pm at the defaults, 2 threads,
 * MSE against the references, seeds 1 and 2; by hand at 75d9cf3), for shares of 0.15 / 0.6 / 1.5
 * / 4: pinhole_room 2.6 / 1.4 / 0.43 / 0.82 e-10 and 0.19 / 0.57 / 0.23 / 1.5 e-10,
 * sun_window_fog 2.9 / 1.1 / 0.65 / 0.53 e-4 and 2.3 / 0.84 / 0.60 / 0.55 e-4, sun_window 4.0 /
 * 3.9 / 3.8 / 4.8 e-6 and 3.9 / 3.7 / 3.4 / 3.7 e-6, lamp_shade (no 4) 5.2 / 3.8 / 4.2 e-3 and 1.7
 * / 30 / 2.8 e-3 (its maps' rare heavy photons: one pass can carry most of the error).
 * The same holds where no port is used but the light guide is on (most light samples are
 * blocked: the light the camera sees comes round a wall, door_ajar's through the gap of a door
 * ajar): door_ajar at --time 10, 16 x 16, seeds 1-4 (by hand at 8c01f39): MSE 4.4, 8.3, 15.0,
 * 9.2 e-8 at 0.15 (fractions 0.027, 0.051, 0.016, 0.016), 3.4, 4.8, 3.8, 4.0 e-8 at 1.5
 * (fractions 0.27, 0.51, 0.15, 0.15); fixed fractions 0.06 / 0.25 / 0.5 / 1 on seeds 1 and 2:
 * 3.6 / 3.1 / 2.0 / 3.5 and 7.0 / 3.0 / 4.4 / 5.7 e-8. No other shipped scene has the light guide
 * on without ports. */
#define PPM_PORT_SHARE 1.5

static void choose_fraction(mapper_state *st, const scene *s) {
    photon_settings *c = &st->cfg;
    /* the settings' targets, and their work: pass 0's maps are fit_scale x the targets */
    for (int i = 0; i < 4; i++) st->target0[i] = st->fit_target[i];
    double wp = pm__photon_work_at(st, st->fit_scale > 0 ? st->fit_scale : 1, st->fit_scale_c > 0 ? st->fit_scale_c : 1);
    double wr = pm__camera_work(st, s);
    st->photon_work0 = wp;
    if (c->ppm_photons > 0) {
        st->pass_fraction = c->ppm_photons;
        snprintf(st->fraction_reason, sizeof st->fraction_reason, "set by photon_mapping.ppm_photons");
    } else if (!(wr > 0) || !(wp > 0) || !isfinite(wr) || !isfinite(wp)) {
        st->pass_fraction = 1;
        snprintf(st->fraction_reason, sizeof st->fraction_reason,
                 "the targets: no counted work to weigh (%s)", wr > 0 ? "no photons" : "no sample pilot");
    } else {
        int ports = st->plan.ports.on, blocked = !ports && st->plan.light_guide.on;
        double share = ports || blocked ? PPM_PORT_SHARE : PPM_PHOTON_SHARE, f = share * wr / wp;
        st->pass_fraction = f > 1 ? 1 : f < 1 / PPM_MIN_DIV ? 1 / PPM_MIN_DIV : f;
        snprintf(st->fraction_reason, sizeof st->fraction_reason,
                 "counted work: the targets' photons %.3g, a pass's %d x %d x %d camera samples %.3g; "
                 "photons at %.3g of that%s (ppm_photons sets it)",
                 wp, s->cam.width, s->cam.height, s->cam.spp, wr, share,
                 ports     ? ", as photon ports are on: the maps' noise is most of the error"
                 : blocked ? ", as the light guide is on (light samples mostly blocked): the maps' noise is most "
                             "of the error"
                           : "");
    }
    st->fraction_made = 1;
}

/* The settings' targets for pass p: pass 0's whole, a later pass's fraction of them. The
 * estimates of a later pass read k f photons (k_global and k_caustic; at least PPM_K_MIN):
 * with f of the photons, the k f-th neighbour is about as far as pass 0's k-th, so a pass's
 * estimates cover the same discs as the plain render's: caustics as sharp, irradiance as
 * local (with all k photons the discs would widen by 1/sqrt(f), blurring caustics and
 * reading low near edges, and the Knaus-Zwicker caps take many thousands of passes to undo
 * that), while the mean of the passes keeps their noise down. */
static const int PPM_K_MIN[2] = {32, 8};
/* k_global (i 0) or k_caustic (1) for maps of f times the settings' targets. */
static int k_of(const mapper_state *st, int i, double f) {
    long kf = llround(st->k0[i] * f), lo = st->k0[i] < PPM_K_MIN[i] ? st->k0[i] : PPM_K_MIN[i];
    return kf >= st->k0[i] ? st->k0[i] : kf < lo ? (int)lo : (int)kf;
}

static void pass_targets(mapper_state *st, int pass) {
    int *k[2] = {&st->cfg.k_global, &st->cfg.k_caustic};
    for (int i = 0; i < 2; i++) {
        if (!st->k0[i]) st->k0[i] = *k[i];
        *k[i] = k_of(st, i, pass ? st->pass_fraction : 1);
    }
    long *dst[4] = {&st->cfg.global_photons, &st->cfg.caustic_photons, &st->cfg.volume_photons,
                    &st->cfg.volume_caustic_photons};
    for (int i = 0; i < 4; i++) {
        double t = (double)st->target0[i] * (pass ? st->pass_fraction : 1);
        *dst[i] = st->target0[i] > 0 && t < 1 ? 1 : (long)llround(t);
    }
}

/* One line per pass on stdout: the maps, what building them cost, and the radii. */
static void print_pass(const mapper_state *st, int pass) {
    printf("Pass %d: photons %zu global, %zu caustic", pass, st->nglobal_all, st->ncaustic_all);
    if (st->vol.on) {
        double r2v = 0; /* the largest r^2 of the media's multiple-scattering maps */
        for (int md = 0; st->vol.ms && md < st->vol.nmedia; md++)
            if (st->vol.ms[md].n && (double)st->vol.ms[md].r2 > r2v) r2v = (double)st->vol.ms[md].r2;
        printf(", %zu volume (r^2 %.9g), %zu volume-caustic", st->vol.n_all, r2v, st->vol.n_caus);
    }
    printf("; trace %.3f s, kd-trees %.3f s, irradiance %.3f s; r^2 global %.9g, caustic %.9g, "
           "lookup %.9g (pass 0's x %.9g; the lookup's x that to the power %g)",
           st->t_trace, st->t_trees, st->t_irr, (double)st->r2_global, (double)st->r2_caustic,
           (double)st->r2_lookup, st->r2_scale, st->cfg.ppm_lookup_shrink);
    if (pass > 0)
        printf("; %.4g of the photon targets, estimates of %d global and %d caustic photons (%s)",
               st->pass_fraction, st->cfg.k_global, st->cfg.k_caustic, st->fraction_reason);
    printf("\n");
    fflush(stdout);
}

int pm__begin_pass(integrator *self, const scene *s, int pass, uint64_t seed, char *err,
                             size_t errcap) {
    mapper_state *st = self->data;
    /* Pass 0 is what preprocess made, unless ppm_radius asks for other first radii: then its
     * readers (precomputed irradiance, caustic side map) are made again with them, from the
     * same maps. */
    int again = pass == 0 && !st->progressive && st->cfg.ppm_radius > 0;
    if (!st->progressive && st->cfg.filter == CAUSTIC_FILTER_HULL && st->ncaustic_all)
        fprintf(stderr, "render: note: filter hull divides by the photons' hull, not by the "
                "shrinking disc: the caustics of progressive passes converge with the cone or none "
                "(README.md, Progressive photon mapping)\n");
    /* The first call (pass 0, or the first pass of a resumed render: preprocess made pass 0
     * and its counts are still here): pass 0's radii become the progressive start. */
    if (!st->progressive && st->cfg.ppm_radius > 0 && st->pass == 0) pm__start_radii(st, &st->rad0);
    st->progressive = 1;
    if (again && st->pass == 0 && !pm__lookup) {
        side_cache_free(&st->sides);
        side_map_free(&st->caus_side);
        side_map_free(&st->glob_side);
        double t0 = stats_now();
        int rc = pm__build_estimates(st, s, &st->rad0, err, errcap);
        st->t_irr = stats_now() - t0;
        if (rc == 0) print_pass(st, pass);
        return rc;
    }
    if (pass == st->pass && !again) {
        print_pass(st, pass);
        return 0;
    }
    if (pm__lookup) {
        snprintf(err, errcap, "progressive passes (--time, --passes) are not available with --pm "
                 "distributed=partitioned: every pass would partition fresh maps (use the "
                 "replicated mode)");
        return PM_EINVAL;
    }
    if (st->cfg.load_dir[0]) {
        snprintf(err, errcap, "load_photons (--load-photons %s) fixes the photon maps, but each "
                 "progressive pass traces its own: render one pass (no --time or --passes) or "
                 "leave the maps out", st->cfg.load_dir);
        return PM_EINVAL;
    }
    if (!st->fraction_made) choose_fraction(st, s); /* from pass 0's maps, still here */
    pm__drop_maps(st);
    pass_targets(st, pass);
    st->pass = pass;
    st->pass_seed = seed;
    st->r2_scale = ppm_r2_scale(pass, st->cfg.ppm_alpha);
    int progress = st->cfg.progress;
    st->cfg.progress = 0; /* one line per pass instead of the tracer's bars */
    int rc = pm__preprocess(self, s, err, errcap);
    st->cfg.progress = progress;
    if (rc == 0) print_pass(st, pass);
    return rc;
}
