/* pbrt_lights.c: pbrt-v3's "spot" and "infinite" LightSource directives, converted to this
 * renderer's spot and infinite lights (light.h); pbrt_directives.c converts point and distant.
 * A spot keeps pbrt-v3's own falloff (delta^4 between cos(coneangle - conedeltaangle) and
 * cos(coneangle): "falloff": "quartic"); an infinite light keeps its radiance L, and its
 * environment image (mapname) when it is a PFM or an OpenEXR file ("map", with "map_frame" the
 * rotation from our world to pbrt's light space, which is z-up lat-long as ours); another image
 * format is warned about, with the constant L used instead.
 */
#include <math.h>
#include <string.h>
#include <strings.h>

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
    size_t ml = map ? strlen(map) : 0;
    int pfm = ml > 4 && (strcasecmp(map + ml - 4, ".pfm") == 0 || strcasecmp(map + ml - 4, ".exr") == 0);
    if (map && *map && !pfm)
        pb_warn(c, at, "%s: the environment image \"%s\" (mapname) is not supported (a PFM or EXR is): a constant "
                "radiance L (times scale) from every direction is used instead", what, map);
    for (const cJSON *it = c->lights->child; it; it = it->next) {
        const cJSON *t = cJSON_GetObjectItemCaseSensitive(it, "type");
        if (cJSON_IsString(t) && strcmp(t->valuestring, "infinite") == 0)
            return pb_fail(c, at, PM_EINVAL, "%s: a second infinite light (one is supported: add their L)", what);
    }
    cJSON *l = cJSON_CreateObject();
    if (!l) return PM_ENOMEM;
    cJSON_AddStringToObject(l, "type", "infinite");
    cJSON_AddItemToObject(l, "radiance", pb_jv(L));
    if (pfm) { /* the map's frame: world (ours) to light space, the transpose of light to world */
        char path[4096];
        pb_resolve(pb_file(c, at), map, path, sizeof path);
        cJSON_AddStringToObject(l, "map", path);
        double F[9];
        for (int i = 0; i < 3; i++) {
            vec3 col = pb_out(c, pb_dir(c->g.m, v3(i == 0, i == 1, i == 2)));
            double n = v3_len(col);
            col = n > 0 ? v3_scale(col, 1 / n) : col;
            F[3 * i] = col.x, F[3 * i + 1] = col.y, F[3 * i + 2] = col.z;
        }
        cJSON_AddItemToObject(l, "map_frame", cJSON_CreateDoubleArray(F, 9));
    }
    cJSON_AddItemToArray(c->lights, l);
    pb_warn_unused(c, at, what, pl);
    return 0;
}
