/* pm_beam.h: beam radiance estimates of the volume photon maps along eye rays (Jarosz, Zwicker
 * and Jensen 2008, "The Beam Radiance Estimate for Volumetric Photon Mapping"), which replace
 * the k-nearest estimates at every ray-marching step (pm_volume.h, EYE RAYS).
 *
 * THE ESTIMATE. Each photon i of a tree gets its own radius r_i once, when the map is built:
 * the distance to its k-th nearest photon of the same tree (itself included), at most the
 * tree's search limit (pm_volume.h, STEP, k AND RADII), and its kernel is the uniform ball of
 * that radius, normalised over the part f_i of the ball that lies inside the medium
 * (pmv_ball_fraction, at the photon, once): K_i(x) = 1 / (f_i 4/3 pi r_i^3) in the ball. The
 * in-scattered radiance per unit length at x is then sum_i phase_i Phi_i K_i(x) (a
 * sample-point density estimate: every photon's power is spread over its ball, so no power is
 * lost or counted twice, and a uniform Poisson cloud reads its density exactly in expectation,
 * with no (k - 1) / k factor). Its integral along the segment [0, T] of an eye ray, weighted
 * by the transmittance exp(-sigma_t t), is computed exactly: photon i adds
 *   phase_i Phi_i / (f_i 4/3 pi r_i^3) * (exp(-sigma_t a) - exp(-sigma_t b)) / sigma_t
 * per channel, [a, b] the chord of its ball on the ray, clipped to [0, T]. One traversal of a
 * bounding-volume hierarchy over the photons' balls finds every ball the segment crosses, so
 * a segment costs one query instead of one k-nearest search per step, and the estimate has no
 * noise of its own (the steps' random offset no longer matters to it).
 *
 * What it gives up against the per-step k-nearest estimate (the balloon estimator): the radius
 * belongs to the photon, not to the point, so a lone photon in a dark region spreads over a
 * ball of up to the search limit instead of being read by every step whose ball reaches it;
 * the boundary correction is taken at the photon rather than at the point (the same planes,
 * a different centre). Both estimates converge to the same in-scattered radiance as the
 * photons grow in number (tested: media_beam_matches_march_estimate).
 *
 * Threads: pmv_beam_build runs its per-photon searches in parallel (OpenMP); the result does
 * not depend on the thread count. pmv_beam_segment only reads.
 */
#ifndef RENDER_PM_BEAM_H
#define RENDER_PM_BEAM_H

#include <stddef.h>
#include <stdint.h>

#include "photonmap/kdtree.h"
#include "photonmap/photon.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* One photon of a beam map: its centre, radius^2, power already divided by its kernel's
 * volume (f_i 4/3 pi r_i^3), and the direction it travelled. */
typedef struct pmv_beam_photon {
    float p[3];
    float r2;
    float w[3];
    float d[3];
} pmv_beam_photon;

typedef struct pmv_beam_node {
    float lo[3], hi[3]; /* bounds of the balls below */
    uint32_t first;     /* leaf: first photon; inner: index of the right child (left is next) */
    uint32_t count;     /* leaf: photons (> 0); inner: 0 */
} pmv_beam_node;

typedef struct pmv_beam {
    pmv_beam_photon *ph;
    size_t n;
    pmv_beam_node *nodes;
    size_t nnodes;
    double mean_r; /* the photons' mean radius, for the message */
} pmv_beam;

/* Build the beam map of the n photons a (a built kd-tree t over them): radii from t with k
 * photons at most r2max, ball fractions when boundary (pmv_ball_fraction on s). 0 or
 * PM_ENOMEM. n = 0 gives an empty map. */
int pmv_beam_build(pmv_beam *b, const scene *s, const pm_kdtree *t, const pm_photon *a, size_t n, unsigned k,
                   float r2max, int boundary);
void pmv_beam_free(pmv_beam *b);

/* The integral over [0, T] of the map's in-scattered radiance along r (unit direction) times
 * the transmittance exp(-sigma_t t) of a medium with HG parameter g (THE ESTIMATE above).
 * *nphotons (if not NULL) is increased by the photons whose ball the segment crossed. */
rgb pmv_beam_segment(const pmv_beam *b, ray r, double T, rgb sigma_t, double g, uint64_t *nphotons);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PM_BEAM_H */
