/* scene_lights.c: the spot and infinite lights of a JSON scene ($.lights[i] of type "spot" or
 * "infinite", format in data/scenes/README.md), every field checked; scene_load.c reads the
 * point and directional ones and hands the other types here.
 */
#include <math.h>
#include <string.h>

#include "load/scene_load_internal.h"
#include "photonmap/common.h"

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

static int infinite(const scene *s, light *l, const cJSON *o, const char *P, json_err *e) {
    KEYS(o, P, "an infinite light", "type", "radiance");
    l->type = LIGHT_INFINITE;
    TRY(json_rgb(o, P, "radiance", 1, &l->Le, e));
    TRY(sl_check_nonneg_rgb(l->Le, P, "radiance", e));
    if (v3_maxabs(l->Le) > SCENE_RADIANCE_MAX)
        return json_fail(e, PM_EINVAL, "%s.radiance: %g is outside the supported range, 0 to %g (the "
                         "image is stored in 32-bit floats)", P, v3_maxabs(l->Le), SCENE_RADIANCE_MAX);
    for (int i = 0; i < s->nlights; i++)
        if (s->lights[i].type == LIGHT_INFINITE)
            return json_fail(e, PM_EINVAL, "%s: a second infinite light ($.lights[%d] is one): give one, "
                             "with the radiances added", P, i);
    return 0;
}

int sl_load_light_more(const scene *s, light *l, const char *type, const cJSON *o, const char *P, json_err *e) {
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
