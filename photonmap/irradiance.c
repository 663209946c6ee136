/* irradiance.c: precomputed irradiance at photons, its normal-checked lookup, and combined
 * photon maps; the lookups are irradiance_lookup.c.
 *
 * BUILD. A plain loop over the chosen photons runs the disc-estimate wrapper of estimate.c at
 * each photon's position with its normal; OpenMP splits the loop, and each thread gets its own
 * estimate scratch, allocated before the parallel region so that a failed allocation is
 * reported without racing. Values go to a temporary array over the whole map (RGBE) next to a
 * bitmask of which photons were done. The done photons are then copied into compact 20-byte
 * records (position, RGBE value, normal code, the tree's axis byte), with radii^2 in a parallel
 * array when kept (and the map indices, with store_index), and a kd-tree (bucket
 * PM__IRR_BUCKET) is built over those records alone, so that a lookup never wades through the
 * photons that were not precomputed. A rank table (one uint32 per 64 photons of the map) and a
 * slot array (the record of each precomputed photon) keep pm_irradiance_value(i) O(1) in the
 * map's own indices. pm_irradiance_build_values fills the same temporary arrays from the
 * caller's values instead of estimates, and shares the rest (irr_alloc, irr_finish).
 *
 * LOOKUP: irradiance_lookup.c; the record and the structure both files read are
 * irradiance_internal.h's.
 */
/* The reach test compares a cell's distance with records' distances, both rounded once per
 * operation (GCC in ISO C mode contracts nothing; clang would fuse a * b + c). */
#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF
#endif
#include "irradiance.h"
#include "internal.h"
#include "irradiance_internal.h"
#include "kdtree_internal.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

#define PM__PI 3.14159265358979323846

/* Leaf bucket of the lookup tree: nearest-if queries on 8-record buckets visit fewer nodes
 * than on the classic tree for the same answer (bench_estimate's irradiance_lookup rows race
 * it against a pm_photon tree). */
#define PM__IRR_BUCKET 8u

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
    pm_kdtree_free(irr->tree);
    free(irr->mask);
    free(irr->rank);
    free(irr->slot);
    free(irr->recs);
    free(irr->r2);
    free(irr->photon);
    free(irr->reach);
    free(irr->nmask);
    free(irr);
}

static int is_done(const pm_irradiance *irr, size_t i) {
    return (int)((irr->mask[i >> 6] >> (i & 63)) & 1u);
}

/* The smallest-eigenvalue eigenvector of the symmetric 3x3 matrix a (cyclic Jacobi
 * rotations; a is destroyed). */
static void smallest_eigvec(double a[3][3], double out[3]) {
    double v[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    for (int sweep = 0; sweep < 30; sweep++) {
        double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        double diag = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if (!(off > 1e-30 * diag)) break;
        for (int p = 0; p < 2; p++)
            for (int q = p + 1; q < 3; q++) {
                if (a[p][q] == 0) continue;
                double th = (a[q][q] - a[p][p]) / (2 * a[p][q]);
                double t = (th >= 0 ? 1 : -1) / (fabs(th) + sqrt(th * th + 1));
                double c = 1 / sqrt(t * t + 1), s = t * c;
                for (int k = 0; k < 3; k++) { /* columns p, q of a */
                    double akp = a[k][p], akq = a[k][q];
                    a[k][p] = c * akp - s * akq, a[k][q] = s * akp + c * akq;
                }
                for (int k = 0; k < 3; k++) { /* rows p, q */
                    double apk = a[p][k], aqk = a[q][k];
                    a[p][k] = c * apk - s * aqk, a[q][k] = s * apk + c * aqk;
                }
                for (int k = 0; k < 3; k++) {
                    double vkp = v[k][p], vkq = v[k][q];
                    v[k][p] = c * vkp - s * vkq, v[k][q] = s * vkp + c * vkq;
                }
            }
    }
    int m = 0;
    if (a[1][1] < a[m][m]) m = 1;
    if (a[2][2] < a[m][m]) m = 2;
    for (int k = 0; k < 3; k++) out[k] = v[k][m];
}

/* cos 12 degrees: more than the normal code's worst rounding (about 9.72 degrees, photon.h). */
#define PM__FIT_COS 0.97814760073380569

/* The normal of the plane fitted (least squares) to the k photons nearest p, oriented like
 * the quantized normal q; q itself if the fit is more than 12 degrees from q (a corner, a
 * curved patch, too few photons), since then it is no better than the code. */
static void fitted_normal(const pm_kdtree *tree, const float p[3], const float q[3], unsigned k,
                          float max_dist2, pm_neighbor *nb, float out[3]) {
    memcpy(out, q, 3 * sizeof *out);
    int found = pm_kdtree_knn(tree, p, k, max_dist2, nb, 0, NULL);
    if (found < 3) return;
    double mean[3] = {0, 0, 0}, cov[3][3] = {{0}};
    for (int i = 0; i < found; i++) {
        const float *x = pm_kdtree_pos(tree, nb[i].index);
        for (int c = 0; c < 3; c++) mean[c] += x[c];
    }
    for (int c = 0; c < 3; c++) mean[c] /= found;
    for (int i = 0; i < found; i++) {
        const float *x = pm_kdtree_pos(tree, nb[i].index);
        double d[3] = {x[0] - mean[0], x[1] - mean[1], x[2] - mean[2]};
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 3; c++) cov[r][c] += d[r] * d[c];
    }
    double e[3];
    smallest_eigvec(cov, e);
    double len = sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]);
    if (!(len > 0) || !isfinite(len)) return;
    double dot = (e[0] * q[0] + e[1] * q[1] + e[2] * q[2]) / len;
    if (fabs(dot) < PM__FIT_COS) return;
    double sgn = dot < 0 ? -1.0 : 1.0;
    for (int c = 0; c < 3; c++) out[c] = (float)(sgn * e[c] / len);
}

/* The estimates at the chosen photons of `tree`: rgbe[i] (and r2[i]) for every i whose bit is
 * set in mask; returns the count, or a negative code. */
static long precompute(const pm_kdtree *tree, const pm_irradiance_options *opt,
                       const float (*normals)[3], uint64_t *mask, uint8_t (*rgbe)[4], float *r2) {
    const pm_photon *ph = (const pm_photon *)pm_kdtree_records(tree);
    long n = (long)pm_kdtree_size(tree);
    int nthreads = 1, err = 0;
#ifdef _OPENMP
    nthreads = opt->threads > 0 ? opt->threads : omp_get_max_threads();
#endif
    void **scratch = calloc((size_t)nthreads, sizeof *scratch);
    if (!scratch) return PM_ENOMEM;
    for (int t = 0; t < nthreads; t++)
        if (!(scratch[t] = malloc(pm_estimate_scratch_bytes(opt->k)))) err = PM_ENOMEM;
    pm_estimate_options eo;
    pm_estimate_options_init(&eo, PM_EST_DISC, opt->k);
    eo.max_dist2 = opt->max_dist2;
    eo.bias = opt->bias;
    eo.squash = opt->squash;
    eo.reject_behind = opt->reject_behind;
    eo.diffuse = opt->diffuse;
    /* Each mask word (64 photons) is written by the one thread that owns it. */
    long nwords = (n + 63) / 64;
    long done = 0;
    if (!err) {
#ifdef _OPENMP
#pragma omp parallel for num_threads(nthreads) schedule(dynamic, 8) reduction(+ : done)
#endif
        for (long w = 0; w < nwords; w++) {
            int t = 0;
#ifdef _OPENMP
            t = omp_get_thread_num();
#endif
            uint64_t bits = 0;
            for (long i = w * 64; i < n && i < w * 64 + 64; i++) {
                if (opt->fraction == PM_PRECOMP_QUARTER && pm_kdtree_height(tree, (uint32_t)i) < 2)
                    continue;
                const pm_photon *p = &ph[i];
                const float *nrm = opt->normals ? opt->normals + 3 * i : normals[p->normal];
                float fit[3];
                if (!opt->normals && opt->squash > 1.0f) {
                    fitted_normal(tree, p->pos, nrm, opt->k, opt->max_dist2,
                                  (pm_neighbor *)scratch[t], fit);
                    nrm = fit;
                }
                pm_estimate_result r;
                float rgb[3];
                if (pm_estimate(tree, p->pos, nrm, &eo, scratch[t], &r, NULL) != PM_OK) continue;
                for (int c = 0; c < 3; c++) rgb[c] = (float)fmin(r.rgb[c], 1e38);
                pm_rgbe_encode(rgb, rgbe[i]);
                if (r2) r2[i] = (float)fmin(r.r2, 3e38);
                bits |= (uint64_t)1 << (i - w * 64);
                done++;
            }
            mask[w] = bits;
        }
    }
    for (int t = 0; t < nthreads; t++) free(scratch[t]);
    free(scratch);
    return err ? err : done;
}

/* The common checks of both builds and a structure with the normal table, mask and rank
 * arrays allocated; the caller fills the mask. */
static int irr_alloc(pm_irradiance **out, const pm_kdtree *tree, const pm_irradiance_options *opt) {
    if (!out) return PM_EINVAL;
    *out = NULL;
    if (!tree || !opt) return PM_EINVAL;
    if (opt->fraction != PM_PRECOMP_ALL && opt->fraction != PM_PRECOMP_QUARTER) return PM_EINVAL;
    size_t n = pm_kdtree_size(tree);
    if (n == 0) return PM_EEMPTY;
    pm_irradiance *irr = calloc(1, sizeof *irr);
    if (!irr) return PM_ENOMEM;
    irr->n = n;
    for (int c = 0; c < 256; c++) {
        pm_normal_decode((uint8_t)c, irr->normals[c]);
        irr->nbucket[c] = pm__normal_bucket(irr->normals[c]);
    }
    size_t nwords = (n + 63) / 64;
    irr->mask = calloc(nwords, sizeof *irr->mask);
    irr->rank = malloc(nwords * sizeof *irr->rank);
    if (!irr->mask || !irr->rank) {
        pm_irradiance_free(irr);
        return PM_ENOMEM;
    }
    *out = irr;
    return PM_OK;
}

/* REACH. With stored radii, reach[p] is the largest r2 of the records in heap node p's subtree
 * (its own record, if internal, and all below; a leaf's bucket), for p = 1 .. 2 L - 1 (L leaf
 * buckets). A lookup then skips a subtree whose cell is no closer to x than that: no record
 * in it can pass the radius rule, so the search meets the same accepted records in the same
 * order, and the answer is bit for bit the one of the plain search. Only for trees without
 * tightening codes (this module's record layout never has them). */
static int reach_build(pm_irradiance *irr) {
    const struct pm_kdtree *t = irr->tree;
    if (t->tight) return PM_OK; /* no reach: the plain search */
    uint64_t L = t->nleaves;
    irr->reach = malloc(2 * L * sizeof *irr->reach);
    if (!irr->reach) return PM_ENOMEM;
    irr->nmask = malloc(2 * L);
    if (!irr->nmask) return PM_ENOMEM;
    irr->reach[0] = 0;
    irr->nmask[0] = 0;
    for (uint64_t j = 0; j < L; j++) {
        uint64_t b = t->ninternal + pm__cum(t, j), e = b + t->leaf_q + (j < t->leaf_extra);
        float m = -INFINITY;
        uint8_t nm = 0;
        for (uint64_t i = b; i < e; i++) {
            m = irr->r2[i] > m ? irr->r2[i] : m;
            nm |= irr->nbucket[irr->recs[i].ncode];
        }
        irr->reach[L + j] = m;
        irr->nmask[L + j] = nm;
    }
    for (uint64_t p = L; p-- > 1;) {
        float m = irr->r2[p - 1], a = irr->reach[2 * p], b = irr->reach[2 * p + 1];
        m = a > m ? a : m;
        irr->reach[p] = b > m ? b : m;
        irr->nmask[p] = (uint8_t)(irr->nbucket[irr->recs[p - 1].ncode] | irr->nmask[2 * p] | irr->nmask[2 * p + 1]);
    }
    return PM_OK;
}

/* Compact the precomputed photons (mask set, done counted) into records in map order with
 * their values rgbe[i] and radii^2 r2[i] (map-indexed), then build the lookup tree, which
 * reorders them. 0 or a negative code; irr is left for the caller to free on failure. */
static int irr_finish(pm_irradiance *irr, const pm_kdtree *tree, const pm_irradiance_options *opt,
                      const uint8_t (*rgbe)[4], const float *r2) {
    size_t nwords = (irr->n + 63) / 64, nd = irr->done ? irr->done : 1;
    irr->slot = malloc(nd * sizeof *irr->slot);
    irr->recs = malloc(nd * sizeof *irr->recs);
    if (opt->store_radius) irr->r2 = malloc(nd * sizeof *irr->r2);
    if (opt->store_index) irr->photon = malloc(nd * sizeof *irr->photon);
    uint32_t *perm = malloc(nd * sizeof *perm), *src = malloc(nd * sizeof *src);
    int rc = PM_ENOMEM;
    if (!irr->slot || !irr->recs || !perm || !src || (opt->store_radius && !irr->r2) ||
        (opt->store_index && !irr->photon))
        goto done;
    /* Compact, in map order; the tree build then reorders the records. */
    const pm_photon *ph = (const pm_photon *)pm_kdtree_records(tree);
    size_t j = 0;
    for (size_t w = 0; w < nwords; w++) {
        irr->rank[w] = (uint32_t)j;
        for (uint64_t b = irr->mask[w]; b; b &= b - 1) {
            size_t i = w * 64 + (size_t)__builtin_ctzll(b);
            memcpy(irr->recs[j].pos, ph[i].pos, sizeof ph[i].pos);
            memcpy(irr->recs[j].rgbe, rgbe[i], 4);
            irr->recs[j].ncode = opt->normals ? pm_normal_encode(opt->normals + 3 * i) : ph[i].normal;
            irr->recs[j].axis = 0;
            irr->recs[j].pad[0] = irr->recs[j].pad[1] = 0;
            src[j] = (uint32_t)i;
            j++;
        }
    }
    rc = PM_OK;
    if (irr->done) {
        pm_kdtree_config kc = {sizeof(pm__irr_rec), 0, (int)offsetof(pm__irr_rec, axis),
                               PM__IRR_BUCKET};
        rc = pm_kdtree_build(&irr->tree, irr->recs, irr->done, &kc, perm);
        if (rc < 0) goto done;
        for (size_t t = 0; t < irr->done; t++) {
            irr->slot[perm[t]] = (uint32_t)t;
            if (irr->r2) irr->r2[t] = r2[src[perm[t]]];
            if (irr->photon) irr->photon[t] = src[perm[t]];
        }
        if (irr->r2) rc = reach_build(irr);
    }
done:
    free(perm);
    free(src);
    return rc;
}

int pm_irradiance_build(pm_irradiance **out, const pm_kdtree *tree,
                        const pm_irradiance_options *opt) {
    if (out) *out = NULL;
    if (!out || !tree || !opt || opt->k == 0) return PM_EINVAL;
    if (opt->bias < PM_BIAS_NONE || opt->bias > PM_BIAS_HALF_FARTHEST) return PM_EINVAL;
    if (isnan(opt->max_dist2) || isnan(opt->squash)) return PM_ENONFINITE;
    pm_irradiance *irr = NULL;
    int rc0 = irr_alloc(&irr, tree, opt);
    if (rc0 < 0) return rc0;
    size_t n = irr->n;
    uint8_t(*rgbe)[4] = malloc(n * sizeof *rgbe);
    float *r2 = opt->store_radius ? malloc(n * sizeof *r2) : NULL;
    long rc = PM_ENOMEM;
    if (!rgbe || (opt->store_radius && !r2)) goto fail;
    rc = precompute(tree, opt, (const float(*)[3])irr->normals, irr->mask, rgbe, r2);
    if (rc < 0) goto fail;
    irr->done = (size_t)rc;
    rc = irr_finish(irr, tree, opt, (const uint8_t(*)[4])rgbe, r2);
    if (rc < 0) goto fail;
    free(rgbe);
    free(r2);
    *out = irr;
    return PM_OK;
fail:
    free(rgbe);
    free(r2);
    pm_irradiance_free(irr);
    return (int)rc;
}

int pm_irradiance_build_values(pm_irradiance **out, const pm_kdtree *tree,
                               const pm_irradiance_options *opt, const float *rgb, const float *r2) {
    if (out) *out = NULL;
    if (!out || !tree || !opt || !rgb || (opt->store_radius && !r2)) return PM_EINVAL;
    pm_irradiance *irr = NULL;
    int rc = irr_alloc(&irr, tree, opt);
    if (rc < 0) return rc;
    size_t n = irr->n;
    uint8_t(*rgbe)[4] = malloc(n * sizeof *rgbe);
    rc = PM_ENOMEM;
    if (!rgbe) goto fail;
    /* The same choice as precompute(), checked and encoded. */
    for (size_t i = 0; i < n; i++) {
        if (opt->fraction == PM_PRECOMP_QUARTER && pm_kdtree_height(tree, (uint32_t)i) < 2) continue;
        const float *v = rgb + 3 * i;
        for (int c = 0; c < 3; c++) {
            rc = !isfinite(v[c]) ? PM_ENONFINITE : v[c] < 0 ? PM_EINVAL : PM_OK;
            if (rc < 0) goto fail;
        }
        rc = PM_ENONFINITE;
        if (opt->store_radius && isnan(r2[i])) goto fail;
        pm_rgbe_encode(v, rgbe[i]);
        irr->mask[i >> 6] |= (uint64_t)1 << (i & 63);
        irr->done++;
    }
    rc = irr_finish(irr, tree, opt, (const uint8_t(*)[4])rgbe, r2);
    if (rc < 0) goto fail;
    free(rgbe);
    *out = irr;
    return PM_OK;
fail:
    free(rgbe);
    pm_irradiance_free(irr);
    return rc;
}

size_t pm_irradiance_count(const pm_irradiance *irr) { return irr ? irr->done : 0; }

size_t pm_irradiance_bytes(const pm_irradiance *irr) {
    if (!irr) return 0;
    size_t nwords = (irr->n + 63) / 64, nd = irr->done ? irr->done : 1;
    return sizeof *irr + nwords * (sizeof *irr->mask + sizeof *irr->rank) +
           nd * (sizeof *irr->slot + sizeof *irr->recs + (irr->r2 ? sizeof *irr->r2 : 0) +
                 (irr->photon ? sizeof *irr->photon : 0)) +
           pm_kdtree_index_bytes(irr->tree) +
           (irr->reach ? 2 * (size_t)irr->tree->nleaves * sizeof *irr->reach : 0) +
           (irr->nmask ? 2 * (size_t)irr->tree->nleaves : 0);
}

double pm_irradiance_bytes_per_photon(const pm_irradiance *irr) {
    if (!irr || irr->n == 0) return 0.0;
    return (double)pm_irradiance_bytes(irr) / (double)irr->n;
}

int pm_irradiance_value(const pm_irradiance *irr, uint32_t i, float rgb[3]) {
    if (!irr || i >= irr->n || !is_done(irr, i)) {
        if (rgb) rgb[0] = rgb[1] = rgb[2] = 0.0f;
        return 0;
    }
    uint64_t below = irr->mask[i >> 6] & (((uint64_t)1 << (i & 63)) - 1);
    uint32_t j = irr->rank[i >> 6] + (uint32_t)__builtin_popcountll(below);
    pm_rgbe_decode(irr->recs[irr->slot[j]].rgbe, rgb);
    return 1;
}
