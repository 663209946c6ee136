/* tile_queue.h: the pixel pass of render-mpi (dist.h, PIXEL PASS; tile_queue.c): rank 0 serves
 * the queue of tiles and renders chunks of its own, the workers ask for chunks, render them and
 * send their pixel sums back. Called by dist.c's image loop after the agreement.
 */
#ifndef RENDER_MPI_TILE_QUEUE_H
#define RENDER_MPI_TILE_QUEUE_H

#include <stdint.h>

#include "run/renderer.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Rank 0: render into st (a resumed one: its incomplete tiles only) with every rank, making
 * ctl's pauses between chunks (ctl may be NULL); print the traffic ("MPI:" lines, with
 * bytes_photon, the photon exchanges' bytes) and add it to the statistics. 0,
 * RENDER_INTERRUPTED, or a negative code. */
int tq_root(const scene *s, const integrator *it, const render_job *job, render_state *st,
            const render_control *ctl, uint64_t bytes_photon);
/* A worker: ask for chunks, render them into st and send their sums, until the queue is empty;
 * then send the counters this rank added since base (STATS_MAX values). 0 or a negative code. */
int tq_worker(const scene *s, const integrator *it, const render_job *job, render_state *st,
              const uint64_t *base);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_MPI_TILE_QUEUE_H */
