/* dist.c: the MPI side of render-mpi: the start agreement, the photon exchange, the tile
 * queue and the film gathering, failures; see dist.h.
 *
 * Only the main thread calls MPI (MPI_THREAD_FUNNELED): OpenMP threads work inside
 * render_tiles and the photon batches, between MPI calls.
 *
 * Messages of the pixel pass (all through rank 0, which counts their bytes):
 *   REQ     worker -> 0   int32 threads: "give me one more chunk"
 *   ASSIGN  0 -> worker   int32 n, then n tile indices (n = 0: the queue is empty)
 *   RESULT  worker -> 0   int32 n, then per tile: int32 tile, int32 0, the tile's pixel sums
 *                         (3 doubles each, rows of the tile clipped to the image)
 *   STATS   worker -> 0   the worker's pixel-pass counters (name, value), its last message
 *   FAIL    worker -> 0   int32 status, then its message
 * A worker keeps one request ahead (two at the start), so the next chunk is already there
 * when it finishes one; replies to one worker come in the order of its requests, so after
 * the first empty ASSIGN every later reply is empty too. REQ is small, so it travels
 * eagerly even while a large RESULT waits for its receiver.
 */
#include "dist.h"
#include "lookup.h"

#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <mpi.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "run/checkpoint.h"
#include "base/output.h"
#include "photonmap/common.h"
#include "photons/photon_trace.h"
#include "base/progress.h"
#include "base/stats.h"
#include "photons/volume.h"

enum { TAG_REQ = 101, TAG_ASSIGN, TAG_RESULT, TAG_STATS, TAG_FAIL };
#define MSG_MAX 1024
#define NAME_MAX_LEN 80

static int g_rank, g_size, g_mode;
static int g_stage;      /* 0: before dist_start; 1: agreed, rendering; 2: film gathered */
static int g_real_err = 2; /* ranks > 0: the stderr they were started with */
static uint64_t g_bytes_photon, g_bytes_pixel; /* rank 0: bytes sent by all ranks */
static trace_dist g_td;
static struct sigaction g_old_term, g_old_int;

int dist_rank(void) { return g_rank; }
int dist_size(void) { return g_size; }

/* The last lines this rank wrote to its (captured) stderr: its own failure message. */
static void captured_tail(char *out, size_t cap) {
    out[0] = 0;
    if (g_rank == 0) return;
    fflush(stderr);
    struct stat sb;
    if (fstat(2, &sb) < 0 || sb.st_size <= 0) return;
    off_t from = sb.st_size > (off_t)(cap - 1) ? sb.st_size - (off_t)(cap - 1) : 0;
    ssize_t n = pread(2, out, cap - 1, from);
    if (n <= 0) return;
    out[n] = 0;
    while (n > 0 && (out[n - 1] == '\n' || out[n - 1] == ' ')) out[--n] = 0;
    char *start = out;
    if (from > 0 && strchr(out, '\n')) start = strchr(out, '\n') + 1; /* whole lines only */
    memmove(out, start, strlen(start) + 1);
}

/* ---- failures after the agreement --------------------------------------------------------
 *
 * A rank that fails once the ranks agreed to render (an allocation, or render_main's own
 * error) does not stop the job itself: it sends its message to rank 0 (TAG_FAIL), and rank 0,
 * which listens for it wherever it waits (the tile queue, the photon exchange, and
 * dist_poll_fail in other waits), prints "rank K of N failed (status S): what" and stops every
 * rank (MPI_Abort: non-zero exit; nothing is written, since rank 0 writes only at the end).
 * The failing rank then waits; if the job is still running after FAIL_GRACE seconds (rank 0
 * blocked where it does not listen), it says so on its own stderr and stops the job itself.
 * Rank 0's own failures and failures before the agreement stop the job at once. */
#define FAIL_GRACE 30

static void say_real(const char *line) {
    size_t n = strlen(line);
    if (write(g_real_err, line, n) < 0) {
        /* nothing more to do: the abort that follows still stops the job */
    }
}

static void fail_to_root(int status, const char *what) {
    char line[MSG_MAX + 160];
    if (g_rank == 0 || g_stage == 0) {
        snprintf(line, sizeof line, "render-mpi: rank %d of %d failed: %s; stopping every rank, "
                 "nothing is written\n", g_rank, g_size, what);
        fflush(stderr);
        say_real(line);
        MPI_Abort(MPI_COMM_WORLD, status > 0 ? status : 1);
        _exit(1);
    }
    char buf[sizeof(int32_t) + MSG_MAX];
    int32_t st = status > 0 ? status : 1;
    memcpy(buf, &st, sizeof st);
    snprintf(buf + sizeof st, MSG_MAX, "%s", what && what[0] ? what : "(no message)");
    MPI_Request r;
    MPI_Isend(buf, (int)(sizeof st + strlen(buf + sizeof st) + 1), MPI_BYTE, 0, TAG_FAIL,
              MPI_COMM_WORLD, &r);
    for (int i = 0; i < FAIL_GRACE * 20; i++) {
        int done;
        MPI_Test(&r, &done, MPI_STATUS_IGNORE);
        struct timespec ts = {0, 50 * 1000 * 1000};
        nanosleep(&ts, NULL);
    }
    snprintf(line, sizeof line, "render-mpi: rank %d of %d failed: %s; rank 0 did not stop the "
             "job within %d s, stopping it from here; nothing is written\n", g_rank, g_size,
             buf + sizeof st, FAIL_GRACE);
    say_real(line);
    MPI_Abort(MPI_COMM_WORLD, st);
    _exit(1);
}

static void die_now(const char *what) { fail_to_root(1, what); }

/* Rank 0: a worker's TAG_FAIL message (status, then text): say it and stop the job. */
static void root_report_fail(int src, char *buf, int nbytes) {
    int32_t st = 1;
    if (nbytes >= (int)sizeof st) memcpy(&st, buf, sizeof st);
    if (nbytes > 0) buf[nbytes - 1] = 0;
    fprintf(stderr, "render-mpi: rank %d of %d failed (status %d): %s\n", src, g_size, (int)st,
            nbytes > (int)sizeof st ? buf + sizeof st : "(no message)");
    fprintf(stderr, "render-mpi: stopping every rank; nothing was written\n");
    fflush(stderr);
    MPI_Abort(MPI_COMM_WORLD, st > 0 ? st : 1);
    _exit(1);
}

void dist_poll_fail(void) {
    if (g_rank != 0 || g_stage == 0) return;
    int flag = 0;
    MPI_Status ms;
    MPI_Iprobe(MPI_ANY_SOURCE, TAG_FAIL, MPI_COMM_WORLD, &flag, &ms);
    if (!flag) return;
    int nbytes;
    MPI_Get_count(&ms, MPI_BYTE, &nbytes);
    char buf[sizeof(int32_t) + MSG_MAX];
    if (nbytes > (int)sizeof buf) nbytes = (int)sizeof buf;
    MPI_Recv(buf, (int)sizeof buf, MPI_BYTE, ms.MPI_SOURCE, TAG_FAIL, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    root_report_fail(ms.MPI_SOURCE, buf, nbytes);
}

/* Wait for a request; rank 0 listens for the others' failures meanwhile. */
static void wait_listening(MPI_Request *r) {
    if (g_rank != 0) {
        MPI_Wait(r, MPI_STATUS_IGNORE);
        return;
    }
    for (unsigned spins = 0;; spins++) {
        int done = 0;
        MPI_Test(r, &done, MPI_STATUS_IGNORE);
        if (done) return;
        dist_poll_fail();
        if (spins > 1000) { /* a long wait: let the other ranks have the core */
            struct timespec ts = {0, 100 * 1000};
            nanosleep(&ts, NULL);
        }
    }
}
void dist_wait(MPI_Request *r) { wait_listening(r); }

/* Test hook: PM_RENDER_MPI_TEST_ENOMEM="RANK PHASE N" (PHASE: photons, pixels, irradiance or
 * tracer) makes the N-th allocation that dist.c makes, or asks for, on that rank in that phase
 * fail as if malloc returned NULL. Photons: per exchange, the sizes, counts, offsets, then the
 * receive buffer; pixels: on a worker the render state, the counters' base, the tile list,
 * then one result buffer per chunk, and the counters; on rank 0 the queue's three arrays, then
 * one buffer per message received; irradiance: the allocations of lookup.c's partitioned
 * precomputed-irradiance build, in its order (dist_irr_malloc: lookup.c's hook_side_build);
 * tracer: the photon tracer's own, one per batch this rank traces in a distributed pass (the
 * rounds' batches, then in a partitioned pass those traced again; trace_dist.test_fail in
 * photon_trace.h), the batch failing as if the tracer's buffer could not grow. */
enum { PH_PHOTONS, PH_PIXELS, PH_IRRADIANCE, PH_TRACER };
static int test_enomem(int phase) {
    static int parsed, rank = -1, ph = -1;
    static long nth, count[4];
    if (!parsed) {
        parsed = 1;
        const char *v = getenv("PM_RENDER_MPI_TEST_ENOMEM");
        char name[16];
        if (v && sscanf(v, "%d %15s %ld", &rank, name, &nth) == 3)
            ph = strcmp(name, "photons") == 0      ? PH_PHOTONS
                 : strcmp(name, "pixels") == 0     ? PH_PIXELS
                 : strcmp(name, "irradiance") == 0 ? PH_IRRADIANCE
                 : strcmp(name, "tracer") == 0     ? PH_TRACER
                                                   : -1;
    }
    if (rank != g_rank || ph != phase) return 0;
    return ++count[phase] == nth;
}
static void *dmalloc(size_t n, int phase) { return test_enomem(phase) ? NULL : malloc(n); }
static void *dcalloc(size_t n, size_t m, int phase) { return test_enomem(phase) ? NULL : calloc(n, m); }
void *dist_irr_malloc(size_t n) { return dmalloc(n, PH_IRRADIANCE); }
void *dist_irr_calloc(size_t n, size_t m) { return dcalloc(n, m, PH_IRRADIANCE); }

/* Rank 0, when mpirun stops the job (a rank died or the job was cancelled) or the user
 * interrupts: say so, then let main.c's handler (output.h: remove temporaries) end us. */
static void on_stop(int sig) {
    static const char m[] = "render-mpi: rank 0: the job is being stopped before the image was "
                            "complete (a rank died, or the job was cancelled); no output is "
                            "written\n";
    ssize_t r = write(2, m, sizeof m - 1);
    (void)r;
    struct sigaction *old = sig == SIGTERM ? &g_old_term : &g_old_int;
    if (old->sa_handler == SIG_IGN || old->sa_handler == SIG_DFL) signal(sig, SIG_DFL);
    else sigaction(sig, old, NULL);
    raise(sig); /* delivered when this handler returns */
}

typedef struct start_msg {
    int rc; /* 0 ready to render, > 0 failed with this status, -1 finished without rendering */
    int mode; /* DIST_* */
    char msg[MSG_MAX];
} start_msg;

/* The agreement (see dist.h). Returns when every rank is ready to render, or every rank
 * finished without rendering (*all_done = 1); otherwise exits with the failing status. */
static void dist_start(int rc, const char *msg, int *all_done) {
    if (all_done) *all_done = 0;
    if (g_stage > 0) return;
    start_msg m;
    memset(&m, 0, sizeof m);
    m.rc = rc;
    m.mode = g_mode;
    snprintf(m.msg, sizeof m.msg, "%s", msg ? msg : "");
    start_msg *all = g_rank == 0 ? calloc((size_t)g_size, sizeof *all) : NULL;
    if (g_rank == 0 && !all) die_now("out of memory");
    MPI_Gather(&m, (int)sizeof m, MPI_BYTE, all, (int)sizeof m, MPI_BYTE, 0, MPI_COMM_WORLD);
    int verdict = 0; /* > 0: exit with it; -1: all finished; 0: render */
    if (g_rank == 0) {
        int failed = 0, finished = 0, ready = 0;
        for (int k = 0; k < g_size; k++) {
            if (all[k].rc > 0 && !verdict) verdict = all[k].rc;
            failed += all[k].rc > 0;
            finished += all[k].rc < 0;
            ready += all[k].rc == 0;
        }
        /* Rank 0 said its own error already; the others' follow, each text once. */
        for (int k = 1; k < g_size; k++) {
            if (all[k].rc <= 0 || (all[0].rc > 0 && all[0].rc == all[k].rc)) continue;
            int seen = 0;
            for (int j = 1; j < k; j++) seen |= all[j].rc > 0 && strcmp(all[j].msg, all[k].msg) == 0;
            if (seen) continue;
            fprintf(stderr, "render-mpi: rank %d", k);
            for (int j = k + 1; j < g_size; j++)
                if (all[j].rc > 0 && strcmp(all[j].msg, all[k].msg) == 0) fprintf(stderr, ", %d", j);
            fprintf(stderr, " of %d could not start (status %d): %s\n", g_size, all[k].rc,
                    all[k].msg[0] ? all[k].msg : "(no message)");
        }
        /* Ranks given different commands (mpirun's MPMD form): some rendered and some did not,
         * or the modes differ. Rank 0 names the ranks that differ from rank 0. */
        int partitioned = 0;
        for (int k = 0; k < g_size; k++) partitioned += all[k].mode == DIST_PARTITIONED;
        int odd_run = !verdict && finished && ready, odd_mode = !verdict && ready && partitioned &&
                                                                partitioned < g_size;
        if (odd_run || odd_mode) {
            int nodd = 0, n = 0; /* the ranks that differ from rank 0 */
            for (int pass = 0; pass < 2; pass++) {
                if (pass) fprintf(stderr, "render-mpi: the ranks were given different commands: "
                                  "rank%s", nodd > 1 ? "s" : "");
                for (int k = 1; k < g_size; k++) {
                    if (odd_run ? (all[k].rc < 0) == (all[0].rc < 0) : all[k].mode == all[0].mode)
                        continue;
                    if (pass) fprintf(stderr, "%s %d", n++ ? "," : "", k);
                    else nodd++;
                }
            }
            const char *what[2][2] = {{"rendered", "finished without rendering"},
                                      {"replicated maps", "--pm distributed=partitioned"}};
            int kind = odd_run ? 0 : 1, r0 = odd_run ? all[0].rc < 0 : all[0].mode == DIST_PARTITIONED;
            fprintf(stderr, " of %d: %s; rank 0: %s\n", g_size, what[kind][!r0], what[kind][r0]);
            verdict = 2;
        } else if (!verdict && finished) {
            verdict = -1;
        }
        if (verdict > 0 && failed)
            fprintf(stderr, "render-mpi: stopped before rendering: %d of %d rank%s could not start; "
                    "nothing was written\n", failed, g_size, g_size == 1 ? "" : "s");
        else if (verdict > 0)
            fprintf(stderr, "render-mpi: stopped before rendering; nothing was written\n");
        free(all);
    }
    MPI_Bcast(&verdict, 1, MPI_INT, 0, MPI_COMM_WORLD);
    if (verdict > 0) {
        MPI_Finalize();
        exit(verdict);
    }
    if (verdict < 0) {
        if (all_done) *all_done = 1;
        return;
    }
    g_stage = 1;
    if (g_rank == 0) {
        struct sigaction sa;
        memset(&sa, 0, sizeof sa);
        sa.sa_handler = on_stop;
        sigemptyset(&sa.sa_mask);
        sigaction(SIGTERM, &sa, &g_old_term);
        sigaction(SIGINT, &sa, &g_old_int);
    }
}

void dist_fail_early(int rc, const char *msg) {
    if (g_rank == 0 && msg) fprintf(stderr, "%s\n", msg);
    dist_start(rc, msg, NULL);
    /* Not reached when rc > 0: dist_start exits with the status. */
    MPI_Finalize();
    exit(rc);
}

int dist_finish(int rc) {
    char tail[MSG_MAX];
    captured_tail(tail, sizeof tail);
    if (g_stage == 0) {
        int done;
        dist_start(rc ? rc : -1, tail, &done); /* exits unless every rank finished */
        MPI_Finalize();
        return rc;
    }
    if (g_stage == 1) {
        if (g_rank == 0) {
            fprintf(stderr, "render-mpi: rank 0 of %d failed (status %d; its message is above); "
                    "stopping every rank; nothing was written\n", g_size, rc > 0 ? rc : 1);
            fflush(stderr);
            MPI_Abort(MPI_COMM_WORLD, rc > 0 ? rc : 1);
        } else {
            fail_to_root(rc > 0 ? rc : 1, tail); /* rank 0 says it and stops the job */
        }
    }
    MPI_Finalize();
    return rc;
}

/* ---- photon pass ---------------------------------------------------------------------- */

static int photon_allgather(void *user, const void *mine, size_t nbytes, void **all, size_t *sizes) {
    (void)user;
    dist_start(0, NULL, NULL);
    unsigned long long n = nbytes, *ns = dmalloc((size_t)g_size * sizeof *ns, PH_PHOTONS);
    int *cnt = dmalloc((size_t)g_size * sizeof *cnt, PH_PHOTONS);
    int *dsp = dmalloc((size_t)g_size * sizeof *dsp, PH_PHOTONS);
    if (!ns || !cnt || !dsp) die_now("out of memory in the photon exchange (its counts)");
    /* Non-blocking, so that rank 0 hears a rank that failed instead of waiting for it. */
    MPI_Request r;
    MPI_Iallgather(&n, 1, MPI_UNSIGNED_LONG_LONG, ns, 1, MPI_UNSIGNED_LONG_LONG, MPI_COMM_WORLD, &r);
    wait_listening(&r);
    unsigned long long total = 0;
    for (int k = 0; k < g_size; k++) {
        if (total > (unsigned long long)INT_MAX) break;
        cnt[k] = (int)ns[k];
        dsp[k] = (int)total;
        total += ns[k];
    }
    if (total > (unsigned long long)INT_MAX)
        die_now("a photon round exceeds 2 GiB (MPI's int counts)");
    char *buf = dmalloc(total ? (size_t)total : 1, PH_PHOTONS);
    if (!buf) {
        char what[128];
        snprintf(what, sizeof what, "out of memory in the photon exchange (%llu bytes for a round)",
                 total);
        die_now(what);
    }
    MPI_Iallgatherv(mine, (int)n, MPI_BYTE, buf, cnt, dsp, MPI_BYTE, MPI_COMM_WORLD, &r);
    wait_listening(&r);
    for (int k = 0; k < g_size; k++) sizes[k] = (size_t)ns[k];
    g_bytes_photon += total * (unsigned long long)(g_size - 1); /* each part goes to the others */
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
    dist_start(0, NULL, NULL);
    die_now(what);
}
static int tracer_test_fail(void *user) {
    (void)user;
    return test_enomem(PH_TRACER);
}

void dist_collective_begin(void) { dist_start(0, NULL, NULL); }
void dist_die(const char *what) { die_now(what); }

void dist_init(int mode) {
    MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
    MPI_Comm_size(MPI_COMM_WORLD, &g_size);
    g_mode = mode;
    if (g_rank > 0) {
        /* Quiet ranks: stdout discarded, stderr kept for the failure message. */
        fflush(stdout);
        fflush(stderr);
        int devnull = open("/dev/null", O_WRONLY);
        if (devnull >= 0) {
            dup2(devnull, 1);
            close(devnull);
        }
        g_real_err = dup(2);
        FILE *cap = tmpfile();
        if (cap && g_real_err >= 0) dup2(fileno(cap), 2);
        else g_real_err = 2;
    }
    g_td.nparts = g_size;
    g_td.part = g_rank;
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
    if (mode == DIST_PARTITIONED) lk_init(g_rank, g_size, lk_comm);
    else MPI_Comm_free(&lk_comm);
    /* Checkpoints: rank 0 writes them. A replicated render's image is render's, so are its
     * checkpoints; a partitioned one depends on the number of parts, and its maps cannot be
     * saved whole (they are traced again on resume). */
    char extra[64] = "";
    if (mode == DIST_PARTITIONED)
        snprintf(extra, sizeof extra, "; distributed partitioned over %d ranks", g_size);
    ckpt_set_distributed(g_rank == 0, extra, mode == DIST_PARTITIONED);
    if (mode == DIST_PARTITIONED) { /* only the same number of ranks resumes it */
        char cmd[64];
        snprintf(cmd, sizeof cmd, "mpirun -np %d render-mpi", g_size);
        ckpt_set_resume_command(cmd);
    }
}

/* ---- pixel pass ----------------------------------------------------------------------- */

typedef struct tile_box {
    int x0, y0, x1, y1;
} tile_box;

static tile_box tile_of(const camera *c, int tile) {
    int tx = (c->width + RENDER_TILE - 1) / RENDER_TILE;
    tile_box b;
    b.x0 = (tile % tx) * RENDER_TILE;
    b.y0 = (tile / tx) * RENDER_TILE;
    b.x1 = b.x0 + RENDER_TILE < c->width ? b.x0 + RENDER_TILE : c->width;
    b.y1 = b.y0 + RENDER_TILE < c->height ? b.y0 + RENDER_TILE : c->height;
    return b;
}

static int tile_pixels(const camera *c, int tile) {
    tile_box b = tile_of(c, tile);
    return (b.x1 - b.x0) * (b.y1 - b.y0);
}

/* Tiles for a rank with `threads` threads: one per thread, fewer as the queue empties so the
 * last chunks spread over the ranks. */
static int chunk_size(int threads, int left) {
    int fair = (left + g_size - 1) / g_size;
    int n = threads < fair ? threads : fair;
    return n < 1 ? 1 : n;
}

typedef struct queue {
    const scene *s;
    render_state *st;
    int ntiles, next, done;
    int *todo, ntodo; /* the tiles to render (a resumed render skips those done), in order */
    int *per_rank; /* tiles rendered by each rank */
    progress prog;
} queue;

static void add_tiles_done(queue *q, int rank, const int *tiles, int n) {
    int64_t samples = 0;
    for (int i = 0; i < n; i++) samples += (int64_t)tile_pixels(&q->s->cam, tiles[i]) * q->st->spp;
    q->done += n;
    q->per_rank[rank] += n;
    progress_add(&q->prog, samples);
}

/* Rank 0: one message from a worker. */
static void serve(queue *q, MPI_Status *ms, int *finished) {
    int nbytes;
    MPI_Get_count(ms, MPI_BYTE, &nbytes);
    char *buf = dmalloc(nbytes > 0 ? (size_t)nbytes : 1, PH_PIXELS);
    if (!buf) die_now("out of memory in the tile queue (a message from a rank)");
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
        if (!reply) die_now("out of memory in the tile queue");
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
        if (!tiles) die_now("out of memory in the tile queue");
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
                for (size_t x = 0; x < w; x++) q->st->count[p + x] = (uint32_t)q->st->spp;
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
        root_report_fail(src, buf, nbytes);
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
static int tile_complete(const render_state *st, const camera *c, int tile) {
    tile_box b = tile_of(c, tile);
    for (int y = b.y0; y < b.y1; y++)
        for (int x = b.x0; x < b.x1; x++)
            if (st->count[(size_t)y * (size_t)c->width + (size_t)x] < (uint32_t)st->spp) return 0;
    return 1;
}

static int render_root(const scene *s, const integrator *it, const render_job *job,
                       render_state *st, const render_control *ctl) {
    const camera *c = &s->cam;
    queue q;
    memset(&q, 0, sizeof q);
    q.s = s;
    q.st = st;
    int tx = (c->width + RENDER_TILE - 1) / RENDER_TILE;
    q.ntiles = tx * ((c->height + RENDER_TILE - 1) / RENDER_TILE);
    q.per_rank = dcalloc((size_t)g_size, sizeof *q.per_rank, PH_PIXELS);
    q.todo = dmalloc((size_t)q.ntiles * sizeof *q.todo, PH_PIXELS);
    int threads = job->threads > 0 ? job->threads : 1;
    int *mine = dmalloc((size_t)threads * sizeof *mine, PH_PIXELS);
    if (!q.per_rank || !mine || !q.todo) die_now("out of memory in the tile queue");
    /* A resumed state: a tile is rendered again unless it is complete; a partly done one
     * (from render's checkpoint) starts over, which gives the same sums, since a pixel's
     * samples are added in sample order from 0 on one rank. */
    for (int t = 0; t < q.ntiles; t++) {
        if (tile_complete(st, c, t)) continue;
        q.todo[q.ntodo++] = t;
        tile_box b = tile_of(c, t);
        for (int y = b.y0; y < b.y1; y++) {
            size_t p = (size_t)y * (size_t)c->width + (size_t)b.x0, w = (size_t)(b.x1 - b.x0);
            memset(st->sum + 3 * p, 0, 3 * w * sizeof(double));
            memset(st->count + p, 0, w * sizeof(uint32_t));
        }
    }
    int64_t total = (int64_t)c->width * c->height * c->spp, done = (int64_t)render_state_done(st);
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
    while (q.done < q.ntodo || finished < g_size - 1) {
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
        } else if (q.done < q.ntodo || finished < g_size - 1) {
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
        if (q.ntodo < q.ntiles)
            printf("MPI: resumed: %d of %d tiles were complete in the checkpoint\n",
                   q.ntiles - q.ntodo, q.ntiles);
        printf("MPI: %d rank%s x %d thread%s; tiles rendered per rank:", g_size,
               g_size == 1 ? "" : "s", threads, threads == 1 ? "" : "s");
        for (int k = 0; k < g_size; k++) printf(" %d", q.per_rank[k]);
        printf(" (of %d)\n", q.ntodo);
        printf("MPI: bytes sent: photon exchange %llu, pixel pass %llu (%.2f per pixel)\n",
               (unsigned long long)g_bytes_photon, (unsigned long long)g_bytes_pixel,
               (double)g_bytes_pixel / ((double)c->width * c->height));
        stat_add(stats_register("MPI/Bytes sent in photon exchanges (all ranks)"), g_bytes_photon);
        stat_add(stats_register("MPI/Bytes sent in the pixel pass (all ranks)"), g_bytes_pixel);
        stat_add(stats_register("MPI/Tiles rendered by rank 0"), (uint64_t)q.per_rank[0]);
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
static int render_worker(const scene *s, const integrator *it, const render_job *job,
                         render_state *st, const uint64_t *base) {
    const camera *c = &s->cam;
    int32_t threads = job->threads > 0 ? job->threads : 1;
    int maxn = threads;
    int32_t *assign = dmalloc((size_t)(maxn + 1) * sizeof *assign, PH_PIXELS);
    char *out = NULL; /* the results of a chunk, while they are being sent */
    if (!assign) die_now("out of memory in the tile queue (the tile list)");
    MPI_Request sent = MPI_REQUEST_NULL;
    int outstanding = 0;
    /* Test hook: PM_RENDER_MPI_TEST_SLOW="RANK SECONDS" makes that rank wait before each
     * chunk, so a test can check that the queue gives the slow rank fewer tiles. */
    double test_slow = 0;
    const char *slow = getenv("PM_RENDER_MPI_TEST_SLOW");
    int slow_rank;
    if (slow && sscanf(slow, "%d %lf", &slow_rank, &test_slow) != 2) test_slow = 0;
    if (slow && slow_rank != g_rank) test_slow = 0;
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
        if (!(out = dmalloc(cap, PH_PIXELS))) {
            char what[160];
            snprintf(what, sizeof what, "out of memory in the pixel pass (%zu bytes for the "
                     "results of %d tiles)", cap, n);
            die_now(what);
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
    char *sbuf = dmalloc(sizeof(uint64_t) + STATS_MAX * (NAME_MAX_LEN + sizeof(uint64_t)), PH_PIXELS);
    if (!sbuf) die_now("out of memory in the pixel pass (the statistics)");
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

/* One distributed image. in_passes 0: the whole render (workers end here); 1: one pass of a
 * render in passes (dist.h): every rank returns, the workers with a black film. */
static int dist_image(const scene *s, const integrator *it, const render_job *job,
                      const render_control *ctl, film *out, int in_passes) {
    dist_start(0, NULL, NULL);
    lk_begin(s); /* before this rank answers another's photon lookups */
    const camera *c = &s->cam;
    /* Rank 0 renders into the caller's state (a checkpointed or resumed render: checkpoints
     * are written from it), the workers into their own. */
    render_state own, *st = &own;
    int rc;
    if (g_rank == 0 && ctl && ctl->state) {
        st = ctl->state;
        if (st->width != c->width || st->height != c->height || st->spp != c->spp) return PM_EINVAL;
    } else if ((rc = test_enomem(PH_PIXELS) ? PM_ENOMEM
                                            : render_state_init(&own, c->width, c->height, c->spp)) < 0) {
        return rc; /* main.c says it; dist_finish sends it to rank 0 */
    }
    double t0 = stats_now();
    if (g_rank == 0) {
        rc = render_root(s, it, job, st, ctl);
        if (rc >= 0 && film_init(out, c->width, c->height) < 0) rc = PM_ENOMEM;
        if (rc >= 0) render_state_to_film(st, out);
        if (st == &own) render_state_free(&own);
        stats_time_add("Time/Rendering", stats_now() - t0);
        if (rc == 0 && !in_passes) g_stage = 2;
        return rc;
    }
    uint64_t *base = dcalloc(STATS_MAX, sizeof *base, PH_PIXELS);
    if (!base) {
        render_state_free(&own);
        return PM_ENOMEM;
    }
    for (int id = 0; id < STATS_MAX; id++) base[id] = stats_total(id);
    rc = render_worker(s, it, job, &own, base);
    free(base);
    render_state_free(&own);
    if (rc < 0) return rc;
    if (in_passes) return film_init(out, c->width, c->height); /* rank 0 has the pass's tiles */
    /* Done: rank 0 has this rank's tiles and statistics, and writes the image. */
    g_stage = 2;
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
    dist_start(0, NULL, NULL);
    int32_t v = go;
    MPI_Request r;
    MPI_Ibcast(&v, 1, MPI_INT32_T, 0, MPI_COMM_WORLD, &r);
    wait_listening(&r);
    return v != 0;
}

int dist_partitioned(void) { return g_mode == DIST_PARTITIONED; }

void dist_passes_end(int rc) {
    if (rc < 0) return; /* main.c says it; dist_finish stops the job */
    if (g_rank == 0) {
        g_stage = 2;
        return;
    }
    g_stage = 2;
    fflush(stdout);
    MPI_Finalize();
    exit(0);
}
