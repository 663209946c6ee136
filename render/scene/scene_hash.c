/* scene_hash.c: the scene's transport fingerprint (see scene_hash.h). Each value goes into
 * the hash as 8 little-endian bytes; every array is preceded by its length, so moving a value
 * from one array to the next changes the hash.
 */
#include "scene/scene_hash.h"

#include <string.h>

#include "base/hash.h"
#include "scene/envmap.h"
#include "scene/medium.h"

static uint64_t hash_u64(uint64_t h, uint64_t v) {
    unsigned char b[8];
    for (int i = 0; i < 8; i++) b[i] = (unsigned char)(v >> (8 * i));
    return hash_fnv1a(h, b, sizeof b);
}

uint64_t hash_double(uint64_t h, double v) {
    uint64_t u;
    memcpy(&u, &v, sizeof u);
    return hash_u64(h, u);
}

uint64_t hash_int(uint64_t h, int64_t v) { return hash_u64(h, (uint64_t)v); }

static uint64_t hash_vec(uint64_t h, vec3 v) {
    return hash_double(hash_double(hash_double(h, v.x), v.y), v.z);
}

/* Field by field, in a fixed order, not a hash of the bytes: padding and pointers would change
 * the hash. hash_light below is alike for another struct. */
static uint64_t hash_material(uint64_t h, const material *m) {
    h = hash_vec(h, m->diffuse);
    h = hash_double(h, m->sigma);
    h = hash_double(h, m->specular);
    h = hash_int(h, m->fresnel);
    h = hash_vec(h, m->specular_tint);
    h = hash_double(h, m->transparency);
    h = hash_vec(h, m->transmit_tint);
    h = hash_double(h, m->ior);
    h = hash_vec(h, m->emission);
    return hash_int(h, m->two_sided);
}

static uint64_t hash_light(uint64_t h, const light *l) {
    h = hash_int(h, l->type);
    h = hash_int(h, l->tri);
    h = hash_int(h, l->sphere);
    h = hash_vec(h, l->pos);
    h = hash_vec(h, l->dir);
    h = hash_vec(h, l->Le);
    h = hash_vec(h, l->intensity);
    h = hash_vec(h, l->irradiance);
    h = hash_int(h, l->two_sided);
    h = hash_vec(h, l->power);
    if (l->type == LIGHT_SPOT) /* only for the newer types: older scenes keep their hashes */
        h = hash_int(hash_double(hash_double(h, l->cos_total), l->cos_start), l->falloff);
    return h;
}

uint64_t scene_transport_hash(const scene *s) {
    uint64_t h = HASH_FNV_INIT;
    h = hash_int(h, s->ntris);
    for (int i = 0; i < s->ntris; i++) {
        const triangle *t = &s->tris[i];
        h = hash_vec(hash_vec(hash_vec(hash_vec(h, t->v0), t->e1), t->e2), t->n);
        h = hash_int(hash_int(h, t->mat), t->light);
    }
    h = hash_int(h, s->tri_ns ? s->ntri_ns : 0);
    for (int i = 0; s->tri_ns && i < s->ntri_ns; i++)
        for (int c = 0; c < 3; c++) h = hash_vec(h, s->tri_ns[i][c]);
    h = hash_int(h, s->nspheres);
    for (int i = 0; i < s->nspheres; i++) {
        const sphere *sp = &s->spheres[i];
        h = hash_double(hash_vec(h, sp->c), sp->r);
        h = hash_int(hash_int(h, sp->mat), sp->light);
    }
    h = hash_int(h, s->nmats);
    for (int i = 0; i < s->nmats; i++) h = hash_material(h, &s->mats[i]);
    h = hash_int(h, s->nlights);
    for (int i = 0; i < s->nlights; i++) h = hash_light(h, &s->lights[i]);
    if (s->env_map) { /* an infinite light's image (only then: older scenes keep their hashes) */
        const envmap *m = s->env_map;
        h = hash_int(hash_int(h, m->w), m->h);
        for (int i = 0; i < 9; i++) h = hash_double(h, m->frame[i / 3][i % 3]);
        for (size_t i = 0; i < 3 * (size_t)m->w * (size_t)m->h; i++) h = hash_double(h, m->px[i]);
    }
    h = hash_double(h, s->medium_ior);
    h = hash_int(h, s->nmedia);
    for (int i = 0; i < s->nmedia; i++) {
        const medium *m = &s->media[i];
        h = hash_double(hash_vec(hash_vec(h, m->sigma_a), m->sigma_s), m->g);
    }
    h = hash_int(h, s->global_medium);
    h = hash_int(h, s->obj_medium ? s->nobj : 0);
    for (int i = 0; s->obj_medium && i < s->nobj; i++) h = hash_int(h, s->obj_medium[i]);
    /* interfaces (medium.h): only when some object has one, so older scenes hash as before */
    for (int i = 0; s->obj_iface && s->obj_medium_out && i < s->nobj; i++)
        h = hash_int(hash_int(h, s->obj_iface[i]), s->obj_medium_out[i]);
    return h;
}
