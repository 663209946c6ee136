/* renderer.h: the image loop shared by every integrator: tiles, threads, strata, film.
 *
 * render_image() splits the image into 16x16 tiles and renders them with OpenMP (dynamic
 * schedule, so slow tiles around glass do not hold up a thread). Each pixel takes
 * cam.spp = strata^2 samples, one per stratum, jittered inside it; sample k of pixel i uses the
 * random stream (seed, i, k) and nothing else, and a pixel is summed by one thread in sample
 * order, so the film is bit-identical for any thread count. The pixel value is the plain mean
 * (box filter). Non-finite samples are dropped and counted ("Film/Non-finite samples").
 *
 * The caller owns the integrator (already created and preprocessed) and the film, which
 * render_image initializes to the camera's size (film_free it afterwards).
 */
#ifndef RENDER_RENDERER_H
#define RENDER_RENDERER_H

#include <stdint.h>

#include "film.h"
#include "integrator.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

#define RENDER_TILE 16

typedef struct render_job {
    int threads;   /* 0: OpenMP's default (all cores) */
    int quiet;     /* no progress output */
    uint64_t seed; /* usually scene.settings.seed */
} render_job;

/* 0, or a negative PM_E* code (PM_ENOMEM). */
int render_image(const scene *s, const integrator *it, const render_job *job, film *out);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_RENDERER_H */
