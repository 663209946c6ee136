/* photon_trace.c: the surface passes' bookkeeping (the global and caustic passes, the pilot's
 * photons joining them, packing); see photon_trace.h. The walk of one photon is
 * photon_walk.c's, shared with the media's tracer (volume.c); running a pass, its batches,
 * budgets and distributed rounds is photon_pass.h's.
 */
#include "photons/photon_trace.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "photonmap/estimate.h"
#include "scene/material.h"
#include "photons/importance.h"
#include "photons/photon_pass.h"
#include "photons/photon_path.h"
#include "photons/ports.h"
#include "photons/projmap.h"
#include "base/rng.h"
#include "base/sampling.h"
#include "base/stats.h"

/* A pilot's photons, kept for the real passes (PILOT PHOTONS in photon_trace.h). */
struct pilot_photons {
    pass_buf g, s;         /* its global pass's global and shadow stores, in photon order */
    uint64_t emitted;      /* photons its global pass emitted (0: it ran none) */
    int max_depth, max_bounces, global, shadow; /* the rules its global pass was traced by */
    const importance *imp; /* the table its rel were computed under (NULL: none) */
    pass_buf c;            /* its caustic pass's L S+ D stores, in photon order */
    uint64_t c_emitted, c_first_specular; /* that pass's photons (0: it ran none) */
    int c_max_depth, c_max_bounces, c_cells; /* its rules; c_cells: projection cells per side */
};

/* ---- passes ------------------------------------------------------------------------------- */

/* Pack b's photons with power / (np + nm rel): photons from two emissions joined by the
 * balance heuristic (Veach), np of them emitted by power (rel is their p / p_l under the
 * other's table) and nm by the pass (rel: its own p / p_l). np = 0 and rel = 1: power / nm. */
static int pack(const pass_buf *b, double np, double nm, pm_photon **out, size_t *n) {
    *n = b->n;
    /* Zeroed: pm_photon_set keeps a record's kd-tree bits, which must start at 0. */
    *out = calloc(b->n ? b->n : 1, sizeof **out);
    if (!*out) return PM_ENOMEM;
    for (size_t k = 0; k < b->n; k++) {
        const pass_rec *f = &b->v[k];
        double scale = 1.0 / (np + nm * (double)f->rel);
        float pw[3] = {(float)(f->power[0] * scale), (float)(f->power[1] * scale),
                       (float)(f->power[2] * scale)};
        pm_photon_init(&(*out)[k], f->pos, pw, f->dir, f->normal, f->kind);
    }
    return 0;
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
    const trace_dist *d = pass_dist();
    m->part = 1;
    m->whole_global = o->global ? wg[0] : 0;
    m->whole_shadow = o->global ? wg[1] : wg[0];
    m->whole_caustic = wc[0];
    double mine[2] = {pm_photons_max_power(m->global, m->nglobal),
                      pm_photons_max_power(m->caustic, m->ncaustic)},
           *all = NULL;
    size_t *sizes = NULL;
    int rc = pass_allgather(d, mine, sizeof mine, (void **)&all, &sizes) < 0 ? PM_ENOMEM : 0;
    for (int p = 0; rc == 0 && p < d->nparts; p++)
        for (int k = 0; k < 2; k++)
            if (p == 0 || all[2 * p + k] > m->whole_max_power[k]) m->whole_max_power[k] = all[2 * p + k];
    free(all);
    free(sizes);
    return rc;
}

/* Append the kept pilot photons of from to b (after the pass's own, which were cut already). */
static int join(pass_buf *b, const pass_buf *from) {
    for (size_t k = 0; k < from->n; k++)
        if (pass_buf_push(b, &from->v[k]) < 0) return PM_ENOMEM;
    return 0;
}

void pilot_photons_free(pilot_photons *k) {
    if (!k) return;
    free(k->g.v);
    free(k->s.v);
    free(k->c.v);
    free(k);
}

/* A photon_trace call's buffers and counts, shared by its steps. */
typedef struct trace_run {
    const scene *s;
    const trace_opts *o;
    photon_maps *m;
    char *err;
    size_t errcap;
    rgb *scale;                    /* per light: the pass's power / p_light */
    const pilot_photons *rk, *rkc; /* the pilot photons joining the global, caustic pass */
    pass_buf gbuf, sbuf, cbuf;
    size_t wg[2], wc[2]; /* whole counts: global pass (main, shadow), caustic */
    uint64_t c_own;      /* photons the caustic pass itself emitted (without a joining pilot's) */
    int G;               /* projection cells per side */
    int st_emit_g, st_emit_c, st_glob, st_caus, st_shadow, st_saved, st_first, st_imp_paths, st_imp_unocc,
        st_imp_cells, st_reused, st_reused_c, st_reused_cs;
} trace_run;

/* The global pass (also carries the shadow photons). */
static int global_pass(trace_run *t) {
    const scene *s = t->s;
    const trace_opts *o = t->o;
    const pilot_photons *rk = t->rk;
    pass_ctx c = {0};
    c.s = s;
    c.o = o;
    c.want_global = o->global;
    c.want_shadow = o->shadow;
    c.choose = s->light_distrib;
    for (int i = 0; i < s->nlights; i++) {
        double pl = distrib1d_prob(&s->light_distrib, i);
        t->scale[i] = pl > 0 ? v3_scale(s->lights[i].power, 1.0 / pl) : v3s(0);
    }
    c.light_scale = t->scale;
    shifts(c.shift, o->seed, 1);
    /* Importance-driven emission (importance.h): the plan's table of where the camera
     * sees light; the pass emits toward it, its photons' powers divided by the steering. */
    if (o->importance && o->importance->on && o->pilot) { /* photons that may join: rel */
        c.imp = o->importance;
        c.imp_rel_only = 1;
    }
    if (o->importance && o->importance->on && !o->pilot) {
        c.imp = o->importance;
        stat_add(t->st_imp_paths, (uint64_t)c.imp->paths);
        stat_add(t->st_imp_unocc, c.imp->contributing);
        stat_add(t->st_imp_cells, c.imp->lv[0].ncells);
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
    pass_out po = {0};
    photon_ports ports;
    int rc = ports_build(&ports, s);
    c.ports = ports.on ? &ports : NULL;
    if (rc == 0)
        rc = pass_run(&c, target, o->global ? &t->gbuf : &t->sbuf, o->global ? &t->sbuf : NULL, &po,
                      o->global ? "Tracing global photons" : "Tracing shadow photons", t->err, t->errcap);
    ports_free(&ports);
    t->m->global_emitted = po.emitted;
    t->m->global_runaway = po.runaway;
    t->wg[0] = po.whole[0];
    t->wg[1] = po.whole[1];
    if (!o->pilot) stat_add(t->st_emit_g, t->m->global_emitted);
    return rc;
}

/* The caustic pass, aimed by the projection maps. */
static int caustic_pass(trace_run *t) {
    const scene *s = t->s;
    const trace_opts *o = t->o;
    const pilot_photons *rkc = t->rkc;
    photon_maps *m = t->m;
    pass_aim aim;
    int rc = pass_aim_build(s, t->G, &aim);
    if (rc == 0 && aim.chosen) {
        pass_ctx c = {0};
        c.s = s;
        c.o = o;
            c.caustic_pass = 1;
        c.proj = aim.proj;
        c.choose = aim.choose;
        for (int i = 0; i < s->nlights; i++) {
            double pl = distrib1d_prob(&c.choose, i);
            /* Eq. 2.2: only the fraction f of the directions is sampled. */
            t->scale[i] = pl > 0 ? v3_scale(s->lights[i].power, aim.proj[i].fraction / pl) : v3s(0);
        }
        c.light_scale = t->scale;
        shifts(c.shift, o->seed, 2);
        /* The pilot's stores, when they join, count toward the target (as in the global
         * pass); its photons count as emitted, and its first-specular ones too. */
        long target = o->caustic_target;
        c.tail = rkc ? &rkc->c : NULL;
        c.tail_emitted = rkc ? rkc->c_emitted : 0;
        if (rkc) target = (long)rkc->c.n < target ? target - (long)rkc->c.n : 1;
        double ge = (double)(m->global_emitted ? m->global_emitted : o->cap_global_emitted);
        double floor = o->caustic_cap_min > 0 && o->caustic_cap_min < CAUSTIC_CAP_MIN ? o->caustic_cap_min
                                                                                      : CAUSTIC_CAP_MIN;
        double cap = fmax(floor, CAUSTIC_CAP_FACTOR * ge);
        double budget = o->max_emitted_factor * (double)target;
        if (o->max_emitted > 0 && o->max_emitted < budget) budget = o->max_emitted;
        char cap_name[160];
        if (o->caustic_cap && cap < budget) { /* CAUSTIC CAP in photon_trace.h */
            snprintf(cap_name, sizeof cap_name, "caustic pass's cap (4 times the global pass's photons "
                     "emitted, at least %.0f; photon_trace.h CAUSTIC CAP)", floor);
            c.limit = cap;
            c.limit_name = cap_name;
        }
        pass_out po = {0};
        rc = pass_run(&c, target, &t->cbuf, NULL, &po, "Tracing caustic photons", t->err, t->errcap);
        m->caustic_emitted = po.emitted;
        m->caustic_first_specular = po.first_specular;
        m->caustic_runaway = po.runaway;
        t->wc[0] = po.whole[0];
        t->wc[1] = po.whole[1];
        t->c_own = m->caustic_emitted;
        if (rc == 0 && rkc) {
            m->caustic_emitted += rkc->c_emitted;
            m->caustic_first_specular += rkc->c_first_specular;
        }
        m->caustic_fraction = aim.wsum / aim.psum;
        if (m->caustic_fraction > 0)
            m->caustic_saved = (uint64_t)((double)m->caustic_emitted * (1.0 / m->caustic_fraction - 1.0) + 0.5);
        if (!o->pilot) stat_add(t->st_emit_c, m->caustic_emitted);
        if (!o->pilot) stat_add(t->st_saved, m->caustic_saved);
        if (!o->pilot) stat_add(t->st_first, m->caustic_first_specular);
    }
    if (rc == PM_ENOMEM && !t->err[0]) snprintf(t->err, t->errcap, "out of memory");
    pass_aim_free(&aim);
    return rc;
}

/* The pilot's photons join the maps (PILOT PHOTONS in photon_trace.h; a partitioned pass's
 * part has its share already, from pass_part_finish), and the maps are packed. */
static int pack_maps(trace_run *t) {
    const trace_opts *o = t->o;
    const pilot_photons *rk = t->rk, *rkc = t->rkc;
    photon_maps *m = t->m;
    int rc = 0, part = pass_dist() && pass_dist()->partitioned;
    if (m->global_emitted) {
        double nm = (double)m->global_emitted, np = 0;
        if (rk) {
            if (!part) rc = join(o->global ? &t->gbuf : &t->sbuf, o->global ? &rk->g : &rk->s);
            if (rc == 0 && !part && o->global && o->shadow) rc = join(&t->sbuf, &rk->s);
            if (part) {
                t->wg[0] += o->global ? rk->g.n : rk->s.n;
                if (o->global && o->shadow) t->wg[1] += rk->s.n; /* as the join above */
            }
            np = (double)rk->emitted;
            m->global_emitted += rk->emitted;
            m->pilot_emitted[0] = rk->emitted;
            m->pilot_stored[0] = o->global ? rk->g.n : rk->s.n;
            if (!o->pilot) stat_add(t->st_reused, rk->emitted);
        }
        if (rc == 0 && o->global) rc = pack(&t->gbuf, np, nm, &m->global, &m->nglobal);
        if (rc == 0 && o->shadow) rc = pack(&t->sbuf, np, nm, &m->shadow, &m->nshadow);
    }
    if (rc == 0 && m->caustic_emitted) {
        double np = 0;
        if (rkc) { /* as the global pass's join above */
            if (!part) rc = join(&t->cbuf, &rkc->c);
            else t->wc[0] += rkc->c.n;
            np = (double)rkc->c_emitted;
            m->pilot_emitted[1] = rkc->c_emitted;
            m->pilot_stored[1] = rkc->c.n;
            stat_add(t->st_reused_c, rkc->c_emitted);
            stat_add(t->st_reused_cs, rkc->c.n);
        }
        if (rc == 0) rc = pack(&t->cbuf, np, (double)t->c_own, &m->caustic, &m->ncaustic);
    }
    return rc;
}

/* A pilot keeping its stores for the real passes: its buffers, before packing (kept, or
 * added to the kept photons of another pilot call). */
static void keep_pilot(trace_run *t) {
    const trace_opts *o = t->o;
    photon_maps *m = t->m;
    pilot_photons *k = o->pilot->kept ? o->pilot->kept : calloc(1, sizeof *k);
    if (k && m->global_emitted) {
        free(k->g.v);
        free(k->s.v);
        k->g = t->gbuf;
        k->s = t->sbuf;
        t->gbuf.v = t->sbuf.v = NULL;
        k->emitted = m->global_emitted;
        k->max_depth = o->max_depth;
        k->max_bounces = o->max_bounces;
        k->imp = o->importance;
        k->global = o->global;
        k->shadow = o->shadow;
    }
    if (k && m->caustic_emitted) {
        free(k->c.v);
        k->c = t->cbuf;
        t->cbuf.v = NULL;
        k->c_emitted = m->caustic_emitted;
        k->c_first_specular = m->caustic_first_specular;
        k->c_max_depth = o->max_depth;
        k->c_max_bounces = o->max_bounces;
        k->c_cells = t->G;
    }
    o->pilot->kept = k;
}

int photon_trace(const scene *s, const trace_opts *o, photon_maps *m, char *err, size_t errcap) {
    memset(m, 0, sizeof *m);
    if (errcap) err[0] = 0;
    trace_run t;
    memset(&t, 0, sizeof t);
    /* Field by field (as renderer.c does its loop): the run's own members, of another struct. */
    t.s = s;
    t.o = o;
    t.m = m;
    t.err = err;
    t.errcap = errcap;
    /* One registration a counter, deliberately unrolled: each names its own field and line. */
    t.st_emit_g = stats_register("Photons/Emitted, global pass");
    t.st_emit_c = stats_register("Photons/Emitted, caustic pass");
    t.st_glob = stats_register("Photons/Global photons stored");
    t.st_caus = stats_register("Photons/Caustic photons stored");
    t.st_shadow = stats_register("Photons/Shadow-map photons stored (direct + shadow)");
    t.st_saved = stats_register("Photons/Caustic emissions saved by the projection map");
    t.st_first = stats_register("Photons/Caustic-pass photons whose first hit is specular");
    t.st_imp_paths = stats_register("Photons/Importance: camera paths");
    t.st_imp_unocc = stats_register("Photons/Importance: light connections carrying light");
    t.st_imp_cells = stats_register("Photons/Importance: emission cells with importance (finest level)");
    t.st_reused = stats_register("Photons/Pilot photons reused in the global maps (emitted)");
    t.st_reused_c = stats_register("Photons/Pilot photons reused in the caustic map (emitted)");
    t.st_reused_cs = stats_register("Photons/Pilot photons reused in the caustic map (stored)");
    int nl = s->nlights;
    if (nl == 0 || s->light_distrib.n == 0) return 0;
    /* The plan's pilot photons join this pass's maps when they were traced by the same rules
     * and stored less than half the target (PILOT PHOTONS in photon_trace.h). */
    t.rk = pilot_photons_joining(o->reuse, o, 0, NULL, NULL, NULL) ? o->reuse : NULL;
    t.rkc = pilot_photons_joining(o->reuse, o, 1, NULL, NULL, NULL) ? o->reuse : NULL;
    t.G = projection_cells(o);
    int rc = 0;
    if (!(t.scale = calloc((size_t)nl, sizeof *t.scale))) {
        snprintf(err, errcap, "out of memory");
        return PM_ENOMEM;
    }
    if ((o->global || o->shadow) && o->global_target > 0) rc = global_pass(&t);
    if (rc == 0 && o->caustic && o->caustic_target > 0) rc = caustic_pass(&t);
    if (rc == 0) rc = pack_maps(&t);
    if (rc == 0 && o->pilot && o->pilot->keep && (m->global_emitted || m->caustic_emitted)) keep_pilot(&t);
    if (rc == 0 && pass_dist() && pass_dist()->partitioned && !o->pilot) rc = part_whole(o, m, t.wg, t.wc);
    if (rc < 0 && !err[0]) snprintf(err, errcap, "%s", pm_strerror(rc));
    if (!o->pilot) stat_add(t.st_glob, m->part ? m->whole_global : m->nglobal);
    if (!o->pilot) stat_add(t.st_caus, m->part ? m->whole_caustic : m->ncaustic);
    if (!o->pilot) stat_add(t.st_shadow, m->part ? m->whole_shadow : m->nshadow);
    free(t.gbuf.v);
    free(t.sbuf.v);
    free(t.cbuf.v);
    free(t.scale);
    if (rc < 0) photon_maps_free(m);
    return rc;
}
