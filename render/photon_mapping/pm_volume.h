/* pm_volume.h: participating media in photon mapping ("--mode pm" and "--mode preview" on a
 * scene with a medium or a null surface): the volume photon maps and the ray marching of eye
 * rays and gather rays through media.
 *
 * MAPS (pmv_trace). The maps of a scene with media come from volume.h's tracer, not from
 * photon_trace: its global pass gives the global map (diffuse-surface photons, attenuated and
 * scattered by the media on their way) and the volume map, its caustic pass the caustic map
 * (L S+ D) and the volume caustic map (L S+ V), each pass run only if the plan asks for one of
 * its maps. The caustic pass is aimed by the projection maps (settings projection,
 * projection_cells) and stops after max(4 x the global pass's photons, 4M) emitted, whichever
 * target is missed (a wall lit through a smoke-filled glass gets few photons: the map keeps what
 * it stored, with its emitted count, and a message says so). Shadow photons are not used
 * (shadow rays carry the media's transmittance). The volume photons are split by kind into three kd-trees:
 *   multiple scattering  INDIRECT photons (and, without a volume caustic map, the global
 *                        pass's CAUSTIC ones): read while marching eye rays;
 *   volume caustics      the caustic pass's L S+ V photons, read at every march step of every
 *                        camera sample (full resolution, no stride);
 *   all                  every volume photon of the global pass, DIRECT included: read by
 *                        final-gather rays, which have no single-scattering term of their own.
 * DIRECT photons are left out of the eye march because single scattering is computed there
 * with shadow rays. Each of the three is split by the medium the photons scattered in, and an
 * estimate in medium m reads only m's photons (a smoke ball in fog does not borrow the fog's
 * photons at its rim). The maps are traced, or with load_photons loaded (the global, caustic
 * and per-medium volume files of photon_maps.h; pmv_trace then builds the trees from them).
 *
 * EYE RAYS (pmv_march). A segment of an eye ray inside medium m, of length T (a surface, or
 * where the ray leaves the scene's bounds), is marched in n = ceil(T / step) equal steps of
 * length dt = T / n at t_i = (i + u) dt with one random offset u per segment, which makes the
 * sum an unbiased estimate of the integral over [0, T]. At each point x (transmittance Tr from
 * the segment's start):
 *   L += Tr dt [ sigma_s * single(x) + S_ms(x) + S_caustic(x) ]
 * single(x) is one light sample with the HG phase function and the shadow segment's
 * transmittance (direct.h, direct_light_medium_mis), weighted by the balance heuristic against
 * ceil(n / 2) equiangular samples of the segment (Kulla and Fajardo 2012; direct.h, EQUIANGULAR
 * SAMPLING ALONG A SEGMENT), which are added to L: the stratified steps' density is n / T, and
 * where the segment passes close to a light (fog just under a lamp: 1 / dist^2) the
 * equiangular samples carry the light instead of a rare step that lands there. A ray 0.02 from
 * a point light: the march's spread 1/11 of the steps' alone; 0.3 from it, 1.3 times (test
 * media_single_scattering_march_matches_quadrature). S_ms and S_caustic are the volume radiance
 * estimates (pm_estimate_volume with sigma_s = 1, i.e. sum phase dPhi / (4/3 pi r^3): the light
 * scattered per unit length, HG phase per photon) of the two trees. The segment's
 * transmittance exp(-sigma_t T) multiplies what lies beyond it.
 *   With settings volume_beam (the default) the steps keep only the single scattering: the
 * two trees are read once per segment by beam estimates (pm_beam.h), the exact integral over
 * [0, T] of Tr times an estimate whose kernels are the photons' own balls. Why: on
 * volumetric_caustic (48x48, 16 spp) the k-nearest searches and their ball fractions at ~48
 * steps per camera sample were 93% of the render phase (pm_kdtree_knn 40%, pmv_ball_fraction
 * 14%); the beam estimate does one traversal per segment, takes each photon's ball fraction
 * once when the map is built, and adds no noise of its own.
 *
 * BOUNDARIES. Near the boundary of a medium (a wall, a glass, a null surface, an object in a
 * fog) part of the search ball lies outside the medium and holds no photons, so dividing by
 * the whole ball's volume reads low there, over a shell as thick as the radius; in a dense
 * medium seen from outside, all the light the camera gets comes from that shell. Each estimate
 * is therefore divided by the part of its ball (the radius it used: the k-th neighbour's, or
 * the search limit when fewer were found) that lies inside the medium, pmv_ball_fraction
 * (pm_ball.h): rays of length r in 14 directions (the 6 axes and the 8 diagonals) find the
 * nearby surfaces; each
 * hit gives the surface's tangent plane there (its geometric normal, and its distance h from x
 * along it, not along the ray), equal planes are counted once, and the part of the ball on x's
 * side of every plane is the fraction: one plane cuts off a cap of (1 - h/r)^2 (2 + h/r) / 4 of
 * the ball (exact); two or more are integrated as the mean of (rho / r)^3 over a 32 x 32 grid
 * of equal-area directions, rho the distance to the nearest plane along the direction (at most
 * r), exact for an edge or corner through x along the axes and within 0.5% of the fraction
 * elsewhere (tested against Monte Carlo, media_ball_fraction_slanted_and_curved: a cube rotated
 * by 0.6 rad, faces, edges and corners within 0.4%, where the old rule of six axis rays and caps
 * at the distance along the ray read -36% .. +15%). The rule holds because the photons are a
 * sample of the medium's in-scattered flux density only where the medium is: k photons in the
 * part f of the ball estimate the density k / (f 4/3 pi r^3). Its limits, all toward too little
 * correction (a fraction too large, an estimate too low) except the last:
 *   - a plane farther than 0.807 r can fall between the 14 directions (0.807 is the smallest
 *     cosine from any direction to the nearest of them); its cap is at most 2.6% of the ball;
 *   - a curved boundary is replaced by tangent planes at the hits, whose half-spaces hold a
 *     convex medium: inside a sphere of radius 1 with r = 0.5, 0.3 from its surface, +2.3%
 *     (the old rule +6.6%);
 *   - around the outside of an object's edge or corner (fog beside a block) the medium is the
 *     union of the half-spaces, not their intersection: there the fraction reads too small
 *     (as the old rule did), at worst the floor 1/8;
 *   - any surface counts as a boundary (a thin surface inside a medium is rare: the photons
 *     beyond it would be read with a slightly too large correction).

 * GATHER RAYS (pmv_gather). A final-gather ray gets one point per segment, drawn in [0, T]
 * with a density proportional to the mean-channel exp(-sigma_t t): its in-scattered light is
 * the "all" tree's estimate times Tr / pdf (unbiased for the integral of that estimate); the
 * segment's transmittance multiplies what lies beyond.
 *
 * RADIANCE INSIDE GLASS. The renderer's radiance does not change when a ray refracts (no n^2
 * factor, material.h), so inside an object of index n it is the physical radiance times
 * (n_0 / n)^2, n_0 the index around the lights (medium_ior). Photons carry physical power, so
 * an estimate in a medium inside a dielectric (smoke in a glass) is multiplied by
 * (n_0 / n)^2: 1 / 2.25 for glass of index 1.5 in air. Without it the smoke in a glass sphere
 * read 2.2 times the path tracer's radiance. Media bounded by null surfaces have n = n_0.
 * The factor is material_radiance_scale(n_0, n) (material.h, where the rule is written down);
 * surface photons get the same factor when they are stored (photon_walk.c keeps
 * the index around the light and the index the photon is in), so the caustic and global maps,
 * precomputed irradiance and final gather read the renderer's radiance at a diffuse surface
 * inside glass or under water too. Which n: pm_volume.c's pmv_index_scales reads it off the
 * interfaces (a refractive object's back side has its ior, its front side and the space
 * between objects n_0); a medium found on both sides of a refractive surface (a gas around a
 * glass and inside it), or any medium when a refractive object keeps the ray's medium, is
 * scaled per eye segment by the index scene_index_ahead (medium.h) finds there.
 *
 * STEP, k AND RADII, chosen from the densities:
 *   step   settings volume_step, else per medium min(1 / (4 max sigma_t), D / 64), D the
 *          diagonal of the scene's bounds (lights included): a quarter of the mean free path
 *          in dense media, where Tr changes fast, and 64 steps across the scene in thin ones,
 *          so light shafts and shadows are resolved;
 *   k      per tree: k_volume (multiple scattering, the all tree) or k_volume_caustic
 *          (settings), k0 below, unless the tree is sparse for its medium's density: when
 *          the typical radius r_typ(k0) (below) exceeds half the medium's mean free path
 *          mfp = 1 / max sigma_t, k = max(16, floor(k0 (mfp / 2 / r_typ(k0))^3)), the k whose
 *          typical radius is mfp / 2 (or 16 photons). The multiple scattering changes over a
 *          mean free path (it grows with depth below a lit boundary), and a ball that reaches
 *          deeper than that averages it: in a dense fog cube with 100,000 photons (k 50,
 *          r_typ 0.05, mfp 0.08) the image read +5% after the boundary rule (BOUNDARIES) and
 *          -6% without it; with this rule (k 24) +0.9%. A thin medium (mfp large against
 *          r_typ), or enough photons, keeps k0. Each estimate that ends at its k-th neighbour
 *          is multiplied by (k - 1) / k: for a Poisson cloud E[k / V_k] = rho k / (k - 1);
 *          at the search limit no factor;
 *   radius 2 r_typ for each tree, r_typ = cbrt(3 k V / (4 pi N)) the radius of a k-photon
 *          estimate at the tree's mean density (N photons in the box V that bounds them): a
 *          dense map (a thick medium, many photons) searches a small ball, a sparse one a
 *          large one, and an estimate in the dark part of a medium stops at twice the typical
 *          radius instead of gathering from far away. Each estimate's ball is that of its
 *          k-th neighbour, at most 2 r_typ.
 *
 * Threads: after pmv_trace, pmv_march and pmv_gather only read the state; each thread passes
 * its own scratch of pmv_scratch_bytes().
 */
#ifndef RENDER_PM_VOLUME_H
#define RENDER_PM_VOLUME_H

#include <stddef.h>

#include "photons/photon_maps.h"
#include "load/photon_settings.h"
#include "photonmap/kdtree.h"
#include "photon_mapping/plan.h"
#include "photon_mapping/pm_ball.h"
#include "photon_mapping/pm_beam.h"
#include "base/rng.h"
#include "scene/scene.h"

struct pm_sample_caustics; /* pm_sample.h */

#ifdef __cplusplus
extern "C" {
#endif

/* One tree of volume photons of one medium, its records (owned) and its search radius^2. */
typedef struct pmv_map {
    pm_kdtree *t;
    pm_photon *a;
    size_t n;
    float r2;
    unsigned k;  /* photons per estimate (STEP, k AND RADII) */
    pmv_beam beam; /* the eye trees' beam map (pm_beam.h), built by pmv_build_beams; empty: none */
} pmv_map;

typedef struct pmv_state {
    int on;                      /* the scene has a medium or a null surface */
    int quiet;                   /* pmv_trace prints no "Photons" line (the fit's first stage) */
    double caustic_cap_min;      /* the caustic pass's cap floor when above 0 and below
                                  * CAUSTIC_CAP_MIN (pm_preprocess.c, THE CAUSTIC PROBE) */
    int nmedia;
    pmv_map *ms, *caus, *all;    /* per medium (nmedia each): the three trees above */
    size_t n_ms, n_caus, n_all;  /* photons in all media */
    unsigned k_ms, k_caus;
    int boundary;                /* settings volume_boundary: BOUNDARIES below */
    int beam;                    /* settings volume_beam: EYE RAYS below */
    double *step;                /* per medium */
    double *n2_scale;            /* per medium: (n_lights / n_medium)^2, -1: per segment (RADIANCE below) */
    vec3 lo, hi;                 /* the scene's bounds, lights included */
    int st_steps, st_ms, st_caus, st_gather, st_beam, st_beam_photons;
} pmv_state;

/* Decide whether s needs the media code (v->on) and the steps; registers statistics. 0 or
 * PM_ENOMEM. */
int pmv_init(pmv_state *v, const scene *s, const photon_settings *c);
/* Trace the maps the plan asks for into m (global, caustic; no shadow map) and build the volume
 * trees; prints what it traced. 0, or a negative code with a message. */
int pmv_trace(pmv_state *v, const scene *s, const photon_settings *c, const render_plan *p,
              photon_maps *m, char *err, size_t errcap);
/* Build the beam maps (pm_beam.h) of the multiple-scattering and volume-caustic trees of every
 * medium, with their radii as they are now (after pm_fit.c's pm__pass_volume_radii scaled them), when settings
 * volume_beam is on; without it, or for an empty tree, none. 0 or PM_ENOMEM. */
/* The "Photons (scene with media)" line of the maps in v and m on stdout (pmv_trace prints it
 * unless v->quiet; the caller prints it for maps a quiet trace made and the render kept);
 * loaded_from: the directory the maps were loaded from, or NULL. */
void pmv_print_maps(const pmv_state *v, const scene *s, const photon_maps *m, const char *loaded_from);
int pmv_build_beams(pmv_state *v, const scene *s);
void pmv_free(pmv_state *v);
/* Bytes of scratch per thread. */
size_t pmv_scratch_bytes(const pmv_state *v);

/* The light scattered toward r.o by the part [0, tmax) of r in medium med (tmax may be INFINITY:
 * up to the scene's bounds), not multiplied by any throughput; *tr = its transmittance.
 * inscatter = 0 gives only *tr (no random numbers used). med < 0: 0 and *tr = 1. */
rgb pmv_march(const pmv_state *v, const scene *s, ray r, double tmax, int med, int inscatter, rng *g,
              void *scratch, rgb *tr);
/* pmv_march for an eye segment of a camera sample: the light it adds times beta and the
 * sample's volume weight vw (inscatter with vw 0: only *tr), tallied into pc (the sample
 * pilot's, pm_sample.h: the light, the counted BVH work, the beam photons crossed) unless
 * pc is NULL. */
rgb pmv_march_eye(const pmv_state *v, const scene *s, ray r, double tmax, int med, int inscatter, rgb beta,
                  double vw, rng *g, void *scratch, struct pm_sample_caustics *pc, rgb *tr);
/* The same for a final-gather ray: one point per segment from the "all" tree. */
rgb pmv_gather(const pmv_state *v, const scene *s, ray r, double tmax, int med, rng *g, void *scratch,
               rgb *tr);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PM_VOLUME_H */
