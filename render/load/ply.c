/* ply.c: the PLY reader; see ply.h.
 *
 * The header is read line by line into a small table of elements and their properties. Before
 * anything is allocated the counts are checked against the bytes left (each binary element
 * needs at least the sum of its scalar sizes and list counts, each ASCII value at least one
 * character and a separator), so a lying header fails at once with its numbers. The data is
 * then read element by element through one value reader that either decodes binary bytes
 * (memcpy, byte swap when the file's order is not the machine's) or scans an ASCII token
 * (strtod), and keeps the line or byte offset for messages. Faces are fanned into triangles as
 * they are read, with their face number; vertex indices are checked against the header's
 * vertex count at once, degeneracy (which needs the positions, and PLY allows faces before
 * vertices) in one pass at the end.
 */
#include "load/ply.h"

#include <errno.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common.h"
#include "scene/shapes.h"

enum { T_NONE, T_I8, T_U8, T_I16, T_U16, T_I32, T_U32, T_F32, T_F64 };
static const int k_tsize[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};

#define PLY_MAX_ELEMS 16
#define PLY_MAX_PROPS 64
#define PLY_MAX_VERTICES (1 << 30)

typedef struct pprop {
    char name[32];
    int type;       /* the scalar type, or a list's item type */
    int count_type; /* a list's count type; T_NONE for a scalar */
} pprop;

typedef struct pelem {
    char name[32];
    unsigned long long count;
    pprop props[PLY_MAX_PROPS];
    int nprops;
} pelem;

typedef struct rd {
    const char *buf;
    size_t len, pos;
    int ascii, swap;
    long line; /* ASCII: the line of pos */
    const char *name;
    char *err;
    size_t cap;
} rd;

static int fail_at(const rd *r, size_t off, long line, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
static int fail_at(const rd *r, size_t off, long line, const char *fmt, ...) {
    char msg[300];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    if (line > 0)
        snprintf(r->err, r->cap, "%s:%ld: %s", r->name, line, msg);
    else if (off == (size_t)-1) /* the whole file */
        snprintf(r->err, r->cap, "%s: %s", r->name, msg);
    else
        snprintf(r->err, r->cap, "%s: byte %zu: %s", r->name, off, msg);
    return PM_EINVAL;
}

/* Where r is now: the line for ASCII data, else the byte offset. */
#define HERE(r) (r)->pos, ((r)->ascii ? (r)->line : 0)

static int type_of(const char *s) {
    static const struct {
        const char *n;
        int t;
    } names[] = {{"char", T_I8},   {"int8", T_I8},    {"uchar", T_U8},   {"uint8", T_U8},    {"short", T_I16},
                 {"int16", T_I16}, {"ushort", T_U16}, {"uint16", T_U16}, {"int", T_I32},     {"int32", T_I32},
                 {"uint", T_U32},  {"uint32", T_U32}, {"float", T_F32},  {"float32", T_F32}, {"double", T_F64},
                 {"float64", T_F64}};
    for (size_t i = 0; i < sizeof names / sizeof *names; i++)
        if (strcmp(s, names[i].n) == 0) return names[i].t;
    return T_NONE;
}

static int is_int_type(int t) { return t != T_NONE && t != T_F32 && t != T_F64; }

/* One value of type t at r->pos; advances. elem/index name the place in messages. */
static int read_value(rd *r, int t, const pelem *el, unsigned long long index, double *out) {
    if (!r->ascii) {
        size_t n = (size_t)k_tsize[t];
        if (r->len - r->pos < n)
            return fail_at(r, r->pos, 0, "truncated: the data ends inside %s %llu (the header says %llu)", el->name,
                           index, el->count);
        unsigned char b[8];
        memcpy(b, r->buf + r->pos, n);
        if (r->swap)
            for (size_t i = 0; i < n / 2; i++) {
                unsigned char c = b[i];
                b[i] = b[n - 1 - i];
                b[n - 1 - i] = c;
            }
        r->pos += n;
        switch (t) {
        case T_I8: { int8_t v; memcpy(&v, b, 1); *out = v; break; }
        case T_U8: *out = b[0]; break;
        case T_I16: { int16_t v; memcpy(&v, b, 2); *out = v; break; }
        case T_U16: { uint16_t v; memcpy(&v, b, 2); *out = v; break; }
        case T_I32: { int32_t v; memcpy(&v, b, 4); *out = v; break; }
        case T_U32: { uint32_t v; memcpy(&v, b, 4); *out = v; break; }
        case T_F32: { float v; memcpy(&v, b, 4); *out = v; break; }
        default: { double v; memcpy(&v, b, 8); *out = v; break; }
        }
        return 0;
    }
    const char *s = r->buf + r->pos, *end = r->buf + r->len;
    for (; s < end && (*s == ' ' || *s == '\t' || *s == '\r' || *s == '\n' || *s == '\f' || *s == '\v'); s++)
        if (*s == '\n') r->line++;
    r->pos = (size_t)(s - r->buf);
    if (s >= end)
        return fail_at(r, r->pos, r->line, "truncated: the data ends inside %s %llu (the header says %llu)", el->name,
                       index, el->count);
    if (is_int_type(t)) { /* counts and indices, most of a face list: digits, exactly, without strtod */
        const char *q = s + (*s == '-' || *s == '+');
        long long v = 0;
        int nd = 0;
        while (q < end && *q >= '0' && *q <= '9' && nd < 15) v = 10 * v + (*q++ - '0'), nd++;
        if (nd > 0 && (q == end || *q == ' ' || *q == '\t' || *q == '\r' || *q == '\n')) {
            *out = (double)(*s == '-' ? -v : v);
            r->pos = (size_t)(q - r->buf);
            return 0;
        } /* anything else (a sign alone, a decimal point, letters): strtod says what it is */
    }
    char *e;
    double v = strtod(s, &e);
    size_t tl = 0;
    while (s + tl < end && !(s[tl] == ' ' || s[tl] == '\t' || s[tl] == '\r' || s[tl] == '\n')) tl++;
    if (e == s || e != s + tl)
        return fail_at(r, r->pos, r->line, "%s %llu: \"%.*s\" is not a number", el->name, index,
                       (int)(tl > 40 ? 40 : tl), s);
    if (is_int_type(t) && !(v == floor(v)))
        return fail_at(r, r->pos, r->line, "%s %llu: \"%.*s\" is not an integer (the header's type is an integer)",
                       el->name, index, (int)(tl > 40 ? 40 : tl), s);
    r->pos += tl;
    *out = v;
    return 0;
}

/* The triangles read so far, before the degeneracy pass. */
typedef struct tris {
    int (*v)[3];
    int *face; /* the face (or strip element) each came from, for first_skip */
    int n, cap;
} tris;

static int tris_add(tris *t, int a, int b, int c, int face) {
    if (t->n == t->cap) {
        if (t->n >= (1 << 30)) return PM_ENOMEM;
        int nc = t->cap ? 2 * t->cap : 1024;
        void *x = realloc(t->v, (size_t)nc * sizeof *t->v);
        if (x) t->v = x;
        void *y = x ? realloc(t->face, (size_t)nc * sizeof *t->face) : NULL;
        if (y) t->face = y;
        if (!x || !y) return PM_ENOMEM;
        t->cap = nc;
    }
    t->v[t->n][0] = a;
    t->v[t->n][1] = b;
    t->v[t->n][2] = c;
    t->face[t->n] = face;
    t->n++;
    return 0;
}

/* Split a header line into up to 8 words (in place). */
static int words(char *line, char *w[8]) {
    int n = 0;
    for (char *s = line; *s && n < 8;) {
        while (*s == ' ' || *s == '\t') s++;
        if (!*s) break;
        w[n++] = s;
        while (*s && *s != ' ' && *s != '\t') s++;
        if (*s) *s++ = 0;
    }
    return n;
}

static int parse_header(rd *r, pelem *els, int *nels) {
    const char *b = r->buf, *end = r->buf + r->len;
    if (r->len < 4 || memcmp(b, "ply", 3) != 0 || (b[3] != '\n' && b[3] != '\r'))
        return fail_at(r, 0, 0, "not a PLY file (it must start with the line \"ply\")");
    int have_format = 0;
    *nels = 0;
    size_t pos = 0;
    for (;;) {
        const char *s = b + pos;
        if (s >= end) return fail_at(r, pos, 0, "truncated header: no end_header line");
        const char *eol = memchr(s, '\n', (size_t)(end - s));
        if (!eol) return fail_at(r, pos, 0, "truncated header: no end_header line");
        size_t ll = (size_t)(eol - s);
        if (ll > 0 && s[ll - 1] == '\r') ll--;
        size_t here = pos;
        pos = (size_t)(eol - b) + 1;
        r->line++;
        if (r->line == 1) continue; /* "ply" */
        if ((ll >= 7 && memcmp(s, "comment", 7) == 0 && (ll == 7 || s[7] == ' ' || s[7] == '\t')) ||
            (ll >= 8 && memcmp(s, "obj_info", 8) == 0))
            continue;
        char line[256], *w[8];
        if (ll >= sizeof line) return fail_at(r, here, 0, "header line %ld is too long", r->line);
        memcpy(line, s, ll);
        line[ll] = 0;
        int n = words(line, w);
        if (n == 0) continue;
        if (strcmp(w[0], "end_header") == 0) {
            r->pos = pos;
            break;
        } else if (strcmp(w[0], "format") == 0) {
            if (n != 3 || strcmp(w[2], "1.0") != 0)
                return fail_at(r, here, 0, "header line %ld: expected \"format ascii|binary_little_endian|"
                               "binary_big_endian 1.0\"", r->line);
            uint16_t one = 1;
            unsigned char lo;
            memcpy(&lo, &one, 1);
            if (strcmp(w[1], "ascii") == 0) {
                r->ascii = 1;
            } else if (strcmp(w[1], "binary_little_endian") == 0) {
                r->swap = lo != 1;
            } else if (strcmp(w[1], "binary_big_endian") == 0) {
                r->swap = lo == 1;
            } else {
                return fail_at(r, here, 0, "header line %ld: unknown format \"%s\" (ascii, binary_little_endian, "
                               "binary_big_endian)", r->line, w[1]);
            }
            have_format = 1;
        } else if (strcmp(w[0], "element") == 0) {
            if (n != 3) return fail_at(r, here, 0, "header line %ld: expected \"element NAME COUNT\"", r->line);
            if (*nels == PLY_MAX_ELEMS) return fail_at(r, here, 0, "more than %d elements", PLY_MAX_ELEMS);
            char *e;
            errno = 0;
            unsigned long long c = strtoull(w[2], &e, 10);
            if (e == w[2] || *e || w[2][0] == '-' || errno)
                return fail_at(r, here, 0, "header line %ld: element %s: the count \"%s\" is not a whole number",
                               r->line, w[1], w[2]);
            pelem *el = &els[(*nels)++];
            memset(el, 0, sizeof *el);
            snprintf(el->name, sizeof el->name, "%s", w[1]);
            el->count = c;
        } else if (strcmp(w[0], "property") == 0) {
            if (*nels == 0) return fail_at(r, here, 0, "header line %ld: a property before any element", r->line);
            pelem *el = &els[*nels - 1];
            if (el->nprops == PLY_MAX_PROPS)
                return fail_at(r, here, 0, "element %s: more than %d properties", el->name, PLY_MAX_PROPS);
            pprop *p = &el->props[el->nprops];
            memset(p, 0, sizeof *p);
            if (n == 5 && strcmp(w[1], "list") == 0) {
                p->count_type = type_of(w[2]);
                p->type = type_of(w[3]);
                if (!is_int_type(p->count_type))
                    return fail_at(r, here, 0, "header line %ld: a list's count type must be an integer type, got "
                                   "\"%s\"", r->line, w[2]);
                if (p->type == T_NONE)
                    return fail_at(r, here, 0, "header line %ld: unknown type \"%s\"", r->line, w[3]);
                snprintf(p->name, sizeof p->name, "%s", w[4]);
            } else if (n == 3) {
                p->type = type_of(w[1]);
                if (p->type == T_NONE) return fail_at(r, here, 0, "header line %ld: unknown type \"%s\"", r->line, w[1]);
                snprintf(p->name, sizeof p->name, "%s", w[2]);
            } else {
                return fail_at(r, here, 0, "header line %ld: expected \"property TYPE NAME\" or \"property list "
                               "COUNT_TYPE ITEM_TYPE NAME\"", r->line);
            }
            el->nprops++;
        } else {
            return fail_at(r, here, 0, "header line %ld: unknown keyword \"%.40s\"", r->line, w[0]);
        }
    }
    if (!have_format) return fail_at(r, 0, 0, "the header has no format line");
    return 0;
}

static int find_prop(const pelem *el, const char *name, int list) {
    for (int i = 0; i < el->nprops; i++)
        if (strcmp(el->props[i].name, name) == 0 && (el->props[i].count_type != T_NONE) == list) return i;
    return -1;
}

/* The vertex element of the header and where its coordinates and normals are. */
typedef struct vlayout {
    const pelem *ve;
    int ix, iy, iz, inx, iny, inz, has_n;
} vlayout;

/* The state of reading the data: the triangles so far, one list's corners, the face number. */
typedef struct reader {
    rd r;
    vlayout vl;
    int nv;
    tris t;
    int *corner, ccap, face;
} reader;

/* ---- the header's elements --------------------------------------------------------------- */

static int find_vertex(rd *r, const pelem *els, int nels, vlayout *vl) {
    const pelem *ve = NULL;
    for (int i = 0; i < nels; i++)
        if (strcmp(els[i].name, "vertex") == 0) {
            if (ve) return fail_at(r, 0, 0, "two vertex elements");
            ve = &els[i];
        }
    if (!ve) return fail_at(r, 0, 0, "no vertex element in the header");
    vl->ve = ve;
    vl->ix = find_prop(ve, "x", 0), vl->iy = find_prop(ve, "y", 0), vl->iz = find_prop(ve, "z", 0);
    if (vl->ix < 0 || vl->iy < 0 || vl->iz < 0) return fail_at(r, 0, 0, "the vertex element has no x, y or z property");
    vl->inx = find_prop(ve, "nx", 0), vl->iny = find_prop(ve, "ny", 0), vl->inz = find_prop(ve, "nz", 0);
    vl->has_n = vl->inx >= 0 && vl->iny >= 0 && vl->inz >= 0;
    if (ve->count > PLY_MAX_VERTICES)
        return fail_at(r, 0, 0, "%llu vertices: more than this renderer's %d", ve->count, PLY_MAX_VERTICES);
    return 0;
}

/* Counts against the bytes left (a lying header fails here, before any allocation). */
static int check_counts(rd *r, const pelem *els, int nels) {
    double need = 0, nvals = 0;
    for (int i = 0; i < nels; i++) {
        double per = 0;
        for (int k = 0; k < els[i].nprops; k++)
            per += k_tsize[els[i].props[k].count_type != T_NONE ? els[i].props[k].count_type : els[i].props[k].type];
        need += (double)els[i].count * per;
        nvals += (double)els[i].count * els[i].nprops;
    }
    if (r->ascii) need = 2 * nvals - 1;
    if (need > (double)(r->len - r->pos))
        return fail_at(r, r->pos, 0, "truncated, or the header's counts are wrong: its elements need at least %.0f "
                       "bytes of %s data, the file has %zu after the header", need, r->ascii ? "ASCII" : "binary",
                       r->len - r->pos);
    return 0;
}

/* The vertex list of a face or tristrips element (*ilist -1 for other elements). */
static int find_list(rd *r, const pelem *el, int is_f, int is_s, int *ilist) {
    *ilist = -1;
    if (is_f) {
        *ilist = find_prop(el, "vertex_indices", 1);
        if (*ilist < 0) *ilist = find_prop(el, "vertex_index", 1);
        if (*ilist < 0) return fail_at(r, 0, 0, "the face element has no list vertex_indices (or vertex_index)");
    } else if (is_s) {
        *ilist = find_prop(el, "vertex_indices", 1);
        if (*ilist < 0) return fail_at(r, 0, 0, "the tristrips element has no list vertex_indices");
    }
    if (*ilist >= 0 && !is_int_type(el->props[*ilist].type))
        return fail_at(r, 0, 0, "element %s: vertex indices must have an integer type", el->name);
    return 0;
}

/* ---- faces and strips to triangles -------------------------------------------------------- */

/* A face's nc corners fanned into triangles. */
static int add_face(tris *t, const int *corner, int nc, int face) {
    for (int j = 2; j < nc; j++)
        if (tris_add(t, corner[0], corner[j - 1], corner[j], face) < 0) return PM_ENOMEM;
    return 0;
}

/* A triangle strip: restart at -1, alternate the winding. */
static int add_strip(tris *t, const int *corner, int nc, int face) {
    int run = 0;
    for (int j = 0; j < nc; j++) {
        if (corner[j] < 0) {
            run = 0;
            continue;
        }
        if (++run < 3) continue;
        int a = corner[j - 2], b = corner[j - 1], c = corner[j];
        if (a == b || b == c || a == c) continue; /* a stitch between strips */
        if (run % 2 == 0 && tris_add(t, b, a, c, face) < 0) return PM_ENOMEM;
        if (run % 2 == 1 && tris_add(t, a, b, c, face) < 0) return PM_ENOMEM;
    }
    return 0;
}

/* ---- the data ----------------------------------------------------------------------------- */

/* List property p of item i of el, whose count starts at byte `at`; use: it is the vertex list
 * of a face (is_f) or strip, whose triangles are added. */
static int read_list(reader *x, const pelem *el, const pprop *p, unsigned long long i, int use, int is_f, size_t at) {
    rd *r = &x->r;
    double cnt, v;
    int rc = read_value(r, p->count_type, el, i, &cnt);
    if (rc < 0) return rc;
    long at_line = r->line; /* the count's own line (ASCII) */
    /* a list's length against the bytes left before anything is stored */
    double left = (double)(r->len - r->pos), per = r->ascii ? 2 : k_tsize[p->type];
    if (cnt < 0 || cnt * per > left + 1)
        return fail_at(r, at, r->ascii ? at_line : 0, "%s %llu: a list of %.0f items, %s", el->name, i, cnt,
                       cnt < 0 ? "a negative count" : "more than the bytes left hold (truncated?)");
    int nc = (int)cnt;
    if (use && nc > x->ccap) {
        int *c2 = realloc(x->corner, (size_t)nc * sizeof *x->corner);
        if (!c2) {
            snprintf(r->err, r->cap, "%s: out of memory", r->name);
            return PM_ENOMEM;
        }
        x->corner = c2;
        x->ccap = nc;
    }
    for (int j = 0; j < nc && rc == 0; j++) {
        size_t vat = r->pos;
        rc = read_value(r, p->type, el, i, &v);
        if (rc < 0 || !use) continue;
        if (r->ascii) vat = r->pos; /* the line is what matters */
        if (!is_f && v == -1) {
            x->corner[j] = -1; /* a strip restart */
        } else if (!(v >= 0 && v < x->nv)) {
            rc = fail_at(r, vat, r->ascii ? r->line : 0, "%s %llu: vertex index %.0f out of range (%d vertices)",
                         el->name, i, v, x->nv);
        } else {
            x->corner[j] = (int)v;
        }
    }
    if (rc < 0 || !use) return rc;
    if (is_f && nc < 3)
        return fail_at(r, at, r->ascii ? at_line : 0, "face %llu: a face needs at least 3 corners, got %d", i, nc);
    rc = is_f ? add_face(&x->t, x->corner, nc, x->face) : add_strip(&x->t, x->corner, nc, x->face);
    if (rc == PM_ENOMEM) snprintf(r->err, r->cap, "%s: out of memory", r->name);
    return rc;
}

/* Item i of element el: its scalars (a vertex's position and normal kept) and lists. */
static int read_item(reader *x, const pelem *el, unsigned long long i, int is_f, int ilist, mesh_data *m) {
    rd *r = &x->r;
    const vlayout *vl = &x->vl;
    int is_v = el == vl->ve, rc = 0;
    double xyz[3] = {0, 0, 0}, nrm[3] = {0, 0, 0};
    for (int k = 0; k < el->nprops && rc == 0; k++) {
        const pprop *p = &el->props[k];
        double v;
        size_t at = r->pos;
        if (p->count_type != T_NONE) {
            rc = read_list(x, el, p, i, k == ilist, is_f, at);
            continue;
        }
        rc = read_value(r, p->type, el, i, &v);
        if (rc < 0 || !is_v) continue;
        if (!isfinite(v) && (k == vl->ix || k == vl->iy || k == vl->iz ||
                             (vl->has_n && (k == vl->inx || k == vl->iny || k == vl->inz))))
            return fail_at(r, at, r->ascii ? r->line : 0, "vertex %llu: %s is not finite", i, p->name);
        if (k == vl->ix) xyz[0] = v;
        else if (k == vl->iy) xyz[1] = v;
        else if (k == vl->iz) xyz[2] = v;
        else if (k == vl->inx) nrm[0] = v;
        else if (k == vl->iny) nrm[1] = v;
        else if (k == vl->inz) nrm[2] = v;
    }
    if (rc < 0) return rc;
    if (is_v) {
        m->pos[i] = v3(xyz[0], xyz[1], xyz[2]);
        if (vl->has_n) m->nrm[i] = v3(nrm[0], nrm[1], nrm[2]);
    }
    return 0;
}

/* Every element's items in order, then nothing but (ASCII) white space after the last. */
static int read_elements(reader *x, const pelem *els, int nels, mesh_data *m) {
    rd *r = &x->r;
    r->line++; /* the first data line follows end_header */
    for (int ei = 0; ei < nels; ei++) {
        const pelem *el = &els[ei];
        int is_f = strcmp(el->name, "face") == 0, is_s = strcmp(el->name, "tristrips") == 0, ilist;
        int rc = find_list(r, el, is_f, is_s, &ilist);
        if (rc < 0) return rc;
        for (unsigned long long i = 0; i < el->count; i++) {
            if ((rc = read_item(x, el, i, is_f, ilist, m)) < 0) return rc;
            if (is_f || is_s) x->face++;
        }
    }
    size_t p = r->pos; /* what follows the last element */
    if (r->ascii)
        while (p < r->len && (r->buf[p] == ' ' || r->buf[p] == '\t' || r->buf[p] == '\r' || r->buf[p] == '\n')) p++;
    if (p < r->len)
        return fail_at(r, p, 0, "%zu bytes after the last element (the header's counts are wrong, or not a PLY "
                       "file)", r->len - p);
    return 0;
}

/* The triangles with an area become the mesh's (degenerate faces: skipped and counted,
 * mesh.h), with the vertex normals of the file where it has them. */
static int finish_mesh(reader *x, mesh_data *m) {
    rd *r = &x->r;
    tris *t = &x->t;
    int out = 0, rc = 0;
    for (int k = 0; k < t->n; k++) {
        const int *v = t->v[k];
        triangle tr;
        if (triangle_make(&tr, m->pos[v[0]], m->pos[v[1]], m->pos[v[2]], 0) < 0) {
            if (m->nskipped++ == 0) snprintf(m->first_skip, sizeof m->first_skip, "face %d", t->face[k]);
            continue;
        }
        memmove(t->v[out++], v, sizeof t->v[0]);
    }
    if (out == 0)
        return m->nskipped ? fail_at(r, (size_t)-1, 0, "empty mesh: all %ld faces are degenerate (zero area; the first at %s)",
                                     m->nskipped, m->first_skip)
                           : fail_at(r, (size_t)-1, 0, "empty mesh: no face");
    m->tri = t->v;
    t->v = NULL;
    m->ntris = out;
    m->tri_group = malloc((size_t)out * sizeof *m->tri_group);
    if (x->vl.has_n) m->tri_n = malloc((size_t)out * sizeof *m->tri_n);
    if (!m->tri_group || (x->vl.has_n && !m->tri_n)) {
        rc = PM_ENOMEM;
        snprintf(r->err, r->cap, "%s: out of memory", r->name);
    } else {
        for (int k = 0; k < out; k++) {
            m->tri_group[k] = -1;
            if (x->vl.has_n) /* a zero normal cannot shade: left to mesh_smooth_normals */
                for (int c = 0; c < 3; c++) m->tri_n[k][c] = v3_iszero(m->nrm[m->tri[k][c]]) ? -1 : m->tri[k][c];
        }
    }
    return rc;
}

int ply_parse(const char *buf, size_t len, const char *name, mesh_data *m, char *err, size_t cap) {
    memset(m, 0, sizeof *m);
    reader x;
    memset(&x, 0, sizeof x);
    x.r = (rd){buf, len, 0, 0, 0, 0, name, err, cap};
    pelem els[PLY_MAX_ELEMS];
    int nels = 0, rc = parse_header(&x.r, els, &nels);
    if (rc == 0) rc = find_vertex(&x.r, els, nels, &x.vl);
    if (rc == 0) rc = check_counts(&x.r, els, nels);
    if (rc < 0) return rc;
    int nv = x.nv = (int)x.vl.ve->count;
    m->npos = nv;
    m->pos = malloc((size_t)(nv ? nv : 1) * sizeof *m->pos);
    if (x.vl.has_n) {
        m->nnrm = nv;
        m->nrm = malloc((size_t)(nv ? nv : 1) * sizeof *m->nrm);
    }
    if (!m->pos || (x.vl.has_n && !m->nrm)) {
        rc = PM_ENOMEM;
        snprintf(err, cap, "%s: out of memory", name);
    }
    if (rc == 0) rc = read_elements(&x, els, nels, m);
    free(x.corner);
    if (rc == 0) rc = finish_mesh(&x, m);
    free(x.t.face);
    free(x.t.v);
    if (rc < 0) mesh_free(m);
    return rc;
}
