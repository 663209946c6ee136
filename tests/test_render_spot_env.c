/* test_render_spot_env.c: spot lights and the constant infinite light (light.h).
 *
 * Oracles:
 *   - the spot's power, 2 pi I times the integral of its falloff over cos, and the flux its
 *     photons carry into a disc under it, 2 pi I times the integral of the falloff over the
 *     disc's cone of cos: both integrals by Simpson's rule (100000 intervals) over the falloff
 *     as written in pbrt's books (smoothstep 3d^2 - 2d^3, pbrt-v4; d^4, pbrt-v3), not through
 *     light.c's closed forms; the photon count is binomial, checked within 5 standard errors;
 *   - the radiance of a lambert plane under the spot, rho/pi I f(cos) cos / r^2 (closed form):
 *     path and pm use one point light sample per estimate, so the plane alone (no other
 *     surface to light it) gives it to 1e-9; preview shows the global photon map directly, a
 *     density estimate, checked over nine points of the inner cone within 4 standard errors
 *     of k nearest photons (1 / sqrt(k) each);
 *   - under a constant sky of radiance L nothing but the plane or the sphere: irradiance pi L
 *     on the plane's top, and on every point of a convex sphere, so the radiance is rho L
 *     (path and pm: within 5 standard errors of their samples; preview: 4 of its k photons);
 *     a camera ray that leaves the scene sees L exactly;
 *   - the infinite light's photons: the flux into a unit sphere is 4 pi^2 r^2 L (each
 *     direction's light crossing the sphere's cross-section), binomial, 5 standard errors;
 *   - bad parameters: exit codes and messages naming the field; pbrt-v3 LightSource "spot"
 *     and "infinite" converted to the values by hand.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "test.h"
#include "../render/base/rng.h"
#include "../render/integrators/integrator.h"
#include "../render/load/pbrt.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"

/* The falloff as the books write it, for the oracle integrals. */
static double book_falloff(double c, double ct, double cs, int quartic) {
    if (c < ct) return 0;
    if (c >= cs) return 1;
    double d = (c - ct) / (cs - ct);
    return quartic ? d * d * d * d : d * d * (3 - 2 * d);
}

/* Simpson's rule of book_falloff over cos in [a, 1]. */
static double falloff_integral(double a, double ct, double cs, int quartic) {
    int n = 100000;
    double h = (1 - a) / n, sum = book_falloff(a, ct, cs, quartic) + book_falloff(1, ct, cs, quartic);
    for (int i = 1; i < n; i++) sum += (i % 2 ? 4 : 2) * book_falloff(a + i * h, ct, cs, quartic);
    return sum * h / 3;
}

static const char *k_cam = "\"camera\": {\"eye\": [0, 3, -3], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 4, \"height\": 4}";
static const char *k_plane = "{\"type\": \"quad\", \"vertices\": [[-4,0,-4],[-4,0,4],[4,0,4],[4,0,-4]], \"material\": \"w\"}";

static int spot_scene(scene *s, const char *falloff, const char *pm) {
    char txt[2048];
    snprintf(txt, sizeof txt,
             "{%s, \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.6}},"
             " \"objects\": [%s],"
             " \"lights\": [{\"type\": \"spot\", \"position\": [0, 2, 0], \"direction\": [0, -1, 0], \"intensity\": [3, 3, 3],"
             " \"cone_angle\": 40, \"cone_delta\": 15, \"falloff\": \"%s\"}]%s}",
             k_cam, k_plane, falloff, pm ? pm : "");
    json_err e;
    int rc = scene_load_text(s, txt, &e);
    EXPECT_MSG(rc == 0, "%s", e.msg);
    return rc;
}

TEST(spot_power_and_photon_flux_into_a_disc) {
    for (int q = 0; q < 2; q++) {
        scene s;
        if (spot_scene(&s, q ? "quartic" : "smoothstep", NULL) != 0) return;
        double ct = cos(40 * M_PI / 180), cs = cos(25 * M_PI / 180);
        const light *l = &s.lights[0];
        ASSERT_EQ_INT(l->type, LIGHT_SPOT);
        /* Simpson's error at the falloff's kinks (cos_total, cos_start off its grid) is ~1e-9 */
        EXPECT_REL(l->power.x, 2 * M_PI * 3 * falloff_integral(-1, ct, cs, q), 1e-7);
        /* photons into the disc of radius 1 on y = 0 under the spot (its edge at 26.6 degrees,
         * inside the falloff band 25..40) */
        double cd = 2 / sqrt(5.0), expect = 2 * M_PI * 3 * falloff_integral(cd, ct, cs, q);
        int N = 400000, hits = 0, outside = 0, inv_bad = 0;
        rng g = rng_stream(7, (uint64_t)q, 0);
        for (int i = 0; i < N; i++) {
            double u[4] = {rng_uniform(&g), rng_uniform(&g), rng_uniform(&g), rng_uniform(&g)};
            vec3 p, n, d;
            light_sample_le(&s, 0, u, &p, &n, &d);
            if (v3_dot(d, l->dir) < ct - 1e-12) outside++;
            double t = -p.y / d.y;
            if (d.y < 0 && (p.x + t * d.x) * (p.x + t * d.x) + (p.z + t * d.z) * (p.z + t * d.z) < 1) hits++;
            double a, b;
            if (!light_spot_invert(l, d, &a, &b) || fabs(a - u[0]) > 1e-7 || fabs(b - u[1]) > 1e-7) inv_bad++;
        }
        EXPECT_EQ_INT(outside, 0);
        EXPECT_EQ_INT(inv_bad, 0);
        double frac = expect / l->power.x, flux = l->power.x * hits / N;
        double sd = l->power.x * sqrt(frac * (1 - frac) / N);
        EXPECT_MSG(fabs(flux - expect) < 5 * sd, "%s: photon flux %.6g, expected %.6g (5 sd = %.3g)",
                   q ? "quartic" : "smoothstep", flux, expect, 5 * sd);
        scene_free(&s);
    }
}

/* An integrator of mode for s, preprocessed (0), or -1 with the reason printed. */
static int mode_open(const scene *s, const char *mode, integrator *it) {
    char err[256];
    if (integrator_create(mode, s, it, err, sizeof err) < 0) {
        printf("    %s: %s\n", mode, err);
        return -1;
    }
    if (it->preprocess && it->preprocess(it, s, err, sizeof err) < 0) {
        printf("    preprocess: %s\n", err);
        integrator_destroy(it);
        return -1;
    }
    return 0;
}

/* Mean radiance of n camera rays of it from o through the point x (fresh streams), with its
 * standard error over the rays in *se. */
static double ray_mean(const scene *s, const integrator *it, vec3 o, vec3 x, int n, double *se) {
    void *sc = it->thread_begin ? it->thread_begin(it) : NULL;
    double sum = 0, sum2 = 0;
    for (int i = 0; i < n; i++) {
        rng g = rng_stream(43, (uint64_t)i, 0);
        sample_id id = {0};
        rgb L = it->li(it, s, (ray){o, v3_norm(v3_sub(x, o))}, &g, &id, sc);
        double v = (L.x + L.y + L.z) / 3;
        sum += v;
        sum2 += v * v;
    }
    if (it->thread_end) it->thread_end(it, sc);
    double m = sum / n;
    *se = sqrt(fmax(sum2 / n - m * m, 0) / n);
    return m;
}

/* rho/pi I f cos / r^2 at (x, 0, z) under the spot at height 2. */
static double spot_radiance(double x, double z, int quartic) {
    double r2 = 4 + x * x + z * z, c = 2 / sqrt(r2);
    return 0.6 / M_PI * 3 * book_falloff(c, cos(40 * M_PI / 180), cos(25 * M_PI / 180), quartic) * c / r2;
}

/* The photon settings of path and pm (pm's own maps add nothing here: no second surface), and
 * of preview (many photons, k_global large: the density estimate's noise 1 / sqrt(k)). */
#define PM_SMALL ", \"photon_mapping\": {\"global_photons\": 20000, \"progress\": false}"
#define PM_PREVIEW ", \"photon_mapping\": {\"global\": true, \"global_photons\": 400000, \"k_global\": 1000, " \
                   "\"final_gather\": false, \"progress\": false}"

TEST(spot_irradiance_on_a_plane_path_pm_preview) {
    scene s;
    if (spot_scene(&s, "smoothstep", PM_SMALL) != 0) return;
    vec3 eye = s.cam.eye;
    const double xs[4] = {0, 1.25, 1.5, 2.0}; /* axis, the falloff band (32 and 37 degrees), outside (45) */
    integrator it;
    for (int m = 0; m < 2; m++) {
        if (mode_open(&s, m ? "pm" : "path", &it) < 0) continue;
        for (int k = 0; k < 4; k++) {
            double se, L = ray_mean(&s, &it, eye, v3(xs[k], 0, 0), 64, &se);
            double want = spot_radiance(xs[k], 0, 0);
            EXPECT_MSG(fabs(L - want) <= 1e-9 * fmax(want, 1e-3), "%s at x = %g: %.12g, closed form %.12g",
                       m ? "pm" : "path", xs[k], L, want);
        }
        integrator_destroy(&it);
    }
    scene_free(&s);
    /* preview: nine points of the inner cone, their mean against the closed forms' */
    if (spot_scene(&s, "smoothstep", PM_PREVIEW) != 0) return;
    if (mode_open(&s, "preview", &it) == 0) {
        double got = 0, want = 0;
        for (int a = -1; a <= 1; a++)
            for (int b = -1; b <= 1; b++) {
                double se;
                got += ray_mean(&s, &it, eye, v3(0.45 * a, 0, 0.45 * b), 1, &se) / 9;
                want += spot_radiance(0.45 * a, 0.45 * b, 0) / 9;
            }
        integrator_destroy(&it);
        double tol = 4 * want / sqrt(1000.0) / 3; /* nine independent estimates of k = 1000 */
        printf("    spot, preview: %.6g, closed form %.6g (%+.2f%%)\n", got, want, 100 * (got / want - 1));
        EXPECT_MSG(fabs(got - want) < tol, "preview (photon map): %.6g, closed form %.6g (tolerance %.3g)", got, want,
                   tol);
    }
    scene_free(&s);
}

static int sky_scene(scene *s, int ball, const char *pm) {
    char txt[2048];
    snprintf(txt, sizeof txt,
             "{%s, \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.6}},"
             " \"objects\": [%s],"
             " \"lights\": [{\"type\": \"infinite\", \"radiance\": [0.5, 1, 2]}]%s}",
             k_cam, ball ? "{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, \"material\": \"w\"}" : k_plane,
             pm ? pm : "");
    json_err e;
    int rc = scene_load_text(s, txt, &e);
    EXPECT_MSG(rc == 0, "%s", e.msg);
    return rc;
}

TEST(infinite_light_constant_sky_plane_and_sphere) {
    const double Lm = (0.5 + 1 + 2) / 3.0; /* the channels' mean */
    for (int sp = 0; sp < 2; sp++) {
        scene s;
        if (sky_scene(&s, sp, PM_SMALL) != 0) return;
        ASSERT(s.env_light == 1);
        EXPECT_REL(s.lights[0].power.y, 4 * M_PI * M_PI * s.bsphere_r * s.bsphere_r, 1e-12);
        vec3 eye = s.cam.eye;
        vec3 x = sp ? v3(0, 1, 0) : v3(0.3, 0, -0.2); /* the sphere's top, a point of the plane */
        integrator it;
        for (int m = 0; m < 2; m++) {
            if (mode_open(&s, m ? "pm" : "path", &it) < 0) continue;
            /* a ray past everything sees the sky */
            double se, L = ray_mean(&s, &it, eye, v3_add(eye, v3(0, 1, 0)), 4, &se);
            EXPECT_REL(L, Lm, 1e-12);
            L = ray_mean(&s, &it, eye, x, 4000, &se);
            printf("    %s, %s: %.6g +- %.2g, rho L %.6g\n", sp ? "sphere" : "plane", m ? "pm" : "path", L, se, 0.6 * Lm);
            EXPECT_MSG(fabs(L - 0.6 * Lm) < 5 * se, "%s, %s: %.6g, rho L = %.6g (5 se = %.3g)", sp ? "sphere" : "plane",
                       m ? "pm" : "path", L, 0.6 * Lm, 5 * se);
            integrator_destroy(&it);
        }
        scene_free(&s);
        if (sky_scene(&s, sp, PM_PREVIEW) != 0) return;
        if (mode_open(&s, "preview", &it) == 0) {
            double se, L = ray_mean(&s, &it, eye, x, 1, &se), tol = 4 * 0.6 * Lm / sqrt(1000.0);
            integrator_destroy(&it);
            printf("    %s, preview: %.6g, rho L %.6g (%+.2f%%)\n", sp ? "sphere" : "plane", L, 0.6 * Lm, 100 * (L / (0.6 * Lm) - 1));
            EXPECT_MSG(fabs(L - 0.6 * Lm) < tol, "%s, preview (photon map): %.6g, rho L = %.6g (tolerance %.3g)",
                       sp ? "sphere" : "plane", L, 0.6 * Lm, tol);
        }
        scene_free(&s);
    }
}

TEST(infinite_light_photon_flux_into_a_sphere) {
    /* a unit sphere and a far small one that makes the bounding sphere larger */
    const char *txt =
        "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 4, \"height\": 4},"
        "\"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
        "\"objects\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 1, \"material\": \"w\"},"
        " {\"type\": \"sphere\", \"center\": [4,0,0], \"radius\": 0.1, \"material\": \"w\"}],"
        "\"lights\": [{\"type\": \"infinite\", \"radiance\": 2}]}";
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    int N = 200000, hits = 0;
    rng g = rng_stream(9, 0, 0);
    for (int i = 0; i < N; i++) {
        double u[4] = {rng_uniform(&g), rng_uniform(&g), rng_uniform(&g), rng_uniform(&g)};
        vec3 p, n, d;
        light_sample_le(&s, 0, u, &p, &n, &d);
        hit h;
        if (scene_intersect(&s, (ray){p, d}, INFINITY, &h) && v3_len(h.p) < 1.0001) hits++;
    }
    double P = s.lights[0].power.x, expect = 4 * M_PI * M_PI * 2, frac = expect / P;
    double flux = P * hits / N, sd = P * sqrt(frac * (1 - frac) / N);
    EXPECT_MSG(fabs(flux - expect) < 5 * sd, "flux into the unit sphere %.6g, expected %.6g (5 sd = %.3g)", flux,
               expect, 5 * sd);
    scene_free(&s);
}

/* Bad parameters: the message names the field. */
TEST(spot_and_infinite_bad_parameters) {
    static const struct {
        const char *light, *needle;
    } k[] = {
        {"{\"type\": \"spot\", \"position\": [0,2,0], \"direction\": [0,-1,0], \"intensity\": 1, \"cone_angle\": 10, \"cone_delta\": 20}",
         "$.lights[0].cone_delta"},
        {"{\"type\": \"spot\", \"position\": [0,2,0], \"direction\": [0,-1,0], \"intensity\": 1, \"cone_angle\": 0}",
         "$.lights[0].cone_angle"},
        {"{\"type\": \"spot\", \"position\": [0,2,0], \"direction\": [0,0,0], \"intensity\": 1}", "$.lights[0].direction"},
        {"{\"type\": \"spot\", \"position\": [0,2,0], \"direction\": [0,-1,0], \"intensity\": -1}", "$.lights[0].intensity"},
        {"{\"type\": \"spot\", \"position\": [0,2,0], \"direction\": [0,-1,0], \"intensity\": 1, \"falloff\": \"linear\"}",
         "$.lights[0].falloff"},
        {"{\"type\": \"spot\", \"position\": [0,2,0], \"direction\": [0,-1,0], \"intensity\": 1, \"coneangle\": 3}",
         "$.lights[0].coneangle"},
        {"{\"type\": \"infinite\", \"radiance\": [1, -1, 1]}", "$.lights[0].radiance"},
        {"{\"type\": \"infinite\"}", "radiance"},
        {"{\"type\": \"infinite\", \"radiance\": 1}, {\"type\": \"infinite\", \"radiance\": 2}", "$.lights[1]"},
        {"{\"type\": \"sky\", \"radiance\": 1}", "$.lights[0].type"},
    };
    for (size_t i = 0; i < sizeof k / sizeof *k; i++) {
        char txt[2048];
        snprintf(txt, sizeof txt,
                 "{%s, \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.6}}, \"objects\": [%s], \"lights\": [%s]}",
                 k_cam, k_plane, k[i].light);
        scene s;
        json_err e;
        e.msg[0] = 0;
        int rc = scene_load_text(&s, txt, &e);
        EXPECT_MSG(rc < 0 && strstr(e.msg, k[i].needle), "case %zu: rc %d, message \"%s\" (wanted %s)", i, rc, e.msg,
                   k[i].needle);
        if (rc == 0) scene_free(&s);
    }
}

static double jnum(const cJSON *o, const char *key, int i) {
    const cJSON *it = cJSON_GetObjectItemCaseSensitive(o, key);
    if (i >= 0) it = cJSON_GetArrayItem(it, i);
    return cJSON_IsNumber(it) ? it->valuedouble : NAN;
}

/* Oracle by hand: pbrt's spot from (0 0 0) to (0 0 1) under Translate 0 4 0 and Rotate 90 about
 * x (z -> y... so the axis (0, 0, 1) becomes (0, -1, 0)... with pbrt's frame mirrored in x, as
 * test_render_import_pbrt.c's conversion test says: positions (x, y, z) -> (-x, y, z)). */
TEST(pbrt_spot_and_infinite_convert) {
    const char *t =
        "LookAt 0 0 -5  0 0 0  0 1 0\n"
        "Camera \"perspective\" \"float fov\" 40\n"
        "WorldBegin\n"
        "AttributeBegin\n"
        "  Translate 1 4 0\n  Rotate 90 1 0 0\n"
        "  LightSource \"spot\" \"rgb I\" [1 2 3] \"rgb scale\" [2 2 2] \"float coneangle\" 20 \"float conedeltaangle\" 4\n"
        "AttributeEnd\n"
        "LightSource \"infinite\" \"rgb L\" [0.1 0.2 0.3] \"integer nsamples\" 4\n"
        "Material \"matte\"\n"
        "Shape \"sphere\"\n";
    cJSON *out = NULL;
    json_err e;
    e.msg[0] = 0;
    ASSERT_MSG(pbrt_convert_text(t, "t.pbrt", &out, &e) == 0, "%s", e.msg);
    const cJSON *lights = cJSON_GetObjectItemCaseSensitive(out, "lights");
    ASSERT_EQ_INT(cJSON_GetArraySize(lights), 2);
    const cJSON *sp = cJSON_GetArrayItem(lights, 0), *inf = cJSON_GetArrayItem(lights, 1);
    EXPECT(strcmp(cJSON_GetObjectItemCaseSensitive(sp, "type")->valuestring, "spot") == 0);
    EXPECT(strcmp(cJSON_GetObjectItemCaseSensitive(sp, "falloff")->valuestring, "quartic") == 0);
    EXPECT_NEAR(fabs(jnum(sp, "position", 0)), 1, 1e-12);
    EXPECT_NEAR(jnum(sp, "position", 1), 4, 1e-12);
    EXPECT_NEAR(jnum(sp, "position", 2), 0, 1e-12);
    /* Rotate 90 about x takes z to -y */
    EXPECT_NEAR(jnum(sp, "direction", 0), 0, 1e-12);
    EXPECT_NEAR(jnum(sp, "direction", 1), -1, 1e-12);
    EXPECT_NEAR(jnum(sp, "direction", 2), 0, 1e-12);
    EXPECT_NEAR(jnum(sp, "intensity", 2), 6, 1e-12);
    EXPECT_NEAR(jnum(sp, "cone_angle", -1), 20, 0);
    EXPECT_NEAR(jnum(sp, "cone_delta", -1), 4, 0);
    EXPECT(strcmp(cJSON_GetObjectItemCaseSensitive(inf, "type")->valuestring, "infinite") == 0);
    EXPECT_NEAR(jnum(inf, "radiance", 1), 0.2, 1e-12);
    cJSON_Delete(out);
    /* bad cone: named with file:line */
    const char *bad = "LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin\n"
                      "LightSource \"spot\" \"float coneangle\" 10 \"float conedeltaangle\" 30\n";
    out = NULL;
    e.msg[0] = 0;
    EXPECT(pbrt_convert_text(bad, "t.pbrt", &out, &e) < 0 && strstr(e.msg, "t.pbrt:4") && strstr(e.msg, "conedeltaangle"));
    cJSON_Delete(out);
}

/* Tungsten's infinite_sphere: emission is its radiance, power / (4 pi) too (Tungsten's
 * powerToRadianceFactor); a texture is refused with the key named. */
TEST(tungsten_infinite_sphere_converts) {
    const char *fmt =
        "{\"bsdfs\": [{\"name\": \"w\", \"type\": \"lambert\", \"albedo\": 0.5}],"
        " \"primitives\": [{\"type\": \"sphere\", \"transform\": {\"position\": [0, 0, 0]}, \"bsdf\": \"w\"},"
        " {\"type\": \"infinite_sphere\", %s}],"
        " \"camera\": {\"resolution\": [8, 8], \"transform\": {\"position\": [0, 0, -5], \"look_at\": [0, 0, 0], \"up\": [0, 1, 0]}}}";
    const char *cases[3] = {"\"emission\": [1, 2, 3]", "\"power\": 6.283185307179586", "\"emission\": \"sky.exr\""};
    for (int k = 0; k < 3; k++) {
        char txt[2048];
        snprintf(txt, sizeof txt, fmt, cases[k]);
        scene s;
        json_err e;
        e.msg[0] = 0;
        int rc = scene_load_text(&s, txt, &e);
        if (k == 2) {
            EXPECT_MSG(rc < 0 && strstr(e.msg, "$.primitives[1].emission"), "texture: rc %d, %s", rc, e.msg);
            if (rc == 0) scene_free(&s);
            continue;
        }
        ASSERT_MSG(rc == 0, "%s", e.msg);
        ASSERT_EQ_INT(s.nlights, 1);
        EXPECT_EQ_INT(s.lights[0].type, LIGHT_INFINITE);
        EXPECT_NEAR(s.lights[0].Le.y, k == 0 ? 2 : 0.5, 1e-12);
        EXPECT_EQ_INT(s.env_light, 1);
        scene_free(&s);
    }
}
