/* import.c: preparing foreign scene files and mesh objects for the scene loader; see import.h.
 *
 * A relative mesh path is joined to the scene file's directory and then made absolute with
 * realpath, so a dumped scene loads from wherever it is saved. (A path that does not resolve
 * stays joined; loading it then reports the missing file by that name.)
 */
#define _XOPEN_SOURCE 700
#include "load/import.h"

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "common.h"
#include "scene/scene.h"
#include "base/stats.h"
#include "load/pbrt.h"
#include "load/tungsten.h"

#define TRY(x) JSON_TRY(x)

/* The directory part of path ("" for a bare name). */
static void dir_of(const char *path, char *dir, size_t cap) {
    const char *s = path ? strrchr(path, '/') : NULL;
    if (!s) {
        dir[0] = 0;
        return;
    }
    size_t n = (size_t)(s - path);
    if (n == 0) n = 1; /* "/x.json": the root */
    if (n >= cap) n = cap - 1;
    memcpy(dir, path, n);
    dir[n] = 0;
}

int scene_import(cJSON **root, const char *scene_path, json_err *e) {
    char dir[4096];
    dir_of(scene_path, dir, sizeof dir);
    double t0 = stats_now();
    if (tungsten_is_scene(*root)) {
        cJSON *out;
        TRY(tungsten_convert(*root, dir, scene_path, &out, e));
        cJSON_Delete(*root);
        *root = out;
        stats_time_add("Time/Mesh loading", stats_now() - t0);
    }
    /* the objects' mesh files and the lights' images (an infinite light's "map") */
    for (int k = 0; k < 2; k++) {
        const cJSON *arr = cJSON_IsObject(*root) ? json_get(*root, k ? "lights" : "objects") : NULL;
        if (!cJSON_IsArray(arr)) continue;
        for (cJSON *o = arr->child; o; o = o->next) {
            const char *key = k ? "map" : "file";
            cJSON *f = cJSON_IsObject(o) ? cJSON_GetObjectItemCaseSensitive(o, key) : NULL;
            if (!cJSON_IsString(f) || f->valuestring[0] == '/') continue;
            char path[8192], real[PATH_MAX];
            if (dir[0])
                snprintf(path, sizeof path, "%s/%s", dir, f->valuestring);
            else
                snprintf(path, sizeof path, "%s", f->valuestring);
            cJSON *nf = cJSON_CreateString(realpath(path, real) ? real : path);
            if (!nf) return json_fail(e, PM_ENOMEM, "out of memory");
            cJSON_ReplaceItemInObjectCaseSensitive(o, key, nf);
        }
    }
    return 0;
}

int mesh_object_read(const cJSON *o, const char *P, mesh_data *m, int *smooth, int *usemtl, json_err *e) {
    memset(m, 0, sizeof *m);
    const char *file;
    int recompute = 0;
    *smooth = 0;
    *usemtl = 1;
    TRY(json_string(o, P, "file", 1, &file, e));
    TRY(json_bool(o, P, "smooth", 0, smooth, e));
    TRY(json_bool(o, P, "recompute_normals", 0, &recompute, e));
    TRY(json_bool(o, P, "usemtl", 0, usemtl, e));
    int flip = 0;
    TRY(json_bool(o, P, "flip", 0, &flip, e));
    if (json_get(o, "vertices") || json_get(o, "triangles"))
        return json_fail(e, PM_EINVAL, "%s: give a file or vertices and triangles, not both", P);
    double M[3][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}};
    const cJSON *t = json_get(o, "transform");
    if (t) {
        if (!cJSON_IsArray(t) || cJSON_GetArraySize(t) != 16)
            return json_fail(e, PM_EINVAL, "%s.transform: expected 16 numbers (a 4x4 matrix, row by row)", P);
        double a[16];
        int i = 0;
        for (const cJSON *it = t->child; it; it = it->next, i++) {
            if (!cJSON_IsNumber(it) || !isfinite(it->valuedouble))
                return json_fail(e, PM_EINVAL, "%s.transform[%d]: expected a finite number, got %s", P, i,
                                 json_type_name(it));
            a[i] = it->valuedouble;
        }
        if (a[12] != 0 || a[13] != 0 || a[14] != 0 || a[15] != 1)
            return json_fail(e, PM_EINVAL, "%s.transform: the last row must be 0 0 0 1", P);
        for (int r = 0; r < 3; r++)
            for (int c = 0; c < 4; c++) M[r][c] = a[4 * r + c];
    }
    double t0 = stats_now();
    clock_t c0 = clock(); /* CPU time too: on a shared machine the wall clock says little */
    char err[400];
    int rc = mesh_load(file, m, err, sizeof err);
    /* A transform that takes the file's lengths out of the scene's range is the transform's
     * error (scene.h "Ranges"), said as the other range errors are. */
    if (rc == 0 && mesh_transform_lengths(m, (const double(*)[4])M, SCENE_LENGTH_MIN, SCENE_LENGTH_MAX,
                                          err, sizeof err) < 0) {
        mesh_free(m);
        return json_fail(e, PM_EINVAL, "%s.transform: %s", P, err);
    }
    for (int k = 0; rc == 0 && flip && k < m->ntris; k++) { /* the other side is the front */
        int x = m->tri[k][1];
        m->tri[k][1] = m->tri[k][2];
        m->tri[k][2] = x;
        if (m->tri_n) {
            x = m->tri_n[k][1];
            m->tri_n[k][1] = m->tri_n[k][2];
            m->tri_n[k][2] = x;
        }
    }
    if (rc == 0 && m->nskipped > 0) /* one counted warning per file (mesh.h) */
        fprintf(stderr, "render: %s: warning: %s.file: skipped %ld degenerate face%s (zero area: repeated or "
                "collinear corners; the first at %s), kept %d triangles\n", file, P, m->nskipped,
                m->nskipped == 1 ? "" : "s", m->first_skip, m->ntris);
    if (rc == 0) rc = mesh_transform(m, (const double(*)[4])M, file, err, sizeof err);
    if (rc == 0 && *smooth && mesh_smooth_normals(m, recompute) < 0) {
        rc = PM_ENOMEM;
        snprintf(err, sizeof err, "%s: out of memory", file);
    }
    stats_time_add("Time/Mesh loading", stats_now() - t0);
    stats_time_add("Time/Mesh loading (CPU)", (double)(clock() - c0) / CLOCKS_PER_SEC);
    if (rc < 0) {
        mesh_free(m);
        return json_fail(e, rc, "%s.file: %s", P, err);
    }
    return 0;
}

int scene_parse_file(const char *path, cJSON **root, json_err *e) {
    if (!pbrt_is_file(path)) return json_parse_file(path, root, e);
    double t0 = stats_now();
    int rc = pbrt_convert_file(path, root, e);
    stats_time_add("Time/Mesh loading", stats_now() - t0);
    return rc;
}
