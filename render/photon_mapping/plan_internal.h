/* plan_internal.h: what plan.c and plan_emission.c share; not an interface (plan.h is). */
#ifndef RENDER_PLAN_INTERNAL_H
#define RENDER_PLAN_INTERNAL_H

#include "photon_mapping/plan.h"

struct importance;

/* it->on = on, it->reason = fmt with one string argument. */
void plan__set(plan_item *it, int on, const char *fmt, const char *arg);
/* The importance table of the scene's settings (importance.h), or NULL (plan_emission.c). */
struct importance *plan__make_importance(const scene *s, const photon_settings *c);
/* The emission line from that table: kept in p->imp when used, freed otherwise. */
void plan__emission(const scene *s, const photon_settings *c, render_plan *p, struct importance *tab);

/* The camera probe for ports (ports_find) into p->found; PM_ENOMEM with a message. */
int plan__find_ports(const scene *s, render_plan *p, char *err, size_t errcap);
/* The ports line: p->ports from ports_plan; PM_ENOMEM with a message (plan_emission.c). */
int plan__ports(const scene *s, render_plan *p, char *err, size_t errcap);

#endif /* RENDER_PLAN_INTERNAL_H */
