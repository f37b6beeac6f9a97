/* c_index3.c - a C program integrating a planar scene through libmbdk's trapezoidal_index3.
 *
 * The double pendulum of python/mbdk/scenes/double_pendulum.toml, its tables written out by hand
 * (the layout mbdk.model.build_tables makes: revolute = joint type 1, gravity = force type 1,
 * bodies 1-based, 0 = ground): a 1 m, 1 kg bar hinged at the origin, a 2 m, 2 kg bar hinged to
 * its tip. Checked here, independently of the kernel: both hinges hold (|P1 - P2| computed from
 * q) at every sample, the energy (computed from q, v) stays within 1e-3 of its start, the book's
 * scheme and the projected form agree in q to O(h^2), the step-size controller meets its error
 * tolerance against a fine fixed-step run, and bad options get the documented statuses.
 * Exit code 0 = pass.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include "mbdk.h"

static const double mass[2] = {1.0, 2.0};
static const double inertia[2] = {1.0 / 12.0, 2.0 * 4.0 / 12.0};
static const int jint[2][4] = {{1, 1, 0, 0}, {1, 2, 1, 0}};
static const double jreal[2][12] = {{-0.5, 0, 0, 0, 1, 0}, {-1.0, 0, 0.5, 0, 1, 0}};
static const int fint[1][4] = {{1, 0, 0, 0}};
static const double freal[1][12] = {{0.0, -9.81}};
static const double y_start[12] = {0.12989094272387777, -0.48283365976110476, -1.308,
                              0.2605782121584888, -1.9656670024540441, -1.57,
                              0, 0, 0, 0, 0, 0};

static void point(const double *q, int b, double sx, double sy, double *p)
{
    double c = cos(q[3 * b + 2]), s = sin(q[3 * b + 2]);
    p[0] = q[3 * b] + c * sx - s * sy;
    p[1] = q[3 * b + 1] + s * sx + c * sy;
}

static double hinge_error(const double *q)
{
    double a[2], b[2], e;
    point(q, 0, -0.5, 0.0, a);                 /* crank end at the origin */
    e = fmax(fabs(a[0]), fabs(a[1]));
    point(q, 1, -1.0, 0.0, a);
    point(q, 0, 0.5, 0.0, b);
    return fmax(e, fmax(fabs(a[0] - b[0]), fabs(a[1] - b[1])));
}

static double energy(const double *y)
{
    double e = 0.0;
    for (int b = 0; b < 2; b++) {
        const double *v = y + 6 + 3 * b;
        e += 0.5 * mass[b] * (v[0] * v[0] + v[1] * v[1]) + 0.5 * inertia[b] * v[2] * v[2]
           + 9.81 * mass[b] * y[3 * b + 1];
    }
    return e;
}

static int run(mbdk_index3_options *opt, double t_end, double *q_end, mbdk_stats *st)
{
    int nsamp, nw, status;
    status = mbdk_index3_sample_count(opt, 0.0, t_end, &nsamp);
    if (status < 0) { fprintf(stderr, "  sample count: status %d\n", status); return -1000; }
    double *t = malloc(sizeof(double) * nsamp), *y = malloc(sizeof(double) * 12 * nsamp);
    double *a = malloc(sizeof(double) * 6 * nsamp), *lam = malloc(sizeof(double) * 4 * nsamp);
    int *it = malloc(sizeof(int) * nsamp);
    status = mbdk_index3_solve(2, mass, inertia, 2, &jint[0][0], &jreal[0][0], 1, &fint[0][0],
                               &freal[0][0], opt, 0.0, t_end, y_start, nsamp, t, y, a, lam, it, &nw,
                               st);
    if (status < 0) fprintf(stderr, "  solve: status %d after %d samples\n", status, nw);
    if (status >= 0) {
        double e0 = energy(y), worst_phi = 0.0, worst_e = 0.0;
        for (int k = 0; k < nw; k++) {
            worst_phi = fmax(worst_phi, hinge_error(y + 12 * k));
            worst_e = fmax(worst_e, fabs(energy(y + 12 * k) - e0));
        }
        printf("  formulation %d adaptive %d: %d samples, %lld steps, %lld Newton, %lld LU, "
               "%lld rejected, max|Phi| %.2e, max|dE| %.2e, %.4f s\n", opt->formulation,
               opt->adaptive, nw, (long long)st->steps, (long long)st->newton_iterations,
               (long long)st->nlu, (long long)st->rejected_steps, worst_phi,
               worst_e, st->cpu_time);
        if (nw != nsamp || worst_phi > 1e-10 || worst_e > 1e-3) status = -1001;
        for (int i = 0; i < 6; i++) q_end[i] = y[12 * (nw - 1) + i];
    }
    free(t); free(y); free(a); free(lam); free(it);
    return status;
}

int main(void)
{
    mbdk_index3_options opt;
    mbdk_stats st;
    double qb[6], qa[6], qf[6], qc[6], d = 0.0;
    int fails = 0;

    mbdk_index3_default_options(&opt);
    opt.h = 1e-3;
    opt.every = 100;
    opt.formulation = MBDK_INDEX3_BOOK;
    if (run(&opt, 2.0, qb, &st) != MBDK_SUCCESS) { fprintf(stderr, "book run failed\n"); fails++; }
    opt.formulation = MBDK_INDEX3_AUGMENTED;
    if (run(&opt, 2.0, qa, &st) != MBDK_SUCCESS) { fprintf(stderr, "augmented failed\n"); fails++; }
    for (int i = 0; i < 6; i++) d = fmax(d, fabs(qa[i] - qb[i]));
    if (!(d < 1e-4)) { fprintf(stderr, "book and augmented differ by %g\n", d); fails++; }

    /* adaptive against a fine fixed step (h = 1e-4: its error is about 1e-7 here) */
    opt.h = 1e-4;
    opt.every = 1000;
    if (run(&opt, 2.0, qf, &st) != MBDK_SUCCESS) { fprintf(stderr, "fine run failed\n"); fails++; }
    opt.h = 1e-3;
    opt.adaptive = 1;
    opt.err_rtol = opt.err_atol = 1e-6;
    opt.dt_out = 0.1;
    if (run(&opt, 2.0, qc, &st) != MBDK_SUCCESS) { fprintf(stderr, "adaptive failed\n"); fails++; }
    d = 0.0;
    for (int i = 0; i < 6; i++) d = fmax(d, fabs(qc[i] - qf[i]));
    if (!(d < 1e-4 && st.steps > 50)) { fprintf(stderr, "adaptive error %g\n", d); fails++; }
    /* extrapolated (third order): at the same tolerance, within the fine run's own error */
    opt.adaptive = MBDK_INDEX3_EXTRAPOLATED;
    if (run(&opt, 2.0, qc, &st) != MBDK_SUCCESS) { fprintf(stderr, "extrapolated failed\n"); fails++; }
    d = 0.0;
    for (int i = 0; i < 6; i++) d = fmax(d, fabs(qc[i] - qf[i]));
    if (!(d < 2e-6)) { fprintf(stderr, "extrapolated error %g\n", d); fails++; }
    opt.adaptive = 3;
    if (run(&opt, 1.0, qc, &st) != MBDK_ERR_INVALID_INPUT) { fprintf(stderr, "adaptive 3\n"); fails++; }
    opt.adaptive = MBDK_INDEX3_ESTIMATED;

    /* statuses: the book's scheme refuses step-size control, an unknown formulation is bad input */
    opt.formulation = MBDK_INDEX3_BOOK;
    if (run(&opt, 1.0, qc, &st) != MBDK_ERR_NOT_APPLICABLE) { fprintf(stderr, "book+adaptive\n"); fails++; }
    opt.formulation = MBDK_INDEX3_AUGMENTED;
    opt.h_min = 0.1;
    opt.h_max = 0.01;
    if (run(&opt, 1.0, qc, &st) != -1000) { fprintf(stderr, "h_min > h_max\n"); fails++; }
    opt.h_min = opt.h_max = 0.0;
    opt.adaptive = 0;
    opt.formulation = 7;
    if (run(&opt, 1.0, qc, &st) != MBDK_ERR_INVALID_INPUT) { fprintf(stderr, "formulation 7\n"); fails++; }
    printf("c_index3: %s\n", fails ? "FAIL" : "ok");
    return fails ? 1 : 0;
}
