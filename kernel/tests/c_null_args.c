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
    return mbdk_solve_ode(rhs, NULL, 1, 0.0, 1.0, which == 1 ? NULL : y0, which == 2 ? NULL : &opt,
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
    printf("%d checks, %d failed\n", checks, bad);
    return bad != 0;
}
