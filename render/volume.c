/* volume.c: photon tracing through participating media for the volume photon map; see
 * volume.h. One loop per photon: free flight in the current medium, a stored photon and an
 * HG bounce at each scattering event, a material bounce or a medium change at each surface.
 */
#include "volume.h"

#include <stdlib.h>

#include "medium.h"
#include "photonmap/common.h"
#include "rng.h"

static int store(vol_photons *o, vec3 p, rgb power, vec3 d, int kind) {
    if (o->count == o->cap) {
        size_t nc = o->cap ? 2 * o->cap : 1024;
        pm_photon *np = realloc(o->photons, nc * sizeof *np);
        if (!np) return PM_ENOMEM;
        o->photons = np;
        o->cap = nc;
    }
    float fp[3] = {(float)p.x, (float)p.y, (float)p.z}, fw[3] = {(float)power.x, (float)power.y, (float)power.z},
          fd[3] = {(float)d.x, (float)d.y, (float)d.z};
    pm_photon_init(&o->photons[o->count++], fp, fw, fd, NULL, kind);
    return 0;
}

/* Roulette on a throughput factor w: survive with q = min(1, max channel), power * w / q. */
static int survive(rgb *power, rgb w, rng *g) {
    double q = fmin(1.0, v3_maxc(w)), u = rng_uniform(g);
    if (!(q > 0) || !(u < q)) return 0;
    *power = v3_mul(*power, v3_scale(w, 1.0 / q));
    return 1;
}

int vol_trace(const scene *s, uint64_t n, uint64_t seed, int max_depth, vol_photons *out) {
    out->photons = NULL;
    out->count = out->cap = 0;
    if (s->nlights == 0 || s->light_distrib.n == 0) return PM_EINVAL;
    for (uint64_t i = 0; i < n; i++) {
        rng g = rng_stream(seed, i, 7);
        double pl, u[4];
        int li = distrib1d_sample(&s->light_distrib, rng_uniform(&g), &pl);
        for (int k = 0; k < 4; k++) u[k] = rng_uniform(&g);
        vec3 p, nl, d;
        light_sample_le(s, li, u, &p, &nl, &d);
        if (!(pl > 0)) continue;
        rgb power = v3_scale(s->lights[li].power, 1.0 / ((double)n * pl));
        ray r = {v3_iszero(nl) ? p : v3_offset(p, nl, d), d};
        int med = s->global_medium, specular = 0, scattered = 0, crossings = 0;
        for (int depth = 0; depth <= max_depth;) {
            hit h;
            int got = scene_intersect(s, r, INFINITY, &h);
            if (med >= 0) {
                double uc = rng_uniform(&g), ud = rng_uniform(&g), t;
                rgb w;
                if (medium_sample_distance(&s->media[med], got ? h.t : INFINITY, uc, ud, &t, &w)) {
                    vec3 x = ray_at(r, t);
                    int kind = scattered ? PM_KIND_INDIRECT : specular ? PM_KIND_CAUSTIC : PM_KIND_DIRECT;
                    if (store(out, x, v3_mul(power, w), r.d, kind) < 0) {
                        free(out->photons);
                        out->photons = NULL;
                        out->count = out->cap = 0;
                        return PM_ENOMEM;
                    }
                    scattered = 1;
                    if (!survive(&power, w, &g)) break;
                    vec3 nd;
                    hg_sample(s->media[med].g, r.d, rng_uniform(&g), rng_uniform(&g), &nd);
                    r.o = x;
                    r.d = nd;
                    depth++;
                    continue;
                }
                power = v3_mul(power, w);
            }
            if (!got) break;
            const material *m = scene_material(s, &h);
            if (m->kind == MAT_NULL) {
                if (++crossings > 4 * max_depth + 1024) break;
                med = scene_medium_after(s, &h, r.d);
                r.o = v3_offset(h.p, h.ng, r.d);
                continue;
            }
            bsdf_sample bs;
            double ul = rng_uniform(&g), u1 = rng_uniform(&g), u2 = rng_uniform(&g);
            if (!material_sample_ns(m, v3_neg(r.d), h.ng, h.ns, s->medium_ior, ul, u1, u2, &bs)) break;
            if (bs.lobe == LOBE_DIFFUSE) scattered = 1; else specular = 1;
            if (!survive(&power, bs.weight, &g)) break;
            med = scene_medium_after(s, &h, bs.wi);
            r.o = v3_offset(h.p, h.ng, bs.wi);
            r.d = bs.wi;
            depth++;
        }
    }
    return 0;
}
