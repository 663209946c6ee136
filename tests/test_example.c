/* test_example.c: the installed library as a user gets it. `make test` stages `make install`
 * in BUILD/stage and builds the example program (photonmap/examples/knn_example.c) against it
 * with pkg-config twice: example/knn_example against the shared library, and
 * example/knn_example_static against the static one. These tests run both and check what
 * was installed: the shared library's soname, symlinks and exported symbols, the version
 * macros, photonmap.pc and the render program.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "test.h"
#include "common.h"
#include "photon.h"

/* Oracle: brute force. The example is deterministic: it stores N = 100000 photons at points
 * of a fixed LCG on the unit square (power 1e-5, 1e-5, 0.8e-5 each), finds the K = 50 nearest
 * to (0.5, 0, 0.5) within dist2 0.01 and prints sum(power) / (pi r2) with r2 the 50th dist2.
 * The same points, sorted by dist2 here, give that r2; the powers are the RGBE-decoded
 * photon's (all equal). The printed density must match to its printed 4 significant digits
 * (relative 5e-4, plus float rounding: tolerance 1e-3, so a 1.2x error fails by 200 times
 * the tolerance), the nearest and farthest dist2 to their 3 printed digits (5e-3), and the
 * density is within 15% of the analytic 1 (about 1/sqrt(50), the noise of a 50-photon
 * estimate: a sanity check on the oracle itself). Building is checked by the Makefile; this
 * checks that what was built works, linked either way. */
static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static void example_oracle(double *density, double *near2, double *far2) {
    enum { N = 100000, K = 50 };
    static double d2[N];
    /* knn_example.c's points, repeated on purpose: the example stands alone (a user's program
     * shares no code with the tests), and the oracle must not run what it checks. */
    unsigned seed = 1;
    for (int i = 0; i < N; i++) {
        seed = seed * 1664525u + 1013904223u;
        float x = (float)(seed >> 8) / 16777216.0f;
        seed = seed * 1664525u + 1013904223u;
        float z = (float)(seed >> 8) / 16777216.0f;
        float dx = x - 0.5f, dz = z - 0.5f;
        d2[i] = (double)(dx * dx + dz * dz);
    }
    qsort(d2, N, sizeof *d2, cmp_double);
    pm_photon p;
    float c[3];
    pm_photon_init(&p, (float[3]){0, 0, 0}, (float[3]){1e-5f, 1e-5f, 0.8e-5f}, (float[3]){0, -1, 0},
                   (float[3]){0, 1, 0}, PM_KIND_INDIRECT);
    pm_rgbe_decode(p.power, c);
    *near2 = d2[0];
    *far2 = d2[K - 1];
    *density = K * (double)c[0] / (3.14159265 * d2[K - 1]);
}

static void check_example(const char *name) {
    char cmd[2048], out[4096];
    snprintf(cmd, sizeof cmd, "%s/example/%s", pm_test_build_dir(), name);
    EXPECT_MSG(access(cmd, X_OK) == 0, "%s was not built (make example)", cmd);
    if (access(cmd, X_OK) != 0) return;
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    int found = 0;
    double d[3] = {0, 0, 0}, n2 = 0, f2 = 0, want, want_n2, want_f2;
    example_oracle(&want, &want_n2, &want_f2);
    const char *p = strstr(out, "found ");
    EXPECT_MSG(p && sscanf(p, "found %d photons, nearest dist2 %lf, farthest dist2 %lf", &found, &n2, &f2) == 3,
               "%s: %s", name, out);
    EXPECT_EQ_INT(found, 50);
    EXPECT_REL(n2, want_n2, 5e-3);
    EXPECT_REL(f2, want_f2, 5e-3);
    p = strstr(out, "flux density ");
    EXPECT_MSG(p && sscanf(p, "flux density %lf %lf %lf", &d[0], &d[1], &d[2]) == 3, "%s: %s", name, out);
    EXPECT_REL(d[0], want, 1e-3);
    EXPECT_REL(want, 1.0, 0.15);
    EXPECT_REL(d[1], d[0], 1e-6);
    EXPECT_REL(d[2], 0.8 * d[0], 0.01);
    snprintf(cmd, sizeof cmd, "%s/example/%s --help", pm_test_build_dir(), name);
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "usage: knn_example") != NULL, "%s", out);
}

TEST(example_program_runs_against_installed_library) {
    check_example("knn_example");
    check_example("knn_example_static");
}

/* Oracle: the ELF dynamic sections (readelf -d). The shared example needs libphotonmap.so.N
 * for N = PM_VERSION_MAJOR, the static one does not need it at all. */
TEST(example_links_shared_and_static) {
    char cmd[2048], out[8192], want[128];
    snprintf(want, sizeof want, "[libphotonmap.so.%d]", PM_VERSION_MAJOR);
    snprintf(cmd, sizeof cmd, "readelf -d '%s/example/knn_example'", pm_test_build_dir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "(NEEDED)") && strstr(out, want), "shared example does not need %s: %s", want, out);
    snprintf(cmd, sizeof cmd, "readelf -d '%s/example/knn_example_static'", pm_test_build_dir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(!strstr(out, "libphotonmap"), "static example needs the shared library: %s", out);
}

/* Oracle: the documented names. The soname is libphotonmap.so.MAJOR; libphotonmap.so links to
 * it and it to libphotonmap.so.MAJOR.MINOR.PATCH, all from the PM_VERSION_* macros. */
TEST(packaging_shared_library_soname_and_links) {
    char path[2048], link[256], want[128], cmd[4096], out[8192];
    ssize_t n;
    snprintf(path, sizeof path, "%s/stage/lib/libphotonmap.so", pm_test_build_dir());
    n = readlink(path, link, sizeof link - 1);
    ASSERT_MSG(n > 0, "%s is not a symlink", path);
    link[n] = 0;
    snprintf(want, sizeof want, "libphotonmap.so.%d", PM_VERSION_MAJOR);
    EXPECT_MSG(strcmp(link, want) == 0, "libphotonmap.so -> %s, want %s", link, want);
    snprintf(path, sizeof path, "%s/stage/lib/libphotonmap.so.%d", pm_test_build_dir(), PM_VERSION_MAJOR);
    n = readlink(path, link, sizeof link - 1);
    ASSERT_MSG(n > 0, "%s is not a symlink", path);
    link[n] = 0;
    snprintf(want, sizeof want, "libphotonmap.so.%d.%d.%d", PM_VERSION_MAJOR, PM_VERSION_MINOR,
             PM_VERSION_PATCH);
    EXPECT_MSG(strcmp(link, want) == 0, "-> %s, want %s", link, want);
    snprintf(cmd, sizeof cmd, "readelf -d '%s'", path);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    snprintf(want, sizeof want, "Library soname: [libphotonmap.so.%d]", PM_VERSION_MAJOR);
    EXPECT_MSG(strstr(out, want) != NULL, "no %s in: %s", want, out);
    snprintf(want, sizeof want, "%d.%d.%d", PM_VERSION_MAJOR, PM_VERSION_MINOR, PM_VERSION_PATCH);
    EXPECT_MSG(strcmp(PM_VERSION_STRING, want) == 0, "PM_VERSION_STRING %s, macros %s", PM_VERSION_STRING, want);
}

/* Oracle: the symbol tables (nm). The shared library exports exactly the archive's global
 * pm_ names (the API, complete) and nothing else: no pm__ internal, no unprefixed name. */
TEST(packaging_shared_library_exports_only_the_api) {
    static char dyn[65536], stat_syms[65536];
    char cmd[2048];
    const char *lib = pm_test_build_dir();
    snprintf(cmd, sizeof cmd, "nm -D --defined-only '%s/stage/lib/libphotonmap.so.%d' | awk '{ print $3 }' | sort -u",
             lib, PM_VERSION_MAJOR);
    ASSERT_EQ_INT(pm_test_run(cmd, dyn, sizeof dyn), 0);
    snprintf(cmd, sizeof cmd,
             "nm -g --defined-only '%s/stage/lib/libphotonmap.a' | awk 'NF == 3 && $3 ~ /^pm_/ { print $3 }' | sort -u",
             lib);
    ASSERT_EQ_INT(pm_test_run(cmd, stat_syms, sizeof stat_syms), 0);
    int exported = 0, internal = 0;
    for (char *s = strtok(dyn, "\n"); s; s = strtok(NULL, "\n")) {
        exported++;
        EXPECT_MSG(strncmp(s, "pm_", 3) == 0 && strncmp(s, "pm__", 4) != 0, "exported: %s", s);
    }
    EXPECT_MSG(exported >= 20, "only %d symbols exported", exported);
    /* Every public name of the archive is exported; every internal one is not. */
    snprintf(cmd, sizeof cmd, "nm -D --defined-only '%s/stage/lib/libphotonmap.so.%d' | awk '{ print \" \" $3 \" \" }'",
             lib, PM_VERSION_MAJOR);
    static char dyn2[65536];
    ASSERT_EQ_INT(pm_test_run(cmd, dyn2, sizeof dyn2), 0);
    for (char *s = strtok(stat_syms, "\n"); s; s = strtok(NULL, "\n")) {
        char key[512];
        snprintf(key, sizeof key, " %s ", s);
        if (strncmp(s, "pm__", 4) == 0) {
            internal++;
            EXPECT_MSG(!strstr(dyn2, key), "internal %s is exported", s);
        } else {
            EXPECT_MSG(strstr(dyn2, key) != NULL, "public %s is not exported", s);
        }
    }
    printf("    %d exported, %d pm__ internals kept local\n", exported, internal);
}

/* Oracle: the pkg-config documentation. Version is PM_VERSION_STRING; a shared link needs only
 * -lphotonmap (no -fopenmp in Libs); a static link also gets libm and, in an OpenMP build
 * (this test is compiled with the library's flags, so _OPENMP says which), the OpenMP runtime
 * from Libs.private. The installed headers compile alone and leave out the internal ones. */
TEST(packaging_pkg_config_and_headers) {
    char cmd[4096], out[4096];
    const char *b = pm_test_build_dir();
    snprintf(cmd, sizeof cmd, "PKG_CONFIG_PATH='%s/stage/lib/pkgconfig' pkg-config --modversion photonmap", b);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    out[strcspn(out, "\n")] = 0;
    EXPECT_MSG(strcmp(out, PM_VERSION_STRING) == 0, "pc version %s, header %s", out, PM_VERSION_STRING);
    snprintf(cmd, sizeof cmd, "PKG_CONFIG_PATH='%s/stage/lib/pkgconfig' pkg-config --libs photonmap", b);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "-lphotonmap") && !strstr(out, "-fopenmp") && !strstr(out, "-lgomp") &&
                   !strstr(out, "-lomp"), "Libs: %s", out);
    snprintf(cmd, sizeof cmd, "PKG_CONFIG_PATH='%s/stage/lib/pkgconfig' pkg-config --static --libs photonmap", b);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "-lphotonmap") && strstr(out, "-lm"), "static Libs: %s", out);
#ifdef _OPENMP
    EXPECT_MSG(strstr(out, "-lgomp") || strstr(out, "-lomp"), "static Libs lack the OpenMP runtime: %s", out);
#else
    EXPECT_MSG(!strstr(out, "-lgomp") && !strstr(out, "-lomp") && !strstr(out, "-fopenmp"),
               "OpenMP runtime in a build without OpenMP: %s", out);
#endif
    snprintf(cmd, sizeof cmd, "ls '%s/stage/include/photonmap'", b);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "photonmap.h") && !strstr(out, "internal"), "installed headers: %s", out);
    /* Each installed header on its own, as C11 with every warning an error. */
    snprintf(cmd, sizeof cmd,
             "cd '%s' && for h in '%s'/stage/include/photonmap/*.h; do printf '#include <photonmap/%%s>\\n' "
             "\"$(basename \"$h\")\" > t.c && cc -std=c11 -Wall -Wextra -Wpedantic -Werror -I'%s/stage/include' "
             "-c t.c -o t.o || exit 1; done",
             pm_test_tmpdir(), b, b);
    EXPECT_MSG(pm_test_run(cmd, out, sizeof out) == 0, "%s", out);
}

/* Oracle: the documented install. `make install` puts the renderer in PREFIX/bin, and the
 * installed program runs (--help exits 0 with its usage). */
TEST(packaging_install_has_render) {
    char cmd[2048], out[8192];
    snprintf(cmd, sizeof cmd, "'%s/stage/bin/render' --help", pm_test_build_dir());
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "usage") || strstr(out, "Usage"), "%s", out);
}
