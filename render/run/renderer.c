/* renderer.c: the tile loop and the render state; see renderer.h.
 *
 * The loop runs in segments. A segment is one OpenMP parallel region in which threads claim
 * unfinished tiles from an atomic counter and work on them sample by sample until the tile
 * is done or the shared stop flag is set (a pause is due, a signal is pending, or the test
 * pause fraction is reached). When the region ends every worker is idle and every pixel's
 * sum and count agree, which is when a checkpoint or snapshot can read the state. Then the
 * next segment takes the tiles still unfinished. Stopping inside a tile only between two
 * whole samples keeps each pixel's additions in sample order whatever the schedule.
 */
#include "run/renderer.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "common.h"
#include "base/output.h"
#include "base/progress.h"
#include "base/stats.h"
#include "run/focus.h"

#ifdef _OPENMP
#include <omp.h>
#endif

int render_state_init(render_state *st, int width, int height, int spp) {
    size_t n = (size_t)width * (size_t)height;
    st->width = width;
    st->height = height;
    st->spp = spp;
    st->sum = calloc(n * 3, sizeof *st->sum);
    st->count = calloc(n, sizeof *st->count);
    if (!st->sum || !st->count) {
        render_state_free(st);
        return PM_ENOMEM;
    }
    return 0;
}

/* Member by member, as pass_state_free (passes.c) for another struct's arrays. */
void render_state_free(render_state *st) {
    free(st->sum);
    free(st->count);
    st->sum = NULL;
    st->count = NULL;
}

uint64_t render_state_done(const render_state *st) {
    uint64_t d = 0;
    for (size_t i = 0; i < (size_t)st->width * (size_t)st->height; i++) d += st->count[i];
    return d;
}

void render_state_to_film(const render_state *st, film *f) {
    for (int y = 0; y < st->height; y++)
        for (int x = 0; x < st->width; x++) {
            size_t i = (size_t)y * (size_t)st->width + (size_t)x;
            const double *s = st->sum + 3 * i;
            rgb c = st->count[i] ? v3_scale(v3(s[0], s[1], s[2]), 1.0 / st->count[i]) : v3s(0);
            film_set(f, x, y, c);
        }
}

render_grid render_grid_of(int width, int height) {
    render_grid g = {RENDER_TILE, 0, 0};
    for (;;) {
        g.tiles_x = (width + g.side - 1) / g.side;
        g.tiles_y = (height + g.side - 1) / g.side;
        if (g.side <= 2 || (int64_t)g.tiles_x * g.tiles_y >= RENDER_MIN_TILES) return g;
        g.side /= 2;
    }
}

void render_grid_tile(const render_grid *g, int width, int height, int tile, int *x0, int *y0, int *x1, int *y1) {
    *x0 = (tile % g->tiles_x) * g->side;
    *y0 = (tile / g->tiles_x) * g->side;
    *x1 = *x0 + g->side < width ? *x0 + g->side : width;
    *y1 = *y0 + g->side < height ? *y0 + g->side : height;
}

typedef struct loop {
    const scene *s;
    const integrator *it;
    const render_job *job;
    const render_control *ctl;
    render_state *st;
    render_grid grid;
    int stat_nonfinite;
    progress prog;
    _Atomic int stop;
    double due;          /* stats_now() time of the next periodic pause, or INFINITY */
    int64_t pause_at;    /* samples done at which the test pause happens, or -1 */
} loop;

static int tile_done(const loop *L, int tile) {
    const render_state *st = L->st;
    int x0, y0, x1, y1;
    render_grid_tile(&L->grid, st->width, st->height, tile, &x0, &y0, &x1, &y1);
    for (int y = y0; y < y1; y++)
        for (int x = x0; x < x1; x++)
            if (st->count[(size_t)y * (size_t)st->width + (size_t)x] <
                render_pixel_spp(L->job, st->spp, (uint64_t)y * (uint64_t)st->width + (uint64_t)x))
                return 0;
    return 1;
}

static int should_stop(loop *L) {
    if (atomic_load(&L->stop)) return 1;
    int stop = (L->ctl->stop_on_signal && out_pending_signal()) || stats_now() >= L->due ||
               (L->pause_at >= 0 && atomic_load(&L->prog.done) >= L->pause_at);
    if (stop) atomic_store(&L->stop, 1);
    return stop;
}

double render_camera_sample(const render_job *job, const camera *c, int x, int y, uint32_t k, int n, rng *g, ray *r,
                            sample_id *id) {
    uint64_t pixel = (uint64_t)y * (uint64_t)c->width + (uint64_t)x;
    int ks = (int)(k % (uint32_t)c->spp); /* its stratum */
    *g = rng_stream(job->seed, pixel, (uint64_t)k);
    double jx = rng_uniform(g), jy = rng_uniform(g);
    double px, py, fw = focus_film_point(job->focus, x, y, ((ks % n) + jx) / n, ((ks / n) + jy) / n, &px, &py);
    *r = camera_ray(c, px, py);
    *id = (sample_id){pixel, job->seed, ks, c->spp, n, fw != 1}; /* fw is never 1 when focused */
    return fw;
}

/* Samples of one tile, one sample index at a time, until it is done or the loop stops. */
static void render_tile(loop *L, int tile, void *scratch) {
    const camera *c = &L->s->cam;
    render_state *st = L->st;
    int x0, y0, x1, y1;
    render_grid_tile(&L->grid, c->width, c->height, tile, &x0, &y0, &x1, &y1);
    int n = c->strata;
    uint32_t kmin = UINT32_MAX, kmax = 0;
    for (int y = y0; y < y1; y++)
        for (int x = x0; x < x1; x++) {
            uint64_t pixel = (uint64_t)y * (uint64_t)c->width + (uint64_t)x;
            uint32_t k = st->count[pixel], t = render_pixel_spp(L->job, c->spp, pixel);
            if (k < kmin) kmin = k;
            if (t > kmax) kmax = t;
        }
    for (uint32_t k = kmin; k < kmax; k++) {
        uint64_t bad = 0, did = 0;
        for (int y = y0; y < y1; y++) {
            for (int x = x0; x < x1; x++) {
                uint64_t pixel = (uint64_t)y * (uint64_t)c->width + (uint64_t)x;
                if (st->count[pixel] > k) continue; /* done before a resume */
                if (k >= render_pixel_spp(L->job, c->spp, pixel)) continue;
                rng g;
                ray r;
                sample_id id;
                double fw = render_camera_sample(L->job, c, x, y, k, n, &g, &r, &id);
                rgb Li = L->it->li(L->it, L->s, r, &g, &id, scratch);
                if (fw != 1) Li = v3_scale(Li, fw);
                double *sum = st->sum + 3 * pixel;
                if (v3_isfinite(Li)) {
                    sum[0] += Li.x;
                    sum[1] += Li.y;
                    sum[2] += Li.z;
                } else {
                    bad++;
                }
                st->count[pixel] = k + 1;
                did++;
            }
        }
        stat_add(STAT_CAMERA_RAYS, did);
        stat_add(STAT_SAMPLES, did);
        if (bad) stat_add(L->stat_nonfinite, bad);
        progress_add(&L->prog, (int64_t)did);
        if (k + 1 < kmax && should_stop(L)) return;
    }
}

int render_image(const scene *s, const integrator *it, const render_job *job, film *out) {
    return render_image_ctl(s, it, job, NULL, out);
}

int render_image_ctl(const scene *s, const integrator *it, const render_job *job,
                     const render_control *ctl_or_null, film *out) {
    const camera *c = &s->cam;
    render_control none;
    memset(&none, 0, sizeof none);
    const render_control *ctl = ctl_or_null ? ctl_or_null : &none;
    render_state own, *st = ctl->state;
    int rc;
    if (!st) {
        if ((rc = render_state_init(&own, c->width, c->height, c->spp)) < 0) return rc;
        st = &own;
    } else if (st->width != c->width || st->height != c->height || st->spp != c->spp) {
        return PM_EINVAL;
    }
    if ((rc = film_init(out, c->width, c->height)) < 0) {
        if (st == &own) render_state_free(&own);
        return rc;
    }
    loop L;
    memset(&L, 0, sizeof L);
    /* Field by field (as photon_trace.c does its run): the loop's own members. */
    L.s = s;
    L.it = it;
    L.job = job;
    L.ctl = ctl;
    L.st = st;
    L.grid = render_grid_of(c->width, c->height);
    int ntiles = L.grid.tiles_x * L.grid.tiles_y;
    L.stat_nonfinite = stats_register("Film/Non-finite samples");
    int64_t total = (int64_t)render_image_spp(job, c->spp, c->width, c->height);
    int64_t done = (int64_t)render_state_done(st);
    double frac = out_test_pause_fraction();
    L.pause_at = frac >= 0 && done < (int64_t)(frac * (double)total) ? (int64_t)(frac * (double)total) : -1;
    if (done > 0 && !job->quiet)
        fprintf(stderr, "Resuming: %lld of %lld samples done (%.1f%%)\n", (long long)done,
                (long long)total, 100.0 * (double)done / (double)total);
    progress_begin(&L.prog, "Rendering", total, job->quiet);
    if (done > 0) progress_resume(&L.prog, done); /* the bar starts at the resumed state */
    double t0 = stats_now();
    int *todo = malloc((size_t)ntiles * sizeof *todo);
    if (!todo) rc = PM_ENOMEM;
#ifdef _OPENMP
    int nthreads = job->threads > 0 ? job->threads : omp_get_max_threads();
#endif
    while (rc == 0) {
        int ntodo = 0;
        for (int t = 0; t < ntiles; t++)
            if (!tile_done(&L, t)) todo[ntodo++] = t;
        if (ntodo == 0) break;
        L.due = ctl->pause_every > 0 && ctl->on_pause ? stats_now() + ctl->pause_every : INFINITY;
        atomic_store(&L.stop, 0);
        _Atomic int next = 0;
#ifdef _OPENMP
#pragma omp parallel num_threads(nthreads)
#endif
        {
            void *scratch = it->thread_begin ? it->thread_begin(it) : NULL;
            while (!atomic_load(&L.stop)) {
                int i = atomic_fetch_add(&next, 1);
                if (i >= ntodo) break;
                render_tile(&L, todo[i], scratch);
            }
            if (it->thread_end) it->thread_end(it, scratch);
        }
        if (!atomic_load(&L.stop)) continue; /* every tile finished */
        if (L.pause_at >= 0 && atomic_load(&L.prog.done) >= L.pause_at) {
            L.pause_at = -1;
            out_test_pause("render");
        }
        if (ctl->stop_on_signal && out_pending_signal()) {
            if (ctl->on_pause) {
                int prc = ctl->on_pause(ctl->user, st, RENDER_PAUSE_SIGNAL);
                if (prc < 0) {
                    rc = prc;
                    break;
                }
            }
            rc = RENDER_INTERRUPTED;
            break;
        }
        if (ctl->on_pause && stats_now() >= L.due) {
            int prc = ctl->on_pause(ctl->user, st, RENDER_PAUSE_PERIODIC);
            if (prc < 0) rc = prc;
        }
    }
    free(todo);
    if (rc < 0) {
        film_free(out);
    } else {
        render_state_to_film(st, out);
        /* What lands in the film: a sum finite in double can still overflow the film's floats. */
        stat_add(stats_register("Film/Non-finite pixels"), film_count_nonfinite(out));
        if (rc == 0) progress_end(&L.prog);
    }
    if (st == &own) render_state_free(&own);
    stats_time_add("Time/Rendering", stats_now() - t0);
    return rc;
}

int render_tiles(const scene *s, const integrator *it, const render_job *job, render_state *st,
                 const int *tiles, int ntiles) {
    const camera *c = &s->cam;
    if (st->width != c->width || st->height != c->height || st->spp != c->spp) return PM_EINVAL;
    render_control none;
    memset(&none, 0, sizeof none);
    loop L;
    memset(&L, 0, sizeof L);
    L.s = s;
    L.it = it;
    L.job = job;
    L.ctl = &none;
    L.st = st;
    L.grid = render_grid_of(c->width, c->height);
    int all = L.grid.tiles_x * L.grid.tiles_y;
    for (int i = 0; i < ntiles; i++)
        if (tiles[i] < 0 || tiles[i] >= all) return PM_EINVAL;
    L.stat_nonfinite = stats_register("Film/Non-finite samples");
    L.due = INFINITY;
    L.pause_at = -1;
    progress_begin(&L.prog, "Rendering", (int64_t)ntiles * L.grid.side * L.grid.side * c->spp, 1);
    _Atomic int next = 0;
#ifdef _OPENMP
    int nthreads = job->threads > 0 ? job->threads : omp_get_max_threads();
#pragma omp parallel num_threads(nthreads)
#endif
    {
        void *scratch = it->thread_begin ? it->thread_begin(it) : NULL;
        for (;;) {
            int i = atomic_fetch_add(&next, 1);
            if (i >= ntiles) break;
            render_tile(&L, tiles[i], scratch);
        }
        if (it->thread_end) it->thread_end(it, scratch);
    }
    return 0;
}
