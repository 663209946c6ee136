/* ports.c: photon emission through photon ports; see ports.h. */
#include "photons/ports.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "photons/importance.h"
#include "photons/photon_pass.h"
#include "base/rng.h"
#include "base/sampling.h"

/* The points of a port the weights are averaged over: the 2 x 2 Gauss points of a quad (exact
 * for a bicubic), 4 points at r / sqrt 2 on a disc (exact for a quadratic in the radius). */
static int port_points(const port *pt, vec3 out[4]) {
    if (pt->type == PORT_QUAD) {
        const double g[2] = {0.5 - 0.5 / sqrt(3.0), 0.5 + 0.5 / sqrt(3.0)};
        for (int k = 0; k < 4; k++)
            out[k] = v3_add(pt->corner, v3_add(v3_scale(pt->e1, g[k & 1]), v3_scale(pt->e2, g[k >> 1])));
    } else {
        vec3 a, b;
        v3_basis(pt->n, &a, &b);
        double r = pt->r / sqrt(2.0);
        out[0] = v3_madd(pt->c, a, r);
        out[1] = v3_madd(pt->c, a, -r);
        out[2] = v3_madd(pt->c, b, r);
        out[3] = v3_madd(pt->c, b, -r);
    }
    return 4;
}

/* g_lk of ports.h and, in *per_unit, what turns a sum of them into a share of the power. */
static double weight(const scene *s, const light *L, const port *pt, double *per_unit) {
    vec3 xs[3], ys[4];
    int nx = 1, ny = port_points(pt, ys);
    vec3 nl = v3s(0);
    int cosine = 0;
    double R = s->bsphere_r > 0 ? s->bsphere_r : 1.0;
    switch (L->type) {
    case LIGHT_AREA: {
        const triangle *tr = &s->tris[L->tri];
        /* the edge midpoints: exact for a quadratic over the triangle */
        xs[0] = v3_add(tr->v0, v3_scale(tr->e1, 0.5));
        xs[1] = v3_add(tr->v0, v3_scale(tr->e2, 0.5));
        xs[2] = v3_add(tr->v0, v3_scale(v3_add(tr->e1, tr->e2), 0.5));
        nx = 3;
        nl = tr->n;
        cosine = 1;
        *per_unit = L->two_sided ? 1 / (2 * M_PI) : 1 / M_PI;
        break;
    }
    case LIGHT_SPHERE: xs[0] = s->spheres[L->sphere].c; *per_unit = 1 / (4 * M_PI); break;
    case LIGHT_POINT: xs[0] = L->pos; *per_unit = 1 / (4 * M_PI); break;
    case LIGHT_SPOT: xs[0] = L->pos; *per_unit = 1 / (2 * M_PI * light_spot_w(L)); break;
    case LIGHT_INFINITE: *per_unit = 0; return 0; /* no port share: its photons keep the ordinary emission */
    default: *per_unit = 1 / (M_PI * R * R); return pt->area * fabs(v3_dot(L->dir, pt->n));
    }
    double g = 0;
    for (int i = 0; i < nx; i++)
        for (int j = 0; j < ny; j++) {
            vec3 v = v3_sub(ys[j], xs[i]);
            double t2 = v3_len2(v), t = sqrt(t2);
            if (!(t > 0)) continue;
            v = v3_scale(v, 1 / t);
            double cl = 1;
            if (cosine) cl = L->two_sided ? fabs(v3_dot(v, nl)) : fmax(0, v3_dot(v, nl));
            if (L->type == LIGHT_SPOT) cl = light_spot_falloff(L, v);
            g += pt->area * fabs(v3_dot(v, pt->n)) * cl / (t2 + pt->area);
        }
    return g / (nx * ny);
}

/* +1 when light L lies on the side of port pt's normal, -1 behind it (a directional light:
 * the side its light comes from), 0 in its plane. */
static double light_side(const scene *s, const light *L, const port *pt) {
    double v;
    switch (L->type) {
    case LIGHT_AREA: {
        const triangle *tr = &s->tris[L->tri];
        v = v3_dot(v3_sub(v3_add(tr->v0, v3_scale(v3_add(tr->e1, tr->e2), 1.0 / 3)), pt->c), pt->n);
        break;
    }
    case LIGHT_SPHERE: v = v3_dot(v3_sub(s->spheres[L->sphere].c, pt->c), pt->n); break;
    case LIGHT_POINT:
    case LIGHT_SPOT: v = v3_dot(v3_sub(L->pos, pt->c), pt->n); break;
    default: v = -v3_dot(L->dir, pt->n); break;
    }
    return v > 0 ? 1 : v < 0 ? -1 : 0;
}

int ports_build(photon_ports *pp, const scene *s) {
    memset(pp, 0, sizeof *pp);
    pp->s = s;
    pp->a = s->port_fraction;
    pp->nl = s->nlights;
    pp->np = s->nports;
    if (!s->nports || !(pp->a > 0) || !s->nlights) return 0;
    int np = s->nports;
    pp->wcdf = calloc((size_t)s->nlights * (size_t)(np + 1), sizeof *pp->wcdf);
    pp->q_p = calloc((size_t)s->nlights, sizeof *pp->q_p);
    pp->side = calloc((size_t)np, sizeof *pp->side);
    double *ql = calloc((size_t)s->nlights, sizeof *ql), *sd = calloc((size_t)np, sizeof *sd);
    if (!pp->wcdf || !pp->q_p || !pp->side || !ql || !sd) {
        free(sd);
        free(ql);
        ports_free(pp);
        return PM_ENOMEM;
    }
    for (int l = 0; l < s->nlights; l++) {
        double *row = &pp->wcdf[(size_t)l * (size_t)(np + 1)], per_unit = 0, sum = 0;
        for (int k = 0; k < np; k++) {
            double g = weight(s, &s->lights[l], &s->ports[k], &per_unit);
            sum += isfinite(g) && g > 0 ? g : 0;
            row[k + 1] = sum;
        }
        for (int k = 1; k <= np && sum > 0; k++) row[k] /= sum;
        double F = fmin(1, sum * per_unit), p_l = distrib1d_prob(&s->light_distrib, l);
        ql[l] = sum > 0 && p_l > 0 ? p_l * F : 0;
        pp->flux += ql[l];
        for (int k = 0; k < np; k++) /* the side of port k this light's weight comes from */
            sd[k] += ql[l] * (row[k + 1] - row[k]) * light_side(s, &s->lights[l], &s->ports[k]);
    }
    for (int k = 0; k < np; k++) pp->side[k] = (signed char)(sd[k] > 0 ? 1 : sd[k] < 0 ? -1 : 0);
    free(sd);
    if (pp->flux > 0) {
        for (int l = 0; l < s->nlights; l++) {
            double p_l = distrib1d_prob(&s->light_distrib, l);
            pp->q_p[l] = p_l > 0 ? ql[l] / pp->flux / p_l : 0;
        }
        int rc = distrib1d_init(&pp->light, ql, s->nlights);
        if (rc < 0) {
            free(ql);
            ports_free(pp);
            return rc;
        }
        pp->on = 1;
    }
    free(ql);
    return 0;
}

void ports_free(photon_ports *pp) {
    free(pp->wcdf);
    free(pp->q_p);
    free(pp->side);
    if (pp->on) distrib1d_free(&pp->light);
    memset(pp, 0, sizeof *pp);
}

/* The directional light's disc (light.h): its centre, and R. */
static vec3 disc_centre(const scene *s, const light *L, double *R) {
    *R = s->bsphere_r > 0 ? s->bsphere_r : 1.0;
    return v3_madd(s->bsphere_c, L->dir, -*R);
}

/* p_d(d | x) of the ordinary emission: per steradian, or per unit area of a directional
 * light's disc. */
static double ordinary_pd(const scene *s, const light *L, vec3 x, vec3 d) {
    vec3 n;
    switch (L->type) {
    case LIGHT_AREA: n = s->tris[L->tri].n; break;
    case LIGHT_SPHERE: n = v3_norm(v3_sub(x, s->spheres[L->sphere].c)); break;
    case LIGHT_POINT: return 1 / (4 * M_PI);
    case LIGHT_SPOT: return light_spot_pdf(L, d);
    case LIGHT_INFINITE: return 0;
    default: {
        double R;
        vec3 c = disc_centre(s, L, &R), r = v3_sub(x, c);
        r = v3_madd(r, L->dir, -v3_dot(r, L->dir));
        return v3_len2(r) < R * R ? 1 / (M_PI * R * R) : 0;
    }
    }
    double cs = v3_dot(d, n);
    if (L->two_sided) return fabs(cs) / (2 * M_PI);
    return cs > 0 ? cs / M_PI : 0;
}

double ports_ratio(const photon_ports *pp, int l, vec3 x, vec3 d) {
    if (!pp->on || !(pp->q_p[l] > 0)) return 0;
    const scene *s = pp->s;
    const light *L = &s->lights[l];
    double pd = ordinary_pd(s, L, x, d);
    if (!(pd > 0)) return 0;
    int dirl = L->type == LIGHT_DIRECTIONAL;
    const double *row = &pp->wcdf[(size_t)l * (size_t)(pp->np + 1)];
    double sum = 0;
    for (int k = 0; k < pp->np; k++) {
        double w = row[k + 1] - row[k], t, cs;
        if (!(w > 0) || !port_cross(&s->ports[k], x, dirl ? L->dir : d, &t, &cs)) continue;
        const port *pt = &s->ports[k];
        sum += w * (dirl ? 1 : t * t) / (pt->area * cs);
    }
    return pp->q_p[l] * sum / pd;
}

int ports_sample(const photon_ports *pp, double ul, double uk, const double u[4], int *l, vec3 *x, vec3 *n,
                 vec3 *d) {
    const scene *s = pp->s;
    double q;
    int li = distrib1d_sample(&pp->light, ul, &q);
    const double *row = &pp->wcdf[(size_t)li * (size_t)(pp->np + 1)];
    int k = 0;
    while (k < pp->np - 1 && !(uk < row[k + 1])) k++;
    const light *L = &s->lights[li];
    vec3 y = port_sample(&s->ports[k], u[2], u[3]);
    *l = li;
    if (L->type == LIGHT_DIRECTIONAL) {
        double R;
        vec3 c = disc_centre(s, L, &R);
        double back = v3_dot(v3_sub(y, c), L->dir);
        if (!(back > 0)) return 0;
        *x = v3_madd(y, L->dir, -back);
        *n = v3s(0);
        *d = L->dir;
        return v3_len2(v3_sub(*x, c)) < R * R;
    }
    vec3 nx = v3s(0);
    if (L->type == LIGHT_AREA) {
        const triangle *tr = &s->tris[L->tri];
        *x = triangle_sample(tr, u[0], u[1]);
        nx = tr->n;
    } else if (L->type == LIGHT_SPHERE) {
        const sphere *sp = &s->spheres[L->sphere];
        nx = sample_uniform_sphere(u[0], u[1]);
        *x = v3_madd(sp->c, nx, sp->r);
    } else {
        *x = L->pos;
    }
    vec3 v = v3_sub(y, *x);
    double t = v3_len(v);
    if (!(t > 0)) return 0;
    *d = v3_scale(v, 1 / t);
    if (!light_is_point(L)) {
        double cs = v3_dot(*d, nx);
        if (cs < 0 && L->two_sided) nx = v3_neg(nx);
        else if (!(cs > 0)) return 0;
    }
    *n = nx;
    return 1;
}

/* The ports x may aim at from a diffuse bounce (BOUNCES in ports.h), with their weights
 * (summing to 1) in w; how many. */
static int bounce_ports(const photon_ports *pp, vec3 x, vec3 nsh, double *w) {
    const scene *s = pp->s;
    double sum = 0;
    for (int k = 0; k < pp->np; k++) {
        const port *pt = &s->ports[k];
        vec3 v = v3_sub(pt->c, x);
        double t2 = v3_len2(v);
        w[k] = 0;
        if (!pp->side[k] || !(t2 > 0) || pp->side[k] * v3_dot(v, pt->n) >= 0 || v3_dot(v, nsh) <= 0) continue;
        w[k] = pt->area * fabs(v3_dot(v, pt->n)) / sqrt(t2) / (t2 + pt->area);
        sum += w[k];
    }
    if (!(sum > 0) || !isfinite(sum)) return 0;
    for (int k = 0; k < pp->np; k++) w[k] /= sum;
    return 1;
}

double ports_scatter(const photon_ports *pp, vec3 x, vec3 nsh, rng *g, double u1, double u2, double aim, vec3 *nd) {
    double w[256]; /* PORTS_MAX of scene_ports.c */
    if (pp->np > 256 || !bounce_ports(pp, x, nsh, w)) {
        *nd = sampling_to_world(sample_cosine_hemisphere(u1, u2), nsh);
        return 1;
    }
    const scene *s = pp->s;
    double a = ports_bounce_share(pp->a, aim), uc = rng_uniform(g);
    if (uc < a) {
        double uk = uc / a, acc = 0;
        int k = 0;
        for (; k < pp->np - 1; k++) {
            acc += w[k];
            if (uk < acc && w[k] > 0) break;
        }
        while (k > 0 && !(w[k] > 0)) k--; /* rounding past the last port with weight */
        vec3 v = v3_sub(port_sample(&s->ports[k], u1, u2), x);
        double t = v3_len(v);
        if (!(t > 0)) return 0;
        *nd = v3_scale(v, 1 / t);
    } else {
        *nd = sampling_to_world(sample_cosine_hemisphere(u1, u2), nsh);
    }
    double cs = v3_dot(*nd, nsh);
    if (!(cs > 0)) return 0;
    double pport = 0;
    for (int k = 0; k < pp->np; k++) {
        double t, ck;
        if (w[k] > 0 && port_cross(&s->ports[k], x, *nd, &t, &ck)) pport += w[k] * t * t / (s->ports[k].area * ck);
    }
    double pc = cs / M_PI;
    return pc / ((1 - a) * pc + a * pport);
}

void ports_mix(const pass_ctx *c, uint64_t i, int *li, vec3 *p, vec3 *n, vec3 *d, rgb *power, double *rel) {
    const photon_ports *pp = c->ports;
    double a = pp->a, h = sample_halton(i, 5, c->shift);
    if (c->o->pilot || !(h < a)) { /* the ordinary photon, weighed by the mixture */
        *rel = a * ports_ratio(pp, *li, *p, *d) + (1 - a) * *rel;
        return;
    }
    double u[4] = {sample_halton(i, 1, c->shift), sample_halton(i, 2, c->shift), sample_halton(i, 3, c->shift),
                   sample_halton(i, 4, c->shift)};
    int l;
    vec3 x, nx, dd;
    double r = 0, rb = 1;
    if (ports_sample(pp, sample_halton(i, 0, c->shift), h / a, u, &l, &x, &nx, &dd)) r = ports_ratio(pp, l, x, dd);
    if (r > 0 && c->imp) { /* importance emission is the ordinary branch: its rel here */
        double ui[4];
        if (importance_invert_le(c->s, l, x, dd, ui)) rb = importance_rel(c->imp, c->s, l, ui);
        else r = 0;
    }
    if (!(r > 0)) { /* a direction the light does not emit into: it carries nothing */
        *power = v3s(0);
        *rel = 1;
        return;
    }
    *li = l;
    *p = x;
    *n = nx;
    *d = dd;
    *power = c->light_scale[l];
    *rel = a * r + (1 - a) * rb;
}

int ports_mix_media(const photon_ports *pp, rng *g, int *li, vec3 *p, vec3 *n, vec3 *d, rgb *power) {
    const scene *s = pp->s;
    double a = pp->a, uc = rng_uniform(g);
    if (!(uc < a)) { /* the ordinary photon, weighed by the mixture */
        *power = v3_scale(*power, 1 / (a * ports_ratio(pp, *li, *p, *d) + (1 - a)));
        return 1;
    }
    double ul = rng_uniform(g), uk = rng_uniform(g), u[4];
    for (int k = 0; k < 4; k++) u[k] = rng_uniform(g);
    int l;
    vec3 x, nx, dd;
    if (!ports_sample(pp, ul, uk, u, &l, &x, &nx, &dd)) return 0;
    double r = ports_ratio(pp, l, x, dd), pl = distrib1d_prob(&s->light_distrib, l);
    if (!(r > 0) || !(pl > 0)) return 0; /* a direction the light does not emit into */
    *li = l;
    *p = x;
    *n = nx;
    *d = dd;
    *power = v3_scale(s->lights[l].power, 1 / (pl * (a * r + (1 - a))));
    return 1;
}

void ports_describe(const photon_ports *pp, const scene *s, char *buf, size_t cap) {
    if (!s->nports) {
        snprintf(buf, cap, "none declared in the scene ($.ports)");
        return;
    }
    if (!pp->on) {
        snprintf(buf, cap, "%d declared, but %s", s->nports,
                 !(s->port_fraction > 0) ? "port_fraction is 0" : "no light faces them");
        return;
    }
    size_t n = (size_t)snprintf(buf, cap, "%.3g of the global photons aimed through %d port%s (",
                                pp->a, s->nports, s->nports == 1 ? "" : "s");
    for (int k = 0; k < s->nports && k < 4 && n < cap; k++) {
        const port *pt = &s->ports[k];
        n += (size_t)snprintf(buf + n, cap - n, "%s$.ports[%d] %s of area %.4g at (%.4g, %.4g, %.4g)", k ? "; " : "", k,
                              pt->type == PORT_QUAD ? "quad" : "disc", pt->area, pt->c.x, pt->c.y, pt->c.z);
    }
    if (n < cap && s->nports > 4) n += (size_t)snprintf(buf + n, cap - n, "; ...");
    if (n < cap)
        snprintf(buf + n, cap - n, "): about %.3g%% of the lights' power passes them (estimated at a few points), "
                 "the share ordinary emission would send there", 100 * pp->flux);
}

int ports_plan(const scene *s, char *buf, size_t cap) {
    photon_ports pp;
    int rc = ports_build(&pp, s);
    if (rc < 0) return rc;
    ports_describe(&pp, s, buf, cap);
    int on = pp.on;
    ports_free(&pp);
    return on;
}
