/* photon_maps.h: the three photon maps of the renderer as data: what photon tracing
 * (photon_trace.h) fills or the map files give back, the kd-trees built over them, and the
 * radius policy of their estimates.
 *
 * MAP FILES. photon_maps_save writes DIR/global.pmap, caustic.pmap and shadow.pmap in the
 * format of photonmap/photon.h (tree_bucket 0: the photons as traced, before a kd-tree
 * reorders them, so loading them gives the same trees and the same image bit for bit);
 * photon_maps_load reads them back, an absent file being an empty map.
 *
 * RADII. Maximum search radii are automatic unless the settings give them: Christensen's
 * radius beyond which k photons of the largest power would give less than a threshold
 * radiance, 0.5% of the mean radiance the lights' power would give on the diffuse area
 * (phi / (pi A)). The "typical" radius is that of a k_global estimate at the global map's
 * mean density; the precomputed-irradiance lookup searches within 4 of them (at most the
 * global radius), and the shadow-map query within 2 of its own typical radius.
 *
 * Ownership: a photon_maps owns its three arrays (photon_maps_free; a zeroed one may be freed).
 */
#ifndef RENDER_PHOTON_MAPS_H
#define RENDER_PHOTON_MAPS_H

#include <stddef.h>
#include <stdint.h>

#include "photonmap/kdtree.h"
#include "photonmap/photon.h"
#include "photon_settings.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct photon_maps {
    pm_photon *global, *caustic, *shadow;
    size_t nglobal, ncaustic, nshadow;
    uint64_t global_emitted, caustic_emitted; /* the shadow map shares the global pass */
    double caustic_fraction;        /* power-weighted active fraction of the projection maps */
    uint64_t caustic_saved;         /* emissions the projection map saved */
    uint64_t caustic_first_specular; /* caustic-pass photons whose first hit was specular */
    int global_runaway, caustic_runaway; /* 1 if the pass stopped short of its target */
} photon_maps;

void photon_maps_free(photon_maps *m);

/* Save the three maps into dir (created if missing). 0, or a negative code with a message
 * naming the file. */
int photon_maps_save(const photon_maps *m, const char *dir, char *err, size_t errcap);
/* Load the maps found in dir into a zeroed m (absent files: empty maps). 0, or a negative
 * code with a message naming the file; what was loaded stays in m for photon_maps_free. */
int photon_maps_load(photon_maps *m, const char *dir, char *err, size_t errcap);

/* A kd-tree over n photons (reordered in place), buckets of `bucket`; *t = NULL when n == 0.
 * 0, or a negative code with a message. */
int photon_tree_build(pm_kdtree **t, pm_photon *ph, size_t n, unsigned bucket, char *err,
                      size_t errcap);

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
