/* photon_maps.c: the photon maps as data: freeing, saving and loading them (photonmap/'s
 * map files), their kd-trees, and the radius policy of their estimates; see photon_maps.h.
 */
#include "photons/photon_maps.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "photonmap/common.h"
#include "photonmap/estimate.h"
#include "base/hash.h"
#include "scene/material.h"
#include "base/output.h"
#include "scene/scene_hash.h"

/* Member by member: the maps' own arrays (guide.c and scene.c free other structs alike). */
void photon_maps_free(photon_maps *m) {
    free(m->global);
    free(m->global_path);
    free(m->caustic);
    free(m->shadow);
    free(m->volume);
    free(m->volume_caustic);
    free(m->volume_medium);
    free(m->volume_caustic_medium);
    memset(m, 0, sizeof *m);
}

#define HASH48 0xFFFFFFFFFFFFull
/* tag[1] = the version in bits 48-63, the hash in bits 0-47 (photon_maps.h MAP FILES). */
static uint64_t with_version(uint64_t h) { return (uint64_t)PHOTON_TRACE_VERSION << 48 | (h & HASH48); }

static const char *kind_name(uint32_t kind) {
    static const char *const names[] = {"?", "global", "caustic", "shadow", "other", "volume"};
    return kind <= PM_MAP_VOLUME ? names[kind] : "?";
}

void map_stamp_make(const scene *s, const photon_settings *cfg, int global_on, int caustic_on,
                    int shadow_on, map_stamp *st) {
    st->scene = scene_transport_hash(s);
    uint64_t h = hash_int(HASH_FNV_INIT, PHOTON_TRACE_VERSION);
    h = hash_int(hash_int(hash_int(h, global_on != 0), caustic_on != 0), shadow_on != 0);
    h = hash_int(h, s->settings.max_depth);
    h = hash_double(h, cfg->max_emitted_factor);
    h = hash_double(h, cfg->max_emitted);
    h = hash_int(h, cfg->max_memory_mb);
    h = hash_int(h, cfg->max_bounces);
    /* The shadow map is stored by the global pass, whose target is global_photons. */
    if (global_on || shadow_on) {
        h = hash_int(h, cfg->global_photons);
        /* Importance-driven emission (importance.h) changes which photons the global pass
         * stores and their powers; see IMPORTANCE in photon_maps.h for what is left out. */
        h = hash_double(hash_int(h, cfg->importance_paths), cfg->importance_defensive);
    }
    if (caustic_on)
        h = hash_int(hash_int(hash_int(h, cfg->caustic_photons), cfg->projection),
                     cfg->projection_cells);
    st->settings = with_version(h);
}

void map_stamp_volume(const scene *s, const photon_settings *cfg, int volume_on,
                      int volume_caustic_on, map_stamp *st) {
    uint64_t h = hash_int(hash_int(st->settings, volume_on != 0), volume_caustic_on != 0);
    if (volume_on) h = hash_int(h, cfg->volume_photons);
    if (volume_caustic_on) h = hash_int(h, cfg->volume_caustic_photons);
    h = hash_double(hash_double(hash_double(h, s->cam.eye.x), s->cam.eye.y), s->cam.eye.z);
    st->settings = with_version(h);
}

uint64_t map_stamp_file(const map_stamp *st, int caustic, int md) {
    if (md < 0) return st->settings;
    return with_version(hash_int(hash_int(st->settings, caustic ? 2 : 1), md));
}

/* The file name of a volume map (caustic 0) or volume-caustic map (1) of medium md. */
static void volume_name(char *name, size_t cap, int caustic, int md) {
    snprintf(name, cap, "%s-%d.pmap", caustic ? "volume_caustic" : "volume", md);
}

static int save_map(const char *dir, const char *name, const pm_photon *ph, size_t n, uint32_t kind,
                    uint64_t emitted, const map_stamp *stamp, char *err, size_t errcap) {
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    pm_map_header hdr = {PM_FILE_VERSION, sizeof(pm_photon), n, kind, emitted, 0,
                         {stamp->scene, stamp->settings}};
    if (!n) ph = NULL;
    int rc = pm_map_save(path, ph, &hdr);
    if (rc < 0)
        snprintf(err, errcap, "cannot save %s: %s", path, rc == PM_EIO ? strerror(errno) : pm_strerror(rc));
    return rc;
}

/* The stamp check of one loaded file whose tag[1] should be want_tag: 0 when it matches
 * (or, forced, after a warning), else PM_EINVAL with the message. */
static int check_stamp(const char *path, const pm_map_header *hdr, const map_stamp *want,
                       uint64_t want_tag, int force, char *err, size_t errcap) {
    char why[1400];
    unsigned version = (unsigned)(hdr->tag[1] >> 48);
    if (hdr->tag[0] == 0 && hdr->tag[1] == 0)
        snprintf(why, sizeof why, "%s carries no scene or settings stamp (a version-%u map file, "
                 "or one saved by another program)", path, (unsigned)hdr->version);
    else if (hdr->tag[0] != want->scene)
        snprintf(why, sizeof why, "%s was traced for another scene, or the scene has changed "
                 "since (its scene hash %016llx, this scene's %016llx)", path,
                 (unsigned long long)hdr->tag[0], (unsigned long long)want->scene);
    else if (version != PHOTON_TRACE_VERSION)
        snprintf(why, sizeof why, "%s was traced by another version of the photon tracer (its "
                 "stamp says tracer version %u, this renderer's is %u; maps saved before the "
                 "version was stamped say an arbitrary number)", path, version,
                 (unsigned)PHOTON_TRACE_VERSION);
    else if (hdr->tag[1] != want_tag)
        snprintf(why, sizeof why, "%s was traced with other photon settings: the maps the plan "
                 "traces, photon counts, pass budgets, projection maps, render.max_depth, or in "
                 "a scene with media the volume maps and the camera's position (its settings "
                 "hash %016llx, this run's %016llx)", path,
                 (unsigned long long)hdr->tag[1], (unsigned long long)want_tag);
    else
        return 0;
    if (force) {
        fprintf(stderr, "render: warning: force_load_photons: %s; used anyway\n", why);
        return 0;
    }
    snprintf(err, errcap, "cannot load photon maps: %s; trace them again, or use them anyway "
             "with --force-load-photons", why);
    return PM_EINVAL;
}

/* What a file of the set holds: a surface map (medium < 0) or the volume (caustic 0) or
 * volume-caustic (1) map of a medium. */
typedef struct map_role {
    int caustic, medium, nmedia;
} map_role;

static void role_name(char *buf, size_t cap, uint32_t kind, int caustic, int md) {
    if (kind == PM_MAP_VOLUME && md >= 0)
        snprintf(buf, cap, "the %s map of medium %d", caustic ? "volume-caustic" : "volume", md);
    else
        snprintf(buf, cap, "a %s map", kind_name(kind));
}

static int load_map(const char *dir, const char *name, uint32_t kind, map_role role,
                    const map_stamp *want, int force, pm_photon **ph, size_t *n, uint64_t *emitted,
                    map_stamp *got, char *err, size_t errcap) {
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    pm_map_header hdr;
    int rc = pm_map_load(path, ph, &hdr);
    if (rc == PM_ENOMEM) {
        snprintf(err, errcap, "cannot load %s: %s", path, pm_strerror(rc));
        return rc;
    }
    if (rc < 0) {
        /* A missing, unreadable, truncated or foreign file is bad input: exit status 2. */
        int missing = rc == PM_EIO && errno == ENOENT;
        snprintf(err, errcap, "cannot load photon maps: %s: %s%s", path,
                 rc == PM_EIO ? strerror(errno) : pm_strerror(rc),
                 missing ? (role.nmedia > 0
                                ? " (a directory of saved maps of a scene with media holds global.pmap, "
                                  "caustic.pmap, shadow.pmap, and volume-M.pmap and "
                                  "volume_caustic-M.pmap for each medium M)"
                                : " (a directory of saved maps holds global.pmap, caustic.pmap and "
                                  "shadow.pmap)")
                         : "");
        return PM_EINVAL;
    }
    *n = (size_t)hdr.count;
    if (hdr.kind != kind) {
        snprintf(err, errcap, "cannot load photon maps: %s holds a %s map, not a %s map", path,
                 kind_name(hdr.kind), kind_name(kind));
        return PM_EINVAL;
    }
    uint64_t want_tag = map_stamp_file(want, role.caustic, role.medium);
    /* A volume file of the right stamp but another role (renamed): the wrong kind of map. */
    if (role.medium >= 0 && hdr.tag[0] == want->scene && hdr.tag[1] != want_tag)
        for (int c = 0; c < 2; c++)
            for (int md = 0; md < role.nmedia; md++)
                if (hdr.tag[1] == map_stamp_file(want, c, md)) {
                    char has[96], should[96];
                    role_name(has, sizeof has, kind, c, md);
                    role_name(should, sizeof should, kind, role.caustic, role.medium);
                    snprintf(err, errcap, "cannot load photon maps: %s holds %s, not %s", path, has,
                             should);
                    return PM_EINVAL;
                }
    if (emitted) *emitted = hdr.emitted;
    if (got) got->scene = hdr.tag[0], got->settings = hdr.tag[1];
    return check_stamp(path, &hdr, want, want_tag, force, err, errcap);
}

/* The volume files of one role (caustic 0: volume maps, 1: volume-caustic maps) into one array
 * in medium order, with each photon's medium. */
static int load_volume(photon_maps *m, const char *dir, int caustic, const map_stamp *want,
                       int force, char *err, size_t errcap) {
    pm_photon **all = caustic ? &m->volume_caustic : &m->volume;
    short **med = caustic ? &m->volume_caustic_medium : &m->volume_medium;
    size_t *nall = caustic ? &m->nvolume_caustic : &m->nvolume;
    uint64_t *emitted = caustic ? &m->volume_caustic_emitted : &m->volume_emitted;
    for (int md = 0; md < m->nmedia; md++) {
        char name[64];
        volume_name(name, sizeof name, caustic, md);
        pm_photon *ph = NULL;
        size_t n = 0;
        uint64_t ne = 0;
        map_role role = {caustic, md, m->nmedia};
        int rc = load_map(dir, name, PM_MAP_VOLUME, role, want, force, &ph, &n, &ne, NULL, err,
                          errcap);
        if (rc == 0 && n > 0) {
            pm_photon *na = realloc(*all, (*nall + n) * sizeof *na);
            short *nm = na ? realloc(*med, (*nall + n) * sizeof *nm) : NULL;
            if (na) *all = na;
            if (nm) *med = nm;
            if (!na || !nm) {
                rc = PM_ENOMEM;
                snprintf(err, errcap, "out of memory loading %s/%s", dir, name);
            } else {
                memcpy(*all + *nall, ph, n * sizeof *ph);
                for (size_t i = 0; i < n; i++) (*med)[*nall + i] = (short)md;
                *nall += n;
            }
        }
        free(ph);
        if (rc < 0) return rc;
        /* Every medium's file of one role comes from the same pass: one emitted count. */
        *emitted = ne;
    }
    return 0;
}

int photon_tree_build(pm_kdtree **t, pm_photon *ph, size_t n, unsigned bucket, char *err, size_t errcap) {
    *t = NULL;
    if (!ph || n == 0) return 0;
    pm_kdtree_config kc = pm_kdtree_photon_config(bucket);
    int rc = pm_kdtree_build(t, ph, n, &kc, NULL);
    if (rc < 0) snprintf(err, errcap, "building a photon kd-tree: %s", pm_strerror(rc));
    return rc;
}

void photon_paths(const pm_photon *ph, size_t n, uint32_t *path) {
    uint32_t id = 0;
    for (size_t i = 0; i < n; i++) {
        if (i > 0 && pm_photon_kind(&ph[i]) == PM_KIND_DIRECT) id++;
        path[i] = id;
    }
}

int photon_tree_build_global(pm_kdtree **t, photon_maps *m, unsigned bucket, char *err, size_t errcap) {
    *t = NULL;
    free(m->global_path);
    m->global_path = NULL;
    size_t n = m->nglobal;
    if (!m->global || n == 0) return 0;
    uint32_t *path = malloc(n * sizeof *path), *perm = malloc(n * sizeof *perm);
    if (!path || !perm) {
        free(path);
        free(perm);
        snprintf(err, errcap, "building a photon kd-tree: %s", pm_strerror(PM_ENOMEM));
        return PM_ENOMEM;
    }
    photon_paths(m->global, n, path); /* in map order, before the build reorders the records */
    pm_kdtree_config kc = pm_kdtree_photon_config(bucket);
    int rc = pm_kdtree_build(t, m->global, n, &kc, perm);
    if (rc < 0) {
        free(path);
        free(perm);
        snprintf(err, errcap, "building a photon kd-tree: %s", pm_strerror(rc));
        return rc;
    }
    /* perm[i]: the map-order index of tree record i. */
    for (size_t i = 0; i < n; i++) perm[i] = path[perm[i]];
    free(path);
    m->global_path = perm;
    return 0;
}

int photon_maps_load(photon_maps *m, const char *dir, const map_stamp *want, int force, char *err,
                     size_t errcap) {
    struct stat sb;
    const char *bad = NULL;
    if (stat(dir, &sb) != 0)
        bad = errno == ENOENT ? "no such directory" : strerror(errno);
    else if (!S_ISDIR(sb.st_mode))
        bad = "not a directory";
    if (bad) {
        snprintf(err, errcap, "cannot load photon maps from %s: %s", dir, bad);
        return PM_EINVAL;
    }
    int rc;
    map_role surf = {0, -1, m->nmedia};
    if ((rc = load_map(dir, "global.pmap", PM_MAP_GLOBAL, surf, want, force, &m->global,
                       &m->nglobal, &m->global_emitted, &m->stamp, err, errcap)) < 0 ||
        (rc = load_map(dir, "caustic.pmap", PM_MAP_CAUSTIC, surf, want, force, &m->caustic,
                       &m->ncaustic, &m->caustic_emitted, NULL, err, errcap)) < 0 ||
        (rc = load_map(dir, "shadow.pmap", PM_MAP_SHADOW, surf, want, force, &m->shadow,
                       &m->nshadow, NULL, NULL, err, errcap)) < 0 ||
        (rc = load_volume(m, dir, 0, want, force, err, errcap)) < 0 ||
        (rc = load_volume(m, dir, 1, want, force, err, errcap)) < 0)
        return rc;
    m->loaded = 1;
    return 0;
}

/* The volume files of one role: each medium's photons, in photon order. */
static int save_volume(const photon_maps *m, const char *dir, int caustic, char *err, size_t errcap) {
    const pm_photon *all = caustic ? m->volume_caustic : m->volume;
    const short *med = caustic ? m->volume_caustic_medium : m->volume_medium;
    size_t nall = caustic ? m->nvolume_caustic : m->nvolume;
    pm_photon *part = nall ? malloc(nall * sizeof *part) : NULL;
    if (nall && !part) {
        snprintf(err, errcap, "out of memory saving volume photons");
        return PM_ENOMEM;
    }
    int rc = 0;
    for (int md = 0; md < m->nmedia && rc == 0; md++) {
        size_t n = 0;
        for (size_t i = 0; i < nall; i++)
            if (med[i] == md) part[n++] = all[i];
        char name[64];
        volume_name(name, sizeof name, caustic, md);
        map_stamp st = {m->stamp.scene, map_stamp_file(&m->stamp, caustic, md)};
        rc = save_map(dir, name, part, n, PM_MAP_VOLUME,
                      caustic ? m->volume_caustic_emitted : m->volume_emitted, &st, err, errcap);
    }
    free(part);
    return rc;
}

int photon_maps_save(const photon_maps *m, const char *dir, char *err, size_t errcap) {
    if (mkdir(dir, 0777) != 0 && errno != EEXIST) {
        snprintf(err, errcap, "cannot create %s: %s", dir, strerror(errno));
        return PM_EIO;
    }
    int rc;
    /* pm_map_save's temporaries are not in output.h's registry: SIGINT/SIGTERM wait until the
     * files are complete (then end the program), so none is left behind. */
    out_defer_begin();
    if ((rc = save_map(dir, "global.pmap", m->global, m->nglobal, PM_MAP_GLOBAL, m->global_emitted,
                       &m->stamp, err, errcap)) < 0 ||
        (rc = save_map(dir, "caustic.pmap", m->caustic, m->ncaustic, PM_MAP_CAUSTIC,
                       m->caustic_emitted, &m->stamp, err, errcap)) < 0 ||
        (rc = save_map(dir, "shadow.pmap", m->shadow, m->nshadow, PM_MAP_SHADOW, m->global_emitted,
                       &m->stamp, err, errcap)) < 0 ||
        (rc = save_volume(m, dir, 0, err, errcap)) < 0 ||
        (rc = save_volume(m, dir, 1, err, errcap)) < 0) {
        out_defer_end();
        out_die_if_pending();
        return rc;
    }
    out_defer_end();
    out_die_if_pending();
    return 0;
}

static double diffuse_area(const scene *s) {
    double a = 0;
    for (int i = 0; i < s->ntris; i++)
        if (material_is_diffuse(&s->mats[s->tris[i].mat])) a += s->tris[i].area;
    for (int i = 0; i < s->nspheres; i++)
        if (material_is_diffuse(&s->mats[s->spheres[i].mat]))
            a += 4 * M_PI * s->spheres[i].r * s->spheres[i].r;
    return a;
}

/* A surface map's maximum radius: r, or where r is not positive the automatic radius of a
 * k-photon estimate (pm_auto_radius_surface) from the brightest of the map's n photons (the
 * whole map's, whole_max_power[which], for one part of a partitioned pass); infinite for a map
 * of no photons (nwhole, of all parts). */
static double surface_radius(double r, int k, size_t nwhole, const photon_maps *m, int which,
                             const pm_photon *ph, size_t n, double Lt) {
    if (r <= 0)
        r = nwhole ? pm_auto_radius_surface((unsigned)k,
                                            m->part ? m->whole_max_power[which]
                                                    : pm_photons_max_power(ph, n),
                                            Lt)
                   : INFINITY;
    return r;
}

void photon_maps_radii(const scene *s, const photon_maps *m, const photon_settings *cfg, map_radii *r) {
    double area = diffuse_area(s);
    double phi = 0;
    for (int i = 0; i < s->nlights; i++) phi += v3_maxc(s->lights[i].power);
    double Lt = area > 0 ? 0.005 * phi / (M_PI * area) : 0;
    double rg = cfg->max_radius_global, rc_ = cfg->max_radius_caustic;
    /* The whole maps' figures (of all parts, for one part of a partitioned pass). */
    size_t ng = m->part ? m->whole_global : m->nglobal, nc = m->part ? m->whole_caustic : m->ncaustic;
    size_t ns = m->part ? m->whole_shadow : m->nshadow;
    rg = surface_radius(rg, cfg->k_global, ng, m, 0, m->global, m->nglobal, Lt);
    rc_ = surface_radius(rc_, cfg->k_caustic, nc, m, 1, m->caustic, m->ncaustic, Lt);
    r->global = rg;
    r->caustic = rc_;
    r->r2_global = (float)(rg * rg);
    r->r2_caustic = (float)(rc_ * rc_);
    /* The radius of a k-photon estimate at the mean density of the global map. */
    double rtyp = ng ? sqrt(cfg->k_global * area / (M_PI * (double)ng)) : INFINITY;
    r->typical = rtyp;
    r->r2_lookup = (float)fmin(16 * rtyp * rtyp, (double)r->r2_global);
    double rsh = ns ? sqrt(cfg->k_shadow * area / (M_PI * (double)ns)) : 0;
    r->shadow = 2 * rsh;
    r->r2_shadow = (float)(4 * rsh * rsh);
}
