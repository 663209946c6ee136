/* compare.h: numerical comparison of two linear images (PFM), whole or in a rectangle.
 *
 * Used by `render --compare A.pfm B.pfm [--rect x y w h]` (and scripts/imgcmp), with B the
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

#include "film.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct image_diff {
    double rmse, mean_a, mean_b, rel_mean, mre, rel_rmse;
    long npixels;
} image_diff;

/* Compare a against the reference b in the rectangle (x, y, w, h), clipped to the image;
 * w <= 0 or h <= 0 means the whole image. Returns 0, or PM_EINVAL if the sizes differ or
 * the rectangle is empty. */
int image_compare(const film *a, const film *b, int x, int y, int w, int h, image_diff *d);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_COMPARE_H */
