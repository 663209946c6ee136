/* test_docs.c: the generated documents regenerate exactly from the committed files.
 *
 * Every measured figure in docs/ is written by a script in scripts/ from committed CSV and
 * results files, never typed. These tests run each generator on the committed files into a
 * temporary directory and fail on any difference from the committed document, so a document
 * edited by hand, a generator changed without regenerating, or a generator that reads
 * something other than its files (the clock, the checkout's commit, the machine) shows up.
 * Oracle: the committed document itself, byte for byte.
 *
 * docs/MEDIA.md (scripts/gen-media-md.sh from docs/media/) is checked here too, and
 * docs/HARD_SCENES.md (scripts/gen-hard-scenes-md.sh from docs/hard_scenes/) in
 * tests/test_docs_hard.c. docs/MPI.md is checked the same way in tests/test_mpi.c. docs/IMPORT.md is formatted from
 * docs/import/ (scripts/gen-import-md.sh, whose --run renders and measures into that folder).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "test.h"
#include "test_docs.h"

/* docs/RESULTS.md from docs/results/ (scripts/gen-results-md.sh). */
TEST(docs_results_md_regenerates_exactly) {
    char cmd[4096], got[2048];
    snprintf(got, sizeof got, "%s/RESULTS.md", pm_test_tmpdir());
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/gen-results-md.sh' --out '%s'", pm_test_source_dir(), got);
    expect_regenerates(cmd, got, "docs/RESULTS.md");
}

/* docs/BENCHMARKS.md from bench/results/ (scripts/gen-benchmarks-md.sh, plots linked under
 * bench/ as `make bench` does). */
TEST(docs_benchmarks_md_regenerates_exactly) {
    char cmd[4096], got[2048];
    snprintf(got, sizeof got, "%s/BENCHMARKS.md", pm_test_tmpdir());
    snprintf(cmd, sizeof cmd, "cd '%s' && sh scripts/gen-benchmarks-md.sh bench/results bench > '%s'",
             pm_test_source_dir(), got);
    expect_regenerates(cmd, got, "docs/BENCHMARKS.md");
}

/* docs/IMPORT.md from docs/import/ (scripts/gen-import-md.sh, formatting only). */
TEST(docs_import_md_regenerates_exactly) {
    char cmd[4096], got[2048];
    snprintf(got, sizeof got, "%s/IMPORT.md", pm_test_tmpdir());
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/gen-import-md.sh' --out '%s'", pm_test_source_dir(), got);
    expect_regenerates(cmd, got, "docs/IMPORT.md");
}

/* Oracle: the script's documented usage. --help prints it and writes nothing (run in an empty
 * directory, which stays empty, and docs/IMPORT.md regenerates as before: checked above); an
 * unknown option and a missing results folder exit 2 with a message naming the problem. */
TEST(docs_import_generator_help_and_errors) {
    char cmd[4096], out[8192];
    snprintf(cmd, sizeof cmd, "cd '%s' && sh '%s/scripts/gen-import-md.sh' --help", pm_test_tmpdir(),
             pm_test_source_dir());
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "gen-import-md.sh [--out FILE] [RESULTS_DIR]") && strstr(out, "--run BUILD_DIR"),
               "--help printed: %s", out);
    snprintf(cmd, sizeof cmd, "ls -A '%s' | wc -l", pm_test_tmpdir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strtol(out, NULL, 10) == 0, "--help left files: %s", out);
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/gen-import-md.sh' --bogus", pm_test_source_dir());
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 2);
    EXPECT_MSG(strstr(out, "--bogus") != NULL, "%s", out);
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/gen-import-md.sh' --out '%s/x.md' '%s/none'", pm_test_source_dir(),
             pm_test_tmpdir(), pm_test_tmpdir());
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 2);
    EXPECT_MSG(strstr(out, "comparisons.csv missing") != NULL, "%s", out);
}

/* docs/ACCURACY.md from docs/accuracy/ (scripts/gen-accuracy-md.sh). */
TEST(docs_accuracy_md_regenerates_exactly) {
    char cmd[4096], got[2048];
    snprintf(got, sizeof got, "%s/ACCURACY.md", pm_test_tmpdir());
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/gen-accuracy-md.sh' --out '%s'", pm_test_source_dir(), got);
    expect_regenerates(cmd, got, "docs/ACCURACY.md");
}

/* Oracle: measurement.txt is the only source of the stamp (media/measurement.txt of the media
 * section's own). With their commits and dates replaced by values no checkout or clock can
 * have, the document carries exactly those, and neither the checkout's commit nor today's
 * date. */
TEST(docs_results_md_stamps_the_measurement) {
    const char *dir = pm_test_tmpdir();
    char cmd[8192], out[65536], head[64] = "", today[64] = "";
    snprintf(cmd, sizeof cmd,
             "cp -R '%s/docs/results' '%s/res' && cd '%s/res' && "
             "sed -i -e 's/^commit .*/commit c0ffee0-test/' -e 's/^date .*/date 1999-12-31 23:59 UTC/' "
             "measurement.txt && { [ ! -f media/measurement.txt ] || sed -i -e 's/^commit .*/commit c0ffee1-test/' "
             "-e 's/^date .*/date 1999-12-30 23:59 UTC/' media/measurement.txt; } && "
             "{ [ ! -f equal_time/measurement.txt ] || sed -i -e 's/^commit .*/commit c0ffee2-test/' "
             "-e 's/^date .*/date 1999-12-29 23:59 UTC/' equal_time/measurement.txt; } && "
             "{ [ ! -f survey/measurement.txt ] || sed -i -e 's/^commit .*/commit c0ffee3-test/' "
             "-e 's/^date .*/date 1999-12-28 23:59 UTC/' survey/measurement.txt; } && "
             "{ [ ! -f survey96/measurement.txt ] || sed -i -e 's/^commit .*/commit c0ffee4-test/' "
             "-e 's/^date .*/date 1999-12-27 23:59 UTC/' survey96/measurement.txt; } && "
             "sh '%s/scripts/gen-results-md.sh' --out '%s/R.md' '%s/res'",
             pm_test_source_dir(), dir, dir, pm_test_source_dir(), dir, dir);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    snprintf(cmd, sizeof cmd, "cat '%s/R.md'", dir);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "| commit | c0ffee0-test |"), "no measured commit in:\n%.2000s", out);
    EXPECT_MSG(strstr(out, "| date | 1999-12-31 23:59 UTC |"), "no measured date in:\n%.2000s", out);
    snprintf(cmd, sizeof cmd, "%s/docs/results/media/measurement.txt", pm_test_source_dir());
    struct stat media;
    if (stat(cmd, &media) == 0)
        EXPECT_MSG(strstr(out, "at commit c0ffee1-test,\n1999-12-30 23:59 UTC"), "no measured media stamp in:\n%.200s",
                   strstr(out, "## 3.") ? strstr(out, "## 3.") : out);
    snprintf(cmd, sizeof cmd, "%s/docs/results/equal_time/measurement.txt", pm_test_source_dir());
    if (stat(cmd, &media) == 0)
        EXPECT_MSG(strstr(out, "| commit | c0ffee2-test |") && strstr(out, "| date | 1999-12-29 23:59 UTC |") &&
                       strstr(out, "Measured sources (stamp c0ffee2-test)"),
                   "no measured equal-time stamp in:\n%.400s",
                   strstr(out, "## Equal time") ? strstr(out, "## Equal time") : out);
    snprintf(cmd, sizeof cmd, "%s/docs/results/survey/measurement.txt", pm_test_source_dir());
    if (stat(cmd, &media) == 0)
        EXPECT_MSG(strstr(out, "| commit | c0ffee3-test |") && strstr(out, "| date | 1999-12-28 23:59 UTC |") &&
                       strstr(out, "Measured sources (stamp c0ffee3-test)"),
                   "no measured survey stamp in:\n%.400s",
                   strstr(out, "## Every shipped") ? strstr(out, "## Every shipped") : out);
    snprintf(cmd, sizeof cmd, "%s/docs/results/survey96/measurement.txt", pm_test_source_dir());
    if (stat(cmd, &media) == 0)
        EXPECT_MSG(strstr(out, "| commit | c0ffee4-test |") && strstr(out, "| date | 1999-12-27 23:59 UTC |") &&
                       strstr(out, "Measured sources (stamp c0ffee4-test)") &&
                       strstr(out, "## The small survey's misses, at 96x96"),
                   "no measured stamp of the survey's misses in:\n%.400s",
                   strstr(out, "## The small survey") ? strstr(out, "## The small survey") : out);
    snprintf(cmd, sizeof cmd, "git -C '%s' rev-parse --short HEAD 2>/dev/null", pm_test_source_dir());
    if (pm_test_run(cmd, head, sizeof head) == 0 && head[0]) {
        head[strcspn(head, "\n")] = 0;
        snprintf(cmd, sizeof cmd, "| commit | %s", head);
        EXPECT_MSG(!strstr(out, cmd), "the checkout's commit %s leaked into the document", head);
    }
    ASSERT_EQ_INT(pm_test_run("date -u +%Y-%m-%d", today, sizeof today), 0);
    today[strcspn(today, "\n")] = 0;
    EXPECT_MSG(!strstr(out, today), "today's date %s leaked into the document", today);
}

/* Oracle: the documented usage. --help prints it, exits 0 and writes no document (the
 * committed one keeps its bytes and time); an unknown option is an input error (2). */
TEST(docs_results_generator_help_writes_nothing) {
    char cmd[4096], out[8192], path[2048];
    struct stat before, after;
    snprintf(path, sizeof path, "%s/docs/RESULTS.md", pm_test_source_dir());
    ASSERT(stat(path, &before) == 0);
    snprintf(cmd, sizeof cmd, "cd '%s' && sh '%s/scripts/gen-results-md.sh' --help", pm_test_tmpdir(),
             pm_test_source_dir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "gen-results-md.sh [--out FILE] [RESULTS_DIR]"), "--help printed: %s", out);
    EXPECT_MSG(!strstr(out, "wrote"), "--help wrote a document: %s", out);
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/gen-results-md.sh' --bogus", pm_test_source_dir());
    EXPECT_EQ_INT(pm_test_run(cmd, out, sizeof out), 2);
    ASSERT(stat(path, &after) == 0);
    EXPECT(after.st_mtim.tv_sec == before.st_mtim.tv_sec && after.st_mtim.tv_nsec == before.st_mtim.tv_nsec);
    snprintf(cmd, sizeof cmd, "ls -A '%s' | wc -l", pm_test_tmpdir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strtol(out, NULL, 10) == 0, "--help left files: %s", out);
}

/* docs/PROFILE.md from docs/profile/ (scripts/profile-pm.sh --gen, formatting only). */
TEST(docs_profile_md_regenerates_exactly) {
    char cmd[4096], got[2048];
    snprintf(got, sizeof got, "%s/PROFILE.md", pm_test_tmpdir());
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/profile-pm.sh' --gen --out '%s'", pm_test_source_dir(), got);
    expect_regenerates(cmd, got, "docs/PROFILE.md");
}

/* docs/MEDIA.md from docs/media/ (scripts/gen-media-md.sh). */
TEST(docs_media_md_regenerates_exactly) {
    char cmd[4096], got[2048];
    snprintf(got, sizeof got, "%s/MEDIA.md", pm_test_tmpdir());
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/gen-media-md.sh' --out '%s'", pm_test_source_dir(), got);
    expect_regenerates(cmd, got, "docs/MEDIA.md");
}

/* Oracle: each section's measurement file is the only source of its stamp. With the commit
 * and date of cornell_fog's measurement replaced by values no checkout or clock can have, the
 * document carries exactly those; every script of the media proofs prints its usage. */
TEST(docs_media_md_stamps_the_measurement) {
    const char *dir = pm_test_tmpdir();
    char cmd[8192], out[65536];
    snprintf(cmd, sizeof cmd,
             "cp -R '%s/docs/media' '%s/res' && cd '%s/res' && "
             "sed -i -e 's/^commit .*/commit c0ffee0-test/' -e 's/^date .*/date 1999-12-31 23:59 UTC/' "
             "measurement_cornell_fog.txt && sh '%s/scripts/gen-media-md.sh' --out '%s/M.md' '%s/res' && cat '%s/M.md'",
             pm_test_source_dir(), dir, dir, pm_test_source_dir(), dir, dir, dir);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "Measured at commit c0ffee0-test, 1999-12-31 23:59 UTC"), "no measured stamp in:\n%.1500s", out);
    static const char *const scripts[] = {"gen-media-md.sh", "media-time-error.sh", "media-results.sh", "media-cost.sh"};
    for (int i = 0; i < 4; i++) {
        snprintf(cmd, sizeof cmd, "cd '%s' && sh '%s/scripts/%s' --help", dir, pm_test_source_dir(), scripts[i]);
        EXPECT_MSG(pm_test_run(cmd, out, sizeof out) == 0 && strstr(out, scripts[i]), "%s --help: %s", scripts[i], out);
    }
}

/* Oracle: the definition of the column. docs/MEDIA.md's cost table gives, per case, the lowest
 * and the highest of the run-by-run after / before ratios: the lowest is never above the
 * highest (the column once printed the ratio of the minima over that of the maxima, and a
 * "minimum" above the "maximum"). Each is recomputed from docs/media/cost.csv (runs paired by
 * run number) to 0.0005, the table's rounding. */
TEST(docs_media_cost_column_is_lowest_and_highest) {
    char cmd[4096], out[8192];
    snprintf(cmd, sizeof cmd,
             "cd '%s/docs' && awk -F, 'NR > 1 { t[$1 SUBSEP $2 SUBSEP $3] = $4; c[$1] = 1; b[$2] = 1 }"
             " END { for (k in c) print k }' media/cost.csv | sort", pm_test_source_dir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    int cases = 0;
    for (char *line = strtok(out, "\n"); line; line = strtok(NULL, "\n")) {
        char name[256], row[8192], *p;
        double lo = 0, hi = 0, want_lo = 0, want_hi = 0;
        snprintf(name, sizeof name, "%s", line);
        snprintf(cmd, sizeof cmd, "grep '^| %s |' '%s/docs/MEDIA.md'", name, pm_test_source_dir());
        if (pm_test_run(cmd, row, sizeof row) != 0) continue;
        p = strrchr(row, '|');
        if (p) *p = 0;
        p = strrchr(row, '|');
        ASSERT_MSG(p && sscanf(p, "| %lf / %lf", &lo, &hi) == 2, "row: %s", row);
        snprintf(cmd, sizeof cmd,
                 "cd '%s/docs' && b0=$(awk '$1 == \"before\" { print $2 }' media/cost_measurement.txt) && "
                 "b1=$(awk '$1 == \"after\" { print $2 }' media/cost_measurement.txt) && "
                 "awk -F, -v c='%s' -v b0=\"$b0\" -v b1=\"$b1\" '$1 == c && $2 == b0 { t0[$3] = $4 } "
                 "$1 == c && $2 == b1 { t1[$3] = $4 } END { lo = 1e9; hi = -1e9; for (r in t0) if (r in t1) "
                 "{ q = t1[r] / t0[r]; if (q < lo) lo = q; if (q > hi) hi = q } printf \"%%.6f %%.6f\", lo, hi }' "
                 "media/cost.csv",
                 pm_test_source_dir(), name);
        char got[256];
        ASSERT_EQ_INT(pm_test_run(cmd, got, sizeof got), 0);
        ASSERT(sscanf(got, "%lf %lf", &want_lo, &want_hi) == 2);
        EXPECT_MSG(lo <= hi, "%s: lowest %.3f above highest %.3f", name, lo, hi);
        EXPECT_NEAR(lo, want_lo, 0.0005 + 1e-9); /* half a unit of %.3f, inclusive: 0.3125 prints 0.312 */
        EXPECT_NEAR(hi, want_hi, 0.0005 + 1e-9);
        cases++;
    }
    EXPECT_MSG(cases >= 1, "no cost row of docs/media/cost.csv found in docs/MEDIA.md");
}

/* ---- staleness: a measured section is older than the sources it measures ----------------- */

/* Each measured section of the documents in docs/ says what it measured in one line written by its
 * generator from the measurement's own files:
 *
 *     Measured sources (stamp COMMIT): `photonmap/` `render/` `Makefile`
 *
 * (the stamp is the commit the measured binaries were built from). The section is stale when a
 * commit after the stamp, other than a merge, touched one of those sources (git rev-list
 * --no-merges STAMP..HEAD -- SOURCES),
 * or when the stamp is not a commit of this history.
 *
 * KNOWN_STALE lists the sections that were stale when this check was written and are being or
 * will be re-measured, as "doc|section heading|stamp": they are reported, not failed. An entry
 * matches only its stamp, so a section re-measured (a new stamp) is checked again at once; an
 * entry that matches nothing any more is reported for removal. The lead shrinks this list as
 * sections are re-measured; a new stale section fails. `sh scripts/remeasure-docs.sh` re-measures
 * the stale sections of ACCURACY, IMPORT, MEDIA, MPI and PROFILE (scripts/profile-pm.sh) in one run
 * (NULL: the list is empty).
 *
 * UNDECLARED lists the measured documents whose generators do not write the line yet (NULL:
 * none; docs/BENCHMARKS.md's workload race declares its sources, written by
 * scripts/gen-benchmarks-md.sh from the race's knn_machine.csv): reported; every other document
 * in docs/ must have the line at least once, or be in NOT_MEASURED. */
static const char *const KNOWN_STALE[] = {
    NULL, /* none: scripts/remeasure-docs.sh re-measures every declared section but BENCHMARKS and RESULTS */
};
static const char *const UNDECLARED[] = {NULL}; /* none: BENCHMARKS declares its race section since knn3 */
static const char *const NOT_MEASURED[] = {NULL};

static int in_list(const char *const *list, size_t n, const char *s) {
    for (size_t i = 0; i < n; i++)
        if (list[i] && !strcmp(list[i], s)) return 1;
    return 0;
}

/* Oracle: git's history of the checkout against the stamps and sources the documents state. */
TEST(docs_measured_sections_are_not_stale) {
    char cmd[8192], out[32768];
    snprintf(cmd, sizeof cmd, "git -C '%s' rev-parse --verify -q HEAD", pm_test_source_dir());
    if (pm_test_run(cmd, out, sizeof out) != 0) SKIP("the source directory is not a git checkout: no history to compare stamps with");
    /* doc|heading|stamp|newer commits|newest of them|sources, one line per measured section;
     * then "doc|-" for each document with no such line */
    snprintf(cmd, sizeof cmd,
             "cd '%s' && for d in docs/*.md; do "
             "awk -v d=\"$d\" '/^#/ { h = $0; sub(/^#+ */, \"\", h) } "
             "/^Measured sources \\(stamp [0-9a-f]+\\): / { s = $0; sub(/^Measured sources \\(stamp /, \"\", s); "
             "st = s; sub(/\\).*/, \"\", st); sub(/^[^:]*: /, \"\", s); gsub(/`/, \"\", s); "
             "print d \"|\" h \"|\" st \"|\" s; f = 1 } END { if (!f) print d \"|-\" }' \"$d\"; done | "
             "while IFS='|' read -r doc head stamp src; do "
             "if [ \"$head\" = - ]; then echo \"$doc|-\"; continue; fi; "
             "if git cat-file -e \"$stamp^{commit}\" 2>/dev/null; then "
             "n=$(git rev-list --no-merges --count \"$stamp..HEAD\" -- $src); last=$(git log --no-merges -1 --format=%%h \"$stamp..HEAD\" -- $src); "
             "else n=unknown; last=-; fi; echo \"$doc|$head|$stamp|$n|$last|$src\"; done",
             pm_test_source_dir());
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    int sections = 0, stale = 0, known = 0;
    int used[sizeof KNOWN_STALE / sizeof *KNOWN_STALE] = {0};
    for (char *line = strtok(out, "\n"); line; line = strtok(NULL, "\n")) {
        char doc[256] = "", head[512] = "", stamp[64] = "", n[32] = "", last[64] = "", src[1024] = "", key[1024];
        char *f[6] = {doc, head, stamp, n, last, src};
        size_t cap[6] = {sizeof doc, sizeof head, sizeof stamp, sizeof n, sizeof last, sizeof src};
        char *p = line;
        for (int i = 0; i < 6 && p; i++) {
            char *bar = i < 5 ? strchr(p, '|') : NULL;
            size_t len = bar ? (size_t)(bar - p) : strlen(p);
            snprintf(f[i], cap[i], "%.*s", (int)len, p);
            p = bar ? bar + 1 : NULL;
        }
        if (!strcmp(head, "-")) {
            if (in_list(UNDECLARED, sizeof UNDECLARED / sizeof *UNDECLARED, doc))
                printf("    %s: no 'Measured sources' line yet (listed as undeclared)\n", doc);
            else
                EXPECT_MSG(in_list(NOT_MEASURED, sizeof NOT_MEASURED / sizeof *NOT_MEASURED, doc),
                           "%s has no 'Measured sources (stamp ...)' line: its generator must write one", doc);
            continue;
        }
        if (in_list(UNDECLARED, sizeof UNDECLARED / sizeof *UNDECLARED, doc))
            printf("    %s now declares its sources: take it off UNDECLARED\n", doc);
        sections++;
        if (!strcmp(n, "0")) continue;
        snprintf(key, sizeof key, "%s|%s|%s", doc, head, stamp);
        int k = -1;
        for (size_t i = 0; i < sizeof KNOWN_STALE / sizeof *KNOWN_STALE; i++)
            if (KNOWN_STALE[i] && !strcmp(KNOWN_STALE[i], key)) k = (int)i;
        if (k >= 0) {
            used[k] = 1;
            known++;
            printf("    known stale: %s \"%s\" (stamp %s; %s later commits to %s, the last %s)\n", doc, head, stamp, n, src, last);
        } else {
            stale++;
            EXPECT_MSG(0, "%s \"%s\" is stale: measured at %s, and %s later commits touched %s (the last %s): re-measure it",
                       doc, head, stamp, n, src, last);
        }
    }
    for (size_t i = 0; i < sizeof KNOWN_STALE / sizeof *KNOWN_STALE; i++)
        if (KNOWN_STALE[i] && !used[i])
            printf("    KNOWN_STALE entry no longer stale or gone (remove it): %s\n", KNOWN_STALE[i]);
    printf("    %d measured sections: %d stale (known %d)\n", sections, stale + known, known);
    EXPECT_MSG(sections >= 8, "only %d measured sections found", sections);
}

/* Oracle: the data the sentences read. gen-media-md.sh's sentences on the path-traced beam
 * runs are computed from time_error_volumetric_caustic.csv, not typed: on a copy of docs/media/
 * whose path-traced runs all see the beam (image mean that of photon mapping) with RMSE
 * exactly sqrt(40 / N), the document says no run misses the beam and that N RMSE² stays
 * within 40 to 40 (RMSE falls as 1/sqrt(N)); with the runs of 16 and 64 spp made to miss it
 * (image mean 0) and N RMSE² 10 for the next run and 40 for the rest, it names those two runs
 * and says RMSE does not yet fall as 1/sqrt(N) (ranges from 10 to 40). Both on copies of the
 * committed files, so the check does not depend on what a re-measurement finds. gen-accuracy-md.sh likewise says
 * the two lookups agree only when every row's mismatches is 0. */
TEST(docs_generators_sentences_follow_the_data) {
    char cmd[8192], out[65536];
    const char *t = pm_test_tmpdir(), *src = pm_test_source_dir();
    /* the runs of 16 and 64 spp made to miss the beam (mean 0), the others given N RMSE² = 10
     * for the first that sees it and 40 for the rest */
    snprintf(cmd, sizeof cmd,
             "cp -r '%s/docs/media' '%s/miss' && cd '%s/miss' && "
             "awk -F, -v OFS=, 'NR == 1 { print; next } $1 == \"pm\" { m = $6 } { r[NR] = $0 } "
             "END { for (i = 2; i <= NR; i++) { split(r[i], f, \",\"); if (f[1] == \"path\") { "
             "if (f[2] == 16 || f[2] == 64) f[6] = 0; else { f[6] = m; f[5] = f[7] = sqrt((k++ ? 40 : 10) / f[2]) } } "
             "print f[1], f[2], f[3], f[4], f[5], f[6], f[7] } }' "
             "time_error_volumetric_caustic.csv > x && mv x time_error_volumetric_caustic.csv && "
             "sh '%s/scripts/gen-media-md.sh' --out - '%s/miss' 2>/dev/null",
             src, t, t, src, t);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "Path tracing's runs of 16 and 64 spp miss the beam"), "media with two misses: %.400s", out);
    EXPECT_MSG(strstr(out, "N RMSE² ranges from 10 to 40: its RMSE does not yet fall as 1/sqrt(N)."), "media 10 to 40");
    snprintf(cmd, sizeof cmd,
             "cp -r '%s/docs/media' '%s/media' && cd '%s/media' && "
             "awk -F, -v OFS=, 'NR == 1 { print; next } $1 == \"pm\" { m = $6 } { r[NR] = $0 } "
             "END { for (i = 2; i <= NR; i++) { split(r[i], f, \",\"); if (f[1] == \"path\") { f[6] = m; "
             "f[5] = f[7] = sqrt(40 / f[2]) } print f[1], f[2], f[3], f[4], f[5], f[6], f[7] } }' "
             "time_error_volumetric_caustic.csv > x && mv x time_error_volumetric_caustic.csv && "
             "sh '%s/scripts/gen-media-md.sh' --out - '%s/media' 2>/dev/null",
             src, t, t, src, t);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(!strstr(out, "miss the beam"), "no run misses the beam here: %.400s", out);
    EXPECT_MSG(strstr(out, "N RMSE² stays within 40 to 40: its RMSE falls as 1/sqrt(N)."), "synthetic media");
    snprintf(cmd, sizeof cmd,
             "cp -r '%s/docs/accuracy' '%s/acc' && cd '%s/acc' && "
             "awk -F, -v OFS=, 'NR == 2 { $9 = 3 } { print }' irradiance_lookup.csv > x && mv x irradiance_lookup.csv && "
             "sh '%s/scripts/gen-accuracy-md.sh' --out - '%s/acc'",
             src, t, t, src, t);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(!strstr(out, "Both give the same answers") && strstr(out, "In 3 answers of the rows below the two disagree"),
               "accuracy with 3 mismatches: %.300s", strstr(out, "private tree") ? strstr(out, "private tree") : out);
}

/* Oracle: synthetic results whose verdicts are known by construction. Path tracing's RMSE is
 * exactly sqrt(c (1/N + 1/N_ref)) with c = 0.1, N_ref = 10000, and its CPU time 0.01 N; photon
 * mapping's corrected errors 0.01 and 0.005 need path tracing 0.01 x 0.1 / E² = 10 and 40
 * CPU-s, so at 1 and 2 CPU-s its ratios are 10x and 20x (the 5x target met by both runs), and
 * at 1 and 20 CPU-s 10x and 2x (met by one of two). One region mean of three is outside its
 * tolerance. Then the path-traced run of 256 spp is given twice its RMSE (c four times as
 * large): gen-results-md.sh must no longer say that the error falls as 1/sqrt(N). */
TEST(docs_results_sentences_follow_the_data) {
    char cmd[8192], out[65536];
    const char *t = pm_test_tmpdir(), *src = pm_test_source_dir();
    snprintf(cmd, sizeof cmd,
             "mkdir -p '%s/r' && cd '%s/r' && "
             "printf 'commit abc1234\\ndate 2000-01-01 00:00 UTC\\nmachine test\\nthreads 2\\npm_spp 64\\n"
             "pt_spps 64 256\\npm_spps 16 64\\nref_cornell_spheres_width 128\\nref_cornell_spheres_height 128\\n"
             "ref_cornell_spheres_spp 10000\\nref_cornell_spheres_seed 1000\\n' > measurement.txt && "
             "printf 'c 0.1\\nreference_spp 10000\\nreference_rmse 0.00316228\\npt_cpu_per_spp 0.01\\n"
             "pt_cpu_fixed 0\\n' > time_error_summary.txt && "
             "printf 'scene,config,region,pixels,pm_mean,ref_mean,rel_diff,tolerance,pass\\n"
             "cornell_spheres,defaults,image,100,1.01,1,0.01,0.03,yes\\n"
             "cornell_spheres,defaults,floor,10,1.07,1,0.07,0.05,no\\n"
             "cornell_diffuse,defaults,image,100,0.99,1,-0.01,0.03,yes\\n' > regions.csv && "
             "awk 'BEGIN { print \"method,spp,seed,wall_s,cpu_s,rmse_vs_ref,rmse_corrected\"; "
             "for (n = 64; n <= 256; n *= 4) printf \"path,%%d,1,%%g,%%g,%%.9g,%%.9g\\n\", n, n / 200, n / 100, "
             "sqrt(0.1 * (1 / n + 1e-4)), sqrt(0.1 / n); "
             "printf \"pm,16,2,1,1,%%.9g,0.01\\npm,64,3,2,2,%%.9g,0.005\\n\", sqrt(1e-4 + 1e-5), sqrt(2.5e-5 + 1e-5) }' "
             "> time_error.csv && sh '%s/scripts/gen-results-md.sh' --out - '%s/r' 2>&1",
             t, t, src, t);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "within 25%, so the path tracer's error falls as 1/sqrt(N) here."), "1/sqrt(N): %.3000s",
               strstr(out, "## 2.") ? strstr(out, "## 2.") : out);
    EXPECT_MSG(strstr(out, "ranges from **10.00x** (16 spp) to **20.00x** (64 spp)") &&
                   strstr(out, "target at least 5x: met by every run."),
               "ratios 10x and 20x: %.3000s", strstr(out, "## 2.") ? strstr(out, "## 2.") : out);
    EXPECT_MSG(strstr(out, "At the defaults: 2 of 3 region means are within their tolerance; the largest difference "
                           "is 7.00%, cornell_spheres floor."),
               "regions: %.2000s", out);
    EXPECT_MSG(strstr(out, "Measured sources (stamp abc1234): `photonmap/` `render/` `Makefile`"), "stamp line");
    /* photon mapping's second run at 20 CPU-s: 2x, below the target */
    snprintf(cmd, sizeof cmd,
             "cd '%s/r' && sed -i 's/^pm,64,3,2,2,/pm,64,3,20,20,/' time_error.csv && "
             "sh '%s/scripts/gen-results-md.sh' --out - '%s/r' 2>&1",
             t, src, t);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "ranges from **2.00x** (64 spp) to **10.00x** (16 spp)") &&
                   strstr(out, "target at least 5x: met by 1 of 2 runs."),
               "ratios 2x and 10x: %.3000s", strstr(out, "## 2.") ? strstr(out, "## 2.") : out);
    /* the path-traced run of 256 spp with twice its RMSE: c from 0.1 to 0.4 */
    snprintf(cmd, sizeof cmd,
             "cd '%s/r' && awk -F, -v OFS=, '$1 == \"path\" && $2 == 256 { $6 = 2 * $6 } { print }' time_error.csv > x && "
             "mv x time_error.csv && sh '%s/scripts/gen-results-md.sh' --out - '%s/r' 2>&1",
             t, src, t);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(!strstr(out, "falls as 1/sqrt(N) here") &&
                   strstr(out, "they differ by 300%, more than 25%, so the path tracer's error does not follow 1/sqrt(N)"),
               "c from 0.1 to 0.4: %.3000s", strstr(out, "## 2.") ? strstr(out, "## 2.") : out);
}

/* The survey's targets table (scripts/gen-equal-time-md.sh --survey) marks a scene whose
 * path-traced reference misses light (make-equal-time.sh writes "ref_misses_NAME yes" where
 * render warns that path tracing cannot render the scene's L S+ D light) as not comparable,
 * and only that scene. Oracle: the shipped survey data with such a line added for one scene,
 * and the same data without it. */
TEST(docs_survey_marks_references_that_miss_light) {
    char cmd[8192], out[65536];
    const char *t = pm_test_tmpdir(), *src = pm_test_source_dir();
    snprintf(cmd, sizeof cmd,
             "mkdir -p '%s/s' && cp '%s/docs/results/survey/'* '%s/s/' && sed -i '/^ref_misses_/d' '%s/s/measurement.txt' && "
             "sh '%s/scripts/gen-equal-time-md.sh' --survey '%s/s' | grep '^| cornell_box |\\|^| cornell_diffuse |'",
             t, src, t, t, src, t);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(!strstr(out, "not comparable"), "without the line: %s", out);
    snprintf(cmd, sizeof cmd,
             "echo 'ref_misses_cornell_box yes' >> '%s/s/measurement.txt' && "
             "sh '%s/scripts/gen-equal-time-md.sh' --survey '%s/s' | grep '^| cornell_box |\\|^| cornell_diffuse |'",
             t, src, t);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    const char *box = strstr(out, "| cornell_box |"), *diffuse = strstr(out, "| cornell_diffuse |");
    ASSERT_MSG(box && diffuse, "%s", out);
    EXPECT_MSG(strstr(box, "| not comparable: ") && strstr(box, "path tracing cannot render") &&
                   strstr(box, "| not comparable: ") < diffuse,
               "cornell_box: %s", out);
    EXPECT_MSG(!strstr(diffuse, "not comparable"), "cornell_diffuse: %s", out);
}

/* make-survey.sh measures again, larger, the scenes that `gen-equal-time-md.sh --misses` lists:
 * those whose verdict in the survey's targets table is "no", each against its own target (5x
 * for cornell_spheres, 1x for most), or "not measured" (cornell_fog here: its one run's error is
 * below the reference's noise, and the lower bound on its ratio is under the target). Oracle: a
 * survey built here with a path tracer of variance constant c = 1 and 0.01 CPU-s a sample, so
 * that path tracing needs 0.01 / E^2 CPU-s for an error E, and photon-mapping runs of 1 CPU-s
 * whose errors give ratios of 3 (cornell_box: met; cornell_spheres: missed, its target is 5)
 * and 0.5 (glass_hole: missed); black_box's run is below the reference's noise (MSE 0.5e-6
 * against the reference's 1e-6), and its uncorrected error gives path tracing 2e4 CPU-s, a
 * lower bound of 2e4x, met; cornell_fog's is the same run at 1e6 CPU-s, 0.02x. cornell_diffuse's
 * run is above the noise but its corrected MSE (0.5e-6) is under it: it counts with its whole
 * MSE (1.5e-6), a lower bound of 0.01 / 1.5e-6 = 6666.67x (its corrected MSE would give 2e4x).
 * With follow_up_of in its measurement.txt the same data prints as the follow-up section. */
TEST(docs_survey_misses_follow_the_verdict) {
    char cmd[8192], out[65536];
    const char *t = pm_test_tmpdir(), *src = pm_test_source_dir();
    FILE *f;
    snprintf(cmd, sizeof cmd, "%s/runs.csv", t);
    ASSERT((f = fopen(cmd, "w")) != NULL);
    fprintf(f, "scene,mode,budget_cpu_s,spp,cpu_s,wall_s,rmse,ref_spp\n");
    const char *scenes[6] = {"black_box", "cornell_box", "cornell_spheres", "glass_hole", "cornell_fog",
                             "cornell_diffuse"};
    const double ratio[6] = {0, 3, 3, 0.5, 0, -1}; /* 0: an error below the reference's noise; -1: see above */
    for (int i = 0; i < 6; i++) {
        double nref = 1e6;
        fprintf(f, "%s,path,1,100,1.00,0.5,%.9g,1000000\n", scenes[i], sqrt(1.0 / 100 + 1 / nref));
        fprintf(f, "%s,path,4,400,4.00,2.0,%.9g,1000000\n", scenes[i], sqrt(1.0 / 400 + 1 / nref));
        /* below the noise, 1 CPU-s (black_box) or 1e6 (cornell_fog): path tracing needs
         * 1 / (0.5e-6) spp at 0.01 CPU-s each for the uncorrected error, 2e4 CPU-s, so the lower
         * bounds are 2e4x (met) and 0.02x (under the target: not measured) */
        fprintf(f, "%s,pm,1,50,%s,0.5,%.9g,1000000\n", scenes[i], i == 4 ? "1000000" : "1.00",
                ratio[i] > 0 ? sqrt(0.01 / ratio[i] + 1 / nref) : sqrt((ratio[i] < 0 ? 1.5 : 0.5) / nref));
    }
    fclose(f);
    snprintf(cmd, sizeof cmd, "%s/calib.csv", t);
    ASSERT((f = fopen(cmd, "w")) != NULL);
    fprintf(f, "scene,mode,spp,cpu_s,wall_s\n");
    for (int i = 0; i < 6; i++) fprintf(f, "%s,path,16,0.16,0.1\n%s,path,800,8.00,4.0\n", scenes[i], scenes[i]);
    fclose(f);
    snprintf(cmd, sizeof cmd, "%s/measurement.txt", t);
    ASSERT((f = fopen(cmd, "w")) != NULL);
    fprintf(f, "commit c0ffee5-test\ndate 1999-12-26 23:59 UTC\nmachine 2 cores\nload 0 0 0\n"
               "resolution 96\nthreads 2\nbudgets 1 4\n");
    fclose(f);
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/gen-equal-time-md.sh' --misses '%s'", src, t);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strcmp(out, "cornell_spheres\nglass_hole\ncornell_fog\n") == 0, "--misses printed:\n%s", out);
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/gen-equal-time-md.sh' --survey '%s'", src, t);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "## Every shipped scene, small") && strstr(out, "| cornell_box | 1x | 3.00x | 3.00x | 0 | yes |") &&
                   strstr(out, "| cornell_spheres | 5x | 3.00x | 3.00x | 0 | no |") &&
                   strstr(out, "| glass_hole | 1x | 0.50x | 0.50x | 0 | no |") &&
                   strstr(out, "| black_box | 1x | >= 20000.00x | - | 1 | yes, every run by a lower bound (>= 20000.00x)") &&
                   strstr(out, "| cornell_fog | 1x | - | - | 1 | not measured: 1 photon-mapping run had a corrected error "
                               "below the reference's own noise, and its lower bound (>= 0.02x) is under the target") &&
                   strstr(out, "| cornell_diffuse | 1x | >= 6666.67x | - | 1 | yes, every run by a lower bound (>= "
                               "6666.67x)"),
               "the survey's table:\n%s", out);
    snprintf(cmd, sizeof cmd, "echo 'follow_up_of 32' >> '%s/measurement.txt' && sh '%s/scripts/gen-equal-time-md.sh' --survey '%s'",
             t, src, t);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "## The small survey's misses, at 96x96") && strstr(out, "at 32x32") &&
                   strstr(out, "9 times the pixels") && !strstr(out, "## Every shipped"),
               "the follow-up's header:\n%.1500s", out);
}

/* The consistency table with several seeds (gen-equal-time-md.sh): a row per seed's chain and a
 * median row. Oracle: progressive runs built here over one decade of CPU time (1 -> 10 CPU-s),
 * whose RMSEs fall 2x, 3x and 1.5x (seeds 7, 8, 9; a reference of 1e12 samples, so its noise is
 * nothing), and blocks all +0.10% but seed 8's block3 (-0.80%) and seed 9's block0 (+1.20%):
 * the steps per 10x are those falls, their median 2.00x, 26 of the 27 blocks are within 1%,
 * and the worst is seed 9's block0. */
TEST(docs_consistency_table_gives_each_seed_and_the_median) {
    char cmd[8192], out[65536];
    const char *t = pm_test_tmpdir(), *src = pm_test_source_dir();
    FILE *f;
    snprintf(cmd, sizeof cmd, "%s/runs.csv", t);
    ASSERT((f = fopen(cmd, "w")) != NULL);
    fprintf(f, "scene,mode,budget_cpu_s,spp,cpu_s,wall_s,rmse,ref_spp,seed\n");
    fprintf(f, "water_caustic,path,1,100,1.00,0.5,%.9g,1000000000000,101\n", sqrt(1.0 / 100));
    fprintf(f, "water_caustic,path,4,400,4.00,2.0,%.9g,1000000000000,102\n", sqrt(1.0 / 400));
    const double first[3] = {0.2, 0.3, 0.15};
    for (int k = 0; k < 3; k++) {
        fprintf(f, "water_caustic,pm_passes,1,16,1.00,0.5,%.9g,1000000000000,%d\n", first[k], 7 + k);
        fprintf(f, "water_caustic,pm_passes,4,64,10.00,5.0,0.1,1000000000000,%d\n", 7 + k);
    }
    fclose(f);
    snprintf(cmd, sizeof cmd, "%s/calib.csv", t);
    ASSERT((f = fopen(cmd, "w")) != NULL);
    fprintf(f, "scene,mode,spp,cpu_s,wall_s\nwater_caustic,path,16,0.16,0.1\n");
    fclose(f);
    snprintf(cmd, sizeof cmd, "%s/regions_prog.csv", t);
    ASSERT((f = fopen(cmd, "w")) != NULL);
    fprintf(f, "scene,passes,region,pm_mean,ref_mean,rel_diff,seed\n");
    for (int k = 0; k < 3; k++) {
        fprintf(f, "water_caustic,4,image,1,1,-0.00100,%d\n", 7 + k);
        for (int b = 0; b < 9; b++) {
            double d = (k == 1 && b == 3) ? -0.008 : (k == 2 && b == 0) ? 0.012 : 0.001;
            fprintf(f, "water_caustic,4,block%d,1,1,%.5f,%d\n", b, d, 7 + k);
        }
    }
    fclose(f);
    snprintf(cmd, sizeof cmd, "%s/measurement.txt", t);
    ASSERT((f = fopen(cmd, "w")) != NULL);
    fprintf(f, "commit c0ffee6-test\nprog_spp 16\nprog_seeds 7 8 9\ndate 1999-12-25 23:59 UTC\nmachine 2 cores\n"
               "load 0 0 0\nresolution 96\nthreads 2\nbudgets 1 4\n");
    fclose(f);
    snprintf(cmd, sizeof cmd, "sh '%s/scripts/gen-equal-time-md.sh' '%s' | grep '^| water_caustic |'", src, t);
    ASSERT_EQ_INT(pm_test_run(cmd, out, sizeof out), 0);
    EXPECT_MSG(strstr(out, "| water_caustic | 7 | 1 to 4 | 1 to 10 | 2.00x | 2.00x | 2.00x | -0.10% | 9 of 9 | +0.10% (block0) |") &&
                   strstr(out, "| water_caustic | 8 | 1 to 4 | 1 to 10 | 3.00x | 3.00x | 3.00x | -0.10% | 9 of 9 | -0.80% (block3) |") &&
                   strstr(out, "| water_caustic | 9 | 1 to 4 | 1 to 10 | 1.50x | 1.50x | 1.50x | -0.10% | 8 of 9 | +1.20% (block0) |") &&
                   strstr(out, "| water_caustic | median of 3 | | | 2.00x | 2.00x | 2.00x (each seed's lowest: 2.00x) | - | 26 of 27 | "
                               "worst +1.20% (block0) (seed 9) |"),
               "the consistency rows:\n%s", out);
}
