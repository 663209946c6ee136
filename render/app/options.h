/* options.h: render's command-line options (options.c): one table drives their parsing, the
 * messages for bad values and the text of `render --help`.
 */
#ifndef RENDER_APP_OPTIONS_H
#define RENDER_APP_OPTIONS_H

#include <stdio.h>

#ifdef __cplusplus
extern "C" {
#endif

#define OPTIONS_PM_MAX 64

/* What the command line asks for; zero/NULL (or the defaults of options_parse) when absent. */
typedef struct render_options {
    const char *scene_path, *png, *pfm, *mode, *tone, *ckpt_path, *resume;
    int hdr_half, quiet;
    double ckpt_every, snap_every, time_budget, exposure, adaptive;
    long max_scene_mb, spp, threads, width, height, seed, passes, pass_spp, only_pass;
    /* Photon-mapping flags in order (--pm, --save-photons, --load-photons, and
     * --force-load-photons as --pm force_load_photons=true), applied to the scene's
     * photon_mapping object (photon_settings.h). */
    const char *pm_flag[OPTIONS_PM_MAX], *pm_value[OPTIONS_PM_MAX];
    int npm;
    int argc;   /* the arguments parsed (after --resume's replay), for the checkpoint */
    char **argv;
} render_options;

/* Parse argv into *o (which it fills whole). APP_GO (app.h) to render, else the exit status
 * after printing why (or --help's text, status 0). A missing scene prints the usage to stderr
 * (status 2). */
int options_parse(render_options *o, int argc, char **argv);

/* `render --help`: the usage, the options of the table, the notes, and the settings. */
void options_usage(FILE *f);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_APP_OPTIONS_H */
