/* pm_volume.c: the volume photon maps and the ray marching of photon mapping in scenes with
 * media; see pm_volume.h. pmv_trace runs volume.h's passes for the maps the plan wants and
 * splits the volume photons by kind into trees; pmv_march integrates a segment of an eye ray
 * with stratified steps (single scattering by shadow rays, the rest from the trees);
 * pmv_gather takes one point of a gather ray's segment.
 */
#include "photon_mapping/pm_volume.h"

#include <stdlib.h>
#include <string.h>

#include "integrators/direct.h"
#include "photon_mapping/pm_ball.h"
#include "photon_mapping/pm_sample.h"
#include "scene/medium.h"
#include "photonmap/common.h"
#include "photonmap/estimate.h"
#include "base/stats.h"
#include "photons/photon_trace.h"
#include "photons/volume.h"

/* No segment is marched in more steps than this (a tiny step setting in a huge scene). */
#define PMV_MAX_STEPS 4096
/* A volume estimate's typical radius is at most this many mean free paths, and its k at least
 * PMV_K_MIN (STEP, k AND RADII in pm_volume.h). */
#define PMV_RADIUS_MFP 0.5
#define PMV_K_MIN 16u
/* A segment marched in n steps gets ceil(n / PMV_EQUIANGULAR_DIV) equiangular light samples. */
#define PMV_EQUIANGULAR_DIV 2

/* The index of refraction around each medium (RADIANCE INSIDE GLASS in pm_volume.h), from the
 * interfaces: the back side of a refractive object has its ior, its front side and the space
 * between objects (the global medium) the index medium_ior. A medium that meets one index
 * gets its scale once; one that meets two (a gas both around a glass and inside it), or any
 * medium when a refractive object keeps the ray's medium (it could be in any), gets -1: each
 * eye segment then asks scene_index_ahead where it is (pmv_segment_scale). */
static int pmv_index_scales(pmv_state *v, const scene *s) {
    int nm = s->nmedia > 0 ? s->nmedia : 1;
    v->n2_scale = malloc((size_t)nm * sizeof *v->n2_scale);
    double *idx = malloc((size_t)nm * sizeof *idx);
    if (!v->n2_scale || !idx) {
        free(idx);
        return PM_ENOMEM;
    }
    for (int m = 0; m < s->nmedia; m++) idx[m] = 0; /* 0: no index met yet; -1: two met */
    int keep = 0;
    for (int prim = 0; prim < s->ntris + s->nspheres; prim++) {
        int obj = scene_prim_object(s, prim);
        const material *mt = &s->mats[prim < s->ntris ? s->tris[prim].mat : s->spheres[prim - s->ntris].mat];
        if (obj < 0 || obj >= s->nobj || mt->kind == MAT_NULL || !(mt->transparency > 0) || !(mt->ior > 0)) continue;
        for (int front = 0; front < 2; front++) {
            int m = scene_object_side_medium(s, obj, front);
            double n = front ? s->medium_ior : mt->ior;
            if (m == -2) keep = 1;
            else if (m >= 0 && idx[m] != n) idx[m] = idx[m] == 0 ? n : -1;
        }
    }
    int g = s->global_medium;
    if (g >= 0 && idx[g] != s->medium_ior) idx[g] = idx[g] == 0 ? s->medium_ior : -1;
    for (int m = 0; m < s->nmedia; m++)
        v->n2_scale[m] = keep || idx[m] < 0 ? -1 : idx[m] > 0 ? material_radiance_scale(s->medium_ior, idx[m]) : 1;
    free(idx);
    return 0;
}

/* The scale of the volume estimates along eye segment r in medium med (pmv_index_scales). */
static double pmv_segment_scale(const pmv_state *v, const scene *s, int med, ray r) {
    double k = v->n2_scale[med];
    return k >= 0 ? k : material_radiance_scale(s->medium_ior, scene_index_ahead(s, r));
}

int pmv_init(pmv_state *v, const scene *s, const photon_settings *c) {
    memset(v, 0, sizeof *v);
    v->on = scene_has_media(s);
    if (!v->on) return 0;
    v->lo = v3_min(s->bounds_lo, s->cam.eye);
    v->hi = v3_max(s->bounds_hi, s->cam.eye);
    for (int i = 0; i < s->nlights; i++)
        if (light_is_point(&s->lights[i])) {
            v->lo = v3_min(v->lo, s->lights[i].pos);
            v->hi = v3_max(v->hi, s->lights[i].pos);
        }
    double diag = v3_len(v3_sub(v->hi, v->lo));
    if (!(diag > 0) || !isfinite(diag)) diag = 1;
    /* A margin of 1% of the diagonal, so surfaces on the bounds are inside. */
    v->lo = v3_sub(v->lo, v3s(0.01 * diag));
    v->hi = v3_add(v->hi, v3s(0.01 * diag));
    v->step = calloc((size_t)(s->nmedia > 0 ? s->nmedia : 1), sizeof *v->step);
    if (!v->step) return PM_ENOMEM;
    for (int m = 0; m < s->nmedia; m++) {
        double st = v3_maxc(s->media[m].sigma_t), auto_step = diag / 64;
        if (st > 0) auto_step = fmin(auto_step, 0.25 / st);
        v->step[m] = c->volume_step > 0 ? c->volume_step : auto_step;
    }
    v->k_ms = (unsigned)c->k_volume;
    v->k_caus = (unsigned)c->k_volume_caustic;
    v->boundary = c->volume_boundary;
    v->beam = c->volume_beam;
    /* The media's counters, one per line like pm_setup.c's (deliberately the same shape). */
    v->st_steps = stats_register("Photon mapping/Volume march steps");
    v->st_ms = stats_register("Photon mapping/Volume estimates (multiple scattering)");
    v->st_caus = stats_register("Photon mapping/Volume caustic estimates");
    v->st_gather = stats_register("Photon mapping/Volume estimates of gather rays");
    v->st_beam = stats_register("Photon mapping/Volume beam estimates (eye segments x maps)");
    v->st_beam_photons = stats_register("Photon mapping/Volume beam photons crossed");
    return pmv_index_scales(v, s);
}

static void maps_free(pmv_map *m, int n) {
    for (int i = 0; m && i < n; i++) {
        pm_kdtree_free(m[i].t);
        free(m[i].a);
        pmv_beam_free(&m[i].beam);
    }
    free(m);
}

int pmv_build_beams(pmv_state *v, const scene *s) {
    if (!v->on || !v->beam) return 0;
    pmv_map *maps[2] = {v->ms, v->caus};
    for (int k = 0; k < 2; k++)
        for (int md = 0; maps[k] && md < v->nmedia; md++) {
            pmv_map *m = &maps[k][md];
            pmv_beam_free(&m->beam);
            int rc = pmv_beam_build(&m->beam, s, m->t, m->a, m->n, m->k, m->r2, v->boundary);
            if (rc < 0) return rc;
        }
    return 0;
}

void pmv_free(pmv_state *v) {
    maps_free(v->ms, v->nmedia);
    maps_free(v->caus, v->nmedia);
    maps_free(v->all, v->nmedia);
    free(v->step);
    free(v->n2_scale);
    memset(v, 0, sizeof *v);
}

size_t pmv_scratch_bytes(const pmv_state *v) {
    unsigned k = v->k_ms > v->k_caus ? v->k_ms : v->k_caus;
    return pm_estimate_scratch_bytes(k ? k : 1);
}

/* The k and the radius^2 (2 r_typ) of a tree of n photons of ph in a medium whose largest
 * sigma_t is sigma_t, for k0 per estimate at most (STEP, k AND RADII in pm_volume.h); *k_out
 * = k0 and INFINITY if n = 0. */
static float radius2_from_density(const pm_photon *ph, size_t n, unsigned k0, double sigma_t, unsigned *k_out) {
    *k_out = k0;
    if (n == 0) return INFINITY;
    float lo[3], hi[3];
    for (int a = 0; a < 3; a++) lo[a] = hi[a] = ph[0].pos[a];
    for (size_t i = 1; i < n; i++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fminf(lo[a], ph[i].pos[a]);
            hi[a] = fmaxf(hi[a], ph[i].pos[a]);
        }
    /* A flat or tiny cloud: at least a sliver of 1e-3 of its largest extent per axis. */
    double ext = 0;
    for (int a = 0; a < 3; a++) ext = fmax(ext, (double)hi[a] - lo[a]);
    double vol = 1;
    for (int a = 0; a < 3; a++) vol *= fmax((double)hi[a] - lo[a], 1e-3 * ext);
    if (!(vol > 0)) return INFINITY;
    double r_typ = cbrt(3.0 * k0 * vol / (4 * M_PI * (double)n));
    double r_cap = sigma_t > 0 ? PMV_RADIUS_MFP / sigma_t : INFINITY;
    if (r_typ > r_cap && k0 > PMV_K_MIN) {
        double k = floor((double)k0 * pow(r_cap / r_typ, 3));
        *k_out = k < PMV_K_MIN ? PMV_K_MIN : (unsigned)k;
        r_typ = cbrt(3.0 * *k_out * vol / (4 * M_PI * (double)n));
    }
    double r = 2 * r_typ;
    return (float)(r * r);
}

enum { USE_MS, USE_MS_AND_CAUSTIC, USE_ALL };

/* Copy the photons of medium md that serve `use` (INDIRECT; INDIRECT and CAUSTIC; all) into
 * map, choose its radius and build its tree. */
static int split(const pmv_state *v, const scene *s, pmv_map *map, const pm_photon *ph, const short *med, size_t n, int md,
                 unsigned k, int use, char *err, size_t errcap) {
    (void)v;
    size_t cnt = 0;
    for (int pass = 0; pass < 2; pass++) {
        for (size_t i = 0; i < n; i++) {
            int kind = pm_photon_kind(&ph[i]);
            int want = med[i] == md && (use == USE_ALL || kind == PM_KIND_INDIRECT ||
                                        (use == USE_MS_AND_CAUSTIC && kind == PM_KIND_CAUSTIC));
            if (!want) continue;
            if (pass == 1) map->a[map->n++] = ph[i];
            else cnt++;
        }
        if (pass == 0) {
            if (cnt == 0) return 0;
            if (!(map->a = malloc(cnt * sizeof *map->a))) return PM_ENOMEM;
        }
    }
    map->r2 = radius2_from_density(map->a, map->n, k, v3_maxc(s->media[md].sigma_t), &map->k);
    return photon_tree_build(&map->t, map->a, map->n, 8, err, errcap);
}

/* A pass's options (pmv_trace): the targets of its surface and volume maps, the budgets of c
 * (max_emitted: c's, or max_emitted_factor times the larger target), the scene's rules. */
static void pass_opts(vol_pass_opts *o, const pmv_state *v, const scene *s, const photon_settings *c,
                      long surface_target, long volume_target) {
    memset(o, 0, sizeof *o);
    o->surface_target = surface_target;
    o->volume_target = volume_target;
    long tmax = surface_target > volume_target ? surface_target : volume_target;
    double by_factor = c->max_emitted_factor * (double)(tmax > 0 ? tmax : 1);
    o->max_emitted = fmin(c->max_emitted, by_factor);
    o->max_emitted_budget = c->max_emitted < by_factor ? "photon_mapping.max_emitted budget"
                                                       : "photon_mapping.max_emitted_factor budget";
    o->max_memory_bytes = (size_t)c->max_memory_mb << 20;
    o->max_depth = s->settings.max_depth;
    o->max_bounces = c->max_bounces;
    o->seed = s->settings.seed;
    o->lo = v->lo;
    o->hi = v->hi;
}

void pmv_print_maps(const pmv_state *v, const scene *s, const photon_maps *m, const char *loaded_from) {
    double r_ms = 0, r_caus = 0; /* the largest radius and smallest k over the media, for the message */
    unsigned k_ms = v->k_ms, k_caus = v->k_caus;
    for (int md = 0; md < s->nmedia; md++) {
        if (v->ms[md].n) r_ms = fmax(r_ms, sqrt((double)v->ms[md].r2));
        if (v->caus[md].n) r_caus = fmax(r_caus, sqrt((double)v->caus[md].r2));
        if (v->ms[md].n && v->ms[md].k < k_ms) k_ms = v->ms[md].k;
        if (v->caus[md].n && v->caus[md].k < k_caus) k_caus = v->caus[md].k;
    }
    if (loaded_from) printf("Loaded photon maps from %s", loaded_from);
    else printf("Photons");
    printf(" (scene with media): %zu global (from %llu emitted), %zu caustic (from %llu "
           "emitted); volume: %zu (from %llu emitted), %zu of them for multiple scattering (radius "
           "%.4g, k %u), %zu volume-caustic (from %llu emitted, radius %.4g, k %u)\n",
           m->nglobal, (unsigned long long)m->global_emitted, m->ncaustic,
           (unsigned long long)m->caustic_emitted, v->n_all, (unsigned long long)m->volume_emitted,
           v->n_ms, r_ms, k_ms, v->n_caus, (unsigned long long)m->volume_caustic_emitted, r_caus, k_caus);
}

int pmv_trace(pmv_state *v, const scene *s, const photon_settings *c, const render_plan *p,
              photon_maps *m, char *err, size_t errcap) {
    /* Maps loaded by photon_maps_load (m->loaded): their photons, not traced ones. */
    int loaded = m->loaded;
    if (!loaded) memset(m, 0, sizeof *m);
    m->nmedia = s->nmedia;
    int rc = 0;
    vol_pass_result g = {0}, k = {0};
    if (loaded) {
        /* The plan decides which loaded maps are used (as photonmapper.c does without media). */
        if (!p->global.on) m->nglobal = 0;
        if (!p->caustics.on) m->ncaustic = 0;
        g.volume = m->volume, g.volume_medium = m->volume_medium;
        g.nvolume = p->volume.on ? m->nvolume : 0, g.volume_emitted = m->volume_emitted;
        k.volume = m->volume_caustic, k.volume_medium = m->volume_caustic_medium;
        k.nvolume = p->volume_caustics.on ? m->nvolume_caustic : 0;
        k.volume_emitted = m->volume_caustic_emitted;
        m->volume = m->volume_caustic = NULL;
        m->volume_medium = m->volume_caustic_medium = NULL;
    }
    if (!loaded && (p->global.on || p->volume.on)) {
        vol_pass_opts o;
        pass_opts(&o, v, s, c, p->global.on ? c->global_photons : 0, p->volume.on ? c->volume_photons : 0);
        scene sp; /* with the ports the plan's probe found (ports.h), if any */
        if ((rc = vol_trace_pass(ports_found_scene(s, &p->found, &sp), &o, &g)) < 0) goto fail;
    }
    if (!loaded && (p->caustics.on || p->volume_caustics.on)) {
        vol_pass_opts o;
        pass_opts(&o, v, s, c, p->caustics.on ? c->caustic_photons : 0,
                  p->volume_caustics.on ? c->volume_caustic_photons : 0);
        o.caustic_pass = 1;
        o.projection_cells = c->projection ? c->projection_cells : 0;
        /* Light that reaches a wall through a smoke-filled glass is rare: do not let that map
         * take more than CAUSTIC_CAP_FACTOR times the global pass's photons (at least
         * CAUSTIC_CAP_MIN, or the caller's lower floor: pm_preprocess.c, THE CAUSTIC PROBE);
         * it keeps what it stored, for the photons emitted. A pass under the lower floor that
         * stores nothing is traced again at CAUSTIC_CAP_MIN, as a surface pass is. */
        double floor = v->caustic_cap_min > 0 && v->caustic_cap_min < CAUSTIC_CAP_MIN ? v->caustic_cap_min
                                                                                       : CAUSTIC_CAP_MIN;
        double max0 = o.max_emitted;
        for (;;) {
            double cap = fmax(floor, CAUSTIC_CAP_FACTOR * (double)g.emitted);
            o.max_emitted = max0;
            if (cap < o.max_emitted) {
                o.max_emitted = cap;
                o.max_emitted_budget = floor < CAUSTIC_CAP_MIN
                                           ? "caustic pass's cap in a scene with media (4 times the global "
                                             "pass's photons emitted, at least the render's camera samples; "
                                             "pm_volume.c)"
                                           : "caustic pass's cap in a scene with media (4 times the global "
                                             "pass's photons emitted, at least 4194304; pm_volume.c)";
            }
            rc = vol_trace_pass(s, &o, &k);
            if (rc != PM_EEMPTY || floor >= CAUSTIC_CAP_MIN) break;
            floor = CAUSTIC_CAP_MIN;
        }
        if (rc < 0) goto fail;
    }
    /* Split the volume photons by medium and by use (pm_volume.h), and build the trees. */
    v->nmedia = s->nmedia;
    int nm = s->nmedia > 0 ? s->nmedia : 1;
    v->ms = calloc((size_t)nm, sizeof *v->ms);
    v->caus = calloc((size_t)nm, sizeof *v->caus);
    v->all = calloc((size_t)nm, sizeof *v->all);
    if (!v->ms || !v->caus || !v->all) {
        rc = PM_ENOMEM;
        goto fail;
    }
    for (int md = 0; md < s->nmedia && rc == 0; md++) {
        rc = split(v, s, &v->ms[md], g.volume, g.volume_medium, g.nvolume, md, v->k_ms,
                   p->volume_caustics.on ? USE_MS : USE_MS_AND_CAUSTIC, err, errcap);
        if (rc == 0) rc = split(v, s, &v->all[md], g.volume, g.volume_medium, g.nvolume, md, v->k_ms, USE_ALL, err, errcap);
        if (rc == 0)
            rc = split(v, s, &v->caus[md], k.volume, k.volume_medium, k.nvolume, md, v->k_caus, USE_ALL, err, errcap);
        v->n_ms += v->ms[md].n;
        v->n_all += v->all[md].n;
        v->n_caus += v->caus[md].n;
    }
    if (rc < 0) goto fail;
    /* The surface maps move into photon_maps field by field, as pm_preprocess.c's caustic
     * retrace does from its own result type (a deliberate same-shape run: the two result
     * types differ). */
    if (!loaded) {
        m->global = g.surface;
        m->nglobal = g.nsurface;
        m->global_emitted = g.surface_emitted;
        m->global_runaway = g.surface_short;
        g.surface = NULL;
        m->caustic = k.surface;
        m->ncaustic = k.nsurface;
        m->caustic_emitted = k.surface_emitted;
        m->caustic_runaway = k.surface_short;
        m->caustic_fraction = 1;
        k.surface = NULL;
    }
    /* The volume photons stay in m, in photon order, for photon_maps_save. */
    m->volume = g.volume, m->volume_medium = g.volume_medium, m->nvolume = g.nvolume;
    m->volume_emitted = g.volume_emitted;
    m->volume_caustic = k.volume, m->volume_caustic_medium = k.volume_medium;
    m->nvolume_caustic = k.nvolume, m->volume_caustic_emitted = k.volume_emitted;
    g.volume = k.volume = NULL;
    g.volume_medium = k.volume_medium = NULL;
    if (!v->quiet) pmv_print_maps(v, s, m, loaded ? c->load_dir : NULL);
    vol_pass_free(&g);
    vol_pass_free(&k);
    return 0;
fail:
    if (g.msg[0] || k.msg[0]) snprintf(err, errcap, "%s", g.msg[0] ? g.msg : k.msg);
    else if (rc == PM_ENOMEM && !err[0]) snprintf(err, errcap, "out of memory tracing volume photons");
    else if (rc < 0 && !err[0]) snprintf(err, errcap, "tracing volume photons: %s", pm_strerror(rc));
    vol_pass_free(&g);
    vol_pass_free(&k);
    return rc;
}

/* The HG phase of a photon (it came from wi) scattered toward the eye ray's origin. */
typedef struct phase_ctx {
    double g;
    vec3 d; /* the eye ray's direction */
} phase_ctx;

static void phase_fn(void *user, const float wi[3], float f[3]) {
    const phase_ctx *c = user;
    double cs = (double)wi[0] * c->d.x + (double)wi[1] * c->d.y + (double)wi[2] * c->d.z;
    f[0] = f[1] = f[2] = (float)hg_phase(c->g, cs);
}

/* sum phase dPhi / (4/3 pi r^3) from tree t at x, for an eye ray along d in medium med. */
static rgb volume_estimate(const pmv_state *v, const pm_kdtree *t, unsigned k, float r2, const scene *s,
                           int med, vec3 x, vec3 d, void *scratch) {
    pm_estimate_options o;
    pm_estimate_options_init(&o, PM_EST_DISC, k);
    o.max_dist2 = r2;
    phase_ctx pc = {s->media[med].g, d};
    if (fabs(pc.g) > 1e-3) {
        o.brdf = phase_fn;
        o.brdf_user = &pc;
    }
    float xf[3] = {(float)x.x, (float)x.y, (float)x.z};
    pm_estimate_result res;
    if (pm_estimate_volume(t, xf, 1.0, &o, scratch, &res, NULL) < 0) return v3s(0);
    rgb e = v3(res.rgb[0], res.rgb[1], res.rgb[2]);
    /* A ball that ends at its k-th neighbour holds k photons, but in a Poisson cloud of density
     * rho E[k / V_k] = rho k / (k - 1): the k-th sits on the sphere, not inside. (k - 1) / k
     * removes that (+7% at k 16, +2% at k 50); a ball cut at the search limit needs none. */
    if (k > 1 && res.found >= k && res.r2 < (double)r2) e = v3_scale(e, (double)(k - 1) / k);
    if (!v->boundary || res.found == 0 || v3_iszero(e)) return e;
    /* BOUNDARIES (pm_volume.h): divide by the part of the ball inside the medium. */
    return v3_scale(e, 1 / pmv_ball_fraction(s, x, sqrt(res.r2)));
}

/* The same in the renderer's radiance (RADIANCE INSIDE GLASS in pm_volume.h): times n2, the
 * segment's pmv_segment_scale. */
static rgb volume_estimate_in(const pmv_state *v, const pm_kdtree *t, unsigned k, float r2, const scene *s,
                              int med, vec3 x, vec3 d, void *scratch, double n2) {
    rgb e = volume_estimate(v, t, k, r2, s, med, x, d, scratch);
    return n2 == 1 ? e : v3_scale(e, n2);
}

/* Where r leaves the bounds (0 if it misses them). */
static double bounds_exit(const pmv_state *v, ray r) {
    double t0 = 0, t1 = INFINITY;
    for (int a = 0; a < 3; a++) {
        double o = v3_idx(r.o, a), d = v3_idx(r.d, a), lo = v3_idx(v->lo, a), hi = v3_idx(v->hi, a);
        if (d == 0) {
            if (o < lo || o > hi) return 0;
            continue;
        }
        double ta = (lo - o) / d, tb = (hi - o) / d;
        if (ta > tb) {
            double t = ta;
            ta = tb;
            tb = t;
        }
        t0 = fmax(t0, ta);
        t1 = fmin(t1, tb);
    }
    return t1 >= t0 ? t1 : 0;
}

/* The equiangular samples of a segment marched in n steps: ceil(n / PMV_EQUIANGULAR_DIV)
 * (EYE RAYS in pm_volume.h). */
static int pmv_equiangular_samples(int n) { return (n + PMV_EQUIANGULAR_DIV - 1) / PMV_EQUIANGULAR_DIV; }

/* The stratified steps' density n / T, for the equiangular samples' weights. */
static double const_density(const void *user, double t) {
    (void)t;
    return *(const double *)user;
}

rgb pmv_march(const pmv_state *v, const scene *s, ray r, double tmax, int med, int inscatter, rng *g,
              void *scratch, rgb *tr) {
    *tr = v3s(1);
    if (med < 0) return v3s(0);
    const medium *md = &s->media[med];
    double T = isfinite(tmax) ? tmax : bounds_exit(v, r);
    *tr = isfinite(tmax) ? medium_tr(md, tmax) : medium_tr(md, INFINITY);
    if (!inscatter || !(T > 0) || v3_iszero(md->sigma_s)) return v3s(0);
    static const pmv_map none = {0};
    const pmv_map *ms = v->ms ? &v->ms[med] : &none, *caus = v->caus ? &v->caus[med] : &none;
    double nf = ceil(T / v->step[med]);
    int n = nf > PMV_MAX_STEPS ? PMV_MAX_STEPS : nf < 1 ? 1 : (int)nf;
    double dt = T / n, u = rng_uniform(g);
    rgb L = v3s(0);
    direct_segment seg = {r, T, med, pmv_equiangular_samples(n)};
    double dens = n / T, n2 = ms->t || caus->t ? pmv_segment_scale(v, s, med, r) : 1;
    if (seg.m > 0) L = direct_light_equiangular(s, &seg, const_density, &dens, g);
    for (int i = 0; i < n; i++) {
        double t = (i + u) * dt;
        vec3 x = ray_at(r, t);
        rgb src = v3_mul(md->sigma_s, direct_light_medium_mis(s, &seg, t, dens, g));
        if (ms->t && !ms->beam.n) {
            src = v3_add(src, volume_estimate_in(v, ms->t, ms->k, ms->r2, s, med, x, r.d, scratch, n2));
            stat_inc(v->st_ms);
        }
        if (caus->t && !caus->beam.n) {
            src = v3_add(src, volume_estimate_in(v, caus->t, caus->k, caus->r2, s, med, x, r.d, scratch, n2));
            stat_inc(v->st_caus);
        }
        L = v3_add(L, v3_scale(v3_mul(medium_tr(md, t), src), dt));
    }
    stat_add(v->st_steps, (uint64_t)n);
    /* The beam maps: the exact integral of their estimate over the whole segment (pm_beam.h). */
    const pmv_map *bm[2] = {ms, caus};
    for (int k = 0; k < 2; k++) {
        if (!bm[k]->beam.n) continue;
        uint64_t hits = 0;
        rgb e = pmv_beam_segment(&bm[k]->beam, r, T, md->sigma_t, md->g, &hits);
        L = v3_add(L, n2 == 1 ? e : v3_scale(e, n2));
        stat_inc(v->st_beam);
        stat_add(v->st_beam_photons, hits);
    }
    return L;
}

rgb pmv_gather(const pmv_state *v, const scene *s, ray r, double tmax, int med, rng *g, void *scratch,
               rgb *tr) {
    *tr = v3s(1);
    if (med < 0) return v3s(0);
    const medium *md = &s->media[med];
    double T = isfinite(tmax) ? tmax : bounds_exit(v, r);
    *tr = medium_tr(md, tmax);
    const pmv_map *all = v->all ? &v->all[med] : NULL;
    if (!all || !all->t || !(T > 0) || v3_iszero(md->sigma_s)) return v3s(0);
    /* t in [0, T] with density c e^{-k t}, k the mean sigma_t (uniform if k T is tiny). */
    double kk = (md->sigma_t.x + md->sigma_t.y + md->sigma_t.z) / 3, u = rng_uniform(g), t, pdf;
    if (kk * T < 1e-6) {
        t = u * T;
        pdf = 1 / T;
    } else {
        double norm = -expm1(-kk * T); /* 1 - e^{-k T} */
        t = -log1p(-u * norm) / kk;
        pdf = kk * exp(-kk * t) / norm;
    }
    vec3 x = ray_at(r, t);
    stat_inc(v->st_gather);
    rgb src = volume_estimate_in(v, all->t, all->k, all->r2, s, med, x, r.d, scratch, pmv_segment_scale(v, s, med, r));
    return v3_scale(v3_mul(medium_tr(md, t), src), 1 / pdf);
}

rgb pmv_march_eye(const pmv_state *v, const scene *s, ray r, double tmax, int med, int inscatter, rgb beta,
                  double vw, rng *g, void *scratch, pm_sample_caustics *pc, rgb *tr) {
    int in = inscatter && vw > 0;
    if (!in) pc = NULL;
    uint64_t w0 = pc ? stats_trace_work() : 0, b0 = pc ? stats_total(v->st_beam_photons) : 0;
    rgb c = v3_scale(v3_mul(beta, pmv_march(v, s, r, tmax, med, in, g, scratch, tr)), vw);
    if (pc) {
        pc->Lv = v3_add(pc->Lv, c);
        pc->workv += stats_trace_work() - w0;
        pc->beamv += stats_total(v->st_beam_photons) - b0;
    }
    return c;
}
