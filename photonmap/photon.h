/* photon.h: the compact photon record of Jensen's notes (the photon-map file format that
 * stores it is in mapfile.h).
 *
 * A pm_photon is 20 bytes (checked by a static assertion in photon.c):
 *
 *   pos[3]     3 x float   world position, exact
 *   power[4]   RGBE        Ward's shared-exponent colour (see precision below)
 *   theta,phi  2 x uint8   incident direction (the direction the photon travelled), decoded
 *                          through constant tables: no trigonometry per lookup
 *   flag       uint8       bits 0-1 and 4-7 (PM_FLAG_TREE_MASK): the kd-tree's, see below;
 *                          bits 2-3 (PM_FLAG_KIND_MASK): photon kind (PM_KIND_*)
 *   normal     uint8       the surface normal where the photon was stored, quantized to one
 *                          of 256 directions (used by precomputed irradiance)
 *
 * Precision of the packed fields (bounds derived in photon.c and asserted over random inputs
 * in tests/test_photon.c):
 *   - RGBE: each channel is an 8-bit mantissa scaled by one shared 8-bit exponent, rounded to
 *     nearest. The largest channel has a relative error <= 2^-8 (0.39%); every other
 *     channel an absolute error <= max(r,g,b) * 2^-8 / (1 - 2^-9) (0.3914% of the largest),
 *     so channels far below the largest lose relative precision and those below max/512
 *     may become 0. A largest channel below 2^-128 (2.9e-39) encodes
 *     as zero; above 255 * 2^119 (1.69e38), and +inf, saturate to that value. Negative and NaN
 *     channels encode as zero. Decoding is exact arithmetic (byte * a power of two).
 *   - direction: theta = acos(z) and phi = atan2(y, x) are quantized to 256 bins each and
 *     decoded at the bin centre: at most 0.35 degrees in theta and 0.70*sin(theta) degrees in
 *     phi, 0.79 degrees in all, and 0.36 at the poles. The decoded vector has unit length
 *     within 1e-6.
 *   - normal: the nearest (exactly, by dot product) of 256 points of a spherical Fibonacci
 *     lattice; the angular error is at most the lattice's covering radius, about 9.72 degrees
 *     (the test asserts <= 10 degrees over random normals). Encoding costs about 50 dot
 *     products; decoding is a table lookup.
 *
 * THE TREE'S BITS. A pm_kdtree built with pm_kdtree_photon_config() keeps the split axis of
 * each internal node in bits 0-1 of that record's flag byte (PM_FLAG_AXIS_MASK) and a code
 * that shrinks the node's cell toward its records in bits 4-7 (kdtree.h), writes 0 in all six
 * for bucket records, and reads them in every query. Exactly those six bits
 * (PM_FLAG_TREE_MASK) are the tree's; while the tree exists nothing else may change them (or
 * the position). Everything
 * else may change: pm_photon_set, pm_photon_set_power and pm_photon_set_kind rewrite their
 * fields and keep the tree's bits, so updating powers after a build (e.g. rescaling for the
 * number of photons emitted) is safe with any of them. pm_photon_init is for fresh memory:
 * it also zeroes the tree's bits (pm_photon_set would keep whatever bytes were there, which a
 * later build overwrites anyway). Writing p->flag or a whole record by hand, or memcpy from
 * another record, does clobber the tree's bits (and a clobbered code can make queries miss
 * records).
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
#define PM_FLAG_TREE_MASK 0xF3u /* the kd-tree's bits (see THE TREE'S BITS above) */
#define PM_FLAG_AXIS_MASK 0x03u /* of which the split axis */
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

/* Fill a photon from unpacked values (kind is a PM_KIND_*; normal may be NULL: code 0).
 * pm_photon_set keeps the tree's bits of p->flag as they are (safe on a record of a built
 * tree); pm_photon_init zeroes them (for fresh memory). */
void pm_photon_set(pm_photon *p, const float pos[3], const float power[3], const float dir[3],
                   const float normal[3], int kind);
void pm_photon_init(pm_photon *p, const float pos[3], const float power[3], const float dir[3],
                    const float normal[3], int kind);
/* Change one field, keeping the tree's bits (and, for power, everything else). */
void pm_photon_set_power(pm_photon *p, const float power[3]);
void pm_photon_set_kind(pm_photon *p, int kind);
static inline int pm_photon_kind(const pm_photon *p) {
    return (p->flag & PM_FLAG_KIND_MASK) >> PM_FLAG_KIND_SHIFT;
}

#ifdef __cplusplus
}
#endif

/* The photon-map file format used to be declared here; code that included photon.h for it
 * keeps compiling. */
#include "mapfile.h"

#endif /* PM_PHOTON_H */
