/* checkpoint.c: writing and reading render checkpoints; see checkpoint.h.
 *
 * Values are written byte by byte in little-endian order (doubles by their IEEE bits), so a
 * file means the same on any host and the state read back is bit-identical to the one
 * written. The checksum is computed while writing and while reading, over the same bytes.
 */
#include "run/checkpoint.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "common.h"
#include "base/hash.h"
#include "base/output.h"
#include "load/photon_settings.h"
#include "base/stats.h"

#define MAGIC "PMRCKPT\n"
/* PIXEL_BYTES: version 1 (a render state: 3 sums, a count); PASS_PIXEL_BYTES: versions 2 and 3
 * (a render in passes: 3 sums of pass images, 3 of their squares; then version 3's multipliers). */
enum { HEADER_BYTES = 56, PIXEL_BYTES = 28, PASS_PIXEL_BYTES = 48, MAX_SIDE = 1 << 14, MAX_SPP = 1 << 20,
       MAX_PASSES = 1 << 30 };

static pass_state *g_ps; /* ckpt_set_passes: a render in passes, and its state */
static double g_adapt;

void ckpt_set_passes(pass_state *ps, double adapt) {
    g_ps = ps;
    g_adapt = adapt;
}

/* ---- writing ------------------------------------------------------------------------------ */

typedef struct wr {
    FILE *fp;
    uint64_t h;
    int ok;
} wr;

static void put(wr *w, const void *p, size_t n) {
    w->h = hash_fnv1a(w->h, p, n);
    if (w->ok && fwrite(p, 1, n, w->fp) != n) w->ok = 0;
}
static void le32(unsigned char *b, uint32_t v) {
    for (int i = 0; i < 4; i++) b[i] = (unsigned char)(v >> (8 * i));
}
static void le64(unsigned char *b, uint64_t v) {
    for (int i = 0; i < 8; i++) b[i] = (unsigned char)(v >> (8 * i));
}
static uint32_t get32(const unsigned char *b) {
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}
static uint64_t get64(const unsigned char *b) { return (uint64_t)get32(b) | (uint64_t)get32(b + 4) << 32; }

/* Version 1 from st, or version 3 from ps (spp: the samples of each pass). */
static int write_any(const char *path, const ckpt_info *ci, const render_state *st,
                     const pass_state *ps, int spp, char *err, size_t errcap) {
    out_file o;
    int rc = out_open(&o, path, err, errcap);
    if (rc < 0) return rc;
    wr w = {o.fp, HASH_FNV_INIT, 1};
    size_t ls = strlen(ci->settings), lp = strlen(ci->photons);
    int width = ps ? ps->width : st->width, height = ps ? ps->height : st->height;
    unsigned char hd[HEADER_BYTES];
    memcpy(hd, MAGIC, 8);
    le32(hd + 8, ps ? 3u : 1u);
    le32(hd + 12, (uint32_t)width);
    le32(hd + 16, (uint32_t)height);
    le32(hd + 20, (uint32_t)(ps ? spp : st->spp));
    le64(hd + 24, ci->scene_hash);
    le64(hd + 32, ci->photon_hash);
    le32(hd + 40, (uint32_t)ls);
    le32(hd + 44, (uint32_t)ci->args_len);
    le32(hd + 48, (uint32_t)lp);
    le32(hd + 52, ps ? (uint32_t)ps->done : 0u);
    put(&w, hd, sizeof hd);
    put(&w, ci->settings, ls);
    put(&w, ci->args, ci->args_len);
    put(&w, ci->photons, lp);
    size_t n = (size_t)width * (size_t)height;
    size_t pb = ps ? PASS_PIXEL_BYTES : PIXEL_BYTES;
    unsigned char px[PASS_PIXEL_BYTES * 256];
    for (size_t i = 0; i < n && w.ok;) {
        size_t m = 0;
        for (; m < 256 && i < n; m++, i++) {
            for (int c = 0; c < (ps ? 6 : 3); c++) {
                uint64_t u;
                const double *src = ps ? (c < 3 ? ps->sum : ps->sum2) : st->sum;
                memcpy(&u, &src[3 * i + (size_t)(c % 3)], 8);
                le64(px + pb * m + 8 * (size_t)c, u);
            }
            if (!ps) le32(px + pb * m + 24, st->count[i]);
        }
        put(&w, px, pb * m);
    }
    for (size_t i = 0; ps && i < n; i += sizeof px) { /* version 3: the multipliers (0: undecided) */
        size_t m = n - i < sizeof px ? n - i : sizeof px;
        for (size_t j = 0; j < m; j++) px[j] = ps->mult ? ps->mult[i + j] : 0;
        put(&w, px, m);
    }
    unsigned char tail[8];
    le64(tail, w.h);
    put(&w, tail, 8);
    if (!w.ok) {
        snprintf(err, errcap, "%s: cannot write: %s", path, strerror(errno));
        out_abort(&o);
        return PM_EIO;
    }
    out_file *list[1] = {&o};
    return out_commit(list, 1, err, errcap);
}

int ckpt_write(const char *path, const ckpt_info *ci, const render_state *st, char *err,
               size_t errcap) {
    return write_any(path, ci, st, NULL, 0, err, errcap);
}

int ckpt_write_passes(const char *path, const ckpt_info *ci, const pass_state *ps, int spp, char *err,
                      size_t errcap) {
    return write_any(path, ci, NULL, ps, spp, err, errcap);
}

/* ---- reading ------------------------------------------------------------------------------ */

static int fail(char *err, size_t errcap, int code, const char *path, const char *msg) {
    snprintf(err, errcap, "%s: %s", path, msg);
    return code;
}

/* Read n bytes into p, hashing them. 0 or -1. */
static int get(FILE *f, void *p, size_t n, uint64_t *h) {
    if (fread(p, 1, n, f) != n) return -1;
    *h = hash_fnv1a(*h, p, n);
    return 0;
}

/* Pixels i0 .. i0 + m - 1 from their bytes px into st or ps (either may be NULL); 1 when a
 * count is above spp (version 1). */
static int decode_pixels(const unsigned char *px, size_t m, size_t i0, uint32_t version, uint32_t spp,
                         render_state *st, pass_state *ps) {
    size_t pb = version != 1 ? PASS_PIXEL_BYTES : PIXEL_BYTES;
    int over = 0;
    for (size_t j = 0, i = i0; j < m; j++, i++) {
        for (int c = 0; version != 1 && ps && c < 6; c++) {
            uint64_t u = get64(px + pb * j + 8 * (size_t)c);
            memcpy(&(c < 3 ? ps->sum : ps->sum2)[3 * i + (size_t)(c % 3)], &u, 8);
        }
        if (version != 1) continue;
        uint32_t cnt = get32(px + pb * j + 24);
        over |= cnt > spp;
        for (int c = 0; st && c < 3; c++) {
            uint64_t u = get64(px + pb * j + 8 * (size_t)c);
            memcpy(&st->sum[3 * i + (size_t)c], &u, 8);
        }
        if (st) st->count[i] = cnt;
    }
    return over;
}

static int read_any(const char *path, ckpt_info *ci, render_state *st, pass_state *ps, char *err,
                    size_t errcap) {
    memset(ci, 0, sizeof *ci);
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, errcap, "%s: %s", path, strerror(errno));
        return PM_EIO;
    }
    struct stat sb;
    unsigned char hd[HEADER_BYTES];
    uint64_t h = HASH_FNV_INIT;
    int rc = PM_EFORMAT;
    char msg[256];
    if (fstat(fileno(f), &sb) != 0 || !S_ISREG(sb.st_mode)) {
        rc = fail(err, errcap, PM_EFORMAT, path, "not a regular file; a checkpoint is read from a file");
        goto out;
    }
    if (get(f, hd, sizeof hd, &h) != 0 || memcmp(hd, MAGIC, 8) != 0) {
        rc = fail(err, errcap, PM_EFORMAT, path, "not a render checkpoint (or truncated in its header)");
        goto out;
    }
    uint32_t version = get32(hd + 8), w = get32(hd + 12), ht = get32(hd + 16), spp = get32(hd + 20);
    uint32_t ls = get32(hd + 40), la = get32(hd + 44), lp = get32(hd + 48);
    if (version < 1 || version > CKPT_VERSION) {
        snprintf(msg, sizeof msg, "checkpoint format version %u; this renderer reads versions 1 "
                 "to %u", version, CKPT_VERSION);
        rc = fail(err, errcap, PM_EVERSION, path, msg);
        goto out;
    }
    uint32_t npass = get32(hd + 52);
    if (w < 1 || w > MAX_SIDE || ht < 1 || ht > MAX_SIDE || spp < 1 || spp > MAX_SPP ||
        ls >= sizeof ci->settings || la > sizeof ci->args || lp >= sizeof ci->photons ||
        (version == 1 && npass != 0) || npass > MAX_PASSES) {
        rc = fail(err, errcap, PM_EFORMAT, path, "corrupt header (a size out of range)");
        goto out;
    }
    ci->version = version, ci->passes = npass, ci->spp = spp;
    /* A state of the other kind than the caller's render is refused before it is read. */
    if ((st && version != 1) || (ps && version == 1)) {
        rc = fail(err, errcap, PM_EINVAL, path,
                  version != 1 ? "a checkpoint of a render in passes (--time, --passes, render.time); "
                                 "this render is one pass of fixed work"
                               : "a checkpoint of one pass of fixed work (--spp); this render is in "
                                 "passes (--time, --passes, render.time)");
        goto out;
    }
    size_t pb = version != 1 ? PASS_PIXEL_BYTES : PIXEL_BYTES;
    uint64_t want = (uint64_t)HEADER_BYTES + ls + la + lp + (uint64_t)w * ht * (pb + (version == 3)) + 8;
    if ((uint64_t)sb.st_size != want) {
        snprintf(msg, sizeof msg, "%s: %lld bytes, but its header says %llu",
                 (uint64_t)sb.st_size < want ? "truncated" : "has extra data", (long long)sb.st_size,
                 (unsigned long long)want);
        rc = fail(err, errcap, PM_EFORMAT, path, msg);
        goto out;
    }
    if (get(f, ci->settings, ls, &h) != 0 || get(f, ci->args, la, &h) != 0 ||
        get(f, ci->photons, lp, &h) != 0) {
        rc = fail(err, errcap, PM_EFORMAT, path, "truncated");
        goto out;
    }
    ci->args_len = la;
    if (la > 0 && ci->args[la - 1] != 0) {
        rc = fail(err, errcap, PM_EFORMAT, path, "corrupt argument list");
        goto out;
    }
    ci->scene_hash = get64(hd + 24);
    ci->photon_hash = get64(hd + 32);
    /* Without st the pixels are read only to check the checksum: the arguments replayed from
     * a file whose bytes changed are never used (a flipped byte there once came back as an
     * unknown --pm key of the user's). */
    if (st && render_state_init(st, (int)w, (int)ht, (int)spp) < 0) {
        rc = fail(err, errcap, PM_ENOMEM, path, "out of memory");
        goto out;
    }
    if (ps && pass_state_init(ps, (int)w, (int)ht) < 0) {
        rc = fail(err, errcap, PM_ENOMEM, path, "out of memory");
        goto out;
    }
    if (ps) ps->done = (int)npass;
    size_t n = (size_t)w * ht;
    unsigned char px[PASS_PIXEL_BYTES * 256];
    int over_spp = 0;
    rc = 0;
    for (size_t i = 0; i < n && rc == 0;) {
        size_t m = n - i < 256 ? n - i : 256;
        if (get(f, px, pb * m, &h) != 0) {
            rc = fail(err, errcap, PM_EFORMAT, path, "truncated");
            break;
        }
        over_spp |= decode_pixels(px, m, i, version, spp, st, ps);
        i += m;
    }
    unsigned char *mb = NULL; /* version 3's multipliers */
    if (rc == 0 && version == 3 && (!(mb = malloc(n)) || get(f, mb, n, &h) != 0))
        rc = fail(err, errcap, mb ? PM_EFORMAT : PM_ENOMEM, path, mb ? "truncated" : "out of memory");
    unsigned char tail[8];
    uint64_t body = h;
    if (rc == 0 && (fread(tail, 1, 8, f) != 8 || get64(tail) != body))
        rc = fail(err, errcap, PM_EFORMAT, path, "corrupt (checksum mismatch)");
    if (rc == 0 && over_spp)
        rc = fail(err, errcap, PM_EFORMAT, path, "corrupt (a pixel has more samples than spp)");
    if (rc == 0 && mb && !pass_mult_valid(mb, n)) rc = fail(err, errcap, PM_EFORMAT, path, "corrupt (sample multipliers)");
    if (rc == 0 && ps && mb && mb[0]) ps->mult = mb, mb = NULL;
    free(mb);
    if (rc < 0 && st) render_state_free(st);
    if (rc < 0 && ps) pass_state_free(ps);
out:
    fclose(f);
    return rc;
}

int ckpt_read(const char *path, ckpt_info *ci, render_state *st, char *err, size_t errcap) {
    return read_any(path, ci, st, NULL, err, errcap);
}

int ckpt_read_passes(const char *path, ckpt_info *ci, pass_state *ps, char *err, size_t errcap) {
    return read_any(path, ci, NULL, ps, err, errcap);
}

/* ---- around a checkpointed render ----------------------------------------------------------- */

static int g_writer = 1, g_retrace;
static char g_extra[256];

static char g_resume_cmd[128] = "render";

void ckpt_set_resume_command(const char *cmd) {
    snprintf(g_resume_cmd, sizeof g_resume_cmd, "%s", cmd ? cmd : "render");
}

const char *ckpt_resume_command(void) { return g_resume_cmd; }

void ckpt_set_distributed(int writer, const char *extra, int retrace) {
    g_writer = writer != 0;
    snprintf(g_extra, sizeof g_extra, "%s", extra ? extra : "");
    g_retrace = retrace != 0;
}

void ckpt_settings_text(const scene *s, const char *mode, char *buf, size_t cap) {
    char *pm = NULL;
    if (s->photon_mapping) {
        cJSON *copy = cJSON_Duplicate(s->photon_mapping, 1);
        if (copy) {
            cJSON_DeleteItemFromObjectCaseSensitive(copy, "save_photons");
            cJSON_DeleteItemFromObjectCaseSensitive(copy, "load_photons");
            cJSON_DeleteItemFromObjectCaseSensitive(copy, "progress");
            pm = cJSON_PrintUnformatted(copy);
            cJSON_Delete(copy);
        }
    }
    char adapt[48] = "";
    if (g_ps) snprintf(adapt, sizeof adapt, "; adaptive samples %g", g_adapt);
    snprintf(buf, cap, "renderer %s; mode %s; %dx%d; %s %d; seed %llu%s; photon_mapping %s%s",
             PM_VERSION_STRING, mode, s->cam.width, s->cam.height, g_ps ? "in passes of spp" : "spp",
             s->cam.spp, (unsigned long long)s->settings.seed, adapt, pm ? pm : "{}", g_extra);
    free(pm);
}

int ckpt_store_args(ckpt_info *ci, int argc, char **argv, const char *scene_path) {
    size_t n = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (a == scene_path) continue;
        if (strcmp(a, "--quiet") == 0 || strcmp(a, "-q") == 0) continue;
        if ((strcmp(a, "--resume") == 0 || strcmp(a, "--threads") == 0) && i + 1 < argc) {
            i++;
            continue;
        }
        size_t len = strlen(a) + 1;
        if (n + len > sizeof ci->args) return PM_EINVAL;
        memcpy(ci->args + n, a, len);
        n += len;
    }
    ci->args_len = n;
    return 0;
}

int ckpt_replay_args(int argc, char **argv, int *nargc, char ***nargv, char **store, char *err,
                     size_t errcap) {
    *nargv = NULL;
    *store = NULL;
    const char *file = NULL;
    for (int i = 1; i + 1 < argc; i++)
        if (strcmp(argv[i], "--resume") == 0) file = argv[i + 1];
    if (!file) return 0;
    ckpt_info *ci = malloc(sizeof *ci);
    if (!ci) return PM_ENOMEM;
    int rc = ckpt_read(file, ci, NULL, err, errcap);
    if (rc < 0) {
        free(ci);
        return rc;
    }
    int nstored = 0;
    for (size_t k = 0; k < ci->args_len; k++) nstored += ci->args[k] == 0;
    char **v = malloc((size_t)(argc + nstored + 1) * sizeof *v);
    char *copy = malloc(ci->args_len + 1);
    if (!v || !copy) {
        free(v);
        free(copy);
        free(ci);
        return PM_ENOMEM;
    }
    memcpy(copy, ci->args, ci->args_len);
    int m = 0;
    v[m++] = argv[0];
    for (size_t k = 0; k < ci->args_len; k += strlen(copy + k) + 1) v[m++] = copy + k;
    for (int i = 1; i < argc; i++) v[m++] = argv[i];
    v[m] = NULL;
    free(ci);
    *nargc = m;
    *nargv = v;
    *store = copy;
    return 0;
}

int ckpt_photon_hash(const char *dir, uint64_t *h, char *err, size_t errcap) {
    static const char *names[3] = {"global.pmap", "caustic.pmap", "shadow.pmap"};
    *h = HASH_FNV_INIT;
    char path[OUT_PATH_MAX], name[64];
    for (int k = 0; k < 3; k++) {
        snprintf(path, sizeof path, "%s/%s", dir, names[k]);
        *h = hash_fnv1a(*h, names[k], strlen(names[k]) + 1);
        if (access(path, F_OK) != 0) continue;
        int rc = hash_file(path, UINT64_MAX, h, err, errcap);
        if (rc < 0) return rc;
    }
    /* A scene with media: the volume maps of media 0, 1, ... (photon_maps.h), up to the
     * first medium that has neither. */
    for (int m = 0;; m++) {
        int any = 0;
        for (int k = 0; k < 2; k++) {
            snprintf(name, sizeof name, "%s-%d.pmap", k ? "volume_caustic" : "volume", m);
            snprintf(path, sizeof path, "%s/%s", dir, name);
            if (access(path, F_OK) != 0) continue;
            any = 1;
            *h = hash_fnv1a(*h, name, strlen(name) + 1);
            int rc = hash_file(path, UINT64_MAX, h, err, errcap);
            if (rc < 0) return rc;
        }
        if (!any) break;
    }
    return 0;
}

void ckpt_session_start(ckpt_session *cs) {
    double now = stats_now();
    cs->next_ckpt = cs->ckpt_path && cs->ckpt_every > 0 ? now + cs->ckpt_every : INFINITY;
    cs->next_snap = cs->snap_path && cs->snap_every > 0 ? now + cs->snap_every : INFINITY;
}

double ckpt_session_period(const ckpt_session *cs) {
    double p = 0;
    if (cs->ckpt_path && cs->ckpt_every > 0) p = cs->ckpt_every;
    if (cs->snap_path && cs->snap_every > 0 && (p == 0 || cs->snap_every < p)) p = cs->snap_every;
    return p;
}

/* The periodic snapshot of ckpt_session_pause (st) or ckpt_session_pass (ps), when one is due:
 * the image so far as a PNG at cs->snap_path. 0, or a negative code with cs->err set. */
static int session_snapshot(ckpt_session *cs, int why, double now, const render_state *st, const pass_state *ps) {
    if (!cs->snap_path || why != RENDER_PAUSE_PERIODIC || now < cs->next_snap) return 0;
    film f;
    if (film_init(&f, st ? st->width : ps->width, st ? st->height : ps->height) < 0) return PM_ENOMEM;
    if (st)
        render_state_to_film(st, &f);
    else
        pass_state_to_film(ps, &f);
    int rc = film_write_png(&f, cs->snap_path, cs->tone, cs->exposure, cs->clip_percent, NULL);
    int saved = errno;
    film_free(&f);
    if (rc < 0) {
        snprintf(cs->err, sizeof cs->err, "%s: cannot write the snapshot: %s", cs->snap_path, strerror(saved));
        return rc;
    }
    cs->next_snap = stats_now() + cs->snap_every;
    return 0;
}

int ckpt_session_pause(void *user, const render_state *st, int why) {
    ckpt_session *cs = user;
    if (!g_writer) return 0;
    double now = stats_now();
    if (cs->ckpt_path && (why == RENDER_PAUSE_SIGNAL || now >= cs->next_ckpt)) {
        int rc = ckpt_write(cs->ckpt_path, &cs->info, st, cs->err, sizeof cs->err);
        if (rc < 0) return rc;
        if (!cs->quiet)
            fprintf(stderr, "render: checkpoint %s (%.1f%% of the samples)\n", cs->ckpt_path,
                    100.0 * (double)render_state_done(st) / ((double)st->width * st->height * st->spp));
        cs->next_ckpt = stats_now() + cs->ckpt_every;
    }
    return session_snapshot(cs, why, now, st, NULL);
}

int ckpt_session_pass(void *user, const pass_state *ps, int why) {
    ckpt_session *cs = user;
    if (!g_writer) return 0;
    double now = stats_now();
    if (cs->ckpt_path && (why == RENDER_PAUSE_SIGNAL || now >= cs->next_ckpt)) {
        int rc = ckpt_write_passes(cs->ckpt_path, &cs->info, ps, cs->pass_spp, cs->err, sizeof cs->err);
        if (rc < 0) return rc;
        if (!cs->quiet)
            fprintf(stderr, "render: checkpoint %s (%d pass%s)\n", cs->ckpt_path, ps->done,
                    ps->done == 1 ? "" : "es");
        cs->next_ckpt = stats_now() + cs->ckpt_every;
    }
    return session_snapshot(cs, why, now, NULL, ps);
}

static const char *pm_dir_key(const scene *s, const char *key) {
    const cJSON *v = s->photon_mapping ? cJSON_GetObjectItemCaseSensitive(s->photon_mapping, key) : NULL;
    return cJSON_IsString(v) && v->valuestring[0] ? v->valuestring : NULL;
}

int checkpoint_setup(scene *s, const char *scene_path, int argc, char **argv, const char *ckpt_path,
                     const char *resume, int uses_photons, ckpt_session *cs, render_state *st) {
    char err[1024], msg[600];
    ckpt_info *ci = &cs->info;
    memset(ci, 0, sizeof *ci);
    const char *load = uses_photons ? pm_dir_key(s, "load_photons") : NULL;
    const char *save = uses_photons ? pm_dir_key(s, "save_photons") : NULL;
    /* A mode without photons reads and writes no maps: say so rather than ignore the request. */
    for (int k = 0; !uses_photons && k < 2; k++) {
        const char *key = k ? "save_photons" : "load_photons", *dir = pm_dir_key(s, key);
        if (dir)
            fprintf(stderr, "render: %s: warning: mode %s traces no photons: %s %s (photon_mapping.%s) "
                    "is not used\n", scene_path, s->settings.mode, k ? "--save-photons" : "--load-photons",
                    dir, key);
    }
    /* Maps that cannot be saved whole (ckpt_set_distributed's retrace) are traced again by a
     * resumed render: the checkpoint names none. */
    /* A render in passes keeps no maps: each pass traces its own from its seed. */
    if (ckpt_path && uses_photons && !resume && !g_retrace && !g_ps) {
        if (load) {
            snprintf(ci->photons, sizeof ci->photons, "%s", load);
        } else {
            if (!save) {
                snprintf(ci->photons, sizeof ci->photons, "%s.photons", ckpt_path);
                if (g_writer && photon_settings_cli_set(&s->photon_mapping, "--save-photons", ci->photons, msg,
                                         sizeof msg) < 0) {
                    fprintf(stderr, "render: %s\n", msg);
                    return 2;
                }
                save = g_writer ? pm_dir_key(s, "save_photons") : NULL;
            } else {
                snprintf(ci->photons, sizeof ci->photons, "%s", save);
            }
        }
    }
    if (save && !resume && out_check_dir(save, msg, sizeof msg) < 0) {
        fprintf(stderr, "render: %s: save_photons (--save-photons DIR or photon_mapping.save_photons): "
                "%s\n", scene_path, msg);
        return 2;
    }
    /* pm_map_save replaces regular files only (a FIFO, device or symlink there is refused):
     * say so now rather than after the photon pass. */
    static const char *names[3] = {"global.pmap", "caustic.pmap", "shadow.pmap"};
    for (int k = 0; save && !resume && k < 3; k++) {
        char path[OUT_PATH_MAX];
        struct stat sb;
        snprintf(path, sizeof path, "%s/%s", save, names[k]);
        if (lstat(path, &sb) == 0 && !S_ISREG(sb.st_mode)) {
            fprintf(stderr, "render: %s: save_photons: %s is not a regular file; photon maps replace "
                    "only regular files\n", scene_path, path);
            return 2;
        }
    }
    ckpt_settings_text(s, s->settings.mode, ci->settings, sizeof ci->settings);
    err[0] = 0;
    ci->scene_hash = HASH_FNV_INIT;
    if (hash_file(scene_path, UINT64_MAX, &ci->scene_hash, err, sizeof err) < 0 ||
        ckpt_store_args(ci, argc, argv, scene_path) < 0) {
        fprintf(stderr, "render: %s\n", err[0] ? err : "too many arguments to keep in a checkpoint");
        return 2;
    }
    if (!resume) return 0;
    ckpt_info *old = malloc(sizeof *old);
    if (!old) return 1;
    int rc = g_ps ? ckpt_read_passes(resume, old, g_ps, err, sizeof err) : ckpt_read(resume, old, st, err, sizeof err);
    if (rc < 0) {
        fprintf(stderr, "render: --resume %s\n", err);
        free(old);
        return 2;
    }
    int status = 0;
    if (old->scene_hash != ci->scene_hash) {
        fprintf(stderr, "render: --resume %s: the checkpoint is of another scene (or %s changed since)\n",
                resume, scene_path);
        status = 2;
    } else if (strcmp(old->settings, ci->settings) != 0) {
        fprintf(stderr, "render: --resume %s: the checkpoint has other settings\n  checkpoint: %s\n"
                "  this run:   %s\n", resume, old->settings, ci->settings);
        status = 2;
    } else if (uses_photons && !g_retrace && !g_ps) {
        uint64_t h;
        if (!old->photons[0] || ckpt_photon_hash(old->photons, &h, err, sizeof err) < 0 ||
            h != old->photon_hash) {
            fprintf(stderr, "render: --resume %s: the photon maps in %s are missing or changed since "
                    "the checkpoint\n", resume, old->photons[0] ? old->photons : "(none)");
            status = 2;
        } else if (photon_settings_cli_set(&s->photon_mapping, "--load-photons", old->photons, msg,
                                        sizeof msg) < 0) {
            fprintf(stderr, "render: %s\n", msg);
            status = 2;
        }
        snprintf(ci->photons, sizeof ci->photons, "%s", old->photons);
        ci->photon_hash = old->photon_hash;
    }
    free(old);
    if (status) {
        render_state_free(st);
        if (g_ps) pass_state_free(g_ps);
    }
    return status;
}

int checkpoint_begin(ckpt_session *cs, int uses_photons, render_state *st) {
    char err[1024];
    int fresh = g_ps ? g_ps->done == 0 : render_state_done(st) == 0;
    if (!g_writer) { /* another process writes (ckpt_set_distributed) */
        ckpt_session_start(cs);
        return 0;
    }
    if (cs->ckpt_path && uses_photons && fresh && cs->info.photons[0] &&
        ckpt_photon_hash(cs->info.photons, &cs->info.photon_hash, err, sizeof err) < 0) {
        fprintf(stderr, "render: photon maps: %s\n", err);
        return 1;
    }
    if (cs->ckpt_path && fresh &&
        (g_ps ? ckpt_write_passes(cs->ckpt_path, &cs->info, g_ps, cs->pass_spp, err, sizeof err)
              : ckpt_write(cs->ckpt_path, &cs->info, st, err, sizeof err)) < 0) {
        fprintf(stderr, "render: --checkpoint %s\n", err);
        return 1;
    }
    ckpt_session_start(cs);
    return 0;
}
