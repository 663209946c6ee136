/* port.h: photon ports, openings that the scene file declares ($.ports) as a hint for photon
 * emission: a quad (a parallelogram: corner, corner + edge1, corner + edge2) or a disc (centre,
 * normal, radius). A port is not a surface: rays do not hit it, nothing renders it, and a scene
 * with ports gives the same images in expectation as without them. Photon tracing aims a share
 * of its photons through the ports (photons/ports.h says how, and why the estimate stays
 * unbiased); this file is the geometry: area, a uniform point, and where a ray crosses it.
 *
 * The loader (load/scene_ports.c) fills scene.ports; a port is then read-only, and these
 * functions are pure and reentrant.
 */
#ifndef RENDER_PORT_H
#define RENDER_PORT_H

#include "base/vec.h"

#ifdef __cplusplus
extern "C" {
#endif

enum { PORT_QUAD, PORT_DISC };

typedef struct port {
    int type;         /* PORT_QUAD or PORT_DISC */
    vec3 corner, e1, e2; /* quad: the points corner + a e1 + b e2, a and b in [0, 1] */
    vec3 c;           /* the centre (quad: corner + (e1 + e2) / 2) */
    vec3 n;           /* unit normal (quad: e1 x e2 normalized; either side is crossed alike) */
    double r;         /* disc: radius */
    double area;
} port;

/* A quad from its corner and edges, a disc from its centre, normal (any length > 0) and
 * radius. Call only with non-degenerate input (the loader checks it). */
port port_quad(vec3 corner, vec3 e1, vec3 e2);
port port_disc(vec3 c, vec3 n, double r);

/* A uniform point of the port (density 1 / area) from (u1, u2) in [0, 1)^2. */
vec3 port_sample(const port *pt, double u1, double u2);

/* Does the ray o + t d (d unit) cross the port at some t > 0? Then 1, with *t and *cos_p =
 * |d . n| (> 0); else 0 (also for a ray in the port's plane). */
int port_cross(const port *pt, vec3 o, vec3 d, double *t, double *cos_p);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PORT_H */
