/* lk_irradiance.c: the partitioned precomputed irradiance (lookup.h, PRECOMPUTED IRRADIANCE),
 * built once, collectively: each rank chooses a quarter of its photons as queries, every rank
 * answers every query from its part, each owner combines the parts of its queries into records
 * and keeps its own records only, in a side_cache whose lookups ask every rank.
 *
 * It is the distributed twin of photon_sides.c's side_cache_build: the same choice of photons,
 * side rule, widening past a wall, indirect power, sparse rule and disc fraction, taken over
 * the ranks' parts. The allocations are made in a fixed order through dist_irr_malloc, so that
 * the test hook PM_RENDER_MPI_TEST_ENOMEM="RANK irradiance N" (ranks.h) names one of them.
 */
#include "lk_irradiance.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ranks.h"
#include "photonmap/common.h"
#include "base/stats.h"

#ifdef _OPENMP
#include <omp.h>
#endif

/* This rank's part of the precomputed estimate at query q: its k/M nearest photons on q's side,
 * by side_cache_build's rule (side_precomp_neighbours: widened past a wall, visible ones only). */
static void answer_side(const scene *s, const pm_kdtree *t, const pm_photon *ph, const uint32_t *path,
                        const float *hfree, unsigned k, float max_dist2, const lk_query *q, pm_neighbor *nb,
                        uint32_t *ids, lk_part *out) {
    unsigned km = lk_per_map(k);
    pm_combine_acc acc;
    pm_combine_init(&acc);
    int wall;
    float limit;
    int found = side_precomp_neighbours(s, t, ph, hfree, q->x, q->n, q->h, km, max_dist2, nb, &wall, &limit, NULL);
    pm_combine_add(&acc, t ? ph : NULL, nb, (unsigned)found, km, limit, PM_BIAS_AREA, q->x);
    /* The value is the indirect irradiance, as side_cache_build's: direct photons count in
     * the radius (and in the photons found) but not in the power. */
    for (int i = 0; i < found; i++) {
        if (pm_photon_kind(&ph[nb[i].index]) != PM_KIND_DIRECT) continue;
        float pw[3];
        pm_rgbe_decode(ph[nb[i].index].power, pw);
        for (int c = 0; c < 3; c++) acc.power[c] -= pw[c];
    }
    for (int c = 0; c < 3; c++)
        if (acc.power[c] < 0) acc.power[c] = 0;
    lk_part_from_acc(&acc, out);
    out->wall = (uint8_t)wall;
    /* The part's distinct photon paths: a part is a run of the whole map's order (photon_maps.h,
     * PHOTON PATHS), so a path lies in one part, but for the at most M - 1 that straddle two
     * parts' boundaries (counted in both: a few paths too many in a whole map, only near
     * those paths' records). */
    out->paths = (uint16_t)(t ? side_count_paths(path, nb, found, SIDE_MIN_PATHS, ids) : 0);
}

static int side_fail(side_cache *c, char *err, size_t errcap, const char *what) {
    side_cache_free(c);
    snprintf(err, errcap, "precomputing irradiance (partitioned maps): %s", what);
    return PM_ENOMEM;
}

/* The build's collectives, nonblocking on every rank (nonblocking and blocking collectives do
 * not match each other) and waited for with dist_wait: rank 0 hears a rank that failed here
 * (an allocation, its own error) instead of waiting for it in the collective. */
static void ireduce(const unsigned long long *in, unsigned long long *out, MPI_Op op) {
    MPI_Request req;
    MPI_Ireduce(in, out, 1, MPI_UNSIGNED_LONG_LONG, op, 0, MPI_COMM_WORLD, &req);
    dist_wait(&req);
}

/* One build: its inputs, this rank's chosen photons and their queries, and the per-rank counts
 * of the collectives. */
typedef struct side_build {
    const scene *s;
    const pm_kdtree *global;
    const pm_photon *ph;
    size_t n;
    unsigned k;
    float max_dist2;
    float *hfree;         /* every photon's free height */
    uint32_t *which;      /* the chosen photons (indices into ph) */
    const uint32_t *path; /* the part's path ids, in its tree's order, or NULL */
    size_t m;             /* chosen photons: this rank's queries */
    lk_query *mine;       /* their queries */
    int *cnt, *dsp, *cnt2; /* per rank: its queries; a collective's displacements and counts */
    long long total;      /* the queries of all ranks */
    lk_part *back;        /* every rank's parts of this rank's queries: rank r's of query j at [r m + j] */
    uint64_t bytes;       /* sent by this rank */
} side_build;

/* A record this rank keeps: its photon with E as power, the radius^2 of the combined disc (0:
 * never read) and its free height. */
typedef struct side_rec {
    pm_photon p;
    float r2, h;
} side_rec;

/* This rank's chosen photons and every photon's free height (photon_sides.c's rules), and their
 * queries. */
static void choose(side_build *b) {
    size_t n = b->n;
    b->hfree = dist_irr_malloc((n ? n : 1) * sizeof *b->hfree);
    b->which = dist_irr_malloc((n ? n : 1) * sizeof *b->which);
    if (!b->hfree || !b->which) dist_die("out of memory precomputing irradiance");
    side_free_heights(b->s, b->ph, n, b->max_dist2, b->hfree);
    /* The part's path ids, in its tree's order (photon_tree_build_global; NULL if the mapper
     * built the tree without them: every photon then counts as a path of its own). */
    b->path = lk.maps && lk.maps->global == b->ph ? lk.maps->global_path : NULL;
    for (size_t i = 0; i < n; i++)
        if (pm_kdtree_height(b->global, (uint32_t)i) >= 2) b->which[b->m++] = (uint32_t)i;
    size_t m = b->m;
    int M = lk.size;
    b->mine = dist_irr_malloc((m ? m : 1) * sizeof *b->mine);
    b->cnt = dist_irr_malloc((size_t)M * sizeof *b->cnt);
    b->dsp = dist_irr_malloc((size_t)M * sizeof *b->dsp);
    b->cnt2 = dist_irr_malloc((size_t)M * sizeof *b->cnt2);
    if (!b->mine || !b->cnt || !b->dsp || !b->cnt2) dist_die("out of memory precomputing irradiance");
    for (size_t j = 0; j < m; j++) {
        const pm_photon *p = &b->ph[b->which[j]];
        lk_query *q = &b->mine[j];
        memset(q, 0, sizeof *q);
        memcpy(q->x, p->pos, sizeof q->x);
        pm_normal_decode(p->normal, q->n);
        q->h = b->hfree[b->which[j]];
        q->map = LK_BUILD;
    }
}

/* Every rank's queries to every rank (returned: the caller frees it); *ans and b->back get room
 * for the answers. */
static lk_query *share_queries(side_build *b, lk_part **ans) {
    int M = lk.size, mq = (int)b->m;
    MPI_Request req;
    MPI_Iallgather(&mq, 1, MPI_INT, b->cnt, 1, MPI_INT, MPI_COMM_WORLD, &req);
    dist_wait(&req);
    b->total = 0;
    for (int r = 0; r < M; r++) b->total += b->cnt[r];
    if (b->total * (long long)sizeof(lk_part) > INT32_MAX)
        dist_die("precomputed irradiance: the queries exceed 2 GiB (MPI's int counts)");
    size_t t1 = (size_t)(b->total ? b->total : 1);
    lk_query *all = dist_irr_malloc(t1 * sizeof *all);
    *ans = dist_irr_malloc(t1 * sizeof **ans);
    b->back = dist_irr_malloc((b->m ? b->m : 1) * (size_t)M * sizeof *b->back);
    if (!all || !*ans || !b->back) dist_die("out of memory precomputing irradiance");
    for (int r = 0, off = 0; r < M; r++) {
        b->dsp[r] = off * (int)sizeof(lk_query);
        off += b->cnt[r];
        b->cnt2[r] = b->cnt[r] * (int)sizeof(lk_query);
    }
    MPI_Iallgatherv(b->mine, mq * (int)sizeof(lk_query), MPI_BYTE, all, b->cnt2, b->dsp, MPI_BYTE,
                    MPI_COMM_WORLD, &req);
    dist_wait(&req);
    b->bytes += (uint64_t)b->m * sizeof(lk_query) * (uint64_t)(M - 1);
    return all;
}

/* This rank's parts of every query, on OpenMP threads. */
static void answer_all(const side_build *b, const lk_query *all, lk_part *ans) {
    unsigned want = SIDE_WIDEN * lk_per_map(b->k);
    int fail = 0;
#ifdef _OPENMP
#pragma omp parallel reduction(| : fail)
#endif
    {
        pm_neighbor *nb = malloc((size_t)want * sizeof *nb);
        uint32_t *ids = malloc(SIDE_MIN_PATHS * sizeof *ids); /* side_count_paths's scratch */
        if (!nb || !ids) fail = 1;
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 64)
#endif
        for (long long i = 0; i < b->total; i++)
            if (nb && ids)
                answer_side(b->s, b->global, b->ph, b->path, b->hfree, b->k, b->max_dist2, &all[i], nb, ids,
                            &ans[i]);
        free(nb);
        free(ids);
    }
    if (fail) dist_die("out of memory precomputing irradiance");
}

/* Each owner gets every rank's parts of its queries: rank r's block of ans goes to r (b->back). */
static void return_parts(side_build *b, const lk_part *ans) {
    int M = lk.size, mq = (int)b->m;
    for (int r = 0, off = 0; r < M; r++) {
        b->cnt2[r] = b->cnt[r] * (int)sizeof(lk_part);
        b->dsp[r] = off * (int)sizeof(lk_part);
        off += b->cnt[r];
    }
    int *rc_ = dist_irr_malloc((size_t)M * sizeof *rc_);
    int *rd = dist_irr_malloc((size_t)M * sizeof *rd);
    if (!rc_ || !rd) dist_die("out of memory precomputing irradiance");
    for (int r = 0; r < M; r++) {
        rc_[r] = mq * (int)sizeof(lk_part);
        rd[r] = r * mq * (int)sizeof(lk_part);
    }
    MPI_Request req;
    MPI_Ialltoallv(ans, b->cnt2, b->dsp, MPI_BYTE, b->back, rc_, rd, MPI_BYTE, MPI_COMM_WORLD, &req);
    dist_wait(&req);
    b->bytes += (uint64_t)(b->total - mq) * sizeof(lk_part);
    free(rc_);
    free(rd);
}

/* Combine: E of this rank's chosen photons, with the radius^2 of the combined disc. *walls: the
 * records whose estimate met a wall; *sparse: those with too few photon paths. */
static side_rec *combine(const side_build *b, size_t *walls_out, size_t *sparse_out) {
    size_t m = b->m;
    int M = lk.size;
    side_rec *recs = dist_irr_calloc(m ? m : 1, sizeof *recs);
    if (!recs) dist_die("out of memory precomputing irradiance");
    size_t walls = 0, sparse = 0;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 64) reduction(+ : walls, sparse)
#endif
    for (size_t j = 0; j < m; j++) {
        pm_combine_acc acc;
        pm_combine_init(&acc);
        acc.bias = PM_BIAS_AREA;
        int wall = 0;
        unsigned paths = 0;
        for (int r = 0; r < M; r++) {
            lk_add_part(&acc, &b->back[(size_t)r * m + j]);
            wall |= b->back[(size_t)r * m + j].wall;
            paths += b->back[(size_t)r * m + j].paths;
        }
        double E[3];
        pm_combine_finish(&acc, E, NULL);
        double r2 = acc.r2_sum / M;
        /* Too few photon paths in all the parts: never looked up (photon_sides.h, sparse
         * estimates). */
        int readable = side_estimate_readable(paths);
        if (wall) {
            double frac = side_disc_fraction(b->s, lk_v3f(b->mine[j].x), lk_v3f(b->mine[j].n), sqrt(r2));
            for (int ch = 0; ch < 3; ch++) E[ch] /= frac;
            walls++;
        }
        float ef[3] = {(float)E[0], (float)E[1], (float)E[2]};
        recs[j].p = b->ph[b->which[j]];
        pm_rgbe_encode(ef, recs[j].p.power);
        recs[j].r2 = readable ? (float)r2 : 0.0f;
        sparse += !readable;
        recs[j].h = b->hfree[b->which[j]];
    }
    *walls_out = walls;
    *sparse_out = sparse;
    return recs;
}

/* This rank keeps its own records in c (lookups ask every rank: lookup.c's side_remote). A rank
 * with none keeps one that no lookup accepts (radius 0), so that the mapper, which looks up
 * only where a cache exists, asks the others too. Frees recs. 0 or a negative code; *N: the
 * records kept. */
static int keep_records(side_cache *c, side_rec *recs, size_t m, long long total, size_t *N_out, char *err,
                        size_t errcap) {
    size_t N = m ? m : (total ? 1 : 0);
    *N_out = N;
    pm_photon *rp = dist_irr_malloc((N ? N : 1) * sizeof *rp);
    float *r2 = dist_irr_malloc((N ? N : 1) * sizeof *r2);
    float *hf = dist_irr_malloc((N ? N : 1) * sizeof *hf);
    if (!rp || !r2 || !hf) {
        free(rp);
        free(r2);
        free(hf);
        free(recs);
        return side_fail(c, err, errcap, "out of memory");
    }
    for (size_t i = 0; i < m; i++) {
        rp[i] = recs[i].p;
        r2[i] = recs[i].r2;
        hf[i] = recs[i].h;
    }
    if (m == 0 && N) {
        memset(rp, 0, sizeof *rp);
        r2[0] = hf[0] = 0;
    }
    free(recs);
    int rc = side_cache_from_records(c, rp, r2, hf, N, err, errcap);
    free(rp);
    free(r2);
    free(hf);
    return rc;
}

/* The build's figures, summed over the ranks: the records each rank keeps and their bytes (an
 * "MPI:" line), the walls met and sparse records (into c), and the bytes sent (statistics). */
static void report(side_cache *c, size_t m, size_t N, long long total, size_t walls, size_t sparse,
                   uint64_t bytes) {
    if (total > 0) {
        /* The cache's own bytes: the module's records, radii, indices and lookup tree, and a
         * free height per record. All parts together are about what every rank held when
         * each built the whole cache. */
        unsigned long long here = m, most = 0, least = 0;
        unsigned long long cb = (unsigned long long)(pm_irradiance_bytes(c->irr) + N * sizeof(float));
        unsigned long long cmax = 0, csum = 0;
        ireduce(&here, &most, MPI_MAX);
        ireduce(&here, &least, MPI_MIN);
        ireduce(&cb, &cmax, MPI_MAX);
        ireduce(&cb, &csum, MPI_SUM);
        if (lk.rank == 0)
            printf("MPI: partitioned precomputed irradiance: each rank keeps its own records, "
                   "%llu to %llu of %lld (at most %llu bytes on a rank, %llu on all); lookups ask "
                   "every rank\n", least, most, total, cmax, csum);
    }
    unsigned long long w = walls, wsum = 0, b = bytes, bsum = 0, sp = sparse, spsum = 0;
    ireduce(&w, &wsum, MPI_SUM);
    ireduce(&sp, &spsum, MPI_SUM);
    c->sparse = (size_t)spsum;
    c->indirect_only = 1; /* the mapper adds a gather hit's direct light itself */
    ireduce(&b, &bsum, MPI_SUM);
    c->researched = (size_t)wsum;
    if (lk.rank == 0) {
        stat_add(lk.st_side_bytes, bsum);
        stat_add(lk.st_side_queries, (uint64_t)total);
    }
}

int lk_side_build(side_cache *c, const scene *s, const pm_kdtree *global, const pm_photon *ph, size_t n,
                  unsigned k, float max_dist2, char *err, size_t errcap) {
    memset(c, 0, sizeof *c);
    dist_collective_begin();
    side_build b = {.s = s, .global = global, .ph = ph, .n = n, .k = k, .max_dist2 = max_dist2};
    choose(&b);                                /* 1. this rank's queries */
    lk_part *ans;
    lk_query *all = share_queries(&b, &ans);   /*    to every rank */
    answer_all(&b, all, ans);                  /* 2. this rank's parts of every query */
    return_parts(&b, ans);                     /* 3. to their owners */
    free(ans);
    free(all);
    size_t walls = 0, sparse = 0, N = 0;
    side_rec *recs = combine(&b, &walls, &sparse); /* 4. the records of this rank's queries */
    free(b.back);
    free(b.mine);
    free(b.which);
    free(b.hfree);
    free(b.cnt);
    free(b.dsp);
    free(b.cnt2);
    int rc = keep_records(c, recs, b.m, b.total, &N, err, errcap); /* 5. kept here */
    if (rc < 0) return rc;
    c->n = (size_t)b.total; /* the records of all ranks, as side_cache_build's count */
    lk.side = c;
    lk.scene = s;
    report(c, b.m, N, b.total, walls, sparse, b.bytes);
    return 0;
}
