/* pm_sample.h: the photon mapper's camera sample, decided once before rendering (pm_sample.c):
 * where its emission-only rays go (the emission mask: the pixels where probe rays see an
 * emitter) and how much work a sample does (the sample pilot: gather_rays, secondary_rays and
 * caustic_stride by variance x cost). The plan's "emission rays:" and "sample:" lines.
 *
 * The photon mapper (photonmapper.c) lends its eye rays through pm_sample_host, so this file
 * traces nothing of its own. Both use fixed random streams (the scene's seed, the pixel), so
 * the mask and the choice are the same for any thread count, and the pilot counts work instead
 * of timing it, so its choice is the same on any machine. The mask is owned by the caller
 * (pm_emission_mask_free). */
#ifndef RENDER_PM_SAMPLE_H
#define RENDER_PM_SAMPLE_H

#include <stddef.h>
#include <stdint.h>

#include "base/rng.h"
#include "base/vec.h"
#include "load/photon_settings.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The caustic light a camera path took at weight 1 (already times the path's throughput), and
 * how many caustic estimates that took: the pilot's tally of one sample. */
typedef struct pm_sample_caustics {
    rgb L;
    uint64_t n;
    rgb Lv;             /* the in-scattered light of media the path met (times its throughput) */
    uint64_t workv;     /* the BVH work of those media segments (pm_volume.h, pmv_march_eye) */
    uint64_t beamv;     /* the beam photons they crossed (pm_beam.h) */
} pm_sample_caustics;

/* What the mask and the pilot borrow from the photon mapper. */
typedef struct pm_sample_host {
    const scene *s;
    photon_settings *cfg;       /* read; the pilot sets gather_rays, secondary_rays, caustic_stride,
                                   miss_survival */
    int st_lookup, st_caustic;  /* the ids of the irradiance-lookup and caustic-estimate counters */
    int caustics;               /* the scene has a caustic map */
    const char *no_pilot;       /* why the pilot cannot run (no final gather, ...), or NULL */
    int volume_stride;          /* the pilot chooses cfg->volume_stride (a scene with media, not set) */
    int no_probe;               /* the eye rays cannot be traced before the render (partitioned
                                   render-mpi: its lookups are shared between processes) */
    void *user;
    void *(*scratch_new)(void *user); /* a thread's scratch for eye rays (NULL: out of memory) */
    void (*scratch_free)(void *user, void *scratch);
    /* Radiance along a camera ray: emit = 1 the emission it meets alone (directly, mirrors,
     * glass), emit = 0 the shading alone, caustics read at weight 1 and tallied into pc;
     * emit = 2 the direct light at its first hit alone (a diffuse surface the camera sees). */
    rgb (*eye)(void *user, ray r, int emit, rng *g, void *scratch, pm_sample_caustics *pc);
    int st_miss;       /* the id of the counter of lookups finding nothing on their side */
    int explicit_miss; /* cfg->miss_survival was set: kept (MISS SURVIVAL in pm_sample.c) */
    const char *no_direct; /* why no pixel takes its first hit's direct light from the extra rays
                              (DIRECT STRATA in pm_sample.c), or NULL */
} pm_sample_host;

typedef struct pm_emission_mask {
    unsigned char *mask; /* one byte per pixel (y * width + x): 1 = emission-only rays there */
    size_t pixels, marked;
    unsigned char *direct; /* per pixel: 1 = the first hit's direct light from the extra rays
                              (pm_sample.c, DIRECT STRATA); NULL: nowhere */
    size_t direct_marked;
    double var; /* a sample's emission variance over m x m rays, the image's mean */
} pm_emission_mask;

/* Build the mask of h->s's image (4 x 4 probe rays a pixel, in parallel) and write the
 * "emission rays:" reason. 0, or PM_ENOMEM with a message in err. */
int pm_emission_mask_build(const pm_sample_host *h, pm_emission_mask *m, char *reason, size_t cap, char *err,
                           size_t errcap);
void pm_emission_mask_free(pm_emission_mask *m);
/* The sample pilot: sets h->cfg's gather_rays, secondary_rays, caustic_stride and
 * miss_survival (those the user did not set: explicit_*, h->explicit_miss) and writes the
 * "sample:" reason. emit_var: the mask's var.
 * *work: the counted work of one camera sample as chosen (BVH node visits, primitive tests,
 * lookups and caustic estimates at their costs), measured by the pilot's samples even where
 * no choice is left to it; 0 when h->no_probe or out of memory. *caus_share: the share of the
 * samples' luminance read from the caustic map at the camera path's hits (0 likewise). */
void pm_sample_pilot(const pm_sample_host *h, int explicit_g, int explicit_s, int explicit_c, double emit_var,
                     char *reason, size_t cap, double *work, double *caus_share);
/* CAUSTICS AT A STRIDE. With caustic_stride c > 1 a pixel's S x S strata (S = strata) are cut
 * into m x m blocks, m = round(S / c) per axis (at least 1), block i spanning strata
 * floor(i S / m) to floor((i + 1) S / m) - 1 along each axis, and the caustic map is read at one
 * stratum of each block, weighted by the block's area, the others weighted 0. The stratum is
 * the same offset (floor(u w), floor(v w')) in every block of widths w x w' (u, v uniform in
 * [0, 1), drawn per pixel), so each sample is chosen with probability 1 / its block's area and
 * the pixel's expected value is unchanged; the weights sum to S^2 in every pixel. When c divides
 * S the blocks are c x c (a lattice: one stratum in c x c, m^2 = (S / c)^2 reads); otherwise
 * they are floor(S / m) or ceil(S / m) wide, still one read per block, spread evenly over the
 * pixel. (Earlier rules: the lattice alone chose a varying count when c did not divide S; then
 * exact counts along the strata's raster order, which at 16 spp and c = 3 read two strata of
 * one column, so the pilot weighed only strides that divide S, and prime strata such as 25 or
 * 169 spp read every sample.) The caustic radiance barely changes within a pixel, so this costs
 * little noise and saves most of the estimates' time.
 * pm_caustic_weight gives sample k's weight (k = sy S + sx); S < c or c <= 1 reads every sample
 * (weight 1). pm_caustic_reads: m^2, the estimates a pixel makes. pm_caustic_factor: the factor
 * on the variance of the pixel's caustic part for samples independent within the pixel,
 * sum(area^2) / S^2 (c^2 when c divides S). */
double pm_caustic_weight(int strata, int c, int k, double u, double v);
int pm_caustic_reads(int strata, int c);
double pm_caustic_factor(int strata, int c);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PM_SAMPLE_H */
