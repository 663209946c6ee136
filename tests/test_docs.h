/* test_docs.h: what the documentation tests (test_docs.c, test_docs_hard.c) share: a generated
 * document regenerates exactly from its committed files, and README.md's generated blocks are
 * what their generators print.
 * Static inline, so a file that includes it has no unused-function warnings.
 */
#ifndef TEST_DOCS_H
#define TEST_DOCS_H

#include <stdio.h>
#include <string.h>

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

/* README.md's block (the lines between the one that starts with START and the one that starts
 * with END) equals what GEN_CMD prints, which must contain MUST; FIX says how to regenerate it.
 * The blocks were typed by hand before, and went stale. */
static inline void expect_readme_block(const char *gen_cmd, const char *must, const char *start, const char *end,
                                       const char *fix) {
    static char gen[16384], block[16384];
    char path[1024], line[2048];
    block[0] = 0;
    int rc = pm_test_run(gen_cmd, gen, sizeof gen);
    EXPECT_MSG(rc == 0 && strstr(gen, must), "generator failed (%d) or printed no \"%s\": %s\n%s", rc, must, gen_cmd, gen);
    if (rc != 0 || !strstr(gen, must)) return;
    snprintf(path, sizeof path, "%s/README.md", pm_test_source_dir());
    FILE *f = fopen(path, "r");
    EXPECT_MSG(f != NULL, "cannot open %s", path);
    if (!f) return;
    size_t len = 0, ls = strlen(start), le = strlen(end);
    int in = 0, seen = 0;
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, end, le) == 0) break;
        if (in) {
            size_t l = strlen(line);
            if (len + l < sizeof block) memcpy(block + len, line, l + 1), len += l;
        }
        if (strncmp(line, start, ls) == 0) in = seen = 1;
    }
    fclose(f);
    EXPECT_MSG(seen, "README.md has no \"%s\" block", start);
    EXPECT_MSG(strcmp(block, gen) == 0, "README.md's block \"%s\" is not the generated one (run %s):\n--- README:\n%s--- generated:\n%s",
               start, fix, block, gen);
}

#endif /* TEST_DOCS_H */
