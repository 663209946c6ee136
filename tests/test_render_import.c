/* test_render_import.c: scenes and meshes written elsewhere: the OBJ and wo3 readers, mesh
 * transforms and smooth normals, Tungsten scene conversion (rotation order, units, errors),
 * `render --dump-scene`, and renders that compare imported scenes with their own-format
 * equivalents.
 *
 * Oracles, one per test (details above each): hand-counted triangles and indices of small OBJ
 * texts; the file:line or byte offset of every malformed input; the bytes of a wo3 file written
 * here; rotations composed from axis-angle matrices, and Tungsten's own Cornell box block
 * transforms (boxes that must stand upright on the floor); power / (pi area) for emitters; the
 * analytic sphere normal for recomputed smooth normals; a hand-written scene of ours for the
 * converted Tungsten Cornell box (same image within noise, path and pm); the analytic sphere
 * for a tessellated OBJ sphere (region means within 1%); path tracing for photon mapping of a
 * water caustic (regions within 5%, the caustic within 10%); the original for its dump (the
 * same image, bit for bit).
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "../render/image/compare.h"
#include "../render/image/film.h"
#include "../render/load/mesh.h"
#include "../render/load/obj.h"
#include "../render/load/scene_load.h"
#include "../render/scene/medium.h"
#include "../render/scene/scene.h"
#include "../render/load/tungsten.h"
#include "../render/load/wo3.h"

/* ---- helpers ------------------------------------------------------------------------------ */

static int write_text(const char *path, const char *text) {
    FILE *f = fopen(path, "w");
    if (!f) return -1;
    fputs(text, f);
    return fclose(f);
}

static int write_bytes(const char *path, const void *b, size_t n) {
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    size_t w = fwrite(b, 1, n, f);
    return fclose(f) == 0 && w == n ? 0 : -1;
}

/* Parse OBJ text; on failure err holds the message. */
static int obj_text(const char *text, mesh_data *m, char *err, size_t cap) {
    return obj_parse(text, strlen(text), "t.obj", m, err, cap);
}

/* A mesh made by scripts/gen-mesh.sh (args after the script name) into dir/name. */
static int gen_mesh(const char *args, const char *path) {
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/gen-mesh.sh' %s > '%s'", pm_test_source_dir(), args, path);
    return pm_test_run(cmd, NULL, 0);
}

/* render SCENE at 32x32 into pfm with extra flags; output (stdout + stderr) into buf. */
static int render_file(const char *scn, const char *flags, const char *pfm, char *buf, size_t cap) {
    /* --width/--height given later in flags win over these */
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "%s/render '%s' --width 32 --height 32 --quiet --threads 2 --hdr '%s' %s",
             pm_test_build_dir(), scn, pfm, flags);
    return pm_test_run(cmd, buf, cap);
}

static const char *shipped(const char *name) {
    static char buf[4][2048];
    static int k;
    k = (k + 1) % 4;
    snprintf(buf[k], sizeof buf[k], "%s/data/scenes/%s", pm_test_source_dir(), name);
    return buf[k];
}

/* ---- 1. OBJ ------------------------------------------------------------------------------- */

/* Oracle: counted by hand. A quad, a pentagon (fan: 3 triangles) with negative indices and
 * v//n corners, v/t/n corners, and two usemtl groups. */
TEST(obj_polygons_negative_indices_usemtl) {
    const char *t = "# test\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\n"
                    "usemtl a\nf 1 2 3 4\n"
                    "v 2 0 0\nv 3 0 0\nv 3.5 1 0\nv 2.5 2 0\nv 2 1 0\n"
                    "usemtl b\nf -5//1 -4//1 -3//1 -2//-1 -1//1\n"
                    "g group\ns off\nusemtl a\nf 1/1/1 2/1/1 3/1/1   # trailing comment\n";
    mesh_data m;
    char err[256] = "";
    ASSERT_MSG(obj_text(t, &m, err, sizeof err) == 0, "%s", err);
    ASSERT_EQ_INT(m.npos, 9);
    ASSERT_EQ_INT(m.ntris, 2 + 3 + 1);
    ASSERT_EQ_INT(m.ngroups, 2);
    EXPECT(strcmp(m.groups[0], "a") == 0 && strcmp(m.groups[1], "b") == 0);
    int want[6][3] = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}, {4, 6, 7}, {4, 7, 8}, {0, 1, 2}};
    int grp[6] = {0, 0, 1, 1, 1, 0};
    for (int i = 0; i < 6; i++) {
        for (int k = 0; k < 3; k++) EXPECT_EQ_INT(m.tri[i][k], want[i][k]);
        EXPECT_EQ_INT(m.tri_group[i], grp[i]);
    }
    ASSERT(m.tri_n != NULL);
    EXPECT_EQ_INT(m.tri_n[0][0], -1); /* the first quad gave no normals */
    EXPECT_EQ_INT(m.tri_n[2][0], 0);
    EXPECT_EQ_INT(m.tri_n[5][2], 0);
    mesh_free(&m);
}

/* Oracle: the line of each malformed statement and the reason, for every error the reader
 * knows (one OBJ text each); and nothing is returned (a failed parse frees the mesh). */
TEST(obj_errors_name_line_and_reason) {
    static const struct {
        const char *text, *want;
    } cases[] = {
        {"v 0 0 0\nv 1 0\nf 1 2 1\n", "t.obj:2: v: expected 3 numbers, got 2"},         /* truncated */
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "t.obj:4: vertex index 4 out of range"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n", "t.obj:4: vertex index -4 out of range"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "t.obj:4: vertex index 0"},
        {"v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n", "t.obj:2: v: coordinate 2 is not finite"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 inf\nf 1 2 3\n", "t.obj:3: v: coordinate 3 is not finite"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 1e999\nf 1 2 3\n", "t.obj:3: v: coordinate 3 is not finite"},
        {"v 0 0 0\nv 1 0 x\n", "t.obj:2: v: coordinate 3 is not a number"},
        {"v 0 0 0\nv 1 0 0.00000000000000000000000000000000000000000000000000000000000000000001\n",
         "t.obj:2: v: coordinate 3 is too long a number"}, /* never cut short silently */
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\n", "t.obj: empty mesh"},
        {"# nothing\n", "t.obj: empty mesh"},
        {"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n", "t.obj: empty mesh: all 1 faces are degenerate (zero area; the first at line 4)"},
        {"v 0 0 0\nv 1 0 0\nf 1 2\n", "t.obj:3: f: a face needs at least 3 corners, got 2"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n", "t.obj:5: normal index 2 out of range"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3x\n", "t.obj:4: f: corner 3: unexpected character 'x'"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 a\n", "t.obj:4: f: corner 3 is not an index"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\nf 1 2 3\n", "t.obj:4: unsupported statement \"l\""},
        {"v 0 0 0\nvn 0 0 0\n", "t.obj:2: vn: zero normal"},
        {"v 0 0 0\nusemtl\n", "t.obj:2: usemtl: missing material name"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        mesh_data m;
        char err[256] = "";
        int rc = obj_text(cases[i].text, &m, err, sizeof err);
        EXPECT_MSG(rc < 0, "case %zu parsed", i);
        EXPECT_MSG(strncmp(err, cases[i].want, strlen(cases[i].want)) == 0, "case %zu: got \"%s\", want \"%s...\"",
                   i, err, cases[i].want);
        EXPECT(m.pos == NULL && m.tri == NULL && m.ntris == 0);
    }
}

/* ---- 2. wo3 ------------------------------------------------------------------------------- */

static void put_u64(unsigned char *p, uint64_t v) {
    for (int i = 0; i < 8; i++) p[i] = (unsigned char)(v >> (8 * i));
}
static void put_u32(unsigned char *p, uint32_t v) {
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(v >> (8 * i));
}
static void put_f32(unsigned char *p, float f) {
    uint32_t u;
    memcpy(&u, &f, 4);
    put_u32(p, u);
}

/* A tetrahedron in wo3 layout (4 vertices of 32 bytes, 4 triangles of 16 bytes): 208 bytes. */
static size_t tetra_wo3(unsigned char *b) {
    static const float P[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    static const uint32_t T[4][3] = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
    put_u64(b, 4);
    for (int i = 0; i < 4; i++) {
        unsigned char *v = b + 8 + 32 * i;
        for (int k = 0; k < 3; k++) put_f32(v + 4 * k, P[i][k]);
        for (int k = 0; k < 3; k++) put_f32(v + 12 + 4 * k, P[i][k] - 0.25f); /* outward-ish */
        put_f32(v + 24, 0.5f);
        put_f32(v + 28, 0.5f);
    }
    put_u64(b + 136, 4);
    for (int i = 0; i < 4; i++) {
        for (int k = 0; k < 3; k++) put_u32(b + 144 + 16 * i + 4 * k, T[i][k]);
        put_u32(b + 144 + 16 * i + 12, (uint32_t)-1);
    }
    return 208;
}

/* Oracle: the values written into the bytes above. */
TEST(wo3_reads_tungsten_layout) {
    unsigned char b[256];
    size_t n = tetra_wo3(b);
    mesh_data m;
    char err[256] = "";
    ASSERT_MSG(wo3_parse(b, n, "t.wo3", &m, err, sizeof err) == 0, "%s", err);
    ASSERT_EQ_INT(m.npos, 4);
    ASSERT_EQ_INT(m.ntris, 4);
    EXPECT_NEAR(m.pos[3].z, 1.0, 0);
    EXPECT_NEAR(m.nrm[1].x, 0.75, 0);
    EXPECT_EQ_INT(m.tri[3][0], 1);
    EXPECT_EQ_INT(m.tri[3][2], 3);
    EXPECT_EQ_INT(m.tri_n[3][1], 2);
    mesh_free(&m);
    /* and from a file, through mesh_load's extension dispatch */
    char path[1024];
    snprintf(path, sizeof path, "%s/tetra.WO3", pm_test_tmpdir());
    ASSERT(write_bytes(path, b, n) == 0);
    ASSERT_MSG(mesh_load(path, &m, err, sizeof err) == 0, "%s", err);
    EXPECT_EQ_INT(m.ntris, 4);
    mesh_free(&m);
}

/* Oracle: the byte offset and reason of each corruption of the tetrahedron: cut at every
 * length (truncated), one byte too many, a NaN position, an index out of range, no triangle;
 * a degenerate triangle is skipped and counted (3 of 4 kept, its byte offset kept). */
TEST(wo3_errors_name_byte_offset) {
    unsigned char b[256], c[256];
    size_t n = tetra_wo3(b);
    char err[256];
    mesh_data m;
    for (size_t len = 0; len < n; len++) { /* every truncation */
        err[0] = 0;
        int rc = wo3_parse(b, len, "t.wo3", &m, err, sizeof err);
        EXPECT_MSG(rc < 0 && strstr(err, "t.wo3: byte ") && strstr(err, "truncated"), "length %zu: %s", len, err);
    }
    memcpy(c, b, n);
    c[n] = 0;
    EXPECT(wo3_parse(c, n + 1, "t.wo3", &m, err, sizeof err) < 0 && strstr(err, "byte 208: 1 bytes after"));
    memcpy(c, b, n);
    put_f32(c + 8 + 32 * 2 + 4, NAN); /* vertex 2, y */
    EXPECT_MSG(wo3_parse(c, n, "t.wo3", &m, err, sizeof err) < 0 &&
               strstr(err, "byte 76: vertex 2: position y is not finite"), "%s", err);
    memcpy(c, b, n);
    put_u32(c + 144 + 16 * 3 + 8, 4); /* triangle 3, third index */
    EXPECT_MSG(wo3_parse(c, n, "t.wo3", &m, err, sizeof err) < 0 &&
               strstr(err, "byte 200: triangle 3: vertex index 4 out of range"), "%s", err);
    memcpy(c, b, n);
    put_u32(c + 144 + 16 * 1 + 4, 0); /* triangle 1: 0 0 3: skipped and counted, not an error */
    EXPECT_MSG(wo3_parse(c, n, "t.wo3", &m, err, sizeof err) == 0, "%s", err);
    EXPECT_EQ_INT(m.ntris, 3);
    EXPECT_EQ_INT(m.nskipped, 1);
    EXPECT_MSG(strcmp(m.first_skip, "byte 160 (triangle 1)") == 0, "%s", m.first_skip);
    mesh_free(&m);
    memcpy(c, b, 144);
    put_u64(c + 136, 0); /* no triangle */
    EXPECT_MSG(wo3_parse(c, 144, "t.wo3", &m, err, sizeof err) < 0 && strstr(err, "empty mesh"), "%s", err);
}

/* Oracle: a malformed mesh file through the renderer exits 2 with the scene's JSON path, the
 * file and its line, and writes no image. */
TEST(render_bad_mesh_exits_2_with_file_line) {
    const char *dir = pm_test_tmpdir();
    char obj[1024], scn[1024], pfm[1024], out[4096];
    snprintf(obj, sizeof obj, "%s/bad.obj", dir);
    snprintf(scn, sizeof scn, "%s/s.json", dir);
    snprintf(pfm, sizeof pfm, "%s/o.pfm", dir);
    ASSERT(write_text(obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7\n") == 0);
    ASSERT(write_text(scn, "{\"camera\": {\"eye\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, "
                           "\"width\": 8, \"height\": 8},\n \"materials\": {\"m\": {\"type\": \"lambert\", "
                           "\"reflectance\": 0.5, \"emission\": 1}},\n \"objects\": [{\"type\": \"mesh\", "
                           "\"file\": \"bad.obj\", \"material\": \"m\"}]}\n") == 0);
    int rc = render_file(scn, "", pfm, out, sizeof out);
    EXPECT_EQ_INT(rc, 2);
    EXPECT_MSG(strstr(out, "$.objects[0].file: ") && strstr(out, "bad.obj:5: vertex index 7 out of range"), "%s", out);
    FILE *f = fopen(pfm, "rb");
    EXPECT(f == NULL);
    if (f) fclose(f);
    /* and --dump-scene refuses it the same way */
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "%s/render --dump-scene '%s'", pm_test_build_dir(), scn);
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 2);
    EXPECT_MSG(strstr(out, "bad.obj:5:"), "%s", out);
}

/* ---- 3. transforms and normals ------------------------------------------------------------ */

/* Oracle: recomputed smooth normals of a tessellated unit sphere against the exact normal
 * (each corner within 1 degree at 64 x 32), a transform's effect on points and normals
 * (normals by the inverse transpose: a sphere scaled 2x in x has normals ~ (x/4, y, z)), and
 * a cube's corners, which the crease angle keeps flat (each corner normal is its face's). */
TEST(mesh_smooth_normals_and_transform) {
    char path[1024], err[256] = "";
    snprintf(path, sizeof path, "%s/s.obj", pm_test_tmpdir());
    ASSERT_EQ_INT(gen_mesh("sphere 64 32 1 0 0 0", path), 0);
    mesh_data m;
    ASSERT_MSG(mesh_load(path, &m, err, sizeof err) == 0, "%s", err);
    ASSERT_EQ_INT(m.ntris, 2 * 64 * 31 - 0 * 64); /* caps 2 x 64 tris, 30 bands of 64 quads */
    ASSERT_EQ_INT(mesh_smooth_normals(&m, 1), 0);
    double worst = 1;
    for (int t = 0; t < m.ntris; t++)
        for (int k = 0; k < 3; k++) worst = fmin(worst, v3_dot(m.corner_n[t][k], v3_norm(m.pos[m.tri[t][k]])));
    EXPECT_MSG(worst > cos(M_PI / 180), "worst corner %.3f degrees off", acos(worst) * 180 / M_PI);
    double M[3][4] = {{2, 0, 0, 1}, {0, 1, 0, 2}, {0, 0, 1, 3}};
    ASSERT_EQ_INT(mesh_transform(&m, (const double(*)[4])M, path, err, sizeof err), 0);
    ASSERT_EQ_INT(mesh_smooth_normals(&m, 0), 0); /* the file's vn, transformed */
    worst = 1;
    for (int t = 0; t < m.ntris; t++)
        for (int k = 0; k < 3; k++) {
            vec3 p = v3_sub(m.pos[m.tri[t][k]], v3(1, 2, 3));
            EXPECT_NEAR(p.x * p.x / 4 + p.y * p.y + p.z * p.z, 1.0, 1e-12);
            worst = fmin(worst, v3_dot(m.corner_n[t][k], v3_norm(v3(p.x / 4, p.y, p.z))));
        }
    EXPECT_MSG(worst > 1 - 1e-12, "transformed normal off by %g", 1 - worst);
    double S[3][4] = {{1, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 1, 0}};
    EXPECT(mesh_transform(&m, (const double(*)[4])S, path, err, sizeof err) < 0 && strstr(err, "singular"));
    mesh_free(&m);
    const char *cube = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
                       "f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 4 8 7 3\nf 1 5 8 4\nf 2 3 7 6\n";
    ASSERT_MSG(obj_text(cube, &m, err, sizeof err) == 0, "%s", err);
    ASSERT_EQ_INT(mesh_smooth_normals(&m, 1), 0);
    for (int t = 0; t < m.ntris; t++) {
        vec3 a = m.pos[m.tri[t][0]], n = v3_norm(v3_cross(v3_sub(m.pos[m.tri[t][1]], a), v3_sub(m.pos[m.tri[t][2]], a)));
        for (int k = 0; k < 3; k++) EXPECT_NEAR(v3_dot(m.corner_n[t][k], n), 1.0, 1e-12);
    }
    mesh_free(&m);
}

/* A uniform scale by k (negative k mirrors in x too), as a 3x4 matrix. */
static void scale_matrix(double k, double M[3][4]) {
    memset(M, 0, 12 * sizeof(double));
    M[0][0] = k < 0 ? k : fabs(k);
    M[1][1] = M[2][2] = fabs(k);
}

/* Oracle: the inverse transpose, analytic for a scale: a mesh scaled by any factor keeps its
 * normals (mirrored in x: x negated), and its points are k p (rounded once); a scale by
 * (a, a, 2a) turns normal n into (n.x, n.y, n.z / 2), normalized. The determinant of a uniform
 * scale by 1e-150 is 1e-450, which underflows to 0 in a double, and by 1e150 overflows: both
 * were called "singular" (and 1e-90, determinant 1e-270, was accepted, but its cofactors, of
 * 1e-180, squared to 0 when normalized: NaN normals). Singular (linearly dependent columns:
 * a zero column, the rank-2 matrix 1..9, the same scaled by 1e-150) is still singular. */
TEST(mesh_transform_scale_is_not_singular) {
    char path[1024], err[256] = "";
    snprintf(path, sizeof path, "%s/s.obj", pm_test_tmpdir());
    ASSERT_EQ_INT(gen_mesh("sphere 16 8 1 0 0 0", path), 0);
    mesh_data m0;
    ASSERT_MSG(mesh_load(path, &m0, err, sizeof err) == 0, "%s", err);
    ASSERT(m0.nnrm > 0);
    const double ks[] = {1e-150, -1e-150, 1e-90, 1e-40, 1e-30, 1e30, 1e150, 1e300, 1e-300};
    for (size_t j = 0; j < sizeof ks / sizeof ks[0]; j++) {
        double M[3][4];
        scale_matrix(ks[j], M);
        mesh_data m;
        ASSERT_MSG(mesh_load(path, &m, err, sizeof err) == 0, "%s", err);
        int rc = mesh_transform(&m, (const double(*)[4])M, path, err, sizeof err);
        EXPECT_MSG(rc == 0, "scale %g: %s", ks[j], err);
        if (rc == 0) {
            double worst_p = 0, worst_n = 0;
            for (int k = 0; k < m.npos; k++) {
                vec3 want = v3_scale(m0.pos[k], fabs(ks[j]));
                if (ks[j] < 0) want.x = -want.x;
                worst_p = fmax(worst_p, v3_maxabs(v3_sub(m.pos[k], want)) / fabs(ks[j]));
            }
            for (int k = 0; k < m.nnrm; k++) {
                vec3 want = v3_norm(m0.nrm[k]);
                if (ks[j] < 0) want.x = -want.x;
                double d = v3_maxabs(v3_sub(m.nrm[k], want));
                worst_n = isfinite(d) ? fmax(worst_n, d) : INFINITY;
            }
            EXPECT_MSG(worst_p <= 1e-15, "scale %g: points off by %g of the scale", ks[j], worst_p);
            EXPECT_MSG(worst_n <= 1e-15, "scale %g: normals off by %g", ks[j], worst_n);
        }
        mesh_free(&m);
    }
    { /* (a, a, 2a), a = 1e-100: cofactors of M itself would be of 1e-200 */
        double M[3][4] = {{1e-100, 0, 0, 0}, {0, 1e-100, 0, 0}, {0, 0, 2e-100, 0}};
        mesh_data m;
        ASSERT_MSG(mesh_load(path, &m, err, sizeof err) == 0, "%s", err);
        ASSERT_MSG(mesh_transform(&m, (const double(*)[4])M, path, err, sizeof err) == 0, "%s", err);
        double worst = 0;
        for (int k = 0; k < m.nnrm; k++) {
            vec3 n = m0.nrm[k], want = v3_norm(v3(n.x, n.y, n.z / 2));
            double d = v3_maxabs(v3_sub(m.nrm[k], want));
            worst = isfinite(d) ? fmax(worst, d) : INFINITY;
        }
        EXPECT_MSG(worst <= 1e-15, "scale (1, 1, 2) x 1e-100: normals off by %g", worst);
        mesh_free(&m);
    }
    static const struct {
        double M[3][4];
        const char *why;
    } singular[] = {
        {{{1, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 1, 0}}, "its column 2 is zero"},
        {{{1e-150, 0, 0, 0}, {0, 0, 0, 0}, {0, 0, 1e-150, 0}}, "its column 2 is zero"},
        {{{1, 2, 3, 0}, {4, 5, 6, 0}, {7, 8, 9, 0}}, "its columns, scaled to length 1, span a volume of"},
        {{{1e-150, 2e-150, 3e-150, 0}, {4e-150, 5e-150, 6e-150, 0}, {7e-150, 8e-150, 9e-150, 0}},
         "its columns, scaled to length 1, span a volume of"},
    };
    for (size_t j = 0; j < sizeof singular / sizeof singular[0]; j++) {
        mesh_data m;
        ASSERT_MSG(mesh_load(path, &m, err, sizeof err) == 0, "%s", err);
        int rc = mesh_transform(&m, singular[j].M, path, err, sizeof err);
        EXPECT_MSG(rc < 0 && strstr(err, "the transform is singular (") && strstr(err, singular[j].why),
                   "singular case %zu: rc %d: %s", j, rc, err);
        mesh_free(&m);
    }
    mesh_free(&m0);
}

/* A unit quad (two triangles, 1.41421 across) with a normal, scaled by k about the origin,
 * seen by a camera scaled with it: written to dir/q<tag>.json (and dir/q.obj). */
static void quad_scene(const char *tag, const char *transform) {
    char obj[1024], scn[1024], text[4096];
    snprintf(obj, sizeof obj, "%s/q.obj", pm_test_tmpdir());
    write_text(obj, "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\n");
    snprintf(scn, sizeof scn, "%s/q%s.json", pm_test_tmpdir(), tag);
    snprintf(text, sizeof text,
             "{\"camera\": {\"eye\": [0.5, 0.5, 3], \"look_at\": [0.5, 0.5, 0], \"fov_deg\": 40, \"width\": 8, "
             "\"height\": 8},\n \"materials\": {\"lamp\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 1}},\n"
             " \"objects\": [{\"type\": \"mesh\", \"file\": \"q.obj\", \"material\": \"lamp\", \"transform\": %s}]}\n",
             transform);
    write_text(scn, text);
}

/* Oracle: the Ranges table (data/scenes/README.md, scene.h): lengths 1e-100 to 1e100, a
 * triangle's longest edge among them, and a range error names the field, gives the value and
 * the range, and exits 2 (render_validate_range_errors). A transform that scales the unit quad
 * by 1e-150 makes its triangles 1.41421e-150 across: out of range, said of $.objects[0].transform
 * (it used to be "$.objects[0].file: q.obj: the transform is singular or not finite
 * (determinant 0)"); by 1e150 it moves a vertex to 1e150. Scales 1e-30 and 1e-40 (determinants
 * 1e-90 and 1e-120, fine in a double) keep it in range: an emitter of radiance 1 seen whole
 * renders the same at any scale, so the image's mean equals the unscaled one's (the scene
 * scaled, camera included: the camera is outside the mesh's transform, so it is moved with
 * the scale written into the scene). A zero column is still "singular", exit 2. */
TEST(render_mesh_transform_range_not_singular) {
    const char *dir = pm_test_tmpdir();
    char out[8192], scn[1024], pfm[1024];
    static const struct {
        const char *tag, *transform, *want;
    } bad[] = {
        {"m150", "[1e-150,0,0,0, 0,1e-150,0,0, 0,0,1e-150,0, 0,0,0,1]",
         "$.objects[0].transform: makes a triangle 1.41421 across in the file 1.41421e-150 across, below the "
         "supported range of lengths, 1e-100 to 1e+100"},
        {"p150", "[1e150,0,0,0, 0,1e150,0,0, 0,0,1e150,0, 0,0,0,1]",
         "$.objects[0].transform: moves the file's vertex 2, [1, 0, 0], to [1e+150, 0, 0], outside the "
         "supported range of coordinates, -1e+100 to 1e+100"},
        {"zero", "[1,0,0,0, 0,0,0,0, 0,0,1,0, 0,0,0,1]", "the transform is singular (its column 2 is zero"},
    };
    for (size_t j = 0; j < sizeof bad / sizeof bad[0]; j++) {
        quad_scene(bad[j].tag, bad[j].transform);
        snprintf(scn, sizeof scn, "%s/q%s.json", dir, bad[j].tag);
        snprintf(pfm, sizeof pfm, "%s/q%s.pfm", dir, bad[j].tag);
        int rc = render_file(scn, "--mode path", pfm, out, sizeof out);
        EXPECT_MSG(rc == 2 && strstr(out, bad[j].want), "%s: exit %d, want \"%s\": %s", bad[j].tag, rc,
                   bad[j].want, out);
        EXPECT_MSG(!strstr(out, "Rendering"), "%s: it rendered: %s", bad[j].tag, out);
    }
    double mean[3];
    const double ks[3] = {1, 1e-30, 1e-40};
    for (int j = 0; j < 3; j++) {
        char tr[256], text[4096], tag[16];
        snprintf(tag, sizeof tag, "ok%d", j);
        snprintf(tr, sizeof tr, "[%g,0,0,0, 0,%g,0,0, 0,0,%g,0, 0,0,0,1]", ks[j], ks[j], ks[j]);
        snprintf(scn, sizeof scn, "%s/q%s.json", dir, tag);
        snprintf(text, sizeof text,
                 "{\"camera\": {\"eye\": [%g, %g, %g], \"look_at\": [%g, %g, 0], \"fov_deg\": 40, \"width\": 8, "
                 "\"height\": 8},\n \"materials\": {\"lamp\": {\"type\": \"lambert\", \"reflectance\": 0, "
                 "\"emission\": 1}},\n \"objects\": [{\"type\": \"mesh\", \"file\": \"q.obj\", \"material\": "
                 "\"lamp\", \"transform\": %s}]}\n", 0.5 * ks[j], 0.5 * ks[j], 3 * ks[j], 0.5 * ks[j], 0.5 * ks[j], tr);
        ASSERT(write_text(scn, text) == 0);
        snprintf(pfm, sizeof pfm, "%s/q%s.pfm", dir, tag);
        int rc = render_file(scn, "--mode path --spp 4", pfm, out, sizeof out);
        ASSERT_MSG(rc == 0, "scale %g: exit %d: %s", ks[j], rc, out);
        film f;
        ASSERT(film_read_pfm(&f, pfm) == 0);
        double sum = 0;
        for (size_t i = 0; i < (size_t)f.width * (size_t)f.height * 3; i++) sum += f.px[i];
        mean[j] = sum / ((double)f.width * f.height * 3);
        film_free(&f);
    }
    EXPECT_MSG(mean[0] > 0.2 && mean[0] < 0.8, "the quad should fill part of the image: mean %g", mean[0]);
    EXPECT_NEAR(mean[1], mean[0], 1e-3 * mean[0]);
    EXPECT_NEAR(mean[2], mean[0], 1e-3 * mean[0]);
}

/* A scene of ours around one mesh object (extra keys in obj_extra), written to dir/name. */
static void mesh_scene(const char *path, const char *obj_extra) {
    char text[4096];
    snprintf(text, sizeof text,
             "{\"camera\": {\"eye\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},\n"
             " \"materials\": {\"m\": {\"type\": \"lambert\", \"reflectance\": 0.5}, \"a\": {\"type\": \"lambert\", "
             "\"reflectance\": 0.2}, \"glass\": {\"type\": \"dielectric\", \"ior\": 1.5}},\n"
             " \"objects\": [{\"type\": \"mesh\", %s}],\n \"lights\": [{\"type\": \"point\", \"position\": [0, 0, 5], "
             "\"power\": 10}]}\n", obj_extra);
    write_text(path, text);
}

/* Oracle: geometry. A smooth sphere mesh: the shading normal at a hit is the interpolated one
 * (not the facet's), always on the geometric normal's side, and the geometric normal alone
 * says which side a ray came from: the same triangle hit from outside and from inside (a ray
 * from the centre) reports the same outward ng. usemtl picks scene materials by name. */
TEST(mesh_shading_normal_never_decides_side) {
    const char *dir = pm_test_tmpdir();
    char obj[1024], scn[1024], err_unused[8];
    (void)err_unused;
    snprintf(obj, sizeof obj, "%s/s.obj", dir);
    snprintf(scn, sizeof scn, "%s/s.json", dir);
    ASSERT_EQ_INT(gen_mesh("sphere 12 6 1 0 0 0", obj), 0);
    mesh_scene(scn, "\"file\": \"s.obj\", \"material\": \"glass\", \"smooth\": true");
    scene s;
    json_err e;
    ASSERT_MSG(scene_load(&s, scn, &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(s.ntri_ns, s.ntris);
    hit out, in;
    vec3 d = v3_norm(v3(0.3, 0.2, -1));
    ray r1 = {v3_scale(d, -5), d}, r2 = {v3(0, 0, 0), v3_neg(d)};
    ASSERT(scene_intersect(&s, r1, INFINITY, &out));
    ASSERT(scene_intersect(&s, r2, INFINITY, &in));
    EXPECT_EQ_INT(out.prim, in.prim);
    EXPECT_NEAR(v3_dot(out.ng, in.ng), 1.0, 1e-12);                  /* same ng from both sides */
    EXPECT(v3_dot(out.ng, v3_neg(r1.d)) > 0 && v3_dot(in.ng, v3_neg(r2.d)) < 0); /* front, back */
    EXPECT(v3_dot(out.ns, out.ng) > 0 && v3_dot(out.ns, out.ng) < 1 - 1e-6);  /* smooth, same side */
    EXPECT_MSG(v3_dot(out.ns, v3_norm(out.p)) > v3_dot(out.ng, v3_norm(out.p)), "ns is not closer to the sphere normal");
    scene_free(&s);
    /* usemtl: faces before any usemtl take "material", the rest their group's material */
    char obj2[1024];
    snprintf(obj2, sizeof obj2, "%s/u.obj", dir);
    ASSERT(write_text(obj2, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nusemtl a\nf 2 4 3\n") == 0);
    mesh_scene(scn, "\"file\": \"u.obj\", \"material\": \"m\"");
    ASSERT_MSG(scene_load(&s, scn, &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(s.ntris, 2);
    EXPECT(strcmp(s.mats[s.tris[0].mat].name, "m") == 0 && strcmp(s.mats[s.tris[1].mat].name, "a") == 0);
    EXPECT(s.tri_ns == NULL);
    scene_free(&s);
    mesh_scene(scn, "\"file\": \"u.obj\"");
    EXPECT(scene_load(&s, scn, &e) < 0 && strstr(e.msg, "$.objects[0].material: missing"));
    ASSERT(write_text(obj2, "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl nosuch\nf 1 2 3\n") == 0);
    mesh_scene(scn, "\"file\": \"u.obj\", \"material\": \"m\"");
    EXPECT_MSG(scene_load(&s, scn, &e) < 0 && strstr(e.msg, "usemtl \"nosuch\" names no material"), "%s", e.msg);
    mesh_scene(scn, "\"file\": \"u.obj\", \"material\": \"m\", \"usemtl\": false");
    EXPECT_MSG(scene_load(&s, scn, &e) == 0, "%s", e.msg);
    scene_free(&s);
    /* a mirroring transform turns the front around (the winding decides, as in Tungsten) */
    ASSERT(write_text(obj2, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n") == 0);
    mesh_scene(scn, "\"file\": \"u.obj\", \"material\": \"m\", \"transform\": [-2, 0, 0, 1, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]");
    ASSERT_MSG(scene_load(&s, scn, &e) == 0, "%s", e.msg);
    EXPECT_NEAR(s.tris[0].n.z, -1, 1e-12);
    EXPECT_NEAR(s.tris[0].v0.x, 1, 1e-12);
    EXPECT_NEAR(s.tris[0].e1.x, -2, 1e-12);
    scene_free(&s);
    mesh_scene(scn, "\"file\": \"missing.obj\", \"material\": \"m\"");
    EXPECT_MSG(scene_load(&s, scn, &e) < 0 && strstr(e.msg, "missing.obj: cannot open"), "%s", e.msg);
    mesh_scene(scn, "\"file\": \"u.obj\", \"material\": \"m\", \"transform\": [1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1]");
    EXPECT_MSG(scene_load(&s, scn, &e) < 0 && strstr(e.msg, "$.objects[0].transform: the last row"), "%s", e.msg);
}

/* ---- 4. Tungsten -------------------------------------------------------------------------- */

/* Rotation by angle t (degrees) about the unit axis a (Rodrigues), counter-clockwise seen from
 * the axis's tip. */
static void axis_angle(vec3 a, double t, double R[3][3]) {
    double c = cos(t * M_PI / 180), s = sin(t * M_PI / 180), C = 1 - c;
    double m[3][3] = {{c + a.x * a.x * C, a.x * a.y * C - a.z * s, a.x * a.z * C + a.y * s},
                      {a.y * a.x * C + a.z * s, c + a.y * a.y * C, a.y * a.z * C - a.x * s},
                      {a.z * a.x * C - a.y * s, a.z * a.y * C + a.x * s, c + a.z * a.z * C}};
    memcpy(R, m, sizeof m);
}
static void mat_mul(double A[3][3], double B[3][3], double out[3][3]) {
    double r[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) r[i][j] = A[i][0] * B[0][j] + A[i][1] * B[1][j] + A[i][2] * B[2][j];
    memcpy(out, r, sizeof r);
}
static vec3 mat_apply(double R[3][3], vec3 v) {
    return v3(R[0][0] * v.x + R[0][1] * v.y + R[0][2] * v.z, R[1][0] * v.x + R[1][1] * v.y + R[1][2] * v.z,
              R[2][0] * v.x + R[2][1] * v.y + R[2][2] * v.z);
}

/* Lowest and highest y of a Tungsten cube (unit cube, transform T R S) under the rotation R. */
static void cube_y_range(double R[3][3], vec3 pos, vec3 scale, double *lo, double *hi) {
    *lo = INFINITY;
    *hi = -INFINITY;
    for (int i = 0; i < 8; i++) {
        vec3 p = v3((i & 1 ? 0.5 : -0.5) * scale.x, (i & 2 ? 0.5 : -0.5) * scale.y, (i & 4 ? 0.5 : -0.5) * scale.z);
        double y = mat_apply(R, p).y + pos.y;
        *lo = fmin(*lo, y);
        *hi = fmax(*hi, y);
    }
}

/* Oracle for the rotation order, three ways.
 * (1) Axis-angle composition: rotation [x, y, z] is Ry(-y) Rx(x) Rz(z), the z angle acting
 *     first; checked at random angles to 1e-12.
 * (2) A case that tells the orders apart by hand: [90, 90, 0] takes +y to -x (x first: +y ->
 *     +z, then -90 about y: +z -> -x); applying y first would give +z.
 * (3) Tungsten's own Cornell box (data/example-scenes/cornell-box in its repository) stands
 *     its blocks on the floor with rotation [90, 90, -163.36] (short block, position y 0.3,
 *     scale [0.594811, 0.604394, 0.6]) and [90, 180, 160.812] (tall block, y 0.6, scale
 *     [0.607289, 0.597739, 1.2]): only the right order makes each block upright, from y = 0
 *     to twice its centre. The converter's cube must do so, while the other five orders of the
 *     same three angles tilt the short block (its lowest corner 0.0026 or more off the floor). */
TEST(tungsten_rotation_order) {
    uint64_t st = 12345;
    for (int it = 0; it < 200; it++) {
        double a[3];
        for (int k = 0; k < 3; k++) {
            st = st * 6364136223846793005ULL + 1442695040888963407ULL;
            a[k] = (double)(st >> 11) / 9007199254740992.0 * 720 - 360;
        }
        double R[3][3], X[3][3], Y[3][3], Z[3][3], W[3][3];
        tungsten_rotation(v3(a[0], a[1], a[2]), R);
        axis_angle(v3(1, 0, 0), a[0], X);
        axis_angle(v3(0, 1, 0), -a[1], Y);
        axis_angle(v3(0, 0, 1), a[2], Z);
        mat_mul(X, Z, W);
        mat_mul(Y, W, W);
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) EXPECT_NEAR(R[i][j], W[i][j], 1e-12);
    }
    double R[3][3];
    tungsten_rotation(v3(90, 90, 0), R);
    vec3 y = mat_apply(R, v3(0, 1, 0));
    EXPECT_NEAR(y.x, -1, 1e-12);
    EXPECT_NEAR(y.y, 0, 1e-12);
    EXPECT_NEAR(y.z, 0, 1e-12);
    /* (3) through the converter: a scene with Tungsten's two blocks */
    const char *t = "{\"bsdfs\": [{\"name\": \"w\", \"type\": \"lambert\", \"albedo\": 0.7}],\n"
                    " \"primitives\": [\n"
                    "  {\"type\": \"cube\", \"bsdf\": \"w\", \"emission\": 1, \"transform\": {\"position\": [0.328631, 0.3, 0.374592],"
                    " \"scale\": [0.594811, 0.604394, 0.6], \"rotation\": [90, 90, -163.36]}},\n"
                    "  {\"type\": \"cube\", \"bsdf\": \"w\", \"transform\": {\"position\": [-0.335439, 0.6, -0.291415],"
                    " \"scale\": [0.607289, 0.597739, 1.2], \"rotation\": [90, 180, 160.812]}}],\n"
                    " \"camera\": {\"resolution\": 8, \"transform\": {\"position\": [0, 1, 6.8], \"look_at\": [0, 1, 0]}}}";
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, t, &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(s.ntris, 24);
    double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
    for (int i = 0; i < s.ntris; i++) {
        int b = i / 12;
        vec3 v[3] = {s.tris[i].v0, v3_add(s.tris[i].v0, s.tris[i].e1), v3_add(s.tris[i].v0, s.tris[i].e2)};
        for (int k = 0; k < 3; k++) {
            lo[b] = fmin(lo[b], v[k].y);
            hi[b] = fmax(hi[b], v[k].y);
        }
    }
    EXPECT_NEAR(lo[0], 0, 1e-6);
    EXPECT_NEAR(hi[0], 0.6, 1e-6);
    EXPECT_NEAR(lo[1], 0, 1e-6);
    EXPECT_NEAR(hi[1], 1.2, 1e-6);
    /* every cube face's front looks out of its block (the emitting short block lights outward) */
    for (int i = 0; i < 12; i++) {
        vec3 c = v3_add(s.tris[i].v0, v3_scale(v3_add(s.tris[i].e1, s.tris[i].e2), 1.0 / 3));
        EXPECT(v3_dot(s.tris[i].n, v3_sub(c, v3(0.328631, 0.3, 0.374592))) > 0);
    }
    scene_free(&s);
    /* the other orders of the same angles tilt the short block out of [0, 0.6] */
    double X[3][3], Y[3][3], Z[3][3];
    axis_angle(v3(1, 0, 0), 90, X);
    axis_angle(v3(0, 1, 0), -90, Y);
    axis_angle(v3(0, 0, 1), -163.36, Z);
    double(*orders[5][3])[3] = {{Y, Z, X}, {X, Y, Z}, {X, Z, Y}, {Z, X, Y}, {Z, Y, X}};
    for (int o = 0; o < 5; o++) {
        double A[3][3];
        mat_mul(orders[o][0], orders[o][1], A);
        mat_mul(A, orders[o][2], A);
        double l, h;
        cube_y_range(A, v3(0.328631, 0.3, 0.374592), v3(0.594811, 0.604394, 0.6), &l, &h);
        EXPECT_MSG(fabs(l) > 1e-3 || fabs(h - 0.6) > 1e-3, "order %d also stands the block upright (y from %g to %g)", o, l, h);
    }
}

/* Oracle: the Tungsten definitions: a quad is the unit square in x-z around the origin with
 * its front along +y, emitting from the front only; "power" P of a quad becomes radiance
 * P / (pi area); a sphere's radius is its largest scale; resolution, fov, spp and max_bounces
 * map to our camera and render keys; a null bsdf without emission, and a forward one without
 * a medium, disappear; a dielectric without refraction keeps only its Fresnel reflection. */
TEST(tungsten_conversion_values) {
    const char *t =
        "{\"media\": [], \"bsdfs\": [{\"name\": \"w\", \"type\": \"lambert\", \"albedo\": [0.5, 0.6, 0.7]},\n"
        "  {\"name\": \"g\", \"type\": \"dielectric\", \"ior\": 1.4, \"enable_refraction\": false},\n"
        "  {\"name\": \"n\", \"type\": \"null\"}, {\"name\": \"mirror\", \"type\": \"mirror\", \"albedo\": 0.9}],\n"
        " \"primitives\": [\n"
        "  {\"type\": \"quad\", \"bsdf\": \"w\", \"power\": [10, 20, 30], \"transform\": {\"position\": [1, 2, 3], \"scale\": [2, 1, 0.5]}},\n"
        "  {\"type\": \"sphere\", \"bsdf\": \"g\", \"transform\": {\"position\": [0, 1, 0], \"scale\": [0.5, 0.25, 0.75]}},\n"
        "  {\"type\": \"quad\", \"bsdf\": \"n\"}, {\"type\": \"cube\", \"bsdf\": {\"type\": \"forward\"}},\n"
        "  {\"type\": \"sphere\", \"bsdf\": {\"type\": \"mirror\"}, \"transform\": {\"scale\": 2}}],\n"
        " \"camera\": {\"type\": \"pinhole\", \"fov\": 35, \"resolution\": [40, 30], \"reconstruction_filter\": \"tent\",\n"
        "   \"transform\": {\"position\": [0, 1, 6], \"look_at\": [0, 1, 0], \"up\": [0, 1, 0]}},\n"
        " \"integrator\": {\"type\": \"path_tracer\", \"max_bounces\": 7, \"min_bounces\": 0},\n"
        " \"renderer\": {\"spp\": 9, \"output_file\": \"x.png\"}}";
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, t, &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(s.ntris, 2);
    ASSERT_EQ_INT(s.nspheres, 2);
    const triangle *q = &s.tris[0];
    EXPECT_NEAR(q->n.y, 1, 1e-12);
    EXPECT_NEAR(q->area * 2, 1.0, 1e-12); /* 2 x 0.5 */
    const material *m = &s.mats[q->mat];
    EXPECT_NEAR(m->emission.x, 10 / M_PI, 1e-12);
    EXPECT_NEAR(m->emission.z, 30 / M_PI, 1e-12);
    EXPECT_NEAR(m->diffuse.y, 0.6, 0);
    EXPECT(!m->two_sided);
    EXPECT_NEAR(s.spheres[0].r, 0.75, 1e-12);
    EXPECT_NEAR(s.spheres[0].c.y, 1, 1e-12);
    const material *g = &s.mats[s.spheres[0].mat];
    EXPECT(g->fresnel && g->transparency == 0 && v3_iszero(g->diffuse) && g->ior == 1.4);
    EXPECT_NEAR(s.spheres[1].r, 2, 1e-12);
    EXPECT_NEAR(s.mats[s.spheres[1].mat].specular, 1, 0);
    EXPECT_EQ_INT(s.cam.width, 40);
    EXPECT_EQ_INT(s.cam.height, 30);
    EXPECT_EQ_INT(s.cam.spp, 9);
    EXPECT_NEAR(s.cam.tan_half_w, tan(17.5 * M_PI / 180), 1e-12);
    EXPECT_EQ_INT(s.settings.max_depth, 7);
    EXPECT(strcmp(s.settings.mode, "path") == 0);
    /* Tungsten's image right is forward x up, like ours: at +z looking at -z that is +x */
    EXPECT_NEAR(s.cam.right.x, 1, 1e-12);
    scene_free(&s);
}

/* Oracle: Tungsten's definitions of media (HomogeneousMedium: sigma_a and sigma_s times
 * density; the phase function isotropic or henyey_greenstein with g; Primitive: int_medium
 * inside, ext_medium outside; the camera's medium around it), mapped as data/scenes/README.md
 * says: the camera's medium becomes the global one, int_medium the interior, a glass surface
 * that names no medium keeps the one around it inside (Tungsten changes the medium only at a
 * surface that names one), a forward boundary with a medium becomes a null surface, and an
 * inline medium object gets its path as its name. */
TEST(tungsten_media_conversion_values) {
    const char *t =
        "{\"media\": [{\"name\": \"fog\", \"type\": \"homogeneous\", \"sigma_a\": 0.01, \"sigma_s\": [0.05, 0.06, 0.07], \"density\": 2},\n"
        "  {\"name\": \"smoke\", \"type\": \"homogeneous\", \"sigma_s\": 3, \"phase_function\": {\"type\": \"henyey_greenstein\", \"g\": 0.5}},\n"
        "  {\"name\": \"iso\", \"type\": \"homogeneous\", \"sigma_a\": 1, \"phase_function\": \"isotropic\", \"max_bounces\": 64}],\n"
        " \"bsdfs\": [{\"name\": \"w\", \"type\": \"lambert\", \"albedo\": 0.5}],\n"
        " \"primitives\": [\n"
        "  {\"type\": \"quad\", \"bsdf\": \"w\", \"ext_medium\": \"fog\", \"transform\": {\"scale\": 10}},\n"
        "  {\"type\": \"sphere\", \"bsdf\": {\"type\": \"dielectric\", \"ior\": 1.33}, \"int_medium\": \"smoke\", \"ext_medium\": \"fog\",\n"
        "   \"transform\": {\"position\": [-1, 1, 0]}},\n"
        "  {\"type\": \"cube\", \"bsdf\": {\"type\": \"forward\"}, \"int_medium\": \"iso\", \"transform\": {\"position\": [1, 1, 0]}},\n"
        "  {\"type\": \"sphere\", \"bsdf\": {\"type\": \"dielectric\"}, \"transform\": {\"position\": [0, 3, 0], \"scale\": 0.5}},\n"
        "  {\"type\": \"sphere\", \"bsdf\": {\"type\": \"dielectric\"}, \"ext_medium\": \"fog\", \"transform\": {\"position\": [0, 5, 0], \"scale\": 0.5}},\n"
        "  {\"type\": \"sphere\", \"bsdf\": {\"type\": \"null\"}, \"int_medium\": {\"type\": \"homogeneous\", \"sigma_s\": 0.5},\n"
        "   \"transform\": {\"position\": [3, 1, 0]}},\n"
        "  {\"type\": \"cube\", \"bsdf\": {\"type\": \"forward\"}, \"transform\": {\"position\": [5, 1, 0]}}],\n"
        " \"camera\": {\"medium\": \"fog\", \"resolution\": 8, \"transform\": {\"position\": [0, 1, 9], \"look_at\": [0, 1, 0]}}}";
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, t, &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(s.nmedia, 4);
    int fog = -1, smoke = -1, iso = -1, inl = -1;
    for (int i = 0; i < s.nmedia; i++) {
        if (strcmp(s.media[i].name, "fog") == 0) fog = i;
        if (strcmp(s.media[i].name, "smoke") == 0) smoke = i;
        if (strcmp(s.media[i].name, "iso") == 0) iso = i;
        if (strcmp(s.media[i].name, "primitives[5].int_medium") == 0) inl = i;
    }
    ASSERT(fog >= 0 && smoke >= 0 && iso >= 0 && inl >= 0);
    EXPECT_EQ_INT(s.global_medium, fog);
    EXPECT_EQ_INT(s.camera_medium, fog);
    EXPECT_NEAR(s.media[fog].sigma_a.y, 0.02, 1e-15);
    EXPECT_NEAR(s.media[fog].sigma_s.z, 0.14, 1e-15);
    EXPECT_NEAR(s.media[fog].g, 0, 0);
    EXPECT_NEAR(s.media[smoke].sigma_s.x, 3, 0);
    EXPECT_NEAR(s.media[smoke].sigma_a.x, 0, 0);
    EXPECT_NEAR(s.media[smoke].g, 0.5, 0);
    EXPECT_NEAR(s.media[iso].sigma_t.y, 1, 0);
    EXPECT_NEAR(s.media[inl].sigma_s.x, 0.5, 0);
    /* objects: quad, sphere (smoke), cube (iso, null), sphere (fog kept inside), sphere
     * (ext only: nothing inside), sphere (inline, null); the forward cube without a medium is
     * dropped */
    ASSERT_EQ_INT(s.nobj, 6);
    EXPECT_EQ_INT(s.obj_medium[0], -1);
    EXPECT_EQ_INT(s.obj_medium[1], smoke);
    EXPECT_EQ_INT(s.obj_medium[2], iso);
    EXPECT_EQ_INT(s.obj_medium[3], -1); /* names no medium: keeps the ray's (fog) inside */
    ASSERT(s.obj_iface != NULL);
    EXPECT_EQ_INT(s.obj_iface[3], MEDIUM_IFACE_KEEP);
    EXPECT_EQ_INT(s.obj_iface[1], MEDIUM_IFACE_DECLARED);
    EXPECT_EQ_INT(s.obj_medium_out[1], fog);
    EXPECT_EQ_INT(s.obj_medium[4], -1);
    EXPECT_EQ_INT(s.obj_medium[5], inl);
    EXPECT_EQ_INT(s.has_null, 1);
    EXPECT_EQ_INT(s.ntris, 2 + 12);
    EXPECT(s.mats[s.tris[2].mat].kind == MAT_NULL);
    EXPECT(s.mats[s.spheres[0].mat].kind != MAT_NULL);
    EXPECT(s.mats[s.spheres[3].mat].kind == MAT_NULL);
    scene_free(&s);
}

/* Loads a one-bsdf Tungsten scene with the primitives prims (and extra top-level text) and
 * expects a refusal whose message holds want (exact: is want). */
static void expect_refused(size_t i, const char *prims, const char *extra, const char *want, int exact) {
    char t[2048];
    snprintf(t, sizeof t, "{\"bsdfs\": [{\"name\": \"w\", \"type\": \"lambert\"}], \"primitives\": [%s],\n"
             " \"camera\": {\"transform\": {\"position\": [0, 1, 5], \"look_at\": [0, 0, 0]}}%s}",
             prims, extra);
    scene s;
    json_err e;
    e.msg[0] = 0;
    int rc = scene_load_text(&s, t, &e);
    EXPECT_MSG(rc < 0, "case %zu loaded", i);
    if (rc == 0) scene_free(&s);
    EXPECT_MSG(exact ? strcmp(e.msg, want) == 0 : strstr(e.msg, want) != NULL, "case %zu: \"%s\", want \"%s\"", i,
               e.msg, want);
}

/* Oracle: the JSON path and the feature named in each message, for what the subset leaves
 * out (every one would change the image). */
TEST(tungsten_unsupported_is_an_error_naming_path) {
    static const struct {
        const char *prims, *extra, *want;
    } cases[] = {
        {"{\"type\": \"quad\", \"bsdf\": \"w\", \"int_medium\": \"fog\"}", "", "$.primitives[0].int_medium: unknown medium \"fog\""},
        {"{\"type\": \"quad\", \"bsdf\": \"w\"}", ", \"media\": [{\"name\": \"fog\", \"type\": \"voxel\"}]",
         "$.media[0].type: medium type \"voxel\" is not supported (homogeneous)"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\"}", ", \"media\": [{\"type\": \"homogeneous\"}]", "$.media[0].name: missing"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\"}",
         ", \"media\": [{\"name\": \"f\", \"type\": \"homogeneous\", \"phase_function\": {\"type\": \"rayleigh\"}}]",
         "$.media[0].phase_function.type: phase function \"rayleigh\" is not supported"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\"}",
         ", \"media\": [{\"name\": \"f\", \"type\": \"homogeneous\", \"phase_function\": {\"type\": \"henyey_greenstein\", \"g\": 1}}]",
         "$.media[0].phase_function.g: must be in (-1, 1)"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\"}", ", \"media\": [{\"name\": \"f\", \"type\": \"homogeneous\", \"sigma_s\": [1, -1, 1]}]",
         "$.media[0].sigma_s: must not be negative"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\"}", ", \"media\": [{\"name\": \"f\", \"type\": \"homogeneous\", \"density\": -2}]",
         "$.media[0].density: must not be negative"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\"}", ", \"media\": [{\"name\": \"f\", \"type\": \"homogeneous\", \"sigma_s\": \"t.vdb\"}]",
         "$.media[0].sigma_s: textures are not supported"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\"}", ", \"media\": [{\"name\": \"f\", \"type\": \"homogeneous\", \"max_bounces\": 3}]",
         "$.media[0].max_bounces: 3, below the integrator's max_bounces (64)"},
        {"{\"type\": \"sphere\", \"bsdf\": {\"type\": \"dielectric\"}, \"ext_medium\": \"f\"}", ", \"media\": [{\"name\": \"f\", \"type\": \"homogeneous\"}]",
         "$.media.f: the surfaces around the medium \"f\" enclose a volume of -4.18879: their sides are swapped, or the medium is unbounded"}, /* f outside a sphere: unbounded, not the camera's */
        {"{\"type\": \"quad\", \"bsdf\": {\"type\": \"dielectric\"}, \"int_medium\": \"f\"}",
         ", \"media\": [{\"name\": \"f\", \"type\": \"homogeneous\"}]",
         "$.media.f: the surfaces around the medium \"f\" do not close it: the edge"}, /* one quad cannot close a volume */
        {"{\"type\": \"sphere\", \"bsdf\": {\"type\": \"forward\"}, \"int_medium\": \"f\", \"emission\": 1}",
         ", \"media\": [{\"name\": \"f\", \"type\": \"homogeneous\"}]",
         "$.primitives[0].emission: an emitting \"forward\" medium boundary is not supported"},
        {"{\"type\": \"sphere\", \"bsdf\": \"w\", \"int_medium\": {\"type\": \"exponential\"}}", "",
         "$.primitives[0].int_medium.type: medium type \"exponential\""},
        {"{\"type\": \"disk\", \"bsdf\": \"w\"}", "", "$.primitives[0].type: primitive type \"disk\" is not supported"},
        {"{\"type\": \"quad\", \"bsdf\": {\"type\": \"plastic\"}}", "", "$.primitives[0].bsdf.type: bsdf type \"plastic\""},
        {"{\"type\": \"quad\", \"bsdf\": {\"type\": \"lambert\", \"albedo\": \"wood.png\"}}", "",
         "$.primitives[0].bsdf.albedo: textures are not supported"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\", \"bump\": \"b.png\"}", "", "$.primitives[0].bump: bump maps"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\", \"visible\": false}", "", "$.primitives[0].visible: not supported"},
        {"{\"type\": \"quad\", \"bsdf\": \"nosuch\"}", "", "$.primitives[0].bsdf: unknown bsdf \"nosuch\""},
        {"{\"type\": \"quad\", \"bsdf\": \"w\", \"transform\": {\"look_at\": [0, 0, 1]}}", "",
         "$.primitives[0].transform.look_at: not supported"},
        {"{\"type\": \"mesh\", \"file\": \"m.obj\", \"bsdf\": \"w\", \"backface_culling\": true}", "",
         "$.primitives[0].backface_culling: true is not supported"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\"}", ", \"integrator\": {\"min_bounces\": 2}", "$.integrator.min_bounces"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\"}", ", \"textures\": []", "$.textures: not supported"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\", \"emission\": [1, -1, 1]}", "", "$.primitives[0].emission"},
        /* our ranges (scene.h), named by the Tungsten file's paths */
        {"{\"type\": \"quad\", \"bsdf\": \"w\", \"emission\": [1, 2e30, 1]}", "",
         "$.primitives[0].emission: 2e+30 is outside the supported range, 0 to 1e+30"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\", \"power\": 1e31, \"transform\": {\"scale\": 1}}", "",
         "$.primitives[0].power: 1e+31 gives the radiance 3.1831e+30 (power / (pi area), area 1), outside the "
         "supported range, 0 to 1e+30"},
        {"{\"type\": \"sphere\", \"bsdf\": \"w\", \"emission\": 1e300}", "",
         "$.primitives[0].emission: 1e+300 is outside the supported range, 0 to 1e+30"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\"}",
         ", \"media\": [{\"name\": \"f\", \"type\": \"homogeneous\", \"sigma_s\": 1e60, \"density\": 1e41}]",
         "$.media[0]: sigma_a or sigma_s times density is 1e+101, outside the supported range, 0 to 1e+100 per unit length"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++)
        expect_refused(i, cases[i].prims, cases[i].extra, cases[i].want, 0);
    /* a camera that is not a pinhole, and one whose medium would matter */
    scene s;
    json_err e;
    EXPECT(scene_load_text(&s, "{\"primitives\": [], \"camera\": {\"type\": \"thinlens\", \"transform\": {\"look_at\": [0, 0, 1]}}}", &e) < 0 &&
           strstr(e.msg, "$.camera.type: camera type \"thinlens\""));
    EXPECT(scene_load_text(&s, "{\"primitives\": [], \"camera\": {\"medium\": \"fog\", \"transform\": {\"look_at\": [0, 0, 1]}}}", &e) < 0 &&
           strstr(e.msg, "$.camera.medium: unknown medium \"fog\""));
}

/* Oracle: the subset's key lists (tungsten.c): a key outside them names the nearest supported
 * key, as our own format's unknown keys do (worded so that it also fits a real Tungsten key
 * the subset leaves out); render --dump-scene refuses a scene whose render.mode is unknown,
 * as render does. */
TEST(tungsten_unsupported_key_names_the_nearest) {
    static const struct {
        const char *prims, *extra, *want;
    } cases[] = {
        {"{\"type\": \"quad\", \"bsdf\": \"w\", \"emision\": 1}", "",
         "$.primitives[0].emision: not supported (a primitive key outside the supported subset; the nearest "
         "supported key is \"emission\")"},
        {"{\"type\": \"quad\", \"bsdf\": {\"type\": \"lambert\", \"albdo\": 0.5}}", "",
         "$.primitives[0].bsdf.albdo: not supported (a bsdf key outside the supported subset; the nearest "
         "supported key is \"albedo\")"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\"}", ", \"integrator\": {\"max_bounce\": 3}",
         "$.integrator.max_bounce: not supported (an integrator key outside the supported subset; the nearest "
         "supported key is \"max_bounces\")"},
        {"{\"type\": \"quad\", \"bsdf\": \"w\", \"visible\": false}", "",
         "$.primitives[0].visible: not supported (a primitive key outside the supported subset)"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++)
        expect_refused(i, cases[i].prims, cases[i].extra, cases[i].want, 1);
    char path[1024], cmd[4096], out[8192];
    snprintf(path, sizeof path, "%s/mode.json", pm_test_tmpdir());
    ASSERT(write_text(path, "{\"camera\": {\"eye\": [0, 0, -5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 4, \"height\": 4},"
                            " \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
                            " \"objects\": [{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1,"
                            " \"material\": \"w\"}], \"render\": {\"mode\": \"pmm\"}}") == 0);
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' --dump-scene mode.json 2>&1 >/dev/null", pm_test_tmpdir(),
             pm_test_build_dir());
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 2 && strstr(out, "render: mode.json: $.render.mode: unknown mode \"pmm\"; modes:"),
               "--dump-scene: exit %d: %s", rc, out);
}

/* Oracle: tungsten.h: a key that does not change the image is skipped with a warning, and
 * every warning (like every error) names the scene file, as render's own warnings do
 * ("render: FILE: warning: ..."). The same scene given as text to the loader warns without a
 * file name. */
TEST(tungsten_warnings_name_the_file) {
    char path[1024], cmd[4096], out[16384];
    snprintf(path, sizeof path, "%s/tw.json", pm_test_tmpdir());
    FILE *f = fopen(path, "w");
    ASSERT(f);
    fputs("{\"bsdfs\": [{\"name\": \"w\", \"type\": \"lambert\"}, {\"name\": \"n\", \"type\": \"null\"}],\n"
          " \"primitives\": [{\"type\": \"quad\", \"bsdf\": \"w\"},\n"
          "  {\"type\": \"quad\", \"bsdf\": \"n\", \"emission\": 1, \"transform\": {\"position\": [0, 2, 0]}}],\n"
          " \"camera\": {\"tonemap\": \"filmic\", \"transform\": {\"position\": [0, 1, 5], \"look_at\": [0, 0, 0]}},\n"
          " \"renderer\": {\"output_file\": \"x.png\", \"spp\": 1},\n"
          " \"integrator\": {\"type\": \"path_tracer\", \"enable_light_sampling\": true}}\n", f);
    fclose(f);
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' tw.json --width 2 --height 2 --quiet --hdr tw.pfm 2>&1",
             pm_test_tmpdir(), pm_test_build_dir());
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 0, "exit %d: %s", rc, out);
    const char *want[] = {"render: tw.json: warning: $.camera.tonemap: ignored (does not change the image)",
                          "render: tw.json: warning: $.renderer.output_file: ignored",
                          "render: tw.json: warning: $.integrator.enable_light_sampling: ignored",
                          "render: tw.json: warning: $.primitives[1].bsdf: a \"null\" surface that emits"};
    for (size_t i = 0; i < sizeof want / sizeof *want; i++)
        EXPECT_MSG(strstr(out, want[i]), "no \"%s\" in: %s", want[i], out);
    /* No warning without the file's name. */
    for (const char *q = out; (q = strstr(q, "warning: ")) != NULL; q++) {
        const char *line = q;
        while (line > out && line[-1] != '\n') line--;
        EXPECT_MSG(strncmp(line, "render: tw.json: ", 17) == 0, "a warning without the file: %.120s", line);
    }
    /* An error names it too (render's prefix). */
    f = fopen(path, "w");
    ASSERT(f);
    fputs("{\"primitives\": [{\"type\": \"quad\", \"bsdf\": {\"type\": \"lambert\"}, \"emission\": 1e31}],"
          " \"camera\": {\"transform\": {\"look_at\": [0, 0, 1]}}}", f);
    fclose(f);
    rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 2 && strstr(out, "render: tw.json: $.primitives[0].emission: 1e+31 is outside the supported range"),
               "exit %d: %s", rc, out);
}

/* ---- 5. renders --------------------------------------------------------------------------- */

/* Compare image a with reference b: whole image and each object id in [1, nids] of the mask;
 * each relative difference of means must be within tol. Prints them. */
static void compare_regions(const char *what, const char *a, const char *b, const char *ids, int nids,
                            double tol_image, double tol_region) {
    film A, B, M;
    ASSERT_EQ_INT(film_read_pfm(&A, a), 0);
    ASSERT_EQ_INT(film_read_pfm(&B, b), 0);
    ASSERT_EQ_INT(film_read_pfm(&M, ids), 0);
    image_diff d;
    ASSERT_EQ_INT(image_compare(&A, &B, 0, 0, 0, 0, &d), 0);
    printf("    %s: image %+.2f%%", what, 100 * d.rel_mean);
    EXPECT_MSG(fabs(d.rel_mean) <= tol_image, "%s: image mean off by %+.2f%%", what, 100 * d.rel_mean);
    for (int id = 1; id <= nids; id++) {
        image_region r = {0, 0, 0, 0, &M, &id, 1};
        if (image_compare_region(&A, &B, &r, &d) < 0 || d.npixels < 20 || !(d.mean_b > 0)) continue;
        printf(", #%d %+.2f%%", id, 100 * d.rel_mean);
        EXPECT_MSG(fabs(d.rel_mean) <= tol_region, "%s: object %d (%ld pixels) off by %+.2f%%", what, id,
                   d.npixels, 100 * d.rel_mean);
    }
    printf("\n");
    film_free(&A);
    film_free(&B);
    film_free(&M);
}

/* Oracle: data/scenes/cornell_rect.json, the same box written by hand in our format. The
 * converted Tungsten file (data/scenes/cornell_tungsten.json: quads with rotations about z
 * and x, cubes turned about y and about x then z) must render the same image within noise:
 * path tracing at 32x32, 256 samples, and photon mapping at 64 samples, with different seeds
 * for the two files (so agreement is not shared noise): the image mean within 1.5% and each
 * object's mean within 6% (seed-to-seed spread of these regions measured up to about 2%). */
TEST(tungsten_cornell_matches_our_format) {
    static char out[65536];
    const char *dir = pm_test_tmpdir();
    char a[1024], b[1024], ids[1024];
    snprintf(a, sizeof a, "%s/t.pfm", dir);
    snprintf(b, sizeof b, "%s/o.pfm", dir);
    snprintf(ids, sizeof ids, "%s/ids.pfm", dir);
    ASSERT_MSG(render_file(shipped("cornell_rect.json"), "--mode objects --spp 16", ids, out, sizeof out) == 0, "%s", out);
    /* the same sizes under the sanitizers: 64 path samples left the ceiling's noise near 10% */
    const char *modes[2][2] = {{"path", "--spp 256"}, {"pm", "--spp 64"}};
    for (int k = 0; k < 2; k++) {
        char fl[256];
        snprintf(fl, sizeof fl, "--mode %s %s --seed 3", modes[k][0], modes[k][1]);
        ASSERT_MSG(render_file(shipped("cornell_tungsten.json"), fl, a, out, sizeof out) == 0, "%s", out);
        snprintf(fl, sizeof fl, "--mode %s %s --seed 4", modes[k][0], modes[k][1]);
        ASSERT_MSG(render_file(shipped("cornell_rect.json"), fl, b, out, sizeof out) == 0, "%s", out);
        compare_regions(modes[k][0], a, b, ids, 8, 0.015, 0.06);
    }
}

static int cmp_double(const void *x, const void *y) {
    double a = *(const double *)x, b = *(const double *)y;
    return (a > b) - (a < b);
}

/* Region means of a and b (pixels whose object id in the mask is id, or all with id 0), each
 * pixel's luminance clamped in both images to 4 times the median of b's in the region: a rare
 * firefly of a path through a medium then cannot move the mean of a few dozen pixels by more
 * than a few percent, and it is clamped alike in both images, so the comparison tests the
 * scene, not the tail of the noise. */
static void clamped_means(const film *a, const film *b, const film *m, int id, double *ma, double *mb, long *n) {
    long npx = (long)a->width * a->height, k = 0;
    double *lb = malloc((size_t)npx * sizeof *lb), sa = 0, sb = 0;
    *n = 0;
    *ma = *mb = 0;
    if (!lb) return;
    for (long i = 0; i < npx; i++)
        if (id == 0 || (int)m->px[3 * i] == id) lb[k++] = (b->px[3 * i] + b->px[3 * i + 1] + b->px[3 * i + 2]) / 3.0;
    if (k > 0) {
        qsort(lb, (size_t)k, sizeof *lb, cmp_double);
        double c = 4 * lb[k / 2];
        for (long i = 0; i < npx; i++) {
            if (id > 0 && (int)m->px[3 * i] != id) continue;
            sa += fmin((a->px[3 * i] + a->px[3 * i + 1] + a->px[3 * i + 2]) / 3.0, c);
            sb += fmin((b->px[3 * i] + b->px[3 * i + 1] + b->px[3 * i + 2]) / 3.0, c);
        }
        *ma = sa / (double)k;
        *mb = sb / (double)k;
    }
    *n = k;
    free(lb);
}

/* Oracle: the same scene written by hand in our format. A Tungsten-style file with media
 * (the camera in fog with density 2, a forward sphere holding forward-scattering smoke, a
 * forward cube holding a denser isotropic mist, a lamp quad) and our equivalent (global
 * medium, interior_medium, null surfaces) are path traced at 32x32, 512 samples, with
 * different seeds; with luminance clamped at 4 times the region's median (clamped_means), the
 * image mean agrees within 2% and each object's mean within 6%. Measured at 256 samples over
 * five seeds: image within 0.5% of the seeds' mean, objects within 2.8% (unclamped, one seed's
 * firefly moved the smoke sphere by 11%). */
TEST(tungsten_media_matches_our_format) {
    static char out[65536];
    const char *dir = pm_test_tmpdir();
    const char *tung =
        "{\"media\": [{\"name\": \"fog\", \"type\": \"homogeneous\", \"sigma_a\": 0.01, \"sigma_s\": 0.05, \"density\": 2},\n"
        "  {\"name\": \"smoke\", \"type\": \"homogeneous\", \"sigma_a\": [0.1, 0.2, 0.4], \"sigma_s\": 2,\n"
        "   \"phase_function\": {\"type\": \"henyey_greenstein\", \"g\": 0.5}},\n"
        "  {\"name\": \"mist\", \"type\": \"homogeneous\", \"sigma_a\": 0.5, \"sigma_s\": 1, \"density\": 0.5, \"phase_function\": \"isotropic\"}],\n"
        " \"bsdfs\": [{\"name\": \"white\", \"type\": \"lambert\", \"albedo\": 0.7},\n"
        "  {\"name\": \"edge\", \"type\": \"forward\"}, {\"name\": \"black\", \"type\": \"lambert\", \"albedo\": 0}],\n"
        " \"primitives\": [\n"
        "  {\"type\": \"quad\", \"bsdf\": \"white\", \"ext_medium\": \"fog\", \"transform\": {\"position\": [0, 0, 0], \"scale\": 4}},\n"
        "  {\"type\": \"quad\", \"bsdf\": \"white\", \"transform\": {\"position\": [0, 2, -2], \"scale\": 4, \"rotation\": [90, 0, 0]}},\n"
        "  {\"type\": \"quad\", \"bsdf\": \"black\", \"emission\": 4, \"transform\": {\"position\": [0, 3.9, 0], \"scale\": 2, \"rotation\": [180, 0, 0]}},\n"
        "  {\"type\": \"sphere\", \"bsdf\": \"edge\", \"int_medium\": \"smoke\", \"ext_medium\": \"fog\",\n"
        "   \"transform\": {\"position\": [-0.8, 1, 0], \"scale\": 0.8}},\n"
        "  {\"type\": \"cube\", \"bsdf\": \"edge\", \"int_medium\": \"mist\", \"transform\": {\"position\": [1, 0.9, 0], \"scale\": 1.2}}],\n"
        " \"camera\": {\"type\": \"pinhole\", \"fov\": 45, \"resolution\": 32, \"medium\": \"fog\",\n"
        "   \"transform\": {\"position\": [0, 2, 6], \"look_at\": [0, 1.5, 0], \"up\": [0, 1, 0]}},\n"
        " \"integrator\": {\"type\": \"path_tracer\", \"max_bounces\": 64}}\n";
    const char *ours =
        "{\"camera\": {\"eye\": [0, 2, 6], \"look_at\": [0, 1.5, 0], \"up\": [0, 1, 0], \"fov_deg\": 45, \"width\": 32, \"height\": 32},\n"
        " \"media\": {\"fog\": {\"sigma_a\": 0.02, \"sigma_s\": 0.1}, \"smoke\": {\"sigma_a\": [0.1, 0.2, 0.4], \"sigma_s\": 2, \"g\": 0.5},\n"
        "   \"mist\": {\"sigma_a\": 0.25, \"sigma_s\": 0.5}},\n"
        " \"medium\": \"fog\",\n"
        " \"materials\": {\"white\": {\"type\": \"lambert\", \"reflectance\": 0.7},\n"
        "   \"edge\": {\"type\": \"null\"}, \"lamp\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 4}},\n"
        " \"objects\": [\n"
        "  {\"type\": \"quad\", \"vertices\": [[-2, 0, -2], [-2, 0, 2], [2, 0, 2], [2, 0, -2]], \"material\": \"white\"},\n"
        "  {\"type\": \"quad\", \"vertices\": [[-2, 0, -2], [2, 0, -2], [2, 4, -2], [-2, 4, -2]], \"material\": \"white\"},\n"
        "  {\"type\": \"quad\", \"vertices\": [[-1, 3.9, -1], [1, 3.9, -1], [1, 3.9, 1], [-1, 3.9, 1]], \"material\": \"lamp\"},\n"
        "  {\"type\": \"sphere\", \"center\": [-0.8, 1, 0], \"radius\": 0.8, \"material\": \"edge\", \"interior_medium\": \"smoke\"},\n"
        "  {\"type\": \"mesh\", \"material\": \"edge\", \"interior_medium\": \"mist\",\n"
        "   \"vertices\": [[0.4, 0.3, -0.6], [1.6, 0.3, -0.6], [1.6, 1.5, -0.6], [0.4, 1.5, -0.6], [0.4, 0.3, 0.6], [1.6, 0.3, 0.6], [1.6, 1.5, 0.6], [0.4, 1.5, 0.6]],\n"
        "   \"triangles\": [[0, 3, 2], [0, 2, 1], [4, 5, 6], [4, 6, 7], [0, 4, 7], [0, 7, 3], [1, 2, 6], [1, 6, 5], [0, 1, 5], [0, 5, 4], [3, 7, 6], [3, 6, 2]]}]}\n";
    char ts[1024], os[1024], a[1024], b[1024], ids[1024];
    snprintf(ts, sizeof ts, "%s/media_tungsten.json", dir);
    snprintf(os, sizeof os, "%s/media_ours.json", dir);
    snprintf(a, sizeof a, "%s/mt.pfm", dir);
    snprintf(b, sizeof b, "%s/mo.pfm", dir);
    snprintf(ids, sizeof ids, "%s/mids.pfm", dir);
    ASSERT_EQ_INT(write_text(ts, tung), 0);
    ASSERT_EQ_INT(write_text(os, ours), 0);
    ASSERT_MSG(render_file(os, "--mode objects --spp 16", ids, out, sizeof out) == 0, "%s", out);
    ASSERT_MSG(render_file(ts, "--mode path --spp 512 --seed 3", a, out, sizeof out) == 0, "%s", out);
    ASSERT_MSG(render_file(os, "--mode path --spp 512 --seed 4", b, out, sizeof out) == 0, "%s", out);
    film A, B, M;
    ASSERT_EQ_INT(film_read_pfm(&A, a), 0);
    ASSERT_EQ_INT(film_read_pfm(&B, b), 0);
    ASSERT_EQ_INT(film_read_pfm(&M, ids), 0);
    ASSERT(A.width == B.width && A.height == B.height && M.width == A.width && M.height == A.height);
    printf("    media (clamped means):");
    for (int id = 0; id <= 5; id++) {
        double ma, mb, tol = id == 0 ? 0.02 : 0.06;
        long n;
        clamped_means(&A, &B, &M, id, &ma, &mb, &n);
        if (id > 0 && (n < 20 || !(mb > 0))) continue;
        printf(" %s%d %+.2f%%", id ? "#" : "image/", id, 100 * (ma / mb - 1));
        EXPECT_MSG(fabs(ma / mb - 1) <= tol, "object %d (%ld pixels): Tungsten %g, ours %g (%+.2f%%, tolerance %.0f%%)",
                   id, n, ma, mb, 100 * (ma / mb - 1), 100 * tol);
    }
    printf("\n");
    film_free(&A);
    film_free(&B);
    film_free(&M);
}

/* Oracle: the analytic sphere. The same scene with a sphere of radius 100 and with an OBJ of
 * it (128 x 64 segments, smooth, the file's exact normals), path traced at 32x32 with 256
 * samples and the same seed: the image, the sphere's pixels and each wall's pixels agree
 * within 1% (the polygon's silhouette is inside the sphere's by at most r (1 - cos(pi/128)) =
 * 0.03 units, far below a pixel). */
TEST(obj_sphere_matches_analytic_sphere) {
    static char out[65536];
    const char *dir = pm_test_tmpdir();
    char obj[1024], s1[1024], s2[1024], a[1024], b[1024], ids[1024];
    snprintf(obj, sizeof obj, "%s/sphere.obj", dir);
    ASSERT_EQ_INT(gen_mesh("sphere 128 64 100 278 150 300", obj), 0);
    const char *fmt =
        "{\"camera\": {\"eye\": [278, 273, -800], \"look_at\": [278, 273, 0], \"fov_deg\": 39.3, \"width\": 32, \"height\": 32},\n"
        " \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.7}, \"r\": {\"type\": \"lambert\", "
        "\"reflectance\": [0.6, 0.1, 0.1]}, \"light\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 15}},\n"
        " \"objects\": [\n"
        "  {\"type\": \"quad\", \"vertices\": [[0, 0, 0], [0, 0, 560], [556, 0, 560], [556, 0, 0]], \"material\": \"w\"},\n"
        "  {\"type\": \"quad\", \"vertices\": [[0, 0, 560], [0, 550, 560], [556, 550, 560], [556, 0, 560]], \"material\": \"w\"},\n"
        "  {\"type\": \"quad\", \"vertices\": [[556, 0, 0], [556, 0, 560], [556, 550, 560], [556, 550, 0]], \"material\": \"r\"},\n"
        "  {\"type\": \"quad\", \"vertices\": [[0, 550, 0], [556, 550, 0], [556, 550, 560], [0, 550, 560]], \"material\": \"w\"},\n"
        "  {\"type\": \"quad\", \"vertices\": [[200, 549, 200], [350, 549, 200], [350, 549, 350], [200, 549, 350]], \"material\": \"light\"},\n"
        "  %s]}\n";
    char text[8192];
    snprintf(s1, sizeof s1, "%s/analytic.json", dir);
    snprintf(text, sizeof text, fmt, "{\"type\": \"sphere\", \"center\": [278, 150, 300], \"radius\": 100, \"material\": \"w\"}");
    ASSERT(write_text(s1, text) == 0);
    snprintf(s2, sizeof s2, "%s/mesh.json", dir);
    snprintf(text, sizeof text, fmt, "{\"type\": \"mesh\", \"file\": \"sphere.obj\", \"smooth\": true, \"material\": \"w\"}");
    ASSERT(write_text(s2, text) == 0);
    snprintf(a, sizeof a, "%s/mesh.pfm", dir);
    snprintf(b, sizeof b, "%s/analytic.pfm", dir);
    snprintf(ids, sizeof ids, "%s/ids.pfm", dir);
    const char *spp = PM_TEST_SANITIZED ? "--spp 64 --seed 5" : "--spp 256 --seed 5";
    ASSERT_MSG(render_file(s2, spp, a, out, sizeof out) == 0, "%s", out);
    ASSERT_MSG(render_file(s1, spp, b, out, sizeof out) == 0, "%s", out);
    ASSERT_MSG(render_file(s1, "--mode objects --spp 16", ids, out, sizeof out) == 0, "%s", out);
    compare_regions("sphere", a, b, ids, 6, 0.01, 0.01);
}

/* Oracle: path tracing. data/scenes/water_caustic.json (a glass slab with a wavy top from
 * scripts/gen-mesh.sh, lit through by an area light) in photon mapping against path tracing
 * at 32x32: every object's mean within 5%, and the caustic (the floor pixels below the slab,
 * lit only through the water) within 10%. The path tracer sees the caustic when a diffuse
 * bounce from the floor refracts through the slab into the area light. */
TEST(water_caustic_pm_matches_path) {
    static char out[65536];
    const char *dir = pm_test_tmpdir();
    char a[1024], b[1024], ids[1024];
    snprintf(a, sizeof a, "%s/pm.pfm", dir);
    snprintf(b, sizeof b, "%s/pt.pfm", dir);
    snprintf(ids, sizeof ids, "%s/ids.pfm", dir);
    const char *scn = shipped("water_caustic.json");
    /* the same sizes under the sanitizers: 256 path samples left a wall's noise near 9% */
    ASSERT_MSG(render_file(scn, "--mode path --spp 2048 --seed 8", b, out, sizeof out) == 0, "%s", out);
    ASSERT_MSG(render_file(scn, "--mode pm --spp 64 --seed 9 --pm caustic_photons=200000", a, out, sizeof out) == 0,
               "%s", out);
    ASSERT_MSG(render_file(scn, "--mode objects --spp 16", ids, out, sizeof out) == 0, "%s", out);
    compare_regions("water", a, b, ids, 7, 0.05, 0.05);
    /* the caustic: floor pixels (id 1) in the rows and columns below the slab */
    film A, B, M;
    ASSERT_EQ_INT(film_read_pfm(&A, a), 0);
    ASSERT_EQ_INT(film_read_pfm(&B, b), 0);
    ASSERT_EQ_INT(film_read_pfm(&M, ids), 0);
    int id = 1;
    image_region r = {10, 18, 12, 8, &M, &id, 1};
    image_diff d;
    ASSERT_EQ_INT(image_compare_region(&A, &B, &r, &d), 0);
    printf("    caustic: %+.2f%% (%ld pixels)\n", 100 * d.rel_mean, d.npixels);
    EXPECT(d.npixels >= 30);
    EXPECT_MSG(fabs(d.rel_mean) <= 0.10, "caustic off by %+.2f%%", 100 * d.rel_mean);
    film_free(&A);
    film_free(&B);
    film_free(&M);
}

/* Oracle: the original scene. `render --dump-scene` of the Tungsten Cornell box prints our
 * format; rendering the printed file gives the original's image bit for bit (same seed), and
 * dumping the dump prints the same text again. */
TEST(dump_scene_round_trip) {
    static char out[1 << 17], out2[1 << 17];
    const char *dir = pm_test_tmpdir();
    char dump[1024], dump2[1024], a[1024], b[1024], cmd[4096];
    snprintf(dump, sizeof dump, "%s/dump.json", dir);
    snprintf(dump2, sizeof dump2, "%s/dump2.json", dir);
    snprintf(cmd, sizeof cmd, "%s/render --dump-scene '%s' 2>/dev/null > '%s'", pm_test_build_dir(),
             shipped("cornell_tungsten.json"), dump);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    snprintf(cmd, sizeof cmd, "%s/render --dump-scene '%s' > '%s'", pm_test_build_dir(), dump, dump2);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    snprintf(cmd, sizeof cmd, "cmp '%s' '%s'", dump, dump2);
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    snprintf(a, sizeof a, "%s/a.pfm", dir);
    snprintf(b, sizeof b, "%s/b.pfm", dir);
    ASSERT_MSG(render_file(shipped("cornell_tungsten.json"), "--spp 16 --seed 2", a, out, sizeof out) == 0, "%s", out);
    ASSERT_MSG(render_file(dump, "--spp 16 --seed 2", b, out2, sizeof out2) == 0, "%s", out2);
    snprintf(cmd, sizeof cmd, "cmp '%s' '%s'", a, b);
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    /* a scene with a mesh file: the dump names it by an absolute path, so it loads from here */
    char obj[1024], scn[1024];
    snprintf(obj, sizeof obj, "%s/s.obj", dir);
    snprintf(scn, sizeof scn, "%s/m.json", dir);
    ASSERT_EQ_INT(gen_mesh("sphere 8 4 1 0 0 0", obj), 0);
    mesh_scene(scn, "\"file\": \"s.obj\", \"material\": \"m\"");
    snprintf(cmd, sizeof cmd, "cd / && %s/render --dump-scene '%s' > '%s'", pm_test_build_dir(), scn, dump);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    snprintf(cmd, sizeof cmd, "grep -q '\"file\":.*\"/.*/s.obj\"' '%s'", dump);
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
}

/* Oracle: the analytic sphere again, now against a coarse OBJ sphere (16 x 8 segments) drawn
 * flat and smooth. Smooth shading interpolates the file's exact normals, so its pixels on
 * the sphere must be much closer to the analytic sphere's than the facets' are: the relative
 * RMS error at most 0.6 times the flat one (measured 0.07 against 0.14 at 64x64, 256
 * samples, same seed). If the integrators shaded with the geometric normal the two would be
 * equal. Photon mapping shades the smooth sphere the same way: its sphere pixels' mean within
 * 3% of the path tracer's (measured -0.3%; flat shading would still agree, so this checks
 * that the two integrators read the shading normal alike, not that they use it). */
TEST(smooth_shading_uses_vertex_normals) {
    static char out[65536];
    const char *dir = pm_test_tmpdir();
    char obj[1024], scn[3][1024], pfm[3][1024], ids[1024];
    snprintf(obj, sizeof obj, "%s/cs.obj", dir);
    ASSERT_EQ_INT(gen_mesh("sphere 16 8 100 278 150 300", obj), 0);
    const char *obj_json[3] = {"{\"type\": \"mesh\", \"file\": \"cs.obj\", \"smooth\": true, \"material\": \"w\"}",
                               "{\"type\": \"mesh\", \"file\": \"cs.obj\", \"smooth\": false, \"material\": \"w\"}",
                               "{\"type\": \"sphere\", \"center\": [278, 150, 300], \"radius\": 100, \"material\": \"w\"}"};
    for (int k = 0; k < 3; k++) {
        char text[4096];
        snprintf(text, sizeof text,
                 "{\"camera\": {\"eye\": [278, 273, -800], \"look_at\": [278, 273, 0], \"fov_deg\": 39.3, \"width\": 32, \"height\": 32},\n"
                 " \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.7}, \"light\": {\"type\": \"lambert\", "
                 "\"reflectance\": 0, \"emission\": 15}},\n \"objects\": [\n"
                 "  {\"type\": \"quad\", \"vertices\": [[0, 0, 0], [0, 0, 560], [556, 0, 560], [556, 0, 0]], \"material\": \"w\"},\n"
                 "  {\"type\": \"quad\", \"vertices\": [[0, 0, 560], [0, 550, 560], [556, 550, 560], [556, 0, 560]], \"material\": \"w\"},\n"
                 "  {\"type\": \"quad\", \"vertices\": [[200, 549, 200], [350, 549, 200], [350, 549, 350], [200, 549, 350]], "
                 "\"material\": \"light\"},\n  %s]}\n", obj_json[k]);
        snprintf(scn[k], sizeof scn[k], "%s/s%d.json", dir, k);
        snprintf(pfm[k], sizeof pfm[k], "%s/s%d.pfm", dir, k);
        ASSERT(write_text(scn[k], text) == 0);
        char fl[128];
        snprintf(fl, sizeof fl, "--width 64 --height 64 --seed 3 --spp %d", PM_TEST_SANITIZED ? 64 : 256);
        ASSERT_MSG(render_file(scn[k], fl, pfm[k], out, sizeof out) == 0, "%s", out);
    }
    snprintf(ids, sizeof ids, "%s/ids.pfm", dir);
    ASSERT_MSG(render_file(scn[2], "--width 64 --height 64 --mode objects --spp 16", ids, out, sizeof out) == 0, "%s", out);
    film S, F, A, M;
    ASSERT_EQ_INT(film_read_pfm(&S, pfm[0]), 0);
    ASSERT_EQ_INT(film_read_pfm(&F, pfm[1]), 0);
    ASSERT_EQ_INT(film_read_pfm(&A, pfm[2]), 0);
    ASSERT_EQ_INT(film_read_pfm(&M, ids), 0);
    int id = 4;
    image_region r = {0, 0, 0, 0, &M, &id, 1};
    image_diff ds, df;
    ASSERT_EQ_INT(image_compare_region(&S, &A, &r, &ds), 0);
    ASSERT_EQ_INT(image_compare_region(&F, &A, &r, &df), 0);
    printf("    sphere pixels: smooth rel_rmse %.3f, flat %.3f\n", ds.rel_rmse, df.rel_rmse);
    EXPECT_MSG(ds.rel_rmse <= 0.6 * df.rel_rmse, "smooth %.3f vs flat %.3f", ds.rel_rmse, df.rel_rmse);
    char pmf[1024];
    snprintf(pmf, sizeof pmf, "%s/pm.pfm", dir);
    ASSERT_MSG(render_file(scn[0], "--width 64 --height 64 --seed 4 --mode pm --spp 64", pmf, out, sizeof out) == 0,
               "%s", out);
    film P;
    ASSERT_EQ_INT(film_read_pfm(&P, pmf), 0);
    ASSERT_EQ_INT(image_compare_region(&P, &S, &r, &ds), 0);
    printf("    sphere pixels: photon mapping against path tracing %+.2f%%\n", 100 * ds.rel_mean);
    EXPECT_MSG(fabs(ds.rel_mean) <= 0.03, "pm off by %+.2f%%", 100 * ds.rel_mean);
    film_free(&P);
    film_free(&S);
    film_free(&F);
    film_free(&A);
    film_free(&M);
}

/* Oracle: the tetrahedron's area by hand (three right triangles of 1/2 and an equilateral one
 * of side sqrt 2: 3/2 + sqrt(3)/2), times 4 for a scale of 2. A Tungsten mesh primitive
 * reading a wo3 file with "power" P gets the radiance P / (pi area), and keeps its transform
 * (scale 2, then moved by +1 in x) and, with smooth, the file's normals. */
TEST(tungsten_mesh_power_and_transform) {
    unsigned char b[256];
    size_t n = tetra_wo3(b);
    char path[1024], t[4096];
    snprintf(path, sizeof path, "%s/tetra.wo3", pm_test_tmpdir());
    ASSERT(write_bytes(path, b, n) == 0);
    snprintf(t, sizeof t,
             "{\"bsdfs\": [{\"name\": \"w\", \"type\": \"lambert\", \"albedo\": 0.5}],\n"
             " \"primitives\": [{\"type\": \"mesh\", \"file\": \"%s\", \"bsdf\": \"w\", \"power\": 10, \"smooth\": true,\n"
             "   \"transform\": {\"position\": [1, 0, 0], \"scale\": 2}}],\n"
             " \"camera\": {\"resolution\": 8, \"transform\": {\"position\": [0, 1, 6.8], \"look_at\": [0, 1, 0]}}}", path);
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, t, &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(s.ntris, 4);
    double area = 0;
    for (int i = 0; i < 4; i++) area += s.tris[i].area;
    EXPECT_NEAR(area, 4 * (1.5 + sqrt(3) / 2), 1e-9);
    EXPECT_NEAR(s.mats[s.tris[0].mat].emission.x, 10 / (M_PI * area), 1e-9);
    EXPECT_NEAR(s.tris[3].v0.x, 1 + 2 * 1, 1e-12); /* triangle 3 starts at vertex 1 = (1, 0, 0) */
    EXPECT_EQ_INT(s.ntri_ns, 4);
    scene_free(&s);
}

/* ---- 6. small import fixes ---------------------------------------------------------------- */

/* Oracle: JSON's number grammar (RFC 8259: -?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)?),
 * which cJSON does not enforce: each bad number is refused with its line, column and JSON
 * path; the good ones (and digits inside strings) load. Through render: exit 2, the file named,
 * no image. */
TEST(json_leading_zeros_refused_with_path) {
    static const struct {
        const char *num, *want;
    } bad[] = {
        {"01", "line 2, column 64: $.objects[0].radius: the number 01 has a leading zero (JSON forbids it)"},
        {"-01", "line 2, column 64: $.objects[0].radius: the number -01 has a leading zero"},
        {"00", "line 2, column 64: $.objects[0].radius: the number 00 has a leading zero"},
        {"007.5", "line 2, column 64: $.objects[0].radius: the number 007.5 has a leading zero"},
        {"1.", "line 2, column 64: $.objects[0].radius: the number 1. has no digit after its decimal point"},
        {"1.e2", "line 2, column 64: $.objects[0].radius: the number 1.e2 has no digit after its decimal point"},
    };
    static const char *const good[] = {"1", "0.5", "10", "1e0", "1.0E+0", "100e-2", "0.1e1"};
    char t[1024];
    for (size_t i = 0; i < sizeof bad / sizeof *bad + sizeof good / sizeof *good; i++) {
        int is_bad = i < sizeof bad / sizeof *bad;
        const char *num = is_bad ? bad[i].num : good[i - sizeof bad / sizeof *bad];
        snprintf(t, sizeof t, "{\"camera\": {\"eye\": [0, 0, -5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 4, \"height\": 4, \"comment\": \"01\"},\n"
                 " \"objects\": [{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": %s, \"material\": \"w\"}],\n"
                 " \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5, \"emission\": 1}}}", num);
        scene s;
        json_err e;
        e.msg[0] = 0;
        int rc = scene_load_text(&s, t, &e);
        if (is_bad) {
            EXPECT_MSG(rc < 0 && strncmp(e.msg, bad[i].want, strlen(bad[i].want)) == 0, "%s: rc %d \"%s\", want \"%s\"",
                       num, rc, e.msg, bad[i].want);
        } else {
            EXPECT_MSG(rc == 0, "%s refused: %s", num, e.msg);
        }
        if (rc == 0) scene_free(&s);
    }
    /* deeper: the path of an array element */
    scene s;
    json_err e;
    EXPECT(scene_load_text(&s, "{\"camera\": {\"eye\": [0, 0, -05]}}", &e) < 0 &&
           strstr(e.msg, "line 1, column 27: $.camera.eye[2]: the number -05 has a leading zero"));
    char path[1024], cmd[4096], out[4096];
    snprintf(path, sizeof path, "%s/lz.json", pm_test_tmpdir());
    snprintf(t, sizeof t, "{\"camera\": {\"eye\": [0, 0, -5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 4, \"height\": 4},\n"
             " \"objects\": [{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 01, \"material\": \"w\"}],\n"
             " \"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5, \"emission\": 1}}}");
    ASSERT(write_text(path, t) == 0);
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' lz.json --quiet --hdr lz.pfm 2>&1; test ! -e lz.pfm",
             pm_test_tmpdir(), pm_test_build_dir());
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' lz.json --quiet --hdr lz.pfm 2>&1", pm_test_tmpdir(),
             pm_test_build_dir());
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 2 && strstr(out, "render: lz.json: line 2, column 64: $.objects[0].radius: the number 01 has a "
                                      "leading zero"), "exit %d: %s", rc, out);
    snprintf(path, sizeof path, "%s/lz.pfm", pm_test_tmpdir());
    FILE *f = fopen(path, "rb");
    EXPECT_MSG(f == NULL, "an image was written");
    if (f) fclose(f);
}

/* Oracle: an integrator we lack is no refusal: the scene loads with mode
 * "path" (the nearest unbiased method), one warning names the key and what is used, one more
 * per setting of that integrator; an unknown reconstruction filter is named with the box
 * filter used instead. The converted document says mode "path" and keeps max_bounces. */
TEST(tungsten_unsupported_integrator_warns) {
    char path[1024], cmd[4096], out[16384];
    snprintf(path, sizeof path, "%s/bdpt.json", pm_test_tmpdir());
    ASSERT(write_text(path,
        "{\"bsdfs\": [{\"name\": \"w\", \"type\": \"lambert\"}],\n"
        " \"primitives\": [{\"type\": \"quad\", \"bsdf\": \"w\", \"emission\": 1}],\n"
        " \"camera\": {\"reconstruction_filter\": \"tent\", \"transform\": {\"position\": [0, 1, 5], \"look_at\": [0, 0, 0]}},\n"
        " \"integrator\": {\"type\": \"bidirectional_path_tracer\", \"max_bounces\": 7, \"image_pyramid\": true}}\n") == 0);
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' --dump-scene bdpt.json 2>&1", pm_test_tmpdir(), pm_test_build_dir());
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 0, "exit %d: %s", rc, out);
    const char *want[] = {
        "render: bdpt.json: warning: $.integrator.type: integrator \"bidirectional_path_tracer\" is not supported: "
        "rendering with \"path\"",
        "render: bdpt.json: warning: $.integrator.image_pyramid: ignored (a setting of the integrator "
        "\"bidirectional_path_tracer\", which is not used)",
        "render: bdpt.json: warning: $.camera.reconstruction_filter: the filter \"tent\" is not supported: each pixel "
        "is the mean of its own samples (a box filter) instead",
        "\"mode\":\t\"path\"", "\"max_depth\":\t7"};
    for (size_t i = 0; i < sizeof want / sizeof *want; i++) EXPECT_MSG(strstr(out, want[i]), "no '%s' in: %s", want[i], out);
    EXPECT_MSG(!strstr(out, "$.integrator.max_bounces: ignored"), "%s", out);
    /* and it renders, with --mode pm too */
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' bdpt.json --width 4 --height 4 --spp 1 --mode pm --quiet --hdr b.pfm 2>&1",
             pm_test_tmpdir(), pm_test_build_dir());
    rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 0, "exit %d: %s", rc, out);
}

/* Oracle: hand-counted faces. Degenerate faces (a repeated corner, three collinear corners, a
 * zero-area polygon's fan) are skipped and counted, never refused; the rest are kept with
 * their indices; render prints one warning for the file with the count and the first line. */
TEST(degenerate_faces_skipped_with_one_warning) {
    const char *t = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 1 1 0\n"
                    "f 1 2 3\n"      /* kept */
                    "f 1 1 2\n"      /* repeated corner (line 7) */
                    "f 1 2 4\n"      /* collinear */
                    "f 1 2 4 2\n"    /* a flat polygon: 2 fan triangles, both zero area */
                    "f 2 5 3\n";     /* kept */
    mesh_data m;
    char err[256] = "";
    ASSERT_MSG(obj_text(t, &m, err, sizeof err) == 0, "%s", err);
    EXPECT_EQ_INT(m.ntris, 2);
    EXPECT_EQ_INT(m.nskipped, 4);
    EXPECT_MSG(strcmp(m.first_skip, "line 7") == 0, "%s", m.first_skip);
    EXPECT(m.tri[0][0] == 0 && m.tri[0][1] == 1 && m.tri[0][2] == 2);
    EXPECT(m.tri[1][0] == 1 && m.tri[1][1] == 4 && m.tri[1][2] == 2);
    mesh_free(&m);
    const char *dir = pm_test_tmpdir();
    char obj[1024], scn[1024], pfm[1024], out[8192];
    snprintf(obj, sizeof obj, "%s/deg.obj", dir);
    snprintf(scn, sizeof scn, "%s/s.json", dir);
    snprintf(pfm, sizeof pfm, "%s/o.pfm", dir);
    ASSERT(write_text(obj, t) == 0);
    ASSERT(write_text(scn, "{\"camera\": {\"eye\": [0.5, 0.5, 5], \"look_at\": [0.5, 0.5, 0], \"fov_deg\": 40, "
                           "\"width\": 8, \"height\": 8},\n \"materials\": {\"m\": {\"type\": \"lambert\", "
                           "\"reflectance\": 0.5, \"emission\": 1}},\n \"objects\": [{\"type\": \"mesh\", "
                           "\"file\": \"deg.obj\", \"material\": \"m\"}]}\n") == 0);
    int rc = render_file(scn, "--spp 1", pfm, out, sizeof out);
    EXPECT_MSG(rc == 0, "exit %d: %s", rc, out);
    const char *w = strstr(out, "warning: $.objects[0].file: skipped 4 degenerate faces (zero area: repeated or "
                                "collinear corners; the first at line 7), kept 2 triangles");
    EXPECT_MSG(w != NULL, "%s", out);
    if (w) EXPECT_MSG(strstr(w + 1, "warning") == NULL, "more than one warning: %s", out);
}

/* Oracle: a Tungsten cube primitive bounding the same gas (the converter's closed 12-triangle
 * mesh). Six null quads with int_medium "gas" on the faces of a box (fronts outward: the medium
 * is behind them) are six interfaces with that interior medium, closed together (the
 * loader's scene-wide closedness check), and render the cube's image, with the camera outside the box and
 * inside it (the camera's medium found from the geometry), path and pm, same seed: relative
 * rmse below 1e-6 (measured 0). The gas matters (without it the image mean moves by more than
 * 3%), and five quads (an open box) are refused by the closedness check, exit 2. */
TEST(tungsten_quads_bound_a_medium) {
    static const char *const head =
        "{\"media\": [{\"name\": \"gas\", \"type\": \"homogeneous\", \"sigma_a\": 0.05, \"sigma_s\": 0.6,"
        " \"phase_function\": {\"type\": \"henyey_greenstein\", \"g\": 0.2}}],\n"
        " \"bsdfs\": [{\"name\": \"white\", \"type\": \"lambert\", \"albedo\": 0.7}, {\"name\": \"lamp\", \"type\": \"lambert\", \"albedo\": 0},"
        " {\"name\": \"gasb\", \"type\": \"null\"}],\n"
        " \"integrator\": {\"type\": \"path_tracer\", \"max_bounces\": 64}, \"renderer\": {\"spp\": 16},\n";
    static const char *const cams[2] = {
        " \"camera\": {\"fov\": 50, \"resolution\": 16, \"transform\": {\"position\": [0, 0.5, -5], \"look_at\": [0, 0, 0]}},\n",
        " \"camera\": {\"fov\": 50, \"resolution\": 16, \"transform\": {\"position\": [0, 0, -0.5], \"look_at\": [0, -0.5, 1]}},\n"};
    static const char *const fixed =
        " \"primitives\": [{\"type\": \"quad\", \"bsdf\": \"white\", \"transform\": {\"position\": [0, -1.5, 0], \"scale\": 10}},\n"
        "  {\"type\": \"quad\", \"bsdf\": \"lamp\", \"emission\": 8, \"transform\": {\"position\": [0, 3, 0], \"rotation\": [180, 0, 0], \"scale\": 2}}";
    static const char *const faces[6] = {"[0, 1, 0], \"rotation\": [0, 0, 0]", "[0, -1, 0], \"rotation\": [180, 0, 0]",
                                         "[1, 0, 0], \"rotation\": [0, 0, -90]", "[-1, 0, 0], \"rotation\": [0, 0, 90]",
                                         "[0, 0, 1], \"rotation\": [90, 0, 0]", "[0, 0, -1], \"rotation\": [-90, 0, 0]"};
    const char *dir = pm_test_tmpdir();
    char path[1024], text[8192], cmd[8192], out[8192];
    for (int cam = 0; cam < 2; cam++) {
        for (int v = 0; v < 4; v++) { /* 0 quads, 1 cube, 2 open box (5 quads), 3 no gas */
            int n = snprintf(text, sizeof text, "%s%s%s", head, cams[cam], fixed);
            if (v == 1)
                n += snprintf(text + n, sizeof text - (size_t)n, ",\n  {\"type\": \"cube\", \"bsdf\": \"gasb\", \"int_medium\": \"gas\","
                              " \"transform\": {\"position\": [0, 0, 0], \"scale\": 2}}");
            for (int f = 0; f < (v == 0 ? 6 : v == 2 ? 5 : 0); f++)
                n += snprintf(text + n, sizeof text - (size_t)n, ",\n  {\"type\": \"quad\", \"bsdf\": \"gasb\", \"int_medium\": \"gas\","
                              " \"transform\": {\"position\": %s, \"scale\": 2}}", faces[f]);
            snprintf(text + n, sizeof text - (size_t)n, "]}\n");
            snprintf(path, sizeof path, "%s/v%d.json", dir, v);
            ASSERT(write_text(path, text) == 0);
        }
        snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' v2.json --quiet --hdr o.pfm 2>&1", dir, pm_test_build_dir());
        int rc = pm_test_run(cmd, out, sizeof out);
        EXPECT_MSG(rc == 2 && strstr(out, "$.media.gas: the surfaces around the medium \"gas\" do not close it"), "open box: exit %d: %s", rc, out);
        for (int m = 0; m < 2; m++) {
            snprintf(cmd, sizeof cmd,
                     "cd '%s' && R='%s/render' && O='--quiet --threads 2 --seed 3 --mode %s' && $R v0.json $O --hdr q.pfm >/dev/null 2>&1 && "
                     "$R v1.json $O --hdr c.pfm >/dev/null 2>&1 && $R v3.json $O --hdr n.pfm >/dev/null 2>&1 && "
                     "$R --compare q.pfm c.pfm && echo NOGAS && $R --compare q.pfm n.pfm",
                     dir, pm_test_build_dir(), m ? "pm" : "path");
            rc = pm_test_run(cmd, out, sizeof out);
            ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
            const char *r = strstr(out, "rel_rmse "), *g = strstr(out, "NOGAS");
            double rel = r ? atof(r + 9) : 1;
            const char *gm = g ? strstr(g, "rel_mean ") : NULL;
            double gas = gm ? atof(gm + 9) : 0;
            printf("    camera %s, %s: quads against cube rel_rmse %.3g; without the gas rel_mean %+.3f\n",
                   cam ? "inside" : "outside", m ? "pm" : "path", rel, gas);
            EXPECT_MSG(rel < 1e-6, "%s", out);
            EXPECT_MSG(fabs(gas) > 0.03, "the gas changes nothing: %s", out);
        }
    }
}

/* Oracle: Tungsten's Point (src/core/primitives/Point.cpp, read as a description): its
 * emission is a radiant intensity (it sends emission / r^2 to a point at distance r), power
 * becomes emission by 1 / (4 pi), and it sits at its transform's translation. Converted: our
 * point lights with that intensity and position, and no object; an unknown key is named. */
TEST(tungsten_point_light_converts) {
    const char *t =
        "{\"bsdfs\": [{\"name\": \"w\", \"type\": \"lambert\", \"albedo\": 0.5}],\n"
        " \"primitives\": [{\"type\": \"quad\", \"bsdf\": \"w\", \"transform\": {\"scale\": 4}},\n"
        "  {\"type\": \"point\", \"power\": [12.566370614359172, 25.132741228718345, 0], \"transform\": {\"position\": [1, 2, 3]}},\n"
        "  {\"type\": \"point\", \"emission\": 5, \"transform\": {\"position\": [0, 1, 0], \"scale\": 7}}],\n"
        " \"camera\": {\"type\": \"pinhole\", \"fov\": 40, \"resolution\": 8,\n"
        "   \"transform\": {\"position\": [0, 3, 6], \"look_at\": [0, 0, 0], \"up\": [0, 1, 0]}}}";
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, t, &e) == 0, "%s", e.msg);
    EXPECT_EQ_INT(s.ntris, 2);
    ASSERT_EQ_INT(s.nlights, 2); /* the two points (the quad emits nothing) */
    int k = 0;
    for (int i = 0; i < s.nlights; i++) {
        if (s.lights[i].type != LIGHT_POINT) continue;
        const light *l = &s.lights[i];
        if (k == 0) {
            EXPECT_NEAR(l->pos.x, 1, 1e-12);
            EXPECT_NEAR(l->pos.z, 3, 1e-12);
            EXPECT_NEAR(l->intensity.x, 1, 1e-12);
            EXPECT_NEAR(l->intensity.y, 2, 1e-12);
            EXPECT_NEAR(l->intensity.z, 0, 0);
        } else {
            EXPECT_NEAR(l->pos.y, 1, 1e-12);
            EXPECT_NEAR(l->intensity.z, 5, 1e-12);
        }
        k++;
    }
    EXPECT_EQ_INT(k, 2);
    scene_free(&s);
    const char *bad = "{\"bsdfs\": [], \"primitives\": [{\"type\": \"point\", \"power\": 1, \"bsdf\": \"w\"}],\n"
                      " \"camera\": {\"type\": \"pinhole\", \"fov\": 40, \"resolution\": 8,"
                      " \"transform\": {\"position\": [0, 3, 6], \"look_at\": [0, 0, 0], \"up\": [0, 1, 0]}}}";
    EXPECT(scene_load_text(&s, bad, &e) < 0 && strstr(e.msg, "$.primitives[0].bsdf: not supported"));
}
