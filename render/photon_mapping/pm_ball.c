/* pm_ball.c: the part of a volume estimate's search ball inside the medium; see pm_ball.h. */
#include "photon_mapping/pm_ball.h"

#include <math.h>

/* The smallest part of a search ball taken to lie inside a medium (a ball at a box's corner). */
#define PMV_MIN_BALL_FRACTION 0.125
/* The directions searched for boundaries, and the quadrature's directions. */
#define PMV_BALL_DIRS 14
#define PMV_BALL_QUAD 32

/* The part of the ball of radius r at x that a plane at distance h (along one axis) leaves
 * on x's side: 1 minus the cap beyond it, (1 - h/r)^2 (2 + h/r) / 4 of the ball. */
static double cap_fraction(double h, double r) {
    if (!(h < r)) return 0;
    double q = h / r;
    return (1 - q) * (1 - q) * (2 + q) / 4;
}

/* The planes found near x (pmv_ball_fraction): unit normal n pointing away from x, distance h. */
typedef struct pmv_plane {
    vec3 n;
    double h;
} pmv_plane;

/* The 14 search directions: the 6 axes and the 8 diagonals. */
static vec3 ball_dir(int i) {
    if (i < 6) {
        vec3 d = v3s(0);
        double sg = i & 1 ? -1 : 1;
        if (i / 2 == 0) d.x = sg;
        else if (i / 2 == 1) d.y = sg;
        else d.z = sg;
        return d;
    }
    double c = 1 / sqrt(3.0);
    int k = i - 6;
    return v3(k & 1 ? -c : c, k & 2 ? -c : c, k & 4 ? -c : c);
}

/* The part of the ball of radius r at x inside every plane's half-space (the side of x): the
 * mean of (rho / r)^3 over the sphere of directions, rho the distance from x to the nearest
 * plane along the direction, at most r (the region is convex and holds x, so its volume is the
 * integral of rho^3 / 3 over the sphere). The mean is taken on a grid of PMV_BALL_QUAD^2
 * equal-area cells (midpoints in z = cos theta and in phi), symmetric about the axis planes, so
 * a plane, edge or corner through x along the axes gets exactly 1/2, 1/4, 1/8. */
static double planes_fraction(const pmv_plane *pl, int np, double r) {
    double cphi[PMV_BALL_QUAD], sphi[PMV_BALL_QUAD], acc = 0;
    for (int j = 0; j < PMV_BALL_QUAD; j++) {
        double ph = 2 * M_PI * (j + 0.5) / PMV_BALL_QUAD;
        cphi[j] = cos(ph);
        sphi[j] = sin(ph);
    }
    for (int i = 0; i < PMV_BALL_QUAD; i++) {
        double z = -1 + (2 * i + 1.0) / PMV_BALL_QUAD, rad = sqrt(fmax(0.0, 1 - z * z));
        for (int j = 0; j < PMV_BALL_QUAD; j++) {
            vec3 w = v3(rad * cphi[j], rad * sphi[j], z);
            double rho = r;
            for (int k = 0; k < np; k++) {
                double cs = v3_dot(pl[k].n, w);
                if (cs > 0 && pl[k].h < rho * cs) rho = pl[k].h / cs;
            }
            double q = rho / r;
            acc += q * q * q;
        }
    }
    return acc / ((double)PMV_BALL_QUAD * PMV_BALL_QUAD);
}

double pmv_ball_fraction(const scene *s, vec3 x, double r) {
    if (!(r > 0) || !isfinite(r)) return 1;
    pmv_plane pl[PMV_BALL_DIRS];
    int np = 0;
    for (int i = 0; i < PMV_BALL_DIRS; i++) {
        hit h;
        ray ry = {x, ball_dir(i)};
        if (!scene_intersect(s, ry, r, &h)) continue;
        /* the surface's tangent plane at the hit: its distance from x along its normal */
        vec3 n = h.ng;
        double hd = v3_dot(n, v3_sub(h.p, x));
        if (hd < 0) {
            n = v3_neg(n);
            hd = -hd;
        }
        if (!(hd < r)) continue; /* cuts nothing off the ball */
        int same = 0;
        for (int j = 0; j < np && !same; j++)
            same = v3_dot(n, pl[j].n) > 1 - 1e-9 && fabs(hd - pl[j].h) <= 1e-9 * r;
        if (!same) pl[np++] = (pmv_plane){n, hd};
    }
    double f = np == 0 ? 1 : np == 1 ? 1 - cap_fraction(pl[0].h, r) : planes_fraction(pl, np, r);
    return fmax(f, PMV_MIN_BALL_FRACTION);
}
