/* test_photon.c: the packed fields of pm_photon and the photon-map file format.
 *
 * Oracles: the precision bounds documented in photon.h / photon.c (RGBE relative error of the
 * largest channel <= 2^-8 and absolute error of every channel <= 2^-8 / (1 - 2^-9) * max;
 * direction angular
 * error <= 0.79 degrees, <= 0.36 at the poles; normal angular error <= the lattice's covering
 * radius, 10 degrees, and exactly the nearest of the 256 directions by brute force), and
 * byte-for-byte equality for file round trips.
 */
#define _GNU_SOURCE
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <dirent.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <signal.h>
#include <unistd.h>

#include "photon.h"
#include "kdtree.h"
#include "test.h"

static uint64_t ph_rng = 0x1234567;
static double ph_uniform(void) {
    ph_rng ^= ph_rng << 13;
    ph_rng ^= ph_rng >> 7;
    ph_rng ^= ph_rng << 17;
    return (double)(ph_rng >> 11) * (1.0 / 9007199254740992.0);
}

static double angle_deg(const float a[3], const double b[3]) {
    double la = sqrt((double)a[0] * a[0] + (double)a[1] * a[1] + (double)a[2] * a[2]);
    double lb = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    double c = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (la * lb);
    if (c > 1) c = 1;
    if (c < -1) c = -1;
    /* acos is ill-conditioned near 1: use the cross product for small angles */
    double cx = a[1] * b[2] - a[2] * b[1], cy = a[2] * b[0] - a[0] * b[2], cz = a[0] * b[1] - a[1] * b[0];
    double s = sqrt(cx * cx + cy * cy + cz * cz) / (la * lb);
    return atan2(s, c) * 180.0 / 3.14159265358979323846;
}

/* FNV-1a 64, written from its definition (the test's own, not mapfile.c's): checked against
 * the published vectors of "" and "a" before use. */
static uint64_t test_fnv1a(uint64_t h, const unsigned char *b, size_t n) {
    for (size_t i = 0; i < n; i++) {
        h ^= b[i];
        h *= 1099511628211ull; /* 2^40 + 2^8 + 0xb3 */
    }
    return h;
}
#define TEST_FNV_BASIS 14695981039346656037ull

/* Oracle: mapfile.h's table of the format, read byte by byte from a saved file (the size of
 * the record itself is a static assertion in photon.c; this checks what reaches the disk):
 * magic, version, record size, count, kind, emitted (two halves), tree_bucket, the checksum
 * (FNV-1a 64 of bytes 0..55 and the records, computed here from the bytes read), then each
 * record as little-endian float x, y, z, RGBE, theta, phi, flag, normal. */
TEST(map_file_bytes_match_the_documented_layout) {
    char path[600];
    snprintf(path, sizeof path, "%s/one.pm", pm_test_tmpdir());
    pm_photon p[2];
    float pos[3] = {1.0f, -2.5f, 0x1p-3f}, pw[3] = {0.5f, 0.25f, 1}, dir[3] = {0, 0, -1}, n[3] = {0, 0, 1};
    pm_photon_init(&p[0], pos, pw, dir, n, PM_KIND_SHADOW);
    p[1] = p[0];
    p[1].flag |= 2; /* as a tree's axis bits would be */
    pm_map_header h = {0, 0, 2, PM_MAP_SHADOW, 0x0000000500000007ull, 8,
                       {0x1122334455667788ull, 0x00000000000000a9ull}};
    ASSERT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
    unsigned char b[64 + 40];
    FILE *f = fopen(path, "rb");
    ASSERT(f);
    ASSERT_EQ_INT(fread(b, 1, sizeof b, f), sizeof b);
    EXPECT_EQ_INT(fgetc(f), EOF);
    fclose(f);
    EXPECT(memcmp(b, "PMAPHOTN", 8) == 0);
    const uint32_t w[12] = {PM_FILE_VERSION, 20, 2, 0, PM_MAP_SHADOW, 7, 5, 8,
                            0x55667788u, 0x11223344u, 0xa9u, 0};
    EXPECT_EQ_INT(PM_FILE_VERSION, 3);
    for (int i = 0; i < 12; i++) {
        uint32_t v = (uint32_t)b[8 + 4 * i] | (uint32_t)b[9 + 4 * i] << 8 |
                     (uint32_t)b[10 + 4 * i] << 16 | (uint32_t)b[11 + 4 * i] << 24;
        EXPECT_MSG(v == w[i], "header word %d at byte %d: %u, want %u", i, 8 + 4 * i, v, w[i]);
    }
    EXPECT(test_fnv1a(TEST_FNV_BASIS, (const unsigned char *)"", 0) == 0xcbf29ce484222325ull);
    EXPECT(test_fnv1a(TEST_FNV_BASIS, (const unsigned char *)"a", 1) == 0xaf63dc4c8601ec8cull);
    uint64_t sum = test_fnv1a(test_fnv1a(TEST_FNV_BASIS, b, 56), b + 64, 40), got = 0;
    for (int i = 7; i >= 0; i--) got = got << 8 | b[56 + i];
    EXPECT_MSG(got == sum, "checksum %016llx, FNV-1a of the bytes %016llx", (unsigned long long)got,
               (unsigned long long)sum);
    for (int r = 0; r < 2; r++) {
        const unsigned char *rec = b + 64 + 20 * r;
        for (int a = 0; a < 3; a++) {
            uint32_t u = (uint32_t)rec[4 * a] | (uint32_t)rec[4 * a + 1] << 8 |
                         (uint32_t)rec[4 * a + 2] << 16 | (uint32_t)rec[4 * a + 3] << 24;
            float x;
            memcpy(&x, &u, 4);
            EXPECT(x == pos[a]);
        }
        EXPECT(memcmp(rec + 12, p[r].power, 4) == 0);
        EXPECT(rec[16] == p[r].theta && rec[17] == p[r].phi && rec[19] == p[r].normal);
        EXPECT_EQ_INT(rec[18], (PM_KIND_SHADOW << PM_FLAG_KIND_SHIFT) | (r ? 2 : 0));
    }
}

/* Oracle: the bound |decoded - c| <= 2^-8 / (1 - 2^-9) * max(r,g,b) for every channel, and
 * relative error of the largest channel <= 2^-8, over random colours spanning 1e-30 .. 1e30. */
TEST(rgbe_round_trip_error_bound) {
    double worst_rel = 0;
    for (int i = 0; i < 200000; i++) {
        double mag = pow(10.0, -30 + 60 * ph_uniform());
        float c[3], d[3];
        for (int j = 0; j < 3; j++) c[j] = (float)(mag * ph_uniform());
        if (i % 7 == 0) c[i % 3] = 0;
        uint8_t e[4];
        pm_rgbe_encode(c, e);
        pm_rgbe_decode(e, d);
        double mx = fmax(c[0], fmax(c[1], c[2]));
        for (int j = 0; j < 3; j++) {
            ASSERT_MSG(fabs((double)d[j] - c[j]) <= mx * 0x1p-8 / (1 - 0x1p-9),
                       "channel %d: %g -> %g (max %g)", j, c[j], d[j], mx);
            if (c[j] == mx && mx > 0) worst_rel = fmax(worst_rel, fabs((double)d[j] - mx) / mx);
        }
    }
    EXPECT(worst_rel <= 0x1p-8);
    EXPECT(worst_rel > 0x1p-10); /* the bound is nearly reached: the test is sensitive */
}

/* Oracle: the documented special cases of photon.h. */
TEST(rgbe_special_values) {
    uint8_t e[4];
    float d[3];
    float zero[3] = {0, 0, 0};
    pm_rgbe_encode(zero, e);
    EXPECT(e[0] == 0 && e[1] == 0 && e[2] == 0 && e[3] == 0);
    pm_rgbe_decode(e, d);
    EXPECT(d[0] == 0 && d[1] == 0 && d[2] == 0);
    /* tiny: below 2^-128 encodes as zero; just above stays within the bound */
    float tiny[3] = {1e-39f, 0, 0};
    pm_rgbe_encode(tiny, e);
    EXPECT_EQ_INT(e[3], 0);
    float small[3] = {3e-38f, 1e-38f, 0};
    pm_rgbe_encode(small, e);
    pm_rgbe_decode(e, d);
    EXPECT_REL(d[0], 3e-38f, 0x1p-8);
    EXPECT_NEAR(d[1], 1e-38f, 3e-38 * 0x1p-8);
    /* huge: 1e38 round-trips; beyond 1.7e38 and +inf saturate to the largest value */
    float huge[3] = {1e38f, 5e37f, 1.0f};
    pm_rgbe_encode(huge, e);
    pm_rgbe_decode(e, d);
    EXPECT_REL(d[0], 1e38f, 0x1p-8);
    EXPECT_REL(d[1], 5e37f, 0x1p-7);
    float sat[3] = {INFINITY, 3e38f, 1.0f};
    pm_rgbe_encode(sat, e);
    pm_rgbe_decode(e, d);
    EXPECT(isfinite(d[0]) && d[0] >= 1.69e38f);
    EXPECT(d[1] >= 1.69e38f);
    /* NaN and negative channels encode as zero, leaving the others intact */
    float bad[3] = {NAN, -5.0f, 2.0f};
    pm_rgbe_encode(bad, e);
    pm_rgbe_decode(e, d);
    EXPECT(d[0] == 0 && d[1] == 0);
    EXPECT_REL(d[2], 2.0f, 0x1p-8);
    /* exact powers of two and the round-up case 255.5/256 */
    float one[3] = {1.0f, 0.5f, 0.25f};
    pm_rgbe_encode(one, e);
    pm_rgbe_decode(e, d);
    EXPECT(d[0] == 1.0f && d[1] == 0.5f && d[2] == 0.25f);
    float up[3] = {0.999f, 0, 0};
    pm_rgbe_encode(up, e);
    pm_rgbe_decode(e, d);
    EXPECT_REL(d[0], 0.999f, 0x1p-8);
}

/* Oracle: the angular bound of photon.c (<= 0.79 degrees; <= 0.36 degrees when theta falls in
 * the first or last bin), over random unit vectors and vectors right at the poles. */
TEST(direction_round_trip_angular_bound) {
    double worst = 0, worst_pole = 0;
    for (int i = 0; i < 200000; i++) {
        double v[3];
        if (i < 1000) { /* near the poles */
            double z = i % 2 ? 1 : -1, a = 6.283185307 * ph_uniform(), s = 0.006 * ph_uniform();
            v[0] = s * cos(a), v[1] = s * sin(a), v[2] = z;
        } else {
            double z = 2 * ph_uniform() - 1, a = 6.283185307 * ph_uniform(), s = sqrt(1 - z * z);
            double len = 0.1 + 10 * ph_uniform(); /* not normalized */
            v[0] = len * s * cos(a), v[1] = len * s * sin(a), v[2] = len * z;
        }
        float f[3] = {(float)v[0], (float)v[1], (float)v[2]}, d[3];
        uint8_t th, ph;
        pm_dir_encode(f, &th, &ph);
        pm_dir_decode(th, ph, d);
        double dv[3] = {f[0], f[1], f[2]};
        double err = angle_deg(d, dv);
        EXPECT_NEAR(sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]), 1.0, 1e-6);
        if (th == 0 || th == 255) worst_pole = fmax(worst_pole, err);
        worst = fmax(worst, err);
    }
    float zp[3] = {0, 0, 1}, zm[3] = {0, 0, -1}, d[3];
    uint8_t th, ph;
    pm_dir_encode(zp, &th, &ph);
    EXPECT_EQ_INT(th, 0);
    pm_dir_encode(zm, &th, &ph);
    EXPECT_EQ_INT(th, 255);
    float z0[3] = {0, 0, 0}, zn[3] = {NAN, 1, 0};
    pm_dir_encode(z0, &th, &ph);
    EXPECT(th == 0 && ph == 0);
    pm_dir_encode(zn, &th, &ph);
    EXPECT(th == 0 && ph == 0);
    pm_dir_decode(255, 255, d);
    EXPECT(d[2] < -0.9999f);
    EXPECT_MSG(worst <= 0.79, "worst direction error %g degrees", worst);
    EXPECT_MSG(worst_pole <= 0.36, "worst pole error %g degrees", worst_pole);
    EXPECT(worst > 0.6); /* sensitive: the bound is nearly reached */
}

/* Oracle: brute force over the 256 decoded directions picks the same nearest code, and the
 * angle to it is <= 10 degrees (the lattice's covering radius, 9.7 measured). */
TEST(normal_round_trip_is_nearest_and_bounded) {
    double worst = 0;
    for (int i = 0; i < 100000; i++) {
        double z = 2 * ph_uniform() - 1, a = 6.283185307 * ph_uniform(), s = sqrt(1 - z * z);
        if (i < 100) z = i % 2 ? 1 : -1, s = 0;
        float n[3] = {(float)(s * cos(a)), (float)(s * sin(a)), (float)z};
        uint8_t c = pm_normal_encode(n);
        float d[3];
        int best = 0;
        float bd = -2;
        for (int j = 0; j < 256; j++) {
            pm_normal_decode((uint8_t)j, d);
            float dot = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
            if (dot > bd) bd = dot, best = j;
        }
        pm_normal_decode(c, d);
        float dc = n[0] * d[0] + n[1] * d[1] + n[2] * d[2];
        EXPECT_MSG(c == best || dc == bd, "normal %d: code %d, nearest %d", i, c, best);
        double nv[3] = {n[0], n[1], n[2]};
        worst = fmax(worst, angle_deg(d, nv));
        if (pm_test_failed()) return;
    }
    EXPECT_MSG(worst <= 10.0, "worst normal error %g degrees", worst);
    EXPECT(worst > 8.0);
}

/* Oracle: pm_photon_init and pm_photon_set store exactly what the separate encoders produce;
 * init zeroes the tree's bits (PM_FLAG_TREE_MASK: bits 0-1 and 4-7, so the flag holds the
 * kind alone), set and the single-field setters keep them and every other field. */
TEST(photon_set_packs_all_fields) {
    pm_photon p;
    memset(&p, 0xFF, sizeof p);
    float pos[3] = {1.5f, -2, 3}, pw[3] = {0.5f, 0.25f, 2}, dir[3] = {0, 1, 0}, n[3] = {1, 0, 0};
    pm_photon_set(&p, pos, pw, dir, n, PM_KIND_CAUSTIC);
    EXPECT_EQ_INT(p.flag, PM_FLAG_TREE_MASK | (PM_KIND_CAUSTIC << PM_FLAG_KIND_SHIFT));
    pm_photon q = p;
    float pw2[3] = {4, 0, 1}, back[3];
    pm_photon_set_power(&q, pw2);
    pm_rgbe_decode(q.power, back);
    EXPECT(back[0] == 4 && back[1] == 0 && back[2] == 1);
    EXPECT(memcmp(q.pos, p.pos, sizeof p.pos) == 0 && q.theta == p.theta && q.phi == p.phi &&
           q.flag == p.flag && q.normal == p.normal);
    pm_photon_set_kind(&q, PM_KIND_SHADOW);
    EXPECT_EQ_INT(q.flag, PM_FLAG_TREE_MASK | (PM_KIND_SHADOW << PM_FLAG_KIND_SHIFT));
    memset(&p, 0xFF, sizeof p);
    pm_photon_init(&p, pos, pw, dir, n, PM_KIND_CAUSTIC);
    EXPECT(p.pos[0] == 1.5f && p.pos[1] == -2 && p.pos[2] == 3);
    uint8_t e[4], th, ph;
    pm_rgbe_encode(pw, e);
    EXPECT(memcmp(e, p.power, 4) == 0);
    pm_dir_encode(dir, &th, &ph);
    EXPECT(th == p.theta && ph == p.phi);
    EXPECT_EQ_INT(p.normal, pm_normal_encode(n));
    EXPECT_EQ_INT(pm_photon_kind(&p), PM_KIND_CAUSTIC);
    EXPECT_EQ_INT(p.flag, PM_KIND_CAUSTIC << PM_FLAG_KIND_SHIFT);
}

static pm_photon *some_photons(size_t n) {
    pm_photon *p = malloc((n ? n : 1) * sizeof *p);
    for (size_t i = 0; i < n; i++) {
        float pos[3] = {(float)ph_uniform(), (float)i, -(float)ph_uniform()};
        float pw[3] = {(float)ph_uniform(), 0.1f, 1e-3f}, dir[3] = {1, (float)ph_uniform(), 0};
        pm_photon_init(&p[i], pos, pw, dir, dir, (int)(i % 4));
    }
    return p;
}

/* Oracle: byte equality of the records and equality of the header fields after a round trip;
 * the documented error codes for damaged files; no file left behind by a failed save. */
TEST(map_file_round_trip_and_errors) {
    char path[600], tmp[620], cmd[1400];
    snprintf(path, sizeof path, "%s/map.pm", pm_test_tmpdir());
    size_t n = 3001;
    pm_photon *p = some_photons(n);
    pm_map_header h = {PM_FILE_VERSION, sizeof(pm_photon), n, PM_MAP_CAUSTIC, 123456789012ull, 8,
                       {UINT64_MAX, 0x8000000000000001ull}};
    ASSERT_EQ_INT(pm_map_save(path, p, &h), 0);
    pm_photon *q = NULL;
    pm_map_header g;
    memset(&g, 0, sizeof g);
    ASSERT_EQ_INT(pm_map_load(path, &q, &g), 0);
    ASSERT(q != NULL);
    EXPECT(memcmp(p, q, n * sizeof *p) == 0);
    EXPECT_EQ_INT(g.count, n);
    EXPECT_EQ_INT(g.kind, PM_MAP_CAUSTIC);
    EXPECT(g.emitted == 123456789012ull);
    EXPECT_EQ_INT(g.tree_bucket, 8);
    EXPECT_EQ_INT(g.version, PM_FILE_VERSION);
    EXPECT_EQ_INT(g.record_size, 20);
    EXPECT(g.tag[0] == UINT64_MAX && g.tag[1] == 0x8000000000000001ull);
    free(q);
    struct stat sb;
    ASSERT_EQ_INT(stat(path, &sb), 0);
    EXPECT_EQ_INT(sb.st_size, 64 + 20 * n);

    /* An empty map. */
    pm_map_header h0 = {0, 0, 0, PM_MAP_GLOBAL, 0, 0, {0, 0}};
    ASSERT_EQ_INT(pm_map_save(path, NULL, &h0), 0);
    q = (pm_photon *)1;
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), 0);
    EXPECT(q == NULL);
    EXPECT_EQ_INT(g.count, 0);

    /* Truncated: one byte short. */
    ASSERT_EQ_INT(pm_map_save(path, p, &h), 0);
    ASSERT_EQ_INT(truncate(path, 64 + 20 * (off_t)n - 1), 0);
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), PM_EFORMAT);
    EXPECT(q == NULL);
    ASSERT_EQ_INT(truncate(path, 30), 0); /* inside the header */
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), PM_EFORMAT);

    /* Bad magic, wrong version, wrong record size: patch bytes of a good file. */
    FILE *f;
    ASSERT_EQ_INT(pm_map_save(path, p, &h), 0);
    f = fopen(path, "r+b");
    ASSERT(f);
    fputc('X', f);
    fclose(f);
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), PM_EFORMAT);
    ASSERT_EQ_INT(pm_map_save(path, p, &h), 0);
    f = fopen(path, "r+b");
    fseek(f, 8, SEEK_SET);
    fputc(PM_FILE_VERSION + 1, f);
    fclose(f);
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), PM_EVERSION);
    ASSERT_EQ_INT(pm_map_save(path, p, &h), 0);
    f = fopen(path, "r+b");
    fseek(f, 12, SEEK_SET);
    fputc(24, f);
    fclose(f);
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), PM_EFORMAT);
    /* A count far beyond the file size must not allocate it. */
    ASSERT_EQ_INT(pm_map_save(path, p, &h), 0);
    f = fopen(path, "r+b");
    fseek(f, 20, SEEK_SET);
    fputc(0x7F, f);
    fclose(f);
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), PM_EFORMAT);

    /* Missing file; unwritable path: PM_EIO and no partial file. */
    snprintf(path, sizeof path, "%s/nope/map.pm", pm_test_tmpdir());
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), PM_EIO);
    EXPECT_EQ_INT(pm_map_save(path, p, &h), PM_EIO);
    /* A directory is not replaced. */
    snprintf(path, sizeof path, "%s/dir.pm", pm_test_tmpdir());
    ASSERT_EQ_INT(mkdir(path, 0700), 0);
    EXPECT_EQ_INT(pm_map_save(path, p, &h), PM_ENOTFILE);
    (void)cmd;
    (void)tmp;
    free(p);
}

/* Oracle: brute force. Random (Poisson) photons in a built kd-tree (axis bits in the flag
 * byte, bucket 1 and 8); every record's power (and kind) is then rewritten, with pm_photon_set
 * from its own decoded fields or with pm_photon_set_power and pm_photon_set_kind, as a
 * renderer scaling powers after the build does. 1000 k-NN
 * queries (k = 10) must still return exactly the brute-force multiset of distances, and every
 * rewritten field must read back. */
TEST(photon_set_after_build_keeps_the_tree) {
    const size_t n = 20000;
    const unsigned K = 10, Q = 1000;
    pm_photon *p = malloc(n * sizeof *p);
    for (int b = 0; b < 4; b++) { /* bucket 1 and 8; pm_photon_set, then pm_photon_set_power */
        for (size_t i = 0; i < n; i++) {
            float pos[3] = {(float)ph_uniform(), (float)ph_uniform(), (float)ph_uniform()};
            float pw[3] = {1, 1, 1}, dir[3] = {0, 0, -1}, nrm[3] = {0, 0, 1};
            pm_photon_init(&p[i], pos, pw, dir, nrm, PM_KIND_INDIRECT);
        }
        pm_kdtree *t = NULL;
        pm_kdtree_config cfg = pm_kdtree_photon_config(b & 1 ? 8u : 1u);
        ASSERT_EQ_INT(pm_kdtree_build(&t, p, n, &cfg, NULL), PM_OK);
        for (size_t i = 0; i < n; i++) {
            float pw[3] = {(float)(i % 7), 0.5f, 2.0f}, dir[3], nrm[3];
            pm_dir_decode(p[i].theta, p[i].phi, dir);
            pm_normal_decode(p[i].normal, nrm);
            float pos[3] = {p[i].pos[0], p[i].pos[1], p[i].pos[2]};
            if (b < 2) pm_photon_set(&p[i], pos, pw, dir, nrm, PM_KIND_CAUSTIC);
            else pm_photon_set_power(&p[i], pw), pm_photon_set_kind(&p[i], PM_KIND_CAUSTIC);
        }
        unsigned wrong = 0;
        float d2[10];
        for (unsigned qi = 0; qi < Q; qi++) {
            float q[3] = {(float)ph_uniform(), (float)ph_uniform(), (float)ph_uniform()};
            pm_neighbor nb[10];
            int got = pm_kdtree_knn(t, q, K, INFINITY, nb, PM_SORT, NULL);
            unsigned m = 0; /* the K smallest so far, sorted (insertion) */
            for (size_t i = 0; i < n; i++) {
                float d[3] = {p[i].pos[0] - q[0], p[i].pos[1] - q[1], p[i].pos[2] - q[2]};
                float v = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                if (m == K && !(v < d2[K - 1])) continue;
                unsigned j = m < K ? m++ : K - 1;
                for (; j > 0 && d2[j - 1] > v; j--) d2[j] = d2[j - 1];
                d2[j] = v;
            }
            int ok = got == (int)K;
            for (unsigned j = 0; ok && j < K; j++) ok = nb[j].dist2 == d2[j];
            wrong += !ok;
        }
        EXPECT_MSG(wrong == 0, "bucket %d: %u of %u k-NN queries wrong after %s", b & 1 ? 8 : 1, wrong, Q,
                   b < 2 ? "pm_photon_set" : "pm_photon_set_power/kind");
        float back[3];
        pm_rgbe_decode(p[5].power, back);
        EXPECT(back[0] == 5.0f && back[1] == 0.5f && back[2] == 2.0f);
        EXPECT_EQ_INT(pm_photon_kind(&p[5]), PM_KIND_CAUSTIC);
        pm_kdtree_free(t);
    }
    free(p);
}

/* 1 if the map file at path loads and holds exactly the n photons p. */
static int file_holds(const char *path, const pm_photon *p, size_t n) {
    pm_photon *q = NULL;
    pm_map_header g;
    int ok = pm_map_load(path, &q, &g) == PM_OK && g.count == n && (n == 0 || memcmp(p, q, n * sizeof *p) == 0);
    free(q);
    return ok;
}

/* Entries of dir other than the names given (a leftover temporary shows up here). */
static int stray_entries(const char *dir, const char *const *known, int nknown) {
    DIR *d = opendir(dir);
    if (!d) return -1;
    int stray = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, "..")) continue;
        int k = 0;
        for (int i = 0; i < nknown; i++) k |= !strcmp(e->d_name, known[i]);
        if (!k) {
            printf("stray entry %s/%s\n", dir, e->d_name);
            stray++;
        }
    }
    closedir(d);
    return stray;
}

/* Oracle: mapfile.h's SAVING ("a new file gets mode 0644; a replaced file keeps its
 * permission bits"), read back with stat. The umask is set to 0, 022 and 077 in turn: the
 * temporary comes from mkstemp (0600) and is given the mode with fchmod, which the umask does
 * not touch, so a new file is 0644 under each; a file replaced after chmod 0604 stays 0604. */
TEST(map_file_new_file_mode_0644_whatever_the_umask) {
    size_t n = 10;
    pm_photon *p = some_photons(n);
    pm_map_header h = {PM_FILE_VERSION, 0, n, PM_MAP_GLOBAL, 1000, 0, {0, 0}};
    const mode_t masks[] = {0, 022, 077};
    mode_t saved = umask(022);
    for (int i = 0; i < 3; i++) {
        char path[600];
        struct stat sb;
        snprintf(path, sizeof path, "%s/new%d.pm", pm_test_tmpdir(), i);
        umask(masks[i]);
        EXPECT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
        EXPECT_MSG(stat(path, &sb) == 0 && (sb.st_mode & 07777) == 0644, "umask %03o: new file mode %03o",
                   (unsigned)masks[i], (unsigned)(sb.st_mode & 07777));
        EXPECT_EQ_INT(chmod(path, 0604), 0);
        EXPECT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
        EXPECT_MSG(stat(path, &sb) == 0 && (sb.st_mode & 07777) == 0604, "umask %03o: replaced file mode %03o",
                   (unsigned)masks[i], (unsigned)(sb.st_mode & 07777));
    }
    umask(saved);
    free(p);
}

/* A save into a directory without write permission, run unprivileged (test.h). */
typedef struct ro_save { const char *path; const pm_photon *p; const pm_map_header *h; } ro_save;
static void save_read_only(void *arg) {
    const ro_save *a = arg;
    EXPECT_EQ_INT(pm_map_save(a->path, a->p, a->h), PM_EIO);
}

/* Oracle: mapfile.h's ERRORS. A save into a directory the user may enter but not write (mode
 * 0500, owned by the user) fails with PM_EIO and leaves nothing: no file, no temporary. Root
 * writes anyway, so as root the save runs as nobody (the directory then nobody's own); a SKIP,
 * counted so, only where privileges cannot be dropped. */
TEST(map_file_save_into_read_only_directory) {
    char dir[600], path[700], why[256];
    size_t n = 100;
    pm_photon *p = some_photons(n);
    pm_map_header h = {PM_FILE_VERSION, 0, n, PM_MAP_GLOBAL, 1000, 0, {0, 0}};
    snprintf(dir, sizeof dir, "%s/ro", pm_test_tmpdir());
    snprintf(path, sizeof path, "%s/map.pm", dir);
    ASSERT_EQ_INT(mkdir(dir, 0500), 0);
    if (geteuid() == 0) {
        ASSERT_EQ_INT(chmod(pm_test_tmpdir(), 0711), 0);
        ASSERT_EQ_INT(chown(dir, PM_TEST_NOBODY, PM_TEST_NOBODY), 0);
    }
    ro_save a = {path, p, &h};
    int rc = pm_test_unprivileged(save_read_only, &a, why, sizeof why);
    free(p);
    if (rc < 0) SKIP(why);
    EXPECT_EQ_INT(rc, 0);
    const char *none[] = {NULL};
    EXPECT_EQ_INT(stray_entries(dir, none, 0), 0);
    chmod(dir, 0700);
}

/* Oracle: the file system, inspected with lstat and by reading back. pm_map_save never
 * replaces or writes through a path that is not a regular file: a FIFO, a symbolic link (to a
 * regular file, whose contents must stay as they were) and a directory (a character device:
 * the next test) all give PM_ENOTFILE and stay what they were. A file named PATH.tmp (the old
 * fixed temporary name) is left alone. No temporary is left in the directory after a
 * successful save or a refused one, and the saved file keeps a replaced file's permission
 * bits. */
TEST(map_file_never_replaces_what_is_not_a_regular_file) {
    const char *dir = pm_test_tmpdir();
    char path[600], fifo[600], link[600], old[600], sub[600];
    size_t n = 100;
    pm_photon *p = some_photons(n);
    pm_map_header h = {PM_FILE_VERSION, 0, n, PM_MAP_GLOBAL, 1000, 0, {0, 0}};
    snprintf(path, sizeof path, "%s/map.pm", dir);
    snprintf(old, sizeof old, "%s/map.pm.tmp", dir);
    snprintf(fifo, sizeof fifo, "%s/fifo.pm", dir);
    snprintf(link, sizeof link, "%s/link.pm", dir);
    snprintf(sub, sizeof sub, "%s/sub.pm", dir);
    FILE *f = fopen(old, "wb");
    ASSERT(f);
    fputs("not mine", f);
    fclose(f);
    ASSERT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
    ASSERT_EQ_INT(chmod(path, 0640), 0);
    ASSERT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
    struct stat sb;
    ASSERT_EQ_INT(stat(path, &sb), 0);
    EXPECT_EQ_INT(sb.st_mode & 07777, 0640);
    ASSERT_EQ_INT(stat(old, &sb), 0);
    EXPECT_EQ_INT(sb.st_size, 8);

    ASSERT_EQ_INT(mkfifo(fifo, 0600), 0);
    EXPECT_EQ_INT(pm_map_save(fifo, p, &h), PM_ENOTFILE);
    ASSERT_EQ_INT(lstat(fifo, &sb), 0);
    EXPECT(S_ISFIFO(sb.st_mode));

    ASSERT_EQ_INT(symlink("map.pm", link), 0);
    struct stat before, after;
    ASSERT_EQ_INT(stat(path, &before), 0);
    pm_map_header h2 = h;
    h2.count = 7;
    EXPECT_EQ_INT(pm_map_save(link, p, &h2), PM_ENOTFILE);
    ASSERT_EQ_INT(lstat(link, &sb), 0);
    EXPECT(S_ISLNK(sb.st_mode));
    ASSERT_EQ_INT(stat(path, &after), 0);
    EXPECT_EQ_INT(after.st_size, before.st_size);
    EXPECT_EQ_INT(after.st_ino, before.st_ino);

    ASSERT_EQ_INT(mkdir(sub, 0700), 0);
    EXPECT_EQ_INT(pm_map_save(sub, p, &h), PM_ENOTFILE);

    const char *known[] = {"map.pm", "map.pm.tmp", "fifo.pm", "link.pm", "sub.pm"};
    EXPECT_EQ_INT(stray_entries(dir, known, 5), 0);
    EXPECT(file_holds(path, p, n));
    free(p);
}

/* Oracle: lstat. A character device made with mknod inside the test's own directory (c 1 3,
 * never under /dev) is refused with PM_ENOTFILE, stays the same device, and no temporary is
 * left beside it. Skipped, and counted so, where mknod is not permitted. */
TEST(map_file_refuses_a_character_device) {
    const char *dir = pm_test_tmpdir();
    char dev[600];
    size_t n = 100;
    snprintf(dev, sizeof dev, "%s/dev.pm", dir);
    if (mknod(dev, S_IFCHR | 0600, makedev(1, 3)) != 0) {
        char why[256];
        snprintf(why, sizeof why, "mknod of a character device not permitted here (%s)", strerror(errno));
        SKIP(why);
    }
    pm_photon *p = some_photons(n);
    pm_map_header h = {PM_FILE_VERSION, 0, n, PM_MAP_GLOBAL, 1000, 0, {0, 0}};
    struct stat sb;
    EXPECT_EQ_INT(pm_map_save(dev, p, &h), PM_ENOTFILE);
    ASSERT_EQ_INT(lstat(dev, &sb), 0);
    EXPECT(S_ISCHR(sb.st_mode) && major(sb.st_rdev) == 1 && minor(sb.st_rdev) == 3);
    const char *known[] = {"dev.pm"};
    EXPECT_EQ_INT(stray_entries(dir, known, 1), 0);
    free(p);
}

/* Oracle: the loaded file. Two processes save different maps to the same path 50 times each
 * at the same moment: every save succeeds, the file that remains loads and is one of the two
 * maps whole, and no temporary is left. (With one fixed temporary name, two saves write into
 * the same file and one renames the other's half-written data, or fails.) */
TEST(map_file_concurrent_saves) {
    const char *dir = pm_test_tmpdir();
    char path[600];
    snprintf(path, sizeof path, "%s/map.pm", dir);
    size_t n[2] = {20000, 30001};
    pm_photon *p[2] = {some_photons(n[0]), some_photons(n[1])};
    pid_t kid[2];
    for (int c = 0; c < 2; c++) {
        kid[c] = fork();
        ASSERT(kid[c] >= 0);
        if (kid[c] == 0) {
            pm_map_header h = {PM_FILE_VERSION, 0, n[c], PM_MAP_GLOBAL, 1, 0, {0, 0}};
            int bad = 0;
            for (int i = 0; i < 50; i++) bad += pm_map_save(path, p[c], &h) != PM_OK;
            _exit(bad ? 1 : 0);
        }
    }
    for (int c = 0; c < 2; c++) {
        int status = 0;
        ASSERT(waitpid(kid[c], &status, 0) == kid[c]);
        EXPECT_MSG(WIFEXITED(status) && WEXITSTATUS(status) == 0, "saver %d: some saves failed", c);
    }
    pm_photon *q = NULL;
    pm_map_header g;
    ASSERT_EQ_INT(pm_map_load(path, &q, &g), PM_OK);
    int which = g.count == n[0] ? 0 : 1;
    EXPECT(g.count == n[which] && memcmp(q, p[which], n[which] * sizeof *q) == 0);
    const char *known[] = {"map.pm"};
    EXPECT_EQ_INT(stray_entries(dir, known, 1), 0);
    free(q);
    free(p[0]);
    free(p[1]);
}

/* Oracle: the header's own fields against the file's size. A file truncated anywhere (inside
 * the header, inside a record, at a record boundary), a file with bytes after its last record,
 * a count near 2^64 / 20 (whose product with 20 wraps to a small number), the largest count,
 * an unknown kind and non-zero reserved bytes all give PM_EFORMAT and allocate nothing (the
 * sanitizer build would report an allocation of the counted size as too large). */
TEST(map_file_load_checks_the_header_against_the_size) {
    char path[600];
    snprintf(path, sizeof path, "%s/map.pm", pm_test_tmpdir());
    size_t n = 50;
    pm_photon *p = some_photons(n), *q = (pm_photon *)1;
    pm_map_header h = {PM_FILE_VERSION, 0, n, PM_MAP_CAUSTIC, 9, 0, {0, 0}}, g;
    const off_t cuts[] = {0, 8, 63, 64, 65, 64 + 20 * 25, 64 + 20 * 49 + 19};
    for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++) {
        ASSERT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
        ASSERT_EQ_INT(truncate(path, cuts[i]), 0);
        EXPECT_MSG(pm_map_load(path, &q, &g) == PM_EFORMAT, "truncated to %ld bytes", (long)cuts[i]);
        EXPECT(q == NULL);
    }
    ASSERT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
    ASSERT_EQ_INT(truncate(path, 64 + 20 * 50 + 20), 0); /* one zero record too many */
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), PM_EFORMAT);
    const uint64_t counts[] = {0xCCCCCCCCCCCCCCCDull /* * 20 wraps to 4 */, UINT64_MAX,
                               (uint64_t)1 << 40, 51, 49};
    for (size_t i = 0; i < sizeof counts / sizeof counts[0]; i++) {
        ASSERT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
        FILE *f = fopen(path, "r+b");
        ASSERT(f);
        unsigned char b[8];
        for (int j = 0; j < 8; j++) b[j] = (unsigned char)(counts[i] >> (8 * j));
        fseek(f, 16, SEEK_SET);
        fwrite(b, 1, 8, f);
        fclose(f);
        EXPECT_MSG(pm_map_load(path, &q, &g) == PM_EFORMAT, "count %llu", (unsigned long long)counts[i]);
        EXPECT(q == NULL);
    }
    /* kind 0 and 6, and a non-zero reserved byte */
    const int offs[3] = {24, 24, 60};
    const unsigned char vals[3] = {0, 6, 1};
    for (int i = 0; i < 3; i++) {
        ASSERT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
        FILE *f = fopen(path, "r+b");
        ASSERT(f);
        fseek(f, offs[i], SEEK_SET);
        fputc(vals[i], f);
        fclose(f);
        EXPECT_MSG(pm_map_load(path, &q, &g) == PM_EFORMAT, "byte %d = %d", offs[i], vals[i]);
    }
    free(p);
}

/* Oracle: the directory listing and the old file's bytes. A save that fails while writing
 * (a child process limited to 4 KB files by RLIMIT_FSIZE, so write() fails with EFBIG) returns
 * PM_EIO, leaves no temporary behind and leaves the existing file as it was. */
TEST(map_file_failed_save_removes_its_temporary) {
    const char *dir = pm_test_tmpdir();
    char path[600];
    snprintf(path, sizeof path, "%s/map.pm", dir);
    size_t n = 100, big = 3000;
    pm_photon *p = some_photons(big);
    pm_map_header h = {0, 0, n, PM_MAP_GLOBAL, 1, 0, {0, 0}};
    ASSERT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
    pid_t kid = fork();
    ASSERT(kid >= 0);
    if (kid == 0) {
        signal(SIGXFSZ, SIG_IGN);
        struct rlimit rl = {4096, 4096};
        if (setrlimit(RLIMIT_FSIZE, &rl) != 0) _exit(3);
        pm_map_header hb = {0, 0, big, PM_MAP_GLOBAL, 1, 0, {0, 0}};
        _exit(pm_map_save(path, p, &hb) == PM_EIO ? 0 : 1);
    }
    int status = 0;
    ASSERT(waitpid(kid, &status, 0) == kid);
    EXPECT_MSG(WIFEXITED(status) && WEXITSTATUS(status) == 0, "child status %d", status);
    const char *known[] = {"map.pm"};
    EXPECT_EQ_INT(stray_entries(dir, known, 1), 0);
    EXPECT(file_holds(path, p, n));
    free(p);
}

/* Patch len bytes at offset off of the file at path. */
static int patch_bytes(const char *path, long off, const unsigned char *b, size_t len) {
    FILE *f = fopen(path, "r+b");
    if (!f) return -1;
    int ok = fseek(f, off, SEEK_SET) == 0 && fwrite(b, 1, len, f) == len;
    return fclose(f) == 0 && ok ? 0 : -1;
}

/* Oracle: mapfile.h's VERSIONS paragraph, on files patched byte by byte. A version-1 file
 * (version word 1, bytes 40..63 zero) loads with version 1, tag {0, 0} and the same photons;
 * a version-1 file with any non-zero byte at 40..63 (where version 2 keeps its tags) or with
 * kind PM_MAP_VOLUME is corrupt; versions 0 and 4 are PM_EVERSION; a map of kind
 * PM_MAP_VOLUME round-trips; saving a kind outside the PM_MAP_* values is PM_EINVAL and
 * writes nothing. */
TEST(map_file_reads_version_1_and_tags) {
    char path[600];
    snprintf(path, sizeof path, "%s/v.pm", pm_test_tmpdir());
    size_t n = 40;
    pm_photon *p = some_photons(n), *q = NULL;
    pm_map_header h = {0, 0, n, PM_MAP_GLOBAL, 77, 0, {0xdeadbeefcafef00dull, 42}}, g;
    const unsigned char one[4] = {1, 0, 0, 0}, zeros[24] = {0};
    /* Version 1: the version word set to 1 and the tags cleared. */
    ASSERT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
    ASSERT_EQ_INT(patch_bytes(path, 8, one, 4), 0);
    ASSERT_EQ_INT(patch_bytes(path, 40, zeros, 24), 0);
    memset(&g, 0xff, sizeof g);
    ASSERT_EQ_INT(pm_map_load(path, &q, &g), PM_OK);
    EXPECT_EQ_INT(g.version, 1);
    EXPECT(g.tag[0] == 0 && g.tag[1] == 0);
    EXPECT_EQ_INT(g.count, n);
    EXPECT_EQ_INT(g.kind, PM_MAP_GLOBAL);
    EXPECT(g.emitted == 77);
    EXPECT(q && memcmp(p, q, n * sizeof *p) == 0);
    free(q);
    q = NULL;
    /* Version 1 with a tag left in (any byte 40..63 non-zero): corrupt. */
    for (int b = 40; b < 64; b += 5) {
        ASSERT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
        ASSERT_EQ_INT(patch_bytes(path, 8, one, 4), 0);
        ASSERT_EQ_INT(patch_bytes(path, 40, zeros, 24), 0);
        const unsigned char x = 0x10;
        ASSERT_EQ_INT(patch_bytes(path, b, &x, 1), 0);
        EXPECT_MSG(pm_map_load(path, &q, &g) == PM_EFORMAT, "version 1, byte %d set", b);
        EXPECT(q == NULL);
    }
    /* Version 1 knew no volume maps; version 2 does. */
    pm_map_header hv = h;
    hv.kind = PM_MAP_VOLUME;
    ASSERT_EQ_INT(pm_map_save(path, p, &hv), PM_OK);
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), PM_OK);
    EXPECT_EQ_INT(g.kind, PM_MAP_VOLUME);
    EXPECT(g.tag[0] == 0xdeadbeefcafef00dull && g.tag[1] == 42);
    EXPECT_EQ_INT(g.version, PM_FILE_VERSION);
    free(q);
    q = NULL;
    ASSERT_EQ_INT(patch_bytes(path, 8, one, 4), 0);
    ASSERT_EQ_INT(patch_bytes(path, 40, zeros, 24), 0);
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), PM_EFORMAT);
    /* Versions 0 and 4. */
    const unsigned char v0[4] = {0, 0, 0, 0}, v3[4] = {4, 0, 0, 0};
    ASSERT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
    ASSERT_EQ_INT(patch_bytes(path, 8, v0, 4), 0);
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), PM_EVERSION);
    ASSERT_EQ_INT(patch_bytes(path, 8, v3, 4), 0);
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), PM_EVERSION);
    EXPECT(q == NULL);
    /* A kind outside PM_MAP_*: refused before anything is written. */
    char fresh[640];
    snprintf(fresh, sizeof fresh, "%s/never.pm", pm_test_tmpdir());
    const uint32_t bad_kinds[2] = {0, PM_MAP_VOLUME + 1};
    for (int i = 0; i < 2; i++) {
        pm_map_header hk = h;
        hk.kind = bad_kinds[i];
        EXPECT_EQ_INT(pm_map_save(fresh, p, &hk), PM_EINVAL);
        EXPECT(access(fresh, F_OK) != 0);
    }
    free(p);
}

/* Oracle: mapfile.h's VERSIONS paragraph (version 3's checksum), on files patched byte by byte.
 * One flipped bit anywhere the checksum covers is refused as PM_EFORMAT with nothing returned:
 * in the first, a middle and the last record (position, power, flag, normal bytes), in a tag,
 * in emitted and in tree_bucket (header fields the other checks accept any value of), and in
 * the checksum itself. The same file made version 2 (version word 2, bytes 56..63 zero) still
 * loads, with version 2 and the same photons; with a record bit flipped it loads too (version
 * 2 has no checksum: what version 3 adds), and with a byte at 56..63 non-zero it is corrupt. */
TEST(map_file_checksum_refuses_flipped_bits) {
    char path[600];
    snprintf(path, sizeof path, "%s/c.pm", pm_test_tmpdir());
    size_t n = 2500; /* over two read chunks of 1024 records */
    pm_photon *p = some_photons(n), *q = NULL;
    pm_map_header h = {0, 0, n, PM_MAP_CAUSTIC, 123456, 8, {0x0123456789abcdefull, 99}}, g;
    const long rec = 64 + 20 * (long)n;
    const long at[] = {64, 64 + 5, 64 + 12, 64 + 18, 64 + 20 * 1100 + 7, 64 + 20 * 1100 + 19, rec - 1,
                       40, 47, 55, 28, 36, 56, 63};
    for (size_t i = 0; i < sizeof at / sizeof at[0]; i++) {
        ASSERT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
        FILE *f = fopen(path, "r+b");
        ASSERT(f);
        fseek(f, at[i], SEEK_SET);
        int c = fgetc(f);
        fseek(f, at[i], SEEK_SET);
        fputc(c ^ 0x10, f);
        fclose(f);
        q = (pm_photon *)1;
        EXPECT_MSG(pm_map_load(path, &q, &g) == PM_EFORMAT, "bit flipped at byte %ld: loaded", at[i]);
        EXPECT_MSG(q == NULL, "byte %ld: photons returned", at[i]);
        if (q != (pm_photon *)1) free(q);
        q = NULL;
    }
    /* Version 2: no checksum, bytes 56..63 zero. */
    const unsigned char two[4] = {2, 0, 0, 0}, zeros[8] = {0};
    ASSERT_EQ_INT(pm_map_save(path, p, &h), PM_OK);
    ASSERT_EQ_INT(patch_bytes(path, 8, two, 4), 0);
    ASSERT_EQ_INT(patch_bytes(path, 56, zeros, 8), 0);
    memset(&g, 0xff, sizeof g);
    ASSERT_EQ_INT(pm_map_load(path, &q, &g), PM_OK);
    EXPECT_EQ_INT(g.version, 2);
    EXPECT_EQ_INT(g.count, n);
    EXPECT(g.tag[0] == 0x0123456789abcdefull && g.tag[1] == 99 && g.emitted == 123456 && g.tree_bucket == 8);
    EXPECT(q && memcmp(p, q, n * sizeof *p) == 0);
    free(q);
    q = NULL;
    const unsigned char x = 0x5a;
    ASSERT_EQ_INT(patch_bytes(path, 64 + 20 * 1100 + 7, &x, 1), 0);
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), PM_OK);
    free(q);
    q = NULL;
    ASSERT_EQ_INT(patch_bytes(path, 60, &x, 1), 0);
    EXPECT_EQ_INT(pm_map_load(path, &q, &g), PM_EFORMAT);
    EXPECT(q == NULL);
    free(p);
}
