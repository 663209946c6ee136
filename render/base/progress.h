/* progress.h: a progress reporter for long loops (rendering tiles, tracing photons).
 *
 * On a terminal it redraws one line on stderr: a bar, the percentage, elapsed time and an
 * ETA. When stderr is not a terminal (a log file, a test, CI) it prints a plain line at every
 * 10% instead, so logs stay readable. progress_add() is thread-safe and lock-free; only the
 * thread whose addition crosses a redraw threshold prints, so it costs nothing in a loop.
 * A reporter with quiet = 1 counts but prints nothing.
 *
 *   progress p;
 *   progress_begin(&p, "Rendering", ntiles, quiet);
 *   ... progress_add(&p, 1); ...           // from any thread
 *   progress_end(&p);                       // prints the final line with the total time
 */
#ifndef RENDER_PROGRESS_H
#define RENDER_PROGRESS_H

#include <stdatomic.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct progress {
    const char *title;
    int64_t total;
    _Atomic int64_t done;
    _Atomic int64_t next_report; /* work count at which the next line or redraw is due */
    double t0;
    int tty, quiet;
    int64_t base; /* work already done when this run began (a resumed render); the ETA
                   * counts only the work done since */
} progress;

void progress_begin(progress *p, const char *title, int64_t total, int quiet);
void progress_add(progress *p, int64_t n);
/* Start from done units already finished (a resumed render): the bar shows them, and the
 * ETA is estimated from the rate of this run alone. Call right after progress_begin. */
void progress_resume(progress *p, int64_t done);
void progress_end(progress *p);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PROGRESS_H */
