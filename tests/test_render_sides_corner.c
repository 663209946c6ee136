/* test_render_sides_corner.c: the precomputed irradiance of render/photon_mapping/photon_sides.h
 * at a concave corner, where a floor meets a wall (photon_sides.h, A CORNER).
 *
 * Oracle: the irradiance is known in closed form. The floor (z = 0) and the wall standing on
 * it (x = 0) hold one photon of power 1 in each cell of a jittered grid of spacing h, so the
 * irradiance on both is 1 / h^2 everywhere. The photons on the wall travel down and toward it,
 * so they pass the floor's direction rule (pm_filter_front): a k-nearest search at a floor
 * point within a radius of the wall finds some of them, and before the corner rule the disc
 * estimate counted their power over the floor's disc (reading high there: about +9% averaged
 * over the strip within a radius of the wall, more where the wall cuts the disc least). With
 * the rule the estimate keeps the floor's photons and divides by the part of the disc on the
 * floor, so it reads 1 / h^2 at the corner as in the open. Tolerances: the jittered grid
 * leaves a few per cent of noise in one estimate of k = 40 photons; the means over a strip of
 * lookups are asked to be within 3% (the open floor, far from the wall, is the control: the
 * rule leaves it alone, and it must read right too).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "../render/photons/photon_maps.h"
#include "../render/photon_mapping/photon_sides.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"

/* A floor 0..4 x -2..2 and a wall on its edge x = 0, 2 high, both facing into the corner. */
static const char *CORNER_SCENE =
    "{\"camera\": {\"eye\": [3, 0, 3], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
    " \"materials\": {\"white\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
    " \"objects\": ["
    "  {\"type\": \"quad\", \"vertices\": [[0, -2, 0], [4, -2, 0], [4, 2, 0], [0, 2, 0]], \"material\": \"white\"},"
    "  {\"type\": \"quad\", \"vertices\": [[0, -2, 0], [0, 2, 0], [0, 2, 2], [0, -2, 2]], \"material\": \"white\"}]}";

/* Mean of side_cache_lookup's irradiance (first channel) over n floor points with x in
 * [x0, x1), y in [-1, 1]; *missed counts lookups that found nothing. */
static double strip_mean(const side_cache *c, const scene *s, double x0, double x1, int n, pm_test_rng *r, int *missed) {
    double sum = 0;
    int got = 0;
    for (int i = 0; i < n; i++) {
        vec3 y = v3(x0 + (x1 - x0) * pm_test_unit(r), 2 * pm_test_unit(r) - 1, 0);
        float e[3];
        if (side_cache_lookup(c, s, y, v3(0, 0, 1), 1.0f, e)) {
            sum += e[0];
            got++;
        } else {
            (*missed)++;
        }
    }
    return got ? sum / got : 0;
}

TEST(render_sides_corner_reads_the_surface_irradiance) {
    scene s;
    json_err je;
    ASSERT_MSG(scene_load_text(&s, CORNER_SCENE, &je) == 0, "%s", je.msg);
    const double h = 0.05; /* grid spacing: E = 1 / h^2 = 400 */
    const unsigned k = 40; /* radius about sqrt(k / (pi E)) = 0.18 */
    const int nx = 80, ny = 80, nz = 40;
    const size_t n = (size_t)nx * ny + (size_t)ny * nz;
    pm_test_rng r = {2024};
    photon_maps m;
    memset(&m, 0, sizeof m);
    m.global = calloc(n, sizeof *m.global);
    m.nglobal = n;
    ASSERT(m.global);
    float pw[3] = {1, 1, 1}, up[3] = {0, 0, 1}, toward_wall[3] = {1, 0, 0};
    float down[3] = {0, 0, -1}, down_wall[3] = {-0.6f, 0, -0.8f};
    size_t at = 0;
    for (int i = 0; i < nx; i++) /* the floor */
        for (int j = 0; j < ny; j++) {
            float pos[3] = {(float)(h * (i + pm_test_unit(&r))), (float)(-2 + h * (j + pm_test_unit(&r))), 0};
            pm_photon_init(&m.global[at++], pos, pw, down, up, PM_KIND_INDIRECT);
        }
    for (int j = 0; j < ny; j++) /* the wall: travelling down and toward it */
        for (int i = 0; i < nz; i++) {
            float pos[3] = {0, (float)(-2 + h * (j + pm_test_unit(&r))), (float)(h * (i + pm_test_unit(&r)))};
            pm_photon_init(&m.global[at++], pos, pw, down_wall, toward_wall, PM_KIND_INDIRECT);
        }
    ASSERT(at == n);
    pm_kdtree *t;
    char err[256];
    ASSERT_EQ_INT(photon_tree_build_global(&t, &m, 8, err, sizeof err), 0);
    side_cache c;
    ASSERT_EQ_INT(side_cache_build(&c, &s, t, pm_kdtree_records(t), NULL, n, k, 1.0f, err, sizeof err), 0);
    const double E = 1.0 / (h * h);
    int missed = 0;
    double corner = strip_mean(&c, &s, 0.0, 0.18, 800, &r, &missed) / E - 1;
    double open = strip_mean(&c, &s, 1.5, 3.5, 800, &r, &missed) / E - 1;
    printf("    corner strip %+.2f%%, open floor %+.2f%% of the analytic %g; %zu estimates met a corner, "
           "%d lookups found none\n",
           100 * corner, 100 * open, E, c.corners, missed);
    EXPECT_MSG(fabs(open) < 0.03, "open floor reads %+.2f%%", 100 * open);
    EXPECT_MSG(fabs(corner) < 0.03, "the corner strip reads %+.2f%% (the wall's photons counted on the floor?)",
               100 * corner);
    EXPECT(c.corners > 0 && missed < 16);
    side_cache_free(&c);
    pm_kdtree_free(t);
    photon_maps_free(&m);
    scene_free(&s);
}
