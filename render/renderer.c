/* renderer.c: the tile loop; see renderer.h. */
#include "renderer.h"

#include "common.h"
#include "progress.h"
#include "stats.h"

#ifdef _OPENMP
#include <omp.h>
#endif

static void render_tile(const scene *s, const integrator *it, const render_job *job, film *out,
                        int tile, int tiles_x, void *scratch, int stat_nonfinite) {
    const camera *c = &s->cam;
    int x0 = (tile % tiles_x) * RENDER_TILE, y0 = (tile / tiles_x) * RENDER_TILE;
    int x1 = x0 + RENDER_TILE < c->width ? x0 + RENDER_TILE : c->width;
    int y1 = y0 + RENDER_TILE < c->height ? y0 + RENDER_TILE : c->height;
    int n = c->strata;
    uint64_t bad = 0;
    for (int y = y0; y < y1; y++) {
        for (int x = x0; x < x1; x++) {
            uint64_t pixel = (uint64_t)y * (uint64_t)c->width + (uint64_t)x;
            rgb sum = v3s(0);
            for (int k = 0; k < c->spp; k++) {
                rng g = rng_stream(job->seed, pixel, (uint64_t)k);
                double jx = rng_uniform(&g), jy = rng_uniform(&g);
                double px = x + ((k % n) + jx) / n, py = y + ((k / n) + jy) / n;
                ray r = camera_ray(c, px, py);
                sample_id id = {pixel, job->seed, k, c->spp, n};
                rgb L = it->li(it, s, r, &g, &id, scratch);
                if (v3_isfinite(L))
                    sum = v3_add(sum, L);
                else
                    bad++;
            }
            film_set(out, x, y, v3_scale(sum, 1.0 / c->spp));
        }
    }
    uint64_t npx = (uint64_t)(x1 - x0) * (uint64_t)(y1 - y0);
    stat_add(STAT_CAMERA_RAYS, npx * (uint64_t)c->spp);
    stat_add(STAT_SAMPLES, npx * (uint64_t)c->spp);
    if (bad) stat_add(stat_nonfinite, bad);
}

int render_image(const scene *s, const integrator *it, const render_job *job, film *out) {
    const camera *c = &s->cam;
    int rc = film_init(out, c->width, c->height);
    if (rc < 0) return rc;
    int tiles_x = (c->width + RENDER_TILE - 1) / RENDER_TILE;
    int tiles_y = (c->height + RENDER_TILE - 1) / RENDER_TILE;
    int ntiles = tiles_x * tiles_y;
    int stat_nonfinite = stats_register("Film/Non-finite samples");
    progress prog;
    progress_begin(&prog, "Rendering", ntiles, job->quiet);
    double t0 = stats_now();
#ifdef _OPENMP
    int nthreads = job->threads > 0 ? job->threads : omp_get_max_threads();
#pragma omp parallel num_threads(nthreads)
#endif
    {
        void *scratch = it->thread_begin ? it->thread_begin(it) : NULL;
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 1)
#endif
        for (int t = 0; t < ntiles; t++) {
            render_tile(s, it, job, out, t, tiles_x, scratch, stat_nonfinite);
            progress_add(&prog, 1);
        }
        if (it->thread_end) it->thread_end(it, scratch);
    }
    progress_end(&prog);
    stats_time_add("Time/Rendering", stats_now() - t0);
    return 0;
}
