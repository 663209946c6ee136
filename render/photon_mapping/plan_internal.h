/* plan_internal.h: what plan.c, plan_emission.c and plan_pilots.c share; not an interface (plan.h is). */
#ifndef RENDER_PLAN_INTERNAL_H
#define RENDER_PLAN_INTERNAL_H

#include <stdio.h>

#include "photon_mapping/plan.h"

/* it->on = on, it->reason = fmt with one string argument. Inline here, so that plan_emission.c,
 * which plan.c calls, does not call back into plan.c for it. */
static inline void plan__set(plan_item *it, int on, const char *fmt, const char *arg) {
    it->on = on;
    snprintf(it->reason, sizeof it->reason, fmt, arg);
}
/* Lights that emit photons: every light in the list with some power. */
int plan__emitting_lights(const scene *s);
/* The emission line from the pilots' importance table: p takes it when used (plan_emission.c). */
void plan__emission(const scene *s, const photon_settings *c, render_plan *p, plan_pilots *pl);
/* The ports line from the pilots' ports table and port probe (plan_emission.c). */
void plan__ports(const scene *s, render_plan *p, const plan_pilots *pl);

#endif /* RENDER_PLAN_INTERNAL_H */
