/* octree.h: an octree over records that carry a float[3] position, with the same queries as
 * the kd-tree (kdtree.h). It exists to be raced against the kd-tree (bench_search, bench_knn)
 * and is not part of the installed module: its names are the benchmarks' (bench_octree_*).
 *
 * WHAT IT IS. The classic "photons in leaf containers" octree: a cell holds its records until
 * it has more than `capacity` of them, then it splits into 8 equal octants. The build does this
 * top-down: it reorders the caller's records IN PLACE so that the records of each leaf are one
 * contiguous run, and keeps only the cells (12 bytes each, children stored 8 at a time). Query
 * results are indices into the reordered array; pass perm to map back (perm[i] = the original
 * index of the record now at position i). The records must outlive the octree and their
 * positions must not change while it exists.
 *
 * CELLS. The root is the bounding cube of the finite positions. A cell [lo, hi] splits at
 * mid = lo + (hi - lo) * 0.5 on each axis; a record goes to the upper half of an axis when its
 * coordinate is >= mid. Queries recompute the cell bounds with the same float expressions, so
 * every record lies inside its cell's box exactly and box pruning never loses a record. A cell
 * that cannot split any more (float resolution, BENCH_OCTREE_MAX_DEPTH, many identical points)
 * stays a leaf above capacity: duplicates never recurse forever.
 *
 * NON-FINITE INPUT, QUERIES, TIES, EDGE CASES, THREADS: exactly as in kdtree.h. Records with a
 * NaN or infinite coordinate are moved to the tail and counted (bench_octree_dropped). A record is
 * within r2 when dist2 < r2 (strict); r2 = INFINITY is unlimited and then, as in the kd-tree,
 * accepts every record, even one whose float dist2 overflowed to +inf. k = 0, an empty tree or
 * r2 <= 0 give 0 results; a NaN r2 or non-finite query gives PM_ENONFINITE. Queries use a fixed
 * stack scratch, never allocate, never lock and never write to the tree, so any number of
 * threads may query one octree at once. The multiset of returned k-nearest distances equals a
 * brute-force scan's.
 *
 * OWNERSHIP. bench_octree_build allocates the octree (not the records); bench_octree_free frees it.
 */
#ifndef BENCH_OCTREE_H
#define BENCH_OCTREE_H

#include "common.h"
#include "kdtree.h" /* PM_SORT, pm_query_stats users expect the same flags */

#ifdef __cplusplus
extern "C" {
#endif

/* Deepest cell level; a cell at this depth is a leaf whatever its count. */
#define BENCH_OCTREE_MAX_DEPTH 40

typedef struct bench_octree bench_octree;

typedef struct bench_octree_config {
    size_t stride;     /* bytes from one record to the next; >= 12 */
    size_t pos_offset; /* byte offset of the float[3] position; pos_offset + 12 <= stride */
    unsigned capacity; /* a leaf splits when it holds more than this many records; >= 1 */
} bench_octree_config;

/* A config for pm_photon records (stride 20, position at 0) with the given leaf capacity. */
bench_octree_config bench_octree_photon_config(unsigned capacity);

/* Build an octree over records[0..n). Reorders records in place; perm is optional (n entries).
 * Returns 0 and sets *out, or PM_EINVAL (bad config), PM_ERANGE (n >= 2^32 - 1), PM_ENOMEM;
 * on error *out is NULL and the records are unchanged. */
int bench_octree_build(bench_octree **out, void *records, size_t n, const bench_octree_config *cfg,
                    uint32_t *perm);
void bench_octree_free(bench_octree *tree);

size_t bench_octree_size(const bench_octree *tree);        /* records indexed */
size_t bench_octree_dropped(const bench_octree *tree);     /* non-finite records moved to the tail */
size_t bench_octree_index_bytes(const bench_octree *tree); /* bytes the octree owns (cells), not the records */
size_t bench_octree_cells(const bench_octree *tree);       /* cells, leaves included */
int bench_octree_depth(const bench_octree *tree);          /* deepest leaf level (root = 0) */
unsigned bench_octree_capacity(const bench_octree *tree);
const float *bench_octree_pos(const bench_octree *tree, uint32_t i);

/* The k nearest records with dist2 < max_dist2, as pm_kdtree_knn: out holds k entries; returns
 * the number found or a negative code; heap order unless flags has PM_SORT. Cells are visited
 * nearest first; a cell is pruned when its box is no closer than the current k-th distance. */
int bench_octree_knn(const bench_octree *tree, const float q[3], unsigned k, float max_dist2,
                  pm_neighbor *out, unsigned flags, pm_query_stats *stats);

/* All records with dist2 < r2, as pm_kdtree_radius: writes at most cap to out and returns the
 * total count (may exceed cap). out may be NULL when cap is 0. */
long bench_octree_radius(const bench_octree *tree, const float q[3], float r2, pm_neighbor *out,
                      size_t cap, unsigned flags, pm_query_stats *stats);

#ifdef __cplusplus
}
#endif

#endif /* BENCH_OCTREE_H */
