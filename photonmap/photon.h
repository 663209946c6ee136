/* photon.h: the compact photon record of Jensen's notes, and the photon-map file format.
 *
 * A pm_photon is 20 bytes (checked by a static assertion in photon.c):
 *
 *   pos[3]     3 x float   world position, exact
 *   power[4]   RGBE        Ward's shared-exponent colour (see precision below)
 *   theta,phi  2 x uint8   incident direction (the direction the photon travelled), decoded
 *                          through constant tables: no trigonometry per lookup
 *   flag       uint8       bits 0-1: kd-tree split axis (owned by the tree, see kdtree.h);
 *                          bits 2-3: photon kind (PM_KIND_*); bits 4-7: reserved, zero
 *   normal     uint8       the surface normal where the photon was stored, quantized to one
 *                          of 256 directions (used by precomputed irradiance)
 *
 * Precision of the packed fields (bounds derived in photon.c, measured over 2M random inputs
 * and tested in tests/test_photon.c):
 *   - RGBE: each channel is an 8-bit mantissa scaled by one shared 8-bit exponent, rounded to
 *     nearest. The largest channel has a relative error <= 2^-8 (0.39%; measured 0.389%); every
 *     other channel an absolute error <= max(r,g,b) * 2^-8 / (1 - 2^-9) (0.3914% of the
 *     largest; measured 0.3912%), so channels far below the largest lose relative precision
 *     and those below max/512 may become 0. A largest channel below 2^-128 (2.9e-39) encodes
 *     as zero; above 255 * 2^119 (1.69e38), and +inf, saturate to that value. Negative and NaN
 *     channels encode as zero. Decoding is exact arithmetic (byte * a power of two).
 *   - direction: theta = acos(z) and phi = atan2(y, x) are quantized to 256 bins each and
 *     decoded at the bin centre: at most 0.35 degrees in theta and 0.70*sin(theta) degrees in
 *     phi, 0.79 degrees in all (measured 0.784), and 0.36 at the poles (measured 0.346). The
 *     decoded vector has unit length within 1e-6.
 *   - normal: the nearest (exactly, by dot product) of 256 points of a spherical Fibonacci
 *     lattice; the angular error is at most the lattice's covering radius, about 9.72 degrees
 *     (measured 9.717 over 2M random normals; the test asserts <= 10).
 *     Encoding costs about 50 dot products; decoding is a table lookup.
 *
 * Thread safety: all functions here are pure or read constant tables; no initialization call.
 */
#ifndef PM_PHOTON_H
#define PM_PHOTON_H

#include <stdio.h>
#include "common.h"

#ifdef __cplusplus
extern "C" {
#endif

enum {
    PM_KIND_INDIRECT = 0, /* reached its surface after at least one bounce */
    PM_KIND_DIRECT = 1,   /* first hit from the light */
    PM_KIND_SHADOW = 2,   /* later hit along the light's ray: marks a shadowed point */
    PM_KIND_CAUSTIC = 3   /* L S+ D path (kept in a caustic map) */
};
#define PM_FLAG_AXIS_MASK 0x03u
#define PM_FLAG_KIND_SHIFT 2
#define PM_FLAG_KIND_MASK 0x0Cu

typedef struct pm_photon {
    float pos[3];
    uint8_t power[4]; /* RGBE */
    uint8_t theta, phi;
    uint8_t flag;
    uint8_t normal;
} pm_photon;

/* RGBE packing of a non-negative RGB triple. */
void pm_rgbe_encode(const float rgb[3], uint8_t rgbe[4]);
void pm_rgbe_decode(const uint8_t rgbe[4], float rgb[3]);

/* Direction packing. dir need not be normalized but must be non-zero and finite; a zero or
 * non-finite dir encodes as theta = phi = 0. decode writes a unit vector. */
void pm_dir_encode(const float dir[3], uint8_t *theta, uint8_t *phi);
void pm_dir_decode(uint8_t theta, uint8_t phi, float dir[3]);

/* Normal packing: the nearest of 256 fixed unit directions. */
uint8_t pm_normal_encode(const float n[3]);
void pm_normal_decode(uint8_t code, float n[3]);

/* Fill a photon from unpacked values (kind is a PM_KIND_*; the axis bits are left zero). */
void pm_photon_set(pm_photon *p, const float pos[3], const float power[3], const float dir[3],
                   const float normal[3], int kind);
static inline int pm_photon_kind(const pm_photon *p) {
    return (p->flag & PM_FLAG_KIND_MASK) >> PM_FLAG_KIND_SHIFT;
}

/* Photon-map files.
 *
 * A little-endian binary file: a 64-byte header, then `count` records of `record_size`
 * bytes, each a pm_photon as laid out above. Header fields, in order:
 *   char     magic[8]     "PMAPHOTN"
 *   uint32   version      PM_FILE_VERSION
 *   uint32   record_size  sizeof(pm_photon) = 20
 *   uint64   count        number of photons
 *   uint32   kind         what the map is (PM_MAP_* below)
 *   uint32   emitted      photons emitted to build the map (for the power scale), low 32 bits
 *   uint32   emitted_hi   high 32 bits
 *   uint32   tree_bucket  0 if the records are in no particular order; B if they are in the
 *                         tree order of a pm_kdtree built with bucket size B (the loader can
 *                         then rebuild the tree without reordering)
 *   uint8    reserved[24] zero
 *
 * pm_map_save writes to PATH.tmp and renames it over PATH, so a file is written whole or not
 * at all (on any failure PATH.tmp is removed and PATH is untouched); hdr->version is ignored
 * (PM_FILE_VERSION is written) and hdr->record_size must be 0 or 20. pm_map_load allocates
 * *photons with malloc (NULL for an empty map); the caller frees it. Errors: PM_EIO (cannot
 * open, read or write; errno has the detail), PM_EFORMAT (bad magic, record size, or a file
 * shorter than its count says), PM_EVERSION, PM_EINVAL (NULL arguments).
 * Records are stored little-endian whatever the host.
 */
#define PM_FILE_VERSION 1u
enum { PM_MAP_GLOBAL = 1, PM_MAP_CAUSTIC = 2, PM_MAP_SHADOW = 3, PM_MAP_OTHER = 4 };

typedef struct pm_map_header {
    uint32_t version;
    uint32_t record_size;
    uint64_t count;
    uint32_t kind;
    uint64_t emitted;
    uint32_t tree_bucket;
} pm_map_header;

int pm_map_save(const char *path, const pm_photon *photons, const pm_map_header *hdr);
int pm_map_load(const char *path, pm_photon **photons, pm_map_header *hdr);

#ifdef __cplusplus
}
#endif

#endif /* PM_PHOTON_H */
