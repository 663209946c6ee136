/* photon_pass.c: running a photon pass, the part both tracers share; see photon_pass.h.
 *
 * Photons are traced in full precision (float position and RGB power, before the division by
 * the number emitted) into per-thread buffers tagged with their photon index, merged in index
 * order after each batch, and cut at the target by whole photon paths; the tracers pack them
 * into 20-byte pm_photon records only at the end, once the number emitted is known, so the
 * RGBE rounding happens once per photon.
 */
#include "photons/photon_pass.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/progress.h"
#include "photonmap/common.h"

#ifdef _OPENMP
#include <omp.h>
#endif

/* ---- records ------------------------------------------------------------------------------ */

/* photon_rounds.c sends a batch's head in the room of one record. */
_Static_assert(sizeof(pass_rec) == 64, "pass_rec is 64 bytes");

int pass_buf_push(pass_buf *b, const pass_rec *p) {
    if (b->n == b->cap) {
        size_t nc = b->cap ? 2 * b->cap : 1024;
        pass_rec *nv = realloc(b->v, nc * sizeof *nv);
        if (!nv) return PM_ENOMEM;
        b->v = nv;
        b->cap = nc;
    }
    b->v[b->n++] = *p;
    return 0;
}

/* Ties cannot straddle buffers: one photon is traced by one thread. cap_max keeps a pass's
 * buffers within its memory budget instead of up to twice it. */
int pass_buf_merge_capped(pass_buf *out, pass_buf *bufs, int nb, size_t cap_max) {
    size_t total = 0;
    for (int t = 0; t < nb; t++) total += bufs[t].n;
    if (out->n + total > out->cap) {
        size_t need = out->n + total, nc = out->cap ? out->cap : 1024;
        while (nc < need) nc *= 2;
        if (cap_max && nc > cap_max) nc = need > cap_max ? need : cap_max;
        pass_rec *nv = realloc(out->v, nc * sizeof *nv);
        if (!nv) return PM_ENOMEM;
        out->v = nv;
        out->cap = nc;
    }
    size_t head[256] = {0};
    for (size_t k = 0; k < total; k++) {
        int best = -1;
        for (int t = 0; t < nb; t++)
            if (head[t] < bufs[t].n &&
                (best < 0 || bufs[t].v[head[t]].index < bufs[best].v[head[best]].index))
                best = t;
        out->v[out->n++] = bufs[best].v[head[best]++];
    }
    for (int t = 0; t < nb; t++) bufs[t].n = 0;
    return 0;
}

/* The maps are then exactly those of a pass that stopped at that photon, so the powers
 * (divided by the number emitted) stay unbiased, and the stored count overshoots the target
 * by less than one path. */
uint64_t pass_cut_at_target(pass_buf *main_buf, pass_buf *shadow_buf, long target, uint64_t n_e) {
    if (target <= 0 || main_buf->n <= (size_t)target) return n_e;
    uint64_t last = main_buf->v[target - 1].index;
    size_t k = (size_t)target;
    while (k < main_buf->n && main_buf->v[k].index == last) k++;
    main_buf->n = k;
    if (shadow_buf) {
        size_t j = 0;
        while (j < shadow_buf->n && shadow_buf->v[j].index <= last) j++;
        shadow_buf->n = j;
    }
    return last + 1;
}

void pass_rec_set(pass_rec *f, uint64_t idx, vec3 p, rgb power, vec3 d, vec3 n, int kind, double rel) {
    f->index = idx;
    f->rel = (float)rel;
    f->pos[0] = (float)p.x, f->pos[1] = (float)p.y, f->pos[2] = (float)p.z;
    f->power[0] = (float)power.x, f->power[1] = (float)power.y, f->power[2] = (float)power.z;
    f->dir[0] = (float)d.x, f->dir[1] = (float)d.y, f->dir[2] = (float)d.z;
    f->normal[0] = (float)n.x, f->normal[1] = (float)n.y, f->normal[2] = (float)n.z;
    f->kind = (int16_t)kind;
    f->medium = -1;
}

/* Whether a batch passes the cap depends only on its photons (their records in all), not on
 * which thread traced which, so a pass stops where it would on any number of threads. */
int pass_store(const pass_ctx *c, pass_buf *b, const pass_rec *fp) {
    if (c->batch_cap) {
        uint64_t now;
#ifdef _OPENMP
#pragma omp atomic capture
#endif
        now = ++*c->batch_records;
        if (now > c->batch_cap) return PASS_OVER_BUDGET;
    }
    return pass_buf_push(b, fp);
}

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

/* ---- exchange and messages ---------------------------------------------------------------- */

int pass_allgather(const trace_dist *d, const void *mine, size_t nbytes, void **all, size_t **sizes) {
    if (!*sizes) *sizes = calloc((size_t)d->nparts, sizeof **sizes);
    if (!*sizes) return -1;
    return d->allgather(d->user, mine, nbytes, all, *sizes) < 0 ? -1 : 0;
}

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

/* ---- the surface pass driver -------------------------------------------------------------- */

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
    const char *stop; /* the budget that stopped the pass */
    char why[256];
    int part, use_dist;
    pass_rounds rb;
} pass_run_state;

/* The budgets checked between batches: 1 (with st->stop) when one stops the pass. */
static int pass_stops(pass_run_state *st) {
    const pass_buf *mb = st->main_buf, *sb = st->shadow_buf;
    if ((double)st->n_e >= st->limit) {
        st->stop = st->limit_name;
        snprintf(st->why, sizeof st->why, "%.0f photons emitted", st->limit);
        return 1;
    }
    /* Nothing stored after PASS_EMPTY_BATCHES batches: the lights reach no surface that
     * stores photons (they face nothing, or only mirrors and glass that never lead to a
     * diffuse surface). Any one photon that could store would have had a chance of at
     * least 1 in PASS_EMPTY_BATCHES x PT_BATCH to be seen by now. */
    if (mb->n == 0 && st->n_e >= (uint64_t)PASS_EMPTY_BATCHES * PT_BATCH) {
        st->stop = "nothing stored";
        return 1;
    }
    /* Stored so slowly that the emission budget cannot reach the target: stop now rather
     * than after the whole budget (the map keeps what was stored). */
    if (mb->n > 0 && st->n_e >= 4 * (uint64_t)PT_BATCH) {
        double need = (double)st->target * (double)st->n_e / (double)mb->n;
        if (need > 2 * st->limit) {
            st->stop = st->limit_name;
            snprintf(st->why, sizeof st->why,
                     "the target needs about %.3g photons emitted at the rate seen (%zu stored "
                     "of %llu emitted), over the budget of %.3g",
                     need, mb->n, (unsigned long long)st->n_e, st->limit);
            return 1;
        }
    }
    size_t bytes = (mb->cap + (sb ? sb->cap : 0)) * sizeof(pass_rec);
    size_t max = st->c->o->max_memory_bytes;
    if (max > 0 && bytes > max) {
        st->stop = "max_memory_mb";
        snprintf(st->why, sizeof st->why, "%zu MiB of photon buffers", bytes >> 20);
        return 1;
    }
    return 0;
}

/* One batch: traced here, or its round's share by a distributed pass, and merged into the
 * pass's buffers. 0, 1 (st->stop: the memory budget stopped the pass), or PM_ENOMEM. */
static int pass_batch(pass_run_state *st, const char *title, char *err, size_t errcap) {
    pass_ctx *c = st->c;
    size_t max = c->o->max_memory_bytes;
    int fail;
    /* The memory budget inside the batch too: one batch can store PT_BATCH times the path
     * length (a lossless furnace: 4096 x 1e5 records, 19 GB), so the check between batches
     * alone comes too late. A batch whose records would pass what is left of the budget is
     * dropped whole (its photons are not counted as emitted: the map is then that of a pass
     * that stopped before it, its powers unbiased); distributed passes split what is left
     * among a round's batches (dist_round) and stop every process together. */
    uint64_t in_batch = 0, budget = max / sizeof(pass_rec),
             held = (uint64_t)st->main_buf->n + (st->shadow_buf ? (uint64_t)st->shadow_buf->n : 0);
    c->batch_cap = max > 0 ? (budget > held ? budget - held : 1) : 0;
    c->batch_records = c->batch_cap ? &in_batch : NULL;
    if (st->use_dist) {
        fail = pass_dist_batch(c, &st->rb, st->n_e, st->tg, st->ts, st->nthreads, &st->nfirst, st->main_buf,
                               st->shadow_buf);
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
    if (fail == 2) {
        for (int t = 0; t < st->nthreads; t++) st->tg[t].n = st->ts[t].n = 0;
        st->stop = "max_memory_mb";
        snprintf(st->why, sizeof st->why, "the next %s%d photons would store more than the %zu MiB left of %zu MiB",
                 st->use_dist ? "batches of " : "", PT_BATCH,
                 (size_t)((budget > held ? budget - held : 0) * sizeof(pass_rec)) >> 20, max >> 20);
        return 1;
    }
    st->n_e += PT_BATCH;
    /* The memory budget in records, less what the other buffer holds (the check between
     * batches adds both buffers' capacities). */
    pass_buf *mb = st->main_buf, *sb = st->shadow_buf;
    size_t recs = max / sizeof(pass_rec);
    size_t cap_main = recs ? recs - (sb && sb->cap < recs ? sb->cap : 0) : 0;
    size_t cap_shadow = recs ? recs - (mb->cap < recs ? mb->cap : 0) : 0;
    if (fail || (!st->part && (pass_buf_merge_capped(mb, st->tg, st->nthreads, cap_main) < 0 ||
                               (sb && pass_buf_merge_capped(sb, st->ts, st->nthreads, cap_shadow) < 0)))) {
        snprintf(err, errcap, "out of memory while tracing photons (%s)", title);
        return PM_ENOMEM;
    }
    return 0;
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
        char with[96] = "", budget[64];
        if (c->tail)
            snprintf(with, sizeof with, " (the pilot's %zu stores and %llu photons included)", tn,
                     (unsigned long long)c->tail_emitted);
        snprintf(budget, sizeof budget, "photon_mapping.%s budget", st->stop ? st->stop : "?");
        pass_say_short(file, title, mb->n + tn, st->target + (long)tn, st->n_e + c->tail_emitted, with, budget,
                       st->why);
    }
    return rc;
}

int pass_run(pass_ctx *c, long target, pass_buf *main_buf, pass_buf *shadow_buf, pass_out *out,
             const char *title, char *err, size_t errcap) {
    const trace_opts *o = c->o;
    pass_run_state st;
    memset(&st, 0, sizeof st);
    st.c = c;
    st.target = target;
    st.nthreads = 1;
#ifdef _OPENMP
    st.nthreads = o->threads > 0 ? o->threads : omp_get_max_threads();
#endif
    if (st.nthreads > 256) st.nthreads = 256;
    st.tg = calloc((size_t)st.nthreads, sizeof *st.tg);
    st.ts = calloc((size_t)st.nthreads, sizeof *st.ts);
    if (!st.tg || !st.ts) {
        free(st.tg);
        free(st.ts);
        snprintf(err, errcap, "out of memory");
        return PM_ENOMEM;
    }
    st.limit = o->max_emitted_factor * (double)target;
    st.limit_name = "max_emitted_factor";
    if (o->max_emitted > 0 && (double)o->max_emitted < st.limit) {
        st.limit = (double)o->max_emitted;
        st.limit_name = "max_emitted";
    }
    /* A partitioned pass keeps counts in vmain and vshadow. A distributed render's pilot
     * passes are traced whole by every process, exchanging nothing: every process plans from
     * the evidence one process sees, so the plans agree with each other and with render's. */
    st.part = pass_partitioned(c);
    st.use_dist = pass_dist() && !o->pilot;
    pass_buf vmain = {0}, vshadow = {0};
    st.main_buf = st.part ? &vmain : main_buf;
    st.shadow_buf = st.part && shadow_buf ? &vshadow : shadow_buf;
    st.rb.target = target;
    st.rb.stored = st.main_buf;
    st.rb.limit = st.limit;
    int rc = 0;
    progress prog;
    progress_begin(&prog, title, target, o->quiet);
    size_t reported = 0;
    while ((long)st.main_buf->n < target && rc == 0 && !pass_stops(&st)) {
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
    } else if (rc == 0) {
        st.n_e = pass_cut_at_target(st.main_buf, st.shadow_buf, target, st.n_e);
    }
    pass_rounds_free(&st.rb);
    uint64_t cut = st.nfirst >> 32;
    rc = pass_report(&st, rc, cut, &out->runaway, title, err, errcap);
    out->emitted = st.n_e;
    out->whole[0] = st.main_buf->n;
    out->whole[1] = st.shadow_buf ? st.shadow_buf->n : 0;
    out->first_specular = st.nfirst & 0xffffffffULL;
    for (int t = 0; t < st.nthreads; t++) {
        free(st.tg[t].v);
        free(st.ts[t].v);
    }
    free(st.tg);
    free(st.ts);
    return rc;
}
