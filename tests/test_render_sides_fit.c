/* test_render_sides_fit.c: precomputed irradiance at fewer photons (photon_sides.h,
 * side_cache_build_at and side_cache_refine; pm_fit.c, PRECOMPUTED POINTS FITTED TO THE RENDER).
 *
 * Oracles, exact (bit for bit), on a map of photons over the floor and both faces of the tall
 * wall of a floor-and-walls scene (so that estimates meet walls and corners):
 *   1. a cache built at a height and refined down to a lower one equals the cache built there
 *      directly: the same count, counters, value of every photon and answer of every lookup,
 *      with 1 and with 2 threads (the eager build of a quarter on 1 thread is the reference);
 *   2. a cache at a height above the quarter (its own tree over the chosen photons) answers
 *      every lookup as the quarter's cache does once the photons below that height are made
 *      unreadable (radius^2 0, as a sparse estimate's): the nearest readable point by the same
 *      rules, i.e. fewer points never change a value, only which one is nearest.
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

#ifdef _OPENMP
#include <omp.h>
#endif

#include "test_sides_scene.h"

enum { FIT_K = 20 };
static const float FIT_R2 = 0.1f;

static void set_threads(int n) {
#ifdef _OPENMP
    omp_set_num_threads(n);
#else
    (void)n;
#endif
}

/* n photons: 70% on the floor (both sides of the tall wall, travelling down), 30% on the tall
 * wall's two faces (travelling toward it), a path of 1 to 4 records each (DIRECT first). */
static void fit_map(photon_maps *m, size_t n, pm_test_rng *r) {
    memset(m, 0, sizeof *m);
    m->global = calloc(n, sizeof *m->global);
    m->nglobal = n;
    int left = 0;
    for (size_t i = 0; i < n && m->global; i++) {
        float pos[3], nrm[3], dir[3];
        float pw[3] = {(float)(0.5 + pm_test_unit(r)), (float)(0.5 + pm_test_unit(r)), (float)(0.5 + pm_test_unit(r))};
        if (pm_test_unit(r) < 0.7) {
            pos[0] = (float)(4 * pm_test_unit(r) - 2), pos[1] = (float)(4 * pm_test_unit(r) - 2), pos[2] = 0;
            nrm[0] = 0, nrm[1] = 0, nrm[2] = 1;
            dir[0] = (float)(pm_test_unit(r) - 0.5), dir[1] = (float)(pm_test_unit(r) - 0.5), dir[2] = -1;
        } else {
            float side = pm_test_unit(r) < 0.5 ? -1.0f : 1.0f;
            pos[0] = side * 1e-4f, pos[1] = (float)(4 * pm_test_unit(r) - 2), pos[2] = (float)pm_test_unit(r);
            nrm[0] = side, nrm[1] = 0, nrm[2] = 0;
            dir[0] = -side, dir[1] = (float)(pm_test_unit(r) - 0.5), dir[2] = (float)(-pm_test_unit(r));
        }
        int first = left == 0; /* a new path: its first record is its DIRECT one */
        if (first) left = 1 + (int)(4 * pm_test_unit(r));
        pm_photon_init(&m->global[i], pos, pw, dir, nrm, first ? PM_KIND_DIRECT : PM_KIND_INDIRECT);
        left--;
    }
}

static int build_at(side_cache *c, const scene *s, const pm_kdtree *t, const photon_maps *m, int height) {
    char err[256];
    int rc = side_cache_build_at(c, s, t, pm_kdtree_records(t), m->global_path, m->nglobal, FIT_K, FIT_R2, height,
                                 err, sizeof err);
    if (rc) printf("    %s\n", err);
    return rc;
}

static int refine(side_cache *c, const scene *s, const pm_kdtree *t, const photon_maps *m, int height) {
    char err[256];
    int rc = side_cache_refine(c, s, t, pm_kdtree_records(t), m->global_path, m->nglobal, FIT_K, FIT_R2, height, err,
                               sizeof err);
    if (rc) printf("    %s\n", err);
    return rc;
}

/* Random lookups over the floor and the wall's faces (facing up, or away from the wall). */
static void fit_query(pm_test_rng *r, vec3 *y, vec3 *n) {
    if (pm_test_unit(r) < 0.8) {
        *y = v3(3.8 * pm_test_unit(r) - 1.9, 3.8 * pm_test_unit(r) - 1.9, 0);
        *n = v3(0, 0, 1);
    } else {
        double side = pm_test_unit(r) < 0.5 ? -1 : 1;
        *y = v3(side * 1e-4, 3.8 * pm_test_unit(r) - 1.9, 0.9 * pm_test_unit(r) + 0.05);
        *n = v3(side, 0, 0);
    }
}

/* Lookups that differ between a and b (found, or any bit of the value), of q; *found counts
 * a's answers. */
static int lookups_differ(const side_cache *a, const side_cache *b, const scene *s, int q, unsigned seed, int *found) {
    pm_test_rng r = {seed};
    int bad = 0;
    *found = 0;
    for (int i = 0; i < q; i++) {
        vec3 y, n;
        fit_query(&r, &y, &n);
        float ea[3], eb[3];
        int fa = side_cache_lookup(a, s, y, n, FIT_R2, ea), fb = side_cache_lookup(b, s, y, n, FIT_R2, eb);
        *found += fa;
        bad += fa != fb || memcmp(ea, eb, sizeof ea) != 0;
    }
    return bad;
}

/* Photons whose precomputed value differs between a and b (both over the map's own tree, or
 * both over trees of the same chosen photons), or whose presence does. */
static size_t values_differ(const side_cache *a, const side_cache *b, size_t n) {
    size_t bad = 0;
    for (uint32_t i = 0; i < n; i++) {
        float va[3], vb[3];
        int ha = pm_irradiance_value(a->irr, i, va), hb = pm_irradiance_value(b->irr, i, vb);
        bad += ha != hb || memcmp(va, vb, sizeof va) != 0;
    }
    return bad;
}

static int counters_equal(const side_cache *a, const side_cache *b) {
    return a->n == b->n && a->rays_first == b->rays_first && a->rays_second == b->rays_second &&
           a->researched == b->researched && a->corners == b->corners && a->sparse == b->sparse &&
           a->height == b->height && a->quarter == b->quarter;
}

/* The fixture of both oracles: SIDES_SCENE, n photons of fit_map from seed, and the global map's
 * tree with the renderer's buckets. 0, or -1 with a message (nothing left to free). */
static int fit_setup(scene *s, photon_maps *m, pm_kdtree **t, size_t n, unsigned seed) {
    json_err e;
    if (scene_load_text(s, SIDES_SCENE, &e) != 0) {
        printf("    %s\n", e.msg);
        return -1;
    }
    pm_test_rng r = {seed};
    fit_map(m, n, &r);
    char err[256];
    if (m->global && photon_tree_build_global(t, m, 1, err, sizeof err) == 0) return 0;
    printf("    %s\n", m->global ? err : "out of memory");
    photon_maps_free(m);
    scene_free(s);
    return -1;
}

/* Oracle 1 above. */
TEST(render_sides_refined_cache_equals_built) {
    const size_t n = PM_TEST_SANITIZED ? 3000 : 12000;
    const int q = PM_TEST_SANITIZED ? 400 : 2000;
    scene s;
    photon_maps m;
    pm_kdtree *t;
    ASSERT(fit_setup(&s, &m, &t, n, 977) == 0);
    int saved = 1;
#ifdef _OPENMP
    saved = omp_get_max_threads();
#endif
    set_threads(1);
    side_cache ref[3]; /* built at 2, 3, 4 on one thread */
    for (int h = 2; h <= 4; h++) ASSERT_EQ_INT(build_at(&ref[h - 2], &s, t, &m, h), 0);
    size_t cnt[3] = {0, 0, 0};
    for (uint32_t i = 0; i < n; i++)
        for (int h = 2; h <= 4; h++) cnt[h - 2] += pm_kdtree_height(t, i) >= h;
    printf("    %zu photons: %zu / %zu / %zu precomputed at heights 2 / 3 / 4 (%zu corners, %zu walls at 2)\n", n,
           ref[0].n, ref[1].n, ref[2].n, ref[0].corners, ref[0].researched);
    for (int h = 2; h <= 4; h++) EXPECT_MSG(ref[h - 2].n == cnt[h - 2], "height %d: %zu of %zu", h, ref[h - 2].n, cnt[h - 2]);
    EXPECT_MSG(ref[0].corners > 0 && ref[0].researched > 0, "no estimate met the wall (%zu) or a corner (%zu)",
               ref[0].researched, ref[0].corners);
    for (int threads = 1; threads <= 2; threads++) {
        set_threads(threads);
        for (int from = 3; from <= 4; from++)
            for (int to = 2; to < from; to++) {
                side_cache c;
                ASSERT_EQ_INT(build_at(&c, &s, t, &m, from), 0);
                ASSERT_EQ_INT(refine(&c, &s, t, &m, to), 0);
                int found;
                int bad = lookups_differ(&c, &ref[to - 2], &s, q, 5 + (unsigned)to, &found);
                size_t vbad = values_differ(&c, &ref[to - 2], n);
                printf("    %d thread(s), %d -> %d: %d of %d lookups found, %d differ, %zu values differ\n", threads,
                       from, to, found, q, bad, vbad);
                EXPECT_MSG(counters_equal(&c, &ref[to - 2]), "%d -> %d: counters differ", from, to);
                EXPECT_EQ_INT(bad, 0);
                EXPECT_MSG(vbad == 0, "%zu values differ", vbad);
                EXPECT_MSG(found > q / 2, "only %d of %d lookups found a value", found, q);
                side_cache_free(&c);
            }
        side_cache c; /* the quarter on 2 threads too */
        ASSERT_EQ_INT(build_at(&c, &s, t, &m, 2), 0);
        int found;
        EXPECT_EQ_INT(lookups_differ(&c, &ref[0], &s, q, 11, &found), 0);
        EXPECT_MSG(counters_equal(&c, &ref[0]) && values_differ(&c, &ref[0], n) == 0, "quarter, %d threads", threads);
        side_cache_free(&c);
    }
    set_threads(saved);
    for (int h = 0; h < 3; h++) side_cache_free(&ref[h]);
    pm_kdtree_free(t);
    photon_maps_free(&m);
    scene_free(&s);
}

/* Oracle 2 above. */
TEST(render_sides_fewer_points_answer_as_the_quarter_masked) {
    const size_t n = PM_TEST_SANITIZED ? 3000 : 12000;
    const int q = PM_TEST_SANITIZED ? 400 : 3000;
    scene s;
    photon_maps m;
    pm_kdtree *t;
    ASSERT(fit_setup(&s, &m, &t, n, 1201) == 0);
    side_cache quarter;
    ASSERT_EQ_INT(build_at(&quarter, &s, t, &m, 2), 0);
    float *r2m = malloc(n * sizeof *r2m);
    ASSERT(r2m);
    for (int h = 3; h <= 4; h++) {
        side_cache c, masked;
        ASSERT_EQ_INT(build_at(&c, &s, t, &m, h), 0);
        memset(&masked, 0, sizeof masked);
        for (uint32_t i = 0; i < n; i++) r2m[i] = pm_kdtree_height(t, i) >= h ? quarter.r2v[i] : 0.0f;
        pm_irradiance_options io;
        pm_irradiance_options_init(&io, FIT_K);
        io.fraction = PM_PRECOMP_QUARTER;
        io.store_radius = 1;
        io.store_index = 1;
        ASSERT_EQ_INT(pm_irradiance_build_values(&masked.irr, t, &io, quarter.val, r2m), 0);
        masked.look_hfree = quarter.hfree;
        masked.look_flat = quarter.flat;
        int found, found_q;
        int bad = lookups_differ(&c, &masked, &s, q, 23 + (unsigned)h, &found);
        int moved = lookups_differ(&c, &quarter, &s, q, 23 + (unsigned)h, &found_q);
        printf("    height %d: %zu points, %d of %d lookups found, %d differ from the masked quarter's, %d from the "
               "quarter's\n", h, c.n, found, q, bad, moved);
        EXPECT_EQ_INT(bad, 0);
        EXPECT_MSG(found > q / 2, "only %d of %d lookups found a value", found, q);
        EXPECT_MSG(moved > 0, "height %d answered every lookup as the quarter (the test cannot tell them apart)", h);
        pm_irradiance_free(masked.irr);
        side_cache_free(&c);
    }
    free(r2m);
    side_cache_free(&quarter);
    pm_kdtree_free(t);
    photon_maps_free(&m);
    scene_free(&s);
}
