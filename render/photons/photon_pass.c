/* photon_pass.c: running a photon pass, the part both tracers share; see photon_pass.h.
 *
 * Photons are traced in full precision (float position and RGB power, before the division by
 * the number emitted) into per-thread buffers tagged with their photon index, merged in index
 * order after each batch, and cut at the target by whole photon paths; the tracers pack them
 * into 20-byte pm_photon records only at the end, once the number emitted is known, so the
 * RGBE rounding happens once per photon. The records, their buffers and the exchange are
 * photon_records.c's (under this file, the walk and the rounds alike).
 */
#include "photons/photon_pass.h"

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/progress.h"
#include "photonmap/common.h"
#include "photons/volume.h"

#ifdef _OPENMP
#include <omp.h>
#endif

/* ---- aim ---------------------------------------------------------------------------------- */

int pass_aim_build(const scene *s, int cells, pass_aim *a) {
    memset(a, 0, sizeof *a);
    a->nl = s->nlights;
    double *w = malloc((size_t)(s->nlights > 0 ? s->nlights : 1) * sizeof *w);
    int rc = projmap_build_all(s, cells, &a->proj);
    if (!w) rc = PM_ENOMEM;
    for (int i = 0; rc == 0 && i < s->nlights; i++) {
        rgb pw = s->lights[i].power;
        double mean = (pw.x + pw.y + pw.z) / 3;
        w[i] = mean * a->proj[i].fraction;
        a->wsum += w[i];
        a->psum += mean;
    }
    if (rc == 0 && a->wsum > 0) {
        rc = distrib1d_init(&a->choose, w, s->nlights);
        a->chosen = rc == 0;
    }
    free(w);
    return rc;
}

void pass_aim_free(pass_aim *a) {
    if (a->chosen) distrib1d_free(&a->choose);
    projmap_free_all(a->proj, a->nl);
    memset(a, 0, sizeof *a);
}

/* ---- messages ----------------------------------------------------------------------------- */

void pass_say_cut(const char *file, const char *title, uint64_t cut, int max_bounces) {
    int f = file && file[0];
    fprintf(stderr,
            "%s%s%sphoton tracing: %s: %llu photon paths were cut by the path-length budget "
            "(photon_mapping.max_bounces = %d)\n",
            f ? "render: " : "", f ? file : "", f ? ": " : "", title, (unsigned long long)cut, max_bounces);
}

void pass_say_short(const char *file, const char *title, size_t n, long target, uint64_t n_e, const char *with,
                    const char *budget, const char *why) {
    int f = file && file[0];
    fprintf(stderr,
            "%s%s%sphoton tracing: %s: only %zu of %ld photons stored after %llu emitted%s; stopped by "
            "the %s (%s)\n",
            f ? "render: " : "", f ? file : "", f ? ": " : "", title, n, target, (unsigned long long)n_e, with,
            budget, why);
}

void pass_say_empty(char *err, size_t errcap, const char *title, uint64_t n_e, const char *places,
                    const char *stopped) {
    snprintf(err, errcap,
             "photon tracing: %s: no photon stored after %llu emitted: the lights reach no "
             "%s that stores photons (do they face anything? are they enclosed by "
             "mirrors or glass only?)%s%s",
             title, (unsigned long long)n_e, places, stopped ? "; stopped by " : "", stopped ? stopped : "");
}

/* ---- the driver (the rules: the top of photon_rounds.c) ------------------------------------ */

/* A pass while it runs: pass_run's state, shared by its steps. */
typedef struct pass_run_state {
    pass_ctx *c;
    long target;
    pass_buf *main_buf, *shadow_buf;
    pass_buf *tg, *ts; /* per-thread buffers */
    int nthreads;
    double limit; /* the emission budget: max_emitted_factor x target, and at most max_emitted */
    const char *limit_name;
    uint64_t n_e, nfirst;
    uint64_t cut[2]; /* the maps' cuts (main, second buffer): photons [0, cut) kept; UINT64_MAX:
                        open; a map not kept, or following the main map's cut: 0 */
    const char *stop; /* the budget that stopped the pass */
    char why[256];
    int part, use_dist;
    pass_rounds rb;
} pass_run_state;

static long map_target(const pass_run_state *st, int k) { return k == 0 ? st->target : st->c->target2; }
static pass_buf *map_buf(const pass_run_state *st, int k) { return k == 0 ? st->main_buf : st->shadow_buf; }
static int map_open(const pass_run_state *st, int k) { return st->cut[k] == UINT64_MAX; }
static int maps_open(const pass_run_state *st) { return map_open(st, 0) || map_open(st, 1); }

/* Drop b's records of photons cut and after. */
static void cut_buf(pass_buf *b, uint64_t cut) {
    while (b && b->n > 0 && b->v[b->n - 1].index >= cut) b->n--;
}

/* After a batch: a map whose stores reach its target is cut after the photon that reached it
 * (a partitioned pass's cut is pass_part_finish's), a map with nothing stored after
 * PASS_EMPTY_BATCHES batches stays empty; each map keeps only the photons before its cut (the
 * second buffer, when it has no target of its own, the main map's). */
static void close_maps(pass_run_state *st) {
    for (int k = 0; k < 2; k++) {
        pass_buf *b = map_buf(st, k);
        long t = map_target(st, k);
        if (!map_open(st, k)) continue;
        if ((long)b->n >= t) st->cut[k] = st->part ? st->n_e : b->v[t - 1].index + 1;
        else if (b->n == 0 && st->n_e >= (uint64_t)PASS_EMPTY_BATCHES * PT_BATCH) {
            st->cut[k] = st->n_e;
            if (!st->stop && !maps_open(st)) st->stop = "nothing stored";
        }
    }
    if (st->part) return;
    for (int k = 0; k < 2; k++)
        if (!map_open(st, k) && map_target(st, k) > 0) cut_buf(map_buf(st, k), st->cut[k]);
    if (st->c->target2 <= 0 && !map_open(st, 0)) cut_buf(st->shadow_buf, st->cut[0]);
}

/* The budgets checked between batches: 1 (with st->stop) when one stops the pass. */
static int pass_stops(pass_run_state *st) {
    if (st->n_e >= st->c->end) {
        st->stop = st->limit_name;
        snprintf(st->why, sizeof st->why, "%.0f photons emitted", st->limit);
        return 1;
    }
    st->why[0] = 0;
    const pass_buf *mb = st->main_buf, *sb = st->shadow_buf;
    size_t bytes = (mb->cap + (sb ? sb->cap : 0)) * sizeof(pass_rec);
    size_t max = st->c->o->max_memory_bytes;
    if (max > 0 && bytes > max) {
        st->stop = "max_memory_mb";
        snprintf(st->why, sizeof st->why, "%zu MiB of photon buffers", bytes >> 20);
        return 1;
    }
    return 0;
}

/* A batch past the memory budget: its prefix that fits, traced again on one thread (every
 * process alike in a distributed pass, which counts it in its bookkeeping when partitioned).
 * 1 when the pass stops there (st->stop), 0 when the whole batch fits (a distributed round's
 * share was passed, not the budget), PM_ENOMEM. */
static int pass_over(pass_run_state *st, uint64_t cap, uint64_t left, size_t max) {
    pass_ctx *c = st->c;
    for (int t = 0; t < st->nthreads; t++) st->tg[t].n = st->ts[t].n = 0;
    uint64_t hi = st->n_e + PT_BATCH < c->end ? st->n_e + PT_BATCH : c->end;
    int fail = 0;
    uint64_t end = pass_trace_prefix(c, st->n_e, cap, st->tg, st->ts, &st->nfirst, &fail);
    if (fail) return PM_ENOMEM;
    st->rb.next = st->rb.nbatch; /* a distributed pass goes on with a new round */
    if (st->part) { /* its counts stand for the records, which the parts trace again at the end */
        if (pass_part_count(c, &st->rb, st->tg[0].n, st->ts[0].n, end == hi ? UINT64_MAX : end, st->main_buf,
                            st->shadow_buf) < 0)
            return PM_ENOMEM;
        st->tg[0].n = st->ts[0].n = 0;
    }
    if (end == hi) return 0;
    st->stop = "max_memory_mb";
    snprintf(st->why, sizeof st->why, "photon %llu would store past the %zu MiB left of %zu MiB",
             (unsigned long long)end, (size_t)(left * sizeof(pass_rec)) >> 20, max >> 20);
    st->n_e = end;
    return 1;
}

/* One batch: traced here, or its round's share by a distributed pass, and merged into the
 * pass's buffers. 0, 1 (st->stop: the memory budget stopped the pass), or PM_ENOMEM. */
static int pass_batch(pass_run_state *st, const char *title, char *err, size_t errcap) {
    pass_ctx *c = st->c;
    size_t max = c->o->max_memory_bytes;
    int fail, stop = 0;
    /* The memory budget inside the batch too: one batch can store PT_BATCH times the path
     * length (a lossless furnace: 4096 x 1e5 records, 19 GB), so the check between batches
     * alone comes too late (pass_over). */
    uint64_t in_batch = 0, budget = max / sizeof(pass_rec),
             held = (uint64_t)st->main_buf->n + (st->shadow_buf ? (uint64_t)st->shadow_buf->n : 0);
    uint64_t left = budget > held ? budget - held : 0;
    c->batch_cap = max > 0 ? (left > 0 ? left : 1) : 0;
    c->batch_records = c->batch_cap ? &in_batch : NULL;
    uint64_t cap = c->batch_cap;
    if (st->use_dist) {
        uint64_t nf0 = st->nfirst;
        fail = pass_dist_batch(c, &st->rb, st->n_e, st->tg, st->ts, st->nthreads, &st->nfirst, st->main_buf,
                               st->shadow_buf);
        /* A round's batches were traced with what was left at its start: a batch that passes
         * what is left now is over the budget here too (a replicated pass; pass_over). */
        if (fail == 0 && !st->part && cap && st->tg[0].n + st->ts[0].n > cap) fail = 2;
        if (fail == 2) st->nfirst = nf0;
    } else {
        uint64_t nf = 0;
        fail = pass_trace_batch(c, st->n_e, st->tg, st->ts, st->nthreads, &nf);
        if (fail != 2) { /* 2: over the budget and nothing failed, below */
            st->nfirst += nf;
            fail &= 1;
        }
    }
    c->batch_cap = 0;
    c->batch_records = NULL;
    if (fail == 2 && (stop = pass_over(st, cap, left, max)) < 0) fail = 1;
    else if (fail == 2) fail = 0;
    if (stop == 0) st->n_e = st->n_e + PT_BATCH < c->end ? st->n_e + PT_BATCH : c->end;
    /* The memory budget in records, less what the other buffer holds (the check between
     * batches adds both buffers' capacities). A closed map takes no more records. */
    pass_buf *mb = st->main_buf, *sb = st->shadow_buf;
    size_t recs = max / sizeof(pass_rec);
    size_t cap_main = recs ? recs - (sb && sb->cap < recs ? sb->cap : 0) : 0;
    size_t cap_shadow = recs ? recs - (mb->cap < recs ? mb->cap : 0) : 0;
    int shadow_open = c->target2 > 0 ? map_open(st, 1) : map_open(st, 0);
    for (int t = 0; t < st->nthreads; t++) {
        if (!map_open(st, 0)) st->tg[t].n = 0;
        if (!shadow_open) st->ts[t].n = 0;
    }
    if (fail || (!st->part && (pass_buf_merge_capped(mb, st->tg, st->nthreads, cap_main) < 0 ||
                               (sb && pass_buf_merge_capped(sb, st->ts, st->nthreads, cap_shadow) < 0)))) {
        snprintf(err, errcap, "out of memory while tracing photons (%s)", title);
        return PM_ENOMEM;
    }
    close_maps(st);
    return stop;
}

/* The pass's end: its messages on stderr and in err; PM_EEMPTY for a pass that stored
 * nothing, else rc. */
static int pass_report(pass_run_state *st, int rc, uint64_t cut, int *runaway, const char *title, char *err,
                       size_t errcap) {
    const pass_ctx *c = st->c;
    const trace_opts *o = c->o;
    const pass_buf *mb = st->main_buf;
    /* The warnings name the scene file as render's other messages do ("render: FILE: ..."). */
    const char *file = c->s->file;
    if (rc == 0 && cut > 0 && !o->pilot) pass_say_cut(file, title, cut, o->max_bounces);
    *runaway = rc == 0 && (long)mb->n < st->target;
    if (rc == 0 && st->stop && mb->n == 0 && strcmp(st->stop, "max_memory_mb") == 0) {
        snprintf(err, errcap,
                 "photon tracing: %s: no photon stored within the photon_mapping.max_memory_mb budget "
                 "(%s): raise it, or lower photon_mapping.max_bounces or render.max_depth",
                 title, st->why);
        return PM_EEMPTY;
    }
    if (rc == 0 && st->stop && mb->n == 0) {
        pass_say_empty(err, errcap, title, st->n_e, "surface", st->why[0] ? st->limit_name : NULL);
        return PM_EEMPTY;
    }
    if (*runaway && !o->pilot) {
        /* The figures of the whole map: with a joining pilot's stores and photons. */
        size_t tn = c->tail ? c->tail->n : 0;
        char with[96] = "", budget[160];
        if (c->tail)
            snprintf(with, sizeof with, " (the pilot's %zu stores and %llu photons included)", tn,
                     (unsigned long long)c->tail_emitted);
        if (st->stop && strchr(st->stop, ' ')) /* a caller's phrase (pass_ctx.limit_name) */
            snprintf(budget, sizeof budget, "%s", st->stop);
        else
            snprintf(budget, sizeof budget, "photon_mapping.%s budget", st->stop ? st->stop : "?");
        pass_say_short(file, title, mb->n + tn, st->target + (long)tn, st->n_e + c->tail_emitted, with, budget,
                       st->why);
    }
    return rc;
}

/* A media pass's end (volume.c says its messages): the maps' emitted counts, the stop, the
 * pilot's counts summed from the threads'. */
static void media_out(pass_run_state *st, pass_out *out) {
    pass_ctx *c = st->c;
    out->traced = st->n_e;
    out->emitted = st->cut[0] != UINT64_MAX ? st->cut[0] : st->n_e;
    out->emitted2 = st->cut[1] != UINT64_MAX ? st->cut[1] : st->n_e;
    out->runaway = map_open(st, 0);
    out->short2 = map_open(st, 1);
    out->stop = !st->stop || strcmp(st->stop, "nothing stored") == 0 ? NULL
                : strcmp(st->stop, "max_memory_mb") == 0 ? "photon_mapping.max_memory_mb budget"
                                                          : st->stop;
    snprintf(out->why, sizeof out->why, "%s", st->why);
    for (int t = 0; c->vpilot && t < st->nthreads; t++) {
        vol_pilot *a = c->vpilot, *b = &c->vps[t];
        a->emitted += b->emitted;
        for (int m = 0; m < VOL_PILOT_MEDIA; m++)
            for (int k = 0; k < 4; k++) a->events[m][k] += b->events[m][k];
        for (int k = 0; k < VOL_PILOT_MATS; k++) a->caustic_by_mat[k] += b->caustic_by_mat[k];
        a->surf_direct += b->surf_direct;
        a->surf_caustic += b->surf_caustic;
        a->surf_indirect += b->surf_indirect;
        a->surf_after_scatter += b->surf_after_scatter;
    }
}

/* pass_run's start: threads, buffers, the emission budget, the maps. 0 or PM_ENOMEM. */
static int pass_begin(pass_run_state *st, pass_ctx *c, long target) {
    const trace_opts *o = c->o;
    st->c = c;
    st->target = target;
    st->nthreads = 1;
#ifdef _OPENMP
    st->nthreads = o->threads > 0 ? o->threads : omp_get_max_threads();
#endif
    if (st->nthreads > 256) st->nthreads = 256;
    st->tg = calloc((size_t)st->nthreads, sizeof *st->tg);
    st->ts = calloc((size_t)st->nthreads, sizeof *st->ts);
    c->vps = c->media ? calloc((size_t)st->nthreads, sizeof *c->vps) : NULL;
    if (!st->tg || !st->ts || (c->media && !c->vps)) return PM_ENOMEM;
    st->limit = o->max_emitted_factor * (double)target;
    st->limit_name = "max_emitted_factor";
    if (o->max_emitted > 0 && (double)o->max_emitted < st->limit) {
        st->limit = (double)o->max_emitted;
        st->limit_name = "max_emitted";
    }
    if (c->limit > 0) {
        st->limit = c->limit;
        st->limit_name = c->limit_name ? c->limit_name : "photon_mapping.max_emitted budget";
    }
    c->end = st->limit < 1.8e19 ? (uint64_t)st->limit : UINT64_MAX;
    st->cut[0] = target > 0 ? UINT64_MAX : 0;
    st->cut[1] = c->target2 > 0 ? UINT64_MAX : 0;
    return 0;
}

int pass_run(pass_ctx *c, long target, pass_buf *main_buf, pass_buf *shadow_buf, pass_out *out,
             const char *title, char *err, size_t errcap) {
    const trace_opts *o = c->o;
    pass_run_state st;
    memset(&st, 0, sizeof st);
    int rc = pass_begin(&st, c, target);
    /* A partitioned pass keeps counts in vmain and vshadow. A distributed render's pilot
     * passes are traced whole by every process, exchanging nothing: every process plans from
     * the evidence one process sees, so the plans agree with each other and with render's. */
    st.part = pass_partitioned(c);
    st.use_dist = pass_ctx_dist(c) != NULL;
    pass_buf vmain = {0}, vshadow = {0};
    st.main_buf = st.part ? &vmain : main_buf;
    st.shadow_buf = st.part && shadow_buf ? &vshadow : shadow_buf;
    st.rb.target = c->target2 > target ? c->target2 : target;
    st.rb.stored = c->target2 > target ? st.shadow_buf : st.main_buf;
    st.rb.limit = st.limit;
    progress prog;
    progress_begin(&prog, title, target, o->quiet || c->media);
    size_t reported = 0;
    /* A media pilot keeps no map: it runs to the emission budget. */
    while (rc == 0 && (maps_open(&st) || c->vpilot) && !pass_stops(&st)) {
        rc = pass_batch(&st, title, err, errcap);
        if (rc == 1) {
            rc = 0;
            break;
        }
        size_t now = st.main_buf->n < (size_t)target ? st.main_buf->n : (size_t)target;
        progress_add(&prog, (int64_t)(now - reported));
        reported = now;
    }
    progress_end(&prog);
    if (rc == 0 && st.part) {
        rc = pass_part_finish(c, &st.rb, target, &st.n_e, st.main_buf, st.shadow_buf, main_buf, st.tg, st.ts,
                              st.nthreads);
        if (rc < 0) snprintf(err, errcap, "out of memory while tracing photons (%s)", title);
    } else if (rc == 0 && !c->media && !map_open(&st, 0)) {
        st.n_e = st.cut[0];
    }
    pass_rounds_free(&st.rb);
    if (c->media) media_out(&st, out);
    else {
        rc = pass_report(&st, rc, st.nfirst >> 32, &out->runaway, title, err, errcap);
        out->emitted = st.n_e;
    }
    out->paths_cut = st.nfirst >> 32;
    out->whole[0] = st.main_buf->n;
    out->whole[1] = st.shadow_buf ? st.shadow_buf->n : 0;
    out->first_specular = st.nfirst & 0xffffffffULL;
    for (int t = 0; st.tg && t < st.nthreads; t++) free(st.tg[t].v);
    for (int t = 0; st.ts && t < st.nthreads; t++) free(st.ts[t].v);
    free(st.tg);
    free(st.ts);
    free(c->vps);
    c->vps = NULL;
    if (rc == PM_ENOMEM && !err[0]) snprintf(err, errcap, "out of memory");
    return rc;
}
