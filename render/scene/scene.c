/* scene.c: what the scene is once loaded: its setup (bounds, the lights of emissive
 * surfaces and their powers, the light distribution, the BVH), and the ray queries
 * (nearest hit, visibility) every integrator asks; see scene.h. The JSON loader is
 * scene_load.c.
 */
#include "scene/scene.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "base/errors.h"
#include "scene/envmap.h"
#include "photonmap/common.h"
#include "base/stats.h"

/* Bounds, area lights, light powers and the BVH. */
/* Each object of $.objects at most SCENE_OBJECT_OFFSET_MAX of its own bounding radii from
 * the origin (see scene_prepare): its offsets stay under 6.4% of its radius. */
static int check_object_offsets(const scene *s, json_err *e) {
    if (s->nobj <= 0 || !s->tri_obj || (s->nspheres && !s->sphere_obj)) return 0;
    vec3 *lo = malloc((size_t)s->nobj * sizeof *lo), *hi = malloc((size_t)s->nobj * sizeof *hi);
    if (!lo || !hi) {
        free(lo);
        free(hi);
        return json_fail(e, PM_ENOMEM, "out of memory");
    }
    for (int k = 0; k < s->nobj; k++) {
        lo[k] = v3s(INFINITY);
        hi[k] = v3s(-INFINITY);
    }
    for (int p = 0; p < s->ntris + s->nspheres; p++) {
        vec3 a, b;
        int k = scene_prim_object(s, p);
        if (k < 0 || k >= s->nobj) continue;
        if (p < s->ntris) triangle_bounds(&s->tris[p], &a, &b);
        else sphere_bounds(&s->spheres[p - s->ntris], &a, &b);
        lo[k] = v3_min(lo[k], a);
        hi[k] = v3_max(hi[k], b);
    }
    int rc = 0;
    for (int k = 0; k < s->nobj && rc == 0; k++) {
        if (!(lo[k].x <= hi[k].x)) continue; /* no geometry (a dropped Tungsten primitive) */
        double r = 0.5 * v3_len(v3_sub(hi[k], lo[k])), far = fmax(v3_maxabs(lo[k]), v3_maxabs(hi[k]));
        if (far > SCENE_OBJECT_OFFSET_MAX * r)
            rc = json_fail(e, PM_EINVAL, "$.objects[%d]: the object reaches %g from the origin, more than "
                           "%g times its bounding radius %g (the supported range; ray offsets grow with "
                           "the coordinates and would no longer be small against it); move the scene "
                           "toward the origin", k, far, SCENE_OBJECT_OFFSET_MAX, r);
    }
    free(lo);
    free(hi);
    return rc;
}

/* A light's total power (light.h). */
static rgb light_power(const scene *s, const light *l) {
    switch (l->type) {
    case LIGHT_AREA: return v3_scale(l->Le, M_PI * s->tris[l->tri].area * (l->two_sided ? 2 : 1));
    case LIGHT_SPHERE:
        return v3_scale(l->Le, M_PI * 4 * M_PI * s->spheres[l->sphere].r * s->spheres[l->sphere].r *
                                   (l->two_sided ? 2 : 1));
    case LIGHT_POINT: return v3_scale(l->intensity, 4 * M_PI);
    case LIGHT_SPOT: return v3_scale(l->intensity, 2 * M_PI * light_spot_w(l));
    case LIGHT_INFINITE: /* pi R^2 times int L dw */
        if (s->env_map) return v3_scale(s->env_map->integral, M_PI * s->bsphere_r * s->bsphere_r);
        return v3_scale(l->Le, 4 * M_PI * M_PI * s->bsphere_r * s->bsphere_r);
    default: return v3_scale(l->irradiance, M_PI * s->bsphere_r * s->bsphere_r);
    }
}

int scene_prepare(scene *s, json_err *e) {
    if (s->ntris + s->nspheres == 0)
        return json_fail(e, PM_EINVAL, "$.objects: the scene has no geometry");
    vec3 lo = v3s(INFINITY), hi = v3s(-INFINITY);
    for (int i = 0; i < s->ntris; i++) {
        vec3 a, b;
        triangle_bounds(&s->tris[i], &a, &b);
        lo = v3_min(lo, a);
        hi = v3_max(hi, b);
    }
    for (int i = 0; i < s->nspheres; i++) {
        vec3 a, b;
        sphere_bounds(&s->spheres[i], &a, &b);
        lo = v3_min(lo, a);
        hi = v3_max(hi, b);
    }
    s->bounds_lo = lo;
    s->bounds_hi = hi;
    s->bsphere_c = v3_scale(v3_add(lo, hi), 0.5);
    s->bsphere_r = 0.5 * v3_len(v3_sub(hi, lo));
    if (!(s->bsphere_r >= SCENE_LENGTH_MIN))
        return json_fail(e, PM_EINVAL, "$.objects: the scene's bounding radius %g is below the "
                         "supported range of lengths, %g to %g", s->bsphere_r, SCENE_LENGTH_MIN,
                         SCENE_LENGTH_MAX);
    /* A thousandth of the scene's size: 64e-9 of it is still about 1e5 times the rounding error of
     * a hit point found by a ray from anywhere in the scene, and it shrinks with the scene (a
     * fixed floor of 1 was 1% of a box 5e-6 wide: contact shadows went missing). Not above 1,
     * the old floor: in a large scene the point's own magnitude sets the offset anyway, and a
     * huge sphere (a ground or sky) would otherwise push offsets past the small objects. */
    s->offset_floor = fmin(1.0, 1e-3 * s->bsphere_r);
    /* The other part of a ray offset is 64e-9 of the point's coordinates (vec.h): far from the
     * origin it outgrows the scene's details (a 10-unit box moved 1e8 along x, offsets 6.4
     * units, read 17% dark in path tracing; 3.5e6 radii away -2.7%, 1.2e6 radii +0.2%). 1e5
     * radii keeps every offset under 0.64% of the scene's radius. */
    double far = fmax(v3_maxabs(lo), v3_maxabs(hi));
    if (far > SCENE_OFFSET_MAX * s->bsphere_r)
        return json_fail(e, PM_EINVAL, "$.objects: the scene reaches %g from the origin, more than "
                         "%g times its bounding radius %g (the supported range; ray offsets grow with "
                         "the coordinates and would no longer be small against the scene); move the "
                         "scene toward the origin", far, SCENE_OFFSET_MAX, s->bsphere_r);
    /* And each object against its own size, more loosely (1e6 of its radii): a huge ground
     * sphere makes the scene's radius large, and a 10-unit box 1e8 from the origin on it read
     * 17% dark all the same; a lamp 0.42 across 2e5 of its radii out renders right. */
    int orc = check_object_offsets(s, e);
    if (orc < 0) return orc;
    /* One light per emissive primitive p (numbered as hit.prim): triangles, then spheres. */
    int nemit = 0;
    for (int p = 0; p < s->ntris + s->nspheres; p++)
        nemit += material_is_emissive(&s->mats[p < s->ntris ? s->tris[p].mat
                                                            : s->spheres[p - s->ntris].mat]);
    if (nemit) {
        light *nl = realloc(s->lights, (size_t)(s->nlights + nemit) * sizeof *nl);
        if (!nl) return json_fail(e, PM_ENOMEM, "out of memory");
        s->lights = nl;
    }
    for (int p = 0; p < s->ntris + s->nspheres; p++) {
        int is_tri = p < s->ntris, k = is_tri ? p : p - s->ntris;
        const material *m = &s->mats[is_tri ? s->tris[k].mat : s->spheres[k].mat];
        if (!material_is_emissive(m)) continue;
        light l;
        memset(&l, 0, sizeof l);
        l.type = is_tri ? LIGHT_AREA : LIGHT_SPHERE;
        l.tri = is_tri ? k : -1;
        l.sphere = is_tri ? -1 : k;
        l.Le = m->emission;
        l.two_sided = m->two_sided;
        *(is_tri ? &s->tris[k].light : &s->spheres[k].light) = s->nlights;
        s->lights[s->nlights++] = l;
    }
    double *w = malloc((size_t)(s->nlights ? s->nlights : 1) * sizeof *w);
    if (!w) return json_fail(e, PM_ENOMEM, "out of memory");
    for (int i = 0; i < s->nlights; i++) {
        light *l = &s->lights[i];
        l->power = light_power(s, l);
        if (l->type == LIGHT_INFINITE) s->env_light = i + 1;
        w[i] = (l->power.x + l->power.y + l->power.z) / 3.0;
        if (!isfinite(w[i])) { /* finite inputs whose product overflows */
            double wi = w[i];
            free(w);
            if (l->type == LIGHT_AREA || l->type == LIGHT_SPHERE)
                return json_fail(e, PM_EINVAL, "$.objects[%d]: an emissive %s whose power (pi Le "
                                 "area) is too large to represent (%g): make it smaller or dimmer",
                                 l->type == LIGHT_AREA ? s->tri_obj[l->tri] : s->sphere_obj[l->sphere],
                                 l->type == LIGHT_AREA ? "triangle" : "sphere", wi);
            return json_fail(e, PM_EINVAL, "$.lights[%d]: its power is too large to represent%s", i,
                             l->type == LIGHT_DIRECTIONAL ? " (irradiance times the scene's cross-section)"
                             : l->type == LIGHT_INFINITE ? " (4 pi radiance times the scene's cross-section)" : "");
        }
    }
    double total = 0;
    for (int i = 0; i < s->nlights; i++) total += w[i];
    if (!isfinite(total)) {
        free(w);
        return json_fail(e, PM_EINVAL, "$.lights: the total light power is too large to represent");
    }
    if (total > 0) {
        int rc = distrib1d_init(&s->light_distrib, w, s->nlights);
        if (rc < 0) {
            free(w);
            return json_fail(e, rc, "lights: %s", render_strerror(rc));
        }
    }
    free(w);
    double t_bvh = stats_now();
    clock_t c_bvh = clock(); /* CPU time too: on a shared machine the wall clock says little */
    int rc = bvh_build(&s->accel, s->tris, s->ntris, s->spheres, s->nspheres);
    stats_time_add("Time/BVH build", stats_now() - t_bvh);
    stats_time_add("Time/BVH build (CPU, all threads)", (double)(clock() - c_bvh) / CLOCKS_PER_SEC);
    if (rc < 0) return json_fail(e, rc, "building the BVH: %s", render_strerror(rc));
    return 0;
}

int scene_check_photon_range(const scene *s, json_err *e) {
    /* Photon positions are floats (photonmap/photon.h) and kd-tree distances are squared in
     * float: a search radius r needs r^2 between 1.2e-38 and 3.4e38, and an estimate's radius
     * runs from about 1e-4 of the scene to the scene's size. Far from the origin a float
     * position is coarse: its rounding step is 6e-8 of the coordinate. */
    double R = s->bsphere_r, far = fmax(v3_maxabs(s->bounds_lo), v3_maxabs(s->bounds_hi));
    if (!(R >= SCENE_PM_SIZE_MIN && R <= SCENE_PM_SIZE_MAX))
        return json_fail(e, PM_EINVAL, "$.objects: the scene's bounding radius %g is outside the "
                         "range photon mapping supports, %g to %g (photon positions and squared "
                         "distances are 32-bit floats); scale the scene, or use --mode path", R,
                         SCENE_PM_SIZE_MIN, SCENE_PM_SIZE_MAX);
    if (far > SCENE_PM_OFFSET_MAX * R)
        return json_fail(e, PM_EINVAL, "$.objects: the scene reaches %g from the origin, more "
                         "than %g times its bounding radius %g: photon mapping stores positions "
                         "as 32-bit floats, too coarse there; move the scene to the origin, or "
                         "use --mode path", far, SCENE_PM_OFFSET_MAX, R);
    double total = 0;
    for (int i = 0; i < s->nlights; i++)
        total += (s->lights[i].power.x + s->lights[i].power.y + s->lights[i].power.z) / 3;
    /* A photon carries total / n, n up to 1e8, in a float with a shared 8-bit exponent. */
    if (total > SCENE_PM_POWER_MAX || (total > 0 && total < 1 / SCENE_PM_POWER_MAX))
        return json_fail(e, PM_EINVAL, "$.lights: the scene's total light power %g is outside the "
                         "range photon mapping supports, %g to %g (photon powers are 32-bit "
                         "floats); change the lights' strength, or use --mode path", total,
                         1 / SCENE_PM_POWER_MAX, SCENE_PM_POWER_MAX);
    return 0;
}

/* Member by member: the scene's own arrays (photon_maps.c frees another struct's alike). */
void scene_free(scene *s) {
    free(s->mats);
    free(s->tris);
    free(s->spheres);
    free(s->tri_obj);
    free(s->sphere_obj);
    free(s->tri_ns);
    free(s->media);
    free(s->obj_medium);
    free(s->ports);
    free(s->obj_medium_out);
    free(s->obj_iface);
    free(s->iface_report);
    free(s->lights);
    if (s->env_map) envmap_free(s->env_map);
    free(s->env_map);
    distrib1d_free(&s->light_distrib);
    bvh_free(&s->accel);
    cJSON_Delete(s->photon_mapping);
    memset(s, 0, sizeof *s);
}

int scene_intersect(const scene *s, ray r, double tmax, hit *h) {
    double t, u, v;
    int prim;
    if (!bvh_intersect(&s->accel, r, 0.0, tmax, &t, &prim, &u, &v)) return 0;
    h->t = t;
    h->p = ray_at(r, t);
    h->prim = prim;
    h->u = u;
    h->v = v;
    if (prim < s->ntris) {
        h->ng = s->tris[prim].n;
        h->mat = s->tris[prim].mat;
        h->ns = h->ng;
        if (prim < s->ntri_ns) { /* smooth mesh: barycentric blend of the corner normals */
            const vec3 *n = s->tri_ns[prim];
            vec3 ns = v3_norm(v3_add(v3_scale(n[0], 1 - u - v), v3_add(v3_scale(n[1], u), v3_scale(n[2], v))));
            if (v3_dot(ns, h->ng) > 0) h->ns = ns;
        }
    } else {
        const sphere *sp = &s->spheres[prim - s->ntris];
        h->ng = v3_scale(v3_sub(h->p, sp->c), 1.0 / sp->r);
        h->ng = v3_norm(h->ng);
        h->ns = h->ng;
        h->mat = sp->mat;
    }
    return 1;
}

int scene_visible(const scene *s, vec3 p, vec3 np, vec3 q, vec3 nq) {
    vec3 d = v3_sub(q, p);
    vec3 po = v3_iszero(np) ? p : scene_offset(s, p, np, d);
    vec3 qo = v3_iszero(nq) ? q : scene_offset(s, q, nq, v3_neg(d));
    ray r = {po, v3_sub(qo, po)};
    /* Parametric in [0, 1]: stop just short of q when q is not on a surface. */
    double tmax = v3_iszero(nq) ? 1.0 - 1e-9 : 1.0;
    return !bvh_occluded(&s->accel, r, 0.0, tmax);
}

int scene_visible_dir(const scene *s, vec3 p, vec3 np, vec3 d) {
    ray r = {v3_iszero(np) ? p : scene_offset(s, p, np, d), d};
    return !bvh_occluded(&s->accel, r, 0.0, INFINITY);
}
