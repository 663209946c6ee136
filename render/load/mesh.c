/* mesh.c: loading a mesh file by extension, placing it with a transform, and its shading
 * normals; see mesh.h.
 *
 * Smooth normals are computed from an index of the triangles around each vertex (counts,
 * prefix sums, fill: two passes, no per-vertex allocation). A corner's normal sums the
 * unnormalized geometric normals (|n| = 2 area, so larger triangles weigh more) of the
 * triangles at that vertex whose normals are within the crease angle of its own triangle's.
 */
#include "load/mesh.h"

#include <ctype.h>
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "common.h"
#include "load/obj.h"
#include "load/ply.h"
#include "base/sampling.h"
#include "load/wo3.h"

int mesh_read_file(const char *path, char **buf, size_t *len, char *err, size_t cap) {
    *buf = NULL;
    *len = 0;
    struct stat st;
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, cap, "%s: cannot open: %s", path, strerror(errno));
        return PM_EIO;
    }
    if (fstat(fileno(f), &st) < 0 || !S_ISREG(st.st_mode)) {
        fclose(f);
        snprintf(err, cap, "%s: not a regular file", path);
        return PM_EIO;
    }
    size_t n = (size_t)st.st_size;
    char *b = malloc(n + 1);
    if (!b) {
        fclose(f);
        snprintf(err, cap, "%s: out of memory (%zu bytes)", path, n);
        return PM_ENOMEM;
    }
    size_t got = fread(b, 1, n, f);
    int bad = ferror(f);
    fclose(f);
    if (bad || got != n) {
        free(b);
        snprintf(err, cap, "%s: read error", path);
        return PM_EIO;
    }
    b[n] = 0;
    *buf = b;
    *len = n;
    return 0;
}

static int has_ext(const char *path, const char *ext) {
    size_t lp = strlen(path), le = strlen(ext);
    if (lp < le) return 0;
    for (size_t i = 0; i < le; i++)
        if (tolower((unsigned char)path[lp - le + i]) != ext[i]) return 0;
    return 1;
}

int mesh_load(const char *path, mesh_data *m, char *err, size_t cap) {
    memset(m, 0, sizeof *m);
    int is_obj = has_ext(path, ".obj"), is_ply = has_ext(path, ".ply");
    if (!is_obj && !is_ply && !has_ext(path, ".wo3")) {
        snprintf(err, cap, "%s: unknown mesh format (the name must end in .obj, .ply or .wo3)", path);
        return PM_EINVAL;
    }
    char *buf;
    size_t len;
    int rc = mesh_read_file(path, &buf, &len, err, cap);
    if (rc < 0) return rc;
    rc = is_obj   ? obj_parse(buf, len, path, m, err, cap)
         : is_ply ? ply_parse(buf, len, path, m, err, cap)
                  : wo3_parse((const unsigned char *)buf, len, path, m, err, cap);
    free(buf);
    return rc;
}

/* |v| without squaring: no underflow for tiny vectors (1e-160 squared is 0 in a double), no
 * overflow for huge ones. */
static double len_scaled(vec3 v) {
    double mx = v3_maxabs(v);
    if (!(mx > 0) || !isfinite(mx)) return mx;
    return mx * v3_len(v3_scale(v, 1 / mx));
}

static vec3 xf_point(const double M[3][4], vec3 p) {
    return v3(M[0][0] * p.x + M[0][1] * p.y + M[0][2] * p.z + M[0][3],
              M[1][0] * p.x + M[1][1] * p.y + M[1][2] * p.z + M[1][3],
              M[2][0] * p.x + M[2][1] * p.y + M[2][2] * p.z + M[2][3]);
}

static double tri_longest(vec3 a, vec3 b, vec3 c) {
    return fmax(len_scaled(v3_sub(b, a)), fmax(len_scaled(v3_sub(c, b)), len_scaled(v3_sub(a, c))));
}

int mesh_transform_lengths(const mesh_data *m, const double M[3][4], double len_min, double len_max,
                           char *err, size_t cap) {
    for (int k = 0; k < m->npos; k++) {
        vec3 p = m->pos[k], q = xf_point(M, p);
        if (v3_maxabs(p) <= len_max && !(v3_maxabs(q) <= len_max)) {
            snprintf(err, cap, "moves the file's vertex %d, [%g, %g, %g], to [%g, %g, %g], outside the "
                     "supported range of coordinates, -%g to %g", k + 1, p.x, p.y, p.z, q.x, q.y, q.z,
                     len_max, len_max);
            return PM_EINVAL;
        }
    }
    for (int t = 0; t < m->ntris; t++) {
        const int *v = m->tri[t];
        double before = tri_longest(m->pos[v[0]], m->pos[v[1]], m->pos[v[2]]);
        double after = tri_longest(xf_point(M, m->pos[v[0]]), xf_point(M, m->pos[v[1]]),
                                   xf_point(M, m->pos[v[2]]));
        /* 0 after is a collapse (a singular transform, or a tiny mesh far from the origin),
         * not a length out of range: mesh_transform and the scene's triangles say so. */
        if (before >= len_min && after > 0 && after < len_min) {
            snprintf(err, cap, "makes a triangle %g across in the file %g across, below the "
                     "supported range of lengths, %g to %g", before, after, len_min, len_max);
            return PM_EINVAL;
        }
    }
    return 0;
}

int mesh_transform(mesh_data *m, const double M[3][4], const char *path, char *err, size_t cap) {
    int finite = 1;
    for (int r = 0; r < 3; r++)
        for (int k = 0; k < 4; k++) finite &= isfinite(M[r][k]) != 0;
    if (!finite) {
        snprintf(err, cap, "%s: the transform is not finite", path);
        return PM_EINVAL;
    }
    /* The singular test and the normals use N, the matrix with unit columns: M = N D with
     * D = diag(column lengths). |det N| is the volume the unit columns span, 1 for any rotation
     * and scale (uniform or not) and 0 when they are linearly dependent: a test of M's
     * determinant itself said "singular" for a uniform scale of 1e-150 (det 1e-450 underflows
     * to 0) and for 1e150 (det overflows). Normals take M's inverse transpose,
     * N^-T D^-1 = cof(N) D^-1 / det N: D^-1 is applied as lmin / len (all <= 1, no
     * overflow), and cof(N) has entries of at most 1 (cofactors of M itself, of order
     * scale^2, underflowed for a scale of 1e-90: NaN normals). */
    double len[3], N[3][3];
    int zero = -1;
    for (int k = 0; k < 3; k++) {
        len[k] = len_scaled(v3(M[0][k], M[1][k], M[2][k]));
        if (!(len[k] > 0) && zero < 0) zero = k;
    }
    if (zero >= 0) {
        snprintf(err, cap, "%s: the transform is singular (its column %d is zero: it flattens the "
                 "mesh)", path, zero + 1);
        return PM_EINVAL;
    }
    for (int r = 0; r < 3; r++)
        for (int k = 0; k < 3; k++) N[r][k] = M[r][k] / len[k];
    double a = N[0][0], b = N[0][1], c = N[0][2], d = N[1][0], e = N[1][1], f = N[1][2], g = N[2][0],
           h = N[2][1], i = N[2][2];
    /* cofactors: inverse transpose = cof / det */
    double C[3][3] = {{e * i - f * h, f * g - d * i, d * h - e * g},
                      {c * h - b * i, a * i - c * g, b * g - a * h},
                      {b * f - c * e, c * d - a * f, a * e - b * d}};
    double det = a * C[0][0] + b * C[0][1] + c * C[0][2];
    if (!(fabs(det) >= MESH_SINGULAR_VOLUME)) {
        snprintf(err, cap, "%s: the transform is singular (its columns, scaled to length 1, span a "
                 "volume of %g, below %g: they are linearly dependent, and it flattens the mesh)",
                 path, fabs(det), MESH_SINGULAR_VOLUME);
        return PM_EINVAL;
    }
    double lmin = fmin(len[0], fmin(len[1], len[2]));
    vec3 dinv = v3(lmin / len[0], lmin / len[1], lmin / len[2]);
    for (int k = 0; k < m->npos; k++) m->pos[k] = xf_point(M, m->pos[k]);
    for (int k = 0; k < m->nnrm; k++) {
        vec3 n = v3_mul(m->nrm[k], dinv);
        m->nrm[k] = v3_norm(v3(C[0][0] * n.x + C[0][1] * n.y + C[0][2] * n.z,
                               C[1][0] * n.x + C[1][1] * n.y + C[1][2] * n.z,
                               C[2][0] * n.x + C[2][1] * n.y + C[2][2] * n.z));
        if (det < 0) m->nrm[k] = v3_neg(m->nrm[k]); /* cof = det * inv^T: undo det's sign */
    }
    return 0;
}

static vec3 tri_cross(const mesh_data *m, int t) {
    vec3 a = m->pos[m->tri[t][0]], b = m->pos[m->tri[t][1]], c = m->pos[m->tri[t][2]];
    return v3_cross(v3_sub(b, a), v3_sub(c, a));
}

double mesh_area(const mesh_data *m) {
    double s = 0;
    for (int t = 0; t < m->ntris; t++) s += 0.5 * v3_len(tri_cross(m, t));
    return s;
}

int mesh_smooth_normals(mesh_data *m, int recompute) {
    free(m->corner_n);
    m->corner_n = malloc((size_t)(m->ntris ? m->ntris : 1) * sizeof *m->corner_n);
    int *start = calloc((size_t)m->npos + 1, sizeof *start);
    int *list = malloc((size_t)(m->ntris ? m->ntris : 1) * 3 * sizeof *list);
    vec3 *ng = malloc((size_t)(m->ntris ? m->ntris : 1) * sizeof *ng);
    int *fill = malloc((size_t)(m->npos ? m->npos : 1) * sizeof *fill);
    if (!m->corner_n || !start || !list || !ng || !fill) {
        free(start);
        free(list);
        free(ng);
        free(fill);
        free(m->corner_n);
        m->corner_n = NULL;
        return PM_ENOMEM;
    }
    for (int t = 0; t < m->ntris; t++) {
        ng[t] = tri_cross(m, t);
        for (int k = 0; k < 3; k++) start[m->tri[t][k] + 1]++;
    }
    for (int v = 0; v < m->npos; v++) start[v + 1] += start[v];
    memcpy(fill, start, (size_t)m->npos * sizeof *fill);
    for (int t = 0; t < m->ntris; t++)
        for (int k = 0; k < 3; k++) list[fill[m->tri[t][k]]++] = t;
    free(fill);
    const double cos_crease = cos(MESH_CREASE_DEG * M_PI / 180.0);
    for (int t = 0; t < m->ntris; t++) {
        vec3 n0 = v3_norm(ng[t]);
        for (int k = 0; k < 3; k++) {
            vec3 n;
            int fi = m->tri_n && !recompute ? m->tri_n[t][k] : -1;
            if (fi >= 0) {
                n = v3_norm(m->nrm[fi]);
            } else {
                int v = m->tri[t][k];
                n = v3s(0);
                for (int j = start[v]; j < start[v + 1]; j++) {
                    vec3 o = ng[list[j]];
                    if (v3_dot(v3_norm(o), n0) >= cos_crease) n = v3_add(n, o);
                }
                n = v3_norm(n);
            }
            /* shading normals shade; the geometric normal keeps the side */
            if (!(v3_dot(n, n0) > 0)) n = v3_dot(n, n0) < 0 ? v3_neg(n) : n0;
            m->corner_n[t][k] = n;
        }
    }
    free(start);
    free(list);
    free(ng);
    return 0;
}
