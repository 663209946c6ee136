/* photonmap.h: the one header a user includes.
 *
 * photonmap is a small C11 library for photon maps as described in Jensen's course notes
 * ("A Practical Guide to Global Illumination using Photon Maps") and Christensen's notes
 * ("Faster photon map global illumination", "iteration instead of recursion"):
 *
 *   photon.h    the 20-byte photon record (RGBE power, 2-byte direction, 1-byte normal)
 *   mapfile.h   the photon-map file (save and load)
 *   kdtree.h    a left-balanced kd-tree stored as an implicit heap over any records that
 *               carry a float[3] position; k-nearest, radius and predicate queries
 *   estimate.h  radiance estimates (disc, cone, Gaussian, differential, convex hull, volume)
 *   irradiance.h precomputed irradiance and its normal-checked lookup
 *   combined.h  one estimate from several maps of the same scene
 *
 * Conventions used everywhere:
 *   - public names start with pm_ (macros PM_); names with pm__ are internal.
 *   - functions that can fail return int: 0 (or a count) on success, a negative PM_E* code
 *     on failure; pm_strerror() turns a code into text. There is no global error state.
 *   - every squared distance is named dist2 or r2. Nothing takes a plain radius unless the
 *     name says so.
 *   - a built tree is immutable; queries never allocate and never lock, so any number of
 *     threads may query one tree at once.
 *
 * Dependencies: libc and libm. OpenMP is used, where the build enables it, to parallelize
 * precomputation; without it the same code runs on one thread.
 */
#ifndef PM_PHOTONMAP_H
#define PM_PHOTONMAP_H

#include "common.h"
#include "photon.h"
#include "mapfile.h"
#include "kdtree.h"
#include "estimate.h"
#include "irradiance.h"
#include "combined.h"

#endif /* PM_PHOTONMAP_H */
