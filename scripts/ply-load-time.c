/* ply-load-time.c: our PLY reader (render/load/ply.c, through mesh_load) against Debian's
 * libassimp (its C API, aiImportFile with aiProcess_Triangulate), by load time and by the
 * triangles each returns, on PLY files written here. scripts/gen-import-md.sh --run-ply builds
 * and runs it; by hand:
 *
 *   cc -O2 -std=c11 -D_POSIX_C_SOURCE=200809L -Irender -I. -Iphotonmap scripts/ply-load-time.c \
 *      build/release/obj/render/load/{mesh,obj,ply,wo3}.o build/release/obj/render/scene/shapes.o \
 *      -lassimp -lm -o /tmp/ply-load-time && /tmp/ply-load-time DIR [N] [RUNS]
 *
 * The files, in DIR: a grid of N x N quads (2 N^2 triangles; N = 708 gives 1,002,528) with a
 * wave in z, vertices with a normal, an RGB colour and a confidence, faces of 4 corners, as
 * ASCII, binary little-endian and binary big-endian; the same grid as triangle strips (one
 * strip per row, restarts at -1); and the little-endian grid with every 100th quad collapsed to
 * zero area (two corners at one point). The oracle for the counts is the construction: 2 N^2
 * triangles, and 2 N^2 - 2 ceil(N^2 / 100) non-degenerate ones in the last file.
 *
 * Output: CSV on stdout, one row per file and reader: file, bytes, reader, triangles_expected,
 * triangles, cpu_s (process CPU time of one load, median of RUNS).
 */
#include <assimp/cimport.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "load/mesh.h"

static int host_big(void) {
    uint16_t one = 1;
    unsigned char lo;
    memcpy(&lo, &one, 1);
    return lo != 1;
}

static void put(FILE *f, const void *p, size_t n, int big) {
    unsigned char t[8];
    memcpy(t, p, n);
    if (big != host_big())
        for (size_t i = 0; i < n / 2; i++) {
            unsigned char c = t[i];
            t[i] = t[n - 1 - i];
            t[n - 1 - i] = c;
        }
    fwrite(t, 1, n, f);
}

/* enc: 0 ascii, 1 LE, 2 BE; strips: faces as one strip per row; degen: every 100th quad flat */
static int write_grid(const char *path, int n, int enc, int strips, int degen) {
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    int nv = (n + 1) * (n + 1);
    fprintf(f, "ply\nformat %s 1.0\ncomment grid of %d x %d quads\nelement vertex %d\n", enc == 0 ? "ascii"
            : enc == 1 ? "binary_little_endian" : "binary_big_endian", n, n, nv);
    fprintf(f, "property float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\n"
               "property float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
               "property float confidence\n");
    if (strips)
        fprintf(f, "element tristrips %d\nproperty list int int vertex_indices\nend_header\n", n);
    else
        fprintf(f, "element face %d\nproperty list uchar int vertex_indices\nend_header\n", n * n);
    for (int j = 0; j <= n; j++)
        for (int i = 0; i <= n; i++) {
            float x = (float)i / (float)n, y = (float)j / (float)n;
            float z = 0.05f * sinf(12.0f * x) * cosf(9.0f * y);
            float dzx = 0.05f * 12.0f * cosf(12.0f * x) * cosf(9.0f * y), dzy = -0.05f * 9.0f * sinf(12.0f * x) * sinf(9.0f * y);
            float l = sqrtf(dzx * dzx + dzy * dzy + 1);
            float v[6] = {x, y, z, -dzx / l, -dzy / l, 1 / l};
            unsigned char c[3] = {(unsigned char)(255 * x), (unsigned char)(255 * y), 128};
            float conf = 0.75f;
            if (enc == 0) {
                fprintf(f, "%.9g %.9g %.9g %.9g %.9g %.9g %d %d %d %g\n", v[0], v[1], v[2], v[3], v[4], v[5], c[0], c[1],
                        c[2], conf);
            } else {
                for (int k = 0; k < 6; k++) put(f, &v[k], 4, enc == 2);
                fwrite(c, 1, 3, f);
                put(f, &conf, 4, enc == 2);
            }
        }
    long q = 0;
    for (int j = 0; j < n; j++) {
        if (strips) { /* row j: (j, i) and (j+1, i) alternately: 2n + 2 indices */
            int32_t cnt = 2 * n + 2;
            if (enc == 0) fprintf(f, "%d", cnt);
            else put(f, &cnt, 4, enc == 2);
            for (int i = 0; i <= n; i++) {
                int32_t a = j * (n + 1) + i, b = (j + 1) * (n + 1) + i;
                if (enc == 0) fprintf(f, " %d %d", a, b);
                else {
                    put(f, &a, 4, enc == 2);
                    put(f, &b, 4, enc == 2);
                }
            }
            if (enc == 0) fprintf(f, "\n");
            continue;
        }
        for (int i = 0; i < n; i++, q++) {
            int32_t a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
            if (degen && q % 100 == 0) { /* (a b b a): both fan triangles have zero area */
                c = b;
                d = a;
            }
            unsigned char k4 = 4;
            if (enc == 0) fprintf(f, "4 %d %d %d %d\n", a, b, c, d);
            else {
                fwrite(&k4, 1, 1, f);
                put(f, &a, 4, enc == 2);
                put(f, &b, 4, enc == 2);
                put(f, &c, 4, enc == 2);
                put(f, &d, 4, enc == 2);
            }
        }
    }
    return fclose(f);
}

static double cpu_now(void) { return (double)clock() / CLOCKS_PER_SEC; }

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: ply-load-time DIR [N] [RUNS]\n");
        return 2;
    }
    int n = argc > 2 ? atoi(argv[2]) : 708, runs = argc > 3 ? atoi(argv[3]) : 3;
    if (n < 1 || runs < 1 || runs > 15) return 2;
    static const struct {
        const char *name;
        int enc, strips, degen;
    } files[] = {{"grid_ascii.ply", 0, 0, 0}, {"grid_le.ply", 1, 0, 0}, {"grid_be.ply", 2, 0, 0},
                 {"grid_strips_le.ply", 1, 1, 0}, {"grid_degenerate_le.ply", 1, 0, 1}};
    printf("file,bytes,reader,triangles_expected,triangles,cpu_s\n");
    for (size_t fi = 0; fi < sizeof files / sizeof *files; fi++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", argv[1], files[fi].name);
        if (write_grid(path, n, files[fi].enc, files[fi].strips, files[fi].degen) != 0) {
            fprintf(stderr, "cannot write %s\n", path);
            return 1;
        }
        struct stat st;
        stat(path, &st);
        long nq = (long)n * n, expect = 2 * nq - (files[fi].degen ? 2 * ((nq + 99) / 100) : 0);
        for (int reader = 0; reader < 2; reader++) {
            double t[15];
            long tris = -1;
            for (int r = 0; r < runs; r++) {
                double t0 = cpu_now();
                if (reader == 0) {
                    mesh_data m;
                    char err[400];
                    if (mesh_load(path, &m, err, sizeof err) < 0) {
                        fprintf(stderr, "ours: %s\n", err);
                        tris = -1;
                    } else {
                        tris = m.ntris;
                    }
                    mesh_free(&m);
                } else {
                    const struct aiScene *s = aiImportFile(path, aiProcess_Triangulate);
                    tris = -1;
                    if (!s) {
                        fprintf(stderr, "assimp: %s: %s\n", path, aiGetErrorString());
                    } else {
                        tris = 0;
                        for (unsigned i = 0; i < s->mNumMeshes; i++)
                            for (unsigned k = 0; k < s->mMeshes[i]->mNumFaces; k++)
                                tris += s->mMeshes[i]->mFaces[k].mNumIndices == 3;
                        aiReleaseImport(s);
                    }
                }
                t[r] = cpu_now() - t0;
            }
            qsort(t, (size_t)runs, sizeof *t, cmp_d);
            printf("%s,%lld,%s,%ld,%ld,%.3f\n", files[fi].name, (long long)st.st_size, reader ? "assimp" : "ours", expect,
                   tris, t[(runs - 1) / 2]);
            fflush(stdout);
        }
    }
    return 0;
}
