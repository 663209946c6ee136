/* test_render_import_exr.c: OpenEXR output and input (render/image/exr.h).
 *
 * Oracles: the film's own floats (a float round trip is bit for bit); IEEE half precision (a
 * half round trip is within 2^-11 relative, round to nearest, over half's normal range, and
 * beyond 65504 is infinity); the PFM of the same render (an EXR --hdr holds the same pixels,
 * --compare reads EXR and reports rmse 0, --tonemap from EXR writes the PNG that the PFM
 * gives, byte for byte); Debian's exrheader (package openexr) reads our files, when installed;
 * truncated files fail with the file named, never a crash.
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "image/exr.h"
#include "image/film.h"

static int write_exr(const film *f, const char *path, int type, char *err, size_t cap) {
    FILE *fp = fopen(path, "wb");
    if (!fp) return -1;
    int rc = exr_write_fp(f->px, f->width, f->height, fp, type, err, cap);
    if (fclose(fp) != 0) rc = -1;
    return rc;
}

/* Read an EXR file into g (zeroed first), as film_read_image does for an EXR file. */
static int read_exr(film *g, const char *path, char *err, size_t cap) {
    memset(g, 0, sizeof *g);
    return exr_read_rgb(path, &g->width, &g->height, &g->px, err, cap);
}

/* A 37 x 23 film (not a multiple of ZIP's 16-line chunks) of varied floats. */
static void test_film(film *f, int half_range) {
    film_init(f, 37, 23);
    uint64_t s = 0x9e3779b97f4a7c15ull;
    for (int i = 0; i < 37 * 23 * 3; i++) {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        double u = (double)(s >> 11) / 9007199254740992.0;
        /* log-uniform: float range 1e-30..1e30, half's normal range 6.2e-5..65000 */
        double lo = half_range ? log(6.2e-5) : log(1e-30), hi = half_range ? log(65000.0) : log(1e30);
        f->px[i] = (float)exp(lo + u * (hi - lo));
    }
    f->px[0] = 0;
    f->px[4] = 1;
    if (!half_range) {
        f->px[5] = 3.4e38f;
        f->px[6] = 1e-40f; /* a float subnormal */
    }
}

/* Oracle: the film's floats, bit for bit, after a float EXR round trip. */
TEST(exr_float_round_trip_exact) {
    film f, g;
    test_film(&f, 0);
    char path[1024], err[400] = "";
    snprintf(path, sizeof path, "%s/f.exr", pm_test_tmpdir());
    ASSERT_MSG(write_exr(&f, path, EXR_FLOAT, err, sizeof err) == 0, "%s", err);
    EXPECT(exr_is_exr(path));
    ASSERT_MSG(read_exr(&g, path, err, sizeof err) == 0, "%s", err);
    ASSERT(g.width == 37 && g.height == 23);
    EXPECT(memcmp(f.px, g.px, sizeof(float) * 37 * 23 * 3) == 0);
    int diff = 0;
    for (int i = 0; i < 37 * 23 * 3; i++) diff += memcmp(&f.px[i], &g.px[i], 4) != 0;
    EXPECT_EQ_INT(diff, 0);
    film_free(&g);
    /* film_read_image tells EXR from PFM by the bytes, whatever the name */
    snprintf(path, sizeof path, "%s/f.exr", pm_test_tmpdir());
    ASSERT_MSG(film_read_image(&g, path, err, sizeof err) == 0, "%s", err);
    EXPECT(memcmp(f.px, g.px, sizeof(float) * 37 * 23 * 3) == 0);
    film_free(&g);
    film_free(&f);
}

/* Oracle: IEEE 754 half, round to nearest: |h - v| <= 2^-11 |v| for v in the normal range
 * (6.1e-5 .. 65504); 0 and 1 exact; 1e6 (beyond 65504) is infinity, as exr.h says. */
TEST(exr_half_within_half_precision) {
    film f, g;
    test_film(&f, 1);
    f.px[7] = 1e6f;
    char path[1024], err[400] = "";
    snprintf(path, sizeof path, "%s/h.exr", pm_test_tmpdir());
    ASSERT_MSG(write_exr(&f, path, EXR_HALF, err, sizeof err) == 0, "%s", err);
    ASSERT_MSG(read_exr(&g, path, err, sizeof err) == 0, "%s", err);
    ASSERT(g.width == 37 && g.height == 23);
    double worst = 0;
    int exact = 0;
    for (int i = 0; i < 37 * 23 * 3; i++) {
        if (i == 7) continue;
        double r = fabs((double)g.px[i] - f.px[i]) / (f.px[i] > 0 ? f.px[i] : 1);
        if (r > worst) worst = r;
        exact += g.px[i] == f.px[i];
    }
    printf("    half: worst relative error %.3g (bound %.3g), %d of %d exact\n", worst, ldexp(1, -11), exact,
           37 * 23 * 3);
    EXPECT_MSG(worst <= ldexp(1, -11), "worst relative error %g", worst);
    EXPECT(worst > 0); /* it is half: something was rounded */
    EXPECT(g.px[0] == 0 && g.px[4] == 1);
    EXPECT(isinf(g.px[7]));
    /* a half file is about half the size of the float one */
    film_free(&g);
    film_free(&f);
}

/* Oracle: every prefix of a good file is refused with the file named (never a crash; ASan
 * and UBSan watch the sanitizer build), and a file that is not EXR is refused. */
TEST(exr_truncated_files_refused) {
    film f, g;
    test_film(&f, 0);
    char path[1024], cut[1024], err[400] = "";
    snprintf(path, sizeof path, "%s/t.exr", pm_test_tmpdir());
    snprintf(cut, sizeof cut, "%s/cut.exr", pm_test_tmpdir());
    ASSERT_MSG(write_exr(&f, path, EXR_FLOAT, err, sizeof err) == 0, "%s", err);
    FILE *fp = fopen(path, "rb");
    ASSERT(fp);
    unsigned char *b = malloc(1 << 20);
    ASSERT(b);
    size_t n = fread(b, 1, 1 << 20, fp);
    fclose(fp);
    int refused = 0, tried = 0;
    for (size_t len = 0; len < n; len += (len < 400 ? 1 : 97)) {
        fp = fopen(cut, "wb");
        ASSERT(fp);
        fwrite(b, 1, len, fp);
        fclose(fp);
        err[0] = 0;
        int rc = read_exr(&g, cut, err, sizeof err);
        tried++;
        if (rc == 0) {
            film_free(&g);
            continue;
        }
        refused++;
        EXPECT_MSG(strncmp(err, cut, strlen(cut)) == 0, "length %zu: %s", len, err);
    }
    printf("    %d of %d truncations refused\n", refused, tried);
    EXPECT_EQ_INT(refused, tried);
    free(b);
    film_free(&f);
    EXPECT(read_exr(&g, "/nonexistent/x.exr", err, sizeof err) < 0 && strstr(err, "No such file"));
}

/* Oracle: the same render written as PFM. --hdr x.exr holds the PFM's pixels (--compare
 * reads both: rmse 0), --tonemap of the EXR writes the same PNG bytes as of the PFM,
 * --hdr-half is refused without an .exr (exit 2, nothing rendered). */
TEST(render_hdr_exr_compare_tonemap) {
    const char *dir = pm_test_tmpdir();
    char cmd[8192], out[16384];
    snprintf(cmd, sizeof cmd,
             "cd '%s' && R='%s/render' && S='%s/data/scenes/cornell_box.json' && "
             "$R $S --width 24 --height 16 --spp 4 --quiet --threads 2 --hdr a.exr -o a.png >/dev/null && "
             "$R $S --width 24 --height 16 --spp 4 --quiet --threads 2 --hdr a.pfm >/dev/null && "
             "$R $S --width 24 --height 16 --spp 4 --quiet --threads 2 --hdr h.exr --hdr-half >/dev/null && "
             "$R --compare a.exr a.pfm && echo HALF && $R --compare h.exr a.pfm && "
             "$R --tonemap a.exr t1.png && $R --tonemap a.pfm t2.png && cmp t1.png t2.png && echo SAME",
             dir, pm_test_build_dir(), pm_test_source_dir());
    int rc = pm_test_run(cmd, out, sizeof out);
    ASSERT_MSG(rc == 0, "exit %d: %s", rc, out);
    EXPECT_MSG(strstr(out, "rmse 0\n") && strstr(out, "rel_mean 0\n"), "%s", out);
    const char *h = strstr(out, "HALF");
    ASSERT(h);
    double rel = 1;
    const char *r = strstr(h, "rel_mean ");
    if (r) rel = atof(r + 9);
    EXPECT_MSG(fabs(rel) < 1e-3, "half rel_mean %g: %s", rel, h);
    EXPECT_MSG(strstr(out, "SAME"), "%s", out);
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' '%s/data/scenes/cornell_box.json' --quiet --hdr x.pfm --hdr-half",
             dir, pm_test_build_dir(), pm_test_source_dir());
    rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 2 && strstr(out, "--hdr-half needs --hdr FILE.exr"), "exit %d: %s", rc, out);
}

/* Oracle: Debian's exrheader (package openexr, the C++ library's reader) reads our float and
 * half files and reports their channels and size. */
TEST(exr_exrheader_reads_ours) {
    char out[8192];
    if (pm_test_run("command -v exrheader", out, sizeof out) != 0) SKIP("exrheader not installed (Debian: openexr)");
    film f;
    test_film(&f, 1);
    char path[1024], cmd[2048], err[400] = "";
    for (int type = 0; type < 2; type++) {
        snprintf(path, sizeof path, "%s/e%d.exr", pm_test_tmpdir(), type);
        ASSERT_MSG(write_exr(&f, path, type, err, sizeof err) == 0, "%s", err);
        snprintf(cmd, sizeof cmd, "exrheader '%s'", path);
        int rc = pm_test_run(cmd, out, sizeof out);
        EXPECT_MSG(rc == 0, "exit %d: %s", rc, out);
        const char *want = type ? "R, 16-bit floating-point" : "R, 32-bit floating-point";
        EXPECT_MSG(strstr(out, want) && strstr(out, "dataWindow (type box2i): (0 0) - (36 22)"), "%s", out);
    }
    film_free(&f);
}
