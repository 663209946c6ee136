/* exr_read.h: reading OpenEXR images with OpenEXRCore (Debian's libopenexr-dev, openexr.h,
 * -lOpenEXRCore), in base/ so that the loader (environment maps, load/) and the image stage
 * (image/exr.h: --compare, --tonemap, and the writer, which shares the error helpers below)
 * read EXR files the same way.
 *
 * Reading: the first part of a scanline file, any compression OpenEXRCore decodes, channels R,
 * G and B (or Y alone, read as grey) of any pixel type, converted to float; the data window
 * gives the size (1 to 65536 on a side). Tiled and deep files, and files with neither R, G, B
 * nor Y, are refused.
 *
 * Errors: a negative PM_E* code (PM_EIO: cannot open; PM_EFORMAT: not an EXR file we read,
 * with OpenEXRCore's own message; PM_ENOMEM) and a message in err naming the file. Nothing
 * here keeps state.
 */
#ifndef RENDER_EXR_READ_H
#define RENDER_EXR_READ_H

#include <OpenEXR/openexr.h>
#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The EXR file at path as 3 width height floats, row 0 at the top (EXR's y grows downward),
 * in *px (the caller's, free()); *px NULL and the sizes 0 on failure. */
int exr_read_rgb(const char *path, int *width, int *height, float **px, char *err, size_t cap);

/* Does the file start with EXR's magic number (76 2f 31 01)? 0 when it cannot be read. */
int exr_is_exr(const char *path);

/* Does the name end in ".exr" (any case)? */
int exr_has_ext(const char *path);

/* Shared by the reader and image/exr.c's writer: a call's state, which OpenEXRCore's error
 * callback (exr__on_error, the context's user data) fills with the library's first message. */
typedef struct exr_io {
    unsigned char *b; /* writing: the file being built */
    size_t len, cap;
    int oom;
    char msg[256]; /* the library's first error message */
} exr_io;
void exr__on_error(exr_const_context_t c, exr_result_t code, const char *msg);
/* Our message for an OpenEXRCore failure rc in `what` (PM_ENOMEM after io->oom, else
 * PM_EFORMAT). */
int exr__fail(const exr_io *io, exr_result_t rc, const char *path, const char *what, char *err, size_t cap);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_EXR_READ_H */
