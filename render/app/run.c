/* run.c: the steps of a render; see run.h.
 *
 * One pass of --spp samples (the scene's image.spp) is fixed work; --time, --passes or the
 * scene's render.time render in passes instead (run/passes.h). The image loops are the
 * hooks' (app.h): render's own, or render-mpi's. Progress goes to stderr; the summary and
 * statistics to stdout.
 */
#include "app/run.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "app/tools.h"
#include "base/errors.h"
#include "base/json.h"
#include "base/output.h"
#include "base/stats.h"
#include "image/exr.h"
#include "load/scene_load.h"
#include "photonmap/common.h"
#include "load/photon_settings.h"
#include "run/focus.h"
#include "scene/delta_lit.h"

#ifdef _OPENMP
#include <omp.h>
#endif

static const char *basename_of(const char *p) {
    const char *s = strrchr(p, '/');
    return s ? s + 1 : p;
}

int run_prepare(app_run *r) {
    const render_options *o = r->o;
    json_set_max_file_bytes((size_t)o->max_scene_mb << 20);
    out_signals_install();
    /* An output that cannot be written is refused now, not after the render. */
    const char *outs[3] = {o->pfm, o->png, o->ckpt_path}, *out_opt[3] = {"--hdr", "-o", "--checkpoint"};
    for (int k = 0; k < 3; k++) {
        char oerr[600];
        if (outs[k] && out_check(outs[k], oerr, sizeof oerr) < 0) {
            fprintf(stderr, "render: %s %s\n", out_opt[k], oerr);
            return 2;
        }
        for (int j = 0; j < k; j++)
            if (outs[j] && outs[k] && strcmp(outs[j], outs[k]) == 0) {
                fprintf(stderr, "render: %s and %s name the same file %s\n", out_opt[j], out_opt[k], outs[k]);
                return 2;
            }
    }
    /* --threads governs every parallel loop of the run, set before the first: the plan's
     * pilots run inside integrator_create, photon tracing in preprocess, then the pixels. */
    int nthreads = (int)o->threads;
#ifdef _OPENMP
    if (nthreads <= 0) nthreads = omp_get_max_threads();
    omp_set_num_threads(nthreads);
#else
    nthreads = 1;
#endif
    r->nthreads = nthreads;
    return APP_GO;
}

/* Passes (run/passes.h): --time, --passes, --only-pass, or the scene's render.time unless
 * --spp asks for one pass of fixed work. */
static int choose_passes(app_run *r) {
    const render_options *o = r->o;
    scene *s = &r->s;
    r->cli_passes = o->time_budget > 0 || o->passes > 0 || o->only_pass >= 0;
    r->in_passes = r->cli_passes || (s->settings.time > 0 && !o->spp);
    if (r->cli_passes && o->spp) {
        fprintf(stderr, "render: --spp is one pass of fixed work; with --time, --passes or "
                "--only-pass give the samples of each pass with --pass-spp\n");
        return 2;
    }
    if (!r->in_passes && o->pass_spp) {
        fprintf(stderr, "render: --pass-spp needs passes: --time, --passes or the scene's render.time\n");
        return 2;
    }
    if (o->only_pass >= 0 && (o->ckpt_path || o->resume || o->snap_every > 0)) {
        fprintf(stderr, "render: --only-pass renders one pass alone: no --checkpoint, --resume or "
                "--snapshot-every with it\n");
        return 2;
    }
    r->budget = o->time_budget > 0 ? o->time_budget : r->cli_passes ? 0 : s->settings.time;
    r->pspp = o->pass_spp ? (int)o->pass_spp : s->settings.pass_spp; /* 0: pass_spp_default */
    return APP_GO;
}

/* THE DEFAULT SAMPLES PER PASS: 4, or at a small image the least square whose pass has
 * PASS_MIN_SAMPLES camera samples (8x8: 1024, 16x16: 256, 32x32: 64, 64x64: 16, 96x96: 9;
 * 128x128 and up: 4). Why: a pass has costs of its own whatever its size (in pm and preview a
 * later pass traces at least 1/64 of the photon targets, builds their kd-trees and precomputes
 * their irradiance; pm_passes.c, PHOTONS PER PASS), and a tiny image's pass of 4 spp spent most
 * of its time there: pinhole_room at 8x8 with --time 10 spent 8 s of 10 on photon maps.
 * Measured by hand at ed0f409 (pm, --time, 2 threads, RMSE against the hard and
 * s32 references, samples per pass 4 / 16 / 64 / 256 / 1024 ...): pinhole_room 8x8, 10 s, seeds
 * 1-4, mean MSE 11.7 / 7.2 / 3.3 / 2.3 / 0.87 e-10 (2304: 0.90, its walls lower: fewer passes
 * shrink the radii less); door_ajar 16x16, 5 s, 4 / 64 / 256 / 576 spp: RMSE 5.5 / 3.9 / 3.1 /
 * 3.5 e-4; cornell_box 32x32, 5 s, 4 / 16 / 64 / 144: 2.1 / 1.56 / 1.29 / 1.29 e-3;
 * cornell_spheres 32x32: 5.5 / 4.2 / 4.0 / 4.2 e-3; at 96x96, 10 s, 4 / 9 / 16 spp:
 * cornell_box 2.31 / 2.13 / 2.10 e-3, cornell_spheres 4.5 / 4.3 / 3.6 e-3. Past about 65,536
 * samples a pass the error stops falling; a larger pass only makes the budget coarser (a run
 * ends within the budget plus about one pass). */
#define PASS_MIN_SAMPLES 65536.0
#define PASS_DEFAULT_SPP 4

/* The default's camera samples a pass before rounding to a square (camera_set_spp rounds). */
static int pass_spp_default(const camera *cam) {
    double px = (double)cam->width * cam->height, want = ceil(PASS_MIN_SAMPLES / (px > 0 ? px : 1));
    return want <= PASS_DEFAULT_SPP ? PASS_DEFAULT_SPP : (int)want;
}

/* The samples of each pass, at the image's final size: as asked, else pass_spp_default. A
 * resumed render not asked for them takes its checkpoint's: the default may have been another
 * when it was made (it was 4 at every size before 3982015), and the checkpoint refuses other
 * settings. A checkpoint that cannot be read is left to checkpoint_setup to report. */
static int set_pass_spp(app_run *r) {
    if (!r->in_passes) return APP_GO;
    r->pspp_default = !r->pspp;
    if (r->pspp) {
        camera_set_spp(&r->s.cam, r->pspp);
        return APP_GO;
    }
    camera_set_spp(&r->s.cam, pass_spp_default(&r->s.cam));
    if (r->o->resume) {
        static ckpt_info ci; /* 13 KiB: not on the stack */
        char err[512];
        if (ckpt_read_passes(r->o->resume, &ci, NULL, err, sizeof err) == 0 && ci.version >= 2 &&
            ci.spp != (uint32_t)r->s.cam.spp) {
            fprintf(stderr, "render: note: %s was rendered in passes of %u spp (then the default at "
                    "%dx%d); resuming with them\n", r->o->resume, ci.spp, r->s.cam.width, r->s.cam.height);
            camera_set_spp(&r->s.cam, (int)ci.spp);
            r->pspp_default = 0; /* the run's line gives no reason of the default's */
        }
    }
    r->pspp = r->s.cam.spp;
    return APP_GO;
}

/* --width / --height: the side not given follows the scene's aspect, and must stay in
 * range too. */
static int resize(app_run *r) {
    long width = r->o->width, height = r->o->height;
    scene *s = &r->s;
    if (!width && !height) return APP_GO;
    double w = width ? (double)width : floor((double)height * s->cam.width / s->cam.height + 0.5);
    double h = height ? (double)height : floor((double)width * s->cam.height / s->cam.width + 0.5);
    if (w > 1 << 14 || h > 1 << 14) {
        fprintf(stderr, "render: %s %ld gives a %s of %.0f at the scene's aspect %dx%d; the "
                "limit is 16384 (give both --width and --height)\n", width ? "--width" : "--height",
                width ? width : height, width ? "height" : "width", width ? h : w, s->cam.width,
                s->cam.height);
        return 2;
    }
    camera_resize(&s->cam, w > 0 ? (int)w : 1, h > 0 ? (int)h : 1);
    return APP_GO;
}

/* The photon-mapping settings are checked in every mode, so a typo in them is found by a
 * path-traced preview too: the scene's object first (its errors name the file), then each
 * option alone (its errors name the option). */
static int apply_photon_settings(app_run *r) {
    const render_options *o = r->o;
    scene *s = &r->s;
    json_err e;
    photon_settings ps;
    if (photon_settings_parse(&ps, s->photon_mapping, &e) < 0) {
        fprintf(stderr, "render: %s: %s\n", o->scene_path, e.msg);
        return 2;
    }
    for (int k = 0; k < o->npm; k++) {
        char perr[256];
        /* A resumed render loads the maps its checkpoint names; they were saved already. */
        if (o->resume && strcmp(o->pm_flag[k], "--save-photons") == 0) continue;
        if (photon_settings_check_cli(o->pm_flag[k], o->pm_value[k], perr, sizeof perr) < 0 ||
            photon_settings_cli_set(&s->photon_mapping, o->pm_flag[k], o->pm_value[k], perr, sizeof perr) < 0) {
            fprintf(stderr, "render: %s\n", perr);
            return 2;
        }
    }
    char err_unused[64];
    if (o->quiet) photon_settings_cli_set(&s->photon_mapping, "--pm", "progress=false", err_unused, sizeof err_unused);
    return APP_GO;
}

/* Seed, mode, tone and exposure, the notes on rounded spp, and the warnings on the scene. */
static int apply_render_settings(app_run *r) {
    const render_options *o = r->o;
    scene *s = &r->s;
    if (o->seed >= 0) s->settings.seed = (uint64_t)o->seed;
    /* The file's render.mode is checked even when --mode replaces it: a misspelt mode in the
     * file is an error of the file, found now rather than when the option is dropped. */
    if (o->mode && strcmp(o->mode, s->settings.mode) != 0 && cli_mode_known(s->settings.mode) == 0) {
        char merr[256];
        integrator dummy;
        integrator_create(s->settings.mode, s, &dummy, merr, sizeof merr); /* only says why */
        fprintf(stderr, "render: %s: $.render.mode: %s\n", o->scene_path, merr);
        return 2;
    }
    if (o->mode) snprintf(s->settings.mode, sizeof s->settings.mode, "%s", o->mode);
    if (o->tone) s->settings.tone = strcmp(o->tone, "srgb") == 0 ? TONE_SRGB : TONE_FILMIC;
    if (o->exposure > 0) s->settings.exposure = o->exposure;
    if (o->spp && s->cam.spp != o->spp)
        fprintf(stderr, "render: note: %ld spp rounded up to %d (%dx%d strata)\n", o->spp, s->cam.spp,
                s->cam.strata, s->cam.strata);
    if (r->in_passes && s->cam.spp != r->pspp)
        fprintf(stderr, "render: note: %d samples per pass rounded up to %d (%dx%d strata)\n", r->pspp,
                s->cam.spp, s->cam.strata, s->cam.strata);
    if (s->nlights == 0) {
        int any_emit = 0;
        for (int i = 0; i < s->nmats; i++) any_emit |= material_is_emissive(&s->mats[i]);
        if (!any_emit)
            fprintf(stderr, "render: %s: warning: the scene has no light; the image will be black\n",
                    o->scene_path);
    }
    /* The path tracer cannot show caustics of point and directional lights: say where. */
    if (strcmp(s->settings.mode, "path") == 0) delta_lit_warn(s, o->scene_path, stderr);
    return APP_GO;
}

int run_load_scene(app_run *r) {
    const render_options *o = r->o;
    r->t_start = stats_now();
    json_err e;
    if (scene_load(&r->s, o->scene_path, &e) < 0) {
        fprintf(stderr, "render: %s: %s\n", o->scene_path, e.msg);
        return 2;
    }
    r->have_scene = 1;
    r->t_load = stats_now() - r->t_start;
    stats_time_add("Time/Scene loading and BVH build", r->t_load);
    if (o->spp) camera_set_spp(&r->s.cam, (int)o->spp);
    int rc;
    if ((rc = choose_passes(r)) != APP_GO || (rc = resize(r)) != APP_GO || (rc = set_pass_spp(r)) != APP_GO ||
        (rc = apply_photon_settings(r)) != APP_GO)
        return rc;
    return apply_render_settings(r);
}

int run_setup_checkpoint(app_run *r) {
    const render_options *o = r->o;
    scene *s = &r->s;
    json_err e;
    r->uses_photons = strcmp(s->settings.mode, "pm") == 0 || strcmp(s->settings.mode, "preview") == 0;
    if (r->uses_photons && scene_check_photon_range(s, &e) < 0) { /* float photons: scene.h */
        fprintf(stderr, "render: %s: %s\n", o->scene_path, e.msg);
        return 2;
    }
    if (r->in_passes) {
        if (r->hooks->no_passes) { /* render-mpi's partitioned mode */
            fprintf(stderr, "%s\n", r->hooks->no_passes);
            return 2;
        }
        const cJSON *ld = s->photon_mapping ? cJSON_GetObjectItemCaseSensitive(s->photon_mapping, "load_photons") : NULL;
        if (r->uses_photons && cJSON_IsString(ld) && ld->valuestring[0]) {
            fprintf(stderr, "render: --load-photons (photon_mapping.load_photons) fixes the photon "
                    "maps, but each pass of --time, --passes or render.time traces its own: use one "
                    "or the other\n");
            return 2;
        }
        ckpt_set_passes(&r->pstate, o->adaptive);
    }
    int rc = checkpoint_setup(s, o->scene_path, o->argc, o->argv, o->ckpt_path, o->resume,
                              r->uses_photons, &r->cs, &r->rstate);
    return rc != 0 ? rc : APP_GO;
}

int run_create_integrator(app_run *r) {
    const render_options *o = r->o;
    scene *s = &r->s;
    char err[512];
    int rc = integrator_create(s->settings.mode, s, &r->it, err, sizeof err);
    r->it.in_passes = r->in_passes;
    if (rc < 0 && rc != PM_EINVAL) { /* the mode is known; making it failed (the plan's pilots
                                      * ran out of memory): a failure, not bad input */
        fprintf(stderr, "render: %s: %s\n", o->scene_path, err);
        return 1;
    }
    if (rc < 0) { /* name where the mode came from: the option, or the file's render.mode */
        if (o->mode)
            fprintf(stderr, "render: --mode %s: %s\n", o->mode, err);
        else
            fprintf(stderr, "render: %s: $.render.mode: %s\n", o->scene_path, err);
        return 2;
    }
    r->have_it = 1;
    printf("Scene %s: %d triangles, %d spheres, %d materials, %d lights; BVH %d nodes, depth %d "
           "(%.3f s)\n",
           basename_of(o->scene_path), s->ntris, s->nspheres, s->nmats, s->nlights, s->accel.nnodes,
           s->accel.depth, r->t_load);
    printf("Rendering %dx%d, %d spp (%dx%d strata), mode %s, %d thread%s, seed %llu\n", s->cam.width,
           s->cam.height, s->cam.spp, s->cam.strata, s->cam.strata, r->it.name, r->nthreads,
           r->nthreads == 1 ? "" : "s", (unsigned long long)s->settings.seed);
    if (r->in_passes) {
        printf("In passes of %d spp", s->cam.spp);
        if (r->pspp_default && s->cam.spp != PASS_DEFAULT_SPP)
            printf(" (not %d: at %dx%d a pass has at least %.0f camera samples; --pass-spp sets it)",
                   PASS_DEFAULT_SPP, s->cam.width, s->cam.height, PASS_MIN_SAMPLES);
        if (o->only_pass >= 0) printf(": pass %ld alone", o->only_pass);
        if (o->passes > 0 && o->only_pass < 0) printf(": %ld passes", o->passes);
        if (r->budget > 0 && o->only_pass < 0)
            printf("%s time budget %.4g s", o->passes > 0 ? ", or a" : ": a", r->budget);
        printf("\n");
    }
    fflush(stdout);
    out_test_pause("photons");
    r->t_prep0 = stats_now();
    if (r->it.preprocess) {
        double t0 = stats_now();
        rc = r->it.preprocess(&r->it, s, err, sizeof err);
        stats_time_add("Time/Preprocessing", stats_now() - t0);
        if (rc < 0) {
            fprintf(stderr, "render: %s: %s\n", o->scene_path, err);
            return rc == PM_EINVAL ? 2 : 1;
        }
    }
    return APP_GO;
}

/* The checkpoint session's settings (checkpoint.h), when the render saves, snapshots or
 * resumes: the image loop's control. */
static int begin_session(app_run *r, render_control *ctl) {
    const render_options *o = r->o;
    const scene *s = &r->s;
    if (!r->in_passes && !r->rstate.sum && render_state_init(&r->rstate, s->cam.width, s->cam.height, s->cam.spp) < 0) {
        fprintf(stderr, "render: out of memory for the render state\n");
        return 1;
    }
    ckpt_session *cs = &r->cs;
    cs->ckpt_path = o->ckpt_path;
    cs->ckpt_every = o->ckpt_every;
    cs->snap_path = o->snap_every > 0 ? o->png : NULL;
    cs->snap_every = o->snap_every;
    cs->tone = s->settings.tone;
    cs->exposure = s->settings.exposure;
    cs->clip_percent = s->settings.clip_percent;
    cs->quiet = o->quiet;
    cs->pass_spp = s->cam.spp;
    int rc = checkpoint_begin(cs, r->uses_photons, &r->rstate);
    if (rc != 0) return rc;
    *ctl = (render_control){&r->rstate, ckpt_session_period(cs), ckpt_session_pause, cs, o->ckpt_path != NULL};
    return APP_GO;
}

/* The pass loop (run/passes.h) into r->f: 0, RENDER_INTERRUPTED or a negative code. */
static int render_in_passes(app_run *r, const render_job *job) {
    const render_options *o = r->o;
    pass_run pr;
    memset(&pr, 0, sizeof pr);
    pr.max_passes = (int)o->passes;
    pr.budget = r->budget;
    pr.t_origin = r->t_start;
    pr.t_first = r->t_prep0; /* the first pass of this run counts its preprocessing */
    pr.only = (int)o->only_pass;
    pr.stop_on_signal = o->ckpt_path != NULL;
    pr.image = r->hooks->pass_image;
    pr.agree = r->hooks->pass_agree;
    pr.adapt = o->adaptive;
    pr.share = r->hooks->pass_share;
    pr.on_pass = o->ckpt_path || o->snap_every > 0 ? ckpt_session_pass : NULL;
    pr.user = &r->cs;
    pr.quiet = o->quiet;
    char err[512];
    err[0] = 0;
    int rc = render_passes(&r->s, &r->it, job, &pr, &r->pstate, &r->f, &r->prep, err, sizeof err);
    if (r->hooks->passes_end) r->hooks->passes_end(rc); /* render-mpi: the worker ranks end here */
    if (rc < 0 && err[0]) snprintf(r->cs.err, sizeof r->cs.err, "%s", err);
    /* The last state, so that the render can be continued with more passes. */
    if (rc == 0 && o->ckpt_path && !out_pending_signal() &&
        ckpt_session_pass(&r->cs, &r->pstate, RENDER_PAUSE_SIGNAL) < 0)
        rc = PM_EIO;
    return rc;
}

/* The footprints of the ports the integrator names (run/focus.h), and the line that says
 * where they are. */
static int build_focus(app_run *r, film_focus *f) {
    const port *ports = NULL;
    int n = r->it.camera_ports ? r->it.camera_ports(&r->it, &r->s, &ports) : 0;
    if (n <= 0) return APP_GO;
    if (focus_build(f, &r->s.cam, ports, n) < 0) {
        fprintf(stderr, "render: out of memory for the camera's focus table\n");
        return 1;
    }
    if (!f->npolys) return APP_GO;
    double lo = 1, hi = 0;
    for (int i = 0; i < f->npolys; i++) {
        lo = fmin(lo, f->polys[i].area);
        hi = fmax(hi, f->polys[i].area);
    }
    printf("Camera focus: %d pixel%s see%s a photon port in %.2g%% to %.2g%% of %s area: %g of "
           "%s samples aimed at it, weighted (photon_mapping.camera_focus=false: none)\n",
           f->npolys, f->npolys == 1 ? "" : "s", f->npolys == 1 ? "s" : "", 100 * lo, 100 * hi,
           f->npolys == 1 ? "its" : "their", 1 - FOCUS_PLAIN, f->npolys == 1 ? "its" : "their");
    return APP_GO;
}

int run_render(app_run *r) {
    const render_options *o = r->o;
    int rc;
    render_job job = {r->nthreads, o->quiet, r->s.settings.seed, NULL, NULL};
    render_control ctl = {NULL, 0, NULL, NULL, 0};
    if (r->in_passes && !r->pstate.sum && pass_state_init(&r->pstate, r->s.cam.width, r->s.cam.height) < 0) {
        fprintf(stderr, "render: out of memory for the render state\n");
        return 1;
    }
    if (o->ckpt_path || o->snap_every > 0 || o->resume)
        if ((rc = begin_session(r, &ctl)) != APP_GO) return rc;
    /* With a checkpoint, SIGINT/SIGTERM stop the render at the next sample boundary, write
     * the checkpoint, and then end the program by that signal. */
    if (o->ckpt_path) out_defer_begin();
    film_focus focus = {0};
    if ((rc = build_focus(r, &focus)) != APP_GO) return rc;
    if (focus.npolys) job.focus = &focus;
    double t_render0 = stats_now();
    memset(&r->prep, 0, sizeof r->prep);
    if (r->in_passes)
        rc = render_in_passes(r, &job);
    else
        rc = r->hooks->image(&r->s, &r->it, &job, &ctl, &r->f);
    r->t_render = stats_now() - t_render0;
    integrator_destroy(&r->it);
    r->have_it = 0;
    focus_free(&focus);
    if (o->ckpt_path) {
        if (rc == 0 && out_pending_signal())
            rc = r->in_passes ? ckpt_session_pass(&r->cs, &r->pstate, RENDER_PAUSE_SIGNAL)
                              : ckpt_session_pause(&r->cs, &r->rstate, RENDER_PAUSE_SIGNAL);
        if (rc == 0 && out_pending_signal()) rc = RENDER_INTERRUPTED;
        if (rc == RENDER_INTERRUPTED)
            fprintf(stderr, "render: interrupted; the render state is in %s (continue with: %s "
                    "%s --resume %s)\n", o->ckpt_path, ckpt_resume_command(), o->scene_path, o->ckpt_path);
        out_defer_end();
        out_die_if_pending();
    }
    if (rc < 0) {
        fprintf(stderr, "render: rendering failed: %s%s%s\n", render_strerror(rc), r->cs.err[0] ? ": " : "",
                r->cs.err);
        return 1;
    }
    render_state_free(&r->rstate);
    return APP_GO;
}

/* The summary line, the passes' line, and what was written. */
static void print_summary(const app_run *r, int status, double used, int passes_done, double pass_err,
                          double pass_mean) {
    const render_options *o = r->o;
    const scene *s = &r->s;
    double wall = stats_now() - r->t_start, t_render = r->t_render;
    uint64_t rays = stats_total(STAT_CAMERA_RAYS) + stats_total(STAT_INDIRECT_RAYS) +
                    stats_total(STAT_SHADOW_RAYS);
    printf("Summary: wall time %.2f s (rendering %.2f s), %.3g M rays, %.3g M rays/s\n", wall, t_render,
           (double)rays * 1e-6, t_render > 0 ? (double)rays * 1e-6 / t_render : 0.0);
    if (r->in_passes) {
        const pass_report *prep = &r->prep;
        printf("Passes: %d done (%d by this run) of %d spp; mean pass %.3f s, longest %.3f s; "
               "elapsed %.3f s", passes_done, prep->passes, s->cam.spp, prep->mean, prep->longest,
               prep->elapsed);
        if (r->budget > 0 && o->only_pass < 0)
            printf(" of a budget of %.4g s%s", r->budget, prep->stopped_by_budget ? " (stopped by it)" : "");
        if (pass_err >= 0)
            printf("; error estimate %.4g (%.3f%% of the mean %.4g)", pass_err,
                   pass_mean > 0 ? 100 * pass_err / pass_mean : 0.0, pass_mean);
        printf("\n");
    }
    if (status == 0) {
        if (o->png)
            printf("Wrote %s (%s, exposure %.4g%s)\n", o->png, s->settings.tone == TONE_SRGB ? "sRGB" : "filmic",
                   used, s->settings.exposure > 0 ? "" : ", auto");
        if (o->pfm) printf("Wrote %s (linear)\n", o->pfm);
    }
    stats_print(stdout);
}

int run_write_outputs(app_run *r) {
    const render_options *o = r->o;
    const scene *s = &r->s;
    double pass_err = -1, pass_mean = 0;
    int passes_done = r->pstate.done;
    if (r->in_passes) pass_err = pass_state_rmse(&r->pstate, &pass_mean);
    pass_state_free(&r->pstate);
    int status = 0;
    size_t nonfinite = film_count_nonfinite(&r->f);
    if (nonfinite)
        fprintf(stderr, "render: warning: %zu pixel%s of the image %s not finite (inf or NaN; "
                "\"Film/Non-finite pixels\" below)\n", nonfinite, nonfinite == 1 ? "" : "s",
                nonfinite == 1 ? "is" : "are");
    double used = 0;
    char werr[600];
    if (film_write_outputs_ex(&r->f, o->pfm, o->hdr_half ? EXR_HALF : EXR_FLOAT, o->png, s->settings.tone,
                              s->settings.exposure, s->settings.clip_percent, &used, werr, sizeof werr) < 0) {
        fprintf(stderr, "render: %s (no output written)\n", werr);
        status = 1;
    }
    print_summary(r, status, used, passes_done, pass_err, pass_mean);
    film_free(&r->f);
    return status;
}

void run_free(app_run *r) {
    if (r->have_it) integrator_destroy(&r->it);
    if (r->have_scene) scene_free(&r->s);
    r->have_it = r->have_scene = 0;
}
