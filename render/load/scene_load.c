/* scene_load.c: the JSON scene loader (format: data/scenes/README.md); see scene.h.
 *
 * Loading is one pass over the document with the json.h getters. Each check reports the
 * JSON path of the offending field. Arrays grow with a small push helper; on any error the
 * partly built scene is freed, so the caller never sees half a scene. What follows from the
 * loaded shapes (bounds, the lights of emissive surfaces, the BVH) is scene_prepare's, in
 * scene.c.
 */
#include "scene/scene.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"
#include "load/import.h"
#include "photons/photon_settings.h"

#define P_MAX 256

#define TRY(x) JSON_TRY(x)


/* Append one element of size sz to *arr (count *n, capacity *cap). */
static int push(void **arr, int *n, int *cap, size_t sz, const void *elem) {
    if (*n == *cap) {
        int nc = *cap ? 2 * *cap : 16;
        void *na = realloc(*arr, (size_t)nc * sz);
        if (!na) return PM_ENOMEM;
        *arr = na;
        *cap = nc;
    }
    memcpy((char *)*arr + (size_t)*n * sz, elem, sz);
    (*n)++;
    return 0;
}

typedef struct {
    int tcap, scap, mcap, lcap; /* capacities of tris, spheres, mats, lights */
    int tocap, socap; /* capacities of tri_obj, sphere_obj */
    int obj;          /* index in $.objects of the object being loaded */
} caps;

static int check_unit_rgb(rgb c, const char *path, const char *key, json_err *e) {
    if (c.x < 0 || c.y < 0 || c.z < 0 || c.x > 1 || c.y > 1 || c.z > 1)
        return json_fail(e, PM_EINVAL, "%s.%s: each component must be in [0, 1] (got [%g, %g, %g])",
                         path, key, c.x, c.y, c.z);
    return 0;
}

static int check_nonneg_rgb(rgb c, const char *path, const char *key, json_err *e) {
    if (c.x < 0 || c.y < 0 || c.z < 0)
        return json_fail(e, PM_EINVAL, "%s.%s: must not be negative (got [%g, %g, %g])", path, key,
                         c.x, c.y, c.z);
    return 0;
}

/* Emission (a radiance) and a directional light's irradiance: in [0, SCENE_RADIANCE_MAX].
 * Not a point light's intensity or power: the light they give scales with 1 / length^2, so
 * their range depends on the scene's units (a film value that overflows is counted). */
static int check_light_rgb(rgb c, const char *path, const char *key, json_err *e) {
    TRY(check_nonneg_rgb(c, path, key, e));
    if (v3_maxabs(c) > SCENE_RADIANCE_MAX)
        return json_fail(e, PM_EINVAL, "%s.%s: %g is outside the supported range, 0 to %g (the "
                         "image is stored in 32-bit floats)", path, key, v3_maxabs(c), SCENE_RADIANCE_MAX);
    return 0;
}

/* A medium's coefficient (per unit length): in [0, 1 / SCENE_LENGTH_MIN], a mean free path no
 * shorter than the shortest length the scene may have. */
static int check_sigma_rgb(rgb c, const char *path, const char *key, json_err *e) {
    TRY(check_nonneg_rgb(c, path, key, e));
    if (v3_maxabs(c) > 1 / SCENE_LENGTH_MIN)
        return json_fail(e, PM_EINVAL, "%s.%s: %g is outside the supported range, 0 to %g per unit "
                         "length (a mean free path of at least %g, the shortest supported length)",
                         path, key, v3_maxabs(c), 1 / SCENE_LENGTH_MIN, SCENE_LENGTH_MIN);
    return 0;
}

/* A point light's intensity or power, once the scene's bounds are known: the irradiance it
 * gives at D, the larger of the scene's bounding radius and the light's distance from the
 * scene's centre, is at most SCENE_RADIANCE_MAX (a directional light's limit). Scaled with the
 * scene (I / D^2 is what lights it), so a scene in other units keeps its lights. */
static int check_point_lights(const scene *s, const cJSON *lights, json_err *e) {
    int i = 0;
    char P[P_MAX];
    for (const cJSON *it = lights ? lights->child : NULL; it; it = it->next, i++) {
        if (i >= s->nlights || s->lights[i].type != LIGHT_POINT) continue;
        const light *l = &s->lights[i];
        double D = fmax(s->bsphere_r, v3_len(v3_sub(l->pos, s->bsphere_c)));
        double I = v3_maxabs(l->intensity);
        if (I / (D * D) <= SCENE_RADIANCE_MAX) continue;
        int power = json_get(it, "power") != NULL;
        double f = power ? 4 * M_PI : 1;
        json_path_index(P, sizeof P, "$.lights", i);
        return json_fail(e, PM_EINVAL, "%s.%s: %g is outside the supported range for this scene, 0 "
                         "to %g (a point light's %s at D = %g, the larger of the scene's bounding "
                         "radius and the light's distance from its centre, must be at most %g, as "
                         "a directional light's irradiance: the image is stored in 32-bit floats)",
                         P, power ? "power" : "intensity", f * I, f * SCENE_RADIANCE_MAX * D * D,
                         power ? "irradiance, power / (4 pi D^2)," : "irradiance, intensity / D^2,",
                         D, SCENE_RADIANCE_MAX);
    }
    return 0;
}

/* A point (key NULL: path names it): every coordinate within SCENE_LENGTH_MAX. */
static int check_point(vec3 v, const char *path, const char *key, json_err *e) {
    if (!(v3_maxabs(v) <= SCENE_LENGTH_MAX))
        return json_fail(e, PM_EINVAL, "%s%s%s: [%g, %g, %g] is outside the supported range of "
                         "coordinates, -%g to %g", path, key ? "." : "", key ? key : "", v.x, v.y,
                         v.z, SCENE_LENGTH_MAX, SCENE_LENGTH_MAX);
    return 0;
}


/* The known keys of each object of the format (json_check_keys: any other key is an error
 * that suggests the nearest of these). "comment" is allowed everywhere, as free text. */
#define KEYS(obj, path, what, ...)                                                         \
    do {                                                                                    \
        static const char *const k__[] = {__VA_ARGS__, "comment"};                          \
        TRY(json_check_keys(obj, path, k__, sizeof k__ / sizeof *k__, what, e));            \
    } while (0)

static int load_camera(scene *s, const cJSON *root, json_err *e) {
    const cJSON *c;
    TRY(json_object(root, "$", "camera", 1, &c, e));
    const char *P = "$.camera";
    KEYS(c, P, "the camera", "eye", "look_at", "forward", "up", "fov_deg", "focal_length_mm",
         "sensor_width_mm", "width", "height", "spp");
    vec3 eye, look, fwd, up = v3(0, 1, 0);
    TRY(json_vec3(c, P, "eye", 1, &eye, e));
    TRY(check_point(eye, P, "eye", e));
    int has_look = json_get(c, "look_at") != NULL, has_fwd = json_get(c, "forward") != NULL;
    if (has_look && has_fwd)
        return json_fail(e, PM_EINVAL, "%s: give either look_at or forward, not both", P);
    if (!has_look && !has_fwd)
        return json_fail(e, PM_EINVAL, "%s.look_at: missing (required, or give forward)", P);
    if (has_look) {
        TRY(json_vec3(c, P, "look_at", 1, &look, e));
        TRY(check_point(look, P, "look_at", e));
        fwd = v3_sub(look, eye);
    } else {
        TRY(json_vec3(c, P, "forward", 1, &fwd, e));
    }
    TRY(json_vec3(c, P, "up", 0, &up, e));
    double fov = -1, focal = -1, sensor = 36.0;
    int has_fov = json_get(c, "fov_deg") != NULL, has_focal = json_get(c, "focal_length_mm") != NULL;
    if (has_fov && has_focal)
        return json_fail(e, PM_EINVAL, "%s: give either fov_deg or focal_length_mm, not both", P);
    if (has_fov) {
        TRY(json_number(c, P, "fov_deg", 1, &fov, e));
        if (!(fov > 0 && fov < 180))
            return json_fail(e, PM_EINVAL, "%s.fov_deg: must be in (0, 180), got %g", P, fov);
    } else {
        TRY(json_number(c, P, "focal_length_mm", 1, &focal, e));
        TRY(json_number(c, P, "sensor_width_mm", 0, &sensor, e));
        if (!(focal > 0))
            return json_fail(e, PM_EINVAL, "%s.focal_length_mm: must be positive, got %g", P, focal);
        if (!(sensor > 0))
            return json_fail(e, PM_EINVAL, "%s.sensor_width_mm: must be positive, got %g", P, sensor);
        fov = 2.0 * atan(0.5 * sensor / focal) * 180.0 / M_PI;
    }
    long w, h, spp = 16;
    TRY(json_int(c, P, "width", 1, 1, 1 << 14, &w, e));
    TRY(json_int(c, P, "height", 1, 1, 1 << 14, &h, e));
    TRY(json_int(c, P, "spp", 0, 1, 1 << 20, &spp, e));
    const char *why = "";
    camera_set_spp(&s->cam, (int)spp);
    if (camera_setup(&s->cam, eye, fwd, up, fov, (int)w, (int)h, &why) < 0)
        return json_fail(e, PM_EINVAL, "%s: %s", P, why);
    return 0;
}

/* Oren-Nayar's sigma: the standard deviation of the facets' slope angle, in radians. */
static int check_sigma(double sigma, const char *P, json_err *e) {
    if (!(sigma >= 0 && sigma <= M_PI / 2))
        return json_fail(e, PM_EINVAL, "%s.sigma: %g is outside the supported range, 0 to %.6g "
                         "(radians: the spread of the facets' slope angle; pi/2 is a 90-degree "
                         "spread)", P, sigma, M_PI / 2);
    return 0;
}

static int load_material(material *m, const cJSON *it, const char *P, json_err *e) {
    memset(m, 0, sizeof *m);
    snprintf(m->name, sizeof m->name, "%s", it->string ? it->string : "?");
    if (!cJSON_IsObject(it))
        return json_fail(e, PM_EINVAL, "%s: expected an object, got %s", P, json_type_name(it));
    const char *type;
    TRY(json_string(it, P, "type", 1, &type, e));
    m->specular_tint = v3s(1);
    m->transmit_tint = v3s(1);
    m->ior = 1.5;
    if (strcmp(type, "lambert") == 0) {
        KEYS(it, P, "a lambert material", "type", "reflectance", "emission", "two_sided");
        m->kind = MAT_LAMBERT;
        TRY(json_rgb(it, P, "reflectance", 1, &m->diffuse, e));
        TRY(check_unit_rgb(m->diffuse, P, "reflectance", e));
    } else if (strcmp(type, "oren_nayar") == 0) {
        KEYS(it, P, "an oren_nayar material", "type", "reflectance", "sigma", "emission", "two_sided");
        m->kind = MAT_OREN_NAYAR;
        TRY(json_rgb(it, P, "reflectance", 1, &m->diffuse, e));
        TRY(check_unit_rgb(m->diffuse, P, "reflectance", e));
        TRY(json_number(it, P, "sigma", 1, &m->sigma, e));
        TRY(check_sigma(m->sigma, P, e));
    } else if (strcmp(type, "mirror") == 0) {
        KEYS(it, P, "a mirror material", "type", "reflectance", "emission", "two_sided");
        m->kind = MAT_MIRROR;
        m->specular = 1;
        TRY(json_rgb(it, P, "reflectance", 0, &m->specular_tint, e));
        TRY(check_unit_rgb(m->specular_tint, P, "reflectance", e));
    } else if (strcmp(type, "dielectric") == 0) {
        KEYS(it, P, "a dielectric material", "type", "ior", "tint", "emission", "two_sided");
        m->kind = MAT_DIELECTRIC;
        m->fresnel = 1;
        m->transparency = 1;
        TRY(json_number(it, P, "ior", 1, &m->ior, e));
        TRY(json_rgb(it, P, "tint", 0, &m->transmit_tint, e));
        TRY(check_unit_rgb(m->transmit_tint, P, "tint", e));
    } else if (strcmp(type, "mix") == 0) {
        KEYS(it, P, "a mix material", "type", "specular", "transparency", "ior", "diffuse", "sigma",
             "specular_tint", "transmit_tint", "emission", "two_sided");
        m->kind = MAT_MIX;
        const cJSON *sp = json_get(it, "specular");
        if (cJSON_IsString(sp) && strcmp(sp->valuestring, "fresnel") == 0) {
            m->fresnel = 1;
        } else if (sp && !cJSON_IsNumber(sp)) {
            return json_fail(e, PM_EINVAL, "%s.specular: expected a number in [0, 1] or \"fresnel\", got %s",
                             P, json_type_name(sp));
        } else {
            TRY(json_number(it, P, "specular", 0, &m->specular, e));
            if (m->specular < 0 || m->specular > 1)
                return json_fail(e, PM_EINVAL, "%s.specular: must be in [0, 1], got %g", P, m->specular);
        }
        TRY(json_number(it, P, "transparency", 0, &m->transparency, e));
        if (m->transparency < 0 || m->transparency > 1)
            return json_fail(e, PM_EINVAL, "%s.transparency: must be in [0, 1], got %g", P,
                             m->transparency);
        TRY(json_number(it, P, "ior", 0, &m->ior, e));
        TRY(json_rgb(it, P, "diffuse", 0, &m->diffuse, e));
        TRY(check_unit_rgb(m->diffuse, P, "diffuse", e));
        TRY(json_number(it, P, "sigma", 0, &m->sigma, e));
        TRY(check_sigma(m->sigma, P, e));
        TRY(json_rgb(it, P, "specular_tint", 0, &m->specular_tint, e));
        TRY(check_unit_rgb(m->specular_tint, P, "specular_tint", e));
        TRY(json_rgb(it, P, "transmit_tint", 0, &m->transmit_tint, e));
        TRY(check_unit_rgb(m->transmit_tint, P, "transmit_tint", e));
    } else if (strcmp(type, "null") == 0 || strcmp(type, "interface") == 0) {
        KEYS(it, P, "a null material", "type", "emission", "two_sided");
        m->kind = MAT_NULL; /* invisible: its ior is set to medium_ior by the caller */
        m->transparency = 1;
        if (json_get(it, "emission"))
            return json_fail(e, PM_EINVAL, "%s.emission: a null (invisible) surface cannot emit", P);
    } else {
        return json_fail(e, PM_EINVAL,
                         "%s.type: unknown material type \"%s\" (lambert, oren_nayar, mirror, "
                         "dielectric, mix, null)", P, type);
    }
    if (!(m->ior > 0)) return json_fail(e, PM_EINVAL, "%s.ior: must be positive, got %g", P, m->ior);
    TRY(json_rgb(it, P, "emission", 0, &m->emission, e));
    TRY(check_light_rgb(m->emission, P, "emission", e));
    TRY(json_bool(it, P, "two_sided", 0, &m->two_sided, e));
    return 0;
}

static int find_material(const scene *s, const cJSON *obj, const char *P, int *out, json_err *e) {
    const char *name;
    TRY(json_string(obj, P, "material", 1, &name, e));
    for (int i = 0; i < s->nmats; i++)
        if (strcmp(s->mats[i].name, name) == 0) {
            *out = i;
            return 0;
        }
    return json_fail(e, PM_EINVAL, "%s.material: unknown material \"%s\"", P, name);
}

static int add_tri(scene *s, caps *cp, vec3 a, vec3 b, vec3 c, int mat, const char *P,
                   json_err *e) {
    triangle t;
    TRY(check_point(a, P, NULL, e));
    TRY(check_point(b, P, NULL, e));
    TRY(check_point(c, P, NULL, e));
    double longest = fmax(v3_len(v3_sub(b, a)), fmax(v3_len(v3_sub(c, b)), v3_len(v3_sub(a, c))));
    if (longest > 0 && longest < SCENE_LENGTH_MIN)
        return json_fail(e, PM_EINVAL, "%s: a triangle %g across is below the supported range of "
                         "lengths, %g to %g", P, longest, SCENE_LENGTH_MIN, SCENE_LENGTH_MAX);
    if (triangle_make(&t, a, b, c, mat) < 0)
        return json_fail(e, PM_EINVAL, "%s: degenerate triangle (zero area: repeated or collinear vertices)", P);
    int n = s->ntris;
    if (push((void **)&s->tris, &s->ntris, &cp->tcap, sizeof t, &t) < 0 ||
        push((void **)&s->tri_obj, &n, &cp->tocap, sizeof cp->obj, &cp->obj) < 0)
        return json_fail(e, PM_ENOMEM, "out of memory");
    return 0;
}

/* Read exactly n points from key into v. */
static int read_points(const cJSON *obj, const char *P, const char *key, int n, vec3 *v,
                       json_err *e) {
    const cJSON *arr;
    TRY(json_array(obj, P, key, 1, &arr, e));
    if (cJSON_GetArraySize(arr) != n)
        return json_fail(e, PM_EINVAL, "%s.%s: expected %d points, got %d", P, key, n,
                         cJSON_GetArraySize(arr));
    char p[P_MAX], pk[P_MAX];
    json_path_key(pk, sizeof pk, P, key);
    for (int i = 0; i < n; i++) {
        json_path_index(p, sizeof p, pk, i);
        TRY(json_item_vec3(cJSON_GetArrayItem(arr, i), p, &v[i], e));
    }
    return 0;
}

/* A mesh from a file (import.h): its triangles, their materials (usemtl names or "material")
 * and, when smooth, their corner normals in s->tri_ns. */
static int load_mesh_file(scene *s, caps *cp, const cJSON *o, const char *P, json_err *e) {
    mesh_data m;
    int smooth, usemtl, def = -1, rc = 0;
    TRY(mesh_object_read(o, P, &m, &smooth, &usemtl, e));
    if (json_get(o, "material")) rc = find_material(s, o, P, &def, e);
    int *gmat = calloc((size_t)m.ngroups + 1, sizeof *gmat);
    if (!gmat) rc = json_fail(e, PM_ENOMEM, "out of memory");
    for (int g = 0; g < m.ngroups && rc == 0 && usemtl; g++) {
        gmat[g] = -1;
        for (int i = 0; i < s->nmats; i++)
            if (strcmp(s->mats[i].name, m.groups[g]) == 0) gmat[g] = i;
        if (gmat[g] < 0)
            rc = json_fail(e, PM_EINVAL, "%s.file: usemtl \"%s\" names no material in $.materials", P, m.groups[g]);
    }
    int first = s->ntris;
    for (int t = 0; t < m.ntris && rc == 0; t++) {
        int g = m.tri_group[t], mat = usemtl && g >= 0 ? gmat[g] : def;
        if (mat < 0) {
            rc = json_fail(e, PM_EINVAL, "%s.material: missing (required for the faces before any usemtl)", P);
            break;
        }
        rc = add_tri(s, cp, m.pos[m.tri[t][0]], m.pos[m.tri[t][1]], m.pos[m.tri[t][2]], mat, P, e);
    }
    if (rc == 0 && smooth) { /* corner normals for every triangle so far; flat ones get n */
        vec3(*ns)[3] = realloc(s->tri_ns, (size_t)s->ntris * sizeof *ns);
        if (!ns) {
            rc = json_fail(e, PM_ENOMEM, "out of memory");
        } else {
            s->tri_ns = ns;
            for (int t = s->ntri_ns; t < first; t++) ns[t][0] = ns[t][1] = ns[t][2] = s->tris[t].n;
            memcpy(ns + first, m.corner_n, (size_t)m.ntris * sizeof *ns);
            s->ntri_ns = s->ntris;
        }
    }
    free(gmat);
    mesh_free(&m);
    return rc;
}

static int load_object(scene *s, caps *cp, const cJSON *o, const char *P, json_err *e) {
    if (!cJSON_IsObject(o))
        return json_fail(e, PM_EINVAL, "%s: expected an object, got %s", P, json_type_name(o));
    const char *type;
    int mat;
    TRY(json_string(o, P, "type", 1, &type, e));
    if (strcmp(type, "sphere") == 0) {
        KEYS(o, P, "a sphere", "type", "name", "center", "radius", "material", "interior_medium");
        sphere sp;
        TRY(json_vec3(o, P, "center", 1, &sp.c, e));
        TRY(check_point(sp.c, P, "center", e));
        TRY(json_number(o, P, "radius", 1, &sp.r, e));
        if (!(sp.r > 0))
            return json_fail(e, PM_EINVAL, "%s.radius: must be positive, got %g", P, sp.r);
        if (!(sp.r >= SCENE_LENGTH_MIN && sp.r <= SCENE_LENGTH_MAX))
            return json_fail(e, PM_EINVAL, "%s.radius: %g is outside the supported range of "
                             "lengths, %g to %g", P, sp.r, SCENE_LENGTH_MIN, SCENE_LENGTH_MAX);
        TRY(find_material(s, o, P, &mat, e));
        sp.mat = mat;
        sp.light = -1;
        int n = s->nspheres;
        if (push((void **)&s->spheres, &s->nspheres, &cp->scap, sizeof sp, &sp) < 0 ||
            push((void **)&s->sphere_obj, &n, &cp->socap, sizeof cp->obj, &cp->obj) < 0)
            return json_fail(e, PM_ENOMEM, "out of memory");
    } else if (strcmp(type, "triangle") == 0 || strcmp(type, "quad") == 0) {
        int nv = strcmp(type, "quad") == 0 ? 4 : 3; /* a quad is the fan (0 1 2) (0 2 3) */
        KEYS(o, P, nv == 4 ? "a quad" : "a triangle", "type", "name", "vertices", "material",
             "interior_medium");
        vec3 v[4];
        TRY(read_points(o, P, "vertices", nv, v, e));
        TRY(find_material(s, o, P, &mat, e));
        for (int i = 1; i + 1 < nv; i++) TRY(add_tri(s, cp, v[0], v[i], v[i + 1], mat, P, e));
    } else if (strcmp(type, "mesh") == 0 && json_get(o, "file")) {
        KEYS(o, P, "a mesh from a file", "type", "name", "file", "material", "usemtl", "transform", "smooth",
             "recompute_normals", "interior_medium", "vertices", "triangles"); /* import.c: not both */
        return load_mesh_file(s, cp, o, P, e);
    } else if (strcmp(type, "mesh") == 0) {
        KEYS(o, P, "a mesh", "type", "name", "vertices", "triangles", "material", "interior_medium", "file");
        const cJSON *va, *ta;
        TRY(json_array(o, P, "vertices", 1, &va, e));
        TRY(json_array(o, P, "triangles", 1, &ta, e));
        TRY(find_material(s, o, P, &mat, e));
        int nv = cJSON_GetArraySize(va), nt = cJSON_GetArraySize(ta);
        if (nt == 0) return json_fail(e, PM_EINVAL, "%s.triangles: empty mesh", P);
        vec3 *v = malloc((size_t)(nv > 0 ? nv : 1) * sizeof *v);
        if (!v) return json_fail(e, PM_ENOMEM, "out of memory");
        char pk[P_MAX], p[P_MAX];
        int rc = 0, i = 0;
        json_path_key(pk, sizeof pk, P, "vertices");
        for (const cJSON *it = va->child; it && rc == 0; it = it->next, i++) {
            json_path_index(p, sizeof p, pk, i);
            rc = json_item_vec3(it, p, &v[i], e);
        }
        json_path_key(pk, sizeof pk, P, "triangles");
        i = 0;
        for (const cJSON *it = ta->child; it && rc == 0; it = it->next, i++) {
            json_path_index(p, sizeof p, pk, i);
            vec3 idx;
            rc = json_item_vec3(it, p, &idx, e);
            if (rc < 0) break;
            double ix[3] = {idx.x, idx.y, idx.z};
            for (int k = 0; k < 3 && rc == 0; k++)
                if (ix[k] != floor(ix[k]) || ix[k] < 0 || ix[k] >= nv)
                    rc = json_fail(e, PM_EINVAL, "%s[%d]: vertex index %g is not an integer in [0, %d)",
                                   p, k, ix[k], nv);
            if (rc == 0) rc = add_tri(s, cp, v[(int)ix[0]], v[(int)ix[1]], v[(int)ix[2]], mat, p, e);
        }
        free(v);
        return rc;
    } else {
        return json_fail(e, PM_EINVAL,
                         "%s.type: unknown object type \"%s\" (sphere, triangle, quad, mesh)", P, type);
    }
    return 0;
}

static int load_light(scene *s, caps *cp, const cJSON *o, const char *P, json_err *e) {
    if (!cJSON_IsObject(o))
        return json_fail(e, PM_EINVAL, "%s: expected an object, got %s", P, json_type_name(o));
    const char *type;
    light l;
    memset(&l, 0, sizeof l);
    l.tri = -1;
    TRY(json_string(o, P, "type", 1, &type, e));
    if (strcmp(type, "point") == 0) {
        KEYS(o, P, "a point light", "type", "position", "intensity", "power");
        l.type = LIGHT_POINT;
        TRY(json_vec3(o, P, "position", 1, &l.pos, e));
        TRY(check_point(l.pos, P, "position", e));
        int has_i = json_get(o, "intensity") != NULL, has_p = json_get(o, "power") != NULL;
        if (has_i == has_p)
            return json_fail(e, PM_EINVAL, "%s: give exactly one of intensity (W/sr) or power (W)", P);
        if (has_i) {
            TRY(json_rgb(o, P, "intensity", 1, &l.intensity, e));
            TRY(check_nonneg_rgb(l.intensity, P, "intensity", e));
        } else {
            rgb pw;
            TRY(json_rgb(o, P, "power", 1, &pw, e));
            TRY(check_nonneg_rgb(pw, P, "power", e));
            l.intensity = v3_scale(pw, 1.0 / (4 * M_PI));
        }
    } else if (strcmp(type, "directional") == 0) {
        KEYS(o, P, "a directional light", "type", "direction", "irradiance");
        l.type = LIGHT_DIRECTIONAL;
        TRY(json_vec3(o, P, "direction", 1, &l.dir, e));
        if (!(v3_len(l.dir) > 0))
            return json_fail(e, PM_EINVAL, "%s.direction: must not be the zero vector", P);
        l.dir = v3_norm(l.dir);
        TRY(json_rgb(o, P, "irradiance", 1, &l.irradiance, e));
        TRY(check_light_rgb(l.irradiance, P, "irradiance", e));
    } else {
        return json_fail(e, PM_EINVAL,
                         "%s.type: unknown light type \"%s\" (point, directional; area lights are "
                         "objects with an emissive material)", P, type);
    }
    if (push((void **)&s->lights, &s->nlights, &cp->lcap, sizeof l, &l) < 0)
        return json_fail(e, PM_ENOMEM, "out of memory");
    return 0;
}

static int load_settings(scene *s, const cJSON *root, json_err *e) {
    render_settings *st = &s->settings;
    st->max_depth = 64;
    st->rr_depth = 3;
    snprintf(st->mode, sizeof st->mode, "path");
    st->seed = 1;
    st->tone = TONE_FILMIC;
    st->clip_percent = 1.0;
    st->exposure = 0;
    st->time = 0;
    st->pass_spp = 0;
    const cJSON *r, *im;
    TRY(json_object(root, "$", "render", 0, &r, e));
    if (r) {
        KEYS(r, "$.render", "the render settings", "mode", "max_depth", "rr_depth", "seed", "time",
             "pass_spp");
        long v;
        v = st->max_depth;
        TRY(json_int(r, "$.render", "max_depth", 0, 1, 100000, &v, e));
        st->max_depth = (int)v;
        v = st->rr_depth;
        TRY(json_int(r, "$.render", "rr_depth", 0, 0, 100000, &v, e));
        st->rr_depth = (int)v;
        v = (long)st->seed;
        TRY(json_int(r, "$.render", "seed", 0, 0, 2147483647L, &v, e));
        st->seed = (uint64_t)v;
        /* A time budget: render in passes (run/passes.h) for this many seconds. */
        double tb = 0;
        TRY(json_number(r, "$.render", "time", 0, &tb, e));
        if (json_get(r, "time") && !(tb > 0 && tb <= 1e9))
            return json_fail(e, PM_EINVAL, "$.render.time: expected seconds in (0, 1e9], got %g", tb);
        st->time = tb;
        v = 0;
        TRY(json_int(r, "$.render", "pass_spp", 0, 1, 1 << 20, &v, e));
        st->pass_spp = (int)v;
        const char *mode = NULL;
        TRY(json_string(r, "$.render", "mode", 0, &mode, e));
        if (mode) snprintf(st->mode, sizeof st->mode, "%s", mode);
    }
    TRY(json_object(root, "$", "image", 0, &im, e));
    if (im) {
        KEYS(im, "$.image", "the image settings", "tone", "clip_percent", "exposure");
        const char *tone = NULL;
        TRY(json_string(im, "$.image", "tone", 0, &tone, e));
        if (tone) {
            if (strcmp(tone, "filmic") == 0)
                st->tone = TONE_FILMIC;
            else if (strcmp(tone, "srgb") == 0)
                st->tone = TONE_SRGB;
            else
                return json_fail(e, PM_EINVAL, "$.image.tone: expected \"filmic\" or \"srgb\", got \"%s\"", tone);
        }
        TRY(json_number(im, "$.image", "clip_percent", 0, &st->clip_percent, e));
        if (!(st->clip_percent >= 0 && st->clip_percent < 100))
            return json_fail(e, PM_EINVAL, "$.image.clip_percent: must be in [0, 100), got %g",
                             st->clip_percent);
        TRY(json_number(im, "$.image", "exposure", 0, &st->exposure, e));
        if (st->exposure < 0)
            return json_fail(e, PM_EINVAL, "$.image.exposure: must be positive (or 0 for auto), got %g",
                             st->exposure);
    }
    return 0;
}

/* "comment" is allowed in every object of the format, also in the maps of named materials
 * and media, where a text under that key is a comment, not a material or medium (an object
 * under it is one named "comment"). */
static int is_comment(const cJSON *it) {
    return it->string && strcmp(it->string, "comment") == 0 && cJSON_IsString(it);
}

/* $.media: named homogeneous media (medium.h). */
static int load_media(scene *s, const cJSON *root, json_err *e) {
    const cJSON *ms;
    TRY(json_object(root, "$", "media", 0, &ms, e));
    int n = ms ? cJSON_GetArraySize(ms) : 0;
    if (n == 0) return 0;
    s->media = calloc((size_t)n, sizeof *s->media);
    if (!s->media) return json_fail(e, PM_ENOMEM, "out of memory");
    char P[P_MAX];
    for (const cJSON *it = ms->child; it; it = it->next) {
        if (is_comment(it)) continue;
        medium *m = &s->media[s->nmedia];
        json_path_key(P, sizeof P, "$.media", it->string ? it->string : "?");
        if (!cJSON_IsObject(it))
            return json_fail(e, PM_EINVAL, "%s: expected an object, got %s", P, json_type_name(it));
        if (strlen(it->string) >= sizeof m->name)
            return json_fail(e, PM_EINVAL, "%s: medium name too long (max %d characters)", P,
                             (int)sizeof m->name - 1);
        snprintf(m->name, sizeof m->name, "%s", it->string);
        KEYS(it, P, "a medium", "sigma_a", "sigma_s", "g");
        TRY(json_rgb(it, P, "sigma_a", 0, &m->sigma_a, e));
        TRY(check_sigma_rgb(m->sigma_a, P, "sigma_a", e));
        TRY(json_rgb(it, P, "sigma_s", 0, &m->sigma_s, e));
        TRY(check_sigma_rgb(m->sigma_s, P, "sigma_s", e));
        TRY(json_number(it, P, "g", 0, &m->g, e));
        if (!(m->g > -1 && m->g < 1))
            return json_fail(e, PM_EINVAL, "%s.g: must be in (-1, 1), got %g", P, m->g);
        m->sigma_t = v3_add(m->sigma_a, m->sigma_s);
        s->nmedia++;
    }
    return 0;
}

/* The index of the medium named by the string at obj.key, in *out. */
static int find_medium(const scene *s, const cJSON *obj, const char *P, const char *key, int *out,
                       json_err *e) {
    const char *name;
    TRY(json_string(obj, P, key, 1, &name, e));
    for (int i = 0; i < s->nmedia; i++)
        if (strcmp(s->media[i].name, name) == 0) {
            *out = i;
            return 0;
        }
    return json_fail(e, PM_EINVAL, "%s.%s: unknown medium \"%s\" (not in $.media)", P, key, name);
}

/* x rounded to float (the closedness check's tolerance, below). */
static double as_float(double x) {
    float f = (float)x;
    return (double)f;
}

/* Edge order for the closedness check: the 6 coordinates of a directed edge. */
static int edge_cmp(const void *a, const void *b) {
    const double *x = a, *y = b;
    for (int k = 0; k < 6; k++)
        if (x[k] != y[k]) return x[k] < y[k] ? -1 : 1;
    return 0;
}

/* Triangles first..s->ntris-1 bound a medium only if they form a closed, consistently wound
 * surface whose normals point out: each directed edge (by vertex position) appears once and
 * its reverse once, and the enclosed signed volume is positive. A triangle keeps v0 and two
 * edge vectors, so its other corners come back as v0 + e, which can miss the loaded vertex by
 * a rounding of the double: positions are compared rounded to float (vertices closer than
 * float precision count as one, which only makes the check more lenient). */
static int check_closed(const scene *s, int first, const char *P, json_err *e) {
    int nt = s->ntris - first;
    if (nt < 4)
        return json_fail(e, PM_EINVAL, "%s.interior_medium: a medium needs a closed surface "
                         "(this one has %d triangles)", P, nt);
    double(*ed)[6] = malloc((size_t)nt * 3 * sizeof *ed);
    if (!ed) return json_fail(e, PM_ENOMEM, "out of memory");
    double vol = 0;
    for (int t = 0; t < nt; t++) {
        const triangle *tr = &s->tris[first + t];
        vec3 v[3] = {tr->v0, v3_add(tr->v0, tr->e1), v3_add(tr->v0, tr->e2)};
        vol += v3_dot(v[0], v3_cross(v[1], v[2])) / 6;
        for (int k = 0; k < 3; k++) {
            vec3 a = v[k], b = v[(k + 1) % 3];
            double *d = ed[3 * t + k];
            const double c[6] = {a.x, a.y, a.z, b.x, b.y, b.z};
            for (int j = 0; j < 6; j++) d[j] = as_float(c[j]);
        }
    }
    int n = 3 * nt, bad = 0;
    qsort(ed, (size_t)n, sizeof *ed, edge_cmp);
    for (int i = 0; i < n && !bad; i++) {
        double rev[6] = {ed[i][3], ed[i][4], ed[i][5], ed[i][0], ed[i][1], ed[i][2]};
        if (i + 1 < n && edge_cmp(ed[i], ed[i + 1]) == 0) bad = 1; /* an edge used twice one way */
        else if (!bsearch(rev, ed, (size_t)n, sizeof *ed, edge_cmp)) bad = 2; /* an open edge */
    }
    free(ed);
    if (bad)
        return json_fail(e, PM_EINVAL, "%s.interior_medium: a medium needs a closed surface, "
                         "consistently wound (%s)", P,
                         bad == 1 ? "an edge is shared by faces of the same winding"
                                  : "an edge belongs to one face only: the mesh is open");
    if (!(vol > 0))
        return json_fail(e, PM_EINVAL, "%s.interior_medium: the surface's normals point inward "
                         "(reverse the winding so the front side is the outside)", P);
    return 0;
}

/* An object's "interior_medium": spheres and closed meshes only. */
static int load_interior_medium(scene *s, const cJSON *o, const char *P, int obj, int first_tri,
                                json_err *e) {
    if (!json_get(o, "interior_medium")) return 0;
    int med;
    TRY(find_medium(s, o, P, "interior_medium", &med, e));
    const char *type = json_get(o, "type")->valuestring;
    if (strcmp(type, "triangle") == 0 || strcmp(type, "quad") == 0)
        return json_fail(e, PM_EINVAL, "%s.interior_medium: a %s is open and cannot bound a medium "
                         "(use a sphere or a closed mesh)", P, type);
    if (strcmp(type, "mesh") == 0) TRY(check_closed(s, first_tri, P, e));
    s->obj_medium[obj] = med;
    return 0;
}

/* Which medium the camera is in: the side of the nearest surface a ray from the eye meets
 * (the rule of medium.h); the global medium when it meets nothing. */
static void find_camera_medium(scene *s) {
    s->camera_medium = s->global_medium;
    if (s->nmedia == 0) return;
    ray r = {s->cam.eye, s->cam.forward};
    hit h;
    if (scene_intersect(s, r, INFINITY, &h))
        s->camera_medium = scene_medium_after(s, &h, v3_neg(r.d));
}

static int from_json(scene *s, const cJSON *root, json_err *e) {
    caps cp = {0};
    if (!cJSON_IsObject(root))
        return json_fail(e, PM_EINVAL, "$: expected an object, got %s", json_type_name(root));
    KEYS(root, "$", "a scene", "camera", "materials", "objects", "lights", "medium_ior", "media",
         "medium", "render", "image", "photon_mapping", "description");
    TRY(load_camera(s, root, e));
    TRY(load_settings(s, root, e));
    s->medium_ior = 1.0;
    TRY(json_number(root, "$", "medium_ior", 0, &s->medium_ior, e));
    if (!(s->medium_ior > 0))
        return json_fail(e, PM_EINVAL, "$.medium_ior: must be positive, got %g", s->medium_ior);
    s->global_medium = -1;
    TRY(load_media(s, root, e));
    if (json_get(root, "medium")) TRY(find_medium(s, root, "$", "medium", &s->global_medium, e));
    const cJSON *mats, *objs, *lights, *pm;
    TRY(json_object(root, "$", "materials", 1, &mats, e));
    char p[P_MAX];
    for (const cJSON *it = mats->child; it; it = it->next) {
        if (is_comment(it)) continue;
        material m;
        json_path_key(p, sizeof p, "$.materials", it->string ? it->string : "?");
        if (it->string && strlen(it->string) >= sizeof m.name)
            return json_fail(e, PM_EINVAL, "%s: material name too long (max %d characters)", p,
                             (int)sizeof m.name - 1);
        TRY(load_material(&m, it, p, e));
        if (m.kind == MAT_NULL) {
            m.ior = s->medium_ior;
            s->has_null = 1;
        }
        if (push((void **)&s->mats, &s->nmats, &cp.mcap, sizeof m, &m) < 0)
            return json_fail(e, PM_ENOMEM, "out of memory");
    }
    TRY(json_array(root, "$", "objects", 1, &objs, e));
    int i = 0;
    s->nobj = cJSON_GetArraySize(objs);
    s->obj_medium = malloc((size_t)(s->nobj > 0 ? s->nobj : 1) * sizeof *s->obj_medium);
    if (!s->obj_medium) return json_fail(e, PM_ENOMEM, "out of memory");
    for (int k = 0; k < s->nobj; k++) s->obj_medium[k] = -1;
    for (const cJSON *it = objs->child; it; it = it->next, i++) {
        json_path_index(p, sizeof p, "$.objects", i);
        cp.obj = i;
        int first_tri = s->ntris;
        TRY(load_object(s, &cp, it, p, e));
        TRY(load_interior_medium(s, it, p, i, first_tri, e));
    }
    TRY(json_array(root, "$", "lights", 0, &lights, e));
    i = 0;
    for (const cJSON *it = lights ? lights->child : NULL; it; it = it->next, i++) {
        json_path_index(p, sizeof p, "$.lights", i);
        TRY(load_light(s, &cp, it, p, e));
    }
    TRY(json_object(root, "$", "photon_mapping", 0, &pm, e));
    if (pm) {
        /* Checked here, whatever will read it (any mode, render --dump-scene, render-mpi): a
         * misspelt or out-of-range setting is an error of the file. */
        photon_settings ps;
        TRY(photon_settings_parse(&ps, pm, e));
        s->photon_mapping = cJSON_Duplicate(pm, 1);
        if (!s->photon_mapping) return json_fail(e, PM_ENOMEM, "out of memory");
    }
    TRY(scene_prepare(s, e));
    TRY(check_point_lights(s, lights, e));
    find_camera_medium(s);
    return 0;
}

int scene_from_json(scene *s, const cJSON *root, json_err *e) {
    memset(s, 0, sizeof *s);
    int rc = from_json(s, root, e);
    if (rc < 0) scene_free(s);
    return rc;
}

/* A parsed document (rc from its parser) to a scene: Tungsten scenes converted and mesh
 * paths resolved (import.h; filename NULL for a text), then loaded; the document is freed. */
static int load_parsed(scene *s, int rc, cJSON *root, const char *filename, json_err *e) {
    if (rc < 0) return rc;
    rc = scene_import(&root, filename, e);
    if (rc == 0) rc = scene_from_json(s, root, e);
    cJSON_Delete(root);
    return rc;
}

int scene_load_text(scene *s, const char *text, json_err *e) {
    cJSON *root = NULL;
    memset(s, 0, sizeof *s);
    int rc = json_parse_text(text, &root, e);
    return load_parsed(s, rc, root, NULL, e);
}

int scene_load(scene *s, const char *filename, json_err *e) {
    cJSON *root = NULL;
    memset(s, 0, sizeof *s);
    int rc = json_parse_file(filename, &root, e);
    rc = load_parsed(s, rc, root, filename, e);
    if (rc == 0) snprintf(s->file, sizeof s->file, "%s", filename);
    return rc;
}
