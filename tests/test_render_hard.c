/* test_render_hard.c: photon mapping on scenes built to break it: light behind opaque walls.
 *
 * Each test renders a small image in path tracing (the reference) and in photon mapping and
 * compares region means (rectangles of the image). Scenes: data/scenes/partition_thin.json
 * and partition_thick.json (a Cornell box cut in two by an opaque partition, a single quad or
 * a slab 2 units thick, the light above it). The lower half gets no light at all: light
 * leaving the box's open front never comes back, so its exact radiance is 0, and a photon
 * lookup that reads photons from across the partition shows up there directly.
 * data/scenes/shelf_glass.json (a glass sphere under a shelf: the region under it is lit only
 * by light bounced in past the shelf's edge) and pinhole_room.json (a closed room lit through
 * a 10 x 10 hole: a handful of photons get in, and the lit patch under the hole sees a few
 * percent of the light): region means against path tracing. A caustic cage (scene text in the
 * test): nothing leaves it, and photon mapping must read 0 outside.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "test.h"
#include "test_film.h"
#include "../render/image/film.h"

static int render_scene_at(const char *name, int size, const char *flags, const char *pfm) {
    char cmd[4096], out[16384];
    snprintf(cmd, sizeof cmd, "%s/render '%s/data/scenes/%s.json' --width %d --height %d --quiet --hdr '%s' %s",
             pm_test_build_dir(), pm_test_source_dir(), name, size, size, pfm, flags);
    return pm_test_run(cmd, out, sizeof out);
}

static int render_scene(const char *name, const char *flags, const char *pfm) {
    return render_scene_at(name, 32, flags, pfm);
}

/* A named rectangle [x0, x1) x [y0, y1) of the image and the largest relative error allowed. */
typedef struct region {
    const char *name;
    int x0, y0, x1, y1;
    double tol;
} region;

/* Render `name` at size x size in path tracing (pt_flags) and photon mapping (pm_flags) and
 * check each region's mean: |pm / path - 1| < tol. */
static void check_regions(const char *name, int size, const char *pt_flags, const char *pm_flags,
                          const region *r, int nr) {
    char pt[1024], pm[1024];
    snprintf(pt, sizeof pt, "%s/%s_pt.pfm", pm_test_tmpdir(), name);
    snprintf(pm, sizeof pm, "%s/%s_pm.pfm", pm_test_tmpdir(), name);
    ASSERT_EQ_INT(render_scene_at(name, size, pt_flags, pt), 0);
    ASSERT_EQ_INT(render_scene_at(name, size, pm_flags, pm), 0);
    film a, b;
    ASSERT(film_read_pfm(&a, pt) == 0 && film_read_pfm(&b, pm) == 0);
    for (int i = 0; i < nr; i++) {
        double ma = rt_rect_mean(&a, r[i].x0, r[i].y0, r[i].x1, r[i].y1);
        double mb = rt_rect_mean(&b, r[i].x0, r[i].y0, r[i].x1, r[i].y1);
        double rel = ma > 0 ? mb / ma - 1 : INFINITY;
        printf("    %s %s: path %.5g pm %.5g (%+.2f%%, bound %.0f%%)\n", name, r[i].name, ma, mb,
               100 * rel, 100 * r[i].tol);
        EXPECT_MSG(fabs(rel) < r[i].tol, "%s %s: %+.2f%%", name, r[i].name, 100 * rel);
    }
    film_free(&a);
    film_free(&b);
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
    double up_pt = rt_rect_mean(&a, 0, 0, 32, 14), low_pt = rt_rect_mean(&a, 0, 18, 32, 32);
    double up_pm = rt_rect_mean(&b, 0, 0, 32, 14), low_pm = rt_rect_mean(&b, 0, 18, 32, 32);
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

/* Oracle: path tracing, 32x32 at 1024 spp (three seeds of it agree within 1% on each region).
 * Regions: the room above the shelf (rows 0-16), under the shelf (rows 20-27, columns 4-27:
 * back wall, floor and the glass sphere, lit only by light bounced in past the shelf's edge;
 * 6% of the brightness above) and the floor in front (rows 29-31). Photon mapping: 16 spp and
 * the default maps (200,000 global photons), emitted toward what the camera sees (the plan
 * chooses importance-driven emission here: importance.h). The region under the shelf reads
 * the precomputed irradiance of the floor beside the shelf's edge, spread by the estimate's
 * radius, so it reads high where photons are sparse: over four photon seeds against a
 * 4096-spp path render it read +0.9..+5.3% by power alone (eight seeds, the mean +3.2%),
 * -0.8..+3.4% with importance (+2.1%), and -1.8..+3.0% (five seeds, +1.5%) with the plan's
 * pilot photons joining the map as well. Each region within 5%. */
TEST(render_hard_shelf_glass_regions) {
    const region r[] = {{"above the shelf", 0, 0, 32, 17, 0.05},
                        {"under the shelf", 4, 20, 28, 28, 0.05},
                        {"floor in front", 0, 29, 32, 32, 0.05}};
    /* 64 spp: the plan's sample pilot gives a pm sample one gather ray here where the constant
     * default gave four, for about a quarter of the work; at 16 spp "under the shelf" (192
     * pixels lit by bounced light) read +6.9% from that noise, at 64 +1.8% (seed 1). */
    /* The 200,000 global photons are given: left to the plan, a 32x32 render's maps are fitted
     * to its few camera samples (README.md, "Photons fitted to the render"); with a quarter of
     * the targets under the shelf read +9.9% (the estimate's radius doubles). */
    check_regions("shelf_glass", 32, "--mode path --spp 1024", "--mode pm --spp 64 --pm global_photons=200000", r, 3);
}

/* Oracle: a long path-traced reference, rendered once and stored (data/reference-hard/
 * pinhole_room.pfm, 8x8, the mean of four 1,048,576-spp renders, seeds 1000-1003, whose region
 * means span 0.3% (walls) to 1.0% (patch); its .info has the commands, the commit and the scene
 * file's SHA-256, and the test refuses a reference of another version of the scene). The room
 * is lit only through a 10 x 10 hole: the lit patch on the floor sees about 3% of the lamp (a
 * light sample from it passes the hole about 1 time in 37); everything else is lit by that
 * patch, by light that bounced in the big room first (a third of what enters), and, on the
 * walls, by the camera's own view of the lit big room through the hole (a quarter of the walls'
 * light, from a few hundredths of a pixel). Photon mapping (default maps, 16384 spp, one gather
 * and one secondary ray; 20-25 CPU-s a render, pilots included): about 4 of 200,000 global
 * photons get in, so the lookups inside mostly find nothing and the gathers compute the light
 * themselves; the plan's light guide aims the light samples at the part of the lamp the hole
 * shows (guide.h) and its gather guide aims a share of the gather rays at the opening its
 * pilot finds (gather_guide.h). What this checks: nothing there is counted dark (the shadow
 * photons' "all shadow", the lookups that miss), nothing is counted lit that is not (the
 * shadow photons' "all direct" from the roof's top, through the single-quad roof: walls +18%
 * at photon seed 3 before side_filter_shadow, photon_sides.h), and no estimate of a few
 * photon paths lights the room (8 photons of 4 paths on the green wall: walls +12% at seed 4
 * before the distinct-paths rule, photon_sides.h "Sparse estimates"; the image was -51%, and
 * 25x before lookups kept to their side).
 * Twelve photon-mapping seeds (1-12; photon maps and samples both vary) against this reference:
 * whole image -1.62..+1.03%, patch -3.12..+2.01%, walls and ceiling -3.20..+3.97% (seeds 1-6:
 * -1.24..+1.03%, -2.60..+2.01%, -3.20..+3.97%; seed 1, the test's: +1.03%, +1.80%, +1.10%),
 * 20-23 CPU-s each. What is left is sampling noise, and the walls have the most: one standard
 * deviation of their mean is 2.0% over the twelve seeds (1.9% before the gather guide kept to
 * the opening's dark side, gather_guide.h WHO AIMS, when seeds 1-12 read -0.64..+5.48%: seed 3
 * +5.48%, and its maps under three more sample seeds +5.31, +1.74, -0.30%), three pixels of the
 * top row carry most of it (two see the lit big room through the hole, in a few hundredths of a
 * pixel; a quarter of the walls' light). Their mean over the twelve seeds is +0.67% (se 0.6%;
 * +1.65% before): no bias shows above the noise. Checked: without the shadow photons
 * (shadow=false) seeds 1-6 read -1.89..+3.60% (mean +1.0%), without the gather guide
 * -0.66..+4.79% (+1.0%); the pixels by the corner of the white and the red wall read about +6%
 * over those 21 renders, but path tracing itself moves them -1.2% and +5.4% against the
 * reference at 1M and 512K spp (a pixel's path-traced noise is still +-10% at 1M spp), so that
 * is not shown to be a bias either (these checks ran before the dark-side rule). The bounds then:
 * whole 5%, patch 5%, walls 5% (the target set for this scene); the walls' bound is 2.2 of
 * their standard deviations above their mean, so a new seed would land outside it about 1 time in 60 (a
 * normal law), and the test's seed 1 reads +1.10%.
 * AT 983b284 (the gathers aim at the found port and the direct light takes a ray through it:
 * gather_guide.h PORTS AS OPENINGS, direct.h THROUGH A PORT) seeds 1-12 read whole -4.54..-0.15%
 * (mean -1.93, sd 1.38), patch -3.30..-0.23% (mean -1.77, sd 0.97), walls -5.36..+1.94% (mean
 * -1.66, sd 2.20); seed 1, the test's: -0.15, -0.23, +0.57%. The patch's noise fell (sd 0.97
 * against about 2 before) and left an offset: every seed reads it low. It is the photon map's:
 * the patch's indirect light comes through the hole from the big room's precomputed
 * irradiance, and at 1,000,000 global photons (10x the 100,000 the plan stores here at the
 * defaults, half the 200,000 target; seeds 1-4) the patch
 * reads -0.62, +0.26, -0.27, +1.72% (mean +0.27%). Seed 7 reads whole -4.54% and walls -5.36%,
 * outside the 5% bounds: with the offset a new seed lands outside one about 1 time in 13 (a
 * normal law on these twelve; one of the twelve did), so
 * the fixed seed 1 keeps this a check of the estimators, and the spread is measured here by hand
 * (the 2% the issue asks for is not met over seeds).
 * AT 9ae7966 (the camera's focus, run/focus.h: the two top-row pixels that see the big room
 * through the hole aim half their samples at it) seeds 1-12 read whole -1.47..-0.16% (mean
 * -0.80), patch -1.69..-0.88% (mean -1.28), walls -1.20..+1.15% (mean +0.09); seed 1, the
 * test's: -0.66, -0.98, +0.25%. Every seed is within the 2%, so the bounds are 2%. The
 * patch keeps the photon map's offset above (-1.28% here), so a new seed would land outside
 * its bound now and then; the fixed seed keeps the test a check of the estimators. */
TEST(render_hard_pinhole_room_regions) {
    const region r[] = {{"whole image", 0, 0, 8, 8, 0.02},
                        {"lit patch", 2, 6, 6, 8, 0.02},
                        {"walls and ceiling", 0, 0, 8, 5, 0.02}};
    char scn[1024], ref[1024], pm[1024], cmd[4096], want[256] = "", got[256] = "";
    snprintf(scn, sizeof scn, "%s/data/scenes/pinhole_room.json", pm_test_source_dir());
    snprintf(ref, sizeof ref, "%s/data/reference-hard/pinhole_room.pfm", pm_test_source_dir());
    snprintf(pm, sizeof pm, "%s/pinhole_room_pm.pfm", pm_test_tmpdir());
    snprintf(cmd, sizeof cmd, "awk '$1 == \"scene_sha256\" { print $2 }' '%s/data/reference-hard/pinhole_room.info'",
             pm_test_source_dir());
    ASSERT_EQ_INT(pm_test_run(cmd, want, sizeof want), 0);
    snprintf(cmd, sizeof cmd, "sha256sum '%s' | cut -d' ' -f1", scn);
    ASSERT_EQ_INT(pm_test_run(cmd, got, sizeof got), 0);
    ASSERT_MSG(want[0] && strcmp(want, got) == 0, "%s changed since its reference was rendered (%s, now %s)", scn,
               want, got);
    ASSERT_EQ_INT(render_scene_at("pinhole_room", 8, "--mode pm --spp 16384 --pm gather_rays=1 --pm secondary_rays=1", pm), 0);
    film a, b;
    ASSERT_MSG(film_read_pfm(&a, ref) == 0, "cannot read %s", ref);
    ASSERT(a.width == 8 && a.height == 8 && film_read_pfm(&b, pm) == 0);
    for (int i = 0; i < 3; i++) {
        double ma = rt_rect_mean(&a, r[i].x0, r[i].y0, r[i].x1, r[i].y1);
        double mb = rt_rect_mean(&b, r[i].x0, r[i].y0, r[i].x1, r[i].y1);
        double rel = ma > 0 ? mb / ma - 1 : INFINITY;
        printf("    pinhole_room %s: reference %.5g pm %.5g (%+.2f%%, bound %.0f%%)\n", r[i].name, ma, mb, 100 * rel,
               100 * r[i].tol);
        EXPECT_MSG(fabs(rel) < r[i].tol, "pinhole_room %s: %+.2f%%", r[i].name, 100 * rel);
    }
    film_free(&a);
    film_free(&b);
}

/* Helper D's cage: a point light inside a closed box of nearly-mirror quads (specular 0.99999,
 * a trace of diffuse: caustic photons are stored on its inner faces), the box standing 0.5
 * above a floor. No light leaves the box, so the exact image is 0 (path tracing gives exactly
 * 0). The floor's caustic estimates found the photons on the box bottom's inner face, 0.5
 * above, facing up like the floor and travelling down, so the direction and normal rules let
 * them in: the image read 0.0094 (16x16, 16 spp, 20,000 caustic photons). Photon mapping must
 * stay below 1e-6 (measured 2.9e-10 with side_estimate, photon_sides.h). */
static const char *CAGE_SCENE =
    "{\"camera\": {\"eye\": [0, 3, -8], \"look_at\": [0, 1, 0], \"fov_deg\": 50, \"width\": 16, \"height\": 16},"
    " \"materials\": {\"mirror\": {\"type\": \"mix\", \"specular\": 0.99999, \"diffuse\": 0.5},"
    "  \"white\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
    " \"objects\": ["
    "  {\"type\": \"quad\", \"vertices\": [[-1, 0.5, -1], [1, 0.5, -1], [1, 0.5, 1], [-1, 0.5, 1]], \"material\": \"mirror\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-1, 2.5, -1], [-1, 2.5, 1], [1, 2.5, 1], [1, 2.5, -1]], \"material\": \"mirror\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-1, 0.5, -1], [-1, 2.5, -1], [1, 2.5, -1], [1, 0.5, -1]], \"material\": \"mirror\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-1, 0.5, 1], [1, 0.5, 1], [1, 2.5, 1], [-1, 2.5, 1]], \"material\": \"mirror\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-1, 0.5, -1], [-1, 0.5, 1], [-1, 2.5, 1], [-1, 2.5, -1]], \"material\": \"mirror\"},"
    "  {\"type\": \"quad\", \"vertices\": [[1, 0.5, -1], [1, 2.5, -1], [1, 2.5, 1], [1, 0.5, 1]], \"material\": \"mirror\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-5, 0, -5], [-5, 0, 5], [5, 0, 5], [5, 0, -5]], \"material\": \"white\"}],"
    " \"lights\": [{\"type\": \"point\", \"position\": [0, 1.5, 0], \"power\": 50}]}";

TEST(render_hard_caustic_cage_no_leak) {
    char scn[1024], pt[1024], pm[1024], cmd[4096], out[16384];
    snprintf(scn, sizeof scn, "%s/caustic_cage.json", pm_test_tmpdir());
    snprintf(pt, sizeof pt, "%s/caustic_cage_pt.pfm", pm_test_tmpdir());
    snprintf(pm, sizeof pm, "%s/caustic_cage_pm.pfm", pm_test_tmpdir());
    FILE *f = fopen(scn, "w");
    ASSERT(f != NULL);
    fputs(CAGE_SCENE, f);
    fclose(f);
    const char *flags[2] = {"--mode path --spp 16", "--mode pm --spp 16 --pm global=false --pm caustic_photons=20000"};
    const char *files[2] = {pt, pm};
    for (int i = 0; i < 2; i++) {
        snprintf(cmd, sizeof cmd, "%s/render '%s' --width 16 --height 16 --quiet --hdr '%s' %s 2>&1",
                 pm_test_build_dir(), scn, files[i], flags[i]);
        int rc = pm_test_run(cmd, out, sizeof out);
        ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    }
    film a, b;
    ASSERT(film_read_pfm(&a, pt) == 0 && film_read_pfm(&b, pm) == 0);
    double ma = rt_rect_mean(&a, 0, 0, 16, 16), mb = rt_rect_mean(&b, 0, 0, 16, 16);
    printf("    caustic cage: path %.3g, photon mapping %.3g (bound 1e-6)\n", ma, mb);
    EXPECT_MSG(ma == 0, "path tracing lights the outside of the cage: %g", ma);
    EXPECT_MSG(mb < 1e-6, "caustic photons leak out of the cage: %g", mb);
    film_free(&a);
    film_free(&b);
}

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
