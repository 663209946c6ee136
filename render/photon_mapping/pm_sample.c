/* pm_sample.c: the photon mapper's camera sample, decided before rendering; see pm_sample.h.
 *
 * The emission mask (pm_emission_mask_build) and the sample pilot (pm_sample_pilot, THE SAMPLE
 * PILOT below) trace their camera rays through the photon mapper's own eye-ray code (the
 * host's eye callback), so they measure exactly the sample the render will take. Why each
 * exists and what it saved: docs/PROFILE.md.
 */
#include "photon_mapping/pm_sample.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/stats.h"
#include "photonmap/common.h"
#include "scene/camera.h"

/* Probe rays per pixel side of the emission mask, and its streams. */
enum { EMIT_PROBE = 4 };
#define EMIT_SEED 0x656d6974ULL   /* "emit" */
#define DIRECT_SEED 0x64697265ULL /* "dire" */
/* DIRECT STRATA: the largest share of the pixels that may take the first hit's direct light
 * from the extra rays. */
#define DIRECT_MAX_SHARE 0.1

/* Emission-only rays only where the camera sees emitters. A pixel is marked when one of
 * EMIT_PROBE x EMIT_PROBE emission-only rays through fixed points of it, or of one of its eight
 * neighbours (the probes can miss a light's edge that crosses a pixel between them), finds
 * emission, directly or through mirrors and glass. Marked pixels take their emission from
 * emission_strata^2 extra rays per sample (photonmapper.c, mapper_li); the others from the sample's own path,
 * as with emission_strata 0. Either way each part of the pixel integral is estimated without
 * bias, so a pixel the probes miss (a light seen through glass in a sliver of it) keeps its
 * expected value and only loses the extra antialiasing. The probes use fixed streams (the
 * scene's seed, the pixel), so the mask is the same for any thread count and under
 * render-mpi. Cost: 16 rays a pixel, once; on cornell_box at 16 spp it saves the 256
 * emission-only rays per pixel of the 90% of pixels that see no light.
 * EMISSION STRATA: the default m is 4 (16 rays a sample, in a 4 x 4 grid of the sample's
 * stratum), not 2: where photon mapping's other noise is low the light's edges are much of a
 * pixel's error, and these rays are a camera ray and an emission read each. Measured by hand
 * (96x96, 100 spp, one thread, seeds 101 and 102, a machine loaded by other jobs so the CPU
 * seconds are rough, RMSE against the references of docs/RESULTS.md): cornell_box RMSE
 * 0.0067/0.0068 at m = 2, 0.0052/0.0052 at 4, 0.0051/0.0050 at 6; cornell_spheres
 * 0.0089/0.0079, 0.0063/0.0064, 0.0062/0.0062 at 8; CPU time within the noise (2.1-3.1 s and
 * 3.8-4.5 s at every m). Above 4 the gain is a few percent for m^2 rays a sample.
 * DIRECT STRATA: the same extra rays also take the direct light at the camera's first hit (a
 * diffuse surface seen directly), and the sample's own path leaves it out, at pixels where the
 * probes find an edge of that light: of EMIT_PROBE^2 probes of the pixel or of a neighbour
 * (one light sample each, their own stream), some lit and some not (the sun's patch through a
 * window, a shadow's edge). There the light's coverage of the pixel is what varies, as at a
 * light's edge, and a light sample costs a camera ray and a shadow ray instead of a sample's
 * gathers. Unbiased the same way: the pixel integral of the first hit's direct light plus that
 * of the rest. Not where more than DIRECT_MAX_SHARE of the pixels are marked (the direct light
 * is noisy everywhere, not at edges: the extra rays would cost more than they save), and not
 * with the global map shown directly, and only where every light is a delta light
 * (point, spot, directional: a probe's light sample is then exact, lit or not; an area light's
 * one sample is lit or blocked by chance in its penumbra and behind openings, which marked most
 * pixels of lamp_shade and pinhole_room, and cost them passes) (host's no_direct).
 * Measured by hand (pm at the defaults, --time 10, 2 threads, MSE against the long references;
 * seeds 1 / 2): sun_window 16 x 16 (23 of 256 pixels marked) 2.7 / 3.2 e-6 without, 0.58 / 0.50
 * e-6 with; at 16 x 16 its error had been mostly the sun's patch's edge pixels (2.65 of 3.05 e-6
 * of a seed's luminance MSE), where path tracing, with more camera samples in the same time,
 * was 3 times better. cornell_point at 96 x 96 (1698 of 9216 marked, --time 8): RMSE 0.00068 /
 * 0.00089 with, 0.00067 / 0.00081 without (a pass costs more, and its shadows' edges are a small
 * part of its error), so the share of marked pixels is capped at DIRECT_MAX_SHARE: at 10%
 * cornell_point and sun_spheres at 32 x 32 and cornell_point at 96 x 96 keep their paths.
 * With media the extra rays march the camera's segment for its transmittance alone (in-scatter
 * is the sample's own): sun_window_fog at --time 10, seeds 1-4, MSE 5.0 / 5.8 / 5.2 / 5.8 e-5
 * with, 6.8 / 5.6 / 5.1 / 6.5 e-5 without (a small gain, within the seeds' spread: its error is
 * mostly the fog's, and a pass costs 0.7 s, so it gets 5 to 13 passes). */
int pm_emission_mask_build(const pm_sample_host *h, pm_emission_mask *em, char *reason, size_t cap, char *err,
                           size_t errcap) {
    const scene *s = h->s;
    memset(em, 0, sizeof *em);
    int W = s->cam.width, H = s->cam.height;
    size_t n = (size_t)W * (size_t)H;
    unsigned char *seen = calloc(n ? n : 1, 1), *mask = calloc(n ? n : 1, 1);
    unsigned char *edge = calloc(n ? n : 1, 1), *direct = calloc(n ? n : 1, 1);
    float *pvar = calloc(n ? n : 1, sizeof *pvar); /* the probes' luminance variance, per pixel */
    int fail = 0, probe_direct = !h->no_direct && h->cfg->emission_strata > 0;
    if (!seen || !mask || !pvar || !edge || !direct) fail = 1;
    if (!fail) {
#ifdef _OPENMP
#pragma omp parallel reduction(| : fail)
#endif
        {
            void *sc = h->scratch_new(h->user);
            if (!sc) fail = 1;
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 64)
#endif
            for (long p = 0; p < (long)n; p++) {
                if (!sc) continue;
                rng g = rng_stream(s->settings.seed ^ EMIT_SEED, (uint64_t)p, 0);
                double x = (double)(p % W), y = (double)(p / W), sum = 0, sum2 = 0;
                for (int k = 0; k < EMIT_PROBE * EMIT_PROBE; k++) {
                    ray re = camera_ray(&s->cam, x + (k % EMIT_PROBE + 0.5) / EMIT_PROBE,
                                        y + (k / EMIT_PROBE + 0.5) / EMIT_PROBE);
                    rgb E = h->eye(h->user, re, 1, &g, sc, NULL);
                    double l = rgb_lum(E);
                    if (v3_maxc(E) > 0) seen[p] = 1;
                    if (isfinite(l)) {
                        sum += l;
                        sum2 += l * l;
                    }
                }
                const double np = EMIT_PROBE * EMIT_PROBE;
                pvar[p] = seen[p] ? (float)fmax(0.0, (sum2 - sum * sum / np) / (np - 1)) : 0.0f;
                if (probe_direct) { /* DIRECT STRATA: lit and unlit probes in one pixel */
                    rng gd = rng_stream(s->settings.seed ^ DIRECT_SEED, (uint64_t)p, 0);
                    int lit = 0;
                    for (int k = 0; k < EMIT_PROBE * EMIT_PROBE; k++) {
                        ray rd = camera_ray(&s->cam, x + (k % EMIT_PROBE + 0.5) / EMIT_PROBE,
                                            y + (k / EMIT_PROBE + 0.5) / EMIT_PROBE);
                        lit += rgb_lum(h->eye(h->user, rd, 2, &gd, sc, NULL)) > 0;
                    }
                    edge[p] = lit > 0 && lit < EMIT_PROBE * EMIT_PROBE;
                }
            }
            if (sc) h->scratch_free(h->user, sc);
        }
    }
    if (fail) {
        free(seen);
        free(mask);
        free(pvar);
        free(edge);
        free(direct);
        snprintf(err, errcap, "emission mask: out of memory");
        return PM_ENOMEM;
    }
    size_t marked = 0, dmarked = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            int any = 0, de = 0;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int xx = x + dx, yy = y + dy;
                    if (!(xx >= 0 && yy >= 0 && xx < W && yy < H)) continue;
                    any |= seen[(size_t)yy * (size_t)W + (size_t)xx];
                    de |= edge[(size_t)yy * (size_t)W + (size_t)xx];
                }
            mask[(size_t)y * (size_t)W + (size_t)x] = (unsigned char)any;
            direct[(size_t)y * (size_t)W + (size_t)x] = (unsigned char)de;
            marked += (size_t)any;
            dmarked += (size_t)de;
        }
    free(edge);
    const char *dwhy = h->no_direct;
    int too_many = !dwhy && dmarked > DIRECT_MAX_SHARE * (double)n;
    if (dwhy || too_many || !dmarked) {
        free(direct);
        direct = NULL;
    }
    /* The variance a sample's emission adds to a pixel, over the image (in pixel order, so the
     * same for any thread count): the probes' variance over the m x m emission-only rays of a
     * marked pixel's sample (the sample pilot adds it to every candidate's: it costs them
     * nothing, but it falls with the samples a pixel gets). */
    double vsum = 0;
    int m = h->cfg->emission_strata;
    for (size_t p = 0; p < n; p++) vsum += pvar[p];
    em->var = n ? vsum / (double)n / (m > 0 ? (double)m * m : 1.0) : 0;
    free(pvar);
    free(seen);
    em->mask = mask;
    em->pixels = n;
    em->marked = marked;
    em->direct = direct;
    em->direct_marked = direct ? dmarked : 0;
    int len = snprintf(reason, cap,
                       "%dx%d emission-only rays per sample at %zu of %zu pixels, where %dx%d probe rays of "
                       "the pixel or a neighbour see an emitter; elsewhere a sample's own path collects emission",
                       m, m, marked, n, EMIT_PROBE, EMIT_PROBE);
    if (len > 0 && (size_t)len < cap) {
        if (direct)
            snprintf(reason + len, cap - (size_t)len,
                     "; they take the first hit's direct light too at %zu pixels, where the probes of the pixel "
                     "or a neighbour find an edge of it (lit and unlit)",
                     dmarked);
        else if (too_many)
            snprintf(reason + len, cap - (size_t)len,
                     "; the first hit's direct light from the sample's path (the probes find an edge of it at %zu "
                     "of %zu pixels, over %g%%: extra rays there would cost more than they save)",
                     dmarked, n, 100 * DIRECT_MAX_SHARE);
        else
            snprintf(reason + len, cap - (size_t)len, "; the first hit's direct light from the sample's path (%s)",
                     dwhy ? dwhy : "the probes find no edge of it");
    }
    return 0;
}

void pm_emission_mask_free(pm_emission_mask *m) {
    free(m->mask);
    free(m->direct);
    memset(m, 0, sizeof *m);
}

/* THE SAMPLE PILOT: which gather_rays, secondary_rays and caustic_stride a camera sample gets.
 * Candidates (gather_rays, secondary_rays): k_pilot_cand below; strides 1 to PILOT_MAX_STRIDE.
 * Each (gather, secondary) candidate renders the same PILOT_SIDE x PILOT_SIDE pixels spread
 * over the image, PILOT_SPP jittered samples in each, with the same random streams for every
 * candidate (common random numbers, so the streams do not decide the comparison), caustics
 * read at every sample. Its variance is the mean over pixels of the sample variance of the
 * shaded luminance inside a pixel (the noise a pixel average keeps; the differences between
 * pixels are the image, not noise). Its cost is the work the samples did, counted, not timed,
 * so the choice is the same on any machine, load or thread count, and deterministic for a
 * seed: BVH nodes visited and primitive tests, plus PILOT_LOOKUP_COST per irradiance lookup
 * and PILOT_CAUSTIC_COST per caustic estimate.
 * A stride c reads the camera path's caustics at one stratum in c x c, weighted c^2, at a
 * random offset per pixel (pm_caustic_weight, pm_sample.h): those estimates cost 1/c^2, and the pixel's
 * caustic part is the mean over (S/c)^2 strata instead of S^2, which adds (c^2 - 1) times the
 * variance of the caustic part between a pixel's samples (measured by the pilot too) to a
 * sample's variance. The emission the camera sees adds the same variance to every candidate
 * (pm_emission_mask_build measures it: on cornell_box the light's edges are most of the image's
 * error at equal time), and it falls with the samples a pixel gets, so it favours the cheaper
 * samples; it is added to each. A stride applies only where the strata (sqrt of spp) reach it, so the
 * strides above the render's strata are not candidates; a stride that does not divide the strata
 * reads blocks of two widths (pm_sample.h) and is weighed by its exact reads and variance factor.
 * An explicit stride is kept whatever the strata.
 * Of all (gather, secondary, stride) the lowest variance x cost, the time a pixel needs for a
 * given error, wins. The pilot's work is taken back out of the statistics, so they count the render only.
 * VOLUME STRIDE. In a scene with media (h->volume_stride) the in-scattering along the camera
 * path's segments in media (pmv_march: single scattering by shadow rays, the beam estimates) is
 * read at one stratum per block the same way (volume_stride v, pm_caustic_weight with its own
 * offset per pixel): the samples' tally (pm_sample_caustics) gives its variance between a
 * pixel's samples (varv) and its work (workv: BVH work of those segments plus PILOT_BEAM_COST
 * per beam photon crossed), and given the chosen (gather, secondary, stride), the v of 1 to
 * PILOT_MAX_STRIDE with the lowest (variance + (pm_caustic_factor - 1) varv) x (work - workv +
 * workv reads / S^2) wins.
 * Why: on sun_window_fog (16x16, 1024 spp) the beam estimates and the march were 65% of the
 * render, and the in-scattered light barely changes within a pixel: volume_stride 2 took the
 * run from 15.7 to 6.6 CPU-s at the same RMSE against the reference (0.0123). */
#define PILOT_SEED 0x73616d706c65ULL /* "sample" */
enum { PILOT_SIDE = 16, PILOT_SPP = 4, PILOT_MAX_STRIDE = 4 };
/* Cost of one irradiance lookup and one caustic estimate in BVH node visits (plan.h has the
 * shadow map's: 150). Measured by perf (docs/PROFILE.md; 96x96, one thread): on cornell_box an
 * irradiance lookup of the side cache took 0.9 us (nearest candidate first) and the rest of
 * the render 34 ns per BVH node visited (rays, shading, everything); on cornell_spheres 5.4 us
 * a caustic estimate (60 photons, cone filter) and 37 ns per node visit: 30 and 150 visits. */
#define PILOT_LOOKUP_COST 30.0
#define PILOT_CAUSTIC_COST 150.0
/* Cost of one photon a beam estimate crosses (pm_beam.h), in the same units: 60 ns per photon
 * crossed, the tree's traversal included (perf, sun_window_fog 16x16, 512 spp: 54% of 8 s for
 * 72M photons), about 2 node visits. */
#define PILOT_BEAM_COST 2.0
static const int k_pilot_cand[][2] = {{1, 1}, {2, 1}, {4, 2}};
#define PILOT_NCAND ((int)(sizeof k_pilot_cand / sizeof *k_pilot_cand))

/* MISS SURVIVAL (photonmapper.c): where a gather's lookup finds nothing on its side, the light
 * there is computed with chance miss_survival m, weighted 1/m. When at least
 * PILOT_MISS_SHARE of the chosen candidate's lookups miss, the pilot renders its samples again
 * at each m of k_pilot_miss (the same streams) and keeps the m of lowest variance x cost at
 * the chosen stride; with fewer misses computing them costs little and m stays 1 (the image
 * is the same as without the roulette, bit for bit). Why: partition_thick's lower half is a
 * sealed room, dark, whose lookups all miss: 3.0 M of its 4.0 M lookups at 96x96 x 256 spp,
 * each followed by a secondary gather that finds nothing, so a dark sample cost about 4 lit
 * ones and photon mapping lost to path tracing at 4 CPU-s (README.md, "Where photon mapping
 * still loses"). Where misses carry the light (the furnace with 30 global photons, whose
 * lookups nearly all miss: tests/test_render_sample.c) the variance the roulette adds
 * outweighs the work it saves and the pilot keeps m = 1. m is never below
 * the smallest candidate, so a pilot that misses a rare bright continuation multiplies that
 * part's variance by at most 1 / that. Where the pilot does not run (gather_rays,
 * secondary_rays and caustic_stride all set, no final gather) m is the setting's, 1 unless set. */
#define PILOT_MISS_SHARE 0.25
static const double k_pilot_miss[] = {0.5, 0.25};
#define PILOT_NMISS ((int)(sizeof k_pilot_miss / sizeof *k_pilot_miss))

typedef struct pilot_figures {
    double var, varc;  /* mean within-pixel variance of a sample, of its caustic part */
    double work, caus; /* per sample: work without the camera path's caustics, those estimates */
    double lum, lumc;  /* per sample: mean luminance, of its caustic part */
    double varv, workv; /* the in-scattering of media: its variance as varc, its work per sample */
    double look, miss;  /* per sample: irradiance lookups, those finding nothing on their side */
} pilot_figures;

static void pilot_run(const pm_sample_host *h, void *sc, pilot_figures *f) {
    const scene *s = h->s;
    int W = s->cam.width, H = s->cam.height;
    uint64_t w0 = stats_trace_work(), l0 = stats_total(h->st_lookup), k0 = stats_total(h->st_caustic);
    uint64_t m0 = stats_total(h->st_miss);
    double vsum = 0, vcsum = 0, lsum = 0, lcsum = 0, vvsum = 0;
    uint64_t ncam = 0, workv = 0, beamv = 0;
    for (int py = 0; py < PILOT_SIDE; py++)
        for (int px = 0; px < PILOT_SIDE; px++) {
            int x = (int)((px + 0.5) * W / PILOT_SIDE), y = (int)((py + 0.5) * H / PILOT_SIDE);
            uint64_t pixel = (uint64_t)y * (uint64_t)W + (uint64_t)x;
            double sum = 0, sum2 = 0, csum = 0, csum2 = 0, vs = 0, vs2 = 0;
            for (int k = 0; k < PILOT_SPP; k++) {
                rng g = rng_stream(s->settings.seed ^ PILOT_SEED, pixel, (uint64_t)k);
                double u = rng_uniform(&g), v = rng_uniform(&g);
                ray r = camera_ray(&s->cam, x + (k % 2 + u) / 2, y + (k / 2 + v) / 2);
                pm_sample_caustics pc = {v3s(0), 0, v3s(0), 0, 0};
                rgb L = h->eye(h->user, r, 0, &g, sc, &pc);
                double l = rgb_lum(L), lc = rgb_lum(pc.L), lv = rgb_lum(pc.Lv);
                if (!isfinite(l) || !isfinite(lc) || !isfinite(lv)) l = lc = lv = 0;
                vs += lv;
                vs2 += lv * lv;
                workv += pc.workv;
                beamv += pc.beamv;
                sum += l;
                sum2 += l * l;
                csum += lc;
                csum2 += lc * lc;
                ncam += pc.n;
            }
            lsum += sum;
            lcsum += csum;
            vsum += fmax(0.0, (sum2 - sum * sum / PILOT_SPP) / (PILOT_SPP - 1));
            vcsum += fmax(0.0, (csum2 - csum * csum / PILOT_SPP) / (PILOT_SPP - 1));
            vvsum += fmax(0.0, (vs2 - vs * vs / PILOT_SPP) / (PILOT_SPP - 1));
        }
    uint64_t w1 = stats_trace_work();
    double n = (double)PILOT_SIDE * PILOT_SIDE * PILOT_SPP;
    double ncaus = (double)(stats_total(h->st_caustic) - k0);
    f->var = vsum / (PILOT_SIDE * PILOT_SIDE);
    f->varc = vcsum / (PILOT_SIDE * PILOT_SIDE);
    f->caus = (double)ncam / n;
    f->lum = lsum / n;
    f->lumc = lcsum / n;
    f->work = ((double)(w1 - w0) + PILOT_LOOKUP_COST * (double)(stats_total(h->st_lookup) - l0) +
               PILOT_CAUSTIC_COST * (ncaus - (double)ncam) + PILOT_BEAM_COST * (double)beamv) / n;
    f->varv = vvsum / (PILOT_SIDE * PILOT_SIDE);
    f->workv = ((double)workv + PILOT_BEAM_COST * (double)beamv) / n;
    f->look = (double)(stats_total(h->st_lookup) - l0) / n;
    f->miss = (double)(stats_total(h->st_miss) - m0) / n;
}

/* The caustic map's share of the luminance the camera samples carry (0 for a black image). */
static double caustic_share(const pilot_figures *f) {
    return f->lum > 0 && isfinite(f->lum) ? fmin(1.0, fmax(0.0, f->lumc / f->lum)) : 0.0;
}

/* Run the pilot's samples once at cfg's settings for their counted work alone (the counters
 * taken back out) and *share, their caustic_share; 0 when out of memory. */
static double work_of_current(const pm_sample_host *h, double *share) {
    void *sc = h->scratch_new(h->user);
    if (!sc) return 0;
    int undo[STATS_MAX], nundo = 0;
    uint64_t before[STATS_MAX];
    for (int id = 0; id < STATS_MAX; id++)
        if (stats_name(id)) undo[nundo++] = id;
    for (int i = 0; i < nundo; i++) before[i] = stats_total(undo[i]);
    pilot_figures f;
    pilot_run(h, sc, &f);
    for (int i = 0; i < nundo; i++) stat_add(undo[i], before[i] - stats_total(undo[i])); /* mod 2^64 */
    h->scratch_free(h->user, sc);
    *share = caustic_share(&f);
    int strata = h->s->cam.strata > 0 ? h->s->cam.strata : 1;
    int c = h->cfg->caustic_stride > 1 ? h->cfg->caustic_stride : 1;
    return f.work + PILOT_CAUSTIC_COST * f.caus * pm_caustic_reads(strata, c) / ((double)strata * strata);
}

/* The blocks of a stride: m = round(S / c) per axis (at least 1), block i spanning strata
 * floor(i S / m) to floor((i + 1) S / m) - 1 (all c wide when c divides S). */
static int stride_blocks(int S, int c) {
    long m = lround((double)S / c);
    return m < 1 ? 1 : (int)m;
}

int pm_caustic_reads(int strata, int c) {
    if (c <= 1 || strata < c) return strata * strata;
    int m = stride_blocks(strata, c);
    return m * m;
}

double pm_caustic_factor(int strata, int c) {
    if (c <= 1 || strata < c) return 1.0;
    int S = strata, m = stride_blocks(S, c);
    double sum = 0; /* sum over one axis's blocks of width^2; the areas' squares are its square */
    for (int i = 0; i < m; i++) {
        double w = (double)(((int64_t)(i + 1) * S) / m - ((int64_t)i * S) / m);
        sum += w * w;
    }
    return sum * sum / ((double)S * S);
}

/* one axis: the weight factor (the block's width) of stratum x for offset u, or 0 */
static double stride_axis(int S, int m, int x, double u) {
    int64_t b = (((int64_t)x + 1) * m - 1) / S; /* the block holding x */
    int64_t lo = b * S / m, w = (b + 1) * S / m - lo;
    int64_t o = (int64_t)(u * (double)w);
    return x - lo == (o < w ? o : w - 1) ? (double)w : 0.0;
}

double pm_caustic_weight(int strata, int c, int k, double u, double v) {
    int S = strata;
    if (c <= 1 || S < c) return 1.0;
    int m = stride_blocks(S, c);
    double wx = stride_axis(S, m, k % S, u);
    return wx == 0 ? 0.0 : wx * stride_axis(S, m, k / S, v);
}

/* A candidate's figures at stride k: a sample's variance (the caustic part's within-pixel
 * variance grows by pm_caustic_factor - 1) and its cost (the caustic estimates' share falls to
 * the reads). */
static void stride_figures(const pilot_figures *f, int strata, int k, double emit_var, double *var,
                           double *cost) {
    *var = f->var + (pm_caustic_factor(strata, k) - 1) * f->varc + emit_var;
    *cost = f->work + PILOT_CAUSTIC_COST * f->caus * pm_caustic_reads(strata, k) / ((double)strata * strata);
}

/* MISS SURVIVAL: sets h->cfg->miss_survival (unless set) given the chosen candidate's figures
 * *f at stride bs, which become the chosen survival's; writes the reason into why. */
static void choose_miss_survival(const pm_sample_host *h, void *sc, int strata, int bs, double emit_var,
                                 pilot_figures *f, char *why, size_t cap) {
    photon_settings *cfg = h->cfg;
    double share = f->look > 0 ? f->miss / f->look : 0;
    if (h->explicit_miss) {
        snprintf(why, cap, "miss_survival %g (set)", cfg->miss_survival);
        return;
    }
    if (share < PILOT_MISS_SHARE) {
        snprintf(why, cap, "miss_survival 1 (%.1f%% of the pilot's lookups find nothing on their side, under "
                 "%g%%: not weighed)", 100 * share, 100 * PILOT_MISS_SHARE);
        return;
    }
    char list[160];
    double var, cost, best, keep = 1;
    stride_figures(f, strata, bs, emit_var, &var, &cost);
    best = var * cost;
    size_t len = (size_t)snprintf(list, sizeof list, "1 %.3g x %.0f", var, cost);
    for (int i = 0; i < PILOT_NMISS; i++) {
        pilot_figures fm;
        cfg->miss_survival = k_pilot_miss[i];
        pilot_run(h, sc, &fm);
        stride_figures(&fm, strata, bs, emit_var, &var, &cost);
        if (len < sizeof list)
            len += (size_t)snprintf(list + len, sizeof list - len, ", %g %.3g x %.0f", k_pilot_miss[i], var, cost);
        if (var * cost < best) {
            best = var * cost;
            keep = k_pilot_miss[i];
            *f = fm;
        }
    }
    cfg->miss_survival = keep;
    snprintf(why, cap, "miss_survival %g (%.1f%% of the pilot's lookups find nothing on their side: lowest "
             "variance x cost of %s)", keep, 100 * share, list);
}

void pm_sample_pilot(const pm_sample_host *h, int explicit_g, int explicit_s, int explicit_c, double emit_var,
                     char *reason, size_t cap, double *work, double *caus_share) {
    *work = 0;
    *caus_share = 0;
    const scene *s = h->s;
    photon_settings *cfg = h->cfg;
    int cand[PILOT_NCAND][2], nc = 0;
    for (int i = 0; i < PILOT_NCAND; i++) { /* an explicit setting replaces the candidates' own */
        int g = explicit_g ? cfg->gather_rays : k_pilot_cand[i][0];
        int sr = explicit_s ? cfg->secondary_rays : k_pilot_cand[i][1];
        int dup = 0;
        for (int j = 0; j < nc; j++) dup |= cand[j][0] == g && cand[j][1] == sr;
        if (!dup) {
            cand[nc][0] = g;
            cand[nc][1] = sr;
            nc++;
        }
    }
    int strata = s->cam.strata > 0 ? s->cam.strata : 1;
    int cmin = explicit_c || !h->caustics ? cfg->caustic_stride : 1;
    int cmax = explicit_c || !h->caustics ? cfg->caustic_stride
               : strata < PILOT_MAX_STRIDE ? (strata > 1 ? strata : 1) : PILOT_MAX_STRIDE;
    const char *why = explicit_g && explicit_s && cmin == cmax ? "set by photon_mapping (or --pm)"
                      : h->no_pilot;
    if (why) {
        snprintf(reason, cap,
                 "gather_rays %d, secondary_rays %d, caustic_stride %d, miss_survival %g (%s)",
                 cfg->gather_rays, cfg->secondary_rays, cfg->caustic_stride, cfg->miss_survival, why);
        if (!h->no_probe) *work = work_of_current(h, caus_share);
        return;
    }
    void *sc = h->scratch_new(h->user);
    if (!sc) {
        snprintf(reason, cap,
                 "gather_rays %d, secondary_rays %d, caustic_stride %d (no pilot: out of memory)",
                 cfg->gather_rays, cfg->secondary_rays, cfg->caustic_stride);
        return;
    }
    /* every counter the pilot's samples can touch, to take them back out afterwards */
    int undo[STATS_MAX], nundo = 0;
    for (int id = 0; id < STATS_MAX; id++)
        if (stats_name(id)) undo[nundo++] = id;
    uint64_t before[STATS_MAX];
    for (int i = 0; i < nundo; i++) before[i] = stats_total(undo[i]);
    pilot_figures fig[PILOT_NCAND];
    int keep_g = cfg->gather_rays, keep_s = cfg->secondary_rays;
    for (int c = 0; c < nc; c++) {
        cfg->gather_rays = cand[c][0];
        cfg->secondary_rays = cand[c][1];
        pilot_run(h, sc, &fig[c]);
    }
    cfg->gather_rays = keep_g;
    cfg->secondary_rays = keep_s;
    /* the scores of (candidate, stride); a black image (all 0) falls to the cheapest */
    int bc = 0, bs = cmin;
    double best = INFINITY, bestcost = INFINITY;
    for (int c = 0; c < nc; c++)
        for (int k = cmin; k <= cmax; k++) {
            double var, cost;
            stride_figures(&fig[c], strata, k, emit_var, &var, &cost);
            if (var * cost < best || (var * cost == best && cost < bestcost)) {
                best = var * cost;
                bestcost = cost;
                bc = c;
                bs = k;
            }
        }
    cfg->gather_rays = cand[bc][0];
    cfg->secondary_rays = cand[bc][1];
    cfg->caustic_stride = bs;
    /* the miss survival, given the rest (MISS SURVIVAL above) */
    char mwhy[320];
    choose_miss_survival(h, sc, strata, bs, emit_var, &fig[bc], mwhy, sizeof mwhy);
    for (int i = 0; i < nundo; i++) stat_add(undo[i], before[i] - stats_total(undo[i])); /* mod 2^64 */
    h->scratch_free(h->user, sc);
    /* the volume stride, given the rest (VOLUME STRIDE above) */
    double var0, c0, vbest = INFINITY, S2 = (double)strata * strata;
    stride_figures(&fig[bc], strata, bs, emit_var, &var0, &c0);
    c0 -= fig[bc].workv;
    for (int k = 1; h->volume_stride && k <= (strata < PILOT_MAX_STRIDE ? strata : PILOT_MAX_STRIDE); k++) {
        double cost = c0 + fig[bc].workv * pm_caustic_reads(strata, k) / S2;
        double score = (var0 + (pm_caustic_factor(strata, k) - 1) * fig[bc].varv) * cost;
        if (score < vbest) {
            vbest = score;
            cfg->volume_stride = k;
            bestcost = cost;
        }
    }
    *work = bestcost;
    *caus_share = caustic_share(&fig[bc]);
    size_t len = (size_t)snprintf(reason, cap,
                                  "gather_rays %d, secondary_rays %d, caustic_stride %d (pilot of %d camera "
                                  "samples at %d pixels: lowest variance x cost of",
                                  cand[bc][0], cand[bc][1], bs, PILOT_SIDE * PILOT_SIDE * PILOT_SPP,
                                  PILOT_SIDE * PILOT_SIDE);
    for (int c = 0; c < nc && len < cap; c++) {
        double var, cost;
        stride_figures(&fig[c], strata, bs, emit_var, &var, &cost);
        len += (size_t)snprintf(reason + len, cap - len, " %d/%d/%d %.3g x %.0f%s", cand[c][0], cand[c][1],
                                bs, var, cost, c + 1 < nc ? "," : "");
    }
    if (len < cap)
        len += (size_t)snprintf(reason + len, cap - len,
                                "; the variances include %.3g of the emission the camera sees; the caustic "
                                "map carries %.1f%% of the samples' luminance", emit_var, 100 * *caus_share);
    if (len < cap && cmax > cmin) {
        len += (size_t)snprintf(reason + len, cap - len, "; strides");
        for (int k = cmin; k <= cmax && len < cap; k++)
            len += (size_t)snprintf(reason + len, cap - len, "%s %d (%d of %d)", k == cmin ? "" : ",", k,
                                    pm_caustic_reads(strata, k), strata * strata);
        if (len < cap) len += (size_t)snprintf(reason + len, cap - len, " weighed");
    }
    if (len < cap && h->volume_stride)
        len += (size_t)snprintf(reason + len, cap - len,
                                "; volume_stride %d: in-scattering in media, variance %.3g and work %.0f of a "
                                "sample's, read at one sample in %d x %d", cfg->volume_stride, fig[bc].varv,
                                fig[bc].workv, cfg->volume_stride, cfg->volume_stride);
    if (len < cap) len += (size_t)snprintf(reason + len, cap - len, ")");
    if (len < cap) snprintf(reason + len, cap - len, "; %s", mwhy);
}
