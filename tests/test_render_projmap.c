/* test_render_projmap.c: the caustic projection maps (render/photons/projmap.c).
 *
 * Oracle: ray-sphere intersection, worked out here. A cell must be active when any direction
 * in it hits a specular sphere (the map is conservative: no caustic photon is lost), and
 * inactive when every direction in it stays far from every sphere (the map saves what it
 * promises). The cone test decides most spheres from cosines and keeps the inverse cosines
 * for the cases near the cone's edge; both must agree with the rays, here with many small
 * spheres at random places, seen from a point light and from an area light.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "test.h"
#include "../render/base/sampling.h"
#include "../render/load/scene_load.h"
#include "../render/photons/projmap.h"
#include "../render/scene/light.h"
#include "../render/scene/scene.h"

#define PJ_NSPH 8
#define PJ_G 24

/* A scene text: a floor, PJ_NSPH mirror spheres at random (seeded) places around the origin,
 * the objects in more_objects and the top-level keys in more_keys (the light). Centres and
 * radii go to c[] and r[]. */
static void pj_scene_text(char *buf, size_t cap, uint64_t seed, const char *more_objects, const char *more_keys,
                          vec3 *c, double *r) {
    pm_test_rng st = {seed};
    size_t n = (size_t)snprintf(buf, cap,
                                "{\"camera\": {\"eye\": [0,0,-30], \"look_at\": [0,0,0], \"fov_deg\": 50, "
                                "\"width\": 8, \"height\": 8, \"spp\": 1},"
                                "\"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5}, "
                                "\"m\": {\"type\": \"mirror\"}, "
                                "\"e\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 5}},"
                                "\"objects\": [{\"type\": \"quad\", \"vertices\": "
                                "[[-50,-20,-50],[-50,-20,50],[50,-20,50],[50,-20,-50]], \"material\": \"w\"}");
    for (int i = 0; i < PJ_NSPH; i++) {
        /* a point 4 to 12 units from the origin in a random direction, radius 0.2 to 0.6 */
        vec3 d = sample_uniform_sphere(pm_test_unit(&st), pm_test_unit(&st));
        double dist = 4 + 8 * pm_test_unit(&st);
        c[i] = v3_scale(d, dist);
        r[i] = 0.2 + 0.4 * pm_test_unit(&st);
        n += (size_t)snprintf(buf + n, cap - n,
                              ",{\"type\": \"sphere\", \"center\": [%.17g,%.17g,%.17g], \"radius\": %.17g, "
                              "\"material\": \"m\"}",
                              c[i].x, c[i].y, c[i].z, r[i]);
    }
    snprintf(buf + n, cap - n, "%s]%s}", more_objects, more_keys);
}

/* Does the ray o + t d (t > 0, d unit) hit the sphere (c, r)? */
static int pj_hits(vec3 o, vec3 d, vec3 c, double r) {
    vec3 oc = v3_sub(c, o);
    double t = v3_dot(oc, d);
    double m2 = v3_len2(oc) - t * t;
    return m2 <= r * r && (t > 0 || v3_len2(oc) <= r * r);
}

/* The angle between d and the direction from o to the sphere, less the sphere's half angle
 * (negative: d points into it). */
static double pj_gap(vec3 o, vec3 d, vec3 c, double r) {
    vec3 oc = v3_sub(c, o);
    double dist = v3_len(oc);
    if (dist <= r) return -1;
    double cosang = v3_dot(oc, d) / dist;
    return acos(cosang > 1 ? 1 : (cosang < -1 ? -1 : cosang)) - asin(r / dist);
}

/* Check light 0's map of the scene against the rays: every hit in an active cell; every
 * cell whose directions all keep clear of the spheres (by more than the cell's own size)
 * inactive. Rays start at the light's sampled points (area: points over the light). */
static void pj_check(const char *const light_json[2], uint64_t seed, int *nactive_out, int *nfar_out) {
    static char text[16384];
    vec3 c[PJ_NSPH];
    double r[PJ_NSPH];
    pj_scene_text(text, sizeof text, seed, light_json[0], light_json[1], c, r);
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, text, &e) == 0, "%s", e.msg);
    ASSERT(s.nlights >= 1);
    const light *l = &s.lights[0];
    int dim = projmap_dim(l);
    unsigned char active[PJ_G * PJ_G];
    int na = projmap_cells(&s, 0, PJ_G, active);
    ASSERT(na >= 0);
    int count = 0, nfar = 0, missed = 0, wasted = 0;
    for (int k = 0; k < PJ_G * PJ_G; k++) count += active[k];
    EXPECT_EQ_INT(na, count);
    pm_test_rng st = {seed ^ 0x9e3779b97f4a7c15ull};
    for (int cy = 0; cy < PJ_G; cy++)
        for (int cx = 0; cx < PJ_G; cx++) {
            int any_hit = 0;
            double gap = 1e9; /* the smallest angular gap to a sphere over the cell's rays */
            for (int j = 0; j < 48; j++) {
                double u[4] = {pm_test_unit(&st), pm_test_unit(&st), pm_test_unit(&st), pm_test_unit(&st)};
                u[dim] = (cx + pm_test_unit(&st)) / PJ_G;
                u[dim + 1] = (cy + pm_test_unit(&st)) / PJ_G;
                vec3 p, n, d;
                light_sample_le(&s, 0, u, &p, &n, &d);
                for (int i = 0; i < PJ_NSPH; i++) {
                    any_hit |= pj_hits(p, d, c[i], r[i]);
                    double g = pj_gap(p, d, c[i], r[i]);
                    if (g < gap) gap = g;
                }
            }
            int a = active[cy * PJ_G + cx];
            if (any_hit && !a) missed++;
            /* far: more than 1 radian clear of every sphere, several cells' widths (a cell
             * of a 24 x 24 grid spans at most about 0.5 radian of directions) */
            if (gap > 1.0) {
                nfar++;
                if (a) wasted++;
            }
        }
    EXPECT_MSG(missed == 0, "%s%s seed %llu: %d cells with a ray into a sphere are inactive", light_json[0], light_json[1],
               (unsigned long long)seed, missed);
    EXPECT_MSG(wasted == 0, "%s%s seed %llu: %d cells far from every sphere are active", light_json[0], light_json[1],
               (unsigned long long)seed, wasted);
    *nactive_out = na;
    *nfar_out = nfar;
    scene_free(&s);
}

TEST(render_projmap_cells_cover_every_hit_and_no_far_cell) {
    static const char *const lights[2][2] = {
        /* a point light at the origin, among the spheres */
        {"", ",\"lights\": [{\"type\": \"point\", \"position\": [0,0,0], \"power\": [100,100,100]}]"},
        /* a small area light at the origin, facing +y */
        {",{\"type\": \"quad\", \"vertices\": [[-0.3,0,-0.3],[0.3,0,-0.3],[0.3,0,0.3],[-0.3,0,0.3]], "
         "\"material\": \"e\"}",
         ""},
    };
    for (int li = 0; li < 2; li++) {
        int some_active = 0, some_far = 0;
        for (uint64_t seed = 1; seed <= 4; seed++) {
            int na = 0, nfar = 0;
            pj_check(lights[li], seed, &na, &nfar);
            some_active += na > 0 && na < PJ_G * PJ_G;
            some_far += nfar > 0;
        }
        /* the check has teeth: maps that are neither empty nor full, and far cells to test */
        EXPECT_MSG(some_active >= 3, "light %d: %d of 4 maps partly active", li, some_active);
        EXPECT_MSG(some_far >= 3, "light %d: %d of 4 scenes with far cells", li, some_far);
    }
}
