/* irradiance.c: precomputed irradiance at photons, its lookup, and combined photon maps.
 *
 * The precomputation is a plain loop over the chosen photons, each running the disc-estimate
 * wrapper of estimate.c at the photon's position with its decoded normal; OpenMP splits the
 * loop, and each thread gets its own estimate scratch, allocated before the parallel region
 * so that a failed allocation is reported without racing. Results are packed as RGBE next to
 * a bitmask of which photons were done. The 256 possible normals are decoded once into a
 * table, so the lookup predicate is a bit test and a dot product.
 */
#include "irradiance.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#define PM__PI 3.14159265358979323846

struct pm_irradiance {
    const pm_kdtree *tree;
    const pm_photon *photons;
    size_t n;
    size_t done;
    uint8_t (*rgbe)[4]; /* n values */
    uint8_t *mask;      /* (n + 7) / 8 bytes */
    float *r2;          /* n radii^2, or NULL */
    float normals[256][3];
};

void pm_irradiance_options_init(pm_irradiance_options *opt, unsigned k) {
    memset(opt, 0, sizeof *opt);
    opt->k = k;
    opt->max_dist2 = INFINITY;
    opt->fraction = PM_PRECOMP_ALL;
    opt->bias = PM_BIAS_AREA;
    opt->squash = 1.0f;
    opt->reject_behind = 1;
}

void pm_irradiance_free(pm_irradiance *irr) {
    if (!irr) return;
    free(irr->rgbe);
    free(irr->mask);
    free(irr->r2);
    free(irr);
}

int pm_irradiance_build(pm_irradiance **out, const pm_kdtree *tree,
                        const pm_irradiance_options *opt) {
    pm_irradiance *irr;
    int nthreads = 1, err = 0;
    void **scratch;
    long n;
    if (!out) return PM_EINVAL;
    *out = NULL;
    if (!tree || !opt || opt->k == 0) return PM_EINVAL;
    if (opt->fraction != PM_PRECOMP_ALL && opt->fraction != PM_PRECOMP_QUARTER) return PM_EINVAL;
    if (opt->bias < PM_BIAS_NONE || opt->bias > PM_BIAS_HALF_FARTHEST) return PM_EINVAL;
    if (isnan(opt->max_dist2)) return PM_ENONFINITE;
    if (pm_kdtree_size(tree) == 0) return PM_EEMPTY;
    irr = calloc(1, sizeof *irr);
    if (!irr) return PM_ENOMEM;
    irr->tree = tree;
    irr->photons = (const pm_photon *)pm_kdtree_records(tree);
    irr->n = pm_kdtree_size(tree);
    n = (long)irr->n;
    irr->rgbe = calloc(irr->n, sizeof *irr->rgbe);
    irr->mask = calloc((irr->n + 7) / 8, 1);
    if (opt->store_radius) irr->r2 = calloc(irr->n, sizeof *irr->r2);
    for (int c = 0; c < 256; c++) pm_normal_decode((uint8_t)c, irr->normals[c]);
#ifdef _OPENMP
    nthreads = opt->threads > 0 ? opt->threads : omp_get_max_threads();
#endif
    scratch = calloc((size_t)nthreads, sizeof *scratch);
    if (!irr->rgbe || !irr->mask || (opt->store_radius && !irr->r2) || !scratch) {
        free(scratch);
        pm_irradiance_free(irr);
        return PM_ENOMEM;
    }
    for (int t = 0; t < nthreads; t++)
        if (!(scratch[t] = malloc(pm_estimate_scratch_bytes(opt->k)))) err = PM_ENOMEM;

    /* The mask is written per byte, 8 photons at a time, by the thread that owns the chunk:
     * the loop runs over bytes of the mask so no two threads share one. */
    pm_estimate_options eo;
    pm_estimate_options_init(&eo, PM_EST_DISC, opt->k);
    eo.max_dist2 = opt->max_dist2;
    eo.bias = opt->bias;
    eo.squash = opt->squash;
    eo.reject_behind = opt->reject_behind;
    eo.diffuse = opt->diffuse;
    long nbytes = (n + 7) / 8;
    size_t done = 0;
    if (!err) {
#ifdef _OPENMP
#pragma omp parallel for num_threads(nthreads) schedule(dynamic, 64) reduction(+ : done)
#endif
        for (long byte = 0; byte < nbytes; byte++) {
            int t = 0;
#ifdef _OPENMP
            t = omp_get_thread_num();
#endif
            uint8_t bits = 0;
            for (long i = byte * 8; i < n && i < byte * 8 + 8; i++) {
                if (opt->fraction == PM_PRECOMP_QUARTER && pm_kdtree_height(tree, (uint32_t)i) < 2)
                    continue;
                const pm_photon *p = &irr->photons[i];
                const float *nrm = irr->normals[p->normal];
                pm_estimate_result r;
                float rgb[3];
                if (pm_estimate(tree, p->pos, nrm, &eo, scratch[t], &r, NULL) != PM_OK) continue;
                for (int c = 0; c < 3; c++) rgb[c] = (float)fmin(r.rgb[c], 1e38);
                pm_rgbe_encode(rgb, irr->rgbe[i]);
                if (irr->r2) irr->r2[i] = (float)fmin(r.r2, 3e38);
                bits |= (uint8_t)(1u << (i - byte * 8));
                done++;
            }
            irr->mask[byte] = bits;
        }
    }
    for (int t = 0; t < nthreads; t++) free(scratch[t]);
    free(scratch);
    if (err) {
        pm_irradiance_free(irr);
        return err;
    }
    irr->done = done;
    *out = irr;
    return PM_OK;
}

size_t pm_irradiance_count(const pm_irradiance *irr) { return irr ? irr->done : 0; }

size_t pm_irradiance_bytes(const pm_irradiance *irr) {
    if (!irr) return 0;
    return sizeof *irr + irr->n * 4 + (irr->n + 7) / 8 + (irr->r2 ? irr->n * sizeof(float) : 0);
}

double pm_irradiance_bytes_per_photon(const pm_irradiance *irr) {
    if (!irr) return 0.0;
    return 4.0 + 1.0 / 8.0 + (irr->r2 ? 4.0 : 0.0);
}

static int is_done(const pm_irradiance *irr, uint32_t i) {
    return (irr->mask[i >> 3] >> (i & 7)) & 1;
}

int pm_irradiance_value(const pm_irradiance *irr, uint32_t i, float rgb[3]) {
    if (!irr || i >= irr->n || !is_done(irr, i)) {
        if (rgb) rgb[0] = rgb[1] = rgb[2] = 0.0f;
        return 0;
    }
    pm_rgbe_decode(irr->rgbe[i], rgb);
    return 1;
}

typedef struct lookup_ctx {
    const pm_irradiance *irr;
    const float *n, *q;
    float cos_min;
} lookup_ctx;

static int accept(void *user, const void *record, uint32_t index) {
    const lookup_ctx *c = (const lookup_ctx *)user;
    const pm_photon *p = (const pm_photon *)record;
    if (!is_done(c->irr, index)) return 0;
    const float *pn = c->irr->normals[p->normal];
    if (pn[0] * c->n[0] + pn[1] * c->n[1] + pn[2] * c->n[2] < c->cos_min) return 0;
    if (c->irr->r2) {
        float d[3] = {p->pos[0] - c->q[0], p->pos[1] - c->q[1], p->pos[2] - c->q[2]};
        if (!(d[0] * d[0] + d[1] * d[1] + d[2] * d[2] < c->irr->r2[index])) return 0;
    }
    return 1;
}

int pm_irradiance_lookup(const pm_irradiance *irr, const float x[3], const float n[3],
                         float max_dist2, float cos_min, float rgb[3], pm_query_stats *stats) {
    pm_neighbor nb;
    lookup_ctx c;
    if (rgb) rgb[0] = rgb[1] = rgb[2] = 0.0f;
    if (!irr || !x || !n || !rgb) return PM_EINVAL;
    if (!isfinite(n[0]) || !isfinite(n[1]) || !isfinite(n[2]) || isnan(cos_min))
        return PM_ENONFINITE;
    c.irr = irr, c.n = n, c.q = x, c.cos_min = cos_min;
    int rc = pm_kdtree_nearest_if(irr->tree, x, max_dist2, accept, &c, &nb, stats);
    if (rc <= 0) return rc;
    pm_rgbe_decode(irr->rgbe[nb.index], rgb);
    return 1;
}

void pm_combine_init(pm_combine_acc *acc) { memset(acc, 0, sizeof *acc); }

int pm_combine_add(pm_combine_acc *acc, const pm_photon *photons, const pm_neighbor *nb,
                   unsigned count, unsigned k_per_map, float max_dist2, int bias,
                   const float x[3]) {
    pm_estimate_options o;
    pm_estimate_result r;
    if (!acc) return PM_EINVAL;
    /* One map's term is its bias-corrected disc estimate, split back into power and area:
     * P_m = E_m * area_m, r_m^2 = area_m / pi (the corrected area, if any). */
    pm_estimate_options_init(&o, PM_EST_DISC, k_per_map ? k_per_map : 1);
    o.max_dist2 = max_dist2;
    o.bias = bias;
    int rc = pm_estimate_core(photons, nb, count, x, NULL, &o, NULL, &r);
    if (rc) return rc;
    acc->maps++;
    acc->flags |= r.flags;
    if (r.found == 0 && !isfinite(max_dist2)) return PM_OK; /* an empty map adds nothing */
    double r2 = r.area / PM__PI;
    if (r.found == 0) r2 = (double)max_dist2; /* searched the whole disc, found nothing */
    if (!isfinite(r2) || (r.flags & PM_EST_F_FAR)) return PM_OK;
    acc->r2_sum += r2;
    for (int c = 0; c < 3; c++) {
        acc->power[c] += r.rgb[c] * r.area;
        acc->naive[c] += r.rgb[c];
    }
    return PM_OK;
}

void pm_combine_finish(const pm_combine_acc *acc, double combined[3], double naive[3]) {
    for (int c = 0; c < 3; c++) {
        double e = 0.0;
        if (acc->r2_sum > 0.0 && isfinite(acc->r2_sum))
            e = (double)acc->maps / PM__PI * acc->power[c] / acc->r2_sum;
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
    float nrm[3] = {0, 0, 1};
    if (n) memcpy(nrm, n, sizeof nrm);
    pm_knn_options ko;
    memset(&ko, 0, sizeof ko);
    if (n && opt->squash > 1.0f) {
        ko.normal = nrm;
        ko.squash = opt->squash;
    }
    if (opt->reject_behind) {
        ko.filter = pm_filter_front;
        ko.filter_user = nrm;
    }
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
