/* test_render_material.c: Fresnel, refraction, BRDF reciprocity and energy, branch choice.
 *
 * Oracles: closed-form Fresnel values (normal incidence ((n1-n2)/(n1+n2))^2, Brewster's angle
 * where rp = 0, the critical angle), Snell's law, the symmetry of a reciprocal BRDF, and
 * Monte Carlo integrals with their standard errors.
 */
#include "test.h"
#include "../render/scene/material.h"
#include "../render/base/rng.h"
#include "../render/base/sampling.h"

/* Oracle: ((n1 - n2)/(n1 + n2))^2 = 0.04 for air to glass 1.5, both ways; 1e-15 absolute. */
TEST(render_fresnel_normal_incidence) {
    ASSERT_NEAR(fresnel_dielectric(1.0, 1.0, 1.5), 0.04, 1e-15);
    ASSERT_NEAR(fresnel_dielectric(1.0, 1.5, 1.0), 0.04, 1e-15);
    ASSERT_NEAR(fresnel_dielectric(1.0, 1.0, 2.4), pow(1.4 / 3.4, 2), 1e-15);
}

/* Oracle: at Brewster's angle atan(n2/n1) the p reflectance vanishes, so R = rs^2 / 2 with
 * cos_t = sin_i; for n = 1.5, Rs = 0.14793 (tables) and R = 0.073964. 1e-12 / 1e-5. */
TEST(render_fresnel_brewster) {
    double n1 = 1.0, n2 = 1.5, th = atan(n2 / n1), ci = cos(th), si = sin(th);
    double rs = (n1 * ci - n2 * si) / (n1 * ci + n2 * si);
    ASSERT_NEAR(fresnel_dielectric(ci, n1, n2), 0.5 * rs * rs, 1e-12);
    ASSERT_NEAR(fresnel_dielectric(ci, n1, n2), 0.5 * 0.147929, 1e-5);
    /* from the glass side, Brewster's angle is atan(n1/n2) */
    th = atan(n1 / n2), ci = cos(th), si = sin(th);
    rs = (n2 * ci - n1 * si) / (n2 * ci + n1 * si);
    ASSERT_NEAR(fresnel_dielectric(ci, n2, n1), 0.5 * rs * rs, 1e-12);
}

/* Oracle: beyond the critical angle asin(n2/n1) R = 1 exactly; just inside it R < 1; and
 * Fresnel is reciprocal: R(theta_i; n1, n2) = R(theta_t; n2, n1) (Snell pairs), 1e-12. */
TEST(render_fresnel_total_internal_reflection) {
    double crit = asin(1.0 / 1.5);
    ASSERT_NEAR(fresnel_dielectric(cos(crit + 1e-6), 1.5, 1.0), 1.0, 0);
    ASSERT_NEAR(fresnel_dielectric(cos(1.2), 1.5, 1.0), 1.0, 0);
    ASSERT(fresnel_dielectric(cos(crit - 1e-3), 1.5, 1.0) < 1.0);
    for (double th = 0; th < crit; th += 0.05) {
        double st = 1.5 * sin(th);
        double thi = asin(st);
        ASSERT_NEAR(fresnel_dielectric(cos(th), 1.5, 1.0), fresnel_dielectric(cos(thi), 1.0, 1.5), 1e-12);
    }
}

/* Oracle: equal indices reflect nothing at any angle (0 exactly). */
TEST(render_fresnel_equal_indices) {
    for (double c = 0; c <= 1.0; c += 0.125) ASSERT_NEAR(fresnel_dielectric(c, 1.33, 1.33), 0.0, 0);
}

/* Oracle: Snell's law n1 sin_i = n2 sin_t, to 1e-12, and the refracted ray stays in the plane
 * of incidence on the far side. */
TEST(render_refraction_snell) {
    rng g = rng_stream(1, 2, 3);
    vec3 n = v3(0, 0, 1);
    for (int i = 0; i < 1000; i++) {
        vec3 d = sample_uniform_hemisphere(rng_uniform(&g), rng_uniform(&g));
        d.z = -d.z;
        vec3 t;
        ASSERT(refract_dir(d, n, 1.0 / 1.5, &t));
        double si = sqrt(1 - d.z * d.z), st = sqrt(1 - t.z * t.z);
        ASSERT_NEAR(1.0 * si, 1.5 * st, 1e-12);
        ASSERT(t.z < 0);
        ASSERT_NEAR(v3_dot(v3_cross(d, n), t), 0.0, 1e-12);
    }
}

static material diffuse_mat(double rho, double sigma) {
    material m = {0};
    m.kind = sigma > 0 ? MAT_OREN_NAYAR : MAT_LAMBERT;
    m.diffuse = v3s(rho);
    m.sigma = sigma;
    m.specular_tint = m.transmit_tint = v3s(1);
    m.ior = 1.5;
    return m;
}

/* Oracle: reciprocity f(wo, wi) = f(wi, wo) for Oren–Nayar (and thus Lambert), to 1e-13
 * relative, over random pairs; and sigma = 0 gives exactly rho/pi. */
TEST(render_brdf_reciprocity_and_on_sigma0) {
    rng g = rng_stream(9, 0, 0);
    vec3 n = v3_norm(v3(0.2, -0.3, 1));
    for (int k = 0; k < 3; k++) {
        material m = diffuse_mat(0.8, k * 0.4);
        material lam = diffuse_mat(0.8, 0);
        for (int i = 0; i < 2000; i++) {
            vec3 a = sampling_to_world(sample_uniform_hemisphere(rng_uniform(&g), rng_uniform(&g)), n);
            vec3 b = sampling_to_world(sample_uniform_hemisphere(rng_uniform(&g), rng_uniform(&g)), n);
            double fab = material_diffuse_f(&m, n, a, b).x, fba = material_diffuse_f(&m, n, b, a).x;
            ASSERT_NEAR(fab, fba, 1e-13 * fab);
            ASSERT(fab >= 0);
            if (k == 0) ASSERT_NEAR(fab, material_diffuse_f(&lam, n, a, b).x, 0);
            if (k == 0) ASSERT_NEAR(fab, 0.8 / M_PI, 1e-15);
        }
    }
}

/* Oracle: the directional albedo integral of f cos over the hemisphere, by Monte Carlo with
 * uniform directions (N samples, standard error s/sqrt(N)): for rho = 1 it is 1 for Lambert
 * (within 4 standard errors) and at most 1 + 4 SE for Oren–Nayar at every tested angle. */
TEST(render_brdf_energy) {
    int N = PM_TEST_SANITIZED ? 20000 : 200000;
    rng g = rng_stream(10, 0, 0);
    vec3 n = v3(0, 0, 1);
    const double sig[] = {0, 0.3, 1.0, 2.0};
    for (int k = 0; k < 4; k++) {
        material m = diffuse_mat(1.0, sig[k]);
        for (double tho = 0; tho < 1.5; tho += 0.35) {
            vec3 wo = v3(sin(tho), 0, cos(tho));
            double s = 0, s2 = 0;
            for (int i = 0; i < N; i++) {
                vec3 wi = sample_uniform_hemisphere(rng_uniform(&g), rng_uniform(&g));
                double v = material_diffuse_f(&m, n, wo, wi).x * wi.z * 2 * M_PI;
                s += v;
                s2 += v * v;
            }
            double mean = s / N, se = sqrt(fmax(0, s2 / N - mean * mean) / N);
            ASSERT_MSG(mean <= 1.0 + 4 * se, "sigma %g theta_o %g: albedo %g (se %g)", sig[k], tho, mean, se);
            if (k == 0) ASSERT_NEAR(mean, 1.0, 4 * se);
        }
    }
}

/* Oracle: the branch frequencies of material_sample follow the weights R, (1-R)T, (1-R)(1-T)
 * (binomial, within 5 standard deviations), with R from Fresnel for a "mix" material. And
 * the diffuse branch's weight f cos / pdf equals rho for Lambert. */
TEST(render_material_branch_weights) {
    material m = diffuse_mat(0.5, 0);
    m.kind = MAT_MIX;
    m.fresnel = 1;
    m.transparency = 0.3;
    vec3 ng = v3(0, 0, 1), wo = v3_norm(v3(1, 0, 1.2));
    double w[LOBE_COUNT];
    material_weights(&m, wo, ng, 1.0, w);
    double R = fresnel_dielectric(wo.z, 1.0, 1.5);
    ASSERT_NEAR(w[LOBE_REFLECT], R, 1e-15);
    ASSERT_NEAR(w[LOBE_TRANSMIT], (1 - R) * 0.3, 1e-15);
    ASSERT_NEAR(w[LOBE_DIFFUSE], (1 - R) * 0.7, 1e-15);
    int N = 100000, cnt[LOBE_COUNT] = {0};
    rng g = rng_stream(12, 0, 0);
    for (int i = 0; i < N; i++) {
        bsdf_sample s;
        material_sample(&m, wo, ng, 1.0, rng_uniform(&g), rng_uniform(&g), rng_uniform(&g), &s);
        cnt[s.lobe]++;
        if (s.lobe == LOBE_DIFFUSE) ASSERT_NEAR(s.weight.x, 0.5, 1e-12);
        if (s.lobe == LOBE_TRANSMIT) ASSERT(s.wi.z < 0);
        if (s.lobe == LOBE_REFLECT) ASSERT_NEAR(s.wi.z, wo.z, 1e-12);
    }
    for (int k = 0; k < LOBE_COUNT; k++) {
        double p = w[k], sd = sqrt(N * p * (1 - p));
        ASSERT_NEAR(cnt[k], N * p, 5 * sd + 1);
    }
}

/* Oracle: the planning predicates follow the branch weights: a branch counts when its weight
 * can be positive and its colour is not black (hand-worked table for each preset). */
TEST(render_material_predicates) {
    material lam = diffuse_mat(0.5, 0), on = diffuse_mat(0.5, 0.3), black = diffuse_mat(0, 0);
    material mir = diffuse_mat(0, 0), glass = diffuse_mat(0, 0), plastic = diffuse_mat(0.4, 0);
    mir.specular = 1;
    glass.fresnel = 1;
    glass.transparency = 1;
    plastic.fresnel = 1;
    EXPECT(material_is_diffuse(&lam) && !material_is_specular(&lam));
    EXPECT(material_is_diffuse(&on) && !material_is_specular(&on));
    EXPECT(!material_is_diffuse(&black) && !material_is_specular(&black));
    EXPECT(!material_is_diffuse(&mir) && material_is_specular(&mir));
    EXPECT(!material_is_diffuse(&glass) && material_is_specular(&glass));
    EXPECT(material_is_diffuse(&plastic) && material_is_specular(&plastic));
    EXPECT(!material_is_emissive(&lam));
    lam.emission = v3(0, 0, 0.1);
    EXPECT(material_is_emissive(&lam));
}
