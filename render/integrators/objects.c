/* objects.c: "--mode objects", an image of which scene object each pixel sees.
 *
 * Each sample returns (j, j^2, j) with j = i + 1, i being the index in "$.objects" of the
 * object its camera ray hits first (j = 0 when it hits nothing). The renderer averages the
 * samples of a pixel, so a pixel that sees one object alone keeps G = R^2 exactly, while on a
 * silhouette the mean of j^2 exceeds the square of the mean of j (strictly, by Jensen's
 * inequality), even when the mean of j happens to be a whole number. `render --compare ... --mask IDS.pfm --id I` uses such an image
 * to measure the mean radiance of one object (a wall, the floor) exactly and without its
 * edges; scripts/make-results.sh does this for docs/RESULTS.md.
 */
#include "integrators/integrator.h"
#include "base/stats.h"

static rgb objects_li(const integrator *self, const scene *s, ray r, rng *g, const sample_id *id,
                      void *scratch) {
    (void)self;
    (void)id;
    (void)g;
    (void)scratch;
    hit h;
    if (!scene_intersect(s, r, INFINITY, &h)) return v3s(0);
    stat_inc(STAT_PATH_VERTICES);
    double j = (double)scene_prim_object(s, h.prim) + 1;
    return v3(j, j * j, j);
}

static int objects_create(integrator *it, const scene *s, char *err, size_t errcap) {
    (void)s;
    (void)err;
    (void)errcap;
    it->li = objects_li;
    return 0;
}

INTEGRATOR_REGISTER(objects, "objects", "index + 1 of the scene object each pixel sees (region masks)",
                    objects_create)
