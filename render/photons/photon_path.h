/* photon_path.h: the state of one photon's walk that both photon tracers keep the same way,
 * photon_trace.c over surfaces and volume.c through media: how many bounces it may make, the
 * refraction chain that scales what it stores, the side of a surface it arrived on, the kind
 * of each stored photon, and whether the path-length budget cut it.
 *
 * KINDS. A photon's event (a store on a surface or, in a medium, at a scattering event) is
 * PM_KIND_DIRECT before any bounce, PM_KIND_CAUSTIC after one or more specular bounces and
 * nothing else (L S+ D, L S+ V), PM_KIND_INDIRECT after a diffuse bounce or a scattering
 * event. The global map has no caustic kind (photon_trace.h): there L S+ D is INDIRECT
 * (path_global_kind).
 *
 * REFRACTION CHAIN. A surface photon is stored with P (n_src / n_here)^2, the renderer's
 * radiance convention (material_radiance_scale, material.h), n_src the index around the light
 * (known at the first refraction) and n_here the index where the photon is; exactly P when it
 * is back in n_src. That is the product of (n1 / n2)^2 over its refractions when each starts
 * in the index the last one ended in; open surfaces can break that chain (two single glass
 * quads crossed front to back), and n_src takes the factor n1 / n_here of each such break.
 * Volume photons are not scaled (pm_volume.c scales their estimates per medium).
 *
 * Header only: the walks call these once per bounce.
 */
#ifndef RENDER_PHOTON_PATH_H
#define RENDER_PHOTON_PATH_H

#include "photonmap/photon.h"
#include "scene/material.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct photon_path {
    int depth;     /* bounces so far (surface bounces and scattering events) */
    int max_depth; /* the bounces allowed: max_depth, or max_bounces below it */
    int full_depth; /* the scene's max_depth (max_bounces below it cuts paths) */
    int specular;  /* a specular bounce so far */
    int scattered; /* a diffuse bounce or a scattering event so far */
    double n_src, n_here; /* the refraction chain (0: no refraction yet) */
    double aim; /* the product of its aimed bounces' weights so far (ports.h, BOUNCES); 1 at first */
} photon_path;

static inline photon_path path_start(int max_depth, int max_bounces) {
    photon_path p = {0, max_depth, max_depth, 0, 0, 0, 0, 1};
    if (max_bounces > 0 && max_bounces < max_depth) p.max_depth = max_bounces;
    return p;
}

/* A refraction from index n1 into n2 (not a total internal reflection). */
static inline void path_refract(photon_path *p, double n1, double n2) {
    if (!(p->n_src > 0)) p->n_src = n1;
    else if (n1 != p->n_here) p->n_src *= n1 / p->n_here; /* a broken chain */
    p->n_here = n2;
}

/* The factor of a surface photon's power (REFRACTION CHAIN). */
static inline double path_store_scale(const photon_path *p) {
    return material_radiance_scale(p->n_src, p->n_here);
}

/* The surface normal on the side the photon arrived at, wo pointing back along its travel. */
static inline vec3 path_arrival_normal(vec3 wo, vec3 ng) { return v3_dot(wo, ng) >= 0 ? ng : v3_neg(ng); }

/* The kind of an event now (KINDS); path_global_kind for the global map. */
static inline int path_kind(const photon_path *p) {
    return p->scattered ? PM_KIND_INDIRECT : p->specular ? PM_KIND_CAUSTIC : PM_KIND_DIRECT;
}
static inline int path_global_kind(const photon_path *p) {
    return path_kind(p) == PM_KIND_DIRECT ? PM_KIND_DIRECT : PM_KIND_INDIRECT;
}

/* Whether a photon still alive after its walk was cut by the path-length budget. */
static inline int path_cut(const photon_path *p) { return p->depth > p->max_depth && p->max_depth < p->full_depth; }

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PHOTON_PATH_H */
