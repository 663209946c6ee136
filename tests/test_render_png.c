/* test_render_png.c: the PNG writer, read back with libpng.
 *
 * Oracle: the published curves, written out here independently of render/image/film.c: the sRGB
 * transfer function (IEC 61966-2-1: 12.92 v below 0.0031308, else 1.055 v^(1/2.4) - 0.055)
 * and Hable's filmic curve (A = 0.15, B = 0.50, C = 0.10, D = 0.20, E = 0.02, F = 0.30,
 * normalised by its value at the white point W = 11.2). A film whose pixels hold known values
 * in every row, column and channel is written with a fixed exposure; the file must be an
 * 8-bit RGB PNG of the same size, top row first, each byte round(255 curve(exposure * v)).
 * Negative and NaN pixels are documented to show black.
 */
#include <png.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "../render/image/film.h"

static double ref_srgb(double v) {
    v = v < 0 ? 0 : v > 1 ? 1 : v;
    return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055;
}

static double ref_hable(double x) {
    const double A = 0.15, B = 0.50, C = 0.10, D = 0.20, E = 0.02, F = 0.30, W = 11.2;
#define HABLE(t) (((t) * (A * (t) + C * B) + D * E) / ((t) * (A * (t) + B) + D * F) - E / F)
    return HABLE(x) / HABLE(W);
#undef HABLE
}

/* Reads an 8-bit RGB PNG into a malloc'd buffer (rows top first); NULL on any error. */
static unsigned char *read_png(const char *path, int *w, int *h) {
    png_image img;
    memset(&img, 0, sizeof img);
    img.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&img, path)) return NULL;
    if ((img.format & PNG_FORMAT_FLAG_COLOR) == 0 || (img.format & PNG_FORMAT_FLAG_ALPHA) ||
        PNG_IMAGE_SAMPLE_COMPONENT_SIZE(img.format) != 1) {
        png_image_free(&img);
        return NULL;
    }
    img.format = PNG_FORMAT_RGB;
    unsigned char *buf = malloc(PNG_IMAGE_SIZE(img));
    if (!buf || !png_image_finish_read(&img, NULL, buf, 0, NULL)) {
        free(buf);
        png_image_free(&img);
        return NULL;
    }
    *w = (int)img.width;
    *h = (int)img.height;
    return buf;
}

TEST(render_png_bytes_match_the_tone_curves) {
    const int W = 13, H = 7;
    film f;
    ASSERT_EQ_INT(film_init(&f, W, H), 0);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < 3; c++) /* distinct per row, column and channel; some > 1 */
                f.px[3 * (y * W + x) + c] = (float)(0.001 + 0.05 * x + 0.3 * y + 0.013 * c);
    f.px[0] = -1.0f; /* shows black */
    f.px[4] = NAN;   /* shows black */
    const double exposure = 0.7;
    for (int tone = 0; tone < 2; tone++) {
        char path[1024];
        snprintf(path, sizeof path, "%s/t%d.png", pm_test_tmpdir(), tone);
        double used = 0;
        ASSERT_EQ_INT(film_write_png(&f, path, tone ? FILM_TONE_SRGB : FILM_TONE_FILMIC, exposure, 1.0, &used), 0);
        EXPECT_NEAR(used, exposure, 0);
        int w = 0, h = 0;
        unsigned char *img = read_png(path, &w, &h);
        ASSERT_MSG(img != NULL, "%s is not an 8-bit RGB PNG libpng can read", path);
        EXPECT_EQ_INT(w, W);
        EXPECT_EQ_INT(h, H);
        int bad = 0;
        for (int i = 0; i < W * H * 3 && w == W && h == H; i++) {
            double v = f.px[i] * exposure;
            if (!(v >= 0)) v = 0;
            double want = 255.0 * ref_srgb(tone ? v : ref_hable(v));
            if (fabs(img[i] - want) > 0.5 + 1e-9 && bad++ < 5)
                EXPECT_MSG(0, "tone %d: byte %d (pixel %d, %d, channel %d) is %d, want %.2f", tone, i,
                           i / 3 % W, i / 3 / W, i % 3, img[i], want);
        }
        EXPECT_EQ_INT(bad, 0);
        EXPECT(img[0] == 0 && img[4] == 0); /* the negative and the NaN pixel */
        free(img);
    }
    film_free(&f);
}
