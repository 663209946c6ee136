/* test_film.h: small helpers over render/image/film.h's framebuffers, shared by the render
 * tests that read regions of an image. */
#ifndef TEST_FILM_H
#define TEST_FILM_H

#include <math.h>
#include <stddef.h>
#include <stdio.h>

#include "../render/image/film.h"
#include "test.h"

/* Mean of the three channels over the rectangle [x0, x1) x [y0, y1) (top-left origin); 0 for
 * an empty rectangle. */
static inline double rt_rect_mean(const film *f, int x0, int y0, int x1, int y1) {
    double sum = 0;
    int n = 0;
    for (int y = y0; y < y1; y++)
        for (int x = x0; x < x1; x++) {
            const float *p = &f->px[3 * ((size_t)y * (size_t)f->width + (size_t)x)];
            sum += (p[0] + p[1] + p[2]) / 3.0;
            n++;
        }
    return n ? sum / n : 0;
}

/* Mean of the three channels over the whole image in the PFM file at path; NAN if it cannot be
 * read. */
static inline double rt_file_mean(const char *path) {
    film im;
    if (film_read_pfm(&im, path) != 0) return NAN;
    double s = rt_rect_mean(&im, 0, 0, im.width, im.height);
    film_free(&im);
    return s;
}

/* rt_file_mean of the test directory's TAG.pfm. */
static inline double rt_tmp_mean(const char *tag) {
    char p[1024];
    snprintf(p, sizeof p, "%s/%s.pfm", pm_test_tmpdir(), tag);
    return rt_file_mean(p);
}

/* The mean and the sample variance (n - 1) of x[0..n), n >= 2; the variance at least 0. */
static inline void rt_mean_var(const double *x, int n, double *mean, double *var) {
    double s1 = 0, s2 = 0;
    for (int i = 0; i < n; i++) {
        s1 += x[i];
        s2 += x[i] * x[i];
    }
    *mean = s1 / n;
    *var = fmax(0, (s2 - n * *mean * *mean) / (n - 1));
}

#endif /* TEST_FILM_H */
