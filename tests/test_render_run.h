/* test_render_run.h: running the render program from the output and checkpoint tests.
 *
 * Every command runs in the test's own directory (pm_test_tmpdir()), background jobs
 * included, so outputs never land anywhere else. rt_render_paused uses the render program's
 * test-only hook PM_RENDER_TEST_PAUSE=PHASE (render/base/output.h): it starts the program, waits
 * until it says "test pause at", runs a shell snippet (e.g. copy a snapshot), sends the
 * signal and returns the exit status as the shell reports it (128 + signal when killed).
 * Static inline helpers, so a file that uses some of them has no unused-function warnings.
 */
#ifndef TEST_RENDER_RUN_H
#define TEST_RENDER_RUN_H

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"

/* name inside the test directory (a few calls may be live at once) */
static inline char *rt_path(const char *name) {
    static char buf[8][1024];
    static int k;
    char *p = buf[k++ % 8];
    snprintf(p, 1024, "%s/%s", pm_test_tmpdir(), name);
    return p;
}

/* The whole file, NUL-terminated; *n its length. NULL if unreadable. */
static inline char *rt_slurp(const char *path, size_t *n) {
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    size_t cap = 1 << 16, len = 0, got;
    char *b = malloc(cap + 1);
    while (b && (got = fread(b + len, 1, cap - len, f)) > 0) {
        len += got;
        if (len == cap) {
            char *nb = realloc(b, 2 * cap + 1);
            if (!nb) {
                free(b);
                b = NULL;
                break;
            }
            b = nb;
            cap *= 2;
        }
    }
    fclose(f);
    if (b) b[len] = 0;
    if (n) *n = len;
    return b;
}

/* Whether two files (paths, or names in the test directory) hold the same bytes. */
static inline int rt_same_file(const char *a, const char *b) {
    char pa[1024], pb[1024];
    snprintf(pa, sizeof pa, "%s", a[0] == '/' ? a : rt_path(a));
    snprintf(pb, sizeof pb, "%s", b[0] == '/' ? b : rt_path(b));
    size_t na = 0, nb = 0;
    char *x = rt_slurp(pa, &na), *y = rt_slurp(pb, &nb);
    int same = x && y && na == nb && memcmp(x, y, na) == 0;
    free(x);
    free(y);
    return same;
}

/* Names in the test directory that contain ".tmp" (leftover temporaries). */
static inline int rt_count_temps(void) {
    DIR *d = opendir(pm_test_tmpdir());
    if (!d) return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)))
        if (strstr(e->d_name, ".tmp")) n++;
    closedir(d);
    return n;
}

/* A shell command line run in the test directory. */
static inline int rt_run(const char *cmdline, char *out, size_t cap) {
    char cmd[16384];
    snprintf(cmd, sizeof cmd, "cd '%s' || exit 9; %s", pm_test_tmpdir(), cmdline);
    return pm_test_run(cmd, out, cap);
}

/* render SCENE ARGS, where scene_fmt has one %s for the source directory. */
static inline int rt_render(const char *scene_fmt, const char *args, char *out, size_t cap) {
    char sc[2048], cmd[8192];
    snprintf(sc, sizeof sc, scene_fmt, pm_test_source_dir());
    snprintf(cmd, sizeof cmd, "timeout 60 '%s/render' %s %s", pm_test_build_dir(), sc, args);
    return rt_run(cmd, out, cap);
}

/* render paused at phase, then while_paused (shell, may be ""), then signal sig (INT, TERM,
 * KILL). The shell's status of the program, or -1. out gets its messages. */
static inline int rt_render_paused(const char *phase, const char *sig, const char *scene_fmt,
                                   const char *args, const char *while_paused, char *out, size_t cap) {
    char sc[2048], cmd[8192];
    snprintf(sc, sizeof sc, scene_fmt, pm_test_source_dir());
    snprintf(cmd, sizeof cmd,
             "PM_RENDER_TEST_PAUSE=%s '%s/render' %s %s >log.txt 2>&1 & pid=$!; i=0; "
             "while ! grep -q 'test pause at' log.txt 2>/dev/null; do i=$((i+1)); "
             "[ $i -gt 1200 ] && break; sleep 0.05; done; %s%s kill -%s $pid; wait $pid; "
             "echo \"exit=$?\"; cat log.txt; rm -f log.txt",
             phase, pm_test_build_dir(), sc, args, while_paused, while_paused[0] ? ";" : "", sig);
    if (rt_run(cmd, out, cap) != 0) return -1;
    const char *e = strstr(out, "exit=");
    return e ? atoi(e + 5) : -1;
}

/* A 10-unit box's floor, ceiling, back (z = 10), left and right walls (material "white") and a
 * 2 x 2 lamp quad just under the ceiling (material "lamp"), facing in: JSON objects separated by
 * commas, for a scene's "objects" array; the front wall (z = 0) is the caller's (open or closed). */
#define TEST_BOX10_QUADS \
    "{\"type\": \"quad\", \"vertices\": [[10, 0, 0], [0, 0, 0], [0, 0, 10], [10, 0, 10]], \"material\": \"white\"}," \
    "{\"type\": \"quad\", \"vertices\": [[10, 10, 0], [10, 10, 10], [0, 10, 10], [0, 10, 0]], \"material\": " \
    "\"white\"}," \
    "{\"type\": \"quad\", \"vertices\": [[10, 0, 10], [0, 0, 10], [0, 10, 10], [10, 10, 10]], \"material\": " \
    "\"white\"}," \
    "{\"type\": \"quad\", \"vertices\": [[0, 0, 10], [0, 0, 0], [0, 10, 0], [0, 10, 10]], \"material\": \"white\"}," \
    "{\"type\": \"quad\", \"vertices\": [[10, 0, 0], [10, 0, 10], [10, 10, 10], [10, 10, 0]], \"material\": " \
    "\"white\"}," \
    "{\"type\": \"quad\", \"vertices\": [[6, 9.99, 4], [6, 9.99, 6], [4, 9.99, 6], [4, 9.99, 4]], \"material\": " \
    "\"lamp\"}"

#endif /* TEST_RENDER_RUN_H */
