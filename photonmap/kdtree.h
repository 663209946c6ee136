/* kdtree.h: a left-balanced kd-tree stored as an implicit heap, over any records that carry
 * a float[3] position.
 *
 * WHAT IT INDEXES. An array of n records of `stride` bytes each, with a float[3] position at
 * byte `pos_offset` of each record. A pm_photon array is one case (stride 20, offset 0), but
 * any struct works. pm_kdtree_build REORDERS THE CALLER'S RECORDS IN PLACE into tree order and
 * keeps no copy of them: query results are indices into the reordered array. If the caller
 * needs to map back, it passes a perm array and gets perm[i] = the original index of the
 * record now at position i. The records must outlive the tree, and their positions must not
 * change while it exists (other fields may).
 *
 * LAYOUT. Nodes are numbered as an implicit heap: the root is node 1 and node i has children
 * 2i and 2i+1; there are no child pointers. The tree has depth D, the smallest D >= 0 with
 * n + 1 <= (B + 1) * 2^D: heap nodes 1 .. 2^D - 1 are internal, each one record (record
 * i - 1 is node i), and heap nodes 2^D .. 2^(D+1) - 1 are the 2^D leaf buckets, which share the
 * remaining records as evenly as possible (q or q + 1 each, the larger ones first) and store
 * them contiguously after the internal records, so a bucket is scanned linearly. With B = 1
 * this is exactly Jensen's classic balanced tree (record i - 1 is node i for every i). The
 * average bucket holds between (B - 1) / 2 and B records. Each internal node is the median of
 * its subtree along the axis of largest extent of the subtree's tight bounding box (ties: the
 * lowest axis), with one exception for duplicates described in kdtree.c. The split axis
 * (2 bits per internal node) is kept in the byte at `axis_offset` of the record when the caller
 * gives one (the low two bits of pm_photon.flag; the other six bits are preserved; bucket
 * records get 0 there), or else in a small array the tree owns. Axis code 3 marks a uniform
 * subtree, all of whose records have the same position: queries treat it as one distance, so
 * a million identical points cost O(k), not a full scan. Every record in the left subtree of a
 * node has coordinate <= the split value on its axis, and every record in the right subtree
 * has coordinate >= it. When the tree owns bits 4-7 of the axis byte too (the tree-owned array,
 * and the pm_photon layout of pm_kdtree_photon_config: stride 20, position at 0, axis byte 18,
 * see photon.h), they hold a 4-bit code per internal node that shrinks the node's cell toward
 * its records (one face moved in by 1/2 or 7/8 of the cell's extent, or both faces of one axis
 * by 1/4), written only where every record of the subtree stays inside; any other layout keeps
 * its bits 2-7 untouched and gets no codes.
 *
 * COST. The build is O(n log n) with no recursion (an explicit stack, linear-time selection)
 * and uses n * (max(16, stride) + 4) bytes of temporary memory. The tree itself owns
 * sizeof(struct) bytes (including the records' bounding box) plus, with axis_offset = -1, one
 * byte per internal node: photons + tree are 20 bytes per photon. A query prunes a subtree by
 * the distance from q to the subtree's cell (not just to one split plane), the cell shrunk by
 * those codes, so queries off a plane of photons, between the walls of a scene or in the empty
 * space between clusters stay cheap. Build times and
 * queries/s against FLANN and an octree, on several workloads, worst case first: the
 * generated docs/BENCHMARKS.md.
 *
 * NON-FINITE INPUT. Records whose position has a NaN or infinite coordinate are DROPPED AND
 * COUNTED, not indexed: the build moves them to the tail of the array, after the n indexed
 * records, and pm_kdtree_dropped() tells how many there are.
 *
 * QUERIES. Distances are squared Euclidean distances, in float, computed as dx*dx + dy*dy +
 * dz*dz with d = q - p. A record is "within" a squared radius r2 when its dist2 < r2 (strict,
 * as in Jensen's notes and FLANN); r2 = +INFINITY means unlimited and then accepts every record,
 * even one whose dist2 overflowed to +inf. Float dist2 overflows when a coordinate difference
 * exceeds about 1.8e19 and underflows to 0 below about 1e-19 (tiny spreads become exact ties):
 * results stay consistent with a brute-force scan in the same float arithmetic (tested with
 * coordinates around 1e30 and spreads around 1e-30), but their order then carries no more
 * information than those floats. Results go to caller-owned arrays; queries use only a fixed-size stack scratch of
 * at most PM_KDTREE_MAX_DEPTH entries, never allocate, never lock, and never write to the tree,
 * so any number of threads may query one tree at once.
 *
 * TIES. Among records at equal dist2 the smaller record index wins: the k nearest are the k
 * records of smallest (dist2, index), compared by dist2 and then by index into the reordered
 * array, among those with dist2 < max_dist2. That set does not depend on the traversal, so
 * every k-nearest search here (pm_kdtree_knn, _recursive, _knn_ex with its metric and filter,
 * pm_kdtree_nearest_if, with or without a maximum radius or PM_SORT) returns exactly it, and
 * repeated or concurrent queries from any number of threads give identical arrays. (A filter
 * applies first: the rule picks among the records it accepts.) The iterative and recursive
 * searches visit in the same order and return identical arrays (and identical
 * pm_query_stats). ORDER of results: with PM_SORT, ascending by (dist2, index); without it,
 * for k <= 16 also ascending (the search sorts its result set once at the end, so PM_SORT costs
 * nothing more there),
 * and for k > 16 a max-heap on (dist2, index) (out[0] is the k-th nearest once k were found).
 * pm_kdtree_radius returns every record within r2, so ties do not arise; when more than cap
 * are within, which cap of them are written follows the traversal.
 *
 * STATS. nodes_visited counts internal nodes descended through, buckets scanned and uniform
 * subtrees met; dist_evals counts dist2 computations. Passing NULL selects a search instance
 * without counters.
 *
 * DEFINED EDGE CASES. k = 0, an empty tree, or r2 <= 0 give 0 results. k > n gives at most n
 * results. A NaN r2 or a non-finite query coordinate returns PM_ENONFINITE. None of these
 * crash, loop or read out of bounds.
 *
 * OWNERSHIP. pm_kdtree_build allocates the tree (not the records); pm_kdtree_free frees it.
 */
#ifndef PM_KDTREE_H
#define PM_KDTREE_H

#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The deepest tree a query's fixed stack can handle; build refuses more records than fit. */
#define PM_KDTREE_MAX_DEPTH 64

/* Query flags. */
#define PM_SORT 1u /* sort results by (dist2, index) ascending */

typedef struct pm_kdtree pm_kdtree;

typedef struct pm_kdtree_config {
    size_t stride;     /* bytes from one record to the next; >= 12 and a multiple of 4 */
    size_t pos_offset; /* byte offset of the float[3] position; pos_offset + 12 <= stride; the
                          position must be 4-byte aligned in memory */
    int axis_offset;   /* byte offset of a uint8 whose low 2 bits may hold the split axis (it
                          must not overlap the position), or -1 for a tree-owned axis array */
    unsigned bucket;   /* leaf bucket size B >= 1; 1 is Jensen's classic tree */
} pm_kdtree_config;

/* The bucket size recommended by the k-nearest race (docs/BENCHMARKS.md, "Choosing B"): B = 32
 * and 64 come out even in the geometric mean of their queries/s against each cell's fastest B
 * (64 is the fastest in more cells, 32 slightly ahead on the cells of the targets, k = 10 and
 * 50), and 32 is the fastest in the worst cell (clustered data, empty-space queries, k = 10),
 * where 64 loses most. */
#define PM_KDTREE_BUCKET_DEFAULT 32u

/* A config for pm_photon records with bucket size B (axis in the flag byte); bucket 0 means
 * PM_KDTREE_BUCKET_DEFAULT. */
pm_kdtree_config pm_kdtree_photon_config(unsigned bucket);

/* Build a tree over records[0..n). Reorders records in place (see the top of this file).
 * perm is optional (may be NULL); if given it must hold n entries. n = 0 builds an empty tree.
 * Returns 0 and sets *out, or a negative PM_E* code (PM_EINVAL for a bad config, PM_ERANGE
 * for n >= 2^32 - 1, PM_ENOMEM) and leaves *out NULL and the records unchanged. */
int pm_kdtree_build(pm_kdtree **out, void *records, size_t n, const pm_kdtree_config *cfg,
                    uint32_t *perm);
void pm_kdtree_free(pm_kdtree *tree);

size_t pm_kdtree_size(const pm_kdtree *tree);        /* records indexed */
size_t pm_kdtree_dropped(const pm_kdtree *tree);     /* non-finite records moved to the tail */
size_t pm_kdtree_index_bytes(const pm_kdtree *tree); /* bytes the tree owns, not counting the records */
unsigned pm_kdtree_bucket(const pm_kdtree *tree);
const void *pm_kdtree_records(const pm_kdtree *tree);
/* Position of record i (0 <= i < size). */
const float *pm_kdtree_pos(const pm_kdtree *tree, uint32_t i);
/* Height of record i above the bottom of the tree: 0 for a record in a leaf (a bucket, or a
 * node without children), 1 for a node whose children are all leaves, and so on. Precomputed
 * irradiance uses it to pick "the photons that are neither leaves nor parents of leaves". */
int pm_kdtree_height(const pm_kdtree *tree, uint32_t i);

/* The k nearest records with dist2 < max_dist2 (ties: the smaller index, see TIES above). out
 * must hold k entries. Returns the number found (0..k) or a negative code. Iterative: an
 * explicit stack of cells and far children; the results are kept in unordered slots whose
 * largest (dist2, index) is tracked for k <= 64, else in a max-heap, and the k-th entry
 * shrinks the search radius.
 * Order: see TIES (PM_SORT sorts when k > 16). */
int pm_kdtree_knn(const pm_kdtree *tree, const float q[3], unsigned k, float max_dist2,
                  pm_neighbor *out, unsigned flags, pm_query_stats *stats);
/* The same search written recursively (depth at most D + 1 <= 33 frames), for comparison;
 * identical results. */
int pm_kdtree_knn_recursive(const pm_kdtree *tree, const float q[3], unsigned k,
                            float max_dist2, pm_neighbor *out, unsigned flags,
                            pm_query_stats *stats);

/* A caller predicate: nonzero to accept the record. */
typedef int (*pm_filter_fn)(void *user, const void *record, uint32_t index);

/* k nearest with options, for leak control in radiance estimates:
 *   - normal, squash: if normal is non-NULL (unit length) and squash > 1, distances are
 *     measured in an ellipsoid metric compressed along the normal,
 *       dist2 = |d|^2 + (squash - 1) * (d . normal)^2,
 *     so records off the tangent plane count as farther (a "disc-shaped" search). The
 *     returned dist2 values are in this metric.
 *   - filter: if non-NULL, records it rejects are skipped (e.g. photons arriving from
 *     behind the surface).
 * Otherwise as pm_kdtree_knn. */
typedef struct pm_knn_options {
    const float *normal;
    float squash;
    pm_filter_fn filter;
    void *filter_user;
    unsigned flags;
} pm_knn_options;
int pm_kdtree_knn_ex(const pm_kdtree *tree, const float q[3], unsigned k, float max_dist2,
                     const pm_knn_options *opt, pm_neighbor *out, pm_query_stats *stats);

/* All records with dist2 < r2. Writes at most cap of them to out (in traversal order, or by
 * (dist2, index) with PM_SORT when all fit) and returns the TOTAL number within the radius,
 * which may exceed cap, or a negative code. out may be NULL when cap is 0 (a pure count). */
long pm_kdtree_radius(const pm_kdtree *tree, const float q[3], float r2, pm_neighbor *out,
                      size_t cap, unsigned flags, pm_query_stats *stats);
/* The same, calling fn for each record within the radius; fn returns nonzero to stop early.
 * Returns the number of calls made. */
typedef int (*pm_visit_fn)(void *user, uint32_t index, float dist2);
long pm_kdtree_radius_cb(const pm_kdtree *tree, const float q[3], float r2, pm_visit_fn fn,
                         void *user, pm_query_stats *stats);

/* The single nearest record with dist2 < max_dist2 that pred accepts (pred may be NULL).
 * Returns 1 and fills *out, 0 if there is none, or a negative code. */
int pm_kdtree_nearest_if(const pm_kdtree *tree, const float q[3], float max_dist2,
                         pm_filter_fn pred, void *user, pm_neighbor *out,
                         pm_query_stats *stats);

#ifdef __cplusplus
}
#endif

#endif /* PM_KDTREE_H */
