/* test_irradiance.c: precomputed irradiance and combined photon maps (photonmap/irradiance.h).
 *
 * Scenes are jittered grids of photons on the unit square z = 0 (normal +z, photons travelling
 * down), as in test_estimate.c, built into a kd-tree. Oracles: the full disc estimate at the
 * same point (precomputed lookups), the estimate recomputed at each precomputed photon (stored
 * values), pm_kdtree_height (which photons are precomputed), the analytic irradiance and a
 * single map of all photons (combined maps).
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "photonmap.h"
#include "estimate.h"
#include "irradiance.h"

typedef struct { uint64_t s; } rng_t;
static uint64_t rng_u64(rng_t *r) {
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
static double rng_unit(rng_t *r) { return (double)(rng_u64(r) >> 11) * 0x1p-53; }

static const float DOWN[3] = {0, 0, -1}, UP[3] = {0, 0, 1};
static const double PI = 3.14159265358979323846;

/* The smooth field of the precomputation tests: relative power 1 + 0.5 sin(2 pi x) sin(2 pi y). */
static double field(double x, double y) { return 1.0 + 0.5 * sin(2 * PI * x) * sin(2 * PI * y); }

/* side x side jittered photons in [x0, x0 + w) x [0, 1) on z = 0, base power p (times field()
 * if smooth). Appends to ph at offset *n. */
static void add_grid(pm_photon *ph, size_t *n, int side, double x0, double w, float p, int smooth,
                     uint64_t seed) {
    rng_t r = {seed};
    for (int i = 0; i < side; i++)
        for (int j = 0; j < side; j++) {
            double x = x0 + w * (i + rng_unit(&r)) / side, y = (j + rng_unit(&r)) / side;
            float pos[3] = {(float)x, (float)y, 0};
            float q = smooth ? (float)(p * field(x, y)) : p;
            pm_photon_set(&ph[(*n)++], pos, (float[3]){q, q, q}, DOWN, UP, PM_KIND_DIRECT);
        }
}

typedef struct stats { double sum, sum2, n; } stats;
static void st_add(stats *s, double v) { s->sum += v, s->sum2 += v * v, s->n += 1; }
static double st_mean(const stats *s) { return s->sum / s->n; }
static double st_var(const stats *s) {
    double m = st_mean(s);
    return fmax((s->sum2 - s->n * m * m) / (s->n - 1), 0.0);
}

/* Oracle: pm_kdtree_height decides the quarter; each stored value equals the full disc
 * estimate (same options) recomputed at that photon with its decoded normal, within the RGBE
 * precision (2^-8 relative); the parallel build equals the one-thread build bit for bit; the
 * memory report is 4 bytes of RGBE + 1 bit per photon (+4 with radii). */
TEST(irradiance_precompute_values_and_selection) {
    const int side = PM_TEST_SANITIZED ? 60 : 120;
    size_t n = 0;
    pm_photon *ph = malloc(sizeof *ph * side * side);
    add_grid(ph, &n, side, 0, 1, 0x1p-12f, 1, 1);
    pm_kdtree *tree = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(1);
    ASSERT_EQ_INT(pm_kdtree_build(&tree, ph, n, &cfg, NULL), PM_OK);
    for (int fr = 0; fr < 2; fr++) {
        pm_irradiance_options io;
        pm_irradiance *irr = NULL, *irr1 = NULL;
        pm_irradiance_options_init(&io, 50);
        io.fraction = fr ? PM_PRECOMP_QUARTER : PM_PRECOMP_ALL;
        io.threads = 2;
        ASSERT_EQ_INT(pm_irradiance_build(&irr, tree, &io), PM_OK);
        io.threads = 1;
        ASSERT_EQ_INT(pm_irradiance_build(&irr1, tree, &io), PM_OK);
        size_t want = 0;
        for (uint32_t i = 0; i < n; i++) {
            int sel = !fr || pm_kdtree_height(tree, i) >= 2;
            float a[3], b[3];
            want += (size_t)sel;
            EXPECT_EQ_INT(pm_irradiance_value(irr, i, a), sel);
            pm_irradiance_value(irr1, i, b);
            EXPECT(memcmp(a, b, sizeof a) == 0);
        }
        EXPECT_EQ_INT(pm_irradiance_count(irr), want);
        if (fr) EXPECT_MSG(want >= n / 5 && want <= n / 3, "quarter selected %zu of %zu", want, n);
        EXPECT_NEAR(pm_irradiance_bytes_per_photon(irr), 4.125, 1e-12);
        EXPECT(pm_irradiance_bytes(irr) >= n * 4 + n / 8 && pm_irradiance_bytes(irr) <= n * 4 + n / 8 + 4096);
        /* stored value vs the estimate recomputed at the photon */
        pm_estimate_options eo;
        pm_estimate_options_init(&eo, PM_EST_DISC, 50);
        eo.reject_behind = 1;
        void *scratch = malloc(pm_estimate_scratch_bytes(50));
        const pm_photon *tp = pm_kdtree_records(tree);
        for (uint32_t i = 0; i < n; i += 37) {
            float v[3], nrm[3];
            if (!pm_irradiance_value(irr, i, v)) continue;
            pm_estimate_result r;
            pm_normal_decode(tp[i].normal, nrm);
            ASSERT_EQ_INT(pm_estimate(tree, tp[i].pos, nrm, &eo, scratch, &r, NULL), PM_OK);
            EXPECT_REL(v[0], r.rgb[0], 1.0 / 128);
        }
        free(scratch);
        pm_irradiance_free(irr);
        pm_irradiance_free(irr1);
    }
    /* radiance for a diffuse reflectance: rho/pi times the irradiance, per channel, within
     * two RGBE roundings (2 * 2^-8) */
    pm_irradiance_options io;
    pm_irradiance *irr = NULL, *rad = NULL;
    const float rho[3] = {0.8f, 0.5f, 0.2f};
    pm_irradiance_options_init(&io, 20);
    io.store_radius = 1;
    ASSERT_EQ_INT(pm_irradiance_build(&irr, tree, &io), PM_OK);
    EXPECT_NEAR(pm_irradiance_bytes_per_photon(irr), 8.125, 1e-12);
    io.diffuse = rho;
    ASSERT_EQ_INT(pm_irradiance_build(&rad, tree, &io), PM_OK);
    for (uint32_t i = 0; i < n; i += 101) {
        float e[3], l[3];
        ASSERT_EQ_INT(pm_irradiance_value(irr, i, e), 1);
        ASSERT_EQ_INT(pm_irradiance_value(rad, i, l), 1);
        for (int c = 0; c < 3; c++) EXPECT_REL(l[c], rho[c] / PI * e[c], 2.0 / 256 / rho[c] * rho[0]);
    }
    pm_irradiance_free(rad);
    pm_irradiance_free(irr);
    pm_kdtree_free(tree);
    free(ph);
}

/* Oracle: the full disc estimate (k = 50, bias-corrected, behind-rejection) at the lookup
 * point, and the analytic field 1 + 0.5 sin sin. The lookup returns the estimate at the
 * nearest precomputed photon instead, which differs from the full estimate by the field's
 * change over that distance (about h/2 for all photons, h for a quarter; |grad E|/E <= 2 pi)
 * and by the noise of a different photon set (a k = 50 estimate has about 4% noise here, and
 * the two sets overlap only in part) and the RGBE rounding (< 0.4%). Tolerances: the mean
 * relative difference within 0.5%; the RMS difference below 6.5% (all) and 8% (quarter); and
 * the lookup's RMS error against the analytic field at most 1.1 (all) or 1.2 (quarter) times
 * that of the full estimate. */
TEST(irradiance_lookup_matches_full_estimate) {
    const int side = 200;
    const unsigned lookups = PM_TEST_SANITIZED ? 500 : 3000;
    size_t n = 0;
    pm_photon *ph = malloc(sizeof *ph * side * side);
    add_grid(ph, &n, side, 0, 1, 0x1p-14f, 1, 2);
    const double truth0 = (double)side * side * 0x1p-14; /* E = N P field(x, y) */
    pm_kdtree *tree = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(1);
    ASSERT_EQ_INT(pm_kdtree_build(&tree, ph, n, &cfg, NULL), PM_OK);
    pm_estimate_options eo;
    pm_estimate_options_init(&eo, PM_EST_DISC, 50);
    eo.reject_behind = 1;
    void *scratch = malloc(pm_estimate_scratch_bytes(50));
    for (int fr = 0; fr < 2; fr++) {
        pm_irradiance_options io;
        pm_irradiance *irr = NULL;
        pm_irradiance_options_init(&io, 50);
        io.fraction = fr ? PM_PRECOMP_QUARTER : PM_PRECOMP_ALL;
        ASSERT_EQ_INT(pm_irradiance_build(&irr, tree, &io), PM_OK);
        rng_t r = {20 + (uint64_t)fr};
        stats d = {0, 0, 0}, el = {0, 0, 0}, ef = {0, 0, 0};
        for (unsigned l = 0; l < lookups; l++) {
            float q[3] = {(float)(0.1 + 0.8 * rng_unit(&r)), (float)(0.1 + 0.8 * rng_unit(&r)), 0}, v[3];
            pm_estimate_result full;
            ASSERT_EQ_INT(pm_irradiance_lookup(irr, q, UP, INFINITY, 0.9f, v, NULL), 1);
            ASSERT_EQ_INT(pm_estimate(tree, q, UP, &eo, scratch, &full, NULL), PM_OK);
            double truth = truth0 * field(q[0], q[1]);
            st_add(&d, v[0] / full.rgb[0] - 1);
            st_add(&el, v[0] / truth - 1);
            st_add(&ef, full.rgb[0] / truth - 1);
        }
        double rms = sqrt(st_var(&d) + st_mean(&d) * st_mean(&d));
        double rms_l = sqrt(st_var(&el) + st_mean(&el) * st_mean(&el));
        double rms_f = sqrt(st_var(&ef) + st_mean(&ef) * st_mean(&ef));
        printf("precomputed (%s, %zu photons): mean diff %+.3f%%, rms diff %.3f%%; rms error vs field: lookup %.3f%%, full %.3f%%; %.3f bytes/photon\n",
               fr ? "quarter" : "all", pm_irradiance_count(irr), 100 * st_mean(&d), 100 * rms,
               100 * rms_l, 100 * rms_f, pm_irradiance_bytes_per_photon(irr));
        EXPECT_MSG(fabs(st_mean(&d)) <= 0.005, "mean diff %+.3f%%", 100 * st_mean(&d));
        EXPECT_MSG(rms <= (fr ? 0.08 : 0.065), "rms diff %.3f%%", 100 * rms);
        EXPECT_MSG(rms_l <= (fr ? 1.2 : 1.1) * rms_f, "rms error %.3f%% vs full %.3f%%", 100 * rms_l, 100 * rms_f);
        pm_irradiance_free(irr);
    }
    free(scratch);
    pm_kdtree_free(tree);
    free(ph);
}

/* Oracle: the scene's geometry. A floor (z = 0, x in [0.1, 1], normal +z, power P) and a wall
 * (x = 0, normal +x, power 100 P, photons travelling -x). At a point near both, closer to the
 * wall, a lookup with normal +z must return a floor photon's value (below 2 E_floor; the wall's
 * is about 100 E_floor), and with the normal test off (cos_min = -1) the wall's (above 30
 * E_floor). Outside max_dist2, or beyond a photon's stored radius, the answer is black and 0;
 * values found on the floor are within 30% of E_floor (a k = 30 estimate). */
TEST(irradiance_lookup_normal_and_cutoff) {
    enum { S = 60 };
    pm_photon *ph = malloc(sizeof *ph * 2 * S * S);
    rng_t r = {5};
    size_t n = 0;
    const float P = 0x1p-12f;
    add_grid(ph, &n, S, 0.1, 0.9, P, 0, 3);
    const float west[3] = {-1, 0, 0}, east[3] = {1, 0, 0};
    for (int i = 0; i < S * S; i++) {
        float pos[3] = {0, (float)((i / S + rng_unit(&r)) / S), (float)((i % S + rng_unit(&r)) / S)};
        pm_photon_set(&ph[n++], pos, (float[3]){100 * P, 100 * P, 100 * P}, west, east, PM_KIND_DIRECT);
    }
    const double e_floor = S * S * (double)P / 0.9;
    pm_kdtree *tree = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(1);
    ASSERT_EQ_INT(pm_kdtree_build(&tree, ph, n, &cfg, NULL), PM_OK);
    pm_irradiance_options io;
    pm_irradiance *irr = NULL;
    pm_irradiance_options_init(&io, 30);
    ASSERT_EQ_INT(pm_irradiance_build(&irr, tree, &io), PM_OK);
    float v[3];
    const float q[3] = {0.05f, 0.5f, 0.04f};
    ASSERT_EQ_INT(pm_irradiance_lookup(irr, q, UP, INFINITY, 0.9f, v, NULL), 1);
    EXPECT_MSG(v[0] < 2 * e_floor && v[0] > 0.3 * e_floor, "floor lookup %g (E_floor %g)", v[0], e_floor);
    ASSERT_EQ_INT(pm_irradiance_lookup(irr, q, UP, INFINITY, -1.0f, v, NULL), 1);
    EXPECT_MSG(v[0] > 30 * e_floor, "any-normal lookup %g", v[0]);
    /* cut-off distance */
    const float far[3] = {5, 5, 5};
    EXPECT_EQ_INT(pm_irradiance_lookup(irr, far, UP, 0.01f, 0.9f, v, NULL), 0);
    EXPECT(v[0] == 0 && v[1] == 0 && v[2] == 0);
    /* unlimited search: the nearest floor photon, 0.5 below */
    const float above[3] = {0.5f, 0.5f, 0.5f};
    EXPECT_EQ_INT(pm_irradiance_lookup(irr, above, UP, INFINITY, 0.9f, v, NULL), 1);
    EXPECT_REL(v[0], e_floor, 0.3);
    EXPECT_EQ_INT(pm_irradiance_lookup(irr, above, (float[3]){NAN, 0, 0}, INFINITY, 0.9f, v, NULL), PM_ENONFINITE);
    pm_irradiance_free(irr);
    /* with stored radii (about 0.05 here) the same lookup is black, and one on the floor not */
    io.store_radius = 1;
    ASSERT_EQ_INT(pm_irradiance_build(&irr, tree, &io), PM_OK);
    EXPECT_EQ_INT(pm_irradiance_lookup(irr, above, UP, INFINITY, 0.9f, v, NULL), 0);
    EXPECT(v[0] == 0);
    const float on[3] = {0.5f, 0.5f, 0};
    EXPECT_EQ_INT(pm_irradiance_lookup(irr, on, UP, INFINITY, 0.9f, v, NULL), 1);
    EXPECT_REL(v[0], e_floor, 0.3);
    pm_irradiance_free(irr);
    pm_kdtree_free(tree);
    free(ph);
}

/* Combined maps. M = 4 independent jittered 100 x 100 grids, each photon with the power of a
 * photon of their union (which is one map of 40,000). Oracles:
 *  (a) the single map of all photons with k = 100: the combined estimate (25 per map) agrees
 *      with it: both means within 0.5% of the analytic irradiance (the bound of the square
 *      test) and their mean paired difference below 0.3% (their small biases differ; measured
 *      about 0.1%);
 *  (b) over the same lookups with k = 16 (4 per map), the naive sum of per-map estimates has a
 *      variance at least 1.3 times that of the combined formula (Poisson theory: 1/(k-2M) vs
 *      1/(k-2), i.e. 1.75 times; measured about 1.5). The combined mean stays within 1% of the
 *      truth; the naive one is biased high (4-photon ratios; measured about +7%). */
TEST(irradiance_combined_maps) {
    enum { M = 4, S = 100 };
    const unsigned lookups = PM_TEST_SANITIZED ? 1000 : 4000;
    const float P = 0x1p-15f;
    pm_photon *maps[M], *all = malloc(sizeof *all * M * S * S);
    pm_kdtree *trees[M], *one = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(1);
    size_t na = 0;
    for (int m = 0; m < M; m++) {
        size_t n = 0;
        maps[m] = malloc(sizeof(pm_photon) * S * S);
        add_grid(maps[m], &n, S, 0, 1, P, 0, 100 + (uint64_t)m);
        memcpy(all + na, maps[m], n * sizeof *all);
        na += n;
        ASSERT_EQ_INT(pm_kdtree_build(&trees[m], maps[m], n, &cfg, NULL), PM_OK);
    }
    ASSERT_EQ_INT(pm_kdtree_build(&one, all, na, &cfg, NULL), PM_OK);
    float dec[3];
    pm_rgbe_decode(all[0].power, dec);
    const double truth = (double)na * dec[0];
    void *scratch = malloc(pm_estimate_scratch_bytes(100));
    rng_t r = {77};
    stats diff = {0, 0, 0}, comb = {0, 0, 0}, single = {0, 0, 0}, c16 = {0, 0, 0}, n16 = {0, 0, 0};
    for (unsigned l = 0; l < lookups; l++) {
        float q[3] = {(float)(0.1 + 0.8 * rng_unit(&r)), (float)(0.1 + 0.8 * rng_unit(&r)), 0};
        pm_estimate_options o;
        pm_estimate_result res;
        double c[3], nv[3];
        pm_estimate_options_init(&o, PM_EST_DISC, 100);
        ASSERT_EQ_INT(pm_estimate((const pm_kdtree *)one, q, UP, &o, scratch, &res, NULL), PM_OK);
        ASSERT_EQ_INT(pm_estimate_combined((const pm_kdtree *const *)trees, M, q, UP, &o, scratch, c, nv, NULL), PM_OK);
        st_add(&diff, (c[0] - res.rgb[0]) / truth);
        st_add(&comb, c[0] / truth - 1);
        st_add(&single, res.rgb[0] / truth - 1);
        o.k = 16;
        ASSERT_EQ_INT(pm_estimate_combined((const pm_kdtree *const *)trees, M, q, UP, &o, scratch, c, nv, NULL), PM_OK);
        st_add(&c16, c[0] / truth - 1);
        st_add(&n16, nv[0] / truth - 1);
    }
    double se = sqrt(st_var(&diff) / diff.n);
    printf("combined k=100: mean %+.3f%%, single map %+.3f%%, paired diff %+.3f%% (se %.3f%%)\n",
           100 * st_mean(&comb), 100 * st_mean(&single), 100 * st_mean(&diff), 100 * se);
    printf("k=16, M=4: combined mean %+.2f%% var %.5f, naive mean %+.2f%% var %.5f (ratio %.2f)\n",
           100 * st_mean(&c16), st_var(&c16), 100 * st_mean(&n16), st_var(&n16), st_var(&n16) / st_var(&c16));
    EXPECT_MSG(fabs(st_mean(&diff)) <= 0.003, "combined vs single: %+.3f%% (se %.3f%%)", 100 * st_mean(&diff), 100 * se);
    EXPECT_MSG(fabs(st_mean(&comb)) <= 0.005, "combined mean %+.3f%%", 100 * st_mean(&comb));
    EXPECT_MSG(fabs(st_mean(&single)) <= 0.005, "single mean %+.3f%%", 100 * st_mean(&single));
    EXPECT_MSG(st_var(&n16) >= 1.3 * st_var(&c16), "variance naive %.5f vs combined %.5f", st_var(&n16), st_var(&c16));
    EXPECT_MSG(fabs(st_mean(&c16)) <= 0.01, "combined k=16 mean %+.2f%%", 100 * st_mean(&c16));
    EXPECT_MSG(st_mean(&n16) > st_mean(&c16), "naive k=16 mean %+.2f%%", 100 * st_mean(&n16));
    for (int m = 0; m < M; m++) pm_kdtree_free(trees[m]), free(maps[m]);
    pm_kdtree_free(one);
    free(all), free(scratch);
}

/* Oracle: the guarantee (finite, non-negative) and exact values on hand-made lists: no
 * photons anywhere gives 0; maps with photons at x give the floor-limited finite spike; a map
 * that ran dry inside max_dist2 counts with r^2 = max_dist2; powers 1e-30..1e30 stay finite. */
TEST(irradiance_combine_degenerate) {
    pm_photon ph[4];
    pm_neighbor nb[4];
    const float x[3] = {0, 0, 0};
    pm_combine_acc acc;
    double c[3], nv[3];
    pm_combine_init(&acc);
    for (int m = 0; m < 3; m++) EXPECT_EQ_INT(pm_combine_add(&acc, ph, nb, 0, 4, INFINITY, PM_BIAS_AREA, x), PM_OK);
    pm_combine_finish(&acc, c, nv);
    EXPECT(c[0] == 0 && nv[0] == 0);
    for (int i = 0; i < 4; i++) {
        float p = i == 0 ? 1e-30f : i == 1 ? 1e30f : 1.0f;
        pm_photon_set(&ph[i], x, (float[3]){p, p, p}, DOWN, UP, 0);
        nb[i].index = (uint32_t)i, nb[i].dist2 = 0;
    }
    pm_combine_init(&acc);
    EXPECT_EQ_INT(pm_combine_add(&acc, ph, nb, 4, 4, INFINITY, PM_BIAS_AREA, x), PM_OK);
    EXPECT_EQ_INT(pm_combine_add(&acc, ph, nb, 2, 4, 0.5f, PM_BIAS_HALF_FARTHEST, x), PM_OK);
    pm_combine_finish(&acc, c, nv);
    for (int i = 0; i < 3; i++) EXPECT(isfinite(c[i]) && c[i] > 0 && isfinite(nv[i]) && nv[i] > 0);
    /* exact: one map of 2 unit photons that ran dry within r^2 = 0.5, one empty dry map:
     * E = (2/pi) * 2 / (0.5 + 0.5); naive = 2/(pi 0.5) + 0. */
    for (int i = 0; i < 2; i++) {
        pm_photon_set(&ph[i], (float[3]){0.1f * (i + 1), 0, 0}, (float[3]){1, 1, 1}, DOWN, UP, 0);
        nb[i].index = (uint32_t)i, nb[i].dist2 = 0.01f * (i + 1) * (i + 1);
    }
    pm_combine_init(&acc);
    pm_combine_add(&acc, ph, nb, 2, 4, 0.5f, PM_BIAS_AREA, x);
    pm_combine_add(&acc, ph, nb, 0, 4, 0.5f, PM_BIAS_AREA, x);
    pm_combine_finish(&acc, c, nv);
    EXPECT_REL(c[0], 2 / PI * 2 / 1.0, 1e-6);
    EXPECT_REL(nv[0], 2 / (PI * 0.5), 1e-6);
}
