/* photon_pass.h: running a photon pass, the part both photon tracers share (photon_trace.c for
 * surfaces, volume.c for media; the walk of one photon, photon_walk.c, is both tracers', on
 * photon_path.h's state). Internal to photons/: the tracers' own headers say what a pass does.
 *
 *   records   a stored photon while tracing (pass_rec: full precision, tagged with the index
 *             of the emitted photon it came from) and a growable buffer of them (pass_buf),
 *             pushed, merged in photon order from per-thread buffers, and cut at a target by
 *             whole photon paths (the cut at the target, PASS BUDGETS in photon_trace.h);
 *             photon_records.c, under the walk, the rounds and the driver alike;
 *   aim       the caustic passes' projection maps and the light choice by power times each
 *             light's active fraction (CAUSTIC PROJECTION MAP in photon_trace.h);
 *   walk      photon_walk (photon_walk.c): one photon of either tracer, from its emission
 *             through media and off surfaces to its stores;
 *   driver    pass_run: ONE driver for both tracers' passes (photon_trace.h's surface passes
 *             and volume.h's media passes): batches of PT_BATCH on the threads, each photon
 *             traced by photon_walk, the maps cut at their targets, the budgets and, after
 *             photon_trace_set_dist / vol_set_dist, the distributed rounds (photon_rounds.c;
 *             its top comment states the rules);
 *   exchange  pass_allgather, every distributed exchange of both tracers (trace_dist;
 *             photon_records.c);
 *   messages  the texts on stderr and in err that both tracers print alike.
 */
#ifndef RENDER_PHOTON_PASS_H
#define RENDER_PHOTON_PASS_H

#include <stddef.h>
#include <stdint.h>

#include "photons/photon_trace.h"
#include "photons/projmap.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- records ---- */

typedef struct pass_rec {
    uint64_t index; /* emitted photon it came from: the merge key */
    float pos[3], power[3], dir[3], normal[3];
    int16_t kind;   /* PM_KIND_* */
    int16_t medium; /* a volume photon's medium (index into scene.media); -1: a surface photon */
    float rel; /* p(l, u) / p_l of its emission under the pass's importance table (1: none) */
} pass_rec;

typedef struct pass_buf {
    pass_rec *v;
    size_t n, cap;
} pass_buf;

int pass_buf_push(pass_buf *b, const pass_rec *p);
/* Merge the per-thread buffers (each sorted by index) onto the end of out in index order, and
 * empty them. cap_max (0: none): out's capacity never grows past it by doubling. */
int pass_buf_merge_capped(pass_buf *out, pass_buf *bufs, int nb, size_t cap_max);
static inline int pass_buf_merge(pass_buf *out, pass_buf *bufs, int nb) { return pass_buf_merge_capped(out, bufs, nb, 0); }
/* Keep the records of the first photons whose records reach `target` (each photon whole) and
 * return how many photons that is (n_e when the target is not passed); the shadow buffer (or
 * NULL) keeps the records of the same photons. */
uint64_t pass_cut_at_target(pass_buf *main_buf, pass_buf *shadow_buf, long target, uint64_t n_e);
/* A surface photon's record (medium -1); a volume photon sets medium after it. */
void pass_rec_set(pass_rec *f, uint64_t idx, vec3 p, rgb power, vec3 d, vec3 n, int kind, double rel);

/* ---- aim ---- */

typedef struct pass_aim {
    projmap *proj;     /* one per light (NULL: not built) */
    distrib1d choose;  /* lights by power x active fraction, when some light has one */
    int chosen;        /* choose was built (wsum > 0) */
    double wsum, psum; /* sums of mean-channel power x fraction, and of power */
    int nl;
} pass_aim;
/* 0, or a negative PM_E* code; with aim->chosen 0, no light can reach a specular object. */
int pass_aim_build(const scene *s, int cells, pass_aim *a);
void pass_aim_free(pass_aim *a);

/* ---- driver (both tracers' passes; the rules: the top of photon_rounds.c) ---- */

#define PASS_OVER_BUDGET 1

typedef struct pass_ctx {
    const scene *s;
    const trace_opts *o; /* a media pass's: seed, max_depth, max_bounces (volume.c fills it) */
    int media;           /* 1: a pass of volume.h (the media's rules, photon_walk.c), 0: photon_trace.h's */
    int caustic_pass;
    int want_global, want_shadow; /* a media pass: want_global keeps its surface map, no shadow */
    int keep_volume;              /* a media pass: keeps its volume map */
    vec3 lo, hi;                  /* a media pass: volume photons stored only inside (lo > hi: anywhere) */
    distrib1d choose; /* light choice for this pass */
    rgb *light_scale; /* per light: power / p_light (times the projection fraction) */
    projmap *proj;    /* caustic pass: one per light */
    const struct importance *imp; /* global pass: importance-driven emission, or NULL */
    int imp_rel_only;      /* a pilot: emit by power, and only record rel under imp */
    const struct photon_ports *ports; /* global pass: emission through photon ports (ports.h), or NULL */
    const pass_buf *tail;  /* pilot stores that follow the pass's own in the main map, or NULL */
    uint64_t tail_emitted; /* the pilot photons those stores came from */
    double shift[6];
    /* The memory budget inside a batch (one process; PASS BUDGETS in photon_trace.h): the
     * records the batch may store (0: no cap), and the count so far, shared by its threads. */
    uint64_t batch_cap;
    uint64_t *batch_records;
    /* The driver's (pass_run) rules of a media pass (volume.c sets them; 0 for surface passes):
     * the second buffer's own target (the volume map; 0: it follows the main map's cut, as the
     * shadow map does), the emission budget and its name for messages (limit 0: the surface
     * passes' max_emitted_factor x target, at most max_emitted; the caustic pass sets it for
     * its cap, photon_trace.h CAUSTIC CAP; a name with a space is printed as it is, else as a
     * setting, "photon_mapping.NAME budget"), and a media pilot's counts
     * (summed into it; such a pass keeps no map and runs to the emission budget). */
    long target2;
    double limit;
    const char *limit_name;
    struct vol_pilot *vpilot;
    /* Set by pass_run: the first photon not traced (the emission budget), and the per-thread
     * scratch counts a media walk writes (walk_out.vp). */
    uint64_t end;
    struct vol_pilot *vps;
} pass_ctx;

/* ---- the walk (photon_walk.c) ---- */

struct vol_pilot;
/* Where a walk stores, and what it reports. */
typedef struct walk_out {
    pass_buf *gb, *sb; /* surface passes: the main map's stores (global or caustic) and the
                          shadow map's; media passes: both the batch's buffer (a volume record
                          has its medium, a surface record medium -1) */
    int first_specular; /* bit 0: a caustic-pass photon whose first hit is specular; bit 1: a
                           path cut by the path-length budget */
    struct vol_pilot *vp; /* media passes: the thread's counts (the pilot's evidence, volume.h) */
} walk_out;
/* The walk of photon i of pass c: emission, flights through media (a media pass), bounces and
 * stores into o (the top of photon_walk.c). 0, PM_ENOMEM or PASS_OVER_BUDGET (a store past
 * the batch's cap, pass_store; the photon is then not whole). */
int photon_walk(const pass_ctx *c, uint64_t i, walk_out *o);

/* Store a record of the batch: PM_ENOMEM, PASS_OVER_BUDGET once the batch's records (all
 * threads') pass its cap, or 0. */
int pass_store(const pass_ctx *c, pass_buf *b, const pass_rec *fp);

/* What a pass gives back besides its buffers. */
typedef struct pass_out {
    uint64_t emitted, first_specular;
    int runaway;
    size_t whole[2]; /* the whole pass's counts, main and shadow (a partitioned pass keeps a part) */
    /* A media pass (the messages are volume.c's): photons traced, the second map's emitted
     * count and whether it fell short, the paths cut, and the budget that stopped the pass
     * (NULL: none) with what it saw. */
    uint64_t traced, emitted2, paths_cut;
    int short2;
    const char *stop;
    char why[256];
} pass_out;
/* Run one pass until its maps reach their targets or a budget stops it (the rules: the top of
 * photon_rounds.c). A surface pass: `target` stores in main_buf, shadow_buf following its cut;
 * a media pass (c->media): the surface map in main_buf (target, 0: not kept), the volume map
 * in shadow_buf (c->target2). 0, PM_ENOMEM, or for a surface pass PM_EEMPTY (message in err). */
int pass_run(pass_ctx *c, long target, pass_buf *main_buf, pass_buf *shadow_buf, pass_out *out,
             const char *title, char *err, size_t errcap);

/* The distributed setting of surface passes (photon_trace_set_dist), pass c's (a media
 * pass's: vol_set_dist's; NULL for a pilot), and whether a pass is a partitioned one (a pilot
 * pass and a media pass are always replicated). */
const trace_dist *pass_dist(void);
const trace_dist *pass_ctx_dist(const pass_ctx *c);
int pass_partitioned(const pass_ctx *c);

/* Trace photons start .. start + PT_BATCH - 1 on nthreads threads into the per-thread buffers
 * (thread t: tg[t] and ts[t]). 0; bit 0 set on failure (out of memory), bit 1 when the batch's
 * records passed c->batch_cap (the batch is then incomplete). *nfirst gains the batch's
 * first-specular photons, and its cut paths in the high 32 bits. */
int pass_trace_batch(const pass_ctx *c, uint64_t start, pass_buf *tg, pass_buf *ts, int nthreads,
                     uint64_t *nfirst);
/* The memory budget's prefix (photon_rounds.c's rules): photons start .. of a batch traced on
 * one thread into tg[0] and ts[0] while their records stay within cap; the first photon past
 * it is dropped whole. Returns that photon's index (the batch's end, or c->end, when all
 * fit); *fail set on out of memory. */
uint64_t pass_trace_prefix(pass_ctx *c, uint64_t start, uint64_t cap, pass_buf *tg, pass_buf *ts, uint64_t *nfirst,
                           int *fail);

/* ---- distributed rounds (photon_rounds.c) ---- */

typedef struct pass_batch_count {
    uint64_t nmain, nshadow;
    uint64_t end; /* its photons before end (the memory budget's prefix); UINT64_MAX: the whole batch */
} pass_batch_count;
/* The exchanged bytes of the current round: batch j of it starts at photon start + j PT_BATCH;
 * `next` is the batch to hand out, at byte `off`. target, stored and limit are the pass's,
 * for sizing the rounds. A partitioned pass keeps each batch's counts in bc. */
typedef struct pass_rounds {
    uint64_t start;
    int nbatch, next;
    char *all;
    size_t *sizes, off;
    long target;
    const pass_buf *stored;
    double limit;
    pass_batch_count *bc;
    size_t nbc, capbc;
} pass_rounds;
void pass_rounds_free(pass_rounds *rb);
/* Batch [n_e, n_e + PT_BATCH) of a distributed pass: a replicated pass's records into tg[0] and
 * ts[0]; a partitioned pass's counts into rb->bc and the count-only buffers main_buf and
 * shadow_buf (NULL: none). 0, 1 on failure anywhere, 2 when the batch passed the memory
 * budget (every process stops there). */
int pass_dist_batch(const pass_ctx *c, pass_rounds *rb, uint64_t n_e, pass_buf *tg, pass_buf *ts, int nthreads,
                    uint64_t *nfirst, pass_buf *main_buf, pass_buf *shadow_buf);
/* A partitioned pass: a batch every process traced alike, the memory budget's prefix
 * (pass_trace_prefix: its photons before end; UINT64_MAX: the whole batch), which stored
 * nmain and nshadow records, counted in rb->bc and the count-only buffers as pass_dist_batch
 * counts one. 0, or PM_ENOMEM. */
int pass_part_count(const pass_ctx *c, pass_rounds *rb, uint64_t nmain, uint64_t nshadow, uint64_t end,
                    pass_buf *main_buf, pass_buf *shadow_buf);
/* The end of a partitioned pass (photon_trace.h, trace_dist.partitioned): the cut at the
 * target found by tracing its batch again, then this process's part of the main map traced
 * again into out. Sets vm, vs and *n_e to the whole pass's figures. Every process returns the
 * same: 0, or PM_ENOMEM if any failed. */
int pass_part_finish(const pass_ctx *c, pass_rounds *rb, long target, uint64_t *n_e, pass_buf *vm, pass_buf *vs,
                     pass_buf *out, pass_buf *tg, pass_buf *ts, int nthreads);

/* ---- exchange ---- */

/* Every process's bytes in part order: d->allgather, with *all (malloc'd) and *sizes (calloc'd,
 * nparts; reused when non-NULL) for the caller to free. 0, or -1 on failure anywhere. */
int pass_allgather(const trace_dist *d, const void *mine, size_t nbytes, void **all, size_t **sizes);

/* ---- messages ---- */

/* "[render: FILE: ]photon tracing: TITLE: N photon paths were cut by the path-length budget
 * (photon_mapping.max_bounces = B)" on stderr (file NULL or "": no prefix). */
void pass_say_cut(const char *file, const char *title, uint64_t cut, int max_bounces);
/* "[render: FILE: ]photon tracing: TITLE: only N of T photons stored after E emitted[WITH];
 * stopped by the BUDGET (WHY)" on stderr. */
void pass_say_short(const char *file, const char *title, size_t n, long target, uint64_t n_e, const char *with,
                    const char *budget, const char *why);
/* The message of a pass that stored nothing: the lights reach no PLACES that stores photons,
 * and "; stopped by STOPPED" when stopped is non-NULL. */
void pass_say_empty(char *err, size_t errcap, const char *title, uint64_t n_e, const char *places,
                    const char *stopped);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PHOTON_PASS_H */
