/* ranks.h: the base of render-mpi, under the photon exchange and image loop (dist.h) and the
 * partitioned lookups (lookup.h): which rank this is, the ranks' agreement before the first
 * collective step, a rank's failure after it (dist.h, FAILURES: rank 0 names the failing rank
 * and stops the job), and the test hook PM_RENDER_MPI_TEST_ENOMEM that makes an allocation
 * fail. Only the main thread calls these (MPI_THREAD_FUNNELED).
 */
#ifndef RENDER_MPI_RANKS_H
#define RENDER_MPI_RANKS_H

#include <mpi.h>
#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

enum { DIST_REPLICATED = 0, DIST_PARTITIONED = 1 };
/* The tag of a worker's failure message to rank 0 (int32 status, then its text), on
 * MPI_COMM_WORLD next to the tile queue's tags (tile_queue.c). */
enum { DIST_TAG_FAIL = 105 };

/* After MPI_Init (dist_init): rank, size and mode (a DIST_*); ranks > 0 discard their stdout
 * and keep their stderr in a temporary file, whose last lines become their failure message. */
void dist_ranks_init(int mode);
int dist_rank(void);
int dist_size(void);
/* 1 with --pm distributed=partitioned. */
int dist_partitioned(void);
/* This rank's own failure before the render started (usage error, bad option), with a
 * message (printed by rank 0 only). Joins the agreement and exits the program with status rc. */
void dist_fail_early(int rc, const char *msg);
/* Before this rank's first collective call (the agreement: returns once every rank is ready
 * to render; see dist.h, FAILURES). Later calls return at once. */
void dist_collective_begin(void);
/* A failure of this rank after the agreement: rank 0 says "rank K of N failed: what" and
 * stops the job (see FAILURES); does not return. */
void dist_die(const char *what);
/* Rank 0, while it waits for other ranks (a blocking collective would not hear a rank that
 * failed and never joins it): if a rank sent its failure, say it and stop the job; else
 * return at once. Other ranks: returns at once. */
void dist_poll_fail(void);
/* Rank 0: a worker's failure message (DIST_TAG_FAIL, received into buf, nbytes long): say it
 * and stop the job; does not return. */
void dist_report_fail(int src, char *buf, int nbytes);
/* Wait for a request (a nonblocking collective's: every rank must call the same collective,
 * so all ranks use the nonblocking form and wait here). Rank 0 listens meanwhile as in
 * dist_poll_fail, so a rank that failed and never joins the collective stops the job at once
 * (not after the failing rank's own FAIL_GRACE, ranks.c). Other ranks: MPI_Wait. */
void dist_wait(MPI_Request *r);
/* The test hook PM_RENDER_MPI_TEST_ENOMEM="RANK PHASE N" (ranks.c): 1 if this allocation (or
 * the tracer's batch), the N-th of this phase on this rank, is to fail. */
enum { DIST_PH_PHOTONS, DIST_PH_PIXELS, DIST_PH_IRRADIANCE, DIST_PH_TRACER };
int dist_test_enomem(int phase);
/* malloc / calloc that the test hook can make fail in that phase (a DIST_PH_*). */
void *dist_malloc(size_t n, int phase);
void *dist_calloc(size_t n, size_t m, int phase);
/* The same for the partitioned precomputed-irradiance build (lk_irradiance.c), phase
 * irradiance. */
void *dist_irr_malloc(size_t n);
void *dist_irr_calloc(size_t n, size_t m);
/* The render is over on this rank (rank 0: the film is complete; a worker: its tiles and
 * statistics are sent): dist_finish then only finishes MPI. */
void dist_film_gathered(void);
/* What render_main returned on this rank: finishes MPI and returns the exit status. */
int dist_finish(int rc);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_MPI_RANKS_H */
