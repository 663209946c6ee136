/* test_render_validate.c: the scene checks of the render program: misspelt keys and numbers out
 * of the range the renderer supports are input errors (exit 2, nothing written) whose message
 * names the scene file, the JSON path and the nearest known key or the supported range; and
 * scenes scaled far from unit size render as the unit scene does, or are refused.
 *
 * Each test writes its scenes into its own temporary directory as s.json (so every message
 * must name "s.json") and runs the render program there.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "test.h"
#include "../render/film.h"

/* A small closed box (floor, ceiling, walls; open front) with an area light in its
 * ceiling, one sphere and one point light. %s: extra top-level members (with a leading
 * comma) or "". Keys the tests misspell appear once each, so a text substitution can. */
static const char *k_base =
    "{\"camera\": {\"eye\": [0, 1, 3.5], \"look_at\": [0, 1, 0], \"fov_deg\": 50, \"width\": 8,"
    "  \"height\": 8, \"spp\": 1},"
    " \"materials\": {\"wall\": {\"type\": \"lambert\", \"reflectance\": 0.6},"
    "  \"rough\": {\"type\": \"oren_nayar\", \"reflectance\": 0.5, \"sigma\": 0.3},"
    "  \"lamp\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 5}},"
    " \"objects\": ["
    "  {\"type\": \"quad\", \"vertices\": [[-1,0,-1],[-1,0,1],[1,0,1],[1,0,-1]], \"material\": \"wall\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-1,2,-1],[1,2,-1],[1,2,1],[-1,2,1]], \"material\": \"wall\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-1,0,-1],[1,0,-1],[1,2,-1],[-1,2,-1]], \"material\": \"wall\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-1,0,-1],[-1,2,-1],[-1,2,1],[-1,0,1]], \"material\": \"wall\"},"
    "  {\"type\": \"quad\", \"vertices\": [[1,0,-1],[1,0,1],[1,2,1],[1,2,-1]], \"material\": \"wall\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-0.3,1.99,-0.3],[0.3,1.99,-0.3],[0.3,1.99,0.3],[-0.3,1.99,0.3]],"
    "   \"material\": \"lamp\"},"
    "  {\"type\": \"sphere\", \"center\": [0.3, 0.4, 0], \"radius\": 0.4, \"material\": \"rough\"}],"
    " \"lights\": [{\"type\": \"point\", \"position\": [-0.5, 1.5, 0.5], \"intensity\": 0.5}],"
    " \"render\": {\"mode\": \"path\", \"max_depth\": 8},"
    " \"image\": {\"exposure\": 1}"
    "%s}";

/* The base scene with the first `from` replaced by `to` and `extra` members added. */
static char *scene_text(const char *from, const char *to, const char *extra) {
    static char buf[8192];
    char tmp[8192];
    snprintf(tmp, sizeof tmp, k_base, extra ? extra : "");
    const char *at = from ? strstr(tmp, from) : NULL;
    if (!at) {
        snprintf(buf, sizeof buf, "%s", tmp);
        return buf;
    }
    snprintf(buf, sizeof buf, "%.*s%s%s", (int)(at - tmp), tmp, to, at + strlen(from));
    return buf;
}

/* Write text to s.json in the test directory and run render on it with args; the exit
 * status, messages (stdout and stderr) in out. */
static int render_text(const char *text, const char *args, char *out, size_t cap) {
    char path[1024], cmd[4096];
    snprintf(path, sizeof path, "%s/s.json", pm_test_tmpdir());
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    fputs(text, f);
    fclose(f);
    snprintf(cmd, sizeof cmd, "cd '%s' && timeout 120 '%s/render' s.json --quiet --hdr o.pfm %s 2>&1",
             pm_test_tmpdir(), pm_test_build_dir(), args);
    return pm_test_run(cmd, out, cap);
}

/* Expect exit 2 and the message "render: s.json: " + msg, and no image written. */
static void expect_error(const char *text, const char *args, const char *msg) {
    char out[16384], want[1024], pfm[1024];
    snprintf(pfm, sizeof pfm, "%s/o.pfm", pm_test_tmpdir());
    remove(pfm);
    int rc = render_text(text, args, out, sizeof out);
    snprintf(want, sizeof want, "render: s.json: %s", msg);
    EXPECT_MSG(rc == 2, "exit %d (want 2) for %s: %s", rc, msg, out);
    EXPECT_MSG(strstr(out, want) != NULL, "want '%s', got: %s", want, out);
    FILE *f = fopen(pfm, "rb");
    EXPECT_MSG(f == NULL, "an image was written for %s", msg);
    if (f) fclose(f);
}

/* Oracle: the scene format (data/scenes/README.md): the known keys of each object. The base
 * scene renders (exit 0); each misspelling is an error naming the file, the JSON path and the
 * nearest known key, wherever it is. A key of another material type is unknown for this type
 * and the message lists the known ones. */
TEST(render_validate_typo_everywhere) {
    char out[16384];
    int rc = render_text(scene_text(NULL, NULL, NULL), "", out, sizeof out);
    ASSERT_MSG(rc == 0, "the base scene: exit %d: %s", rc, out);
    expect_error(scene_text("\"emission\"", "\"emision\"", NULL), "",
                 "$.materials.lamp.emision: unknown key (did you mean \"emission\"?)");
    expect_error(scene_text("\"radius\"", "\"raduis\"", NULL), "",
                 "$.objects[6].raduis: unknown key (did you mean \"radius\"?)");
    expect_error(scene_text("\"position\"", "\"positon\"", NULL), "",
                 "$.lights[0].positon: unknown key (did you mean \"position\"?)");
    expect_error(scene_text("\"look_at\"", "\"lookat\"", NULL), "",
                 "$.camera.lookat: unknown key (did you mean \"look_at\"?)");
    expect_error(scene_text("\"max_depth\"", "\"max_dept\"", NULL), "",
                 "$.render.max_dept: unknown key (did you mean \"max_depth\"?)");
    expect_error(scene_text("\"exposure\"", "\"exposre\"", NULL), "",
                 "$.image.exposre: unknown key (did you mean \"exposure\"?)");
    expect_error(scene_text("\"lights\"", "\"ligths\"", NULL), "",
                 "$.ligths: unknown key (did you mean \"lights\"?)");
    expect_error(scene_text("\"material\": \"wall\"}", "\"materal\": \"wall\"}", NULL), "",
                 "$.objects[0].materal: unknown key (did you mean \"material\"?)");
    expect_error(scene_text(NULL, NULL, ", \"media\": {\"fog\": {\"sigmaa\": 0.1}}"), "",
                 "$.media.fog.sigmaa: unknown key (did you mean \"sigma_a\"?)");
    expect_error(scene_text("\"reflectance\": 0.6", "\"reflectance\": 0.6, \"sigma\": 0.2", NULL), "",
                 "$.materials.wall.sigma: unknown key of a lambert material (known: type, "
                 "reflectance, emission, two_sided, comment)");
}

/* Oracle: the photon-mapping settings table. "photon_mapping" is checked in every mode (here
 * path tracing, which does not use it): a misspelt key in the file names the file and the
 * JSON path; a misspelt or out-of-range --pm option names the option, not a JSON path. */
TEST(render_validate_photon_mapping_in_every_mode) {
    char out[16384];
    expect_error(scene_text(NULL, NULL, ", \"photon_mapping\": {\"k_globl\": 20}"), "--mode path",
                 "$.photon_mapping.k_globl: unknown key (did you mean \"k_global\"?)");
    expect_error(scene_text(NULL, NULL, ", \"photon_mapping\": {\"k_global\": 0}"), "--mode path",
                 "$.photon_mapping.k_global: 0 is out of range [1, 10000]");
    int rc = render_text(scene_text(NULL, NULL, NULL), "--mode path --pm k_globl=20", out, sizeof out);
    EXPECT_MSG(rc == 2 && strstr(out, "render: --pm k_globl: unknown key (did you mean \"k_global\"?)") &&
                   !strstr(out, "$.photon_mapping"),
               "exit %d: %s", rc, out);
    rc = render_text(scene_text(NULL, NULL, NULL), "--mode path --pm k_global=0", out, sizeof out);
    EXPECT_MSG(rc == 2 && strstr(out, "render: --pm k_global: 0 is out of range [1, 10000]"), "exit %d: %s",
               rc, out);
}

/* Oracle: the files themselves. Every shipped scene still loads under the one rule for
 * unknown keys (exit 0 at 2x2 pixels, 1 sample, path tracing); the Tungsten scene among them
 * is converted by render/tungsten.c, which skips Tungsten keys that do not change the image
 * (with a warning) and refuses those that would. */
TEST(render_validate_shipped_scenes_load) {
    char cmd[4096], out[16384];
    snprintf(cmd, sizeof cmd,
             "cd '%s' && for f in '%s'/data/scenes/*.json; do timeout 60 '%s/render' \"$f\" --mode path "
             "--width 2 --height 2 --spp 1 --quiet --hdr o.pfm >log.txt 2>&1 || { echo \"FAILED $f\"; "
             "cat log.txt; }; done; echo done",
             pm_test_tmpdir(), pm_test_source_dir(), pm_test_build_dir());
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 0 && strstr(out, "done") && !strstr(out, "FAILED"), "%s", out);
}
