/* integrator.h: the interface every rendering algorithm implements, and the mode registry.
 *
 * An integrator computes the radiance arriving at the camera along one ray. The renderer
 * (renderer.h) owns the image loop: tiles, threads, strata, random streams, the film and the
 * progress bar; it asks the integrator only for li(ray). So a new algorithm is one file:
 *
 *   static int my_create(integrator *it, const scene *s, char *err, size_t cap) {
 *       it->li = my_li; ...; return 0;
 *   }
 *   INTEGRATOR_REGISTER(my, "pm", "photon mapping (Jensen)", my_create)
 *
 * and `render --mode pm` selects it (the scene's "render.mode" sets the default). The path
 * tracer (pathtracer.c) registers "path".
 *
 * Life cycle, called by the renderer:
 *   create(it, scene)       set the hooks and it->data; no heavy work
 *   preprocess(it, scene)   optional; once, on the main thread, before any li (it may use
 *                           OpenMP itself): e.g. trace and balance photon maps
 *   thread_begin(it)        optional; per worker thread, returns that thread's scratch
 *   li(it, scene, ray, rng, id, scratch)   radiance along the camera ray; called
 *                           concurrently, so it must only read shared state; g is this
 *                           sample's own stream and id says which sample it is
 *   thread_end(it, scratch) optional
 *   begin_pass(it, scene, pass, seed)  optional; a render in passes (run/passes.h) calls
 *                           it on the main thread before each pass p >= 1 (pass 0 is what
 *                           preprocess made), between two passes' li calls, with the pass's
 *                           own seed: e.g. trace fresh photon maps with that seed and shrink
 *                           the radii (photonmapper.c: progressive photon mapping). An
 *                           integrator without it renders every pass alike but for the seed
 *   destroy(it)             optional; frees it->data
 * Failures return a negative PM_E* code with a message in err (preprocess, create).
 *
 * What a photon-mapping integrator finds ready-made:
 *   - scene.h: scene_intersect / scene_visible / scene_visible_dir; hit.ng is the unit
 *     geometric normal (not flipped toward the ray); scene->photon_mapping is the file's
 *     "photon_mapping" object, to read with json.h getters under the path "$.photon_mapping";
 *   - scene.h: light_sample_le() emits a photon ray (photon power = light.power / n emitted
 *     from that light); scene->light_distrib picks a light in proportion to its power;
 *   - material.h: material_weights() gives R, (1-R)T, (1-R)(1-T); material_sample() works
 *     for photons too (pass wo = -photon direction; wi is the scattered direction);
 *     material_is_specular / _diffuse / _emissive for planning;
 *   - rng.h: rng_stream(seed, photon_index, salt) is a per-photon stream;
 *   - stats.h: stats_register("Photons/...") at create time, so skipped work prints as 0;
 *   - progress.h: a reporter for the photon loop; vec.h: v3_offset() for new ray origins.
 */
#ifndef RENDER_INTEGRATOR_H
#define RENDER_INTEGRATOR_H

#include <stddef.h>
#include <stdio.h>

#include "base/rng.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Which camera sample li is computing: pixel y * width + x, sample k of count in that pixel,
 * in stratum (k % strata, k / strata) of a strata x strata grid, and the render's seed. An
 * integrator may use it to spread work over a pixel's samples in a fixed pattern (the photon
 * mapper estimates caustics at a stratified subset of them). */
typedef struct sample_id {
    uint64_t pixel, seed;
    int k, count, strata;
    int focused; /* the camera's focus aimed it (run/focus.h): its film point is not uniform
                  * in stratum k, so nothing may be drawn from that stratum in its place */
} sample_id;

typedef struct integrator integrator;
struct integrator {
    const char *name;
    void *data;
    int (*preprocess)(integrator *self, const scene *s, char *err, size_t errcap);
    void *(*thread_begin)(const integrator *self);
    rgb (*li)(const integrator *self, const scene *s, ray r, rng *g, const sample_id *id,
              void *scratch);
    void (*thread_end)(const integrator *self, void *scratch);
    void (*destroy)(integrator *self);
    int (*begin_pass)(integrator *self, const scene *s, int pass, uint64_t seed, char *err,
                      size_t errcap);
    /* NULL, or the openings (photon ports) whose footprints on the film the camera samples
     * may aim at (run/focus.h): their count, and *ports; called after preprocess. */
    int (*camera_ports)(const integrator *self, const scene *s, const port **ports);
    int in_passes; /* set by the caller before preprocess: the render runs in passes (its
                    * camera's spp is a pass's), so begin_pass follows */
};

typedef int (*integrator_create_fn)(integrator *it, const scene *s, char *err, size_t errcap);

void integrator_register(const char *name, const char *help, integrator_create_fn create);
/* Fill *it for mode name; 0, or PM_EINVAL with "unknown mode" and the list of modes. */
int integrator_create(const char *name, const scene *s, integrator *it, char *err, size_t errcap);
void integrator_destroy(integrator *it);
/* Print "  name   help" lines for --help. */
void integrator_list(FILE *f);

#define INTEGRATOR_REGISTER(id, name, help, create)                                  \
    __attribute__((constructor)) static void integrator__register_##id(void) {       \
        integrator_register(name, help, create);                                     \
    }

#ifdef __cplusplus
}
#endif
#endif /* RENDER_INTEGRATOR_H */
