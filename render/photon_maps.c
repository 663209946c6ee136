/* photon_maps.c: the photon maps as data: freeing, saving and loading them (photonmap/'s
 * map files), their kd-trees, and the radius policy of their estimates; see photon_maps.h.
 */
#include "photon_maps.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "photonmap/common.h"
#include "photonmap/estimate.h"
#include "material.h"
#include "output.h"

void photon_maps_free(photon_maps *m) {
    free(m->global);
    free(m->caustic);
    free(m->shadow);
    memset(m, 0, sizeof *m);
}

static int save_map(const char *dir, const char *name, const pm_photon *ph, size_t n, uint32_t kind,
                    uint64_t emitted, unsigned bucket, char *err, size_t errcap) {
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    pm_map_header hdr = {PM_FILE_VERSION, sizeof(pm_photon), n, kind, emitted, bucket};
    int rc = pm_map_save(path, ph, &hdr);
    if (rc < 0)
        snprintf(err, errcap, "cannot save %s: %s", path, rc == PM_EIO ? strerror(errno) : pm_strerror(rc));
    return rc;
}

static int load_map(const char *dir, const char *name, pm_photon **ph, size_t *n, uint64_t *emitted,
                    char *err, size_t errcap) {
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    struct stat sb;
    if (stat(path, &sb) != 0) return 0; /* absent: that map is empty */
    pm_map_header hdr;
    int rc = pm_map_load(path, ph, &hdr);
    if (rc < 0) {
        snprintf(err, errcap, "cannot load %s: %s", path, rc == PM_EIO ? strerror(errno) : pm_strerror(rc));
        return rc;
    }
    *n = (size_t)hdr.count;
    if (emitted) *emitted = hdr.emitted;
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

int photon_maps_load(photon_maps *m, const char *dir, char *err, size_t errcap) {
    int rc;
    if ((rc = load_map(dir, "global.pmap", &m->global, &m->nglobal, &m->global_emitted, err,
                       errcap)) < 0 ||
        (rc = load_map(dir, "caustic.pmap", &m->caustic, &m->ncaustic, &m->caustic_emitted, err,
                       errcap)) < 0 ||
        (rc = load_map(dir, "shadow.pmap", &m->shadow, &m->nshadow, NULL, err, errcap)) < 0)
        return rc;
    return 0;
}

int photon_maps_save(const photon_maps *m, const char *dir, char *err, size_t errcap) {
    if (mkdir(dir, 0777) != 0 && errno != EEXIST) {
        snprintf(err, errcap, "cannot create %s: %s", dir, strerror(errno));
        return PM_EIO;
    }
    int rc;
    /* pm_map_save's temporaries are not in output.h's registry: SIGINT/SIGTERM wait until the
     * three files are complete (then end the program), so none is left behind. */
    out_defer_begin();
    if ((rc = save_map(dir, "global.pmap", m->global, m->nglobal, PM_MAP_GLOBAL, m->global_emitted,
                       0, err, errcap)) < 0 ||
        (rc = save_map(dir, "caustic.pmap", m->caustic, m->ncaustic, PM_MAP_CAUSTIC,
                       m->caustic_emitted, 0, err, errcap)) < 0 ||
        (rc = save_map(dir, "shadow.pmap", m->shadow, m->nshadow, PM_MAP_SHADOW, m->global_emitted,
                       0, err, errcap)) < 0) {
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

void photon_maps_radii(const scene *s, const photon_maps *m, const photon_settings *cfg, map_radii *r) {
    double area = diffuse_area(s);
    double phi = 0;
    for (int i = 0; i < s->nlights; i++) phi += v3_maxc(s->lights[i].power);
    double Lt = area > 0 ? 0.005 * phi / (M_PI * area) : 0;
    double rg = cfg->max_radius_global, rc_ = cfg->max_radius_caustic;
    if (rg <= 0)
        rg = m->nglobal ? pm_auto_radius_surface((unsigned)cfg->k_global,
                                                 pm_photons_max_power(m->global, m->nglobal), Lt)
                        : INFINITY;
    if (rc_ <= 0)
        rc_ = m->ncaustic ? pm_auto_radius_surface((unsigned)cfg->k_caustic,
                                                   pm_photons_max_power(m->caustic, m->ncaustic), Lt)
                          : INFINITY;
    r->global = rg;
    r->caustic = rc_;
    r->r2_global = (float)(rg * rg);
    r->r2_caustic = (float)(rc_ * rc_);
    /* The radius of a k-photon estimate at the mean density of the global map. */
    double rtyp = m->nglobal ? sqrt(cfg->k_global * area / (M_PI * (double)m->nglobal)) : INFINITY;
    r->typical = rtyp;
    r->r2_lookup = (float)fmin(16 * rtyp * rtyp, (double)r->r2_global);
    double rsh = m->nshadow ? sqrt(cfg->k_shadow * area / (M_PI * (double)m->nshadow)) : 0;
    r->shadow = 2 * rsh;
    r->r2_shadow = (float)(4 * rsh * rsh);
}
