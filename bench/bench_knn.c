/* bench_knn.c: the k-nearest race on workloads that do not flatter the kd-tree, against
 * nanoflann's best configuration, FLANN's best exact configuration and the best octree, side
 * by side in one run.
 *
 * WORKLOADS, generated here from a seed (or read from photon maps the renderer dumped):
 *   cluster  64 Gaussian clusters, centres uniform in [0.1, 0.9]^3, widths (sigma) spaced
 *            evenly in log from 0.002 to 0.2 (two decades), equal counts;
 *   slab     a nearly planar slab: x, z uniform in [0, 1), y uniform in [0, 0.002);
 *   caustic  a planar caustic on y = 0: 40% in a ring of radius 0.25 (Gaussian profile,
 *            sigma 0.004), 30% in a focused spot (sigma 0.01), 30% uniform over [0, 1)^2;
 *   map:NAME a photon map file (pm_map_save format), e.g. dumped by `render --save-photons`.
 * Each workload has two query sets, reported apart: `near` (a random record jittered by up to
 * 1e-3 of the largest extent of the bounding box on each axis) and `empty` (uniform in the
 * bounding box; for the planar caustic, whose box is flat, uniform over the plane's box at a
 * height of 0.02 to 0.1 above it: the lookups above a caustic).
 *
 * CELLS. For every workload, N, query set, k in {10, 50, 200} and mode (`unlimited` radius,
 * or `radius`: the median over the verified queries of their true k-th nearest dist2, so that
 * a typical query finds about k; above 1.5M points k = 50 only) the following race side by
 * side: our kd-tree for B in {8, 16, 32, 64}, unsorted and with PM_SORT; nanoflann's
 * KDTreeSingleIndexAdaptor (nanoflann_peer.h) for leaf sizes {8, 16, 32, 64}, each with its
 * points in input order and in its own tree order (a copy rewritten in the order of its index
 * array, then built again), k-NN with the radius as its result set's first worst distance;
 * FLANN's exact single kd-tree for leaf sizes
 * {16, 32, 64} (8 was never its fastest in trial runs), as batched k-NN (256 queries per call; in radius mode the sorted k
 * nearest are then cut at the radius, which gives the exact answer) and, in radius mode, as
 * radius search with max_neighbors = k (one call per query, the API's own way); and, at
 * k = 50, the octree at capacities {32, 128}. FLANN runs one thread (cores = 1), sorted = 1.
 * Every configuration is first VERIFIED on the first G queries against a brute-force scan
 * (same float dist2), then TIMED round-robin `runs` times over the same queries; medians.
 * Times are the CPU time of the one thread that runs the queries (see cpu_now), builds too.
 * The cost of PM_SORT is measured PAIRED: at the cell's fastest unsorted B, the unsorted and
 * the sorted search answer the same queries in chunks of 256, each chunk by both back to back
 * (alternating which goes first), for 9 rounds (3 in --quick); the median of the rounds' time
 * ratios is reported (the ratio of two independent best-of medians, used before, swung from
 * -28% to +34% on a loaded machine; whole-run pairs still spread -7%..+34% within a cell).
 *
 * OUTPUT (columns in bench/README.md): knn.csv (one row per configuration and cell),
 * knn_build.csv (build time and bytes per photon), knn_best.csv (per cell: the fastest of
 * each family and the ratios the headline is made of).
 */
#define _GNU_SOURCE
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <flann/flann.h>

#include "bench.h"
#include "kdtree.h"
#include "nanoflann_peer.h"
#include "octree.h"
#include "photon.h"

#define NELEM(a) (sizeof(a) / sizeof((a)[0]))
#define KMAX 200u
#define FL_BATCH 256
#define MAX_MAPS 8

static const unsigned KD_B[] = {8, 16, 32, 64};
static const int FL_LEAF[] = {16, 32, 64};
/* nanoflann's leaf_max_size, each with its points in input order and in its own tree order */
static const unsigned NF_LEAF[] = {8, 16, 32, 64};
static const unsigned OCT_CAP[] = {32, 128};
static const unsigned KS_FULL[] = {10, 50, 200};
static const unsigned KS_QUICK[] = {50};
#define OCT_K 50u

static struct {
    int quick, runs, build_runs;
    const char *out;
    size_t ns[4];
    int nn;
    double target;
    size_t pool, g;
    uint64_t seed;
    const char *map_name[MAX_MAPS], *map_file[MAX_MAPS];
    int nmaps;
    const char *workloads;
    unsigned ks[3];
    int nks;        /* --k: the k to race (0: the defaults) */
    int sets, modes; /* --queries, --modes: bit 0 near / unlimited, bit 1 empty / radius */
    int sort_rounds; /* rounds of the paired PM_SORT measurement */
    int oracle;      /* --oracle: also time the searches given their own k-th distance */
} opt;

static FILE *g_csv, *g_build, *g_best;

/* Seconds of CPU time of the calling thread. Every timed section runs on this one thread
 * (FLANN with cores = 1 too), so time slices the shared machine gives to other jobs do not
 * count; what remains of the load (shared caches, memory bandwidth) hits every configuration
 * of a cell alike, as they alternate. */
static double cpu_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
static volatile uint64_t g_sink;

/* ---- workloads ---- */

static double gauss(bench_rng *r) {
    double u = bench_rng_unit(r), v = bench_rng_unit(r);
    return sqrt(-2.0 * log(1.0 - u)) * cos(6.283185307179586 * v);
}

static void gen_point(bench_rng *r, const char *w, float p[3], const double (*cc)[4]) {
    if (!strcmp(w, "cluster")) {
        const double *c = cc[bench_rng_u64(r) % 64];
        for (int a = 0; a < 3; a++) p[a] = (float)(c[a] + c[3] * gauss(r));
    } else if (!strcmp(w, "slab")) {
        p[0] = (float)bench_rng_unit(r);
        p[1] = (float)(0.002 * bench_rng_unit(r));
        p[2] = (float)bench_rng_unit(r);
    } else { /* caustic */
        double u = bench_rng_unit(r), x, z;
        if (u < 0.4) {
            double phi = 6.283185307179586 * bench_rng_unit(r), rad = 0.25 + 0.004 * gauss(r);
            x = 0.5 + rad * cos(phi), z = 0.5 + rad * sin(phi);
        } else if (u < 0.7) {
            x = 0.5 + 0.01 * gauss(r), z = 0.5 + 0.01 * gauss(r);
        } else {
            x = bench_rng_unit(r), z = bench_rng_unit(r);
        }
        p[0] = (float)x, p[1] = 0.0f, p[2] = (float)z;
    }
}

typedef struct qset {
    const char *name; /* near, empty */
    float *q;
    bench_truth truth;
} qset;

typedef struct dataset {
    char name[64];
    size_t n;
    pm_photon *ph; /* original order */
    float *xyz;
    float lo[3], hi[3];
    qset qs[2];
} dataset;

static void dataset_queries(dataset *d, int planar) {
    bench_rng r;
    float ext = 0;
    bench_rng_seed(&r, opt.seed * 977 + d->n + 13 * (uint64_t)strlen(d->name));
    for (int a = 0; a < 3; a++)
        if (d->hi[a] - d->lo[a] > ext) ext = d->hi[a] - d->lo[a];
    for (int s = 0; s < 2; s++) {
        qset *qs = &d->qs[s];
        qs->name = s == 0 ? "near" : "empty";
        qs->q = malloc(opt.pool * 3 * sizeof *qs->q);
        for (size_t i = 0; i < opt.pool; i++) {
            float *q = &qs->q[3 * i];
            if (s == 0) {
                const float *p = &d->xyz[3 * (bench_rng_u64(&r) % d->n)];
                for (int a = 0; a < 3; a++)
                    q[a] = p[a] + 1e-3f * ext * (float)(2.0 * bench_rng_unit(&r) - 1.0);
            } else {
                for (int a = 0; a < 3; a++)
                    q[a] = d->lo[a] + (d->hi[a] - d->lo[a]) * (float)bench_rng_unit(&r);
                if (planar) q[1] = d->lo[1] + (float)(0.02 + 0.08 * bench_rng_unit(&r));
            }
        }
        bench_log("truth: %s n=%zu %s, brute force for %zu queries", d->name, d->n, qs->name,
                  opt.g);
        if (bench_truth_compute(&qs->truth, d->xyz, 3, d->n, qs->q, opt.g, KMAX) != 0) {
            fprintf(stderr, "bench_knn: out of memory\n");
            exit(2);
        }
    }
}

static void dataset_finish(dataset *d, int planar) {
    d->xyz = malloc(d->n * 3 * sizeof *d->xyz);
    if (!d->xyz) {
        fprintf(stderr, "bench_knn: out of memory\n");
        exit(2);
    }
    for (int a = 0; a < 3; a++) d->lo[a] = INFINITY, d->hi[a] = -INFINITY;
    for (size_t i = 0; i < d->n; i++)
        for (size_t a = 0; a < 3; a++) {
            float x = d->ph[i].pos[a];
            d->xyz[3 * i + a] = x;
            if (x < d->lo[a]) d->lo[a] = x;
            if (x > d->hi[a]) d->hi[a] = x;
        }
    dataset_queries(d, planar);
}

static void dataset_generate(dataset *d, const char *w, size_t n) {
    bench_rng r;
    double cc[64][4];
    memset(d, 0, sizeof *d);
    snprintf(d->name, sizeof d->name, "%s", w);
    d->n = n;
    d->ph = calloc(n, sizeof *d->ph);
    if (!d->ph) {
        fprintf(stderr, "bench_knn: out of memory\n");
        exit(2);
    }
    bench_rng_seed(&r, opt.seed * 1000003 + n);
    for (int c = 0; c < 64; c++) {
        for (int a = 0; a < 3; a++) cc[c][a] = 0.1 + 0.8 * bench_rng_unit(&r);
        cc[c][3] = 0.002 * pow(100.0, c / 63.0);
    }
    for (size_t i = 0; i < n; i++) gen_point(&r, w, d->ph[i].pos, (const double (*)[4])cc);
    dataset_finish(d, !strcmp(w, "caustic"));
}

static int dataset_load(dataset *d, const char *name, const char *file) {
    pm_map_header hdr;
    memset(d, 0, sizeof *d);
    int rc = pm_map_load(file, &d->ph, &hdr);
    if (rc != 0) {
        fprintf(stderr, "bench_knn: cannot load %s: %s\n", file, pm_strerror(rc));
        return -1;
    }
    if (hdr.count < 1000) {
        fprintf(stderr, "bench_knn: %s has %llu photons; need >= 1000\n", file,
                (unsigned long long)hdr.count);
        return -1;
    }
    snprintf(d->name, sizeof d->name, "map:%s", name);
    d->n = (size_t)hdr.count;
    /* The renderer saves its maps in an order that would hand the builds a presorted
     * input; shuffle, so that a map is built from unordered photons like the others. */
    bench_rng r;
    bench_rng_seed(&r, opt.seed + 99);
    for (size_t i = d->n - 1; i > 0; i--) {
        size_t j = (size_t)(bench_rng_u64(&r) % (i + 1));
        pm_photon t = d->ph[i];
        d->ph[i] = d->ph[j];
        d->ph[j] = t;
    }
    dataset_finish(d, 0);
    return 0;
}

static void dataset_free(dataset *d) {
    free(d->ph);
    free(d->xyz);
    for (int s = 0; s < 2; s++) {
        free(d->qs[s].q);
        bench_truth_free(&d->qs[s].truth);
    }
}

/* ---- structures ---- */
enum { S_KD, S_FLANN, S_OCT, S_NF };
typedef struct structure {
    int type, param;
    int tree_order; /* S_NF: points rewritten in nanoflann's tree order */
    nf_peer *nf;
    pm_photon *rec;
    pm_kdtree *kd;
    bench_octree *oct;
    flann_index_t fl;
    struct FLANNParameters fp;
    double build_s, bytes_pp;
} structure;

static const char *struct_name(int t) {
    return t == S_KD ? "kdtree" : t == S_FLANN ? "flann_single" : t == S_NF ? "nanoflann" : "octree";
}

static void structure_release(structure *s) {
    if (s->kd) pm_kdtree_free(s->kd);
    if (s->oct) bench_octree_free(s->oct);
    if (s->fl) flann_free_index(s->fl, &s->fp);
    if (s->nf) nf_free(s->nf);
    s->nf = NULL;
    free(s->rec);
    s->kd = NULL, s->oct = NULL, s->fl = NULL, s->rec = NULL;
}

static void structure_build(structure *s, const dataset *d, int type, int param, int tree_order) {
    double t[16];
    int runs = opt.build_runs;
    size_t heap = 0;
    memset(s, 0, sizeof *s);
    s->type = type, s->param = param, s->tree_order = tree_order;
    for (int r = 0; r < runs; r++) {
        structure_release(s);
        if (type != S_FLANN && type != S_NF) {
            s->rec = malloc(d->n * sizeof *s->rec);
            memcpy(s->rec, d->ph, d->n * sizeof *s->rec);
        }
        size_t h0 = bench_heap_bytes();
        double t0 = cpu_now();
        int rc;
        if (type == S_KD) {
            pm_kdtree_config c = pm_kdtree_photon_config((unsigned)param);
            rc = pm_kdtree_build(&s->kd, s->rec, d->n, &c, NULL);
        } else if (type == S_OCT) {
            bench_octree_config c = bench_octree_photon_config((unsigned)param);
            rc = bench_octree_build(&s->oct, s->rec, d->n, &c, NULL);
        } else if (type == S_NF) {
            double bt = 0;
            s->nf = nf_build(d->xyz, d->n, (unsigned)param, tree_order, cpu_now, &bt);
            rc = s->nf ? 0 : -1;
            t0 = cpu_now() - bt; /* the build in input order alone */
        } else {
            float speedup;
            s->fp = DEFAULT_FLANN_PARAMETERS;
            s->fp.algorithm = FLANN_INDEX_KDTREE_SINGLE;
            s->fp.leaf_max_size = param;
            s->fp.checks = FLANN_CHECKS_UNLIMITED;
            s->fp.cores = 1;
            s->fp.sorted = 1;
            s->fp.max_neighbors = -1;
            s->fp.eps = 0;
            s->fp.log_level = FLANN_LOG_NONE;
            s->fp.random_seed = 12345;
            s->fl = flann_build_index(d->xyz, (int)d->n, 3, &speedup, &s->fp);
            rc = s->fl ? 0 : -1;
        }
        t[r] = cpu_now() - t0;
        heap = bench_heap_bytes() - h0;
        if (rc != 0) {
            fprintf(stderr, "bench_knn: build of %s(%d) failed: %d\n", struct_name(type), param, rc);
            exit(2);
        }
    }
    s->build_s = bench_median(t, runs);
    if (type == S_KD)
        s->bytes_pp = sizeof(pm_photon) + (double)pm_kdtree_index_bytes(s->kd) / (double)d->n;
    else if (type == S_OCT)
        s->bytes_pp = sizeof(pm_photon) + (double)bench_octree_index_bytes(s->oct) / (double)d->n;
    else if (type == S_NF) /* the caller's float[3] points it reads, and its index */
        s->bytes_pp = 12.0 + (double)nf_index_bytes(s->nf) / (double)d->n;
    else /* its reordered point copy and its index: the heap growth across the build */
        s->bytes_pp = (double)heap / (double)d->n;
    fprintf(g_build, "%s,%zu,%s%s,%d,%.6f,%d,%.3f\n", d->name, d->n, struct_name(type),
            tree_order ? "_tree_order" : "", param,
            s->build_s, runs, s->bytes_pp);
    fflush(g_build);
}

/* ---- configurations ---- */
enum { OP_KNN, OP_KNN_SORTED, OP_FL_BATCH, OP_FL_RMAXNN, OP_KNN_ORACLE, OP_NF, OP_NF_TREE };

/* --oracle: per query of the pool (g_oracle_q), the next float above its own k-th dist2, so
 * that a search given it as max_dist2 returns the same k distances having known the final
 * radius from the start. Not something a caller can do: it measures how much of a query's
 * time goes into finding that radius. */
static float *g_oracle_r2;
static const float *g_oracle_q;
static const char *op_name(int op) {
    switch (op) {
    case OP_KNN: return "knn";
    case OP_KNN_SORTED: return "knn_sorted";
    case OP_KNN_ORACLE: return "knn_oracle";
    case OP_FL_BATCH: return "knn_batch";
    case OP_NF: return "knn";
    case OP_NF_TREE: return "knn_tree_order";
    default: return "radius_maxnn";
    }
}

typedef struct config {
    structure *s;
    int op;
    size_t m;
    double qps, qps_min, qps_max, nodes_pq, evals_pq, found_mean, exact_frac;
    int has_stats;
} config;

typedef struct scratch {
    pm_neighbor nb[KMAX];
    int idx[FL_BATCH * KMAX];
    uint32_t nfi[KMAX];
    float d[FL_BATCH * KMAX];
} scratch;

/* Queries [0, m) of q, one thread; returns the number found (a checksum). With st, counts. */
static uint64_t run(const config *c, const float *q, size_t m, unsigned k, float r2,
                    scratch *sc, pm_query_stats *st, unsigned *found_each) {
    const structure *s = c->s;
    uint64_t sum = 0;
    if (c->op == OP_FL_BATCH) {
        struct FLANNParameters fp = s->fp;
        for (size_t b = 0; b < m; b += FL_BATCH) {
            int rows = (int)(m - b < FL_BATCH ? m - b : FL_BATCH);
            flann_find_nearest_neighbors_index(s->fl, (float *)&q[3 * b], rows, sc->idx, sc->d,
                                               (int)k, &fp);
            for (int r = 0; r < rows; r++) {
                /* sorted ascending: the answer within the radius is a prefix */
                unsigned f = 0;
                const float *dr = &sc->d[(size_t)r * k];
                if (isinf(r2)) f = k;
                else
                    while (f < k && dr[f] < r2) f++;
                sum += f;
                if (found_each) found_each[b + (size_t)r] = f;
            }
        }
        return sum;
    }
    for (size_t i = 0; i < m; i++) {
        const float *qi = &q[3 * i];
        long f;
        if (s->type == S_NF) {
            f = (long)nf_knn(s->nf, qi, k, r2, sc->nfi, sc->d);
        } else if (c->op == OP_FL_RMAXNN) {
            struct FLANNParameters fp = s->fp;
            fp.max_neighbors = (int)k;
            f = flann_radius_search(s->fl, (float *)qi, sc->idx, sc->d, (int)k,
                                    isinf(r2) ? FLT_MAX : r2, &fp);
        } else if (s->type == S_KD) {
            float ri = c->op == OP_KNN_ORACLE ? g_oracle_r2[(size_t)(qi - g_oracle_q) / 3] : r2;
            f = pm_kdtree_knn(s->kd, qi, k, ri, sc->nb, c->op == OP_KNN_SORTED ? PM_SORT : 0, st);
        } else {
            f = bench_octree_knn(s->oct, qi, k, r2, sc->nb, c->op == OP_KNN_SORTED ? PM_SORT : 0,
                                 st);
        }
        if (f < 0) {
            fprintf(stderr, "bench_knn: query failed: %ld\n", f);
            exit(2);
        }
        sum += (uint64_t)f;
        if (found_each) found_each[i] = (unsigned)f;
    }
    return sum;
}

/* Verify on the first G queries against brute force: exact fraction, mean found, work. */
static void verify(config *c, const dataset *d, const qset *qs, unsigned k, float r2,
                   scratch *sc) {
    const size_t g = qs->truth.m;
    pm_query_stats st = {0, 0};
    uint64_t exact = 0, found = 0, hits = 0, wanted = 0;
    float d2[KMAX];
    for (size_t i = 0; i < g; i++) {
        const float *q = &qs->q[3 * i];
        unsigned f;
        if (c->op == OP_FL_BATCH) {
            g_sink += run(c, q, 1, k, r2, sc, NULL, &f);
        } else {
            g_sink += run(c, q, 1, k, r2, sc, &st, &f);
        }
        found += f;
        for (unsigned j = 0; j < f; j++) {
            const float *p;
            if (c->s->type == S_KD) p = pm_kdtree_pos(c->s->kd, sc->nb[j].index);
            else if (c->s->type == S_OCT) p = bench_octree_pos(c->s->oct, sc->nb[j].index);
            else if (c->s->type == S_NF) p = nf_pos(c->s->nf, sc->nfi[j]);
            else p = &d->xyz[3 * (size_t)sc->idx[j]];
            float dx = q[0] - p[0], dy = q[1] - p[1], dz = q[2] - p[2];
            d2[j] = dx * dx + dy * dy + dz * dz;
            if ((c->s->type == S_KD || c->s->type == S_OCT) && sc->nb[j].dist2 != d2[j])
                d2[j] = -1; /* poisons */
        }
        if (c->op == OP_KNN_SORTED)
            for (unsigned j = 1; j < f; j++)
                if (sc->nb[j - 1].dist2 > sc->nb[j].dist2 ||
                    (sc->nb[j - 1].dist2 == sc->nb[j].dist2 && sc->nb[j - 1].index > sc->nb[j].index))
                    d2[0] = -1;
        exact += (uint64_t)bench_score(&qs->truth, i, k, r2, d2, f, &hits, &wanted);
    }
    c->exact_frac = g ? (double)exact / (double)g : 1;
    c->found_mean = g ? (double)found / (double)g : 0;
    c->has_stats = c->s->type == S_KD || c->s->type == S_OCT;
    c->nodes_pq = g ? (double)st.nodes_visited / (double)g : 0;
    c->evals_pq = g ? (double)st.dist_evals / (double)g : 0;
}

static void measure(config *cs, int nc, const dataset *d, const qset *qs, unsigned k,
                    const char *mode, float r2, scratch *sc) {
    double *qps = malloc((size_t)nc * (size_t)opt.runs * sizeof *qps);
    for (int i = 0; i < nc; i++) {
        config *c = &cs[i];
        verify(c, d, qs, k, r2, sc);
        size_t m0 = opt.quick ? 32 : 256;
        if (m0 > opt.pool) m0 = opt.pool;
        g_sink += run(c, qs->q, m0, k, r2, sc, NULL, NULL);
        double t0 = cpu_now();
        g_sink += run(c, qs->q, m0, k, r2, sc, NULL, NULL);
        double per = (cpu_now() - t0) / (double)m0;
        size_t m = per > 0 ? (size_t)(opt.target / per) : opt.pool;
        if (m < m0) m = m0;
        if (m > opt.pool) m = opt.pool;
        c->m = m;
    }
    for (int r = 0; r < opt.runs; r++)
        for (int i = 0; i < nc; i++) {
            double t0 = cpu_now();
            g_sink += run(&cs[i], qs->q, cs[i].m, k, r2, sc, NULL, NULL);
            double dt = cpu_now() - t0;
            qps[i * opt.runs + r] = (double)cs[i].m / (dt > 0 ? dt : 1e-9);
        }
    for (int i = 0; i < nc; i++) {
        config *c = &cs[i];
        double *v = &qps[i * opt.runs];
        c->qps = bench_median(v, opt.runs);
        c->qps_min = v[0];
        c->qps_max = v[opt.runs - 1];
        fprintf(g_csv, "%s,%zu,%s,%u,%s,%.6g,%s,%s,%d,%zu,%d,%.1f,%.1f,%.1f,", d->name, d->n,
                qs->name, k, mode, (double)r2, struct_name(c->s->type), op_name(c->op),
                c->s->param, c->m, opt.runs, c->qps, c->qps_min, c->qps_max);
        if (c->has_stats) fprintf(g_csv, "%.2f,%.2f,", c->nodes_pq, c->evals_pq);
        else fprintf(g_csv, ",,");
        fprintf(g_csv, "%.2f,%.4f,%zu\n", c->found_mean, c->exact_frac, qs->truth.m);
    }
    fflush(g_csv);
    free(qps);
}

/* The cost of PM_SORT, paired: the unsorted configuration u and the sorted one s on the same
 * tree answer the same m queries in `rounds` rounds. Inside a round the queries go in chunks of
 * 256, each chunk answered by both back to back, the order alternating from chunk to chunk, so
 * that the load of the shared machine (which moves on a scale of milliseconds) hits both alike;
 * a round gives the ratio of the two summed times, t(s) / t(u). Returns the median ratio minus
 * 1 and the smallest and largest. */
static void sort_cost_paired(const config *u, const config *s, const float *q, unsigned k,
                             float r2, scratch *sc, int rounds, double *med, double *lo,
                             double *hi) {
    double ratio[64];
    const size_t m = u->m, chunk = 256;
    if (rounds > 64) rounds = 64;
    for (int r = 0; r < rounds; r++) {
        double t[2] = {0, 0};
        for (size_t b = 0, j = 0; b < m; b += chunk, j++) {
            size_t len = m - b < chunk ? m - b : chunk;
            for (int x = 0; x < 2; x++) {
                int srt = x ^ (int)((j + (size_t)r) & 1);
                double t0 = cpu_now();
                g_sink += run(srt ? s : u, q + 3 * b, len, k, r2, sc, NULL, NULL);
                t[srt] += cpu_now() - t0;
            }
        }
        ratio[r] = t[1] / (t[0] > 0 ? t[0] : 1e-9);
    }
    *med = bench_median(ratio, rounds) - 1; /* sorts ratio[] */
    *lo = ratio[0] - 1;
    *hi = ratio[rounds - 1] - 1;
}

/* The fastest configuration of cs[0..nc) with the given structure type and op (op < 0: any
 * FLANN op); -1 if none. */
static int best_of(const config *cs, int nc, int type, int op) {
    int b = -1;
    for (int i = 0; i < nc; i++)
        if (cs[i].s->type == type && (op < 0 || cs[i].op == op) && (b < 0 || cs[i].qps > cs[b].qps))
            b = i;
    return b;
}

static void label(char *buf, size_t n, const config *c) {
    snprintf(buf, n, "%s_%s_%d", struct_name(c->s->type), op_name(c->op), c->s->param);
}

/* g_oracle_r2 for the pool of qs: each query's k-th dist2 by an (untimed) unlimited search. */
static void oracle_radii(const structure *kd, const qset *qs, unsigned k, scratch *sc) {
    float *r = realloc(g_oracle_r2, opt.pool * sizeof *r);
    if (!r) {
        fprintf(stderr, "bench_knn: out of memory\n");
        exit(2);
    }
    g_oracle_r2 = r, g_oracle_q = qs->q;
    for (size_t i = 0; i < opt.pool; i++) {
        int f = pm_kdtree_knn(kd->kd, &qs->q[3 * i], k, INFINITY, sc->nb, 0, NULL);
        float mx = 0;
        for (int j = 0; j < f; j++)
            if (sc->nb[j].dist2 > mx) mx = sc->nb[j].dist2;
        r[i] = f < (int)k ? INFINITY : nextafterf(mx, INFINITY);
    }
}

static void run_dataset(dataset *d) {
    structure kd[NELEM(KD_B)], fl[NELEM(FL_LEAF)], oc[NELEM(OCT_CAP)], nf[2 * NELEM(NF_LEAF)];
    /* above 1.5M points only k = 50 (the 4M target), to keep the run within its time */
    const int small = opt.quick || d->n > 1500000;
    const unsigned *ks = opt.nks ? opt.ks : small ? KS_QUICK : KS_FULL;
    const int nk = opt.nks ? opt.nks : small ? (int)NELEM(KS_QUICK) : (int)NELEM(KS_FULL);
    scratch *sc = malloc(sizeof *sc);
    bench_log("%s n=%zu: building", d->name, d->n);
    for (size_t i = 0; i < NELEM(KD_B); i++) structure_build(&kd[i], d, S_KD, (int)KD_B[i], 0);
    for (size_t i = 0; i < NELEM(FL_LEAF); i++) structure_build(&fl[i], d, S_FLANN, FL_LEAF[i], 0);
    for (size_t i = 0; i < NELEM(OCT_CAP); i++)
        structure_build(&oc[i], d, S_OCT, (int)OCT_CAP[i], 0);
    for (size_t i = 0; i < NELEM(nf); i++)
        structure_build(&nf[i], d, S_NF, (int)NF_LEAF[i / 2], (int)(i & 1));
    for (int s = 0; s < 2; s++) {
        qset *qs = &d->qs[s];
        if (!(opt.sets >> s & 1)) continue;
        for (int ki = 0; ki < nk; ki++) {
            unsigned k = ks[ki];
            for (int mode = 0; mode < 2; mode++) {
                float r2 = INFINITY;
                if (!(opt.modes >> mode & 1)) continue;
                if (mode == 1) {
                    double *v = malloc(qs->truth.m * sizeof *v);
                    for (size_t i = 0; i < qs->truth.m; i++)
                        v[i] = qs->truth.count[i] >= k ? qs->truth.dist2[i * KMAX + k - 1] : INFINITY;
                    r2 = (float)bench_median(v, (int)qs->truth.m);
                    free(v);
                    if (!(r2 > 0) || isinf(r2)) continue;
                }
                config cs[48];
                int nc = 0;
                for (size_t i = 0; i < NELEM(KD_B); i++) {
                    cs[nc++] = (config){.s = &kd[i], .op = OP_KNN};
                    cs[nc++] = (config){.s = &kd[i], .op = OP_KNN_SORTED};
                }
                for (size_t i = 0; i < NELEM(FL_LEAF); i++) {
                    cs[nc++] = (config){.s = &fl[i], .op = OP_FL_BATCH};
                    if (mode == 1) cs[nc++] = (config){.s = &fl[i], .op = OP_FL_RMAXNN};
                }
                for (size_t i = 0; i < NELEM(nf); i++)
                    cs[nc++] = (config){.s = &nf[i], .op = nf[i].tree_order ? OP_NF_TREE : OP_NF};
                if (opt.oracle && mode == 0) {
                    oracle_radii(&kd[0], qs, k, sc);
                    for (size_t i = 0; i < NELEM(KD_B); i++)
                        cs[nc++] = (config){.s = &kd[i], .op = OP_KNN_ORACLE};
                }
                if (k == OCT_K)
                    for (size_t i = 0; i < NELEM(OCT_CAP); i++)
                        cs[nc++] = (config){.s = &oc[i], .op = OP_KNN};
                const char *mname = mode ? "radius" : "unlimited";
                bench_log("%s n=%zu %s k=%u %s: %d configurations", d->name, d->n, qs->name, k,
                          mname, nc);
                measure(cs, nc, d, qs, k, mname, r2, sc);
                int bk = best_of(cs, nc, S_KD, OP_KNN), bs = best_of(cs, nc, S_KD, OP_KNN_SORTED);
                /* the sorted twin of the fastest unsorted B, for the paired cost of PM_SORT */
                int bt = bk;
                for (int i = 0; i < nc; i++)
                    if (cs[i].s == cs[bk].s && cs[i].op == OP_KNN_SORTED) bt = i;
                double scm, scl, sch;
                sort_cost_paired(&cs[bk], &cs[bt], qs->q, k, r2, sc, opt.sort_rounds, &scm, &scl,
                                 &sch);
                int bf = best_of(cs, nc, S_FLANN, -1), bo = best_of(cs, nc, S_OCT, -1);
                int bn = best_of(cs, nc, S_NF, -1), bni = best_of(cs, nc, S_NF, OP_NF);
                char lk[64], ls[64], lf[64], lo[64] = "";
                label(lk, sizeof lk, &cs[bk]);
                label(ls, sizeof ls, &cs[bs]);
                label(lf, sizeof lf, &cs[bf]);
                if (bo >= 0) label(lo, sizeof lo, &cs[bo]);
                double exact = 1;
                for (int i = 0; i < nc; i++)
                    if (cs[i].exact_frac < exact) exact = cs[i].exact_frac;
                fprintf(g_best, "%s,%zu,%s,%u,%s,%.6g,%s,%.1f,%s,%.1f,%s,%.1f,", d->name, d->n,
                        qs->name, k, mname, (double)r2, lk, cs[bk].qps, ls, cs[bs].qps, lf,
                        cs[bf].qps);
                if (bo >= 0) fprintf(g_best, "%s,%.1f,", lo, cs[bo].qps);
                else fprintf(g_best, ",,");
                fprintf(g_best, "%.3f,%.3f,%.3f,", cs[bk].qps / cs[bf].qps, cs[bs].qps / cs[bf].qps,
                        scm);
                if (bo >= 0) fprintf(g_best, "%.3f,", cs[bk].qps / cs[bo].qps);
                else fprintf(g_best, ",");
                fprintf(g_best, "%.2f,%.2f,%.4f,%.3f,%.3f,%d,", cs[bk].evals_pq, cs[bk].found_mean,
                        exact, scl, sch, opt.sort_rounds);
                char ln[64], lni[64];
                label(ln, sizeof ln, &cs[bn]);
                label(lni, sizeof lni, &cs[bni]);
                fprintf(g_best, "%s,%.1f,%.3f,%s,%.1f,%.3f\n", ln, cs[bn].qps,
                        cs[bk].qps / cs[bn].qps, lni, cs[bni].qps, cs[bk].qps / cs[bni].qps);
                fflush(g_best);
            }
        }
    }
    for (size_t i = 0; i < NELEM(KD_B); i++) structure_release(&kd[i]);
    for (size_t i = 0; i < NELEM(FL_LEAF); i++) structure_release(&fl[i]);
    for (size_t i = 0; i < NELEM(OCT_CAP); i++) structure_release(&oc[i]);
    for (size_t i = 0; i < NELEM(nf); i++) structure_release(&nf[i]);
    free(sc);
}

static void usage(FILE *f) {
    fprintf(f,
            "usage: bench_knn [--quick] [--out DIR] [--n LIST] [--runs R] [--seed S]\n"
            "                 [--workloads LIST] [--map NAME=FILE]... [--k LIST]\n"
            "                 [--queries near|empty] [--modes unlimited|radius]\n"
            "\n"
            "Races our kd-tree (B 8..64; unsorted and PM_SORT) against nanoflann (leaf 8..64, points\n"
            "in input order and in its tree order), FLANN's exact single kd-tree (leaf 16..64)\n"
            "and the octree on clustered, slab and planar-caustic points and\n"
            "on photon-map files, with near-data and empty-space queries, k = 10, 50, 200,\n"
            "unlimited and maximum-radius modes, one thread. Writes knn.csv, knn_build.csv and\n"
            "knn_best.csv to DIR (columns: bench/README.md); progress goes to stderr.\n"
            "\n"
            "  --quick           N = 20000, k = 50, short runs: the test suite's smoke run\n"
            "  --out DIR         output directory (default bench/results; must exist)\n"
            "  --n LIST          comma list of N for the generated workloads (default 1e6,4e6)\n"
            "  --runs R          timed runs per configuration, median reported (default 3)\n"
            "  --build-runs R    builds per structure, median reported (default 1)\n"
            "  --seed S          random seed (default 1)\n"
            "  --workloads LIST  comma list of cluster,slab,caustic (default all three)\n"
            "  --map NAME=FILE   also race on a photon-map file (pm_map_save format); may repeat\n"
            "  --k LIST          only these k (comma list of 10, 50, 200; default all three,\n"
            "                    above 1.5M points 50)\n"
            "  --queries SET     only the query set near or empty (default both)\n"
            "  --modes MODE      only unlimited or radius (default both)\n"
            "  --oracle          also time kdtree_knn_oracle_B in unlimited mode: the same search\n"
            "                    given each query's own k-th distance (next float up) as its\n"
            "                    maximum radius, found first by an untimed search. A diagnostic of\n"
            "                    how much time goes into finding the radius, not a configuration a\n"
            "                    caller can run: never counted as ours\n");
}

int main(int argc, char **argv) {
    static const char *const P = "bench_knn";
    const char *nlist = NULL;
    opt.out = "bench/results";
    opt.runs = 3;
    opt.build_runs = 1;
    opt.seed = 1;
    opt.workloads = "cluster,slab,caustic";
    opt.sets = opt.modes = 3;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            usage(stdout);
            return 0;
        } else if (!strcmp(a, "--quick")) {
            opt.quick = 1;
        } else if (!strcmp(a, "--oracle")) {
            opt.oracle = 1;
        } else if (v && !strcmp(a, "--out")) {
            opt.out = v, i++;
        } else if (v && !strcmp(a, "--n")) {
            nlist = v, i++;
        } else if (v && !strcmp(a, "--runs")) {
            if (bench_parse_int(P, a, v, 3, 1000, &opt.runs) < 0) return 2;
            i++;
        } else if (v && !strcmp(a, "--build-runs")) {
            if (bench_parse_int(P, a, v, 1, 16, &opt.build_runs) < 0) return 2;
            i++;
        } else if (v && !strcmp(a, "--seed")) {
            if (bench_parse_u64(P, a, v, &opt.seed) < 0) return 2;
            i++;
        } else if (v && !strcmp(a, "--workloads")) {
            opt.workloads = v, i++;
        } else if (v && !strcmp(a, "--k")) {
            const char *p = v;
            for (;;) {
                size_t n = strcspn(p, ",");
                unsigned kv = n == 2 && !strncmp(p, "10", 2)    ? 10
                              : n == 2 && !strncmp(p, "50", 2)  ? 50
                              : n == 3 && !strncmp(p, "200", 3) ? 200
                                                                : 0;
                if (!kv || opt.nks == (int)NELEM(opt.ks)) {
                    fprintf(stderr, "bench_knn: --k: expected a comma list of 10, 50, 200, got '%s'\n", v);
                    return 2;
                }
                opt.ks[opt.nks++] = kv;
                if (!p[n]) break;
                p += n + 1;
            }
            i++;
        } else if (v && (!strcmp(a, "--queries") || !strcmp(a, "--modes"))) {
            int q = !strcmp(a, "--queries");
            const char *w0 = q ? "near" : "unlimited", *w1 = q ? "empty" : "radius";
            int bits = !strcmp(v, w0) ? 1 : !strcmp(v, w1) ? 2 : 0;
            if (!bits) {
                fprintf(stderr, "bench_knn: %s: expected %s or %s, got '%s'\n", a, w0, w1, v);
                return 2;
            }
            *(q ? &opt.sets : &opt.modes) = bits;
            i++;
        } else if (v && !strcmp(a, "--map")) {
            const char *eq = strchr(v, '=');
            if (!eq || eq == v || !eq[1] || opt.nmaps == MAX_MAPS) {
                fprintf(stderr, "bench_knn: --map: expected NAME=FILE (at most %d), got '%s'\n",
                        MAX_MAPS, v);
                return 2;
            }
            opt.map_name[opt.nmaps] = strndup(v, (size_t)(eq - v));
            opt.map_file[opt.nmaps++] = eq + 1;
            i++;
        } else {
            fprintf(stderr, "bench_knn: unknown or incomplete option '%s'\n", a);
            usage(stderr);
            return 2;
        }
    }
    /* the workload words */
    {
        const char *p = opt.workloads;
        for (;;) {
            size_t n = strcspn(p, ",");
            if (!((n == 7 && !strncmp(p, "cluster", 7)) || (n == 4 && !strncmp(p, "slab", 4)) ||
                  (n == 7 && !strncmp(p, "caustic", 7)) || n == 0)) {
                fprintf(stderr, "bench_knn: --workloads: unknown word '%.*s' (allowed: cluster slab caustic)\n",
                        (int)n, p);
                return 2;
            }
            if (!p[n]) break;
            p += n + 1;
        }
    }
    if (nlist) {
        const char *p = nlist;
        for (;;) {
            char w[64];
            size_t n = strcspn(p, ",");
            if (n >= sizeof w || opt.nn == (int)NELEM(opt.ns)) {
                fprintf(stderr, "bench_knn: --n: at most %d counts, got '%s'\n", (int)NELEM(opt.ns), nlist);
                return 2;
            }
            memcpy(w, p, n);
            w[n] = 0;
            if (bench_parse_count(P, "--n", w, 1000, 1e8, &opt.ns[opt.nn++]) < 0) return 2;
            if (!p[n]) break;
            p += n + 1;
        }
    } else if (opt.quick) {
        opt.ns[opt.nn++] = 20000;
    } else {
        opt.ns[opt.nn++] = 1000000;
        opt.ns[opt.nn++] = 4000000;
    }
    opt.target = opt.quick ? 0.003 : 0.03;
    opt.sort_rounds = opt.quick ? 3 : 9;
    opt.pool = opt.quick ? 2000 : 30000;
    opt.g = opt.quick ? 40 : 60;

    g_csv = bench_csv_open(opt.out, "knn.csv",
                           "workload,n,queries,k,mode,r2,index,variant,param,timed_queries,runs,"
                           "qps,qps_min,qps_max,nodes_per_query,dist_evals_per_query,mean_found,"
                           "exact_frac,verified");
    g_build = bench_csv_open(opt.out, "knn_build.csv",
                             "workload,n,index,param,build_s,runs,bytes_per_photon");
    g_best = bench_csv_open(opt.out, "knn_best.csv",
                            "workload,n,queries,k,mode,r2,kdtree,kdtree_qps,kdtree_sorted,"
                            "kdtree_sorted_qps,flann,flann_qps,octree,octree_qps,ratio_flann,"
                            "ratio_sorted_flann,sort_cost,ratio_octree,kdtree_dist_evals,"
                            "kdtree_mean_found,min_exact_frac,sort_cost_min,sort_cost_max,"
                            "sort_rounds,nanoflann,nanoflann_qps,ratio_nanoflann,"
                            "nanoflann_input,nanoflann_input_qps,ratio_nanoflann_input");
    bench_log("bench_knn: %s, %d runs", opt.quick ? "quick" : "full", opt.runs);

    static const char *const W[] = {"cluster", "slab", "caustic"};
    for (int ni = 0; ni < opt.nn; ni++)
        for (size_t wi = 0; wi < NELEM(W); wi++) {
            const char *p = opt.workloads;
            int on = 0;
            for (;;) {
                size_t n = strcspn(p, ",");
                on |= n == strlen(W[wi]) && !strncmp(p, W[wi], n);
                if (!p[n]) break;
                p += n + 1;
            }
            if (!on) continue;
            dataset d;
            dataset_generate(&d, W[wi], opt.ns[ni]);
            run_dataset(&d);
            dataset_free(&d);
        }
    for (int mi = 0; mi < opt.nmaps; mi++) {
        dataset d;
        if (dataset_load(&d, opt.map_name[mi], opt.map_file[mi]) != 0) return 1;
        run_dataset(&d);
        dataset_free(&d);
    }
    fclose(g_csv);
    fclose(g_build);
    fclose(g_best);
    bench_log("done (checksum %llu)", (unsigned long long)(g_sink & 0xff));
    return 0;
}
