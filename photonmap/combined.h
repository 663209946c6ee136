/* combined.h: one radiance estimate from several photon maps of the same scene.
 *
 * WHAT. M maps of one scene (built by M threads or machines, each emitting 1/M of the photons,
 * or one map split into M at random), with photon powers scaled for the total emission so that
 * the union of the maps is an ordinary map. A lookup gathers km = k/M photons in each map m
 * (all it finds within max_dist2 if fewer), with power sum P_m and squared radius r_m^2 (the
 * km-th photon's dist2, or max_dist2 when the map ran dry inside it), and returns
 *     E = c * (M / pi) * sum_m P_m / sum_m r_m^2,
 * the total power over the mean disc area, where c is ONE bias correction for the whole
 * estimate (below), and, beside it, the naive sum of the M per-map disc estimates (each with
 * its own correction), for comparison.
 *
 * DERIVATION. Let the union be a Poisson process of density lambda photons per unit area near
 * x, each photon in map m with probability 1/M independently: map m is then a Poisson process
 * of density lambda/M, independent of the others. For a map whose radius is set by its km-th
 * photon, (lambda/M) pi r_m^2 is the area, in units of the mean area per photon, that holds km
 * photons: a Gamma(km, 1) variable (the km-th arrival of a unit-rate process in area). Sums of
 * independent Gamma variables with one scale add their shapes, so
 *     (lambda/M) pi sum_m r_m^2 ~ Gamma(M km, 1) = Gamma(k, 1),
 * which is exactly the law of lambda pi r_k^2 for ONE map holding all the photons, with r_k its
 * k-th neighbour. So (M/pi) sum P_m / sum r_m^2 has the same distribution as the single-map
 * estimate sum P / (pi r_k^2) of the same k photons: it is that estimate, and it needs that
 * estimate's correction, applied once to the total: with PM_BIAS_AREA, c = (n - 1/2)/n with n
 * the photons found in all maps (n = k when every map found its km); with PM_BIAS_HALF_FARTHEST,
 * half a photon's power is taken off the total, that photon's power being the mean of the maps'
 * farthest photons (for equal powers the two rules agree, as for one map). Correcting each map
 * instead, (km - 1/2)/km per map, takes off half a photon M times: the estimate then reads
 * low by the factor ((km - 1/2)/km) / ((k - 1/2)/k), about 1 - (M - 1)/(2k). Maps that ran dry inside
 * max_dist2 contribute their whole disc (r_m^2 = max_dist2) and their photons without a rim
 * photon; if no map has a rim photon no correction is applied (as for one map that ran dry).
 * The naive sum of M ratios P_m/(pi r_m^2) has E[1/Gamma(km)] = 1/(km - 1) in each term: a
 * higher variance and, for small km, a bias high.
 *
 * Tested: combined_random_split_matches_single_map (M = 4 and 16, km = 4, 16, 64, random
 * powers: the mean paired difference from the single-map estimate within 1% and 3 standard
 * errors, both bias rules) and irradiance_combined_maps (independent jittered maps against
 * the analytic irradiance and one map of all photons).
 *
 * TWO LAYERS. pm_combine_* are the core (on neighbour lists someone found), pm_estimate_combined
 * the wrapper over M trees of pm_photon records. Irradiance only (f = 1): multiply by a BRDF
 * afterwards. Nothing allocates; the accumulator is the caller's, so calls are reentrant.
 */
#ifndef PM_COMBINED_H
#define PM_COMBINED_H

#include "common.h"
#include "photon.h"
#include "kdtree.h"
#include "estimate.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct pm_combine_acc {
    double power[3];     /* sum over maps of P_m (per channel, uncorrected) */
    double r2_sum;       /* sum over maps of r_m^2 (uncorrected; floor-limited as estimate.h) */
    double far_power[3]; /* sum over maps with a rim photon of that photon's power */
    double naive[3];     /* sum over maps of each map's own corrected disc estimate */
    unsigned long found; /* photons added over all maps */
    unsigned maps;       /* maps added */
    unsigned rims;       /* maps whose radius was set by their farthest photon */
    int bias;            /* PM_BIAS_* of the last map added (all must agree) */
    unsigned flags;      /* PM_EST_F_* seen in any map */
} pm_combine_acc;

void pm_combine_init(pm_combine_acc *acc);
/* Add one map: nb[0..count) found with k_per_map requested and max_dist2 (for the radius
 * rule), at point x; bias is a PM_BIAS_* and must be the same for every map of one estimate
 * (PM_EINVAL otherwise). */
int pm_combine_add(pm_combine_acc *acc, const pm_photon *photons, const pm_neighbor *nb,
                   unsigned count, unsigned k_per_map, float max_dist2, int bias,
                   const float x[3]);
/* combined = c (M/pi) sum P_m / sum r_m^2 (see DERIVATION), naive = the sum of the per-map
 * estimates, M = maps added; either output may be NULL. Always finite and non-negative. */
void pm_combine_finish(const pm_combine_acc *acc, double combined[3], double naive[3]);

/* Wrapper: k total photons, k/M (at least 1) from each of trees[0..M) (pm_photon records),
 * with the search options of opt (max_dist2, bias, squash, reject_behind; kind, BRDF and the
 * rest are ignored). scratch: ceil(k/M) * 8 bytes. */
int pm_estimate_combined(const pm_kdtree *const *trees, unsigned M, const float x[3],
                         const float n[3], const pm_estimate_options *opt, void *scratch,
                         double combined[3], double naive[3], pm_query_stats *stats);

#ifdef __cplusplus
}
#endif

#endif /* PM_COMBINED_H */
