/* c_scene_file.c - a C program that runs a scene from its file: `mbdk tables SCENE -o FILE`
 * writes the scene's tables (the scene file read and checked by mbdk's reader), and the program
 * reads them with mbdk_scene_tables_read and steps them.
 *
 *   c_scene_file FILE METHOD H T_END [FORMULATION]
 *       steps the scene of FILE (planar or spatial) by METHOD (a fixed-step ODE method: rk4, heun,
 *       ..., on FORMULATION, 1 reduced .. 4 projection, 0 the default; or trapezoidal_index3, on 1
 *       index3 or 2 augmented_lagrangian) with step
 *       H to T_END and prints `final t y...` (every digit: %.17g). A bad file: its message on
 *       stderr, exit 2; a failed step: the status's message, exit 3.
 *   c_scene_file check FILE
 *       what meson runs, on the double pendulum's tables (kernel/examples/
 *       double_pendulum.tables.toml): the tables read have the scene's sizes, 1000 rk4 steps of
 *       1 ms keep the pendulum's energy (the pivot at the origin, gravity -9.81 y: to 1e-9 of
 *       its swing), and bad files fail by name: a missing file, a value that is no number, a
 *       list one value short, an unknown key.
 * Exit code 0 = pass.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "mbdk.h"

static int failures = 0;

static void check(int ok, const char *what)
{
    if (!ok) {
        printf("FAIL: %s\n", what);
        failures++;
    }
}

static int run(const char *path, const char *method, double h, double t_end, int formulation,
               int print)
{
    mbdk_scene_tables sc;
    mbdk_stepper *s = NULL;
    char msg[512];
    double t, *y;
    int status, i;
    status = mbdk_scene_tables_read(path, &sc, msg, sizeof msg);
    if (status != MBDK_SUCCESS) {
        fprintf(stderr, "%s\n", msg);
        return 2;
    }
    if (strcmp(method, "trapezoidal_index3") == 0) {
        mbdk_index3_options opt;
        mbdk_index3_default_options(&opt);
        opt.h = h;
        if (formulation) opt.formulation = formulation;   /* 1 index3, 2 augmented */
        if (sc.kind == MBDK_SCENE_PLANAR)
            status = mbdk_stepper_create_index3(sc.nb, sc.mass, sc.inertia, sc.nj, sc.jint,
                                                sc.jreal, sc.nf, sc.fint, sc.freal, &opt, sc.t0,
                                                sc.y0, &s);
        else {
            mbdk_spatial_options so;
            mbdk_spatial_default_options(&so);
            so.rotation = sc.rotation;
            so.norm = sc.norm;
            so.norm_gain = sc.norm_gain;
            status = mbdk_stepper_create_spatial_index3(sc.nb, sc.mass, sc.inertia, sc.nj,
                                                        sc.jtype, sc.jbody, sc.jreal, sc.nf,
                                                        sc.ftype, sc.fbody, sc.freal, &so, &opt,
                                                        sc.t0, sc.y0, &s);
        }
    } else {
        mbdk_options opt;
        mbdk_default_options(&opt);
        opt.method = mbdk_method_id(method);
        opt.h = h;
        status = mbdk_stepper_create_tables(&sc, formulation, &opt, &s);
    }
    if (status == MBDK_SUCCESS) status = mbdk_stepper_advance(s, t_end);
    y = malloc(sizeof(double) * (size_t)sc.n);
    if (status == MBDK_SUCCESS && !y) status = MBDK_ERR_NO_MEMORY;
    if (status == MBDK_SUCCESS) status = mbdk_stepper_state(s, &t, y, sc.n);
    if (status == MBDK_SUCCESS && print) {
        printf("final %.17g", t);
        for (i = 0; i < sc.n; i++) printf(" %.17g", y[i]);
        printf("\n");
    }
    if (status != MBDK_SUCCESS) {
        mbdk_status_message(status, msg, sizeof msg);
        fprintf(stderr, "%s: %s\n", method, msg);
    }
    free(y);
    mbdk_stepper_destroy(s);
    mbdk_scene_tables_free(&sc);
    return status == MBDK_SUCCESS ? 0 : 3;
}

/* the double pendulum's energy: bars of length 1 (bar 1) and 2 (bar 2), y up */
static double energy(const mbdk_scene_tables *sc, const double *y)
{
    double e = 0.0;
    int b;
    for (b = 0; b < sc->nb; b++) {
        const double *v = y + 3 * sc->nb + 3 * b;
        e += 0.5 * sc->mass[b] * (v[0] * v[0] + v[1] * v[1]) + 0.5 * sc->inertia[b] * v[2] * v[2]
             + sc->mass[b] * 9.81 * y[3 * b + 1];
    }
    return e;
}

/* a copy of the file at path with line `key = ...` replaced by `line` (or removed: NULL) and
 * `extra` appended; returns the copy's name */
static const char *altered(const char *path, const char *key, const char *line, const char *extra)
{
    static const char *name = "c_scene_file_bad.toml";
    char buf[65536];
    FILE *in = fopen(path, "r"), *out = fopen(name, "w");
    size_t n = strlen(key);
    if (!in || !out) {
        if (in) fclose(in);
        if (out) fclose(out);
        return "";
    }
    while (fgets(buf, sizeof buf, in)) {
        if (strncmp(buf, key, n) == 0 && buf[n] == ' ') {
            if (line) fprintf(out, "%s\n", line);
        } else {
            fputs(buf, out);
        }
    }
    if (extra) fprintf(out, "%s\n", extra);
    fclose(in);
    fclose(out);
    return name;
}

static void expect_error(const char *path, const char *what, const char *w1, const char *w2)
{
    mbdk_scene_tables sc;
    char msg[512], label[600];
    int status = mbdk_scene_tables_read(path, &sc, msg, sizeof msg);
    snprintf(label, sizeof label, "%s: refused naming '%s' and '%s' (got %d: %s)", what, w1, w2,
             status, msg);
    check(status == MBDK_ERR_INVALID_INPUT && strstr(msg, path) && strstr(msg, w1) &&
          strstr(msg, w2) && sc.mass == NULL, label);
}

static int self_check(const char *path)
{
    mbdk_scene_tables sc;
    mbdk_options opt;
    mbdk_stepper *s = NULL;
    char msg[512];
    double t, y[12], e0, e1;
    int status = mbdk_scene_tables_read(path, &sc, msg, sizeof msg);
    check(status == MBDK_SUCCESS, msg);
    if (status != MBDK_SUCCESS) return 1;
    check(sc.kind == MBDK_SCENE_PLANAR && sc.nb == 2 && sc.nj == 2 && sc.n == 12 &&
          strcmp(sc.name, "double_pendulum") == 0, "the double pendulum's sizes");
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("rk4");
    opt.h = 1e-3;
    check(mbdk_stepper_create_tables(&sc, MBDK_FORM_PROJECTION, &opt, &s) == MBDK_SUCCESS,
          "stepper created from the tables");
    e0 = energy(&sc, sc.y0);
    check(mbdk_stepper_advance(s, 1.0) == MBDK_SUCCESS, "1000 rk4 steps");
    check(mbdk_stepper_state(s, &t, y, 12) == MBDK_SUCCESS && t == 1.0, "at t = 1");
    e1 = energy(&sc, y);
    /* the swing's energy scale: m g L of the heavier bar */
    check(fabs(e1 - e0) < 1e-9 * 2.0 * 9.81 * 2.0, "energy kept");
    mbdk_stepper_destroy(s);
    mbdk_scene_tables_free(&sc);
    check(sc.mass == NULL && sc.y0 == NULL, "freed");

    expect_error("no_such_file.toml", "a missing file", "cannot open", "No such file");
    expect_error(altered(path, "mass", "mass = [1.0, 2.0x]", NULL), "a value that is no number",
                 "mass", "2.0x");
    expect_error(altered(path, "y0", "y0 = [0.0]", NULL), "a list one value short", "y0",
                 "12 expected");
    expect_error(altered(path, "nb", NULL, "bodies = 2"), "an unknown key", "line",
                 "bodies");
    expect_error(altered(path, "format", "format = \"other\"", NULL), "another format",
                 "format", "other");
    remove("c_scene_file_bad.toml");
    printf("%s\n", failures ? "FAILED" : "all checks passed");
    return failures ? 1 : 0;
}

int main(int argc, char **argv)
{
    if (argc == 3 && strcmp(argv[1], "check") == 0) return self_check(argv[2]);
    if (argc == 5 || argc == 6)
        return run(argv[1], argv[2], atof(argv[3]), atof(argv[4]), argc == 6 ? atoi(argv[5]) : 0,
                   1);
    fprintf(stderr, "usage: c_scene_file FILE METHOD H T_END [FORMULATION] | "
                    "c_scene_file check FILE\n");
    return 2;
}
