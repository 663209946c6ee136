/* exr.c: OpenEXR output and input through OpenEXRCore; see exr.h.
 *
 * Writing uses OpenEXRCore's custom write callback to fill a growing memory buffer (the
 * library writes the header, then the chunks, then goes back to fill the chunk offset table,
 * so a plain stream would not do), and the buffer is written to the caller's stream at the
 * end. Each chunk is encoded by the library's default pipeline from the caller's interleaved
 * floats (pixel stride 12 bytes, one pointer per channel), converting to half where asked.
 * Reading is base/exr_read.c's (exr_read_rgb). Errors come through base/exr_read.h's
 * callback into the call's own buffer, so nothing global is kept.
 */
#include "image/exr.h"

#include <OpenEXR/openexr.h>
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "base/exr_read.h"
#include "common.h"

static int64_t mem_write(exr_const_context_t c, void *ud, const void *buf, uint64_t sz, uint64_t off,
                         exr_stream_error_func_ptr_t error_cb) {
    (void)c;
    (void)error_cb;
    exr_io *io = ud;
    if (off + sz > (uint64_t)SIZE_MAX / 2) return -1;
    size_t end = (size_t)(off + sz);
    if (end > io->cap) {
        size_t nc = io->cap ? io->cap : 1 << 16;
        while (nc < end) nc *= 2;
        unsigned char *nb = realloc(io->b, nc);
        if (!nb) {
            io->oom = 1;
            return -1;
        }
        memset(nb + io->cap, 0, nc - io->cap);
        io->b = nb;
        io->cap = nc;
    }
    memcpy(io->b + off, buf, (size_t)sz);
    if (end > io->len) io->len = end;
    return (int64_t)sz;
}

/* ---- writing ------------------------------------------------------------------------------ */

int exr_write_fp(const float *px, int width, int height, FILE *fp, int pixel_type, char *err, size_t cap) {
    exr_io io;
    memset(&io, 0, sizeof io);
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = exr__on_error;
    init.user_data = &io;
    init.write_fn = mem_write;
    exr_context_t c = NULL;
    exr_encode_pipeline_t enc;
    int have_enc = 0, part = 0;
    const char *what = "starting the file";
    exr_result_t rc = exr_start_write(&c, "render.exr", EXR_WRITE_FILE_DIRECTLY, &init);
    if (rc == EXR_ERR_SUCCESS) rc = exr_add_part(c, "render", EXR_STORAGE_SCANLINE, &part);
    if (rc == EXR_ERR_SUCCESS) rc = exr_initialize_required_attr_simple(c, part, width, height, EXR_COMPRESSION_ZIP);
    exr_pixel_type_t pt = pixel_type == EXR_HALF ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT;
    static const char *const names[3] = {"B", "G", "R"}; /* EXR keeps channels sorted by name */
    static const int comp[3] = {2, 1, 0};
    for (int k = 0; k < 3 && rc == EXR_ERR_SUCCESS; k++)
        rc = exr_add_channel(c, part, names[k], pt, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
    if (rc == EXR_ERR_SUCCESS) {
        what = "writing the header";
        rc = exr_write_header(c);
    }
    int32_t lines = 1;
    if (rc == EXR_ERR_SUCCESS) rc = exr_get_scanlines_per_chunk(c, part, &lines);
    what = "encoding the pixels";
    for (int y = 0; y < height && rc == EXR_ERR_SUCCESS; y += lines) {
        exr_chunk_info_t ci;
        rc = exr_write_scanline_chunk_info(c, part, y, &ci);
        if (rc != EXR_ERR_SUCCESS) break;
        rc = have_enc ? exr_encoding_update(c, part, &ci, &enc) : exr_encoding_initialize(c, part, &ci, &enc);
        if (rc != EXR_ERR_SUCCESS) break;
        for (int k = 0; k < enc.channel_count; k++) {
            exr_coding_channel_info_t *ch = &enc.channels[k];
            int cc = 0;
            for (int j = 0; j < 3; j++)
                if (strcmp(ch->channel_name, names[j]) == 0) cc = comp[j];
            ch->user_bytes_per_element = 4;
            ch->user_data_type = EXR_PIXEL_FLOAT;
            ch->user_pixel_stride = 12;
            ch->user_line_stride = 12 * width;
            ch->encode_from_ptr = (const uint8_t *)(px + 3 * ((size_t)(ci.start_y) * (size_t)width) + cc);
        }
        if (!have_enc) rc = exr_encoding_choose_default_routines(c, part, &enc);
        have_enc = 1;
        if (rc == EXR_ERR_SUCCESS) rc = exr_encoding_run(c, part, &enc);
    }
    if (have_enc) exr_encoding_destroy(c, &enc);
    exr_result_t fin = c ? exr_finish(&c) : EXR_ERR_SUCCESS;
    if (rc == EXR_ERR_SUCCESS && fin != EXR_ERR_SUCCESS) {
        rc = fin;
        what = "finishing the file";
    }
    int ret = 0;
    if (rc != EXR_ERR_SUCCESS) {
        ret = exr__fail(&io, rc, "EXR", what, err, cap);
    } else if (fwrite(io.b, 1, io.len, fp) != io.len) {
        snprintf(err, cap, "cannot write: %s", strerror(errno));
        ret = PM_EIO;
    }
    free(io.b);
    return ret;
}
