/* knn_example.c: the smallest complete use of the photonmap module, built against the
 * installed library exactly as another project would:
 *
 *   make install PREFIX=$HOME/.local
 *   cc -std=c11 knn_example.c $(pkg-config --cflags --libs photonmap) -o knn_example
 *
 * It stores random photons on a floor, builds the left-balanced kd-tree over them (which
 * reorders the array), finds the 50 photons nearest to a point within a maximum radius, and
 * sums their power for Jensen's density estimate L ~ sum(power) / (pi r^2).
 */
#include <photonmap/photonmap.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int main(int argc, char **argv) {
    enum { N = 100000, K = 50 };
    if (argc > 1) {
        int help = strcmp(argv[1], "--help") == 0 || strcmp(argv[1], "-h") == 0;
        fprintf(help ? stdout : stderr,
                "usage: knn_example\n"
                "Stores %d photons on the unit floor square (total power 1, 1, 0.8), finds the\n"
                "%d nearest to its centre and prints their flux density (about 1, 1, 0.8).\n"
                "Exit status 0 when %d photons were found.\n",
                N, K, K);
        return help ? 0 : 2;
    }
    pm_photon *photons = malloc(N * sizeof *photons);
    if (!photons) return 1;
    unsigned seed = 1; /* tests/test_example.c repeats these points as its oracle */
    for (int i = 0; i < N; i++) {
        seed = seed * 1664525u + 1013904223u;
        float x = (float)(seed >> 8) / 16777216.0f;
        seed = seed * 1664525u + 1013904223u;
        float z = (float)(seed >> 8) / 16777216.0f;
        float pos[3] = {x, 0.0f, z}, power[3] = {1e-5f, 1e-5f, 0.8e-5f};
        float dir[3] = {0.0f, -1.0f, 0.0f}, normal[3] = {0.0f, 1.0f, 0.0f};
        pm_photon_init(&photons[i], pos, power, dir, normal, PM_KIND_INDIRECT);
    }

    pm_kdtree *tree;
    pm_kdtree_config cfg = pm_kdtree_photon_config(PM_KDTREE_BUCKET_DEFAULT); /* B = 32 */
    int rc = pm_kdtree_build(&tree, photons, N, &cfg, NULL);
    if (rc < 0) {
        fprintf(stderr, "build: %s\n", pm_strerror(rc));
        return 1;
    }

    const float q[3] = {0.5f, 0.0f, 0.5f};
    pm_neighbor nb[K];
    int found = pm_kdtree_knn(tree, q, K, 0.01f /* max squared radius */, nb, PM_SORT, NULL);
    if (found < 0) {
        fprintf(stderr, "knn: %s\n", pm_strerror(found));
        return 1;
    }
    float sum[3] = {0, 0, 0};
    for (int i = 0; i < found; i++) {
        const pm_photon *p = &photons[nb[i].index]; /* indices refer to the reordered array */
        float c[3];
        pm_rgbe_decode(p->power, c);
        for (int j = 0; j < 3; j++) sum[j] += c[j];
    }
    float r2 = found ? nb[found - 1].dist2 : 0.0f; /* sorted: the last is the farthest */
    printf("found %d photons, nearest dist2 %.3g, farthest dist2 %.3g\n", found,
           found ? nb[0].dist2 : 0.0f, r2);
    if (r2 > 0)
        printf("flux density %.4g %.4g %.4g\n", sum[0] / (3.14159265f * r2),
               sum[1] / (3.14159265f * r2), sum[2] / (3.14159265f * r2));
    pm_kdtree_free(tree);
    free(photons);
    return found == K ? 0 : 1;
}
