/* errors.c: render_strerror, the renderer's wording of the PM_E* codes; see errors.h. */
#include "base/errors.h"

#include <errno.h>
#include <string.h>

#include "photonmap/common.h"

const char *render_strerror(int code) {
    switch (code) {
    case 0: return "no error";
    case PM_EINVAL: return "invalid value";
    case PM_ENOMEM: return "out of memory";
    case PM_ENONFINITE: return "a NaN or infinite value";
    case PM_EIO: return errno ? strerror(errno) : "input/output error";
    case PM_EFORMAT: return "not in the expected file format, or truncated or corrupt";
    case PM_EVERSION: return "file version not supported";
    case PM_ERANGE: return "too large";
    case PM_EEMPTY: return "empty";
    case PM_ENOTFILE: return "exists and is not a regular file";
    }
    return "unknown error";
}
