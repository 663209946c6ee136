/* camera.h: the pinhole camera and the rays it shoots through the image plane.
 *
 * The scene file gives the eye, a look-at point or a forward direction, an up vector, and
 * either a focal length and sensor width in millimetres (like the published Cornell box
 * camera: 35 mm lens, 25 mm film) or a horizontal field of view in degrees. Pixels are square,
 * so the sensor height follows from the image's aspect ratio. Image x runs right, y down.
 * right = forward x up, so with forward +z and up +y the image's right is -x (right-handed).
 *
 * camera_ray() maps a film position (pixel coordinates, continuous, (0,0) the top-left
 * corner) to a ray with unit direction. Pure and thread-safe.
 */
#ifndef RENDER_CAMERA_H
#define RENDER_CAMERA_H

#include "base/vec.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct camera {
    vec3 eye, forward, right, up; /* orthonormal frame: forward, right, up */
    double tan_half_w;            /* tan of half the horizontal field of view */
    double tan_half_h;
    int width, height;
    int spp;     /* samples per pixel = strata * strata */
    int strata;  /* strata per pixel side */
} camera;

/* Set up the frame. Returns 0, or -1 with a reason in *why when the camera points nowhere:
 * a zero forward vector (eye == look_at), an up vector parallel to forward or zero, a
 * non-positive size, or a field of view outside (0, 180) degrees. */
int camera_setup(camera *c, vec3 eye, vec3 forward, vec3 up, double fov_deg, int width,
                 int height, const char **why);
/* Round spp up to a square number of strata and set spp and strata. */
void camera_set_spp(camera *c, int spp);
/* Change the image size, keeping the horizontal field of view (the vertical one follows
 * the new aspect ratio). Returns -1 for a non-positive size. */
int camera_resize(camera *c, int width, int height);
ray camera_ray(const camera *c, double px, double py);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_CAMERA_H */
