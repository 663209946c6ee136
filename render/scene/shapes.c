/* shapes.c: Möller–Trumbore triangles and numerically stable spheres; see shapes.h. */
#include "scene/shapes.h"

#include <float.h>
#include <math.h>

#include "base/sampling.h"

#define BARY_EPS 1e-12

/* |v| without overflow or underflow in the squares: v3_len where it is exact enough, else
 * scaled by the largest component. */
static double len_safe(vec3 v) {
    double l = v3_len(v), m = v3_maxabs(v);
    if ((isfinite(l) && (l > 0 || m == 0)) || !isfinite(m) || m < DBL_MIN) return isfinite(l) ? l : m;
    return m * v3_len(v3_scale(v, 1.0 / m));
}

int triangle_make(triangle *t, vec3 a, vec3 b, vec3 c, int mat) {
    t->v0 = a;
    t->e1 = v3_sub(b, a);
    t->e2 = v3_sub(c, a);
    t->mat = mat;
    t->light = -1;
    vec3 cr = v3_cross(t->e1, t->e2);
    /* Lengths without overflow in their squares: a triangle with a vertex at 1e200 (out of the
     * scene's range, which the loader reports with the coordinates, after a mesh file's
     * transform) was called degenerate here. Its area may still be infinite; such a triangle
     * never reaches a scene. */
    double len = len_safe(cr);
    t->area = 0.5 * len;
    t->n = len > 0 && isfinite(len) ? v3_scale(cr, 1.0 / len) : v3(0, 0, 0);
    if (!v3_isfinite(a) || !v3_isfinite(b) || !v3_isfinite(c)) return -1;
    /* |e1 x e2| = |e1||e2| sin(angle): degenerate when the sine is at rounding level. */
    double l1 = len_safe(t->e1), l2 = len_safe(t->e2);
    if (!(l1 > 0) || !(l2 > 0)) return -1;
    double sine = len_safe(v3_cross(v3_scale(t->e1, 1.0 / l1), v3_scale(t->e2, 1.0 / l2)));
    if (!(sine > 1e-12)) return -1;
    return 0;
}

int triangle_intersect(const triangle *tr, ray r, double tmin, double tmax, double *t,
                       double *u, double *v) {
    vec3 p = v3_cross(r.d, tr->e2);
    double det = v3_dot(tr->e1, p);
    if (det == 0.0) return 0; /* the ray lies in the triangle's plane or is parallel to it */
    double inv = 1.0 / det;
    vec3 s = v3_sub(r.o, tr->v0);
    double uu = v3_dot(s, p) * inv;
    /* BARY_EPS widens the inclusive edge tests by rounding level: plain Möller–Trumbore
     * lets about 1% of rays through a shared edge between two triangles (both see u+v a few
     * ulps above 1); the shared-edge test measures this. */
    if (uu < -BARY_EPS || uu > 1.0 + BARY_EPS) return 0;
    vec3 q = v3_cross(s, tr->e1);
    double vv = v3_dot(r.d, q) * inv;
    if (vv < -BARY_EPS || uu + vv > 1.0 + BARY_EPS) return 0;
    double tt = v3_dot(tr->e2, q) * inv;
    if (!(tt > tmin && tt < tmax)) return 0;
    *t = tt;
    if (u) *u = uu;
    if (v) *v = vv;
    return 1;
}

/* x + y exactly as hi + lo (Knuth's two-sum). */
static void two_sum(double x, double y, double *hi, double *lo) {
    double sum = x + y, yv = sum - x;
    *hi = sum;
    *lo = (x - (sum - yv)) + (y - yv);
}

/* |o - c|^2 - r^2 for a sphere much larger than |o| whose surface passes near o: the direct
 * form rounds o - c to an ulp of |c| (2048 at 1e19), so the height of o over the surface came
 * out wrong by that much and a ground sphere of radius 1e19 under a unit scene lit it 15% too
 * dark. Expanded as |o|^2 - 2 o.c + (|c|^2 - r^2), the last term summed from error-free
 * products (fma) stays exact where |c| ~ r, and the others round at |o| |c|, not |c|^2. */
static double big_sphere_c(vec3 o, vec3 c, double r) {
    double p[4] = {c.x * c.x, c.y * c.y, c.z * c.z, -(r * r)};
    double err = fma(c.x, c.x, -p[0]) + fma(c.y, c.y, -p[1]) + fma(c.z, c.z, -p[2]) - fma(r, r, p[3]);
    double hi = p[0], lo = 0, h2, l2;
    for (int k = 1; k < 4; k++) {
        two_sum(hi, p[k], &h2, &l2);
        hi = h2;
        lo += l2;
    }
    double k = hi + (lo + err); /* |c|^2 - r^2 */
    return (v3_dot(o, o) - 2.0 * v3_dot(o, c)) + k;
}

int sphere_intersect(const sphere *s, ray r, double tmin, double tmax, double *t) {
    vec3 f = v3_sub(r.o, s->c);
    double a = v3_dot(r.d, r.d);
    double b = v3_dot(f, r.d); /* half of the usual b */
    double c = v3_dot(f, f) - s->r * s->r;
    /* The origin near the surface (relative to r) and much nearer the world's origin than the
     * centre is: a huge sphere seen from a small scene (only then; the direct form is the
     * better one when o and c are close). */
    if (fabs(c) < 1e-3 * s->r * s->r && v3_maxabs(r.o) < 1e-3 * v3_maxabs(s->c))
        c = big_sphere_c(r.o, s->c, s->r);
    /* disc = b^2 - a c, computed as a (r^2 - |f - (b/a) d|^2) to avoid cancellation. */
    vec3 l = v3_madd(f, r.d, -b / a);
    double disc = a * (s->r * s->r - v3_dot(l, l));
    if (disc < 0) return 0;
    double q = -(b + copysign(sqrt(disc), b));
    double t0, t1;
    if (q == 0) {
        t0 = t1 = 0; /* origin on the sphere and ray tangent: no hit beyond tmin >= 0 */
    } else {
        t0 = c / q;
        t1 = q / a;
    }
    if (t0 > t1) {
        double tmp = t0;
        t0 = t1;
        t1 = tmp;
    }
    if (t0 > tmin && t0 < tmax) {
        *t = t0;
        return 1;
    }
    if (t1 > tmin && t1 < tmax) {
        *t = t1;
        return 1;
    }
    return 0;
}

vec3 triangle_sample(const triangle *tr, double u1, double u2) {
    double b1, b2;
    sample_triangle(u1, u2, &b1, &b2);
    return v3_add(tr->v0, v3_add(v3_scale(tr->e1, b1), v3_scale(tr->e2, b2)));
}

void triangle_bounds(const triangle *tr, vec3 *lo, vec3 *hi) {
    vec3 b = v3_add(tr->v0, tr->e1), c = v3_add(tr->v0, tr->e2);
    *lo = v3_min(tr->v0, v3_min(b, c));
    *hi = v3_max(tr->v0, v3_max(b, c));
}

void sphere_bounds(const sphere *s, vec3 *lo, vec3 *hi) {
    *lo = v3_sub(s->c, v3s(s->r));
    *hi = v3_add(s->c, v3s(s->r));
}
