/* scene_lights.c: the spot and infinite lights of a JSON scene ($.lights[i] of type "spot" or
 * "infinite", format in data/scenes/README.md), every field checked; scene_load.c reads the
 * point and directional ones and hands the other types here. An infinite light's image
 * ("map") is a PFM file, read here (the image/ stage comes later than load/), or an OpenEXR
 * file (a name ending in .exr, read by base/exr_read.h), and every pixel checked: finite and
 * not negative.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "base/exr_read.h"
#include "load/scene_load_internal.h"
#include "photonmap/common.h"
#include "scene/envmap.h"

/* The PFM at path ("PF", w h, scale (< 0: little-endian), rows bottom to top) into *px (3 w h
 * floats, row 0 at the top, the caller's). */
static int read_pfm(const char *path, const char *P, int *w, int *h, float **px, json_err *e) {
    FILE *f = fopen(path, "rb");
    if (!f) return json_fail(e, PM_EIO, "%s.map: cannot open \"%s\"", P, path);
    char magic[3] = {0};
    double scale;
    if (fscanf(f, "%2s %d %d %lf", magic, w, h, &scale) != 4 || strcmp(magic, "PF") != 0 || *w <= 0 || *h <= 0 ||
        *w > (1 << 15) || *h > (1 << 15) || !(scale != 0) || fgetc(f) == EOF) {
        fclose(f);
        return json_fail(e, PM_EFORMAT, "%s.map: \"%s\" is not a colour PFM (\"PF\", width and height in 1 to "
                         "32768, a non-zero scale)", P, path);
    }
    size_t n = 3 * (size_t)*w * (size_t)*h;
    unsigned char *b = malloc(4 * n);
    *px = malloc(n * sizeof **px);
    if (!b || !*px) {
        free(b), free(*px), fclose(f);
        return json_fail(e, PM_ENOMEM, "out of memory");
    }
    size_t got = fread(b, 4, n, f);
    fclose(f);
    for (size_t i = 0; i < n && got == n; i++) {
        unsigned char *q = &b[4 * i];
        uint32_t u = scale < 0 ? (uint32_t)q[0] | (uint32_t)q[1] << 8 | (uint32_t)q[2] << 16 | (uint32_t)q[3] << 24
                               : (uint32_t)q[3] | (uint32_t)q[2] << 8 | (uint32_t)q[1] << 16 | (uint32_t)q[0] << 24;
        float v;
        memcpy(&v, &u, sizeof v);
        size_t pxi = i / 3, row = pxi / (size_t)*w, col = pxi % (size_t)*w;
        if (!isfinite(v) || v < 0) {
            free(b), free(*px);
            return json_fail(e, PM_EINVAL, "%s.map: \"%s\": pixel (%zu, %zu) from the top has %g: radiances must be "
                             "finite and not negative", P, path, col, (size_t)*h - 1 - row, (double)v);
        }
        (*px)[3 * (((size_t)*h - 1 - row) * (size_t)*w + col) + i % 3] = v;
    }
    free(b);
    if (got != n) {
        free(*px);
        return json_fail(e, PM_EFORMAT, "%s.map: \"%s\" is truncated (%zu of %zu values)", P, path, got, n);
    }
    return 0;
}

/* The EXR at path into *px (as read_pfm), with read_pfm's limits and checks. */
static int read_exr(const char *path, const char *P, int *w, int *h, float **px, json_err *e) {
    char msg[400];
    int rc = exr_read_rgb(path, w, h, px, msg, sizeof msg);
    if (rc < 0) return json_fail(e, rc, "%s.map: %s", P, msg);
    if (*w > (1 << 15) || *h > (1 << 15)) {
        free(*px);
        return json_fail(e, PM_EFORMAT, "%s.map: \"%s\" is %d x %d (width and height in 1 to 32768)", P, path, *w, *h);
    }
    for (size_t i = 0; i < 3 * (size_t)*w * (size_t)*h; i++)
        if (!isfinite((*px)[i]) || (*px)[i] < 0) {
            double v = (double)(*px)[i];
            free(*px);
            return json_fail(e, PM_EINVAL, "%s.map: \"%s\": pixel (%zu, %zu) from the top has %g: radiances must be "
                             "finite and not negative", P, path, i / 3 % (size_t)*w, i / 3 / (size_t)*w, v);
        }
    return 0;
}

/* "map_frame": 9 numbers, row-major, a rotation (or a reflection) from world directions to the
 * map's (envmap.h); absent: the map's z up along world y (rows [1 0 0], [0 0 -1], [0 1 0]). */
static int map_frame(const cJSON *o, const char *P, double F[3][3], json_err *e) {
    static const double def[3][3] = {{1, 0, 0}, {0, 0, -1}, {0, 1, 0}};
    memcpy(F, def, sizeof def);
    const cJSON *a = json_get(o, "map_frame");
    if (!a) return 0;
    if (!cJSON_IsArray(a) || cJSON_GetArraySize(a) != 9)
        return json_fail(e, PM_EINVAL, "%s.map_frame: expected 9 numbers (a 3 x 3 rotation, row-major)", P);
    int k = 0;
    for (const cJSON *it = a->child; it; it = it->next, k++) {
        if (!cJSON_IsNumber(it) || !isfinite(it->valuedouble))
            return json_fail(e, PM_EINVAL, "%s.map_frame[%d]: expected a finite number", P, k);
        F[k / 3][k % 3] = it->valuedouble;
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            double d = F[i][0] * F[j][0] + F[i][1] * F[j][1] + F[i][2] * F[j][2];
            if (fabs(d - (i == j)) > 1e-6)
                return json_fail(e, PM_EINVAL, "%s.map_frame: not a rotation (its rows must be orthonormal: rows %d "
                                 "and %d have the dot product %g)", P, i, j, d);
        }
    return 0;
}

static int spot(light *l, const cJSON *o, const char *P, json_err *e) {
    KEYS(o, P, "a spot light", "type", "position", "direction", "intensity", "cone_angle", "cone_delta",
         "falloff");
    l->type = LIGHT_SPOT;
    TRY(json_vec3(o, P, "position", 1, &l->pos, e));
    TRY(sl_check_point(l->pos, P, "position", e));
    TRY(json_vec3(o, P, "direction", 1, &l->dir, e));
    if (!(v3_len(l->dir) > 0) || !isfinite(v3_len(l->dir)))
        return json_fail(e, PM_EINVAL, "%s.direction: must be a finite vector other than zero (the spot's axis)", P);
    l->dir = v3_norm(l->dir);
    TRY(json_rgb(o, P, "intensity", 1, &l->intensity, e));
    TRY(sl_check_nonneg_rgb(l->intensity, P, "intensity", e));
    double cone = 30, delta = 5; /* pbrt's defaults, degrees */
    TRY(json_number(o, P, "cone_angle", 0, &cone, e));
    if (!(cone > 0 && cone <= 180))
        return json_fail(e, PM_EINVAL, "%s.cone_angle: %g is outside (0, 180] (degrees from the axis to "
                         "the edge of the cone)", P, cone);
    TRY(json_number(o, P, "cone_delta", 0, &delta, e));
    if (!(delta >= 0 && delta <= cone))
        return json_fail(e, PM_EINVAL, "%s.cone_delta: %g is outside [0, cone_angle = %g] (degrees over "
                         "which the light falls off inside the cone's edge)", P, delta, cone);
    l->cos_total = cos(cone * M_PI / 180);
    l->cos_start = cos((cone - delta) * M_PI / 180);
    const char *f = "smoothstep";
    TRY(json_string(o, P, "falloff", 0, &f, e));
    if (strcmp(f, "smoothstep") == 0) l->falloff = SPOT_SMOOTHSTEP;
    else if (strcmp(f, "quartic") == 0) l->falloff = SPOT_QUARTIC;
    else
        return json_fail(e, PM_EINVAL, "%s.falloff: unknown falloff \"%s\" (smoothstep: pbrt-v4's; "
                         "quartic: pbrt-v3's)", P, f);
    return 0;
}

static int infinite(scene *s, light *l, const cJSON *o, const char *P, json_err *e) {
    KEYS(o, P, "an infinite light", "type", "radiance", "map", "map_frame");
    l->type = LIGHT_INFINITE;
    const char *map = NULL;
    TRY(json_string(o, P, "map", 0, &map, e));
    l->Le = v3s(1);
    TRY(json_rgb(o, P, "radiance", !map, &l->Le, e));
    TRY(sl_check_nonneg_rgb(l->Le, P, "radiance", e));
    if (v3_maxabs(l->Le) > SCENE_RADIANCE_MAX)
        return json_fail(e, PM_EINVAL, "%s.radiance: %g is outside the supported range, 0 to %g (the "
                         "image is stored in 32-bit floats)", P, v3_maxabs(l->Le), SCENE_RADIANCE_MAX);
    for (int i = 0; i < s->nlights; i++)
        if (s->lights[i].type == LIGHT_INFINITE)
            return json_fail(e, PM_EINVAL, "%s: a second infinite light ($.lights[%d] is one): give one, "
                             "with the radiances added", P, i);
    if (!map) {
        if (json_get(o, "map_frame")) return json_fail(e, PM_EINVAL, "%s.map_frame: only with a map", P);
        return 0;
    }
    double F[3][3];
    int w, h;
    float *px = NULL;
    TRY(map_frame(o, P, F, e));
    TRY(exr_has_ext(map) ? read_exr(map, P, &w, &h, &px, e) : read_pfm(map, P, &w, &h, &px, e));
    for (size_t i = 0; i < 3 * (size_t)w * (size_t)h; i++) {
        px[i] *= (float)(i % 3 == 0 ? l->Le.x : i % 3 == 1 ? l->Le.y : l->Le.z);
        if (!(px[i] <= SCENE_RADIANCE_MAX)) {
            free(px);
            return json_fail(e, PM_EINVAL, "%s.map: \"%s\" times radiance exceeds %g (the image is stored in 32-bit "
                             "floats)", P, map, SCENE_RADIANCE_MAX);
        }
    }
    s->env_map = malloc(sizeof *s->env_map);
    if (!s->env_map) {
        free(px);
        return json_fail(e, PM_ENOMEM, "out of memory");
    }
    int rc = envmap_init(s->env_map, w, h, px, (const double (*)[3])F);
    if (rc < 0) {
        free(s->env_map);
        s->env_map = NULL;
        return json_fail(e, rc, rc == PM_EINVAL ? "%s.map: \"%s\" is black (times radiance): an infinite light "
                         "that gives no light" : "%s.map: \"%s\": out of memory", P, map);
    }
    return 0;
}

int sl_load_light_more(scene *s, light *l, const char *type, const cJSON *o, const char *P, json_err *e) {
    if (strcmp(type, "spot") == 0) {
        TRY(spot(l, o, P, e));
        return 1;
    }
    if (strcmp(type, "infinite") == 0) {
        TRY(infinite(s, l, o, P, e));
        return 1;
    }
    return 0;
}
