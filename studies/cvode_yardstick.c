/* The yardstick of studies/error_control.py (table error_control_bdf_vs_cvode): CVODE driven
   from plain C with a C right-hand side, configured as the kernel's cvode_bdf configures it
   (kernel/src/sundials/mbdk_cvode.f90): BDF, Newton on SUNDIALS' dense matrix and dense LU,
   CVODE's difference-quotient Jacobian (the double pendulum has no analytic one in the kernel
   either), scalar tolerances, one step per call up to the stop time t_end. The right-hand side
   is the book's double pendulum (3.64), the arithmetic of the kernel's (mbdk_textbook.f90).
   The difference between the two CPU times is what the kernel's bridge costs.
   argv: rtol atol t_end reps m1 m2 l1 l2 g y0[4]
   Prints: the least CPU seconds of one solve over the reps (the thread's, creation to free: on
   a shared machine the least is the one least disturbed), steps, evaluations of F
   (difference-quotient columns included), phi1(t_end), phi2(t_end). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>
#include <cvode/cvode.h>
#include <nvector/nvector_serial.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

static double P[5];

static int rhs(realtype t, N_Vector yv, N_Vector fv, void *user_data)
{
    const double *y = N_VGetArrayPointer(yv);
    double *f = N_VGetArrayPointer(fv);
    const double *p = P;
    (void)t; (void)user_data;
    double d = y[0] - y[1], sd = sin(d), cd = cos(d);
    double m11 = (p[0] / 3.0 + p[1]) * p[2] * p[2];
    double m12 = 0.5 * p[1] * p[2] * p[3] * cd;
    double m22 = p[1] * p[3] * p[3] / 3.0;
    double r1 = -0.5 * p[1] * p[2] * p[3] * sd * y[3] * y[3]
                - (0.5 * p[0] + p[1]) * p[4] * p[2] * cos(y[0]);
    double r2 = 0.5 * p[1] * p[2] * p[3] * sd * y[2] * y[2] - 0.5 * p[1] * p[4] * p[3] * cos(y[1]);
    double det = m11 * m22 - m12 * m12;
    f[0] = y[2];
    f[1] = y[3];
    f[2] = (m22 * r1 - m12 * r2) / det;
    f[3] = (m11 * r2 - m12 * r1) / det;
    return 0;
}

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

int main(int argc, char **argv)
{
    if (argc != 14) {
        fprintf(stderr, "usage: %s rtol atol t_end reps m1 m2 l1 l2 g y0[4]\n", argv[0]);
        return 2;
    }
    double rtol = atof(argv[1]), atol = atof(argv[2]), t_end = atof(argv[3]);
    int reps = atoi(argv[4]);
    double y0[4];
    for (int i = 0; i < 5; i++) P[i] = atof(argv[5 + i]);
    for (int i = 0; i < 4; i++) y0[i] = atof(argv[10 + i]);
    long nst = 0, nfe = 0, nfel = 0;
    double yend[2] = {0.0, 0.0}, best = 1e300;
    for (int r = 0; r < reps; r++) {
        double c0 = cpu_now();
        SUNContext ctx;
        if (SUNContext_Create(NULL, &ctx)) return 1;
        N_Vector y = N_VNew_Serial(4, ctx);
        for (int i = 0; i < 4; i++) NV_Ith_S(y, i) = y0[i];
        void *mem = CVodeCreate(CV_BDF, ctx);
        CVodeSetErrFile(mem, NULL);
        CVodeInit(mem, rhs, 0.0, y);
        CVodeSStolerances(mem, rtol, atol);
        SUNMatrix A = SUNDenseMatrix(4, 4, ctx);
        SUNLinearSolver LS = SUNLinSol_Dense(y, A, ctx);
        CVodeSetLinearSolver(mem, LS, A);
        CVodeSetMaxNumSteps(mem, -1);
        CVodeSetStopTime(mem, t_end);
        double t = 0.0;
        int flag = 0;
        while (t < t_end) {
            flag = CVode(mem, t_end, y, &t, CV_ONE_STEP);
            if (flag < 0) break;
        }
        CVodeGetNumSteps(mem, &nst);
        CVodeGetNumRhsEvals(mem, &nfe);
        CVodeGetNumLinRhsEvals(mem, &nfel);
        yend[0] = NV_Ith_S(y, 0);
        yend[1] = NV_Ith_S(y, 1);
        CVodeFree(&mem);
        SUNLinSolFree(LS);
        SUNMatDestroy(A);
        N_VDestroy(y);
        SUNContext_Free(&ctx);
        double used = cpu_now() - c0;
        if (used < best) best = used;
        if (flag < 0) { fprintf(stderr, "CVODE flag %d\n", flag); return 1; }
    }
    printf("%.9e %ld %ld %.17g %.17g\n", best, nst, nfe + nfel, yend[0], yend[1]);
    return 0;
}
