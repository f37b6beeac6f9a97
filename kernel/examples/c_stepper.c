/* c_stepper.c - a C program driving libmbdk's stepper one step, or one time, at a time.
 *
 * 1. The damped oscillator y'' + 2 zeta w y' + w^2 y = 0 stepped by rk4: the stepper's state
 *    after 500 steps equals mbdk_solve_ode's final state bit for bit (same grid, same step
 *    routine), and an advance to an off-grid time agrees with the analytic solution.
 * 2. A stiff linear system y' = A y (eigenvalues -1 and -1000) by bdf2 with the analytic
 *    Jacobian callback: the same answer as finite differences (to the Newton tolerance) with
 *    fewer evaluations of F, and within 1e-4 of exp(A t) y0.
 * 3. A scene: a 1 m, 1 kg bar hanging straight down from a hinge at rest (static equilibrium,
 *    reduced formulation, rk4): it stays there, and the hinge's multipliers carry the bar's
 *    weight, |lambda| = (0, m g) (the joint force -D^T lambda balances gravity).
 * 4. trapezoidal_index3 stepped on the double pendulum (the tables of c_index3.c), both forms:
 *    after 1000 steps the state and the multipliers equal mbdk_index3_solve's bit for bit.
 * 5. Failures: a right-hand side that fails at its 41st call stops the stepper with
 *    MBDK_ERR_CALLBACK_FAILED, the last good state (t = 1.0) stays readable, and further steps
 *    are refused; an interrupt flag set before an advance stops it with MBDK_ERR_INTERRUPTED.
 * Exit code 0 = pass.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "mbdk.h"

static const double PI = 3.14159265358979323846;

struct oscillator { double w, zeta; int calls, fail_after; };

static int osc(int n, double t, const double *y, double *dydt, void *user_data)
{
    struct oscillator *p = user_data;
    (void)t; (void)n;
    if (p->fail_after > 0 && ++p->calls > p->fail_after) return 1;
    dydt[0] = y[1];
    dydt[1] = -2.0 * p->zeta * p->w * y[1] - p->w * p->w * y[0];
    return 0;
}

static const double A[2][2] = {{-500.5, 499.5}, {499.5, -500.5}};   /* eigenvalues -1, -1000 */

static int lin(int n, double t, const double *y, double *dydt, void *user_data)
{
    int *calls = user_data;
    (void)t; (void)n;
    ++*calls;
    dydt[0] = A[0][0] * y[0] + A[0][1] * y[1];
    dydt[1] = A[1][0] * y[0] + A[1][1] * y[1];
    return 0;
}

static int lin_jac(int n, double t, const double *y, double *dfdy, void *user_data)
{
    (void)t; (void)y; (void)user_data;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) dfdy[i + j * n] = A[i][j];
    return 0;
}

static int fails = 0;
static void check(int ok, const char *what)
{
    printf("%s: %s\n", ok ? "ok  " : "FAIL", what);
    if (!ok) fails++;
}

static void oscillator_matches_solve_ode(void)
{
    struct oscillator p = {3.0, 0.1, 0, 0};
    double y0[2] = {1.0, 0.0}, t_out[2], y_out[4], t, y[2];
    int nw;
    mbdk_options opt;
    mbdk_stats st;
    mbdk_stepper *s = NULL;
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("rk4");
    opt.h = 0.01;
    opt.every = 500;
    mbdk_solve_ode(osc, NULL, &p, 2, 0.0, 5.0, y0, &opt, 2, t_out, y_out, &nw, &st);
    check(mbdk_stepper_create_ode(osc, NULL, &p, 2, 0.0, y0, &opt, &s) == MBDK_SUCCESS,
          "create an ode stepper");
    for (int k = 0; k < 500; k++) mbdk_stepper_step(s);
    mbdk_stepper_state(s, &t, y, 2);
    check(t == 5.0 && y[0] == y_out[2] && y[1] == y_out[3],
          "500 steps = mbdk_solve_ode's final state, bit for bit");
    check(mbdk_stepper_advance(s, 5.1234) == MBDK_SUCCESS, "advance to an off-grid time");
    mbdk_stepper_state(s, &t, y, 2);
    double wd = 3.0 * sqrt(1.0 - 0.01), ex = exp(-0.3 * t) * (cos(wd * t) + 0.3 / wd * sin(wd * t));
    check(t == 5.1234 && fabs(y[0] - ex) < 1e-8, "lands on t, within 1e-8 of the exact solution");
    mbdk_stepper_stats(s, &st);
    check(st.steps == 513 && st.nfev == 4 * 513, "steps and evaluations counted");
    check(mbdk_stepper_state(s, &t, y, 3) == MBDK_ERR_INVALID_INPUT, "wrong state size refused");
    mbdk_stepper_destroy(s);
}

static void stiff_with_jacobian(void)
{
    double y0[2] = {1.0, 0.0}, ya[2], yf[2], t;
    int calls_a = 0, calls_f = 0;
    mbdk_options opt;
    mbdk_stats sa, sf;
    mbdk_stepper *a = NULL, *f = NULL;
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("bdf2");
    opt.h = 1e-3;
    opt.startup = MBDK_STARTUP_BDF;
    mbdk_stepper_create_ode(lin, lin_jac, &calls_a, 2, 0.0, y0, &opt, &a);
    mbdk_stepper_create_ode(lin, NULL, &calls_f, 2, 0.0, y0, &opt, &f);
    check(mbdk_stepper_advance(a, 1.0) == MBDK_SUCCESS && mbdk_stepper_advance(f, 1.0) == MBDK_SUCCESS,
          "bdf2 on the stiff system, analytic and finite-difference Jacobians");
    mbdk_stepper_state(a, &t, ya, 2);
    mbdk_stepper_state(f, &t, yf, 2);
    /* exp(A t) y0: (1, 0) = ((1,1) + (1,-1))/2 -> (e^-t (1,1) + e^-1000t (1,-1))/2 */
    double e = 0.5 * exp(-1.0);
    check(fabs(ya[0] - e) < 1e-4 && fabs(ya[1] - e) < 1e-4, "within 1e-4 of exp(A t) y0");
    check(fabs(ya[0] - yf[0]) < 1e-8 && fabs(ya[1] - yf[1]) < 1e-8, "both Jacobians agree");
    mbdk_stepper_stats(a, &sa);
    mbdk_stepper_stats(f, &sf);
    check(sa.njev > 0 && calls_a == sa.nfev && sa.nfev < sf.nfev,
          "the analytic Jacobian saves evaluations of F");
    printf("      nfev %lld (analytic) vs %lld (finite differences)\n", (long long)sa.nfev,
           (long long)sf.nfev);
    mbdk_stepper_destroy(a);
    mbdk_stepper_destroy(f);
}

static void hanging_bar(void)
{
    const double mass[1] = {1.0}, inertia[1] = {1.0 / 12.0};
    const int jint[4] = {1, 1, 0, 0};                     /* revolute, bar - ground */
    const double jreal[12] = {0.5, 0.0, 0.0, 0.0, 1, 0};  /* bar point (0.5, 0) at the origin */
    const int fint[4] = {1, 0, 0, 0};                     /* gravity */
    const double freal[12] = {0.0, -9.81};
    const double y0[6] = {0.0, -0.5, PI / 2, 0, 0, 0};  /* bar along -y, its +x end up */
    double y[6], lam[2], t;
    int n, m;
    mbdk_options opt;
    mbdk_model_options mopt;
    mbdk_model_default_options(&mopt);   /* the reduced formulation */
    mbdk_stepper *s = NULL;
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("rk4");
    opt.h = 1e-3;
    check(mbdk_stepper_create_scene(1, mass, inertia, 1, jint, jreal, 1, fint, freal, &mopt, &opt,
                                    0.0, y0, &s) == MBDK_SUCCESS, "create a scene stepper");
    mbdk_stepper_size(s, &n, &m);
    check(n == 6 && m == 2, "state size 6, two constraint rows");
    check(mbdk_stepper_advance(s, 1.0) == MBDK_SUCCESS, "advance the scene to t = 1");
    mbdk_stepper_state(s, &t, y, 6);
    check(fabs(y[0]) < 1e-12 && fabs(y[1] + 0.5) < 1e-12 && fabs(y[2] - PI / 2) < 1e-12,
          "the hanging bar stays at rest");
    check(mbdk_stepper_multipliers(s, lam, 2) == MBDK_SUCCESS && fabs(lam[0]) < 1e-9
          && fabs(fabs(lam[1]) - 9.81) < 1e-9, "the hinge carries the weight m g");
    mbdk_stepper_destroy(s);
}

/* The same bar released horizontally, explicit Euler at h = 0.01: the reduced formulation
 * drifts off its hinge, and the watch (on by default) stops the stepper at the check where it
 * left the tolerance; the report says which quantity, when, and the last good time. */
static void drifting_bar_is_stopped_by_the_watch(void)
{
    const double mass[1] = {1.0}, inertia[1] = {1.0 / 12.0};
    const int jint[4] = {1, 1, 0, 0};
    const double jreal[12] = {0.5, 0.0, 0.0, 0.0, 1, 0};
    const int fint[4] = {1, 0, 0, 0};
    const double freal[12] = {0.0, -9.81};
    const double y0[6] = {-0.5, 0.0, 0.0, 0, 0, 0};       /* bar along -x from the hinge */
    double t, y[6];
    mbdk_watch_report report;
    mbdk_options opt;
    mbdk_model_options mopt;
    mbdk_stepper *s = NULL;
    int status;
    mbdk_model_default_options(&mopt);
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("explicit_euler");
    opt.h = 1e-2;
    check(mbdk_stepper_create_scene(1, mass, inertia, 1, jint, jreal, 1, fint, freal, &mopt, &opt,
                                    0.0, y0, &s) == MBDK_SUCCESS, "create a drifting stepper");
    status = mbdk_stepper_advance(s, 20.0);
    check(status == MBDK_ERR_CONSTRAINT_DRIFT || status == MBDK_ERR_ENERGY_DRIFT,
          "explicit Euler's drift stops the run with a drift status");
    check(mbdk_stepper_watch_report(s, &report) == MBDK_SUCCESS && report.quantity >= 1
          && report.quantity <= 3 && report.t > report.t_good && report.value > report.tol,
          "the report: quantity, value above tolerance, failed after the last good check");
    mbdk_stepper_state(s, &t, y, 6);
    check(t == report.t_good || t < report.t, "the state readable is the last good one");
    printf("      stopped: quantity %d at t = %g (last good %g), %g of its scale\n",
           report.quantity, report.t, report.t_good, report.value);
    mbdk_stepper_destroy(s);
}

static void index3_matches_the_solve(int formulation)
{
    static const double mass[2] = {1.0, 2.0};
    static const double inertia[2] = {1.0 / 12.0, 2.0 * 4.0 / 12.0};
    static const int jint[2][4] = {{1, 1, 0, 0}, {1, 2, 1, 0}};
    static const double jreal[2][12] = {{-0.5, 0, 0, 0, 1, 0}, {-1.0, 0, 0.5, 0, 1, 0}};
    static const int fint[1][4] = {{1, 0, 0, 0}};
    static const double freal[1][12] = {{0.0, -9.81}};
    static const double y_start[12] = {0.12989094272387777, -0.48283365976110476, -1.308,
                                       0.2605782121584888, -1.9656670024540441, -1.57,
                                       0, 0, 0, 0, 0, 0};
    double t_out[2], y_out[24], a_out[12], lam_out[8], y[12], lam[4], t;
    int it[2], nw;
    mbdk_index3_options opt;
    mbdk_stats st;
    mbdk_stepper *s = NULL;
    char what[96];
    mbdk_index3_default_options(&opt);
    opt.formulation = formulation;
    opt.h = 1e-3;
    opt.every = 1000;
    mbdk_index3_solve(2, mass, inertia, 2, &jint[0][0], &jreal[0][0], 1, &fint[0][0],
                      &freal[0][0], &opt, 0.0, 1.0, y_start, 2, t_out, y_out, a_out, lam_out, it,
                      &nw, &st);
    snprintf(what, sizeof what, "index3 stepper (formulation %d) created", formulation);
    check(mbdk_stepper_create_index3(2, mass, inertia, 2, &jint[0][0], &jreal[0][0], 1,
                                     &fint[0][0], &freal[0][0], &opt, 0.0, y_start, &s)
          == MBDK_SUCCESS, what);
    for (int k = 0; k < 1000; k++) mbdk_stepper_step(s);
    mbdk_stepper_state(s, &t, y, 12);
    mbdk_stepper_multipliers(s, lam, 4);
    check(nw == 2 && t == t_out[1] && memcmp(y, y_out + 12, sizeof y) == 0
          && memcmp(lam, lam_out + 4, sizeof lam) == 0,
          "1000 index-3 steps = mbdk_index3_solve's state and multipliers, bit for bit");
    mbdk_stepper_destroy(s);
    opt.adaptive = 1;
    check(mbdk_stepper_create_index3(2, mass, inertia, 2, &jint[0][0], &jreal[0][0], 1,
                                     &fint[0][0], &freal[0][0], &opt, 0.0, y_start, &s)
          == MBDK_ERR_NOT_APPLICABLE, "an adaptive index-3 stepper is refused");
}

static void failures(void)
{
    struct oscillator p = {3.0, 0.1, 0, 40};   /* fails at its 41st call: in step 11 */
    double y0[2] = {1.0, 0.0}, y[2], t;
    volatile int stop = 1;
    mbdk_options opt;
    mbdk_stepper *s = NULL;
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("rk4");
    opt.h = 0.1;
    mbdk_stepper_create_ode(osc, NULL, &p, 2, 0.0, y0, &opt, &s);
    check(mbdk_stepper_advance(s, 2.0) == MBDK_ERR_CALLBACK_FAILED, "a failing callback stops it");
    mbdk_stepper_state(s, &t, y, 2);
    check(fabs(t - 1.0) < 1e-12 && isfinite(y[0]), "the last good state (t = 1) stays readable");
    check(mbdk_stepper_step(s) == MBDK_ERR_NOT_APPLICABLE, "no step after a failure");
    mbdk_stepper_destroy(s);
    p.fail_after = 0;
    opt.interrupt = &stop;
    mbdk_stepper_create_ode(osc, NULL, &p, 2, 0.0, y0, &opt, &s);
    check(mbdk_stepper_advance(s, 2.0) == MBDK_ERR_INTERRUPTED, "the interrupt flag stops it");
    mbdk_stepper_destroy(s);
    check(mbdk_stepper_create_ode(osc, NULL, &p, 2, 0.0, y0, &opt, NULL) == MBDK_ERR_INVALID_INPUT
          && mbdk_stepper_step(NULL) == MBDK_ERR_INVALID_INPUT
          && mbdk_stepper_destroy(NULL) == MBDK_SUCCESS, "NULL handles");
    opt.method = mbdk_method_id("trapezoidal_index3");
    check(mbdk_stepper_create_ode(osc, NULL, &p, 2, 0.0, y0, &opt, &s) == MBDK_ERR_NOT_APPLICABLE
          && s == NULL, "trapezoidal_index3 is no ODE method");
}

int main(void)
{
    oscillator_matches_solve_ode();
    stiff_with_jacobian();
    hanging_bar();
    drifting_bar_is_stopped_by_the_watch();
    index3_matches_the_solve(MBDK_INDEX3_BOOK);
    index3_matches_the_solve(MBDK_INDEX3_AUGMENTED);
    failures();
    printf("%s\n", fails ? "FAILED" : "PASS");
    return fails != 0;
}
