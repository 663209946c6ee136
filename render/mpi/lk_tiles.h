/* lk_tiles.h: a partitioned render's tiles (lookup.h, PIXEL PASS; lk_tiles.c defines
 * lk_render_tiles): the camera sample each render thread is tracing, where its queries are
 * kept (lookup.c's ask). Internal to render/mpi.
 */
#ifndef RENDER_MPI_LK_TILES_H
#define RENDER_MPI_LK_TILES_H

#include "lk_serve.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The sample a render thread is tracing (NULL outside lk_render_tiles's traces). */
extern _Thread_local lk_smp *lk_tl_smp;

#ifdef __cplusplus
}
#endif
#endif /* RENDER_MPI_LK_TILES_H */
