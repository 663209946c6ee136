/* photon_sides.h: photon lookups that keep to the query's side of its surface.
 *
 * A density estimate at x reads the photons nearest x. Near a wall the nearest photons can lie
 * on the other side of it: the lower half of a box cut in two by an opaque partition shares its
 * side walls' planes with the lit upper half, a closed room standing on a lit floor shares the
 * floor's plane with the outside. Normals cannot tell such photons apart (they are on the same
 * plane, facing the same way), and a distance bound cannot either (the wall may be as thin as
 * a single quad). Only visibility can: a photon belongs to x's estimate only if light could
 * travel from where the photon landed to x without crossing a surface. This file applies that
 * rule where it changes the image:
 *
 *   side_visible     the visibility test. The segment joins the two points LIFTED off their
 *                    surfaces along their normals by a quarter of their distance (plus the
 *                    usual offset). Why lifted: two points on one smooth convex surface (a
 *                    sphere of radius R) see each other only through the surface itself, the
 *                    chord of length L passes L^2/(8R) below it; lifting both ends by L/4
 *                    clears any surface with R > L/2, so photons on one curved surface are
 *                    never cut off from each other. A wall between the points is still hit
 *                    unless it is lower than the lift (under L/4 high) or has a gap. The lift
 *                    stops halfway to the first surface above the point (its "free height",
 *                    one ray per photon, computed once), so a lifted end never pokes through a
 *                    shelf or a ceiling into another room.
 *   side_cache_build precomputed irradiance (Christensen) at a quarter of the global photons,
 *                    like pm_irradiance_build (same choice of photons, the same bias-corrected
 *                    disc estimate of k photons, photons from behind the photon's surface
 *                    skipped), but each estimate sums only the neighbours side_visible from the
 *                    photon. Why this holds: a neighbour hidden from photon i lies on another
 *                    surface as far as light is concerned, and its power never reached i's.
 *                    The search first takes the k nearest front-side photons and tests each
 *                    (k short shadow rays); only if one is hidden does it search again with the
 *                    test inside the search, so that the estimate still has k photons on its
 *                    own side (the radius then grows into the dark side, which holds none of
 *                    them: the same boundary bias as at any edge of a surface, low, never a
 *                    leak). Each precomputed photon keeps the radius^2 of its own estimate.
 *                    A CORNER: the search is a ball, so where another surface meets the
 *                    photon's (a floor and a wall) it also finds photons on that surface that
 *                    travelled toward this side (down and toward the wall), and a disc estimate
 *                    counted their power over this surface's disc: high within a radius of
 *                    every concave edge (+8.5% over that strip with constant irradiance,
 *                    tests/test_render_sides_corner.c), and in a dim room lit through a slit,
 *                    where the radii are a good part of the room, high nearly everywhere
 *                    (door_ajar +7% over 5 seeds at 1024 spp). So the estimate takes the k
 *                    nearest on its own surface (side_filter_shadow: normal within 45 degrees),
 *                    and when a photon of a surface facing another way lies inside their disc,
 *                    divides by the part of the disc on this side of every surface, as after a
 *                    wall (33 rays). An estimate with no such photon in its disc is as before,
 *                    bit for bit (the k nearest are the same photons). Where a
 *                    surface meets it at less than 45 degrees (a door beside its wall), the
 *                    plane rule of photon_corner.h keeps the estimate to x's plane.
 *                    Sparse estimates: one whose photons come from fewer than SIDE_MIN_PATHS
 *                    (8) distinct photon paths keeps radius^2 0, so no lookup returns it (the
 *                    module's own-radius test, dist2 < r2, never holds) and the caller
 *                    computes the light there instead. Why paths and not photons: the photons
 *                    of one path (an emitted photon storing a record at each diffuse bounce,
 *                    photon_maps.h PHOTON PATHS) are not independent; in a closed room they
 *                    land all over the same few walls, so an estimate of n photons from p
 *                    paths has the error of p samples (1/sqrt(p)), not of n. Why the rule
 *                    holds: the estimate is a sum over the paths that reached its disc, each
 *                    an independent sample, so it is as trustworthy as their number; with 8
 *                    or more its error is at most about 35%, and where many more are expected
 *                    (every lit part of a scene) the rule never bites. Where few paths reach a
 *                    region (a room lit through a pinhole: about 4 of 56,000 emitted get in),
 *                    an estimate is read only when, by chance, many came near, and then it
 *                    reads the region's light high over a disc as wide as the largest radius:
 *                    counting photons let 8 photons from 4 paths light pinhole_room's green
 *                    wall (walls +12%, photon seed 4); counting paths computes that light
 *                    instead (+0.6%). Every photon found counts, direct ones too (each the
 *                    first hit of its own path): they are independent samples of the disc
 *                    as well, and whether they came is not the indirect value's chance, so
 *                    counting them selects no estimate for reading high; counting indirect
 *                    photons only made 42,872 of sun_spheres' 50,000 estimates unreadable (an
 *                    open ground under the sun: 100 direct photons, a few indirect, all of
 *                    it read correctly before) and computed their light at every gather hit.
 *                    The rule needs no k: it holds as well for a distributed process's part
 *                    of an estimate, whose paths add up over the parts (render/mpi/lk_serve.c).
 *                    Fixed-radius estimates: where fewer than k photons lie within the cap
 *                    and the search covered its whole disc (no wall cut it short), the
 *                    estimate is the photons in it over its area, a fixed-radius estimate
 *                    (what progressive passes shrink;
 *                    README.md, "Progressive photon mapping"). Two rules keep it unbiased.
 *                    Its own photon is left out of the sum: the disc is centred on that
 *                    photon, so it is there whatever the density (the map's other photons
 *                    are as random given it), and counting it added one photon's power over
 *                    the area, 1/mu high where mu photons are expected. And the paths rule
 *                    above does not apply: a disc read only when enough paths came near is
 *                    read when its count, and so its value, is high. Measured by hand
 *                    (cornell_spheres and water_caustic, 96x96, passes started at
 *                    ppm_radius 1, pass 1 of 16 rendered alone, image mean against the
 *                    reference): +1.70% and +5.97% with both rules as they were, +1.11% and
 *                    +3.69% with the centre left out, +0.16% and +0.46% with both changes.
 *                    At the default caps (Christensen's radius, often the whole room)
 *                    estimates are k-nearest nearly everywhere, and the k-nearest ones keep
 *                    their centre and the paths rule (the k / (k - 0.5) area is their
 *                    correction). render-mpi's distributed estimates (lk_irradiance.c) sum
 *                    their parts' photons and paths and keep the paths rule for all.
 *                    Direct light: the values leave out the direct photons (first hits from
 *                    a light; they still count toward the k that set the radius), and the
 *                    caller computes y's direct light with a light sample instead. Why: direct
 *                    light has the sharpest edges of a scene (shadow boundaries), and a disc
 *                    estimate spreads them by its radius; where a region is lit only by light
 *                    bounced in past an edge (the floor under a shelf) that spread is all the
 *                    gather reads: +4.4% there over 8 photon seeds at 200,000 photons.
 *                    The values, their radii and the lookup structure belong to the module
 *                    (pm_irradiance_build_values, photonmap/irradiance.h); the cache adds the
 *                    free height of every photon of the global map, and whether each
 *                    precomputed photon lies on a flat surface (the plane rule's).
 *   side_cache_lookup what a final-gather ray reads at its hit y: pm_irradiance_lookup_if
 *                    with the module's normal rule at cos_min 0.7 (about 45 degrees; y within
 *                    the photon's own estimate radius) and side_visible from y as the caller's
 *                    rule, tried on the 8 nearest candidates, with photon_corner.h's plane
 *                    rule (a candidate off y's tangent plane is another surface's). Why: the
 *                    value of a photon behind a wall is the irradiance of another room. With
 *                    none, the lookup reports "none" (the caller computes y's light otherwise).
 *   side_filter_shadow the shadow-photon hint's search: photons on the query's own surface
 *                    only (the normal rule), below with its why.
 *   side_estimate    a map's radiance estimate read directly (the caustic map): neighbours off
 *                    the query's plane count only if side_visible sees them; below, with why.
 *
 * Threads: side_cache_build runs on OpenMP threads; a built cache is read-only and lookups
 * may run on any thread. The caller frees the cache with side_cache_free.
 */
#ifndef RENDER_PHOTON_SIDES_H
#define RENDER_PHOTON_SIDES_H

#include <stddef.h>
#include <stdint.h>

#include "photonmap/estimate.h"
#include "photonmap/irradiance.h"
#include "photonmap/kdtree.h"
#include "photonmap/photon.h"
#include "photon_mapping/photon_corner.h"
#include "photon_mapping/side_visibility.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Fewest distinct photon paths an estimate's photons come from for it to be read
 * ("Sparse estimates" above). */
#define SIDE_MIN_PATHS 8u
/* 1 if an estimate whose photons come from `paths` distinct photon paths may be looked up
 * (see "Sparse estimates" above); the build gives the others radius^2 0. */
int side_estimate_readable(unsigned paths);
/* The distinct paths among the photons nb[0..count) of a map whose path ids are path
 * (photon_maps.h, PHOTON PATHS; in the map's order), counted up to cap: the count, or cap if
 * there are at least cap (the readable rule needs no more than SIDE_MIN_PATHS, and parts
 * capped at it add up to at least SIDE_MIN_PATHS exactly when their full counts do). path NULL
 * (not known): every photon counts as a path of its own, which reads the estimate as often as
 * counting photons would. scratch: room for cap ids (read only with path). */
unsigned side_count_paths(const uint32_t *path, const pm_neighbor *nb, int count, unsigned cap, uint32_t *scratch);

/* The part of the disc of radius r around the surface point p (normal n) on p's side of every
 * surface (side_cache_build's area for an estimate that met a wall, at least 1/32): 33 rays.
 * For a distributed build (render/mpi/lk_irradiance.c) that combines such estimates. */
double side_disc_fraction(const scene *s, vec3 p, vec3 n, double r);

/* The photons side_cache_build precomputes: height >= 2 in the map's kd-tree
 * (pm_kdtree_height), neither leaves nor parents of leaves, about a quarter of them. */
#define SIDE_HEIGHT_QUARTER 2

typedef struct side_cache {
    pm_irradiance *irr; /* the values E with their radii^2 and the lookup (NULL when n == 0) */
    float *hfree;    /* the free height (side_free_height) of every photon of the global map */
    uint8_t *flat;   /* 1: the precomputed photon lies on a flat surface (side_surface_normal), by
                      * map index (NULL: none known, side_cache_from_records) */
    /* What a lookup's rule reads of the photon irr names (its index in the tree irr was built
     * over): hfree and flat themselves when that is the global map's tree (height
     * SIDE_HEIGHT_QUARTER), else own_hfree and own_flat, copied into the order of the tree over
     * the chosen photons alone (side_cache_build_at); look_flat NULL: none known. */
    const float *look_hfree;
    const uint8_t *look_flat;
    float *own_hfree;
    uint8_t *own_flat;
    int height;      /* the photons of height >= this in the global map's tree were precomputed */
    float *val, *r2v; /* their values and radii^2 by map index (side_cache_refine adds to them) */
    size_t quarter;  /* the photons of height >= SIDE_HEIGHT_QUARTER (what a quarter build takes) */
    size_t n;        /* photons precomputed */
    unsigned long long rays_first, rays_second; /* shadow rays of the build (first, second search) */
    size_t researched;                          /* estimates searched again (a neighbour was hidden) */
    size_t corners; /* estimates that met a corner (A CORNER above; render-mpi's count them as researched) */
    size_t sparse; /* estimates of too few photon paths to be looked up (see "Sparse estimates" above) */
    int indirect_only; /* 1: the values leave out direct photons (side_cache_build; see "Direct
                        * light" above): the caller adds y's direct light itself */
    /* A distributed render's lookups (render/mpi/lookup.c and lk_irradiance.c, partitioned maps: this process holds
     * only its part of the records): when set, side_cache_lookup returns remote(remote_user,
     * ...) instead of reading irr, which then holds this process's part alone (NULL: the
     * cache is read here, as always in one process). Not freed by side_cache_free. */
    int (*remote)(void *user, const scene *s, vec3 y, vec3 n, float max_dist2, float e[3]);
    void *remote_user;
} side_cache;

/* Build over the global map's kd-tree (records in tree order, n of them, with their path ids
 * in path, or NULL: see side_count_paths): k photons per estimate within radius^2 max_dist2.
 * 0, or a negative PM_E* code with a message. */
int side_cache_build(side_cache *c, const scene *s, const pm_kdtree *global, const pm_photon *ph,
                     const uint32_t *path, size_t n, unsigned k, float max_dist2, char *err, size_t errcap);
/* PRECOMPUTED POINTS FITTED TO THE RENDER (pm_fit.c, pm__irr_height). side_cache_build_at is
 * side_cache_build at the photons of height >= height in the global map's kd-tree (at least
 * SIDE_HEIGHT_QUARTER: side_cache_build itself, bit for bit; each height above halves them, so
 * 3 an eighth, 4 a sixteenth, in a balanced tree spread over the map as the quarter is). The
 * estimates are the same at every photon whatever the height (each is a function of the map
 * alone); a lookup reads the nearest precomputed one by the same rules, so fewer points move
 * the nearest value farther from the query, never change a value. side_cache_refine computes
 * the photons of height in [height, c->height) that c lacks, keeping those c has, and rebuilds
 * the lookup: a cache refined to a height equals one built there, bit for bit, for any thread
 * count (tests/test_render_sides.c). It does nothing when height >= c->height. Both return 0, or
 * a negative PM_E* code with a message (the cache freed). */
int side_cache_build_at(side_cache *c, const scene *s, const pm_kdtree *global, const pm_photon *ph,
                        const uint32_t *path, size_t n, unsigned k, float max_dist2, int height, char *err,
                        size_t errcap);
int side_cache_refine(side_cache *c, const scene *s, const pm_kdtree *global, const pm_photon *ph,
                      const uint32_t *path, size_t n, unsigned k, float max_dist2, int height, char *err,
                      size_t errcap);
void side_cache_free(side_cache *c);
/* A cache from m precomputed photons computed elsewhere (render-mpi gathers them from its
 * ranks): recs (power = E, RGBE; reordered in place into a kd-tree's order), their radii^2 r2
 * and free heights hfree, in recs' order. Lookups then read them as side_cache_lookup says. 0,
 * or a negative PM_E* code with a message. */
int side_cache_from_records(side_cache *c, pm_photon *recs, const float *r2, const float *hfree,
                            size_t m, char *err, size_t errcap);

/* Irradiance at the surface point y (unit normal n, the side the gather ray came from), read
 * from the cache within radius^2 max_dist2. Returns 1 and sets e, or 0 (none found: e = 0). */
int side_cache_lookup(const side_cache *c, const scene *s, vec3 y, vec3 n, float max_dist2,
                      float e[3]);
/* side_cache_lookup's search of this process's records (never remote), with y's free height hy
 * (side_free_height(s, y, n, sqrt(max_dist2) / 4)) given: 1 and e, and the answer's position
 * in pos (if not NULL), or 0 (none: e = 0). side_cache_lookup is this with hy computed. */
int side_cache_lookup_local(const side_cache *c, const scene *s, vec3 y, vec3 n, double hy,
                            float max_dist2, float e[3], float pos[3]);

/* Radiance estimates of a map read directly (the photon mapper's caustic map) that keep to the
 * query's side: side_estimate is pm_estimate (the same search, pm_filter_front and squash as
 * the options say, and the same core), but a neighbour that lies off the query's tangent plane
 * (by more than 1e-3 of its distance) counts only if side_visible_h sees it from the query
 * (the free heights of the map's photons are computed once, by side_map_init: one ray each).
 * Why: a photon off the query's plane may lie on another surface across a wall, and its
 * power reached that surface, not the query's: D's cage (a closed box of nearly-mirror walls
 * with a point light inside, standing 0.5 above a floor) has caustic photons on its bottom's
 * inner face, facing up like the floor below and travelling down, so the direction and normal
 * rules pass them and the floor read 0.0196 where nothing reaches it. When one is hidden, the
 * estimate takes SIDE_WIDEN x k candidates and keeps those on its side, as side_cache_build
 * does. Photons in the query's own plane are taken without a ray, so a caustic on a flat floor
 * costs nothing more; LIMIT: a wall standing on that plane between the query and a photon is
 * not seen by this rule (the same floor on both sides of a wall), only by the distance. */
typedef struct side_map {
    const scene *s;
    const pm_kdtree *t; /* the map's tree (records in tree order), or NULL: empty */
    float *hfree;       /* the free height of each record (side_free_heights) */
    size_t n;
    int in_plane_rays;  /* 1: a neighbour in the query's own plane is tested by a ray too (the
                         * global map shown directly: a floor runs under a wall into the lit room) */
} side_map;
/* For the tree t of n records in scene s (kept: it must outlive sm), estimates within radius^2
 * max_dist2 (the lift's cap). 0, or PM_ENOMEM with a message. side_map_free frees it (a zeroed
 * one too). */
int side_map_init(side_map *sm, const scene *s, const pm_kdtree *t, size_t n, float max_dist2, char *err,
                  size_t errcap);
void side_map_free(side_map *sm);
/* pm_estimate over sm's map at x (unit normal n, the side the viewer is on) keeping to x's side
 * (above). scratch: pm_estimate_scratch_bytes(o->k) bytes. PM_OK (res set; an estimate whose
 * every neighbour is hidden is 0, PM_EST_F_EMPTY), or a negative PM_E* code. Reentrant; it
 * allocates only when a neighbour is hidden. */
int side_estimate(const side_map *sm, const float x[3], const float n[3], const pm_estimate_options *o,
                  void *scratch, pm_estimate_result *res);
/* side_estimate's neighbour rule for callers that search themselves (render/mpi/lk_irradiance.c):
 * nb[0..found) are the k nearest that ko accepts within max_dist2, from sm's tree; returns how
 * many of them stay (in nb[0..), at most k, the k nearest on x's side among 4k candidates when
 * one of the first was hidden) and sets *limit to the radius^2 of the disc they cover when
 * fewer than k stay (max_dist2 otherwise), or PM_ENOMEM. */
int side_neighbours(const side_map *sm, const float x[3], const float n[3], const pm_knn_options *ko, unsigned k,
                    float max_dist2, pm_neighbor *nb, int found, float *limit);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PHOTON_SIDES_H */
