/* tungsten_media.c: Tungsten's media in our terms (tungsten_internal.h): homogeneous media by
 * name or inline. Where they are (int_medium, ext_medium) tungsten.c turns into our
 * interfaces (medium.h, tungsten.h).
 */
#define _XOPEN_SOURCE 700
#include "load/tungsten_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "scene/scene.h"

/* One Tungsten medium object at path P into our media under the name `name`; its index in
 * *idx. Homogeneous only: sigma = sigma_a|sigma_s times density, the phase function isotropic
 * or Henyey-Greenstein. */
int tg_read_medium(conv *c, const cJSON *m, const char *P, const char *name, int *idx, json_err *e) {
    if (!cJSON_IsObject(m)) return json_fail(e, PM_EINVAL, "%s: expected an object or a medium name, got %s", P, json_type_name(m));
    static const char *const ok[] = {"name", "type", "sigma_a", "sigma_s", "density", "phase_function", "max_bounces", NULL};
    const char *type = "homogeneous";
    TRY(json_string(m, P, "type", 1, &type, e));
    if (strcmp(type, "homogeneous") != 0)
        return json_fail(e, PM_EINVAL, "%s.type: medium type \"%s\" is not supported (homogeneous)", P, type);
    TRY(tg_check_keys(NULL, m, P, ok, NULL, "a medium key outside the supported subset", e));
    if (c->nmedia == T_MEDIA) return json_fail(e, PM_EINVAL, "%s: more than %d media", P, T_MEDIA);
    if (strlen(name) >= sizeof c->mnames[0]) return json_fail(e, PM_EINVAL, "%s.name: too long (max 63 characters)", P);
    for (int i = 0; i < c->nmedia; i++)
        if (strcmp(c->mnames[i], name) == 0) return json_fail(e, PM_EINVAL, "%s.name: \"%s\" is used twice", P, name);
    rgb sa = v3s(0), ss = v3s(0);
    double density = 1, g = 0;
    TRY(tg_color(m, P, "sigma_a", &sa, e));
    TRY(tg_color(m, P, "sigma_s", &ss, e));
    TRY(json_number(m, P, "density", 0, &density, e));
    if (sa.x < 0 || sa.y < 0 || sa.z < 0) return json_fail(e, PM_EINVAL, "%s.sigma_a: must not be negative", P);
    if (ss.x < 0 || ss.y < 0 || ss.z < 0) return json_fail(e, PM_EINVAL, "%s.sigma_s: must not be negative", P);
    if (!(density >= 0)) return json_fail(e, PM_EINVAL, "%s.density: must not be negative, got %g", P, density);
    /* Our media's range (scene.h): a coefficient at most 1 / SCENE_LENGTH_MIN per unit length. */
    double smax = fmax(v3_maxabs(sa), v3_maxabs(ss)) * density;
    if (smax > 1 / SCENE_LENGTH_MIN)
        return json_fail(e, PM_EINVAL, "%s: sigma_a or sigma_s times density is %g, outside the supported "
                         "range, 0 to %g per unit length (a mean free path of at least %g)", P, smax,
                         1 / SCENE_LENGTH_MIN, SCENE_LENGTH_MIN);
    const cJSON *ph = json_get(m, "phase_function");
    char pp[P_MAX];
    json_path_key(pp, sizeof pp, P, "phase_function");
    if (ph) {
        const char *pt = NULL;
        if (cJSON_IsString(ph)) {
            pt = ph->valuestring;
        } else if (cJSON_IsObject(ph)) {
            static const char *const pok[] = {"type", "g", NULL};
            TRY(json_string(ph, pp, "type", 1, &pt, e));
            TRY(tg_check_keys(NULL, ph, pp, pok, NULL, "a phase function takes type and g", e));
            TRY(json_number(ph, pp, "g", 0, &g, e));
        } else {
            return json_fail(e, PM_EINVAL, "%s: expected an object or a type name, got %s", pp, json_type_name(ph));
        }
        if (strcmp(pt, "isotropic") == 0) {
            if (g != 0) return json_fail(e, PM_EINVAL, "%s.g: an isotropic phase function has no g", pp);
        } else if (strcmp(pt, "henyey_greenstein") != 0) {
            return json_fail(e, PM_EINVAL, "%s%s: phase function \"%s\" is not supported (isotropic, henyey_greenstein)",
                             pp, cJSON_IsObject(ph) ? ".type" : "", pt);
        }
        if (!(g > -1 && g < 1)) return json_fail(e, PM_EINVAL, "%s.g: must be in (-1, 1), got %g", pp, g);
    }
    long mb = 1024; /* Tungsten's default */
    TRY(json_int(m, P, "max_bounces", 0, 0, 1L << 30, &mb, e));
    if (mb < c->max_depth)
        return json_fail(e, PM_EINVAL, "%s.max_bounces: %ld, below the integrator's max_bounces (%ld): a separate "
                         "limit for scattering in a medium is not supported", P, mb, c->max_depth);
    if (!c->media && !(c->media = cJSON_CreateObject())) return json_fail(e, PM_ENOMEM, "out of memory");
    cJSON *o = cJSON_CreateObject();
    if (!o) return json_fail(e, PM_ENOMEM, "out of memory");
    cJSON_AddItemToObject(o, "sigma_a", tg_jvec(v3_scale(sa, density)));
    cJSON_AddItemToObject(o, "sigma_s", tg_jvec(v3_scale(ss, density)));
    cJSON_AddNumberToObject(o, "g", g);
    cJSON_AddItemToObject(c->media, name, o);
    snprintf(c->mnames[c->nmedia], sizeof c->mnames[0], "%s", name);
    *idx = c->nmedia++;
    return 0;
}

/* A medium reference at path P (Tungsten's fetchMedium): a name from $.media, or an inline
 * medium object (named after its path). *idx = -1 when v is NULL. */
int tg_medium_ref(conv *c, const cJSON *v, const char *P, int *idx, json_err *e) {
    *idx = -1;
    if (!v) return 0;
    if (cJSON_IsString(v)) {
        for (int i = 0; i < c->nmedia; i++)
            if (strcmp(c->mnames[i], v->valuestring) == 0) {
                *idx = i;
                return 0;
            }
        return json_fail(e, PM_EINVAL, "%s: unknown medium \"%s\"", P, v->valuestring);
    }
    return tg_read_medium(c, v, P, P + (P[0] == '$' && P[1] == '.' ? 2 : 0), idx, e);
}
