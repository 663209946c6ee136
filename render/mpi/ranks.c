/* ranks.c: the base of render-mpi (ranks.h): which rank this is, the ranks' agreement before
 * the first collective step, the failures after it (a rank's message to rank 0, which says it
 * and stops the job; dist.h, FAILURES), rank 0's words when mpirun stops the job, and the test
 * hook that makes an allocation fail. The photon exchange and the image loop (dist.c,
 * tile_queue.c) and the partitioned lookups (lookup.c and its lk_*.c) build on it.
 */
#include "ranks.h"

#include <fcntl.h>
#include <mpi.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define MSG_MAX 1024

static int g_rank, g_size, g_mode;
static int g_stage;      /* 0: before dist_start; 1: agreed, rendering; 2: film gathered */
static int g_real_err = 2; /* ranks > 0: the stderr they were started with */
static struct sigaction g_old_term, g_old_int;

int dist_rank(void) { return g_rank; }
int dist_size(void) { return g_size; }
int dist_partitioned(void) { return g_mode == DIST_PARTITIONED; }

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
 * error) does not stop the job itself: it sends its message to rank 0 (DIST_TAG_FAIL), and
 * rank 0, which listens for it wherever it waits (the tile queue, the photon exchange, and
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
    MPI_Isend(buf, (int)(sizeof st + strlen(buf + sizeof st) + 1), MPI_BYTE, 0, DIST_TAG_FAIL,
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

void dist_die(const char *what) { fail_to_root(1, what); }

/* Rank 0: a worker's DIST_TAG_FAIL message (status, then text): say it and stop the job. */
void dist_report_fail(int src, char *buf, int nbytes) {
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
    MPI_Iprobe(MPI_ANY_SOURCE, DIST_TAG_FAIL, MPI_COMM_WORLD, &flag, &ms);
    if (!flag) return;
    int nbytes;
    MPI_Get_count(&ms, MPI_BYTE, &nbytes);
    char buf[sizeof(int32_t) + MSG_MAX];
    if (nbytes > (int)sizeof buf) nbytes = (int)sizeof buf;
    MPI_Recv(buf, (int)sizeof buf, MPI_BYTE, ms.MPI_SOURCE, DIST_TAG_FAIL, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    dist_report_fail(ms.MPI_SOURCE, buf, nbytes);
}

void dist_wait(MPI_Request *r) {
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

/* Test hook: PM_RENDER_MPI_TEST_ENOMEM="RANK PHASE N" (PHASE: photons, pixels, irradiance or
 * tracer) makes the N-th allocation that render/mpi makes, or asks for, on that rank in that phase
 * fail as if malloc returned NULL. Photons: per exchange, the sizes, counts, offsets, then the
 * receive buffer; pixels: on a worker the render state, the counters' base, the tile list,
 * then one result buffer per chunk, and the counters; on rank 0 the queue's three arrays, then
 * one buffer per message received; irradiance: the allocations of the partitioned
 * precomputed-irradiance build, in its order (dist_irr_malloc: lk_irradiance.c's lk_side_build);
 * tracer: the photon tracer's own, one per batch this rank traces in a distributed pass (the
 * rounds' batches, then in a partitioned pass those traced again; trace_dist.test_fail in
 * photon_trace.h), the batch failing as if the tracer's buffer could not grow. */
int dist_test_enomem(int phase) {
    static int parsed, rank = -1, ph = -1;
    static long nth, count[4];
    if (!parsed) {
        parsed = 1;
        const char *v = getenv("PM_RENDER_MPI_TEST_ENOMEM");
        char name[16];
        if (v && sscanf(v, "%d %15s %ld", &rank, name, &nth) == 3)
            ph = strcmp(name, "photons") == 0      ? DIST_PH_PHOTONS
                 : strcmp(name, "pixels") == 0     ? DIST_PH_PIXELS
                 : strcmp(name, "irradiance") == 0 ? DIST_PH_IRRADIANCE
                 : strcmp(name, "tracer") == 0     ? DIST_PH_TRACER
                                                   : -1;
    }
    if (rank != g_rank || ph != phase) return 0;
    return ++count[phase] == nth;
}
void *dist_malloc(size_t n, int phase) { return dist_test_enomem(phase) ? NULL : malloc(n); }
void *dist_calloc(size_t n, size_t m, int phase) { return dist_test_enomem(phase) ? NULL : calloc(n, m); }
void *dist_irr_malloc(size_t n) { return dist_malloc(n, DIST_PH_IRRADIANCE); }
void *dist_irr_calloc(size_t n, size_t m) { return dist_calloc(n, m, DIST_PH_IRRADIANCE); }

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
    if (g_rank == 0 && !all) dist_die("out of memory");
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

void dist_collective_begin(void) { dist_start(0, NULL, NULL); }
void dist_film_gathered(void) { g_stage = 2; }

void dist_ranks_init(int mode) {
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
}
