/* plan_emission.c: the plan's "photon emission" line (plan.h): whether the global pass
 * emits by importance (importance.h: toward what the camera sees) or by power, from the
 * importance table the pilot stage built (plan_pilots.c), which the pilot's photons already
 * use; and its "photon ports" line (ports.h), from the ports table and the port probe. Both
 * decide only: the pilots ran before. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photon_mapping/plan.h"
#include "photon_mapping/plan_internal.h"
#include "photons/importance.h"
#include "photons/ports.h"
#include "scene/medium.h"

/* Importance-driven emission of the global pass, from the table the pilot stage built (its
 * evidence); the plan takes the table when it is used, else plan_pilots_free frees it. */
void plan__emission(const scene *s, const photon_settings *c, render_plan *p, plan_pilots *pl) {
    importance *tab = pl->imp;
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
    if (!tab || p->emission.reason[0]) return;
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
        pl->imp = NULL;
    }
}


/* The line for ports the probe found: each port, and why. */
static void found_reason(const scene *s, const port_found *f, char *buf, size_t cap) {
    size_t n = (size_t)snprintf(buf, cap, "found by a camera probe, %.3g of the global photons aimed through "
                                "them:", s->port_fraction);
    for (int k = 0; k < f->n && n < cap; k++) {
        const port *pt = &f->p[k];
        n += (size_t)snprintf(buf + n, cap - n, " port %d quad %.3g x %.3g at (%.4g, %.4g, %.4g) normal (%.2g, %.2g, "
                              "%.2g), threaded by %d carriers with %.3g%% of the light the camera's paths carry, "
                              "where ordinary emission sends %.3g%% of the lights' power;", k, v3_len(pt->e1),
                              v3_len(pt->e2), pt->c.x, pt->c.y, pt->c.z, pt->n.x, pt->n.y, pt->n.z, f->count[k],
                              100 * f->share[k], 100 * f->flux[k]);
    }
    if (n < cap) snprintf(buf + n, cap - n, " %s", f->why);
}

/* The ports line (ports.h): whether the global pass aims through the scene's ports (declared,
 * or found by the probe: s is then the pilots' copy with them), and why, from the pilot
 * stage's ports_plan and port probe. */
void plan__ports(const scene *s, render_plan *p, const plan_pilots *pl) {
    char *buf = p->ports.reason;
    size_t cap = sizeof p->ports.reason;
    int on = pl->ports_on;
    snprintf(buf, cap, "%s", pl->ports_reason);
    if (on && p->found.n) {
        found_reason(s, &p->found, buf, cap);
    } else if (p->found.ran || (!s->nports && p->found.why[0])) {
        size_t n = strlen(buf);
        snprintf(buf + n, cap - n, "; %s: %s", p->found.ran ? "none found by a camera probe" : "not looked for",
                 p->found.why);
    }
    p->ports.on = on;
}
