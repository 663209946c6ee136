/* test_build.c: what the Makefile promises about rebuilding and about installing packages.
 *
 * Each test runs make on this checkout with a BUILD directory inside its own temporary
 * directory (and MAKEFLAGS cleared, so the flags of the `make test` that runs the suite do not
 * leak in), building only the library at -O0 to stay quick.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "test.h"

/* Run `make ARGS` on the checkout with BUILD=<tmp>/b and the default flags (stated on the
 * command line: a `make OPENMP=0 test` or `make MPI=1 test` exports its variables to the
 * tests); later ARGS override them. Returns make's exit status. */
static int make_in_tmp(const char *args, char *out, size_t cap) {
    char cmd[16384];
    snprintf(cmd, sizeof cmd,
             "env -u MAKEFLAGS -u MFLAGS -u MAKELEVEL -u MAKEOVERRIDES make -C '%s' "
             "--no-print-directory BUILD='%s/b' OPT=-O0 CC=cc CXX=c++ OPENMP=1 SIMD= SANITIZE= MPI=0 "
             "CFLAGS= LDFLAGS= %s",
             pm_test_source_dir(), pm_test_tmpdir(), args);
    return pm_test_run(cmd, out, cap);
}

static int count(const char *hay, const char *needle) {
    int n = 0;
    for (const char *p = hay; (p = strstr(p, needle)) != NULL; p += strlen(needle)) n++;
    return n;
}

/* Oracle: make's own answer. `make -q` exits 0 when nothing needs rebuilding and 1 otherwise;
 * `make -n` prints the commands a run would execute. After a build, the same flags rebuild
 * nothing and leave the flags stamp alone; OPENMP=0, SIMD=avx2 and a different CC each
 * recompile every library source (both the static and the position-independent object);
 * after building with OPENMP=0, the default flags are out of date again. */
TEST(build_tracks_flags) {
    static char out[65536];
    char stamp[2048];
    struct stat st1, st2;
    int nsrc = 0;
    {
        char cmd[2048];
        snprintf(cmd, sizeof cmd, "ls '%s'/photonmap/*.c | wc -l", pm_test_source_dir());
        ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
        nsrc = atoi(out);
    }
    ASSERT(nsrc > 0);
    ASSERT_MSG(make_in_tmp("-j2 lib", out, sizeof out) == 0, "%s", out);
    snprintf(stamp, sizeof stamp, "%s/b/flags.stamp", pm_test_tmpdir());
    ASSERT(stat(stamp, &st1) == 0);

    EXPECT_MSG(make_in_tmp("-q lib", out, sizeof out) == 0, "same flags, yet out of date: %s", out);
    EXPECT_MSG(make_in_tmp("lib", out, sizeof out) == 0 && count(out, " -c ") == 0,
               "an identical make rebuilt: %s", out);
    ASSERT(stat(stamp, &st2) == 0);
    EXPECT(st1.st_mtim.tv_sec == st2.st_mtim.tv_sec && st1.st_mtim.tv_nsec == st2.st_mtim.tv_nsec);

    EXPECT_EQ_INT(make_in_tmp("-q lib OPENMP=0", out, sizeof out), 1);
    EXPECT_EQ_INT(make_in_tmp("-n lib OPENMP=0", out, sizeof out), 0);
    EXPECT_EQ_INT(count(out, " -c photonmap/"), 2 * nsrc);
    EXPECT_MSG(!strstr(out, "-fopenmp"), "OPENMP=0 still compiles with OpenMP: %s", out);
    EXPECT_EQ_INT(make_in_tmp("-n lib SIMD=avx2", out, sizeof out), 0);
    EXPECT_EQ_INT(count(out, "-mavx2"), 2 * nsrc);
    EXPECT_EQ_INT(make_in_tmp("-q lib CC=gcc", out, sizeof out), 1);
    /* The dry runs above changed nothing. */
    EXPECT_MSG(make_in_tmp("-q lib", out, sizeof out) == 0, "a dry run touched the stamp: %s", out);

    ASSERT_MSG(make_in_tmp("-j2 lib OPENMP=0", out, sizeof out) == 0, "%s", out);
    EXPECT_EQ_INT(count(out, " -c photonmap/"), 2 * nsrc);
    EXPECT_EQ_INT(make_in_tmp("-q lib OPENMP=0", out, sizeof out), 0);
    EXPECT_EQ_INT(make_in_tmp("-q lib", out, sizeof out), 1);
}

/* Oracle: the commands make would run (make -n). Building the library, `all` and installing
 * never reach scripts/install-deps.sh (so never apt-get); `make test`, `run` and `deps` do.
 * The second half shows that the first half can fail. */
TEST(build_library_and_install_never_call_apt) {
    static char out[262144];
    char args[4096];
    snprintf(args, sizeof args, "-n lib all install PREFIX='%s/p'", pm_test_tmpdir());
    ASSERT_MSG(make_in_tmp(args, out, sizeof out) == 0, "%s", out);
    EXPECT_MSG(!strstr(out, "install-deps") && !strstr(out, "apt-get"), "%s", out);
    EXPECT(strstr(out, "libphotonmap.so") != NULL);
    ASSERT_MSG(make_in_tmp("-n deps", out, sizeof out) == 0, "%s", out);
    EXPECT_MSG(strstr(out, "install-deps.sh") != NULL, "%s", out);
    ASSERT_MSG(make_in_tmp("-n run", out, sizeof out) == 0, "%s", out);
    EXPECT_MSG(strstr(out, "install-deps.sh") != NULL, "%s", out);
}
