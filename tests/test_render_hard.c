/* test_render_hard.c: photon mapping on scenes built to break it: light behind opaque walls.
 *
 * Each test renders a small image in path tracing (the reference) and in photon mapping and
 * compares region means (rectangles of the image). Scenes: data/scenes/partition_thin.json
 * and partition_thick.json (a Cornell box cut in two by an opaque partition, a single quad or
 * a slab 2 units thick, the light above it). The lower half gets no light at all: light
 * leaving the box's open front never comes back, so its exact radiance is 0, and a photon
 * lookup that reads photons from across the partition shows up there directly.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "test.h"
#include "../render/film.h"

/* Mean of the three channels over the rectangle [x0, x1) x [y0, y1) (top-left origin). */
static double rect_mean(const film *f, int x0, int y0, int x1, int y1) {
    double sum = 0;
    int n = 0;
    for (int y = y0; y < y1; y++)
        for (int x = x0; x < x1; x++) {
            const float *p = &f->px[3 * ((size_t)y * f->width + x)];
            sum += (p[0] + p[1] + p[2]) / 3.0;
            n++;
        }
    return n ? sum / n : 0;
}

static int render_scene(const char *name, const char *flags, const char *pfm) {
    char cmd[4096], out[16384];
    snprintf(cmd, sizeof cmd, "%s/render '%s/data/scenes/%s.json' --width 32 --height 32 --quiet --hdr '%s' %s",
             pm_test_build_dir(), pm_test_source_dir(), name, pfm, flags);
    return pm_test_run(cmd, out, sizeof out);
}

/* Oracle: path tracing (256 samples per pixel at 32x32; the upper half's mean has a standard
 * error well below 1%) and the exact 0 of the lower half. Photon mapping (50,000 global
 * photons, 16 samples): the lower half's mean must stay below 1e-4 of the upper half's (it
 * was 1.2% when gather lookups and precomputed irradiance read photons through the
 * partition), and the upper half within 5% of path tracing. Rows 0-13 are above the
 * partition, rows 18-31 below it (the camera is level with it). */
static void check_partition(const char *name) {
    char pt[1024], pm[1024];
    snprintf(pt, sizeof pt, "%s/%s_pt.pfm", pm_test_tmpdir(), name);
    snprintf(pm, sizeof pm, "%s/%s_pm.pfm", pm_test_tmpdir(), name);
    ASSERT_EQ_INT(render_scene(name, "--mode path --spp 256", pt), 0);
    ASSERT_EQ_INT(render_scene(name, "--mode pm --spp 16 --pm global_photons=50000", pm), 0);
    film a, b;
    ASSERT(film_read_pfm(&a, pt) == 0 && film_read_pfm(&b, pm) == 0);
    double up_pt = rect_mean(&a, 0, 0, 32, 14), low_pt = rect_mean(&a, 0, 18, 32, 32);
    double up_pm = rect_mean(&b, 0, 0, 32, 14), low_pm = rect_mean(&b, 0, 18, 32, 32);
    printf("    %s: upper half path %.5f pm %.5f (%+.2f%%); lower half path %.3g pm %.3g\n", name,
           up_pt, up_pm, 100 * (up_pm / up_pt - 1), low_pt, low_pm);
    EXPECT_MSG(low_pt == 0, "%s: path tracing lights the lower half (%g)", name, low_pt);
    EXPECT_MSG(low_pm < 1e-4 * up_pm, "%s: light leaks under the partition: %g", name, low_pm);
    EXPECT_MSG(fabs(up_pm / up_pt - 1) < 0.05, "%s: upper half %+.2f%%", name, 100 * (up_pm / up_pt - 1));
    film_free(&a);
    film_free(&b);
}

TEST(render_hard_partition_thin_no_leak) { check_partition("partition_thin"); }
TEST(render_hard_partition_thick_no_leak) { check_partition("partition_thick"); }

/* Oracle: the settings table's keys. A misspelt photon-mapping key is an input error (exit 2)
 * that names the option (--pm KEY) and the nearest known key; one far from every key gets no
 * guess. */
TEST(render_hard_typo_suggests_the_key) {
    char cmd[4096], out[16384];
    snprintf(cmd, sizeof cmd,
             "%s/render '%s/data/scenes/cornell_box.json' --mode pm --width 8 --height 8 --spp 1 "
             "--quiet --pm global_photon=5000 2>&1",
             pm_test_build_dir(), pm_test_source_dir());
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 2, "exit %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "render: --pm global_photon: unknown key (did you mean \"global_photons\"?)"),
               "%s", out);
    snprintf(cmd, sizeof cmd,
             "%s/render '%s/data/scenes/cornell_box.json' --mode pm --width 8 --height 8 --spp 1 "
             "--quiet --pm zzzzzzzz=1 2>&1",
             pm_test_build_dir(), pm_test_source_dir());
    rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 2 && strstr(out, "zzzzzzzz: unknown key") && !strstr(out, "did you mean"),
               "exit %d: %s", rc, out);
}
