/* photon_records.c: the records of a photon pass (photon_pass.h), under both tracers' walk
 * (photon_walk.c), rounds (photon_rounds.c) and driver (photon_pass.c): the per-thread buffers,
 * the store with its batch cap, the cut at the target, and the all-gather of a distributed round.
 */
#include "photons/photon_pass.h"

#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"

/* ---- records ------------------------------------------------------------------------------ */

/* photon_rounds.c sends a batch's head in the room of one record. */
_Static_assert(sizeof(pass_rec) == 64, "pass_rec is 64 bytes");

int pass_buf_push(pass_buf *b, const pass_rec *p) {
    /* Doubling growth of this array (photon_rounds.c grows another type's alike). */
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

/* ---- exchange ------------------------------------------------------------------------------ */

int pass_allgather(const trace_dist *d, const void *mine, size_t nbytes, void **all, size_t **sizes) {
    if (!*sizes) *sizes = calloc((size_t)d->nparts, sizeof **sizes);
    if (!*sizes) return -1;
    return d->allgather(d->user, mine, nbytes, all, *sizes) < 0 ? -1 : 0;
}
