/* mapfile.h: the photon-map file, a pm_photon array and its header on disk.
 *
 * FORMAT. A little-endian binary file: a 64-byte header, then `count` records of
 * `record_size` bytes, each a pm_photon laid out as in photon.h, and nothing after them.
 * Header fields, in order:
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
 * Records are stored little-endian whatever the host.
 *
 * SAVING. pm_map_save writes the whole file to a new temporary file in the same directory
 * (PATH.XXXXXX, created by mkstemp, so concurrent saves never share one and no existing file
 * is touched), flushes it to disk and renames it over PATH: a reader sees the old file or the
 * new one, never a mix, and on any failure the temporary is removed and PATH is untouched.
 * PATH itself is replaced only if it does not exist or is a regular file: if it is anything
 * else (a symbolic link, even to a regular file; a FIFO; a device node; a directory; a
 * socket) the save is refused with PM_ENOTFILE before anything is written, so a save never
 * writes through a link or into a pipe or device. (Between that check and the rename another
 * process could put a link at PATH; the rename then replaces the link, never its target.)
 * A new file gets mode 0644; a replaced file keeps its permission bits. hdr->version is
 * ignored (PM_FILE_VERSION is written) and hdr->record_size must be 0 or 20.
 *
 * LOADING. pm_map_load reads the header and checks every field before allocating anything:
 * the magic, the version, the record size, the kind (a PM_MAP_* value), the reserved bytes
 * (zero), and that the file's size is exactly 64 + 20 * count (so a corrupt or hostile count
 * can never make it allocate more than the file holds). It allocates *photons with malloc
 * (NULL for an empty map); the caller frees it.
 *
 * ERRORS. PM_EIO (cannot open, read, write, flush or rename; errno has the detail),
 * PM_ENOTFILE (save: PATH exists and is not a regular file), PM_EFORMAT (bad magic, record
 * size, kind, reserved bytes, or a size that does not match the count), PM_EVERSION,
 * PM_EINVAL (NULL arguments, a bad record size), PM_ENOMEM, PM_ERANGE (a count this build
 * cannot address).
 *
 * Thread safety: no shared state; concurrent saves to one PATH each write their own temporary
 * and the last rename wins.
 */
#ifndef PM_MAPFILE_H
#define PM_MAPFILE_H

#include "common.h"
#include "photon.h"

#ifdef __cplusplus
extern "C" {
#endif

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

#endif /* PM_MAPFILE_H */
