/* app.h: the render program as a function, render_main, and the hooks through which a later
 * stage changes its flow without app/ knowing that stage.
 *
 * render's main() (main.c) is render_main(argc, argv, NULL). render-mpi (render/mpi/
 * render_mpi.c) starts MPI and calls render_main with its own hooks: the image loop of a
 * distributed render, the agreement of the ranks before each pass, and the refusal of passes
 * in the partitioned mode. app/ never includes mpi/: the hooks are the whole seam.
 *
 * The steps of render_main (options.h parses, run.h renders) return APP_GO to go on, or the
 * program's exit status: 0 ok, 1 a failure while rendering or writing, 2 a usage error or a
 * bad scene file.
 */
#ifndef RENDER_APP_H
#define RENDER_APP_H

#include "run/passes.h"

#ifdef __cplusplus
extern "C" {
#endif

#define APP_GO (-1)

typedef struct render_hooks {
    pass_image_fn image;        /* the image loop of a render of fixed work (render_image_ctl) */
    pass_image_fn pass_image;   /* the image loop of one pass (render_image_ctl) */
    int (*pass_agree)(int go);  /* before each pass (pass_run.agree); NULL: none */
    int (*pass_share)(unsigned char *buf, size_t n); /* pass_run.share; NULL: none */
    void (*passes_end)(int rc); /* after the pass loop, with its result; NULL: none */
    const char *no_passes;      /* not NULL: rendering in passes is refused with this message
                                 * (exit status 2) */
} render_hooks;

/* The render program: argv as main's; hooks NULL for render's own. Returns the exit status.
 * Called once per process: its state is static, as the checkpoint's signal path needs. */
int render_main(int argc, char **argv, const render_hooks *hooks);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_APP_H */
