/* test_docs.h: what the documentation tests (test_docs.c, test_docs_hard.c) share: a generated
 * document regenerates exactly from its committed files.
 * Static inline, so a file that includes it has no unused-function warnings.
 */
#ifndef TEST_DOCS_H
#define TEST_DOCS_H

#include <stdio.h>

#include "test.h"

/* Run CMD (which writes GOT) and compare GOT with the committed document DOC (relative to the
 * repository root); on a difference print the first lines of the diff. */
static inline void expect_regenerates(const char *cmd, const char *got, const char *doc) {
    char full[8192], out[16384];
    int rc = pm_test_run(cmd, out, sizeof out);
    EXPECT_MSG(rc == 0, "generator failed (%d): %s\n%s", rc, cmd, out);
    if (rc != 0) return;
    snprintf(full, sizeof full, "diff -u '%s/%s' '%s' | head -60", pm_test_source_dir(), doc, got);
    pm_test_run(full, out, sizeof out);
    EXPECT_MSG(out[0] == 0, "%s does not regenerate exactly from its files:\n%s", doc, out);
}

#endif /* TEST_DOCS_H */
