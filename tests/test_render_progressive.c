/* test_render_progressive.c: rendering in passes (render --time, --passes; run/passes.h) and
 * progressive photon mapping (photonmapper.c, mapper_begin_pass).
 *
 * Oracles: the furnace's analytic radiance (L = Le / (1 - rho) = 2 everywhere), within a
 * tolerance from the spread of the pass images (a t bound that shrinks as 1/sqrt(passes));
 * the radius schedule's recurrence r^2_{i+1} = r^2_i (i + alpha) / (i + 1), computed here
 * step by step; the documented mean of the pass images, computed here from passes rendered
 * one at a time (--only-pass) and compared bit for bit; an uninterrupted render, against which
 * a resumed one and one at another thread count must be bit-identical; the budget rule
 * (elapsed <= budget + the longest pass, from the counts the program prints, never a speed);
 * and the documented refusals (exit 2 with a message naming the option or field).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "test.h"
#include "../photonmap/common.h"
#include "../render/base/hash.h"
#include "../render/image/film.h"
#include "../render/run/checkpoint.h"
#include "../render/run/passes.h"
#include "test_render_run.h"

#define FURNACE_PM                                                                         \
    "'%s/data/scenes/furnace.json' --mode pm --pm global_photons=20000 --width 8 --height 8 " \
    "--pass-spp 4"
#define BOX_PM_SCENE                                                                       \
    "'%s/data/scenes/cornell_spheres.json' --mode pm --pm global_photons=8000 --pm "       \
    "caustic_photons=8000 --width 16 --height 16"
#define BOX_PM BOX_PM_SCENE " --pass-spp 4"

/* The number after key in text (the first occurrence after from), or NAN. */
static double num_after(const char *text, const char *key) {
    const char *p = strstr(text, key);
    return p ? strtod(p + strlen(key), NULL) : NAN;
}

/* cornell_box.json with a "render" object holding `keys` (JSON members), as name in the test
 * directory. 0 or -1. */
static int write_box_with_render(const char *name, const char *keys) {
    char src[1024];
    snprintf(src, sizeof src, "%s/data/scenes/cornell_box.json", pm_test_source_dir());
    size_t n;
    char *text = rt_slurp(src, &n);
    char *brace = text ? strchr(text, '{') : NULL;
    FILE *f = brace ? fopen(rt_path(name), "wb") : NULL;
    if (!f) {
        free(text);
        return -1;
    }
    fprintf(f, "{\"render\": {%s},%s", keys, brace + 1);
    fclose(f);
    free(text);
    return 0;
}

/* The mean over pixels and channels of a PFM in the test directory, or NAN. */
static double pfm_mean(const char *name) {
    film f;
    if (film_read_pfm(&f, rt_path(name)) < 0) return NAN;
    double m = 0;
    size_t n = (size_t)f.width * (size_t)f.height * 3;
    for (size_t i = 0; i < n; i++) m += f.px[i];
    film_free(&f);
    return m / (double)n;
}

/* Oracle: (a) the analytic furnace value 2 and (c) the documented mean. Six passes of
 * progressive photon mapping rendered one at a time (--only-pass p) and all together
 * (--passes 6): the whole render's PFM is, bit for bit, (float)(sum_p (double)image_p / 6)
 * summed in pass order; and its mean radiance is within t * s / sqrt(6) of 2, where s is the
 * spread of the six passes' image means and t = 6.87 the two-sided 99.9% point of Student's t
 * with 5 degrees of freedom (a bound that shrinks with the passes; the photon maps of one pass
 * are shared by all its pixels, so the passes, not the pixels, are the independent samples).
 * Passes 1..5 differ from pass 0 (fresh photons), so the mean is not one image repeated. */
TEST(render_progressive_furnace_converges_and_mean_of_passes) {
    enum { P = 6 };
    char out[32768], args[512];
    film img[P];
    double means[P];
    for (int p = 0; p < P; p++) {
        snprintf(args, sizeof args, "--only-pass %d --threads 2 --quiet --hdr p%d.pfm -o p%d.png", p, p, p);
        ASSERT_MSG(rt_render(FURNACE_PM, args, out, sizeof out) == 0, "%s", out);
    }
    for (int p = 0; p < P; p++) {
        char name[32];
        snprintf(name, sizeof name, "p%d.pfm", p);
        ASSERT(film_read_pfm(&img[p], rt_path(name)) == 0);
        means[p] = pfm_mean(name);
    }
    /* --adaptive 0: a pass rendered alone has no adaptive samples (run/passes.h) */
    ASSERT_MSG(rt_render(FURNACE_PM, "--passes 6 --adaptive 0 --threads 2 --quiet --hdr all.pfm -o all.png", out,
                         sizeof out) == 0, "%s", out);
    film all;
    ASSERT(film_read_pfm(&all, rt_path("all.pfm")) == 0);
    size_t n = (size_t)all.width * (size_t)all.height * 3, mismatched = 0;
    for (size_t i = 0; i < n; i++) {
        double sum = 0;
        for (int p = 0; p < P; p++) sum += (double)img[p].px[i];
        float want = (float)(sum / P);
        mismatched += memcmp(&want, &all.px[i], sizeof want) != 0;
    }
    EXPECT_MSG(mismatched == 0, "%zu of %zu values differ from the mean of the passes", mismatched, n);
    EXPECT_MSG(memcmp(img[0].px, img[1].px, n * sizeof(float)) != 0, "pass 1 repeats pass 0");
    double m = 0, s2 = 0;
    for (int p = 0; p < P; p++) m += means[p] / P;
    for (int p = 0; p < P; p++) s2 += (means[p] - m) * (means[p] - m) / (P - 1);
    double tol = 6.87 * sqrt(s2 / P);
    double got = pfm_mean("all.pfm");
    EXPECT_MSG(tol > 0 && fabs(got - 2.0) <= tol, "furnace mean %.6f, expected 2 within %.6f", got, tol);
    printf("    furnace: mean of 6 passes %.6f (pass means' spread %.3g, tolerance %.3g)\n", got,
           sqrt(s2), tol);
    for (int p = 0; p < P; p++) film_free(&img[p]);
    film_free(&all);
}

/* Oracle: the recurrence r^2_{i+1} = r^2_i (i + alpha) / (i + 1), i = 1 for the first pass
 * (Knaus and Zwicker 2011), stepped here from the r^2 pass 0 prints, against the r^2 of the
 * global and caustic estimates each pass prints, to float precision (the searches take r^2 as
 * a float: relative 2^-23, so 1e-6), for the default alpha 2/3 and for ppm_alpha=0.4; and the
 * lookup's r^2, pass 0's times the same factor to the power ppm_lookup_shrink (default 3, and
 * 1.5 set). */
TEST(render_progressive_radius_schedule) {
    static const struct {
        const char *extra;
        double alpha, shrink;
    } cases[] = {{"", 2.0 / 3.0, 3}, {"--pm ppm_alpha=0.4", 0.4, 3}, {"--pm ppm_lookup_shrink=1.5", 2.0 / 3.0, 1.5}};
    char out[65536], args[512];
    for (int c = 0; c < 3; c++) {
        snprintf(args, sizeof args, "--passes 5 --threads 2 --quiet --hdr r.pfm -o r.png %s", cases[c].extra);
        ASSERT_MSG(rt_render(BOX_PM, args, out, sizeof out) == 0, "%s", out);
        const char *p0 = strstr(out, "Pass 0: ");
        ASSERT_MSG(p0 && strstr(p0, "r^2 global "), "no pass line: %s", out);
        double g = num_after(p0, "r^2 global "), k = num_after(strstr(p0, "r^2 global "), "caustic ");
        double l0 = num_after(strstr(p0, "r^2 global "), "lookup "), f = 1;
        ASSERT(g > 0 && k > 0 && l0 > 0 && isfinite(g) && isfinite(k) && isfinite(l0));
        for (int i = 1; i < 5; i++) {
            g *= (i + cases[c].alpha) / (i + 1);
            k *= (i + cases[c].alpha) / (i + 1);
            f *= (i + cases[c].alpha) / (i + 1);
            double l = l0 * pow(f, cases[c].shrink);
            char key[32];
            snprintf(key, sizeof key, "Pass %d: ", i);
            const char *pl = strstr(out, key);
            ASSERT_MSG(pl, "no line for pass %d", i);
            const char *r2 = strstr(pl, "r^2 global ");
            ASSERT(r2);
            double rg = num_after(r2, "r^2 global "), rc = num_after(r2, "caustic "), rl = num_after(r2, "lookup ");
            EXPECT_MSG(fabs(rg - g) <= 1e-6 * g, "alpha %g pass %d: global r^2 %.9g, expected %.9g",
                       cases[c].alpha, i, rg, g);
            EXPECT_MSG(fabs(rc - k) <= 1e-6 * k, "alpha %g pass %d: caustic r^2 %.9g, expected %.9g",
                       cases[c].alpha, i, rc, k);
            EXPECT_MSG(fabs(rl - l) <= 1e-6 * l, "alpha %g shrink %g pass %d: lookup r^2 %.9g, expected %.9g",
                       cases[c].alpha, cases[c].shrink, i, rl, l);
        }
    }
}

/* Oracle: ppm_radius's definition and the schedule of the volume maps. In the fog room with
 * ppm_radius=0.5, pass 0's global r^2 is (0.5 x the typical radius)^2, the typical radius
 * being what the plain render prints as the secondary-gather distance (4 significant digits:
 * relative 2e-3), and below the maximum radius it prints; the volume map's r^2 follows the
 * same recurrence as the surface maps (float precision); and the render checkpointed after
 * 1 pass and resumed to 3 is the 3 passes' image byte for byte. */
TEST(render_progressive_start_radius_and_volume_schedule) {
    char out[65536];
    ASSERT_MSG(rt_render("'%s/data/scenes/cornell_fog.json' --mode pm --width 8 --height 8 --pm "
                         "global_photons=5000 --pm volume_photons=5000 --pass-spp 1",
                         "--passes 3 --pm ppm_radius=0.5 --threads 2 --quiet --hdr v.pfm -o v.png", out,
                         sizeof out) == 0, "%s", out);
    double typical = num_after(out, "secondary gather below "), cap = num_after(out, "Radii: global estimate ");
    const char *p0 = strstr(out, "Pass 0: ");
    ASSERT_MSG(p0 && typical > 0 && cap > 0, "%s", out);
    double g0 = num_after(p0, "r^2 global "), v = num_after(p0, "volume (r^2 ");
    EXPECT_MSG(fabs(g0 - 0.25 * typical * typical) <= 2e-3 * g0, "pass 0 r^2 %.9g, typical %.6g", g0, typical);
    EXPECT_MSG(g0 < cap * cap, "pass 0 r^2 %.9g not below the cap %.6g^2", g0, cap);
    for (int i = 1; i < 3; i++) {
        v *= (i + 2.0 / 3.0) / (i + 1);
        char key[32];
        snprintf(key, sizeof key, "Pass %d: ", i);
        const char *pl = strstr(out, key);
        ASSERT_MSG(pl, "no line for pass %d", i);
        double got = num_after(pl, "volume (r^2 ");
        EXPECT_MSG(fabs(got - v) <= 1e-6 * v, "pass %d: volume r^2 %.9g, expected %.9g", i, got, v);
    }
    /* a resumed render starts its radii where the uninterrupted one did (the first pass it
     * renders is not pass 0) */
    ASSERT_MSG(rt_render("'%s/data/scenes/cornell_fog.json' --mode pm --width 8 --height 8 --pm "
                         "global_photons=5000 --pm volume_photons=5000 --pass-spp 1",
                         "--passes 1 --pm ppm_radius=0.5 --threads 2 --quiet --hdr w.pfm -o w.png --checkpoint w.ckpt",
                         out, sizeof out) == 0, "%s", out);
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "'%s/render' '%s/data/scenes/cornell_fog.json' --resume w.ckpt --passes 3 --threads 1",
             pm_test_build_dir(), pm_test_source_dir());
    ASSERT_MSG(rt_run(cmd, out, sizeof out) == 0, "%s", out);
    EXPECT_MSG(rt_same_file("w.pfm", "v.pfm") && rt_same_file("w.png", "v.png"),
               "ppm_radius: resumed after 1 pass, the image differs from 3 passes at once");
}

/* Oracle: the budget rule, from what the program prints (never a speed). Path tracing with a
 * budget of 1.5 s in passes of 1 sample: more than one pass runs, the run stops because of the
 * budget, and the elapsed time is at most the budget plus the longest pass. The scene's own
 * render.time does the same, and --spp on the command line overrides it (one pass, no
 * "Passes:" line). */
TEST(render_progressive_time_budget) {
    char out[65536], cmd[8192];
    ASSERT_MSG(rt_render("'%s/data/scenes/cornell_box.json' --width 16 --height 16",
                         "--time 1.5 --pass-spp 1 --threads 2 --quiet --hdr t.pfm -o t.png", out,
                         sizeof out) == 0, "%s", out);
    const char *l = strstr(out, "Passes: ");
    ASSERT_MSG(l, "no Passes line: %s", out);
    double done = num_after(l, "Passes: "), longest = num_after(l, "longest "),
           elapsed = num_after(l, "elapsed "), budget = num_after(l, "budget of ");
    printf("    %g passes, longest %.3f s, elapsed %.3f s of %.3g s\n", done, longest, elapsed, budget);
    EXPECT_MSG(done > 1, "%g passes", done);
    EXPECT_MSG(budget == 1.5, "budget %g", budget);
    EXPECT_MSG(elapsed <= budget + longest, "elapsed %.3f > budget %.3f + longest pass %.3f", elapsed,
               budget, longest);
    EXPECT_MSG(strstr(l, "(stopped by it)"), "not stopped by the budget: %s", l);
    /* the scene's render.time */
    ASSERT(write_box_with_render("timed.json", "\"time\": 0.5, \"pass_spp\": 1") == 0);
    snprintf(cmd, sizeof cmd, "'%s/render' timed.json --width 16 --height 16 --threads 2 --quiet --hdr s.pfm -o s.png",
             pm_test_build_dir());
    ASSERT_MSG(rt_run(cmd, out, sizeof out) == 0, "%s", out);
    l = strstr(out, "Passes: ");
    ASSERT_MSG(l, "render.time: no Passes line: %s", out);
    EXPECT_MSG(num_after(l, "Passes: ") > 1, "render.time: %s", l);
    EXPECT_MSG(num_after(l, "budget of ") == 0.5, "render.time: %s", l);
    snprintf(cmd, sizeof cmd, "'%s/render' timed.json --width 16 --height 16 --spp 1 --threads 2 --quiet --hdr u.pfm -o u.png",
             pm_test_build_dir());
    ASSERT_MSG(rt_run(cmd, out, sizeof out) == 0, "%s", out);
    EXPECT_MSG(!strstr(out, "Passes: ") && strstr(out, "1 spp"), "--spp did not override render.time: %s", out);
}

/* Oracle: the uninterrupted render with the same passes, byte for byte (PFM and PNG).
 * (1) A render of 2 passes with --checkpoint, resumed with --passes 4 (the checkpoint's
 * options replayed, the new count winning), equals 4 passes at once. (2) A render stopped by
 * SIGINT in the middle of pass 2 (PM_RENDER_TEST_PAUSE=pass:2) writes a checkpoint of the 2
 * passes done (exit 130, no image); resumed at 1 thread, it equals the uninterrupted 4 passes.
 * (3) A checkpoint of one pass of fixed work is refused by a render in passes (exit 2). */
TEST(render_progressive_resume_bit_identical) {
    char out[65536], sc[2048], cmd[8192];
    ASSERT_MSG(rt_render(BOX_PM, "--passes 4 --threads 2 --quiet --hdr ref.pfm -o ref.png", out, sizeof out) == 0,
               "%s", out);
    ASSERT_MSG(rt_render(BOX_PM, "--passes 2 --threads 2 --quiet --hdr c.pfm -o c.png --checkpoint c.ckpt", out,
                         sizeof out) == 0, "%s", out);
    snprintf(sc, sizeof sc, BOX_PM, pm_test_source_dir());
    *strchr(sc + 1, '\'') = 0;
    snprintf(cmd, sizeof cmd, "'%s/render' %s' --resume c.ckpt --passes 4 --threads 1", pm_test_build_dir(), sc);
    ASSERT_MSG(rt_run(cmd, out, sizeof out) == 0, "%s", out);
    EXPECT_MSG(strstr(out, "Passes: 4 done (2 by this run)"), "%s", out);
    EXPECT_MSG(rt_same_file("c.pfm", "ref.pfm") && rt_same_file("c.png", "ref.png"),
               "continued to 4 passes: the image differs from 4 passes at once");
    rt_run("rm -f c.ckpt c.pfm c.png", out, sizeof out);
    int rc = rt_render_paused("pass:2", "INT", BOX_PM, "--passes 4 --threads 2 --hdr c.pfm -o c.png --checkpoint c.ckpt",
                              "", out, sizeof out);
    EXPECT_MSG(rc == 130, "status %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "checkpoint c.ckpt (2 passes)"), "the checkpoint does not keep 2 passes: %s", out);
    EXPECT_MSG(access(rt_path("c.pfm"), F_OK) != 0, "an image was written");
    snprintf(cmd, sizeof cmd, "'%s/render' %s' --resume c.ckpt --threads 1", pm_test_build_dir(), sc);
    ASSERT_MSG(rt_run(cmd, out, sizeof out) == 0, "%s", out);
    EXPECT_MSG(strstr(out, "Passes: 4 done (2 by this run)"), "%s", out);
    EXPECT_MSG(rt_same_file("c.pfm", "ref.pfm") && rt_same_file("c.png", "ref.png"),
               "resumed after SIGINT: the image differs from the uninterrupted one");
    /* a checkpoint of one pass of fixed work, resumed in passes */
    rt_run("rm -f c.ckpt c.pfm c.png", out, sizeof out);
    ASSERT_MSG(rt_render("'%s/data/scenes/cornell_box.json' --width 16 --height 16",
                         "--spp 1 --threads 2 --quiet --hdr c.pfm --checkpoint one.ckpt", out, sizeof out) == 0,
               "%s", out);
    snprintf(cmd, sizeof cmd, "'%s/render' '%s/data/scenes/cornell_box.json' --resume one.ckpt --passes 2",
             pm_test_build_dir(), pm_test_source_dir());
    rc = rt_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 2 && strstr(out, "one pass of fixed work"), "status %d: %s", rc, out);
}

/* Oracle: the PNG of the same render stopped after 2 passes, byte for byte. With
 * --snapshot-every, the PNG rewritten after each pass is the running estimate: paused before
 * pass 2's image (PM_RENDER_TEST_PAUSE=pass:2), it holds the mean of passes 0 and 1. */
TEST(render_progressive_snapshot_is_the_running_estimate) {
    char out[65536];
    ASSERT_MSG(rt_render(BOX_PM, "--passes 2 --threads 2 --quiet -o two.png", out, sizeof out) == 0, "%s", out);
    int rc = rt_render_paused("pass:2", "TERM", BOX_PM, "--passes 4 --threads 2 -o snap.png --snapshot-every 0.001",
                              "cp snap.png seen.png", out, sizeof out);
    EXPECT_MSG(rc == 143, "status %d: %s", rc, out);
    EXPECT_MSG(rt_same_file("seen.png", "two.png"), "the snapshot after 2 passes differs from 2 passes' PNG");
}

/* Oracle: the same render at 1 thread, byte for byte: 3 passes of progressive photon mapping
 * (cornell_spheres: caustic and global maps) and of path tracing at 2 threads. */
TEST(render_progressive_threads_bit_identical) {
    char out[65536];
    static const char *scenes[2] = {BOX_PM, "'%s/data/scenes/cornell_box.json' --width 24 --height 16 --pass-spp 4"};
    for (int k = 0; k < 2; k++) {
        ASSERT_MSG(rt_render(scenes[k], "--passes 3 --threads 1 --quiet --hdr one.pfm -o one.png", out, sizeof out) == 0,
                   "%s", out);
        ASSERT_MSG(rt_render(scenes[k], "--passes 3 --threads 2 --quiet --hdr two.pfm -o two.png", out, sizeof out) == 0,
                   "%s", out);
        if (!strstr(out, ", 2 threads,")) SKIP("a build without OpenMP renders one thread");
        EXPECT_MSG(rt_same_file("one.pfm", "two.pfm") && rt_same_file("one.png", "two.png"),
                   "%s: 1 and 2 threads differ", k ? "path" : "pm");
    }
}

/* Oracle: the plain render (--spp), byte for byte. One pass is that render in path tracing,
 * and in photon mapping with ppm_radius 0 (the caps); at the default start radius (2) pass 0's
 * precomputed irradiance and caustic side map are made again at it, so its image differs
 * (README.md, "A time budget, and passes"). BOX_PM at 4 spp, seed 3. */
TEST(render_progressive_one_pass_is_the_plain_render) {
    char out[65536];
    static const struct {
        const char *scene, *extra;
        int same;
    } cases[] = {{BOX_PM_SCENE, "--pm ppm_radius=0", 1},
                 {BOX_PM_SCENE, "", 0},
                 {"'%s/data/scenes/cornell_box.json' --width 16 --height 16", "", 1}};
    for (int c = 0; c < 3; c++) {
        char args[512];
        snprintf(args, sizeof args, "--spp 4 --seed 3 --threads 2 --quiet --hdr plain.pfm -o plain.png %s",
                 cases[c].extra);
        ASSERT_MSG(rt_render(cases[c].scene, args, out, sizeof out) == 0, "%s", out);
        snprintf(args, sizeof args, "--passes 1 --pass-spp 4 --seed 3 --threads 2 --quiet --hdr one.pfm -o one.png %s",
                 cases[c].extra);
        ASSERT_MSG(rt_render(cases[c].scene, args, out, sizeof out) == 0, "%s", out);
        EXPECT_MSG(rt_same_file("plain.pfm", "one.pfm") == cases[c].same, "case %d (%s): one pass %s the plain render",
                   c, cases[c].extra[0] ? cases[c].extra : "the defaults", cases[c].same ? "differs from" : "equals");
    }
}

/* Pass 1's fraction of the photon targets, with its counted work (W_p, W_r), from a render's
 * output; checks it against the documented rule clamp(share W_r / W_p, 1/64, 1) (3 significant
 * digits printed: relative 5e-3 plus the fraction's own 4) and that pass 1's global map holds
 * that fraction of `targets` (-1: not checked). *fo gets the fraction. */
static void check_fraction(const char *out, double share, double targets, double *fo) {
    const char *l = strstr(out, "Pass 1: photons ");
    ASSERT_MSG(l, "%s", out);
    double wp = num_after(l, "the targets' photons ");
    const char *cam = strstr(l, "camera samples ");
    const char *fl = strstr(l, "); ");
    double f = fl ? strtod(fl + 3, NULL) : NAN;
    double wr = cam ? strtod(cam + strlen("camera samples "), NULL) : NAN;
    ASSERT_MSG(isfinite(f) && wp > 0 && wr > 0, "no fraction or counted work in: %.400s", l);
    double rule = fmin(1.0, fmax(1.0 / 64, share * wr / wp));
    EXPECT_MSG(fabs(f - rule) <= 1e-2 * rule, "fraction %g, the rule at share %g gives %g (W_p %g, W_r %g)", f, share,
               rule, wp, wr);
    if (targets > 0) {
        double g = num_after(l, "Pass 1: photons "), want = floor(targets * f);
        EXPECT_MSG(g >= want - targets * 5e-4 - 1 && g <= want + targets * 5e-4 + 64, "pass 1: %g global photons at fraction %g",
                   g, f);
    }
    *fo = f;
}

/* Oracle: photons per pass (pm_passes.c, PHOTONS PER PASS). (a) ppm_photons=0.25 on targets
 * of 8000: passes 1 and 2 store 2000 of each map, plus at most the last photon path's stores
 * (a path's stores are kept together: 64 is far above the few a path leaves), and pass 0 the
 * whole targets; a later pass's estimates read k f photons, at least 32 global and 8 caustic
 * (k_global 100 -> 32, k_caustic 60 -> 15). (b) At the default the fraction printed is the documented rule applied to
 * the counted work the same line prints: clamp(0.15 W_r / W_p, 1/64, 1) (check_fraction),
 * and the next pass's maps hold that fraction of the targets; the same fraction for 1 and 2
 * threads (counted work, never
 * timed: the images' bit-identity is render_progressive_threads_bit_identical). */
TEST(render_progressive_photons_per_pass) {
    char out[65536];
    ASSERT_MSG(rt_render(BOX_PM, "--passes 3 --pm ppm_photons=0.25 --threads 2 --hdr a.pfm -o a.png", out, sizeof out) == 0,
               "%s", out);
    for (int p = 0; p < 3; p++) {
        char key[32];
        snprintf(key, sizeof key, "Pass %d: photons ", p);
        const char *l = strstr(out, key);
        ASSERT_MSG(l, "no line for pass %d:\n%s", p, out);
        double g = num_after(l, key), c = num_after(l, "global, "), want = p ? 2000 : 8000;
        EXPECT_MSG(g >= want && g <= want + 64 && c >= want && c <= want + 64,
                   "pass %d: %g global, %g caustic photons, expected %g (+ one path's stores)", p, g, c, want);
        if (p) { /* k f photons an estimate, at least 32 global and 8 caustic: 25 -> 32, 15 */
            double kg = num_after(l, "estimates of "), kc = num_after(l, " global and ");
            EXPECT_MSG(kg == 32 && kc == 15, "pass %d: estimates of %g global and %g caustic photons, expected 32 and 15",
                       p, kg, kc);
        }
    }
    double frac[2];
    for (int t = 0; t < 2; t++) {
        ASSERT_MSG(rt_render(BOX_PM, t ? "--passes 2 --threads 2 --hdr b.pfm -o b.png"
                                       : "--passes 2 --threads 1 --hdr b.pfm -o b.png", out, sizeof out) == 0,
                   "%s", out);
        double f = NAN;
        check_fraction(out, 0.15, 8000, &f);
        frac[t] = f;
    }
    EXPECT_MSG(frac[0] == frac[1], "the fraction differs for 1 and 2 threads: %g, %g", frac[0], frac[1]);
}

/* Oracle: where the plan's photon ports are on, or its light guide (light samples mostly
 * blocked), a later pass's fraction is the same rule at the share 1.5 (pm_passes.c,
 * PPM_PORT_SHARE), and the line says why: pinhole_room_ports.json declares its hole a port;
 * pinhole_room.json, where the probe finds it; door_ajar.json has no port but the light guide;
 * cornell_box has neither, so 0.15 (there clamped to 1/64 at this size:
 * render_progressive_photons_per_pass checks 0.15 unclamped). */
TEST(render_progressive_photons_per_pass_with_ports) {
    char out[65536];
    static const struct {
        const char *scene;
        double share;
        const char *why;
    } cases[] = {{"pinhole_room_ports", 1.5, "as photon ports are on"},
                 {"pinhole_room", 1.5, "as photon ports are on"},
                 {"door_ajar", 1.5, "as the light guide is on (light samples mostly blocked)"},
                 {"cornell_box", 0.15, NULL}};
    for (int i = 0; i < 4; i++) {
        char sc[256];
        snprintf(sc, sizeof sc, "'%%s/data/scenes/%s.json' --mode pm --width 8 --height 8", cases[i].scene);
        ASSERT_MSG(rt_render(sc, "--passes 2 --pass-spp 1024 --hdr p.pfm -o p.png", out, sizeof out) == 0, "%s", out);
        printf("    %s: %.300s\n", cases[i].scene, strstr(out, "Pass 1: photons ") ? strstr(out, "Pass 1: photons ") : "");
        double f = NAN;
        check_fraction(out, cases[i].share, -1, &f);
        if (cases[i].share > 1) /* where the shares' fractions differ, 0.0235 against 0.235 here */
            EXPECT_MSG(f > 10.0 / 64 && f < 1, "%s: fraction %g: the port share is not seen", cases[i].scene, f);
        int ports = strstr(out, "as photon ports are on") != NULL, guide = strstr(out, "as the light guide is on") != NULL;
        EXPECT_MSG(cases[i].why ? strstr(out, cases[i].why) != NULL && ports + guide == 1 : !ports && !guide,
                   "%s: the pass line does not say \"%s\"", cases[i].scene, cases[i].why ? cases[i].why : "(nothing)");
    }
}

/* Oracle: the documented refusals: exit status 2, a message that names the option or the
 * field, and no image. */
TEST(render_progressive_bad_input) {
    char out[16384], cmd[8192];
    static const struct {
        const char *args, *expect;
    } cases[] = {
        {"--time -1", "--time"},
        {"--time nan", "--time"},
        {"--time inf", "--time"},
        {"--time 0", "--time"},
        {"--time", "--time needs a value"},
        {"--passes 0", "--passes"},
        {"--passes two", "--passes"},
        {"--pass-spp 0 --passes 2", "--pass-spp"},
        {"--pass-spp 4", "--pass-spp needs passes"},
        {"--time 5 --spp 4", "--pass-spp"},
        {"--only-pass -1", "--only-pass"},
        {"--passes 2 --pm ppm_alpha=0", "ppm_alpha"},
        {"--passes 2 --pm ppm_alpha=1.5", "ppm_alpha"},
        {"--passes 2 --mode pm --load-photons nowhere", "load-photons"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        int rc = rt_render("'%s/data/scenes/cornell_box.json' --width 8 --height 8 --quiet --hdr bad.pfm",
                           cases[k].args, out, sizeof out);
        EXPECT_MSG(rc == 2 && strstr(out, cases[k].expect), "%s: status %d: %s", cases[k].args, rc, out);
    }
    static const char *fields[] = {"\"abc\"", "-1", "0", "true", "[1]", "1e300"};
    for (size_t k = 0; k < sizeof fields / sizeof fields[0]; k++) {
        char keys[64];
        snprintf(keys, sizeof keys, "\"time\": %s", fields[k]);
        ASSERT(write_box_with_render("bad.json", keys) == 0);
        snprintf(cmd, sizeof cmd, "'%s/render' bad.json --width 8 --height 8 --quiet --hdr bad.pfm", pm_test_build_dir());
        int rc = rt_run(cmd, out, sizeof out);
        EXPECT_MSG(rc == 2 && strstr(out, "$.render.time"), "render.time %s: status %d: %s", fields[k], rc, out);
    }
    EXPECT_MSG(access(rt_path("bad.pfm"), F_OK) != 0, "an image was written");
}

/* Oracle: the state written, bit for bit, and the documented refusals. A version 3 checkpoint
 * (a render in passes) reads back to the same passes, sums and sample multipliers (none
 * decided: read back as none; decided: the same bytes); a multiplier out of range, or some
 * pixels decided and others not, under a valid checksum, is refused (PM_EFORMAT,
 * "multiplier"); truncated at several lengths or
 * with a flipped byte it is refused (PM_EFORMAT, "truncated" / "checksum"); read as a state of
 * fixed work it is refused with a message naming the kind (PM_EINVAL), and a version 1 file
 * read as a render in passes likewise. */
TEST(render_progressive_checkpoint_v3_file) {
    pass_state ps, back;
    ASSERT(pass_state_init(&ps, 5, 3) == 0);
    for (int i = 0; i < 45; i++) {
        ps.sum[i] = 0.1 * i - 1.0 / 3.0;
        ps.sum2[i] = 0.01 * i * i + 1e-300;
    }
    ps.done = 7;
    ckpt_info ci, got;
    memset(&ci, 0, sizeof ci);
    snprintf(ci.settings, sizeof ci.settings, "mode=pm; in passes");
    memcpy(ci.args, "--passes\0" "7\0", 11);
    ci.args_len = 11;
    char err[512];
    const char *p = rt_path("v2.ckpt");
    ASSERT_MSG(ckpt_write_passes(p, &ci, &ps, 4, err, sizeof err) == 0, "%s", err);
    ASSERT_MSG(ckpt_read_passes(p, &got, &back, err, sizeof err) == 0, "%s", err);
    EXPECT(got.version == 3 && got.passes == 7 && back.done == 7 && back.width == 5 && back.height == 3);
    EXPECT_MSG(back.mult == NULL, "undecided multipliers read back as decided");
    EXPECT(memcmp(back.sum, ps.sum, 45 * sizeof(double)) == 0 && memcmp(back.sum2, ps.sum2, 45 * sizeof(double)) == 0);
    EXPECT(strcmp(got.settings, ci.settings) == 0 && got.args_len == 11);
    pass_state_free(&back);
    ASSERT_MSG(ckpt_read(p, &got, NULL, err, sizeof err) == 0, "the arguments-only read: %s", err);
    render_state rs;
    EXPECT_EQ_INT(ckpt_read(p, &got, &rs, err, sizeof err), PM_EINVAL);
    EXPECT_MSG(strstr(err, "a checkpoint of a render in passes"), "%s", err);
    size_t n;
    char *buf = rt_slurp(p, &n);
    ASSERT(buf && n == 56 + strlen(ci.settings) + 11 + 15 * 48 + 15 + 8);
    /* decided multipliers, written and read back */
    ASSERT((ps.mult = malloc(15)) != NULL);
    for (int i = 0; i < 15; i++) ps.mult[i] = (unsigned char)(1 + (i * 7) % ADAPT_MAX);
    const char *pm = rt_path("v3m.ckpt");
    ASSERT_MSG(ckpt_write_passes(pm, &ci, &ps, 4, err, sizeof err) == 0, "%s", err);
    ASSERT_MSG(ckpt_read_passes(pm, &got, &back, err, sizeof err) == 0, "%s", err);
    EXPECT_MSG(back.mult && memcmp(back.mult, ps.mult, 15) == 0, "the multipliers differ when read back");
    pass_state_free(&back);
    size_t nm;
    unsigned char *bm = (unsigned char *)rt_slurp(pm, &nm);
    ASSERT(bm && nm == n);
    const unsigned char bad[2][2] = {{ADAPT_MAX + 1, 3}, {0, 3}}; /* byte 0, byte 1 of the multipliers */
    for (int b = 0; b < 2; b++) {
        bm[nm - 8 - 15] = bad[b][0];
        bm[nm - 8 - 14] = bad[b][1];
        uint64_t h = hash_fnv1a(HASH_FNV_INIT, bm, nm - 8);
        for (int k = 0; k < 8; k++) bm[nm - 8 + (size_t)k] = (unsigned char)(h >> (8 * k));
        FILE *fm = fopen(pm, "wb");
        ASSERT(fm);
        fwrite(bm, 1, nm, fm);
        fclose(fm);
        EXPECT_EQ_INT(ckpt_read_passes(pm, &got, &back, err, sizeof err), PM_EFORMAT);
        EXPECT_MSG(strstr(err, "multiplier"), "case %d: %s", b, err);
    }
    free(bm);
    size_t cuts[] = {30, 60, n / 2, n - 1};
    const char *q = rt_path("bad.ckpt");
    for (size_t k = 0; k < sizeof cuts / sizeof cuts[0]; k++) {
        FILE *f = fopen(q, "wb");
        ASSERT(f);
        fwrite(buf, 1, cuts[k], f);
        fclose(f);
        EXPECT_EQ_INT(ckpt_read_passes(q, &got, &back, err, sizeof err), PM_EFORMAT);
        EXPECT_MSG(strstr(err, "truncated") || strstr(err, "not a render checkpoint"), "cut %zu: %s", cuts[k], err);
    }
    buf[n - 20] ^= 1;
    FILE *f = fopen(q, "wb");
    ASSERT(f);
    fwrite(buf, 1, n, f);
    fclose(f);
    EXPECT_EQ_INT(ckpt_read_passes(q, &got, &back, err, sizeof err), PM_EFORMAT);
    EXPECT_MSG(strstr(err, "checksum"), "%s", err);
    free(buf);
    /* a version 1 file (one pass of fixed work) read as a render in passes */
    ASSERT(render_state_init(&rs, 5, 3, 4) == 0);
    ASSERT_MSG(ckpt_write(q, &ci, &rs, err, sizeof err) == 0, "%s", err);
    EXPECT_EQ_INT(ckpt_read_passes(q, &got, &back, err, sizeof err), PM_EINVAL);
    EXPECT_MSG(strstr(err, "one pass of fixed work"), "%s", err);
    render_state_free(&rs);
    pass_state_free(&ps);
}

/* Oracle: the documented default of samples per pass (render/app/run.c, THE DEFAULT SAMPLES PER
 * PASS), computed here on its own: 4, or at fewer than 16,384 pixels the least square s^2 with
 * pixels x s^2 >= 65,536. The run's "In passes of N spp" line and its film's sample count
 * (pixels x N x passes) must both follow it; --pass-spp and the scene's render.pass_spp keep
 * their value (rounded up to a square as before). Path tracing, one pass each. */
TEST(render_progressive_default_pass_spp) {
    char out[65536];
    static const struct {
        int w, h, asked;   /* asked: --pass-spp (0: none) */
        const char *scene; /* NULL: cornell_box.json */
    } cases[] = {{8, 8, 0, NULL},   {20, 12, 0, NULL}, {96, 96, 0, NULL}, {128, 128, 0, NULL},
                 {300, 2, 0, NULL}, {8, 8, 4, NULL},   {8, 8, 0, "ps.json"}};
    ASSERT_EQ_INT(write_box_with_render("ps.json", "\"pass_spp\": 6"), 0); /* rounded up to 9 */
    for (int c = 0; c < 7; c++) {
        long px = (long)cases[c].w * cases[c].h, want = 4;
        if (cases[c].asked || cases[c].scene)
            want = cases[c].asked ? cases[c].asked : 9;
        else
            for (long side = 1; px * 4 < 65536; side++)
                if (px * side * side >= 65536) {
                    want = side * side;
                    break;
                }
        char scn[1100], args[512];
        if (cases[c].scene)
            snprintf(scn, sizeof scn, "'%s'", rt_path(cases[c].scene));
        else
            snprintf(scn, sizeof scn, "'%%s/data/scenes/cornell_box.json'");
        snprintf(args, sizeof args, "--mode path --width %d --height %d --passes 1 --threads 2 --hdr d.pfm %s%.0d",
                 cases[c].w, cases[c].h, cases[c].asked ? "--pass-spp " : "", cases[c].asked);
        ASSERT_MSG(rt_render(scn, args, out, sizeof out) == 0, "case %d: %s", c, out);
        double got = num_after(out, "In passes of "), samples = num_after(out, "    Samples");
        EXPECT_MSG(got == (double)want, "case %d (%dx%d): %g spp a pass, the rule says %ld", c, cases[c].w,
                   cases[c].h, got, want);
        EXPECT_MSG(samples == (double)(px * want), "case %d: the film has %g samples, not %ld x %ld", c, samples, px,
                   want);
        int said = strstr(out, "camera samples; --pass-spp sets it") != NULL;
        int defaulted = !cases[c].asked && !cases[c].scene;
        EXPECT_MSG(said == (defaulted && want != 4), "case %d: the run %s why the pass is not 4 spp", c,
                   said ? "says" : "does not say");
    }
}

/* Oracle: the uninterrupted render, byte for byte. A checkpoint made in passes of the default
 * samples before the default changed (at 16x16 it was 4 before 3982015, 256 now) is made here
 * from one of --pass-spp 4 by taking that option out of its stored arguments (ckpt_info.args):
 * resumed without --pass-spp, the render takes the checkpoint's 4 (and says so), where it
 * refused it before ("the checkpoint has other settings"), and its 4 passes equal 4 passes of
 * --pass-spp 4 at once. */
TEST(render_progressive_resume_keeps_the_checkpoints_pass_spp) {
    char out[65536], cmd[8192], err[512];
    const char *box = "'%s/data/scenes/cornell_box.json' --mode path --width 16 --height 16 --pass-spp 4";
    ASSERT_MSG(rt_render(box, "--passes 4 --threads 2 --quiet --hdr ref.pfm -o ref.png", out, sizeof out) == 0, "%s",
               out);
    ASSERT_MSG(rt_render(box, "--passes 2 --threads 2 --quiet --hdr o.pfm -o o.png --checkpoint old.ckpt", out,
                         sizeof out) == 0, "%s", out);
    static ckpt_info ci;
    pass_state ps;
    const char *p = rt_path("old.ckpt");
    ASSERT_MSG(ckpt_read_passes(p, &ci, &ps, err, sizeof err) == 0, "%s", err);
    EXPECT_MSG(ci.spp == 4 && ci.passes == 2, "the checkpoint says %u spp a pass, %u passes", ci.spp, ci.passes);
    size_t w = 0, removed = 0;
    for (size_t r = 0; r < ci.args_len;) { /* drop "--pass-spp" and its value */
        size_t len = strlen(ci.args + r) + 1;
        if (strcmp(ci.args + r, "--pass-spp") == 0) {
            r += len;
            r += strlen(ci.args + r) + 1;
            removed = 1;
            continue;
        }
        memmove(ci.args + w, ci.args + r, len);
        w += len;
        r += len;
    }
    ASSERT_MSG(removed, "no --pass-spp among the stored arguments");
    ci.args_len = w;
    ASSERT_MSG(ckpt_write_passes(p, &ci, &ps, 4, err, sizeof err) == 0, "%s", err);
    pass_state_free(&ps);
    snprintf(cmd, sizeof cmd, "'%s/render' '%s/data/scenes/cornell_box.json' --resume old.ckpt --passes 4 --threads 1",
             pm_test_build_dir(), pm_test_source_dir());
    int rc = rt_run(cmd, out, sizeof out);
    ASSERT_MSG(rc == 0, "status %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "rendered in passes of 4 spp") && strstr(out, "In passes of 4 spp"), "%s", out);
    EXPECT_MSG(strstr(out, "Passes: 4 done (2 by this run)"), "%s", out);
    EXPECT_MSG(rt_same_file("o.pfm", "ref.pfm") && rt_same_file("o.png", "ref.png"),
               "resumed at the checkpoint's pass spp: the image differs from 4 passes at once");
}
