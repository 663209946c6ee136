/* exr.c: OpenEXR output and input through OpenEXRCore; see exr.h.
 *
 * Writing uses OpenEXRCore's custom write callback to fill a growing memory buffer (the
 * library writes the header, then the chunks, then goes back to fill the chunk offset table,
 * so a plain stream would not do), and the buffer is written to the caller's stream at the
 * end. Each chunk is encoded by the library's default pipeline from the film's interleaved
 * floats (pixel stride 12 bytes, one pointer per channel), converting to half where asked.
 * Reading runs the decoding pipeline chunk by chunk into the film, converting any pixel type
 * to float. OpenEXRCore reports errors through a callback: ours keeps the first message in
 * the call's own buffer (the context's user data), so nothing global is kept.
 */
#include "image/exr.h"

#include <OpenEXR/openexr.h>
#include <errno.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "common.h"

/* ---- errors ------------------------------------------------------------------------------- */

typedef struct exr_io {
    unsigned char *b; /* writing: the file being built */
    size_t len, cap;
    int oom;
    char msg[256]; /* the library's first error message */
} exr_io;

static void on_error(exr_const_context_t c, exr_result_t code, const char *msg) {
    void *ud = NULL;
    if (exr_get_user_data(c, &ud) != EXR_ERR_SUCCESS || !ud) return;
    exr_io *io = ud;
    if (!io->msg[0]) snprintf(io->msg, sizeof io->msg, "%s", msg ? msg : exr_get_default_error_message(code));
}

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

/* Our message for an OpenEXRCore failure rc in `what`. */
static int exr_fail(const exr_io *io, exr_result_t rc, const char *path, const char *what, char *err, size_t cap) {
    if (io->oom) {
        snprintf(err, cap, "%s: out of memory", path);
        return PM_ENOMEM;
    }
    snprintf(err, cap, "%s: %s: %s", path, what, io->msg[0] ? io->msg : exr_get_default_error_message(rc));
    return PM_EFORMAT;
}

int exr_has_ext(const char *path) {
    size_t n = strlen(path);
    if (n < 4) return 0;
    const char *e = path + n - 4;
    return e[0] == '.' && (e[1] | 32) == 'e' && (e[2] | 32) == 'x' && (e[3] | 32) == 'r';
}

int exr_is_exr(const char *path) {
    unsigned char m[4];
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    size_t got = fread(m, 1, 4, f);
    fclose(f);
    return got == 4 && m[0] == 0x76 && m[1] == 0x2f && m[2] == 0x31 && m[3] == 0x01;
}

/* ---- writing ------------------------------------------------------------------------------ */

int exr_write_fp(const film *f, FILE *fp, int pixel_type, char *err, size_t cap) {
    exr_io io;
    memset(&io, 0, sizeof io);
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = on_error;
    init.user_data = &io;
    init.write_fn = mem_write;
    exr_context_t c = NULL;
    exr_encode_pipeline_t enc;
    int have_enc = 0, part = 0;
    const char *what = "starting the file";
    exr_result_t rc = exr_start_write(&c, "render.exr", EXR_WRITE_FILE_DIRECTLY, &init);
    if (rc == EXR_ERR_SUCCESS) rc = exr_add_part(c, "render", EXR_STORAGE_SCANLINE, &part);
    if (rc == EXR_ERR_SUCCESS) rc = exr_initialize_required_attr_simple(c, part, f->width, f->height, EXR_COMPRESSION_ZIP);
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
    for (int y = 0; y < f->height && rc == EXR_ERR_SUCCESS; y += lines) {
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
            ch->user_line_stride = 12 * f->width;
            ch->encode_from_ptr = (const uint8_t *)(f->px + 3 * ((size_t)(ci.start_y) * (size_t)f->width) + cc);
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
        ret = exr_fail(&io, rc, "EXR", what, err, cap);
    } else if (fwrite(io.b, 1, io.len, fp) != io.len) {
        snprintf(err, cap, "cannot write: %s", strerror(errno));
        ret = PM_EIO;
    }
    free(io.b);
    return ret;
}

/* ---- reading ------------------------------------------------------------------------------ */

int exr_read(film *f, const char *path, char *err, size_t cap) {
    memset(f, 0, sizeof *f);
    FILE *probe = fopen(path, "rb");
    if (!probe) {
        snprintf(err, cap, "%s: cannot open: %s", path, strerror(errno));
        return PM_EIO;
    }
    fclose(probe);
    exr_io io;
    memset(&io, 0, sizeof io);
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = on_error;
    init.user_data = &io;
    exr_context_t c = NULL;
    exr_result_t rc = exr_start_read(&c, path, &init);
    if (rc != EXR_ERR_SUCCESS) {
        int r = exr_fail(&io, rc, path, "not an EXR file this reads", err, cap);
        if (c) exr_finish(&c);
        return r;
    }
    int ret = 0, nparts = 0;
    exr_storage_t st = EXR_STORAGE_SCANLINE;
    exr_attr_box2i_t dw;
    const exr_attr_chlist_t *chl = NULL;
    int32_t lines = 1;
    rc = exr_get_count(c, &nparts);
    if (rc == EXR_ERR_SUCCESS) rc = exr_get_storage(c, 0, &st);
    if (rc == EXR_ERR_SUCCESS) rc = exr_get_data_window(c, 0, &dw);
    if (rc == EXR_ERR_SUCCESS) rc = exr_get_channels(c, 0, &chl);
    if (rc == EXR_ERR_SUCCESS) rc = exr_get_scanlines_per_chunk(c, 0, &lines);
    if (rc != EXR_ERR_SUCCESS) {
        ret = exr_fail(&io, rc, path, "reading the header", err, cap);
        exr_finish(&c);
        return ret;
    }
    /* which channel fills which component: R G B, or Y for all three */
    int have[3] = {0, 0, 0}, grey = 0;
    for (int i = 0; i < chl->num_channels; i++) {
        const char *n = chl->entries[i].name.str;
        if (chl->entries[i].x_sampling != 1 || chl->entries[i].y_sampling != 1) continue;
        if (strcmp(n, "R") == 0) have[0] = 1;
        if (strcmp(n, "G") == 0) have[1] = 1;
        if (strcmp(n, "B") == 0) have[2] = 1;
        if (strcmp(n, "Y") == 0) grey = 1;
    }
    int is_rgb = have[0] && have[1] && have[2];
    long w = (long)dw.max.x - dw.min.x + 1, h = (long)dw.max.y - dw.min.y + 1;
    if (st != EXR_STORAGE_SCANLINE) {
        snprintf(err, cap, "%s: a tiled or deep EXR file (only scanline images are read)", path);
        ret = PM_EFORMAT;
    } else if (!is_rgb && !grey) {
        snprintf(err, cap, "%s: no R, G and B channels (nor Y) at full resolution", path);
        ret = PM_EFORMAT;
    } else if (w < 1 || h < 1 || w > (1 << 16) || h > (1 << 16)) {
        snprintf(err, cap, "%s: the data window is %ld x %ld (1 to 65536 on a side are read)", path, w, h);
        ret = PM_EFORMAT;
    } else if (film_init(f, (int)w, (int)h) < 0) {
        snprintf(err, cap, "%s: out of memory", path);
        ret = PM_ENOMEM;
    }
    exr_decode_pipeline_t dec;
    int have_dec = 0;
    for (long y = dw.min.y; y <= dw.max.y && ret == 0; y += lines) {
        exr_chunk_info_t ci;
        rc = exr_read_scanline_chunk_info(c, 0, (int)y, &ci);
        if (rc == EXR_ERR_SUCCESS)
            rc = have_dec ? exr_decoding_update(c, 0, &ci, &dec) : exr_decoding_initialize(c, 0, &ci, &dec);
        if (rc != EXR_ERR_SUCCESS) {
            ret = exr_fail(&io, rc, path, "reading the pixels", err, cap);
            break;
        }
        long row = ci.start_y - dw.min.y;
        for (int k = 0; k < dec.channel_count; k++) {
            exr_coding_channel_info_t *ch = &dec.channels[k];
            int cc = -1;
            if (is_rgb) cc = strcmp(ch->channel_name, "R") == 0   ? 0
                          : strcmp(ch->channel_name, "G") == 0 ? 1
                          : strcmp(ch->channel_name, "B") == 0 ? 2 : -1;
            else if (strcmp(ch->channel_name, "Y") == 0) cc = 0;
            if (cc < 0 || ch->x_samples != 1 || ch->y_samples != 1) {
                ch->decode_to_ptr = NULL; /* skipped */
                continue;
            }
            ch->user_bytes_per_element = 4;
            ch->user_data_type = EXR_PIXEL_FLOAT;
            ch->user_pixel_stride = 12;
            ch->user_line_stride = (int32_t)(12 * w);
            ch->decode_to_ptr = (uint8_t *)(f->px + 3 * ((size_t)row * (size_t)w) + cc);
        }
        if (!have_dec) rc = exr_decoding_choose_default_routines(c, 0, &dec);
        have_dec = 1;
        if (rc == EXR_ERR_SUCCESS) rc = exr_decoding_run(c, 0, &dec);
        if (rc != EXR_ERR_SUCCESS) ret = exr_fail(&io, rc, path, "reading the pixels", err, cap);
    }
    if (have_dec) exr_decoding_destroy(c, &dec);
    exr_finish(&c);
    if (ret == 0 && !is_rgb) /* Y: grey */
        for (size_t i = 0; i < (size_t)w * (size_t)h; i++) f->px[3 * i + 1] = f->px[3 * i + 2] = f->px[3 * i];
    if (ret < 0) film_free(f);
    return ret;
}
