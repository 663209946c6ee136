/* test_render_light.c: light emission sampling for photon tracing, and light power.
 *
 * Oracles: the moments of the sampled distributions (uniform point on a triangle: mean =
 * centroid; cosine-weighted direction: mean cos = 2/3), and the flux a directional light
 * delivers to a sphere, E pi r^2 (analytic), estimated from emitted photons each carrying
 * power / n. Monte Carlo results are checked within 5 standard errors.
 */
#include "test.h"
#include "../render/base/rng.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"

TEST(render_light_area_emission_moments) {
    const char *txt =
        "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 4, \"height\": 4},"
        "\"materials\": {\"e\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": [2, 1, 0.5]}},"
        "\"objects\": [{\"type\": \"triangle\", \"vertices\": [[0,0,0],[3,0,0],[0,0,2]], \"material\": \"e\"}]}";
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(s.nlights, 1);
    /* power = pi Le A, A = 3 */
    ASSERT_NEAR(s.lights[0].power.x, M_PI * 2 * 3, 1e-12);
    int N = 100000;
    rng g = rng_stream(1, 0, 0);
    double sc = 0, sc2 = 0;
    vec3 sp = v3s(0);
    vec3 nrm = s.tris[0].n;
    for (int i = 0; i < N; i++) {
        double u[4] = {rng_uniform(&g), rng_uniform(&g), rng_uniform(&g), rng_uniform(&g)};
        vec3 p, n, d;
        light_sample_le(&s, 0, u, &p, &n, &d);
        ASSERT_NEAR(v3_len(d), 1.0, 1e-12);
        double c = v3_dot(d, nrm);
        ASSERT(c >= 0);
        sc += c;
        sc2 += c * c;
        sp = v3_add(sp, p);
    }
    double mc = sc / N, se = sqrt((sc2 / N - mc * mc) / N);
    ASSERT_NEAR(mc, 2.0 / 3.0, 5 * se);
    sp = v3_scale(sp, 1.0 / N);
    /* centroid (1, 0, 2/3); the coordinates' standard deviations are < 1, so 5 se < 0.016 */
    ASSERT_NEAR(sp.x, 1.0, 0.016);
    ASSERT_NEAR(sp.y, 0.0, 1e-12);
    ASSERT_NEAR(sp.z, 2.0 / 3.0, 0.016);
    scene_free(&s);
}

/* A directional light over a unit sphere: the bounding sphere has R = sqrt(3), photons carry
 * E pi R^2 / n each, and the flux hitting the sphere must be E pi r^2 (r = 1): binomial
 * fraction 1/3, within 5 standard errors. */
TEST(render_light_directional_flux) {
    const char *txt =
        "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 4, \"height\": 4},"
        "\"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
        "\"objects\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 1, \"material\": \"w\"}],"
        "\"lights\": [{\"type\": \"directional\", \"direction\": [0.3, -1, 0.2], \"irradiance\": 2}]}";
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    ASSERT_NEAR(s.bsphere_r, sqrt(3.0), 1e-12);
    int N = 60000, hits = 0;
    rng g = rng_stream(2, 0, 0);
    for (int i = 0; i < N; i++) {
        double u[4] = {rng_uniform(&g), rng_uniform(&g), rng_uniform(&g), rng_uniform(&g)};
        vec3 p, n, d;
        light_sample_le(&s, 0, u, &p, &n, &d);
        hit h;
        hits += scene_intersect(&s, (ray){p, d}, INFINITY, &h);
    }
    double flux = s.lights[0].power.x * hits / N;
    double sd = s.lights[0].power.x * sqrt(N * (1.0 / 3) * (2.0 / 3)) / N;
    ASSERT_NEAR(flux, 2.0 * M_PI, 5 * sd);
    scene_free(&s);
}

/* A sphere light (radius r, Le) seen from a point at distance D from its centre, facing it:
 * the irradiance there is E = pi Le r^2 / D^2 (the sphere subtends a cap of sin^2 = r^2/D^2).
 * Next-event samples must average to it (the far half of the sphere gives 0), within 5
 * standard errors; emission must start on the sphere, go out of it cosine-distributed about
 * the outward normal (mean cos 2/3), and the light's power is pi Le 4 pi r^2. */
TEST(render_light_sphere_irradiance_and_emission) {
    const char *txt =
        "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 4, \"height\": 4},"
        "\"materials\": {\"e\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 3}},"
        "\"objects\": [{\"type\": \"sphere\", \"center\": [1,2,3], \"radius\": 0.5, \"material\": \"e\"}]}";
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(s.nlights, 1);
    ASSERT_EQ_INT(s.lights[0].type, LIGHT_SPHERE);
    ASSERT(scene_prim_is_light(&s, s.ntris + 0));
    ASSERT_NEAR(s.lights[0].power.x, M_PI * 3 * 4 * M_PI * 0.25, 1e-9);
    double D = 2.0;
    vec3 c = v3(1, 2, 3), p = v3(1, 2, 3 - D), np = v3(0, 0, 1);
    int N = 200000;
    rng g = rng_stream(3, 0, 0);
    double se1 = 0, se2 = 0;
    for (int i = 0; i < N; i++) {
        light_sample ls;
        double v = 0;
        if (light_sample_li(&s, 0, p, rng_uniform(&g), rng_uniform(&g), &ls)) {
            ASSERT_NEAR(v3_len(v3_sub(ls.p, c)), 0.5, 1e-9);
            double cp = v3_dot(ls.wi, np);
            ASSERT(cp > 0);
            v = ls.L.x * cp;
        }
        se1 += v;
        se2 += v * v;
    }
    double mean = se1 / N, sd = sqrt((se2 / N - mean * mean) / N);
    ASSERT_NEAR(mean, M_PI * 3 * 0.25 / (D * D), 5 * sd);
    double mc = 0;
    for (int i = 0; i < N; i++) {
        double u[4] = {rng_uniform(&g), rng_uniform(&g), rng_uniform(&g), rng_uniform(&g)};
        vec3 o, n, d;
        light_sample_le(&s, 0, u, &o, &n, &d);
        ASSERT_NEAR(v3_len(v3_sub(o, c)), 0.5, 1e-9);
        ASSERT_NEAR(v3_dot(n, v3_scale(v3_sub(o, c), 2)), 1.0, 1e-9); /* outward */
        mc += v3_dot(d, n);
    }
    ASSERT_NEAR(mc / N, 2.0 / 3.0, 0.005); /* sd of cos is 0.24: 5 se = 0.0027 */
    scene_free(&s);
}
