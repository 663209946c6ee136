/* test_docs.c: the generated documents regenerate exactly from the committed files.
 *
 * Every measured figure in docs/ is written by a script in scripts/ from committed CSV and
 * results files, never typed. These tests run each generator on the committed files into a
 * temporary directory and fail on any difference from the committed document, so a document
 * edited by hand, a generator changed without regenerating, or a generator that reads
 * something other than its files (the clock, the checkout's commit, the machine) shows up.
 * Oracle: the committed document itself, byte for byte.
 *
 * docs/MEDIA.md (scripts/gen-media-md.sh from docs/media/) is checked here too. docs/MPI.md is
 * checked the same way in tests/test_mpi.c. docs/IMPORT.md is formatted from
 * docs/import/ (scripts/gen-import-md.sh, whose --run renders and measures into that folder).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "test.h"

/* Run CMD (which writes GOT) and compare GOT with the committed document DOC (relative to the
 * repository root); on a difference print the first lines of the diff. */
static void expect_regenerates(const char *cmd, const char *got, const char *doc) {
    char full[8192], out[16384];
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 0, "generator failed (%d): %s\n%s", rc, cmd, out);
    if (rc != 0) return;
    snprintf(full, sizeof full, "diff -u '%s/%s' '%s' | head -60", pm_test_source_dir(), doc, got);
    pm_test_run(full, out, sizeof out);
    EXPECT_MSG(out[0] == 0, "%s does not regenerate exactly from its files:\n%s", doc, out);
}

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
