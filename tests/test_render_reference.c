/* test_render_reference.c: the path tracer says what it cannot render (render/scene/delta_lit.h).
 *
 * Oracles: the photon tracer's caustic map (independent of delta_lit.c: its photons are the
 * L S+ D paths themselves, stored where they land, each landing point assigned to its object
 * by the scene's analytic geometry); hand-made scenes whose answer is known by construction
 * (a mirror behind a wall is not lit, the same mirror in the open is); and the documented
 * warning text of `render --mode path`.
 */
#define _GNU_SOURCE
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "render/scene/delta_lit.h"
#include "render/photons/photon_maps.h"
#include "render/photons/photon_trace.h"
#include "render/load/scene_load.h"
#include "render/scene/scene.h"
#include "test.h"
#include "test_render_run.h"

static const char *shipped(const char *name) {
    static char p[1024];
    snprintf(p, sizeof p, "%s/data/scenes/%s.json", pm_test_source_dir(), name);
    return p;
}

static int path_warning(const char *name, const char *mode, char *out, size_t cap) {
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "timeout 120 '%s/render' '%s' --mode %s --width 16 --height 16 --spp 1 "
             "--quiet -o o.png --pm global_photons=2000 --pm caustic_photons=1000",
             pm_test_build_dir(), shipped(name), mode);
    return rt_run(cmd, out, cap);
}

/* `render --mode path` on sun_spheres names the three specular spheres (chrome, glass,
 * Fresnel plastic: $.objects[2..4]) and not the clay sphere or the ground, which the
 * caustics fall on; --mode pm, which renders those paths, says nothing; and scenes whose
 * only lights are area lights (cornell_box, and cornell_spheres with its mirror and glass),
 * or whose point light sees no specular surface (cornell_point), get no warning. */
TEST(render_reference_warns_on_delta_lit_specular) {
    static char out[1 << 16];
    int rc = path_warning("sun_spheres", "path", out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    const char *want[] = {"render: warning: ", "sun_spheres.json: path tracing cannot render light that "
                          "point or directional lights send through specular surfaces onto diffuse ones (L S+ D)",
                          "lit straight by a point or directional light: $.objects[2] (\"chrome\"), "
                          "$.objects[3] (\"glass\"), $.objects[4] (\"plastic\"); their caustics fall on "
                          "$.objects[0] (\"ground\")", "use --mode pm"};
    for (size_t i = 0; i < sizeof want / sizeof *want; i++)
        EXPECT_MSG(strstr(out, want[i]), "no \"%s\" in %s", want[i], out);
    EXPECT_MSG(!strstr(out, "straight by a point or directional light: $.objects[1]") &&
               !strstr(out, "$.objects[0] (\"ground\"), $.objects[2]"), "%s", out);
    rc = path_warning("sun_spheres", "pm", out, sizeof out);
    EXPECT_MSG(rc == 0 && !strstr(out, "cannot render"), "pm mode: exit %d: %s", rc, out);
    const char *quiet[] = {"cornell_box", "cornell_spheres", "cornell_point"};
    for (int i = 0; i < 3; i++) {
        rc = path_warning(quiet[i], "path", out, sizeof out);
        EXPECT_MSG(rc == 0 && !strstr(out, "warning"), "%s: exit %d: %s", quiet[i], rc, out);
    }
}

/* Oracle: the caustic map of sun_spheres traced by photon_trace (the L S+ D paths from the
 * sun, stored on the diffuse surface where each lands). Each landing point belongs to the
 * ground (y = 0), the clay sphere or the plastic sphere (|p - c| = r, to 1e-3). Every object
 * that holds at least 1% of the caustic photons must be in the footprint, and every object
 * of the footprint must hold at least one of 20000 caustic photons; the lit objects are
 * exactly the three specular spheres. */
TEST(render_reference_footprint_matches_the_caustic_map) {
    scene s;
    json_err e;
    ASSERT_MSG(scene_load(&s, shipped("sun_spheres"), &e) == 0, "%s", e.msg);
    unsigned char *flags = NULL;
    int n = delta_lit_find(&s, &flags);
    ASSERT_EQ_INT(n, 3);
    ASSERT_EQ_INT(s.nobj, 5);
    const unsigned char lit[5] = {0, 0, 1, 1, 1};
    for (int o = 0; o < 5; o++)
        EXPECT_MSG(((flags[o] & DELTA_LIT) != 0) == lit[o], "object %d: flags %d", o, flags[o]);

    trace_opts o;
    trace_opts_init(&o, &s);
    o.caustic = 1;
    o.caustic_target = PM_TEST_SANITIZED ? 5000 : 20000;
    o.projection = 1;
    o.projection_cells = 64;
    o.max_emitted_factor = 64;
    o.quiet = 1;
    photon_maps m;
    char err[256];
    ASSERT_MSG(photon_trace(&s, &o, &m, err, sizeof err) == 0, "%s", err);
    ASSERT(m.ncaustic > 0);
    /* Objects: 0 ground, 1 clay (-2.2, 1, 0) r 1, 4 plastic (0.2, 0.5, -1.3) r 0.5. */
    const double c[5][4] = {{0, 0, 0, 0}, {-2.2, 1, 0, 1}, {0, 1, 1.5, 1}, {2.2, 1, 0, 1}, {0.2, 0.5, -1.3, 0.5}};
    size_t count[5] = {0}, other = 0;
    for (size_t i = 0; i < m.ncaustic; i++) {
        const float *p = m.caustic[i].pos;
        int where = -1;
        if (fabs(p[1]) < 1e-3)
            where = 0;
        else
            for (int k = 1; k < 5; k++) {
                double dx = p[0] - c[k][0], dy = p[1] - c[k][1], dz = p[2] - c[k][2];
                if (fabs(sqrt(dx * dx + dy * dy + dz * dz) - c[k][3]) < 1e-3) where = k;
            }
        if (where < 0)
            other++;
        else
            count[where]++;
    }
    EXPECT_MSG(other == 0, "%zu caustic photons on no known object", other);
    for (int k = 0; k < 5; k++) {
        double share = (double)count[k] / (double)m.ncaustic;
        printf("    object %d: %5.2f%% of %zu caustic photons, footprint %s\n", k, 100 * share,
               m.ncaustic, flags[k] & DELTA_FOOTPRINT ? "yes" : "no");
        if (share >= 0.01) EXPECT_MSG(flags[k] & DELTA_FOOTPRINT, "object %d holds %.2f%% of the caustic", k, 100 * share);
        if (flags[k] & DELTA_FOOTPRINT) EXPECT_MSG(count[k] > 0, "object %d in the footprint has no caustic photon", k);
    }
    photon_maps_free(&m);
    free(flags);
    scene_free(&s);
}

static int find_text(const char *text, unsigned char **flags, int *nobj) {
    scene s;
    json_err e;
    if (scene_load_text(&s, text, &e) != 0) {
        fprintf(stderr, "    %s\n", e.msg);
        return -100;
    }
    int n = delta_lit_find(&s, flags);
    *nobj = s.nobj;
    scene_free(&s);
    return n;
}

/* By construction: a point light over a floor, a mirror quad beside it tilted to send its
 * light down to the floor (its normal (-3, -1, 0) / sqrt(10)). With an opaque wall
 * between the light and the mirror the mirror is not lit (no warning); without the wall it
 * is, and its reflection lands on the floor (footprint: the floor). A glass sphere under a
 * directional light with a closed lid above it: not lit. */
TEST(render_reference_visibility_by_construction) {
    const char *fmt =
        "{\"camera\": {\"eye\": [0, 2, -6], \"look_at\": [0, 0, 0], \"fov_deg\": 50, \"width\": 8, "
        "\"height\": 8},"
        " \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
        " \"m\": {\"type\": \"mirror\", \"reflectance\": 0.9}},"
        " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-5, 0, -5], [-5, 0, 5], [5, 0, 5], [5, 0, -5]],"
        " \"material\": \"w\"},"
        " {\"type\": \"quad\", \"vertices\": [[2.5, 0.5, -1], [2.5, 0.5, 1], [2, 2, 1], [2, 2, -1]], \"material\": \"m\"}"
        "%s],"
        " \"lights\": [{\"type\": \"point\", \"position\": [0, 1.5, 0], \"intensity\": 5}]}";
    const char *wall = ", {\"type\": \"quad\", \"vertices\": [[1, 0, -3], [1, 0, 3], [1, 4, 3], [1, 4, -3]], "
                       "\"material\": \"w\"}";
    char text[4096];
    unsigned char *flags = NULL;
    int nobj = 0;
    snprintf(text, sizeof text, fmt, wall);
    int n = find_text(text, &flags, &nobj);
    EXPECT_MSG(n == 0, "mirror behind a wall: %d lit", n);
    free(flags);
    flags = NULL;
    snprintf(text, sizeof text, fmt, "");
    n = find_text(text, &flags, &nobj);
    EXPECT_MSG(n == 1 && nobj == 2 && (flags[1] & DELTA_LIT) && (flags[0] & DELTA_FOOTPRINT) &&
               !(flags[0] & DELTA_LIT), "open mirror: n %d, flags %d %d", n, flags ? flags[0] : -1,
               flags ? flags[1] : -1);
    free(flags);
    flags = NULL;
    const char *lid =
        "{\"camera\": {\"eye\": [0, 2, -6], \"look_at\": [0, 0, 0], \"fov_deg\": 50, \"width\": 8, "
        "\"height\": 8},"
        " \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
        " \"g\": {\"type\": \"dielectric\", \"ior\": 1.5}},"
        " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-5, 0, -5], [-5, 0, 5], [5, 0, 5], [5, 0, -5]],"
        " \"material\": \"w\"},"
        " {\"type\": \"sphere\", \"center\": [0, 1, 0], \"radius\": 1, \"material\": \"g\"},"
        " {\"type\": \"quad\", \"vertices\": [[-50, 3, -50], [50, 3, -50], [50, 3, 50], [-50, 3, 50]], \"material\": \"w\"}],"
        " \"lights\": [{\"type\": \"directional\", \"direction\": [0.1, -1, 0.2], \"irradiance\": 2}]}";
    n = find_text(lid, &flags, &nobj);
    EXPECT_MSG(n == 0, "glass under a lid: %d lit", n);
    free(flags);
}

/* The scenes the tests and `make results` compare photon mapping with path tracing on
 * (tests/test_render_pm.c, test_render_hard.c and scripts/make-results.sh, and the scenes
 * of the pinhole and shelf tests) have nothing delta-lit, so those comparisons leave nothing
 * out. Of the shipped scenes, exactly sun_spheres and mirror_cage have delta-lit objects. */
TEST(render_reference_compared_scenes_are_complete) {
    const char *compared[] = {"cornell_spheres", "cornell_diffuse", "cornell_box", "furnace",
                              "partition_thin", "partition_thick", "pinhole_room", "pinhole_room_ports", "door_ajar", "sun_window", "lamp_shade",
                              "sun_window_fog", "shelf_glass",
                              "glass_hole", "water_caustic"};
    for (size_t i = 0; i < sizeof compared / sizeof *compared; i++) {
        scene s;
        json_err e;
        if (scene_load(&s, shipped(compared[i]), &e) != 0) {
            EXPECT_MSG(0, "%s: %s", compared[i], e.msg);
            continue;
        }
        unsigned char *flags = NULL;
        int n = delta_lit_find(&s, &flags);
        EXPECT_MSG(n == 0, "%s: %d delta-lit objects", compared[i], n);
        free(flags);
        scene_free(&s);
    }
    const char *lit[] = {"sun_spheres", "mirror_cage"};
    for (int i = 0; i < 2; i++) {
        scene s;
        json_err e;
        ASSERT_MSG(scene_load(&s, shipped(lit[i]), &e) == 0, "%s", e.msg);
        unsigned char *flags = NULL;
        EXPECT_MSG(delta_lit_find(&s, &flags) > 0, "%s: nothing delta-lit", lit[i]);
        free(flags);
        scene_free(&s);
    }
}
