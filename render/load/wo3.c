/* wo3.c: the reader of Tungsten's binary meshes; see wo3.h for the layout.
 *
 * The whole file is read, its size checked against the two counts before anything is
 * allocated (so a corrupt count cannot ask for terabytes), then the records are decoded with
 * memcpy (no alignment assumptions) from little-endian bytes.
 */
#include "load/wo3.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common.h"
#include "scene/shapes.h"

static int fail(char *err, size_t cap, const char *name, size_t off, const char *fmt, ...)
    __attribute__((format(printf, 5, 6)));
static int fail(char *err, size_t cap, const char *name, size_t off, const char *fmt, ...) {
    char msg[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    snprintf(err, cap, "%s: byte %zu: %s", name, off, msg);
    return PM_EINVAL;
}

static uint64_t rd_u64(const unsigned char *p) {
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--) v = v << 8 | p[i];
    return v;
}
static uint32_t rd_u32(const unsigned char *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static float rd_f32(const unsigned char *p) {
    uint32_t u = rd_u32(p);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

enum { VERT_BYTES = 32, TRI_BYTES = 16 };

int wo3_parse(const unsigned char *buf, size_t len, const char *name, mesh_data *m, char *err,
              size_t cap) {
    memset(m, 0, sizeof *m);
    if (len < 8) return fail(err, cap, name, len, "truncated: the vertex count needs 8 bytes, the file has %zu", len);
    uint64_t nv = rd_u64(buf);
    if (nv > (len - 8) / VERT_BYTES)
        return fail(err, cap, name, 0, "truncated: %llu vertices need %llu bytes after the count, the file has %zu",
                    (unsigned long long)nv, (unsigned long long)nv * VERT_BYTES, len - 8);
    size_t toff = 8 + (size_t)nv * VERT_BYTES;
    if (len - toff < 8)
        return fail(err, cap, name, toff, "truncated: the triangle count needs 8 bytes, %zu left", len - toff);
    uint64_t nt = rd_u64(buf + toff);
    size_t avail = (len - toff - 8) / TRI_BYTES;
    if (nt > avail)
        return fail(err, cap, name, toff, "truncated: %llu triangles need %llu bytes, %zu left",
                    (unsigned long long)nt, (unsigned long long)nt * TRI_BYTES, len - toff - 8);
    if (len != toff + 8 + (size_t)nt * TRI_BYTES)
        return fail(err, cap, name, toff + 8 + (size_t)nt * TRI_BYTES, "%zu bytes after the last triangle (not a wo3 file?)",
                    len - (toff + 8 + (size_t)nt * TRI_BYTES));
    if (nt == 0) return fail(err, cap, name, toff, "empty mesh: no triangle");
    if (nv > (1u << 30) || nt > (1u << 30)) return fail(err, cap, name, 0, "too many vertices or triangles for this renderer");
    m->npos = m->nnrm = (int)nv;
    m->ntris = (int)nt;
    m->pos = malloc((size_t)(nv ? nv : 1) * sizeof *m->pos);
    m->nrm = malloc((size_t)(nv ? nv : 1) * sizeof *m->nrm);
    m->tri = malloc((size_t)nt * sizeof *m->tri);
    m->tri_n = malloc((size_t)nt * sizeof *m->tri_n);
    m->tri_group = malloc((size_t)nt * sizeof *m->tri_group);
    if (!m->pos || !m->nrm || !m->tri || !m->tri_n || !m->tri_group) {
        mesh_free(m);
        snprintf(err, cap, "%s: out of memory", name);
        return PM_ENOMEM;
    }
    int rc = 0;
    for (uint64_t i = 0; i < nv && rc == 0; i++) {
        const unsigned char *p = buf + 8 + i * VERT_BYTES;
        double f[6];
        for (int k = 0; k < 6; k++) f[k] = rd_f32(p + 4 * k);
        for (int k = 0; k < 6 && rc == 0; k++)
            if (!isfinite(f[k]))
                rc = fail(err, cap, name, (size_t)(p - buf) + (size_t)(4 * k), "vertex %llu: %s %c is not finite",
                          (unsigned long long)i, k < 3 ? "position" : "normal", "xyzxyz"[k]);
        m->pos[i] = v3(f[0], f[1], f[2]);
        m->nrm[i] = v3(f[3], f[4], f[5]);
    }
    int out = 0; /* triangles kept: degenerate ones are skipped and counted (mesh.h) */
    for (uint64_t i = 0; i < nt && rc == 0; i++) {
        const unsigned char *p = buf + toff + 8 + i * TRI_BYTES;
        int v[3];
        for (int k = 0; k < 3 && rc == 0; k++) {
            uint32_t x = rd_u32(p + 4 * k);
            if (x >= nv)
                rc = fail(err, cap, name, (size_t)(p - buf) + (size_t)(4 * k),
                          "triangle %llu: vertex index %u out of range (%llu vertices)", (unsigned long long)i, x,
                          (unsigned long long)nv);
            v[k] = (int)x;
        }
        if (rc < 0) break;
        triangle t;
        if (triangle_make(&t, m->pos[v[0]], m->pos[v[1]], m->pos[v[2]], 0) < 0) {
            if (m->nskipped++ == 0)
                snprintf(m->first_skip, sizeof m->first_skip, "byte %zu (triangle %llu)", (size_t)(p - buf),
                         (unsigned long long)i);
            continue;
        }
        memcpy(m->tri[out], v, sizeof v);
        /* A zero normal cannot shade: leave such corners to mesh_smooth_normals. */
        for (int k = 0; k < 3; k++) m->tri_n[out][k] = v3_iszero(m->nrm[v[k]]) ? -1 : v[k];
        m->tri_group[out] = -1;
        out++;
    }
    if (rc == 0) m->ntris = out;
    if (rc == 0 && out == 0)
        rc = fail(err, cap, name, toff, "empty mesh: all %ld triangles are degenerate (zero area; the first at %s)",
                  m->nskipped, m->first_skip);
    if (rc < 0) mesh_free(m);
    return rc;
}
