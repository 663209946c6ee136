/* lookup.c: partitioned photon maps across the ranks of render-mpi; lookup.h says how it works.
 *
 * Messages of the pixel pass, on a communicator of their own (so that rank 0's tile queue on
 * MPI_COMM_WORLD never sees them):
 *   QUERY   owner -> every other rank   n lk_query records (28 bytes each)
 *   ANSWER  rank -> owner               n lk_part records (32 bytes each), in query order
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

#include "dist.h"
#include "photon_lookup.h"
#include "photonmap/combined.h"
#include "photonmap/common.h"
#include "stats.h"

#ifdef _OPENMP
#include <omp.h>
#endif

enum { TAG_QUERY = 201, TAG_ANSWER, TAG_DONE };
/* Candidates examined by an estimate that meets a wall, as a multiple of its k (photon_sides.c). */
#define LK_WIDEN 4

typedef struct lk_query {
    float x[3], n[3];
    uint32_t map; /* PHOTON_LOOKUP_*; the precomputed irradiance: the free height's bits */
} lk_query;

/* One rank's part of one estimate: the fields of a pm_combine_acc that one map adds. */
typedef struct lk_part {
    float power[3], far[3], r2;
    uint16_t found;
    uint8_t rims, wall; /* wall: the precomputed irradiance's search met a wall */
} lk_part;

typedef struct lk_tile {
    lk_query *q;
    double (*e)[3];
    size_t n, cap, cursor;
    int bad; /* the replay asked for another query than the recording */
} lk_tile;

typedef struct lk_pending { /* an answer on its way */
    MPI_Request req;
    void *buf;
} lk_pending;

typedef struct lk_state {
    int rank, size, on;
    MPI_Comm comm;
    const pm_kdtree *trees[2];
    pm_estimate_options opts[2];
    int width, tiles_x, ntiles;
    lk_tile *tiles;
    int mode;  /* 0: record, 1: replay */
    int ready; /* the photon mapper handed over its trees (else: not a photon-mapping render) */
    int done_from; /* DONE notices received */
    lk_pending *pend;
    int npend, cappend;
    int st_queries, st_bytes, st_side_bytes, st_side_queries;
} lk_state;

static lk_state L;
static photon_lookup_hook g_hook;

int lk_on(void) { return L.on; }

void lk_idle(void) {
    struct timespec ts = {0, 100000}; /* 0.1 ms */
    nanosleep(&ts, NULL);
}

/* ---- answering from this rank's part ---------------------------------------------------- */

static void part_from_acc(const pm_combine_acc *a, lk_part *p) {
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
    if (t) {
        float nrm[3];
        pm_knn_options ko;
        pm_estimate_search_options(o, q->n, nrm, &ko);
        found = pm_kdtree_knn_ex(t, q->x, km, o->max_dist2, &ko, nb, NULL);
        if (found < 0) found = 0;
    }
    if (filtered_kind(o)) {
        /* The filter's weighted power and its area (pi r_m^2 times the filter's norm), both
         * measured against this part's own radius: E = M sum S_m / sum area_m (combine_one). */
        pm_estimate_options oo = *o;
        oo.k = km;
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
        } else if (found == 0 && isfinite(o->max_dist2)) {
            area = M_PI * (double)o->max_dist2 *
                   (o->kind == PM_EST_CONE ? pm_cone_norm(o->cone_k) : pm_gauss_norm());
        }
        for (int c = 0; c < 3; c++) out->power[c] = (float)S[c];
        out->r2 = (float)area;
        out->found = (uint16_t)found;
        return;
    }
    pm_combine_add(&acc, t ? (const pm_photon *)pm_kdtree_records(t) : NULL, nb, (unsigned)found,
                   km, o->max_dist2, o->bias, q->x);
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

/* Answer n queries (OpenMP threads, each with its own neighbour buffer). */
static void answer_all(const lk_query *q, size_t n, lk_part *out) {
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
            if (nb) answer_estimate(&q[i], nb, &out[i]);
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
        answer_all(q, n, a);
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

/* The parts of every rank for the n queries q (this rank's are mine), added into acc[0..n)
 * in rank order, so that a pixel's value does not depend on which answer came first. */
static void exchange(const lk_query *q, size_t n, const lk_part *mine, pm_combine_acc *acc,
                     int (*also)(void *), void *arg) {
    if (n == 0) return;
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
            if ((size_t)nbytes != n * sizeof *all) dist_die("a rank answered another number of lookups");
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
    for (int r = 0; r < L.size; r++)
        for (size_t i = 0; i < n; i++) add_part(&acc[i], &all[(size_t)r * n + i]);
    free(req);
    free(all);
}

/* ---- the hook ----------------------------------------------------------------------------- */

static void hook_estimate(void *user, const sample_id *id, int map, vec3 x, vec3 n, double e[3]) {
    (void)user;
    e[0] = e[1] = e[2] = 0;
    if (!id || !L.tiles) {
        dist_die("a photon estimate outside a tile of a partitioned render");
        return;
    }
    int px = (int)(id->pixel % (uint64_t)L.width), py = (int)(id->pixel / (uint64_t)L.width);
    lk_tile *t = &L.tiles[(py / RENDER_TILE) * L.tiles_x + px / RENDER_TILE];
    lk_query q;
    memset(&q, 0, sizeof q);
    q.x[0] = (float)x.x, q.x[1] = (float)x.y, q.x[2] = (float)x.z;
    q.n[0] = (float)n.x, q.n[1] = (float)n.y, q.n[2] = (float)n.z;
    q.map = (uint32_t)map;
    if (L.mode == 0) {
        if (t->n == t->cap) {
            size_t cap = t->cap ? 2 * t->cap : 256;
            lk_query *nq = realloc(t->q, cap * sizeof *nq);
            if (!nq) {
                t->bad = 2;
                return;
            }
            t->q = nq;
            t->cap = cap;
        }
        t->q[t->n++] = q;
        return;
    }
    if (t->cursor >= t->n || memcmp(&t->q[t->cursor], &q, sizeof q) != 0) {
        t->bad = 1;
        return;
    }
    memcpy(e, t->e[t->cursor++], sizeof t->e[0]);
}

static int hook_partition(void *user, photon_maps *m, char *err, size_t errcap) {
    (void)user;
    (void)err;
    (void)errcap;
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

static vec3 v3f(const float f[3]) { return v3(f[0], f[1], f[2]); }

/* This rank's part of the precomputed estimate at query q: its k/M nearest photons on q's side,
 * as side_cache_build takes them (widened past a wall, visible ones only). */
static void answer_side(const scene *s, const pm_kdtree *t, const pm_photon *ph, const float *hfree,
                        unsigned k, float max_dist2, const lk_query *q, pm_neighbor *nb, lk_part *out) {
    unsigned km = per_map(k);
    pm_combine_acc acc;
    pm_combine_init(&acc);
    float hq;
    memcpy(&hq, &q->map, sizeof hq);
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
}

static int side_fail(side_cache *c, char *err, size_t errcap, const char *what) {
    side_cache_free(c);
    snprintf(err, errcap, "precomputing irradiance (partitioned maps): %s", what);
    return PM_ENOMEM;
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
    float *hfree = malloc((n ? n : 1) * sizeof *hfree);
    uint32_t *which = malloc((n ? n : 1) * sizeof *which);
    if (!hfree || !which) dist_die("out of memory precomputing irradiance");
    side_free_heights(s, ph, n, max_dist2, hfree);
    size_t m = 0;
    for (size_t i = 0; i < n; i++)
        if (pm_kdtree_height(global, (uint32_t)i) >= 2) which[m++] = (uint32_t)i;
    lk_query *mine = malloc((m ? m : 1) * sizeof *mine);
    int *cnt = malloc((size_t)M * sizeof *cnt), *dsp = malloc((size_t)M * sizeof *dsp);
    int *cnt2 = malloc((size_t)M * sizeof *cnt2);
    if (!mine || !cnt || !dsp || !cnt2) dist_die("out of memory precomputing irradiance");
    for (size_t j = 0; j < m; j++) {
        const pm_photon *p = &ph[which[j]];
        memcpy(mine[j].x, p->pos, sizeof mine[j].x);
        pm_normal_decode(p->normal, mine[j].n);
        memcpy(&mine[j].map, &hfree[which[j]], sizeof(float));
    }
    /* 1. Every rank's queries to every rank. */
    int mq = (int)m;
    MPI_Allgather(&mq, 1, MPI_INT, cnt, 1, MPI_INT, MPI_COMM_WORLD);
    long long total = 0;
    for (int r = 0; r < M; r++) total += cnt[r];
    if (total * (long long)sizeof(lk_part) > INT32_MAX)
        dist_die("precomputed irradiance: the queries exceed 2 GiB (MPI's int counts)");
    lk_query *all = malloc((size_t)(total ? total : 1) * sizeof *all);
    lk_part *ans = malloc((size_t)(total ? total : 1) * sizeof *ans);
    lk_part *back = malloc((m ? m : 1) * (size_t)M * sizeof *back);
    if (!all || !ans || !back) dist_die("out of memory precomputing irradiance");
    for (int r = 0, off = 0; r < M; r++) {
        dsp[r] = off * (int)sizeof(lk_query);
        off += cnt[r];
        cnt2[r] = cnt[r] * (int)sizeof(lk_query);
    }
    MPI_Allgatherv(mine, mq * (int)sizeof(lk_query), MPI_BYTE, all, cnt2, dsp, MPI_BYTE, MPI_COMM_WORLD);
    bytes += (uint64_t)m * sizeof(lk_query) * (uint64_t)(M - 1);
    /* 2. This rank's parts of every query. */
    unsigned want = LK_WIDEN * per_map(k);
    int fail = 0;
#ifdef _OPENMP
#pragma omp parallel reduction(| : fail)
#endif
    {
        pm_neighbor *nb = malloc((size_t)want * sizeof *nb);
        if (!nb) fail = 1;
#ifdef _OPENMP
#pragma omp for schedule(dynamic, 64)
#endif
        for (long long i = 0; i < total; i++)
            if (nb) answer_side(s, global, ph, hfree, k, max_dist2, &all[i], nb, &ans[i]);
        free(nb);
    }
    if (fail) dist_die("out of memory precomputing irradiance");
    /* 3. Each owner gets every rank's parts of its queries: rank r's block of ans goes to r. */
    for (int r = 0, off = 0; r < M; r++) {
        cnt2[r] = cnt[r] * (int)sizeof(lk_part);
        dsp[r] = off * (int)sizeof(lk_part);
        off += cnt[r];
    }
    int *rc_ = malloc((size_t)M * sizeof *rc_), *rd = malloc((size_t)M * sizeof *rd);
    if (!rc_ || !rd) dist_die("out of memory precomputing irradiance");
    for (int r = 0; r < M; r++) {
        rc_[r] = mq * (int)sizeof(lk_part);
        rd[r] = r * mq * (int)sizeof(lk_part);
    }
    MPI_Alltoallv(ans, cnt2, dsp, MPI_BYTE, back, rc_, rd, MPI_BYTE, MPI_COMM_WORLD);
    bytes += (uint64_t)(total - mq) * sizeof(lk_part);
    free(ans);
    free(all);
    /* 4. Combine: E of this rank's chosen photons, with the radius^2 of the combined disc. */
    typedef struct side_rec {
        pm_photon p;
        float r2, h;
    } side_rec;
    side_rec *recs = calloc(m ? m : 1, sizeof *recs);
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
        for (int r = 0; r < M; r++) {
            add_part(&acc, &back[(size_t)r * m + j]);
            wall |= back[(size_t)r * m + j].wall;
        }
        double E[3];
        pm_combine_finish(&acc, E, NULL);
        double r2 = acc.r2_sum / M;
        /* Too few photons in all the parts: never looked up (photon_sides.h, sparse estimates). */
        int readable = side_estimate_readable((unsigned)acc.found, k);
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
    /* 5. Every rank's records to every rank, in rank order: the same cache everywhere. */
    for (int r = 0, off = 0; r < M; r++) {
        cnt2[r] = cnt[r] * (int)sizeof(side_rec);
        dsp[r] = off * (int)sizeof(side_rec);
        off += cnt[r];
    }
    side_rec *allrec = malloc((size_t)(total ? total : 1) * sizeof *allrec);
    if (!allrec) dist_die("out of memory precomputing irradiance");
    MPI_Allgatherv(recs, mq * (int)sizeof(side_rec), MPI_BYTE, allrec, cnt2, dsp, MPI_BYTE,
                   MPI_COMM_WORLD);
    bytes += (uint64_t)m * sizeof(side_rec) * (uint64_t)(M - 1);
    free(recs);
    free(cnt);
    free(dsp);
    free(cnt2);
    free(rc_);
    free(rd);
    size_t N = (size_t)total;
    pm_photon *rp = malloc((N ? N : 1) * sizeof *rp);
    float *r2 = malloc((N ? N : 1) * sizeof *r2), *hf = malloc((N ? N : 1) * sizeof *hf);
    if (!rp || !r2 || !hf) {
        free(rp);
        free(r2);
        free(hf);
        free(allrec);
        return side_fail(c, err, errcap, "out of memory");
    }
    for (size_t i = 0; i < N; i++) {
        rp[i] = allrec[i].p;
        r2[i] = allrec[i].r2;
        hf[i] = allrec[i].h;
    }
    free(allrec);
    int rc = side_cache_from_records(c, rp, r2, hf, N, err, errcap);
    free(rp);
    free(r2);
    free(hf);
    if (rc < 0) return rc;
    unsigned long long w = walls, wsum = 0, b = bytes, bsum = 0, sp = sparse, spsum = 0;
    MPI_Reduce(&w, &wsum, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, 0, MPI_COMM_WORLD);
    MPI_Reduce(&sp, &spsum, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, 0, MPI_COMM_WORLD);
    c->sparse = (size_t)spsum;
    c->indirect_only = 1; /* the mapper adds a gather hit's direct light itself */
    MPI_Reduce(&b, &bsum, 1, MPI_UNSIGNED_LONG_LONG, MPI_SUM, 0, MPI_COMM_WORLD);
    c->researched = (size_t)wsum;
    if (L.rank == 0) {
        stat_add(L.st_side_bytes, bsum);
        stat_add(L.st_side_queries, (uint64_t)N);
    }
    return 0;
}

/* ---- the tiles ------------------------------------------------------------------------------ */

static void clear_tiles_state(const scene *s, render_state *st, const int *tiles, int n) {
    const camera *c = &s->cam;
    for (int i = 0; i < n; i++) {
        int x0 = (tiles[i] % L.tiles_x) * RENDER_TILE, y0 = (tiles[i] / L.tiles_x) * RENDER_TILE;
        int x1 = x0 + RENDER_TILE < c->width ? x0 + RENDER_TILE : c->width;
        int y1 = y0 + RENDER_TILE < c->height ? y0 + RENDER_TILE : c->height;
        for (int y = y0; y < y1; y++)
            for (int x = x0; x < x1; x++) {
                size_t p = (size_t)y * (size_t)c->width + (size_t)x;
                st->count[p] = 0;
                st->sum[3 * p] = st->sum[3 * p + 1] = st->sum[3 * p + 2] = 0;
            }
    }
}

int lk_render_tiles(const scene *s, const integrator *it, const render_job *job, render_state *st,
                    const int *tiles, int n, int (*also)(void *), void *arg) {
    const camera *c = &s->cam;
    if (!L.ready) return render_tiles(s, it, job, st, tiles, n); /* no photon maps to look up */
    if (!L.tiles) {
        L.width = c->width;
        L.tiles_x = (c->width + RENDER_TILE - 1) / RENDER_TILE;
        L.ntiles = L.tiles_x * ((c->height + RENDER_TILE - 1) / RENDER_TILE);
        L.tiles = calloc((size_t)L.ntiles, sizeof *L.tiles);
        if (!L.tiles) return PM_ENOMEM;
    }
    /* 1. Record: the counters of this trace are taken off again afterwards. */
    uint64_t *before = malloc(STATS_MAX * sizeof *before);
    if (!before) return PM_ENOMEM;
    for (int id = 0; id < STATS_MAX; id++) before[id] = stats_name(id) ? stats_total(id) : 0;
    L.mode = 0;
    int rc = render_tiles(s, it, job, st, tiles, n);
    size_t nq = 0;
    for (int i = 0; i < n; i++) {
        if (L.tiles[tiles[i]].bad) dist_die("out of memory recording photon lookups");
        nq += L.tiles[tiles[i]].n;
    }
    if (rc == 0 && nq == 0) {
        /* No estimate in these tiles (a scene without caustics, say): the recording trace
         * used no placeholder, so it is the image; it keeps its counters, and there is
         * nothing to exchange or trace again. */
        free(before);
        return 0;
    }
    for (int id = 0; id < STATS_MAX; id++)
        if (stats_name(id)) stat_add(id, before[id] - stats_total(id)); /* mod 2^64 */
    free(before);
    if (rc < 0) return rc;
    clear_tiles_state(s, st, tiles, n);
    /* 2. The chunk's queries in tile order; this rank's parts, then every other rank's. */
    lk_query *q = malloc((nq ? nq : 1) * sizeof *q);
    lk_part *mine = malloc((nq ? nq : 1) * sizeof *mine);
    pm_combine_acc *acc = calloc(nq ? nq : 1, sizeof *acc);
    if (!q || !mine || !acc) dist_die("out of memory in the photon lookups");
    for (int i = 0, off = 0; i < n; i++) {
        lk_tile *t = &L.tiles[tiles[i]];
        if (t->n) memcpy(q + off, t->q, t->n * sizeof *q);
        off += (int)t->n;
    }
    stat_add(L.st_queries, nq);
    answer_all(q, nq, mine);
    for (size_t i = 0; i < nq; i++) acc[i].bias = L.opts[q[i].map == PHOTON_LOOKUP_CAUSTIC].bias;
    exchange(q, nq, mine, acc, also, arg);
    free(mine);
    free(q);
    /* 3. Combine, and replay. */
    for (int i = 0, off = 0; i < n; i++) {
        lk_tile *t = &L.tiles[tiles[i]];
        t->e = malloc((t->n ? t->n : 1) * sizeof *t->e);
        if (!t->e) dist_die("out of memory in the photon lookups");
        for (size_t j = 0; j < t->n; j++) {
            const lk_query *qq = &t->q[j];
            combine_one(&L.opts[qq->map == PHOTON_LOOKUP_CAUSTIC], &acc[off + (int)j], t->e[j]);
        }
        off += (int)t->n;
        t->cursor = 0;
    }
    free(acc);
    L.mode = 1;
    rc = render_tiles(s, it, job, st, tiles, n);
    for (int i = 0; i < n; i++) {
        lk_tile *t = &L.tiles[tiles[i]];
        if (rc == 0 && (t->bad || t->cursor != t->n))
            dist_die("a tile traced again asked for other photon lookups than when it was "
                     "recorded (an estimate changed a decision of the integrator)");
        free(t->q);
        free(t->e);
        memset(t, 0, sizeof *t);
    }
    return rc;
}

void lk_init(int rank, int size) {
    memset(&L, 0, sizeof L);
    L.rank = rank;
    L.size = size;
    L.on = 1;
    MPI_Comm_dup(MPI_COMM_WORLD, &L.comm);
    L.st_queries = stats_register("MPI/Partitioned: photon lookups sent (all ranks)");
    L.st_bytes = stats_register("MPI/Partitioned: bytes sent in photon lookups (all ranks)");
    L.st_side_queries = stats_register("MPI/Partitioned: precomputed irradiance estimates");
    L.st_side_bytes = stats_register("MPI/Partitioned: bytes sent precomputing irradiance (all ranks)");
    g_hook.partition = hook_partition;
    g_hook.side_build = hook_side_build;
    g_hook.ready = hook_ready;
    g_hook.estimate = hook_estimate;
    g_hook.user = NULL;
    photon_lookup_set_hook(&g_hook);
}
