/* photon_trace.h: photon tracing: emit photons from the lights, scatter them through the
 * scene, and classify what they leave on diffuse surfaces into the caustic, global and
 * shadow maps (Jensen, "A practical guide to global illumination using photon maps").
 *
 * EMISSION. Photon i picks its light and its origin and direction from a Halton point (bases
 * 2, 3, 5, 7, 11, 13; radical inverses of i + 1, shifted by a seed-dependent rotation), so
 * emission is stratified (sample_halton, sampling.h); lights are chosen in proportion to
 * their power (the scene's light_distrib), through light_sample_le (area: uniform point, cosine direction; point:
 * uniform direction; directional: a disc covering the scene). The power of every photon is
 * P_light / (p_light * n_e), n_e being the number emitted for the map.
 *
 * IMPORTANCE. With o->importance (importance.h) the global pass emits by the table's defensive
 * mixture instead: photon i's Halton dimension 0 picks uniform emission (light by power) or a
 * level and cell of the table, dimensions 1-4 the point in the light's u-space or in the cell,
 * and its power is the uniform photon's divided by rel = p(l, u) / p_l.
 *
 * PILOT PHOTONS. A pilot pass (plan_pilots.c: emission by power, its own streams) may keep its
 * photons (trace_pilot.keep): the global pass's stores, with each photon's rel under the
 * importance table the real pass will use, and the caustic pass's L S+ D stores. A real pass
 * joins them (trace_opts.reuse; pilot_photons_joining says whether, and why not) when they
 * were traced by its rules (the same max_depth and max_bounces; for the global pass the same
 * importance table and the maps it builds; for the caustic pass the same projection maps:
 * projection on with the same projection_cells) and stored less than half its target,
 * counting their stores toward the target. The two emissions are combined by the balance
 * heuristic: with n_p pilot photons (density p_l) and n_m of the pass's (density rel p_l),
 * every photon's power is P_l / p_l / (n_p + n_m rel), which is unbiased and for rel = 1 the
 * plain P_l / p_l / (n_p + n_m). The caustic pass never emits by importance, and the pilot's
 * caustic pass aims through the same projection maps as the pass (light chosen by P_l f_l,
 * a uniform point of an active cell): the two densities are the same, rel = 1, and the
 * caustic map is the pooled estimate, every photon at P_l f_l / p_l / (n_p + n_m). The whole
 * map is the pass's stores followed by the pilot's; a partitioned distributed pass keeps each
 * process's part of that order, so its parts are those of the one-process maps.
 * global_emitted and caustic_emitted count both emissions; pilot_emitted / pilot_stored (in
 * photon_maps) the pilot's share. The stored count, and so the estimates' noise, stays what
 * the target asks: the gain is the pass's emissions saved (n_p of them). The pilot's streams
 * come from the scene's seed (plan_pilot_seed, plan.h), so its share of a map (n_p / (n_p +
 * n_m) of the weight) is drawn anew with the seed like the pass's photons: with one fixed
 * pilot for every seed, cornell_spheres' caustic (caustic_photons 20000, the pilot 10% of the
 * weight) read -1.9% and, for another fixed pilot, -1.1% against no pilot over 6 seeds,
 * offsets that no averaging over seeds would remove (the pilots' photons are distributed as
 * the pass's: floor power in 124 cells, 60 pilots against 12 passes, chi2 126.6).
 *   Not joined: a caustic pass without the projection map (projection false) or with other
 * cells: the pilot is always aimed (the plan needs it), so the two densities differ, and
 * each photon would need its ratio of them (1 / F in the pilot's active cells and 0 outside,
 * F the power-weighted active fraction, for projection false); not built, as a setting away
 * from the default; maps loaded instead of traced; a scene with media, whose maps and pilot
 * are volume.h's (that pilot keeps no photons: joining there is volume.c's to build).
 * caustic_stride does not matter: it changes where the caustic map is read, not the map.
 * CAUSTIC PROJECTION MAP. The caustic pass emits only into the active cells of each light's
 * projection map (projmap.h), chooses a light in proportion to P_light * f_light with f_light
 * its fraction of active cells, and scales each photon's power by that fraction (Jensen's
 * eq. 2.2). The emissions this saves, n_e (1/f - 1) with f the power-weighted active
 * fraction, are reported.
 *
 * SCATTERING. At each hit, Russian roulette picks the diffuse, specular-reflection or
 * transmission branch, or absorption, with probabilities P_x = max_c(w_x t_c Phi_c) /
 * max_c(Phi_c) (w_x the branch weight, t the branch colour, Phi the photon power: the maximum
 * over colour channels), and divides the power by the chosen probability, so photon powers
 * stay even. Paths stop at the scene's max_depth.
 *
 * STORAGE AND CLASSES. Photons are stored only on surfaces with a diffuse branch, with the
 * power arriving there, the direction of travel and the normal on the side they arrived at:
 *   global map   every such hit of the global pass (L {S|D}* D), kind DIRECT for the first
 *                hit from the light, INDIRECT after one or more bounces;
 *   caustic map  hits of the caustic pass whose path so far was all specular (L S+ D);
 *   shadow map   from area lights only: the first hit's photon (DIRECT) and, continuing
 *                the light's ray straight on through every surface, SHADOW photons at the
 *                later diffuse hits. A renderer asks whether the nearest photons are all
 *                DIRECT (lit) or all SHADOW (dark) to skip shadow rays.
 *
 * DETERMINISM AND THREADS. Photon i uses only its own random stream rng_stream(seed, i, pass)
 * and its Halton point, and photons are traced in batches of PT_BATCH on all threads (OpenMP)
 * and merged in photon-index order; the number of batches depends only on the counts stored.
 * So the maps are bit-identical for any thread count, and a small change to the scene changes
 * only the photons whose paths it touches.
 *
 * PASS BUDGETS. A pass stops when its target count is stored: it keeps the stores of the
 * first emitted photons that reach the target, each photon whole, and counts only those as
 * emitted (so the stored count exceeds the target by less than one path, and the powers stay
 * unbiased). Budgets stop it earlier, and the message on stderr names the one that did
 * ("stopped by the photon_mapping.KEY budget"):
 *   emitted    max_emitted_factor x target, and at most max_emitted photons (exactly: the
 *              last batch is cut there); a pass that cannot reach its target takes the whole
 *              budget (no stop by rate: photon_rounds.c's rules);
 *   memory     max_memory_mb of photon buffers (the map's buffers grow to at most the
 *              budget, not by doubling past it): checked between batches, and inside a batch:
 *              a batch whose records, with those held, would pass the budget keeps its
 *              longest prefix of photons that fit (each whole; one batch can store PT_BATCH
 *              times the path length: 19 GB in a lossless furnace with max_depth 1e5) and
 *              the pass stops there, for any thread count and, in a distributed pass
 *              (replicated or partitioned), any process count (the maps are the one-process
 *              maps, budget stops included; a partitioned pass keeps its part of them). A
 *              pass stopped so before storing anything ends with PM_EEMPTY and a message that
 *              names the budget;
 *   path       max_bounces bounces per photon (below the scene's max_depth), so one photon
 *              stores a bounded number of records (the furnace with reflectance 1 would
 *              bounce to max_depth); the paths cut are counted and reported;
 *   stored     the target itself, as above.
 * A pass that stores nothing in PASS_EMPTY_BATCHES batches (lights that face nothing, a light
 * inside a closed mirror) ends with PM_EEMPTY and a message that says so: there is no map to
 * render from, and `render` exits non-zero instead of writing a black image. A pass that
 * stored some photons but hit a budget keeps them (runaway flag set).
 *
 * CODE. photon_trace.c has the passes' bookkeeping; what both tracers share, this one and
 * volume.h's, is the walk of one photon (photon_walk.c, on photon_path.h's state: bounces,
 * kinds, the refraction chain, the path-length cut; EMISSION and SCATTERING above are its
 * surface passes' rules) and photon_pass.h's (the records, the cut at the target, the caustic
 * pass's aim, the budgets' messages, the distributed exchange, and the ONE pass driver of
 * both tracers, its batches, rounds and rules: photon_pass.c, photon_rounds.c).
 *
 * OWNERSHIP. photon_trace fills a photon_maps (photon_maps.h) whose arrays it allocates;
 * photon_maps_free frees them.
 *
 * DISTRIBUTED PASSES (render/mpi/). After photon_trace_set_dist(d), a pass runs in rounds of
 * d->nparts x m batches: this process traces the round's batches d->part m .. d->part m + m - 1
 * (on its threads), and d->allgather gives every process all the round's batches, which then
 * go through the one-process bookkeeping one batch at a time: stored counts, the budgets and
 * stopping tests, the index-order merge. So every process ends with the one-process maps bit
 * for bit, having traced about 1/nparts of the photons. m starts at 1 and then follows the
 * batches still needed at the rate stored so far (at most 16), so rounds are few and at most
 * nparts - 1 batches are traced past the stopping point and dropped.
 */
#ifndef RENDER_PHOTON_TRACE_H
#define RENDER_PHOTON_TRACE_H

#include <stdint.h>

#include "photons/photon_maps.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* PT_BATCH (photons per batch) and the budget defaults PASS_MAX_MEMORY_MB, PASS_MAX_EMITTED and
 * PASS_MAX_BOUNCES are photon_settings.h's (the settings' table, a stage below, needs them as
 * its defaults and ranges); photon_maps.h includes it. */
/* A pass that stores nothing in this many batches stops with PM_EEMPTY. */
#define PASS_EMPTY_BATCHES 32

/* A pilot's photons kept for the real passes (PILOT PHOTONS above); opaque. */
typedef struct pilot_photons pilot_photons;
void pilot_photons_free(pilot_photons *k);

/* A pilot pass's evidence (plan_pilots.c): counts of pilot photons, in total and by the material
 * named (its index; PILOT_MAX_MATS - 1 collects any beyond). */
#define PILOT_MAX_MATS 64
typedef struct pilot_counts {
    unsigned long long total, by_mat[PILOT_MAX_MATS];
} pilot_counts;
typedef struct trace_pilot {
    unsigned long long emitted; /* pilot photons emitted */
    pilot_counts first_hits;     /* photons' first hits, by the surface hit */
    pilot_counts caustic;        /* L S+ D stores (caustic pass), by the first specular surface */
    pilot_counts diffuse_bounce; /* stores after a diffuse bounce, by that bounce's surface */
    pilot_counts occluder;       /* photons from area lights that reach a diffuse surface behind
                                    their first hit (a shadow photon), by the first hit */
    int keep; /* 1: keep the passes' stores in kept (the caller frees it; when kept is set
                 already, by another pilot's call, the passes run here are added to it) */
    pilot_photons *kept;
} trace_pilot;

/* CAUSTIC CAP. A caustic pass that emits CAUSTIC_CAP_FACTOR times the global pass's photons
 * (at least CAUSTIC_CAP_MIN) without reaching its target is rare light: the photon mapper
 * stops it there when the caller asks (trace_opts.caustic_cap; the media tracer always, in
 * pm_volume.c), and it keeps what it stored for the photons emitted (unbiased, a smaller
 * map). The photon mapper asks for it where it does not yet know the camera sees the caustic
 * map, or knows it barely does (photon_mapping/pm_fit.c, THE CAUSTIC CAP). A caller may lower the floor
 * (trace_opts.caustic_cap_min). */
#define CAUSTIC_CAP_FACTOR 4.0
#define CAUSTIC_CAP_MIN 4194304.0

typedef struct trace_opts {
    int global, caustic, shadow;     /* which maps to build */
    long global_target, caustic_target; /* photons to store */
    double max_emitted_factor;       /* give up after this many times the target emitted */
    double max_emitted;              /* and after this many emitted (0: no absolute cap) */
    size_t max_memory_bytes;         /* photon buffers of a pass (0: no cap) */
    int caustic_cap;                 /* 1: the caustic pass emits at most CAUSTIC_CAP (below) */
    double caustic_cap_min;          /* the cap's floor when above 0 and below CAUSTIC_CAP_MIN
                                        (the photon mapper's first stage, pm_preprocess.c THE
                                        CAUSTIC PROBE); else CAUSTIC_CAP_MIN */
    uint64_t cap_global_emitted;     /* a trace without a global pass (the photon mapper's
                                        caustic-only trace): the global photons emitted that
                                        CAUSTIC_CAP scales with (0: none) */
    int max_bounces;                 /* photon path length cap below max_depth (0: none) */
    int projection, projection_cells;
    /* The global pass (and its shadow photons) emits by this table (importance.h; the plan
     * builds it) when non-NULL and on; NULL: by power alone. Not used by a pilot. */
    const struct importance *importance;
    const pilot_photons *reuse; /* the plan's pilot photons to join the maps, or NULL */
    int max_depth;
    uint64_t seed;
    int threads; /* 0: OpenMP's default */
    int quiet;   /* no progress or messages except errors and the runaway warning */
    trace_pilot *pilot; /* non-NULL: a pilot pass; counts evidence here, prints nothing and
                           adds nothing to the statistics */
} trace_opts;

/* Fill the options from the scene's settings: seed, max_depth, the budgets' defaults; the
 * rest zero. */
void trace_opts_init(trace_opts *o, const scene *s);
/* trace_opts_init, then the photon settings c: the targets, budgets, projection and
 * progress (quiet = !c->progress). Which maps, the importance table and reuse are the
 * caller's. */
void trace_opts_settings(trace_opts *o, const scene *s, const photon_settings *c);

/* Whether a pass with options o joins the stores of k to its map (PILOT PHOTONS): caustic 0
 * the global pass's main map (global, else shadow), 1 the caustic map. 1: they join, with
 * *stores the pilot's stores that join that map and *emitted the pilot photons they count
 * as emitted (either may be NULL); 0: not, with *why (if non-NULL) saying why (a static
 * string; "" when k is NULL or holds no such pass). photon_trace decides by this function,
 * so a plan can print what the pass will do. */
int pilot_photons_joining(const pilot_photons *k, const trace_opts *o, int caustic, size_t *stores,
                          uint64_t *emitted, const char **why);

typedef struct trace_dist {
    int nparts, part; /* processes, and this one's place among them */
    /* Every process calls it with its bytes; it returns the concatenation of all processes'
     * bytes in part order (*all: malloc'd, the caller frees it) and their sizes (sizes[k]
     * for part k). 0, or negative on failure (then every process must see the failure). */
    int (*allgather)(void *user, const void *mine, size_t nbytes, void **all, size_t *sizes);
    void *user;
    /* 1: a partitioned pass. The rounds exchange only each batch's counts (stores in the main
     * and shadow buffers, first-specular and cut paths: 32 bytes), never a photon, so every
     * process runs the same bookkeeping and stops where one process would. Then every process
     * traces the stopping batch again to find the cut (the emitted photon whose stores reach
     * the target), and traces again only the batches holding its part of the stored photons:
     * process p keeps the main map's stores p n / nparts .. (p + 1) n / nparts - 1 in index
     * order (n: the whole map's count), no shadow-map photons, and the maps come back with
     * part 1 and the whole maps' counts and largest powers (one more all-gather of 24 bytes
     * per process) in whole_* (photon_maps.h). Each process traces about 2 / nparts of the
     * photons; its memory holds its part and one round's counts. */
    int partitioned;
    /* NULL, or called by a process whose own tracing failed (out of memory), with what
     * failed, before the exchange that tells every process: render-mpi names the process
     * there and stops the job (it need not return; if it does, the pass fails everywhere). */
    void (*failed)(void *user, const char *what);
    /* Test hook, NULL, or asked once for each batch a process traces in a distributed pass
     * (also the batches a partitioned pass traces again): nonzero fails that batch as if an
     * allocation of the tracer had failed. */
    int (*test_fail)(void *user);
} trace_dist;
/* Distribute every later pass as described above (NULL: back to one process). The caller
 * keeps d alive while passes run. */
void photon_trace_set_dist(const trace_dist *d);
/* Trace the maps. Returns 0, or a negative PM_E* code with a message (PM_ENOMEM; PM_EEMPTY
 * for a pass that stores nothing, see PASS BUDGETS). */
int photon_trace(const scene *s, const trace_opts *o, photon_maps *m, char *err, size_t errcap);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PHOTON_TRACE_H */
