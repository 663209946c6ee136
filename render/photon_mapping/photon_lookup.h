/* photon_lookup.h: the seam through which a distributed render takes over the photon mapper's
 * map lookups (render/mpi/lookup.c, partitioned mode: each process holds only its part of the
 * maps). In one process no hook is set and the mapper (photonmapper.c) reads its own maps.
 *
 * With a hook set, the mapper
 *   1. calls partition() once the maps are traced or loaded and the search radii chosen (the
 *      radii are those of the whole maps), before it builds the kd-trees: the hook keeps this
 *      process's part of the maps and may drop a map altogether (the shadow-photon map);
 *   2. calls side_build() in place of side_cache_build (photon_sides.h): the precomputed
 *      irradiance of the whole global map, from every process's part;
 *   3. calls ready() at the end of preprocessing with its trees and estimate options, so the
 *      hook can answer other processes' queries from this process's part;
 *   4. routes every global-map and caustic-map radiance estimate of li() through estimate(),
 *      which returns the irradiance (f = 1) at x for the camera sample id; the mapper applies
 *      the diffuse BRDF. The hook may return a placeholder while it records the queries of a
 *      tile and the combined values when the tile is traced again: no decision of li() (a
 *      branch, a random number drawn) depends on an estimate's value, so the two traces of a
 *      tile make the same queries in the same order.
 *
 * The hook and its user data outlive the integrator. estimate() is called from the render
 * threads concurrently (one tile per thread at a time).
 */
#ifndef RENDER_PHOTON_LOOKUP_H
#define RENDER_PHOTON_LOOKUP_H

#include <stddef.h>

#include "integrators/integrator.h"
#include "photons/photon_maps.h"
#include "photon_mapping/photon_sides.h"
#include "photonmap/estimate.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { PHOTON_LOOKUP_GLOBAL = 0, PHOTON_LOOKUP_CAUSTIC = 1 };

typedef struct photon_lookup_hook {
    int (*partition)(void *user, photon_maps *m, char *err, size_t errcap);
    int (*side_build)(void *user, side_cache *c, const scene *s, const pm_kdtree *global,
                      const pm_photon *ph, size_t n, unsigned k, float max_dist2, char *err,
                      size_t errcap);
    /* trees[PHOTON_LOOKUP_*] (NULL: this part is empty), opts[PHOTON_LOOKUP_*]. */
    void (*ready)(void *user, const pm_kdtree *const trees[2], const pm_estimate_options opts[2]);
    void (*estimate)(void *user, const sample_id *id, int map, vec3 x, vec3 n, double e[3]);
    void *user;
} photon_lookup_hook;

/* Route later photon-mapping renders through h (NULL: back to this process's own maps). */
void photon_lookup_set_hook(const photon_lookup_hook *h);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PHOTON_LOOKUP_H */
