/* checkpoint.h: the render-state file that `render --checkpoint FILE` writes and
 * `render SCENE --resume FILE` continues from.
 *
 * A checkpoint holds what a resumed render needs to finish with the image an uninterrupted
 * render would have given, bit for bit, and what it needs to refuse a mismatch:
 *   - a format version (CKPT_VERSION): a file of another version is refused;
 *   - the image size and samples per pixel;
 *   - the scene hash: 64-bit FNV-1a of the scene file's bytes (another scene, or the same file
 *     edited, is refused);
 *   - the settings text: every setting that changes the image (mode, size, samples, seed,
 *     photon-mapping settings, the renderer's version), as the program prints them; a resumed
 *     run must arrive at the same text;
 *   - the command-line arguments to replay on resume (so `render SCENE --resume FILE` needs
 *     nothing else), each NUL-terminated;
 *   - the photon maps' directory ("" in path mode) and the hash of the map files in it;
 *   - per pixel the render state (renderer.h): the sum of its samples (three doubles) and the
 *     sample count;
 *   - a trailing 64-bit FNV-1a checksum of everything before it.
 * Layout, all integers and doubles little-endian: "PMRCKPT\n", u32 version, u32 width,
 * u32 height, u32 spp, u64 scene hash, u64 photon hash, u32 lengths of the settings, the
 * arguments and the photon directory, u32 0; those bytes; width * height pixels of
 * (3 x f64 sum, u32 count), rows top to bottom; u64 checksum.
 *
 * VERSIONS. Version 1 (above) is the state of one pass of fixed work (--spp). Version 2 is a
 * render in passes (run/passes.h; --time, --passes, render.time): the same layout but spp is
 * the samples of each pass, the last header u32 is the number of passes done, each pixel is
 * (3 x f64 sum of the pass images, 3 x f64 sum of their squares), and no photon maps are kept
 * (photon directory "", hash 0: each pass traces its maps from its own seed, so a resumed
 * render needs none). A checkpoint is written at pass boundaries only (periodically, at the
 * end, and at a signal, which drops the pass being rendered), so resuming is bit-identical
 * to the uninterrupted render with the same passes; resuming with a larger --passes or
 * --time continues the render. Version 3 (written since the adaptive samples, passes.h) is
 * version 2 followed by one byte per pixel, rows top to bottom: the pixel's sample
 * multiplier, or 0 at every pixel while none is decided; a version 2 file reads as
 * undecided. All three versions are read; each kind of render refuses the other's (with a
 * message that says which is which), and an older renderer refuses newer files by their
 * version.
 *
 * ckpt_read checks the size the header implies against the file's size before it allocates
 * anything, so a truncated (or padded) file is refused at once with a message, as are a
 * count above spp, a multiplier above ADAPT_MAX (or some 0 and some not) and a checksum mismatch. It reads regular files only.
 * ckpt_write goes through output.h: the file is replaced atomically (or written through a
 * FIFO or device), and SIGINT/SIGTERM during the write leave the previous checkpoint.
 *
 * Errors: PM_EIO (errno kept), PM_EFORMAT, PM_EVERSION, PM_ENOMEM, with a message in err that
 * names the file. The caller owns the info and the state (render_state_free).
 */
#ifndef RENDER_CHECKPOINT_H
#define RENDER_CHECKPOINT_H

#include <stddef.h>
#include <stdint.h>

#include "run/passes.h"
#include "run/renderer.h"
#include "scene/scene.h"

#ifdef __cplusplus
extern "C" {
#endif

#define CKPT_VERSION 3u

typedef struct ckpt_info {
    uint32_t version, passes; /* set by the readers: the file's version; passes done (version 2) */
    uint32_t spp;             /* set by the readers: samples per pixel (version 2: of each pass) */
    uint64_t scene_hash, photon_hash;
    char settings[4096];
    char args[8192]; /* NUL-terminated arguments, one after another */
    size_t args_len; /* bytes used in args, the NULs included */
    char photons[1024];
} ckpt_info;

int ckpt_write(const char *path, const ckpt_info *ci, const render_state *st, char *err,
               size_t errcap);
/* st == NULL reads the header and strings (for the arguments to replay) and checks the whole
 * file's checksum without keeping the pixels; else st gets a new state (render_state_free
 * it). A file whose checksum does not match is refused either way (PM_EFORMAT). */
int ckpt_read(const char *path, ckpt_info *ci, render_state *st, char *err, size_t errcap);
/* Version 2 (a render in passes; spp: each pass's samples) and its reader (ps: a new state,
 * pass_state_free it; a version 1 file is refused with a message). */
int ckpt_write_passes(const char *path, const ckpt_info *ci, const pass_state *ps, int spp, char *err,
                      size_t errcap);
int ckpt_read_passes(const char *path, ckpt_info *ci, pass_state *ps, char *err, size_t errcap);
/* A render in passes: before checkpoint_setup, main.c gives the state that a resume fills and
 * that checkpoint_begin writes (settings text, VERSIONS), and the adaptive samples' share
 * (passes.h; part of the settings text). NULL (the default): one pass. */
void ckpt_set_passes(pass_state *ps, double adapt);

/* ---- a distributed render (render/mpi/) ---------------------------------------------------
 *
 * Every process of a distributed render runs main.c, so every process sets up the checkpoint
 * session (it replays the arguments and checks the scene, the settings and the maps just as
 * one process does); ckpt_set_distributed, called on every process before checkpoint_setup,
 * says which one writes:
 *   - writer 1 (rank 0): writes the checkpoints, the snapshots and the photon maps a
 *     checkpoint keeps; writer 0: writes none of them (checkpoint_setup does not ask for the
 *     maps to be saved, checkpoint_begin writes nothing, ckpt_session_pause does nothing);
 *   - extra: appended to the settings text. "" for a render whose image is render's, bit for
 *     bit: then its checkpoints are render's, and either program resumes the other's. A
 *     render whose image depends on how it is distributed names that here, so that a resume
 *     under another distribution is refused as "other settings";
 *   - retrace 1: the photon maps cannot be saved whole (no process holds them): a checkpoint
 *     keeps no maps, and a resumed render traces them again (deterministic for the same
 *     extra text).
 * The default (never called) is one process: writer 1, "", retrace 0. */
void ckpt_set_distributed(int writer, const char *extra, int retrace);

/* The command that continues an interrupted render, for the message that names it: "render"
 * by default (a replicated render-mpi checkpoint is render's, so render resumes it); a render
 * whose checkpoint only the same distribution resumes sets its own (render-mpi partitioned:
 * "mpirun -np R render-mpi"). The text is copied; NULL restores the default. */
void ckpt_set_resume_command(const char *cmd);
const char *ckpt_resume_command(void);

/* ---- what main.c needs around a checkpointed render ---------------------------------------
 *
 * Settings text: "renderer VERSION; mode M; WxH; spp N; seed S; photon_mapping {json}" with
 * the photon_mapping object as the run applies it, less the keys that do not change the image
 * (save_photons, load_photons, progress), then ckpt_set_distributed's extra text. Tone and
 * exposure only change the PNG, so a resumed run may change them. */
void ckpt_settings_text(const scene *s, const char *mode, char *buf, size_t cap);

/* The arguments a resumed run replays: argv[1..] less the scene path, --resume FILE,
 * --threads N and --quiet (which may differ between runs). PM_EINVAL if they do not fit. */
int ckpt_store_args(ckpt_info *ci, int argc, char **argv, const char *scene_path);
/* If argv holds "--resume FILE": *nargv = argv[0], the checkpoint's stored arguments, then
 * argv[1..] (so options given now win), *nargc its length; the caller frees *nargv (the
 * strings point into *store, which the caller keeps and frees too). Else *nargv = NULL.
 * 0, or a negative code with a message (the checkpoint cannot be read). */
int ckpt_replay_args(int argc, char **argv, int *nargc, char ***nargv, char **store, char *err,
                     size_t errcap);

/* The hash of the photon-map files in dir (global, caustic, shadow; absent ones count as
 * absent; then the volume maps volume-M.pmap and volume_caustic-M.pmap of M = 0, 1, ... up to
 * the first M with neither). 0 or PM_EIO with a message. */
int ckpt_photon_hash(const char *dir, uint64_t *h, char *err, size_t errcap);

/* Periodic checkpoints and snapshots during a render: a render_pause_fn (renderer.h) with
 * this session as its user pointer. On a signal pause it writes the checkpoint only. */
typedef struct ckpt_session {
    const char *ckpt_path; /* NULL: no checkpoints */
    double ckpt_every;     /* seconds */
    const char *snap_path; /* NULL: no snapshots (the -o PNG) */
    double snap_every;
    int tone;
    double exposure, clip_percent;
    int quiet;
    ckpt_info info;
    int pass_spp;                /* a render in passes: each pass's samples per pixel */
    double next_ckpt, next_snap; /* stats_now() times; set by ckpt_session_start */
    char err[512];               /* why the last write failed */
} ckpt_session;

void ckpt_session_start(ckpt_session *cs);

/* main.c's steps, so that the program stays a list of steps:
 * checkpoint_setup, before the integrator is created: checks the photon-map directory that
 * will be written (exists or can be created, writable) before any photon is traced; with
 * --checkpoint in a photon mode, makes the maps be saved (to FILE.photons unless
 * --save-photons or --load-photons names a directory); fills cs->info (scene hash,
 * settings, arguments); with --resume, reads the checkpoint into *st and refuses another
 * scene, other settings, changed photon maps, or a damaged file, then points the photon
 * settings at the checkpoint's maps. 0, or the exit status (2) after printing why.
 * checkpoint_begin, after preprocessing: hashes the photon maps and, for a fresh render,
 * writes the first checkpoint (so a kill before the first period still resumes without
 * tracing again); starts the session's clocks. 0, or the exit status (1) after printing why. */
int checkpoint_setup(scene *s, const char *scene_path, int argc, char **argv, const char *ckpt_path,
                     const char *resume, int uses_photons, ckpt_session *cs, render_state *st);
int checkpoint_begin(ckpt_session *cs, int uses_photons, render_state *st);
/* The shorter of the two periods, 0 if neither is set: the render's pause_every. */
double ckpt_session_period(const ckpt_session *cs);
int ckpt_session_pause(void *user, const render_state *st, int why);
/* The same for a render in passes: a passes.h pass_fn (called at pass boundaries). */
int ckpt_session_pass(void *user, const pass_state *ps, int why);

#ifdef __cplusplus
}
#endif
#endif /* RENDER_CHECKPOINT_H */
