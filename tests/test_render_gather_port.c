/* test_render_gather_port.c: the gather guide aimed at a photon port (gather_guide.h, PORTS AS
 * OPENINGS): where the scene has a port and the pilot finds neither an opening nor a bright
 * patch, the gathers aim at a disc around the port, from its dark side.
 *
 * Oracles: the port's geometry (its centre; a quad's circumscribed radius, half its longer
 * diagonal) and the lights' positions (which side of the port's plane holds their power); the
 * photon mapper without the guide (gather_guide=false, the same maps loaded from a file) for
 * the mean of pinhole_room's image with the port-aimed guide; the renderer's own output for
 * thread independence; path tracing for the means of cornell_box and cornell_spheres with a
 * port declared and every guide forced on (the "unbiased" target).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "test_render_run.h"
#include "../render/image/film.h"
#include "test_film.h"
#include "../render/guiding/gather_guide.h"
#include "../render/load/scene_load.h"
#include "../render/base/rng.h"
#include "../render/guiding/guide.h"
#include "../render/integrators/direct.h"
#include "../render/scene/port.h"
#include "../render/load/photon_settings.h"

/* A floor, a 10 x 10 port at height 3 and area lights given by LIGHTS (JSON objects). */
static int gp_scene(scene *s, const char *ports, const char *lights) {
    char text[4096];
    snprintf(text, sizeof text,
             "{\"camera\": {\"eye\": [0, 1, -5], \"look_at\": [0, 1, 0], \"fov_deg\": 60, \"width\": 8, \"height\": 8},"
             " \"materials\": {\"white\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
             "  \"lamp\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": 10}},"
             " \"objects\": [{\"type\": \"quad\", \"vertices\": [[-20, 0, -20], [-20, 0, 20], [20, 0, 20], [20, 0, -20]],"
             " \"material\": \"white\"}%s],"
             " \"ports\": [%s]}",
             lights, ports);
    json_err e;
    int rc = scene_load_text(s, text, &e);
    if (rc != 0) printf("    scene: %s\n", e.msg);
    return rc;
}

static const char *LAMP_ABOVE = ", {\"type\": \"quad\", \"vertices\": [[-1, 9, -1], [1, 9, -1], [1, 9, 1], [-1, 9, 1]],"
                                " \"material\": \"lamp\"}";
static const char *LAMP_BELOW = ", {\"type\": \"quad\", \"vertices\": [[-1, 1, -1], [-1, 1, 1], [1, 1, 1], [1, 1, -1]],"
                                " \"material\": \"lamp\"}";
static const char *QUAD_UP = "{\"type\": \"quad\", \"corner\": [-5, 3, -5], \"edge1\": [10, 0, 0], \"edge2\": [0, 0, 10]}";
static const char *QUAD_DOWN = "{\"type\": \"quad\", \"corner\": [-5, 3, -5], \"edge1\": [0, 0, 10], \"edge2\": [10, 0, 0]}";

/* Oracle: the geometry. A 10 x 10 quad port at y = 3 (centre (0, 3, 0), circumscribed radius
 * 5 sqrt 2) with the lamp above it: lit points up (+y), whichever way the port's normal points,
 * so a point 11 below it aims and a point 11 above does not (WHO AIMS: more than the radius
 * away along lit); the lamp below: lit points down;
 * a lamp on each side with the same power: lit unknown (zero), every point in front aims; a
 * disc port keeps its own radius. The plan's words name the port. */
TEST(render_gather_port_disc_and_side) {
    struct {
        const char *name, *port, *lights;
        double lit_y, radius;
    } c[] = {
        {"quad up, lamp above", QUAD_UP, LAMP_ABOVE, 1, 5 * 1.4142135623730951},
        {"quad down, lamp above", QUAD_DOWN, LAMP_ABOVE, 1, 5 * 1.4142135623730951},
        {"quad up, lamp below", QUAD_UP, LAMP_BELOW, -1, 5 * 1.4142135623730951},
        {"lamps on both sides", QUAD_UP, NULL, 0, 5 * 1.4142135623730951},
        {"disc, lamp above", "{\"type\": \"disc\", \"center\": [0, 3, 0], \"normal\": [0, 1, 0], \"radius\": 2}",
         LAMP_ABOVE, 1, 2},
    };
    char both[1024];
    snprintf(both, sizeof both, "%s%s", LAMP_ABOVE, LAMP_BELOW);
    for (size_t i = 0; i < sizeof c / sizeof c[0]; i++) {
        scene s;
        ASSERT_MSG(gp_scene(&s, c[i].port, c[i].lights ? c[i].lights : both) == 0, "%s", c[i].name);
        ASSERT(s.nports == 1);
        gather_guide gg;
        gather_guide_init(&gg);
        char what[400];
        gather_guide_port(&gg, &s, &s.ports[0], what, sizeof what);
        printf("    %-22s centre (%g, %g, %g), radius %.4g, lit (%g, %g, %g)\n", c[i].name, gg.centre.x, gg.centre.y,
               gg.centre.z, gg.radius, gg.lit.x, gg.lit.y, gg.lit.z);
        EXPECT_MSG(gg.on && gg.aim, "%s: not aimed", c[i].name);
        EXPECT_MSG(fabs(gg.centre.x) < 1e-9 && fabs(gg.centre.y - 3) < 1e-9 && fabs(gg.centre.z) < 1e-9, "%s: centre",
                   c[i].name);
        EXPECT_MSG(fabs(gg.radius - c[i].radius) < 1e-9, "%s: radius %g, want %g", c[i].name, gg.radius, c[i].radius);
        EXPECT_MSG(gg.lit.x == 0 && gg.lit.z == 0 && gg.lit.y == c[i].lit_y, "%s: lit (%g, %g, %g)", c[i].name,
                   gg.lit.x, gg.lit.y, gg.lit.z);
        EXPECT_MSG(strstr(what, "aim at the photon port"), "%s: %s", c[i].name, what);
        double below = gather_guide_share(&gg, v3(0.5, -8, 0), v3(0, 1, 0));
        double above = gather_guide_share(&gg, v3(0.5, 14, 0), v3(0, -1, 0));
        double want_below = c[i].lit_y >= 0 ? GATHER_GUIDE_SHARE : 0;
        double want_above = c[i].lit_y <= 0 ? GATHER_GUIDE_SHARE : 0;
        EXPECT_MSG(below == want_below && above == want_above, "%s: share below %g, above %g", c[i].name, below,
                   above);
        gather_guide_free(&gg);
        scene_free(&s);
    }
}

/* Render data/scenes/NAME.json in pm mode with FLAGS into the temp dir as TAG.pfm; out: what it
 * printed. */
static int gp_render(const char *name, const char *flags, const char *tag, char *out, size_t cap) {
    char sc[256], args[4096];
    snprintf(sc, sizeof sc, "'%%s/data/scenes/%s.json'", name);
    snprintf(args, sizeof args, "--mode pm --quiet --hdr '%s.pfm' %s 2>&1", tag, flags);
    return rt_render(sc, args, out, cap);
}

/* Oracle: the plan's geometry and the photon mapper without the guide. pinhole_room (the plan
 * finds the port at the hole) and pinhole_room_ports (declared there) plan the guide on, aimed
 * at the port's disc at (500, 300, 500) with its light along +y (the lamp is above the hole),
 * of radius about 7.07 (the 10 x 10 hole's half diagonal; the found port is grown 5% at each
 * edge, ports.h THE FIT: about 7.8),
 * and gathers are aimed; 1 and 2 threads give the same image. On the same photon maps (traced
 * once, loaded), 4 x 4 at 1024 spp, seeds 1-4, light guide off so only the gathers differ, the
 * port-aimed and the cosine means of the whole image agree within 4 standard errors of their
 * difference. */
TEST(render_gather_port_pinhole_room) {
    static char out[65536];
    const char *scn[2] = {"pinhole_room", "pinhole_room_ports"};
    for (int i = 0; i < 2; i++) {
        ASSERT_EQ_INT(gp_render(scn[i], "--width 8 --height 8 --spp 4 --threads 1", "gp1", out, sizeof out), 0);
        const char *p = strstr(out, "gather guide: on (");
        ASSERT_MSG(p, "%s: %s", scn[i], strstr(out, "gather guide") ? strstr(out, "gather guide") : out);
        const char *q = strstr(p, "aim at the photon port instead: a disc of radius ");
        ASSERT_MSG(q, "%s: %.600s", scn[i], p);
        double r, x, y, z, lx, ly, lz;
        ASSERT(sscanf(q, "aim at the photon port instead: a disc of radius %lf at (%lf, %lf, %lf)", &r, &x, &y, &z) == 4);
        const char *l = strstr(q, "on its side along (");
        ASSERT_MSG(l && sscanf(l, "on its side along (%lf, %lf, %lf)", &lx, &ly, &lz) == 3, "%.400s", q);
        printf("    %s: disc radius %.3g at (%.1f, %.1f, %.1f), light along (%g, %g, %g)\n", scn[i], r, x, y, z, lx, ly,
               lz);
        EXPECT_MSG(fabs(x - 500) < 1 && fabs(y - 300) < 1 && fabs(z - 500) < 1 && r > 6.5 && r < 8 && ly > 0.99,
                   "%s: radius %g at (%g, %g, %g), lit y %g", scn[i], r, x, y, z, ly);
        const char *aimed = strstr(out, "Gather rays aimed at the opening (gather guide)");
        EXPECT_MSG(aimed && atol(aimed + strlen("Gather rays aimed at the opening (gather guide)")) > 0, "%s: none aimed",
                   scn[i]);
        ASSERT_EQ_INT(gp_render(scn[i], "--width 8 --height 8 --spp 4 --threads 2", "gp2", out, sizeof out), 0);
        film a, b;
        char pa[1024], pb[1024];
        snprintf(pa, sizeof pa, "%s/gp1.pfm", pm_test_tmpdir());
        snprintf(pb, sizeof pb, "%s/gp2.pfm", pm_test_tmpdir());
        ASSERT(film_read_pfm(&a, pa) == 0 && film_read_pfm(&b, pb) == 0);
        EXPECT_MSG(memcmp(a.px, b.px, sizeof *a.px * 3 * (size_t)a.width * a.height) == 0, "%s: 1 and 2 threads differ",
                   scn[i]);
        film_free(&a);
        film_free(&b);
    }

    enum { N = 4 };
    char flags[2048], tag[64];
    snprintf(flags, sizeof flags, "--width 4 --height 4 --spp 1 --save-photons '%s/gp_maps'", pm_test_tmpdir());
    ASSERT_EQ_INT(gp_render("pinhole_room", flags, "gp_maps", out, sizeof out), 0);
    double m[2][N];
    for (int on = 0; on < 2; on++)
        for (int i = 0; i < N; i++) {
            snprintf(flags, sizeof flags,
                     "--width 4 --height 4 --spp 1024 --seed %d --load-photons '%s/gp_maps' --pm light_guide=false "
                     "--pm gather_rays=1 --pm secondary_rays=1%s",
                     i + 1, pm_test_tmpdir(), on ? "" : " --pm gather_guide=false");
            snprintf(tag, sizeof tag, "gp%d_%d", on, i);
            ASSERT_EQ_INT(gp_render("pinhole_room", flags, tag, out, sizeof out), 0);
            if (on) ASSERT_MSG(strstr(out, "aim at the photon port instead"), "%s", strstr(out, "gather guide"));
            m[on][i] = rt_tmp_mean(tag);
        }
    double mean[2], var[2];
    for (int on = 0; on < 2; on++) rt_mean_var(m[on], N, &mean[on], &var[on]);
    double se = sqrt((var[0] + var[1]) / N), d = mean[1] - mean[0];
    printf("    pinhole_room whole image: cosine %.5g (sd %.1f%%), aimed at the port %.5g (sd %.1f%%), difference "
           "%+.2f%% (se %.2f%%)\n",
           mean[0], 100 * sqrt(var[0]) / mean[0], mean[1], 100 * sqrt(var[1]) / mean[1], 100 * d / mean[0],
           100 * se / mean[0]);
    EXPECT_MSG(fabs(d) <= 4 * se, "aimed %g vs cosine %g: %+.2f%% (4 se %.2f%%)", mean[1], mean[0], 100 * d / mean[0],
               400 * se / mean[0]);
}

/* Oracle: path tracing, the same scene. cornell_box and cornell_spheres with a port declared
 * in the open room (a 200 x 175 quad at y = 400 under the lamp: it blocks nothing, and light
 * reaches most points both through it and around it) and the light and gather guides forced
 * on: half the global photons are aimed through the port, the gathers aim at it where the
 * pilot finds no patch, and the direct light at the points under it takes a ray through it
 * (direct.h, THROUGH A PORT). The image mean over seeds 1-4 (16 x 16, 64 spp) stays within 4
 * standard errors (the seeds' spread) plus 1% of path tracing's (16 x 16, 4096 spp; photon
 * mapping's own blur reads cornell_box about -0.2..-0.6% low, README.md), and within the same
 * of the seeds' mean without the port and the forced guides. */
TEST(render_gather_port_forced_on_keeps_the_means) {
    static char out[65536];
    const char *scn[2] = {"cornell_box", "cornell_spheres"};
    for (int k = 0; k < 2; k++) {
        char cmd[4096], file[1024], flags[1024], tag[64];
        snprintf(file, sizeof file, "%s/%s_port.json", pm_test_tmpdir(), scn[k]);
        snprintf(cmd, sizeof cmd,
                 "sed '1s/^{/{\"ports\": [{\"type\": \"quad\", \"corner\": [178, 400, 192], \"edge1\": [200, "
                 "0, 0], \"edge2\": [0, 0, 175]}],/' '%s/data/scenes/%s.json' > '%s'",
                 pm_test_source_dir(), scn[k], file);
        ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
        snprintf(cmd, sizeof cmd, "%s/render '%s/data/scenes/%s.json' --mode path --quiet --width 16 --height 16 "
                 "--spp 4096 --seed 99 --hdr '%s/gpf_path.pfm' 2>&1", pm_test_build_dir(), pm_test_source_dir(),
                 scn[k], pm_test_tmpdir());
        ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
        double path = rt_tmp_mean("gpf_path"), m[2] = {0, 0}, v[2] = {0, 0};
        enum { N = 4 };
        for (int on = 0; on < 2; on++)
            for (int i = 0; i < N; i++) {
                char src[1024];
                snprintf(src, sizeof src, "%s/data/scenes/%s.json", pm_test_source_dir(), scn[k]);
                snprintf(flags, sizeof flags, "%s", on ? "--pm light_guide=true --pm gather_guide=true" : "");
                snprintf(tag, sizeof tag, "gpf%d_%d", on, i);
                snprintf(cmd, sizeof cmd, "%s/render '%s' --mode pm --quiet --width 16 --height 16 --spp 64 --seed %d "
                         "--hdr '%s/%s.pfm' %s 2>&1", pm_test_build_dir(), on ? file : src, i + 1, pm_test_tmpdir(), tag,
                         flags);
                ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
                if (on && i == 0) {
                    EXPECT_MSG(strstr(out, "photon ports: on"), "%s: %s", scn[k], strstr(out, "photon ports"));
                    EXPECT_MSG(strstr(out, "direct light through the port: on"), "%s: %s", scn[k],
                               strstr(out, "direct light through"));
                    EXPECT_MSG(strstr(out, "gather guide: on"), "%s: %s", scn[k], strstr(out, "gather guide"));
                }
                double x = rt_tmp_mean(tag);
                m[on] += x / N;
                v[on] += x * x / N;
            }
        double sd[2], se;
        for (int on = 0; on < 2; on++) sd[on] = sqrt(fmax(0, (v[on] - m[on] * m[on]) * N / (N - 1)));
        se = sd[1] / sqrt(N);
        printf("    %s: path %.5g; pm with the port and guides %.5g (%+.2f%%, se %.2f%%); without %.5g (%+.2f%%)\n",
               scn[k], path, m[1], 100 * (m[1] / path - 1), 100 * se / path, m[0], 100 * (m[0] / path - 1));
        EXPECT_MSG(fabs(m[1] - path) <= 4 * se + 0.01 * path, "%s: with the port %.5g, path %.5g", scn[k], m[1], path);
        double se2 = sqrt((sd[0] * sd[0] + sd[1] * sd[1]) / N);
        EXPECT_MSG(fabs(m[1] - m[0]) <= 4 * se2 + 0.01 * m[0], "%s: with the port %.5g, without %.5g", scn[k], m[1], m[0]);
    }
}

/* A sphere lamp (radius 0.3 at height 2) over a roof at height 1 with a 0.1 x 0.1 hole, a floor
 * at 0: the hole scene of test_render_guide.c with a sphere light, whose points the direct
 * light's port branch inverts through sample_uniform_sphere's map (direct.c, light_point_uv). */
static const char *SPHERE_HOLE =
    "{\"camera\": {\"eye\": [0, 0.6, 0.6], \"look_at\": [0, 0, 0], \"fov_deg\": 40, \"width\": 8, \"height\": 8},"
    "\"materials\": {\"w\": {\"type\": \"lambert\", \"reflectance\": 0.5},"
    "  \"e\": {\"type\": \"lambert\", \"reflectance\": 0, \"emission\": [3, 2, 1]}},"
    "\"objects\": ["
    " {\"type\": \"quad\", \"vertices\": [[-3,0,-3],[-3,0,3],[3,0,3],[3,0,-3]], \"material\": \"w\"},"
    " {\"type\": \"sphere\", \"center\": [0, 2, 0], \"radius\": 0.3, \"material\": \"e\"},"
    " {\"type\": \"quad\", \"vertices\": [[-3,1,-3],[3,1,-3],[3,1,-0.05],[-3,1,-0.05]], \"material\": \"w\"},"
    " {\"type\": \"quad\", \"vertices\": [[-3,1,0.05],[3,1,0.05],[3,1,3],[-3,1,3]], \"material\": \"w\"},"
    " {\"type\": \"quad\", \"vertices\": [[-3,1,-0.05],[-0.05,1,-0.05],[-0.05,1,0.05],[-3,1,0.05]], \"material\": \"w\"},"
    " {\"type\": \"quad\", \"vertices\": [[0.05,1,-0.05],[3,1,-0.05],[3,1,0.05],[0.05,1,0.05]], \"material\": \"w\"}"
    "]}";

/* The direct light at floor point (x, 0, z) by n samples (guide gd or NULL, port pt or NULL):
 * mean and standard error of the luminance. */
static void gp_direct_at(const scene *s, const guide *gd, const port *pt, double x, double z, long n, double *mean,
                         double *se) {
    hit h;
    *mean = *se = NAN;
    if (!scene_intersect(s, (ray){v3(x, 0.5, z), v3(0, -1, 0)}, INFINITY, &h)) return;
    direct_options o = {DIRECT_BSDF_FULL, 0, NULL, NULL, -1, pt, {0, 1, 0}};
    rng g = rng_stream(77, 3, 4);
    double s1 = 0, s2 = 0;
    for (long k = 0; k < n; k++) {
        double y = rgb_lum(direct_light_surface_guided(s, scene_material(s, &h), &h, v3(0, 1, 0), v3(0, 1, 0), &g, &o,
                                                       gd));
        s1 += y;
        s2 += y * y;
    }
    *mean = s1 / n;
    *se = sqrt(fmax(0, s2 / n - *mean * *mean) / n);
}

/* Oracle: the plain light sampling (no guide, no port: uniform points on the sphere, unbiased
 * by construction, tests/test_render_light.c), at 4,000,000 samples. With a sphere light the
 * direct light through the port must agree with it within 4 standard errors of the difference,
 * with and without the learned light guide (whose table density the port branch reads at the
 * inverted (u1, u2) of the sphere point its ray hits), at three floor points under the hole;
 * and the port must pay there (a standard error under half the plain one's at a tenth of the
 * samples, scaled). What it does not catch: a wrong (u1, u2) inversion. Where the port rays
 * carry the light their weight is nearly 1 / (b p_port), so the light sample's density there
 * barely counts; a build with u1 mirrored (1 + z) moved the means by under 0.1%, inside the
 * plain estimate's 0.3% standard error, and passed. */
TEST(render_gather_port_direct_light_sphere_lamp) {
    scene s;
    json_err e;
    ASSERT_MSG(scene_load_text(&s, SPHERE_HOLE, &e) == 0, "%s", e.msg);
    int on = 0;
    char reason[400];
    guide_light_evidence ev;
    guide *gd = guide_light_make(&s, PLAN_ON, 1, &on, reason, sizeof reason, &ev);
    ASSERT_MSG(on && gd, "%s", reason);
    port hole = port_quad(v3(-0.05, 1, -0.05), v3(0.1, 0, 0), v3(0, 0, 0.1));
    const double xs[3] = {0, 0.06, -0.1}, zs[3] = {0, 0.03, 0.05};
    for (int p = 0; p < 3; p++) {
        double m0, s0, m1, s1, m2, s2;
        gp_direct_at(&s, NULL, NULL, xs[p], zs[p], 4000000, &m0, &s0);
        gp_direct_at(&s, NULL, &hole, xs[p], zs[p], 400000, &m1, &s1);
        gp_direct_at(&s, gd, &hole, xs[p], zs[p], 400000, &m2, &s2);
        printf("    (%g, %g): plain %.6g (se %.2g); port %.6g (se %.2g); port and guide %.6g (se %.2g)\n", xs[p], zs[p],
               m0, s0, m1, s1, m2, s2);
        EXPECT_MSG(m0 > 0, "no light reaches (%g, %g)", xs[p], zs[p]);
        EXPECT_MSG(fabs(m1 - m0) <= 4 * sqrt(s0 * s0 + s1 * s1), "port: %g vs %g", m1, m0);
        EXPECT_MSG(fabs(m2 - m0) <= 4 * sqrt(s0 * s0 + s2 * s2), "port and guide: %g vs %g", m2, m0);
        EXPECT_MSG(s2 * sqrt(0.1) < 0.5 * s0, "the port does not pay: se %g at 400000, plain %g at 4000000", s2, s0);
    }
    guide_destroy(gd);
    scene_free(&s);
}

/* photon_mapping.direct_port (direct.h, THROUGH A PORT), on pinhole_room_ports (its hole
 * declared as a port), 8 x 8 pm. (a) Absent, the plan turns it on; false turns it off, and the
 * port's rays go: fewer shadow rays, the same photon maps (the line of stored photons is the
 * same). (b) With a point lamp of 5x the area lamp's power added over the hole, the plan keeps
 * it off (area and sphere lights under half the power) and true forces it on; the two image
 * means agree within 4 standard errors plus 0.5% (the oracle: both are unbiased estimates of
 * the same image). Paired by seed (1-4, 1024 spp): a seed's photon maps are the same either
 * way, so the seeds' differences hold the camera samples' noise alone, not the maps'. */
TEST(render_direct_port_setting) {
    static char out[65536];
    char cmd[4096], file[1024], src[1024];
    snprintf(src, sizeof src, "%s/data/scenes/pinhole_room_ports.json", pm_test_source_dir());
    double shadow[2], stored[2];
    for (int off = 0; off < 2; off++) {
        snprintf(cmd, sizeof cmd, "%s/render '%s' --mode pm --width 8 --height 8 --spp 16 --seed 1 --threads 2 "
                 "--hdr '%s/dp.pfm' %s 2>&1", pm_test_build_dir(), src, pm_test_tmpdir(),
                 off ? "--pm direct_port=false" : "");
        ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
        const char *want = off ? "direct light through the port: off (photon_mapping.direct_port=false)"
                               : "direct light through the port: on (the port at (500, 300, 500)";
        EXPECT_MSG(strstr(out, want), "%s: %s", want, strstr(out, "direct light through"));
        const char *p = strstr(out, "Shadow rays"), *q = strstr(out, "Photons: ");
        shadow[off] = p ? strtod(p + strlen("Shadow rays"), NULL) : NAN;
        stored[off] = q ? strtod(q + strlen("Photons: "), NULL) : NAN;
    }
    EXPECT_MSG(shadow[1] < shadow[0], "shadow rays: on %g, off %g", shadow[0], shadow[1]);
    EXPECT_MSG(stored[1] == stored[0] && stored[0] > 0, "global photons: on %g, off %g", stored[0], stored[1]);

    snprintf(file, sizeof file, "%s/pinhole_point.json", pm_test_tmpdir());
    snprintf(cmd, sizeof cmd, "sed '1s/^{/{\"lights\": [{\"type\": \"point\", \"position\": [500, 900, 500], "
             "\"power\": [10000000, 7000000, 2500000]}],/' '%s' > '%s'", src, file);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    enum { N = 4 };
    double x[2][N], m[2] = {0, 0};
    for (int on = 0; on < 2; on++)
        for (int i = 0; i < N; i++) {
            char tag[32];
            snprintf(tag, sizeof tag, "dpp%d_%d", on, i);
            snprintf(cmd, sizeof cmd, "%s/render '%s' --mode pm --width 8 --height 8 --spp 1024 --seed %d --threads 2 "
                     "--hdr '%s/%s.pfm' %s 2>&1", pm_test_build_dir(), file, i + 1, pm_test_tmpdir(), tag,
                     on ? "--pm direct_port=true" : "");
            ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
            if (i == 0) {
                const char *want = on ? "direct light through the port: on (photon_mapping.direct_port=true; the port"
                                      : "direct light through the port: off (the port at (500, 300, 500): area and "
                                        "sphere lights carry under half";
                EXPECT_MSG(strstr(out, want), "%s: %s", want, strstr(out, "direct light through"));
            }
            x[on][i] = rt_tmp_mean(tag);
            m[on] += x[on][i] / N;
        }
    double diff[N], d, var;
    for (int i = 0; i < N; i++) diff[i] = x[1][i] - x[0][i];
    rt_mean_var(diff, N, &d, &var);
    double se = sqrt(var / N);
    printf("    point lamp over the hole: plan's choice (off) %.5g, forced on %.5g (%+.3f%%, se of the paired "
           "difference %.3f%%)\n", m[0], m[1], 100 * d / m[0], 100 * se / m[0]);
    EXPECT_MSG(fabs(d) <= 4 * se + 0.005 * m[0], "forced on %.5g, off %.5g", m[1], m[0]);
}
