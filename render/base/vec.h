/* vec.h: the 3-vector, colour and ray types of the renderer, with their inline arithmetic.
 *
 * Geometry is computed in double precision: the Cornell box spans 555 units and the tests shoot
 * rays from 1e8 units away, and doubles make the intersection code robust there without
 * tricks. Colours (rgb) reuse the same type with x, y, z read as red, green, blue; radiance is
 * linear (no gamma) everywhere until the film writes a PNG.
 *
 * Everything here is a static inline function on values: no allocation, no state, thread-safe.
 */
#ifndef RENDER_VEC_H
#define RENDER_VEC_H

#include <math.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct vec3 {
    double x, y, z;
} vec3;

/* A colour: linear RGB radiance, power, reflectance or throughput. */
typedef vec3 rgb;

/* A ray o + t d for t in (0, tmax). d need not be normalized unless a function says so. */
typedef struct ray {
    vec3 o, d;
} ray;

static inline vec3 v3(double x, double y, double z) { return (vec3){x, y, z}; }
static inline vec3 v3s(double s) { return (vec3){s, s, s}; }
static inline vec3 v3_add(vec3 a, vec3 b) { return v3(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline vec3 v3_sub(vec3 a, vec3 b) { return v3(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline vec3 v3_mul(vec3 a, vec3 b) { return v3(a.x * b.x, a.y * b.y, a.z * b.z); }
static inline vec3 v3_scale(vec3 a, double s) { return v3(a.x * s, a.y * s, a.z * s); }
static inline vec3 v3_neg(vec3 a) { return v3(-a.x, -a.y, -a.z); }
/* a + b * s, the most common update in a path tracer. */
static inline vec3 v3_madd(vec3 a, vec3 b, double s) {
    return v3(a.x + b.x * s, a.y + b.y * s, a.z + b.z * s);
}
static inline double v3_dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline vec3 v3_cross(vec3 a, vec3 b) {
    return v3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline double v3_len2(vec3 a) { return v3_dot(a, a); }
static inline double v3_len(vec3 a) { return sqrt(v3_dot(a, a)); }
static inline vec3 v3_norm(vec3 a) {
    double l = v3_len(a);
    return l > 0 ? v3_scale(a, 1.0 / l) : a;
}
static inline double v3_maxc(vec3 a) { return fmax(a.x, fmax(a.y, a.z)); }
static inline double v3_maxabs(vec3 a) { return fmax(fabs(a.x), fmax(fabs(a.y), fabs(a.z))); }
static inline vec3 v3_min(vec3 a, vec3 b) { return v3(fmin(a.x, b.x), fmin(a.y, b.y), fmin(a.z, b.z)); }
static inline vec3 v3_max(vec3 a, vec3 b) { return v3(fmax(a.x, b.x), fmax(a.y, b.y), fmax(a.z, b.z)); }
static inline double v3_idx(vec3 a, int i) { return i == 0 ? a.x : i == 1 ? a.y : a.z; }
static inline int v3_isfinite(vec3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }
static inline int v3_iszero(vec3 a) { return a.x == 0 && a.y == 0 && a.z == 0; }
/* Rec. 709 luminance of a linear colour. */
static inline double rgb_lum(rgb c) { return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; }
static inline vec3 ray_at(ray r, double t) { return v3_madd(r.o, r.d, t); }

/* Mirror reflection of the incoming direction d about the normal n (n unit length). */
static inline vec3 v3_reflect(vec3 d, vec3 n) { return v3_madd(d, n, -2.0 * v3_dot(d, n)); }

/* An orthonormal basis (s, t, n) around the unit vector n (Duff et al. 2017, branchless). */
static inline void v3_basis(vec3 n, vec3 *s, vec3 *t) {
    double sign = copysign(1.0, n.z);
    double a = -1.0 / (sign + n.z);
    double b = n.x * n.y * a;
    *s = v3(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    *t = v3(b, sign + n.y * n.y * a, -n.y);
}

/* Offset a surface point p along its geometric normal n (unit) to the side of direction d, so
 * that a ray leaving p does not hit the surface it starts on. The offset grows with the point's
 * magnitude because the rounding error of a computed hit point does (it is a few ulps of the
 * largest coordinate); a fixed epsilon would be too big in a unit scene and too small at 1e6.
 * `floor` is the length the offset does not shrink below near the origin (where the point's
 * own coordinates are small but the ray that found it may have come from afar): a scene's
 * scene_offset (scene.h) passes a thousandth of the scene's size, so the offset scales with
 * the scene. v3_offset uses a floor of 1 (a scene of unit size). */
static inline vec3 v3_offset_floor(vec3 p, vec3 n, vec3 d, double floor_len) {
    double eps = 1e-9 * (floor_len + v3_maxabs(p)) * 64.0;
    return v3_madd(p, n, v3_dot(d, n) >= 0 ? eps : -eps);
}
static inline vec3 v3_offset(vec3 p, vec3 n, vec3 d) { return v3_offset_floor(p, n, d, 1.0); }

#ifdef __cplusplus
}
#endif
#endif /* RENDER_VEC_H */
