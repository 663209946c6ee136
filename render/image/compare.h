/* compare.h: numerical comparison of two linear images (PFM), whole or in a rectangle.
 *
 * Used by `render --compare A.pfm B.pfm [--rect x y w h] [--mask IDS.pfm --id N...]` (and scripts/imgcmp), with B the
 * reference. Reported:
 *   rmse       sqrt(mean over pixels and channels of (a - b)^2)
 *   mean_a/b   mean over pixels and channels (the mean radiance)
 *   rel_mean   (mean_a - mean_b) / mean_b: the bias of A's mean radiance
 *   mre        mean relative error: mean over pixels and channels of |a - b| / (|b| + eps),
 *              with eps = 0.01 * mean |b|, so black reference pixels do not divide by zero
 *   rel_rmse   rmse / mean_b
 * Pure; the caller owns the films.
 */
#ifndef RENDER_COMPARE_H
#define RENDER_COMPARE_H

#include "image/film.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct image_diff {
    double rmse, mean_a, mean_b, rel_mean, mre, rel_rmse;
    long npixels;
} image_diff;

/* A region: the rectangle (x, y, w, h), clipped to the image (w <= 0 or h <= 0: the whole
 * image), and, if mask is not NULL, only the pixels that see one of the objects ids[0..nids)
 * alone in a `render --mode objects` image (R = B = id exactly and G = R^2: object index + 1,
 * see objects.c). */
typedef struct image_region {
    int x, y, w, h;
    const film *mask;
    const int *ids;
    int nids;
} image_region;

/* Compare a against the reference b over region r. Returns 0, or PM_EINVAL if the sizes
 * differ or the region holds no pixel. */
int image_compare_region(const film *a, const film *b, const image_region *r, image_diff *d);

/* Write a PNG of the luminance difference a - b, relative to the mean luminance of b and
 * divided by scale (so scale = 0.25 saturates at 25% of the mean): orange where a is
 * brighter, blue where it is darker, black where they agree. 0 or a negative PM_E* code. */
int image_diff_png(const film *a, const film *b, double scale, const char *path);

/* Compare a against the reference b in the rectangle (x, y, w, h), clipped to the image;
 * w <= 0 or h <= 0 means the whole image. Returns 0, or PM_EINVAL if the sizes differ or
 * the rectangle is empty. */
int image_compare(const film *a, const film *b, int x, int y, int w, int h, image_diff *d);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_COMPARE_H */
