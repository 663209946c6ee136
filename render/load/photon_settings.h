/* photon_settings.h: the settings of photon mapping.
 *
 * photon_settings holds every parameter of photon mapping, read from "$.photon_mapping"
 * with the json.h getters (errors name the JSON path and make `render` exit with status 2). The
 * command line sets the same keys: photon_settings_cli_set() applies `--pm KEY=VALUE`,
 * `--save-photons DIR` and `--load-photons DIR` to the scene's photon_mapping object before
 * the integrator reads it, so a flag and the file can never disagree about names.
 *
 * Keys, types, defaults, ranges and meanings are one table in photon_settings.c; read it
 * with `render --help`, or as the table in data/scenes/README.md, which is
 * `render --help-settings=markdown` verbatim (a test checks they are equal).
 *
 * Plain data; nothing is shared between threads.
 */
#ifndef RENDER_PHOTON_SETTINGS_H
#define RENDER_PHOTON_SETTINGS_H

#include <cjson/cJSON.h>
#include <stddef.h>
#include <stdio.h>

#include "base/json.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Photons are traced in batches of PT_BATCH (photon_trace.h): max_emitted is at least one. */
#define PT_BATCH 4096
/* Budget defaults (photon_trace.h, PASS BUDGETS), sized for a machine of 24 GiB and 2 cores: a
 * pass may use 8 GiB of photon buffers (48 bytes per photon while tracing: 170 M photons, more
 * than the largest target the settings allow), emit 2^32 photons (about an hour on 2 cores for
 * photons that hit something), and follow a photon for 256 bounces (a photon that survives
 * Russian roulette that long carries at most 0.9^256 = 2e-12 of its power in a scene of
 * reflectance 0.9: only a lossless scene reaches it). */
#define PASS_MAX_MEMORY_MB 8192
#define PASS_MAX_EMITTED 4294967296.0
#define PASS_MAX_BOUNCES 256

enum { PLAN_AUTO = -1, PLAN_OFF = 0, PLAN_ON = 1 };
#define PHOTON_SETTINGS_PATH_MAX 512
enum { CAUSTIC_FILTER_NONE, CAUSTIC_FILTER_CONE, CAUSTIC_FILTER_GAUSS, CAUSTIC_FILTER_HULL };

typedef struct photon_settings {
    int force_caustics, force_global, force_shadow, force_final_gather; /* PLAN_* */
    long global_photons, caustic_photons;
    int k_global, k_caustic, k_shadow;
    double max_radius_global, max_radius_caustic; /* 0: automatic */
    int filter;                                   /* CAUSTIC_FILTER_* for the caustic estimate */
    int gather_rays, secondary_rays;
    int split_depth; /* eye-path bounces at which glass sends both a reflected and a refracted ray */
    int caustic_stride; /* caustic estimates at one camera sample in stride x stride */
    int emission_strata; /* m: m x m emission-only camera rays per sample (0: none) */
    double secondary_distance; /* 0: automatic */
    double miss_survival;      /* after a lookup miss, the chance the gather is computed (1: always) */
    double max_emitted_factor;
    double max_emitted; /* pass budgets: photons emitted, MiB of buffers, bounces per photon */
    long max_memory_mb;
    int max_bounces;
    int projection_cells;
    int projection;
    long importance_paths;       /* camera paths of importance-driven emission (0: uniform) */
    double importance_defensive; /* share of global photons emitted uniformly */
    int force_light_guide;       /* PLAN_*: guided light samples in direct light (guide.h) */
    int force_gather_guide;      /* PLAN_*: guided final-gather directions (guide.h) */
    int force_direct_port;       /* PLAN_*: direct light through a photon port (direct.h) */
    int camera_focus;            /* camera samples aimed at ports seen in slivers (run/focus.h) */
    int progress; /* progress bars while tracing (render --quiet sets it false) */
    /* Participating media (volume.h, pm_volume.h). */
    int force_volume, force_volume_caustics; /* PLAN_* */
    long volume_photons, volume_caustic_photons;
    int k_volume, k_volume_caustic;
    double volume_step; /* 0: automatic */
    int volume_boundary; /* volume estimates divide by the part of their ball inside the medium */
    int volume_beam;     /* eye rays read the volume maps by beam estimates (pm_beam.h) */
    int volume_stride;   /* in-scattering in media at one camera sample in stride x stride */
    int force_load; /* load_photons: a stamp mismatch is a warning, not an error */
    double ppm_alpha; /* progressive passes: the radius schedule's alpha (photonmapper.c) */
    double ppm_radius; /* progressive passes: the first radius / the typical radius; 0: the caps */
    double ppm_lookup_shrink; /* progressive passes: the lookup's r^2 shrinks as the estimates' to this power */
    double ppm_photons; /* progressive passes: the fraction of the targets a later pass traces; 0: the plan's */
    /* Directories for save_photons and load_photons; empty: none. */
    char save_dir[PHOTON_SETTINGS_PATH_MAX], load_dir[PHOTON_SETTINGS_PATH_MAX];
} photon_settings;

void photon_settings_defaults(photon_settings *c);
/* Read "$.photon_mapping" (pm may be NULL: defaults). 0 or a negative code with e->msg. */
int photon_settings_parse(photon_settings *c, const cJSON *pm, json_err *e);
const char *caustic_filter_name(int filter);
/* The settings table: markdown = 0 an indented listing for `render --help`, 1 the markdown
 * table of data/scenes/README.md (header row included). */
void photon_settings_print(FILE *f, int markdown);

/* Apply a command-line option to the scene's photon_mapping object (created if NULL):
 * flag "--pm" with value "KEY=VALUE" (VALUE a number, true/false or a string), or
 * "--save-photons"/"--load-photons" with a directory. 0, or PM_EINVAL with a message. */
int photon_settings_cli_set(cJSON **pm, const char *flag, const char *value, char *err, size_t errcap);
/* Check one command-line option as photon_settings_cli_set would apply it (its key, type and range),
 * without a scene: 0, or PM_EINVAL with a message that names the option, not a JSON path
 * ("--pm global_photon: unknown key (did you mean "global_photons"?)"). */
int photon_settings_check_cli(const char *flag, const char *value, char *err, size_t errcap);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PHOTON_SETTINGS_H */
