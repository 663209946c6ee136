/* volume.h: photon tracing for scenes with participating media: the volume photon maps, and the
 * surface maps attenuated by the media on the way.
 *
 * One photon: a light is chosen in proportion to its power and a point and direction sampled
 * from it (light_sample_le; photon power = light power / (n p_light) for n emitted). The
 * photon starts in the medium on the light's side of the first surface its ray meets (the
 * global medium if it meets none). In a medium it samples free-flight distances (medium.h);
 * at each scattering event it may store a VOLUME photon: its position, the direction it
 * travelled, and the scattered power (the power arriving times the free-flight weight, which
 * is sigma_s / sigma_t in a grey medium), then continues in an HG direction with Russian
 * roulette on that weight, so a photon's power stays constant in a grey medium. At a surface
 * with a diffuse branch it may store a SURFACE photon (position, the power arriving, the
 * direction, the normal on the side it arrived at), then scatters by material_sample
 * (roulette on the branch weight). Null surfaces only change the medium (no bounce).
 *
 * Kinds (pm_photon_kind), the same for both places: PM_KIND_DIRECT for a photon's first event
 * straight from the light (through media without scattering), PM_KIND_CAUSTIC for the first
 * event after one or more specular surface bounces and nothing else (L S+ V, L S+ D),
 * PM_KIND_INDIRECT for every other event. A renderer that computes single scattering by ray
 * marching with shadow rays leaves the DIRECT volume photons out of its estimates.
 *
 * PASSES (vol_trace_pass). The GLOBAL pass keeps every surface photon (the global map) and
 * every volume photon; the CAUSTIC pass keeps only L S+ D surface photons (the caustic map) and
 * L S+ V volume photons (the volume caustic map), and ends a photon's path at its first diffuse
 * bounce or scattering event. Each kept map has its own store target and its own emitted
 * count: the map holds the photons of the first n_e emitted paths whose stores reach the target
 * (each path whole), scaled by 1/n_e, so a thin medium can take many more photons than the
 * surfaces without the surface map growing with it. A map that never reaches its target keeps
 * everything emitted, within max_emitted. A map that stores nothing in the first
 * PASS_EMPTY_BATCHES x PT_BATCH (131072) emitted stops there (empty). With projection_cells > 0 the caustic pass
 * emits only into the active cells of each light's projection map (projmap.h: directions
 * that can meet a specular object, null surfaces included) and chooses lights in proportion
 * to power times active fraction, with each photon's power scaled by that fraction (Jensen's
 * eq. 2.2), as photon_trace does.
 *
 * BUDGETS: the one driver's (pass_run; the rules at the top of photon_rounds.c), as
 * photon_trace.h's PASS BUDGETS, with the same messages on stderr (none in a pilot):
 *   emitted  max_emitted photons at most (the caller's min of max_emitted_factor x target and
 *            max_emitted, named by max_emitted_budget); a map short of its target then says
 *            "photon tracing: Tracing volume photons: only N of T photons stored after E
 *            emitted; stopped by the photon_mapping.KEY budget (...)" (or another budget the
 *            caller names). A map that cannot reach its target (the wall behind a
 *            smoke-filled glass) takes the whole budget;
 *   memory   max_memory_bytes of 64-byte records while tracing: the maps' buffers between
 *            batches; a batch whose records would pass what is left keeps its longest prefix
 *            of photons that fit (each whole) and the pass ends there, for any thread or
 *            process count;
 *   path     max_bounces bounces per photon below max_depth; the paths cut are counted
 *            ("N photon paths were cut by the path-length budget (photon_mapping.max_bounces
 *            = B)");
 *   stored   each map's target, as above.
 * A pass that keeps a map and stores nothing in any (the lights reach no diffuse surface or
 * scattering medium) fails with PM_EEMPTY and the message in the result's msg ("no photon
 * stored after N emitted"); render then exits 1, as for photon_trace's empty pass.
 *
 * DETERMINISM AND THREADS. Photon i of a pass uses only rng_stream(seed, i, stream); photons are
 * traced in batches of PT_BATCH on all threads (OpenMP), merged in photon order (pass_run).
 * The maps are bit-identical for any thread count.
 *
 * PILOT. With a vol_pilot the pass keeps nothing and counts what the photons do (the plan's
 * evidence, plan.h).
 *
 * CODE. volume.c sets a pass's options, packs its maps and says its messages; the driver is
 * pass_run (photon_pass.c, photon_rounds.c), the surfaces' tracer's too; the walk of one
 * photon is photon_walk.c's, shared with
 * photon_trace.c (with the medium handling in it, and this tracer's rules of emission and
 * bounces, above), on photon_path.h's state (bounces, kinds, the refraction chain, the
 * path-length cut); the caustic pass's aim, the exchange and the budgets' messages are
 * photon_pass.h's.
 *
 * Ownership: the caller frees the result's arrays (vol_pass_free, or free() on vol_photons).
 */
#ifndef RENDER_VOLUME_H
#define RENDER_VOLUME_H

#include <stddef.h>
#include <stdint.h>

#include "photonmap/photon.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

#define VOL_PILOT_MEDIA 16 /* media counted separately; the last slot collects any beyond */
#define VOL_PILOT_MATS 64  /* materials counted separately; the last slot collects any beyond */
typedef struct vol_photons {
    pm_photon *photons;
    size_t count, cap;
} vol_photons;

/* Trace n photons (bounces limited to max_depth per photon), keeping every volume photon (all
 * kinds) and no surface photon, powers for n emitted. 0, or PM_ENOMEM / PM_EINVAL (no light
 * with power) with out empty. */
int vol_trace(const scene *s, uint64_t n, uint64_t seed, int max_depth, vol_photons *out);

typedef struct vol_pilot {
    unsigned long long emitted;
    unsigned long long events[VOL_PILOT_MEDIA][4]; /* scattering events by medium and kind */
    unsigned long long caustic_by_mat[VOL_PILOT_MATS]; /* L S+ V events by the first specular
                                                           surface's material */
    unsigned long long surf_direct, surf_caustic, surf_indirect; /* diffuse-surface arrivals */
    unsigned long long surf_after_scatter; /* of those, after a scattering event in a medium */
} vol_pilot;

typedef struct vol_pass_opts {
    int caustic_pass;               /* 0: the global pass, 1: the caustic pass */
    long surface_target, volume_target; /* stores to reach; 0: that map is not kept */
    double max_emitted;             /* photons emitted at most */
    const char *max_emitted_budget; /* what max_emitted comes from, for messages ("stopped by
                                       the ..."; NULL: "photon_mapping.max_emitted budget") */
    size_t max_memory_bytes;        /* records while tracing (BUDGETS; 0: no cap) */
    int max_depth;                  /* bounces (surface and volume) per photon: render.max_depth */
    int max_bounces;                /* the path-length budget below max_depth (0: none) */
    uint64_t seed;
    int threads;       /* 0: OpenMP's default */
    vol_pilot *pilot;  /* non-NULL: count (summed into it), keep nothing */
    int projection_cells; /* caustic pass: aim the photons through projection maps of this
                             many cells per side (projmap.h); 0: emit in all directions */
    /* Volume photons outside [lo, hi] are traced on but not stored (where nothing reads them:
     * an unbounded medium around the scene); lo > hi: no limit. */
    vec3 lo, hi;
} vol_pass_opts;

typedef struct vol_pass_result {
    pm_photon *surface, *volume;
    short *volume_medium; /* the medium (index into scene.media) of each volume photon */
    size_t nsurface, nvolume;
    uint64_t surface_emitted, volume_emitted; /* each map's n_e */
    uint64_t emitted;                         /* photons traced by the pass */
    int surface_short, volume_short;          /* 1: the map stopped short of its target */
    uint64_t cut;                             /* photon paths cut by max_bounces */
    char msg[512];                            /* PM_EEMPTY: what happened (BUDGETS) */
} vol_pass_result;

/* Run a pass. 0, or PM_ENOMEM / PM_EINVAL (no light with power, bad options) / PM_EEMPTY
 * (nothing stored, r->msg says so) with r empty but for msg. */
int vol_trace_pass(const scene *s, const vol_pass_opts *o, vol_pass_result *r);
void vol_pass_free(vol_pass_result *r);

/* DISTRIBUTED PASSES (render/mpi/; set by render-mpi, NULL by default). After vol_set_dist(d)
 * every process runs every pass's rounds, but traces only its share of each round's batches;
 * d->allgather then gives every process every batch (its records and counts), and the merge
 * goes on as in one process: every process ends
 * with the one-process maps bit for bit, the budgets' stops included. Pilot passes are traced
 * whole by every process (each plans as one process does). A process whose own batch failed
 * (out of memory) calls d->failed before that exchange, and d->test_fail is asked once per
 * batch it traces (photon_trace.h). The rounds are photon_trace.h's (one driver); a media
 * pass is always replicated, also with d->partitioned. The caller keeps d alive. The setting belongs to the
 * calling thread (the one that runs the passes). */
struct trace_dist;
void vol_set_dist(const struct trace_dist *d);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_VOLUME_H */
