/* test_render_sample.c: the photon mapper's per-sample work as its preprocess decides it
 * (render/photon_mapping/pm_sample.c: THE SAMPLE PILOT and pm_emission_mask_build): the plan
 * lines "sample:" and "emission rays:".
 *
 * Oracles: the documented candidates and line format; an explicit setting is kept (printed
 * as set, and the pilot does not run); the choice is applied (rendering with the printed
 * choice set explicitly gives the same image, byte for byte); the choice is deterministic
 * (the same line and image for 1 and 2 threads, and from run to run); the emission mask marks
 * pixels only where the camera can see an emitter (cornell_box sees its light, water_caustic's
 * camera does not see its light). Small renders (16x16), no timing.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "test_render_run.h"

static char g_out[1 << 16];

/* render data/scenes/NAME.json --mode pm at 16x16, in the test directory. */
static int run_pm(const char *name, const char *extra) {
    char cmd[4096];
    snprintf(cmd, sizeof cmd,
             "timeout 300 '%s/render' '%s/data/scenes/%s.json' --mode pm --width 16 --height 16 --spp 16 "
             "--quiet --seed 5 --pm global_photons=20000 --pm caustic_photons=20000 %s",
             pm_test_build_dir(), pm_test_source_dir(), name, extra);
    return rt_run(cmd, g_out, sizeof g_out);
}

/* The "  sample: " line of the last run (copied), or "" */
static const char *sample_line(char *buf, size_t cap) {
    const char *p = strstr(g_out, "  sample: ");
    size_t n = p ? strcspn(p, "\n") : 0;
    snprintf(buf, cap, "%.*s", (int)n, p ? p : "");
    return buf;
}

/* The pilot's choice is printed with its figures and is one of the documented candidates. */
TEST(render_sample_pilot_prints_its_choice) {
    const char *scenes[] = {"cornell_box", "cornell_spheres"};
    for (int i = 0; i < 2; i++) {
        int rc = run_pm(scenes[i], "-o a.png");
        ASSERT_MSG(rc == 0, "%s: exit %d: %s", scenes[i], rc, g_out);
        char line[1024];
        sample_line(line, sizeof line);
        int g = 0, s = 0, c = 0;
        ASSERT_MSG(sscanf(line, "  sample: gather_rays %d, secondary_rays %d, caustic_stride %d (pilot of ", &g, &s,
                          &c) == 3 && strstr(line, "(pilot of 1024 camera samples at 256 pixels: lowest variance x cost of"),
                   "%s: %s", scenes[i], line);
        EXPECT_MSG((g == 1 && s == 1) || (g == 2 && s == 1) || (g == 4 && s == 2), "%s: %s", scenes[i], line);
        EXPECT_MSG(c >= 1 && c <= 4, "%s: %s", scenes[i], line);
        /* every candidate's figures are printed */
        EXPECT_MSG(strstr(line, " 1/1/") && strstr(line, " 2/1/") && strstr(line, " 4/2/"), "%s", line);
        EXPECT_MSG(strstr(g_out, "  emission rays: 2x2 emission-only rays per sample at "), "%s", g_out);
    }
}

/* Explicit settings win: all three set, the pilot does not run and the line says so; one set,
 * every candidate keeps it. */
TEST(render_sample_explicit_settings_win) {
    int rc = run_pm("cornell_spheres", "-o a.png --pm gather_rays=3 --pm secondary_rays=2 --pm caustic_stride=3");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    char line[1024];
    EXPECT_MSG(strcmp(sample_line(line, sizeof line), "  sample: gather_rays 3, secondary_rays 2, caustic_stride 3 "
                                                         "(set by photon_mapping (or --pm))") == 0,
               "%s", line);
    rc = run_pm("cornell_box", "-o b.png --pm gather_rays=3");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    sample_line(line, sizeof line);
    EXPECT_MSG(strncmp(line, "  sample: gather_rays 3, ", 25) == 0 && strstr(line, " 3/1/") && strstr(line, " 3/2/") &&
                   !strstr(line, " 1/1/"),
               "%s", line);
}

/* The choice is applied and deterministic: the printed choice, set explicitly, renders the same
 * image; 1 and 2 threads print the same line and render the same image. */
TEST(render_sample_choice_applied_and_deterministic) {
    int rc = run_pm("cornell_spheres", "--threads 1 --hdr t1.pfm -o t1.png");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    char l1[1024], l2[1024];
    sample_line(l1, sizeof l1);
    int g = 0, s = 0, c = 0;
    ASSERT_MSG(sscanf(l1, "  sample: gather_rays %d, secondary_rays %d, caustic_stride %d", &g, &s, &c) == 3, "%s", l1);
    rc = run_pm("cornell_spheres", "--threads 2 --hdr t2.pfm -o t2.png");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    EXPECT_MSG(strcmp(sample_line(l2, sizeof l2), l1) == 0, "1 thread: %s\n2 threads: %s", l1, l2);
    EXPECT_MSG(rt_same_file("t1.pfm", "t2.pfm"), "1 and 2 threads render different images");
    char extra[512];
    snprintf(extra, sizeof extra, "--threads 2 --hdr e.pfm -o e.png --pm gather_rays=%d --pm secondary_rays=%d "
             "--pm caustic_stride=%d", g, s, c);
    rc = run_pm("cornell_spheres", extra);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    EXPECT_MSG(strstr(g_out, "(set by photon_mapping (or --pm))"), "%s", g_out);
    EXPECT_MSG(rt_same_file("t1.pfm", "e.pfm"), "the printed choice set explicitly renders another image");
}

/* Emission-only rays where the camera sees an emitter: cornell_box's camera sees its ceiling
 * light (some pixels marked, not all); water_caustic's camera looks down at the floor and
 * never sees its light (none marked). */
TEST(render_sample_emission_rays_where_emitters_are_seen) {
    int rc = run_pm("cornell_box", "-o a.png");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    unsigned long marked = 0, total = 0;
    const char *p = strstr(g_out, "  emission rays: 2x2 emission-only rays per sample at ");
    ASSERT_MSG(p && sscanf(p, "  emission rays: 2x2 emission-only rays per sample at %lu of %lu pixels", &marked,
                           &total) == 2, "%s", g_out);
    EXPECT_MSG(total == 256 && marked > 0 && marked < total, "cornell_box: %lu of %lu marked", marked, total);
    rc = run_pm("water_caustic", "-o w.png");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    p = strstr(g_out, "  emission rays: 2x2 emission-only rays per sample at ");
    ASSERT_MSG(p && sscanf(p, "  emission rays: 2x2 emission-only rays per sample at %lu of %lu pixels", &marked,
                           &total) == 2, "%s", g_out);
    EXPECT_MSG(total == 256 && marked == 0, "water_caustic: %lu of %lu marked", marked, total);
    /* and none are traced */
    p = strstr(g_out, "Emission-only camera rays");
    unsigned long long rays = 1;
    EXPECT_MSG(p && sscanf(p + strlen("Emission-only camera rays"), "%llu", &rays) == 1 && rays == 0, "%s",
               p ? p : g_out);
}
