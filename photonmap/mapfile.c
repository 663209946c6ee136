/* mapfile.c: saving and loading photon-map files (format and guarantees in mapfile.h).
 *
 * Records are packed field by field into a byte buffer in file order (little-endian floats),
 * so the format does not depend on the host's byte order or on struct padding. A save writes
 * a mkstemp temporary next to the target and renames it over the target only after every
 * byte was written, flushed and synced, and only if the target is absent or a regular file
 * (checked with lstat, which does not follow links). A load checks the whole header against
 * the file's size (fstat) before it allocates. The version-3 checksum (FNV-1a 64 of header
 * bytes 0..55 and then the record bytes, as stored) is summed while the records are packed or
 * unpacked, so it costs no second pass; a save writes it into the header last.
 */
#ifndef _POSIX_C_SOURCE
#define _POSIX_C_SOURCE 200809L
#endif
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <unistd.h>

#include "mapfile.h"

#define PM__HEADER_BYTES 64
#define PM__RECORD_BYTES 20
#define PM__CHUNK 1024 /* records per buffered read or write */
#define PM__CHECKSUM_AT 56 /* version 3: the checksum's 8 bytes (reserved, zero, before) */
static const char pm__magic[8] = {'P', 'M', 'A', 'P', 'H', 'O', 'T', 'N'};

_Static_assert(sizeof(pm_photon) == PM__RECORD_BYTES, "the file's record is one pm_photon");

/* FNV-1a, 64 bits (Fowler, Noll, Vo): h = (h ^ byte) * prime, from the offset basis. */
#define PM__FNV_BASIS 0xcbf29ce484222325ull
#define PM__FNV_PRIME 0x100000001b3ull
static uint64_t fnv1a(uint64_t h, const unsigned char *b, size_t n) {
    for (size_t i = 0; i < n; i++) h = (h ^ b[i]) * PM__FNV_PRIME;
    return h;
}

static void put32(unsigned char *b, uint32_t v) {
    b[0] = (unsigned char)v, b[1] = (unsigned char)(v >> 8);
    b[2] = (unsigned char)(v >> 16), b[3] = (unsigned char)(v >> 24);
}
static uint32_t get32(const unsigned char *b) {
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}

static void pack_photon(unsigned char *b, const pm_photon *p) {
    for (int i = 0; i < 3; i++) {
        uint32_t u;
        memcpy(&u, &p->pos[i], 4);
        put32(b + 4 * i, u);
    }
    memcpy(b + 12, p->power, 4);
    b[16] = p->theta, b[17] = p->phi, b[18] = p->flag, b[19] = p->normal;
}
static void unpack_photon(pm_photon *p, const unsigned char *b) {
    for (int i = 0; i < 3; i++) {
        uint32_t u = get32(b + 4 * i);
        memcpy(&p->pos[i], &u, 4);
    }
    memcpy(p->power, b + 12, 4);
    p->theta = b[16], p->phi = b[17], p->flag = b[18], p->normal = b[19];
}

static int write_all(int fd, const unsigned char *b, size_t n) {
    while (n > 0) {
        ssize_t w = write(fd, b, n);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) return -1;
        b += w;
        n -= (size_t)w;
    }
    return 0;
}

int pm_map_save(const char *path, const pm_photon *photons, const pm_map_header *hdr) {
    if (!path || !hdr || (hdr->count > 0 && !photons)) return PM_EINVAL;
    if (hdr->record_size != 0 && hdr->record_size != sizeof(pm_photon)) return PM_EINVAL;
    if (hdr->kind < PM_MAP_GLOBAL || hdr->kind > PM_MAP_VOLUME) return PM_EINVAL;
    struct stat st;
    mode_t mode = 0644;
    if (lstat(path, &st) == 0) {
        if (!S_ISREG(st.st_mode)) return PM_ENOTFILE;
        mode = st.st_mode & 07777;
    } else if (errno != ENOENT) {
        return PM_EIO;
    }
    size_t plen = strlen(path);
    char *tmp = malloc(plen + 8);
    if (!tmp) return PM_ENOMEM;
    memcpy(tmp, path, plen);
    memcpy(tmp + plen, ".XXXXXX", 8);
    int fd = mkstemp(tmp);
    if (fd < 0) {
        free(tmp);
        return PM_EIO;
    }
    unsigned char h[PM__HEADER_BYTES];
    memset(h, 0, sizeof h);
    memcpy(h, pm__magic, 8);
    put32(h + 8, PM_FILE_VERSION);
    put32(h + 12, (uint32_t)sizeof(pm_photon));
    put32(h + 16, (uint32_t)hdr->count);
    put32(h + 20, (uint32_t)(hdr->count >> 32));
    put32(h + 24, hdr->kind);
    put32(h + 28, (uint32_t)hdr->emitted);
    put32(h + 32, (uint32_t)(hdr->emitted >> 32));
    put32(h + 36, hdr->tree_bucket);
    for (int t = 0; t < 2; t++) {
        put32(h + 40 + 8 * t, (uint32_t)hdr->tag[t]);
        put32(h + 44 + 8 * t, (uint32_t)(hdr->tag[t] >> 32));
    }
    /* The header with its checksum bytes zero, the records, then the checksum at 56. */
    int ok = write_all(fd, h, sizeof h) == 0;
    uint64_t sum = fnv1a(PM__FNV_BASIS, h, PM__CHECKSUM_AT);
    unsigned char buf[PM__RECORD_BYTES * PM__CHUNK];
    for (uint64_t i = 0; ok && i < hdr->count;) {
        size_t c = 0;
        for (; c < PM__CHUNK && i < hdr->count; c++, i++)
            pack_photon(buf + PM__RECORD_BYTES * c, &photons[i]);
        sum = fnv1a(sum, buf, PM__RECORD_BYTES * c);
        ok = write_all(fd, buf, PM__RECORD_BYTES * c) == 0;
    }
    unsigned char cs[8];
    put32(cs, (uint32_t)sum);
    put32(cs + 4, (uint32_t)(sum >> 32));
    if (ok && (lseek(fd, PM__CHECKSUM_AT, SEEK_SET) != PM__CHECKSUM_AT || write_all(fd, cs, sizeof cs) != 0))
        ok = 0;
    if (ok && fchmod(fd, mode) != 0) ok = 0;
    if (ok && fsync(fd) != 0) ok = 0;
    if (close(fd) != 0) ok = 0;
    if (ok && rename(tmp, path) != 0) ok = 0;
    if (!ok) unlink(tmp);
    free(tmp);
    return ok ? PM_OK : PM_EIO;
}

int pm_map_load(const char *path, pm_photon **photons, pm_map_header *hdr) {
    if (!path || !photons || !hdr) return PM_EINVAL;
    *photons = NULL;
    FILE *f = fopen(path, "rb");
    if (!f) return PM_EIO;
    unsigned char h[PM__HEADER_BYTES];
    int rc = PM_OK;
    pm_photon *p = NULL;
    struct stat st;
    if (fstat(fileno(f), &st) != 0) {
        rc = PM_EIO;
        goto out;
    }
    if (fread(h, 1, sizeof h, f) != sizeof h) {
        rc = ferror(f) ? PM_EIO : PM_EFORMAT;
        goto out;
    }
    if (memcmp(h, pm__magic, 8) != 0) {
        rc = PM_EFORMAT;
        goto out;
    }
    pm_map_header hd;
    hd.version = get32(h + 8);
    hd.record_size = get32(h + 12);
    hd.count = (uint64_t)get32(h + 16) | (uint64_t)get32(h + 20) << 32;
    hd.kind = get32(h + 24);
    hd.emitted = (uint64_t)get32(h + 28) | (uint64_t)get32(h + 32) << 32;
    hd.tree_bucket = get32(h + 36);
    for (int t = 0; t < 2; t++)
        hd.tag[t] = (uint64_t)get32(h + 40 + 8 * t) | (uint64_t)get32(h + 44 + 8 * t) << 32;
    if (hd.version < 1 || hd.version > PM_FILE_VERSION) {
        rc = PM_EVERSION;
        goto out;
    }
    /* Version 1 reserved bytes 40..63 (zero) and knew kinds up to PM_MAP_OTHER; version 2
     * keeps bytes 56..63 zero; version 3 has its checksum there. */
    int reserved_zero = 1;
    for (int i = hd.version == 1 ? 40 : 56; hd.version < 3 && i < PM__HEADER_BYTES; i++) reserved_zero &= h[i] == 0;
    uint64_t want_sum = (uint64_t)get32(h + PM__CHECKSUM_AT) | (uint64_t)get32(h + PM__CHECKSUM_AT + 4) << 32;
    uint64_t sum = fnv1a(PM__FNV_BASIS, h, PM__CHECKSUM_AT);
    uint32_t max_kind = hd.version == 1 ? PM_MAP_OTHER : PM_MAP_VOLUME;
    if (hd.record_size != sizeof(pm_photon) || hd.kind < PM_MAP_GLOBAL || hd.kind > max_kind ||
        !reserved_zero) {
        rc = PM_EFORMAT;
        goto out;
    }
    /* The size must be exactly what the count says; compared by division so that a huge
     * count cannot overflow the product and pass. Only then is anything allocated. */
    if (!S_ISREG(st.st_mode) || st.st_size < PM__HEADER_BYTES ||
        (uint64_t)(st.st_size - PM__HEADER_BYTES) % PM__RECORD_BYTES != 0 ||
        (uint64_t)(st.st_size - PM__HEADER_BYTES) / PM__RECORD_BYTES != hd.count) {
        rc = PM_EFORMAT;
        goto out;
    }
    if (hd.count > SIZE_MAX / sizeof(pm_photon)) {
        rc = PM_ERANGE;
        goto out;
    }
    if (hd.count > 0) {
        p = malloc((size_t)hd.count * sizeof *p);
        if (!p) {
            rc = PM_ENOMEM;
            goto out;
        }
        unsigned char buf[PM__RECORD_BYTES * PM__CHUNK];
        for (uint64_t i = 0; i < hd.count;) {
            size_t want = hd.count - i < PM__CHUNK ? (size_t)(hd.count - i) : PM__CHUNK;
            if (fread(buf, PM__RECORD_BYTES, want, f) != want) {
                rc = ferror(f) ? PM_EIO : PM_EFORMAT;
                goto out;
            }
            sum = fnv1a(sum, buf, PM__RECORD_BYTES * want);
            for (size_t c = 0; c < want; c++, i++)
                unpack_photon(&p[i], buf + PM__RECORD_BYTES * c);
        }
    }
    if (hd.version >= 3 && sum != want_sum) { /* a damaged header field or record */
        rc = PM_EFORMAT;
        goto out;
    }
    *hdr = hd;
    *photons = p;
    p = NULL;
out:
    free(p);
    fclose(f);
    return rc;
}
