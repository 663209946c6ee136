/* photon_maps.h: the three photon maps of the renderer as data: what photon tracing
 * (photon_trace.h) fills or the map files give back, the kd-trees built over them, and the
 * radius policy of their estimates.
 *
 * MAP FILES. photon_maps_save writes DIR/global.pmap, caustic.pmap and shadow.pmap, all
 * three (an empty map too), in the format of photonmap/mapfile.h (tree_bucket 0: the photons
 * as traced, before a kd-tree reorders them, so loading them gives the same trees and the
 * same image bit for bit). The maps of a scene with media (nmedia > 0, pm_volume.h) add
 * DIR/volume-M.pmap and DIR/volume_caustic-M.pmap for each medium M (its index in $.media,
 * 0..nmedia-1; all of them, an empty map too), both of kind PM_MAP_VOLUME: the volume
 * photons of the global pass (every kind) and of the caustic pass (L S+ V) that scattered in
 * medium M, in photon order (so the per-medium trees pm_volume.c builds from them are the
 * traced run's, and so is the image). Each header carries the map's kind and the maps' stamp
 * in its two tags: tag[0] the scene's transport hash (scene_hash.h: geometry, materials,
 * lights, media; not the camera), tag[1] the tracer's version and the hash of the settings
 * that shaped the photons (map_stamp_make): bits 48-63 PHOTON_TRACE_VERSION (below), bits
 * 0-47 a hash of that version, which maps the plan traced, and for those maps the photon
 * targets, every pass budget (max_emitted_factor, max_emitted, max_memory_mb, max_bounces),
 * the projection maps (projection, projection_cells; caustic map only) and
 * render.max_depth; in a scene with media (map_stamp_volume) also the volume maps the plan
 * traced, their targets, and the camera's position (the volume passes keep only photons
 * inside the box around the scene, the lights and the eye, pm_volume.h). A volume file's
 * tag[1] has its role and medium mixed into bits 0-47 (map_stamp_file), so a volume map
 * under the name of another medium's, or a volume-caustic map under a volume map's name, is
 * a map of the wrong kind. Left out, because they do not change which photons a pass stores:
 * the seed (it picks another sample of the same photon distribution, so loading one set of
 * maps under several seeds is how new camera noise is drawn over fixed photons), the thread
 * count (the maps do not depend on it), and everything the camera pass alone reads (image
 * size, samples, k_*, radii, filter, gather settings, volume_step, volume_boundary, volume_beam,
 * tone).
 * The global and caustic maps hold the plan's pilot photons that joined them (photon_trace.h,
 * PILOT PHOTONS), as traced (the saved caustic map is the pass's stores then the pilot's);
 * whether they join and what they are depends only on what the stamp covers and on the
 * seed (the pilot's streams, plan_pilot_seed in plan.h, left out like the passes' own seed;
 * its rules are the passes' max_depth, max_bounces and projection maps; the targets decide
 * the half-target rule).
 *
 * IMPORTANCE. The global pass's importance-driven emission (importance.h) is steered by
 * importance_paths and importance_defensive, which are stamped, and by the camera, the image
 * size, the seed and final_gather (without it the plan emits by power), which are not: like
 * the seed, they pick another sample whose expected power everywhere is the same (each photon's power is divided by its emission probability), so
 * maps traced for one view render another view without bias, only with other noise.
 *
 * TRACER VERSION. PHOTON_TRACE_VERSION names what photon tracing means: which photons a pass
 * stores for given scene and settings, and with what power, position, direction and kind.
 * Bump it in the same commit as any change to render/photons/photon_walk.c, photon_trace.c, volume.c,
 * render/projmap.c, or to what they call (light_sample_le and the light distribution,
 * material_sample / material_weights / material_radiance_scale, medium_sample_distance,
 * hg_sample, scene_offset, the rng streams) that changes a stored photon; a change that
 * leaves every stored photon bit for bit as it was (speed, messages) needs no bump. Maps
 * stamped with another version are refused like maps of other settings ("traced by photon
 * tracer version N"), and so are maps saved before the version was stamped (their bits
 * 48-63 are an arbitrary part of the old hash).
 *
 * photon_maps_load reads them back and refuses, with PM_EINVAL (render exits 2) and a
 * message that names the file: a directory that does not exist or is not one; a missing
 * file (a directory of saved maps holds all three, and for a scene with media the two volume
 * files of each medium); a file that is not a photon map, is truncated or corrupt, or of
 * another version; a file of the wrong kind (global.pmap must hold a PM_MAP_GLOBAL map,
 * volume-1.pmap the volume map of medium 1, and so on; forcing does not change this); and,
 * unless forced, a map whose stamp differs from the run's: traced from another scene (or the
 * scene was edited since), by another version of the photon tracer, with other settings, or
 * with no stamp (written by an older version, or by another program with tag 0). Forced, a
 * mismatched map is used and one warning per file on stderr says what differs (a forced
 * volume file whose stamp differs cannot be checked for its role: only its kind is). Out of
 * memory is PM_ENOMEM.
 *
 * RADII. Maximum search radii are automatic unless the settings give them: Christensen's
 * radius beyond which k photons of the largest power would give less than a threshold
 * radiance, 0.5% of the mean radiance the lights' power would give on the diffuse area
 * (phi / (pi A)). The "typical" radius is that of a k_global estimate at the global map's
 * mean density; the precomputed-irradiance lookup searches within 4 of them (at most the
 * global radius), and the shadow-map query within 2 of its own typical radius.
 *
 * PHOTON PATHS. The global map's photons are not independent samples: one emitted photon
 * stores a record at every diffuse surface it bounces off (a path), and an estimate's error
 * goes with the number of paths its photons come from, not with their number (photon_sides.h,
 * "Sparse estimates"). photon_tree_build_global numbers the paths before the tree reorders
 * the records, from the map as traced, saved and loaded: photon tracing merges each batch in
 * emitted-photon order and keeps each photon's stores together, first hit first (photon_trace.h,
 * DETERMINISM), and a path's first store is its only DIRECT one when its first hit is diffuse.
 * So a new path begins at every DIRECT record, and path ids are recomputed from the records
 * alone: no file, checkpoint or distributed exchange carries them, and traced, saved, loaded
 * and partitioned maps (each process's part is a run of that order) number them alike. A
 * path whose first hit is specular (a mirror, glass) has no DIRECT store and is counted with
 * the path before it; so is the first path of a part that begins mid-path. Merging two paths
 * only ever lowers a count of distinct paths, so an estimate is never read because of it.
 *
 * Ownership: a photon_maps owns its arrays (photon_maps_free; a zeroed one may be freed).
 */
#ifndef RENDER_PHOTON_MAPS_H
#define RENDER_PHOTON_MAPS_H

#include <stddef.h>
#include <stdint.h>

#include "photonmap/kdtree.h"
#include "photonmap/photon.h"
#include "load/photon_settings.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The version of photon tracing in every map's stamp: see TRACER VERSION above for when to
 * bump it. */
/* 2: importance-driven emission and the plan's pilot photons joined (global pass); 3: the
 * caustic pilot's photons joined too (the caustic map); 4: the joining pilot's streams
 * follow the scene's seed (plan_pilot_seed); 5: one pass driver for both tracers (the rules
 * at the top of photon_rounds.c): a pass stopped by the memory budget keeps its batch's
 * longest prefix that fits, the emission budget is exact, no stop by rate, a map's first
 * store may come up to 131072 photons; 6: the media tracer emits a share of its photons through
 * photon ports, declared or found by the plan's probe, which now runs in scenes with media too
 * (ports.h, MEDIA); 7: a diffuse bounce aims at the ports with a share that falls with the
 * photon's weight so far (ports.h, BOUNCES). */
#define PHOTON_TRACE_VERSION 7

/* A map set's stamp: scene_transport_hash and the tracer version + settings hash
 * (map_stamp_make). */
typedef struct map_stamp {
    uint64_t scene, settings;
} map_stamp;

typedef struct photon_maps {
    pm_photon *global, *caustic, *shadow;
    size_t nglobal, ncaustic, nshadow;
    /* The path of every global photon (PHOTON PATHS above), in global's order: set by
     * photon_tree_build_global (NULL before). */
    uint32_t *global_path;
    uint64_t global_emitted, caustic_emitted; /* the shadow map shares the global pass */
    double caustic_fraction;        /* power-weighted active fraction of the projection maps */
    uint64_t caustic_saved;         /* emissions the projection map saved */
    uint64_t caustic_first_specular; /* caustic-pass photons whose first hit was specular */
    int global_runaway, caustic_runaway; /* 1 if the pass stopped short of its target */
    /* The plan's pilot photons that joined ([0] the global pass's main map, [1] the caustic
     * map; photon_trace.h, PILOT PHOTONS): emitted (counted in *_emitted too) and stored (the
     * last pilot_stored[i] photons of the whole map). Set by photon_trace; 0 after a load. */
    uint64_t pilot_emitted[2];
    size_t pilot_stored[2];
    map_stamp stamp; /* what shaped them: set by the caller after tracing; by a load, the
                      * global.pmap's */
    /* A scene with media (pm_volume.h): nmedia > 0, and the volume photons of the global pass
     * (every kind) and of the caustic pass (L S+ V), in photon order, with the medium (index
     * in scene.media) of each, and each map's emitted count. loaded: the maps came from
     * photon_maps_load (pm_volume.c then builds its trees from them instead of tracing). */
    int nmedia, loaded;
    pm_photon *volume, *volume_caustic;
    short *volume_medium, *volume_caustic_medium;
    size_t nvolume, nvolume_caustic;
    uint64_t volume_emitted, volume_caustic_emitted;
    /* part 1: the maps are this process's part of a partitioned distributed pass
     * (photon_trace.h); the whole maps' counts and largest photon powers (global, caustic)
     * are in whole_*, for the radius policy. part 0: the maps are whole (whole_* unused). */
    int part;
    size_t whole_global, whole_caustic, whole_shadow;
    double whole_max_power[2];
} photon_maps;

void photon_maps_free(photon_maps *m);

/* The stamp of maps traced for scene s with settings cfg, the plan tracing the maps whose
 * flag is set (see MAP FILES for what the settings hash covers). */
void map_stamp_make(const scene *s, const photon_settings *cfg, int global_on, int caustic_on,
                    int shadow_on, map_stamp *st);
/* For a scene with media: mix the volume maps the plan traces (volume_on, volume_caustic_on),
 * their targets and the camera's position into st->settings (after map_stamp_make). */
void map_stamp_volume(const scene *s, const photon_settings *cfg, int volume_on,
                      int volume_caustic_on, map_stamp *st);
/* The tag[1] a file of the set carries: st->settings itself for the surface maps (medium < 0),
 * and for the volume map (caustic 0) or volume-caustic map (caustic 1) of a medium the same
 * with the role mixed into bits 0-47 (MAP FILES). */
uint64_t map_stamp_file(const map_stamp *st, int caustic, int md);

/* Save the maps into dir (created if missing): the three surface maps, and for nmedia > 0 the
 * two volume files of each medium; each header stamped with m->stamp (map_stamp_file). 0, or a
 * negative code with a message naming the file. */
int photon_maps_save(const photon_maps *m, const char *dir, char *err, size_t errcap);
/* Load the maps of dir into m, zeroed but for m->nmedia (the scene's count of media: its
 * volume files are read too), checking each file's kind and its stamp against want (force: a
 * stamp mismatch is a warning); sets m->loaded. 0, or a negative code with a message naming
 * the file (see MAP FILES); what was loaded stays in m for photon_maps_free. */
int photon_maps_load(photon_maps *m, const char *dir, const map_stamp *want, int force, char *err,
                     size_t errcap);

/* A kd-tree over n photons (reordered in place), buckets of `bucket`; *t = NULL when n == 0.
 * 0, or a negative code with a message. */
int photon_tree_build(pm_kdtree **t, pm_photon *ph, size_t n, unsigned bucket, char *err,
                      size_t errcap);

/* The paths of ph[0..n) in map order (PHOTON PATHS above): path[i] = the number of DIRECT
 * records among ph[1..i] (so ph[0]'s path is 0). */
void photon_paths(const pm_photon *ph, size_t n, uint32_t *path);
/* photon_tree_build over m's global map, numbering its paths first: m->global_path (replaced
 * if set) ends in the tree's order, beside m->global. 0, or a negative code with a message. */
int photon_tree_build_global(pm_kdtree **t, photon_maps *m, unsigned bucket, char *err, size_t errcap);

typedef struct map_radii {
    double global, caustic; /* maximum radius of a global / caustic estimate (INFINITY: none) */
    double typical;         /* a k_global estimate's radius at the mean density (INFINITY) */
    double shadow;          /* the shadow-map query radius (0 without a shadow map) */
    float r2_global, r2_caustic, r2_lookup, r2_shadow; /* squared, as the searches take them */
} map_radii;
void photon_maps_radii(const scene *s, const photon_maps *m, const photon_settings *cfg, map_radii *r);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PHOTON_MAPS_H */
