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
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "test_render_run.h"
#include "image/film.h"
#include "photon_mapping/pm_sample.h"

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
        EXPECT_MSG(strstr(g_out, "  emission rays: 4x4 emission-only rays per sample at "), "%s", g_out);
    }
}

/* Explicit settings win: all three set, the pilot does not run and the line says so; one set,
 * every candidate keeps it. */
TEST(render_sample_explicit_settings_win) {
    int rc = run_pm("cornell_spheres", "-o a.png --pm gather_rays=3 --pm secondary_rays=2 --pm caustic_stride=3");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    char line[1024];
    EXPECT_MSG(strcmp(sample_line(line, sizeof line), "  sample: gather_rays 3, secondary_rays 2, caustic_stride 3, "
                                                         "miss_survival 1 (set by photon_mapping (or --pm))") == 0,
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
    const char *p = strstr(g_out, "  emission rays: 4x4 emission-only rays per sample at ");
    ASSERT_MSG(p && sscanf(p, "  emission rays: 4x4 emission-only rays per sample at %lu of %lu pixels", &marked,
                           &total) == 2, "%s", g_out);
    EXPECT_MSG(total == 256 && marked > 0 && marked < total, "cornell_box: %lu of %lu marked", marked, total);
    rc = run_pm("water_caustic", "-o w.png");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    p = strstr(g_out, "  emission rays: 4x4 emission-only rays per sample at ");
    ASSERT_MSG(p && sscanf(p, "  emission rays: 4x4 emission-only rays per sample at %lu of %lu pixels", &marked,
                           &total) == 2, "%s", g_out);
    EXPECT_MSG(total == 256 && marked == 0, "water_caustic: %lu of %lu marked", marked, total);
    /* and none are traced */
    p = strstr(g_out, "Emission-only camera rays");
    unsigned long long rays = 1;
    EXPECT_MSG(p && sscanf(p + strlen("Emission-only camera rays"), "%llu", &rays) == 1 && rays == 0, "%s",
               p ? p : g_out);
}

/* DIRECT STRATA (pm_sample.c): the extra rays take the first hit's direct light where the
 * probes find an edge of a delta light's light, at most 10% of the pixels. sun_window (the sun
 * through a window onto the floor: its patch's edges cross a few pixels) marks some, and the
 * extra rays run though the camera sees no emitter; lamp_shade (an area light) is refused with
 * the reason; cornell_point's point light edges too many of 16 x 16 pixels; emission_strata 0
 * turns the extra rays off. That the split keeps each pixel's mean is checked against the long
 * reference by render_hard_scenes_sun_window_regions (its sunlit patch within 2%: taking the
 * direct light from both parts would read it about twice, from neither about 0). */
TEST(render_sample_direct_rays_at_edges_of_delta_light) {
    ASSERT_MSG(run_pm("sun_window", "-o s.png") == 0, "%s", g_out);
    unsigned long marked = 0;
    const char *key = "they take the first hit's direct light too at ";
    const char *p = strstr(g_out, key);
    ASSERT_MSG(p && sscanf(p + strlen(key), "%lu pixels", &marked) == 1, "%s", g_out);
    EXPECT_MSG(marked > 0 && marked <= 25, "sun_window: %lu of 256 pixels marked (at most 10%%)", marked);
    p = strstr(g_out, "Emission-only camera rays");
    double rays = p ? strtod(p + strlen("Emission-only camera rays"), NULL) : 0;
    EXPECT_MSG(rays >= 16.0 * 16 * marked, "sun_window: %g extra rays for %lu marked pixels at 16 spp", rays, marked);
    ASSERT_MSG(run_pm("lamp_shade", "-o l.png") == 0, "%s", g_out);
    EXPECT_MSG(strstr(g_out, "the first hit's direct light from the sample's path (a light with an area"), "%s", g_out);
    ASSERT_MSG(run_pm("cornell_point", "-o c.png") == 0, "%s", g_out);
    EXPECT_MSG(strstr(g_out, "the first hit's direct light from the sample's path (the probes find an edge of it at "),
               "%s", g_out);
    EXPECT_MSG(strstr(g_out, "of 256 pixels, over 10%"), "%s", g_out);
    ASSERT_MSG(run_pm("sun_window", "-o z.png --pm emission_strata=0") == 0, "%s", g_out);
    EXPECT_MSG(!strstr(g_out, key) && strstr(g_out, "none (photon_mapping.emission_strata is 0)"), "%s", g_out);
    p = strstr(g_out, "Emission-only camera rays");
    EXPECT_MSG(p && strtod(p + strlen("Emission-only camera rays"), NULL) == 0, "%s", p ? p : g_out);
}

/* ---- the miss survival (pm_sample.c and photonmapper.c, MISS SURVIVAL) --------------------- */

/* A counter of the statistics in g_out ("    NAME   count"), or -1. */
static double counter(const char *name) {
    const char *p = strstr(g_out, name);
    return p ? strtod(p + strlen(name), NULL) : -1;
}

/* The pilot weighs the miss survival where a quarter or more of its lookups miss and keeps
 * it at 1 elsewhere, by the documented line: partition_thick (a sealed dark room, most lookups
 * miss and find no light) gets a survival below 1 from the candidates 1/2 and 1/4, with every
 * candidate's figures printed, and fewer secondary gather rays than the same render at 1;
 * cornell_box (no misses) 1, not weighed. A set value is kept and said to be; impossible ones
 * are refused with the key named. */
TEST(render_sample_miss_survival_by_the_pilot) {
    int rc = run_pm("partition_thick", "--threads 2 -o a.png");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    char line[1024];
    sample_line(line, sizeof line);
    const char *m = strstr(line, "; miss_survival ");
    double ms = -1, share = -1;
    ASSERT_MSG(m && sscanf(m, "; miss_survival %lf (%lf%% of the pilot's lookups find nothing on their side: lowest "
                              "variance x cost of 1 ", &ms, &share) == 2, "%s", line);
    EXPECT_MSG((ms == 0.5 || ms == 0.25) && share >= 25, "%s", line);
    EXPECT_MSG(strstr(m, ", 0.5 ") && strstr(m, ", 0.25 "), "%s", m);
    double sec = counter("Secondary gather rays"), miss = counter("Irradiance lookups finding nothing on their side");
    EXPECT_MSG(sec >= 0 && miss > 0, "%s", g_out);
    rc = run_pm("partition_thick", "--threads 2 -o b.png --pm miss_survival=1");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    EXPECT_MSG(strstr(sample_line(line, sizeof line), "; miss_survival 1 (set)"), "%s", line);
    double sec1 = counter("Secondary gather rays");
    printf("    partition_thick: miss_survival %g, %.0f secondary gather rays (%.0f at 1)\n", ms, sec, sec1);
    EXPECT_MSG(sec < 0.75 * sec1, "secondary gather rays %.0f at %g, %.0f at 1", sec, ms, sec1);
    rc = run_pm("cornell_box", "-o c.png");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    sample_line(line, sizeof line);
    EXPECT_MSG(strstr(line, "; miss_survival 1 (") && strstr(line, "under 25%: not weighed)"), "%s", line);
    const char *bad[] = {"0", "1.5", "-1", "nan"};
    for (int i = 0; i < 4; i++) {
        char extra[128];
        snprintf(extra, sizeof extra, "-o d.png --pm miss_survival=%s", bad[i]);
        rc = run_pm("cornell_box", extra);
        EXPECT_MSG(rc == 2 && strstr(g_out, "miss_survival"), "miss_survival=%s: exit %d: %s", bad[i], rc, g_out);
    }
}

/* Oracle: the furnace (radiance 2 everywhere, render_pm_furnace) with a starved global map (30
 * photons: most lookups miss, and the light is what the misses compute) renders the same
 * mean at miss survival 1/4 as at 1, both within 1% of 2: the roulette weights by 1/survival,
 * so the expected value is unchanged (at 32 x 32 x 64 the means differ by less than 0.1%
 * measured); at 1/4 the image is another one, the same bit for bit on 1 and 2 threads. There the survival buys less work with much more variance, and the pilot at its
 * defaults keeps 1 (variance x cost: 6.7 at 1, 13 at 1/2, 31 at 1/4 measured). */
TEST(render_pm_miss_survival_keeps_the_furnace) {
    const char *spp = PM_TEST_SANITIZED ? "16" : "64";
    double mean[3];
    const char *ms[3] = {"1", "0.25", "0.25"};
    const int threads[3] = {2, 2, 1}; /* the roulette's draws are the sample's own: any thread count */
    char pfm[3][1024];
    for (int i = 0; i < 3; i++) {
        char cmd[4096];
        snprintf(pfm[i], sizeof pfm[i], "%s/furnace_m%d.pfm", pm_test_tmpdir(), i);
        snprintf(cmd, sizeof cmd,
                 "timeout 300 '%s/render' '%s/data/scenes/furnace.json' --mode pm --spp %s --threads %d --quiet "
                 "--seed 3 --pm global_photons=30 --pm gather_rays=4 --pm secondary_rays=2 --pm miss_survival=%s "
                 "--hdr '%s' -o '%s/furnace_m%d.png'",
                 pm_test_build_dir(), pm_test_source_dir(), spp, threads[i], ms[i], pfm[i], pm_test_tmpdir(), i);
        int rc = rt_run(cmd, g_out, sizeof g_out);
        ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
        double look = counter("Irradiance lookups "), miss = counter("Irradiance lookups finding nothing on their side");
        EXPECT_MSG(look > 0 && miss > 0.5 * look, "lookups %.0f, misses %.0f: %s", look, miss, g_out);
        film f;
        ASSERT_EQ_INT(film_read_pfm(&f, pfm[i]), 0);
        double sum = 0;
        long n = (long)f.width * f.height;
        for (long k = 0; k < 3 * n; k++) sum += f.px[k];
        mean[i] = sum / (3.0 * n);
        film_free(&f);
    }
    printf("    starved furnace: mean %.5f at miss survival 1, %.5f at 1/4 (expected 2)\n", mean[0], mean[1]);
    EXPECT_NEAR(mean[0], 2.0, 0.02);
    EXPECT_NEAR(mean[1], 2.0, 0.02);
    EXPECT_NEAR(mean[1], mean[0], 0.01);
    EXPECT_MSG(rt_same_file(pfm[1], pfm[2]), "miss survival 1/4: 1 and 2 threads render different images");
    EXPECT_MSG(!rt_same_file(pfm[0], pfm[1]), "miss survival 1/4 renders the image of 1: the setting is not applied");
    char cmd[4096];
    snprintf(cmd, sizeof cmd,
             "timeout 300 '%s/render' '%s/data/scenes/furnace.json' --mode pm --spp 4 --threads 2 --quiet --seed 3 "
             "--pm global_photons=30 -o '%s/furnace_d.png'",
             pm_test_build_dir(), pm_test_source_dir(), pm_test_tmpdir());
    ASSERT_EQ_INT(rt_run(cmd, g_out, sizeof g_out), 0);
    char line[1024];
    sample_line(line, sizeof line);
    EXPECT_MSG(strstr(line, "; miss_survival 1 (") && strstr(line, "lowest variance x cost of 1 "), "%s", line);
}

/* ---- pass 0's photons fitted to the render (pm_fit.c, PASS 0'S PHOTONS) ------------------- */

/* render data/scenes/cornell_box.json --mode pm at its photon defaults (no count given). */
static int run_box_defaults(const char *args) {
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "timeout 300 '%s/render' '%s/data/scenes/cornell_box.json' --mode pm --quiet --seed 5 %s",
             pm_test_build_dir(), pm_test_source_dir(), args);
    return rt_run(cmd, g_out, sizeof g_out);
}

static double after(const char *text, const char *key) {
    const char *p = text ? strstr(text, key) : NULL;
    return p ? strtod(p + strlen(key), NULL) : -1;
}

/* PRECOMPUTED POINTS FITTED TO THE RENDER (pm_fit.c) in g_out's "Precomputed irradiance" line:
 * at the photons of height >= h of a balanced tree of G (one a bucket: floor(G / 2^h) of them),
 * h the lowest in [2, hmax] (hmax as printed) whose floor(G / 2^h) estimates are at most 0.2 x
 * the printed camera work / 800; want: the h expected. 1 if all holds (failures recorded). */
static int precomputed_points_by_the_rule(int want) {
    const char *l = strstr(g_out, "\nPrecomputed irradiance at ");
    double n = -1, g = -1;
    EXPECT_MSG(l && sscanf(l, "\nPrecomputed irradiance at %lf of %lf global photons", &n, &g) == 2, "%s", g_out);
    if (!l) return 0;
    double h = after(l, "(the photons of height >= "), hmax = after(l, "in the map's kd-tree, 2 to ");
    double wr = after(l, "of the camera samples' ");
    EXPECT_MSG(h >= 2 && hmax >= h && wr > 0, "%.500s", l);
    int rule = 2;
    while (rule < hmax && floor(g / ldexp(1, rule)) > 0.2 * wr / 800) rule++;
    EXPECT_MSG(rule == (int)h && rule == want, "height %g printed, %d by the rule, %d expected: %.500s", h, rule, want, l);
    EXPECT_MSG(n == floor(g / ldexp(1, (int)h)), "%g points of %g at height %g", n, g, h);
    return rule == (int)h && rule == want && n == floor(g / ldexp(1, (int)h));
}

/* Oracle: the documented rule applied to the counted work the "photons:" line prints:
 * s = clamp(0.2 W_r / W_p, 1/2, ceiling), the ceiling 1 + 3 clamp((q - 0.1) / 0.15, 0, 1) from the
 * caustic map's printed share q of the luminance, traced again when s > 1.25 / 2, else the first stage's
 * half stays (3 significant digits printed: relative 5e-3); the "Photons:" line's global
 * count is s x 200,000 (+ at most one photon path's stores). A small render keeps the half,
 * a render of about 800 times the camera samples traces again; the same line for 1 and 2 threads
 * (counted work, never timed); a count given with --pm is traced as given and the line says
 * why; a render in passes fits pass 0 to one pass, and a later pass traces its printed
 * fraction of the settings' targets. Also the precomputed irradiance's points by their rule
 * (precomputed_points_by_the_rule: an eighth at 16 x 16 x 16, the quarter at 40 x 40 x 2025,
 * the quarter without a fit) and the fitted render's image bit for bit on 1 and 2 threads. */
TEST(render_pm_fit_photons_to_the_render) {
    static const char *runs[] = {"--width 16 --height 16 --spp 16 --threads 1 -o a.png --hdr r0.pfm",
                                 "--width 16 --height 16 --spp 16 --threads 2 -o a.png --hdr r1.pfm",
                                 "--width 40 --height 40 --spp 2025 --threads 2 -o a.png"};
    char first[1024] = "";
    for (int r = 0; r < 3; r++) {
        ASSERT_MSG(run_box_defaults(runs[r]) == 0, "%s: %s", runs[r], g_out);
        const char *l = strstr(g_out, "  photons: ");
        ASSERT_MSG(l, "no photons line: %s", g_out);
        double s = after(l, "  photons: "), wp = after(l, "the targets' photons "), wr = after(l, "camera samples ");
        ASSERT_MSG(s > 0 && wp > 0 && wr > 0, "%.300s", l);
        /* the ceiling from the caustic map's printed share of the luminance (cornell_box: none, so 1) */
        double q = after(l, "(the caustic map carries ") / 100, t = fmin(1, fmax(0, (q - 0.10) / 0.15));
        double ceil = after(l, ": ceiling ");
        EXPECT_MSG(fabs(ceil - (1 + 3 * t)) <= 5e-3 * ceil, "%s: ceiling %g at a caustic share %g", runs[r], ceil, q);
        double rule = fmin(ceil, fmax(0.5, 0.2 * wr / wp));
        int again = rule > 1.25 * 0.5;
        if (!again) rule = 0.5;
        EXPECT_MSG(fabs(s - rule) <= 5e-3 * rule, "%s: s %g, the rule gives %g (W_p %g, W_r %g)", runs[r], s, rule, wp, wr);
        EXPECT_MSG(strstr(l, again ? "; traced again" : "; the first stage's maps kept") != NULL, "%s: %.400s", runs[r], l);
        EXPECT_MSG(r < 2 ? !again : again, "%s: the fit %s (s %g)", runs[r], again ? "traced again" : "kept the first stage", s);
        double g = after(g_out, "\nPhotons: ");
        EXPECT_MSG(g >= 200000 * s * (1 - 5e-3) - 1 && g <= 200000 * s * (1 + 5e-3) + 64, "%s: %g global photons at s %g",
                   runs[r], g, s);
        EXPECT_MSG(precomputed_points_by_the_rule(r < 2 ? 3 : 2), "%s", runs[r]);
        size_t n = strcspn(l, "\n");
        if (r == 0) snprintf(first, sizeof first, "%.*s", (int)n, l);
        if (r == 1) EXPECT_MSG(strlen(first) == n && strncmp(first, l, n) == 0, "1 thread: %s\n2 threads: %.*s", first, (int)n, l);
    }
    /* PRECOMPUTED POINTS FITTED TO THE RENDER: the same image on 1 and 2 threads */
    EXPECT_MSG(rt_same_file("r0.pfm", "r1.pfm"), "the fitted render's image differs on 1 and 2 threads");
    ASSERT_MSG(run_box_defaults("--width 16 --height 16 --spp 16 --pm global_photons=20000 -o a.png") == 0, "%s", g_out);
    EXPECT_MSG(strstr(g_out, "  photons: the targets (photon_mapping.global_photons is set)") != NULL, "%s", g_out);
    double n0 = after(g_out, "\nPrecomputed irradiance at "), g0 = after(strstr(g_out, "\nPrecomputed irradiance at "), " of ");
    EXPECT_MSG(g0 >= 20000 && g0 <= 20064 && n0 == floor(g0 / 4) && !strstr(g_out, "of them (the photons of height"),
               "counts set: the quarter, no fit: %s", g_out);
    EXPECT_MSG(after(g_out, "\nPhotons: ") >= 20000 && after(g_out, "\nPhotons: ") <= 20064, "%s", g_out);
    /* a render in passes: pass 0 fitted to one pass's camera samples (the half, here); a later
     * pass's photons are its printed fraction of the settings' targets, not of pass 0's half */
    ASSERT_MSG(run_box_defaults("--width 16 --height 16 --passes 2 --pass-spp 4 -o a.png") == 0, "%s", g_out);
    EXPECT_MSG(strstr(g_out, "  photons: 0.5 x the targets (global 200000,") != NULL, "%s", g_out);
    EXPECT_MSG(after(g_out, "\nPass 0: photons ") >= 100000 && after(g_out, "\nPass 0: photons ") <= 100064, "%s", g_out);
    const char *p1 = strstr(g_out, "\nPass 1: photons ");
    ASSERT_MSG(p1, "%s", g_out);
    const char *ft = strstr(p1, " of the photon targets");
    ASSERT_MSG(ft, "%.300s", p1);
    while (ft > p1 && ft[-1] != ' ') ft--; /* back to the fraction's first digit */
    double g1 = after(p1, "\nPass 1: photons "), f1 = strtod(ft, NULL);
    EXPECT_MSG(f1 > 0 && f1 <= 1 && g1 >= 200000 * f1 * (1 - 5e-3) - 1 && g1 <= 200000 * f1 * (1 + 5e-3) + 64,
               "pass 1: %g global photons at f %g of the targets: %.300s", g1, f1, p1);
}

/* render data/scenes/NAME.json --mode pm at 24x24, 4 spp, seed 5, with ARGS. */
static int run_small(const char *name, const char *args) {
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "timeout 300 '%s/render' '%s/data/scenes/%s.json' --mode pm --width 24 --height 24 "
             "--spp 4 --threads 2 --seed 5 %s -o a.png", pm_test_build_dir(), pm_test_source_dir(), name, args);
    return rt_run(cmd, g_out, sizeof g_out);
}

/* The "Photons:" line's counts: global stored and emitted, caustic stored and emitted. */
static int photons_line(double v[4]) {
    const char *p = strstr(g_out, "\nPhotons: ");
    return p && sscanf(p, "\nPhotons: %lf global, %*u shadow-map (from %lf emitted); %lf caustic (from %lf emitted",
                       &v[0], &v[1], &v[2], &v[3]) == 4;
}

/* THE CAUSTIC FLOOR (pm_fit.c). Oracle: the rule and the renderer's own maps. The first stage
 * traces the caustic map at 1/8 of its target; the fit scales it by s_c = k x 0.2 W_r / W_p (k 1
 * where the map carries under 10% of the pilot's luminance, 2 where it carries more: its photons
 * at 0.4 of the camera samples' work), within [1/8, the global maps' scale], and keeps the first
 * stage's map when s_c <= 1.25 / 8. Cases: cornell_spheres (under 10%, 24 x 24 x 484) and
 * water_caustic (over, 24 x 24 x 400) keep 62,500 photons (at these sizes the camera samples,
 * 278,784 and 230,400, exceed the first stage's caustic emissions, 255,082 and 206,180, so
 * pm_preprocess.c's CAUSTIC PROBE does not cap them: render_pm_caustic_cap_at_the_defaults_only
 * checks it); water_caustic at 24 x 24 x 576 traces its caustic map
 * again, alone, at s_c = 2 x 0.2 W_r / W_p of the target (about 0.19; W_r and W_p as printed,
 * 3 significant digits: relative 1.5%). In every case the maps are exactly those a render given
 * global_photons=100000 and that caustic count stores and emits (the same count, emitted photons
 * and statistics counter: the first stage's caustic photons are taken back out of the counters
 * and the retrace traces the photons a whole trace does). Control: the emitted counts of the
 * 62,500 and the retraced map differ (the comparison can fail). */
TEST(render_pm_caustic_floor_where_the_map_carries_little) {
    static const struct {
        const char *name, *spp;
        double k; /* 1: under 10% of the luminance, 2: at least 10% */
        int again;
    } cases[] = {{"cornell_spheres", "--spp 484", 1, 0},
                 {"water_caustic", "--spp 400", 2, 0},
                 {"water_caustic", "--spp 576", 2, 1}};
    double caustic_emitted[3] = {0, 0, 0};
    for (int i = 0; i < 3; i++) {
        double a[4], b[4];
        const char *nm = cases[i].name;
        ASSERT_MSG(run_small(nm, cases[i].spp) == 0, "%s: %s", nm, g_out);
        const char *l = strstr(g_out, "  photons: ");
        ASSERT_MSG(l && photons_line(a), "%s: %s", nm, g_out);
        double q = after(l, "(the caustic map carries ") / 100;
        EXPECT_MSG(cases[i].k == 1 ? q < 0.10 : q >= 0.10, "%s: caustic share %g", nm, q);
        double wp = after(l, "counted work of the targets' photons "), wr = after(l, " camera samples ");
        double sc = cases[i].k * 0.2 * wr / wp, want = cases[i].again ? llround(500000 * sc) : 62500;
        EXPECT_MSG(cases[i].again ? sc > 1.25 / 8 && sc < 0.5 : sc <= 1.25 / 8, "%s %s: s_c %g", nm, cases[i].spp, sc);
        EXPECT_MSG(strstr(l, cases[i].k == 1 ? "(at 0.2 of the camera samples' work: it carries under 10%"
                                             : "(at 0.4 of the camera samples' work: it carries at least 10%"),
                   "%s: %.700s", nm, l);
        EXPECT_MSG(strstr(l, cases[i].again ? "; the caustic map traced again" : "; the first stage's maps kept"),
                   "%s: %.700s", nm, l);
        EXPECT_MSG(fabs(a[2] - want) <= 0.015 * want, "%s %s: %g caustic photons, the rule %g", nm, cases[i].spp, a[2],
                   want);
        double counter = after(strstr(g_out, "Emitted, caustic pass"), "Emitted, caustic pass");
        char given[128];
        snprintf(given, sizeof given, "--pm global_photons=100000 --pm caustic_photons=%.0f", a[2]);
        ASSERT_MSG(run_small(nm, given) == 0, "%s: %s", nm, g_out);
        ASSERT_MSG(photons_line(b), "%s: %s", nm, g_out);
        double counter_given = after(strstr(g_out, "Emitted, caustic pass"), "Emitted, caustic pass");
        EXPECT_MSG(a[0] == b[0] && a[1] == b[1] && a[2] == b[2] && a[3] == b[3],
                   "%s: defaults %g global from %g, %g caustic from %g; given %g from %g, %g from %g", nm, a[0],
                   a[1], a[2], a[3], b[0], b[1], b[2], b[3]);
        EXPECT_MSG(counter > 0 && counter == counter_given, "%s: caustic pass emitted counter %g, given %g", nm,
                   counter, counter_given);
        caustic_emitted[i] = a[3];
    }
    EXPECT(caustic_emitted[1] != caustic_emitted[2]);
}

/* Caustics at a stride (pm_sample.h, CAUSTICS AT A STRIDE): for every strata S (1 to 20) and
 * stride c (1 to 5), at every pixel offset, the weights of a pixel's n = S^2 samples sum to n
 * exactly (the old lattice, which chose (S mod c) more columns at some offsets, fails this for
 * S = 4, c = 3: sums 36, 18, 9 instead of 16), exactly m = pm_caustic_reads(S, c) samples are
 * read, one in each block, weighted by its block's area; over the offsets each sample is chosen
 * equally often: its mean weight is 1 (the estimate stays unbiased); and pm_caustic_factor is
 * sum(weight^2) / n over a pixel's reads (c^2 when c divides S). Oracle: the blocks rebuilt here
 * from their definition, m = round(S / c), edges floor(i S / m). Offsets: u, v on a P x P grid,
 * P the least common multiple of the block widths, which reaches every offset equally often. */
static int stride_block_of(int S, int m, int x, int *w) {
    for (int i = 0; i < m; i++) {
        int lo = i * S / m, hi = (i + 1) * S / m;
        if (x >= lo && x < hi) {
            *w = hi - lo;
            return i;
        }
    }
    return -1;
}

TEST(render_pm_caustic_stride_weights_sum_exactly) {
    static double mean[400];
    for (int S = 1; S <= 20; S++)
        for (int c = 1; c <= 5; c++) {
            int n = S * S, bad = 0, strided = c > 1 && S >= c;
            int m = strided ? (int)lround((double)S / c) : S;
            if (m < 1) m = 1;
            int P = 1, wx = 1, wy = 1;
            for (int x = 0; x < S; x++) {
                stride_block_of(S, m, x, &wx);
                int a = P, b = wx;
                while (b) { int t = a % b; a = b; b = t; }
                P = P / a * wx;
            }
            ASSERT_EQ_INT(pm_caustic_reads(S, c), strided ? m * m : n);
            if (strided && S % c == 0) ASSERT_EQ_INT(m, S / c);
            for (int k = 0; k < n; k++) mean[k] = 0;
            double factor = -1;
            for (int i = 0; i < P; i++)
                for (int j = 0; j < P; j++) {
                    double u = (i + 0.5) / P, v = (j + 0.5) / P, sum = 0, sq = 0;
                    int chosen = 0, per_block[400] = {0};
                    for (int k = 0; k < n; k++) {
                        double w = pm_caustic_weight(S, c, k, u, v);
                        int bx = stride_block_of(S, m, k % S, &wx), by = stride_block_of(S, m, k / S, &wy);
                        double expect = strided ? (double)wx * wy : 1.0;
                        if (w != 0 && w != expect) bad++;
                        if (w != 0) per_block[strided ? by * m + bx : k]++;
                        chosen += w != 0;
                        sum += w;
                        sq += w * w;
                        mean[k] += w;
                    }
                    for (int b = 0; b < (strided ? m * m : n); b++) bad += per_block[b] != 1;
                    if (fabs(sum - n) > 1e-9 * n || chosen != pm_caustic_reads(S, c)) bad++;
                    if (factor < 0) factor = sq / n;
                    else if (fabs(factor - sq / n) > 1e-12 * factor) bad++;
                }
            double worst = 0;
            for (int k = 0; k < n; k++) worst = fmax(worst, fabs(mean[k] / ((double)P * P) - 1));
            ASSERT_MSG(!bad && worst <= 1e-9, "S %d c %d: %d bad pixels or weights, mean weight off by %g", S,
                       c, bad, worst);
            EXPECT_MSG(fabs(pm_caustic_factor(S, c) - factor) <= 1e-12 * factor, "S %d c %d: factor %g, weights %g",
                       S, c, pm_caustic_factor(S, c), factor);
            if (strided && S % c == 0) EXPECT_MSG(fabs(factor - (double)c * c) <= 1e-12, "S %d c %d: factor %g", S, c, factor);
        }
}
