/* light_guide.c: the light guide (guide.h, THE LIGHT GUIDE): for the photon mapper's direct
 * light, a pilot that finds where light samples are mostly blocked (stage A: light samples
 * drawn as next-event estimation draws them, summed per region), learns a table per light in
 * the cells of those regions (stage B: guide_learn_jobs_spread with an unoccluded-light probe),
 * and decides, with the evidence in words, whether the photon mapper guides its light samples.
 */
#include "guiding/guide.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "scene/light.h"
#include "scene/material.h"
#include "scene/medium.h"
#include "load/photon_settings.h"
#include "base/sampling.h"
#include "base/stats.h"


/* Light li sampled from pt with (u1, u2), chosen with probability pl: the luminance it would
 * add unshadowed (f Li cos / pl, times the point's throughput), 0 if none; *ls filled. */
static double light_value(const scene *s, const guide_point *pt, int li, double pl, double u1, double u2,
                          light_sample *ls) {
    if (!light_sample_li(s, li, pt->h.p, u1, u2, ls) || v3_iszero(ls->L)) return 0;
    double c = v3_dot(ls->wi, pt->n);
    if (!(c > 0)) return 0;
    rgb f = material_f(scene_material(s, &pt->h), pt->h.ng, s->medium_ior, pt->wo, ls->wi);
    double x = rgb_lum(v3_mul(pt->beta, v3_mul(f, ls->L))) * c / pl;
    return x > 0 && isfinite(x) ? x : 0;
}

static int light_visible(const scene *s, const guide_point *pt, int li, const light_sample *ls) {
    if (light_at_infinity(&s->lights[li])) return scene_visible_dir(s, pt->h.p, pt->h.ng, ls->wi);
    return scene_visible(s, pt->h.p, pt->h.ng, ls->p, ls->n);
}

static int guided_light(const light *l) { return l->type == LIGHT_AREA || l->type == LIGHT_SPHERE; }

/* Stage B's probe: the unoccluded contribution of light `slot` at (u1, u2). */
static double light_probe(void *user, const scene *s, const guide_point *pt, int slot, double u1, double u2,
                          rng *g) {
    (void)user;
    (void)g;
    light_sample ls;
    double x = light_value(s, pt, slot, 1.0, u1, u2, &ls);
    return x > 0 && light_visible(s, pt, slot, &ls) ? x : 0;
}

/* Stage A's record of one point. */
typedef struct point_a {
    double U, V;           /* unshadowed, passed luminance */
    int ns, np;            /* samples that would contribute; that pass */
    int li[GUIDE_PROBES];  /* their lights (-1: none) */
} point_a;

static int int_cmp(const void *a, const void *b) {
    int x = *(const int *)a, y = *(const int *)b;
    return x < y ? -1 : x > y;
}

static void say(char *reason, size_t cap, const char *text) { snprintf(reason, cap, "%s", text); }

/* Stage A: at every point, GUIDE_PROBES light samples drawn as next-event estimation draws
 * them (light by power, a uniform point): what they would carry unshadowed and what passes. */
static void stage_a(const scene *s, const guide_point *pts, size_t np, uint64_t seed, point_a *pa) {
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 256)
#endif
    for (long k = 0; k < (long)np; k++) {
        rng g = rng_stream(seed, (uint64_t)k, GUIDE_STREAM + 2);
        point_a *a = &pa[k];
        for (int t = 0; t < GUIDE_PROBES; t++) {
            double ul = rng_uniform(&g), u1 = rng_uniform(&g), u2 = rng_uniform(&g), pl;
            a->li[t] = -1;
            int li = distrib1d_sample(&s->light_distrib, ul, &pl);
            if (!(pl > 0)) continue;
            light_sample ls;
            double x = light_value(s, &pts[k], li, pl, u1, u2, &ls);
            if (!(x > 0)) continue;
            a->U += x;
            a->ns++;
            if (guided_light(&s->lights[li])) a->li[t] = li;
            if (light_visible(s, &pts[k], li, &ls)) {
                a->V += x;
                a->np++;
            }
        }
    }
}

/* Stage B's jobs: in each coarse cell that stage A found blocked (something passes, less than
 * GUIDE_PASS_MAX of the unshadowed light), the first GUIDE_CELL_POINTS points of every fine
 * cell, each with the lights stage A saw contribute in the coarse cell. Jobs sorted by (point,
 * light), as guide_learn_jobs wants. Evidence into e. 0 or PM_ENOMEM. */
static int guide_jobs(const guide_grid *grid, const guide_point *pts, size_t np, const point_a *pa,
                     guide_light_evidence *e, size_t **jp_out, int **js_out, size_t *nj_out) {
    enum { MAXL = 64 };
    guide_cell_ref *cr = malloc((np ? np : 1) * sizeof *cr);
    unsigned char *blocked = calloc(np ? np : 1, 1); /* per point: in a blocked coarse cell */
    size_t *group = malloc((np ? np : 1) * sizeof *group); /* per point: its coarse group */
    int *glights = NULL, *gn = NULL;
    size_t *jp = NULL;
    int *js = NULL;
    int rc = PM_ENOMEM;
    if (!cr || !blocked || !group) goto done;
    for (size_t k = 0; k < np; k++) cr[k] = (guide_cell_ref){guide_region(guide_cell(grid, pts[k].h.p, pts[k].n)), k};
    qsort(cr, np, sizeof *cr, guide_cell_ref_cmp);
    size_t ngroups = 0;
    for (size_t a = 0, b; a < np; a = b) {
        for (b = a; b < np && cr[b].cell == cr[a].cell; b++) {}
        ngroups++;
    }
    glights = malloc((ngroups ? ngroups : 1) * MAXL * sizeof *glights);
    gn = calloc(ngroups ? ngroups : 1, sizeof *gn);
    if (!glights || !gn) goto done;
    double Vall = 0, Vb = 0, Ub = 0;
    size_t gi = 0;
    for (size_t a = 0, b; a < np; a = b, gi++) {
        double U = 0, V = 0;
        int nsamp = 0;
        for (b = a; b < np && cr[b].cell == cr[a].cell; b++) {
            const point_a *p = &pa[cr[b].k];
            U += p->U;
            V += p->V;
            nsamp += p->ns;
            e->samples += (unsigned long long)p->ns;
            e->passed += (unsigned long long)p->np;
            group[cr[b].k] = gi;
        }
        Vall += V;
        if (nsamp == 0) continue;
        e->cells++;
        if (!(V > 0 && V < GUIDE_PASS_MAX * U)) continue;
        e->blocked++;
        Vb += V;
        Ub += U;
        int *L = &glights[gi * MAXL], nl = 0;
        for (size_t c = a; c < b; c++) {
            blocked[cr[c].k] = 1;
            for (int t = 0; t < GUIDE_PROBES; t++) {
                int li = pa[cr[c].k].li[t], dup = 0;
                if (li < 0) continue;
                for (int q = 0; q < nl; q++) dup |= L[q] == li;
                if (!dup && nl < MAXL) L[nl++] = li;
            }
        }
        qsort(L, (size_t)nl, sizeof *L, int_cmp);
        gn[gi] = nl;
    }
    e->points = np;
    e->blocked_share = Vall > 0 ? Vb / Vall : 0;
    e->blocked_pass = Ub > 0 ? Vb / Ub : 0;
    /* Fine cells of blocked coarse cells: their first points. */
    size_t cnt = 0;
    for (size_t k = 0; k < np; k++) cr[k] = (guide_cell_ref){guide_cell(grid, pts[k].h.p, pts[k].n), k};
    qsort(cr, np, sizeof *cr, guide_cell_ref_cmp);
    for (int pass = 0; pass < 2; pass++) {
        size_t nj = 0;
        for (size_t a = 0, b; a < np; a = b) {
            for (b = a; b < np && cr[b].cell == cr[a].cell; b++) {}
            size_t used = 0;
            for (size_t c = a; c < b && used < GUIDE_CELL_POINTS; c++) {
                size_t k = cr[c].k;
                if (!blocked[k]) continue;
                used++;
                for (int q = 0; q < gn[group[k]]; q++) {
                    if (pass) {
                        jp[nj] = k;
                        js[nj] = glights[group[k] * MAXL + (size_t)q];
                    }
                    nj++;
                }
            }
        }
        if (!pass) {
            cnt = nj;
            jp = malloc((cnt ? cnt : 1) * sizeof *jp);
            js = malloc((cnt ? cnt : 1) * sizeof *js);
            if (!jp || !js) goto done;
        }
    }
    /* Sort the jobs by (point, light). */
    guide_cell_ref *o = malloc((cnt ? cnt : 1) * sizeof *o);
    if (!o) goto done;
    for (size_t k = 0; k < cnt; k++) o[k] = (guide_cell_ref){(uint64_t)jp[k] << 32 | (uint64_t)(unsigned)js[k], k};
    qsort(o, cnt, sizeof *o, guide_cell_ref_cmp);
    for (size_t k = 0; k < cnt; k++) {
        jp[k] = (size_t)(o[k].cell >> 32);
        js[k] = (int)(o[k].cell & 0xffffffffu);
    }
    free(o);
    *jp_out = jp;
    *js_out = js;
    *nj_out = cnt;
    jp = NULL;
    js = NULL;
    rc = 0;
done:
    free(cr);
    free(blocked);
    free(group);
    free(glights);
    free(gn);
    free(jp);
    free(js);
    return rc;
}

const char *guide_light_skip(const scene *s, int force, int usable) {
    if (force == PLAN_OFF) return "forced off by photon_mapping.light_guide";
    if (!usable) return "no light samples to guide (the global map is shown directly)";
    if (scene_has_media(s)) return "a scene with media: shadow rays carry transmittance, the probes test visibility";
    int any = 0;
    for (int l = 0; l < s->nlights; l++) any |= guided_light(&s->lights[l]);
    if (!any || s->light_distrib.n == 0)
        return "no area or sphere light (a point or directional light has no point to choose)";
    return NULL;
}

void guide_light_pilot_run(const scene *s, guide_light_pilot *pl) {
    memset(pl, 0, sizeof *pl);
    pl->ran = 1;
    pl->seed = s->settings.seed ^ 0x6c69676874ULL; /* "light" */
    point_a *pa = NULL;
    guide_grid_init(&pl->grid, s, GUIDE_RES);
    if (guide_points(s, GUIDE_PATHS, pl->seed, 0, &pl->pts, &pl->np) < 0 ||
        !(pa = calloc(pl->np ? pl->np : 1, sizeof *pa))) {
        free(pl->pts);
        pl->pts = NULL;
        pl->np = 0;
        pl->rc = PM_ENOMEM; /* the evidence stays empty */
        return;
    }
    stage_a(s, pl->pts, pl->np, pl->seed, pa);
    pl->rc = guide_jobs(&pl->grid, pl->pts, pl->np, pa, &pl->e, &pl->jp, &pl->js, &pl->nj);
    free(pa);
}

/* Free, then clear, member by member: the pilot's own arrays (photon_rounds.c frees another
 * struct's alike). */
void guide_light_pilot_free(guide_light_pilot *pl) {
    free(pl->pts);
    free(pl->jp);
    free(pl->js);
    pl->pts = NULL;
    pl->jp = NULL;
    pl->js = NULL;
}

int guide_light_wanted(int force, const guide_light_pilot *pl) {
    if (!pl->ran) return 0;
    return force == PLAN_ON || (pl->e.blocked > 0 && pl->e.blocked_share >= GUIDE_MIN_SHARE);
}

/* STAGE B'S SIZE (guide.h): of nj jobs, how many the render s's camera is set for pays for. */
size_t guide_light_jobs(const scene *s, size_t nj) {
    const double G2 = (double)GUIDE_G * GUIDE_G;
    double samples = (double)s->cam.width * (double)s->cam.height * (double)s->cam.spp;
    double probes = fmax(GUIDE_B_PER_SAMPLE * samples, GUIDE_B_MIN);
    double want = floor(probes / G2);
    return want >= (double)nj ? nj : (size_t)want;
}

guide *guide_light_learn(const scene *s, guide_light_pilot *pl, size_t max_jobs) {
    if (!pl->ran || pl->rc < 0 || pl->nj == 0) return NULL;
    /* Evenly in (point, light) order, which stays sorted as guide_learn_jobs wants. */
    pl->e.jobs_all = pl->nj;
    pl->nj = pl->e.jobs = guide_thin(pl->jp, pl->js, pl->nj, max_jobs ? max_jobs : pl->nj, pl->jp, pl->js);
    guide *gd = malloc(sizeof *gd);
    if (!gd || guide_learn_jobs_spread(gd, s, &pl->grid, GUIDE_G, GUIDE_ALPHA, pl->pts, pl->jp, pl->js, pl->nj,
                                       light_probe, NULL, pl->seed, 0, &pl->e.probes) < 0) {
        free(gd);
        pl->rc = PM_ENOMEM;
        return NULL;
    }
    pl->e.tables = gd->ntables;
    gd->stat_id = stats_register("Integrator/Light samples guided (light guide)");
    return gd;
}

void guide_light_say(int force, const char *skip, const guide_light_pilot *pl, const guide *gd, int *on,
                     char *reason, size_t cap) {
    *on = 0;
    if (skip) {
        say(reason, cap, skip);
        return;
    }
    const guide_light_evidence e = pl->e;
    int want = guide_light_wanted(force, pl);
    double rate = e.samples ? (double)e.passed / (double)e.samples : 0;
    if (pl->rc < 0) {
        say(reason, cap, "out of memory for the pilot");
        return;
    }
    if (want && (!gd || gd->ntables == 0)) {
        snprintf(reason, cap,
                 "%s, but no cell had light samples that were mostly blocked: nothing to guide (%zu points, "
                 "%llu light samples, %.1f%% pass)",
                 force == PLAN_ON ? "forced on by photon_mapping.light_guide" : "wanted", e.points, e.samples,
                 100 * rate);
        return;
    }
    if (want) {
        *on = 1;
        snprintf(reason, cap,
                 "%s: in %zu of %zu lit regions %.1f%% of the unshadowed light passes, and they carry "
                 "%.0f%% of the light that passes; %llu probes (%zu of %zu jobs%s) made %zu tables in %zu cells "
                 "(pilot: %zu points, %llu light samples, %.1f%% pass)",
                 force == PLAN_ON ? "forced by photon_mapping.light_guide" : "light samples are mostly blocked",
                 e.blocked, e.cells, 100 * e.blocked_pass, 100 * e.blocked_share, e.probes, e.jobs, e.jobs_all,
                 e.jobs < e.jobs_all ? ": at most " GUIDE_B_SAY : "", gd->ntables, gd->ncells, e.points, e.samples,
                 100 * rate);
        return;
    }
    /* Nothing to learn from: say so, rather than "mostly pass" over evidence of none. */
    if (e.samples == 0)
        snprintf(reason, cap,
                 "no pilot light sample would carry light where the camera looks, shadowed or not (black "
                 "surfaces, or lights facing away): nothing to learn (pilot: %zu points, 0 light samples)",
                 e.points);
    else if (e.passed == 0)
        snprintf(reason, cap,
                 "no pilot light sample passes where the camera looks: nothing to learn (pilot: %zu points, "
                 "%llu light samples, none pass)",
                 e.points, e.samples);
    else
        snprintf(reason, cap,
                 "light samples mostly pass: the regions where they are mostly blocked (%zu of %zu) carry "
                 "%.1f%% of the light that passes, below %.0f%% (pilot: %zu points, %llu light samples, %.1f%% "
                 "pass)",
                 e.blocked, e.cells, 100 * e.blocked_share, 100 * GUIDE_MIN_SHARE, e.points, e.samples,
                 100 * rate);
}

guide *guide_light_make(const scene *s, int force, int usable, int *on, char *reason, size_t cap,
                        guide_light_evidence *ev) {
    guide_light_pilot pl;
    memset(&pl, 0, sizeof pl);
    const char *skip = guide_light_skip(s, force, usable);
    if (!skip) guide_light_pilot_run(s, &pl);
    guide *gd = guide_light_wanted(force, &pl) && pl.rc == 0 ? guide_light_learn(s, &pl, 0) : NULL;
    guide_light_say(force, skip, &pl, gd, on, reason, cap);
    if (ev) *ev = pl.e;
    guide_light_pilot_free(&pl);
    if (!*on) {
        guide_destroy(gd);
        gd = NULL;
    }
    return gd;
}
