/* nanoflann_peer.h: a C interface to nanoflann's exact kd-tree (libnanoflann-dev, header-only
 * C++), so that bench_knn (C) can race it beside FLANN. Benchmark code only: photonmap/ never
 * sees it. Implemented in nanoflann_peer.cpp.
 *
 * A peer indexes a float[3] array it copies (so the caller's array may go). With tree_order,
 * it is built twice: once over the points in input order, then its points are rewritten in the
 * order of that tree's index array (vAcc) and a second tree is built over that copy, so that a
 * leaf's points are contiguous in memory as ours are; the build time reported is the first
 * build's. Indices returned are into the peer's own copy (nf_pos gives a position back).
 * Queries are nanoflann's KNNResultSet through findNeighbors; a maximum radius is given the way
 * nanoflann 1.4 allows it: the result set's worst distance starts at r2 instead of the largest
 * float (it accepts dist2 < worst, strictly, as ours does), and the found count is its size. */
#ifndef BENCH_NANOFLANN_PEER_H
#define BENCH_NANOFLANN_PEER_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct nf_peer nf_peer;

/* Builds over xyz[0 .. 3n) with leaf_max_size leaf; NULL on failure. *build_s gets the CPU
 * seconds of the build in input order (timed by the caller's clock through now()). */
nf_peer *nf_build(const float *xyz, size_t n, unsigned leaf, int tree_order,
                  double (*now)(void), double *build_s);
void nf_free(nf_peer *p);
/* The k nearest with dist2 < r2 (r2 = +inf: unlimited), ascending; returns the count. */
unsigned nf_knn(const nf_peer *p, const float q[3], unsigned k, float r2, uint32_t *idx,
                float *dist2);
const float *nf_pos(const nf_peer *p, uint32_t i);
/* Heap bytes nanoflann's index owns (its nodes and index array), not the points. */
size_t nf_index_bytes(const nf_peer *p);
/* libnanoflann's NANOFLANN_VERSION, e.g. 0x143. */
unsigned nf_version(void);

#ifdef __cplusplus
}
#endif

#endif
