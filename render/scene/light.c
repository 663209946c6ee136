/* light.c: the spot light's falloff, its power's integral W and its emission direction; see
 * light.h. The direction is drawn from the falloff by the inverse of the distribution of cos
 * (closed form for the quartic, bisection for smoothstep), so every photon of a spot carries
 * the same power. Sampling the scene's lights (a point seen from a shading point, a ray of
 * light leaving one) reads the scene's shapes, so it is light_sample.c's, declared in
 * scene.h: this file stands under scene.c, which calls it, and includes no scene.h. */
#include "scene/light.h"

#include "base/sampling.h"

/* The falloff's profile g(delta) on [0, 1] and its integral G(delta) = int_0^delta g. */
static double spot_g(int falloff, double x) {
    return falloff == SPOT_QUARTIC ? (x * x) * (x * x) : x * x * (3 - 2 * x);
}
static double spot_G(int falloff, double x) {
    return falloff == SPOT_QUARTIC ? x * x * x * x * x / 5 : x * x * x * (1 - x / 2);
}

double light_spot_falloff(const light *l, vec3 d) {
    double c = v3_dot(d, l->dir);
    if (c < l->cos_total) return 0;
    if (c >= l->cos_start) return 1;
    return spot_g(l->falloff, (c - l->cos_total) / (l->cos_start - l->cos_total));
}

double light_spot_w(const light *l) {
    return (1 - l->cos_start) + (l->cos_start - l->cos_total) * spot_G(l->falloff, 1);
}

double light_spot_pdf(const light *l, vec3 d) {
    double w = light_spot_w(l);
    return w > 0 ? light_spot_falloff(l, d) / (2 * M_PI * w) : 0;
}

/* cos of the direction whose share of the spot's power below it (in cos) is u. */
static double spot_cos(const light *l, double u) {
    double band = l->cos_start - l->cos_total, t = u * light_spot_w(l), inner = band * spot_G(l->falloff, 1);
    if (t >= inner || !(band > 0)) return fmin(1, l->cos_start + (t - inner));
    double y = t / band, lo = 0, hi = 1; /* G(x) = y, G increasing on [0, 1] */
    if (l->falloff == SPOT_QUARTIC) return l->cos_total + band * fmin(1, pow(5 * y, 0.2));
    for (int k = 0; k < 60; k++) {
        double m = 0.5 * (lo + hi);
        if (spot_G(l->falloff, m) < y) lo = m;
        else hi = m;
    }
    return l->cos_total + band * 0.5 * (lo + hi);
}

vec3 light_spot_dir(const light *l, double u0, double u1) {
    double c = spot_cos(l, u0), r = sqrt(fmax(0, 1 - c * c)), phi = 2 * M_PI * u1;
    return sampling_to_world(v3(r * cos(phi), r * sin(phi), c), l->dir);
}

int light_spot_invert(const light *l, vec3 d, double *u0, double *u1) {
    double c = v3_dot(d, l->dir), band = l->cos_start - l->cos_total, w = light_spot_w(l);
    if (!(light_spot_falloff(l, d) > 0) || !(w > 0)) return 0;
    double below = c >= l->cos_start || !(band > 0)
                       ? band * spot_G(l->falloff, 1) + (c - l->cos_start)
                       : band * spot_G(l->falloff, (c - l->cos_total) / band);
    vec3 a, b;
    v3_basis(l->dir, &a, &b);
    double phi = atan2(v3_dot(d, b), v3_dot(d, a)) / (2 * M_PI);
    if (phi < 0) phi += 1;
    *u0 = fmin(fmax(below / w, 0), 0x1.fffffffffffffp-1);
    *u1 = fmin(phi, 0x1.fffffffffffffp-1);
    return 1;
}
