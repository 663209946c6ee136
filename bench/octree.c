/* octree.c: the benchmark octree of octree.h, built top-down by in-place partitioning.
 *
 * BUILD. Non-finite records are first swapped to the tail. The root cell is the bounding cube
 * of the rest. A cell with more than `capacity` records is partitioned in place into its 8
 * octants by three two-way partitions (on z, then y, then x), which leaves the octants in order
 * 0..7 (octant = x | y << 1 | z << 2, a bit set when the coordinate is >= the cell's mid). The 8
 * children are appended to the cell array together, so a cell needs one child index and its
 * record range: 12 bytes. Every swap also swaps an index permutation; if an allocation fails
 * half way, that permutation undoes the reordering, so a failed build leaves the records as
 * they were (the interface promises it).
 *
 * QUERIES. Depth-first with an explicit stack whose entries carry the cell box and its squared
 * distance to the query. The children of a cell are pushed farthest first, so the nearest is
 * searched next; a popped cell whose box distance is not below the current bound (max_dist2,
 * or the k-th distance once k are held) is skipped. Child boxes are recomputed with the same
 * float expressions as the build, so a record is always inside its cell's box and, float
 * rounding being monotonic, its dist2 is never below the box's: pruning is exact. The k best
 * are kept as in the kd-tree: a plain array until k are found, then a max-heap on dist2.
 */
#include "octree.h"

#include "internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct oct_cell {
    uint32_t child; /* index of the first of 8 children; 0 for a leaf (0 is the root) */
    uint32_t begin, end;
} oct_cell;

struct bench_octree {
    const unsigned char *rec;
    size_t stride, pos_offset;
    size_t n, dropped;
    unsigned capacity;
    int depth;
    float lo[3], hi[3]; /* root cube */
    oct_cell *cells;
    size_t ncells, cap_cells;
};

/* Build state: the records as writable bytes, a swap buffer and the permutation. */
typedef struct oct_build {
    bench_octree *t;
    unsigned char *rec;
    unsigned char *tmp;
    uint32_t *perm;
    int failed;
} oct_build;

bench_octree_config bench_octree_photon_config(unsigned capacity) {
    bench_octree_config c;
    c.stride = 20;
    c.pos_offset = 0;
    c.capacity = capacity;
    return c;
}

static inline void load_pos(const unsigned char *rec, size_t stride, size_t off, size_t i,
                            float p[3]) {
    memcpy(p, rec + i * stride + off, 3 * sizeof(float));
}

static void swap_rec(oct_build *b, size_t i, size_t j) {
    size_t s = b->t->stride;
    uint32_t tp;
    if (i == j) return;
    memcpy(b->tmp, b->rec + i * s, s);
    memcpy(b->rec + i * s, b->rec + j * s, s);
    memcpy(b->rec + j * s, b->tmp, s);
    tp = b->perm[i];
    b->perm[i] = b->perm[j];
    b->perm[j] = tp;
}

/* Two-way partition of [begin, end) by coordinate `axis` >= mid; returns the split point. */
static size_t partition(oct_build *b, size_t begin, size_t end, int axis, float mid) {
    size_t i = begin, j = end;
    const bench_octree *t = b->t;
    while (i < j) {
        float p[3];
        load_pos(b->rec, t->stride, t->pos_offset, i, p);
        if (p[axis] >= mid) {
            j--;
            swap_rec(b, i, j);
        } else {
            i++;
        }
    }
    return i;
}

static inline float cell_mid(float lo, float hi) { return lo + (hi - lo) * 0.5f; }

/* The box of child c of the cell [lo, hi]: the same expressions in build and query. */
static inline void child_box(const float lo[3], const float hi[3], const float mid[3], int c,
                             float clo[3], float chi[3]) {
    for (int a = 0; a < 3; a++) {
        if (c >> a & 1) {
            clo[a] = mid[a];
            chi[a] = hi[a];
        } else {
            clo[a] = lo[a];
            chi[a] = mid[a];
        }
    }
}

static int add_cells(bench_octree *t, size_t count, uint32_t *first) {
    if (t->ncells + count > t->cap_cells) {
        size_t nc = t->cap_cells ? t->cap_cells * 2 : 64;
        while (nc < t->ncells + count) nc *= 2;
        if (nc > UINT32_MAX) return PM_ERANGE;
        oct_cell *c = realloc(t->cells, nc * sizeof *c);
        if (!c) return PM_ENOMEM;
        t->cells = c;
        t->cap_cells = nc;
    }
    *first = (uint32_t)t->ncells;
    t->ncells += count;
    return 0;
}

static int build_cell(oct_build *b, uint32_t ci, const float lo[3], const float hi[3], int depth) {
    bench_octree *t = b->t;
    size_t begin = t->cells[ci].begin, end = t->cells[ci].end;
    float mid[3];
    size_t bound[9];
    uint32_t first;
    int rc, splittable = 0;

    t->cells[ci].child = 0;
    if (depth > t->depth) t->depth = depth;
    if (end - begin <= t->capacity || depth >= BENCH_OCTREE_MAX_DEPTH) return 0;
    for (int a = 0; a < 3; a++) {
        mid[a] = cell_mid(lo[a], hi[a]);
        /* A cell splits only if some axis still has room between lo and hi. */
        if (mid[a] > lo[a] && mid[a] < hi[a]) splittable = 1;
    }
    if (!splittable) return 0;

    /* z, then y within each half, then x within each quarter: octants end up in order. */
    bound[0] = begin;
    bound[8] = end;
    bound[4] = partition(b, begin, end, 2, mid[2]);
    bound[2] = partition(b, bound[0], bound[4], 1, mid[1]);
    bound[6] = partition(b, bound[4], bound[8], 1, mid[1]);
    for (int q = 0; q < 8; q += 2) bound[q + 1] = partition(b, bound[q], bound[q + 2], 0, mid[0]);

    if ((rc = add_cells(t, 8, &first)) != 0) return rc;
    t->cells[ci].child = first;
    for (uint32_t c = 0; c < 8; c++) {
        t->cells[first + c].child = 0;
        t->cells[first + c].begin = (uint32_t)bound[c];
        t->cells[first + c].end = (uint32_t)bound[c + 1];
    }
    for (int c = 0; c < 8; c++) {
        float clo[3], chi[3];
        child_box(lo, hi, mid, c, clo, chi);
        if ((rc = build_cell(b, first + (uint32_t)c, clo, chi, depth + 1)) != 0) return rc;
    }
    return 0;
}

/* Undo the reordering: perm[i] is the original index of the record now at i. */
static void restore_order(oct_build *b, size_t n) {
    for (size_t i = 0; i < n; i++) {
        while (b->perm[i] != i) swap_rec(b, i, b->perm[i]);
    }
}

int bench_octree_build(bench_octree **out, void *records, size_t n, const bench_octree_config *cfg,
                    uint32_t *perm) {
    bench_octree *t;
    oct_build b;
    size_t nf;
    int rc = 0;

    if (!out) return PM_EINVAL;
    *out = NULL;
    if (!cfg || cfg->stride < 12 || cfg->pos_offset + 12 > cfg->stride || cfg->capacity < 1 ||
        (n > 0 && !records))
        return PM_EINVAL;
    if (n >= (size_t)UINT32_MAX) return PM_ERANGE;

    t = calloc(1, sizeof *t);
    if (!t) return PM_ENOMEM;
    t->rec = records;
    t->stride = cfg->stride;
    t->pos_offset = cfg->pos_offset;
    t->capacity = cfg->capacity;
    memset(&b, 0, sizeof b);
    b.t = t;
    b.rec = records;
    b.tmp = malloc(cfg->stride);
    b.perm = perm ? perm : malloc((n ? n : 1) * sizeof *b.perm);
    if (!b.tmp || !b.perm) {
        rc = PM_ENOMEM;
        goto fail_early;
    }
    for (size_t i = 0; i < n; i++) b.perm[i] = (uint32_t)i;

    /* Finite records to the front, non-finite ones to the tail (dropped, counted). */
    nf = n;
    for (size_t i = 0; i < nf;) {
        float p[3];
        load_pos(b.rec, t->stride, t->pos_offset, i, p);
        if (isfinite(p[0]) && isfinite(p[1]) && isfinite(p[2])) {
            i++;
        } else {
            nf--;
            swap_rec(&b, i, nf);
        }
    }
    t->n = nf;
    t->dropped = n - nf;

    {
        uint32_t root;
        float mn[3] = {0, 0, 0}, mx[3] = {0, 0, 0}, ext = 0;
        for (size_t i = 0; i < nf; i++) {
            float p[3];
            load_pos(b.rec, t->stride, t->pos_offset, i, p);
            for (int a = 0; a < 3; a++) {
                if (i == 0 || p[a] < mn[a]) mn[a] = p[a];
                if (i == 0 || p[a] > mx[a]) mx[a] = p[a];
            }
        }
        for (int a = 0; a < 3; a++)
            if (mx[a] - mn[a] > ext) ext = mx[a] - mn[a];
        for (int a = 0; a < 3; a++) {
            t->lo[a] = mn[a];
            t->hi[a] = mn[a] + ext;
            if (t->hi[a] < mx[a]) t->hi[a] = mx[a]; /* rounding must not cut the last point off */
        }
        if ((rc = add_cells(t, 1, &root)) != 0) goto fail;
        t->cells[0].child = 0;
        t->cells[0].begin = 0;
        t->cells[0].end = (uint32_t)nf;
        if ((rc = build_cell(&b, 0, t->lo, t->hi, 0)) != 0) goto fail;
    }
    /* Trim the cell array to its size; a failed shrink keeps the larger block. */
    {
        oct_cell *c = realloc(t->cells, t->ncells * sizeof *c);
        if (c) {
            t->cells = c;
            t->cap_cells = t->ncells;
        }
    }
    free(b.tmp);
    if (!perm) free(b.perm);
    *out = t;
    return 0;

fail:
    restore_order(&b, n);
fail_early:
    free(b.tmp);
    if (!perm) free(b.perm);
    free(t->cells);
    free(t);
    return rc;
}

void bench_octree_free(bench_octree *tree) {
    if (!tree) return;
    free(tree->cells);
    free(tree);
}

size_t bench_octree_size(const bench_octree *tree) { return tree ? tree->n : 0; }
size_t bench_octree_dropped(const bench_octree *tree) { return tree ? tree->dropped : 0; }
size_t bench_octree_index_bytes(const bench_octree *tree) {
    return tree ? sizeof *tree + tree->cap_cells * sizeof(oct_cell) : 0;
}
size_t bench_octree_cells(const bench_octree *tree) { return tree ? tree->ncells : 0; }
int bench_octree_depth(const bench_octree *tree) { return tree ? tree->depth : 0; }
unsigned bench_octree_capacity(const bench_octree *tree) { return tree ? tree->capacity : 0; }
const float *bench_octree_pos(const bench_octree *tree, uint32_t i) {
    return (const float *)(const void *)(tree->rec + (size_t)i * tree->stride + tree->pos_offset);
}

/* ---- queries ------------------------------------------------------------------------------ */

typedef struct oct_item {
    float d2;
    uint32_t cell;
    float lo[3], hi[3];
} oct_item;

/* Each level pushes at most 8 children and pops one, so this bounds the stack. */
#define OCT_STACK (8 * (BENCH_OCTREE_MAX_DEPTH + 2))

static inline float box_dist2(const float q[3], const float lo[3], const float hi[3]) {
    float d2 = 0;
    for (int a = 0; a < 3; a++) {
        float g = 0;
        if (q[a] < lo[a]) g = lo[a] - q[a];
        else if (q[a] > hi[a]) g = q[a] - hi[a];
        d2 += g * g;
    }
    return d2;
}

static inline float rec_dist2(const bench_octree *t, const float q[3], uint32_t i) {
    float p[3];
    load_pos(t->rec, t->stride, t->pos_offset, i, p);
    float dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
    return dx * dx + dy * dy + dz * dz;
}

static int check_query(const float q[3], float r2) {
    if (isnan(r2) || !isfinite(q[0]) || !isfinite(q[1]) || !isfinite(q[2])) return PM_ENONFINITE;
    return 0;
}

/* Push the non-empty children of `it` whose box distance is below bound, nearest on top. */
static int push_children(const bench_octree *t, const oct_item *it, const float q[3], float bound,
                         oct_item *stack, int sp) {
    const oct_cell *cell = &t->cells[it->cell];
    oct_item kids[8];
    int nk = 0;
    float mid[3];
    for (int a = 0; a < 3; a++) mid[a] = cell_mid(it->lo[a], it->hi[a]);
    for (int c = 0; c < 8; c++) {
        uint32_t ci = cell->child + (uint32_t)c;
        if (t->cells[ci].begin == t->cells[ci].end) continue;
        oct_item k;
        child_box(it->lo, it->hi, mid, c, k.lo, k.hi);
        k.d2 = box_dist2(q, k.lo, k.hi);
        if (k.d2 >= bound) continue; /* NaN bound: unlimited */
        k.cell = ci;
        /* insertion sort, descending d2, so the nearest ends last (popped first) */
        int j = nk++;
        while (j > 0 && kids[j - 1].d2 < k.d2) {
            kids[j] = kids[j - 1];
            j--;
        }
        kids[j] = k;
    }
    for (int j = 0; j < nk; j++) stack[sp++] = kids[j];
    return sp;
}

/* The root cell on an empty stack; returns the stack size. */
static int push_root(const bench_octree *t, const float q[3], oct_item *stack) {
    stack[0].cell = 0;
    memcpy(stack[0].lo, t->lo, sizeof t->lo);
    memcpy(stack[0].hi, t->hi, sizeof t->hi);
    stack[0].d2 = box_dist2(q, t->lo, t->hi);
    return 1;
}

/* Pops cells, nearest first, until a leaf whose box is within bound (NaN: unlimited), pushing
 * the children of the internal cells met; returns that leaf, or NULL when the stack is empty.
 * bound cannot change on the way: no record is taken between two leaves. */
static const oct_cell *next_leaf(const bench_octree *t, const float q[3], float bound,
                                 oct_item *stack, int *sp, uint64_t *nodes) {
    while (*sp > 0) {
        const oct_item it = stack[--*sp];
        if (it.d2 >= bound) continue;
        const oct_cell *cell = &t->cells[it.cell];
        (*nodes)++;
        if (!cell->child) return cell;
        *sp = push_children(t, &it, q, bound, stack, *sp);
    }
    return NULL;
}

int bench_octree_knn(const bench_octree *tree, const float q[3], unsigned k, float max_dist2,
                  pm_neighbor *out, unsigned flags, pm_query_stats *stats) {
    oct_item stack[OCT_STACK];
    int sp = 0, rc;
    unsigned found = 0;
    uint64_t nodes = 0, evals = 0;

    if (!tree || !q) return PM_EINVAL;
    if ((rc = check_query(q, max_dist2)) != 0) return rc;
    if (k == 0 || tree->n == 0 || !(max_dist2 > 0)) return 0;
    if (!out) return PM_EINVAL;

    /* Unlimited is NaN inside, and every test is !(x >= bound), as in the kd-tree: then a
     * record whose float dist2 overflowed to +inf is still accepted. */
    const float r2 = max_dist2 == INFINITY ? NAN : max_dist2;
    sp = push_root(tree, q, stack);
    const oct_cell *cell;
    while ((cell = next_leaf(tree, q, found == k ? out[0].dist2 : r2, stack, &sp, &nodes))) {
        evals += cell->end - cell->begin;
        for (uint32_t i = cell->begin; i < cell->end; i++) {
            float d2 = rec_dist2(tree, q, i);
            if (found < k) {
                if (!(d2 >= r2)) {
                    out[found].dist2 = d2;
                    out[found].index = i;
                    if (++found == k) pm__heapify(out, k);
                }
            } else if (d2 < out[0].dist2) {
                pm_neighbor nb = {d2, i};
                pm__heap_replace_top(out, k, nb);
            }
        }
    }
    if (stats) {
        stats->nodes_visited += nodes;
        stats->dist_evals += evals;
    }
    if (flags & PM_SORT) {
        if (found <= PM__SORT_KEYS_MAX) pm__nb_sort_keys(out, found);
        else pm__nb_sort(out, found);
    }
    return (int)found;
}

long bench_octree_radius(const bench_octree *tree, const float q[3], float r2, pm_neighbor *out,
                      size_t cap, unsigned flags, pm_query_stats *stats) {
    oct_item stack[OCT_STACK];
    int sp, rc;
    long total = 0;
    uint64_t nodes = 0, evals = 0;

    if (!tree || !q) return PM_EINVAL;
    if ((rc = check_query(q, r2)) != 0) return rc;
    if (tree->n == 0 || !(r2 > 0)) return 0;
    if (cap > 0 && !out) return PM_EINVAL;

    if (r2 == INFINITY) r2 = NAN; /* unlimited: see bench_octree_knn */
    sp = push_root(tree, q, stack);
    const oct_cell *cell;
    while ((cell = next_leaf(tree, q, r2, stack, &sp, &nodes))) {
        evals += cell->end - cell->begin;
        for (uint32_t i = cell->begin; i < cell->end; i++) {
            float d2 = rec_dist2(tree, q, i);
            if (!(d2 >= r2)) {
                if ((size_t)total < cap) {
                    out[total].dist2 = d2;
                    out[total].index = i;
                }
                total++;
            }
        }
    }
    if (stats) {
        stats->nodes_visited += nodes;
        stats->dist_evals += evals;
    }
    if ((flags & PM_SORT) && (size_t)total <= cap) {
        if ((size_t)total <= PM__SORT_KEYS_MAX) pm__nb_sort_keys(out, (unsigned)total);
        else pm__nb_sort(out, (size_t)total);
    }
    return total;
}
