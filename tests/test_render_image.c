/* test_render_image.c: whole renders against analytic radiance, and determinism.
 *
 * Oracles: the furnace (radiance Le/(1-rho) everywhere), direct lighting of a Lambertian
 * plane by a point light, a square area light and a directional light (closed forms),
 * bit-identical films for 1 and 2 threads, the tile grid's partition of the image, and auto
 * exposure against sorted luminances.
 * Images are tiny so the suite stays fast.
 */
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "../photonmap/common.h"
#include "../render/image/compare.h"
#include "../render/base/errors.h"
#include "../render/image/film.h"
#include "../render/integrators/integrator.h"
#include "../render/run/renderer.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"
#include "../render/base/stats.h"

static int render_text(const char *text, int w, int h, int spp, int threads, film *f) {
    scene s;
    json_err e;
    if (scene_load_text(&s, text, &e) < 0) {
        printf("    scene: %s\n", e.msg);
        return -1;
    }
    if (w) camera_resize(&s.cam, w, h);
    if (spp) camera_set_spp(&s.cam, spp);
    integrator it;
    char err[256];
    int rc = integrator_create("path", &s, &it, err, sizeof err);
    if (rc == 0) {
        render_job job = {threads, 1, s.settings.seed, NULL, NULL};
        rc = render_image(&s, &it, &job, f);
        integrator_destroy(&it);
    }
    scene_free(&s);
    return rc;
}

static int render_file(const char *name, int w, int h, int spp, int threads, film *f) {
    char path[1024];
    snprintf(path, sizeof path, "%s/data/scenes/%s", pm_test_source_dir(), name);
    FILE *fp = fopen(path, "rb");
    if (!fp) return -1;
    static char buf[1 << 16];
    size_t n = fread(buf, 1, sizeof buf - 1, fp);
    fclose(fp);
    buf[n] = 0;
    return render_text(buf, w, h, spp, threads, f);
}

/* Mean and standard error of the per-pixel means of channel 1 (green). */
static void pixel_stats(const film *f, double *mean, double *se) {
    long n = (long)f->width * f->height;
    double s = 0, s2 = 0;
    for (long i = 0; i < n; i++) {
        double v = f->px[3 * i + 1];
        s += v;
        s2 += v * v;
    }
    *mean = s / n;
    *se = sqrt(fmax(0, s2 / n - *mean * *mean) / n);
}

/* Oracle: in data/scenes/furnace.json (Le = 1, rho = 0.5) the radiance is Le/(1-rho) = 2 in
 * every direction. Statistical bound: the image mean of N independent pixel means has
 * standard error se (measured); we require |mean - 2| <= 1% of 2 and also check that 4 se is
 * below 1%, so the 1% bound is a > 4-sigma statement and not luck. */
TEST(render_furnace_le_over_one_minus_rho) {
    film f;
    int n = PM_TEST_SANITIZED ? 16 : 32;
    ASSERT_EQ_INT(render_file("furnace.json", n, n, 256, 2, &f), 0);
    double mean, se;
    pixel_stats(&f, &mean, &se);
    printf("    furnace: mean %.5f, se %.5f (expected 2)\n", mean, se);
    ASSERT(4 * se < 0.01 * 2.0);
    ASSERT_NEAR(mean, 2.0, 0.01 * 2.0);
    film_free(&f);
}

#define PLANE_SCENE(LIGHTS, EXTRA_MAT, EXTRA_OBJ)                                                 \
    "{\"camera\": {\"eye\": [0, 1, 0], \"forward\": [0, -1, 0], \"up\": [0, 0, 1], "              \
    "\"fov_deg\": 0.01, \"width\": 1, \"height\": 1, \"spp\": 1},"                                \
    "\"materials\": {\"p\": {\"type\": \"lambert\", \"reflectance\": 0.6}" EXTRA_MAT "},"         \
    "\"objects\": [{\"type\": \"quad\", \"vertices\": [[-1e4,0,-1e4],[-1e4,0,1e4],[1e4,0,1e4],[1e4,0,-1e4]], " \
    "\"material\": \"p\"}" EXTRA_OBJ "]," LIGHTS "\"render\": {\"max_depth\": 1}}"

/* Oracle: a point light of intensity I at height h over a Lambertian plane (rho = 0.6): the
 * radiance below it is rho/pi * I / h^2. One bounce (max_depth 1) and a 0.01-degree view, so
 * the answer is exact to ~1e-9; tolerance 1e-6 relative. */
TEST(render_direct_point_light) {
    const char *txt = PLANE_SCENE("\"lights\": [{\"type\": \"point\", \"position\": [0, 2, 0], \"intensity\": 8}],", "", "");
    film f;
    ASSERT_EQ_INT(render_text(txt, 0, 0, 4, 1, &f), 0);
    ASSERT_REL(f.px[1], 0.6 / M_PI * 8.0 / 4.0, 1e-6);
    film_free(&f);
}

/* Oracle: a directional light with irradiance E arriving at 60 degrees from the normal gives
 * rho/pi * E cos(60 deg); 1e-6 relative. */
TEST(render_direct_directional_light) {
    const char *txt = PLANE_SCENE("\"lights\": [{\"type\": \"directional\", \"direction\": [0.8660254037844386, -0.5, 0], \"irradiance\": 3}],", "", "");
    film f;
    ASSERT_EQ_INT(render_text(txt, 0, 0, 4, 1, &f), 0);
    ASSERT_REL(f.px[1], 0.6 / M_PI * 3.0 * 0.5, 1e-6);
    film_free(&f);
}

/* Oracle: a square area light (side 2a, radiance Le, facing down, black so nothing bounces
 * back) at height h over the plane: the irradiance at the point below its centre is
 * E = 4 Le pi F_corner, F_corner = 1/(2 pi) [A/sqrt(1+A^2) atan(B/sqrt(1+A^2)) + (A<->B)]
 * with A = B = a/h (form factor of a rectangle to a point under its corner). Radiance:
 * rho/pi * E. Many light samples; tolerance 1% against a measured standard error. */
TEST(render_direct_area_light) {
    const char *txt = PLANE_SCENE(
        "", ", \"e\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 5}",
        ", {\"type\": \"quad\", \"vertices\": [[-1,2,-1],[1,2,-1],[1,2,1],[-1,2,1]], \"material\": \"e\"}");
    film f;
    /* One pixel can only hold a mean; render several seeds' worth via a wider image of the
     * same point: a 0.01 degree view is ~1e-3 units wide, where E is constant to 1e-6. */
    int spp = PM_TEST_SANITIZED ? 1024 : 16384;
    ASSERT_EQ_INT(render_text(txt, 4, 4, spp, 2, &f), 0);
    double mean, se;
    pixel_stats(&f, &mean, &se);
    double A = 1.0 / 2.0, s = sqrt(1 + A * A);
    double Fc = 1.0 / (2 * M_PI) * 2 * (A / s * atan(A / s));
    double E = 4 * 5.0 * M_PI * Fc;
    printf("    area light: %.6f vs %.6f (se %.2g)\n", mean, 0.6 / M_PI * E, se);
    ASSERT(4 * se < 0.01 * 0.6 / M_PI * E);
    ASSERT_REL(mean, 0.6 / M_PI * E, 0.01);
    film_free(&f);
}

/* Oracle: the same seed gives a bit-identical film with 1 and 2 threads (per-sample random
 * streams; each pixel is summed by one thread in sample order), on the scene with glass and
 * a mirror; a different seed gives a different film (so the test can fail). */
TEST(render_same_image_any_thread_count) {
    film a, b, c;
    int n = PM_TEST_SANITIZED ? 16 : 40;
    uint64_t ids[] = {STAT_CAMERA_RAYS, STAT_SHADOW_RAYS, STAT_INDIRECT_RAYS, STAT_TRI_TESTS,
                      STAT_SPHERE_TESTS, STAT_SPECULAR_BOUNCES};
    uint64_t counts[2][6];
    stats_reset();
    ASSERT_EQ_INT(render_file("cornell_spheres.json", n, n, 4, 1, &a), 0);
    for (int i = 0; i < 6; i++) counts[0][i] = stats_total((int)ids[i]);
    stats_reset();
    ASSERT_EQ_INT(render_file("cornell_spheres.json", n, n, 4, 2, &b), 0);
    for (int i = 0; i < 6; i++) counts[1][i] = stats_total((int)ids[i]);
    ASSERT(memcmp(a.px, b.px, (size_t)n * n * 3 * sizeof(float)) == 0);
    /* The statistics are the same too, and count what was done: one camera ray per sample,
     * some shadow rays, sphere tests (the scene has two spheres) and specular bounces. */
    for (int i = 0; i < 6; i++) ASSERT_EQ_INT(counts[0][i], counts[1][i]);
    ASSERT_EQ_INT(counts[0][0], (uint64_t)n * n * 4);
    for (int i = 1; i < 6; i++) ASSERT(counts[0][i] > 0);
    ASSERT_EQ_INT(render_file("cornell_spheres.json", n, n, 9, 2, &c), 0);
    image_diff d;
    ASSERT_EQ_INT(image_compare(&a, &c, 0, 0, 0, 0, &d), 0);
    ASSERT(d.rmse > 0);
    ASSERT(d.mean_a > 0);
    film_free(&a);
    film_free(&b);
    film_free(&c);
#ifndef _OPENMP
    /* OPENMP=0: the "2 threads" run above was the same one-thread program, so the comparison
     * could not fail; the other checks ran. */
    SKIP("built without OpenMP (OPENMP=0): 1 and 2 threads are the same program here");
#endif
}

/* Oracle: the tile grid (renderer.h) partitions the image, every pixel in exactly one tile,
 * for every size from 1 x 1 to 70 x 70 and a few large ones; images of at least
 * RENDER_MIN_TILES tiles of RENDER_TILE keep that side, smaller ones are cut finer until they
 * have that many tiles or a side of 2 (hand-counted cases below). Before, a 16 x 16 image was
 * one tile, which one thread rendered while the other waited. */
TEST(render_tile_grid_partitions_the_image) {
    static unsigned char seen[70 * 70];
    for (int w = 1; w <= 70; w++)
        for (int h = 1; h <= 70; h++) {
            render_grid g = render_grid_of(w, h);
            ASSERT(g.side >= 2 && g.side <= RENDER_TILE);
            ASSERT(g.side == RENDER_TILE || g.side == 2 || g.tiles_x * g.tiles_y >= RENDER_MIN_TILES);
            memset(seen, 0, sizeof seen);
            for (int t = 0; t < g.tiles_x * g.tiles_y; t++) {
                int x0, y0, x1, y1;
                render_grid_tile(&g, w, h, t, &x0, &y0, &x1, &y1);
                ASSERT(x0 >= 0 && y0 >= 0 && x1 <= w && y1 <= h && x0 < x1 && y0 < y1);
                ASSERT(x1 - x0 <= g.side && y1 - y0 <= g.side);
                for (int y = y0; y < y1; y++)
                    for (int x = x0; x < x1; x++) seen[y * w + x]++;
            }
            for (int i = 0; i < w * h; i++) ASSERT_EQ_INT(seen[i], 1);
        }
    struct { int w, h, side, tx, ty; } want[] = {
        {16, 16, 4, 4, 4},  {8, 8, 2, 4, 4},      {32, 32, 8, 4, 4},     {64, 64, 16, 4, 4},
        {96, 96, 16, 6, 6}, {128, 96, 16, 8, 6},  {1, 1, 2, 1, 1},       {40, 24, 4, 10, 6},
        {2000, 10, 16, 125, 1}, {10, 2000, 16, 1, 125}, {3, 100, 4, 1, 25},
    };
    for (size_t i = 0; i < sizeof want / sizeof want[0]; i++) {
        render_grid g = render_grid_of(want[i].w, want[i].h);
        ASSERT_EQ_INT(g.side, want[i].side);
        ASSERT_EQ_INT(g.tiles_x, want[i].tx);
        ASSERT_EQ_INT(g.tiles_y, want[i].ty);
    }
}

/* Oracle: a PFM written and read back is bit-identical; --compare of a file with itself
 * gives rmse 0, and against a copy scaled by 1.1 gives rel_mean 0.1 (analytic). */
TEST(render_pfm_roundtrip_and_compare) {
    film f, g, h;
    ASSERT_EQ_INT(film_init(&f, 7, 5), 0);
    for (int i = 0; i < 7 * 5 * 3; i++) f.px[i] = (float)(0.1 * i + 0.01);
    char p1[1024], p2[1024], cmd[4096], out[4096];
    snprintf(p1, sizeof p1, "%s/a.pfm", pm_test_tmpdir());
    snprintf(p2, sizeof p2, "%s/b.pfm", pm_test_tmpdir());
    ASSERT_EQ_INT(film_write_pfm(&f, p1), 0);
    ASSERT_EQ_INT(film_read_pfm(&g, p1), 0);
    ASSERT(g.width == 7 && g.height == 5);
    ASSERT(memcmp(f.px, g.px, sizeof(float) * 105) == 0);
    for (int i = 0; i < 105; i++) g.px[i] *= 1.1f;
    ASSERT_EQ_INT(film_write_pfm(&g, p2), 0);
    image_diff d;
    ASSERT_EQ_INT(film_read_pfm(&h, p2), 0);
    ASSERT_EQ_INT(image_compare(&h, &f, 0, 0, 0, 0, &d), 0);
    ASSERT_NEAR(d.rel_mean, 0.1, 1e-6);
    ASSERT_EQ_INT(image_compare(&h, &f, 2, 1, 3, 2, &d), 0);
    ASSERT_EQ_INT(d.npixels, 6);
    snprintf(cmd, sizeof cmd, "%s/render --compare '%s' '%s' --rect 0 0 7 5", pm_test_build_dir(), p2, p1);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    ASSERT_MSG(strstr(out, "rel_mean 0.1") != NULL, "%s", out);
    snprintf(cmd, sizeof cmd, "%s/render --compare '%s' '%s'", pm_test_build_dir(), p1, p1);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    ASSERT_MSG(strstr(out, "rmse 0\n") != NULL, "%s", out);
    film_free(&f);
    film_free(&g);
    film_free(&h);
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Auto exposure puts clip_percent % of the pixels at or above the clipping level. Oracle: the
 * luminances sorted; with the exposure the function picks, the count of pixels whose exposed
 * luminance exceeds the clipping level (1 for sRGB, the filmic white point otherwise) must be
 * the requested count within the histogram's resolution (4096 bins over a 2^20 range: a bin is
 * 0.5% in luminance, so allow the pixels within 1% of the level, plus one). Zero, NaN and
 * infinite pixels must not disturb it. */
TEST(render_auto_exposure_clips_requested_fraction) {
    const int w = 200, h = 100, n = w * h;
    film f;
    ASSERT(film_init(&f, w, h) == 0);
    double *lum = malloc((size_t)n * sizeof *lum);
    ASSERT(lum);
    uint64_t st = 12345;
    int m = 0;
    for (int i = 0; i < n; i++) {
        st = st * 6364136223846793005ULL + 1442695040888963407ULL;
        double u = (double)(st >> 11) / 9007199254740992.0;
        double l = exp2(20.0 * u - 10.0);
        if (i % 97 == 0) l = 0;
        float v = (float)l;
        if (i == 5) v = NAN;
        if (i == 6) v = INFINITY;
        f.px[3 * i] = f.px[3 * i + 1] = f.px[3 * i + 2] = v;
        if (v > 0 && isfinite(v)) lum[m++] = rgb_lum(v3(v, v, v));
    }
    qsort(lum, (size_t)m, sizeof *lum, cmp_double);
    for (int tone = 0; tone < 2; tone++) {
        int t = tone ? FILM_TONE_SRGB : FILM_TONE_FILMIC;
        for (double pct = 0.5; pct <= 8; pct *= 2) {
            double e = film_auto_exposure(&f, t, pct);
            ASSERT(e > 0 && isfinite(e));
            /* the clipping level in scene units is clip_level / e; count the pixels above it */
            double clip_level = t == FILM_TONE_SRGB ? 1.0 : FILM_HABLE_WHITE;
            double level = clip_level / e;
            long above = 0, near = 0;
            for (int i = 0; i < m; i++) {
                if (lum[i] > level) above++;
                if (fabs(lum[i] / level - 1) < 0.01) near++;
            }
            long want = (long)(pct / 100.0 * n);
            EXPECT_MSG(labs(above - want) <= near + 1,
                       "tone %d pct %.1f: %ld above the level, want %ld (+-%ld)", t, pct, above,
                       want, near + 1);
        }
    }
    free(lum);
    film_free(&f);
}

/* Oracles: geometry for `render --mode objects` on cornell_spheres (the ray through the image
 * centre meets the back wall, object 2, since both spheres top out at y = 200 below the eye's
 * 273; two rows from the top the centre sees the ceiling, object 1, and four rows down the
 * light, object 5, which hangs at y = 548.7 over x 213..343; every object is seen), and hand sums
 * for image_compare_region over a mask with a silhouette pixel (G != R^2) that must be left
 * out even though its R is a whole number. */
TEST(render_object_masks_and_region_compare) {
    char ids[1024], cmd[4096], out[8192];
    snprintf(ids, sizeof ids, "%s/ids.pfm", pm_test_tmpdir());
    snprintf(cmd, sizeof cmd, "%s/render '%s/data/scenes/cornell_spheres.json' --mode objects "
             "--width 32 --height 32 --spp 64 --quiet --hdr '%s'", pm_test_build_dir(),
             pm_test_source_dir(), ids);
    ASSERT_MSG(pm_test_run(cmd, out, sizeof out) == 0, "%s", out);
    film m;
    ASSERT_EQ_INT(film_read_pfm(&m, ids), 0);
    int count[10] = {0}, silhouette = 0;
    for (int y = 0; y < 32; y++)
        for (int x = 0; x < 32; x++) {
            rgb p = film_get(&m, x, y);
            if (p.x == p.z && p.y == p.x * p.x && p.x == floor(p.x) && p.x >= 0 && p.x <= 8)
                count[(int)p.x]++;
            else
                silhouette++;
        }
    rgb c = film_get(&m, 16, 16), t = film_get(&m, 16, 2), l = film_get(&m, 16, 4);
    EXPECT_MSG(c.x == 3 && c.y == 9, "centre pixel sees (%g, %g), not the back wall", c.x, c.y);
    EXPECT_MSG(t.x == 2 && t.y == 4, "pixel (16, 2) sees (%g, %g), not the ceiling", t.x, t.y);
    EXPECT_MSG(l.x == 6 && l.y == 36, "pixel (16, 4) sees (%g, %g), not the light", l.x, l.y);
    for (int j = 1; j <= 8; j++) EXPECT_MSG(count[j] > 0, "object %d seen by no pixel alone", j - 1);
    EXPECT_MSG(silhouette > 0 && silhouette < 32 * 32 / 2, "%d silhouette pixels", silhouette);
    film_free(&m);

    /* 3 x 1 images: pixel 0 sees object id 1, pixel 1 a silhouette with R = 1 (mean of 0 and
     * 2: G = 2 != 1), pixel 2 id 2. */
    film a, b, k;
    ASSERT_EQ_INT(film_init(&a, 3, 1), 0);
    ASSERT_EQ_INT(film_init(&b, 3, 1), 0);
    ASSERT_EQ_INT(film_init(&k, 3, 1), 0);
    film_set(&a, 0, 0, v3s(2));
    film_set(&a, 1, 0, v3s(100));
    film_set(&a, 2, 0, v3s(5));
    film_set(&b, 0, 0, v3s(1));
    film_set(&b, 1, 0, v3s(1));
    film_set(&b, 2, 0, v3s(4));
    film_set(&k, 0, 0, v3(1, 1, 1));
    film_set(&k, 1, 0, v3(1, 2, 1));
    film_set(&k, 2, 0, v3(2, 4, 2));
    int one = 1, both[2] = {1, 2};
    image_diff d;
    image_region r1 = {0, 0, 0, 0, &k, &one, 1};
    ASSERT_EQ_INT(image_compare_region(&a, &b, &r1, &d), 0);
    EXPECT_EQ_INT(d.npixels, 1);
    EXPECT_NEAR(d.rel_mean, 1.0, 1e-12); /* 2 against 1 */
    image_region r2 = {0, 0, 0, 0, &k, both, 2};
    ASSERT_EQ_INT(image_compare_region(&a, &b, &r2, &d), 0);
    EXPECT_EQ_INT(d.npixels, 2);
    EXPECT_NEAR(d.mean_a, 3.5, 1e-12);
    EXPECT_NEAR(d.rmse, 1.0, 1e-12);
    image_region r3 = {2, 0, 1, 1, &k, &one, 1}; /* the rectangle holds no pixel of id 1 */
    EXPECT_EQ_INT(image_compare_region(&a, &b, &r3, &d), PM_EINVAL);
    film_free(&a);
    film_free(&b);
    film_free(&k);
}

/* Oracle: the renderer words its own errors. A file that is not a PFM, given to
 * `render --compare` and `render --tonemap`, exits 2 with a message that names the file and
 * says the format is wrong, never the module's "photon-map file" wording; a missing file
 * gives the system's "No such file or directory". render_strerror gives a text of its own
 * for every code the renderer returns. */
TEST(render_errors_are_the_renderers_own) {
    char bad[1024], good[1024], missing[1024], png[1024], cmd[4096], out[4096];
    snprintf(bad, sizeof bad, "%s/bad.pfm", pm_test_tmpdir());
    snprintf(good, sizeof good, "%s/good.pfm", pm_test_tmpdir());
    snprintf(missing, sizeof missing, "%s/missing.pfm", pm_test_tmpdir());
    snprintf(png, sizeof png, "%s/out.png", pm_test_tmpdir());
    FILE *f = fopen(bad, "w");
    ASSERT(f != NULL);
    fputs("P6\n2 2\n255\nnot a float map\n", f);
    fclose(f);
    film g;
    ASSERT_EQ_INT(film_init(&g, 2, 2), 0);
    ASSERT_EQ_INT(film_write_pfm(&g, good), 0);
    film_free(&g);
    snprintf(cmd, sizeof cmd, "%s/render --compare '%s' '%s'", pm_test_build_dir(), bad, good);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 2);
    EXPECT_MSG(strstr(out, bad) && strstr(out, "file format") && !strstr(out, "photon-map"), "%s",
               out);
    snprintf(cmd, sizeof cmd, "%s/render --tonemap '%s' '%s'", pm_test_build_dir(), bad, png);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 2);
    EXPECT_MSG(strstr(out, "file format") && !strstr(out, "photon-map"), "%s", out);
    snprintf(cmd, sizeof cmd, "%s/render --compare '%s' '%s'", pm_test_build_dir(), missing, good);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 2);
    EXPECT_MSG(strstr(out, "No such file or directory") != NULL, "%s", out);
    for (int code = PM_EINVAL; code >= PM_ENOTFILE; code--) {
        const char *t = render_strerror(code);
        EXPECT_MSG(t && *t && !strstr(t, "photon-map") && strcmp(t, "unknown error") != 0,
                   "code %d: %s", code, t ? t : "(null)");
    }
}
