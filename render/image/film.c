/* film.c: framebuffer, PFM read/write, auto exposure and PNG via libpng; see film.h.
 *
 * The writers fill a stream; the path versions get it from output.h, which decides how the
 * path is written (a temporary renamed over a regular file, or written through a FIFO or
 * device) and removes the temporary on failure or SIGINT/SIGTERM.
 */
#include "image/film.h"
#include "image/exr.h"

#include <errno.h>
#include <png.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "common.h"
#include "base/errors.h"
#include "base/output.h"

#define HABLE_W FILM_HABLE_WHITE

int film_init(film *f, int width, int height) {
    f->width = width;
    f->height = height;
    f->px = calloc((size_t)width * (size_t)height * 3, sizeof(float));
    return f->px ? 0 : PM_ENOMEM;
}

size_t film_count_nonfinite(const film *f) {
    size_t n = 0, npx = (size_t)f->width * (size_t)f->height;
    for (size_t i = 0; f->px && i < npx; i++)
        n += !isfinite(f->px[3 * i]) || !isfinite(f->px[3 * i + 1]) || !isfinite(f->px[3 * i + 2]);
    return n;
}

void film_free(film *f) {
    free(f->px);
    f->px = NULL;
    f->width = f->height = 0;
}

/* One output through output.h: open, write with fn, commit. */
static int write_one(const char *path, int (*fn)(const void *, FILE *), const void *arg) {
    char err[512];
    out_file o;
    int rc = out_open(&o, path, err, sizeof err);
    if (rc < 0) return rc;
    rc = fn(arg, o.fp);
    if (rc < 0) {
        int saved = errno;
        out_abort(&o);
        errno = saved;
        return rc;
    }
    out_file *list[1] = {&o};
    return out_commit(list, 1, err, sizeof err);
}

int film_write_pfm_fp(const film *f, FILE *fp) {
    int ok = fprintf(fp, "PF\n%d %d\n-1.0\n", f->width, f->height) > 0;
    for (int y = f->height - 1; y >= 0 && ok; y--) {
        const float *row = f->px + (size_t)y * (size_t)f->width * 3;
        /* The format is little-endian with scale -1; x86 is little-endian already, but write
         * byte by byte so the file is right on any host. */
        for (int i = 0; i < f->width * 3 && ok; i++) {
            uint32_t u;
            memcpy(&u, &row[i], 4);
            unsigned char b[4] = {(unsigned char)u, (unsigned char)(u >> 8), (unsigned char)(u >> 16),
                                  (unsigned char)(u >> 24)};
            ok = fwrite(b, 1, 4, fp) == 4;
        }
    }
    return ok ? 0 : PM_EIO;
}

static int pfm_fn(const void *f, FILE *fp) { return film_write_pfm_fp(f, fp); }
int film_write_pfm(const film *f, const char *path) { return write_one(path, pfm_fn, f); }

int film_read_pfm(film *f, const char *path) {
    memset(f, 0, sizeof *f);
    FILE *fp = fopen(path, "rb");
    if (!fp) return PM_EIO;
    char magic[3] = {0};
    int w, h;
    double scale;
    struct stat st;
    if (fscanf(fp, "%2s %d %d %lf", magic, &w, &h, &scale) != 4 || strcmp(magic, "PF") != 0 ||
        w <= 0 || h <= 0 || w > (1 << 16) || h > (1 << 16) || scale == 0 || fgetc(fp) == EOF ||
        fstat(fileno(fp), &st) != 0) {
        fclose(fp);
        return PM_EFORMAT;
    }
    /* The header's size is checked against the file before anything is allocated, so a
     * forged "65536 65536" header costs nothing. A pipe has no size: its pixels are read into
     * a buffer that grows with what actually arrives. */
    size_t bytes = (size_t)w * (size_t)h * 12;
    long pos = ftell(fp);
    if (S_ISREG(st.st_mode) && (pos < 0 || (uint64_t)st.st_size - (uint64_t)pos < bytes)) {
        fclose(fp);
        return PM_EFORMAT;
    }
    size_t cap = S_ISREG(st.st_mode) ? bytes : (bytes < (1u << 20) ? bytes : (1u << 20)), got = 0;
    unsigned char *buf = malloc(cap);
    while (buf && got < bytes) {
        if (got == cap) {
            size_t nc = cap * 2 < bytes ? cap * 2 : bytes;
            unsigned char *nb = realloc(buf, nc);
            if (!nb) break;
            buf = nb;
            cap = nc;
        }
        size_t r = fread(buf + got, 1, cap - got, fp);
        if (r == 0) break;
        got += r;
    }
    fclose(fp);
    if (!buf || got < bytes) {
        int rc = !buf || got == cap ? PM_ENOMEM : PM_EFORMAT;
        free(buf);
        return rc;
    }
    if (film_init(f, w, h) < 0) {
        free(buf);
        return PM_ENOMEM;
    }
    int little = scale < 0;
    const unsigned char *b = buf;
    for (int y = h - 1; y >= 0; y--) {
        for (int i = 0; i < w * 3; i++, b += 4) {
            uint32_t u = little ? (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 |
                                      (uint32_t)b[3] << 24
                                : (uint32_t)b[3] | (uint32_t)b[2] << 8 | (uint32_t)b[1] << 16 |
                                      (uint32_t)b[0] << 24;
            memcpy(&f->px[(size_t)y * (size_t)w * 3 + (size_t)i], &u, 4);
        }
    }
    free(buf);
    return 0;
}

static double hable_raw(double x) {
    const double A = 0.15, B = 0.50, C = 0.10, D = 0.20, E = 0.02, F = 0.30;
    return ((x * (A * x + C * B) + D * E) / (x * (A * x + B) + D * F)) - E / F;
}

double film_hable(double x) { return hable_raw(x) / hable_raw(HABLE_W); }

double film_srgb_encode(double v) {
    v = fmin(1.0, fmax(0.0, v));
    return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1.0 / 2.4) - 0.055;
}

double film_auto_exposure(const film *f, int tone, double clip_percent) {
    enum { NB = 4096 };
    long n = (long)f->width * f->height;
    double lmin = INFINITY, lmax = 0;
    for (long i = 0; i < n; i++) {
        double l = rgb_lum(v3(f->px[3 * i], f->px[3 * i + 1], f->px[3 * i + 2]));
        if (l > 0 && isfinite(l)) {
            lmin = fmin(lmin, l);
            lmax = fmax(lmax, l);
        }
    }
    if (!(lmax > 0)) return 1.0;
    double clip_level = tone == FILM_TONE_SRGB ? 1.0 : HABLE_W;
    double lo = log2(lmin), hi = log2(lmax) + 1e-9;
    if (!(hi > lo)) return clip_level / lmax;
    long *hist = calloc(NB, sizeof *hist);
    if (!hist) return clip_level / lmax;
    for (long i = 0; i < n; i++) {
        double l = rgb_lum(v3(f->px[3 * i], f->px[3 * i + 1], f->px[3 * i + 2]));
        if (!(l > 0) || !isfinite(l)) continue;
        int b = (int)((log2(l) - lo) / (hi - lo) * NB);
        hist[b < 0 ? 0 : b >= NB ? NB - 1 : b]++;
    }
    /* Walk down from the top until clip_percent % of all pixels are above the level. */
    long want = (long)(clip_percent / 100.0 * (double)n), acc = 0;
    int b = NB - 1;
    for (; b > 0; b--) {
        acc += hist[b];
        if (acc > want) break;
    }
    free(hist);
    double level = exp2(lo + (double)b / NB * (hi - lo)); /* lower edge of the bin */
    return clip_level / level;
}

static void png_err(png_structp p, png_const_charp msg) {
    (void)msg;
    png_longjmp(p, 1);
}
static void png_warn(png_structp p, png_const_charp msg) {
    (void)p;
    (void)msg;
}

int film_write_png_fp(const film *f, FILE *fp, int tone, double exposure, double clip_percent,
                      double *used) {
    if (!(exposure > 0)) exposure = film_auto_exposure(f, tone, clip_percent);
    if (used) *used = exposure;
    size_t rowbytes = (size_t)f->width * 3;
    unsigned char *img = malloc(rowbytes * (size_t)f->height);
    png_bytep *rows = malloc((size_t)f->height * sizeof *rows);
    if (!img || !rows) {
        free(img);
        free(rows);
        return PM_ENOMEM;
    }
    for (long i = 0; i < (long)f->width * f->height * 3; i++) {
        double v = f->px[i] * exposure;
        if (!(v >= 0)) v = 0; /* NaN and negative noise show as black, not garbage */
        if (tone == FILM_TONE_FILMIC) v = film_hable(fmin(v, 1e6));
        img[i] = (unsigned char)lrint(255.0 * film_srgb_encode(v));
    }
    for (int y = 0; y < f->height; y++) rows[y] = img + (size_t)y * rowbytes;
    volatile int ok = 0;
    png_structp p = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, png_err, png_warn);
    png_infop info = p ? png_create_info_struct(p) : NULL;
    if (p && info) {
        if (setjmp(png_jmpbuf(p)) == 0) {
            png_init_io(p, fp);
            png_set_IHDR(p, info, (png_uint_32)f->width, (png_uint_32)f->height, 8, PNG_COLOR_TYPE_RGB,
                         PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
            png_set_sRGB(p, info, PNG_sRGB_INTENT_PERCEPTUAL);
            png_write_info(p, info);
            png_write_image(p, rows);
            png_write_end(p, NULL);
            ok = 1;
        }
    }
    png_destroy_write_struct(p ? &p : NULL, info ? &info : NULL);
    free(img);
    free(rows);
    if (ok && fflush(fp) != 0) ok = 0;
    return ok ? 0 : PM_EIO;
}

typedef struct png_args {
    const film *f;
    int tone;
    double exposure, clip_percent, *used;
} png_args;

static int png_fn(const void *arg, FILE *fp) {
    const png_args *a = arg;
    return film_write_png_fp(a->f, fp, a->tone, a->exposure, a->clip_percent, a->used);
}

int film_write_png(const film *f, const char *path, int tone, double exposure, double clip_percent,
                   double *used) {
    png_args a = {f, tone, exposure, clip_percent, used};
    return write_one(path, png_fn, &a);
}

int film_write_outputs(const film *f, const char *pfm, const char *png, int tone, double exposure,
                       double clip_percent, double *used, char *err, size_t errcap) {
    return film_write_outputs_ex(f, pfm, EXR_FLOAT, png, tone, exposure, clip_percent, used, err, errcap);
}

int film_read_image(film *f, const char *path, char *err, size_t errcap) {
    if (exr_is_exr(path)) {
        memset(f, 0, sizeof *f);
        return exr_read_rgb(path, &f->width, &f->height, &f->px, err, errcap);
    }
    int rc = film_read_pfm(f, path);
    if (rc < 0)
        snprintf(err, errcap, "%s: %s%s", path, render_strerror(rc), rc == PM_EFORMAT ? " (PFM or OpenEXR expected)" : "");
    return rc;
}

int film_write_outputs_ex(const film *f, const char *pfm, int exr_type, const char *png, int tone, double exposure,
                          double clip_percent, double *used, char *err, size_t errcap) {
    out_file o[2];
    out_file *list[2];
    int n = 0, rc = 0;
    memset(o, 0, sizeof o);
    o[0].slot = o[1].slot = -1;
    if (pfm) {
        if ((rc = out_open(&o[n], pfm, err, errcap)) < 0) goto fail;
        list[n] = &o[n];
        n++;
        if (exr_has_ext(pfm)) {
            char eerr[400];
            if ((rc = exr_write_fp(f->px, f->width, f->height, o[n - 1].fp, exr_type, eerr, sizeof eerr)) < 0 ||
                (rc = fflush(o[n - 1].fp) ? PM_EIO : 0) < 0) {
                snprintf(err, errcap, "%s: %s", pfm, rc == PM_EIO ? strerror(errno) : eerr);
                goto fail;
            }
        } else if ((rc = film_write_pfm_fp(f, o[n - 1].fp)) < 0 || (rc = fflush(o[n - 1].fp) ? PM_EIO : 0) < 0) {
            snprintf(err, errcap, "%s: cannot write: %s", pfm, strerror(errno));
            goto fail;
        }
        out_test_pause("pfm");
    }
    if (png) {
        if ((rc = out_open(&o[n], png, err, errcap)) < 0) goto fail;
        list[n] = &o[n];
        n++;
        if ((rc = film_write_png_fp(f, o[n - 1].fp, tone, exposure, clip_percent, used)) < 0) {
            snprintf(err, errcap, "%s: cannot write: %s", png, rc == PM_ENOMEM ? "out of memory" : strerror(errno));
            goto fail;
        }
        out_test_pause("png");
    }
    return out_commit(list, n, err, errcap);
fail:
    for (int i = 0; i < 2; i++) out_abort(&o[i]);
    return rc;
}
