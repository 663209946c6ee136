/* bvh.h: a bounding volume hierarchy over all triangles and spheres of a scene.
 *
 * Built top-down with the binned surface area heuristic (16 bins per axis over the centroid
 * bounds, Wald 2007): each split minimizes area(left) * n(left) + area(right) * n(right), and a
 * node becomes a leaf when no split is cheaper than intersecting its primitives (or it holds
 * <= 2, or all centroids coincide, or the tree is 96 levels deep). Nodes are stored depth-first
 * in one array: a node's left child follows it, the right child's index is stored.
 *
 * Primitive ids: 0 .. ntris-1 are triangles, ntris .. ntris+nspheres-1 are spheres.
 *
 * Ownership: the bvh owns its node and index arrays (bvh_free); it does not own the shapes,
 * which must outlive it and not move. A built bvh is immutable; queries allocate nothing and
 * can run on any number of threads at once.
 */
#ifndef RENDER_BVH_H
#define RENDER_BVH_H

#include <stdint.h>

#include "scene/shapes.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct bvh_node {
    double lo[3], hi[3];
    uint32_t first; /* leaf: first index into prim_ids; inner: index of the right child */
    uint16_t count; /* leaf: number of primitives; inner: 0 */
    uint16_t axis;  /* inner: the split axis, for front-to-back traversal */
} bvh_node;

typedef struct bvh {
    bvh_node *nodes;
    uint32_t *prim_ids;
    int nnodes, nprims, depth;
    const triangle *tris;
    const sphere *spheres;
    int ntris, nspheres;
} bvh;

/* 0, PM_ENOMEM, or PM_EEMPTY when there are no primitives. */
int bvh_build(bvh *b, const triangle *tris, int ntris, const sphere *spheres, int nspheres);
void bvh_free(bvh *b);

/* Nearest hit with tmin < t < tmax: returns 1 and fills *t, *prim and, for triangles, the
 * barycentrics (*u, *v) (both 0 for spheres). */
int bvh_intersect(const bvh *b, ray r, double tmin, double tmax, double *t, int *prim, double *u,
                  double *v);
/* Any hit with tmin < t < tmax (shadow rays): returns 1 if the segment is blocked. */
int bvh_occluded(const bvh *b, ray r, double tmin, double tmax);
/* The primitives whose bounds (a triangle's vertices' box, a sphere's cube) overlap the box
 * [lo, hi]: their ids into out[0..cap) and their count, or cap + 1 when there are more than cap
 * (out then holds cap of them). For a caller that wants to know which surfaces a set of
 * segments inside the box could meet (photon_sides.c); counts no statistics. */
int bvh_overlap(const bvh *b, const double lo[3], const double hi[3], uint32_t *out, int cap);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_BVH_H */
