/* irradiance.h: precomputed irradiance (Christensen, "Faster photon map global illumination").
 * (The combination of several photon maps, declared here before, is in combined.h, which this
 * header still includes so that code written against it keeps compiling.)
 *
 * PRECOMPUTED IRRADIANCE. pm_irradiance_build takes a built pm_kdtree over pm_photon records
 * and computes, at a chosen set of photons, the irradiance E (or, given a diffuse reflectance
 * rho, the radiance rho E / pi) with the bias-corrected disc estimate of k photons, using the
 * photon's normal as the surface normal (its 1-byte code, pm_photon.normal, or the exact or
 * fitted normal of LEAK CONTROL AT BUILD below) and rejecting photons that arrived from behind
 * that surface. The set is either every photon or about a quarter of
 * them: those with pm_kdtree_height(tree, i) >= 2, i.e. neither leaves nor parents of leaves
 * (for the classic tree, B = 1, exactly the records i with 4 (i + 1) <= n). With leaf buckets
 * of B > 2 records fewer qualify (pm_irradiance_count says how many). The loop runs in
 * parallel with OpenMP when the build has it.
 *
 * The k photons of the estimate at photon i include i itself. At its own sample point a density
 * estimate reads high (about 1/k for Poisson photons), but a value is only ever used through a
 * lookup at some point x, which takes the photon nearest x, and "nearest to x" means the disc
 * between x and it holds no other photon: the two effects cancel, and a lookup then matches
 * pm_estimate at x in the mean (irradiance_lookup_matches_full_estimate in
 * tests/test_irradiance.c); leaving i out makes lookups read about 1/k low.
 *
 * STORAGE AND COST. The build copies what lookups need, so the map's tree and photons may be
 * freed or reused afterwards. Per precomputed photon: a 20-byte record (float position, RGBE
 * value, normal code, the lookup tree's axis byte, 2 bytes of padding), its slot for
 * pm_irradiance_value (4 bytes) and, only if opt.store_radius, the float radius^2 of its own
 * estimate (4 bytes), and only if opt.store_index its index in the map (4 bytes): 24 bytes,
 * plus 4 for each of the two options. With radii, the lookup tree also keeps its REACH: per
 * node the largest radius^2 in its subtree (4 bytes per node, 8/9 to 16/9 of a byte per
 * precomputed photon). Per photon of the map: one bit (was it
 * precomputed) and a 4-byte rank per 64 photons (3/16 byte in all). pm_irradiance_bytes() adds
 * up what was actually allocated; irradiance_memory_measured checks it against the heap's
 * growth and against this layout, and docs/ACCURACY.md reports it per precomputed photon.
 * RGBE keeps a relative error below 2^-8 in the largest channel.
 *
 * LOOKUP. pm_irradiance_lookup returns the value of the single nearest precomputed photon
 * within radius^2 max_dist2 that passes THE NORMAL RULE below; if there is none, black
 * (rgb = 0) and 0. The search runs on the kd-tree of the precomputed photons only, so it never
 * steps over the photons that were not precomputed; tests/test_irradiance.c checks it against
 * a brute-force scan of the precomputed photons. When several photons tie at the nearest
 * dist2, which one answers is a fixed function of the build.
 *
 * THE NORMAL RULE, for both lookups: a precomputed photon may answer at x only if
 * dot(its decoded normal code, n) >= cos_min, in float arithmetic (a photon's value is the
 * irradiance of the surface it lies on, and a surface turned away by more than acos(cos_min)
 * is another surface: the floor's value must not light the wall beside it). With stored radii
 * x must also lie within that photon's own estimate radius (dist2 < its r2): its value
 * describes the disc it was computed over, no farther. The search skips every subtree of the
 * lookup tree that is no nearer to x than its reach (so a lookup where no radius reaches x,
 * as in a region photons barely reach, costs a few nodes instead of a scan of every record
 * within max_dist2); it meets the remaining records in the same order, so answers, and the
 * photons offered to the caller's rule, are bit for bit those of the search without it
 * (irradiance_lookup_reach_matches_plain_search); only pm_query_stats counts less.
 *
 * LOOKUP WITH THE CALLER'S RULE. pm_irradiance_lookup_if adds a predicate of the caller's
 * (a renderer's visibility test: is the photon on x's side of every wall?) and returns the
 * nearest precomputed photon that passes the normal rule, max_dist2 and the predicate. The
 * predicate may be costly (a shadow ray), so the module calls it only on photons that already
 * pass the normal rule and max_dist2, nearest first, and at most `tries` times: the answer is
 * the first of the `tries` nearest such photons that the predicate accepts, or none (0, rgb =
 * 0) if it rejects them all, even when a farther photon would pass. When photons tie at the
 * same dist2, which of them are asked, and in which order, is a fixed function of the build
 * and of tries (a cut inside a tie may keep other photons for other tries). The predicate receives the photon's index in the map the build read (tree order,
 * as for pm_irradiance_value), its position and its decoded normal; *photon (if not NULL) gets
 * the index of the answer. It needs a build with opt.store_index (PM_EINVAL otherwise).
 * tries runs from 1 to PM_IRRADIANCE_MAX_TRIES (PM_EINVAL otherwise); the search uses a
 * buffer of that many neighbours on the stack, so it never allocates.
 *
 * VALUES OF THE CALLER'S. pm_irradiance_build_values builds the same structure over values the
 * caller computed (an estimate with its own visibility rule, say): for the photons that
 * opt.fraction chooses (the same choice as pm_irradiance_build), rgb[3 i..3 i + 2] is the value
 * of map photon i (tree order) and, with opt.store_radius, r2[i] its radius^2; entries of the
 * photons not chosen are not read. Values must be finite and >= 0 (PM_ENONFINITE, PM_EINVAL),
 * radii^2 not NaN (PM_ENONFINITE). opt.k, max_dist2, bias, squash, reject_behind, diffuse and
 * threads are not used; opt.normals, when given, supplies the normal codes as in the build.
 *
 * LEAK CONTROL AT BUILD. opt.squash > 1 searches an ellipsoid compressed along the surface
 * normal; a normal a few degrees off makes the flat ellipsoid cut the surface and miss photons
 * (a bias low that grows with squash), and the stored 1-byte normal is up to about 10 degrees
 * off (photon.h). So the squashed search never uses that code directly: it uses the exact
 * normals of opt.normals when given (3 floats per photon, in the map's tree order: reorder
 * with the perm of pm_kdtree_build), else a normal fitted to the photons: the least-squares
 * plane through the k photons nearest the photon (one extra sphere search per precomputed
 * photon), oriented like the code, and used only if within 12 degrees of it (beyond that, at
 * a corner or on a tight curve, the fit is no better and the code is used). On a plane either
 * way squash then leaves the estimates as they are without it
 * (irradiance_squash_uses_an_exact_normal, with planes the code rounds 5 and 9.7 degrees off).
 * That normal is the estimate's surface normal throughout (the squash and the behind test);
 * the lookup's normal test uses the 1-byte code kept with each precomputed photon (the code of
 * opt.normals when given).
 *
 * THREADS. A built pm_irradiance is read-only: lookups never allocate or lock and may run on
 * any number of threads. pm_irradiance_build allocates (the caller frees with
 * pm_irradiance_free); it keeps no pointer to the tree or its photons.
 */
#ifndef PM_IRRADIANCE_H
#define PM_IRRADIANCE_H

#include "common.h"
#include "photon.h"
#include "kdtree.h"
#include "estimate.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { PM_PRECOMP_ALL = 0, PM_PRECOMP_QUARTER = 1 };

typedef struct pm_irradiance_options {
    unsigned k;           /* photons per estimate (>= 1) */
    float max_dist2;      /* search radius^2, INFINITY for none */
    int fraction;         /* PM_PRECOMP_ALL or PM_PRECOMP_QUARTER */
    int bias;             /* PM_BIAS_* of the disc estimate (default PM_BIAS_AREA) */
    float squash;         /* > 1: ellipsoid search along the photon's normal (default 1) */
    int reject_behind;    /* skip photons from behind the photon's surface (default 1) */
    const float *diffuse; /* RGB reflectance: store radiance rho E / pi; NULL: irradiance */
    int store_radius;     /* keep each estimate's radius^2 as a per-photon cut-off */
    int threads;          /* OpenMP threads, 0 = the runtime's default */
    const float *normals; /* exact unit normals, 3 floats per photon in tree order, or NULL:
                             the photons' quantized normals (see LEAK CONTROL AT BUILD) */
    int store_index;      /* keep each precomputed photon's map index (for lookup_if) */
} pm_irradiance_options;

/* The most candidates pm_irradiance_lookup_if hands to its predicate. */
#define PM_IRRADIANCE_MAX_TRIES 64u

/* The caller's rule in pm_irradiance_lookup_if: 1 accepts map photon `photon` (at pos, with
 * decoded normal) as the answer at the query, 0 rejects it. */
typedef int (*pm_irradiance_accept_fn)(void *user, uint32_t photon, const float pos[3],
                                       const float normal[3]);

typedef struct pm_irradiance pm_irradiance;

void pm_irradiance_options_init(pm_irradiance_options *opt, unsigned k);
/* Build: see the top of this file. Returns 0 and sets *out, or a negative code (PM_EINVAL,
 * PM_ENOMEM, PM_EEMPTY for an empty tree). */
int pm_irradiance_build(pm_irradiance **out, const pm_kdtree *tree,
                        const pm_irradiance_options *opt);
/* Build over values the caller computed: see VALUES OF THE CALLER'S. Returns 0 and sets *out,
 * or a negative code (PM_EINVAL, PM_ENONFINITE, PM_ENOMEM, PM_EEMPTY for an empty tree). */
int pm_irradiance_build_values(pm_irradiance **out, const pm_kdtree *tree,
                               const pm_irradiance_options *opt, const float *rgb, const float *r2);
void pm_irradiance_free(pm_irradiance *irr);

size_t pm_irradiance_count(const pm_irradiance *irr);    /* photons precomputed */
size_t pm_irradiance_bytes(const pm_irradiance *irr);    /* bytes it owns (allocated) */
double pm_irradiance_bytes_per_photon(const pm_irradiance *irr); /* bytes / photons of the map */
/* 1 and the stored value if photon i was precomputed, else 0. */
int pm_irradiance_value(const pm_irradiance *irr, uint32_t i, float rgb[3]);

/* Lookup: returns 1 (found; rgb set), 0 (none: rgb = 0) or a negative code. n is the unit
 * normal at x; cos_min the threshold on dot(photon normal, n), e.g. 0.9. If max_dist2 is not
 * finite and no radii were stored, the whole map is searched. */
int pm_irradiance_lookup(const pm_irradiance *irr, const float x[3], const float n[3],
                         float max_dist2, float cos_min, float rgb[3], pm_query_stats *stats);
/* Lookup with the caller's predicate: see LOOKUP WITH THE CALLER'S RULE. Returns 1 (found; rgb
 * and *photon set), 0 (none: rgb = 0) or a negative code. accept may be NULL (accept all). */
int pm_irradiance_lookup_if(const pm_irradiance *irr, const float x[3], const float n[3],
                            float max_dist2, float cos_min, unsigned tries,
                            pm_irradiance_accept_fn accept, void *user, float rgb[3],
                            uint32_t *photon, pm_query_stats *stats);

#ifdef __cplusplus
}
#endif

#include "combined.h"

#endif /* PM_IRRADIANCE_H */
