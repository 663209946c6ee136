/* errors.h: the renderer's own texts for the error codes its functions return.
 *
 * The renderer's functions follow the module's convention (0 ok, a negative PM_E* code on
 * failure; photonmap/common.h), but pm_strerror words them for photon-map files ("not a
 * photon-map file"), which is wrong for a PFM, a PNG or a scene. render_strerror says what
 * the code means for any file or value the renderer handles, and for PM_EIO gives
 * strerror(errno) (so call it before anything else can change errno). Errors that come from
 * photonmap/ itself (loading a .pmap file, building a tree) keep pm_strerror's text.
 */
#ifndef RENDER_ERRORS_H
#define RENDER_ERRORS_H

#ifdef __cplusplus
extern "C" {
#endif

/* A static string for a PM_E* code; for PM_EIO the text of the current errno. */
const char *render_strerror(int code);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_ERRORS_H */
