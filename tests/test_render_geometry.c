/* test_render_geometry.c: ray-shape intersection, the BVH, and self-intersection offsets.
 *
 * Oracles: analytic hit distances (planes and spheres with known geometry), and brute force
 * over all primitives for the BVH.
 */
#include <stdlib.h>

#include "test.h"
#include "../render/scene/bvh.h"
#include "../render/base/rng.h"
#include "../render/base/sampling.h"
#include "../render/scene/shapes.h"

static triangle unit_tri(void) {
    triangle t;
    triangle_make(&t, v3(0, 0, 0), v3(1, 0, 0), v3(0, 1, 0), 0);
    return t;
}

/* Oracle: a ray straight down onto z = 0 at a vertex or on an edge hits at exactly t = 1
 * (the barycentric tests are inclusive); 1e-9 outside the triangle it misses. */
TEST(render_triangle_edges_and_vertices) {
    triangle t = unit_tri();
    const double on[][2] = {{0, 0}, {1, 0}, {0, 1}, {0.5, 0}, {0, 0.5}, {0.5, 0.5}, {0.25, 0.75},
                            {1e-300, 0}, {0.3, 0}};
    for (size_t i = 0; i < sizeof on / sizeof on[0]; i++) {
        double th;
        ray r = {v3(on[i][0], on[i][1], 1), v3(0, 0, -1)};
        ASSERT_MSG(triangle_intersect(&t, r, 0, INFINITY, &th, NULL, NULL), "missed (%g, %g)",
                   on[i][0], on[i][1]);
        ASSERT_NEAR(th, 1.0, 1e-15);
    }
    const double off[][2] = {{-1e-9, 0.5}, {0.5, -1e-9}, {0.5 + 1e-9, 0.5}, {1 + 1e-9, 0}, {0, 1 + 1e-9}};
    for (size_t i = 0; i < sizeof off / sizeof off[0]; i++) {
        double th;
        ray r = {v3(off[i][0], off[i][1], 1), v3(0, 0, -1)};
        ASSERT_MSG(!triangle_intersect(&t, r, 0, INFINITY, &th, NULL, NULL), "hit (%g, %g)",
                   off[i][0], off[i][1]);
    }
}

/* Oracle: a quad split along its diagonal is closed: every ray through the shared edge hits
 * at least one of the two triangles (brute force over 20000 points on the diagonal, from
 * oblique directions). */
TEST(render_triangle_shared_edge_no_leak) {
    triangle a, b;
    triangle_make(&a, v3(0, 0, 0), v3(1, 0, 0), v3(0, 1, 0), 0);
    triangle_make(&b, v3(1, 0, 0), v3(1, 1, 0), v3(0, 1, 0), 0);
    rng g = rng_stream(7, 0, 0);
    int leaks = 0;
    for (int i = 0; i < 20000; i++) {
        double s = rng_uniform(&g);
        vec3 p = v3(s, 1 - s, 0);
        vec3 d = v3_norm(v3(rng_uniform(&g) - 0.5, rng_uniform(&g) - 0.5, -1));
        ray r = {v3_madd(p, d, -3.0), d};
        double t;
        if (!triangle_intersect(&a, r, 0, INFINITY, &t, NULL, NULL) &&
            !triangle_intersect(&b, r, 0, INFINITY, &t, NULL, NULL))
            leaks++;
    }
    ASSERT_EQ_INT(leaks, 0);
}

/* Oracle: a ray 1e-6 rad from the plane of a big triangle, starting 1e-4 above it, hits at
 * t = 1e-4 / sin(1e-6) (analytic), within 1e-9 relative; the hit point lies on z = 0. */
TEST(render_triangle_grazing) {
    triangle t;
    triangle_make(&t, v3(-1e3, -1e3, 0), v3(1e3, -1e3, 0), v3(0, 1e3, 0), 0);
    double a = 1e-6, h = 1e-4;
    ray r = {v3(0, -500, h), v3(0, cos(a), -sin(a))};
    double th;
    ASSERT(triangle_intersect(&t, r, 0, INFINITY, &th, NULL, NULL));
    ASSERT_REL(th, h / sin(a), 1e-9);
    ASSERT_NEAR(ray_at(r, th).z, 0.0, 1e-12);
    /* Parallel to the plane: no hit, and no NaN trouble. */
    ray par = {v3(0, -500, h), v3(0, 1, 0)};
    ASSERT(!triangle_intersect(&t, par, 0, INFINITY, &th, NULL, NULL));
}

/* Oracle: from inside a sphere every ray hits the far side: |p - c| = r to 1e-12 relative. */
TEST(render_sphere_from_inside) {
    sphere s = {v3(1, 2, 3), 5, 0, -1};
    rng g = rng_stream(3, 0, 0);
    for (int i = 0; i < 1000; i++) {
        vec3 o = v3_add(s.c, v3_scale(sample_uniform_sphere(rng_uniform(&g), rng_uniform(&g)),
                                      4.9 * rng_uniform(&g)));
        vec3 d = sample_uniform_sphere(rng_uniform(&g), rng_uniform(&g));
        double t;
        ASSERT(sphere_intersect(&s, (ray){o, d}, 0, INFINITY, &t));
        ASSERT(t > 0);
        ASSERT_REL(v3_len(v3_sub(ray_at((ray){o, d}, t), s.c)), 5.0, 1e-12);
    }
}

/* Oracle: from 1e8 away, a ray at height 0.5 hits the unit sphere at t = 1e8 - sqrt(0.75)
 * (the textbook b^2 - c form loses every digit here: 1e16 - (1e16 - 0.75)); a ray passing at
 * 1 + 1e-6 misses and one at 1 - 1e-6 hits. Also a huge sphere (r = 1e6) seen from near its
 * surface gives |p - c| = r to 1e-12. */
TEST(render_sphere_far_away) {
    sphere s = {v3(0, 0, 0), 1, 0, -1};
    double t;
    ray r = {v3(1e8, 0.5, 0), v3(-1, 0, 0)};
    ASSERT(sphere_intersect(&s, r, 0, INFINITY, &t));
    ASSERT_NEAR(t, 1e8 - sqrt(0.75), 3e-8);
    ASSERT(!sphere_intersect(&s, (ray){v3(1e8, 1 + 1e-6, 0), v3(-1, 0, 0)}, 0, INFINITY, &t));
    ASSERT(sphere_intersect(&s, (ray){v3(1e8, 1 - 1e-6, 0), v3(-1, 0, 0)}, 0, INFINITY, &t));
    sphere big = {v3(0, -1e6, 0), 1e6, 0, -1};
    rng g = rng_stream(4, 0, 0);
    for (int i = 0; i < 1000; i++) {
        vec3 o = v3(rng_uniform(&g) * 100, 1 + rng_uniform(&g), rng_uniform(&g) * 100);
        vec3 d = v3_norm(v3(rng_uniform(&g) - 0.5, -rng_uniform(&g), rng_uniform(&g) - 0.5));
        if (!sphere_intersect(&big, (ray){o, d}, 0, INFINITY, &t)) continue;
        ASSERT_REL(v3_len(v3_sub(ray_at((ray){o, d}, t), big.c)), 1e6, 1e-12);
    }
}

static int brute(const triangle *tr, int nt, const sphere *sp, int ns, ray r, double *tbest) {
    int best = -1;
    *tbest = INFINITY;
    for (int i = 0; i < nt; i++) {
        double t;
        if (triangle_intersect(&tr[i], r, 0, *tbest, &t, NULL, NULL)) *tbest = t, best = i;
    }
    for (int i = 0; i < ns; i++) {
        double t;
        if (sphere_intersect(&sp[i], r, 0, *tbest, &t)) *tbest = t, best = nt + i;
    }
    return best;
}

/* Oracle: brute force over all primitives gives the same nearest hit and the same
 * occlusion answer as the BVH, for random triangles and spheres (including duplicates). */
TEST(render_bvh_matches_brute_force) {
    int nt = 600, ns = 60, nrays = PM_TEST_SANITIZED ? 1000 : 4000;
    triangle *tr = malloc((size_t)nt * sizeof *tr);
    sphere *sp = malloc((size_t)ns * sizeof *sp);
    ASSERT(tr && sp);
    rng g = rng_stream(11, 0, 0);
    for (int i = 0; i < nt; i++) {
        vec3 c = v3(rng_uniform(&g) * 100, rng_uniform(&g) * 100, rng_uniform(&g) * 100);
        if (i % 50 == 49) c = v3(50, 50, 50); /* a cluster of coincident centroids */
        vec3 a, b, cc;
        do {
            a = v3_add(c, v3_scale(sample_uniform_sphere(rng_uniform(&g), rng_uniform(&g)), 5));
            b = v3_add(c, v3_scale(sample_uniform_sphere(rng_uniform(&g), rng_uniform(&g)), 5));
            cc = v3_add(c, v3_scale(sample_uniform_sphere(rng_uniform(&g), rng_uniform(&g)), 5));
        } while (triangle_make(&tr[i], a, b, cc, 0) < 0);
    }
    for (int i = 0; i < ns; i++)
        sp[i] = (sphere){v3(rng_uniform(&g) * 100, rng_uniform(&g) * 100, rng_uniform(&g) * 100),
                         0.5 + 4 * rng_uniform(&g), 0, -1};
    sp[1] = sp[0]; /* an exact duplicate */
    bvh b;
    ASSERT_EQ_INT(bvh_build(&b, tr, nt, sp, ns), 0);
    ASSERT(b.depth < 96);
    int hits = 0;
    for (int i = 0; i < nrays; i++) {
        vec3 o = v3(rng_uniform(&g) * 140 - 20, rng_uniform(&g) * 140 - 20, rng_uniform(&g) * 140 - 20);
        vec3 d = sample_uniform_sphere(rng_uniform(&g), rng_uniform(&g));
        if (i % 10 == 0) d = v3(1, 0, 0); /* axis-parallel rays exercise the slab's infinities */
        ray r = {o, d};
        double tb, t, u, v;
        int pb = brute(tr, nt, sp, ns, r, &tb), p = -1;
        int h = bvh_intersect(&b, r, 0, INFINITY, &t, &p, &u, &v);
        ASSERT_EQ_INT(h, pb >= 0);
        if (h) {
            hits++;
            ASSERT_NEAR(t, tb, 1e-12 * tb);
        }
        ASSERT_EQ_INT(bvh_occluded(&b, r, 0, INFINITY), pb >= 0);
    }
    ASSERT(hits > nrays / 10); /* the test must actually hit things */
    bvh_free(&b);
    free(tr);
    free(sp);
}

/* Oracle: rays reflected off a convex sphere cannot hit it again. Far from the origin
 * (centre at 1e5) a fixed tiny epsilon would re-hit; the magnitude-scaled offset never does. */
TEST(render_offset_avoids_self_hits) {
    sphere s = {v3(1e5, -2e5, 3e5), 1e3, 0, -1};
    rng g = rng_stream(5, 0, 0);
    int self = 0, n = 0;
    for (int i = 0; i < 5000; i++) {
        vec3 o = v3_add(s.c, v3_scale(sample_uniform_sphere(rng_uniform(&g), rng_uniform(&g)), 5e3));
        vec3 d = v3_norm(v3_sub(v3_add(s.c, v3_scale(sample_uniform_sphere(rng_uniform(&g),
                                                                           rng_uniform(&g)), 900)), o));
        double t, t2;
        if (!sphere_intersect(&s, (ray){o, d}, 0, INFINITY, &t)) continue;
        n++;
        vec3 p = ray_at((ray){o, d}, t);
        vec3 nrm = v3_norm(v3_sub(p, s.c));
        vec3 rd = v3_reflect(d, nrm);
        if (sphere_intersect(&s, (ray){v3_offset(p, nrm, rd), rd}, 0, INFINITY, &t2)) self++;
    }
    ASSERT(n > 1000);
    ASSERT_EQ_INT(self, 0);
}
