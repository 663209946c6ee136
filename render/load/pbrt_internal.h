/* pbrt_internal.h: what the files of the pbrt-v3 converter share (pbrt.c the entry point,
 * pbrt_matrix.c the matrices, pbrt_lex.c the tokens and parameter lists, pbrt_directives.c
 * the directives and running files, pbrt_shapes.c, pbrt_materials.c and pbrt_lights.c the
 * conversions); not for use outside render/load/pbrt*.c.
 *
 * How it works: each file (and each Include) is read whole and cut into tokens (quoted strings,
 * numbers, bare words, [ and ]), each with its file and line. The directives are then run in
 * order against a graphics state (the current transform, material, area light, orientation)
 * and its stack; every shape is written at once as world-space geometry in the output document
 * (inline meshes and spheres; PLY meshes as file objects with their matrix), so instances are
 * copies of already converted objects under one more transform. A directive's parameters are
 * parsed into a list, looked up by name with their type checked, and any parameter nobody
 * asked for is warned about when the directive is done, so nothing is dropped silently.
 * The mirror of the scene (pbrt.h, "Handedness") is decided at WorldBegin from the camera and
 * applied as each point, direction and matrix is written out.
 */
#ifndef RENDER_PBRT_INTERNAL_H
#define RENDER_PBRT_INTERNAL_H

#include <cjson/cJSON.h>

#include "common.h"
#include "base/json.h"
#include "base/vec.h"
#include "load/pbrt.h"

#define TRY(x) JSON_TRY(x)
#define PB_MAX_INCLUDE 32
#define PB_MAX_STACK 256

/* ---- tokens, parameters, the conversion's state ------------------------------------------- */

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

/* ---- pbrt_lex.c: tokens, messages, parameters ------------------------------------------- */

/* The name of the file of token t. */
const char *pb_file(const conv *c, const tok *t);
/* An error (code) whose message starts with t's file and line (none when t is NULL). */
int pb_fail(conv *c, const tok *t, int code, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
/* "render: FILE:LINE: warning: ..." on stderr. */
void pb_warn(const conv *c, const tok *t, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
/* Cut text into tokens; file is the index of its name. */
int pb_lex(conv *c, const char *text, int file, toks *ts);
void pb_toks_free(toks *ts);
/* Parameters from *i on: "type name" value, where value is [ ... ] or one number/string/word. */
int pb_read_params(conv *c, const toks *ts, int *i, plist *pl);
void pb_plist_free(plist *pl);
/* The parameter `name`, if its type is one of the '|'-separated types (another type is an
 * error); *out NULL when absent. */
int pb_get(conv *c, const tok *at, plist *pl, const char *name, const char *types, pparam **out);
/* The getters return 1 when the parameter is there (and set *v), 0 when absent, < 0 on error. */
int pb_get_floats(conv *c, const tok *at, plist *pl, const char *name, const char *types, int n, double *v);
int pb_get_string(conv *c, const tok *at, plist *pl, const char *name, const char **s);
int pb_get_bool(conv *c, const tok *at, plist *pl, const char *name, int *b);
int pb_get_color(conv *c, const tok *at, plist *pl, const char *name, rgb *v);
/* Warn about every parameter nobody asked for. */
void pb_warn_unused(const conv *c, const tok *at, const char *what, const plist *pl);
/* A directive's own arguments: n numbers (in [ ] or not), one quoted name. */
int pb_nums(conv *c, const toks *ts, int *i, const tok *at, int n, double *v, const char *what);
int pb_one_string(conv *c, const toks *ts, int *i, const tok *at, const char **s, const char *what);

/* ---- pbrt_matrix.c: matrices, output coordinates -------------------------------------------- */

void pb_ident(double m[4][4]);
void pb_mul(double a[4][4], double b[4][4], double out[4][4]);
/* Inverse by Gauss-Jordan with partial pivoting; -1 when singular or not finite. */
int pb_inv(double m[4][4], double out[4][4]);
double pb_det3(double m[4][4]);
vec3 pb_point(double m[4][4], vec3 p);
vec3 pb_dir(double m[4][4], vec3 d);
/* Output coordinates: the world, mirrored in x when pbrt's camera frame is ours mirrored. */
vec3 pb_out(const conv *c, vec3 p);
cJSON *pb_jv(vec3 v);
/* ---- pbrt_directives.c ------------------------------------------------------------------- */

/* Read and run the file at path (from: the Include token, NULL for the top file). */
int pb_run_file(conv *c, const char *path, const tok *from);
/* Run a text (name: its file's name, for messages), as pb_run_file runs a file's. */
int pb_run_text(conv *c, const char *text, const char *name);

/* Run the directive at *i with its arguments, moving *i past them. */
int pb_directive(conv *c, const toks *ts, int *i);

/* ---- pbrt_shapes.c, pbrt_materials.c: the conversions ------------------------------------- */

/* path relative to the directory of file, made absolute. */
void pb_resolve(const char *file, const char *name, char *out, size_t cap);
/* A copy of converted object o under the matrix X (output coordinates). */
cJSON *pb_xform_obj(const conv *c, const cJSON *o, double X[4][4]);
/* The material for the next shape: the current one, or a copy with the area light's emission. */
int pb_shape_material(conv *c, char *name, size_t cap);

/* Directives with a name s and a parameter list pl ("what" is 'Directive "name"' for
 * messages); they return < 0 on error. */
int pb_do_shape(conv *c, const tok *at, const char *s, plist *pl, const char *what);
int pb_do_material(conv *c, const tok *at, const char *s, plist *pl, const char *what);
int pb_do_named_material(conv *c, const tok *at, const char *s, plist *pl, const char *what);
int pb_do_area_light(conv *c, const tok *at, const char *s, plist *pl, const char *what);

/* ---- pbrt_lights.c: LightSource "spot" and "infinite" (sc: the directive's scale) -------- */

int pb_spot_light(conv *c, const tok *at, plist *pl, rgb sc, const char *what);
int pb_infinite_light(conv *c, const tok *at, plist *pl, rgb sc, const char *what);
int pb_do_named_medium(conv *c, const tok *at, const char *s, plist *pl, const char *what);
/* MediumInterface "inside" ["outside"], which reads its own arguments. */
int pb_do_medium_interface(conv *c, const toks *ts, int *i, const tok *at);

#endif /* RENDER_PBRT_INTERNAL_H */
