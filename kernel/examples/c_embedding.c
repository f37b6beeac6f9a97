/* c_embedding.c - a C program integrating its own ODE through libmbdk.
 *
 * The damped oscillator y'' + 2 zeta w y' + w^2 y = 0 with w and zeta passed through user_data,
 * integrated with rk4 and bdf4 at a fixed step and with dopri54, bdf and cvode_bdf by tolerance
 * (samples every 0.1 from their dense output); the result is compared with the analytic solution
 * (underdamped: y = e^{-zeta w t}(y0 cos(wd t) + (v0 + zeta w y0)/wd sin(wd t))).
 * A failing callback must come back as MBDK_ERR_CALLBACK_FAILED. Exit code 0 = pass.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "mbdk.h"

struct oscillator { double w, zeta; int calls; int fail_after; };

static int rhs(int n, double t, const double *y, double *dydt, void *user_data)
{
    struct oscillator *p = (struct oscillator *)user_data;
    (void)t; (void)n;
    p->calls++;
    if (p->fail_after > 0 && p->calls > p->fail_after) return 1;
    dydt[0] = y[1];
    dydt[1] = -2.0 * p->zeta * p->w * y[1] - p->w * p->w * y[0];
    return 0;
}

static double exact(const struct oscillator *p, double t, double y0, double v0)
{
    double wd = p->w * sqrt(1.0 - p->zeta * p->zeta);
    return exp(-p->zeta * p->w * t)
         * (y0 * cos(wd * t) + (v0 + p->zeta * p->w * y0) / wd * sin(wd * t));
}

static int run(const char *method, double h, double tol)
{
    struct oscillator p = {3.0, 0.1, 0, 0};
    double y0[2] = {1.0, 0.0};
    mbdk_options opt;
    mbdk_stats st;
    int nsamp, nw, status;
    char msg[128];

    mbdk_default_options(&opt);
    opt.method = mbdk_method_id(method);
    opt.h = h;
    opt.every = 10;
    if (opt.method == 0) { fprintf(stderr, "unknown method %s\n", method); return 1; }
    if (mbdk_sample_count(0.0, 5.0, h, opt.every, &nsamp) < 0) return 1;
    double *t = malloc(sizeof(double) * nsamp);
    double *y = malloc(sizeof(double) * 2 * nsamp);
    status = mbdk_solve_ode(rhs, NULL, &p, 2, 0.0, 5.0, y0, &opt, nsamp, t, y, &nw, &st);
    mbdk_status_message(status, msg, sizeof msg);
    double err = 0.0;
    for (int i = 0; i < nw; i++) {
        double e = fabs(y[2 * i] - exact(&p, t[i], y0[0], y0[1]));
        if (e > err) err = e;
    }
    printf("%-6s h=%g status=%d (%s) samples=%d steps=%lld rhs=%lld max|err|=%.3e\n", method,
           h, status, msg, nw, (long long)st.steps, (long long)st.nfev, err);
    int ok = status == MBDK_SUCCESS && nw == nsamp && err < tol && p.calls == st.nfev
             && fabs(t[nw - 1] - 5.0) < 1e-12;
    free(t); free(y);
    return ok ? 0 : 1;
}

/* An error-controlled method by name: rtol/atol and the sample spacing dt_out instead of h. */
static int run_tol(const char *method, double rtol, double tol)
{
    struct oscillator p = {3.0, 0.1, 0, 0};
    double y0[2] = {1.0, 0.0};
    mbdk_options opt;
    mbdk_stats st;
    int nsamp, nw, status;

    mbdk_default_options(&opt);
    opt.method = mbdk_method_id(method);
    opt.rtol = rtol;
    opt.atol = rtol * 1e-2;
    opt.dt_out = 0.1;
    if (opt.method == 0) { fprintf(stderr, "unknown method %s\n", method); return 1; }
    if (mbdk_solve_sample_count(0.0, 5.0, &opt, &nsamp) < 0 || nsamp != 51) return 1;
    double *t = malloc(sizeof(double) * nsamp);
    double *y = malloc(sizeof(double) * 2 * nsamp);
    status = mbdk_solve_ode(rhs, NULL, &p, 2, 0.0, 5.0, y0, &opt, nsamp, t, y, &nw, &st);
    double err = 0.0;
    for (int i = 0; i < nw; i++) {
        double e = fabs(y[2 * i] - exact(&p, t[i], y0[0], y0[1]));
        if (e > err) err = e;
    }
    printf("%-10s rtol=%g status=%d samples=%d steps=%lld rejected=%lld rhs=%lld max|err|=%.3e\n",
           method, rtol, status, nw, (long long)st.steps, (long long)st.rejected_steps,
           (long long)st.nfev, err);
    int ok = status == MBDK_SUCCESS && nw == nsamp && err < tol && st.steps > 10
             && fabs(t[nw - 1] - 5.0) == 0.0 && fabs(t[10] - 1.0) < 1e-12;
    free(t); free(y);
    return ok ? 0 : 1;
}

int main(void)
{
    int fails = 0;
    /* tolerances from the methods' error constants: rk4 ~ C h^4, bdf4 ~ C h^4 with C ~ 1 */
    fails += run("rk4", 1e-2, 1e-6);
    fails += run("bdf4", 1e-3, 1e-6);
    /* global error within a few hundred times the local tolerance (tests/test_adaptive.py) */
    fails += run_tol("dopri54", 1e-8, 3e-6);
    fails += run_tol("bdf", 1e-8, 3e-6);
    fails += run_tol("cvode_bdf", 1e-8, 3e-6);

    /* a callback that fails on its 5th call must stop the solve with a status, not a crash */
    struct oscillator p = {3.0, 0.1, 0, 4};
    double y0[2] = {1.0, 0.0}, t[64], y[128];
    mbdk_options opt;
    mbdk_stats st;
    int nw;
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("rk4");
    opt.h = 0.1;
    int status = mbdk_solve_ode(rhs, NULL, &p, 2, 0.0, 5.0, y0, &opt, 51, t, y, &nw, &st);
    printf("failing callback: status=%d samples=%d\n", status, nw);
    if (status != MBDK_ERR_CALLBACK_FAILED || nw != 2) fails++;

    /* bad input: unknown method id, negative step */
    opt.method = 999;
    if (mbdk_solve_ode(rhs, NULL, &p, 2, 0.0, 5.0, y0, &opt, 51, t, y, &nw, &st) != MBDK_ERR_UNKNOWN_METHOD) fails++;
    opt.method = mbdk_method_id("rk4");
    opt.h = -0.1;
    if (mbdk_solve_ode(rhs, NULL, &p, 2, 0.0, 5.0, y0, &opt, 51, t, y, &nw, &st) != MBDK_ERR_INVALID_INPUT) fails++;

    /* a tolerance no double can meet is refused before the first step */
    opt.h = 0.0;
    opt.method = mbdk_method_id("dopri54");
    opt.rtol = 1e-20;
    opt.atol = 0.0;
    if (mbdk_solve_ode(rhs, NULL, &p, 2, 0.0, 5.0, y0, &opt, 2, t, y, &nw, &st) != MBDK_ERR_INVALID_INPUT) fails++;

    printf(fails ? "FAIL\n" : "PASS\n");
    return fails ? 1 : 0;
}
