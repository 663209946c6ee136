/* photon_settings.c: the photon-mapping settings; see photon_settings.h.
 *
 * One table, k_settings, holds every key: its type, the field it fills, its default, its
 * range and its help. The defaults, the parsing of "$.photon_mapping", the known-keys check,
 * the typing of `--pm KEY=VALUE`, `render --help` and the table in data/scenes/README.md
 * (`render --help-settings=markdown`) all read it, so a key, a default or a range is written
 * once. Numbers are kept as doubles in the table; every integer default and bound is exact
 * in a double.
 */
#include "load/photon_settings.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"

typedef enum {
    ST_FORCE,  /* true/false, absent = automatic (PLAN_*), an int field */
    ST_BOOL,   /* true/false, an int field */
    ST_INT,    /* a whole number in [lo, hi], an int field */
    ST_LONG,   /* a whole number in [lo, hi], a long field */
    ST_NUMBER, /* a finite number in [lo, hi], a double field */
    ST_FILTER, /* a caustic filter name, an int field (CAUSTIC_FILTER_*) */
    ST_DIR,    /* a directory (string), a char[PHOTON_SETTINGS_PATH_MAX] field */
    ST_TEXT    /* anything; ignored (comments) */
} setting_type;

typedef struct setting_def {
    const char *key;
    setting_type type;
    size_t offset; /* of the field in photon_settings */
    double def, lo, hi;
    const char *help;
} setting_def;

#define F(field) offsetof(photon_settings, field)
#define NONE 0, 0 /* lo, hi: no range */

/* Rows of one table, alike by design (key, type, field, default, range, help): each row is a
 * setting, not repeated logic. */
static const setting_def k_settings[] = {
    {"caustics", ST_FORCE, F(force_caustics), PLAN_AUTO, 0, 0,
     "build the caustic map or not; absent, the plan decides from the scene and prints why"},
    {"global", ST_FORCE, F(force_global), PLAN_AUTO, 0, 0,
     "build the global map or not (absent: the plan decides)"},
    {"shadow", ST_FORCE, F(force_shadow), PLAN_AUTO, 0, 0,
     "store shadow photons or not (absent: the plan decides)"},
    {"final_gather", ST_FORCE, F(force_final_gather), PLAN_AUTO, 0, 0,
     "final gathering or the global map shown directly (absent: the plan decides)"},
    {"global_photons", ST_LONG, F(global_photons), 200000, 0, 100000000,
     "photons to store in the global map"},
    {"caustic_photons", ST_LONG, F(caustic_photons), 500000, 0, 100000000,
     "photons to store in the caustic map"},
    {"k_global", ST_INT, F(k_global), 100, 1, 10000,
     "photons per precomputed-irradiance estimate (and per preview estimate)"},
    {"k_caustic", ST_INT, F(k_caustic), 60, 1, 10000, "photons per caustic estimate"},
    {"k_shadow", ST_INT, F(k_shadow), 16, 1, 1000, "photons per shadow-map query"},
    {"max_radius_global", ST_NUMBER, F(max_radius_global), 0, 0, INFINITY,
     "largest search radius of a global-map estimate, in scene units; 0: Christensen's radius "
     "for a threshold radiance of 0.5% of the mean"},
    {"max_radius_caustic", ST_NUMBER, F(max_radius_caustic), 0, 0, INFINITY,
     "the same for the caustic map"},
    {"filter", ST_FILTER, F(filter), CAUSTIC_FILTER_CONE, NONE,
     "filter of the caustic estimate: none (a disc), cone, gauss or hull (convex hull)"},
    {"gather_rays", ST_INT, F(gather_rays), 4, 0, 100000,
     "final-gather rays per camera sample at a diffuse surface (scaled by the path's "
     "throughput after glass, at least 1); absent, the plan's sample pilot picks 1, 2 or 4 (with "
     "secondary_rays 1, 1 or 2) by variance x cost and prints it (\"sample:\"); the default "
     "here is used where no pilot runs"},
    {"secondary_rays", ST_INT, F(secondary_rays), 2, 0, 100000,
     "rays of a secondary gather, made where a gather ray hits a surface closer than "
     "secondary_distance; absent, the sample pilot picks it with gather_rays"},
    {"secondary_distance", ST_NUMBER, F(secondary_distance), 0, 0, INFINITY,
     "0: the radius of a k_global estimate at the global map's mean density"},
    {"miss_survival", ST_NUMBER, F(miss_survival), 1, 0.01, 1,
     "where a gather ray's irradiance lookup finds nothing on its side (a photon-starved or "
     "dark region), the chance that the light there is computed rather than taken as 0 (Russian "
     "roulette, weighted by its inverse: no bias); absent, the sample pilot picks 1, 1/2 or 1/4 by "
     "variance x cost when a quarter or more of its lookups find nothing (\"sample:\")"},
    {"split_depth", ST_INT, F(split_depth), 2, 0, 16,
     "camera-path bounces at which glass traces both its reflected and its refracted ray "
     "(weighted) instead of choosing one"},
    {"caustic_stride", ST_INT, F(caustic_stride), 2, 1, 64,
     "the caustic map is read at one camera sample in c x c strata (a stratified subset, "
     "the same count in every pixel, weighted to sum to the pixel's samples; 1: at every "
     "sample); absent, the sample pilot picks it, 1 to 4, dividing the strata (\"sample:\")"},
    {"emission_strata", ST_INT, F(emission_strata), 4, 0, 16,
     "emission seen by the camera (directly or through mirrors and glass) comes from m x m "
     "extra emission-only rays per sample, at the pixels where probe rays see an emitter (the "
     "plan's \"emission rays:\" line); elsewhere, and with 0, from the sample's own path"},
    {"max_emitted_factor", ST_NUMBER, F(max_emitted_factor), 64, 1, 1e9,
     "a photon pass gives up, with a message, after emitting this many times its target "
     "without storing it"},
    {"max_emitted", ST_NUMBER, F(max_emitted), PASS_MAX_EMITTED, PT_BATCH, 1e15,
     "a photon pass also stops after emitting this many photons (a pass budget, photon_trace.h)"},
    {"max_memory_mb", ST_LONG, F(max_memory_mb), PASS_MAX_MEMORY_MB, 16, 1L << 30,
     "MiB of photon buffers a pass may hold (a pass budget)"},
    {"max_bounces", ST_INT, F(max_bounces), PASS_MAX_BOUNCES, 1, 1000000,
     "bounces per photon (a pass budget, below render.max_depth)"},
    {"projection", ST_BOOL, F(projection), 1, NONE,
     "aim caustic photons at specular objects through a projection map"},
    {"projection_cells", ST_INT, F(projection_cells), 64, 1, 4096,
     "cells per side of a light's projection map"},
    {"importance_paths", ST_LONG, F(importance_paths), 16384, 0, 100000000,
     "camera paths that find which emissions of the lights reach what the camera sees "
     "(importance.h); the global pass emits toward them, each photon's power divided "
     "accordingly, when they cover at least 10% of the lights' power (the plan prints the "
     "decision); 0: emission by power alone"},
    {"importance_defensive", ST_NUMBER, F(importance_defensive), 0.2, 0.01, 1,
     "share of the global photons emitted by power alone, the rest by importance: every "
     "emission keeps a chance, so the map stays unbiased and a photon carries at most 1/share "
     "of the uniform power"},
    {"light_guide", ST_FORCE, F(force_light_guide), PLAN_AUTO, 0, 0,
     "guide the direct light's samples toward the part of each area light that a pilot saw "
     "pass (guide.h; unbiased for any table) or not; absent, the plan turns it on where light "
     "samples are mostly blocked where the camera looks (light through an opening)"},
    {"gather_guide", ST_FORCE, F(force_gather_guide), PLAN_AUTO, 0, 0,
     "guide the final gather's directions toward what a pilot's probes saw bright (light "
     "through an opening; guide.h, unbiased for any table) or not; absent, the photon mapper "
     "turns it on where the probes find most of the gathered light in a small part of the "
     "hemisphere"},
    {"direct_port", ST_FORCE, F(force_direct_port), PLAN_AUTO, 0, 0,
     "join each direct-light sample at points on a photon port's dark side by a ray through "
     "the port (direct.h, THROUGH A PORT; unbiased by the balance heuristic) or not; absent, "
     "the plan turns it on where a port is used, the scene has no media, the lights' power "
     "is on one side of the port and area or sphere lights carry at least half of it (true "
     "drops the last condition only)"},
    {"camera_focus", ST_BOOL, F(camera_focus), 1, NONE,
     "where the camera sees a photon port in a sliver of a pixel (at most half of it), aim half "
     "of that pixel's samples at the port's footprint, weighted (run/focus.h; unbiased for any "
     "port); false: every sample uniform over its pixel"},
    {"progress", ST_BOOL, F(progress), 1, NONE,
     "progress lines while tracing photons (render --quiet sets it false)"},
    {"volume", ST_FORCE, F(force_volume), PLAN_AUTO, 0, 0,
     "build the volume photon map of a scene with media or not (absent: the plan decides)"},
    {"volume_caustics", ST_FORCE, F(force_volume_caustics), PLAN_AUTO, 0, 0,
     "build the volume caustic map (light sent into a medium by specular surfaces) or not "
     "(absent: the plan decides)"},
    {"volume_photons", ST_LONG, F(volume_photons), 100000, 0, 100000000,
     "photons to store in the volume map (scattering events in media)"},
    {"volume_caustic_photons", ST_LONG, F(volume_caustic_photons), 100000, 0, 100000000,
     "photons to store in the volume caustic map (first scattering events after specular "
     "surfaces only)"},
    {"k_volume", ST_INT, F(k_volume), 50, 1, 10000,
     "photons per volume radiance estimate (multiple scattering)"},
    {"k_volume_caustic", ST_INT, F(k_volume_caustic), 30, 1, 10000,
     "photons per volume caustic estimate"},
    {"volume_step", ST_NUMBER, F(volume_step), 0, 0, INFINITY,
     "ray-marching step in media, in scene units; 0: a quarter of the mean free path, at most "
     "1/64 of the scene's diagonal"},
    {"volume_boundary", ST_BOOL, F(volume_boundary), 1, NONE,
     "volume estimates near a medium's boundary divide by the part of their search ball inside "
     "the medium (pm_volume.h, BOUNDARIES); false: by the whole ball"},
    {"volume_beam", ST_BOOL, F(volume_beam), 1, NONE,
     "eye rays read the volume maps by beam estimates, one per segment (pm_beam.h); false: a "
     "k-nearest estimate at every ray-marching step"},
    {"volume_stride", ST_INT, F(volume_stride), 1, 1, 64,
     "in-scattering in media (the march and the beam estimates) at one camera sample per "
     "stride x stride block of strata, as caustic_stride does for the caustic map; absent, in a "
     "scene with media the sample pilot picks it, 1 to 4 (\"sample:\")"},
    {"ppm_alpha", ST_NUMBER, F(ppm_alpha), 2.0 / 3.0, 0.01, 1,
     "progressive photon mapping (a photon mode rendered in passes, render --time or "
     "--passes): pass i+1's squared radii are pass i's times (i + alpha) / (i + 1), i = 1, 2, "
     "... (Knaus and Zwicker 2011); 1: the radii do not shrink"},
    {"ppm_radius", ST_NUMBER, F(ppm_radius), 2, 0, 1000,
     "progressive photon mapping: the first pass's radius of the global and caustic estimates, "
     "in units of a k-photon estimate's radius at the map's mean density over the diffuse "
     "area (at most the maximum radius), so that the passes' shrinking radii bind (README.md, "
     "Progressive photon mapping); 0: the maximum radii of max_radius_global/_caustic"},
    {"ppm_lookup_shrink", ST_NUMBER, F(ppm_lookup_shrink), 3, 1, 10,
     "progressive photon mapping: the precomputed-irradiance lookup's squared radius shrinks "
     "as the estimates' squared radii to this power (pass p: pass 0's times the schedule's "
     "factor to this power; 3 at the default alpha: about 1 / p), so the lookups' bias falls "
     "faster than the estimates' and a lookup that finds no point computes its light instead "
     "(README.md, Progressive photon mapping); 1: as the estimates"},
    {"ppm_photons", ST_NUMBER, F(ppm_photons), 0, 0, 1,
     "progressive photon mapping: the fraction of the photon targets (global, caustic, volume) "
     "each pass after the first traces; 0: chosen from counted work so that a pass's photons "
     "cost about 0.15 of its camera samples (README.md, Progressive photon mapping)"},
    {"save_photons", ST_DIR, F(save_dir), 0, NONE,
     "a directory to save the maps to (global.pmap, caustic.pmap, shadow.pmap, and in a scene "
     "with media volume-M.pmap and volume_caustic-M.pmap for each medium M; the format of "
     "photonmap/mapfile.h), as traced"},
    {"load_photons", ST_DIR, F(load_dir), 0, NONE,
     "a directory to load the maps from instead of tracing them; maps of another scene or "
     "traced with other settings, a missing, corrupt or wrong-kind map file are refused"},
    {"force_load_photons", ST_BOOL, F(force_load), 0, NONE,
     "use the maps of load_photons even when their headers say another scene or other "
     "settings traced them (a warning per file; render --force-load-photons sets it)"},
    {"comment", ST_TEXT, 0, 0, NONE, "ignored"},
};
#define NSETTINGS (sizeof k_settings / sizeof k_settings[0])

static const char *const k_filter_names[] = {"none", "cone", "gauss", "hull"};

static const setting_def *find(const char *key) {
    for (size_t k = 0; key && k < NSETTINGS; k++)
        if (strcmp(k_settings[k].key, key) == 0) return &k_settings[k];
    return NULL;
}

void photon_settings_defaults(photon_settings *c) {
    memset(c, 0, sizeof *c);
    for (size_t k = 0; k < NSETTINGS; k++) {
        const setting_def *d = &k_settings[k];
        void *field = (char *)c + d->offset;
        switch (d->type) {
        case ST_FORCE:
        case ST_BOOL:
        case ST_INT:
        case ST_FILTER: *(int *)field = (int)d->def; break;
        case ST_LONG: *(long *)field = (long)d->def; break;
        case ST_NUMBER: *(double *)field = d->def; break;
        case ST_DIR:
        case ST_TEXT: break; /* empty */
        }
    }
}

const char *caustic_filter_name(int filter) {
    return filter >= 0 && filter < 4 ? k_filter_names[filter] : "?";
}

#define P "$.photon_mapping"

static int parse_one(photon_settings *c, const setting_def *d, const cJSON *pm, json_err *e) {
    void *field = (char *)c + d->offset;
    int rc = 0;
    switch (d->type) {
    case ST_FORCE: {
        int b = 0;
        if ((rc = json_bool(pm, P, d->key, 1, &b, e)) == 0) *(int *)field = b ? PLAN_ON : PLAN_OFF;
        break;
    }
    case ST_BOOL: rc = json_bool(pm, P, d->key, 1, (int *)field, e); break;
    case ST_INT:
    case ST_LONG: {
        long v = 0;
        rc = json_int(pm, P, d->key, 1, (long)d->lo, (long)d->hi, &v, e);
        if (rc == 0 && d->type == ST_INT) *(int *)field = (int)v;
        if (rc == 0 && d->type == ST_LONG) *(long *)field = v;
        break;
    }
    case ST_NUMBER: {
        double v = 0;
        if ((rc = json_number(pm, P, d->key, 1, &v, e)) < 0) break;
        if (!(v >= d->lo && v <= d->hi)) {
            if (isinf(d->hi))
                return json_fail(e, PM_EINVAL, P ".%s: must be >= %g, got %g", d->key, d->lo, v);
            return json_fail(e, PM_EINVAL, P ".%s: must be in [%g, %g], got %g", d->key, d->lo,
                             d->hi, v);
        }
        *(double *)field = v;
        break;
    }
    case ST_FILTER: {
        const char *f = NULL;
        if ((rc = json_string(pm, P, d->key, 1, &f, e)) < 0) break;
        /* The names the estimators go by elsewhere are accepted too. */
        static const char *const alias[] = {"disc", NULL, "gaussian", "convex_hull"};
        for (int k = 0; k < 4; k++)
            if (strcmp(f, k_filter_names[k]) == 0 || (alias[k] && strcmp(f, alias[k]) == 0)) {
                *(int *)field = k;
                return 0;
            }
        return json_fail(e, PM_EINVAL,
                         P ".%s: expected \"none\", \"cone\", \"gauss\" or \"hull\", got \"%s\"",
                         d->key, f);
    }
    case ST_DIR: {
        const char *s = NULL;
        if ((rc = json_string(pm, P, d->key, 1, &s, e)) < 0) break;
        if (!s[0]) /* was read as "no directory": the maps were traced (or not saved) silently */
            return json_fail(e, PM_EINVAL, P ".%s: an empty directory name (leave the key out for "
                             "none)", d->key);
        if (strlen(s) >= PHOTON_SETTINGS_PATH_MAX)
            return json_fail(e, PM_EINVAL, P ".%s: path too long", d->key);
        snprintf((char *)field, PHOTON_SETTINGS_PATH_MAX, "%s", s);
        break;
    }
    case ST_TEXT: break;
    }
    return rc;
}

int photon_settings_parse(photon_settings *c, const cJSON *pm, json_err *e) {
    photon_settings_defaults(c);
    if (!pm) return 0;
    for (const cJSON *it = pm->child; it; it = it->next)
        if (!find(it->string)) {
            /* render-mpi's one setting of its own, taken from its command line before render's
             * code sees it (render/mpi/render_mpi.c): anywhere else, say whose it is. */
            if (it->string && strcmp(it->string, "distributed") == 0)
                return json_fail(e, PM_EINVAL, P ".distributed: a setting of render-mpi, the "
                                 "distributed renderer, given only on its command line (mpirun -np N "
                                 "render-mpi SCENE.json --pm distributed=replicated or partitioned); "
                                 "render renders in one process and has no such setting");
            const char *names[NSETTINGS];
            for (size_t k = 0; k < NSETTINGS; k++) names[k] = k_settings[k].key;
            const char *near = json_nearest_key(it->string, names, NSETTINGS);
            return json_fail(e, PM_EINVAL, P ".%s: unknown key%s%s%s", it->string ? it->string : "?",
                             near ? " (did you mean \"" : "", near ? near : "",
                             near ? "\"?)" : " (render --help-settings lists the keys)");
        }
    /* In table order, so that of several bad keys the same one is always reported. */
    for (size_t k = 0; k < NSETTINGS; k++)
        if (json_get(pm, k_settings[k].key)) {
            int rc = parse_one(c, &k_settings[k], pm, e);
            if (rc < 0) return rc;
        }
    return 0;
}

/* ---- documentation ------------------------------------------------------------------------- */

static const char *type_name(setting_type t) {
    switch (t) {
    case ST_FORCE: return "true/false";
    case ST_BOOL: return "true/false";
    case ST_INT:
    case ST_LONG: return "integer";
    case ST_NUMBER: return "number";
    case ST_FILTER: return "string";
    case ST_DIR: return "directory";
    case ST_TEXT: return "any";
    }
    return "?";
}

/* v in the fewest significant digits (15 to 17) that read back as v exactly, so a documented
 * default such as 2/3 written into a scene gives the default itself. */
static void exact_text(double v, char *buf, size_t cap) {
    for (int digits = 15; digits <= 17; digits++) {
        snprintf(buf, cap, "%.*g", digits, v);
        if (strtod(buf, NULL) == v) return;
    }
}

static void default_text(const setting_def *d, char *buf, size_t cap) {
    switch (d->type) {
    case ST_FORCE: snprintf(buf, cap, "automatic"); break;
    case ST_BOOL: snprintf(buf, cap, "%s", d->def != 0 ? "true" : "false"); break;
    case ST_INT:
    case ST_LONG:
    case ST_NUMBER: exact_text(d->def, buf, cap); break;
    case ST_FILTER: snprintf(buf, cap, "\"%s\"", caustic_filter_name((int)d->def)); break;
    case ST_DIR:
    case ST_TEXT: snprintf(buf, cap, "none"); break;
    }
}

static void range_text(const setting_def *d, char *buf, size_t cap) {
    switch (d->type) {
    case ST_INT:
    case ST_LONG:
    case ST_NUMBER:
        if (isinf(d->hi))
            snprintf(buf, cap, ">= %.15g", d->lo);
        else
            snprintf(buf, cap, "%.15g to %.15g", d->lo, d->hi);
        break;
    case ST_FILTER: snprintf(buf, cap, "none, cone, gauss, hull"); break;
    default: snprintf(buf, cap, "-"); break;
    }
}

/* text in lines of at most `width` columns, each indented by `indent` spaces. */
static void print_wrapped(FILE *f, const char *text, int indent, int width) {
    const char *s = text;
    while (*s) {
        int room = width - indent, n = (int)strlen(s);
        if (n > room) {
            n = room;
            while (n > 0 && s[n] != ' ') n--;
            if (n == 0) n = room; /* one word longer than a line */
        }
        fprintf(f, "%*s%.*s\n", indent, "", n, s);
        s += n;
        while (*s == ' ') s++;
    }
}

void photon_settings_print(FILE *f, int markdown) {
    char def[64], range[64];
    if (markdown) fprintf(f, "| key | type | default | range | meaning |\n|---|---|---|---|---|\n");
    for (size_t k = 0; k < NSETTINGS; k++) {
        const setting_def *d = &k_settings[k];
        default_text(d, def, sizeof def);
        range_text(d, range, sizeof range);
        if (markdown)
            fprintf(f, "| `%s` | %s | %s | %s | %s |\n", d->key, type_name(d->type), def, range,
                    d->help);
        else {
            fprintf(f, "  %-20s %s, default %s%s%s\n", d->key, type_name(d->type), def,
                    strcmp(range, "-") ? ", " : "", strcmp(range, "-") ? range : "");
            print_wrapped(f, d->help, 23, 80);
        }
    }
}

/* ---- command line ------------------------------------------------------------------------ */

int photon_settings_cli_set(cJSON **pm, const char *flag, const char *value, char *err, size_t errcap) {
    char key[64];
    const char *val;
    if (strcmp(flag, "--save-photons") == 0 || strcmp(flag, "--load-photons") == 0) {
        snprintf(key, sizeof key, "%s", flag[2] == 's' ? "save_photons" : "load_photons");
        val = value;
    } else {
        const char *eq = strchr(value, '=');
        if (!eq || eq == value || (size_t)(eq - value) >= sizeof key) {
            snprintf(err, errcap, "%s: expected KEY=VALUE, got '%s'", flag, value);
            return PM_EINVAL;
        }
        memcpy(key, value, (size_t)(eq - value));
        key[eq - value] = 0;
        val = eq + 1;
    }
    if (!*pm) *pm = cJSON_CreateObject();
    if (!*pm) {
        snprintf(err, errcap, "out of memory");
        return PM_ENOMEM;
    }
    cJSON *item;
    char *end;
    errno = 0;
    double num = strtod(val, &end);
    /* The table says which keys take text; any other value is typed as JSON would type it
     * (an unknown key is reported, with its path, when the settings are read). */
    const setting_def *d = find(key);
    int is_text = d && (d->type == ST_DIR || d->type == ST_FILTER || d->type == ST_TEXT);
    if (!is_text && strcmp(val, "true") == 0)
        item = cJSON_CreateBool(1);
    else if (!is_text && strcmp(val, "false") == 0)
        item = cJSON_CreateBool(0);
    else if (!is_text && *val && !*end && !errno)
        item = cJSON_CreateNumber(num);
    else
        item = cJSON_CreateString(val);
    if (!item) {
        snprintf(err, errcap, "out of memory");
        return PM_ENOMEM;
    }
    cJSON_DeleteItemFromObjectCaseSensitive(*pm, key);
    cJSON_AddItemToObject(*pm, key, item);
    return 0;
}

int photon_settings_check_cli(const char *flag, const char *value, char *err, size_t errcap) {
    cJSON *one = NULL;
    int rc = photon_settings_cli_set(&one, flag, value, err, errcap);
    if (rc == 0) {
        photon_settings c;
        json_err e;
        rc = photon_settings_parse(&c, one, &e);
        if (rc < 0) {
            /* e.msg starts with "$.photon_mapping.KEY"; the user typed "--pm KEY=..." or
             * "--save-photons DIR", so say that instead. */
            const char *m = e.msg, *key = one && one->child ? one->child->string : "";
            size_t lp = strlen(P "."), lk = strlen(key);
            int is_pm = strcmp(flag, "--pm") == 0;
            if (strncmp(m, P ".", lp) == 0 && strncmp(m + lp, key, lk) == 0)
                snprintf(err, errcap, "%s%s%s%s", flag, is_pm ? " " : "", is_pm ? key : "", m + lp + lk);
            else
                snprintf(err, errcap, "%s %s: %s", flag, value, m);
        }
    }
    cJSON_Delete(one);
    return rc;
}
