/* plan.c: the plan's decisions (plan.h, step 2 of plan_make) and its lines.
 *
 * The path from a scene to its photon maps, in three steps (plan.h):
 *   1. plan_pilots_run (plan_pilots.c) runs the pilots: the port probe, the importance table,
 *      the photon pilots (or volume.h's in a scene with media), the ports table and the light
 *      guide's stage A. They hand their evidence over in a plan_pilots.
 *   2. plan_decide (here) decides every line from that evidence alone: it traces nothing and
 *      calls no tracer; it takes over what the plan keeps (the importance table, the pilot's
 *      photons) when a line uses it.
 *   3. The tracers then run from the decisions: the light guide's learning (plan_make, and
 *      plan_light_guide here writes its line), and the photon passes (pm_preprocess.c traces
 *      the maps the plan turned on, with its table and pilot photons).
 *
 * The plan is decided from the lights' point of view, not by material names alone: a glass
 * sphere hidden in a box without light makes no caustics, a light inside a closed mirror
 * stores nothing, and a single diffuse sphere under a sun has nothing to interreflect with.
 * Each reason prints the pilot's counts and the materials involved. The caustics and global
 * lines say how many of the pilot's stores join the maps, or why none do, by the rule
 * photon_trace applies (pilot_photons_joining).
 */
#include "photon_mapping/plan.h"
#include "photon_mapping/plan_internal.h"

#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "guiding/guide.h"
#include "photons/importance.h"
#include "photons/photon_trace.h"
#include "photons/volume.h"
#include "scene/medium.h"

/* ---- probes ------------------------------------------------------------------------------ */

static int prim_count(const scene *s) { return s->ntris + s->nspheres; }
static const material *prim_mat(const scene *s, int prim) {
    return &s->mats[prim < s->ntris ? s->tris[prim].mat : s->spheres[prim - s->ntris].mat];
}

/* Lights that emit photons: every light in the list with some power. */
int plan__emitting_lights(const scene *s) {
    int n = 0;
    for (int i = 0; i < s->nlights; i++) n += v3_maxc(s->lights[i].power) > 0;
    return n;
}

static int any_diffuse(const scene *s) {
    for (int i = 0; i < prim_count(s); i++)
        if (material_is_diffuse(prim_mat(s, i))) return 1;
    return 0;
}

/* ---- surface maps ------------------------------------------------------------------------ */

/* "\"white\" 120, \"red\" 31" : the (up to) three materials with the largest counts. */
static void top_mats(const scene *s, const pilot_counts *pc, char *buf, size_t cap) {
    int used[PILOT_MAX_MATS] = {0};
    size_t len = 0;
    buf[0] = 0;
    for (int r = 0; r < 3; r++) {
        int best = -1;
        for (int i = 0; i < PILOT_MAX_MATS; i++)
            if (!used[i] && pc->by_mat[i] > 0 && (best < 0 || pc->by_mat[i] > pc->by_mat[best])) best = i;
        if (best < 0) break;
        used[best] = 1;
        const char *name = best < s->nmats && best < PILOT_MAX_MATS - 1 ? s->mats[best].name : "(others)";
        int w = snprintf(buf + len, cap - len, "%s\"%s\" %llu", r ? ", " : "", name,
                         pc->by_mat[best]);
        if (w < 0 || (size_t)w >= cap - len) break;
        len += (size_t)w;
    }
}

/* A map's line off for want of a light that emits photons; nonzero if so. */
static int no_emitting_light(const scene *s, plan_item *it) {
    if (plan__emitting_lights(s)) return 0;
    plan__set(it, 0, "no light emits photons%s", "");
    return 1;
}

/* A map's line on when the pilot stored photons of its kind (pc): fmt takes pc's total, its
 * first materials (top_mats) and the pilot photons emitted, in that order. Nonzero if on. */
static int stored_on(const scene *s, const pilot_counts *pc, unsigned long long emitted,
                     plan_item *it, const char *fmt) {
    if (pc->total == 0) return 0;
    char mats[128], buf[300];
    top_mats(s, pc, mats, sizeof mats);
    snprintf(buf, sizeof buf, fmt, pc->total, mats, emitted);
    plan__set(it, 1, "%s", buf);
    return 1;
}

static void plan_caustics(const scene *s, const plan_pilots *r, render_plan *p) {
    int nspec = 0;
    for (int i = 0; i < prim_count(s); i++)
        nspec += material_is_specular(prim_mat(s, i));
    if (!nspec) {
        plan__set(&p->caustics, 0, "no specular surface%s", "");
        return;
    }
    if (no_emitting_light(s, &p->caustics)) return;
    if (!any_diffuse(s)) {
        plan__set(&p->caustics, 0, "no diffuse surface to receive them%s", "");
        return;
    }
    if (stored_on(s, &r->c.caustic, r->c.emitted, &p->caustics,
                  "L S+ D paths: %llu photons stored through specular surfaces (first %s), from "
                  "%llu pilot photons aimed at them"))
        return;
    char mats[128], buf[300];
    if (r->c.emitted == 0) {
        plan__set(&p->caustics, 0,
            "no specular surface reachable from a light (no light faces one: the "
            "projection maps are empty)%s",
            "");
        return;
    }
    top_mats(s, &r->c.first_hits, mats, sizeof mats);
    snprintf(buf, sizeof buf,
             "no specular surface reachable from a light leads to a diffuse one: 0 of %llu pilot "
             "photons aimed at the specular surfaces were stored (first hits: %s)",
             (unsigned long long)r->c.emitted, mats[0] ? mats : "none");
    plan__set(&p->caustics, 0, "%s", buf);
}

static void plan_global(const scene *s, const plan_pilots *r, render_plan *p) {
    if (no_emitting_light(s, &p->global)) return;
    if (stored_on(s, &r->g.diffuse_bounce, r->g.emitted, &p->global,
                  "diffuse surfaces reflect onto each other: %llu photons stored after a diffuse "
                  "bounce off %s, from %llu pilot photons: indirect diffuse light"))
        return;
    char mats[128], buf[300];
    top_mats(s, &r->g.first_hits, mats, sizeof mats);
    if (r->g_stored == 0)
        snprintf(buf, sizeof buf,
                 "no diffuse surface reflects onto another: no surface the lights reach stores "
                 "photons, 0 of %llu pilot photons stored (first hits: %s)",
                 (unsigned long long)r->g.emitted, mats[0] ? mats : "none");
    else
        snprintf(buf, sizeof buf,
                 "no diffuse surface reflects onto another: %zu pilot photons stored, none after "
                 "a diffuse bounce (%llu emitted)",
                 r->g_stored, (unsigned long long)r->g.emitted);
    plan__set(&p->global, 0, "%s", buf);
}

static void plan_shadow(const scene *s, const photon_settings *cfg, const plan_pilots *r, render_plan *p) {
    int area = 0;
    for (int i = 0; i < s->nlights; i++) area += s->lights[i].type == LIGHT_AREA && v3_maxc(s->lights[i].power) > 0;
    if (!area) {
        plan__set(&p->shadow, 0,
            "no area light of triangles (point, directional and sphere lights take one shadow ray each)%s",
            "");
        return;
    }
    int ndiff = 0;
    for (int i = 0; i < prim_count(s); i++)
        ndiff += material_is_diffuse(prim_mat(s, i));
    if (!ndiff) {
        plan__set(&p->shadow, 0, "no diffuse surface%s", "");
        return;
    }
    char mats[128], buf[480];
    if (r->g.occluder.total > 0) {
        /* Occluders, so shadow photons could answer some shadow tests; but the answer costs
         * more than the test it saves (PLAN_SHADOW_HINT_NODES in plan.h): off unless forced. */
        top_mats(s, &r->g.occluder, mats, sizeof mats);
        snprintf(buf, sizeof buf,
                 "area light with occluders (%llu of %llu pilot photons reach a diffuse surface "
                 "behind their first hit; occluders %s), but the hint costs more than the shadow "
                 "rays it saves: its %d-photon search of the shadow map costs about %d BVH node "
                 "visits, a shadow ray far fewer (BVH depth %d, %d primitives); "
                 "photon_mapping.shadow=true forces it",
                 r->g.occluder.total, (unsigned long long)r->g.emitted, mats, cfg->k_shadow,
                 PLAN_SHADOW_HINT_NODES, s->accel.depth, prim_count(s));
        plan__set(&p->shadow, 0, "%s", buf);
        return;
    }
    /* Off, as plan_global's tail: the same two cases, but each line its own words and figures. */
    top_mats(s, &r->g.first_hits, mats, sizeof mats);
    if (r->g_stored == 0)
        snprintf(buf, sizeof buf,
                 "no surface the lights reach stores photons: 0 of %llu pilot photons stored "
                 "(first hits: %s)",
                 (unsigned long long)r->g.emitted, mats[0] ? mats : "none");
    else
        snprintf(buf, sizeof buf,
                 "nothing occludes the area lights: none of %llu pilot photons reaches a "
                 "diffuse surface behind its first hit (first hits: %s)",
                 (unsigned long long)r->g.emitted, mats);
    plan__set(&p->shadow, 0, "%s", buf);
}

/* ---- scenes with media ------------------------------------------------------------------- */

/* The index of the largest of n counts (-1 if all are 0). */
static int argmax(const unsigned long long *c, int n, size_t stride) {
    int best = -1;
    for (int i = 0; i < n; i++)
        if (c[(size_t)i * stride] > 0 && (best < 0 || c[(size_t)i * stride] > c[(size_t)best * stride])) best = i;
    return best;
}

static const char *medium_name(const scene *s, int m) {
    return m >= 0 && m < s->nmedia && m < VOL_PILOT_MEDIA - 1 ? s->media[m].name : "(others)";
}

/* Every decision of a scene with media, from volume.h's pilots (the tracer of its maps). */
static void plan_media(const scene *s, const plan_pilots *pl, render_plan *p) {
    const vol_pilot pg = pl->vg, pc = pl->vc;
    char buf[300];
    int scatters = 0, nspec = 0;
    for (int m = 0; m < s->nmedia; m++) scatters += v3_maxc(s->media[m].sigma_s) > 0;
    for (int i = 0; i < prim_count(s); i++) /* a null surface is no specular one */
        nspec += prim_mat(s, i)->kind != MAT_NULL && material_is_specular(prim_mat(s, i));
    unsigned long long ev[VOL_PILOT_MEDIA] = {0}, total = 0, direct = 0;
    for (int m = 0; m < VOL_PILOT_MEDIA; m++) {
        for (int k = 0; k < 4; k++) ev[m] += pg.events[m][k];
        total += ev[m];
        direct += pg.events[m][PM_KIND_DIRECT];
    }
    /* volume */
    if (!plan__emitting_lights(s))
        plan__set(&p->volume, 0, "no light emits photons%s", "");
    else if (!s->nmedia)
        plan__set(&p->volume, 0, "no participating medium (only null surfaces): no volume photon map%s", "");
    else if (!scatters)
        plan__set(&p->volume, 0, "no medium scatters light (sigma_s = 0 in every medium): they only attenuate, "
                           "no volume photon map%s", "");
    else if (total == 0) {
        snprintf(buf, sizeof buf, "no medium is lit: 0 of %llu pilot photons scatter in a medium", pg.emitted);
        plan__set(&p->volume, 0, "%s", buf);
    } else {
        int top = argmax(ev, VOL_PILOT_MEDIA, 1);
        snprintf(buf, sizeof buf,
                 "medium \"%s\" is lit by the lights: %llu scattering events of %llu pilot photons in it "
                 "(%llu in all media: %llu straight from a light, %llu after a bounce or an earlier "
                 "event)",
                 medium_name(s, top), ev[top], pg.emitted, total, direct, total - direct);
        plan__set(&p->volume, 1, "%s", buf);
    }
    /* volume caustics */
    unsigned long long vc = 0, vcm[VOL_PILOT_MEDIA];
    for (int m = 0; m < VOL_PILOT_MEDIA; m++) vc += (vcm[m] = pc.events[m][PM_KIND_CAUSTIC]);
    if (!p->volume.on && !(scatters && vc > 0))
        plan__set(&p->volume_caustics, 0, "no volume map%s", "");
    else if (!nspec)
        plan__set(&p->volume_caustics, 0, "no specular surface%s", "");
    else if (vc == 0) {
        snprintf(buf, sizeof buf,
                 "no specular surface sends light into a medium: 0 of %llu pilot photons aimed at "
                 "specular surfaces scatter in a medium after specular bounces only",
                 pc.emitted);
        plan__set(&p->volume_caustics, 0, "%s", buf);
    } else {
        int tm = argmax(vcm, VOL_PILOT_MEDIA, 1), ts = argmax(pc.caustic_by_mat, VOL_PILOT_MATS, 1);
        snprintf(buf, sizeof buf,
                 "\"%s\" sends light into a medium: %llu of %llu pilot photons aimed at specular "
                 "surfaces scatter in \"%s\" after specular bounces only (L S+ V)",
                 ts >= 0 && ts < s->nmats && ts < VOL_PILOT_MATS - 1 ? s->mats[ts].name : "(others)", vc,
                 pc.emitted, medium_name(s, tm));
        plan__set(&p->volume_caustics, 1, "%s", buf);
    }
    /* surface maps */
    if (!nspec)
        plan__set(&p->caustics, 0, "no specular surface%s", "");
    else if (pc.surf_caustic == 0) {
        snprintf(buf, sizeof buf,
                 "no L S+ D path: 0 of %llu pilot photons aimed at specular surfaces reach a diffuse "
                 "surface through specular surfaces only",
                 pc.emitted);
        plan__set(&p->caustics, 0, "%s", buf);
    } else {
        snprintf(buf, sizeof buf,
                 "L S+ D paths: %llu arrivals at diffuse surfaces through specular surfaces only, from "
                 "%llu pilot photons aimed at them",
                 pc.surf_caustic, pc.emitted);
        plan__set(&p->caustics, 1, "%s", buf);
    }
    if (pg.surf_indirect == 0) {
        snprintf(buf, sizeof buf,
                 "no diffuse surface or medium sends light onto a diffuse surface: %llu arrivals "
                 "after a bounce, from %llu pilot photons",
                 pg.surf_indirect, pg.emitted);
        plan__set(&p->global, 0, "%s", buf);
    } else {
        snprintf(buf, sizeof buf,
                 "diffuse surfaces and media send light onto diffuse surfaces: %llu arrivals after a "
                 "bounce (%llu of them after scattering in a medium), from %llu pilot photons",
                 pg.surf_indirect, pg.surf_after_scatter, pg.emitted);
        plan__set(&p->global, 1, "%s", buf);
    }
    plan__set(&p->shadow, 0, "a scene with media: shadow rays carry the transmittance, no shadow photons%s", "");
}

void plan_free(render_plan *p) {
    if (p->imp) importance_free(p->imp);
    free(p->imp);
    p->imp = NULL;
    pilot_photons_free(p->pilot);
    p->pilot = NULL;
    guide_destroy(p->guide);
    p->guide = NULL;
}

/* Append to the caustics and global reasons (the shadow reason for a shadow map without a
 * global map) how many of the pilot's stores join those maps,
 * or why none do, by photon_trace's own rule for the options the pass will have
 * (photonmapper.c: trace_opts_settings, the plan's maps and table). Keeps the pilot's photons
 * only when some join. */
static void plan_joins(const scene *s, const photon_settings *c, render_plan *p) {
    if (!p->pilot) return;
    trace_opts o;
    trace_opts_settings(&o, s, c);
    o.global = p->global.on;
    o.shadow = p->shadow.on;
    o.caustic = p->caustics.on;
    o.importance = p->imp;
    int any = 0;
    for (int caustic = 0; caustic < 2; caustic++) {
        plan_item *it = caustic ? &p->caustics : p->global.on ? &p->global : &p->shadow;
        const char *map = caustic ? "caustic map" : o.global ? "global map" : "shadow map";
        size_t n = 0;
        uint64_t ne = 0;
        const char *why = "";
        int joins = !c->load_dir[0] && pilot_photons_joining(p->pilot, &o, caustic, &n, &ne, &why);
        any |= joins;
        size_t len = strlen(it->reason), cap = sizeof it->reason - len;
        char *at = it->reason + len;
        if (joins)
            snprintf(at, cap, "; the pilot's %zu stores join the %s (its %llu photons counted as emitted)", n,
                     map, (unsigned long long)ne);
        else if (caustic ? !p->caustics.on : !(p->global.on || p->shadow.on))
            continue;
        else if (c->load_dir[0])
            snprintf(at, cap, "; the maps are loaded: no pilot stores join");
        else if (why[0])
            snprintf(at, cap, "; the pilot's stores do not join the %s: %s", map, why);
    }
    if (!any) {
        pilot_photons_free(p->pilot);
        p->pilot = NULL;
    }
}

/* Apply a forced setting from the scene file (or --pm key=true|false). */
static void force(plan_item *it, int f, const char *key) {
    if (f == PLAN_AUTO) return;
    it->on = f == PLAN_ON;
    snprintf(it->reason, sizeof it->reason, "forced by photon_mapping.%s", key);
}

/* The map lines (caustics, global, shadow, volume, volume caustics) and final gathering, forces
 * applied: what the light guide's pilot needs to know (plan_samples_lights) and plan_decide's
 * first part. Pure. */
static void decide_maps(const photon_settings *c, int preview, const plan_pilots *pl, render_plan *p) {
    const scene *s = pl->s;
    if (pl->media) {
        plan_media(s, pl, p);
        force(&p->volume, c->force_volume, "volume");
        force(&p->volume_caustics, c->force_volume_caustics, "volume_caustics");
    } else {
        plan_caustics(s, pl, p);
        plan_global(s, pl, p);
        plan_shadow(s, c, pl, p);
        plan__set(&p->volume, 0, "no participating medium in the scene: no volume photon map%s", "");
        plan__set(&p->volume_caustics, 0, "no participating medium in the scene%s", "");
    }
    force(&p->caustics, c->force_caustics, "caustics");
    force(&p->global, c->force_global, "global");
    force(&p->shadow, c->force_shadow, "shadow");
    if (preview)
        plan__set(&p->final_gather, 0, "preview mode: the global map is shown directly%s", "");
    else if (!p->global.on)
        plan__set(&p->final_gather, 0, "no global map to gather from%s", "");
    else if (c->force_final_gather == PLAN_OFF)
        plan__set(&p->final_gather, 0, "forced by photon_mapping.final_gather: the global map is shown directly%s", "");
    else if (c->force_final_gather == PLAN_ON)
        plan__set(&p->final_gather, 1, "forced by photon_mapping.final_gather%s", "");
    else
        plan__set(&p->final_gather, 1,
            "indirect diffuse by gather rays reading precomputed irradiance of the global map%s", "");
}

/* The photon mapper samples lights unless it shows the global map directly. */
static int samples_lights(int preview, const render_plan *p) {
    return !((preview || !p->final_gather.on) && p->global.on);
}

int plan_samples_lights(const photon_settings *c, int preview, const plan_pilots *pl) {
    render_plan *p = calloc(1, sizeof *p);
    if (!p) return 1; /* the guide's pilot then runs; its line is decided from the plan anyway */
    decide_maps(c, preview, pl, p);
    int on = samples_lights(preview, p);
    free(p);
    return on;
}

void plan_decide(const photon_settings *c, int preview, plan_pilots *pl, render_plan *p) {
    const scene *s = pl->s;
    memset(p, 0, sizeof *p);
    p->found = pl->found;
    if (!pl->media) {
        p->pilot = pl->g.kept; /* both pilots' stores, until plan_joins says whether they join */
        pl->g.kept = NULL;
        p->work_emit[0] = pl->g.emitted ? pl->g_work / (double)pl->g.emitted : 0;
        p->work_emit[1] = pl->c.emitted ? pl->c_work / (double)pl->c.emitted : 0;
    }
    decide_maps(c, preview, pl, p);
    plan__emission(s, c, p, pl);
    plan__ports(s, p, pl);
    /* The light guide: wanted (on) when its pilot's evidence says so; plan_light_guide writes
     * the line once its tables are learned. */
    p->light_guide.on = !pl->guide_skip && guide_light_wanted(c->force_light_guide, &pl->guide);
    plan_joins(s, c, p);
}

void plan_light_guide(const photon_settings *c, const plan_pilots *pl, guide *gd, render_plan *p) {
    guide_light_say(c->force_light_guide, pl->guide_skip, &pl->guide, gd, &p->light_guide.on, p->light_guide.reason,
                    sizeof p->light_guide.reason);
    if (p->light_guide.on) {
        p->guide = gd;
        return;
    }
    guide_destroy(gd);
}

void plan_print(const render_plan *p, FILE *f) {
    const plan_item *it[] = {&p->caustics, &p->global, &p->shadow, &p->final_gather, &p->volume,
                             &p->volume_caustics, &p->emission, &p->ports, &p->light_guide};
    static const char *name[] = {"caustics", "global", "shadow photons", "final gather", "volume",
                                 "volume caustics", "photon emission", "photon ports", "light guide"};
    fprintf(f, "Plan:\n");
    for (int i = 0; i < 9; i++)
        fprintf(f, "  %s: %s (%s)\n", name[i],
                i == 6 ? (it[i]->on ? "importance" : "by power") : it[i]->on ? "on" : "off", it[i]->reason);
}
