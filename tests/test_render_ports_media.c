/* test_render_ports_media.c: photon ports in the media tracer (render/photons/ports.h, MEDIA):
 * a medium behind an aperture, its volume photons emitted through a port in the defensive
 * mixture, and the camera probe finding the port through a medium's null boundary.
 *
 * Oracles:
 * - analytic: a sun straight down (irradiance E = 1) on an opaque plate at y = 100 with a
 *   square hole of side 20 (area A = 400); under it, a box of dust (y from 0 to 90, x and z
 *   from -50 to 50, bounded by a null mesh; sigma_s 0.008, sigma_a 0.002, sigma_t 0.01). The
 *   beam through the hole falls straight through the box, so the power of the photons' first
 *   scattering events (volume photons of kind DIRECT, each storing power x sigma_s / sigma_t,
 *   medium.h) is, in expectation, E A (sigma_s / sigma_t) (1 - exp(-sigma_t H)) with H = 90:
 *   400 x 0.8 x (1 - e^-0.9) = 189.9. Traced with the hole declared as a port and without:
 *   both within 4 standard errors (the photons' own: one DIRECT photon at most per emitted
 *   photon) plus 0.5% (the RGBE photon powers).
 * - ports on and off agree: the later events (kinds INDIRECT: after an earlier scattering
 *   event or a bounce off the plate's underside), within 5 standard errors computed as if the
 *   photons were independent (a path stores a few; this understates the error a little) plus 1%.
 * - the probe: in a scene with media, the port the plan's camera probe finds lies at the hole
 *   (a room version of the same: walls around the box, the camera inside, the hole the only way
 *   in), its light connections and threading rays passing the box's null boundary.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "../photonmap/common.h"
#include "../photonmap/photon.h"
#include "../render/photons/ports.h"
#include "../render/photons/volume.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"

/* The box of dust: a closed null mesh, x and z from -50 to 50, y from 0 to 90, outward faces. */
#define DUST_BOX                                                                                                  \
    "{\"type\": \"mesh\", \"vertices\": [[-50, 0, -50], [50, 0, -50], [-50, 90, -50], [50, 90, -50], [-50, 0, 50], " \
    "[50, 0, 50], [-50, 90, 50], [50, 90, 50]], \"triangles\": [[0, 2, 3], [0, 3, 1], [4, 5, 7], [4, 7, 6], "      \
    "[0, 1, 5], [0, 5, 4], [2, 6, 7], [2, 7, 3], [0, 4, 6], [0, 6, 2], [1, 3, 7], [1, 7, 5]], "                   \
    "\"material\": \"air\", \"interior_medium\": \"dust\"}"

/* The plate at y = 100 (x and z from -100 to 100) around the hole (-10 .. 10). */
#define PLATE                                                                                                    \
    "{\"type\": \"quad\", \"vertices\": [[-100, 100, -100], [-100, 100, 100], [-10, 100, 100], [-10, 100, -100]], " \
    "\"material\": \"plate\"},"                                                                                     \
    "{\"type\": \"quad\", \"vertices\": [[10, 100, -100], [10, 100, 100], [100, 100, 100], [100, 100, -100]], "     \
    "\"material\": \"plate\"},"                                                                                     \
    "{\"type\": \"quad\", \"vertices\": [[-10, 100, -100], [-10, 100, -10], [10, 100, -10], [10, 100, -100]], "     \
    "\"material\": \"plate\"},"                                                                                     \
    "{\"type\": \"quad\", \"vertices\": [[-10, 100, 10], [-10, 100, 100], [10, 100, 100], [10, 100, 10]], "         \
    "\"material\": \"plate\"}"

static const char *APERTURE_FMT =
    "{\"camera\": {\"eye\": [0, 45, -300], \"look_at\": [0, 45, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
    " \"media\": {\"dust\": {\"sigma_a\": 0.002, \"sigma_s\": 0.008, \"g\": 0}},"
    " \"materials\": {\"plate\": {\"type\": \"lambert\", \"reflectance\": 0.5}, \"air\": {\"type\": \"null\"}},"
    " \"objects\": [" PLATE ", " DUST_BOX "],"
    " \"lights\": [{\"type\": \"directional\", \"direction\": [0, -1, 0], \"irradiance\": 1}]%s}";

static const char *APERTURE_PORT =
    ", \"ports\": [{\"type\": \"quad\", \"corner\": [-10, 100, -10], \"edge1\": [20, 0, 0], \"edge2\": [0, 0, 20]}]";

typedef struct vol_sum {
    double mean, se;
    size_t n;
} vol_sum;

/* The volume photons of one kind: their power (channel 0) in all, and its standard error from
 * the photons' powers as if each came from its own emitted photon (X_i = N P_i, zero for most). */
static vol_sum kind_sum(const vol_photons *vp, uint64_t emitted, int kind) {
    vol_sum v = {0, 0, 0};
    double s2 = 0;
    for (size_t i = 0; i < vp->count; i++) {
        if (pm_photon_kind(&vp->photons[i]) != kind) continue;
        float pw[3];
        pm_rgbe_decode(vp->photons[i].power, pw);
        v.mean += pw[0];
        s2 += (double)pw[0] * pw[0];
        v.n++;
    }
    v.se = sqrt(fmax(0, s2 - v.mean * v.mean / (double)emitted));
    return v;
}

static void trace_aperture(int with_port, uint64_t n, vol_sum *direct, vol_sum *later) {
    char text[8192];
    snprintf(text, sizeof text, APERTURE_FMT, with_port ? APERTURE_PORT : "");
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, text, &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(s.nports, with_port);
    photon_ports pp;
    ASSERT_EQ_INT(ports_build(&pp, &s), 0);
    EXPECT_EQ_INT(pp.on, with_port);
    ports_free(&pp);
    vol_photons vp;
    ASSERT_EQ_INT(vol_trace(&s, n, 11, 100, &vp), 0);
    *direct = kind_sum(&vp, n, PM_KIND_DIRECT);
    *later = kind_sum(&vp, n, PM_KIND_INDIRECT);
    vol_sum caustic = kind_sum(&vp, n, PM_KIND_CAUSTIC);
    EXPECT_MSG(caustic.n == 0, "%zu caustic volume photons (no specular surface)", caustic.n);
    free(vp.photons);
    scene_free(&s);
}

TEST(render_ports_media_aperture_analytic) {
    const double E = 1, A = 400, ss = 0.008, st = 0.01, H = 90;
    const double want = E * A * (ss / st) * (1 - exp(-st * H));
    const uint64_t n_port = PM_TEST_SANITIZED ? 20000 : 200000, n_plain = PM_TEST_SANITIZED ? 200000 : 1500000;
    vol_sum d[2], l[2];
    trace_aperture(1, n_port, &d[1], &l[1]);
    trace_aperture(0, n_plain, &d[0], &l[0]);
    const double sf = PM_TEST_SANITIZED ? sqrt(10.0) : 1;
    for (int k = 1; k >= 0; k--) {
        printf("    %s port: first events %.5g (exact %.5g, %+.2f%%, se %.2f%%, %zu photons); later events %.5g "
               "(se %.2f%%, %zu photons)\n",
               k ? "with a" : "without a", d[k].mean, want, 100 * (d[k].mean / want - 1), 100 * d[k].se / want,
               d[k].n, l[k].mean, 100 * l[k].se / fmax(l[k].mean, 1e-30), l[k].n);
        /* The test has power: a 10% error would show (sanitized builds trace a tenth). */
        EXPECT_MSG(d[k].se < 0.02 * sf * want, "standard error %.3g too large", d[k].se / want);
        EXPECT_MSG(fabs(d[k].mean - want) < 4 * d[k].se + 0.005 * want, "first events %s port: %.6g, exact %.6g",
                   k ? "with a" : "without a", d[k].mean, want);
    }
    /* The port puts many more photons into the dust, each with its true share of the power. */
    EXPECT_MSG(d[1].n > 20 * d[0].n * n_port / n_plain, "with the port %zu first events of %llu photons, without %zu of %llu",
               d[1].n, (unsigned long long)n_port, d[0].n, (unsigned long long)n_plain);
    double dl = fabs(l[1].mean - l[0].mean), sl = sqrt(l[1].se * l[1].se + l[0].se * l[0].se);
    EXPECT_MSG(l[0].n > 100 && l[1].n > 100, "later events: %zu and %zu photons", l[0].n, l[1].n);
    EXPECT_MSG(dl < 5 * sl + 0.01 * l[1].mean, "later events: %.6g with the port, %.6g without (se %.3g)", l[1].mean,
               l[0].mean, sl);
}

/* The room: the plate is its ceiling, walls and floor close it (y from 0 to 100, x and z from
 * -100 to 100), the dust box inside, the camera inside looking down at the lit floor. */
static const char *ROOM_TEXT =
    "{\"camera\": {\"eye\": [-80, 95, -80], \"look_at\": [0, 0, 0], \"fov_deg\": 60, \"width\": 8, \"height\": 8},"
    " \"media\": {\"dust\": {\"sigma_a\": 0.002, \"sigma_s\": 0.008, \"g\": 0}},"
    " \"materials\": {\"plate\": {\"type\": \"lambert\", \"reflectance\": 0.5}, \"air\": {\"type\": \"null\"}},"
    " \"objects\": [" PLATE ", " DUST_BOX ","
    "  {\"type\": \"quad\", \"vertices\": [[-100, 0, -100], [100, 0, -100], [100, 0, 100], [-100, 0, 100]], \"material\": \"plate\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-100, 0, -100], [-100, 100, -100], [100, 100, -100], [100, 0, -100]], \"material\": \"plate\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-100, 0, 100], [100, 0, 100], [100, 100, 100], [-100, 100, 100]], \"material\": \"plate\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-100, 0, -100], [-100, 0, 100], [-100, 100, 100], [-100, 100, -100]], \"material\": \"plate\"},"
    "  {\"type\": \"quad\", \"vertices\": [[100, 0, -100], [100, 100, -100], [100, 100, 100], [100, 0, 100]], \"material\": \"plate\"}],"
    " \"lights\": [{\"type\": \"directional\", \"direction\": [0, -1, 0], \"irradiance\": 1}]}";

TEST(render_ports_media_probe_finds_the_hole) {
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, ROOM_TEXT, &e) == 0, "%s", e.msg);
    ASSERT(s.has_null && s.nmedia == 1);
    port_found f;
    ASSERT_EQ_INT(ports_find(&s, 5, &f), 0);
    ASSERT_MSG(f.ran && f.n == 1, "%d ports found: %s", f.n, f.why);
    const port *p = &f.p[0];
    double a = v3_len(p->e1), b = v3_len(p->e2);
    printf("    found: quad %.3g x %.3g at (%.3g, %.4g, %.3g), normal (%.2f, %.2f, %.2f); %s\n", a, b, p->c.x, p->c.y,
           p->c.z, p->n.x, p->n.y, p->n.z, f.why);
    EXPECT_MSG(fabs(p->c.y - 100) < 0.01 && hypot(p->c.x, p->c.z) < 1e-6, "centre (%g, %g, %g), the hole's (0, 100, 0)",
               p->c.x, p->c.y, p->c.z);
    /* ports.h, THE RIM: the sides are the hole's edges, found by rays (bisection to ~1e-11) */
    EXPECT_MSG(fabs(a / 20 - 1) < 1e-6 && fabs(b / 20 - 1) < 1e-6, "sides %.9g x %.9g, the hole's 20 x 20", a, b);
    EXPECT_MSG(fabs(p->n.y) > 0.999, "normal (%g, %g, %g)", p->n.x, p->n.y, p->n.z);
    scene_free(&s);
}
