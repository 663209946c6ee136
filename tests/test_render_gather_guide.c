/* test_render_gather_guide.c: the photon mapper's gather guide (render/photonmapper.c, GATHER
 * GUIDE): gather rays aimed at an opening the pilot finds, weighted by the mixture's density.
 *
 * Oracles: the scene's geometry (pinhole_room's hole is the square 495..505 x 495..505 at
 * y = 300: the opening the plan reports must lie in it); the photon mapper without the guide
 * (gather_guide=false: the same maps, cosine gathers) for the mean; the renderer's own output
 * for "unchanged where off" (byte-identical images) and for thread independence.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "../render/film.h"

/* Render data/scenes/NAME.json with FLAGS into DIR/TAG.pfm; the output in out. */
static int gg_render(const char *name, const char *flags, const char *tag, char *out, size_t cap) {
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "%s/render '%s/data/scenes/%s.json' --mode pm --quiet --hdr '%s/%s.pfm' %s 2>&1",
             pm_test_build_dir(), pm_test_source_dir(), name, pm_test_tmpdir(), tag, flags);
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

static double gg_mean(const char *tag) {
    char p[1024];
    snprintf(p, sizeof p, "%s/%s.pfm", pm_test_tmpdir(), tag);
    film im;
    if (film_read_pfm(&im, p) != 0) return NAN;
    double s = 0;
    for (size_t k = 0; k < (size_t)im.width * (size_t)im.height * 3; k++) s += im.px[k];
    s /= (double)im.width * im.height * 3;
    film_free(&im);
    return s;
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
    double m[2][N], s1[2] = {0, 0}, s2[2] = {0, 0};
    for (int on = 0; on < 2; on++)
        for (int i = 0; i < N; i++) {
            snprintf(flags, sizeof flags,
                     "--width 4 --height 4 --spp 1024 --seed %d --pm global_photons=50000 --load-photons '%s/maps' "
                     "--pm light_guide=false --pm gather_guide=%s --pm gather_rays=1 --pm secondary_rays=1",
                     i + 1, pm_test_tmpdir(), on ? "true" : "false");
            snprintf(tag, sizeof tag, "g%d_%d", on, i);
            ASSERT_EQ_INT(gg_render("pinhole_room", flags, tag, out, sizeof out), 0);
            if (on) ASSERT_MSG(strstr(out, "gather guide: on (forced)"), "%s", out);
            m[on][i] = gg_mean(tag);
            s1[on] += m[on][i];
            s2[on] += m[on][i] * m[on][i];
        }
    double mean[2], var[2];
    for (int on = 0; on < 2; on++) {
        mean[on] = s1[on] / N;
        var[on] = fmax(0, (s2[on] - N * mean[on] * mean[on]) / (N - 1));
    }
    double se = sqrt((var[0] + var[1]) / N), d = mean[1] - mean[0];
    printf("    pinhole_room whole image: cosine %.5g (sd %.1f%%), guided %.5g (sd %.1f%%), difference %+.2f%% (se %.2f%%)\n",
           mean[0], 100 * sqrt(var[0]) / mean[0], mean[1], 100 * sqrt(var[1]) / mean[1], 100 * d / mean[0],
           100 * se / mean[0]);
    EXPECT_MSG(fabs(d) <= 4 * se, "guided %g vs cosine %g: %+.2f%% (4 se %.2f%%)", mean[1], mean[0], 100 * d / mean[0],
               400 * se / mean[0]);
}
