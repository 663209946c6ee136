/* pm_ball.h: the part of a volume estimate's search ball that lies inside the medium
 * (pm_volume.h, BOUNDARIES), for the k-nearest estimates of pm_volume.c and the beam estimates
 * of pm_beam.c, which divide by it.
 */
#ifndef RENDER_PM_BALL_H
#define RENDER_PM_BALL_H

#include "base/vec.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The part of the ball of radius r at x that lies inside the medium at x (pm_volume.h,
 * BOUNDARIES): the part on x's side of the tangent planes of the surfaces that rays in 14
 * directions meet within r; at least 1/8. Exact for one plane, and for axis-aligned edges and
 * corners through x; within 0.5% for several planes. 1 if no surface is within r along the 14
 * directions, or r is not finite. */
double pmv_ball_fraction(const scene *s, vec3 x, double r);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PM_BALL_H */
