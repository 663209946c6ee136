/* renderer.h: the image loop shared by every integrator: tiles, threads, strata, film, and
 * the render state that checkpoints save and resumed renders continue.
 *
 * render_image() splits the image into 16x16 tiles and renders them with OpenMP (threads take
 * the next unfinished tile, so slow tiles around glass do not hold up a thread). Each pixel
 * takes cam.spp = strata^2 samples, one per stratum, jittered inside it; sample k of pixel i
 * uses the random stream (seed, i, k) and nothing else. A pixel's samples are added in sample
 * order (k = 0, 1, ...) into a double sum by one thread at a time, and the pixel value is
 * sum * (1 / spp) (box filter), so the film is bit-identical for any thread count. Non-finite
 * samples are dropped and counted ("Film/Non-finite samples").
 *
 * The render state (render_state) is that sum and the number of samples done, per pixel. A
 * tile works sample by sample (sample k of all its pixels, then k + 1), and between two
 * samples it may stop: for a periodic pause (render_control.pause_every: the on_pause callback writes a
 * checkpoint or a snapshot while every thread waits) or for a signal deferred by output.h
 * (stop_on_signal: on_pause is called once more, then render_image returns
 * RENDER_INTERRUPTED). A render given a state that is partly done continues from it: the
 * samples it adds are the ones an uninterrupted render would have added next, in the same
 * order, so the final image is bit-identical to an uninterrupted render at any thread count
 * (tests/test_render_checkpoint.c).
 *
 * The caller owns the integrator (already created and preprocessed), the film (render_image
 * initializes it to the camera's size; film_free it afterwards) and the state, if it gives one.
 */
#ifndef RENDER_RENDERER_H
#define RENDER_RENDERER_H

#include <stdint.h>

#include "image/film.h"
#include "integrators/integrator.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Tiles: the image is cut into square tiles that threads (and MPI ranks) take one at a time.
 * RENDER_TILE is the largest side; an image of fewer than RENDER_MIN_TILES such tiles is cut
 * finer (the side halved, down to 2), so that a small image (16 x 16: one tile of 16) still
 * keeps two threads busy. The grid depends on the image's size alone, and each pixel's samples
 * are summed in sample order by whichever thread takes its tile, so the image is the same for
 * any thread count, process count and tile side. */
#define RENDER_TILE 16
#define RENDER_MIN_TILES 16

typedef struct render_grid {
    int side;       /* a tile's side in pixels (the last row and column may be narrower) */
    int tiles_x, tiles_y;
} render_grid;

render_grid render_grid_of(int width, int height);
/* Tile `tile` (row-major) of the grid: pixels [x0, x1) x [y0, y1). */
void render_grid_tile(const render_grid *g, int width, int height, int tile, int *x0, int *y0, int *x1, int *y1);

typedef struct render_state {
    int width, height, spp;
    double *sum;     /* 3 per pixel, row-major: the sum of the pixel's finite samples */
    uint32_t *count; /* per pixel: samples 0 .. count-1 are in sum */
} render_state;

/* An empty state (all counts 0). 0 or PM_ENOMEM. */
int render_state_init(render_state *st, int width, int height, int spp);
void render_state_free(render_state *st);
/* Samples done over all pixels. */
uint64_t render_state_done(const render_state *st);
/* The image so far: sum * (1 / count) per pixel, black where count is 0. f must have the
 * state's size. For a finished state this is exactly the image render_image gives. */
void render_state_to_film(const render_state *st, film *f);

enum { RENDER_PAUSE_PERIODIC = 0, RENDER_PAUSE_SIGNAL = 1 };
enum { RENDER_INTERRUPTED = 1 }; /* render_image's return when a signal stopped it */
/* Called on the calling thread with all workers idle; why is a RENDER_PAUSE_*. A negative
 * return ends the render with that code. */
typedef int (*render_pause_fn)(void *user, const render_state *st, int why);

typedef struct render_job {
    int threads;   /* 0: OpenMP's default (all cores) */
    int quiet;     /* no progress output */
    uint64_t seed; /* usually scene.settings.seed */
    /* NULL, or one multiplier per pixel (1 or more, row-major): pixel p takes spp x mult[p]
     * samples (run/passes.h, ADAPTIVE SAMPLES). Sample k of a pixel lies in stratum k mod spp,
     * with stream k: each further round of spp samples is stratified again, on its own
     * streams, and the integrator sees sample k mod spp of spp (its strides stay whole). */
    const unsigned char *mult;
    /* NULL, or the footprints of openings the camera sees in slivers of pixels: there the
     * samples are aimed at the opening and weighted (run/focus.h). */
    const struct film_focus *focus;
} render_job;

/* The samples pixel p takes in job: spp x job->mult[p] (or spp). */
static inline uint32_t render_pixel_spp(const render_job *job, int spp, uint64_t p) {
    return (uint32_t)spp * (job->mult ? (uint32_t)job->mult[p] : 1u);
}

/* The samples the whole image takes in job: render_pixel_spp summed over the W x H pixels. */
static inline uint64_t render_image_spp(const render_job *job, int spp, int width, int height) {
    uint64_t total = 0;
    for (uint64_t p = 0; p < (uint64_t)width * (uint64_t)height; p++) total += render_pixel_spp(job, spp, p);
    return total;
}

/* Camera sample k of pixel (x, y) in job, n x n strata (sample k lies in stratum k mod spp,
 * render_job.mult): its stream *g, past the film jitter, its ray *r and its id *id. Returns the
 * weight its radiance is multiplied by: the camera's focus weight (run/focus.h), 1 unfocused.
 * render_tile and render-mpi's tiles (mpi/lk_tiles.c) both take their samples here. */
double render_camera_sample(const render_job *job, const camera *c, int x, int y, uint32_t k, int n, rng *g, ray *r,
                            sample_id *id);

/* What a checkpointed or snapshotted render adds to the job (zero it, then set fields). */
typedef struct render_control {
    render_state *state; /* NULL: a private, empty one; else continue from it and keep it */
    double pause_every;  /* seconds between periodic on_pause calls; 0: none */
    render_pause_fn on_pause;
    void *user;
    int stop_on_signal; /* stop at a signal deferred by output.h (see above) */
} render_control;

/* 0, or a negative PM_E* code (PM_ENOMEM). */
int render_image(const scene *s, const integrator *it, const render_job *job, film *out);
/* The same with a control (NULL: none). 0, RENDER_INTERRUPTED, or a negative PM_E* code
 * (PM_ENOMEM, PM_EINVAL for a state of another size, or on_pause's code). The film holds
 * the image so far unless the return is negative. */
int render_image_ctl(const scene *s, const integrator *it, const render_job *job,
                     const render_control *ctl, film *out);

/* Render the listed tiles (indices row-major over render_grid_of's grid) completely into st,
 * threads taking the next tile as in render_image; no film, progress, pauses or timers. Each
 * pixel gets exactly the sums render_image gives it, so a distributed render (render/mpi/)
 * can hand tiles to any process and copy the sums into one state. 0, or PM_EINVAL for a
 * state of another size or a tile index out of range. */
int render_tiles(const scene *s, const integrator *it, const render_job *job, render_state *st,
                 const int *tiles, int ntiles);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_RENDERER_H */
