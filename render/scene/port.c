/* port.c: the geometry of photon ports; see port.h. */
#include "scene/port.h"

#include <math.h>

#include "base/sampling.h"

port port_quad(vec3 corner, vec3 e1, vec3 e2) {
    port pt = {0};
    pt.type = PORT_QUAD;
    pt.corner = corner;
    pt.e1 = e1;
    pt.e2 = e2;
    vec3 x = v3_cross(e1, e2);
    pt.area = v3_len(x);
    pt.n = v3_scale(x, 1.0 / pt.area);
    pt.c = v3_add(corner, v3_scale(v3_add(e1, e2), 0.5));
    return pt;
}

port port_disc(vec3 c, vec3 n, double r) {
    port pt = {0};
    pt.type = PORT_DISC;
    pt.c = c;
    pt.n = v3_norm(n);
    pt.r = r;
    pt.area = M_PI * r * r;
    return pt;
}

vec3 port_sample(const port *pt, double u1, double u2) {
    if (pt->type == PORT_QUAD) return v3_add(pt->corner, v3_add(v3_scale(pt->e1, u1), v3_scale(pt->e2, u2)));
    double x, y;
    vec3 a, b;
    sample_concentric_disc(u1, u2, &x, &y);
    v3_basis(pt->n, &a, &b);
    return v3_add(pt->c, v3_add(v3_scale(a, x * pt->r), v3_scale(b, y * pt->r)));
}

int port_cross(const port *pt, vec3 o, vec3 d, double *t, double *cos_p) {
    double dn = v3_dot(d, pt->n);
    if (dn == 0) return 0;
    double tt = v3_dot(v3_sub(pt->c, o), pt->n) / dn;
    if (!(tt > 0) || !isfinite(tt)) return 0;
    vec3 q = v3_madd(o, d, tt);
    if (pt->type == PORT_QUAD) {
        /* q = corner + a e1 + b e2: solve in the plane with the Gram matrix of (e1, e2). */
        vec3 w = v3_sub(q, pt->corner);
        double g11 = v3_dot(pt->e1, pt->e1), g12 = v3_dot(pt->e1, pt->e2), g22 = v3_dot(pt->e2, pt->e2);
        double w1 = v3_dot(w, pt->e1), w2 = v3_dot(w, pt->e2), det = g11 * g22 - g12 * g12;
        double a = (w1 * g22 - w2 * g12) / det, b = (w2 * g11 - w1 * g12) / det;
        if (!(a >= 0 && a <= 1 && b >= 0 && b <= 1)) return 0;
    } else if (!(v3_len2(v3_sub(q, pt->c)) <= pt->r * pt->r)) {
        return 0;
    }
    *t = tt;
    *cos_p = fabs(dn);
    return 1;
}
