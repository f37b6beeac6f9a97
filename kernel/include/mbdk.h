/* mbdk.h - C API of the mbdk kernel (hand-written mirror of kernel/src/api/mbdk_capi.f90).
 *
 * Link with libmbdk (static, PIC): `pkg-config --cflags --libs mbdk`.
 * Every function returns a status (0 success, > 0 success with a note, < 0 failure) or an id;
 * nothing prints and nothing stops the process. The status table is mirrored from
 * kernel/src/core/mbdk_status.f90; tests/test_status.py checks that the two agree.
 */
#ifndef MBDK_H
#define MBDK_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Status codes (kernel/src/core/mbdk_status.f90). */
enum mbdk_status {
    MBDK_SUCCESS = 0,
    MBDK_NOTE_LAST_STEP_SHORTENED = 1,
    MBDK_ERR_INVALID_INPUT = -1,
    MBDK_ERR_UNKNOWN_METHOD = -2,
    MBDK_ERR_UNKNOWN_PROBLEM = -3,
    MBDK_ERR_NOT_APPLICABLE = -4,
    MBDK_ERR_OUTPUT_SIZE = -5,
    MBDK_ERR_STEP_TOO_SMALL = -10,
    MBDK_ERR_NEWTON_DIVERGED = -20,
    MBDK_ERR_SINGULAR_MATRIX = -21,
    MBDK_ERR_NONFINITE = -30,
    MBDK_ERR_CALLBACK_FAILED = -40,
    MBDK_ERR_BACKEND = -50
};

/* Options of a fixed-step solve; fill with mbdk_default_options, then set method and h. */
typedef struct mbdk_options {
    int method;          /* from mbdk_method_id("rk4") etc. */
    double h;            /* step size */
    int every;           /* keep every k-th step as a sample (the last one always) */
    double newton_rtol;  /* implicit methods: Newton stops when WRMS(update) < 1 */
    double newton_atol;
    int newton_max_iter;
    int fd_jacobian;     /* callbacks have no Jacobian: finite differences are always used */
    int nq;              /* > 0: y = [q; v] with n = 2*nq (needed by euler_cromer) */
    int startup;         /* k-step methods: MBDK_STARTUP_RK4 (the book) or MBDK_STARTUP_BDF */
} mbdk_options;

/* Start-up of bdf2..bdf6: RK4 steps (the book, (4.80)) or BDF steps of rising order. */
enum mbdk_startup { MBDK_STARTUP_RK4 = 0, MBDK_STARTUP_BDF = 1 };

typedef struct mbdk_stats {
    int64_t steps, rhs_evals, jac_evals, lu_factorizations, newton_iterations, startup_steps;
    double cpu_time;     /* CPU seconds of the time loop, measured in the kernel */
    int64_t rejected_steps, newton_failures;  /* step-size control: error test, Newton */
} mbdk_stats;

/* Right-hand side y' = F(t, y). Return 0 on success, non-zero on failure
 * (the solve then stops with MBDK_ERR_CALLBACK_FAILED). */
typedef int (*mbdk_rhs_fn)(int n, double t, const double *y, double *dydt, void *user_data);

void mbdk_default_options(mbdk_options *opt);

/* Id of a method name ("explicit_euler", "heun", "rk4", "euler_cromer", "implicit_euler",
 * "trapezoidal", "bdf1" ... "bdf6"); 0 when unknown. */
int mbdk_method_id(const char *name);

/* Number of samples a solve writes; returns a status (MBDK_ERR_INVALID_INPUT for a bad h,
 * interval or every; MBDK_NOTE_LAST_STEP_SHORTENED when the interval is not whole steps). */
int mbdk_sample_count(double t0, double t_end, double h, int every, int *nsamp);

/* Integrates y' = f(t, y) from (t0, y0) to t_end. t_out[nsamp], y_out[nsamp][n] (row per
 * sample) are written; *nwritten tells how many samples (fewer only on failure). */
int mbdk_solve_ode(mbdk_rhs_fn f, void *user_data, int n, double t0, double t_end,
                   const double *y0, const mbdk_options *opt, int nsamp, double *t_out,
                   double *y_out, int *nwritten, mbdk_stats *stats);

/* trapezoidal_index3 (kernel/src/dae/mbdk_trapezoidal_index3.f90 is its manual): the index-3
 * DAE of a planar scene integrated by the implicit trapezoidal rule with Newton-Raphson. */
enum mbdk_index3_formulation { MBDK_INDEX3_BOOK = 1, MBDK_INDEX3_AUGMENTED = 2 };

typedef struct mbdk_index3_options {
    int formulation;       /* MBDK_INDEX3_BOOK (the book's scheme) or MBDK_INDEX3_AUGMENTED */
    double h;              /* fixed step, or the first step when adaptive */
    int every;             /* fixed step: keep every k-th step as a sample */
    double newton_rtol, newton_atol;   /* on the position update; max |Phi| <= newton_atol */
    int newton_max_iter;
    double alpha;          /* augmented penalty; 0 = 1e3 max(M) / (h^2/4) at every step */
    int adaptive;          /* non-zero: step-size control (augmented only), samples every dt_out */
    double err_rtol, err_atol, dt_out, h_min, h_max;   /* h_min, h_max: 0 = automatic */
} mbdk_index3_options;

void mbdk_index3_default_options(mbdk_index3_options *opt);

/* Samples an mbdk_index3_solve will write (fixed: as mbdk_sample_count; adaptive: one per dt_out
 * and t_end). Returns a status. */
int mbdk_index3_sample_count(const mbdk_index3_options *opt, double t0, double t_end, int *nsamp);

/* Integrates a scene given by its tables (what mbdk.model.build_tables(scene) makes in Python):
 * nb bodies with mass[nb], inertia[nb]; nj joints, jint[nj][4] = (type, body1, body2,
 * coordinate), jreal[nj][12]; nf force elements, fint[nf][4], freal[nf][12]. Codes and fields:
 * kernel/src/model/mbdk_joints.f90 and mbdk_force_elements.f90 (bodies 1-based, 0 = ground).
 * y0[6 nb] = (q, v), q = (x, y, theta) per body, consistent with the constraints.
 * Outputs, row per sample: t_out[nsamp], y_out[nsamp][6 nb], a_out[nsamp][3 nb],
 * lam_out[nsamp][m] (m = constraint rows), iters_out[nsamp] (Newton iterations of the step).
 * *nwritten samples are valid (fewer only on failure). Returns a status. */
int mbdk_index3_solve(int nb, const double *mass, const double *inertia, int nj, const int *jint,
                      const double *jreal, int nf, const int *fint, const double *freal,
                      const mbdk_index3_options *opt, double t0, double t_end, const double *y0,
                      int nsamp, double *t_out, double *y_out, double *a_out, double *lam_out,
                      int *iters_out, int *nwritten, mbdk_stats *stats);

/* Copies the message of a status into buf (NUL-terminated). */
int mbdk_status_message(int status, char *buf, int buflen);

/* i-th (1-based) entry of the kernel's status table: its code and name ("ERR_NONFINITE").
 * Returns MBDK_ERR_INVALID_INPUT past the end. */
int mbdk_status_entry(int i, int *code, char *name, int namelen);

#ifdef __cplusplus
}
#endif

#endif /* MBDK_H */
