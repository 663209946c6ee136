/* runner.c: runs every registered test, each in its own forked child.
 *
 * Usage: run_tests [--list] [-j N] [-x PATTERN]... [--times FILE [--quick]] [PATTERN...]
 *   PATTERN selects tests whose name or file contains it (any pattern matches); -x PATTERN
 *   leaves out those whose name or file contains it (`make check` uses it for slow tests).
 *   --times FILE reads and rewrites FILE, one "name cpu_seconds wall_seconds" line per test
 *   as last measured (CPU time of the test's process and everything it ran). With --quick,
 *   the tests that FILE says took more than QUICK_CPU CPU-seconds or QUICK_WALL seconds are
 *   left out and named (`make check`: the full `make test` records the times).
 *   -j N runs N tests at once (default: PM_TEST_JOBS, else 2). Each child's output is
 *   captured and printed whole when it ends, so parallel output does not interleave.
 *   PM_TEST_TIMEOUT (seconds, default 300) kills a test that runs too long.
 * FIXTURE bodies (test.h) are left out, unlisted and uncounted, unless PM_TEST_INNER is set.
 * A test that cannot run here (a missing tool) calls SKIP("reason"): its child exits with
 * PM_TEST_SKIP_STATUS, and it is neither passed nor failed. The skipped tests are listed with
 * their reasons before the last line, "N passed, N failed, N skipped"; the exit status is 1
 * if any test failed.
 */
#define _GNU_SOURCE
#include "test.h"

#include <errno.h>
#include <grp.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

typedef struct {
    const char *name, *file;
    pm_test_fn fn;
    int timed;          /* cpu and wall hold a measurement (read from --times or just made) */
    int fixture;        /* FIXTURE: run only when PM_TEST_INNER is set */
    double cpu, wall;
} test_entry;

/* --quick leaves out what took longer than this in the last recorded run. */
#define QUICK_CPU 0.5
#define QUICK_WALL 3.0

static test_entry *g_tests;
static int g_ntests, g_cap;
static int g_failures;       /* in the child: failures of the running test */
static int g_skipped;        /* in the child: the running test called SKIP */
static char g_tmpdir[512];

static void add_entry(const char *name, const char *file, pm_test_fn fn, int fixture) {
    if (g_ntests == g_cap) {
        g_cap = g_cap ? 2 * g_cap : 64;
        g_tests = realloc(g_tests, (size_t)g_cap * sizeof *g_tests);
        if (!g_tests) abort();
    }
    g_tests[g_ntests++] = (test_entry){.name = name, .file = file, .fn = fn, .fixture = fixture};
}

void pm_test_register(const char *name, const char *file, pm_test_fn fn) { add_entry(name, file, fn, 0); }

void pm_test_register_fixture(const char *name, const char *file, pm_test_fn fn) {
    add_entry(name, file, fn, 1);
}

void pm_test_fail(const char *file, int line, const char *fmt, ...) {
    va_list ap;
    g_failures++;
    if (g_failures > 20) return; /* one broken loop should not flood the log */
    fprintf(stdout, "    %s:%d: ", file, line);
    va_start(ap, fmt);
    vfprintf(stdout, fmt, ap);
    va_end(ap);
    fputc('\n', stdout);
    fflush(stdout);
}

int pm_test_failed(void) { return g_failures; }

/* The reason goes to the test's log behind a fixed marker, where the parent finds it for the
 * list of skipped tests. */
#define SKIP_MARKER "    skipped: "
void pm_test_skip(const char *reason) {
    g_skipped = 1;
    printf(SKIP_MARKER "%s\n", reason);
    fflush(stdout);
}

const char *pm_test_build_dir(void) {
    const char *d = getenv("PM_BUILD_DIR");
    return d && *d ? d : "build/release";
}

const char *pm_test_source_dir(void) {
    const char *d = getenv("PM_SOURCE_DIR");
    return d && *d ? d : ".";
}

const char *pm_test_tmpdir(void) {
    if (!g_tmpdir[0]) {
        const char *base = getenv("TMPDIR");
        snprintf(g_tmpdir, sizeof g_tmpdir, "%s/pmtest.XXXXXX", base && *base ? base : "/tmp");
        if (!mkdtemp(g_tmpdir)) {
            perror("mkdtemp");
            abort();
        }
    }
    return g_tmpdir;
}

int pm_test_run(const char *cmd, char *buf, size_t cap) {
    FILE *p;
    size_t len = 0;
    int status;
    char *full = malloc(strlen(cmd) + 16);
    if (!full) return -1;
    sprintf(full, "(%s) 2>&1", cmd);
    fflush(NULL);
    p = popen(full, "r");
    free(full);
    if (!p) return -1;
    if (buf && cap) {
        size_t got;
        while (len + 1 < cap && (got = fread(buf + len, 1, cap - 1 - len, p)) > 0) len += got;
        buf[len] = 0;
    }
    {   /* drain whatever did not fit */
        char sink[4096];
        while (fread(sink, 1, sizeof sink, p) > 0) {}
    }
    status = pclose(p);
    if (status == -1 || !WIFEXITED(status)) return -1;
    return WEXITSTATUS(status);
}

int pm_test_unprivileged(void (*fn)(void *), void *arg, char *why, size_t cap) {
    int status;
    pid_t pid;
    fflush(NULL);
    if ((pid = fork()) < 0) {
        snprintf(why, cap, "fork: %s", strerror(errno));
        return -1;
    }
    if (pid == 0) {
        if (geteuid() == 0 && (setgroups(0, NULL) != 0 || setgid(PM_TEST_NOBODY) != 0 ||
                               setuid(PM_TEST_NOBODY) != 0))
            _exit(PM_TEST_SKIP_STATUS);
        g_failures = 0;
        fn(arg);
        fflush(NULL);
        _exit(g_failures > 100 ? 100 : g_failures);
    }
    if (waitpid(pid, &status, 0) != pid || !WIFEXITED(status)) {
        snprintf(why, cap, "the unprivileged child did not exit normally");
        g_failures++;
        return 1;
    }
    if (WEXITSTATUS(status) == PM_TEST_SKIP_STATUS) {
        snprintf(why, cap, "running as root and cannot drop to uid %d (setuid: not permitted here)",
                 PM_TEST_NOBODY);
        return -1;
    }
    g_failures += WEXITSTATUS(status);
    return WEXITSTATUS(status);
}

const char *pm_test_unprivileged_prefix(char *why, size_t cap) {
    static const char prefix[] = "setpriv --reuid=65534 --regid=65534 --clear-groups ";
    char cmd[256];
    if (geteuid() != 0) return "";
    snprintf(cmd, sizeof cmd, "%s sh -c 'test \"$(id -u)\" = 65534'", prefix);
    if (pm_test_run(cmd, NULL, 0) != 0) {
        snprintf(why, cap, "running as root and setpriv cannot drop to uid %d here", PM_TEST_NOBODY);
        return NULL;
    }
    return prefix;
}

static double now_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Child side: run one test with stdout/stderr going to fd `out`. */
static void run_child(const test_entry *t, int out, unsigned timeout) {
    dup2(out, 1);
    dup2(out, 2);
    close(out);
    setvbuf(stdout, NULL, _IOLBF, 0);
    alarm(timeout);
    t->fn();
    fflush(NULL);
    if (g_tmpdir[0] && !g_failures) {
        char cmd[600];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", g_tmpdir);
        if (system(cmd) != 0) {}
    } else if (g_tmpdir[0]) {
        printf("    (scratch kept in %s)\n", g_tmpdir);
    }
    _exit(g_failures ? 1 : g_skipped ? PM_TEST_SKIP_STATUS : 0);
}

typedef struct {
    pid_t pid;
    int idx;
    FILE *log;
    double t0;
} running;

static int matches(const test_entry *t, int npat, char **pat) {
    for (int i = 0; i < npat; i++)
        if (strstr(t->name, pat[i]) || strstr(t->file, pat[i])) return 1;
    return 0;
}

/* Fixtures (FIXTURE) run only inside the runner's own tests, which set PM_TEST_INNER. */
static int selected(const test_entry *t, int npat, char **pat, int nexcl, char **excl) {
    static int inner = -1;
    if (inner < 0) inner = getenv("PM_TEST_INNER") != NULL;
    if (t->fixture && !inner) return 0;
    return (npat == 0 || matches(t, npat, pat)) && !matches(t, nexcl, excl);
}

/* The reason a skipped test printed after SKIP_MARKER, or "" (into buf of cap bytes). */
static void skip_reason(FILE *log, char *buf, size_t cap) {
    char line[1024];
    buf[0] = 0;
    rewind(log);
    while (fgets(line, sizeof line, log))
        if (!strncmp(line, SKIP_MARKER, strlen(SKIP_MARKER))) {
            const char *r = line + strlen(SKIP_MARKER);
            size_t n = strcspn(r, "\n");
            if (n >= cap) n = cap - 1;
            memcpy(buf, r, n);
            buf[n] = 0;
            return;
        }
}

static void read_times(const char *path) {
    FILE *f = fopen(path, "r");
    char name[256];
    double cpu, wall;
    if (!f) return; /* no record yet: nothing is known to be slow */
    while (fscanf(f, "%255s %lf %lf", name, &cpu, &wall) == 3)
        for (int i = 0; i < g_ntests; i++)
            if (!strcmp(g_tests[i].name, name)) {
                g_tests[i].timed = 1;
                g_tests[i].cpu = cpu;
                g_tests[i].wall = wall;
            }
    fclose(f);
}

/* Whole or not at all: a temporary beside it, renamed over it. */
static void write_times(const char *path) {
    char tmp[4096];
    FILE *f;
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    if (!(f = fopen(tmp, "w"))) { perror(tmp); return; }
    for (int i = 0; i < g_ntests; i++)
        if (g_tests[i].timed) fprintf(f, "%s %.3f %.3f\n", g_tests[i].name, g_tests[i].cpu, g_tests[i].wall);
    if (fclose(f) != 0 || rename(tmp, path) != 0) perror(path);
}

static int too_slow(const test_entry *t) {
    return t->timed && (t->cpu > QUICK_CPU || t->wall > QUICK_WALL);
}

int main(int argc, char **argv) {
    int jobs = 2, npat = 0, nexcl = 0, list = 0, passed = 0, failed = 0, skipped = 0;
    char **pat = calloc((size_t)argc, sizeof *pat), **excl = calloc((size_t)argc, sizeof *excl);
    char *skips = NULL; /* "name (reason)\n" of each skipped test */
    size_t skips_len = 0;
    const char *env;
    unsigned timeout = 300;
    running *run;
    int nrun = 0, next = 0, quick = 0, nslow = 0;
    const char *times = NULL;

    if ((env = getenv("PM_TEST_JOBS")) && atoi(env) > 0) jobs = atoi(env);
    if ((env = getenv("PM_TEST_TIMEOUT")) && atoi(env) > 0) timeout = (unsigned)atoi(env);
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--list")) list = 1;
        else if (!strcmp(argv[i], "-j") && i + 1 < argc) jobs = atoi(argv[++i]);
        else if (!strcmp(argv[i], "-x") && i + 1 < argc) excl[nexcl++] = argv[++i];
        else if (!strcmp(argv[i], "--times") && i + 1 < argc) times = argv[++i];
        else if (!strcmp(argv[i], "--quick")) quick = 1;
        else if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            printf("usage: %s [--list] [-j N] [-x PATTERN]... [--times FILE [--quick]] [PATTERN...]\n",
                   argv[0]);
            return 0;
        } else pat[npat++] = argv[i];
    }
    if (jobs < 1) jobs = 1;
    if (times) read_times(times);
    if (list) {
        for (int i = 0; i < g_ntests; i++)
            if (selected(&g_tests[i], npat, pat, nexcl, excl)) printf("%s  (%s)\n", g_tests[i].name, g_tests[i].file);
        return 0;
    }
    run = calloc((size_t)jobs, sizeof *run);
    signal(SIGPIPE, SIG_IGN);
    while (next < g_ntests || nrun > 0) {
        while (nrun < jobs && next < g_ntests) {
            int i = next++;
            FILE *log;
            pid_t pid;
            if (!selected(&g_tests[i], npat, pat, nexcl, excl)) continue;
            if (quick && too_slow(&g_tests[i])) {
                if (nslow++ == 0) printf("left out as slow in the last recorded run (%s):\n", times);
                printf("  %s (%.1f CPU-s, %.1f s)\n", g_tests[i].name, g_tests[i].cpu, g_tests[i].wall);
                continue;
            }
            log = tmpfile();
            if (!log) { perror("tmpfile"); return 2; }
            fflush(NULL);
            pid = fork();
            if (pid < 0) { perror("fork"); return 2; }
            if (pid == 0) run_child(&g_tests[i], fileno(log), timeout);
            run[nrun++] = (running){pid, i, log, now_s()};
        }
        if (nrun == 0) break;
        {
            int status, k;
            struct rusage ru;
            pid_t pid = wait4(-1, &status, 0, &ru);
            char buf[4096];
            size_t got;
            const test_entry *t;
            int ok, skip;
            if (pid < 0) {
                if (errno == EINTR) continue;
                perror("wait");
                return 2;
            }
            for (k = 0; k < nrun && run[k].pid != pid; k++) {}
            if (k == nrun) continue;
            t = &g_tests[run[k].idx];
            ok = WIFEXITED(status) && WEXITSTATUS(status) == 0;
            skip = WIFEXITED(status) && WEXITSTATUS(status) == PM_TEST_SKIP_STATUS;
            g_tests[run[k].idx].timed = 1;
            g_tests[run[k].idx].wall = now_s() - run[k].t0;
            g_tests[run[k].idx].cpu = (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec +
                                      (double)ru.ru_stime.tv_sec + 1e-6 * (double)ru.ru_stime.tv_usec;
            printf("%s %s (%.2fs)\n", ok ? "PASS" : skip ? "SKIP" : "FAIL", t->name,
                   g_tests[run[k].idx].wall);
            rewind(run[k].log);
            while ((got = fread(buf, 1, sizeof buf, run[k].log)) > 0) fwrite(buf, 1, got, stdout);
            if (WIFSIGNALED(status))
                printf("    killed by signal %d%s\n", WTERMSIG(status),
                       WTERMSIG(status) == SIGALRM ? " (time limit; PM_TEST_TIMEOUT)" : "");
            fflush(stdout);
            if (skip) {
                char reason[512], *grown;
                skip_reason(run[k].log, reason, sizeof reason);
                size_t add = strlen(t->name) + strlen(reason) + 8;
                if (!(grown = realloc(skips, skips_len + add + 1))) abort();
                skips = grown;
                skips_len += (size_t)sprintf(skips + skips_len, "  %s (%s)\n", t->name, reason);
            }
            fclose(run[k].log);
            if (ok) passed++;
            else if (skip) skipped++;
            else failed++;
            run[k] = run[--nrun];
        }
    }
    if (times) write_times(times);
    if (skipped) printf("skipped:\n%s", skips);
    printf("%d passed, %d failed, %d skipped\n", passed, failed, skipped);
    free(skips);
    free(run);
    free(pat);
    free(excl);
    return failed ? 1 : 0;
}
