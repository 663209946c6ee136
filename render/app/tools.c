/* tools.c: the two image tools of the render program, `render --compare` (error of one PFM
 * against a reference, over the image, a rectangle or an object mask, with an optional
 * difference PNG) and `render --tonemap` (a PFM to a PNG with the render's tone curves), and
 * the strict number parsers they share with main.c's options, and the check of a mode name
 * against integrator.h's registry (main.c and render --dump-scene).
 *
 * Each tool parses its own arguments (argv[1] is the tool's flag) and returns the exit status:
 * 0 ok, 1 a write failure, 2 a usage error or an unreadable input. The comparison itself is
 * compare.c's; the PFM and PNG codecs are film.c's.
 */
#include "app/tools.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "image/compare.h"
#include "base/errors.h"
#include "image/film.h"
#include "integrators/integrator.h"
#include "load/import.h"
#include "load/scene_load.h"
#include "scene/scene.h"

/* 1 if name is a mode of integrator.h's registry (read from integrator_list's lines: four
 * spaces, the name, spaces, its help), 0 if not, -1 if it cannot tell (no memory). */
int cli_mode_known(const char *name) {
    char *buf = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&buf, &len);
    if (!f) return -1;
    integrator_list(f);
    if (fclose(f) != 0 || !buf) {
        free(buf);
        return -1;
    }
    int found = 0;
    size_t n = strlen(name);
    for (const char *line = buf; *line && !found;) {
        while (*line == ' ') line++;
        found = strncmp(line, name, n) == 0 && (line[n] == ' ' || line[n] == '\n' || !line[n]);
        const char *nl = strchr(line, '\n');
        line = nl ? nl + 1 : line + strlen(line);
    }
    free(buf);
    return found;
}

/* A whole number in [lo, hi] with nothing after it: 0, or -1. */
int cli_parse_long(const char *s, long lo, long hi, long *out) {
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || end == s || *end || v < lo || v > hi) return -1;
    *out = v;
    return 0;
}

/* A positive, finite number: 0, or -1 (a missing value, trailing text, <= 0, inf, nan). */
int cli_parse_positive(const char *s, double *out) {
    if (!s) return -1;
    char *end;
    double v = strtod(s, &end);
    if (end == s || *end || !(v > 0) || !isfinite(v)) return -1;
    *out = v;
    return 0;
}

static int read_pfm_or_say(film *f, const char *path) { /* PFM or OpenEXR (film_read_image) */
    char err[600];
    int rc = film_read_image(f, path, err, sizeof err);
    if (rc < 0)
        fprintf(stderr, "render: %s\n", err);
    return rc;
}

/* A usage error of a tool's arguments: the message on stderr, and the exit status 2. */
static int usage(const char *msg) {
    fprintf(stderr, "render: %s\n", msg);
    return 2;
}

/* A tool's next positional argument, into *first, then *second: 0, or -1 when both are taken. */
static int positional(const char *arg, const char **first, const char **second) {
    if (!*first)
        *first = arg;
    else if (!*second)
        *second = arg;
    else
        return -1;
    return 0;
}

int tools_compare(int argc, char **argv) {
    const char *fa = NULL, *fb = NULL, *fmask = NULL, *fdiff = NULL;
    long rect[4] = {0, 0, 0, 0};
    int ids[64], nids = 0;
    double dscale = 0.25;
    for (int i = 2; i < argc; i++) {
        if (strcmp(argv[i], "--rect") == 0) {
            if (i + 4 >= argc)
                return usage("--rect needs X Y W H");
            for (int k = 0; k < 4; k++)
                if (cli_parse_long(argv[i + 1 + k], -100000, 100000, &rect[k]) < 0) {
                    fprintf(stderr, "render: --rect: bad number '%s'\n", argv[i + 1 + k]);
                    return 2;
                }
            i += 4;
        } else if (strcmp(argv[i], "--mask") == 0 || strcmp(argv[i], "--diff") == 0) {
            if (i + 1 >= argc) {
                fprintf(stderr, "render: %s needs a file name\n", argv[i]);
                return 2;
            }
            *(argv[i][2] == 'm' ? &fmask : &fdiff) = argv[i + 1];
            i++;
        } else if (strcmp(argv[i], "--id") == 0) {
            long v;
            if (i + 1 >= argc || cli_parse_long(argv[i + 1], 0, 1000000, &v) < 0)
                return usage("--id needs an object id (a whole number >= 0)");
            if (nids == (int)(sizeof ids / sizeof ids[0])) {
                fprintf(stderr, "render: at most %d --id options\n", nids);
                return 2;
            }
            ids[nids++] = (int)v;
            i++;
        } else if (strcmp(argv[i], "--diff-scale") == 0) {
            if (cli_parse_positive(i + 1 < argc ? argv[i + 1] : NULL, &dscale) < 0)
                return usage("--diff-scale needs a positive number");
            i++;
        } else if (positional(argv[i], &fa, &fb) < 0) {
            return usage("--compare takes two files");
        }
    }
    if (!fa || !fb)
        return usage("--compare needs two PFM files");
    if (!fmask != !nids)
        return usage("--mask and --id go together");
    film a = {0}, b = {0}, mask = {0};
    int rc = read_pfm_or_say(&a, fa);
    if (rc == 0) rc = read_pfm_or_say(&b, fb);
    if (rc == 0 && fmask) rc = read_pfm_or_say(&mask, fmask);
    if (rc < 0) {
        film_free(&a);
        film_free(&b);
        film_free(&mask);
        return 2;
    }
    image_diff d;
    image_region reg = {(int)rect[0], (int)rect[1], (int)rect[2], (int)rect[3], fmask ? &mask : NULL,
                        ids, nids};
    rc = image_compare_region(&a, &b, &reg, &d);
    if (rc < 0) {
        fprintf(stderr, "render: --compare: %s\n",
                a.width != b.width || a.height != b.height ? "the images differ in size"
                : fmask && (mask.width != a.width || mask.height != a.height)
                    ? "the mask differs in size from the images"
                    : "the region holds no pixel");
    } else {
        printf("pixels %ld\nrmse %.6g\nrel_rmse %.6g\nmre %.6g\nmean_a %.6g\nmean_b %.6g\nrel_mean %.6g\n",
               d.npixels, d.rmse, d.rel_rmse, d.mre, d.mean_a, d.mean_b, d.rel_mean);
        if (fdiff && (rc = image_diff_png(&a, &b, dscale, fdiff)) < 0)
            fprintf(stderr, "render: %s: %s\n", fdiff, render_strerror(rc));
    }
    film_free(&a);
    film_free(&b);
    film_free(&mask);
    return rc < 0 ? 2 : 0;
}

/* render --tonemap IN.pfm OUT.png [--exposure X] [--tone filmic|srgb]: a PFM to a PNG, with
 * the same tone curves and auto exposure as a render (so images can share one exposure). */
int tools_tonemap(int argc, char **argv) {
    const char *in = NULL, *out = NULL;
    double exposure = -1;
    int tone = FILM_TONE_FILMIC;
    for (int i = 2; i < argc; i++) {
        if (strcmp(argv[i], "--exposure") == 0) {
            if (cli_parse_positive(i + 1 < argc ? argv[i + 1] : NULL, &exposure) < 0)
                return usage("--exposure needs a positive number");
            i++;
        } else if (strcmp(argv[i], "--tone") == 0) {
            if (i + 1 >= argc || (strcmp(argv[i + 1], "filmic") && strcmp(argv[i + 1], "srgb")))
                return usage("--tone must be filmic or srgb");
            tone = strcmp(argv[++i], "srgb") == 0 ? FILM_TONE_SRGB : FILM_TONE_FILMIC;
        } else if (positional(argv[i], &in, &out) < 0) {
            return usage("--tonemap takes one PFM and one PNG");
        }
    }
    if (!in || !out)
        return usage("--tonemap needs IN.pfm OUT.png");
    film f;
    if (read_pfm_or_say(&f, in) < 0) return 2;
    double used = 0;
    int rc = film_write_png(&f, out, tone, exposure, 1.0, &used);
    film_free(&f);
    if (rc < 0) {
        fprintf(stderr, "render: %s: %s\n", out, render_strerror(rc));
        return 1;
    }
    printf("Wrote %s (%s, exposure %.4g%s)\n", out, tone == FILM_TONE_SRGB ? "sRGB" : "filmic", used,
           exposure > 0 ? "" : ", auto");
    return 0;
}

/* ---- render --dump-scene ----------------------------------------------------------------- */

int scene_dump_main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: render --dump-scene SCENE.json\n");
        return 2;
    }
    cJSON *root;
    json_err e;
    int rc = scene_parse_file(argv[2], &root, &e);
    if (rc == 0) {
        rc = scene_import(&root, argv[2], &e);
        if (rc < 0) cJSON_Delete(root);
    }
    if (rc == 0) { /* load it all, meshes too, so what is printed is what renders */
        scene s;
        rc = scene_from_json(&s, root, &e);
        /* and the mode, which the loader leaves to the integrators' registry (main.c checks
         * it the same way) */
        if (rc == 0 && cli_mode_known(s.settings.mode) == 0) {
            char merr[256];
            integrator none;
            integrator_create(s.settings.mode, &s, &none, merr, sizeof merr); /* says why only */
            rc = json_fail(&e, PM_EINVAL, "$.render.mode: %s", merr);
            scene_free(&s);
        } else if (rc == 0) {
            scene_free(&s);
        }
        if (rc < 0) cJSON_Delete(root);
    }
    if (rc < 0) {
        fprintf(stderr, "render: %s: %s\n", argv[2], e.msg);
        return 2;
    }
    char *text = cJSON_Print(root);
    cJSON_Delete(root);
    if (!text) {
        fprintf(stderr, "render: out of memory\n");
        return 1;
    }
    int bad = puts(text) < 0 || fflush(stdout) != 0;
    free(text);
    return bad ? 1 : 0;
}
