/* pm_scratch.c: a thread's scratch for the photon mapper's eye rays (photonmapper.c): its
 * estimate buffers, made per thread by the renderer and the pilots, freed with the thread. */
#include <stdlib.h>

#include "photon_mapping/pm_internal.h"

mapper_scratch *pm__scratch_new(const mapper_state *st) {
    mapper_scratch *sc = calloc(1, sizeof *sc);
    if (!sc) return NULL;
    sc->vw = 1;
    sc->est = malloc(pm_estimate_scratch_bytes(st->kmax));
    sc->nb = malloc((size_t)st->cfg.k_shadow * sizeof *sc->nb);
    if (!sc->est || !sc->nb) {
        pm__thread_end(NULL, sc);
        return NULL;
    }
    return sc;
}

void *pm__thread_begin(const integrator *self) { return pm__scratch_new(self->data); }

void pm__thread_end(const integrator *self, void *scratch) {
    (void)self;
    mapper_scratch *sc = scratch;
    if (!sc) return;
    free(sc->est);
    free(sc->nb);
    free(sc);
}
