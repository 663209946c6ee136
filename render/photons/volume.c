/* volume.c: photon tracing through participating media for the volume photon maps and the
 * surface maps of a scene with media; see volume.h. Each photon is traced by photon_walk
 * (photon_walk.c, the surfaces' tracer's walk too: free flight in the current medium, a volume
 * store and an HG bounce at each scattering event, a surface store and a material bounce at
 * each diffuse surface, a medium change at each null surface) into its batch's buffer;
 * vol_trace_pass runs rounds of batches on the threads and merges them in photon order,
 * cutting each map at its target by whole photon paths. What the pass shares with the
 * surfaces' tracer, photon_trace.c, is photon_pass.h's (the walk, the records, the caustic
 * pass's aim, the distributed exchange, the budgets' messages).
 *
 * A change here that changes any stored photon (which photons are stored, their power,
 * position, direction or kind) must bump PHOTON_TRACE_VERSION in photon_maps.h in the same
 * commit, so maps saved before it are refused (photon_maps.h TRACER VERSION).
 */
#include "photons/volume.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#endif

#include "photonmap/common.h"
#include "photons/photon_pass.h"
#include "photons/photon_trace.h"

/* Records are photon_pass.h's pass_rec, before the power is divided by the map's emitted
 * count: a volume photon's has its medium, a surface photon's medium -1. The memory budget
 * counts each as VOL_RECORD_BYTES (volume.h). */

typedef struct vbuf {
    pass_buf b;      /* the batch's records */
    walk_out w;      /* the walks' sink (photon_pass.h): b, the budget's share w.max_n in
                        records, w.over (past it: the photon being traced is not whole), w.fail */
    vol_pilot pilot; /* this batch's counts */
    uint64_t stop;   /* w.over: the first photon not traced whole; else UINT64_MAX */
    uint64_t cut;    /* photons cut by the path-length budget */
} vbuf;

static void pilot_add(vol_pilot *a, const vol_pilot *b) {
    a->emitted += b->emitted;
    for (int m = 0; m < VOL_PILOT_MEDIA; m++)
        for (int k = 0; k < 4; k++) a->events[m][k] += b->events[m][k];
    for (int k = 0; k < VOL_PILOT_MATS; k++) a->caustic_by_mat[k] += b->caustic_by_mat[k];
    a->surf_direct += b->surf_direct;
    a->surf_caustic += b->surf_caustic;
    a->surf_indirect += b->surf_indirect;
    a->surf_after_scatter += b->surf_after_scatter;
}

/* One map being filled: its records in photon order, and where it was cut. */
typedef struct vmap {
    int keep;
    long target;
    pass_rec *r;
    size_t n, cap;
    uint64_t cut; /* photons [0, cut) kept; UINT64_MAX: not cut yet */
} vmap;

static int vmap_take(vmap *m, const pass_rec *v) {
    if (!m->keep || v->index >= m->cut) return 0;
    if (m->n == m->cap) {
        size_t nc = m->cap ? 2 * m->cap : 4096;
        pass_rec *nr = realloc(m->r, nc * sizeof *nr);
        if (!nr) return PM_ENOMEM;
        m->r = nr;
        m->cap = nc;
    }
    m->r[m->n++] = *v;
    if (m->cut == UINT64_MAX && (long)m->n >= m->target) m->cut = v->index + 1;
    return 0;
}

/* The records as pm_photons with the power divided by the map's emitted count. */
static int vmap_finish(vmap *m, uint64_t emitted, pm_photon **out, short **med, size_t *n, uint64_t *ne) {
    *out = NULL;
    *n = 0;
    *ne = m->cut == UINT64_MAX ? emitted : m->cut;
    if (!m->keep || m->n == 0) return 0;
    pm_photon *ph = malloc(m->n * sizeof *ph);
    if (!ph) return PM_ENOMEM;
    if (med) {
        if (!(*med = malloc(m->n * sizeof **med))) {
            free(ph);
            return PM_ENOMEM;
        }
        for (size_t k = 0; k < m->n; k++) (*med)[k] = m->r[k].medium;
    }
    float sc = (float)(1.0 / (double)*ne);
    for (size_t k = 0; k < m->n; k++) {
        const pass_rec *v = &m->r[k];
        float pw[3] = {v->power[0] * sc, v->power[1] * sc, v->power[2] * sc};
        pm_photon_init(&ph[k], v->pos, pw, v->dir, v->medium < 0 ? v->normal : NULL, v->kind);
    }
    *out = ph;
    *n = m->n;
    return 0;
}

void vol_pass_free(vol_pass_result *r) {
    free(r->surface);
    free(r->volume);
    free(r->volume_medium);
    memset(r, 0, sizeof *r);
}

/* ---- distributed passes (volume.h; render/mpi/) ---------------------------------------------- */

/* Per thread: render-mpi sets it on the thread that runs the passes; a test runs several parts
 * in threads of one process. */
static _Thread_local const trace_dist *g_vdist;

void vol_set_dist(const struct trace_dist *d) { g_vdist = d; }

/* One batch as exchanged: this head, then n records. */
typedef struct vbatch_head {
    uint64_t n, cap, stop, cut;
    int32_t fail, over, b, pad;
    vol_pilot pilot;
} vbatch_head;

/* After this process traced its batches of the round (b % nparts == part): every process gets
 * every batch of the round into bufs[0..nb-1], each buffer's capacity set to the tracing
 * process's so the memory budget sees one process's buffers. 0, or PM_ENOMEM (a batch that
 * failed anywhere is sent as failed, so that case is seen by every process). */
static int vol_exchange(vbuf *bufs, int nb) {
    const trace_dist *d = g_vdist;
    size_t bytes = 0;
    int mine = 0;
    for (int b = d->part; b < nb; b += d->nparts) {
        bytes += sizeof(vbatch_head) + bufs[b].b.n * sizeof(pass_rec);
        mine++;
    }
    char *out = malloc(bytes ? bytes : 1);
    vbatch_head failed[VOL_ROUND];
    size_t off = 0;
    int own_fail = !out;
    for (int b = d->part, j = 0; b < nb; b += d->nparts, j++) {
        vbuf *bf = &bufs[b];
        if (d->test_fail && d->test_fail(d->user)) bf->w.fail = 1; /* test hook (photon_trace.h) */
        own_fail |= bf->w.fail;
        vbatch_head h;
        memset(&h, 0, sizeof h);
        h.n = out ? bf->b.n : 0;
        h.cap = bf->b.cap;
        h.stop = bf->stop;
        h.cut = bf->cut;
        h.fail = bf->w.fail || !out;
        h.over = bf->w.over;
        h.b = b;
        h.pilot = bf->pilot;
        failed[j] = h;
        if (!out) continue;
        memcpy(out + off, &h, sizeof h);
        off += sizeof h;
        if (bf->b.n) memcpy(out + off, bf->b.v, bf->b.n * sizeof(pass_rec));
        off += bf->b.n * sizeof(pass_rec);
    }
    /* This process's own failure: said before the exchange tells every process of it. */
    if (own_fail && d->failed)
        d->failed(d->user, "out of memory while tracing photons (a pass of the media)");
    size_t *sizes = NULL;
    char *all = NULL;
    int rc = out ? pass_allgather(d, out, off, (void **)&all, &sizes)
                 : pass_allgather(d, failed, (size_t)mine * sizeof *failed, (void **)&all, &sizes);
    free(out);
    if (rc < 0) {
        free(sizes);
        free(all);
        return PM_ENOMEM;
    }
    off = 0;
    rc = 0;
    for (int p = 0; p < d->nparts; p++) {
        size_t end = off + sizes[p];
        while (off < end) {
            vbatch_head h;
            memcpy(&h, all + off, sizeof h);
            off += sizeof h;
            vbuf *bf = &bufs[h.b];
            if (h.cap != bf->b.cap) { /* the tracing process's capacity */
                pass_rec *nr = realloc(bf->b.v, (h.cap ? h.cap : 1) * sizeof *nr);
                if (!nr) rc = PM_ENOMEM;
                else {
                    bf->b.v = nr;
                    bf->b.cap = h.cap;
                }
            }
            bf->b.n = rc == 0 ? h.n : 0;
            if (bf->b.n) memcpy(bf->b.v, all + off, h.n * sizeof(pass_rec));
            off += h.n * sizeof(pass_rec);
            bf->stop = h.stop;
            bf->cut = h.cut;
            bf->w.fail = h.fail || rc < 0;
            bf->w.over = h.over;
            bf->pilot = h.pilot;
        }
    }
    free(sizes);
    free(all);
    return rc;
}

/* A pass while it runs: vol_trace_pass's state, shared by its steps. */
typedef struct vpass {
    const vol_pass_opts *o;
    trace_opts to; /* the walk's rules: seed, max_depth, max_bounces */
    pass_ctx c;    /* the walk's pass (photon_pass.h, a media pass) */
    pass_aim aim;  /* a caustic pass with projection maps: the aim (c.proj, c.choose) */
    int counting;  /* a pilot: count, keep nothing */
    vmap ms, mv; /* the surface and volume maps */
    vbuf bufs[VOL_ROUND];
    int nthreads;
    uint64_t emitted, max_emitted, cut;
    const trace_dist *dist; /* a distributed pass (vol_set_dist), or NULL */
    const char *stop;       /* the budget that stopped the pass (NULL: none) */
    char why[160];          /* and what it saw */
} vpass;

/* One round of VOL_ROUND batches on the threads (each batch in its own buffer), exchanged in a
 * distributed pass, and merged into the maps in photon order. 0: go on; 1: a budget stopped
 * the pass (p->stop); PM_ENOMEM. */
static int vol_round(vpass *p) {
    const vol_pass_opts *o = p->o;
    vbuf *bufs = p->bufs;
    uint64_t start = p->emitted, max_emitted = p->max_emitted;
    int nb = VOL_ROUND, rc = 0;
    /* The memory budget (max_memory_bytes): the maps' buffers between rounds, and within a
     * round each batch's buffer at most its share of what the maps leave, so the stop is
     * the same for any thread count. */
    size_t held = (p->ms.cap + p->mv.cap) * VOL_RECORD_BYTES, room = SIZE_MAX;
    for (int b = 0; b < nb; b++) held += bufs[b].b.cap * VOL_RECORD_BYTES;
    if (o->max_memory_bytes > 0 && !p->counting) {
        if (held > o->max_memory_bytes) {
            p->stop = "photon_mapping.max_memory_mb budget";
            snprintf(p->why, sizeof p->why, "%.2f MiB of photon buffers", (double)held / (1 << 20));
            return 1;
        }
        room = (o->max_memory_bytes - (p->ms.cap + p->mv.cap) * VOL_RECORD_BYTES) / VOL_ROUND / VOL_RECORD_BYTES;
    }
    const trace_dist *dist = p->dist;
    const pass_ctx *c = &p->c;
#ifdef _OPENMP
#pragma omp parallel for num_threads(p->nthreads) schedule(dynamic, 1)
#endif
    for (int b = 0; b < nb; b++) {
        vbuf *bf = &bufs[b];
        /* A distributed pass (vol_set_dist): another process traces this batch. */
        if (dist && b % dist->nparts != dist->part) continue;
        bf->b.n = 0;
        bf->w.gb = bf->w.sb = &bf->b;
        bf->w.vp = &bf->pilot;
        bf->w.over = 0;
        bf->stop = UINT64_MAX;
        bf->cut = 0;
        bf->w.max_n = room;
        memset(&bf->pilot, 0, sizeof bf->pilot);
        uint64_t lo = start + (uint64_t)b * VOL_BATCH, hi = lo + VOL_BATCH;
        if (hi > max_emitted) hi = max_emitted;
        for (uint64_t i = lo; i < hi && !bf->w.over && !bf->w.fail; i++) {
            bf->w.first_specular = 0;
            photon_walk(c, i, &bf->w);
            if (bf->w.first_specular & 2) bf->cut++; /* the path-length budget cut it */
            if (bf->w.over) { /* photon i is not whole: drop its records, end the batch here */
                while (bf->b.n > 0 && bf->b.v[bf->b.n - 1].index == i) bf->b.n--;
                bf->stop = i;
            }
        }
    }
    if (dist && vol_exchange(bufs, nb) < 0) return PM_ENOMEM;
    uint64_t end = start + (uint64_t)nb * VOL_BATCH;
    for (int b = 0; b < nb && rc == 0; b++) {
        if (bufs[b].w.fail) rc = PM_ENOMEM;
        if (o->pilot) pilot_add(o->pilot, &bufs[b].pilot);
        p->cut += bufs[b].cut;
        for (size_t k = 0; k < bufs[b].b.n && rc == 0; k++) {
            const pass_rec *v = &bufs[b].b.v[k];
            rc = vmap_take(v->medium < 0 ? &p->ms : &p->mv, v);
        }
        if (bufs[b].w.over) { /* the photons before it are whole; none after it counts */
            end = bufs[b].stop;
            p->stop = "photon_mapping.max_memory_mb budget";
            snprintf(p->why, sizeof p->why, "a batch of photons outgrew its share of the budget, "
                     "%.2f MiB, at photon %llu", (double)(room * VOL_RECORD_BYTES) / (1 << 20),
                     (unsigned long long)bufs[b].stop);
            break;
        }
    }
    if (rc < 0) return rc;
    p->emitted = end < max_emitted ? end : max_emitted;
    if (p->stop) return 1;
    /* A map that stored nothing in its first VOL_EMPTY_PHOTONS photons stays empty. */
    if (p->emitted >= VOL_EMPTY_PHOTONS) {
        if (p->ms.cut == UINT64_MAX && p->ms.n == 0) p->ms.cut = p->emitted;
        if (p->mv.cut == UINT64_MAX && p->mv.n == 0) p->mv.cut = p->emitted;
    }
    return 0;
}

/* The pass's end: its messages (BUDGETS in volume.h), PM_EEMPTY for a pass that stored
 * nothing, else rc. */
static int vol_report(vpass *p, vol_pass_result *res, int rc) {
    const vol_pass_opts *o = p->o;
    const char *title_s = o->caustic_pass ? "Tracing caustic photons" : "Tracing global photons";
    const char *title_v = o->caustic_pass ? "Tracing volume-caustic photons" : "Tracing volume photons";
    res->emitted = p->emitted;
    res->cut = p->cut;
    res->surface_short = p->ms.keep && p->ms.cut == UINT64_MAX;
    res->volume_short = p->mv.keep && p->mv.cut == UINT64_MAX;
    if (!p->stop && p->emitted >= p->max_emitted) {
        p->stop = o->max_emitted_budget ? o->max_emitted_budget : "photon_mapping.max_emitted budget";
        snprintf(p->why, sizeof p->why, "%llu photons emitted", (unsigned long long)p->max_emitted);
    }
    if (rc != 0 || o->pilot) return rc;
    if (p->cut > 0) pass_say_cut(NULL, p->c.keep_volume ? title_v : title_s, p->cut, o->max_bounces);
    if ((p->ms.keep || p->mv.keep) && p->ms.n == 0 && p->mv.n == 0) {
        char stopped[96];
        snprintf(stopped, sizeof stopped, "the %s", p->stop ? p->stop : "");
        pass_say_empty(res->msg, sizeof res->msg, p->mv.keep ? title_v : title_s, p->emitted, "surface or medium",
                       p->stop ? stopped : NULL);
        return PM_EEMPTY;
    }
    const char *budget = p->stop ? p->stop : "?";
    if (res->surface_short) pass_say_short(NULL, title_s, p->ms.n, p->ms.target, p->emitted, "", budget, p->why);
    if (res->volume_short) pass_say_short(NULL, title_v, p->mv.n, p->mv.target, p->emitted, "", budget, p->why);
    return 0;
}

int vol_trace_pass(const scene *s, const vol_pass_opts *o, vol_pass_result *res) {
    memset(res, 0, sizeof *res);
    if (s->nlights == 0 || s->light_distrib.n == 0) return PM_EINVAL;
    if (!(o->max_emitted >= 1) || o->max_depth < 0 || o->surface_target < 0 || o->volume_target < 0 ||
        o->max_bounces < 0)
        return PM_EINVAL;
    vpass *p = calloc(1, sizeof *p);
    if (!p) return PM_ENOMEM;
    p->o = o;
    p->to.seed = o->seed;
    p->to.max_depth = o->max_depth;
    p->to.max_bounces = o->max_bounces;
    pass_ctx *c = &p->c;
    c->s = s;
    c->o = &p->to;
    c->media = 1;
    c->caustic_pass = o->caustic_pass;
    c->want_global = o->surface_target > 0 && !o->pilot;
    c->keep_volume = o->volume_target > 0 && !o->pilot;
    c->lo = o->lo;
    c->hi = o->hi;
    c->choose = s->light_distrib;
    p->counting = o->pilot != NULL;
    if (o->caustic_pass && o->projection_cells > 0) {
        int rc0 = pass_aim_build(s, o->projection_cells, &p->aim);
        if (rc0 < 0 || !p->aim.chosen) { /* no light faces a specular object: nothing to aim at */
            pass_aim_free(&p->aim);
            free(p);
            return rc0 == PM_ENOMEM ? rc0 : 0; /* empty maps: nothing can reach a specular object */
        }
        c->proj = p->aim.proj;
        c->choose = p->aim.choose;
    }
    vmap ms = {c->want_global, o->surface_target, NULL, 0, 0, c->want_global ? UINT64_MAX : 0};
    vmap mv = {c->keep_volume, o->volume_target, NULL, 0, 0, c->keep_volume ? UINT64_MAX : 0};
    p->ms = ms;
    p->mv = mv;
    p->nthreads = 1;
#ifdef _OPENMP
    p->nthreads = o->threads > 0 ? o->threads : omp_get_max_threads();
#endif
    p->max_emitted = (uint64_t)o->max_emitted;
    p->dist = g_vdist && !o->pilot ? g_vdist : NULL;
    int rc = 0;
    while (p->emitted < p->max_emitted && (p->counting || p->ms.cut == UINT64_MAX || p->mv.cut == UINT64_MAX)) {
        rc = vol_round(p);
        if (rc != 0) break;
    }
    if (rc > 0) rc = 0;
    for (int b = 0; b < VOL_ROUND; b++) free(p->bufs[b].b.v);
    pass_aim_free(&p->aim);
    rc = vol_report(p, res, rc);
    if (rc == 0) rc = vmap_finish(&p->ms, p->emitted, &res->surface, NULL, &res->nsurface, &res->surface_emitted);
    if (rc == 0)
        rc = vmap_finish(&p->mv, p->emitted, &res->volume, &res->volume_medium, &res->nvolume, &res->volume_emitted);
    free(p->ms.r);
    free(p->mv.r);
    free(p);
    if (rc < 0) {
        char msg[sizeof res->msg];
        memcpy(msg, res->msg, sizeof msg);
        vol_pass_free(res);
        memcpy(res->msg, msg, sizeof msg);
    }
    return rc;
}

int vol_trace(const scene *s, uint64_t n, uint64_t seed, int max_depth, vol_photons *out) {
    out->photons = NULL;
    out->count = out->cap = 0;
    vol_pass_opts o = {0};
    o.lo = v3s(1);
    o.hi = v3s(-1); /* no limit */
    o.volume_target = (long)(n * (uint64_t)max_depth + n + 1); /* never reached: keep all */
    o.max_emitted = (double)n;
    o.max_depth = max_depth;
    o.seed = seed;
    vol_pass_result r;
    int rc = vol_trace_pass(s, &o, &r);
    if (rc < 0) return rc;
    out->photons = r.volume;
    out->count = out->cap = r.nvolume;
    r.volume = NULL;
    vol_pass_free(&r);
    return 0;
}
