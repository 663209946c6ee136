/* projmap.h: caustic projection maps: which emission directions of a light can reach a
 * specular surface (Jensen, "A practical guide to global illumination using photon maps",
 * eq. 2.2).
 *
 * Each light gets a G x G grid of cells over the two parameters of light_sample_le that set
 * the direction (a position on the disc for a directional light); a cell is active when its
 * bundle of rays, bounded conservatively by a cone (area, point) or a tube (directional), can
 * meet the bounding sphere of a specular primitive. Caustic photons are emitted only into
 * active cells, and each photon's power is scaled by the light's active fraction. A sphere
 * light's normal changes over its surface, so a cell bounds no cone: all its cells stay
 * active (no saving, no loss).
 *
 * Ownership: projmap_build_all allocates the array and the cells; projmap_free_all frees
 * them. A built map is read-only and may be sampled from any number of threads.
 */
#ifndef RENDER_PROJMAP_H
#define RENDER_PROJMAP_H

#include "base/rng.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct projmap {
    int G;       /* cells per side */
    int nactive; /* active cells */
    int *active; /* indices cy * G + cx of the active cells, nactive of them */
    double fraction; /* nactive / G^2 */
} projmap;

/* One map per light of s with G x G cells; G = 0 gives every light one always-active cell
 * (no projection). 0 with *out set, or PM_ENOMEM with *out NULL. */
int projmap_build_all(const scene *s, int G, projmap **out);
void projmap_free_all(projmap *pm, int n);

/* Which pair of light_sample_le's u[] the grid covers: 2 (u[2], u[3]: the direction) for area
 * lights, 0 (u[0], u[1]: the direction of a point light, the disc position of a directional
 * one) otherwise. */
int projmap_dim(const light *l);
/* Put a uniform point of an active cell of pm (picked by uc in [0,1), jittered with two
 * numbers from g) into u[projmap_dim(l)] and the next entry. */
void projmap_sample(const projmap *pm, const light *l, double uc, rng *g, double u[4]);

/* Light li's projection map with G x G cells (for tests): active[cy * G + cx] = 1 for the
 * active cells. Returns the number of active cells or a negative code. */
int projmap_cells(const scene *s, int li, int G, unsigned char *active);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PROJMAP_H */
