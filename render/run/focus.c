/* focus.c: camera samples aimed at an opening seen in a sliver of a pixel; see focus.h. */
#include "run/focus.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Film position of the world point p, or 0 when it is behind or beside the eye. */
static int project(const camera *c, vec3 p, double *fx, double *fy) {
    vec3 d = v3_sub(p, c->eye);
    double z = v3_dot(d, c->forward);
    if (!(z > 1e-6 * v3_len(d))) return 0;
    double sx = v3_dot(d, c->right) / z, sy = v3_dot(d, c->up) / z;
    *fx = (sx / c->tan_half_w + 1) * 0.5 * c->width;
    *fy = (1 - sy / c->tan_half_h) * 0.5 * c->height;
    return isfinite(*fx) && isfinite(*fy);
}

static double signed_area(const double *x, const double *y, int n) {
    double a = 0;
    for (int i = 0; i < n; i++) {
        int j = (i + 1) % n;
        a += x[i] * y[j] - x[j] * y[i];
    }
    return 0.5 * a;
}

/* Keep the part of the polygon (x, y, *n) where s * (coordinate axis) <= s * lim. */
static void clip(double *x, double *y, int *n, int axis, double lim, double s) {
    double ox[FOCUS_VERTS + 4], oy[FOCUS_VERTS + 4];
    int m = 0;
    for (int i = 0; i < *n; i++) {
        int j = (i + 1) % *n;
        double ci = s * ((axis ? y[i] : x[i]) - lim), cj = s * ((axis ? y[j] : x[j]) - lim);
        if (ci <= 0) {
            ox[m] = x[i];
            oy[m++] = y[i];
        }
        if ((ci < 0 && cj > 0) || (ci > 0 && cj < 0)) {
            double t = ci / (ci - cj);
            ox[m] = x[i] + t * (x[j] - x[i]);
            oy[m++] = y[i] + t * (y[j] - y[i]);
        }
    }
    *n = m > FOCUS_VERTS ? FOCUS_VERTS : m; /* a convex 4-gon cut by 4 lines has at most 8 */
    memcpy(x, ox, (size_t)*n * sizeof *x);
    memcpy(y, oy, (size_t)*n * sizeof *y);
}

/* The port's outline on the film (4 corners, counter-clockwise), or 0. */
static int outline(const camera *c, const port *pt, double *x, double *y) {
    vec3 e1 = pt->e1, e2 = pt->e2, o = pt->corner;
    if (pt->type == PORT_DISC) { /* the square around the disc, in its plane */
        vec3 a = fabs(pt->n.x) < 0.9 ? v3(1, 0, 0) : v3(0, 1, 0);
        vec3 u = v3_norm(v3_cross(pt->n, a)), v = v3_cross(pt->n, u);
        e1 = v3_scale(u, 2 * pt->r);
        e2 = v3_scale(v, 2 * pt->r);
        o = v3_sub(pt->c, v3_scale(v3_add(e1, e2), 0.5));
    }
    vec3 q[4] = {o, v3_add(o, e1), v3_add(v3_add(o, e1), e2), v3_add(o, e2)};
    for (int i = 0; i < 4; i++)
        if (!project(c, q[i], &x[i], &y[i])) return 0;
    if (signed_area(x, y, 4) < 0)
        for (int i = 0; i < 2; i++) {
            double t = x[i];
            x[i] = x[3 - i];
            x[3 - i] = t;
            t = y[i];
            y[i] = y[3 - i];
            y[3 - i] = t;
        }
    return 1;
}

int focus_build(film_focus *f, const camera *c, const port *ports, int nports) {
    memset(f, 0, sizeof *f);
    f->width = c->width;
    f->height = c->height;
    size_t npix = (size_t)c->width * (size_t)c->height;
    if (!(f->index = malloc(npix * sizeof *f->index))) return -1;
    for (size_t i = 0; i < npix; i++) f->index[i] = -1;
    int cap = 0;
    for (int k = 0; k < nports; k++) {
        double X[4], Y[4];
        if (!outline(c, &ports[k], X, Y)) continue;
        double lo_x = fmin(fmin(X[0], X[1]), fmin(X[2], X[3])), hi_x = fmax(fmax(X[0], X[1]), fmax(X[2], X[3]));
        double lo_y = fmin(fmin(Y[0], Y[1]), fmin(Y[2], Y[3])), hi_y = fmax(fmax(Y[0], Y[1]), fmax(Y[2], Y[3]));
        int x0 = (int)fmax(0, floor(lo_x)), x1 = (int)fmin(c->width - 1, floor(hi_x));
        int y0 = (int)fmax(0, floor(lo_y)), y1 = (int)fmin(c->height - 1, floor(hi_y));
        for (int py = y0; py <= y1; py++)
            for (int px = x0; px <= x1; px++) {
                size_t pi = (size_t)py * (size_t)c->width + (size_t)px;
                if (f->index[pi] >= 0) continue;
                focus_poly p;
                memset(&p, 0, sizeof p);
                p.n = 4;
                for (int i = 0; i < 4; i++) {
                    p.x[i] = X[i] - px;
                    p.y[i] = Y[i] - py;
                }
                clip(p.x, p.y, &p.n, 0, 0, -1);
                clip(p.x, p.y, &p.n, 0, 1, 1);
                clip(p.x, p.y, &p.n, 1, 0, -1);
                clip(p.x, p.y, &p.n, 1, 1, 1);
                if (p.n < 3) continue;
                p.area = signed_area(p.x, p.y, p.n);
                if (!(p.area > 1e-9) || p.area > FOCUS_MAX_COVER) continue;
                double acc = 0;
                for (int i = 1; i + 1 < p.n; i++) {
                    acc += signed_area((double[]){p.x[0], p.x[i], p.x[i + 1]},
                                       (double[]){p.y[0], p.y[i], p.y[i + 1]}, 3);
                    p.cum[i - 1] = acc / p.area;
                }
                p.cum[p.n - 3] = 1;
                if (f->npolys == cap) {
                    int nc = cap ? 2 * cap : 16;
                    focus_poly *np = realloc(f->polys, (size_t)nc * sizeof *np);
                    if (!np) {
                        focus_free(f);
                        return -1;
                    }
                    f->polys = np;
                    cap = nc;
                }
                f->polys[f->npolys] = p;
                f->index[pi] = f->npolys++;
            }
    }
    return 0;
}

void focus_free(film_focus *f) {
    free(f->index);
    free(f->polys);
    memset(f, 0, sizeof *f);
}

static int inside(const focus_poly *p, double lx, double ly) {
    for (int i = 0; i < p->n; i++) {
        int j = (i + 1) % p->n;
        if ((p->x[j] - p->x[i]) * (ly - p->y[i]) - (p->y[j] - p->y[i]) * (lx - p->x[i]) < 0) return 0;
    }
    return 1;
}

double focus_weight(const focus_poly *p, double lx, double ly) {
    return 1 / (FOCUS_PLAIN + (inside(p, lx, ly) ? (1 - FOCUS_PLAIN) / p->area : 0));
}

double focus_film_point(const film_focus *f, int x, int y, double u, double v, double *px, double *py) {
    int i = f ? f->index[(size_t)y * (size_t)f->width + (size_t)x] : -1;
    if (i < 0) {
        *px = x + u;
        *py = y + v;
        return 1;
    }
    const focus_poly *p = &f->polys[i];
    if (u < FOCUS_PLAIN) {
        double lx = u / FOCUS_PLAIN;
        *px = x + lx;
        *py = y + v;
        return focus_weight(p, lx, v);
    }
    double t = (u - FOCUS_PLAIN) / (1 - FOCUS_PLAIN), c0 = 0;
    int j = 0;
    while (j < p->n - 3 && t >= p->cum[j]) c0 = p->cum[j++];
    double w = p->cum[j] - c0, tt = w > 0 ? (t - c0) / w : 0.5;
    if (tt > 1) tt = 1;
    double s = sqrt(tt), b1 = s * (1 - v), b2 = s * v, b0 = 1 - s;
    *px = x + b0 * p->x[0] + b1 * p->x[j + 1] + b2 * p->x[j + 2];
    *py = y + b0 * p->y[0] + b1 * p->y[j + 1] + b2 * p->y[j + 2];
    return 1 / (FOCUS_PLAIN + (1 - FOCUS_PLAIN) / p->area);
}
