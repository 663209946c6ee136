/* test_render_guide.c: the learned primary-sample guide (render/guiding/guide.h) and guided light
 * sampling in the photon mapper's direct light (direct.h).
 *
 * Oracles: the table's own definition (q' = alpha / G^2 + (1 - alpha) q: sums, the density of
 * the warped samples by histogram); an irradiance computed by quadrature over the part of a
 * lamp a point sees through a hole (the guided estimate must match it, for the learned table and
 * for a deliberately wrong one); the plan's decision on shipped scenes (on for pinhole_room,
 * off elsewhere) from the render program's own plan line.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "../photonmap/common.h"
#include "test_render_run.h"
#include "../render/integrators/direct.h"
#include "../render/image/film.h"
#include "../render/guiding/guide.h"
#include "../render/scene/port.h"
#include "../render/load/photon_settings.h"
#include "../render/base/rng.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"

#ifdef _OPENMP
#include <omp.h>
#endif

static guide_grid unit_grid(void) {
    guide_grid gr = {v3s(0), 1.0};
    return gr;
}

/* Oracle: the definition. Three cells' rows (one with values only in a few strata, one with
 * two rows that must be summed, one all zero: no table); each table's cumulative array ends at
 * 1, every stratum's probability is alpha / G^2 + (1 - alpha) v / sum v, and guide_pdf is
 * G^2 times it. */
TEST(render_guide_table_probabilities) {
    enum { G = 8, G2 = G * G };
    double a[G2] = {0}, b1[G2], b2[G2], z[G2] = {0};
    a[3] = 2;
    a[17] = 6;
    for (int k = 0; k < G2; k++) b1[k] = k % 5, b2[k] = 1.5;
    guide_grid gr = unit_grid();
    vec3 up = v3(0, 1, 0);
    guide_row rows[4] = {{guide_cell(&gr, v3(0.5, 0.5, 0.5), up), 0, a},
                         {guide_cell(&gr, v3(2.5, 0.5, 0.5), up), 1, b1},
                         {guide_cell(&gr, v3(2.5, 0.5, 0.5), up), 1, b2},
                         {guide_cell(&gr, v3(4.5, 0.5, 0.5), up), 0, z}};
    guide g;
    double alpha = 0.25;
    ASSERT_EQ_INT(guide_build(&g, &gr, G, alpha, rows, 4), 0);
    ASSERT_EQ_INT((int)g.ntables, 2);
    ASSERT_EQ_INT((int)g.ncells, 2);
    const double *ta = guide_find(&g, v3(0.2, 0.9, 0.1), up, 0);
    const double *tb = guide_find(&g, v3(2.1, 0.1, 0.9), up, 1);
    ASSERT(ta && tb);
    EXPECT(guide_find(&g, v3(0.2, 0.9, 0.1), up, 1) == NULL);           /* another slot */
    EXPECT(guide_find(&g, v3(0.2, 0.9, 0.1), v3(1, 0, 0), 0) == NULL);  /* another side */
    EXPECT(guide_find(&g, v3(4.5, 0.5, 0.5), up, 0) == NULL);           /* all zero */
    double sa = 8, sb = 0;
    for (int k = 0; k < G2; k++) sb += b1[k] + b2[k];
    EXPECT_NEAR(ta[0], 0, 0);
    EXPECT_NEAR(ta[G2], 1, 0);
    EXPECT_NEAR(tb[G2], 1, 0);
    double integral = 0;
    for (int k = 0; k < G2; k++) {
        double qa = alpha / G2 + (1 - alpha) * a[k] / sa, qb = alpha / G2 + (1 - alpha) * (b1[k] + b2[k]) / sb;
        EXPECT_NEAR(ta[k + 1] - ta[k], qa, 1e-14);
        EXPECT_NEAR(tb[k + 1] - tb[k], qb, 1e-14);
        double u1 = ((k % G) + 0.5) / G, u2 = ((k / G) + 0.5) / G;
        EXPECT_NEAR(guide_pdf(&g, ta, u1, u2), G2 * qa, 1e-12);
        integral += guide_pdf(&g, tb, u1, u2) / G2;
    }
    EXPECT_NEAR(integral, 1, 1e-12);
    guide_free(&g);
}

/* Oracle: the table. 400,000 uniform (u1, u2) warped by a table: the share of warped points
 * per stratum within 5 binomial standard errors of q'_k; within the strata, the points are
 * uniform (their mean position in their stratum within 5 standard errors, 0.289 / sqrt(n), of
 * its centre, per axis); the
 * density guide_warp returns equals guide_pdf at the warped point, exactly. */
TEST(render_guide_sampling_histogram) {
    enum { G = 16, G2 = G * G };
    double v[G2];
    rng r = rng_stream(7, 0, 0);
    for (int k = 0; k < G2; k++) v[k] = k % 7 == 0 ? 0 : rng_uniform(&r) * rng_uniform(&r) * 10;
    guide_grid gr = unit_grid();
    guide_row row = {guide_cell(&gr, v3s(0.5), v3(0, 0, 1)), 3, v};
    guide g;
    ASSERT_EQ_INT(guide_build(&g, &gr, G, 0.2, &row, 1), 0);
    const double *t = guide_find(&g, v3s(0.5), v3(0, 0, 1), 3);
    ASSERT(t);
    static long count[G2];
    static double sx[G2], sy[G2];
    memset(count, 0, sizeof count);
    memset(sx, 0, sizeof sx);
    memset(sy, 0, sizeof sy);
    const long N = 400000;
    int mismatch = 0;
    for (long n = 0; n < N; n++) {
        double u1 = rng_uniform(&r), u2 = rng_uniform(&r);
        double d = guide_warp(&g, t, &u1, &u2);
        if (!(u1 >= 0 && u1 < 1 && u2 >= 0 && u2 < 1)) {
            ASSERT_MSG(0, "warped point (%g, %g) outside the unit square", u1, u2);
        }
        int i = (int)(u1 * G), j = (int)(u2 * G), k = i + G * j;
        mismatch += d != guide_pdf(&g, t, u1, u2);
        count[k]++;
        sx[k] += u1 * G - i;
        sy[k] += u2 * G - j;
    }
    EXPECT_EQ_INT(mismatch, 0);
    for (int k = 0; k < G2; k++) {
        double q = t[k + 1] - t[k], se = sqrt(q * (1 - q) / N);
        EXPECT_MSG(fabs((double)count[k] / N - q) < 5 * se, "stratum %d: %g of the samples, q' %g", k,
                   (double)count[k] / N, q);
        if (count[k] > 100) {
            double tol = 5 * sqrt(1.0 / 12 / (double)count[k]);
            EXPECT_NEAR(sx[k] / count[k], 0.5, tol);
            EXPECT_NEAR(sy[k] / count[k], 0.5, tol);
        }
    }
    guide_free(&g);
}

/* Oracle: the definition of "no data": an empty guide, a NULL guide and an unvisited cell
 * leave (u1, u2) unchanged with density 1; bad input is refused. */
TEST(render_guide_uniform_without_data) {
    guide_grid gr = unit_grid();
    guide g;
    ASSERT_EQ_INT(guide_build(&g, &gr, 8, 0.3, NULL, 0), 0);
    double u1 = 0.123, u2 = 0.987;
    EXPECT_NEAR(guide_sample(&g, v3s(0.5), v3(0, 1, 0), 0, &u1, &u2), 1, 0);
    EXPECT_NEAR(guide_sample(NULL, v3s(0.5), v3(0, 1, 0), 0, &u1, &u2), 1, 0);
    EXPECT(u1 == 0.123 && u2 == 0.987);
    EXPECT_NEAR(guide_density(&g, v3s(0.5), v3(0, 1, 0), 0, 0.5, 0.5), 1, 0);
    guide_free(&g);
    double v[64];
    for (int k = 0; k < 64; k++) v[k] = 1;
    guide_row row = {guide_cell(&gr, v3s(0.5), v3(0, 1, 0)), 0, v};
    EXPECT_EQ_INT(guide_build(&g, &gr, 8, 0, &row, 1), PM_EINVAL); /* alpha 0: not unbiased */
    EXPECT_EQ_INT(guide_build(&g, &gr, 6, 0.3, &row, 1), PM_EINVAL); /* G not a power of 2 */
    v[5] = -1;
    EXPECT_EQ_INT(guide_build(&g, &gr, 8, 0.3, &row, 1), PM_EINVAL);
    v[5] = NAN;
    EXPECT_EQ_INT(guide_build(&g, &gr, 8, 0.3, &row, 1), PM_EINVAL);
    /* uniform values: q' uniform, density 1 everywhere (the warp reorders the square: the
     * stratum comes from u1 alone, so the point moves, with density 1) */
    v[5] = 1;
    ASSERT_EQ_INT(guide_build(&g, &gr, 8, 0.3, &row, 1), 0);
    u1 = 0.3;
    u2 = 0.6;
    EXPECT_NEAR(guide_sample(&g, v3s(0.5), v3(0, 1, 0), 0, &u1, &u2), 1, 1e-12);
    EXPECT_NEAR(u1, (3 + 0.2) / 8, 1e-12); /* stratum 19 of 64 (i 3, j 2), 0.2 into it */
    EXPECT_NEAR(u2, (2 + 0.6) / 8, 1e-12);
    guide_free(&g);
}

/* A floor lit by a 1 x 1 lamp at height 2 through a 0.1 x 0.1 hole in a plate at height 1; the
 * camera under the plate looks at the floor under the hole. */
static const char *k_hole_scene =
    "{\"camera\": {\"eye\": [0, 0.6, 0.6], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 16, \"height\": 16},"
    "\"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
    "  \"e\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": [3, 2, 1]}},"
    "\"objects\": ["
    " {\"type\": \"quad\", \"vertices\": [[-3,0,-3],[-3,0,3],[3,0,3],[3,0,-3]], \"material\": \"w\"},"
    " {\"type\": \"quad\", \"vertices\": [[-0.5,2,-0.5],[0.5,2,-0.5],[0.5,2,0.5],[-0.5,2,0.5]], \"material\": \"e\"},"
    " {\"type\": \"quad\", \"vertices\": [[-3,1,-3],[3,1,-3],[3,1,-0.05],[-3,1,-0.05]], \"material\": \"w\"},"
    " {\"type\": \"quad\", \"vertices\": [[-3,1,0.05],[3,1,0.05],[3,1,3],[-3,1,3]], \"material\": \"w\"},"
    " {\"type\": \"quad\", \"vertices\": [[-3,1,-0.05],[-0.05,1,-0.05],[-0.05,1,0.05],[-3,1,0.05]], \"material\": \"w\"},"
    " {\"type\": \"quad\", \"vertices\": [[0.05,1,-0.05],[3,1,-0.05],[3,1,0.05],[0.05,1,0.05]], \"material\": \"w\"}"
    "]}";

/* The radiance leaving the floor at (x, 0, z) upward: (0.5 / pi) Le E, E = the integral over the
 * lamp's part seen through the hole of cos cos' / r^2 dA. From (x, 0, z) the hole
 * [-0.05, 0.05]^2 at height 1 projects onto the lamp (height 2) as [2(-0.05) - x, 2(0.05) - x]
 * (and the same in z), inside the lamp for |x|, |z| <= 0.4. Midpoint rule, 1000 x 1000. */
static double hole_irradiance(double x, double z) {
    int n = 1000;
    double a0 = -0.1 - x, b0 = -0.1 - z, w = 0.2 / n, e = 0;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) { /* (dx, 2, dz): from the floor point to the lamp's point */
            double dx = a0 + (i + 0.5) * w - x, dz = b0 + (j + 0.5) * w - z, r2 = dx * dx + 4 + dz * dz;
            e += 4 / (r2 * r2) * w * w; /* cos = cos' = 2 / r */
        }
    return e;
}

/* The direct light at floor point (x, 0, z) by n guided samples: mean and standard error of
 * the luminance. */
static void direct_at_port(const scene *s, const guide *gd, const port *pt, double x, double z, long n, double *mean,
                           double *se) {
    hit h;
    ray r = {v3(x, 0.5, z), v3(0, -1, 0)};
    *mean = *se = NAN;
    if (!scene_intersect(s, r, INFINITY, &h)) return;
    const material *m = scene_material(s, &h);
    vec3 wo = v3(0, 1, 0), n0 = v3(0, 1, 0);
    direct_options o = {DIRECT_BSDF_FULL, 0, NULL, NULL, -1, pt, {0, 1, 0}};
    rng g = rng_stream(99, 1, 2);
    double s1 = 0, s2 = 0;
    for (long k = 0; k < n; k++) {
        double y = rgb_lum(direct_light_surface_guided(s, m, &h, n0, wo, &g, &o, gd));
        s1 += y;
        s2 += y * y;
    }
    *mean = s1 / n;
    *se = sqrt(fmax(0, s2 / n - *mean * *mean) / n);
}

static void direct_at(const scene *s, const guide *gd, double x, double z, long n, double *mean, double *se) {
    direct_at_port(s, gd, NULL, x, z, n, mean, se);
}

/* The hole scene loaded into s and its light guide, forced on; NULL (reason says why, s freed)
 * if the scene does not load or the guide is off. */
static guide *hole_guide(scene *s, char *reason, size_t cap) {
    json_err e;
    if (scene_load_text(s, k_hole_scene, &e) != 0) {
        snprintf(reason, cap, "%.300s", e.msg);
        return NULL;
    }
    int on = 0;
    guide_light_evidence ev;
    guide *gd = guide_light_make(s, PLAN_ON, 1, &on, reason, cap, &ev);
    if (on && gd) return gd;
    if (gd) guide_destroy(gd);
    scene_free(s);
    return NULL;
}

/* Oracle: quadrature (hole_irradiance), for the light samples drawn in part through a port
 * (direct.h, THROUGH A PORT): at the three floor points the estimate with the hole as the port
 * (its light from above) is within 4 standard errors and 1% of the quadrature, without a guide
 * and with the learned one, and so is it with a wrong port (0.1 x 0.1 at (0.3, 1, 0.3), over the
 * solid roof: its rays find nothing, and the light samples, whose directions it cannot draw,
 * keep their whole weight). The port must pay: a standard error under a third of the learned
 * guide's alone (measured 4.5x lower). */
TEST(render_guide_direct_light_through_a_port) {
    scene s;
    char reason[400];
    guide *gd = hole_guide(&s, reason, sizeof reason);
    ASSERT_MSG(gd, "%s", reason);
    port hole = port_quad(v3(-0.05, 1, -0.05), v3(0.1, 0, 0), v3(0, 0, 0.1));
    port wrong = port_quad(v3(0.25, 1, 0.25), v3(0.1, 0, 0), v3(0, 0, 0.1));
    const double xs[3] = {0, 0.1, -0.15}, zs[3] = {0, 0.05, 0.1};
    for (int p = 0; p < 3; p++) {
        double exact = 0.5 / M_PI * rgb_lum(v3(3, 2, 1)) * hole_irradiance(xs[p], zs[p]);
        double m0, s0, m1, s1, m2, s2, m3, s3;
        long n = 200000;
        direct_at(&s, gd, xs[p], zs[p], n, &m0, &s0);
        direct_at_port(&s, NULL, &hole, xs[p], zs[p], n, &m1, &s1);
        direct_at_port(&s, gd, &hole, xs[p], zs[p], n, &m2, &s2);
        direct_at_port(&s, gd, &wrong, xs[p], zs[p], n, &m3, &s3);
        printf("    (%g, %g): exact %.6g; guide %.6g (se %.2g); port %.6g (se %.2g); port and guide %.6g (se %.2g); "
               "wrong port %.6g (se %.2g)\n",
               xs[p], zs[p], exact, m0, s0, m1, s1, m2, s2, m3, s3);
        EXPECT_MSG(fabs(m1 - exact) < 4 * s1 && fabs(m1 / exact - 1) < 0.01, "port: %g vs %g", m1, exact);
        EXPECT_MSG(fabs(m2 - exact) < 4 * s2 && fabs(m2 / exact - 1) < 0.01, "port and guide: %g vs %g", m2, exact);
        EXPECT_MSG(fabs(m3 - exact) < 4 * s3, "wrong port: %g vs %g", m3, exact);
        EXPECT_MSG(s2 < s0 / 3, "the port does not pay: se %g, the guide alone %g", s2, s0);
    }
    guide_destroy(gd);
    scene_free(&s);
}

/* Oracle: quadrature (hole_irradiance). The guided estimate at three floor points under the
 * hole is within 4 standard errors and 1.5% of the quadrature, with the guide the plan learns
 * (forced on) and with a wrong hand-made table (all weight on strata that see nothing: the
 * defensive share alone reaches the hole); the learned guide must pay: a standard error at
 * most half of the unguided one's at the same sample count. */
TEST(render_guide_direct_light_unbiased) {
    scene s;
    char reason[400];
    guide *gd = hole_guide(&s, reason, sizeof reason);
    printf("    light guide: %s (%s)\n", gd ? "on" : "off", reason);
    ASSERT_MSG(gd, "%s", reason);
    /* A wrong table for the cells of the three points: value only in stratum 0 of each light,
     * which is a corner of its triangle, outside what the hole shows. */
    enum { G2 = GUIDE_G * GUIDE_G };
    static double bad[G2];
    bad[0] = 1;
    const double xs[3] = {0, 0.1, -0.15}, zs[3] = {0, 0.05, 0.1};
    guide_row rows[6];
    for (int p = 0; p < 3; p++)
        for (int l = 0; l < 2; l++)
            rows[2 * p + l] = (guide_row){guide_cell(&gd->grid, v3(xs[p], 0, zs[p]), v3(0, 1, 0)), l, bad};
    guide wrong;
    ASSERT_EQ_INT(guide_build(&wrong, &gd->grid, GUIDE_G, GUIDE_ALPHA, rows, 6), 0);
    for (int p = 0; p < 3; p++) {
        double exact = 0.5 / M_PI * rgb_lum(v3(3, 2, 1)) * hole_irradiance(xs[p], zs[p]);
        double m0, s0, m1, s1, m2, s2;
        long n = 200000;
        EXPECT(guide_find(gd, v3(xs[p], 0, zs[p]), v3(0, 1, 0), 0) || guide_find(gd, v3(xs[p], 0, zs[p]), v3(0, 1, 0), 1));
        direct_at(&s, NULL, xs[p], zs[p], n, &m0, &s0);
        direct_at(&s, gd, xs[p], zs[p], n, &m1, &s1);
        direct_at(&s, &wrong, xs[p], zs[p], n, &m2, &s2);
        printf("    (%g, %g): exact %.6g; uniform %.6g (se %.2g); learned %.6g (se %.2g); wrong table %.6g (se %.2g)\n",
               xs[p], zs[p], exact, m0, s0, m1, s1, m2, s2);
        EXPECT_MSG(fabs(m0 - exact) < 4 * s0, "uniform: %g vs %g", m0, exact);
        EXPECT_MSG(fabs(m1 - exact) < 4 * s1 && fabs(m1 / exact - 1) < 0.015, "learned: %g vs %g", m1, exact);
        EXPECT_MSG(fabs(m2 - exact) < 4 * s2, "wrong table: %g vs %g", m2, exact);
        EXPECT_MSG(s1 < 0.5 * s0, "the learned guide does not pay: se %g, uniform %g", s1, s0);
    }
    guide_free(&wrong);
    guide_destroy(gd);
    scene_free(&s);
}

/* Oracle: determinism as guide.h states it: the light guide learned on 1 thread and on 2 has
 * the same tables, bit for bit (render-mpi's ranks build it each on their own). */
TEST(render_guide_same_for_any_thread_count) {
#ifndef _OPENMP
    SKIP("built without OpenMP");
#else
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, k_hole_scene, &e) == 0, "%s", e.msg);
    int on1 = 0, on2 = 0;
    char r1[400], r2[400];
    int saved = omp_get_max_threads();
    omp_set_num_threads(1);
    guide *a = guide_light_make(&s, PLAN_AUTO, 1, &on1, r1, sizeof r1, NULL);
    omp_set_num_threads(2);
    guide *b = guide_light_make(&s, PLAN_AUTO, 1, &on2, r2, sizeof r2, NULL);
    omp_set_num_threads(saved);
    EXPECT_EQ_INT(on1, on2);
    EXPECT(strcmp(r1, r2) == 0);
    ASSERT(a && b);
    ASSERT_EQ_INT((int)a->ntables, (int)b->ntables);
    ASSERT_EQ_INT((int)a->ncells, (int)b->ncells);
    size_t n = a->ntables * (GUIDE_G * GUIDE_G + 1);
    EXPECT(memcmp(a->cdf, b->cdf, n * sizeof *a->cdf) == 0);
    EXPECT(memcmp(a->tw, b->tw, a->ntables * sizeof *a->tw) == 0);
    EXPECT(memcmp(a->tslot, b->tslot, a->ntables * sizeof *a->tslot) == 0);
    EXPECT(a->cap == b->cap && memcmp(a->hkey, b->hkey, a->cap * sizeof *a->hkey) == 0);
    guide_destroy(a);
    guide_destroy(b);
    scene_free(&s);
#endif
}

/* The plan's light-guide line of a shipped scene, rendered tiny (the plan is decided before
 * any photon is traced). */
static int plan_line(const char *name, char *line, size_t cap) {
    char cmd[4096], out[16384];
    snprintf(cmd, sizeof cmd,
             "%s/render '%s/data/scenes/%s.json' --mode pm --width 4 --height 4 --spp 1 --quiet --pm global_photons=2000 "
             "--pm caustic_photons=2000 --hdr '%s/%s.pfm'",
             pm_test_build_dir(), pm_test_source_dir(), name, pm_test_tmpdir(), name);
    int rc = pm_test_run(cmd, out, sizeof out);
    const char *p = strstr(out, "light guide: ");
    line[0] = 0;
    if (p) {
        size_t n = strcspn(p, "\n");
        snprintf(line, cap, "%.*s", (int)n, p);
    } else
        printf("    %s printed no light guide line:\n%.2000s\n", name, out);
    return rc;
}

/* Oracle: what the scenes are. pinhole_room's camera looks at light that comes through a 10 x 10
 * hole (light samples from the lit patch pass ~1 in 37): on. The others are lit openly (their
 * shadows are a small part of their light): off, so their images are the same as without the
 * guide. */
TEST(render_guide_plan_lines) {
    const char *off[] = {"cornell_box", "cornell_spheres", "shelf_glass", "partition_thin", "partition_thick"};
    char line[1024];
    ASSERT_EQ_INT(plan_line("pinhole_room", line, sizeof line), 0);
    printf("    pinhole_room: %s\n", line);
    EXPECT_MSG(strncmp(line, "light guide: on (light samples are mostly blocked", 49) == 0, "pinhole_room: %s", line);
    for (size_t i = 0; i < sizeof off / sizeof off[0]; i++) {
        ASSERT_EQ_INT(plan_line(off[i], line, sizeof line), 0);
        printf("    %s: %s\n", off[i], line);
        EXPECT_MSG(strncmp(line, "light guide: off (light samples mostly pass", 43) == 0, "%s: %s", off[i], line);
    }
}

/* Oracle: the geometry. Two scenes where the pilot has nothing to learn, whose line must say so
 * instead of "light samples mostly pass" (the old wording, over evidence of 0 light samples or
 * 0% passing): a lamp shut in an opaque box on a lit-nowhere floor (every segment from a point
 * the camera sees to the lamp crosses the box: samples > 0, none pass), and a closed room of
 * reflectance 0 lit by a ceiling lamp (every light sample's BSDF is 0: no sample carries
 * light). Both off, with the pilot's counts. */
TEST(render_guide_plan_nothing_to_learn) {
    static const char *boxed =
        "{\"camera\": {\"eye\": [5, 6, -8], \"look_at\": [5, 0, 5], \"fov_deg\": 60, \"width\": 4, \"height\": 4, "
        "\"spp\": 1}, \"materials\": {\"white\": {\"type\": \"lambert\", \"reflectance\": 0.6}, \"lamp\": {\"type\": "
        "\"lambert\", \"reflectance\": 0, \"emission\": 20}}, \"objects\": ["
        "{\"type\": \"quad\", \"vertices\": [[-20, 0, -20], [-20, 0, 30], [30, 0, 30], [30, 0, -20]], \"material\": "
        "\"white\"},"
        "{\"type\": \"quad\", \"vertices\": [[3, 0, 3], [7, 0, 3], [7, 3, 3], [3, 3, 3]], \"material\": \"white\"},"
        "{\"type\": \"quad\", \"vertices\": [[3, 0, 7], [7, 0, 7], [7, 3, 7], [3, 3, 7]], \"material\": \"white\"},"
        "{\"type\": \"quad\", \"vertices\": [[3, 0, 3], [3, 0, 7], [3, 3, 7], [3, 3, 3]], \"material\": \"white\"},"
        "{\"type\": \"quad\", \"vertices\": [[7, 0, 3], [7, 0, 7], [7, 3, 7], [7, 3, 3]], \"material\": \"white\"},"
        "{\"type\": \"quad\", \"vertices\": [[3, 3, 3], [7, 3, 3], [7, 3, 7], [3, 3, 7]], \"material\": \"white\"},"
        "{\"type\": \"quad\", \"vertices\": [[4, 2, 4], [6, 2, 4], [6, 2, 6], [4, 2, 6]], \"material\": \"lamp\"}], "
        "\"render\": {\"max_depth\": 16}}";
    static const char *black =
        "{\"camera\": {\"eye\": [5, 5, -12], \"look_at\": [5, 5, 0], \"fov_deg\": 50, \"width\": 4, \"height\": 4, "
        "\"spp\": 1}, \"materials\": {\"white\": {\"type\": \"lambert\", \"reflectance\": 0}, \"lamp\": {\"type\": "
        "\"lambert\", \"reflectance\": 0.5, \"emission\": 10}}, \"objects\": ["
        TEST_BOX10_QUADS "], \"render\": {\"max_depth\": 16}}";
    const char *texts[2] = {boxed, black}, *names[2] = {"boxed", "black"};
    const char *want[2] = {"light guide: off (no pilot light sample passes where the camera looks: nothing to learn "
                           "(pilot: ",
                           "light guide: off (no pilot light sample would carry light where the camera looks"};
    for (int i = 0; i < 2; i++) {
        char path[1024], cmd[4096];
        static char out[16384];
        snprintf(path, sizeof path, "%s/%s.json", pm_test_tmpdir(), names[i]);
        FILE *f = fopen(path, "w");
        ASSERT(f);
        fputs(texts[i], f);
        fclose(f);
        snprintf(cmd, sizeof cmd,
                 "%s/render '%s' --mode pm --quiet --pm global_photons=2000 --pm caustic_photons=2000 --hdr "
                 "'%s/%s.pfm'",
                 pm_test_build_dir(), path, pm_test_tmpdir(), names[i]);
        int rc = pm_test_run(cmd, out, sizeof out);
        const char *p = strstr(out, "light guide: ");
        size_t n = p ? strcspn(p, "\n") : 0;
        printf("    %s (exit %d): %.*s\n", names[i], rc, (int)n, p ? p : "no light guide line");
        EXPECT_MSG(p && strncmp(p, want[i], strlen(want[i])) == 0, "%s: %.*s", names[i], (int)n, p ? p : out);
        EXPECT_MSG(p && !strstr(p, "mostly pass"), "%s", names[i]);
    }
}

/* The mean of an image and whether the render's statistics counted guided light samples. */
static int render_hole(const char *flags, int seed, double *mean, long *guided) {
    char scn[1024], pfm[1024], cmd[4096], out[16384];
    snprintf(scn, sizeof scn, "%s/hole.json", pm_test_tmpdir());
    snprintf(pfm, sizeof pfm, "%s/hole_%d.pfm", pm_test_tmpdir(), seed);
    FILE *f = fopen(scn, "w");
    if (!f) return -1;
    fputs("{\"find_ports\": false, ", f); /* the light guide alone (the port's aids off) */
    fputs(k_hole_scene + 1, f);
    fclose(f);
    snprintf(cmd, sizeof cmd,
             "%s/render '%s' --mode pm --width 16 --height 16 --spp 64 --seed %d --quiet --pm global_photons=20000 "
             "%s --hdr '%s'",
             pm_test_build_dir(), scn, seed, flags, pfm);
    int rc = pm_test_run(cmd, out, sizeof out);
    const char *p = strstr(out, "Light samples guided (light guide)");
    *guided = p ? atol(p + strlen("Light samples guided (light guide)")) : 0;
    film im;
    if (rc != 0 || film_read_pfm(&im, pfm) != 0) return -1;
    double s = 0;
    for (size_t k = 0; k < (size_t)im.width * (size_t)im.height * 3; k++) s += im.px[k];
    *mean = s / ((double)im.width * im.height * 3);
    film_free(&im);
    return 0;
}

/* Oracle: the photon mapper without the guide (its direct light is next-event estimation as
 * the path tracer's). The hole scene rendered by photon mapping with light_guide forced on and
 * off, six seeds each (16 x 16, 64 spp): the two means agree within 4 standard errors of their
 * difference (from the seeds' spread) and within 3%; the guided runs counted guided samples and
 * their spread over the seeds is smaller (measured with these seeds: sd
 * 1.30% on, 4.45% off, the means +0.58% apart, se 1.89%). The scene's photon ports are off
 * ($.find_ports false): with the port the probe finds over the hole, its aimed photons, gathers
 * and direct light leave the unguided spread at about 0.5%, where the guide's was the same
 * (0.52% on, 0.59% off), and the comparison would be of noise. */
TEST(render_guide_pm_image_same_mean) {
    enum { NS = 6 };
    double m[2][NS], mean[2] = {0, 0}, var[2] = {0, 0};
    for (int on = 0; on < 2; on++)
        for (int k = 0; k < NS; k++) {
            long guided = 0;
            ASSERT_EQ_INT(render_hole(on ? "--pm light_guide=true" : "--pm light_guide=false", 1 + k, &m[on][k], &guided), 0);
            if (on)
                EXPECT_MSG(guided > 1000, "seed %d: %ld light samples guided", 1 + k, guided);
            else
                EXPECT_MSG(guided == 0, "seed %d with the guide off: %ld light samples guided", 1 + k, guided);
            mean[on] += m[on][k] / NS;
        }
    for (int on = 0; on < 2; on++)
        for (int k = 0; k < NS; k++) var[on] += (m[on][k] - mean[on]) * (m[on][k] - mean[on]) / (NS - 1);
    double se = sqrt(var[0] / NS + var[1] / NS);
    printf("    image mean: guide off %.6g (sd %.2f%%), on %.6g (sd %.2f%%): %+.2f%% (se %.2f%%)\n", mean[0],
           100 * sqrt(var[0]) / mean[0], mean[1], 100 * sqrt(var[1]) / mean[1], 100 * (mean[1] / mean[0] - 1),
           100 * se / mean[0]);
    EXPECT(fabs(mean[1] - mean[0]) < 4 * se);
    EXPECT(fabs(mean[1] / mean[0] - 1) < 0.03);
    EXPECT(var[1] < var[0]);
}

/* A probe that is 1 where u1 < 1/4 and u2 >= 1/2 (whole strata at G = 8), else 0; slot 1 is 2
 * everywhere. */
static double quarter_probe(void *user, const scene *s, const guide_point *pt, int slot, double u1, double u2,
                            rng *g) {
    (void)user, (void)s, (void)pt, (void)g;
    if (slot == 1) return 2;
    return u1 < 0.25 && u2 >= 0.5 ? 1 : 0;
}

/* Oracle: the probe's own values. guide_points gives the same points on 1 and 2 threads;
 * guide_learn with a use mask makes tables only for the (point, slot) pairs asked for, and a
 * table from that probe has q = 1/8 on each of its 8 lit strata (alpha / G^2 + (1 - alpha) / 8
 * after the mixture) and alpha / G^2 elsewhere; a cell's slot weights are the slots' shares of
 * the cell's sums (slot 0 sums 8 per point of the cell, slot 1 2 x 64 per even point), and
 * guide_pick_slot chooses by them. */
TEST(render_guide_learn_from_probes) {
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, k_hole_scene, &e) == 0, "%s", e.msg);
    guide_point *p1 = NULL, *p2 = NULL;
    size_t n1 = 0, n2 = 0;
    ASSERT_EQ_INT(guide_points(&s, 500, 5, 1, &p1, &n1), 0);
    ASSERT_EQ_INT(guide_points(&s, 500, 5, 2, &p2, &n2), 0);
    ASSERT(n1 == n2 && n1 > 500);
    EXPECT(memcmp(p1, p2, n1 * sizeof *p1) == 0);
    guide_grid gr;
    guide_grid_init(&gr, &s, GUIDE_RES);
    size_t np = 40;
    unsigned char *use = calloc(np * 2, 1);
    ASSERT(use);
    for (size_t k = 0; k < np; k++) use[2 * k] = 1, use[2 * k + 1] = k % 2 == 0; /* slot 1 at even points */
    guide g;
    unsigned long long probes = 0;
    ASSERT_EQ_INT(guide_learn(&g, &s, &gr, 8, 0.3, p1, np, 2, use, quarter_probe, NULL, 9, 0, &probes), 0);
    EXPECT_EQ_INT((int)probes, (int)(np + np / 2) * 64);
    int checked = 0;
    for (size_t k = 0; k < np; k++) {
        const double *t0 = guide_find(&g, p1[k].h.p, p1[k].n, 0), *t1 = guide_find(&g, p1[k].h.p, p1[k].n, 1);
        ASSERT(t0);
        for (int j = 0; j < 8; j++)
            for (int i = 0; i < 8; i++) {
                double q = t0[i + 8 * j + 1] - t0[i + 8 * j], want = 0.3 / 64 + (i < 2 && j >= 4 ? 0.7 / 8 : 0);
                EXPECT_NEAR(q, want, 1e-12);
            }
        /* slot 1 has a table where some point of this cell is even */
        int even = 0;
        for (size_t m = 0; m < np; m += 2)
            even |= guide_cell(&gr, p1[m].h.p, p1[m].n) == guide_cell(&gr, p1[k].h.p, p1[k].n);
        EXPECT((t1 != NULL) == even);
        long c = guide_cell_index(&g, p1[k].h.p, p1[k].n);
        ASSERT(c >= 0);
        if (!t1) {
            EXPECT_NEAR(guide_slot_weight(&g, c, 0), 1, 1e-12);
            EXPECT_NEAR(guide_slot_weight(&g, c, 1), 0, 0);
            EXPECT_EQ_INT(guide_pick_slot(&g, c, 0.99), 0);
        } else {
            double n_all = 0, n_even = 0;
            for (size_t m = 0; m < np; m++)
                if (guide_cell(&gr, p1[m].h.p, p1[m].n) == guide_cell(&gr, p1[k].h.p, p1[k].n)) {
                    n_all++;
                    n_even += m % 2 == 0;
                }
            double w0 = guide_slot_weight(&g, c, 0), w1 = guide_slot_weight(&g, c, 1);
            EXPECT_NEAR(w1, 128 * n_even / (128 * n_even + 8 * n_all), 1e-12);
            EXPECT_NEAR(w0 + w1, 1, 1e-12);
            EXPECT_EQ_INT(guide_pick_slot(&g, c, 0.5 * w0), 0);
            EXPECT_EQ_INT(guide_pick_slot(&g, c, w0 + 0.5 * w1), 1);
            checked++;
        }
    }
    EXPECT(checked > 0);
    guide_free(&g);
    free(use);
    free(p1);
    free(p2);
    scene_free(&s);
}
