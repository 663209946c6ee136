/* dist.c: the MPI side of render-mpi (dist.h): its set-up, the photon exchange (the all-gather
 * of each round's batches that trace_dist hands over) and the image loop, which joins the
 * ranks' agreement and runs the tile queue (tile_queue.c) for a whole render or one pass of a
 * render in passes. The agreement and the failures are ranks.c's.
 *
 * Only the main thread calls MPI (MPI_THREAD_FUNNELED): OpenMP threads work inside
 * render_tiles and the photon batches, between MPI calls.
 */
#include "dist.h"

#include <limits.h>
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lookup.h"
#include "ranks.h"
#include "tile_queue.h"
#include "run/checkpoint.h"
#include "photonmap/common.h"
#include "photons/photon_trace.h"
#include "base/stats.h"
#include "photons/volume.h"

static uint64_t g_bytes_photon; /* rank 0: bytes sent by all ranks in the photon exchanges */
static trace_dist g_td;

/* ---- photon pass ----------------------------------------------------------------------- */

static int photon_allgather(void *user, const void *mine, size_t nbytes, void **all, size_t *sizes) {
    (void)user;
    dist_collective_begin();
    int size = dist_size();
    unsigned long long n = nbytes, *ns = dist_malloc((size_t)size * sizeof *ns, DIST_PH_PHOTONS);
    int *cnt = dist_malloc((size_t)size * sizeof *cnt, DIST_PH_PHOTONS);
    int *dsp = dist_malloc((size_t)size * sizeof *dsp, DIST_PH_PHOTONS);
    if (!ns || !cnt || !dsp) dist_die("out of memory in the photon exchange (its counts)");
    /* Non-blocking, so that rank 0 hears a rank that failed instead of waiting for it. */
    MPI_Request r;
    MPI_Iallgather(&n, 1, MPI_UNSIGNED_LONG_LONG, ns, 1, MPI_UNSIGNED_LONG_LONG, MPI_COMM_WORLD, &r);
    dist_wait(&r);
    unsigned long long total = 0;
    for (int k = 0; k < size; k++) {
        if (total > (unsigned long long)INT_MAX) break;
        cnt[k] = (int)ns[k];
        dsp[k] = (int)total;
        total += ns[k];
    }
    if (total > (unsigned long long)INT_MAX)
        dist_die("a photon round exceeds 2 GiB (MPI's int counts)");
    char *buf = dist_malloc(total ? (size_t)total : 1, DIST_PH_PHOTONS);
    if (!buf) {
        char what[128];
        snprintf(what, sizeof what, "out of memory in the photon exchange (%llu bytes for a round)",
                 total);
        dist_die(what);
    }
    MPI_Iallgatherv(mine, (int)n, MPI_BYTE, buf, cnt, dsp, MPI_BYTE, MPI_COMM_WORLD, &r);
    dist_wait(&r);
    for (int k = 0; k < size; k++) sizes[k] = (size_t)ns[k];
    g_bytes_photon += total * (unsigned long long)(size - 1); /* each part goes to the others */
    *all = buf;
    free(ns);
    free(cnt);
    free(dsp);
    return 0;
}

/* The photon tracer failed on this rank (out of memory), before the exchange that would tell
 * every rank: a failure after the agreement (joined here if this is the first exchange, where
 * the other ranks wait in it), so rank 0 names this rank and the pass. */
static void tracer_failed(void *user, const char *what) {
    (void)user;
    dist_collective_begin();
    dist_die(what);
}
static int tracer_test_fail(void *user) {
    (void)user;
    return dist_test_enomem(DIST_PH_TRACER);
}

/* ---- set-up and the image loop ----------------------------------------------------------- */

void dist_init(int mode) {
    dist_ranks_init(mode);
    int rank = dist_rank(), size = dist_size();
    g_td.nparts = size;
    g_td.part = rank;
    g_td.allgather = photon_allgather;
    g_td.user = NULL;
    g_td.partitioned = mode == DIST_PARTITIONED;
    g_td.failed = tracer_failed;
    g_td.test_fail = tracer_test_fail;
    photon_trace_set_dist(&g_td);
    vol_set_dist(&g_td); /* the media passes too (volume.h), in both modes */
    /* Every rank makes the same collective calls before the agreement, whatever its mode or
     * command (render_mpi.c: the node's ranks, MPI_Comm_split_type): ranks given different
     * commands meet there and are told so instead of waiting for each other. */
    MPI_Comm lk_comm;
    MPI_Comm_dup(MPI_COMM_WORLD, &lk_comm);
    if (mode == DIST_PARTITIONED) lk_init(rank, size, lk_comm);
    else MPI_Comm_free(&lk_comm);
    /* Checkpoints: rank 0 writes them. A replicated render's image is render's, so are its
     * checkpoints; a partitioned one depends on the number of parts, and its maps cannot be
     * saved whole (they are traced again on resume). */
    char extra[64] = "";
    if (mode == DIST_PARTITIONED)
        snprintf(extra, sizeof extra, "; distributed partitioned over %d ranks", size);
    ckpt_set_distributed(rank == 0, extra, mode == DIST_PARTITIONED);
    if (mode == DIST_PARTITIONED) { /* only the same number of ranks resumes it */
        char cmd[64];
        snprintf(cmd, sizeof cmd, "mpirun -np %d render-mpi", size);
        ckpt_set_resume_command(cmd);
    }
}

/* One distributed image. in_passes 0: the whole render (workers end here); 1: one pass of a
 * render in passes (dist.h): every rank returns, the workers with a black film. */
static int dist_image(const scene *s, const integrator *it, const render_job *job,
                      const render_control *ctl, film *out, int in_passes) {
    dist_collective_begin();
    lk_begin(s); /* before this rank answers another's photon lookups */
    const camera *c = &s->cam;
    /* Rank 0 renders into the caller's state (a checkpointed or resumed render: checkpoints
     * are written from it), the workers into their own. */
    render_state own, *st = &own;
    int rc;
    if (dist_rank() == 0 && ctl && ctl->state) {
        st = ctl->state;
        if (st->width != c->width || st->height != c->height || st->spp != c->spp) return PM_EINVAL;
    } else if ((rc = dist_test_enomem(DIST_PH_PIXELS) ? PM_ENOMEM
                                                 : render_state_init(&own, c->width, c->height, c->spp)) < 0) {
        return rc; /* main.c says it; dist_finish sends it to rank 0 */
    }
    double t0 = stats_now();
    if (dist_rank() == 0) {
        rc = tq_root(s, it, job, st, ctl, g_bytes_photon);
        if (rc >= 0 && film_init(out, c->width, c->height) < 0) rc = PM_ENOMEM;
        if (rc >= 0) render_state_to_film(st, out);
        if (st == &own) render_state_free(&own);
        stats_time_add("Time/Rendering", stats_now() - t0);
        if (rc == 0 && !in_passes) dist_film_gathered();
        return rc;
    }
    uint64_t *base = dist_calloc(STATS_MAX, sizeof *base, DIST_PH_PIXELS);
    if (!base) {
        render_state_free(&own);
        return PM_ENOMEM;
    }
    for (int id = 0; id < STATS_MAX; id++) base[id] = stats_total(id);
    rc = tq_worker(s, it, job, &own, base);
    free(base);
    render_state_free(&own);
    if (rc < 0) return rc;
    if (in_passes) return film_init(out, c->width, c->height); /* rank 0 has the pass's tiles */
    /* Done: rank 0 has this rank's tiles and statistics, and writes the image. */
    dist_film_gathered();
    fflush(stdout);
    MPI_Finalize();
    exit(0);
}

int dist_render_image_ctl(const scene *s, const integrator *it, const render_job *job,
                          const render_control *ctl, film *out) {
    return dist_image(s, it, job, ctl, out, 0);
}

int dist_pass_image(const scene *s, const integrator *it, const render_job *job,
                    const render_control *ctl, film *out) {
    return dist_image(s, it, job, ctl, out, 1);
}

int dist_pass_agree(int go) {
    dist_collective_begin();
    int32_t v = go;
    MPI_Request r;
    MPI_Ibcast(&v, 1, MPI_INT32_T, 0, MPI_COMM_WORLD, &r);
    dist_wait(&r);
    return v != 0;
}

int dist_pass_share(unsigned char *buf, size_t n) {
    if (n > INT32_MAX) return PM_EINVAL;
    dist_collective_begin();
    MPI_Request r;
    MPI_Ibcast(buf, (int)n, MPI_BYTE, 0, MPI_COMM_WORLD, &r);
    dist_wait(&r);
    return 0;
}

void dist_passes_end(int rc) {
    if (rc < 0) return; /* main.c says it; dist_finish stops the job */
    dist_film_gathered();
    if (dist_rank() == 0) return;
    fflush(stdout);
    MPI_Finalize();
    exit(0);
}
