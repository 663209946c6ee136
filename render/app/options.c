/* options.c: render's command-line options; see options.h.
 *
 * One table, k_options, holds every option: its name, the kind of its argument, its range,
 * the field of render_options it sets, and its help. The parser looks an argument up in it
 * and checks the value by its kind (each kind has one message for a bad value), and --help
 * prints the rows in order: the name and argument, the help at column 20, continuation lines
 * indented to it. The settings of photon mapping have their own table (photon_settings.c),
 * which --pm reaches and --help prints after these.
 */
#include "app/options.h"

#include <stddef.h>
#include <stdlib.h>
#include <string.h>

#include "app/app.h"
#include "app/tools.h"
#include "image/exr.h"
#include "integrators/integrator.h"
#include "load/photon_settings.h"

typedef enum {
    OPT_FLAG,     /* no value: an int field set to 1 */
    OPT_TEXT,     /* a value kept as given: a const char * field */
    OPT_CHOICE,   /* one of the words of `extra` ("filmic|srgb"): a const char * field */
    OPT_LONG,     /* a whole number in [lo, hi]: a long field */
    OPT_POSITIVE, /* a positive, finite number: a double field */
    OPT_SECONDS,  /* a positive number up to hi, in seconds: a double field */
    OPT_SHARE,    /* a finite number in [lo, hi]: a double field */
    OPT_PM,       /* a photon-mapping flag, kept in order with its value (pm_flag, pm_value) */
    OPT_PM_SET,   /* no value: the photon-mapping setting `extra` (as --pm extra) */
    OPT_HELP,     /* this text, then exit 0 */
    OPT_ALONE     /* only as the sole argument (render_main dispatches it); listed here */
} opt_kind;

typedef struct option_def {
    const char *name, *alias; /* alias: a short form, or NULL */
    const char *arg;          /* the value's name in --help ("N"); NULL: none */
    opt_kind kind;
    double lo, hi;
    size_t offset;            /* of the field in render_options */
    const char *extra;        /* OPT_CHOICE: the words; OPT_PM_SET: the setting */
    const char *help;         /* lines after the first are indented to column 20 */
    void (*more)(FILE *f);    /* prints more help after the row's (a list), or NULL */
} option_def;

#define F(field) offsetof(render_options, field)
#define NONE 0, 0 /* lo, hi: no range */

static const option_def k_options[] = {
    {"-o", NULL, "FILE.png", OPT_TEXT, NONE, F(png), NULL,
     "tone-mapped 8-bit image (default: out.png unless --hdr is given)", NULL},
    {"--hdr", NULL, "FILE.pfm", OPT_TEXT, NONE, F(pfm), NULL,
     "linear float image, for exact comparison (FILE.exr: OpenEXR)", NULL},
    {"--hdr-half", NULL, NULL, OPT_FLAG, NONE, F(hdr_half), NULL,
     "with --hdr FILE.exr: 16-bit half floats instead of 32-bit", NULL},
    {"--spp", NULL, "N", OPT_LONG, 1, 1 << 20, F(spp), NULL,
     "samples per pixel (rounded up to a square number of strata)", NULL},
    {"--threads", NULL, "N", OPT_LONG, 1, 1024, F(threads), NULL,
     "worker threads (default: all cores)", NULL},
    {"--seed", NULL, "S", OPT_LONG, 0, 2147483647L, F(seed), NULL,
     "random seed (same seed, same image, for any thread count)", NULL},
    {"--width", NULL, "W", OPT_LONG, 1, 1 << 14, F(width), NULL,
     "image width (the height follows the aspect unless given)", NULL},
    {"--height", NULL, "H", OPT_LONG, 1, 1 << 14, F(height), NULL, "image height", NULL},
    {"--mode", NULL, "M", OPT_TEXT, NONE, F(mode), NULL,
     "rendering algorithm (default: the scene's render.mode, else path):", integrator_list},
    {"--time", NULL, "S", OPT_SECONDS, 0, 1e9, F(time_budget), NULL,
     "render in passes until S seconds of wall time are spent (the\n"
     "scene's render.time; overrides the scene's spp): a pass that\n"
     "the mean pass time says would overrun is not started, so the\n"
     "run takes at most S plus about one pass, and at least one pass", NULL},
    {"--passes", NULL, "N", OPT_LONG, 1, 1 << 20, F(passes), NULL,
     "render exactly N passes (with --time: whichever ends first);\n"
     "the same seed and passes give the same image on any threads", NULL},
    {"--pass-spp", NULL, "N", OPT_LONG, 1, 1 << 20, F(pass_spp), NULL,
     "samples per pixel of each pass (default: the scene's\n"
     "render.pass_spp, else 4, or more below 128x128 pixels: at\n"
     "least 65536 samples a pass; rounded up to a square)\n"
     "The image is the mean of the pass images. Pass 0 is the plain\n"
     "render with --seed; pass p > 0 has its own seed. In pm and\n"
     "preview each pass traces fresh photon maps and the radii shrink\n"
     "(progressive photon mapping; --pm ppm_alpha=A; README.md)", NULL},
    {"--only-pass", NULL, "P", OPT_LONG, 0, 1 << 20, F(only_pass), NULL,
     "render pass P of such a render alone (to check the mean;\n"
     "it takes no adaptive samples: compare with --adaptive 0)", NULL},
    {"--adaptive", NULL, "A", OPT_SHARE, 0, 31, F(adaptive), NULL,
     "in passes, after the first 4: at most A times a plain pass's\n"
     "samples more (default 0.25: 25% more), given to the pixels whose\n"
     "pass images vary most, each up to 32 x its own (0: none)", NULL},
    {"--tone", NULL, "T", OPT_CHOICE, NONE, F(tone), "filmic|srgb",
     "filmic or srgb (PNG tone curve)", NULL},
    {"--exposure", NULL, "X", OPT_POSITIVE, NONE, F(exposure), NULL,
     "fixed exposure multiplier instead of auto exposure", NULL},
    {"--pm", NULL, "KEY=VALUE", OPT_PM, NONE, 0, NULL,
     "a photon-mapping setting, as in the scene's \"photon_mapping\"\n"
     "object (e.g. --pm global_photons=500000 --pm caustics=false);\n"
     "the settings are listed below", NULL},
    {"--save-photons", NULL, "DIR", OPT_PM, NONE, 0, NULL,
     "save the photon maps (DIR/global.pmap, caustic.pmap, shadow.pmap;\n"
     "with media also volume-M.pmap, volume_caustic-M.pmap per medium M)", NULL},
    {"--load-photons", NULL, "DIR", OPT_PM, NONE, 0, NULL,
     "use saved photon maps instead of tracing photons; maps\n"
     "traced for another scene (or before it was edited), by another\n"
     "version of the photon tracer or with other photon settings are\n"
     "refused (exit status 2), as are a missing, corrupt or wrong-kind\n"
     "map file", NULL},
    {"--force-load-photons", NULL, NULL, OPT_PM_SET, NONE, 0, "force_load_photons=true",
     "use --load-photons maps of another scene or settings\n"
     "anyway (a warning per file; same as --pm force_load_photons=true)", NULL},
    /* "FILE " (one space more): its help starts where the photon-map options' does */
    {"--checkpoint", NULL, "FILE ", OPT_TEXT, NONE, F(ckpt_path), NULL,
     "save the render state to FILE (atomically) every\n"
     "--checkpoint-every seconds (default 600) and on SIGINT/SIGTERM;\n"
     "photon maps go to FILE.photons/ unless --save/--load-photons", NULL},
    {"--checkpoint-every", NULL, "S", OPT_POSITIVE, NONE, F(ckpt_every), NULL,
     "seconds between checkpoints", NULL},
    {"--resume", NULL, "FILE", OPT_TEXT, NONE, F(resume), NULL,
     "continue the render saved in FILE (its options are replayed;\n"
     "with no --pass-spp among them, its samples per pass are kept;\n"
     "another scene, other settings or version are refused)", NULL},
    {"--snapshot-every", NULL, "S", OPT_POSITIVE, NONE, F(snap_every), NULL,
     "rewrite the PNG (atomically) every S seconds while rendering", NULL},
    {"--max-scene-mb", NULL, "N", OPT_LONG, 1, 1L << 20, F(max_scene_mb), NULL,
     "refuse scene files larger than N MiB (default 256)", NULL},
    {"--quiet", "-q", NULL, OPT_FLAG, NONE, F(quiet), NULL, "no progress output", NULL},
    {"--help", "-h", NULL, OPT_HELP, NONE, 0, NULL, "this text", NULL},
    {"--help-settings", NULL, "[=markdown]", OPT_ALONE, NONE, 0, NULL,
     "the photon-mapping settings alone (markdown: the\n"
     "table of data/scenes/README.md)", NULL},
};
#define NOPTIONS (sizeof k_options / sizeof k_options[0])

static const option_def *find(const char *a) {
    for (size_t i = 0; i < NOPTIONS; i++) {
        const option_def *d = &k_options[i];
        if (d->kind != OPT_ALONE && (strcmp(a, d->name) == 0 || (d->alias && strcmp(a, d->alias) == 0)))
            return d;
    }
    return NULL;
}

/* A word of a "a|b|c" list, whole. */
static int is_choice(const char *words, const char *v) {
    size_t n = strlen(v);
    for (const char *w = words; w; w = strchr(w, '|'), w = w ? w + 1 : NULL)
        if (strncmp(w, v, n) == 0 && (w[n] == '|' || w[n] == 0)) return 1;
    return 0;
}

/* A bound as it is written in the source: 1e9, not 1e+09. */
static void short_number(double x, char *buf, size_t cap) {
    char tmp[32];
    snprintf(tmp, sizeof tmp, "%g", x);
    char *e = strchr(tmp, 'e');
    if (e) {
        char *d = e + 1;
        if (*d == '+') memmove(d, d + 1, strlen(d));
        if (*d == '-') d++;
        while (d[0] == '0' && d[1]) memmove(d, d + 1, strlen(d));
    }
    snprintf(buf, cap, "%s", tmp);
}

static int add_pm(render_options *o, const char *flag, const char *value) {
    if (o->npm == OPTIONS_PM_MAX) {
        fprintf(stderr, "render: too many photon-mapping flags\n");
        return 2;
    }
    o->pm_flag[o->npm] = flag;
    o->pm_value[o->npm++] = value;
    return APP_GO;
}

/* Option d, as typed a, with its value v (NULL for none): APP_GO or the exit status. */
static int apply(render_options *o, const option_def *d, const char *a, const char *v) {
    char *field = (char *)o + d->offset;
    int bad = 0;
    switch (d->kind) {
    case OPT_FLAG: *(int *)field = 1; break;
    case OPT_TEXT: *(const char **)field = v; break;
    case OPT_CHOICE:
        *(const char **)field = v;
        bad = !is_choice(d->extra, v);
        break;
    case OPT_LONG:
        if (cli_parse_long(v, (long)d->lo, (long)d->hi, (long *)field) < 0) {
            fprintf(stderr, "render: %s: expected a whole number in [%ld, %ld], got '%s'\n", a,
                    (long)d->lo, (long)d->hi, v);
            return 2;
        }
        break;
    case OPT_POSITIVE: bad = cli_parse_positive(v, (double *)field) < 0; break;
    case OPT_SECONDS:
        if (cli_parse_positive(v, (double *)field) < 0 || *(double *)field > d->hi) {
            char hi[32];
            short_number(d->hi, hi, sizeof hi);
            fprintf(stderr, "render: %s: expected seconds, a number in (0, %s], got '%s'\n", a, hi, v);
            return 2;
        }
        break;
    case OPT_SHARE: {
        char *end;
        double x = strtod(v, &end);
        if (end == v || *end || !(x >= d->lo && x <= d->hi)) {
            char lo[32], hi[32];
            short_number(d->lo, lo, sizeof lo);
            short_number(d->hi, hi, sizeof hi);
            fprintf(stderr, "render: %s: expected a number in [%s, %s], got '%s'\n", a, lo, hi, v);
            return 2;
        }
        *(double *)field = x;
        break;
    }
    case OPT_PM: return add_pm(o, a, v);
    case OPT_PM_SET: return add_pm(o, "--pm", d->extra);
    case OPT_HELP: options_usage(stdout); return 0;
    case OPT_ALONE: break; /* never found: find() skips it */
    }
    if (bad) {
        fprintf(stderr, "render: %s: invalid value '%s' (see --help)\n", a, v);
        return 2;
    }
    return APP_GO;
}

int options_parse(render_options *o, int argc, char **argv) {
    memset(o, 0, sizeof *o);
    o->ckpt_every = 600;
    o->max_scene_mb = 256;
    o->seed = -1;
    o->only_pass = -1;
    o->exposure = -1;
    o->adaptive = 0.25;
    o->argc = argc;
    o->argv = argv;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        const option_def *d = find(a);
        const char *v = NULL;
        if (d && d->arg) {
            if (i + 1 >= argc) {
                fprintf(stderr, "render: %s needs a value (see --help)\n", a);
                return 2;
            }
            v = argv[++i];
        }
        int rc;
        if (d) {
            if ((rc = apply(o, d, a, v)) != APP_GO) return rc;
        } else if (a[0] == '-' && a[1]) {
            fprintf(stderr, "render: unknown option %s (see --help)\n", a);
            return 2;
        } else if (!o->scene_path) {
            o->scene_path = a;
        } else {
            fprintf(stderr, "render: more than one scene file given (%s, %s)\n", o->scene_path, a);
            return 2;
        }
    }
    if (!o->scene_path) {
        options_usage(stderr);
        return 2;
    }
    if (!o->png && !o->pfm) o->png = "out.png";
    if (o->hdr_half && !(o->pfm && exr_has_ext(o->pfm))) {
        fprintf(stderr, "render: --hdr-half needs --hdr FILE.exr (a PFM holds 32-bit floats only)\n");
        return 2;
    }
    return APP_GO;
}

/* One row: "  NAME ARG", the help from column 20 (at least two spaces after the name), its
 * further lines indented to column 20. */
static void print_option(FILE *f, const option_def *d) {
    char left[64];
    snprintf(left, sizeof left, "%s%s%s", d->name, d->arg && d->arg[0] != '[' ? " " : "",
             d->arg ? d->arg : "");
    int pad = 18 - (int)strlen(left);
    fprintf(f, "  %s%*s", left, pad < 2 ? 2 : pad, "");
    for (const char *h = d->help; *h;) {
        const char *nl = strchr(h, '\n');
        int n = nl ? (int)(nl - h) : (int)strlen(h);
        fprintf(f, "%.*s\n", n, h);
        if (!nl) break;
        h = nl + 1;
        fprintf(f, "%20s", "");
    }
    if (d->more) d->more(f);
}

void options_usage(FILE *f) {
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
            "options:\n");
    for (size_t i = 0; i < NOPTIONS; i++) print_option(f, &k_options[i]);
    fprintf(f,
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
