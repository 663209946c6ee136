/* lk_tiles.c: a partitioned render's tiles (lookup.h, PIXEL PASS): the camera samples of a chunk
 * traced a block at a time, the queries they made exchanged with every rank, the samples traced
 * again on the answers until every sample's last trace read answers only, and each pixel's
 * samples added in sample order as render_tile adds them.
 */
#include "lk_tiles.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "lookup.h"
#include "ranks.h"
#include "scene/camera.h"
#include "photonmap/common.h"
#include "base/rng.h"
#include "base/stats.h"

#ifdef _OPENMP
#include <omp.h>
#endif

_Thread_local lk_smp *lk_tl_smp;

static void rec_free(lk_rec *r) {
    if (!r) return;
    free(r->q);
    free(r->mine);
    free(r->e);
    free(r->flags);
    free(r->counted);
    free(r);
}

/* Trace the camera samples smp[idx[0..n)] on the job's threads, each from its start, exactly as
 * renderer.c's render_tile traces sample k of a pixel (render_camera_sample: its stream, jitter and ray).
 * A trace that made a query not answered before (rec->fresh) ran on guesses: the counters it
 * added on its thread are taken off and kept in rec->counted, to be added back if every guess
 * turns out to be the answer (its radiance is then the sample's), so the statistics count
 * the one trace of each sample that is kept. */
static void trace_samples(const scene *s, const integrator *it, const render_job *job, lk_smp *smp,
                          const uint32_t *idx, size_t n) {
    const camera *c = &s->cam;
    int strata = c->strata;
#ifdef _OPENMP
    int nthreads = job->threads > 0 ? job->threads : omp_get_max_threads();
#pragma omp parallel num_threads(nthreads)
#endif
    {
        void *scratch = it->thread_begin ? it->thread_begin(it) : NULL;
        uint64_t *cnt = stats__local ? stats__local : stats__attach();
        uint64_t snap[STATS_MAX];
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 16)
#endif
        for (size_t i = 0; i < n; i++) {
            lk_smp *sm = &smp[idx[i]];
            if (sm->rec) {
                sm->rec->cursor = 0;
                sm->rec->fresh = 0;
            }
            memcpy(snap, cnt, sizeof snap);
            int x = (int)(sm->pixel % (uint64_t)c->width), y = (int)(sm->pixel / (uint64_t)c->width);
            rng g;
            ray r;
            sample_id id;
            double fw = render_camera_sample(job, c, x, y, (uint32_t)sm->k, strata, &g, &r, &id);
            lk_tl_smp = sm;
            rgb Li = it->li(it, s, r, &g, &id, scratch);
            if (fw != 1) Li = v3_scale(Li, fw);
            lk_tl_smp = NULL;
            sm->L[0] = Li.x;
            sm->L[1] = Li.y;
            sm->L[2] = Li.z;
            if (sm->rec && sm->rec->fresh) {
                lk_rec *rec = sm->rec;
                uint64_t nz = 0;
                for (int c_ = 0; c_ < STATS_MAX; c_++) nz += cnt[c_] != snap[c_];
                free(rec->counted);
                if (!(rec->counted = malloc((1 + 2 * nz) * sizeof *rec->counted)))
                    dist_die("out of memory recording photon lookups");
                rec->counted[0] = nz;
                for (int c_ = 0, o_ = 1; c_ < STATS_MAX; c_++)
                    if (cnt[c_] != snap[c_]) {
                        rec->counted[o_++] = (uint64_t)c_;
                        rec->counted[o_++] = cnt[c_] - snap[c_];
                    }
                memcpy(cnt, snap, sizeof snap);
            }
        }
        if (it->thread_end) it->thread_end(it, scratch);
    }
}

typedef struct lk_count {
    uint64_t traced, again, more, rounds, nest, nlook, exact;
} lk_count;

/* Samples per block of lk_render_tiles. */
#define LK_BLOCK 8192

/* Render the ns samples smp[0..ns) to their radiance (idx: room for ns indices). */
static void render_block(const scene *s, const integrator *it, const render_job *job, lk_smp *smp,
                         size_t ns, uint32_t *idx, int (*also)(void *), void *arg, lk_count *cn) {
    /* Trace; the samples that made queries not answered yet get them answered by every rank in
     * one exchange, and are traced again; until every sample's trace read answers only. */
    size_t np = ns;
    for (size_t i = 0; i < ns; i++) idx[i] = (uint32_t)i;
    uint64_t rounds = 0;
    for (;;) {
        trace_samples(s, it, job, smp, idx, np);
        cn->traced += np;
        if (rounds == 1) cn->again += np;
        if (rounds >= 2) cn->more += np;
        size_t keep = 0, nq = 0;
        for (size_t i = 0; i < np; i++) {
            lk_rec *r = smp[idx[i]].rec;
            if (r && r->fresh) {
                idx[keep++] = idx[i];
                nq += r->n - r->from;
            }
        }
        np = keep;
        if (np == 0) break;
        rounds++;
        cn->rounds++;
        lk_query *q = malloc(nq * sizeof *q);
        lk_part *mine = malloc(nq * sizeof *mine);
        uint8_t *have = malloc(nq);
        if (!q || !mine || !have) dist_die("out of memory in the photon lookups");
        size_t o = 0;
        for (size_t i = 0; i < np; i++) {
            lk_rec *r = smp[idx[i]].rec;
            for (uint32_t j = r->from; j < r->n; j++, o++) {
                q[o] = r->q[j];
                have[o] = (r->flags[j] & LK_MINE) != 0;
                if (have[o]) mine[o] = r->mine[j];
                if (q[o].map == LK_SIDE)
                    cn->nlook++;
                else
                    cn->nest++;
            }
        }
        /* this rank's parts not computed during the trace */
        lk_answer_queries(q, have, nq, mine);
        lk_part *all = lk_exchange(q, nq, mine, also, arg);
        o = 0;
        for (size_t i = 0; i < np; i++) {
            lk_rec *r = smp[idx[i]].rec;
            for (uint32_t j = r->from; j < r->n; j++, o++) {
                int found = 0;
                if (q[o].map == LK_SIDE) {
                    found = lk_combine_lookup(&all[o], nq, r->e[j]);
                } else {
                    const pm_estimate_options *opt = &lk.opts[q[o].map == PHOTON_LOOKUP_CAUSTIC];
                    pm_combine_acc acc;
                    pm_combine_init(&acc);
                    acc.bias = opt->bias;
                    for (int rk = 0; rk < lk.size; rk++) lk_add_part(&acc, &all[(size_t)rk * nq + o]);
                    lk_combine_one(opt, &acc, r->e[j]);
                }
                r->flags[j] = (uint8_t)(LK_HAVE | (found ? LK_FOUND : 0));
            }
        }
        /* A sample whose every guess was the answer (a lookup that this rank's own records
         * answered as all ranks do, found or not; an estimate that is 0) was traced exactly as
         * the next trace would trace it: keep that trace (its radiance and counters). */
        size_t left = 0;
        for (size_t i = 0; i < np; i++) {
            lk_rec *r = smp[idx[i]].rec;
            int exact = 1;
            for (uint32_t j = r->from; j < r->n && exact; j++) {
                const double *e = r->e[j];
                if (r->q[j].map == LK_SIDE) {
                    const lk_part *g = &r->mine[j];
                    int found = (r->flags[j] & LK_FOUND) != 0;
                    exact = found == (g->found != 0) &&
                            (!found || (e[0] == g->power[0] && e[1] == g->power[1] && e[2] == g->power[2]));
                } else {
                    exact = e[0] == 0 && e[1] == 0 && e[2] == 0;
                }
            }
            if (exact && !lk.trace_again) {
                for (uint64_t c_ = 0; c_ < r->counted[0]; c_++)
                    stat_add((int)r->counted[1 + 2 * c_], r->counted[2 + 2 * c_]);
                cn->exact++;
            } else {
                idx[left++] = idx[i];
            }
        }
        np = left;
        free(all);
        free(have);
        free(mine);
        free(q);
    }
    for (size_t i = 0; i < ns; i++) {
        rec_free(smp[i].rec);
        smp[i].rec = NULL;
    }
}

int lk_render_tiles(const scene *s, const integrator *it, const render_job *job, render_state *st,
                    const int *tiles, int n, int (*also)(void *), void *arg) {
    const camera *c = &s->cam;
    if (!lk.ready) return render_tiles(s, it, job, st, tiles, n); /* no photon maps to look up */
    if (st->width != c->width || st->height != c->height || st->spp != c->spp) return PM_EINVAL;
    render_grid grid = render_grid_of(c->width, c->height);
    int ntiles = grid.tiles_x * grid.tiles_y;
    for (int i = 0; i < n; i++)
        if (tiles[i] < 0 || tiles[i] >= ntiles) return PM_EINVAL;
    /* The samples still to do, tile by tile, pixel by pixel, in sample order, a block at a
     * time (the queries of a whole chunk at many samples per pixel would take gigabytes). */
    lk_smp *smp = calloc(LK_BLOCK, sizeof *smp);
    uint32_t *idx = malloc(LK_BLOCK * sizeof *idx);
    if (!smp || !idx) dist_die("out of memory in the photon lookups");
    lk_count cn = {0, 0, 0, 0, 0, 0, 0};
    uint64_t bad = 0, ns = 0;
    int ti = 0, px = 0, k = -1; /* the next sample: tile ti, its pixel px, sample k (-1: start) */
    for (;;) {
        size_t m = 0;
        while (m < LK_BLOCK && ti < n) {
            int x0, y0, x1, y1;
            render_grid_tile(&grid, c->width, c->height, tiles[ti], &x0, &y0, &x1, &y1);
            int w = x1 - x0, h = y1 - y0;
            if (px >= w * h) {
                ti++;
                px = 0;
                k = -1;
                continue;
            }
            uint64_t p = (uint64_t)(y0 + px / w) * (uint64_t)c->width + (uint64_t)(x0 + px % w);
            if (k < 0) k = (int)st->count[p];
            if ((uint32_t)k >= render_pixel_spp(job, c->spp, p)) {
                px++;
                k = -1;
                continue;
            }
            smp[m].pixel = p;
            smp[m].k = k++;
            smp[m].rec = NULL;
            m++;
        }
        if (m == 0) break;
        render_block(s, it, job, smp, m, idx, also, arg, &cn);
        /* Each pixel's samples in sample order, as render_tile adds them. */
        for (size_t i = 0; i < m; i++) {
            lk_smp *sm = &smp[i];
            double *sum = st->sum + 3 * sm->pixel;
            if (isfinite(sm->L[0]) && isfinite(sm->L[1]) && isfinite(sm->L[2])) {
                sum[0] += sm->L[0];
                sum[1] += sm->L[1];
                sum[2] += sm->L[2];
            } else {
                bad++;
            }
            st->count[sm->pixel] = (uint32_t)sm->k + 1;
        }
        ns += m;
    }
    stat_add(STAT_CAMERA_RAYS, ns);
    stat_add(STAT_SAMPLES, ns);
    if (bad) stat_add(lk.st_nonfinite, bad);
    stat_add(lk.st_queries, cn.nest + cn.nlook);
    stat_add(lk.st_gather_queries, cn.nlook);
    stat_add(lk.st_traced, cn.traced);
    stat_add(lk.st_again, cn.again);
    stat_add(lk.st_more, cn.more);
    stat_add(lk.st_rounds, cn.rounds);
    stat_add(lk.st_exact, cn.exact);
    free(idx);
    free(smp);
    return 0;
}
