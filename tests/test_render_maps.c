/* test_render_maps.c: saved photon maps (--save-photons / --load-photons) and what they
 * promise in render/photons/photon_maps.h and render/scene/scene_hash.h.
 *
 * Oracles: the stamp's definition (photon_maps.h MAP FILES, scene_hash.h): every field that
 * shapes photons changes it, one at a time, and every field that does not leaves it equal;
 * the exit status and message render/app/main.c documents for bad input (2, naming the file);
 * and byte equality: the image rendered from loaded maps is the traced run's, and a refused
 * run leaves no output file. Renders are 16x16 with a few thousand photons (well under a
 * second each). Scenes with media (cornell_fog, volumetric_caustic) save and load their
 * volume maps too; maps stamped by another tracer version are refused like other settings.
 */
#define _GNU_SOURCE
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "photonmap/mapfile.h"
#include "render/photons/photon_maps.h"
#include "render/load/scene_load.h"
#include "render/scene/scene.h"
#include "render/scene/scene_hash.h"
#include "test.h"
#include "test_render_run.h"

/* shadow=true: the plan leaves shadow photons off by default (plan.h); these tests save and
 * load all three surface maps, so they force them (a later --pm shadow=false still wins). */
#define SMALL "--width 16 --height 16 --spp 1 --quiet --seed 3 --pm global_photons=3000 " \
              "--pm caustic_photons=1500 --pm gather_rays=1 --pm shadow=true"

static char g_out[1 << 16];

/* render SCENE (a path) --mode pm SMALL extra, in the test directory. */
static int run_pm(const char *scene_path, const char *extra) {
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "timeout 120 '%s/render' '%s' --mode pm " SMALL " %s",
             pm_test_build_dir(), scene_path, extra);
    return rt_run(cmd, g_out, sizeof g_out);
}

static const char *shipped(const char *name) {
    static char p[1024];
    snprintf(p, sizeof p, "%s/data/scenes/%s.json", pm_test_source_dir(), name);
    return p;
}

/* A copy of a shipped scene with the first `from` replaced by `to`, in the test directory
 * under name. Returns its path (NULL if `from` is not in the file). */
static const char *edited_copy(const char *base, const char *name, const char *from, const char *to) {
    char *text = rt_slurp(shipped(base), NULL);
    if (!text) return NULL;
    char *at = strstr(text, from);
    if (!at) {
        free(text);
        return NULL;
    }
    const char *path = rt_path(name);
    FILE *f = fopen(path, "w");
    if (!f) {
        free(text);
        return NULL;
    }
    fwrite(text, 1, (size_t)(at - text), f);
    fputs(to, f);
    fputs(at + strlen(from), f);
    fclose(f);
    free(text);
    return path;
}

static int exists(const char *name) { return access(rt_path(name), F_OK) == 0; }

/* The maps of cornell_spheres, saved once per test into DIR "maps", with the traced image. */
static void save_maps(void) {
    int rc = run_pm(shipped("cornell_spheres"), "--save-photons maps --hdr traced.pfm");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    ASSERT(exists("maps/global.pmap") && exists("maps/caustic.pmap") && exists("maps/shadow.pmap"));
}

/* A refused load: exit 2, the message has each of want (NULL-terminated), no output file. */
static void expect_refused(const char *scene_path, const char *extra, const char *const *want) {
    unlink(rt_path("out.png"));
    unlink(rt_path("out.pfm"));
    char args[2048];
    snprintf(args, sizeof args, "%s -o out.png --hdr out.pfm", extra);
    int rc = run_pm(scene_path, args);
    EXPECT_MSG(rc == 2, "%s: exit %d, want 2: %s", extra, rc, g_out);
    for (int i = 0; want[i]; i++) EXPECT_MSG(strstr(g_out, want[i]), "%s: no \"%s\" in: %s", extra, want[i], g_out);
    EXPECT_MSG(!exists("out.png") && !exists("out.pfm"), "%s: an output was written on refusal", extra);
    EXPECT_MSG(!strstr(g_out, "\nPhotons: "), "%s: photons were traced instead: %s", extra, g_out);
}

/* Same scene and settings: accepted, and the image is the traced one bit for bit; so are
 * runs that change only what the camera pass reads (image size, samples, seed, k, gather
 * rays: not in the stamp), and a copy of the scene elsewhere with another description and
 * camera size (the scene hash is of the loaded scene, not of the file). */
TEST(render_maps_same_scene_is_accepted) {
    save_maps();
    int rc = run_pm(shipped("cornell_spheres"), "--load-photons maps --hdr loaded.pfm");
    EXPECT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    EXPECT_MSG(strstr(g_out, "Loaded photon maps from maps"), "%s", g_out);
    EXPECT_MSG(!strstr(g_out, "warning"), "%s", g_out);
    EXPECT_MSG(rt_same_file("traced.pfm", "loaded.pfm"), "the image from the loaded maps differs");
    const char *camera_only[] = {"--width 20 --height 12", "--spp 4", "--seed 9",
                                 "--pm k_global=50 --pm k_caustic=30", "--pm gather_rays=3",
                                 "--pm filter=gauss", "--mode preview"};
    for (size_t i = 0; i < sizeof camera_only / sizeof *camera_only; i++) {
        char args[512];
        snprintf(args, sizeof args, "--load-photons maps -o c%zu.png %s", i, camera_only[i]);
        rc = run_pm(shipped("cornell_spheres"), args);
        /* Preview traces the same maps in this scene (the plan's choice is in the stamp). */
        EXPECT_MSG(rc == 0 && strstr(g_out, "Loaded photon maps") && !strstr(g_out, "warning"),
                   "%s: exit %d: %s", camera_only[i], rc, g_out);
    }
    const char *moved = edited_copy("cornell_spheres", "moved.json", "Jensen's Cornell box",
                                    "Another description of the box");
    ASSERT(moved);
    const char *resized = edited_copy("cornell_spheres", "resized.json", "\"width\": 512", "\"width\": 300");
    ASSERT(resized);
    rc = run_pm(moved, "--load-photons maps -o m.png");
    EXPECT_MSG(rc == 0 && !strstr(g_out, "warning"), "moved copy: exit %d: %s", rc, g_out);
    rc = run_pm(resized, "--load-photons maps -o r.png");
    EXPECT_MSG(rc == 0 && !strstr(g_out, "warning"), "camera width edited: exit %d: %s", rc, g_out);
}

/* An edited scene (a wall's reflectance, a sphere's radius, the glass's index) and another
 * scene are refused with exit 2, naming global.pmap (the first file checked); forced, each is
 * rendered with one warning per map file. */
TEST(render_maps_other_scene_is_refused_unless_forced) {
    save_maps();
    const char *edits[][2] = {{"0.725", "0.724"}, {"\"radius\": 100", "\"radius\": 101"},
                              {"\"ior\": 1.5", "\"ior\": 1.45"}};
    for (size_t i = 0; i < sizeof edits / sizeof *edits; i++) {
        char name[64];
        snprintf(name, sizeof name, "edit%zu.json", i);
        const char *p = edited_copy("cornell_spheres", name, edits[i][0], edits[i][1]);
        ASSERT_MSG(p, "%s not in the scene", edits[i][0]);
        const char *want[] = {"cannot load photon maps", "maps/global.pmap",
                              "traced for another scene", "--force-load-photons", NULL};
        expect_refused(p, "--load-photons maps", want);
    }
    const char *want[] = {"maps/global.pmap", "traced for another scene", NULL};
    expect_refused(shipped("cornell_box"), "--load-photons maps", want);

    const char *p = edited_copy("cornell_spheres", "forced.json", "0.725", "0.724");
    ASSERT(p);
    int rc = run_pm(p, "--load-photons maps --force-load-photons -o forced.png");
    EXPECT_MSG(rc == 0 && exists("forced.png"), "forced: exit %d: %s", rc, g_out);
    const char *files[] = {"maps/global.pmap", "maps/caustic.pmap", "maps/shadow.pmap"};
    for (int i = 0; i < 3; i++) {
        char w[256];
        snprintf(w, sizeof w, "warning: force_load_photons: %s was traced for another scene", files[i]);
        EXPECT_MSG(strstr(g_out, w), "no \"%s\" in %s", w, g_out);
    }
    /* The scene's own photon_mapping key forces too. */
    rc = run_pm(p, "--load-photons maps --pm force_load_photons=true -o forced2.png");
    EXPECT_MSG(rc == 0 && strstr(g_out, "used anyway"), "exit %d: %s", rc, g_out);
}

/* Settings that shape the photons (targets, budgets, projection, importance-driven emission,
 * max_depth, the plan's choice of maps) are refused; forced they load. */
TEST(render_maps_other_settings_are_refused) {
    save_maps();
    const char *shaping[] = {"--pm global_photons=3001", "--pm caustic_photons=1000",
                             "--pm max_bounces=7", "--pm max_emitted_factor=32",
                             "--pm max_memory_mb=512", "--pm max_emitted=1e9",
                             "--pm projection=false", "--pm projection_cells=32",
                             "--pm caustics=false", "--pm shadow=false",
                             "--pm importance_paths=4096", "--pm importance_defensive=0.5"};
    for (size_t i = 0; i < sizeof shaping / sizeof *shaping; i++) {
        char args[512];
        snprintf(args, sizeof args, "--load-photons maps %s", shaping[i]);
        const char *want[] = {"maps/global.pmap", "traced with other photon settings", NULL};
        expect_refused(shipped("cornell_spheres"), args, want);
    }
    int rc = run_pm(shipped("cornell_spheres"),
                    "--load-photons maps --pm global_photons=3001 --force-load-photons -o f.png");
    EXPECT_MSG(rc == 0 && strstr(g_out, "other photon settings") && strstr(g_out, "used anyway"),
               "exit %d: %s", rc, g_out);
}

static int copy_file(const char *from, const char *to) {
    size_t n;
    char *b = rt_slurp(rt_path(from), &n);
    if (!b) return -1;
    FILE *f = fopen(rt_path(to), "wb");
    int ok = f && fwrite(b, 1, n, f) == n;
    if (f && fclose(f) != 0) ok = 0;
    free(b);
    return ok ? 0 : -1;
}

/* Missing, corrupt, truncated, unstamped and wrong-kind files: exit 2 naming the file, no
 * output. Forcing does not load a wrong kind or a damaged file; it does load an unstamped
 * (version-1) map. */
TEST(render_maps_bad_files_exit_2) {
    save_maps();
    const char *sc = shipped("cornell_spheres");
    const char *w_nodir[] = {"cannot load photon maps from nowhere: no such directory", NULL};
    expect_refused(sc, "--load-photons nowhere", w_nodir);
    expect_refused(sc, "--load-photons nowhere --force-load-photons", w_nodir);
    FILE *f = fopen(rt_path("plainfile"), "w");
    ASSERT(f);
    fputs("x", f);
    fclose(f);
    const char *w_notdir[] = {"plainfile: not a directory", NULL};
    expect_refused(sc, "--load-photons plainfile", w_notdir);

    /* Each file in turn: missing, truncated by one byte, garbage. */
    const char *names[] = {"global.pmap", "caustic.pmap", "shadow.pmap"};
    ASSERT_EQ_INT(mkdir(rt_path("bad"), 0755), 0);
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 3; j++) {
            char from[64], to[64];
            snprintf(from, sizeof from, "maps/%s", names[j]);
            snprintf(to, sizeof to, "bad/%s", names[j]);
            ASSERT_EQ_INT(copy_file(from, to), 0);
        }
        char file[64], want[128];
        snprintf(file, sizeof file, "bad/%s", names[i]);
        unlink(rt_path(file));
        snprintf(want, sizeof want, "bad/%s: No such file or directory", names[i]);
        const char *w1[] = {want, NULL};
        expect_refused(sc, "--load-photons bad --force-load-photons", w1);

        char from[64];
        snprintf(from, sizeof from, "maps/%s", names[i]);
        ASSERT_EQ_INT(copy_file(from, file), 0);
        struct stat sb;
        ASSERT_EQ_INT(stat(rt_path(file), &sb), 0);
        ASSERT_EQ_INT(truncate(rt_path(file), sb.st_size - 1), 0);
        snprintf(want, sizeof want, "bad/%s: not a photon-map file, or a truncated or corrupt one", names[i]);
        const char *w2[] = {want, NULL};
        expect_refused(sc, "--load-photons bad --force-load-photons", w2);

        f = fopen(rt_path(file), "w");
        ASSERT(f);
        fputs("{\"this is\": \"not a photon map\"}\n", f);
        fclose(f);
        expect_refused(sc, "--load-photons bad", w2);
    }

    /* Wrong kind: the caustic map under the global map's name, even forced. */
    ASSERT_EQ_INT(copy_file("maps/caustic.pmap", "bad/global.pmap"), 0);
    ASSERT_EQ_INT(copy_file("maps/caustic.pmap", "bad/caustic.pmap"), 0);
    ASSERT_EQ_INT(copy_file("maps/shadow.pmap", "bad/shadow.pmap"), 0);
    const char *w_kind[] = {"bad/global.pmap holds a caustic map, not a global map", NULL};
    expect_refused(sc, "--load-photons bad", w_kind);
    expect_refused(sc, "--load-photons bad --force-load-photons", w_kind);

    /* Unstamped: each file rewritten as version 1 (version word 1, bytes 40..63 zero). */
    for (int j = 0; j < 3; j++) {
        char from[64], to[64];
        snprintf(from, sizeof from, "maps/%s", names[j]);
        snprintf(to, sizeof to, "bad/%s", names[j]);
        ASSERT_EQ_INT(copy_file(from, to), 0);
        f = fopen(rt_path(to), "r+b");
        ASSERT(f);
        const unsigned char one[4] = {1, 0, 0, 0}, zeros[24] = {0};
        fseek(f, 8, SEEK_SET);
        fwrite(one, 1, 4, f);
        fseek(f, 40, SEEK_SET);
        fwrite(zeros, 1, 24, f);
        fclose(f);
    }
    const char *w_v1[] = {"bad/global.pmap carries no scene or settings stamp (a version-1 map file", NULL};
    expect_refused(sc, "--load-photons bad", w_v1);
    int rc = run_pm(sc, "--load-photons bad --force-load-photons --hdr v1.pfm");
    EXPECT_MSG(rc == 0 && strstr(g_out, "carries no scene or settings stamp"), "exit %d: %s", rc, g_out);
    EXPECT_MSG(rt_same_file("v1.pfm", "traced.pfm"), "the version-1 maps gave another image");
}

/* The saved headers: kind per file, tags = (scene_transport_hash of the scene as loaded, the
 * settings hash of map_stamp_make with the settings and plan render used), the current format
 * version (PM_FILE_VERSION, 3: with the checksum). */
TEST(render_maps_headers_carry_kind_and_stamp) {
    save_maps();
    scene s;
    json_err e;
    ASSERT_MSG(scene_load(&s, shipped("cornell_spheres"), &e) == 0, "%s", e.msg);
    s.settings.seed = 3;
    photon_settings cfg;
    ASSERT(photon_settings_parse(&cfg, NULL, &e) == 0);
    cfg.global_photons = 3000;
    cfg.caustic_photons = 1500;
    map_stamp want;
    map_stamp_make(&s, &cfg, 1, 1, 1, &want); /* the printed plan: all three on (checked) */
    EXPECT_MSG(strstr(g_out, "caustics: on") && strstr(g_out, "global: on") &&
               strstr(g_out, "shadow photons: on"), "%s", g_out);
    scene_free(&s);
    const char *names[] = {"maps/global.pmap", "maps/caustic.pmap", "maps/shadow.pmap"};
    const uint32_t kinds[] = {PM_MAP_GLOBAL, PM_MAP_CAUSTIC, PM_MAP_SHADOW};
    for (int i = 0; i < 3; i++) {
        pm_photon *ph = NULL;
        pm_map_header h;
        ASSERT_EQ_INT(pm_map_load(rt_path(names[i]), &ph, &h), 0);
        EXPECT_EQ_INT(h.kind, kinds[i]);
        EXPECT_EQ_INT(h.version, PM_FILE_VERSION);
        EXPECT_MSG(h.tag[0] == want.scene && h.tag[1] == want.settings,
                   "%s: tags %016llx %016llx, want %016llx %016llx", names[i],
                   (unsigned long long)h.tag[0], (unsigned long long)h.tag[1],
                   (unsigned long long)want.scene, (unsigned long long)want.settings);
        free(ph);
    }
}

/* ---- the hashes themselves ---------------------------------------------------------------- */

static const char *k_base =
    "{\"description\": \"D\", \"camera\": {\"eye\": [0, 1, -5], \"look_at\": [0, 1, 0], "
    "\"fov_deg\": 40, \"width\": 32, \"height\": 24, \"spp\": 4},"
    " \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": [0.5, 0.5, 0.5]},"
    " \"g\": {\"type\": \"dielectric\", \"ior\": 1.5},"
    " \"l\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": [4, 4, 4]}},"
    " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-3, 0, -3], [-3, 0, 3], [3, 0, 3], [3, 0, -3]],"
    " \"material\": \"w\"}, {\"type\": \"sphere\", \"center\": [0, 1, 0], \"radius\": 1, \"material\": \"g\"},"
    " {\"type\": \"quad\", \"vertices\": [[-1, 4, -1], [1, 4, -1], [1, 4, 1], [-1, 4, 1]], \"material\": \"l\"}],"
    " \"lights\": [{\"type\": \"point\", \"position\": [2, 3, 0], \"intensity\": [1, 1, 1]}],"
    " \"render\": {\"max_depth\": 20, \"seed\": 1}}";

static int hash_of(const char *from, const char *to, uint64_t *h) {
    const char *at = strstr(k_base, from);
    if (!at) return -1;
    char text[4096];
    snprintf(text, sizeof text, "%.*s%s%s", (int)(at - k_base), k_base, to, at + strlen(from));
    scene s;
    json_err e;
    if (scene_load_text(&s, text, &e) != 0) {
        fprintf(stderr, "    %s -> %s: %s\n", from, to, e.msg);
        return -1;
    }
    *h = scene_transport_hash(&s);
    scene_free(&s);
    return 0;
}

/* Oracle: scene_hash.h's list. Each edit of a field that light transport reads changes the
 * hash (a vertex, a sphere's centre and radius, a reflectance, an index of refraction, an
 * emission, a point light's position and intensity, the light's type); edits of the
 * camera, image size, samples, seed and description do not; the same text loaded twice
 * hashes the same. */
TEST(render_scene_transport_hash_covers_what_it_says) {
    uint64_t base, h;
    ASSERT_EQ_INT(hash_of("\"D\"", "\"D\"", &base), 0);
    ASSERT_EQ_INT(hash_of("\"D\"", "\"D\"", &h), 0);
    EXPECT(h == base);
    const char *same[][2] = {{"\"D\"", "\"another description\""},
                             {"\"eye\": [0, 1, -5]", "\"eye\": [0, 2, -6]"},
                             {"\"width\": 32", "\"width\": 64"},
                             {"\"spp\": 4", "\"spp\": 16"},
                             {"\"seed\": 1", "\"seed\": 2"}};
    for (size_t i = 0; i < sizeof same / sizeof *same; i++) {
        int rc = hash_of(same[i][0], same[i][1], &h);
        EXPECT_MSG(rc == 0 && h == base, "%s -> %s changed the hash", same[i][0], same[i][1]);
    }
    const char *differ[][2] = {{"[-3, 0, -3]", "[-3, 0.001, -3]"},
                               {"\"radius\": 1", "\"radius\": 1.01"},
                               {"\"center\": [0, 1, 0]", "\"center\": [0, 1.1, 0]"},
                               {"[0.5, 0.5, 0.5]", "[0.5, 0.5, 0.49]"},
                               {"\"ior\": 1.5", "\"ior\": 1.4"},
                               {"[4, 4, 4]", "[4, 4, 5]"},
                               {"\"position\": [2, 3, 0]", "\"position\": [2, 3, 0.5]"},
                               {"\"intensity\": [1, 1, 1]", "\"intensity\": [1, 2, 1]"}};
    for (size_t i = 0; i < sizeof differ / sizeof *differ; i++) {
        int rc = hash_of(differ[i][0], differ[i][1], &h);
        EXPECT_MSG(rc == 0 && h != base, "%s -> %s kept the hash (rc %d)", differ[i][0], differ[i][1], rc);
    }
    int rc = hash_of("{\"type\": \"point\", \"position\": [2, 3, 0], \"intensity\": [1, 1, 1]}",
                     "{\"type\": \"directional\", \"direction\": [0, -1, 0], \"irradiance\": [1, 1, 1]}", &h);
    EXPECT_MSG(rc == 0 && h != base, "a directional light for the point light kept the hash");
}

/* Oracle: photon_maps.h's list. Each setting that shapes photons changes the settings hash
 * (the photon targets only for the maps the plan traces), each camera-pass setting and the
 * seed leave it as it is, and the scene half is scene_transport_hash. */
TEST(render_map_stamp_covers_what_it_says) {
    scene s;
    json_err e;
    ASSERT_MSG(scene_load(&s, shipped("cornell_spheres"), &e) == 0, "%s", e.msg);
    photon_settings c0, c;
    ASSERT(photon_settings_parse(&c0, NULL, &e) == 0);
    map_stamp base, st;
    map_stamp_make(&s, &c0, 1, 1, 1, &base);
    EXPECT(base.scene == scene_transport_hash(&s));
#define SAME(stmt)                                                                      \
    do {                                                                                \
        c = c0;                                                                         \
        stmt;                                                                           \
        map_stamp_make(&s, &c, 1, 1, 1, &st);                                           \
        EXPECT_MSG(st.settings == base.settings && st.scene == base.scene, "%s changed it", #stmt); \
    } while (0)
#define DIFFERS(stmt)                                                                   \
    do {                                                                                \
        c = c0;                                                                         \
        stmt;                                                                           \
        map_stamp_make(&s, &c, 1, 1, 1, &st);                                           \
        EXPECT_MSG(st.settings != base.settings, "%s kept it", #stmt);                  \
    } while (0)
    SAME(c.k_global = 7);
    SAME(c.k_caustic = 7);
    SAME(c.k_shadow = 7);
    SAME(c.gather_rays = 9);
    SAME(c.secondary_rays = 9);
    SAME(c.filter = CAUSTIC_FILTER_HULL);
    SAME(c.max_radius_global = 3);
    SAME(c.caustic_stride = 3);
    SAME(c.emission_strata = 0);
    SAME(c.split_depth = 5);
    SAME(c.progress = 0);
    SAME(c.force_load = 1);
    SAME(s.settings.seed = 12345);
    SAME(s.cam.spp = 99);
    DIFFERS(c.global_photons++);
    DIFFERS(c.caustic_photons++);
    DIFFERS(c.max_emitted_factor *= 2);
    DIFFERS(c.max_emitted /= 2);
    DIFFERS(c.max_memory_mb *= 2);
    DIFFERS(c.max_bounces--);
    DIFFERS(c.projection = 0);
    DIFFERS(c.projection_cells = 32);
    DIFFERS(c.importance_paths = 0);
    DIFFERS(c.importance_defensive = 0.5);
    /* photon_maps.h IMPORTANCE: the camera and the seed steer the emission, unstamped. */
    SAME(s.cam.width = 7);
    SAME(c.force_final_gather = PLAN_OFF);
    int depth = s.settings.max_depth;
    DIFFERS(s.settings.max_depth = depth + 1);
    s.settings.max_depth = depth;
#undef SAME
#undef DIFFERS
    /* The plan's maps: each flag on its own. */
    for (int k = 0; k < 3; k++) {
        map_stamp_make(&s, &c0, k != 0, k != 1, k != 2, &st);
        EXPECT_MSG(st.settings != base.settings, "map %d off kept it", k);
    }
    /* Without a caustic map its target and projection do not matter, and without global
     * and shadow maps the global target does not. */
    map_stamp a, b;
    c = c0;
    map_stamp_make(&s, &c, 1, 0, 1, &a);
    c.caustic_photons = 7, c.projection = 0, c.projection_cells = 3;
    map_stamp_make(&s, &c, 1, 0, 1, &b);
    EXPECT(a.settings == b.settings);
    c = c0;
    map_stamp_make(&s, &c, 0, 1, 0, &a);
    c.global_photons = 7;
    map_stamp_make(&s, &c, 0, 1, 0, &b);
    EXPECT(a.settings == b.settings);
    scene_free(&s);
}

/* ---- the tracer's version (photon_maps.h TRACER VERSION) ---------------------------------- */

/* Rewrite the stamp of map file `name` (in the test directory) with tag[1]'s bits 48-63 set
 * to `version`, keeping everything else. */
static int restamp_version(const char *name, unsigned version) {
    pm_photon *ph = NULL;
    pm_map_header h;
    int rc = pm_map_load(rt_path(name), &ph, &h);
    if (rc < 0) return rc;
    h.tag[1] = (uint64_t)version << 48 | (h.tag[1] & 0xFFFFFFFFFFFFull);
    rc = pm_map_save(rt_path(name), ph, &h);
    free(ph);
    return rc;
}

/* Oracle: photon_maps.h TRACER VERSION. Every saved file carries PHOTON_TRACE_VERSION in bits
 * 48-63 of tag[1]; maps stamped with another version (each file in turn, everything else
 * equal) are refused with exit 2 naming the file and both versions; forced, they load (one
 * warning per file) and, being the same photons, give the traced image bit for bit. */
TEST(render_maps_other_tracer_version_is_refused_unless_forced) {
    save_maps();
    const char *names[] = {"global.pmap", "caustic.pmap", "shadow.pmap"};
    ASSERT_EQ_INT(mkdir(rt_path("old"), 0755), 0);
    for (int i = 0; i < 3; i++) {
        char from[64], to[64];
        snprintf(from, sizeof from, "maps/%s", names[i]);
        snprintf(to, sizeof to, "old/%s", names[i]);
        pm_photon *ph = NULL;
        pm_map_header h;
        ASSERT_EQ_INT(pm_map_load(rt_path(from), &ph, &h), 0);
        EXPECT_MSG((unsigned)(h.tag[1] >> 48) == PHOTON_TRACE_VERSION, "%s: version %u", from,
                   (unsigned)(h.tag[1] >> 48));
        ASSERT_EQ_INT(pm_map_save(rt_path(to), ph, &h), 0);
        free(ph);
    }
    int rc = run_pm(shipped("cornell_spheres"), "--load-photons old -o same.png");
    EXPECT_MSG(rc == 0 && !strstr(g_out, "warning"), "unchanged copy: exit %d: %s", rc, g_out);
    for (int i = 0; i < 3; i++) {
        char file[64], want[256];
        snprintf(file, sizeof file, "old/%s", names[i]);
        ASSERT_EQ_INT(restamp_version(file, PHOTON_TRACE_VERSION + 1), 0);
        snprintf(want, sizeof want, "old/%s was traced by another version of the photon tracer (its "
                 "stamp says tracer version %u, this renderer's is %u", names[i],
                 PHOTON_TRACE_VERSION + 1, PHOTON_TRACE_VERSION);
        const char *w[] = {"cannot load photon maps", want, "--force-load-photons", NULL};
        expect_refused(shipped("cornell_spheres"), "--load-photons old", w);
        if (i < 2) ASSERT_EQ_INT(restamp_version(file, PHOTON_TRACE_VERSION), 0);
    }
    for (int i = 0; i < 2; i++) {
        char file[64];
        snprintf(file, sizeof file, "old/%s", names[i]);
        ASSERT_EQ_INT(restamp_version(file, PHOTON_TRACE_VERSION + 1), 0);
    }
    rc = run_pm(shipped("cornell_spheres"), "--load-photons old --force-load-photons --hdr forced.pfm");
    EXPECT_MSG(rc == 0, "forced: exit %d: %s", rc, g_out);
    for (int i = 0; i < 3; i++) {
        char w[256];
        snprintf(w, sizeof w, "warning: force_load_photons: old/%s was traced by another version", names[i]);
        EXPECT_MSG(strstr(g_out, w), "no \"%s\" in %s", w, g_out);
    }
    EXPECT_MSG(rt_same_file("forced.pfm", "traced.pfm"), "the forced maps gave another image");
}

/* ---- scenes with media: the volume maps (photon_maps.h MAP FILES) ------------------------- */

/* shadow=false undoes SMALL's shadow=true: a scene with media has no shadow photons (plan.h). */
#define MEDIA_FLAGS "--pm volume_photons=3000 --pm volume_caustic_photons=1500 --pm shadow=false"

/* volumetric_caustic (a fog box, a glass sphere: all four maps but the shadow map) saved into
 * DIR "vmaps" with its traced image vtraced.pfm. */
static void save_media_maps(void) {
    int rc = run_pm(shipped("volumetric_caustic"), MEDIA_FLAGS " --save-photons vmaps --hdr vtraced.pfm");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    ASSERT_MSG(strstr(g_out, "  volume: on") && strstr(g_out, "  volume caustics: on") &&
                   strstr(g_out, "  caustics: on") && strstr(g_out, "  global: on"),
               "the plan changed: %s", g_out);
    const char *files[] = {"global.pmap", "caustic.pmap", "shadow.pmap", "volume-0.pmap",
                           "volume_caustic-0.pmap"};
    for (int i = 0; i < 5; i++) {
        char f[64];
        snprintf(f, sizeof f, "vmaps/%s", files[i]);
        ASSERT_MSG(exists(f), "%s was not saved", f);
    }
}

/* Oracle: byte equality and the files' own counts. The images rendered from loaded maps equal
 * the traced runs' (cornell_fog: global and volume maps; volumetric_caustic: all four), the
 * load prints the counts the trace printed, and each volume file holds the volume photons the
 * trace reported (one medium: all of them), with its kind and the stamp of map_stamp_file.
 * That the loaded photons are the ones used, not traced again: under another seed, the loaded
 * maps (of seed 3) give an image that differs from that seed's own traced run. */
TEST(render_maps_media_loaded_equals_traced) {
    int rc = run_pm(shipped("cornell_fog"), MEDIA_FLAGS " --save-photons fog --hdr ft.pfm");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    ASSERT(exists("fog/volume-0.pmap") && exists("fog/volume_caustic-0.pmap"));
    rc = run_pm(shipped("cornell_fog"), MEDIA_FLAGS " --load-photons fog --hdr fl.pfm");
    EXPECT_MSG(rc == 0 && strstr(g_out, "Loaded photon maps from fog (scene with media)") &&
                   !strstr(g_out, "warning") && !strstr(g_out, "\nPhotons"),
               "exit %d: %s", rc, g_out);
    EXPECT_MSG(rt_same_file("ft.pfm", "fl.pfm"), "cornell_fog: the image from the loaded maps differs");

    save_media_maps();
    const char *traced = strstr(g_out, "Photons (scene with media): ");
    ASSERT_MSG(traced, "%s", g_out);
    char counts[512];
    snprintf(counts, sizeof counts, "%.*s", (int)strcspn(traced + strlen("Photons"), "\n"),
             traced + strlen("Photons"));
    long long ng, nc, nvol, nms, nvc;
    ASSERT_MSG(sscanf(traced, "Photons (scene with media): %lld global (from %*u emitted), %lld caustic "
                              "(from %*u emitted); volume: %lld (from %*u emitted), %lld of them for "
                              "multiple scattering (radius %*g, k %*u), %lld volume-caustic",
                      &ng, &nc, &nvol, &nms, &nvc) == 5,
               "%s", traced);
    rc = run_pm(shipped("volumetric_caustic"), MEDIA_FLAGS " --load-photons vmaps --hdr vloaded.pfm");
    EXPECT_MSG(rc == 0 && !strstr(g_out, "warning"), "exit %d: %s", rc, g_out);
    const char *loaded = strstr(g_out, "Loaded photon maps from vmaps");
    EXPECT_MSG(loaded && strncmp(loaded + strlen("Loaded photon maps from vmaps"), counts, strlen(counts)) == 0,
               "traced \"%s\", loaded: %s", counts, g_out);
    EXPECT_MSG(rt_same_file("vtraced.pfm", "vloaded.pfm"), "volumetric_caustic: the image from the loaded maps differs");

    /* The files: kind, stamp, and counts. */
    scene s;
    json_err e;
    ASSERT_MSG(scene_load(&s, shipped("volumetric_caustic"), &e) == 0, "%s", e.msg);
    photon_settings cfg;
    ASSERT(photon_settings_parse(&cfg, NULL, &e) == 0);
    cfg.global_photons = 3000;
    cfg.caustic_photons = 1500;
    cfg.volume_photons = 3000;
    cfg.volume_caustic_photons = 1500;
    map_stamp want;
    map_stamp_make(&s, &cfg, 1, 1, 0, &want);
    map_stamp_volume(&s, &cfg, 1, 1, &want);
    scene_free(&s);
    const char *vnames[] = {"vmaps/volume-0.pmap", "vmaps/volume_caustic-0.pmap"};
    long long vcounts[] = {nvol, nvc};
    for (int c = 0; c < 2; c++) {
        pm_photon *ph = NULL;
        pm_map_header h;
        ASSERT_EQ_INT(pm_map_load(rt_path(vnames[c]), &ph, &h), 0);
        EXPECT_EQ_INT(h.kind, PM_MAP_VOLUME);
        EXPECT_MSG((long long)h.count == vcounts[c] && h.count > 0, "%s: %llu photons, the trace said %lld",
                   vnames[c], (unsigned long long)h.count, vcounts[c]);
        EXPECT_MSG(h.tag[0] == want.scene && h.tag[1] == map_stamp_file(&want, c, 0),
                   "%s: tags %016llx %016llx", vnames[c], (unsigned long long)h.tag[0],
                   (unsigned long long)h.tag[1]);
        EXPECT_MSG(h.tag[1] != want.settings && (unsigned)(h.tag[1] >> 48) == PHOTON_TRACE_VERSION,
                   "%s: the role is not in tag[1]", vnames[c]);
        free(ph);
    }

    /* Under seed 4: loaded (seed-3 photons) vs traced (seed-4 photons). */
    rc = run_pm(shipped("volumetric_caustic"), MEDIA_FLAGS " --seed 4 --hdr s4traced.pfm");
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, g_out);
    rc = run_pm(shipped("volumetric_caustic"), MEDIA_FLAGS " --seed 4 --load-photons vmaps --hdr s4loaded.pfm");
    EXPECT_MSG(rc == 0 && strstr(g_out, "Loaded photon maps from vmaps"), "exit %d: %s", rc, g_out);
    EXPECT_MSG(!rt_same_file("s4traced.pfm", "s4loaded.pfm"),
               "under seed 4 the loaded seed-3 maps gave seed 4's traced image: they were traced again");
}

/* Oracle: photon_maps.h MAP FILES and render/app/main.c's exit status 2 for bad input. Each volume
 * file missing, truncated or garbage; a surface map under a volume map's name; the two volume
 * roles swapped (refused even forced: the wrong kind); the fog edited (another scene), the
 * volume target or the camera's position changed (other settings): exit 2 naming the file, no
 * output. Forced, the edited scene loads with a warning for every file, the volume files too. */
TEST(render_maps_media_bad_files_exit_2) {
    save_media_maps();
    const char *sc = shipped("volumetric_caustic");
    const char *all[] = {"global.pmap", "caustic.pmap", "shadow.pmap", "volume-0.pmap", "volume_caustic-0.pmap"};
    ASSERT_EQ_INT(mkdir(rt_path("vbad"), 0755), 0);
#define RESET_VBAD()                                                                     \
    for (int j = 0; j < 5; j++) {                                                        \
        char f_[64], t_[64];                                                             \
        snprintf(f_, sizeof f_, "vmaps/%s", all[j]);                                     \
        snprintf(t_, sizeof t_, "vbad/%s", all[j]);                                      \
        ASSERT_EQ_INT(copy_file(f_, t_), 0);                                             \
    }
    for (int i = 3; i < 5; i++) {
        char file[64], want[160];
        RESET_VBAD();
        snprintf(file, sizeof file, "vbad/%s", all[i]);
        unlink(rt_path(file));
        snprintf(want, sizeof want, "vbad/%s: No such file or directory", all[i]);
        const char *w1[] = {want, "volume-M.pmap and volume_caustic-M.pmap for each medium M", NULL};
        expect_refused(sc, MEDIA_FLAGS " --load-photons vbad --force-load-photons", w1);
        RESET_VBAD();
        struct stat sb;
        ASSERT_EQ_INT(stat(rt_path(file), &sb), 0);
        ASSERT_EQ_INT(truncate(rt_path(file), sb.st_size - 1), 0);
        snprintf(want, sizeof want, "vbad/%s: not a photon-map file, or a truncated or corrupt one", all[i]);
        const char *w2[] = {want, NULL};
        expect_refused(sc, MEDIA_FLAGS " --load-photons vbad --force-load-photons", w2);
        FILE *f = fopen(rt_path(file), "w");
        ASSERT(f);
        fputs("not a photon map\n", f);
        fclose(f);
        expect_refused(sc, MEDIA_FLAGS " --load-photons vbad", w2);
    }
    RESET_VBAD();
    ASSERT_EQ_INT(copy_file("vmaps/global.pmap", "vbad/volume-0.pmap"), 0);
    const char *w_kind[] = {"vbad/volume-0.pmap holds a global map, not a volume map", NULL};
    expect_refused(sc, MEDIA_FLAGS " --load-photons vbad --force-load-photons", w_kind);
    RESET_VBAD();
    ASSERT_EQ_INT(copy_file("vmaps/volume_caustic-0.pmap", "vbad/volume-0.pmap"), 0);
    ASSERT_EQ_INT(copy_file("vmaps/volume-0.pmap", "vbad/volume_caustic-0.pmap"), 0);
    const char *w_role[] = {"vbad/volume-0.pmap holds the volume-caustic map of medium 0, not the "
                            "volume map of medium 0", NULL};
    expect_refused(sc, MEDIA_FLAGS " --load-photons vbad", w_role);
    expect_refused(sc, MEDIA_FLAGS " --load-photons vbad --force-load-photons", w_role);

    const char *fogged = edited_copy("volumetric_caustic", "thicker.json", "\"sigma_s\": 0.3", "\"sigma_s\": 0.31");
    ASSERT(fogged);
    const char *w_scene[] = {"vmaps/global.pmap was traced for another scene", NULL};
    expect_refused(fogged, MEDIA_FLAGS " --load-photons vmaps", w_scene);
    int rc = run_pm(fogged, MEDIA_FLAGS " --load-photons vmaps --force-load-photons -o forced.png");
    EXPECT_MSG(rc == 0 && exists("forced.png"), "forced: exit %d: %s", rc, g_out);
    for (int j = 0; j < 5; j++) {
        char w[160];
        snprintf(w, sizeof w, "warning: force_load_photons: vmaps/%s was traced for another scene", all[j]);
        EXPECT_MSG(strstr(g_out, w), "no \"%s\" in %s", w, g_out);
    }
    const char *w_set[] = {"vmaps/global.pmap was traced with other photon settings", NULL};
    expect_refused(sc, "--pm volume_photons=3001 --pm volume_caustic_photons=1500 --load-photons vmaps", w_set);
    expect_refused(sc, "--pm volume_photons=3000 --pm volume_caustic_photons=1499 --load-photons vmaps", w_set);
    const char *moved = edited_copy("volumetric_caustic", "eye.json", "\"eye\": [\n   1,", "\"eye\": [\n   1.01,");
    ASSERT(moved);
    expect_refused(moved, MEDIA_FLAGS " --load-photons vmaps", w_set);
#undef RESET_VBAD
}
