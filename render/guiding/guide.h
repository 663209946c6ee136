/* guide.h: learned, unbiased guiding of a 2-D primary sample (u1, u2) in [0,1)^2, per receiver
 * cell: where most of a sampling domain carries nothing (a lamp seen through a 10 x 10 hole), the
 * samples go where a pilot found something.
 *
 * WHAT IS GUIDED. A sampling routine maps (u1, u2) uniform in [0,1)^2 to something: a point on
 * a light (light_sample_li), a cosine-weighted direction (sample_cosine_hemisphere). Its estimate
 * divides by the density that uniform (u1, u2) gives, call it p0. Here (u1, u2) is drawn from
 * another density d(u) over the unit square instead, and the estimate is divided by d(u) as well:
 *     E[ f(x(u)) / (p0(x(u)) d(u)) ] = integral over u of f(x(u)) / p0(x(u)) du = the same mean,
 * for ANY d that is > 0 wherever f is. d is piecewise constant on G x G strata:
 *     q'_ij = alpha / G^2 + (1 - alpha) q_ij,        d(u) = G^2 q'_ij on stratum (i, j),
 * where q_ij >= 0, sum q_ij = 1, is what the pilot learned, and alpha (the defensive share, > 0)
 * keeps every stratum's density at least alpha: so the estimate is unbiased for any table,
 * however poor (a wrong table costs noise, at most 1/alpha times the uniform weight, never
 * bias; the light guide's light choice, below, can add another 1/alpha). Where there is no
 * table d = 1: exactly the uniform sampling.
 *
 * RECEIVER CELLS. A table belongs to a (cell, slot). Cells: a grid over the scene's bounds with
 * cubes of side h (guide_grid_init: the largest side / res, so it scales with the scene), times
 * the dominant axis and sign of the receiving side's normal (a floor and a wall meeting in a cube
 * get different tables). Only cells the learning visits are stored (a hash). A slot is whatever
 * the caller numbers: the light (light guide), or 0 (one table per cell).
 *
 * SAMPLING. guide_sample takes the caller's (u1, u2) and returns the warped pair and d(u): the
 * stratum k = i + G j is chosen by u1 against the cumulative q', u1's remainder inside its
 * interval, rescaled to [0,1), becomes the position in the stratum's first coordinate, and u2
 * the second: so the caller draws the same two numbers as before (a stream advances the same).
 * guide_density gives d(u) for any u (1 where there is no table); d(u) is computed from the
 * same cumulative array the sampling uses, so they agree (tests: a histogram against it).
 *
 * LEARNING. guide_build sums rows (cell, slot, G^2 non-negative values) per (cell, slot), in an
 * order that does not depend on the order of the rows given (a sort by cell, slot, row number,
 * and equal rows summed in row order), normalizes to q, and makes the cumulative q'. A (cell,
 * slot) whose values sum to 0 gets no table. guide_learn makes the rows from a callback: at
 * each pilot point (guide_points: camera rays' first diffuse hits and one cosine bounce from
 * each), for each slot asked for, one probe per stratum at a jittered u in it; the row is the
 * probes' values. Every point has its own random stream (seed, point), so the table is the
 * same for any thread count and on every process of a distributed render.
 *
 * THE LIGHT GUIDE (guide_light_make, light_guide.c; used by the photon mapper's direct light, direct.h):
 * slots are lights (area and sphere lights; a point or directional light ignores (u1, u2)).
 * Stage A: GUIDE_PATHS camera paths give points (guide_points); at each, GUIDE_PROBES light
 * samples drawn as next-event estimation draws them (light by power, a uniform point) count
 * what would arrive unshadowed (U) and what passes the shadow test (V), summed per REGION: a
 * cube of GUIDE_COARSE^3 receiver cells, same side (a region gathers enough samples to see a
 * pass rate of a few percent; a single cell would not). A region is blocked when V > 0 and
 * V < GUIDE_PASS_MAX U. Stage B: in every receiver cell of a blocked region, at its first
 * GUIDE_CELL_POINTS points (point order), one probe per stratum for each light stage A saw
 * contribute in the region: value = the luminance f Li cos if the segment is unoccluded, else 0.
 * Each probed row is spread (half itself plus half the largest value in its 3 x 3 strata):
 * the part of a lamp seen through a hole moves with the receiver, and a few points of a cell
 * otherwise miss strata the rest of the cell sees (on pinhole_room the spread took the direct
 * light's variance gain on the lit patch from about 1x to about 5x). Only cells of blocked
 * regions get tables: where light samples mostly pass, sampling stays as it was.
 * The light is chosen per cell too (direct.c): p' = alpha p_power + (1 - alpha) w_l, w_l the
 * cell's share of light l's probe values (guide_pick_slot / guide_slot_weight); a light the
 * cell never saw keeps alpha p_power > 0.
 * The plan turns it on when the blocked regions carry at least GUIDE_MIN_SHARE of the light
 * that passed in stage A (the camera looks at light that comes through an opening) and prints
 * the evidence: blocked and lit regions, the pass rate and light share in the blocked ones,
 * probes, tables, cells, and stage A's points, samples and overall pass rate.
 * photon_mapping.light_guide true/false forces it.
 *
 * MEASURED (pinhole_room, 8 x 8, gather_rays 1, secondary_rays 1, against the 4M-spp path
 * reference). With the photon maps fixed (traced once, loaded) so only sampling varies, 24
 * seeds at 1024 spp, spread of the region errors guide off -> on: lit patch 14.5% -> 6.0%
 * (variance 5.8x lower), whole image 10.3% -> 6.3%, walls and ceiling 13.0% -> 14.8% (their
 * noise is the gather rays that must find the patch or the hole; unchanged), CPU 2.71 -> 2.76 s
 * a run. Direct light alone on the patch's pixels: per-sample relative variance 141 -> 34; at
 * the first gather hits seen from the walls 1916 -> 1002. The pilot: 0.14-0.20 CPU-s on
 * pinhole_room (~2% of a default pm render), 0.05-0.08 s where it stays off. Of the 20
 * shipped scenes only pinhole_room plans it on.
 *
 * THE GATHER'S SHADOW RAYS, where the ports the plan finds fill the rooms with photons
 * (measured 2026-12-05 at 89291b5 with a counting build, 16 x 16, 64 spp, seed 1, pm at the
 * defaults): of the light samples taken at gather hits (the hits that read the map's indirect
 * light, and the secondary gathers' own), 0.25% reach the light on pinhole_room (0.04% with the
 * guide forced off), 3.2% on door_ajar (1.8%), 0.54% on lamp_shade (0.23%); the camera hits'
 * own samples 0.88% (0.13%), 9.3% (2.9%), 2.3% (0.80%). Does the guide help: 8 x 8 pinhole_room
 * and 16 x 16 door_ajar, 1024 spp, seeds 1-3, against their references: mean squared error
 * 5.6e-9 with the guide against 1.6e-8 without on pinhole_room (2.9x lower, CPU 1.79 against
 * 1.62 s), 1.8e-7 against 3.3e-7 on door_ajar (1.8x lower, CPU 3.1 against 1.7 s: the pilot's
 * stage B, 1.9M probes, costs about what it saves at this size). Reading a gather hit's direct
 * light from the global map instead of a light sample where the guide has a table (the cells
 * where shadow rays mostly fail; a consistent estimate, tried with a full radiance estimate)
 * lowered the mean squared error by only 3-6% on pinhole_room and 1-3% on door_ajar, at 1-12%
 * more CPU: with ports filling the rooms with photons, what remains is the photon map's own
 * noise (a seed's region means move by +-5% on both and do not move with more spp), not the
 * gathers' light samples, so it was not kept.
 *
 * STAGE B'S SIZE. Its tables serve the render's light samples, so stage B probes at most
 * GUIDE_B_PER_SAMPLE (4) per camera sample of the render the camera is set for (width x height x
 * spp; a render in passes: its first pass), and at least GUIDE_B_MIN (524,288, about 0.15 CPU-s):
 * of the jobs stage A made, evenly in (point, light) order, floor(that / G^2) (guide_light_jobs;
 * the plan's learn; guide_light_make, for tests and callers without a render size, keeps all).
 * The decision (stage A's) is unchanged; cells whose jobs are dropped sample uniformly (no gain,
 * no loss). Of the shipped scenes that plan it on, only door_ajar's is cut (at its own size,
 * 32 x 32 x 16, too): its 7,292 jobs (1.87M probes) are all kept from 466,688 camera samples up (32 x 32 x 456), 2,048
 * below 131,072; pinhole_room's 1,428 and lamp_shade's 1,786 are always kept. The floor: at
 * 262,144 (1,024 jobs) pinhole_room's 32 x 32 RMSE rose 2-22% (seeds 1-2, 16 and 64 spp, the
 * same maps) for 0.05 CPU-s (measured by hand on 84ae036 with this rule).
 * LIMITS. A cell's table is the sum over a few points in it: where what a light sample can
 * reach changes within a cell (the window onto a lamp through a hole moves with the receiver),
 * the table covers the union, so guided samples pass less often than at one point. Cells the
 * pilot did not visit, or in regions where no stage-A sample passed, sample uniformly (no gain,
 * no loss). Media: off (the probes test visibility, not transmittance). Cost: stage A's rays
 * (about 2 GUIDE_PATHS camera and bounce rays and up to 2 GUIDE_PATHS GUIDE_PROBES shadow rays,
 * every pm render that samples lights) and stage B's (cells x points x lights x G^2 shadow
 * rays, only when on; pinhole_room: 365,568).
 *
 * Ownership: a built guide owns its arrays (guide_free; guide_destroy for a guide_light_make
 * result). Once built it is read-only: guide_sample and guide_density may be called from any
 * number of threads.
 */
#ifndef RENDER_GUIDE_H
#define RENDER_GUIDE_H

#include <stddef.h>
#include <stdint.h>

#include "base/rng.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The pilot's random streams (seed, point, GUIDE_STREAM + i): i = 0 the camera paths of
 * guide_points, 1 the probes of guide_learn, 2 the light guide's stage A (light_guide.c). */
#define GUIDE_STREAM 0x6775696465ULL /* "guide" */
#define GUIDE_G 16             /* strata per side of a table */
#define GUIDE_RES 128          /* receiver cells along the scene's largest side */
#define GUIDE_ALPHA 0.4        /* defensive share: d(u) >= alpha everywhere */
#define GUIDE_PATHS 16384      /* light guide: camera paths of stage A */
#define GUIDE_PROBES 4         /* light guide: light samples per point in stage A */
#define GUIDE_COARSE 8         /* light guide: fine cells per side of a stage-A region */
#define GUIDE_PASS_MAX 0.5     /* light guide: a region is blocked below this pass share */
#define GUIDE_CELL_POINTS 2    /* light guide: stage-B points per cell of a blocked region */
#define GUIDE_MIN_SHARE 0.25   /* light guide: plan on when blocked regions carry this share */
#define GUIDE_B_PER_SAMPLE 4   /* light guide: stage-B probes per camera sample, at most (STAGE B'S SIZE) */
#define GUIDE_B_MIN 524288     /* light guide: stage-B probes always allowed (2048 jobs of G^2) */
#define GUIDE_B_SAY "4 probes a camera sample, at least 524288" /* the two above, in the plan's line */

typedef struct guide_grid {
    vec3 lo;  /* the scene's lower bound, less a margin */
    double h; /* the cell's side */
} guide_grid;

/* Cells of side (largest side of the scene's bounds) / res. */
void guide_grid_init(guide_grid *gr, const scene *s, int res);
/* The key of the cell holding p on the side of normal n (any length; the receiving side). */
uint64_t guide_cell(const guide_grid *gr, vec3 p, vec3 n);
/* A point's cell and its index, for grouping points by cell: qsort by guide_cell_ref_cmp orders
 * by cell, then by index (so the order does not depend on qsort's). */
typedef struct guide_cell_ref {
    uint64_t cell;
    size_t k;
} guide_cell_ref;
int guide_cell_ref_cmp(const void *a, const void *b);

/* want of the n jobs (jp[k], js[k]), evenly in their order (k = j n / want), into tp and ts (which
 * may be jp and js themselves); how many: n if want >= n. The pilots sized by the render (STAGE
 * B'S SIZE; gather_guide.h, THE PILOT'S SIZE) thin their jobs so. */
size_t guide_thin(const size_t *jp, const int *js, size_t n, size_t want, size_t *tp, int *ts);

/* One learned row: G^2 values (stratum k = i + G j, i along u1) for (cell, slot). */
typedef struct guide_row {
    uint64_t cell;
    int slot;
    const double *v; /* G^2 values >= 0 (not copied: valid during guide_build) */
} guide_row;

typedef struct guide {
    guide_grid grid;
    int G;
    double alpha;
    size_t ntables, ncells; /* (cell, slot) tables; distinct cells among them */
    size_t cap;             /* hash slots (a power of 2), open addressing */
    uint64_t *hkey;         /* per hash slot: cell key */
    int *hslot;             /* per hash slot: slot (INT_MAX: the cell's entry), -1 when empty */
    size_t *hidx;           /* per hash slot: table number (the cell's number for its entry) */
    double *cdf;            /* ntables x (G^2 + 1): cumulative q' per table */
    /* Tables are in (cell, slot) order; a cell's are cfirst[c] .. cfirst[c + 1] - 1. */
    int *tslot;             /* per table: its slot */
    double *tw;             /* per table: its share of its cell's values (the slot's weight) */
    double *tcum;           /* per table: cumulative tw within its cell */
    size_t *cfirst;         /* ncells + 1 */
    int stat_id;            /* a stats.h counter of the samples it guided, or -1 (none) */
} guide;

/* Build from n rows (G strata per side, defensive share alpha in (0, 1]). 0, PM_EINVAL (G < 1,
 * alpha out of range, a negative or non-finite value, a slot < 0) or PM_ENOMEM. Rows with an
 * all-zero sum make no table. A guide with no table samples uniformly. */
int guide_build(guide *g, const guide_grid *grid, int G, double alpha, const guide_row *rows, size_t n);
void guide_free(guide *g);
/* guide_free and free(g); g may be NULL. */
void guide_destroy(guide *g);

/* The table of (p, n, slot): its cumulative array, or NULL (uniform). g may be NULL. */
const double *guide_find(const guide *g, vec3 p, vec3 n, int slot);
/* Warp (u1, u2) by table t (guide_find; NULL: unchanged) and return d(u) (1 for NULL). */
double guide_warp(const guide *g, const double *t, double *u1, double *u2);
/* d(u) of table t at (u1, u2) (1 for NULL). */
double guide_pdf(const guide *g, const double *t, double u1, double u2);
/* guide_find + guide_warp / guide_pdf. */
double guide_sample(const guide *g, vec3 p, vec3 n, int slot, double *u1, double *u2);
double guide_density(const guide *g, vec3 p, vec3 n, int slot, double u1, double u2);

/* CHOOSING THE SLOT (the light guide's light choice). A cell's tables also carry each slot's
 * share w_s of the cell's summed values (the pilot's estimate of what each light gives there).
 * guide_cell_index finds the cell (-1: none), guide_pick_slot(g, c, u) chooses a slot with
 * probability w_s, guide_slot_weight gives w_s (0 for a slot without a table there) and
 * guide_cell_table the slot's table (NULL: none). A caller mixes it with its own choice,
 * p'_s = alpha p_s + (1 - alpha) w_s, to stay unbiased (direct.c). */
long guide_cell_index(const guide *g, vec3 p, vec3 n);
int guide_pick_slot(const guide *g, long c, double u);
double guide_slot_weight(const guide *g, long c, int slot);
const double *guide_cell_table(const guide *g, long c, int slot);

/* A pilot point: a diffuse hit of a camera ray (bounce 0) or of one cosine bounce from it
 * (bounce 1). */
typedef struct guide_point {
    hit h;
    vec3 wo;   /* unit, toward where the ray came from */
    vec3 n;    /* the geometric normal on wo's side */
    rgb beta;  /* throughput to here: 1 at bounce 0, the diffuse albedo at bounce 1 */
    int bounce;
} guide_point;

/* Trace `paths` camera rays (uniform film positions, stream (seed, path)), passing mirrors
 * and glass (up to 8 specular bounces), to their first surface with a diffuse branch, and
 * one cosine-weighted bounce from it to the next: up to 2 points per path, written in path
 * order (any thread count gives the same array). *out is malloc'd (the caller frees). 0 or
 * PM_ENOMEM. */
int guide_points(const scene *s, long paths, uint64_t seed, int threads, guide_point **out, size_t *n);

/* A probe's value (>= 0) at point pt for slot at primary sample (u1, u2); g: the probe's
 * stream, for any further numbers. Called from several threads at once. */
typedef double (*guide_probe_fn)(void *user, const scene *s, const guide_point *pt, int slot, double u1,
                                 double u2, rng *g);

/* Learn a guide: for each point k and slot l with use[k * nslots + l] != 0 (use NULL: all),
 * one probe per stratum (u jittered in it, stream (seed, k)), one row; then guide_build. 0,
 * PM_EINVAL or PM_ENOMEM. *probes (may be NULL) gets the number of probes made. */
int guide_learn(guide *g, const scene *s, const guide_grid *grid, int G, double alpha, const guide_point *pts,
                size_t npts, int nslots, const unsigned char *use, guide_probe_fn fn, void *user, uint64_t seed,
                int threads, unsigned long long *probes);

/* The same with an explicit list of jobs: job k probes slot job_slot[k] at point
 * pts[job_point[k]]. A point's jobs must be consecutive (its stream (seed, point) runs through
 * them in the order given). */
int guide_learn_jobs(guide *g, const scene *s, const guide_grid *grid, int G, double alpha, const guide_point *pts,
                     const size_t *job_point, const int *job_slot, size_t njobs, guide_probe_fn fn, void *user,
                     uint64_t seed, int threads, unsigned long long *probes);

/* The same, each probed row spread before the build (half itself plus half the largest value
 * in its 3 x 3 strata; THE LIGHT GUIDE above). */
int guide_learn_jobs_spread(guide *g, const scene *s, const guide_grid *grid, int G, double alpha,
                            const guide_point *pts, const size_t *job_point, const int *job_slot, size_t njobs,
                            guide_probe_fn fn, void *user, uint64_t seed, int threads, unsigned long long *probes);

/* The region of a cell key of guide_cell: its cube of GUIDE_COARSE^3 cells, same side (THE
 * LIGHT GUIDE's stage A). */
uint64_t guide_region(uint64_t cell);

/* The light guide's evidence (guide_light_make). */
typedef struct guide_light_evidence {
    size_t points;                    /* stage-A points */
    unsigned long long samples;       /* stage-A light samples that would contribute unshadowed */
    unsigned long long passed;        /* of them, those that pass the shadow test */
    size_t cells, blocked;            /* cells with contributing samples; blocked ones */
    double blocked_share;             /* share of the passing light in blocked cells */
    double blocked_pass;              /* share of the unshadowed light that passes there */
    unsigned long long probes;        /* stage-B probes */
    size_t tables;                    /* (cell, light) tables built */
    size_t jobs, jobs_all;            /* stage-B jobs (point, light) probed, of those stage A made */
} guide_light_evidence;

/* The light guide in its steps, for a caller that runs its pilot with others and decides
 * later (the photon mapper's plan, plan.h): guide_light_skip says why no pilot runs (force
 * off, no light samples, media, no area or sphere light; NULL: it runs); guide_light_pilot_run
 * is stage A and stage B's jobs (evidence in e; rc PM_ENOMEM: out of memory, said in the line,
 * not an error); guide_light_wanted decides from it (pure); guide_light_learn is stage B (the
 * tables; NULL when it learns nothing or runs out of memory, rc then PM_ENOMEM); guide_light_say
 * writes the decision and its reason from all that (pure; *on = 0 unless the guide learned
 * tables). guide_light_make below runs them in that order. */
typedef struct guide_light_pilot {
    int ran;                /* stage A ran */
    int rc;                 /* 0, or PM_ENOMEM */
    guide_light_evidence e; /* stage A's (and B's probes and tables, once learned) */
    uint64_t seed;
    guide_grid grid;
    guide_point *pts; /* stage A's points */
    size_t np;
    size_t *jp; /* stage B's jobs: point and light of each */
    int *js;
    size_t nj;
} guide_light_pilot;
const char *guide_light_skip(const scene *s, int force, int usable);
void guide_light_pilot_run(const scene *s, guide_light_pilot *pl);
void guide_light_pilot_free(guide_light_pilot *pl);
int guide_light_wanted(int force, const guide_light_pilot *pl);
size_t guide_light_jobs(const scene *s, size_t nj);
/* max_jobs: stage B's jobs at most (0: all; the plan passes guide_light_jobs, STAGE B'S SIZE). */
guide *guide_light_learn(const scene *s, guide_light_pilot *pl, size_t max_jobs);
void guide_light_say(int force, const char *skip, const guide_light_pilot *pl, const guide *gd, int *on,
                     char *reason, size_t cap);

/* The light guide of scene s for the photon mapper: force is PLAN_AUTO/ON/OFF (photon_settings.h),
 * usable = 0 when the renderer makes no light samples (no final gather / preview). Writes the
 * decision (*on) and its reason (with the evidence) and returns the guide when on (the caller
 * frees it with guide_destroy), else NULL. The same scene gives the same answer on any thread
 * count. ev may be NULL. */
guide *guide_light_make(const scene *s, int force, int usable, int *on, char *reason, size_t cap,
                        guide_light_evidence *ev);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_GUIDE_H */
