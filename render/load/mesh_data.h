/* mesh_data.h: the mesh a reader fills (obj.h, ply.h, wo3.h) and mesh_free(); loading by
 * extension, the transform and the shading normals are mesh.h's.
 *
 * Positions, optional normals and triangles that index them, in the file's own coordinates
 * (mesh.h says what the readers check and skip). Kept apart from mesh.h so that the readers
 * depend on this alone and mesh.c's dispatch (mesh_load) on them, with no circle between them.
 *
 * Ownership: the mesh_data owns its arrays; mesh_free() releases them (a zeroed one may be
 * freed).
 */
#ifndef RENDER_MESH_DATA_H
#define RENDER_MESH_DATA_H

#include <stdlib.h>
#include <string.h>

#include "base/vec.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct mesh_data {
    vec3 *pos;
    int npos;
    vec3 *nrm; /* normals of the file (OBJ vn, wo3 vertex normals), NULL if none */
    int nnrm;
    int (*tri)[3];   /* position indices of each triangle, 0-based */
    int (*tri_n)[3]; /* normal indices per corner, -1 where the face gave none; NULL if none */
    int *tri_group;  /* OBJ: index into groups (the usemtl name), -1 before any usemtl */
    int ntris;
    char **groups; /* usemtl names in order of first use */
    int ngroups;
    vec3 (*corner_n)[3]; /* after mesh_smooth_normals: unit shading normal of each corner */
    long nskipped;       /* degenerate faces (zero area) the reader left out */
    char first_skip[64]; /* where the first of them is ("line 12", "byte 1032", "face 7") */
} mesh_data;

static inline void mesh_free(mesh_data *m) {
    free(m->pos);
    free(m->nrm);
    free(m->tri);
    free(m->tri_n);
    free(m->tri_group);
    for (int g = 0; g < m->ngroups; g++) free(m->groups[g]);
    free(m->groups);
    free(m->corner_n);
    memset(m, 0, sizeof *m);
}

#ifdef __cplusplus
}
#endif
#endif /* RENDER_MESH_DATA_H */
