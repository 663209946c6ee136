/* test_render_ports.c: photon ports (render/scene/port.h, render/photons/ports.h): openings the
 * scene declares, through which a share of the global photons is aimed, the rest emitted as
 * before, each photon's power divided by the mixture's density over the ordinary one.
 *
 * Oracles:
 * - analytic: a Lambertian sphere lamp in a closed black box with a square hole in its floor,
 *   over a white plane. The flux a uniform sphere of radiance L and radius r sends across any
 *   region of a plane that does not cut it is pi L r^2 Omega, Omega the region's solid angle
 *   from the centre (its irradiance on the plane is pi L (r / D)^2 cos theta); for a square of
 *   half-side b on the axis at distance h, Omega = 4 asin(b^2 / (b^2 + h^2)). So the photons
 *   stored on the plane carry pi L r^2 Omega_hole in all, and those in a central patch every
 *   point of which sees the whole lamp through the hole carry pi L r^2 Omega_patch. Traced
 *   with the hole declared as a port and without: both within 4 standard errors (the photons'
 *   own, as if independent; Halton points do better) plus 0.5% (the RGBE photon powers); and
 *   with a plan's pilot photons (emitted by power) joining the port pass. With the box's
 *   ceiling white, the light that reaches the plane after a bounce off it (the photons of kind
 *   INDIRECT) against a quadrature of the ceiling's radiosity through the hole, the lamp
 *   blocking what passes it: the ceiling's photons aim at the hole too (ports.h, BOUNCES).
 * - bounces: ports_scatter's weights restore the cosine density (chi-square over bins where it
 *   is uniform), from points that aim and from one on the port's dark side, which never does.
 * - the definition: the mixture's direction density from a point light, by a chi-square over
 *   4096 bins of the sphere against p(d) = ((1 - a) + a ratio(d)) / (4 pi), integrated over
 *   each bin on a 48 x 48 grid; for area, sphere and directional lights, the photons weighted
 *   by 1 / rel in bins of the light's own sample space u (light.h), where the ordinary
 *   emission is uniform: each bin's weighted share must be the bin's volume (chi-square); the
 *   port weights of each light and the lights' port shares each sum to one.
 * - bad ports: each wrong field named by its JSON path, and render exits 2.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "test_film.h"
#include "../photonmap/common.h"
#include "../photonmap/photon.h"
#include "../render/base/rng.h"
#include "../render/image/film.h"
#include "../render/base/sampling.h"
#include "../render/photons/importance.h"
#include "../render/photons/photon_maps.h"
#include "../render/photons/photon_trace.h"
#include "../render/photons/ports.h"
#include "../render/load/scene_load.h"
#include "../render/scene/scene.h"
#include "../render/scene/scene_hash.h"

/* ---- the analytic case ---------------------------------------------------------------------- */

#define LAMP_R 0.05
#define HOLE_B 0.2  /* the hole's half-side, in the box's floor at y = -1 (1 below the lamp) */
#define PLANE_H 3.0 /* the white plane at y = -3 */
#define PATCH_B 0.2 /* the central patch's half-side on the plane */

static const char *BOX_SCENE_FMT =
    "{\"camera\": {\"eye\": [0, -2, 4], \"look_at\": [0, -3, 0], \"fov_deg\": 60, \"width\": 8, \"height\": 8},"
    " \"materials\": {\"black\": {\"type\": \"lambert\", \"reflectance\": 0},"
    "  \"white\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
    "  \"ceiling\": {\"type\": \"lambert\", \"reflectance\": 0.8},"
    "  \"lamp\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 1}},"
    " \"objects\": ["
    "  {\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 0.05, \"material\": \"lamp\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-1, 1, -1], [1, 1, -1], [1, 1, 1], [-1, 1, 1]], \"material\": \"%s\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-1, -1, -1], [-1, 1, -1], [-1, 1, 1], [-1, -1, 1]], \"material\": \"black\"},"
    "  {\"type\": \"quad\", \"vertices\": [[1, -1, -1], [1, -1, 1], [1, 1, 1], [1, 1, -1]], \"material\": \"black\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1]], \"material\": \"black\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-1, -1, 1], [-1, 1, 1], [1, 1, 1], [1, -1, 1]], \"material\": \"black\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-1, -1, 0.2], [1, -1, 0.2], [1, -1, 1], [-1, -1, 1]], \"material\": \"black\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-1, -1, -1], [1, -1, -1], [1, -1, -0.2], [-1, -1, -0.2]], \"material\": \"black\"},"
    "  {\"type\": \"quad\", \"vertices\": [[0.2, -1, -0.2], [1, -1, -0.2], [1, -1, 0.2], [0.2, -1, 0.2]], \"material\": \"black\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-1, -1, -0.2], [-0.2, -1, -0.2], [-0.2, -1, 0.2], [-1, -1, 0.2]], \"material\": \"black\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-3, -3, -3], [-3, -3, 3], [3, -3, 3], [3, -3, -3]], \"material\": \"white\"}]"
    "%s}";

static const char *BOX_PORT =
    ", \"ports\": [{\"type\": \"quad\", \"corner\": [-0.2, -1, -0.2], \"edge1\": [0.4, 0, 0], \"edge2\": [0, 0, 0.4]}]";

static double square_solid_angle(double b, double h) { return 4 * asin(b * b / (b * b + h * h)); }

typedef struct flux_est {
    double mean, se; /* the flux and its standard error, per channel 0 */
    size_t n;        /* photons that made it */
} flux_est;

/* The stored photons on the plane (within half-side `half` of the axis): the flux, and its
 * standard error from the photons' powers (X_i = N P_i per emitted photon, zero for most). */
static flux_est plane_flux(const photon_maps *m, double half, int kind) {
    flux_est f = {0, 0, 0};
    double s2 = 0, N = (double)m->global_emitted;
    for (size_t k = 0; k < m->nglobal; k++) {
        const pm_photon *p = &m->global[k];
        if (fabs(p->pos[1] + PLANE_H) > 1e-3 || fabs(p->pos[0]) > half || fabs(p->pos[2]) > half) continue;
        if (pm_photon_kind(p) != kind) continue;
        float pw[3];
        pm_rgbe_decode(p->power, pw);
        f.mean += pw[0];
        s2 += (double)pw[0] * pw[0];
        f.n++;
    }
    f.se = sqrt(fmax(0, s2 - f.mean * f.mean / N));
    return f;
}

/* The flux the box's white ceiling (y = 1, reflectance CEIL_RHO, lit by the lamp with
 * irradiance pi L r^2 cos / D^2) sends through the hole, by midpoint quadrature over n x n points
 * of the ceiling and n/4 x n/4 of the hole, the lamp sphere blocking what passes it. */
#define CEIL_RHO 0.8
static double ceiling_flux(int n) {
    int nh = n / 4;
    double sum = 0, base = M_PI * LAMP_R * LAMP_R;
    for (int i = 0; i < n * n; i++) {
        vec3 x = v3(-1 + 2 * (i % n + 0.5) / n, 1, -1 + 2 * (i / n + 0.5) / n);
        double D2 = v3_len2(x), E = base / D2 * (1 / sqrt(D2)); /* cos at the ceiling: 1 / D */
        double B = CEIL_RHO * E / M_PI;
        for (int j = 0; j < nh * nh; j++) {
            vec3 y = v3(-HOLE_B + 2 * HOLE_B * (j % nh + 0.5) / nh, -1, -HOLE_B + 2 * HOLE_B * (j / nh + 0.5) / nh);
            vec3 d = v3_sub(y, x);
            double d2 = v3_len2(d);
            /* the segment's nearest point to the lamp's centre */
            double tt = -v3_dot(x, d) / d2;
            tt = tt < 0 ? 0 : tt > 1 ? 1 : tt;
            if (v3_len2(v3_madd(x, d, tt)) <= LAMP_R * LAMP_R) continue;
            double c = 2 / sqrt(d2); /* both planes are horizontal, 2 apart */
            sum += B * c * c / d2;
        }
    }
    return sum * (4.0 / (n * n)) * (4 * HOLE_B * HOLE_B / (nh * nh));
}

/* with_port: 0 none, 1 declared ($.ports), 2 found by the plan's camera probe (ports_find). */
static void check_box(int with_port, int white_ceiling, long target, uint64_t pilot) {
    char text[8192];
    snprintf(text, sizeof text, BOX_SCENE_FMT, white_ceiling ? "ceiling" : "black", with_port == 1 ? BOX_PORT : "");
    scene s0, sc;
    json_err e;
    ASSERT_MSG(scene_load_text(&s0, text, &e) == 0, "%s", e.msg);
    ASSERT_EQ_INT(s0.nports, with_port == 1 ? 1 : 0);
    port_found pf;
    const scene *sp = &s0;
    if (with_port == 2) { /* the hole, found: used as the declared one is */
        ASSERT_EQ_INT(ports_find(&s0, 7, &pf), 0);
        ASSERT_MSG(pf.n == 1, "found %d ports: %s", pf.n, pf.why);
        printf("    found: quad %.4g x %.4g at (%.4g, %.4g, %.4g); %s\n", v3_len(pf.p[0].e1), v3_len(pf.p[0].e2),
               pf.p[0].c.x, pf.p[0].c.y, pf.p[0].c.z, pf.why);
        sp = ports_found_scene(&s0, &pf, &sc);
    }
    const scene s = *sp; /* a copy that shares s0's arrays (freed once, below) */
    trace_opts o;
    trace_opts_init(&o, &s);
    o.global = 1;
    o.global_target = target;
    o.max_emitted_factor = 1e4;
    o.quiet = 1;
    o.seed = 7;
    photon_maps m;
    memset(&m, 0, sizeof m);
    char err[512] = "";
    trace_pilot tp;
    memset(&tp, 0, sizeof tp);
    if (pilot) { /* a plan's pilot (plan.c): by power, its stores kept to join the pass */
        trace_opts po = o;
        po.pilot = &tp;
        tp.keep = 1;
        po.max_emitted = (double)pilot;
        /* Above the ~1.2% of the pilot that passes the hole: the pilot runs to its emission
         * budget (its photons), as the plan's does. */
        po.global_target = (long)(pilot / 50);
        int rc = photon_trace(&s, &po, &m, err, sizeof err);
        ASSERT_MSG(rc == 0 && tp.kept, "pilot: %d %s", rc, err);
        photon_maps_free(&m);
        memset(&m, 0, sizeof m);
        o.reuse = tp.kept;
        o.seed = 8;
        const char *why = "";
        ASSERT_MSG(pilot_photons_joining(tp.kept, &o, 0, NULL, NULL, &why), "the pilot does not join: %s", why);
    }
    int rc = photon_trace(&s, &o, &m, err, sizeof err);
    pilot_photons_free(tp.kept);
    ASSERT_MSG(rc == 0, "photon_trace: %d %s", rc, err);
    if (pilot) EXPECT_MSG(m.pilot_emitted[0] == tp.emitted && tp.emitted >= pilot, "the pilot's %llu photons did not join (%llu)",
                          (unsigned long long)tp.emitted, (unsigned long long)m.pilot_emitted[0]);
    double L = 1, base = M_PI * L * LAMP_R * LAMP_R;
    double want_all = base * square_solid_angle(HOLE_B, 1.0), ind = 0;
    double want_patch = base * square_solid_angle(PATCH_B, PLANE_H);
    flux_est all = plane_flux(&m, PLANE_H, PM_KIND_DIRECT), patch = plane_flux(&m, PATCH_B, PM_KIND_DIRECT);
    flux_est bounced = plane_flux(&m, PLANE_H, PM_KIND_INDIRECT);
    printf("    %s port%s: %llu emitted, %zu stored; straight through the hole %.6g (exact %.6g, %+.2f%%, se %.2f%%); "
           "patch %.6g (exact %.6g, %+.2f%%, se %.2f%%, %zu photons)\n",
           with_port ? "with a" : "without a", pilot ? " and a pilot's photons joining" : "",
           (unsigned long long)m.global_emitted, m.nglobal, all.mean, want_all,
           100 * (all.mean / want_all - 1), 100 * all.se / want_all, patch.mean, want_patch,
           100 * (patch.mean / want_patch - 1), 100 * patch.se / want_patch, patch.n);
    /* The test has power: a 10% error would show (sanitized builds trace a tenth of the photons). */
    const double sf = PM_TEST_SANITIZED ? sqrt(10.0) : 1;
    EXPECT_MSG(all.se < 0.02 * sf * want_all && patch.se < 0.025 * sf * want_patch,
               "standard errors %.3g, %.3g too large", all.se / want_all, patch.se / want_patch);
    EXPECT_MSG(fabs(all.mean - want_all) < 4 * all.se + 0.005 * want_all, "through the hole: %.6g, exact %.6g",
               all.mean, want_all);
    EXPECT_MSG(fabs(patch.mean - want_patch) < 4 * patch.se + 0.005 * want_patch, "patch: %.6g, exact %.6g",
               patch.mean, want_patch);
    if (white_ceiling) { /* and what the ceiling sends through the hole */
        double coarse = ceiling_flux(96);
        ind = ceiling_flux(192);
        printf("    after a bounce off the ceiling: %.6g (quadrature %.6g, at half the points %.6g; %+.2f%%, se %.2f%%, "
               "%zu photons)\n",
               bounced.mean, ind, coarse, 100 * (bounced.mean / ind - 1), 100 * bounced.se / ind, bounced.n);
        EXPECT_MSG(fabs(coarse / ind - 1) < 0.002, "quadrature: %.6g against %.6g", coarse, ind);
        EXPECT_MSG(bounced.se < 0.04 * sf * ind, "standard error %.3g too large", bounced.se / ind);
        EXPECT_MSG(fabs(bounced.mean - ind) < 4 * bounced.se + 0.005 * ind, "after a bounce: %.6g, quadrature %.6g",
                   bounced.mean, ind);
    } else {
        EXPECT_MSG(bounced.n == 0, "%zu photons bounced onto the plane (only black surfaces)", bounced.n);
    }
    photon_maps_free(&m);
    scene_free(&s0);
}

TEST(render_ports_analytic_hole_with_port) { check_box(1, 0, PM_TEST_SANITIZED ? 4000 : 40000, 0); }
TEST(render_ports_analytic_hole_without_port) { check_box(0, 0, PM_TEST_SANITIZED ? 4000 : 25000, 0); }
/* The box's ceiling white: light reaches the hole straight from the lamp and after a bounce
 * off the ceiling (ports.h, BOUNCES: the ceiling's photons aim at the hole too). */
TEST(render_ports_analytic_hole_bounce_with_port) { check_box(1, 1, PM_TEST_SANITIZED ? 8000 : 80000, 0); }
TEST(render_ports_analytic_hole_bounce_without_port) { check_box(0, 1, PM_TEST_SANITIZED ? 25000 : 250000, 0); }
/* The same with the port the plan's camera probe finds (ports.h) instead of a declared one. */
TEST(render_ports_analytic_hole_with_found_port) { check_box(2, 0, PM_TEST_SANITIZED ? 4000 : 40000, 0); }
TEST(render_ports_analytic_hole_bounce_with_found_port) { check_box(2, 1, PM_TEST_SANITIZED ? 8000 : 80000, 0); }
/* The pilot's photons, emitted by power, join the port pass by the balance heuristic (their rel
 * is the mixture's too): 400,000 of them, about 4,900 through the hole. */
TEST(render_ports_analytic_hole_with_port_and_pilot) {
    check_box(1, 0, PM_TEST_SANITIZED ? 4000 : 40000, PM_TEST_SANITIZED ? 40000 : 400000);
}

/* ---- the mixture's density ------------------------------------------------------------------ */

/* The mixture as photon_trace.c samples it (ports_mix), from independent uniforms: the light,
 * origin, direction and rel of one photon; 0 when it carries nothing. */
static int mix_sample(const photon_ports *pp, const scene *s, rng *g, int *l, vec3 *x, vec3 *d, double *rel) {
    double a = pp->a, h = rng_uniform(g), ul = rng_uniform(g);
    double u[4] = {rng_uniform(g), rng_uniform(g), rng_uniform(g), rng_uniform(g)};
    vec3 n;
    if (h < a) {
        if (!ports_sample(pp, ul, h / a, u, l, x, &n, d)) return 0;
        double r = ports_ratio(pp, *l, *x, *d);
        if (!(r > 0)) return 0;
        *rel = a * r + (1 - a);
        return 1;
    }
    double pl;
    *l = distrib1d_sample(&s->light_distrib, ul, &pl);
    light_sample_le(s, *l, u, x, &n, d);
    *rel = a * ports_ratio(pp, *l, *x, *d) + (1 - a);
    return 1;
}

static const char *POINT_SCENE =
    "{\"camera\": {\"eye\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
    " \"materials\": {\"grey\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
    " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-9, -9, -9], [9, -9, -9], [9, -9, 9], [-9, -9, 9]],"
    "  \"material\": \"grey\"}],"
    " \"lights\": [{\"type\": \"point\", \"position\": [0, 0, 0], \"intensity\": 1}],"
    " \"ports\": [{\"type\": \"quad\", \"corner\": [-0.3, -1, -0.3], \"edge1\": [0.6, 0, 0], \"edge2\": [0, 0, 0.6]},"
    "  {\"type\": \"disc\", \"center\": [1.5, 0.5, 0], \"normal\": [-1, 0, 0.3], \"radius\": 0.4}],"
    " \"port_fraction\": 0.6}";

/* The direction d of bin (i, j) at fractions (fa, fb) inside it: d.x uniform in [-1, 1]
 * (equal-area bins of the sphere), phi about the x axis. */
static vec3 bin_dir(int i, int j, int nb, double fa, double fb) {
    double z = -1 + 2 * (i + fa) / nb, phi = 2 * M_PI * (j + fb) / nb, r = sqrt(fmax(0, 1 - z * z));
    return v3(z, r * cos(phi), r * sin(phi));
}

/* Oracle: the definition of the mixture's density, p(d) = ((1 - a) + a ratio(d)) / (4 pi) for
 * a point light (p_def = 1 / (4 pi)); two ports, a quad and a tilted disc. 400,000 photons in
 * 64 x 64 equal-area bins against that density integrated over each bin (48 x 48 midpoints):
 * the chi-square statistic over 4095 degrees of freedom must stay below df + 5 sqrt(2 df). The
 * port branch's density must integrate to 1 (each port's does): the midpoint grid's own error
 * at the ports' edges falls as 1 / grid (measured +0.71% at 16 x 16, +0.22% at 48 x 48), so the
 * tolerance is 0.5%. */
TEST(render_ports_point_light_density_histogram) {
    enum { NB = 64, SUB = 48 };
    const long N = PM_TEST_SANITIZED ? 100000 : 400000;
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, POINT_SCENE, &e) == 0, "%s", e.msg);
    photon_ports pp;
    ASSERT_EQ_INT(ports_build(&pp, &s), 0);
    ASSERT(pp.on);
    EXPECT_NEAR(pp.a, 0.6, 1e-12);
    static double cnt[NB * NB], want[NB * NB];
    memset(cnt, 0, sizeof cnt);
    rng g = rng_stream(11, 0, 0);
    long ok = 0;
    for (long k = 0; k < N; k++) {
        int l;
        vec3 x, d;
        double rel;
        if (!mix_sample(&pp, &s, &g, &l, &x, &d, &rel)) continue;
        ok++;
        double phi = atan2(d.z, d.y);
        if (phi < 0) phi += 2 * M_PI;
        int i = (int)((d.x + 1) / 2 * NB), j = (int)(phi / (2 * M_PI) * NB);
        i = i < 0 ? 0 : i >= NB ? NB - 1 : i;
        j = j < 0 ? 0 : j >= NB ? NB - 1 : j;
        cnt[i * NB + j]++;
    }
    EXPECT_EQ_INT((int)ok, (int)N); /* a point light emits every direction: no photon is dropped */
    double total = 0, chi2 = 0, port_mass = 0;
    for (int i = 0; i < NB; i++)
        for (int j = 0; j < NB; j++) {
            double sum = 0;
            for (int a = 0; a < SUB; a++)
                for (int b = 0; b < SUB; b++) {
                    double r = ports_ratio(&pp, 0, s.lights[0].pos, bin_dir(i, j, NB, (a + 0.5) / SUB, (b + 0.5) / SUB));
                    sum += (1 - pp.a) + pp.a * r;
                    port_mass += r;
                }
            want[i * NB + j] = sum / (SUB * SUB) / (NB * NB); /* the bin's probability */
            total += want[i * NB + j];
        }
    port_mass /= (double)NB * NB * SUB * SUB; /* the port branch's density integrates to 1 */
    for (int b = 0; b < NB * NB; b++) {
        double w = want[b] * (double)ok;
        chi2 += (cnt[b] - w) * (cnt[b] - w) / w;
    }
    double df = NB * NB - 1, bound = df + 5 * sqrt(2 * df);
    printf("    point light, two ports, a = %.2f: chi-square %.1f over %.0f degrees of freedom (bound %.0f); "
           "the density integrates to %.5f, its port branch to %.5f\n",
           pp.a, chi2, df, bound, total, port_mass);
    EXPECT_NEAR(total, 1.0, 0.003);
    EXPECT_NEAR(port_mass, 1.0, 0.005);
    EXPECT_MSG(chi2 < bound, "chi-square %.1f above %.0f", chi2, bound);
    ports_free(&pp);
    scene_free(&s);
}

/* Scenes for the u-space check: an area light (a one-sided quad, two lights), a two-sided
 * one, a sphere lamp and a directional light, each with ports in front of it. */
static const char *U_SCENES[] = {
    "{\"camera\": {\"eye\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
    " \"materials\": {\"grey\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
    "  \"lamp\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": [4, 2, 1]}},"
    " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-9, -3, -9], [9, -3, -9], [9, -3, 9], [-9, -3, 9]], \"material\": \"grey\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5]], \"material\": \"lamp\"}],"
    " \"ports\": [{\"type\": \"quad\", \"corner\": [0.2, 0, -0.1], \"edge1\": [0.2, 0, 0], \"edge2\": [0, 0, 0.2]},"
    "  {\"type\": \"disc\", \"center\": [-1, -0.5, 0.5], \"normal\": [0, 1, 0], \"radius\": 0.3}]}",
    "{\"camera\": {\"eye\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
    " \"materials\": {\"grey\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
    "  \"lamp\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 3, \"two_sided\": true}},"
    " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-9, -3, -9], [9, -3, -9], [9, -3, 9], [-9, -3, 9]], \"material\": \"grey\"},"
    "  {\"type\": \"quad\", \"vertices\": [[-0.5, 1, -0.5], [0.5, 1, -0.5], [0.5, 1, 0.5], [-0.5, 1, 0.5]], \"material\": \"lamp\"}],"
    " \"ports\": [{\"type\": \"quad\", \"corner\": [-0.2, 2, -0.2], \"edge1\": [0.4, 0, 0], \"edge2\": [0, 0, 0.4]},"
    "  {\"type\": \"disc\", \"center\": [0, 0, 0], \"normal\": [0, 1, 0], \"radius\": 0.2}], \"port_fraction\": 0.8}",
    "{\"camera\": {\"eye\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
    " \"materials\": {\"grey\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
    "  \"lamp\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 1}},"
    " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-9, -3, -9], [9, -3, -9], [9, -3, 9], [-9, -3, 9]], \"material\": \"grey\"},"
    "  {\"type\": \"sphere\", \"center\": [0, 1, 0], \"radius\": 0.3, \"material\": \"lamp\"}],"
    " \"ports\": [{\"type\": \"disc\", \"center\": [0.3, 0, 0], \"normal\": [0, 1, 0], \"radius\": 0.25}], \"port_fraction\": 0.3}",
    "{\"camera\": {\"eye\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
    " \"materials\": {\"grey\": {\"type\": \"lambert\", \"reflectance\": 0.5}},"
    " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-2, -1, -2], [2, -1, -2], [2, -1, 2], [-2, -1, 2]], \"material\": \"grey\"}],"
    " \"lights\": [{\"type\": \"directional\", \"direction\": [0.3, -1, 0.1], \"irradiance\": 2}],"
    " \"ports\": [{\"type\": \"quad\", \"corner\": [-0.4, 0, -0.2], \"edge1\": [0.5, 0, 0], \"edge2\": [0, 0.1, 0.3]}]}",
};

/* Oracle: the ordinary emission is uniform over each light's sample space u (light.h), with
 * the light chosen by power, so the share of photons in a box of u of light l is p_l times the
 * box's volume. Photons from the mixture, each counted 1 / rel (the power it carries relative
 * to an ordinary photon), must give the same shares: in 16 x 16 bins over the direction's two
 * numbers (u[2], u[3]; a directional light: the disc point's u[0], u[1]) per light, each bin's
 * weighted share against p_l / 256, as a chi-square with the bins' own standard errors (bound
 * df + 5 sqrt(2 df)). The weighted shares add up to 1 within 4 standard errors (port photons
 * that leave the back of the sphere lamp are dropped: they count 0, and the ordinary emission
 * never gives such a photon), each light's port weights end at 1 and the port shares q_l / p_l,
 * weighted by p_l, sum to 1. */
TEST(render_ports_mixture_unbiased_in_light_space) {
    enum { G = 16 };
    const long N = PM_TEST_SANITIZED ? 50000 : 300000;
    for (size_t sc = 0; sc < sizeof U_SCENES / sizeof *U_SCENES; sc++) {
        scene s;
        json_err e;
        ASSERT_MSG(scene_load_text(&s, U_SCENES[sc], &e) == 0, "scene %zu: %s", sc, e.msg);
        photon_ports pp;
        ASSERT_EQ_INT(ports_build(&pp, &s), 0);
        ASSERT_MSG(pp.on, "scene %zu: ports off", sc);
        double qsum = 0;
        for (int l = 0; l < s.nlights; l++) {
            qsum += pp.q_p[l] * distrib1d_prob(&s.light_distrib, l);
            EXPECT_NEAR(pp.wcdf[(size_t)l * (size_t)(pp.np + 1) + (size_t)pp.np], 1.0, 1e-12);
        }
        EXPECT_NEAR(qsum, 1.0, 1e-12);
        int nb = s.nlights * G * G;
        double *w1 = calloc((size_t)nb, sizeof *w1), *w2 = calloc((size_t)nb, sizeof *w2);
        ASSERT(w1 && w2);
        rng g = rng_stream(12, sc, 0);
        double tot = 0, tot2 = 0;
        long dropped = 0;
        for (long k = 0; k < N; k++) {
            int l;
            vec3 x, d;
            double rel, u[4];
            if (!mix_sample(&pp, &s, &g, &l, &x, &d, &rel)) {
                dropped++;
                continue;
            }
            ASSERT_MSG(importance_invert_le(&s, l, x, d, u), "scene %zu: a photon the light cannot emit", sc);
            int dirl = s.lights[l].type == LIGHT_DIRECTIONAL;
            double a = dirl ? u[0] : u[2], b = dirl ? u[1] : u[3];
            int i = (int)(a * G), j = (int)(b * G);
            i = i < 0 ? 0 : i >= G ? G - 1 : i;
            j = j < 0 ? 0 : j >= G ? G - 1 : j;
            int bin = (l * G + i) * G + j;
            w1[bin] += 1 / rel;
            w2[bin] += 1 / (rel * rel);
            tot += 1 / rel;
            tot2 += 1 / (rel * rel);
        }
        double chi2 = 0;
        int df = 0;
        for (int b = 0; b < nb; b++) {
            double want = distrib1d_prob(&s.light_distrib, b / (G * G)) / (G * G);
            /* Pearson's form, as in render_ports_bounce_density */
            double m = w1[b] / N, var = (w1[b] > 0 ? w2[b] / w1[b] * want - want * want : 0) / N;
            if (!(var > 0)) continue;
            chi2 += (m - want) * (m - want) / var;
            df++;
        }
        double se = sqrt((tot2 / N - (tot / N) * (tot / N)) / N), bound = df + 5 * sqrt(2.0 * df);
        printf("    scene %zu (%s light%s, a = %.2f): weighted total %.5f (se %.5f), chi-square %.1f over %d bins "
               "(bound %.0f), %ld photons dropped\n",
               sc, s.lights[0].type == LIGHT_AREA ? "area" : s.lights[0].type == LIGHT_SPHERE ? "sphere" : "directional",
               s.lights[0].two_sided ? ", two-sided" : "", pp.a, tot / N, se, chi2, df, bound, dropped);
        EXPECT_MSG(fabs(tot / N - 1) < 4 * se, "scene %zu: weighted total %.5f", sc, tot / N);
        EXPECT_MSG(df > nb / 2 && chi2 < bound, "scene %zu: chi-square %.1f over %d bins", sc, chi2, df);
        free(w1);
        free(w2);
        ports_free(&pp);
        scene_free(&s);
    }
}

/* ---- bad input -------------------------------------------------------------------------------- */

/* Oracle: the format (data/scenes/README.md, "ports"): each mistake names its JSON path. */
TEST(render_ports_bad_input_errors) {
    static const struct {
        const char *ports, *want;
    } cases[] = {
        {"\"ports\": {}", "$.ports: expected an array"},
        {"\"ports\": []", "$.ports: empty"},
        {"\"ports\": [3]", "$.ports[0]: expected an object"},
        {"\"ports\": [{\"corner\": [0, 0, 0]}]", "$.ports[0].type"},
        {"\"ports\": [{\"type\": \"hole\"}]", "$.ports[0].type: unknown port type \"hole\" (quad, disc)"},
        {"\"ports\": [{\"type\": \"quad\", \"corner\": [0, 0, 0], \"edge1\": [1, 0, 0]}]", "$.ports[0].edge2"},
        {"\"ports\": [{\"type\": \"quad\", \"corner\": [0, 0], \"edge1\": [1, 0, 0], \"edge2\": [0, 1, 0]}]",
         "$.ports[0].corner"},
        {"\"ports\": [{\"type\": \"quad\", \"corner\": [0, 0, 0], \"edge1\": [1, 0, 0], \"edge2\": [2, 0, 0]}]",
         "$.ports[0]: edge1 and edge2 are parallel"},
        {"\"ports\": [{\"type\": \"quad\", \"corner\": [0, 0, 0], \"edge1\": [0, 0, 0], \"edge2\": [2, 0, 0]}]",
         "$.ports[0].edge1: must not be zero"},
        {"\"ports\": [{\"type\": \"quad\", \"corner\": [0, 0, 1e300], \"edge1\": [1, 0, 0], \"edge2\": [0, 1, 0]}]",
         "$.ports[0].corner: [0, 0, 1e+300] is outside the supported range"},
        {"\"ports\": [{\"type\": \"quad\", \"corner\": [0, 0, 0], \"edge1\": [1, 0, 0], \"edge2\": [0, 1, 0], "
         "\"edge3\": [1, 1, 1]}]",
         "$.ports[0].edge3: unknown key"},
        {"\"ports\": [{\"type\": \"disc\", \"center\": [0, 0, 0], \"normal\": [0, 1, 0], \"radius\": -1}]",
         "$.ports[0].radius: must be positive"},
        {"\"ports\": [{\"type\": \"disc\", \"center\": [0, 0, 0], \"normal\": [0, 0, 0], \"radius\": 1}]",
         "$.ports[0].normal: must not be zero"},
        {"\"ports\": [{\"type\": \"disc\", \"center\": [0, 0, 0], \"normal\": [0, 1, 0]}]", "$.ports[0].radius"},
        {"\"ports\": [{\"type\": \"disc\", \"center\": [0, 0, 0], \"normal\": [0, 1, 0], \"radius\": 1, "
         "\"radus\": 1}]",
         "$.ports[0].radus: unknown key"},
        {"\"port_fraction\": 0.5", "$.port_fraction: given without $.ports"},
        {"\"find_ports\": 1", "$.find_ports: expected true or false, got a number"},
        {"\"ports\": [{\"type\": \"disc\", \"center\": [0, 0, 0], \"normal\": [0, 1, 0], \"radius\": 1}], "
         "\"port_fraction\": 1",
         "$.port_fraction: must be at least 0 and below 1"},
        {"\"ports\": [{\"type\": \"disc\", \"center\": [0, 0, 0], \"normal\": [0, 1, 0], \"radius\": 1}], "
         "\"port_fraction\": \"half\"",
         "$.port_fraction"},
        {"\"prots\": []", "$.prots: unknown key (did you mean \"ports\"?)"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof *cases; k++) {
        char text[4096];
        snprintf(text, sizeof text,
                 "{\"camera\": {\"eye\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
                 " \"materials\": {\"m\": {\"type\": \"lambert\", \"reflectance\": 0.5, \"emission\": 1}},"
                 " \"objects\": [{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, \"material\": \"m\"}], %s}",
                 cases[k].ports);
        scene s;
        json_err e;
        int rc = scene_load_text(&s, text, &e);
        EXPECT_MSG(rc < 0, "case %zu (%s) loaded", k, cases[k].ports);
        if (rc < 0) {
            EXPECT_MSG(strstr(e.msg, cases[k].want) != NULL, "case %zu: \"%s\", want \"%s\"", k, e.msg, cases[k].want);
        } else {
            scene_free(&s);
        }
    }
    /* And the render program: the file named, exit 2. */
    char path[1024], cmd[4096], out[4096];
    snprintf(path, sizeof path, "%s/bad_port.json", pm_test_tmpdir());
    FILE *f = fopen(path, "w");
    ASSERT(f);
    fprintf(f, "{\"camera\": {\"eye\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
               " \"materials\": {\"m\": {\"type\": \"lambert\", \"reflectance\": 0.5, \"emission\": 1}},"
               " \"objects\": [{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, \"material\": \"m\"}],"
               " \"ports\": [{\"type\": \"disc\", \"center\": [0, 0, 0], \"normal\": [0, 1, 0], \"radius\": 0}]}\n");
    fclose(f);
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/render' '%s' --mode pm --width 4 --height 4 --spp 1 --quiet 2>&1",
             pm_test_tmpdir(), pm_test_build_dir(), path);
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_EQ_INT(rc, 2);
    EXPECT_MSG(strstr(out, "bad_port.json") && strstr(out, "$.ports[0].radius: must be positive"), "%s", out);
}

/* ---- the plan's line -------------------------------------------------------------------------- */

static int load_file(scene *s, const char *name) {
    char path[1024];
    json_err e;
    snprintf(path, sizeof path, "%s/data/scenes/%s", pm_test_source_dir(), name);
    int rc = scene_load(s, path, &e);
    if (rc < 0) printf("    %s: %s\n", name, e.msg);
    return rc;
}

/* Oracle: the scene's geometry. pinhole_room_ports.json declares the 10 x 10 hole at
 * (500, 300, 500): the plan's reason names it, and the share of the lamp's power it says passes
 * the hole matches the form factor from the lamp (200 x 200, 699.9 above) to the hole, by
 * quadrature over 32 x 32 points of the lamp and 8 x 8 of the hole, within 3% (the estimate
 * uses 3 points of each lamp triangle and 4 of the hole). Without ports, with port_fraction 0,
 * and with the port behind the lamp (a one-sided lamp facing down), the reason says why they
 * are off; in a scene with media they are on (ports.h, MEDIA). */
TEST(render_ports_plan_reason) {
    scene s;
    char why[1024];
    ASSERT_EQ_INT(load_file(&s, "pinhole_room_ports.json"), 0);
    ASSERT_EQ_INT(ports_plan(&s, why, sizeof why), 1);
    printf("    pinhole_room_ports: photon ports: on (%s)\n", why);
    EXPECT_MSG(strstr(why, "0.5 of the global photons aimed through 1 port ($.ports[0] quad of area 100 at "
                           "(500, 300, 500))") != NULL, "%s", why);
    photon_ports pp;
    ASSERT_EQ_INT(ports_build(&pp, &s), 0);
    double ff = 0;
    enum { NL = 32, NH = 8 };
    for (int i = 0; i < NL * NL; i++)
        for (int j = 0; j < NH * NH; j++) {
            vec3 x = v3(400 + 200 * (i % NL + 0.5) / NL, 999.9, 400 + 200 * (i / NL + 0.5) / NL);
            vec3 y = v3(495 + 10 * (j % NH + 0.5) / NH, 300, 495 + 10 * (j / NH + 0.5) / NH);
            vec3 d = v3_sub(y, x);
            double d2 = v3_len2(d), c = -d.y / sqrt(d2); /* both normals along y */
            ff += c * c / d2;
        }
    ff *= (200.0 * 200 / (NL * NL)) * (100.0 / (NH * NH)) / (M_PI * 200 * 200);
    printf("    share of the lamp's power through the hole: ports.h's estimate %.5g, quadrature %.5g (%+.2f%%)\n",
           pp.flux, ff, 100 * (pp.flux / ff - 1));
    EXPECT_MSG(fabs(pp.flux / ff - 1) < 0.03, "estimate %.5g, quadrature %.5g", pp.flux, ff);
    ports_free(&pp);
    s.port_fraction = 0;
    EXPECT_EQ_INT(ports_plan(&s, why, sizeof why), 0);
    EXPECT_MSG(strcmp(why, "1 declared, but port_fraction is 0") == 0, "%s", why);
    s.port_fraction = 0.5;
    s.ports[0] = port_quad(v3(495, 1200, 495), v3(10, 0, 0), v3(0, 0, 10)); /* above the lamp */
    EXPECT_EQ_INT(ports_plan(&s, why, sizeof why), 0);
    EXPECT_MSG(strcmp(why, "1 declared, but no light faces them") == 0, "%s", why);
    scene_free(&s);
    ASSERT_EQ_INT(load_file(&s, "pinhole_room.json"), 0);
    EXPECT_EQ_INT(ports_plan(&s, why, sizeof why), 0);
    EXPECT_MSG(strcmp(why, "none declared in the scene ($.ports)") == 0, "%s", why);
    scene_free(&s);
    static const char *fog =
        "{\"camera\": {\"eye\": [0, 0, 5], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
        " \"materials\": {\"m\": {\"type\": \"lambert\", \"reflectance\": 0.5, \"emission\": 1}},"
        " \"media\": {\"fog\": {\"sigma_a\": 0.01, \"sigma_s\": 0.1}}, \"medium\": \"fog\","
        " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-1, 1, -1], [1, 1, -1], [1, 1, 1], [-1, 1, 1]], \"material\": \"m\"}],"
        " \"ports\": [{\"type\": \"disc\", \"center\": [0, 0, 0], \"normal\": [0, 1, 0], \"radius\": 0.5}]}";
    json_err e;
    ASSERT_MSG(scene_load_text(&s, fog, &e) == 0, "%s", e.msg);
    EXPECT_EQ_INT(ports_plan(&s, why, sizeof why), 1); /* the media tracer aims too (ports.h, MEDIA) */
    EXPECT_MSG(strstr(why, "0.5 of the global photons aimed through 1 port ($.ports[0] disc") != NULL, "%s", why);
    scene_free(&s);
}

/* ---- bounces aimed at the ports ----------------------------------------------------------------- */

/* Oracle: the cosine density, which ports_scatter's weight k must restore: under it sin^2 theta
 * and phi are uniform, so 32 x 32 bins over (sin^2 theta, phi) each hold 1/1024 of the weighted
 * photons (chi-square against the bins' own variances, bound df + 5 sqrt(2 df)), and the weights
 * average 1 within 4 standard errors (a direction below the horizon counts 0). On
 * pinhole_room_ports: a point of the big room's ceiling above the hole (it aims), a point 10
 * above the hole's plane whose horizon cuts the hole (it aims, and the part of the hole below
 * its horizon carries nothing), and a point on the small room's floor under the hole, on the
 * port's dark side: it never aims (k = 1, the cosine direction itself). Each case at a photon's
 * first bounce (aim 1) and at a heavier photon's (aim 3: the share a / 3, ports.h BOUNCES). */
TEST(render_ports_bounce_density) {
    enum { G = 32 };
    const long N = PM_TEST_SANITIZED ? 50000 : 400000;
    scene s;
    ASSERT_EQ_INT(load_file(&s, "pinhole_room_ports.json"), 0);
    photon_ports pp;
    ASSERT_EQ_INT(ports_build(&pp, &s), 0);
    ASSERT(pp.on && pp.side[0] != 0);
    const struct {
        const char *name;
        vec3 x, n;
        int aims;
    } cases[] = {{"the big room's ceiling", {520, 1000, 470}, {0, -1, 0}, 1},
                 {"a wall whose horizon cuts the hole", {499, 310, 500}, {1, 0, 0}, 1},
                 {"the small room's floor", {500, 0, 500}, {0, 1, 0}, 0}};
    static double w1[G * G], w2[G * G];
    for (int ca = 0; ca < 6; ca++) {
        int c = ca % 3;
        double aim = ca < 3 ? 1 : 3;
        memset(w1, 0, sizeof w1);
        memset(w2, 0, sizeof w2);
        rng g = rng_stream(13, (uint64_t)ca, 0);
        vec3 a, b;
        v3_basis(cases[c].n, &a, &b);
        double tot = 0, tot2 = 0;
        long aimed = 0, not_one = 0;
        for (long k = 0; k < N; k++) {
            vec3 nd;
            double u1 = rng_uniform(&g), u2 = rng_uniform(&g);
            double wk = ports_scatter(&pp, cases[c].x, cases[c].n, &g, u1, u2, aim, &nd);
            tot += wk;
            tot2 += wk * wk;
            if (wk != 1) not_one++;
            if (!(wk > 0)) continue;
            double ct = v3_dot(nd, cases[c].n), phi = atan2(v3_dot(nd, b), v3_dot(nd, a));
            if (phi < 0) phi += 2 * M_PI;
            double t_ = 0, cr;
            if (port_cross(&s.ports[0], cases[c].x, nd, &t_, &cr)) aimed++;
            int i = (int)((1 - ct * ct) * G), j = (int)(phi / (2 * M_PI) * G);
            i = i < 0 ? 0 : i >= G ? G - 1 : i;
            j = j < 0 ? 0 : j >= G ? G - 1 : j;
            w1[i * G + j] += wk;
            w2[i * G + j] += wk * wk;
        }
        double chi2 = 0, want = 1.0 / (G * G);
        int df = 0;
        for (int k = 0; k < G * G; k++) {
            /* Pearson's form: the bin's variance at its expected share (the observed share
             * would understate the variance of low bins and inflate the statistic). */
            double m = w1[k] / N, var = (w1[k] > 0 ? w2[k] / w1[k] * want - want * want : 0) / N;
            if (!(var > 0)) continue;
            chi2 += (m - want) * (m - want) / var;
            df++;
        }
        double mean = tot / N, se = sqrt((tot2 / N - mean * mean) / N), bound = df + 5 * sqrt(2.0 * df);
        printf("    %s, aim %g: %.1f%% of the directions cross the hole, weights average %.5f (se %.5f), "
               "chi-square %.1f over %d bins (bound %.0f)\n",
               cases[c].name, aim, 100.0 * aimed / N, mean, se, chi2, df, bound);
        if (cases[c].aims) {
            double share = ports_bounce_share(pp.a, aim); /* the aimed share: at least half of it crosses */
            EXPECT_MSG(aimed > share * N / 2, "%s, aim %g: only %ld of %ld directions cross the hole", cases[c].name,
                       aim, aimed, N);
            EXPECT_MSG(fabs(mean - 1) < 4 * se, "%s: weights average %.5f", cases[c].name, mean);
            EXPECT_MSG(df > G * G / 2 && chi2 < bound, "%s: chi-square %.1f over %d", cases[c].name, chi2, df);
        } else {
            EXPECT_MSG(not_one == 0, "%s: %ld weights are not 1", cases[c].name, not_one);
        }
    }
    ports_free(&pp);
    scene_free(&s);
}

/* A photon that bounces n times on the lit side: the product K of its bounce weights (ports.h
 * BOUNCES). Oracle: each weight has mean 1 given the path before it (the density it was drawn
 * from), so K after 12 bounces averages 1 (within 4 standard errors), and no chain's K passes
 * the bound 1 + n a / (1 - a) (13 at a = 0.5). Before the share fell with K, a chain that
 * missed the hole at every bounce reached 2^n = 4096 at a = 0.5; the test checks that some
 * chains missed it 12 times, so the bound is not met by luck. The chain bounces at
 * the big room's ceiling each time, the photon's K carried over as photon_walk.c does. */
TEST(render_ports_bounce_weight_grows_slowly) {
    enum { NB = 12 };
    const long N = PM_TEST_SANITIZED ? 20000 : 200000;
    scene s;
    ASSERT_EQ_INT(load_file(&s, "pinhole_room_ports.json"), 0);
    photon_ports pp;
    ASSERT_EQ_INT(ports_build(&pp, &s), 0);
    ASSERT(pp.on && pp.a > 0 && pp.a < 1);
    vec3 x = {520, 1000, 470}, n = {0, -1, 0};
    double bound = 1 + NB * pp.a / (1 - pp.a), tot = 0, tot2 = 0, kmax = 0;
    long all_missed = 0;
    rng g = rng_stream(17, 0, 0);
    for (long i = 0; i < N; i++) {
        double K = 1;
        int missed = 0;
        for (int b = 0; b < NB && K > 0; b++) {
            vec3 nd;
            double u1 = rng_uniform(&g), u2 = rng_uniform(&g), t, ck;
            double k = ports_scatter(&pp, x, n, &g, u1, u2, K, &nd);
            K *= k;
            missed += k > 0 && !port_cross(&s.ports[0], x, nd, &t, &ck);
        }
        all_missed += missed == NB;
        tot += K;
        tot2 += K * K;
        if (K > kmax) kmax = K;
    }
    double mean = tot / N, se = sqrt((tot2 / N - mean * mean) / N);
    printf("    %d bounces, a %g: K averages %.5f (se %.5f), at most %.3f (bound %.3f); %ld of %ld chains missed "
           "the hole every time\n", NB, pp.a, mean, se, kmax, bound, all_missed, N);
    EXPECT_MSG(fabs(mean - 1) < 4 * se, "K averages %.5f (se %.5f)", mean, se);
    EXPECT_MSG(kmax <= bound * (1 + 1e-12), "K reached %.4f, over 1 + n a / (1 - a) = %.4f", kmax, bound);
    EXPECT_MSG(all_missed > 0, "no chain missed the hole %d times: the old rule's 2^%d was not tried", NB, NB);
    ports_free(&pp);
    scene_free(&s);
}

/* ---- pinhole_room with its hole as a port ------------------------------------------------------ */

/* MEASURED (at d3c7df1, the test's settings, seeds 1-12, photon maps and samples both varying;
 * /tmp scripts, not kept): against the reference, region means in %
 *                      whole image          lit patch            walls and ceiling
 *   pinhole_room       -1.40..+0.45         -2.99..+0.92         -2.40..+3.01
 *                      mean -0.60, sd 0.58  mean -0.86, sd 1.34  mean +0.32, sd 1.76
 *   with the port      -2.09..+1.59         -2.49..+1.35         -2.67..+4.83
 *                      mean -0.13, sd 1.08  mean -0.85, sd 1.36  mean +1.20, sd 2.14
 * at a median of 6.1 CPU-s a render with the port against 15.2 without (user + system, 2
 * threads, a shared machine): the port puts the room's light in the photon map (the gathers read it; the gather
 * guide is not needed and stays off), at less than half the cost, but at equal samples the
 * region means do not move closer to the reference: the noise left is the camera's and the
 * gathers'. At about equal time they do: with the port at 40960 spp (a median 11.5 CPU-s, still
 * below the 15.2 without), seeds 1-6 read whole -0.60..+0.83% (rms 0.51), patch -0.96..+1.31%
 * (rms 0.77), walls -2.27..+2.39% (rms 1.44), against rms 0.86, 1.55 and 1.84 without the port
 * at 16384 spp on the same seeds. Emission ports alone, before the bounces aimed too, read walls -18.45..+42.49%
 * (seeds 1-6). Bounds: whole 4% (3.6 sd from the mean), patch 5% (3.1 sd), walls 6% (2.2 sd, as
 * render_hard_pinhole_room_regions's walls); seed 1 reads +0.29, +1.35, -0.05%.
 * At 983b284 (the gathers aim at the port and the direct light takes a ray through it)
 * seeds 1-12 read whole -2.02..+1.04% (rms 1.02), patch -2.06..+0.13% (rms 1.41: mean -1.27, sd
 * 0.63, the photon map's offset that render_hard_pinhole_room_regions describes), walls
 * -2.46..+3.75% (rms 1.58); seed 1: +0.17, +0.13, +0.65%. All inside the bounds. */
#define PINHOLE_PORT_REGIONS \
    {{"whole image", 0, 0, 8, 8, 0.04}, {"lit patch", 2, 6, 6, 8, 0.05}, {"walls and ceiling", 0, 0, 8, 5, 0.06}}

/* Oracle: the long path-traced reference of pinhole_room (data/reference-hard/pinhole_room.pfm,
 * tests/test_render_hard.c says how it was made), which is also pinhole_room_ports.json's: the
 * two files load to the same scene (scene_transport_hash leaves ports out: they do not change
 * what the scene does to light), and pinhole_room.json is still the file the reference was
 * rendered from (its SHA-256 in the reference's .info). The same render as
 * render_hard_pinhole_room_regions (8 x 8, 16384 spp, one gather and one secondary ray, seed 1),
 * with region bounds from twelve seeds (MEASURED above). */
TEST(render_ports_pinhole_room_regions) {
    typedef struct {
        const char *name;
        int x0, y0, x1, y1;
        double tol;
    } region;
    const region r[] = PINHOLE_PORT_REGIONS;
    scene a, b;
    ASSERT_EQ_INT(load_file(&a, "pinhole_room.json"), 0);
    ASSERT_EQ_INT(load_file(&b, "pinhole_room_ports.json"), 0);
    EXPECT_MSG(scene_transport_hash(&a) == scene_transport_hash(&b) && a.nports == 0 && b.nports == 1,
               "pinhole_room_ports.json is not pinhole_room.json with a port");
    scene_free(&a);
    scene_free(&b);
    char scn[1024], ref[1024], pm[1024], cmd[4096], want[256] = "", got[256] = "", out[16384];
    snprintf(scn, sizeof scn, "%s/data/scenes/pinhole_room.json", pm_test_source_dir());
    snprintf(ref, sizeof ref, "%s/data/reference-hard/pinhole_room.pfm", pm_test_source_dir());
    snprintf(pm, sizeof pm, "%s/pinhole_room_ports_pm.pfm", pm_test_tmpdir());
    snprintf(cmd, sizeof cmd, "awk '$1 == \"scene_sha256\" { print $2 }' '%s/data/reference-hard/pinhole_room.info'",
             pm_test_source_dir());
    ASSERT_EQ_INT(pm_test_run(cmd, want, sizeof want), 0);
    snprintf(cmd, sizeof cmd, "sha256sum '%s' | cut -d' ' -f1", scn);
    ASSERT_EQ_INT(pm_test_run(cmd, got, sizeof got), 0);
    ASSERT_MSG(want[0] && strcmp(want, got) == 0, "%s changed since its reference was rendered", scn);
    snprintf(cmd, sizeof cmd,
             "'%s/render' '%s/data/scenes/pinhole_room_ports.json' --width 8 --height 8 --hdr '%s' --mode pm "
             "--spp %d --pm gather_rays=1 --pm secondary_rays=1 --seed 1",
             pm_test_build_dir(), pm_test_source_dir(), pm, PM_TEST_SANITIZED ? 1024 : 16384);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    /* The plan's pilot joins, the ports are used: the room is lit by the map. */
    EXPECT_MSG(strstr(out, "the pilot's") && strstr(out, "join the global map"), "%s", out);
    film fa, fb;
    ASSERT_MSG(film_read_pfm(&fa, ref) == 0, "cannot read %s", ref);
    ASSERT(fa.width == 8 && fa.height == 8 && film_read_pfm(&fb, pm) == 0);
    for (int i = 0; i < 3; i++) {
        double ma = rt_rect_mean(&fa, r[i].x0, r[i].y0, r[i].x1, r[i].y1);
        double mb = rt_rect_mean(&fb, r[i].x0, r[i].y0, r[i].x1, r[i].y1);
        double rel = ma > 0 ? mb / ma - 1 : INFINITY;
        printf("    pinhole_room_ports %s: reference %.5g pm %.5g (%+.2f%%, bound %.1f%%)\n", r[i].name, ma, mb,
               100 * rel, 100 * r[i].tol);
        if (!PM_TEST_SANITIZED) EXPECT_MSG(fabs(rel) < r[i].tol, "%s: %+.2f%%", r[i].name, 100 * rel);
    }
    film_free(&fa);
    film_free(&fb);
}
