/* c_bad_input.c - bad input through the C API gets a status that names the problem (issue 36).
 *
 * 1. A right-hand side that returns NaN: dopri54, bs32 and bdf end with MBDK_ERR_NONFINITE, both
 *    when F is NaN at the initial state and when it turns NaN at t = 0.5 (error control shrinks
 *    the steps that reach it down to the floor: no step size avoids it), not with
 *    MBDK_ERR_STEP_TOO_SMALL; the samples before t = 0.5 are kept.
 * 2. A stepper asked to advance to an earlier time: MBDK_ERR_INVALID_INPUT, its state unchanged;
 *    to its own time: success, nothing to do.
 * 3. A scene stepper whose initial state is off its joints: the bar of c_stepper.c 0.5 m off its
 *    hinge, or with a velocity the hinge does not allow, is refused at creation with
 *    MBDK_ERR_INCONSISTENT_INITIAL; the consistent states (at rest, and turning about the hinge
 *    with its centre at omega x r) are accepted.
 * 4. A Newton matrix that overflows while the residual stays finite: the same bar with a rigid
 *    lever, a spring of k = 1.7e308 N/m at rest, horizontal, 10 m below the bar's centre (its
 *    rotational stiffness k r^2 overflows; at rest it pulls with no force). trapezoidal_index3
 *    with h = 1 (the book's and the augmented form, the small dense path) stops with
 *    MBDK_ERR_SINGULAR_MATRIX at its first step, with only the initial sample written:
 *    mbdk_index3_matrix refuses a matrix that is not finite, naming the matrix (without that
 *    test the LU takes the infinite pivot, and the run ends with MBDK_ERR_NONFINITE once its
 *    result turns NaN). (Python's scene reader keeps magnitudes within 1e150; a C caller's
 *    tables are not checked so.)
 * Exit code 0 = pass.
 */
#include <math.h>
#include <stdio.h>
#include "mbdk.h"

static const double PI = 3.14159265358979323846;
static int fails = 0;

static void check(int ok, const char *what)
{
    printf("%s: %s\n", ok ? "ok  " : "FAIL", what);
    if (!ok) fails++;
}

/* y' = -y, NaN from t_nan on */
static int decay_then_nan(int n, double t, const double *y, double *dydt, void *user_data)
{
    const double *t_nan = user_data;
    (void)n;
    dydt[0] = t >= *t_nan ? NAN : -y[0];
    return 0;
}

static void nonfinite_right_hand_side(void)
{
    const char *names[3] = {"dopri54", "bs32", "bdf"};
    for (int i = 0; i < 3; i++) {
        double y0[1] = {1.0}, t_out[11], y_out[11], t_nan;
        int nw = 0, status;
        char what[120];
        mbdk_options opt;
        mbdk_stats st;
        mbdk_default_options(&opt);
        opt.method = mbdk_method_id(names[i]);
        opt.dt_out = 0.1;
        t_nan = 0.0;
        status = mbdk_solve_ode(decay_then_nan, NULL, &t_nan, 1, 0.0, 1.0, y0, &opt, 11, t_out,
                                y_out, &nw, &st);
        snprintf(what, sizeof what, "%s: F NaN at the initial state -> MBDK_ERR_NONFINITE (%d)",
                 names[i], status);
        check(status == MBDK_ERR_NONFINITE, what);
        t_nan = 0.55;
        status = mbdk_solve_ode(decay_then_nan, NULL, &t_nan, 1, 0.0, 1.0, y0, &opt, 11, t_out,
                                y_out, &nw, &st);
        snprintf(what, sizeof what, "%s: F NaN from t = 0.55 -> MBDK_ERR_NONFINITE (%d), the "
                 "samples up to t = 0.5 kept (%d)", names[i], status, nw);
        check(status == MBDK_ERR_NONFINITE && nw >= 6 && t_out[nw - 1] < 0.55
              && fabs(y_out[5] - exp(-0.5)) < 1e-4, what);
    }
}

static int osc(int n, double t, const double *y, double *dydt, void *user_data)
{
    (void)t; (void)n; (void)user_data;
    dydt[0] = y[1];
    dydt[1] = -y[0];
    return 0;
}

static void advance_backwards(void)
{
    double y0[2] = {1.0, 0.0}, y[2], t;
    mbdk_options opt;
    mbdk_stepper *s = NULL;
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("rk4");
    opt.h = 0.01;
    mbdk_stepper_create_ode(osc, NULL, NULL, 2, 0.0, y0, &opt, &s);
    check(mbdk_stepper_advance(s, 1.0) == MBDK_SUCCESS, "advance to t = 1");
    check(mbdk_stepper_advance(s, 0.5) == MBDK_ERR_INVALID_INPUT,
          "advance to an earlier time (0.5) -> MBDK_ERR_INVALID_INPUT");
    mbdk_stepper_state(s, &t, y, 2);
    check(t == 1.0 && fabs(y[0] - cos(1.0)) < 1e-8, "the state stays at t = 1");
    check(mbdk_stepper_advance(s, 1.0) == MBDK_SUCCESS, "advance to its own time: nothing to do");
    check(mbdk_stepper_step(s) == MBDK_SUCCESS, "it still steps");
    mbdk_stepper_destroy(s);
}

/* the hanging bar of c_stepper.c: 1 m, 1 kg, its +x end on a hinge at the origin */
static int bar_stepper(const double y0[6], mbdk_stepper **s)
{
    static const double mass[1] = {1.0}, inertia[1] = {1.0 / 12.0};
    static const int jint[4] = {1, 1, 0, 0};
    static const double jreal[12] = {0.5, 0.0, 0.0, 0.0, 1, 0};
    static const int fint[4] = {1, 0, 0, 0};
    static const double freal[12] = {0.0, -9.81};
    mbdk_options opt;
    mbdk_model_options mopt;
    mbdk_model_default_options(&mopt);
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("rk4");
    opt.h = 1e-3;
    *s = NULL;
    return mbdk_stepper_create_scene(1, mass, inertia, 1, jint, jreal, 1, fint, freal, &mopt,
                                     &opt, 0.0, y0, s);
}

static void inconsistent_scene_start(void)
{
    const double good[6] = {0.0, -0.5, PI / 2, 0, 0, 0};
    const double off[6] = {0.5, -0.5, PI / 2, 0, 0, 0};        /* 0.5 m off the hinge */
    const double moving[6] = {0.0, -0.5, PI / 2, 1.0, 0, 0};   /* the hinge point moves */
    /* turning about the hinge at 1 rad/s: the centre moves at omega x r = (0.5, 0) */
    const double turning[6] = {0.0, -0.5, PI / 2, 0.5, 0.0, 1.0};
    mbdk_stepper *s;
    check(bar_stepper(good, &s) == MBDK_SUCCESS && s != NULL, "the consistent start is accepted");
    mbdk_stepper_destroy(s);
    check(bar_stepper(turning, &s) == MBDK_SUCCESS && s != NULL,
          "a consistent turning start is accepted");
    mbdk_stepper_destroy(s);
    check(bar_stepper(off, &s) == MBDK_ERR_INCONSISTENT_INITIAL && s == NULL,
          "0.5 m off the hinge -> MBDK_ERR_INCONSISTENT_INITIAL");
    check(bar_stepper(moving, &s) == MBDK_ERR_INCONSISTENT_INITIAL && s == NULL,
          "a velocity that moves the hinge point -> MBDK_ERR_INCONSISTENT_INITIAL");
}

static void overflowing_newton_matrix(void)
{
    static const double mass[1] = {1.0}, inertia[1] = {1.0 / 12.0};
    static const int jint[4] = {MBDK_JOINT_REVOLUTE, 1, 0, 0};
    static const double jreal[12] = {0.5, 0.0, 0.0, 0.0};
    /* gravity; the spring from (-10, 0) on the bar, (0, -10.5) in space, to (10, -10.5) */
    static const int fint[2][4] = {{MBDK_FORCE_GRAVITY, 0, 0, 0}, {MBDK_FORCE_SPRING, 1, 0, 0}};
    static const double freal[2][12] = {{0.0, -9.81},
                                        {-10.0, 0.0, 10.0, -10.5, 1.7e308, 10.0}};
    const double y0[6] = {0.0, -0.5, PI / 2, 0, 0, 0};
    const int forms[2] = {MBDK_INDEX3_BOOK, MBDK_INDEX3_AUGMENTED};
    for (int k = 0; k < 2; k++) {
        mbdk_index3_options opt;
        mbdk_stats st;
        double t[3], y[18], a[9], lam[6];
        int it[3], nw = -1;
        mbdk_index3_default_options(&opt);
        opt.formulation = forms[k];
        opt.h = 1.0;
        int status = mbdk_index3_solve(1, mass, inertia, 1, jint, jreal, 2, &fint[0][0],
                                       &freal[0][0], &opt, 0.0, 2.0, y0, 3, t, y, a, lam, it, &nw,
                                       &st);
        check(status == MBDK_ERR_SINGULAR_MATRIX && nw == 1,
              k == 0 ? "an overflowing Newton matrix, book form -> MBDK_ERR_SINGULAR_MATRIX"
                     : "an overflowing Newton matrix, augmented -> MBDK_ERR_SINGULAR_MATRIX");
    }
}

int main(void)
{
    nonfinite_right_hand_side();
    advance_backwards();
    inconsistent_scene_start();
    overflowing_newton_matrix();
    printf("%s\n", fails ? "FAILED" : "PASSED");
    return fails ? 1 : 0;
}
