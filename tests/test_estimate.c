/* test_estimate.c: the radiance estimates of photonmap/estimate.h against analytic truth.
 *
 * Most tests drive the estimator CORES with neighbour lists from a brute-force oracle, so they
 * test the estimates and not the kd-tree: for the lit square the oracle scans a window of
 * grid cells that provably contains the k nearest (it widens the window until the
 * k-th distance is inside it). The wrapper tests then check that pm_estimate() over a real
 * kd-tree gives the same value as the core on the brute-force list, and test leak control.
 *
 * The uniform square is Christensen's experiment: the unit square z = 0 lit by parallel
 * light, 200 x 200 photons (one per cell of a jittered grid, or uniform random), every photon
 * with the same power,
 * chosen exactly representable in RGBE (2^-15, 2^-16, 2^-17 per channel) so the truth
 * E = N * P (per unit area) carries no quantization error. Each square test runs on both
 * layouts: stratified (jittered) and random (uniform, independent, as photon tracing makes).
 */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#ifdef _OPENMP
#include <omp.h>
#endif
#include "test.h"
#include "photonmap.h"
#include "estimate.h"
#include "irradiance.h"

/* ---- tiny deterministic RNG (splitmix64) --------------------------------------------- */
typedef struct { uint64_t s; } rng_t;
static uint64_t rng_u64(rng_t *r) {
    uint64_t z = (r->s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}
static double rng_unit(rng_t *r) { return (double)(rng_u64(r) >> 11) * 0x1p-53; }

/* ---- the lit square (stratified or random) and its brute-force k-nearest oracle ---------- */
#define SIDE 200
static const float DOWN[3] = {0, 0, -1}, UP[3] = {0, 0, 1};

/* SIDE * SIDE photons on the unit square: STRATIFIED (one uniform point in each cell of the
 * SIDE x SIDE grid, i.e. jittered) or RANDOM (uniform, independent: a Poisson-like map, as
 * photon tracing makes). Either way the photons are stored grouped by grid cell, cell c
 * holding ph[start[c] .. start[c + 1]), so the oracle can scan a window of cells. */
enum { STRATIFIED = 0, RANDOM = 1 };
static const char *const LAYOUT[2] = {"stratified", "random"};
typedef struct square {
    pm_photon *ph;
    uint32_t *start; /* SIDE * SIDE + 1 offsets */
    double truth[3];
} square;

static void make_square(square *sq, uint64_t seed, int layout) {
    rng_t r = {seed};
    const float power[3] = {0x1p-15f, 0x1p-16f, 0x1p-17f};
    const size_t n = SIDE * SIDE;
    float(*pos)[3] = malloc(sizeof *pos * n);
    uint32_t *cell = malloc(sizeof *cell * n);
    sq->ph = malloc(sizeof(pm_photon) * n);
    sq->start = calloc(n + 1, sizeof *sq->start);
    for (size_t i = 0; i < n; i++) {
        double x = rng_unit(&r), y = rng_unit(&r);
        if (layout == STRATIFIED) x = ((double)(i / SIDE) + x) / SIDE, y = ((double)(i % SIDE) + y) / SIDE;
        pos[i][0] = (float)x, pos[i][1] = (float)y, pos[i][2] = 0;
        int ci = (int)floor(pos[i][0] * SIDE), cj = (int)floor(pos[i][1] * SIDE);
        ci = ci < 0 ? 0 : ci >= SIDE ? SIDE - 1 : ci, cj = cj < 0 ? 0 : cj >= SIDE ? SIDE - 1 : cj;
        cell[i] = (uint32_t)(ci * SIDE + cj);
        sq->start[cell[i] + 1]++;
    }
    for (size_t c = 0; c < n; c++) sq->start[c + 1] += sq->start[c];
    uint32_t *fill = malloc(sizeof *fill * n);
    memcpy(fill, sq->start, sizeof *fill * n);
    for (size_t i = 0; i < n; i++) pm_photon_init(&sq->ph[fill[cell[i]]++], pos[i], power, DOWN, UP, PM_KIND_DIRECT);
    free(fill), free(cell), free(pos);
    float dec[3];
    pm_rgbe_decode(sq->ph[0].power, dec);
    for (int c = 0; c < 3; c++) sq->truth[c] = (double)SIDE * SIDE * dec[c];
}
static void free_square(square *sq) { free(sq->ph), free(sq->start); }

static int cmp_nb(const void *a, const void *b) {
    const pm_neighbor *x = a, *y = b;
    return x->dist2 < y->dist2 ? -1 : x->dist2 > y->dist2 ? 1 : (x->index > y->index) - (x->index < y->index);
}

static float dist2f(const float *p, const float *q) {
    float dx = p[0] - q[0], dy = p[1] - q[1], dz = p[2] - q[2];
    return dx * dx + dy * dy + dz * dz;
}

/* The k nearest photons of the square to q (sorted), into out (k entries); cand must hold
 * SIDE*SIDE entries. Scans the cells within w of q's cell, widening until the k-th distance
 * is within w cell widths (every photon outside the window is farther than that). Returns the
 * count (k unless the square has fewer). */
static unsigned square_knn(const square *sq, const float q[3], unsigned k, pm_neighbor *out,
                           pm_neighbor *cand) {
    const double h = 1.0 / SIDE;
    int ci = (int)floor(q[0] * SIDE), cj = (int)floor(q[1] * SIDE);
    int w = (int)ceil(sqrt(k / 3.14159)) + 1;
    for (;;) {
        unsigned nc = 0;
        for (int i = ci - w; i <= ci + w; i++) {
            if (i < 0 || i >= SIDE) continue;
            for (int j = cj - w; j <= cj + w; j++) {
                if (j < 0 || j >= SIDE) continue;
                uint32_t c = (uint32_t)(i * SIDE + j);
                for (uint32_t idx = sq->start[c]; idx < sq->start[c + 1]; idx++) {
                    cand[nc].index = idx;
                    cand[nc].dist2 = dist2f(sq->ph[idx].pos, q);
                    nc++;
                }
            }
        }
        qsort(cand, nc, sizeof *cand, cmp_nb);
        int whole = ci - w <= 0 && cj - w <= 0 && ci + w >= SIDE - 1 && cj + w >= SIDE - 1;
        if (whole || (nc >= k && cand[k - 1].dist2 <= (float)((w * h) * (w * h)))) {
            unsigned n = nc < k ? nc : k;
            memcpy(out, cand, n * sizeof *out);
            return n;
        }
        w *= 2;
    }
}

typedef struct stats { double sum, sum2, n; } stats;
static void st_add(stats *s, double v) { s->sum += v, s->sum2 += v * v, s->n += 1; }
static double st_mean(const stats *s) { return s->sum / s->n; }
static double st_sem(const stats *s) {
    double m = st_mean(s), var = (s->sum2 - s->n * m * m) / (s->n - 1);
    return sqrt(fmax(var, 0.0) / s->n);
}

/* Relative error statistics of one estimator over `lookups` queries drawn by `draw`. */
typedef void (*draw_fn)(rng_t *r, float q[3]);
static void draw_interior(rng_t *r, float q[3]) {
    q[0] = (float)(0.1 + 0.8 * rng_unit(r)), q[1] = (float)(0.1 + 0.8 * rng_unit(r)), q[2] = 0;
}
/* Between 0.01 and 0.02 from one of the four edges, away from the corners: a 100-photon
 * disc (radius about 0.028) starts inside the square and crosses the edge as it grows. */
static void draw_near_edge(rng_t *r, float q[3]) {
    double along = 0.1 + 0.8 * rng_unit(r), in = 0.01 + 0.01 * rng_unit(r);
    switch (rng_u64(r) & 3) {
    case 0: q[0] = (float)along, q[1] = (float)in; break;
    case 1: q[0] = (float)along, q[1] = (float)(1 - in); break;
    case 2: q[0] = (float)in, q[1] = (float)along; break;
    default: q[0] = (float)(1 - in), q[1] = (float)along; break;
    }
    q[2] = 0;
}

/* Within 0.002 of one of the four edges, away from the corners. */
static void draw_edge(rng_t *r, float q[3]) {
    double along = 0.1 + 0.8 * rng_unit(r), in = 0.002 * rng_unit(r);
    switch (rng_u64(r) & 3) {
    case 0: q[0] = (float)along, q[1] = (float)in; break;
    case 1: q[0] = (float)along, q[1] = (float)(1 - in); break;
    case 2: q[0] = (float)in, q[1] = (float)along; break;
    default: q[0] = (float)(1 - in), q[1] = (float)along; break;
    }
    q[2] = 0;
}

typedef struct run_out { stats rel; stats used; double max_chan_err; } run_out;

static run_out run_square(const square *sq, const pm_estimate_options *opt, unsigned lookups,
                          draw_fn draw, uint64_t seed) {
    run_out ro;
    memset(&ro, 0, sizeof ro);
    rng_t r = {seed};
    pm_neighbor *nb = malloc(sizeof *nb * opt->k), *cand = malloc(sizeof *cand * SIDE * SIDE);
    void *scratch = malloc(pm_estimate_scratch_bytes(opt->k));
    for (unsigned l = 0; l < lookups; l++) {
        float q[3];
        pm_estimate_result res;
        draw(&r, q);
        unsigned n = square_knn(sq, q, opt->k, nb, cand);
        int rc = pm_estimate_core(sq->ph, nb, n, q, UP, opt, scratch, &res);
        EXPECT_EQ_INT(rc, PM_OK);
        st_add(&ro.rel, res.rgb[0] / sq->truth[0] - 1.0);
        st_add(&ro.used, res.used);
        /* The channels keep their exact 4:2:1 ratio (same photons, same weights). */
        ro.max_chan_err = fmax(ro.max_chan_err, fabs(res.rgb[1] * 2 - res.rgb[0]) / fmax(res.rgb[0], 1e-300));
    }
    free(nb), free(cand), free(scratch);
    return ro;
}

/* Lookups giving a standard error of the mean below 0.15% (checked in each test): the
 * per-lookup spread of a k-photon estimate falls roughly as 1/sqrt(k). */
static unsigned lookups_for(unsigned k) {
    unsigned n = 150000u / k;
    return n < 2000 ? 2000 : n;
}
/* On random photons the tolerances carry 3 SEM, so half as many lookups do. */
static unsigned lookups_for_layout(unsigned k, int layout) {
    return layout == RANDOM ? lookups_for(k) / 2 : lookups_for(k);
}

/* The mean relative error a k-photon estimate has on RANDOM photons in a uniform density,
 * derived: with the k-th photon on the rim at radius r, the other k - 1 are independent and
 * uniform in the disc (a Poisson process conditioned on r), so a filter w with disc mean N_w
 * sums to (k - 1) N_w on average, plus w(rim) times the rim photon's factor (1/2 with a bias
 * correction, else 1); and pi r^2 lambda is a Gamma(k) variable with E[1/Gamma(k)] =
 * 1/(k - 1). So E[estimate]/E = (k - 1 + rim w(rim)/N_w)/(k - 1) times any area factor:
 * the corrected disc (k - 1/2)/(k - 1), the uncorrected disc k/(k - 1), the cone with k_c = 1
 * exactly 1 (its rim weight is 0). */
static double poisson_bias(unsigned k, double rim_weight_over_norm, double area_factor) {
    return area_factor * ((double)k - 1 + rim_weight_over_norm) / ((double)k - 1) - 1;
}

/* Oracle: the analytic irradiance N * P of the uniformly lit square (Christensen's test), on
 * stratified and on random photons. Stratified: the bias-corrected disc (both forms) and the
 * hull within 0.5% for k in {25, 50, 100, 500} and within 1.2% at k = 15 (the rim photon is
 * the only bias there: a k-photon disc holds k - 1/2 photons' worth of area). Random: the
 * disc's mean relative error is poisson_bias (+0.5/(k - 1)), checked within 0.5% + 3 SEM;
 * the hull with its default boundary weight reads high (more than 3 SEM above the truth for
 * k <= 100: estimate.h, RANDOM PHOTONS), and with hull_boundary = 0 (the Ripley-Rasson
 * correction) it is within 0.6% + 3 SEM of the truth. The SEM of each stratified mean is
 * below 0.15% (lookups_for). */
TEST(estimate_square_corrected_disc_and_hull) {
    const unsigned ks[] = {15, 25, 50, 100, 500};
    const pm_estimator kinds[] = {PM_EST_DISC, PM_EST_DISC, PM_EST_HULL, PM_EST_HULL};
    const int biases[] = {PM_BIAS_AREA, PM_BIAS_HALF_FARTHEST, PM_BIAS_AREA, PM_BIAS_AREA};
    for (int layout = 0; layout < 2; layout++) {
        square sq;
        make_square(&sq, 1, layout);
        for (unsigned ki = 0; ki < sizeof ks / sizeof ks[0]; ki++) {
            for (int e = 0; e < 4; e++) {
                unsigned k = ks[ki];
                pm_estimate_options o;
                pm_estimate_options_init(&o, kinds[e], k);
                o.bias = biases[e];
                if (e == 3) o.hull_boundary = 0;
                run_out ro = run_square(&sq, &o, lookups_for_layout(k, layout), draw_interior, 100 + ki);
                double m = st_mean(&ro.rel), sem = st_sem(&ro.rel), tol = k == 15 ? 0.012 : 0.005;
                printf("%s square k=%u %s%s bias=%d: mean %+.3f%% sem %.3f%%\n", LAYOUT[layout], k,
                       pm_estimator_name(kinds[e]), e == 3 ? " (boundary 0)" : "", biases[e], 100 * m, 100 * sem);
                EXPECT_MSG(ro.max_chan_err < 1e-12, "channel ratio off by %g", ro.max_chan_err);
                if (layout == STRATIFIED) {
                    if (e == 3) continue; /* boundary 0 is the random-photon correction */
                    EXPECT_MSG(sem < 0.0015, "k=%u %s: sem %.4f%% too large", k, pm_estimator_name(kinds[e]), 100 * sem);
                    EXPECT_MSG(fabs(m) <= tol, "stratified k=%u %s bias %d: mean error %+.3f%% (tol %.1f%%)", k,
                               pm_estimator_name(kinds[e]), biases[e], 100 * m, 100 * tol);
                } else if (e < 2) {
                    double want = poisson_bias(k, 1.0, ((double)k - 0.5) / (double)k);
                    EXPECT_MSG(fabs(m - want) <= 0.005 + 3 * sem, "random k=%u disc bias %d: %+.3f%%, derived %+.3f%%",
                               k, biases[e], 100 * m, 100 * want);
                } else if (e == 2) {
                    if (k <= 100) EXPECT_MSG(m > 3 * sem, "random k=%u hull: %+.3f%% (sem %.3f%%)", k, 100 * m, 100 * sem);
                } else {
                    EXPECT_MSG(fabs(m) <= 0.006 + 3 * sem, "random k=%u hull boundary 0: %+.3f%%", k, 100 * m);
                }
            }
        }
        free_square(&sq);
    }
}

/* Oracle: as above. The uncorrected disc counts the rim photon in full, so it is too bright:
 * by about 1/(2k) on stratified photons (asserted: k = 15 in [+2%, +6%], k = 50 in
 * [+0.5%, +2%]) and by 1/(k - 1) on random photons (poisson_bias; within 0.5% + 3 SEM). */
TEST(estimate_square_uncorrected_disc_too_bright) {
    const unsigned ks[] = {15, 50};
    const double lo[] = {0.02, 0.005}, hi[] = {0.06, 0.02};
    for (int layout = 0; layout < 2; layout++) {
        square sq;
        make_square(&sq, 2, layout);
        for (int i = 0; i < 2; i++) {
            pm_estimate_options o;
            pm_estimate_options_init(&o, PM_EST_DISC, ks[i]);
            o.bias = PM_BIAS_NONE;
            run_out ro = run_square(&sq, &o, lookups_for_layout(ks[i], layout), draw_interior, 200 + i);
            double m = st_mean(&ro.rel), sem = st_sem(&ro.rel);
            printf("%s, uncorrected disc k=%u: mean %+.3f%% sem %.3f%%\n", LAYOUT[layout], ks[i], 100 * m, 100 * sem);
            if (layout == STRATIFIED)
                EXPECT_MSG(m >= lo[i] && m <= hi[i], "k=%u: uncorrected mean %+.3f%% outside [%+.1f%%, %+.1f%%]",
                           ks[i], 100 * m, 100 * lo[i], 100 * hi[i]);
            else
                EXPECT_MSG(fabs(m - poisson_bias(ks[i], 1.0, 1.0)) <= 0.005 + 3 * sem, "random k=%u: %+.3f%%, derived %+.3f%%",
                           ks[i], 100 * m, 100 * poisson_bias(ks[i], 1.0, 1.0));
        }
        free_square(&sq);
    }
}

/* Oracle: the analytic irradiance, for lookups within 0.002 of an edge (where the true
 * irradiance steps from E to 0, and x sees E). The disc there sees a little more than half a
 * disc of photons, so it is about 45% too dark (asserted: mean in [-50%, -38%]) on both
 * layouts. The hull follows the edge: within 2% on stratified photons for k >= 25. On random
 * photons, with hull_boundary = 0 (the random-photon correction), it reads a few percent high
 * at the edge (the hull there is cut by the edge, which random photons outline less well):
 * within 7% for k >= 25 and 1.5% at k = 500. */
TEST(estimate_square_edges) {
    const unsigned ks[] = {25, 50, 100, 500};
    for (int layout = 0; layout < 2; layout++) {
        square sq;
        make_square(&sq, 3, layout);
        for (int i = 0; i < 4; i++) {
            pm_estimate_options o;
            pm_estimate_options_init(&o, PM_EST_HULL, ks[i]);
            if (layout == RANDOM) o.hull_boundary = 0;
            run_out h = run_square(&sq, &o, lookups_for_layout(ks[i], layout), draw_edge, 300 + i);
            o.kind = PM_EST_DISC;
            run_out d = run_square(&sq, &o, lookups_for_layout(ks[i], layout), draw_edge, 300 + i);
            double mh = st_mean(&h.rel), md = st_mean(&d.rel);
            printf("%s edge k=%u: hull %+.3f%% (sem %.3f%%), disc %+.2f%%\n", LAYOUT[layout], ks[i], 100 * mh,
                   100 * st_sem(&h.rel), 100 * md);
            double tol = layout == STRATIFIED ? 0.02 : ks[i] >= 500 ? 0.015 : 0.07;
            EXPECT_MSG(fabs(mh) <= tol, "%s k=%u: hull at edges %+.3f%%", LAYOUT[layout], ks[i], 100 * mh);
            EXPECT_MSG(md >= -0.50 && md <= -0.38, "%s k=%u: disc at edges %+.2f%%", LAYOUT[layout], ks[i], 100 * md);
        }
        free_square(&sq);
    }
}

/* Oracle: the analytic irradiance. With their normalisations (1 - 2/(3 k_c) for the cone, the
 * exact disc mean of the weight for the Gaussian) the interior mean is within 1% on stratified
 * photons, and within 1% + 3 SEM of poisson_bias (the rim photon at half its weight, over the
 * filter's mean) on random photons, for k_c in {1, 1.5} and k in {25, 50, 100}. */
TEST(estimate_square_cone_gauss) {
    const unsigned ks[] = {25, 50, 100};
    for (int layout = 0; layout < 2; layout++) {
        square sq;
        make_square(&sq, 4, layout);
        for (int i = 0; i < 3; i++) {
            for (int f = 0; f < 3; f++) {
                pm_estimate_options o;
                pm_estimate_options_init(&o, f < 2 ? PM_EST_CONE : PM_EST_GAUSS, ks[i]);
                o.cone_k = f == 1 ? 1.5 : 1.0;
                run_out ro = run_square(&sq, &o, lookups_for_layout(ks[i], layout), draw_interior, 400 + 3 * i + f);
                double m = st_mean(&ro.rel), sem = st_sem(&ro.rel);
                double rim = f < 2 ? 1 - 1 / o.cone_k : PM_GAUSS_ALPHA * (exp(-PM_GAUSS_BETA / 2) - exp(-PM_GAUSS_BETA)) / (1 - exp(-PM_GAUSS_BETA));
                double norm = f < 2 ? pm_cone_norm(o.cone_k) : pm_gauss_norm();
                double want = layout == RANDOM ? poisson_bias(ks[i], 0.5 * rim / norm, 1.0) : 0.0;
                printf("%s %s k=%u kc=%.1f: mean %+.3f%% sem %.3f%% (derived for random photons %+.3f%%)\n", LAYOUT[layout],
                       pm_estimator_name(o.kind), ks[i], o.cone_k, 100 * m, 100 * sem, 100 * poisson_bias(ks[i], 0.5 * rim / norm, 1.0));
                EXPECT_MSG(fabs(m - want) <= 0.01 + (layout == RANDOM ? 3 * sem : 0), "%s %s k=%u: mean %+.3f%%", LAYOUT[layout],
                           pm_estimator_name(o.kind), ks[i], 100 * m);
            }
        }
        free_square(&sq);
    }
    /* The normalisations themselves: closed forms against a midpoint-rule integral of the
     * weight over the unit disc (2 s ds in s = d/r), to 1e-6. */
    double cone = 0, gauss = 0;
    const int steps = 200000;
    for (int i = 0; i < steps; i++) {
        double s = (i + 0.5) / steps;
        cone += (1 - s) * 2 * s / steps;
        gauss += PM_GAUSS_ALPHA * (1 - (1 - exp(-PM_GAUSS_BETA * s * s / 2)) / (1 - exp(-PM_GAUSS_BETA))) * 2 * s / steps;
    }
    EXPECT_NEAR(pm_cone_norm(1.0), cone, 1e-6);
    EXPECT_NEAR(pm_gauss_norm(), gauss, 1e-6);
}

/* Oracle: the analytic irradiance. Differential checking (default parameters) must (a) leave
 * the interior mean within 1% on stratified photons and within 1% of the corrected disc's
 * derived random-photon bias (+0.5/(k - 1)) plus 3 SEM on random ones (it sometimes stops
 * early on noise, which random photons have more of), and (b) for lookups 0.01 to 0.02 from
 * an edge, where the 100-photon disc crosses it, be at least 5 points less dark than the plain
 * disc there and use fewer photons than in the interior (under 80% of them on stratified
 * photons; on random ones the interior already stops early on noise). */
TEST(estimate_square_differential) {
    for (int layout = 0; layout < 2; layout++) {
        square sq;
        make_square(&sq, 5, layout);
        pm_estimate_options o;
        pm_estimate_options_init(&o, PM_EST_DIFFERENTIAL, 100);
        run_out in = run_square(&sq, &o, lookups_for_layout(100, layout), draw_interior, 500);
        run_out ed = run_square(&sq, &o, lookups_for_layout(100, layout), draw_near_edge, 501);
        o.kind = PM_EST_DISC;
        run_out disc = run_square(&sq, &o, lookups_for_layout(100, layout), draw_near_edge, 501);
        printf("%s, differential k=100: interior %+.3f%% (mean photons %.1f), edge %+.2f%% (mean photons %.1f), disc at edge %+.2f%%\n",
               LAYOUT[layout], 100 * st_mean(&in.rel), st_mean(&in.used), 100 * st_mean(&ed.rel), st_mean(&ed.used),
               100 * st_mean(&disc.rel));
        double want = layout == RANDOM ? 0.5 / 99 : 0.0, slack = layout == RANDOM ? 3 * st_sem(&in.rel) : 0.0;
        EXPECT_MSG(fabs(st_mean(&in.rel) - want) <= 0.01 + slack, "%s: interior mean %+.3f%%", LAYOUT[layout], 100 * st_mean(&in.rel));
        EXPECT(st_mean(&ed.used) < (layout == STRATIFIED ? 0.8 : 1.0) * st_mean(&in.used));
        EXPECT(st_mean(&ed.rel) > st_mean(&disc.rel) + 0.05);
        free_square(&sq);
    }
}

/* ---- degenerate inputs ---------------------------------------------------------------- */

/* Photons placed by hand; nb lists all of them with exact dist2 to x. */
static unsigned hand_list(const pm_photon *ph, unsigned n, const float x[3], pm_neighbor *nb) {
    for (unsigned i = 0; i < n; i++) nb[i].index = i, nb[i].dist2 = dist2f(ph[i].pos, x);
    return n;
}

/* Degenerate neighbour lists every estimator must survive (estimate.h, GUARANTEES). Each
 * fills ph (N photons at most) and may move x. */
enum { DG_NONE, DG_ONE, DG_TWO, DG_AT_X, DG_COLLINEAR, DG_NEAR_COLLINEAR, DG_ZERO_POWER,
       DG_POWER_RANGE, DG_FAR };
#define DG_N 40
static unsigned degenerate_scene(int kase, pm_photon *ph, float q[3]) {
    const float one[3] = {1, 1, 1}, zero[3] = {0, 0, 0};
    q[0] = 0.5f, q[1] = 0.5f, q[2] = 0;
    switch (kase) {
    case DG_NONE: return 0;
    case DG_ONE:
        pm_photon_init(&ph[0], (float[3]){0.6f, 0.5f, 0}, one, DOWN, UP, 0);
        return 1;
    case DG_TWO:
        pm_photon_init(&ph[0], (float[3]){0.6f, 0.5f, 0}, one, DOWN, UP, 0);
        pm_photon_init(&ph[1], (float[3]){0.5f, 0.4f, 0}, one, DOWN, UP, 0);
        return 2;
    case DG_AT_X:
        for (int i = 0; i < DG_N; i++) pm_photon_init(&ph[i], q, one, DOWN, UP, 0);
        return DG_N;
    case DG_COLLINEAR:
        for (int i = 0; i < DG_N; i++)
            pm_photon_init(&ph[i], (float[3]){0.5f + 0.01f * (i - DG_N / 2), 0.5f + 0.02f * (i - DG_N / 2), 0}, one, DOWN, UP, 0);
        return DG_N;
    case DG_NEAR_COLLINEAR: /* 0.4 long, 2e-7 wide */
        for (int i = 0; i < DG_N; i++)
            pm_photon_init(&ph[i], (float[3]){0.5f + 0.01f * (i - DG_N / 2), 0.5f + 1e-7f * (float)(i % 3), 0}, one, DOWN, UP, 0);
        return DG_N;
    default: break;
    }
    for (int i = 0; i < DG_N; i++) {
        float pos[3] = {0.5f + 0.01f * (i % 7), 0.5f + 0.013f * (i / 7), 0};
        float p = kase == DG_ZERO_POWER ? 0.0f : kase == DG_POWER_RANGE ? (float)pow(10.0, -30.0 + 60.0 * i / (DG_N - 1)) : 1.0f;
        pm_photon_init(&ph[i], pos, kase == DG_ZERO_POWER ? zero : (float[3]){p, p, p}, DOWN, UP, 0);
    }
    if (kase == DG_FAR) q[0] = 3e37f, q[1] = -3e37f;
    return DG_N;
}

static void check_finite(const pm_estimate_result *r, const char *what, const char *kind) {
    for (int c = 0; c < 3; c++)
        EXPECT_MSG(isfinite(r->rgb[c]) && r->rgb[c] >= 0.0, "%s, %s: rgb[%d] = %g", what, kind, c, r->rgb[c]);
    EXPECT_MSG(isfinite(r->area) && r->area >= 0.0, "%s, %s: area %g", what, kind, r->area);
}

/* Runs every estimator (5 kinds x 3 bias rules, the volume estimate and combined maps) on one
 * case, through the core on the exact list and through the wrappers on a kd-tree. */
static void degenerate_case(int kase, const char *what) {
    pm_photon ph[DG_N], tph[DG_N];
    pm_neighbor nb[DG_N];
    float q[3];
    void *scratch = malloc(pm_estimate_scratch_bytes(DG_N));
    unsigned n = degenerate_scene(kase, ph, q);
    hand_list(ph, n, q, nb);
    memcpy(tph, ph, sizeof ph);
    pm_kdtree *tree = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(1);
    EXPECT_EQ_INT(pm_kdtree_build(&tree, tph, n, &cfg, NULL), PM_OK);
    for (int kind = 0; kind < PM_EST_COUNT_; kind++) {
        for (int bias = 0; bias < 3; bias++) {
            pm_estimate_options o;
            pm_estimate_result r, d, w;
            pm_estimate_options_init(&o, (pm_estimator)kind, DG_N);
            o.bias = bias;
            EXPECT_EQ_INT(pm_estimate_core(ph, nb, n, q, UP, &o, scratch, &r), PM_OK);
            check_finite(&r, what, pm_estimator_name(o.kind));
            if (tree) {
                o.reject_behind = 1;
                EXPECT_EQ_INT(pm_estimate(tree, q, UP, &o, scratch, &w, NULL), PM_OK);
                check_finite(&w, what, "wrapper");
                o.reject_behind = 0;
            }
            if (kase == DG_NONE || kase == DG_ZERO_POWER) EXPECT(r.rgb[0] == 0.0 && r.rgb[1] == 0.0);
            if (kase == DG_FAR) EXPECT_MSG(r.rgb[0] < 1e-60, "far: %g", r.rgb[0]);
            if (kase == DG_AT_X || kase == DG_POWER_RANGE) EXPECT(r.rgb[0] > 0.0); /* finite, not 0 */
            if (kind == PM_EST_HULL && kase >= DG_ONE && kase <= DG_NEAR_COLLINEAR) {
                EXPECT_MSG(r.flags & PM_EST_F_HULL_FALLBACK, "%s: hull must fall back", what);
                o.kind = PM_EST_DISC;
                pm_estimate_core(ph, nb, n, q, UP, &o, scratch, &d);
                EXPECT_REL(r.rgb[0], d.rgb[0], 1e-15);
            }
        }
    }
    pm_estimate_options o;
    pm_estimate_result r;
    pm_estimate_options_init(&o, PM_EST_DISC, DG_N);
    EXPECT_EQ_INT(pm_estimate_volume_core(ph, nb, n, q, 0.5, &o, &r), PM_OK);
    check_finite(&r, what, "volume");
    if (tree) {
        EXPECT_EQ_INT(pm_estimate_volume(tree, q, 0.5, &o, scratch, &r, NULL), PM_OK);
        check_finite(&r, what, "volume wrapper");
    }
    /* combined maps: the case's photons as each of two maps */
    pm_combine_acc acc;
    double c[3], nv[3];
    pm_combine_init(&acc);
    for (int m = 0; m < 2; m++) EXPECT_EQ_INT(pm_combine_add(&acc, ph, nb, n, DG_N, INFINITY, PM_BIAS_AREA, q), PM_OK);
    pm_combine_finish(&acc, c, nv);
    for (int i = 0; i < 3; i++)
        EXPECT_MSG(isfinite(c[i]) && c[i] >= 0 && isfinite(nv[i]) && nv[i] >= 0, "%s: combined %g naive %g", what, c[i], nv[i]);
    pm_kdtree_free(tree);
    free(scratch);
}

/* Oracle, for each of the tests below: the guarantee of estimate.h (PM_OK; finite,
 * non-negative rgb and area) for every estimator, bias rule, wrapper, the volume estimate and
 * combined maps; plus the values known exactly: no photons and zero power give 0; x far away
 * gives 0 or a value below 1e-60; photons at x and powers 1e-30..1e30 give a positive value;
 * the hull on 1 or 2 photons, duplicates, collinear or nearly collinear photons falls back to
 * the disc (flag set) and equals it. */
TEST(estimate_degenerate_no_photons) { degenerate_case(DG_NONE, "no photons"); }
TEST(estimate_degenerate_one_photon) { degenerate_case(DG_ONE, "one photon"); }
TEST(estimate_degenerate_two_photons) { degenerate_case(DG_TWO, "two photons"); }
TEST(estimate_degenerate_all_at_x) { degenerate_case(DG_AT_X, "all at x (r = 0)"); }
TEST(estimate_degenerate_collinear) { degenerate_case(DG_COLLINEAR, "collinear"); }
TEST(estimate_degenerate_nearly_collinear) { degenerate_case(DG_NEAR_COLLINEAR, "nearly collinear"); }
TEST(estimate_degenerate_zero_power) { degenerate_case(DG_ZERO_POWER, "zero power"); }
TEST(estimate_degenerate_power_range) { degenerate_case(DG_POWER_RANGE, "powers 1e-30..1e30"); }
TEST(estimate_degenerate_far_outside) { degenerate_case(DG_FAR, "x far outside the map"); }

/* Oracle: the hand-computed values. The disc radius rule: 4 photons of power 1 at distance
 * 0.1..0.4 with k = 4 give E = 4 / (pi 0.16) uncorrected, times 3.5/4 with either correction;
 * with k = 8 and max_dist2 = 0.25 (ran dry) the area is pi 0.25, uncorrected. Photons at x
 * (r = 0) give power / (pi floor^2) with the documented floor. */
TEST(estimate_disc_radius_rule_exact) {
    pm_photon ph[4];
    pm_neighbor nb[4];
    const float x[3] = {0, 0, 0}, one[3] = {1, 1, 1};
    for (int i = 0; i < 4; i++) pm_photon_init(&ph[i], (float[3]){0.1f * (i + 1), 0, 0}, one, DOWN, UP, 0);
    hand_list(ph, 4, x, nb);
    pm_estimate_options o;
    pm_estimate_result r;
    pm_estimate_options_init(&o, PM_EST_DISC, 4);
    const double pi = 3.14159265358979323846, r2 = (double)(0.4f * 0.4f);
    for (int bias = 0; bias < 3; bias++) {
        o.bias = bias;
        ASSERT_EQ_INT(pm_estimate_core(ph, nb, 4, x, UP, &o, NULL, &r), PM_OK);
        EXPECT_REL(r.rgb[0], 4.0 / (pi * r2) * (bias ? 3.5 / 4 : 1.0), 1e-6);
    }
    o.k = 8, o.max_dist2 = 0.25f, o.bias = PM_BIAS_AREA;
    ASSERT_EQ_INT(pm_estimate_core(ph, nb, 4, x, UP, &o, NULL, &r), PM_OK);
    EXPECT_REL(r.rgb[0], 4.0 / (pi * 0.25), 1e-6);
    EXPECT(r.flags & PM_EST_F_RADIUS_LIMIT);
    /* All at x: the floor (2^-20 * max(1, |x|))^2 = 2^-40. */
    for (int i = 0; i < 4; i++) pm_photon_init(&ph[i], x, one, DOWN, UP, 0);
    hand_list(ph, 4, x, nb);
    o.k = 4, o.max_dist2 = INFINITY, o.bias = PM_BIAS_NONE;
    ASSERT_EQ_INT(pm_estimate_core(ph, nb, 4, x, UP, &o, NULL, &r), PM_OK);
    EXPECT_REL(r.rgb[0], 4.0 / (pi * 0x1p-40), 1e-12);
    EXPECT(r.flags & PM_EST_F_RADIUS_FLOOR);
}

/* Brute-force hull oracle for points in general position: p -> q is a counter-clockwise hull
 * edge iff every other point lies strictly to its left. Returns the area; marks vertices. */
static double brute_hull(const double (*p)[2], int n, int *vertex) {
    double area = 0;
    for (int i = 0; i < n; i++) vertex[i] = 0;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            if (i == j) continue;
            int ok = 1;
            for (int m = 0; m < n && ok; m++) {
                if (m == i || m == j) continue;
                double c = (p[j][0] - p[i][0]) * (p[m][1] - p[i][1]) - (p[j][1] - p[i][1]) * (p[m][0] - p[i][0]);
                if (!(c > 0)) ok = 0;
            }
            if (ok) {
                area += 0.5 * (p[i][0] * p[j][1] - p[j][0] * p[i][1]);
                vertex[i] = vertex[j] = 1;
            }
        }
    return area;
}

/* Oracle: the brute-force hull above. For random point sets of 3 to 150 points (enough that
 * the Akl-Toussaint prefilter sets most aside) in a tilted plane (so the projection matters),
 * half of them uniform in a square and half in a disc, the hull estimate equals (interior power + 0.2 * vertex power) / area
 * with area and vertices from the oracle, to 1e-5 relative (float positions). */
TEST(estimate_hull_matches_brute_force) {
    enum { N = 150 };
    rng_t r = {7};
    pm_photon ph[N];
    pm_neighbor nb[N];
    double uv[N][2];
    int vertex[N];
    void *scratch = malloc(pm_estimate_scratch_bytes(N));
    /* Plane through x with normal n; tangent axes t, b. */
    const double nn[3] = {0, 0.6, 0.8}, t[3] = {1, 0, 0}, b[3] = {0, 0.8, -0.6};
    const float n[3] = {0, 0.6f, 0.8f}, x[3] = {1, 2, 3};
    for (int trial = 0; trial < 50; trial++) {
        int cnt = 3 + (int)(rng_u64(&r) % (N - 2));
        double inner = 0, outer = 0;
        for (int i = 0; i < cnt; i++) {
            double u = rng_unit(&r) * 2 - 1, v = rng_unit(&r) * 2 - 1, h = (rng_unit(&r) - 0.5) * 0.01;
            if ((trial & 1) && u * u + v * v > 1) { i--; continue; } /* rejection: uniform in the disc */
            float pos[3], pw = (float)(0.5 + rng_unit(&r));
            for (int c = 0; c < 3; c++) pos[c] = (float)(x[c] + u * t[c] + v * b[c] + h * nn[c]);
            pm_photon_init(&ph[i], pos, (float[3]){pw, pw, pw}, DOWN, n, 0);
            for (int c = 0; c < 2; c++) {
                const double *ax = c ? b : t;
                uv[i][c] = ((double)pos[0] - x[0]) * ax[0] + ((double)pos[1] - x[1]) * ax[1] + ((double)pos[2] - x[2]) * ax[2];
            }
        }
        double area = brute_hull(uv, cnt, vertex);
        for (int i = 0; i < cnt; i++) {
            float dec[3];
            pm_rgbe_decode(ph[i].power, dec);
            if (vertex[i]) outer += dec[0]; else inner += dec[0];
        }
        hand_list(ph, (unsigned)cnt, x, nb);
        pm_estimate_options o;
        pm_estimate_result res;
        pm_estimate_options_init(&o, PM_EST_HULL, (unsigned)cnt);
        ASSERT_EQ_INT(pm_estimate_core(ph, nb, (unsigned)cnt, x, n, &o, scratch, &res), PM_OK);
        if (res.flags & PM_EST_F_HULL_FALLBACK) {
            /* only allowed for a sliver: area below the documented fraction */
            EXPECT_MSG(area < 2e-3 * 3.14159 * 2, "trial %d: unexpected fallback, area %g", trial, area);
            continue;
        }
        EXPECT_REL(res.area, area, 1e-5);
        EXPECT_REL(res.rgb[0], (inner + 0.2 * outer) / area, 1e-5);
    }
    free(scratch);
}

/* Oracle: exact geometry. A square's corners plus its centre repeated, with duplicates of a
 * corner and points on the edges (collinear with two vertices): the hull is the square (area
 * 4), and its 4 corner vertices (not the duplicates, not the edge points) count at 20%. */
TEST(estimate_hull_duplicates_and_edge_points) {
    pm_photon ph[12];
    pm_neighbor nb[12];
    const float x[3] = {0, 0, 0}, one[3] = {1, 1, 1};
    const float pts[12][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}, {-1, -1}, {-1, -1},
                              {0, -1}, {1, 0}, {0, 0}, {0, 0}, {0.5f, 0.5f}, {-1, 0.25f}};
    void *scratch = malloc(pm_estimate_scratch_bytes(12));
    for (int i = 0; i < 12; i++) pm_photon_init(&ph[i], (float[3]){pts[i][0], pts[i][1], 0}, one, DOWN, UP, 0);
    hand_list(ph, 12, x, nb);
    pm_estimate_options o;
    pm_estimate_result r;
    pm_estimate_options_init(&o, PM_EST_HULL, 12);
    ASSERT_EQ_INT(pm_estimate_core(ph, nb, 12, x, UP, &o, scratch, &r), PM_OK);
    EXPECT(!(r.flags & PM_EST_F_HULL_FALLBACK));
    EXPECT_REL(r.area, 4.0, 1e-12);
    EXPECT_REL(r.rgb[0], (8 + 0.2 * 4) / 4.0, 1e-12);
    free(scratch);
}

/* Oracle: Poisson statistics. For photons uniform at random in a cube, the k-th nearest
 * neighbour's ball volume V_k satisfies E[1/V_k] = rho/(k-1), so the uncorrected volume
 * estimate k P/(sigma 4 pi V_k) has mean k/(k-1) times the truth rho P/(4 pi sigma). Asserted
 * to within 4 standard errors of the mean (about 1%). */
TEST(estimate_volume_poisson) {
    enum { N = 20000, K = 40 };
    const unsigned lookups = PM_TEST_SANITIZED ? 800 : 3000;
    rng_t r = {11};
    pm_photon *ph = malloc(sizeof *ph * N);
    pm_neighbor *all = malloc(sizeof *all * N);
    const float pw[3] = {0x1p-10f, 0x1p-10f, 0x1p-10f};
    for (int i = 0; i < N; i++) {
        float pos[3] = {(float)rng_unit(&r), (float)rng_unit(&r), (float)rng_unit(&r)};
        pm_photon_init(&ph[i], pos, pw, DOWN, UP, 0);
    }
    const double sigma = 0.7, truth = N * 0x1p-10 / (4 * 3.14159265358979323846 * sigma);
    stats s = {0, 0, 0};
    for (unsigned l = 0; l < lookups; l++) {
        float q[3] = {(float)(0.2 + 0.6 * rng_unit(&r)), (float)(0.2 + 0.6 * rng_unit(&r)), (float)(0.2 + 0.6 * rng_unit(&r))};
        hand_list(ph, N, q, all);
        /* the K nearest: keep K candidates and replace the farthest when a closer one comes */
        pm_neighbor best[K];
        int mx = 0;
        memcpy(best, all, sizeof best);
        for (int j = 1; j < K; j++) if (best[j].dist2 > best[mx].dist2) mx = j;
        for (int i = K; i < N; i++) {
            if (!(all[i].dist2 < best[mx].dist2)) continue;
            best[mx] = all[i];
            for (int j = 0; j < K; j++) if (best[j].dist2 > best[mx].dist2) mx = j;
        }
        pm_estimate_options o;
        pm_estimate_result res;
        pm_estimate_options_init(&o, PM_EST_DISC, K);
        o.bias = PM_BIAS_NONE;
        ASSERT_EQ_INT(pm_estimate_volume_core(ph, best, K, q, sigma, &o, &res), PM_OK);
        st_add(&s, res.rgb[0] / truth * (K - 1.0) / K - 1.0);
    }
    printf("volume k=%d: mean %+.3f%% sem %.3f%%\n", K, 100 * st_mean(&s), 100 * st_sem(&s));
    EXPECT_MSG(fabs(st_mean(&s)) <= 4 * st_sem(&s), "volume mean %+.3f%% (sem %.3f%%)", 100 * st_mean(&s), 100 * st_sem(&s));
    EXPECT(st_sem(&s) < 0.01);
    free(ph), free(all);
}

/* Oracle: the definitions. k photons of power p_max inside radius r_m give, with a white
 * diffuse BRDF (1/pi), exactly L_t: (1/pi) k p / (pi r^2) = L_t; in a volume with phase
 * 1/(4 pi): k p / (4 pi sigma 4/3 pi r^3) = L_t. Bad thresholds mean no limit. */
TEST(estimate_auto_radius) {
    const double pi = 3.14159265358979323846;
    double r = pm_auto_radius_surface(50, 0.01, 2.0);
    EXPECT_REL(50 * 0.01 / (pi * pi * r * r), 2.0, 1e-12);
    r = pm_auto_radius_volume(50, 0.01, 0.3, 2.0);
    EXPECT_REL(50 * 0.01 / (4 * pi * 0.3 * 4.0 / 3.0 * pi * r * r * r), 2.0, 1e-12);
    EXPECT(isinf(pm_auto_radius_surface(50, 1, 0)));
    EXPECT(isinf(pm_auto_radius_volume(50, 1, 0.3, NAN)));
    EXPECT(pm_auto_radius_surface(50, 0, 1) == 0.0);
    pm_photon ph[3];
    const float pw[3][3] = {{1, 2, 3}, {0.5f, 8, 0.25f}, {0, 0, 0}};
    for (int i = 0; i < 3; i++) pm_photon_init(&ph[i], (float[3]){0, 0, 0}, pw[i], DOWN, UP, 0);
    EXPECT_REL(pm_photons_max_power(ph, 3), 8.0, 1e-2); /* RGBE keeps 8 within 2^-8 */
    EXPECT(pm_photons_max_power(ph, 0) == 0.0);
}

/* The callback receives wi = minus the photon's travel direction, within the direction
 * quantization (about 0.7 degrees: |wi - expected| < 0.02), for each photon. */
static void brdf_check(void *user, const float wi[3], float f[3]) {
    const float *want = user;
    float d = fabsf(wi[0] - want[0]) + fabsf(wi[1] - want[1]) + fabsf(wi[2] - want[2]);
    f[0] = d < 0.02f ? 0.25f : 100.0f;
    f[1] = -1.0f; /* a negative BRDF value must be clamped to 0 */
    f[2] = NAN;   /* and a NaN too */
}

/* Oracle: a constant BRDF f scales the irradiance by f; a diffuse albedo rho by rho/pi. */
TEST(estimate_brdf_callback_and_diffuse) {
    enum { N = 16 };
    pm_photon ph[N];
    pm_neighbor nb[N];
    const float x[3] = {0, 0, 0}, one[3] = {1, 1, 1};
    float dir[3] = {0.3f, -0.4f, -0.866f}, want[3];
    float len = sqrtf(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    for (int c = 0; c < 3; c++) want[c] = -dir[c] / len;
    for (int i = 0; i < N; i++) pm_photon_init(&ph[i], (float[3]){0.1f * (i % 4), 0.1f * (i / 4), 0}, one, dir, UP, 0);
    hand_list(ph, N, x, nb);
    pm_estimate_options o;
    pm_estimate_result e, l;
    pm_estimate_options_init(&o, PM_EST_DISC, N);
    ASSERT_EQ_INT(pm_estimate_core(ph, nb, N, x, UP, &o, NULL, &e), PM_OK);
    o.brdf = brdf_check, o.brdf_user = want;
    ASSERT_EQ_INT(pm_estimate_core(ph, nb, N, x, UP, &o, NULL, &l), PM_OK);
    EXPECT_REL(l.rgb[0], 0.25 * e.rgb[0], 1e-12);
    EXPECT(l.rgb[1] == 0.0 && l.rgb[2] == 0.0);
    const float rho[3] = {0.5f, 0.25f, 1.0f};
    o.brdf = NULL, o.diffuse = rho;
    ASSERT_EQ_INT(pm_estimate_core(ph, nb, N, x, UP, &o, NULL, &l), PM_OK);
    for (int c = 0; c < 3; c++) EXPECT_REL(l.rgb[c], rho[c] / 3.14159265358979323846 * e.rgb[c], 1e-12);
}

/* Oracle: the documented argument checks. */
TEST(estimate_bad_arguments) {
    pm_photon ph[1];
    pm_neighbor nb[1] = {{0, 0}};
    pm_estimate_options o;
    pm_estimate_result r;
    float x[3] = {0, 0, 0};
    pm_photon_init(&ph[0], x, (float[3]){1, 1, 1}, DOWN, UP, 0);
    pm_estimate_options_init(&o, PM_EST_DISC, 0);
    EXPECT_EQ_INT(pm_estimate_core(ph, nb, 1, x, UP, &o, NULL, &r), PM_EINVAL);
    pm_estimate_options_init(&o, PM_EST_CONE, 4);
    o.cone_k = 0.5;
    EXPECT_EQ_INT(pm_estimate_core(ph, nb, 1, x, UP, &o, NULL, &r), PM_EINVAL);
    pm_estimate_options_init(&o, PM_EST_HULL, 4);
    EXPECT_EQ_INT(pm_estimate_core(ph, nb, 1, x, UP, &o, NULL, &r), PM_EINVAL); /* no scratch */
    float bad[3] = {NAN, 0, 0};
    pm_estimate_options_init(&o, PM_EST_DISC, 4);
    EXPECT_EQ_INT(pm_estimate_core(ph, nb, 1, bad, UP, &o, NULL, &r), PM_ENONFINITE);
    EXPECT(r.rgb[0] == 0.0);
    EXPECT_EQ_INT(pm_estimate_volume_core(ph, nb, 1, x, 0.0, &o, &r), PM_EINVAL);
    o.k = 1;
    EXPECT_EQ_INT(pm_estimate_core(ph, nb, 2, x, UP, &o, NULL, &r), PM_EINVAL); /* count > k */
    EXPECT_EQ_INT(pm_estimate_core(ph, nb, 1, x, UP, &o, NULL, &r), PM_OK);
    EXPECT(strcmp(pm_estimator_name(PM_EST_HULL), "hull") == 0);
}

/* ---- wrappers over a real kd-tree ------------------------------------------------------ */

/* Oracle: the core on the brute-force list. pm_estimate() on a kd-tree of the square returns,
 * for every estimator, the same value as the core on the oracle's neighbours (the same
 * multiset of photons; dist2 may round differently in the tree: 1e-6 relative). */
TEST(estimate_wrapper_matches_core) {
    square sq;
    make_square(&sq, 6, STRATIFIED);
    pm_photon *tree_ph = malloc(sizeof *tree_ph * SIDE * SIDE);
    memcpy(tree_ph, sq.ph, sizeof *tree_ph * SIDE * SIDE);
    pm_kdtree *tree = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(1);
    ASSERT_EQ_INT(pm_kdtree_build(&tree, tree_ph, SIDE * SIDE, &cfg, NULL), PM_OK);
    rng_t r = {60};
    pm_neighbor nb[100], *cand = malloc(sizeof *cand * SIDE * SIDE);
    void *scratch = malloc(pm_estimate_scratch_bytes(100));
    void *scratch2 = malloc(pm_estimate_scratch_bytes(100));
    for (int l = 0; l < 200; l++) {
        float q[3];
        if (l & 1) draw_interior(&r, q); else draw_edge(&r, q);
        for (int kind = 0; kind < PM_EST_COUNT_; kind++) {
            pm_estimate_options o;
            pm_estimate_result a, b;
            pm_estimate_options_init(&o, (pm_estimator)kind, 10 + (unsigned)(l % 90));
            if (l % 5 == 0) o.max_dist2 = 4e-5f; /* some searches run dry inside the radius */
            unsigned n = square_knn(&sq, q, o.k, nb, cand);
            while (n > 0 && !(nb[n - 1].dist2 < o.max_dist2)) n--;
            ASSERT_EQ_INT(pm_estimate_core(sq.ph, nb, n, q, UP, &o, scratch2, &a), PM_OK);
            ASSERT_EQ_INT(pm_estimate(tree, q, UP, &o, scratch, &b, NULL), PM_OK);
            EXPECT_EQ_INT(a.found, b.found);
            EXPECT_REL(b.rgb[0], a.rgb[0], 1e-6);
        }
    }
    pm_kdtree_free(tree);
    free(tree_ph), free(cand), free(scratch), free(scratch2), free_square(&sq);
}

/* Oracle: the geometry of a thin wall. Photons at z = +0.001 arrive from above (front), and
 * at z = -0.001 from below (the other side of the wall). Estimated at z = 0 with normal +z:
 *   - plain search: both layers, about twice the truth;
 *   - reject_behind: only the front layer, within 10% of the truth (k = 50);
 * and a layer at z = +0.05 (a parallel surface above) leaks into a plain search but not into
 * the disc-shaped search (squash = 1000), which gives the truth within 10% again. */
TEST(estimate_leak_control) {
    enum { S = 60 };
    rng_t r = {13};
    pm_photon *ph = malloc(sizeof *ph * 2 * S * S);
    const float pw[3] = {0x1p-12f, 0x1p-12f, 0x1p-12f};
    for (int layer = 0; layer < 2; layer++)
        for (int i = 0; i < S * S; i++) {
            float pos[3] = {(float)((i / S + rng_unit(&r)) / S), (float)((i % S + rng_unit(&r)) / S),
                            layer ? -0.001f : 0.001f};
            pm_photon_init(&ph[layer * S * S + i], pos, pw, layer ? UP : DOWN, layer ? DOWN : UP, 0);
        }
    const double truth = S * S * 0x1p-12;
    pm_kdtree *tree = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(1);
    ASSERT_EQ_INT(pm_kdtree_build(&tree, ph, 2 * S * S, &cfg, NULL), PM_OK);
    void *scratch = malloc(pm_estimate_scratch_bytes(50));
    const float q[3] = {0.5f, 0.5f, 0};
    pm_estimate_options o;
    pm_estimate_result res;
    pm_estimate_options_init(&o, PM_EST_DISC, 50);
    ASSERT_EQ_INT(pm_estimate(tree, q, UP, &o, scratch, &res, NULL), PM_OK);
    EXPECT_REL(res.rgb[0], 2 * truth, 0.15);
    o.reject_behind = 1;
    ASSERT_EQ_INT(pm_estimate(tree, q, UP, &o, scratch, &res, NULL), PM_OK);
    EXPECT_REL(res.rgb[0], truth, 0.10);
    pm_kdtree_free(tree);
    /* Second scene: the front layer and a parallel surface 0.05 above. (The build reordered
     * ph, so the layers are made again from the same random stream.) */
    r.s = 13;
    for (int layer = 0; layer < 2; layer++)
        for (int i = 0; i < S * S; i++) {
            float pos[3] = {(float)((i / S + rng_unit(&r)) / S), (float)((i % S + rng_unit(&r)) / S),
                            layer ? 0.05f : 0.001f};
            pm_photon_init(&ph[layer * S * S + i], pos, pw, DOWN, UP, 0);
        }
    ASSERT_EQ_INT(pm_kdtree_build(&tree, ph, 2 * S * S, &cfg, NULL), PM_OK);
    const float q2[3] = {0.5f, 0.5f, 0.001f}; /* on the front layer, so the squash adds nothing */
    pm_estimate_options_init(&o, PM_EST_DISC, 200);
    void *scratch2 = malloc(pm_estimate_scratch_bytes(200));
    ASSERT_EQ_INT(pm_estimate(tree, q2, UP, &o, scratch2, &res, NULL), PM_OK);
    EXPECT_MSG(res.rgb[0] > 1.2 * truth, "plain search should leak: %g vs %g", res.rgb[0], truth);
    o.squash = 1000.0f;
    ASSERT_EQ_INT(pm_estimate(tree, q2, UP, &o, scratch2, &res, NULL), PM_OK);
    EXPECT_REL(res.rgb[0], truth, 0.10);
    pm_kdtree_free(tree);
    free(ph), free(scratch), free(scratch2);
}

/* Oracle: the same calls made serially. Estimates are reentrant: with one scratch buffer per
 * thread, lookups run in parallel (OpenMP, when the build has it) give bit-identical results
 * for every estimator. */
TEST(estimate_parallel_matches_serial) {
#ifdef _OPENMP
    int team = 0;
#pragma omp parallel num_threads(2)
    {
#pragma omp single
        team = omp_get_num_threads();
    }
    ASSERT_MSG(team == 2, "OpenMP gave %d threads, not 2: the comparison would not test anything", team);
#endif
    square sq;
    make_square(&sq, 8, RANDOM);
    pm_kdtree *tree = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(4);
    ASSERT_EQ_INT(pm_kdtree_build(&tree, sq.ph, SIDE * SIDE, &cfg, NULL), PM_OK);
    enum { Q = 2000 };
    float (*qs)[3] = malloc(sizeof *qs * Q);
    double *serial = malloc(sizeof *serial * Q * PM_EST_COUNT_), *par = malloc(sizeof *par * Q * PM_EST_COUNT_);
    rng_t r = {80};
    for (int i = 0; i < Q; i++) draw_interior(&r, qs[i]);
    for (int pass = 0; pass < 2; pass++) {
        double *res = pass ? par : serial;
        int bad = 0;
#ifdef _OPENMP
#pragma omp parallel for num_threads(2) schedule(dynamic, 16) reduction(+ : bad) if (pass)
#endif
        for (int i = 0; i < Q; i++) {
            void *scratch = malloc(pm_estimate_scratch_bytes(60));
            for (int kind = 0; kind < PM_EST_COUNT_; kind++) {
                pm_estimate_options o;
                pm_estimate_result e;
                pm_estimate_options_init(&o, (pm_estimator)kind, 60);
                o.reject_behind = 1;
                bad += pm_estimate(tree, qs[i], UP, &o, scratch, &e, NULL) != PM_OK;
                res[i * PM_EST_COUNT_ + kind] = e.rgb[0];
            }
            free(scratch);
        }
        EXPECT_EQ_INT(bad, 0);
    }
    EXPECT(memcmp(serial, par, sizeof *par * Q * PM_EST_COUNT_) == 0);
    pm_kdtree_free(tree);
    free(qs), free(serial), free(par), free_square(&sq);
#ifndef _OPENMP
    /* OPENMP=0: the "parallel" pass was the serial loop again, so the comparison could not
     * fail. */
    SKIP("built without OpenMP (OPENMP=0): the parallel lookups are the serial ones here");
#endif
}

/* Oracle: the disc estimate's own flag. For every estimator, PM_EST_F_FAR is set, and the
 * estimate is exactly 0, exactly when the disc sets it on the same neighbour list. Lists: 12
 * photons spread over 1e-3 or 0.5 times their distance from the origin, around points at
 * 1e19..1e20, with x at the opposite 1e19..1e20 (some or all float dist2 overflow), or with x
 * near the photons (none do). Before the hull checked
 * it, the hull returned a finite value from the (arbitrary) photons of an all-infinite list. */
TEST(estimate_far_flag_agrees_with_the_disc) {
    enum { NP = 12 };
    pm_photon ph[NP];
    pm_neighbor nb[NP];
    rng_t r = {404};
    void *scratch = malloc(pm_estimate_scratch_bytes(NP));
    unsigned far_cases = 0, near_cases = 0;
    for (int trial = 0; trial < 300; trial++) {
        double scale = trial % 3 == 2 ? 1.0 : pow(10.0, 19 + rng_unit(&r));
        float c[3] = {(float)scale, (float)(scale * rng_unit(&r)), (float)(0.5 * scale * rng_unit(&r))};
        float x[3];
        for (int a = 0; a < 3; a++) x[a] = trial % 3 == 2 ? c[a] + 0.01f : -c[a] * (float)(0.5 + rng_unit(&r));
        float spread = trial % 2 ? 1e-3f : 0.5f;
        for (int i = 0; i < NP; i++) {
            float pos[3] = {c[0] * (1 + spread * (float)rng_unit(&r)), c[1] + spread * (float)rng_unit(&r) * c[0],
                            c[2] + spread * (float)rng_unit(&r) * c[0]};
            pm_photon_init(&ph[i], pos, (float[3]){1, 1, 1}, DOWN, UP, 0);
            float d[3] = {pos[0] - x[0], pos[1] - x[1], pos[2] - x[2]};
            nb[i].index = (uint32_t)i, nb[i].dist2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
        }
        pm_estimate_options o;
        pm_estimate_result disc, res;
        pm_estimate_options_init(&o, PM_EST_DISC, NP);
        ASSERT_EQ_INT(pm_estimate_core(ph, nb, NP, x, UP, &o, scratch, &disc), PM_OK);
        int far = (disc.flags & PM_EST_F_FAR) != 0;
        far_cases += (unsigned)far, near_cases += (unsigned)!far;
        for (int kind = 0; kind < PM_EST_COUNT_; kind++) {
            pm_estimate_options_init(&o, (pm_estimator)kind, NP);
            ASSERT_EQ_INT(pm_estimate_core(ph, nb, NP, x, UP, &o, scratch, &res), PM_OK);
            int f = (res.flags & PM_EST_F_FAR) != 0;
            EXPECT_MSG(f == far, "trial %d, %s: FAR %d, disc %d", trial, pm_estimator_name((pm_estimator)kind), f, far);
            if (far) EXPECT_MSG(res.rgb[0] == 0 && res.rgb[1] == 0 && res.rgb[2] == 0, "trial %d, %s: %g with FAR", trial,
                                pm_estimator_name((pm_estimator)kind), res.rgb[0]);
            else EXPECT_MSG(res.rgb[0] > 0, "trial %d, %s: 0 without FAR", trial, pm_estimator_name((pm_estimator)kind));
        }
    }
    EXPECT(far_cases >= 100 && near_cases >= 50);
    free(scratch);
}

/* Oracle: the analytic irradiance of a half-lit plane (E on x < 0.5, 0 beyond) and the
 * behaviour documented in estimate.h. Random (Poisson) photons on [0, 0.5] x [0, 1]; at
 * points a distance D past the lit edge (D = 0 to 25 mean photon spacings h), with k = 50:
 * the hull keeps reading the lit side's density (its photons all lie in the lit region and
 * their hull covers only them): within 15% of E at every D; the disc falls off (its radius
 * grows with D) and reads below 0.3 E from D = 10 h on; with max_dist2 = (5h)^2 every estimator
 * reads exactly 0 from D = 6 h on (no photon within the radius). */
TEST(estimate_hull_past_the_edge_of_a_lit_region) {
    const size_t N = 40000;
    pm_photon *ph = malloc(sizeof *ph * N);
    rng_t r = {808};
    for (size_t i = 0; i < N; i++) {
        float pos[3] = {(float)(0.5 * rng_unit(&r)), (float)rng_unit(&r), 0};
        pm_photon_init(&ph[i], pos, (float[3]){0x1p-16f, 0x1p-16f, 0x1p-16f}, DOWN, UP, 0);
    }
    const double E = (double)N * 0x1p-16 / 0.5, h = sqrt(0.5 / (double)N);
    pm_kdtree *t = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(8);
    ASSERT_EQ_INT(pm_kdtree_build(&t, ph, N, &cfg, NULL), PM_OK);
    void *scratch = malloc(pm_estimate_scratch_bytes(50));
    const double Ds[] = {0, 2, 5, 10, 25};
    for (int di = 0; di < 5; di++) {
        double sh = 0, sd = 0, s0 = 0;
        const int L = 300;
        for (int l = 0; l < L; l++) {
            float x[3] = {(float)(0.5 + Ds[di] * h), (float)(0.2 + 0.6 * rng_unit(&r)), 0};
            pm_estimate_options o;
            pm_estimate_result res;
            pm_estimate_options_init(&o, PM_EST_HULL, 50);
            ASSERT_EQ_INT(pm_estimate(t, x, UP, &o, scratch, &res, NULL), PM_OK);
            sh += res.rgb[0] / E;
            o.kind = PM_EST_DISC;
            ASSERT_EQ_INT(pm_estimate(t, x, UP, &o, scratch, &res, NULL), PM_OK);
            sd += res.rgb[0] / E;
            o.max_dist2 = (float)(25 * h * h);
            for (int kind = 0; kind < PM_EST_COUNT_; kind++) {
                o.kind = (pm_estimator)kind;
                ASSERT_EQ_INT(pm_estimate(t, x, UP, &o, scratch, &res, NULL), PM_OK);
                s0 = fmax(s0, res.rgb[0] / E);
            }
        }
        printf("past the edge by %4.1f spacings: hull %.3f E, disc %.3f E; with max_dist2 (5 h)^2 at most %.3f E\n",
               Ds[di], sh / L, sd / L, s0);
        EXPECT_MSG(fabs(sh / L - 1) <= 0.15, "hull at D = %g h: %.3f E", Ds[di], sh / L);
        if (Ds[di] >= 10) EXPECT_MSG(sd / L < 0.3, "disc at D = %g h: %.3f E", Ds[di], sd / L);
        if (Ds[di] >= 6) EXPECT_MSG(s0 == 0, "max_dist2 at D = %g h: %.3f E", Ds[di], s0);
    }
    free(scratch);
    pm_kdtree_free(t);
    free(ph);
}

/* Oracle: the committed files. scripts/gen-accuracy-md.sh run on the committed
 * docs/accuracy/ reproduces the committed docs/ACCURACY.md byte for byte (the document holds
 * no figure that is not in those files). */
TEST(accuracy_doc_regenerates_exactly) {
    char cmd[4096], out[4096];
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/gen-accuracy-md.sh' --out '%s/ACCURACY.md' && cmp '%s/ACCURACY.md' '%s/docs/ACCURACY.md'",
             pm_test_source_dir(), pm_test_tmpdir(), pm_test_tmpdir(), pm_test_source_dir());
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 0, "docs/ACCURACY.md does not regenerate: %s", out);
}

/* Oracle: the derivations of docs/ACCURACY.md, on bench_estimate's own quick run. accuracy.csv
 * has every layout, region, estimator and k (4 layouts x 2 regions x 3 k x 7 methods), every
 * value finite; on random photons in the interior the corrected disc's bias is within 4
 * standard errors + 1% of the derived (k - 1/2)/(k - 1) - 1, and the default hull reads above
 * the boundary-0 hull at k = 15 (estimate.h, RANDOM PHOTONS); on stratified photons the
 * corrected disc is within 4 standard errors + 1% of 0. */
TEST(bench_estimate_accuracy_tables) {
    char cmd[4096], out[8192], path[2048];
    snprintf(cmd, sizeof cmd, "%s/bench_estimate --quick --accuracy-only --out %s", pm_test_build_dir(), pm_test_tmpdir());
    int rc = pm_test_run(cmd, out, sizeof out);
    ASSERT_MSG(rc == 0, "bench_estimate failed (%d): %s", rc, out);
    snprintf(path, sizeof path, "%s/accuracy.csv", pm_test_tmpdir());
    FILE *f = fopen(path, "r");
    ASSERT(f);
    char line[512];
    ASSERT(fgets(line, sizeof line, f));
    EXPECT(strcmp(line, "layout,region,photons,estimator,variant,k,points,mean_rel_error,sem,rms_rel_error\n") == 0);
    int rows = 0, checked = 0;
    double hull02 = NAN, hull0 = NAN;
    while (fgets(line, sizeof line, f)) {
        char lay[32], reg[32], est[32], var[32];
        unsigned long n, pts;
        unsigned k;
        double mean, sem, rms;
        /* variant may be empty: parse the fields by hand */
        char *fld[10], *p = line;
        int nf = 0;
        while (nf < 10 && p) {
            fld[nf++] = p;
            p = strchr(p, ',');
            if (p) *p++ = 0;
        }
        ASSERT_EQ_INT(nf, 10);
        snprintf(lay, sizeof lay, "%s", fld[0]), snprintf(reg, sizeof reg, "%s", fld[1]);
        snprintf(est, sizeof est, "%s", fld[3]), snprintf(var, sizeof var, "%s", fld[4]);
        n = strtoul(fld[2], NULL, 10), k = (unsigned)strtoul(fld[5], NULL, 10), pts = strtoul(fld[6], NULL, 10);
        mean = atof(fld[7]), sem = atof(fld[8]), rms = atof(fld[9]);
        rows++;
        EXPECT(n > 0 && pts > 0 && isfinite(mean) && isfinite(sem) && sem >= 0 && isfinite(rms) && rms >= fabs(mean) - 1e-9);
        if (!strcmp(reg, "interior") && !strcmp(est, "disc") && !strcmp(var, "area")) {
            double want = strcmp(lay, "random") == 0 ? (k - 0.5) / (k - 1.0) - 1 : 0.0;
            EXPECT_MSG(fabs(mean - want) <= 4 * sem + 0.01, "%s k=%u disc: %+.3f%% (se %.3f%%), want %+.3f%%", lay, k,
                       100 * mean, 100 * sem, 100 * want);
            checked++;
        }
        if (!strcmp(lay, "random") && !strcmp(reg, "interior") && !strcmp(est, "hull") && k == 15)
            *(strcmp(var, "boundary=0") ? &hull02 : &hull0) = mean;
    }
    fclose(f);
    EXPECT_EQ_INT(rows, 4 * 2 * 3 * 7);
    EXPECT_EQ_INT(checked, 6);
    EXPECT_MSG(hull02 > hull0, "random k=15: hull %g, boundary 0 %g", hull02, hull0);
}

/* Oracle: estimate.h's GUARANTEES ("a non-finite x or normal gives PM_ENONFINITE"). For every
 * estimator, through the core (with a list of real neighbours) and through the wrapper, and for
 * the combined estimate: a normal with a NaN, +inf or -inf component gives PM_ENONFINITE and a
 * zero estimate; the same calls with the finite normal give PM_OK and a positive value, so the
 * refusal is the normal's doing. */
TEST(estimate_non_finite_normal_refused) {
    square sq;
    make_square(&sq, 11, RANDOM);
    pm_kdtree *tree = NULL;
    pm_kdtree_config cfg = pm_kdtree_photon_config(4);
    ASSERT_EQ_INT(pm_kdtree_build(&tree, sq.ph, SIDE * SIDE, &cfg, NULL), PM_OK);
    const pm_photon *tp = pm_kdtree_records(tree);
    const float x[3] = {0.5f, 0.5f, 0};
    const float bad[3][3] = {{NAN, 0, 1}, {0, INFINITY, 1}, {0, 0, -INFINITY}};
    enum { K = 30 };
    pm_neighbor nb[K];
    void *scratch = malloc(pm_estimate_scratch_bytes(K));
    ASSERT(scratch);
    int found = pm_kdtree_knn(tree, x, K, INFINITY, nb, 0, NULL);
    ASSERT_EQ_INT(found, K);
    for (int kind = 0; kind < PM_EST_COUNT_; kind++) {
        pm_estimate_options o;
        pm_estimate_result r;
        pm_estimate_options_init(&o, (pm_estimator)kind, K);
        EXPECT_EQ_INT(pm_estimate(tree, x, UP, &o, scratch, &r, NULL), PM_OK);
        EXPECT_MSG(r.rgb[0] > 0, "%s: finite normal gave %g", pm_estimator_name((pm_estimator)kind), r.rgb[0]);
        EXPECT_EQ_INT(pm_estimate_core(tp, nb, K, x, UP, &o, scratch, &r), PM_OK);
        EXPECT(r.rgb[0] > 0);
        for (int b = 0; b < 3; b++) {
            EXPECT_EQ_INT(pm_estimate(tree, x, bad[b], &o, scratch, &r, NULL), PM_ENONFINITE);
            EXPECT(r.rgb[0] == 0 && r.rgb[1] == 0 && r.rgb[2] == 0);
            EXPECT_EQ_INT(pm_estimate_core(tp, nb, K, x, bad[b], &o, scratch, &r), PM_ENONFINITE);
            EXPECT(r.rgb[0] == 0 && r.rgb[1] == 0 && r.rgb[2] == 0);
        }
    }
    free(scratch);
    pm_kdtree_free(tree);
    free_square(&sq);
}
