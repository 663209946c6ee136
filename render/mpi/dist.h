/* dist.h: the distributed renderer `render-mpi`: one render spread over MPI processes
 * (ranks), on one machine or many, giving the image of the one-process `render` bit for bit.
 *
 * HOW IT IS BUILT. render-mpi is the files of render/mpi/, compiled with mpicc (Makefile,
 * MPI=1) and linked with the renderer's objects: render_mpi.c's main calls render's own
 * program, render_main (app/app.h), with hooks. So it parses the same options and runs the
 * same scene loading, preprocessing and output code, and the two seams are the image loop
 * (dist_render_image_ctl and the pass hooks below, handed over as render_hooks) and the
 * photon passes (photon_trace.h's trace_dist, set by dist_init). The default build never
 * sees mpi.h.
 *
 * PHOTON PASS. Every rank loads the scene and plans alike. Each pass runs in rounds: rank r
 * traces batch r of the round, an all-gather gives every rank all the batches, and every
 * rank keeps the one-process bookkeeping (photon_trace.h, DISTRIBUTED PASSES). So every
 * rank builds the same maps as a one-process run (replicated mode, the default). With
 * --pm distributed=partitioned the rounds carry only each batch's counts, and each rank traces
 * its own part of the maps again and keeps only that (trace_dist.partitioned, photon_trace.h).
 *
 * PIXEL PASS. Rank 0 keeps a queue of the image's 16x16 tiles. A worker rank asks for a
 * chunk of tiles (at most its thread count, fewer as the queue empties), renders it with
 * render_tiles (OpenMP threads inside the rank) and sends the tiles' per-pixel sums back,
 * asking for the next chunk before it starts rendering one, so it never waits for rank 0.
 * Rank 0 answers between chunks of its own. A pixel's sum is made on one rank in sample
 * order exactly as in render_image, and rank 0 copies it into one render_state: the film is
 * bit-identical whatever tile went where. Rank 0 shows the progress, adds every rank's
 * pixel-pass statistics to its own, writes the outputs once through main.c's atomic output
 * code, and prints the traffic ("MPI:" lines; statistics "MPI/...").
 *
 * FAILURES. Until the first collective step every rank runs alone; there (ranks.c's
 * dist_start) the ranks agree: if any failed (a scene it could not load, a bad option), rank 0
 * prints each failing rank's message and every rank exits with the failing rank's status (2
 * for input errors), nothing written; ranks given different commands (mpirun's MPMD form:
 * some render and some do not, or the --pm distributed modes differ) are named and exit 2.
 * So that they meet there, every rank makes the same collective calls before it, whatever
 * its command. A rank failing later (an allocation in render/mpi, or render_main's own
 * error, e.g. out of memory in the photon pass or the pixel pass; the photon tracer's own out
 * of memory, which the exchange would tell every rank, is sent by the failing rank before
 * that exchange, through trace_dist.failed) sends its message to rank 0, which listens for it
 * wherever it waits (the tile queue, the photon exchange, dist_poll_fail, and dist_wait in the
 * collectives of lk_irradiance.c's partitioned precomputed irradiance), prints "rank K of N
 * failed (status S): what" and aborts the job (MPI_Abort, non-zero exit) before anything is
 * written; rank 0's own failures abort at once. A rank that dies (killed, a lost node, the kernel's OOM killer) makes mpirun stop
 * the job; rank 0 then says so on stderr from its SIGTERM handler and, the output being
 * written only at the very end through a temporary and a rename, leaves no output file.
 * Test hook: PM_RENDER_MPI_TEST_ENOMEM="RANK PHASE N" fails an allocation (ranks.c), or a
 * batch of the photon tracer (PHASE tracer).
 *
 * The agreement, the failures and the test hook are ranks.c's (ranks.h); the photon exchange
 * and the image loop dist.c's, rank 0's tile queue and the workers' chunks tile_queue.c's.
 *
 * Ranks other than 0 print nothing: their stdout is discarded and their stderr kept in a
 * temporary file, whose last lines become their failure message.
 */
#ifndef RENDER_MPI_DIST_H
#define RENDER_MPI_DIST_H

#include <mpi.h>
#include <stddef.h>
#include <stdint.h>

#include "ranks.h"
#include "run/renderer.h"

#ifdef __cplusplus
extern "C" {
#endif

/* After MPI_Init: rank and size (dist_ranks_init), streams of ranks > 0, the photon-pass hook,
 * the partitioned lookups (lookup.h) in that mode. mode: a DIST_* (ranks.h). */
void dist_init(int mode);
/* The image loop of a distributed render (see above), called by render_main in place of
 * render_image_ctl. On ranks > 0 it does not return: they exit once their tiles are sent.
 * With a control (a checkpointed, snapshotted or resumed render), rank 0 renders into
 * ctl->state, skipping its complete tiles, and makes ctl's pauses between chunks (tile_queue.c,
 * root_pause); it returns RENDER_INTERRUPTED after the checkpoint of a signal, as
 * render_image_ctl does. The other ranks ignore ctl: they write nothing. */
int dist_render_image_ctl(const scene *s, const integrator *it, const render_job *job,
                          const render_control *ctl, film *out);

/* RENDERING IN PASSES (run/passes.h; replicated mode only, render_mpi.c's hook refuses partitioned). Every
 * rank runs the pass loop in lockstep: before each pass dist_pass_agree gives every rank rank
 * 0's decision to render it (the budget, a signal and the pass count are rank 0's), so all
 * ranks call begin_pass (whose photon passes exchange batches as above) and the pass's image
 * together. dist_pass_image is one pass's image: the tile queue as above, but every rank
 * returns (rank 0 with the pass's film, the others with a black one, which they never write),
 * and ctl's pauses are not made inside a pass (a signal ends the render after the pass in
 * progress, at the next agreement). Rank 0's passes are the one-process render's, so the
 * mean is too, bit for bit. dist_passes_end(rc) after the loop: the workers finish MPI and
 * exit (0); rank 0 goes on to write the outputs. */
int dist_pass_image(const scene *s, const integrator *it, const render_job *job,
                    const render_control *ctl, film *out);
int dist_pass_agree(int go);
/* Before each pass of a render with adaptive samples (run/passes.h): every rank gets rank 0's
 * n bytes in buf (the sample multipliers), so the ranks render the same pass. 0. */
int dist_pass_share(unsigned char *buf, size_t n);
void dist_passes_end(int rc);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_MPI_DIST_H */
