/* output.h: writing the renderer's output files safely: whole or not at all, several of them
 * together, never replacing what is not a regular file, and no leftovers on SIGINT/SIGTERM.
 *
 * What happens to each kind of existing path (out_open, and out_check before the work):
 *   - absent, or a regular file: the bytes go to a temporary "<path>.tmpXXXXXX" in the same
 *     directory (mkstemp), renamed over the path at commit, so the path holds either the
 *     old file or the whole new one. New files get mode 0666 less the umask, as with fopen.
 *   - a symbolic link: followed (realpath). The link stays as it is; its final target is
 *     handled by these rules (a regular target is replaced atomically in its own
 *     directory; a FIFO or character device is written through). A link whose target does
 *     not exist, or that loops, is refused: creating a file at a place the link names is
 *     not something a user asking for "-o link" can be assumed to want.
 *   - a FIFO or a character device (e.g. /dev/null, a terminal): written through, never
 *     replaced: the bytes are produced in memory first and written to the opened node at
 *     commit. Opening a FIFO blocks until a reader opens it, as `cat > fifo` does.
 *   - a directory, block device or socket: refused with a message.
 * Refusals return PM_EIO with a message in err naming the path and why.
 *
 * Several outputs: out_open each (the writer fills o->fp), then out_commit(all): every
 * temporary is complete before the first rename, the write-through outputs are written
 * first (they cannot be taken back: if one fails no rename happens), then the renames run
 * with SIGINT/SIGTERM deferred so that a signal sees all old files or all new ones.
 *
 * Signals: out_signals_install() makes SIGINT and SIGTERM remove every registered temporary
 * (a fixed-size registry of paths, unlinked from the handler, which is async-signal-safe)
 * and then end the program by the same signal. Between out_defer_begin() and
 * out_defer_end() a signal is only recorded (out_pending_signal()): the renderer uses this
 * to finish the samples in flight and write a checkpoint; out_die_if_pending() then ends
 * the program as the handler would have. A second signal while deferred acts at once.
 *
 * Test hook (test-only, documented for the tests): with PM_RENDER_TEST_PAUSE=PHASE in the
 * environment, out_test_pause(PHASE) prints "render: test pause at PHASE" to stderr and
 * sleeps up to 60 s (a signal ends the wait), so a test can signal the program at a known
 * point. Phases: "photons" (before the photon pass), "render:F" (once a fraction F of the
 * samples is done), "pfm" and "png" (after that temporary is written, before the commit).
 *
 * Not thread-safe except the signal parts: outputs are opened and committed on one thread.
 */
#ifndef RENDER_OUTPUT_H
#define RENDER_OUTPUT_H

#include <stddef.h>
#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

#define OUT_PATH_MAX 4096

typedef struct out_file {
    char path[OUT_PATH_MAX];   /* as given */
    char target[OUT_PATH_MAX]; /* where the bytes end up (a symlink's resolved target) */
    char tmp[OUT_PATH_MAX];    /* the temporary (atomic outputs), else "" */
    int through;               /* 1: written through an existing FIFO or character device */
    FILE *fp;                  /* the stream the writer fills */
    char *mem;                 /* write-through: the bytes, kept in memory until commit */
    size_t memlen;
    int slot; /* signal registry slot of tmp, or -1 */
} out_file;

/* Whether path could be written, checked before expensive work. Creates nothing that stays.
 * 0, or PM_EIO with a message ("-o x/y.png: cannot write there: No such file or directory"). */
int out_check(const char *path, char *err, size_t errcap);
/* Whether dir is (or could be created as) a writable directory. 0 or PM_EIO with a message. */
int out_check_dir(const char *dir, char *err, size_t errcap);

/* Prepare o for path; o->fp is ready for writing. 0 or PM_EIO/PM_ENOMEM with a message. */
int out_open(out_file *o, const char *path, char *err, size_t errcap);
/* Close every stream and put all n outputs in place, or none of the atomic ones (see above).
 * Every output is finished afterwards (temporaries removed on failure). 0 or PM_EIO. */
int out_commit(out_file *const *o, int n, char *err, size_t errcap);
/* Drop o: close it, remove its temporary. Safe on a zeroed or finished out_file. */
void out_abort(out_file *o);

void out_signals_install(void);
void out_defer_begin(void);
void out_defer_end(void);
/* The signal recorded while deferred, or 0. */
int out_pending_signal(void);
/* If a signal is pending and nothing defers it any more: remove the temporaries and end the
 * program by that signal. Returns otherwise. */
void out_die_if_pending(void);

/* The test hook described above; returns at once unless PM_RENDER_TEST_PAUSE names phase. */
void out_test_pause(const char *phase);
/* The F of PM_RENDER_TEST_PAUSE=render:F, or a negative number when not set. */
double out_test_pause_fraction(void);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_OUTPUT_H */
