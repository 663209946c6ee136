/* volume.c: photon tracing through participating media for the volume photon maps and the
 * surface maps of a scene with media; see volume.h. trace_photon follows one photon (free
 * flight in the current medium, a volume store and an HG bounce at each scattering event, a
 * surface store and a material bounce at each diffuse surface, a medium change at each null
 * surface) into its batch's buffer; vol_trace_pass runs rounds of batches on the threads and
 * merges them in photon order, cutting each map at its target by whole photon paths.
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

#include "scene/medium.h"
#include "photons/photon_trace.h"
#include "photonmap/common.h"
#include "photons/projmap.h"
#include "base/rng.h"

enum { WHERE_SURFACE, WHERE_VOLUME };

/* A stored photon before the power is divided by the map's emitted count. */
typedef struct vrec {
    uint64_t index; /* photon index in the pass */
    float pos[3], power[3], dir[3], nrm[3];
    int kind, where, med;
} vrec;

_Static_assert(sizeof(vrec) == VOL_RECORD_BYTES, "VOL_RECORD_BYTES in volume.h");

typedef struct vbuf {
    vrec *r;
    size_t n, cap;
    size_t max_n;    /* the memory budget's share of this batch, in records */
    vol_pilot pilot; /* this batch's counts */
    int fail, over;  /* out of memory; over max_n (the photon being traced is not whole) */
    uint64_t stop;   /* over: the first photon not traced whole; else UINT64_MAX */
    uint64_t cut;    /* photons cut by the path-length budget */
} vbuf;

typedef struct vctx {
    const scene *s;
    const vol_pass_opts *o;
    int keep_surface, keep_volume, counting;
    projmap *proj;    /* caustic pass with projection maps: one per light, else NULL */
    distrib1d choose; /* with proj: lights by power times active fraction */
    double wsum;      /* with proj: the sum of those weights (mean-channel power) */
} vctx;

static void to3(float f[3], vec3 v) {
    f[0] = (float)v.x;
    f[1] = (float)v.y;
    f[2] = (float)v.z;
}

static void push(vbuf *b, uint64_t i, vec3 p, rgb power, vec3 d, vec3 n, int kind, int where, int med) {
    if (b->fail || b->over) return;
    if (b->n >= b->max_n) { /* the memory budget: this photon's path is not kept */
        b->over = 1;
        return;
    }
    if (b->n == b->cap) {
        size_t nc = b->cap ? 2 * b->cap : 1024;
        if (nc > b->max_n) nc = b->max_n;
        vrec *nr = realloc(b->r, nc * sizeof *nr);
        if (!nr) {
            b->fail = 1;
            return;
        }
        b->r = nr;
        b->cap = nc;
    }
    vrec *v = &b->r[b->n++];
    v->index = i;
    to3(v->pos, p);
    to3(v->power, power);
    to3(v->dir, d);
    to3(v->nrm, n);
    v->kind = kind;
    v->where = where;
    v->med = med;
}

/* Roulette on a throughput factor w: survive with q = min(1, max channel), power * w / q. */
static int survive(rgb *power, rgb w, rng *g) {
    double q = fmin(1.0, v3_maxc(w)), u = rng_uniform(g);
    if (!(q > 0) || !(u < q)) return 0;
    *power = v3_mul(*power, v3_scale(w, 1.0 / q));
    return 1;
}

static int inside(const vol_pass_opts *o, vec3 x) {
    if (!(o->lo.x <= o->hi.x)) return 1;
    return x.x >= o->lo.x && x.y >= o->lo.y && x.z >= o->lo.z && x.x <= o->hi.x && x.y <= o->hi.y &&
           x.z <= o->hi.z;
}

static int clampi(int v, int n) { return v < 0 || v >= n ? n - 1 : v; }

static void trace_photon(const vctx *c, uint64_t i, vbuf *b) {
    const scene *s = c->s;
    const int caustic_pass = c->o->caustic_pass;
    int max_depth = c->o->max_depth;
    if (c->o->max_bounces > 0 && c->o->max_bounces < max_depth) max_depth = c->o->max_bounces;
    rng g = rng_stream(c->o->seed, i, caustic_pass ? 8 : 7);
    double pl, u[4];
    int li = distrib1d_sample(c->proj ? &c->choose : &s->light_distrib, rng_uniform(&g), &pl);
    for (int k = 0; k < 4; k++) u[k] = rng_uniform(&g);
    b->pilot.emitted++;
    if (!(pl > 0)) return;
    /* Aimed: a point of an active cell, the power times the light's active fraction. */
    if (c->proj) projmap_sample(&c->proj[li], &s->lights[li], rng_uniform(&g), &g, u);
    vec3 p, nl, d;
    light_sample_le(s, li, u, &p, &nl, &d);
    rgb power = v3_scale(s->lights[li].power, (c->proj ? c->proj[li].fraction : 1.0) / pl);
    if (v3_iszero(power)) return;
    ray r = {v3_iszero(nl) ? p : scene_offset(c->s, p, nl, d), d};
    /* specular: a specular bounce so far; scattered: a diffuse bounce or a scattering event;
     * in_medium_scatter: a scattering event so far. med -2: not known until the first hit. */
    int med = -2, specular = 0, scattered = 0, vscattered = 0, crossings = 0, spec_mat = -1;
    /* The index around the light and where the photon is (set at refractions): surface photons
     * are stored with power (n_src / n_here)^2, material_radiance_scale in material.h; volume
     * photons are not (pm_volume.c scales their estimates per medium). */
    double n_src = 0, n_here = 0;
    int depth = 0;
    for (; depth <= max_depth && !b->over;) {
        hit h;
        int got = scene_intersect(s, r, INFINITY, &h);
        if (med == -2) med = got ? scene_medium_after(s, &h, v3_neg(r.d)) : s->global_medium;
        if (med >= 0) {
            double uc = rng_uniform(&g), ud = rng_uniform(&g), t;
            rgb w;
            if (medium_sample_distance(&s->media[med], got ? h.t : INFINITY, uc, ud, &t, &w)) {
                if (v3_iszero(w)) return; /* sigma_s = 0: absorbed, nothing scatters */
                vec3 x = ray_at(r, t);
                int kind = scattered ? PM_KIND_INDIRECT : specular ? PM_KIND_CAUSTIC : PM_KIND_DIRECT;
                b->pilot.events[clampi(med, VOL_PILOT_MEDIA)][kind]++;
                if (kind == PM_KIND_CAUSTIC) b->pilot.caustic_by_mat[clampi(spec_mat, VOL_PILOT_MATS)]++;
                if (c->keep_volume && (!caustic_pass || kind == PM_KIND_CAUSTIC) && inside(c->o, x))
                    push(b, i, x, v3_mul(power, w), r.d, v3s(0), kind, WHERE_VOLUME, med);
                if (caustic_pass) return; /* not L S+ any more */
                scattered = vscattered = 1;
                if (!survive(&power, w, &g)) return;
                vec3 nd;
                hg_sample(s->media[med].g, r.d, rng_uniform(&g), rng_uniform(&g), &nd);
                r.o = x;
                r.d = nd;
                depth++;
                continue;
            }
            power = v3_mul(power, w);
            if (v3_iszero(power)) return;
        }
        if (!got) return;
        const material *m = scene_material(s, &h);
        if (m->kind == MAT_NULL) {
            if (++crossings > 4 * max_depth + 1024) return;
            med = scene_medium_after(s, &h, r.d);
            r.o = scene_offset(c->s, h.p, h.ng, r.d);
            continue;
        }
        vec3 wo = v3_neg(r.d);
        double wl[LOBE_COUNT];
        material_weights(m, wo, h.ng, s->medium_ior, wl);
        if (wl[LOBE_DIFFUSE] > 0 && v3_maxc(m->diffuse) > 0) {
            int kind = scattered ? PM_KIND_INDIRECT : specular ? PM_KIND_CAUSTIC : PM_KIND_DIRECT;
            if (kind == PM_KIND_DIRECT) b->pilot.surf_direct++;
            if (kind == PM_KIND_CAUSTIC) b->pilot.surf_caustic++;
            if (kind == PM_KIND_INDIRECT) b->pilot.surf_indirect++;
            if (vscattered) b->pilot.surf_after_scatter++;
            vec3 ns = v3_dot(wo, h.ng) >= 0 ? h.ng : v3_neg(h.ng);
            /* The global map has no caustic kind (photon_trace.h): L S+ D counts as indirect. */
            rgb ps = v3_scale(power, material_radiance_scale(n_src, n_here));
            if (c->keep_surface && !caustic_pass)
                push(b, i, h.p, ps, r.d, ns, kind == PM_KIND_DIRECT ? kind : PM_KIND_INDIRECT, WHERE_SURFACE, -1);
            if (c->keep_surface && caustic_pass && kind == PM_KIND_CAUSTIC)
                push(b, i, h.p, ps, r.d, ns, kind, WHERE_SURFACE, -1);
        }
        bsdf_sample bs;
        double ul = rng_uniform(&g), u1 = rng_uniform(&g), u2 = rng_uniform(&g);
        if (!material_sample_ns(m, wo, h.ng, h.ns, s->medium_ior, ul, u1, u2, &bs)) return;
        if (bs.lobe == LOBE_TRANSMIT && !bs.tir && m->kind != MAT_NULL) {
            double n1, n2;
            material_indices(m, wo, h.ng, s->medium_ior, &n1, &n2);
            if (!(n_src > 0)) n_src = n1;
            else if (n1 != n_here) n_src *= n1 / n_here; /* a broken chain (photon_trace.c) */
            n_here = n2;
        }
        if (bs.lobe == LOBE_DIFFUSE) {
            if (caustic_pass) return;
            scattered = 1;
        } else if (!specular) {
            specular = 1;
            spec_mat = h.mat;
        }
        if (!survive(&power, bs.weight, &g)) return;
        med = scene_medium_after(s, &h, bs.wi);
        r.o = scene_offset(c->s, h.p, h.ng, bs.wi);
        r.d = bs.wi;
        depth++;
    }
    /* Still alive after the last bounce allowed by max_bounces: the path-length budget cut it. */
    if (depth > max_depth && !b->over && c->o->max_bounces > 0 && c->o->max_bounces < c->o->max_depth)
        b->cut++;
}

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
    vrec *r;
    size_t n, cap;
    uint64_t cut; /* photons [0, cut) kept; UINT64_MAX: not cut yet */
} vmap;

static int vmap_take(vmap *m, const vrec *v) {
    if (!m->keep || v->index >= m->cut) return 0;
    if (m->n == m->cap) {
        size_t nc = m->cap ? 2 * m->cap : 4096;
        vrec *nr = realloc(m->r, nc * sizeof *nr);
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
        for (size_t k = 0; k < m->n; k++) (*med)[k] = (short)m->r[k].med;
    }
    float sc = (float)(1.0 / (double)*ne);
    for (size_t k = 0; k < m->n; k++) {
        const vrec *v = &m->r[k];
        float pw[3] = {v->power[0] * sc, v->power[1] * sc, v->power[2] * sc};
        pm_photon_init(&ph[k], v->pos, pw, v->dir, v->where == WHERE_SURFACE ? v->nrm : NULL, v->kind);
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

/* The message of a map that stopped short of its target (photon_trace.c's wording). */
static void say_short(const char *title, const vmap *m, uint64_t n_e, const char *budget, const char *why) {
    fprintf(stderr,
            "photon tracing: %s: only %zu of %ld photons stored after %llu emitted; stopped by "
            "the %s (%s)\n",
            title, m->n, m->target, (unsigned long long)n_e, budget, why);
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
        bytes += sizeof(vbatch_head) + bufs[b].n * sizeof(vrec);
        mine++;
    }
    char *out = malloc(bytes ? bytes : 1);
    vbatch_head failed[VOL_ROUND];
    size_t off = 0;
    int own_fail = !out;
    for (int b = d->part, j = 0; b < nb; b += d->nparts, j++) {
        vbuf *bf = &bufs[b];
        if (d->test_fail && d->test_fail(d->user)) bf->fail = 1; /* test hook (photon_trace.h) */
        own_fail |= bf->fail;
        vbatch_head h;
        memset(&h, 0, sizeof h);
        h.n = out ? bf->n : 0;
        h.cap = bf->cap;
        h.stop = bf->stop;
        h.cut = bf->cut;
        h.fail = bf->fail || !out;
        h.over = bf->over;
        h.b = b;
        h.pilot = bf->pilot;
        failed[j] = h;
        if (!out) continue;
        memcpy(out + off, &h, sizeof h);
        off += sizeof h;
        if (bf->n) memcpy(out + off, bf->r, bf->n * sizeof(vrec));
        off += bf->n * sizeof(vrec);
    }
    /* This process's own failure: said before the exchange tells every process of it. */
    if (own_fail && d->failed)
        d->failed(d->user, "out of memory while tracing photons (a pass of the media)");
    size_t *sizes = calloc((size_t)d->nparts, sizeof *sizes);
    char *all = NULL;
    int rc = !sizes ? -1
             : out ? d->allgather(d->user, out, off, (void **)&all, sizes)
                   : d->allgather(d->user, failed, (size_t)mine * sizeof *failed, (void **)&all, sizes);
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
            if (h.cap != bf->cap) { /* the tracing process's capacity */
                vrec *nr = realloc(bf->r, (h.cap ? h.cap : 1) * sizeof *nr);
                if (!nr) rc = PM_ENOMEM;
                else {
                    bf->r = nr;
                    bf->cap = h.cap;
                }
            }
            bf->n = rc == 0 ? h.n : 0;
            if (bf->n) memcpy(bf->r, all + off, h.n * sizeof(vrec));
            off += h.n * sizeof(vrec);
            bf->stop = h.stop;
            bf->cut = h.cut;
            bf->fail = h.fail || rc < 0;
            bf->over = h.over;
            bf->pilot = h.pilot;
        }
    }
    free(sizes);
    free(all);
    return rc;
}

int vol_trace_pass(const scene *s, const vol_pass_opts *o, vol_pass_result *res) {
    memset(res, 0, sizeof *res);
    if (s->nlights == 0 || s->light_distrib.n == 0) return PM_EINVAL;
    if (!(o->max_emitted >= 1) || o->max_depth < 0 || o->surface_target < 0 || o->volume_target < 0 ||
        o->max_bounces < 0)
        return PM_EINVAL;
    vctx c = {s, o, o->surface_target > 0 && !o->pilot, o->volume_target > 0 && !o->pilot, o->pilot != NULL,
              NULL, {0}, 0};
    const char *title_s = o->caustic_pass ? "Tracing caustic photons" : "Tracing global photons";
    const char *title_v = o->caustic_pass ? "Tracing volume-caustic photons" : "Tracing volume photons";
    const char *emit_budget = o->max_emitted_budget ? o->max_emitted_budget : "photon_mapping.max_emitted budget";
    if (o->caustic_pass && o->projection_cells > 0) {
        double *w = malloc((size_t)s->nlights * sizeof *w);
        if (!w || projmap_build_all(s, o->projection_cells, &c.proj) < 0) {
            free(w);
            return PM_ENOMEM;
        }
        for (int i = 0; i < s->nlights; i++) {
            rgb pw = s->lights[i].power;
            w[i] = (pw.x + pw.y + pw.z) / 3 * c.proj[i].fraction;
            c.wsum += w[i];
        }
        int rc0 = c.wsum > 0 ? distrib1d_init(&c.choose, w, s->nlights) : PM_EINVAL;
        free(w);
        if (rc0 < 0) { /* no light faces a specular object: nothing to aim at */
            projmap_free_all(c.proj, s->nlights);
            c.proj = NULL;
            return rc0 == PM_ENOMEM ? rc0 : 0; /* empty maps: nothing can reach a specular object */
        }
    }
    vmap ms = {c.keep_surface, o->surface_target, NULL, 0, 0, c.keep_surface ? UINT64_MAX : 0};
    vmap mv = {c.keep_volume, o->volume_target, NULL, 0, 0, c.keep_volume ? UINT64_MAX : 0};
    vbuf bufs[VOL_ROUND];
    memset(bufs, 0, sizeof bufs);
    int nthreads = 1;
#ifdef _OPENMP
    nthreads = o->threads > 0 ? o->threads : omp_get_max_threads();
#endif
    uint64_t emitted = 0, max_emitted = (uint64_t)o->max_emitted, cut = 0;
    int rc = 0;
    const trace_dist *dist = g_vdist && !o->pilot ? g_vdist : NULL;
    /* The budget that stopped the pass (NULL: none) and what it saw. */
    const char *stop = NULL;
    char why[160] = "";
    while (emitted < max_emitted && (c.counting || ms.cut == UINT64_MAX || mv.cut == UINT64_MAX)) {
        uint64_t start = emitted;
        int nb = VOL_ROUND;
        /* The memory budget (max_memory_bytes): the maps' buffers between rounds, and within a
         * round each batch's buffer at most its share of what the maps leave, so the stop is
         * the same for any thread count. */
        size_t held = (ms.cap + mv.cap) * sizeof(vrec), room = SIZE_MAX;
        for (int b = 0; b < nb; b++) held += bufs[b].cap * sizeof(vrec);
        if (o->max_memory_bytes > 0 && !c.counting) {
            if (held > o->max_memory_bytes) {
                stop = "photon_mapping.max_memory_mb budget";
                snprintf(why, sizeof why, "%.2f MiB of photon buffers", (double)held / (1 << 20));
                break;
            }
            room = (o->max_memory_bytes - (ms.cap + mv.cap) * sizeof(vrec)) / VOL_ROUND / sizeof(vrec);
        }
        (void)nthreads;
#ifdef _OPENMP
#pragma omp parallel for num_threads(nthreads) schedule(dynamic, 1)
#endif
        for (int b = 0; b < nb; b++) {
            vbuf *bf = &bufs[b];
            /* A distributed pass (vol_set_dist): another process traces this batch. */
            if (dist && b % dist->nparts != dist->part) continue;
            bf->n = 0;
            bf->over = 0;
            bf->stop = UINT64_MAX;
            bf->cut = 0;
            bf->max_n = room;
            memset(&bf->pilot, 0, sizeof bf->pilot);
            uint64_t lo = start + (uint64_t)b * VOL_BATCH, hi = lo + VOL_BATCH;
            if (hi > max_emitted) hi = max_emitted;
            for (uint64_t i = lo; i < hi && !bf->over; i++) {
                trace_photon(&c, i, bf);
                if (bf->over) { /* photon i is not whole: drop its records, end the batch here */
                    while (bf->n > 0 && bf->r[bf->n - 1].index == i) bf->n--;
                    bf->stop = i;
                }
            }
        }
        if (dist && vol_exchange(bufs, nb) < 0) {
            rc = PM_ENOMEM;
            break;
        }
        uint64_t end = start + (uint64_t)nb * VOL_BATCH;
        for (int b = 0; b < nb && rc == 0; b++) {
            if (bufs[b].fail) rc = PM_ENOMEM;
            if (o->pilot) pilot_add(o->pilot, &bufs[b].pilot);
            cut += bufs[b].cut;
            for (size_t k = 0; k < bufs[b].n && rc == 0; k++) {
                const vrec *v = &bufs[b].r[k];
                rc = vmap_take(v->where == WHERE_SURFACE ? &ms : &mv, v);
            }
            if (bufs[b].over) { /* the photons before it are whole; none after it counts */
                end = bufs[b].stop;
                stop = "photon_mapping.max_memory_mb budget";
                snprintf(why, sizeof why, "a batch of photons outgrew its share of the budget, "
                         "%.2f MiB, at photon %llu", (double)(room * sizeof(vrec)) / (1 << 20),
                         (unsigned long long)bufs[b].stop);
                break;
            }
        }
        if (rc < 0) break;
        emitted = end < max_emitted ? end : max_emitted;
        if (stop) break;
        /* A map that stored nothing in its first VOL_EMPTY_PHOTONS photons stays empty. */
        if (emitted >= VOL_EMPTY_PHOTONS) {
            if (ms.cut == UINT64_MAX && ms.n == 0) ms.cut = emitted;
            if (mv.cut == UINT64_MAX && mv.n == 0) mv.cut = emitted;
        }
    }
    for (int b = 0; b < VOL_ROUND; b++) free(bufs[b].r);
    if (c.proj) {
        projmap_free_all(c.proj, s->nlights);
        distrib1d_free(&c.choose);
    }
    res->emitted = emitted;
    res->cut = cut;
    res->surface_short = ms.keep && ms.cut == UINT64_MAX;
    res->volume_short = mv.keep && mv.cut == UINT64_MAX;
    if (!stop && emitted >= max_emitted) {
        stop = emit_budget;
        snprintf(why, sizeof why, "%llu photons emitted", (unsigned long long)max_emitted);
    }
    if (rc == 0 && !o->pilot) {
        if (cut > 0)
            fprintf(stderr,
                    "photon tracing: %s: %llu photon paths were cut by the path-length budget "
                    "(photon_mapping.max_bounces = %d)\n",
                    c.keep_volume ? title_v : title_s, (unsigned long long)cut, o->max_bounces);
        if ((ms.keep || mv.keep) && ms.n == 0 && mv.n == 0) {
            snprintf(res->msg, sizeof res->msg,
                     "photon tracing: %s: no photon stored after %llu emitted: the lights reach no "
                     "surface or medium that stores photons (do they face anything? are they "
                     "enclosed by mirrors or glass only?)%s%s",
                     mv.keep ? title_v : title_s, (unsigned long long)emitted,
                     stop ? "; stopped by the " : "", stop ? stop : "");
            rc = PM_EEMPTY;
        } else {
            if (res->surface_short) say_short(title_s, &ms, emitted, stop ? stop : "?", why);
            if (res->volume_short) say_short(title_v, &mv, emitted, stop ? stop : "?", why);
        }
    }
    if (rc == 0) rc = vmap_finish(&ms, emitted, &res->surface, NULL, &res->nsurface, &res->surface_emitted);
    if (rc == 0)
        rc = vmap_finish(&mv, emitted, &res->volume, &res->volume_medium, &res->nvolume, &res->volume_emitted);
    free(ms.r);
    free(mv.r);
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
