/* test_render_images.c: the shipped scenes' images stay byte-identical unless a commit means
 * to change them.
 *
 * Oracle: tests/data/image_hashes.txt, the SHA-256 of the linear image (render --hdr X.pfm)
 * of every scene file in data/scenes/, in --mode pm and --mode path, rendered small (16x16,
 * 4 spp, seed 1, 2 threads, small photon maps: the table's "args" line) by the build of the
 * commit that last changed images on purpose; exact equality, no tolerance.
 * scripts/update-image-hashes.sh writes the table; a commit that changes images on purpose
 * runs it and says so in its message (which scenes and modes: the script prints them). A
 * refactor leaves the table alone, and this test names each scene and mode whose image moved.
 * (scripts/same-images.sh OLD NEW compares two builds by hand, at 32x32 and the plan's own
 * photon counts.)
 *
 * The same rows rendered on one thread must give the table's hashes too: the renderer
 * promises the same image for any thread count. One table serves every build: the hashes were
 * found the same with gcc and with clang, at -O2 and in the ASan/UBSan build (-O1), and
 * without OpenMP (OPENMP=0). (Two calls that drew random numbers as their arguments got them
 * in the compiler's order, and clang's images differed from gcc's, until the draws were named:
 * a draw inside an argument list is a bug this test finds when run with both compilers.)
 */
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "test.h"

#define IH_MAX_ROWS 256

typedef struct {
    char scene[128], mode[16], sha[65];
    int width, height, spp, line;
} ih_row;

typedef struct {
    char args[2048];
    ih_row rows[IH_MAX_ROWS];
    int n;
} ih_table;

static const char *ih_table_path(void) {
    static char p[1024];
    snprintf(p, sizeof p, "%s/tests/data/image_hashes.txt", pm_test_source_dir());
    return p;
}

/* The table, every line checked: 0, or -1 with a failure that names the line. */
static int ih_read(ih_table *t) {
    FILE *f = fopen(ih_table_path(), "r");
    char line[2048];
    int ln = 0, bad = 0;
    t->n = 0;
    t->args[0] = 0;
    if (!f) {
        pm_test_fail(__FILE__, __LINE__, "cannot read %s (write it: scripts/update-image-hashes.sh)",
                     ih_table_path());
        return -1;
    }
    while (fgets(line, sizeof line, f)) {
        ln++;
        line[strcspn(line, "\n")] = 0;
        if (line[0] == '#' || line[0] == 0) continue;
        if (!strncmp(line, "args ", 5)) {
            snprintf(t->args, sizeof t->args, "%s", line + 5);
            continue;
        }
        ih_row *r = &t->rows[t->n];
        char extra[8];
        if (t->n == IH_MAX_ROWS ||
            sscanf(line, "%127s %15s %d %d %d %64s %7s", r->scene, r->mode, &r->width, &r->height, &r->spp,
                   r->sha, extra) != 6 ||
            strlen(r->sha) != 64 || r->width < 1 || r->height < 1 || r->spp < 1) {
            pm_test_fail(__FILE__, __LINE__, "%s:%d: not a row (scene mode width height spp sha256): %s",
                         ih_table_path(), ln, line);
            bad = 1;
            continue;
        }
        r->line = ln;
        t->n++;
    }
    fclose(f);
    if (!t->args[0]) {
        pm_test_fail(__FILE__, __LINE__, "%s: no args line", ih_table_path());
        bad = 1;
    }
    return bad ? -1 : 0;
}

/* Render row r with `threads` threads and the table's args plus `more`; its image's SHA-256
 * into sha. 0, or -1 with the render's messages in msg. */
static int ih_render(const ih_table *t, const ih_row *r, int threads, const char *more, char *sha,
                     char *msg, size_t cap) {
    char cmd[8192];
    snprintf(cmd, sizeof cmd,
             "cd '%s' || exit 9; rm -f img.pfm; timeout 120 '%s/render' '%s/data/scenes/%s.json' --mode %s "
             "--width %d --height %d --spp %d --threads %d %s %s --quiet --hdr img.pfm -o img.png "
             ">/dev/null 2>err.txt || { echo \"exit status $?\"; cat err.txt; exit 1; }; sha256sum img.pfm",
             pm_test_tmpdir(), pm_test_build_dir(), pm_test_source_dir(), r->scene, r->mode, r->width,
             r->height, r->spp, threads, t->args, more);
    int rc = pm_test_run(cmd, msg, cap);
    if (rc != 0 || strlen(msg) < 64 || strspn(msg, "0123456789abcdef") != 64) return -1;
    memcpy(sha, msg, 64);
    sha[64] = 0;
    return 0;
}

#define IH_HOW                                                                                      \
    "if the change is meant to change images, run scripts/update-image-hashes.sh and say so in the " \
    "commit message; if not, it broke an image that should have stayed byte-identical"

/* Oracle: the table's hashes, exact. A render of one row with another seed must hash
 * differently, so that the hashes do see the image. */
TEST(render_images_keep_their_hashes) {
    static ih_table t;
    char sha[65], msg[4096];
    ASSERT(ih_read(&t) == 0);
    ASSERT(t.n > 0);
    int changed = 0;
    for (int i = 0; i < t.n; i++) {
        const ih_row *r = &t.rows[i];
        if (ih_render(&t, r, 2, "", sha, msg, sizeof msg) != 0) {
            EXPECT_MSG(0, "data/scenes/%s.json --mode %s: the render failed:\n%s", r->scene, r->mode, msg);
            changed++;
            continue;
        }
        EXPECT_MSG(!strcmp(sha, r->sha),
                   "data/scenes/%s.json --mode %s (%dx%d, %d spp): the image changed: sha256 %s, the "
                   "table (tests/data/image_hashes.txt:%d) has %s",
                   r->scene, r->mode, r->width, r->height, r->spp, sha, r->line, r->sha);
        changed += strcmp(sha, r->sha) != 0;
    }
    EXPECT_MSG(changed == 0, "%d of %d images changed (listed above): " IH_HOW, changed, t.n);
    /* cornell_box in path, with seed 2 after the table's seed 1 */
    int seen = 0;
    for (int i = 0; i < t.n; i++) {
        const ih_row *r = &t.rows[i];
        if (strcmp(r->mode, "path") || strcmp(r->scene, "cornell_box")) continue;
        seen = 1;
        ASSERT_MSG(ih_render(&t, r, 2, "--seed 2", sha, msg, sizeof msg) == 0, "cornell_box --seed 2: %s", msg);
        EXPECT_MSG(strcmp(sha, r->sha) != 0, "data/scenes/cornell_box.json --mode path --seed 2 hashes as seed 1 "
                   "does: the hash does not see the image");
    }
    EXPECT_MSG(seen, "no cornell_box path row: the check that the hash sees the image did not run");
}

/* Oracle: the directory listing. Every shipped scene has a pm and a path row, every row names
 * a shipped scene and a mode of those two, and no scene and mode has two rows. */
TEST(render_images_cover_every_scene) {
    static ih_table t;
    ASSERT(ih_read(&t) == 0);
    char dir[1024];
    snprintf(dir, sizeof dir, "%s/data/scenes", pm_test_source_dir());
    DIR *d = opendir(dir);
    ASSERT_MSG(d, "cannot list %s", dir);
    struct dirent *e;
    int scenes = 0;
    while ((e = readdir(d))) {
        size_t n = strlen(e->d_name);
        if (n < 6 || strcmp(e->d_name + n - 5, ".json")) continue;
        scenes++;
        static const char *const modes[] = {"pm", "path"};
        for (int m = 0; m < 2; m++) {
            int found = 0;
            for (int i = 0; i < t.n; i++)
                found += !strncmp(t.rows[i].scene, e->d_name, n - 5) && t.rows[i].scene[n - 5] == 0 &&
                         !strcmp(t.rows[i].mode, modes[m]);
            EXPECT_MSG(found == 1,
                       "data/scenes/%s --mode %s has %d rows in tests/data/image_hashes.txt, not 1 (a new "
                       "scene: run scripts/update-image-hashes.sh and say so in the commit message)",
                       e->d_name, modes[m], found);
        }
    }
    closedir(d);
    ASSERT(scenes > 0);
    for (int i = 0; i < t.n; i++) {
        char path[1400];
        snprintf(path, sizeof path, "%s/%s.json", dir, t.rows[i].scene);
        FILE *f = fopen(path, "r");
        EXPECT_MSG(f, "tests/data/image_hashes.txt:%d names %s, which is not a shipped scene (%s): run "
                   "scripts/update-image-hashes.sh", t.rows[i].line, t.rows[i].scene, path);
        if (f) fclose(f);
        EXPECT_MSG(!strcmp(t.rows[i].mode, "pm") || !strcmp(t.rows[i].mode, "path"),
                   "tests/data/image_hashes.txt:%d: mode %s", t.rows[i].line, t.rows[i].mode);
    }
    EXPECT_EQ_INT(t.n, 2 * scenes);
}

/* Oracle: the table (written with 2 threads), exact. Every path row, and the pm rows of scenes
 * that reach the photon mapper's parallel parts between them (caustics through glass, media,
 * photon ports found by the camera probe, the light and gather guides, a sun through a window),
 * on one thread. */
TEST(render_images_same_on_one_thread) {
#ifndef _OPENMP
    SKIP("built without OpenMP (OPENMP=0): every thread count is the same one-thread program here");
#else
    static const char *const pm_scenes[] = {"cornell_spheres", "cornell_fog", "pinhole_room_ports", "lamp_shade",
                                            "sun_window"};
    static ih_table t;
    char sha[65], msg[4096];
    ASSERT(ih_read(&t) == 0);
    int done = 0, differ = 0;
    for (int i = 0; i < t.n; i++) {
        const ih_row *r = &t.rows[i];
        int pick = !strcmp(r->mode, "path");
        for (size_t k = 0; k < sizeof pm_scenes / sizeof pm_scenes[0]; k++)
            pick |= !strcmp(r->mode, "pm") && !strcmp(r->scene, pm_scenes[k]);
        if (!pick) continue;
        done++;
        if (ih_render(&t, r, 1, "", sha, msg, sizeof msg) != 0) {
            EXPECT_MSG(0, "data/scenes/%s.json --mode %s --threads 1: the render failed:\n%s", r->scene, r->mode,
                       msg);
            continue;
        }
        EXPECT_MSG(!strcmp(sha, r->sha),
                   "data/scenes/%s.json --mode %s --threads 1: sha256 %s, the table (2 threads, "
                   "tests/data/image_hashes.txt:%d) has %s",
                   r->scene, r->mode, sha, r->line, r->sha);
        differ += strcmp(sha, r->sha) != 0;
    }
    EXPECT_MSG(differ == 0,
               "%d images on one thread differ from the table: if render_images_keep_their_hashes fails for "
               "them too, the table is stale (" IH_HOW "); if not, the image depends on the thread count",
               differ);
    EXPECT_MSG(done == t.n / 2 + (int)(sizeof pm_scenes / sizeof pm_scenes[0]),
               "%d renders, not every path row and the pm rows of the %zu scenes listed here", done,
               sizeof pm_scenes / sizeof pm_scenes[0]);
#endif
}
