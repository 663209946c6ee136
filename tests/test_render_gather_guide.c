/* test_render_gather_guide.c: the photon mapper's gather guide (render/photon_mapping/photonmapper.c, GATHER
 * GUIDE): gather rays aimed at an opening the pilot finds, weighted by the mixture's density.
 *
 * Oracles: closed forms for the mixture's own estimate (the irradiance of a constant sky and
 * of a disc seen on and off its axis; a 1-D quadrature of a smooth integrand for a disc
 * straddling the horizon); the scene's geometry (pinhole_room's hole is the square 495..505 x
 * 495..505 at y = 300: the opening the plan reports must lie in it); the photon mapper without
 * the guide (gather_guide=false: the same maps, cosine gathers) for the mean; the renderer's
 * own output for "unchanged where off" (byte-identical images) and for thread independence; the
 * geometry of which points aim (gather_guide.h, WHO AIMS).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "../render/image/film.h"
#include "test_film.h"
#include "../render/guiding/gather_guide.h"
#include "../render/base/rng.h"

/* Render data/scenes/NAME.json with FLAGS into DIR/TAG.pfm; the output in out. pinhole_room with
 * "find_ports": false: the guide is for a room the photon map does not reach, and the port the
 * plan finds at the hole (photons/ports.h) would fill it with photons (the guide then, rightly,
 * stays off). */
static int gg_render(const char *name, const char *flags, const char *tag, char *out, size_t cap) {
    char cmd[4096], scn[1024];
    snprintf(scn, sizeof scn, "%s/data/scenes/%s.json", pm_test_source_dir(), name);
    if (strcmp(name, "pinhole_room") == 0) {
        snprintf(scn, sizeof scn, "%s/pinhole_room_no_ports.json", pm_test_tmpdir());
        snprintf(cmd, sizeof cmd, "sed '1s/^{/{\"find_ports\": false,/' '%s/data/scenes/pinhole_room.json' > '%s'",
                 pm_test_source_dir(), scn);
        int rc = pm_test_run(cmd, out, cap);
        if (rc != 0) return rc;
    }
    snprintf(cmd, sizeof cmd, "%s/render '%s' --mode pm --quiet --hdr '%s/%s.pfm' %s 2>&1", pm_test_build_dir(), scn,
             pm_test_tmpdir(), tag, flags);
    return pm_test_run(cmd, out, cap);
}

static int gg_same_file(const char *a, const char *b) {
    char pa[1024], pb[1024];
    snprintf(pa, sizeof pa, "%s/%s.pfm", pm_test_tmpdir(), a);
    snprintf(pb, sizeof pb, "%s/%s.pfm", pm_test_tmpdir(), b);
    FILE *fa = fopen(pa, "rb"), *fb = fopen(pb, "rb");
    int same = fa && fb;
    while (same) {
        int ca = fgetc(fa), cb = fgetc(fb);
        if (ca != cb) same = 0;
        if (ca == EOF || cb == EOF) break;
    }
    if (fa) fclose(fa);
    if (fb) fclose(fb);
    return same;
}

/* Oracle: the geometry and the renderer's own images. pinhole_room plans the guide on, with
 * the opening's centre inside the 10 x 10 hole (and in its plane within 1 unit); the shipped
 * scenes without an opening plan it off, and there the image is byte-identical to
 * gather_guide=false (the gathers draw the same numbers as without the guide). With the guide
 * on, 1 and 2 threads give the same image (the pilot's streams are per point). */
TEST(render_gather_guide_plan) {
    static char out[65536];
    ASSERT_EQ_INT(gg_render("pinhole_room", "--width 8 --height 8 --spp 4 --threads 1", "pin1", out, sizeof out), 0);
    const char *p = strstr(out, "gather guide: on (");
    ASSERT_MSG(p, "pinhole_room: %s", out);
    const char *q = strstr(p, "an opening at (");
    ASSERT_MSG(q, "no opening: %.300s", p);
    double x, y, z;
    ASSERT(sscanf(q, "an opening at (%lf, %lf, %lf)", &x, &y, &z) == 3);
    printf("    pinhole_room opening at (%.2f, %.2f, %.2f)\n", x, y, z);
    EXPECT_MSG(x > 495 && x < 505 && z > 495 && z < 505 && fabs(y - 300) < 1, "(%g, %g, %g)", x, y, z);
    const char *aimed = strstr(out, "Gather rays aimed at the opening (gather guide)");
    EXPECT_MSG(aimed && atol(aimed + strlen("Gather rays aimed at the opening (gather guide)")) > 0, "no aimed ray");
    ASSERT_EQ_INT(gg_render("pinhole_room", "--width 8 --height 8 --spp 4 --threads 2", "pin2", out, sizeof out), 0);
    EXPECT_MSG(gg_same_file("pin1", "pin2"), "pinhole_room: 1 and 2 threads differ");

    const char *off[] = {"cornell_box", "cornell_spheres", "shelf_glass", "partition_thin", "partition_thick"};
    for (int i = 0; i < 5; i++) {
        ASSERT_EQ_INT(gg_render(off[i], "--width 8 --height 8 --spp 1", "auto", out, sizeof out), 0);
        EXPECT_MSG(strstr(out, "gather guide: off ("), "%s: %s", off[i], strstr(out, "gather guide") ? strstr(out, "gather guide") : out);
    }
    ASSERT_EQ_INT(gg_render("cornell_box", "--width 16 --height 16 --spp 4", "cb_auto", out, sizeof out), 0);
    ASSERT_EQ_INT(gg_render("cornell_box", "--width 16 --height 16 --spp 4 --pm gather_guide=false", "cb_off", out,
                            sizeof out),
                  0);
    EXPECT_MSG(gg_same_file("cb_auto", "cb_off"), "cornell_box: the image changed where the guide is off");
    ASSERT_EQ_INT(gg_render("cornell_box", "--width 8 --height 8 --spp 1 --pm gather_guide=true", "cb_on", out, sizeof out),
                  0);
    EXPECT_MSG(strstr(out, "gather guide: on (forced; no opening"), "%s", out);
}

/* Oracle: photon mapping without the guide, on the same photon maps (traced once and loaded).
 * pinhole_room 4 x 4 at 1024 spp, light guide off so only the gathers differ, seeds 1..N: the
 * guided and the cosine means of the whole image agree within 4 standard errors of their
 * difference (from the seeds' spread). A weight that forgot the disc's density (aimed rays
 * weighted as cosine rays) reads the hole's light about 100x too bright and fails. */
TEST(render_gather_guide_same_mean) {
    enum { N = 4 };
    static char out[65536];
    char flags[2048], tag[64];
    snprintf(flags, sizeof flags, "--width 4 --height 4 --spp 1 --pm global_photons=50000 --save-photons '%s/maps'",
             pm_test_tmpdir());
    ASSERT_EQ_INT(gg_render("pinhole_room", flags, "maps", out, sizeof out), 0);
    double m[2][N];
    for (int on = 0; on < 2; on++)
        for (int i = 0; i < N; i++) {
            snprintf(flags, sizeof flags,
                     "--width 4 --height 4 --spp 1024 --seed %d --pm global_photons=50000 --load-photons '%s/maps' "
                     "--pm light_guide=false --pm gather_guide=%s --pm gather_rays=1 --pm secondary_rays=1",
                     i + 1, pm_test_tmpdir(), on ? "true" : "false");
            snprintf(tag, sizeof tag, "g%d_%d", on, i);
            ASSERT_EQ_INT(gg_render("pinhole_room", flags, tag, out, sizeof out), 0);
            if (on) ASSERT_MSG(strstr(out, "gather guide: on (forced)"), "%s", out);
            m[on][i] = rt_tmp_mean(tag);
        }
    double mean[2], var[2];
    for (int on = 0; on < 2; on++) rt_mean_var(m[on], N, &mean[on], &var[on]);
    double se = sqrt((var[0] + var[1]) / N), d = mean[1] - mean[0];
    printf("    pinhole_room whole image: cosine %.5g (sd %.1f%%), guided %.5g (sd %.1f%%), difference %+.2f%% (se %.2f%%)\n",
           mean[0], 100 * sqrt(var[0]) / mean[0], mean[1], 100 * sqrt(var[1]) / mean[1], 100 * d / mean[0],
           100 * se / mean[0]);
    EXPECT_MSG(fabs(d) <= 4 * se, "guided %g vs cosine %g: %+.2f%% (4 se %.2f%%)", mean[1], mean[0], 100 * d / mean[0],
               400 * se / mean[0]);
}

/* ---- the mixture against closed forms ------------------------------------------------------ */

/* The radiance arriving at the origin from direction d: L = 1 through a physical disc (centre
 * pc, unit normal pn, radius pr), 0 elsewhere; pr <= 0: L = 1 from every direction (a constant
 * sky). */
typedef struct gg_sky {
    vec3 pc, pn;
    double pr;
} gg_sky;

static double gg_sky_L(const gg_sky *k, vec3 d) {
    if (k->pr <= 0) return 1;
    double dn = v3_dot(d, k->pn);
    if (dn == 0) return 0;
    double t = v3_dot(k->pc, k->pn) / dn;
    if (!(t > 0)) return 0;
    return v3_len2(v3_sub(v3_scale(d, t), k->pc)) <= k->pr * k->pr ? 1 : 0;
}

/* E[pi wk L(d)] over n directions from the origin (normal +z) drawn by gather_guide_direction
 * with the share gather_guide_share gives there: the irradiance int L cos dw, estimated as the
 * gather estimates it (pi f L wk with f = 1 / pi: the cosine sample's weight pi times wk).
 * *se: its standard error from the sample variance; *aimed: the share a used. */
static double gg_mixture_irradiance(const gather_guide *gg, const gg_sky *k, long n, uint64_t seed, double *se,
                                    double *aimed) {
    vec3 x = v3(0, 0, 0), nz = v3(0, 0, 1);
    double a = gather_guide_share(gg, x, nz), s1 = 0, s2 = 0;
    *aimed = a;
    for (long i = 0; i < n; i++) {
        rng g = rng_stream(seed, (uint64_t)i, 0);
        double u1 = rng_uniform(&g), u2 = rng_uniform(&g), wk;
        vec3 d = gather_guide_direction(gg, a, x, nz, u1, u2, &g, &wk);
        double e = wk > 0 ? M_PI * wk * gg_sky_L(k, d) : 0;
        s1 += e;
        s2 += e * e;
    }
    double m = s1 / (double)n;
    *se = sqrt(fmax(0, s2 / (double)n - m * m) / (double)(n - 1));
    return m;
}

/* The form factor from a point to a parallel disc of radius R at height h whose centre is a
 * away from the point's normal line (Siegel and Howell): pi F is the irradiance from L = 1. */
static double gg_disc_form_factor(double h, double a, double R) {
    double H2 = h * h + a * a;
    return 0.5 * (1 - (H2 - R * R) / sqrt((H2 + R * R) * (H2 + R * R) - 4 * R * R * a * a));
}

/* The irradiance at the origin (normal +z) from L = 1 through the disc of radius R centred at
 * (D, 0, eps), its normal along x (it faces the point; the horizon z = 0 cuts it at eps below
 * its centre): int over the disc's part above the horizon of z D / r^4 dA. The integral over y
 * is closed, int dy / (A + y^2)^2 = y / (2 A (A + y^2)) + atan(y / sqrt A) / (2 A^1.5),
 * A = D^2 + z^2; the one over the disc's height v (z = eps + v) is done by Simpson's rule in
 * t (v = R sin t, so the integrand is smooth up to the disc's top), to about 1e-10. */
static double gg_horizon_disc(double D, double eps, double R) {
    double t0 = asin(fmax(-1.0, -eps / R)), t1 = M_PI / 2, sum = 0;
    int m = 20000;
    for (int i = 0; i <= m; i++) {
        double t = t0 + (t1 - t0) * i / m, v = R * sin(t), z = eps + v, Y = R * cos(t);
        double A = D * D + z * z;
        double iy = 2 * (Y / (2 * A * (A + Y * Y)) + atan(Y / sqrt(A)) / (2 * A * sqrt(A)));
        double f = z > 0 ? z * D * iy * R * cos(t) : 0;
        sum += f * (i == 0 || i == m ? 1 : i % 2 ? 4 : 2);
    }
    return sum * (t1 - t0) / m / 3;
}

/* Oracle: closed forms of the irradiance the mixture's weights estimate, E[pi wk L] =
 * int L cos dw (gather_guide.h: p(d) = a p_disc + (1 - a) cos / pi, wk = (cos / pi) / p):
 *   sky        L = 1 everywhere: pi, with the guide aiming at a disc above the point;
 *   on axis    L = 1 only through the disc the guide aims at (radius 1 at height 4): pi F,
 *              F = R^2 / (R^2 + h^2) (= gg_disc_form_factor at a = 0);
 *   wrong disc the same light, the guide aiming at a disc twice as wide and off centre;
 *   off axis   a horizontal disc 2 units to the side (the guide's disc faces the point, so it
 *              is tilted against the physical one: part of each is outside the other);
 *   horizon    a disc facing the point 4 away whose centre is 0.01 above the point's horizon,
 *              so almost half of the aimed directions are below it (weight 0: the pdf's edge)
 *              and the rest graze it (cos near 0): the quadrature of gg_horizon_disc.
 * 2^20 directions each (fixed streams); bound: 4 standard errors (from the sample variance)
 * and 0.5%, both. A density off by a constant factor fails (checked by breaking
 * gather_guide_disc_pdf locally): p_disc x 1.05 reads on axis -3.8%, wrong disc -2.5%, off
 * axis -3.8%, horizon -4.4%; x 1.01 still fails on axis (-0.72%, 4 se 0.68%) and at the
 * horizon (-0.74%): the aimed rays carry most of the disc's light and are weighted by 1 / p.
 * The share must be GATHER_GUIDE_SHARE where the disc is in front, 0 where its centre is on
 * the horizon. Seen: +0.12% (2.7 se) for the sky, within 0.3% for the discs; four other
 * streams of 2^22 gave the sky +0.02, +0.04, +0.02, -0.02% (se 0.02%). */
TEST(render_gather_guide_mixture_closed_forms) {
    enum { N = 1 << 20 };
    gather_guide gg;
    gather_guide_init(&gg);
    gg.aim = gg.on = 1;
    struct {
        const char *name;
        vec3 gc;
        double gr;
        gg_sky sky;
        double want;
    } c[5] = {
        {"sky", {0.5, 0, 4}, 1, {{0, 0, 0}, {0, 0, 1}, 0}, M_PI},
        {"on axis", {0, 0, 4}, 1, {{0, 0, 4}, {0, 0, 1}, 1}, M_PI * gg_disc_form_factor(4, 0, 1)},
        {"wrong disc", {0.7, 0, 4}, 2, {{0, 0, 4}, {0, 0, 1}, 1}, M_PI * gg_disc_form_factor(4, 0, 1)},
        {"off axis", {2, 0, 4}, 1, {{2, 0, 4}, {0, 0, 1}, 1}, M_PI * gg_disc_form_factor(4, 2, 1)},
        {"horizon", {4, 0, 0.01}, 1, {{4, 0, 0.01}, {1, 0, 0}, 1}, gg_horizon_disc(4, 0.01, 1)},
    };
    /* The closed form's own sanity: a point under the disc's rim sees less of it than one on
     * the axis, and more than half as much. */
    double f0 = gg_disc_form_factor(4, 0, 1), f1 = gg_disc_form_factor(4, 1, 1);
    EXPECT_MSG(f1 < f0 && f1 > 0.5 * f0, "F on axis %g, under the rim %g", f0, f1);
    for (int i = 0; i < 5; i++) {
        gg.centre = c[i].gc;
        gg.radius = c[i].gr;
        double se, a, m = gg_mixture_irradiance(&gg, &c[i].sky, N, (uint64_t)(0x6767 + i), &se, &a);
        double rel = m / c[i].want - 1;
        printf("    %-10s irradiance %.6g, closed form %.6g: %+.3f%% (se %.3f%%, share %.2f)\n", c[i].name, m,
               c[i].want, 100 * rel, 100 * se / c[i].want, a);
        EXPECT_MSG(a == GATHER_GUIDE_SHARE, "%s: share %g", c[i].name, a);
        EXPECT_MSG(fabs(m - c[i].want) <= 4 * se && fabs(rel) < 0.005, "%s: %.6g vs %.6g (%+.3f%%, 4 se %.3f%%)",
                   c[i].name, m, c[i].want, 100 * rel, 400 * se / c[i].want);
    }
    /* A centre on the horizon is not in front: no aimed rays (cosine sampling alone). */
    gg.centre = v3(4, 0, 0);
    EXPECT_MSG(gather_guide_share(&gg, v3(0, 0, 0), v3(0, 0, 1)) == 0, "centre on the horizon: share %g",
               gather_guide_share(&gg, v3(0, 0, 0), v3(0, 0, 1)));
    gather_guide_free(&gg);
}

/* Oracle: the geometry of the rule (gather_guide.h, WHO AIMS). An opening at (0, 0, 4), radius
 * 1, its light coming from +z (the pilot's lines went up through it): a point below it facing
 * it aims (GATHER_GUIDE_SHARE); a point on the lit side facing it (it would look down into the
 * dark side) and points level with the opening or less than its radius below it (the disc on
 * their horizon: the small room's ceiling around the hole) do not, though all have the centre
 * in front and farther than the radius; with the side unknown (lit zero) the rule is the old
 * one. And the plan: pinhole_room's light comes down through the hole, so
 * the direction it reports points up (the big room is above). */
TEST(render_gather_guide_aims_from_the_dark_side) {
    gather_guide gg;
    gather_guide_init(&gg);
    gg.aim = gg.on = 1;
    gg.centre = v3(0, 0, 4);
    gg.radius = 1;
    gg.lit = v3(0, 0, 1);
    double below = gather_guide_share(&gg, v3(0.5, 0, 0), v3(0, 0, 1));
    double above = gather_guide_share(&gg, v3(0.5, 0, 8), v3(0, 0, -1));
    double plane = gather_guide_share(&gg, v3(3, 0, 4.2), v3(-1, 0, 0));
    double edge = gather_guide_share(&gg, v3(3, 0, 3.2), v3(-1, 0, 0)); /* 0.8 below: within r */
    double deep = gather_guide_share(&gg, v3(3, 0, 2.5), v3(-1, 0, 0)); /* 1.5 below */
    printf("    share below %.2f, above %.2f, in the plane %.2f, 0.8 below %.2f, 1.5 below %.2f\n", below, above,
           plane, edge, deep);
    EXPECT_MSG(below == GATHER_GUIDE_SHARE && deep == GATHER_GUIDE_SHARE, "dark side: %g %g", below, deep);
    EXPECT_MSG(above == 0 && plane == 0 && edge == 0, "lit side or the opening's plane: %g %g %g", above, plane, edge);
    gg.lit = v3(0, 0, 0);
    EXPECT_MSG(gather_guide_share(&gg, v3(0.5, 0, 8), v3(0, 0, -1)) == GATHER_GUIDE_SHARE, "side unknown: %g",
               gather_guide_share(&gg, v3(0.5, 0, 8), v3(0, 0, -1)));
    gather_guide_free(&gg);

    static char out[65536];
    ASSERT_EQ_INT(gg_render("pinhole_room", "--width 8 --height 8 --spp 1 --threads 1", "pin_lit", out, sizeof out), 0);
    const char *q = strstr(out, "its light along (");
    ASSERT_MSG(q, "no light direction: %.400s", strstr(out, "gather guide") ? strstr(out, "gather guide") : out);
    double x, y, z;
    ASSERT(sscanf(q, "its light along (%lf, %lf, %lf)", &x, &y, &z) == 3);
    EXPECT_MSG(y > 0.9, "pinhole_room: the opening's light along (%g, %g, %g), not up", x, y, z);
}
