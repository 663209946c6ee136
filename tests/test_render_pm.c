/* test_render_pm.c: the renderer's photon mapping: the plan of effects, photon tracing
 * (thread independence, energy conservation, runaway scenes) and `render --mode pm` (skipped
 * work shows as zero, saved photon maps give the same image).
 *
 * Oracles, one per test (details above each): the physics of each shipped scene for its plan;
 * the one-thread maps for the two-thread maps (bit-identical); Phi (1 - rho^D) / (1 - rho),
 * D = max_depth + 1, for the power stored in a closed box, within 1% with 4 standard errors and the RGBE
 * rounding bound inside it; exact emitted counts for a light that faces nothing; zeros in
 * the statistics for skipped caustics; the traced maps for the saved files, and the render
 * that traced the maps for the one that loads them (bit-identical); a path-traced render of
 * the same scene for a small photon-mapped one (means of the image and of each wall).
 */
#include <dirent.h>
#include <fcntl.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "test.h"
#include "test_render_run.h"
#include "../photonmap/photon.h"
#include "../render/image/compare.h"
#include "../render/image/film.h"
#include "../render/photons/importance.h"
#include "../render/photons/photon_trace.h"
#include "../render/load/photon_settings.h"
#include "../render/photon_mapping/plan.h"
#include "../render/photons/projmap.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"
#include "../render/base/stats.h"

/* ---- helpers ------------------------------------------------------------------------------ */

static int write_file(const char *path, const char *text) {
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    fputs(text, f);
    return fclose(f);
}

/* The whole file in a malloc'd buffer (NUL-terminated), its size in *n; NULL if unreadable. */
static char *read_file(const char *path, size_t *n) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    size_t cap = 4096, len = 0, got;
    char *buf = malloc(cap + 1);
    while (buf && (got = fread(buf + len, 1, cap - len, f)) > 0) {
        len += got;
        if (len == cap) {
            char *nb = realloc(buf, 2 * cap + 1);
            if (!nb) {
                free(buf);
                buf = NULL;
                break;
            }
            buf = nb;
            cap *= 2;
        }
    }
    fclose(f);
    if (!buf) return NULL;
    buf[len] = 0;
    if (n) *n = len;
    return buf;
}

/* A counter from render's statistics: the number after "    NAME   " at the start of a line;
 * -1 if the line is absent. */
static long long stat_in(const char *out, const char *name) {
    size_t ln = strlen(name);
    for (const char *p = out; (p = strstr(p, name)) != NULL; p += ln) {
        if (p - out < 5 || strncmp(p - 5, "\n    ", 5) != 0 || p[ln] != ' ') continue;
        return strtoll(p + ln, NULL, 10);
    }
    return -1;
}

static int load_shipped(scene *s, const char *name, json_err *e) {
    char path[1024];
    snprintf(path, sizeof path, "%s/data/scenes/%s.json", pm_test_source_dir(), name);
    return scene_load(s, path, e);
}

/* ---- 1. the plan --------------------------------------------------------------------------- */

typedef struct expected_plan {
    const char *scene;
    int caustics, global, shadow, final_gather;
    /* what each "off" reason must say (a substring; "" when the item is on) */
    const char *why_caustics, *why_global, *why_shadow, *why_final_gather;
} expected_plan;

/* The plan each shipped scene needs, decided from its file:
 *   cornell_box      only Lambertian materials: no specular surface, so no caustics;
 *                    the walls interreflect (global); the area light and the two blocks
 *                    cast shadows on the floor (shadow photons); final gathering.
 *   cornell_spheres  the mirror and glass spheres are lit straight by the area light (L S D
 *                    caustics); walls interreflect; the spheres shadow the floor.
 *   cornell_diffuse  Lambert and Oren-Nayar only: no caustics; interreflection; the
 *                    spheres shadow the floor under the area light.
 *   cornell_point    a point light, no area light: shadow photons are for area lights only
 *                    (a point light needs one exact shadow ray); no specular surface;
 *                    the walls interreflect.
 *   sun_spheres      chrome, glass and Fresnel plastic lit by the sun: caustics; the
 *                    ground reflects onto the spheres: global; a directional light only:
 *                    no shadow photons.
 *   furnace          nothing specular, and its one light is the emitting sphere itself (a
 *                    sphere light, not triangles: no shadow photons). Half its radiance is
 *                    interreflection (L = Le + rho L): global map and final gather.
 *   cornell_rect, cornell_tungsten   the Cornell box with its blocks (Lambertian only).
 *   water_caustic    a water surface (glass) under the area light: caustics on the floor.
 *   partition_thin/thick  a Lambertian box cut in two, the light above: interreflection,
 *                    and the partition occludes the lower half (shadow photons).
 *   shelf_glass      the glass sphere stands under a shelf that hides it from the light:
 *                    no photon reaches it straight from the light, so no L S+ D path.
 *   pinhole_room     Lambertian rooms; the small room's roof occludes the light.
 *   pinhole_room_ports  the same scene with its hole declared as a photon port: the same plan.
 *   door_ajar        Lambertian rooms; the door between them, opened 15 degrees, occludes most
 *                    of the light.
 *   sun_window       Lambertian room lit by the sun (a directional light) through a window:
 *                    no specular surface; interreflection; a directional light: no shadow photons.
 *   lamp_shade       Lambertian room; the lamp inside a shade with a hole: the shade occludes
 *                    nearly all of the light (shadow photons as for door_ajar).
 *   sun_window_fog   sun_window filled with dust: shadow rays carry the transmittance.
 *   glass_hole       a glass sphere lit straight from the light only through a 10 x 10 hole
 *                    in a wall: caustics (the pilot aims photons at it and finds the hole).
 *   glass_enclosed   a white plate under water and a white sphere in a glass sphere, lit
 *                    through them: caustics; the walls interreflect; the glass shadows.
 *   mirror_cage      a point light inside a closed mirror sphere: no photon ever reaches a
 *                    diffuse surface, so nothing is planned (and no pass is run).
 *   black_box        every surface but the lamp has reflectance 0: no surface stores photons;
 *                    that, not "nothing occludes", is the reason shadow photons are off.
 * A new scene file without a row here fails the test. */
static const expected_plan k_plans[] = {
    {"cornell_box", 0, 1, 0, 1, "no specular surface", "", "the hint costs more than the shadow rays it saves", ""},
    {"cornell_spheres", 1, 1, 0, 1, "", "", "the hint costs more than the shadow rays it saves", ""},
    {"cornell_diffuse", 0, 1, 0, 1, "no specular surface", "", "the hint costs more than the shadow rays it saves", ""},
    {"cornell_point", 0, 1, 0, 1, "no specular surface", "", "no area light", ""},
    {"sun_spheres", 1, 1, 0, 1, "", "", "no area light", ""},
    {"furnace", 0, 1, 0, 1, "no specular surface", "", "no area light", ""},
    {"cornell_rect", 0, 1, 0, 1, "no specular surface", "", "the hint costs more than the shadow rays it saves", ""},
    {"cornell_tungsten", 0, 1, 0, 1, "no specular surface", "", "the hint costs more than the shadow rays it saves", ""},
    {"water_caustic", 1, 1, 0, 1, "", "", "the hint costs more than the shadow rays it saves", ""},
    {"partition_thin", 0, 1, 0, 1, "no specular surface", "", "the hint costs more than the shadow rays it saves", ""},
    {"partition_thick", 0, 1, 0, 1, "no specular surface", "", "the hint costs more than the shadow rays it saves", ""},
    {"shelf_glass", 0, 1, 0, 1, "leads to a diffuse one: 0 of", "", "the hint costs more than the shadow rays it saves", ""},
    {"pinhole_room", 0, 1, 0, 1, "no specular surface", "", "the hint costs more than the shadow rays it saves", ""},
    {"pinhole_room_ports", 0, 1, 0, 1, "no specular surface", "", "the hint costs more than the shadow rays it saves", ""},
    {"door_ajar", 0, 1, 0, 1, "no specular surface", "", "the hint costs more than the shadow rays it saves", ""},
    {"sun_window", 0, 1, 0, 1, "no specular surface", "", "no area light", ""},
    {"lamp_shade", 0, 1, 0, 1, "no specular surface", "", "the hint costs more than the shadow rays it saves", ""},
    {"glass_hole", 1, 1, 0, 1, "", "", "the hint costs more than the shadow rays it saves", ""},
    {"glass_enclosed", 1, 1, 0, 1, "", "", "the hint costs more than the shadow rays it saves", ""},
    {"mirror_cage", 0, 0, 0, 0, "leads to a diffuse one: 0 of 8192", "no surface the lights reach stores photons, 0 of 8192", "no area light", "no global map"},
    {"black_box", 0, 0, 0, 0, "no specular surface", "no surface the lights reach stores photons", "no surface the lights reach stores photons", "no global map"},
    /* Media: shadow rays carry the transmittance there, so no shadow photons (plan.h). */
    {"cornell_fog", 0, 1, 0, 1, "no specular surface", "", "shadow rays carry the transmittance", ""},
    {"volumetric_caustic", 1, 1, 0, 1, "", "", "shadow rays carry the transmittance", ""},
    {"glass_of_smoke", 1, 1, 0, 1, "", "", "shadow rays carry the transmittance", ""},
    /* Media bounded by interfaces: the same physics; the Tungsten room's glass ball
     * focuses the lamp through the gas onto the floor (L S+ D). */
    {"sun_window_fog", 0, 1, 0, 1, "no specular surface", "", "shadow rays carry the transmittance", ""},
    {"gas_room", 0, 1, 0, 1, "no specular surface", "", "shadow rays carry the transmittance", ""},
    {"gas_room_tungsten", 1, 1, 0, 1, "", "", "shadow rays carry the transmittance", ""},
};

static void check_item(const char *scene_name, const char *what, const plan_item *it, int want,
                       const char *why) {
    EXPECT_MSG(it->on == want, "%s: %s is %s, expected %s (reason: %s)", scene_name, what,
               it->on ? "on" : "off", want ? "on" : "off", it->reason);
    EXPECT_MSG(it->reason[0] != 0, "%s: %s has no reason", scene_name, what);
    if (!it->on && why[0])
        EXPECT_MSG(strstr(it->reason, why) != NULL, "%s: %s off for \"%s\", expected \"%s\"",
                   scene_name, what, it->reason, why);
}

/* Oracle: the physics of each scene (table above), exactly, and the reason for each item
 * that is off; the plan is the same when made twice (fixed probe streams), and preview mode
 * turns final gathering off. Every .json file in data/scenes must have a row, and every row
 * a file. */
TEST(render_pm_plan_shipped_scenes) {
    char dir[1024];
    snprintf(dir, sizeof dir, "%s/data/scenes", pm_test_source_dir());
    DIR *d = opendir(dir);
    ASSERT_MSG(d != NULL, "cannot open %s", dir);
    int seen[sizeof k_plans / sizeof k_plans[0]] = {0};
    int nfiles = 0;
    struct dirent *de;
    while ((de = readdir(d)) != NULL) {
        size_t len = strlen(de->d_name);
        if (len < 6 || strcmp(de->d_name + len - 5, ".json") != 0) continue;
        char name[256];
        snprintf(name, sizeof name, "%.*s", (int)(len - 5), de->d_name);
        nfiles++;
        const expected_plan *ex = NULL;
        for (size_t k = 0; k < sizeof k_plans / sizeof k_plans[0]; k++)
            if (strcmp(k_plans[k].scene, name) == 0) {
                ex = &k_plans[k];
                seen[k] = 1;
            }
        EXPECT_MSG(ex != NULL,
                   "data/scenes/%s has no expected plan: add a row to k_plans in "
                   "tests/test_render_pm.c (decided from the scene's physics)",
                   de->d_name);
        if (!ex) continue;
        scene s;
        json_err e;
        int rc = load_shipped(&s, name, &e);
        EXPECT_MSG(rc == 0, "%s: %s", name, e.msg);
        if (rc != 0) continue;
        photon_settings c;
        rc = photon_settings_parse(&c, s.photon_mapping, &e);
        EXPECT_MSG(rc == 0, "%s: %s", name, e.msg);
        render_plan p, p2, pv;
        EXPECT_EQ_INT(plan_make(&s, &c, 0, &p, NULL, 0), 0);
        EXPECT_EQ_INT(plan_make(&s, &c, 0, &p2, NULL, 0), 0);
        EXPECT_EQ_INT(plan_make(&s, &c, 1, &pv, NULL, 0), 0);
        check_item(name, "caustics", &p.caustics, ex->caustics, ex->why_caustics);
        check_item(name, "global", &p.global, ex->global, ex->why_global);
        check_item(name, "shadow", &p.shadow, ex->shadow, ex->why_shadow);
        check_item(name, "final gather", &p.final_gather, ex->final_gather, ex->why_final_gather);
        /* The importance tables are compared by content: the plans own different copies. */
        EXPECT_MSG((p.imp == NULL) == (p2.imp == NULL) && (p.imp == NULL) == !p.emission.on,
                   "%s: importance table %p/%p with emission %s", name, (void *)p.imp, (void *)p2.imp,
                   p.emission.reason);
        if (p.imp && p2.imp)
            EXPECT_MSG(p.imp->lv[0].ncells == p2.imp->lv[0].ncells &&
                           memcmp(p.imp->lv[0].cdf, p2.imp->lv[0].cdf,
                                  (p.imp->lv[0].ncells + 1) * sizeof(double)) == 0,
                       "%s: the importance table changed between two calls", name);
        /* The owned tables (importance, pilot photons, light guide) are other copies. */
        struct importance *keep[3] = {p.imp, p2.imp, pv.imp};
        pilot_photons *kp[3] = {p.pilot, p2.pilot, pv.pilot};
        struct guide *kg[3] = {p.guide, p2.guide, pv.guide};
        EXPECT_MSG((p.pilot == NULL) == (p2.pilot == NULL) && (p.guide == NULL) == (p2.guide == NULL),
                   "%s: pilot photons %p/%p, light guide %p/%p", name, (void *)p.pilot, (void *)p2.pilot,
                   (void *)p.guide, (void *)p2.guide);
        p.imp = p2.imp = pv.imp = NULL;
        p.pilot = p2.pilot = pv.pilot = NULL;
        p.guide = p2.guide = pv.guide = NULL;
        EXPECT_MSG(memcmp(&p, &p2, sizeof p) == 0, "%s: the plan changed between two calls", name);
        p.imp = keep[0], p2.imp = keep[1], pv.imp = keep[2];
        p.pilot = kp[0], p2.pilot = kp[1], pv.pilot = kp[2];
        p.guide = kg[0], p2.guide = kg[1], pv.guide = kg[2];
        plan_free(&p);
        plan_free(&p2);
        plan_free(&pv);
        EXPECT_MSG(!pv.final_gather.on && strstr(pv.final_gather.reason, "preview"),
                   "%s: preview final gather: %s", name, pv.final_gather.reason);
        EXPECT_MSG(pv.caustics.on == p.caustics.on && pv.global.on == p.global.on &&
                       pv.shadow.on == p.shadow.on,
                   "%s: preview changed the maps", name);
        scene_free(&s);
    }
    closedir(d);
    EXPECT_MSG(nfiles >= 6, "only %d scene files in %s", nfiles, dir);
    for (size_t k = 0; k < sizeof k_plans / sizeof k_plans[0]; k++)
        EXPECT_MSG(seen[k], "expected plan for %s, but data/scenes/%s.json is missing",
                   k_plans[k].scene, k_plans[k].scene);
}

#define CAM8 "\"camera\": {\"eye\": [0,2,-9], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 8, \"height\": 8, \"spp\": 1}"
/* A closed cube of two triangles per face, corners +-H around the origin. */
#define CUBE_MESH(H, MAT)                                                                      \
    "{\"type\": \"mesh\", \"vertices\": [[-" H ",-" H ",-" H "],[" H ",-" H ",-" H "],[" H "," H ",-" H "],[-" H "," H ",-" H "]," \
    "[-" H ",-" H "," H "],[" H ",-" H "," H "],[" H "," H "," H "],[-" H "," H "," H "]],"       \
    "\"triangles\": [[0,2,1],[0,3,2],[4,5,6],[4,6,7],[0,1,5],[0,5,4],[3,7,6],[3,6,2],[0,4,7],[0,7,3],[1,2,6],[1,6,5]], " \
    "\"material\": \"" MAT "\"}"

typedef struct physics_case {
    const char *name, *json;
    int caustics, global, shadow;
} physics_case;

/* Oracle: small scenes whose needs are plain from their geometry (the cases plan.c names):
 *   sphere_sun      one diffuse sphere under the sun: nothing to interreflect with (the unlit
 *                   inside of the sphere must not count), no specular, no area light;
 *   lit_inside      a point light inside a diffuse sphere: the inside interreflects;
 *   hidden_glass    a glass sphere inside a closed diffuse box, the sun outside: the light
 *                   never reaches it, so no caustics, and the lit outside of the box has
 *                   nothing to reflect onto;
 *   glass_lamp      a point light inside a glass sphere over a floor and a wall: the light
 *                   reaches the diffuse surfaces only through glass (caustics), and the
 *                   floor lights the wall (global, found through the specular surface);
 *   open_plane      an area light over a plane: no occluder, nothing to interreflect;
 *   plane_sphere    the same with a diffuse sphere between: shadows, and the plane and
 *                   sphere light each other; shadow photons stay off all the same (their hint
 *                   costs more than the shadow rays it saves: render_pm_plan_shadow_hint). */
TEST(render_pm_plan_physics_cases) {
    static const physics_case cases[] = {
        {"sphere_sun",
         "{" CAM8 ", \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
         "\"objects\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 1, \"material\": \"w\"}],"
         "\"lights\": [{\"type\": \"directional\", \"direction\": [0.2,-1,0.1], \"irradiance\": 1}]}",
         0, 0, 0},
        {"lit_inside",
         "{" CAM8 ", \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
         "\"objects\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 3, \"material\": \"w\"}],"
         "\"lights\": [{\"type\": \"point\", \"position\": [0.5,0.2,0], \"power\": 10}]}",
         0, 1, 0},
        {"hidden_glass",
         "{" CAM8 ", \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
         "\"g\": {\"type\": \"dielectric\", \"ior\": 1.5}},"
         "\"objects\": [" CUBE_MESH("2", "w") ", {\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 1, \"material\": \"g\"}],"
         "\"lights\": [{\"type\": \"directional\", \"direction\": [0.2,-1,0.1], \"irradiance\": 1}]}",
         0, 0, 0},
        {"glass_lamp",
         "{" CAM8 ", \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
         "\"g\": {\"type\": \"dielectric\", \"ior\": 1.5}},"
         "\"objects\": [{\"type\": \"quad\", \"vertices\": [[-5,0,-5],[-5,0,5],[5,0,5],[5,0,-5]], \"material\": \"w\"},"
         "{\"type\": \"quad\", \"vertices\": [[-5,0,5],[-5,5,5],[5,5,5],[5,0,5]], \"material\": \"w\"},"
         "{\"type\": \"sphere\", \"center\": [0,2,0], \"radius\": 0.5, \"material\": \"g\"}],"
         "\"lights\": [{\"type\": \"point\", \"position\": [0,2,0], \"power\": 10}]}",
         1, 1, 0},
        {"open_plane",
         "{" CAM8 ", \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
         "\"e\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 1}},"
         "\"objects\": [{\"type\": \"quad\", \"vertices\": [[-5,0,-5],[-5,0,5],[5,0,5],[5,0,-5]], \"material\": \"w\"},"
         "{\"type\": \"quad\", \"vertices\": [[-1,3,-1],[1,3,-1],[1,3,1],[-1,3,1]], \"material\": \"e\"}]}",
         0, 0, 0},
        {"plane_sphere",
         "{" CAM8 ", \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
         "\"e\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 1}},"
         "\"objects\": [{\"type\": \"quad\", \"vertices\": [[-5,0,-5],[-5,0,5],[5,0,5],[5,0,-5]], \"material\": \"w\"},"
         "{\"type\": \"sphere\", \"center\": [0,1,0], \"radius\": 0.6, \"material\": \"w\"},"
         "{\"type\": \"quad\", \"vertices\": [[-1,3,-1],[1,3,-1],[1,3,1],[-1,3,1]], \"material\": \"e\"}]}",
         0, 1, 0},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const physics_case *pc = &cases[i];
        scene s;
        json_err e;
        int rc = scene_load_text(&s, pc->json, &e);
        EXPECT_MSG(rc == 0, "%s: %s", pc->name, e.msg);
        if (rc != 0) continue;
        photon_settings c;
        photon_settings_defaults(&c);
        render_plan p;
        EXPECT_EQ_INT(plan_make(&s, &c, 0, &p, NULL, 0), 0);
        check_item(pc->name, "caustics", &p.caustics, pc->caustics, "");
        check_item(pc->name, "global", &p.global, pc->global, "");
        check_item(pc->name, "shadow", &p.shadow, pc->shadow, "");
        scene_free(&s);
    }
}

/* Oracle: plan.h, PLAN_SHADOW_HINT_NODES (measured: the shadow hint paid in no scene, so it is
 * off unless forced). An area light over a plane with a sphere between: occluders, and the
 * reason says so with its figures (the pilot's occluder count, the search's k, the BVH);
 * photon_mapping.shadow=true (or --pm shadow=true) still turns it on, "forced". */
TEST(render_pm_plan_shadow_hint) {
    static const char *json =
        "{" CAM8 ", \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
        "\"e\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 1}},"
        "\"objects\": [{\"type\": \"quad\", \"vertices\": [[-5,0,-5],[-5,0,5],[5,0,5],[5,0,-5]], \"material\": \"w\"},"
        "{\"type\": \"sphere\", \"center\": [0,1,0], \"radius\": 0.6, \"material\": \"w\"},"
        "{\"type\": \"quad\", \"vertices\": [[-1,3,-1],[1,3,-1],[1,3,1],[-1,3,1]], \"material\": \"e\"}]}";
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, json, &e) == 0, "%s", e.msg);
    photon_settings c;
    photon_settings_defaults(&c);
    render_plan p;
    EXPECT_EQ_INT(plan_make(&s, &c, 0, &p, NULL, 0), 0);
    EXPECT(!p.shadow.on);
    char want[160];
    snprintf(want, sizeof want, "its %d-photon search of the shadow map costs about %d BVH node visits",
             c.k_shadow, PLAN_SHADOW_HINT_NODES);
    char bvh_want[80]; /* two triangles a quad and the sphere */
    snprintf(bvh_want, sizeof bvh_want, "(BVH depth %d, %d primitives)", s.accel.depth, s.ntris + s.nspheres);
    EXPECT_EQ_INT(s.ntris + s.nspheres, 5);
    EXPECT_MSG(strstr(p.shadow.reason, "area light with occluders (") && strstr(p.shadow.reason, want) &&
                   strstr(p.shadow.reason, bvh_want) &&
                   strstr(p.shadow.reason, "photon_mapping.shadow=true forces it"),
               "%s", p.shadow.reason);
    plan_free(&p);
    char err[256];
    ASSERT_EQ_INT(photon_settings_cli_set(&s.photon_mapping, "--pm", "shadow=true", err, sizeof err), 0);
    ASSERT_MSG(photon_settings_parse(&c, s.photon_mapping, &e) == 0, "%s", e.msg);
    EXPECT_EQ_INT(plan_make(&s, &c, 0, &p, NULL, 0), 0);
    EXPECT_MSG(p.shadow.on && strcmp(p.shadow.reason, "forced by photon_mapping.shadow") == 0, "%s",
               p.shadow.reason);
    plan_free(&p);
    scene_free(&s);
}

/* Oracle: the documented forcing (plan.h): a "photon_mapping" key or `--pm KEY=VALUE`
 * (photon_settings_cli_set) sets the item whatever the probes found, with the reason "forced by
 * photon_mapping.KEY"; a global map forced off takes final gathering with it; bad values are
 * errors naming the JSON path. */
TEST(render_pm_plan_forced) {
    scene s;
    json_err e;
    /* In the file: cornell_diffuse needs no caustics and has shadows; force the opposite. */
    char path[1024], *text;
    snprintf(path, sizeof path, "%s/data/scenes/cornell_diffuse.json", pm_test_source_dir());
    ASSERT((text = read_file(path, NULL)) != NULL);
    cJSON *root = cJSON_Parse(text);
    free(text);
    ASSERT(root != NULL);
    cJSON *pmo = cJSON_CreateObject();
    cJSON_AddBoolToObject(pmo, "caustics", 1);
    cJSON_AddBoolToObject(pmo, "shadow", 0);
    cJSON_AddBoolToObject(pmo, "final_gather", 0);
    cJSON_AddItemToObject(root, "photon_mapping", pmo);
    int rc = scene_from_json(&s, root, &e);
    cJSON_Delete(root);
    ASSERT_MSG(rc == 0, "%s", e.msg);
    photon_settings c;
    ASSERT_MSG(photon_settings_parse(&c, s.photon_mapping, &e) == 0, "%s", e.msg);
    render_plan p;
    EXPECT_EQ_INT(plan_make(&s, &c, 0, &p, NULL, 0), 0);
    EXPECT(p.caustics.on);
    EXPECT_MSG(strcmp(p.caustics.reason, "forced by photon_mapping.caustics") == 0, "%s", p.caustics.reason);
    EXPECT(!p.shadow.on);
    EXPECT_MSG(strcmp(p.shadow.reason, "forced by photon_mapping.shadow") == 0, "%s", p.shadow.reason);
    EXPECT(p.global.on && !strstr(p.global.reason, "forced"));
    EXPECT(!p.final_gather.on);
    EXPECT_MSG(strstr(p.final_gather.reason, "forced by photon_mapping.final_gather"), "%s",
               p.final_gather.reason);
    scene_free(&s);

    /* On the command line: cornell_spheres needs every map; --pm turns them off. */
    ASSERT_MSG(load_shipped(&s, "cornell_spheres", &e) == 0, "%s", e.msg);
    char err[256];
    ASSERT_EQ_INT(photon_settings_cli_set(&s.photon_mapping, "--pm", "caustics=false", err, sizeof err), 0);
    ASSERT_EQ_INT(photon_settings_cli_set(&s.photon_mapping, "--pm", "global_photons=5000", err, sizeof err), 0);
    ASSERT_MSG(photon_settings_parse(&c, s.photon_mapping, &e) == 0, "%s", e.msg);
    EXPECT_EQ_INT(c.global_photons, 5000);
    EXPECT_EQ_INT(c.force_caustics, PLAN_OFF);
    EXPECT_EQ_INT(c.force_global, PLAN_AUTO);
    EXPECT_EQ_INT(plan_make(&s, &c, 0, &p, NULL, 0), 0);
    EXPECT(!p.caustics.on);
    EXPECT_MSG(strcmp(p.caustics.reason, "forced by photon_mapping.caustics") == 0, "%s", p.caustics.reason);
    EXPECT(p.global.on && !p.shadow.on && p.final_gather.on);
    /* A later flag replaces the earlier one; global off takes final gathering with it. */
    ASSERT_EQ_INT(photon_settings_cli_set(&s.photon_mapping, "--pm", "caustics=true", err, sizeof err), 0);
    ASSERT_EQ_INT(photon_settings_cli_set(&s.photon_mapping, "--pm", "global=false", err, sizeof err), 0);
    ASSERT_MSG(photon_settings_parse(&c, s.photon_mapping, &e) == 0, "%s", e.msg);
    EXPECT_EQ_INT(plan_make(&s, &c, 0, &p, NULL, 0), 0);
    EXPECT(p.caustics.on && strstr(p.caustics.reason, "forced"));
    EXPECT(!p.global.on && strcmp(p.global.reason, "forced by photon_mapping.global") == 0);
    EXPECT_MSG(!p.final_gather.on && strstr(p.final_gather.reason, "no global map"), "%s",
               p.final_gather.reason);
    /* Errors. */
    EXPECT(photon_settings_cli_set(&s.photon_mapping, "--pm", "caustics", err, sizeof err) == PM_EINVAL);
    EXPECT_MSG(strstr(err, "expected KEY=VALUE"), "%s", err);
    ASSERT_EQ_INT(photon_settings_cli_set(&s.photon_mapping, "--pm", "shadow=maybe", err, sizeof err), 0);
    EXPECT(photon_settings_parse(&c, s.photon_mapping, &e) < 0);
    EXPECT_MSG(strstr(e.msg, "$.photon_mapping.shadow: expected true or false"), "%s", e.msg);
    scene_free(&s);
}

/* ---- 2. thread independence ------------------------------------------------------------ */

static int trace_spheres_imp(const scene *s, int threads, uint64_t seed, long target, const importance *imp,
                             photon_maps *m) {
    trace_opts o;
    trace_opts_init(&o, s);
    o.importance = imp;
    o.global = o.caustic = o.shadow = 1;
    o.global_target = o.caustic_target = target;
    o.threads = threads;
    o.seed = seed;
    o.quiet = 1;
    char err[256];
    return photon_trace(s, &o, m, err, sizeof err);
}

static int trace_spheres(const scene *s, int threads, uint64_t seed, long target, photon_maps *m) {
    return trace_spheres_imp(s, threads, seed, target, NULL, m);
}

#define SAME_MAP(a, b, arr, n)                                                              \
    do {                                                                                    \
        EXPECT_EQ_INT((a).n, (b).n);                                                        \
        if ((a).n == (b).n)                                                                 \
            EXPECT_MSG(memcmp((a).arr, (b).arr, (a).n * sizeof(pm_photon)) == 0,            \
                       #arr " map differs between 1 and 2 threads");                       \
    } while (0)

/* Oracle: the one-thread maps of cornell_spheres; the two-thread maps must be bit-identical
 * (arrays and every count), as photon_trace.h promises. A different seed must change them,
 * so the comparison can see a difference. Also, as every surface of the scene is either
 * purely specular or purely diffuse, a caustic path stores at most one photon and only after
 * a specular first hit, so ncaustic <= caustic_first_specular <= caustic_emitted, and the
 * count equals its statistics counter. */
TEST(render_pm_maps_thread_independent) {
    const long target = PM_TEST_SANITIZED ? 6000 : 20000;
#ifdef _OPENMP
    int team = 0;
#pragma omp parallel num_threads(2)
    {
#pragma omp single
        team = omp_get_num_threads();
    }
    ASSERT_MSG(team == 2, "OpenMP gave %d threads, not 2: the test would not test anything", team);
#endif
    scene s;
    json_err e;
    ASSERT_MSG(load_shipped(&s, "cornell_spheres", &e) == 0, "%s", e.msg);
    photon_maps m1, m2, m3;
    int st_first = stats_register("Photons/Caustic-pass photons whose first hit is specular");
    uint64_t first0 = stats_total(st_first);
    ASSERT_EQ_INT(trace_spheres(&s, 1, 3, target, &m1), 0);
    EXPECT_EQ_INT(stats_total(st_first) - first0, m1.caustic_first_specular);
    EXPECT_MSG(m1.ncaustic <= m1.caustic_first_specular &&
                   m1.caustic_first_specular <= m1.caustic_emitted,
               "caustic photons %zu, first hit specular %llu, emitted %llu", m1.ncaustic,
               (unsigned long long)m1.caustic_first_specular,
               (unsigned long long)m1.caustic_emitted);
    ASSERT_EQ_INT(trace_spheres(&s, 2, 3, target, &m2), 0);
    ASSERT_EQ_INT(trace_spheres(&s, 2, 4, target, &m3), 0);
    EXPECT((long)m1.nglobal >= target && (long)m1.ncaustic >= target && m1.nshadow > 0);
    SAME_MAP(m1, m2, global, nglobal);
    SAME_MAP(m1, m2, caustic, ncaustic);
    SAME_MAP(m1, m2, shadow, nshadow);
    EXPECT_EQ_INT(m1.global_emitted, m2.global_emitted);
    EXPECT_EQ_INT(m1.caustic_emitted, m2.caustic_emitted);
    EXPECT_EQ_INT(m1.caustic_saved, m2.caustic_saved);
    EXPECT_EQ_INT(m1.caustic_first_specular, m2.caustic_first_specular);
    EXPECT(m1.caustic_fraction == m2.caustic_fraction);
    EXPECT(!m1.global_runaway && !m1.caustic_runaway && !m2.global_runaway && !m2.caustic_runaway);
    size_t n = m1.nglobal < m3.nglobal ? m1.nglobal : m3.nglobal;
    EXPECT_MSG(memcmp(m1.global, m3.global, n * sizeof(pm_photon)) != 0,
               "seeds 3 and 4 gave the same global map");
    photon_maps_free(&m1);
    photon_maps_free(&m2);
    photon_maps_free(&m3);
    /* Importance-driven emission (importance.h): the table built on 1 and on 2 threads is
     * the same, and so are the maps traced with it; and they differ from the maps by power. */
    importance i1, i2;
    ASSERT_EQ_INT(importance_build(&s, 4096, 0.2, 3, 1, &i1), 0);
    ASSERT_EQ_INT(importance_build(&s, 4096, 0.2, 3, 2, &i2), 0);
    EXPECT_MSG(i1.on && i1.lv[0].ncells == i2.lv[0].ncells && i1.contributing == i2.contributing,
               "importance tables: on %d, cells %zu / %zu", i1.on, i1.lv[0].ncells, i2.lv[0].ncells);
    for (int v = 0; v < IMP_LEVELS && i1.lv[v].ncells == i2.lv[v].ncells; v++)
        EXPECT_MSG(memcmp(i1.lv[v].cell, i2.lv[v].cell, i1.lv[v].ncells * sizeof(uint64_t)) == 0 &&
                       memcmp(i1.lv[v].cdf, i2.lv[v].cdf, (i1.lv[v].ncells + 1) * sizeof(double)) == 0,
                   "importance level %d differs between 1 and 2 threads", v);
    ASSERT_EQ_INT(trace_spheres_imp(&s, 1, 3, target, &i1, &m1), 0);
    ASSERT_EQ_INT(trace_spheres_imp(&s, 2, 3, target, &i1, &m2), 0);
    ASSERT_EQ_INT(trace_spheres(&s, 1, 3, target, &m3), 0);
    SAME_MAP(m1, m2, global, nglobal);
    SAME_MAP(m1, m2, shadow, nshadow);
    EXPECT_EQ_INT(m1.global_emitted, m2.global_emitted);
    n = m1.nglobal < m3.nglobal ? m1.nglobal : m3.nglobal;
    EXPECT_MSG(memcmp(m1.global, m3.global, n * sizeof(pm_photon)) != 0,
               "the importance table did not change the global map");
    photon_maps_free(&m1);
    photon_maps_free(&m2);
    photon_maps_free(&m3);
    importance_free(&i1);
    importance_free(&i2);
    scene_free(&s);
#ifndef _OPENMP
    /* OPENMP=0: the "2 threads" run above was the same one-thread program, so the comparison
     * could not fail; the other checks ran. */
    SKIP("built without OpenMP (OPENMP=0): 1 and 2 threads are the same program here");
#endif
}

/* ---- importance-driven emission (importance.h) ----------------------------------------- */

/* Oracle: light_sample_le itself. For random u, (p, d) = light_sample_le(u) and
 * importance_invert_le(p, d) must give u back (to 1e-6; near the seams of the concentric map
 * and at the triangle's apex only to the rounding of their trigonometry), for a one-sided and a
 * two-sided area light, a sphere light, a point light and a directional light. */
TEST(render_pm_importance_inverts_emission) {
    const char *txt =
        "{\"camera\": {\"eye\": [0,0,-8], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
        " \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
        "  \"e\": {\"type\": \"lambert\", \"reflectance\": 0.5, \"emission\": 2},"
        "  \"e2\": {\"type\": \"lambert\", \"reflectance\": 0.5, \"emission\": 1, \"two_sided\": true}},"
        " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-1,2,-1],[1,2,-1],[1,2,1],[-1,2,1]], \"material\": \"e\"},"
        "  {\"type\": \"quad\", \"vertices\": [[-3,0,-1],[-3,0,1],[-3,1,1],[-3,1,-1]], \"material\": \"e2\"},"
        "  {\"type\": \"sphere\", \"center\": [2,-1,0], \"radius\": 0.5, \"material\": \"e\"},"
        "  {\"type\": \"sphere\", \"center\": [0,-3,0], \"radius\": 1, \"material\": \"w\"}],"
        " \"lights\": [{\"type\": \"point\", \"position\": [0,1,0], \"intensity\": 1},"
        "  {\"type\": \"directional\", \"direction\": [0.2,-1,0.1], \"irradiance\": 1}]}";
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    int kinds[4] = {0, 0, 0, 0}, two = 0;
    rng g = rng_stream(7, 1, 2);
    for (int li = 0; li < s.nlights; li++) {
        const light *l = &s.lights[li];
        kinds[l->type]++;
        two += l->two_sided;
        double worst = 0;
        for (int k = 0; k < 2000; k++) {
            double u[4], w[4];
            for (int j = 0; j < 4; j++) u[j] = 0.001 + 0.998 * rng_uniform(&g);
            vec3 p, n, d;
            light_sample_le(&s, li, u, &p, &n, &d);
            EXPECT(importance_invert_le(&s, li, p, d, w) == 1);
            int dims = l->type == LIGHT_AREA || l->type == LIGHT_SPHERE ? 4 : 2;
            for (int j = 0; j < dims; j++) worst = fmax(worst, fabs(w[j] - u[j]));
            EXPECT(importance_cell(l, u) == importance_cell(l, w) || worst > 0);
        }
        EXPECT_MSG(worst < 1e-6, "light %d (type %d, two-sided %d): |u - invert(le(u))| up to %g", li, l->type,
                   l->two_sided, worst);
    }
    EXPECT_MSG(kinds[LIGHT_AREA] >= 4 && kinds[LIGHT_SPHERE] == 1 && kinds[LIGHT_POINT] == 1 &&
                   kinds[LIGHT_DIRECTIONAL] == 1 && two == 2,
               "light kinds %d %d %d %d, two-sided %d", kinds[0], kinds[1], kinds[2], kinds[3], two);
    scene_free(&s);
}

/* Sum of the three channels' power over n photons. */
static void map_power(const pm_photon *ph, size_t n, double tot[3]) {
    tot[0] = tot[1] = tot[2] = 0;
    for (size_t i = 0; i < n; i++) {
        float pw[3];
        pm_rgbe_decode(ph[i].power, pw);
        for (int c = 0; c < 3; c++) tot[c] += pw[c];
    }
}

/* Oracle: energy conservation, exactly as in render_pm_energy_closed_box (a point light of
 * power Phi in a closed box of albedo rho, max_depth 3: the stored power of channel c is
 * Phi (1 - rho_c^4) / (1 - rho_c) in expectation), now for maps that the plan's pilot photons
 * join (photon_trace.h, PILOT PHOTONS): their stores count toward the target, both emissions
 * count as emitted, and the total stays within 1% (the estimate's standard error there is
 * about 0.1%). Then cornell_spheres with importance-driven emission (rel != 1: the balance
 * heuristic's denominators differ per photon): the global map's total power with the pilot's
 * photons joined equals, within 2%, that of a pass of the same target without them, and the
 * two emissions are both counted. */
TEST(render_pm_pilot_photons_join) {
    const double rho[3] = {0.5, 0.45, 0.4}, Phi = 100;
    char txt[4096];
    snprintf(txt, sizeof txt,
             "{" CAM8 ", \"materials\": {\"wall\": {\"type\": \"lambert\", \"reflectance\": [%g, %g, %g]}},"
             "\"objects\": [" CUBE_MESH("1", "wall") "],"
             "\"lights\": [{\"type\": \"point\", \"position\": [0.2,-0.1,0.3], \"power\": %g}],"
             "\"render\": {\"max_depth\": 3, \"seed\": 5}}",
             rho[0], rho[1], rho[2], Phi);
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    photon_settings c;
    ASSERT_MSG(photon_settings_parse(&c, s.photon_mapping, &e) == 0, "%s", e.msg);
    render_plan p;
    EXPECT_EQ_INT(plan_make(&s, &c, 0, &p, NULL, 0), 0);
    ASSERT_MSG(p.global.on && p.pilot != NULL && p.imp == NULL, "global %d, pilot %p, table %p (%s)", p.global.on,
               (void *)p.pilot, (void *)p.imp, p.emission.reason);
    trace_opts o;
    trace_opts_init(&o, &s);
    o.global = 1;
    o.global_target = 100000;
    o.quiet = 1;
    o.reuse = p.pilot;
    photon_maps m;
    char err[256];
    ASSERT_MSG(photon_trace(&s, &o, &m, err, sizeof err) == 0, "%s", err);
    double tot[3];
    map_power(m.global, m.nglobal, tot);
    EXPECT_MSG((long)m.nglobal >= o.global_target && (long)m.nglobal < o.global_target + 8,
               "%zu photons stored for a target of %ld", m.nglobal, o.global_target);
    long ndirect = 0;
    for (size_t i = 0; i < m.nglobal; i++) ndirect += pm_photon_kind(&m.global[i]) == PM_KIND_DIRECT;
    EXPECT_EQ_INT(ndirect, (long)m.global_emitted); /* every emitted photon, pilot's too, is stored once direct */
    for (int ch = 0; ch < 3; ch++) {
        double want = Phi * (1 - pow(rho[ch], 4)) / (1 - rho[ch]);
        printf("    closed box, channel %d: stored %.4f, expected %.4f (%+.3f%%)\n", ch, tot[ch], want,
               100 * (tot[ch] / want - 1));
        EXPECT_MSG(fabs(tot[ch] / want - 1) < 0.01, "channel %d: %g vs %g", ch, tot[ch], want);
    }
    photon_maps_free(&m);
    plan_free(&p);
    scene_free(&s);

    ASSERT_MSG(load_shipped(&s, "cornell_spheres", &e) == 0, "%s", e.msg);
    ASSERT_MSG(photon_settings_parse(&c, s.photon_mapping, &e) == 0, "%s", e.msg);
    EXPECT_EQ_INT(plan_make(&s, &c, 0, &p, NULL, 0), 0);
    ASSERT_MSG(p.imp != NULL && p.pilot != NULL, "table %p, pilot %p", (void *)p.imp, (void *)p.pilot);
    double t2[3];
    photon_maps m2;
    trace_opts_init(&o, &s);
    o.global = o.shadow = 1;
    o.global_target = 100000;
    o.quiet = 1;
    o.importance = p.imp;
    ASSERT_MSG(photon_trace(&s, &o, &m2, err, sizeof err) == 0, "%s", err);
    o.reuse = p.pilot;
    ASSERT_MSG(photon_trace(&s, &o, &m, err, sizeof err) == 0, "%s", err);
    map_power(m.global, m.nglobal, tot);
    map_power(m2.global, m2.nglobal, t2);
    EXPECT_MSG(m.global_emitted > m2.global_emitted - 8192 && m.nshadow > 0, "emitted %llu and %llu",
               (unsigned long long)m.global_emitted, (unsigned long long)m2.global_emitted);
    for (int ch = 0; ch < 3; ch++) {
        printf("    cornell_spheres, channel %d: with the pilot's photons %.5g, without %.5g (%+.3f%%)\n", ch, tot[ch],
               t2[ch], 100 * (tot[ch] / t2[ch] - 1));
        EXPECT_MSG(fabs(tot[ch] / t2[ch] - 1) < 0.02, "channel %d: %g vs %g", ch, tot[ch], t2[ch]);
    }
    photon_maps_free(&m);
    photon_maps_free(&m2);
    plan_free(&p);
    scene_free(&s);
}

/* Oracle: a caustic whose total power is exact. A point light of power Phi at distance d
 * above the centre of a mirror sphere (radius r, reflectance R) inside a closed Lambertian
 * box: the photons that hit the sphere (solid angle Omega = 2 pi (1 - sqrt(1 - (r/d)^2)))
 * survive the mirror with probability R and then hit a wall (a convex mirror never sees
 * itself), each stored once as an L S D photon; so the caustic map's power is
 * Phi R Omega / (4 pi) in expectation, whatever the projection map does. The caustic
 * pilot's stores joining the map (photon_trace.h, PILOT PHOTONS) must keep that: over 6
 * seeds the mean total with the pilot joined, and without it, is within 4 standard errors
 * (from the counts stored, a binomial) plus the RGBE rounding bound (0.4%) of the exact
 * value. Counts: the plan's caustics line says how many pilot stores join; they are the
 * pilot's L S+ D stores (its evidence counter), the last photons of the map (positions equal
 * to a pilot traced here with the plan's seed and size, power scaled by n_p / (n_p + n_m)),
 * counted in pilot_stored/pilot_emitted and the statistics; the pass stops at the target
 * with them counted. The scene's next seed draws another pilot. The joined map is the same
 * on 1 and 2 threads. Not joined (with the plan saying why): the pass without the projection
 * map, and a target below twice the pilot's stores. */
TEST(render_pm_caustic_pilot_joins) {
    const double Phi = 100, R = 0.8, r = 0.3, d = 1.0;
    const double want = Phi * R * 2 * M_PI * (1 - sqrt(1 - (r / d) * (r / d))) / (4 * M_PI);
    const long target = PM_TEST_SANITIZED ? 12000 : 20000;
    char txt[4096];
    snprintf(txt, sizeof txt,
             "{" CAM8 ", \"materials\": {\"wall\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
             "\"chrome\": {\"type\": \"mirror\", \"reflectance\": %g}},"
             "\"objects\": [" CUBE_MESH("1", "wall") ", {\"type\": \"sphere\", \"center\": [0,-0.5,0], \"radius\": %g,"
             "\"material\": \"chrome\"}],"
             "\"lights\": [{\"type\": \"point\", \"position\": [0,%g,0], \"power\": %g}]}",
             R, r, d - 0.5, Phi);
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    photon_settings c;
    ASSERT_MSG(photon_settings_parse(&c, s.photon_mapping, &e) == 0, "%s", e.msg);
    c.caustic_photons = target;
    render_plan p;
    EXPECT_EQ_INT(plan_make(&s, &c, 0, &p, NULL, 0), 0);
    ASSERT_MSG(p.caustics.on && p.pilot, "caustics %d (%s), pilot %p", p.caustics.on, p.caustics.reason,
               (void *)p.pilot);
    printf("    plan: caustics: %s\n", p.caustics.reason);
    const char *at = strstr(p.caustics.reason, "the pilot's ");
    size_t nplan = 0;
    unsigned long long eplan = 0;
    ASSERT_MSG(at && sscanf(at, "the pilot's %zu stores join the caustic map (its %llu photons", &nplan, &eplan) == 2,
               "%s", p.caustics.reason);
    EXPECT_EQ_INT(eplan, PLAN_PILOT_PHOTONS);

    /* The pilot, traced again as plan.c traces it: its L S+ D stores and evidence. */
    trace_opts o;
    trace_opts_settings(&o, &s, &c);
    o.seed = plan_pilot_seed(&s);
    o.caustic = 1;
    o.caustic_target = 1L << 40;
    o.max_emitted = PLAN_PILOT_PHOTONS;
    o.max_emitted_factor = 1e300;
    o.quiet = 1;
    trace_pilot tp;
    memset(&tp, 0, sizeof tp);
    o.pilot = &tp;
    photon_maps mp;
    char err[256];
    ASSERT_MSG(photon_trace(&s, &o, &mp, err, sizeof err) == 0, "%s", err);
    EXPECT_EQ_INT(mp.ncaustic, nplan);
    EXPECT_EQ_INT(tp.caustic.total, nplan);
    EXPECT_EQ_INT(mp.caustic_emitted, PLAN_PILOT_PHOTONS);
    ASSERT_MSG(nplan > 1000 && 2 * nplan <= (size_t)target, "%zu pilot stores", nplan);
    { /* another seed, another pilot (plan_pilot_seed): its share averages out over seeds */
        uint64_t seed0 = s.settings.seed;
        s.settings.seed = seed0 + 1;
        o.seed = plan_pilot_seed(&s);
        s.settings.seed = seed0;
        photon_maps mq;
        ASSERT_MSG(photon_trace(&s, &o, &mq, err, sizeof err) == 0, "%s", err);
        size_t n = mq.ncaustic < mp.ncaustic ? mq.ncaustic : mp.ncaustic;
        EXPECT_MSG(n > 0 && memcmp(mq.caustic, mp.caustic, n * sizeof(pm_photon)) != 0,
                   "the pilots of two seeds stored the same photons");
        photon_maps_free(&mq);
    }

    int st_stored = stats_register("Photons/Pilot photons reused in the caustic map (stored)");
    double sum[2] = {0, 0}, se2[2] = {0, 0};
    const int nseeds = 6;
    for (int join = 0; join < 2; join++)
        for (int seed = 1; seed <= nseeds; seed++) {
            trace_opts_settings(&o, &s, &c);
            o.caustic = 1;
            o.seed = (uint64_t)seed;
            o.quiet = 1;
            o.reuse = join ? p.pilot : NULL;
            photon_maps m;
            uint64_t st0 = stats_total(st_stored);
            ASSERT_MSG(photon_trace(&s, &o, &m, err, sizeof err) == 0, "%s", err);
            double tot[3];
            map_power(m.caustic, m.ncaustic, tot);
            double q = (double)m.ncaustic / (double)m.caustic_emitted;
            sum[join] += tot[0];
            se2[join] += want * want * (1 - q) / (double)m.ncaustic;
            EXPECT_MSG((long)m.ncaustic >= target && (long)m.ncaustic < target + 4, "%zu stored for %ld",
                       m.ncaustic, target);
            if (!join) {
                EXPECT(m.pilot_stored[1] == 0 && m.pilot_emitted[1] == 0);
                photon_maps_free(&m);
                continue;
            }
            EXPECT_EQ_INT(m.pilot_stored[1], nplan);
            EXPECT_EQ_INT(m.pilot_emitted[1], PLAN_PILOT_PHOTONS);
            EXPECT_EQ_INT(stats_total(st_stored) - st0, nplan);
            /* The joined photons: the pilot's, last, at power n_p / (n_p + n_m) of the pilot's. */
            double ratio = (double)PLAN_PILOT_PHOTONS / (double)m.caustic_emitted, worst = 0;
            size_t same = 0;
            for (size_t k = 0; k < nplan && m.ncaustic >= nplan; k++) {
                const pm_photon *a = &m.caustic[m.ncaustic - nplan + k], *b = &mp.caustic[k];
                same += memcmp(a->pos, b->pos, sizeof a->pos) == 0;
                float pa[3], pb[3];
                pm_rgbe_decode(a->power, pa);
                pm_rgbe_decode(b->power, pb);
                double dev = fabs(pa[0] / (pb[0] * ratio) - 1);
                if (dev > worst) worst = dev;
            }
            EXPECT_MSG(same == nplan, "seed %d: %zu of %zu joined photons at the pilot's positions", seed, same, nplan);
            EXPECT_MSG(worst < 0.01, "seed %d: a joined photon's power is off the pilot's x %g by %g", seed, ratio,
                       worst);
            if (seed == 1) { /* the same map on 2 threads */
                photon_maps m2;
                o.threads = 2;
                ASSERT_MSG(photon_trace(&s, &o, &m2, err, sizeof err) == 0, "%s", err);
                SAME_MAP(m, m2, caustic, ncaustic);
                EXPECT_EQ_INT(m.caustic_emitted, m2.caustic_emitted);
                photon_maps_free(&m2);
            }
            photon_maps_free(&m);
        }
    for (int join = 0; join < 2; join++) {
        double mean = sum[join] / nseeds, se = sqrt(se2[join]) / nseeds, tol = 4 * se / want + 0.004;
        printf("    caustic map power %s the pilot: %.5f, exact %.5f (%+.3f%%, tolerance %.2f%%, se %.3f%%)\n",
               join ? "with" : "without", mean, want, 100 * (mean / want - 1), 100 * tol, 100 * se / want);
        EXPECT_MSG(fabs(mean / want - 1) < tol, "%s the pilot: %g vs %g", join ? "with" : "without", mean, want);
    }

    /* Not joined: the pass without the projection map, and a target under twice the pilot's
     * stores; the plan says why, and photon_trace agrees. */
    photon_settings c2 = c;
    c2.projection = 0;
    render_plan p2;
    EXPECT_EQ_INT(plan_make(&s, &c2, 0, &p2, NULL, 0), 0);
    EXPECT_MSG(strstr(p2.caustics.reason, "do not join the caustic map: the pass aims by other projection maps"),
               "%s", p2.caustics.reason);
    c2 = c;
    c2.caustic_photons = (long)nplan;
    render_plan p3;
    EXPECT_EQ_INT(plan_make(&s, &c2, 0, &p3, NULL, 0), 0);
    EXPECT_MSG(strstr(p3.caustics.reason, "do not join the caustic map: the pilot stored half the target or more"),
               "%s", p3.caustics.reason);
    for (int k = 0; k < 2; k++) {
        trace_opts_settings(&o, &s, k ? &c2 : &c);
        o.caustic = 1;
        o.quiet = 1;
        o.projection = k; /* k 0: no projection map; k 1: the small target */
        o.reuse = p.pilot;
        photon_maps m;
        ASSERT_MSG(photon_trace(&s, &o, &m, err, sizeof err) == 0, "%s", err);
        EXPECT_MSG(m.pilot_stored[1] == 0 && m.pilot_emitted[1] == 0, "case %d: %zu pilot stores joined", k,
                   m.pilot_stored[1]);
        photon_maps_free(&m);
    }
    /* The other reasons of pilot_photons_joining (photon_trace.h), each with its words. */
    trace_opts_settings(&o, &s, &c);
    o.caustic = 1;
    const char *why = NULL;
    EXPECT(pilot_photons_joining(p.pilot, &o, 1, NULL, NULL, &why) == 1 && why && !why[0]);
    o.max_bounces = 7;
    EXPECT(pilot_photons_joining(p.pilot, &o, 1, NULL, NULL, &why) == 0 && strstr(why, "max_bounces"));
    trace_opts_settings(&o, &s, &c);
    o.caustic = 1;
    o.max_depth++;
    EXPECT(pilot_photons_joining(p.pilot, &o, 1, NULL, NULL, &why) == 0 && strstr(why, "max_depth"));
    trace_opts_settings(&o, &s, &c);
    EXPECT(pilot_photons_joining(p.pilot, &o, 1, NULL, NULL, &why) == 0 && strstr(why, "no caustic pass"));
    o.caustic = 1;
    o.pilot = &tp;
    EXPECT(pilot_photons_joining(p.pilot, &o, 1, NULL, NULL, &why) == 0 && strstr(why, "a pilot pass"));
    EXPECT(pilot_photons_joining(NULL, &o, 1, NULL, NULL, &why) == 0 && why && !why[0]);
    plan_free(&p3);
    plan_free(&p2);
    photon_maps_free(&mp);
    plan_free(&p);
    scene_free(&s);
}

/* Oracle: what each scene's camera sees. shelf_glass and cornell_spheres see most of what
 * their lamps light: importance-driven emission, its line naming the coverage. pinhole_room
 * sees only light through a 10 x 10 hole (a few percent of the lamp's emission: by power,
 * importance.h LIMITS); importance_paths = 0 turns it off, and so does a global map shown
 * directly (no final gather); a scene with media never uses it.
 * The table the plan keeps is the one it describes (coverage and on). */
TEST(render_pm_plan_emission) {
    const struct {
        const char *scene, *set;
        int on;
        const char *why;
    } cases[] = {{"shelf_glass", NULL, 1, "of the lights' power"},
                 {"cornell_spheres", NULL, 1, "of the lights' power"},
                 {"pinhole_room", NULL, 0, "below the 10% emission can steer by"},
                 {"shelf_glass", "importance_paths=0", 0, "importance_paths is 0"},
                 {"shelf_glass", "final_gather=false", 0, "shown directly"},
                 {"cornell_fog", NULL, 0, "a scene with media"}};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        scene s;
        json_err e;
        ASSERT_MSG(load_shipped(&s, cases[k].scene, &e) == 0, "%s", e.msg);
        char err[256];
        if (cases[k].set) ASSERT_EQ_INT(photon_settings_cli_set(&s.photon_mapping, "--pm", cases[k].set, err, sizeof err), 0);
        photon_settings c;
        ASSERT_MSG(photon_settings_parse(&c, s.photon_mapping, &e) == 0, "%s", e.msg);
        render_plan p;
        EXPECT_EQ_INT(plan_make(&s, &c, 0, &p, NULL, 0), 0);
        printf("    %s%s%s: %s (%s)\n", cases[k].scene, cases[k].set ? " --pm " : "", cases[k].set ? cases[k].set : "",
               p.emission.on ? "importance" : "by power", p.emission.reason);
        EXPECT_MSG(p.emission.on == cases[k].on && strstr(p.emission.reason, cases[k].why),
                   "%s: emission %d: %s", cases[k].scene, p.emission.on, p.emission.reason);
        EXPECT_MSG((p.imp != NULL) == p.emission.on, "%s: table %p", cases[k].scene, (void *)p.imp);
        if (p.imp) EXPECT(p.imp->on && p.imp->coverage >= IMP_MIN_COVERAGE);
        plan_free(&p);
        scene_free(&s);
    }
}

/* Oracle: the uniform emission's exact answers. The defensive mixture must be unbiased: for
 * photons drawn by importance_sample, the mean of f(l, u) / rel equals the mean of f under
 * uniform emission (light by power, u uniform), which for f = 1 on a box B of u-space of
 * light l is p_l vol(B). Checked on cornell_spheres' table for boxes inside and outside the
 * important cells (5 standard errors of the estimate, 400,000 draws), and rel >= a
 * everywhere (no photon carries more than 1/a of the uniform power). Also, the table steers:
 * the photons' share landing in the finest important cells is at least half the (1 - a)
 * that is aimed there. */
TEST(render_pm_importance_mixture_is_unbiased) {
    scene s;
    json_err e;
    ASSERT_MSG(load_shipped(&s, "cornell_spheres", &e) == 0, "%s", e.msg);
    importance imp;
    ASSERT_EQ_INT(importance_build(&s, 4096, 0.2, 1, 0, &imp), 0);
    ASSERT_MSG(imp.on, "no importance on cornell_spheres (coverage %g)", imp.coverage);
    /* Boxes of light 0's u-space: [lo, hi) per dimension. */
    const double box[3][2][4] = {{{0, 0, 0, 0}, {1, 1, 1, 1}},
                                 {{0.1, 0.2, 0.3, 0.4}, {0.6, 0.5, 0.7, 0.9}},
                                 {{0.0, 0.0, 0.9, 0.9}, {1, 1, 1, 1}}};
    const long N = PM_TEST_SANITIZED ? 100000 : 400000;
    for (int b = 0; b < 3; b++) {
        double sum = 0, sum2 = 0, vol = 1, minrel = INFINITY, in_table = 0;
        for (int j = 0; j < 4; j++) vol *= box[b][1][j] - box[b][0][j];
        rng g = rng_stream(11, (uint64_t)b, 3);
        for (long k = 0; k < N; k++) {
            double h[4], u[4], rel;
            for (int j = 0; j < 4; j++) h[j] = rng_uniform(&g);
            int li = importance_sample(&imp, &s, rng_uniform(&g), h, u, &rel);
            minrel = fmin(minrel, rel);
            in_table += rel > 1;
            int inside = li == 0;
            for (int j = 0; j < 4; j++) inside &= u[j] >= box[b][0][j] && u[j] < box[b][1][j];
            double f = inside ? 1 / rel : 0;
            sum += f;
            sum2 += f * f;
            EXPECT(fabs(importance_rel(&imp, &s, li, u) - rel) <= 1e-12 * rel);
        }
        double mean = sum / N, se = sqrt(fmax(0, sum2 / N - mean * mean) / N);
        double want = imp.pl[0] * vol;
        printf("    box %d: mean f/rel %.5f, uniform %.5f (se %.5f); min rel %.3f; %.0f%% drawn where rel > 1\n", b,
               mean, want, se, minrel, 100 * in_table / N);
        EXPECT_MSG(fabs(mean - want) < 5 * se + 1e-12, "box %d: %g vs %g (se %g)", b, mean, want, se);
        EXPECT_MSG(minrel >= 0.2 - 1e-12, "rel %g below the defensive fraction", minrel);
        EXPECT_MSG(in_table / N > 0.4, "only %.1f%% of the photons are steered", 100 * in_table / N);
    }
    importance_free(&imp);
    scene_free(&s);
}

/* ---- 3. energy conservation ------------------------------------------------------------ */

/* Oracle: a closed box (a watertight cube mesh) of one Lambertian material with albedo rho_c
 * per channel, and a point light of power Phi inside. Every emitted photon hits a wall first
 * and is stored there (kind DIRECT); at each hit Russian roulette keeps it with probability
 * p = max_c(rho_c P_c) / max_c P_c = 0.5 (channel 0 has the largest albedo, so it keeps the
 * largest power) and scales channel c by rho_c / p, and photon_trace.c stores at depths
 * 0..max_depth (its loop runs depth <= max_depth), so with D = max_depth + 1 stored hits at
 * most,
 *     total stored power, channel c = Phi sum_{j=0}^{D-1} rho_c^j = Phi (1 - rho_c^D) / (1 - rho_c).
 * max_depth = 3 makes the truncation 6% of channel 0, so an off-by-one in the depth
 * convention changes the total by 3.3% or 6.7%. Exact side checks: the number of DIRECT
 * photons equals the number emitted, the longest path stores exactly D photons, and every
 * photon at bounce j carries Phi/n_e (rho_c/p)^j within the RGBE bound of photon.h.
 * Tolerance: 1% of the expected total per channel, which must hold 4 standard errors (the
 * spread of the per-path sums of stored power, paths being independent: the total does not
 * depend on where the light's photons go) plus Q_c, the RGBE rounding bound summed over the
 * photons (2^-8 / (1 - 2^-9) of the largest channel each). Not shrunk under sanitizers (it
 * takes about 2 s there): fewer photons would not fit 4 standard errors in the 1%. */
TEST(render_pm_energy_closed_box) {
    const double rho[3] = {0.5, 0.45, 0.4}, Phi = 100;
    const int max_depth = 3, D = max_depth + 1;
    const long target = 400000;
    char txt[4096];
    snprintf(txt, sizeof txt,
             "{" CAM8 ", \"materials\": {\"wall\": {\"type\": \"lambert\", \"reflectance\": [%g, %g, %g]}},"
             "\"objects\": [" CUBE_MESH("1", "wall") "],"
             "\"lights\": [{\"type\": \"point\", \"position\": [0.2,-0.1,0.3], \"power\": %g}],"
             "\"render\": {\"max_depth\": %d, \"seed\": 5}}",
             rho[0], rho[1], rho[2], Phi, max_depth);
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(s.nlights, 1);
    ASSERT_NEAR(s.lights[0].power.x, Phi, 1e-9);
    trace_opts o;
    trace_opts_init(&o, &s);
    ASSERT_EQ_INT(o.max_depth, max_depth);
    o.global = 1;
    o.global_target = target;
    o.quiet = 1;
    photon_maps m;
    char err[256];
    ASSERT_MSG(photon_trace(&s, &o, &m, err, sizeof err) == 0, "%s", err);
    ASSERT(!m.global_runaway && (long)m.nglobal >= target);
    const double ne = (double)m.global_emitted, p = Phi / ne;
    const double qrel = ldexp(1.0, -8) / (1 - ldexp(1.0, -9));

    double total[3] = {0}, path[3] = {0}, sum2[3] = {0}, quant = 0;
    long ndirect = 0, maxlen = 0, len = 0, bad_power = 0;
    for (size_t i = 0; i <= m.nglobal; i++) {
        int kind = i < m.nglobal ? pm_photon_kind(&m.global[i]) : PM_KIND_DIRECT;
        if (kind == PM_KIND_DIRECT) { /* a new path starts: close the previous one */
            if (i > 0)
                for (int c = 0; c < 3; c++) sum2[c] += path[c] * path[c];
            path[0] = path[1] = path[2] = 0;
            if (len > maxlen) maxlen = len;
            len = 0;
            if (i == m.nglobal) break;
            ndirect++;
        }
        EXPECT_MSG(kind == PM_KIND_DIRECT || kind == PM_KIND_INDIRECT, "photon %zu: kind %d", i, kind);
        float pw[3];
        pm_rgbe_decode(m.global[i].power, pw);
        for (int c = 0; c < 3; c++) {
            double want = p * pow(rho[c] / rho[0], (double)len);
            double tol = c == 0 ? want * ldexp(1.0, -8) : p * qrel;
            if (fabs(pw[c] - want) > tol + 1e-6 * want && bad_power++ < 5)
                EXPECT_MSG(0, "photon %zu (bounce %ld): channel %d power %.9g, expected %.9g", i,
                           len, c, pw[c], want);
            total[c] += pw[c];
            path[c] += pw[c];
        }
        quant += p * qrel;
        len++;
    }
    EXPECT_EQ_INT(ndirect, (long)m.global_emitted);
    EXPECT_EQ_INT(maxlen, D);
    EXPECT_EQ_INT(bad_power, 0);
    for (int c = 0; c < 3; c++) {
        double expect = Phi * (1 - pow(rho[c], D)) / (1 - rho[c]);
        double n = (double)ndirect;
        double var = (sum2[c] - total[c] * total[c] / n) / (n - 1);
        double se = sqrt(n * var);
        printf("    channel %d: stored %.6g, expected %.6g (rel err %+.4f%%), standard error %.4f%%, "
               "RGBE bound %.4f%%; %zu photons from %.0f emitted\n",
               c, total[c], expect, 100 * (total[c] - expect) / expect, 100 * se / expect,
               100 * quant / expect, m.nglobal, ne);
        EXPECT_MSG(4 * se + quant <= 0.01 * expect,
                   "channel %d: 4 standard errors (%.4g) + RGBE bound (%.4g) exceed 1%% (%.4g)", c,
                   4 * se, quant, 0.01 * expect);
        EXPECT_REL(total[c], expect, 0.01);
    }
    photon_maps_free(&m);
    scene_free(&s);
}

/* ---- 4. runaway scenes ------------------------------------------------------------------- */

/* An area light at y = 10 facing up (+y), and under it a floor and a mirror sphere: no photon
 * it emits can hit anything. */
static const char *k_runaway_scene =
    "{\"camera\": {\"eye\": [0,4,-9], \"look_at\": [0,1,0], \"fov_deg\": 50, \"width\": 8, \"height\": 8, \"spp\": 1},"
    "\"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5}, \"m\": {\"type\": \"mirror\"},"
    "\"e\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 5}},"
    "\"objects\": [{\"type\": \"quad\", \"vertices\": [[-5,0,-5],[-5,0,5],[5,0,5],[5,0,-5]], \"material\": \"w\"},"
    "{\"type\": \"sphere\", \"center\": [0,1,0], \"radius\": 0.5, \"material\": \"m\"},"
    "{\"type\": \"quad\", \"vertices\": [[-1,10,1],[1,10,1],[1,10,-1],[-1,10,-1]], \"material\": \"e\"}]}";

/* Oracle: nothing can be hit, so each pass stores nothing; it stops at its emission budget,
 * max_emitted_factor x target (exactly: 20 x 1000, the last batch cut there), and
 * photon_trace returns PM_EEMPTY with a message naming the pass and the budget. With
 * projection maps on, no cell of the light can reach the sphere (every emitted direction is
 * at least 88 degrees from the direction to it, and its bounding cone, widened by the light's
 * size, has a half-angle of about 13 degrees), so the caustic pass emits nothing and the
 * global pass alone fails. */
TEST(render_pm_runaway_trace) {
    scene s;
    json_err e;
    int rc;
    ASSERT_MSG(scene_load_text(&s, k_runaway_scene, &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(s.nlights, 2);
    ASSERT(s.tris[s.lights[0].tri].n.y > 0.999 && s.tris[s.lights[1].tri].n.y > 0.999);
    trace_opts o;
    trace_opts_init(&o, &s);
    o.global = o.shadow = 0;
    o.caustic = 1;
    o.caustic_target = 1000;
    o.max_emitted_factor = 20;
    o.projection = 0;
    o.quiet = 1;
    photon_maps m;
    char err[512];
    rc = photon_trace(&s, &o, &m, err, sizeof err);
    EXPECT_EQ_INT(rc, PM_EEMPTY);
    EXPECT_MSG(strstr(err, "photon tracing: Tracing caustic photons: no photon stored after 20000 "
                           "emitted") && strstr(err, "stopped by max_emitted_factor"),
               "%s", err);
    photon_maps_free(&m);

    o.global = o.shadow = 1;
    o.caustic = 0;
    o.global_target = 1000;
    rc = photon_trace(&s, &o, &m, err, sizeof err);
    EXPECT_EQ_INT(rc, PM_EEMPTY);
    EXPECT_MSG(strstr(err, "Tracing global photons: no photon stored after 20000 emitted"), "%s", err);
    photon_maps_free(&m);

    o.caustic = 1;
    o.projection = 1;
    rc = photon_trace(&s, &o, &m, err, sizeof err);
    EXPECT_EQ_INT(rc, PM_EEMPTY);
    EXPECT_EQ_INT(m.caustic_emitted, 0);
    EXPECT_EQ_INT(m.ncaustic, 0);
    photon_maps_free(&m);
    unsigned char cells[16 * 16];
    EXPECT_EQ_INT(projmap_cells(&s, 0, 16, cells), 0);
    scene_free(&s);
}

/* Run `render` on scene text with extra flags; exit status, stdout+stderr in out, and the
 * wall time in *secs. */
static int render_text(const char *name, const char *text, const char *flags, char *out, size_t cap,
                       double *secs) {
    char spath[1024], cmd[8192];
    snprintf(spath, sizeof spath, "%s/%s.json", pm_test_tmpdir(), name);
    if (write_file(spath, text) != 0) return -1;
    /* Run in the test's own directory: a render without -o writes out.png into the current
     * directory, and that must be the test's, never the checkout's. */
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' '%s' --quiet %s 2>&1", pm_test_tmpdir(),
             pm_test_build_dir(), spath, flags);
    double t0 = stats_now();
    int rc = pm_test_run(cmd, out, cap);
    *secs = stats_now() - t0;
    return rc;
}

/* The runaway scenes, each of which used to run for minutes, never end, or run out of
 * memory. Oracle: the pass budgets (photon_trace.h): a pass that stores nothing in 32 batches
 * (131072 photons, PASS_EMPTY_BATCHES)
 * ends with exit status 1 and says so; a photon path is cut at max_bounces and the stored
 * count stops within one path of the target. Each must end inside 300 s (on an idle machine each
 * takes a few seconds; the bound is wide because the machine is shared, at loads of 20 on 2
 * cores, and a runaway takes from 10 minutes to forever). */
TEST(render_pm_runaway_render) {
    char out[65536];
    double secs;
    /* The light facing nothing, every map forced on. */
    int rc = render_text("runaway", k_runaway_scene,
                         "--mode pm --pm global=true --pm shadow=true --pm caustics=true "
                         "--pm projection=false --pm global_photons=1000 --pm max_emitted_factor=20",
                         out, sizeof out, &secs);
    EXPECT_MSG(rc == 1, "exit %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "Tracing global photons: no photon stored after 20000 emitted: the "
                           "lights reach no surface that stores photons"),
               "%s", out);
    EXPECT_MSG(secs < 300, "%.1f s", secs);

    /* A point light inside a closed mirror sphere, caustics forced on (the plan turns them off). */
    char path[1024];
    snprintf(path, sizeof path, "%s/data/scenes/mirror_cage.json", pm_test_source_dir());
    char *cage = read_file(path, NULL);
    ASSERT(cage);
    rc = render_text("cage", cage, "--mode pm --pm caustics=true", out, sizeof out, &secs);
    EXPECT_MSG(rc == 1, "exit %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "Tracing caustic photons: no photon stored after 131072 emitted"), "%s", out);
    EXPECT_MSG(secs < 300, "%.1f s", secs);
    /* The same with the global map forced and an emission budget of 1e9 times the target:
     * the nothing-stored rule ends it, not the budget. */
    rc = render_text("cage", cage,
                     "--mode pm --pm global=true --pm max_emitted_factor=1e9 --pm global_photons=100000000",
                     out, sizeof out, &secs);
    EXPECT_MSG(rc == 1, "exit %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "Tracing global photons: no photon stored after 131072 emitted"), "%s", out);
    EXPECT_MSG(secs < 300, "%.1f s", secs);
    /* An emission factor beyond the supported range is an input error. */
    rc = render_text("cage", cage, "--mode pm --pm max_emitted_factor=1e300", out, sizeof out, &secs);
    EXPECT_MSG(rc == 2 && strstr(out, "max_emitted_factor"), "exit %d: %s", rc, out);
    /* Without forcing, the plan traces nothing, and the image is black (as in path tracing). */
    rc = render_text("cage", cage, "--mode pm --width 8 --height 8", out, sizeof out, &secs);
    EXPECT_MSG(rc == 0 && strstr(out, "caustics: off"), "exit %d: %s", rc, out);
    free(cage);

    /* The furnace with reflectance 1 and max_depth 100000: photons never die. 2000 asked:
     * the pass keeps whole photon paths up to the first that reaches 2000 (each path holds at
     * most max_bounces + 1 = 257 stores), so at most 2256 are stored, and it says the paths
     * were cut by the path-length budget. */
    snprintf(path, sizeof path, "%s/data/scenes/furnace.json", pm_test_source_dir());
    char *fur = read_file(path, NULL);
    ASSERT(fur);
    cJSON *doc = cJSON_Parse(fur);
    ASSERT(doc);
    cJSON_ReplaceItemInObject(cJSON_GetObjectItem(cJSON_GetObjectItem(doc, "materials"), "wall"),
                              "reflectance", cJSON_CreateNumber(1));
    cJSON_ReplaceItemInObject(cJSON_GetObjectItem(doc, "render"), "max_depth",
                              cJSON_CreateNumber(100000));
    char *text = cJSON_PrintUnformatted(doc);
    rc = render_text("furnace1", text,
                     "--mode pm --width 8 --height 8 --spp 1 --pm global_photons=2000", out,
                     sizeof out, &secs);
    EXPECT_MSG(rc == 0, "exit %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "cut by the path-length budget (photon_mapping.max_bounces = 256)"), "%s", out);
    long long stored = stat_in(out, "Global photons stored");
    EXPECT_MSG(stored >= 2000 && stored <= 2256, "stored %lld: %s", stored, out);
    EXPECT_MSG(secs < 300, "%.1f s", secs);
    free(text);
    cJSON_Delete(doc);
    free(fur);
}

/* ---- 5. skipped work shows as zero ------------------------------------------------------- */

/* Render a shipped scene tiny in pm mode; returns the exit status, output in buf. */
static int render_tiny(const char *scene_name, const char *extra, char *buf, size_t cap) {
    char cmd[8192];
    snprintf(cmd, sizeof cmd,
             "%s/render '%s/data/scenes/%s.json' --mode pm --width 16 --height 16 --spp 1 --quiet "
             "--pm global_photons=4000 --pm caustic_photons=2000 --pm gather_rays=4 %s",
             pm_test_build_dir(), pm_test_source_dir(), scene_name, extra);
    return pm_test_run(cmd, buf, cap);
}

/* Oracle: cornell_diffuse has nothing specular, so its plan line says caustics are off and
 * why, and every caustic counter (emitted, stored, saved by projection maps, estimates) is
 * printed as 0. Controls: cornell_spheres under the same flags has non-zero caustic
 * counters (the parsing can see them), and `--pm caustics=false` brings them to 0 with a
 * "forced" reason. */
TEST(render_pm_render_skipped_caustics_zero) {
    static char out[65536];
    char extra[4096];
    snprintf(extra, sizeof extra, "--hdr '%s/d.pfm'", pm_test_tmpdir());
    int rc = render_tiny("cornell_diffuse", extra, out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "\n  caustics: off (no specular surface)\n"), "%s", out);
    EXPECT_MSG(strstr(out, "\n  global: on ("), "%s", out);
    EXPECT_EQ_INT(stat_in(out, "Emitted, caustic pass"), 0);
    EXPECT_EQ_INT(stat_in(out, "Caustic photons stored"), 0);
    EXPECT_EQ_INT(stat_in(out, "Caustic emissions saved by the projection map"), 0);
    EXPECT_EQ_INT(stat_in(out, "Caustic estimates"), 0);
    EXPECT_MSG(stat_in(out, "Global photons stored") >= 4000, "%s", out);
    EXPECT_MSG(strstr(out, "; 0 caustic (from 0 emitted;"), "%s", out);

    rc = render_tiny("cornell_spheres", extra, out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "\n  caustics: on ("), "%s", out);
    EXPECT_MSG(stat_in(out, "Emitted, caustic pass") > 0, "%s", out);
    EXPECT_MSG(stat_in(out, "Caustic photons stored") >= 2000, "%s", out);
    EXPECT_MSG(stat_in(out, "Caustic estimates") > 0, "%s", out);

    snprintf(extra, sizeof extra, "--hdr '%s/s.pfm' --pm caustics=false", pm_test_tmpdir());
    rc = render_tiny("cornell_spheres", extra, out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "\n  caustics: off (forced by photon_mapping.caustics)\n"), "%s", out);
    EXPECT_EQ_INT(stat_in(out, "Emitted, caustic pass"), 0);
    EXPECT_EQ_INT(stat_in(out, "Caustic photons stored"), 0);
    EXPECT_EQ_INT(stat_in(out, "Caustic estimates"), 0);
}

/* Oracle: the render's own figures. glass_hole's caustic pass (a glass sphere lit only
 * through a 10 x 10 hole) cannot store 2000 photons within its emission budget, and the
 * pilot's few L S+ D stores join it: the budget message must give the whole map, pilot
 * included, as the "Photons:" line counts it ("only N of 2000 photons stored after E emitted
 * (the pilot's n stores and 8192 photons included)", N and E the line's caustic figures, n
 * the plan's caustics line's joined stores). */
TEST(render_pm_caustic_pilot_runaway_message) {
    static char out[65536];
    char extra[1024], want[512];
    snprintf(extra, sizeof extra, "--hdr '%s/g.pfm'", pm_test_tmpdir());
    int rc = render_tiny("glass_hole", extra, out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    const char *line = strstr(out, "\n  caustics: on ("), *eol = line ? strchr(line + 1, '\n') : NULL;
    const char *at = line ? strstr(line, "the pilot's ") : NULL;
    size_t n = 0, nc = 0;
    unsigned long long ne = 0, ce = 0;
    ASSERT_MSG(at && eol && at < eol &&
                   sscanf(at, "the pilot's %zu stores join the caustic map (its %llu photons", &n, &ne) == 2,
               "%s", out);
    const char *ph = strstr(out, "\nPhotons: ");
    ASSERT_MSG(ph && (ph = strstr(ph, "; ")) && sscanf(ph, "; %zu caustic (from %llu emitted", &nc, &ce) == 2, "%s",
               out);
    snprintf(want, sizeof want,
             "Tracing caustic photons: only %zu of 2000 photons stored after %llu emitted (the pilot's %zu stores "
             "and %llu photons included); stopped by the photon_mapping.",
             nc, ce, n, ne);
    EXPECT_MSG(n > 0 && nc < 2000 && strstr(out, want), "expected \"%s\" in %s", want, out);
}

/* Oracle: the rule of the caustic cap (photon_trace.h CAUSTIC CAP, pm_fit.c THE CAUSTIC
 * CAP, pm_preprocess.c THE CAUSTIC PROBE) and the render's own figures. glass_hole's caustic
 * map lies behind a wall the camera does not see through: at its defaults (the fit applies)
 * the first stage's caustic pass stops at the cap, max(min(4194304, width x height x spp),
 * 4 x the global pass's own emitted photons) of its own, plus the plan's 8192 pilot photons
 * that join it, exactly (the emission budget is exact), and says so with the floor it used
 * (the first stage traces 1/8 of the caustic target, THE CAUSTIC FLOOR in pm_fit.c;
 * max_emitted_factor 256, not a photon count, leaves the fit on and the cap the first limit).
 * Before THE CAUSTIC PROBE the floor was 4194304 at any image size (4.0M caustic photons
 * for a 16 x 16 x 1 render). Control: with caustic_photons set (no fit) the cap does not
 * apply: the same scene emits past 4194304 and stops by photon_mapping.max_emitted_factor. */
TEST(render_pm_caustic_cap_at_the_defaults_only) {
    static char out[65536];
    char cmd[8192];
    for (int set = 0; set < 2; set++) {
        snprintf(cmd, sizeof cmd,
                 "%s/render '%s/data/scenes/glass_hole.json' --mode pm --width 16 --height 16 --spp 1 --quiet "
                 "--pm gather_rays=4 %s --hdr '%s/cap%d.pfm'",
                 pm_test_build_dir(), pm_test_source_dir(),
                 set ? "--pm caustic_photons=66000" : "--pm max_emitted_factor=256",
                 pm_test_tmpdir(), set);
        int rc = pm_test_run(cmd, out, sizeof out);
        ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
        const char *line = strstr(out, "\n  caustics: on ("), *at = line ? strstr(line, "the pilot's ") : NULL;
        const char *gl = strstr(out, "\n  global: on ("), *gat = gl ? strstr(gl, "the pilot's ") : NULL;
        size_t n = 0, ng = 0, nc = 0, ngp = 0;
        unsigned long long ne = 0, ge = 0, ce = 0, gpe = 0;
        ASSERT_MSG(at && sscanf(at, "the pilot's %zu stores join the caustic map (its %llu photons", &n, &ne) == 2,
                   "%s", out);
        ASSERT_MSG(gat && sscanf(gat, "the pilot's %zu stores join the global map (its %llu photons", &ngp, &gpe) == 2,
                   "%s", out);
        const char *ph = strstr(out, "\nPhotons: ");
        ASSERT_MSG(ph && sscanf(ph, "\nPhotons: %zu global, %*u shadow-map (from %llu emitted); %zu caustic (from %llu "
                                    "emitted",
                                &ng, &ge, &nc, &ce) == 4,
                   "%s", out);
        double own = (double)(ge - gpe), floor = 16.0 * 16.0 * 1.0; /* the camera samples, under 4194304 */
        double cap = 4.0 * own > floor ? 4.0 * own : floor;
        if (!set) {
            EXPECT_MSG(strstr(out, "stopped by the caustic pass's cap (4 times the global pass's photons emitted, "
                                   "at least 256;"),
                       "%s", out);
            EXPECT_MSG((double)ce == cap + (double)ne, "caustic emitted %llu, cap %.0f (4 x %.0f) + pilot %llu", ce,
                       cap, own, ne);
        } else {
            cap = 4.0 * (double)ge > 4194304.0 ? 4.0 * (double)ge : 4194304.0;
            EXPECT_MSG(strstr(out, "stopped by the photon_mapping.max_emitted_factor budget"), "%s", out);
            EXPECT_MSG((double)ce > cap + (double)ne, "caustic emitted %llu, cap %.0f + pilot %llu", ce, cap, ne);
        }
    }
}

/* Oracle: the same rule in a scene with media (pm_volume.c's cap, which stops the caustic pass
 * of a scene with media at 4 x the global pass's photons, at least CAUSTIC_CAP_MIN or, at the
 * defaults, the render's camera samples: pm_preprocess.c, THE CAUSTIC PROBE). glass_of_smoke
 * (a smoke-filled glass: surface caustics rare) at 16 x 16 x 1 and its defaults: the caustic
 * pass stops under 4194304, between 4 x the global pass's surface photons emitted and 4 x all
 * it emitted (surface and volume), and says the cap's floor was the camera samples; the kept
 * first-stage maps get their "Photons (scene with media)" line (before, a kept first stage of
 * a scene with media printed none). Before THE CAUSTIC PROBE reached media, this render
 * emitted 4194304 caustic photons (8.6 CPU-s at 32 x 32 x 4; 1.9 after). Control: with
 * caustic_photons set (no fit) the floor is 4194304, exactly what the pass emits. */
TEST(render_pm_media_caustic_cap_at_the_defaults_only) {
    static char out[65536];
    char cmd[8192];
    for (int set = 0; set < 2; set++) {
        snprintf(cmd, sizeof cmd,
                 "%s/render '%s/data/scenes/glass_of_smoke.json' --mode pm --width 16 --height 16 --spp 1 %s "
                 "--hdr '%s/smoke%d.pfm' -o '%s/smoke%d.png' 2>&1",
                 pm_test_build_dir(), pm_test_source_dir(), set ? "--pm caustic_photons=66000" : "",
                 pm_test_tmpdir(), set, pm_test_tmpdir(), set);
        int rc = pm_test_run(cmd, out, sizeof out);
        ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
        const char *ph = strstr(out, "\nPhotons (scene with media): ");
        size_t ng = 0, nc = 0, nv = 0;
        unsigned long long ge = 0, ce = 0, ve = 0;
        ASSERT_MSG(ph && sscanf(ph, "\nPhotons (scene with media): %zu global (from %llu emitted), %zu caustic (from "
                                    "%llu emitted); volume: %zu (from %llu emitted)",
                                &ng, &ge, &nc, &ce, &nv, &ve) == 6,
                   "no photon line: %s", out);
        if (!set) {
            EXPECT_MSG(strstr(out, "stopped by the caustic pass's cap in a scene with media (4 times the global "
                                   "pass's photons emitted, at least the render's camera samples; pm_volume.c)"),
                       "%s", out);
            EXPECT_MSG(ce < 4194304ull && ce >= 4 * ge && ce <= 4 * (ge + ve),
                       "caustic emitted %llu: global %llu, volume %llu", ce, ge, ve);
        } else {
            EXPECT_MSG(strstr(out, "at least 4194304; pm_volume.c)"), "%s", out);
            EXPECT_MSG(ce == 4194304ull, "caustic emitted %llu, the floor 4194304 (global %llu)", ce, ge);
        }
    }
}

/* Oracle: the fault-injection hook PM_PLAN_TEST_ENOMEM (plan.c) makes one pilot pass fail as
 * if it had run out of memory. Before, run_pilot ignored photon_trace's code and the plan read
 * a pass cut short as evidence ("nothing reaches there"). Now plan_make returns PM_ENOMEM with
 * a message naming the pilot and leaves nothing to free (no pilot photons, no importance
 * table), and `render` exits non-zero with that message and writes no image: the global and
 * caustic pilots on cornell_spheres, the volume pilot on cornell_fog. Control: the same
 * plan_make without the hook returns 0 and keeps the pilots' photons. */
TEST(render_pm_plan_pilot_out_of_memory) {
    scene s;
    json_err e;
    ASSERT_MSG(load_shipped(&s, "cornell_spheres", &e) == 0, "%s", e.msg);
    photon_settings c;
    ASSERT_MSG(photon_settings_parse(&c, s.photon_mapping, &e) == 0, "%s", e.msg);
    render_plan p;
    char err[256];
    const char *which[] = {"global", "caustic"};
    for (int i = 0; i < 2; i++) {
        char want[128];
        snprintf(want, sizeof want, "plan: %s photon pilot: out of memory", which[i]);
        setenv("PM_PLAN_TEST_ENOMEM", which[i], 1);
        int rc = plan_make(&s, &c, 0, &p, err, sizeof err);
        unsetenv("PM_PLAN_TEST_ENOMEM");
        EXPECT_EQ_INT(rc, PM_ENOMEM);
        EXPECT_MSG(strcmp(err, want) == 0, "%s: \"%s\"", which[i], err);
        EXPECT_MSG(!p.pilot && !p.imp && !p.guide, "%s: the failed plan holds memory", which[i]);
        if (rc == 0) plan_free(&p);
    }
    err[0] = 'x';
    EXPECT_EQ_INT(plan_make(&s, &c, 0, &p, err, sizeof err), 0);
    EXPECT_MSG(err[0] == 0 && p.pilot, "control: err \"%s\", pilot photons %p", err, (void *)p.pilot);
    plan_free(&p);
    scene_free(&s);

    static char out[65536];
    const char *cases[][2] = {{"cornell_spheres", "global"}, {"cornell_spheres", "caustic"}, {"cornell_fog", "volume"}};
    for (int i = 0; i < 3; i++) {
        char cmd[4096], pfm[1024], want[128];
        snprintf(pfm, sizeof pfm, "%s/oom_%d.pfm", pm_test_tmpdir(), i);
        snprintf(cmd, sizeof cmd,
                 "PM_PLAN_TEST_ENOMEM=%s %s/render '%s/data/scenes/%s.json' --mode pm --width 4 --height 4 --spp 1 "
                 "--quiet --hdr '%s'",
                 cases[i][1], pm_test_build_dir(), pm_test_source_dir(), cases[i][0], pfm);
        int rc = pm_test_run(cmd, out, sizeof out);
        snprintf(want, sizeof want, "plan: %s photon pilot: out of memory\n", cases[i][1]);
        EXPECT_MSG(rc != 0 && rc != -1, "%s, %s pilot: exit %d", cases[i][0], cases[i][1], rc);
        EXPECT_MSG(strstr(out, want), "%s: expected \"%s\" in: %s", cases[i][0], want, out);
        EXPECT_MSG(access(pfm, F_OK) != 0, "%s: an image was written", cases[i][0]);
    }
}

/* Oracle: the pilots' path cap (plan.c pilot_bounces) and closed-form counts. A closed box of
 * reflectance 1 with max_depth 1e5 and --pm max_bounces 1e6: without the cap the pilot follows
 * each of its 8192 photons 1e5 bounces (minutes, or 8 GiB of stores). Capped at
 * PASS_MAX_BOUNCES, a lossless box keeps every photon to the cap, so the global pilot stores
 * exactly 8192 x 256 records after a diffuse bounce, and they do not join the pass (traced
 * with another max_bounces). The same box filled with lossless fog (sigma_s 1): the volume
 * pilot's scattering events are at most 8192 x (256 + 1). Control: cornell_box (max_depth 16,
 * below the cap) with max_bounces 1e6 keeps the user's value: its pilot photons join. */
TEST(render_pm_pilots_capped_in_lossless_scenes) {
    static char txt[4096];
    const char *box =
        "{\"camera\": {\"eye\": [5, 5, 1], \"look_at\": [5, 5, 9], \"fov_deg\": 50, \"width\": 8, \"height\": 8, "
        "\"spp\": 4}, \"materials\": {\"white\": {\"type\": \"lambert\", \"reflectance\": 1.0}, \"lamp\": {\"type\": "
        "\"lambert\", \"reflectance\": 1.0, \"emission\": 10.0}}, \"objects\": ["
        TEST_BOX10_QUADS ","
        "{\"type\": \"quad\", \"vertices\": [[0, 0, 0], [10, 0, 0], [10, 10, 0], [0, 10, 0]], \"material\": \"white\"}], "
        "\"render\": {\"max_depth\": 100000}";
    for (int fog = 0; fog < 2; fog++) {
        snprintf(txt, sizeof txt, "%s%s}", box, fog ? ", \"media\": {\"fog\": {\"sigma_s\": 1.0}}, \"medium\": \"fog\"" : "");
        scene s;
        json_err e;
        ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
        photon_settings c;
        photon_settings_defaults(&c);
        c.max_bounces = 1000000;
        c.progress = 0;
        render_plan p;
        char err[256];
        int rc = plan_make(&s, &c, 0, &p, err, sizeof err);
        ASSERT_MSG(rc == 0, "%s", err);
        if (!fog) {
            unsigned long long n = 0;
            const char *at = strstr(p.global.reason, "diffuse surfaces reflect onto each other: ");
            EXPECT_MSG(at && sscanf(at, "diffuse surfaces reflect onto each other: %llu photons stored", &n) == 1 &&
                           n == (unsigned long long)PLAN_PILOT_PHOTONS * PASS_MAX_BOUNCES,
                       "want %d x %d stores: %s", PLAN_PILOT_PHOTONS, PASS_MAX_BOUNCES, p.global.reason);
            EXPECT_MSG(strstr(p.global.reason, "do not join the global map: the pilot was traced with another "
                                               "max_depth or max_bounces"),
                       "%s", p.global.reason);
            printf("    lossless box: %llu pilot stores\n", n);
        } else {
            unsigned long long n = 0, np = 0;
            const char *at = strstr(p.volume.reason, "is lit by the lights: ");
            EXPECT_MSG(at && sscanf(at, "is lit by the lights: %llu scattering events of %llu pilot photons", &n, &np) == 2 &&
                           n > 0 && n <= np * (PASS_MAX_BOUNCES + 1ull),
                       "%s", p.volume.reason);
            printf("    lossless fog: %llu scattering events of %llu pilot photons\n", n, np);
        }
        plan_free(&p);
        scene_free(&s);
    }
    scene s;
    json_err e;
    ASSERT_MSG(load_shipped(&s, "cornell_box", &e) == 0, "%s", e.msg);
    photon_settings c;
    ASSERT_MSG(photon_settings_parse(&c, s.photon_mapping, &e) == 0, "%s", e.msg);
    c.max_bounces = 1000000;
    render_plan p;
    EXPECT_EQ_INT(plan_make(&s, &c, 0, &p, NULL, 0), 0);
    EXPECT_MSG(strstr(p.global.reason, "stores join the global map"), "%s", p.global.reason);
    plan_free(&p);
    scene_free(&s);
}

/* ---- 6. saved photon maps ------------------------------------------------------------------ */

/* DIR/NAME must load with pm_map_load and hold exactly the photons of `want` (n of them, in
 * the same order: maps are saved as traced, before a kd-tree reorders them), with the map
 * kind, emitted count and bucket size (0: no tree order) of the header right. */
static void check_saved(const char *dir, const char *name, const pm_photon *want, size_t n,
                        uint32_t kind, uint64_t emitted, uint32_t bucket) {
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    pm_photon *ph = NULL;
    pm_map_header h;
    int rc = pm_map_load(path, &ph, &h);
    EXPECT_MSG(rc == 0, "%s: %s", path, pm_strerror(rc));
    if (rc != 0) return;
    EXPECT_MSG(h.count == n, "%s: %llu photons, photon_trace stored %zu", name,
               (unsigned long long)h.count, n);
    EXPECT_EQ_INT(h.kind, kind);
    EXPECT_EQ_INT(h.emitted, emitted);
    EXPECT_EQ_INT(h.record_size, sizeof(pm_photon));
    EXPECT_EQ_INT(h.tree_bucket, bucket);
    if (h.count == n)
        EXPECT_MSG(n == 0 || memcmp(ph, want, n * sizeof *ph) == 0,
                   "%s: the saved photons are not the traced ones, in trace order", name);
    free(ph);
}

/* Oracle: photon_trace run in this process with the options `render` derives from the same
 * scene, seed and flags (the maps do not depend on the thread count, see above): the saved
 * files load with pm_map_load and hold exactly those photons in the same order, with the
 * right counts, kinds, emitted numbers and bucket sizes (0: saved before the trees).
 * Rendering from the saved maps is reproducible: two renders with the same seed give
 * bit-identical PFMs, and a different seed a different one. The image from the saved maps
 * equals the image of the run that traced them bit for bit. With 4000 caustic photons the
 * caustic pilot's stores join the caustic map (photon_trace.h, PILOT PHOTONS; the plan's
 * line says so): the saved caustic map holds them. Shadow photons are forced on (the plan
 * leaves them off, plan.h) so the shadow map is saved and loaded too. */
TEST(render_pm_save_load_round_trip) {
    static char out[65536];
    char dir[1024], extra[4096], a[1024], b[1024], c[1024], d[1024];
    snprintf(dir, sizeof dir, "%s/maps", pm_test_tmpdir());
    snprintf(a, sizeof a, "%s/traced.pfm", pm_test_tmpdir());
    snprintf(b, sizeof b, "%s/loaded.pfm", pm_test_tmpdir());
    snprintf(c, sizeof c, "%s/loaded_again.pfm", pm_test_tmpdir());
    snprintf(d, sizeof d, "%s/loaded_seed8.pfm", pm_test_tmpdir());
    snprintf(extra, sizeof extra, "--seed 7 --pm caustic_photons=4000 --pm shadow=true --hdr '%s' --save-photons '%s'", a, dir);
    int rc = render_tiny("cornell_spheres", extra, out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "Saved photon maps to"), "%s", out);

    /* The maps render traced (render_tiny's flags: 16 x 16, 4000 global photons; 4000
     * caustic), with its plan's importance table and pilot photons. */
    scene s;
    json_err e;
    ASSERT_MSG(load_shipped(&s, "cornell_spheres", &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(camera_resize(&s.cam, 16, 16), 0);
    s.settings.seed = 7;
    photon_settings cfg;
    ASSERT_MSG(photon_settings_parse(&cfg, s.photon_mapping, &e) == 0, "%s", e.msg);
    cfg.global_photons = cfg.caustic_photons = 4000;
    cfg.gather_rays = 4;
    cfg.force_shadow = PLAN_ON; /* --pm shadow=true: the shadow map is saved and loaded too */
    render_plan plan;
    EXPECT_EQ_INT(plan_make(&s, &cfg, 0, &plan, NULL, 0), 0);
    ASSERT_MSG(plan.imp && plan.pilot, "table %p, pilot photons %p", (void *)plan.imp, (void *)plan.pilot);
    trace_opts o;
    trace_opts_settings(&o, &s, &cfg);
    o.global = o.caustic = o.shadow = 1;
    o.quiet = 1;
    o.importance = plan.imp;
    o.reuse = plan.pilot;
    photon_maps m;
    char err[256];
    ASSERT_MSG(photon_trace(&s, &o, &m, err, sizeof err) == 0, "%s", err);
    char joined[160];
    snprintf(joined, sizeof joined, "the pilot's %zu stores join the caustic map (its %llu photons", m.pilot_stored[1],
             (unsigned long long)m.pilot_emitted[1]);
    EXPECT_MSG(m.pilot_stored[1] > 0 && strstr(out, joined), "expected \"%s\" in %s", joined, out);
    plan_free(&plan);
    scene_free(&s);
    char want[512];
    snprintf(want, sizeof want,
             "Photons: %zu global, %zu shadow-map (from %llu emitted); %zu caustic (from %llu emitted",
             m.nglobal, m.nshadow, (unsigned long long)m.global_emitted, m.ncaustic,
             (unsigned long long)m.caustic_emitted);
    EXPECT_MSG(strstr(out, want), "expected \"%s\" in %s", want, out);
    check_saved(dir, "global.pmap", m.global, m.nglobal, PM_MAP_GLOBAL, m.global_emitted, 0);
    check_saved(dir, "caustic.pmap", m.caustic, m.ncaustic, PM_MAP_CAUSTIC, m.caustic_emitted, 0);
    check_saved(dir, "shadow.pmap", m.shadow, m.nshadow, PM_MAP_SHADOW, m.global_emitted, 0);

    snprintf(extra, sizeof extra, "--seed 7 --pm caustic_photons=4000 --pm shadow=true --hdr '%s' --load-photons '%s'", b, dir);
    rc = render_tiny("cornell_spheres", extra, out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    snprintf(want, sizeof want, ": %zu global, %zu caustic, %zu shadow-map photons", m.nglobal,
             m.ncaustic, m.nshadow);
    EXPECT_MSG(strstr(out, "Loaded photon maps from") && strstr(out, want), "expected \"%s\" in %s",
               want, out);
    EXPECT_MSG(!strstr(out, "\nPhotons: "), "photons were traced, not loaded: %s", out);
    photon_maps_free(&m);
    snprintf(extra, sizeof extra, "--seed 7 --pm caustic_photons=4000 --pm shadow=true --hdr '%s' --load-photons '%s'", c, dir);
    rc = render_tiny("cornell_spheres", extra, out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    snprintf(extra, sizeof extra, "--seed 8 --pm caustic_photons=4000 --pm shadow=true --hdr '%s' --load-photons '%s'", d, dir);
    rc = render_tiny("cornell_spheres", extra, out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);

    size_t na, nb, nc, nd;
    char *ia = read_file(a, &na), *ib = read_file(b, &nb), *ic = read_file(c, &nc),
         *id = read_file(d, &nd);
    ASSERT(ia && ib && ic && id);
    EXPECT_MSG(nb == nc && memcmp(ib, ic, nb) == 0, "two renders from the same maps and seed differ");
    EXPECT_MSG(nb != nd || memcmp(ib, id, nb) != 0, "seed 8 gave the same image as seed 7");
    EXPECT_MSG(na == nb && memcmp(ia, ib, na) == 0,
               "the PFM rendered from the loaded maps differs from the traced one");
    free(ia);
    free(ib);
    free(ic);
    free(id);
    film f;
    ASSERT(film_read_pfm(&f, b) == 0);
    double sum = 0;
    for (int i = 0; i < f.width * f.height * 3; i++) sum += f.px[i];
    EXPECT_MSG(sum > 0 && isfinite(sum), "image sum %g", sum);
    film_free(&f);
}

/* ---- 7. photon mapping against path tracing ------------------------------------------------- */

static int render_to(const char *scene_name, const char *flags, const char *pfm, char *buf,
                     size_t cap) {
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "%s/render '%s/data/scenes/%s.json' --width 32 --height 32 --quiet "
             "--hdr '%s' %s", pm_test_build_dir(), pm_test_source_dir(), scene_name, pfm, flags);
    return pm_test_run(cmd, buf, cap);
}

/* Oracle: a path-traced render of cornell_spheres at 32x32 (4096 samples per pixel; the mean
 * of the image then has a standard error near 0.05%, of a wall about 0.2%). A photon-mapped
 * render (default maps, 256 samples, one gather ray each) must agree on the mean of the
 * whole image within 0.75% and on the mean of each wall, the floor and the ceiling within 4%
 * (the walls carry the photon maps' own noise: 0.1% to 2.3% over seeds). Before the final
 * gather read mirrored surfaces from the right side the image was 1.0% dark and the walls
 * down to -2.4% (so the image bound is the one that catches that bug). */
TEST(render_pm_agrees_with_path_tracing) {
    static char out[65536];
    char pt[1024], pm[1024], ids[1024];
    snprintf(pt, sizeof pt, "%s/pt.pfm", pm_test_tmpdir());
    snprintf(pm, sizeof pm, "%s/pm.pfm", pm_test_tmpdir());
    snprintf(ids, sizeof ids, "%s/ids.pfm", pm_test_tmpdir());
    int rc = render_to("cornell_spheres", PM_TEST_SANITIZED ? "--mode path --spp 1024 --seed 11"
                                                            : "--mode path --spp 4096 --seed 11",
                       pt, out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    rc = render_to("cornell_spheres", PM_TEST_SANITIZED ? "--mode pm --spp 64 --seed 12 --pm gather_rays=1"
                                                        : "--mode pm --spp 256 --seed 12 --pm gather_rays=1",
                   pm, out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    rc = render_to("cornell_spheres", "--mode objects --spp 256", ids, out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    film a, b, m;
    ASSERT_EQ_INT(film_read_pfm(&a, pm), 0);
    ASSERT_EQ_INT(film_read_pfm(&b, pt), 0);
    ASSERT_EQ_INT(film_read_pfm(&m, ids), 0);
    image_diff d;
    ASSERT_EQ_INT(image_compare(&a, &b, 0, 0, 0, 0, &d), 0);
    printf("    image: photon mapping %.5f, path tracing %.5f (%+.2f%%)\n", d.mean_a, d.mean_b,
           100 * d.rel_mean);
    EXPECT_MSG(fabs(d.rel_mean) <= 0.0075, "image mean off by %+.2f%%", 100 * d.rel_mean);
    static const char *names[] = {"floor", "ceiling", "back wall", "right wall", "left wall"};
    for (int id = 1; id <= 5; id++) {
        image_region r = {0, 0, 0, 0, &m, &id, 1};
        ASSERT_EQ_INT(image_compare_region(&a, &b, &r, &d), 0);
        EXPECT_MSG(d.npixels >= 50, "%s: only %ld pixels", names[id - 1], d.npixels);
        printf("    %-10s %+.2f%% (%ld pixels)\n", names[id - 1], 100 * d.rel_mean, d.npixels);
        EXPECT_MSG(fabs(d.rel_mean) <= 0.04, "%s mean off by %+.2f%%", names[id - 1], 100 * d.rel_mean);
    }
    film_free(&a);
    film_free(&b);
    film_free(&m);
}

/* Oracle: the furnace (data/scenes/furnace.json: inside a sphere that emits Le = 1 from both
 * sides and reflects rho = 0.5) has radiance Le / (1 - rho) = 2 everywhere. Photon mapping
 * gets it from direct light off the sphere light plus one final gather of the global map's
 * precomputed irradiance: the image mean within 1% and every pixel within 3% (the maps'
 * noise; measured 1.995 to 2.014 at 32 x 32, 64 samples). */
TEST(render_pm_furnace) {
    static char out[65536];
    char pfm[1024];
    snprintf(pfm, sizeof pfm, "%s/furnace.pfm", pm_test_tmpdir());
    int rc = render_to("furnace", PM_TEST_SANITIZED ? "--mode pm --spp 16 --pm global_photons=50000"
                                                    : "--mode pm --spp 64",
                       pfm, out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "\n  global: on ("), "%s", out);
    film f;
    ASSERT_EQ_INT(film_read_pfm(&f, pfm), 0);
    double sum = 0, lo = INFINITY, hi = -INFINITY;
    long n = (long)f.width * f.height;
    for (long i = 0; i < n; i++) {
        double v = (f.px[3 * i] + f.px[3 * i + 1] + f.px[3 * i + 2]) / 3;
        sum += v;
        lo = fmin(lo, v);
        hi = fmax(hi, v);
    }
    printf("    furnace, photon mapping: mean %.5f, pixels %.4f to %.4f (expected 2)\n", sum / n, lo, hi);
    EXPECT_NEAR(sum / n, 2.0, 0.02);
    EXPECT_MSG(lo >= 1.94 && hi <= 2.06, "pixels from %.4f to %.4f", lo, hi);
    film_free(&f);
}

/* ---- the settings table ------------------------------------------------------------------ */

/* Oracle: data/scenes/README.md as committed. Its settings table, between the markers, is
 * byte for byte what `render --help-settings=markdown` prints, so the documented keys,
 * defaults and ranges are the ones the program has (regenerate the table with that command
 * when a setting changes). */
TEST(render_settings_readme_table_is_generated) {
    char path[1024], cmd[2048], gen[1024];
    snprintf(path, sizeof path, "%s/data/scenes/README.md", pm_test_source_dir());
    snprintf(gen, sizeof gen, "%s/table.md", pm_test_tmpdir());
    snprintf(cmd, sizeof cmd, "%s/render --help-settings=markdown > '%s'", pm_test_build_dir(), gen);
    char out[256];
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    char *readme = read_file(path, NULL), *table = read_file(gen, NULL);
    ASSERT(readme && table);
    const char *begin = "<!-- settings table: render --help-settings=markdown -->\n";
    const char *end = "<!-- end of settings table -->";
    char *a = strstr(readme, begin), *b = a ? strstr(a, end) : NULL;
    ASSERT_MSG(a && b, "%s: the settings table's markers are missing", path);
    a += strlen(begin);
    *b = 0;
    EXPECT_MSG(strcmp(a, table) == 0,
               "%s: the settings table differs from `render --help-settings=markdown`; "
               "regenerate it\n--- README:\n%s--- generated:\n%s", path, a, table);
    free(readme);
    free(table);
}

/* Trim the spaces around s in place. */
static char *trim(char *s) {
    while (*s == ' ') s++;
    size_t n = strlen(s);
    while (n && s[n - 1] == ' ') s[--n] = 0;
    return s;
}

/* Parse {"key": value}: 0 and *c, or < 0 with e->msg. */
static int parse_one_setting(const char *key, const char *value, photon_settings *c, json_err *e) {
    char text[256];
    snprintf(text, sizeof text, "{\"%s\": %s}", key, value);
    cJSON *o = cJSON_Parse(text);
    if (!o) {
        snprintf(e->msg, sizeof e->msg, "bad JSON %s", text);
        return -100;
    }
    int rc = photon_settings_parse(c, o, e);
    cJSON_Delete(o);
    return rc;
}

/* Oracle: the documented table (`render --help-settings=markdown`), read as a user reads it.
 * Each documented default, written explicitly into "$.photon_mapping", gives exactly the
 * settings of an empty object; the ends of each documented range are accepted and values
 * just outside refused with a message naming the key's JSON path; each documented filter
 * name is accepted and another refused. */
TEST(render_settings_documented_defaults_and_ranges_hold) {
    char cmd[2048], gen[1024], out[256];
    snprintf(gen, sizeof gen, "%s/table.md", pm_test_tmpdir());
    snprintf(cmd, sizeof cmd, "%s/render --help-settings=markdown > '%s'", pm_test_build_dir(), gen);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    char *table = read_file(gen, NULL);
    ASSERT(table);
    photon_settings def, got;
    photon_settings_defaults(&def);
    json_err e;
    ASSERT_EQ_INT(photon_settings_parse(&got, NULL, &e), 0);
    EXPECT(memcmp(&got, &def, sizeof def) == 0);
    int rows = 0, ranges = 0;
    char *save = NULL;
    for (char *line = strtok_r(table, "\n", &save); line; line = strtok_r(NULL, "\n", &save)) {
        char key[64], tb[32], db[64], rb[64];
        if (sscanf(line, "| `%63[^`]` | %31[^|]| %63[^|]| %63[^|]|", key, tb, db, rb) != 4) continue;
        rows++;
        char *type = trim(tb), *dflt = trim(db), *range = trim(rb), path[128], v[64];
        snprintf(path, sizeof path, "$.photon_mapping.%s", key);
        if (strcmp(dflt, "automatic") != 0 && strcmp(dflt, "none") != 0) {
            int rc = parse_one_setting(key, dflt, &got, &e);
            EXPECT_MSG(rc == 0 && memcmp(&got, &def, sizeof def) == 0,
                       "%s: the documented default %s is not the default (%s)", key, dflt,
                       rc ? e.msg : "other settings");
        }
        double lo, hi;
        int integer = strcmp(type, "integer") == 0;
        int two = sscanf(range, "%lf to %lf", &lo, &hi) == 2;
        if (two || sscanf(range, ">= %lf", &lo) == 1) {
            ranges++;
            if (!two) hi = 1e6 > lo ? 1e6 : lo; /* any large value */
            double below = integer ? lo - 1 : lo - 1e-3 * (fabs(lo) > 1 ? fabs(lo) : 1);
            double above = integer ? hi + 1 : hi + 1e-3 * (fabs(hi) > 1 ? fabs(hi) : 1);
            double ok[2] = {lo, hi}, bad[2] = {below, above};
            for (int k = 0; k < 2; k++) {
                snprintf(v, sizeof v, "%.17g", ok[k]);
                EXPECT_MSG(parse_one_setting(key, v, &got, &e) == 0, "%s = %s refused: %s", key, v,
                           e.msg);
                if (k == 1 && !two) continue; /* no upper end */
                snprintf(v, sizeof v, "%.17g", bad[k]);
                int rc = parse_one_setting(key, v, &got, &e);
                EXPECT_MSG(rc < 0 && strstr(e.msg, path), "%s = %s: rc %d, '%s'", key, v, rc,
                           rc ? e.msg : "accepted");
            }
        } else if (strcmp(type, "string") == 0) {
            char names[64];
            snprintf(names, sizeof names, "%s", range);
            char *s2 = NULL;
            for (char *n = strtok_r(names, ", ", &s2); n; n = strtok_r(NULL, ", ", &s2)) {
                snprintf(v, sizeof v, "\"%s\"", n);
                EXPECT_MSG(parse_one_setting(key, v, &got, &e) == 0, "%s = %s refused: %s", key, v,
                           e.msg);
            }
            EXPECT(parse_one_setting(key, "\"no such name\"", &got, &e) < 0 && strstr(e.msg, path));
        }
    }
    free(table);
    EXPECT_MSG(rows >= 25 && ranges >= 15, "%d rows, %d with a numeric range", rows, ranges);
    /* And a key that is not in the table is refused by name. */
    EXPECT(parse_one_setting("k_globle", "1", &got, &e) < 0 && strstr(e.msg, "k_globle: unknown key"));
}
