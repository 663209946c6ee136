/* photon_trace.c: emission, scattering and classification of photons; see photon_trace.h.
 *
 * Photons are traced in full precision (double position, RGB power) into per-thread buffers
 * tagged with their photon index, merged in index order after each batch, and packed into
 * 20-byte pm_photon records only at the end, once the number emitted (which divides every
 * power) is known; so the RGBE rounding happens once per photon.
 */
#include "photons/photon_trace.h"

#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "photonmap/estimate.h"
#include "scene/material.h"
#include "base/progress.h"
#include "photons/importance.h"
#include "photons/projmap.h"
#include "base/rng.h"
#include "base/sampling.h"
#include "base/stats.h"

#ifdef _OPENMP
#include <omp.h>
#endif

/* ---- full-precision photons and growable buffers ----------------------------------------- */

typedef struct fphoton {
    uint64_t index; /* emitted photon it came from: the merge key */
    float pos[3], power[3], dir[3], normal[3];
    int kind;
    float rel; /* p(l, u) / p_l of its emission under the pass's importance table (1: none) */
} fphoton;

typedef struct fbuf {
    fphoton *v;
    size_t n, cap;
} fbuf;

/* A pilot's photons, kept for the real passes (PILOT PHOTONS in photon_trace.h). */
struct pilot_photons {
    fbuf g, s;                /* its global pass's global and shadow stores, in photon order */
    uint64_t emitted;         /* photons its global pass emitted (0: it ran none) */
    int max_depth, max_bounces, global, shadow; /* the rules its global pass was traced by */
    const importance *imp;    /* the table its rel were computed under (NULL: none) */
    fbuf c;                   /* its caustic pass's L S+ D stores, in photon order */
    uint64_t c_emitted, c_first_specular; /* that pass's photons (0: it ran none) */
    int c_max_depth, c_max_bounces, c_cells; /* its rules; c_cells: projection cells per side */
};

static int fbuf_push(fbuf *b, const fphoton *p) {
    if (b->n == b->cap) {
        size_t nc = b->cap ? 2 * b->cap : 1024;
        fphoton *nv = realloc(b->v, nc * sizeof *nv);
        if (!nv) return PM_ENOMEM;
        b->v = nv;
        b->cap = nc;
    }
    b->v[b->n++] = *p;
    return 0;
}

/* Merge the per-thread buffers (each sorted by index, as every thread handles its photons in
 * increasing order) onto the end of out, in index order; empties them. Ties cannot straddle
 * buffers: one photon is traced by one thread. cap_max (0: none): out's capacity in records
 * never grows past it by doubling (only to what the records need), so that a pass's buffers
 * stay within its memory budget instead of up to twice it. */
static int fbuf_merge_capped(fbuf *out, fbuf *bufs, int nb, size_t cap_max) {
    size_t total = 0;
    for (int t = 0; t < nb; t++) total += bufs[t].n;
    if (out->n + total > out->cap) {
        size_t need = out->n + total, nc = out->cap ? out->cap : 1024;
        while (nc < need) nc *= 2;
        if (cap_max && nc > cap_max) nc = need > cap_max ? need : cap_max;
        fphoton *nv = realloc(out->v, nc * sizeof *nv);
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

static int fbuf_merge(fbuf *out, fbuf *bufs, int nb) { return fbuf_merge_capped(out, bufs, nb, 0); }

/* ---- tracing one photon ------------------------------------------------------------------- */

typedef struct pass_ctx {
    const scene *s;
    const trace_opts *o;
    int caustic_pass;
    int want_global, want_shadow;
    distrib1d choose; /* light choice for this pass */
    rgb *light_scale; /* per light: power / p_light (times the projection fraction) */
    projmap *proj;    /* caustic pass: one per light */
    const importance *imp; /* global pass: importance-driven emission (importance.h), or NULL */
    int imp_rel_only;      /* a pilot: emit by power, and only record rel under imp */
    const fbuf *tail;      /* pilot stores that follow the pass's own in the main map, or NULL */
    uint64_t tail_emitted; /* the pilot photons those stores came from */
    double shift[6];
    /* The memory budget inside a batch (one process; PASS BUDGETS in photon_trace.h): the
     * records the batch may store (0: no cap), and the count so far, shared by its threads. */
    uint64_t batch_cap;
    uint64_t *batch_records;
} pass_ctx;

/* trace_photon's result when the batch's records pass batch_cap. */
#define TRACE_OVER_BUDGET 1

/* Store a record of the batch: PM_ENOMEM, TRACE_OVER_BUDGET once the batch's records (all
 * threads') pass its cap, or 0. Whether a batch passes the cap depends only on its photons
 * (their records in all), not on which thread traced which, so a pass stops where it would
 * on any number of threads. */
static int store(const pass_ctx *c, fbuf *b, const fphoton *fp) {
    if (c->batch_cap) {
        uint64_t now;
#ifdef _OPENMP
#pragma omp atomic capture
#endif
        now = ++*c->batch_records;
        if (now > c->batch_cap) return TRACE_OVER_BUDGET;
    }
    return fbuf_push(b, fp);
}

/* The photon's light, origin, normal, direction, and power before the pass's division (the
 * per-photon denominator is applied at packing, see pack); *rel its p(l, u) / p_l. */
static void emit_photon(const pass_ctx *c, uint64_t i, rng *g, int *li, vec3 *p, vec3 *n, vec3 *d,
                        rgb *power, double *rel) {
    double u0 = sample_halton(i, 0, c->shift);
    double pl;
    double u[4] = {sample_halton(i, 1, c->shift), sample_halton(i, 2, c->shift), sample_halton(i, 3, c->shift),
                   sample_halton(i, 4, c->shift)};
    *rel = 1;
    if (c->imp && !c->imp_rel_only) { /* the defensive mixture of importance.h */
        double h[4] = {u[0], u[1], u[2], u[3]};
        *li = importance_sample(c->imp, c->s, u0, h, u, rel);
        light_sample_le(c->s, *li, u, p, n, d);
        *power = c->light_scale[*li];
        return;
    }
    *li = distrib1d_sample(&c->choose, u0, &pl);
    if (c->imp) *rel = importance_rel(c->imp, c->s, *li, u); /* a pilot whose photons join */
    const light *l = &c->s->lights[*li];
    if (c->caustic_pass && c->proj) {
        projmap_sample(&c->proj[*li], l, sample_halton(i, 5, c->shift), g, u);
    }
    light_sample_le(c->s, *li, u, p, n, d);
    *power = c->light_scale[*li];
}

static void make_fp(fphoton *f, uint64_t idx, vec3 p, rgb power, vec3 d, vec3 n, int kind, double rel) {
    f->index = idx;
    f->rel = (float)rel;
    f->pos[0] = (float)p.x, f->pos[1] = (float)p.y, f->pos[2] = (float)p.z;
    f->power[0] = (float)power.x, f->power[1] = (float)power.y, f->power[2] = (float)power.z;
    f->dir[0] = (float)d.x, f->dir[1] = (float)d.y, f->dir[2] = (float)d.z;
    f->normal[0] = (float)n.x, f->normal[1] = (float)n.y, f->normal[2] = (float)n.z;
    f->kind = kind;
}

static double maxc_prod(double w, rgb t, rgb P) {
    return w * fmax(t.x * P.x, fmax(t.y * P.y, t.z * P.z));
}

/* The pilot's counters: per material, shared by the threads. */
static void pilot_count(pilot_counts *pc, int mat) {
    if (mat < 0 || mat >= PILOT_MAX_MATS) mat = PILOT_MAX_MATS - 1;
#ifdef _OPENMP
#pragma omp atomic
#endif
    pc->by_mat[mat]++;
#ifdef _OPENMP
#pragma omp atomic
#endif
    pc->total++;
}

/* Trace photon i; stores into gb (global or caustic) and sb (shadow), and sets *first_specular
 * to 1 if it is a caustic-pass photon whose first hit is specular. Returns 0, PM_ENOMEM or
 * TRACE_OVER_BUDGET (store). */
static int trace_photon(const pass_ctx *c, uint64_t i, fbuf *gb, fbuf *sb, int *first_specular) {
    const scene *s = c->s;
    rng g = rng_stream(c->o->seed, i, c->caustic_pass ? 2 : 1);
    int li;
    vec3 p, n, d;
    rgb P;
    double rel;
    emit_photon(c, i, &g, &li, &p, &n, &d, &P, &rel);
    trace_pilot *pl = c->o->pilot;
    if (pl) {
#ifdef _OPENMP
#pragma omp atomic
#endif
        pl->emitted++;
    }
    if (v3_iszero(P)) return 0;
    int from_area = s->lights[li].type == LIGHT_AREA;
    int first_spec_mat = -1, diffuse_mat = -1; /* the pilot's evidence: which surfaces */
    ray r = {scene_offset(c->s, p, n, d), d};
    int all_specular = 1; /* no diffuse bounce yet */
    /* The index around the light (known at the first refraction) and where the photon is: a
     * surface photon is stored with P (n_src / n_here)^2, the renderer's radiance convention
     * (material_radiance_scale, material.h); exactly P when it is back in n_src. That is the
     * product of (n1 / n2)^2 over its refractions when each starts in the index the last one
     * ended in; open surfaces can break that chain (two single glass quads crossed front to
     * back), and n_src takes the factor n1 / n_here of each such break. */
    double n_src = 0, n_here = 0;
    fphoton fp;
    int rc;
    int max_depth = c->o->max_depth;
    if (c->o->max_bounces > 0 && c->o->max_bounces < max_depth) max_depth = c->o->max_bounces;
    int depth;
    for (depth = 0; depth <= max_depth; depth++) {
        hit h;
        if (!scene_intersect(s, r, INFINITY, &h)) break;
        const material *m = scene_material(s, &h);
        vec3 wo = v3_neg(d);
        vec3 ns = v3_dot(wo, h.ng) >= 0 ? h.ng : v3_neg(h.ng); /* the side it arrived on */
        vec3 nsh = material_shading_side(wo, h.ng, h.ns);    /* bends directions only */
        double w[LOBE_COUNT];
        material_weights(m, wo, h.ng, s->medium_ior, w);
        int diffuse_here = w[LOBE_DIFFUSE] > 0 && v3_maxc(m->diffuse) > 0;
        if (c->caustic_pass && depth == 0 && !diffuse_here) *first_specular |= 1;
        if (depth == 0) first_spec_mat = h.mat; /* an L S+ D path's first surface is specular */
        if (pl && depth == 0) pilot_count(&pl->first_hits, h.mat);
        if (diffuse_here) {
            rgb Ps = v3_scale(P, material_radiance_scale(n_src, n_here));
            if (c->caustic_pass) {
                if (depth > 0 && all_specular) {
                    if (pl) pilot_count(&pl->caustic, first_spec_mat);
                    make_fp(&fp, i, h.p, Ps, d, ns, PM_KIND_CAUSTIC, rel);
                    if ((rc = store(c, gb, &fp)) != 0) return rc;
                }
            } else {
                int kind = depth == 0 ? PM_KIND_DIRECT : PM_KIND_INDIRECT;
                if (pl && !all_specular) pilot_count(&pl->diffuse_bounce, diffuse_mat);
                make_fp(&fp, i, h.p, Ps, d, ns, kind, rel);
                if (c->want_global && (rc = store(c, gb, &fp)) != 0) return rc;
                if (c->want_shadow && from_area && depth == 0 && (rc = store(c, sb, &fp)) != 0) return rc;
            }
        }
        if (c->want_shadow && from_area && depth == 0) {
            /* Shadow photons: the light's ray continued straight on through every surface. */
            hit h2 = h;
            int counted = 0; /* the pilot counts one occluded photon, not each shadow photon */
            for (int k = 0; k < 16; k++) {
                ray r2 = {scene_offset(c->s, h2.p, h2.ng, d), d};
                if (!scene_intersect(s, r2, INFINITY, &h2)) break;
                const material *m2 = scene_material(s, &h2);
                if (!material_is_diffuse(m2)) continue;
                vec3 ns2 = v3_dot(wo, h2.ng) >= 0 ? h2.ng : v3_neg(h2.ng);
                if (pl && !counted++) pilot_count(&pl->occluder, h.mat);
                make_fp(&fp, i, h2.p, v3s(0), d, ns2, PM_KIND_SHADOW, rel);
                if ((rc = store(c, sb, &fp)) != 0) return rc;
            }
        }
        /* Russian roulette over the branches (see the top of photon_trace.h). */
        double pmax = v3_maxc(P);
        if (!(pmax > 0)) break;
        double pd = diffuse_here ? maxc_prod(w[LOBE_DIFFUSE], m->diffuse, P) / pmax : 0;
        double pr = maxc_prod(w[LOBE_REFLECT], m->specular_tint, P) / pmax;
        double pt = maxc_prod(w[LOBE_TRANSMIT], m->transmit_tint, P) / pmax;
        double u = rng_uniform(&g), u1 = rng_uniform(&g), u2 = rng_uniform(&g);
        vec3 nd;
        if (u < pd) {
            if (c->caustic_pass) break; /* L S* D D...: not a caustic any more */
            nd = sampling_to_world(sample_cosine_hemisphere(u1, u2), nsh);
            if (v3_dot(nd, ns) <= 0) break; /* below the real surface: absorbed */
            /* f cos / pdf = pi f for cosine sampling; branch weight over its probability. */
            rgb f = material_diffuse_f(m, nsh, wo, nd);
            P = v3_scale(v3_mul(P, f), M_PI * w[LOBE_DIFFUSE] / pd);
            all_specular = 0;
            diffuse_mat = h.mat;
        } else if (u < pd + pr) {
            nd = material_reflect_shaded(d, ns, nsh);
            P = v3_scale(v3_mul(P, m->specular_tint), w[LOBE_REFLECT] / pr);
        } else if (u < pd + pr + pt) {
            double n1, n2;
            material_indices(m, wo, h.ng, s->medium_ior, &n1, &n2);
            if (!material_refract_shaded(d, ns, nsh, n1 / n2, &nd)) {
                nd = material_reflect_shaded(d, ns, nsh);
            } else {
                if (!(n_src > 0)) n_src = n1;
                else if (n1 != n_here) n_src *= n1 / n_here;
                n_here = n2;
            }
            P = v3_scale(v3_mul(P, m->transmit_tint), w[LOBE_TRANSMIT] / pt);
        } else {
            break; /* absorbed */
        }
        if (v3_iszero(P) || !v3_isfinite(P)) break;
        d = nd;
        r.o = scene_offset(c->s, h.p, h.ng, d);
        r.d = d;
    }
    /* Still alive after the last bounce allowed: the path-length budget cut it. */
    if (depth > max_depth && max_depth < c->o->max_depth) *first_specular |= 2;
    return 0;
}

/* ---- batches, and distributed rounds of batches ------------------------------------------- */

/* Trace photons start .. start + PT_BATCH - 1 on nthreads threads into the per-thread buffers
 * (thread t: tg[t] and ts[t]). 0; bit 0 set on failure (out of memory), bit 1 when the batch's
 * records passed c->batch_cap (the batch is then incomplete). */
static int trace_batch(const pass_ctx *c, uint64_t start, fbuf *tg, fbuf *ts, int nthreads,
                       uint64_t *nfirst_out) {
    int fail = 0;
    uint64_t nfirst = 0;
    (void)nthreads; /* read by OpenMP only */
#ifdef _OPENMP
/* monotonic: each thread must get its chunks in increasing order, because fbuf_merge takes
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
        /* Without a global map the shadow photons are the pass's main output. */
        int r = trace_photon(c, start + (uint64_t)k, &tg[t], c->want_global ? &ts[t] : &tg[t], &fs);
        if (r < 0) fail |= 1;
        if (r == TRACE_OVER_BUDGET) fail |= 2;
        /* fs bit 0: first hit specular (caustic pass); bit 1: cut by the path-length budget,
         * counted in the high half so that one word carries both through the exchange. */
        nfirst += (uint64_t)(fs & 1) + ((uint64_t)(fs >> 1) << 32);
    }
    *nfirst_out += nfirst;
    return fail;
}

static const trace_dist *g_dist;

void photon_trace_set_dist(const trace_dist *d) { g_dist = d; }

/* A partitioned distributed pass (photon_trace.h); a pilot pass is always replicated (its
 * evidence counts each photon traced once). */
static int part_pass(const pass_ctx *c) { return g_dist && g_dist->partitioned && !c->o->pilot; }

/* A distributed pass: trace a batch (trace_batch), through the test hook; and say this
 * process's own failure before the exchange tells every process (trace_dist.failed). */
static int dist_trace(const trace_dist *d, const pass_ctx *c, uint64_t start, fbuf *tg, fbuf *ts,
                      int nthreads, uint64_t *nfirst) {
    if (c->batch_records) *c->batch_records = 0; /* the memory budget counts each batch anew */
    int fail = trace_batch(c, start, tg, ts, nthreads, nfirst);
    return d->test_fail && d->test_fail(d->user) ? 1 : fail;
}
static void dist_failed(const trace_dist *d, const pass_ctx *c, int again) {
    char what[128];
    snprintf(what, sizeof what, "out of memory while tracing photons (the %s pass%s)",
             c->caustic_pass ? "caustic" : c->want_global ? "global" : "shadow",
             again ? ", tracing this process's part of the map again" : "");
    if (d->failed) d->failed(d->user, what);
}

/* One batch as exchanged: this head in the room of one photon record, then nmain main-buffer
 * and nshadow shadow-buffer photons in index order. A process that failed sends only a head
 * with fail set. */
typedef struct batch_head {
    uint64_t nmain, nshadow, nfirst, fail;
} batch_head;

/* The exchanged bytes of the current round: batch j of it starts at photon start + j PT_BATCH;
 * `next` is the batch to hand out, at byte `off`. target, stored and limit are the pass's,
 * for sizing the rounds. */
typedef struct round_buf {
    uint64_t start;
    int nbatch, next;
    char *all;
    size_t *sizes, off;
    long target;
    const fbuf *stored;
    double limit;
} round_buf;

#define ROUND_MAX_PER_PART 16

/* Batches per process in the round that begins at photon `start`: 1 at first; then as many as
 * still fit in every process's share of the batches the pass needs at the rate stored so far
 * (and of the emission budget), at most ROUND_MAX_PER_PART. Fewer rounds mean fewer waits
 * for the slowest process; the last rounds shrink to one batch each, so at most
 * nparts - 1 batches are traced past the stopping point. Every process computes the same
 * number from the same bookkeeping. */
static int round_batches(const round_buf *rb, uint64_t start, int nparts) {
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
static int dist_round(const pass_ctx *c, round_buf *rb, uint64_t start, fbuf *tg, fbuf *ts,
                      int nthreads) {
    const trace_dist *d = g_dist;
    int per = round_batches(rb, start, d->nparts);
    size_t *sizes = rb->sizes ? rb->sizes : calloc((size_t)d->nparts, sizeof *sizes);
    free(rb->all);
    rb->all = NULL;
    rb->sizes = sizes;
    rb->next = rb->nbatch = 0;
    rb->off = 0;
    fbuf out = {0}; /* this process's blocks: head, then its photons, per batch */
    batch_head *heads = NULL; /* a partitioned pass: the heads alone */
    int fail = !sizes, part = part_pass(c);
    if (part && !(heads = calloc((size_t)per, sizeof *heads))) fail = 1;
    /* The memory budget inside the batches (run_pass sets the records still allowed): each of
     * this process's `per` batches of the round may store its share, so the round's records
     * stay within what is left. c is run_pass's own (not const there). */
    uint64_t allowance = c->batch_cap;
    if (allowance) ((pass_ctx *)c)->batch_cap = allowance / (uint64_t)per > 0 ? allowance / (uint64_t)per : 1;
    for (int j = 0; j < per && !fail; j++) {
        batch_head h = {0, 0, 0, 0};
        fbuf m = {0}, sh = {0};
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
        if (fbuf_merge(&m, tg, nthreads) < 0 || fbuf_merge(&sh, ts, nthreads) < 0) h.fail = 1;
        h.nmain = m.n;
        h.nshadow = sh.n;
        /* The head takes half a photon record's room (fphoton is 8-byte aligned, 64 bytes). */
        fphoton head[1];
        memset(head, 0, sizeof head);
        memcpy(head, &h, sizeof h);
        if (!h.fail && fbuf_push(&out, head) < 0) h.fail = 1;
        for (size_t i = 0; !h.fail && i < m.n; i++) h.fail = fbuf_push(&out, &m.v[i]) < 0;
        for (size_t i = 0; !h.fail && i < sh.n; i++) h.fail = fbuf_push(&out, &sh.v[i]) < 0;
        free(m.v);
        free(sh.v);
        for (int t = 0; t < nthreads; t++) tg[t].n = ts[t].n = 0;
        fail = (int)h.fail;
    }
    if (allowance) ((pass_ctx *)c)->batch_cap = allowance;
    /* fail 2: a batch passed the memory budget (no error): every process stops there. */
    batch_head failed = {0, 0, 0, fail == 2 ? 2 : 1};
    if (fail && fail != 2) dist_failed(d, c, 0);
    int rc = !sizes ? -1
             : fail ? d->allgather(d->user, &failed, sizeof failed, (void **)&rb->all, sizes)
             : part ? d->allgather(d->user, heads, (size_t)per * sizeof *heads, (void **)&rb->all, sizes)
                    : d->allgather(d->user, out.v, out.n * sizeof(fphoton), (void **)&rb->all, sizes);
    free(out.v);
    free(heads);
    if (rc < 0) return 1;
    rb->start = start;
    rb->nbatch = d->nparts * per;
    return 0;
}

/* Batch [n_e, n_e + PT_BATCH) of a distributed pass into tg[0] and ts[0] (the other buffers
 * stay empty, so run_pass merges them as it merges its own), from the current round, or from
 * a new one when that is used up. 1 on failure anywhere. */
static int dist_batch(const pass_ctx *c, round_buf *rb, uint64_t n_e, fbuf *tg, fbuf *ts,
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
    const fphoton *p = (const fphoton *)(rb->all + rb->off) + 1; /* after the head's slot */
    for (uint64_t i = 0; i < h.nmain; i++)
        if (fbuf_push(&tg[0], &p[i]) < 0) return 1;
    for (uint64_t i = 0; i < h.nshadow; i++)
        if (fbuf_push(&ts[0], &p[h.nmain + i]) < 0) return 1;
    *nfirst += h.nfirst;
    rb->off += (size_t)(1 + h.nmain + h.nshadow) * sizeof(fphoton);
    rb->next++;
    return 0;
}

/* ---- passes ------------------------------------------------------------------------------- */

/* Pack b's photons with power / (np + nm rel): photons from two emissions joined by the
 * balance heuristic (Veach), np of them emitted by power (rel is their p / p_l under the
 * other's table) and nm by the pass (rel: its own p / p_l). np = 0 and rel = 1: power / nm. */
static int pack(const fbuf *b, double np, double nm, pm_photon **out, size_t *n) {
    *n = b->n;
    /* Zeroed: pm_photon_set keeps a record's kd-tree bits, which must start at 0. */
    *out = calloc(b->n ? b->n : 1, sizeof **out);
    if (!*out) return PM_ENOMEM;
    for (size_t k = 0; k < b->n; k++) {
        const fphoton *f = &b->v[k];
        double scale = 1.0 / (np + nm * (double)f->rel);
        float pw[3] = {(float)(f->power[0] * scale), (float)(f->power[1] * scale),
                       (float)(f->power[2] * scale)};
        pm_photon_init(&(*out)[k], f->pos, pw, f->dir, f->normal, f->kind);
    }
    return 0;
}

/* Keep the photons of the first emitted photons whose stores reach `target` (each emitted
 * photon whole: all its stores or none) and return how many were emitted: the maps are then
 * exactly those of a pass that stopped at that photon, so the powers (divided by the number
 * emitted) stay unbiased, and the stored count overshoots the target by less than one path. */
static uint64_t cut_at_target(fbuf *main_buf, fbuf *shadow_buf, long target, uint64_t n_e) {
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

/* A partitioned pass: the bookkeeping's counts stand for the buffers. vgrow adds k photons
 * to a count-only buffer (v stays NULL) and grows its capacity as fbuf_merge would, so the
 * memory budget stops the pass where one process would. */
static void vgrow(fbuf *b, uint64_t k) {
    if (b->n + k > b->cap) {
        size_t nc = b->cap ? b->cap : 1024;
        while (nc < b->n + k) nc *= 2;
        b->cap = nc;
    }
    b->n += (size_t)k;
}

typedef struct batch_count {
    uint64_t nmain, nshadow;
} batch_count;

/* The end of a partitioned pass whose nb batches stored bc[b] photons each (vm, vs: the
 * counts of the main and shadow buffers). The cut of cut_at_target, found by tracing the
 * batch that holds the target-th store again (every process does it: the same photons); then
 * this process traces again the batches that hold its part of the main buffer's stores and
 * keeps that part in `out`. Sets vm, vs and *n_e to the whole pass's figures. Every process
 * returns the same: 0, or PM_ENOMEM if any failed (one all-gather of 8 bytes). */
static int part_finish(const pass_ctx *c, batch_count *bc, size_t nb, long target, uint64_t *n_e,
                       fbuf *vm, fbuf *vs, fbuf *out, fbuf *tg, fbuf *ts, int nthreads) {
    const trace_dist *d = g_dist;
    int fail = 0;
    size_t ncut = nb;
    uint64_t dummy = 0;
    if (target > 0 && vm->n > (size_t)target) {
        uint64_t before = 0, sbefore = 0;
        size_t b = 0;
        while (b < nb && before + bc[b].nmain < (uint64_t)target) {
            before += bc[b].nmain;
            sbefore += bc[b++].nshadow;
        }
        fbuf m = {0}, sh = {0};
        fail = b == nb || dist_trace(d, c, (uint64_t)b * PT_BATCH, tg, ts, nthreads, &dummy) ||
               fbuf_merge(&m, tg, nthreads) < 0 || fbuf_merge(&sh, ts, nthreads) < 0 ||
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
        fbuf m = {0};
        fail = dist_trace(d, c, (uint64_t)b * PT_BATCH, tg, ts, nthreads, &dummy) ||
               fbuf_merge(&m, tg, nthreads) < 0 || m.n < bc[b].nmain;
        for (int t = 0; t < nthreads; t++) ts[t].n = 0;
        uint64_t i0 = lo > at ? lo - at : 0, i1 = hi - at < bc[b].nmain ? hi - at : bc[b].nmain;
        for (uint64_t i = i0; !fail && i < i1; i++) fail = fbuf_push(out, &m.v[i]) < 0;
        free(m.v);
    }
    for (uint64_t i = lo > n ? lo : n; !fail && i < hi; i++) fail = fbuf_push(out, &c->tail->v[i - n]) < 0;
    if (fail) dist_failed(d, c, 1);
    uint64_t f = (uint64_t)fail, *all = NULL;
    size_t *sizes = calloc((size_t)d->nparts, sizeof *sizes);
    if (!sizes || d->allgather(d->user, &f, sizeof f, (void **)&all, sizes) < 0) fail = 1;
    for (int p = 0; all && p < d->nparts; p++) fail |= all[p] != 0;
    free(all);
    free(sizes);
    return fail ? PM_ENOMEM : 0;
}

/* Run one pass until `target` photons are in main_buf, or until a budget stops it (see
 * PASS BUDGETS in photon_trace.h). Returns 0, PM_ENOMEM, or PM_EEMPTY (with the message in
 * err) when the pass stores nothing. */
static int run_pass(pass_ctx *c, long target, fbuf *main_buf, fbuf *shadow_buf, uint64_t *emitted,
                    uint64_t *first_specular, int *runaway, const char *title, char *err,
                    size_t errcap, size_t whole[2]) {
    const trace_opts *o = c->o;
    int nthreads = 1;
#ifdef _OPENMP
    nthreads = o->threads > 0 ? o->threads : omp_get_max_threads();
#endif
    if (nthreads > 256) nthreads = 256;
    fbuf *tg = calloc((size_t)nthreads, sizeof *tg), *ts = calloc((size_t)nthreads, sizeof *ts);
    if (!tg || !ts) {
        free(tg);
        free(ts);
        snprintf(err, errcap, "out of memory");
        return PM_ENOMEM;
    }
    /* The emission budget: max_emitted_factor x target, and at most max_emitted. */
    double limit = o->max_emitted_factor * (double)target;
    const char *limit_name = "max_emitted_factor";
    if (o->max_emitted > 0 && (double)o->max_emitted < limit) {
        limit = (double)o->max_emitted;
        limit_name = "max_emitted";
    }
    uint64_t n_e = 0, nfirst = 0;
    int rc = 0;
    const char *stop = NULL; /* the budget that stopped the pass */
    char why[256] = "";
    progress prog;
    progress_begin(&prog, title, target, o->quiet);
    size_t reported = 0;
    /* A partitioned pass keeps counts in vmain and vshadow, and each batch's in bc. */
    int part = part_pass(c);
    /* A distributed render's pilot passes (replicated or partitioned) are traced whole by
     * every process, exchanging nothing: every process plans from the evidence one process
     * sees, so the plans agree with each other and with render's. */
    int use_dist = g_dist && !c->o->pilot;
    fbuf vmain = {0}, vshadow = {0}, *out_main = main_buf;
    batch_count *bc = NULL;
    size_t nbc = 0, capbc = 0;
    if (part) {
        main_buf = &vmain;
        if (shadow_buf) shadow_buf = &vshadow;
    }
    round_buf rb = {0};
    rb.target = target;
    rb.stored = main_buf;
    rb.limit = limit;
    while ((long)main_buf->n < target && rc == 0) {
        if ((double)n_e >= limit) {
            stop = limit_name;
            snprintf(why, sizeof why, "%.0f photons emitted", limit);
            break;
        }
        /* Nothing stored after PASS_EMPTY_BATCHES batches: the lights reach no surface that
         * stores photons (they face nothing, or only mirrors and glass that never lead to a
         * diffuse surface). Any one photon that could store would have had a chance of at
         * least 1 in PASS_EMPTY_BATCHES x PT_BATCH to be seen by now. */
        if (main_buf->n == 0 && n_e >= (uint64_t)PASS_EMPTY_BATCHES * PT_BATCH) {
            stop = "nothing stored";
            break;
        }
        /* Stored so slowly that the emission budget cannot reach the target: stop now rather
         * than after the whole budget (the map keeps what was stored). */
        if (main_buf->n > 0 && n_e >= 4 * (uint64_t)PT_BATCH) {
            double need = (double)target * (double)n_e / (double)main_buf->n;
            if (need > 2 * limit) {
                stop = limit_name;
                snprintf(why, sizeof why,
                         "the target needs about %.3g photons emitted at the rate seen (%zu stored "
                         "of %llu emitted), over the budget of %.3g",
                         need, main_buf->n, (unsigned long long)n_e, limit);
                break;
            }
        }
        size_t bytes = (main_buf->cap + (shadow_buf ? shadow_buf->cap : 0)) * sizeof(fphoton);
        if (o->max_memory_bytes > 0 && bytes > o->max_memory_bytes) {
            stop = "max_memory_mb";
            snprintf(why, sizeof why, "%zu MiB of photon buffers", bytes >> 20);
            break;
        }
        int fail;
        /* The memory budget inside the batch too: one batch can store PT_BATCH times the path
         * length (a lossless furnace: 4096 x 1e5 records, 19 GB), so the check between batches
         * alone comes too late. A batch whose records would pass what is left of the budget is
         * dropped whole (its photons are not counted as emitted: the map is then that of a pass
         * that stopped before it, its powers unbiased); distributed passes split what is left
         * among a round's batches (dist_round) and stop every process together. */
        uint64_t in_batch = 0, budget = o->max_memory_bytes / sizeof(fphoton),
                 held = (uint64_t)main_buf->n + (shadow_buf ? (uint64_t)shadow_buf->n : 0);
        c->batch_cap = o->max_memory_bytes > 0 ? (budget > held ? budget - held : 1) : 0;
        c->batch_records = c->batch_cap ? &in_batch : NULL;
        if (part) {
            uint64_t cnt[2] = {0, 0};
            fail = dist_batch(c, &rb, n_e, tg, ts, nthreads, &nfirst, cnt);
            if (!fail && nbc == capbc) {
                size_t nc = capbc ? 2 * capbc : 64;
                batch_count *nv = realloc(bc, nc * sizeof *nv);
                if (nv) {
                    bc = nv;
                    capbc = nc;
                }
            }
            if (!fail && nbc < capbc) {
                bc[nbc].nmain = cnt[0];
                bc[nbc++].nshadow = cnt[1];
                vgrow(main_buf, cnt[0]);
                if (shadow_buf) vgrow(shadow_buf, cnt[1]);
            } else if (fail != 2) { /* 2: over the memory budget, below */
                fail = 1;
            }
        } else if (use_dist) {
            fail = dist_batch(c, &rb, n_e, tg, ts, nthreads, &nfirst, NULL);
        } else {
            uint64_t nf = 0;
            fail = trace_batch(c, n_e, tg, ts, nthreads, &nf);
            if (fail != 2) { /* 2: over the budget and nothing failed, below */
                nfirst += nf;
                fail &= 1;
            }
        }
        c->batch_cap = 0;
        c->batch_records = NULL;
        if (fail == 2) {
            for (int t = 0; t < nthreads; t++) tg[t].n = ts[t].n = 0;
            stop = "max_memory_mb";
            snprintf(why, sizeof why, "the next %s%d photons would store more than the %zu MiB left of %zu MiB",
                     part || use_dist ? "batches of " : "", PT_BATCH,
                     (size_t)((budget > held ? budget - held : 0) * sizeof(fphoton)) >> 20, o->max_memory_bytes >> 20);
            break;
        }
        n_e += PT_BATCH;
        /* The memory budget in records, less what the other buffer holds (the check above
         * adds both buffers' capacities). */
        size_t recs = o->max_memory_bytes / sizeof(fphoton);
        size_t cap_main = recs ? recs - (shadow_buf && shadow_buf->cap < recs ? shadow_buf->cap : 0) : 0;
        size_t cap_shadow = recs ? recs - (main_buf->cap < recs ? main_buf->cap : 0) : 0;
        if (fail || (!part && (fbuf_merge_capped(main_buf, tg, nthreads, cap_main) < 0 ||
                               (shadow_buf && fbuf_merge_capped(shadow_buf, ts, nthreads, cap_shadow) < 0)))) {
            snprintf(err, errcap, "out of memory while tracing photons (%s)", title);
            rc = PM_ENOMEM;
        }
        size_t now = main_buf->n < (size_t)target ? main_buf->n : (size_t)target;
        progress_add(&prog, (int64_t)(now - reported));
        reported = now;
    }
    progress_end(&prog);
    free(rb.all);
    free(rb.sizes);
    if (rc == 0 && part) {
        rc = part_finish(c, bc, nbc, target, &n_e, main_buf, shadow_buf, out_main, tg, ts, nthreads);
        if (rc < 0) snprintf(err, errcap, "out of memory while tracing photons (%s)", title);
    } else if (rc == 0) {
        n_e = cut_at_target(main_buf, shadow_buf, target, n_e);
    }
    free(bc);
    uint64_t cut = nfirst >> 32;
    nfirst &= 0xffffffffULL;
    /* The warnings name the scene file as render's other messages do ("render: FILE: ..."). */
    const char *file = c->s->file[0] ? c->s->file : NULL;
    if (rc == 0 && cut > 0 && !o->pilot)
        fprintf(stderr,
                "%s%s%sphoton tracing: %s: %llu photon paths were cut by the path-length budget "
                "(photon_mapping.max_bounces = %d)\n",
                file ? "render: " : "", file ? file : "", file ? ": " : "", title, (unsigned long long)cut,
                o->max_bounces);
    *runaway = rc == 0 && (long)main_buf->n < target;
    if (rc == 0 && stop && main_buf->n == 0 && strcmp(stop, "max_memory_mb") == 0) {
        snprintf(err, errcap,
                 "photon tracing: %s: no photon stored within the photon_mapping.max_memory_mb budget "
                 "(%s): raise it, or lower photon_mapping.max_bounces or render.max_depth",
                 title, why);
        rc = PM_EEMPTY;
    } else if (rc == 0 && stop && main_buf->n == 0) {
        snprintf(err, errcap,
                 "photon tracing: %s: no photon stored after %llu emitted: the lights reach no "
                 "surface that stores photons (do they face anything? are they enclosed by "
                 "mirrors or glass only?)%s%s",
                 title, (unsigned long long)n_e, why[0] ? "; stopped by " : "",
                 why[0] ? limit_name : "");
        rc = PM_EEMPTY;
    } else if (*runaway && !o->pilot) {
        /* The figures of the whole map: with a joining pilot's stores and photons. */
        size_t tn = c->tail ? c->tail->n : 0;
        char with[96] = "";
        if (c->tail)
            snprintf(with, sizeof with, " (the pilot's %zu stores and %llu photons included)", tn,
                     (unsigned long long)c->tail_emitted);
        fprintf(stderr,
                "%s%s%sphoton tracing: %s: only %zu of %ld photons stored after %llu emitted%s; stopped by "
                "the photon_mapping.%s budget (%s)\n",
                file ? "render: " : "", file ? file : "", file ? ": " : "", title, main_buf->n + tn,
                target + (long)tn, (unsigned long long)(n_e + c->tail_emitted), with, stop ? stop : "?", why);
    }
    *emitted = n_e;
    whole[0] = main_buf->n; /* the whole pass's counts (a partitioned pass keeps a part) */
    whole[1] = shadow_buf ? shadow_buf->n : 0;
    if (first_specular) *first_specular = nfirst;
    for (int t = 0; t < nthreads; t++) {
        free(tg[t].v);
        free(ts[t].v);
    }
    free(tg);
    free(ts);
    return rc;
}

/* The projection cells per side a pass with options o aims its caustic photons by (0: none). */
static int projection_cells(const trace_opts *o) {
    return o->projection ? (o->projection_cells > 0 ? o->projection_cells : 64) : 0;
}

int pilot_photons_joining(const pilot_photons *k, const trace_opts *o, int caustic, size_t *stores,
                          uint64_t *emitted, const char **why) {
    const char *w = NULL;
    size_t n = 0;
    uint64_t ne = 0;
    if (!k || !(caustic ? k->c_emitted : k->emitted))
        w = "";
    else if (o->pilot)
        w = "a pilot pass joins no pilot";
    else if (!caustic) {
        n = o->global ? k->g.n : k->s.n;
        ne = k->emitted;
        if (!(o->global || o->shadow) || o->global_target <= 0)
            w = "no global pass";
        else if (k->max_depth != o->max_depth || k->max_bounces != o->max_bounces)
            w = "the pilot was traced with another max_depth or max_bounces";
        else if (k->imp != o->importance)
            w = "the pilot's photons were weighed for another importance table";
        else if ((o->global && !k->global) || (o->shadow && !k->shadow))
            w = "the pilot did not trace the maps the pass builds";
        /* A pilot that stored half the target or more does not join (a lossless furnace
         * stores hundreds of records per photon): the pass keeps its stored-count bound. */
        else if (2 * (double)n > (double)o->global_target)
            w = "the pilot stored half the target or more";
    } else {
        n = k->c.n;
        ne = k->c_emitted;
        if (!o->caustic || o->caustic_target <= 0)
            w = "no caustic pass";
        else if (k->c_max_depth != o->max_depth || k->c_max_bounces != o->max_bounces)
            w = "the pilot was traced with another max_depth or max_bounces";
        else if (k->c_cells != projection_cells(o))
            w = "the pass aims by other projection maps than the pilot (projection, projection_cells)";
        else if (2 * (double)n > (double)o->caustic_target)
            w = "the pilot stored half the target or more";
    }
    if (why) *why = w ? w : "";
    if (stores) *stores = w ? 0 : n;
    if (emitted) *emitted = w ? 0 : ne;
    return !w;
}

void trace_opts_settings(trace_opts *o, const scene *s, const photon_settings *c) {
    trace_opts_init(o, s);
    o->global_target = c->global_photons;
    o->caustic_target = c->caustic_photons;
    o->max_emitted_factor = c->max_emitted_factor;
    o->max_emitted = c->max_emitted;
    o->max_memory_bytes = (size_t)c->max_memory_mb << 20;
    o->max_bounces = c->max_bounces;
    o->projection = c->projection;
    o->projection_cells = c->projection_cells;
    o->quiet = !c->progress;
}

void trace_opts_init(trace_opts *o, const scene *s) {
    memset(o, 0, sizeof *o);
    o->seed = s->settings.seed;
    o->max_depth = s->settings.max_depth;
    o->max_emitted_factor = 64;
    o->max_emitted = PASS_MAX_EMITTED;
    o->max_memory_bytes = (size_t)PASS_MAX_MEMORY_MB << 20;
    o->max_bounces = PASS_MAX_BOUNCES;
    o->projection = 1;
    o->projection_cells = 64;
}

static void shifts(double *shift, uint64_t seed, uint64_t pass) {
    rng g = rng_stream(seed, 0xffffffffffULL, pass);
    for (int d = 0; d < 6; d++) shift[d] = rng_uniform(&g);
}

/* After a partitioned pass: the whole maps' counts (wg: the global pass's main and shadow
 * buffers, wc: the caustic pass's) and their largest photon powers, the largest of every
 * part's (an all-gather of 16 bytes per process), so the radius policy reads the figures of
 * the whole maps exactly. */
static int part_whole(const trace_opts *o, photon_maps *m, const size_t wg[2], const size_t wc[2]) {
    const trace_dist *d = g_dist;
    m->part = 1;
    m->whole_global = o->global ? wg[0] : 0;
    m->whole_shadow = o->global ? wg[1] : wg[0];
    m->whole_caustic = wc[0];
    double mine[2] = {pm_photons_max_power(m->global, m->nglobal),
                      pm_photons_max_power(m->caustic, m->ncaustic)},
           *all = NULL;
    size_t *sizes = calloc((size_t)d->nparts, sizeof *sizes);
    int rc = !sizes || d->allgather(d->user, mine, sizeof mine, (void **)&all, sizes) < 0 ? PM_ENOMEM : 0;
    for (int p = 0; rc == 0 && p < d->nparts; p++)
        for (int k = 0; k < 2; k++)
            if (p == 0 || all[2 * p + k] > m->whole_max_power[k]) m->whole_max_power[k] = all[2 * p + k];
    free(all);
    free(sizes);
    return rc;
}

/* Append the kept pilot photons of from to b (after the pass's own, which were cut already). */
static int join(fbuf *b, const fbuf *from) {
    for (size_t k = 0; k < from->n; k++)
        if (fbuf_push(b, &from->v[k]) < 0) return PM_ENOMEM;
    return 0;
}

void pilot_photons_free(pilot_photons *k) {
    if (!k) return;
    free(k->g.v);
    free(k->s.v);
    free(k->c.v);
    free(k);
}

int photon_trace(const scene *s, const trace_opts *o, photon_maps *m, char *err, size_t errcap) {
    memset(m, 0, sizeof *m);
    if (errcap) err[0] = 0;
    int st_emit_g = stats_register("Photons/Emitted, global pass");
    int st_emit_c = stats_register("Photons/Emitted, caustic pass");
    int st_glob = stats_register("Photons/Global photons stored");
    int st_caus = stats_register("Photons/Caustic photons stored");
    int st_shadow = stats_register("Photons/Shadow-map photons stored (direct + shadow)");
    int st_saved = stats_register("Photons/Caustic emissions saved by the projection map");
    int st_first = stats_register("Photons/Caustic-pass photons whose first hit is specular");
    int st_imp_paths = stats_register("Photons/Importance: camera paths");
    int st_imp_unocc = stats_register("Photons/Importance: light connections carrying light");
    int st_imp_cells = stats_register("Photons/Importance: emission cells with importance (finest level)");
    int st_reused = stats_register("Photons/Pilot photons reused in the global maps (emitted)");
    int st_reused_c = stats_register("Photons/Pilot photons reused in the caustic map (emitted)");
    int st_reused_cs = stats_register("Photons/Pilot photons reused in the caustic map (stored)");
    int nl = s->nlights;
    if (nl == 0 || s->light_distrib.n == 0) return 0;
    /* The plan's pilot photons join this pass's maps when they were traced by the same rules
     * and stored less than half the target (PILOT PHOTONS in photon_trace.h): rk for the
     * global pass, rkc for the caustic pass. */
    const pilot_photons *rk = pilot_photons_joining(o->reuse, o, 0, NULL, NULL, NULL) ? o->reuse : NULL;
    const pilot_photons *rkc = pilot_photons_joining(o->reuse, o, 1, NULL, NULL, NULL) ? o->reuse : NULL;
    int rc = 0;
    rgb *scale = calloc((size_t)nl, sizeof *scale);
    double *w = calloc((size_t)nl, sizeof *w);
    if (!scale || !w) {
        free(scale);
        free(w);
        snprintf(err, errcap, "out of memory");
        return PM_ENOMEM;
    }
    fbuf gbuf = {0}, sbuf = {0}, cbuf = {0};
    size_t wg[2] = {0, 0}, wc[2] = {0, 0}; /* whole counts: global pass (main, shadow), caustic */

    /* Global pass (also carries the shadow photons). */
    if ((o->global || o->shadow) && o->global_target > 0) {
        pass_ctx c = {0};
        c.s = s;
        c.o = o;
        c.want_global = o->global;
        c.want_shadow = o->shadow;
        c.choose = s->light_distrib;
        for (int i = 0; i < nl; i++) {
            double pl = distrib1d_prob(&s->light_distrib, i);
            scale[i] = pl > 0 ? v3_scale(s->lights[i].power, 1.0 / pl) : v3s(0);
        }
        c.light_scale = scale;
        shifts(c.shift, o->seed, 1);
        /* Importance-driven emission (importance.h): the plan's table of where the camera
         * sees light; the pass emits toward it, its photons' powers divided by the steering. */
        if (o->importance && o->importance->on && o->pilot) { /* photons that may join: rel */
            c.imp = o->importance;
            c.imp_rel_only = 1;
        }
        if (o->importance && o->importance->on && !o->pilot) {
            c.imp = o->importance;
            stat_add(st_imp_paths, (uint64_t)c.imp->paths);
            stat_add(st_imp_unocc, c.imp->contributing);
            stat_add(st_imp_cells, c.imp->lv[0].ncells);
        }
        /* With the global map off, the shadow map's count is the target. The pilot's stores,
         * when they join, count toward it. */
        long target = o->global_target;
        c.tail = rk ? (o->global ? &rk->g : &rk->s) : NULL;
        c.tail_emitted = rk ? rk->emitted : 0;
        if (rk) {
            size_t have = o->global ? rk->g.n : rk->s.n;
            target = (long)have < target ? target - (long)have : 1;
        }
        rc = run_pass(&c, target, o->global ? &gbuf : &sbuf, o->global ? &sbuf : NULL,
                      &m->global_emitted, NULL, &m->global_runaway,
                      o->global ? "Tracing global photons" : "Tracing shadow photons", err, errcap,
                      wg);
        if (!o->pilot) stat_add(st_emit_g, m->global_emitted);
    }

    /* Caustic pass. */
    projmap *proj = NULL;
    int G = projection_cells(o);
    uint64_t c_own = 0; /* photons the caustic pass itself emitted (without a joining pilot's) */
    if (rc == 0 && o->caustic && o->caustic_target > 0) {
        rc = projmap_build_all(s, G, &proj);
        double wsum = 0, psum = 0;
        for (int i = 0; rc == 0 && i < nl; i++) {
            const light *l = &s->lights[i];
            double pw = (l->power.x + l->power.y + l->power.z) / 3;
            w[i] = pw * proj[i].fraction;
            wsum += w[i];
            psum += pw;
        }
        if (rc == 0 && wsum > 0) {
            pass_ctx c = {0};
            c.s = s;
            c.o = o;
            c.caustic_pass = 1;
            c.proj = proj;
            rc = distrib1d_init(&c.choose, w, nl);
            for (int i = 0; rc == 0 && i < nl; i++) {
                double pl = distrib1d_prob(&c.choose, i);
                /* Eq. 2.2: only the fraction f of the directions is sampled. */
                scale[i] = pl > 0 ? v3_scale(s->lights[i].power, proj[i].fraction / pl) : v3s(0);
            }
            c.light_scale = scale;
            shifts(c.shift, o->seed, 2);
            /* The pilot's stores, when they join, count toward the target (as in the global
             * pass); its photons count as emitted, and its first-specular ones too. */
            long target = o->caustic_target;
            c.tail = rkc ? &rkc->c : NULL;
            c.tail_emitted = rkc ? rkc->c_emitted : 0;
            if (rkc) target = (long)rkc->c.n < target ? target - (long)rkc->c.n : 1;
            if (rc == 0)
                rc = run_pass(&c, target, &cbuf, NULL, &m->caustic_emitted, &m->caustic_first_specular,
                              &m->caustic_runaway, "Tracing caustic photons", err, errcap, wc);
            c_own = m->caustic_emitted;
            if (rc == 0 && rkc) {
                m->caustic_emitted += rkc->c_emitted;
                m->caustic_first_specular += rkc->c_first_specular;
            }
            distrib1d_free(&c.choose);
            m->caustic_fraction = wsum / psum;
            if (m->caustic_fraction > 0)
                m->caustic_saved =
                    (uint64_t)((double)m->caustic_emitted * (1.0 / m->caustic_fraction - 1.0) + 0.5);
            if (!o->pilot) stat_add(st_emit_c, m->caustic_emitted);
            if (!o->pilot) stat_add(st_saved, m->caustic_saved);
            if (!o->pilot) stat_add(st_first, m->caustic_first_specular);
        }
        if (rc == PM_ENOMEM && !err[0]) snprintf(err, errcap, "out of memory");
        projmap_free_all(proj, nl);
    }

    if (rc == 0 && m->global_emitted) {
        double nm = (double)m->global_emitted, np = 0;
        if (rk) { /* the pilot's photons join the maps (PILOT PHOTONS in photon_trace.h); a
                   * partitioned pass's part has its share already (part_finish) */
            int part = g_dist && g_dist->partitioned;
            if (!part) rc = join(o->global ? &gbuf : &sbuf, o->global ? &rk->g : &rk->s);
            if (rc == 0 && !part && o->global && o->shadow) rc = join(&sbuf, &rk->s);
            if (part) {
                wg[0] += o->global ? rk->g.n : rk->s.n;
                if (o->global && o->shadow) wg[1] += rk->s.n; /* as the join above */
            }
            np = (double)rk->emitted;
            m->global_emitted += rk->emitted;
            m->pilot_emitted[0] = rk->emitted;
            m->pilot_stored[0] = o->global ? rk->g.n : rk->s.n;
            if (!o->pilot) stat_add(st_reused, rk->emitted);
        }
        if (rc == 0 && o->global) rc = pack(&gbuf, np, nm, &m->global, &m->nglobal);
        if (rc == 0 && o->shadow) rc = pack(&sbuf, np, nm, &m->shadow, &m->nshadow);
    }
    if (rc == 0 && m->caustic_emitted) {
        double np = 0;
        if (rkc) { /* as the global pass's join above */
            int part = g_dist && g_dist->partitioned;
            if (!part) rc = join(&cbuf, &rkc->c);
            else wc[0] += rkc->c.n;
            np = (double)rkc->c_emitted;
            m->pilot_emitted[1] = rkc->c_emitted;
            m->pilot_stored[1] = rkc->c.n;
            stat_add(st_reused_c, rkc->c_emitted);
            stat_add(st_reused_cs, rkc->c.n);
        }
        if (rc == 0) rc = pack(&cbuf, np, (double)c_own, &m->caustic, &m->ncaustic);
    }
    /* A pilot keeping its stores for the real passes: its buffers, before packing (kept, or
     * added to the kept photons of another pilot call). */
    if (rc == 0 && o->pilot && o->pilot->keep && (m->global_emitted || m->caustic_emitted)) {
        pilot_photons *k = o->pilot->kept ? o->pilot->kept : calloc(1, sizeof *k);
        if (k && m->global_emitted) {
            free(k->g.v);
            free(k->s.v);
            k->g = gbuf;
            k->s = sbuf;
            gbuf.v = sbuf.v = NULL;
            k->emitted = m->global_emitted;
            k->max_depth = o->max_depth;
            k->max_bounces = o->max_bounces;
            k->imp = o->importance;
            k->global = o->global;
            k->shadow = o->shadow;
        }
        if (k && m->caustic_emitted) {
            free(k->c.v);
            k->c = cbuf;
            cbuf.v = NULL;
            k->c_emitted = m->caustic_emitted;
            k->c_first_specular = m->caustic_first_specular;
            k->c_max_depth = o->max_depth;
            k->c_max_bounces = o->max_bounces;
            k->c_cells = G;
        }
        o->pilot->kept = k;
    }
    if (rc == 0 && g_dist && g_dist->partitioned && !o->pilot) rc = part_whole(o, m, wg, wc);
    if (rc < 0 && !err[0]) snprintf(err, errcap, "%s", pm_strerror(rc));
    if (!o->pilot) stat_add(st_glob, m->part ? m->whole_global : m->nglobal);
    if (!o->pilot) stat_add(st_caus, m->part ? m->whole_caustic : m->ncaustic);
    if (!o->pilot) stat_add(st_shadow, m->part ? m->whole_shadow : m->nshadow);
    free(gbuf.v);
    free(sbuf.v);
    free(cbuf.v);
    free(scale);
    free(w);
    if (rc < 0) photon_maps_free(m);
    return rc;
}
