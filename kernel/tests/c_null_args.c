/* Every pointer argument of every entry of mbdk.h, NULL in turn: the entry must return
 * MBDK_ERR_INVALID_INPUT (mbdk_method_id: 0; the default-options setters: nothing) and never
 * crash. The same calls with every pointer valid must succeed, so that the refusals come from
 * the NULL and not from the rest of the call. Exit code 0 = pass. */
#include <stdio.h>
#include <string.h>
#include "mbdk.h"

static int rhs(int n, double t, const double *y, double *dydt, void *user_data)
{
    (void)t; (void)user_data;
    for (int i = 0; i < n; i++) dydt[i] = -y[i];
    return 0;
}

/* a 1 m, 1 kg bar hinged at the origin under gravity (tables as in c_index3.c) */
static const double mass[1] = {1.0}, inertia[1] = {1.0 / 12.0};
static const int jint[1][4] = {{1, 1, 0, 0}};
static const double jreal[1][12] = {{-0.5, 0, 0, 0, 1, 0}};
static const int fint[1][4] = {{1, 0, 0, 0}};
static const double freal[1][12] = {{0.0, -9.81}};
static const double yp[6] = {0.5, 0.0, 0.0, 0.0, 0.0, 0.0};

static int bad = 0, checks = 0;

static void expect(const char *what, int got, int want)
{
    checks++;
    if (got != want) { printf("%s: status %d, expected %d\n", what, got, want); bad++; }
}

static int solve_ode(int which)
{
    mbdk_options opt;
    mbdk_stats st;
    double y0[1] = {1.0}, t[11], y[11];
    int nw;
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("rk4");
    opt.h = 0.1;
    return mbdk_solve_ode(rhs, NULL, NULL, 1, 0.0, 1.0, which == 1 ? NULL : y0, which == 2 ? NULL : &opt,
                          11, which == 3 ? NULL : t, which == 4 ? NULL : y,
                          which == 5 ? NULL : &nw, which == 6 ? NULL : &st);
}

static int solve_index3(int which)
{
    mbdk_index3_options opt;
    mbdk_stats st;
    double t[11], y[66], a[33], lam[22];
    int it[11], nw;
    mbdk_index3_default_options(&opt);
    opt.formulation = MBDK_INDEX3_AUGMENTED;
    opt.h = 0.01;
    return mbdk_index3_solve(1, which == 1 ? NULL : mass, which == 2 ? NULL : inertia, 1,
                             which == 3 ? NULL : &jint[0][0], which == 4 ? NULL : &jreal[0][0], 1,
                             which == 5 ? NULL : &fint[0][0], which == 6 ? NULL : &freal[0][0],
                             which == 7 ? NULL : &opt, 0.0, 0.1, which == 8 ? NULL : yp, 11,
                             which == 9 ? NULL : t, which == 10 ? NULL : y,
                             which == 11 ? NULL : a, which == 12 ? NULL : lam,
                             which == 13 ? NULL : it, which == 14 ? NULL : &nw,
                             which == 15 ? NULL : &st);
}

int main(void)
{
    char buf[64], msg[32];
    int code, n1, n2, nsamp;
    mbdk_index3_options o3;
    mbdk_index3_default_options(&o3);

    expect("solve_ode, all valid", solve_ode(0), MBDK_SUCCESS);
    for (int k = 1; k <= 6; k++) {
        snprintf(msg, sizeof msg, "solve_ode, NULL #%d", k);
        expect(msg, solve_ode(k), MBDK_ERR_INVALID_INPUT);
    }
    expect("index3_solve, all valid", solve_index3(0), MBDK_SUCCESS);
    for (int k = 1; k <= 15; k++) {
        snprintf(msg, sizeof msg, "index3_solve, NULL #%d", k);
        expect(msg, solve_index3(k), MBDK_ERR_INVALID_INPUT);
    }
    mbdk_default_options(NULL);
    mbdk_index3_default_options(NULL);
    mbdk_model_default_options(NULL);
    expect("method_id(NULL)", mbdk_method_id(NULL), 0);
    expect("sample_count, nsamp NULL", mbdk_sample_count(0, 1, 0.1, 1, NULL), MBDK_ERR_INVALID_INPUT);
    expect("sample_count", mbdk_sample_count(0, 1, 0.1, 1, &nsamp), MBDK_SUCCESS);
    expect("index3_sample_count, opt NULL", mbdk_index3_sample_count(NULL, 0, 1, &nsamp),
           MBDK_ERR_INVALID_INPUT);
    expect("index3_sample_count, nsamp NULL", mbdk_index3_sample_count(&o3, 0, 1, NULL),
           MBDK_ERR_INVALID_INPUT);
    expect("status_message, buf NULL", mbdk_status_message(0, NULL, 10), MBDK_ERR_INVALID_INPUT);
    expect("status_message", mbdk_status_message(0, buf, sizeof buf), MBDK_SUCCESS);
    expect("status_entry, code NULL", mbdk_status_entry(1, NULL, buf, sizeof buf), MBDK_ERR_INVALID_INPUT);
    expect("status_entry, name NULL", mbdk_status_entry(1, &code, NULL, 10), MBDK_ERR_INVALID_INPUT);
    expect("struct_info, name NULL", mbdk_struct_info(1, NULL, 10, &n1, &n2), MBDK_ERR_INVALID_INPUT);
    expect("struct_info, nbytes NULL", mbdk_struct_info(1, buf, sizeof buf, NULL, &n2), MBDK_ERR_INVALID_INPUT);
    expect("struct_info, nfields NULL", mbdk_struct_info(1, buf, sizeof buf, &n1, NULL), MBDK_ERR_INVALID_INPUT);
    expect("struct_field, name NULL", mbdk_struct_field(1, 1, NULL, 10, &n1, &n2), MBDK_ERR_INVALID_INPUT);
    expect("struct_field, offset NULL", mbdk_struct_field(1, 1, buf, sizeof buf, NULL, &n2), MBDK_ERR_INVALID_INPUT);
    expect("struct_field, type NULL", mbdk_struct_field(1, 1, buf, sizeof buf, &n1, NULL), MBDK_ERR_INVALID_INPUT);
    {
        mbdk_options opt;
        mbdk_model_options mopt;
        mbdk_model_default_options(&mopt);   /* the reduced formulation */
        mbdk_stepper *s = NULL, *sc = NULL, *s3 = NULL;
        mbdk_stats st;
        double y0[1] = {1.0}, t, y[6], lam[2];
        int n, m;
        mbdk_watch_report report;
        /* a spatial pendulum: one body on a spherical joint at the origin, hanging, at rest */
        mbdk_spatial_options so;
        mbdk_index3_options i3;
        mbdk_stepper *ss = NULL;
        const double smass[1] = {1.0}, sinertia[9] = {0.1, 0, 0, 0, 0.1, 0, 0, 0, 0.1};
        const int sjtype[1] = {MBDK_JOINT_SPHERICAL}, sjbody[2] = {1, 0};
        double sjreal[MBDK_SPATIAL_JOINT_REALS] = {0, 0, 0.5}, sfreal[MBDK_SPATIAL_FORCE_REALS] = {0, 0, -9.81};
        const int sftype[1] = {MBDK_FORCE_GRAVITY}, sfbody[2] = {1, 0};
        const double sy0[13] = {0, 0, -0.5, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0};
        mbdk_spatial_default_options(&so);
        mbdk_index3_default_options(&i3);
        i3.h = 0.01;
        mbdk_default_options(&opt);
        opt.method = mbdk_method_id("rk4");
        opt.h = 0.1;
        expect("stepper_create_ode, f NULL", mbdk_stepper_create_ode(NULL, NULL, NULL, 1, 0, y0, &opt, &s), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_ode, y0 NULL", mbdk_stepper_create_ode(rhs, NULL, NULL, 1, 0, NULL, &opt, &s), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_ode, opt NULL", mbdk_stepper_create_ode(rhs, NULL, NULL, 1, 0, y0, NULL, &s), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_ode", mbdk_stepper_create_ode(rhs, NULL, NULL, 1, 0, y0, &opt, &s), MBDK_SUCCESS);
        expect("stepper_create_scene, mass NULL", mbdk_stepper_create_scene(1, NULL, inertia, 1, &jint[0][0], &jreal[0][0], 1, &fint[0][0], &freal[0][0], &mopt, &opt, 0, yp, &sc), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_scene, jint NULL", mbdk_stepper_create_scene(1, mass, inertia, 1, NULL, &jreal[0][0], 1, &fint[0][0], &freal[0][0], &mopt, &opt, 0, yp, &sc), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_scene, model options NULL", mbdk_stepper_create_scene(1, mass, inertia, 1, &jint[0][0], &jreal[0][0], 1, &fint[0][0], &freal[0][0], NULL, &opt, 0, yp, &sc), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_scene", mbdk_stepper_create_scene(1, mass, inertia, 1, &jint[0][0], &jreal[0][0], 1, &fint[0][0], &freal[0][0], &mopt, &opt, 0, yp, &sc), MBDK_SUCCESS);
        expect("stepper_create_index3, opt NULL", mbdk_stepper_create_index3(1, mass, inertia, 1, &jint[0][0], &jreal[0][0], 1, &fint[0][0], &freal[0][0], NULL, 0, yp, &s3), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_index3, inertia NULL", mbdk_stepper_create_index3(1, mass, NULL, 1, &jint[0][0], &jreal[0][0], 1, &fint[0][0], &freal[0][0], &o3, 0, yp, &s3), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_index3, y0 NULL", mbdk_stepper_create_index3(1, mass, inertia, 1, &jint[0][0], &jreal[0][0], 1, &fint[0][0], &freal[0][0], &o3, 0, NULL, &s3), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_index3, handle NULL", mbdk_stepper_create_index3(1, mass, inertia, 1, &jint[0][0], &jreal[0][0], 1, &fint[0][0], &freal[0][0], &o3, 0, yp, NULL), MBDK_ERR_INVALID_INPUT);
        expect("stepper_state, t NULL", mbdk_stepper_state(s, NULL, y, 1), MBDK_ERR_INVALID_INPUT);
        expect("stepper_state, y NULL", mbdk_stepper_state(s, &t, NULL, 1), MBDK_ERR_INVALID_INPUT);
        expect("stepper_state, handle NULL", mbdk_stepper_state(NULL, &t, y, 1), MBDK_ERR_INVALID_INPUT);
        expect("stepper_size, n NULL", mbdk_stepper_size(s, NULL, &m), MBDK_ERR_INVALID_INPUT);
        expect("stepper_size, m NULL", mbdk_stepper_size(s, &n, NULL), MBDK_ERR_INVALID_INPUT);
        expect("stepper_stats, NULL", mbdk_stepper_stats(s, NULL), MBDK_ERR_INVALID_INPUT);
        expect("stepper_watch_report, NULL", mbdk_stepper_watch_report(sc, NULL), MBDK_ERR_INVALID_INPUT);
        expect("stepper_watch_report, handle NULL", mbdk_stepper_watch_report(NULL, &report), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_spatial, mass NULL", mbdk_stepper_create_spatial(1, NULL, sinertia, 1, sjtype, sjbody, sjreal, 1, sftype, sfbody, sfreal, &so, &opt, 0, sy0, &ss), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_spatial, jbody NULL", mbdk_stepper_create_spatial(1, smass, sinertia, 1, sjtype, NULL, sjreal, 1, sftype, sfbody, sfreal, &so, &opt, 0, sy0, &ss), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_spatial, freal NULL", mbdk_stepper_create_spatial(1, smass, sinertia, 1, sjtype, sjbody, sjreal, 1, sftype, sfbody, NULL, &so, &opt, 0, sy0, &ss), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_spatial, spatial options NULL", mbdk_stepper_create_spatial(1, smass, sinertia, 1, sjtype, sjbody, sjreal, 1, sftype, sfbody, sfreal, NULL, &opt, 0, sy0, &ss), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_spatial, options NULL", mbdk_stepper_create_spatial(1, smass, sinertia, 1, sjtype, sjbody, sjreal, 1, sftype, sfbody, sfreal, &so, NULL, 0, sy0, &ss), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_spatial, y0 NULL", mbdk_stepper_create_spatial(1, smass, sinertia, 1, sjtype, sjbody, sjreal, 1, sftype, sfbody, sfreal, &so, &opt, 0, NULL, &ss), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_spatial, handle NULL", mbdk_stepper_create_spatial(1, smass, sinertia, 1, sjtype, sjbody, sjreal, 1, sftype, sfbody, sfreal, &so, &opt, 0, sy0, NULL), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_spatial_index3, options NULL", mbdk_stepper_create_spatial_index3(1, smass, sinertia, 1, sjtype, sjbody, sjreal, 1, sftype, sfbody, sfreal, &so, NULL, 0, sy0, &ss), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_spatial_index3, spatial options NULL", mbdk_stepper_create_spatial_index3(1, smass, sinertia, 1, sjtype, sjbody, sjreal, 1, sftype, sfbody, sfreal, NULL, &i3, 0, sy0, &ss), MBDK_ERR_INVALID_INPUT);
        expect("a refused spatial create leaves a NULL handle", ss == NULL, 1);
        expect("stepper_create_spatial_index3", mbdk_stepper_create_spatial_index3(1, smass, sinertia, 1, sjtype, sjbody, sjreal, 1, sftype, sfbody, sfreal, &so, &i3, 0, sy0, &ss), MBDK_SUCCESS);
        expect("spatial stepper_watch_report, NULL", mbdk_stepper_watch_report(ss, NULL), MBDK_ERR_INVALID_INPUT);
        expect("spatial stepper_multipliers, lam NULL", mbdk_stepper_multipliers(ss, NULL, 3), MBDK_ERR_INVALID_INPUT);
        {
            double out[MBDK_STEPPER_NOUT], rc[3];
            mbdk_stepper *copy = NULL;
            expect("stepper_outputs, out NULL", mbdk_stepper_outputs(ss, NULL, MBDK_STEPPER_NOUT), MBDK_ERR_INVALID_INPUT);
            expect("stepper_outputs, handle NULL", mbdk_stepper_outputs(NULL, out, MBDK_STEPPER_NOUT), MBDK_ERR_INVALID_INPUT);
            expect("stepper_outputs, nout wrong", mbdk_stepper_outputs(ss, out, 4), MBDK_ERR_INVALID_INPUT);
            expect("stepper_outputs", mbdk_stepper_outputs(ss, out, MBDK_STEPPER_NOUT), MBDK_SUCCESS);
            expect("stepper_outputs, the hanging body's kinetic energy", out[0] == 0.0, 1);
            expect("stepper_reactions on a spatial stepper", mbdk_stepper_reactions(ss, rc, 1), MBDK_ERR_NOT_APPLICABLE);
            expect("stepper_set_force on gravity", mbdk_stepper_set_force(ss, 1, 1, 1.0), MBDK_ERR_INVALID_INPUT);
            expect("stepper_set_force, entry 0", mbdk_stepper_set_force(ss, 0, 1, 1.0), MBDK_ERR_INVALID_INPUT);
            expect("stepper_set_force, handle NULL", mbdk_stepper_set_force(NULL, 1, 1, 1.0), MBDK_ERR_INVALID_INPUT);
            expect("stepper_copy, dst NULL", mbdk_stepper_copy(ss, NULL), MBDK_ERR_INVALID_INPUT);
            expect("stepper_copy, src NULL", mbdk_stepper_copy(NULL, &copy), MBDK_ERR_INVALID_INPUT);
            expect("stepper_copy", mbdk_stepper_copy(ss, &copy), MBDK_SUCCESS);
            expect("stepper_copy onto a stepper of another kind", mbdk_stepper_copy(ss, &s), MBDK_ERR_INVALID_INPUT);
            expect("the copy steps", mbdk_stepper_step(copy), MBDK_SUCCESS);
            mbdk_stepper_destroy(copy);
        }
        mbdk_stepper_destroy(ss);
        expect("stepper_multipliers, lam NULL", mbdk_stepper_multipliers(sc, NULL, 2), MBDK_ERR_INVALID_INPUT);
        expect("stepper_multipliers", mbdk_stepper_multipliers(sc, lam, 2), MBDK_SUCCESS);
        expect("stepper_advance, handle NULL", mbdk_stepper_advance(NULL, 1.0), MBDK_ERR_INVALID_INPUT);
        expect("stepper_stats", mbdk_stepper_stats(s, &st), MBDK_SUCCESS);
        mbdk_stepper_destroy(s);
        mbdk_stepper_destroy(sc);
        expect("a refused create leaves a NULL handle", s3 == NULL, 1);
        /* counts far beyond the arrays: refused before any size is computed from them (12 nj
         * would overflow an int), not read out of bounds */
        expect("stepper_create_scene, nj huge", mbdk_stepper_create_scene(1, mass, inertia, 2000000000, &jint[0][0], &jreal[0][0], 1, &fint[0][0], &freal[0][0], &mopt, &opt, 0, yp, &s3), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_scene, nf huge", mbdk_stepper_create_scene(1, mass, inertia, 1, &jint[0][0], &jreal[0][0], 2000000000, &fint[0][0], &freal[0][0], &mopt, &opt, 0, yp, &s3), MBDK_ERR_INVALID_INPUT);
    }
    {   /* the tables file's reader and its stepper: NULL anywhere is refused, nothing kept */
        mbdk_scene_tables t;
        mbdk_stepper *s4 = NULL;
        mbdk_options o;
        char msg[256];
        mbdk_default_options(&o);
        o.method = mbdk_method_id("rk4");
        o.h = 1e-3;
        expect("scene_tables_read, path NULL", mbdk_scene_tables_read(NULL, &t, msg, sizeof msg), MBDK_ERR_INVALID_INPUT);
        expect("scene_tables_read, tables NULL", mbdk_scene_tables_read("x.toml", NULL, msg, sizeof msg), MBDK_ERR_INVALID_INPUT);
        expect("scene_tables_read, message NULL", mbdk_scene_tables_read("no_such.toml", &t, NULL, 0), MBDK_ERR_INVALID_INPUT);
        expect("scene_tables_read, no arrays after a failure", t.mass == NULL && t.y0 == NULL, 1);
        mbdk_scene_tables_free(NULL);
        expect("stepper_create_tables, tables NULL", mbdk_stepper_create_tables(NULL, 0, &o, &s4), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_tables, empty tables", mbdk_stepper_create_tables(&t, 0, &o, &s4), MBDK_ERR_INVALID_INPUT);
        expect("stepper_create_tables, handle NULL", mbdk_stepper_create_tables(&t, 0, &o, NULL), MBDK_ERR_INVALID_INPUT);
        expect("a refused create_tables leaves a NULL handle", s4 == NULL, 1);
    }
    printf("%d checks, %d failed\n", checks, bad);
    return bad != 0;
}
