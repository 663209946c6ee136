/* test_render_media_proof.c: the shipped media scenes against oracles that do not share the
 * renderer's code.
 *
 * 1. The volumetric caustic (data/scenes/volumetric_caustic.json). A path-traced reference is
 *    hopeless there (seen from the fog, the lamp lies behind glass), so the energy is checked
 *    instead: the power that the focused beam deposits by first scattering in two boxes of
 *    fog along the beam (one before the focus, one after it), against a brute-force integral
 *    written here from the scene's numbers: lamp points and cosine-weighted directions, the
 *    black tube around the lamp, Beer's law in the fog, the glass sphere intersected and
 *    refracted exactly with unpolarized Fresnel weights (every reflected and refracted branch
 *    followed to 8 internal bounces), and, for each ray leaving the glass, the expected power
 *    of its first scattering event inside each box, Phi (sigma_s / sigma_t) (e^{-sigma_t t0} -
 *    e^{-sigma_t t1}) for the part [t0, t1] of the ray in the box. The photon tracer's answer
 *    is the sum of the powers of its volume-caustic photons (kind CAUSTIC: the first
 *    scattering event after specular bounces only) in each box.
 * 2. Equiangular sampling (medium.h, direct.h): the sampler against its own density, and the
 *    single scattering of a ray passing a point light in a fog, marched (pm_volume.c) and
 *    path-traced, against a quadrature written here.
 * 3. The boundary rule's ball fraction (pm_volume.h) at slanted and curved boundaries against
 *    Monte Carlo.
 * 4. cornell_fog and glass_of_smoke: photon mapping against long path-traced references that
 *    are committed (data/reference-media/: scripts/make-reference.sh at 64x64, copied; each
 *    .info holds the samples, the CPU time and the scene file's SHA-256, and a reference of
 *    another version of the scene is refused): region means within 5%, the image within 3%.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "../render/image/compare.h"
#include "../render/integrators/direct.h"
#include "../render/image/film.h"
#include "../render/scene/medium.h"
#include "../render/load/photon_settings.h"
#include "../render/photon_mapping/pm_volume.h"
#include "../render/base/rng.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"
#include "../render/photons/volume.h"

/* ---- 1. the volumetric caustic --------------------------------------------------------------- */

/* The scene's numbers (checked against the loaded scene in the test). */
#define VC_LAMP_Y 1.95   /* lamp: the square |x-1|, |z-1| <= VC_LAMP_H at this height, facing -y */
#define VC_LAMP_H 0.05
#define VC_LE 1000.0     /* its radiance */
#define VC_TUBE_Y0 1.65  /* the black tube: |x-1|, |z-1| <= VC_TUBE_H from here up to the lamp */
#define VC_TUBE_H 0.06
#define VC_SC_Y 1.2      /* glass sphere: centre (1, VC_SC_Y, 1), radius VC_SR, index VC_IOR */
#define VC_SR 0.25
#define VC_IOR 1.5
#define VC_SIGMA_S 0.3   /* the fog (grey) */
#define VC_SIGMA_A 0.02

typedef struct vc_box {
    double lo[3], hi[3];
} vc_box;

/* Two boxes on the beam: before the focus (about 0.45 above the floor) and after it. */
static const vc_box vc_boxes[2] = {{{0.9, 0.5, 0.9}, {1.1, 0.85, 1.1}}, {{0.85, 0.08, 0.85}, {1.15, 0.38, 1.15}}};

/* Unpolarized Fresnel reflectance from index n1 into n2 at incidence cosine ci (> 0); 1 under
 * total internal reflection. */
static double fresnel(double n1, double n2, double ci) {
    double s2 = (n1 / n2) * (n1 / n2) * (1 - ci * ci);
    if (s2 >= 1) return 1;
    double ct = sqrt(1 - s2);
    double rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct), rp = (n1 * ct - n2 * ci) / (n1 * ct + n2 * ci);
    return 0.5 * (rs * rs + rp * rp);
}

/* The part [t0, t1] of the ray o + t d (t > 0) inside box b; 0 if none. */
static int slab(const vc_box *b, const double o[3], const double d[3], double *t0, double *t1) {
    double lo = 0, hi = INFINITY;
    for (int k = 0; k < 3; k++) {
        if (d[k] == 0) {
            if (o[k] < b->lo[k] || o[k] > b->hi[k]) return 0;
            continue;
        }
        double a = (b->lo[k] - o[k]) / d[k], c = (b->hi[k] - o[k]) / d[k];
        if (a > c) {
            double x = a;
            a = c;
            c = x;
        }
        lo = fmax(lo, a);
        hi = fmin(hi, c);
    }
    *t0 = lo;
    *t1 = hi;
    return hi > lo;
}

/* Second (far) hit of the ray o + t d with the sphere when o is on or inside it, or the
 * first hit from outside (0 when the ray misses). */
static int sphere_hit(const double o[3], const double d[3], int inside, double *t) {
    double oc[3] = {o[0] - 1, o[1] - VC_SC_Y, o[2] - 1};
    double b = oc[0] * d[0] + oc[1] * d[1] + oc[2] * d[2];
    double c = oc[0] * oc[0] + oc[1] * oc[1] + oc[2] * oc[2] - VC_SR * VC_SR;
    double disc = b * b - c;
    if (disc <= 0) return 0;
    double q = sqrt(disc);
    *t = inside ? -b + q : -b - q;
    return *t > 1e-9;
}

/* Follow a ray that has just met the sphere at p (outside, direction d, power w), every branch
 * weighted by Fresnel, and add each box's expected first-scattering power of every ray that
 * leaves the glass. */
static void vc_glass(const double p[3], const double d[3], double w, double acc[2]) {
    double pos[3] = {p[0], p[1], p[2]}, dir[3] = {d[0], d[1], d[2]};
    double n[3] = {(p[0] - 1) / VC_SR, (p[1] - VC_SC_Y) / VC_SR, (p[2] - 1) / VC_SR};
    double ci = -(dir[0] * n[0] + dir[1] * n[1] + dir[2] * n[2]);
    double R = fresnel(1, VC_IOR, ci);
    /* the reflected branch leaves at once */
    double rd[3];
    for (int k = 0; k < 3; k++) rd[k] = dir[k] + 2 * ci * n[k];
    for (int b = 0; b < 2; b++) {
        double t0, t1;
        if (slab(&vc_boxes[b], pos, rd, &t0, &t1))
            acc[b] += w * R * VC_SIGMA_S / (VC_SIGMA_S + VC_SIGMA_A) *
                      (exp(-(VC_SIGMA_S + VC_SIGMA_A) * t0) - exp(-(VC_SIGMA_S + VC_SIGMA_A) * t1));
    }
    /* the refracted branch, then internal bounces */
    double eta = 1 / VC_IOR, ct = sqrt(1 - eta * eta * (1 - ci * ci));
    for (int k = 0; k < 3; k++) dir[k] = eta * dir[k] + (eta * ci - ct) * n[k];
    w *= 1 - R;
    for (int bounce = 0; bounce < 8 && w > 0; bounce++) {
        double t;
        if (!sphere_hit(pos, dir, 1, &t)) return;
        for (int k = 0; k < 3; k++) pos[k] += t * dir[k];
        for (int k = 0; k < 3; k++) n[k] = (pos[k] - (k == 1 ? VC_SC_Y : 1)) / VC_SR;
        double c = dir[0] * n[0] + dir[1] * n[1] + dir[2] * n[2]; /* > 0: leaving */
        double Ri = fresnel(VC_IOR, 1, c);
        if (Ri < 1) {
            double e2 = VC_IOR, ctt = sqrt(1 - e2 * e2 * (1 - c * c)), od[3];
            for (int k = 0; k < 3; k++) od[k] = e2 * dir[k] + (ctt - e2 * c) * n[k];
            for (int b = 0; b < 2; b++) {
                double t0, t1;
                if (slab(&vc_boxes[b], pos, od, &t0, &t1))
                    acc[b] += w * (1 - Ri) * VC_SIGMA_S / (VC_SIGMA_S + VC_SIGMA_A) *
                              (exp(-(VC_SIGMA_S + VC_SIGMA_A) * t0) - exp(-(VC_SIGMA_S + VC_SIGMA_A) * t1));
        }
        }
        for (int k = 0; k < 3; k++) dir[k] -= 2 * c * n[k];
        w *= Ri;
    }
}

/* A small generator of its own (splitmix64), so the oracle shares nothing with render/. */
static double vc_rand(uint64_t *s) {
    uint64_t z = (*s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return (double)(z >> 11) * 0x1.0p-53;
}

/* The brute-force integral: n stratified rays (lamp point and direction), the power of each
 * box and its standard error. */
static void vc_oracle(long n_side, double mean[2], double se[2]) {
    double phi = VC_LE * M_PI * (2 * VC_LAMP_H) * (2 * VC_LAMP_H), st = VC_SIGMA_S + VC_SIGMA_A;
    double s1[2] = {0, 0}, s2[2] = {0, 0};
    long n = n_side * n_side;
    uint64_t seed = 12345;
    for (long i = 0; i < n; i++) {
        /* strata over the direction (the sharp part: tube and sphere), the point at random */
        double u1 = ((double)(i / n_side) + vc_rand(&seed)) / (double)n_side;
        double u2 = ((double)(i % n_side) + vc_rand(&seed)) / (double)n_side;
        double o[3] = {1 - VC_LAMP_H + 2 * VC_LAMP_H * vc_rand(&seed), VC_LAMP_Y,
                       1 - VC_LAMP_H + 2 * VC_LAMP_H * vc_rand(&seed)};
        double r = sqrt(u1), a = 2 * M_PI * u2;
        double d[3] = {r * cos(a), -sqrt(fmax(0, 1 - u1)), r * sin(a)};
        double acc[2] = {0, 0};
        double tb = (VC_LAMP_Y - VC_TUBE_Y0) / -d[1];
        double xb = o[0] + tb * d[0], zb = o[2] + tb * d[2];
        double t;
        if (fabs(xb - 1) <= VC_TUBE_H && fabs(zb - 1) <= VC_TUBE_H && sphere_hit(o, d, 0, &t)) {
            double p[3] = {o[0] + t * d[0], o[1] + t * d[1], o[2] + t * d[2]};
            vc_glass(p, d, phi * exp(-st * t), acc);
        }
        for (int b = 0; b < 2; b++) {
            s1[b] += acc[b];
            s2[b] += acc[b] * acc[b];
        }
    }
    for (int b = 0; b < 2; b++) {
        mean[b] = s1[b] / (double)n;
        se[b] = sqrt(fmax(0, s2[b] / (double)n - mean[b] * mean[b]) / (double)n);
    }
}

static int in_box(const vc_box *b, const float p[3]) {
    for (int k = 0; k < 3; k++)
        if (p[k] < b->lo[k] || p[k] > b->hi[k]) return 0;
    return 1;
}

/* Oracle: the brute-force integral above. vol_trace's volume-caustic photons in each box must
 * sum to its power within 4 combined standard errors plus 0.5% (the RGBE photon power rounds
 * each photon by up to 0.4%). Each path stores at most one CAUSTIC photon, so the photon sum's
 * variance is sum p_i^2 - (sum p_i)^2 / N, exactly. The scene's numbers used by the oracle
 * are checked against the loaded scene first. */
TEST(media_volumetric_caustic_energy) {
    char path[2048];
    snprintf(path, sizeof path, "%s/data/scenes/volumetric_caustic.json", pm_test_source_dir());
    scene s;
    json_err e;
    ASSERT_MSG(scene_load(&s, path, &e) == 0, "%s", e.msg);
    /* the oracle's constants are the scene's */
    ASSERT_EQ_INT(s.nspheres, 1);
    EXPECT_NEAR(s.spheres[0].r, VC_SR, 1e-12);
    EXPECT_NEAR(s.spheres[0].c.y, VC_SC_Y, 1e-12);
    EXPECT_NEAR(s.mats[s.spheres[0].mat].ior, VC_IOR, 1e-12);
    ASSERT_EQ_INT(s.nmedia, 1);
    EXPECT_NEAR(s.media[0].sigma_s.y, VC_SIGMA_S, 1e-12);
    EXPECT_NEAR(s.media[0].sigma_a.y, VC_SIGMA_A, 1e-12);
    double phi = 0;
    for (int i = 0; i < s.nlights; i++) phi += s.lights[i].power.y;
    EXPECT_NEAR(phi, VC_LE * M_PI * 4 * VC_LAMP_H * VC_LAMP_H, 1e-9);
    if (pm_test_failed()) {
        scene_free(&s);
        return;
    }

    double om[2], ose[2];
    vc_oracle(PM_TEST_SANITIZED ? 600 : 2000, om, ose);

    uint64_t n = PM_TEST_SANITIZED ? 500000 : 4000000;
    vol_photons vp;
    ASSERT_EQ_INT(vol_trace(&s, n, 21, 100, &vp), 0);
    double sum[2] = {0, 0}, sq[2] = {0, 0};
    long cnt[2] = {0, 0}, other = 0;
    for (size_t i = 0; i < vp.count; i++) {
        const pm_photon *p = &vp.photons[i];
        float pw[3];
        pm_rgbe_decode(p->power, pw);
        for (int b = 0; b < 2; b++) {
            if (!in_box(&vc_boxes[b], p->pos)) continue;
            if (pm_photon_kind(p) != PM_KIND_CAUSTIC) {
                other++;
                continue;
            }
            sum[b] += pw[1];
            sq[b] += (double)pw[1] * pw[1];
            cnt[b]++;
        }
    }
    free(vp.photons);
    scene_free(&s);
    for (int b = 0; b < 2; b++) {
        double se = sqrt(fmax(0, sq[b] - sum[b] * sum[b] / (double)n));
        double tol = 4 * sqrt(se * se + ose[b] * ose[b]) + 0.005 * om[b];
        printf("    box %d (%s the focus): oracle %.5g W (+-%.2f%%), photons %.5g W (%ld photons, +-%.2f%%): %+.2f%%, "
               "tolerance %.2f%%\n", b, b ? "after" : "before", om[b], 100 * ose[b] / om[b], sum[b], cnt[b],
               100 * se / om[b], 100 * (sum[b] / om[b] - 1), 100 * tol / om[b]);
        EXPECT_MSG(om[b] > 0 && cnt[b] > 1000, "box %d: oracle %g, %ld photons", b, om[b], cnt[b]);
        EXPECT_MSG(fabs(sum[b] - om[b]) <= tol, "box %d: photons %g W against the integral %g W (%+.2f%%, tolerance %.2f%%)",
                   b, sum[b], om[b], 100 * (sum[b] / om[b] - 1), 100 * tol / om[b]);
    }
    printf("    (%ld non-caustic photons in the boxes: multiple scattering, not counted)\n", other);
}

/* ---- 2. equiangular sampling: single scattering from a point light ------------------------ */

/* Adaptive Simpson of the equiangular pdf over [a, b] (the oracle of the CDF test). */
static double eq_simpson(vec3 o, vec3 d, double t0, double t1, vec3 y, double a, double b, double fa, double fm,
                         double fb, double whole, int depth) {
    double m = (a + b) / 2, lm = (a + m) / 2, rm = (m + b) / 2;
    double flm = medium_equiangular_pdf(o, d, t0, t1, y, lm), frm = medium_equiangular_pdf(o, d, t0, t1, y, rm);
    double left = (m - a) / 6 * (fa + 4 * flm + fm), right = (b - m) / 6 * (fm + 4 * frm + fb);
    if (depth <= 0 || fabs(left + right - whole) < 1e-12) return left + right + (left + right - whole) / 15;
    return eq_simpson(o, d, t0, t1, y, a, m, fa, flm, fm, left, depth - 1) +
           eq_simpson(o, d, t0, t1, y, m, b, fm, frm, fb, right, depth - 1);
}

/* Oracle: the definition of a density. For a light point y at several distances from the line
 * (0.3, 0.01, behind the start, beyond the end, an infinite end): the sampler's returned pdf is
 * medium_equiangular_pdf at the t it drew, t stays in [t0, t1], and the integral of the pdf from
 * t0 to the t drawn for u (adaptive Simpson in t, with no change of variable) is u within 1e-6:
 * the sampler inverts the CDF of the density it reports. Outside [t0, t1] the pdf is 0, and a
 * point on the line itself still gives finite densities. */
TEST(media_equiangular_sampler_inverts_its_cdf) {
    vec3 o = v3(0.1, -0.2, 0.3), d = v3_norm(v3(0.3, 0.4, 1));
    struct {
        vec3 off; /* y = o + off.z d + off.x (a unit vector perpendicular to d) */
        double t0, t1;
    } c[] = {
        {{0.3, 0, 1.0}, 0, 3}, {{0.01, 0, 1.5}, 0.2, 3}, {{0.5, 0, -1.0}, 0, 2}, {{0.2, 0, 5.0}, 0, 2}, {{0.3, 0, 1.0}, 0, INFINITY},
    };
    vec3 perp = v3_norm(v3_cross(d, v3(1, 0, 0)));
    for (size_t i = 0; i < sizeof c / sizeof c[0]; i++) {
        vec3 y = v3_add(o, v3_add(v3_scale(d, c[i].off.z), v3_scale(perp, c[i].off.x)));
        double worst = 0;
        for (int k = 1; k < 20; k++) {
            double u = k / 20.0, t, pdf = medium_equiangular_sample(o, d, c[i].t0, c[i].t1, y, u, &t);
            EXPECT_MSG(pdf > 0 && t >= c[i].t0 && t <= c[i].t1, "case %zu u %g: t %g pdf %g", i, u, t, pdf);
            EXPECT_NEAR(pdf, medium_equiangular_pdf(o, d, c[i].t0, c[i].t1, y, t), 1e-12 * pdf);
            double fa = medium_equiangular_pdf(o, d, c[i].t0, c[i].t1, y, c[i].t0);
            double fb = medium_equiangular_pdf(o, d, c[i].t0, c[i].t1, y, t);
            double fm = medium_equiangular_pdf(o, d, c[i].t0, c[i].t1, y, (c[i].t0 + t) / 2);
            double cdf = eq_simpson(o, d, c[i].t0, c[i].t1, y, c[i].t0, t, fa, fm, fb, (t - c[i].t0) / 6 * (fa + 4 * fm + fb), 40);
            worst = fmax(worst, fabs(cdf - u));
        }
        printf("    case %zu: distance %.2f, closest approach %.2f, [%g, %g]: worst |CDF(t(u)) - u| %.2e\n", i, c[i].off.x,
               c[i].off.z, c[i].t0, c[i].t1, worst);
        EXPECT_MSG(worst < 1e-6, "case %zu: CDF off by %.3g", i, worst);
        EXPECT_NEAR(medium_equiangular_pdf(o, d, c[i].t0, c[i].t1, y, c[i].t0 - 0.1), 0, 0);
        if (isfinite(c[i].t1)) EXPECT_NEAR(medium_equiangular_pdf(o, d, c[i].t0, c[i].t1, y, c[i].t1 + 0.1), 0, 0);
    }
    /* y on the line, inside the interval */
    double t, pdf = medium_equiangular_sample(o, d, 0, 2, v3_add(o, d), 0.3, &t);
    EXPECT_MSG(pdf > 0 && isfinite(pdf) && t >= 0 && t <= 2, "y on the line: t %g pdf %g", t, pdf);
    EXPECT_NEAR(medium_equiangular_sample(o, d, 1, 1, v3_add(o, d), 0.3, &t), 0, 0);
}

/* A point light of intensity I at y and a ray o + t d in a homogeneous medium (RGB sigma_s,
 * sigma_t, HG g), nothing else: the single scattering toward o along [0, T],
 *   L = int_0^T e^{-sigma_t t} sigma_s p_HG(dot(d, w)) I e^{-sigma_t r} / r^2 dt,
 * r = |y - o - t d|, w = (y - x) / r. Integrated by Simpson's rule in the angle theta =
 * atan((t - delta) / D) seen from y, where dt / r^2 = dtheta / D and the integrand is smooth
 * (HG and Beer's law written out here, not the renderer's). */
static void ss_quadrature(vec3 o, vec3 d, double T, vec3 y, rgb I, rgb ss, rgb st, double g, double out[3]) {
    vec3 oy = v3_sub(y, o);
    double delta = v3_dot(oy, d), D = v3_len(v3_sub(oy, v3_scale(d, delta)));
    double th0 = atan2(-delta, D), th1 = isfinite(T) ? atan2(T - delta, D) : M_PI / 2;
    int n = 200000;
    double h = (th1 - th0) / n, acc[3] = {0, 0, 0}, I3[3] = {I.x, I.y, I.z}, s3[3] = {ss.x, ss.y, ss.z}, t3[3] = {st.x, st.y, st.z};
    for (int i = 0; i <= n; i++) {
        double th = th0 + i * h, wgt = (i == 0 || i == n) ? 1 : (i % 2 ? 4 : 2);
        if (i == n && !isfinite(T)) continue; /* the integrand is 0 at infinity */
        double t = delta + D * tan(th), r = D / cos(th);
        vec3 x = v3_add(o, v3_scale(d, t));
        double cs = v3_dot(d, v3_scale(v3_sub(y, x), 1 / r));
        double den = 1 + g * g - 2 * g * cs, ph = (1 - g * g) / (4 * M_PI * den * sqrt(den));
        for (int c = 0; c < 3; c++) acc[c] += wgt * exp(-t3[c] * (t + r)) * s3[c] * ph * I3[c] / D;
    }
    for (int c = 0; c < 3; c++) out[c] = acc[c] * h / 3;
}

/* The scene of the single-scattering tests: a point light at (0, ly, lz) in a global fog, the
 * camera at the origin looking along +z with a tiny field of view, and one black quad far
 * below (the format wants an object; no ray or shadow ray meets it). */
static int ss_scene(scene *s, double ly, double lz, int max_depth) {
    char txt[4096];
    snprintf(txt, sizeof txt,
             "{\"camera\": {\"eye\": [0, 0, 0], \"look_at\": [0, 0, 1], \"fov_deg\": 0.0001, \"width\": 4, \"height\": 4},"
             " \"render\": {\"max_depth\": %d},"
             " \"medium\": \"fog\", \"media\": {\"fog\": {\"sigma_s\": [0.5, 0.8, 1.1], \"sigma_a\": 0.1, \"g\": 0.4}},"
             " \"materials\": {\"black\": {\"type\": \"lambert\", \"reflectance\": 0}},"
             " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-1, -50, -1], [1, -50, -1], [1, -50, 4], [-1, -50, 4]],"
             " \"material\": \"black\"}],"
             " \"lights\": [{\"type\": \"point\", \"position\": [0, %.17g, %.17g], \"power\": 20}]}",
             max_depth, ly, lz);
    json_err e = {0};
    int rc = scene_load_text(s, txt, &e);
    if (rc) printf("    scene: %s\n", e.msg);
    return rc;
}

/* Oracle: ss_quadrature. pmv_march with no volume maps computes exactly the single scattering
 * of a segment (its stratified steps' light samples and their equiangular partners, direct.h);
 * averaged over 20,000 marches of [0, 3] it must match the quadrature within 4 standard errors
 * per channel, for a light 0.3 and 0.02 off the ray. At 0.02 the old estimator (the same steps,
 * one light sample each, no equiangular samples: direct_light_medium) is the comparison: its
 * spread per march must be at least 3 times the new one's (printed: the standard deviations
 * and both means). */
TEST(media_single_scattering_march_matches_quadrature) {
    double offs[2] = {0.3, 0.02};
    for (int k = 0; k < 2; k++) {
        scene s;
        ASSERT_EQ_INT(ss_scene(&s, offs[k], 1.2, 64), 0);
        photon_settings c;
        photon_settings_defaults(&c);
        pmv_state v;
        ASSERT_EQ_INT(pmv_init(&v, &s, &c), 0);
        const medium *md = &s.media[0];
        ray r = {v3(0, 0, 0), v3(0, 0, 1)};
        double T = 3, want[3];
        ss_quadrature(r.o, r.d, T, s.lights[0].pos, s.lights[0].intensity, md->sigma_s, md->sigma_t, md->g, want);
        void *scratch = malloc(pmv_scratch_bytes(&v));
        int trials = PM_TEST_SANITIZED ? 2000 : 20000;
        double s1[3] = {0}, s2[3] = {0}, p1 = 0, p2 = 0;
        int n = (int)ceil(T / v.step[0]);
        for (int i = 0; i < trials; i++) {
            rng g = rng_stream(77, (uint64_t)i, (uint64_t)k);
            rgb tr, L = pmv_march(&v, &s, r, T, 0, 1, &g, scratch, &tr);
            double l[3] = {L.x, L.y, L.z};
            for (int ch = 0; ch < 3; ch++) {
                s1[ch] += l[ch];
                s2[ch] += l[ch] * l[ch];
            }
            /* the old estimator: stratified steps, one light sample each */
            rng h = rng_stream(78, (uint64_t)i, (uint64_t)k);
            double dt = T / n, u = rng_uniform(&h), old = 0;
            for (int j = 0; j < n; j++) {
                double t = (j + u) * dt;
                old += dt * medium_tr(md, t).y * md->sigma_s.y * direct_light_medium(&s, ray_at(r, t), r.d, 0, &h).y;
            }
            p1 += old;
            p2 += old * old;
        }
        double sd_new = sqrt(fmax(0, s2[1] / trials - (s1[1] / trials) * (s1[1] / trials)));
        double sd_old = sqrt(fmax(0, p2 / trials - (p1 / trials) * (p1 / trials)));
        printf("    light %.2f off the ray, %d steps: quadrature %.6g %.6g %.6g; march", offs[k], n, want[0], want[1], want[2]);
        for (int ch = 0; ch < 3; ch++) {
            double m = s1[ch] / trials, se = sqrt(fmax(0, s2[ch] / trials - m * m) / trials);
            printf(" %.6g (%+.2f%%, se %.2f%%)", m, 100 * (m / want[ch] - 1), 100 * se / want[ch]);
            EXPECT_MSG(fabs(m - want[ch]) <= 4 * se + 1e-4 * want[ch], "offset %g channel %d: %g vs %g (se %g)", offs[k],
                       ch, m, want[ch], se);
        }
        double mo = p1 / trials, seo = sd_old / sqrt(trials);
        printf("\n      green: sd per march %.4g (equiangular + steps) vs %.4g (steps only, mean %+.2f%% se %.2f%%)\n", sd_new,
               sd_old, 100 * (mo / want[1] - 1), 100 * seo / want[1]);
        if (k == 1) EXPECT_MSG(sd_old >= 3 * sd_new, "sd %g (new) vs %g (old)", sd_new, sd_old);
        free(scratch);
        pmv_free(&v);
        scene_free(&s);
    }
}

/* Oracle: ss_quadrature over [0, infinity). The path tracer with max_depth 1 computes the
 * single scattering of the camera ray only (one scattering event; its free-flight next-event
 * estimate and the segment's equiangular sample, direct.h); a 4x4 image with a 1e-4 degree
 * field of view sees one ray. The image mean must match the quadrature within 4 standard
 * errors (the 16 pixels' spread) per channel, the light 0.05 off the ray. */
TEST(media_single_scattering_path_matches_quadrature) {
    scene s;
    ASSERT_EQ_INT(ss_scene(&s, 0.05, 1.2, 1), 0);
    double want[3];
    const medium *md = &s.media[0];
    ss_quadrature(v3(0, 0, 0), v3(0, 0, 1), INFINITY, s.lights[0].pos, s.lights[0].intensity, md->sigma_s, md->sigma_t,
                  md->g, want);
    scene_free(&s);
    char txt[4096], scn[2048], pfm[2048], cmd[8192];
    static char out[65536];
    snprintf(txt, sizeof txt,
             "{\"camera\": {\"eye\": [0, 0, 0], \"look_at\": [0, 0, 1], \"fov_deg\": 0.0001, \"width\": 4, \"height\": 4},"
             " \"render\": {\"max_depth\": 1},"
             " \"medium\": \"fog\", \"media\": {\"fog\": {\"sigma_s\": [0.5, 0.8, 1.1], \"sigma_a\": 0.1, \"g\": 0.4}},"
             " \"materials\": {\"black\": {\"type\": \"lambert\", \"reflectance\": 0}},"
             " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-1, -50, -1], [1, -50, -1], [1, -50, 4], [-1, -50, 4]],"
             " \"material\": \"black\"}],"
             " \"lights\": [{\"type\": \"point\", \"position\": [0, 0.05, 1.2], \"power\": 20}]}");
    snprintf(scn, sizeof scn, "%s/ss.json", pm_test_tmpdir());
    snprintf(pfm, sizeof pfm, "%s/ss.pfm", pm_test_tmpdir());
    FILE *f = fopen(scn, "w");
    ASSERT(f != NULL);
    fputs(txt, f);
    fclose(f);
    snprintf(cmd, sizeof cmd, "cd '%s' && %s/render '%s' --mode path --spp %d --seed 9 --threads 2 --quiet --hdr '%s' -o ss.png",
             pm_test_tmpdir(), pm_test_build_dir(), scn, PM_TEST_SANITIZED ? 256 : 4096, pfm);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    film im;
    ASSERT_EQ_INT(film_read_pfm(&im, pfm), 0);
    printf("    quadrature %.6g %.6g %.6g; path tracing", want[0], want[1], want[2]);
    for (int ch = 0; ch < 3; ch++) {
        double s1 = 0, s2 = 0;
        for (int i = 0; i < 16; i++) {
            double v = im.px[3 * i + ch];
            s1 += v;
            s2 += v * v;
        }
        double m = s1 / 16, se = sqrt(fmax(0, s2 / 16 - m * m) / 15);
        printf(" %.6g (%+.2f%%, se %.2f%%)", m, 100 * (m / want[ch] - 1), 100 * se / want[ch]);
        EXPECT_MSG(fabs(m - want[ch]) <= 4 * se + 1e-4 * want[ch], "channel %d: %g vs %g (se %g)", ch, m, want[ch], se);
    }
    printf("\n");
    film_free(&im);
}

/* ---- 3. the boundary rule's ball fraction at slanted and curved boundaries ------------------ */

/* A rotation (Rodrigues, about a unit axis by angle a) applied to v. */
static vec3 bf_rotate(vec3 v, vec3 axis, double a) {
    double c = cos(a), s = sin(a);
    return v3_add(v3_add(v3_scale(v, c), v3_scale(v3_cross(axis, v), s)), v3_scale(axis, v3_dot(axis, v) * (1 - c)));
}

/* The old rule (before the tangent planes): six axis rays, a cap at each hit's distance along
 * the ray, the product over the axes; printed beside the new one. */
static double bf_old_rule(const scene *s, vec3 x, double r) {
    double f = 1;
    for (int a = 0; a < 3; a++) {
        double cut = 0;
        for (int sg = -1; sg <= 1; sg += 2) {
            vec3 d = v3s(0);
            if (a == 0) d.x = sg;
            else if (a == 1) d.y = sg;
            else d.z = sg;
            hit h;
            ray ry = {x, d};
            if (scene_intersect(s, ry, r, &h) && h.t < r) {
                double q = h.t / r;
                cut += (1 - q) * (1 - q) * (2 + q) / 4;
            }
        }
        f *= fmax(0.0, 1 - cut);
    }
    return fmax(f, 0.125);
}

/* Oracle: Monte Carlo with a generator of its own: 400,000 points uniform in the ball, the
 * fraction inside the medium tested analytically (a rotated cube |u| < 1 in its own frame, or
 * a sphere). pmv_ball_fraction in a null cube [-1, 1]^3 rotated by 0.6 rad about (1, 2, 3), a
 * ball of radius 0.5: one face at 0.2 (the tangent plane's cap: exact), an edge and a corner
 * (the grid quadrature of the planes: within 0.5% of the fraction), each within that plus 4
 * standard errors. Faces farther than 0.807 r may be missed by all 14 search directions (the
 * largest angle from any direction to the nearest of them has cosine 0.807), each missing at
 * most a cap of 2.61% of the ball: the far cases (faces at 0.8 r and 0.9 r) may read high by
 * that much and never low. Curved boundaries (inside a null sphere of radius 1, the ball's
 * centre 0.7 from its centre; the exact part is the lens of two spheres) are replaced by
 * tangent planes, whose half-spaces hold the sphere: the fraction may read high (less
 * correction), never low; printed, and bounded by the measured +3%. */
TEST(media_ball_fraction_slanted_and_curved) {
    vec3 axis = v3_norm(v3(1, 2, 3));
    double ang = 0.6;
    char verts[1024];
    size_t n = (size_t)snprintf(verts, sizeof verts, "[");
    for (int i = 0; i < 8; i++) {
        vec3 v = bf_rotate(v3(i & 1 ? 1 : -1, i & 2 ? 1 : -1, i & 4 ? 1 : -1), axis, ang);
        n += (size_t)snprintf(verts + n, sizeof verts - n, "%s[%.17g, %.17g, %.17g]", i ? ", " : "", v.x, v.y, v.z);
    }
    snprintf(verts + n, sizeof verts - n, "]");
    static char txt[8192];
    snprintf(txt, sizeof txt,
             "{\"camera\": {\"eye\": [0, 0, -9], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
             " \"media\": {\"fog\": {\"sigma_s\": 1}}, \"materials\": {\"air\": {\"type\": \"null\"}},"
             " \"objects\": [{\"type\": \"mesh\", \"vertices\": %s, \"triangles\": [[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6],"
             " [0, 1, 5], [0, 5, 4], [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]], \"material\": \"air\","
             " \"interior_medium\": \"fog\"},"
             " {\"type\": \"sphere\", \"center\": [5, 0, 0], \"radius\": 1, \"material\": \"air\", \"interior_medium\": \"fog\"}],"
             " \"lights\": [{\"type\": \"point\", \"position\": [0, 3, 0], \"power\": 10}]}",
             verts);
    scene s;
    json_err e = {0};
    ASSERT_MSG(scene_load_text(&s, txt, &e) == 0, "%s", e.msg);
    struct {
        vec3 local; /* cube cases: the point in the cube's frame; sphere: offset from (5, 0, 0) */
        int sphere, far;
        const char *what;
    } c[] = {
        {{0.8, 0, 0}, 0, 0, "slanted face at 0.2"},
        {{0.85, 0.8, 0.1}, 0, 0, "slanted edge at 0.15, 0.2"},
        {{0.85, 0.8, 0.9}, 0, 0, "slanted corner at 0.15, 0.2, 0.1"},
        {{0.9, -0.95, -0.7}, 0, 0, "slanted corner at 0.1, 0.05, 0.3"},
        {{0.6, 0, 0}, 0, 1, "slanted face at 0.4 (0.8 r)"},
        {{0.55, 0.55, 0}, 0, 1, "slanted edge at 0.45, 0.45 (0.9 r)"},
        {{0.7, 0, 0}, 1, 0, "inside a sphere, 0.3 from its surface"},
        {{0.45, 0.45, 0.2}, 1, 0, "inside a sphere, 0.33 from its surface"},
    };
    const double r = 0.5;
    uint64_t seed = 4242;
    for (size_t i = 0; i < sizeof c / sizeof c[0]; i++) {
        vec3 x = c[i].sphere ? v3_add(v3(5, 0, 0), c[i].local) : bf_rotate(c[i].local, axis, ang);
        long M = PM_TEST_SANITIZED ? 100000 : 400000, in = 0;
        for (long k = 0; k < M;) {
            vec3 p = v3(2 * vc_rand(&seed) - 1, 2 * vc_rand(&seed) - 1, 2 * vc_rand(&seed) - 1);
            if (v3_len2(p) > 1) continue;
            k++;
            vec3 q = v3_add(x, v3_scale(p, r));
            int inside;
            if (c[i].sphere) {
                inside = v3_len(v3_sub(q, v3(5, 0, 0))) < 1;
            } else {
                vec3 u = bf_rotate(q, axis, -ang);
                inside = fabs(u.x) < 1 && fabs(u.y) < 1 && fabs(u.z) < 1;
            }
            in += inside;
        }
        double want = (double)in / M, se = sqrt(want * (1 - want) / M);
        double got = pmv_ball_fraction(&s, x, r), old = bf_old_rule(&s, x, r);
        printf("    %-40s: Monte Carlo %.4f (se %.4f), pmv_ball_fraction %.4f (%+.2f%%), old rule %.4f (%+.2f%%)\n", c[i].what,
               want, se, got, 100 * (got / want - 1), old, 100 * (old / want - 1));
        double lo = -(0.005 * want + 4 * se), hi = 0.005 * want + 4 * se;
        if (c[i].far) hi += 2 * 0.0261;
        if (c[i].sphere) hi += 0.03 * want;
        EXPECT_MSG(got - want >= lo && got - want <= hi, "%s: %.5f vs %.5f (allowed %+.4f .. %+.4f)", c[i].what, got, want, lo, hi);
    }
    scene_free(&s);
}

/* ---- 4. photon mapping against long path-traced references --------------------------------- */

/* The reference, averaged 2 x 2 down to the test's resolution (a pixel of the small image
 * covers the same part of the film as the four it averages). */
static int downsample2(const film *in, film *out) {
    if (film_init(out, in->width / 2, in->height / 2) < 0) return -1;
    for (int y = 0; y < out->height; y++)
        for (int x = 0; x < out->width; x++)
            for (int c = 0; c < 3; c++) {
                double s = 0;
                for (int k = 0; k < 4; k++)
                    s += in->px[3 * ((long)(2 * y + k / 2) * in->width + 2 * x + k % 2) + c];
                out->px[3 * ((long)y * out->width + x) + c] = (float)(s / 4);
            }
    return 0;
}

/* Render NAME (a shipped scene) at 32x32 with photon mapping (flags), and compare the image
 * and the listed objects' pixels (ids: object index + 1, names) with the committed 64x64
 * path-traced reference data/reference-media/NAME.pfm averaged down. */
static void pm_against_reference(const char *name, const char *flags, const int *ids, const char *const *names,
                                 const double *tols, int nids, double tol_image) {
    static char out[65536];
    char cmd[8192], scn[2048], ref[2048], pm[2048], mask[2048];
    const char *dir = pm_test_tmpdir();
    snprintf(scn, sizeof scn, "%s/data/scenes/%s.json", pm_test_source_dir(), name);
    snprintf(ref, sizeof ref, "%s/data/reference-media/%s.pfm", pm_test_source_dir(), name);
    snprintf(pm, sizeof pm, "%s/%s_pm.pfm", dir, name);
    snprintf(mask, sizeof mask, "%s/%s_ids.pfm", dir, name);
    snprintf(cmd, sizeof cmd, "%s/render '%s' --width 32 --height 32 --quiet --threads 2 --mode objects --spp 16 "
             "--hdr '%s' -o '%s/ids.png'", pm_test_build_dir(), scn, mask, dir);
    ASSERT_MSG(pm_test_run(cmd, out, sizeof out) == 0, "%s", out);
    snprintf(cmd, sizeof cmd, "%s/render '%s' --width 32 --height 32 --quiet --threads 2 --mode pm --seed 5 %s "
             "--hdr '%s' -o '%s/pm.png'", pm_test_build_dir(), scn, flags, pm, dir);
    ASSERT_MSG(pm_test_run(cmd, out, sizeof out) == 0, "%s", out);
    /* the reference must be of this scene file */
    char want[256] = "", got[256] = "";
    snprintf(cmd, sizeof cmd, "awk '$1 == \"scene_sha256\" { print $2 }' '%s/data/reference-media/%s.info'",
             pm_test_source_dir(), name);
    ASSERT_EQ_INT(pm_test_run(cmd, want, sizeof want), 0);
    snprintf(cmd, sizeof cmd, "sha256sum '%s' | cut -d' ' -f1", scn);
    ASSERT_EQ_INT(pm_test_run(cmd, got, sizeof got), 0);
    ASSERT_MSG(want[0] && strcmp(want, got) == 0, "%s changed since its reference was rendered (%s, now %s)", scn, want, got);
    film R64, R, P, M;
    ASSERT_MSG(film_read_pfm(&R64, ref) == 0, "cannot read %s", ref);
    ASSERT(R64.width == 64 && R64.height == 64);
    ASSERT_EQ_INT(downsample2(&R64, &R), 0);
    ASSERT_EQ_INT(film_read_pfm(&P, pm), 0);
    ASSERT_EQ_INT(film_read_pfm(&M, mask), 0);
    image_diff d;
    ASSERT_EQ_INT(image_compare(&P, &R, 0, 0, 0, 0, &d), 0);
    printf("    %s: image %+.2f%%", name, 100 * d.rel_mean);
    EXPECT_MSG(fabs(d.rel_mean) <= tol_image, "%s: image mean %+.2f%% off the reference (tolerance %.0f%%)", name,
               100 * d.rel_mean, 100 * tol_image);
    for (int i = 0; i < nids; i++) {
        image_region r = {0, 0, 0, 0, &M, &ids[i], 1};
        ASSERT_EQ_INT(image_compare_region(&P, &R, &r, &d), 0);
        printf(", %s %+.2f%% (%ld px)", names[i], 100 * d.rel_mean, d.npixels);
        EXPECT_MSG(d.npixels >= 20, "%s: only %ld pixels see %s", name, d.npixels, names[i]);
        EXPECT_MSG(fabs(d.rel_mean) <= tols[i], "%s: %s mean %+.2f%% off the reference (tolerance %.0f%%)", name,
                   names[i], 100 * d.rel_mean, 100 * tols[i]);
    }
    printf("\n");
    film_free(&R64);
    film_free(&R);
    film_free(&P);
    film_free(&M);
}

/* Oracle: the long path-traced reference of cornell_fog (data/reference-media/, its .info has
 * the samples, the scene's hash and the reference's own noise per region: 0.08% (back wall) to
 * 0.52% (right wall); the test refuses a reference of another version of the scene). Photon
 * mapping at 32x32, 16 spp, with its default plan and emission_strata 8: the image mean within
 * 3%, and the pixels that see each wall, the floor and the ceiling (through the fog) within 5%.
 * The ceiling's pixels next to the lamp see part of the lamp, 17 times brighter than the
 * ceiling: with the default 2 x 2 emission-only rays per sample their coverage of the lamp was
 * most of the ceiling's spread between seeds, and fog under the lamp (1 / dist^2 next-event
 * estimation) the rest, which the march's equiangular samples now carry (pm_volume.h). Ceiling
 * over seeds 5..10 (the previous reference): before the equiangular samples +2.7, -4.0, -1.5,
 * +2.4, -0.4, -2.2% (sd 2.8%; the bound was 8%); with them -1.9..+1.4% (sd 2.1%); with them and
 * emission_strata 8, -1.1..+0.8% (sd 0.7%). Against the present reference (4096 spp, the path
 * tracer with equiangular samples; the previous one, 2304 spp without them, held fireflies and
 * read the back wall 1.9% high): seed 5 image -0.1%, regions -1.3..+1.4% (ceiling +1.4%);
 * seeds 6-8 (a 32x32 mask of its own) every region within -1.4..+0.4%. A mutation that counts
 * the fog's direct light twice near the lamp (MIS weight 1 in both strategies) reads ceiling
 * +8.7%, back wall +13.1%, image +7.0%, and fails. */
TEST(media_cornell_fog_pm_matches_path) {
    static const int ids[] = {1, 2, 3, 4, 5};
    static const char *const names[] = {"floor", "ceiling", "back wall", "left wall", "right wall"};
    static const double tols[] = {0.05, 0.05, 0.05, 0.05, 0.05};
    pm_against_reference("cornell_fog", "--spp 16 --pm emission_strata=8", ids, names, tols, 5, 0.03);
}

/* Oracle: the same for glass_of_smoke: the image within 3%, the smoke-filled sphere's pixels,
 * the floor and the back wall within 5%. Fewer surface caustic photons than the default (the
 * pass would emit 32 M photons for 500,000 in the glass's small caustic); the volume maps keep
 * their defaults. This test found volume estimates inside glass 2.2 times too bright (smoke
 * +104%, fixed in ac02625 by the (n_0/n)^2 scale); measured at 74cc17c: image -0.25%, smoke
 * sphere -2.48%, floor -1.24%, back wall -0.13%. */
TEST(media_glass_of_smoke_pm_matches_path) {
    static const int ids[] = {7, 1, 3};
    static const char *const names[] = {"smoke sphere", "floor", "back wall"};
    static const double tols[] = {0.05, 0.05, 0.05};
    pm_against_reference("glass_of_smoke", "--spp 16 --pm caustic_photons=50000", ids, names, tols, 3, 0.03);
}
