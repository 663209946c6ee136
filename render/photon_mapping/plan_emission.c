/* plan_emission.c: the plan's "photon emission" line (plan.h): whether the global pass
 * emits by importance (importance.h: toward what the camera sees) or by power, from the
 * importance table built before the pilot, which the pilot's photons already use. */
#include <stdio.h>
#include <stdlib.h>

#include "photon_mapping/plan.h"
#include "photon_mapping/plan_internal.h"
#include "photons/importance.h"

/* The importance table of the scene's settings (importance.h), or NULL: none asked for, maps
 * loaded, media, or out of memory (the emission line says which). */
importance *plan__make_importance(const scene *s, const photon_settings *c) {
    if (scene_has_media(s) || c->load_dir[0] || c->importance_paths <= 0) return NULL;
    importance *imp = malloc(sizeof *imp);
    if (imp && importance_build(s, c->importance_paths, c->importance_defensive, s->settings.seed, 0, imp) < 0) {
        free(imp);
        imp = NULL;
    }
    return imp;
}

/* Importance-driven emission of the global pass, from the table plan__make_importance built (its
 * evidence); the plan keeps the table when it is used and frees it otherwise. */
void plan__emission(const scene *s, const photon_settings *c, render_plan *p, importance *tab) {
    char buf[320];
    if (scene_has_media(s))
        plan__set(&p->emission, 0, "a scene with media traces its maps with volume.h%s", "");
    else if (!p->global.on && !p->shadow.on)
        plan__set(&p->emission, 0, "no global pass%s", "");
    else if (c->load_dir[0])
        plan__set(&p->emission, 0, "the maps are loaded (photon_mapping.load_photons), not traced%s", "");
    else if (c->importance_paths <= 0)
        plan__set(&p->emission, 0, "photon_mapping.importance_paths is 0%s", "");
    else if (p->global.on && !p->final_gather.on)
        /* The map is the image there: photons of even power (a k-nearest estimate over
         * photons of uneven power is noisier, and a partitioned render's combination of the
         * parts' estimates assumes even powers: 3% off in a quarter, where 0.2% by power). */
        plan__set(&p->emission, 0, "the global map is shown directly (no final gather): photons of even power%s", "");
    else if (!tab)
        plan__set(&p->emission, 0, "out of memory for the importance table%s", "");
    if (!tab || p->emission.reason[0]) {
        if (tab) importance_free(tab);
        free(tab);
        return;
    }
    importance imp = *tab;
    if (imp.contributing == 0)
        snprintf(buf, sizeof buf,
                 "none of %llu light connections from %ld camera paths carries light",
                 imp.connections, imp.paths);
    else if (!imp.on)
        snprintf(buf, sizeof buf,
                 "the camera sees light from cells of %.1f%% of the lights' power (%zu of "
                 "%llu light connections from %ld camera paths carry light), below the %.0f%% "
                 "emission can steer by (what enters a small opening after a bounce cannot be aimed "
                 "at; importance.h, LIMITS)",
                 100 * imp.coverage, imp.contributing, imp.connections, imp.paths, 100 * IMP_MIN_COVERAGE);
    else
        snprintf(buf, sizeof buf,
                 "%zu of %llu light connections from %ld camera paths carry light, "
                 "into %zu/%zu/%zu emission cells (finest to coarsest) covering %.1f%% of the lights' "
                 "power; %.0f%% of the global photons by importance, %.0f%% by power",
                 imp.contributing, imp.connections, imp.paths, imp.lv[0].ncells, imp.lv[1].ncells,
                 imp.lv[IMP_LEVELS - 1].ncells, 100 * imp.coverage, 100 * (1 - imp.a), 100 * imp.a);
    plan__set(&p->emission, imp.on, "%s", buf);
    if (imp.on) {
        p->imp = tab; /* kept for the global pass (trace_opts.importance) */
        return;
    }
    importance_free(tab);
    free(tab);
}

