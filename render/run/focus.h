/* focus.h: camera samples aimed at an opening the camera sees in a sliver of a pixel.
 *
 * WHY. Where the camera looks through a small opening (pinhole_room's hole in the roof,
 * lamp_shade's hole in the shade), the pixels at the opening see, in a sliver of their area,
 * a region many times brighter than the rest of the pixel. A pixel's value is the mean of its
 * samples over its area, so its noise is that of a rare bright hit: for a sliver of a fraction
 * a of the pixel, radiance Lh there and Lb around it, a uniform sample's variance is about
 * a (1 - a) (Lh - Lb)^2. Those few pixels were most of the error of the renders that aim
 * photons through the opening (pinhole_room: 86% of the squared error in 2 of 64 pixels).
 *
 * THE FOOTPRINT. The integrator names the openings it aims photons through (the plan's photon
 * ports, ports.h, declared or found). Each port is projected onto the film (a quad's four
 * corners; a disc as the square around it); a port with a corner behind or beside the eye is
 * left out. In each pixel the projection is clipped to the pixel's square (a convex polygon of
 * at most 8 corners). A pixel takes a focus where that polygon F covers a fraction a of it with
 * 0 < a <= FOCUS_MAX_COVER; where more ports cover it, the first (the plan's order) is taken.
 *
 * THE SAMPLES. A focused pixel's sample maps its stratified point (u, v) in [0, 1)^2: for u <
 * FOCUS_PLAIN it is the uniform point (u / FOCUS_PLAIN, v) of the pixel, else a uniform point of
 * F (a fan triangle of F chosen by area with the rest of u, uniform in it by (u', v)). The
 * density of the mixture over the pixel is q(x) = FOCUS_PLAIN + (1 - FOCUS_PLAIN) [x in F] / a,
 * and the sample's radiance is multiplied by 1 / q(x): its mean over the pixel is the pixel's
 * value exactly, whatever the port and wherever it is (a defensive mixture: a wrong footprint
 * costs at most 1 / FOCUS_PLAIN times the variance, never bias). The strata stay whole: the
 * count of samples in F is fixed by the strata, so the sliver's part of the pixel is nearly
 * deterministic, and a uniform sample that lands in F carries about a / (1 - FOCUS_PLAIN) of
 * its radiance. For a << 1 the variance falls from about a Lh^2 to about (a Lh - Lb)^2.
 *
 * Pure and reentrant once built; the table is read by every thread.
 */
#ifndef RENDER_FOCUS_H
#define RENDER_FOCUS_H

#include "scene/camera.h"
#include "scene/port.h"

#ifdef __cplusplus
extern "C" {
#endif

#define FOCUS_MAX_COVER 0.5 /* a footprint larger than this part of its pixel is not aimed at */
#define FOCUS_PLAIN 0.5     /* the share of a focused pixel's samples that stay uniform */
#define FOCUS_VERTS 8

typedef struct focus_poly {
    int n;                            /* corners, counter-clockwise, in the pixel's [0, 1]^2 */
    double x[FOCUS_VERTS], y[FOCUS_VERTS];
    double area;                      /* a: its part of the pixel */
    double cum[FOCUS_VERTS];          /* fan triangles' cumulative areas over area (last 1) */
} focus_poly;

typedef struct film_focus {
    int width, height;
    int *index;        /* per pixel, row-major: -1, or the pixel's polygon in polys */
    focus_poly *polys;
    int npolys;
} film_focus;

/* The footprints of the ports on the film of c. 0 (f->npolys may be 0), or -1: out of memory. */
int focus_build(film_focus *f, const camera *c, const port *ports, int nports);
void focus_free(film_focus *f);

/* The film position (*px, *py) of the sample at stratified point (u, v) in [0, 1)^2 of pixel
 * (x, y), and its weight: 1 where the pixel has no focus (or f is NULL), never 1 where it has
 * one (at most 2/3 in the footprint, 2 outside it). */
double focus_film_point(const film_focus *f, int x, int y, double u, double v, double *px, double *py);

/* The weight 1 / q of the pixel-local point (lx, ly) of a focused pixel's polygon p (as above). */
double focus_weight(const focus_poly *p, double lx, double ly);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_FOCUS_H */
