/* material.c: Fresnel, Lambert, Oren–Nayar, mirror and refraction, and the branch choice.
 *
 * Oren–Nayar is the qualitative model of Oren and Nayar (1994):
 *   f = rho/pi (A + B max(0, cos(phi_i - phi_o)) sin(alpha) tan(beta)),
 *   A = 1 - 0.5 s^2/(s^2 + 0.33), B = 0.45 s^2/(s^2 + 0.09), alpha = max(theta_i, theta_o),
 *   beta = min(theta_i, theta_o). It is symmetric in wi and wo, hence reciprocal, and equals
 *   Lambert (A = 1, B = 0) at sigma = 0. It is sampled with the cosine distribution.
 */
#include "scene/material.h"

#include "base/sampling.h"

double fresnel_dielectric(double cos_i, double n1, double n2) {
    cos_i = fmin(1.0, fmax(0.0, cos_i));
    if (n1 == n2) return 0.0;
    double sin_i2 = fmax(0.0, 1.0 - cos_i * cos_i);
    double eta = n1 / n2;
    double sin_t2 = eta * eta * sin_i2;
    if (sin_t2 >= 1.0) return 1.0;
    double cos_t = sqrt(1.0 - sin_t2);
    double rs = (n1 * cos_i - n2 * cos_t) / (n1 * cos_i + n2 * cos_t);
    double rp = (n2 * cos_i - n1 * cos_t) / (n2 * cos_i + n1 * cos_t);
    return 0.5 * (rs * rs + rp * rp);
}

int refract_dir(vec3 d, vec3 n, double eta, vec3 *out) {
    double cos_i = -v3_dot(d, n);
    double sin_t2 = eta * eta * fmax(0.0, 1.0 - cos_i * cos_i);
    if (sin_t2 >= 1.0) return 0;
    double cos_t = sqrt(1.0 - sin_t2);
    *out = v3_norm(v3_add(v3_scale(d, eta), v3_scale(n, eta * cos_i - cos_t)));
    return 1;
}

void material_indices(const material *m, vec3 wo, vec3 ng, double n_medium, double *n1,
                      double *n2) {
    if (m->transparency > 0 && v3_dot(wo, ng) < 0) {
        *n1 = m->ior; /* inside the object, looking out */
        *n2 = n_medium;
    } else {
        *n1 = n_medium;
        *n2 = m->ior;
    }
}

double material_radiance_scale(double n_src, double n) {
    if (!(n_src > 0) || !(n > 0) || n_src == n) return 1;
    double q = n_src / n;
    return q * q;
}

void material_weights(const material *m, vec3 wo, vec3 ng, double n_medium, double w[LOBE_COUNT]) {
    double R = m->specular;
    if (m->fresnel) {
        double n1, n2;
        material_indices(m, wo, ng, n_medium, &n1, &n2);
        R = fresnel_dielectric(fabs(v3_dot(wo, ng)), n1, n2);
    }
    R = fmin(1.0, fmax(0.0, R));
    double T = fmin(1.0, fmax(0.0, m->transparency));
    w[LOBE_REFLECT] = R;
    w[LOBE_TRANSMIT] = (1.0 - R) * T;
    w[LOBE_DIFFUSE] = (1.0 - R) * (1.0 - T);
}

rgb material_diffuse_f(const material *m, vec3 n, vec3 wo, vec3 wi) {
    double ci = v3_dot(wi, n), co = v3_dot(wo, n);
    if (co < 0) {
        ci = -ci;
        co = -co;
        n = v3_neg(n);
    }
    if (ci <= 0 || co <= 0) return v3s(0);
    if (m->sigma <= 0) return v3_scale(m->diffuse, 1.0 / M_PI);
    double s2 = m->sigma * m->sigma;
    /* s2 / (s2 + c) as 1 / (1 + c / s2): finite for any sigma (the loader keeps it <= pi/2). */
    double A = 1.0 - 0.5 / (1.0 + 0.33 / s2), B = 0.45 / (1.0 + 0.09 / s2);
    double si = sqrt(fmax(0.0, 1.0 - ci * ci)), so = sqrt(fmax(0.0, 1.0 - co * co));
    double cphi = 0;
    if (si > 1e-12 && so > 1e-12) {
        vec3 ti = v3_madd(wi, n, -ci), to = v3_madd(wo, n, -co);
        cphi = fmax(0.0, v3_dot(ti, to) / (si * so));
    }
    double sin_alpha, tan_beta;
    if (ci < co) { /* theta_i is the larger angle */
        sin_alpha = si;
        tan_beta = so / co;
    } else {
        sin_alpha = so;
        tan_beta = si / ci;
    }
    return v3_scale(m->diffuse, (A + B * cphi * sin_alpha * tan_beta) / M_PI);
}

rgb material_f(const material *m, vec3 ng, double n_medium, vec3 wo, vec3 wi) {
    double w[LOBE_COUNT];
    material_weights(m, wo, ng, n_medium, w);
    if (w[LOBE_DIFFUSE] <= 0) return v3s(0);
    return v3_scale(material_diffuse_f(m, ng, wo, wi), w[LOBE_DIFFUSE]);
}

int material_sample(const material *m, vec3 wo, vec3 ng, double n_medium, double u_lobe, double u1,
                    double u2, bsdf_sample *s) {
    return material_sample_ns(m, wo, ng, ng, n_medium, u_lobe, u1, u2, s);
}

int material_is_specular(const material *m) {
    return (m->fresnel || m->specular > 0 || m->transparency > 0) &&
           (!v3_iszero(m->specular_tint) || (m->transparency > 0 && !v3_iszero(m->transmit_tint)));
}

int material_is_diffuse(const material *m) {
    /* The diffuse weight (1-R)(1-T) can be positive: T < 1, and R < 1 somewhere (Fresnel R
     * is below 1 at normal incidence). */
    return m->transparency < 1 && (m->fresnel || m->specular < 1) && v3_maxc(m->diffuse) > 0;
}

int material_is_emissive(const material *m) { return v3_maxc(m->emission) > 0; }

vec3 material_shading_side(vec3 wo, vec3 ng, vec3 ns) {
    double g = v3_dot(wo, ng), h = v3_dot(wo, ns);
    vec3 n = (g >= 0) == (h >= 0) ? ns : ng;
    return g >= 0 ? n : v3_neg(n);
}

vec3 material_reflect_shaded(vec3 d, vec3 n_g, vec3 n_s) {
    vec3 r = v3_reflect(d, n_s);
    return v3_dot(r, n_g) > 0 ? r : v3_reflect(d, n_g);
}

int material_refract_shaded(vec3 d, vec3 n_g, vec3 n_s, double eta, vec3 *out) {
    if (refract_dir(d, n_s, eta, out) && v3_dot(*out, n_g) < 0) return 1;
    return refract_dir(d, n_g, eta, out);
}

int material_sample_ns(const material *m, vec3 wo, vec3 ng, vec3 ns, double n_medium, double u_lobe,
                       double u1, double u2, bsdf_sample *s) {
    double w[LOBE_COUNT];
    material_weights(m, wo, ng, n_medium, w);
    vec3 n = v3_dot(wo, ng) >= 0 ? ng : v3_neg(ng); /* the geometric side of wo */
    vec3 nsh = material_shading_side(wo, ng, ns);
    s->tir = 0;
    if (u_lobe < w[LOBE_REFLECT]) {
        s->lobe = LOBE_REFLECT;
        s->wi = material_reflect_shaded(v3_neg(wo), n, nsh);
        s->weight = m->specular_tint;
        return !v3_iszero(s->weight);
    }
    if (u_lobe < w[LOBE_REFLECT] + w[LOBE_TRANSMIT]) {
        double n1, n2;
        material_indices(m, wo, ng, n_medium, &n1, &n2);
        s->lobe = LOBE_TRANSMIT;
        s->weight = m->transmit_tint;
        if (!material_refract_shaded(v3_neg(wo), n, nsh, n1 / n2, &s->wi)) {
            s->wi = material_reflect_shaded(v3_neg(wo), n, nsh);
            s->tir = 1;
        }
        return !v3_iszero(s->weight);
    }
    s->lobe = LOBE_DIFFUSE;
    vec3 l = sample_cosine_hemisphere(u1, u2);
    s->wi = sampling_to_world(l, nsh);
    if (l.z <= 0 || v3_dot(s->wi, n) <= 0) return 0;
    /* f cos / pdf with pdf = cos/pi: Lambert gives rho exactly. */
    s->weight = v3_scale(material_diffuse_f(m, nsh, wo, s->wi), M_PI);
    return !v3_iszero(s->weight);
}
