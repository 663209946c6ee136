/* bench_estimate.c: what accuracy costs — RMS error of each radiance estimator against its
 * time per estimate, on a case with an analytic answer.
 *
 * THE CASE. A unit square in the plane y = 0 (normal +y) lit uniformly: N photons at uniform
 * random positions, all with the same power, arriving from above. The true irradiance is
 * E = N * (decoded photon power) / 1 everywhere on the square and 0 outside, so the relative
 * error of an estimate at a point of the square is E_est / E - 1. Points are drawn in two
 * regions: the INTERIOR ([0.25, 0.75]^2, far from the edges for every k used) and near an EDGE
 * (x within 3 photon spacings of the edge x = 0), where the gathering disc reaches into the
 * dark and blurs the step: the place where differential checking and the convex hull are meant
 * to help.
 *
 * WHAT IS TIMED. pm_estimate (k-nearest search on the kd-tree + the estimator), one thread,
 * over all points of a region; the median of the runs. For precomputed irradiance the
 * precomputation (pm_irradiance_build, all threads) is reported as setup_s and the timed part
 * is pm_irradiance_lookup alone. Errors come from a separate untimed pass.
 *
 * OUTPUT: estimate.csv in the output directory (columns in bench/README.md), and two more
 * tables for docs/ACCURACY.md (scripts/gen-accuracy-md.sh): accuracy.csv (bias and noise of
 * every estimator on stratified and random photons and a focused caustic, untimed; see
 * accuracy() below) and irradiance_lookup.csv (the precomputed-irradiance lookup raced against
 * a private pm_photon tree; see lookup_race()). --help for options.
 */
#define _GNU_SOURCE
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "bench.h"
#include "estimate.h"
#include "irradiance.h"
#include "kdtree.h"
#include "photon.h"

static const unsigned KS[] = {15, 50, 100, 500};
#define NELEM(a) (sizeof(a) / sizeof((a)[0]))

typedef struct method {
    const char *name;
    const char *bias;
    pm_estimator kind;
    int bias_code;
    int precomputed;
} method;

static const method METHODS[] = {
    {"disc", "none", PM_EST_DISC, PM_BIAS_NONE, 0},
    {"disc", "area", PM_EST_DISC, PM_BIAS_AREA, 0},
    {"cone", "", PM_EST_CONE, PM_BIAS_AREA, 0},
    {"gauss", "", PM_EST_GAUSS, PM_BIAS_AREA, 0},
    {"differential", "", PM_EST_DIFFERENTIAL, PM_BIAS_AREA, 0},
    {"hull", "", PM_EST_HULL, PM_BIAS_AREA, 0},
    {"precomputed", "area", PM_EST_DISC, PM_BIAS_AREA, 1},
};

static volatile double g_sink;

static void usage(FILE *f) {
    fprintf(f,
            "usage: bench_estimate [--quick] [--out DIR] [--n N] [--points P] [--runs R]\n"
            "                      [--bucket B] [--seed S]\n"
            "\n"
            "RMS relative error against nanoseconds per estimate for the estimators of\n"
            "photonmap/estimate.h (disc with and without bias correction, cone, Gaussian,\n"
            "differential checking, convex hull) and precomputed irradiance (irradiance.h), for\n"
            "k in 15, 50, 100, 500, on a uniformly lit unit square (interior and near an edge).\n"
            "Writes DIR/estimate.csv (columns: bench/README.md); progress on stderr.\n"
            "\n"
            "  --quick      N = 20000 photons, 300 points per region\n"
            "  --lookup-only  only the precomputed-irradiance lookup race (irradiance_lookup.csv)\n"
            "  --accuracy-only  only the accuracy tables (accuracy.csv: stratified, random and\n"
            "               caustic photons; untimed)\n"
            "  --out DIR    output directory (default bench/results; must exist)\n"
            "  --n N        photons (default 200000)\n"
            "  --points P   estimate points per region (default 3000)\n"
            "  --runs R     timed runs, median reported (default 5, >= 3)\n"
            "  --bucket B   kd-tree bucket size (default 1, the classic tree that precomputed\n"
            "               irradiance's quarter selection is defined on)\n"
            "  --seed S     random seed (default 1)\n");
}

/* ---- precomputed irradiance lookup: the module's structure against a private pm_photon tree ----
 *
 * A photon map of random (Poisson) photons on three planes (floor, wall, a plane tilted 37
 * degrees), the quarter precomputed with k = 50. "private_tree" is what a renderer would build
 * by hand: a pm_kdtree (bucket 8) over copies of the precomputed pm_photon records with the
 * power replaced by the irradiance, queried with pm_kdtree_nearest_if and a predicate that
 * decodes each photon's normal; "pm_irradiance_lookup" is the module's own. Both answer "the
 * nearest precomputed photon with dot(normal, n) >= 0.7 within max_dist2"; every answer is
 * compared before timing. The runs alternate between the two, and the ratio of medians is
 * written (private / module: > 1 means the module is faster). */
static int private_agrees(void *user, const void *record, uint32_t index) {
    (void)index;
    const float *n = user;
    float pn[3];
    pm_normal_decode(((const pm_photon *)record)->normal, pn);
    return n[0] * pn[0] + n[1] * pn[1] + n[2] * pn[2] >= 0.7f;
}

static int lookup_race(const char *out, size_t n, size_t nq, int runs, uint64_t seed) {
    pm_photon *ph = malloc(n * sizeof *ph);
    float *q = malloc(nq * 6 * sizeof *q), *md2 = NULL;
    double *t[2] = {malloc((size_t)runs * sizeof(double)), malloc((size_t)runs * sizeof(double))};
    if (!ph || !q || !t[0] || !t[1]) return -1;
    bench_rng rng;
    bench_rng_seed(&rng, seed);
    const double c37 = cos(37 * 3.14159265358979 / 180), s37 = sin(37 * 3.14159265358979 / 180);
    const float nrm3[3][3] = {{0, 0, 1}, {1, 0, 0}, {(float)-s37, 0, (float)c37}};
    for (size_t i = 0; i < n; i++) {
        int pl = (int)(i % 3);
        double u = bench_rng_unit(&rng), v = bench_rng_unit(&rng);
        float pos[3] = {(float)u, (float)v, 0};
        if (pl == 1) pos[0] = 0, pos[1] = (float)u, pos[2] = (float)v;
        if (pl == 2) pos[0] = (float)(0.2 + 0.6 * u * c37), pos[1] = (float)v, pos[2] = (float)(0.3 + 0.6 * u * s37);
        const float *nm = nrm3[pl];
        float d[3] = {-nm[0], -nm[1], -nm[2]}, pw = (float)((0.5 + bench_rng_unit(&rng)) / (double)n);
        pm_photon_init(&ph[i], pos, (float[3]){pw, pw, pw}, d, nm, PM_KIND_INDIRECT);
    }
    /* queries on the planes, each with its plane's normal */
    for (size_t i = 0; i < nq; i++) {
        size_t j = (size_t)(bench_rng_unit(&rng) * (double)n);
        const float *nm = nrm3[j % 3];
        for (size_t a = 0; a < 3; a++) {
            q[6 * i + a] = ph[j].pos[a] + (float)(0.002 * (bench_rng_unit(&rng) - 0.5)) * (1 - fabsf(nm[a]));
            q[6 * i + 3 + a] = nm[a];
        }
    }
    pm_kdtree *tree = NULL, *priv = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(1), cfg8 = pm_kdtree_photon_config(8);
    if (pm_kdtree_build(&tree, ph, n, &cfg, NULL) != 0) return -1;
    pm_irradiance_options io;
    pm_irradiance *irr = NULL;
    pm_irradiance_options_init(&io, 50);
    io.fraction = PM_PRECOMP_QUARTER;
    if (pm_irradiance_build(&irr, tree, &io) != 0) return -1;
    size_t ni = pm_irradiance_count(irr), j = 0;
    pm_photon *iph = malloc((ni ? ni : 1) * sizeof *iph);
    if (!iph) return -1;
    for (size_t i = 0; i < n; i++) {
        float e[3];
        if (pm_irradiance_value(irr, (uint32_t)i, e)) {
            iph[j] = ph[i];
            pm_rgbe_encode(e, iph[j].power);
            j++;
        }
    }
    if (pm_kdtree_build(&priv, iph, j, &cfg8, NULL) != 0) return -1;
    FILE *csv = bench_csv_open(out, "irradiance_lookup.csv",
                               "photons,precomputed,queries,max_dist2,method,ns_per_lookup,"
                               "ratio_private_over_module,bytes_per_precomputed,mismatches");
    const float radii[2] = {INFINITY, (float)(4.0 / (double)n)};
    const double bytes_mod = (double)pm_irradiance_bytes(irr) / (double)ni;
    const double bytes_priv = (double)(j * sizeof *iph + pm_kdtree_index_bytes(priv)) / (double)ni;
    (void)md2;
    for (int ri = 0; ri < 2; ri++) {
        float r2 = radii[ri];
        size_t mism = 0;
        for (size_t i = 0; i < nq; i++) {
            float a[3], b[3] = {0, 0, 0};
            pm_neighbor nb;
            pm_irradiance_lookup(irr, &q[6 * i], &q[6 * i + 3], r2, 0.7f, a, NULL);
            if (pm_kdtree_nearest_if(priv, &q[6 * i], r2, private_agrees, &q[6 * i + 3], &nb, NULL) > 0)
                pm_rgbe_decode(iph[nb.index].power, b);
            mism += memcmp(a, b, sizeof a) != 0;
        }
        for (int run = 0; run < runs; run++)
            for (int m = 0; m < 2; m++) {
                double acc = 0, t0 = bench_now();
                for (size_t i = 0; i < nq; i++) {
                    float a[3] = {0, 0, 0};
                    pm_neighbor nb;
                    if (m == 1)
                        pm_irradiance_lookup(irr, &q[6 * i], &q[6 * i + 3], r2, 0.7f, a, NULL);
                    else if (pm_kdtree_nearest_if(priv, &q[6 * i], r2, private_agrees, &q[6 * i + 3], &nb, NULL) > 0)
                        pm_rgbe_decode(iph[nb.index].power, a);
                    acc += a[0];
                }
                t[m][run] = (bench_now() - t0) / (double)nq;
                g_sink += acc;
            }
        double med[2] = {bench_median(t[0], runs), bench_median(t[1], runs)};
        for (int m = 0; m < 2; m++)
            fprintf(csv, "%zu,%zu,%zu,%g,%s,%.1f,%.3f,%.2f,%zu\n", n, ni, nq, (double)r2,
                    m ? "pm_irradiance_lookup" : "private_tree", 1e9 * med[m], med[0] / med[1],
                    m ? bytes_mod : bytes_priv, mism);
        bench_log("irradiance lookup, max_dist2 %g: private %.1f ns, module %.1f ns (ratio %.3f), %zu mismatches",
                  (double)r2, 1e9 * med[0], 1e9 * med[1], med[0] / med[1], mism);
        if (mism) {
            fprintf(stderr, "bench_estimate: %zu lookups disagree with the private tree\n", mism);
            return -1;
        }
    }
    fclose(csv);
    pm_kdtree_free(priv);
    pm_kdtree_free(tree);
    pm_irradiance_free(irr);
    free(iph);
    free(ph);
    free(q);
    free(t[0]);
    free(t[1]);
    return 0;
}

/* ---- accuracy: bias and noise on stratified and random photons and a focused caustic ------
 *
 * Untimed. Three photon layouts with analytic irradiance:
 *   stratified  N photons on the unit square y = 0, one uniform point per cell of a jittered
 *               grid (as a stratified emission onto a plane would give);
 *   random      N uniform independent photons on the same square (what photon tracing gives:
 *               a Poisson-like map);
 *   caustic     a focused caustic: N photons drawn from a 2D Gaussian of standard deviation
 *               sigma = 0.05 around (0.5, 0.5), total power 1, so E(x) = exp(-d^2/(2 sigma^2))
 *               / (2 pi sigma^2); at two photon counts. The focus is the gathering radius
 *               over sigma: at the centre a k-photon disc has r/sigma = sqrt(2k/N), from 0.04
 *               (k = 15, N = 10000) to 0.63 (k = 200, N = 1000), so the caustic's curvature
 *               inside the disc goes from negligible to dominant.
 * Regions: the square's interior ([0.25, 0.75]^2) and edge (x within 3 photon spacings of
 * x = 0, where the true irradiance steps from E to 0); the caustic's centre (d < sigma/2)
 * and flank (sigma < d < 1.5 sigma). Each point's relative error is E_est / E_true - 1; the
 * CSV gives the mean (the bias), its standard error (from independent photon maps) and the
 * RMS over the points. */
typedef struct acc_method {
    const char *name, *variant;
    pm_estimator kind;
    int bias;
    double boundary;
} acc_method;

static const acc_method ACC_METHODS[] = {
    {"disc", "none", PM_EST_DISC, PM_BIAS_NONE, 0.2},
    {"disc", "area", PM_EST_DISC, PM_BIAS_AREA, 0.2},
    {"cone", "k_c=1", PM_EST_CONE, PM_BIAS_AREA, 0.2},
    {"gauss", "", PM_EST_GAUSS, PM_BIAS_AREA, 0.2},
    {"differential", "", PM_EST_DIFFERENTIAL, PM_BIAS_AREA, 0.2},
    {"hull", "boundary=0.2", PM_EST_HULL, PM_BIAS_AREA, 0.2},
    {"hull", "boundary=0", PM_EST_HULL, PM_BIAS_AREA, 0.0},
};
static const unsigned ACC_KS[] = {15, 50, 200};

#define ACC_SIGMA 0.05

static double gauss_sample(bench_rng *r) { /* Box-Muller, one of the pair */
    double u = bench_rng_unit(r), v = bench_rng_unit(r);
    return sqrt(-2.0 * log(1.0 - u)) * cos(2 * 3.14159265358979323846 * v);
}

static int accuracy(const char *out, int quick, uint64_t seed) {
    const int side = quick ? 100 : 200;
    /* Each layout is drawn R times, independently; every realization gets npts / R points per
     * region, and the standard error comes from the spread of the R realization means: points
     * of one photon map share photons (all of a caustic's centre does), so their errors are
     * correlated and a spread over points would understate it. */
    const int R = quick ? 4 : 32;
    const size_t npts = quick ? 400 : 6400, per = npts / (size_t)R;
    const size_t ncaus[2] = {quick ? 500u : 1000u, quick ? 5000u : 10000u};
    enum { NK = NELEM(ACC_KS), NM = NELEM(ACC_METHODS) };
    FILE *csv = bench_csv_open(out, "accuracy.csv",
                               "layout,region,photons,estimator,variant,k,points,mean_rel_error,"
                               "sem,rms_rel_error");
    const float up[3] = {0, 1, 0}, down[3] = {0, -1, 0};
    bench_rng rng;
    bench_rng_seed(&rng, seed + 17);
    void *scratch = malloc(pm_estimate_scratch_bytes(200));
    float *pts = malloc(per * 3 * sizeof *pts);
    double *etrue = malloc(per * sizeof *etrue);
    if (!scratch || !pts || !etrue) return -1;
    for (int lay = 0; lay < 4; lay++) {
        const char *layout = lay == 0 ? "stratified" : lay == 1 ? "random" : "caustic";
        size_t n = lay < 2 ? (size_t)side * (size_t)side : ncaus[lay - 2];
        double acc[2][NK][NM][3]; /* sum of realization means, of their squares, of rel^2 */
        memset(acc, 0, sizeof acc);
        pm_photon *ph = malloc(n * sizeof *ph);
        if (!ph) return -1;
        for (int rep = 0; rep < R; rep++) {
            for (size_t i = 0; i < n; i++) {
                double x, z;
                if (lay == 0) {
                    x = ((double)(i / (size_t)side) + bench_rng_unit(&rng)) / side;
                    z = ((double)(i % (size_t)side) + bench_rng_unit(&rng)) / side;
                } else if (lay == 1) {
                    x = bench_rng_unit(&rng), z = bench_rng_unit(&rng);
                } else {
                    x = 0.5 + ACC_SIGMA * gauss_sample(&rng), z = 0.5 + ACC_SIGMA * gauss_sample(&rng);
                }
                float pos[3] = {(float)x, 0.0f, (float)z}, pw = (float)(1.0 / (double)n);
                pm_photon_init(&ph[i], pos, (float[3]){pw, pw, pw}, down, up, PM_KIND_INDIRECT);
            }
            float dec[3];
            pm_rgbe_decode(ph[0].power, dec);
            const double ptot = (double)n * dec[0]; /* total decoded power (1 within RGBE rounding) */
            pm_kdtree *tree = NULL;
            pm_kdtree_config cfg = pm_kdtree_photon_config(8);
            if (pm_kdtree_build(&tree, ph, n, &cfg, NULL) != 0) return -1;
            for (int reg = 0; reg < 2; reg++) {
                for (size_t i = 0; i < per; i++) {
                    double x, z;
                    if (lay < 2) {
                        z = 0.25 + 0.5 * bench_rng_unit(&rng);
                        x = reg ? 3.0 / side * bench_rng_unit(&rng) : 0.25 + 0.5 * bench_rng_unit(&rng);
                        etrue[i] = ptot;
                    } else {
                        /* uniform over the region's disc or annulus */
                        double r0 = reg ? ACC_SIGMA : 0, r1 = reg ? 1.5 * ACC_SIGMA : 0.5 * ACC_SIGMA;
                        double d = sqrt(r0 * r0 + (r1 * r1 - r0 * r0) * bench_rng_unit(&rng));
                        double a = 2 * 3.14159265358979323846 * bench_rng_unit(&rng);
                        x = 0.5 + d * cos(a), z = 0.5 + d * sin(a);
                        etrue[i] = ptot * exp(-d * d / (2 * ACC_SIGMA * ACC_SIGMA)) /
                                   (2 * 3.14159265358979323846 * ACC_SIGMA * ACC_SIGMA);
                    }
                    pts[3 * i] = (float)x, pts[3 * i + 1] = 0.0f, pts[3 * i + 2] = (float)z;
                }
                for (size_t ki = 0; ki < NK; ki++)
                    for (size_t mi = 0; mi < NM; mi++) {
                        const acc_method *m = &ACC_METHODS[mi];
                        pm_estimate_options o;
                        pm_estimate_options_init(&o, m->kind, ACC_KS[ki]);
                        o.bias = m->bias;
                        o.hull_boundary = m->boundary;
                        double sum = 0, sum2 = 0;
                        for (size_t i = 0; i < per; i++) {
                            pm_estimate_result res;
                            if (pm_estimate(tree, &pts[3 * i], up, &o, scratch, &res, NULL) != 0) return -1;
                            double rel = res.rgb[0] / etrue[i] - 1.0;
                            sum += rel, sum2 += rel * rel;
                        }
                        double mean = sum / (double)per;
                        acc[reg][ki][mi][0] += mean;
                        acc[reg][ki][mi][1] += mean * mean;
                        acc[reg][ki][mi][2] += sum2;
                    }
            }
            pm_kdtree_free(tree);
        }
        for (int reg = 0; reg < 2; reg++) {
            const char *region = lay < 2 ? (reg ? "edge" : "interior") : (reg ? "flank" : "centre");
            for (size_t ki = 0; ki < NK; ki++)
                for (size_t mi = 0; mi < NM; mi++) {
                    const double *a = acc[reg][ki][mi];
                    double mean = a[0] / R, var = (a[1] - R * mean * mean) / (R - 1);
                    fprintf(csv, "%s,%s,%zu,%s,%s,%u,%zu,%.6f,%.6f,%.6f\n", layout, region, n,
                            ACC_METHODS[mi].name, ACC_METHODS[mi].variant, ACC_KS[ki], per * (size_t)R,
                            mean, sqrt(fmax(var, 0) / R), sqrt(a[2] / (double)(per * (size_t)R)));
                }
        }
        fflush(csv);
        bench_log("accuracy: %s, %zu photons, %d maps done", layout, n, R);
        free(ph);
    }
    fclose(csv);
    free(scratch), free(pts), free(etrue);
    return 0;
}

int main(int argc, char **argv) {
    static const char *const P = "bench_estimate";
    const char *out = "bench/results";
    size_t n = 0, npts = 0;
    int runs = 5, quick = 0, lookup_only = 0, accuracy_only = 0;
    unsigned bucket = 1;
    uint64_t seed = 1;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            usage(stdout);
            return 0;
        } else if (!strcmp(a, "--lookup-only")) {
            lookup_only = 1;
        } else if (!strcmp(a, "--accuracy-only")) {
            accuracy_only = 1;
        } else if (!strcmp(a, "--quick")) {
            quick = 1;
        } else if (!strcmp(a, "--full")) {
            quick = 0;
        } else if (v && !strcmp(a, "--out")) {
            out = v, i++;
        } else if (v && !strcmp(a, "--n")) {
            if (bench_parse_count(P, a, v, 1000, 1e8, &n) < 0) return 2;
            i++;
        } else if (v && !strcmp(a, "--points")) {
            if (bench_parse_count(P, a, v, 1, 1e7, &npts) < 0) return 2;
            i++;
        } else if (v && !strcmp(a, "--runs")) {
            if (bench_parse_int(P, a, v, 3, 1000, &runs) < 0) return 2;
            i++;
        } else if (v && !strcmp(a, "--bucket")) {
            int b;
            if (bench_parse_int(P, a, v, 1, 1 << 20, &b) < 0) return 2;
            bucket = (unsigned)b;
            i++;
        } else if (v && !strcmp(a, "--seed")) {
            if (bench_parse_u64(P, a, v, &seed) < 0) return 2;
            i++;
        } else {
            fprintf(stderr, "bench_estimate: unknown or incomplete option '%s'\n", a);
            usage(stderr);
            return 2;
        }
    }
    if (!n) n = quick ? 20000 : 200000;
    if (!npts) npts = quick ? 300 : 3000;
    if (!accuracy_only && lookup_race(out, n, quick ? 20000 : 100000, runs, seed) < 0) {
        fprintf(stderr, "bench_estimate: irradiance lookup race failed\n");
        return 1;
    }
    if (lookup_only) return 0;
    if (accuracy(out, quick, seed) < 0) {
        fprintf(stderr, "bench_estimate: accuracy run failed\n");
        return 1;
    }
    if (accuracy_only) return 0;

    /* The lit square: equal powers summing to 1, arriving straight down. */
    pm_photon *ph = malloc(n * sizeof *ph);
    if (!ph) {
        fprintf(stderr, "bench_estimate: out of memory for %zu photons\n", n);
        return 1;
    }
    bench_rng rng;
    bench_rng_seed(&rng, seed);
    const float up[3] = {0, 1, 0}, down[3] = {0, -1, 0};
    for (size_t i = 0; i < n; i++) {
        float pos[3] = {(float)bench_rng_unit(&rng), 0.0f, (float)bench_rng_unit(&rng)};
        float pw[3] = {(float)(1.0 / (double)n), (float)(1.0 / (double)n), (float)(1.0 / (double)n)};
        pm_photon_init(&ph[i], pos, pw, down, up, PM_KIND_INDIRECT);
    }
    float dec[3];
    pm_rgbe_decode(ph[0].power, dec);
    const double e_true = (double)n * dec[0]; /* per unit area; the square has area 1 */

    pm_kdtree *tree = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(bucket);
    int rc = pm_kdtree_build(&tree, ph, n, &cfg, NULL);
    if (rc != 0) {
        fprintf(stderr, "bench_estimate: kd-tree build: %s\n", pm_strerror(rc));
        return 1;
    }

    /* Points: interior, and within 3 mean photon spacings of the edge x = 0. */
    const double spacing = 1.0 / sqrt((double)n);
    float *pts[2];
    const char *regions[2] = {"interior", "edge"};
    for (int r = 0; r < 2; r++) {
        pts[r] = malloc(npts * 3 * sizeof(float));
        if (!pts[r]) {
            fprintf(stderr, "bench_estimate: out of memory for %zu points\n", npts);
            return 1;
        }
        for (size_t i = 0; i < npts; i++) {
            double u = bench_rng_unit(&rng), w = 0.25 + 0.5 * bench_rng_unit(&rng);
            pts[r][3 * i + 0] = (float)(r == 0 ? 0.25 + 0.5 * u : 3.0 * spacing * u);
            pts[r][3 * i + 1] = 0.0f;
            pts[r][3 * i + 2] = (float)w;
        }
    }

    FILE *csv = bench_csv_open(out, "estimate.csv",
                               "region,estimator,bias,k,estimates,ns_per_estimate,rms_rel_error,"
                               "mean_rel_error,setup_s");
    bench_log("bench_estimate: n=%zu photons, %zu points per region, B=%u, E=%g", n, npts,
              bucket, e_true);
    double *t = malloc((size_t)runs * sizeof *t);
    if (!t) {
        fprintf(stderr, "bench_estimate: out of memory\n");
        return 1;
    }
    for (size_t ki = 0; ki < NELEM(KS); ki++) {
        const unsigned k = KS[ki];
        void *scratch = malloc(pm_estimate_scratch_bytes(k));
        if (!scratch) {
            fprintf(stderr, "bench_estimate: out of memory\n");
            return 1;
        }
        for (size_t mi = 0; mi < NELEM(METHODS); mi++) {
            const method *m = &METHODS[mi];
            pm_estimate_options o;
            pm_irradiance *irr = NULL;
            double setup = 0;
            pm_estimate_options_init(&o, m->kind, k);
            o.bias = m->bias_code;
            if (m->precomputed) {
                pm_irradiance_options io;
                pm_irradiance_options_init(&io, k);
                io.fraction = PM_PRECOMP_QUARTER;
                io.bias = m->bias_code;
                io.store_radius = 1;
                double t0 = bench_now();
                rc = pm_irradiance_build(&irr, tree, &io);
                setup = bench_now() - t0;
                if (rc != 0) {
                    fprintf(stderr, "bench_estimate: precompute: %s\n", pm_strerror(rc));
                    return 1;
                }
            }
            for (int r = 0; r < 2; r++) {
                double sum2 = 0, sum = 0;
                /* untimed pass: the errors */
                for (size_t i = 0; i < npts; i++) {
                    const float *x = &pts[r][3 * i];
                    double e;
                    if (irr) {
                        float rgb[3];
                        rc = pm_irradiance_lookup(irr, x, up, INFINITY, 0.9f, rgb, NULL);
                        e = rgb[0];
                    } else {
                        pm_estimate_result res;
                        rc = pm_estimate(tree, x, up, &o, scratch, &res, NULL);
                        e = res.rgb[0];
                    }
                    if (rc < 0) {
                        fprintf(stderr, "bench_estimate: %s: %s\n", m->name, pm_strerror(rc));
                        return 1;
                    }
                    double rel = e / e_true - 1.0;
                    sum += rel;
                    sum2 += rel * rel;
                }
                /* timed runs */
                for (int run = 0; run < runs; run++) {
                    double acc = 0, t0 = bench_now();
                    for (size_t i = 0; i < npts; i++) {
                        const float *x = &pts[r][3 * i];
                        if (irr) {
                            float rgb[3];
                            pm_irradiance_lookup(irr, x, up, INFINITY, 0.9f, rgb, NULL);
                            acc += rgb[0];
                        } else {
                            pm_estimate_result res;
                            pm_estimate(tree, x, up, &o, scratch, &res, NULL);
                            acc += res.rgb[0];
                        }
                    }
                    t[run] = (bench_now() - t0) / (double)npts;
                    g_sink += acc;
                }
                fprintf(csv, "%s,%s,%s,%u,%zu,%.1f,%.6f,%.6f,%.4f\n", regions[r], m->name, m->bias,
                        k, npts, 1e9 * bench_median(t, runs), sqrt(sum2 / (double)npts),
                        sum / (double)npts, setup);
            }
            fflush(csv);
            pm_irradiance_free(irr);
        }
        bench_log("k=%u done", k);
        free(scratch);
    }
    fclose(csv);
    free(t);
    free(pts[0]);
    free(pts[1]);
    pm_kdtree_free(tree);
    free(ph);
    bench_log("done");
    return 0;
}
