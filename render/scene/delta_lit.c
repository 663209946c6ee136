/* delta_lit.c: which specular objects point and directional lights see, and where the light
 * they redirect lands (see delta_lit.h for the rules and what they can miss).
 *
 * One sweep per delta light over the primitives: each specular primitive gives its sample
 * points, each point is tested with a shadow ray toward the light, and from the first
 * LIT_TRACE lit points of each object the light's ray is followed through specular bounces
 * (both branches of a dielectric) to the diffuse surfaces it reaches.
 */
#include "scene/delta_lit.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "scene/material.h"
#include "photonmap/common.h"

enum {
    SPHERE_POINTS = 256,  /* Fibonacci points per sphere */
    OBJECT_POINTS = 4096, /* sample points per triangle object, at most */
    LIT_TRACE = 64,       /* lit points per object and light whose light is followed */
    MAX_SPECULAR = 8      /* specular bounces followed */
};

/* A material whose light can leave by a specular branch (the null interface only passes
 * light on, unchanged: not a caustic maker). */
static int makes_caustics(const material *m) { return m->kind != MAT_NULL && material_is_specular(m); }

/* Follow light travelling along unit d that meets the surface at p (normal ng, material m)
 * through its specular branches; mark the diffuse objects reached. */
static void follow(const scene *s, vec3 p, vec3 ng, const material *m, vec3 d, int depth,
                   unsigned char *flags) {
    if (depth >= MAX_SPECULAR) return;
    vec3 out[2];
    int nout = 0;
    int reflects = (m->fresnel || m->specular > 0) && !v3_iszero(m->specular_tint);
    if (m->transparency > 0 && !v3_iszero(m->transmit_tint)) {
        double n1, n2;
        material_indices(m, v3_neg(d), ng, s->medium_ior, &n1, &n2);
        vec3 side = v3_dot(d, ng) < 0 ? ng : v3_neg(ng);
        vec3 t;
        if (refract_dir(d, side, n1 / n2, &t))
            out[nout++] = t;
        else
            reflects = 1; /* total internal reflection */
    }
    if (reflects) out[nout++] = v3_reflect(d, ng);
    for (int k = 0; k < nout; k++) {
        ray r = {scene_offset(s, p, ng, out[k]), out[k]};
        hit h;
        if (!scene_intersect(s, r, INFINITY, &h)) continue;
        const material *hm = &s->mats[h.mat];
        int obj = scene_prim_object(s, h.prim);
        if (material_is_diffuse(hm) && obj >= 0 && obj < s->nobj) flags[obj] |= DELTA_FOOTPRINT;
        if (makes_caustics(hm)) follow(s, h.p, h.ng, hm, out[k], depth + 1, flags);
    }
}

/* Test one sample point of object obj (material m) against light l; follow its light if lit
 * and the object has had fewer than LIT_TRACE points followed. */
static void test_point(const scene *s, const light *l, vec3 p, vec3 ng, const material *m, int obj,
                       unsigned char *flags, int *traced) {
    vec3 d; /* the light's direction of travel at p */
    int seen;
    if (light_is_point(l)) {
        vec3 to = v3_sub(p, l->pos);
        if (v3_len2(to) == 0) return;
        d = v3_norm(to);
        if (l->type == LIGHT_SPOT && !(light_spot_falloff(l, d) > 0)) return;
        seen = scene_visible(s, p, ng, l->pos, v3(0, 0, 0));
    } else {
        d = l->dir;
        seen = scene_visible_dir(s, p, ng, v3_neg(d));
    }
    if (!seen) return;
    flags[obj] |= DELTA_LIT;
    if (traced[obj] >= LIT_TRACE) return;
    traced[obj]++;
    follow(s, p, ng, m, d, 0, flags);
}

int delta_lit_find(const scene *s, unsigned char **flags_out) {
    int nobj = s->nobj > 0 ? s->nobj : 0;
    unsigned char *flags = calloc((size_t)(nobj ? nobj : 1), 1);
    int *ntri = calloc((size_t)(nobj ? nobj : 1), sizeof *ntri);
    int *seen = calloc((size_t)(nobj ? nobj : 1), sizeof *seen);
    int *traced = calloc((size_t)(nobj ? nobj : 1), sizeof *traced);
    *flags_out = NULL;
    if (!flags || !ntri || !seen || !traced) {
        free(flags), free(ntri), free(seen), free(traced);
        return PM_ENOMEM;
    }
    for (int i = 0; i < s->ntris; i++) {
        int o = s->tri_obj ? s->tri_obj[i] : -1;
        if (o >= 0 && o < nobj) ntri[o]++;
    }
    for (int li = 0; li < s->nlights; li++) {
        const light *l = &s->lights[li];
        if ((!light_is_point(l) && l->type != LIGHT_DIRECTIONAL) || !(v3_maxc(l->power) > 0))
            continue;
        memset(seen, 0, (size_t)nobj * sizeof *seen);
        memset(traced, 0, (size_t)nobj * sizeof *traced);
        for (int i = 0; i < s->ntris; i++) {
            const triangle *t = &s->tris[i];
            const material *m = &s->mats[t->mat];
            int o = s->tri_obj ? s->tri_obj[i] : -1;
            if (o < 0 || o >= nobj || !makes_caustics(m)) continue;
            /* Four points per triangle; every stride-th triangle of a large object. */
            int stride = (4 * ntri[o] + OBJECT_POINTS - 1) / OBJECT_POINTS;
            if (seen[o]++ % (stride > 0 ? stride : 1) != 0) continue;
            vec3 c = v3_add(t->v0, v3_scale(v3_add(t->e1, t->e2), 1.0 / 3));
            vec3 corner[3] = {t->v0, v3_add(t->v0, t->e1), v3_add(t->v0, t->e2)};
            test_point(s, l, c, t->n, m, o, flags, traced);
            for (int k = 0; k < 3; k++)
                test_point(s, l, v3_scale(v3_add(c, corner[k]), 0.5), t->n, m, o, flags, traced);
        }
        for (int i = 0; i < s->nspheres; i++) {
            const sphere *sp = &s->spheres[i];
            const material *m = &s->mats[sp->mat];
            int o = s->sphere_obj ? s->sphere_obj[i] : -1;
            if (o < 0 || o >= nobj || !makes_caustics(m)) continue;
            const double golden = M_PI * (3 - sqrt(5.0));
            for (int k = 0; k < SPHERE_POINTS; k++) {
                double z = 1 - (2 * k + 1) / (double)SPHERE_POINTS, rr = sqrt(1 - z * z);
                vec3 n = v3(rr * cos(golden * k), rr * sin(golden * k), z);
                test_point(s, l, v3_madd(sp->c, n, sp->r), n, m, o, flags, traced);
            }
        }
    }
    int count = 0;
    for (int o = 0; o < nobj; o++) count += (flags[o] & DELTA_LIT) != 0;
    free(ntri), free(seen), free(traced);
    *flags_out = flags;
    return count;
}

/* The material name of object o's first primitive. */
static const char *object_material(const scene *s, int o) {
    for (int i = 0; i < s->ntris; i++)
        if (s->tri_obj && s->tri_obj[i] == o) return s->mats[s->tris[i].mat].name;
    for (int i = 0; i < s->nspheres; i++)
        if (s->sphere_obj && s->sphere_obj[i] == o) return s->mats[s->spheres[i].mat].name;
    return "?";
}

static int list_objects(const scene *s, const unsigned char *flags, int flag, FILE *f) {
    int n = 0;
    for (int o = 0; o < s->nobj; o++)
        if (flags[o] & flag) fprintf(f, "%s$.objects[%d] (\"%s\")", n++ ? ", " : "", o, object_material(s, o));
    return n;
}

void delta_lit_warn(const scene *s, const char *scene_name, FILE *f) {
    unsigned char *flags = NULL;
    int n = delta_lit_find(s, &flags);
    if (n < 0) {
        fprintf(f, "render: warning: %s: out of memory checking for caustics of point and "
                   "directional lights\n", scene_name);
        return;
    }
    if (n > 0) {
        fprintf(f, "render: warning: %s: path tracing cannot render light that point or "
                   "directional lights send through specular surfaces onto diffuse ones "
                   "(L S+ D); lit straight by a point or directional light: ", scene_name);
        list_objects(s, flags, DELTA_LIT, f);
        int any = 0;
        for (int o = 0; o < s->nobj; o++) any |= flags[o] & DELTA_FOOTPRINT;
        if (any) {
            fprintf(f, "; their caustics fall on ");
            list_objects(s, flags, DELTA_FOOTPRINT, f);
            fprintf(f, "; those regions are missing light in this image (use --mode pm for them)\n");
        } else {
            fprintf(f, "; within %d specular bounces their light reaches no diffuse surface, so "
                       "no caustic of theirs is missing here\n", MAX_SPECULAR);
        }
    }
    free(flags);
}
