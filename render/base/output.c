/* output.c: safe output files and the SIGINT/SIGTERM clean-up; see output.h.
 *
 * Why a registry instead of atexit or a list on the heap: the handler may run at any
 * instruction, on any thread (OpenMP workers do not block signals), so it may only read
 * memory that is always consistent and call async-signal-safe functions (unlink, signal,
 * raise). Each slot's path is written completely before its "used" flag is set with a
 * sequentially consistent atomic store, and the handler reads the flag first.
 *
 * Deferral is a depth counter plus the recorded signal, both lock-free atomics (which are
 * async-signal-safe). Temporaries are created and registered inside a deferred section, so
 * there is no window in which a signal could leave one behind unregistered.
 */
#define _XOPEN_SOURCE 700 /* realpath */
#include "base/output.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "common.h"

/* ---- signal registry ---------------------------------------------------------------------- */

enum { REG_SLOTS = 32 };
static char g_reg[REG_SLOTS][OUT_PATH_MAX];
static _Atomic int g_used[REG_SLOTS];
static _Atomic int g_defer, g_pending;

static void remove_temps(void) {
    for (int i = 0; i < REG_SLOTS; i++)
        if (atomic_load(&g_used[i])) unlink(g_reg[i]);
}

static void on_signal(int sig) {
    int saved = errno;
    int none = 0;
    if (atomic_load(&g_defer) > 0 && atomic_compare_exchange_strong(&g_pending, &none, sig)) {
        errno = saved;
        return;
    }
    remove_temps();
    signal(sig, SIG_DFL);
    raise(sig); /* delivered when the handler returns: the program ends by this signal */
}

void out_signals_install(void) {
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = on_signal;
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
}

void out_defer_begin(void) { atomic_fetch_add(&g_defer, 1); }
void out_defer_end(void) { atomic_fetch_sub(&g_defer, 1); }
int out_pending_signal(void) { return atomic_load(&g_pending); }

void out_die_if_pending(void) {
    int sig = atomic_load(&g_pending);
    if (!sig || atomic_load(&g_defer) > 0) return;
    remove_temps();
    signal(sig, SIG_DFL);
    raise(sig);
}

static int reg_add(const char *path) {
    for (int i = 0; i < REG_SLOTS; i++)
        if (!atomic_load(&g_used[i])) {
            snprintf(g_reg[i], OUT_PATH_MAX, "%s", path);
            atomic_store(&g_used[i], 1);
            return i;
        }
    return -1;
}

static void reg_drop(int slot) {
    if (slot >= 0) atomic_store(&g_used[slot], 0);
}

/* ---- what a path is ----------------------------------------------------------------------- */

enum { K_NEW, K_REGULAR, K_THROUGH, K_REFUSE };

/* Classify path and fill target (where the bytes go); for K_REFUSE, why says why. */
static int classify(const char *path, char *target, char *why, size_t whycap) {
    struct stat st;
    snprintf(target, OUT_PATH_MAX, "%s", path);
    if (!*path) {
        snprintf(why, whycap, "empty path");
        return K_REFUSE;
    }
    if (lstat(path, &st) != 0) {
        if (errno == ENOENT) return K_NEW;
        snprintf(why, whycap, "%s", strerror(errno));
        return K_REFUSE;
    }
    if (S_ISLNK(st.st_mode)) {
        char *rp = realpath(path, NULL);
        if (!rp) {
            snprintf(why, whycap, "a symbolic link whose target cannot be followed (%s); not written",
                     strerror(errno));
            return K_REFUSE;
        }
        int fits = strlen(rp) < OUT_PATH_MAX;
        if (fits) snprintf(target, OUT_PATH_MAX, "%s", rp);
        free(rp);
        if (!fits || stat(target, &st) != 0) {
            snprintf(why, whycap, "a symbolic link whose target cannot be followed; not written");
            return K_REFUSE;
        }
    }
    if (S_ISREG(st.st_mode)) return K_REGULAR;
    if (S_ISFIFO(st.st_mode) || S_ISCHR(st.st_mode)) return K_THROUGH;
    snprintf(why, whycap, "cannot write there: %s; only a regular file (replaced), a FIFO or a "
             "character device (written through) can be an output",
             S_ISDIR(st.st_mode) ? "Is a directory" : S_ISBLK(st.st_mode) ? "a block device" : "a socket");
    return K_REFUSE;
}

/* A registered temporary beside target, mode 0666 less the umask. fd or -1 (errno set). */
static int make_tmp(const char *target, char *tmp, int *slot) {
    *slot = -1;
    if ((size_t)snprintf(tmp, OUT_PATH_MAX, "%s.tmpXXXXXX", target) >= OUT_PATH_MAX) {
        errno = ENAMETOOLONG;
        return -1;
    }
    out_defer_begin(); /* mkstemp and registration as one step for the handler */
    int fd = mkstemp(tmp);
    if (fd >= 0) *slot = reg_add(tmp);
    out_defer_end();
    if (fd < 0) {
        out_die_if_pending();
        return -1;
    }
    /* Reading the umask means setting it back; outputs are opened on one thread. */
    mode_t mask = umask(022);
    umask(mask);
    if (*slot < 0 || fchmod(fd, 0666 & ~mask) != 0) {
        int saved = *slot < 0 ? EMFILE : errno;
        close(fd);
        unlink(tmp);
        reg_drop(*slot);
        *slot = -1;
        errno = saved;
        out_die_if_pending();
        return -1;
    }
    out_die_if_pending();
    return fd;
}

int out_check(const char *path, char *err, size_t errcap) {
    char target[OUT_PATH_MAX], tmp[OUT_PATH_MAX], why[256];
    int k = classify(path, target, why, sizeof why);
    if (k == K_REFUSE) {
        snprintf(err, errcap, "%s: %s", path, why);
        return PM_EIO;
    }
    if (k == K_THROUGH) {
        if (access(target, W_OK) == 0) return 0;
        snprintf(err, errcap, "%s: cannot write there: %s", path, strerror(errno));
        return PM_EIO;
    }
    int slot, fd = make_tmp(target, tmp, &slot);
    if (fd < 0) {
        snprintf(err, errcap, "%s: cannot write there: %s", path, strerror(errno));
        return PM_EIO;
    }
    close(fd);
    unlink(tmp);
    reg_drop(slot);
    return 0;
}

int out_check_dir(const char *dir, char *err, size_t errcap) {
    struct stat st;
    if (!*dir) {
        snprintf(err, errcap, "empty directory name");
        return PM_EIO;
    }
    if (stat(dir, &st) == 0) {
        if (!S_ISDIR(st.st_mode)) {
            snprintf(err, errcap, "%s: not a directory", dir);
            return PM_EIO;
        }
        if (access(dir, W_OK | X_OK) != 0) {
            snprintf(err, errcap, "%s: cannot write there: %s", dir, strerror(errno));
            return PM_EIO;
        }
        return 0;
    }
    if (errno != ENOENT) {
        snprintf(err, errcap, "%s: %s", dir, strerror(errno));
        return PM_EIO;
    }
    /* Absent: it will be created, so its parent must be a writable directory. */
    char parent[OUT_PATH_MAX];
    snprintf(parent, sizeof parent, "%s", dir);
    size_t n = strlen(parent);
    while (n > 1 && parent[n - 1] == '/') parent[--n] = 0;
    char *slash = strrchr(parent, '/');
    if (!slash)
        snprintf(parent, sizeof parent, ".");
    else if (slash == parent)
        parent[1] = 0;
    else
        *slash = 0;
    if (stat(parent, &st) != 0 || !S_ISDIR(st.st_mode) || access(parent, W_OK | X_OK) != 0) {
        snprintf(err, errcap, "%s: cannot be created: %s", dir,
                 errno ? strerror(errno) : "the parent is not a directory");
        return PM_EIO;
    }
    return 0;
}

int out_open(out_file *o, const char *path, char *err, size_t errcap) {
    memset(o, 0, sizeof *o);
    o->slot = -1;
    char why[256];
    snprintf(o->path, sizeof o->path, "%s", path);
    int k = classify(path, o->target, why, sizeof why);
    if (k == K_REFUSE) {
        snprintf(err, errcap, "%s: %s", path, why);
        return PM_EIO;
    }
    if (k == K_THROUGH) {
        o->through = 1;
        o->fp = open_memstream(&o->mem, &o->memlen);
        if (!o->fp) {
            snprintf(err, errcap, "%s: out of memory", path);
            return PM_ENOMEM;
        }
        return 0;
    }
    int fd = make_tmp(o->target, o->tmp, &o->slot);
    if (fd < 0 || !(o->fp = fdopen(fd, "wb"))) {
        snprintf(err, errcap, "%s: cannot write there: %s", path, strerror(errno));
        if (fd >= 0) {
            close(fd);
            out_abort(o);
        }
        o->tmp[0] = 0;
        return PM_EIO;
    }
    return 0;
}

void out_abort(out_file *o) {
    if (o->fp) fclose(o->fp);
    o->fp = NULL;
    if (o->tmp[0]) {
        unlink(o->tmp);
        reg_drop(o->slot);
        o->slot = -1;
        o->tmp[0] = 0;
    }
    free(o->mem);
    o->mem = NULL;
    o->memlen = 0;
}

/* Write the in-memory bytes through the FIFO or device at o->target. 0 or -1 (errno). */
static int write_through(const out_file *o) {
    int fd = open(o->target, O_WRONLY | O_NOCTTY);
    if (fd < 0) return -1;
    struct stat st;
    /* The node may have been swapped for something else since out_open: write only through
     * what we said we would. */
    if (fstat(fd, &st) != 0 || !(S_ISFIFO(st.st_mode) || S_ISCHR(st.st_mode))) {
        close(fd);
        errno = EEXIST;
        return -1;
    }
    /* A reader that goes away gives EPIPE instead of killing the program by SIGPIPE before it
     * could remove its temporaries. */
    struct sigaction ign, old;
    memset(&ign, 0, sizeof ign);
    ign.sa_handler = SIG_IGN;
    sigaction(SIGPIPE, &ign, &old);
    size_t done = 0;
    int rc = 0;
    while (done < o->memlen) {
        ssize_t w = write(fd, o->mem + done, o->memlen - done);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) {
            rc = -1;
            break;
        }
        done += (size_t)w;
    }
    int saved = errno;
    sigaction(SIGPIPE, &old, NULL);
    if (close(fd) != 0 && rc == 0) saved = errno, rc = -1;
    errno = saved;
    return rc;
}

int out_commit(out_file *const *o, int n, char *err, size_t errcap) {
    int rc = 0;
    for (int i = 0; i < n; i++) {
        int bad = ferror(o[i]->fp);
        if (fclose(o[i]->fp) != 0 || bad) {
            if (rc == 0) snprintf(err, errcap, "%s: cannot write: %s", o[i]->path, strerror(errno));
            rc = PM_EIO;
        }
        o[i]->fp = NULL;
    }
    for (int i = 0; i < n && rc == 0; i++)
        if (o[i]->through && write_through(o[i]) != 0) {
            snprintf(err, errcap, "%s: cannot write through it: %s", o[i]->path, strerror(errno));
            rc = PM_EIO;
        }
    if (rc == 0) {
        out_defer_begin(); /* all renames, or (signal) none: the handler waits for them */
        for (int i = 0; i < n; i++) {
            if (!o[i]->tmp[0]) continue;
            if (rename(o[i]->tmp, o[i]->target) != 0) {
                if (rc == 0)
                    snprintf(err, errcap, "%s: cannot put the file in place: %s", o[i]->path,
                             strerror(errno));
                rc = PM_EIO;
                continue;
            }
            reg_drop(o[i]->slot);
            o[i]->slot = -1;
            o[i]->tmp[0] = 0;
        }
        out_defer_end();
    }
    for (int i = 0; i < n; i++) out_abort(o[i]);
    out_die_if_pending();
    return rc;
}

/* ---- test hook ---------------------------------------------------------------------------- */

void out_test_pause(const char *phase) {
    const char *v = getenv("PM_RENDER_TEST_PAUSE");
    size_t n = strlen(phase);
    if (!v || strncmp(v, phase, n) != 0 || (v[n] != 0 && v[n] != ':')) return;
    fprintf(stderr, "render: test pause at %s\n", phase);
    fflush(stderr);
    struct timespec ts = {0, 20 * 1000 * 1000};
    for (int i = 0; i < 3000 && !out_pending_signal(); i++) nanosleep(&ts, NULL);
}

double out_test_pause_fraction(void) {
    const char *v = getenv("PM_RENDER_TEST_PAUSE");
    if (!v || strncmp(v, "render:", 7) != 0) return -1;
    char *end;
    double f = strtod(v + 7, &end);
    return end != v + 7 && f >= 0 && f <= 1 ? f : -1;
}
