/* pbrt_lex.c: the pbrt converter's tokens and parameter lists (pbrt_internal.h): a file cut
 * into tokens (quoted strings, numbers, bare words, [ and ]), each with its file and line; a
 * directive's parameters parsed into a list, looked up by name with their type checked; and the
 * messages that name the file and line.
 */
#define _XOPEN_SOURCE 700
#include "load/pbrt_internal.h"

#include <ctype.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- tokens ----------------------------------------------------------------------- */

const char *pb_file(const conv *c, const tok *t) { return c->files[t->file]; }

int pb_fail(conv *c, const tok *t, int code, const char *fmt, ...) {
    char msg[400];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (t)
        return json_fail(c->e, code, "%s:%d: %s", pb_file(c, t), t->line, msg);
    return json_fail(c->e, code, "%s", msg);
}

void pb_warn(const conv *c, const tok *t, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "render: %s:%d: warning: ", pb_file(c, t), t->line);
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

void pb_toks_free(toks *ts) {
    for (int i = 0; i < ts->n; i++) free(ts->t[i].s);
    free(ts->t);
    memset(ts, 0, sizeof *ts);
}

/* Cut text into tokens; file is the index of its name. */
int pb_lex(conv *c, const char *text, int file, toks *ts) {
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
                    return pb_fail(c, &t, PM_EINVAL, "unterminated string (a \" without its closing \" on the line)");
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

/* ---- parameters ------------------------------------------------------------------- */

void pb_plist_free(plist *pl) {
    for (int i = 0; i < pl->n; i++) {
        free(pl->p[i].num);
        free(pl->p[i].str); /* the strings belong to the tokens */
    }
    pl->n = 0;
}

/* Parameters from *i on: "type name" value, where value is [ ... ] or one number/string/word. */
int pb_read_params(conv *c, const toks *ts, int *i, plist *pl) {
    pl->n = 0;
    while (*i < ts->n && ts->t[*i].kind == K_STR) {
        const tok *t = &ts->t[*i];
        char ty[16], nm[64], extra[8];
        int k = sscanf(t->s, "%15s %63s %7s", ty, nm, extra);
        if (k != 2) return pb_fail(c, t, PM_EINVAL, "expected a parameter \"TYPE NAME\", got \"%.60s\"", t->s);
        if (pl->n == 64) return pb_fail(c, t, PM_EINVAL, "more than 64 parameters");
        pparam *p = &pl->p[pl->n];
        memset(p, 0, sizeof *p);
        snprintf(p->type, sizeof p->type, "%s", ty);
        snprintf(p->name, sizeof p->name, "%s", nm);
        (*i)++;
        int lo = *i, hi, bracket = *i < ts->n && ts->t[*i].kind == K_LB;
        if (bracket) {
            lo = ++(*i);
            while (*i < ts->n && ts->t[*i].kind != K_RB) {
                if (ts->t[*i].kind == K_LB) return pb_fail(c, &ts->t[*i], PM_EINVAL, "a [ inside a parameter's [ ]");
                (*i)++;
            }
            if (*i >= ts->n) return pb_fail(c, t, PM_EINVAL, "parameter \"%s\": unbalanced [ (no closing ])", t->s);
            hi = (*i)++;
        } else {
            const tok *u = *i < ts->n ? &ts->t[*i] : NULL;
            if (!u || u->kind == K_RB || u->kind == K_LB ||
                (u->kind == K_WORD && strcmp(u->s, "true") != 0 && strcmp(u->s, "false") != 0))
                return pb_fail(c, t, PM_EINVAL, "parameter \"%s\" has no value", t->s);
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
            return pb_fail(c, t, PM_EINVAL, "parameter \"%s\": numbers and strings mixed in one value", t->s);
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
int pb_get(conv *c, const tok *at, plist *pl, const char *name, const char *types, pparam **out) {
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
            return pb_fail(c, at, PM_EINVAL, "parameter \"%s %s\": the type should be %s", p->type, p->name, types);
        p->used = 1;
        int want_str = strcmp(p->type, "string") == 0 || strcmp(p->type, "texture") == 0 || strcmp(p->type, "bool") == 0 ||
                       (strcmp(p->type, "spectrum") == 0 && p->is_str);
        if (p->n > 0 && want_str != p->is_str)
            return pb_fail(c, at, PM_EINVAL, "parameter \"%s %s\": expected %s", p->type, p->name,
                         want_str ? "a string" : "numbers");
        *out = p;
        return 0;
    }
    return 0;
}

int pb_get_floats(conv *c, const tok *at, plist *pl, const char *name, const char *types, int n, double *v) {
    pparam *p;
    TRY(pb_get(c, at, pl, name, types, &p));
    if (!p) return 0;
    if (p->n != n) return pb_fail(c, at, PM_EINVAL, "parameter \"%s %s\": expected %d value%s, got %d", p->type, name, n,
                                n == 1 ? "" : "s", p->n);
    for (int i = 0; i < n; i++) {
        if (!isfinite(p->num[i])) return pb_fail(c, at, PM_EINVAL, "parameter \"%s %s\": value %d is not finite", p->type, name, i + 1);
        v[i] = p->num[i];
    }
    return 1;
}

int pb_get_string(conv *c, const tok *at, plist *pl, const char *name, const char **s) {
    pparam *p;
    TRY(pb_get(c, at, pl, name, "string", &p));
    if (!p) return 0;
    if (p->n != 1) return pb_fail(c, at, PM_EINVAL, "parameter \"string %s\": expected one string, got %d", name, p->n);
    *s = p->str[0];
    return 1;
}

int pb_get_bool(conv *c, const tok *at, plist *pl, const char *name, int *b) {
    pparam *p;
    TRY(pb_get(c, at, pl, name, "bool", &p));
    if (!p) return 0;
    if (p->n != 1 || (strcmp(p->str[0], "true") != 0 && strcmp(p->str[0], "false") != 0))
        return pb_fail(c, at, PM_EINVAL, "parameter \"bool %s\": expected \"true\" or \"false\"", name);
    *b = strcmp(p->str[0], "true") == 0;
    return 1;
}

/* A colour: rgb (3 numbers), spectrum (wavelength-value pairs: their mean, a warning),
 * blackbody (warned: grey of its scale); a texture is warned about and leaves *v. */
int pb_get_color(conv *c, const tok *at, plist *pl, const char *name, rgb *v) {
    pparam *p;
    TRY(pb_get(c, at, pl, name, "rgb|spectrum|blackbody|texture|float", &p));
    if (!p) return 0;
    if (strcmp(p->type, "texture") == 0) {
        pb_warn(c, at, "parameter \"texture %s\": textures are not supported: the default value is used", name);
        return 0;
    }
    for (int i = 0; i < p->n; i++)
        if (!p->is_str && !isfinite(p->num[i]))
            return pb_fail(c, at, PM_EINVAL, "parameter \"%s %s\": value %d is not finite", p->type, name, i + 1);
    if (strcmp(p->type, "rgb") == 0 || strcmp(p->type, "color") == 0) {
        if (p->n != 3) return pb_fail(c, at, PM_EINVAL, "parameter \"%s %s\": expected 3 values, got %d", p->type, name, p->n);
        *v = v3(p->num[0], p->num[1], p->num[2]);
    } else if (strcmp(p->type, "float") == 0) {
        if (p->n != 1) return pb_fail(c, at, PM_EINVAL, "parameter \"float %s\": expected 1 value, got %d", name, p->n);
        *v = v3s(p->num[0]);
    } else if (strcmp(p->type, "spectrum") == 0 && !p->is_str && p->n >= 2 && p->n % 2 == 0) {
        double s = 0;
        for (int i = 1; i < p->n; i += 2) s += p->num[i];
        *v = v3s(s / (p->n / 2));
        pb_warn(c, at, "parameter \"spectrum %s\": a spectrum becomes the grey of its mean value, %g", name, v->x);
    } else if (strcmp(p->type, "blackbody") == 0 && p->n >= 1) {
        double scale = p->n >= 2 ? p->num[1] : 1;
        *v = v3s(scale);
        pb_warn(c, at, "parameter \"blackbody %s\": a blackbody of %g K becomes a grey of its scale, %g", name, p->num[0], scale);
    } else {
        return pb_fail(c, at, PM_EINVAL, "parameter \"%s %s\": not a colour this converter reads (rgb, spectrum pairs, "
                     "blackbody)", p->type, name);
    }
    return 1;
}

/* Warn about every parameter nobody asked for. */
void pb_warn_unused(const conv *c, const tok *at, const char *what, const plist *pl) {
    for (int i = 0; i < pl->n; i++)
        if (!pl->p[i].used)
            pb_warn(c, at, "%s: parameter \"%s %s\" is not supported: ignored", what, pl->p[i].type, pl->p[i].name);
}

int pb_nums(conv *c, const toks *ts, int *i, const tok *at, int n, double *v, const char *what) {
    int br = *i < ts->n && ts->t[*i].kind == K_LB;
    if (br) (*i)++;
    for (int k = 0; k < n; k++, (*i)++) {
        if (*i >= ts->n || ts->t[*i].kind != K_NUM)
            return pb_fail(c, at, PM_EINVAL, "%s: expected %d numbers, got %d", what, n, k);
        v[k] = ts->t[*i].num;
        if (!isfinite(v[k])) return pb_fail(c, at, PM_EINVAL, "%s: number %d is not finite", what, k + 1);
    }
    if (br) {
        if (*i >= ts->n || ts->t[*i].kind != K_RB) return pb_fail(c, at, PM_EINVAL, "%s: unbalanced [ (no closing ] after %d numbers)", what, n);
        (*i)++;
    }
    return 0;
}

int pb_one_string(conv *c, const toks *ts, int *i, const tok *at, const char **s, const char *what) {
    if (*i >= ts->n || ts->t[*i].kind != K_STR) return pb_fail(c, at, PM_EINVAL, "%s: expected a quoted name", what);
    *s = ts->t[(*i)++].s;
    return 0;
}
