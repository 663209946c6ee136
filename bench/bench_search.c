/* bench_search.c: nearest-neighbour search benchmark — our kd-tree (iterative and recursive,
 * bucket sizes B), the octree (leaf capacities), FLANN's exact single kd-tree (leaf sizes) and
 * randomized 4-tree forest (checks), and brute force, on uniform, photon-like and dumped maps.
 *
 * HOW IT MEASURES. Each structure is built `runs` times from the same unordered points (the
 * build time is the median); bytes per photon are the record bytes plus what the index owns
 * (ours: pm_*_index_bytes, checked against the heap growth; FLANN: the heap growth across its
 * build, measured with mallinfo2, which covers its point copy and its index). Queries come from
 * the same distribution as the points. Each configuration is first VERIFIED on the first G
 * queries one at a time against brute force (recall, exact fraction; work counters from
 * pm_query_stats), then TIMED: a group of configurations is run round-robin `runs` times over
 * the same query prefix (as many queries as fill the target time), so that every median in a
 * group was measured side by side under the same machine load.
 *
 * FLANN is raced at its best (see /work/shared/BENCH-NOTES.md): cores = 1 for one thread (its
 * default 0 means OpenMP on every call), sorted = 1, squared radii, and k-NN in batches of 256
 * queries because each C call costs about a microsecond. Its k-NN has no maximum radius, so it
 * is measured twice: batched unlimited k-NN ("knn_batch") and radius search with max_neighbors
 * = k ("radius_maxnn", one query per call, which is what honours the radius). The headline takes
 * FLANN's faster of the two.
 *
 * OUTPUT (columns documented in bench/README.md): build.csv, queries.csv, headline.csv in the
 * output directory. Progress on stderr. Run with --help for options.
 */
#define _GNU_SOURCE
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <flann/flann.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#if defined(__has_include)
#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h>
#endif
#endif
#ifndef CALLGRIND_START_INSTRUMENTATION
#define CALLGRIND_START_INSTRUMENTATION
#define CALLGRIND_STOP_INSTRUMENTATION
#endif

#include "bench.h"
#include "kdtree.h"
#include "octree.h"
#include "photon.h"

/* ---- options ---- */
static struct {
    int quick;
    const char *out;
    const char *map;
    int threads;
    int runs;
    size_t nh;          /* headline N */
    double target;      /* seconds per timed run */
    size_t pool;        /* queries per data set */
    size_t g;           /* verified queries */
    int dists;          /* bit mask of 1 << BENCH_* */
    int sweeps;         /* bit mask of SW_* */
    uint64_t seed;
    const char *probe;  /* INDEX:VARIANT:PARAM for a profiler run */
    double probe_r2;
    size_t probe_queries;
} opt;

enum { SW_PARAM = 1, SW_K = 2, SW_RADIUS = 4, SW_N = 8, SW_HEAD = 16, SW_ALL = 31 };

static const unsigned KD_B[] = {1, 2, 4, 8, 16, 32};
static const unsigned OCT_CAP[] = {1, 4, 16, 64, 190, 1000, 10000};
static const int FL_LEAF[] = {1, 4, 10, 16, 32, 64};
static const int FL_CHECKS[] = {16, 32, 64, 128, 256};
static const unsigned KS[] = {1, 10, 50, 100, 500};
static const double R_REL[] = {0.1, 0.2, 0.35, 0.5, 0.7, 1.0, 1.4, 2.0, 4.0, INFINITY};
#define NELEM(a) (sizeof(a) / sizeof((a)[0]))
#define KMAX 500u
#define HEAD_K 50u
/* Result buffer of a plain radius search. FLANN's C API copies its whole buffer on every call,
 * so a huge buffer would handicap it; 4096 holds every answer except in the dense floor disc,
 * where both FLANN and ours are scored against min(true count, 4096) entries written. */
#define RADIUS_CAP 4096u
#define FL_BATCH 256

static FILE *g_build_csv, *g_query_csv, *g_head_csv;
static volatile uint64_t g_sink;

/* ---- data sets ---- */
typedef struct dataset {
    int dist;
    size_t n;
    pm_photon *ph; /* original order, never modified */
    float *xyz;    /* n x 3, for FLANN and brute force */
    float *q;      /* pool x 3 queries */
    size_t nq;
    bench_truth truth; /* first opt.g queries */
    float r50_2;       /* median over verified queries of the 50th-nearest dist2 */
} dataset;

static void dataset_init(dataset *d, int dist, size_t n, const pm_photon *from_file) {
    memset(d, 0, sizeof *d);
    d->dist = dist;
    d->n = n;
    d->ph = malloc(n * sizeof *d->ph);
    d->xyz = malloc(n * 3 * sizeof *d->xyz);
    d->nq = opt.pool;
    d->q = malloc(d->nq * 3 * sizeof *d->q);
    if (!d->ph || !d->xyz || !d->q) {
        fprintf(stderr, "out of memory\n");
        exit(2);
    }
    float jitter = 0;
    if (from_file) {
        float mn[3] = {INFINITY, INFINITY, INFINITY}, mx[3] = {-INFINITY, -INFINITY, -INFINITY};
        memcpy(d->ph, from_file, n * sizeof *d->ph);
        /* The renderer saves its maps in its own tree order, which would hand every index a
         * presorted input (faster builds, cache-friendly FLANN copies); shuffle it so that a
         * dumped map is built from unordered photons like the synthetic sets. */
        bench_rng rng;
        bench_rng_seed(&rng, opt.seed + 99);
        for (size_t i = n - 1; i > 0; i--) {
            size_t j = (size_t)(bench_rng_u64(&rng) % (i + 1));
            pm_photon t = d->ph[i];
            d->ph[i] = d->ph[j];
            d->ph[j] = t;
        }
        for (size_t i = 0; i < n; i++)
            for (int a = 0; a < 3; a++) {
                if (d->ph[i].pos[a] < mn[a]) mn[a] = d->ph[i].pos[a];
                if (d->ph[i].pos[a] > mx[a]) mx[a] = d->ph[i].pos[a];
            }
        for (int a = 0; a < 3; a++)
            if (1e-3f * (mx[a] - mn[a]) > jitter) jitter = 1e-3f * (mx[a] - mn[a]);
    } else {
        bench_fill_photons(d->ph, n, dist, opt.seed + n * 31 + (uint64_t)dist);
    }
    for (size_t i = 0; i < n; i++) memcpy(&d->xyz[3 * i], d->ph[i].pos, 3 * sizeof(float));
    bench_make_queries(d->q, d->nq, dist, d->ph, n, jitter, opt.seed + 7 * n + (uint64_t)dist);
    size_t g = opt.g < d->nq ? opt.g : d->nq;
    if (g == 0) return; /* probe mode: no truth */
    bench_log("truth: %s n=%zu, brute force for %zu queries", bench_dist_name(dist), n, g);
    if (bench_truth_compute(&d->truth, d->xyz, 3, n, d->q, g, KMAX) != 0) {
        fprintf(stderr, "out of memory\n");
        exit(2);
    }
    double *v = malloc(g * sizeof *v);
    for (size_t i = 0; i < g; i++) {
        unsigned c = d->truth.count[i];
        v[i] = c >= HEAD_K ? d->truth.dist2[i * KMAX + HEAD_K - 1] : INFINITY;
    }
    d->r50_2 = (float)bench_median(v, (int)g);
    free(v);
}

static void dataset_free(dataset *d) {
    free(d->ph);
    free(d->xyz);
    free(d->q);
    bench_truth_free(&d->truth);
}

/* ---- structures ---- */
enum { S_KD, S_OCT, S_FLANN, S_FOREST, S_BRUTE };
typedef struct structure {
    int type;
    int param; /* B, capacity, leaf_max_size, trees */
    pm_photon *rec;
    pm_kdtree *kd;
    bench_octree *oct;
    flann_index_t fl;
    struct FLANNParameters fp;
    const dataset *ds;
    double build_s;
    double bytes_pp;
} structure;

static const char *struct_name(int type) {
    switch (type) {
    case S_KD: return "kdtree";
    case S_OCT: return "octree";
    case S_FLANN: return "flann_single";
    case S_FOREST: return "flann_forest4";
    default: return "brute";
    }
}

static struct FLANNParameters flann_params(int type, int leaf) {
    struct FLANNParameters p = DEFAULT_FLANN_PARAMETERS;
    p.algorithm = type == S_FLANN ? FLANN_INDEX_KDTREE_SINGLE : FLANN_INDEX_KDTREE;
    p.leaf_max_size = leaf;
    p.trees = 4;
    p.checks = type == S_FLANN ? FLANN_CHECKS_UNLIMITED : 32;
    p.cores = 1;
    p.sorted = 1;
    p.max_neighbors = -1;
    p.eps = 0;
    p.log_level = FLANN_LOG_NONE;
    p.random_seed = 12345;
    return p;
}

static void structure_release(structure *s) {
    if (s->kd) pm_kdtree_free(s->kd);
    if (s->oct) bench_octree_free(s->oct);
    if (s->fl) flann_free_index(s->fl, &s->fp);
    free(s->rec);
    s->kd = NULL;
    s->oct = NULL;
    s->fl = NULL;
    s->rec = NULL;
}

/* Build `runs` times (median time), keep the last build; write a build.csv row. */
static void structure_build(structure *s, const dataset *ds, int type, int param,
                            const char *sweep) {
    const size_t n = ds->n;
    double *t = malloc((size_t)opt.runs * sizeof *t);
    double heap_pp = 0, flann_pp = NAN, data_pp = 0, index_pp = 0;
    const char *method = "index_bytes";
    memset(s, 0, sizeof *s);
    s->type = type;
    s->param = param;
    s->ds = ds;
    for (int r = 0; r < opt.runs; r++) {
        structure_release(s);
        if (type == S_KD || type == S_OCT) {
            s->rec = malloc(n * sizeof *s->rec);
            memcpy(s->rec, ds->ph, n * sizeof *s->rec);
        }
        size_t h0 = bench_heap_bytes();
        double t0 = bench_now();
        int rc = 0;
        if (type == S_KD) {
            pm_kdtree_config cfg = pm_kdtree_photon_config((unsigned)param);
            rc = pm_kdtree_build(&s->kd, s->rec, n, &cfg, NULL);
        } else if (type == S_OCT) {
            bench_octree_config cfg = bench_octree_photon_config((unsigned)param);
            rc = bench_octree_build(&s->oct, s->rec, n, &cfg, NULL);
        } else if (type == S_FLANN || type == S_FOREST) {
            float speedup;
            s->fp = flann_params(type, param);
            s->fl = flann_build_index(ds->xyz, (int)n, 3, &speedup, &s->fp);
            rc = s->fl ? 0 : -1;
        }
        t[r] = bench_now() - t0;
        heap_pp = (double)(bench_heap_bytes() - h0) / (double)n;
        if (rc != 0) {
            fprintf(stderr, "build of %s(%d) failed: %d\n", struct_name(type), param, rc);
            exit(2);
        }
    }
    s->build_s = bench_median(t, opt.runs);
    switch (type) {
    case S_KD:
        data_pp = sizeof(pm_photon);
        index_pp = (double)pm_kdtree_index_bytes(s->kd) / (double)n;
        break;
    case S_OCT:
        data_pp = sizeof(pm_photon);
        index_pp = (double)bench_octree_index_bytes(s->oct) / (double)n;
        break;
    case S_FLANN:
        /* the single tree reorders a private copy of the points: all of it is in the delta */
        method = "mallinfo2";
        index_pp = heap_pp;
        flann_pp = (double)flann_used_memory(s->fl) / (double)n;
        break;
    case S_FOREST:
        /* the forest searches the caller's float[3] array: count it as data */
        method = "mallinfo2+caller_xyz";
        data_pp = 3 * sizeof(float);
        index_pp = heap_pp;
        flann_pp = (double)flann_used_memory(s->fl) / (double)n;
        break;
    default:
        method = "caller_xyz";
        data_pp = 3 * sizeof(float);
    }
    s->bytes_pp = data_pp + index_pp;
    fprintf(g_build_csv, "%s,%s,%zu,%s,%d,%.6f,%.6f,%.6f,%d,%.3f,%.3f,%.3f,%.3f,", sweep,
            bench_dist_name(ds->dist), n, struct_name(type), param, s->build_s, t[0],
            t[opt.runs - 1], opt.runs, s->bytes_pp, data_pp, index_pp, heap_pp);
    if (isnan(flann_pp)) fprintf(g_build_csv, ",%s\n", method);
    else fprintf(g_build_csv, "%.3f,%s\n", flann_pp, method);
    fflush(g_build_csv);
    free(t);
}

/* ---- configurations: a structure and a query operation ---- */
enum { OP_ITER, OP_REC, OP_RADIUS, OP_FL_BATCH, OP_FL_RMAXNN, OP_FL_RADIUS, OP_BRUTE };
static const char *op_name(int op) {
    switch (op) {
    case OP_ITER: return "iterative";
    case OP_REC: return "recursive";
    case OP_RADIUS: return "radius";
    case OP_FL_BATCH: return "knn_batch";
    case OP_FL_RMAXNN: return "radius_maxnn";
    case OP_FL_RADIUS: return "radius";
    default: return "knn";
    }
}

typedef struct config {
    structure *s;
    int op;
    int checks; /* forest only */
    /* results of the last measure() */
    double qps, qps_min, qps_max;
    double nodes_pq, evals_pq, found_mean, recall, exact_frac;
    int has_stats;
    size_t m;
} config;

static config mkcfg(structure *s, int op, int checks) {
    config c;
    memset(&c, 0, sizeof c);
    c.s = s;
    c.op = op;
    c.checks = checks;
    return c;
}

static int cfg_param(const config *c) { return c->s->type == S_FOREST ? c->checks : c->s->param; }
/* FLANN k-NN ignores the radius; its answers are scored against the unlimited k nearest. */
static int cfg_unlimited(const config *c) { return c->op == OP_FL_BATCH; }

/* Brute force with a max-heap, as the timed floor. */
static unsigned brute_knn(const dataset *ds, const float q[3], unsigned k, float r2,
                          pm_neighbor *out) {
    unsigned found = 0;
    for (size_t i = 0; i < ds->n; i++) {
        const float *p = &ds->xyz[3 * i];
        float dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
        float d2 = dx * dx + dy * dy + dz * dz;
        if (found < k) {
            if (d2 < r2) {
                out[found].dist2 = d2;
                out[found].index = (uint32_t)i;
                if (++found == k) {
                    for (unsigned h = k / 2; h-- > 0;) {
                        unsigned j = h;
                        for (;;) {
                            unsigned l = 2 * j + 1, m;
                            if (l >= k) break;
                            m = (l + 1 < k && out[l + 1].dist2 > out[l].dist2) ? l + 1 : l;
                            if (out[m].dist2 <= out[j].dist2) break;
                            pm_neighbor t = out[j];
                            out[j] = out[m];
                            out[m] = t;
                            j = m;
                        }
                    }
                }
            }
        } else if (d2 < out[0].dist2) {
            unsigned j = 0;
            out[0].dist2 = d2;
            out[0].index = (uint32_t)i;
            for (;;) {
                unsigned l = 2 * j + 1, m;
                if (l >= k) break;
                m = (l + 1 < k && out[l + 1].dist2 > out[l].dist2) ? l + 1 : l;
                if (out[m].dist2 <= out[j].dist2) break;
                pm_neighbor t = out[j];
                out[j] = out[m];
                out[m] = t;
                j = m;
            }
        }
    }
    return found;
}

typedef struct scratch {
    pm_neighbor *nb;
    int *idx;
    float *d;
} scratch;
static void scratch_init(scratch *s, size_t entries) {
    s->nb = malloc(entries * sizeof *s->nb);
    s->idx = malloc(entries * sizeof *s->idx);
    s->d = malloc(entries * sizeof *s->d);
}
static void scratch_free(scratch *s) {
    free(s->nb);
    free(s->idx);
    free(s->d);
}

/* One query (not for OP_FL_BATCH). Fills sc->nb (ours) or sc->idx/sc->d (FLANN); returns the
 * count found (for radius ops the total within r2). */
static long query_one(const config *c, const float *q, unsigned k, float r2, scratch *sc,
                      struct FLANNParameters *fp, pm_query_stats *st) {
    const structure *s = c->s;
    switch (c->op) {
    case OP_ITER:
        if (s->type == S_KD) return pm_kdtree_knn(s->kd, q, k, r2, sc->nb, 0, st);
        return bench_octree_knn(s->oct, q, k, r2, sc->nb, 0, st);
    case OP_REC: return pm_kdtree_knn_recursive(s->kd, q, k, r2, sc->nb, 0, st);
    case OP_RADIUS:
        if (s->type == S_KD) return pm_kdtree_radius(s->kd, q, r2, sc->nb, RADIUS_CAP, 0, st);
        return bench_octree_radius(s->oct, q, r2, sc->nb, RADIUS_CAP, 0, st);
    case OP_FL_RMAXNN:
        fp->max_neighbors = (int)k;
        return flann_radius_search(s->fl, (float *)q, sc->idx, sc->d, (int)k,
                                   isinf(r2) ? FLT_MAX : r2, fp);
    case OP_FL_RADIUS:
        fp->max_neighbors = -1;
        return flann_radius_search(s->fl, (float *)q, sc->idx, sc->d, (int)RADIUS_CAP,
                                   isinf(r2) ? FLT_MAX : r2, fp);
    case OP_BRUTE: return brute_knn(s->ds, q, k, r2, sc->nb);
    default: return -1;
    }
}

/* Run queries [0, m) with T threads; returns a checksum of counts found. */
static uint64_t run_queries(const config *c, size_t m, unsigned k, float r2, int threads) {
    const dataset *ds = c->s->ds;
    uint64_t sum = 0;
    if (c->op == OP_FL_BATCH) {
        struct FLANNParameters fp = c->s->fp;
        int *idx = malloc((size_t)FL_BATCH * k * sizeof *idx);
        float *d = malloc((size_t)FL_BATCH * k * sizeof *d);
        fp.cores = threads;
        fp.checks = c->s->type == S_FOREST ? c->checks : FLANN_CHECKS_UNLIMITED;
        for (size_t b = 0; b < m; b += FL_BATCH) {
            int rows = (int)(m - b < FL_BATCH ? m - b : FL_BATCH);
            flann_find_nearest_neighbors_index(c->s->fl, (float *)&ds->q[3 * b], rows, idx, d,
                                               (int)k, &fp);
            sum += (uint64_t)idx[0];
        }
        free(idx);
        free(d);
        return sum;
    }
#pragma omp parallel num_threads(threads) reduction(+ : sum)
    {
        scratch sc;
        struct FLANNParameters fp = c->s->fp;
        scratch_init(&sc, (c->op == OP_RADIUS || c->op == OP_FL_RADIUS) ? RADIUS_CAP : k);
        fp.cores = 1;
#pragma omp for schedule(dynamic, 16)
        for (size_t i = 0; i < m; i++) sum += (uint64_t)query_one(c, &ds->q[3 * i], k, r2, &sc, &fp, NULL);
        scratch_free(&sc);
    }
    return sum;
}

/* Radius-search truth: a brute-force count (the k-NN truth list is too short for it). */
static size_t brute_count(const dataset *ds, const float *q, float r2) {
    size_t c = 0;
    for (size_t i = 0; i < ds->n; i++) {
        const float *p = &ds->xyz[3 * i];
        float dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
        c += dx * dx + dy * dy + dz * dz < r2;
    }
    return c;
}

/* The position of result j as the index sees it: ours index into their reordered records,
 * FLANN's into the caller's array. */
static const float *result_pos(const config *c, const scratch *sc, unsigned j) {
    const structure *s = c->s;
    if (s->type == S_KD) return pm_kdtree_pos(s->kd, sc->nb[j].index);
    if (s->type == S_OCT) return bench_octree_pos(s->oct, sc->nb[j].index);
    if (s->type == S_BRUTE) return &s->ds->xyz[3 * (size_t)sc->nb[j].index];
    return &s->ds->xyz[3 * (size_t)sc->idx[j]];
}

/* Verify on the first G queries: recall, exact fraction, mean found, work counters. */
static void verify(config *c, unsigned k, float r2) {
    const dataset *ds = c->s->ds;
    const size_t g = ds->truth.m;
    const int radius_op = c->op == OP_RADIUS || c->op == OP_FL_RADIUS;
    scratch sc;
    struct FLANNParameters fp = c->s->fp;
    pm_query_stats st = {0, 0};
    uint64_t hits = 0, wanted = 0, exact = 0, found = 0;
    float *d2 = malloc((radius_op ? RADIUS_CAP : k) * sizeof *d2);
    int *bidx = NULL;
    float *bd = NULL;
    scratch_init(&sc, radius_op ? RADIUS_CAP : k);
    fp.cores = 1;
    if (c->op == OP_FL_BATCH) {
        bidx = malloc(g * k * sizeof *bidx);
        bd = malloc(g * k * sizeof *bd);
        fp.checks = c->s->type == S_FOREST ? c->checks : FLANN_CHECKS_UNLIMITED;
        flann_find_nearest_neighbors_index(c->s->fl, ds->q, (int)g, bidx, bd, (int)k, &fp);
    }
    for (size_t qi = 0; qi < g; qi++) {
        const float *q = &ds->q[3 * qi];
        long got;
        if (c->op == OP_FL_BATCH) {
            got = ds->n < k ? (long)ds->n : (long)k;
            memcpy(sc.idx, &bidx[qi * k], (size_t)got * sizeof *sc.idx);
        } else {
            got = query_one(c, q, k, r2, &sc, &fp, &st);
        }
        if (got < 0) {
            fprintf(stderr, "query failed: %ld\n", got);
            exit(2);
        }
        found += (uint64_t)got;
        if (radius_op) {
            size_t want = brute_count(ds, q, r2);
            /* ours return the total; FLANN the number written (at most the buffer) */
            size_t expect = c->op == OP_FL_RADIUS && want > RADIUS_CAP ? RADIUS_CAP : want;
            wanted += want;
            hits += (size_t)got == expect ? want : 0;
            exact += (size_t)got == expect;
            continue;
        }
        for (unsigned j = 0; j < (unsigned)got; j++) {
            const float *p = result_pos(c, &sc, j);
            float dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
            d2[j] = dx * dx + dy * dy + dz * dz;
            /* our indexes report dist2: it must be the record's true dist2 */
            if ((c->s->type == S_KD || c->s->type == S_OCT || c->s->type == S_BRUTE) &&
                sc.nb[j].dist2 != d2[j])
                d2[j] = -1; /* poisons the exact check below */
        }
        exact += (uint64_t)bench_score(&ds->truth, qi, k, cfg_unlimited(c) ? INFINITY : r2, d2,
                                       (unsigned)got, &hits, &wanted);
    }
    c->recall = wanted ? (double)hits / (double)wanted : 1.0;
    c->exact_frac = g ? (double)exact / (double)g : 1.0;
    c->found_mean = g ? (double)found / (double)g : 0;
    c->has_stats = c->s->type == S_KD || c->s->type == S_OCT;
    c->nodes_pq = g ? (double)st.nodes_visited / (double)g : 0;
    c->evals_pq = g ? (double)st.dist_evals / (double)g : 0;
    if (c->s->type == S_BRUTE) {
        c->has_stats = 1;
        c->nodes_pq = 0;
        c->evals_pq = (double)ds->n;
    }
    scratch_free(&sc);
    free(d2);
    free(bidx);
    free(bd);
}

/* Verify, calibrate and time a group of configurations side by side; write queries.csv rows. */
static void measure(config *cs, int nc, unsigned k, float r2, double r_rel, int threads,
                    int runs, const char *sweep) {
    const dataset *ds = cs[0].s->ds;
    double *qps = malloc((size_t)nc * (size_t)runs * sizeof *qps);
    for (int i = 0; i < nc; i++) {
        config *c = &cs[i];
        verify(c, k, r2);
        /* calibrate: time a warm-up prefix, then size the run to the target time */
        size_t m0 = ds->nq < (opt.quick ? 64u : 256u) ? ds->nq : (opt.quick ? 64u : 256u);
        /* warm-up first: the first parallel region starts the OpenMP threads, which would
         * otherwise inflate the calibration and shrink the timed runs */
        g_sink += run_queries(c, m0, k, r2, threads);
        double t0 = bench_now();
        g_sink += run_queries(c, m0, k, r2, threads);
        double per = (bench_now() - t0) / (double)m0;
        size_t m = per > 0 ? (size_t)(opt.target / per) : ds->nq;
        if (m < m0) m = m0;
        if (m > ds->nq) m = ds->nq;
        c->m = m;
    }
    for (int r = 0; r < runs; r++)
        for (int i = 0; i < nc; i++) {
            double t0 = bench_now();
            g_sink += run_queries(&cs[i], cs[i].m, k, r2, threads);
            double dt = bench_now() - t0;
            qps[i * runs + r] = (double)cs[i].m / (dt > 0 ? dt : 1e-9);
        }
    for (int i = 0; i < nc; i++) {
        config *c = &cs[i];
        double *v = &qps[i * runs];
        c->qps = bench_median(v, runs); /* sorts v */
        c->qps_min = v[0];
        c->qps_max = v[runs - 1];
        fprintf(g_query_csv, "%s,%s,%zu,%s,%s,%d,%u,", sweep, bench_dist_name(ds->dist), ds->n,
                struct_name(c->s->type), op_name(c->op), cfg_param(c), k);
        if (isinf(r2)) fprintf(g_query_csv, "inf,inf,");
        else fprintf(g_query_csv, "%.4g,%.6g,", r_rel, (double)r2);
        fprintf(g_query_csv, "%d,%zu,%d,%.1f,%.1f,%.1f,%.1f,", threads, c->m, runs, c->qps,
                c->qps_min, c->qps_max, 1e9 / c->qps);
        if (c->has_stats) fprintf(g_query_csv, "%.2f,%.2f,", c->nodes_pq, c->evals_pq);
        else fprintf(g_query_csv, ",,");
        fprintf(g_query_csv, "%.2f,%.6f,%.6f,%zu\n", c->found_mean, c->recall, c->exact_frac,
                ds->truth.m);
    }
    fflush(g_query_csv);
    free(qps);
}

/* ---- sweeps ---- */

typedef struct zoo {
    structure kd[NELEM(KD_B)];
    structure oct[NELEM(OCT_CAP)];
    structure fl[NELEM(FL_LEAF)];
    structure forest;
    structure brute;
    int best_kd, best_oct, best_fl; /* indices into the arrays, from the param sweep */
    int best_kd_rec;
} zoo;

static int brute_ok(size_t n) { return n <= 100000; }

static void zoo_build(zoo *z, const dataset *ds) {
    memset(z, 0, sizeof *z);
    for (size_t i = 0; i < NELEM(KD_B); i++) structure_build(&z->kd[i], ds, S_KD, (int)KD_B[i], "param");
    bench_log("  built kd-trees");
    for (size_t i = 0; i < NELEM(OCT_CAP); i++)
        structure_build(&z->oct[i], ds, S_OCT, (int)OCT_CAP[i], "param");
    bench_log("  built octrees");
    for (size_t i = 0; i < NELEM(FL_LEAF); i++) structure_build(&z->fl[i], ds, S_FLANN, FL_LEAF[i], "param");
    structure_build(&z->forest, ds, S_FOREST, 4, "param");
    bench_log("  built FLANN indexes");
    z->brute.type = S_BRUTE;
    z->brute.ds = ds;
}

static void zoo_free(zoo *z) {
    for (size_t i = 0; i < NELEM(KD_B); i++) structure_release(&z->kd[i]);
    for (size_t i = 0; i < NELEM(OCT_CAP); i++) structure_release(&z->oct[i]);
    for (size_t i = 0; i < NELEM(FL_LEAF); i++) structure_release(&z->fl[i]);
    structure_release(&z->forest);
}

static int argmax_qps(const config *cs, int from, int count) {
    int b = from;
    for (int i = from; i < from + count; i++)
        if (cs[i].qps > cs[b].qps) b = i;
    return b - from;
}

/* Every parameter of every structure at the headline configuration; picks the best ones. */
static void sweep_param(zoo *z, const dataset *ds) {
    config cs[64];
    int nc = 0;
    const int nkd = (int)NELEM(KD_B), noct = (int)NELEM(OCT_CAP), nfl = (int)NELEM(FL_LEAF);
    for (int i = 0; i < nkd; i++) cs[nc++] = mkcfg(&z->kd[i], OP_ITER, 0);
    for (int i = 0; i < nkd; i++) cs[nc++] = mkcfg(&z->kd[i], OP_REC, 0);
    for (int i = 0; i < noct; i++) cs[nc++] = mkcfg(&z->oct[i], OP_ITER, 0);
    for (int i = 0; i < nfl; i++) cs[nc++] = mkcfg(&z->fl[i], OP_FL_BATCH, 0);
    for (int i = 0; i < nfl; i++) cs[nc++] = mkcfg(&z->fl[i], OP_FL_RMAXNN, 0);
    for (size_t i = 0; i < NELEM(FL_CHECKS); i++) cs[nc++] = mkcfg(&z->forest, OP_FL_BATCH, FL_CHECKS[i]);
    if (brute_ok(ds->n)) cs[nc++] = mkcfg(&z->brute, OP_BRUTE, 0);
    bench_log("param sweep: %s n=%zu, %d configurations, 1 thread", bench_dist_name(ds->dist),
              ds->n, nc);
    measure(cs, nc, HEAD_K, ds->r50_2, 1.0, 1, opt.runs, "param");
    z->best_kd = argmax_qps(cs, 0, nkd);
    z->best_kd_rec = argmax_qps(cs, nkd, nkd);
    z->best_oct = argmax_qps(cs, 2 * nkd, noct);
    {
        int a = argmax_qps(cs, 2 * nkd + noct, nfl), b = argmax_qps(cs, 2 * nkd + noct + nfl, nfl);
        z->best_fl = cs[2 * nkd + noct + a].qps >= cs[2 * nkd + noct + nfl + b].qps ? a : b;
    }
    if (opt.threads > 1) {
        bench_log("param sweep: %s n=%zu, %d threads", bench_dist_name(ds->dist), ds->n, opt.threads);
        measure(cs, nc, HEAD_K, ds->r50_2, 1.0, opt.threads, opt.runs, "param");
    }
}

static void sweep_k(zoo *z, const dataset *ds) {
    config cs[8];
    int nc = 0;
    cs[nc++] = mkcfg(&z->kd[z->best_kd], OP_ITER, 0);
    if (z->best_kd != 0) cs[nc++] = mkcfg(&z->kd[0], OP_ITER, 0);
    cs[nc++] = mkcfg(&z->kd[z->best_kd], OP_REC, 0);
    cs[nc++] = mkcfg(&z->oct[z->best_oct], OP_ITER, 0);
    cs[nc++] = mkcfg(&z->fl[z->best_fl], OP_FL_BATCH, 0);
    cs[nc++] = mkcfg(&z->forest, OP_FL_BATCH, 128);
    for (size_t i = 0; i < NELEM(KS); i++) {
        bench_log("k sweep: %s n=%zu k=%u", bench_dist_name(ds->dist), ds->n, KS[i]);
        measure(cs, nc, KS[i], INFINITY, INFINITY, 1, opt.runs, "k");
    }
}

static void sweep_radius(zoo *z, const dataset *ds) {
    for (size_t i = 0; i < NELEM(R_REL); i++) {
        config cs[10];
        int nc = 0;
        float r2 = isinf(R_REL[i]) ? INFINITY : (float)(R_REL[i] * R_REL[i] * ds->r50_2);
        cs[nc++] = mkcfg(&z->kd[z->best_kd], OP_ITER, 0);
        cs[nc++] = mkcfg(&z->kd[z->best_kd], OP_REC, 0);
        if (z->best_kd != 0) cs[nc++] = mkcfg(&z->kd[0], OP_ITER, 0);
        cs[nc++] = mkcfg(&z->oct[z->best_oct], OP_ITER, 0);
        cs[nc++] = mkcfg(&z->fl[z->best_fl], OP_FL_RMAXNN, 0);
        if (isinf(r2)) cs[nc++] = mkcfg(&z->fl[z->best_fl], OP_FL_BATCH, 0);
        if (R_REL[i] <= 1.0) {
            /* plain radius search: every record within r (no k) */
            cs[nc++] = mkcfg(&z->kd[z->best_kd], OP_RADIUS, 0);
            cs[nc++] = mkcfg(&z->oct[z->best_oct], OP_RADIUS, 0);
            cs[nc++] = mkcfg(&z->fl[z->best_fl], OP_FL_RADIUS, 0);
        }
        bench_log("radius sweep: %s n=%zu r/r50=%g", bench_dist_name(ds->dist), ds->n, R_REL[i]);
        measure(cs, nc, HEAD_K, r2, R_REL[i], 1, opt.runs, "radius");
    }
}

/* The headline: the best of each family side by side, more runs. */
static void headline(zoo *z, const dataset *ds) {
    config cs[8];
    int nc = 0;
    const int runs = opt.runs + 4;
    /* 0: ours best (iterative), 1: ours best B recursive, 2: ours B=1, 3: octree best,
     * 4,5: FLANN best leaf batch / radius_maxnn, 6,7: FLANN leaf 1 batch / radius_maxnn */
    cs[nc++] = mkcfg(&z->kd[z->best_kd], OP_ITER, 0);
    cs[nc++] = mkcfg(&z->kd[z->best_kd], OP_REC, 0);
    cs[nc++] = mkcfg(&z->kd[0], OP_ITER, 0);
    cs[nc++] = mkcfg(&z->oct[z->best_oct], OP_ITER, 0);
    cs[nc++] = mkcfg(&z->fl[z->best_fl], OP_FL_BATCH, 0);
    cs[nc++] = mkcfg(&z->fl[z->best_fl], OP_FL_RMAXNN, 0);
    cs[nc++] = mkcfg(&z->fl[0], OP_FL_BATCH, 0);
    cs[nc++] = mkcfg(&z->fl[0], OP_FL_RMAXNN, 0);
    bench_log("headline: %s n=%zu k=%u, %d runs", bench_dist_name(ds->dist), ds->n, HEAD_K, runs);
    measure(cs, nc, HEAD_K, ds->r50_2, 1.0, 1, runs, "headline");

    const char *d = bench_dist_name(ds->dist);
    char a[64], b[64];
    /* ours best: the faster of iterative and recursive at the best B */
    int ours = cs[1].qps > cs[0].qps ? 1 : 0;
    int fb = cs[5].qps > cs[4].qps ? 5 : 4, f1 = cs[7].qps > cs[6].qps ? 7 : 6;
#define HROW(metric, ci, cj, target, strict)                                                    \
    do {                                                                                        \
        snprintf(a, sizeof a, "%s_%s_%d", struct_name(cs[ci].s->type), op_name(cs[ci].op),      \
                 cfg_param(&cs[ci]));                                                           \
        snprintf(b, sizeof b, "%s_%s_%d", struct_name(cs[cj].s->type), op_name(cs[cj].op),      \
                 cfg_param(&cs[cj]));                                                           \
        double ratio = cs[ci].qps / cs[cj].qps;                                                 \
        fprintf(g_head_csv, "%s,%zu,%s,%s,%.1f,%s,%.1f,%.3f,%.2f,%s\n", d, ds->n, metric, a,     \
                cs[ci].qps, b, cs[cj].qps, ratio, (double)(target),                             \
                ((strict) ? ratio > (target) : ratio >= (target)) ? "yes" : "no");              \
    } while (0)
    HROW("qps_ours_best_vs_flann_best_exact", ours, fb, 1.5, 0);
    HROW("qps_ours_B1_vs_flann_leaf1", 2, f1, 1.0, 0);
    HROW("qps_iterative_vs_recursive_bestB", 0, 1, 1.0, 1); /* "faster" */
    HROW("qps_kdtree_best_vs_octree_best", ours, 3, 2.0, 0);
#undef HROW
    /* memory: ours (records + tree) vs FLANN best leaf (its copy + index); lower is better,
     * so the "ratio" column is FLANN's bytes over ours and the target is ours <= 20 B. */
    {
        const structure *k = cs[ours].s, *f = cs[fb].s;
        fprintf(g_head_csv, "%s,%zu,bytes_per_photon_ours_vs_flann_best,kdtree_%d,%.2f,flann_single_%d,%.2f,%.3f,20,%s\n",
                d, ds->n, k->param, k->bytes_pp, f->param, f->bytes_pp, f->bytes_pp / k->bytes_pp,
                k->bytes_pp < 20.005 ? "yes" : "no"); /* 20.00 to two decimals: the fixed header amortizes */
    }
    fflush(g_head_csv);
}

/* N sweep: build time, memory and queries for the best of each family at every N. */
static void sweep_n(const zoo *zb, int dist) {
    size_t ns_full[] = {10000, 100000, 1000000, 4000000};
    size_t ns_quick[2];
    size_t *ns = ns_full, nn = 4;
    if (opt.quick) {
        ns_quick[0] = opt.nh / 2;
        ns_quick[1] = opt.nh;
        ns = ns_quick;
        nn = 2;
    }
    for (size_t i = 0; i < nn; i++) {
        dataset ds;
        structure kd, kd1, oc, fl;
        config cs[6];
        int nc = 0;
        size_t save_g = opt.g;
        if (ns[i] > 1000000) opt.g = opt.g / 2; /* brute force truth costs n per query */
        dataset_init(&ds, dist, ns[i], NULL);
        opt.g = save_g;
        bench_log("n sweep: %s n=%zu: building", bench_dist_name(dist), ns[i]);
        structure_build(&kd, &ds, S_KD, (int)KD_B[zb->best_kd], "n");
        if (zb->best_kd != 0) structure_build(&kd1, &ds, S_KD, 1, "n");
        structure_build(&oc, &ds, S_OCT, (int)OCT_CAP[zb->best_oct], "n");
        structure_build(&fl, &ds, S_FLANN, FL_LEAF[zb->best_fl], "n");
        structure br;
        memset(&br, 0, sizeof br);
        br.type = S_BRUTE;
        br.ds = &ds;
        cs[nc++] = mkcfg(&kd, OP_ITER, 0);
        if (zb->best_kd != 0) cs[nc++] = mkcfg(&kd1, OP_ITER, 0);
        cs[nc++] = mkcfg(&oc, OP_ITER, 0);
        cs[nc++] = mkcfg(&fl, OP_FL_BATCH, 0);
        cs[nc++] = mkcfg(&fl, OP_FL_RMAXNN, 0);
        if (brute_ok(ns[i])) cs[nc++] = mkcfg(&br, OP_BRUTE, 0);
        bench_log("n sweep: %s n=%zu: queries", bench_dist_name(dist), ns[i]);
        measure(cs, nc, HEAD_K, ds.r50_2, 1.0, 1, opt.runs, "n");
        structure_release(&kd);
        if (zb->best_kd != 0) structure_release(&kd1);
        structure_release(&oc);
        structure_release(&fl);
        dataset_free(&ds);
    }
}

/* Profiler run: build one structure, then run only its queries (k = 50 at the given r2), with
 * callgrind instrumentation switched on around them when run under valgrind. */
static int probe(void) {
    char index[32] = "", variant[32] = "";
    int param = 0, type, op;
    if (sscanf(opt.probe, "%31[^:]:%31[^:]:%d", index, variant, &param) != 3) {
        fprintf(stderr, "bench_search: --probe wants INDEX:VARIANT:PARAM\n");
        return 2;
    }
    if (!strcmp(index, "kdtree")) type = S_KD;
    else if (!strcmp(index, "octree")) type = S_OCT;
    else if (!strcmp(index, "flann_single")) type = S_FLANN;
    else {
        fprintf(stderr, "bench_search: --probe index must be kdtree, octree or flann_single\n");
        return 2;
    }
    if (!strcmp(variant, "iterative")) op = OP_ITER;
    else if (!strcmp(variant, "recursive") && type == S_KD) op = OP_REC;
    else if (!strcmp(variant, "knn_batch") && type == S_FLANN) op = OP_FL_BATCH;
    else if (!strcmp(variant, "radius_maxnn") && type == S_FLANN) op = OP_FL_RMAXNN;
    else {
        fprintf(stderr, "bench_search: --probe variant does not fit the index\n");
        return 2;
    }
    dataset ds;
    structure s;
    opt.g = 0;
    opt.pool = opt.probe_queries;
    opt.runs = 1; /* one build: its time is not reported, and under valgrind it is slow */
    dataset_init(&ds, BENCH_PHOTON, opt.nh, NULL);
    g_build_csv = fopen("/dev/null", "w");
    structure_build(&s, &ds, type, param, "probe");
    config c = mkcfg(&s, op, 0);
    float r2 = op == OP_FL_BATCH ? INFINITY : (float)opt.probe_r2;
    double t0 = bench_now();
    CALLGRIND_START_INSTRUMENTATION;
    g_sink += run_queries(&c, ds.nq, HEAD_K, r2, 1);
    CALLGRIND_STOP_INSTRUMENTATION;
    double dt = bench_now() - t0;
    printf("probe %s n=%zu queries=%zu k=%u r2=%g: %.1f queries/s\n", opt.probe, ds.n, ds.nq,
           HEAD_K, (double)r2, (double)ds.nq / dt);
    structure_release(&s);
    dataset_free(&ds);
    fclose(g_build_csv);
    return 0;
}

static void usage(FILE *f) {
    fprintf(f,
            "usage: bench_search [--quick] [--out DIR] [--map FILE] [--threads T] [--runs R]\n"
            "                    [--n N] [--dists LIST] [--sweeps LIST] [--seed S]\n"
            "\n"
            "Races our kd-tree (iterative/recursive, B in 1..32), the octree (capacity 1..10000),\n"
            "FLANN's exact single kd-tree (leaf 1..64) and randomized 4-tree forest (checks\n"
            "16..256) and brute force, and writes build.csv, queries.csv and headline.csv to DIR\n"
            "(columns: bench/README.md). Progress goes to stderr.\n"
            "\n"
            "  --quick        small sizes (N = 20000), short runs: the test suite's smoke run\n"
            "  --out DIR      output directory (default bench/results; must exist)\n"
            "  --map FILE     also run on a photon-map file (pm_map_save format); dist 'file'\n"
            "  --threads T    threads for the all-threads rows (default: all OpenMP threads)\n"
            "  --runs R       timed runs per configuration, median reported (default 3, >= 3)\n"
            "  --n N          headline N (default 1000000, quick 20000)\n"
            "  --dists LIST   comma list of photon,uniform,file (default photon,uniform[,file])\n"
            "  --sweeps LIST  comma list of param,headline,k,radius,n (default all; headline\n"
            "                 and the later sweeps need param, which picks the best settings)\n"
            "  --seed S       random seed (default 1)\n"
            "  --probe INDEX:VARIANT:PARAM  profiler mode: photon-like data of --n points, one\n"
            "                 structure (e.g. kdtree:iterative:8, octree:iterative:64,\n"
            "                 flann_single:knn_batch:16), --probe-queries Q (default 20000)\n"
            "                 k = 50 queries at squared radius --probe-r2 R2; under valgrind\n"
            "                 --tool=callgrind --instr-atstart=no only the queries are counted\n");
}

static int has_word(const char *list, const char *w) {
    size_t n = strlen(w);
    for (const char *p = list; (p = strstr(p, w)) != NULL; p += n)
        if ((p == list || p[-1] == ',') && (p[n] == 0 || p[n] == ',')) return 1;
    return 0;
}

/* Every comma-separated word of list is one of the allowed words (a NULL-terminated array). */
static int words_ok(const char *opt_name, const char *list, const char *const *allowed) {
    const char *p = list;
    for (;;) {
        size_t n = strcspn(p, ",");
        int ok = 0;
        for (int j = 0; allowed[j]; j++) ok |= strlen(allowed[j]) == n && !strncmp(p, allowed[j], n);
        if (!ok) {
            fprintf(stderr, "bench_search: %s: unknown word '%.*s' in '%s' (allowed:", opt_name,
                    (int)n, p, list);
            for (int j = 0; allowed[j]; j++) fprintf(stderr, " %s", allowed[j]);
            fprintf(stderr, ")\n");
            return 0;
        }
        if (!p[n]) return 1;
        p += n + 1;
    }
}

int main(int argc, char **argv) {
    static const char *const P = "bench_search";
    static const char *const DIST_WORDS[] = {"photon", "uniform", "file", NULL};
    static const char *const SWEEP_WORDS[] = {"param", "headline", "k", "radius", "n", NULL};
    const char *dists = NULL, *sweeps = NULL;
    opt.out = "bench/results";
    opt.threads = bench_max_threads();
    opt.runs = 3;
    opt.seed = 1;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            usage(stdout);
            return 0;
        } else if (!strcmp(a, "--quick")) {
            opt.quick = 1;
        } else if (!strcmp(a, "--full")) {
            opt.quick = 0;
        } else if (v && !strcmp(a, "--out")) {
            opt.out = v, i++;
        } else if (v && !strcmp(a, "--map")) {
            opt.map = v, i++;
        } else if (v && !strcmp(a, "--threads")) {
            if (bench_parse_int(P, a, v, 1, 1024, &opt.threads) < 0) return 2;
            i++;
        } else if (v && !strcmp(a, "--runs")) {
            if (bench_parse_int(P, a, v, 3, 1000, &opt.runs) < 0) return 2;
            i++;
        } else if (v && !strcmp(a, "--n")) {
            if (bench_parse_count(P, a, v, 1000, 1e8, &opt.nh) < 0) return 2;
            i++;
        } else if (v && !strcmp(a, "--dists")) {
            dists = v, i++;
        } else if (v && !strcmp(a, "--sweeps")) {
            sweeps = v, i++;
        } else if (v && !strcmp(a, "--probe")) {
            opt.probe = v, i++;
        } else if (v && !strcmp(a, "--probe-r2")) {
            if (bench_parse_double(P, a, v, 0, INFINITY, &opt.probe_r2) < 0) return 2;
            i++;
        } else if (v && !strcmp(a, "--probe-queries")) {
            if (bench_parse_count(P, a, v, 1, 1e8, &opt.probe_queries) < 0) return 2;
            i++;
        } else if (v && !strcmp(a, "--seed")) {
            if (bench_parse_u64(P, a, v, &opt.seed) < 0) return 2;
            i++;
        } else {
            fprintf(stderr, "bench_search: unknown or incomplete option '%s'\n", a);
            usage(stderr);
            return 2;
        }
    }
    if ((dists && !words_ok("--dists", dists, DIST_WORDS)) ||
        (sweeps && !words_ok("--sweeps", sweeps, SWEEP_WORDS)))
        return 2;
    if (!opt.nh) opt.nh = opt.quick ? 20000 : 1000000;
    if (opt.nh < 1000) {
        fprintf(stderr, "bench_search: --n must be >= 1000\n");
        return 2;
    }
    if (opt.probe) {
        if (!opt.probe_queries) opt.probe_queries = 20000;
        if (!(opt.probe_r2 > 0)) opt.probe_r2 = INFINITY;
        return probe();
    }
    opt.target = opt.quick ? 0.004 : 0.15; /* quick: a smoke run, its timings mean little */
    opt.pool = opt.quick ? 4000 : 100000;
    opt.g = opt.quick ? 100 : 200;
    if (!dists) dists = opt.map ? "photon,uniform,file" : "photon,uniform";
    opt.dists = (has_word(dists, "uniform") << BENCH_UNIFORM) |
                (has_word(dists, "photon") << BENCH_PHOTON) | (has_word(dists, "file") << BENCH_FILE);
    if ((opt.dists >> BENCH_FILE & 1) && !opt.map) {
        fprintf(stderr, "bench_search: dist 'file' needs --map FILE\n");
        return 2;
    }
    opt.sweeps = sweeps ? (has_word(sweeps, "param") * SW_PARAM | has_word(sweeps, "k") * SW_K |
                           has_word(sweeps, "radius") * SW_RADIUS | has_word(sweeps, "n") * SW_N |
                           has_word(sweeps, "headline") * SW_HEAD)
                        : SW_ALL;
    if (opt.sweeps & ~SW_PARAM) opt.sweeps |= SW_PARAM;

    g_build_csv = bench_csv_open(opt.out, "build.csv",
                                 "sweep,dist,n,index,param,build_s,build_s_min,build_s_max,runs,"
                                 "bytes_per_photon,data_bytes_per_photon,index_bytes_per_photon,"
                                 "heap_delta_per_photon,flann_used_per_photon,mem_method");
    g_query_csv = bench_csv_open(opt.out, "queries.csv",
                                 "sweep,dist,n,index,variant,param,k,r_rel,r2,threads,queries,runs,"
                                 "qps,qps_min,qps_max,ns_per_query,nodes_per_query,"
                                 "dist_evals_per_query,mean_found,recall,exact_frac,verified");
    g_head_csv = bench_csv_open(opt.out, "headline.csv",
                                "dist,n,metric,ours,ours_value,peer,peer_value,ratio,target,met");
    bench_log("bench_search: %s, headline n=%zu, %d threads, %d runs", opt.quick ? "quick" : "full",
              opt.nh, opt.threads, opt.runs);

    /* photon first: the headline distribution */
    const int order[3] = {BENCH_PHOTON, BENCH_UNIFORM, BENCH_FILE};
    for (int oi = 0; oi < 3; oi++) {
        int dist = order[oi];
        if (!(opt.dists >> dist & 1)) continue;
        dataset ds;
        zoo *z = calloc(1, sizeof *z);
        if (dist == BENCH_FILE) {
            pm_photon *ph = NULL;
            pm_map_header hdr;
            int rc = pm_map_load(opt.map, &ph, &hdr);
            if (rc != 0) {
                fprintf(stderr, "bench_search: cannot load %s: %s\n", opt.map, pm_strerror(rc));
                return 1;
            }
            if (hdr.count < 1000) {
                fprintf(stderr, "bench_search: %s has %llu photons; need >= 1000\n", opt.map,
                        (unsigned long long)hdr.count);
                return 1;
            }
            bench_log("map %s: %llu photons", opt.map, (unsigned long long)hdr.count);
            dataset_init(&ds, BENCH_FILE, (size_t)hdr.count, ph);
            free(ph);
        } else {
            dataset_init(&ds, dist, opt.nh, NULL);
        }
        bench_log("%s n=%zu: radius finding ~%u: r2 = %g", bench_dist_name(dist), ds.n, HEAD_K,
                  (double)ds.r50_2);
        zoo_build(z, &ds);
        sweep_param(z, &ds);
        if (opt.sweeps & SW_HEAD) headline(z, &ds);
        if (opt.sweeps & SW_K) sweep_k(z, &ds);
        if (opt.sweeps & SW_RADIUS) sweep_radius(z, &ds);
        zoo_free(z);
        dataset_free(&ds);
        /* the N sweep runs on synthetic photon-like data only, with this run's best settings */
        if ((opt.sweeps & SW_N) && dist == BENCH_PHOTON) sweep_n(z, dist);
        free(z);
    }
    fclose(g_build_csv);
    fclose(g_query_csv);
    fclose(g_head_csv);
    bench_log("done (checksum %llu)", (unsigned long long)(g_sink & 0xff));
    return 0;
}
