/* film.h: the linear float framebuffer and the image writers (PFM, PNG; OpenEXR in exr.h).
 *
 * The film holds linear RGB radiance per pixel, row 0 at the top. PFM files keep it exactly
 * (32-bit floats; rows stored bottom to top as the format says, little-endian, scale -1), so
 * images can be compared numerically (render --compare, scripts/imgcmp).
 *
 * PNG output tone-maps: an exposure multiplier, then Hable's filmic curve (Uncharted 2; white
 * point W = 11.2) or a plain clamp, then the sRGB transfer curve, 8 bits per channel.
 * Auto exposure builds a histogram of pixel luminance (log-spaced bins) and picks the
 * exposure that puts the brightest clip_percent % of pixels at or above clipping (white for
 * sRGB, W for filmic).
 *
 * The path writers go through output.h: a regular file (or a new path) is written to a
 * temporary beside it and renamed into place only when everything succeeded; a FIFO or
 * character device is written through and never replaced; a symbolic link is followed to
 * its target; anything else is refused. They return 0 or a negative PM_E* code (PM_EIO with
 * errno kept). Files get mode 0666 less the umask, as with fopen. The _fp writers fill a
 * caller's stream, for writing several outputs together (out_commit).
 *
 * film_read_pfm checks the header's width x height against the file's size before it
 * allocates anything (PM_EFORMAT for a file shorter than its header says).
 *
 * Ownership: the film owns its pixel array (film_free).
 */
#ifndef RENDER_FILM_H
#define RENDER_FILM_H

#include <stdio.h>

#include "base/vec.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct film {
    int width, height;
    float *px; /* width * height * 3 floats, row-major, top row first */
} film;

int film_init(film *f, int width, int height); /* zeroed pixels; 0 or PM_ENOMEM */
void film_free(film *f);
/* The pixels with a channel that is not finite (inf or NaN) as stored: a sample finite in
 * double may still overflow a float. */
size_t film_count_nonfinite(const film *f);
static inline void film_set(film *f, int x, int y, rgb c) {
    float *p = f->px + 3 * ((long)y * f->width + x);
    p[0] = (float)c.x;
    p[1] = (float)c.y;
    p[2] = (float)c.z;
}
static inline rgb film_get(const film *f, int x, int y) {
    const float *p = f->px + 3 * ((long)y * f->width + x);
    return v3(p[0], p[1], p[2]);
}

int film_write_pfm(const film *f, const char *path);
int film_write_pfm_fp(const film *f, FILE *fp);
/* Read a colour PFM ("PF"); handles either byte order. 0, PM_EIO or PM_EFORMAT. */
int film_read_pfm(film *f, const char *path);

enum { FILM_TONE_FILMIC = 0, FILM_TONE_SRGB = 1 }; /* same values as TONE_* in scene.h */
/* The filmic curve's white point: scene luminance (after exposure) that maps to display 1. */
#define FILM_HABLE_WHITE 11.2

/* The auto exposure multiplier (see above); 1 for an all-black image. */
double film_auto_exposure(const film *f, int tone, double clip_percent);
/* exposure <= 0 means auto. *used (may be NULL) receives the exposure applied. */
int film_write_png(const film *f, const char *path, int tone, double exposure, double clip_percent,
                   double *used);
int film_write_png_fp(const film *f, FILE *fp, int tone, double exposure, double clip_percent,
                      double *used);

/* The PFM and the PNG (either may be NULL) as one set of outputs: both are written in full
 * (temporaries) before either is put in place (out_commit), so a failure or SIGINT/SIGTERM
 * leaves both old files. 0 or a negative code with a message in err. */
int film_write_outputs(const film *f, const char *pfm, const char *png, int tone, double exposure,
                       double clip_percent, double *used, char *err, size_t errcap);
/* The same, with the HDR output's format: a name ending in ".exr" (any case) is written as
 * OpenEXR (image/exr.h; exr_type EXR_FLOAT or EXR_HALF), any other as PFM (exr_type must then
 * be EXR_FLOAT). film_write_outputs is this with EXR_FLOAT. */
int film_write_outputs_ex(const film *f, const char *hdr, int exr_type, const char *png, int tone, double exposure,
                          double clip_percent, double *used, char *err, size_t errcap);
/* Read a PFM or an OpenEXR file (told apart by the first bytes). 0, or a negative code with a
 * message naming path in err (PM_EIO, PM_EFORMAT, PM_ENOMEM). */
int film_read_image(film *f, const char *path, char *err, size_t errcap);

/* Hable's filmic curve, normalized so that W maps to 1 (x >= 0). */
double film_hable(double x);
/* Linear [0,1] to the sRGB-encoded value. */
double film_srgb_encode(double v);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_FILM_H */
