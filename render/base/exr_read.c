/* exr_read.c: reading OpenEXR images through OpenEXRCore; see exr_read.h. Reading runs the
 * decoding pipeline chunk by chunk into the caller's floats, converting any pixel type to
 * float. OpenEXRCore reports errors through a callback: ours keeps the first message in the
 * call's own buffer (the context's user data), so nothing global is kept.
 */
#include "base/exr_read.h"

#include <errno.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common.h"

void exr__on_error(exr_const_context_t c, exr_result_t code, const char *msg) {
    void *ud = NULL;
    if (exr_get_user_data(c, &ud) != EXR_ERR_SUCCESS || !ud) return;
    exr_io *io = ud;
    if (!io->msg[0]) snprintf(io->msg, sizeof io->msg, "%s", msg ? msg : exr_get_default_error_message(code));
}

/* Our message for an OpenEXRCore failure rc in `what`. */
int exr__fail(const exr_io *io, exr_result_t rc, const char *path, const char *what, char *err, size_t cap) {
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

int exr_read_rgb(const char *path, int *width, int *height, float **px, char *err, size_t cap) {
    *width = *height = 0;
    *px = NULL;
    FILE *probe = fopen(path, "rb");
    if (!probe) {
        snprintf(err, cap, "%s: cannot open: %s", path, strerror(errno));
        return PM_EIO;
    }
    fclose(probe);
    exr_io io;
    memset(&io, 0, sizeof io);
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = exr__on_error;
    init.user_data = &io;
    exr_context_t c = NULL;
    exr_result_t rc = exr_start_read(&c, path, &init);
    if (rc != EXR_ERR_SUCCESS) {
        int r = exr__fail(&io, rc, path, "not an EXR file this reads", err, cap);
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
        ret = exr__fail(&io, rc, path, "reading the header", err, cap);
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
    } else if ((*px = calloc((size_t)w * (size_t)h * 3, sizeof **px)) == NULL) {
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
            ret = exr__fail(&io, rc, path, "reading the pixels", err, cap);
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
            ch->decode_to_ptr = (uint8_t *)(*px + 3 * ((size_t)row * (size_t)w) + cc);
        }
        if (!have_dec) rc = exr_decoding_choose_default_routines(c, 0, &dec);
        have_dec = 1;
        if (rc == EXR_ERR_SUCCESS) rc = exr_decoding_run(c, 0, &dec);
        if (rc != EXR_ERR_SUCCESS) ret = exr__fail(&io, rc, path, "reading the pixels", err, cap);
    }
    if (have_dec) exr_decoding_destroy(c, &dec);
    exr_finish(&c);
    if (ret == 0 && !is_rgb) /* Y: grey */
        for (size_t i = 0; i < (size_t)w * (size_t)h; i++) (*px)[3 * i + 1] = (*px)[3 * i + 2] = (*px)[3 * i];
    if (ret < 0) {
        free(*px);
        *px = NULL;
    } else {
        *width = (int)w;
        *height = (int)h;
    }
    return ret;
}
