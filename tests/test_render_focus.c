/* test_render_focus.c: camera samples aimed at a photon port seen in a sliver of a pixel
 * (render/run/focus.h).
 *
 * Oracles: the port's footprint in a pixel against the share of a fine grid of camera rays
 * through the pixel that cross the port (port_cross); the mixture's weighted samples against
 * integrals over the pixel known in closed form, within 5 standard errors of their own spread;
 * and on pinhole_room, the pixels that see the roof's hole against the long reference.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "test.h"
#include "../render/base/rng.h"
#include "../render/run/focus.h"
#include "../render/scene/camera.h"
#include "../render/scene/port.h"
#include "../render/image/film.h"
#include "test_render_run.h"

static camera test_camera(void) {
    camera c;
    memset(&c, 0, sizeof c);
    const char *why = NULL;
    camera_setup(&c, v3(0, 0, 0), v3(0.1, 0.05, 1), v3(0, 1, 0), 60, 16, 16, &why);
    return c;
}

/* The test camera and three ports: a quad of about 1.5 pixels, turned in its plane and
 * tilted; a small disc; one behind the eye. The focus table of the first n of them into *f. */
static int test_focus(camera *c, port *p, int n, film_focus *f) {
    *c = test_camera();
    p[0] = port_quad(v3(0.3, 0.2, 10), v3(0.9, 0.3, 0.1), v3(-0.25, 0.8, 0.2));
    p[1] = port_disc(v3(-1.5, 0.8, 8), v3(0.3, 0.2, 1), 0.05);
    p[2] = port_quad(v3(0, 0, -5), v3(1, 0, 0), v3(0, 1, 0));
    return focus_build(f, c, p, n);
}

/* The share of a G x G grid of the pixel's film points whose camera rays cross pt. */
static double ray_share(const camera *c, const port *pt, int x, int y, int G) {
    int hit = 0;
    for (int j = 0; j < G; j++)
        for (int i = 0; i < G; i++) {
            ray r = camera_ray(c, x + (i + 0.5) / G, y + (j + 0.5) / G);
            double t, cs;
            hit += port_cross(pt, r.o, r.d, &t, &cs);
        }
    return (double)hit / ((double)G * G);
}

/* Oracle: rays. A quad's footprint in each pixel is the part of the pixel whose rays cross it
 * (a 256 x 256 grid: within 0.012 plus a little for the grid's steps along the edges); a
 * pixel without a focus is covered by none of it or by more than FOCUS_MAX_COVER; the disc's
 * rays all land in its pixel's polygon (the square around it); the port behind the eye gives
 * none. */
TEST(render_focus_footprint_against_rays) {
    camera c;
    port p[3];
    film_focus f;
    ASSERT(test_focus(&c, p, 1, &f) == 0);
    int focused = 0, bad = 0;
    for (int y = 0; y < c.height; y++)
        for (int x = 0; x < c.width; x++) {
            int i = f.index[y * c.width + x];
            double share = ray_share(&c, &p[0], x, y, 256);
            if (i < 0) {
                if (share > 0.004 && share < FOCUS_MAX_COVER - 0.01 && bad++ < 4)
                    printf("    pixel (%d, %d): rays cross the port in %.4f of it, but no focus\n", x, y, share);
                continue;
            }
            focused++;
            double a = f.polys[i].area;
            if (fabs(a - share) > 0.012 && bad++ < 4)
                printf("    pixel (%d, %d): footprint %.4f, rays %.4f\n", x, y, a, share);
        }
    EXPECT_MSG(focused >= 2, "only %d pixels focused", focused);
    EXPECT_MSG(bad == 0, "%d pixels disagree with the rays", bad);
    focus_free(&f);

    ASSERT(focus_build(&f, &c, p + 1, 2) == 0); /* the disc, and the port behind the eye */
    int disc_px = 0, outside = 0;
    for (int y = 0; y < c.height; y++)
        for (int x = 0; x < c.width; x++) {
            int i = f.index[y * c.width + x];
            if (i >= 0) disc_px++;
            for (int j = 0; j < 64; j++)
                for (int k = 0; k < 64; k++) {
                    double lx = (k + 0.5) / 64, ly = (j + 0.5) / 64, t, cs;
                    ray r = camera_ray(&c, x + lx, y + ly);
                    if (port_cross(&p[1], r.o, r.d, &t, &cs) && (i < 0 || focus_weight(&f.polys[i], lx, ly) >= 1 / FOCUS_PLAIN))
                        outside++;
                }
        }
    EXPECT_MSG(disc_px >= 1, "the disc has no footprint");
    EXPECT_MSG(outside == 0, "%d of the disc's rays land outside its footprint", outside);
    EXPECT_MSG(f.npolys == disc_px, "the port behind the eye has a footprint (%d polygons, %d disc pixels)", f.npolys,
               disc_px);
    focus_free(&f);
}

/* Oracle: closed forms over the unit pixel: the integrals of 1, x^2, x y and 1 + 100 [x in F]
 * (1, 1/3, 1/4, 1 + 100 a). Each of R rounds is one pixel's estimate from n x n stratified,
 * jittered samples; the rounds' mean must be within 5 of their standard errors (plus 1e-9).
 * The focused estimate of the bright sliver must also have at most a tenth of the plain
 * stratified samples' variance (the reason for aiming). */
TEST(render_focus_samples_unbiased) {
    camera c;
    port p[3];
    film_focus f;
    ASSERT(test_focus(&c, p, 2, &f) == 0);
    ASSERT(f.npolys >= 3);
    const int n = 8, R = 2000;
    int bad = 0;
    for (int pi = 0; pi < f.npolys; pi++) {
        const focus_poly *q = &f.polys[pi];
        double exact[4] = {1, 1.0 / 3, 0.25, 1 + 100 * q->area}, s[4] = {0}, s2[4] = {0}, plain = 0, plain2 = 0;
        int strays = 0;
        rng g = rng_stream(7, (uint64_t)pi, 0);
        for (int r = 0; r < R; r++) {
            double e[4] = {0}, ep = 0;
            for (int k = 0; k < n * n; k++) {
                double u = ((k % n) + rng_uniform(&g)) / n, v = ((k / n) + rng_uniform(&g)) / n, px, py;
                /* pixel (0, 0) of a one-pixel table that holds polygon pi */
                int idx = 0;
                film_focus one = {1, 1, &idx, (focus_poly *)q, 1};
                double w = focus_film_point(&one, 0, 0, u, v, &px, &py);
                if (px < -1e-12 || px > 1 + 1e-12 || py < -1e-12 || py > 1 + 1e-12) strays++;
                int in = focus_weight(q, px, py) < 1 / FOCUS_PLAIN;
                double fv[4] = {1, px * px, px * py, 1 + 100.0 * in};
                for (int m = 0; m < 4; m++) e[m] += w * fv[m];
                ep += 1 + 100.0 * (focus_weight(q, u, v) < 1 / FOCUS_PLAIN);
            }
            for (int m = 0; m < 4; m++) {
                e[m] /= n * n;
                s[m] += e[m];
                s2[m] += e[m] * e[m];
            }
            ep /= n * n;
            plain += ep;
            plain2 += ep * ep;
        }
        EXPECT_MSG(strays == 0, "polygon %d: %d samples outside the pixel", pi, strays);
        for (int m = 0; m < 4; m++) {
            double mu = s[m] / R, var = fmax(0, s2[m] / R - mu * mu), se = sqrt(var / R);
            if (fabs(mu - exact[m]) > 5 * se + 1e-9 && bad++ < 6)
                printf("    polygon %d (area %.4f), integrand %d: %.6f against %.6f, standard error %.2g\n", pi,
                       q->area, m, mu, exact[m], se);
        }
        double mu = s[3] / R, var = s2[3] / R - mu * mu, pm = plain / R, pvar = plain2 / R - pm * pm;
        EXPECT_MSG(var <= 0.1 * pvar, "polygon %d (area %.4f): variance %.3g, plain %.3g", pi, q->area, var, pvar);
    }
    EXPECT_MSG(bad == 0, "%d integrals outside 5 standard errors", bad);
    focus_free(&f);
}

#define PINHOLE "'%s/data/scenes/pinhole_room.json' --mode pm --width 8 --height 8 --threads 2 --seed 5"

/* Oracle: the long reference render (data/reference-hard). The 2 pixels that see the roof's
 * hole in 0.2% of their area are within 4% of it after 8 passes at the defaults (without the
 * focus they read -12% and +4% after 33 passes at seed 5); the plan's line names them, and
 * photon_mapping.camera_focus=false takes it away. */
TEST(render_focus_pinhole_room_sliver_pixels) {
    char out[65536];
    ASSERT_MSG(rt_render(PINHOLE, "--passes 8 --hdr a.pfm -o a.png", out, sizeof out) == 0, "%s", out);
    EXPECT_MSG(strstr(out, "Camera focus: 2 pixels see a photon port"), "no focus line:\n%.3000s", out);
    film a, ref;
    char refp[1024];
    snprintf(refp, sizeof refp, "%s/data/reference-hard/pinhole_room.pfm", pm_test_source_dir());
    ASSERT(film_read_pfm(&a, rt_path("a.pfm")) == 0);
    ASSERT(film_read_pfm(&ref, refp) == 0);
    for (int x = 3; x <= 4; x++) {
        double sa = 0, sr = 0;
        for (int ch = 0; ch < 3; ch++) {
            sa += a.px[3 * x + ch];
            sr += ref.px[3 * x + ch];
        }
        printf("    pixel (%d, 0): %+.2f%% against the reference\n", x, 100 * (sa / sr - 1));
        EXPECT_MSG(fabs(sa / sr - 1) < 0.04, "pixel (%d, 0) reads %+.2f%%", x, 100 * (sa / sr - 1));
    }
    film_free(&a);
    film_free(&ref);
    ASSERT_MSG(rt_render(PINHOLE, "--passes 1 --pm camera_focus=false --hdr b.pfm -o b.png", out, sizeof out) == 0,
               "%s", out);
    EXPECT_MSG(!strstr(out, "Camera focus:"), "camera_focus=false still focuses:\n%.3000s", out);
}

#define FOCUS_LIGHT "'%s/tests/data/focus_light.json' --threads 2"

/* Sum of the RGB of pixel (x, y) of a PFM in the test directory (-1 if unreadable). */
static double pixel_sum(const char *name, int x, int y) {
    film f;
    if (film_read_pfm(&f, rt_path(name)) != 0) return -1;
    double v = 0;
    for (int c = 0; c < 3; c++) v += f.px[3 * ((size_t)y * (size_t)f.width + (size_t)x) + c];
    film_free(&f);
    return v;
}

/* Oracle: path tracing (no ports, no focus) at 16384 spp. tests/data/focus_light.json's middle
 * pixel sees the big room's ceiling light through the roof's hole (a declared port) in 7.7% of
 * its area, and the photon mapper's emission-only rays cover every pixel: a focused sample must
 * collect its own emission, not the m x m rays of its stratum (which it no longer lies in;
 * with them the pixel read +6.6%). pm at 1024 spp, with and without the focus, within 2%. */
TEST(render_focus_sees_the_light_through_the_port) {
    char out[65536];
    ASSERT_MSG(rt_render(FOCUS_LIGHT, "--mode path --spp 16384 --quiet --hdr path.pfm -o path.png", out, sizeof out) == 0,
               "%s", out);
    ASSERT_MSG(rt_render(FOCUS_LIGHT, "--mode pm --spp 1024 --hdr on.pfm -o on.png", out, sizeof out) == 0, "%s", out);
    EXPECT_MSG(strstr(out, "Camera focus: 1 pixel sees a photon port"), "no focus line:\n%.3000s", out);
    ASSERT_MSG(rt_render(FOCUS_LIGHT, "--mode pm --spp 1024 --pm camera_focus=false --quiet --hdr off.pfm -o off.png", out,
                         sizeof out) == 0,
               "%s", out);
    double ref = pixel_sum("path.pfm", 1, 1), on = pixel_sum("on.pfm", 1, 1), off = pixel_sum("off.pfm", 1, 1);
    ASSERT(ref > 0);
    printf("    middle pixel against path tracing: focus %+.2f%%, without %+.2f%%\n", 100 * (on / ref - 1),
           100 * (off / ref - 1));
    EXPECT_MSG(fabs(on / ref - 1) < 0.02, "with the focus the middle pixel reads %+.2f%%", 100 * (on / ref - 1));
    EXPECT_MSG(fabs(off / ref - 1) < 0.02, "without the focus the middle pixel reads %+.2f%%", 100 * (off / ref - 1));
}
