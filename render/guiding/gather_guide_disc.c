/* gather_guide_disc.c: the disc the gather guide aims at (gather_guide.h): the mixture of aimed
 * and cosine gather directions with its density, and the disc around a photon port (PORTS AS
 * OPENINGS). gather_guide.c has the pilot that finds an opening or a bright patch.
 */
#include "guiding/gather_guide.h"

#include <math.h>
#include <stdio.h>

#include "base/sampling.h"
#include "base/stats.h"

/* ---- the mixture (WHY THE ESTIMATE STAYS UNBIASED) ---------------------------------------- */

double gather_guide_disc_pdf(const gather_guide *gg, vec3 x, vec3 d) {
    vec3 toc = v3_sub(gg->centre, x);
    double dc = v3_len(toc), cd = v3_dot(d, toc) / dc;
    if (!(cd > 0)) return 0;
    double t = dc / cd, R = gg->radius;
    if (v3_len2(v3_sub(v3_add(x, v3_scale(d, t)), gg->centre)) > R * R) return 0;
    return t * t / (M_PI * R * R * cd);
}

double gather_guide_share(const gather_guide *gg, vec3 x, vec3 ns) {
    if (!gg->aim) return 0;
    vec3 toc = v3_sub(gg->centre, x);
    if (v3_len2(gg->lit) > 0 && !(v3_dot(toc, gg->lit) > gg->radius)) return 0; /* WHO AIMS */
    return v3_dot(toc, ns) > 0 && v3_len2(toc) > gg->radius * gg->radius ? GATHER_GUIDE_SHARE : 0;
}

double gather_guide_pdf(const gather_guide *gg, double a, vec3 x, vec3 nsh, vec3 d) {
    double c = v3_dot(d, nsh);
    return (1 - a) * (c > 0 ? c : 0) / M_PI + a * gather_guide_disc_pdf(gg, x, d);
}

vec3 gather_guide_direction(const gather_guide *gg, double a, vec3 x, vec3 nsh, double u1, double u2, rng *g,
                            double *wk) {
    vec3 d;
    if (rng_uniform(g) < a) {
        vec3 toc = v3_sub(gg->centre, x), ds, dt;
        double dx, dy;
        v3_basis(v3_norm(toc), &ds, &dt);
        sample_concentric_disc(u1, u2, &dx, &dy);
        vec3 q = v3_add(gg->centre, v3_add(v3_scale(ds, gg->radius * dx), v3_scale(dt, gg->radius * dy)));
        d = v3_norm(v3_sub(q, x));
        if (gg->stat_aimed >= 0) stat_inc(gg->stat_aimed);
    } else
        d = sampling_to_world(sample_cosine_hemisphere(u1, u2), nsh);
    double c = v3_dot(d, nsh);
    double p = gather_guide_pdf(gg, a, x, nsh, d);
    *wk = c > 0 && p > 0 ? c / M_PI / p : 0;
    return d;
}

/* ---- a photon port as the opening (PORTS AS OPENINGS) ------------------------------------- */

/* gather_guide.h: the side of pt's plane the lights shine from, each weighted by its power: an
 * area light's triangle or a sphere light by its centre, a point or spot light by its
 * position, a directional light by where it comes from; an infinite light counts on both
 * sides. *share: the larger side's share of the power. */
vec3 gather_guide_port_lit(const scene *s, const port *pt, double *share) {
    double side[2] = {0, 0};
    for (int i = 0; i < s->nlights; i++) {
        const light *l = &s->lights[i];
        double w = rgb_lum(l->power), d;
        if (!(w > 0)) continue;
        if (l->type == LIGHT_INFINITE) {
            side[0] += w;
            side[1] += w;
            continue;
        }
        if (l->type == LIGHT_DIRECTIONAL) d = -v3_dot(l->dir, pt->n);
        else if (l->type == LIGHT_AREA) {
            const triangle *t = &s->tris[l->tri];
            d = v3_dot(v3_sub(v3_add(t->v0, v3_scale(v3_add(t->e1, t->e2), 1.0 / 3)), pt->c), pt->n);
        } else if (l->type == LIGHT_SPHERE) d = v3_dot(v3_sub(s->spheres[l->sphere].c, pt->c), pt->n);
        else d = v3_dot(v3_sub(l->pos, pt->c), pt->n);
        if (d != 0) side[d > 0] += w;
    }
    double all = side[0] + side[1];
    *share = all > 0 ? fmax(side[0], side[1]) / all : 0;
    return *share >= GG_PORT_SIDE ? v3_scale(pt->n, side[1] >= side[0] ? 1 : -1) : v3(0, 0, 0);
}

void gather_guide_port(gather_guide *gg, const scene *s, const port *pt, char *what, size_t cap) {
    double share;
    gg->centre = pt->c;
    gg->radius = pt->type == PORT_DISC ? pt->r
                                       : 0.5 * fmax(v3_len(v3_add(pt->e1, pt->e2)), v3_len(v3_sub(pt->e1, pt->e2)));
    gg->lit = gather_guide_port_lit(s, pt, &share);
    gg->aim = gg->on = 1;
    if (v3_len2(gg->lit) > 0)
        snprintf(what, cap, "; so the gathers aim at the photon port instead: a disc of radius %.3g at (%.4g, %.4g, "
                 "%.4g), from the points on its dark side (%.0f%% of the lights' power is on its side along "
                 "(%.2f, %.2f, %.2f))", gg->radius, pt->c.x, pt->c.y, pt->c.z, 100 * share, gg->lit.x, gg->lit.y,
                 gg->lit.z);
    else
        snprintf(what, cap, "; so the gathers aim at the photon port instead: a disc of radius %.3g at (%.4g, %.4g, "
                 "%.4g), from every point in front of it (the lights' power is on both of its sides, at most %.0f%% "
                 "on one)", gg->radius, pt->c.x, pt->c.y, pt->c.z, 100 * share);
}
