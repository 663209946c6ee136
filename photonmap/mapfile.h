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
 *   uint64   tag[0]       two words the caller chooses to say what made the map (the
 *   uint64   tag[1]       renderer: a hash of the scene and one of the photon settings;
 *                         render/photons/photon_maps.h); 0 = none. Stored and returned, never
 *                         interpreted here
 *   uint64   checksum     FNV-1a 64 of header bytes 0..55 followed by every record's bytes as
 *                         stored (version 3; bytes 56..63, zero in versions 1 and 2)
 * Records are stored little-endian whatever the host.
 *
 * VERSIONS. Version 3 (PM_FILE_VERSION, written by every save) added the checksum in the
 * last 8 header bytes, which version 2 kept zero: a flipped bit anywhere in the header or the
 * records (a count, a tag, a photon's position or power) is refused as PM_EFORMAT, where the
 * checks of the header alone saw only bad values and sizes. Version 2 added tag[] and the kind
 * PM_MAP_VOLUME in bytes that version 1 kept zero (reserved[24] from byte 40) and in a kind
 * value it refused. Older files still load, without the checksum's protection: a version-2
 * file (hdr->version = 2) if its bytes 56..63 are zero; a version-1 file (hdr->version = 1,
 * tag = {0, 0}) if its bytes 40..63 are zero and its kind is one of
 * PM_MAP_GLOBAL..PM_MAP_OTHER. A reader of an older version refuses a newer file with
 * PM_EVERSION (not as a corrupt one). Any other version is refused with PM_EVERSION.
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
 * ignored (PM_FILE_VERSION is written), hdr->record_size must be 0 or 20 and hdr->kind one
 * of the PM_MAP_* values (else PM_EINVAL, nothing written); hdr->tag is written as given.
 *
 * LOADING. pm_map_load reads the header and checks every field before allocating anything:
 * the magic, the version (1 to 3), the record size, the kind (a PM_MAP_* value), the reserved
 * bytes (zero), and that the file's size is exactly 64 + 20 * count (so a corrupt or hostile count
 * can never make it allocate more than the file holds). It allocates *photons with malloc
 * (NULL for an empty map), and for version 3 compares the checksum after reading the records
 * (it is summed as they are read: no second pass); on a mismatch nothing is returned. The
 * caller frees *photons.
 *
 * ERRORS. PM_EIO (cannot open, read, write, flush or rename; errno has the detail),
 * PM_ENOTFILE (save: PATH exists and is not a regular file), PM_EFORMAT (bad magic, record
 * size, kind, reserved bytes, a size that does not match the count, or a checksum that does
 * not match the bytes), PM_EVERSION,
 * PM_EINVAL (NULL arguments, a bad record size or kind), PM_ENOMEM, PM_ERANGE (a count this build
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

#define PM_FILE_VERSION 3u
/* What a map holds. PM_MAP_VOLUME (photons in a participating medium) is new in version 2. */
enum { PM_MAP_GLOBAL = 1, PM_MAP_CAUSTIC = 2, PM_MAP_SHADOW = 3, PM_MAP_OTHER = 4, PM_MAP_VOLUME = 5 };

typedef struct pm_map_header {
    uint32_t version;     /* load: the file's version; save: ignored */
    uint32_t record_size;
    uint64_t count;
    uint32_t kind;        /* PM_MAP_* */
    uint64_t emitted;
    uint32_t tree_bucket;
    uint64_t tag[2];      /* the caller's, see FORMAT; a version-1 file loads with {0, 0} */
} pm_map_header;

int pm_map_save(const char *path, const pm_photon *photons, const pm_map_header *hdr);
int pm_map_load(const char *path, pm_photon **photons, pm_map_header *hdr);

#ifdef __cplusplus
}
#endif

#endif /* PM_MAPFILE_H */
