/* irradiance_internal.h: what the two files of precomputed irradiance share (irradiance.c the
 * build, irradiance_lookup.c the lookups): the compact record of the lookup tree and the
 * pm_irradiance structure. Not installed, not API.
 */
#ifndef PM_IRRADIANCE_INTERNAL_H
#define PM_IRRADIANCE_INTERNAL_H

#include <stddef.h>
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
    float normals[256][3];
};

#endif /* PM_IRRADIANCE_INTERNAL_H */
