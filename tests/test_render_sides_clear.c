/* test_render_sides_clear.c: the precomputation's segments cleared without a ray
 * (render/photon_mapping/photon_sides.h, side_planes_near and side_clear) and the BVH's box
 * query they use (render/scene/bvh.h, bvh_overlap).
 *
 * Oracles: bvh_overlap against a scan of every primitive's box; side_clear against the ray
 * itself: whenever it says clear, side_visible_h (the traced segment) must say visible, over
 * many random segments in pinhole_room (a closed room standing on the big room's floor plane,
 * with walls, a roof with a hole and corners, where many segments are blocked) and in a box
 * with a sphere (no plane for a sphere: never cleared). The test also checks that clearing
 * happens at all (most segments in open stretches of the floor are cleared), so that the
 * implication is not met by a side_clear that never answers 1.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "../render/photon_mapping/photon_sides.h"
#include "../render/scene/bvh.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"

static void prim_box(const bvh *b, int id, double lo[3], double hi[3]) {
    if (id < b->ntris) {
        const triangle *t = &b->tris[id];
        vec3 p[3] = {t->v0, v3_add(t->v0, t->e1), v3_add(t->v0, t->e2)};
        for (int a = 0; a < 3; a++) {
            lo[a] = fmin(fmin(v3_idx(p[0], a), v3_idx(p[1], a)), v3_idx(p[2], a));
            hi[a] = fmax(fmax(v3_idx(p[0], a), v3_idx(p[1], a)), v3_idx(p[2], a));
        }
        return;
    }
    const sphere *sp = &b->spheres[id - b->ntris];
    for (int a = 0; a < 3; a++) {
        lo[a] = v3_idx(sp->c, a) - sp->r;
        hi[a] = v3_idx(sp->c, a) + sp->r;
    }
}

static int load_scene_file(scene *s, const char *name) {
    char path[1024];
    const char *src = getenv("PM_SOURCE_DIR");
    snprintf(path, sizeof path, "%s/data/scenes/%s", src ? src : ".", name);
    json_err e;
    if (scene_load(s, path, &e) != 0) {
        fprintf(stderr, "%s: %s\n", path, e.msg);
        return -1;
    }
    return 0;
}

static const char *BOX_SPHERE =
    "{\"camera\": {\"eye\": [0, -5, 3], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
    " \"materials\": {\"white\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
    " \"objects\": ["
    "  {\"type\": \"quad\", \"vertices\": [[-2, -2, 0], [2, -2, 0], [2, 2, 0], [-2, 2, 0]], \"material\": \"white\"},"
    "  {\"type\": \"quad\", \"vertices\": [[0, -2, 0], [0, 2, 0], [0, 2, 1], [0, -2, 1]], \"material\": \"white\"},"
    "  {\"type\": \"sphere\", \"center\": [1, 1, 0.3], \"radius\": 0.3, \"material\": \"white\"}]}";

/* The two scenes both tests walk: the shipped pinhole room and BOX_SPHERE; 0, or -1 with
 * neither loaded (the error printed). */
static int load_both_scenes(scene s[2]) {
    json_err e;
    if (load_scene_file(&s[0], "pinhole_room.json") != 0) return -1;
    if (scene_load_text(&s[1], BOX_SPHERE, &e) != 0) {
        fprintf(stderr, "BOX_SPHERE: %s\n", e.msg);
        scene_free(&s[0]);
        return -1;
    }
    return 0;
}

/* bvh_overlap returns exactly the primitives whose boxes overlap the query box (as a set), or
 * cap + 1 when there are more than cap. */
TEST(render_bvh_overlap_matches_a_scan) {
    scene s[2];
    ASSERT(load_both_scenes(s) == 0);
    pm_test_rng r = {99};
    int checked = 0, over = 0;
    for (int si = 0; si < 2; si++) {
        const bvh *b = &s[si].accel;
        double scale = si == 0 ? 1000 : 4, off = si == 0 ? 0 : -2;
        for (int q = 0; q < 3000; q++) {
            double lo[3], hi[3], half = scale * 0.3 * pm_test_unit(&r) * pm_test_unit(&r);
            for (int a = 0; a < 3; a++) {
                double c = off + scale * pm_test_unit(&r);
                lo[a] = c - half;
                hi[a] = c + half;
            }
            int cap = q % 3 == 0 ? 2 : 64;
            uint32_t out[64];
            int n = bvh_overlap(b, lo, hi, out, cap);
            int want = 0;
            char *in = calloc((size_t)(b->ntris + b->nspheres), 1);
            ASSERT(in != NULL);
            for (int id = 0; id < b->ntris + b->nspheres; id++) {
                double plo[3], phi[3];
                prim_box(b, id, plo, phi);
                int ov = 1;
                for (int a = 0; a < 3; a++) ov &= plo[a] <= hi[a] && lo[a] <= phi[a];
                in[id] = (char)ov;
                want += ov;
            }
            if (want > cap) {
                EXPECT_EQ_INT(n, cap + 1);
                over++;
            } else {
                EXPECT_EQ_INT(n, want);
                for (int i = 0; i < n && i < cap; i++) {
                    EXPECT(in[out[i]] == 1);
                    in[out[i]] = 2; /* each once */
                }
            }
            free(in);
            checked++;
        }
    }
    EXPECT(over > 0);
    scene_free(&s[0]);
    scene_free(&s[1]);
    (void)checked;
}

/* A random surface point of the scene near x: a ray from x in a random direction, its hit if
 * within reach. */
static int near_point(const scene *s, vec3 x, double reach, pm_test_rng *r, vec3 *p, vec3 *n) {
    double z = 2 * pm_test_unit(r) - 1, a = 2 * M_PI * pm_test_unit(r), q = sqrt(fmax(0, 1 - z * z));
    ray ry = {x, v3(q * cos(a), q * sin(a), z)};
    hit h;
    if (!scene_intersect(s, ry, reach, &h)) return 0;
    *p = h.p;
    *n = v3_dot(h.ng, ry.d) < 0 ? h.ng : v3_neg(h.ng);
    return 1;
}

/* Clear implies visible (the ray's answer), over random segments near random points; and it
 * does clear most of them on an open floor, never near the sphere. */
TEST(render_sides_clear_implies_the_ray_sees) {
    scene s[2];
    ASSERT(load_both_scenes(s) == 0);
    pm_test_rng r = {2024};
    int cleared = 0, tested = 0, blocked = 0, open_cleared = 0, open_tested = 0, sphere_cleared = 0;
    const int trials = PM_TEST_SANITIZED ? 800 : 4000;
    for (int si = 0; si < 2; si++) {
        for (int t = 0; t < trials; t++) {
            /* x: a surface point seen from a random point inside the scene's box */
            vec3 o = si == 0 ? v3(1000 * pm_test_unit(&r), 1000 * pm_test_unit(&r), 1000 * pm_test_unit(&r))
                             : v3(4 * pm_test_unit(&r) - 2, 4 * pm_test_unit(&r) - 2, 0.05 + 0.9 * pm_test_unit(&r));
            vec3 x, nx;
            if (!near_point(&s[si], o, INFINITY, &r, &x, &nx)) continue;
            double rad = (si == 0 ? 60 : 0.6) * (0.05 + pm_test_unit(&r));
            side_planes pl;
            side_planes_near(&s[si], x, rad * rad, &pl);
            double hx = side_free_height(&s[si], x, nx, 0.25 * rad);
            for (int j = 0; j < 8; j++) {
                vec3 q, nq;
                /* q: a surface point seen from a random point near x, so often behind a wall from x */
                vec3 o2 = v3_madd(x, nx, 1e-3 * rad);
                if (j % 2) o2 = v3_add(o2, v3(rad * (2 * pm_test_unit(&r) - 1), rad * (2 * pm_test_unit(&r) - 1),
                                              rad * (2 * pm_test_unit(&r) - 1)));
                if (!near_point(&s[si], o2, 2 * rad, &r, &q, &nq)) continue;
                if (v3_len(v3_sub(q, x)) > rad) continue;
                double hq = side_free_height(&s[si], q, nq, 0.25 * rad);
                int clear = side_clear(&pl, x, nx, hx, q, nq, hq);
                int vis = side_visible_h(&s[si], x, nx, hx, q, nq, hq);
                tested++;
                blocked += !vis;
                cleared += clear;
                EXPECT_MSG(!clear || vis, "scene %d: cleared a blocked segment (%g %g %g) -> (%g %g %g)", si, x.x, x.y, x.z, q.x,
                           q.y, q.z);
                if (si == 1 && pl.ok) { /* the sphere's box overlaps the query's: never listed */
                    double R = 1.3 * rad + 2 * pl.margin;
                    sphere_cleared += fabs(x.x - 1) <= 0.3 + R && fabs(x.y - 1) <= 0.3 + R && fabs(x.z - 0.3) <= 0.3 + R;
                }
                int open = si == 0 && x.y < 1e-9 && nx.y > 0.99 && q.y < 1e-9 && nq.y > 0.99 &&
                           (x.x < 250 || x.x > 750 || x.z < 250 || x.z > 750) && x.x > 60 && x.x < 940 &&
                           x.z > 60 && x.z < 940 && rad < 35;
                open_tested += open;
                open_cleared += open && clear;
            }
        }
    }
    fprintf(stderr, "  %d segments: %d blocked, %d cleared; open floor %d of %d cleared\n", tested, blocked,
            cleared, open_cleared, open_tested);
    EXPECT(tested > 1000);
    EXPECT(blocked > 20); /* the test meets walls */
    EXPECT(open_tested > 20 && open_cleared > 0.9 * open_tested);
    EXPECT_EQ_INT(sphere_cleared, 0);
    scene_free(&s[0]);
    scene_free(&s[1]);
}
