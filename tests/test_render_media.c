/* test_render_media.c: participating media (render/scene/medium.h): the scene format and its
 * errors, the Henyey–Greenstein phase function, free-flight sampling, transmittance through
 * media and invisible (null) interfaces, and the path tracer with media.
 *
 * Oracles (details above each test): the JSON path each bad value must name and render's
 * exit status 2; the HG formula (its integral is 1, its mean cosine is g, and a chi-square
 * test of sampled cosines against the formula's bins); Beer's law e^{-sigma_t d} for
 * transmittance (exact for the shadow walk, within 4 standard errors for free-flight and
 * path-traced estimates); and the furnace: inside a closed emitter of radiance Le and albedo
 * rho filled with a medium of single-scattering albedo 1, radiance is Le / (1 - rho)
 * everywhere.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "test.h"
#include "../render/image/film.h"
#include "../render/integrators/integrator.h"
#include "../render/scene/medium.h"
#include "../render/photon_mapping/plan.h"
#include "../render/photon_mapping/pm_volume.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"
#include "../render/photons/volume.h"

/* The dense-fog comparison (render_media_pm_matches_path_in_dense_fog). */
#ifndef DENSE_PT_SPP
#define DENSE_PT_SPP 4096
#define DENSE_PM_SPP 16
#define DENSE_VOLPH 100000
#endif

/* ---- helpers ------------------------------------------------------------------------------ */

/* A scene text from the pieces that vary: media, extra top-level keys, materials, objects. */
static void scene_text(char *buf, size_t cap, const char *media, const char *top, const char *mats,
                       const char *objs) {
    snprintf(buf, cap,
             "{\"camera\": {\"eye\": [0, 0, -5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, "
             "\"width\": 8, \"height\": 8},"
             " \"media\": {%s}, %s"
             " \"materials\": {\"white\": {\"type\": \"lambert\", \"reflectance\": 0.5}, %s},"
             " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-9, -9, 9], [9, -9, 9], [9, 9, 9], "
             "[-9, 9, 9]], \"material\": \"white\"}, %s]}",
             media, top, mats, objs);
}

/* The 12 triangles of the axis-aligned box [lo, hi], wound so the normals point out, as the
 * "vertices" and "triangles" of a mesh object; skip_face (0..5, or -1) leaves one face out,
 * inward reverses every face. */
static void box_mesh(char *buf, size_t cap, vec3 lo, vec3 hi, int skip_face, int inward) {
    static const int f[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    size_t n = (size_t)snprintf(buf, cap, "\"vertices\": [");
    for (int i = 0; i < 8; i++)
        n += (size_t)snprintf(buf + n, cap - n, "%s[%g, %g, %g]", i ? ", " : "",
                              i & 1 ? hi.x : lo.x, i & 2 ? hi.y : lo.y, i & 4 ? hi.z : lo.z);
    n += (size_t)snprintf(buf + n, cap - n, "], \"triangles\": [");
    int first = 1;
    for (int k = 0; k < 6; k++) {
        if (k == skip_face) continue;
        int a = f[k][0], b = f[k][1], c = f[k][2], d = f[k][3];
        if (inward) {
            int t = b;
            b = d;
            d = t;
        }
        n += (size_t)snprintf(buf + n, cap - n, "%s[%d, %d, %d], [%d, %d, %d]", first ? "" : ", ",
                              a, b, c, a, c, d);
        first = 0;
    }
    snprintf(buf + n, cap - n, "]");
}

/* Oracle: a box is closed wherever it stands. The check compares edges by vertex position,
 * and a triangle keeps v0 and two edge vectors, so v0 + (v1 - v0) may miss v1 by a rounding:
 * boxes with arbitrary corners must still load, and each with one face left out must not. */
TEST(render_media_closed_check_any_box) {
    static const double corners[][6] = {
        {-0.6, -0.98, -0.3, 0.6, 0.3, 0.9}, {-0.9, -0.95, -0.95, 0.95, 0.7, 0.95},
        {0.1, 0.2, 0.3, 0.7, 1.9, 3.3},     {-1e3, 17.3, -0.001, 2e3 / 3, 41.7, 1e-3 / 3},
        {1e-6, -2e-6, 3e-6, 7e-6, 5e-6, 1.1e-5}};
    for (size_t i = 0; i < sizeof corners / sizeof corners[0]; i++) {
        const double *c = corners[i];
        for (int skip = -1; skip < 6; skip += 3) {
            static char box[2048], objs[4096], txt[8192];
            box_mesh(box, sizeof box, v3(c[0], c[1], c[2]), v3(c[3], c[4], c[5]), skip, 0);
            snprintf(objs, sizeof objs,
                     "{\"type\": \"mesh\", %s, \"material\": \"air\", \"interior_medium\": \"smoke\"}", box);
            scene_text(txt, sizeof txt, "\"smoke\": {\"sigma_s\": [2, 2, 2]}", "",
                       "\"air\": {\"type\": \"null\"}", objs);
            scene s;
            json_err e = {0};
            int rc = scene_load_text(&s, txt, &e);
            if (skip < 0) {
                EXPECT_MSG(rc == 0, "box %zu: %s", i, e.msg);
            } else {
                EXPECT_MSG(rc != 0 && strstr(e.msg, "the boundary is open"), "box %zu without face %d: rc %d, '%s'",
                           i, skip, rc, e.msg);
            }
            if (rc == 0) scene_free(&s);
        }
    }
}

/* ---- the scene format --------------------------------------------------------------------- */

/* Oracle: the format's rules. A valid scene loads with the media, the global medium, each
 * object's interior medium and the camera's medium where they are; each bad value fails with
 * a message that names its JSON path. */
TEST(render_media_scene_format) {
    static char txt[8192], box[2048];
    box_mesh(box, sizeof box, v3(-1, -1, -1), v3(1, 1, 1), -1, 0);
    char objs[4096];
    snprintf(objs, sizeof objs,
             "{\"type\": \"mesh\", %s, \"material\": \"air\", \"interior_medium\": \"smoke\"},"
             " {\"type\": \"sphere\", \"center\": [0, 0, 3], \"radius\": 0.5, \"material\": \"white\","
             " \"interior_medium\": \"fog\"}", box);
    scene_text(txt, sizeof txt,
               "\"fog\": {\"sigma_a\": [0.1, 0.2, 0.3], \"sigma_s\": 0.5, \"g\": 0.3},"
               " \"smoke\": {\"sigma_s\": [2, 2, 2]}",
               "\"medium\": \"fog\",", "\"air\": {\"type\": \"null\"}", objs);
    scene s;
    json_err e = {0};
    int rc = scene_load_text(&s, txt, &e);
    ASSERT_MSG(rc == 0, "%s", e.msg);
    ASSERT_EQ_INT(s.nmedia, 2);
    EXPECT_EQ_INT(s.global_medium, 0);
    EXPECT_NEAR(s.media[0].sigma_t.z, 0.8, 1e-15);
    EXPECT_NEAR(s.media[0].g, 0.3, 0);
    EXPECT_NEAR(s.media[1].sigma_t.x, 2, 0);
    EXPECT_EQ_INT(s.obj_medium[0], -1);
    EXPECT_EQ_INT(s.obj_medium[1], 1);
    EXPECT_EQ_INT(s.obj_medium[2], 0);
    EXPECT_EQ_INT(s.camera_medium, 0); /* the eye is outside every object: the global fog */
    EXPECT_EQ_INT(s.has_null, 1);
    scene_free(&s);

    /* Each bad value and the text its message must contain. */
    static char open_box[2048], inward_box[2048];
    box_mesh(open_box, sizeof open_box, v3(-1, -1, -1), v3(1, 1, 1), 3, 0);
    box_mesh(inward_box, sizeof inward_box, v3(-1, -1, -1), v3(1, 1, 1), -1, 1);
    char o1[4096], o2[4096];
    snprintf(o1, sizeof o1, "{\"type\": \"mesh\", %s, \"material\": \"x\", \"interior_medium\": \"fog\"}", open_box);
    snprintf(o2, sizeof o2, "{\"type\": \"mesh\", %s, \"material\": \"x\", \"interior_medium\": \"fog\"}", inward_box);
    const char *sph = "{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, \"material\": \"white\"}";
    struct {
        const char *media, *top, *mats, *objs, *want;
    } bad[] = {
        {"\"fog\": {\"sigma_a\": [0.1, -0.2, 0.3]}", "", "\"x\": {\"type\": \"lambert\", \"reflectance\": 0}", sph,
         "$.media.fog.sigma_a: must not be negative"},
        {"\"fog\": {\"sigma_s\": -1}", "", "\"x\": {\"type\": \"lambert\", \"reflectance\": 0}", sph,
         "$.media.fog.sigma_s: must not be negative"},
        {"\"fog\": {\"sigma_s\": [1e999, 0, 0]}", "", "\"x\": {\"type\": \"lambert\", \"reflectance\": 0}", sph,
         "$.media.fog.sigma_s"},
        {"\"fog\": {\"sigma_s\": 1, \"g\": 1}", "", "\"x\": {\"type\": \"lambert\", \"reflectance\": 0}", sph,
         "$.media.fog.g: must be in (-1, 1)"},
        {"\"fog\": {\"sigma_s\": 1, \"g\": -1e999}", "", "\"x\": {\"type\": \"lambert\", \"reflectance\": 0}", sph,
         "$.media.fog.g"},
        {"\"fog\": 3", "", "\"x\": {\"type\": \"lambert\", \"reflectance\": 0}", sph,
         "$.media.fog: expected an object"},
        {"\"fog\": {}", "\"medium\": \"smoke\",", "\"x\": {\"type\": \"lambert\", \"reflectance\": 0}", sph,
         "$.medium: unknown medium \"smoke\""},
        {"\"fog\": {}", "", "\"x\": {\"type\": \"lambert\", \"reflectance\": 0}",
         "{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, \"material\": \"white\", \"interior_medium\": \"smog\"}",
         "$.objects[1].interior_medium: unknown medium \"smog\""},
        {"\"fog\": {}", "", "\"x\": {\"type\": \"null\"}",
         "{\"type\": \"quad\", \"vertices\": [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], \"material\": \"x\", \"interior_medium\": \"fog\"}",
         "$.media.fog: the surfaces around the medium \"fog\" do not close it: the edge (0, 0, 0)-(1, 0, 0) of $.objects[1] belongs to one face only"},
        {"\"fog\": {}", "", "\"x\": {\"type\": \"null\"}", o1,
         "$.media.fog: the surfaces around the medium \"fog\" do not close it: the edge (-1, 1, -1)-(1, 1, -1) of $.objects[1] belongs to one face only"},
        {"\"fog\": {}", "", "\"x\": {\"type\": \"null\"}", o2,
         "$.media.fog: the surfaces around the medium \"fog\" enclose a volume of -8: their sides are swapped"},
        {"\"fog\": {}", "", "\"x\": {\"type\": \"null\", \"emission\": 1}", sph,
         "$.materials.x.emission: a null (invisible) surface cannot emit"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        scene_text(txt, sizeof txt, bad[i].media, bad[i].top, bad[i].mats, bad[i].objs);
        json_err e2 = {0};
        rc = scene_load_text(&s, txt, &e2);
        EXPECT_MSG(rc < 0, "case %zu loaded", i);
        EXPECT_MSG(strstr(e2.msg, bad[i].want) != NULL, "case %zu: message \"%s\", wanted \"%s\"", i,
                   e2.msg, bad[i].want);
        if (rc == 0) scene_free(&s);
    }
}

/* Oracle: input errors exit with status 2 and print the JSON path (render's contract), and
 * nothing is written. --mode pm on a valid scene with a medium renders it (exit 0, an image). */
TEST(render_media_bad_scene_exits_2) {
    static char txt[8192], out[8192];
    scene_text(txt, sizeof txt, "\"fog\": {\"sigma_a\": -1}", "", "\"x\": {\"type\": \"null\"}",
               "{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, \"material\": \"white\"}");
    char path[1024], png[1024], cmd[4096];
    snprintf(path, sizeof path, "%s/bad.json", pm_test_tmpdir());
    snprintf(png, sizeof png, "%s/bad.png", pm_test_tmpdir());
    FILE *f = fopen(path, "w");
    ASSERT(f != NULL);
    fputs(txt, f);
    fclose(f);
    snprintf(cmd, sizeof cmd, "%s/render '%s' --quiet -o '%s'", pm_test_build_dir(), path, png);
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_EQ_INT(rc, 2);
    EXPECT_MSG(strstr(out, "$.media.fog.sigma_a") != NULL, "%s", out);
    EXPECT_MSG(fopen(png, "r") == NULL, "an output was written");
    /* A valid scene with a medium: photon mapping renders it. */
    scene_text(txt, sizeof txt, "\"fog\": {\"sigma_s\": 0.1}", "\"medium\": \"fog\",",
               "\"x\": {\"type\": \"null\"}",
               "{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, \"material\": \"white\"}");
    f = fopen(path, "w");
    ASSERT(f != NULL);
    fputs(txt, f);
    fclose(f);
    snprintf(cmd, sizeof cmd, "%s/render '%s' --quiet --mode pm -o '%s'", pm_test_build_dir(), path, png);
    rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 0, "exit %d: %s", rc, out);
    f = fopen(png, "r");
    EXPECT_MSG(f != NULL, "no image written");
    if (f) fclose(f);
}

/* ---- phase function and free flight ------------------------------------------------------ */

/* Oracles: the HG formula. Its integral over the sphere (midpoint rule in cos, 200000 bins) is
 * 1 within 1e-5; sampled cosines have mean g within 4 standard errors; and a chi-square test
 * of 40 bins of sampled cosines against the formula's bin probabilities stays under the
 * 99.9% point of chi-square with 39 degrees of freedom (72.1). Every sampled direction is unit
 * and the returned density equals hg_phase of its cosine. */
TEST(render_media_hg_sampling) {
    const double gs[] = {0, 0.0005, 0.7, -0.4, 0.95};
    for (size_t gi = 0; gi < sizeof gs / sizeof *gs; gi++) {
        double g = gs[gi], integral = 0;
        int nb = 200000;
        for (int i = 0; i < nb; i++) integral += 2 * M_PI * hg_phase(g, -1 + (i + 0.5) * 2.0 / nb) * 2.0 / nb;
        EXPECT_NEAR(integral, 1.0, 1e-5);
        rng r = rng_stream(7, gi, 0);
        vec3 a = v3_norm(v3(0.3, -0.5, 0.8));
        enum { N = 200000, B = 40 };
        long hist[B] = {0};
        double sum = 0, sum2 = 0;
        for (int i = 0; i < N; i++) {
            vec3 b;
            double pdf = hg_sample(g, a, rng_uniform(&r), rng_uniform(&r), &b);
            double c = v3_dot(a, b);
            if (i < 1000) {
                EXPECT_NEAR(v3_len(b), 1.0, 1e-12);
                EXPECT_NEAR(pdf, hg_phase(g, c), 1e-6 * pdf);
            }
            sum += c;
            sum2 += c * c;
            int k = (int)((c + 1) / 2 * B);
            hist[k < 0 ? 0 : k >= B ? B - 1 : k]++;
        }
        double mean = sum / N, se = sqrt((sum2 / N - mean * mean) / N);
        EXPECT_MSG(fabs(mean - g) < 4 * se + 1e-12, "g %g: mean cos %g (se %g)", g, mean, se);
        double chi2 = 0;
        for (int k = 0; k < B; k++) { /* bin probability from the closed-form CDF of cos */
            double c0 = -1 + 2.0 * k / B, c1 = -1 + 2.0 * (k + 1) / B, p;
            if (fabs(g) < 1e-3)
                p = (c1 - c0) / 2;
            else
                p = (1 - g * g) / (2 * g) * (1 / sqrt(1 + g * g - 2 * g * c1) - 1 / sqrt(1 + g * g - 2 * g * c0));
            double ex = p * N;
            chi2 += ((double)hist[k] - ex) * ((double)hist[k] - ex) / ex;
        }
        printf("    g %+.4f: mean cos %+.5f (se %.5f), chi2 %.1f (39 dof)\n", g, mean, se, chi2);
        EXPECT_MSG(chi2 < 72.1, "g %g: chi2 %g", g, chi2);
    }
}

/* Oracle: Beer's law. Free-flight sampling over [0, tmax] with different coefficients per
 * channel: the mean weight of the rays that reach tmax is e^{-sigma_t tmax} per channel, and
 * the mean of weight * 1{t < x} over scattering events is sigma_s / sigma_t (1 - e^{-sigma_t x})
 * (the scattered fraction before x), each within 4 standard errors. */
TEST(render_media_free_flight) {
    medium m = {"m", {0.2, 0.0, 1.5}, {0.3, 0.8, 0.5}, {0.5, 0.8, 2.0}, 0};
    double tmax = 1.3, x = 0.6;
    enum { N = 200000 };
    double reach[3] = {0}, reach2[3] = {0}, sc[3] = {0}, sc2[3] = {0};
    rng r = rng_stream(3, 1, 2);
    for (int i = 0; i < N; i++) {
        double t;
        rgb w;
        int s = medium_sample_distance(&m, tmax, rng_uniform(&r), rng_uniform(&r), &t, &w);
        double wv[3] = {w.x, w.y, w.z};
        for (int k = 0; k < 3; k++) {
            double a = s ? 0 : wv[k], b = s && t < x ? wv[k] : 0;
            reach[k] += a;
            reach2[k] += a * a;
            sc[k] += b;
            sc2[k] += b * b;
        }
    }
    double st[3] = {0.5, 0.8, 2.0}, ss[3] = {0.3, 0.8, 0.5};
    for (int k = 0; k < 3; k++) {
        double mr = reach[k] / N, ser = sqrt((reach2[k] / N - mr * mr) / N);
        double ms = sc[k] / N, ses = sqrt((sc2[k] / N - ms * ms) / N);
        double er = exp(-st[k] * tmax), es = ss[k] / st[k] * (1 - exp(-st[k] * x));
        printf("    channel %d: reach %.5f (Beer %.5f), scattered before x %.5f (%.5f)\n", k, mr, er, ms, es);
        EXPECT_MSG(fabs(mr - er) < 4 * ser, "channel %d reach %g vs %g (se %g)", k, mr, er, ser);
        EXPECT_MSG(fabs(ms - es) < 4 * ses, "channel %d scatter %g vs %g (se %g)", k, ms, es, ses);
    }
}

/* ---- transmittance through a slab and a sphere -------------------------------------------- */

/* A slab |z| < 0.75 (a closed box mesh, null boundary) of an absorbing medium in front of an
 * emissive wall at z = 9, and a null sphere of a second medium at the side. */
static int slab_scene(scene *s, const char *slab_medium, const char *top, json_err *e) {
    static char txt[8192], box[2048], objs[4096];
    box_mesh(box, sizeof box, v3(-3, -3, -0.75), v3(3, 3, 0.75), -1, 0);
    snprintf(objs, sizeof objs,
             "{\"type\": \"mesh\", %s, \"material\": \"air\", \"interior_medium\": \"%s\"},"
             " {\"type\": \"sphere\", \"center\": [6, 0, 0], \"radius\": 1.25, \"material\": \"air\","
             " \"interior_medium\": \"ink\"}",
             box, slab_medium);
    snprintf(txt, sizeof txt,
             "{\"camera\": {\"eye\": [0, 0, -5], \"look_at\": [0, 0, 0], \"fov_deg\": 20, \"width\": 8, "
             "\"height\": 8},"
             " \"media\": {\"ink\": {\"sigma_a\": [0.5, 1, 2]}, \"haze\": {\"sigma_a\": [0.05, 0.1, 0.15]}}, %s"
             " \"materials\": {\"lamp\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": [1, 2, 3]},"
             " \"air\": {\"type\": \"null\"}},"
             " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-90, -90, 9], [-90, 90, 9], [90, 90, 9], "
             "[90, -90, 9]], \"material\": \"lamp\"}, %s]}",
             top, objs);
    return scene_load_text(s, txt, e);
}

static void slab_render_check(const scene *s, const double tau[3], double scale);

/* Oracle: Beer's law (deterministic, within 1e-6: the segment is offset off each null face it
 * crosses by ~1e-7, which the exponent sees): the shadow walk through the slab's two null
 * faces gives e^{-sigma_a 1.5} per channel, through the sphere's centre e^{-sigma_a 2.5}, a
 * segment that ends inside the slab e^{-sigma_a d} for the part inside, and a segment to a
 * lambert surface 0. Then the path tracer looking through the slab at the emitter: each
 * channel's mean radiance over 20000 camera rays is Le e^{-sigma_a 1.5} within 4 standard
 * errors (free flight with an absorbing medium is a random estimate of it); and again with a
 * global absorbing haze around the slab (the camera is in it): Le e^{-(12.5 haze + 1.5 ink)}. */
TEST(render_media_slab_transmittance) {
    scene s;
    json_err e = {0};
    ASSERT_MSG(slab_scene(&s, "ink", "", &e) == 0, "%s", e.msg);
    rgb T = scene_transmittance(&s, v3(0.1, 0.2, -4), v3s(0), v3(0.1, 0.2, 4), v3s(0), -1);
    EXPECT_NEAR(T.x, exp(-0.5 * 1.5), 1e-6);
    EXPECT_NEAR(T.y, exp(-1.0 * 1.5), 1e-6);
    EXPECT_NEAR(T.z, exp(-2.0 * 1.5), 1e-6);
    T = scene_transmittance(&s, v3(6, 0, -4), v3s(0), v3(6, 0, 4), v3s(0), -1);
    EXPECT_NEAR(T.z, exp(-2.0 * 2.5), 1e-6);
    T = scene_transmittance(&s, v3(0, 0, -4), v3s(0), v3(0, 0, 0.25), v3s(0), -1);
    EXPECT_NEAR(T.y, exp(-1.0 * 1.0), 1e-6);
    /* from inside the slab (starting medium given) out through one face */
    T = scene_transmittance(&s, v3(0, 0, 0.25), v3s(0), v3(0, 0, 4), v3s(0), 0);
    EXPECT_NEAR(T.x, exp(-0.5 * 0.5), 1e-6);
    T = scene_transmittance(&s, v3(0, 0, -4), v3s(0), v3(0, 0, 12), v3s(0), -1);
    EXPECT_NEAR(v3_maxc(T), 0.0, 0);
    rgb Td = scene_transmittance_dir(&s, v3(6, 0, -4), v3s(0), v3(0, 0, 1), -1);
    EXPECT_NEAR(Td.x, 0.0, 0); /* the emitter blocks the way to infinity */

    double sa[3] = {0.5, 1, 2};
    slab_render_check(&s, sa, 1.5);
    scene_free(&s);
    /* The same in a global haze: 12.5 units of it and 1.5 of the slab's ink. */
    ASSERT_MSG(slab_scene(&s, "ink", "\"medium\": \"haze\",", &e) == 0, "%s", e.msg);
    EXPECT_EQ_INT(s.camera_medium, 1);
    double hz[3] = {0.05 * 12.5 + 0.5 * 1.5, 0.1 * 12.5 + 1.5, 0.15 * 12.5 + 3};
    slab_render_check(&s, hz, 1);
    scene_free(&s);
}

/* The path tracer looking from (0, 0, -5) along +z (a narrow cone) at the emitter Le = (1, 2, 3):
 * each channel's mean radiance is Le e^{-tau scale} within 4 standard errors. */
static void slab_render_check(const scene *s, const double tau[3], double scale) {
    integrator it;
    char err[256];
    ASSERT_EQ_INT(integrator_create("path", s, &it, err, sizeof err), 0);
    enum { N = 20000 };
    double sum[3] = {0}, sum2[3] = {0};
    for (int i = 0; i < N; i++) {
        rng g = rng_stream(5, (uint64_t)i, 0);
        ray r = {v3(0, 0, -5), v3_norm(v3(0.02 * (rng_uniform(&g) - 0.5), 0.02 * (rng_uniform(&g) - 0.5), 1))};
        sample_id id = {0};
        rgb L = it.li(&it, s, r, &g, &id, NULL);
        double v[3] = {L.x, L.y, L.z};
        for (int k = 0; k < 3; k++) sum[k] += v[k], sum2[k] += v[k] * v[k];
    }
    double le[3] = {1, 2, 3};
    for (int k = 0; k < 3; k++) {
        double m = sum[k] / N, se = sqrt((sum2[k] / N - m * m) / N), want = le[k] * exp(-tau[k] * scale);
        printf("    channel %d: %.5f (Beer %.5f, se %.5f)\n", k, m, want, se);
        EXPECT_MSG(fabs(m - want) < 4 * se + 1e-12, "channel %d: %g vs %g (se %g)", k, m, want, se);
    }
    integrator_destroy(&it);
}

/* ---- furnaces ----------------------------------------------------------------------------- */

/* Mean radiance over n camera rays in uniform directions from the eye; its standard error. */
static double furnace_mean(const scene *s, int n, uint64_t seed, double *se) {
    integrator it;
    char err[256];
    *se = NAN;
    if (integrator_create("path", s, &it, err, sizeof err) < 0) return NAN;
    double sum = 0, sum2 = 0;
    for (int i = 0; i < n; i++) {
        rng g = rng_stream(seed, (uint64_t)i, 0);
        vec3 d = sample_uniform_sphere(rng_uniform(&g), rng_uniform(&g));
        ray r = {s->cam.eye, d};
        sample_id id = {0};
        rgb L = it.li(&it, s, r, &g, &id, NULL);
        double v = (L.x + L.y + L.z) / 3;
        sum += v;
        sum2 += v * v;
    }
    integrator_destroy(&it);
    double m = sum / n;
    *se = sqrt((sum2 / n - m * m) / n);
    return m;
}

/* Oracle: the furnace. Inside a closed emitter (Le = 1 from both sides, albedo rho = 0.5)
 * L = Le / (1 - rho) = 2 in every direction at every point, and a medium of albedo 1 placed
 * anywhere inside does not change that (it neither adds nor removes light from a uniform
 * field). The medium fills a ball of radius 3 (null boundary, sigma_s 0.8: optical radius
 * 2.4) inside the furnace sphere of radius 10, and the camera sits in the ball (it must find
 * that medium). Two phase functions, g = 0 and g = 0.6; 20000 rays each (5000 under the
 * sanitizers), the mean within 4 standard errors of 2 and the standard error under 2%, so
 * the test can tell: without the scattering weight (sigma_s / sigma_t), a transmittance
 * missing from next-event estimation or from the crossing of the null boundary, the mean
 * moves by tens of percent. (The ball keeps scattering points away from the emitting wall:
 * next-event estimation by area sampling has unbounded variance for points near an emitter.) */
TEST(render_media_furnace) {
    int n = PM_TEST_SANITIZED ? 5000 : 20000;
    static char txt[8192];
    const double gs[2] = {0, 0.6};
    for (int k = 0; k < 2; k++) {
        snprintf(txt, sizeof txt,
                 "{\"camera\": {\"eye\": [0.5, 0.2, -0.3], \"forward\": [0, 0, 1], \"fov_deg\": 90, \"width\": 8, \"height\": 8},"
                 " \"media\": {\"milk\": {\"sigma_s\": [0.8, 0.8, 0.8], \"g\": %g}},"
                 " \"materials\": {\"wall\": {\"type\": \"lambert\", \"reflectance\": 0.5, \"emission\": 1.0, \"two_sided\": true},"
                 " \"air\": {\"type\": \"null\"}},"
                 " \"objects\": [{\"type\": \"sphere\", \"center\": [0.3, -0.2, 0.1], \"radius\": 10, \"material\": \"wall\"},"
                 " {\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 3, \"material\": \"air\", \"interior_medium\": \"milk\"}],"
                 " \"render\": {\"max_depth\": 1000}}", gs[k]);
        scene s;
        json_err e = {0};
        ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
        EXPECT_EQ_INT(s.camera_medium, 0);
        double se, m = furnace_mean(&s, n, 21 + (uint64_t)k, &se);
        printf("    furnace with a ball of albedo-1 medium, g %.1f: %.4f (se %.4f, expected 2)\n", gs[k], m, se);
        EXPECT_MSG(fabs(m - 2) < 4 * se && se < 0.04, "mean %g se %g", m, se);
        scene_free(&s);
    }
}

/* ---- volume photons ----------------------------------------------------------------------- */

/* Oracles: a point light of power Phi in an unbounded grey medium (sigma_t = 1, albedo
 * a = 0.6; the only surface is 1000 mean free paths away). Every photon scatters first at an
 * exponential distance: n DIRECT photons, their mean distance from the light 1/sigma_t
 * within 4 standard errors, their power summing to Phi a (within 1%: RGBE rounding). Each
 * later event is stored with probability a^k: all stored power sums to Phi a / (1 - a) within
 * 4 standard errors plus 1%. No CAUSTIC photons without specular surfaces. Then a fog box
 * (null boundary, vacuum around) above a point light with a mirror below it: photons that
 * reach the fog after the mirror are CAUSTIC, those straight from the light DIRECT, and every
 * photon lies inside the box. */
TEST(render_media_volume_photons) {
    static char txt[8192], box[2048], objs[4096];
    snprintf(txt, sizeof txt,
             "{\"camera\": {\"eye\": [0, 0, -5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
             " \"media\": {\"fog\": {\"sigma_a\": 0.4, \"sigma_s\": 0.6, \"g\": 0.5}}, \"medium\": \"fog\","
             " \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
             " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-1, -1, 1000], [1, -1, 1000], [1, 1, 1000], [-1, 1, 1000]], \"material\": \"w\"}],"
             " \"lights\": [{\"type\": \"point\", \"position\": [0, 0, 0], \"power\": 10}]}");
    scene s;
    json_err e = {0};
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    uint64_t n = PM_TEST_SANITIZED ? 5000 : 20000;
    vol_photons vp;
    ASSERT_EQ_INT(vol_trace(&s, n, 9, 10000, &vp), 0);
    double pdirect = 0, dsum = 0, dsum2 = 0, ptotal = 0;
    long ndirect = 0, ncaustic = 0;
    for (size_t i = 0; i < vp.count; i++) {
        float pw[3];
        pm_rgbe_decode(vp.photons[i].power, pw);
        double v = (pw[0] + pw[1] + pw[2]) / 3;
        ptotal += v;
        int kind = pm_photon_kind(&vp.photons[i]);
        if (kind == PM_KIND_CAUSTIC) ncaustic++;
        if (kind != PM_KIND_DIRECT) continue;
        ndirect++;
        pdirect += v;
        const float *x = vp.photons[i].pos;
        double r = sqrt((double)x[0] * x[0] + (double)x[1] * x[1] + (double)x[2] * x[2]);
        dsum += r;
        dsum2 += r * r;
    }
    double mr = dsum / (double)ndirect, se = sqrt((dsum2 / (double)ndirect - mr * mr) / (double)ndirect);
    /* total power per photon: (Phi a / n) times a geometric count of mean 1/(1-a), variance a/(1-a)^2 */
    double want_total = 10 * 0.6 / 0.4, se_total = 10 * 0.6 / sqrt((double)n) * sqrt(0.6) / 0.4;
    printf("    grey medium: %ld direct (of %llu), mean distance %.4f (se %.4f, 1), direct power %.4f (6),"
           " total %.4f (%.4f, se %.4f)\n", ndirect, (unsigned long long)n, mr, se, pdirect, ptotal,
           want_total, se_total);
    EXPECT_EQ_INT(ndirect, (long)n);
    EXPECT_EQ_INT(ncaustic, 0);
    EXPECT_MSG(fabs(mr - 1) < 4 * se, "mean distance %g (se %g)", mr, se);
    EXPECT_NEAR(pdirect, 6.0, 0.06);
    EXPECT_MSG(fabs(ptotal - want_total) < 4 * se_total + 0.01 * want_total, "total %g", ptotal);
    free(vp.photons);
    scene_free(&s);

    box_mesh(box, sizeof box, v3(-1, -1, 2), v3(1, 1, 4), -1, 0);
    snprintf(objs, sizeof objs, "{\"type\": \"mesh\", %s, \"material\": \"air\", \"interior_medium\": \"fog\"}", box);
    snprintf(txt, sizeof txt,
             "{\"camera\": {\"eye\": [0, 0, -5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
             " \"media\": {\"fog\": {\"sigma_s\": 0.5}},"
             " \"materials\": {\"m\": {\"type\": \"mirror\"}, \"air\": {\"type\": \"null\"}},"
             " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-3, -3, -0.5], [3, -3, -0.5], [3, 3, -0.5], [-3, 3, -0.5]], \"material\": \"m\"}, %s],"
             " \"lights\": [{\"type\": \"point\", \"position\": [0, 0, 0], \"power\": 10}]}", objs);
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(vol_trace(&s, n, 10, 100, &vp), 0);
    long nk[4] = {0}, outside = 0;
    for (size_t i = 0; i < vp.count; i++) {
        nk[pm_photon_kind(&vp.photons[i])]++;
        const float *x = vp.photons[i].pos;
        if (fabsf(x[0]) > 1.001f || fabsf(x[1]) > 1.001f || x[2] < 1.999f || x[2] > 4.001f) outside++;
    }
    printf("    fog box over a mirror: %ld direct, %ld caustic, %ld indirect, %ld outside the box\n",
           nk[PM_KIND_DIRECT], nk[PM_KIND_CAUSTIC], nk[PM_KIND_INDIRECT], outside);
    EXPECT_MSG(nk[PM_KIND_DIRECT] > 0 && nk[PM_KIND_CAUSTIC] > 0, "direct %ld caustic %ld", nk[PM_KIND_DIRECT],
               nk[PM_KIND_CAUSTIC]);
    EXPECT_EQ_INT(outside, 0);
    free(vp.photons);
    scene_free(&s);
}

/* ---- photon mapping with media ------------------------------------------------------------ */

/* A closed room [-1, 1]^3 of grey-brown lambert walls (normals inward: its inside is the front
 * side) lit by a small downward lamp under the ceiling, with a fog (RGB sigma_s, g 0.3) filling
 * a null box [-0.95, 0.95] x [-0.95, 0.7] x [-0.95, 0.95] that stops 0.29 below the lamp, so
 * scattering points never come close to the emitter (next-event estimation near an emitter
 * has unbounded variance, and the path-traced reference must be trustworthy). The camera is
 * inside the fog. global_fog = 1 fills the whole room with the fog instead (the global
 * medium; no null box): media do not nest, so only then does a glass object in the room have
 * fog around it. */
static void fog_room_with(char *txt, size_t cap, int global_fog, const char *fog_medium, vec3 fog_lo,
                          vec3 fog_hi, const char *more_objects) {
    static char room[2048], fog[2048], fogobj[2560];
    box_mesh(room, sizeof room, v3(-1, -1, -1), v3(1, 1, 1), -1, 1);
    box_mesh(fog, sizeof fog, fog_lo, fog_hi, -1, 0);
    if (global_fog)
        fogobj[0] = 0;
    else
        snprintf(fogobj, sizeof fogobj,
                 " {\"type\": \"mesh\", %s, \"material\": \"air\", \"interior_medium\": \"fog\"},", fog);
    snprintf(txt, cap,
             "{\"camera\": {\"eye\": [0, 0, -0.9], \"look_at\": [0, 0, 1], \"fov_deg\": 70, \"width\": 16, \"height\": 16},"
             " \"media\": {\"fog\": %s}, %s"
             " \"materials\": {\"wall\": {\"type\": \"lambert\", \"reflectance\": [0.6, 0.5, 0.4]},"
             " \"air\": {\"type\": \"null\"}, \"glass\": {\"type\": \"dielectric\", \"ior\": 1.5},"
             " \"lamp\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 20}},"
             " \"objects\": [{\"type\": \"mesh\", %s, \"material\": \"wall\"},%s"
             " {\"type\": \"quad\", \"vertices\": [[0.25, 0.99, -0.25], [0.25, 0.99, 0.25], [-0.25, 0.99, 0.25],"
             " [-0.25, 0.99, -0.25]], \"material\": \"lamp\"}%s]}",
             fog_medium, global_fog ? "\"medium\": \"fog\"," : "", room, fogobj, more_objects);
}

static void fog_room(char *txt, size_t cap, int global_fog, const char *more_objects) {
    fog_room_with(txt, cap, global_fog, "{\"sigma_a\": 0.05, \"sigma_s\": [0.5, 0.6, 0.7], \"g\": 0.3}",
                  v3(-0.95, -0.95, -0.95), v3(0.95, 0.7, 0.95), more_objects);
}

static double rect_mean(const film *f, int x0, int y0, int x1, int y1) {
    double sum = 0;
    for (int y = y0; y < y1; y++)
        for (int x = x0; x < x1; x++) {
            rgb c = film_get(f, x, y);
            sum += c.x + c.y + c.z;
        }
    return sum / (3.0 * (x1 - x0) * (y1 - y0));
}

/* Oracle: path tracing (4096 samples per pixel at 16x16; the quadrant means of two seeds
 * agree within 1%). Photon mapping of the fog room (50,000 global and 100,000 volume photons,
 * 32 samples): each quadrant's mean within 5% of path tracing, and the image mean within 3%.
 * (With 20,000 volume photons the estimates' radius, about a third of the fog box, blurs light
 * out of the fog's edges and the quadrants read 3-7% low: the tolerance is the bias of the
 * density estimate at these photon counts, stated, not noise.) Then --mode pm exits 0 on a
 * scene with media and prints the plan's volume line. */
TEST(render_media_pm_matches_path_in_fog) {
    static char txt[16384];
    fog_room(txt, sizeof txt, 0, "");
    char scene_path[1024], pt[1024], pm[1024], cmd[8192];
    static char out[65536];
    snprintf(scene_path, sizeof scene_path, "%s/fog_room.json", pm_test_tmpdir());
    snprintf(pt, sizeof pt, "%s/fog_pt.pfm", pm_test_tmpdir());
    snprintf(pm, sizeof pm, "%s/fog_pm.pfm", pm_test_tmpdir());
    FILE *f = fopen(scene_path, "w");
    ASSERT(f != NULL);
    fputs(txt, f);
    fclose(f);
    int spp_pt = PM_TEST_SANITIZED ? 256 : 4096, spp_pm = PM_TEST_SANITIZED ? 4 : 32;
    snprintf(cmd, sizeof cmd, "cd '%s' && %s/render '%s' --mode path --spp %d --quiet --hdr '%s' -o pt.png",
             pm_test_tmpdir(), pm_test_build_dir(), scene_path, spp_pt, pt);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    snprintf(cmd, sizeof cmd,
             "cd '%s' && %s/render '%s' --mode pm --spp %d --hdr '%s' -o pm.png --pm progress=false"
             " --pm global_photons=50000 --pm volume_photons=100000",
             pm_test_tmpdir(), pm_test_build_dir(), scene_path, spp_pm, pm);
    int rc = pm_test_run(cmd, out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "volume: on (medium \"fog\" is lit") != NULL, "%s", out);
    film a, b;
    ASSERT(film_read_pfm(&a, pt) == 0);
    ASSERT(film_read_pfm(&b, pm) == 0);
    double tol = PM_TEST_SANITIZED ? 0.25 : 0.05;
    for (int q = 0; q < 4; q++) {
        int x0 = (q & 1) * 8, y0 = (q >> 1) * 8;
        double mp = rect_mean(&a, x0, y0, x0 + 8, y0 + 8), mm = rect_mean(&b, x0, y0, x0 + 8, y0 + 8);
        printf("    quadrant %d: path %.4f, pm %.4f (%+.2f%%)\n", q, mp, mm, 100 * (mm / mp - 1));
        EXPECT_MSG(fabs(mm / mp - 1) < tol, "quadrant %d: %+.2f%%", q, 100 * (mm / mp - 1));
    }
    double all_p = rect_mean(&a, 0, 0, 16, 16), all_m = rect_mean(&b, 0, 0, 16, 16);
    printf("    image: path %.4f, pm %.4f (%+.2f%%)\n", all_p, all_m, 100 * (all_m / all_p - 1));
    EXPECT_MSG(fabs(all_m / all_p - 1) < (PM_TEST_SANITIZED ? 0.2 : 0.03), "image %+.2f%%",
               100 * (all_m / all_p - 1));
    film_free(&a);
    film_free(&b);
}

/* Oracle: path tracing. The fog room with a DENSE fog in a null cube [-0.5, 0.5]^3 seen from
 * outside (sigma_s [8, 10, 12], sigma_a 0.5, g 0.3: 8.5 to 12.5 mean free paths across, albedo
 * 0.94 to 0.96): nearly all the light the camera gets is scattered within a mean free path
 * (0.08 to 0.12) of the cube's faces, where a volume estimate's ball reaches out of the fog.
 * Path tracing 2 x 2048 spp at 16x16 (two seeds: their quadrant means differ by at most 1%,
 * printed); photon mapping 16 spp with 100,000 volume photons (k 24 by the density rule,
 * pm_volume.h). Each quadrant's mean within 5% of path tracing and the image within 3%
 * (measured: quadrants -1.7% .. +3.3%, image +0.8%; with 400,000 photons -4.1% .. +0.9%).
 * The same render with volume_boundary=false (dividing by the whole ball) must read at least
 * 3% low over the image (measured -6.3%, quadrants -8.2% .. -3.4%), so the scene does
 * exercise the boundary. Before the boundary and density rules (k 50, whole ball): quadrants
 * -7.0% .. -2.3% at 100,000 photons and -10.0% .. -5.3% at 400,000. */
TEST(render_media_pm_matches_path_in_dense_fog) {
    static char txt[16384];
    fog_room_with(txt, sizeof txt, 0, "{\"sigma_a\": 0.5, \"sigma_s\": [8, 10, 12], \"g\": 0.3}",
                  v3(-0.5, -0.5, -0.5), v3(0.5, 0.5, 0.5), "");
    char scene_path[1024], pt[2][1024], pm[2][1024], cmd[8192];
    static char out[65536];
    snprintf(scene_path, sizeof scene_path, "%s/dense_fog.json", pm_test_tmpdir());
    for (int i = 0; i < 2; i++) {
        snprintf(pt[i], sizeof pt[i], "%s/dense_pt%d.pfm", pm_test_tmpdir(), i);
        snprintf(pm[i], sizeof pm[i], "%s/dense_pm%d.pfm", pm_test_tmpdir(), i);
    }
    FILE *f = fopen(scene_path, "w");
    ASSERT(f != NULL);
    fputs(txt, f);
    fclose(f);
    int spp_pt = PM_TEST_SANITIZED ? 128 : DENSE_PT_SPP, spp_pm = PM_TEST_SANITIZED ? 1 : DENSE_PM_SPP;
    long nph = PM_TEST_SANITIZED ? 100000 : DENSE_VOLPH;
    for (int i = 0; i < 2; i++) {
        snprintf(cmd, sizeof cmd,
                 "cd '%s' && %s/render '%s' --mode path --spp %d --seed %d --quiet --hdr '%s' -o pt.png",
                 pm_test_tmpdir(), pm_test_build_dir(), scene_path, spp_pt / 2, 11 + i, pt[i]);
        ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
        snprintf(cmd, sizeof cmd,
                 "cd '%s' && %s/render '%s' --mode pm --spp %d --quiet --hdr '%s' -o pm.png"
                 " --pm global_photons=50000 --pm volume_photons=%ld --pm volume_boundary=%s",
                 pm_test_tmpdir(), pm_test_build_dir(), scene_path, spp_pm, pm[i], nph, i ? "false" : "true");
        int rc = pm_test_run(cmd, out, sizeof out);
        ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    }
    film a[2], b[2];
    for (int i = 0; i < 2; i++) {
        ASSERT(film_read_pfm(&a[i], pt[i]) == 0);
        ASSERT(film_read_pfm(&b[i], pm[i]) == 0);
    }
    double tol = PM_TEST_SANITIZED ? 0.3 : 0.05, lo[2] = {1, 1}, hi[2] = {-1, -1};
    for (int q = 0; q < 4; q++) {
        int x0 = (q & 1) * 8, y0 = (q >> 1) * 8;
        double p0 = rect_mean(&a[0], x0, y0, x0 + 8, y0 + 8), p1 = rect_mean(&a[1], x0, y0, x0 + 8, y0 + 8);
        double mp = (p0 + p1) / 2, d[2];
        for (int i = 0; i < 2; i++) {
            d[i] = rect_mean(&b[i], x0, y0, x0 + 8, y0 + 8) / mp - 1;
            lo[i] = fmin(lo[i], d[i]);
            hi[i] = fmax(hi[i], d[i]);
        }
        printf("    quadrant %d: path %.4f (seeds differ %+.2f%%), pm %+.2f%%, pm without the boundary "
               "rule %+.2f%%\n", q, mp, 100 * (p1 / p0 - 1), 100 * d[0], 100 * d[1]);
        EXPECT_MSG(fabs(d[0]) < tol, "quadrant %d: %+.2f%%", q, 100 * d[0]);
    }
    double all_p = (rect_mean(&a[0], 0, 0, 16, 16) + rect_mean(&a[1], 0, 0, 16, 16)) / 2;
    double all_m = rect_mean(&b[0], 0, 0, 16, 16) / all_p - 1, all_n = rect_mean(&b[1], 0, 0, 16, 16) / all_p - 1;
    printf("    image: pm %+.2f%% (quadrants %+.2f%% .. %+.2f%%); without the rule %+.2f%% (%+.2f%% .. %+.2f%%)\n",
           100 * all_m, 100 * lo[0], 100 * hi[0], 100 * all_n, 100 * lo[1], 100 * hi[1]);
    EXPECT_MSG(fabs(all_m) < (PM_TEST_SANITIZED ? 0.2 : 0.03), "image %+.2f%%", 100 * all_m);
    if (!PM_TEST_SANITIZED) EXPECT_MSG(all_n < -0.03, "without the boundary rule: image %+.2f%%", 100 * all_n);
    for (int i = 0; i < 2; i++) {
        film_free(&a[i]);
        film_free(&b[i]);
    }
}

/* Oracle: the volume of a ball cut by planes (a cap beyond a plane at distance h is
 * pi (r - h)^2 (2r + h) / 3). In a null cube [-1, 1]^3 filled with fog: a ball of radius 0.5
 * at the centre is whole (1); at distance h = 0.2 from the face x = 1 it keeps
 * 1 - (0.6)^2 2.4 / 4 = 0.784; touching the face (h = 0) 1/2; at an edge 1/4, at a corner 1/8
 * (the floor); two faces at 0.2 and 0.3 on the x axis (a ball of radius 1 at x = 0.8 in a
 * slab... here: radius 1.0 at (0.8, 0, 0) reaches x = 1 at 0.2 and x = -1 at 1.8 > r) gives
 * 1 - cap(0.2). A ball of infinite or zero radius: 1. */
TEST(render_media_pm_ball_fraction) {
    static char txt[8192], box[2048];
    box_mesh(box, sizeof box, v3(-1, -1, -1), v3(1, 1, 1), -1, 0);
    snprintf(txt, sizeof txt,
             "{\"camera\": {\"eye\": [0, 0, -5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
             " \"media\": {\"fog\": {\"sigma_s\": 1}}, \"materials\": {\"air\": {\"type\": \"null\"}},"
             " \"objects\": [{\"type\": \"mesh\", %s, \"material\": \"air\", \"interior_medium\": \"fog\"}],"
             " \"lights\": [{\"type\": \"point\", \"position\": [0, 3, 0], \"power\": 10}]}",
             box);
    scene s;
    json_err e = {0};
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    struct {
        vec3 x;
        double r, want;
    } c[] = {
        {{0, 0, 0}, 0.5, 1},
        {{0.8, 0, 0}, 0.5, 1 - 0.6 * 0.6 * 2.4 / 4},
        {{0, -0.8, 0}, 0.5, 1 - 0.6 * 0.6 * 2.4 / 4},
        {{0, 0, 0.8}, 1.0, 1 - 0.8 * 0.8 * 2.2 / 4},
        {{1 - 1e-9, 0, 0}, 0.5, 0.5},
        {{1 - 1e-9, 1 - 1e-9, 0}, 0.5, 0.25},
        {{1 - 1e-9, 1 - 1e-9, -1 + 1e-9}, 0.5, 0.125},
        {{0.5, 0.5, 0.5}, 0.5, 1},
        {{0, 0, 0}, INFINITY, 1},
        {{0.9, 0, 0}, 0, 1},
    };
    for (size_t i = 0; i < sizeof c / sizeof c[0]; i++) {
        double got = pmv_ball_fraction(&s, c[i].x, c[i].r);
        printf("    x (%g, %g, %g) r %g: %.6f (want %.6f)\n", c[i].x.x, c[i].x.y, c[i].x.z, c[i].r, got, c[i].want);
        EXPECT_MSG(fabs(got - c[i].want) < 1e-6, "case %zu: %.9f vs %.9f", i, got, c[i].want);
    }
    scene_free(&s);
}

/* Oracle: the rule of pm_volume.h (STEP, k AND RADII), recomputed from each tree's photons.
 * A thin fog (sigma_t 0.1: mean free path 10, much longer than any radius) over a floor and a
 * denser smoke ball (sigma_t 3.3: mfp 0.3) in it, 20,000 volume photons: the fog's trees keep
 * k_volume 50 and radius 2 r_typ(50); the smoke's trees, whose r_typ(50) exceeds mfp / 2, get
 * k = max(16, floor(50 (mfp / 2 / r_typ(50))^3)) < 50 and radius 2 r_typ(k), which is at most
 * mfp unless k hit 16. Checked for the multiple-scattering and "all" trees. */
TEST(render_media_pm_k_follows_density) {
    static char txt[8192];
    snprintf(txt, sizeof txt,
             "{\"camera\": {\"eye\": [0, 0, -2.5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
             " \"medium\": \"fog\", \"media\": {\"fog\": {\"sigma_s\": 0.1}, \"smoke\": {\"sigma_a\": 0.3, \"sigma_s\": 3}},"
             " \"materials\": {\"air\": {\"type\": \"null\"}, \"wall\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
             " \"objects\": [{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 0.5, \"material\": \"air\","
             " \"interior_medium\": \"smoke\"}, {\"type\": \"quad\", \"vertices\": [[-3, -1, -3], [-3, -1, 3], [3, -1, 3], [3, -1, -3]],"
             " \"material\": \"wall\"}],"
             " \"lights\": [{\"type\": \"point\", \"position\": [0, 2, 0], \"power\": 10}]}");
    scene s;
    json_err e = {0};
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    photon_settings cfg;
    photon_settings_defaults(&cfg);
    cfg.volume_photons = 20000;
    cfg.global_photons = 2000;
    cfg.progress = 0;
    render_plan p;
    plan_make(&s, &cfg, 0, &p, NULL, 0);
    ASSERT(p.volume.on);
    pmv_state v;
    photon_maps m;
    char err[256] = "";
    ASSERT_EQ_INT(pmv_init(&v, &s, &cfg), 0);
    ASSERT_MSG(pmv_trace(&v, &s, &cfg, &p, &m, err, sizeof err) == 0, "%s", err);
    int reduced = 0;
    for (int md = 0; md < s.nmedia; md++)
        for (int w = 0; w < 2; w++) {
            const pmv_map *t = w ? &v.all[md] : &v.ms[md];
            if (t->n == 0) continue;
            float lo[3], hi[3];
            for (int a = 0; a < 3; a++) lo[a] = hi[a] = t->a[0].pos[a];
            for (size_t i = 1; i < t->n; i++)
                for (int a = 0; a < 3; a++) {
                    lo[a] = fminf(lo[a], t->a[i].pos[a]);
                    hi[a] = fmaxf(hi[a], t->a[i].pos[a]);
                }
            double ext = 0, vol = 1;
            for (int a = 0; a < 3; a++) ext = fmax(ext, (double)hi[a] - lo[a]);
            for (int a = 0; a < 3; a++) vol *= fmax((double)hi[a] - lo[a], 1e-3 * ext);
            double mfp = 1 / v3_maxc(s.media[md].sigma_t);
            double rt50 = cbrt(3.0 * 50 * vol / (4 * M_PI * (double)t->n));
            unsigned k = 50;
            if (rt50 > mfp / 2) {
                double kk = floor(50 * pow(mfp / 2 / rt50, 3));
                k = kk < 16 ? 16 : (unsigned)kk;
            }
            double r = 2 * cbrt(3.0 * k * vol / (4 * M_PI * (double)t->n));
            printf("    medium %s, %s tree: %zu photons, mfp %.4g, r_typ(50) %.4g: k %u (rule %u), radius %.4g "
                   "(rule %.4g)\n", s.media[md].name, w ? "all" : "multiple-scattering", t->n, mfp, rt50, t->k, k,
                   sqrt((double)t->r2), r);
            EXPECT_EQ_INT((int)t->k, (int)k);
            EXPECT_MSG(fabs(sqrt((double)t->r2) / r - 1) < 1e-5, "radius %.6g vs %.6g", sqrt((double)t->r2), r);
            if (k < 50) {
                reduced++;
                EXPECT_MSG(k == 16 || r <= mfp * (1 + 1e-9), "radius %.4g > 2 mfp / 2", r);
            }
            if (mfp > 1) EXPECT_EQ_INT((int)t->k, 50);
        }
    EXPECT_MSG(reduced >= 1, "the smoke's trees should have a smaller k");
    photon_maps_free(&m);
    pmv_free(&v);
    scene_free(&s);
}

/* The mean of n pm radiance values along r (fresh streams), through the integrator API. */
static rgb pm_mean(const scene *s, ray r, int n) {
    integrator it;
    char err[256];
    rgb sum = v3s(0);
    if (integrator_create("pm", s, &it, err, sizeof err) < 0) return v3s(NAN);
    if (it.preprocess && it.preprocess(&it, s, err, sizeof err) < 0) {
        printf("    preprocess: %s\n", err);
        integrator_destroy(&it);
        return v3s(NAN);
    }
    void *sc = it.thread_begin ? it.thread_begin(&it) : NULL;
    for (int i = 0; i < n; i++) {
        rng g = rng_stream(31, (uint64_t)i, 0);
        sample_id id = {0};
        sum = v3_add(sum, it.li(&it, s, r, &g, &id, sc));
    }
    if (it.thread_end) it.thread_end(&it, sc);
    integrator_destroy(&it);
    return v3_scale(sum, 1.0 / n);
}

/* Oracle: Beer's law, exactly. In a medium that only absorbs (sigma_s = 0) photon mapping has
 * nothing to estimate: the camera sees the emitter through the slab (null faces) times
 * e^{-sigma_a 1.5} per channel, and with a global haze around it e^{-(12.5 haze + 1.5 ink)}
 * (both lengths divided by the ray's d.z: it is slanted); each pm value equals that within
 * 1e-6 relative (no randomness enters). The plan says the
 * media only attenuate. */
TEST(render_media_pm_absorbing_exact) {
    for (int k = 0; k < 2; k++) {
        scene s;
        json_err e = {0};
        ASSERT_MSG(slab_scene(&s, "ink", k ? "\"medium\": \"haze\"," : "", &e) == 0, "%s", e.msg);
        double tau[3] = {0.5 * 1.5, 1.0 * 1.5, 2.0 * 1.5};
        if (k) {
            tau[0] += 0.05 * 12.5;
            tau[1] += 0.1 * 12.5;
            tau[2] += 0.15 * 12.5;
        }
        ray r = {v3(0, 0, -5), v3_norm(v3(0.01, -0.005, 1))};
        rgb L = pm_mean(&s, r, 4);
        double le[3] = {1, 2, 3}, got[3] = {L.x, L.y, L.z};
        for (int c = 0; c < 3; c++) {
            double want = le[c] * exp(-tau[c] / r.d.z); /* the slanted ray's longer path */
            printf("    %s channel %d: pm %.8f, Beer %.8f\n", k ? "haze + ink" : "ink", c, got[c], want);
            EXPECT_MSG(fabs(got[c] / want - 1) < 1e-6, "channel %d: %.9g vs %.9g", c, got[c], want);
        }
        photon_settings cfg;
        photon_settings_defaults(&cfg);
        render_plan p;
        plan_make(&s, &cfg, 0, &p, NULL, 0);
        EXPECT_MSG(!p.volume.on && strstr(p.volume.reason, "sigma_s = 0"), "volume: %s", p.volume.reason);
        scene_free(&s);
    }
}

/* Oracle: single scattering in a slab, analytic. A fog slab 0 < z < 1 (a null box 100 wide,
 * sigma_s 0.2, sigma_a 0.3, HG g 0.5) in vacuum under a directional light travelling along -z
 * (irradiance E = 2). With the volume map forced off, photon mapping's radiance along a camera
 * ray from z0 = 0.2 in direction d is single scattering alone:
 *   L = sigma_s p(d.z) E e^{-sigma_t (1 - z0)} (1 - e^{-sigma_t T (1 - d.z)}) / (sigma_t (1 - d.z))
 * with T the distance to where the ray leaves the slab (the light's path to a point at
 * height z is 1 - z; the phase angle is between the light's travel -z and the path's -d).
 * Two directions (level, T = 50; rising at d.z = 0.447, leaving by the top), the mean of 1024
 * rays within 0.5% per channel (only the march's random offset varies: in four steps of the
 * rising ray one offset shifts the sum by up to 6%, a standard error of 0.11% over 1024). With the volume map
 * on, multiple scattering adds light: the mean rises above single scattering (by less than
 * the slab's albedo 0.4 allows: less than 1 / (1 - 0.4) times). */
TEST(render_media_pm_single_scattering_slab) {
    static char txt[8192], box[2048];
    box_mesh(box, sizeof box, v3(-50, -50, 0), v3(50, 50, 1), -1, 0);
    const double ss = 0.2, st = 0.5, gg = 0.5, E = 2, z0 = 0.2;
    for (int on = 0; on < 2; on++) {
        snprintf(txt, sizeof txt,
                 "{\"camera\": {\"eye\": [0, 0, 0.2], \"look_at\": [1, 0, 0.2], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
                 " \"media\": {\"fog\": {\"sigma_a\": 0.3, \"sigma_s\": 0.2, \"g\": 0.5}},"
                 " \"materials\": {\"air\": {\"type\": \"null\"}},"
                 " \"objects\": [{\"type\": \"mesh\", %s, \"material\": \"air\", \"interior_medium\": \"fog\"}],"
                 " \"lights\": [{\"type\": \"directional\", \"direction\": [0, 0, -1], \"irradiance\": 2}],"
                 " \"photon_mapping\": {\"volume\": %s, \"volume_photons\": 20000, \"progress\": false}}",
                 box, on ? "true" : "false");
        scene s;
        json_err e = {0};
        ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
        EXPECT_EQ_INT(s.camera_medium, 0);
        vec3 dirs[2] = {v3(1, 0, 0), v3_norm(v3(1, 0, 0.5))};
        for (int k = 0; k < 2; k++) {
            vec3 d = dirs[k];
            double T = d.z > 0 ? (1 - z0) / d.z : 50;
            double p = (1 - gg * gg) / (4 * M_PI * pow(1 + gg * gg - 2 * gg * d.z, 1.5));
            double want = ss * p * E * exp(-st * (1 - z0)) * -expm1(-st * T * (1 - d.z)) / (st * (1 - d.z));
            rgb L = pm_mean(&s, (ray){v3(0, 0, z0), d}, PM_TEST_SANITIZED ? 256 : 1024);
            printf("    volume map %s, d.z %.3f: pm %.6f, single scattering %.6f (%+.3f%%)\n", on ? "on" : "off",
                   d.z, L.x, want, 100 * (L.x / want - 1));
            if (!on) {
                EXPECT_MSG(fabs(L.x / want - 1) < 0.005 && fabs(L.z / want - 1) < 0.005, "%g vs %g", L.x, want);
            } else {
                EXPECT_MSG(L.x > want * 1.01 && L.x < want / (1 - 0.4), "%g vs single %g", L.x, want);
            }
        }
        scene_free(&s);
    }
}

/* Oracle: the plan's rules on scenes whose answer is known by construction. A scene without
 * a medium builds no volume map and says so; the lit fog room prints `volume: on (medium
 * "fog" is lit ...` with pilot counts, no volume caustics (no specular surface) and no shadow
 * photons (the room's null fog box is no specular surface); a glass ball in the fog (the
 * room filled with it) under the lamp makes volume caustics, naming "glass". */
TEST(render_media_pm_plan) {
    static char txt[16384];
    photon_settings cfg;
    photon_settings_defaults(&cfg);
    render_plan p;
    scene s;
    json_err e = {0};
    scene_text(txt, sizeof txt, "", "\"lights\": [{\"type\": \"point\", \"position\": [0, 0, 0], \"power\": 10}],",
               "\"x\": {\"type\": \"lambert\", \"reflectance\": 0}",
               "{\"type\": \"sphere\", \"center\": [0, 0, 3], \"radius\": 1, \"material\": \"white\"}");
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    plan_make(&s, &cfg, 0, &p, NULL, 0);
    printf("    no medium: volume: %s\n", p.volume.reason);
    EXPECT_MSG(!p.volume.on && strstr(p.volume.reason, "no participating medium"), "%s", p.volume.reason);
    EXPECT(!p.volume_caustics.on);
    scene_free(&s);

    fog_room(txt, sizeof txt, 0, "");
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    plan_make(&s, &cfg, 0, &p, NULL, 0);
    printf("    fog room: volume: %s\n    volume caustics: %s\n", p.volume.reason, p.volume_caustics.reason);
    EXPECT_MSG(p.volume.on && strstr(p.volume.reason, "medium \"fog\" is lit by the lights: "), "%s",
               p.volume.reason);
    EXPECT_MSG(!p.volume_caustics.on && strstr(p.volume_caustics.reason, "no specular"), "%s",
               p.volume_caustics.reason);
    EXPECT(!p.shadow.on);
    EXPECT(p.global.on);
    scene_free(&s);

    fog_room(txt, sizeof txt, 1,
             ", {\"type\": \"sphere\", \"center\": [0, 0.2, 0], \"radius\": 0.3, \"material\": \"glass\"}");
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    plan_make(&s, &cfg, 0, &p, NULL, 0);
    printf("    glass ball in the fog: volume caustics: %s\n", p.volume_caustics.reason);
    EXPECT_MSG(p.volume_caustics.on && strstr(p.volume_caustics.reason, "\"glass\" sends light into a medium"),
               "%s", p.volume_caustics.reason);
    scene_free(&s);
}

/* Oracle: determinism. vol_trace_pass on the fog room gives the same photons, byte for byte,
 * on 1 and on 2 threads (both maps of the global pass, and the emitted counts), and so does a
 * photon-mapping render of it (the PFMs of --threads 1 and 2 are the same bytes). */
TEST(render_media_volume_pass_thread_independent) {
    static char txt[16384];
    fog_room(txt, sizeof txt, 0, "");
    scene s;
    json_err e = {0};
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    vol_pass_result r[2];
    for (int t = 0; t < 2; t++) {
        vol_pass_opts o = {0};
        o.surface_target = 5000;
        o.volume_target = 7000;
        o.max_emitted = 1e6;
        o.max_depth = 20;
        o.seed = 3;
        o.threads = t + 1;
        o.lo = v3s(1);
        o.hi = v3s(-1);
        ASSERT_EQ_INT(vol_trace_pass(&s, &o, &r[t]), 0);
    }
    printf("    %zu surface photons (%llu emitted), %zu volume photons (%llu emitted)\n", r[0].nsurface,
           (unsigned long long)r[0].surface_emitted, r[0].nvolume, (unsigned long long)r[0].volume_emitted);
    EXPECT(r[0].nsurface >= 5000 && r[0].nvolume >= 7000);
    EXPECT(r[0].nsurface == r[1].nsurface && r[0].nvolume == r[1].nvolume);
    EXPECT(r[0].surface_emitted == r[1].surface_emitted && r[0].volume_emitted == r[1].volume_emitted);
    if (r[0].nsurface == r[1].nsurface && r[0].nvolume == r[1].nvolume) {
        EXPECT(memcmp(r[0].surface, r[1].surface, r[0].nsurface * sizeof *r[0].surface) == 0);
        EXPECT(memcmp(r[0].volume, r[1].volume, r[0].nvolume * sizeof *r[0].volume) == 0);
    }
    vol_pass_free(&r[0]);
    vol_pass_free(&r[1]);
    scene_free(&s);
    char scene_path[1024], cmd[8192], pfm[2][1024];
    static char out[16384];
    snprintf(scene_path, sizeof scene_path, "%s/fog_room_threads.json", pm_test_tmpdir());
    FILE *f = fopen(scene_path, "w");
    ASSERT(f != NULL);
    fputs(txt, f);
    fclose(f);
    for (int t = 0; t < 2; t++) {
        snprintf(pfm[t], sizeof pfm[t], "%s/threads%d.pfm", pm_test_tmpdir(), t + 1);
        snprintf(cmd, sizeof cmd,
                 "cd '%s' && %s/render '%s' --mode pm --spp 4 --threads %d --quiet --hdr '%s' -o t.png"
                 " --pm global_photons=10000 --pm volume_photons=10000",
                 pm_test_tmpdir(), pm_test_build_dir(), scene_path, t + 1, pfm[t]);
        int rc = pm_test_run(cmd, out, sizeof out);
        ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    }
    size_t na = 0, nb = 0;
    char *a = NULL, *b = NULL;
    FILE *fa = fopen(pfm[0], "rb"), *fb = fopen(pfm[1], "rb");
    if (fa && fb) {
        static char ba[1 << 16], bb[1 << 16];
        na = fread(ba, 1, sizeof ba, fa);
        nb = fread(bb, 1, sizeof bb, fb);
        a = ba;
        b = bb;
    }
    if (fa) fclose(fa);
    if (fb) fclose(fb);
    ASSERT(a && b);
    EXPECT_MSG(na > 0 && na == nb && memcmp(a, b, na) == 0, "the renders on 1 and 2 threads differ");
#ifndef _OPENMP
    /* OPENMP=0: the "2 threads" run above was the same one-thread program, so the comparison
     * could not fail; the other checks ran. */
    SKIP("built without OpenMP (OPENMP=0): 1 and 2 threads are the same program here");
#endif
}

/* Oracle: the rule of pm_volume.h (RADIANCE INSIDE GLASS). The renderer's radiance is not
 * scaled at refraction and photons carry physical power, so a volume estimate inside a
 * refractive object of index n, with medium_ior n_0 around it, is scaled by (n_0 / n)^2:
 * 1/2.25 for smoke in glass of index 1.5 in air, (1.33/1.5)^2 under water (medium_ior 1.33),
 * 1 for a medium behind null surfaces and for the global medium. (Without the scale the smoke
 * of glass_of_smoke read +103% against path tracing; with it -2%.) */
TEST(render_media_pm_glass_scale) {
    static char txt[8192];
    const double nio[2] = {1.0, 1.33};
    for (int k = 0; k < 2; k++) {
        snprintf(txt, sizeof txt,
                 "{\"camera\": {\"eye\": [0, 0, -5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
                 " \"medium_ior\": %g, \"medium\": \"haze\","
                 " \"media\": {\"smoke\": {\"sigma_s\": 2}, \"fog\": {\"sigma_s\": 1}, \"haze\": {\"sigma_s\": 0.01}},"
                 " \"materials\": {\"glass\": {\"type\": \"dielectric\", \"ior\": 1.5}, \"air\": {\"type\": \"null\"}},"
                 " \"objects\": [{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, \"material\": \"glass\","
                 " \"interior_medium\": \"smoke\"}, {\"type\": \"sphere\", \"center\": [3, 0, 0], \"radius\": 1,"
                 " \"material\": \"air\", \"interior_medium\": \"fog\"}],"
                 " \"lights\": [{\"type\": \"point\", \"position\": [0, 3, 0], \"power\": 10}]}",
                 nio[k]);
        scene s;
        json_err e = {0};
        ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
        photon_settings cfg;
        photon_settings_defaults(&cfg);
        pmv_state v;
        ASSERT_EQ_INT(pmv_init(&v, &s, &cfg), 0);
        double q = nio[k] / 1.5;
        EXPECT_NEAR(v.n2_scale[0], q * q, 1e-12); /* smoke, in the glass */
        EXPECT_NEAR(v.n2_scale[1], 1.0, 0);       /* fog, behind null surfaces */
        EXPECT_NEAR(v.n2_scale[2], 1.0, 0);       /* haze, the global medium */
        printf("    medium_ior %.2f: smoke in glass %.6f ((n_0/1.5)^2 = %.6f), fog %.1f, haze %.1f\n", nio[k],
               v.n2_scale[0], q * q, v.n2_scale[1], v.n2_scale[2]);
        pmv_free(&v);
        scene_free(&s);
    }
}

/* ---- pass budgets of the volume passes (volume.h BUDGETS) ---------------------------------- */

/* A point light at the centre of a closed mirror cube [-1, 1]^3 filled with a global medium
 * (sigma_a, sigma_s); the camera outside, looking away (its rays see only fog). With albedo 1
 * no photon is ever absorbed or escapes: it scatters until the path-length budget ends it. */
static void mirror_fog(char *buf, size_t cap, double sigma_a, double sigma_s, int max_depth) {
    snprintf(buf, cap,
             "{\"camera\": {\"eye\": [0, 0, -3], \"look_at\": [0, 0, -10], \"fov_deg\": 60, \"width\": 8, "
             "\"height\": 8, \"spp\": 1}, \"materials\": {\"m\": {\"type\": \"mirror\"}}, \"objects\": ["
             "{\"type\": \"quad\", \"vertices\": [[-1,-1,-1],[1,-1,-1],[1,1,-1],[-1,1,-1]], \"material\": \"m\"},"
             "{\"type\": \"quad\", \"vertices\": [[-1,-1,1],[-1,1,1],[1,1,1],[1,-1,1]], \"material\": \"m\"},"
             "{\"type\": \"quad\", \"vertices\": [[-1,-1,-1],[-1,1,-1],[-1,1,1],[-1,-1,1]], \"material\": \"m\"},"
             "{\"type\": \"quad\", \"vertices\": [[1,-1,-1],[1,-1,1],[1,1,1],[1,1,-1]], \"material\": \"m\"},"
             "{\"type\": \"quad\", \"vertices\": [[-1,-1,-1],[-1,-1,1],[1,-1,1],[1,-1,-1]], \"material\": \"m\"},"
             "{\"type\": \"quad\", \"vertices\": [[-1,1,-1],[1,1,-1],[1,1,1],[-1,1,1]], \"material\": \"m\"}],"
             " \"lights\": [{\"type\": \"point\", \"position\": [0, 0, 0], \"intensity\": 1}],"
             " \"media\": {\"fog\": {\"sigma_a\": %g, \"sigma_s\": %g}}, \"medium\": \"fog\","
             " \"render\": {\"max_depth\": %d}}",
             sigma_a, sigma_s, max_depth);
}

/* Oracle for the memory budget: its definition (volume.h BUDGETS, the driver's rules at the top
 * of photon_rounds.c). A pass stopped by it keeps the longest prefix of its batch's photons
 * whose records fit the budget, each photon whole, so it equals, record for record, an
 * unbudgeted pass of just that many emitted photons (a photon's records depend only on its
 * index); one more photon would not have fit (its path stores at most max_depth + 1 = 2001
 * records); it is the same on 1 and 2 threads; and it says which map stopped short. Each
 * photon here stores up to 2001 records, so the budget of 16 MiB (262144 records of 64 bytes)
 * holds about 130 photons, inside the first batch. */
TEST(render_media_volume_memory_budget) {
    static char txt[8192];
    mirror_fog(txt, sizeof txt, 0, 5, 2000);
    scene s;
    json_err e = {0};
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    vol_pass_result r[2], ref;
    vol_pass_opts o = {0};
    o.volume_target = 100000000;
    o.max_emitted = 1e9;
    o.max_memory_bytes = (size_t)16 << 20;
    o.max_depth = 2000;
    o.seed = 3;
    o.lo = v3s(1);
    o.hi = v3s(-1);
    for (int t = 0; t < 2; t++) {
        o.threads = t + 1;
        ASSERT_EQ_INT(vol_trace_pass(&s, &o, &r[t]), 0);
    }
    printf("    memory budget 16 MiB: %zu volume photons from %llu emitted\n", r[0].nvolume,
           (unsigned long long)r[0].emitted);
    EXPECT(r[0].volume_short && r[0].emitted > 0 && r[0].emitted < PT_BATCH);
    size_t recs = ((size_t)16 << 20) / 64; /* the budget in 64-byte records (pass_rec) */
    EXPECT_MSG(r[0].nvolume > 0 && r[0].nvolume <= recs && r[0].nvolume + 2001 > recs,
               "%zu records kept of a budget of %zu", r[0].nvolume, recs);
    EXPECT(r[0].nvolume == r[1].nvolume && r[0].emitted == r[1].emitted &&
           memcmp(r[0].volume, r[1].volume, r[0].nvolume * sizeof *r[0].volume) == 0);
    o.threads = 0;
    o.max_memory_bytes = 0;
    o.max_emitted = (double)r[0].emitted;
    ASSERT_EQ_INT(vol_trace_pass(&s, &o, &ref), 0);
    EXPECT_MSG(ref.nvolume == r[0].nvolume && ref.volume_emitted == r[0].volume_emitted &&
                   memcmp(ref.volume, r[0].volume, ref.nvolume * sizeof *ref.volume) == 0 &&
                   memcmp(ref.volume_medium, r[0].volume_medium, ref.nvolume * sizeof *ref.volume_medium) == 0,
               "budgeted %zu photons, unbudgeted pass of %llu emitted %zu", r[0].nvolume,
               (unsigned long long)r[0].emitted, ref.nvolume);
    vol_pass_free(&ref);
    vol_pass_free(&r[0]);
    vol_pass_free(&r[1]);
    scene_free(&s);
}

/* Run render on scene text with flags in the test directory; exit status, output in out,
 * wall seconds in *secs. */
static int render_budget(const char *name, const char *text, const char *flags, char *out, size_t cap,
                         double *secs) {
    char path[1024], cmd[8192];
    snprintf(path, sizeof path, "%s/%s.json", pm_test_tmpdir(), name);
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    fputs(text, f);
    fclose(f);
    snprintf(cmd, sizeof cmd, "cd '%s' && timeout 600 '%s/render' '%s' --mode pm --quiet -o %s.png %s",
             pm_test_tmpdir(), pm_test_build_dir(), path, name, flags);
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    int rc = pm_test_run(cmd, out, cap);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    *secs = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    return rc;
}

/* Runaway media passes end in bounded time with photon_trace's messages (volume.h BUDGETS):
 * the albedo-1 fog in a mirror box, whose photons never die, (1) with the default
 * max_bounces (256, below max_depth 2000): the path-length budget cuts the paths and says so,
 * and the volume map stops within one path (2001 records at most) of its target; (2) with the
 * path budget lifted and a target of 1e8 (7.2 GB of records while tracing): the memory budget
 * of 16 MiB stops the pass (exit 0, the map keeps what it stored whole and says by which
 * budget); (3) a purely absorbing fog forced to have a volume map stores nothing: exit 1 with
 * "no photon stored". Each within 300 s (a few seconds idle; the machine is shared). */
TEST(render_media_runaway_passes_end) {
    static char txt[8192], out[65536];
    double secs;
    mirror_fog(txt, sizeof txt, 0, 5, 2000);
    int rc = render_budget("mirrorfog1", txt, "--pm volume_caustics=false --pm volume_photons=20000", out,
                           sizeof out, &secs);
    EXPECT_MSG(rc == 0, "exit %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "photon tracing: Tracing volume photons: ") &&
                   strstr(out, "photon paths were cut by the path-length budget (photon_mapping.max_bounces = 256)"),
               "%s", out);
    const char *v = strstr(out, "; volume: ");
    long long nv = v ? strtoll(v + strlen("; volume: "), NULL, 10) : -1;
    EXPECT_MSG(nv >= 20000 && nv <= 20000 + 257, "volume photons %lld: %s", nv, out);
    EXPECT_MSG(secs < 300, "%.1f s", secs);
    printf("    path budget: %lld volume photons, %.1f s\n", nv, secs);

    rc = render_budget("mirrorfog2", txt,
                       "--pm volume_caustics=false --pm max_bounces=1000000 --pm max_memory_mb=16 "
                       "--pm volume_photons=100000000",
                       out, sizeof out, &secs);
    EXPECT_MSG(rc == 0, "exit %d: %s", rc, out);
    const char *m = strstr(out, "photon tracing: Tracing volume photons: only ");
    EXPECT_MSG(m && strstr(m, " of 100000000 photons stored after ") &&
                   strstr(m, "stopped by the photon_mapping.max_memory_mb budget"),
               "%s", out);
    EXPECT_MSG(!strstr(out, "path-length budget"), "%s", out);
    EXPECT_MSG(secs < 300, "%.1f s", secs);
    printf("    memory budget: %.80s (%.1f s)\n", m ? m + strlen("photon tracing: ") : "?", secs);

    mirror_fog(txt, sizeof txt, 1, 0, 20);
    rc = render_budget("absorbing", txt, "--pm volume=true --pm volume_caustics=false", out, sizeof out, &secs);
    EXPECT_MSG(rc == 1 && strstr(out, "photon tracing: Tracing volume photons: no photon stored after "
                                      "131072 emitted"),
               "exit %d: %s", rc, out);
    EXPECT_MSG(secs < 300, "%.1f s", secs);
}
