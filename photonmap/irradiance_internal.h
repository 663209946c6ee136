/* irradiance_internal.h: what the two files of precomputed irradiance share (irradiance.c the
 * build, irradiance_lookup.c the lookups): the compact record of the lookup tree and the
 * pm_irradiance structure. Not installed, not API.
 */
#ifndef PM_IRRADIANCE_INTERNAL_H
#define PM_IRRADIANCE_INTERNAL_H

#include <stddef.h>
#include <math.h>
#include <stdint.h>

#include "irradiance.h"
#include "kdtree.h"

/* One precomputed photon in the lookup tree: the lookup's predicate reads only this record
 * (plus the radius array when radii are kept). */
typedef struct pm__irr_rec {
    float pos[3];
    uint8_t rgbe[4];
    uint8_t ncode; /* pm_photon.normal of the photon (or of opt.normals) */
    uint8_t axis;  /* the lookup tree's split axis (low 2 bits; pm_kdtree owns them) */
    uint8_t pad[2];
} pm__irr_rec;

struct pm_irradiance {
    size_t n;            /* photons in the map */
    size_t done;         /* photons precomputed */
    uint64_t *mask;      /* (n + 63) / 64 words: bit i = photon i was precomputed */
    uint32_t *rank;      /* per word: precomputed photons before it */
    uint32_t *slot;      /* done entries: record (in recs) of the j-th precomputed photon */
    pm__irr_rec *recs;   /* done records, in the lookup tree's order */
    float *r2;           /* done radii^2, same order, or NULL */
    uint32_t *photon;    /* done map indices, same order, or NULL (opt.store_index) */
    pm_kdtree *tree;     /* over recs (NULL when done = 0) */
    float *reach;        /* with r2: per heap node of tree, the largest r2 in its subtree */
    uint8_t *nmask;      /* with reach: per heap node, the normal buckets of its subtree's records */
    uint8_t nbucket[256]; /* per normal code: its bucket's bit (NORMAL BUCKETS in irradiance.c) */
    float normals[256][3];
};

/* NORMAL BUCKETS. A record's normal falls in one of six buckets, by its largest component and
 * that component's sign (bit 2 a for +a, 2 a + 1 for -a). A normal in a bucket is at most
 * acos(1/sqrt 3) (the cube's corner) from the bucket's axis, so a query normal n with the rule
 * n . m >= c (m unit) can only meet bucket (a, sign) when the angle between n and that axis is
 * at most acos(1/sqrt 3) + acos(c / |n|): sign n[a] >= |n| cos of that sum (less a margin for
 * rounding).
 * A subtree whose buckets miss the query's holds no record the normal rule passes, so skipping
 * it changes no answer. */
static inline uint8_t pm__normal_bucket(const float m[3]) {
    float ax = fabsf(m[0]), ay = fabsf(m[1]), az = fabsf(m[2]);
    int a = ax >= ay && ax >= az ? 0 : (ay >= az ? 1 : 2);
    return (uint8_t)(1u << (2 * a + (m[a] < 0)));
}

static inline uint8_t pm__normal_query_mask(const float n[3], float cos_min) {
    /* the rule is n . m >= cos_min with n as given: for a unit m, an angle whose cosine is
     * cos_min / |n| from n's direction */
    double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
    if (!(len > 0) || !isfinite(len) || isnan(cos_min)) return 0x3f;
    double c = (double)cos_min / len;
    if (c > 1) c = 1;
    if (!(c > -0.57735)) return 0x3f; /* the sum of the angles reaches pi: every bucket */
    double t = (c / sqrt(3.0) - sqrt(2.0 / 3.0) * sqrt(1 - c * c) - 1e-5) * len;
    uint8_t m = 0;
    for (int a = 0; a < 3; a++) {
        if (n[a] >= t) m |= (uint8_t)(1u << (2 * a));
        if (-n[a] >= t) m |= (uint8_t)(1u << (2 * a + 1));
    }
    return m;
}

#endif /* PM_IRRADIANCE_INTERNAL_H */
