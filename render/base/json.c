/* json.c: path-reporting getters over cJSON, and file parsing with line and column.
 *
 * cJSON_ParseWithOpts returns where parsing stopped through its return_parse_end argument
 * (its global error pointer is not thread-safe, so it is not used); the line and column are
 * counted from the start of the text to that point.
 */
#include "base/json.h"

#include <ctype.h>
#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "photonmap/common.h"

int json_fail(json_err *e, int code, const char *fmt, ...) {
    if (e) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(e->msg, sizeof e->msg, fmt, ap);
        va_end(ap);
    }
    return code;
}

void json_path_key(char *buf, size_t cap, const char *path, const char *key) {
    snprintf(buf, cap, "%s.%s", path, key);
}

void json_path_index(char *buf, size_t cap, const char *path, int index) {
    snprintf(buf, cap, "%s[%d]", path, index);
}

const char *json_type_name(const cJSON *it) {
    if (!it) return "nothing";
    if (cJSON_IsNumber(it)) return "a number";
    if (cJSON_IsString(it)) return "a string";
    if (cJSON_IsArray(it)) return "an array";
    if (cJSON_IsObject(it)) return "an object";
    if (cJSON_IsBool(it)) return "a boolean";
    if (cJSON_IsNull(it)) return "null";
    return "an invalid value";
}

/* What a value of the wrong type was, for an error: its type, and for a string its text (a
 * typed --pm value arrives as one: "--pm k_global: expected a number, got the string "1e"").
 * Long strings are cut with "...". buf must hold at least 64 bytes. */
static const char *type_desc(const cJSON *it, char *buf, size_t cap) {
    if (!cJSON_IsString(it) || !it->valuestring) return json_type_name(it);
    size_t n = strlen(it->valuestring);
    if (n > 40) snprintf(buf, cap, "the string \"%.37s...\"", it->valuestring);
    else snprintf(buf, cap, "the string \"%s\"", it->valuestring);
    return buf;
}

static int cmp_key(const void *a, const void *b) {
    return strcmp(*(const char *const *)a, *(const char *const *)b);
}

/* The first key of obj that appears twice, or NULL (PM_ENOMEM aside: *rc). */
static const char *repeated_key(const cJSON *obj, int *rc) {
    size_t n = 0;
    for (const cJSON *c = obj->child; c; c = c->next) n++;
    if (n <= 32) { /* the usual case: a few keys, compared pairwise */
        for (const cJSON *c = obj->child; c; c = c->next)
            for (const cJSON *d = obj->child; d != c; d = d->next)
                if (c->string && d->string && strcmp(c->string, d->string) == 0) return c->string;
        return NULL;
    }
    const char **keys = malloc(n * sizeof *keys), *dup = NULL;
    if (!keys) {
        *rc = PM_ENOMEM;
        return NULL;
    }
    size_t m = 0;
    for (const cJSON *c = obj->child; c; c = c->next)
        if (c->string) keys[m++] = c->string;
    qsort(keys, m, sizeof *keys, cmp_key);
    for (size_t i = 1; i < m && !dup; i++)
        if (strcmp(keys[i - 1], keys[i]) == 0) dup = keys[i];
    free(keys);
    return dup;
}

/* cJSON keeps every copy of a repeated key and the getters see the first, so a file saying
 * "width": 8 and later "width": 0 would quietly render at 8. Refuse repeated keys at any
 * depth. path holds the JSON path of it (len characters; cap bytes), extended in place. */
static int check_repeated_keys(const cJSON *it, char *path, size_t len, size_t cap, json_err *e) {
    int rc = 0, i = 0;
    if (cJSON_IsObject(it)) {
        const char *dup = repeated_key(it, &rc);
        if (rc) return json_fail(e, rc, "out of memory");
        if (dup) return json_fail(e, PM_EINVAL, "%s: the key \"%s\" is given more than once", path, dup);
    }
    for (const cJSON *c = it->child; c; c = c->next, i++) {
        if (!c->child) continue; /* a number, string, ... or an empty array/object */
        int k = cJSON_IsObject(it) ? snprintf(path + len, cap - len, ".%s", c->string ? c->string : "?")
                                   : snprintf(path + len, cap - len, "[%d]", i);
        size_t nl = k < 0 ? len : len + (size_t)k < cap ? len + (size_t)k : cap - 1;
        rc = check_repeated_keys(c, path, nl, cap, e);
        path[len] = 0;
        if (rc) return rc;
    }
    return 0;
}

/* cJSON reads a number with strtod over the characters it allows, so it takes "01", "-00",
 * "1." and "1.e5", which JSON's grammar forbids (-?(0|[1-9][0-9]*)(.[0-9]+)?([eE][+-]?[0-9]+)?).
 * After cJSON accepted the text (so its structure is sound), scan it once more, keeping the
 * JSON path of the current value, and refuse the first such number with its line, column and
 * path: "line 3, column 15: $.objects[0].radius: the number 01 has a leading zero (JSON
 * forbids it)". Strings are skipped with their escapes. */
typedef struct jlevel {
    int is_obj, index, want_key;
    const char *key;
    size_t key_len;
} jlevel;

static int check_numbers(const char *text, json_err *e) {
    static const int max_depth = CJSON_NESTING_LIMIT + 2;
    jlevel *st = malloc((size_t)max_depth * sizeof *st);
    if (!st) return json_fail(e, PM_ENOMEM, "out of memory");
    int depth = 0, rc = 0;
    for (const char *c = text; *c && rc == 0; c++) {
        if (*c == '"') {
            const char *b = ++c;
            while (*c && *c != '"') c += (*c == '\\' && c[1]) ? 2 : 1;
            if (depth > 0 && st[depth - 1].is_obj && st[depth - 1].want_key) {
                st[depth - 1].key = b;
                st[depth - 1].key_len = (size_t)(c - b);
                st[depth - 1].want_key = 0;
            }
            if (!*c) break;
        } else if (*c == '{' || *c == '[') {
            if (depth == max_depth) break; /* deeper than cJSON allows: it refused already */
            st[depth++] = (jlevel){*c == '{', 0, *c == '{', NULL, 0};
        } else if (*c == '}' || *c == ']') {
            if (depth > 0) depth--;
        } else if (*c == ',' && depth > 0) {
            st[depth - 1].index++;
            st[depth - 1].want_key = st[depth - 1].is_obj;
        } else if ((*c == '-' || (*c >= '0' && *c <= '9')) &&
                   (c == text || !(isalnum((unsigned char)c[-1]) || c[-1] == '.' || c[-1] == '+' ||
                                   c[-1] == '-'))) {
            const char *b = c, *q = c + (*c == '-');
            const char *why = NULL;
            if (*q == '0' && q[1] >= '0' && q[1] <= '9') why = "has a leading zero";
            while (*q >= '0' && *q <= '9') q++;
            if (!why && *q == '.') {
                if (!(q[1] >= '0' && q[1] <= '9')) why = "has no digit after its decimal point";
                for (q++; *q >= '0' && *q <= '9'; q++) {}
            }
            if (!why && (*q == 'e' || *q == 'E')) {
                q++;
                if (*q == '+' || *q == '-') q++;
                if (!(*q >= '0' && *q <= '9')) why = "has no digit in its exponent";
            }
            while (*q && strchr("0123456789+-eE.", *q)) q++;
            if (why) {
                int line = 1, col = 1;
                for (const char *t = text; t < b; t++) {
                    if (*t == '\n') {
                        line++;
                        col = 1;
                    } else {
                        col++;
                    }
                }
                char path[512] = "$";
                size_t n = 1;
                for (int d = 0; d < depth && n < sizeof path - 1; d++) {
                    int kl = (int)(st[d].key_len > 200 ? 200 : st[d].key_len);
                    int k = st[d].is_obj ? snprintf(path + n, sizeof path - n, ".%.*s", kl, st[d].key ? st[d].key : "")
                                         : snprintf(path + n, sizeof path - n, "[%d]", st[d].index);
                    if (k < 0 || (size_t)k >= sizeof path - n) break;
                    n += (size_t)k;
                }
                rc = json_fail(e, PM_EFORMAT, "line %d, column %d: %s: the number %.*s %s (JSON forbids it)",
                               line, col, path, (int)(q - b > 40 ? 40 : q - b), b, why);
            }
            c = q - 1;
        }
    }
    free(st);
    return rc;
}

int json_parse_text(const char *text, cJSON **root, json_err *e) {
    const char *end = NULL;
    *root = cJSON_ParseWithOpts(text, &end, 1);
    if (*root) {
        char path[1024] = "$";
        int rc = check_numbers(text, e);
        if (rc == 0) rc = check_repeated_keys(*root, path, 1, sizeof path, e);
        if (rc < 0) {
            cJSON_Delete(*root);
            *root = NULL;
        }
        return rc;
    }
    if (!end) end = text;
    int line = 1, col = 1;
    for (const char *c = text; c < end && *c; c++) {
        if (*c == '\n') {
            line++;
            col = 1;
        } else {
            col++;
        }
    }
    /* Show the text around the stop point: up to 16 characters before it on its line and
     * up to 16 after, with ">" marking where the parser stopped. */
    const char *b = end;
    while (b > text && b[-1] != '\n' && end - b < 16) b--;
    char ctx[40];
    size_t k = 0;
    for (const char *c = b; c < end && k < 16; c++) ctx[k++] = (*c == '\t' || *c == '\r') ? ' ' : *c;
    ctx[k++] = '>';
    for (const char *c = end; *c && *c != '\n' && *c != '\r' && k < sizeof ctx - 1; c++) ctx[k++] = *c;
    ctx[k] = 0;
    if (!*end)
        return json_fail(e, PM_EFORMAT, "line %d, column %d: syntax error (unexpected end of file)",
                         line, col);
    return json_fail(e, PM_EFORMAT, "line %d, column %d: syntax error at '%s'", line, col, ctx);
}

/* The largest file json_parse_file reads (render --max-scene-mb changes it). */
static size_t g_max_file_bytes = (size_t)256 << 20;
void json_set_max_file_bytes(size_t n) { g_max_file_bytes = n; }

int json_parse_file(const char *filename, cJSON **root, json_err *e) {
    *root = NULL;
    FILE *f = fopen(filename, "rb");
    if (!f) return json_fail(e, PM_EIO, "cannot open: %s", strerror(errno));
    size_t cap = 1 << 16, n = 0;
    char *buf = malloc(cap);
    while (buf) {
        size_t got = fread(buf + n, 1, cap - n - 1, f);
        /* Checked while reading, so /dev/zero or an endless pipe fails at its first block. */
        if (memchr(buf + n, 0, got)) {
            free(buf);
            fclose(f);
            return json_fail(e, PM_EFORMAT, "the file contains a NUL byte; not a JSON text");
        }
        n += got;
        if (n > g_max_file_bytes) {
            free(buf);
            fclose(f);
            return json_fail(e, PM_EFORMAT, "larger than the limit of %zu MiB (render --max-scene-mb)",
                             g_max_file_bytes >> 20);
        }
        if (n < cap - 1) break;
        char *nb = realloc(buf, cap * 2);
        if (!nb) {
            free(buf);
            buf = NULL;
            break;
        }
        buf = nb;
        cap *= 2;
    }
    int rerr = ferror(f) ? errno : 0;
    fclose(f);
    if (!buf) return json_fail(e, PM_ENOMEM, "out of memory reading the file");
    if (rerr) {
        free(buf);
        return json_fail(e, PM_EIO, "cannot read: %s", strerror(rerr)); /* e.g. a directory */
    }
    buf[n] = 0;
    if (strlen(buf) != n) {
        free(buf);
        return json_fail(e, PM_EFORMAT, "the file contains a NUL byte; not a JSON text");
    }
    int rc = json_parse_text(buf, root, e);
    free(buf);
    return rc;
}

const cJSON *json_get(const cJSON *obj, const char *key) {
    return obj ? cJSON_GetObjectItemCaseSensitive(obj, key) : NULL;
}

/* Fetch key; 1 = found, 0 = absent and optional, negative = error (absent and required). */
static int fetch(const cJSON *obj, const char *path, const char *key, int required,
                 const cJSON **it, json_err *e) {
    *it = json_get(obj, key);
    if (*it) return 1;
    if (required) return json_fail(e, PM_EINVAL, "%s.%s: missing (required)", path, key);
    return 0;
}

/* fetch, then the item's type: 1 with *it, 0 when absent and optional, or an error saying
 * what was expected ("%s.%s: expected an object, got a string"). */
static int fetch_as(const cJSON *obj, const char *path, const char *key, int required,
                    cJSON_bool (*is)(const cJSON *), const char *expected, const cJSON **it,
                    json_err *e) {
    int rc = fetch(obj, path, key, required, it, e);
    if (rc <= 0) return rc;
    if (!is(*it)) {
        char d[64];
        return json_fail(e, PM_EINVAL, "%s.%s: expected %s, got %s", path, key, expected,
                         type_desc(*it, d, sizeof d));
    }
    return 1;
}

static int check_number(const cJSON *it, const char *p1, const char *p2, double *out, json_err *e) {
    if (!cJSON_IsNumber(it)) {
        char d[64];
        return json_fail(e, PM_EINVAL, "%s%s: expected a number, got %s", p1, p2, type_desc(it, d, sizeof d));
    }
    if (!isfinite(it->valuedouble))
        return json_fail(e, PM_ENONFINITE, "%s%s: not a finite number", p1, p2);
    *out = it->valuedouble;
    return 0;
}

int json_number(const cJSON *obj, const char *path, const char *key, int required, double *out,
                json_err *e) {
    const cJSON *it;
    int rc = fetch(obj, path, key, required, &it, e);
    if (rc <= 0) return rc;
    char p2[128];
    snprintf(p2, sizeof p2, ".%s", key);
    return check_number(it, path, p2, out, e);
}

int json_int(const cJSON *obj, const char *path, const char *key, int required, long lo, long hi,
             long *out, json_err *e) {
    double v;
    const cJSON *it = json_get(obj, key);
    int rc = json_number(obj, path, key, required, &v, e);
    if (rc < 0 || !it) return rc;
    if (v != floor(v))
        return json_fail(e, PM_EINVAL, "%s.%s: expected an integer, got %g", path, key, v);
    if (v < (double)lo || v > (double)hi)
        return json_fail(e, PM_EINVAL, "%s.%s: %g is out of range [%ld, %ld]", path, key, v, lo, hi);
    *out = (long)v;
    return 0;
}

int json_bool(const cJSON *obj, const char *path, const char *key, int required, int *out,
              json_err *e) {
    const cJSON *it;
    int rc = fetch_as(obj, path, key, required, cJSON_IsBool, "true or false", &it, e);
    if (rc <= 0) return rc;
    *out = cJSON_IsTrue(it) ? 1 : 0;
    return 0;
}

int json_string(const cJSON *obj, const char *path, const char *key, int required,
                const char **out, json_err *e) {
    const cJSON *it;
    int rc = fetch_as(obj, path, key, required, cJSON_IsString, "a string", &it, e);
    if (rc <= 0) return rc;
    *out = it->valuestring;
    return 0;
}

int json_item_vec3(const cJSON *it, const char *path, vec3 *out, json_err *e) {
    if (!cJSON_IsArray(it) || cJSON_GetArraySize(it) != 3)
        return json_fail(e, PM_EINVAL, "%s: expected an array of 3 numbers, got %s", path,
                         cJSON_IsArray(it) ? "an array of another length" : json_type_name(it));
    double v[3];
    for (int i = 0; i < 3; i++) {
        char p2[16];
        snprintf(p2, sizeof p2, "[%d]", i);
        int rc = check_number(cJSON_GetArrayItem(it, i), path, p2, &v[i], e);
        if (rc < 0) return rc;
    }
    *out = v3(v[0], v[1], v[2]);
    return 0;
}

/* fetch, and the item's own path ("path.key") in p for the messages about its parts. */
static int fetch_with_path(const cJSON *obj, const char *path, const char *key, int required,
                           const cJSON **it, char *p, size_t pcap, json_err *e) {
    int rc = fetch(obj, path, key, required, it, e);
    if (rc > 0) json_path_key(p, pcap, path, key);
    return rc;
}

/* json_vec3 and json_rgb: three numbers, or with grey one number for all three. */
static int fetch_triple(const cJSON *obj, const char *path, const char *key, int required, int grey,
                        vec3 *out, json_err *e) {
    const cJSON *it;
    char p[256];
    int rc = fetch_with_path(obj, path, key, required, &it, p, sizeof p, e);
    if (rc <= 0) return rc;
    if (grey && cJSON_IsNumber(it)) {
        double g;
        rc = check_number(it, p, "", &g, e);
        if (rc < 0) return rc;
        *out = v3s(g);
        return 0;
    }
    return json_item_vec3(it, p, out, e);
}

int json_vec3(const cJSON *obj, const char *path, const char *key, int required, vec3 *out,
              json_err *e) {
    return fetch_triple(obj, path, key, required, 0, out, e);
}

int json_rgb(const cJSON *obj, const char *path, const char *key, int required, rgb *out,
             json_err *e) {
    return fetch_triple(obj, path, key, required, 1, out, e);
}

/* json_object and json_array: the item itself, NULL when absent (and optional). */
static int fetch_item(const cJSON *obj, const char *path, const char *key, int required,
                      cJSON_bool (*is)(const cJSON *), const char *expected, const cJSON **out,
                      json_err *e) {
    const cJSON *it;
    *out = NULL;
    int rc = fetch_as(obj, path, key, required, is, expected, &it, e);
    if (rc <= 0) return rc;
    *out = it;
    return 0;
}

int json_object(const cJSON *obj, const char *path, const char *key, int required,
                const cJSON **out, json_err *e) {
    return fetch_item(obj, path, key, required, cJSON_IsObject, "an object", out, e);
}

int json_array(const cJSON *obj, const char *path, const char *key, int required,
               const cJSON **out, json_err *e) {
    return fetch_item(obj, path, key, required, cJSON_IsArray, "an array", out, e);
}

/* Optimal string alignment distance (Damerau-Levenshtein without repeated edits of a
 * substring), two rows of the table plus the one before; keys are short. */
static int lower(char c) { return tolower((unsigned char)c); }

/* Damerau-Levenshtein distance, letters compared without case ("K_GLOBAL" is 0 from
 * "k_global"); (size_t)-1 for keys over 63 characters. */
static size_t edit_distance(const char *a, const char *b) {
    size_t la = strlen(a), lb = strlen(b);
    if (la > 63 || lb > 63) return (size_t)-1;
    size_t d[3][64];
    for (size_t j = 0; j <= lb; j++) d[0][j] = j;
    for (size_t i = 1; i <= la; i++) {
        size_t *cur = d[i % 3], *prev = d[(i - 1) % 3], *pp = d[(i + 1) % 3];
        cur[0] = i;
        for (size_t j = 1; j <= lb; j++) {
            size_t cost = lower(a[i - 1]) != lower(b[j - 1]);
            size_t v = prev[j] + 1;
            if (cur[j - 1] + 1 < v) v = cur[j - 1] + 1;
            if (prev[j - 1] + cost < v) v = prev[j - 1] + cost;
            if (i > 1 && j > 1 && lower(a[i - 1]) == lower(b[j - 2]) && lower(a[i - 2]) == lower(b[j - 1]) &&
                pp[j - 2] + 1 < v)
                v = pp[j - 2] + 1;
            cur[j] = v;
        }
    }
    return d[la % 3][lb];
}

const char *json_nearest_key(const char *key, const char *const *known, size_t n) {
    if (!key) return NULL;
    /* The key as given, and the part after its last dot: a key typed as its JSON path
     * ("--pm photon_mapping.k_global=5") finds "k_global". */
    const char *dot = strrchr(key, '.');
    const char *cand[2] = {key, dot && dot[1] ? dot + 1 : NULL};
    const char *best = NULL;
    size_t best_d = (size_t)-1;
    for (int c = 0; c < 2 && cand[c]; c++) {
        size_t limit = strlen(cand[c]) / 3;
        if (limit < 1) limit = 1;
        for (size_t k = 0; k < n; k++) {
            size_t dk = edit_distance(cand[c], known[k]);
            if (dk <= limit && dk < best_d) {
                best_d = dk;
                best = known[k];
            }
        }
    }
    return best;
}

int json_check_keys(const cJSON *obj, const char *path, const char *const *known, size_t n,
                    const char *what, json_err *e) {
    for (const cJSON *it = obj ? obj->child : NULL; it; it = it->next) {
        int ok = 0;
        for (size_t k = 0; k < n && !ok; k++) ok = it->string && strcmp(it->string, known[k]) == 0;
        if (ok) continue;
        const char *key = it->string ? it->string : "?";
        const char *near = json_nearest_key(it->string, known, n);
        if (near)
            return json_fail(e, PM_EINVAL, "%s.%s: unknown key (did you mean \"%s\"?)", path, key, near);
        char list[320];
        size_t len = 0;
        list[0] = 0;
        for (size_t k = 0; k < n && len < sizeof list; k++) {
            int w = snprintf(list + len, sizeof list - len, "%s%s", k ? ", " : "", known[k]);
            if (w < 0) break;
            len += (size_t)w;
        }
        return json_fail(e, PM_EINVAL, "%s.%s: unknown key%s%s (known: %s)", path, key,
                         what ? " of " : "", what ? what : "", list);
    }
    return 0;
}
