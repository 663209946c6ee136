/* kdtree_internal.h: the layout of a built pm_kdtree, shared by kdtree.c (build) and
 * kdtree_query.c (queries). Internal: nothing here is part of the public API, and every
 * name carries the pm__ prefix (or is a struct member).
 *
 * The tree is fully described by its depth D and the bucket fill (q, extra): see the SHAPE
 * paragraph at the top of kdtree.c. The axis of internal node p (record p - 1) is the low two
 * bits of a byte, either in the record (axis_offset >= 0) or in the tree-owned `axes` array.
 * Axis code 3 marks a uniform subtree: all of its records have the same position.
 */
#ifndef PM_KDTREE_INTERNAL_H
#define PM_KDTREE_INTERNAL_H

#include "kdtree.h"

#define PM__AXIS_MASK 3u
#define PM__AXIS_UNIFORM 3u

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
    uint8_t *axes;      /* axis per internal node when axis_offset < 0, else NULL */
    float lo[3], hi[3]; /* bounding box of the indexed positions: the root's cell */
};

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
