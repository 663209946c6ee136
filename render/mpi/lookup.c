/* lookup.c: partitioned photon maps across the ranks of render-mpi; lookup.h says how it works.
 * Here: the set-up (lk_init, lk_begin) and the photon mapper's hooks (photon_lookup.h), through
 * which its estimates and precomputed-irradiance lookups become queries of the sample being
 * traced (ask). This rank's answers and the messages are lk_serve.c's, the tiles' traces
 * lk_tiles.c's, the precomputed irradiance's build lk_irradiance.c's.
 */
#include "lookup.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lk_irradiance.h"
#include "lk_serve.h"
#include "lk_tiles.h"
#include "ranks.h"
#include "base/stats.h"

static photon_lookup_hook g_hook;

int lk_on(void) { return lk.on; }

/* ---- the hook ----------------------------------------------------------------------------- */

static void rec_grow(lk_rec *r) {
    uint32_t cap = r->cap ? 2 * r->cap : 4;
    lk_query *q = realloc(r->q, cap * sizeof *q);
    if (q) r->q = q;
    lk_part *m = q ? realloc(r->mine, cap * sizeof *m) : NULL;
    if (m) r->mine = m;
    double(*e)[3] = m ? realloc(r->e, cap * sizeof *e) : NULL;
    if (e) r->e = e;
    uint8_t *f = e ? realloc(r->flags, cap) : NULL;
    if (!f) dist_die("out of memory recording photon lookups");
    r->flags = f;
    r->cap = cap;
}

/* The answer to the sample's next query qq (lk_render_tiles): the combined one if this query
 * was answered in an earlier trace of the sample at this place, else a guess (this rank's
 * part of a lookup of the precomputed irradiance; 0 for an estimate), with the query kept to
 * be answered. Returns 1 if a lookup found a record. */
static int ask(const lk_query *qq, double e[3]) {
    lk_smp *sm = lk_tl_smp;
    e[0] = e[1] = e[2] = 0;
    if (!sm) {
        dist_die("a photon lookup outside a camera sample of a partitioned render");
        return 0;
    }
    if (!sm->rec && !(sm->rec = calloc(1, sizeof *sm->rec))) dist_die("out of memory recording photon lookups");
    lk_rec *r = sm->rec;
    uint32_t j = r->cursor++;
    if (j < r->n && (r->flags[j] & LK_HAVE) && memcmp(&r->q[j], qq, sizeof *qq) == 0) {
        memcpy(e, r->e[j], sizeof r->e[0]);
        return (r->flags[j] & LK_FOUND) != 0;
    }
    /* Not answered yet, or the trace left the recorded one (an earlier guess was wrong):
     * what was recorded from here on is another path's. */
    if (!r->fresh) {
        r->fresh = 1;
        r->from = j;
    }
    r->n = j;
    if (r->n == r->cap) rec_grow(r);
    r->q[j] = *qq;
    r->flags[j] = 0;
    r->n = j + 1;
    if (qq->map != LK_SIDE) return 0;
    lk_answer_lookup(qq, &r->mine[j]);
    r->flags[j] = LK_MINE;
    for (int c = 0; c < 3; c++) e[c] = r->mine[j].power[c];
    return r->mine[j].found != 0;
}

static void hook_estimate(void *user, const sample_id *id, int map, vec3 x, vec3 n, double e[3]) {
    (void)user;
    (void)id;
    lk_query q;
    memset(&q, 0, sizeof q);
    q.x[0] = (float)x.x, q.x[1] = (float)x.y, q.x[2] = (float)x.z;
    q.n[0] = (float)n.x, q.n[1] = (float)n.y, q.n[2] = (float)n.z;
    q.map = (uint32_t)map;
    ask(&q, e);
}

/* side_cache's remote lookup (photon_sides.h): every rank answers from its part of the
 * records, at y and n rounded to float (on every rank, the owner's part too, so the answer is
 * the same whichever rank traced the sample), with y's free height computed once here. */
static int side_remote(void *user, const scene *s, vec3 y, vec3 n, float max_dist2, float e[3]) {
    (void)user;
    lk_query q;
    memset(&q, 0, sizeof q);
    q.x[0] = (float)y.x, q.x[1] = (float)y.y, q.x[2] = (float)y.z;
    q.n[0] = (float)n.x, q.n[1] = (float)n.y, q.n[2] = (float)n.z;
    q.h = (float)side_free_height(s, lk_v3f(q.x), lk_v3f(q.n), 0.25 * sqrt((double)max_dist2));
    q.d2 = max_dist2;
    q.map = LK_SIDE;
    double ed[3];
    int found = ask(&q, ed);
    for (int c = 0; c < 3; c++) e[c] = (float)ed[c];
    return found;
}

static int hook_partition(void *user, photon_maps *m, char *err, size_t errcap) {
    (void)user;
    (void)err;
    (void)errcap;
    lk.maps = m; /* the mapper numbers the part's paths when it builds its tree (PHOTON PATHS) */
    pm_photon **arr[2] = {&m->global, &m->caustic};
    size_t *cnt[2] = {&m->nglobal, &m->ncaustic}, all[2] = {m->nglobal, m->ncaustic};
    if (m->part) { /* traced by a partitioned pass: already this rank's part (photon_trace.h) */
        all[0] = m->whole_global;
        all[1] = m->whole_caustic;
    }
    for (int k = 0; k < 2 && !m->part; k++) {
        size_t n = *cnt[k];
        size_t lo = n * (size_t)lk.rank / (size_t)lk.size, hi = n * (size_t)(lk.rank + 1) / (size_t)lk.size;
        if (lo > 0 && hi > lo) memmove(*arr[k], *arr[k] + lo, (hi - lo) * sizeof **arr[k]);
        *cnt[k] = hi - lo;
        pm_photon *shrunk = realloc(*arr[k], (hi > lo ? hi - lo : 1) * sizeof **arr[k]);
        if (shrunk) *arr[k] = shrunk;
    }
    free(m->shadow);
    m->shadow = NULL;
    m->nshadow = 0;
    printf("MPI: partitioned maps: rank %d keeps %zu of %zu global photons, %zu of %zu caustic; "
           "shadow rays are traced (no shadow-photon map)\n",
           lk.rank, m->nglobal, all[0], m->ncaustic, all[1]);
    return 0;
}

static void hook_ready(void *user, const pm_kdtree *const trees[2], const pm_estimate_options opts[2]) {
    (void)user;
    lk.ready = 1;
    for (int k = 0; k < 2; k++) {
        lk.trees[k] = trees[k];
        lk.opts[k] = opts[k];
    }
}

static int hook_side_build(void *user, side_cache *c, const scene *s, const pm_kdtree *global,
                           const pm_photon *ph, size_t n, unsigned k, float max_dist2, char *err,
                           size_t errcap) {
    (void)user;
    int rc = lk_side_build(c, s, global, ph, n, k, max_dist2, err, errcap);
    if (rc == 0) c->remote = side_remote; /* every final-gather lookup asks every rank */
    return rc;
}

void lk_begin(const scene *s) {
    if (!lk.ready || lk.caus_side.t || !lk.trees[PHOTON_LOOKUP_CAUSTIC]) return;
    char err[128];
    const pm_kdtree *t = lk.trees[PHOTON_LOOKUP_CAUSTIC];
    if (side_map_init(&lk.caus_side, s, t, pm_kdtree_size(t), lk.opts[PHOTON_LOOKUP_CAUSTIC].max_dist2, err,
                      sizeof err) < 0)
        dist_die(err);
}

/* The counters of the partitioned lookups (statistics). */
static const struct {
    int *id;
    const char *name;
} counters[] = {
    {&lk.st_queries, "MPI/Partitioned: photon lookups sent (all ranks)"},
    {&lk.st_bytes, "MPI/Partitioned: bytes sent in photon lookups (all ranks)"},
    {&lk.st_side_queries, "MPI/Partitioned: precomputed irradiance estimates"},
    {&lk.st_side_bytes, "MPI/Partitioned: bytes sent precomputing irradiance (all ranks)"},
    {&lk.st_gather_queries, "MPI/Partitioned: precomputed irradiance lookups sent (all ranks)"},
    {&lk.st_traced, "MPI/Partitioned: camera sample traces (all ranks)"},
    {&lk.st_again, "MPI/Partitioned: camera samples traced twice or more (all ranks)"},
    {&lk.st_more, "MPI/Partitioned: camera sample traces past the second (all ranks)"},
    {&lk.st_rounds, "MPI/Partitioned: lookup exchanges of chunks (all ranks)"},
    {&lk.st_exact, "MPI/Partitioned: samples kept from a trace on guesses (all ranks)"},
    {&lk.st_nonfinite, "Film/Non-finite samples"},
};

void lk_init(int rank, int size, MPI_Comm comm) {
    memset(&lk, 0, sizeof lk);
    lk.rank = rank;
    lk.size = size;
    lk.on = 1;
    const char *ta = getenv("PM_MPI_TEST_TRACE_AGAIN");
    lk.trace_again = ta && strcmp(ta, "1") == 0;
    lk.comm = comm;
    for (size_t i = 0; i < sizeof counters / sizeof counters[0]; i++)
        *counters[i].id = stats_register(counters[i].name);
    g_hook.partition = hook_partition;
    g_hook.side_build = hook_side_build;
    g_hook.ready = hook_ready;
    g_hook.estimate = hook_estimate;
    g_hook.user = NULL;
    photon_lookup_set_hook(&g_hook);
}
