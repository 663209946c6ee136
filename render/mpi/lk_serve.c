/* lk_serve.c: this rank's side of the partitioned lookups (lookup.h): its part of every query
 * (an estimate from its part of a map, a lookup of its part of the precomputed irradiance), the
 * combination of the ranks' parts, and the messages.
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
#include "lk_serve.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "lookup.h"
#include "ranks.h"
#include "photonmap/common.h"
#include "base/stats.h"

enum { TAG_QUERY = 201, TAG_ANSWER, TAG_DONE };

lk_state lk;

void lk_idle(void) {
    struct timespec ts = {0, 100000}; /* 0.1 ms */
    nanosleep(&ts, NULL);
}

/* ---- answering from this rank's part ---------------------------------------------------- */

void lk_part_from_acc(const pm_combine_acc *a, lk_part *p) {
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

void lk_add_part(pm_combine_acc *a, const lk_part *p) {
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

unsigned lk_per_map(unsigned k) { return k / (unsigned)lk.size ? k / (unsigned)lk.size : 1; }

/* An estimate's part: the k/M nearest photons of this rank's map, as pm_estimate_combined
 * takes them from each map. */
static void answer_estimate(const lk_query *q, pm_neighbor *nb, lk_part *out) {
    int map = q->map == PHOTON_LOOKUP_CAUSTIC ? PHOTON_LOOKUP_CAUSTIC : PHOTON_LOOKUP_GLOBAL;
    const pm_estimate_options *o = &lk.opts[map];
    const pm_kdtree *t = lk.trees[map];
    unsigned km = lk_per_map(o->k);
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
        if (map == PHOTON_LOOKUP_CAUSTIC && lk.caus_side.t) {
            found = side_neighbours(&lk.caus_side, q->x, q->n, &ko, km, o->max_dist2, nb, found, &limit);
            if (found < 0) dist_die("out of memory answering photon lookups");
        }
    }
    if (filtered_kind(o)) {
        /* The filter's weighted power and its area (pi r_m^2 times the filter's norm), both
         * measured against this part's own radius: E = M sum S_m / sum area_m (lk_combine_one). */
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
    lk_part_from_acc(&acc, out);
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
void lk_combine_one(const pm_estimate_options *o, const pm_combine_acc *acc, double e[3]) {
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

/* A lookup of the precomputed irradiance, this rank's part: the nearest of its records that
 * side_cache_lookup would accept at q (the module's normal and own-radius rules, side_visible
 * from y with y's free height q->h, the 8 nearest candidates of this part), as E in power,
 * its dist2 to y in r2 and found = 1; or found = 0. */
void lk_answer_lookup(const lk_query *q, lk_part *out) {
    memset(out, 0, sizeof *out);
    if (!lk.side) return;
    float e[3], pos[3];
    if (!side_cache_lookup_local(lk.side, lk.scene, lk_v3f(q->x), lk_v3f(q->n), q->h, q->d2, e, pos)) return;
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
int lk_combine_lookup(const lk_part *parts, size_t stride, double e[3]) {
    int best = -1;
    for (int r = 0; r < lk.size; r++) {
        const lk_part *p = &parts[(size_t)r * stride];
        if (p->found && (best < 0 || p->r2 < parts[(size_t)best * stride].r2)) best = r;
    }
    for (int c = 0; c < 3; c++) e[c] = best < 0 ? 0.0 : parts[(size_t)best * stride].power[c];
    return best >= 0;
}

static void answer_one(const lk_query *q, pm_neighbor *nb, lk_part *out) {
    if (q->map == LK_SIDE)
        lk_answer_lookup(q, out);
    else
        answer_estimate(q, nb, out);
}

/* Answer the n queries q whose have[i] is 0 (all of them when have is NULL), on OpenMP
 * threads, each with its own neighbour buffer. */
void lk_answer_queries(const lk_query *q, const uint8_t *have, size_t n, lk_part *out) {
    unsigned kmax = lk_per_map(lk.opts[0].k) > lk_per_map(lk.opts[1].k) ? lk_per_map(lk.opts[0].k)
                                                                   : lk_per_map(lk.opts[1].k);
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
    for (int i = 0; i < lk.npend;) {
        int flag = 0;
        MPI_Test(&lk.pend[i].req, &flag, MPI_STATUS_IGNORE);
        if (flag) {
            free(lk.pend[i].buf);
            lk.pend[i] = lk.pend[--lk.npend];
        } else {
            i++;
        }
    }
}

static void send_owned(void *buf, size_t bytes, int to, int tag) {
    if (lk.npend == lk.cappend) {
        int cap = lk.cappend ? 2 * lk.cappend : 16;
        lk_pending *p = realloc(lk.pend, (size_t)cap * sizeof *p);
        if (!p) dist_die("out of memory in the photon lookups");
        lk.pend = p;
        lk.cappend = cap;
    }
    if (bytes > (size_t)INT32_MAX) dist_die("a lookup batch exceeds 2 GiB (MPI's int counts)");
    MPI_Isend(buf, (int)bytes, MPI_BYTE, to, tag, lk.comm, &lk.pend[lk.npend].req);
    lk.pend[lk.npend++].buf = buf;
    stat_add(lk.st_bytes, (uint64_t)bytes);
}

/* A message with this tag waiting on the lookups' communicator: 1, with *ms and its size in
 * bytes; else 0. */
static int waiting_message(int tag, MPI_Status *ms, int *nbytes) {
    int flag = 0;
    MPI_Iprobe(MPI_ANY_SOURCE, tag, lk.comm, &flag, ms);
    if (flag) MPI_Get_count(ms, MPI_BYTE, nbytes);
    return flag;
}

int lk_poll(void) {
    reap_sent();
    MPI_Status ms;
    int nbytes;
    if (waiting_message(TAG_QUERY, &ms, &nbytes)) {
        size_t n = (size_t)nbytes / sizeof(lk_query);
        lk_query *q = malloc(n ? n * sizeof *q : 1);
        lk_part *a = malloc(n ? n * sizeof *a : 1);
        if (!q || !a) dist_die("out of memory answering photon lookups");
        MPI_Recv(q, nbytes, MPI_BYTE, ms.MPI_SOURCE, TAG_QUERY, lk.comm, MPI_STATUS_IGNORE);
        lk_answer_queries(q, NULL, n, a);
        free(q);
        send_owned(a, n * sizeof *a, ms.MPI_SOURCE, TAG_ANSWER);
        return 1;
    }
    if (waiting_message(TAG_DONE, &ms, &nbytes)) {
        MPI_Recv(NULL, 0, MPI_BYTE, ms.MPI_SOURCE, TAG_DONE, lk.comm, MPI_STATUS_IGNORE);
        lk.done_from++;
        return 1;
    }
    return 0;
}

void lk_finish(int (*also)(void *), void *arg) {
    for (int r = 0; r < lk.size; r++)
        if (r != lk.rank) MPI_Send(NULL, 0, MPI_BYTE, r, TAG_DONE, lk.comm);
    while (lk.done_from < lk.size - 1) {
        int did = lk_poll();
        if (also) did |= also(arg);
        if (!did) lk_idle();
    }
    while (lk.npend > 0) {
        reap_sent();
        if (lk.npend > 0) lk_idle();
    }
}

/* The parts of every rank for the n queries q (this rank's are mine): rank r's part of query i
 * at [r n + i] of the array returned (the caller frees it), so that the caller combines them
 * in rank order and a pixel's value does not depend on which answer came first. */
lk_part *lk_exchange(const lk_query *q, size_t n, const lk_part *mine, int (*also)(void *), void *arg) {
    size_t bytes = n * sizeof *q;
    if (bytes > (size_t)INT32_MAX) dist_die("a lookup batch exceeds 2 GiB (MPI's int counts)");
    MPI_Request *req = malloc((size_t)lk.size * sizeof *req);
    lk_part *all = malloc((size_t)lk.size * n * sizeof *all);
    if (!req || !all) dist_die("out of memory in the photon lookups");
    memcpy(all + (size_t)lk.rank * n, mine, n * sizeof *mine);
    int nreq = 0;
    for (int r = 0; r < lk.size; r++)
        if (r != lk.rank) {
            MPI_Isend(q, (int)bytes, MPI_BYTE, r, TAG_QUERY, lk.comm, &req[nreq++]);
            stat_add(lk.st_bytes, (uint64_t)bytes);
        }
    int waiting = lk.size - 1;
    while (waiting > 0) {
        MPI_Status ms;
        int nbytes;
        if (waiting_message(TAG_ANSWER, &ms, &nbytes)) {
            if ((size_t)nbytes != n * sizeof *all) {
                char what[160];
                snprintf(what, sizeof what, "in the photon lookups, rank %d answered %zu lookups "
                         "of %zu", ms.MPI_SOURCE, (size_t)nbytes / sizeof *all, n);
                dist_die(what);
            }
            MPI_Recv(all + (size_t)ms.MPI_SOURCE * n, nbytes, MPI_BYTE, ms.MPI_SOURCE, TAG_ANSWER,
                     lk.comm, MPI_STATUS_IGNORE);
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
