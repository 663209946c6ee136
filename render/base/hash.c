/* hash.c: 64-bit FNV-1a over memory and over files; see hash.h. */
#include "base/hash.h"

#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "photonmap/common.h"

uint64_t hash_fnv1a(uint64_t h, const void *p, size_t n) {
    const unsigned char *b = p;
    for (size_t i = 0; i < n; i++) {
        h ^= b[i];
        h *= 0x100000001b3ULL;
    }
    return h;
}

int hash_file(const char *path, uint64_t max_bytes, uint64_t *h, char *err, size_t errcap) {
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
        *h = hash_fnv1a(*h, buf, got);
    }
    int bad = ferror(f);
    fclose(f);
    if (bad) {
        snprintf(err, errcap, "%s: cannot read", path);
        return PM_EIO;
    }
    return 0;
}
