/* scene.h: the scene: camera, materials, shapes, lights, settings, and its accelerator.
 *
 * Data flow: scene_load() (a later stage, load/scene_load.h) parses a JSON scene file
 * (format: data/scenes/README.md), checks every field and turns quads and meshes into
 * triangles; scene_prepare() (scene.c) then makes one area light per emissive triangle and
 * builds the BVH. After that the scene is immutable, and scene_intersect() / scene_visible()
 * may be called from any number of threads.
 *
 * Errors: a negative PM_E* code and a message in json_err (the loader's: load/scene_load.h).
 *
 * Extensions: the "photon_mapping" object of the file is checked by the loader against the
 * settings table (photon_settings_parse: known keys, types, ranges), not otherwise
 * interpreted; a copy is kept in scene.photon_mapping (NULL when absent) for the
 * photon-mapping code to read with the json.h getters (its path is "$.photon_mapping"). A
 * key the format does not know is an error anywhere in the file (json_check_keys), with the
 * nearest known key.
 *
 * Ranges: numbers that would break the arithmetic are refused with the supported range in
 * the message. Lengths (every coordinate, radius, the scene's size) are within
 * SCENE_LENGTH_MIN..SCENE_LENGTH_MAX: their squares and cubes (areas, light powers, the
 * volume of a closed mesh) stay far inside a double. Emission and a directional light's
 * irradiance are at most SCENE_RADIANCE_MAX: the image is stored in 32-bit floats (PFM, the
 * film), whose largest value is 3.4e38, so that leaves 8 orders of magnitude for light
 * concentrated by a lens. A point light's intensity gives I / d^2, which depends on the
 * scene's units, so its limit scales with the scene: the irradiance it gives at D, the larger
 * of the scene's bounding radius and the light's distance from the scene's centre, is at most
 * SCENE_RADIANCE_MAX (I <= 1e30 D^2, power <= 4 pi 1e30 D^2). A medium's sigma_a and sigma_s
 * are at most 1 / SCENE_LENGTH_MIN per unit length. A film pixel that still overflows is
 * counted ("Film/Non-finite pixels") and `render` warns. The scene reaches at most
 * SCENE_OFFSET_MAX bounding radii from the origin, and each object at most
 * SCENE_OBJECT_OFFSET_MAX of its own: ray offsets include 64e-9 of a point's coordinates
 * (vec.h), and farther out they stop being small against the scene or the object (a box 1.2e7
 * radii out read 17% dark in path tracing, also when a huge ground sphere made the scene's
 * radius large). Photon mapping stores positions and squared
 * distances in 32-bit floats: scene_check_photon_range() says whether a loaded scene is
 * within its narrower range (SCENE_PM_SIZE_MIN..SCENE_PM_SIZE_MAX, not too far from the
 * origin for its size, and light powers a photon can carry).
 *
 * Ownership: the scene owns all its arrays and the photon_mapping copy; scene_free()
 * releases them. A zeroed scene may be freed.
 */
#ifndef RENDER_SCENE_H
#define RENDER_SCENE_H

#include <cjson/cJSON.h>
#include <stdint.h>

#include "scene/bvh.h"
#include "scene/camera.h"
#include "base/json.h"
#include "scene/light.h"
#include "scene/material.h"
#include "scene/port.h"
#include "base/sampling.h"
#include "scene/shapes.h"
#include "base/vec.h"

#ifdef __cplusplus
extern "C" {
#endif

/* medium.h stands on this header (its queries carry rays through the scene): the scene holds
 * its media by pointer, and a file that reads them includes medium.h. */
struct medium;

#define SCENE_LENGTH_MAX 1e100  /* |coordinate|, radius */
#define SCENE_LENGTH_MIN 1e-100 /* the scene's bounding radius; a triangle's longest edge */
#define SCENE_RADIANCE_MAX 1e30 /* emission (W/m^2/sr), a directional light's irradiance */
#define SCENE_OFFSET_MAX 1e5     /* every mode: |coordinate| / bounding radius (ray offsets) */
#define SCENE_OBJECT_OFFSET_MAX 1e6 /* every mode: an object's |coordinate| / its own radius */
#define SCENE_PM_SIZE_MIN 1e-12 /* photon mapping: the scene's bounding radius */
#define SCENE_PM_SIZE_MAX 1e12
#define SCENE_PM_OFFSET_MAX 1e4 /* photon mapping: |coordinate| / bounding radius */
#define SCENE_PM_POWER_MAX 1e30 /* photon mapping: the total light power (photons are floats) */

enum { TONE_FILMIC, TONE_SRGB };

/* Settings from the file's "render" and "image" objects; the command line overrides them. */
typedef struct render_settings {
    int max_depth;       /* path length limit (bounces); default 64 */
    int rr_depth;        /* Russian roulette starts after this many bounces; default 3 */
    char mode[32];       /* integrator name, default "path" */
    uint64_t seed;       /* default 1 */
    int tone;            /* TONE_FILMIC (Hable) or TONE_SRGB; default filmic */
    double clip_percent; /* auto exposure: this % of pixels at or above clipping; default 1 */
    double exposure;     /* > 0: a fixed exposure multiplier instead of auto exposure */
    double time;         /* > 0: render in passes for this many seconds (render.time) */
    int pass_spp;        /* > 0: samples per pixel of each pass (render.pass_spp) */
} render_settings;

typedef struct scene {
    camera cam;
    material *mats;
    int nmats;
    triangle *tris;
    int ntris;
    sphere *spheres;
    int nspheres;
    int *tri_obj, *sphere_obj; /* index in $.objects of each triangle's / sphere's object */
    vec3 (*tri_ns)[3]; /* corner shading normals of triangles 0..ntri_ns-1 (smooth meshes), or NULL */
    int ntri_ns;
    light *lights;
    int nlights;
    distrib1d light_distrib; /* choose a light in proportion to its power (mean of RGB) */
    int env_light;           /* 1 + the index of the infinite light (light.h); 0: none */
    struct envmap *env_map;  /* its image (envmap.h; owned), NULL: a constant radiance */
    double medium_ior;       /* index of refraction of the space between objects; default 1 */
    struct medium *media;    /* participating media ($.media; medium.h), nmedia of them */
    int nmedia;
    int global_medium;       /* index in media of $.medium (between objects), or -1 */
    int camera_medium;       /* the medium the camera is in (found from the nearest surface) */
    int *obj_medium;         /* per object of $.objects: its interior_medium (back side), or -1 */
    int *obj_medium_out;     /* per object: its exterior_medium (front side), or NULL (all global) */
    unsigned char *obj_iface; /* per object: MEDIUM_IFACE_* (medium.h), or NULL (all legacy) */
    int *iface_report;       /* 1 int: an inconsistent interface was reported (medium.c) */
    int nobj;
    int has_null;            /* some surface has the "null" (invisible interface) material */
    port *ports;             /* photon ports ($.ports; port.h), nports of them, or NULL */
    int nports;
    double port_fraction;    /* $.port_fraction: the share of photons aimed through the ports */
    int find_ports;          /* $.find_ports: 1 (default) lets the plan look for ports (ports.h) */
    vec3 bounds_lo, bounds_hi;
    vec3 bsphere_c; /* bounding sphere of all geometry */
    double bsphere_r;
    double offset_floor; /* ray offsets (scene_offset) do not shrink below 64e-9 of this length:
                          * 1e-3 of bsphere_r, so they scale with the scene */
    bvh accel;
    render_settings settings;
    cJSON *photon_mapping; /* a copy of "$.photon_mapping", or NULL */
    char file[512];        /* the scene file as scene_load was given it (cut at 511 bytes), for
                            * messages ("render: FILE: ..."); "" for a scene from text */
} scene;

/* A ray-surface hit. */
typedef struct hit {
    double t;
    vec3 p;            /* hit point */
    vec3 ng;           /* unit geometric normal (front side / outward); not flipped to the ray */
    vec3 ns;           /* unit shading normal: a smooth mesh's interpolated corner normals, else
                        * ng; on ng's side. It only shades: every side decision uses ng */
    int prim;          /* primitive id: < ntris a triangle, else ntris + sphere index */
    int mat;           /* material index */
    double u, v;       /* triangle barycentrics */
} hit;

void scene_free(scene *s);
/* After the loader has filled the camera, materials, shapes and the point and directional
 * lights: the bounds and bounding sphere, one light per emissive triangle or sphere, every
 * light's power and the light distribution, and the BVH. 0, or a negative code with a
 * message in e (no geometry, a power too large to represent, out of memory). */
int scene_prepare(scene *s, json_err *e);
/* Is the loaded scene within the range photon mapping supports (see Ranges above)? 0, or
 * PM_EINVAL with a message that gives the range ("$.objects: the scene's bounding radius
 * 4.8e+21 is outside the range photon mapping supports, 1e-12 to 1e+12 ..."). */
int scene_check_photon_range(const scene *s, json_err *e);

/* Nearest hit along r with 0 < t < tmax. */
int scene_intersect(const scene *s, ray r, double tmax, hit *h);
/* Is the segment between surface points p (normal np) and q (normal nq) unblocked? Both ends
 * are offset off their surfaces; pass a zero normal for a point that is not on a surface. */
int scene_visible(const scene *s, vec3 p, vec3 np, vec3 q, vec3 nq);
/* Is the ray from surface point p (normal np) in direction d unblocked to infinity? */
int scene_visible_dir(const scene *s, vec3 p, vec3 np, vec3 d);

/* v3_offset with the scene's floor: the origin of a ray leaving surface point p (geometric
 * normal n) in direction d. Every new ray origin on a surface should come from here. */
static inline vec3 scene_offset(const scene *s, vec3 p, vec3 n, vec3 d) {
    return v3_offset_floor(p, n, d, s->offset_floor);
}

static inline const material *scene_material(const scene *s, const hit *h) {
    return &s->mats[h->mat];
}
/* The index in $.objects of the object that primitive prim (hit.prim) came from. */
static inline int scene_prim_object(const scene *s, int prim) {
    return prim < s->ntris ? s->tri_obj[prim] : s->sphere_obj[prim - s->ntris];
}
/* Is this primitive an area light in the light list (sampled by next-event estimation)? */
static inline int scene_prim_is_light(const scene *s, int prim) {
    return prim < s->ntris ? s->tris[prim].light >= 0 : s->spheres[prim - s->ntris].light >= 0;
}

/* ---- the scene's lights sampled (light_sample.c; the lights are light.h's) ---------------- */

/* Sample light number li as seen from p with (u1, u2). Returns 1 if the sample can carry
 * light (before the visibility test), 0 otherwise. */
int light_sample_li(const scene *s, int li, vec3 p, double u1, double u2, light_sample *ls);

/* A ray of light leaving light number li, for photon emission; u[0..3] uniform in [0,1).
 *   area:        a uniform point on the triangle and a cosine-weighted direction about its
 *                front normal (two-sided: u[0] < 0.5 picks the front, the rest the back);
 *   sphere:      the same with a uniform point on the sphere (front: the outside);
 *   point:       the light's position and a uniform direction;
 *   spot:        the light's position and a direction of density f / (2 pi W) (light_spot_pdf):
 *                u[0] gives cos by the inverse of its distribution, u[1] the angle about dir;
 *   infinite:    a uniform direction d (u[0], u[1], as sample_uniform_sphere; with an image,
 *                minus envmap_sample's direction) and a uniform point (u[2], u[3]) on the
 *                disc of radius R perpendicular to d, R before the bounding sphere's centre,
 *                travelling along d;
 *   directional: a uniform point on the disc of radius R (the scene's bounding sphere)
 *                perpendicular to the light, R in front of the scene, travelling along dir.
 * With these densities every emitted photon of light li carries power light.power / n_emitted
 * (for n_emitted photons from that light), times light_emit_weight. *p is the origin, *n the
 * surface normal at it (zero for point and directional lights: no offset needed), *d the unit
 * direction. */
void light_sample_le(const scene *s, int li, const double u[4], vec3 *p, vec3 *n, vec3 *d);

/* The radiance that a ray leaving the scene along d sees: the infinite light's, or 0. */
rgb light_env_radiance(const scene *s, vec3 d);

/* What a photon of light li leaving along d carries, per channel, relative to the equal share
 * light.power / n_emitted: 1 for every light but an infinite light with an image
 * (scene.env_map, envmap.h), whose photons are drawn by luminance and so carry each its own
 * colour (L / lum(L)) Sigma / integral. */
rgb light_emit_weight(const scene *s, int li, vec3 d);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_SCENE_H */
