/* lk_serve.h: the partitioned lookups' records and state (lookup.h), and this rank's side of
 * them (lk_serve.c): the answers from its own part of the maps and of the precomputed
 * irradiance, how the ranks' parts combine, and the messages that carry queries and answers.
 * Internal to render/mpi: the base of lk_tiles.c, lk_irradiance.c and lookup.c.
 */
#ifndef RENDER_MPI_LK_SERVE_H
#define RENDER_MPI_LK_SERVE_H

#include <mpi.h>
#include <stddef.h>
#include <stdint.h>

#include "photon_mapping/photon_lookup.h"
#include "photonmap/combined.h"

#ifdef __cplusplus
extern "C" {
#endif


/* A query: an estimate of the global or caustic map at (x, n) (map PHOTON_LOOKUP_*), a lookup
 * of the precomputed irradiance at y = x, normal n, within radius^2 d2, y's free height h (map
 * LK_SIDE), or one of the build's estimates at a chosen photon (LK_BUILD, free height h). All
 * 4-byte fields: no padding, so queries compare with memcmp. */
typedef struct lk_query {
    float x[3], n[3], h, d2;
    uint32_t map;
} lk_query;
enum { LK_SIDE = 2, LK_BUILD = 3 };

/* One rank's part of one estimate: the fields of a pm_combine_acc that one map adds. */
typedef struct lk_part {
    float power[3], far[3], r2;
    uint16_t found;
    uint16_t paths;     /* the build's estimates: distinct paths among the part's photons, up
                         * to SIDE_MIN_PATHS (side_count_paths; the parts' counts add up, lookup.h) */
    uint8_t rims, wall; /* wall: the precomputed irradiance's search met a wall */
    uint8_t spare[2];   /* zero: every byte sent is set */
} lk_part;

/* The queries of one camera sample, in the order its trace makes them, with their answers once
 * known (see lk_render_tiles). */
enum { LK_HAVE = 1, LK_FOUND = 2, LK_MINE = 4 };
typedef struct lk_rec {
    lk_query *q;
    lk_part *mine;    /* this rank's part, when computed during the trace (LK_MINE) */
    double (*e)[3];   /* the combined answer (LK_HAVE) */
    uint8_t *flags;
    uint32_t n, cap, cursor;
    uint32_t from; /* the first query this trace added (valid when fresh) */
    int fresh;     /* this trace made a query whose answer was not known: its radiance stands
                    * only if every guess equals the answer, else it is traced again */
    uint64_t *counted; /* what that trace added to its thread's counters (taken off meanwhile):
                        * the count n, then n pairs (counter id, amount) */
} lk_rec;

/* A camera sample of the tiles being rendered. */
typedef struct lk_smp {
    uint64_t pixel;
    int k;
    lk_rec *rec; /* NULL: no query yet */
    double L[3];
} lk_smp;

typedef struct lk_pending { /* an answer on its way */
    MPI_Request req;
    void *buf;
} lk_pending;

typedef struct lk_state {
    int rank, size, on;
    MPI_Comm comm;
    const pm_kdtree *trees[2];
    pm_estimate_options opts[2];
    const scene *scene;
    const side_cache *side; /* this rank's part of the precomputed irradiance (NULL: none) */
    const photon_maps *maps; /* the photon mapper's maps (hook_partition): their global_path */
    side_map caus_side;      /* this rank's caustic part's free heights (lk_begin): its estimates
                              * keep to the query's side as side_estimate's (photon_sides.h) */
    int ready; /* the photon mapper handed over its trees (else: not a photon-mapping render) */
    int trace_again; /* PM_MPI_TEST_TRACE_AGAIN=1 (tests): keep no trace made on guesses */
    int done_from; /* DONE notices received */
    lk_pending *pend;
    int npend, cappend;
    int st_queries, st_bytes, st_side_bytes, st_side_queries, st_gather_queries, st_traced,
        st_again, st_more, st_exact, st_rounds, st_nonfinite;
} lk_state;

/* The partitioned lookups' state (lookup.c's lk_init sets it up). */
extern lk_state lk;

static inline vec3 lk_v3f(const float f[3]) { return v3(f[0], f[1], f[2]); }
/* k/M: a part's share of an estimate's k photons (at least 1). */
unsigned lk_per_map(unsigned k);
/* A part from the partial sums of a pm_combine_acc (wall and paths 0). */
void lk_part_from_acc(const pm_combine_acc *a, lk_part *p);
/* Add a rank's part to the sums of one estimate. */
void lk_add_part(pm_combine_acc *a, const lk_part *p);
/* The combined value of one estimate of the map with options o from the ranks' parts in acc. */
void lk_combine_one(const pm_estimate_options *o, const pm_combine_acc *acc, double e[3]);
/* This rank's part of a lookup of the precomputed irradiance (a query of map LK_SIDE). */
void lk_answer_lookup(const lk_query *q, lk_part *out);
/* A lookup's answer from every rank's part (parts[r * stride]): 1 (found, e set) or 0. */
int lk_combine_lookup(const lk_part *parts, size_t stride, double e[3]);
/* This rank's parts of the n queries q whose have[i] is 0 (have NULL: all), on OpenMP threads. */
void lk_answer_queries(const lk_query *q, const uint8_t *have, size_t n, lk_part *out);
/* Every rank's parts of the n queries q (this rank's: mine), rank r's part of query i at
 * [r n + i] of the array returned (the caller frees it); serves other ranks' queries and calls
 * also(arg) while it waits. */
lk_part *lk_exchange(const lk_query *q, size_t n, const lk_part *mine, int (*also)(void *), void *arg);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_MPI_LK_SERVE_H */
