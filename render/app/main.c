/* main.c: the render program: parse the command line, load the scene, run an integrator,
 * write the images, print the summary and statistics.
 *
 *   render SCENE.json [-o out.png] [--hdr out.pfm] [--spp N] [--threads N] [--seed S]
 *          [--width W] [--height H] [--mode M] [--time S] [--passes N] [--pass-spp N]
 *          [--quiet] [--help]
 *
 * One pass of --spp samples (the scene's image.spp) is fixed work; --time, --passes or the
 * scene's render.time render in passes instead (run/passes.h).
 *
 * The image tools (render --compare, render --tonemap) are tools.c's; main() dispatches them.
 * Exit status: 0 success, 1 a failure while rendering or writing, 2 a usage error or a bad
 * scene file (nothing is written then). Progress goes to stderr; the summary and statistics
 * to stdout.
 */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "run/checkpoint.h"
#include "base/errors.h"
#include "photonmap/common.h"
#include "image/film.h"
#include "load/import.h"
#include "integrators/integrator.h"
#include "base/json.h"
#include "base/output.h"
#include "photons/photon_settings.h"
#include "run/passes.h"
#include "run/renderer.h"
#include "scene/scene.h"
#include "base/stats.h"
#include "app/tools.h"
#include "scene/delta_lit.h"

#ifdef _OPENMP
#include <omp.h>
#endif
#ifdef render_image_ctl /* render-mpi: main.c compiled again with mpicc (mpi/dist.h) */
#include "mpi/dist.h"
#endif

static void usage(FILE *f) {
    fprintf(f,
            "usage: render SCENE.json [options]\n"
            "       render --compare A.pfm B.pfm [--rect X Y W H] [--mask IDS.pfm --id N...]\n"
            "                    [--diff OUT.png [--diff-scale S]]\n"
            "       render --tonemap IN.pfm OUT.png [--exposure X] [--tone filmic|srgb]\n"
            "       render --dump-scene SCENE.json   (the scene as loaded, in our JSON format)\n"
            "\n"
            "Renders a JSON scene (format: data/scenes/README.md; a Tungsten scene is converted)\n"
            "to a PNG and/or a PFM.\n"
            "\n"
            "options:\n"
            "  -o FILE.png       tone-mapped 8-bit image (default: out.png unless --hdr is given)\n"
            "  --hdr FILE.pfm    linear float image, for exact comparison\n"
            "  --spp N           samples per pixel (rounded up to a square number of strata)\n"
            "  --threads N       worker threads (default: all cores)\n"
            "  --seed S          random seed (same seed, same image, for any thread count)\n"
            "  --width W         image width (the height follows the aspect unless given)\n"
            "  --height H        image height\n"
            "  --mode M          rendering algorithm (default: the scene's render.mode, else path):\n");
    integrator_list(f);
    fprintf(f,
            "  --time S          render in passes until S seconds of wall time are spent (the\n"
            "                    scene's render.time; overrides the scene's spp): a pass that\n"
            "                    the mean pass time says would overrun is not started, so the\n"
            "                    run takes at most S plus about one pass, and at least one pass\n"
            "  --passes N        render exactly N passes (with --time: whichever ends first);\n"
            "                    the same seed and passes give the same image on any threads\n"
            "  --pass-spp N      samples per pixel of each pass (default: the scene's\n"
            "                    render.pass_spp, else 4; rounded up to a square)\n"
            "                    The image is the mean of the pass images. Pass 0 is the plain\n"
            "                    render with --seed; pass p > 0 has its own seed. In pm and\n"
            "                    preview each pass traces fresh photon maps and the radii shrink\n"
            "                    (progressive photon mapping; --pm ppm_alpha=A; README.md)\n"
            "  --only-pass P     render pass P of such a render alone (to check the mean)\n"
            "  --tone T          filmic or srgb (PNG tone curve)\n"
            "  --exposure X      fixed exposure multiplier instead of auto exposure\n"
            "  --pm KEY=VALUE    a photon-mapping setting, as in the scene's \"photon_mapping\"\n"
            "                    object (e.g. --pm global_photons=500000 --pm caustics=false);\n"
            "                    the settings are listed below\n"
            "  --save-photons DIR  save the photon maps (DIR/global.pmap, caustic.pmap, shadow.pmap;\n"
            "                    with media also volume-M.pmap, volume_caustic-M.pmap per medium M)\n"
            "  --load-photons DIR  use saved photon maps instead of tracing photons; maps\n"
            "                    traced for another scene (or before it was edited), by another\n"
            "                    version of the photon tracer or with other photon settings are\n"
            "                    refused (exit status 2), as are a missing, corrupt or wrong-kind\n"
            "                    map file\n"
            "  --force-load-photons  use --load-photons maps of another scene or settings\n"
            "                    anyway (a warning per file; same as --pm force_load_photons=true)\n"
            "  --checkpoint FILE   save the render state to FILE (atomically) every\n"
            "                    --checkpoint-every seconds (default 600) and on SIGINT/SIGTERM;\n"
            "                    photon maps go to FILE.photons/ unless --save/--load-photons\n"
            "  --checkpoint-every S  seconds between checkpoints\n"
            "  --resume FILE     continue the render saved in FILE (its options are replayed;\n"
            "                    another scene, other settings or version are refused)\n"
            "  --snapshot-every S  rewrite the PNG (atomically) every S seconds while rendering\n"
            "  --max-scene-mb N  refuse scene files larger than N MiB (default 256)\n"
            "  --quiet           no progress output\n"
            "  --help            this text\n"
            "  --help-settings[=markdown]  the photon-mapping settings alone (markdown: the\n"
            "                    table of data/scenes/README.md)\n"
            "\n"
            "Outputs (-o, --hdr, --checkpoint, photon maps): a regular file is replaced whole\n"
            "(temporary + rename; all outputs together), a FIFO or character device is written\n"
            "through, a symlink is followed to its target; other kinds are refused. SIGINT or\n"
            "SIGTERM leaves the previous outputs and no temporary files.\n"
            "\n"
            "--compare prints the RMSE, mean relative error and means of A against the\n"
            "reference B, over the whole image or the rectangle X Y W H (pixels, top-left origin);\n"
            "--mask IDS.pfm --id N [--id M ...] keeps only the pixels that see objects N, M\n"
            "(IDS.pfm from --mode objects: the index in $.objects + 1); --diff OUT.png writes\n"
            "the luminance difference A - B (orange: A brighter, blue: darker), saturating\n"
            "at --diff-scale S (default 0.25) of B's mean luminance.\n"
            "\n"
            "exit status: 0 ok, 1 render or write failure, 2 usage error or invalid scene\n"
            "\n"
            "photon-mapping settings (\"photon_mapping\" in the scene, or --pm KEY=VALUE):\n");
    photon_settings_print(f, 0);
}

/* An integer option's value in [lo, hi]: 0, or -1 after saying what was expected. */
static int parse_opt(const char *opt, const char *v, long lo, long hi, long *out) {
    if (cli_parse_long(v, lo, hi, out) == 0) return 0;
    fprintf(stderr, "render: %s: expected a whole number in [%ld, %ld], got '%s'\n", opt, lo, hi, v);
    return -1;
}

static const char *basename_of(const char *p) {
    const char *s = strrchr(p, '/');
    return s ? s + 1 : p;
}

int main(int argc, char **argv) {
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
                usage(stdout);
                return 0;
            }
        return tools_compare(argc, argv);
    }
    /* --resume FILE: the checkpoint's stored arguments come first, then these (so options
     * given now win; settings that change the image must still match, see below). Static:
     * the replayed argv lives as long as the program. */
    static char **replay_argv, *replay_store;
    {
        char rerr[600];
        int rargc = 0;
        if (ckpt_replay_args(argc, argv, &rargc, &replay_argv, &replay_store, rerr, sizeof rerr) < 0) {
            fprintf(stderr, "render: --resume %s\n", rerr);
            return 2;
        }
        if (replay_argv) {
            argc = rargc;
            argv = replay_argv;
        }
    }
    const char *scene_path = NULL, *png = NULL, *pfm = NULL, *mode = NULL, *tone = NULL;
    const char *ckpt_path = NULL, *resume = NULL;
    double ckpt_every = 600, snap_every = 0;
    long max_scene_mb = 256;
    long spp = 0, threads = 0, width = 0, height = 0, seed = -1;
    long passes = 0, pass_spp = 0, only_pass = -1;
    double time_budget = 0;
    double exposure = -1;
    int quiet = 0;
    /* Photon-mapping flags, applied to the scene's photon_mapping object
     * (photon_settings.h). */
    const char *pm_flag[64], *pm_value[64];
    int npm = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const char *v = i + 1 < argc ? argv[i + 1] : NULL;
        int bad = 0;
#define NEED_VALUE()                                                          \
    do {                                                                      \
        if (!v) {                                                             \
            fprintf(stderr, "render: %s needs a value (see --help)\n", a);    \
            return 2;                                                         \
        }                                                                     \
        i++;                                                                  \
    } while (0)
        if (strcmp(a, "--help") == 0 || strcmp(a, "-h") == 0) {
            usage(stdout);
            return 0;
        } else if (strcmp(a, "-o") == 0) {
            NEED_VALUE();
            png = v;
        } else if (strcmp(a, "--hdr") == 0) {
            NEED_VALUE();
            pfm = v;
        } else if (strcmp(a, "--spp") == 0) {
            NEED_VALUE();
            bad = parse_opt(a, v, 1, 1 << 20, &spp);
        } else if (strcmp(a, "--time") == 0) {
            NEED_VALUE();
            if (cli_parse_positive(v, &time_budget) < 0 || time_budget > 1e9) {
                fprintf(stderr, "render: --time: expected seconds, a number in (0, 1e9], got '%s'\n", v);
                return 2;
            }
        } else if (strcmp(a, "--passes") == 0) {
            NEED_VALUE();
            bad = parse_opt(a, v, 1, 1 << 20, &passes);
        } else if (strcmp(a, "--pass-spp") == 0) {
            NEED_VALUE();
            bad = parse_opt(a, v, 1, 1 << 20, &pass_spp);
        } else if (strcmp(a, "--only-pass") == 0) {
            NEED_VALUE();
            bad = parse_opt(a, v, 0, 1 << 20, &only_pass);
        } else if (strcmp(a, "--threads") == 0) {
            NEED_VALUE();
            bad = parse_opt(a, v, 1, 1024, &threads);
        } else if (strcmp(a, "--seed") == 0) {
            NEED_VALUE();
            bad = parse_opt(a, v, 0, 2147483647L, &seed);
        } else if (strcmp(a, "--width") == 0) {
            NEED_VALUE();
            bad = parse_opt(a, v, 1, 1 << 14, &width);
        } else if (strcmp(a, "--height") == 0) {
            NEED_VALUE();
            bad = parse_opt(a, v, 1, 1 << 14, &height);
        } else if (strcmp(a, "--mode") == 0) {
            NEED_VALUE();
            mode = v;
        } else if (strcmp(a, "--tone") == 0) {
            NEED_VALUE();
            tone = v;
            bad = strcmp(v, "filmic") != 0 && strcmp(v, "srgb") != 0;
        } else if (strcmp(a, "--exposure") == 0) {
            NEED_VALUE();
            bad = cli_parse_positive(v, &exposure) < 0;
        } else if (strcmp(a, "--pm") == 0 || strcmp(a, "--save-photons") == 0 ||
                   strcmp(a, "--load-photons") == 0) {
            NEED_VALUE();
            if (npm == 64) {
                fprintf(stderr, "render: too many photon-mapping flags\n");
                return 2;
            }
            pm_flag[npm] = a;
            pm_value[npm++] = v;
        } else if (strcmp(a, "--force-load-photons") == 0) {
            if (npm == 64) {
                fprintf(stderr, "render: too many photon-mapping flags\n");
                return 2;
            }
            pm_flag[npm] = "--pm";
            pm_value[npm++] = "force_load_photons=true";
        } else if (strcmp(a, "--checkpoint") == 0) {
            NEED_VALUE();
            ckpt_path = v;
        } else if (strcmp(a, "--checkpoint-every") == 0) {
            NEED_VALUE();
            bad = cli_parse_positive(v, &ckpt_every) < 0;
        } else if (strcmp(a, "--snapshot-every") == 0) {
            NEED_VALUE();
            bad = cli_parse_positive(v, &snap_every) < 0;
        } else if (strcmp(a, "--resume") == 0) {
            NEED_VALUE();
            resume = v;
        } else if (strcmp(a, "--max-scene-mb") == 0) {
            NEED_VALUE();
            bad = parse_opt(a, v, 1, 1L << 20, &max_scene_mb);
        } else if (strcmp(a, "--quiet") == 0 || strcmp(a, "-q") == 0) {
            quiet = 1;
        } else if (a[0] == '-' && a[1]) {
            fprintf(stderr, "render: unknown option %s (see --help)\n", a);
            return 2;
        } else if (!scene_path) {
            scene_path = a;
        } else {
            fprintf(stderr, "render: more than one scene file given (%s, %s)\n", scene_path, a);
            return 2;
        }
        if (bad > 0) {
            fprintf(stderr, "render: %s: invalid value '%s' (see --help)\n", a, v);
            return 2;
        }
        if (bad < 0) return 2; /* parse_opt said why */
#undef NEED_VALUE
    }
    if (!scene_path) {
        usage(stderr);
        return 2;
    }
    if (!png && !pfm) png = "out.png";
    json_set_max_file_bytes((size_t)max_scene_mb << 20);
    out_signals_install();
    /* An output that cannot be written is refused now, not after the render. */
    const char *outs[3] = {pfm, png, ckpt_path}, *out_opt[3] = {"--hdr", "-o", "--checkpoint"};
    for (int k = 0; k < 3; k++) {
        char oerr[600];
        if (outs[k] && out_check(outs[k], oerr, sizeof oerr) < 0) {
            fprintf(stderr, "render: %s %s\n", out_opt[k], oerr);
            return 2;
        }
        for (int j = 0; j < k; j++)
            if (outs[j] && outs[k] && strcmp(outs[j], outs[k]) == 0) {
                fprintf(stderr, "render: %s and %s name the same file %s\n", out_opt[j], out_opt[k], outs[k]);
                return 2;
            }
    }

    /* --threads governs every parallel loop of the run, set before the first: the plan's
     * pilots run inside integrator_create, photon tracing in preprocess, then the pixels. */
    int nthreads = (int)threads;
#ifdef _OPENMP
    if (nthreads <= 0) nthreads = omp_get_max_threads();
    omp_set_num_threads(nthreads);
#else
    nthreads = 1;
#endif
    double t_start = stats_now();
    scene s;
    json_err e;
    int rc = scene_load(&s, scene_path, &e);
    if (rc < 0) {
        fprintf(stderr, "render: %s: %s\n", scene_path, e.msg);
        return 2;
    }
    double t_load = stats_now() - t_start;
    stats_time_add("Time/Scene loading and BVH build", t_load);
    if (spp) camera_set_spp(&s.cam, (int)spp);
    /* Passes (run/passes.h): --time, --passes, --only-pass, or the scene's render.time unless
     * --spp asks for one pass of fixed work. */
    int cli_passes = time_budget > 0 || passes > 0 || only_pass >= 0;
    int in_passes = cli_passes || (s.settings.time > 0 && !spp);
    if (cli_passes && spp) {
        fprintf(stderr, "render: --spp is one pass of fixed work; with --time, --passes or "
                "--only-pass give the samples of each pass with --pass-spp\n");
        scene_free(&s);
        return 2;
    }
    if (!in_passes && pass_spp) {
        fprintf(stderr, "render: --pass-spp needs passes: --time, --passes or the scene's render.time\n");
        scene_free(&s);
        return 2;
    }
    if (only_pass >= 0 && (ckpt_path || resume || snap_every > 0)) {
        fprintf(stderr, "render: --only-pass renders one pass alone: no --checkpoint, --resume or "
                "--snapshot-every with it\n");
        scene_free(&s);
        return 2;
    }
    double budget = time_budget > 0 ? time_budget : cli_passes ? 0 : s.settings.time;
    int pspp = pass_spp ? (int)pass_spp : s.settings.pass_spp ? s.settings.pass_spp : 4;
    if (in_passes) camera_set_spp(&s.cam, pspp);
    if (width || height) {
        /* The side not given follows the scene's aspect, and must stay in range too. */
        double w = width ? (double)width : floor((double)height * s.cam.width / s.cam.height + 0.5);
        double h = height ? (double)height : floor((double)width * s.cam.height / s.cam.width + 0.5);
        if (w > 1 << 14 || h > 1 << 14) {
            fprintf(stderr, "render: %s %ld gives a %s of %.0f at the scene's aspect %dx%d; the "
                    "limit is 16384 (give both --width and --height)\n", width ? "--width" : "--height",
                    width ? width : height, width ? "height" : "width", width ? h : w, s.cam.width,
                    s.cam.height);
            scene_free(&s);
            return 2;
        }
        camera_resize(&s.cam, w > 0 ? (int)w : 1, h > 0 ? (int)h : 1);
    }
    char err_unused[64];
    /* The photon-mapping settings are checked in every mode, so a typo in them is found
     * by a path-traced preview too: the scene's object first (its errors name the file),
     * then each option alone (its errors name the option). */
    {
        photon_settings ps;
        if (photon_settings_parse(&ps, s.photon_mapping, &e) < 0) {
            fprintf(stderr, "render: %s: %s\n", scene_path, e.msg);
            scene_free(&s);
            return 2;
        }
    }
    for (int k = 0; k < npm; k++) {
        char perr[256];
        /* A resumed render loads the maps its checkpoint names; they were saved already. */
        if (resume && strcmp(pm_flag[k], "--save-photons") == 0) continue;
        if (photon_settings_check_cli(pm_flag[k], pm_value[k], perr, sizeof perr) < 0 ||
            plan_cli_set(&s.photon_mapping, pm_flag[k], pm_value[k], perr, sizeof perr) < 0) {
            fprintf(stderr, "render: %s\n", perr);
            scene_free(&s);
            return 2;
        }
    }
    if (quiet) plan_cli_set(&s.photon_mapping, "--pm", "progress=false", err_unused, sizeof err_unused);
    if (seed >= 0) s.settings.seed = (uint64_t)seed;
    /* The file's render.mode is checked even when --mode replaces it: a misspelt mode in the
     * file is an error of the file, found now rather than when the option is dropped. */
    if (mode && strcmp(mode, s.settings.mode) != 0 && cli_mode_known(s.settings.mode) == 0) {
        char merr[256];
        integrator dummy;
        integrator_create(s.settings.mode, &s, &dummy, merr, sizeof merr); /* only says why */
        fprintf(stderr, "render: %s: $.render.mode: %s\n", scene_path, merr);
        scene_free(&s);
        return 2;
    }
    if (mode) snprintf(s.settings.mode, sizeof s.settings.mode, "%s", mode);
    if (tone) s.settings.tone = strcmp(tone, "srgb") == 0 ? TONE_SRGB : TONE_FILMIC;
    if (exposure > 0) s.settings.exposure = exposure;
    if (spp && s.cam.spp != spp)
        fprintf(stderr, "render: note: %ld spp rounded up to %d (%dx%d strata)\n", spp, s.cam.spp,
                s.cam.strata, s.cam.strata);
    if (in_passes && s.cam.spp != pspp)
        fprintf(stderr, "render: note: %d samples per pass rounded up to %d (%dx%d strata)\n", pspp,
                s.cam.spp, s.cam.strata, s.cam.strata);
    if (s.nlights == 0) {
        int any_emit = 0;
        for (int i = 0; i < s.nmats; i++) any_emit |= material_is_emissive(&s.mats[i]);
        if (!any_emit) fprintf(stderr, "render: %s: warning: the scene has no light; the image will be black\n", scene_path);
    }
    /* The path tracer cannot show caustics of point and directional lights: say where. */
    if (strcmp(s.settings.mode, "path") == 0) delta_lit_warn(&s, scene_path, stderr);

    /* Checkpoints and resume (checkpoint.h): what must match, and where the photon maps are. */
    static ckpt_session cs;
    render_state rstate = {0, 0, 0, NULL, NULL};
    int uses_photons = strcmp(s.settings.mode, "pm") == 0 || strcmp(s.settings.mode, "preview") == 0;
    if (uses_photons && scene_check_photon_range(&s, &e) < 0) { /* float photons: scene.h */
        fprintf(stderr, "render: %s: %s\n", scene_path, e.msg);
        scene_free(&s);
        return 2;
    }
    static pass_state pstate;
    if (in_passes) {
#ifdef render_image_ctl /* render-mpi (mpi/dist.h): passes in the replicated mode only */
        if (dist_partitioned()) {
            fprintf(stderr, "render-mpi: rendering in passes (--time, --passes, --only-pass or the "
                    "scene's render.time) is not available with --pm distributed=partitioned (each "
                    "pass would partition fresh maps); use the replicated mode, or --spp for one "
                    "pass of fixed work\n");
            scene_free(&s);
            return 2;
        }
#endif
        const cJSON *ld = s.photon_mapping ? cJSON_GetObjectItemCaseSensitive(s.photon_mapping, "load_photons") : NULL;
        if (uses_photons && cJSON_IsString(ld) && ld->valuestring[0]) {
            fprintf(stderr, "render: --load-photons (photon_mapping.load_photons) fixes the photon "
                    "maps, but each pass of --time, --passes or render.time traces its own: use one "
                    "or the other\n");
            scene_free(&s);
            return 2;
        }
        ckpt_set_passes(&pstate);
    }
    if ((rc = checkpoint_setup(&s, scene_path, argc, argv, ckpt_path, resume, uses_photons, &cs,
                               &rstate)) != 0) {
        scene_free(&s);
        return rc;
    }

    integrator it;
    char err[512];
    rc = integrator_create(s.settings.mode, &s, &it, err, sizeof err);
    if (rc < 0 && rc != PM_EINVAL) { /* the mode is known; making it failed (the plan's pilots
                                      * ran out of memory): a failure, not bad input */
        fprintf(stderr, "render: %s: %s\n", scene_path, err);
        scene_free(&s);
        return 1;
    }
    if (rc < 0) { /* name where the mode came from: the option, or the file's render.mode */
        if (mode)
            fprintf(stderr, "render: --mode %s: %s\n", mode, err);
        else
            fprintf(stderr, "render: %s: $.render.mode: %s\n", scene_path, err);
        scene_free(&s);
        return 2;
    }
    int nsph = s.nspheres, ntri = s.ntris;
    printf("Scene %s: %d triangles, %d spheres, %d materials, %d lights; BVH %d nodes, depth %d "
           "(%.3f s)\n",
           basename_of(scene_path), ntri, nsph, s.nmats, s.nlights, s.accel.nnodes, s.accel.depth, t_load);
    printf("Rendering %dx%d, %d spp (%dx%d strata), mode %s, %d thread%s, seed %llu\n", s.cam.width,
           s.cam.height, s.cam.spp, s.cam.strata, s.cam.strata, it.name, nthreads,
           nthreads == 1 ? "" : "s", (unsigned long long)s.settings.seed);
    if (in_passes) {
        printf("In passes of %d spp", s.cam.spp);
        if (only_pass >= 0) printf(": pass %ld alone", only_pass);
        if (passes > 0 && only_pass < 0) printf(": %ld passes", passes);
        if (budget > 0 && only_pass < 0) printf("%s time budget %.4g s", passes > 0 ? ", or a" : ": a", budget);
        printf("\n");
    }
    fflush(stdout);
    out_test_pause("photons");
    double t_prep0 = stats_now();
    if (it.preprocess) {
        double t0 = stats_now();
        rc = it.preprocess(&it, &s, err, sizeof err);
        stats_time_add("Time/Preprocessing", stats_now() - t0);
        if (rc < 0) {
            fprintf(stderr, "render: %s: %s\n", scene_path, err);
            integrator_destroy(&it);
            scene_free(&s);
            return rc == PM_EINVAL ? 2 : 1;
        }
    }
    film f;
    render_job job = {nthreads, quiet, s.settings.seed};
    render_control ctl = {NULL, 0, NULL, NULL, 0};
    if (in_passes && !pstate.sum && pass_state_init(&pstate, s.cam.width, s.cam.height) < 0) {
        fprintf(stderr, "render: out of memory for the render state\n");
        return 1;
    }
    if (ckpt_path || snap_every > 0 || resume) {
        if (!in_passes && !rstate.sum && render_state_init(&rstate, s.cam.width, s.cam.height, s.cam.spp) < 0) {
            fprintf(stderr, "render: out of memory for the render state\n");
            return 1;
        }
        cs.ckpt_path = ckpt_path;
        cs.ckpt_every = ckpt_every;
        cs.snap_path = snap_every > 0 ? png : NULL;
        cs.snap_every = snap_every;
        cs.tone = s.settings.tone;
        cs.exposure = s.settings.exposure;
        cs.clip_percent = s.settings.clip_percent;
        cs.quiet = quiet;
        cs.pass_spp = s.cam.spp;
        if ((rc = checkpoint_begin(&cs, uses_photons, &rstate)) != 0) return rc;
        ctl = (render_control){&rstate, ckpt_session_period(&cs), ckpt_session_pause, &cs, ckpt_path != NULL};
    }
    /* With a checkpoint, SIGINT/SIGTERM stop the render at the next sample boundary, write
     * the checkpoint, and then end the program by that signal. */
    if (ckpt_path) out_defer_begin();
    double t_render0 = stats_now();
    pass_report prep;
    memset(&prep, 0, sizeof prep);
    if (in_passes) {
        pass_run pr;
        memset(&pr, 0, sizeof pr);
        pr.max_passes = (int)passes;
        pr.budget = budget;
        pr.t_origin = t_start;
        pr.t_first = t_prep0; /* the first pass of this run counts its preprocessing */
        pr.only = (int)only_pass;
        pr.stop_on_signal = ckpt_path != NULL;
#ifdef render_image_ctl
        pr.image = dist_pass_image;
        pr.agree = dist_pass_agree;
#else
        pr.image = render_image_ctl;
#endif
        pr.on_pass = ckpt_path || snap_every > 0 ? ckpt_session_pass : NULL;
        pr.user = &cs;
        pr.quiet = quiet;
        err[0] = 0;
        rc = render_passes(&s, &it, &job, &pr, &pstate, &f, &prep, err, sizeof err);
#ifdef render_image_ctl
        dist_passes_end(rc); /* the worker ranks end here */
#endif
        if (rc < 0 && err[0]) snprintf(cs.err, sizeof cs.err, "%s", err);
        /* The last state, so that the render can be continued with more passes. */
        if (rc == 0 && ckpt_path && !out_pending_signal() &&
            ckpt_session_pass(&cs, &pstate, RENDER_PAUSE_SIGNAL) < 0)
            rc = PM_EIO;
    } else {
        rc = render_image_ctl(&s, &it, &job, &ctl, &f);
    }
    double t_render = stats_now() - t_render0;
    integrator_destroy(&it);
    if (ckpt_path) {
        if (rc == 0 && out_pending_signal())
            rc = in_passes ? ckpt_session_pass(&cs, &pstate, RENDER_PAUSE_SIGNAL)
                           : ckpt_session_pause(&cs, &rstate, RENDER_PAUSE_SIGNAL);
        if (rc == 0 && out_pending_signal()) rc = RENDER_INTERRUPTED;
        if (rc == RENDER_INTERRUPTED)
            fprintf(stderr, "render: interrupted; the render state is in %s (continue with: %s "
                    "%s --resume %s)\n", ckpt_path, ckpt_resume_command(), scene_path, ckpt_path);
        out_defer_end();
        out_die_if_pending();
    }
    if (rc < 0) {
        fprintf(stderr, "render: rendering failed: %s%s%s\n", render_strerror(rc), cs.err[0] ? ": " : "", cs.err);
        scene_free(&s);
        return 1;
    }
    render_state_free(&rstate);
    double pass_err = -1, pass_mean = 0;
    int passes_done = pstate.done;
    if (in_passes) pass_err = pass_state_rmse(&pstate, &pass_mean);
    pass_state_free(&pstate);
    int status = 0;
    size_t nonfinite = film_count_nonfinite(&f);
    if (nonfinite)
        fprintf(stderr, "render: warning: %zu pixel%s of the image %s not finite (inf or NaN; "
                "\"Film/Non-finite pixels\" below)\n", nonfinite, nonfinite == 1 ? "" : "s",
                nonfinite == 1 ? "is" : "are");
    double used = 0;
    char werr[600];
    if (film_write_outputs(&f, pfm, png, s.settings.tone, s.settings.exposure, s.settings.clip_percent,
                           &used, werr, sizeof werr) < 0) {
        fprintf(stderr, "render: %s (no output written)\n", werr);
        status = 1;
    }
    double wall = stats_now() - t_start;
    uint64_t rays = stats_total(STAT_CAMERA_RAYS) + stats_total(STAT_INDIRECT_RAYS) +
                    stats_total(STAT_SHADOW_RAYS);
    printf("Summary: wall time %.2f s (rendering %.2f s), %.3g M rays, %.3g M rays/s\n", wall, t_render,
           (double)rays * 1e-6, t_render > 0 ? (double)rays * 1e-6 / t_render : 0.0);
    if (in_passes) {
        printf("Passes: %d done (%d by this run) of %d spp; mean pass %.3f s, longest %.3f s; "
               "elapsed %.3f s", passes_done, prep.passes, s.cam.spp, prep.mean, prep.longest,
               prep.elapsed);
        if (budget > 0 && only_pass < 0)
            printf(" of a budget of %.4g s%s", budget, prep.stopped_by_budget ? " (stopped by it)" : "");
        if (pass_err >= 0)
            printf("; error estimate %.4g (%.3f%% of the mean %.4g)", pass_err,
                   pass_mean > 0 ? 100 * pass_err / pass_mean : 0.0, pass_mean);
        printf("\n");
    }
    if (status == 0) {
        if (png)
            printf("Wrote %s (%s, exposure %.4g%s)\n", png, s.settings.tone == TONE_SRGB ? "sRGB" : "filmic",
                   used, s.settings.exposure > 0 ? "" : ", auto");
        if (pfm) printf("Wrote %s (linear)\n", pfm);
    }
    stats_print(stdout);
    film_free(&f);
    scene_free(&s);
    return status;
}
