/* test_render_media_beam.c: the beam radiance estimate of the volume photon maps (pm_beam.h)
 * and the volume stride of the photon mapper's camera samples (pm_sample.h, VOLUME STRIDE).
 *
 * 1. The beam estimate of a random photon cloud against a brute force written here: each
 *    photon's radius from a scan of all photons (the k-th smallest distance, itself included),
 *    its kernel 1 / (4/3 pi r^3), and the integral along the ray by fine midpoint quadrature of
 *    the sum of every photon's kernel times HG phase times exp(-sigma_t t), per channel.
 * 2. A uniform Poisson cloud: the beam estimate's mean over many segments against the exact
 *    in-scattered radiance of the cloud's density (the sample-point estimate has no (k - 1) / k
 *    bias to remove: each photon's power is spread over its own ball).
 * 3. The volume stride keeps the image: cornell_fog rendered with the in-scattering read at
 *    every sample and at one in 4 x 4 (weighted 16), the same photon maps; the image means and
 *    the region of the fog's brightest part agree within the samples' noise.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "../render/base/rng.h"
#include "../render/image/compare.h"
#include "../render/image/film.h"
#include "../render/photon_mapping/pm_beam.h"
#include "../render/scene/medium.h"

/* n photons uniform in [lo, lo + L)^3 (stream seed), power pw (grey when col is 0), random
 * directions; built into a kd-tree (*t, reorders a). */
static pm_photon *cloud(size_t n, double lo, double L, uint64_t seed, int col, pm_kdtree **t) {
    pm_photon *a = malloc(n * sizeof *a);
    if (!a) return NULL;
    for (size_t i = 0; i < n; i++) {
        rng g = rng_stream(seed, i, 0);
        float p[3], pw[3], d[3];
        for (int c = 0; c < 3; c++) p[c] = (float)(lo + L * rng_uniform(&g));
        for (int c = 0; c < 3; c++) pw[c] = col ? (float)(0.5 + rng_uniform(&g)) : 1.0f;
        double z = 1 - 2 * rng_uniform(&g), ph = 2 * M_PI * rng_uniform(&g), s = sqrt(fmax(0, 1 - z * z));
        d[0] = (float)(s * cos(ph)), d[1] = (float)(s * sin(ph)), d[2] = (float)z;
        pm_photon_init(&a[i], p, pw, d, NULL, PM_KIND_INDIRECT);
    }
    pm_kdtree_config cfg = pm_kdtree_photon_config(0);
    if (pm_kdtree_build(t, a, n, &cfg, NULL) != 0) {
        free(a);
        return NULL;
    }
    return a;
}

static int cmp_double(const void *x, const void *y) {
    double a = *(const double *)x, b = *(const double *)y;
    return a < b ? -1 : a > b;
}

/* Oracle: brute force (above). 600 photons with random colours and directions in the unit
 * cube, k 10, search limit 0.25; 24 rays from outside the cube through it, segments of random
 * length (some ending inside it), sigma_t (0.5, 1, 2), HG g 0.4 (and one set of rays isotropic
 * with grey sigma_t 0.7, the estimate's other branch). Quadrature: 40,000 midpoints; each
 * chord's two ends are off by at most one step, so the sums agree within 0.2% (relative) of
 * each channel. */
TEST(media_beam_matches_quadrature) {
    const size_t n = 600;
    const unsigned k = 10;
    const float r2max = 0.0625f;
    pm_kdtree *t = NULL;
    pm_photon *a = cloud(n, 0, 1, 11, 1, &t);
    ASSERT(a && t);
    pmv_beam b;
    ASSERT_EQ_INT(pmv_beam_build(&b, NULL, t, a, n, k, r2max, 0), 0);
    ASSERT(b.n == n);
    /* the brute force's radii and kernels */
    double *r2 = malloc(n * sizeof *r2), *d2 = malloc(n * sizeof *d2);
    ASSERT(r2 && d2);
    for (size_t i = 0; i < n; i++) {
        size_t m = 0;
        for (size_t j = 0; j < n; j++) {
            double dd = 0;
            for (int c = 0; c < 3; c++) {
                double x = (double)a[i].pos[c] - a[j].pos[c];
                dd += x * x;
            }
            if (dd < r2max) d2[m++] = dd;
        }
        qsort(d2, m, sizeof *d2, cmp_double);
        r2[i] = m >= k ? d2[k - 1] : r2max;
    }
    int bad = 0;
    for (int set = 0; set < 2; set++) {
        double g = set ? 0 : 0.4;
        rgb st = set ? v3s(0.7) : v3(0.5, 1, 2);
        double sg[3] = {st.x, st.y, st.z};
        for (int q = 0; q < 12; q++) {
            rng h = rng_stream(12, (uint64_t)q, (uint64_t)set);
            vec3 o = v3(-0.5, rng_uniform(&h), rng_uniform(&h)), to = v3(1.5, rng_uniform(&h), rng_uniform(&h));
            vec3 d = v3_norm(v3_sub(to, o));
            double T = (0.8 + 1.2 * rng_uniform(&h)) * v3_len(v3_sub(to, o)) / 1.5;
            ray r = {o, d};
            uint64_t hits = 0;
            rgb e = pmv_beam_segment(&b, r, T, st, g, &hits);
            double got[3] = {e.x, e.y, e.z}, want[3] = {0, 0, 0};
            const int M = 40000;
            double dt = T / M;
            for (size_t i = 0; i < n; i++) {
                vec3 p = v3(a[i].pos[0], a[i].pos[1], a[i].pos[2]);
                vec3 v = v3_sub(p, o);
                double tc = v3_dot(v, d);
                if (v3_dot(v, v) - tc * tc >= r2[i]) continue; /* the line misses the ball */
                float pw[3], pd[3];
                pm_rgbe_decode(a[i].power, pw);
                pm_dir_decode(a[i].theta, a[i].phi, pd);
                double ph = hg_phase(g, -(pd[0] * d.x + pd[1] * d.y + pd[2] * d.z));
                double kern = 1 / (4.0 / 3.0 * M_PI * r2[i] * sqrt(r2[i]));
                double acc[3] = {0, 0, 0};
                for (int j = 0; j < M; j++) {
                    double tt = (j + 0.5) * dt;
                    vec3 x = v3_sub(ray_at(r, tt), p);
                    if (v3_dot(x, x) >= r2[i]) continue;
                    for (int c = 0; c < 3; c++) acc[c] += exp(-sg[c] * tt) * dt;
                }
                for (int c = 0; c < 3; c++) want[c] += ph * pw[c] * kern * acc[c];
            }
            for (int c = 0; c < 3; c++)
                if (!(fabs(got[c] - want[c]) <= 2e-3 * want[c] + 1e-12)) {
                    if (bad++ < 5)
                        printf("    set %d ray %d channel %d: beam %.6g, quadrature %.6g (%llu photons)\n", set, q, c,
                               got[c], want[c], (unsigned long long)hits);
                }
        }
    }
    EXPECT_MSG(bad == 0, "%d channels of 72 off the quadrature by more than 0.2%%", bad);
    free(r2);
    free(d2);
    pmv_beam_free(&b);
    pm_kdtree_free(t);
    free(a);
}

/* Oracle: the cloud's density. 8 clouds of 40,000 photons of power 1 in a 4 x 4 x 4 box
 * (density 625), k 16 (radii about 0.18), no search limit; in each, 49 segments of length 1
 * along x on a 7 x 7 grid of (y, z) in [1.4, 2.6], all more than 1.2 from the box's faces.
 * Isotropic, grey sigma_t 0.5: each segment's exact in-scattered radiance is 625 / (4 pi) (1 -
 * e^{-0.5}) / 0.5. The mean over the 392 segments must be within 4 standard errors (from
 * the 8 clouds' means) and within 2% of it. A per-point estimate without the (k - 1) / k factor
 * would read 6.7% high at k 16. */
TEST(media_beam_uniform_cloud_reads_its_density) {
    const size_t n = 40000;
    const double rho = (double)n / 64, sig = 0.5;
    const double want = rho / (4 * M_PI) * (1 - exp(-sig)) / sig;
    double m1 = 0, m2 = 0;
    const int nc = PM_TEST_SANITIZED ? 2 : 8;
    for (int cl = 0; cl < nc; cl++) {
        pm_kdtree *t = NULL;
        pm_photon *a = cloud(n, 0, 4, 100 + (uint64_t)cl, 0, &t);
        ASSERT(a && t);
        pmv_beam b;
        ASSERT_EQ_INT(pmv_beam_build(&b, NULL, t, a, n, 16, INFINITY, 0), 0);
        double s = 0;
        for (int iy = 0; iy < 7; iy++)
            for (int iz = 0; iz < 7; iz++) {
                ray r = {v3(1.5, 1.4 + 0.2 * iy, 1.4 + 0.2 * iz), v3(1, 0, 0)};
                s += pmv_beam_segment(&b, r, 1.0, v3s(sig), 0, NULL).y;
            }
        s /= 49;
        m1 += s;
        m2 += s * s;
        pmv_beam_free(&b);
        pm_kdtree_free(t);
        free(a);
    }
    double mean = m1 / nc, se = sqrt(fmax(0, m2 / nc - mean * mean) / (nc > 1 ? nc - 1 : 1));
    printf("    beam mean %.5g, exact %.5g (%+.2f%%, standard error %.2f%%)\n", mean, want, 100 * (mean / want - 1),
           100 * se / want);
    EXPECT_MSG(fabs(mean - want) <= 4 * se + 1e-9 && fabs(mean / want - 1) <= 0.02, "mean %g vs %g (se %g)", mean, want,
               se);
}

/* Oracle: the stride is unbiased (each sample's in-scattering is read with probability 1/16
 * at weight 16 over the pixel's strata), so with the same photon maps (the same seed) and the
 * same camera samples' count the two images differ only by the samples' noise. cornell_fog at
 * 24x24, 64 spp (strata 8), volume_stride 1 and 4: the image means within 1.5%, and the mean
 * over the pixels' absolute relative difference below 15% (measured at 4 vs 1, seed 3: image
 * -0.35%, pixels 5.8%). */
TEST(media_volume_stride_keeps_the_image) {
    static char out[65536];
    char cmd[8192], scn[2048], im[2][2048];
    const char *dir = pm_test_tmpdir();
    snprintf(scn, sizeof scn, "%s/data/scenes/cornell_fog.json", pm_test_source_dir());
    const int strides[2] = {1, 4};
    for (int i = 0; i < 2; i++) {
        snprintf(im[i], sizeof im[i], "%s/stride%d.pfm", dir, strides[i]);
        snprintf(cmd, sizeof cmd, "%s/render '%s' --width 24 --height 24 --spp 64 --quiet --threads 2 --mode pm --seed 3 "
                 "--pm volume_stride=%d --hdr '%s' -o '%s/stride.png'", pm_test_build_dir(), scn, strides[i], im[i], dir);
        ASSERT_MSG(pm_test_run(cmd, out, sizeof out) == 0, "%s", out);
    }
    film A, B;
    ASSERT_EQ_INT(film_read_pfm(&A, im[0]), 0);
    ASSERT_EQ_INT(film_read_pfm(&B, im[1]), 0);
    image_diff d;
    ASSERT_EQ_INT(image_compare(&B, &A, 0, 0, 0, 0, &d), 0);
    printf("    volume_stride 4 vs 1: image %+.2f%%, mean relative difference of the pixels %.2f%%\n", 100 * d.rel_mean,
           100 * d.mre);
    EXPECT_MSG(fabs(d.rel_mean) <= 0.015, "image mean %+.2f%%", 100 * d.rel_mean);
    EXPECT_MSG(d.mre <= 0.15, "pixels differ by %.1f%% on average", 100 * d.mre);
    film_free(&A);
    film_free(&B);
}
