/* light_sample.c: the scene's lights sampled (declared in scene.h): a point on a light as
 * seen from a shading point (next-event estimation), a ray of light leaving one (photon
 * emission), what a ray that leaves the scene sees, and the colour a photon of an infinite
 * light carries. They read the scene's shapes and environment map, so they stand on scene.h
 * (and light.h, the lights themselves), which neither includes nor calls this file. */
#include "scene/scene.h"

#include "base/sampling.h"
#include "scene/envmap.h"

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
        *d = light_spot_dir(l, u[0], u[1]);
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
