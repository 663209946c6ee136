/* combined.c: one estimate from several photon maps (combined.h has the formula and its
 * derivation).
 *
 * Each map's neighbour list goes through the disc core of estimate.c without a bias
 * correction, which applies the radius rule and the radius floor and gives the map's power sum
 * (estimate times area) and its area; the accumulator keeps the raw sums, the photon count, the
 * maps whose radius came from their farthest photon and those photons' powers, so that
 * pm_combine_finish can apply the correction once to the total. The naive per-map sum runs the
 * core a second time with the caller's correction.
 */
#include "combined.h"

#include <math.h>
#include <string.h>

#define PM__PI 3.14159265358979323846

void pm_combine_init(pm_combine_acc *acc) { memset(acc, 0, sizeof *acc); }

int pm_combine_add(pm_combine_acc *acc, const pm_photon *photons, const pm_neighbor *nb,
                   unsigned count, unsigned k_per_map, float max_dist2, int bias,
                   const float x[3]) {
    pm_estimate_options o;
    pm_estimate_result raw, own;
    if (!acc) return PM_EINVAL;
    if (bias < PM_BIAS_NONE || bias > PM_BIAS_HALF_FARTHEST) return PM_EINVAL;
    if (acc->maps > 0 && bias != acc->bias) return PM_EINVAL;
    pm_estimate_options_init(&o, PM_EST_DISC, k_per_map ? k_per_map : 1);
    o.max_dist2 = max_dist2;
    o.bias = PM_BIAS_NONE;
    int rc = pm_estimate_core(photons, nb, count, x, NULL, &o, NULL, &raw);
    if (rc) return rc;
    o.bias = bias;
    rc = pm_estimate_core(photons, nb, count, x, NULL, &o, NULL, &own);
    if (rc) return rc;
    acc->maps++;
    acc->bias = bias;
    acc->flags |= raw.flags | own.flags;
    if (raw.found == 0 && !isfinite(max_dist2)) return PM_OK; /* an empty map adds nothing */
    double r2 = raw.area / PM__PI;
    if (raw.found == 0) r2 = (double)max_dist2; /* searched the whole disc, found nothing */
    if (!isfinite(r2) || (raw.flags & PM_EST_F_FAR)) return PM_OK;
    acc->r2_sum += r2;
    acc->found += count;
    for (int c = 0; c < 3; c++) {
        acc->power[c] += raw.rgb[c] * raw.area;
        acc->naive[c] += own.rgb[c];
    }
    /* A rim photon: the radius is the farthest photon's (the radius rule of estimate.h). */
    if (count > 0 && !(raw.flags & PM_EST_F_RADIUS_LIMIT)) {
        unsigned far = 0;
        for (unsigned i = 1; i < count; i++)
            if (nb[i].dist2 > nb[far].dist2) far = i;
        float p[3];
        pm_rgbe_decode(photons[nb[far].index].power, p);
        for (int c = 0; c < 3; c++) acc->far_power[c] += p[c];
        acc->rims++;
    }
    return PM_OK;
}

void pm_combine_finish(const pm_combine_acc *acc, double combined[3], double naive[3]) {
    for (int c = 0; c < 3; c++) {
        double e = 0.0, p = acc->power[c];
        if (acc->rims > 0 && acc->found > 0) {
            if (acc->bias == PM_BIAS_AREA)
                p *= ((double)acc->found - 0.5) / (double)acc->found;
            else if (acc->bias == PM_BIAS_HALF_FARTHEST)
                p -= 0.5 * acc->far_power[c] / (double)acc->rims;
        }
        if (acc->r2_sum > 0.0 && isfinite(acc->r2_sum))
            e = (double)acc->maps / PM__PI * p / acc->r2_sum;
        if (combined) combined[c] = isfinite(e) && e > 0.0 ? e : 0.0;
        if (naive) naive[c] = isfinite(acc->naive[c]) && acc->naive[c] > 0.0 ? acc->naive[c] : 0.0;
    }
}

int pm_estimate_combined(const pm_kdtree *const *trees, unsigned M, const float x[3],
                         const float n[3], const pm_estimate_options *opt, void *scratch,
                         double combined[3], double naive[3], pm_query_stats *stats) {
    pm_combine_acc acc;
    if (!trees || M == 0 || !opt || opt->k == 0 || !scratch || !x) return PM_EINVAL;
    if (!isfinite(x[0]) || !isfinite(x[1]) || !isfinite(x[2])) return PM_ENONFINITE;
    if (opt->reject_behind && !n) return PM_EINVAL;
    unsigned km = opt->k / M ? opt->k / M : 1;
    float nrm[3];
    pm_knn_options ko;
    pm_estimate_search_options(opt, n, nrm, &ko);
    pm_combine_init(&acc);
    for (unsigned m = 0; m < M; m++) {
        if (!trees[m]) return PM_EINVAL;
        int found = pm_kdtree_knn_ex(trees[m], x, km, opt->max_dist2, &ko,
                                     (pm_neighbor *)scratch, stats);
        if (found < 0) return found;
        int rc = pm_combine_add(&acc, (const pm_photon *)pm_kdtree_records(trees[m]),
                                (const pm_neighbor *)scratch, (unsigned)found, km,
                                opt->max_dist2, opt->bias, x);
        if (rc) return rc;
    }
    pm_combine_finish(&acc, combined, naive);
    return PM_OK;
}
