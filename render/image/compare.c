/* compare.c: RMSE and relative errors between two films, and a difference image; see
 * compare.h. Sums are in double, in two passes (the relative error needs the mean first). */
#include "image/compare.h"

#include "photonmap/common.h"

/* Is pixel (x, y) in the region? The rectangle is already clipped by the caller. */
static int in_mask(const image_region *r, int x, int y) {
    if (!r->mask) return 1;
    rgb m = film_get(r->mask, x, y);
    if (!(m.x == m.z && m.y == m.x * m.x)) return 0; /* a silhouette pixel (objects.c) */
    for (int i = 0; i < r->nids; i++)
        if (m.x == (double)r->ids[i]) return 1;
    return 0;
}

int image_compare_region(const film *a, const film *b, const image_region *r, image_diff *d) {
    if (a->width != b->width || a->height != b->height) return PM_EINVAL;
    if (r->mask && (r->mask->width != a->width || r->mask->height != a->height)) return PM_EINVAL;
    int x = r->x, y = r->y, w = r->w, h = r->h;
    if (w <= 0 || h <= 0) {
        x = y = 0;
        w = a->width;
        h = a->height;
    }
    int x0 = x < 0 ? 0 : x, y0 = y < 0 ? 0 : y;
    int x1 = x + w > a->width ? a->width : x + w, y1 = y + h > a->height ? a->height : y + h;
    if (x1 <= x0 || y1 <= y0) return PM_EINVAL;
    double se = 0, sa = 0, sb = 0, sab = 0;
    long n = 0, np = 0;
    for (int yy = y0; yy < y1; yy++)
        for (int xx = x0; xx < x1; xx++) {
            if (!in_mask(r, xx, yy)) continue;
            np++;
            for (int c = 0; c < 3; c++) {
                double va = a->px[3 * ((long)yy * a->width + xx) + c];
                double vb = b->px[3 * ((long)yy * b->width + xx) + c];
                se += (va - vb) * (va - vb);
                sa += va;
                sb += vb;
                sab += fabs(vb);
                n++;
            }
        }
    if (n == 0) return PM_EINVAL;
    double eps = 0.01 * sab / (double)n;
    if (!(eps > 0)) eps = 1e-12;
    double mre = 0;
    for (int yy = y0; yy < y1; yy++)
        for (int xx = x0; xx < x1; xx++) {
            if (!in_mask(r, xx, yy)) continue;
            for (int c = 0; c < 3; c++) {
                double va = a->px[3 * ((long)yy * a->width + xx) + c];
                double vb = b->px[3 * ((long)yy * b->width + xx) + c];
                mre += fabs(va - vb) / (fabs(vb) + eps);
            }
        }
    d->npixels = np;
    d->rmse = sqrt(se / (double)n);
    d->mean_a = sa / (double)n;
    d->mean_b = sb / (double)n;
    d->rel_mean = d->mean_b != 0 ? (d->mean_a - d->mean_b) / d->mean_b : 0;
    d->rel_rmse = d->mean_b != 0 ? d->rmse / fabs(d->mean_b) : 0;
    d->mre = mre / (double)n;
    return 0;
}

int image_compare(const film *a, const film *b, int x, int y, int w, int h, image_diff *d) {
    image_region r = {x, y, w, h, NULL, NULL, 0};
    return image_compare_region(a, b, &r, d);
}

static double lum(rgb c) { return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; }

int image_diff_png(const film *a, const film *b, double scale, const char *path) {
    if (a->width != b->width || a->height != b->height || !(scale > 0)) return PM_EINVAL;
    double mb = 0;
    for (int y = 0; y < b->height; y++)
        for (int x = 0; x < b->width; x++) mb += lum(film_get(b, x, y));
    mb /= (double)b->width * b->height;
    if (!(mb > 0)) mb = 1;
    film f;
    int rc = film_init(&f, a->width, a->height);
    if (rc < 0) return rc;
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++) {
            double v = (lum(film_get(a, x, y)) - lum(film_get(b, x, y))) / (scale * mb);
            if (!(v == v)) v = 0;
            v = v > 1 ? 1 : v < -1 ? -1 : v;
            /* Brighter than the reference: orange; darker: blue; equal: black. */
            film_set(&f, x, y, v >= 0 ? v3(v, 0.45 * v, 0) : v3(0, 0.35 * -v, -v));
        }
    rc = film_write_png(&f, path, FILM_TONE_SRGB, 1.0, 0, NULL);
    film_free(&f);
    return rc;
}
