/* c_spatial.c - a C program stepping a spatial scene (chapter 5) through libmbdk's stepper.
 *
 * The scene is mbdk's built-in heavy_top (python/mbdk/scenes/spatial/heavy_top.toml): a top of
 * 1 kg on a spherical joint at the origin, its centre 0.1 m up its axis, tilted 0.3 rad, spinning
 * at 50 rad/s about its axis, under gravity; orientation by a unit quaternion, projected onto
 * |p| = 1 after every step. Its tables and initial state are written out below as Python's
 * mbdk.spatial_model.spatial_tables and Scene.state0 give them.
 *
 * 1. rk4 (reduced formulation) for 500 steps of 1 ms: the energy, the angular momentum about
 *    the vertical through the pivot (gravity and the pivot's force have no moment about it) and
 *    the pivot point are kept to the method's accuracy; the multipliers are the pivot's force,
 *    whose vertical part balances gravity and the centripetal terms on average.
 * 2. trapezoidal_index3 (augmented Lagrangian) for 500 steps of 1 ms, and of 0.5 ms: the pivot
 *    held at roundoff, and the distance to rk4's state (rk4's own error is 1e-4 of it and
 *    below) shrinking fourfold as h halves: second order. At 1 ms the distance is about
 *    1e-3, the trapezoidal rule's phase error (omega h)^2 / 12 over omega t = 25 rad of spin.
 * 3. generalized_alpha (rho_inf = 0.8) by its four parameters in mbdk_index3_options: the pivot
 *    held, the energy within 1e-3 J of its start (the numerical damping of a 1 ms step on the
 *    top's slow motion is small).
 * 4. Failures: a state off the joint is refused (MBDK_ERR_INCONSISTENT_INITIAL), an adaptive
 *    index-3 stepper is MBDK_ERR_NOT_APPLICABLE, and an explicit Euler run with a tight watch
 *    stops by name with the watch's report (mbdk_watch_report) filled in.
 * 5. Wear: a ball (1 kg, radius 5 cm, J = 1e-3 kg m^2) sliding at 1 m/s without spin on the
 *    ground (a sphere_plane contact, Coulomb friction 0.3 regularised below 1 mm/s), its Archard
 *    wear (k = 5e-13 m^3/(N m)) a state after the body's: y0 has 14 values. rk4, 2000 steps of
 *    0.1 ms: the ball rolls at 5/7 of its speed (the slip decelerates at (1 + m r^2 / J) mu g
 *    until it vanishes) and the volume is k m g S, S = v0^2 / ((2 + 2 m r^2 / J) mu g) the slip
 *    distance (the regularisation's share below 1e-5 of it); the index-3 stepper refuses the
 *    wear state (MBDK_ERR_NOT_APPLICABLE).
 * With an argument "print", it prints its tables and the final states of 1, 2 and 5 with 17
 * digits: tests/test_c_spatial.py compares them with mbdk.simulate's bit for bit.
 * Exit code 0 = pass.
 */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include "mbdk.h"

enum { NB = 1, NJ = 1, NF = 1, N = 13 };

static const double mass[NB] = {1.0};
static const double inertia[NB * 9] = {0.005, 0, 0, 0, 0.005, 0, 0, 0, 0.01};
static const int jtype[NJ] = {MBDK_JOINT_SPHERICAL}, jbody[2 * NJ] = {1, 0};
static const double jreal[NJ * MBDK_SPATIAL_JOINT_REALS] = {
    0.0, -3.469446951953614e-18, -0.1, 0, 0, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0};
static const int ftype[NF] = {MBDK_FORCE_GRAVITY}, fbody[2 * NF] = {0, 0};
static const double freal[NF * MBDK_SPATIAL_FORCE_REALS] = {0, 0, -9.81};
/* r (3), p (4), r' (3), Omega (3) */
static const double state0[N] = {0.0, -0.029552020666133955, 0.095533648912560595,
                             0.98877107793604235, 0.14943813247359924, 0, 0,
                             0, -0.095533648912560595, -0.029552020666133955,
                             1.0, 0, 50.0};

/* 5: the sliding ball, its force table the gravity, the contact and the wear of the contact
 * (fbody: entry 2 of this table, law 1 archard; freal: k, the knee's c0..c3 unused, load 1 the
 * normal force) */
enum { NFW = 3, NW = 14 };
static const double ball_mass[1] = {1.0};
static const double ball_inertia[9] = {1e-3, 0, 0, 0, 1e-3, 0, 0, 0, 1e-3};
static const int wtype[NFW] = {MBDK_FORCE_GRAVITY, MBDK_FORCE_SPHERE_PLANE, MBDK_EFFECT_WEAR};
static const int wbody[2 * NFW] = {0, 0, 1, 0, 2, 1};
static const double wreal[NFW * MBDK_SPATIAL_FORCE_REALS] = {
    0, 0, -9.81, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    0, 0, 0, 0.05, 0, 0, 0, 0, 0, 1, 0, 1e6, 1, 100, 0, 0.3, 0.3, 1e-3, 2e-3,
    5e-13, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
/* r at the contact's static penetration m g / k, no rotation, v = (1, 0, 0), no spin, V = 0 */
static const double ball0[NW] = {0, 0, 0.049990190000000004, 1, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0};

static int fails = 0;
static void check(int ok, const char *what)
{
    printf("%s  %s\n", ok ? "ok  " : "FAIL", what);
    if (!ok) fails++;
}

/* R of a unit quaternion (scalar first), R[i][j] */
static void rotation(const double *p, double r[3][3])
{
    double s = p[0], x = p[1], y = p[2], z = p[3];
    r[0][0] = 1 - 2 * (y * y + z * z); r[0][1] = 2 * (x * y - s * z); r[0][2] = 2 * (x * z + s * y);
    r[1][0] = 2 * (x * y + s * z); r[1][1] = 1 - 2 * (x * x + z * z); r[1][2] = 2 * (y * z - s * x);
    r[2][0] = 2 * (x * z - s * y); r[2][1] = 2 * (y * z + s * x); r[2][2] = 1 - 2 * (x * x + y * y);
}

/* energy, H_z about the pivot, |pivot| of a state */
static void invariants(const double *y, double *energy, double *hz, double *pivot)
{
    double r[3][3], jw[3], p[3], hs = 0;
    const double *w = y + 10, *v = y + 7;
    rotation(y + 3, r);
    for (int i = 0; i < 3; i++) jw[i] = inertia[3 * i + i] * w[i];
    *energy = 0.5 * mass[0] * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
            + 0.5 * (w[0] * jw[0] + w[1] * jw[1] + w[2] * jw[2]) + mass[0] * 9.81 * y[2];
    for (int j = 0; j < 3; j++) hs += r[2][j] * jw[j];
    *hz = hs + mass[0] * (y[0] * v[1] - y[1] * v[0]);
    for (int i = 0; i < 3; i++)
        p[i] = y[i] + r[i][0] * jreal[0] + r[i][1] * jreal[1] + r[i][2] * jreal[2];
    *pivot = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
}

static void print_state(const char *label, const double *y)
{
    printf("%s", label);
    for (int i = 0; i < N; i++) printf(" %.17g", y[i]);
    printf("\n");
}

static void print_values(const char *label, const double *y, int n)
{
    printf("%s", label);
    for (int i = 0; i < n; i++) printf(" %.17g", y[i]);
    printf("\n");
}

static void print_wear_tables(void)
{
    printf("wear_tables %.17g", ball_mass[0]);
    for (int i = 0; i < 9; i++) printf(" %.17g", ball_inertia[i]);
    for (int i = 0; i < NFW * MBDK_SPATIAL_FORCE_REALS; i++) printf(" %.17g", wreal[i]);
    for (int i = 0; i < NFW; i++) printf(" %d %d %d", wtype[i], wbody[2 * i], wbody[2 * i + 1]);
    printf("\n");
    print_values("wear_y0", ball0, NW);
}

/* 5. the sliding ball's wear */
static void wear(int printing)
{
    const double m = 1.0, r = 0.05, j = 1e-3, mu = 0.3, g = 9.81, v0 = 1.0, k = 5e-13;
    const double slip = v0 * v0 / ((2 + 2 * m * r * r / j) * mu * g);
    mbdk_spatial_options so;
    mbdk_options opt;
    mbdk_index3_options i3;
    mbdk_stepper *s = NULL;
    double t, y[NW];
    int n = 0, m_rows = -1;
    mbdk_spatial_default_options(&so);
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("rk4");
    opt.h = 1e-4;
    if (printing) print_wear_tables();
    check(mbdk_stepper_create_spatial(1, ball_mass, ball_inertia, 0, NULL, NULL, NULL, NFW, wtype,
                                      wbody, wreal, &so, &opt, 0.0, ball0, &s) == MBDK_SUCCESS
          && mbdk_stepper_size(s, &n, &m_rows) == MBDK_SUCCESS && n == NW && m_rows == 0,
          "a spatial stepper on a ball with wear: 13 values of the body, then its volume");
    for (int i = 0; i < 2000; i++) mbdk_stepper_step(s);
    check(mbdk_stepper_state(s, &t, y, NW) == MBDK_SUCCESS && fabs(t - 0.2) < 1e-15,
          "2000 steps of 0.1 ms reach t = 0.2 s");
    check(fabs(y[7] - 5.0 / 7.0 * v0) < 1e-4, "the ball rolls at 5/7 of its initial speed");
    check(fabs(y[13] / (k * m * g * slip) - 1) < 1e-4,
          "its wear is Archard's k m g times the slip distance");
    printf("      v = %.9f m/s (5/7 v0 = %.9f), V = %.6g m^3 (k m g S = %.6g)\n", y[7],
           5.0 / 7.0 * v0, y[13], k * m * g * slip);
    if (printing) print_values("wear_rk4", y, NW);
    mbdk_stepper_destroy(s);
    s = NULL;
    mbdk_index3_default_options(&i3);
    i3.h = 1e-4;
    check(mbdk_stepper_create_spatial_index3(1, ball_mass, ball_inertia, 0, NULL, NULL, NULL, NFW,
                                             wtype, wbody, wreal, &so, &i3, 0.0, ball0, &s)
          == MBDK_ERR_NOT_APPLICABLE && s == NULL,
          "the index-3 family has no place for the wear state: not applicable");
}

static void print_tables(void)
{
    printf("tables");
    printf(" %.17g", mass[0]);
    for (int i = 0; i < 9; i++) printf(" %.17g", inertia[i]);
    for (int i = 0; i < MBDK_SPATIAL_JOINT_REALS; i++) printf(" %.17g", jreal[i]);
    for (int i = 0; i < MBDK_SPATIAL_FORCE_REALS; i++) printf(" %.17g", freal[i]);
    printf(" %d %d %d %d %d %d\n", jtype[0], jbody[0], jbody[1], ftype[0], fbody[0], fbody[1]);
    print_state("y0", state0);
}

int main(int argc, char **argv)
{
    int printing = argc > 1 && strcmp(argv[1], "print") == 0;
    mbdk_spatial_options so;
    mbdk_options opt;
    mbdk_index3_options i3;
    mbdk_stepper *s = NULL, *s3 = NULL;
    double t, y[N], y3[N], lam[3], e0, h0, p0, e, hz, pivot, diff = 0;
    int n = 0, m = 0;

    mbdk_spatial_default_options(&so);
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("rk4");
    opt.h = 1e-3;
    invariants(state0, &e0, &h0, &p0);
    if (printing) print_tables();

    /* 1. rk4 */
    check(mbdk_stepper_create_spatial(NB, mass, inertia, NJ, jtype, jbody, jreal, NF, ftype, fbody,
                                      freal, &so, &opt, 0.0, state0, &s) == MBDK_SUCCESS,
          "a spatial rk4 stepper on the heavy top");
    check(mbdk_stepper_size(s, &n, &m) == MBDK_SUCCESS && n == N && m == 3,
          "its state has 13 values, its joint 3 rows");
    for (int k = 0; k < 500; k++) mbdk_stepper_step(s);
    mbdk_stepper_state(s, &t, y, N);
    invariants(y, &e, &hz, &pivot);
    check(fabs(t - 0.5) < 1e-15, "500 steps of 1 ms reach t = 0.5");
    check(fabs(e - e0) < 1e-6 * fabs(e0), "rk4 keeps the energy (relative 1e-6)");
    check(fabs(hz - h0) < 1e-6 * fabs(h0), "and the angular momentum about the vertical");
    check(pivot < 1e-8, "and the pivot at the origin");
    check(mbdk_stepper_multipliers(s, lam, 3) == MBDK_SUCCESS && fabs(lam[2]) > 1.0
          && fabs(lam[2]) < 30.0, "the pivot's vertical multiplier is of the order of m g");
    printf("      E - E0 = %.3g J, Hz - Hz0 = %.3g, |pivot| = %.3g m, lambda_z = %.6g N\n",
           e - e0, hz - h0, pivot, lam[2]);
    if (printing) print_state("rk4", y);

    /* 2. trapezoidal_index3 */
    mbdk_index3_default_options(&i3);
    i3.h = 1e-3;
    i3.formulation = MBDK_INDEX3_AUGMENTED;
    check(mbdk_stepper_create_spatial_index3(NB, mass, inertia, NJ, jtype, jbody, jreal, NF, ftype,
                                             fbody, freal, &so, &i3, 0.0, state0, &s3) == MBDK_SUCCESS,
          "a spatial trapezoidal_index3 stepper");
    check(mbdk_stepper_advance(s3, 0.5) == MBDK_SUCCESS, "it advances to t = 0.5");
    mbdk_stepper_state(s3, &t, y3, N);
    invariants(y3, &e, &hz, &pivot);
    for (int i = 0; i < N; i++) diff = fmax(diff, fabs(y3[i] - y[i]));
    check(pivot < 1e-12, "trapezoidal_index3 holds the pivot at roundoff");
    if (printing) print_state("trapezoidal_index3", y3);
    mbdk_stepper_destroy(s3);
    s3 = NULL;
    {
        double half = 0;
        i3.h = 5e-4;
        check(mbdk_stepper_create_spatial_index3(NB, mass, inertia, NJ, jtype, jbody, jreal, NF,
                                                 ftype, fbody, freal, &so, &i3, 0.0, state0, &s3)
              == MBDK_SUCCESS && mbdk_stepper_advance(s3, 0.5) == MBDK_SUCCESS,
              "and with h = 0.5 ms");
        mbdk_stepper_state(s3, &t, y3, N);
        for (int i = 0; i < N; i++) half = fmax(half, fabs(y3[i] - y[i]));
        check(diff / half > 3.5 && diff / half < 4.5,
              "its distance to rk4 shrinks fourfold as h halves (second order)");
        printf("      max |y_i3 - y_rk4| = %.3g (h = 1 ms), %.3g (0.5 ms): ratio %.3f\n", diff,
               half, diff / half);
        mbdk_stepper_destroy(s3);
        s3 = NULL;
        i3.h = 1e-3;
    }

    /* 3. generalized_alpha, rho_inf = 0.8 (Chung and Hulbert 1993) */
    {
        double rho = 0.8;
        i3.alpha_m = (2 * rho - 1) / (rho + 1);
        i3.alpha_f = rho / (rho + 1);
        i3.gamma = 0.5 - i3.alpha_m + i3.alpha_f;
        i3.beta = 0.25 * (1 - i3.alpha_m + i3.alpha_f) * (1 - i3.alpha_m + i3.alpha_f);
        check(mbdk_stepper_create_spatial_index3(NB, mass, inertia, NJ, jtype, jbody, jreal, NF,
                                                 ftype, fbody, freal, &so, &i3, 0.0, state0, &s3)
              == MBDK_SUCCESS && mbdk_stepper_advance(s3, 0.5) == MBDK_SUCCESS,
              "generalized_alpha (rho_inf = 0.8) steps the top to t = 0.5");
        mbdk_stepper_state(s3, &t, y3, N);
        invariants(y3, &e, &hz, &pivot);
        check(pivot < 1e-12 && fabs(e - e0) < 1e-3, "the pivot held, the energy within 1 mJ");
        printf("      E - E0 = %.3g J, |pivot| = %.3g m\n", e - e0, pivot);
        mbdk_stepper_destroy(s3);
        s3 = NULL;
    }

    /* 4. failures */
    {
        double off[N];
        mbdk_watch_report report;
        int status;
        memcpy(off, state0, sizeof off);
        off[2] += 0.01;                      /* the centre 1 cm up: off the joint */
        check(mbdk_stepper_create_spatial(NB, mass, inertia, NJ, jtype, jbody, jreal, NF, ftype,
                                          fbody, freal, &so, &opt, 0.0, off, &s3)
              == MBDK_ERR_INCONSISTENT_INITIAL && s3 == NULL,
              "a start off the joint is refused by name");
        so.coordinates = MBDK_COORDS_JOINT;
        check(mbdk_stepper_create_spatial(NB, mass, inertia, NJ, jtype, jbody, jreal, NF, ftype,
                                          fbody, freal, &so, &opt, 0.0, state0, &s3)
              == MBDK_ERR_NOT_APPLICABLE && s3 == NULL,
              "joint coordinates are not a stepper's (the f2py entry spatial_run's)");
        so.coordinates = MBDK_COORDS_ABSOLUTE;
        i3.adaptive = 1;
        check(mbdk_stepper_create_spatial_index3(NB, mass, inertia, NJ, jtype, jbody, jreal, NF,
                                                 ftype, fbody, freal, &so, &i3, 0.0, state0, &s3)
              == MBDK_ERR_NOT_APPLICABLE, "an adaptive index-3 stepper is not applicable");
        opt.method = mbdk_method_id("explicit_euler");
        so.watch_position = 1e-6;
        check(mbdk_stepper_create_spatial(NB, mass, inertia, NJ, jtype, jbody, jreal, NF, ftype,
                                          fbody, freal, &so, &opt, 0.0, state0, &s3) == MBDK_SUCCESS,
              "explicit Euler on the top with a tight watch");
        status = mbdk_stepper_advance(s3, 5.0);
        check(status == MBDK_ERR_CONSTRAINT_DRIFT || status == MBDK_ERR_ENERGY_DRIFT
              || status == MBDK_ERR_INVARIANT_DRIFT, "stops with a drift status");
        check(mbdk_stepper_watch_report(s3, &report) == MBDK_SUCCESS && report.quantity >= 1
              && report.value > report.tol && report.t > report.t_good,
              "the watch's report names what left its tolerance and when");
        printf("      stopped: quantity %d, row %d, %.3g of its scale (tolerance %.3g) at "
               "t = %g\n", report.quantity, report.row, report.value, report.tol, report.t);
        mbdk_stepper_destroy(s3);
    }
    mbdk_stepper_destroy(s);

    /* 5. wear */
    wear(printing);
    printf("%s\n", fails ? "FAILED" : "all checks passed");
    return fails != 0;
}
