/* lookup.c: partitioned photon maps across the ranks of render-mpi; lookup.h says how it works.
 *
 * Messages of the pixel pass, on a communicator of their own (so that rank 0's tile queue on
 * MPI_COMM_WORLD never sees them):
 *   QUERY   owner -> every other rank   n lk_query records (36 bytes each)
 *   ANSWER  rank -> owner               n lk_part records (36 bytes each), in query order
 *   DONE    rank -> every other rank    empty: "I have no more tiles"
 * A rank waiting for answers or for its next tiles keeps serving QUERY messages, so no rank
 * ever waits on one that waits on it. Answers go out with MPI_Isend; their buffers are freed
 * once sent.
 */
#include "lookup.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "scene/camera.h"
#include "dist.h"
#include "photon_mapping/photon_lookup.h"
#include "photonmap/combined.h"
#include "photonmap/common.h"
#include "base/rng.h"
#include "base/stats.h"

#ifdef _OPENMP
#include <omp.h>
#endif

enum { TAG_QUERY = 201, TAG_ANSWER, TAG_DONE };
/* Candidates examined by an estimate that meets a wall, as a multiple of its k (photon_sides.c). */
#define LK_WIDEN 4

/* A query: an estimate of the global or caustic map at (x, n) (map PHOTON_LOOKUP_*), a lookup
 * of the precomputed irradiance at y = x, normal n, within radius^2 d2, y's free height h (map
 * LK_SIDE), or one of the build's estimates at a chosen photon (LK_BUILD, free height h). All
 * 4-byte fields: no padding, so queries compare with memcmp. */
typedef struct lk_query {
    float x[3], n[3], h, d2;
    uint32_t map;
} lk_query;
enum { LK_SIDE = 2, LK_BUILD = 3 };

/* One rank's part of one estimate: the fields of a pm_combine_acc that one map adds. */
typedef struct lk_part {
    float power[3], far[3], r2;
    uint16_t found;
    uint16_t paths;     /* the build's estimates: distinct paths among the part's photons, up
                         * to SIDE_MIN_PATHS (side_count_paths; the parts' counts add up, lookup.h) */
    uint8_t rims, wall; /* wall: the precomputed irradiance's search met a wall */
    uint8_t spare[2];   /* zero: every byte sent is set */
} lk_part;

/* The queries of one camera sample, in the order its trace makes them, with their answers once
 * known (see lk_render_tiles). */
enum { LK_HAVE = 1, LK_FOUND = 2, LK_MINE = 4 };
typedef struct lk_rec {
    lk_query *q;
    lk_part *mine;    /* this rank's part, when computed during the trace (LK_MINE) */
    double (*e)[3];   /* the combined answer (LK_HAVE) */
    uint8_t *flags;
    uint32_t n, cap, cursor;
    uint32_t from; /* the first query this trace added (valid when fresh) */
    int fresh;     /* this trace made a query whose answer was not known: its radiance stands
                    * only if every guess equals the answer, else it is traced again */
    uint64_t *counted; /* what that trace added to its thread's counters (taken off meanwhile):
                        * the count n, then n pairs (counter id, amount) */
} lk_rec;

/* A camera sample of the tiles being rendered. */
typedef struct lk_smp {
    uint64_t pixel;
    int k;
    lk_rec *rec; /* NULL: no query yet */
    double L[3];
} lk_smp;

typedef struct lk_pending { /* an answer on its way */
    MPI_Request req;
    void *buf;
} lk_pending;

typedef struct lk_state {
    int rank, size, on;
    MPI_Comm comm;
    const pm_kdtree *trees[2];
    pm_estimate_options opts[2];
    const scene *scene;
    const side_cache *side; /* this rank's part of the precomputed irradiance (NULL: none) */
    const photon_maps *maps; /* the photon mapper's maps (hook_partition): their global_path */
    side_map caus_side;      /* this rank's caustic part's free heights (lk_begin): its estimates
                              * keep to the query's side as side_estimate's (photon_sides.h) */
    int ready; /* the photon mapper handed over its trees (else: not a photon-mapping render) */
    int trace_again; /* PM_MPI_TEST_TRACE_AGAIN=1 (tests): keep no trace made on guesses */
    int done_from; /* DONE notices received */
    lk_pending *pend;
    int npend, cappend;
    int st_queries, st_bytes, st_side_bytes, st_side_queries, st_gather_queries, st_traced,
        st_again, st_more, st_exact, st_rounds, st_nonfinite;
} lk_state;

static lk_state L;
/* The sample a render thread is tracing (lk_render_tiles): where its queries are kept. */
static _Thread_local lk_smp *tl_smp;
static photon_lookup_hook g_hook;

int lk_on(void) { return L.on; }

void lk_idle(void) {
    struct timespec ts = {0, 100000}; /* 0.1 ms */
    nanosleep(&ts, NULL);
}

/* ---- answering from this rank's part ---------------------------------------------------- */

static void part_from_acc(const pm_combine_acc *a, lk_part *p) {
    memset(p, 0, sizeof *p);
    for (int c = 0; c < 3; c++) {
        p->power[c] = (float)a->power[c];
        p->far[c] = (float)a->far_power[c];
    }
    p->r2 = (float)a->r2_sum;
    p->found = (uint16_t)(a->found > 65535 ? 65535 : a->found);
    p->rims = (uint8_t)a->rims;
    p->wall = 0;
}

static void add_part(pm_combine_acc *a, const lk_part *p) {
    for (int c = 0; c < 3; c++) {
        a->power[c] += p->power[c];
        a->far_power[c] += p->far[c];
    }
    a->r2_sum += p->r2;
    a->found += p->found;
    a->rims += p->rims;
    a->maps++;
}

/* Estimates whose filter weighs photons by distance; the others (disc, and the hull and
 * differential filters, which have no combined form here) use the combined disc rule. */
static int filtered_kind(const pm_estimate_options *o) {
    return o->kind == PM_EST_CONE || o->kind == PM_EST_GAUSS;
}

static unsigned per_map(unsigned k) { return k / (unsigned)L.size ? k / (unsigned)L.size : 1; }

/* An estimate's part: the k/M nearest photons of this rank's map, as pm_estimate_combined
 * takes them from each map. */
static void answer_estimate(const lk_query *q, pm_neighbor *nb, lk_part *out) {
    int map = q->map == PHOTON_LOOKUP_CAUSTIC ? PHOTON_LOOKUP_CAUSTIC : PHOTON_LOOKUP_GLOBAL;
    const pm_estimate_options *o = &L.opts[map];
    const pm_kdtree *t = L.trees[map];
    unsigned km = per_map(o->k);
    pm_combine_acc acc;
    pm_combine_init(&acc);
    int found = 0;
    float limit = o->max_dist2; /* the disc the part covers when short of k/M */
    if (t) {
        float nrm[3];
        pm_knn_options ko;
        pm_estimate_search_options(o, q->n, nrm, &ko);
        found = pm_kdtree_knn_ex(t, q->x, km, o->max_dist2, &ko, nb, NULL);
        if (found < 0) found = 0;
        /* The caustic map's part keeps to the query's side, as one process's side_estimate. */
        if (map == PHOTON_LOOKUP_CAUSTIC && L.caus_side.t) {
            found = side_neighbours(&L.caus_side, q->x, q->n, &ko, km, o->max_dist2, nb, found, &limit);
            if (found < 0) dist_die("out of memory answering photon lookups");
        }
    }
    if (filtered_kind(o)) {
        /* The filter's weighted power and its area (pi r_m^2 times the filter's norm), both
         * measured against this part's own radius: E = M sum S_m / sum area_m (combine_one). */
        pm_estimate_options oo = *o;
        oo.k = km;
        oo.max_dist2 = limit;
        pm_estimate_result res;
        double area = 0, S[3] = {0, 0, 0};
        memset(out, 0, sizeof *out);
        if (found > 0 && pm_estimate_core((const pm_photon *)pm_kdtree_records(t), nb, (unsigned)found,
                                          q->x, q->n, &oo, NULL, &res) == PM_OK) {
            if (!(res.flags & PM_EST_F_FAR) && isfinite(res.area)) {
                area = res.area;
                for (int c = 0; c < 3; c++) S[c] = res.rgb[c] * res.area;
                out->rims = !(res.flags & PM_EST_F_RADIUS_LIMIT);
            }
        } else if (found == 0 && isfinite(limit)) {
            area = M_PI * (double)limit *
                   (o->kind == PM_EST_CONE ? pm_cone_norm(o->cone_k) : pm_gauss_norm());
        }
        for (int c = 0; c < 3; c++) out->power[c] = (float)S[c];
        out->r2 = (float)area;
        out->found = (uint16_t)found;
        return;
    }
    pm_combine_add(&acc, t ? (const pm_photon *)pm_kdtree_records(t) : NULL, nb, (unsigned)found,
                   km, limit, o->bias, q->x);
    part_from_acc(&acc, out);
}

/* The combined value of one estimate from the ranks' parts summed in acc: the disc rule of
 * combined.h (pm_combine_finish: one bias correction on the total), or for a cone or
 * Gaussian filter f M sum_m S_m / sum_m A_m, each part weighted against its own radius.
 * Why f: sum_m A_m has the law of one map's area of k photons (combined.h), and inside it
 * the photons other than the rim ones are uniform, of mean weight norm; but each of the
 * `rims` parts has a rim photon of weight w_r (the filter at the rim, halved by the bias
 * rule) where one map has one. So with n photons found in all,
 *     f = ((n - 1) norm + w_r) / ((n - rims) norm + rims w_r)
 * makes the expected weighted sum that of one map of the same n photons (for the default
 * cone, w_r = 0: f = (n - 1)/(n - rims), about (k - 1)/(k - M), 5% at k = 60, M = 4). */
static void combine_one(const pm_estimate_options *o, const pm_combine_acc *acc, double e[3]) {
    if (!filtered_kind(o)) {
        pm_combine_finish(acc, e, NULL);
        return;
    }
    double f = 1.0;
    if (acc->rims > 0 && acc->found > acc->rims) {
        double norm, wr;
        if (o->kind == PM_EST_CONE) {
            norm = pm_cone_norm(o->cone_k);
            wr = 1.0 - 1.0 / o->cone_k;
        } else {
            norm = pm_gauss_norm();
            wr = PM_GAUSS_ALPHA * (1.0 - (1.0 - exp(-PM_GAUSS_BETA / 2.0)) / (1.0 - exp(-PM_GAUSS_BETA)));
        }
        if (o->bias != PM_BIAS_NONE) wr *= 0.5;
        double n = (double)acc->found, rims = (double)acc->rims;
        double den = (n - rims) * norm + rims * wr;
        if (den > 0) f = ((n - 1.0) * norm + wr) / den;
    }
    for (int c = 0; c < 3; c++) {
        double v = acc->r2_sum > 0 ? f * (double)acc->maps * acc->power[c] / acc->r2_sum : 0.0;
        e[c] = isfinite(v) && v > 0 ? v : 0.0;
    }
}

static vec3 v3f(const float f[3]) { return v3(f[0], f[1], f[2]); }

/* A lookup of the precomputed irradiance, this rank's part: the nearest of its records that
 * side_cache_lookup would accept at q (the module's normal and own-radius rules, side_visible
 * from y with y's free height q->h, the 8 nearest candidates of this part), as E in power,
 * its dist2 to y in r2 and found = 1; or found = 0. */
static void answer_lookup(const lk_query *q, lk_part *out) {
    memset(out, 0, sizeof *out);
    if (!L.side) return;
    float e[3], pos[3];
    if (!side_cache_lookup_local(L.side, L.scene, v3f(q->x), v3f(q->n), q->h, q->d2, e, pos)) return;
    double d2 = 0;
    for (int c = 0; c < 3; c++) {
        out->power[c] = e[c];
        d2 += ((double)pos[c] - q->x[c]) * ((double)pos[c] - q->x[c]);
    }
    out->r2 = (float)d2;
    out->found = 1;
}

/* The answer to a lookup of the precomputed irradiance from every rank's part (parts[r *
 * stride]): the nearest record found wins, the lowest rank on a tie. 1 (found) or 0. */
static int combine_lookup(const lk_part *parts, size_t stride, double e[3]) {
    int best = -1;
    for (int r = 0; r < L.size; r++) {
        const lk_part *p = &parts[(size_t)r * stride];
        if (p->found && (best < 0 || p->r2 < parts[(size_t)best * stride].r2)) best = r;
    }
    for (int c = 0; c < 3; c++) e[c] = best < 0 ? 0.0 : parts[(size_t)best * stride].power[c];
    return best >= 0;
}

static void answer_one(const lk_query *q, pm_neighbor *nb, lk_part *out) {
    if (q->map == LK_SIDE)
        answer_lookup(q, out);
    else
        answer_estimate(q, nb, out);
}

/* Answer the n queries q whose have[i] is 0 (all of them when have is NULL), on OpenMP
 * threads, each with its own neighbour buffer. */
static void answer_queries(const lk_query *q, const uint8_t *have, size_t n, lk_part *out) {
    unsigned kmax = per_map(L.opts[0].k) > per_map(L.opts[1].k) ? per_map(L.opts[0].k)
                                                                   : per_map(L.opts[1].k);
    int fail = 0;
#ifdef _OPENMP
#pragma omp parallel reduction(| : fail)
#endif
    {
        pm_neighbor *nb = malloc((size_t)kmax * sizeof *nb);
        if (!nb) fail = 1;
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 64)
#endif
        for (size_t i = 0; i < n; i++)
            if (nb && !(have && have[i])) answer_one(&q[i], nb, &out[i]);
        free(nb);
    }
    if (fail) dist_die("out of memory answering photon lookups");
}

/* ---- messages --------------------------------------------------------------------------- */

static void reap_sent(void) {
    for (int i = 0; i < L.npend;) {
        int flag = 0;
        MPI_Test(&L.pend[i].req, &flag, MPI_STATUS_IGNORE);
        if (flag) {
            free(L.pend[i].buf);
            L.pend[i] = L.pend[--L.npend];
        } else {
            i++;
        }
    }
}

static void send_owned(void *buf, size_t bytes, int to, int tag) {
    if (L.npend == L.cappend) {
        int cap = L.cappend ? 2 * L.cappend : 16;
        lk_pending *p = realloc(L.pend, (size_t)cap * sizeof *p);
        if (!p) dist_die("out of memory in the photon lookups");
        L.pend = p;
        L.cappend = cap;
    }
    if (bytes > (size_t)INT32_MAX) dist_die("a lookup batch exceeds 2 GiB (MPI's int counts)");
    MPI_Isend(buf, (int)bytes, MPI_BYTE, to, tag, L.comm, &L.pend[L.npend].req);
    L.pend[L.npend++].buf = buf;
    stat_add(L.st_bytes, (uint64_t)bytes);
}

int lk_poll(void) {
    reap_sent();
    int flag = 0;
    MPI_Status ms;
    MPI_Iprobe(MPI_ANY_SOURCE, TAG_QUERY, L.comm, &flag, &ms);
    if (flag) {
        int nbytes;
        MPI_Get_count(&ms, MPI_BYTE, &nbytes);
        size_t n = (size_t)nbytes / sizeof(lk_query);
        lk_query *q = malloc(n ? n * sizeof *q : 1);
        lk_part *a = malloc(n ? n * sizeof *a : 1);
        if (!q || !a) dist_die("out of memory answering photon lookups");
        MPI_Recv(q, nbytes, MPI_BYTE, ms.MPI_SOURCE, TAG_QUERY, L.comm, MPI_STATUS_IGNORE);
        answer_queries(q, NULL, n, a);
        free(q);
        send_owned(a, n * sizeof *a, ms.MPI_SOURCE, TAG_ANSWER);
        return 1;
    }
    MPI_Iprobe(MPI_ANY_SOURCE, TAG_DONE, L.comm, &flag, &ms);
    if (flag) {
        MPI_Recv(NULL, 0, MPI_BYTE, ms.MPI_SOURCE, TAG_DONE, L.comm, MPI_STATUS_IGNORE);
        L.done_from++;
        return 1;
    }
    return 0;
}

void lk_finish(int (*also)(void *), void *arg) {
    for (int r = 0; r < L.size; r++)
        if (r != L.rank) MPI_Send(NULL, 0, MPI_BYTE, r, TAG_DONE, L.comm);
    while (L.done_from < L.size - 1) {
        int did = lk_poll();
        if (also) did |= also(arg);
        if (!did) lk_idle();
    }
    while (L.npend > 0) {
        reap_sent();
        if (L.npend > 0) lk_idle();
    }
}

/* The parts of every rank for the n queries q (this rank's are mine): rank r's part of query i
 * at [r n + i] of the array returned (the caller frees it), so that the caller combines them
 * in rank order and a pixel's value does not depend on which answer came first. */
static lk_part *exchange(const lk_query *q, size_t n, const lk_part *mine, int (*also)(void *),
                         void *arg) {
    size_t bytes = n * sizeof *q;
    if (bytes > (size_t)INT32_MAX) dist_die("a lookup batch exceeds 2 GiB (MPI's int counts)");
    MPI_Request *req = malloc((size_t)L.size * sizeof *req);
    lk_part *all = malloc((size_t)L.size * n * sizeof *all);
    if (!req || !all) dist_die("out of memory in the photon lookups");
    memcpy(all + (size_t)L.rank * n, mine, n * sizeof *mine);
    int nreq = 0;
    for (int r = 0; r < L.size; r++)
        if (r != L.rank) {
            MPI_Isend(q, (int)bytes, MPI_BYTE, r, TAG_QUERY, L.comm, &req[nreq++]);
            stat_add(L.st_bytes, (uint64_t)bytes);
        }
    int waiting = L.size - 1;
    while (waiting > 0) {
        int flag = 0;
        MPI_Status ms;
        MPI_Iprobe(MPI_ANY_SOURCE, TAG_ANSWER, L.comm, &flag, &ms);
        if (flag) {
            int nbytes;
            MPI_Get_count(&ms, MPI_BYTE, &nbytes);
            if ((size_t)nbytes != n * sizeof *all) {
                char what[160];
                snprintf(what, sizeof what, "in the photon lookups, rank %d answered %zu lookups "
                         "of %zu", ms.MPI_SOURCE, (size_t)nbytes / sizeof *all, n);
                dist_die(what);
            }
            MPI_Recv(all + (size_t)ms.MPI_SOURCE * n, nbytes, MPI_BYTE, ms.MPI_SOURCE, TAG_ANSWER,
                     L.comm, MPI_STATUS_IGNORE);
            waiting--;
            continue;
        }
        int did = lk_poll();
        if (also) did |= also(arg);
        if (!did) lk_idle();
    }
    MPI_Waitall(nreq, req, MPI_STATUSES_IGNORE);
    free(req);
    return all;
}

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
    lk_smp *sm = tl_smp;
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
    answer_lookup(qq, &r->mine[j]);
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
    q.h = (float)side_free_height(s, v3f(q.x), v3f(q.n), 0.25 * sqrt((double)max_dist2));
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
    L.maps = m; /* the mapper numbers the part's paths when it builds its tree (PHOTON PATHS) */
    pm_photon **arr[2] = {&m->global, &m->caustic};
    size_t *cnt[2] = {&m->nglobal, &m->ncaustic}, all[2] = {m->nglobal, m->ncaustic};
    if (m->part) { /* traced by a partitioned pass: already this rank's part (photon_trace.h) */
        all[0] = m->whole_global;
        all[1] = m->whole_caustic;
    }
    for (int k = 0; k < 2 && !m->part; k++) {
        size_t n = *cnt[k];
        size_t lo = n * (size_t)L.rank / (size_t)L.size, hi = n * (size_t)(L.rank + 1) / (size_t)L.size;
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
           L.rank, m->nglobal, all[0], m->ncaustic, all[1]);
    return 0;
}

static void hook_ready(void *user, const pm_kdtree *const trees[2], const pm_estimate_options opts[2]) {
    (void)user;
    L.ready = 1;
    for (int k = 0; k < 2; k++) {
        L.trees[k] = trees[k];
        L.opts[k] = opts[k];
    }
}

/* ---- precomputed irradiance ------------------------------------------------------------- */

/* This rank's part of the precomputed estimate at query q: its k/M nearest photons on q's side,
 * as side_cache_build takes them (widened past a wall, visible ones only). */
static void answer_side(const scene *s, const pm_kdtree *t, const pm_photon *ph, const uint32_t *path,
                        const float *hfree, unsigned k, float max_dist2, const lk_query *q, pm_neighbor *nb,
                        uint32_t *ids, lk_part *out) {
    unsigned km = per_map(k);
    pm_combine_acc acc;
    pm_combine_init(&acc);
    float hq = q->h;
    vec3 p = v3f(q->x), pn = v3f(q->n);
    int found = 0, wall = 0;
    float limit = max_dist2;
    if (t) {
        float nf[3] = {q->n[0], q->n[1], q->n[2]};
        pm_knn_options ko = {0};
        ko.filter = pm_filter_front;
        ko.filter_user = nf;
        ko.flags = PM_SORT;
        found = pm_kdtree_knn_ex(t, q->x, km, max_dist2, &ko, nb, NULL);
        if (found < 0) found = 0;
        for (int i = 0; i < found && !wall; i++) {
            if (nb[i].dist2 == 0) continue;
            float nq[3];
            pm_normal_decode(ph[nb[i].index].normal, nq);
            if (!side_visible_h(s, p, pn, hq, v3f(ph[nb[i].index].pos), v3f(nq), hfree[nb[i].index]))
                wall = 1;
        }
        if (wall) {
            unsigned want = LK_WIDEN * km;
            int n2 = pm_kdtree_knn_ex(t, q->x, want, max_dist2, &ko, nb, NULL);
            if (n2 < 0) n2 = 0;
            int kept = 0;
            for (int i = 0; i < n2 && (unsigned)kept < km; i++) {
                int vis = 1;
                if (nb[i].dist2 > 0) {
                    float nq[3];
                    pm_normal_decode(ph[nb[i].index].normal, nq);
                    vis = side_visible_h(s, p, pn, hq, v3f(ph[nb[i].index].pos), v3f(nq),
                                         hfree[nb[i].index]);
                }
                if (vis) nb[kept++] = nb[i];
            }
            /* Short of k/M visible ones: the disc is covered up to the last one examined. */
            if ((unsigned)kept < km && (unsigned)n2 == want) limit = nb[n2 - 1].dist2;
            found = kept;
        }
    }
    pm_combine_add(&acc, t ? ph : NULL, nb, (unsigned)found, km, limit, PM_BIAS_AREA, q->x);
    /* The value is the indirect irradiance, as side_cache_build's: direct photons count in
     * the radius (and in the photons found) but not in the power. */
    for (int i = 0; i < found; i++) {
        if (pm_photon_kind(&ph[nb[i].index]) != PM_KIND_DIRECT) continue;
        float pw[3];
        pm_rgbe_decode(ph[nb[i].index].power, pw);
        for (int c = 0; c < 3; c++) acc.power[c] -= pw[c];
    }
    for (int c = 0; c < 3; c++)
        if (acc.power[c] < 0) acc.power[c] = 0;
    part_from_acc(&acc, out);
    out->wall = (uint8_t)wall;
    /* The part's distinct photon paths: a part is a run of the whole map's order (photon_maps.h,
     * PHOTON PATHS), so a path lies in one part, but for the at most M - 1 that straddle two
     * parts' boundaries (counted in both: a few paths too many in a whole map, only near
     * those paths' records). */
    out->paths = (uint16_t)(t ? side_count_paths(path, nb, found, SIDE_MIN_PATHS, ids) : 0);
}

static int side_fail(side_cache *c, char *err, size_t errcap, const char *what) {
    side_cache_free(c);
    snprintf(err, errcap, "precomputing irradiance (partitioned maps): %s", what);
    return PM_ENOMEM;
}

/* The build's collectives, nonblocking on every rank (nonblocking and blocking collectives do
 * not match each other) and waited for with dist_wait: rank 0 hears a rank that failed here
 * (an allocation, its own error) instead of waiting for it in the collective. */
static void ireduce(const unsigned long long *in, unsigned long long *out, MPI_Op op) {
    MPI_Request req;
    MPI_Ireduce(in, out, 1, MPI_UNSIGNED_LONG_LONG, op, 0, MPI_COMM_WORLD, &req);
    dist_wait(&req);
}

static int hook_side_build(void *user, side_cache *c, const scene *s, const pm_kdtree *global,
                           const pm_photon *ph, size_t n, unsigned k, float max_dist2, char *err,
                           size_t errcap) {
    (void)user;
    memset(c, 0, sizeof *c);
    dist_collective_begin();
    int M = L.size;
    uint64_t bytes = 0;
    /* This rank's chosen photons and every photon's free height (photon_sides.c's rules). */
    float *hfree = dist_irr_malloc((n ? n : 1) * sizeof *hfree);
    uint32_t *which = dist_irr_malloc((n ? n : 1) * sizeof *which);
    if (!hfree || !which) dist_die("out of memory precomputing irradiance");
    side_free_heights(s, ph, n, max_dist2, hfree);
    /* The part's path ids, in its tree's order (photon_tree_build_global; NULL if the mapper
     * built the tree without them: every photon then counts as a path of its own). */
    const uint32_t *path = L.maps && L.maps->global == ph ? L.maps->global_path : NULL;
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        if (pm_kdtree_height(global, (uint32_t)i) >= 2) which[m++] = (uint32_t)i;
    lk_query *mine = dist_irr_malloc((m ? m : 1) * sizeof *mine);
    int *cnt = dist_irr_malloc((size_t)M * sizeof *cnt);
    int *dsp = dist_irr_malloc((size_t)M * sizeof *dsp);
    int *cnt2 = dist_irr_malloc((size_t)M * sizeof *cnt2);
    if (!mine || !cnt || !dsp || !cnt2) dist_die("out of memory precomputing irradiance");
    for (size_t j = 0; j < m; j++) {
        const pm_photon *p = &ph[which[j]];
        memset(&mine[j], 0, sizeof mine[j]);
        memcpy(mine[j].x, p->pos, sizeof mine[j].x);
        pm_normal_decode(p->normal, mine[j].n);
        mine[j].h = hfree[which[j]];
        mine[j].map = LK_BUILD;
    }
    /* 1. Every rank's queries to every rank. */
    int mq = (int)m;
    MPI_Request req;
    MPI_Iallgather(&mq, 1, MPI_INT, cnt, 1, MPI_INT, MPI_COMM_WORLD, &req);
    dist_wait(&req);
    long long total = 0;
    for (int r = 0; r < M; r++) total += cnt[r];
    if (total * (long long)sizeof(lk_part) > INT32_MAX)
        dist_die("precomputed irradiance: the queries exceed 2 GiB (MPI's int counts)");
    lk_query *all = dist_irr_malloc((size_t)(total ? total : 1) * sizeof *all);
    lk_part *ans = dist_irr_malloc((size_t)(total ? total : 1) * sizeof *ans);
    lk_part *back = dist_irr_malloc((m ? m : 1) * (size_t)M * sizeof *back);
    if (!all || !ans || !back) dist_die("out of memory precomputing irradiance");
    for (int r = 0, off = 0; r < M; r++) {
        dsp[r] = off * (int)sizeof(lk_query);
        off += cnt[r];
        cnt2[r] = cnt[r] * (int)sizeof(lk_query);
    }
    MPI_Iallgatherv(mine, mq * (int)sizeof(lk_query), MPI_BYTE, all, cnt2, dsp, MPI_BYTE,
                    MPI_COMM_WORLD, &req);
    dist_wait(&req);
    bytes += (uint64_t)m * sizeof(lk_query) * (uint64_t)(M - 1);
    /* 2. This rank's parts of every query. */
    unsigned want = LK_WIDEN * per_map(k);
    int fail = 0;
#ifdef _OPENMP
#pragma omp parallel reduction(| : fail)
#endif
    {
        pm_neighbor *nb = malloc((size_t)want * sizeof *nb);
        uint32_t *ids = malloc(SIDE_MIN_PATHS * sizeof *ids); /* side_count_paths's scratch */
        if (!nb || !ids) fail = 1;
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 64)
#endif
        for (long long i = 0; i < total; i++)
            if (nb && ids) answer_side(s, global, ph, path, hfree, k, max_dist2, &all[i], nb, ids, &ans[i]);
        free(nb);
        free(ids);
    }
    if (fail) dist_die("out of memory precomputing irradiance");
    /* 3. Each owner gets every rank's parts of its queries: rank r's block of ans goes to r. */
    for (int r = 0, off = 0; r < M; r++) {
        cnt2[r] = cnt[r] * (int)sizeof(lk_part);
        dsp[r] = off * (int)sizeof(lk_part);
        off += cnt[r];
    }
    int *rc_ = dist_irr_malloc((size_t)M * sizeof *rc_);
    int *rd = dist_irr_malloc((size_t)M * sizeof *rd);
    if (!rc_ || !rd) dist_die("out of memory precomputing irradiance");
    for (int r = 0; r < M; r++) {
        rc_[r] = mq * (int)sizeof(lk_part);
        rd[r] = r * mq * (int)sizeof(lk_part);
    }
    MPI_Ialltoallv(ans, cnt2, dsp, MPI_BYTE, back, rc_, rd, MPI_BYTE, MPI_COMM_WORLD, &req);
    dist_wait(&req);
    bytes += (uint64_t)(total - mq) * sizeof(lk_part);
    free(ans);
    free(all);
    /* 4. Combine: E of this rank's chosen photons, with the radius^2 of the combined disc. */
    typedef struct side_rec {
        pm_photon p;
        float r2, h;
    } side_rec;
    side_rec *recs = dist_irr_calloc(m ? m : 1, sizeof *recs);
    if (!recs) dist_die("out of memory precomputing irradiance");
    size_t walls = 0, sparse = 0;
#ifdef _OPENMP
#pragma omp parallel for schedule(dynamic, 64) reduction(+ : walls, sparse)
#endif
    for (size_t j = 0; j < m; j++) {
        pm_combine_acc acc;
        pm_combine_init(&acc);
        acc.bias = PM_BIAS_AREA;
        int wall = 0;
        unsigned paths = 0;
        for (int r = 0; r < M; r++) {
            add_part(&acc, &back[(size_t)r * m + j]);
            wall |= back[(size_t)r * m + j].wall;
            paths += back[(size_t)r * m + j].paths;
        }
        double E[3];
        pm_combine_finish(&acc, E, NULL);
        double r2 = acc.r2_sum / M;
        /* Too few photon paths in all the parts: never looked up (photon_sides.h, sparse
         * estimates). */
        int readable = side_estimate_readable(paths);
        if (wall) {
            double frac = side_disc_fraction(s, v3f(mine[j].x), v3f(mine[j].n), sqrt(r2));
            for (int ch = 0; ch < 3; ch++) E[ch] /= frac;
            walls++;
        }
        float ef[3] = {(float)E[0], (float)E[1], (float)E[2]};
        recs[j].p = ph[which[j]];
        pm_rgbe_encode(ef, recs[j].p.power);
        recs[j].r2 = readable ? (float)r2 : 0.0f;
        sparse += !readable;
        recs[j].h = hfree[which[j]];
    }
    free(back);
    free(mine);
    free(which);
    free(hfree);
    /* 5. This rank keeps its own records (lookups ask every rank: side_remote). A rank with
     * none keeps one that no lookup accepts (radius 0), so that the mapper, which looks up
     * only where a cache exists, asks the others too. */
    free(cnt);
    free(dsp);
    free(cnt2);
    free(rc_);
    free(rd);
    size_t N = m ? m : (total ? 1 : 0);
    pm_photon *rp = dist_irr_malloc((N ? N : 1) * sizeof *rp);
    float *r2 = dist_irr_malloc((N ? N : 1) * sizeof *r2);
    float *hf = dist_irr_malloc((N ? N : 1) * sizeof *hf);
    if (!rp || !r2 || !hf) {
        free(rp);
        free(r2);
        free(hf);
        free(recs);
        return side_fail(c, err, errcap, "out of memory");
    }
    for (size_t i = 0; i < m; i++) {
        rp[i] = recs[i].p;
        r2[i] = recs[i].r2;
        hf[i] = recs[i].h;
    }
    if (m == 0 && N) {
        memset(rp, 0, sizeof *rp);
        r2[0] = hf[0] = 0;
    }
    free(recs);
    int rc = side_cache_from_records(c, rp, r2, hf, N, err, errcap);
    free(rp);
    free(r2);
    free(hf);
    if (rc < 0) return rc;
    c->n = (size_t)total; /* the records of all ranks, as side_cache_build's count */
    c->remote = side_remote;
    L.side = c;
    L.scene = s;
    if (total > 0) {
        /* The cache's own bytes: the module's records, radii, indices and lookup tree, and a
         * free height per record. All parts together are about what every rank held when
         * each built the whole cache. */
        unsigned long long here = m, most = 0, least = 0;
        unsigned long long cb = (unsigned long long)(pm_irradiance_bytes(c->irr) + N * sizeof(float));
        unsigned long long cmax = 0, csum = 0;
        ireduce(&here, &most, MPI_MAX);
        ireduce(&here, &least, MPI_MIN);
        ireduce(&cb, &cmax, MPI_MAX);
        ireduce(&cb, &csum, MPI_SUM);
        if (L.rank == 0)
            printf("MPI: partitioned precomputed irradiance: each rank keeps its own records, "
                   "%llu to %llu of %lld (at most %llu bytes on a rank, %llu on all); lookups ask "
                   "every rank\n", least, most, total, cmax, csum);
    }
    unsigned long long w = walls, wsum = 0, b = bytes, bsum = 0, sp = sparse, spsum = 0;
    ireduce(&w, &wsum, MPI_SUM);
    ireduce(&sp, &spsum, MPI_SUM);
    c->sparse = (size_t)spsum;
    c->indirect_only = 1; /* the mapper adds a gather hit's direct light itself */
    ireduce(&b, &bsum, MPI_SUM);
    c->researched = (size_t)wsum;
    if (L.rank == 0) {
        stat_add(L.st_side_bytes, bsum);
        stat_add(L.st_side_queries, (uint64_t)total);
    }
    return 0;
}

/* ---- the tiles ------------------------------------------------------------------------------ */

static void rec_free(lk_rec *r) {
    if (!r) return;
    free(r->q);
    free(r->mine);
    free(r->e);
    free(r->flags);
    free(r->counted);
    free(r);
}

/* Trace the camera samples smp[idx[0..n)] on the job's threads, each from its start, exactly as
 * renderer.c's render_tile traces sample k of a pixel (its random stream, jitter, camera ray).
 * A trace that made a query not answered before (rec->fresh) ran on guesses: the counters it
 * added on its thread are taken off and kept in rec->counted, to be added back if every guess
 * turns out to be the answer (its radiance is then the sample's), so the statistics count
 * the one trace of each sample that is kept. */
static void trace_samples(const scene *s, const integrator *it, const render_job *job, lk_smp *smp,
                          const uint32_t *idx, size_t n) {
    const camera *c = &s->cam;
    int strata = c->strata;
#ifdef _OPENMP
    int nthreads = job->threads > 0 ? job->threads : omp_get_max_threads();
#pragma omp parallel num_threads(nthreads)
#endif
    {
        void *scratch = it->thread_begin ? it->thread_begin(it) : NULL;
        uint64_t *cnt = stats__local ? stats__local : stats__attach();
        uint64_t snap[STATS_MAX];
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 16)
#endif
        for (size_t i = 0; i < n; i++) {
            lk_smp *sm = &smp[idx[i]];
            if (sm->rec) {
                sm->rec->cursor = 0;
                sm->rec->fresh = 0;
            }
            memcpy(snap, cnt, sizeof snap);
            int x = (int)(sm->pixel % (uint64_t)c->width), y = (int)(sm->pixel / (uint64_t)c->width);
            rng g = rng_stream(job->seed, sm->pixel, (uint64_t)sm->k);
            double jx = rng_uniform(&g), jy = rng_uniform(&g);
            double px = x + ((sm->k % strata) + jx) / strata, py = y + ((sm->k / strata) + jy) / strata;
            ray r = camera_ray(c, px, py);
            sample_id id = {sm->pixel, job->seed, sm->k, c->spp, strata};
            tl_smp = sm;
            rgb Li = it->li(it, s, r, &g, &id, scratch);
            tl_smp = NULL;
            sm->L[0] = Li.x;
            sm->L[1] = Li.y;
            sm->L[2] = Li.z;
            if (sm->rec && sm->rec->fresh) {
                lk_rec *rec = sm->rec;
                uint64_t nz = 0;
                for (int c_ = 0; c_ < STATS_MAX; c_++) nz += cnt[c_] != snap[c_];
                free(rec->counted);
                if (!(rec->counted = malloc((1 + 2 * nz) * sizeof *rec->counted)))
                    dist_die("out of memory recording photon lookups");
                rec->counted[0] = nz;
                for (int c_ = 0, o_ = 1; c_ < STATS_MAX; c_++)
                    if (cnt[c_] != snap[c_]) {
                        rec->counted[o_++] = (uint64_t)c_;
                        rec->counted[o_++] = cnt[c_] - snap[c_];
                    }
                memcpy(cnt, snap, sizeof snap);
            }
        }
        if (it->thread_end) it->thread_end(it, scratch);
    }
}


typedef struct lk_count {
    uint64_t traced, again, more, rounds, nest, nlook, exact;
} lk_count;

/* Samples per block of lk_render_tiles. */
#define LK_BLOCK 8192

/* Render the ns samples smp[0..ns) to their radiance (idx: room for ns indices). */
static void render_block(const scene *s, const integrator *it, const render_job *job, lk_smp *smp,
                         size_t ns, uint32_t *idx, int (*also)(void *), void *arg, lk_count *cn) {
    /* Trace; the samples that made queries not answered yet get them answered by every rank in
     * one exchange, and are traced again; until every sample's trace read answers only. */
    size_t np = ns;
    for (size_t i = 0; i < ns; i++) idx[i] = (uint32_t)i;
    uint64_t rounds = 0;
    for (;;) {
        trace_samples(s, it, job, smp, idx, np);
        cn->traced += np;
        if (rounds == 1) cn->again += np;
        if (rounds >= 2) cn->more += np;
        size_t keep = 0, nq = 0;
        for (size_t i = 0; i < np; i++) {
            lk_rec *r = smp[idx[i]].rec;
            if (r && r->fresh) {
                idx[keep++] = idx[i];
                nq += r->n - r->from;
            }
        }
        np = keep;
        if (np == 0) break;
        rounds++;
        cn->rounds++;
        lk_query *q = malloc(nq * sizeof *q);
        lk_part *mine = malloc(nq * sizeof *mine);
        uint8_t *have = malloc(nq);
        if (!q || !mine || !have) dist_die("out of memory in the photon lookups");
        size_t o = 0;
        for (size_t i = 0; i < np; i++) {
            lk_rec *r = smp[idx[i]].rec;
            for (uint32_t j = r->from; j < r->n; j++, o++) {
                q[o] = r->q[j];
                have[o] = (r->flags[j] & LK_MINE) != 0;
                if (have[o]) mine[o] = r->mine[j];
                if (q[o].map == LK_SIDE)
                    cn->nlook++;
                else
                    cn->nest++;
            }
        }
        /* this rank's parts not computed during the trace */
        answer_queries(q, have, nq, mine);
        lk_part *all = exchange(q, nq, mine, also, arg);
        o = 0;
        for (size_t i = 0; i < np; i++) {
            lk_rec *r = smp[idx[i]].rec;
            for (uint32_t j = r->from; j < r->n; j++, o++) {
                int found = 0;
                if (q[o].map == LK_SIDE) {
                    found = combine_lookup(&all[o], nq, r->e[j]);
                } else {
                    const pm_estimate_options *opt = &L.opts[q[o].map == PHOTON_LOOKUP_CAUSTIC];
                    pm_combine_acc acc;
                    pm_combine_init(&acc);
                    acc.bias = opt->bias;
                    for (int rk = 0; rk < L.size; rk++) add_part(&acc, &all[(size_t)rk * nq + o]);
                    combine_one(opt, &acc, r->e[j]);
                }
                r->flags[j] = (uint8_t)(LK_HAVE | (found ? LK_FOUND : 0));
            }
        }
        /* A sample whose every guess was the answer (a lookup that this rank's own records
         * answered as all ranks do, found or not; an estimate that is 0) was traced exactly as
         * the next trace would trace it: keep that trace (its radiance and counters). */
        size_t left = 0;
        for (size_t i = 0; i < np; i++) {
            lk_rec *r = smp[idx[i]].rec;
            int exact = 1;
            for (uint32_t j = r->from; j < r->n && exact; j++) {
                const double *e = r->e[j];
                if (r->q[j].map == LK_SIDE) {
                    const lk_part *g = &r->mine[j];
                    int found = (r->flags[j] & LK_FOUND) != 0;
                    exact = found == (g->found != 0) &&
                            (!found || (e[0] == g->power[0] && e[1] == g->power[1] && e[2] == g->power[2]));
                } else {
                    exact = e[0] == 0 && e[1] == 0 && e[2] == 0;
                }
            }
            if (exact && !L.trace_again) {
                for (uint64_t c_ = 0; c_ < r->counted[0]; c_++)
                    stat_add((int)r->counted[1 + 2 * c_], r->counted[2 + 2 * c_]);
                cn->exact++;
            } else {
                idx[left++] = idx[i];
            }
        }
        np = left;
        free(all);
        free(have);
        free(mine);
        free(q);
    }
    for (size_t i = 0; i < ns; i++) {
        rec_free(smp[i].rec);
        smp[i].rec = NULL;
    }
}

void lk_begin(const scene *s) {
    if (!L.ready || L.caus_side.t || !L.trees[PHOTON_LOOKUP_CAUSTIC]) return;
    char err[128];
    const pm_kdtree *t = L.trees[PHOTON_LOOKUP_CAUSTIC];
    if (side_map_init(&L.caus_side, s, t, pm_kdtree_size(t), L.opts[PHOTON_LOOKUP_CAUSTIC].max_dist2, err,
                      sizeof err) < 0)
        dist_die(err);
}

int lk_render_tiles(const scene *s, const integrator *it, const render_job *job, render_state *st,
                    const int *tiles, int n, int (*also)(void *), void *arg) {
    const camera *c = &s->cam;
    if (!L.ready) return render_tiles(s, it, job, st, tiles, n); /* no photon maps to look up */
    if (st->width != c->width || st->height != c->height || st->spp != c->spp) return PM_EINVAL;
    int tiles_x = (c->width + RENDER_TILE - 1) / RENDER_TILE;
    int ntiles = tiles_x * ((c->height + RENDER_TILE - 1) / RENDER_TILE);
    for (int i = 0; i < n; i++)
        if (tiles[i] < 0 || tiles[i] >= ntiles) return PM_EINVAL;
    /* The samples still to do, tile by tile, pixel by pixel, in sample order, a block at a
     * time (the queries of a whole chunk at many samples per pixel would take gigabytes). */
    lk_smp *smp = calloc(LK_BLOCK, sizeof *smp);
    uint32_t *idx = malloc(LK_BLOCK * sizeof *idx);
    if (!smp || !idx) dist_die("out of memory in the photon lookups");
    lk_count cn = {0, 0, 0, 0, 0, 0, 0};
    uint64_t bad = 0, ns = 0;
    int ti = 0, px = 0, k = -1; /* the next sample: tile ti, its pixel px, sample k (-1: start) */
    for (;;) {
        size_t m = 0;
        while (m < LK_BLOCK && ti < n) {
            int x0 = (tiles[ti] % tiles_x) * RENDER_TILE, y0 = (tiles[ti] / tiles_x) * RENDER_TILE;
            int w = c->width - x0 < RENDER_TILE ? c->width - x0 : RENDER_TILE;
            int h = c->height - y0 < RENDER_TILE ? c->height - y0 : RENDER_TILE;
            if (px >= w * h) {
                ti++;
                px = 0;
                k = -1;
                continue;
            }
            uint64_t p = (uint64_t)(y0 + px / w) * (uint64_t)c->width + (uint64_t)(x0 + px % w);
            if (k < 0) k = (int)st->count[p];
            if (k >= c->spp) {
                px++;
                k = -1;
                continue;
            }
            smp[m].pixel = p;
            smp[m].k = k++;
            smp[m].rec = NULL;
            m++;
        }
        if (m == 0) break;
        render_block(s, it, job, smp, m, idx, also, arg, &cn);
        /* Each pixel's samples in sample order, as render_tile adds them. */
        for (size_t i = 0; i < m; i++) {
            lk_smp *sm = &smp[i];
            double *sum = st->sum + 3 * sm->pixel;
            if (isfinite(sm->L[0]) && isfinite(sm->L[1]) && isfinite(sm->L[2])) {
                sum[0] += sm->L[0];
                sum[1] += sm->L[1];
                sum[2] += sm->L[2];
            } else {
                bad++;
            }
            st->count[sm->pixel] = (uint32_t)sm->k + 1;
        }
        ns += m;
    }
    stat_add(STAT_CAMERA_RAYS, ns);
    stat_add(STAT_SAMPLES, ns);
    if (bad) stat_add(L.st_nonfinite, bad);
    stat_add(L.st_queries, cn.nest + cn.nlook);
    stat_add(L.st_gather_queries, cn.nlook);
    stat_add(L.st_traced, cn.traced);
    stat_add(L.st_again, cn.again);
    stat_add(L.st_more, cn.more);
    stat_add(L.st_rounds, cn.rounds);
    stat_add(L.st_exact, cn.exact);
    free(idx);
    free(smp);
    return 0;
}

void lk_init(int rank, int size, MPI_Comm comm) {
    memset(&L, 0, sizeof L);
    L.rank = rank;
    L.size = size;
    L.on = 1;
    const char *ta = getenv("PM_MPI_TEST_TRACE_AGAIN");
    L.trace_again = ta && strcmp(ta, "1") == 0;
    L.comm = comm;
    L.st_queries = stats_register("MPI/Partitioned: photon lookups sent (all ranks)");
    L.st_bytes = stats_register("MPI/Partitioned: bytes sent in photon lookups (all ranks)");
    L.st_side_queries = stats_register("MPI/Partitioned: precomputed irradiance estimates");
    L.st_side_bytes = stats_register("MPI/Partitioned: bytes sent precomputing irradiance (all ranks)");
    L.st_gather_queries = stats_register("MPI/Partitioned: precomputed irradiance lookups sent (all ranks)");
    L.st_traced = stats_register("MPI/Partitioned: camera sample traces (all ranks)");
    L.st_again = stats_register("MPI/Partitioned: camera samples traced twice or more (all ranks)");
    L.st_more = stats_register("MPI/Partitioned: camera sample traces past the second (all ranks)");
    L.st_rounds = stats_register("MPI/Partitioned: lookup exchanges of chunks (all ranks)");
    L.st_exact = stats_register("MPI/Partitioned: samples kept from a trace on guesses (all ranks)");
    L.st_nonfinite = stats_register("Film/Non-finite samples");
    g_hook.partition = hook_partition;
    g_hook.side_build = hook_side_build;
    g_hook.ready = hook_ready;
    g_hook.estimate = hook_estimate;
    g_hook.user = NULL;
    photon_lookup_set_hook(&g_hook);
}
