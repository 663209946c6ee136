/* integrator.c: the registry of rendering modes; see integrator.h.
 *
 * Registration runs from constructors before main, single-threaded, into a fixed table.
 */
#include "integrators/integrator.h"

#include <string.h>

#include "photonmap/common.h"

#define MAX_MODES 16
static struct {
    const char *name, *help;
    integrator_create_fn create;
} g_modes[MAX_MODES];
static int g_nmodes;

void integrator_register(const char *name, const char *help, integrator_create_fn create) {
    if (g_nmodes < MAX_MODES) {
        g_modes[g_nmodes].name = name;
        g_modes[g_nmodes].help = help;
        g_modes[g_nmodes].create = create;
        g_nmodes++;
    }
}

int integrator_create(const char *name, const scene *s, integrator *it, char *err, size_t errcap) {
    memset(it, 0, sizeof *it);
    for (int i = 0; i < g_nmodes; i++) {
        if (strcmp(g_modes[i].name, name) == 0) {
            it->name = g_modes[i].name;
            int rc = g_modes[i].create(it, s, err, errcap);
            if (rc == 0 && !it->li) {
                snprintf(err, errcap, "mode \"%s\" has no li function", name);
                return PM_EINVAL;
            }
            return rc;
        }
    }
    size_t n = (size_t)snprintf(err, errcap, "unknown mode \"%s\"; modes:", name);
    for (int i = 0; i < g_nmodes && n < errcap; i++)
        n += (size_t)snprintf(err + n, errcap - n, " %s", g_modes[i].name);
    return PM_EINVAL;
}

void integrator_destroy(integrator *it) {
    if (it->destroy) it->destroy(it);
    memset(it, 0, sizeof *it);
}

void integrator_list(FILE *f) {
    for (int i = 0; i < g_nmodes; i++) fprintf(f, "    %-10s %s\n", g_modes[i].name, g_modes[i].help);
}
