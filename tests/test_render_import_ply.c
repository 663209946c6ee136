/* test_render_import_ply.c: the PLY reader (render/load/ply.h).
 *
 * Oracles: one small mesh written by the test in three encodings (ASCII, binary little- and
 * big-endian) with extra vertex properties (colours, confidence) and an extra face property,
 * whose triangles are listed by hand (a triangle, a quad fanned into 2, a pentagon into 3);
 * triangle strips with a restart and a stitch, listed by hand with their alternating winding
 * (all normals +z for a flat strip); the line or byte offset of each malformed input; every
 * truncation of each encoding fails with the file named, never a crash (ASan/UBSan in the
 * sanitizer build); byte mutations either fail cleanly or give a mesh whose indices are in range
 * and positions finite; a PLY mesh renders the same image, bit for bit, as the same mesh
 * written as OBJ.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "load/mesh.h"
#include "load/ply.h"

/* ---- writing PLY files -------------------------------------------------------------------- */

typedef struct wbuf {
    unsigned char b[8192];
    size_t n;
    int big; /* binary byte order: 1 big-endian */
} wbuf;

static void w_text(wbuf *w, const char *s) {
    size_t l = strlen(s);
    memcpy(w->b + w->n, s, l);
    w->n += l;
}

static void w_raw(wbuf *w, const void *p, size_t sz) {
    unsigned char t[8];
    memcpy(t, p, sz);
    uint16_t one = 1;
    unsigned char lo;
    memcpy(&lo, &one, 1);
    int host_big = lo != 1;
    for (size_t i = 0; i < sz; i++) w->b[w->n + i] = host_big == w->big ? t[i] : t[sz - 1 - i];
    w->n += sz;
}
static void w_f32(wbuf *w, float f) { w_raw(w, &f, 4); }
static void w_u8(wbuf *w, uint8_t v) { w_raw(w, &v, 1); }
static void w_i32(wbuf *w, int32_t v) { w_raw(w, &v, 4); }
static void w_u16(wbuf *w, uint16_t v) { w_raw(w, &v, 2); }

/* The mesh: 6 vertices (x y z, colour, confidence), 3 faces (3, 4 and 5 corners, each with a
 * "flags" ushort after the list). */
static const float k_P[6][3] = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {2, 0, 1}, {0.5f, 2, -1}};
static const int k_F[3][5] = {{0, 1, 2}, {0, 1, 2, 3}, {1, 4, 5, 3, 2}};
static const int k_FN[3] = {3, 4, 5};
/* by hand: the fans */
static const int k_T[6][3] = {{0, 1, 2}, {0, 1, 2}, {0, 2, 3}, {1, 4, 5}, {1, 5, 3}, {1, 3, 2}};

static const char *k_hdr_body =
    "comment written by test_render_import_ply.c\n"
    "element vertex 6\n"
    "property float x\nproperty float y\nproperty float z\n"
    "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty float confidence\n"
    "element face 3\n"
    "property list uchar int vertex_indices\nproperty ushort flags\n"
    "end_header\n";

static void mesh_ply(wbuf *w, int ascii, int big) {
    memset(w, 0, sizeof *w);
    w->big = big;
    w_text(w, "ply\n");
    w_text(w, ascii ? "format ascii 1.0\n" : big ? "format binary_big_endian 1.0\n" : "format binary_little_endian 1.0\n");
    w_text(w, k_hdr_body);
    char line[256];
    for (int i = 0; i < 6; i++) {
        if (ascii) {
            snprintf(line, sizeof line, "%g %g %g %d %d %d %g\n", k_P[i][0], k_P[i][1], k_P[i][2], 10 * i, 255, 0, 0.5);
            w_text(w, line);
        } else {
            for (int k = 0; k < 3; k++) w_f32(w, k_P[i][k]);
            w_u8(w, (uint8_t)(10 * i));
            w_u8(w, 255);
            w_u8(w, 0);
            w_f32(w, 0.5f);
        }
    }
    for (int f = 0; f < 3; f++) {
        if (ascii) {
            int n = snprintf(line, sizeof line, "%d", k_FN[f]);
            for (int k = 0; k < k_FN[f]; k++) n += snprintf(line + n, sizeof line - (size_t)n, " %d", k_F[f][k]);
            snprintf(line + n, sizeof line - (size_t)n, " %d\n", 7);
            w_text(w, line);
        } else {
            w_u8(w, (uint8_t)k_FN[f]);
            for (int k = 0; k < k_FN[f]; k++) w_i32(w, k_F[f][k]);
            w_u16(w, 7);
        }
    }
}

static int ply_buf(const wbuf *w, size_t n, mesh_data *m, char *err, size_t cap) {
    char *b = malloc(n + 1); /* exactly n bytes and a NUL, as mesh_read_file gives */
    if (!b) return -1;
    memcpy(b, w->b, n);
    b[n] = 0;
    int rc = ply_parse(b, n, "t.ply", m, err, cap);
    free(b);
    return rc;
}

static int write_file(const char *path, const void *b, size_t n) {
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    size_t k = fwrite(b, 1, n, f);
    return fclose(f) == 0 && k == n ? 0 : -1;
}

/* ---- tests -------------------------------------------------------------------------------- */

/* Oracle: the positions written and the fans listed by hand (k_T); the same from ASCII,
 * binary little-endian and binary big-endian, through ply_parse and mesh_load. */
TEST(ply_ascii_and_binary_same_triangles) {
    for (int enc = 0; enc < 3; enc++) {
        wbuf w;
        mesh_ply(&w, enc == 0, enc == 2);
        mesh_data m;
        char err[300] = "";
        ASSERT_MSG(ply_buf(&w, w.n, &m, err, sizeof err) == 0, "encoding %d: %s", enc, err);
        EXPECT_EQ_INT(m.npos, 6);
        EXPECT_EQ_INT(m.ntris, 6);
        EXPECT_EQ_INT(m.nskipped, 0);
        EXPECT(m.nrm == NULL && m.tri_n == NULL);
        for (int i = 0; i < 6 && i < m.npos; i++) {
            EXPECT_NEAR(m.pos[i].x, k_P[i][0], 0);
            EXPECT_NEAR(m.pos[i].y, k_P[i][1], 0);
            EXPECT_NEAR(m.pos[i].z, k_P[i][2], 0);
        }
        for (int t = 0; t < 6 && t < m.ntris; t++)
            for (int k = 0; k < 3; k++)
                EXPECT_MSG(m.tri[t][k] == k_T[t][k], "encoding %d: triangle %d corner %d: %d, want %d", enc, t, k,
                           m.tri[t][k], k_T[t][k]);
        mesh_free(&m);
        char path[1024];
        snprintf(path, sizeof path, "%s/m%d.PLY", pm_test_tmpdir(), enc);
        ASSERT(write_file(path, w.b, w.n) == 0);
        ASSERT_MSG(mesh_load(path, &m, err, sizeof err) == 0, "%s", err);
        EXPECT_EQ_INT(m.ntris, 6);
        mesh_free(&m);
    }
}

/* Oracle: by hand. Strip 0 1 2 3 4 gives (0 1 2) (2 1 3) (2 3 4); after -1, strip 5 5 5 6 7 8
 * has the stitches (5 5 5), (5 5 6) left out, (5 6 7) in the third position (as written) and
 * (6 7 8) in the fourth (turned: 7 6 8). Every vertex at z = 0, laid out so the first
 * triangle faces -z: every triangle's normal is -z. Normals nx ny nz are read. */
TEST(ply_tristrips_and_normals) {
    const char *t =
        "ply\nformat ascii 1.0\nelement vertex 9\nproperty float x\nproperty float y\nproperty float z\n"
        "property float nx\nproperty float ny\nproperty float nz\n"
        "element tristrips 1\nproperty list int int vertex_indices\nend_header\n"
        "0 0 0 0 0 1\n0 1 0 0 0 1\n1 0 0 0 0 1\n1 1 0 0 0 1\n2 0 0 0 0 0\n"
        "5 0 0 0 0 1\n5 1 0 0 0 1\n6 0 0 0 0 1\n6 1 0 0 0 1\n"
        "12 0 1 2 3 4 -1 5 5 5 6 7 8\n";
    static const int want[5][3] = {{0, 1, 2}, {2, 1, 3}, {2, 3, 4}, {5, 6, 7}, {7, 6, 8}};
    mesh_data m;
    char err[300] = "";
    ASSERT_MSG(ply_parse(t, strlen(t), "s.ply", &m, err, sizeof err) == 0, "%s", err);
    ASSERT_EQ_INT(m.ntris, 5);
    EXPECT_EQ_INT(m.nskipped, 0);
    for (int i = 0; i < 5; i++) {
        for (int k = 0; k < 3; k++) EXPECT_EQ_INT(m.tri[i][k], want[i][k]);
        vec3 a = m.pos[m.tri[i][0]], b = m.pos[m.tri[i][1]], c = m.pos[m.tri[i][2]];
        vec3 n = v3_cross(v3_sub(b, a), v3_sub(c, a));
        EXPECT_MSG(n.z < 0, "triangle %d: normal z %g, want < 0", i, n.z);
    }
    ASSERT(m.tri_n != NULL && m.nrm != NULL);
    EXPECT_NEAR(m.nrm[3].z, 1, 0);
    EXPECT_EQ_INT(m.tri_n[0][1], 1);
    EXPECT_EQ_INT(m.tri_n[2][2], -1); /* vertex 4's zero normal: left to smoothing */
    mesh_free(&m);
}

/* Oracle: the line (ASCII) or byte offset (binary, header) and the reason of each malformed
 * input, one file each; nothing is returned. Degenerate faces are skipped and counted. */
TEST(ply_errors_name_line_or_byte) {
    const char *H = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                    "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    char texts[16][1024];
    static const struct {
        const char *body, *want;
    } cases[] = {
        {"0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", "t.ply:13: face 0: vertex index 3 out of range (3 vertices)"},
        {"0 0 0\n1 0 0\n0 1 0\n3 0 1 -1\n", "t.ply:13: face 0: vertex index -1 out of range"},
        {"0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n", "t.ply:11: vertex 1: y is not finite"},
        {"0 0 0\n1 0 inf\n0 1 0\n3 0 1 2\n", "t.ply:11: vertex 1: z is not finite"},
        {"0 0 0\n1 0 0\n0 1 0\n2 0 1\n", "t.ply:13: face 0: a face needs at least 3 corners, got 2"},
        {"0 0 0\n1 0 x\n0 1 0\n3 0 1 2\n", "t.ply:11: vertex 1: \"x\" is not a number"},
        {"0 0 0\n1 0 0\n0 1 0\n3 0 1.5 2\n", "t.ply:13: face 0: \"1.5\" is not an integer"},
        {"0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n7\n", "t.ply: byte "},
        {"0 0 0\n1 0 0\n0 1 0\n3 0 1", "t.ply:"},
        {"0 0 0\n1 0 0\n2 0 0\n3 0 1 2\n", "t.ply: empty mesh: all 1 faces are degenerate (zero area; the first at face 0)"},
    };
    size_t nc = sizeof cases / sizeof *cases;
    for (size_t i = 0; i < nc; i++) {
        snprintf(texts[i], sizeof texts[i], "%s%s", H, cases[i].body);
        mesh_data m;
        char err[300] = "";
        int rc = ply_parse(texts[i], strlen(texts[i]), "t.ply", &m, err, sizeof err);
        EXPECT_MSG(rc < 0 && strncmp(err, cases[i].want, strlen(cases[i].want)) == 0, "case %zu: rc %d \"%s\", want \"%s\"",
                   i, rc, err, cases[i].want);
        EXPECT(m.pos == NULL && m.tri == NULL && m.ntris == 0);
    }
    /* the header */
    static const struct {
        const char *text, *want;
    } hdr[] = {
        {"plx\n", "t.ply: byte 0: not a PLY file"},
        {"ply\nformat ascii 1.0\nelement vertex 3\n", "t.ply: byte 38: truncated header: no end_header line"},
        {"ply\nformat ascii 2.0\nend_header\n", "t.ply: byte 4: header line 2: expected \"format ascii|"},
        {"ply\nformat binary_middle_endian 1.0\nend_header\n", "t.ply: byte 4: header line 2: unknown format"},
        {"ply\nformat ascii 1.0\nproperty float x\nend_header\n", "t.ply: byte 21: header line 3: a property before any element"},
        {"ply\nformat ascii 1.0\nelement vertex 3\nproperty float128 x\nend_header\n", "header line 4: unknown type \"float128\""},
        {"ply\nformat ascii 1.0\nelement vertex -3\nend_header\n", "header line 3: element vertex: the count \"-3\" is not a whole number"},
        {"ply\nformat ascii 1.0\nelement vertex 1\nproperty list float int x\nend_header\n", "a list's count type must be an integer type"},
        {"ply\nformat ascii 1.0\nelement face 0\nend_header\n", "no vertex element"},
        {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n", "the vertex element has no x, y or z"},
        {"ply\nformat ascii 1.0\nbogus line\nend_header\n", "header line 3: unknown keyword \"bogus\""},
        {"ply\nelement vertex 0\nend_header\n", "the header has no format line"},
        {"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n",
         "t.ply: empty mesh: no face"},
        /* a lying header: a million vertices in a few bytes, refused before allocating */
        {"ply\nformat binary_little_endian 1.0\nelement vertex 1000000\nproperty float x\nproperty float y\nproperty float z\n"
         "element face 1\nproperty list uchar int vertex_indices\nend_header\n0123456789",
         "truncated, or the header's counts are wrong: its elements need at least 12000001 bytes of binary data, the file has 10 after the header"},
        {"ply\nformat binary_little_endian 1.0\nelement vertex 4294967296000\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
         "4294967296000 vertices: more than this renderer's"},
    };
    for (size_t i = 0; i < sizeof hdr / sizeof *hdr; i++) {
        mesh_data m;
        char err[300] = "";
        int rc = ply_parse(hdr[i].text, strlen(hdr[i].text), "t.ply", &m, err, sizeof err);
        EXPECT_MSG(rc < 0 && strstr(err, hdr[i].want), "header case %zu: rc %d \"%s\", want \"%s\"", i, rc, err, hdr[i].want);
    }
    /* binary: an index out of range names its byte; a NaN names its byte */
    wbuf w;
    mesh_ply(&w, 0, 1);
    size_t hl = strlen("ply\nformat binary_big_endian 1.0\n") + strlen(k_hdr_body);
    size_t face0 = hl + 6 * 19; /* 6 vertices of 3 floats, 3 uchars, 1 float */
    wbuf c = w;
    c.n = face0 + 1 + 4 * 2; /* face 0, third index */
    w_i32(&c, 6);
    c.n = w.n;
    mesh_data m;
    char err[300] = "";
    EXPECT_MSG(ply_buf(&c, c.n, &m, err, sizeof err) < 0 && strstr(err, "t.ply: byte ") &&
               strstr(err, "face 0: vertex index 6 out of range (6 vertices)"), "%s", err);
    char want[64];
    snprintf(want, sizeof want, "byte %zu: face 0", face0 + 9);
    EXPECT_MSG(strstr(err, want), "%s (want %s)", err, want);
    c = w;
    c.n = hl + 19 * 2 + 4; /* vertex 2, y */
    w_f32(&c, NAN);
    c.n = w.n;
    snprintf(want, sizeof want, "t.ply: byte %zu: vertex 2: y is not finite", hl + 19 * 2 + 4);
    EXPECT_MSG(ply_buf(&c, c.n, &m, err, sizeof err) < 0 && strstr(err, want), "%s (want %s)", err, want);
    /* one byte too many */
    c = w;
    c.b[c.n++] = 0;
    snprintf(want, sizeof want, "t.ply: byte %zu: 1 bytes after the last element", w.n);
    EXPECT_MSG(ply_buf(&c, c.n, &m, err, sizeof err) < 0 && strstr(err, want), "%s (want %s)", err, want);
}

/* Oracle: every prefix of each encoding is refused with the file named (the ASCII file is
 * complete only from the last digit on), never a crash; ASan/UBSan watch the reads. Then
 * 3000 mutated files (1 to 4 bytes changed by a fixed generator): each either fails with a
 * message naming the file, or gives a mesh whose indices are in range and positions finite. */
TEST(ply_truncations_and_mutations_never_crash) {
    for (int enc = 0; enc < 3; enc++) {
        wbuf w;
        mesh_ply(&w, enc == 0, enc == 2);
        size_t full = w.n;
        if (enc == 0)
            while (full > 0 && (w.b[full - 1] == '\n' || w.b[full - 1] == ' ')) full--;
        for (size_t len = 0; len < full; len++) {
            mesh_data m;
            char err[300] = "";
            int rc = ply_buf(&w, len, &m, err, sizeof err);
            EXPECT_MSG(rc < 0 && strncmp(err, "t.ply", 5) == 0, "encoding %d, length %zu of %zu: rc %d %s", enc, len,
                       w.n, rc, err);
            if (rc == 0) mesh_free(&m);
        }
        uint64_t s = (uint64_t)88172645463325252ull + (uint64_t)(unsigned)enc;
        int ok = 0, refused = 0;
        for (int it = 0; it < 1000; it++) {
            wbuf c = w;
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            int nmut = 1 + (int)(s % 4);
            for (int k = 0; k < nmut; k++) {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                c.b[s % c.n] = (unsigned char)(s >> 32);
            }
            mesh_data m;
            char err[300] = "";
            if (ply_buf(&c, c.n, &m, err, sizeof err) < 0) {
                refused++;
                EXPECT_MSG(strncmp(err, "t.ply", 5) == 0, "mutation %d: %s", it, err);
                continue;
            }
            ok++;
            for (int t = 0; t < m.ntris; t++)
                for (int k = 0; k < 3; k++) EXPECT(m.tri[t][k] >= 0 && m.tri[t][k] < m.npos);
            for (int i = 0; i < m.npos; i++) EXPECT(isfinite(m.pos[i].x) && isfinite(m.pos[i].y) && isfinite(m.pos[i].z));
            mesh_free(&m);
        }
        printf("    encoding %d: %zu truncations refused; mutations: %d loaded, %d refused\n", enc, full, ok, refused);
    }
}

/* Oracle: the same triangles as OBJ (the same order, so the same BVH): render gives the same
 * image bit for bit, path tracing, 16x16. A bad PLY through render exits 2 naming the JSON
 * path, the file and the line. */
TEST(render_ply_matches_obj) {
    const char *dir = pm_test_tmpdir();
    char ply[1024], obj[1024], scn[1024], cmd[8192], out[8192];
    wbuf w;
    mesh_ply(&w, 1, 0);
    snprintf(ply, sizeof ply, "%s/m.ply", dir);
    snprintf(obj, sizeof obj, "%s/m.obj", dir);
    ASSERT(write_file(ply, w.b, w.n) == 0);
    FILE *f = fopen(obj, "w");
    ASSERT(f);
    for (int i = 0; i < 6; i++) fprintf(f, "v %.9g %.9g %.9g\n", k_P[i][0], k_P[i][1], k_P[i][2]);
    for (int fc = 0; fc < 3; fc++) {
        fprintf(f, "f");
        for (int k = 0; k < k_FN[fc]; k++) fprintf(f, " %d", k_F[fc][k] + 1);
        fprintf(f, "\n");
    }
    fclose(f);
    const char *names[2] = {"m.ply", "m.obj"};
    for (int i = 0; i < 2; i++) {
        snprintf(scn, sizeof scn, "%s/s%d.json", dir, i);
        f = fopen(scn, "w");
        ASSERT(f);
        fprintf(f, "{\"camera\": {\"eye\": [0.7, 0.8, 6], \"look_at\": [0.7, 0.8, 0], \"fov_deg\": 50, \"width\": 16, "
                   "\"height\": 16, \"spp\": 4},\n \"materials\": {\"m\": {\"type\": \"lambert\", \"reflectance\": 0.5}, "
                   "\"l\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 2}},\n \"objects\": [{\"type\": \"mesh\", "
                   "\"file\": \"%s\", \"material\": \"m\"}, {\"type\": \"sphere\", \"center\": [0, 0, 8], \"radius\": 1, "
                   "\"material\": \"l\"}]}\n", names[i]);
        fclose(f);
        snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' s%d.json --quiet --threads 1 --mode path --hdr o%d.pfm 2>&1", dir,
                 pm_test_build_dir(), i, i);
        int rc = pm_test_run(cmd, out, sizeof out);
        ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    }
    snprintf(cmd, sizeof cmd, "cd '%s' && cmp o0.pfm o1.pfm", dir);
    EXPECT_MSG(pm_test_run(cmd, out, sizeof out) == 0, "PLY and OBJ images differ: %s", out);
    /* a bad PLY: index out of range on line 24 */
    char bad[8192];
    memcpy(bad, w.b, w.n);
    bad[w.n] = 0;
    char *last = strstr(bad, "5 1 4 5 3 2");
    ASSERT(last);
    last[4] = '9';
    ASSERT(write_file(ply, bad, w.n) == 0);
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' s0.json --quiet --hdr bad.pfm 2>&1", dir, pm_test_build_dir());
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 2 && strstr(out, "render: s0.json: $.objects[0].file: ") &&
               strstr(out, "m.ply:24: face 2: vertex index 9 out of range (6 vertices)"), "exit %d: %s", rc, out);
}

/* Real meshes in PLY: degenerate faces (a repeated corner, collinear corners, a flat
 * quad fanned into two zero-area triangles) are skipped and counted, the first named by its
 * face; the others kept in order. Oracle: the faces listed by hand, in ASCII. */
TEST(ply_degenerate_faces_skipped_and_counted) {
    const char *t = "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
                    "element face 5\nproperty list uchar int vertex_indices\nend_header\n"
                    "0 0 0\n1 0 0\n0 1 0\n2 0 0\n1 1 0\n"
                    "3 0 1 2\n"     /* kept */
                    "3 0 0 1\n"     /* repeated corner: face 1 */
                    "3 0 1 3\n"     /* collinear */
                    "4 0 1 3 1\n"   /* flat: 2 fan triangles of zero area */
                    "3 1 4 2\n";    /* kept */
    mesh_data m;
    char err[256] = "";
    ASSERT_MSG(ply_parse(t, strlen(t), "t.ply", &m, err, sizeof err) == 0, "%s", err);
    EXPECT_EQ_INT(m.ntris, 2);
    EXPECT_EQ_INT(m.nskipped, 4);
    EXPECT_MSG(strcmp(m.first_skip, "face 1") == 0, "%s", m.first_skip);
    if (m.ntris == 2) {
        EXPECT(m.tri[0][0] == 0 && m.tri[0][1] == 1 && m.tri[0][2] == 2);
        EXPECT(m.tri[1][0] == 1 && m.tri[1][1] == 4 && m.tri[1][2] == 2);
    }
    mesh_free(&m);
}
