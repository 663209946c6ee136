/* estimate.h: radiance and irradiance estimates from the photons nearest a point.
 *
 * WHAT IT COMPUTES. At a surface point x with unit normal n, the photon-map radiance estimate
 * is L = sum_p f_r(x, w_p) dPhi_p * w(d_p) / (N_w pi r^2): a sum over the photons near x of
 * their power, weighted by the BRDF and by a filter w, divided by the (filter-normalised) area
 * of the disc they were gathered from. The estimators differ in w and in how the area is found:
 *
 *   PM_EST_DISC          w = 1, area pi r^2 with r the farthest photon's distance. Optional
 *                        bias correction (Christensen): the k-th photon lies ON the disc's rim,
 *                        so k/(pi r^2) counts one photon too many on average; either scale the
 *                        area by k/(k-0.5) (PM_BIAS_AREA) or count half the farthest photon's
 *                        power (PM_BIAS_HALF_FARTHEST). For equal powers the two agree.
 *   PM_EST_CONE          w = 1 - d/(k_c r), k_c >= 1, normalised by N_w = 1 - 2/(3 k_c).
 *   PM_EST_GAUSS         w = alpha [1 - (1 - exp(-beta d^2/(2r^2))) / (1 - exp(-beta))] with
 *                        alpha = 0.918, beta = 1.953 (Jensen, after Pavicic). That alpha does
 *                        not make the filter's mean over the disc 1 (it is about 0.531), so we
 *                        divide by the exact disc mean N_w = alpha [1 - (1 - (2/beta)(1 -
 *                        exp(-beta/2))) / (1 - exp(-beta))], as the cone divides by its own.
 *                        For both filters, a bias option other than PM_BIAS_NONE counts the
 *                        farthest (rim) photon at half its weight, as for the disc; this
 *                        matters for the Gaussian (rim weight about 0.25) and the cone with
 *                        k_c > 1 (for k_c = 1 the rim weight is 0). Their measured bias,
 *                        on stratified and on random photons, is in docs/ACCURACY.md.
 *   PM_EST_DIFFERENTIAL  Differential checking (Jensen, after Myszkowski): photons are added
 *                        in order of distance and the (half-farthest corrected) disc estimate
 *                        is read at checkpoints every diff_step photons from diff_min on; when
 *                        it moves the same way (up, or down, by more than diff_tol each time)
 *                        at diff_run checkpoints in a row, the disc has crossed an edge of the
 *                        lit region, and the estimate at the checkpoint before that run is
 *                        returned. Single photons change a k-photon estimate by about 1/k
 *                        either way, which is why it compares checkpoints, not photons. It
 *                        uses fewer photons near edges.
 *   PM_EST_HULL          Christensen's convex-hull estimate: the photons are projected onto the
 *                        tangent plane at x, the area is that of their 2D convex hull (Andrew's
 *                        monotone chain in double, with a relative tolerance in the orientation
 *                        test so duplicate and collinear points are never hull vertices), and
 *                        the photons that are hull vertices count with weight hull_boundary
 *                        (0.2) while interior ones count in full. Degenerate input (fewer than 3
 *                        photons, fewer than 3 hull vertices, or a hull whose area is below
 *                        PM_HULL_MIN_AREA_FRACTION of pi r^2 or below pi times the radius^2
 *                        floor: duplicates, collinear or nearly collinear photons, photons at
 *                        x) falls back to the disc estimate and sets
 *                        PM_EST_F_HULL_FALLBACK. There is never a division by a zero area.
 *                        Far from every photon (a dist2 overflowed) it returns 0 with
 *                        PM_EST_F_FAR, exactly as the disc does.
 *                        PAST AN EDGE: the hull measures the density of the photons it found,
 *                        wherever x is. At a point beyond the edge of a lit region (true
 *                        irradiance 0) the k nearest photons all lie in the lit region and
 *                        their hull covers only them, so it reads the lit side's value, with
 *                        no fall-off however far x is (tested out to 25 photon spacings); the
 *                        disc falls off as its radius grows. Where the dark side matters, set
 *                        max_dist2 (beyond it every estimator reads 0) or use the disc.
 *                        RANDOM PHOTONS: with the default hull_boundary 0.2 the hull reads
 *                        high on random (Poisson) photons, where hull vertices are few and
 *                        the hull misses much of the region, and is nearly unbiased on
 *                        stratified ones; hull_boundary = 0 (the interior photons over the
 *                        hull's area: Ripley and Rasson's estimate of a region from uniform
 *                        points) is the correction for random photons but reads low on
 *                        stratified ones. docs/ACCURACY.md measures both against the disc.
 *
 * The volume estimate (pm_estimate_volume_core) is L = (1/sigma_s) sum f dPhi / (4/3 pi r^3)
 * with the isotropic phase function 1/(4 pi) unless a phase callback is given.
 *
 * BRDF. opt.brdf (a callback) gives f_r per photon from its incident direction; else
 * opt.diffuse (an RGB albedo rho) gives f_r = rho/pi; else f_r = 1, and the estimate is the
 * IRRADIANCE E = sum dPhi / (pi r^2) (this is what the tests and precomputed irradiance use).
 *
 * WHICH ONE. docs/ACCURACY.md (generated by bench_estimate) gives the bias and noise of each
 * estimator on stratified and random photons and on a focused caustic; README.md
 * ("Estimates") says which to pick for which case.
 *
 * RADIUS. With n photons found for k requested: if n == k, or the search was unlimited, r^2 is
 * the largest neighbour dist2 (the k-th nearest). If n < k and max_dist2 is finite, the search
 * covered the whole disc of radius^2 max_dist2, so that is the area used (unbiased: no
 * correction is applied then). A radius^2 below the floor (opt.min_dist2, or by default the
 * float resolution at x: (2^-20 max(1, |x|_inf))^2) is raised to it and PM_EST_F_RADIUS_FLOOR
 * is set, so photons all exactly at x give a large but finite value. An infinite r^2 (x far
 * outside the map, float overflow) gives 0.
 *
 * GUARANTEES. Every estimator returns PM_OK and a finite, non-negative rgb for any finite x and
 * any neighbour list: none, one or two photons, all at x, collinear, zero power, powers from
 * 1e-30 to 1e30, x far from every photon. Sums are accumulated in double. A non-finite x or
 * normal gives PM_ENONFINITE; a bad option (k = 0, k_c < 1, ...) PM_EINVAL.
 *
 * TWO LAYERS. Each estimator has a CORE that takes the photon array and a list of neighbours
 * (pm_neighbor: index into the photons, dist2) that someone already found, so it can be tested
 * and timed without a tree, and a WRAPPER, pm_estimate(), that runs the k-nearest search on a
 * pm_kdtree (optionally an ellipsoid search compressed along n, and skipping photons that
 * arrive from behind the surface: leak control) and then the core. The core accepts the list
 * in any order (the kd-tree's unsorted order is fine); it never modifies it.
 *
 * SCRATCH AND THREADS. Nothing here allocates or keeps state. The caller passes `scratch`, at
 * least pm_estimate_scratch_bytes(k) bytes aligned for a double (malloc memory is); one buffer
 * per thread makes every call reentrant. The core needs scratch only for PM_EST_HULL and
 * PM_EST_DIFFERENTIAL (it may be NULL otherwise).
 */
#ifndef PM_ESTIMATE_H
#define PM_ESTIMATE_H

#include "common.h"
#include "photon.h"
#include "kdtree.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum pm_estimator {
    PM_EST_DISC = 0,
    PM_EST_CONE = 1,
    PM_EST_GAUSS = 2,
    PM_EST_DIFFERENTIAL = 3,
    PM_EST_HULL = 4,
    PM_EST_COUNT_ = 5 /* number of estimators, for loops in benchmarks */
} pm_estimator;

/* Bias correction of the disc estimate (also used by the disc fallback of the hull, by
 * differential checking's running estimate, by the volume estimate and by combined maps). */
enum {
    PM_BIAS_NONE = 0,
    PM_BIAS_AREA = 1,         /* area * k/(k - 0.5) */
    PM_BIAS_HALF_FARTHEST = 2 /* the farthest photon counts with half its power */
};

/* Result flags (pm_estimate_result.flags). */
#define PM_EST_F_EMPTY 1u         /* no photons: the estimate is 0 */
#define PM_EST_F_HULL_FALLBACK 2u /* the hull was degenerate; the disc estimate was used */
#define PM_EST_F_RADIUS_FLOOR 4u  /* r^2 was raised to the floor (photons at or next to x) */
#define PM_EST_F_RADIUS_LIMIT 8u  /* fewer than k found; the area is that of max_dist2 */
#define PM_EST_F_DIFF_STOPPED 16u /* differential checking stopped before using all photons */
#define PM_EST_F_FAR 32u          /* r^2 overflowed (x far from every photon): the estimate is 0 */

/* A hull whose area is below this fraction of pi r^2 counts as degenerate (collinear). */
#define PM_HULL_MIN_AREA_FRACTION 1e-3

/* Jensen's Gaussian filter constants. */
#define PM_GAUSS_ALPHA 0.918
#define PM_GAUSS_BETA 1.953

/* f_r for one photon: wi is the unit direction the photon came FROM (minus its travel
 * direction); write the BRDF value per channel to f. Called from the estimating thread. */
typedef void (*pm_brdf_fn)(void *user, const float wi[3], float f[3]);

typedef struct pm_estimate_options {
    pm_estimator kind;
    unsigned k;           /* photons to gather, >= 1 */
    float max_dist2;      /* search radius^2; INFINITY for none */
    int bias;             /* PM_BIAS_* (disc, hull fallback, differential) */
    double cone_k;        /* k_c >= 1 for PM_EST_CONE (default 1) */
    double hull_boundary; /* weight of the hull-vertex photons, in [0, 1] (default 0.2) */
    unsigned diff_min;    /* differential: photons at the first checkpoint (0: max(8, k/4)) */
    unsigned diff_step;   /* differential: photons between checkpoints (0: max(2, k/10)) */
    unsigned diff_run;    /* differential: same-direction moves that stop it (0: 3) */
    double diff_tol;      /* differential: a relative change below this is no move (0.01) */
    /* Leak control (used by the wrapper's search only). */
    float squash;         /* > 1: ellipsoid metric |d|^2 + (squash-1)(d.n)^2; <= 1: sphere */
    int reject_behind;    /* nonzero: skip photons whose travel direction has d.n > 0 */
    /* BRDF: brdf callback, else diffuse albedo, else irradiance (f = 1). */
    pm_brdf_fn brdf;
    void *brdf_user;
    const float *diffuse; /* RGB albedo, or NULL */
    float min_dist2;      /* floor for r^2 (0: automatic, see the top of this file) */
} pm_estimate_options;

typedef struct pm_estimate_result {
    double rgb[3];  /* the estimate: radiance, or irradiance if no BRDF was given */
    double r2;      /* the radius^2 whose area was used (for the hull: the farthest dist2) */
    double area;    /* the area divided by: pi r^2 (times any correction), or the hull's */
    unsigned found; /* neighbours given to the core (or found by the search) */
    unsigned used;  /* photons that contributed (differential checking may use fewer) */
    unsigned flags; /* PM_EST_F_* */
} pm_estimate_result;

/* Defaults: the given kind and k, unlimited radius, PM_BIAS_AREA, k_c = 1, boundary 0.2,
 * differential defaults, sphere search, no rejection, irradiance. */
void pm_estimate_options_init(pm_estimate_options *opt, pm_estimator kind, unsigned k);
/* A short lowercase name ("disc", "cone", "gauss", "differential", "hull"), or "?". */
const char *pm_estimator_name(pm_estimator kind);
/* Bytes of scratch the wrapper needs for k photons (the core needs no more): 48 k + 64. */
size_t pm_estimate_scratch_bytes(unsigned k);
/* The normalisation N_w of each filter: the mean of its weight over the unit disc. */
double pm_cone_norm(double cone_k);
double pm_gauss_norm(void);

/* CORE. photons: the record array the neighbour indices refer to; nb[0..count): neighbours
 * (any order); x, normal: the point and its unit normal (normal is needed by PM_EST_HULL and
 * by a BRDF callback; may be NULL otherwise, then the hull projects onto the z = 0 plane).
 * opt->k is the number that was requested (it decides the radius rule above); count may be
 * smaller, not larger (PM_EINVAL). scratch: see above. */
int pm_estimate_core(const pm_photon *photons, const pm_neighbor *nb, unsigned count,
                     const float x[3], const float normal[3], const pm_estimate_options *opt,
                     void *scratch, pm_estimate_result *out);

/* WRAPPER. Finds up to opt->k photons in the tree (records must be pm_photon) with dist2 <
 * opt->max_dist2, using the ellipsoid metric if opt->squash > 1 and skipping photons from
 * behind if opt->reject_behind, then runs the core. scratch: pm_estimate_scratch_bytes(k). */
int pm_estimate(const pm_kdtree *tree, const float x[3], const float normal[3],
                const pm_estimate_options *opt, void *scratch, pm_estimate_result *out,
                pm_query_stats *stats);

/* The k-nearest options of the wrapper's leak-controlled search, for callers who run the
 * search themselves (then pm_estimate_core): the ellipsoid metric along normal if
 * opt->squash > 1 and normal is given, and pm_filter_front if opt->reject_behind. nrm is the
 * caller's storage that *ko points into (a copy of normal, or +z); keep it alive while ko is
 * used. pm_estimate and pm_estimate_combined use exactly this. */
void pm_estimate_search_options(const pm_estimate_options *opt, const float normal[3],
                                float nrm[3], pm_knn_options *ko);

/* A pm_filter_fn for leak control: user points to a unit normal float[3]; accepts a photon
 * (pm_photon record) whose travel direction d has d . normal <= 0, i.e. that arrived at the
 * front of the surface. */
int pm_filter_front(void *user, const void *record, uint32_t index);

/* VOLUME. L = (1/sigma_s) sum phase * dPhi / (4/3 pi r^3); phase = 1/(4 pi) unless opt->brdf
 * is given (then it is the phase function, called with wi as for a BRDF). Uses opt->k,
 * max_dist2, bias, brdf and min_dist2 (floor for r^2) only; the radius rule is as for
 * surfaces. sigma_s must be finite and > 0. No scratch needed. */
int pm_estimate_volume_core(const pm_photon *photons, const pm_neighbor *nb, unsigned count,
                            const float x[3], double sigma_s, const pm_estimate_options *opt,
                            pm_estimate_result *out);
/* Volume wrapper: a plain (spherical) k-nearest search, then the core. scratch: k * 8 bytes. */
int pm_estimate_volume(const pm_kdtree *tree, const float x[3], double sigma_s,
                       const pm_estimate_options *opt, void *scratch, pm_estimate_result *out,
                       pm_query_stats *stats);

/* AUTOMATIC MAXIMUM RADIUS (Christensen). The radius beyond which k photons of power p_max
 * could only give a radiance below the threshold L_t (with a white diffuse BRDF):
 *   surface: r_m = (1/pi) sqrt(k p_max / L_t)
 *   volume:  r_m = cbrt(3 k p_max / (16 pi^2 sigma_s L_t))
 * These return the RADIUS (square it for max_dist2). A non-positive or non-finite L_t (or
 * sigma_s) gives INFINITY, i.e. no limit; a non-positive p_max gives 0. */
double pm_auto_radius_surface(unsigned k, double p_max, double L_t);
double pm_auto_radius_volume(unsigned k, double p_max, double sigma_s, double L_t);
/* The largest channel power of photons[0..n) (decoded), for p_max above; 0 if n = 0. */
double pm_photons_max_power(const pm_photon *photons, size_t n);

#ifdef __cplusplus
}
#endif

#endif /* PM_ESTIMATE_H */
