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
 * OUTPUT: estimate.csv in the output directory (columns in bench/README.md). --help for options.
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
            "  --out DIR    output directory (default bench/results; must exist)\n"
            "  --n N        photons (default 200000)\n"
            "  --points P   estimate points per region (default 3000)\n"
            "  --runs R     timed runs, median reported (default 5, >= 3)\n"
            "  --bucket B   kd-tree bucket size (default 1, the classic tree that precomputed\n"
            "               irradiance's quarter selection is defined on)\n"
            "  --seed S     random seed (default 1)\n");
}

int main(int argc, char **argv) {
    static const char *const P = "bench_estimate";
    const char *out = "bench/results";
    size_t n = 0, npts = 0;
    int runs = 5, quick = 0;
    unsigned bucket = 1;
    uint64_t seed = 1;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--help") || !strcmp(a, "-h")) {
            usage(stdout);
            return 0;
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
        pm_photon_set(&ph[i], pos, pw, down, up, PM_KIND_INDIRECT);
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
