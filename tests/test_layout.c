/* test_layout.c: render/'s layout keeps its rules (render/README.md, scripts/check-layout.sh).
 *
 * Oracle: the rules themselves. Stages in pipeline order, an include of a later stage is an
 * import that runs back up; no circle of includes among the headers; no circle of calls
 * among the files (from this build's objects); no file over 600 lines and no function over
 * 120, except the exceptions the script lists with their sizes (which may shrink, never
 * grow). The checker is
 * itself checked on a copy of the tree with one planted violation of each kind, so a checker
 * that stopped seeing them fails here too.
 */
#include <stdio.h>
#include <string.h>

#include "test.h"

TEST(layout_render_keeps_its_rules) {
    char cmd[4096], out[16384];
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/check-layout.sh' '%s' '%s/obj/render'", pm_test_source_dir(),
             pm_test_source_dir(), pm_test_build_dir());
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 0 && out[0] == 0, "render/ breaks its layout rules (rc %d):\n%s", rc, out);
}

/* Copy render/, this build's objects of it (../obj) and the checker into the temporary
 * directory, plant one violation (run in the copy's render/; the checker's copy is
 * ../check-layout.sh, so a plant may list an exception in it), run the copied checker there
 * on the copied objects. */
static int planted(const char *plant, char *out, size_t cap) {
    char cmd[8192];
    const char *t = pm_test_tmpdir();
    snprintf(cmd, sizeof cmd,
             "rm -rf '%s/t' && mkdir -p '%s/t' && cp -r '%s/render' '%s/t/' && "
             "cp -r '%s/obj/render' '%s/t/obj' && "
             "cp '%s/scripts/check-layout.sh' '%s/t/' && cd '%s/t/render' && %s "
             "&& sh '%s/t/check-layout.sh' '%s/t' '%s/t/obj'",
             t, t, pm_test_source_dir(), t, pm_test_build_dir(), t, pm_test_source_dir(), t, t, plant, t, t, t);
    return pm_test_run(cmd, out, cap);
}

TEST(layout_checker_sees_each_kind_of_violation) {
    static const struct {
        const char *plant, *expect;
    } cases[] = {
        /* a scene file reaching into the program */
        {"echo '#include \"app/tools.h\"' >> scene/camera.h",
         "back-import: scene/camera.h includes app/tools.h"},
        /* a file of 601 lines */
        {"for i in $(seq 601); do echo '/* x */'; done > base/long.h", "long file: base/long.h has 601 lines"},
        /* a function of 121 lines (signature, 119 statements, closing brace) */
        {"{ echo 'int planted_long(int a) {'; for i in $(seq 119); do echo '    a++;'; done; echo '}'; } "
         "> base/planted.c",
         "long function: base/planted.c planted_long() has 121 lines"},
        /* two headers that include each other (the second by its bare name, beside it) */
        {"printf '#include \"base/pb.h\"\\n' > base/pa.h && printf '#include \"pa.h\"\\n' > base/pb.h",
         "include circle: base/pa.h -> base/pb.h -> base/pa.h"},
        /* two files that call each other, compiled into the copied objects */
        {"printf 'void pb(void);\\nvoid pa(void) { pb(); }\\n' > base/pa.c && "
         "printf 'void pa(void);\\nvoid pb(void) { pa(); }\\n' > base/pb.c && "
         "${CC:-cc} -c base/pa.c -o ../obj/base/pa.o && ${CC:-cc} -c base/pb.c -o ../obj/base/pb.o",
         "call circle: base/pa.c -> base/pb.c -> base/pa.c"},
        /* a listed exception that no longer applies (or never did) must be struck from the list */
        {"sed -i \"/^EXCEPTIONS='/a include load/scene_load.c photons/photon_maps.h\" ../check-layout.sh",
         "stale exception: include load/scene_load.c photons/photon_maps.h"},
        /* a listed exception that grew past its recorded size */
        {"for i in $(seq 650); do echo '/* x */'; done > base/long.h && "
         "sed -i \"/^EXCEPTIONS='/a file base/long.h 640\" ../check-layout.sh",
         "long file: base/long.h has 650 lines (limit 640)"},
    };
    char out[16384];
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        int rc = planted(cases[i].plant, out, sizeof out);
        EXPECT_MSG(rc == 1 && strstr(out, cases[i].expect),
                   "planted '%s': expected rc 1 and '%s', got rc %d:\n%s", cases[i].plant,
                   cases[i].expect, rc, out);
    }
    /* and a clean copy passes, so the cases above fail for their plant alone */
    int rc = planted("true", out, sizeof out);
    EXPECT_MSG(rc == 0 && out[0] == 0, "the unplanted copy fails (rc %d):\n%s", rc, out);
    /* the circle of calls above, but one object's source is gone: the stale object is left out */
    rc = planted("printf 'void pb(void);\\nvoid pa(void) { pb(); }\\n' > base/pa.c && "
                 "printf 'void pa(void);\\nvoid pb(void) { pa(); }\\n' > base/pb.c && "
                 "${CC:-cc} -c base/pa.c -o ../obj/base/pa.o && ${CC:-cc} -c base/pb.c -o ../obj/base/pb.o && "
                 "rm base/pb.c", out, sizeof out);
    EXPECT_MSG(rc == 0 && out[0] == 0, "a stale object counted (rc %d):\n%s", rc, out);
    /* without objects the circles of calls are skipped, and the note says so */
    rc = planted("rm -rf ../obj", out, sizeof out);
    EXPECT_MSG(rc == 0 && strstr(out, "rule 5 (no circle of calls) skipped: no objects of render/"),
               "no objects: expected rc 0 and the note, got rc %d:\n%s", rc, out);
}
