/* photon_settings.c: the photon-mapping settings: defaults, reading "$.photon_mapping", and
 * the command-line flags that set the same keys; see photon_settings.h.
 */
#include "photon_settings.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"

void photon_settings_defaults(photon_settings *c) {
    memset(c, 0, sizeof *c);
    c->force_caustics = c->force_global = c->force_shadow = c->force_final_gather = PLAN_AUTO;
    c->global_photons = 200000;
    c->caustic_photons = 500000;
    c->k_global = 100;
    c->k_caustic = 60;
    c->k_shadow = 16;
    c->filter = CAUSTIC_FILTER_CONE;
    c->gather_rays = 4;
    c->secondary_rays = 2;
    c->split_depth = 2;
    c->caustic_stride = 2;
    c->emission_strata = 2;
    c->max_emitted_factor = 64;
    c->projection_cells = 64;
    c->projection = 1;
    c->progress = 1;
}

const char *caustic_filter_name(int filter) {
    switch (filter) {
    case CAUSTIC_FILTER_NONE: return "none";
    case CAUSTIC_FILTER_CONE: return "cone";
    case CAUSTIC_FILTER_GAUSS: return "gauss";
    case CAUSTIC_FILTER_HULL: return "hull";
    }
    return "?";
}

static int get_force(const cJSON *pm, const char *key, int *out, json_err *e) {
    if (!json_get(pm, key)) return 0;
    int b = 0;
    int rc = json_bool(pm, "$.photon_mapping", key, 1, &b, e);
    if (rc < 0) return rc;
    *out = b ? PLAN_ON : PLAN_OFF;
    return 0;
}

static int get_long(const cJSON *pm, const char *key, long lo, long hi, long *out, json_err *e) {
    return json_int(pm, "$.photon_mapping", key, 0, lo, hi, out, e);
}

static int get_int(const cJSON *pm, const char *key, long lo, long hi, int *out, json_err *e) {
    long v = *out;
    int rc = json_int(pm, "$.photon_mapping", key, 0, lo, hi, &v, e);
    if (rc == 0) *out = (int)v;
    return rc;
}

static int get_nonneg(const cJSON *pm, const char *key, double *out, json_err *e) {
    int rc = json_number(pm, "$.photon_mapping", key, 0, out, e);
    if (rc < 0) return rc;
    if (*out < 0)
        return json_fail(e, PM_EINVAL, "$.photon_mapping.%s: must be >= 0, got %g", key, *out);
    return 0;
}

static int get_dir(const cJSON *pm, const char *key, char *dst, size_t cap, json_err *e) {
    const char *s = NULL;
    int rc = json_string(pm, "$.photon_mapping", key, 0, &s, e);
    if (rc < 0) return rc;
    if (s) {
        if (strlen(s) >= cap)
            return json_fail(e, PM_EINVAL, "$.photon_mapping.%s: path too long", key);
        snprintf(dst, cap, "%s", s);
    }
    return 0;
}

#define TRY(x)                  \
    do {                        \
        int rc_ = (x);          \
        if (rc_ < 0) return rc_; \
    } while (0)

int photon_settings_parse(photon_settings *c, const cJSON *pm, json_err *e) {
    photon_settings_defaults(c);
    if (!pm) return 0;
    static const char *known[] = {
        "caustics", "global", "shadow", "final_gather", "global_photons", "caustic_photons",
        "k_global", "k_caustic", "k_shadow", "max_radius_global", "max_radius_caustic",
        "filter", "gather_rays", "secondary_rays", "split_depth", "caustic_stride", "emission_strata", "secondary_distance", "max_emitted_factor",
        "projection_cells", "projection", "progress", "save_photons", "load_photons", "comment"};
    for (const cJSON *it = pm->child; it; it = it->next) {
        int ok = 0;
        for (size_t k = 0; k < sizeof known / sizeof *known; k++)
            if (it->string && strcmp(it->string, known[k]) == 0) ok = 1;
        if (!ok)
            return json_fail(e, PM_EINVAL, "$.photon_mapping.%s: unknown key",
                             it->string ? it->string : "?");
    }
    TRY(get_force(pm, "caustics", &c->force_caustics, e));
    TRY(get_force(pm, "global", &c->force_global, e));
    TRY(get_force(pm, "shadow", &c->force_shadow, e));
    TRY(get_force(pm, "final_gather", &c->force_final_gather, e));
    TRY(get_long(pm, "global_photons", 0, 100000000L, &c->global_photons, e));
    TRY(get_long(pm, "caustic_photons", 0, 100000000L, &c->caustic_photons, e));
    TRY(get_int(pm, "k_global", 1, 10000, &c->k_global, e));
    TRY(get_int(pm, "k_caustic", 1, 10000, &c->k_caustic, e));
    TRY(get_int(pm, "k_shadow", 1, 1000, &c->k_shadow, e));
    TRY(get_nonneg(pm, "max_radius_global", &c->max_radius_global, e));
    TRY(get_nonneg(pm, "max_radius_caustic", &c->max_radius_caustic, e));
    TRY(get_int(pm, "gather_rays", 0, 100000, &c->gather_rays, e));
    TRY(get_int(pm, "secondary_rays", 0, 100000, &c->secondary_rays, e));
    TRY(get_int(pm, "split_depth", 0, 16, &c->split_depth, e));
    TRY(get_int(pm, "caustic_stride", 1, 64, &c->caustic_stride, e));
    TRY(get_int(pm, "emission_strata", 0, 16, &c->emission_strata, e));
    TRY(get_nonneg(pm, "secondary_distance", &c->secondary_distance, e));
    TRY(get_nonneg(pm, "max_emitted_factor", &c->max_emitted_factor, e));
    if (c->max_emitted_factor < 1)
        return json_fail(e, PM_EINVAL, "$.photon_mapping.max_emitted_factor: must be >= 1, got %g",
                         c->max_emitted_factor);
    TRY(get_int(pm, "projection_cells", 1, 4096, &c->projection_cells, e));
    TRY(json_bool(pm, "$.photon_mapping", "projection", 0, &c->projection, e));
    TRY(json_bool(pm, "$.photon_mapping", "progress", 0, &c->progress, e));
    const char *f = NULL;
    TRY(json_string(pm, "$.photon_mapping", "filter", 0, &f, e));
    if (f) {
        if (strcmp(f, "none") == 0 || strcmp(f, "disc") == 0)
            c->filter = CAUSTIC_FILTER_NONE;
        else if (strcmp(f, "cone") == 0)
            c->filter = CAUSTIC_FILTER_CONE;
        else if (strcmp(f, "gauss") == 0 || strcmp(f, "gaussian") == 0)
            c->filter = CAUSTIC_FILTER_GAUSS;
        else if (strcmp(f, "hull") == 0 || strcmp(f, "convex_hull") == 0)
            c->filter = CAUSTIC_FILTER_HULL;
        else
            return json_fail(e, PM_EINVAL,
                             "$.photon_mapping.filter: expected \"none\", \"cone\", \"gauss\" or "
                             "\"hull\", got \"%s\"",
                             f);
    }
    TRY(get_dir(pm, "save_photons", c->save_dir, sizeof c->save_dir, e));
    TRY(get_dir(pm, "load_photons", c->load_dir, sizeof c->load_dir, e));
    return 0;
}

int plan_cli_set(cJSON **pm, const char *flag, const char *value, char *err, size_t errcap) {
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
    int is_path = strcmp(key, "save_photons") == 0 || strcmp(key, "load_photons") == 0 ||
                  strcmp(key, "filter") == 0;
    if (!is_path && strcmp(val, "true") == 0)
        item = cJSON_CreateBool(1);
    else if (!is_path && strcmp(val, "false") == 0)
        item = cJSON_CreateBool(0);
    else if (!is_path && *val && !*end && !errno)
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
