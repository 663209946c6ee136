/* volume.c: photon tracing through participating media for the volume photon maps and the
 * surface maps of a scene with media; see volume.h. Each photon is traced by photon_walk
 * (photon_walk.c, the surfaces' tracer's walk too: free flight in the current medium, a volume
 * store and an HG bounce at each scattering event, a surface store and a material bounce at
 * each diffuse surface, a medium change at each null surface); the pass is run by pass_run,
 * the one driver of both tracers (photon_pass.c and photon_rounds.c, whose top comment states
 * its rules: batches, the cut of each map at its target by whole photon paths, the budgets,
 * the distributed rounds). This file sets a media pass's options, packs its maps and says its
 * messages.
 *
 * A change here that changes any stored photon (which photons are stored, their power,
 * position, direction or kind) must bump PHOTON_TRACE_VERSION in photon_maps.h in the same
 * commit, so maps saved before it are refused (photon_maps.h TRACER VERSION).
 */
#include "photons/volume.h"

#include <limits.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "photons/photon_pass.h"
#include "photons/photon_trace.h"
#include "photons/ports.h"

/* The records (photon_pass.h's pass_rec) as pm_photons with the power divided by the map's
 * emitted count ne; med: each record's medium (a volume map), or NULL. */
static int map_finish(const pass_buf *b, uint64_t ne, pm_photon **out, short **med, size_t *n) {
    *out = NULL;
    *n = 0;
    if (b->n == 0) return 0;
    pm_photon *ph = malloc(b->n * sizeof *ph);
    if (!ph) return PM_ENOMEM;
    if (med) {
        if (!(*med = malloc(b->n * sizeof **med))) {
            free(ph);
            return PM_ENOMEM;
        }
        for (size_t k = 0; k < b->n; k++) (*med)[k] = b->v[k].medium;
    }
    float sc = (float)(1.0 / (double)ne);
    for (size_t k = 0; k < b->n; k++) {
        const pass_rec *v = &b->v[k];
        float pw[3] = {v->power[0] * sc, v->power[1] * sc, v->power[2] * sc};
        pm_photon_init(&ph[k], v->pos, pw, v->dir, v->medium < 0 ? v->normal : NULL, v->kind);
    }
    *out = ph;
    *n = b->n;
    return 0;
}

void vol_pass_free(vol_pass_result *r) {
    free(r->surface);
    free(r->volume);
    free(r->volume_medium);
    memset(r, 0, sizeof *r);
}

/* The pass's end: its messages (BUDGETS in volume.h), PM_EEMPTY for a pass that stored
 * nothing, else rc. */
static int vol_report(const vol_pass_opts *o, const pass_ctx *c, const pass_out *po, size_t ns, size_t nv,
                      vol_pass_result *res, int rc) {
    const char *title_s = o->caustic_pass ? "Tracing caustic photons" : "Tracing global photons";
    const char *title_v = o->caustic_pass ? "Tracing volume-caustic photons" : "Tracing volume photons";
    res->emitted = po->traced;
    res->cut = po->paths_cut;
    res->surface_short = c->want_global && po->runaway;
    res->volume_short = c->keep_volume && po->short2;
    const char *stop = po->stop;
    if (rc != 0 || o->pilot) return rc;
    if (res->cut > 0) pass_say_cut(NULL, c->keep_volume ? title_v : title_s, res->cut, o->max_bounces);
    if ((c->want_global || c->keep_volume) && ns == 0 && nv == 0) {
        char stopped[160];
        snprintf(stopped, sizeof stopped, "the %s", stop ? stop : "");
        pass_say_empty(res->msg, sizeof res->msg, c->keep_volume ? title_v : title_s, po->traced,
                       "surface or medium", stop ? stopped : NULL);
        return PM_EEMPTY;
    }
    const char *budget = stop ? stop : "?";
    if (res->surface_short) pass_say_short(NULL, title_s, ns, o->surface_target, po->traced, "", budget, po->why);
    if (res->volume_short) pass_say_short(NULL, title_v, nv, o->volume_target, po->traced, "", budget, po->why);
    return 0;
}

int vol_trace_pass(const scene *s, const vol_pass_opts *o, vol_pass_result *res) {
    memset(res, 0, sizeof *res);
    if (s->nlights == 0 || s->light_distrib.n == 0) return PM_EINVAL;
    if (!(o->max_emitted >= 1) || o->max_depth < 0 || o->surface_target < 0 || o->volume_target < 0 ||
        o->max_bounces < 0)
        return PM_EINVAL;
    trace_opts to;
    memset(&to, 0, sizeof to);
    to.seed = o->seed;
    to.max_depth = o->max_depth;
    to.max_bounces = o->max_bounces;
    to.threads = o->threads;
    to.max_memory_bytes = o->pilot ? 0 : o->max_memory_bytes;
    to.quiet = 1;
    pass_ctx c;
    memset(&c, 0, sizeof c);
    c.s = s;
    c.o = &to;
    c.media = 1;
    c.caustic_pass = o->caustic_pass;
    c.want_global = o->surface_target > 0 && !o->pilot;
    c.keep_volume = o->volume_target > 0 && !o->pilot;
    c.target2 = c.keep_volume ? o->volume_target : 0;
    c.limit = o->max_emitted;
    c.limit_name = o->max_emitted_budget ? o->max_emitted_budget : "photon_mapping.max_emitted budget";
    c.vpilot = o->pilot;
    c.lo = o->lo;
    c.hi = o->hi;
    c.choose = s->light_distrib;
    pass_aim aim;
    memset(&aim, 0, sizeof aim);
    if (o->caustic_pass && o->projection_cells > 0) {
        int rc0 = pass_aim_build(s, o->projection_cells, &aim);
        if (rc0 < 0 || !aim.chosen) { /* no light faces a specular object: nothing to aim at */
            pass_aim_free(&aim);
            return rc0 == PM_ENOMEM ? rc0 : 0; /* empty maps: nothing can reach a specular object */
        }
        c.proj = aim.proj;
        c.choose = aim.choose;
    }
    /* Photon ports (ports.h, MEDIA): the pass that is not aimed at specular surfaces emits a
     * share of its photons through them, as the surface tracer's global pass does. */
    photon_ports ports;
    memset(&ports, 0, sizeof ports);
    if (!o->caustic_pass) {
        int rc0 = ports_build(&ports, s);
        if (rc0 < 0) {
            pass_aim_free(&aim);
            return rc0;
        }
        c.ports = ports.on ? &ports : NULL;
    }
    pass_buf ms = {0}, mv = {0};
    pass_out po;
    memset(&po, 0, sizeof po);
    char err[256] = "";
    int rc = pass_run(&c, c.want_global ? o->surface_target : 0, &ms, &mv, &po, "Tracing media photons", err,
                      sizeof err);
    pass_aim_free(&aim);
    ports_free(&ports);
    rc = vol_report(o, &c, &po, ms.n, mv.n, res, rc);
    res->surface_emitted = c.want_global ? po.emitted : 0;
    res->volume_emitted = c.keep_volume ? po.emitted2 : 0;
    if (rc == 0) rc = map_finish(&ms, res->surface_emitted, &res->surface, NULL, &res->nsurface);
    if (rc == 0) rc = map_finish(&mv, res->volume_emitted, &res->volume, &res->volume_medium, &res->nvolume);
    free(ms.v);
    free(mv.v);
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
    o.volume_target = LONG_MAX; /* keep all (the driver's rules: no cut, no stop by rate) */
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
