/* test_photon.c: the packed fields of pm_photon and the photon-map file format.
 *
 * Oracles: the precision bounds documented in photon.h / photon.c (RGBE relative error of the
 * largest channel <= 2^-8 and absolute error of every channel <= 2^-8 / (1 - 2^-9) * max;
 * direction angular
 * error <= 0.79 degrees, <= 0.36 at the poles; normal angular error <= the lattice's covering
 * radius, 10 degrees, and exactly the nearest of the 256 directions by brute force), and
 * byte-for-byte equality for file round trips.
 */
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "photon.h"
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

TEST(photon_is_20_bytes) { ASSERT_EQ_INT(sizeof(pm_photon), 20); }

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

/* Oracle: pm_photon_set stores exactly what the separate encoders produce. */
TEST(photon_set_packs_all_fields) {
    pm_photon p;
    memset(&p, 0xFF, sizeof p);
    float pos[3] = {1.5f, -2, 3}, pw[3] = {0.5f, 0.25f, 2}, dir[3] = {0, 1, 0}, n[3] = {1, 0, 0};
    pm_photon_set(&p, pos, pw, dir, n, PM_KIND_CAUSTIC);
    EXPECT(p.pos[0] == 1.5f && p.pos[1] == -2 && p.pos[2] == 3);
    uint8_t e[4], th, ph;
    pm_rgbe_encode(pw, e);
    EXPECT(memcmp(e, p.power, 4) == 0);
    pm_dir_encode(dir, &th, &ph);
    EXPECT(th == p.theta && ph == p.phi);
    EXPECT_EQ_INT(p.normal, pm_normal_encode(n));
    EXPECT_EQ_INT(pm_photon_kind(&p), PM_KIND_CAUSTIC);
    EXPECT_EQ_INT(p.flag & PM_FLAG_AXIS_MASK, 0);
}

static pm_photon *some_photons(size_t n) {
    pm_photon *p = malloc((n ? n : 1) * sizeof *p);
    for (size_t i = 0; i < n; i++) {
        float pos[3] = {(float)ph_uniform(), (float)i, -(float)ph_uniform()};
        float pw[3] = {(float)ph_uniform(), 0.1f, 1e-3f}, dir[3] = {1, (float)ph_uniform(), 0};
        pm_photon_set(&p[i], pos, pw, dir, dir, (int)(i % 4));
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
    pm_map_header h = {PM_FILE_VERSION, sizeof(pm_photon), n, PM_MAP_CAUSTIC, 123456789012ull, 8};
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
    free(q);
    struct stat sb;
    ASSERT_EQ_INT(stat(path, &sb), 0);
    EXPECT_EQ_INT(sb.st_size, 64 + 20 * n);
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    EXPECT(access(tmp, F_OK) != 0);

    /* An empty map. */
    pm_map_header h0 = {0, 0, 0, PM_MAP_GLOBAL, 0, 0};
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
    fputc(2, f);
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
    snprintf(path, sizeof path, "%s/ro", pm_test_tmpdir());
    ASSERT_EQ_INT(mkdir(path, 0500), 0);
    snprintf(path, sizeof path, "%s/ro/map.pm", pm_test_tmpdir());
    if (geteuid() != 0) { /* root ignores directory permissions */
        EXPECT_EQ_INT(pm_map_save(path, p, &h), PM_EIO);
        EXPECT(access(path, F_OK) != 0);
    }
    /* Writing over a directory fails at the rename: the .tmp is removed. */
    snprintf(path, sizeof path, "%s/dir.pm", pm_test_tmpdir());
    ASSERT_EQ_INT(mkdir(path, 0700), 0);
    EXPECT_EQ_INT(pm_map_save(path, p, &h), PM_EIO);
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    EXPECT(access(tmp, F_OK) != 0);
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", pm_test_tmpdir());
    (void)cmd;
    free(p);
}
