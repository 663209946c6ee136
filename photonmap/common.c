/* common.c: error strings shared by every photonmap module. */
#include "common.h"

const char *pm_strerror(int code) {
    switch (code) {
    case PM_OK: return "success";
    case PM_EINVAL: return "invalid argument";
    case PM_ENOMEM: return "out of memory";
    case PM_ENONFINITE: return "non-finite (NaN or infinite) value";
    case PM_EIO: return "input/output error";
    case PM_EFORMAT: return "not a photon-map file, or a truncated or corrupt one";
    case PM_EVERSION: return "photon-map file version not supported";
    case PM_ERANGE: return "count or size too large";
    case PM_EEMPTY: return "no records";
    case PM_ENOTFILE: return "output path exists and is not a regular file (link, FIFO, device, directory)";
    default: return code > 0 ? "not an error code (positive)" : "unknown error code";
    }
}
