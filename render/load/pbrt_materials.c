/* pbrt_materials.c: pbrt's materials, area lights and media in our terms (pbrt_internal.h):
 * Material, MakeNamedMaterial, NamedMaterial, AreaLightSource, MakeNamedMedium and
 * MediumInterface, with a warning for each thing that is lost.
 */
#define _XOPEN_SOURCE 700
#include "load/pbrt_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

static rgb clamp01(rgb v) { return v3(fmin(fmax(v.x, 0), 1), fmin(fmax(v.y, 0), 1), fmin(fmax(v.z, 0), 1)); }

/* Our material for pbrt material `type` with parameters pl; warnings name what is lost. */
static int make_material(conv *c, const tok *at, const char *type, plist *pl, cJSON **out) {
    cJSON *m = cJSON_CreateObject();
    if (!m) return PM_ENOMEM;
    *out = m;
    char what[80];
    snprintf(what, sizeof what, "Material \"%s\"", type);
    if (strcmp(type, "matte") == 0) {
        rgb kd = v3s(0.5);
        double sigma = 0;
        TRY(pb_get_color(c, at, pl, "Kd", &kd));
        TRY(pb_get_floats(c, at, pl, "sigma", "float", 1, &sigma));
        if (sigma > 0) {
            cJSON_AddStringToObject(m, "type", "oren_nayar");
            cJSON_AddItemToObject(m, "reflectance", pb_jv(clamp01(kd)));
            cJSON_AddNumberToObject(m, "sigma", fmin(sigma, 90) * M_PI / 180); /* pbrt: degrees */
        } else {
            cJSON_AddStringToObject(m, "type", "lambert");
            cJSON_AddItemToObject(m, "reflectance", pb_jv(clamp01(kd)));
        }
    } else if (strcmp(type, "mirror") == 0) {
        rgb kr = v3s(0.9);
        TRY(pb_get_color(c, at, pl, "Kr", &kr));
        cJSON_AddStringToObject(m, "type", "mirror");
        cJSON_AddItemToObject(m, "reflectance", pb_jv(clamp01(kr)));
    } else if (strcmp(type, "glass") == 0) {
        rgb kr = v3s(1), kt = v3s(1);
        double eta = 1.5, r = 0;
        TRY(pb_get_color(c, at, pl, "Kr", &kr));
        TRY(pb_get_color(c, at, pl, "Kt", &kt));
        if (pb_get_floats(c, at, pl, "eta", "float", 1, &eta) == 0) TRY(pb_get_floats(c, at, pl, "index", "float", 1, &eta));
        int ru = pb_get_floats(c, at, pl, "uroughness", "float", 1, &r), rv = pb_get_floats(c, at, pl, "vroughness", "float", 1, &r);
        if (ru < 0 || rv < 0) return PM_EINVAL;
        if (!(eta > 0)) return pb_fail(c, at, PM_EINVAL, "%s: eta must be positive, got %g", what, eta);
        if ((ru || rv) && r > 0) pb_warn(c, at, "%s: roughness %g is lost: smooth glass", what, r);
        cJSON_AddStringToObject(m, "type", "dielectric");
        cJSON_AddNumberToObject(m, "ior", eta);
        if (!(kt.x == 1 && kt.y == 1 && kt.z == 1)) cJSON_AddItemToObject(m, "tint", pb_jv(clamp01(kt)));
        if (!(kr.x == 1 && kr.y == 1 && kr.z == 1))
            pb_warn(c, at, "%s: Kr [%g %g %g] is lost: the reflection is untinted", what, kr.x, kr.y, kr.z);
    } else if (strcmp(type, "plastic") == 0 || strcmp(type, "substrate") == 0 || strcmp(type, "uber") == 0) {
        int sub = strcmp(type, "substrate") == 0, uber = strcmp(type, "uber") == 0;
        rgb kd = v3s(sub ? 0.5 : 0.25), ks = v3s(sub ? 0.5 : 0.25), kr = v3s(0), kt = v3s(0), op = v3s(1);
        double rough = 0.1, eta = 1.5;
        TRY(pb_get_color(c, at, pl, "Kd", &kd));
        TRY(pb_get_color(c, at, pl, "Ks", &ks));
        TRY(pb_get_floats(c, at, pl, "roughness", "float", 1, &rough));
        TRY(pb_get_floats(c, at, pl, "uroughness", "float", 1, &rough));
        TRY(pb_get_floats(c, at, pl, "vroughness", "float", 1, &rough));
        int rm = 1;
        TRY(pb_get_bool(c, at, pl, "remaproughness", &rm));
        if (uber) {
            TRY(pb_get_color(c, at, pl, "Kr", &kr));
            TRY(pb_get_color(c, at, pl, "Kt", &kt));
            TRY(pb_get_color(c, at, pl, "opacity", &op));
            if (pb_get_floats(c, at, pl, "eta", "float", 1, &eta) == 0) TRY(pb_get_floats(c, at, pl, "index", "float", 1, &eta));
            if (!v3_iszero(kr) || !v3_iszero(kt) || !(op.x == 1 && op.y == 1 && op.z == 1))
                pb_warn(c, at, "%s: Kr, Kt and opacity are lost (only Kd under a Fresnel coat tinted by Ks)", what);
        }
        if (!(eta > 1)) eta = 1.5;
        pb_warn(c, at, "%s: the glossy lobe (Ks [%g %g %g], roughness %g) becomes a smooth Fresnel coat (ior %g) "
              "tinted by Ks over the diffuse Kd", what, ks.x, ks.y, ks.z, rough, eta);
        cJSON_AddStringToObject(m, "type", "mix");
        cJSON_AddStringToObject(m, "specular", "fresnel");
        cJSON_AddNumberToObject(m, "ior", eta);
        cJSON_AddNumberToObject(m, "transparency", 0);
        cJSON_AddItemToObject(m, "diffuse", pb_jv(clamp01(kd)));
        cJSON_AddItemToObject(m, "specular_tint", pb_jv(clamp01(ks)));
    } else {
        pb_warn(c, at, "%s is not supported: matte grey 0.5 is used instead", what);
        for (int i = 0; i < pl->n; i++) pl->p[i].used = 1; /* one warning is enough */
        cJSON_AddStringToObject(m, "type", "lambert");
        cJSON_AddNumberToObject(m, "reflectance", 0.5);
    }
    pparam *bm;
    TRY(pb_get(c, at, pl, "bumpmap", "texture", &bm));
    if (bm) pb_warn(c, at, "%s: bump maps are not supported: ignored", what);
    pb_warn_unused(c, at, what, pl);
    return 0;
}

static int add_material(conv *c, const char *name, cJSON *m) {
    cJSON *old = cJSON_GetObjectItemCaseSensitive(c->mats, name);
    if (old) cJSON_ReplaceItemInObjectCaseSensitive(c->mats, name, m);
    else cJSON_AddItemToObject(c->mats, name, m);
    return 0;
}

/* The material for the next shape: the current one, or a copy with the area light's emission. */
int pb_shape_material(conv *c, char *name, size_t cap) {
    if (!c->g.area) {
        snprintf(name, cap, "%s", c->g.mat);
        return 0;
    }
    const cJSON *base = cJSON_GetObjectItemCaseSensitive(c->mats, c->g.mat);
    cJSON *m = base ? cJSON_Duplicate(base, 1) : NULL;
    if (!m) return PM_ENOMEM;
    cJSON_DeleteItemFromObjectCaseSensitive(m, "emission");
    cJSON_AddItemToObject(m, "emission", pb_jv(c->g.L));
    if (c->g.twosided) cJSON_AddBoolToObject(m, "two_sided", 1);
    snprintf(name, cap, "%.60s+light%d", c->g.mat, c->nemit++);
    cJSON_AddItemToObject(c->mats, name, m);
    return 0;
}

/* ---- directives ------------------------------------------------------------------- */

int pb_do_material(conv *c, const tok *at, const char *s, plist *pl, const char *what) {
    const char *d = at->s;
    int rc = 0;
    const char *type = s;
    char name[80];
    if (strcmp(d, "MakeNamedMaterial") == 0) {
        rc = pb_get_string(c, at, pl, "type", &type);
        if (rc == 0) rc = pb_fail(c, at, PM_EINVAL, "%s: \"string type\" missing", what);
        if (rc > 0) rc = 0;
        snprintf(name, sizeof name, "%s", s);
    } else {
        snprintf(name, sizeof name, "pbrt:%d", c->nanon++);
    }
    cJSON *m = NULL;
    if (rc == 0 && (strcmp(type, "") == 0 || strcmp(type, "none") == 0 || strcmp(type, "interface") == 0)) {
        m = cJSON_CreateObject();
        if (m) cJSON_AddStringToObject(m, "type", "null");
    } else if (rc == 0) {
        rc = make_material(c, at, type, pl, &m);
    }
    if (rc == 0 && m) {
        add_material(c, name, m);
        if (strcmp(d, "Material") == 0) snprintf(c->g.mat, sizeof c->g.mat, "%s", name);
    } else {
        cJSON_Delete(m);
    }
    return rc;
}

int pb_do_named_material(conv *c, const tok *at, const char *s, plist *pl, const char *what) {
    int rc = 0;
    (void)pl, (void)what;
    if (!cJSON_GetObjectItemCaseSensitive(c->mats, s)) rc = pb_fail(c, at, PM_EINVAL, "NamedMaterial: no material named \"%s\"", s);
    else snprintf(c->g.mat, sizeof c->g.mat, "%s", s);
    return rc;
}

int pb_do_area_light(conv *c, const tok *at, const char *s, plist *pl, const char *what) {
    int rc = 0;
    if (strcmp(s, "diffuse") != 0) {
        pb_warn(c, at, "%s is not supported (diffuse): the shapes that follow do not emit", what);
        for (int k = 0; k < pl->n; k++) pl->p[k].used = 1;
    } else {
        rgb L = v3s(1), sc = v3s(1);
        int two = 0;
        double ns;
        if ((rc = pb_get_color(c, at, pl, "L", &L)) >= 0 && (rc = pb_get_color(c, at, pl, "scale", &sc)) >= 0 &&
            (rc = pb_get_bool(c, at, pl, "twosided", &two)) >= 0 && (rc = pb_get_floats(c, at, pl, "samples", "integer", 1, &ns)) >= 0 &&
            (rc = pb_get_floats(c, at, pl, "nsamples", "integer", 1, &ns)) >= 0) {
            rc = 0;
            c->g.area = 1;
            c->g.L = v3_mul(L, sc);
            c->g.twosided = two;
            if (c->g.L.x < 0 || c->g.L.y < 0 || c->g.L.z < 0) rc = pb_fail(c, at, PM_EINVAL, "%s: L must not be negative", what);
            if (rc == 0) pb_warn_unused(c, at, what, pl);
        }
    }
    return rc;
}

int pb_do_named_medium(conv *c, const tok *at, const char *s, plist *pl, const char *what) {
    int rc = 0;
    const char *type = NULL, *preset = NULL;
    rgb sa = v3(0.0011, 0.0024, 0.014), ss = v3(2.55, 3.21, 3.77); /* pbrt-v3's defaults */
    double scale = 1, g = 0;
    if ((rc = pb_get_string(c, at, pl, "type", &type)) == 0) rc = pb_fail(c, at, PM_EINVAL, "%s: \"string type\" missing", what);
    if (rc > 0 && strcmp(type, "homogeneous") != 0)
        rc = pb_fail(c, at, PM_EINVAL, "%s: medium type \"%s\" is not supported (homogeneous)", what, type);
    if (rc > 0 && (rc = pb_get_string(c, at, pl, "preset", &preset)) > 0)
        pb_warn(c, at, "%s: the preset \"%s\" is not supported: sigma_a and sigma_s as given (or pbrt's defaults)", what, preset);
    if (rc >= 0 && (rc = pb_get_color(c, at, pl, "sigma_a", &sa)) >= 0 && (rc = pb_get_color(c, at, pl, "sigma_s", &ss)) >= 0 &&
        (rc = pb_get_floats(c, at, pl, "scale", "float", 1, &scale)) >= 0 && (rc = pb_get_floats(c, at, pl, "g", "float", 1, &g)) >= 0)
        rc = 0;
    if (rc == 0 && (sa.x < 0 || sa.y < 0 || sa.z < 0 || ss.x < 0 || ss.y < 0 || ss.z < 0 || !(scale >= 0)))
        rc = pb_fail(c, at, PM_EINVAL, "%s: sigma_a, sigma_s and scale must not be negative", what);
    if (rc == 0 && !(g > -1 && g < 1)) rc = pb_fail(c, at, PM_EINVAL, "%s: g must be in (-1, 1), got %g", what, g);
    if (rc == 0 && !c->media && !(c->media = cJSON_CreateObject())) rc = PM_ENOMEM;
    if (rc == 0) {
        cJSON *m = cJSON_CreateObject();
        if (!m) return PM_ENOMEM;
        cJSON_AddItemToObject(m, "sigma_a", pb_jv(v3_scale(sa, scale)));
        cJSON_AddItemToObject(m, "sigma_s", pb_jv(v3_scale(ss, scale)));
        cJSON_AddNumberToObject(m, "g", g);
        if (cJSON_GetObjectItemCaseSensitive(c->media, s)) cJSON_ReplaceItemInObjectCaseSensitive(c->media, s, m);
        else cJSON_AddItemToObject(c->media, s, m);
        pparam *le;
        TRY(pb_get(c, at, pl, "Le", "rgb|spectrum|blackbody", &le));
        if (le) pb_warn(c, at, "%s: an emitting medium (Le) is not supported: it does not emit", what);
        pb_warn_unused(c, at, what, pl);
    }
    return rc;
}

int pb_do_medium_interface(conv *c, const toks *ts, int *i, const tok *at) {
    const char *d = at->s;
    const char *a = NULL, *b = NULL;
    TRY(pb_one_string(c, ts, i, at, &a, d));
    if (*i < ts->n && ts->t[*i].kind == K_STR) b = ts->t[(*i)++].s;
    if (!b) b = a;
    const char *nm[2] = {a, b};
    for (int k = 0; k < 2; k++)
        if (nm[k][0] && !(c->media && cJSON_GetObjectItemCaseSensitive(c->media, nm[k])))
            return pb_fail(c, at, PM_EINVAL, "MediumInterface: no medium named \"%s\" (MakeNamedMedium first)", nm[k]);
    snprintf(c->g.inside, sizeof c->g.inside, "%s", a);
    snprintf(c->g.outside, sizeof c->g.outside, "%s", b);
    return 0;
}

