/* test_render_scene.c: every scene-loader error case, through the render program.
 *
 * Oracle: the documented behaviour (data/scenes/README.md): exit status 2, a message that
 * names the line and column or the JSON path, and no output file left behind. A valid scene
 * renders with status 0 and writes both files.
 */
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "test.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"

#define CAM "\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 8, \"height\": 8, \"spp\": 1}"
#define MATS "\"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5}, \"e\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 1}}"
#define OK_OBJS "\"objects\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 1, \"material\": \"w\"}, {\"type\": \"quad\", \"vertices\": [[-1,3,-1],[1,3,-1],[1,3,1],[-1,3,1]], \"material\": \"e\"}]"

static int write_file(const char *path, const char *text) {
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    fputs(text, f);
    return fclose(f);
}

/* Run render on text; returns the exit status and the output in out. */
static int run_scene(const char *name, const char *text, char *out, size_t cap, int *png_exists) {
    char spath[1024], png[1024], cmd[4096];
    snprintf(spath, sizeof spath, "%s/%s.json", pm_test_tmpdir(), name);
    snprintf(png, sizeof png, "%s/%s.png", pm_test_tmpdir(), name);
    if (text && write_file(spath, text) != 0) return -100;
    snprintf(cmd, sizeof cmd, "%s/render '%s' -o '%s' --quiet 2>&1", pm_test_build_dir(), spath, png);
    int rc = pm_test_run(cmd, out, cap);
    *png_exists = access(png, F_OK) == 0;
    return rc;
}

typedef struct {
    const char *name, *text, *expect;
} bad_case;

TEST(render_scene_errors_exit_2) {
    static const bad_case cases[] = {
        {"syntax", "{\n  " CAM ",\n  \"materials\": {,\n}", "line 3, column 18: syntax error at ' \"materials\": {,>'"},
        {"truncated", "{\"camera\": {\"eye\": [0,0", "unexpected end of file"},
        {"empty", "", "line 1, column 1"},
        {"not_object", "[1, 2]", "$: expected an object, got an array"},
        {"missing_camera", "{" MATS ", " OK_OBJS "}", "$.camera: missing"},
        {"missing_eye", "{\"camera\": {\"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 8, \"height\": 8}, " MATS ", " OK_OBJS "}",
         "$.camera.eye: missing"},
        {"mistyped_eye", "{\"camera\": {\"eye\": \"here\", \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 8, \"height\": 8}, " MATS ", " OK_OBJS "}",
         "$.camera.eye: expected an array of 3 numbers, got a string"},
        {"mistyped_width", "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 8.5, \"height\": 8}, " MATS ", " OK_OBJS "}",
         "$.camera.width: expected an integer"},
        {"nonfinite", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 1e999, \"material\": \"w\"}]}",
         "$.objects[0].radius: not a finite number"},
        {"nonfinite_vec", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"sphere\", \"center\": [0,-1e400,0], \"radius\": 1, \"material\": \"w\"}]}",
         "$.objects[0].center[1]: not a finite number"},
        {"negative_radius", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": -2, \"material\": \"w\"}]}",
         "$.objects[0].radius: must be positive, got -2"},
        {"degenerate_tri", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"triangle\", \"vertices\": [[0,0,0],[1,1,1],[2,2,2]], \"material\": \"w\"}]}",
         "$.objects[0]: degenerate triangle"},
        {"degenerate_mesh", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"mesh\", \"vertices\": [[0,0,0],[1,0,0],[0,1,0]], \"triangles\": [[0,1,2],[0,1,1]], \"material\": \"w\"}]}",
         "$.objects[0].triangles[1]: degenerate triangle"},
        {"mesh_index", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"mesh\", \"vertices\": [[0,0,0],[1,0,0],[0,1,0]], \"triangles\": [[0,1,3]], \"material\": \"w\"}]}",
         "$.objects[0].triangles[0][2]: vertex index 3"},
        {"quad_count", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"quad\", \"vertices\": [[0,0,0],[1,0,0],[0,1,0]], \"material\": \"w\"}]}",
         "$.objects[0].vertices: expected 4 points, got 3"},
        {"quad_inward", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"quad\", \"vertices\": [[0,0,0],[4,0,0],[4,4,0],[3,1,0]], \"material\": \"w\"}]}",
         "$.objects[0].vertices: the quad's corner 3 turns inward"},
        {"camera_nowhere", "{\"camera\": {\"eye\": [1,2,3], \"look_at\": [1,2,3], \"fov_deg\": 40, \"width\": 8, \"height\": 8}, " MATS ", " OK_OBJS "}",
         "$.camera: the camera points nowhere"},
        {"camera_up_parallel", "{\"camera\": {\"eye\": [0,0,0], \"forward\": [0,2,0], \"fov_deg\": 40, \"width\": 8, \"height\": 8}, " MATS ", " OK_OBJS "}",
         "$.camera: the up vector is parallel"},
        {"camera_fov", "{\"camera\": {\"eye\": [0,0,0], \"forward\": [0,0,1], \"fov_deg\": 180, \"width\": 8, \"height\": 8}, " MATS ", " OK_OBJS "}",
         "$.camera.fov_deg: must be in (0, 180)"},
        {"unknown_material", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 1, \"material\": \"gold\"}]}",
         "$.objects[0].material: unknown material \"gold\""},
        {"bad_reflectance", "{" CAM ", \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": [0.5, 1.5, 0.5]}}, " OK_OBJS "}",
         "$.materials.w.reflectance: each component must be in [0, 1]"},
        {"bad_material_type", "{" CAM ", \"materials\": {\"w\": {\"type\": \"velvet\"}}, " OK_OBJS "}",
         "$.materials.w.type: unknown material type \"velvet\""},
        {"bad_light", "{" CAM ", " MATS ", " OK_OBJS ", \"lights\": [{\"type\": \"point\", \"position\": [0,0,0]}]}",
         "$.lights[0]: give exactly one of intensity"},
        {"zero_direction", "{" CAM ", " MATS ", " OK_OBJS ", \"lights\": [{\"type\": \"directional\", \"direction\": [0,0,0], \"irradiance\": 1}]}",
         "$.lights[0].direction: must not be the zero vector"},
        {"no_geometry", "{" CAM ", " MATS ", \"objects\": []}", "$.objects: the scene has no geometry"},
        {"bad_pm", "{" CAM ", " MATS ", " OK_OBJS ", \"photon_mapping\": 3}", "$.photon_mapping: expected an object"},
        /* The remaining validation paths of scene.c, one case each. */
        {"width_zero", "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 0, \"height\": 8}, " MATS ", " OK_OBJS "}",
         "$.camera.width: 0 is out of range [1, 16384]"},
        {"height_huge", "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 8, \"height\": 20000}, " MATS ", " OK_OBJS "}",
         "$.camera.height: 20000 is out of range [1, 16384]"},
        {"spp_zero", "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 8, \"height\": 8, \"spp\": 0}, " MATS ", " OK_OBJS "}",
         "$.camera.spp: 0 is out of range [1, "},
        {"look_and_forward", "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"forward\": [0,0,1], \"fov_deg\": 40, \"width\": 8, \"height\": 8}, " MATS ", " OK_OBJS "}",
         "$.camera: give either look_at or forward, not both"},
        {"fov_and_focal", "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"fov_deg\": 40, \"focal_length_mm\": 35, \"width\": 8, \"height\": 8}, " MATS ", " OK_OBJS "}",
         "$.camera: give either fov_deg or focal_length_mm, not both"},
        {"no_lens", "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"width\": 8, \"height\": 8}, " MATS ", " OK_OBJS "}",
         "$.camera.focal_length_mm: missing"},
        {"focal_negative", "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"focal_length_mm\": -35, \"width\": 8, \"height\": 8}, " MATS ", " OK_OBJS "}",
         "$.camera.focal_length_mm: must be positive, got -35"},
        {"sensor_zero", "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"focal_length_mm\": 35, \"sensor_width_mm\": 0, \"width\": 8, \"height\": 8}, " MATS ", " OK_OBJS "}",
         "$.camera.sensor_width_mm: must be positive, got 0"},
        {"up_zero", "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"up\": [0,0,0], \"fov_deg\": 40, \"width\": 8, \"height\": 8}, " MATS ", " OK_OBJS "}",
         "$.camera: the up vector is zero"},
        {"ior_zero", "{" CAM ", \"materials\": {\"w\": {\"type\": \"dielectric\", \"ior\": 0}}, " OK_OBJS "}",
         "$.materials.w.ior: must be positive, got 0"},
        {"sigma_negative", "{" CAM ", \"materials\": {\"w\": {\"type\": \"oren_nayar\", \"reflectance\": 0.5, \"sigma\": -1}}, " OK_OBJS "}",
         "$.materials.w.sigma: -1 is outside the supported range, 0 to 1.5708"},
        {"emission_negative", "{" CAM ", \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5, \"emission\": -1}}, " OK_OBJS "}",
         "$.materials.w.emission: must not be negative"},
        {"intensity_negative", "{" CAM ", " MATS ", " OK_OBJS ", \"lights\": [{\"type\": \"point\", \"position\": [0,0,0], \"intensity\": -1}]}",
         "$.lights[0].intensity: must not be negative"},
        {"light_type", "{" CAM ", " MATS ", " OK_OBJS ", \"lights\": [{\"type\": \"lamp\"}]}",
         "$.lights[0].type: unknown light type \"lamp\""},
        {"object_type", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"cone\", \"material\": \"w\"}]}",
         "$.objects[0].type: unknown object type \"cone\""},
        {"zero_radius", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 0, \"material\": \"w\"}]}",
         "$.objects[0].radius: must be positive, got 0"},
        {"short_center", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"sphere\", \"center\": [0,0], \"radius\": 1, \"material\": \"w\"}]}",
         "$.objects[0].center: expected an array of 3 numbers"},
        {"degenerate_quad", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"quad\", \"vertices\": [[0,0,0],[1,0,0],[1,1,0],[0,0,0]], \"material\": \"w\"}]}",
         "$.objects[0]: degenerate triangle"},
        {"empty_mesh", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"mesh\", \"vertices\": [], \"triangles\": [], \"material\": \"w\"}]}",
         "$.objects[0].triangles: empty mesh"},
        {"max_depth", "{" CAM ", " MATS ", " OK_OBJS ", \"render\": {\"max_depth\": -1}}",
         "$.render.max_depth: -1 is out of range"},
        {"clip_percent", "{" CAM ", " MATS ", " OK_OBJS ", \"image\": {\"clip_percent\": 200}}",
         "$.image.clip_percent: must be in [0, 100), got 200"},
        {"tone", "{" CAM ", " MATS ", " OK_OBJS ", \"image\": {\"tone\": \"sepia\"}}",
         "$.image.tone: expected \"filmic\" or \"srgb\", got \"sepia\""},
        {"medium_ior", "{" CAM ", " MATS ", " OK_OBJS ", \"medium_ior\": 0}", "$.medium_ior: must be positive, got 0"},
        {"light_power_overflow", "{" CAM ", " MATS ", " OK_OBJS ", \"lights\": [{\"type\": \"point\", \"position\": [0,0,0], \"power\": 1e308}]}",
         "$.lights[0]: its power is too large to represent"},
        {"sun_power_overflow", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 1e200, \"material\": \"w\"}], \"lights\": [{\"type\": \"directional\", \"direction\": [0,-1,0], \"irradiance\": 1}]}",
         "$.objects[0].radius: 1e+200 is outside the supported range of lengths, 1e-100 to 1e+100"},
        {"area_power_overflow", "{" CAM ", \"materials\": {\"e\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 1e307}}, \"objects\": [{\"type\": \"quad\", \"vertices\": [[-1,3,-1],[1,3,-1],[1,3,1],[-1,3,1]], \"material\": \"e\"}]}",
         "$.materials.e.emission: 1e+307 is outside the supported range, 0 to 1e+30"},
        {"repeated_key", "{\"camera\": {\"eye\": [0,0,-5], \"look_at\": [0,0,0], \"fov_deg\": 40, \"width\": 8, \"height\": 8, \"width\": 0}, " MATS ", " OK_OBJS "}",
         "$.camera: the key \"width\" is given more than once"},
        {"repeated_top_key", "{" CAM ", " MATS ", " OK_OBJS ", \"objects\": []}", "$: the key \"objects\" is given more than once"},
        {"repeated_nested_key", "{" CAM ", " MATS ", \"objects\": [{\"type\": \"sphere\", \"center\": [0,0,0], \"radius\": 1, \"radius\": -1, \"material\": \"w\"}]}",
         "$.objects[0]: the key \"radius\" is given more than once"},
        {"render_mode", "{" CAM ", " MATS ", " OK_OBJS ", \"render\": {\"mode\": \"bogus\"}}", "unknown mode \"bogus\""},
    };
    char out[8192];
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        int exists = 0;
        int rc = run_scene(cases[i].name, cases[i].text, out, sizeof out, &exists);
        EXPECT_MSG(rc == 2, "%s: exit %d, output: %s", cases[i].name, rc, out);
        EXPECT_MSG(strstr(out, cases[i].expect) != NULL, "%s: expected \"%s\" in: %s", cases[i].name,
                   cases[i].expect, out);
        EXPECT_MSG(!exists, "%s: an output file was left behind", cases[i].name);
    }
}

/* Oracle: a missing file and a bad option are errors with status 2 too; a valid scene gives
 * status 0 and writes the PNG. */
TEST(render_scene_cli_errors_and_success) {
    char out[8192], cmd[2048];
    int exists;
    snprintf(cmd, sizeof cmd, "%s/render %s/nope.json --quiet 2>&1", pm_test_build_dir(), pm_test_tmpdir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 2);
    ASSERT_MSG(strstr(out, "cannot open") != NULL, "%s", out);
    snprintf(cmd, sizeof cmd, "%s/render x.json --spp zero 2>&1", pm_test_build_dir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 2);
    int rc = run_scene("good", "{" CAM ", " MATS ", " OK_OBJS "}", out, sizeof out, &exists);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    ASSERT(exists);
    ASSERT_MSG(strstr(out, "Shadow rays") != NULL, "no statistics in: %s", out);
    /* --mode with an unknown name: status 2, the list of modes. */
    char spath[1024];
    snprintf(spath, sizeof spath, "%s/good.json", pm_test_tmpdir());
    snprintf(cmd, sizeof cmd, "%s/render '%s' --mode nosuch -o %s/m.png --quiet 2>&1", pm_test_build_dir(),
             spath, pm_test_tmpdir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 2);
    ASSERT_MSG(strstr(out, "unknown mode \"nosuch\"") && strstr(out, "path"), "%s", out);
    /* Not a terminal: plain progress lines, no carriage returns; and the summary. */
    snprintf(cmd, sizeof cmd, "%s/render '%s' --hdr %s/p.pfm 2>&1 < /dev/null", pm_test_build_dir(),
             spath, pm_test_tmpdir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    ASSERT_MSG(strstr(out, "Rendering: done in") && !strchr(out, '\r'), "%s", out);
    ASSERT_MSG(strstr(out, "Summary: wall time") && strstr(out, "M rays/s"), "%s", out);
}

/* Oracle: every shipped scene loads (the files in data/scenes are the documentation's
 * examples), and the published Cornell box has its light at y = 548.7 facing down. */
TEST(render_scene_shipped_scenes_load) {
    const char *names[] = {"cornell_box", "cornell_spheres", "cornell_diffuse", "cornell_point",
                           "sun_spheres", "furnace"};
    for (size_t i = 0; i < sizeof names / sizeof names[0]; i++) {
        char path[1024];
        snprintf(path, sizeof path, "%s/data/scenes/%s.json", pm_test_source_dir(), names[i]);
        scene s;
        json_err e;
        int rc = scene_load(&s, path, &e);
        ASSERT_MSG(rc == 0, "%s: %s", names[i], e.msg);
        ASSERT(s.nlights > 0 || strcmp(names[i], "furnace") == 0);
        if (strcmp(names[i], "cornell_box") == 0) {
            ASSERT_EQ_INT(s.nlights, 2);
            const triangle *t = &s.tris[s.lights[0].tri];
            ASSERT_NEAR(t->v0.y, 548.7, 1e-12);
            ASSERT_NEAR(t->n.y, -1.0, 1e-12);
            ASSERT_NEAR(t->area + s.tris[s.lights[1].tri].area, 130.0 * 105.0, 1e-6);
        }
        scene_free(&s);
    }
}
