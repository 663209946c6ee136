/* test_render_sides.c: the side-keeping precomputed irradiance of render/photon_mapping/photon_sides.h, read
 * through the module's lookup with a caller's rule (photonmap/irradiance.h).
 *
 * Oracle: a brute-force scan of the records with the rules of photon_sides.h written out:
 * the normal within the module's cos 0.7, the query within the record's own radius and the
 * search radius, the 8 nearest such records, the first of them that side_visible_h sees from
 * the query. The scene is a floor with a tall wall (every segment across it is blocked) and a
 * low wall (a segment across it is blocked or not depending on how high its ends are lifted,
 * so each record's own free height matters). Also the photon paths (photon_maps.h) and the
 * readable rule that counts them, and the shadow hint's filter, each against its definition.
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

#include "test_sides_scene.h"

typedef struct sc_cand { float d2; uint32_t i; } sc_cand;
static int sc_cmp(const void *a, const void *b) {
    const sc_cand *x = a, *y = b;
    return x->d2 < y->d2 ? -1 : x->d2 > y->d2;
}

/* Oracle above. Records: Poisson positions on the floor (none in a strip right of the tall
 * wall, where a quarter of the queries fall), 85% facing up and 15% tilted past the normal
 * rule, random RGB values, radii^2 and free heights. Queries: random floor points facing up. Exact equality of the values (RGBE bytes in, the same bytes out). Also: the wall
 * decides some lookups (an answer that is not the nearest candidate, and "none" with
 * candidates present), and the records come back in tree order (side_cache_from_records
 * reorders them in place). */
TEST(render_sides_cache_from_records_matches_brute_force) {
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, SIDES_SCENE, &e) == 0, "%s", e.msg);
    const size_t m = PM_TEST_SANITIZED ? 1500 : 4000;
    const int queries = PM_TEST_SANITIZED ? 400 : 2000;
    const float max_dist2 = 0.02f;
    pm_photon *recs = malloc(sizeof *recs * m), *orig = malloc(sizeof *orig * m);
    float *r2 = malloc(sizeof *r2 * m), *hf = malloc(sizeof *hf * m);
    sc_cand *cs = malloc(sizeof *cs * m);
    pm_test_rng r = {4242};
    for (size_t i = 0; i < m; i++) {
        float pos[3] = {(float)(2 * pm_test_unit(&r) - 1), (float)(2 * pm_test_unit(&r) - 1), 0};
        if (pos[0] > 0 && pos[0] < 0.15f) pos[0] += 0.15f; /* a strip without photons right of the wall */
        float up[3] = {0, 0, 1}, tilt[3] = {0.8f, 0, 0.6f}, down[3] = {0, 0, -1};
        float p[3] = {(float)pm_test_unit(&r), (float)pm_test_unit(&r), (float)(0.01 + pm_test_unit(&r))};
        pm_photon_init(&recs[i], pos, p, down, pm_test_unit(&r) < 0.85 ? up : tilt, PM_KIND_INDIRECT);
        r2[i] = (float)(0.002 + 0.03 * pm_test_unit(&r));
        hf[i] = (float)(0.1 * pm_test_unit(&r));
    }
    memcpy(orig, recs, sizeof *recs * m);
    side_cache c;
    char err[256];
    ASSERT_EQ_INT(side_cache_from_records(&c, recs, r2, hf, m, err, sizeof err), 0);
    ASSERT(c.n == m && c.irr != NULL);
    EXPECT(memcmp(orig, recs, sizeof *recs * m) != 0); /* reordered in place */
    int found = 0, none_with_candidates = 0, skipped_nearest = 0;
    vec3 n = v3(0, 0, 1);
    float nf[3] = {0, 0, 1};
    for (int qi = 0; qi < queries; qi++) {
        vec3 y = v3(qi % 4 ? 2 * pm_test_unit(&r) - 1 : 0.02 * pm_test_unit(&r), 2 * pm_test_unit(&r) - 1, 0);
        float yf[3] = {(float)y.x, (float)y.y, (float)y.z};
        double hy = side_free_height(&s, y, n, 0.25 * sqrt((double)max_dist2));
        size_t nc = 0;
        for (uint32_t i = 0; i < m; i++) {
            float pn[3];
            pm_normal_decode(orig[i].normal, pn);
            if (pn[0] * nf[0] + pn[1] * nf[1] + pn[2] * nf[2] < 0.7f) continue;
            float d[3] = {orig[i].pos[0] - yf[0], orig[i].pos[1] - yf[1], orig[i].pos[2] - yf[2]};
            float d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            if (!(d2 < r2[i]) || !(d2 < max_dist2)) continue;
            cs[nc].d2 = d2, cs[nc].i = i, nc++;
        }
        qsort(cs, nc, sizeof *cs, sc_cmp);
        int want = -1;
        for (size_t t = 0; t < nc && t < 8 && want < 0; t++) {
            const pm_photon *p = &orig[cs[t].i];
            float pn[3];
            pm_normal_decode(p->normal, pn);
            if (side_visible_h(&s, y, n, hy, v3(p->pos[0], p->pos[1], p->pos[2]), v3(pn[0], pn[1], pn[2]),
                               hf[cs[t].i]))
                want = (int)t;
        }
        float got[3], exp[3] = {0, 0, 0};
        int rc = side_cache_lookup(&c, &s, y, n, max_dist2, got);
        if (want >= 0) pm_rgbe_decode(orig[cs[want].i].power, exp);
        EXPECT_MSG(rc == (want >= 0) && memcmp(got, exp, sizeof got) == 0,
                   "query %d at (%g, %g): lookup %d (%g), brute force %s %g (%zu candidates)", qi, y.x, y.y, rc,
                   got[0], want >= 0 ? "candidate" : "none", exp[0], nc);
        found += want >= 0;
        none_with_candidates += want < 0 && nc > 0;
        skipped_nearest += want > 0;
    }
    printf("side cache from records: %d of %d lookups found, %d found none with candidates, %d skipped a hidden nearest\n",
           found, queries, none_with_candidates, skipped_nearest);
    EXPECT(found > queries / 2 && none_with_candidates > 0 && skipped_nearest > queries / 100);
    side_cache_free(&c);
    EXPECT(c.irr == NULL && c.hfree == NULL);
    free(cs);
    free(hf);
    free(r2);
    free(orig);
    free(recs);
    scene_free(&s);
}

/* Oracle: geometry. Inside a sphere of radius R, the ray from a point of the surface along its
 * inward normal (the photon's 1-byte code, within 10 degrees) runs a chord of at least 1.9 R
 * before it meets anything, so the free height capped at R / 10 is the cap; and two points of
 * the surface see each other along a chord, so side_visible_h says visible. The points are
 * photons' float positions (hit points of rays from inside, rounded, then one float step
 * outward in each coordinate: the furnace's photons lay up to that far outside), off the true
 * surface by more than a ray offset at |p| of 100 and more: a free height taken from there used to meet the photon's own
 * surface at once (0), and hid the photon from every neighbour (the furnace at 10x its size
 * read +42%). Spheres of radius 1, 10, 100 and 1000 off the origin; 500 photons each. */
TEST(render_sides_free_height_past_float_rounding) {
    const double radii[4] = {1, 10, 100, 1000};
    for (int ri = 0; ri < 4; ri++) {
        double R = radii[ri];
        vec3 c = v3(0.3 * R, -0.2 * R, 0.1 * R);
        char txt[1024];
        snprintf(txt, sizeof txt,
                 "{\"camera\": {\"eye\": [%g, %g, %g], \"look_at\": [%g, %g, %g], \"fov_deg\": 90, \"width\": 8, \"height\": 8},"
                 " \"materials\": {\"white\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
                 " \"objects\": [{\"type\": \"sphere\", \"center\": [%.17g, %.17g, %.17g], \"radius\": %g, \"material\": \"white\"}]}",
                 c.x, c.y, c.z, c.x, c.y, c.z + 1, c.x, c.y, c.z, R);
        scene s;
        json_err e;
        ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
        pm_test_rng r = {77 + (uint64_t)ri};
        enum { N = 500 };
        vec3 pos[N], nrm[N];
        double h[N];
        int short_h = 0, hidden = 0;
        for (int i = 0; i < N; i++) {
            /* where a photon lands: a ray from inside, its hit point as a float */
            double z = 2 * pm_test_unit(&r) - 1, a = 2 * M_PI * pm_test_unit(&r), t = sqrt(1 - z * z);
            ray ry = {v3_add(c, v3_scale(v3(pm_test_unit(&r) - 0.5, pm_test_unit(&r) - 0.5, pm_test_unit(&r) - 0.5), R)),
                      v3(t * cos(a), t * sin(a), z)};
            hit hh;
            ASSERT(scene_intersect(&s, ry, INFINITY, &hh));
            vec3 n = v3_dot(ry.d, hh.ng) < 0 ? hh.ng : v3_neg(hh.ng);
            float pf[3] = {(float)hh.p.x, (float)hh.p.y, (float)hh.p.z}, in[3] = {(float)n.x, (float)n.y, (float)n.z}, nd[3];
            /* the worst rounding: one float step outward in each coordinate */
            for (int k = 0; k < 3; k++) pf[k] = nextafterf(pf[k], in[k] < 0 ? INFINITY : -INFINITY);
            pm_normal_decode(pm_normal_encode(in), nd);
            pos[i] = v3(pf[0], pf[1], pf[2]);
            nrm[i] = v3(nd[0], nd[1], nd[2]);
            h[i] = side_free_height(&s, pos[i], nrm[i], 0.1 * R);
            short_h += !(h[i] == 0.1 * R);
        }
        for (int i = 0; i + 1 < N; i += 2)
            hidden += !side_visible_h(&s, pos[i], nrm[i], h[i], pos[i + 1], nrm[i + 1], h[i + 1]);
        EXPECT_MSG(short_h == 0 && hidden == 0, "radius %g: %d of %d free heights below the cap, %d of %d pairs hidden",
                   R, short_h, N, hidden, N / 2);
        scene_free(&s);
    }
}

/* Oracle: the definition (photon_maps.h, PHOTON PATHS): in map order a new path begins at every
 * DIRECT record after the first record. Then the ids follow their records through the tree's
 * reordering (photon_tree_build_global): each record is found again by its position, which
 * holds its map index. */
TEST(render_sides_paths_numbered_from_direct_records) {
    static const int kinds[10] = {PM_KIND_INDIRECT, PM_KIND_INDIRECT, PM_KIND_DIRECT, PM_KIND_INDIRECT,
                                  PM_KIND_DIRECT, PM_KIND_DIRECT, PM_KIND_INDIRECT, PM_KIND_INDIRECT,
                                  PM_KIND_DIRECT, PM_KIND_INDIRECT};
    static const uint32_t want[10] = {0, 0, 1, 1, 2, 3, 3, 3, 4, 4};
    pm_photon ph[10];
    uint32_t got[10];
    float pw[3] = {1, 1, 1}, d[3] = {0, 0, -1}, up[3] = {0, 0, 1};
    for (int i = 0; i < 10; i++) {
        float pos[3] = {(float)i, 0, 0};
        pm_photon_init(&ph[i], pos, pw, d, up, kinds[i]);
    }
    photon_paths(ph, 10, got);
    for (int i = 0; i < 10; i++) EXPECT_MSG(got[i] == want[i], "record %d: path %u, want %u", i, got[i], want[i]);

    const size_t n = PM_TEST_SANITIZED ? 2000 : 20000;
    photon_maps m;
    memset(&m, 0, sizeof m);
    m.global = calloc(n, sizeof *m.global);
    m.nglobal = n;
    uint32_t *ref = malloc(n * sizeof *ref);
    ASSERT(m.global && ref);
    pm_test_rng r = {99};
    for (size_t i = 0; i < n; i++) {
        float pos[3] = {(float)i, (float)pm_test_unit(&r), (float)pm_test_unit(&r)}; /* x: the map index */
        pm_photon_init(&m.global[i], pos, pw, d, up, pm_test_unit(&r) < 0.3 ? PM_KIND_DIRECT : PM_KIND_INDIRECT);
    }
    photon_paths(m.global, n, ref);
    pm_kdtree *t;
    char err[256];
    ASSERT_EQ_INT(photon_tree_build_global(&t, &m, 8, err, sizeof err), 0);
    ASSERT(t && m.global_path);
    size_t moved = 0, bad = 0;
    for (size_t i = 0; i < n; i++) {
        size_t at = (size_t)m.global[i].pos[0];
        moved += at != i;
        bad += m.global_path[i] != ref[at];
    }
    EXPECT_MSG(bad == 0 && moved > n / 2, "%zu of %zu ids wrong (%zu records moved)", bad, n, moved);
    EXPECT(ref[n - 1] > n / 5); /* about 0.3 n paths */
    pm_kdtree_free(t);
    photon_maps_free(&m);
    free(ref);
}

/* Oracle: a brute-force count of the distinct ids among the photons (each id against every
 * earlier one), direct and indirect alike, capped as asked (1, SIDE_MIN_PATHS, 20 and no cap);
 * without ids (NULL) every photon is a path of its own. And the readable rule's threshold. */
TEST(render_sides_count_paths_brute_force) {
    enum { N = 300, K = 64 };
    uint32_t path[N], scratch[K];
    pm_test_rng r = {5};
    for (int i = 0; i < N; i++) path[i] = (uint32_t)(pm_test_unit(&r) * (i % 3 ? 12 : 4000)); /* many repeats */
    for (int trial = 0; trial < 200; trial++) {
        pm_neighbor nb[K];
        int count = (int)(pm_test_unit(&r) * K);
        for (int j = 0; j < count; j++) nb[j].index = (uint32_t)(pm_test_unit(&r) * N), nb[j].dist2 = 0;
        unsigned want = 0;
        for (int j = 0; j < count; j++) {
            int seen = 0;
            for (int q = 0; q < j && !seen; q++) seen = path[nb[q].index] == path[nb[j].index];
            want += !seen;
        }
        const unsigned caps[] = {1, SIDE_MIN_PATHS, 20, K};
        for (int c = 0; c < 4; c++) {
            unsigned cap = caps[c];
            EXPECT_EQ_INT(side_count_paths(path, nb, count, cap, scratch), want < cap ? want : cap);
            EXPECT_EQ_INT(side_count_paths(NULL, nb, count, cap, scratch), (unsigned)count < cap ? (unsigned)count : cap);
        }
    }
    EXPECT(!side_estimate_readable(SIDE_MIN_PATHS - 1) && side_estimate_readable(SIDE_MIN_PATHS));
}

/* Oracle: the whole map's count. render-mpi's partitioned build (lookup.h) sums the distinct
 * paths each part counts with the ids photon_tree_build_global numbers from that part alone (a
 * run of the map's order): the sum is the whole map's count, plus at most one for each path
 * that straddles two parts' boundary (M - 1 of them), never less. And the build's counts,
 * capped at SIDE_MIN_PATHS, make the same readable decision as the full ones. Random maps (30%
 * DIRECT records), split into M = 2..5 runs, random neighbour sets of 10 to 200 records. */
TEST(render_sides_paths_of_parts_add_up) {
    enum { N = 3000, K = 200 };
    pm_photon *ph = malloc(N * sizeof *ph);
    uint32_t *whole = malloc(N * sizeof *whole), *part = malloc(N * sizeof *part), scratch[K];
    ASSERT(ph && whole && part);
    float pw[3] = {1, 1, 1}, d[3] = {0, 0, -1}, up[3] = {0, 0, 1}, pos[3] = {0, 0, 0};
    pm_test_rng r = {123};
    for (int i = 0; i < N; i++)
        pm_photon_init(&ph[i], pos, pw, d, up, pm_test_unit(&r) < 0.3 ? PM_KIND_DIRECT : PM_KIND_INDIRECT);
    photon_paths(ph, N, whole);
    int exact = 0, over = 0;
    for (int M = 2; M <= 5; M++) {
        size_t lo[6];
        for (int p = 0; p <= M; p++) lo[p] = (size_t)N * (size_t)p / (size_t)M;
        for (int p = 0; p < M; p++) photon_paths(ph + lo[p], lo[p + 1] - lo[p], part + lo[p]);
        for (int trial = 0; trial < 100; trial++) {
            int count = 10 + (int)(pm_test_unit(&r) * (K - 10));
            pm_neighbor nb[K], sub[K];
            /* near a part's boundary half the time, so that straddling paths show */
            size_t c0 = trial % 2 ? lo[1 + trial % (M - 1)] - 20 : (size_t)(pm_test_unit(&r) * (N - 60));
            for (int j = 0; j < count; j++)
                nb[j].index = (uint32_t)(c0 + (size_t)(pm_test_unit(&r) * 60)), nb[j].dist2 = 0;
            unsigned want = side_count_paths(whole, nb, count, K, scratch), sum = 0, capped = 0;
            for (int p = 0; p < M; p++) { /* each part counts its own records with its own ids */
                int ns = 0;
                for (int j = 0; j < count; j++)
                    if (nb[j].index >= lo[p] && nb[j].index < lo[p + 1]) sub[ns++] = nb[j];
                sum += side_count_paths(part, sub, ns, K, scratch);
                capped += side_count_paths(part, sub, ns, SIDE_MIN_PATHS, scratch);
            }
            EXPECT_MSG(sum >= want && sum <= want + (unsigned)(M - 1), "M %d: parts %u, whole %u", M, sum, want);
            EXPECT_MSG(side_estimate_readable(capped) == side_estimate_readable(sum), "M %d: capped %u, full %u", M,
                       capped, sum);
            exact += sum == want;
            over += sum > want;
        }
    }
    printf("    parts' path counts: %d equal the whole map's, %d one or more over (straddling paths)\n", exact, over);
    EXPECT(exact > 0 && over > 0);
    free(ph);
    free(whole);
    free(part);
}

/* Oracle: geometry of the shadow hint's filter (photon_sides.h, side_filter_shadow). The query
 * is on a wall facing -z (pinhole_room's red wall from inside). A photon on the roof's top
 * (normal +y) travelling down and toward the wall passes pm_filter_front but not this filter;
 * photons on the wall itself, or on a surface tilted 30 degrees from it, pass; one tilted 60
 * degrees does not; one travelling away from the wall (along -z) passes neither. */
TEST(render_sides_shadow_filter_keeps_to_the_surface) {
    float q[3] = {0, 0, -1}, pos[3] = {0, 0, 0}, pw[3] = {1, 1, 1};
    float roof[3] = {0, 1, 0}, wall[3] = {0, 0, -1};
    float t30[3] = {0, 0.5f, -0.8660254f}, t60[3] = {0, 0.8660254f, -0.5f};
    float down_in[3] = {0.06f, -0.99f, 0.13f}, away[3] = {0, 0, -1};
    pm_photon p;
    pm_photon_init(&p, pos, pw, down_in, roof, PM_KIND_DIRECT);
    EXPECT(pm_filter_front(q, &p, 0) && !side_filter_shadow(q, &p, 0));
    pm_photon_init(&p, pos, pw, down_in, wall, PM_KIND_DIRECT);
    EXPECT(side_filter_shadow(q, &p, 0));
    pm_photon_init(&p, pos, pw, down_in, t30, PM_KIND_SHADOW);
    EXPECT(side_filter_shadow(q, &p, 0));
    pm_photon_init(&p, pos, pw, down_in, t60, PM_KIND_SHADOW);
    EXPECT(!side_filter_shadow(q, &p, 0));
    pm_photon_init(&p, pos, pw, away, wall, PM_KIND_DIRECT);
    EXPECT(!pm_filter_front(q, &p, 0) && !side_filter_shadow(q, &p, 0));
}

/* Oracle: the readable rule's definition, end to end through side_cache_build and the lookup.
 * The floor of SIDES_SCENE left of its tall wall holds 40 indirect photons from 4 paths (their
 * DIRECT first records lie right of the wall); right of it, 300 paths of a DIRECT and an
 * INDIRECT record each, and past the low wall 200 paths that stored one DIRECT record each
 * (an open ground under the sun: their estimates hold direct photons only). With k = 40 every
 * estimate left of the wall has 40 photons from 4 paths: with the map's path ids none is
 * readable (a lookup there finds nothing and side_cache.sparse counts them), without ids
 * (NULL: each photon a path) they all are; elsewhere lookups find a record either way (the
 * direct-only estimates too: each photon is a path of its own). A lookup can miss for other
 * reasons (no candidate's own radius covers it), so "find" means 45 or more of 50. */
TEST(render_sides_sparse_by_distinct_paths) {
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, SIDES_SCENE, &e) == 0, "%s", e.msg);
    const size_t n = 4 * 11 + 300 * 2 + 200;
    float pw[3] = {1, 1, 1}, d[3] = {0, 0, -1}, up[3] = {0, 0, 1};
    pm_test_rng r = {31};
    for (int use_paths = 1; use_paths >= 0; use_paths--) {
        photon_maps m;
        memset(&m, 0, sizeof m);
        m.global = calloc(n, sizeof *m.global);
        m.nglobal = n;
        ASSERT(m.global);
        size_t at = 0;
        for (int p = 0; p < 4; p++) { /* left: 4 paths of 10 stores, first hits on the right */
            float first[3] = {(float)(0.5 + pm_test_unit(&r)), (float)(-1.8 + 1.6 * pm_test_unit(&r)), 0};
            pm_photon_init(&m.global[at++], first, pw, d, up, PM_KIND_DIRECT);
            for (int j = 0; j < 10; j++) {
                float pos[3] = {(float)(-1.8 + 1.6 * pm_test_unit(&r)), (float)(-1.8 + 1.6 * pm_test_unit(&r)), 0};
                pm_photon_init(&m.global[at++], pos, pw, d, up, PM_KIND_INDIRECT);
            }
        }
        for (int p = 0; p < 300; p++) /* right: 300 paths */
            for (int j = 0; j < 2; j++) {
                float pos[3] = {(float)(0.2 + 1.6 * pm_test_unit(&r)), (float)(-1.8 + 1.6 * pm_test_unit(&r)), 0};
                pm_photon_init(&m.global[at++], pos, pw, d, up, j ? PM_KIND_INDIRECT : PM_KIND_DIRECT);
            }
        for (int p = 0; p < 200; p++) { /* past the low wall: direct photons only */
            float pos[3] = {(float)(0.2 + 1.6 * pm_test_unit(&r)), (float)(0.7 + 1.1 * pm_test_unit(&r)), 0};
            pm_photon_init(&m.global[at++], pos, pw, d, up, PM_KIND_DIRECT);
        }
        ASSERT(at == n);
        pm_kdtree *t;
        char err[256];
        ASSERT_EQ_INT(photon_tree_build_global(&t, &m, 8, err, sizeof err), 0);
        side_cache c;
        ASSERT_EQ_INT(side_cache_build(&c, &s, t, pm_kdtree_records(t), use_paths ? m.global_path : NULL, n, 40,
                                       16.0f, err, sizeof err),
                      0);
        int left = 0, right = 0, direct = 0;
        for (int qi = 0; qi < 50; qi++) {
            float e3[3];
            vec3 yl = v3(-1.6 + 1.2 * pm_test_unit(&r), -1.6 + 1.2 * pm_test_unit(&r), 0);
            vec3 yr = v3(0.4 + 1.2 * pm_test_unit(&r), -1.6 + 1.2 * pm_test_unit(&r), 0);
            vec3 yd = v3(0.4 + 1.2 * pm_test_unit(&r), 0.9 + 0.7 * pm_test_unit(&r), 0);
            left += side_cache_lookup(&c, &s, yl, v3(0, 0, 1), 16.0f, e3);
            right += side_cache_lookup(&c, &s, yr, v3(0, 0, 1), 16.0f, e3);
            direct += side_cache_lookup(&c, &s, yd, v3(0, 0, 1), 16.0f, e3);
        }
        printf("    %s path ids: %zu of %zu estimates too sparse to read; lookups found left %d, right %d, "
               "direct-only %d of 50\n",
               use_paths ? "with" : "without", c.sparse, c.n, left, right, direct);
        if (use_paths)
            EXPECT_MSG(left == 0 && c.sparse > 0, "left of the wall %d lookups read estimates of 4 paths", left);
        else
            EXPECT_MSG(left >= 45 && c.sparse == 0, "without ids: left %d, sparse %zu", left, c.sparse);
        EXPECT_MSG(right >= 45 && direct >= 45, "right of the wall: %d of 50, direct-only: %d of 50", right, direct);
        side_cache_free(&c);
        pm_kdtree_free(t);
        photon_maps_free(&m);
    }
    scene_free(&s);
}

/* Oracle: side_precomp_neighbours (photon_sides.h) written out by brute force: every record
 * that pm_filter_front accepts (travelling against the query's normal) with dist2 < max_dist2,
 * sorted by (dist2, index) as the kd-tree's ties rule; the first k, with a wall if one of them
 * at a distance > 0 is not side_visible_h from the query; after a wall the first SIDE_WIDEN x k
 * of them, the visible ones kept in order until k are; reach2 the SIDE_WIDEN x k-th one's
 * dist2 when fewer than k were kept and all SIDE_WIDEN x k were examined, else max_dist2; and
 * the visibility rays of each search. The records: the floor of the sides scene (-0.5..0.5 by
 * -1..1, none in a strip right of the tall wall), 80% travelling down (so accepted), 20% up
 * (refused), in tree order;
 * the queries are records (as side_cache_build asks them, with their own free heights) and
 * random floor points. Also: the walls decide some estimates, and some come short of k. */
TEST(render_sides_precomp_neighbours_match_brute_force) {
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, SIDES_SCENE, &e) == 0, "%s", e.msg);
    const size_t m = PM_TEST_SANITIZED ? 1500 : 3000;
    const int queries = PM_TEST_SANITIZED ? 300 : 1500;
    const float max_dist2 = 0.02f;
    enum { K = 12 };
    const unsigned k = K;
    pm_photon *recs = malloc(sizeof *recs * m);
    float *hf = malloc(sizeof *hf * m);
    sc_cand *cs = malloc(sizeof *cs * m);
    pm_neighbor *nb = malloc(sizeof *nb * SIDE_WIDEN * k);
    uint32_t *perm = malloc(sizeof *perm * m);
    ASSERT(recs && hf && cs && nb && perm);
    pm_test_rng r = {777};
    for (size_t i = 0; i < m; i++) {
        float pos[3] = {(float)(pm_test_unit(&r) - 0.5), (float)(2 * pm_test_unit(&r) - 1), 0};
        if (pos[0] > 0 && pos[0] < 0.12f) pos[0] += 0.12f; /* a strip without photons right of the wall */
        float up[3] = {0, 0, 1}, down[3] = {0, 0, -1}, p[3] = {1, 1, 1};
        pm_photon_init(&recs[i], pos, p, pm_test_unit(&r) < 0.8 ? down : up, up, PM_KIND_INDIRECT);
    }
    pm_kdtree *t = NULL;
    pm_kdtree_config kc = pm_kdtree_photon_config(8);
    ASSERT_EQ_INT(pm_kdtree_build(&t, recs, m, &kc, perm), 0); /* recs now in tree order */
    side_free_heights(&s, recs, m, max_dist2, hf);
    float nf[3] = {0, 0, 1};
    int walls = 0, short_of_k = 0, bad = 0;
    for (int qi = 0; qi < queries; qi++) {
        float x[3];
        double hx;
        if (qi % 2 == 0) { /* a record, as side_cache_build asks */
            size_t j = (size_t)(pm_test_unit(&r) * (double)m);
            memcpy(x, recs[j].pos, sizeof x);
            hx = hf[j];
        } else {
            x[0] = (float)(0.3 * pm_test_unit(&r) - 0.15), x[1] = (float)(2 * pm_test_unit(&r) - 1), x[2] = 0;
            hx = side_free_height(&s, v3(x[0], x[1], x[2]), v3(0, 0, 1), 0.25 * sqrt((double)max_dist2));
        }
        size_t nc = 0;
        for (uint32_t i = 0; i < m; i++) {
            if (!pm_filter_front(nf, &recs[i], i)) continue;
            float d[3] = {recs[i].pos[0] - x[0], recs[i].pos[1] - x[1], recs[i].pos[2] - x[2]};
            float d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
            if (d2 < max_dist2) cs[nc].d2 = d2, cs[nc].i = i, nc++;
        }
        qsort(cs, nc, sizeof *cs, sc_cmp);
        for (size_t a = 1; a < nc; a++) /* equal dist2: the smaller index first, as the kd-tree */
            for (size_t b = a; b > 0 && cs[b - 1].d2 == cs[b].d2 && cs[b - 1].i > cs[b].i; b--) {
                sc_cand tmp = cs[b];
                cs[b] = cs[b - 1];
                cs[b - 1] = tmp;
            }
        unsigned long long rays_want[2] = {0, 0}, rays_got[2] = {0, 0};
        int wall_want = 0;
        uint32_t want[SIDE_WIDEN * K];
        unsigned nwant = 0;
        float reach_want = max_dist2;
        vec3 xv = v3(x[0], x[1], x[2]), up = v3(0, 0, 1);
        for (size_t a = 0; a < nc && a < k; a++) {
            want[nwant++] = cs[a].i;
            if (wall_want || cs[a].d2 == 0) continue;
            rays_want[0]++;
            const float *q = recs[cs[a].i].pos;
            wall_want = !side_visible_h(&s, xv, up, hx, v3(q[0], q[1], q[2]), up, hf[cs[a].i]);
        }
        if (wall_want) {
            nwant = 0;
            size_t a = 0;
            for (; a < nc && a < SIDE_WIDEN * k && nwant < k; a++) {
                int vis = 1;
                if (cs[a].d2 > 0) {
                    rays_want[1]++;
                    const float *q = recs[cs[a].i].pos;
                    vis = side_visible_h(&s, xv, up, hx, v3(q[0], q[1], q[2]), up, hf[cs[a].i]);
                }
                if (vis) want[nwant++] = cs[a].i;
            }
            if (nwant < k && nc >= SIDE_WIDEN * k) reach_want = cs[SIDE_WIDEN * k - 1].d2;
        }
        int wall_got = -1;
        float reach_got = -1;
        int got = side_precomp_neighbours(&s, t, recs, hf, x, nf, hx, k, max_dist2, nb, &wall_got, &reach_got,
                                          rays_got);
        int same = got == (int)nwant && wall_got == wall_want && reach_got == reach_want &&
                   rays_got[0] <= rays_want[0] && rays_got[1] <= rays_want[1]; /* rays: only those traced */
        for (int a = 0; same && a < got; a++) same = nb[a].index == want[a];
        if (!same && bad++ < 5)
            EXPECT_MSG(0, "query %d at (%g, %g): %d neighbours (wall %d, reach2 %g, rays %llu+%llu), brute force %u "
                       "(wall %d, reach2 %g, rays %llu+%llu)", qi, x[0], x[1], got, wall_got, reach_got, rays_got[0],
                       rays_got[1], nwant, wall_want, reach_want, rays_want[0], rays_want[1]);
        walls += wall_want;
        short_of_k += nwant < k;
    }
    printf("precomputed estimates' neighbours: %d of %d queries met a wall, %d came short of k = %u\n", walls,
           queries, short_of_k, k);
    EXPECT(bad == 0 && walls > queries / 20 && short_of_k > 0);
    /* No tree (a distributed rank without photons): nothing, no wall, the whole radius. */
    int w0 = -1;
    float r0 = 0;
    EXPECT(side_precomp_neighbours(&s, NULL, recs, hf, nf, nf, 0, k, max_dist2, nb, &w0, &r0, NULL) == 0 && w0 == 0 &&
           r0 == max_dist2);
    pm_kdtree_free(t);
    free(perm);
    free(nb);
    free(cs);
    free(hf);
    free(recs);
    scene_free(&s);
}
