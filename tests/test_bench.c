/* test_bench.c: runs the quick benchmark so that it never rots, and checks what it wrote.
 *
 * No timing is asserted (the machine is shared). What is checked: every CSV has its documented
 * header and the rows of every sweep; every exact search (our kd-tree, the octree, brute
 * force, FLANN's single kd-tree) had recall 1 and answered every verified query exactly like
 * the brute-force truth computed inside the bench; the approximate forest reports a recall in
 * [0, 1]; the kd-tree costs 20 bytes per photon plus a fixed header; and a photon-map file
 * written with pm_map_save goes through the bench's file path. In the release build the whole
 * quick run goes through scripts/run-bench.sh (plots and document included, and a small
 * photon map dumped by the renderer as the third workload); under the sanitizers the search
 * bench alone runs on smaller sizes.
 */
#include <stdlib.h>
#include <string.h>
#include "test.h"
#include "photon.h"

typedef struct csv {
    int nrows, ncols;
    char **cell; /* nrows x ncols, row 0 is the header */
    char *buf;
} csv;

static int csv_load(csv *c, const char *path) {
    FILE *f = fopen(path, "rb");
    long len;
    memset(c, 0, sizeof *c);
    if (!f) return -1;
    fseek(f, 0, SEEK_END);
    len = ftell(f);
    fseek(f, 0, SEEK_SET);
    c->buf = malloc((size_t)len + 1);
    if (fread(c->buf, 1, (size_t)len, f) != (size_t)len) len = 0;
    c->buf[len] = 0;
    fclose(f);
    int lines = 0;
    for (long i = 0; i < len; i++) lines += c->buf[i] == '\n';
    c->ncols = 1;
    for (char *p = c->buf; *p && *p != '\n'; p++) c->ncols += *p == ',';
    c->cell = calloc((size_t)(lines + 1) * (size_t)c->ncols, sizeof *c->cell);
    char *line = c->buf;
    while (*line) {
        char *nl = strchr(line, '\n');
        if (nl) *nl = 0;
        int col = 0;
        char *p = line;
        c->cell[c->nrows * c->ncols + col++] = p;
        for (; *p; p++)
            if (*p == ',') {
                *p = 0;
                if (col < c->ncols) c->cell[c->nrows * c->ncols + col++] = p + 1;
            }
        if (col != c->ncols) return -2; /* ragged row */
        c->nrows++;
        if (!nl) break;
        line = nl + 1;
    }
    return 0;
}
static void csv_free(csv *c) {
    free(c->cell);
    free(c->buf);
}
static const char *at(const csv *c, int row, const char *name) {
    for (int j = 0; j < c->ncols; j++)
        if (!strcmp(c->cell[j], name)) return c->cell[row * c->ncols + j];
    return ""; /* unknown column: matches nothing, so the row checks fail */
}
/* Rows matching up to three name=value pairs (NULL name: unused). */
static int count_rows(const csv *c, const char *n1, const char *v1, const char *n2,
                      const char *v2, const char *n3, const char *v3) {
    int k = 0;
    for (int r = 1; r < c->nrows; r++) {
        if (n1 && strcmp(at(c, r, n1), v1)) continue;
        if (n2 && strcmp(at(c, r, n2), v2)) continue;
        if (n3 && strcmp(at(c, r, n3), v3)) continue;
        k++;
    }
    return k;
}

/* One-thread rows of a sweep, dist and index (the all-threads rows exist only on >1 core). */
static int count_rows3(const csv *c, const char *sweep, const char *dist, const char *index) {
    int k = 0;
    for (int r = 1; r < c->nrows; r++)
        k += !strcmp(at(c, r, "sweep"), sweep) && !strcmp(at(c, r, "dist"), dist) &&
             !strcmp(at(c, r, "index"), index) && !strcmp(at(c, r, "threads"), "1");
    return k;
}

static const char *QUERY_HDR =
    "sweep,dist,n,index,variant,param,k,r_rel,r2,threads,queries,runs,qps,qps_min,qps_max,"
    "ns_per_query,nodes_per_query,dist_evals_per_query,mean_found,recall,exact_frac,verified";
static const char *BUILD_HDR =
    "sweep,dist,n,index,param,build_s,build_s_min,build_s_max,runs,bytes_per_photon,"
    "data_bytes_per_photon,index_bytes_per_photon,heap_delta_per_photon,flann_used_per_photon,"
    "mem_method";
static const char *HEAD_HDR = "dist,n,metric,ours,ours_value,peer,peer_value,ratio,target,met";

static int first_line_is(const char *path, const char *want) {
    char line[1024] = "";
    FILE *f = fopen(path, "r");
    if (!f) return 0;
    if (!fgets(line, sizeof line, f)) line[0] = 0;
    fclose(f);
    line[strcspn(line, "\n")] = 0;
    return strcmp(line, want) == 0;
}

/* Every exact search answered every verified query like brute force (exact_frac 1, recall 1);
 * the forest's recall is a fraction. */
static void check_exactness(const csv *q, int min_rows) {
    int exact_rows = 0;
    for (int r = 1; r < q->nrows; r++) {
        const char *ix = at(q, r, "index");
        double recall = atof(at(q, r, "recall")), ex = atof(at(q, r, "exact_frac"));
        EXPECT(atoi(at(q, r, "verified")) > 0);
        EXPECT(atof(at(q, r, "qps")) > 0);
        if (!strcmp(ix, "flann_forest4")) {
            EXPECT_MSG(recall >= 0 && recall <= 1, "forest recall %g", recall);
        } else {
            EXPECT_MSG(recall == 1.0 && ex == 1.0, "row %d: %s %s %s recall %s exact %s", r, ix,
                       at(q, r, "variant"), at(q, r, "param"), at(q, r, "recall"),
                       at(q, r, "exact_frac"));
            exact_rows++;
        }
    }
    EXPECT_MSG(exact_rows >= min_rows, "%d exact rows", exact_rows);
}

/* Oracle: brute force inside the bench (exact_frac, recall), the documented CSV layout, the
 * sweep definitions of bench_search.c, and the 20-byte record (bytes per photon). */
TEST(bench_quick_run_writes_checked_csvs) {
    char cmd[4096], out[16384], path[2048];
    const char *dir = pm_test_tmpdir();
    const char *build = pm_test_build_dir();
    int rc;
    if (PM_TEST_SANITIZED)
        snprintf(cmd, sizeof cmd, "%s/bench_search --quick --n 4000 --out %s", build, dir);
    else
        snprintf(cmd, sizeof cmd, "cd %s && sh scripts/run-bench.sh %s quick %s", pm_test_source_dir(),
                 build, dir);
    rc = pm_test_run(cmd, out, sizeof out);
    ASSERT_MSG(rc == 0, "quick bench failed (%d): %s", rc, out);

    snprintf(path, sizeof path, "%s/queries.csv", dir);
    ASSERT(first_line_is(path, QUERY_HDR));
    csv q;
    ASSERT_EQ_INT(csv_load(&q, path), 0);
    snprintf(path, sizeof path, "%s/build.csv", dir);
    ASSERT(first_line_is(path, BUILD_HDR));
    csv b;
    ASSERT_EQ_INT(csv_load(&b, path), 0);
    snprintf(path, sizeof path, "%s/headline.csv", dir);
    ASSERT(first_line_is(path, HEAD_HDR));
    csv h;
    ASSERT_EQ_INT(csv_load(&h, path), 0);

    static const char *dists[] = {"photon", "uniform"};
    for (int d = 0; d < 2; d++) {
        const char *ds = dists[d];
        /* param sweep, one thread: 6 B x 2 searches, 7 capacities, 6 leaves x 2, 5 checks, brute */
        static const char *kb[] = {"1", "2", "4", "8", "16", "32"};
        for (int i = 0; i < 6; i++) {
            EXPECT_EQ_INT(count_rows(&q, "sweep", "param", "dist", ds, "param", kb[i]) > 0, 1);
        }
        EXPECT_EQ_INT(count_rows3(&q, "param", ds, "kdtree"), 12);
        EXPECT_EQ_INT(count_rows3(&q, "param", ds, "octree"), 7);
        EXPECT_EQ_INT(count_rows3(&q, "param", ds, "flann_single"), 12);
        EXPECT_EQ_INT(count_rows3(&q, "param", ds, "flann_forest4"), 5);
        EXPECT_EQ_INT(count_rows3(&q, "param", ds, "brute"), 1);
        EXPECT_EQ_INT(count_rows(&q, "sweep", "headline", "dist", ds, NULL, NULL), 8);
        static const char *ks[] = {"1", "10", "50", "100", "500"};
        for (int i = 0; i < 5; i++)
            EXPECT_MSG(count_rows(&q, "sweep", "k", "dist", ds, "k", ks[i]) >= 5, "k=%s", ks[i]);
        EXPECT(count_rows(&q, "sweep", "radius", "dist", ds, "r_rel", "inf") >= 5);
        EXPECT(count_rows(&q, "sweep", "radius", "dist", ds, "variant", "radius") >= 3 * 6);
        EXPECT_EQ_INT(count_rows(&h, "dist", ds, NULL, NULL, NULL, NULL), 5);
        EXPECT_EQ_INT(count_rows(&b, "sweep", "param", "dist", ds, NULL, NULL), 6 + 7 + 6 + 1);
    }
    EXPECT(count_rows(&q, "sweep", "n", "dist", "photon", NULL, NULL) >= 2 * 5);
    EXPECT(count_rows(&b, "sweep", "n", NULL, NULL, NULL, NULL) >= 2 * 3);
    check_exactness(&q, 2 * (12 + 7 + 12 + 1));
    /* 20-byte records; the tree owns a fixed header only (axis bits in the flag byte) */
    for (int r = 1; r < b.nrows; r++)
        if (!strcmp(at(&b, r, "index"), "kdtree")) {
            double bpp = atof(at(&b, r, "bytes_per_photon"));
            EXPECT_MSG(bpp >= 20.0 && bpp < 20.1, "kd-tree bytes/photon %g", bpp);
        }
    if (!PM_TEST_SANITIZED) {
        /* run-bench.sh had the renderer dump a real photon map (cornell_spheres, 20000
         * global photons): the third workload, verified like the others */
        EXPECT_EQ_INT(count_rows3(&q, "param", "file", "kdtree"), 12);
        EXPECT_EQ_INT(count_rows(&h, "dist", "file", NULL, NULL, NULL, NULL), 5);
        for (int r = 1; r < q.nrows; r++)
            if (!strcmp(at(&q, r, "dist"), "file"))
                EXPECT_MSG(atoi(at(&q, r, "n")) >= 20000, "map of %s photons", at(&q, r, "n"));
        snprintf(path, sizeof path, "%s/BENCHMARKS.md", dir);
        FILE *f = fopen(path, "r");
        EXPECT_MSG(f != NULL, "run-bench.sh wrote no document");
        if (f) fclose(f);
    }
    csv_free(&q);
    csv_free(&b);
    csv_free(&h);

    /* The workload race: every configuration exact on its verified queries; one summary row
     * per workload, query set and mode at k = 50; the kd-tree within 20 bytes per photon. */
    if (PM_TEST_SANITIZED) {
        snprintf(cmd, sizeof cmd, "%s/bench_knn --quick --n 3000 --out %s", build, dir);
        rc = pm_test_run(cmd, out, sizeof out);
        ASSERT_MSG(rc == 0, "bench_knn failed (%d): %s", rc, out);
    }
    csv kq, kb, kd;
    snprintf(path, sizeof path, "%s/knn.csv", dir);
    ASSERT_EQ_INT(csv_load(&kq, path), 0);
    snprintf(path, sizeof path, "%s/knn_best.csv", dir);
    ASSERT_EQ_INT(csv_load(&kb, path), 0);
    snprintf(path, sizeof path, "%s/knn_build.csv", dir);
    ASSERT_EQ_INT(csv_load(&kd, path), 0);
    static const char *wl[] = {"cluster", "slab", "caustic", "map:cornell_spheres"};
    for (int w = 0; w < (PM_TEST_SANITIZED ? 3 : 4); w++)
        for (int qs = 0; qs < 2; qs++)
            EXPECT_MSG(count_rows(&kb, "workload", wl[w], "queries", qs ? "empty" : "near", "k",
                                  "50") == 2,
                       "knn_best.csv: %s %s", wl[w], qs ? "empty" : "near");
    for (int r = 1; r < kq.nrows; r++) {
        EXPECT_MSG(atof(at(&kq, r, "exact_frac")) == 1.0, "knn.csv row %d: %s %s %s exact %s", r,
                   at(&kq, r, "workload"), at(&kq, r, "index"), at(&kq, r, "variant"),
                   at(&kq, r, "exact_frac"));
        EXPECT(atoi(at(&kq, r, "verified")) > 0 && atof(at(&kq, r, "qps")) > 0);
    }
    EXPECT(kq.nrows > 1 && kb.nrows > 1);
    /* nanoflann raced in every cell, in both point orders (their rows are exact above). */
    for (int r = 1; r < kb.nrows; r++)
        EXPECT_MSG(!strncmp(at(&kb, r, "nanoflann"), "nanoflann_knn_", 14) &&
                       atof(at(&kb, r, "nanoflann_qps")) > 0 &&
                       !strncmp(at(&kb, r, "nanoflann_input"), "nanoflann_knn_", 14),
                   "knn_best.csv row %d: no nanoflann ('%s')", r, at(&kb, r, "nanoflann"));
    EXPECT(count_rows(&kq, "workload", "cluster", "index", "nanoflann", "variant", "knn_tree_order") > 0);
    /* The paired cost of PM_SORT: a median of at least 3 rounds, inside their range. */
    for (int r = 1; r < kb.nrows; r++) {
        double c = atof(at(&kb, r, "sort_cost")), lo = atof(at(&kb, r, "sort_cost_min")),
               hi = atof(at(&kb, r, "sort_cost_max"));
        EXPECT_MSG(atoi(at(&kb, r, "sort_rounds")) >= 3 && lo <= c && c <= hi && lo > -1,
                   "knn_best.csv row %d: sort_cost %g outside [%g, %g] or too few rounds", r, c,
                   lo, hi);
    }
    for (int r = 1; r < kd.nrows; r++)
        if (!strcmp(at(&kd, r, "index"), "kdtree")) {
            double bpp = atof(at(&kd, r, "bytes_per_photon"));
            EXPECT_MSG(bpp >= 20.0 && bpp < 20.1, "kd-tree bytes/photon %g", bpp);
        }
    csv_free(&kq);
    csv_free(&kb);
    csv_free(&kd);
}

/* Oracle: brute force inside the bench. `bench_knn --oracle` also times the search given each
 * query's own k-th distance (the next float above it, from an untimed unlimited search): a
 * diagnostic of how much of a query goes into finding its radius, which no caller can do. Its
 * rows must answer exactly like brute force (a radius at or below the k-th distance would lose
 * neighbours: exact_frac < 1), find as many as the unlimited search of the same B, exist only
 * in unlimited mode, and never be named as ours in knn_best.csv (whose ratios are the
 * headline). */
TEST(bench_knn_oracle_rows_exact_and_never_ours) {
    char cmd[4096], out[16384], path[2048];
    const char *dir = pm_test_tmpdir();
    snprintf(cmd, sizeof cmd,
             "%s/bench_knn --quick --n 3000 --workloads cluster,slab --oracle --out %s",
             pm_test_build_dir(), dir);
    int rc = pm_test_run(cmd, out, sizeof out);
    ASSERT_MSG(rc == 0, "bench_knn --oracle failed (%d): %s", rc, out);
    csv kq, kb;
    snprintf(path, sizeof path, "%s/knn.csv", dir);
    ASSERT_EQ_INT(csv_load(&kq, path), 0);
    snprintf(path, sizeof path, "%s/knn_best.csv", dir);
    ASSERT_EQ_INT(csv_load(&kb, path), 0);
    /* 2 workloads x 2 query sets at k = 50, unlimited only, one row per B (8, 16, 32, 64) */
    EXPECT_EQ_INT(count_rows(&kq, "variant", "knn_oracle", NULL, NULL, NULL, NULL), 16);
    EXPECT_EQ_INT(count_rows(&kq, "variant", "knn_oracle", "mode", "radius", NULL, NULL), 0);
    int checked = 0;
    for (int r = 1; r < kq.nrows; r++) {
        if (strcmp(at(&kq, r, "variant"), "knn_oracle")) continue;
        EXPECT_MSG(atof(at(&kq, r, "exact_frac")) == 1.0 && atoi(at(&kq, r, "verified")) > 0,
                   "knn.csv row %d: %s %s B=%s oracle exact %s", r, at(&kq, r, "workload"),
                   at(&kq, r, "queries"), at(&kq, r, "param"), at(&kq, r, "exact_frac"));
        EXPECT(atof(at(&kq, r, "qps")) > 0);
        /* the unlimited search of the same tree and cell found the same number */
        for (int u = 1; u < kq.nrows; u++)
            if (!strcmp(at(&kq, u, "variant"), "knn") && !strcmp(at(&kq, u, "index"), "kdtree") &&
                !strcmp(at(&kq, u, "mode"), "unlimited") &&
                !strcmp(at(&kq, u, "workload"), at(&kq, r, "workload")) &&
                !strcmp(at(&kq, u, "queries"), at(&kq, r, "queries")) &&
                !strcmp(at(&kq, u, "param"), at(&kq, r, "param"))) {
                EXPECT_MSG(!strcmp(at(&kq, u, "mean_found"), at(&kq, r, "mean_found")) &&
                               atof(at(&kq, r, "mean_found")) == 50.0,
                           "oracle row %d found %s, the search %s", r,
                           at(&kq, r, "mean_found"), at(&kq, u, "mean_found"));
                checked++;
            }
    }
    EXPECT_EQ_INT(checked, 16);
    EXPECT_EQ_INT(kb.nrows - 1, 8); /* 2 workloads x 2 query sets x 2 modes */
    for (int r = 1; r < kb.nrows; r++)
        EXPECT_MSG(!strncmp(at(&kb, r, "kdtree"), "kdtree_knn_", 11) &&
                       !strstr(at(&kb, r, "kdtree"), "oracle") &&
                       !strstr(at(&kb, r, "kdtree_sorted"), "oracle"),
                   "knn_best.csv row %d names '%s' / '%s' as ours", r, at(&kb, r, "kdtree"),
                   at(&kb, r, "kdtree_sorted"));
    csv_free(&kq);
    csv_free(&kb);
}

/* Oracle: brute force inside the bench, on a synthetic map file written with pm_map_save
 * (a clustered point set, so the tree shape differs from the built-in distributions). */
TEST(bench_reads_photon_map_files) {
    char cmd[4096], out[16384], path[2048], map[2048];
    const char *dir = pm_test_tmpdir();
    const size_t n = 5000;
    pm_photon *ph = calloc(n, sizeof *ph);
    uint64_t s = 12345;
    for (size_t i = 0; i < n; i++) {
        float pos[3], pw[3] = {1, 0.5f, 0.25f}, dir3[3] = {0, -1, 0}, nrm[3] = {0, 1, 0};
        for (int a = 0; a < 3; a++) {
            s = s * 6364136223846793005ull + 1442695040888963407ull;
            pos[a] = (float)((s >> 40) * (1.0 / 16777216.0));
        }
        if (i % 4 == 0) pos[0] *= 0.01f, pos[1] = 0.0f; /* a thin dense strip */
        pm_photon_set(&ph[i], pos, pw, dir3, nrm, PM_KIND_INDIRECT);
    }
    pm_map_header hdr = {PM_FILE_VERSION, (uint32_t)sizeof(pm_photon), n, PM_MAP_GLOBAL, n, 0, {0, 0}};
    snprintf(map, sizeof map, "%s/synthetic.pmap", dir);
    ASSERT_EQ_INT(pm_map_save(map, ph, &hdr), 0);
    free(ph);
    snprintf(cmd, sizeof cmd,
             "%s/bench_search --quick --threads 1 --dists file --map %s --sweeps param --out %s",
             pm_test_build_dir(), map, dir);
    int rc = pm_test_run(cmd, out, sizeof out);
    ASSERT_MSG(rc == 0, "bench on a map file failed (%d): %s", rc, out);
    snprintf(path, sizeof path, "%s/queries.csv", dir);
    csv q;
    ASSERT_EQ_INT(csv_load(&q, path), 0);
    ASSERT_EQ_INT(count_rows(&q, "dist", "file", "index", "kdtree", "threads", "1"), 12);
    ASSERT(count_rows(&q, "dist", "file", "n", "5000", NULL, NULL) > 0);
    ASSERT_EQ_INT(count_rows(&q, "dist", "photon", NULL, NULL, NULL, NULL), 0);
    check_exactness(&q, 12 + 7 + 12 + 1);
    csv_free(&q);
    /* and the bench refuses a missing file cleanly */
    snprintf(cmd, sizeof cmd, "%s/bench_search --quick --dists file --map %s/none.pmap --out %s",
             pm_test_build_dir(), dir, dir);
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 1);
}

/* Oracle: analytic irradiance of a uniformly lit square. Every estimator and k has a row in
 * both regions; in the interior at k = 500 every estimator is within 15% RMS (Poisson noise
 * alone is 1/sqrt(500) = 4.5%), and the disc's error at k = 15 exceeds its error at k = 500
 * (noise falls like 1/sqrt(k)). */
TEST(bench_estimate_writes_errors) {
    char cmd[4096], out[16384], path[2048];
    const char *dir = pm_test_tmpdir();
    snprintf(cmd, sizeof cmd, "%s/bench_estimate --quick %s --out %s", pm_test_build_dir(),
             PM_TEST_SANITIZED ? "--n 5000 --points 100 --runs 3" : "", dir);
    int rc = pm_test_run(cmd, out, sizeof out);
    ASSERT_MSG(rc == 0, "bench_estimate failed (%d): %s", rc, out);
    snprintf(path, sizeof path, "%s/estimate.csv", dir);
    ASSERT(first_line_is(path, "region,estimator,bias,k,estimates,ns_per_estimate,rms_rel_error,"
                               "mean_rel_error,setup_s"));
    csv e;
    ASSERT_EQ_INT(csv_load(&e, path), 0);
    ASSERT_EQ_INT(e.nrows - 1, 2 * 7 * 4);
    static const char *names[] = {"disc", "cone", "gauss", "differential", "hull", "precomputed"};
    for (int i = 0; i < 6; i++)
        EXPECT_MSG(count_rows(&e, "estimator", names[i], "k", "500", "region", "edge") >= 1, "%s", names[i]);
    double disc15 = -1, disc500 = -1;
    for (int r = 1; r < e.nrows; r++) {
        double rms = atof(at(&e, r, "rms_rel_error"));
        EXPECT(isfinite(rms) && rms >= 0);
        EXPECT(atof(at(&e, r, "ns_per_estimate")) > 0);
        if (!strcmp(at(&e, r, "region"), "interior") && !strcmp(at(&e, r, "k"), "500"))
            EXPECT_MSG(rms < 0.15, "%s interior k=500: rms %g", at(&e, r, "estimator"), rms);
        if (!strcmp(at(&e, r, "region"), "interior") && !strcmp(at(&e, r, "estimator"), "disc") &&
            !strcmp(at(&e, r, "bias"), "area")) {
            if (!strcmp(at(&e, r, "k"), "15")) disc15 = rms;
            if (!strcmp(at(&e, r, "k"), "500")) disc500 = rms;
        }
    }
    EXPECT_MSG(disc15 > disc500 && disc500 > 0, "disc rms k=15 %g, k=500 %g", disc15, disc500);
    csv_free(&e);
}

/* Oracle: the documented command line: --help succeeds and names its options; an unknown
 * option, and impossible or malformed values (negative, zero, too large, trailing garbage),
 * exit with status 2 and a message naming the option, before any output is written (the
 * --out directory does not exist, so a program that ran would fail differently). */
TEST(bench_programs_have_help) {
    static const char *progs[] = {"bench_search", "bench_estimate", "bench_knn"};
    for (int i = 0; i < 3; i++) {
        char cmd[2048], out[8192], bin[1024];
        snprintf(bin, sizeof bin, "%s/%s", pm_test_build_dir(), progs[i]);
        FILE *f = fopen(bin, "rb");
        if (!f) {
            EXPECT_MSG(0, "%s is missing", bin);
            continue;
        }
        fclose(f);
        snprintf(cmd, sizeof cmd, "%s --help", bin);
        EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
        EXPECT_MSG(strstr(out, "usage:") != NULL, "%s --help printed: %s", progs[i], out);
        snprintf(cmd, sizeof cmd, "%s --no-such-option", bin);
        EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 2);
        static const char *const bad[][2] = {
            {"--n", "-5"}, {"--n", "1e30"}, {"--n", "12x"}, {"--n", "1000.5"}, {"--runs", "0"},
            {"--runs", "abc"}, {"--seed", "-1"}, {"--threads", "0"}, {"--bucket", "0"},
            {"--points", "-3"}, {"--dists", "photon,nope"}, {"--sweeps", "k,"},
            {"--k", "7"}, {"--k", "50,"}, {"--queries", "far"}, {"--modes", "both"}};
        for (size_t j = 0; j < sizeof bad / sizeof bad[0]; j++) {
            /* each program rejects the options it knows and calls the others unknown */
            snprintf(cmd, sizeof cmd, "%s --quick --out %s/missing %s '%s' 2>&1", bin,
                     pm_test_tmpdir(), bad[j][0], bad[j][1]);
            int rc = pm_test_run(cmd, out, sizeof out);
            EXPECT_MSG(rc == 2, "%s %s %s: exit %d: %s", progs[i], bad[j][0], bad[j][1], rc, out);
            EXPECT_MSG(strstr(out, bad[j][0]) != NULL, "%s %s %s: message does not name it: %s",
                       progs[i], bad[j][0], bad[j][1], out);
            EXPECT_MSG(strstr(out, "missing/") == NULL, "%s %s %s: it tried to write: %s",
                       progs[i], bad[j][0], bad[j][1], out);
        }
    }
}

/* Oracle: scripts/gen-benchmarks-md.sh --readme-headline on the committed results. README's
 * `bench/` bullet carries the race's headline figures; run-bench.sh writes it from the results,
 * and this checks it was never typed or left stale: the bullet must equal what the generator
 * prints from bench/results now. */
TEST(bench_readme_headline_is_generated) {
    char cmd[4096], gen[8192], path[1024];
    snprintf(cmd, sizeof cmd, "sh %s/scripts/gen-benchmarks-md.sh --readme-headline %s/bench/results",
             pm_test_source_dir(), pm_test_source_dir());
    ASSERT_EQ_INT(pm_test_run(cmd, gen, sizeof gen), 0);
    ASSERT_MSG(strncmp(gen, "- `bench/`", 10) == 0, "generator printed: %s", gen);
    snprintf(path, sizeof path, "%s/README.md", pm_test_source_dir());
    FILE *f = fopen(path, "r");
    ASSERT_MSG(f != NULL, "cannot open %s", path);
    char line[2048], bullet[8192] = "";
    size_t len = 0;
    int in = 0;
    while (fgets(line, sizeof line, f)) {
        if (!in && strncmp(line, "- `bench/`", 10) == 0) in = 1;
        else if (in && (line[0] != ' ' || strncmp(line, "- ", 2) == 0)) break;
        if (in) {
            size_t l = strlen(line);
            if (len + l < sizeof bullet) memcpy(bullet + len, line, l + 1), len += l;
        }
    }
    fclose(f);
    EXPECT_MSG(strcmp(bullet, gen) == 0,
               "README.md's bench/ bullet is not the generated one (run make bench, or "
               "gen-benchmarks-md.sh --readme-headline):\n--- README:\n%s--- generated:\n%s",
               bullet, gen);
}

/* Oracle: the documented usage of every script in scripts/: --help prints it with status 0
 * and does nothing else (run-bench.sh used to take "--help" for its build directory). */
TEST(scripts_have_help) {
    static const char *scripts[] = {"run-bench.sh", "plot-bench.sh", "gen-benchmarks-md.sh",
                                    "install-deps.sh", "imgcmp", "gen-results-md.sh"};
    for (size_t i = 0; i < sizeof scripts / sizeof scripts[0]; i++) {
        char cmd[4096], out[8192];
        snprintf(cmd, sizeof cmd, "cd %s && sh %s/scripts/%s --help 2>&1", pm_test_tmpdir(),
                 pm_test_source_dir(), scripts[i]);
        EXPECT_MSG(pm_test_run(cmd, out, sizeof out) == 0, "%s --help: %s", scripts[i], out);
        EXPECT_MSG(strstr(out, "usage") || strstr(out, scripts[i]), "%s --help printed: %s",
                   scripts[i], out);
        EXPECT_MSG(!strstr(out, "# Benchmarks") && !strstr(out, "cannot open"),
                   "%s --help did work instead: %s", scripts[i], out);
    }
    char cmd[2048], out[256];
    snprintf(cmd, sizeof cmd, "ls -A %s | wc -l", pm_test_tmpdir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strtol(out, NULL, 10) == 0, "--help left files: %s", out);
}
