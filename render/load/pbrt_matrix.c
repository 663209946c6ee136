/* pbrt_matrix.c: the pbrt converter's 4 x 4 matrices, its output coordinates and vectors for
 * the converted document (pbrt_internal.h), under every file of the converter that calls them.
 */
#include "load/pbrt_internal.h"

#include <math.h>
#include <string.h>

/* ---- matrices ----------------------------------------------------------------------------- */

void pb_ident(double m[4][4]) {
    memset(m, 0, 16 * sizeof(double));
    for (int i = 0; i < 4; i++) m[i][i] = 1;
}

void pb_mul(double a[4][4], double b[4][4], double out[4][4]) {
    double r[4][4];
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            r[i][j] = 0;
            for (int k = 0; k < 4; k++) r[i][j] += a[i][k] * b[k][j];
        }
    memcpy(out, r, sizeof r);
}

/* Inverse by Gauss-Jordan with partial pivoting; -1 when singular or not finite. */
int pb_inv(double m[4][4], double out[4][4]) {
    double a[4][8];
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 8; j++) a[i][j] = j < 4 ? m[i][j] : (j - 4 == i);
    for (int col = 0; col < 4; col++) {
        int p = col;
        for (int r = col + 1; r < 4; r++)
            if (fabs(a[r][col]) > fabs(a[p][col])) p = r;
        if (!(fabs(a[p][col]) > 1e-300) || !isfinite(a[p][col])) return -1;
        for (int j = 0; j < 8; j++) {
            double t = a[col][j];
            a[col][j] = a[p][j];
            a[p][j] = t;
        }
        double d = a[col][col];
        for (int j = 0; j < 8; j++) a[col][j] /= d;
        for (int r = 0; r < 4; r++)
            if (r != col) {
                double f = a[r][col];
                for (int j = 0; j < 8; j++) a[r][j] -= f * a[col][j];
            }
    }
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) out[i][j] = a[i][j + 4];
    return 0;
}

double pb_det3(double m[4][4]) {
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

vec3 pb_point(double m[4][4], vec3 p) {
    return v3(m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
              m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
              m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3]);
}
vec3 pb_dir(double m[4][4], vec3 d) {
    return v3(m[0][0] * d.x + m[0][1] * d.y + m[0][2] * d.z, m[1][0] * d.x + m[1][1] * d.y + m[1][2] * d.z,
              m[2][0] * d.x + m[2][1] * d.y + m[2][2] * d.z);
}

/* Output coordinates: the world, mirrored in x when pbrt's camera frame is ours mirrored. */
vec3 pb_out(const conv *c, vec3 p) { return c->mirror ? v3(0.0 - p.x, p.y, p.z) : p; } /* +0, not -0 */

cJSON *pb_jv(vec3 v) {
    double a[3] = {v.x, v.y, v.z};
    return cJSON_CreateDoubleArray(a, 3);
}
