/* light.c: sampling a point on a light as seen from a shading point; see light.h. */
#include "scene/light.h"

#include "base/sampling.h"
#include "scene/scene.h"

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
    case LIGHT_POINT: {
        vec3 d = v3_sub(l->pos, p);
        double dist2 = v3_len2(d);
        if (!(dist2 > 0)) return 0;
        ls->dist = sqrt(dist2);
        ls->wi = v3_scale(d, 1.0 / ls->dist);
        ls->p = l->pos;
        ls->n = v3s(0);
        ls->L = v3_scale(l->intensity, 1.0 / dist2);
        return 1;
    }
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
