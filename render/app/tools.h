/* tools.h: `render --compare`, `render --tonemap` and `render --dump-scene` (tools.c), the strict number parsers
 * that the options (options.c) share with them, and the check of a mode name.
 */
#ifndef RENDER_TOOLS_H
#define RENDER_TOOLS_H

#ifdef __cplusplus
extern "C" {
#endif

/* A whole number in [lo, hi] with nothing after it: 0 and *out set, or -1. */
int cli_parse_long(const char *s, long lo, long hi, long *out);
/* A positive, finite number: 0 and *out set, or -1 (NULL, trailing text, <= 0, inf, nan). */
int cli_parse_positive(const char *s, double *out);

/* 1 if name is a rendering mode of integrator.h's registry, 0 if not, -1 if it cannot tell
 * (out of memory). */
int cli_mode_known(const char *name);

/* The tools' programs: argv[1] is "--compare" or "--tonemap"; they return the exit status
 * (0 ok, 1 write failure, 2 usage error or unreadable input). */
int tools_compare(int argc, char **argv);
int tools_tonemap(int argc, char **argv);

/* `render --dump-scene SCENE.json` (argv[1] is the option): print the document that
 * scene_import makes of the file, after loading it fully (so it is known to load). Exit
 * status 0, 1 when stdout fails, 2 for a bad scene or mesh. */
int scene_dump_main(int argc, char **argv);

#ifdef __cplusplus
}
#endif

#endif
