/* mesh.h: triangle meshes read from files (Wavefront OBJ, Tungsten's binary wo3, PLY), placed in the
 * scene by a transform, with flat or smooth shading normals.
 *
 * A reader (obj.h, ply.h, wo3.h) fills a mesh_data (mesh_data.h) in the file's own coordinates: positions, optional
 * normals, and triangles that index them. Faces are checked while reading, so every error names
 * the place in the file ("bunny.obj:12: vertex index 99 out of range (1..98)", "water.wo3: byte
 * 1032: ..."): a truncated file, an index out of range, a NaN or infinite number and an empty
 * mesh are errors. A degenerate face (zero area: repeated or collinear corners, judged as
 * triangle_make does) is not: real meshes carry them and other renderers skip them, so the
 * readers leave it out and count it (nskipped, first_skip), and mesh_object_read (import.h)
 * prints one warning per file. A file whose faces are all degenerate is an empty mesh.
 * mesh_load() picks the reader by the file name's extension (.obj, .wo3 or .ply, any case).
 *
 * mesh_transform() applies a 3x4 affine matrix to positions (and its inverse transpose to
 * normals). The front of a triangle is decided after the transform, by the winding of the
 * transformed vertices (shapes.h), as Tungsten does: a mirroring matrix (negative
 * determinant) turns the front to the other side. mesh_smooth_normals() makes one shading normal per triangle corner: the
 * file's normals when it has them for every corner and recompute is 0, else the area-weighted
 * mean of the geometric normals of the triangles around the vertex that bend by less than
 * MESH_CREASE_DEG from this triangle (so a cube stays a cube). Shading normals are always
 * turned to the front side of their triangle's geometric normal; they only shade, never
 * decide a side (scene.h).
 *
 * The mesh_data and mesh_free() are mesh_data.h's: the readers need them and nothing else of
 * this file, so they do not depend on the dispatch that calls them. Nothing here keeps state;
 * errors go to the caller's buffer.
 */
#ifndef RENDER_MESH_H
#define RENDER_MESH_H

#include <stddef.h>

#include "base/vec.h"
#include "load/mesh_data.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Smooth normals are not averaged across edges sharper than this (degrees). */
#define MESH_CREASE_DEG 30.0


/* Read path as OBJ, wo3 or PLY by its extension. 0, or a negative PM_E* code with a message that
 * starts with the file name in err. */
int mesh_load(const char *path, mesh_data *m, char *err, size_t cap);
/* Read a whole file into a malloc'd buffer (NUL-terminated; the caller frees it). 0, PM_EIO
 * or PM_ENOMEM with a message naming path. */
int mesh_read_file(const char *path, char **buf, size_t *len, char *err, size_t cap);

/* Below this volume spanned by the transform's columns scaled to length 1 (|det| of the
 * matrix with unit columns: 1 for any rotation and scale, uniform or not, 0 when the columns
 * are linearly dependent) the transform is singular: rounding leaves about 1e-16 in the volume
 * of dependent columns, and at 1e-12 its inverse (for normals) keeps about 4 of 16 digits. */
#define MESH_SINGULAR_VOLUME 1e-12

/* p' = M[0..2][0..2] p + M[.][3]. Returns PM_EINVAL (message in err, starting with path) if M
 * is not finite or singular (see MESH_SINGULAR_VOLUME); how large or small it scales lengths
 * is not judged here (mesh_transform_lengths). */
int mesh_transform(mesh_data *m, const double M[3][4], const char *path, char *err, size_t cap);

/* Does M keep the mesh's lengths in len_min..len_max (the scene's range, scene.h "Ranges")? On
 * the mesh before mesh_transform: PM_EINVAL, with a message (no path; "moves the file's vertex
 * 3, [1, 0, 0], to [1e+150, 0, 0], outside the supported range of coordinates, ..." or "makes
 * a triangle 1.41421 across in the file 1.41421e-150 across, below the supported range of
 * lengths, ..."), when it takes a vertex within len_max of the origin outside it, or a
 * triangle at least len_min across (its longest edge) below that. Lengths the file already
 * had out of range, and triangles the transform collapses to 0 (singular), are not its
 * business. 0 otherwise. */
int mesh_transform_lengths(const mesh_data *m, const double M[3][4], double len_min, double len_max,
                           char *err, size_t cap);

/* Fill corner_n (see the top of this file). PM_ENOMEM or 0. */
int mesh_smooth_normals(mesh_data *m, int recompute);

/* Total area of the triangles. */
double mesh_area(const mesh_data *m);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_MESH_H */
