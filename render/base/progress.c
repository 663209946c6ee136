/* progress.c: the bar and plain-line reporter.
 *
 * Redraw thresholds are work counts: every 1/200 of the total on a terminal, every 1/10
 * otherwise. A thread that pushes `done` past `next_report` claims the report with a
 * compare-and-swap, so exactly one thread prints each step.
 */
#include "base/progress.h"

#include <stdio.h>
#include <unistd.h>

#include "base/stats.h"

static int64_t step_of(const progress *p) {
    int64_t s = p->total / (p->tty ? 200 : 10);
    return s > 0 ? s : 1;
}

static void fmt_time(char *buf, size_t cap, double s) {
    if (s < 0 || s != s) s = 0;
    int t = (int)(s + 0.5);
    if (t >= 3600)
        snprintf(buf, cap, "%dh%02dm", t / 3600, (t / 60) % 60);
    else if (t >= 60)
        snprintf(buf, cap, "%dm%02ds", t / 60, t % 60);
    else
        snprintf(buf, cap, "%.1fs", s);
}

static void draw(progress *p, int64_t done, int final) {
    double el = stats_now() - p->t0;
    double frac = p->total > 0 ? (double)done / (double)p->total : 1.0;
    double ran = done > p->base ? (double)(done - p->base) : 0; /* work of this run */
    char e[32], r[32];
    fmt_time(e, sizeof e, el);
    fmt_time(r, sizeof r, ran > 0 ? el / ran * (double)(p->total - done) : 0);
    if (p->tty) {
        char bar[41];
        int fill = (int)(frac * 40);
        for (int i = 0; i < 40; i++) bar[i] = i < fill ? '=' : (i == fill ? '>' : ' ');
        bar[40] = 0;
        if (final)
            fprintf(stderr, "\r%s [%s] 100%% (%s)          \n", p->title, bar, e);
        else
            fprintf(stderr, "\r%s [%s] %3d%% (%s, ETA %s)   ", p->title, bar, (int)(frac * 100), e, r);
    } else {
        if (final)
            fprintf(stderr, "%s: done in %s\n", p->title, e);
        else
            fprintf(stderr, "%s: %3d%% (%s elapsed, ETA %s)\n", p->title, (int)(frac * 100), e, r);
    }
    fflush(stderr);
}

void progress_begin(progress *p, const char *title, int64_t total, int quiet) {
    p->title = title;
    p->total = total;
    atomic_store(&p->done, 0);
    p->quiet = quiet;
    p->base = 0;
    p->tty = !quiet && isatty(STDERR_FILENO);
    atomic_store(&p->next_report, step_of(p));
    p->t0 = stats_now();
    if (!quiet && p->tty) draw(p, 0, 0);
}

void progress_add(progress *p, int64_t n) {
    int64_t done = atomic_fetch_add(&p->done, n) + n;
    if (p->quiet) return;
    int64_t due = atomic_load(&p->next_report);
    if (done < due || done >= p->total) return;
    int64_t step = step_of(p), next = (done / step + 1) * step;
    if (atomic_compare_exchange_strong(&p->next_report, &due, next)) draw(p, done, 0);
}

void progress_resume(progress *p, int64_t done) {
    p->base = done;
    atomic_store(&p->done, done);
    int64_t step = step_of(p);
    atomic_store(&p->next_report, (done / step + 1) * step);
    if (!p->quiet) draw(p, done, 0);
}

void progress_end(progress *p) {
    if (!p->quiet) draw(p, atomic_load(&p->done), 1);
}
