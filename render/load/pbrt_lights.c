/* pbrt_lights.c: pbrt-v3's "spot" and "infinite" LightSource directives, converted to this
 * renderer's spot and infinite lights (light.h); pbrt_directives.c converts point and distant.
 * A spot keeps pbrt-v3's own falloff (delta^4 between cos(coneangle - conedeltaangle) and
 * cos(coneangle): "falloff": "quartic"); an infinite light keeps its constant radiance L, and
 * an environment image (mapname) is not read: warned about, with what is used instead.
 */
#include <math.h>
#include <string.h>

#include "load/pbrt_internal.h"
#include "photonmap/common.h"

int pb_spot_light(conv *c, const tok *at, plist *pl, rgb sc, const char *what) {
    rgb I = v3s(1);
    double from[3] = {0, 0, 0}, to[3] = {0, 0, 1}, cone = 30, delta = 5;
    int rc;
    if ((rc = pb_get_color(c, at, pl, "I", &I)) < 0 || (rc = pb_get_floats(c, at, pl, "from", "point", 3, from)) < 0 ||
        (rc = pb_get_floats(c, at, pl, "to", "point", 3, to)) < 0 ||
        (rc = pb_get_floats(c, at, pl, "coneangle", "float", 1, &cone)) < 0 ||
        (rc = pb_get_floats(c, at, pl, "conedeltaangle", "float", 1, &delta)) < 0)
        return rc;
    if (!(cone > 0 && cone <= 180))
        return pb_fail(c, at, PM_EINVAL, "%s: coneangle %g is outside (0, 180] degrees", what, cone);
    if (!(delta >= 0 && delta <= cone))
        return pb_fail(c, at, PM_EINVAL, "%s: conedeltaangle %g is outside [0, coneangle = %g] degrees", what, delta, cone);
    I = v3_mul(I, sc);
    if (I.x < 0 || I.y < 0 || I.z < 0) return pb_fail(c, at, PM_EINVAL, "%s: I (times scale) must not be negative", what);
    vec3 dir = pb_out(c, pb_dir(c->g.m, v3(to[0] - from[0], to[1] - from[1], to[2] - from[2])));
    if (!(v3_len(dir) > 0) || !isfinite(v3_len(dir)))
        return pb_fail(c, at, PM_EINVAL, "%s: from and to are the same point (the spot has no axis)", what);
    cJSON *l = cJSON_CreateObject();
    if (!l) return PM_ENOMEM;
    cJSON_AddStringToObject(l, "type", "spot");
    cJSON_AddItemToObject(l, "position", pb_jv(pb_out(c, pb_point(c->g.m, v3(from[0], from[1], from[2])))));
    cJSON_AddItemToObject(l, "direction", pb_jv(v3_norm(dir)));
    cJSON_AddItemToObject(l, "intensity", pb_jv(I));
    cJSON_AddNumberToObject(l, "cone_angle", cone);
    cJSON_AddNumberToObject(l, "cone_delta", delta);
    cJSON_AddStringToObject(l, "falloff", "quartic");
    cJSON_AddItemToArray(c->lights, l);
    pb_warn_unused(c, at, what, pl);
    return 0;
}

int pb_infinite_light(conv *c, const tok *at, plist *pl, rgb sc, const char *what) {
    rgb L = v3s(1);
    const char *map = NULL;
    double ns;
    int rc;
    if ((rc = pb_get_color(c, at, pl, "L", &L)) < 0 || (rc = pb_get_string(c, at, pl, "mapname", &map)) < 0 ||
        (rc = pb_get_floats(c, at, pl, "samples", "integer", 1, &ns)) < 0 ||
        (rc = pb_get_floats(c, at, pl, "nsamples", "integer", 1, &ns)) < 0)
        return rc;
    L = v3_mul(L, sc);
    if (L.x < 0 || L.y < 0 || L.z < 0) return pb_fail(c, at, PM_EINVAL, "%s: L (times scale) must not be negative", what);
    if (map && *map)
        pb_warn(c, at, "%s: the environment image \"%s\" (mapname) is not supported: a constant radiance L "
                "(times scale) from every direction is used instead", what, map);
    for (const cJSON *it = c->lights->child; it; it = it->next) {
        const cJSON *t = cJSON_GetObjectItemCaseSensitive(it, "type");
        if (cJSON_IsString(t) && strcmp(t->valuestring, "infinite") == 0)
            return pb_fail(c, at, PM_EINVAL, "%s: a second infinite light (one is supported: add their L)", what);
    }
    cJSON *l = cJSON_CreateObject();
    if (!l) return PM_ENOMEM;
    cJSON_AddStringToObject(l, "type", "infinite");
    cJSON_AddItemToObject(l, "radiance", pb_jv(L));
    cJSON_AddItemToArray(c->lights, l);
    pb_warn_unused(c, at, what, pl);
    return 0;
}
