/* compare.c: RMSE and relative errors between two films; see compare.h. */
#include "compare.h"

#include "common.h"

int image_compare(const film *a, const film *b, int x, int y, int w, int h, image_diff *d) {
    if (a->width != b->width || a->height != b->height) return PM_EINVAL;
    if (w <= 0 || h <= 0) {
        x = y = 0;
        w = a->width;
        h = a->height;
    }
    int x0 = x < 0 ? 0 : x, y0 = y < 0 ? 0 : y;
    int x1 = x + w > a->width ? a->width : x + w, y1 = y + h > a->height ? a->height : y + h;
    if (x1 <= x0 || y1 <= y0) return PM_EINVAL;
    double se = 0, sa = 0, sb = 0, sab = 0;
    long n = 0;
    for (int yy = y0; yy < y1; yy++)
        for (int xx = x0; xx < x1; xx++)
            for (int c = 0; c < 3; c++) {
                double va = a->px[3 * ((long)yy * a->width + xx) + c];
                double vb = b->px[3 * ((long)yy * b->width + xx) + c];
                se += (va - vb) * (va - vb);
                sa += va;
                sb += vb;
                sab += fabs(vb);
                n++;
            }
    double eps = 0.01 * sab / (double)n;
    if (!(eps > 0)) eps = 1e-12;
    double mre = 0;
    for (int yy = y0; yy < y1; yy++)
        for (int xx = x0; xx < x1; xx++)
            for (int c = 0; c < 3; c++) {
                double va = a->px[3 * ((long)yy * a->width + xx) + c];
                double vb = b->px[3 * ((long)yy * b->width + xx) + c];
                mre += fabs(va - vb) / (fabs(vb) + eps);
            }
    d->npixels = (long)(x1 - x0) * (y1 - y0);
    d->rmse = sqrt(se / (double)n);
    d->mean_a = sa / (double)n;
    d->mean_b = sb / (double)n;
    d->rel_mean = d->mean_b != 0 ? (d->mean_a - d->mean_b) / d->mean_b : 0;
    d->rel_rmse = d->mean_b != 0 ? d->rmse / fabs(d->mean_b) : 0;
    d->mre = mre / (double)n;
    return 0;
}
