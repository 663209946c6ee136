/* scene_load.c: the JSON scene loader (format: data/scenes/README.md); see scene_load.h.
 *
 * Loading is one pass over the document with the json.h getters. Each check reports the
 * JSON path of the offending field. Arrays grow with a small push helper; on any error the
 * partly built scene is freed, so the caller never sees half a scene. What follows from the
 * loaded shapes (bounds, the lights of emissive surfaces, the BVH) is scene_prepare's, in
 * scene.c.
 */
#include "load/scene_load_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "load/import.h"
#include "load/scene_load.h"
#include "load/photon_settings.h"

static int check_unit_rgb(rgb c, const char *path, const char *key, json_err *e) {
    if (c.x < 0 || c.y < 0 || c.z < 0 || c.x > 1 || c.y > 1 || c.z > 1)
        return json_fail(e, PM_EINVAL, "%s.%s: each component must be in [0, 1] (got [%g, %g, %g])",
                         path, key, c.x, c.y, c.z);
    return 0;
}

/* Emission (a radiance) and a directional light's irradiance: in [0, SCENE_RADIANCE_MAX].
 * Not a point light's intensity or power: the light they give scales with 1 / length^2, so
 * their range depends on the scene's units (a film value that overflows is counted). */
static int check_light_rgb(rgb c, const char *path, const char *key, json_err *e) {
    TRY(sl_check_nonneg_rgb(c, path, key, e));
    if (v3_maxabs(c) > SCENE_RADIANCE_MAX)
        return json_fail(e, PM_EINVAL, "%s.%s: %g is outside the supported range, 0 to %g (the "
                         "image is stored in 32-bit floats)", path, key, v3_maxabs(c), SCENE_RADIANCE_MAX);
    return 0;
}

/* A point or spot light's intensity or power, once the scene's bounds are known: the irradiance it
 * gives at D, the larger of the scene's bounding radius and the light's distance from the
 * scene's centre, is at most SCENE_RADIANCE_MAX (a directional light's limit). Scaled with the
 * scene (I / D^2 is what lights it), so a scene in other units keeps its lights. */
static int check_point_lights(const scene *s, const cJSON *lights, json_err *e) {
    int i = 0;
    char P[P_MAX];
    for (const cJSON *it = lights ? lights->child : NULL; it; it = it->next, i++) {
        if (i >= s->nlights || !light_is_point(&s->lights[i])) continue;
        const light *l = &s->lights[i];
        double D = fmax(s->bsphere_r, v3_len(v3_sub(l->pos, s->bsphere_c)));
        double I = v3_maxabs(l->intensity);
        if (I / (D * D) <= SCENE_RADIANCE_MAX) continue;
        int power = json_get(it, "power") != NULL;
        double f = power ? 4 * M_PI : 1;
        json_path_index(P, sizeof P, "$.lights", i);
        return json_fail(e, PM_EINVAL, "%s.%s: %g is outside the supported range for this scene, 0 "
                         "to %g (a point light's %s at D = %g, the larger of the scene's bounding "
                         "radius and the light's distance from its centre, must be at most %g, as "
                         "a directional light's irradiance: the image is stored in 32-bit floats)",
                         P, power ? "power" : "intensity", f * I, f * SCENE_RADIANCE_MAX * D * D,
                         power ? "irradiance, power / (4 pi D^2)," : "irradiance, intensity / D^2,",
                         D, SCENE_RADIANCE_MAX);
    }
    return 0;
}

static int load_camera(scene *s, const cJSON *root, json_err *e) {
    const cJSON *c;
    TRY(json_object(root, "$", "camera", 1, &c, e));
    const char *P = "$.camera";
    KEYS(c, P, "the camera", "eye", "look_at", "forward", "up", "fov_deg", "focal_length_mm",
         "sensor_width_mm", "width", "height", "spp");
    vec3 eye, look, fwd, up = v3(0, 1, 0);
    TRY(json_vec3(c, P, "eye", 1, &eye, e));
    TRY(sl_check_point(eye, P, "eye", e));
    int has_look = json_get(c, "look_at") != NULL, has_fwd = json_get(c, "forward") != NULL;
    if (has_look && has_fwd)
        return json_fail(e, PM_EINVAL, "%s: give either look_at or forward, not both", P);
    if (!has_look && !has_fwd)
        return json_fail(e, PM_EINVAL, "%s.look_at: missing (required, or give forward)", P);
    if (has_look) {
        TRY(json_vec3(c, P, "look_at", 1, &look, e));
        TRY(sl_check_point(look, P, "look_at", e));
        fwd = v3_sub(look, eye);
    } else {
        TRY(json_vec3(c, P, "forward", 1, &fwd, e));
    }
    TRY(json_vec3(c, P, "up", 0, &up, e));
    double fov = -1, focal = -1, sensor = 36.0;
    int has_fov = json_get(c, "fov_deg") != NULL, has_focal = json_get(c, "focal_length_mm") != NULL;
    if (has_fov && has_focal)
        return json_fail(e, PM_EINVAL, "%s: give either fov_deg or focal_length_mm, not both", P);
    if (has_fov) {
        TRY(json_number(c, P, "fov_deg", 1, &fov, e));
        if (!(fov > 0 && fov < 180))
            return json_fail(e, PM_EINVAL, "%s.fov_deg: must be in (0, 180), got %g", P, fov);
    } else {
        TRY(json_number(c, P, "focal_length_mm", 1, &focal, e));
        TRY(json_number(c, P, "sensor_width_mm", 0, &sensor, e));
        if (!(focal > 0))
            return json_fail(e, PM_EINVAL, "%s.focal_length_mm: must be positive, got %g", P, focal);
        if (!(sensor > 0))
            return json_fail(e, PM_EINVAL, "%s.sensor_width_mm: must be positive, got %g", P, sensor);
        fov = 2.0 * atan(0.5 * sensor / focal) * 180.0 / M_PI;
    }
    long w, h, spp = 16;
    TRY(json_int(c, P, "width", 1, 1, 1 << 14, &w, e));
    TRY(json_int(c, P, "height", 1, 1, 1 << 14, &h, e));
    TRY(json_int(c, P, "spp", 0, 1, 1 << 20, &spp, e));
    const char *why = "";
    camera_set_spp(&s->cam, (int)spp);
    if (camera_setup(&s->cam, eye, fwd, up, fov, (int)w, (int)h, &why) < 0)
        return json_fail(e, PM_EINVAL, "%s: %s", P, why);
    return 0;
}

/* Oren-Nayar's sigma: the standard deviation of the facets' slope angle, in radians. */
static int check_sigma(double sigma, const char *P, json_err *e) {
    if (!(sigma >= 0 && sigma <= M_PI / 2))
        return json_fail(e, PM_EINVAL, "%s.sigma: %g is outside the supported range, 0 to %.6g "
                         "(radians: the spread of the facets' slope angle; pi/2 is a 90-degree "
                         "spread)", P, sigma, M_PI / 2);
    return 0;
}

static int load_material(material *m, const cJSON *it, const char *P, json_err *e) {
    memset(m, 0, sizeof *m);
    snprintf(m->name, sizeof m->name, "%s", it->string ? it->string : "?");
    if (!cJSON_IsObject(it))
        return json_fail(e, PM_EINVAL, "%s: expected an object, got %s", P, json_type_name(it));
    const char *type;
    TRY(json_string(it, P, "type", 1, &type, e));
    m->specular_tint = v3s(1);
    m->transmit_tint = v3s(1);
    m->ior = 1.5;
    if (strcmp(type, "lambert") == 0) {
        KEYS(it, P, "a lambert material", "type", "reflectance", "emission", "two_sided");
        m->kind = MAT_LAMBERT;
        TRY(json_rgb(it, P, "reflectance", 1, &m->diffuse, e));
        TRY(check_unit_rgb(m->diffuse, P, "reflectance", e));
    } else if (strcmp(type, "oren_nayar") == 0) {
        KEYS(it, P, "an oren_nayar material", "type", "reflectance", "sigma", "emission", "two_sided");
        m->kind = MAT_OREN_NAYAR;
        TRY(json_rgb(it, P, "reflectance", 1, &m->diffuse, e));
        TRY(check_unit_rgb(m->diffuse, P, "reflectance", e));
        TRY(json_number(it, P, "sigma", 1, &m->sigma, e));
        TRY(check_sigma(m->sigma, P, e));
    } else if (strcmp(type, "mirror") == 0) {
        KEYS(it, P, "a mirror material", "type", "reflectance", "emission", "two_sided");
        m->kind = MAT_MIRROR;
        m->specular = 1;
        TRY(json_rgb(it, P, "reflectance", 0, &m->specular_tint, e));
        TRY(check_unit_rgb(m->specular_tint, P, "reflectance", e));
    } else if (strcmp(type, "dielectric") == 0) {
        KEYS(it, P, "a dielectric material", "type", "ior", "tint", "emission", "two_sided");
        m->kind = MAT_DIELECTRIC;
        m->fresnel = 1;
        m->transparency = 1;
        TRY(json_number(it, P, "ior", 1, &m->ior, e));
        TRY(json_rgb(it, P, "tint", 0, &m->transmit_tint, e));
        TRY(check_unit_rgb(m->transmit_tint, P, "tint", e));
    } else if (strcmp(type, "mix") == 0) {
        KEYS(it, P, "a mix material", "type", "specular", "transparency", "ior", "diffuse", "sigma",
             "specular_tint", "transmit_tint", "emission", "two_sided");
        m->kind = MAT_MIX;
        const cJSON *sp = json_get(it, "specular");
        if (cJSON_IsString(sp) && strcmp(sp->valuestring, "fresnel") == 0) {
            m->fresnel = 1;
        } else if (sp && !cJSON_IsNumber(sp)) {
            return json_fail(e, PM_EINVAL, "%s.specular: expected a number in [0, 1] or \"fresnel\", got %s",
                             P, json_type_name(sp));
        } else {
            TRY(json_number(it, P, "specular", 0, &m->specular, e));
            if (m->specular < 0 || m->specular > 1)
                return json_fail(e, PM_EINVAL, "%s.specular: must be in [0, 1], got %g", P, m->specular);
        }
        TRY(json_number(it, P, "transparency", 0, &m->transparency, e));
        if (m->transparency < 0 || m->transparency > 1)
            return json_fail(e, PM_EINVAL, "%s.transparency: must be in [0, 1], got %g", P,
                             m->transparency);
        TRY(json_number(it, P, "ior", 0, &m->ior, e));
        TRY(json_rgb(it, P, "diffuse", 0, &m->diffuse, e));
        TRY(check_unit_rgb(m->diffuse, P, "diffuse", e));
        TRY(json_number(it, P, "sigma", 0, &m->sigma, e));
        TRY(check_sigma(m->sigma, P, e));
        TRY(json_rgb(it, P, "specular_tint", 0, &m->specular_tint, e));
        TRY(check_unit_rgb(m->specular_tint, P, "specular_tint", e));
        TRY(json_rgb(it, P, "transmit_tint", 0, &m->transmit_tint, e));
        TRY(check_unit_rgb(m->transmit_tint, P, "transmit_tint", e));
    } else if (strcmp(type, "null") == 0 || strcmp(type, "interface") == 0) {
        KEYS(it, P, "a null material", "type", "emission", "two_sided");
        m->kind = MAT_NULL; /* invisible: its ior is set to medium_ior by the caller */
        m->transparency = 1;
        if (json_get(it, "emission"))
            return json_fail(e, PM_EINVAL, "%s.emission: a null (invisible) surface cannot emit", P);
    } else {
        return json_fail(e, PM_EINVAL,
                         "%s.type: unknown material type \"%s\" (lambert, oren_nayar, mirror, "
                         "dielectric, mix, null)", P, type);
    }
    if (!(m->ior > 0)) return json_fail(e, PM_EINVAL, "%s.ior: must be positive, got %g", P, m->ior);
    TRY(json_rgb(it, P, "emission", 0, &m->emission, e));
    TRY(check_light_rgb(m->emission, P, "emission", e));
    TRY(json_bool(it, P, "two_sided", 0, &m->two_sided, e));
    return 0;
}

static int load_light(scene *s, caps *cp, const cJSON *o, const char *P, json_err *e) {
    if (!cJSON_IsObject(o))
        return json_fail(e, PM_EINVAL, "%s: expected an object, got %s", P, json_type_name(o));
    const char *type;
    light l;
    memset(&l, 0, sizeof l);
    l.tri = -1;
    TRY(json_string(o, P, "type", 1, &type, e));
    if (strcmp(type, "point") == 0) {
        KEYS(o, P, "a point light", "type", "position", "intensity", "power");
        l.type = LIGHT_POINT;
        TRY(json_vec3(o, P, "position", 1, &l.pos, e));
        TRY(sl_check_point(l.pos, P, "position", e));
        int has_i = json_get(o, "intensity") != NULL, has_p = json_get(o, "power") != NULL;
        if (has_i == has_p)
            return json_fail(e, PM_EINVAL, "%s: give exactly one of intensity (W/sr) or power (W)", P);
        if (has_i) {
            TRY(json_rgb(o, P, "intensity", 1, &l.intensity, e));
            TRY(sl_check_nonneg_rgb(l.intensity, P, "intensity", e));
        } else {
            rgb pw;
            TRY(json_rgb(o, P, "power", 1, &pw, e));
            TRY(sl_check_nonneg_rgb(pw, P, "power", e));
            l.intensity = v3_scale(pw, 1.0 / (4 * M_PI));
        }
    } else if (strcmp(type, "directional") == 0) {
        KEYS(o, P, "a directional light", "type", "direction", "irradiance");
        l.type = LIGHT_DIRECTIONAL;
        TRY(json_vec3(o, P, "direction", 1, &l.dir, e));
        if (!(v3_len(l.dir) > 0))
            return json_fail(e, PM_EINVAL, "%s.direction: must not be the zero vector", P);
        l.dir = v3_norm(l.dir);
        TRY(json_rgb(o, P, "irradiance", 1, &l.irradiance, e));
        TRY(check_light_rgb(l.irradiance, P, "irradiance", e));
    } else {
        int rc = sl_load_light_more(s, &l, type, o, P, e);
        if (rc < 0) return rc;
        if (rc == 0)
            return json_fail(e, PM_EINVAL,
                             "%s.type: unknown light type \"%s\" (point, spot, directional, infinite; area "
                             "lights are objects with an emissive material)", P, type);
    }
    if (sl_push((void **)&s->lights, &s->nlights, &cp->lcap, sizeof l, &l) < 0)
        return json_fail(e, PM_ENOMEM, "out of memory");
    return 0;
}

static int load_settings(scene *s, const cJSON *root, json_err *e) {
    render_settings *st = &s->settings;
    st->max_depth = 64;
    st->rr_depth = 3;
    snprintf(st->mode, sizeof st->mode, "path");
    st->seed = 1;
    st->tone = TONE_FILMIC;
    st->clip_percent = 1.0;
    st->exposure = 0;
    st->time = 0;
    st->pass_spp = 0;
    const cJSON *r, *im;
    TRY(json_object(root, "$", "render", 0, &r, e));
    if (r) {
        KEYS(r, "$.render", "the render settings", "mode", "max_depth", "rr_depth", "seed", "time",
             "pass_spp");
        long v;
        v = st->max_depth;
        TRY(json_int(r, "$.render", "max_depth", 0, 1, 100000, &v, e));
        st->max_depth = (int)v;
        v = st->rr_depth;
        TRY(json_int(r, "$.render", "rr_depth", 0, 0, 100000, &v, e));
        st->rr_depth = (int)v;
        v = (long)st->seed;
        TRY(json_int(r, "$.render", "seed", 0, 0, 2147483647L, &v, e));
        st->seed = (uint64_t)v;
        /* A time budget: render in passes (run/passes.h) for this many seconds. */
        double tb = 0;
        TRY(json_number(r, "$.render", "time", 0, &tb, e));
        if (json_get(r, "time") && !(tb > 0 && tb <= 1e9))
            return json_fail(e, PM_EINVAL, "$.render.time: expected seconds in (0, 1e9], got %g", tb);
        st->time = tb;
        v = 0;
        TRY(json_int(r, "$.render", "pass_spp", 0, 1, 1 << 20, &v, e));
        st->pass_spp = (int)v;
        const char *mode = NULL;
        TRY(json_string(r, "$.render", "mode", 0, &mode, e));
        if (mode) snprintf(st->mode, sizeof st->mode, "%s", mode);
    }
    TRY(json_object(root, "$", "image", 0, &im, e));
    if (im) {
        KEYS(im, "$.image", "the image settings", "tone", "clip_percent", "exposure");
        const char *tone = NULL;
        TRY(json_string(im, "$.image", "tone", 0, &tone, e));
        if (tone) {
            if (strcmp(tone, "filmic") == 0)
                st->tone = TONE_FILMIC;
            else if (strcmp(tone, "srgb") == 0)
                st->tone = TONE_SRGB;
            else
                return json_fail(e, PM_EINVAL, "$.image.tone: expected \"filmic\" or \"srgb\", got \"%s\"", tone);
        }
        TRY(json_number(im, "$.image", "clip_percent", 0, &st->clip_percent, e));
        if (!(st->clip_percent >= 0 && st->clip_percent < 100))
            return json_fail(e, PM_EINVAL, "$.image.clip_percent: must be in [0, 100), got %g",
                             st->clip_percent);
        TRY(json_number(im, "$.image", "exposure", 0, &st->exposure, e));
        if (st->exposure < 0)
            return json_fail(e, PM_EINVAL, "$.image.exposure: must be positive (or 0 for auto), got %g",
                             st->exposure);
    }
    return 0;
}

static int from_json(scene *s, const cJSON *root, json_err *e) {
    caps cp = {0};
    if (!cJSON_IsObject(root))
        return json_fail(e, PM_EINVAL, "$: expected an object, got %s", json_type_name(root));
    KEYS(root, "$", "a scene", "camera", "materials", "objects", "lights", "medium_ior", "media",
         "medium", "render", "image", "photon_mapping", "description", "ports", "port_fraction",
         "find_ports");
    TRY(load_camera(s, root, e));
    TRY(load_settings(s, root, e));
    s->medium_ior = 1.0;
    TRY(json_number(root, "$", "medium_ior", 0, &s->medium_ior, e));
    if (!(s->medium_ior > 0))
        return json_fail(e, PM_EINVAL, "$.medium_ior: must be positive, got %g", s->medium_ior);
    s->global_medium = -1;
    TRY(sl_load_media(s, root, e));
    if (json_get(root, "medium")) TRY(sl_find_medium(s, root, "$", "medium", &s->global_medium, e));
    const cJSON *mats, *objs, *lights, *pm;
    TRY(json_object(root, "$", "materials", 1, &mats, e));
    char p[P_MAX];
    for (const cJSON *it = mats->child; it; it = it->next) {
        if (sl_is_comment(it)) continue;
        material m;
        json_path_key(p, sizeof p, "$.materials", it->string ? it->string : "?");
        if (it->string && strlen(it->string) >= sizeof m.name)
            return json_fail(e, PM_EINVAL, "%s: material name too long (max %d characters)", p,
                             (int)sizeof m.name - 1);
        TRY(load_material(&m, it, p, e));
        if (m.kind == MAT_NULL) {
            m.ior = s->medium_ior;
            s->has_null = 1;
        }
        if (sl_push((void **)&s->mats, &s->nmats, &cp.mcap, sizeof m, &m) < 0)
            return json_fail(e, PM_ENOMEM, "out of memory");
    }
    TRY(json_array(root, "$", "objects", 1, &objs, e));
    int i = 0;
    s->nobj = cJSON_GetArraySize(objs);
    s->obj_medium = malloc((size_t)(s->nobj > 0 ? s->nobj : 1) * sizeof *s->obj_medium);
    if (!s->obj_medium) return json_fail(e, PM_ENOMEM, "out of memory");
    for (int k = 0; k < s->nobj; k++) s->obj_medium[k] = -1;
    for (const cJSON *it = objs->child; it; it = it->next, i++) {
        json_path_index(p, sizeof p, "$.objects", i);
        cp.obj = i;
        TRY(sl_load_object(s, &cp, it, p, e));
        TRY(sl_load_object_media(s, it, p, i, e));
    }
    TRY(sl_check_media_closed(s, e));
    TRY(json_array(root, "$", "lights", 0, &lights, e));
    i = 0;
    for (const cJSON *it = lights ? lights->child : NULL; it; it = it->next, i++) {
        json_path_index(p, sizeof p, "$.lights", i);
        TRY(load_light(s, &cp, it, p, e));
    }
    TRY(sl_load_ports(s, root, e));
    TRY(json_object(root, "$", "photon_mapping", 0, &pm, e));
    if (pm) {
        /* Checked here, whatever will read it (any mode, render --dump-scene, render-mpi): a
         * misspelt or out-of-range setting is an error of the file. */
        photon_settings ps;
        TRY(photon_settings_parse(&ps, pm, e));
        s->photon_mapping = cJSON_Duplicate(pm, 1);
        if (!s->photon_mapping) return json_fail(e, PM_ENOMEM, "out of memory");
    }
    TRY(scene_prepare(s, e));
    TRY(check_point_lights(s, lights, e));
    sl_find_camera_medium(s);
    s->iface_report = calloc(1, sizeof *s->iface_report);
    if (!s->iface_report) return json_fail(e, PM_ENOMEM, "out of memory");
    return 0;
}

int scene_from_json(scene *s, const cJSON *root, json_err *e) {
    memset(s, 0, sizeof *s);
    int rc = from_json(s, root, e);
    if (rc < 0) scene_free(s);
    return rc;
}

/* A parsed document (rc from its parser) to a scene: Tungsten scenes converted and mesh
 * paths resolved (import.h; filename NULL for a text), then loaded; the document is freed. */
static int load_parsed(scene *s, int rc, cJSON *root, const char *filename, json_err *e) {
    if (rc < 0) return rc;
    rc = scene_import(&root, filename, e);
    if (rc == 0) rc = scene_from_json(s, root, e);
    cJSON_Delete(root);
    return rc;
}

int scene_load_text(scene *s, const char *text, json_err *e) {
    cJSON *root = NULL;
    memset(s, 0, sizeof *s);
    int rc = json_parse_text(text, &root, e);
    return load_parsed(s, rc, root, NULL, e);
}

int scene_load(scene *s, const char *filename, json_err *e) {
    cJSON *root = NULL;
    memset(s, 0, sizeof *s);
    int rc = scene_parse_file(filename, &root, e); /* JSON, or a pbrt-v3 file converted */
    rc = load_parsed(s, rc, root, filename, e);
    if (rc == 0) snprintf(s->file, sizeof s->file, "%s", filename);
    return rc;
}
