/* volume.h: photon tracing for participating media: the photons a volume photon map holds.
 *
 * vol_trace() emits n photons from the scene's lights (a light chosen in proportion to its
 * power, photon power = light power / (n p_light)) and follows each through media and
 * surfaces. In a medium it samples free-flight distances (medium.h); at each scattering event
 * it stores one photon: its position, the direction it travelled, and the scattered power
 * (the power arriving times the free-flight weight, which is sigma_s / sigma_t in a grey
 * medium), then continues in an HG direction with Russian roulette on that weight, so a
 * photon's power stays constant in a grey medium. Surfaces scatter it by material_sample
 * (roulette on the branch weight); null surfaces only change the medium. Nothing is stored
 * on surfaces: that is photon_trace's work.
 *
 * Kinds (pm_photon_kind): PM_KIND_DIRECT for the first event of a photon straight from the
 * light, PM_KIND_CAUSTIC for the first event after one or more specular surface bounces and
 * nothing else (a volumetric caustic, L S+ V), PM_KIND_INDIRECT for every other event. A
 * renderer that computes single scattering by ray marching with shadow rays leaves the
 * DIRECT ones out.
 *
 * Limits (so far): photons start in the global medium (a light inside a medium-filled object
 * is not followed correctly); single-threaded; this module is not yet used by --mode pm.
 * Ownership: the caller frees out->photons with free(). Deterministic for a seed.
 */
#ifndef RENDER_VOLUME_H
#define RENDER_VOLUME_H

#include <stddef.h>
#include <stdint.h>

#include "photonmap/photon.h"
#include "scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct vol_photons {
    pm_photon *photons;
    size_t count, cap;
} vol_photons;

/* Trace n photons (bounces limited to max_depth per photon). 0, or PM_ENOMEM / PM_EINVAL
 * (no light with power) with out empty. */
int vol_trace(const scene *s, uint64_t n, uint64_t seed, int max_depth, vol_photons *out);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_VOLUME_H */
