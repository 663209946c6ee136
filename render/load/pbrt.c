/* pbrt.c: pbrt-v3 scene files to our scene document; see pbrt.h.
 *
 * Each file (and each Include) is read whole and cut into tokens (quoted strings, numbers,
 * bare words, [ and ]), each with its file and line. The directives are then run in order
 * against a graphics state (the current transform, material, area light, orientation) and
 * its stack; every shape is written at once as world-space geometry in the output document
 * (inline meshes and spheres; PLY meshes as file objects with their matrix), so instances are
 * copies of already converted objects under one more transform. A directive's parameters are
 * parsed into a list, looked up by name with their type checked, and any parameter nobody
 * asked for is warned about when the directive is done, so nothing is dropped silently.
 * The mirror of the scene (pbrt.h, "Handedness") is decided at WorldBegin from the camera and
 * applied as each point, direction and matrix is written out.
 */
#define _XOPEN_SOURCE 700
#include "load/pbrt.h"

#include <ctype.h>
#include <errno.h>
#include <limits.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "common.h"
#include "base/vec.h"
#include "load/mesh.h"
#include "scene/shapes.h"

#define TRY(x) JSON_TRY(x)
#define PB_MAX_INCLUDE 32
#define PB_MAX_STACK 256

/* ---- tokens ------------------------------------------------------------------------------- */

enum { K_STR, K_NUM, K_WORD, K_LB, K_RB };

typedef struct tok {
    int kind;
    char *s; /* K_STR, K_WORD: the text (owned) */
    double num;
    int file; /* index into the converter's file names */
    int line;
} tok;

typedef struct toks {
    tok *t;
    int n, cap;
} toks;

typedef struct pparam {
    char type[16], name[64];
    int n, is_str, used;
    double *num;
    char **str;
} pparam;

typedef struct plist {
    pparam p[64];
    int n;
} plist;

typedef struct gstate {
    double m[4][4]; /* current transform: object to world */
    int revor;
    char mat[80];
    int area; /* an AreaLightSource is active */
    rgb L;
    int twosided;
    char inside[64], outside[64]; /* MediumInterface ("" : none) */
} gstate;

typedef struct named_obj {
    char name[64];
    cJSON *objs; /* converted objects (output coordinates) */
} named_obj;

typedef struct named_cs {
    char name[64];
    double m[4][4];
} named_cs;

typedef struct conv {
    char *files[PB_MAX_INCLUDE * 4];
    int nfiles;
    json_err *e;
    gstate g, stack[PB_MAX_STACK];
    int stack_kind[PB_MAX_STACK]; /* 1 attribute, 2 transform, 3 object */
    int depth;
    int in_world, mirror, have_camera, include_depth;
    double cam2world[4][4];
    long width, height, spp, maxdepth;
    double fov;
    const char *mode;
    cJSON *mats, *objs, *lights, *target; /* target: objs, or the object being defined */
    cJSON *media;                         /* our "media" (NULL until MakeNamedMedium) */
    char cam_medium[64];                  /* the outside medium at Camera: our global medium */
    named_obj *nobj;
    int nnobj;
    named_cs cs[16];
    int ncs;
    int nanon, nemit;
    long skipped_degenerate;
    int skip_file, skip_line;
} conv;

static const char *tfile(const conv *c, const tok *t) { return c->files[t->file]; }

static int pfail(conv *c, const tok *t, int code, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
static int pfail(conv *c, const tok *t, int code, const char *fmt, ...) {
    char msg[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (t)
        return json_fail(c->e, code, "%s:%d: %s", tfile(c, t), t->line, msg);
    return json_fail(c->e, code, "%s", msg);
}

static void pwarn(const conv *c, const tok *t, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void pwarn(const conv *c, const tok *t, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "render: %s:%d: warning: ", tfile(c, t), t->line);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
}

static int tok_push(toks *ts, tok t) {
    if (ts->n == ts->cap) {
        int nc = ts->cap ? 2 * ts->cap : 1024;
        tok *nt = realloc(ts->t, (size_t)nc * sizeof *nt);
        if (!nt) return PM_ENOMEM;
        ts->t = nt;
        ts->cap = nc;
    }
    ts->t[ts->n++] = t;
    return 0;
}

static void toks_free(toks *ts) {
    for (int i = 0; i < ts->n; i++) free(ts->t[i].s);
    free(ts->t);
    memset(ts, 0, sizeof *ts);
}

/* Cut text into tokens; file is the index of its name. */
static int lex(conv *c, const char *text, int file, toks *ts) {
    int line = 1;
    for (const char *s = text; *s;) {
        if (*s == '\n') {
            line++;
            s++;
        } else if (isspace((unsigned char)*s)) {
            s++;
        } else if (*s == '#') {
            while (*s && *s != '\n') s++;
        } else if (*s == '[' || *s == ']') {
            if (tok_push(ts, (tok){*s == '[' ? K_LB : K_RB, NULL, 0, file, line}) < 0) return PM_ENOMEM;
            s++;
        } else if (*s == '"') {
            int l0 = line;
            size_t cap = 64, n = 0;
            char *b = malloc(cap);
            if (!b) return PM_ENOMEM;
            for (s++; *s != '"'; s++) {
                if (!*s || *s == '\n') {
                    free(b);
                    tok t = {K_STR, NULL, 0, file, l0};
                    return pfail(c, &t, PM_EINVAL, "unterminated string (a \" without its closing \" on the line)");
                }
                char ch = *s;
                if (ch == '\\' && s[1]) {
                    s++;
                    ch = *s == 'n' ? '\n' : *s == 't' ? '\t' : *s;
                }
                if (n + 2 > cap) {
                    char *nb = realloc(b, cap *= 2);
                    if (!nb) {
                        free(b);
                        return PM_ENOMEM;
                    }
                    b = nb;
                }
                b[n++] = ch;
            }
            s++;
            b[n] = 0;
            if (tok_push(ts, (tok){K_STR, b, 0, file, l0}) < 0) {
                free(b);
                return PM_ENOMEM;
            }
        } else {
            const char *b = s;
            while (*s && !isspace((unsigned char)*s) && *s != '"' && *s != '[' && *s != ']' && *s != '#') s++;
            size_t n = (size_t)(s - b);
            char *e;
            double v = strtod(b, &e);
            tok t = {K_NUM, NULL, v, file, line};
            if (e != s || n == 0 || isalpha((unsigned char)b[0])) { /* a word ("inf" and "nan" too) */
                t.kind = K_WORD;
                t.s = malloc(n + 1);
                if (!t.s) return PM_ENOMEM;
                memcpy(t.s, b, n);
                t.s[n] = 0;
            }
            if (tok_push(ts, t) < 0) {
                free(t.s);
                return PM_ENOMEM;
            }
        }
    }
    return 0;
}

/* ---- matrices ----------------------------------------------------------------------------- */

static void m_ident(double m[4][4]) {
    memset(m, 0, 16 * sizeof(double));
    for (int i = 0; i < 4; i++) m[i][i] = 1;
}

static void m_mul(double a[4][4], double b[4][4], double out[4][4]) {
    double r[4][4];
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) {
            r[i][j] = 0;
            for (int k = 0; k < 4; k++) r[i][j] += a[i][k] * b[k][j];
        }
    memcpy(out, r, sizeof r);
}

/* Inverse by Gauss-Jordan with partial pivoting; -1 when singular or not finite. */
static int m_inv(double m[4][4], double out[4][4]) {
    double a[4][8];
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 8; j++) a[i][j] = j < 4 ? m[i][j] : (j - 4 == i);
    for (int col = 0; col < 4; col++) {
        int p = col;
        for (int r = col + 1; r < 4; r++)
            if (fabs(a[r][col]) > fabs(a[p][col])) p = r;
        if (!(fabs(a[p][col]) > 1e-300) || !isfinite(a[p][col])) return -1;
        for (int j = 0; j < 8; j++) {
            double t = a[col][j];
            a[col][j] = a[p][j];
            a[p][j] = t;
        }
        double d = a[col][col];
        for (int j = 0; j < 8; j++) a[col][j] /= d;
        for (int r = 0; r < 4; r++)
            if (r != col) {
                double f = a[r][col];
                for (int j = 0; j < 8; j++) a[r][j] -= f * a[col][j];
            }
    }
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++) out[i][j] = a[i][j + 4];
    return 0;
}

static double m_det3(double m[4][4]) {
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

static vec3 m_point(double m[4][4], vec3 p) {
    return v3(m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
              m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
              m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3]);
}
static vec3 m_dir(double m[4][4], vec3 d) {
    return v3(m[0][0] * d.x + m[0][1] * d.y + m[0][2] * d.z, m[1][0] * d.x + m[1][1] * d.y + m[1][2] * d.z,
              m[2][0] * d.x + m[2][1] * d.y + m[2][2] * d.z);
}

/* Output coordinates: the world, mirrored in x when pbrt's camera frame is ours mirrored. */
static vec3 out_v(const conv *c, vec3 p) { return c->mirror ? v3(0.0 - p.x, p.y, p.z) : p; } /* +0, not -0 */

static cJSON *jv(vec3 v) {
    double a[3] = {v.x, v.y, v.z};
    return cJSON_CreateDoubleArray(a, 3);
}

/* ---- parameters --------------------------------------------------------------------------- */

static void plist_free(plist *pl) {
    for (int i = 0; i < pl->n; i++) {
        free(pl->p[i].num);
        free(pl->p[i].str); /* the strings belong to the tokens */
    }
    pl->n = 0;
}

/* Parameters from *i on: "type name" value, where value is [ ... ] or one number/string/word. */
static int read_params(conv *c, const toks *ts, int *i, plist *pl) {
    pl->n = 0;
    while (*i < ts->n && ts->t[*i].kind == K_STR) {
        const tok *t = &ts->t[*i];
        char ty[16], nm[64], extra[8];
        int k = sscanf(t->s, "%15s %63s %7s", ty, nm, extra);
        if (k != 2) return pfail(c, t, PM_EINVAL, "expected a parameter \"TYPE NAME\", got \"%.60s\"", t->s);
        if (pl->n == 64) return pfail(c, t, PM_EINVAL, "more than 64 parameters");
        pparam *p = &pl->p[pl->n];
        memset(p, 0, sizeof *p);
        snprintf(p->type, sizeof p->type, "%s", ty);
        snprintf(p->name, sizeof p->name, "%s", nm);
        (*i)++;
        int lo = *i, hi, bracket = *i < ts->n && ts->t[*i].kind == K_LB;
        if (bracket) {
            lo = ++(*i);
            while (*i < ts->n && ts->t[*i].kind != K_RB) {
                if (ts->t[*i].kind == K_LB) return pfail(c, &ts->t[*i], PM_EINVAL, "a [ inside a parameter's [ ]");
                (*i)++;
            }
            if (*i >= ts->n) return pfail(c, t, PM_EINVAL, "parameter \"%s\": unbalanced [ (no closing ])", t->s);
            hi = (*i)++;
        } else {
            const tok *u = *i < ts->n ? &ts->t[*i] : NULL;
            if (!u || u->kind == K_RB || u->kind == K_LB ||
                (u->kind == K_WORD && strcmp(u->s, "true") != 0 && strcmp(u->s, "false") != 0))
                return pfail(c, t, PM_EINVAL, "parameter \"%s\" has no value", t->s);
            hi = ++(*i);
        }
        pl->n++;
        p->n = hi - lo;
        int strs = 0, nums = 0;
        for (int j = lo; j < hi; j++) {
            if (ts->t[j].kind == K_NUM) nums++;
            else strs++;
        }
        if (strs && nums)
            return pfail(c, t, PM_EINVAL, "parameter \"%s\": numbers and strings mixed in one value", t->s);
        p->is_str = strs > 0;
        if (p->n == 0) continue;
        if (p->is_str) {
            p->str = malloc((size_t)p->n * sizeof *p->str);
            if (!p->str) return PM_ENOMEM;
            for (int j = lo; j < hi; j++) p->str[j - lo] = ts->t[j].s;
        } else {
            p->num = malloc((size_t)p->n * sizeof *p->num);
            if (!p->num) return PM_ENOMEM;
            for (int j = lo; j < hi; j++) p->num[j - lo] = ts->t[j].num;
        }
    }
    return 0;
}

/* The parameter `name`, if its type is one of the '|'-separated types; a parameter of that
 * name with another type is an error. NULL when absent. */
static int pget(conv *c, const tok *at, plist *pl, const char *name, const char *types, pparam **out) {
    *out = NULL;
    for (int i = 0; i < pl->n; i++) {
        pparam *p = &pl->p[i];
        if (strcmp(p->name, name) != 0) continue;
        char buf[80];
        snprintf(buf, sizeof buf, "|%s|", types);
        char want[24];
        snprintf(want, sizeof want, "|%s|", p->type);
        /* synonyms of pbrt's */
        if (strcmp(p->type, "color") == 0) snprintf(want, sizeof want, "|rgb|");
        if (strcmp(p->type, "point3") == 0) snprintf(want, sizeof want, "|point|");
        if (strcmp(p->type, "normal3") == 0) snprintf(want, sizeof want, "|normal|");
        if (strcmp(p->type, "vector3") == 0) snprintf(want, sizeof want, "|vector|");
        if (!strstr(buf, want))
            return pfail(c, at, PM_EINVAL, "parameter \"%s %s\": the type should be %s", p->type, p->name, types);
        p->used = 1;
        int want_str = strcmp(p->type, "string") == 0 || strcmp(p->type, "texture") == 0 || strcmp(p->type, "bool") == 0 ||
                       (strcmp(p->type, "spectrum") == 0 && p->is_str);
        if (p->n > 0 && want_str != p->is_str)
            return pfail(c, at, PM_EINVAL, "parameter \"%s %s\": expected %s", p->type, p->name,
                         want_str ? "a string" : "numbers");
        *out = p;
        return 0;
    }
    return 0;
}

static int get_floats(conv *c, const tok *at, plist *pl, const char *name, const char *types, int n, double *v) {
    pparam *p;
    TRY(pget(c, at, pl, name, types, &p));
    if (!p) return 0;
    if (p->n != n) return pfail(c, at, PM_EINVAL, "parameter \"%s %s\": expected %d value%s, got %d", p->type, name, n,
                                n == 1 ? "" : "s", p->n);
    for (int i = 0; i < n; i++) {
        if (!isfinite(p->num[i])) return pfail(c, at, PM_EINVAL, "parameter \"%s %s\": value %d is not finite", p->type, name, i + 1);
        v[i] = p->num[i];
    }
    return 1;
}

static int get_string(conv *c, const tok *at, plist *pl, const char *name, const char **s) {
    pparam *p;
    TRY(pget(c, at, pl, name, "string", &p));
    if (!p) return 0;
    if (p->n != 1) return pfail(c, at, PM_EINVAL, "parameter \"string %s\": expected one string, got %d", name, p->n);
    *s = p->str[0];
    return 1;
}

static int get_bool(conv *c, const tok *at, plist *pl, const char *name, int *b) {
    pparam *p;
    TRY(pget(c, at, pl, name, "bool", &p));
    if (!p) return 0;
    if (p->n != 1 || (strcmp(p->str[0], "true") != 0 && strcmp(p->str[0], "false") != 0))
        return pfail(c, at, PM_EINVAL, "parameter \"bool %s\": expected \"true\" or \"false\"", name);
    *b = strcmp(p->str[0], "true") == 0;
    return 1;
}

/* A colour: rgb (3 numbers), spectrum (wavelength-value pairs: their mean, a warning),
 * blackbody (warned: grey of its scale); a texture is warned about and leaves *v. */
static int get_color(conv *c, const tok *at, plist *pl, const char *name, rgb *v) {
    pparam *p;
    TRY(pget(c, at, pl, name, "rgb|spectrum|blackbody|texture|float", &p));
    if (!p) return 0;
    if (strcmp(p->type, "texture") == 0) {
        pwarn(c, at, "parameter \"texture %s\": textures are not supported: the default value is used", name);
        return 0;
    }
    for (int i = 0; i < p->n; i++)
        if (!p->is_str && !isfinite(p->num[i]))
            return pfail(c, at, PM_EINVAL, "parameter \"%s %s\": value %d is not finite", p->type, name, i + 1);
    if (strcmp(p->type, "rgb") == 0 || strcmp(p->type, "color") == 0) {
        if (p->n != 3) return pfail(c, at, PM_EINVAL, "parameter \"%s %s\": expected 3 values, got %d", p->type, name, p->n);
        *v = v3(p->num[0], p->num[1], p->num[2]);
    } else if (strcmp(p->type, "float") == 0) {
        if (p->n != 1) return pfail(c, at, PM_EINVAL, "parameter \"float %s\": expected 1 value, got %d", name, p->n);
        *v = v3s(p->num[0]);
    } else if (strcmp(p->type, "spectrum") == 0 && !p->is_str && p->n >= 2 && p->n % 2 == 0) {
        double s = 0;
        for (int i = 1; i < p->n; i += 2) s += p->num[i];
        *v = v3s(s / (p->n / 2));
        pwarn(c, at, "parameter \"spectrum %s\": a spectrum becomes the grey of its mean value, %g", name, v->x);
    } else if (strcmp(p->type, "blackbody") == 0 && p->n >= 1) {
        double scale = p->n >= 2 ? p->num[1] : 1;
        *v = v3s(scale);
        pwarn(c, at, "parameter \"blackbody %s\": a blackbody of %g K becomes a grey of its scale, %g", name, p->num[0], scale);
    } else {
        return pfail(c, at, PM_EINVAL, "parameter \"%s %s\": not a colour this converter reads (rgb, spectrum pairs, "
                     "blackbody)", p->type, name);
    }
    return 1;
}

/* Warn about every parameter nobody asked for. */
static void warn_unused(const conv *c, const tok *at, const char *what, const plist *pl) {
    for (int i = 0; i < pl->n; i++)
        if (!pl->p[i].used)
            pwarn(c, at, "%s: parameter \"%s %s\" is not supported: ignored", what, pl->p[i].type, pl->p[i].name);
}

/* ---- materials ---------------------------------------------------------------------------- */

static rgb clamp01(rgb v) { return v3(fmin(fmax(v.x, 0), 1), fmin(fmax(v.y, 0), 1), fmin(fmax(v.z, 0), 1)); }

/* Our material for pbrt material `type` with parameters pl; warnings name what is lost. */
static int make_material(conv *c, const tok *at, const char *type, plist *pl, cJSON **out) {
    cJSON *m = cJSON_CreateObject();
    if (!m) return PM_ENOMEM;
    *out = m;
    char what[80];
    snprintf(what, sizeof what, "Material \"%s\"", type);
    if (strcmp(type, "matte") == 0) {
        rgb kd = v3s(0.5);
        double sigma = 0;
        TRY(get_color(c, at, pl, "Kd", &kd));
        TRY(get_floats(c, at, pl, "sigma", "float", 1, &sigma));
        if (sigma > 0) {
            cJSON_AddStringToObject(m, "type", "oren_nayar");
            cJSON_AddItemToObject(m, "reflectance", jv(clamp01(kd)));
            cJSON_AddNumberToObject(m, "sigma", fmin(sigma, 90) * M_PI / 180); /* pbrt: degrees */
        } else {
            cJSON_AddStringToObject(m, "type", "lambert");
            cJSON_AddItemToObject(m, "reflectance", jv(clamp01(kd)));
        }
    } else if (strcmp(type, "mirror") == 0) {
        rgb kr = v3s(0.9);
        TRY(get_color(c, at, pl, "Kr", &kr));
        cJSON_AddStringToObject(m, "type", "mirror");
        cJSON_AddItemToObject(m, "reflectance", jv(clamp01(kr)));
    } else if (strcmp(type, "glass") == 0) {
        rgb kr = v3s(1), kt = v3s(1);
        double eta = 1.5, r = 0;
        TRY(get_color(c, at, pl, "Kr", &kr));
        TRY(get_color(c, at, pl, "Kt", &kt));
        if (get_floats(c, at, pl, "eta", "float", 1, &eta) == 0) TRY(get_floats(c, at, pl, "index", "float", 1, &eta));
        int ru = get_floats(c, at, pl, "uroughness", "float", 1, &r), rv = get_floats(c, at, pl, "vroughness", "float", 1, &r);
        if (ru < 0 || rv < 0) return PM_EINVAL;
        if (!(eta > 0)) return pfail(c, at, PM_EINVAL, "%s: eta must be positive, got %g", what, eta);
        if ((ru || rv) && r > 0) pwarn(c, at, "%s: roughness %g is lost: smooth glass", what, r);
        cJSON_AddStringToObject(m, "type", "dielectric");
        cJSON_AddNumberToObject(m, "ior", eta);
        if (!(kt.x == 1 && kt.y == 1 && kt.z == 1)) cJSON_AddItemToObject(m, "tint", jv(clamp01(kt)));
        if (!(kr.x == 1 && kr.y == 1 && kr.z == 1))
            pwarn(c, at, "%s: Kr [%g %g %g] is lost: the reflection is untinted", what, kr.x, kr.y, kr.z);
    } else if (strcmp(type, "plastic") == 0 || strcmp(type, "substrate") == 0 || strcmp(type, "uber") == 0) {
        int sub = strcmp(type, "substrate") == 0, uber = strcmp(type, "uber") == 0;
        rgb kd = v3s(sub ? 0.5 : 0.25), ks = v3s(sub ? 0.5 : 0.25), kr = v3s(0), kt = v3s(0), op = v3s(1);
        double rough = 0.1, eta = 1.5;
        TRY(get_color(c, at, pl, "Kd", &kd));
        TRY(get_color(c, at, pl, "Ks", &ks));
        TRY(get_floats(c, at, pl, "roughness", "float", 1, &rough));
        TRY(get_floats(c, at, pl, "uroughness", "float", 1, &rough));
        TRY(get_floats(c, at, pl, "vroughness", "float", 1, &rough));
        int rm = 1;
        TRY(get_bool(c, at, pl, "remaproughness", &rm));
        if (uber) {
            TRY(get_color(c, at, pl, "Kr", &kr));
            TRY(get_color(c, at, pl, "Kt", &kt));
            TRY(get_color(c, at, pl, "opacity", &op));
            if (get_floats(c, at, pl, "eta", "float", 1, &eta) == 0) TRY(get_floats(c, at, pl, "index", "float", 1, &eta));
            if (!v3_iszero(kr) || !v3_iszero(kt) || !(op.x == 1 && op.y == 1 && op.z == 1))
                pwarn(c, at, "%s: Kr, Kt and opacity are lost (only Kd under a Fresnel coat tinted by Ks)", what);
        }
        if (!(eta > 1)) eta = 1.5;
        pwarn(c, at, "%s: the glossy lobe (Ks [%g %g %g], roughness %g) becomes a smooth Fresnel coat (ior %g) "
              "tinted by Ks over the diffuse Kd", what, ks.x, ks.y, ks.z, rough, eta);
        cJSON_AddStringToObject(m, "type", "mix");
        cJSON_AddStringToObject(m, "specular", "fresnel");
        cJSON_AddNumberToObject(m, "ior", eta);
        cJSON_AddNumberToObject(m, "transparency", 0);
        cJSON_AddItemToObject(m, "diffuse", jv(clamp01(kd)));
        cJSON_AddItemToObject(m, "specular_tint", jv(clamp01(ks)));
    } else {
        pwarn(c, at, "%s is not supported: matte grey 0.5 is used instead", what);
        for (int i = 0; i < pl->n; i++) pl->p[i].used = 1; /* one warning is enough */
        cJSON_AddStringToObject(m, "type", "lambert");
        cJSON_AddNumberToObject(m, "reflectance", 0.5);
    }
    pparam *bm;
    TRY(pget(c, at, pl, "bumpmap", "texture", &bm));
    if (bm) pwarn(c, at, "%s: bump maps are not supported: ignored", what);
    warn_unused(c, at, what, pl);
    return 0;
}

static int add_material(conv *c, const char *name, cJSON *m) {
    cJSON *old = cJSON_GetObjectItemCaseSensitive(c->mats, name);
    if (old) cJSON_ReplaceItemInObjectCaseSensitive(c->mats, name, m);
    else cJSON_AddItemToObject(c->mats, name, m);
    return 0;
}

/* The material for the next shape: the current one, or a copy with the area light's emission. */
static int shape_material(conv *c, char *name, size_t cap) {
    if (!c->g.area) {
        snprintf(name, cap, "%s", c->g.mat);
        return 0;
    }
    const cJSON *base = cJSON_GetObjectItemCaseSensitive(c->mats, c->g.mat);
    cJSON *m = base ? cJSON_Duplicate(base, 1) : NULL;
    if (!m) return PM_ENOMEM;
    cJSON_DeleteItemFromObjectCaseSensitive(m, "emission");
    cJSON_AddItemToObject(m, "emission", jv(c->g.L));
    if (c->g.twosided) cJSON_AddBoolToObject(m, "two_sided", 1);
    snprintf(name, cap, "%.60s+light%d", c->g.mat, c->nemit++);
    cJSON_AddItemToObject(c->mats, name, m);
    return 0;
}

/* ---- shapes ------------------------------------------------------------------------------- */

/* Does pbrt's normal point along the winding normal of the world-space vertices (1), or
 * against it (-1: ReverseOrientation xor a handedness-swapping transform)? */
static int pbrt_side(const conv *c) {
    int swap = m_det3((double(*)[4])c->g.m) < 0;
    return (c->g.revor ^ swap) ? -1 : 1;
}
/* Must our winding be flipped for our front to be pbrt's normal, in output coordinates? */
static int need_flip(const conv *c) { return (c->mirror ? -1 : 1) != pbrt_side(c); }

static int shape_trianglemesh(conv *c, const tok *at, plist *pl, const char *mat) {
    pparam *P, *I, *N;
    TRY(pget(c, at, pl, "P", "point", &P));
    TRY(pget(c, at, pl, "indices", "integer", &I));
    TRY(pget(c, at, pl, "N", "normal", &N));
    pparam *uv;
    TRY(pget(c, at, pl, "uv", "float|point2", &uv));
    TRY(pget(c, at, pl, "st", "float|point2", &uv));
    pparam *S;
    TRY(pget(c, at, pl, "S", "vector", &S));
    if (!P || P->n == 0 || P->n % 3) return pfail(c, at, PM_EINVAL, "Shape \"trianglemesh\": \"point P\" needs 3 numbers per vertex");
    int nv = P->n / 3;
    int ni = I ? I->n : (nv == 3 ? 3 : -1);
    if (ni < 0) return pfail(c, at, PM_EINVAL, "Shape \"trianglemesh\": \"integer indices\" missing (required unless P has 3 points)");
    if (ni % 3) return pfail(c, at, PM_EINVAL, "Shape \"trianglemesh\": %d indices, not a multiple of 3", ni);
    if (N && N->n != P->n) return pfail(c, at, PM_EINVAL, "Shape \"trianglemesh\": \"normal N\" has %d numbers, P %d", N->n, P->n);
    vec3 *v = malloc((size_t)nv * sizeof *v), *vn = N ? malloc((size_t)nv * sizeof *vn) : NULL;
    if (!v || (N && !vn)) {
        free(v);
        free(vn);
        return PM_ENOMEM;
    }
    /* normals by the inverse transpose, then the mirror (pbrt.h); pbrt turns the geometric
     * normal toward them (FaceForward), so with N each triangle is wound to face its normals */
    double inv[4][4];
    if (N && m_inv(c->g.m, inv) < 0) {
        free(v);
        free(vn);
        return pfail(c, at, PM_EINVAL, "Shape \"trianglemesh\": the transform is singular");
    }
    for (int i = 0; N && i < nv; i++) {
        vec3 n = v3(N->num[3 * i], N->num[3 * i + 1], N->num[3 * i + 2]);
        vec3 w = v3(inv[0][0] * n.x + inv[1][0] * n.y + inv[2][0] * n.z, inv[0][1] * n.x + inv[1][1] * n.y + inv[2][1] * n.z,
                    inv[0][2] * n.x + inv[1][2] * n.y + inv[2][2] * n.z);
        if (!(v3_len(w) > 0) || !isfinite(w.x + w.y + w.z)) {
            free(v);
            free(vn);
            return pfail(c, at, PM_EINVAL, "Shape \"trianglemesh\": normal %d is zero or not finite", i);
        }
        vn[i] = out_v(c, v3_norm(w));
    }
    for (int i = 0; i < nv; i++) {
        vec3 p = v3(P->num[3 * i], P->num[3 * i + 1], P->num[3 * i + 2]);
        if (!isfinite(p.x) || !isfinite(p.y) || !isfinite(p.z)) {
            free(v);
            free(vn);
            return pfail(c, at, PM_EINVAL, "Shape \"trianglemesh\": point %d is not finite", i);
        }
        v[i] = out_v(c, m_point(c->g.m, p));
    }
    int flip = need_flip(c);
    cJSON *o = cJSON_CreateObject(), *va = cJSON_CreateArray(), *ta = cJSON_CreateArray(), *na = N ? cJSON_CreateArray() : NULL;
    int rc = o && va && ta && (!N || na) ? 0 : PM_ENOMEM;
    for (int i = 0; i < nv && rc == 0; i++) cJSON_AddItemToArray(va, jv(v[i]));
    long skipped = 0;
    for (int t = 0; t < ni / 3 && rc == 0; t++) {
        int k[3];
        for (int j = 0; j < 3; j++) {
            double x = I ? I->num[3 * t + j] : 3 * t + j;
            if (!(x >= 0 && x < nv && x == floor(x))) {
                rc = pfail(c, at, PM_EINVAL, "Shape \"trianglemesh\": index %g (triangle %d) out of range (%d points)", x, t, nv);
                break;
            }
            k[j] = (int)x;
        }
        if (rc) break;
        triangle tr;
        if (triangle_make(&tr, v[k[0]], v[k[1]], v[k[2]], 0) < 0) {
            skipped++;
            continue;
        }
        if (vn ? v3_dot(tr.n, v3_add(vn[k[0]], v3_add(vn[k[1]], vn[k[2]]))) < 0 : flip) {
            int x = k[1];
            k[1] = k[2];
            k[2] = x;
        }
        cJSON_AddItemToArray(ta, cJSON_CreateIntArray(k, 3));
    }
    for (int i = 0; vn && i < nv && rc == 0; i++) cJSON_AddItemToArray(na, jv(vn[i]));
    free(v);
    free(vn);
    if (rc == 0 && skipped)
        pwarn(c, at, "Shape \"trianglemesh\": skipped %ld degenerate triangle%s (zero area)", skipped, skipped == 1 ? "" : "s");
    if (rc == 0 && cJSON_GetArraySize(ta) == 0) {
        pwarn(c, at, "Shape \"trianglemesh\": no triangle with an area: skipped");
        rc = 1;
    }
    if (rc != 0) {
        cJSON_Delete(o);
        cJSON_Delete(va);
        cJSON_Delete(ta);
        cJSON_Delete(na);
        return rc < 0 ? rc : 0;
    }
    cJSON_AddStringToObject(o, "type", "mesh");
    cJSON_AddItemToObject(o, "vertices", va);
    cJSON_AddItemToObject(o, "triangles", ta);
    if (na) {
        cJSON_AddItemToObject(o, "normals", na);
        cJSON_AddBoolToObject(o, "smooth", 1);
    }
    cJSON_AddStringToObject(o, "material", mat);
    cJSON_AddItemToArray(c->target, o);
    return 0;
}

/* Does the PLY file's header give vertex normals (property nx)? */
static int ply_has_normals(const char *path) {
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    char b[8192];
    size_t n = fread(b, 1, sizeof b - 1, f);
    fclose(f);
    b[n] = 0;
    char *end = strstr(b, "end_header");
    if (end) *end = 0;
    return strstr(b, " nx\n") != NULL || strstr(b, " nx\r\n") != NULL;
}

static void dir_of(const char *path, char *dir, size_t cap) {
    const char *s = strrchr(path, '/');
    if (!s) {
        snprintf(dir, cap, ".");
        return;
    }
    size_t n = (size_t)(s - path);
    if (n == 0) n = 1;
    if (n >= cap) n = cap - 1;
    memcpy(dir, path, n);
    dir[n] = 0;
}

/* path relative to the directory of file, made absolute. */
static void resolve(const char *file, const char *name, char *out, size_t cap) {
    char dir[4096], joined[8192], real[PATH_MAX];
    if (name[0] == '/') {
        snprintf(joined, sizeof joined, "%s", name);
    } else {
        dir_of(file, dir, sizeof dir);
        snprintf(joined, sizeof joined, "%s/%s", dir, name);
    }
    if (realpath(joined, real)) {
        snprintf(out, cap, "%s", real);
    } else if (joined[0] != '/') {
        char cwd[4096];
        snprintf(out, cap, "%.4000s/%.4000s", getcwd(cwd, sizeof cwd) ? cwd : ".", joined);
    } else {
        snprintf(out, cap, "%s", joined);
    }
}

static int shape_plymesh(conv *c, const tok *at, plist *pl, const char *mat) {
    const char *fn = NULL;
    TRY(get_string(c, at, pl, "filename", &fn));
    if (!fn) return pfail(c, at, PM_EINVAL, "Shape \"plymesh\": \"string filename\" missing");
    char path[8192];
    resolve(tfile(c, at), fn, path, sizeof path);
    FILE *f = fopen(path, "rb");
    if (!f) return pfail(c, at, PM_EIO, "Shape \"plymesh\": cannot open %s: %s", path, strerror(errno));
    fclose(f);
    if (c->g.m[3][0] != 0 || c->g.m[3][1] != 0 || c->g.m[3][2] != 0 || c->g.m[3][3] != 1)
        return pfail(c, at, PM_EINVAL, "a projective transform is not supported for shapes");
    double M[16];
    for (int r = 0; r < 3; r++)
        for (int k = 0; k < 4; k++) M[4 * r + k] = (c->mirror && r == 0 ? -1 : 1) * c->g.m[r][k];
    M[12] = M[13] = M[14] = 0;
    M[15] = 1;
    cJSON *o = cJSON_CreateObject();
    if (!o) return PM_ENOMEM;
    cJSON_AddStringToObject(o, "type", "mesh");
    cJSON_AddStringToObject(o, "file", path);
    cJSON_AddItemToObject(o, "transform", cJSON_CreateDoubleArray(M, 16));
    cJSON_AddBoolToObject(o, "smooth", ply_has_normals(path));
    if (need_flip(c)) cJSON_AddBoolToObject(o, "flip", 1);
    cJSON_AddBoolToObject(o, "usemtl", 0);
    cJSON_AddStringToObject(o, "material", mat);
    cJSON_AddItemToArray(c->target, o);
    pparam *d;
    TRY(pget(c, at, pl, "displacement", "texture|float", &d));
    if (d) pwarn(c, at, "Shape \"plymesh\": displacement is not supported: ignored");
    return 0;
}

static int shape_sphere(conv *c, const tok *at, plist *pl, const char *mat) {
    double r = 1, zmin = -1, zmax = 1, phimax = 360;
    TRY(get_floats(c, at, pl, "radius", "float", 1, &r));
    int a = get_floats(c, at, pl, "zmin", "float", 1, &zmin), b = get_floats(c, at, pl, "zmax", "float", 1, &zmax),
        d = get_floats(c, at, pl, "phimax", "float", 1, &phimax);
    if (a < 0 || b < 0 || d < 0) return PM_EINVAL;
    if (!(r > 0)) return pfail(c, at, PM_EINVAL, "Shape \"sphere\": radius must be positive, got %g", r);
    if (zmin > -r || zmax < r || phimax < 360)
        pwarn(c, at, "Shape \"sphere\": a partial sphere (zmin, zmax, phimax) is not supported: the full sphere");
    double s[3];
    for (int k = 0; k < 3; k++) s[k] = v3_len(m_dir(c->g.m, v3(k == 0, k == 1, k == 2)));
    double smax = fmax(s[0], fmax(s[1], s[2])), smin = fmin(s[0], fmin(s[1], s[2]));
    if (smax - smin > 1e-9 * smax)
        pwarn(c, at, "Shape \"sphere\": a non-uniform scale (%g %g %g) is not supported: a sphere of the largest", s[0],
              s[1], s[2]);
    if (pbrt_side(c) < 0)
        pwarn(c, at, "Shape \"sphere\": ReverseOrientation (or a mirroring transform) is not supported for spheres: "
              "its front stays the outside");
    cJSON *o = cJSON_CreateObject();
    if (!o) return PM_ENOMEM;
    cJSON_AddStringToObject(o, "type", "sphere");
    cJSON_AddItemToObject(o, "center", jv(out_v(c, m_point(c->g.m, v3s(0)))));
    cJSON_AddNumberToObject(o, "radius", r * smax);
    cJSON_AddStringToObject(o, "material", mat);
    cJSON_AddItemToArray(c->target, o);
    return 0;
}

/* ---- instances ---------------------------------------------------------------------------- */

/* A copy of converted object o under the matrix X (output coordinates). */
static cJSON *xform_obj(const conv *c, const cJSON *o, double X[4][4]) {
    cJSON *n = cJSON_Duplicate(o, 1);
    if (!n) return NULL;
    const cJSON *type = cJSON_GetObjectItemCaseSensitive(n, "type");
    const char *t = cJSON_IsString(type) ? type->valuestring : "";
    (void)c;
    if (strcmp(t, "sphere") == 0) {
        cJSON *ce = cJSON_GetObjectItemCaseSensitive(n, "center"), *r = cJSON_GetObjectItemCaseSensitive(n, "radius");
        vec3 p = v3(cJSON_GetArrayItem(ce, 0)->valuedouble, cJSON_GetArrayItem(ce, 1)->valuedouble,
                    cJSON_GetArrayItem(ce, 2)->valuedouble);
        double s = 0;
        for (int k = 0; k < 3; k++) s = fmax(s, v3_len(m_dir(X, v3(k == 0, k == 1, k == 2))));
        cJSON_ReplaceItemInObjectCaseSensitive(n, "center", jv(m_point(X, p)));
        cJSON_ReplaceItemInObjectCaseSensitive(n, "radius", cJSON_CreateNumber(r->valuedouble * s));
    } else if (cJSON_GetObjectItemCaseSensitive(n, "file")) {
        cJSON *tr = cJSON_GetObjectItemCaseSensitive(n, "transform");
        double A[4][4], R[4][4], M[16];
        for (int i = 0; i < 16; i++) A[i / 4][i % 4] = cJSON_GetArrayItem(tr, i)->valuedouble;
        m_mul(X, A, R);
        for (int i = 0; i < 16; i++) M[i] = R[i / 4][i % 4];
        cJSON_ReplaceItemInObjectCaseSensitive(n, "transform", cJSON_CreateDoubleArray(M, 16));
        if (m_det3(X) < 0) { /* a mirroring instance turns the winding: keep the front */
            cJSON *fl = cJSON_GetObjectItemCaseSensitive(n, "flip");
            int f = cJSON_IsTrue(fl);
            cJSON_DeleteItemFromObjectCaseSensitive(n, "flip");
            if (!f) cJSON_AddBoolToObject(n, "flip", 1);
        }
    } else {
        cJSON *vs = cJSON_GetObjectItemCaseSensitive(n, "vertices");
        for (cJSON *v = vs ? vs->child : NULL; v; v = v->next) {
            vec3 p = v3(cJSON_GetArrayItem(v, 0)->valuedouble, cJSON_GetArrayItem(v, 1)->valuedouble,
                        cJSON_GetArrayItem(v, 2)->valuedouble);
            vec3 q = m_point(X, p);
            double a[3] = {q.x, q.y, q.z};
            for (int k = 0; k < 3; k++) cJSON_SetNumberValue(cJSON_GetArrayItem(v, k), a[k]);
        }
        if (m_det3(X) < 0) {
            cJSON *ts = cJSON_GetObjectItemCaseSensitive(n, "triangles");
            for (cJSON *t3 = ts ? ts->child : NULL; t3; t3 = t3->next) {
                cJSON *b = cJSON_GetArrayItem(t3, 1), *d = cJSON_GetArrayItem(t3, 2);
                double x = b->valuedouble;
                cJSON_SetNumberValue(b, d->valuedouble);
                cJSON_SetNumberValue(d, x);
            }
        }
    }
    return n;
}

/* ---- directives --------------------------------------------------------------------------- */

static int nums(conv *c, const toks *ts, int *i, const tok *at, int n, double *v, const char *what) {
    int br = *i < ts->n && ts->t[*i].kind == K_LB;
    if (br) (*i)++;
    for (int k = 0; k < n; k++, (*i)++) {
        if (*i >= ts->n || ts->t[*i].kind != K_NUM)
            return pfail(c, at, PM_EINVAL, "%s: expected %d numbers, got %d", what, n, k);
        v[k] = ts->t[*i].num;
        if (!isfinite(v[k])) return pfail(c, at, PM_EINVAL, "%s: number %d is not finite", what, k + 1);
    }
    if (br) {
        if (*i >= ts->n || ts->t[*i].kind != K_RB) return pfail(c, at, PM_EINVAL, "%s: unbalanced [ (no closing ] after %d numbers)", what, n);
        (*i)++;
    }
    return 0;
}

static int one_string(conv *c, const toks *ts, int *i, const tok *at, const char **s, const char *what) {
    if (*i >= ts->n || ts->t[*i].kind != K_STR) return pfail(c, at, PM_EINVAL, "%s: expected a quoted name", what);
    *s = ts->t[(*i)++].s;
    return 0;
}

static int apply(conv *c, const tok *at, double T[4][4]) {
    double r[4][4];
    m_mul(c->g.m, T, r);
    for (int i = 0; i < 4; i++)
        for (int j = 0; j < 4; j++)
            if (!isfinite(r[i][j])) return pfail(c, at, PM_EINVAL, "the transform is not finite");
    memcpy(c->g.m, r, sizeof r);
    return 0;
}

static int run_file(conv *c, const char *path, const tok *from);

static int camera_done(conv *c, const tok *at) {
    snprintf(c->cam_medium, sizeof c->cam_medium, "%s", c->g.outside);
    double inv[4][4];
    if (m_inv(c->g.m, inv) < 0) return pfail(c, at, PM_EINVAL, "Camera: the camera transform is singular or not finite");
    memcpy(c->cam2world, inv, sizeof inv);
    c->have_camera = 1;
    if (c->ncs < 16) {
        snprintf(c->cs[c->ncs].name, sizeof c->cs[0].name, "camera");
        memcpy(c->cs[c->ncs++].m, inv, sizeof inv);
    }
    return 0;
}

static int world_begin(conv *c) {
    /* pbrt's image right is the camera's +x; ours is forward x up: mirror when they disagree */
    vec3 fwd = m_dir(c->cam2world, v3(0, 0, 1)), up = m_dir(c->cam2world, v3(0, 1, 0)), right = m_dir(c->cam2world, v3(1, 0, 0));
    c->mirror = v3_dot(v3_cross(fwd, up), right) < 0;
    m_ident(c->g.m);
    c->in_world = 1;
    return 0;
}

static int directive(conv *c, const toks *ts, int *i) {
    const tok *at = &ts->t[*i];
    if (at->kind != K_WORD) {
        if (at->kind == K_LB || at->kind == K_RB)
            return pfail(c, at, PM_EINVAL, "unbalanced %s outside a parameter list", at->kind == K_LB ? "[" : "]");
        if (at->kind == K_STR)
            return pfail(c, at, PM_EINVAL, "a parameter \"%.40s\" without a directive before it", at->s);
        return pfail(c, at, PM_EINVAL, "a number (%g) where a directive was expected", at->num);
    }
    const char *d = at->s;
    (*i)++;
    double v[16];
    const char *s = NULL;
    plist pl;
    pl.n = 0;
    int rc = 0;
    if (strcmp(d, "LookAt") == 0) {
        TRY(nums(c, ts, i, at, 9, v, "LookAt"));
        vec3 eye = v3(v[0], v[1], v[2]), look = v3(v[3], v[4], v[5]), up = v3(v[6], v[7], v[8]);
        vec3 dir = v3_sub(look, eye);
        if (!(v3_len(dir) > 0)) return pfail(c, at, PM_EINVAL, "LookAt: the eye and the point looked at are the same");
        dir = v3_norm(dir);
        vec3 right = v3_cross(v3_norm(up), dir);
        if (!(v3_len(right) > 1e-12)) return pfail(c, at, PM_EINVAL, "LookAt: up is parallel to the view direction");
        right = v3_norm(right);
        vec3 nup = v3_cross(dir, right);
        double C[4][4] = {{right.x, nup.x, dir.x, eye.x}, {right.y, nup.y, dir.y, eye.y}, {right.z, nup.z, dir.z, eye.z}, {0, 0, 0, 1}};
        double W[4][4];
        if (m_inv(C, W) < 0) return pfail(c, at, PM_EINVAL, "LookAt: singular");
        return apply(c, at, W);
    } else if (strcmp(d, "Translate") == 0) {
        TRY(nums(c, ts, i, at, 3, v, "Translate"));
        double T[4][4];
        m_ident(T);
        T[0][3] = v[0];
        T[1][3] = v[1];
        T[2][3] = v[2];
        return apply(c, at, T);
    } else if (strcmp(d, "Scale") == 0) {
        TRY(nums(c, ts, i, at, 3, v, "Scale"));
        double T[4][4];
        m_ident(T);
        T[0][0] = v[0];
        T[1][1] = v[1];
        T[2][2] = v[2];
        return apply(c, at, T);
    } else if (strcmp(d, "Rotate") == 0) {
        TRY(nums(c, ts, i, at, 4, v, "Rotate"));
        vec3 a = v3(v[1], v[2], v[3]);
        if (!(v3_len(a) > 0)) return pfail(c, at, PM_EINVAL, "Rotate: the axis is the zero vector");
        a = v3_norm(a);
        double t = v[0] * M_PI / 180, cs = cos(t), sn = sin(t);
        double T[4][4] = {{a.x * a.x + (1 - a.x * a.x) * cs, a.x * a.y * (1 - cs) - a.z * sn, a.x * a.z * (1 - cs) + a.y * sn, 0},
                          {a.x * a.y * (1 - cs) + a.z * sn, a.y * a.y + (1 - a.y * a.y) * cs, a.y * a.z * (1 - cs) - a.x * sn, 0},
                          {a.x * a.z * (1 - cs) - a.y * sn, a.y * a.z * (1 - cs) + a.x * sn, a.z * a.z + (1 - a.z * a.z) * cs, 0},
                          {0, 0, 0, 1}};
        return apply(c, at, T);
    } else if (strcmp(d, "Transform") == 0 || strcmp(d, "ConcatTransform") == 0) {
        TRY(nums(c, ts, i, at, 16, v, d));
        double T[4][4];
        for (int r = 0; r < 4; r++)
            for (int k = 0; k < 4; k++) T[r][k] = v[4 * k + r]; /* pbrt gives the columns */
        if (d[0] == 'T') m_ident(c->g.m);
        return apply(c, at, T);
    } else if (strcmp(d, "Identity") == 0) {
        m_ident(c->g.m);
        return 0;
    } else if (strcmp(d, "CoordinateSystem") == 0 || strcmp(d, "CoordSysTransform") == 0) {
        TRY(one_string(c, ts, i, at, &s, d));
        if (d[5] == 'i') { /* CoordinateSystem */
            if (c->ncs == 16) return pfail(c, at, PM_EINVAL, "more than 16 named coordinate systems");
            snprintf(c->cs[c->ncs].name, sizeof c->cs[0].name, "%s", s);
            memcpy(c->cs[c->ncs++].m, c->g.m, sizeof c->g.m);
            return 0;
        }
        for (int k = c->ncs - 1; k >= 0; k--)
            if (strcmp(c->cs[k].name, s) == 0) {
                memcpy(c->g.m, c->cs[k].m, sizeof c->g.m);
                return 0;
            }
        return pfail(c, at, PM_EINVAL, "CoordSysTransform: no coordinate system named \"%s\"", s);
    } else if (strcmp(d, "ReverseOrientation") == 0) {
        c->g.revor = !c->g.revor;
        return 0;
    } else if (strcmp(d, "AttributeBegin") == 0 || strcmp(d, "TransformBegin") == 0) {
        if (c->depth == PB_MAX_STACK) return pfail(c, at, PM_EINVAL, "more than %d nested %s", PB_MAX_STACK, d);
        c->stack_kind[c->depth] = d[0] == 'A' ? 1 : 2;
        c->stack[c->depth++] = c->g;
        return 0;
    } else if (strcmp(d, "AttributeEnd") == 0 || strcmp(d, "TransformEnd") == 0) {
        int kind = d[0] == 'A' ? 1 : 2;
        if (c->depth == 0 || c->stack_kind[c->depth - 1] != kind)
            return pfail(c, at, PM_EINVAL, "%s without a matching %s", d, kind == 1 ? "AttributeBegin" : "TransformBegin");
        c->depth--;
        if (kind == 1) c->g = c->stack[c->depth];
        else memcpy(c->g.m, c->stack[c->depth].m, sizeof c->g.m);
        return 0;
    } else if (strcmp(d, "WorldBegin") == 0) {
        if (c->in_world) return pfail(c, at, PM_EINVAL, "WorldBegin twice");
        if (!c->have_camera) { /* pbrt's default camera: at the origin, looking down +z */
            m_ident(c->g.m);
            TRY(camera_done(c, at));
        }
        return world_begin(c);
    } else if (strcmp(d, "WorldEnd") == 0) {
        return 0;
    } else if (strcmp(d, "Include") == 0 || strcmp(d, "Import") == 0) {
        TRY(one_string(c, ts, i, at, &s, d));
        char path[8192];
        resolve(tfile(c, at), s, path, sizeof path);
        return run_file(c, path, at);
    } else if (strcmp(d, "ObjectBegin") == 0) {
        TRY(one_string(c, ts, i, at, &s, d));
        if (c->target != c->objs) return pfail(c, at, PM_EINVAL, "ObjectBegin inside ObjectBegin \"%s\"", s);
        if (c->depth == PB_MAX_STACK) return pfail(c, at, PM_EINVAL, "more than %d nested blocks", PB_MAX_STACK);
        c->stack_kind[c->depth] = 3;
        c->stack[c->depth++] = c->g;
        named_obj *no = realloc(c->nobj, (size_t)(c->nnobj + 1) * sizeof *no);
        if (!no) return PM_ENOMEM;
        c->nobj = no;
        snprintf(no[c->nnobj].name, sizeof no[0].name, "%s", s);
        no[c->nnobj].objs = cJSON_CreateArray();
        if (!no[c->nnobj].objs) return PM_ENOMEM;
        c->target = no[c->nnobj++].objs;
        return 0;
    } else if (strcmp(d, "ObjectEnd") == 0) {
        if (c->target == c->objs || c->depth == 0 || c->stack_kind[c->depth - 1] != 3)
            return pfail(c, at, PM_EINVAL, "ObjectEnd without ObjectBegin");
        c->g = c->stack[--c->depth];
        c->target = c->objs;
        return 0;
    } else if (strcmp(d, "ObjectInstance") == 0) {
        TRY(one_string(c, ts, i, at, &s, d));
        if (c->target != c->objs) return pfail(c, at, PM_EINVAL, "ObjectInstance inside ObjectBegin");
        for (int k = c->nnobj - 1; k >= 0; k--)
            if (strcmp(c->nobj[k].name, s) == 0) {
                double X[4][4]; /* the instance transform in output coordinates: S ctm S */
                memcpy(X, c->g.m, sizeof X);
                if (c->mirror)
                    for (int r = 0; r < 4; r++)
                        for (int q = 0; q < 4; q++)
                            if ((r == 0) != (q == 0)) X[r][q] = -X[r][q];
                for (const cJSON *o = c->nobj[k].objs->child; o; o = o->next) {
                    cJSON *n = xform_obj(c, o, X);
                    if (!n) return PM_ENOMEM;
                    cJSON_AddItemToArray(c->objs, n);
                }
                return 0;
            }
        return pfail(c, at, PM_EINVAL, "ObjectInstance: no object named \"%s\"", s);
    }
    /* directives with a name and a parameter list */
    static const char *const named[] = {"Camera", "Film", "Sampler", "Integrator", "PixelFilter", "Accelerator",
                                        "Shape", "Material", "MakeNamedMaterial", "NamedMaterial", "AreaLightSource",
                                        "LightSource", "MakeNamedMedium", "SurfaceIntegrator", "VolumeIntegrator",
                                        "Renderer", "ColorSpace", "Option", NULL};
    int known = 0;
    for (int k = 0; named[k]; k++) known |= strcmp(d, named[k]) == 0;
    if (strcmp(d, "Texture") == 0) {
        const char *a, *b, *cl;
        TRY(one_string(c, ts, i, at, &a, d));
        TRY(one_string(c, ts, i, at, &b, d));
        TRY(one_string(c, ts, i, at, &cl, d));
        TRY(read_params(c, ts, i, &pl));
        pwarn(c, at, "Texture \"%s\": textures are not supported: materials that use it get their default value", a);
        plist_free(&pl);
        return 0;
    }
    if (strcmp(d, "MediumInterface") == 0) { /* "inside" ["outside"]; one name is both */
        const char *a = NULL, *b = NULL;
        TRY(one_string(c, ts, i, at, &a, d));
        if (*i < ts->n && ts->t[*i].kind == K_STR) b = ts->t[(*i)++].s;
        if (!b) b = a;
        const char *nm[2] = {a, b};
        for (int k = 0; k < 2; k++)
            if (nm[k][0] && !(c->media && cJSON_GetObjectItemCaseSensitive(c->media, nm[k])))
                return pfail(c, at, PM_EINVAL, "MediumInterface: no medium named \"%s\" (MakeNamedMedium first)", nm[k]);
        snprintf(c->g.inside, sizeof c->g.inside, "%s", a);
        snprintf(c->g.outside, sizeof c->g.outside, "%s", b);
        return 0;
    }
    if (!known) {
        pwarn(c, at, "unknown directive \"%s\": skipped with its arguments", d);
        while (*i < ts->n && !(ts->t[*i].kind == K_WORD && strcmp(ts->t[*i].s, "true") != 0 && strcmp(ts->t[*i].s, "false") != 0))
            (*i)++;
        return 0;
    }
    TRY(one_string(c, ts, i, at, &s, d));
    rc = read_params(c, ts, i, &pl);
    if (rc < 0) {
        plist_free(&pl);
        return rc;
    }
    char what[160];
    snprintf(what, sizeof what, "%s \"%s\"", d, s);
    if (strcmp(d, "Camera") == 0) {
        if (strcmp(s, "perspective") != 0)
            rc = pfail(c, at, PM_EINVAL, "Camera \"%s\" is not supported (perspective)", s);
        if (rc == 0 && (rc = get_floats(c, at, &pl, "fov", "float", 1, &c->fov)) > 0) rc = 0;
        double lr = 0, fa = 0, sw[4];
        if (rc == 0 && (rc = get_floats(c, at, &pl, "lensradius", "float", 1, &lr)) > 0) rc = 0;
        if (rc == 0 && lr > 0) pwarn(c, at, "%s: lensradius %g: depth of field is not supported: a pinhole", what, lr);
        if (rc == 0 && (rc = get_floats(c, at, &pl, "focaldistance", "float", 1, &fa)) > 0) rc = 0;
        if (rc == 0 && (rc = get_floats(c, at, &pl, "frameaspectratio", "float", 1, &fa)) > 0) {
            rc = 0;
            pwarn(c, at, "%s: frameaspectratio is not supported: the image's own aspect", what);
        }
        if (rc == 0 && (rc = get_floats(c, at, &pl, "screenwindow", "float", 4, sw)) > 0) {
            rc = 0;
            pwarn(c, at, "%s: screenwindow is not supported: the full frame", what);
        }
        if (rc == 0 && !(c->fov > 0 && c->fov < 180)) rc = pfail(c, at, PM_EINVAL, "%s: fov %g is not in (0, 180)", what, c->fov);
        if (rc == 0) rc = camera_done(c, at);
        if (rc == 0) warn_unused(c, at, what, &pl);
    } else if (strcmp(d, "Film") == 0) {
        double x = 0;
        if ((rc = get_floats(c, at, &pl, "xresolution", "integer", 1, &x)) > 0) c->width = (long)x;
        if (rc >= 0 && (rc = get_floats(c, at, &pl, "yresolution", "integer", 1, &x)) > 0) c->height = (long)x;
        const char *fn;
        if (rc >= 0) rc = get_string(c, at, &pl, "filename", &fn); /* the output name: not ours to follow */
        double cw[4];
        if (rc >= 0 && (rc = get_floats(c, at, &pl, "cropwindow", "float", 4, cw)) > 0)
            pwarn(c, at, "%s: cropwindow is not supported: the whole image", what);
        if (rc >= 0) rc = 0;
        if (rc == 0 && (c->width < 1 || c->height < 1 || c->width > 16384 || c->height > 16384))
            rc = pfail(c, at, PM_EINVAL, "%s: resolution %ld x %ld outside 1..16384", what, c->width, c->height);
        if (rc == 0) warn_unused(c, at, what, &pl);
    } else if (strcmp(d, "Sampler") == 0) {
        double x = 0;
        int strat = strcmp(s, "stratified") == 0;
        if ((rc = get_floats(c, at, &pl, "pixelsamples", "integer", 1, &x)) > 0) c->spp = (long)x;
        if (rc >= 0 && strat) {
            double xs = 4, ys = 4;
            int a = get_floats(c, at, &pl, "xsamples", "integer", 1, &xs), b = get_floats(c, at, &pl, "ysamples", "integer", 1, &ys);
            int jit = 1;
            if (a < 0 || b < 0 || get_bool(c, at, &pl, "jitter", &jit) < 0) rc = PM_EINVAL;
            else c->spp = (long)(xs * ys);
        }
        if (rc >= 0) rc = 0;
        if (rc == 0 && !strat)
            pwarn(c, at, "%s is not supported: our stratified sampler is used (%ld samples per pixel)", what, c->spp);
        if (rc == 0 && (c->spp < 1 || c->spp > (1 << 20)))
            rc = pfail(c, at, PM_EINVAL, "%s: %ld samples per pixel outside 1..1048576", what, c->spp);
        if (rc == 0) warn_unused(c, at, what, &pl);
    } else if (strcmp(d, "Integrator") == 0 || strcmp(d, "SurfaceIntegrator") == 0) {
        double md = 5;
        if ((rc = get_floats(c, at, &pl, "maxdepth", "integer", 1, &md)) >= 0) rc = 0;
        c->maxdepth = (long)md;
        if (rc == 0 && (md < 1 || md > 100000)) rc = pfail(c, at, PM_EINVAL, "%s: maxdepth %g outside 1..100000", what, md);
        if (rc == 0) {
            if (strcmp(s, "path") == 0) c->mode = "path";
            else if (strcmp(s, "sppm") == 0) c->mode = "pm";
            else {
                c->mode = "path";
                pwarn(c, at, "%s is not supported: rendering with \"path\" (path tracing; --mode chooses another)", what);
            }
            for (int k = 0; k < pl.n; k++)
                if (!pl.p[k].used && strcmp(s, "path") != 0) pl.p[k].used = 1; /* settings of another method */
            warn_unused(c, at, what, &pl);
        }
    } else if (strcmp(d, "PixelFilter") == 0) {
        if (strcmp(s, "box") != 0)
            pwarn(c, at, "%s is not supported: each pixel is the mean of its own samples (a box filter) instead", what);
        for (int k = 0; k < pl.n; k++) pl.p[k].used = 1;
    } else if (strcmp(d, "Accelerator") == 0 || strcmp(d, "Renderer") == 0 || strcmp(d, "VolumeIntegrator") == 0 ||
               strcmp(d, "ColorSpace") == 0 || strcmp(d, "Option") == 0) {
        pwarn(c, at, "%s: ignored (does not change the image, or not supported)", what);
    } else if (strcmp(d, "Material") == 0 || strcmp(d, "MakeNamedMaterial") == 0) {
        const char *type = s;
        char name[80];
        if (strcmp(d, "MakeNamedMaterial") == 0) {
            rc = get_string(c, at, &pl, "type", &type);
            if (rc == 0) rc = pfail(c, at, PM_EINVAL, "%s: \"string type\" missing", what);
            if (rc > 0) rc = 0;
            snprintf(name, sizeof name, "%s", s);
        } else {
            snprintf(name, sizeof name, "pbrt:%d", c->nanon++);
        }
        cJSON *m = NULL;
        if (rc == 0 && (strcmp(type, "") == 0 || strcmp(type, "none") == 0 || strcmp(type, "interface") == 0)) {
            m = cJSON_CreateObject();
            if (m) cJSON_AddStringToObject(m, "type", "null");
        } else if (rc == 0) {
            rc = make_material(c, at, type, &pl, &m);
        }
        if (rc == 0 && m) {
            add_material(c, name, m);
            if (strcmp(d, "Material") == 0) snprintf(c->g.mat, sizeof c->g.mat, "%s", name);
        } else {
            cJSON_Delete(m);
        }
    } else if (strcmp(d, "NamedMaterial") == 0) {
        if (!cJSON_GetObjectItemCaseSensitive(c->mats, s)) rc = pfail(c, at, PM_EINVAL, "NamedMaterial: no material named \"%s\"", s);
        else snprintf(c->g.mat, sizeof c->g.mat, "%s", s);
    } else if (strcmp(d, "AreaLightSource") == 0) {
        if (strcmp(s, "diffuse") != 0) {
            pwarn(c, at, "%s is not supported (diffuse): the shapes that follow do not emit", what);
            for (int k = 0; k < pl.n; k++) pl.p[k].used = 1;
        } else {
            rgb L = v3s(1), sc = v3s(1);
            int two = 0;
            double ns;
            if ((rc = get_color(c, at, &pl, "L", &L)) >= 0 && (rc = get_color(c, at, &pl, "scale", &sc)) >= 0 &&
                (rc = get_bool(c, at, &pl, "twosided", &two)) >= 0 && (rc = get_floats(c, at, &pl, "samples", "integer", 1, &ns)) >= 0 &&
                (rc = get_floats(c, at, &pl, "nsamples", "integer", 1, &ns)) >= 0) {
                rc = 0;
                c->g.area = 1;
                c->g.L = v3_mul(L, sc);
                c->g.twosided = two;
                if (c->g.L.x < 0 || c->g.L.y < 0 || c->g.L.z < 0) rc = pfail(c, at, PM_EINVAL, "%s: L must not be negative", what);
                if (rc == 0) warn_unused(c, at, what, &pl);
            }
        }
    } else if (strcmp(d, "LightSource") == 0) {
        rgb sc = v3s(1);
        if ((rc = get_color(c, at, &pl, "scale", &sc)) >= 0) rc = 0;
        if (rc == 0 && strcmp(s, "point") == 0) {
            rgb I = v3s(1);
            double from[3] = {0, 0, 0};
            if ((rc = get_color(c, at, &pl, "I", &I)) >= 0 && (rc = get_floats(c, at, &pl, "from", "point", 3, from)) >= 0) {
                rc = 0;
                cJSON *l = cJSON_CreateObject();
                if (!l) return PM_ENOMEM;
                cJSON_AddStringToObject(l, "type", "point");
                cJSON_AddItemToObject(l, "position", jv(out_v(c, m_point(c->g.m, v3(from[0], from[1], from[2])))));
                cJSON_AddItemToObject(l, "intensity", jv(v3_mul(I, sc)));
                cJSON_AddItemToArray(c->lights, l);
                warn_unused(c, at, what, &pl);
            }
        } else if (rc == 0 && strcmp(s, "distant") == 0) {
            rgb L = v3s(1);
            double from[3] = {0, 0, 0}, to[3] = {0, 0, 1};
            if ((rc = get_color(c, at, &pl, "L", &L)) >= 0 && (rc = get_floats(c, at, &pl, "from", "point", 3, from)) >= 0 &&
                (rc = get_floats(c, at, &pl, "to", "point", 3, to)) >= 0) {
                rc = 0;
                vec3 dir = out_v(c, m_dir(c->g.m, v3(to[0] - from[0], to[1] - from[1], to[2] - from[2])));
                if (!(v3_len(dir) > 0)) rc = pfail(c, at, PM_EINVAL, "%s: from and to are the same point", what);
                cJSON *l = rc == 0 ? cJSON_CreateObject() : NULL;
                if (l) {
                    cJSON_AddStringToObject(l, "type", "directional");
                    cJSON_AddItemToObject(l, "direction", jv(v3_norm(dir)));
                    cJSON_AddItemToObject(l, "irradiance", jv(v3_mul(L, sc)));
                    cJSON_AddItemToArray(c->lights, l);
                    warn_unused(c, at, what, &pl);
                }
            }
        } else if (rc == 0) {
            pwarn(c, at, "%s is not supported (point, distant): skipped, so its light is missing", what);
        }
    } else if (strcmp(d, "MakeNamedMedium") == 0) {
        const char *type = NULL, *preset = NULL;
        rgb sa = v3(0.0011, 0.0024, 0.014), ss = v3(2.55, 3.21, 3.77); /* pbrt-v3's defaults */
        double scale = 1, g = 0;
        if ((rc = get_string(c, at, &pl, "type", &type)) == 0) rc = pfail(c, at, PM_EINVAL, "%s: \"string type\" missing", what);
        if (rc > 0 && strcmp(type, "homogeneous") != 0)
            rc = pfail(c, at, PM_EINVAL, "%s: medium type \"%s\" is not supported (homogeneous)", what, type);
        if (rc > 0 && (rc = get_string(c, at, &pl, "preset", &preset)) > 0)
            pwarn(c, at, "%s: the preset \"%s\" is not supported: sigma_a and sigma_s as given (or pbrt's defaults)", what, preset);
        if (rc >= 0 && (rc = get_color(c, at, &pl, "sigma_a", &sa)) >= 0 && (rc = get_color(c, at, &pl, "sigma_s", &ss)) >= 0 &&
            (rc = get_floats(c, at, &pl, "scale", "float", 1, &scale)) >= 0 && (rc = get_floats(c, at, &pl, "g", "float", 1, &g)) >= 0)
            rc = 0;
        if (rc == 0 && (sa.x < 0 || sa.y < 0 || sa.z < 0 || ss.x < 0 || ss.y < 0 || ss.z < 0 || !(scale >= 0)))
            rc = pfail(c, at, PM_EINVAL, "%s: sigma_a, sigma_s and scale must not be negative", what);
        if (rc == 0 && !(g > -1 && g < 1)) rc = pfail(c, at, PM_EINVAL, "%s: g must be in (-1, 1), got %g", what, g);
        if (rc == 0 && !c->media && !(c->media = cJSON_CreateObject())) rc = PM_ENOMEM;
        if (rc == 0) {
            cJSON *m = cJSON_CreateObject();
            if (!m) return PM_ENOMEM;
            cJSON_AddItemToObject(m, "sigma_a", jv(v3_scale(sa, scale)));
            cJSON_AddItemToObject(m, "sigma_s", jv(v3_scale(ss, scale)));
            cJSON_AddNumberToObject(m, "g", g);
            if (cJSON_GetObjectItemCaseSensitive(c->media, s)) cJSON_ReplaceItemInObjectCaseSensitive(c->media, s, m);
            else cJSON_AddItemToObject(c->media, s, m);
            pparam *le;
            TRY(pget(c, at, &pl, "Le", "rgb|spectrum|blackbody", &le));
            if (le) pwarn(c, at, "%s: an emitting medium (Le) is not supported: it does not emit", what);
            warn_unused(c, at, what, &pl);
        }
    } else if (strcmp(d, "Shape") == 0) {
        char mat[96];
        if (!c->in_world) rc = pfail(c, at, PM_EINVAL, "Shape before WorldBegin");
        const cJSON *cur = rc == 0 ? cJSON_GetObjectItemCaseSensitive(c->mats, c->g.mat) : NULL;
        const cJSON *ct = cur ? cJSON_GetObjectItemCaseSensitive(cur, "type") : NULL;
        int is_null = cJSON_IsString(ct) && strcmp(ct->valuestring, "null") == 0;
        /* media (pbrt.h): the inside of a shape is its interior_medium; its outside must be the
         * camera's medium, ours between all objects */
        int new_inside = strcmp(c->g.inside, c->cam_medium) != 0;
        if (rc == 0 && (c->g.inside[0] || c->g.outside[0]) && strcmp(c->g.outside, c->cam_medium) != 0)
            pwarn(c, at, "%s: the medium outside it (\"%s\") is not the camera's (\"%s\"): one medium surrounds all "
                  "objects here, the camera's", what, c->g.outside, c->cam_medium);
        if (rc == 0 && is_null && !new_inside) {
            pwarn(c, at, "%s with material \"none\" or \"interface\" and no medium of its own inside: skipped", what);
            for (int k = 0; k < pl.n; k++) pl.p[k].used = 1;
        } else if (rc == 0 && (rc = shape_material(c, mat, sizeof mat)) == 0) {
            int before = cJSON_GetArraySize(c->target);
            if (strcmp(s, "trianglemesh") == 0) rc = shape_trianglemesh(c, at, &pl, mat);
            else if (strcmp(s, "plymesh") == 0) rc = shape_plymesh(c, at, &pl, mat);
            else if (strcmp(s, "sphere") == 0) rc = shape_sphere(c, at, &pl, mat);
            else {
                pwarn(c, at, "%s is not supported (trianglemesh, plymesh, sphere): skipped", what);
                for (int k = 0; k < pl.n; k++) pl.p[k].used = 1;
            }
            cJSON *made = cJSON_GetArraySize(c->target) > before ? cJSON_GetArrayItem(c->target, before) : NULL;
            /* only a surface light passes through has an inside that matters (ours: a closed
             * sphere or mesh); no key is no medium inside */
            int passes = is_null || (cJSON_IsString(ct) && strcmp(ct->valuestring, "dielectric") == 0);
            if (rc == 0 && made && passes && c->g.inside[0])
                cJSON_AddStringToObject(made, "interior_medium", c->g.inside);
            pparam *al;
            if (rc == 0) rc = pget(c, at, &pl, "alpha", "float|texture", &al);
            if (rc == 0 && al) pwarn(c, at, "%s: alpha is not supported: opaque", what);
            if (rc == 0) warn_unused(c, at, what, &pl);
        }
    }
    plist_free(&pl);
    return rc < 0 ? rc : 0;
}

static int run_tokens(conv *c, const toks *ts) {
    int i = 0;
    while (i < ts->n) TRY(directive(c, ts, &i));
    return 0;
}

static int run_text(conv *c, const char *text, const char *name) {
    if (c->nfiles == (int)(sizeof c->files / sizeof *c->files))
        return json_fail(c->e, PM_EINVAL, "%s: more than %d files included", name, (int)(sizeof c->files / sizeof *c->files));
    c->files[c->nfiles] = strdup(name);
    if (!c->files[c->nfiles]) return PM_ENOMEM;
    toks ts = {0};
    int rc = lex(c, text, c->nfiles++, &ts);
    if (rc == PM_ENOMEM) json_fail(c->e, rc, "out of memory");
    if (rc == 0) rc = run_tokens(c, &ts);
    toks_free(&ts);
    return rc;
}

static int run_file(conv *c, const char *path, const tok *from) {
    if (c->include_depth >= PB_MAX_INCLUDE)
        return pfail(c, from, PM_EINVAL, "Include nested more than %d deep (a file including itself?)", PB_MAX_INCLUDE);
    char *buf;
    size_t len;
    char err[600];
    int rc = mesh_read_file(path, &buf, &len, err, sizeof err);
    if (rc < 0) return from ? pfail(c, from, rc, "Include: %s", err) : json_fail(c->e, rc, "%s", err);
    if (strlen(buf) != len) {
        free(buf);
        return from ? pfail(c, from, PM_EINVAL, "Include: %s: a NUL byte: not a pbrt text", path)
                    : json_fail(c->e, PM_EINVAL, "a NUL byte: not a pbrt text");
    }
    c->include_depth++;
    rc = run_text(c, buf, path);
    c->include_depth--;
    free(buf);
    return rc;
}

int pbrt_is_file(const char *path) {
    size_t n = path ? strlen(path) : 0;
    return n >= 5 && path[n - 5] == '.' && tolower((unsigned char)path[n - 4]) == 'p' &&
           tolower((unsigned char)path[n - 3]) == 'b' && tolower((unsigned char)path[n - 2]) == 'r' &&
           tolower((unsigned char)path[n - 1]) == 't';
}

static int convert(const char *text, const char *path, cJSON **out, json_err *e) {
    conv *c = calloc(1, sizeof *c);
    *out = NULL;
    if (!c) return json_fail(e, PM_ENOMEM, "out of memory");
    c->e = e;
    m_ident(c->g.m);
    c->width = 1280;
    c->height = 720;
    c->spp = 16;
    c->maxdepth = 5;
    c->fov = 90;
    c->mode = "path";
    c->mats = cJSON_CreateObject();
    c->objs = cJSON_CreateArray();
    c->lights = cJSON_CreateArray();
    c->target = c->objs;
    int rc = c->mats && c->objs && c->lights ? 0 : json_fail(e, PM_ENOMEM, "out of memory");
    /* pbrt's default material: matte, Kd 0.5 */
    cJSON *def = cJSON_CreateObject();
    if (rc == 0 && def) {
        cJSON_AddStringToObject(def, "type", "lambert");
        cJSON_AddNumberToObject(def, "reflectance", 0.5);
        cJSON_AddItemToObject(c->mats, "pbrt:default", def);
        snprintf(c->g.mat, sizeof c->g.mat, "pbrt:default");
    }
    if (rc == 0) rc = text ? run_text(c, text, path) : run_file(c, path, NULL);
    if (rc == 0 && c->depth > 0) {
        rc = json_fail(e, PM_EINVAL, "%s: %d AttributeBegin/TransformBegin/ObjectBegin left open at the end", path, c->depth);
    }
    if (rc == 0 && !c->in_world) rc = json_fail(e, PM_EINVAL, "%s: no WorldBegin", path);
    cJSON *doc = rc == 0 ? cJSON_CreateObject() : NULL;
    if (rc == 0 && !doc) rc = json_fail(e, PM_ENOMEM, "out of memory");
    if (rc == 0) {
        cJSON_AddStringToObject(doc, "description", "converted from a pbrt-v3 scene by render");
        cJSON *cam = cJSON_CreateObject();
        vec3 eye = out_v(c, m_point(c->cam2world, v3s(0)));
        vec3 fwd = out_v(c, m_dir(c->cam2world, v3(0, 0, 1))), up = out_v(c, m_dir(c->cam2world, v3(0, 1, 0)));
        double t = tan(c->fov * M_PI / 360);
        double hfov = c->width >= c->height ? 2 * atan(t * (double)c->width / (double)c->height) * 180 / M_PI : c->fov;
        cJSON_AddItemToObject(cam, "eye", jv(eye));
        cJSON_AddItemToObject(cam, "look_at", jv(v3_add(eye, v3_norm(fwd))));
        cJSON_AddItemToObject(cam, "up", jv(v3_norm(up)));
        cJSON_AddNumberToObject(cam, "fov_deg", hfov);
        cJSON_AddNumberToObject(cam, "width", (double)c->width);
        cJSON_AddNumberToObject(cam, "height", (double)c->height);
        cJSON_AddNumberToObject(cam, "spp", (double)c->spp);
        cJSON_AddItemToObject(doc, "camera", cam);
        cJSON_AddItemToObject(doc, "materials", c->mats);
        cJSON_AddItemToObject(doc, "objects", c->objs);
        cJSON_AddItemToObject(doc, "lights", c->lights);
        if (c->media) cJSON_AddItemToObject(doc, "media", c->media);
        if (c->cam_medium[0]) cJSON_AddStringToObject(doc, "medium", c->cam_medium);
        c->mats = c->objs = c->lights = c->media = NULL;
        cJSON *r = cJSON_CreateObject();
        cJSON_AddStringToObject(r, "mode", c->mode);
        cJSON_AddNumberToObject(r, "max_depth", (double)c->maxdepth);
        cJSON_AddItemToObject(doc, "render", r);
        *out = doc;
    }
    cJSON_Delete(c->mats);
    cJSON_Delete(c->objs);
    cJSON_Delete(c->lights);
    cJSON_Delete(c->media);
    for (int k = 0; k < c->nnobj; k++) cJSON_Delete(c->nobj[k].objs);
    free(c->nobj);
    for (int k = 0; k < c->nfiles; k++) free(c->files[k]);
    free(c);
    return rc;
}

int pbrt_convert_file(const char *path, cJSON **out, json_err *e) { return convert(NULL, path, out, e); }

int pbrt_convert_text(const char *text, const char *name, cJSON **out, json_err *e) {
    return convert(text, name ? name : "(text)", out, e);
}
