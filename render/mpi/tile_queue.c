/* tile_queue.c: the pixel pass of render-mpi (dist.h, PIXEL PASS): rank 0's queue of the image's
 * 16x16 tiles, which it serves between chunks of its own, and a worker's loop (ask, render,
 * send, until the queue is empty; then its statistics). Rank 0 copies every tile's pixel sums
 * into one render_state, so the film is bit-identical whatever tile went where.
 *
 * Messages of the pixel pass (all through rank 0, which counts their bytes):
 *   REQ     worker -> 0   int32 threads: "give me one more chunk"
 *   ASSIGN  0 -> worker   int32 n, then n tile indices (n = 0: the queue is empty)
 *   RESULT  worker -> 0   int32 n, then per tile: int32 tile, int32 0, the tile's pixel sums
 *                         (3 doubles each, rows of the tile clipped to the image)
 *   STATS   worker -> 0   the worker's pixel-pass counters (name, value), its last message
 *   FAIL    worker -> 0   int32 status, then its message (ranks.h)
 * A worker keeps one request ahead (two at the start), so the next chunk is already there
 * when it finishes one; replies to one worker come in the order of its requests, so after
 * the first empty ASSIGN every later reply is empty too. REQ is small, so it travels
 * eagerly even while a large RESULT waits for its receiver.
 */
#include "tile_queue.h"

#include <math.h>
#include <mpi.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "lookup.h"
#include "ranks.h"
#include "base/output.h"
#include "base/progress.h"
#include "base/stats.h"
#include "photonmap/common.h"

enum { TAG_REQ = 101, TAG_ASSIGN, TAG_RESULT, TAG_STATS, TAG_FAIL = DIST_TAG_FAIL };
#define NAME_MAX_LEN 80

static uint64_t g_bytes_pixel; /* rank 0: bytes sent by all ranks in the pixel pass */

typedef struct tile_box {
    int x0, y0, x1, y1;
} tile_box;

static tile_box tile_of(const camera *c, int tile) {
    render_grid g = render_grid_of(c->width, c->height);
    tile_box b;
    render_grid_tile(&g, c->width, c->height, tile, &b.x0, &b.y0, &b.x1, &b.y1);
    return b;
}

/* Tiles for a rank with `threads` threads: one per thread, fewer as the queue empties so the
 * last chunks spread over the ranks. */
static int chunk_size(int threads, int left) {
    int fair = (left + dist_size() - 1) / dist_size();
    int n = threads < fair ? threads : fair;
    return n < 1 ? 1 : n;
}

typedef struct queue {
    const scene *s;
    const render_job *job;
    render_state *st;
    int ntiles, next, done;
    int *todo, ntodo; /* the tiles to render (a resumed render skips those done), in order */
    int *per_rank; /* tiles rendered by each rank */
    progress prog;
} queue;

static void add_tiles_done(queue *q, int rank, const int *tiles, int n) {
    int64_t samples = 0;
    for (int i = 0; i < n; i++) {
        tile_box b = tile_of(&q->s->cam, tiles[i]);
        for (int y = b.y0; y < b.y1; y++)
            for (int x = b.x0; x < b.x1; x++)
                samples += render_pixel_spp(q->job, q->st->spp, (uint64_t)y * (uint64_t)q->s->cam.width + (uint64_t)x);
    }
    q->done += n;
    q->per_rank[rank] += n;
    progress_add(&q->prog, samples);
}

/* Rank 0: one message from a worker. */
static void serve(queue *q, MPI_Status *ms, int *finished) {
    int nbytes;
    MPI_Get_count(ms, MPI_BYTE, &nbytes);
    char *buf = dist_malloc(nbytes > 0 ? (size_t)nbytes : 1, DIST_PH_PIXELS);
    if (!buf) dist_die("out of memory in the tile queue (a message from a rank)");
    MPI_Recv(buf, nbytes, MPI_BYTE, ms->MPI_SOURCE, ms->MPI_TAG, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    g_bytes_pixel += (uint64_t)nbytes;
    int src = ms->MPI_SOURCE;
    const camera *c = &q->s->cam;
    if (ms->MPI_TAG == TAG_REQ) {
        int32_t threads;
        memcpy(&threads, buf, sizeof threads);
        int n = q->next < q->ntodo ? chunk_size(threads, q->ntodo - q->next) : 0;
        if (n > q->ntodo - q->next) n = q->ntodo - q->next;
        int32_t *reply = malloc((size_t)(n + 1) * sizeof *reply);
        if (!reply) dist_die("out of memory in the tile queue");
        reply[0] = n;
        for (int i = 0; i < n; i++) reply[1 + i] = q->todo[q->next++];
        MPI_Send(reply, (int)((size_t)(n + 1) * sizeof *reply), MPI_BYTE, src, TAG_ASSIGN,
                 MPI_COMM_WORLD);
        g_bytes_pixel += (uint64_t)(n + 1) * sizeof *reply;
        free(reply);
    } else if (ms->MPI_TAG == TAG_RESULT) {
        int32_t n;
        memcpy(&n, buf, sizeof n);
        size_t off = sizeof n;
        int *tiles = malloc((size_t)(n > 0 ? n : 1) * sizeof *tiles);
        if (!tiles) dist_die("out of memory in the tile queue");
        for (int i = 0; i < n; i++) {
            int32_t t;
            memcpy(&t, buf + off, sizeof t);
            off += 2 * sizeof t;
            tiles[i] = t;
            tile_box b = tile_of(c, t);
            for (int y = b.y0; y < b.y1; y++) {
                size_t p = (size_t)y * (size_t)c->width + (size_t)b.x0, w = (size_t)(b.x1 - b.x0);
                memcpy(q->st->sum + 3 * p, buf + off, 3 * w * sizeof(double));
                off += 3 * w * sizeof(double);
                for (size_t x = 0; x < w; x++) q->st->count[p + x] = render_pixel_spp(q->job, q->st->spp, p + x);
            }
        }
        add_tiles_done(q, src, tiles, n);
        free(tiles);
    } else if (ms->MPI_TAG == TAG_STATS) {
        uint64_t n;
        memcpy(&n, buf, sizeof n);
        size_t off = sizeof n;
        for (uint64_t i = 0; i < n; i++) {
            char name[NAME_MAX_LEN];
            uint64_t v;
            memcpy(name, buf + off, NAME_MAX_LEN);
            name[NAME_MAX_LEN - 1] = 0;
            memcpy(&v, buf + off + NAME_MAX_LEN, sizeof v);
            off += NAME_MAX_LEN + sizeof v;
            int id = stats_register(name);
            if (id >= 0) stat_add(id, v);
        }
        (*finished)++;
    } else if (ms->MPI_TAG == TAG_FAIL) {
        dist_report_fail(src, buf, nbytes);
    }
    free(buf);
}

/* Rank 0 of a partitioned render, while it waits for lookups: serve the tile queue. */
typedef struct root_ctx {
    queue *q;
    int *finished;
} root_ctx;

static int root_also(void *arg) {
    root_ctx *r = arg;
    int flag = 0, did = 0;
    MPI_Status ms;
    for (;;) {
        MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &ms);
        if (!flag) return did;
        serve(r->q, &ms, r->finished);
        did = 1;
    }
}

/* Rank 0 of a checkpointed render, between two chunks: a checkpoint or snapshot when one is
 * due, and on a signal (output.h defers it while a checkpoint is kept) the last checkpoint
 * and RENDER_INTERRUPTED. The test pause (PM_RENDER_TEST_PAUSE=render:F, output.h) writes a
 * checkpoint once F of the samples are done, then waits for a signal, so a test can stop the
 * job at a known point after a checkpoint exists. 0, RENDER_INTERRUPTED or on_pause's code. */
typedef struct pauses {
    const render_control *ctl;
    double due;       /* stats_now() time of the next periodic pause, or INFINITY */
    int64_t pause_at; /* samples done at which the test pause happens, or -1 */
} pauses;

static int root_pause(pauses *p, queue *q) {
    const render_control *ctl = p->ctl;
    if (!ctl->on_pause) return 0;
    int prc;
    if (p->pause_at >= 0 && atomic_load(&q->prog.done) >= p->pause_at) {
        p->pause_at = -1;
        if ((prc = ctl->on_pause(ctl->user, q->st, RENDER_PAUSE_SIGNAL)) < 0) return prc;
        out_test_pause("render");
    }
    if (ctl->stop_on_signal && out_pending_signal()) {
        prc = ctl->on_pause(ctl->user, q->st, RENDER_PAUSE_SIGNAL);
        return prc < 0 ? prc : RENDER_INTERRUPTED;
    }
    if (stats_now() >= p->due) {
        if ((prc = ctl->on_pause(ctl->user, q->st, RENDER_PAUSE_PERIODIC)) < 0) return prc;
        p->due = stats_now() + ctl->pause_every;
    }
    return 0;
}

/* A tile all of whose pixels have every sample. */
static int tile_complete(const render_job *job, const render_state *st, const camera *c, int tile) {
    tile_box b = tile_of(c, tile);
    for (int y = b.y0; y < b.y1; y++)
        for (int x = b.x0; x < b.x1; x++)
            if (st->count[(size_t)y * (size_t)c->width + (size_t)x] <
                render_pixel_spp(job, st->spp, (uint64_t)y * (uint64_t)c->width + (uint64_t)x))
                return 0;
    return 1;
}

/* Rank 0, after the pixel pass: the tiles each rank rendered and the bytes sent ("MPI:" lines
 * and statistics). */
static void root_report(const queue *q, int threads, uint64_t bytes_photon) {
    const camera *c = &q->s->cam;
    int size = dist_size();
    if (q->ntodo < q->ntiles)
        printf("MPI: resumed: %d of %d tiles were complete in the checkpoint\n",
               q->ntiles - q->ntodo, q->ntiles);
    printf("MPI: %d rank%s x %d thread%s; tiles rendered per rank:", size,
           size == 1 ? "" : "s", threads, threads == 1 ? "" : "s");
    for (int k = 0; k < size; k++) printf(" %d", q->per_rank[k]);
    printf(" (of %d)\n", q->ntodo);
    printf("MPI: bytes sent: photon exchange %llu, pixel pass %llu (%.2f per pixel)\n",
           (unsigned long long)bytes_photon, (unsigned long long)g_bytes_pixel,
           (double)g_bytes_pixel / ((double)c->width * c->height));
    stat_add(stats_register("MPI/Bytes sent in photon exchanges (all ranks)"), bytes_photon);
    stat_add(stats_register("MPI/Bytes sent in the pixel pass (all ranks)"), g_bytes_pixel);
    stat_add(stats_register("MPI/Tiles rendered by rank 0"), (uint64_t)q->per_rank[0]);
    if (lk_on()) {
        uint64_t nl = stats_total(stats_find("MPI/Partitioned: photon lookups sent (all ranks)"));
        uint64_t bl = stats_total(stats_find("MPI/Partitioned: bytes sent in photon lookups (all ranks)"));
        uint64_t ns = stats_total(stats_find("MPI/Partitioned: precomputed irradiance estimates"));
        uint64_t bs = stats_total(stats_find("MPI/Partitioned: bytes sent precomputing irradiance (all ranks)"));
        printf("MPI: partitioned maps: %llu lookups, %llu bytes (%.1f per lookup, %.2f per pixel); "
               "precomputed irradiance: %llu estimates, %llu bytes (%.1f per estimate)\n",
               (unsigned long long)nl, (unsigned long long)bl, nl ? (double)bl / (double)nl : 0.0,
               (double)bl / ((double)c->width * c->height), (unsigned long long)ns,
               (unsigned long long)bs, ns ? (double)bs / (double)ns : 0.0);
    }
}

int tq_root(const scene *s, const integrator *it, const render_job *job, render_state *st,
            const render_control *ctl, uint64_t bytes_photon) {
    const camera *c = &s->cam;
    int size = dist_size();
    queue q;
    memset(&q, 0, sizeof q);
    q.s = s;
    q.job = job;
    q.st = st;
    render_grid grid = render_grid_of(c->width, c->height);
    q.ntiles = grid.tiles_x * grid.tiles_y;
    q.per_rank = dist_calloc((size_t)size, sizeof *q.per_rank, DIST_PH_PIXELS);
    q.todo = dist_malloc((size_t)q.ntiles * sizeof *q.todo, DIST_PH_PIXELS);
    int threads = job->threads > 0 ? job->threads : 1;
    int *mine = dist_malloc((size_t)threads * sizeof *mine, DIST_PH_PIXELS);
    if (!q.per_rank || !mine || !q.todo) dist_die("out of memory in the tile queue");
    /* A resumed state: a tile is rendered again unless it is complete; a partly done one
     * (from render's checkpoint) starts over, which gives the same sums, since a pixel's
     * samples are added in sample order from 0 on one rank. */
    for (int t = 0; t < q.ntiles; t++) {
        if (tile_complete(job, st, c, t)) continue;
        q.todo[q.ntodo++] = t;
        tile_box b = tile_of(c, t);
        for (int y = b.y0; y < b.y1; y++) {
            size_t p = (size_t)y * (size_t)c->width + (size_t)b.x0, w = (size_t)(b.x1 - b.x0);
            memset(st->sum + 3 * p, 0, 3 * w * sizeof(double));
            memset(st->count + p, 0, w * sizeof(uint32_t));
        }
    }
    int64_t total = (int64_t)render_image_spp(job, c->spp, c->width, c->height);
    int64_t done = (int64_t)render_state_done(st);
    if (done > 0 && !job->quiet)
        fprintf(stderr, "Resuming: %lld of %lld samples done (%.1f%%)\n", (long long)done,
                (long long)total, 100.0 * (double)done / (double)total);
    progress_begin(&q.prog, "Rendering", total, job->quiet);
    if (done > 0) progress_resume(&q.prog, done);
    pauses pz = {ctl, INFINITY, -1};
    if (ctl && ctl->on_pause) {
        double frac = out_test_pause_fraction();
        if (frac >= 0 && done < (int64_t)(frac * (double)total)) pz.pause_at = (int64_t)(frac * (double)total);
        if (ctl->pause_every > 0) pz.due = stats_now() + ctl->pause_every;
    }
    int finished = 0, rc = 0, told = 0;
    root_ctx rctx = {&q, &finished};
    while (q.done < q.ntodo || finished < size - 1) {
        int flag = 1;
        MPI_Status ms;
        while (flag) {
            MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &flag, &ms);
            if (flag) serve(&q, &ms, &finished);
        }
        if (pz.ctl && (rc = root_pause(&pz, &q)) != 0) break;
        if (q.next < q.ntodo) {
            int n = chunk_size(threads, q.ntodo - q.next);
            for (int i = 0; i < n; i++) mine[i] = q.todo[q.next++];
            rc = lk_on() ? lk_render_tiles(s, it, job, st, mine, n, root_also, &rctx)
                         : render_tiles(s, it, job, st, mine, n);
            if (rc < 0) break;
            add_tiles_done(&q, 0, mine, n);
        } else if (lk_on() && !told) {
            /* No tiles left for rank 0: answer the others' lookups until they are done too. */
            lk_finish(root_also, &rctx);
            told = 1;
        } else if (q.done < q.ntodo || finished < size - 1) {
            if (lk_on()) {
                if (!root_also(&rctx)) lk_idle();
                continue;
            }
            MPI_Probe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &ms);
            serve(&q, &ms, &finished);
        }
    }
    if (rc == 0) {
        progress_end(&q.prog);
        root_report(&q, threads, bytes_photon);
    }
    free(q.per_rank);
    free(q.todo);
    free(mine);
    return rc;
}

/* A worker: the reply to its next request. In a partitioned render it answers the other ranks'
 * lookups while it waits. */
static void recv_assign(int32_t *assign, int maxn) {
    int bytes = (int)((size_t)(maxn + 1) * sizeof *assign);
    if (!lk_on()) {
        MPI_Recv(assign, bytes, MPI_BYTE, 0, TAG_ASSIGN, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        return;
    }
    for (;;) {
        int flag = 0;
        MPI_Iprobe(0, TAG_ASSIGN, MPI_COMM_WORLD, &flag, MPI_STATUS_IGNORE);
        if (flag) {
            MPI_Recv(assign, bytes, MPI_BYTE, 0, TAG_ASSIGN, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
            return;
        }
        if (!lk_poll()) lk_idle();
    }
}

/* A worker: ask, render, send, until the queue is empty; then the statistics. */
int tq_worker(const scene *s, const integrator *it, const render_job *job, render_state *st,
              const uint64_t *base) {
    const camera *c = &s->cam;
    int32_t threads = job->threads > 0 ? job->threads : 1;
    int maxn = threads;
    int32_t *assign = dist_malloc((size_t)(maxn + 1) * sizeof *assign, DIST_PH_PIXELS);
    char *out = NULL; /* the results of a chunk, while they are being sent */
    if (!assign) dist_die("out of memory in the tile queue (the tile list)");
    MPI_Request sent = MPI_REQUEST_NULL;
    int outstanding = 0;
    /* Test hook: PM_RENDER_MPI_TEST_SLOW="RANK SECONDS" makes that rank wait before each
     * chunk, so a test can check that the queue gives the slow rank fewer tiles. */
    double test_slow = 0;
    const char *slow = getenv("PM_RENDER_MPI_TEST_SLOW");
    int slow_rank;
    if (slow && sscanf(slow, "%d %lf", &slow_rank, &test_slow) != 2) test_slow = 0;
    if (slow && slow_rank != dist_rank()) test_slow = 0;
    for (int i = 0; i < 2; i++, outstanding++)
        MPI_Send(&threads, (int)sizeof threads, MPI_BYTE, 0, TAG_REQ, MPI_COMM_WORLD);
    for (;;) {
        recv_assign(assign, maxn);
        outstanding--;
        int n = assign[0];
        if (n == 0) break;
        /* Ask for the next chunk now, so it is here when this one is done. */
        MPI_Send(&threads, (int)sizeof threads, MPI_BYTE, 0, TAG_REQ, MPI_COMM_WORLD);
        outstanding++;
        if (test_slow > 0) {
            struct timespec ts = {(time_t)test_slow, (long)((test_slow - (double)(time_t)test_slow) * 1e9)};
            nanosleep(&ts, NULL);
        }
        int rc = lk_on() ? lk_render_tiles(s, it, job, st, assign + 1, n, NULL, NULL)
                         : render_tiles(s, it, job, st, assign + 1, n);
        if (rc < 0) return rc;
        MPI_Wait(&sent, MPI_STATUS_IGNORE); /* the previous results have left `out` */
        free(out);
        size_t cap = sizeof(int32_t) + (size_t)n * (2 * sizeof(int32_t) +
                     (size_t)RENDER_TILE * RENDER_TILE * 3 * sizeof(double));
        if (!(out = dist_malloc(cap, DIST_PH_PIXELS))) {
            char what[160];
            snprintf(what, sizeof what, "out of memory in the pixel pass (%zu bytes for the "
                     "results of %d tiles)", cap, n);
            dist_die(what);
        }
        int32_t n32 = n;
        size_t off = 0;
        memcpy(out, &n32, sizeof n32);
        off += sizeof n32;
        for (int i = 0; i < n; i++) {
            int32_t t[2] = {assign[1 + i], 0};
            memcpy(out + off, t, sizeof t);
            off += sizeof t;
            tile_box b = tile_of(c, t[0]);
            for (int y = b.y0; y < b.y1; y++) {
                size_t p = (size_t)y * (size_t)c->width + (size_t)b.x0, w = (size_t)(b.x1 - b.x0);
                memcpy(out + off, st->sum + 3 * p, 3 * w * sizeof(double));
                off += 3 * w * sizeof(double);
            }
        }
        MPI_Isend(out, (int)off, MPI_BYTE, 0, TAG_RESULT, MPI_COMM_WORLD, &sent);
    }
    while (outstanding-- > 0) recv_assign(assign, maxn);
    MPI_Wait(&sent, MPI_STATUS_IGNORE);
    if (lk_on()) lk_finish(NULL, NULL); /* the others may still need this rank's photons */
    /* The pixel pass's counters: what this rank added since the pass began. */
    char *sbuf = dist_malloc(sizeof(uint64_t) + STATS_MAX * (NAME_MAX_LEN + sizeof(uint64_t)), DIST_PH_PIXELS);
    if (!sbuf) dist_die("out of memory in the pixel pass (the statistics)");
    uint64_t ns = 0;
    size_t off = sizeof ns;
    for (int id = 0; id < STATS_MAX; id++) {
        const char *name = stats_name(id);
        uint64_t d = name ? stats_total(id) - base[id] : 0;
        if (!d) continue;
        memset(sbuf + off, 0, NAME_MAX_LEN);
        snprintf(sbuf + off, NAME_MAX_LEN, "%s", name);
        memcpy(sbuf + off + NAME_MAX_LEN, &d, sizeof d);
        off += NAME_MAX_LEN + sizeof d;
        ns++;
    }
    memcpy(sbuf, &ns, sizeof ns);
    MPI_Send(sbuf, (int)off, MPI_BYTE, 0, TAG_STATS, MPI_COMM_WORLD);
    free(sbuf);
    free(assign);
    free(out);
    return 0;
}
