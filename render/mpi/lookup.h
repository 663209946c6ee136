/* lookup.h: partitioned photon maps for render-mpi (--pm distributed=partitioned): every rank
 * keeps only its part of the photon maps, and each estimate combines the parts of all ranks
 * with the combined-map rule of photonmap/combined.h, E = c (M/pi) sum_m P_m / sum_m r_m^2.
 *
 * WHICH PHOTONS. After the photon pass (or loading, with the radii chosen from the whole maps,
 * photon_lookup.h), rank r of M keeps the photons r n/M .. (r+1) n/M - 1 of each map in photon
 * index order: a contiguous range of emitted photons, each traced with its own random stream
 * and Halton point, so each part is a map of the scene with 1/M of the photons and the union
 * is the one-process map. The shadow-photon map is dropped: partitioned renders trace every
 * shadow ray (the exact visibility the shadow map approximates). Traced maps arrive already
 * cut to that part (photon_maps.part: the partitioned photon pass of photon_trace.h keeps
 * only the rank's range, and gives the whole maps' counts and largest powers for the radii);
 * loaded maps are whole on every rank and cut here.
 *
 * PRECOMPUTED IRRADIANCE (collective, once). Each rank chooses a quarter of its own photons as
 * photon_sides.c does in its tree (neither leaves nor parents of leaves) and all-gathers them
 * as queries (position, normal, free height: 28 bytes). Every rank answers every query from
 * its part: its k/M nearest photons on the query's side (photon_sides.h's visibility test,
 * widened past a wall as there), as the partial sums of a pm_combine_acc (power, farthest
 * power, r^2, count, rim, wall seen: 32 bytes). An all-to-all returns each rank the answers to
 * its queries; it combines them (pm_combine_finish, divided by the visible part of the mean
 * disc when a rank met a wall; the indirect irradiance, as side_cache_build's: direct photons
 * count in the radius, not in the power) and all-gathers the records (pm_photon with E, r^2, free height:
 * 28 bytes), so every rank holds the whole precomputed irradiance (about a quarter of the
 * global photons; see docs/MPI.md for its memory).
 *
 * PIXEL PASS. Final-gather lookups read the precomputed irradiance and stay local. The global
 * map's estimates (preview) and the caustic map's go through the hook, batched per chunk of
 * tiles: the rank traces its tiles once recording each estimate's query (28 bytes) with a
 * placeholder value, sends the chunk's queries to every other rank in one message, answers
 * its own from its part, and waits for the answers (32 bytes per query and rank), serving
 * other ranks' queries meanwhile; then it combines them and traces the tiles again, each
 * estimate taking its combined value in order. A cone or Gaussian filter (the caustic map's)
 * is combined as sum_m S_m / sum_m A_m times M, each part's filtered power S_m and area A_m
 * (pi r_m^2 times the filter's norm) taken against its own radius; the hull and differential
 * filters fall back to the combined disc. li() makes no decision on an estimate's value
 * (photon_lookup.h), so the second trace makes the same queries, which is checked: a query
 * that differs stops the job. The recording trace's counters are taken off again. A chunk
 * whose recording made no query (no caustic map, say) is done after the first trace.
 *
 * DETERMINISM. Each estimate adds the ranks' parts in rank order, and a part depends only on
 * the query and the rank's photons: the image depends on the rank count alone (not on the
 * threads, the tile queue, or whether the maps were traced or loaded).
 *
 * All MPI calls are on the main thread; the answers to a batch are computed on OpenMP threads.
 */
#ifndef RENDER_MPI_LOOKUP_H
#define RENDER_MPI_LOOKUP_H

#include <mpi.h>

#include "renderer.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Set the photon-lookup hook (photon_lookup.h) for a partitioned render on these ranks. */
void lk_init(int rank, int size);
/* 1 after lk_init. */
int lk_on(void);
/* Render tiles[0..n) into st: record, exchange, replay (above). While waiting it serves other
 * ranks' queries and calls also(arg) (rank 0: the tile queue), which returns 1 if it did
 * something. 0 or a negative PM_E* code. */
int lk_render_tiles(const scene *s, const integrator *it, const render_job *job, render_state *st,
                    const int *tiles, int n, int (*also)(void *), void *arg);
/* Serve one waiting query batch or end-of-work notice, if any: 1 if one was served. */
int lk_poll(void);
/* This rank has rendered its last tile: tell the others, and serve their queries until every
 * rank has said the same. */
void lk_finish(int (*also)(void *), void *arg);
/* Sleep briefly (a polling loop that found nothing to do). */
void lk_idle(void);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_MPI_LOOKUP_H */
