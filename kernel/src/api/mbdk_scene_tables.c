/* mbdk_scene_tables.c - a scene's tables read from the file `mbdk tables` writes.
 *
 * The scene file (TOML, with bodies, joints and forces by name) is read by one reader, Python's
 * (mbdk.scene_file), whose checks name the file, element, field and value; its tables are what
 * the kernel runs. `mbdk tables SCENE -o FILE` writes them, with the initial state the run starts
 * from (assembled), as a small TOML file of scalars and flat arrays (python/mbdk/tables_file.py
 * documents every key). A C program reads that file here and hands the arrays to the steppers
 * (mbdk_stepper_create_scene, _index3, _spatial, _spatial_index3, or mbdk_stepper_create_tables):
 * no second scene reader in the kernel whose checks could drift from the first.
 *
 * What this file reads is that subset of TOML: comments, and `key = value` lines where value
 * is a number (decimal: digits, sign, point, exponent), a "string" without escapes, or a
 * one-line [list of numbers]. Every key is required once (kind-specific keys for their kind
 * only), and the state's length must be the one its bodies, rotation and wear entries give: the
 * steppers take y0 without a length. Numbers are read in the "C" locale, whatever the host
 * program set. A malformed file is MBDK_ERR_INVALID_INPUT with a message naming the file, the
 * line, the key and the value; a list is counted before its array is allocated; no array is
 * left allocated after a failure. It never prints.
 */
#define _POSIX_C_SOURCE 200809L
#include <errno.h>
#include <limits.h>
#include <locale.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "mbdk.h"

#define FORMAT_NAME "mbdk-scene-tables"
#define FORMAT_VERSION 1

struct reader {
    const char *path;
    char *message;
    int message_len;
    int line;
};

static int fail(struct reader *r, int status, const char *fmt, ...)
{
    if (r->message && r->message_len > 0) {
        int k = snprintf(r->message, (size_t)r->message_len, "%s", r->path);
        if (r->line > 0 && k >= 0 && k < r->message_len)
            k += snprintf(r->message + k, (size_t)(r->message_len - k), ", line %d", r->line);
        if (k >= 0 && k < r->message_len)
            k += snprintf(r->message + k, (size_t)(r->message_len - k), ": ");
        if (k >= 0 && k < r->message_len) {
            va_list ap;
            va_start(ap, fmt);
            vsnprintf(r->message + k, (size_t)(r->message_len - k), fmt, ap);
            va_end(ap);
        }
    }
    return status;
}

/* the keys: which kind needs them (0 both), whether a list, of ints */
enum { K_SCALAR = 0, K_LIST = 1, K_STRING = 2 };
struct key {
    const char *name;
    int kind;       /* 0: every scene; MBDK_SCENE_PLANAR or MBDK_SCENE_SPATIAL: that kind's */
    int shape;      /* K_SCALAR, K_LIST, K_STRING */
    int integer;    /* list or scalar of ints */
};

static const struct key KEYS[] = {
    {"format", 0, K_STRING, 0}, {"version", 0, K_SCALAR, 1}, {"scene", 0, K_STRING, 0},
    {"source", 0, K_STRING, 0}, {"kind", 0, K_STRING, 0}, {"rotation", 0, K_SCALAR, 1},
    {"nb", 0, K_SCALAR, 1}, {"nj", 0, K_SCALAR, 1}, {"nf", 0, K_SCALAR, 1}, {"n", 0, K_SCALAR, 1},
    {"t0", 0, K_SCALAR, 0}, {"mass", 0, K_LIST, 0}, {"inertia", 0, K_LIST, 0},
    {"jreal", 0, K_LIST, 0}, {"freal", 0, K_LIST, 0}, {"y0", 0, K_LIST, 0},
    {"jint", MBDK_SCENE_PLANAR, K_LIST, 1}, {"fint", MBDK_SCENE_PLANAR, K_LIST, 1},
    {"jtype", MBDK_SCENE_SPATIAL, K_LIST, 1}, {"jbody", MBDK_SCENE_SPATIAL, K_LIST, 1},
    {"ftype", MBDK_SCENE_SPATIAL, K_LIST, 1}, {"fbody", MBDK_SCENE_SPATIAL, K_LIST, 1},
    {"norm", MBDK_SCENE_SPATIAL, K_SCALAR, 1}, {"norm_gain", MBDK_SCENE_SPATIAL, K_SCALAR, 0},
};
#define NKEYS ((int)(sizeof KEYS / sizeof KEYS[0]))

struct value {
    int line;       /* 0: not given */
    char *text;     /* as written, after '=' (trimmed) */
};

static char *trim(char *s)
{
    char *e;
    while (*s == ' ' || *s == '\t') s++;
    e = s + strlen(s);
    while (e > s && (e[-1] == ' ' || e[-1] == '\t' || e[-1] == '\n' || e[-1] == '\r')) *--e = 0;
    return s;
}

/* a shortened copy of a value for a message */
static const char *shown(const char *text, char *buf, size_t len)
{
    size_t n = strlen(text);
    if (n < len) return text;
    snprintf(buf, len, "%.*s...", (int)(len - 4), text);
    return buf;
}

static int parse_number(const char *s, int integer, double *x)
{
    char *end;
    errno = 0;
    /* decimal numbers only: no hex, inf or nan, which TOML writes otherwise or not at all */
    if (*s == 0 || s[strspn(s, integer ? "+-0123456789" : "+-0123456789.eE")] != 0) return 0;
    if (integer) {
        long v = strtol(s, &end, 10);
        if (errno || *end || v < INT_MIN || v > INT_MAX) return 0;
        *x = (double)v;
        return 1;
    }
    *x = strtod(s, &end);
    return !(errno == ERANGE && fabs(*x) > 1.0) && *end == 0 && isfinite(*x);
}

/* the list text of key k: its values counted first (each item a number, none empty), checked
 * against want, then read into a new array (*dout or *iout, want values) */
static int parse_list(struct reader *r, const struct key *k, const struct value *v, int want,
                      double **dout, int **iout)
{
    char buf[64];
    const char *s = v->text, *p;
    size_t len = strlen(s);
    int pass, count = 0;
    r->line = v->line;
    if (len < 2 || s[0] != '[' || s[len - 1] != ']')
        return fail(r, MBDK_ERR_INVALID_INPUT, "key '%s' = %s must be a list [x, y, ...] on "
                    "one line%s", k->name, shown(s, buf, sizeof buf),
                    s[0] == '[' && !strchr(s, ']') ? " (a list over several lines is TOML, but "
                    "not what `mbdk tables` writes)" : "");
    for (pass = 0; pass < 2; pass++) {
        int n = 0;
        p = s + 1;
        if (pass == 1) {
            size_t bytes = (size_t)(want > 0 ? want : 1) * (dout ? sizeof(double) : sizeof(int));
            void *a = calloc(1, bytes);
            if (!a) return fail(r, MBDK_ERR_NO_MEMORY, "no memory for key '%s' (%d values)",
                                k->name, want);
            if (dout) *dout = a;
            else *iout = a;
        }
        while (1) {
            char item[128];
            const char *end = p;
            size_t m;
            double x;
            while (*end && *end != ',' && *end != ']') end++;
            m = (size_t)(end - p);
            snprintf(item, sizeof item, "%.*s", (int)(m < sizeof item ? m : sizeof item - 1), p);
            if (m >= sizeof item) snprintf(item + sizeof item - 4, 4, "...");
            {
                char *t = trim(item);
                if (*t == 0 && *end == ']' && n == 0) break;       /* [] */
                if (*t == 0)
                    return fail(r, MBDK_ERR_INVALID_INPUT, "key '%s', value %d is empty",
                                k->name, n + 1);
                if (m >= sizeof item || !parse_number(t, k->integer, &x))
                    return fail(r, MBDK_ERR_INVALID_INPUT, "key '%s', value %d = '%s' is not "
                                "%s", k->name, n + 1, t,
                                k->integer ? "an integer" : "a finite decimal number");
            }
            if (pass == 1) {
                if (dout) (*dout)[n] = x;
                else (*iout)[n] = (int)x;
            }
            n++;
            if (*end == ']') break;
            p = end + 1;
        }
        if (p && strchr(p, ']') != s + len - 1)
            return fail(r, MBDK_ERR_INVALID_INPUT, "key '%s' = %s: text after the list's ']'",
                        k->name, shown(s, buf, sizeof buf));
        count = n;
        if (pass == 0 && count != want)
            return fail(r, MBDK_ERR_INVALID_INPUT, "key '%s' has %d value%s, %d expected",
                        k->name, count, count == 1 ? "" : "s", want);
    }
    return 0;
}

static int key_index(const char *name)
{
    int i;
    for (i = 0; i < NKEYS; i++)
        if (strcmp(KEYS[i].name, name) == 0) return i;
    return -1;
}

static int scalar(struct reader *r, struct value *vals, const char *name, double *x)
{
    char buf[64];
    int i = key_index(name);
    r->line = vals[i].line;
    if (!parse_number(vals[i].text, KEYS[i].integer, x))
        return fail(r, MBDK_ERR_INVALID_INPUT, "key '%s' = %s is not %s", name,
                    shown(vals[i].text, buf, sizeof buf),
                    KEYS[i].integer ? "an integer" : "a finite number");
    return 0;
}

static int string(struct reader *r, struct value *vals, const char *name, char *out, size_t len)
{
    char buf[64];
    int i = key_index(name);
    const char *s = vals[i].text;
    size_t n = strlen(s);
    r->line = vals[i].line;
    if (n < 2 || s[0] != '"' || s[n - 1] != '"' || memchr(s + 1, '"', n - 2) ||
        memchr(s + 1, '\\', n - 2))
        return fail(r, MBDK_ERR_INVALID_INPUT, "key '%s' = %s must be a \"string\" without "
                    "escapes", name, shown(s, buf, sizeof buf));
    snprintf(out, len, "%.*s", (int)(n - 2), s + 1);
    return 0;
}

void mbdk_scene_tables_free(mbdk_scene_tables *t)
{
    if (!t) return;
    free(t->mass); free(t->inertia); free(t->jreal); free(t->freal); free(t->y0);
    free(t->jint); free(t->fint); free(t->jtype); free(t->jbody); free(t->ftype); free(t->fbody);
    memset(t, 0, sizeof *t);
}

/* the value text of a line: up to a comment (a '#' outside a string) */
static char *value_text(char *s)
{
    int in_string = 0;
    char *p;
    for (p = s; *p; p++) {
        if (*p == '"') in_string = !in_string;
        else if (*p == '#' && !in_string) {
            *p = 0;
            break;
        }
    }
    return trim(s);
}

/* the lines of the file into vals (each key once, every key known) */
static int read_lines(struct reader *r, FILE *f, struct value *vals)
{
    char *line = NULL, buf[64];
    size_t cap = 0;
    int status = 0;
    r->line = 0;
    errno = 0;
    while (getline(&line, &cap, f) != -1) {
        char *s = trim(line), *eq, *name;
        int i;
        r->line++;
        if (*s == 0 || *s == '#') continue;
        if (*s == '[') {
            status = fail(r, MBDK_ERR_INVALID_INPUT, "'%s' is a TOML table: a scene file? a C "
                          "program reads the tables `mbdk tables SCENE --out FILE` writes",
                          shown(s, buf, sizeof buf));
            break;
        }
        eq = strchr(s, '=');
        if (!eq) {
            status = fail(r, MBDK_ERR_INVALID_INPUT, "'%s' is not a line key = value",
                          shown(s, buf, sizeof buf));
            break;
        }
        *eq = 0;
        name = trim(s);
        i = key_index(name);
        if (i < 0) {
            status = fail(r, MBDK_ERR_INVALID_INPUT, "unknown key '%s' (a tables file of "
                          "another version of mbdk? write it again with `mbdk tables`)",
                          shown(name, buf, sizeof buf));
            break;
        }
        if (vals[i].line) {
            status = fail(r, MBDK_ERR_INVALID_INPUT, "key '%s' given twice (first on line %d)",
                          name, vals[i].line);
            break;
        }
        vals[i].text = strdup(value_text(eq + 1));
        if (vals[i].text && vals[i].text[0] == '[' && !strchr(vals[i].text, ']')) {
            status = fail(r, MBDK_ERR_INVALID_INPUT, "key '%s': its list goes on over several "
                          "lines, which is TOML but not what `mbdk tables` writes: one line per "
                          "list", name);
            break;
        }
        if (!vals[i].text) {
            status = fail(r, MBDK_ERR_NO_MEMORY, "no memory for key '%s'", name);
            break;
        }
        vals[i].line = r->line;
    }
    if (!status && ferror(f)) {
        r->line = 0;
        status = fail(r, MBDK_ERR_INVALID_INPUT, "cannot read: %s", strerror(errno));
    }
    free(line);
    return status;
}

/* the state's length its bodies, rotation and wear entries give */
static int state_length(const mbdk_scene_tables *t)
{
    int k, nw = 0;
    for (k = 0; k < t->nf; k++)
        if ((t->kind == MBDK_SCENE_PLANAR ? t->fint[4 * k] : t->ftype[k]) == MBDK_EFFECT_WEAR)
            nw++;
    if (t->kind == MBDK_SCENE_PLANAR) return 6 * t->nb + nw;
    return (t->rotation == MBDK_ROT_QUATERNION ? 13 : 12) * t->nb + nw;
}

static int read_tables(struct reader *r, struct value *vals, mbdk_scene_tables *t)
{
    char text[64];
    double x;
    int status, i, planar, na = 0;
    struct { const char *name; double **d; int **n; long count; } arrays[12];

    for (i = 0; i < NKEYS; i++) {       /* the keys every scene has, before any is read */
        if (KEYS[i].kind == 0 && !vals[i].line) {
            r->line = 0;
            return fail(r, MBDK_ERR_INVALID_INPUT, "key '%s' missing (not a file `mbdk "
                        "tables` wrote?)", KEYS[i].name);
        }
    }
    if ((status = string(r, vals, "format", text, sizeof text))) return status;
    if (strcmp(text, FORMAT_NAME) != 0)
        return fail(r, MBDK_ERR_INVALID_INPUT, "key 'format' = \"%s\": not \"" FORMAT_NAME
                    "\" (write the file with `mbdk tables`)", text);
    if ((status = scalar(r, vals, "version", &x))) return status;
    if (x != FORMAT_VERSION)
        return fail(r, MBDK_ERR_INVALID_INPUT, "key 'version' = %g: this mbdk reads version %d "
                    "(write the file again with this mbdk's `mbdk tables`)", x, FORMAT_VERSION);
    if ((status = string(r, vals, "scene", t->name, sizeof t->name))) return status;
    if (strlen(vals[key_index("scene")].text) - 2 >= sizeof t->name)
        return fail(r, MBDK_ERR_INVALID_INPUT, "key 'scene': a name of %zu characters, "
                    "mbdk_scene_tables.name holds %zu", strlen(vals[key_index("scene")].text) - 2,
                    sizeof t->name - 1);
    if ((status = string(r, vals, "source", text, sizeof text))) return status;
    if ((status = string(r, vals, "kind", text, sizeof text))) return status;
    if (strcmp(text, "planar") == 0) t->kind = MBDK_SCENE_PLANAR;
    else if (strcmp(text, "spatial") == 0) t->kind = MBDK_SCENE_SPATIAL;
    else return fail(r, MBDK_ERR_INVALID_INPUT, "key 'kind' = \"%s\": one of \"planar\", "
                     "\"spatial\"", text);
    planar = t->kind == MBDK_SCENE_PLANAR;
    for (i = 0; i < NKEYS; i++) {       /* the kind's own keys, and no other kind's */
        if (KEYS[i].kind == 0) continue;
        if ((KEYS[i].kind == t->kind) != (vals[i].line != 0)) {
            r->line = vals[i].line;
            return fail(r, MBDK_ERR_INVALID_INPUT, "key '%s' %s a %s scene", KEYS[i].name,
                        vals[i].line ? "does not belong to" : "missing: it is needed by",
                        planar ? "planar" : "spatial");
        }
    }
    {
        const char *counts[] = {"rotation", "nb", "nj", "nf", "n"};
        int *dest[] = {&t->rotation, &t->nb, &t->nj, &t->nf, &t->n};
        for (i = 0; i < 5; i++) {
            if ((status = scalar(r, vals, counts[i], &x))) return status;
            if (x < 0 || x > 100000000 || (i == 1 && x < 1))
                return fail(r, MBDK_ERR_INVALID_INPUT, "key '%s' = %g is out of range (%s to "
                            "1e8)", counts[i], x, i == 1 ? "1" : "0");
            *dest[i] = (int)x;
        }
    }
    if ((status = scalar(r, vals, "t0", &t->t0))) return status;
    if (planar != (t->rotation == 0) || t->rotation > 3) {
        r->line = vals[key_index("rotation")].line;
        return fail(r, MBDK_ERR_INVALID_INPUT, "key 'rotation' = %d: %s", t->rotation,
                    planar ? "a planar scene has none (0)" : "a spatial scene's is 1 (quaternion), "
                    "2 (euler313) or 3 (cardan123)");
    }
    if (!planar) {
        if ((status = scalar(r, vals, "norm", &x))) return status;
        if (x < 1 || x > 3)
            return fail(r, MBDK_ERR_INVALID_INPUT, "key 'norm' = %g: 1 (project), 2 "
                        "(stabilise) or 3 (none)", x);
        t->norm = (int)x;
        if ((status = scalar(r, vals, "norm_gain", &t->norm_gain))) return status;
    }
#define ARRAY(NAME, D, N, COUNT) do { arrays[na].name = NAME; arrays[na].d = D; \
        arrays[na].n = N; arrays[na].count = (COUNT); na++; } while (0)
    ARRAY("mass", &t->mass, NULL, t->nb);
    ARRAY("inertia", &t->inertia, NULL, planar ? (long)t->nb : 9L * t->nb);
    ARRAY("jreal", &t->jreal, NULL, (long)(planar ? 12 : MBDK_SPATIAL_JOINT_REALS) * t->nj);
    ARRAY("freal", &t->freal, NULL, (long)(planar ? 12 : MBDK_SPATIAL_FORCE_REALS) * t->nf);
    if (planar) {
        ARRAY("jint", NULL, &t->jint, 4L * t->nj);
        ARRAY("fint", NULL, &t->fint, 4L * t->nf);
    } else {
        ARRAY("jtype", NULL, &t->jtype, t->nj);
        ARRAY("jbody", NULL, &t->jbody, 2L * t->nj);
        ARRAY("ftype", NULL, &t->ftype, t->nf);
        ARRAY("fbody", NULL, &t->fbody, 2L * t->nf);
    }
    ARRAY("y0", &t->y0, NULL, t->n);      /* last: its length is checked against the tables */
#undef ARRAY
    for (i = 0; i < na; i++) {
        int k = key_index(arrays[i].name);
        if (arrays[i].count > INT_MAX / 32) {
            r->line = vals[k].line;
            return fail(r, MBDK_ERR_INVALID_INPUT, "key '%s': %ld values are too many",
                        arrays[i].name, arrays[i].count);
        }
        if (arrays[i].d == &t->y0 && t->n != state_length(t)) {
            r->line = vals[key_index("n")].line;
            return fail(r, MBDK_ERR_INVALID_INPUT, "key 'n' = %d: the state of %d bodies%s and "
                        "the wear entries of the force table has %d values", t->n, t->nb,
                        planar ? "" : (t->rotation == MBDK_ROT_QUATERNION ? " (quaternions)" :
                                       " (angles)"), state_length(t));
        }
        status = parse_list(r, &KEYS[k], &vals[k], (int)arrays[i].count, arrays[i].d,
                            arrays[i].n);
        if (status) return status;
    }
    return 0;
}

int mbdk_scene_tables_read(const char *path, mbdk_scene_tables *tables, char *message,
                           int message_len)
{
    struct reader r = {path ? path : "(null)", message, message_len, 0};
    struct value vals[NKEYS];
    FILE *f;
    int status, i;
    if (message && message_len > 0) message[0] = 0;
    if (!tables) return fail(&r, MBDK_ERR_INVALID_INPUT, "no tables to read into (NULL)");
    memset(tables, 0, sizeof *tables);
    if (!path) return fail(&r, MBDK_ERR_INVALID_INPUT, "no file name (NULL)");
    f = fopen(path, "r");
    if (!f) return fail(&r, MBDK_ERR_INVALID_INPUT, "cannot open: %s", strerror(errno));
    memset(vals, 0, sizeof vals);
    status = read_lines(&r, f, vals);
    fclose(f);
    if (!status) {
        /* numbers in the "C" locale, for this thread only, whatever the host program set */
        locale_t c = newlocale(LC_NUMERIC_MASK, "C", (locale_t)0), old = (locale_t)0;
        if (c) old = uselocale(c);
        status = read_tables(&r, vals, tables);
        if (c) {
            uselocale(old);
            freelocale(c);
        }
    }
    for (i = 0; i < NKEYS; i++) free(vals[i].text);
    if (status) mbdk_scene_tables_free(tables);
    return status;
}

int mbdk_stepper_create_tables(const mbdk_scene_tables *t, int formulation,
                               const mbdk_options *opt, mbdk_stepper **stepper)
{
    if (stepper) *stepper = NULL;
    if (!t || !opt || !stepper || !t->mass || !t->y0) return MBDK_ERR_INVALID_INPUT;
    /* Baumgarte's gains as simulate's defaults, 1/h and sqrt(2)/h, for either kind */
    const double alpha = opt->h > 0 ? 1.0 / opt->h : 0.0;
    const double beta = opt->h > 0 ? sqrt(2.0) / opt->h : 0.0;
    if (t->kind == MBDK_SCENE_PLANAR) {
        mbdk_model_options mopt;
        mbdk_model_default_options(&mopt);
        if (formulation) mopt.formulation = formulation;
        if (opt->h > 0) {
            mopt.baumgarte_alpha = alpha;
            mopt.baumgarte_beta = beta;
        }
        return mbdk_stepper_create_scene(t->nb, t->mass, t->inertia, t->nj, t->jint, t->jreal,
                                         t->nf, t->fint, t->freal, &mopt, opt, t->t0, t->y0,
                                         stepper);
    }
    if (t->kind == MBDK_SCENE_SPATIAL) {
        mbdk_spatial_options sopt;
        mbdk_spatial_default_options(&sopt);
        if (formulation) sopt.formulation = formulation;
        if (opt->h > 0) {
            sopt.baumgarte_alpha = alpha;
            sopt.baumgarte_beta = beta;
        }
        sopt.rotation = t->rotation;
        sopt.norm = t->norm;
        sopt.norm_gain = t->norm_gain;
        return mbdk_stepper_create_spatial(t->nb, t->mass, t->inertia, t->nj, t->jtype, t->jbody,
                                           t->jreal, t->nf, t->ftype, t->fbody, t->freal, &sopt,
                                           opt, t->t0, t->y0, stepper);
    }
    return MBDK_ERR_INVALID_INPUT;
}
