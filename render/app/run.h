/* run.h: the steps of a render (run.c), in the order render_main (render_main.c) calls them:
 * prepare the outputs and threads, load the scene and apply the options to it, set up
 * checkpoints, create and preprocess the integrator, render (fixed work or in passes), write
 * the images, print the summary and statistics. Each step returns APP_GO (app.h) to go on,
 * or the exit status after printing why.
 */
#ifndef RENDER_APP_RUN_H
#define RENDER_APP_RUN_H

#include "app/app.h"
#include "app/options.h"
#include "image/film.h"
#include "integrators/integrator.h"
#include "run/checkpoint.h"
#include "run/passes.h"
#include "run/renderer.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The state of one render, filled step by step. */
typedef struct app_run {
    const render_options *o;
    const render_hooks *hooks;
    int nthreads;
    scene s;
    int have_scene, have_it;
    integrator it;
    int in_passes, cli_passes, uses_photons;
    double budget; /* seconds (0: none) */
    int pspp;      /* samples per pass, as asked (before rounding) */
    int pspp_default; /* pspp is run.c's default (THE DEFAULT SAMPLES PER PASS), not asked for */
    double t_start, t_load, t_prep0, t_render;
    ckpt_session cs;
    render_state rstate;
    pass_state pstate;
    pass_report prep;
    film f;
} app_run;

/* Before the scene: the size limit, the signal handlers, the outputs checked (writable, not
 * the same file twice), and the threads. */
int run_prepare(app_run *r);
/* Load the scene and apply the options: size, passes, photon settings, seed, mode, tone. */
int run_load_scene(app_run *r);
/* What checkpoints and passes need, and the refusals of what cannot go together. */
int run_setup_checkpoint(app_run *r);
/* Create the integrator, print what will be rendered, and preprocess (trace photons). */
int run_create_integrator(app_run *r);
/* Render into r->f, in passes or as one image of fixed work; destroys the integrator. */
int run_render(app_run *r);
/* Write the images and print the summary and statistics: the exit status (0 or 1). */
int run_write_outputs(app_run *r);
/* Free what a step that failed left (the scene, the integrator). */
void run_free(app_run *r);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_APP_RUN_H */
