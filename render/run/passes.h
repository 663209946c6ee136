/* passes.h: rendering in passes, for a time budget (render --time) or a fixed number of
 * passes (--passes): the running estimate, its error, and the pass loop.
 *
 * A PASS is a whole render of the image at pass_spp samples per pixel (renderer.h) with its
 * own seed, pass_seed(seed, p): pass 0 uses the render's seed itself, so a render of one pass
 * is, bit for bit, the plain render at pass_spp with that seed. Before pass p the integrator's
 * begin_pass hook (integrator.h) is called with that seed; the photon mapper traces fresh
 * maps there and shrinks its radii (progressive photon mapping, photonmapper.c).
 *
 * THE RUNNING ESTIMATE is the equal-weight mean of the pass images: with P passes done,
 * pixel = (sum over p of image_p) / P, each image_p the float image the pass's plain render
 * gives, summed in double in pass order. Equal weights because every pass has the same
 * samples per pixel (so the same variance for a fixed integrator), and for progressive photon
 * mapping Knaus and Zwicker's analysis (2011) is of exactly this mean: the radius schedule
 * makes the mean's bias and variance vanish together. The sums are kept with the sums of
 * squares, for the error estimate: the sample variance of the pass images per pixel and
 * channel, over P (the variance of their mean), averaged over the image; its square root is
 * the RMSE the progress line shows (an estimate that counts the pass-to-pass spread only:
 * what the passes share, such as a bias that does not shrink, is not in it).
 *
 * ADAPTIVE SAMPLES (pass_run.adapt > 0, render --adaptive, default 0.25): once ADAPT_AFTER passes
 * are done, each pixel's sample multiplier is decided from them (pass_state_adapt) and kept
 * for the rest of the render (checkpoints keep it too): pixel p then takes spp x mult[p]
 * samples a pass (renderer.h, render_job.mult). The pass images' variance at p, s_p^2 (summed
 * over the channels), is what more samples of p reduce where p's error comes from its own
 * camera samples: a bright feature in a sliver of the pixel (lamp_shade's lit inside seen
 * through the shade's hole, pinhole_room's upper room through the hole). The allocation that
 * minimises the sum of s_p^2 / mult_p for a given number of samples has mult_p proportional to
 * s_p (Neyman's), so mult_p = min(ADAPT_MAX, max(1, floor(lambda s_p))), lambda the largest
 * that keeps a pass within (1 + adapt) times the samples of a plain pass. Unbiased: a pass
 * image is its pixels' sample means whatever their number, the multipliers are fixed before
 * the passes that use them, and the estimate stays the passes' equal-weight mean. Where
 * photon maps' noise, shared by a pass's pixels, is what varies, more camera samples do not
 * remove it; adapt bounds that waste. Measured by hand with a prototype of the rule (pm,
 * --time 10, seeds 1-4, MSE against the long references, at adapt 0 / 0.25): lamp_shade
 * 3.71 / 1.65, 1.14 / 0.66, 1.25 / 0.92, 1.29 / 0.84 e-3 (its two pixels that see the shade's
 * inside were 85% of seed 1's error); pinhole_room (8x8) 22.2 / 1.76, 2.74 / 2.85, 17.3 / 1.99,
 * 2.79 / 4.57 e-11; path tracing on lamp_shade 2.86 / 2.83, 4.10 / 3.87, 2.83 / 2.83, 2.56 /
 * 2.61 e-3 (its error is spread over the room). Thread count and render-mpi: the multipliers
 * are a function of the pass sums (rank 0's, shared with the other ranks before each pass by
 * pass_run.share), so the image is the same bit for bit.
 *
 * Thread count: each pass image is bit-identical for any thread count (renderer.h) and the
 * sums are made on one thread in pass order, so the estimate is too.
 *
 * THE LOOP (render_passes) starts at ps->done (0, or the passes a checkpoint holds) and runs
 * until max_passes are done, or, with a budget, until the next pass would overrun it: before
 * each pass after the first of this run it stops if elapsed + mean pass time > budget, the
 * elapsed time counted from t_origin and the mean over this run's passes (the first of which
 * counts from t_first, so that preprocessing is part of it). So a run takes at most the
 * budget plus about one pass, and always renders at least one pass. After each pass on_pass
 * is called with the state (checkpoints, snapshots). A signal deferred by output.h stops the
 * pass being rendered (stop_on_signal); it is dropped, and the state keeps the passes
 * completed before it. Test hook: PM_RENDER_TEST_PAUSE=pass:N pauses before pass N's image
 * (after its begin_pass), as output.h's phases do.
 */
#ifndef RENDER_PASSES_H
#define RENDER_PASSES_H

#include <stddef.h>
#include <stdint.h>

#include "image/film.h"
#include "integrators/integrator.h"
#include "run/renderer.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct pass_state {
    int width, height;
    int done;            /* passes completed */
    double *sum, *sum2;  /* 3 per pixel each, row-major: sum of the pass images, of their squares */
    unsigned char *mult; /* NULL, or per pixel 1..ADAPT_MAX: the samples' multiplier (ADAPTIVE SAMPLES) */
} pass_state;

/* ADAPTIVE SAMPLES: the passes the multipliers are decided from, and their largest value. */
enum { ADAPT_AFTER = 4, ADAPT_MAX = 32 };

/* An empty state; 0 or PM_ENOMEM. */
int pass_state_init(pass_state *ps, int width, int height);
void pass_state_free(pass_state *ps);
/* Add one pass image (the film of the pass). */
void pass_state_add(pass_state *ps, const film *f);
/* The running estimate: (float)(sum / done) per pixel (black with no pass). f has the state's
 * size. */
void pass_state_to_film(const pass_state *ps, film *f);
/* The error estimate (THE RUNNING ESTIMATE above): the RMSE of the mean, and in *mean the
 * mean pixel value (over pixels and channels). -1 with fewer than 2 passes. */
double pass_state_rmse(const pass_state *ps, double *mean);

/* ADAPTIVE SAMPLES: decide ps->mult from the passes done (at least 2), with at most
 * (1 + share) x the samples of a plain pass (share > 0). In *marked the pixels above 1, in *extra
 * the samples added (a fraction of a plain pass's). 0, or PM_ENOMEM. */
int pass_state_adapt(pass_state *ps, double share, size_t *marked, double *extra);

/* A checkpoint's n multipliers (checkpoint.h, version 3): all 0 (undecided), or all 1 to
 * ADAPT_MAX. 1 if so, else 0. */
int pass_mult_valid(const unsigned char *m, size_t n);

/* The seed of pass p: seed itself for p = 0, else a 64-bit mix of both. */
uint64_t pass_seed(uint64_t seed, int pass);

/* The image loop a pass uses: render_image_ctl, or render-mpi's. */
typedef int (*pass_image_fn)(const scene *s, const integrator *it, const render_job *job,
                             const render_control *ctl, film *out);
/* Called after every completed pass (why: RENDER_PAUSE_PERIODIC) and once after a signal
 * stopped the loop (RENDER_PAUSE_SIGNAL); a negative return ends the loop with that code. */
typedef int (*pass_fn)(void *user, const pass_state *ps, int why);

typedef struct pass_run {
    int max_passes;     /* stop when this many are done (0: no limit; then budget > 0) */
    double budget;      /* seconds from t_origin; 0: none */
    double t_origin;    /* stats_now() when the budget's clock started (the program's start) */
    double t_first;     /* stats_now() when the first pass's work began (before preprocess) */
    int only;           /* >= 0: render pass `only` alone into the empty state (--only-pass) */
    int stop_on_signal;
    pass_image_fn image;
    int (*agree)(int go); /* NULL; render-mpi: every rank gets rank 0's go (mpi/dist.h) */
    double adapt;         /* ADAPTIVE SAMPLES: the extra samples' share; 0: none */
    /* NULL; render-mpi: every rank gets rank 0's n bytes (the multipliers, 0s while undecided) */
    int (*share)(unsigned char *buf, size_t n);
    pass_fn on_pass;
    void *user;
    int quiet;          /* no progress lines */
} pass_run;

/* What the loop did, for the summary. */
typedef struct pass_report {
    int passes;               /* passes rendered by this run */
    double elapsed;           /* stats_now() - t_origin at the end */
    double mean, longest;     /* this run's pass times (seconds) */
    int stopped_by_budget;
} pass_report;

/* Render passes into ps (see THE LOOP) and put the running estimate into out (film_init'ed
 * here; film_free it). 0, RENDER_INTERRUPTED (a signal; out holds the passes done), or a
 * negative code with a message in err (begin_pass's, or the image loop's). */
int render_passes(const scene *s, integrator *it, const render_job *job, const pass_run *run,
                  pass_state *ps, film *out, pass_report *rep, char *err, size_t errcap);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PASSES_H */
