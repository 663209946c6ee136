/* exr.h: OpenEXR images, written and read with OpenEXRCore, the C API of Debian's
 * libopenexr-dev (openexr.h, -lOpenEXRCore).
 *
 * Writing: one scanline part, channels R, G, B, 32-bit float (exact: the film's floats as
 * they are) or 16-bit half (EXR_HALF: rounded to the nearest half, relative error at most
 * 2^-11 for |v| in half's normal range 6.1e-5 .. 65504; larger values become infinity, smaller
 * ones lose precision as half's subnormals do), ZIP compression (lossless), data and display
 * window 0 .. width-1, 0 .. height-1, row 0 at the top (EXR's y grows downward, as the film's).
 * The file is built in memory and then written to the caller's stream in one piece, so it goes
 * through output.h's atomic outputs like every other image (a temporary renamed into place;
 * a FIFO written through).
 *
 * Reading: base/exr_read.h's exr_read_rgb (the first part of a scanline file, R G B or Y, any
 * pixel type converted to float; film.h's film_read_image reads a film with it); exr_is_exr
 * and exr_has_ext are declared there too.
 *
 * The pixels are the caller's interleaved floats, not a film: film.c (film_write_outputs_ex,
 * film_read_image) calls this file, so this file stands under film.h and does not include it.
 *
 * Errors: a negative PM_E* code (PM_EIO: cannot open or write; PM_EFORMAT: not an EXR file we
 * read, with OpenEXRCore's own message; PM_ENOMEM) and a message in err naming the file.
 * Nothing here keeps state.
 */
#ifndef RENDER_EXR_H
#define RENDER_EXR_H

#include <stddef.h>
#include <stdio.h>

#include "base/exr_read.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { EXR_FLOAT = 0, EXR_HALF = 1 };

/* Write width x height pixels px (3 floats each, R G B, row-major, top row first, as a film
 * holds them) as an EXR file to fp (pixel type EXR_FLOAT or EXR_HALF). */
int exr_write_fp(const float *px, int width, int height, FILE *fp, int pixel_type, char *err, size_t cap);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_EXR_H */
