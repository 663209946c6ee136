/* common.h: error codes and the small types every photonmap module shares.
 *
 * Included by each public header, so any one of them can be used alone.
 */
#ifndef PM_COMMON_H
#define PM_COMMON_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* The library's version. The shared library's soname carries the major version
 * (libphotonmap.so.2), which changes only when the API or ABI does; the Makefile and
 * photonmap.pc read these three lines. 2.0.0 changed the ABI: pm_map_header gained tag[2]
 * (mapfile.h, file format version 2) and the kd-tree took the photon flag's bits 4-7
 * (PM_FLAG_TREE_MASK, photon.h). */
#define PM_VERSION_MAJOR 2
#define PM_VERSION_MINOR 0
#define PM_VERSION_PATCH 0
#define PM__VERSION_STR(x) #x
#define PM__VERSION_XSTR(x) PM__VERSION_STR(x)
#define PM_VERSION_STRING                                                    \
    PM__VERSION_XSTR(PM_VERSION_MAJOR) "." PM__VERSION_XSTR(PM_VERSION_MINOR) "." \
    PM__VERSION_XSTR(PM_VERSION_PATCH)

/* Error codes. All are negative; 0 means success. */
enum {
    PM_OK = 0,
    PM_EINVAL = -1,     /* an argument is out of its documented range */
    PM_ENOMEM = -2,     /* an allocation failed */
    PM_ENONFINITE = -3, /* a NaN or infinite number where a finite one is required */
    PM_EIO = -4,        /* reading or writing a file failed (errno has the detail) */
    PM_EFORMAT = -5,    /* a file is not a photon-map file, or is truncated or corrupt */
    PM_EVERSION = -6,   /* a file was written by an incompatible version */
    PM_ERANGE = -7,     /* a count or size is too large for this build (e.g. > 2^32-2 records) */
    PM_EEMPTY = -8,     /* an operation needs at least one record and got none */
    PM_ENOTFILE = -9    /* an output path exists and is not a regular file: never replaced */
};

/* A static English description of an error code; never NULL. */
const char *pm_strerror(int code);

/* One query result: a record's index in the (reordered) record array and its squared
 * distance to the query point. 8 bytes, so k results fit in k*8 bytes of caller memory. */
typedef struct pm_neighbor {
    float dist2;
    uint32_t index;
} pm_neighbor;

/* Optional work counters for one or more queries. Queries add to the fields (they never
 * reset them), so one struct can sum over many queries. Pass NULL to skip counting. */
typedef struct pm_query_stats {
    uint64_t nodes_visited; /* tree nodes (or octree cells) whose children or records were examined */
    uint64_t dist_evals;    /* squared distances computed between the query and a record */
} pm_query_stats;

#ifdef __cplusplus
}
#endif

#endif /* PM_COMMON_H */
