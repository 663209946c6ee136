/* estimate.c: the radiance estimates of estimate.h (disc, cone, Gaussian, differential
 * checking, convex hull, volume), their k-nearest wrappers, and the automatic maximum radius.
 *
 * Every core works the same way: decode each neighbour's RGBE power (times the BRDF) into a
 * double triple, weight it, sum in double, and divide by an area that is never below a floor.
 * The one place that needs care is the area. radius2() applies the radius rule (farthest
 * neighbour, or max_dist2 when the search ran dry inside it) and the floor, and turns an
 * overflowed radius into "far away: 0". The hull builds a 2D convex hull in double with a
 * relative tolerance in its orientation test, after an Akl-Toussaint prefilter has set aside
 * the points that are surely interior; any doubt (too few points, fewer than three hull
 * vertices, a sliver) sends it to the disc estimate, so it never divides by a zero area.
 * Sorting is in place on the caller's scratch, because qsort may allocate and the estimates
 * promise not to: differential checking sorts its neighbours with the module's one
 * (dist2, index) sort (internal.h); the hull sorts its projected points by (u, v) with the
 * same heapsort (PM__HEAPSORT, internal.h), only the key differs.
 */
#include "estimate.h"
#include "internal.h"

#include <math.h>
#include <string.h>

#define PM__PI 3.14159265358979323846

void pm_estimate_options_init(pm_estimate_options *opt, pm_estimator kind, unsigned k) {
    memset(opt, 0, sizeof *opt);
    opt->kind = kind;
    opt->k = k;
    opt->max_dist2 = INFINITY;
    opt->bias = PM_BIAS_AREA;
    opt->cone_k = 1.0;
    opt->hull_boundary = 0.2;
    opt->diff_tol = 0.01;
    opt->squash = 1.0f;
}

const char *pm_estimator_name(pm_estimator kind) {
    switch (kind) {
    case PM_EST_DISC: return "disc";
    case PM_EST_CONE: return "cone";
    case PM_EST_GAUSS: return "gauss";
    case PM_EST_DIFFERENTIAL: return "differential";
    case PM_EST_HULL: return "hull";
    default: return "?";
    }
}

/* Layout of the wrapper's scratch: k neighbours (8 bytes each), then the core's part, which
 * is the larger of the hull's (24 k point bytes + (2k + 2) * 4 hull indices) and the
 * differential's (8 k, a sorted copy). 48 k + 64 covers both with room for alignment. */
typedef struct hull_pt {
    double u, v;
    uint32_t nb;     /* index into the neighbour list */
    uint32_t vertex; /* 1 if a hull vertex */
} hull_pt;

size_t pm_estimate_scratch_bytes(unsigned k) { return 48u * (size_t)k + 64u; }

double pm_cone_norm(double cone_k) { return 1.0 - 2.0 / (3.0 * cone_k); }

double pm_gauss_norm(void) {
    /* The mean of w over the unit disc: with s = d^2/r^2 uniform on [0, 1],
     * mean = alpha [1 - (1 - int_0^1 exp(-beta s/2) ds) / (1 - exp(-beta))]. */
    const double a = PM_GAUSS_ALPHA, b = PM_GAUSS_BETA;
    double mean_exp = (2.0 / b) * (1.0 - exp(-b / 2.0));
    return a * (1.0 - (1.0 - mean_exp) / (1.0 - exp(-b)));
}

static int finite3(const float v[3]) {
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

static int check_options(const pm_estimate_options *opt) {
    if (!opt || opt->k == 0) return PM_EINVAL;
    if ((unsigned)opt->kind >= (unsigned)PM_EST_COUNT_) return PM_EINVAL;
    if (opt->bias < PM_BIAS_NONE || opt->bias > PM_BIAS_HALF_FARTHEST) return PM_EINVAL;
    if (isnan(opt->max_dist2) || isnan(opt->min_dist2)) return PM_ENONFINITE;
    if (opt->kind == PM_EST_CONE && !(opt->cone_k >= 1.0 && isfinite(opt->cone_k))) return PM_EINVAL;
    if (opt->kind == PM_EST_HULL && !(opt->hull_boundary >= 0.0 && opt->hull_boundary <= 1.0))
        return PM_EINVAL;
    if (opt->kind == PM_EST_DIFFERENTIAL && !(opt->diff_tol >= 0.0 && isfinite(opt->diff_tol)))
        return PM_EINVAL;
    return PM_OK;
}

/* Per-call BRDF setup: a constant per-channel factor unless a callback is given. */
typedef struct brdf_ctx {
    double scale[3];
    pm_brdf_fn fn;
    void *user;
} brdf_ctx;

static void brdf_init(brdf_ctx *b, const pm_estimate_options *opt, double extra) {
    b->fn = opt->brdf;
    b->user = opt->brdf_user;
    for (int c = 0; c < 3; c++) {
        double s = opt->diffuse && !opt->brdf ? (double)opt->diffuse[c] / PM__PI : 1.0;
        if (!(s >= 0.0) || !isfinite(s)) s = 0.0; /* a bad albedo must not make NaN */
        b->scale[c] = s * extra;
    }
}

/* f_r * dPhi of one photon, in double. */
static void contrib(const brdf_ctx *b, const pm_photon *p, double out[3]) {
    float rgb[3];
    pm_rgbe_decode(p->power, rgb);
    if (b->fn) {
        float d[3], wi[3], f[3] = {0, 0, 0};
        pm_dir_decode(p->theta, p->phi, d);
        wi[0] = -d[0], wi[1] = -d[1], wi[2] = -d[2];
        b->fn(b->user, wi, f);
        for (int c = 0; c < 3; c++) {
            double fc = (double)f[c];
            if (!(fc >= 0.0) || !isfinite(fc)) fc = 0.0;
            out[c] = fc * (double)rgb[c] * b->scale[c];
        }
    } else {
        for (int c = 0; c < 3; c++) out[c] = (double)rgb[c] * b->scale[c];
    }
}

static double floor_dist2(const float x[3], const pm_estimate_options *opt) {
    if (opt->min_dist2 > 0) return (double)opt->min_dist2;
    double m = 1.0;
    for (int i = 0; i < 3; i++) m = fmax(m, fabs((double)x[i]));
    m *= 0x1p-20;
    return m * m;
}

/* The radius rule of estimate.h. Returns r^2 (possibly INFINITY); sets *limited when the
 * area is that of max_dist2, *far_idx to the farthest neighbour (or -1). */
static double radius2(const pm_neighbor *nb, unsigned count, const float x[3],
                      const pm_estimate_options *opt, int *limited, long *far_idx,
                      unsigned *flags) {
    double r2 = 0.0;
    long far = -1;
    for (unsigned i = 0; i < count; i++) {
        double d2 = (double)nb[i].dist2;
        if (far < 0 || d2 > r2) r2 = d2, far = (long)i;
    }
    *limited = 0;
    if (count < opt->k && isfinite(opt->max_dist2) && opt->max_dist2 > 0) {
        r2 = (double)opt->max_dist2;
        *limited = 1;
        *flags |= PM_EST_F_RADIUS_LIMIT;
    }
    double fl = floor_dist2(x, opt);
    if (!(r2 >= fl)) { /* also catches a NaN dist2 from a hand-made list */
        r2 = fl;
        *flags |= PM_EST_F_RADIUS_FLOOR;
    }
    *far_idx = far;
    return r2;
}

static void zero_result(pm_estimate_result *out, unsigned count) {
    memset(out, 0, sizeof *out);
    out->found = count;
}

/* Divide a power sum by an area into out->rgb; a non-finite or non-positive area gives 0. */
static void finish(pm_estimate_result *out, const double sum[3], double area) {
    out->area = area;
    for (int c = 0; c < 3; c++) {
        double v = area > 0.0 && isfinite(area) ? sum[c] / area : 0.0;
        out->rgb[c] = isfinite(v) && v > 0.0 ? v : 0.0;
    }
}

/* The radius^2 of an estimate over nb[0..count) (radius2), recorded in out with the count;
 * not finite (the estimate reads 0, flagged PM_EST_F_FAR) when it overflowed. */
static double begin_estimate(const pm_neighbor *nb, unsigned count, const float x[3],
                             const pm_estimate_options *opt, int *limited, long *far,
                             pm_estimate_result *out) {
    double r2 = radius2(nb, count, x, opt, limited, far, &out->flags);
    out->r2 = r2;
    out->used = count;
    if (!isfinite(r2)) out->flags |= PM_EST_F_FAR;
    return r2;
}

/* Disc estimate over nb[0..count) with the bias rule; also the hull's fallback. */
static void disc(const pm_photon *ph, const pm_neighbor *nb, unsigned count, const float x[3],
                 const pm_estimate_options *opt, const brdf_ctx *b, pm_estimate_result *out) {
    int limited;
    long far;
    double sum[3] = {0, 0, 0}, c[3];
    double r2 = begin_estimate(nb, count, x, opt, &limited, &far, out);
    if (!isfinite(r2)) return;
    for (unsigned i = 0; i < count; i++) {
        contrib(b, &ph[nb[i].index], c);
        double w = (opt->bias == PM_BIAS_HALF_FARTHEST && !limited && (long)i == far) ? 0.5 : 1.0;
        for (int j = 0; j < 3; j++) sum[j] += w * c[j];
    }
    double area = PM__PI * r2;
    if (opt->bias == PM_BIAS_AREA && !limited) area *= (double)count / ((double)count - 0.5);
    finish(out, sum, area);
}

/* Cone (is_cone) or Gaussian filter. */
static void filtered(const pm_photon *ph, const pm_neighbor *nb, unsigned count,
                     const float x[3], const pm_estimate_options *opt, const brdf_ctx *b,
                     int is_cone, pm_estimate_result *out) {
    int limited;
    long far;
    double sum[3] = {0, 0, 0}, c[3];
    double r2 = begin_estimate(nb, count, x, opt, &limited, &far, out);
    if (!isfinite(r2)) return;
    const double kr = opt->cone_k * sqrt(r2);
    const double eb = 1.0 - exp(-PM_GAUSS_BETA);
    for (unsigned i = 0; i < count; i++) {
        double d2 = (double)nb[i].dist2, w;
        if (!(d2 >= 0.0)) d2 = 0.0;
        if (is_cone)
            w = 1.0 - sqrt(d2) / kr;
        else
            w = PM_GAUSS_ALPHA * (1.0 - (1.0 - exp(-PM_GAUSS_BETA * d2 / (2.0 * r2))) / eb);
        if (!(w > 0.0)) continue;
        if (opt->bias != PM_BIAS_NONE && !limited && (long)i == far) w *= 0.5;
        contrib(b, &ph[nb[i].index], c);
        for (int j = 0; j < 3; j++) sum[j] += w * c[j];
    }
    double norm = is_cone ? pm_cone_norm(opt->cone_k) : pm_gauss_norm();
    finish(out, sum, PM__PI * r2 * norm);
}

static double lum(const double c[3]) { return c[0] + c[1] + c[2]; }

static void differential(const pm_photon *ph, const pm_neighbor *nb, unsigned count,
                         const float x[3], const pm_estimate_options *opt, const brdf_ctx *b,
                         void *scratch, pm_estimate_result *out) {
    pm_neighbor *s = (pm_neighbor *)scratch;
    unsigned dmin = opt->diff_min ? opt->diff_min : (opt->k / 4 > 8 ? opt->k / 4 : 8);
    unsigned step = opt->diff_step ? opt->diff_step : (opt->k / 10 > 2 ? opt->k / 10 : 2);
    unsigned drun = opt->diff_run ? opt->diff_run : 3;
    double fl = floor_dist2(x, opt);
    double sum[3] = {0, 0, 0}, c[3], prev = 0.0;
    unsigned run = 0, run_start = 0, last_check = 0;
    int run_sign = 0;
    long stop = -1; /* index of the last photon of the returned estimate */

    if (dmin < 2) dmin = 2;
    memcpy(s, nb, (size_t)count * sizeof *s);
    pm__nb_sort(s, count);
    for (unsigned j = 0; j < count; j++) {
        contrib(b, &ph[s[j].index], c);
        double d2 = fmax((double)s[j].dist2, fl);
        double e = (lum(sum) + 0.5 * lum(c)) / (PM__PI * d2); /* half-farthest estimate */
        for (int i = 0; i < 3; i++) sum[i] += c[i];
        if (!isfinite(e)) break; /* far away; the full disc below returns 0 */
        if (j + 1 < dmin || (j + 1 - dmin) % step != 0) continue;
        /* A checkpoint: j + 1 photons. Compare with the previous checkpoint. */
        if (j + 1 > dmin) {
            int sign = e > prev * (1.0 + opt->diff_tol) ? 1 : e < prev * (1.0 - opt->diff_tol) ? -1 : 0;
            if (sign != 0 && sign == run_sign) {
                run++;
            } else {
                run_sign = sign;
                run = sign != 0;
                run_start = last_check; /* the checkpoint before this move */
            }
            if (run >= drun) {
                stop = (long)run_start;
                break;
            }
        }
        prev = e;
        last_check = j;
    }
    if (stop < 0) {
        disc(ph, nb, count, x, opt, b, out);
        return;
    }
    /* The disc estimate of the first stop+1 photons, whose farthest is s[stop]; this is a
     * k-nearest result in its own right (n == k'), so the usual bias rule applies. */
    pm_estimate_options o = *opt;
    o.k = (unsigned)stop + 1;
    o.max_dist2 = INFINITY;
    disc(ph, s, (unsigned)stop + 1, x, &o, b, out);
    out->flags |= PM_EST_F_DIFF_STOPPED;
}

/* Orthonormal tangent basis (t, b) of a unit normal (Duff et al. 2017). */
static void tangent_basis(const double n[3], double t[3], double bt[3]) {
    double sign = copysign(1.0, n[2]);
    double a = -1.0 / (sign + n[2]);
    double bb = n[0] * n[1] * a;
    t[0] = 1.0 + sign * n[0] * n[0] * a, t[1] = sign * bb, t[2] = -sign * n[0];
    bt[0] = bb, bt[1] = sign + n[1] * n[1] * a, bt[2] = -n[1];
}

static inline int pt_less(const hull_pt *a, const hull_pt *b) {
    return a->u < b->u || (a->u == b->u && a->v < b->v);
}
/* pt_sort(a, n): the module's heapsort (internal.h) by (u, v). */
PM__HEAPSORT(pt_sort, hull_pt, pt_less)

static double cross(const hull_pt *o, const hull_pt *a, const hull_pt *b) {
    return (a->u - o->u) * (b->v - o->v) - (a->v - o->v) * (b->u - o->u);
}

/* Akl-Toussaint prefilter: the points extreme in 8 directions span a polygon inside the
 * hull, and a point strictly left of each of its edges (by more than margin) lies inside it,
 * so it cannot be a hull vertex. Such points are moved behind the others and only the rest,
 * about a tenth of a uniform disc, need sorting. The argument needs no convexity: a point
 * strictly left of every edge of a closed polygon has a positive winding number. Returns the
 * number of candidates, now at p[0..). */
static unsigned prefilter(hull_pt *p, unsigned count, double margin) {
    static const double dir[8][2] = {{1, 0}, {1, 1}, {0, 1}, {-1, 1},
                                     {-1, 0}, {-1, -1}, {0, -1}, {1, -1}};
    unsigned ext[8], np = 0;
    double best[8], pu[8], pv[8];
    for (unsigned i = 0; i < count; i++)
        for (int d = 0; d < 8; d++) {
            double sd = dir[d][0] * p[i].u + dir[d][1] * p[i].v;
            if (i == 0 || sd > best[d]) best[d] = sd, ext[d] = i;
        }
    for (int d = 0; d < 8; d++)
        if (np == 0 || (ext[d] != ext[d - 1] && !(d == 7 && ext[d] == ext[0]))) {
            pu[np] = p[ext[d]].u, pv[np] = p[ext[d]].v;
            np++;
        }
    if (np < 3) return count;
    unsigned cand = count;
    for (unsigned i = 0; i < cand;) {
        int inside = 1;
        for (unsigned e = 0; e < np && inside; e++) {
            unsigned f = e + 1 == np ? 0 : e + 1;
            double c = (pu[f] - pu[e]) * (p[i].v - pv[e]) - (pv[f] - pv[e]) * (p[i].u - pu[e]);
            inside = c > margin;
        }
        if (inside) {
            hull_pt tmp = p[i];
            p[i] = p[--cand];
            p[cand] = tmp;
        } else {
            i++;
        }
    }
    return cand;
}

static void hull(const pm_photon *ph, const pm_neighbor *nb, unsigned count, const float x[3],
                 const float normal[3], const pm_estimate_options *opt, const brdf_ctx *b,
                 void *scratch, pm_estimate_result *out) {
    hull_pt *p = (hull_pt *)scratch;
    uint32_t *h = (uint32_t *)(p + count);
    double n[3] = {0, 0, 1}, t[3], bt[3], scale = 0.0, rp2 = 0.0, area = 0.0;
    double sum[3] = {0, 0, 0}, c[3];
    int limited;
    long far, m = 0;

    /* Far from every photon (a dist2 overflowed) the disc gives 0 with PM_EST_F_FAR; so does
     * the hull: its projected doubles would not overflow, but the photons found are then an
     * arbitrary set of tied infinite distances, not the nearest. */
    {
        unsigned fl = 0;
        if (!isfinite(radius2(nb, count, x, opt, &limited, &far, &fl))) {
            disc(ph, nb, count, x, opt, b, out);
            return;
        }
    }
    if (count < 3) goto fallback;
    if (normal) {
        double len = sqrt((double)normal[0] * normal[0] + (double)normal[1] * normal[1] +
                          (double)normal[2] * normal[2]);
        if (len > 0.0)
            for (int i = 0; i < 3; i++) n[i] = (double)normal[i] / len;
    }
    tangent_basis(n, t, bt);
    for (unsigned i = 0; i < count; i++) {
        const float *q = ph[nb[i].index].pos;
        double d[3] = {(double)q[0] - x[0], (double)q[1] - x[1], (double)q[2] - x[2]};
        p[i].u = d[0] * t[0] + d[1] * t[1] + d[2] * t[2];
        p[i].v = d[0] * bt[0] + d[1] * bt[1] + d[2] * bt[2];
        p[i].nb = i;
        p[i].vertex = 0;
        scale = fmax(scale, fmax(fabs(p[i].u), fabs(p[i].v)));
        rp2 = fmax(rp2, p[i].u * p[i].u + p[i].v * p[i].v);
    }
    if (!(scale > 0.0) || !isfinite(rp2)) goto fallback;
    {
        /* Andrew's monotone chain. A turn counts as left only if its cross product exceeds
         * eps, well above the rounding error of the products (about 1e-16 scale^2), so
         * duplicates and (nearly) collinear points are dropped rather than kept by noise. */
        const double eps = 1e-12 * scale * scale;
        unsigned cand = prefilter(p, count, 16.0 * eps);
        pt_sort(p, cand);
        for (unsigned i = 0; i < cand; i++) {
            while (m >= 2 && cross(&p[h[m - 2]], &p[h[m - 1]], &p[i]) <= eps) m--;
            h[m++] = i;
        }
        long lower = m + 1;
        for (long i = (long)cand - 2; i >= 0; i--) {
            while (m >= lower && cross(&p[h[m - 2]], &p[h[m - 1]], &p[i]) <= eps) m--;
            h[m++] = (uint32_t)i;
        }
        m--; /* the last point repeats the first */
    }
    if (m < 3) goto fallback;
    for (long i = 0; i < m; i++) {
        const hull_pt *a = &p[h[i]], *q = &p[h[(i + 1) % m]];
        area += a->u * q->v - q->u * a->v;
        p[h[i]].vertex = 1;
    }
    area *= 0.5;
    if (!(area > PM_HULL_MIN_AREA_FRACTION * PM__PI * rp2) ||
        !(area > PM__PI * floor_dist2(x, opt)) || !isfinite(area))
        goto fallback;
    for (unsigned i = 0; i < count; i++) {
        double w = p[i].vertex ? opt->hull_boundary : 1.0;
        contrib(b, &ph[nb[p[i].nb].index], c);
        for (int j = 0; j < 3; j++) sum[j] += w * c[j];
    }
    out->r2 = radius2(nb, count, x, opt, &limited, &far, &out->flags);
    out->flags &= ~(unsigned)(PM_EST_F_RADIUS_FLOOR | PM_EST_F_RADIUS_LIMIT);
    out->used = count;
    finish(out, sum, area);
    return;
fallback:
    out->flags |= PM_EST_F_HULL_FALLBACK;
    disc(ph, nb, count, x, opt, b, out);
}

int pm_estimate_core(const pm_photon *photons, const pm_neighbor *nb, unsigned count,
                     const float x[3], const float normal[3], const pm_estimate_options *opt,
                     void *scratch, pm_estimate_result *out) {
    brdf_ctx b;
    int rc = check_options(opt);
    if (!out) return PM_EINVAL;
    zero_result(out, count);
    if (rc) return rc;
    if (!x || !finite3(x) || (normal && !finite3(normal))) return PM_ENONFINITE;
    if (count > 0 && (!photons || !nb)) return PM_EINVAL;
    if (!scratch && count > 0 && (opt->kind == PM_EST_HULL || opt->kind == PM_EST_DIFFERENTIAL))
        return PM_EINVAL;
    if (count > opt->k) return PM_EINVAL; /* the scratch is sized for k */
    if (count == 0) {
        out->flags |= PM_EST_F_EMPTY;
        return PM_OK;
    }
    brdf_init(&b, opt, 1.0);
    switch (opt->kind) {
    case PM_EST_DISC: disc(photons, nb, count, x, opt, &b, out); break;
    case PM_EST_CONE: filtered(photons, nb, count, x, opt, &b, 1, out); break;
    case PM_EST_GAUSS: filtered(photons, nb, count, x, opt, &b, 0, out); break;
    case PM_EST_DIFFERENTIAL: differential(photons, nb, count, x, opt, &b, scratch, out); break;
    case PM_EST_HULL: hull(photons, nb, count, x, normal, opt, &b, scratch, out); break;
    default: return PM_EINVAL;
    }
    return PM_OK;
}

int pm_filter_front(void *user, const void *record, uint32_t index) {
    const float *n = (const float *)user;
    const pm_photon *p = (const pm_photon *)record;
    float d[3];
    (void)index;
    pm_dir_decode(p->theta, p->phi, d);
    return d[0] * n[0] + d[1] * n[1] + d[2] * n[2] <= 0.0f;
}

/* Scratch after the k neighbours, rounded up to 8 bytes. */
static void *core_scratch(void *scratch, unsigned k) {
    return (char *)scratch + (((size_t)k * sizeof(pm_neighbor) + 7u) & ~(size_t)7u);
}

void pm_estimate_search_options(const pm_estimate_options *opt, const float normal[3],
                                float nrm[3], pm_knn_options *ko) {
    nrm[0] = 0, nrm[1] = 0, nrm[2] = 1;
    if (normal) memcpy(nrm, normal, 3 * sizeof *nrm);
    memset(ko, 0, sizeof *ko);
    if (normal && opt->squash > 1.0f) {
        ko->normal = nrm;
        ko->squash = opt->squash;
    }
    if (opt->reject_behind) {
        ko->filter = pm_filter_front;
        ko->filter_user = nrm;
    }
}

int pm_estimate(const pm_kdtree *tree, const float x[3], const float normal[3],
                const pm_estimate_options *opt, void *scratch, pm_estimate_result *out,
                pm_query_stats *stats) {
    int rc = check_options(opt);
    if (!out) return PM_EINVAL;
    zero_result(out, 0);
    if (rc) return rc;
    if (!tree || !scratch) return PM_EINVAL;
    if (!x || !finite3(x) || (normal && !finite3(normal))) return PM_ENONFINITE;
    if (opt->reject_behind && !normal) return PM_EINVAL;
    float nrm[3];
    pm_knn_options ko;
    pm_estimate_search_options(opt, normal, nrm, &ko);
    pm_neighbor *nb = (pm_neighbor *)scratch;
    int found = pm_kdtree_knn_ex(tree, x, opt->k, opt->max_dist2, &ko, nb, stats);
    if (found < 0) return found;
    return pm_estimate_core((const pm_photon *)pm_kdtree_records(tree), nb, (unsigned)found, x,
                            normal, opt, core_scratch(scratch, opt->k), out);
}

int pm_estimate_volume_core(const pm_photon *photons, const pm_neighbor *nb, unsigned count,
                            const float x[3], double sigma_s, const pm_estimate_options *opt,
                            pm_estimate_result *out) {
    brdf_ctx b;
    int limited;
    long far;
    double sum[3] = {0, 0, 0}, c[3];
    if (!out) return PM_EINVAL;
    zero_result(out, count);
    if (!opt || opt->k == 0 || opt->bias < PM_BIAS_NONE || opt->bias > PM_BIAS_HALF_FARTHEST)
        return PM_EINVAL;
    if (!(sigma_s > 0.0) || !isfinite(sigma_s)) return PM_EINVAL;
    if (isnan(opt->max_dist2) || isnan(opt->min_dist2)) return PM_ENONFINITE;
    if (!x || !finite3(x)) return PM_ENONFINITE;
    if (count > 0 && (!photons || !nb)) return PM_EINVAL;
    if (count > opt->k) return PM_EINVAL;
    if (count == 0) {
        out->flags |= PM_EST_F_EMPTY;
        return PM_OK;
    }
    /* Isotropic phase 1/(4 pi) unless a callback gives the phase function. */
    brdf_init(&b, opt, 1.0);
    if (!opt->brdf)
        for (int i = 0; i < 3; i++) b.scale[i] = 1.0 / (4.0 * PM__PI);
    double r2 = radius2(nb, count, x, opt, &limited, &far, &out->flags);
    out->r2 = r2;
    out->used = count;
    if (!isfinite(r2)) {
        out->flags |= PM_EST_F_FAR;
        return PM_OK;
    }
    for (unsigned i = 0; i < count; i++) {
        contrib(&b, &photons[nb[i].index], c);
        double w = (opt->bias == PM_BIAS_HALF_FARTHEST && !limited && (long)i == far) ? 0.5 : 1.0;
        for (int j = 0; j < 3; j++) sum[j] += w * c[j];
    }
    double vol = 4.0 / 3.0 * PM__PI * r2 * sqrt(r2);
    if (opt->bias == PM_BIAS_AREA && !limited) vol *= (double)count / ((double)count - 0.5);
    finish(out, sum, vol * sigma_s);
    return PM_OK;
}

int pm_estimate_volume(const pm_kdtree *tree, const float x[3], double sigma_s,
                       const pm_estimate_options *opt, void *scratch, pm_estimate_result *out,
                       pm_query_stats *stats) {
    if (!out) return PM_EINVAL;
    zero_result(out, 0);
    if (!opt || opt->k == 0) return PM_EINVAL;
    if (!tree || !scratch) return PM_EINVAL;
    if (!x || !finite3(x)) return PM_ENONFINITE;
    if (isnan(opt->max_dist2)) return PM_ENONFINITE;
    pm_neighbor *nb = (pm_neighbor *)scratch;
    int found = pm_kdtree_knn(tree, x, opt->k, opt->max_dist2, nb, 0, stats);
    if (found < 0) return found;
    return pm_estimate_volume_core((const pm_photon *)pm_kdtree_records(tree), nb,
                                   (unsigned)found, x, sigma_s, opt, out);
}

double pm_auto_radius_surface(unsigned k, double p_max, double L_t) {
    if (!(L_t > 0.0) || !isfinite(L_t)) return INFINITY;
    if (!(p_max > 0.0)) return 0.0;
    return sqrt((double)k * p_max / L_t) / PM__PI;
}

double pm_auto_radius_volume(unsigned k, double p_max, double sigma_s, double L_t) {
    if (!(L_t > 0.0) || !isfinite(L_t) || !(sigma_s > 0.0) || !isfinite(sigma_s)) return INFINITY;
    if (!(p_max > 0.0)) return 0.0;
    return cbrt(3.0 * (double)k * p_max / (16.0 * PM__PI * PM__PI * sigma_s * L_t));
}

double pm_photons_max_power(const pm_photon *photons, size_t n) {
    double m = 0.0;
    for (size_t i = 0; i < n; i++) {
        float rgb[3];
        pm_rgbe_decode(photons[i].power, rgb);
        for (int c = 0; c < 3; c++) m = fmax(m, (double)rgb[c]);
    }
    return m;
}
