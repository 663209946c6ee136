/* render_main.c: the render program as a function (app.h): it dispatches the tools, replays a
 * checkpoint's arguments, parses the options (options.h), and runs the steps of a render
 * (run.h) in order.
 *
 *   render SCENE.json [-o out.png] [--hdr out.pfm] [--spp N] [--threads N] [--seed S]
 *          [--width W] [--height H] [--mode M] [--time S] [--passes N] [--pass-spp N]
 *          [--quiet] [--help]
 *
 * The image tools (render --compare, render --tonemap, render --dump-scene) are tools.c's.
 * Exit status: 0 success, 1 a failure while rendering or writing, 2 a usage error or a bad
 * scene file (nothing is written then).
 */
#include "app/app.h"

#include <stdio.h>
#include <string.h>

#include "app/options.h"
#include "app/run.h"
#include "app/tools.h"
#include "load/photon_settings.h"
#include "run/checkpoint.h"
#include "run/renderer.h"

static const render_hooks k_render_hooks = {render_image_ctl, render_image_ctl, NULL, NULL, NULL, NULL};

/* The programs that are not a render: APP_GO when argv asks for none of them. */
static int run_tool(int argc, char **argv) {
    if (argc == 2 && (strcmp(argv[1], "--help-settings") == 0 ||
                      strcmp(argv[1], "--help-settings=markdown") == 0)) {
        photon_settings_print(stdout, argv[1][15] == '=');
        return 0;
    }
    if (argc >= 2 && strcmp(argv[1], "--tonemap") == 0) return tools_tonemap(argc, argv);
    if (argc >= 2 && strcmp(argv[1], "--dump-scene") == 0) return scene_dump_main(argc, argv);
    if (argc >= 2 && strcmp(argv[1], "--compare") == 0) {
        for (int i = 2; i < argc; i++)
            if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
                options_usage(stdout);
                return 0;
            }
        return tools_compare(argc, argv);
    }
    return APP_GO;
}

int render_main(int argc, char **argv, const render_hooks *hooks) {
    int rc = run_tool(argc, argv);
    if (rc != APP_GO) return rc;
    /* --resume FILE: the checkpoint's stored arguments come first, then these (so options
     * given now win; settings that change the image must still match, checkpoint.h).
     * Static: the replayed argv, the options and the run (whose checkpoint session and pass
     * state the signal path reaches) live as long as the program. */
    static char **replay_argv, *replay_store;
    char rerr[600];
    int rargc = 0;
    if (ckpt_replay_args(argc, argv, &rargc, &replay_argv, &replay_store, rerr, sizeof rerr) < 0) {
        fprintf(stderr, "render: --resume %s\n", rerr);
        return 2;
    }
    static render_options o;
    rc = replay_argv ? options_parse(&o, rargc, replay_argv) : options_parse(&o, argc, argv);
    if (rc != APP_GO) return rc;
    static app_run r;
    r.o = &o;
    r.hooks = hooks ? hooks : &k_render_hooks;
    if ((rc = run_prepare(&r)) == APP_GO && (rc = run_load_scene(&r)) == APP_GO &&
        (rc = run_setup_checkpoint(&r)) == APP_GO && (rc = run_create_integrator(&r)) == APP_GO &&
        (rc = run_render(&r)) == APP_GO)
        rc = run_write_outputs(&r);
    run_free(&r);
    return rc;
}
