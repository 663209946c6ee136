/* importance.h: importance-driven photon emission: photons go where the camera sees (visual
 * importance, cf. Peter and Pietrek, "Importance driven construction of photon maps", 1998).
 *
 * WHY. A uniform emission sends photons in proportion to power alone. In a room lit through a
 * 10 x 10 hole (pinhole_room) about 4 of 200,000 global photons get in, and the room seen by
 * the camera has no map to read. Here the emission is steered toward the parts of each light's
 * emission space whose photons reach what the camera sees, and the photons' powers are
 * divided by the steering, so every estimate stays unbiased.
 *
 * EMISSION CELLS. A photon of light l leaves from light_sample_le(l, u), u in [0,1)^4. Each
 * light's u-space is cut into cells: area and sphere lights GA x GA cells over (u[0], u[1])
 * (the point on the light; u[0] also picks the side of a two-sided light) times GB x GB over
 * (u[2], u[3]) (the cosine-weighted direction); point and directional lights GA2 x GA2 over
 * (u[0], u[1]) (the direction, or the point on the disc). Uniform u carries equal power per
 * cell. There are IMP_LEVELS such grids, each with half the cells per side of the one before
 * (8 x 64, 4 x 32, 2 x 16 per side for area lights).
 *
 * IMPORTANCE. importance_build traces `paths` camera paths (uniform film positions, BSDF
 * sampling through mirrors and glass, up to IMP_DEPTH diffuse vertices, Russian roulette on
 * the throughput after the second). At every vertex with a diffuse branch it makes IMP_LIGHTS
 * light connections (light chosen by power, a uniform point on it, as next-event estimation
 * does): an unoccluded connection is a photon path the camera sees, and its contribution
 * (path throughput x BSDF x Le cos_l cos_x / r^2 / pdf, as luminance) is added to the emission
 * cell, at every level, of (that light point, the direction toward the vertex): the cell whose
 * photons would carry that light there. So I_v(l, c) estimates the image's share of light
 * arriving through cell c at the first few camera vertices (where the gather reads the map).
 * One connection's weight is capped at IMP_CLAMP times the mean, so a vertex next to a light
 * does not take every photon. The tables are sparse (only cells with importance), in
 * (light, cell) order. Why several levels: a fine cell that no connection happened to hit
 * would get only the defensive share, and its photons, where they matter, would carry up to
 * thousands of times the power of their neighbours; a coarser cell (16 finer ones) that a
 * connection hit covers it with a share of its own.
 *
 * THE EMISSION DENSITY (defensive mixture). With a the defensive fraction,
 *     p(l, u) = a p_l + (1 - a) / IMP_LEVELS sum_v I_v(l, c_v(u)) / sum I_v  x  N_{l,v}
 * (per unit u-volume; p_l the light's power share, N_{l,v} its number of cells at level v):
 * with probability a a photon is emitted as before (light by power, u uniform), otherwise a
 * level, then a cell of it in proportion to I_v, and u uniform in the cell. Every (l, u) of a
 * light with power keeps p >= a p_l > 0, so the estimate stays unbiased for any I, however
 * poor; a photon's power is P_l / (p(l, u) n_e), i.e. the uniform photon's power divided by
 * rel = p(l, u) / p_l (importance_rel). Where I is poor (few camera paths, a cell missed) the
 * cost is noise, never bias, and bounded: a photon carries at most 1 / a times the uniform
 * photon's power.
 *
 * LIMITS (when the table is not used). The table is used only when its coarsest cells cover
 * at least IMP_MIN_COVERAGE of the lights' power (importance.coverage); the plan prints that
 * decision with its evidence. Below it the camera sees light that leaves the lights through
 * a narrow part of their emission, such as a room lit through a 10 x 10 hole (pinhole_room:
 * 3.6%). Emission can aim at the hole, but not the light that enters it after a bounce in
 * the room outside (there: about a third of what the room stores), which the defensive
 * photons then carry at 1/a times the uniform power, a handful of them. Measured on
 * pinhole_room with the table used regardless of coverage: over 10 seeds (400,000 photons)
 * the inner room's floor stored 70-150 units of power from photons that came straight
 * through the hole, and 0 to 2.2 times as much again from photons that had bounced first,
 * one to three photons of up to 61 units each; pm images (3 seeds, 1024 spp, default maps)
 * read -18% to +83% (walls -25% to +171%) against the reference, where by power alone (4 seeds) they
 * read -1.9% to +2.2% (walls -2% to +37%). Steering the photons' bounces as well
 * (importance-driven scattering) would be needed there.
 *
 * DETERMINISM. Camera path j uses its own stream rng_stream(seed, j, IMP_STREAM); paths are
 * traced on all threads into fixed slots and reduced in slot order, so the cells and their
 * weights, and the photon maps made from them, are the same for any thread count.
 *
 * Ownership: importance_build fills *imp with malloc'd arrays; importance_free frees them. A
 * built table is read-only and may be sampled from any number of threads.
 */
#ifndef RENDER_IMPORTANCE_H
#define RENDER_IMPORTANCE_H

#include <stdint.h>

#include "base/rng.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

#define IMP_GA 8     /* area and sphere lights: finest cells per side over (u[0], u[1]) */
#define IMP_GB 64    /* and over the direction (u[2], u[3]) */
#define IMP_GA2 128  /* point and directional lights: finest cells per side over (u[0], u[1]) */
#define IMP_LEVELS 3 /* tables at 1, 1/2, 1/4 of the finest resolution */
#define IMP_DEPTH 4  /* camera vertices with light connections, per path */
#define IMP_LIGHTS 4 /* light connections per vertex */
#define IMP_CLAMP 32 /* one connection's weight is at most this many times the mean */
#define IMP_MIN_COVERAGE 0.1 /* steer only when the importance covers this share of the power */

/* One resolution's table: the cells with importance, in (light, cell) order. */
typedef struct imp_level {
    size_t ncells;
    int *light;     /* per cell: its light */
    uint64_t *cell; /* per cell: its index in the light's grid at this level */
    double *cdf;    /* ncells + 1 entries: normalized cumulative importance */
    size_t *first;  /* nlights + 1: cells of light l are first[l] .. first[l + 1] - 1 */
} imp_level;

typedef struct importance {
    int on;          /* 0: no camera path reached a light; emit uniformly */
    double a;        /* the defensive fraction */
    int nlights;
    imp_level lv[IMP_LEVELS];
    double *pl;      /* per light: its power share p_l (the scene's light_distrib) */
    /* Evidence, for the plan's line. */
    long paths;                 /* camera paths traced */
    unsigned long long vertices, connections, unoccluded; /* diffuse vertices, light samples,
                                                             unoccluded ones */
    size_t contributing;        /* connections that carry light (unoccluded, f > 0) */
    double share_top;           /* share of the importance in the largest 1% of the finest cells */
    double coverage;            /* share of the lights' power emitted into the coarsest cells
                                   that have importance */
} importance;

/* Trace `paths` camera paths of scene s (its camera and size) with streams of `seed` on
 * `threads` threads (0: OpenMP's default) and build the table with defensive fraction a
 * (0 < a <= 1). 0 (imp->on = 0 when no connection reached a light), or PM_ENOMEM. */
int importance_build(const scene *s, long paths, double a, uint64_t seed, int threads, importance *imp);
void importance_free(importance *imp);

/* Cells of light l's grid, and the cell of u (importance_build's indexing). */
uint64_t importance_ncells(const light *l);
uint64_t importance_cell(const light *l, const double u[4]);

/* Emit: choose a light and u[0..3] from the mixture with u0 (the choice, uniform in [0,1))
 * and h[0..3] (uniform in [0,1), e.g. Halton dimensions: the point inside the light's u-space
 * or inside the chosen cell). Returns the light; *rel = p(l, u) / p_l (divide the uniform
 * photon's power by it). With imp NULL or off: the scene's light_distrib and u = h, rel 1. */
int importance_sample(const importance *imp, const scene *s, double u0, const double h[4], double u[4],
                      double *rel);
/* p(l, u) / p_l for any (l, u) (1 with imp NULL or off). */
double importance_rel(const importance *imp, const scene *s, int l, const double u[4]);

/* A camera walk's steps, shared by importance_build's pilot and the port probe (ports_find.c).
 * camera_walk_hit: the surface ry meets (0: it escapes), its material, wo = -ry.d, and
 * *diffuse = 1 when the material has a diffuse branch that reflects. camera_walk_next: the next
 * segment from h, a BSDF sample of 3 numbers from g (ul, u1, u2), *beta times its weight, *ry
 * leaving from the side it goes to, *nside that side's normal; 0 when the sample fails. */
int camera_walk_hit(const scene *s, ray ry, hit *h, const material **m, vec3 *wo, int *diffuse);
int camera_walk_next(const scene *s, const material *m, const hit *h, vec3 wo, rng *g, rgb *beta, ray *ry,
                     vec3 *nside);

/* The inverse of light_sample_le (for tests and importance_build): for a light point p (on the
 * light's surface, or anything for point lights) and a direction d leaving it, the u[0..3]
 * that light_sample_le maps to p and d (area lights: u[0], u[1] from the barycentrics of p,
 * front or back side from d; directional: u[0], u[1] of p's place on the disc, d ignored;
 * spot: u[0], u[1] of d; infinite: u[0], u[1] of d and u[2], u[3] of p's place on d's disc).
 * 1, or 0 when no u gives d (d behind a one-sided light, outside a spot's cone). */
int importance_invert_le(const scene *s, int l, vec3 p, vec3 d, double u[4]);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_IMPORTANCE_H */
