/* obj.c: the Wavefront OBJ reader; see obj.h.
 *
 * The file is read into memory once and scanned line by line with hand-written number parsing
 * (strtod for coordinates, a digit loop for indices): no tokenizer allocations, so a million
 * faces cost about as much as reading the bytes. Arrays grow by doubling. Every face is checked
 * when it is read, while the line number is at hand, so a bad face is reported where it is.
 */
#include "load/obj.h"

#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common.h"
#include "scene/shapes.h"

typedef struct parser {
    const char *name;
    long line;
    char *err;
    size_t cap;
    int pcap, tcap, gcap;
} parser;

static int fail(parser *p, int code, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int fail(parser *p, int code, const char *fmt, ...) {
    char msg[256];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (p->line > 0)
        snprintf(p->err, p->cap, "%s:%ld: %s", p->name, p->line, msg);
    else
        snprintf(p->err, p->cap, "%s: %s", p->name, msg);
    return code;
}

/* Make room for one more element of size sz in *arr (count n, capacity *cap). */
static int grow(void **arr, int n, int *cap, size_t sz) {
    if (n < *cap) return 0;
    if (n >= (1 << 30)) return PM_ENOMEM;
    int nc = *cap ? 2 * *cap : 1024;
    void *na = realloc(*arr, (size_t)nc * sz);
    if (!na) return PM_ENOMEM;
    *arr = na;
    *cap = nc;
    return 0;
}

static int is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }

static const char *skip_space(const char *s, const char *end) {
    while (s < end && is_space(*s)) s++;
    return s;
}

/* Three coordinates of a v or vn line (s after the keyword). */
static int read_vec(parser *p, const char *s, const char *end, const char *what, vec3 *out) {
    double c[3];
    for (int k = 0; k < 3; k++) {
        s = skip_space(s, end);
        if (s >= end || *s == '#')
            return fail(p, PM_EINVAL, "%s: expected 3 numbers, got %d", what, k);
        char tmp[64];
        size_t n = 0;
        while (s + n < end && !is_space(s[n]) && n < sizeof tmp - 1) {
            tmp[n] = s[n];
            n++;
        }
        tmp[n] = 0;
        if (s + n < end && !is_space(s[n]))
            return fail(p, PM_EINVAL, "%s: coordinate %d is too long a number", what, k + 1);
        char *e;
        errno = 0;
        c[k] = strtod(tmp, &e);
        if (e == tmp || *e)
            return fail(p, PM_EINVAL, "%s: coordinate %d is not a number: \"%s\"", what, k + 1, tmp);
        if (!isfinite(c[k]))
            return fail(p, PM_EINVAL, "%s: coordinate %d is not finite (%s)", what, k + 1, tmp);
        s += n;
    }
    *out = v3(c[0], c[1], c[2]);
    return 0;
}

/* An index token (1-based or negative) into a list of n items: the 0-based index, or an error. */
static int resolve(parser *p, long v, int n, const char *what, int *out) {
    long i = v > 0 ? v - 1 : v < 0 ? n + v : -1;
    if (v == 0) return fail(p, PM_EINVAL, "%s index 0 (OBJ indices start at 1; negative count back)", what);
    if (i < 0 || i >= n)
        return fail(p, PM_EINVAL, "%s index %ld out of range (%d defined so far)", what, v, n);
    *out = (int)i;
    return 0;
}

/* A signed decimal integer at *s; advances *s. 0 if there is none. */
static int read_long(const char **s, const char *end, long *out) {
    const char *q = *s;
    int neg = 0;
    if (q < end && (*q == '-' || *q == '+')) neg = *q++ == '-';
    if (q >= end || *q < '0' || *q > '9') return 0;
    long v = 0;
    while (q < end && *q >= '0' && *q <= '9') {
        if (v > 100000000000L) v = 100000000000L; /* saturate: out of range anyway */
        v = v * 10 + (*q++ - '0');
    }
    *out = neg ? -v : v;
    *s = q;
    return 1;
}

/* Append triangle (v, n) of group; the arrays tri, tri_group and (once a face had normals)
 * tri_n share the capacity p->tcap. */
static int add_tri(parser *p, mesh_data *m, const int v[3], const int n[3], int group, int any_n) {
    triangle t;
    if (triangle_make(&t, m->pos[v[0]], m->pos[v[1]], m->pos[v[2]], 0) < 0) { /* skipped, counted (mesh.h) */
        if (m->nskipped++ == 0) snprintf(m->first_skip, sizeof m->first_skip, "line %ld", p->line);
        return 0;
    }
    if (m->ntris == p->tcap) {
        if (m->ntris >= (1 << 30)) return fail(p, PM_ERANGE, "too many faces");
        int nc = p->tcap ? 2 * p->tcap : 1024;
        void *a = realloc(m->tri, (size_t)nc * sizeof *m->tri);
        if (a) m->tri = a;
        void *b = a ? realloc(m->tri_group, (size_t)nc * sizeof *m->tri_group) : NULL;
        if (b) m->tri_group = b;
        void *c = b && m->tri_n ? realloc(m->tri_n, (size_t)nc * sizeof *m->tri_n) : b;
        if (c && m->tri_n) m->tri_n = c;
        if (!a || !b || !c) return fail(p, PM_ENOMEM, "out of memory");
        p->tcap = nc;
    }
    if (any_n && !m->tri_n) {
        m->tri_n = malloc((size_t)p->tcap * sizeof *m->tri_n);
        if (!m->tri_n) return fail(p, PM_ENOMEM, "out of memory");
        for (int i = 0; i < m->ntris; i++) m->tri_n[i][0] = m->tri_n[i][1] = m->tri_n[i][2] = -1;
    }
    memcpy(m->tri[m->ntris], v, 3 * sizeof *v);
    if (m->tri_n) memcpy(m->tri_n[m->ntris], n, 3 * sizeof *n);
    m->tri_group[m->ntris] = group;
    m->ntris++;
    return 0;
}

static int parse_face(parser *p, mesh_data *m, const char *s, const char *end, int group,
                      int *any_n) {
    int first[2] = {0, 0}, prev[2] = {0, 0}, k = 0;
    for (;; k++) {
        s = skip_space(s, end);
        if (s >= end || *s == '#') break;
        long vi, ti, ni;
        int has_n = 0;
        if (!read_long(&s, end, &vi))
            return fail(p, PM_EINVAL, "f: corner %d is not an index", k + 1);
        if (s < end && *s == '/') {
            s++;
            if (s < end && *s != '/' && !read_long(&s, end, &ti))
                return fail(p, PM_EINVAL, "f: corner %d: bad texture index", k + 1);
            if (s < end && *s == '/') {
                s++;
                if (!read_long(&s, end, &ni))
                    return fail(p, PM_EINVAL, "f: corner %d: bad normal index", k + 1);
                has_n = 1;
            }
        }
        if (s < end && !is_space(*s) && *s != '#')
            return fail(p, PM_EINVAL, "f: corner %d: unexpected character '%c'", k + 1, *s);
        int cv, cn = -1;
        int rc = resolve(p, vi, m->npos, "vertex", &cv);
        if (rc < 0) return rc;
        if (has_n) {
            rc = resolve(p, ni, m->nnrm, "normal", &cn);
            if (rc < 0) return rc;
            *any_n = 1;
        }
        if (k == 0) {
            first[0] = cv;
            first[1] = cn;
        } else if (k >= 2) {
            int v[3] = {first[0], prev[0], cv}, n[3] = {first[1], prev[1], cn};
            rc = add_tri(p, m, v, n, group, *any_n);
            if (rc < 0) return rc;
        }
        prev[0] = cv;
        prev[1] = cn;
    }
    if (k < 3) return fail(p, PM_EINVAL, "f: a face needs at least 3 corners, got %d", k);
    return 0;
}

int obj_parse(const char *text, size_t len, const char *name, mesh_data *m, char *err, size_t cap) {
    memset(m, 0, sizeof *m);
    parser p = {name, 0, err, cap, 0, 0, 0};
    int ncap_nrm = 0, group = -1, any_n = 0, rc = 0;
    const char *s = text, *end = text + len;
    while (s < end && rc == 0) {
        p.line++;
        const char *eol = memchr(s, '\n', (size_t)(end - s));
        if (!eol) eol = end;
        const char *q = skip_space(s, eol);
        const char *kw = q;
        while (q < eol && !is_space(*q)) q++;
        size_t kl = (size_t)(q - kw);
        if (kl == 0 || kw[0] == '#') {
            /* blank or comment */
        } else if (kl == 1 && kw[0] == 'v') {
            if (grow((void **)&m->pos, m->npos, &p.pcap, sizeof *m->pos) < 0) {
                rc = fail(&p, PM_ENOMEM, "out of memory");
                break;
            }
            rc = read_vec(&p, q, eol, "v", &m->pos[m->npos]);
            if (rc == 0) m->npos++;
        } else if (kl == 2 && kw[0] == 'v' && kw[1] == 'n') {
            if (grow((void **)&m->nrm, m->nnrm, &ncap_nrm, sizeof *m->nrm) < 0) {
                rc = fail(&p, PM_ENOMEM, "out of memory");
                break;
            }
            rc = read_vec(&p, q, eol, "vn", &m->nrm[m->nnrm]);
            if (rc == 0 && v3_iszero(m->nrm[m->nnrm])) rc = fail(&p, PM_EINVAL, "vn: zero normal");
            if (rc == 0) m->nnrm++;
        } else if (kl == 1 && kw[0] == 'f') {
            rc = parse_face(&p, m, q, eol, group, &any_n);
        } else if (kl == 6 && memcmp(kw, "usemtl", 6) == 0) {
            const char *a = skip_space(q, eol), *b = eol;
            while (b > a && is_space(b[-1])) b--;
            if (a == b) {
                rc = fail(&p, PM_EINVAL, "usemtl: missing material name");
                break;
            }
            group = -1;
            for (int g = 0; g < m->ngroups; g++)
                if (strlen(m->groups[g]) == (size_t)(b - a) && memcmp(m->groups[g], a, (size_t)(b - a)) == 0)
                    group = g;
            if (group < 0) {
                char *nm = malloc((size_t)(b - a) + 1);
                if (!nm || grow((void **)&m->groups, m->ngroups, &p.gcap, sizeof *m->groups) < 0) {
                    free(nm);
                    rc = fail(&p, PM_ENOMEM, "out of memory");
                    break;
                }
                memcpy(nm, a, (size_t)(b - a));
                nm[b - a] = 0;
                group = m->ngroups;
                m->groups[m->ngroups++] = nm;
            }
        } else if ((kl == 2 && memcmp(kw, "vt", 2) == 0) || (kl == 6 && memcmp(kw, "mtllib", 6) == 0) ||
                   (kl == 1 && (kw[0] == 'o' || kw[0] == 'g' || kw[0] == 's'))) {
            /* no effect on this renderer's image (obj.h) */
        } else {
            rc = fail(&p, PM_EINVAL, "unsupported statement \"%.*s\" (read: v, vn, f, usemtl; "
                      "skipped: vt, mtllib, o, g, s)", (int)(kl < 40 ? kl : 40), kw);
        }
        s = eol < end ? eol + 1 : end;
    }
    if (rc == 0 && m->ntris == 0) {
        p.line = 0;
        rc = m->nskipped ? fail(&p, PM_EINVAL, "empty mesh: all %ld faces are degenerate (zero area; the first "
                                "at %s)", m->nskipped, m->first_skip)
                         : fail(&p, PM_EINVAL, "empty mesh: no face (f) in the file");
    }
    if (rc < 0) mesh_free(m);
    return rc;
}
