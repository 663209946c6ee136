/* shapes.h: the two kinds of primitive, spheres and triangles, and their ray intersections.
 *
 * Quads and meshes from the scene file become triangles at load time, so the accelerator
 * and the integrators only ever see these two. A triangle stores v0 and its edges e1, e2
 * (Möller–Trumbore needs exactly these) plus the unit geometric normal n = e1 x e2 / |...|,
 * which points to the "front" side (counter-clockwise winding seen from the front). A sphere's
 * normal points outward.
 *
 * Intersection functions return 1 and the distance *t when the ray o + t d hits the shape with
 * tmin < t < tmax, else 0. They are pure and thread-safe.
 *   - triangle: Möller–Trumbore; points exactly on an edge or a vertex count as hits (the
 *     barycentric tests are inclusive, widened by 1e-12), so a ray through a shared edge
 *     never leaks between two triangles.
 *   - sphere: the numerically stable form (Haines et al., Ray Tracing Gems ch. 7): the
 *     discriminant is computed from the distance of the centre to the ray line, and the two
 *     roots from q = -(b + sign(b) sqrt(disc)) as c/q and q/a, so neither a large sphere nor
 *     a distant origin loses the small root to cancellation. From inside, the far root hits.
 */
#ifndef RENDER_SHAPES_H
#define RENDER_SHAPES_H

#include "base/vec.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct triangle {
    vec3 v0, e1, e2; /* vertices v0, v0 + e1, v0 + e2 */
    vec3 n;          /* unit geometric normal, e1 x e2 normalized */
    double area;
    int mat;   /* index into scene.mats */
    int light; /* index into scene.lights if this triangle is a sampled area light, else -1 */
} triangle;

typedef struct sphere {
    vec3 c;
    double r;
    int mat;
    int light; /* index into scene.lights if the sphere emits (a sphere light), else -1 */
} sphere;

/* Build a triangle from three points; returns 0, or -1 if it is degenerate (zero area or
 * non-finite), judged relative to the edge lengths so tiny but valid triangles pass. */
int triangle_make(triangle *t, vec3 a, vec3 b, vec3 c, int mat);

int triangle_intersect(const triangle *tr, ray r, double tmin, double tmax, double *t,
                       double *u, double *v);
int sphere_intersect(const sphere *s, ray r, double tmin, double tmax, double *t);

/* A uniformly distributed point on the triangle (pdf 1/area). */
vec3 triangle_sample(const triangle *tr, double u1, double u2);

void triangle_bounds(const triangle *tr, vec3 *lo, vec3 *hi);
void sphere_bounds(const sphere *s, vec3 *lo, vec3 *hi);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_SHAPES_H */
