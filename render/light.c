/* light.c: sampling a point on a light as seen from a shading point; see light.h. */
#include "light.h"

#include "scene.h"

int light_sample_li(const struct scene *s, int li, vec3 p, double u1, double u2, light_sample *ls) {
    const light *l = &s->lights[li];
    switch (l->type) {
    case LIGHT_AREA: {
        const triangle *tr = &s->tris[l->tri];
        vec3 q = triangle_sample(tr, u1, u2);
        vec3 d = v3_sub(q, p);
        double dist2 = v3_len2(d);
        if (!(dist2 > 0)) return 0;
        double dist = sqrt(dist2);
        ls->wi = v3_scale(d, 1.0 / dist);
        ls->dist = dist;
        ls->p = q;
        ls->n = tr->n;
        double cos_l = -v3_dot(ls->wi, tr->n); /* > 0 when p is in front of the light */
        if (l->two_sided) cos_l = fabs(cos_l);
        if (cos_l <= 0) return 0;
        /* Le / pdf_omega with pdf_omega = dist^2 / (cos_l A). */
        ls->L = v3_scale(l->Le, cos_l * tr->area / dist2);
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
