/* test_render_adaptive.c: the adaptive samples of a render in passes (run/passes.h, ADAPTIVE
 * SAMPLES; renderer.h, render_job.mult).
 *
 * Oracles: the Neyman allocation worked out by hand for pass sums built with known spreads;
 * a long plain render (2^18 samples a pixel) against which every pixel of an adaptive render
 * must agree within a t bound from its own passes' spread (the checkpoint keeps the sums and
 * the multipliers); and the uninterrupted render at another thread count, or resumed from a
 * checkpoint before or after the multipliers were decided, byte for byte.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"
#include "../photonmap/common.h"
#include "../render/image/film.h"
#include "../render/run/checkpoint.h"
#include "../render/run/passes.h"
#include "test_render_run.h"

/* Pass sums of P = 4 passes whose values at pixel i alternate mu + a_i, mu - a_i in every
 * channel: the pass images' variance per channel is 4 a^2 / 3, summed over three channels
 * 4 a^2, so the spread s_i = 2 a_i. */
static void alternating_sums(pass_state *ps, const double *s) {
    size_t n = (size_t)ps->width * (size_t)ps->height;
    ps->done = 4;
    for (size_t i = 0; i < n; i++)
        for (int c = 0; c < 3; c++) {
            double mu = 1.0 + (double)c, a = s[i] / 2;
            ps->sum[3 * i + (size_t)c] = 4 * mu;
            ps->sum2[3 * i + (size_t)c] = 2 * (mu + a) * (mu + a) + 2 * (mu - a) * (mu - a);
        }
}

/* Oracle: worked out by hand. 64 pixels of spread 1 and one (pixel 10) of spread 20, pixel
 * 20 constant (spread 0), at share 0.25: 80 samples for 64 pixels. Any lambda >= 2 would give
 * the 62 pixels of spread 1 two samples each (124 > 80), so lambda < 2 and they keep 1; pixel
 * 10 then gets floor(20 lambda) <= 80 - 63 = 17, and the largest lambda within the budget gives
 * it exactly 17: 16 samples added, 0.25 of a plain pass. At share 30 the spread-1 pixels get
 * floor(lambda) and pixel 10 is capped at ADAPT_MAX. All pixels alike: none is marked. */
TEST(render_adaptive_allocation_by_hand) {
    pass_state ps;
    ASSERT(pass_state_init(&ps, 8, 8) == 0);
    double s[64];
    for (int i = 0; i < 64; i++) s[i] = 1;
    s[10] = 20;
    s[20] = 0;
    alternating_sums(&ps, s);
    size_t marked = 0;
    double extra = 0;
    ASSERT(pass_state_adapt(&ps, 0.25, &marked, &extra) == 0);
    EXPECT_MSG(ps.mult[10] == 17, "pixel 10 takes %d x, not 17 x", ps.mult[10]);
    int others = 0;
    for (int i = 0; i < 64; i++) others += i != 10 && ps.mult[i] != 1;
    EXPECT_MSG(others == 0, "%d other pixels were marked", others);
    EXPECT_MSG(marked == 1 && fabs(extra - 0.25) < 1e-12, "marked %zu, extra %g", marked, extra);
    /* a large share: the spread-1 pixels take floor(lambda), pixel 10 the cap */
    ASSERT(pass_state_adapt(&ps, 30, &marked, &extra) == 0);
    long total = 0;
    for (int i = 0; i < 64; i++) total += ps.mult[i];
    EXPECT_MSG(ps.mult[10] == ADAPT_MAX && ps.mult[20] == 1, "pixel 10 %d x, pixel 20 %d x", ps.mult[10],
               ps.mult[20]);
    EXPECT_MSG(total <= 64 * 31 && ps.mult[0] >= 2, "total %ld, pixel 0 %d x", total, ps.mult[0]);
    for (int i = 0; i < 64; i++) s[i] = 3;
    alternating_sums(&ps, s);
    ASSERT(pass_state_adapt(&ps, 0.25, &marked, &extra) == 0);
    EXPECT_MSG(marked == 0 && extra == 0, "uniform spreads: %zu marked", marked);
    pass_state_free(&ps);
}

#define OBJ8 "'%s/data/scenes/cornell_box.json' --mode objects --width 8 --height 8"

/* Oracle: a plain render of 2^18 samples a pixel (stratified, so its own error is far below the
 * bound). An adaptive render of 48 passes of 16 spp at --adaptive 4 (objects mode: a pixel
 * varies only on a silhouette, where the multipliers go) keeps its pass sums and multipliers
 * in its checkpoint; at every pixel and channel the mean of the passes is within t = 5 of
 * their standard error of the reference (plus 1e-4 of the reference for its own rounding), and
 * at least one pixel took more than 2 x the samples. A wrong stratum for the extra rounds
 * (samples outside the pixel, or one stratum repeated) moves a silhouette pixel by far more. */
TEST(render_adaptive_unbiased_against_a_long_render) {
    char out[65536], err[512];
    ASSERT_MSG(rt_render(OBJ8, "--spp 262144 --threads 2 --quiet --hdr ref.pfm", out, sizeof out) == 0, "%s", out);
    ASSERT_MSG(rt_render(OBJ8, "--passes 48 --pass-spp 16 --adaptive 4 --threads 2 --hdr a.pfm --checkpoint a.ckpt", out,
                         sizeof out) == 0,
               "%s", out);
    EXPECT_MSG(strstr(out, "Adaptive samples: from 4 passes' spread"), "no adaptive samples line:\n%.2000s", out);
    static ckpt_info ci;
    pass_state ps;
    ASSERT_MSG(ckpt_read_passes(rt_path("a.ckpt"), &ci, &ps, err, sizeof err) == 0, "%s", err);
    film ref;
    ASSERT(film_read_pfm(&ref, rt_path("ref.pfm")) == 0);
    ASSERT(ps.done == 48 && ps.mult && ref.width == 8 && ref.height == 8);
    int top = 0, bad = 0;
    double worst = 0;
    for (int i = 0; i < 64; i++) {
        top = ps.mult[i] > top ? ps.mult[i] : top;
        for (int c = 0; c < 3; c++) {
            double P = ps.done, mu = ps.sum[3 * i + c] / P;
            double v = fmax(0, (ps.sum2[3 * i + c] - P * mu * mu) / (P - 1));
            double r = ref.px[3 * i + c], tol = 5 * sqrt(v / P) + 1e-4 * fabs(r);
            if (fabs(mu - r) > tol) {
                if (bad++ < 4)
                    printf("    pixel %d channel %d: mean %.6f, reference %.6f, tolerance %.3g (mult %d)\n", i, c,
                           mu, r, tol, ps.mult[i]);
            }
            if (tol > 0 && fabs(mu - r) / tol > worst) worst = fabs(mu - r) / tol;
        }
    }
    EXPECT_MSG(top > 2, "no pixel took more than 2 x the samples (largest %d)", top);
    EXPECT_MSG(bad == 0, "%d of 192 values outside the bound", bad);
    printf("    largest multiplier %d; worst |mean - reference| / tolerance %.2f\n", top, worst);
    film_free(&ref);
    pass_state_free(&ps);
}

#define BOX_PM6                                                                            \
    "'%s/data/scenes/cornell_spheres.json' --mode pm --pm global_photons=8000 --pm "       \
    "caustic_photons=8000 --width 16 --height 16 --pass-spp 4"

/* Oracle: the uninterrupted render of 6 passes at 2 threads (its passes 4 and 5 take the
 * multipliers), byte for byte: at 1 thread; resumed from a checkpoint of 2 passes (before the
 * multipliers are decided) and of 5 (after: the checkpoint keeps them). At --adaptive 0 the 6
 * passes differ (the default changed passes 4 and 5) and 4 passes do not (nothing is decided
 * before). */
TEST(render_adaptive_threads_and_resume_bit_identical) {
    char out[65536], sc[2048], cmd[8192];
    ASSERT_MSG(rt_render(BOX_PM6, "--passes 6 --threads 2 --hdr ref.pfm -o ref.png", out, sizeof out) == 0, "%s", out);
    EXPECT_MSG(strstr(out, "Adaptive samples: from 4 passes' spread"), "no adaptive samples line:\n%.2000s", out);
    ASSERT_MSG(rt_render(BOX_PM6, "--passes 6 --threads 1 --quiet --hdr one.pfm", out, sizeof out) == 0, "%s", out);
    EXPECT_MSG(rt_same_file("one.pfm", "ref.pfm"), "1 and 2 threads differ");
    snprintf(sc, sizeof sc, BOX_PM6, pm_test_source_dir());
    *strchr(sc + 1, '\'') = 0;
    for (int k = 0; k < 2; k++) {
        int at = k ? 5 : 2;
        char args[256];
        rt_run("rm -f c.ckpt c.pfm", out, sizeof out);
        snprintf(args, sizeof args, "--passes %d --threads 2 --quiet --hdr c.pfm --checkpoint c.ckpt", at);
        ASSERT_MSG(rt_render(BOX_PM6, args, out, sizeof out) == 0, "%s", out);
        snprintf(cmd, sizeof cmd, "'%s/render' %s' --resume c.ckpt --passes 6 --threads 1", pm_test_build_dir(), sc);
        ASSERT_MSG(rt_run(cmd, out, sizeof out) == 0, "%s", out);
        EXPECT_MSG(rt_same_file("c.pfm", "ref.pfm"), "resumed after %d passes: the image differs from 6 at once", at);
    }
    ASSERT_MSG(rt_render(BOX_PM6, "--passes 6 --adaptive 0 --threads 2 --quiet --hdr off.pfm", out, sizeof out) == 0,
               "%s", out);
    EXPECT_MSG(!rt_same_file("off.pfm", "ref.pfm"), "--adaptive 0 changed nothing in 6 passes");
    ASSERT_MSG(rt_render(BOX_PM6, "--passes 4 --threads 2 --quiet --hdr f4.pfm", out, sizeof out) == 0, "%s", out);
    ASSERT_MSG(rt_render(BOX_PM6, "--passes 4 --adaptive 0 --threads 2 --quiet --hdr o4.pfm", out, sizeof out) == 0,
               "%s", out);
    EXPECT_MSG(rt_same_file("f4.pfm", "o4.pfm"), "4 passes differ with and without adaptive samples");
}

/* Oracle: the documented refusals (exit 2, the option named). */
TEST(render_adaptive_bad_option) {
    char out[8192];
    static const char *bad[] = {"-1", "32", "nan", "x", "0.5x"};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; i++) {
        char args[128];
        snprintf(args, sizeof args, "--passes 2 --adaptive %s --quiet --hdr b.pfm", bad[i]);
        int rc = rt_render(OBJ8, args, out, sizeof out);
        EXPECT_MSG(rc == 2 && strstr(out, "--adaptive: expected a number in [0, 31]"), "%s: status %d: %s", bad[i],
                   rc, out);
    }
}
