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
 * as queries (position, normal, free height: 36-byte lk_query). Every rank answers every query
 * from its part: its k/M nearest photons on the query's side (photon_sides.h's visibility test,
 * widened past a wall as there), as the partial sums of a pm_combine_acc (power, farthest
 * power, r^2, count, the distinct photon paths of its photons, rim, wall seen: 36
 * bytes). An all-to-all returns each rank the answers to its queries; it combines them
 * (pm_combine_finish, divided by the visible part of the mean disc when a rank met a wall; the
 * indirect irradiance, as side_cache_build's: direct photons count in the radius, not in the
 * power), reads a record only if the parts' path counts add up to SIDE_MIN_PATHS
 * (photon_sides.h, "Sparse estimates": each part is a run of the map's order, so its paths are
 * its own but for the few that straddle two parts; the rule needs no k, which a part's k/M
 * photons never reach) and KEEPS ITS OWN RECORDS ONLY (pm_photon with E,
 * r^2, free height): each rank holds about a quarter of its part's photons as records, 1/M of
 * the whole precomputed irradiance. The cache it builds from them (side_cache_from_records)
 * gets a remote lookup (side_cache.remote), so every final-gather lookup asks every rank.
 *
 * LOOKUPS OF THE PRECOMPUTED IRRADIANCE (the final gather's). A lookup at y (normal n, radius^2
 * d2) is answered by every rank from its records as side_cache_lookup does from all of them
 * (side_cache_lookup_local: the module's normal and own-radius rules, the visibility test from
 * y with y's free height, computed once by the asking rank, on the 8 nearest candidates of
 * the part): the record it accepts, as its E and its distance^2 to y (36 bytes), or none. The
 * nearest answer wins, the lowest rank on a tie. Whenever one process holding all the ranks'
 * records would answer with record R (the first of its 8 nearest candidates that passes), R's
 * rank answers with R too and no rank has a nearer one; the ranks may also answer where that
 * process found none (a candidate beyond the 8 nearest of the whole set, within the 8 nearest
 * of its part).
 *
 * PIXEL PASS. Every estimate of the global map (preview) or the caustic map, and every lookup of
 * the precomputed irradiance, goes to every rank. The rank traces the camera samples of its
 * chunk of tiles itself (as renderer.c's render_tile: the same random stream, jitter and camera
 * ray per sample), keeping each sample's queries in order. A query whose answer is not known
 * yet gets a guess (an estimate: 0; a lookup: this rank's own part's answer, which decides
 * whether the gather takes the record or computes the light at y) and is kept. After the trace,
 * the chunk's kept queries go in one message to every other rank; each answers from its part
 * (36 bytes a query out, 36 back), serving other ranks' queries while it waits; the answers are
 * combined (estimates: the combined-map rule below; lookups: the nearest record). Then only the
 * samples that made queries are traced again, each query taking its answer; a sample whose
 * trace leaves its recorded queries (a guessed lookup found where no rank found, or the other
 * way round: the gather then draws other random numbers) keeps its queries up to there, and
 * its new ones are answered in a further exchange; until every sample's last trace read known
 * answers only. That trace is the sample's radiance; the earlier traces of a sample are taken
 * off the counters (per thread), so the statistics count one trace per sample. A sample
 * without queries is traced once, and so is a sample whose every guess turns out to be the
 * answer (each lookup answered by this rank's records as by all ranks, found or not, and each
 * estimate 0): that trace is exactly the one it would be traced again to, so its radiance and
 * counters are kept (PM_MPI_TEST_TRACE_AGAIN=1 turns this off, for the test that compares
 * the two). Each pixel's samples are then added in sample order, as
 * render_tile adds them. No decision of li() depends on an estimate's value (photon_lookup.h),
 * and a lookup's value is only added: only whether a lookup found a record changes the path.
 * A caustic estimate's part keeps to the query's side as one process's side_estimate does
 * (side_neighbours, photon_sides.h: neighbours off the query's plane that a wall hides are
 * dropped, the part widened to 4 k/M candidates; the part's free heights come from lk_begin).
 * A cone or Gaussian filter (the caustic map's) is combined as sum_m S_m / sum_m A_m times M,
 * each part's filtered power S_m and area A_m (pi r_m^2 times the filter's norm) taken against
 * its own radius; the hull and differential filters fall back to the combined disc.
 *
 * DETERMINISM. Each estimate adds the ranks' parts in rank order, a lookup takes the nearest
 * answer (the lowest rank on a tie), and a part depends only on the query and the rank's
 * photons or records; a sample's radiance is that of a trace that read answers only (or
 * guesses equal to them), whatever the guesses were. So the image depends on the rank count alone (not on the threads, the tile
 * queue, or whether the maps were traced or loaded).
 *
 * All MPI calls are on the main thread; the answers to a batch are computed on OpenMP threads.
 */
#ifndef RENDER_MPI_LOOKUP_H
#define RENDER_MPI_LOOKUP_H

#include <mpi.h>

#include "run/renderer.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Set the photon-lookup hook (photon_lookup.h) for a partitioned render on these ranks; comm:
 * the lookups' own communicator (a duplicate of MPI_COMM_WORLD, made by every rank whatever
 * its mode, so that ranks started with different modes meet in the ranks' agreement, ranks.c). */
void lk_init(int rank, int size, MPI_Comm comm);
/* Before the pixel pass, on every rank, before it answers any query: the free heights of this
 * rank's caustic part, so that its caustic estimates keep to the query's side (side_neighbours,
 * photon_sides.h) as one process's do. Once; nothing without partitioned photon maps. */
void lk_begin(const scene *s);
/* 1 after lk_init. */
int lk_on(void);
/* Render tiles[0..n) into st: trace, exchange, trace again (above). While waiting it serves other
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
