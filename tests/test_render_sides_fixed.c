/* test_render_sides_fixed.c: precomputed irradiance where the cap binds (photon_sides.h,
 * "Fixed-radius estimates").
 *
 * Oracle, analytic: photons of equal power P, uniform over a square of area A on a plane
 * (indirect records, each its own path), have irradiance n P / A everywhere inside it. Where
 * an estimate's cap holds fewer than k photons the whole disc is searched, and the estimate is
 * a fixed-radius one: its mean over many estimates must be n P / A. Two rules used to move it:
 * counting the estimate's own photon (the disc is centred on it), +1/mu where mu photons are
 * expected in the disc, and reading it only when enough paths came near, which keeps the high
 * ones. With mu = 5 the old rules read +82.5%; the tolerance is 3% (the mean over 64 maps has a
 * standard error near 0.5%: an estimate of 5 photons has a relative standard deviation of 45%,
 * and each map gives about 150, overlapping). Measured: +1.53% at this seed, +0.68%, +1.12%
 * and +0.91% at three others; the points are the kd-tree's upper nodes (medians of their
 * cells), not photons drawn at random, which may be the small rest. Every such estimate must
 * be readable (radius^2 > 0).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "../render/photons/photon_maps.h"
#include "../render/photon_mapping/photon_sides.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"

static const char *FLOOR_SCENE =
    "{\"camera\": {\"eye\": [0, 0, 10], \"look_at\": [0, 0, 0], \"up\": [0, 1, 0], \"fov_deg\": 40,"
    " \"width\": 8, \"height\": 8},"
    " \"materials\": {\"white\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
    " \"objects\": ["
    "  {\"type\": \"quad\", \"vertices\": [[-5, -5, 0], [5, -5, 0], [5, 5, 0], [-5, 5, 0]], \"material\": \"white\"}]}";

enum { FX_N = 4096, FX_K = 50 };
#define FX_HALF 4.0 /* photons over [-4, 4]^2 */
#define FX_MU 5.0   /* photons expected in a disc of the cap */
#define FX_INNER 3.0 /* estimates read at photons within [-3, 3]^2: their discs lie inside */

/* FX_N indirect photons of power 1, uniform over the square, travelling down onto the floor. */
static pm_photon *fx_map(pm_test_rng *r) {
    pm_photon *ph = calloc(FX_N, sizeof *ph);
    for (size_t i = 0; ph && i < FX_N; i++) {
        float pos[3] = {(float)(FX_HALF * (2 * pm_test_unit(r) - 1)), (float)(FX_HALF * (2 * pm_test_unit(r) - 1)), 0};
        float pw[3] = {1, 1, 1}, nrm[3] = {0, 0, 1};
        float dir[3] = {(float)(pm_test_unit(r) - 0.5), (float)(pm_test_unit(r) - 0.5), -1};
        pm_photon_init(&ph[i], pos, pw, dir, nrm, PM_KIND_INDIRECT);
    }
    return ph;
}

TEST(render_sides_fixed_radius_estimate_unbiased) {
    const int maps = PM_TEST_SANITIZED ? 16 : 64;
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, FLOOR_SCENE, &e) == 0, "%s", e.msg);
    const double area = 4 * FX_HALF * FX_HALF, lambda = FX_N / area, truth = lambda; /* power 1 */
    const float r2 = (float)(FX_MU / (M_PI * lambda));
    pm_test_rng r = {4242};
    double sum = 0;
    size_t count = 0, unreadable = 0, limited = 0;
    for (int mi = 0; mi < maps; mi++) {
        pm_photon *ph = fx_map(&r);
        ASSERT(ph);
        pm_kdtree *t = NULL;
        char err[256];
        int rc = photon_tree_build(&t, ph, FX_N, 8, err, sizeof err);
        ASSERT_MSG(rc == 0, "%s", err);
        side_cache c;
        /* no paths: every photon its own path, as the rule reads a map without them */
        rc = side_cache_build(&c, &s, t, pm_kdtree_records(t), NULL, FX_N, FX_K, r2, err, sizeof err);
        ASSERT_MSG(rc == 0, "%s", err);
        const pm_photon *rec = pm_kdtree_records(t);
        for (size_t i = 0; i < FX_N; i++) {
            if (pm_kdtree_height(t, (uint32_t)i) < SIDE_HEIGHT_QUARTER) continue; /* not precomputed */
            if (fabsf(rec[i].pos[0]) > FX_INNER || fabsf(rec[i].pos[1]) > FX_INNER) continue;
            limited += c.r2v[i] == r2;
            if (!(c.r2v[i] > 0)) {
                unreadable++;
                continue;
            }
            sum += c.val[3 * i + 1];
            count++;
        }
        side_cache_free(&c);
        pm_kdtree_free(t);
        free(ph);
    }
    scene_free(&s);
    double mean = count ? sum / (double)count : 0;
    printf("    %zu estimates (%zu with the cap's radius, %zu unreadable), mean %.4g, analytic %.4g (%+.2f%%)\n",
           count + unreadable, limited, unreadable, mean, truth, 100 * (mean / truth - 1));
    EXPECT_MSG(unreadable == 0, "%zu fixed-radius estimates unreadable", unreadable);
    EXPECT_MSG(limited > 0.99 * (double)(count + unreadable), "only %zu of %zu estimates at the cap", limited,
               count + unreadable);
    EXPECT_MSG(fabs(mean / truth - 1) < 0.03, "mean %.4g against %.4g (%+.2f%%)", mean, truth,
               100 * (mean / truth - 1));
}
