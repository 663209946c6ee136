/* light.c: sampling a point on a light as seen from a shading point, and a ray of light
 * leaving it; see light.h. The spot's emission direction is drawn from its falloff by the
 * inverse of the distribution of cos (closed form for the quartic, bisection for smoothstep),
 * so every photon of a spot carries the same power. */
#include "scene/light.h"

#include "base/sampling.h"
#include "scene/envmap.h"
#include "scene/scene.h"

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

static vec3 spot_dir(const light *l, double u0, double u1) {
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

rgb light_env_radiance(const struct scene *s, vec3 d) {
    (void)d;
    if (s->env_light <= 0) return v3s(0);
    return s->env_map ? envmap_eval(s->env_map, d) : s->lights[s->env_light - 1].Le;
}

rgb light_emit_weight(const struct scene *s, int li, vec3 d) {
    const envmap *m = s->env_map;
    if (s->lights[li].type != LIGHT_INFINITE || !m) return v3s(1);
    /* a photon carries (L / lum(L)) Sigma pi R^2 / n (envmap.h); the light's power is
     * integral pi R^2, so the ratio per channel is (L / lum(L)) Sigma / integral */
    rgb L = envmap_eval(m, v3_neg(d)), I = m->integral;
    double lum = rgb_lum(L);
    if (!(lum > 0)) return v3s(0);
    return v3(I.x > 0 ? L.x / lum * m->sigma / I.x : 0, I.y > 0 ? L.y / lum * m->sigma / I.y : 0,
              I.z > 0 ? L.z / lum * m->sigma / I.z : 0);
}

int light_sample_li(const struct scene *s, int li, vec3 p, double u1, double u2, light_sample *ls) {
    const light *l = &s->lights[li];
    switch (l->type) {
    case LIGHT_AREA:
    case LIGHT_SPHERE: {
        vec3 q, nq;
        double area;
        if (l->type == LIGHT_AREA) {
            const triangle *tr = &s->tris[l->tri];
            q = triangle_sample(tr, u1, u2);
            nq = tr->n;
            area = tr->area;
        } else {
            const sphere *sp = &s->spheres[l->sphere];
            nq = sample_uniform_sphere(u1, u2);
            q = v3_madd(sp->c, nq, sp->r);
            area = 4 * M_PI * sp->r * sp->r;
        }
        vec3 d = v3_sub(q, p);
        double dist2 = v3_len2(d);
        if (!(dist2 > 0)) return 0;
        double dist = sqrt(dist2);
        ls->wi = v3_scale(d, 1.0 / dist);
        ls->dist = dist;
        ls->p = q;
        ls->n = nq;
        double cos_l = -v3_dot(ls->wi, nq); /* > 0 when p is in front of the light */
        if (l->two_sided) cos_l = fabs(cos_l);
        if (cos_l <= 0) return 0;
        /* Le / pdf_omega with pdf_omega = dist^2 / (cos_l A). */
        ls->L = v3_scale(l->Le, cos_l * area / dist2);
        return 1;
    }
    case LIGHT_POINT:
    case LIGHT_SPOT: {
        vec3 d = v3_sub(l->pos, p);
        double dist2 = v3_len2(d);
        if (!(dist2 > 0)) return 0;
        ls->dist = sqrt(dist2);
        ls->wi = v3_scale(d, 1.0 / ls->dist);
        ls->p = l->pos;
        ls->n = v3s(0);
        /* a point light is a spot of falloff 1 everywhere (I / dist^2, as before spots) */
        double f = l->type == LIGHT_SPOT ? light_spot_falloff(l, v3_neg(ls->wi)) : 1.0;
        ls->L = v3_scale(l->intensity, f / dist2);
        return f > 0;
    }
    case LIGHT_INFINITE:
        ls->dist = INFINITY;
        ls->p = v3s(0);
        ls->n = v3s(0);
        if (s->env_map) {
            double pdf;
            ls->wi = envmap_sample(s->env_map, u1, u2, &pdf);
            ls->L = pdf > 0 ? v3_scale(envmap_eval(s->env_map, ls->wi), 1 / pdf) : v3s(0);
            return pdf > 0;
        }
        ls->wi = sample_uniform_sphere(u1, u2);
        ls->L = v3_scale(l->Le, 4 * M_PI);
        return 1;
    case LIGHT_DIRECTIONAL:
        ls->wi = v3_neg(l->dir);
        ls->dist = INFINITY;
        ls->p = v3s(0);
        ls->n = v3s(0);
        ls->L = l->irradiance;
        return 1;
    }
    return 0;
}

void light_sample_le(const struct scene *s, int li, const double u[4], vec3 *p, vec3 *n, vec3 *d) {
    const light *l = &s->lights[li];
    switch (l->type) {
    case LIGHT_AREA:
    case LIGHT_SPHERE: {
        double u0 = u[0];
        int back = 0;
        if (l->two_sided) {
            /* Reuse u[0] after the side choice so it stays uniform. */
            if (u0 < 0.5) {
                u0 *= 2;
            } else {
                u0 = 2 * u0 - 1;
                back = 1;
            }
        }
        vec3 nn;
        if (l->type == LIGHT_AREA) {
            const triangle *tr = &s->tris[l->tri];
            *p = triangle_sample(tr, u0, u[1]);
            nn = tr->n;
        } else {
            const sphere *sp = &s->spheres[l->sphere];
            nn = sample_uniform_sphere(u0, u[1]);
            *p = v3_madd(sp->c, nn, sp->r);
        }
        if (back) nn = v3_neg(nn);
        *n = nn;
        *d = sampling_to_world(sample_cosine_hemisphere(u[2], u[3]), nn);
        return;
    }
    case LIGHT_POINT:
        *p = l->pos;
        *n = v3s(0);
        *d = sample_uniform_sphere(u[0], u[1]);
        return;
    case LIGHT_SPOT:
        *p = l->pos;
        *n = v3s(0);
        *d = spot_dir(l, u[0], u[1]);
        return;
    case LIGHT_INFINITE: {
        double pdf;
        vec3 dd = s->env_map ? v3_neg(envmap_sample(s->env_map, u[0], u[1], &pdf)) : sample_uniform_sphere(u[0], u[1]), a, b;
        double x, y, R = s->bsphere_r > 0 ? s->bsphere_r : 1.0;
        sample_concentric_disc(u[2], u[3], &x, &y);
        v3_basis(dd, &a, &b);
        vec3 c = v3_madd(s->bsphere_c, dd, -R);
        *p = v3_add(c, v3_add(v3_scale(a, x * R), v3_scale(b, y * R)));
        *n = v3s(0);
        *d = dd;
        return;
    }
    default: {
        double x, y;
        sample_concentric_disc(u[0], u[1], &x, &y);
        vec3 a, b;
        v3_basis(l->dir, &a, &b);
        double R = s->bsphere_r > 0 ? s->bsphere_r : 1.0;
        vec3 c = v3_madd(s->bsphere_c, l->dir, -R);
        *p = v3_add(c, v3_add(v3_scale(a, x * R), v3_scale(b, y * R)));
        *n = v3s(0);
        *d = l->dir;
        return;
    }
    }
}
