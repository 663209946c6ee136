/* material.h: surface materials, Fresnel, and BSDF sampling and evaluation.
 *
 * Every material is one mixture of three branches (Jensen's model for photon tracing and the
 * path tracer alike):
 *
 *     specular reflection     with weight  R
 *     specular transmission   with weight  (1 - R) T
 *     diffuse reflection      with weight  (1 - R) (1 - T)
 *
 * R is either a constant ("specular": a number) or, when `fresnel` is set, the dielectric
 * Fresnel reflectance at the hit from the full s- and p-polarized equations for the indices on
 * both sides. T is the transparency. The diffuse branch is Lambertian, or Oren–Nayar when
 * sigma > 0. A caller picks ONE branch at random in proportion to its weight (so the weight
 * divided by the probability is 1 and only the branch's colour scales the throughput).
 *
 * The scene-file types map onto it:
 *   lambert      R = 0, T = 0, diffuse = reflectance
 *   oren_nayar   R = 0, T = 0, diffuse = reflectance, sigma (radians)
 *   mirror       R = 1 (tint = reflectance)
 *   dielectric   R = Fresnel(ior), T = 1 (glass: reflects R, refracts 1 - R)
 *   mix          any specular (number or "fresnel"), transparency, diffuse, sigma, ior
 * and any of them may have an emission (radiance Le, front side, or both when two_sided).
 *
 * Sides: the geometric normal ng of a hit says which side is "outside". A ray arriving on the
 * front side (dot(wo, ng) > 0) goes from the scene medium (index n_medium) into the material
 * (index ior); from the back side the indices swap. Opaque branches act on the side the ray
 * came from (two-sided shading).
 *
 * Refraction does not scale radiance by (n2/n1)^2 (the path tracer's convention): the
 * renderer's radiance is the physical radiance times (n_src / n)^2, n the index where it is
 * and n_src the index around the light it came from (medium_ior for lights in the scene
 * medium). Camera paths that enter and leave closed objects see the factors cancel, but a
 * photon carries physical power, conserved through an interface, so an estimate made from
 * photons inside a denser medium (a diffuse surface in glass or under water, smoke in a glass)
 * must be scaled by material_radiance_scale(n_src, n) = (n_src / n)^2 to be the renderer's
 * radiance: 1 / 2.25 in glass of index 1.5 lit from air. photon_trace.c and volume.c apply it
 * to every surface photon when it is stored (so the caustic and global maps, precomputed
 * irradiance and final gather all read it); pm_volume.c to volume estimates.
 *
 * Directions: wo points from the surface toward where the light goes (the viewer), wi toward
 * where it comes from; both unit length. All functions are pure and thread-safe.
 */
#ifndef RENDER_MATERIAL_H
#define RENDER_MATERIAL_H

#include "base/vec.h"

#ifdef __cplusplus
extern "C" {
#endif

/* MAT_NULL: an invisible interface (a medium's boundary): T = 1 with the index of the medium
 * around it, so every integrator passes straight through; medium.h says how media use it. */
enum { MAT_LAMBERT, MAT_OREN_NAYAR, MAT_MIRROR, MAT_DIELECTRIC, MAT_MIX, MAT_NULL };

typedef struct material {
    char name[64];
    int kind;            /* MAT_*: what the file said; the fields below are what counts */
    rgb diffuse;         /* reflectance (albedo) of the diffuse branch */
    double sigma;        /* Oren–Nayar roughness in radians; 0 = Lambert */
    double specular;     /* R when fresnel == 0 */
    int fresnel;         /* R = dielectric Fresnel reflectance for ior */
    rgb specular_tint;   /* colour of the specular reflection */
    double transparency; /* T */
    rgb transmit_tint;   /* colour of the transmission */
    double ior;          /* index of refraction of the material */
    rgb emission;        /* emitted radiance Le */
    int two_sided;       /* emits from both sides (default: front side only) */
} material;

/* Branches (lobes). */
enum { LOBE_REFLECT = 0, LOBE_TRANSMIT = 1, LOBE_DIFFUSE = 2, LOBE_COUNT = 3 };

/* Fresnel reflectance of unpolarized light for a dielectric interface: cos_i is the cosine of
 * the incidence angle (>= 0) in the medium of index n1, n2 is the other side. Returns 1 under
 * total internal reflection, 0 when n1 == n2. R = (rs^2 + rp^2) / 2 with
 * rs = (n1 cos_i - n2 cos_t)/(n1 cos_i + n2 cos_t), rp = (n2 cos_i - n1 cos_t)/(n2 cos_i + n1 cos_t). */
double fresnel_dielectric(double cos_i, double n1, double n2);

/* Refract the unit direction d (travelling toward the surface) through the unit normal n
 * (on the side d comes from, dot(d, n) < 0), with eta = n1 / n2. Returns 0 on total
 * internal reflection. */
int refract_dir(vec3 d, vec3 n, double eta, vec3 *out);

/* The index of refraction on the side wo is on, and on the other side. */
void material_indices(const material *m, vec3 wo, vec3 ng, double n_medium, double *n1, double *n2);

/* (n_src / n)^2: the factor from physical radiance (or photon power density) in a medium of
 * index n to the renderer's radiance, for light that left its source in a medium of index
 * n_src (see "Refraction" above). Exactly 1 when n == n_src; 1 if either is not > 0. */
double material_radiance_scale(double n_src, double n);

/* Branch weights w[LOBE_*] (summing to 1) for light leaving toward wo. */
void material_weights(const material *m, vec3 wo, vec3 ng, double n_medium, double w[LOBE_COUNT]);

/* The diffuse BRDF (Lambert or Oren–Nayar) for the normal n facing wo, without the branch
 * weight. Zero if wi is on the other side of the surface from wo. */
rgb material_diffuse_f(const material *m, vec3 n, vec3 wo, vec3 wi);

/* The full non-specular BSDF value: weight (1-R)(1-T) times the diffuse BRDF. The specular
 * branches are delta functions and contribute only through sampling. */
rgb material_f(const material *m, vec3 ng, double n_medium, vec3 wo, vec3 wi);

typedef struct bsdf_sample {
    vec3 wi;       /* sampled incoming direction (unit) */
    rgb weight;    /* f cos / pdf for the chosen branch, with weight/prob = 1 folded in */
    int lobe;      /* LOBE_* chosen */
    int tir;       /* 1 if a transmission turned into a total internal reflection */
} bsdf_sample;

/* Choose a branch with u_lobe and sample a direction with (u1, u2). Returns 0 if the chosen
 * branch absorbs (e.g. a black diffuse colour), 1 otherwise. */
int material_sample(const material *m, vec3 wo, vec3 ng, double n_medium, double u_lobe, double u1,
                    double u2, bsdf_sample *s);

/* Shading normals (smooth meshes, hit.ns in scene.h). ns only bends directions and cosines;
 * every side decision stays with the geometric normal ng. material_shading_side() is the
 * normal to shade with, turned to wo's side: ns, or ng where wo is on different sides of the
 * two (grazing views of a smooth mesh). The _shaded reflection and refraction use the shading
 * normal n_s but fall back to the geometric normal n_g (both on the side the ray comes from)
 * when the shaded direction would leave on the wrong side of the real surface.
 * material_sample_ns() is material_sample() with a shading normal: the same branch choice
 * (weights from ng), the directions and the cosine sampling from ns, and a direction below the
 * geometric surface is absorbed (returns 0). material_sample() is material_sample_ns() with
 * ns = ng, and with ns == ng the _shaded directions are the plain ones. */
vec3 material_shading_side(vec3 wo, vec3 ng, vec3 ns);
vec3 material_reflect_shaded(vec3 d, vec3 n_g, vec3 n_s);
int material_refract_shaded(vec3 d, vec3 n_g, vec3 n_s, double eta, vec3 *out);
int material_sample_ns(const material *m, vec3 wo, vec3 ng, vec3 ns, double n_medium, double u_lobe,
                       double u1, double u2, bsdf_sample *s);

/* Predicates for planning: can this material reflect or transmit specularly? Reflect
 * diffusely? Emit? */
int material_is_specular(const material *m);
int material_is_diffuse(const material *m);
int material_is_emissive(const material *m);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_MATERIAL_H */
