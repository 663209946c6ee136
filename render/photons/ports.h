/* ports.h: photon emission through photon ports (scene/port.h: openings the scene declares in
 * $.ports), in a defensive mixture with the ordinary emission, so the estimate stays unbiased.
 *
 * WHY. A room lit through a 10 x 10 hole (data/scenes/pinhole_room.json) gets about 4 of
 * 200,000 global photons when photons are emitted by power alone. Aiming a share of them at
 * the hole puts thousands inside, each carrying its true share of the power.
 *
 * THE MIXTURE. A photon of light l leaves x in direction d (for a directional light: from the
 * point x of its emission disc, light.h). The ordinary emission has the density
 *     p_def(l, x, d) = p_l p_x(x) p_d(d | x)
 * (p_l the light's power share, p_x uniform over the light, p_d cosine-weighted about the
 * normal; uniform over the sphere for a point light; a directional light's d is fixed and x
 * uniform over its disc). With a = $.port_fraction (default 0.5, 0 <= a < 1) a photon is, with
 * probability 1 - a, emitted as before (importance emission included, importance.h), and with
 * probability a through a port: a light l with probability q_l, a point x of it uniform as
 * before, a port k with probability w_lk, a point y uniform on port k, d = (y - x) / |y - x|
 * (a directional light: y first, and x where the line through y along the light's direction
 * meets its disc). In solid angle at x that direction has the density t^2 / (A_k cos_k) (t the
 * distance to the port, cos_k the angle to its normal; a directional light: 1 / (A_k cos_k)
 * per unit area of the disc), summed over every port the ray crosses, so the mixture's density
 * is
 *     p(l, x, d) = a q_l p_x(x) sum_k w_lk pdf_k(d | x) + (1 - a) p_base(l, x, d),
 * and a photon's power is the ordinary photon's divided by rel = p / p_def:
 *     rel = a (q_l / p_l) sum_k w_lk pdf_k(d | x) / p_d(d | x) + (1 - a) rel_base,
 * where rel_base is importance.h's rel (1 without importance emission). Every photon of either
 * branch gets this rel (the ordinary ones too: a ray that happens to cross a port is as likely
 * from the port branch), so for any a, any weights and any ports the estimate keeps its mean;
 * rel >= 1 - a bounds a photon's power by 1 / (1 - a) times the ordinary one's. A port photon
 * whose direction the light does not emit into (behind a one-sided light, or a disc point
 * outside a directional light's disc) carries nothing: the ordinary emission gives that
 * direction density 0, and so does the true light.
 *
 * THE WEIGHTS. w_lk is port k's share of light l's estimated flux through the ports, g_lk =
 * the mean over 3 points of the light (a triangle's edge midpoints; a sphere's centre; a point
 * light's position) and 4 of the port (a quad's 2 x 2 Gauss points, a disc's 4 points at
 * r / sqrt 2) of A_k |cos_k| cos_l / (t^2 + A_k) (cos_l: 1 for point and sphere lights; the
 * port's projected area A_k |cos_k| for directional lights), and q_l is proportional to p_l times the fraction of
 * its power that this estimate says passes the ports (at most 1). A light that sees no port
 * has q_l = 0 and only ordinary photons. Good weights lower the noise; no weight changes the
 * mean.
 *
 * BOUNCES. Light that enters an opening after a bounce (pinhole_room: about a third of what
 * enters the hole) cannot be aimed at by emission: only the ordinary photons carry it, a handful,
 * each with the power of thousands of port photons, and the room's estimates read them as
 * splotches (pinhole_room with emission ports alone: walls -18% to +42% over 6 seeds, against
 * -2.4% to +2.3% without ports). So the diffuse bounces aim too: at a point x on a port's lit
 * side (the side its lights' weight comes from, ports_build) that sees the port's centre above
 * its horizon, a diffuse photon is scattered with probability a toward a uniform point of one
 * such port (chosen by A_k |cos_k| / (t^2 + A_k)), else cosine-weighted, and its weight
 * f cos / p uses the mixture's density p = (1 - a) cos / pi + a sum_k w_k t^2 / (A_k cos_k). A
 * point on the dark side (inside the room) never aims out through the port. Unbiased for any
 * share a >= 0 that depends only on x and the photon's path so far (each bounce's weight is over
 * the density it was drawn from).
 *   The share falls with the photon's weight. A photon whose bounce is drawn from the cosine
 * part and misses the port is weighted 1 / (1 - a) (2 at a = 0.5), and with one fixed a a
 * photon that stays on the lit side doubles at each bounce: door_ajar's light room (its light
 * and the lit side of the door) held photons of 524 times the mean power after a few bounces,
 * and one pass of seed 6 read +85% over the image (a splotch 20 times the reference on the far
 * wall, through the gathers). So a bounce aims with a / K, K the product of the photon's
 * earlier bounce weights when above 1 (ports_bounce_share); each bounce's weight is at most
 * 1 / (1 - a / K), so K grows by at most a / (1 - a) a bounce (K <= 1 + n a / (1 - a) after n
 * bounces: 21 at n = 20, against 2^20). Not aiming at all after a first miss (K > 1: a = 0)
 * bounds K by 2, but then light that enters the opening after two bounces is carried by rare
 * photons again: pinhole_room read -2.5 to -5.7% on 6 seeds.
 *
 * MEDIA. In a scene with participating media (volume.h) one pass traces the surface map and the
 * volume map together (photon_walk.c's emit_media), and it mixes the same way: after the
 * ordinary photon (light l by power p_l, drawn from the photon's own stream), with probability a
 * (the stream's next number) a port photon replaces it (light by q_l, port by w_lk, as above),
 * and either photon's power is the light's power / p_l divided by the same rel = a r + (1 - a)
 * (r = ports_ratio; no importance emission in media). The mixture's density is over the
 * emission only, before any flight: the free flights, scattering events, surface bounces and
 * stores that follow are the ordinary tracer's, so every volume and surface photon keeps its
 * mean. The volume pilot of the plan (plan.c, plan_media) emits the same way. Not done in media:
 * the aimed diffuse bounces (BOUNCES: a media pass samples its materials by material_sample,
 * whose lobe probabilities ports_scatter would have to re-weigh) and the volume-caustic pass
 * (its projection maps). The camera probe (ports found by a camera probe, below) runs in scenes
 * with media too: its light connections and its threading rays pass null surfaces (a medium's
 * invisible boundary, such as the quad that closes sun_window_fog's window) as if they were not
 * there.
 *
 * WHERE. The surface tracer's global pass (photon_walk.c, which calls ports_mix after its own
 * emission and ports_scatter at diffuse bounces) and the photons of its pilot, whose rel is computed the same way so they can join
 * the pass (pilot_photons_joining); the media tracer's non-caustic pass (volume.c, which calls
 * ports_mix_media, MEDIA above). The caustic passes keep their projection maps.
 *
 * Ownership: ports_build fills a photon_ports with malloc'd arrays, ports_free frees them; a
 * built table is read-only and may be used from any number of threads.
 */
#ifndef RENDER_PORTS_H
#define RENDER_PORTS_H

#include <stddef.h>
#include <stdint.h>

#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct photon_ports {
    const scene *s;
    int on;         /* 0: the scene has no ports, a = 0, or no light sees a port */
    double a;       /* the share of photons emitted through the ports */
    int nl, np;
    double *wcdf;   /* nl x (np + 1): per light, the cumulative port weights w_lk (0 .. 1) */
    double *q_p;    /* per light: q_l / p_l */
    distrib1d light; /* lights by q_l */
    double flux;    /* sum_l p_l F_l: the share of the lights' power the weights say passes the ports */
    signed char *side; /* per port: +1 or -1, the side of its normal the light comes from; 0: none */
} photon_ports;

/* 0 (pp->on says whether ports are used), or PM_ENOMEM. */
int ports_build(photon_ports *pp, const scene *s);
void ports_free(photon_ports *pp);

/* sum_k w_lk pdf_k(d | x) / p_d(d | x) times q_l / p_l: the port branch's density over the
 * ordinary one for the photon (l, x, d); 0 when no port is crossed, and also when the
 * ordinary emission cannot give it (so callers drop such photons). */
double ports_ratio(const photon_ports *pp, int l, vec3 x, vec3 d);

/* The port branch: a photon from uniform numbers (ul, uk: the light and the port; u[0..1]
 * the point on the light, u[2..3] the point on the port). Returns 1 with the light, origin,
 * origin's normal (zero for point and directional lights), direction; 0 when the photon
 * carries nothing. */
int ports_sample(const photon_ports *pp, double ul, double uk, const double u[4], int *l, vec3 *x, vec3 *n,
                 vec3 *d);

struct pass_ctx;
/* A diffuse bounce at x (nsh: the shading normal on the side the photon leaves from): with
 * probability a toward a uniform point of a port that x sees from the port's lit side (BOUNCES
 * above), else cosine-weighted about nsh, with u1, u2 (and one more number from g when some port
 * is eligible). The direction in *nd; returns cos / pi over the mixture's density there
 * (multiply the cosine-sampled weight pi f by it), 0 when the direction carries nothing. With
 * no eligible port: the cosine direction and 1. aim: the product of the photon's earlier
 * returns (1 at its first bounce), which lowers the share to ports_bounce_share (BOUNCES). */
struct rng;
double ports_scatter(const photon_ports *pp, vec3 x, vec3 nsh, struct rng *g, double u1, double u2, double aim,
                     vec3 *nd);
/* The share a bounce aims with, for the ports' share a and the photon's aim so far (BOUNCES). */
static inline double ports_bounce_share(double a, double aim) { return aim > 1 ? a / aim : a; }

/* The photon walk's hook (photon_walk.c, surface passes): after its own emission of photon i (*li, *p, *n, *d, *power, *rel),
 * with probability a (Halton dimension 5) replace the photon by a port photon; either way set
 * *rel to the mixture's (above). A pilot (c->o->pilot) keeps its own photon and only gets the
 * rel. */
void ports_mix(const struct pass_ctx *c, uint64_t i, int *li, vec3 *p, vec3 *n, vec3 *d, rgb *power,
               double *rel);

/* The media tracer's hook (photon_walk.c emit_media, MEDIA above): after its ordinary photon
 * (*li, *p, *n, *d; *power the light's power / p_l), with probability a (the next number of g)
 * a port photon replaces it; either way *power is divided by the mixture's rel. 0: the photon
 * carries nothing (a port direction the light does not emit into). */
int ports_mix_media(const photon_ports *pp, struct rng *g, int *li, vec3 *p, vec3 *n, vec3 *d, rgb *power);

/* The plan's reason (the text in "photon ports: on (...)"): the ports, the fraction and the
 * estimated share of the power through them, or why they are not used. */
void ports_describe(const photon_ports *pp, const scene *s, char *buf, size_t cap);

/* For the plan (photon_mapping/plan.c): 1 when the global pass will aim through ports, 0 when
 * not (no ports, port_fraction 0, or no light faces them), with the reason in buf (ports_describe); PM_ENOMEM. The plan prints
 *   photon ports: on (0.5 of the global photons aimed through 1 port ($.ports[0] quad of area
 *   100 at (500, 300, 500)): about 0.0247% of the lights' power passes them ...) */
int ports_plan(const scene *s, char *buf, size_t cap);

/* ---- ports found by a camera probe (ports_find.c) ------------------------------------------------
 *
 * WHY. A scene seldom declares its openings. Where the camera sees light that came through a
 * small opening (pinhole_room: the room behind a 10 x 10 hole), the camera's own paths show
 * where: their light connections that pass all pass the opening.
 *
 * THE PROBE. Camera paths (fixed streams of the scene's seed; BSDF sampling through mirrors and
 * glass, up to PF_DEPTH diffuse vertices, PF_LIGHTS light connections at each, as next-event
 * estimation makes them). A connection that reaches the light makes a light path the camera
 * sees: a carrier, weighted by what it carries (luminance). Paths are traced until PF_CARRIERS
 * carriers are found or PF_PATHS_MAX paths traced, in rounds (PF_ROUND paths, then twice as many
 * each time, up to PF_ROUND_MAX); after a round in which
 * at least PF_MAX_PASS of the connections pass so far, the probe stops (most of what the camera sees is lit in
 * the open: no opening to find). Otherwise every carrier's segments (vertex to vertex,
 * the last to the light point) are tested, from the camera's end, for a thread: rays from the
 * segment's camera end toward points around its far end, offset across it by L 2^j / 512
 * (j = 0 .. PF_LEVELS - 1, L its length) in two opposite pairs, each pair until both its rays
 * are blocked. A pair threads an opening when its two blockers are on nearly parallel surfaces
 * (normals within 45 degrees) and the segment crosses one of their walls short of its end,
 * between the two blocks: there is wall on both sides of the light's way. The crossing is the
 * farthest from the camera's end that either pair gives (the opening nearest the light: the
 * slit between a door ajar and its frame, not the doorway in front of it). A carrier's first
 * threading segment gives its crossing point and the wall's normal.
 *
 * THE FIT. Crossings are grouped by single linkage (a crossing joins a group when it lies within
 * PF_CLUSTER of the scene's bounding radius of one of its crossings, their normals within 25
 * degrees: a long slit is one group). Each group's plane is its carriers' weighted mean crossing and
 * mean normal; every carrier's segment is cut with that plane again, and the port is the
 * smallest-area rectangle (over 32 rotations) that holds those points taken as uniform on it,
 * from the order statistics PF_TRIM n and n - 1 - PF_TRIM n of each side (a stray crossing
 * does not stretch it; E[x_(j)] = A + (B - A) j / (n + 1) for n uniform points on [A, B]),
 * then grown by PF_GROW of its side at each edge that THE RIM (below) does not give. Why grown: the crossings are not uniform (few
 * carriers pass near an opening's edge), so the fit falls short of the opening (sun_window's
 * 40 x 40 window was fitted 40.2 x 38), and light through the strip it leaves is carried by the
 * ordinary photons alone, each with about 1 / (a r) times a port photon's power (r the port's
 * gain): there 200 to 300 times. In sun_window_fog's passes of 2,000 volume photons one of them
 * lit the fog at +430% (pass 10 of seed 1 at --time 10), and the mean of 16 passes read the
 * dim fog +25%. A port too large only aims a few photons at the wall around the opening. Measured
 * at --time 10 (pm at the defaults, 2 threads, mean MSE of seeds 1 and 2 against the references,
 * growth 0 / 0.05 / 0.1 of the side at each edge; by hand at 92f5ebb): sun_window_fog 6.0 / 2.8
 * / 3.1 e-4, sun_window 3.7 / 3.8 / 3.9 e-6, pinhole_room 1.5 / 1.6 / 1.3 e-10, lamp_shade 3.3
 * / 3.3 / 3.0 e-3 (two seeds: read a factor 1.5 as noise); with 0.1 the largest power of a volume
 * photon in that pass was 1.2 times the mean, against 200 before.
 *
 * THE TURN. The rectangle's turn about the normal is tried at 32 angles and at the turn of the
 * opening's rim: each crossing votes for the turn of the edge (in the port's plane) of its wall
 * triangle nearest to it, and the most-voted of at most PF_TURNS turns is the rim's (an opening
 * in a mesh is bounded by its triangles' edges). The rim's turn is taken when its area is at
 * most PF_TURN_SLACK times the smallest of all, else the smallest of all (a wall of spheres, or
 * one whose edges do not bound the opening). Why: the smallest area alone follows the
 * crossings' noise, and turned sun_window's fit by 8.4 degrees (seed 1), lamp_shade's by a few:
 * the opening's corners were left out of the port and lit by ordinary photons alone (THE FIT
 * says what that costs). Why a vote: taking the smallest area among every edge the crossings'
 * triangles have fails where those triangles have other edges (tests/data/sun_window_turned.json,
 * the window turned 30 degrees in a wall of four quads: ports turned 15.3, 17.7 and 37.9
 * degrees on seeds 1-3; by the vote 30.00 on all three). A square turned by t has 1 + sin 2t
 * times its area, so the slack passes rims up to about 6 degrees off the crossings' best.
 *
 * THE RIM. Where the rim's turn is taken, each side of the rectangle is moved to the wall by
 * rays: at PF_RIM_PROBES points along the side, between the rectangle's middle (open) and a
 * point PF_RIM_REACH of its size beyond the side (wall), the edge of the wall is found by
 * bisection (40 steps; a point is wall when a segment through the plane, along its normal, of
 * a thousandth of the rectangle's size either way hits a solid surface), and the side goes to
 * the farthest of the probes' edges. Such a side is the opening's edge and is not grown; a side
 * whose probes find no edge (the middle covered, a pane in the opening, or no wall within
 * reach) keeps the crossings' fit and its growth. Why: the crossings' fit falls short where few
 * carriers pass near an edge, and with the right turn the turned window's fit still left 2 of
 * its 40 out on one side (seeds 2 and 3); the rays give sun_window, lamp_shade, pinhole_room,
 * the turned window and the media hole their openings exactly, so no photon is aimed at the
 * wall around them (the growth of 5% at each edge aimed 17% of the port's photons there).
 *
 * THE DECISION. A group becomes a port when it has at least PF_MIN_THREADS carriers, carries
 * at least PF_MIN_SHARE of the carried light, and ordinary emission sends at most 1 /
 * PF_MIN_GAIN of that share of the lights' power through it (ports_build's estimate): aiming
 * there then puts at least PF_MIN_GAIN times as many photons where the camera looks. Why so
 * large a share: the photons that reach the camera's region some other way (another opening,
 * a bounce that misses the port) keep only 1 - a of their density, so they carry 1 / (1 - a)
 * = 2 times their power (and again at a bounce on the lit side), and where they carry much of
 * the light their noise outweighs the gain. Measured on door_ajar (pm, 16 x 16, 1024 spp, seeds
 * 1-4, about 4.5 CPU-s a render, against the path-traced reference), where the probe's group
 * over the door's top edge threads 50-62% of the carried light (the rest comes through the
 * slit below it and after bounces): with a port declared over the door's top the whole image
 * read -4.4..+18.2% (pixels' mean squared relative error 0.013-0.32), without one +4.0..+7.2%
 * (0.011-0.018). On pinhole_room (72-95%) the found port gains (test_render_ports_find.c). At most
 * PF_MAX ports, the largest shares first. A found port is used exactly as a declared one
 * (the plan hands the passes a copy of the scene with it), with the scene's port_fraction:
 * the defensive mixture keeps every estimate unbiased whatever the probe found, so a wrong or
 * poor port costs noise, never bias.
 */
#define PF_PATHS_MAX 65536
#define PF_ROUND 256      /* the first round; each next one twice as many, at most PF_ROUND_MAX */
#define PF_ROUND_MAX 2048
#define PF_CARRIERS 256
#define PF_DEPTH 3
#define PF_LIGHTS 4
#define PF_LEVELS 9
#define PF_MAX_PASS 0.3
#define PF_CLUSTER 0.05
#define PF_TRIM 0.03
#define PF_GROW 0.05
#define PF_TURNS 64
#define PF_TURN_SLACK 1.2
#define PF_RIM_REACH 0.25
#define PF_RIM_PROBES 8
#define PF_MIN_THREADS 8
#define PF_MIN_SHARE 0.65
#define PF_MIN_GAIN 4
#define PF_MAX 4

typedef struct port_found {
    int n;              /* ports kept */
    port p[PF_MAX];
    double share[PF_MAX]; /* the share of the carried light that threads port k */
    double flux[PF_MAX];  /* the share of the lights' power ordinary emission sends through it */
    int count[PF_MAX];    /* carriers that thread it */
    /* Evidence, for the plan's line. */
    int ran;            /* 0: not run (ports declared, find_ports false, media, no light) */
    long paths;
    unsigned long long connections, passed; /* light connections, and those that passed */
    long carriers, threaded, groups;        /* carriers, those that thread, groups of them */
    char why[360];      /* the evidence in words: what was found and kept, or why not */
} port_found;

/* Run the probe on s (not run when s declares ports, $.find_ports is false, or s has no
 * light) with streams of seed; f->why says what it found. 0, or PM_ENOMEM. */
int ports_find(const scene *s, uint64_t seed, port_found *f);
/* *copy = *s with f's ports as its ports (nothing is allocated; copy shares s's arrays), for
 * the passes that should aim through them; returns copy, or s when f found none. */
const scene *ports_found_scene(const scene *s, const port_found *f, scene *copy);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_PORTS_H */
