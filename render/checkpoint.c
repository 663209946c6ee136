/* checkpoint.c: writing and reading render checkpoints; see checkpoint.h.
 *
 * Values are written byte by byte in little-endian order (doubles by their IEEE bits), so a
 * file means the same on any host and the state read back is bit-identical to the one
 * written. The checksum is computed while writing and while reading, over the same bytes.
 */
#include "checkpoint.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "common.h"
#include "output.h"

#define MAGIC "PMRCKPT\n"
enum { HEADER_BYTES = 56, PIXEL_BYTES = 28, MAX_SIDE = 1 << 14, MAX_SPP = 1 << 20 };

uint64_t ckpt_hash(uint64_t h, const void *p, size_t n) {
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++) {
        h ^= b[i];
        h *= 0x100000001b3ULL;
    }
    return h;
}

int ckpt_hash_file(const char *path, uint64_t max_bytes, uint64_t *h, char *err, size_t errcap) {
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, errcap, "%s: %s", path, strerror(errno));
        return PM_EIO;
    }
    unsigned char buf[1 << 16];
    uint64_t total = 0;
    size_t got;
    while ((got = fread(buf, 1, sizeof buf, f)) > 0) {
        total += got;
        if (total > max_bytes) {
            fclose(f);
            snprintf(err, errcap, "%s: larger than %llu bytes", path, (unsigned long long)max_bytes);
            return PM_EIO;
        }
        *h = ckpt_hash(*h, buf, got);
    }
    int bad = ferror(f);
    fclose(f);
    if (bad) {
        snprintf(err, errcap, "%s: cannot read", path);
        return PM_EIO;
    }
    return 0;
}

/* ---- writing ------------------------------------------------------------------------------ */

typedef struct wr {
    FILE *fp;
    uint64_t h;
    int ok;
} wr;

static void put(wr *w, const void *p, size_t n) {
    w->h = ckpt_hash(w->h, p, n);
    if (w->ok && fwrite(p, 1, n, w->fp) != n) w->ok = 0;
}
static void le32(unsigned char *b, uint32_t v) {
    for (int i = 0; i < 4; i++) b[i] = (unsigned char)(v >> (8 * i));
}
static void le64(unsigned char *b, uint64_t v) {
    for (int i = 0; i < 8; i++) b[i] = (unsigned char)(v >> (8 * i));
}
static uint32_t get32(const unsigned char *b) {
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}
static uint64_t get64(const unsigned char *b) { return (uint64_t)get32(b) | (uint64_t)get32(b + 4) << 32; }

int ckpt_write(const char *path, const ckpt_info *ci, const render_state *st, char *err,
               size_t errcap) {
    out_file o;
    int rc = out_open(&o, path, err, errcap);
    if (rc < 0) return rc;
    wr w = {o.fp, CKPT_HASH_INIT, 1};
    size_t ls = strlen(ci->settings), lp = strlen(ci->photons);
    unsigned char hd[HEADER_BYTES];
    memcpy(hd, MAGIC, 8);
    le32(hd + 8, CKPT_VERSION);
    le32(hd + 12, (uint32_t)st->width);
    le32(hd + 16, (uint32_t)st->height);
    le32(hd + 20, (uint32_t)st->spp);
    le64(hd + 24, ci->scene_hash);
    le64(hd + 32, ci->photon_hash);
    le32(hd + 40, (uint32_t)ls);
    le32(hd + 44, (uint32_t)ci->args_len);
    le32(hd + 48, (uint32_t)lp);
    le32(hd + 52, 0);
    put(&w, hd, sizeof hd);
    put(&w, ci->settings, ls);
    put(&w, ci->args, ci->args_len);
    put(&w, ci->photons, lp);
    size_t n = (size_t)st->width * (size_t)st->height;
    unsigned char px[PIXEL_BYTES * 256];
    for (size_t i = 0; i < n && w.ok;) {
        size_t m = 0;
        for (; m < 256 && i < n; m++, i++) {
            for (int c = 0; c < 3; c++) {
                uint64_t u;
                memcpy(&u, &st->sum[3 * i + c], 8);
                le64(px + PIXEL_BYTES * m + 8 * c, u);
            }
            le32(px + PIXEL_BYTES * m + 24, st->count[i]);
        }
        put(&w, px, PIXEL_BYTES * m);
    }
    unsigned char tail[8];
    le64(tail, w.h);
    put(&w, tail, 8);
    if (!w.ok) {
        snprintf(err, errcap, "%s: cannot write: %s", path, strerror(errno));
        out_abort(&o);
        return PM_EIO;
    }
    out_file *list[1] = {&o};
    return out_commit(list, 1, err, errcap);
}

/* ---- reading ------------------------------------------------------------------------------ */

static int fail(char *err, size_t errcap, int code, const char *path, const char *msg) {
    snprintf(err, errcap, "%s: %s", path, msg);
    return code;
}

/* Read n bytes into p, hashing them. 0 or -1. */
static int get(FILE *f, void *p, size_t n, uint64_t *h) {
    if (fread(p, 1, n, f) != n) return -1;
    *h = ckpt_hash(*h, p, n);
    return 0;
}

int ckpt_read(const char *path, ckpt_info *ci, render_state *st, char *err, size_t errcap) {
    memset(ci, 0, sizeof *ci);
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, errcap, "%s: %s", path, strerror(errno));
        return PM_EIO;
    }
    struct stat sb;
    unsigned char hd[HEADER_BYTES];
    uint64_t h = CKPT_HASH_INIT;
    int rc = PM_EFORMAT;
    char msg[256];
    if (fstat(fileno(f), &sb) != 0 || !S_ISREG(sb.st_mode)) {
        rc = fail(err, errcap, PM_EFORMAT, path, "not a regular file; a checkpoint is read from a file");
        goto out;
    }
    if (get(f, hd, sizeof hd, &h) != 0 || memcmp(hd, MAGIC, 8) != 0) {
        rc = fail(err, errcap, PM_EFORMAT, path, "not a render checkpoint (or truncated in its header)");
        goto out;
    }
    uint32_t version = get32(hd + 8), w = get32(hd + 12), ht = get32(hd + 16), spp = get32(hd + 20);
    uint32_t ls = get32(hd + 40), la = get32(hd + 44), lp = get32(hd + 48);
    if (version != CKPT_VERSION) {
        snprintf(msg, sizeof msg, "checkpoint format version %u; this renderer reads version %u",
                 version, CKPT_VERSION);
        rc = fail(err, errcap, PM_EVERSION, path, msg);
        goto out;
    }
    if (w < 1 || w > MAX_SIDE || ht < 1 || ht > MAX_SIDE || spp < 1 || spp > MAX_SPP ||
        ls >= sizeof ci->settings || la > sizeof ci->args || lp >= sizeof ci->photons) {
        rc = fail(err, errcap, PM_EFORMAT, path, "corrupt header (a size out of range)");
        goto out;
    }
    uint64_t want = (uint64_t)HEADER_BYTES + ls + la + lp + (uint64_t)w * ht * PIXEL_BYTES + 8;
    if ((uint64_t)sb.st_size != want) {
        snprintf(msg, sizeof msg, "%s: %lld bytes, but its header says %llu",
                 (uint64_t)sb.st_size < want ? "truncated" : "has extra data", (long long)sb.st_size,
                 (unsigned long long)want);
        rc = fail(err, errcap, PM_EFORMAT, path, msg);
        goto out;
    }
    if (get(f, ci->settings, ls, &h) != 0 || get(f, ci->args, la, &h) != 0 ||
        get(f, ci->photons, lp, &h) != 0) {
        rc = fail(err, errcap, PM_EFORMAT, path, "truncated");
        goto out;
    }
    ci->args_len = la;
    if (la > 0 && ci->args[la - 1] != 0) {
        rc = fail(err, errcap, PM_EFORMAT, path, "corrupt argument list");
        goto out;
    }
    ci->scene_hash = get64(hd + 24);
    ci->photon_hash = get64(hd + 32);
    if (!st) {
        rc = 0;
        goto out;
    }
    if (render_state_init(st, (int)w, (int)ht, (int)spp) < 0) {
        rc = fail(err, errcap, PM_ENOMEM, path, "out of memory");
        goto out;
    }
    size_t n = (size_t)w * ht;
    unsigned char px[PIXEL_BYTES * 256];
    rc = 0;
    for (size_t i = 0; i < n && rc == 0;) {
        size_t m = n - i < 256 ? n - i : 256;
        if (get(f, px, PIXEL_BYTES * m, &h) != 0) {
            rc = fail(err, errcap, PM_EFORMAT, path, "truncated");
            break;
        }
        for (size_t j = 0; j < m; j++, i++) {
            for (int c = 0; c < 3; c++) {
                uint64_t u = get64(px + PIXEL_BYTES * j + 8 * c);
                memcpy(&st->sum[3 * i + c], &u, 8);
            }
            st->count[i] = get32(px + PIXEL_BYTES * j + 24);
        }
    }
    unsigned char tail[8];
    uint64_t body = h;
    if (rc == 0 && (fread(tail, 1, 8, f) != 8 || get64(tail) != body))
        rc = fail(err, errcap, PM_EFORMAT, path, "corrupt (checksum mismatch)");
    for (size_t i = 0; i < n && rc == 0; i++)
        if (st->count[i] > spp) rc = fail(err, errcap, PM_EFORMAT, path, "corrupt (a pixel has more samples than spp)");
    if (rc < 0) render_state_free(st);
out:
    fclose(f);
    return rc;
}
