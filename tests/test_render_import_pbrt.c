/* test_render_import_pbrt.c: pbrt-v3 scene import (render/load/pbrt.h).
 *
 * Oracles: data/pbrt/cornell_box.pbrt, a hand translation of data/scenes/cornell_box.json,
 * renders the JSON scene's image mean within 1% (path and pm, 32x32, different seeds; the
 * renders' own noise is about 0.1-0.5%) with the red wall on the same side; without its
 * "Scale -1 1 1" pbrt's camera sees the mirror image (pbrt.h, "Handedness"), and so does ours;
 * the converted document of small scenes checked value by value against transforms and unit
 * conversions done by hand (fov of the shorter side, sigma in degrees, light scale, instances,
 * ReverseOrientation's winding, PLY file objects); the file and line of every malformed input
 * and of every warning; mutated files (truncations, replaced bytes) either convert or fail
 * with the file named, never a crash (ASan/UBSan in the sanitizer build).
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "test.h"
#include "image/film.h"
#include "load/pbrt.h"
#include "load/scene_load.h"
#include "scene/scene.h"

static int write_text(const char *path, const char *text) {
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    fputs(text, f);
    return fclose(f);
}

static char *read_text(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *b = malloc((size_t)n + 1);
    if (b && fread(b, 1, (size_t)n, f) != (size_t)n) {
        free(b);
        b = NULL;
    }
    if (b) b[n] = 0;
    fclose(f);
    return b;
}

/* Mean of (red - green) over the columns [x0, x1) of a PFM. */
static double red_minus_green(const film *f, int x0, int x1) {
    double s = 0;
    for (int y = 0; y < f->height; y++)
        for (int x = x0; x < x1; x++) {
            rgb c = film_get(f, x, y);
            s += c.x - c.y;
        }
    return s / ((double)(x1 - x0) * f->height);
}

static double film_mean(const film *f) {
    double s = 0;
    for (long i = 0; i < 3L * f->width * f->height; i++) s += f->px[i];
    return s / (3.0 * f->width * f->height);
}

/* Oracle: data/scenes/cornell_box.json. The translation renders its image mean within 1%
 * (path 256 spp, pm 64 spp; different seeds), the red wall on the left in both; the same file
 * without "Scale -1 1 1" shows the red wall on the right (pbrt's mirror image) and the same
 * mean. */
TEST(pbrt_cornell_matches_json) {
    const char *dir = pm_test_tmpdir();
    char cmd[8192], out[8192], path[1024];
    char pbrt[1024];
    snprintf(pbrt, sizeof pbrt, "%s/data/pbrt/cornell_box.pbrt", pm_test_source_dir());
    /* the mirrored variant: the same file without the Scale line, beside its Include */
    char *text = read_text(pbrt);
    ASSERT(text);
    char *sc = strstr(text, "\nScale -1 1 1\n");
    ASSERT(sc);
    memcpy(sc + 1, "#cale", 5);
    char mir[1024];
    snprintf(mir, sizeof mir, "%s/mirrored.pbrt", dir);
    ASSERT(write_text(mir, text) == 0);
    free(text);
    snprintf(cmd, sizeof cmd, "cp '%s/data/pbrt/cornell_box_walls.pbrt' '%s/'", pm_test_source_dir(), dir);
    ASSERT(pm_test_run(cmd, out, sizeof out) == 0);
    static const struct {
        const char *mode;
        int spp;
    } runs[] = {{"path", 256}, {"pm", 64}};
    for (int r = 0; r < 2; r++) {
        snprintf(cmd, sizeof cmd,
                 "cd '%s' && R='%s/render' && O='--width 32 --height 32 --quiet --threads 2 --mode %s --spp %d' && "
                 "$R '%s' $O --seed 1 --hdr p.pfm >/dev/null 2>p.err && "
                 "$R '%s/data/scenes/cornell_box.json' $O --seed 2 --hdr j.pfm >/dev/null && "
                 "$R mirrored.pbrt $O --seed 3 --hdr m.pfm >/dev/null 2>>p.err && cat p.err",
                 dir, pm_test_build_dir(), runs[r].mode, runs[r].spp, pbrt, pm_test_source_dir());
        int rc = pm_test_run(cmd, out, sizeof out);
        ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
        EXPECT_MSG(!strstr(out, "warning"), "the translation warns: %s", out);
        film p, j, m;
        snprintf(path, sizeof path, "%s/p.pfm", dir);
        ASSERT(film_read_pfm(&p, path) == 0);
        snprintf(path, sizeof path, "%s/j.pfm", dir);
        ASSERT(film_read_pfm(&j, path) == 0);
        snprintf(path, sizeof path, "%s/m.pfm", dir);
        ASSERT(film_read_pfm(&m, path) == 0);
        double mp = film_mean(&p), mj = film_mean(&j), mm = film_mean(&m);
        printf("    %s: image mean pbrt %.5f, json %.5f (%+.2f%%), mirrored pbrt %.5f (%+.2f%%)\n", runs[r].mode, mp, mj,
               100 * (mp / mj - 1), mm, 100 * (mm / mj - 1));
        EXPECT_REL(mp, mj, 0.01);
        EXPECT_REL(mm, mj, 0.01);
        /* the red wall: left third in the JSON and the translation, right third when mirrored */
        double pl = red_minus_green(&p, 0, 10), pr = red_minus_green(&p, 22, 32);
        double jl = red_minus_green(&j, 0, 10), jr = red_minus_green(&j, 22, 32);
        double ml = red_minus_green(&m, 0, 10), mr = red_minus_green(&m, 22, 32);
        EXPECT_MSG(jl > 0 && jr < 0 && pl > 0 && pr < 0, "red left: json %g %g, pbrt %g %g", jl, jr, pl, pr);
        EXPECT_MSG(ml < 0 && mr > 0, "mirrored: red right: %g %g", ml, mr);
        EXPECT_REL(pl, jl, 0.1);
        EXPECT_REL(mr, jl, 0.1);
        film_free(&p);
        film_free(&j);
        film_free(&m);
    }
}

/* ---- conversion values -------------------------------------------------------------------- */

static cJSON *convert_ok(const char *text) {
    cJSON *out = NULL;
    json_err e;
    e.msg[0] = 0;
    int rc = pbrt_convert_text(text, "t.pbrt", &out, &e);
    EXPECT_MSG(rc == 0, "refused: %s", e.msg);
    return rc == 0 ? out : NULL;
}

static double num_at(const cJSON *o, const char *path) {
    /* path like "camera.eye.0" */
    char buf[256];
    snprintf(buf, sizeof buf, "%s", path);
    const cJSON *it = o;
    for (char *tok = strtok(buf, "."); tok && it; tok = strtok(NULL, ".")) {
        if (tok[0] >= '0' && tok[0] <= '9') it = cJSON_GetArrayItem(it, atoi(tok));
        else it = cJSON_GetObjectItemCaseSensitive(it, tok);
    }
    return cJSON_IsNumber(it) ? it->valuedouble : NAN;
}

/* Oracle: by hand. Camera: a 200 x 100 image with fov 40 (pbrt: of the shorter side, the
 * height) has the horizontal fov 2 atan(2 tan 20) = 72.1 degrees; LookAt with pbrt's frame
 * mirrored against ours mirrors x (eye [1, 2, 3] -> [-1, 2, 3]). Transform stack: Translate
 * 1 0 0, Rotate 90 about z (x -> y), Scale 2: the unit sphere's centre -> [1, 0, 0] mirrored
 * [-1, 0, 0]... (see below); AttributeEnd restores; pixelsamples, maxdepth; matte sigma 20
 * degrees -> 0.349 rad; glass eta 1.33; mirror Kr; plastic -> mix with Fresnel coat; point light
 * I * scale at its from; distant light direction from -> to, L as irradiance. */
TEST(pbrt_conversion_values) {
    const char *t =
        "LookAt 1 2 3  1 2 4  0 1 0\n"
        "Camera \"perspective\" \"float fov\" 40\n"
        "Film \"image\" \"integer xresolution\" [200] \"integer yresolution\" [100]\n"
        "Sampler \"halton\" \"integer pixelsamples\" 8\n"
        "Integrator \"path\" \"integer maxdepth\" [7]\n"
        "WorldBegin\n"
        "LightSource \"point\" \"rgb I\" [1 2 3] \"point from\" [0 5 0] \"rgb scale\" [2 2 2]\n"
        "LightSource \"distant\" \"rgb L\" [4 4 4] \"point from\" [0 1 0] \"point to\" [0 0 0]\n"
        "AttributeBegin\n"
        "  Translate 1 0 0\n  Rotate 90 0 0 1\n  Scale 2 2 2\n"
        "  Material \"matte\" \"rgb Kd\" [0.2 0.3 0.4] \"float sigma\" 20\n"
        "  Shape \"sphere\" \"float radius\" 0.5\n"
        "  Translate 1 0 0\n"
        "  Shape \"sphere\"\n"
        "AttributeEnd\n"
        "Material \"glass\" \"float eta\" 1.33\n"
        "Shape \"sphere\" \"float radius\" 3\n"
        "Material \"mirror\" \"rgb Kr\" [0.5 0.6 0.7]\n"
        "Shape \"sphere\"\n"
        "Material \"plastic\" \"rgb Kd\" [0.1 0.2 0.3] \"rgb Ks\" [0.4 0.4 0.4]\n"
        "Shape \"sphere\"\n"
        "WorldEnd\n";
    cJSON *d = convert_ok(t);
    ASSERT(d);
    EXPECT_NEAR(num_at(d, "camera.eye.0"), -1, 1e-12);
    EXPECT_NEAR(num_at(d, "camera.eye.1"), 2, 1e-12);
    EXPECT_NEAR(num_at(d, "camera.look_at.2"), 4, 1e-12);
    EXPECT_NEAR(num_at(d, "camera.fov_deg"), 2 * atan(2 * tan(20 * M_PI / 180)) * 180 / M_PI, 1e-9);
    EXPECT_NEAR(num_at(d, "camera.width"), 200, 0);
    EXPECT_NEAR(num_at(d, "camera.spp"), 8, 0);
    EXPECT_NEAR(num_at(d, "render.max_depth"), 7, 0);
    /* lights: point at [0, 5, 0] (x mirrored: 0), intensity [2, 4, 6]; distant travelling -y */
    EXPECT_NEAR(num_at(d, "lights.0.position.1"), 5, 1e-12);
    EXPECT_NEAR(num_at(d, "lights.0.intensity.2"), 6, 1e-12);
    EXPECT_NEAR(num_at(d, "lights.1.direction.1"), -1, 1e-12);
    EXPECT_NEAR(num_at(d, "lights.1.irradiance.0"), 4, 1e-12);
    /* sphere 0: T(1,0,0) R(90 z) S(2) applied to the origin: [1, 0, 0], mirrored [-1, 0, 0],
     * radius 0.5 * 2 = 1; sphere 1: one more Translate 1 0 0 in the object's frame: +x turned
     * by 90 degrees about z is +y, times 2: [1, 2, 0], mirrored [-1, 2, 0], radius 2 */
    EXPECT_NEAR(num_at(d, "objects.0.center.0"), -1, 1e-12);
    EXPECT_NEAR(num_at(d, "objects.0.center.1"), 0, 1e-12);
    EXPECT_NEAR(num_at(d, "objects.0.radius"), 1, 1e-12);
    EXPECT_NEAR(num_at(d, "objects.1.center.0"), -1, 1e-12);
    EXPECT_NEAR(num_at(d, "objects.1.center.1"), 2, 1e-12);
    EXPECT_NEAR(num_at(d, "objects.1.radius"), 2, 1e-12);
    /* after AttributeEnd: the identity */
    EXPECT_NEAR(num_at(d, "objects.2.center.0"), 0, 1e-12);
    EXPECT_NEAR(num_at(d, "objects.2.radius"), 3, 1e-12);
    /* materials */
    const cJSON *mats = cJSON_GetObjectItemCaseSensitive(d, "materials");
    const cJSON *m0 = cJSON_GetObjectItemCaseSensitive(mats, "pbrt:0"), *m1 = cJSON_GetObjectItemCaseSensitive(mats, "pbrt:1"),
                *m2 = cJSON_GetObjectItemCaseSensitive(mats, "pbrt:2"), *m3 = cJSON_GetObjectItemCaseSensitive(mats, "pbrt:3");
    ASSERT(m0 && m1 && m2 && m3);
    EXPECT(strcmp(cJSON_GetObjectItemCaseSensitive(m0, "type")->valuestring, "oren_nayar") == 0);
    EXPECT_NEAR(num_at(m0, "sigma"), 20 * M_PI / 180, 1e-12);
    EXPECT_NEAR(num_at(m0, "reflectance.2"), 0.4, 1e-12);
    EXPECT(strcmp(cJSON_GetObjectItemCaseSensitive(m1, "type")->valuestring, "dielectric") == 0);
    EXPECT_NEAR(num_at(m1, "ior"), 1.33, 1e-12);
    EXPECT(strcmp(cJSON_GetObjectItemCaseSensitive(m2, "type")->valuestring, "mirror") == 0);
    EXPECT_NEAR(num_at(m2, "reflectance.1"), 0.6, 1e-12);
    EXPECT(strcmp(cJSON_GetObjectItemCaseSensitive(m3, "type")->valuestring, "mix") == 0);
    EXPECT_NEAR(num_at(m3, "diffuse.2"), 0.3, 1e-12);
    EXPECT_NEAR(num_at(m3, "specular_tint.0"), 0.4, 1e-12);
    EXPECT(strcmp(cJSON_GetObjectItemCaseSensitive(d, "render")->child->valuestring, "path") == 0);
    /* and it loads as a scene of ours */
    scene s;
    json_err e;
    char *txt = cJSON_PrintUnformatted(d);
    ASSERT(txt);
    EXPECT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    scene_free(&s);
    free(txt);
    cJSON_Delete(d);
}

/* Oracle: by hand. With Scale -1 1 1 before LookAt (no mirror), a triangle keeps its winding;
 * ReverseOrientation turns it (v0 v2 v1); a mirroring transform (Scale -1 1 1 in the world)
 * turns it too (pbrt flips the normal of a handedness-swapping transform), and both together
 * keep it. Instances: ObjectBegin's triangle copied under Translate 0 0 5 and 0 0 7. An area
 * light's material is a copy with the emission L * scale and two_sided. A plymesh is a file
 * object with its matrix (row by row) and flip. */
TEST(pbrt_orientation_instances_plymesh) {
    char ply[1024], text[4096];
    snprintf(ply, sizeof ply, "%s/tri.ply", pm_test_tmpdir());
    ASSERT(write_text(ply, "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                           "property float nx\nproperty float ny\nproperty float nz\n"
                           "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
                           "0 0 0 0 0 1\n1 0 0 0 0 1\n0 1 0 0 0 1\n3 0 1 2\n") == 0);
    snprintf(text, sizeof text,
             "Scale -1 1 1\nLookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\"\nWorldBegin\n"
             "Shape \"trianglemesh\" \"point P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]\n"
             "AttributeBegin\nReverseOrientation\n"
             "Shape \"trianglemesh\" \"point P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]\nAttributeEnd\n"
             "AttributeBegin\nScale -1 1 1\n"
             "Shape \"trianglemesh\" \"point P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]\n"
             "ReverseOrientation\n"
             "Shape \"trianglemesh\" \"point P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]\nAttributeEnd\n"
             "ObjectBegin \"tri\"\nShape \"trianglemesh\" \"point P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]\nObjectEnd\n"
             "AttributeBegin\nTranslate 0 0 5\nObjectInstance \"tri\"\nTranslate 0 0 2\nObjectInstance \"tri\"\nAttributeEnd\n"
             "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 2 3] \"rgb scale\" [2 2 2] \"bool twosided\" \"true\"\n"
             "Translate 0 0 1\nReverseOrientation\nShape \"plymesh\" \"string filename\" \"%s\"\nAttributeEnd\n"
             "WorldEnd\n", ply);
    cJSON *d = convert_ok(text);
    ASSERT(d);
    const cJSON *objs = cJSON_GetObjectItemCaseSensitive(d, "objects");
    ASSERT_EQ_INT(cJSON_GetArraySize(objs), 7);
    static const int want_k1[5] = {1, 2, 2, 1, 1}; /* the second index of each triangle */
    for (int i = 0; i < 5; i++) {
        char p[64];
        snprintf(p, sizeof p, "objects.%d.triangles.0.1", i);
        EXPECT_MSG(num_at(d, p) == want_k1[i], "object %d: second index %g, want %d", i, num_at(d, p), want_k1[i]);
    }
    EXPECT_NEAR(num_at(d, "objects.2.vertices.1.0"), -1, 0); /* Scale -1 1 1 in the world */
    EXPECT_NEAR(num_at(d, "objects.4.vertices.0.2"), 5, 0);
    EXPECT_NEAR(num_at(d, "objects.5.vertices.1.2"), 7, 0);
    EXPECT_NEAR(num_at(d, "objects.5.vertices.1.0"), 1, 0);
    const cJSON *pm = cJSON_GetArrayItem(objs, 6);
    ASSERT(pm);
    const cJSON *file = cJSON_GetObjectItemCaseSensitive(pm, "file");
    EXPECT(cJSON_IsString(file) && strstr(file->valuestring, "tri.ply"));
    EXPECT(cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(pm, "flip")));
    EXPECT(cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(pm, "smooth"))); /* the file has normals */
    EXPECT_NEAR(num_at(pm, "transform.11"), 1, 0); /* z translation, row 2 column 3 */
    const cJSON *mat = cJSON_GetObjectItemCaseSensitive(pm, "material");
    const cJSON *lm = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(d, "materials"), mat->valuestring);
    ASSERT(lm);
    EXPECT_NEAR(num_at(lm, "emission.2"), 6, 0);
    EXPECT(cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(lm, "two_sided")));
    /* it loads: the flip key is ours; the PLY's one triangle is read */
    scene s;
    json_err e;
    char *txt = cJSON_PrintUnformatted(d);
    ASSERT(txt);
    EXPECT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    if (s.ntris == 7) {
        /* the PLY triangle flipped: its front normal is -z (the file's winding gives +z) */
        EXPECT_MSG(s.tris[6].n.z < 0, "flipped PLY normal z %g", s.tris[6].n.z);
    }
    EXPECT_EQ_INT(s.ntris, 7);
    scene_free(&s);
    free(txt);
    cJSON_Delete(d);
}

/* ---- errors and warnings ------------------------------------------------------------------ */

/* Oracle: the file:line and reason of each malformed input (one text each). */
TEST(pbrt_errors_name_file_and_line) {
    static const struct {
        const char *text, *want;
    } cases[] = {
        {"WorldBegin\nShape \"sphere\" \"float radius\" [1\n", "t.pbrt:2: parameter \"float radius\": unbalanced ["},
        {"WorldBegin\n\nShape \"sphere \"float radius\" 1\n", "t.pbrt:3: unterminated string"},
        {"WorldBegin\nShape \"sphere\" \"float radius\" \"big\"\n", "t.pbrt:2: parameter \"float radius\": expected numbers"},
        {"WorldBegin\nShape \"sphere\" \"string radius\" \"big\"\n", "t.pbrt:2: parameter \"string radius\": the type should be float"},
        {"WorldBegin\nMaterial \"matte\" \"rgb Kd\" [1 2]\n", "t.pbrt:2: parameter \"rgb Kd\": expected 3 values, got 2"},
        {"WorldBegin\nNamedMaterial \"nosuch\"\n", "t.pbrt:2: NamedMaterial: no material named \"nosuch\""},
        {"WorldBegin\nInclude \"nosuch.pbrt\"\n", "t.pbrt:2: Include: "},
        {"WorldBegin\nShape \"plymesh\" \"string filename\" \"nosuch.ply\"\n", "t.pbrt:2: Shape \"plymesh\": cannot open"},
        {"WorldBegin\nAttributeEnd\n", "t.pbrt:2: AttributeEnd without a matching AttributeBegin"},
        {"WorldBegin\nAttributeBegin\n", "t.pbrt: 1 AttributeBegin/TransformBegin/ObjectBegin left open at the end"},
        {"Scale 1e300 1e300 1e300\nScale 1e300 1 1\nWorldBegin\n", "t.pbrt:2: the transform is not finite"},
        {"Translate 1 nan 0\nWorldBegin\n", "t.pbrt:1: Translate: expected 3 numbers, got 1"},
        {"WorldBegin\nShape \"trianglemesh\" \"point P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 3]\n",
         "t.pbrt:2: Shape \"trianglemesh\": index 3 (triangle 0) out of range (3 points)"},
        {"WorldBegin\nShape \"trianglemesh\" \"point P\" [0 0 0 1 0 0 0 1]\n", "t.pbrt:2: Shape \"trianglemesh\": \"point P\" needs 3"},
        {"Shape \"sphere\"\nWorldBegin\n", "t.pbrt:1: Shape before WorldBegin"},
        {"LookAt 0 0 0 0 0 1 0 1 0\n", "t.pbrt: no WorldBegin"},
        {"Camera \"orthographic\"\nWorldBegin\n", "t.pbrt:1: Camera \"orthographic\" is not supported (perspective)"},
        {"WorldBegin\nObjectInstance \"x\"\n", "t.pbrt:2: ObjectInstance: no object named \"x\""},
        {"WorldBegin\n]\n", "t.pbrt:2: unbalanced ] outside a parameter list"},
        {"WorldBegin\n\"float x\" 1\n", "t.pbrt:2: a parameter \"float x\" without a directive"},
        {"Scale 0 0 0\nCamera \"perspective\"\nWorldBegin\n", "t.pbrt:2: Camera: the camera transform is singular"},
        {"Film \"image\" \"integer xresolution\" [0]\nWorldBegin\n", "t.pbrt:1: Film \"image\": resolution 0 x 720 outside"},
        {"WorldBegin\nShape \"sphere\" \"float radius\"\n", "t.pbrt:2: parameter \"float radius\" has no value"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        cJSON *out = NULL;
        json_err e;
        e.msg[0] = 0;
        int rc = pbrt_convert_text(cases[i].text, "t.pbrt", &out, &e);
        EXPECT_MSG(rc < 0 && strncmp(e.msg, cases[i].want, strlen(cases[i].want)) == 0, "case %zu: rc %d \"%s\", want \"%s\"",
                   i, rc, e.msg, cases[i].want);
        EXPECT(out == NULL);
        cJSON_Delete(out);
    }
    /* through render: an Include's own file and line; exit 2; a file that includes itself */
    const char *dir = pm_test_tmpdir();
    char p[1024], cmd[4096], outb[4096];
    snprintf(p, sizeof p, "%s/main.pbrt", dir);
    ASSERT(write_text(p, "LookAt 0 0 -5 0 0 0 0 1 0\nCamera \"perspective\"\nWorldBegin\nInclude \"inc.pbrt\"\n") == 0);
    snprintf(p, sizeof p, "%s/inc.pbrt", dir);
    ASSERT(write_text(p, "# included\n\nShape \"sphere\" \"float radius\" -1\n") == 0);
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' main.pbrt --quiet --hdr o.pfm 2>&1", dir, pm_test_build_dir());
    int rc = pm_test_run(cmd, outb, sizeof outb);
    EXPECT_MSG(rc == 2 && strstr(outb, "inc.pbrt:3: Shape \"sphere\": radius must be positive, got -1"), "exit %d: %s", rc, outb);
    ASSERT(write_text(p, "Include \"inc.pbrt\"\n") == 0);
    rc = pm_test_run(cmd, outb, sizeof outb);
    EXPECT_MSG(rc == 2 && strstr(outb, "inc.pbrt:1: Include nested more than 32 deep"), "exit %d: %s", rc, outb);
}

/* Oracle: pbrt.h: what the subset leaves out is warned about with its file and line, and the
 * scene still converts and renders. */
TEST(pbrt_warnings_name_file_and_line) {
    const char *dir = pm_test_tmpdir();
    char p[1024], cmd[4096], out[16384];
    snprintf(p, sizeof p, "%s/w.pbrt", dir);
    ASSERT(write_text(p,
        "LookAt 0 0 -5 0 0 0 0 1 0\n"
        "Camera \"perspective\" \"float lensradius\" 0.1\n"
        "Sampler \"halton\" \"integer pixelsamples\" 4\n"
        "Integrator \"bdpt\" \"integer maxdepth\" 3\n"
        "PixelFilter \"gaussian\"\n"
        "WorldBegin\n"
        "Frobnicate \"x\" \"float y\" 1\n"
        "Texture \"t\" \"spectrum\" \"checkerboard\"\n"
        "Material \"matte\" \"texture Kd\" \"t\" \"float foo\" 3\n"
        "LightSource \"goniometric\" \"rgb I\" [1 1 1]\n"
        "AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n"
        "Shape \"sphere\" \"float radius\" 1 \"float zmax\" 0.5\nAttributeEnd\n"
        "Shape \"cylinder\"\n"
        "Material \"metal\"\n"
        "Shape \"trianglemesh\" \"point P\" [0 0 0 1 0 0 2 0 0  0 0 1 1 0 1 0 1 1] \"integer indices\" [0 1 2 3 4 5]\n"
        "WorldEnd\n") == 0);
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' w.pbrt --quiet --width 8 --height 8 --spp 1 --hdr w.pfm 2>&1", dir,
             pm_test_build_dir());
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 0, "exit %d: %s", rc, out);
    const char *want[] = {
        "render: w.pbrt:2: warning: Camera \"perspective\": lensradius 0.1: depth of field is not supported",
        "render: w.pbrt:3: warning: Sampler \"halton\" is not supported: our stratified sampler is used (4 samples",
        "render: w.pbrt:4: warning: Integrator \"bdpt\" is not supported: rendering with \"path\"",
        "render: w.pbrt:5: warning: PixelFilter \"gaussian\" is not supported: each pixel is the mean",
        "render: w.pbrt:7: warning: unknown directive \"Frobnicate\": skipped",
        "render: w.pbrt:8: warning: Texture \"t\": textures are not supported",
        "render: w.pbrt:9: warning: parameter \"texture Kd\": textures are not supported: the default value is used",
        "render: w.pbrt:9: warning: Material \"matte\": parameter \"float foo\" is not supported: ignored",
        "render: w.pbrt:10: warning: LightSource \"goniometric\" is not supported (point, spot, distant, infinite): skipped",
        "render: w.pbrt:13: warning: Shape \"sphere\": a partial sphere",
        "render: w.pbrt:15: warning: Shape \"cylinder\" is not supported (trianglemesh, plymesh, sphere): skipped",
        "render: w.pbrt:16: warning: Material \"metal\" is not supported: matte grey 0.5",
        "render: w.pbrt:17: warning: Shape \"trianglemesh\": skipped 1 degenerate triangle (zero area)",
    };
    for (size_t i = 0; i < sizeof want / sizeof *want; i++) EXPECT_MSG(strstr(out, want[i]), "no '%s' in:\n%s", want[i], out);
}

/* Oracle: no crash and a clean answer. Every 40th prefix of the Cornell translation (with its
 * Include beside it) and 400 copies with 1-4 bytes replaced by a fixed generator either
 * convert or fail with a message that starts with the file's name and line. */
TEST(pbrt_mutations_never_crash) {
    char src[1024];
    snprintf(src, sizeof src, "%s/data/pbrt/cornell_box.pbrt", pm_test_source_dir());
    char *text = read_text(src);
    ASSERT(text);
    size_t n = strlen(text);
    char *b = malloc(n + 1);
    ASSERT(b);
    char cwd[4096];
    ASSERT(getcwd(cwd, sizeof cwd));
    char pdir[1100];
    snprintf(pdir, sizeof pdir, "%s/data/pbrt", pm_test_source_dir());
    ASSERT(chdir(pdir) == 0); /* the Include is found beside it */
    char wpath[1100];
    snprintf(wpath, sizeof wpath, "%s/warnings.txt", pm_test_tmpdir());
    FILE *saved = freopen(wpath, "w", stderr); /* the mutants' many warnings, kept out of the log */
    int ok = 0, bad = 0;
    uint64_t s = 0x2545f4914f6cdd1dull;
    for (int it = 0; it < 400 + (int)(n / 40); it++) {
        memcpy(b, text, n + 1);
        if (it < (int)(n / 40)) {
            b[40 * it] = 0;
        } else {
            for (int k = 0; k < 1 + (int)(s % 4); k++) {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                b[s % n] = " \"[]#0123456789.-eAaZ\n"[(s >> 40) % 22];
            }
        }
        cJSON *out = NULL;
        json_err e;
        e.msg[0] = 0;
        if (pbrt_convert_text(b, "c.pbrt", &out, &e) == 0) {
            ok++;
            cJSON_Delete(out);
        } else {
            bad++;
            EXPECT_MSG(strncmp(e.msg, "c.pbrt", 6) == 0 || strncmp(e.msg, "/", 1) == 0, "iteration %d: %s", it, e.msg);
        }
    }
    EXPECT(chdir(cwd) == 0);
    if (saved) fflush(stderr);
    printf("    %d converted, %d refused\n", ok, bad);
    free(b);
    free(text);
}

/* PLY of quads (4 corners each), ASCII or binary little-endian, with the corners shifted by
 * -off and, when rev, each face's corners in reverse order. */
static int write_quads_ply(const char *path, const double (*v)[3], int nq, vec3 off, int binary, int rev) {
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    fprintf(f, "ply\nformat %s 1.0\nelement vertex %d\nproperty float x\nproperty float y\nproperty float z\n"
               "element face %d\nproperty list uchar int vertex_indices\nend_header\n",
            binary ? "binary_little_endian" : "ascii", 4 * nq, nq);
    for (int i = 0; i < 4 * nq; i++) {
        float p[3] = {(float)(v[i][0] - off.x), (float)(v[i][1] - off.y), (float)(v[i][2] - off.z)};
        if (binary) fwrite(p, 4, 3, f); /* the tests run on little-endian x86-64 */
        else fprintf(f, "%.9g %.9g %.9g\n", p[0], p[1], p[2]);
    }
    for (int q = 0; q < nq; q++) {
        int32_t k[4] = {4 * q, 4 * q + 1, 4 * q + 2, 4 * q + 3};
        if (rev) {
            int32_t t = k[1];
            k[1] = k[3];
            k[3] = t;
        }
        if (binary) {
            unsigned char four = 4;
            fwrite(&four, 1, 1, f);
            fwrite(k, 4, 4, f);
        } else {
            fprintf(f, "4 %d %d %d %d\n", k[0], k[1], k[2], k[3]);
        }
    }
    return fclose(f);
}

/* Oracle: data/scenes/cornell_box.json again, now with the blocks as PLY files in a
 * subdirectory: the short block binary, in world coordinates, through ObjectBegin and
 * ObjectInstance; the tall block ASCII, centred on its own origin and placed by Translate, its
 * faces wound the other way and turned back by ReverseOrientation (one "flip" in the dump).
 * Path tracing 256 spp and photon mapping 64 spp: image mean within 1% of the JSON scene
 * (different seeds). */
TEST(pbrt_plymesh_cornell_matches_json) {
    static const double shortb[20][3] = {{130, 165, 65}, {82, 165, 225}, {240, 165, 272}, {290, 165, 114},
                                         {290, 0, 114}, {290, 165, 114}, {240, 165, 272}, {240, 0, 272},
                                         {130, 0, 65}, {130, 165, 65}, {290, 165, 114}, {290, 0, 114},
                                         {82, 0, 225}, {82, 165, 225}, {130, 165, 65}, {130, 0, 65},
                                         {240, 0, 272}, {240, 165, 272}, {82, 165, 225}, {82, 0, 225}};
    static const double tallb[20][3] = {{423, 330, 247}, {265, 330, 296}, {314, 330, 456}, {472, 330, 406},
                                        {423, 0, 247}, {423, 330, 247}, {472, 330, 406}, {472, 0, 406},
                                        {472, 0, 406}, {472, 330, 406}, {314, 330, 456}, {314, 0, 456},
                                        {314, 0, 456}, {314, 330, 456}, {265, 330, 296}, {265, 0, 296},
                                        {265, 0, 296}, {265, 330, 296}, {423, 330, 247}, {423, 0, 247}};
    const char *dir = pm_test_tmpdir();
    char p[1024], cmd[8192], out[8192];
    snprintf(cmd, sizeof cmd, "mkdir -p '%s/meshes' && cp '%s/data/pbrt/cornell_box_walls.pbrt' '%s/'", dir,
             pm_test_source_dir(), dir);
    ASSERT(pm_test_run(cmd, out, sizeof out) == 0);
    snprintf(p, sizeof p, "%s/meshes/short.ply", dir);
    ASSERT(write_quads_ply(p, shortb, 5, v3s(0), 1, 0) == 0);
    snprintf(p, sizeof p, "%s/meshes/tall.ply", dir);
    ASSERT(write_quads_ply(p, tallb, 5, v3(368.5, 0, 351.5), 0, 1) == 0);
    snprintf(p, sizeof p, "%s/ply.pbrt", dir);
    ASSERT(write_text(p,
        "Scale -1 1 1\nLookAt 278 273 -800  278 273 0  0 1 0\nCamera \"perspective\" \"float fov\" [39.307648]\n"
        "Film \"image\" \"integer xresolution\" [32] \"integer yresolution\" [32]\n"
        "Integrator \"path\" \"integer maxdepth\" [64]\nWorldBegin\n"
        "MakeNamedMaterial \"white\" \"string type\" \"matte\" \"rgb Kd\" [0.725 0.71 0.68]\n"
        "MakeNamedMaterial \"red\" \"string type\" \"matte\" \"rgb Kd\" [0.63 0.065 0.05]\n"
        "MakeNamedMaterial \"green\" \"string type\" \"matte\" \"rgb Kd\" [0.14 0.45 0.091]\n"
        "Include \"cornell_box_walls.pbrt\"\n"
        "AttributeBegin\n  Material \"matte\" \"rgb Kd\" [0.78 0.78 0.78]\n  AreaLightSource \"diffuse\" \"rgb L\" [17 12 4]\n"
        "  Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point P\" [343 548.7 227  343 548.7 332  213 548.7 332  213 548.7 227]\n"
        "AttributeEnd\n"
        "NamedMaterial \"white\"\n"
        "ObjectBegin \"short\"\n  Shape \"plymesh\" \"string filename\" \"meshes/short.ply\"\nObjectEnd\n"
        "ObjectInstance \"short\"\n"
        "AttributeBegin\n  Translate 368.5 0 351.5\n  ReverseOrientation\n  Shape \"plymesh\" \"string filename\" \"meshes/tall.ply\"\nAttributeEnd\n"
        "WorldEnd\n") == 0);
    for (int m = 0; m < 2; m++) {
        snprintf(cmd, sizeof cmd,
                 "cd '%s' && R='%s/render' && O='--width 32 --height 32 --quiet --threads 2 --mode %s --spp %d' && "
                 "$R ply.pbrt $O --seed 5 --hdr p.pfm >/dev/null 2>p.err && "
                 "$R '%s/data/scenes/cornell_box.json' $O --seed 6 --hdr j.pfm >/dev/null && cat p.err && "
                 "$R --dump-scene ply.pbrt 2>/dev/null | grep -c '\"flip\"'",
                 dir, pm_test_build_dir(), m ? "pm" : "path", m ? 64 : 256, pm_test_source_dir());
        int rc = pm_test_run(cmd, out, sizeof out);
        ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
        EXPECT_MSG(!strstr(out, "warning"), "%s", out);
        /* the tall block's ReverseOrientation: its file object is flipped (its faces, wound
         * inward in the file, face out again), the short block's is not */
        EXPECT_MSG(atoi(out) == 1, "flip count: %s", out);
        film a, b;
        snprintf(p, sizeof p, "%s/p.pfm", dir);
        ASSERT(film_read_pfm(&a, p) == 0);
        snprintf(p, sizeof p, "%s/j.pfm", dir);
        ASSERT(film_read_pfm(&b, p) == 0);
        double ma = film_mean(&a), mb = film_mean(&b);
        printf("    %s: image mean pbrt with PLY blocks %.5f, json %.5f (%+.2f%%)\n", m ? "pm" : "path", ma, mb,
               100 * (ma / mb - 1));
        EXPECT_REL(ma, mb, 0.01);
        film_free(&a);
        film_free(&b);
    }
}

/* Oracle: the shipped JSON scenes. data/pbrt/cornell_spheres.pbrt (mirror and glass spheres:
 * Translate + Shape "sphere", Material mirror and glass), cornell_diffuse.pbrt (matte with
 * sigma in degrees), cornell_point.pbrt (LightSource "point", I = power / 4 pi; the blocks by
 * Include), cornell_fog.pbrt (MakeNamedMedium and a MediumInterface before Camera: the
 * camera's and the scene's medium) and cornell_rect.pbrt (Tungsten's box: quads, blocks of
 * 12 triangles, a light of reflectance 0), hand translations of data/scenes/cornell_*.json: each
 * renders its JSON scene's image mean within 1%, path and pm, 32x32, different seeds (path
 * 1024 spp, 256 in the fog; pm 64 spp, 16 in the fog; the renders' own noise is 0.1-0.5%).
 * With the same seed (16x16, path) the images agree to float rounding (relative rmse below
 * 1e-6), so the converted scenes are the JSON scenes' triangles, spheres, materials and lights.
 * The fog's walls are interfaces of no medium inside and fog outside (the JSON scene's walls
 * are the same: front the global medium, back none), so the first ray that meets a wall's
 * outer side from the fog (over or beside the box) is reported once as an inconsistent
 * interface, as it is in pbrt's terms; no other warning. */
TEST(pbrt_cornell_scenes_match_json) {
    static const char *names[] = {"cornell_spheres", "cornell_diffuse", "cornell_point", "cornell_fog", "cornell_rect"};
    char cmd[8192], out[8192], path[1024];
    const char *dir = pm_test_tmpdir();
    for (int i = 0; i < 5; i++) {
        int fog = strcmp(names[i], "cornell_fog") == 0;
        for (int m = 0; m < 2; m++) {
            int spp = m ? (fog ? 16 : 64) : (fog ? 256 : 1024);
            snprintf(cmd, sizeof cmd,
                     "cd '%s' && R='%s/render' && O='--width 32 --height 32 --quiet --threads 2 --mode %s --spp %d' && "
                     "$R '%s/data/pbrt/%s.pbrt' $O --seed 11 --hdr p.pfm >/dev/null 2>p.err || { cat p.err; exit 1; }; "
                     "$R '%s/data/scenes/%s.json' $O --seed 12 --hdr j.pfm >/dev/null && cat p.err",
                     dir, pm_test_build_dir(), m ? "pm" : "path", spp, pm_test_source_dir(), names[i], pm_test_source_dir(),
                     names[i]);
            int rc = pm_test_run(cmd, out, sizeof out);
            ASSERT_MSG(rc == 0, "%s: exit %d: %s", names[i], rc, out);
            int warnings = 0;
            for (const char *w = strstr(out, "warning"); w; w = strstr(w + 1, "warning")) warnings++;
            int allowed = fog && strstr(out, "warning: inconsistent medium interface: a ray in medium \"fog\" reached $.objects[");
            EXPECT_MSG(warnings == allowed, "%s %s: %s", names[i], m ? "pm" : "path", out);
            film p, j;
            snprintf(path, sizeof path, "%s/p.pfm", dir);
            ASSERT(film_read_pfm(&p, path) == 0);
            snprintf(path, sizeof path, "%s/j.pfm", dir);
            ASSERT(film_read_pfm(&j, path) == 0);
            double mp = film_mean(&p), mj = film_mean(&j);
            printf("    %s %s: image mean pbrt %.5f, json %.5f (%+.2f%%)\n", names[i], m ? "pm" : "path", mp, mj,
                   100 * (mp / mj - 1));
            EXPECT_REL(mp, mj, 0.01);
            film_free(&p);
            film_free(&j);
        }
        snprintf(cmd, sizeof cmd,
                 "cd '%s' && R='%s/render' && O='--width 16 --height 16 --quiet --threads 2 --mode path --spp 16 --seed 3' && "
                 "$R '%s/data/pbrt/%s.pbrt' $O --hdr p.pfm >/dev/null 2>&1 && "
                 "$R '%s/data/scenes/%s.json' $O --hdr j.pfm >/dev/null && $R --compare p.pfm j.pfm",
                 dir, pm_test_build_dir(), pm_test_source_dir(), names[i], pm_test_source_dir(), names[i]);
        int rc = pm_test_run(cmd, out, sizeof out);
        ASSERT_MSG(rc == 0, "%s: exit %d: %s", names[i], rc, out);
        const char *r = strstr(out, "rel_rmse ");
        double rel = r ? atof(r + 9) : 1;
        printf("    %s same seed: rel_rmse %.3g\n", names[i], rel);
        EXPECT_MSG(rel < 1e-6, "%s: %s", names[i], out);
    }
}

/* Oracle: the JSON scene itself. cornell_box.pbrt converts to the JSON scene's triangles in
 * its order (quads split as ours are, nothing mirrored), so with the same seed every path is
 * the same; only the camera differs in rounding (fov 39.307648 in the file against the JSON's
 * 2 atan(12.5 / 35) from focal length and sensor), so pixels agree to float rounding: relative
 * rmse below 1e-6 (measured 1.5e-8 path, 8e-9 pm, 16x16), where any divergent path would give
 * about 1e-1. */
TEST(pbrt_cornell_same_seed_same_image) {
    char cmd[8192], out[8192];
    for (int m = 0; m < 2; m++) {
        snprintf(cmd, sizeof cmd,
                 "cd '%s' && R='%s/render' && O='--width 16 --height 16 --quiet --threads 2 --spp 16 --seed 7 --mode %s' && "
                 "$R '%s/data/pbrt/cornell_box.pbrt' $O --hdr p.pfm >/dev/null && "
                 "$R '%s/data/scenes/cornell_box.json' $O --hdr j.pfm >/dev/null && $R --compare p.pfm j.pfm",
                 pm_test_tmpdir(), pm_test_build_dir(), m ? "pm" : "path", pm_test_source_dir(), pm_test_source_dir());
        int rc = pm_test_run(cmd, out, sizeof out);
        ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
        const char *r = strstr(out, "rel_rmse ");
        double rel = r ? atof(r + 9) : 1;
        printf("    %s: rel_rmse %.3g\n", m ? "pm" : "path", rel);
        EXPECT_MSG(rel < 1e-6, "%s: %s", m ? "pm" : "path", out);
    }
}

/* Oracle: by hand. A trianglemesh with "normal N": the normals go through the transform's
 * inverse transpose (Scale 2 1 1: n = (1, 0, 1) becomes (0.5, 0, 1), normalized) and the
 * mirror (x negated: plain LookAt), the mesh becomes smooth, and each triangle is wound so its
 * front faces its normals as pbrt's FaceForward does (a triangle whose winding gives +z with
 * normals toward -z is turned). Loaded, the corner normals are the given ones. */
TEST(pbrt_trianglemesh_normals_smooth) {
    const char *t = "LookAt 0 0 -5 0 0 0 0 1 0\nCamera \"perspective\"\nWorldBegin\n"
                    "AttributeBegin\nScale 2 1 1\n"
                    "Shape \"trianglemesh\" \"point P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 2]\n"
                    "  \"normal N\" [1 0 1  1 0 1  1 0 1]\n"
                    "AttributeEnd\n"
                    "Shape \"trianglemesh\" \"point P\" [0 0 1 1 0 1 0 1 1] \"integer indices\" [0 1 2]\n"
                    "  \"normal N\" [0 0 -1  0 0 -1  0 0 -1]\n"
                    "WorldEnd\n";
    cJSON *d = convert_ok(t);
    ASSERT(d);
    double l = sqrt(0.25 + 1);
    EXPECT_NEAR(num_at(d, "objects.0.normals.0.0"), -0.5 / l, 1e-12); /* mirrored */
    EXPECT_NEAR(num_at(d, "objects.0.normals.0.2"), 1 / l, 1e-12);
    EXPECT_NEAR(num_at(d, "objects.0.triangles.0.1"), 2, 0); /* mirrored winding -z, normals +z: turned */
    EXPECT(cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(d, "objects"), 0), "smooth")));
    /* object 1: pbrt's winding normal +z, mirrored (x -> -x) it is -z in ours: faces its -z
     * normals without a turn */
    EXPECT_NEAR(num_at(d, "objects.1.triangles.0.1"), 1, 0);
    EXPECT_NEAR(num_at(d, "objects.1.normals.2.2"), -1, 1e-12);
    scene s;
    json_err e;
    char *txt = cJSON_PrintUnformatted(d);
    ASSERT(txt);
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(s.ntris, 2);
    ASSERT(s.tri_ns != NULL && s.ntri_ns == 2);
    for (int k = 0; k < 2; k++) {
        vec3 n0 = s.tri_ns[k][0];
        EXPECT_MSG(v3_dot(s.tris[k].n, n0) > 0, "triangle %d: front against its normals", k);
    }
    EXPECT_NEAR(s.tri_ns[0][1].x, -0.5 / l, 1e-9);
    EXPECT_NEAR(s.tri_ns[1][2].z, -1, 1e-9);
    scene_free(&s);
    free(txt);
    cJSON_Delete(d);
    /* the same second triangle with its normals toward +z: turned (the winding would face -z) */
    d = convert_ok("LookAt 0 0 -5 0 0 0 0 1 0\nCamera \"perspective\"\nWorldBegin\n"
                   "Shape \"trianglemesh\" \"point P\" [0 0 1 1 0 1 0 1 1] \"integer indices\" [0 1 2] \"normal N\" [0 0 1 0 0 1 0 0 1]\n");
    ASSERT(d);
    EXPECT_NEAR(num_at(d, "objects.0.triangles.0.1"), 2, 0);
    cJSON_Delete(d);
    /* JSON: normals need smooth, one per vertex */
    EXPECT(scene_load_text(&s, "{\"camera\": {\"eye\": [0, 0, -5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 4, \"height\": 4},"
                               " \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
                               " \"objects\": [{\"type\": \"mesh\", \"vertices\": [[0,0,0],[1,0,0],[0,1,0]], \"triangles\": [[0,1,2]],"
                               " \"normals\": [[0,0,1],[0,0,1]], \"smooth\": true, \"material\": \"w\"}]}", &e) < 0 &&
           strstr(e.msg, "$.objects[0].normals: expected one normal per vertex (3)"));
}

/* Oracle: a scene of ours written by hand. A pbrt smoke ball (MakeNamedMedium homogeneous,
 * sigma times scale; Material "interface" with MediumInterface "smoke" "") becomes a null
 * sphere with interior_medium "smoke" and media.smoke = sigma * scale; with the same seed the
 * converted scene renders our hand-written one (same triangles in the same order, the same
 * camera: fov 40 on a square image is 40 across) to float rounding: relative rmse below 1e-6,
 * path and pm, 16x16. A MediumInterface naming no medium is an error with file:line. */
TEST(pbrt_medium_matches_json) {
    const char *dir = pm_test_tmpdir();
    char p[1024], cmd[8192], out[8192];
    snprintf(p, sizeof p, "%s/fog.pbrt", dir);
    ASSERT(write_text(p,
        "Scale -1 1 1\nLookAt 0 1 -4  0 1 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n"
        "Film \"image\" \"integer xresolution\" 16 \"integer yresolution\" 16\nIntegrator \"path\" \"integer maxdepth\" 64\n"
        "WorldBegin\n"
        "MakeNamedMedium \"smoke\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.2 0.2 0.2] \"rgb sigma_s\" [1 2 3] "
        "\"float scale\" 2 \"float g\" 0.3\n"
        "Material \"matte\" \"rgb Kd\" [0.5 0.5 0.5]\n"
        "Shape \"trianglemesh\" \"point P\" [-5 0 -5  5 0 -5  5 0 5  -5 0 5] \"integer indices\" [0 2 1 0 3 2]\n"
        "AttributeBegin\n  AreaLightSource \"diffuse\" \"rgb L\" [5 5 5]\n"
        "  Shape \"trianglemesh\" \"point P\" [-1 3 -1  1 3 -1  1 3 1  -1 3 1] \"integer indices\" [0 1 2 0 2 3]\nAttributeEnd\n"
        "AttributeBegin\n  Material \"interface\"\n  MediumInterface \"smoke\" \"\"\n  Translate 0 1 0\n"
        "  Shape \"sphere\" \"float radius\" 0.8\nAttributeEnd\nWorldEnd\n") == 0);
    snprintf(p, sizeof p, "%s/fog.json", dir);
    ASSERT(write_text(p,
        "{\"camera\": {\"eye\": [0, 1, -4], \"look_at\": [0, 1, -3], \"up\": [0, 1, 0], \"fov_deg\": 40, \"width\": 16, \"height\": 16},\n"
        " \"media\": {\"smoke\": {\"sigma_a\": 0.4, \"sigma_s\": [2, 4, 6], \"g\": 0.3}},\n"
        " \"materials\": {\"m\": {\"type\": \"lambert\", \"reflectance\": 0.5},\n"
        "   \"lamp\": {\"type\": \"lambert\", \"reflectance\": 0.5, \"emission\": 5}, \"b\": {\"type\": \"null\"}},\n"
        " \"objects\": [{\"type\": \"mesh\", \"vertices\": [[-5, 0, -5], [5, 0, -5], [5, 0, 5], [-5, 0, 5]], \"triangles\": [[0, 2, 1], [0, 3, 2]], \"material\": \"m\"},\n"
        "   {\"type\": \"mesh\", \"vertices\": [[-1, 3, -1], [1, 3, -1], [1, 3, 1], [-1, 3, 1]], \"triangles\": [[0, 1, 2], [0, 2, 3]], \"material\": \"lamp\"},\n"
        "   {\"type\": \"sphere\", \"center\": [0, 1, 0], \"radius\": 0.8, \"material\": \"b\", \"interior_medium\": \"smoke\"}],\n"
        " \"render\": {\"max_depth\": 64}}\n") == 0);
    for (int m = 0; m < 2; m++) {
        snprintf(cmd, sizeof cmd,
                 "cd '%s' && R='%s/render' && O='--quiet --threads 2 --spp 16 --seed 3 --mode %s' && "
                 "$R fog.pbrt $O --hdr p.pfm >/dev/null 2>p.err && $R fog.json $O --hdr j.pfm >/dev/null && "
                 "cat p.err && $R --compare p.pfm j.pfm",
                 dir, pm_test_build_dir(), m ? "pm" : "path");
        int rc = pm_test_run(cmd, out, sizeof out);
        ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
        EXPECT_MSG(!strstr(out, "warning"), "%s", out);
        const char *r = strstr(out, "rel_rmse ");
        double rel = r ? atof(r + 9) : 1;
        const char *mn = strstr(out, "mean_b ");
        printf("    %s: rel_rmse %.3g (image mean %.6g)\n", m ? "pm" : "path", rel, mn ? atof(mn + 7) : NAN);
        EXPECT_MSG(rel < 1e-6, "%s: %s", m ? "pm" : "path", out);
    }
    cJSON *o = NULL;
    json_err e;
    EXPECT(pbrt_convert_text("WorldBegin\nMediumInterface \"fog\" \"\"\n", "t.pbrt", &o, &e) < 0 &&
           strstr(e.msg, "t.pbrt:2: MediumInterface: no medium named \"fog\""));
    cJSON_Delete(o);
}

/* Oracle: the pbrt file itself. `render --dump-scene x.pbrt` prints our document of it, which
 * loads and renders the same image bit for bit (path, 8x8, same seed), from another directory
 * (the Include was resolved when converting). */
TEST(pbrt_dump_scene_round_trip) {
    char cmd[8192], out[8192];
    snprintf(cmd, sizeof cmd,
             "cd '%s' && R='%s/render' && P='%s/data/pbrt/cornell_box.pbrt' && $R --dump-scene \"$P\" > d.json && "
             "O='--width 8 --height 8 --spp 4 --seed 2 --quiet' && $R d.json $O --hdr a.pfm >/dev/null && "
             "$R \"$P\" $O --hdr b.pfm >/dev/null && cmp a.pfm b.pfm && echo SAME",
             pm_test_tmpdir(), pm_test_build_dir(), pm_test_source_dir());
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 0 && strstr(out, "SAME"), "exit %d: %s", rc, out);
}

/* Oracle: pbrt_materials.c's rule, by hand. "uber" and "substrate" become ours as plastic does:
 * a mix of Kd under a smooth Fresnel coat tinted by Ks, the coat's ior uber's "index" (pbrt-v3's
 * name) or 1.5; uber's Kr, Kt and opacity are lost, with a warning naming the file and line. */
TEST(pbrt_uber_and_substrate_convert) {
    const char *t = "LookAt 0 0 -5 0 0 0 0 1 0\nCamera \"perspective\"\nWorldBegin\n"
                    "Material \"uber\" \"rgb Kd\" [0.1 0.2 0.3] \"rgb Ks\" [0.2 0.2 0.2] \"rgb Kr\" [0.3 0.3 0.3] \"float index\" 1.6\n"
                    "Shape \"sphere\"\n"
                    "Material \"substrate\" \"rgb Kd\" [0.4 0.5 0.6] \"rgb Ks\" [0.1 0.1 0.1]\n"
                    "Shape \"sphere\" \"float radius\" 2\n";
    char wpath[1100];
    snprintf(wpath, sizeof wpath, "%s/uber_warnings.txt", pm_test_tmpdir());
    fflush(stderr);
    FILE *saved = freopen(wpath, "w", stderr);
    cJSON *d = convert_ok(t);
    if (saved) fflush(stderr);
    char *w = read_text(wpath);
    ASSERT(d && w);
    EXPECT_MSG(strstr(w, "t.pbrt:4: warning: Material \"uber\": Kr, Kt and opacity are lost"), "%s", w);
    EXPECT_MSG(strstr(w, "t.pbrt:6: warning: Material \"substrate\": the glossy lobe (Ks [0.1 0.1 0.1]"), "%s", w);
    free(w);
    const cJSON *mats = cJSON_GetObjectItemCaseSensitive(d, "materials");
    const cJSON *u = cJSON_GetObjectItemCaseSensitive(mats, "pbrt:0"), *s = cJSON_GetObjectItemCaseSensitive(mats, "pbrt:1");
    ASSERT(u && s);
    EXPECT(strcmp(cJSON_GetObjectItemCaseSensitive(u, "type")->valuestring, "mix") == 0);
    EXPECT(strcmp(cJSON_GetObjectItemCaseSensitive(u, "specular")->valuestring, "fresnel") == 0);
    EXPECT_NEAR(num_at(u, "ior"), 1.6, 1e-12);
    EXPECT_NEAR(num_at(u, "diffuse.2"), 0.3, 1e-12);
    EXPECT_NEAR(num_at(u, "specular_tint.0"), 0.2, 1e-12);
    EXPECT_NEAR(num_at(s, "ior"), 1.5, 1e-12);
    EXPECT_NEAR(num_at(s, "diffuse.1"), 0.5, 1e-12);
    EXPECT_NEAR(num_at(s, "specular_tint.2"), 0.1, 1e-12);
    cJSON_Delete(d);
}
