/* envmap.c: an environment map's lookups and its luminance sampling; see envmap.h. */
#include "scene/envmap.h"

#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"

static double clamp_open(double u) { return u < 0 ? 0 : u < 1 ? u : 0x1.fffffffffffffp-1; }

/* cos theta at the top of row r (r = h: the bottom of the last row). */
static double row_cos(const envmap *m, int r) { return cos(M_PI * r / m->h); }

static vec3 to_map(const envmap *m, vec3 d) {
    const double (*f)[3] = m->frame;
    return v3(f[0][0] * d.x + f[0][1] * d.y + f[0][2] * d.z, f[1][0] * d.x + f[1][1] * d.y + f[1][2] * d.z,
              f[2][0] * d.x + f[2][1] * d.y + f[2][2] * d.z);
}

static vec3 to_world(const envmap *m, vec3 a) { /* the transpose: frame is a rotation */
    const double (*f)[3] = m->frame;
    return v3(f[0][0] * a.x + f[1][0] * a.y + f[2][0] * a.z, f[0][1] * a.x + f[1][1] * a.y + f[2][1] * a.z,
              f[0][2] * a.x + f[1][2] * a.y + f[2][2] * a.z);
}

static rgb pixel(const envmap *m, int x, int y) {
    const float *p = &m->px[3 * ((size_t)y * (size_t)m->w + (size_t)x)];
    return v3(p[0], p[1], p[2]);
}

/* d's pixel and the fractions (cos theta within its row's band from the top, phi within its
 * column). */
static void locate(const envmap *m, vec3 d, int *x, int *y, double *fy, double *fx) {
    vec3 a = to_map(m, d);
    double z = fmax(-1, fmin(1, a.z)), th = acos(z), ph = atan2(a.y, a.x);
    if (ph < 0) ph += 2 * M_PI;
    double cx = ph / (2 * M_PI) * m->w, cy = th / M_PI * m->h;
    *x = (int)cx < m->w ? (int)cx : m->w - 1;
    *y = (int)cy < m->h ? (int)cy : m->h - 1;
    double c0 = row_cos(m, *y), c1 = row_cos(m, *y + 1);
    *fy = c0 > c1 ? (c0 - z) / (c0 - c1) : 0.5;
    *fx = cx - *x;
}

int envmap_init(envmap *m, int w, int h, float *px, const double frame[3][3]) {
    memset(m, 0, sizeof *m);
    m->w = w;
    m->h = h;
    m->px = px;
    memcpy(m->frame, frame, sizeof m->frame);
    double *rw = calloc((size_t)h, sizeof *rw), *cw = malloc((size_t)w * sizeof *cw);
    m->cols = calloc((size_t)h, sizeof *m->cols);
    if (!rw || !cw || !m->cols) {
        free(rw), free(cw);
        envmap_free(m);
        return PM_ENOMEM;
    }
    double dphi = 2 * M_PI / w;
    for (int y = 0; y < h; y++) {
        double om = dphi * (row_cos(m, y) - row_cos(m, y + 1));
        for (int x = 0; x < w; x++) {
            rgb L = pixel(m, x, y);
            cw[x] = rgb_lum(L) * om;
            rw[y] += cw[x];
            m->integral = v3_add(m->integral, v3_scale(L, om));
        }
        if (rw[y] > 0 && distrib1d_init(&m->cols[y], cw, w) < 0) {
            free(rw), free(cw);
            envmap_free(m);
            return PM_ENOMEM;
        }
        m->sigma += rw[y];
    }
    int rc = m->sigma > 0 ? distrib1d_init(&m->rows, rw, h) : PM_EINVAL;
    free(rw), free(cw);
    if (rc < 0) envmap_free(m);
    return rc;
}

void envmap_free(envmap *m) {
    if (m->cols)
        for (int y = 0; y < m->h; y++)
            if (m->cols[y].n) distrib1d_free(&m->cols[y]);
    free(m->cols);
    if (m->rows.n) distrib1d_free(&m->rows);
    free(m->px);
    memset(m, 0, sizeof *m);
}

rgb envmap_eval(const envmap *m, vec3 d) {
    int x, y;
    double fy, fx;
    locate(m, d, &x, &y, &fy, &fx);
    return pixel(m, x, y);
}

vec3 envmap_sample(const envmap *m, double u1, double u2, double *pdf) {
    double pr, pc;
    int y = distrib1d_sample(&m->rows, u1, &pr);
    if (!(pr > 0) || m->cols[y].n == 0) {
        *pdf = 0;
        return v3(0, 0, 1);
    }
    double fy = clamp_open((u1 - m->rows.cdf[y]) / (m->rows.cdf[y + 1] - m->rows.cdf[y]));
    int x = distrib1d_sample(&m->cols[y], u2, &pc);
    double fx = clamp_open((u2 - m->cols[y].cdf[x]) / (m->cols[y].cdf[x + 1] - m->cols[y].cdf[x]));
    double c0 = row_cos(m, y), c1 = row_cos(m, y + 1), z = c0 + fy * (c1 - c0), r = sqrt(fmax(0, 1 - z * z));
    double ph = 2 * M_PI * (x + fx) / m->w, om = 2 * M_PI / m->w * (c0 - c1);
    *pdf = om > 0 ? pr * pc / om : 0;
    return to_world(m, v3(r * cos(ph), r * sin(ph), z));
}

int envmap_invert(const envmap *m, vec3 d, double *u1, double *u2) {
    int x, y;
    double fy, fx;
    locate(m, d, &x, &y, &fy, &fx);
    if (m->cols[y].n == 0) return 0;
    double pr = m->rows.cdf[y + 1] - m->rows.cdf[y], pc = m->cols[y].cdf[x + 1] - m->cols[y].cdf[x];
    if (!(pr > 0) || !(pc > 0)) return 0;
    *u1 = clamp_open(m->rows.cdf[y] + fy * pr);
    *u2 = clamp_open(m->cols[y].cdf[x] + fx * pc);
    return 1;
}
