/* test_render_envmap.c: an infinite light with an image (envmap.h, "map" in $.lights).
 *
 * Oracles:
 *   - a map of one colour is the constant light: the same power (4 pi^2 R^2 L, to 1e-12) and
 *     every photon's weight 1;
 *   - a banded sky (an 8 x 8 map, a colour per row, the equator a row boundary) over a plane
 *     facing its zenith: the irradiance is the sum over the upper rows of L_row pi (c_top^2 -
 *     c_bottom^2) (c: the rows' cos theta), closed form; the path tracer's radiance rho/pi E
 *     within 5 standard errors, per channel of the mean; the photons' flux into a disc of that
 *     plane (E times its area, per channel) within 5 standard errors of the photons' weighted sum;
 *   - the photons' flux into a unit sphere, pi r^2 times the integral of L over directions (the
 *     sum of L_j Omega_j), per channel, 5 standard errors;
 *   - envmap_sample and envmap_invert undo each other (1e-9), and a ray that leaves the scene
 *     sees its pixel's colour exactly;
 *   - bad input names the field: a missing or malformed PFM, a negative pixel, a black map, a
 *     map_frame that is not a rotation.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "test.h"
#include "../render/base/rng.h"
#include "../render/base/sampling.h"
#include "../render/image/exr.h"
#include "../render/image/film.h"
#include "../render/integrators/integrator.h"
#include "../render/load/pbrt.h"
#include "../render/scene/envmap.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"

/* An 8 x 8 PFM (little-endian), row r (from the top) of colour rows[r], at dir/name. */
static int write_map(const char *path, const rgb rows[8]) {
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    fprintf(f, "PF\n8 8\n-1.0\n");
    for (int y = 7; y >= 0; y--) /* PFM rows run bottom to top */
        for (int x = 0; x < 8; x++) {
            float v[3] = {(float)rows[y].x, (float)rows[y].y, (float)rows[y].z};
            fwrite(v, sizeof v, 1, f);
        }
    return fclose(f);
}

static const char *k_head = "{\"camera\": {\"eye\": [0, 3, -3], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 4, \"height\": 4},"
                            " \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.6}},"
                            " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-4,0,-4],[-4,0,4],[4,0,4],[4,0,-4]], \"material\": \"w\"}],";

static int load_with(scene *s, const char *lt, json_err *e) {
    char txt[12000];
    snprintf(txt, sizeof txt, "%s \"lights\": [%s]}", k_head, lt);
    e->msg[0] = 0;
    return scene_load_text(s, txt, e);
}

/* The banded sky: bright blue-ish rows above, a dim brown ground below. */
static const rgb k_band[8] = {{0.2, 0.4, 1.0}, {0.4, 0.6, 1.2}, {0.8, 0.9, 1.0}, {2.0, 1.8, 1.5},
                              {0.10, 0.08, 0.05}, {0.08, 0.06, 0.04}, {0.05, 0.04, 0.03}, {0.02, 0.02, 0.02}};

/* Irradiance on a surface facing the zenith under k_band: rows 0..3 are the upper hemisphere. */
static rgb band_irradiance(void) {
    rgb E = v3s(0);
    for (int r = 0; r < 4; r++) {
        double c0 = cos(M_PI * r / 8), c1 = cos(M_PI * (r + 1) / 8);
        E = v3_add(E, v3_scale(k_band[r], M_PI * (c0 * c0 - c1 * c1)));
    }
    return E;
}

static rgb band_integral(void) {
    rgb I = v3s(0);
    for (int r = 0; r < 8; r++) I = v3_add(I, v3_scale(k_band[r], 2 * M_PI * (cos(M_PI * r / 8) - cos(M_PI * (r + 1) / 8))));
    return I;
}

TEST(envmap_one_colour_is_the_constant_light) {
    char path[1024], lt[1200];
    snprintf(path, sizeof path, "%s/one.pfm", pm_test_tmpdir());
    rgb rows[8];
    for (int r = 0; r < 8; r++) rows[r] = v3(0.5, 1, 2);
    ASSERT(write_map(path, rows) == 0);
    snprintf(lt, sizeof lt, "{\"type\": \"infinite\", \"map\": \"%s\"}", path);
    scene s, c;
    json_err e;
    ASSERT_MSG(load_with(&s, lt, &e) == 0, "%s", e.msg);
    ASSERT_MSG(load_with(&c, "{\"type\": \"infinite\", \"radiance\": [0.5, 1, 2]}", &e) == 0, "%s", e.msg);
    EXPECT_REL(s.lights[0].power.x, c.lights[0].power.x, 1e-12);
    EXPECT_REL(s.lights[0].power.z, c.lights[0].power.z, 1e-12);
    rng g = rng_stream(3, 0, 0);
    int bad = 0;
    for (int i = 0; i < 1000; i++) {
        double u1 = rng_uniform(&g), u2 = rng_uniform(&g), pdf, a, b;
        vec3 d = envmap_sample(s.env_map, u1, u2, &pdf);
        rgb w = light_emit_weight(&s, 0, v3_neg(d));
        if (fabs(pdf - 1 / (4 * M_PI)) > 1e-9 || fabs(w.x - 1) > 1e-9 || fabs(w.z - 1) > 1e-9) bad++;
        if (!envmap_invert(s.env_map, d, &a, &b) || fabs(a - u1) > 1e-9 || fabs(b - u2) > 1e-9) bad++;
    }
    EXPECT_EQ_INT(bad, 0);
    scene_free(&s);
    scene_free(&c);
}

TEST(envmap_banded_sky_irradiance_and_photons) {
    char path[1024], lt[1200];
    snprintf(path, sizeof path, "%s/band.pfm", pm_test_tmpdir());
    ASSERT(write_map(path, k_band) == 0);
    snprintf(lt, sizeof lt, "{\"type\": \"infinite\", \"map\": \"%s\"}", path);
    scene s;
    json_err e;
    ASSERT_MSG(load_with(&s, lt, &e) == 0, "%s", e.msg);
    rgb E = band_irradiance(), I = band_integral();
    EXPECT_REL(s.lights[0].power.y, M_PI * s.bsphere_r * s.bsphere_r * I.y, 1e-6); /* the map holds floats */
    /* a ray straight up sees the top row, one straight down (under the plane) the bottom row */
    EXPECT_REL(light_env_radiance(&s, v3(0, 1, 0)).z, k_band[0].z, 1e-7);
    EXPECT_REL(light_env_radiance(&s, v3(0.01, -1, 0.02)).x, k_band[7].x, 1e-7);
    /* path: the plane's radiance rho/pi E */
    integrator it;
    char err[256];
    ASSERT(integrator_create("path", &s, &it, err, sizeof err) == 0);
    int n = 20000;
    double sum[3] = {0}, sum2[3] = {0};
    vec3 o = s.cam.eye, x = v3(0.2, 0, 0.1);
    for (int i = 0; i < n; i++) {
        rng g = rng_stream(44, (uint64_t)i, 0);
        sample_id id = {0};
        rgb L = it.li(&it, &s, (ray){o, v3_norm(v3_sub(x, o))}, &g, &id, NULL);
        double v[3] = {L.x, L.y, L.z};
        for (int k = 0; k < 3; k++) sum[k] += v[k], sum2[k] += v[k] * v[k];
    }
    integrator_destroy(&it);
    double want[3] = {0.6 / M_PI * E.x, 0.6 / M_PI * E.y, 0.6 / M_PI * E.z};
    for (int k = 0; k < 3; k++) {
        double m = sum[k] / n, se = sqrt(fmax(sum2[k] / n - m * m, 0) / n);
        EXPECT_MSG(fabs(m - want[k]) < 5 * se, "path channel %d: %.6g, rho/pi E = %.6g (5 se = %.3g)", k, m, want[k], 5 * se);
    }
    /* photons into the disc of radius 1 at the plane's centre, from above */
    int N = 400000;
    double f[3] = {0}, f2[3] = {0};
    rng g = rng_stream(45, 0, 0);
    for (int i = 0; i < N; i++) {
        double u[4] = {rng_uniform(&g), rng_uniform(&g), rng_uniform(&g), rng_uniform(&g)};
        vec3 p, nn, d;
        light_sample_le(&s, 0, u, &p, &nn, &d);
        if (!(d.y < 0) || p.y < 0) continue;
        double t = -p.y / d.y, px = p.x + t * d.x, pz = p.z + t * d.z;
        if (px * px + pz * pz >= 1) continue;
        rgb P = v3_mul(v3_scale(s.lights[0].power, 1.0 / N), light_emit_weight(&s, 0, d));
        double v[3] = {P.x, P.y, P.z};
        for (int k = 0; k < 3; k++) f[k] += v[k], f2[k] += v[k] * v[k] * N;
    }
    double wantf[3] = {E.x * M_PI, E.y * M_PI, E.z * M_PI};
    for (int k = 0; k < 3; k++) {
        double se = sqrt(fmax(f2[k] - f[k] * f[k], 0) / N);
        EXPECT_MSG(fabs(f[k] - wantf[k]) < 5 * se, "photon flux into the disc, channel %d: %.6g, E pi = %.6g (5 se = %.3g)", k,
                   f[k], wantf[k], 5 * se);
    }
    scene_free(&s);
}

TEST(envmap_photon_flux_into_a_sphere) {
    char path[1024], txt[4096];
    snprintf(path, sizeof path, "%s/band.pfm", pm_test_tmpdir());
    ASSERT(write_map(path, k_band) == 0);
    snprintf(txt, sizeof txt,
             "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 4, \"height\": 4},"
             "\"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
             "\"objects\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 1, \"material\": \"w\"},"
             " {\"type\": \"sphere\", \"center\": [4,0,0], \"radius\": 0.1, \"material\": \"w\"}],"
             "\"lights\": [{\"type\": \"infinite\", \"map\": \"%s\", \"radiance\": [1, 2, 0.5]}]}", path);
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    rgb I = v3_mul(band_integral(), v3(1, 2, 0.5));
    int N = 200000;
    double f[3] = {0}, f2[3] = {0};
    rng g = rng_stream(46, 0, 0);
    for (int i = 0; i < N; i++) {
        double u[4] = {rng_uniform(&g), rng_uniform(&g), rng_uniform(&g), rng_uniform(&g)};
        vec3 p, n, d;
        light_sample_le(&s, 0, u, &p, &n, &d);
        hit h;
        if (!scene_intersect(&s, (ray){p, d}, INFINITY, &h) || v3_len(h.p) > 1.0001) continue;
        rgb P = v3_mul(v3_scale(s.lights[0].power, 1.0 / N), light_emit_weight(&s, 0, d));
        double v[3] = {P.x, P.y, P.z};
        for (int k = 0; k < 3; k++) f[k] += v[k], f2[k] += v[k] * v[k] * N;
    }
    double want[3] = {M_PI * I.x, M_PI * I.y, M_PI * I.z};
    for (int k = 0; k < 3; k++) {
        double se = sqrt(fmax(f2[k] - f[k] * f[k], 0) / N);
        EXPECT_MSG(fabs(f[k] - want[k]) < 5 * se, "flux into the unit sphere, channel %d: %.6g, pi I = %.6g (5 se = %.3g)", k,
                   f[k], want[k], 5 * se);
    }
    scene_free(&s);
}

TEST(envmap_bad_input) {
    const char *dir = pm_test_tmpdir();
    char good[1024], neg[1024], black[1024], text[1024];
    snprintf(good, sizeof good, "%s/good.pfm", dir);
    snprintf(neg, sizeof neg, "%s/neg.pfm", dir);
    snprintf(black, sizeof black, "%s/black.pfm", dir);
    snprintf(text, sizeof text, "%s/text.pfm", dir);
    rgb rows[8];
    ASSERT(write_map(good, k_band) == 0);
    for (int r = 0; r < 8; r++) rows[r] = v3s(0);
    ASSERT(write_map(black, rows) == 0);
    rows[3] = v3(1, -1, 1);
    ASSERT(write_map(neg, rows) == 0);
    FILE *f = fopen(text, "w");
    ASSERT(f);
    fputs("P3 not a pfm\n", f);
    fclose(f);
    char cases[6][1400];
    const char *needle[6] = {"cannot open", "is not a colour PFM", "finite and not negative", "is black",
                             "map_frame: not a rotation", "map_frame: only with a map"};
    snprintf(cases[0], sizeof cases[0], "{\"type\": \"infinite\", \"map\": \"%s/missing.pfm\"}", dir);
    snprintf(cases[1], sizeof cases[1], "{\"type\": \"infinite\", \"map\": \"%s\"}", text);
    snprintf(cases[2], sizeof cases[2], "{\"type\": \"infinite\", \"map\": \"%s\"}", neg);
    snprintf(cases[3], sizeof cases[3], "{\"type\": \"infinite\", \"map\": \"%s\"}", black);
    snprintf(cases[4], sizeof cases[4], "{\"type\": \"infinite\", \"map\": \"%s\", \"map_frame\": [1,0,0, 0,1,0, 0,1,0]}", good);
    snprintf(cases[5], sizeof cases[5], "{\"type\": \"infinite\", \"radiance\": 1, \"map_frame\": [1,0,0, 0,1,0, 0,0,1]}");
    for (int k = 0; k < 6; k++) {
        scene s;
        json_err e;
        int rc = load_with(&s, cases[k], &e);
        EXPECT_MSG(rc < 0 && strstr(e.msg, "$.lights[0]") && strstr(e.msg, needle[k]), "case %d: rc %d, \"%s\" (wanted %s)", k,
                   rc, e.msg, needle[k]);
        if (rc == 0) scene_free(&s);
    }
}

/* The photon mapper under the banded sky: preview (the global map shown directly, so the
 * photons' own colours and powers) and pm (next-event estimation) see rho/pi E on the plane,
 * per channel's mean: preview within 4 / sqrt(k) (k = 1000 photons), pm within 5 standard
 * errors of its 4000 samples. Preview again in a medium of zero coefficients, whose photons
 * volume.c traces (the scene has a medium), to the same tolerance. */
TEST(envmap_photon_mapper_matches_closed_form) {
    char path[1024], txt[12000];
    snprintf(path, sizeof path, "%s/band.pfm", pm_test_tmpdir());
    ASSERT(write_map(path, k_band) == 0);
    rgb E = band_irradiance();
    double want = 0.6 / M_PI * (E.x + E.y + E.z) / 3;
    for (int v = 0; v < 3; v++) {
        int m = v == 1;
        snprintf(txt, sizeof txt, "%s \"lights\": [{\"type\": \"infinite\", \"map\": \"%s\"}],%s \"photon_mapping\": %s}",
                 k_head, path, v == 2 ? " \"media\": {\"air\": {\"sigma_a\": 0, \"sigma_s\": 0}}, \"medium\": \"air\"," : "",
                 m ? "{\"global_photons\": 20000, \"progress\": false}"
                         : "{\"global\": true, \"global_photons\": 400000, \"k_global\": 1000, \"final_gather\": false, "
                           "\"progress\": false}");
        scene s;
        json_err e;
        ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
        integrator it;
        char err[256];
        ASSERT(integrator_create(m ? "pm" : "preview", &s, &it, err, sizeof err) == 0);
        ASSERT_MSG(!it.preprocess || it.preprocess(&it, &s, err, sizeof err) == 0, "%s", err);
        void *sc = it.thread_begin ? it.thread_begin(&it) : NULL;
        int n = m ? 4000 : 1;
        double sum = 0, sum2 = 0;
        vec3 o = s.cam.eye, x = v3(0.2, 0, 0.1);
        for (int i = 0; i < n; i++) {
            rng g = rng_stream(47, (uint64_t)i, 0);
            sample_id id = {0};
            rgb L = it.li(&it, &s, (ray){o, v3_norm(v3_sub(x, o))}, &g, &id, sc);
            double lv = (L.x + L.y + L.z) / 3;
            sum += lv, sum2 += lv * lv;
        }
        if (it.thread_end) it.thread_end(&it, sc);
        integrator_destroy(&it);
        double mean = sum / n, tol = m ? 5 * sqrt(fmax(sum2 / n - mean * mean, 0) / n) : 4 * want / sqrt(1000.0);
        const char *name = v == 0 ? "preview" : v == 1 ? "pm" : "preview in a medium";
        printf("    %s: %.6g, rho/pi E = %.6g (%+.2f%%)\n", name, mean, want, 100 * (mean / want - 1));
        EXPECT_MSG(fabs(mean - want) < tol, "%s: %.6g, rho/pi E = %.6g (tolerance %.3g)", name, mean, want, tol);
        scene_free(&s);
    }
}

/* pbrt-v3's infinite light with a PFM mapname: the map, resolved next to the file, and the
 * frame from our world to pbrt's light space; the usual "Rotate -90 1 0 0" (pbrt's z-up map in
 * a y-up world) takes world +y to the map's +z (by hand: the rotation sends (0, 0, 1) to
 * (0, 1, 0), so the frame's third row is (0, 1, 0)). */
TEST(envmap_pbrt_mapname_converts) {
    const char *t = "LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin\n"
                    "AttributeBegin\nRotate -90 1 0 0\n"
                    "LightSource \"infinite\" \"string mapname\" \"sky.pfm\" \"rgb L\" [2 2 2]\nAttributeEnd\n"
                    "Material \"matte\"\nShape \"sphere\"\n";
    cJSON *out = NULL;
    json_err e;
    e.msg[0] = 0;
    ASSERT_MSG(pbrt_convert_text(t, "t.pbrt", &out, &e) == 0, "%s", e.msg);
    const cJSON *l = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(out, "lights"), 0);
    const cJSON *map = cJSON_GetObjectItemCaseSensitive(l, "map"), *fr = cJSON_GetObjectItemCaseSensitive(l, "map_frame");
    EXPECT(cJSON_IsString(map) && strstr(map->valuestring, "sky.pfm"));
    ASSERT(cJSON_GetArraySize(fr) == 9);
    EXPECT_NEAR(cJSON_GetArrayItem(fr, 6)->valuedouble, 0, 1e-12);
    EXPECT_NEAR(cJSON_GetArrayItem(fr, 7)->valuedouble, 1, 1e-12);
    EXPECT_NEAR(cJSON_GetArrayItem(fr, 8)->valuedouble, 0, 1e-12);
    EXPECT_NEAR(cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(l, "radiance"), 0)->valuedouble, 2, 1e-12);
    cJSON_Delete(out);
}

/* An 8 x 8 EXR (32-bit float, image/exr.h's writer) of the same rows as write_map. */
static int write_map_exr(const char *path, const rgb rows[8]) {
    film f;
    if (film_init(&f, 8, 8) < 0) return -1;
    for (int y = 0; y < 8; y++)
        for (int x = 0; x < 8; x++) film_set(&f, x, y, rows[y]);
    FILE *fp = fopen(path, "wb");
    char err[256];
    int rc = fp ? exr_write_fp(f.px, f.width, f.height, fp, EXR_FLOAT, err, sizeof err) : -1;
    if (fp && fclose(fp) != 0) rc = -1;
    film_free(&f);
    return rc;
}

/* An OpenEXR map (a name ending in .exr, read by base/exr_read.h in the loader). Oracle: the
 * same rows as a PFM: the lights' power and the map's radiance in 64 directions are the same
 * numbers (both files hold the same floats). Bad input names the field as for a PFM: a missing
 * file, a file that is not EXR, a negative pixel. pbrt's mapname "sky.exr" becomes the map. */
TEST(envmap_exr_map_matches_pfm) {
    const char *dir = pm_test_tmpdir();
    char pfm[1024], exr[1024], lt[1400];
    snprintf(pfm, sizeof pfm, "%s/sky.pfm", dir);
    snprintf(exr, sizeof exr, "%s/sky.exr", dir);
    ASSERT(write_map(pfm, k_band) == 0);
    ASSERT(write_map_exr(exr, k_band) == 0);
    scene a, b;
    json_err e;
    snprintf(lt, sizeof lt, "{\"type\": \"infinite\", \"map\": \"%s\", \"radiance\": [1, 2, 0.5]}", pfm);
    ASSERT_MSG(load_with(&a, lt, &e) == 0, "%s", e.msg);
    snprintf(lt, sizeof lt, "{\"type\": \"infinite\", \"map\": \"%s\", \"radiance\": [1, 2, 0.5]}", exr);
    ASSERT_MSG(load_with(&b, lt, &e) == 0, "%s", e.msg);
    EXPECT(a.lights[0].power.x == b.lights[0].power.x && a.lights[0].power.y == b.lights[0].power.y &&
           a.lights[0].power.z == b.lights[0].power.z);
    rng g = rng_stream(5, 0, 0);
    int differ = 0;
    for (int i = 0; i < 64; i++) {
        vec3 d = sample_uniform_sphere(rng_uniform(&g), rng_uniform(&g));
        rgb x = envmap_eval(a.env_map, d), y = envmap_eval(b.env_map, d);
        differ += x.x != y.x || x.y != y.y || x.z != y.z;
    }
    EXPECT_EQ_INT(differ, 0);
    scene_free(&a);
    scene_free(&b);
    /* bad input */
    char neg[1024], fake[1024];
    snprintf(neg, sizeof neg, "%s/neg.exr", dir);
    snprintf(fake, sizeof fake, "%s/fake.exr", dir);
    rgb rows[8];
    for (int r = 0; r < 8; r++) rows[r] = k_band[r];
    rows[5] = v3(0.1, -2, 0.1);
    ASSERT(write_map_exr(neg, rows) == 0);
    ASSERT(rename(pfm, fake) == 0); /* a PFM under an EXR name */
    const char *files[3] = {"missing.exr", "fake.exr", "neg.exr"};
    const char *needle[3] = {"cannot open", "not an EXR file", "pixel (0, 5) from the top has -2: radiances must be finite"};
    for (int k = 0; k < 3; k++) {
        snprintf(lt, sizeof lt, "{\"type\": \"infinite\", \"map\": \"%s/%s\"}", dir, files[k]);
        int rc = load_with(&a, lt, &e);
        EXPECT_MSG(rc < 0 && strstr(e.msg, "$.lights[0].map") && strstr(e.msg, needle[k]), "%s: rc %d \"%s\"", files[k], rc,
                   e.msg);
        if (rc == 0) scene_free(&a);
    }
    cJSON *out = NULL;
    e.msg[0] = 0;
    ASSERT_MSG(pbrt_convert_text("LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin\n"
                                 "LightSource \"infinite\" \"string mapname\" \"sky.exr\"\nMaterial \"matte\"\nShape \"sphere\"\n",
                                 "t.pbrt", &out, &e) == 0, "%s", e.msg);
    const cJSON *map = cJSON_GetObjectItemCaseSensitive(cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(out, "lights"), 0), "map");
    EXPECT(cJSON_IsString(map) && strstr(map->valuestring, "sky.exr"));
    cJSON_Delete(out);
}
