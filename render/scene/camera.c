/* camera.c: a pinhole camera; see camera.h. */
#include "scene/camera.h"

#include "base/sampling.h"

int camera_setup(camera *c, vec3 eye, vec3 forward, vec3 up, double fov_deg, int width,
                 int height, const char **why) {
    if (width <= 0 || height <= 0) {
        *why = "the image size must be positive";
        return -1;
    }
    if (!(fov_deg > 0 && fov_deg < 180)) {
        *why = "the field of view must be between 0 and 180 degrees (focal length and sensor "
               "width must be positive)";
        return -1;
    }
    double fl = v3_len(forward);
    if (!(fl > 0) || !isfinite(fl)) {
        *why = "the camera points nowhere: the view direction is zero (eye == look_at?)";
        return -1;
    }
    vec3 f = v3_scale(forward, 1.0 / fl);
    double ul = v3_len(up);
    if (!(ul > 0)) {
        *why = "the up vector is zero";
        return -1;
    }
    vec3 r = v3_cross(f, v3_scale(up, 1.0 / ul));
    if (!(v3_len(r) > 1e-9)) {
        *why = "the up vector is parallel to the view direction";
        return -1;
    }
    r = v3_norm(r);
    c->eye = eye;
    c->forward = f;
    c->right = r;
    c->up = v3_cross(r, f);
    c->width = width;
    c->height = height;
    c->tan_half_w = tan(0.5 * fov_deg * M_PI / 180.0);
    c->tan_half_h = c->tan_half_w * (double)height / (double)width;
    if (c->spp <= 0) camera_set_spp(c, 16);
    return 0;
}

void camera_set_spp(camera *c, int spp) {
    int s = 1;
    while (s * s < spp) s++;
    c->strata = s;
    c->spp = s * s;
}

ray camera_ray(const camera *c, double px, double py) {
    double sx = (2.0 * px / c->width - 1.0) * c->tan_half_w;
    double sy = (1.0 - 2.0 * py / c->height) * c->tan_half_h;
    vec3 d = v3_add(c->forward, v3_add(v3_scale(c->right, sx), v3_scale(c->up, sy)));
    return (ray){c->eye, v3_norm(d)};
}

int camera_resize(camera *c, int width, int height) {
    if (width <= 0 || height <= 0) return -1;
    c->width = width;
    c->height = height;
    c->tan_half_h = c->tan_half_w * (double)height / (double)width;
    return 0;
}
