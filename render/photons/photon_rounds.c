/* photon_rounds.c: the rules of the ONE pass driver of both photon tracers (pass_run,
 * photon_pass.c: photon_trace.h's surface passes and volume.h's media passes), its batches,
 * the memory budget's prefix, and for a distributed pass (photon_trace_set_dist, vol_set_dist;
 * DISTRIBUTED PASSES in photon_trace.h) its rounds of batches: each process traces its
 * batches of a round, the exchange gives every process every batch, and a partitioned pass
 * exchanges only counts and traces again the batches holding its part.
 *
 * THE RULES BEFORE (two drivers, up to 2fcfd51):
 *   surface (pass_run)   batches of PT_BATCH photons on all threads; one target (the main map,
 *       the shadow map following its cut); emission budget max_emitted_factor x target, at
 *       most max_emitted, checked between batches (the last batch passing it whole); a pass
 *       storing nothing in 16 batches (65536 photons) ended PM_EEMPTY; a pass whose rate
 *       needed over twice the emission budget stopped at once; memory: buffer capacities (64 B
 *       a record) between batches, and a batch whose records passed what was left was dropped
 *       whole (a runaway's first batch: nothing stored, PM_EEMPTY); distributed: each
 *       process's m batches of a round shared what was left at the round's start, a batch
 *       past its share stopping every process there (earlier or later than one process).
 *   media (vol_trace_pass)   rounds of 8 batches of 1024 photons, one batch per thread; two
 *       maps with their own targets and cuts; emission budget the caller's max_emitted,
 *       exact; a map storing nothing in 131072 photons stayed empty; no stop by rate;
 *       memory: 72 B a record, buffers between rounds, and each batch of a round 1/8 of what
 *       the maps left, a batch past it ending at its photon that passed (earlier photons
 *       whole); distributed: replicated only, the one-process maps, budget stops included.
 *
 * THE ONE RULE NOW (both kinds of pass; images are unchanged wherever no budget stops a pass,
 * since the maps are then the stores of the first photons in index order cut at each target
 * by whole paths, which both drivers did alike):
 *   batches  PT_BATCH photons on all threads, merged in photon order: the maps are the same
 *            for any thread count (and for any process count, below);
 *   stored   each map kept with its own target (a media pass's surface and volume maps; a
 *            surface pass's main map, its shadow map following the main map's cut) is cut
 *            after the photon whose stores reach the target; the pass ends when every map is
 *            cut. A target of LONG_MAX keeps every store (never cut);
 *   empty    a map with nothing stored after PASS_EMPTY_BATCHES batches (131072 photons, the
 *            media's figure: a surface pass that needs more than 65536 photons for its first
 *            store now gets its map instead of PM_EEMPTY) stays empty; a pass whose maps all
 *            stay empty fails with PM_EEMPTY (the messages are each tracer's);
 *   emitted  at most the emission budget, exactly (the media's rule: the last batch is cut
 *            at it). No stop by rate (the media's rule; the surfaces stopped a pass at once
 *            when its rate after 4 batches needed over twice the budget): a map that cannot
 *            reach its target takes the whole budget and keeps what it buys. Chosen because
 *            the rate stop, applied to both, left gas_room_tungsten's caustic maps with 360
 *            and 40 photons (stopped after 16384 photons, against 90321 and 9784 from the
 *            budget) and glass_of_smoke's with 5086 (against 55472); without it only
 *            glass_hole's caustic pass changes among the shipped scenes (79 photons from 24576
 *            emitted at 32 x 32 x 4: it now runs to its budget);
 *   memory   max_memory_bytes of 64-byte records: the maps' buffer capacities between
 *            batches; inside a batch the records may reach what is left (the budget less the
 *            records held), and a batch that passes it keeps its longest prefix of photons
 *            whose records fit, each whole (traced again on one thread: pass_trace_prefix),
 *            and the pass ends there. So the stop is the same for any thread count and, in a
 *            distributed pass, for any process count (a round's batch past what is left now
 *            is traced again by every process); a runaway keeps the photons that fit instead
 *            of nothing. Chosen: the media's rule was independent of threads and processes
 *            too, but by fixed shares of 1/8 per batch of 1024 photons; the prefix keeps that
 *            independence with the whole of what is left and the surfaces' batches, and
 *            unlike the surfaces' rule it keeps photons in a runaway. A partitioned pass
 *            (surfaces only) does the same with its counts: every process traces the prefix,
 *            counts it as a batch ending at its last whole photon (pass_batch_count.end), and
 *            at the end traces again only that prefix of it (retrace); its count-only buffers
 *            grow as the one-process buffers do (capped at the budget). Until 2026-12-05 it
 *            stopped before a batch past its round's share of what was left, so its stop
 *            could differ from one process's (a runaway's first batch: nothing stored);
 *   path     max_bounces per photon (photon_walk.c), the cut paths counted.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "photons/photon_pass.h"
#include "photons/volume.h"

#ifdef _OPENMP
#include <omp.h>
#endif

/* Trace photons start .. start + PT_BATCH - 1 on nthreads threads into the per-thread buffers
 * (thread t: tg[t] and ts[t]). 0; bit 0 set on failure (out of memory), bit 1 when the batch's
 * records passed c->batch_cap (the batch is then incomplete). */
int pass_trace_batch(const pass_ctx *c, uint64_t start, pass_buf *tg, pass_buf *ts, int nthreads,
                     uint64_t *nfirst_out) {
    int fail = 0;
    uint64_t nfirst = 0;
    (void)nthreads; /* read by OpenMP only */
#ifdef _OPENMP
/* monotonic: each thread must get its chunks in increasing order, because pass_buf_merge takes
 * every per-thread buffer as sorted by photon index. OpenMP 5 makes plain dynamic
 * nonmonotonic, and LLVM's libomp then steals chunks from the other threads' far ends, which
 * made the maps depend on the thread count in clang builds. */
#pragma omp parallel for num_threads(nthreads) schedule(monotonic : dynamic, 64) reduction(| : fail) \
    reduction(+ : nfirst)
#endif
    for (int k = 0; k < PT_BATCH; k++) {
        int t = 0, fs = 0;
#ifdef _OPENMP
        t = omp_get_thread_num();
#endif
        if (start + (uint64_t)k >= c->end) continue; /* past the emission budget */
        /* Without a global map the shadow photons are the pass's main output; a media pass's
         * second buffer is its volume map. */
        walk_out o = {&tg[t], c->media || c->want_global ? &ts[t] : &tg[t], 0, c->vps ? &c->vps[t] : NULL};
        int r = photon_walk(c, start + (uint64_t)k, &o);
        fs = o.first_specular;
        if (r < 0) fail |= 1;
        if (r == PASS_OVER_BUDGET) fail |= 2;
        /* fs bit 0: first hit specular (caustic pass); bit 1: cut by the path-length budget,
         * counted in the high half so that one word carries both through the exchange. */
        nfirst += (uint64_t)(fs & 1) + ((uint64_t)(fs >> 1) << 32);
    }
    *nfirst_out += nfirst;
    return fail;
}

/* Photons start .. hi - 1 on one thread (pass_trace_prefix), their records within cap (0: no
 * cap); returns where it ended. */
static uint64_t trace_range(pass_ctx *c, uint64_t start, uint64_t hi, uint64_t cap, pass_buf *tg, pass_buf *ts,
                            uint64_t *nfirst, int *fail) {
    uint64_t rec = 0;
    c->batch_cap = cap;
    c->batch_records = &rec;
    pass_buf *sb = c->media || c->want_global ? &ts[0] : &tg[0];
    tg[0].n = ts[0].n = 0;
    for (uint64_t i = start; i < hi; i++) {
        walk_out o = {&tg[0], sb, 0, c->vps};
        int r = photon_walk(c, i, &o);
        if (r < 0) *fail = 1;
        if (r < 0) break;
        if (r == PASS_OVER_BUDGET) { /* photon i is not whole: drop its records, end here */
            while (tg[0].n > 0 && tg[0].v[tg[0].n - 1].index == i) tg[0].n--;
            while (ts[0].n > 0 && ts[0].v[ts[0].n - 1].index == i) ts[0].n--;
            hi = i;
            break;
        }
        *nfirst += (uint64_t)(o.first_specular & 1) + ((uint64_t)(o.first_specular >> 1) << 32);
    }
    c->batch_cap = 0;
    c->batch_records = NULL;
    return hi;
}

uint64_t pass_trace_prefix(pass_ctx *c, uint64_t start, uint64_t cap, pass_buf *tg, pass_buf *ts, uint64_t *nfirst,
                           int *fail) {
    return trace_range(c, start, start + PT_BATCH < c->end ? start + PT_BATCH : c->end, cap, tg, ts, nfirst, fail);
}

static const trace_dist *g_dist;
/* Per thread: render-mpi sets it on the thread that runs the passes; a test runs several parts
 * in threads of one process. */
static _Thread_local const trace_dist *g_vdist;

void photon_trace_set_dist(const trace_dist *d) { g_dist = d; }
void vol_set_dist(const struct trace_dist *d) { g_vdist = d; }

/* A partitioned distributed pass (photon_trace.h); a pilot pass is always replicated (its
 * evidence counts each photon traced once), and a media pass too (volume.h). */
int pass_partitioned(const pass_ctx *c) { return g_dist && g_dist->partitioned && !c->o->pilot && !c->media; }

const trace_dist *pass_dist(void) { return g_dist; }

const trace_dist *pass_ctx_dist(const pass_ctx *c) {
    if (c->media) return c->vpilot ? NULL : g_vdist;
    return c->o->pilot ? NULL : g_dist;
}

/* A distributed pass: trace a batch (pass_trace_batch), through the test hook; and say this
 * process's own failure before the exchange tells every process (trace_dist.failed). */
static int dist_trace(const trace_dist *d, const pass_ctx *c, uint64_t start, pass_buf *tg, pass_buf *ts,
                      int nthreads, uint64_t *nfirst) {
    if (c->batch_records) *c->batch_records = 0; /* the memory budget counts each batch anew */
    int fail = pass_trace_batch(c, start, tg, ts, nthreads, nfirst);
    return d->test_fail && d->test_fail(d->user) ? 1 : fail;
}
static void dist_failed(const trace_dist *d, const pass_ctx *c, int again) {
    char what[128];
    snprintf(what, sizeof what, "out of memory while tracing photons (%s%s)",
             c->media ? "a pass of the media" : c->caustic_pass ? "the caustic pass" : c->want_global ? "the global pass" : "the shadow pass",
             again ? ", tracing this process's part of the map again" : "");
    if (d->failed) d->failed(d->user, what);
}

/* One batch as exchanged: this head in the room of one photon record, then nmain main-buffer
 * and nshadow shadow-buffer photons in index order. A process that failed sends only a head
 * with fail set. */
typedef struct batch_head {
    uint64_t nmain, nshadow, nfirst, fail;
} batch_head;

#define ROUND_MAX_PER_PART 16

/* Batches per process in the round that begins at photon `start`: 1 at first; then as many as
 * still fit in every process's share of the batches the pass needs at the rate stored so far
 * (and of the emission budget), at most ROUND_MAX_PER_PART. Fewer rounds mean fewer waits
 * for the slowest process; the last rounds shrink to one batch each, so at most
 * nparts - 1 batches are traced past the stopping point. Every process computes the same
 * number from the same bookkeeping. */
static int round_batches(const pass_rounds *rb, uint64_t start, int nparts) {
    uint64_t done = start / PT_BATCH;
    if (!rb->stored || done == 0 || rb->stored->n == 0) return 1;
    double left = ((double)rb->target - (double)rb->stored->n) * (double)done / (double)rb->stored->n;
    double budget = (rb->limit - (double)start) / PT_BATCH;
    if (budget < left) left = budget;
    double m = floor(left / nparts);
    return m < 1 ? 1 : m > ROUND_MAX_PER_PART ? ROUND_MAX_PER_PART : (int)m;
}

/* A round: trace this process's batches of the round that begins at photon `start`, exchange.
 * Process p traces the round's batches p m .. p m + m - 1, so the exchange, in process order,
 * is in batch order. 1 on failure here or (seen in the exchange) anywhere. */
static int dist_round(const pass_ctx *c, pass_rounds *rb, uint64_t start, pass_buf *tg, pass_buf *ts,
                      int nthreads) {
    const trace_dist *d = pass_ctx_dist(c);
    int per = round_batches(rb, start, d->nparts);
    size_t *sizes = rb->sizes ? rb->sizes : calloc((size_t)d->nparts, sizeof *sizes);
    free(rb->all);
    rb->all = NULL;
    rb->sizes = sizes;
    rb->next = rb->nbatch = 0;
    rb->off = 0;
    pass_buf out = {0}; /* this process's blocks: head, then its photons, per batch */
    batch_head *heads = NULL; /* a partitioned pass: the heads alone */
    int fail = !sizes, part = pass_partitioned(c);
    if (part && !(heads = calloc((size_t)per, sizeof *heads))) fail = 1;
    /* The memory budget inside the batches (pass_run sets the records still allowed): each of
     * this process's `per` batches of the round may store its share, so the round's records
     * stay within what is left. c is pass_run's own (not const there). */
    uint64_t allowance = c->batch_cap;
    if (allowance) ((pass_ctx *)c)->batch_cap = allowance / (uint64_t)per > 0 ? allowance / (uint64_t)per : 1;
    for (int j = 0; j < per && !fail; j++) {
        batch_head h = {0, 0, 0, 0};
        pass_buf m = {0}, sh = {0};
        uint64_t first = start + ((uint64_t)d->part * (uint64_t)per + (uint64_t)j) * PT_BATCH;
        h.fail = (uint64_t)dist_trace(d, c, first, tg, ts, nthreads, &h.nfirst);
        if (part) { /* counts only: the photons are traced again by the process keeping them */
            for (int t = 0; t < nthreads; t++) {
                h.nmain += tg[t].n;
                h.nshadow += ts[t].n;
                tg[t].n = ts[t].n = 0;
            }
            heads[j] = h;
            fail = (int)h.fail;
            continue;
        }
        if (pass_buf_merge(&m, tg, nthreads) < 0 || pass_buf_merge(&sh, ts, nthreads) < 0) h.fail = 1;
        h.nmain = m.n;
        h.nshadow = sh.n;
        /* The head takes half a photon record's room (pass_rec is 8-byte aligned, 64 bytes). */
        pass_rec head[1];
        memset(head, 0, sizeof head);
        memcpy(head, &h, sizeof h);
        if (!h.fail && pass_buf_push(&out, head) < 0) h.fail = 1;
        for (size_t i = 0; !h.fail && i < m.n; i++) h.fail = pass_buf_push(&out, &m.v[i]) < 0;
        for (size_t i = 0; !h.fail && i < sh.n; i++) h.fail = pass_buf_push(&out, &sh.v[i]) < 0;
        free(m.v);
        free(sh.v);
        for (int t = 0; t < nthreads; t++) tg[t].n = ts[t].n = 0;
        fail = (int)h.fail;
    }
    if (allowance) ((pass_ctx *)c)->batch_cap = allowance;
    /* fail 2: a batch passed the memory budget (no error): every process stops there. */
    batch_head failed = {0, 0, 0, fail == 2 ? 2 : 1};
    if (fail && fail != 2) dist_failed(d, c, 0);
    const void *mine = fail ? (const void *)&failed : part ? (const void *)heads : (const void *)out.v;
    size_t nbytes = fail ? sizeof failed : part ? (size_t)per * sizeof *heads : out.n * sizeof(pass_rec);
    int rc = pass_allgather(d, mine, nbytes, (void **)&rb->all, &rb->sizes);
    free(out.v);
    free(heads);
    if (rc < 0) return 1;
    rb->start = start;
    rb->nbatch = d->nparts * per;
    return 0;
}

/* Batch [n_e, n_e + PT_BATCH) of a distributed pass into tg[0] and ts[0] (the other buffers
 * stay empty, so pass_run merges them as it merges its own), from the current round, or from
 * a new one when that is used up. 1 on failure anywhere. */
static int dist_batch(const pass_ctx *c, pass_rounds *rb, uint64_t n_e, pass_buf *tg, pass_buf *ts,
                      int nthreads, uint64_t *nfirst, uint64_t *counts) {
    if (!rb->all || rb->next == rb->nbatch || rb->start + (uint64_t)rb->next * PT_BATCH != n_e)
        if (dist_round(c, rb, n_e, tg, ts, nthreads)) return 1;
    batch_head h;
    memcpy(&h, rb->all + rb->off, sizeof h);
    if (h.fail) return h.fail == 2 ? 2 : 1;
    if (counts) { /* a partitioned pass: the batch's counts, from its head alone */
        counts[0] = h.nmain;
        counts[1] = h.nshadow;
        *nfirst += h.nfirst;
        rb->off += sizeof h;
        rb->next++;
        return 0;
    }
    const pass_rec *p = (const pass_rec *)(rb->all + rb->off) + 1; /* after the head's slot */
    for (uint64_t i = 0; i < h.nmain; i++)
        if (pass_buf_push(&tg[0], &p[i]) < 0) return 1;
    for (uint64_t i = 0; i < h.nshadow; i++)
        if (pass_buf_push(&ts[0], &p[h.nmain + i]) < 0) return 1;
    *nfirst += h.nfirst;
    rb->off += (size_t)(1 + h.nmain + h.nshadow) * sizeof(pass_rec);
    rb->next++;
    return 0;
}

/* A partitioned pass: the bookkeeping's counts stand for the buffers. vgrow adds k photons
 * to a count-only buffer (v stays NULL) and grows its capacity as pass_buf_merge_capped grows
 * a buffer's (capped at the memory budget's records less the other buffer's capacity, as
 * pass_batch merges), so the memory budget stops the pass where one process would. */
static void vgrow(pass_buf *b, uint64_t k, size_t cap_max) {
    if (b->n + k > b->cap) {
        size_t need = b->n + (size_t)k, nc = b->cap ? b->cap : 1024;
        while (nc < need) nc *= 2;
        if (cap_max && nc > cap_max) nc = need > cap_max ? need : cap_max;
        b->cap = nc;
    }
    b->n += (size_t)k;
}

int pass_part_count(const pass_ctx *c, pass_rounds *rb, uint64_t nmain, uint64_t nshadow, uint64_t end,
                    pass_buf *main_buf, pass_buf *shadow_buf) {
    /* Doubling growth of this array (photon_records.c grows another type's alike). */
    if (rb->nbc == rb->capbc) {
        size_t nc = rb->capbc ? 2 * rb->capbc : 64;
        pass_batch_count *nv = realloc(rb->bc, nc * sizeof *nv);
        if (!nv) return PM_ENOMEM;
        rb->bc = nv;
        rb->capbc = nc;
    }
    rb->bc[rb->nbc++] = (pass_batch_count){nmain, nshadow, end};
    size_t recs = c->o->max_memory_bytes / sizeof(pass_rec);
    size_t cap_main = recs ? recs - (shadow_buf && shadow_buf->cap < recs ? shadow_buf->cap : 0) : 0;
    size_t cap_shadow = recs ? recs - (main_buf->cap < recs ? main_buf->cap : 0) : 0;
    vgrow(main_buf, nmain, cap_main);
    if (shadow_buf) vgrow(shadow_buf, nshadow, cap_shadow);
    return 0;
}

int pass_dist_batch(const pass_ctx *c, pass_rounds *rb, uint64_t n_e, pass_buf *tg, pass_buf *ts, int nthreads,
                    uint64_t *nfirst, pass_buf *main_buf, pass_buf *shadow_buf) {
    if (!pass_partitioned(c)) return dist_batch(c, rb, n_e, tg, ts, nthreads, nfirst, NULL);
    uint64_t cnt[2] = {0, 0};
    int fail = dist_batch(c, rb, n_e, tg, ts, nthreads, nfirst, cnt);
    /* A round's batches were traced with what was left at its start: a batch whose records
     * pass what is left now is over the budget here too (pass_over traces its prefix). */
    if (fail == 0 && c->batch_cap && cnt[0] + cnt[1] > c->batch_cap) return 2;
    if (fail == 0 && pass_part_count(c, rb, cnt[0], cnt[1], UINT64_MAX, main_buf, shadow_buf) < 0) fail = 1;
    return fail == 2 ? 2 : fail ? 1 : 0; /* 2: over the memory budget (pass_run) */
}

/* Free, then clear, member by member: the rounds' own arrays (light_guide.c frees another
 * struct's alike). */
void pass_rounds_free(pass_rounds *rb) {
    free(rb->all);
    free(rb->sizes);
    free(rb->bc);
    rb->all = NULL;
    rb->sizes = NULL;
    rb->bc = NULL;
}

/* Batch b of a partitioned pass traced again alike by every process: whole, or the memory
 * budget's prefix it kept (bc[b].end; pass_over), on one thread. Nonzero on failure. */
static int retrace(const trace_dist *d, const pass_ctx *c, const pass_rounds *rb, size_t b, pass_buf *tg,
                   pass_buf *ts, int nthreads) {
    uint64_t dummy = 0, start = (uint64_t)b * PT_BATCH;
    if (rb->bc[b].end == UINT64_MAX) return dist_trace(d, c, start, tg, ts, nthreads, &dummy);
    int fail = 0;
    for (int t = 0; t < nthreads; t++) tg[t].n = ts[t].n = 0;
    /* c is pass_run's own (not const there): trace_range sets and restores its batch budget */
    trace_range((pass_ctx *)c, start, rb->bc[b].end, 0, tg, ts, &dummy, &fail);
    return fail;
}

/* The end of a partitioned pass whose nb batches stored bc[b] photons each (vm, vs: the
 * counts of the main and shadow buffers). The cut of pass_cut_at_target, found by tracing the
 * batch that holds the target-th store again (every process does it: the same photons); then
 * this process traces again the batches that hold its part of the main buffer's stores and
 * keeps that part in `out`. Sets vm, vs and *n_e to the whole pass's figures. Every process
 * returns the same: 0, or PM_ENOMEM if any failed (one all-gather of 8 bytes). */
int pass_part_finish(const pass_ctx *c, pass_rounds *rb, long target, uint64_t *n_e,
                       pass_buf *vm, pass_buf *vs, pass_buf *out, pass_buf *tg, pass_buf *ts, int nthreads) {
    const trace_dist *d = g_dist;
    pass_batch_count *bc = rb->bc;
    size_t nb = rb->nbc, ncut = nb;
    int fail = 0;
    if (target > 0 && vm->n > (size_t)target) {
        uint64_t before = 0, sbefore = 0;
        size_t b = 0;
        while (b < nb && before + bc[b].nmain < (uint64_t)target) {
            before += bc[b].nmain;
            sbefore += bc[b++].nshadow;
        }
        pass_buf m = {0}, sh = {0};
        fail = b == nb || retrace(d, c, rb, b, tg, ts, nthreads) ||
               pass_buf_merge(&m, tg, nthreads) < 0 || pass_buf_merge(&sh, ts, nthreads) < 0 ||
               m.n != bc[b].nmain;
        if (!fail) {
            size_t k = (size_t)((uint64_t)target - before);
            uint64_t last = m.v[k - 1].index;
            while (k < m.n && m.v[k].index == last) k++;
            size_t j = 0;
            while (j < sh.n && sh.v[j].index <= last) j++;
            bc[b].nmain = k;
            vm->n = (size_t)(before + k);
            if (vs) vs->n = (size_t)(sbefore + j);
            *n_e = last + 1;
            ncut = b + 1;
        }
        free(m.v);
        free(sh.v);
    }
    /* The whole map is the pass's n stores, then the joining pilot's (c->tail, PILOT PHOTONS in
     * photon_trace.h), as one process orders them. */
    uint64_t n = vm->n, nall = n + (c->tail ? c->tail->n : 0), lo = nall * (uint64_t)d->part / (uint64_t)d->nparts,
             hi = nall * (uint64_t)(d->part + 1) / (uint64_t)d->nparts, at = 0;
    for (size_t b = 0; b < ncut && !fail && at < hi; at += bc[b++].nmain) {
        if (at + bc[b].nmain <= lo || bc[b].nmain == 0) continue;
        pass_buf m = {0};
        fail = retrace(d, c, rb, b, tg, ts, nthreads) || pass_buf_merge(&m, tg, nthreads) < 0 || m.n < bc[b].nmain;
        for (int t = 0; t < nthreads; t++) ts[t].n = 0;
        uint64_t i0 = lo > at ? lo - at : 0, i1 = hi - at < bc[b].nmain ? hi - at : bc[b].nmain;
        for (uint64_t i = i0; !fail && i < i1; i++) fail = pass_buf_push(out, &m.v[i]) < 0;
        free(m.v);
    }
    for (uint64_t i = lo > n ? lo : n; !fail && i < hi; i++) fail = pass_buf_push(out, &c->tail->v[i - n]) < 0;
    if (fail) dist_failed(d, c, 1);
    uint64_t f = (uint64_t)fail, *all = NULL;
    size_t *sizes = NULL;
    if (pass_allgather(d, &f, sizeof f, (void **)&all, &sizes) < 0) fail = 1;
    for (int p = 0; all && p < d->nparts; p++) fail |= all[p] != 0;
    free(all);
    free(sizes);
    return fail ? PM_ENOMEM : 0;
}
