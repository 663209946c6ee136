/* tungsten_settings.c: a Tungsten scene's camera, renderer and integrator in our terms
 * (tungsten_internal.h): what is kept, and a warning for each setting that does not change the
 * image or that we lack (an unsupported integrator renders with path tracing).
 */
#define _XOPEN_SOURCE 700
#include "load/tungsten_internal.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

int tg_convert_camera(const char *file, const cJSON *root, cJSON *out, long spp, json_err *e) {
    const cJSON *c;
    TRY(json_object(root, "$", "camera", 1, &c, e));
    const char *P = "$.camera";
    static const char *const ok[] = {"type", "resolution", "transform", "fov", "medium", NULL};
    static const char *const warn[] = {"tonemap", NULL};
    const cJSON *filt = json_get(c, "reconstruction_filter");
    if (filt) /* a name ("tent", "gaussian", ...) or an object: either way not ours */
        tg_warn(file, "%s.reconstruction_filter: %s%s%s is not supported: each pixel is the mean of its own "
              "samples (a box filter) instead", P, cJSON_IsString(filt) ? "the filter \"" : "a filter",
              cJSON_IsString(filt) ? filt->valuestring : "", cJSON_IsString(filt) ? "\"" : "");
    static const char *const ok_f[] = {"type", "resolution", "transform", "fov", "medium", "reconstruction_filter", NULL};
    TRY(tg_check_keys(file, c, P, filt ? ok_f : ok, warn, "a camera key outside the supported subset", e));
    const char *type = "pinhole";
    TRY(json_string(c, P, "type", 0, &type, e));
    if (strcmp(type, "pinhole") != 0)
        return json_fail(e, PM_EINVAL, "%s.type: camera type \"%s\" is not supported (pinhole)", P, type);
    double fov = 60;
    TRY(json_number(c, P, "fov", 0, &fov, e));
    long w = 1000, h = 563;
    const cJSON *res = json_get(c, "resolution");
    if (res && cJSON_IsNumber(res)) {
        TRY(json_int(c, P, "resolution", 1, 1, 1 << 14, &w, e));
        h = w;
    } else if (res) {
        if (!cJSON_IsArray(res) || cJSON_GetArraySize(res) != 2 || !cJSON_IsNumber(res->child) ||
            !cJSON_IsNumber(res->child->next))
            return json_fail(e, PM_EINVAL, "%s.resolution: expected a number or [width, height]", P);
        double a = res->child->valuedouble, b = res->child->next->valuedouble;
        if (a != floor(a) || b != floor(b) || a < 1 || b < 1 || a > 1 << 14 || b > 1 << 14)
            return json_fail(e, PM_EINVAL, "%s.resolution: width and height must be integers in [1, 16384]", P);
        w = (long)a;
        h = (long)b;
    }
    const cJSON *t;
    TRY(json_object(c, P, "transform", 1, &t, e));
    const char *TP = "$.camera.transform";
    static const char *const tok[] = {"position", "look_at", "up", NULL};
    TRY(tg_check_keys(NULL, t, TP, tok, NULL, "a camera transform takes position, look_at and up", e));
    vec3 pos = v3s(0), look = v3(0, 0, 1), up = v3(0, 1, 0);
    TRY(json_vec3(t, TP, "position", 0, &pos, e));
    TRY(json_vec3(t, TP, "look_at", 1, &look, e));
    TRY(json_vec3(t, TP, "up", 0, &up, e));
    cJSON *cam = cJSON_CreateObject();
    if (!cam) return json_fail(e, PM_ENOMEM, "out of memory");
    cJSON_AddItemToObject(out, "camera", cam);
    /* Tungsten's image right is forward x up, as ours (it negates the frame's x axis) */
    cJSON_AddItemToObject(cam, "eye", tg_jvec(pos));
    cJSON_AddItemToObject(cam, "look_at", tg_jvec(look));
    cJSON_AddItemToObject(cam, "up", tg_jvec(up));
    cJSON_AddNumberToObject(cam, "fov_deg", fov);
    cJSON_AddNumberToObject(cam, "width", (double)w);
    cJSON_AddNumberToObject(cam, "height", (double)h);
    if (spp > 0) cJSON_AddNumberToObject(cam, "spp", (double)spp);
    return 0;
}

int tg_convert_settings(const char *file, const cJSON *root, cJSON *out, long *spp, long *max_depth,
                            json_err *e) {
    const cJSON *r, *in;
    TRY(json_object(root, "$", "renderer", 0, &r, e));
    *spp = 0;
    if (r) {
        static const char *const ok[] = {"spp", NULL};
        static const char *const warn[] = {"output_file", "hdr_output_file", "resume_render_file",
                                           "overwrite_output_files", "adaptive_sampling", "enable_resume_render",
                                           "stratified_sampler", "scene_bvh", "spp_step", "checkpoint_interval",
                                           "timeout", NULL};
        TRY(tg_check_keys(file, r, "$.renderer", ok, warn, "a renderer key outside the supported subset", e));
        TRY(json_int(r, "$.renderer", "spp", 0, 1, 1 << 20, spp, e));
    }
    TRY(json_object(root, "$", "integrator", 0, &in, e));
    cJSON *rs = cJSON_CreateObject();
    if (!rs) return json_fail(e, PM_ENOMEM, "out of memory");
    cJSON_AddItemToObject(out, "render", rs);
    *max_depth = 64; /* our render.max_depth default */
    if (!in) return 0;
    const char *P = "$.integrator";
    static const char *const ok[] = {"type", "max_bounces", "min_bounces", "enable_two_sided_shading", NULL};
    static const char *const warn[] = {"enable_consistency_checks", "enable_light_sampling",
                                       "enable_volume_light_sampling", "photon_count", "volume_photon_count",
                                       "gather_photon_count", "gather_radius", "alpha", "fixed_volume_radius",
                                       "volume_gather_radius", "volume_photon_type", "include_surfaces", NULL};
    const char *type = "path_tracer";
    TRY(json_string(in, P, "type", 0, &type, e));
    int known = strcmp(type, "path_tracer") == 0 || strcmp(type, "photon_map") == 0 ||
                strcmp(type, "progressive_photon_map") == 0;
    if (!known) {
        /* An integrator we lack is no reason to refuse the scene: the scene is the
         * same, only the method differs. Path tracing renders its expected image; --mode or
         * render.mode chooses another. Its own keys are ignored, each named. */
        tg_warn(file, "%s.type: integrator \"%s\" is not supported: rendering with \"path\" (path tracing; "
              "--mode chooses another: path, pm, ...)", P, type);
        cJSON_AddStringToObject(rs, "mode", "path");
        for (const cJSON *it = in->child; it; it = it->next) {
            const char *k = it->string ? it->string : "?";
            if (strcmp(k, "type") != 0 && strcmp(k, "max_bounces") != 0)
                tg_warn(file, "%s.%s: ignored (a setting of the integrator \"%s\", which is not used)", P, k, type);
        }
        long maxb = 64;
        TRY(json_int(in, P, "max_bounces", 0, 1, 100000, &maxb, e));
        cJSON_AddNumberToObject(rs, "max_depth", (double)maxb);
        *max_depth = maxb;
        return 0;
    }
    TRY(tg_check_keys(file, in, P, ok, warn, "an integrator key outside the supported subset", e));
    if (strcmp(type, "path_tracer") == 0)
        cJSON_AddStringToObject(rs, "mode", "path");
    else
        cJSON_AddStringToObject(rs, "mode", "pm");
    long maxb = 64, minb = 0;
    TRY(json_int(in, P, "max_bounces", 0, 1, 100000, &maxb, e));
    TRY(json_int(in, P, "min_bounces", 0, 0, 100000, &minb, e));
    if (minb != 0)
        return json_fail(e, PM_EINVAL, "%s.min_bounces: only 0 is supported (a minimum drops the short paths' light)", P);
    int two = 1;
    TRY(json_bool(in, P, "enable_two_sided_shading", 0, &two, e));
    if (!two) return json_fail(e, PM_EINVAL, "%s.enable_two_sided_shading: false is not supported", P);
    cJSON_AddNumberToObject(rs, "max_depth", (double)maxb);
    *max_depth = maxb;
    return 0;
}
