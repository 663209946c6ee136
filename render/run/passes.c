/* passes.c: the pass loop and the running estimate; see passes.h.
 *
 * Each pass is one call of the image loop with the pass's seed and no progress bar of its
 * own; its float image is added into the double sums on this thread, so the estimate does not
 * depend on how the pass's tiles were scheduled.
 */
#include "run/passes.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/output.h"
#include "base/rng.h"
#include "base/stats.h"
#include "common.h"

int pass_state_init(pass_state *ps, int width, int height) {
    size_t n = (size_t)width * (size_t)height * 3;
    ps->width = width;
    ps->height = height;
    ps->done = 0;
    ps->sum = calloc(n, sizeof *ps->sum);
    ps->sum2 = calloc(n, sizeof *ps->sum2);
    ps->mult = NULL;
    if (!ps->sum || !ps->sum2) {
        pass_state_free(ps);
        return PM_ENOMEM;
    }
    return 0;
}

/* Member by member, as render_state_free (renderer.c) for another struct's arrays. */
void pass_state_free(pass_state *ps) {
    free(ps->sum);
    free(ps->sum2);
    free(ps->mult);
    ps->sum = ps->sum2 = NULL;
    ps->mult = NULL;
}

void pass_state_add(pass_state *ps, const film *f) {
    size_t n = (size_t)ps->width * (size_t)ps->height * 3;
    for (size_t i = 0; i < n; i++) {
        double v = (double)f->px[i];
        ps->sum[i] += v;
        ps->sum2[i] += v * v;
    }
    ps->done++;
}

void pass_state_to_film(const pass_state *ps, film *f) {
    size_t n = (size_t)ps->width * (size_t)ps->height * 3;
    for (size_t i = 0; i < n; i++) f->px[i] = ps->done ? (float)(ps->sum[i] / ps->done) : 0.0f;
}

double pass_state_rmse(const pass_state *ps, double *mean) {
    size_t n = (size_t)ps->width * (size_t)ps->height * 3;
    double P = ps->done, var = 0, m = 0;
    for (size_t i = 0; i < n; i++) {
        double mu = ps->sum[i] / P;
        m += mu;
        if (ps->done > 1) {
            double v = (ps->sum2[i] - P * mu * mu) / (P - 1); /* the pass images' variance */
            if (v > 0 && isfinite(v)) var += v / P;          /* their mean's */
        }
    }
    if (mean) *mean = n && ps->done ? m / (double)n : 0;
    if (ps->done < 2 || n == 0) return -1;
    return sqrt(var / (double)n);
}

int pass_mult_valid(const unsigned char *m, size_t n) {
    size_t zeros = 0;
    for (size_t i = 0; i < n; i++) {
        if (m[i] > ADAPT_MAX) return 0;
        zeros += m[i] == 0;
    }
    return zeros == 0 || zeros == n;
}

/* The samples of multipliers min(ADAPT_MAX, max(1, floor(lambda s_p))), over the pixels. */
static double adapt_total(const double *s, size_t n, double lambda) {
    double t = 0;
    for (size_t i = 0; i < n; i++) t += fmin(ADAPT_MAX, fmax(1.0, floor(lambda * s[i])));
    return t;
}

int pass_state_adapt(pass_state *ps, double share, size_t *marked, double *extra) {
    size_t n = (size_t)ps->width * (size_t)ps->height;
    double *sd = malloc((n ? n : 1) * sizeof *sd), P = ps->done, smin = INFINITY;
    unsigned char *m = malloc(n ? n : 1);
    if (!sd || !m) {
        free(sd);
        free(m);
        return PM_ENOMEM;
    }
    for (size_t i = 0; i < n; i++) {
        double v = 0;
        for (int c = 0; c < 3 && P > 1; c++) {
            double mu = ps->sum[3 * i + (size_t)c] / P;
            double vc = (ps->sum2[3 * i + (size_t)c] - P * mu * mu) / (P - 1);
            if (vc > 0 && isfinite(vc)) v += vc;
        }
        sd[i] = sqrt(v);
        if (sd[i] > 0 && sd[i] < smin) smin = sd[i];
    }
    /* the largest lambda within the budget, by bisection (the total rises with lambda) */
    double lo = 0, budget = (double)n * (1 + share);
    if (isfinite(smin)) {
        double hi = 2.0 * ADAPT_MAX / smin;
        if (adapt_total(sd, n, hi) <= budget) lo = hi;
        else
            for (int it = 0; it < 200; it++) {
                double mid = 0.5 * (lo + hi);
                if (adapt_total(sd, n, mid) <= budget) lo = mid;
                else hi = mid;
            }
    }
    size_t k = 0;
    double added = 0;
    for (size_t i = 0; i < n; i++) {
        m[i] = (unsigned char)fmin(ADAPT_MAX, fmax(1.0, floor(lo * sd[i])));
        k += m[i] > 1;
        added += m[i] - 1;
    }
    free(sd);
    free(ps->mult);
    ps->mult = m;
    if (marked) *marked = k;
    if (extra) *extra = n ? added / (double)n : 0;
    return 0;
}

uint64_t pass_seed(uint64_t seed, int pass) {
    if (pass == 0) return seed;
    return rng_mix64(seed ^ rng_mix64(UINT64_C(0x7061737300000000) + (uint64_t)pass)); /* "pass" */
}

/* Tests: PM_RENDER_TEST_PAUSE=pass:N pauses (output.h's out_test_pause, phase "pass") once
 * pass N's maps are made, before its image, so a signal there stops pass N mid-way. */
static void test_pause_at(int pass) {
    const char *v = getenv("PM_RENDER_TEST_PAUSE");
    if (v && strncmp(v, "pass:", 5) == 0 && atoi(v + 5) == pass) out_test_pause("pass");
}

/* ADAPTIVE SAMPLES before a pass: decide once ADAPT_AFTER passes are done, then (render-mpi)
 * give every rank rank 0's multipliers. */
static int adapt_before_pass(const pass_run *run, pass_state *ps, char *err, size_t errcap) {
    size_t n = (size_t)ps->width * (size_t)ps->height, marked = 0;
    double extra = 0;
    int fresh = !ps->mult && ps->done >= ADAPT_AFTER;
    if (fresh && pass_state_adapt(ps, run->adapt, &marked, &extra) < 0) {
        snprintf(err, errcap, "adaptive samples: out of memory");
        return PM_ENOMEM;
    }
    if (run->share) {
        if (!ps->mult && !(ps->mult = calloc(n ? n : 1, 1))) {
            snprintf(err, errcap, "adaptive samples: out of memory");
            return PM_ENOMEM;
        }
        if (!fresh && ps->done < ADAPT_AFTER) memset(ps->mult, 0, n); /* undecided */
        int rc = run->share(ps->mult, n);
        if (rc < 0) {
            snprintf(err, errcap, "adaptive samples: sharing the multipliers failed");
            return rc;
        }
        if (n == 0 || ps->mult[0] == 0) { /* rank 0 has not decided */
            free(ps->mult);
            ps->mult = NULL;
        }
    }
    if (fresh && !run->quiet) {
        int top = 1;
        for (size_t i = 0; ps->mult && i < n; i++) top = ps->mult[i] > top ? ps->mult[i] : top;
        fprintf(stderr, "Adaptive samples: from %d passes' spread, %zu of %zu pixels take up to %d times the "
                "samples, %.1f%% more a pass (where the pass images vary most; --adaptive 0: none)\n",
                ps->done, marked, n, top, 100 * extra);
    }
    return 0;
}

int render_passes(const scene *s, integrator *it, const render_job *job, const pass_run *run,
                  pass_state *ps, film *out, pass_report *rep, char *err, size_t errcap) {
    memset(rep, 0, sizeof *rep);
    int rc = 0, interrupted = 0;
    double tsum = 0;
    int first = run->only >= 0 ? run->only : ps->done;
    for (int p = first;; p++) {
        int go = 1, by_budget = 0, by_signal = 0;
        if (run->only >= 0 && p > run->only) go = 0;
        if (run->only < 0 && run->max_passes > 0 && p >= run->max_passes) go = 0;
        if (go && rep->passes > 0 && run->budget > 0 &&
            stats_now() - run->t_origin + tsum / rep->passes > run->budget)
            go = 0, by_budget = 1;
        if (go && run->stop_on_signal && out_pending_signal()) go = 0, by_signal = 1;
        if (run->agree) go = run->agree(go); /* a distributed render: rank 0's decision */
        if (!go) {
            rep->stopped_by_budget = by_budget;
            interrupted = by_signal;
            break;
        }
        if (run->adapt > 0 && (rc = adapt_before_pass(run, ps, err, errcap)) < 0) break;
        double t0 = rep->passes == 0 && run->t_first > 0 ? run->t_first : stats_now();
        uint64_t seed = pass_seed(job->seed, p);
        double tb = stats_now();
        if (it->begin_pass && (rc = it->begin_pass(it, s, p, seed, err, errcap)) < 0) break;
        stats_time_add("Time/Passes: begin_pass (photon maps)", stats_now() - tb);
        test_pause_at(p);
        render_job pj = *job;
        pj.seed = seed;
        pj.quiet = 1;
        pj.mult = ps->mult;
        render_control ctl;
        memset(&ctl, 0, sizeof ctl);
        ctl.stop_on_signal = run->stop_on_signal;
        film f;
        rc = run->image(s, it, &pj, &ctl, &f);
        if (rc == RENDER_INTERRUPTED) {
            film_free(&f);
            rc = 0;
            interrupted = 1;
            break;
        }
        if (rc < 0) {
            snprintf(err, errcap, "rendering pass %d: %s", p, pm_strerror(rc));
            break;
        }
        pass_state_add(ps, &f);
        film_free(&f);
        double dt = stats_now() - t0;
        tsum += dt;
        if (dt > rep->longest) rep->longest = dt;
        rep->passes++;
        if (!run->quiet) {
            double mean, e = pass_state_rmse(ps, &mean);
            fprintf(stderr, "Pass %d done: %d pass%s, %.2f s elapsed", p, ps->done,
                    ps->done == 1 ? "" : "es", stats_now() - run->t_origin);
            if (run->budget > 0) fprintf(stderr, " of %.4g s", run->budget);
            fprintf(stderr, ", this pass %.2f s", dt);
            if (e >= 0)
                fprintf(stderr, ", error estimate %.3g (%.2f%% of the mean)", e,
                        mean > 0 ? 100 * e / mean : 0.0);
            fputc('\n', stderr);
        }
        if (run->on_pass && (rc = run->on_pass(run->user, ps, RENDER_PAUSE_PERIODIC)) < 0) {
            snprintf(err, errcap, "after pass %d", p);
            break;
        }
    }
    rep->elapsed = stats_now() - run->t_origin;
    rep->mean = rep->passes ? tsum / rep->passes : 0;
    stats_time_add("Time/Passes: all passes", tsum);
    if (rc < 0) return rc;
    if (interrupted && run->on_pass && (rc = run->on_pass(run->user, ps, RENDER_PAUSE_SIGNAL)) < 0) {
        snprintf(err, errcap, "writing the checkpoint after a signal");
        return rc;
    }
    if ((rc = film_init(out, ps->width, ps->height)) < 0) return rc;
    pass_state_to_film(ps, out);
    return interrupted ? RENDER_INTERRUPTED : 0;
}
