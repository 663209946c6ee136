/* gather_guide.h: the photon mapper's gather guide: final-gather rays aimed at an opening into a
 * lit region (or, in a scene with photon ports, at a bright patch the light lands on), weighted
 * by the mixture's density so the gather's mean is unchanged.
 *
 * WHY. In a room lit through an opening (pinhole_room: a 10 x 10 hole in the roof of a closed
 * room, the lit big room above it), about a third of the light the walls gather comes through
 * the hole, which covers 1e-4 to 3.5e-4 of their cosine-weighted hemisphere, and about 4 of
 * 200,000 global photons get in, so the lookups inside find nothing and the gathers compute the
 * light themselves, level after level (photonmapper.c, gather: "Compute its light instead"): a
 * cosine ray finds the hole once in thousands and that light is carried by rare, bright samples.
 * The guide aims a share a = GATHER_GUIDE_SHARE of the gather rays from every point that faces
 * the opening at a uniform point of a disc of radius r around its centre c, the disc facing the
 * point; the others are cosine-distributed as before.
 *
 * WHY THE ESTIMATE STAYS UNBIASED. A direction d is weighted by (cos / pi) / p(d) relative to a
 * cosine sample, p being the mixture's density, what either branch would have drawn d with:
 *     p(d) = a p_disc(d) + (1 - a) cos / pi,
 * p_disc = distance^2 / (disc area x cos at the disc) on the disc, 0 off it. p > 0 wherever the
 * integrand is (the cosine branch keeps a share 1 - a of every direction), so the mean is the
 * same for any disc, right or wrong: a wrong one costs noise only, at most 1 / (1 - a) = 1.25
 * times a cosine ray's weight for the light that does not come through it. Every level of a
 * recursive gather is guided: the room's own light then weighs up to 1.25^level, a cost the
 * hole's light more than pays back (measured below). An aimed direction below the shading
 * hemisphere gets weight 0 (the cosine branch never draws it: that part of the disc is behind
 * the surface and carries no cosine-weighted light). tests/test_render_gather_guide.c checks
 * E[f/p] against closed forms (a disc's form factor, on and off its axis and at the horizon).
 *
 * THE PILOT (gather_guide_make; after the precomputed irradiance; fixed streams, each point its
 * own, so the same for any thread count and on every process): guide_points' camera-path points
 * (first diffuse hits and one cosine bounce), at most GG_CELL_POINTS per cell of side (largest
 * side / GG_RES), at most GG_MAX_JOBS in all, one jittered probe per stratum of GG_G x GG_G over
 * the cosine sample's (u1, u2) (1e-3 of the cosine measure each): the value of a gather ray in
 * that direction, pi lum(f beta L(y)), L(y) read from the precomputed irradiance where a lookup
 * finds a record, plus y's light sample, as the gather does (the caller's probe->read); where it
 * finds none, y's light sample plus the light y's own cell gathers (GG_BOUNCES rounds of the
 * cells' mean probe values: a small radiosity solve on the pilot's rays, so the room's own
 * bounced light counts). Probes that read the map and carry over 1/GG_OUTLIER of their point's
 * light are rays through a narrow opening into a lit region: the point nearest all their lines
 * (least squares, then again without the lines 3 spreads away) is its centre, r = GG_AP_SPREAD
 * times their RMS distance from it. (The GG_* constants are gather_guide.c's.)
 *
 * WHO AIMS. Only points on the opening's dark side: the centre must lie more than r ahead of x
 * along `lit`, the mean direction of the fitted lines (from the starved points through the
 * opening toward the light they read), besides being in front of x's surface and farther than r.
 * Why: through the opening a point on the LIT side sees the dark room, whose light is what the
 * guide is not for; its aimed rays carry almost nothing, and its cosine rays then weigh
 * 1 / (1 - a) = 1.25: on pinhole_room the camera's own view of the lit big room through the hole
 * (a quarter of the walls' light, the region's largest noise) aimed a fifth of its gather rays
 * back down into the small room. A point in the opening's own plane (the small room's ceiling
 * around the hole: the disc straddles its horizon) cannot see through it at all; its aimed rays
 * graze the plane with weights near 0. Unbiased either way (the share only chooses the
 * mixture); this only stops spending rays where they cannot find the opening's light.
 * Measured (pinhole_room, test config: 8x8, 16384 spp, one gather and one secondary ray): aimed
 * rays 730,406 -> 608,794 at seed 3 (a sixth were wasted), CPU the same (~21 s); the walls'
 * region against the reference over photon seeds 1-12: -0.64..+5.48% (mean +1.65%, sd 1.9%)
 * -> -3.20..+3.97% (mean +0.67%, sd 2.0%): the spread is unchanged within its own noise (the
 * walls' noise is not mostly in the lit side's gathers).
 *
 * DECISION. The camera points must be photon-starved first (at least GG_STARVED of them find no
 * precomputed irradiance on their side, probe->found; elsewhere the gathers read the map, and
 * the pilot, a few CPU-seconds, is not run); then on when at least GG_MIN_LINES such rays meet
 * within 2% of the scene's size. Forced by photon_mapping.gather_guide.
 *
 * MEASURED on pinhole_room (8x8, 4096 spp, gather_rays 1, secondary_rays 1, light guide on; a
 * build that splits each sample's light by where it was scored, per-sample variance of the
 * walls' region mean): the light through the hole went from 2.9% (x's own ray) and 3.0% (deeper
 * rays) relative standard error to 0.3% and 0.3%, the room's own light from 1.3% and 1.4% to
 * 2.0% and 2.2%: the gathers' variance 2.4x lower. The camera's own view of the lit room through
 * the hole (a few hundredths of a pixel, a quarter of the walls' light) is not a gather's and is
 * untouched. Per-cell direction tables (guide.h's G x G warp of (u1, u2), learned from these
 * probes) were measured and are not used: one probe per stratum finds a 1e-4 hole a tenth to a
 * third of the time, a cell's table is the sum over points that see the hole in different
 * strata, and the defensive share's weights raised the room's own noise (walls 2.0% -> 2.6% with
 * tables at the first level, 5.0% at every level) more than they took from the hole's.
 *
 * BRIGHT PATCHES. Where the scene has photon ports (declared, or found by the plan's probe:
 * gather_guide_probe.ports), its light comes in through openings and lands in bright patches
 * (the sun's patch on a floor under a window, a lamp shade's spot on the ceiling) that light the
 * rest by reflection; the map is dense there, so the camera points are not photon-starved and
 * the rule above would not run the pilot. With ports it runs anyway, and when no opening fits,
 * the bright rays' hits (weighted by their light; again without the hits 3 RMS away) are a
 * patch: centre c their mean, r = GG_PATCH_SPREAD times their RMS distance from it, kept when r
 * is at most GG_PATCH_MAX of the scene's size and the bright rays carry at least GG_PATCH_SHARE
 * of the probed light. The gathers then aim at a disc (c, r) as at an opening, from every point
 * in front of it (lit is zero: a patch has no dark side). Unbiased as above (any disc). Without
 * ports (cornell_box, cornell_spheres, water_caustic, door_ajar) nothing changes: the pilot is
 * not run and the line says "no photon ports: no bright patch is looked for". MEASURED
 * (sun_window, 16 x 16, 1024 spp, seeds 1-3, against its reference; the reference's own noise
 * subtracted): tests/test_render_hard_scenes.c.
 *
 * A PATCH BEHIND THE PORT. A patch whose light comes through the port is not kept: of the light
 * of the bright rays whose hits are the patch's (within 3 RMS of its centre), the share whose
 * segment from its point to its hit crosses the aim port (gather_guide_probe.port) is found, and
 * at GG_PATCH_THROUGH (half) or more the gathers aim at the port instead (PORTS AS OPENINGS):
 * the patch is then the bright inside of what the port opens onto, seen through it, and a disc
 * around the patch (lamp_shade: radius 54 around the lamp inside the shade) spends most of its
 * share on directions that meet the shade's outside, where the port's disc (radius 7) aims only
 * through the hole, and only from its dark side. A patch the light reaches by reflection inside
 * the camera's own room (sun_window's on the floor: 0% through the window) is kept. MEASURED
 * (lamp_shade, pm at its defaults, 16 x 16, --time 10, 2 threads, seeds 1-6, MSE against
 * data/reference-hard; by hand on a quiet machine, on 7b34e84 + this rule): 4.1, 4.9, 8.0, 5.6,
 * 6.8, 8.1 e-4 with the patch, 7.9, 7.7, 8.3, 7.0, 8.6, 10.0 e-5 at the port (the pilot finds
 * 100% through it); pinhole_room and sun_window unchanged (their lines say why). Shown by its
 * test (tests/test_render_pilot_size.c): the closed shade's inside is seen only through its hole.
 *
 * THE CHEAP TEST. In a scene with ports whose camera points are not photon-starved the pilot
 * runs only to look for a patch (or an opening), and where the map fills the room (pinhole_room,
 * whose found port puts thousands of photons inside) it finds neither, at 786,432 probes (about
 * 1.8 CPU-s). So first the same rules run on every GG_CHEAP_EVERY-th (4th) of its points with
 * GG_CHEAP_G^2 (64) probes each, on their own streams (about 1/64 of the cost); when what they
 * find misses both bounds by a factor GG_CHEAP_MARGIN (2): the bright rays fit a meeting point
 * but spread over more than twice an opening's limit, and their hits fit a patch but spread over
 * more than twice its limit or carry under half its share, the pilot is skipped and the line
 * says so with the figures. Where the cheap pilot sees too little to fit (too few bright rays),
 * or either figure is within the margin, the full pilot runs as before: the guide it finds, and
 * so the images, do not change (sun_window, lamp_shade: byte-identical). pinhole_room (16 x 16,
 * 4 spp): bright rays meeting within 94 (an opening: 20), hits over radius 1090 (a patch: 300);
 * 2.82 CPU-s before, 1.64 after, the same image.
 *
 * THE PILOT'S SIZE. Where it only looks for a bright patch (the camera points are not starved,
 * the guide not forced), its probes serve the render's gather rays, so the full pilot probes at most
 * the render's camera samples' worth (width x height x spp of the camera it is made for; a probe
 * costs about half a camera sample), GG_G^2 probes a point, between GG_MIN_JOBS (96) and
 * GG_MAX_JOBS (768) of the points picked (evenly, as they are picked): 768 points (786,432
 * probes) from 786,432 camera samples up, 96 (98,304 probes) at 98,304 and below (32 x 32 x 96).
 * When the smaller pilot's answer rests on fewer than GG_CLEAR_LINES (64) bright rays (a patch's
 * hits after its outliers are dropped, else all bright rays), the full pilot runs on all the
 * picked points, on the same streams, so its answer is the 768-point pilot's (at the cost of the
 * smaller pilot on top of it): lamp_shade at 96 x 96 x 16 found a patch of radius 53 on 29
 * rays with 144 points, and now finds the full pilot's (radius 111, 563 rays); the line says so.
 * The cheap test keeps all the picked points, and so does a pilot looking for an opening (starved
 * points: at 96 points pinhole_room_no_ports's 8 x 8 test found 12 bright rays, too few). A
 * render in passes (--time, --passes) is sized by its first pass (the pilot runs once, before
 * it). Measured by hand on 84ae036 with this rule, 16 x 16 x 16 (the scenes' own size): 96
 * points find the same patch as 768 on lamp_shade (centre within 7 of (199, 152, 200), radius
 * 104-106 against 109) and sun_window (within 1, radius 33.7-34 against 35.1), photon seeds
 * 1-3; at 48 lamp_shade's bright hits were too few to fit one. The pilot at 32 x 32 x 4:
 * lamp_shade 0.96-1.55 -> 0.15-0.19 CPU-s, sun_window 1.10-1.36 -> 0.17-0.19.
 * PORTS AS OPENINGS. Where the scene has a photon port (declared, or found by the plan's probe)
 * and the pilot finds neither an opening nor a patch, or its cheap test rules both out, the
 * gathers aim at the port itself (gather_guide_port): a disc around it (a disc port's own; a
 * quad's circumscribed one), aimed at from its dark side, lit being the port's normal toward the
 * side that holds at least GG_PORT_SIDE of the lights' power (by luminance; else zero, and every
 * point in front aims). Why the pilot misses it: in pinhole_room the found port fills the small
 * room with photons, so the points are not starved, and the bright rays are of two kinds, through
 * the hole and onto the lit patch under it: they meet within 161 (an opening: 20) and their hits
 * spread over 1,080 (a patch: 300). The port is known without a fit. Unbiased as above (any
 * disc). Among the shipped scenes only pinhole_room and pinhole_room_ports change (sun_window
 * and lamp_shade keep their patches; sun_window_fog has media). MEASURED (pinhole_room 96 x 96,
 * 64 spp, seeds 1-3, against data/reference/et96): the squared error of the pixels off the lit
 * patch and the hole 3.1e-8, 1.4e-8, 3.1e-8 -> 4.4e-9, 4.3e-9, 4.4e-9 (4.7x lower on their
 * mean) at the same CPU time (2.65-3.31 -> 2.87-3.07 s); the patch's, which is its direct light
 * (the same with global=false), and the hole's, the camera's view of the big room, unchanged.
 * LIMITS. One opening: rays through two are fitted as one, or, if they do not meet, none
 * (unbiased either way). The light samples at the gather hits are the light guide's (guide.h).
 * The caller turns it off (off_why) with media (the probes do not march), without a final
 * gather, and in a partitioned render-mpi (the probes would read one process's records).
 *
 * OWNERSHIP AND THREADS. A gather_guide is plain data owned by its caller (the photon mapper's
 * state); it owns no memory today, gather_guide_free only resets it. After gather_guide_make it
 * is read-only: gather_guide_share, _pdf and _direction may be called from any thread.
 */
#ifndef RENDER_GATHER_GUIDE_H
#define RENDER_GATHER_GUIDE_H

#include <stddef.h>

#include "guiding/guide.h"
#include "base/rng.h"
#include "scene/scene.h"
#include "base/vec.h"

#ifdef __cplusplus
extern "C" {
#endif

#define GATHER_GUIDE_SHARE 0.2 /* a: the share of a facing point's gather rays aimed at the disc */
#define GG_PORT_SIDE 0.9     /* PORTS AS OPENINGS: a port's lit side holds this share of the power */

typedef struct gather_guide {
    int on;           /* the plan's decision (forced on counts, with or without an opening) */
    int aim;          /* 1: an opening was found; gathers aim a share at (centre, radius) */
    vec3 centre;      /* the disc's centre */
    double radius;    /* the disc's radius */
    vec3 lit;         /* unit: the side the opening's light comes from (the pilot's lines through
                       * it, WHO AIMS); zero: not known, every point in front may aim */
    char reason[1280]; /* the decision and its evidence ("on (...)", "off (...)") */
    int stat_aimed;   /* a stats.h counter of aimed directions, or -1 (none) */
} gather_guide;

/* What a pilot probe's gather ray found (gather_guide_probe.read). */
typedef struct gather_guide_read {
    double value;  /* pi lum(f beta Lo): the ray's light as the gather reads it */
    double weight; /* pi lum(f beta): what the light gathered around y is multiplied by */
    int found;     /* 1: the precomputed irradiance answered at y */
    vec3 y, ny;    /* the diffuse hit and its normal on the ray's side */
} gather_guide_read;

/* The caller's view of its photon map, for the pilot. Both are called from several threads at
 * once and must not count the lookups they make as the render's. */
typedef struct gather_guide_probe {
    void *user;
    /* 1 when the precomputed irradiance answers at h seen from wo (0: photon-starved). */
    int (*found)(void *user, const scene *s, const hit *h, vec3 wo);
    /* A gather ray from pt in the unit direction d (above pt's surface), followed through
     * specular surfaces to a diffuse hit and read there as the gather reads it (g: the probe's
     * stream, for the light sample). 0 when it finds no diffuse surface or f is 0. */
    int (*read)(void *user, const scene *s, const guide_point *pt, vec3 d, rng *g, gather_guide_read *out);
    /* 1: the scene has photon ports (declared, or found by the plan): a bright patch is looked
     * for even where the camera points are not photon-starved (BRIGHT PATCHES). */
    int ports;
    /* The port the gathers aim at when the pilot finds neither (PORTS AS OPENINGS), or NULL. */
    const port *port;
} gather_guide_probe;

/* An empty guide (off, nothing aimed) whose aimed directions are counted by the stats.h counter
 * "Photon mapping/Gather rays aimed at the opening (gather guide)". */
void gather_guide_init(gather_guide *gg);
/* Decide the guide for scene s and find its opening (see THE PILOT, DECISION). force is
 * PLAN_AUTO/ON/OFF (photon_settings.h); off_why, when not NULL, is why the caller cannot use it
 * (the reason then says so and no pilot runs). 0, or PM_ENOMEM with a message in err. */
/* THE PILOT'S SIZE: how many points the full pilot probes for the render s's camera is set for. */
size_t gather_guide_pilot_points(const scene *s);

int gather_guide_make(gather_guide *gg, const scene *s, int force, const char *off_why,
                      const gather_guide_probe *probe, char *err, size_t errcap);
void gather_guide_free(gather_guide *gg);
/* PORTS AS OPENINGS: aim gg at the disc around pt (on, aimed), lit from the lights' side of it;
 * what gets the words for the plan's line, starting "; so the gathers aim at the photon port". */
void gather_guide_port(gather_guide *gg, const scene *s, const port *pt, char *what, size_t cap);
/* The unit side of pt's plane that holds at least GG_PORT_SIDE of the lights' power (luminance;
 * an infinite light counts on both sides), or zero; *share: the larger side's share. */
vec3 gather_guide_port_lit(const scene *s, const port *pt, double *share);

/* The share a of x's gather rays aimed at the opening: GATHER_GUIDE_SHARE when one was found, it
 * is in front of x (side normal ns), farther than the disc's radius, and x is on its dark side
 * (the centre more than the radius ahead of x along lit, when lit is known: WHO AIMS), else 0 (then the gather
 * samples cosine directions alone, drawing the same numbers as without the guide). */
double gather_guide_share(const gather_guide *gg, vec3 x, vec3 ns);
/* The aimed branch's density per steradian of the unit direction d from x (0 off the disc). */
double gather_guide_disc_pdf(const gather_guide *gg, vec3 x, vec3 d);
/* The mixture's density per steradian of d from x with share a and shading normal nsh:
 * a p_disc(d) + (1 - a) max(cos, 0) / pi (cos = d . nsh). */
double gather_guide_pdf(const gather_guide *gg, double a, vec3 x, vec3 nsh, vec3 d);
/* A gather direction from x (shading normal nsh) for the pair (u1, u2): aimed at the disc with
 * probability a (one more number from g decides), else cosine-distributed. *wk is its weight
 * relative to a cosine sample, (cos / pi) / p(d); 0 when d is below the shading hemisphere. */
vec3 gather_guide_direction(const gather_guide *gg, double a, vec3 x, vec3 nsh, double u1, double u2, rng *g,
                            double *wk);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_GATHER_GUIDE_H */
