/* kdtree_internal.h: the layout of a built pm_kdtree, shared by kdtree.c (build) and the
 * queries (kdtree_query.c, kdtree_radius.c, kdtree_query_internal.h). Internal: nothing here
 * is part of the public API, and every name carries the pm__ prefix (or is a struct member).
 *
 * The tree is fully described by its depth D and the bucket fill (q, extra): see the SHAPE
 * paragraph at the top of kdtree.c. The axis of internal node p (record p - 1) is the low two
 * bits of a byte, either in the record (axis_offset >= 0) or in the tree-owned `axes` array.
 * Axis code 3 marks a uniform subtree: all of its records have the same position.
 *
 * TIGHTENING CODES. When the tree owns bits 4-7 of the axis byte (`tight`: the tree-owned
 * array, or the pm_photon layout), they hold a code that shrinks the node's cell toward the
 * records of its subtree: the cell is the root's bounding box cut by the split planes on the
 * path, each node's code applied to its own cell before its children are cut from it. Code 0
 * leaves the cell as it is; codes 1..12 move one face inward, by 1/2 or 7/8 of the cell's
 * extent on that axis; codes 13..15 move both faces of one axis inward by 1/4 each. The build
 * (kdtree.c) writes a code only when every record of the subtree stays inside the shrunk cell
 * as pm__tighten computes it, and the queries shrink their cells with the same function, so
 * the pruning stays exact. Every multiplier is a power of two (7/8 is ext - ext/8), so each
 * product is exact and a fused multiply-add could not change a result either.
 */
#ifndef PM_KDTREE_INTERNAL_H
#define PM_KDTREE_INTERNAL_H

#include "kdtree.h"

#define PM__AXIS_MASK 3u
#define PM__AXIS_UNIFORM 3u
#define PM__CODE_SHIFT 4u
#define PM__CODE_MAX 15u

struct pm_kdtree {
    char *rec;          /* the caller's records, in tree order */
    size_t stride;      /* bytes per record */
    size_t pos_offset;  /* float[3] position inside a record */
    int axis_offset;    /* axis byte inside a record, or -1 (then `axes` is used) */
    unsigned bucket;    /* B */
    uint32_t n;         /* records indexed */
    uint32_t dropped;   /* non-finite records after them */
    uint32_t depth;     /* D: internal nodes are heap nodes 1 .. 2^D - 1 */
    uint32_t ninternal; /* 2^D - 1 */
    uint32_t nleaves;   /* 2^D; leaf j is heap node 2^D + j */
    uint32_t leaf_q;    /* every bucket holds leaf_q records ... */
    uint32_t leaf_extra; /* ... and the first leaf_extra buckets one more */
    int tight;          /* bits 4-7 of the axis byte hold tightening codes (see above) */
    uint8_t *axes;      /* axis (and code) per internal node when axis_offset < 0, else NULL */
    float lo[3], hi[3]; /* bounding box of the indexed positions: the root's cell */
};

/* Shrink the cell [lo, hi] by tightening code c (1..15; see TIGHTENING CODES). */
static inline void pm__tighten(float lo[3], float hi[3], unsigned c) {
    if (c == 0) return;
    if (c <= 12) {
        unsigned f = c - 1, b = f >> 2;
        float ext = hi[b] - lo[b];
        float m = ext * 0.5f;
        if (f & 1u) { /* 7/8 */
            float e8 = ext * 0.125f;
            m = ext - e8;
        }
        if (f & 2u) hi[b] = hi[b] - m;
        else lo[b] = lo[b] + m;
    } else {
        unsigned b = c - 13;
        float ext = hi[b] - lo[b];
        float m = ext * 0.25f;
        lo[b] = lo[b] + m;
        hi[b] = hi[b] - m;
    }
}

static inline int pm__ilog2(uint64_t x) { return 63 - __builtin_clzll(x | 1); }

/* Records in buckets 0 .. j-1. */
static inline uint64_t pm__cum(const struct pm_kdtree *t, uint64_t j) {
    return j * t->leaf_q + (j < t->leaf_extra ? j : t->leaf_extra);
}

typedef struct {
    uint64_t begin, end;
} pm__range;

/* The record index ranges that make up the subtree of heap node p (at `level`): one range of
 * internal records per level below it, then one range of bucket records. Returns the count
 * (at most D + 1). Empty ranges are included. */
static inline int pm__subtree_ranges(const struct pm_kdtree *t, uint64_t p, int level,
                                     pm__range *r) {
    int nr = 0;
    int D = (int)t->depth;
    for (int s = 0; level + s < D; s++) {
        uint64_t first = p << s;
        r[nr].begin = first - 1;
        r[nr].end = first - 1 + ((uint64_t)1 << s);
        nr++;
    }
    uint64_t span = (uint64_t)1 << (D - level);
    uint64_t j0 = (p << (D - level)) - t->nleaves;
    r[nr].begin = t->ninternal + pm__cum(t, j0);
    r[nr].end = t->ninternal + pm__cum(t, j0 + span);
    nr++;
    return nr;
}

#endif /* PM_KDTREE_INTERNAL_H */
