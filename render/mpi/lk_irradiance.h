/* lk_irradiance.h: the partitioned precomputed irradiance of render-mpi (lookup.h, PRECOMPUTED
 * IRRADIANCE; lk_irradiance.c). Internal to render/mpi.
 */
#ifndef RENDER_MPI_LK_IRRADIANCE_H
#define RENDER_MPI_LK_IRRADIANCE_H

#include "lk_serve.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The photon mapper's side_build hook (photon_lookup.h), collective: builds c from this rank's
 * part ph[0..n) of the global map (tree global) and every other rank's, keeping this rank's
 * records; the caller sets c->remote. 0 or a negative code with err set. */
int lk_side_build(side_cache *c, const scene *s, const pm_kdtree *global, const pm_photon *ph, size_t n,
                  unsigned k, float max_dist2, char *err, size_t errcap);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_MPI_LK_IRRADIANCE_H */
