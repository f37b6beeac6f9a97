/* mbdk.h - C API of the mbdk kernel (hand-written mirror of kernel/src/api/mbdk_capi.f90).
 *
 * Link with libmbdk (static, PIC): `pkg-config --cflags --libs mbdk`.
 * Every function returns a status (0 success, > 0 success with a note, < 0 failure) or an id;
 * nothing prints and nothing stops the process. The status table is mirrored from
 * kernel/src/core/mbdk_status.f90; tests/test_status.py checks that the two agree. The structs
 * (options, statistics) are the kernel's bind(C) types; kernel/tests/c_struct_layout.c checks
 * every field's offset against the kernel's own layout (mbdk_struct_field).
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
    MBDK_ERR_INCONSISTENT_INITIAL = -6,
    MBDK_ERR_NO_MEMORY = -7,
    MBDK_ERR_STEP_TOO_SMALL = -10,
    MBDK_ERR_TOO_MANY_STEPS = -11,
    MBDK_ERR_TOO_MUCH_ACCURACY = -12,
    MBDK_ERR_NEWTON_DIVERGED = -20,
    MBDK_ERR_SINGULAR_MATRIX = -21,
    MBDK_ERR_NONFINITE = -30,
    MBDK_ERR_CONSTRAINT_DRIFT = -31,
    MBDK_ERR_ENERGY_DRIFT = -32,
    MBDK_ERR_CONTACT_OVERRUN = -33,
    MBDK_ERR_INVARIANT_DRIFT = -34,
    MBDK_ERR_CALLBACK_FAILED = -40,
    MBDK_ERR_BACKEND = -50,
    MBDK_ERR_INTERRUPTED = -60
};

/* Options of a solve (kernel/src/core/mbdk_options.f90); fill with mbdk_default_options, then
 * set method and h (fixed step) or rtol, atol and dt_out (error-controlled methods). */
typedef struct mbdk_options {
    double h;            /* step size; error-controlled methods: the first step, 0 = automatic */
    double newton_rtol;  /* implicit methods: Newton stops when WRMS(update) < 1 */
    double newton_atol;
    double rtol, atol;   /* error control: WRMS(local error / (atol + rtol |y|)) <= 1;
                            rtol >= 0, atol > 0 */
    double dt_out;       /* error control: a sample every dt_out (dense output); 0: t0, t_end */
    double h_min, h_max; /* error control; 0 = none (h_min: a step must still move t by about
                            10 ulps; h_max: the interval) */
    volatile int *interrupt;  /* NULL, or a flag another thread (or a signal handler) sets
                                 non-zero to stop the solve: MBDK_ERR_INTERRUPTED */
    int64_t max_steps;   /* error control: the most steps (0 = 10^8): MBDK_ERR_TOO_MANY_STEPS */
    int method;          /* from mbdk_method_id("rk4") etc. */
    int every;           /* keep every k-th step as a sample (the last one always) */
    int newton_max_iter;
    int fd_jacobian;     /* non-zero: finite differences even where a Jacobian is given (a C
                            callback's jac, a compiled problem's analytic one) */
    int nq;              /* > 0: y = [q; v] with n = 2*nq (needed by euler_cromer) */
    int startup;         /* k-step methods: MBDK_STARTUP_RK4 (the book) or MBDK_STARTUP_BDF */
    int max_order;       /* bdf, cvode_bdf (5), cvode_adams (12): the highest order; 0 = theirs */
    volatile double *progress;  /* NULL, or where the solve stores the time it has reached,
                                   once per step (for a progress display in another thread) */
} mbdk_options;

/* Start-up of bdf2..bdf6: RK4 steps (the book, (4.80)) or BDF steps of rising order. */
enum mbdk_startup { MBDK_STARTUP_RK4 = 0, MBDK_STARTUP_BDF = 1 };

/* Statistics of a solve (kernel/src/core/mbdk_stats.f90); SciPy's names where they mean the
 * same. */
typedef struct mbdk_stats {
    int64_t steps;              /* accepted steps (start-up steps included) */
    int64_t nfev;               /* evaluations of F (finite-difference columns included) */
    int64_t njev;               /* Jacobian evaluations */
    int64_t nlu;                /* factorisations of a Newton matrix (LU or LDL^T) */
    int64_t newton_iterations;
    int64_t startup_steps;      /* steps of a multistep method's start-up */
    int64_t rejected_steps;     /* step-size control: rejected by the error test */
    int64_t newton_failures;    /* steps retried because Newton failed */
    int64_t order1_steps, order2_steps, order3_steps, order4_steps, order5_steps;
                                /* bdf, cvode_*: accepted steps at each order (cvode_adams
                                   counts orders above 5 in order5_steps) */
    int64_t nlu_sparse;         /* of nlu, those of a DAE method's sparse Newton matrix (a
                                   large scene's DAE: bdf's L D U, ida's KLU); 0 for the
                                   other methods */
    double cpu_time;            /* CPU seconds of the solving thread in the time loop */
    double wall_time;           /* wall-clock seconds of the time loop */
    double t_reached;           /* the last accepted step's time (where a failed solve stopped) */
    double alloc_bytes;         /* MBDK_ERR_NO_MEMORY: bytes of the allocation that failed
                                   (0 where not known); else 0 */
} mbdk_stats;

/* Right-hand side y' = F(t, y). Return 0 on success, non-zero on failure
 * (the solve then stops with MBDK_ERR_CALLBACK_FAILED). */
typedef int (*mbdk_rhs_fn)(int n, double t, const double *y, double *dydt, void *user_data);

/* Jacobian of a right-hand side: dfdy[i + j*n] = dF_i/dy_j (column-major). Return 0 on success.
 * Optional wherever it is asked for (NULL: finite differences). */
typedef int (*mbdk_jac_fn)(int n, double t, const double *y, double *dfdy, void *user_data);

void mbdk_default_options(mbdk_options *opt);

/* Id of a method name; 0 when unknown. Fixed step (opt.h): "explicit_euler", "heun", "rk4",
 * "euler_cromer", "implicit_euler", "trapezoidal", "bdf1" ... "bdf6". Error-controlled
 * (opt.rtol, opt.atol, opt.dt_out): "dopri54", "bs32", "bdf" (variable step and order 1-5),
 * "cvode_bdf", "cvode_adams" (SUNDIALS CVODE). */
int mbdk_method_id(const char *name);

/* Number of samples a solve writes; returns a status (MBDK_ERR_INVALID_INPUT for a bad h,
 * interval or every; MBDK_NOTE_LAST_STEP_SHORTENED when the interval is not whole steps). */
int mbdk_sample_count(double t0, double t_end, double h, int every, int *nsamp);

/* Number of samples mbdk_solve_ode writes with these options, for any method: fixed step
 * (h, every, as mbdk_sample_count) or error-controlled (dopri54, bs32, bdf, cvode_bdf,
 * cvode_adams: t0, every dt_out, t_end). Returns a status. */
int mbdk_solve_sample_count(double t0, double t_end, const mbdk_options *opt, int *nsamp);

/* Integrates y' = f(t, y) from (t0, y0) to t_end; jac (may be NULL) is f's Jacobian for the
 * implicit methods. t_out[nsamp], y_out[nsamp][n] (row per sample) are written; *nwritten tells
 * how many samples (fewer only on failure). */
int mbdk_solve_ode(mbdk_rhs_fn f, mbdk_jac_fn jac, void *user_data, int n, double t0, double t_end,
                   const double *y0, const mbdk_options *opt, int nsamp, double *t_out,
                   double *y_out, int *nwritten, mbdk_stats *stats);

/* trapezoidal_index3 (kernel/src/dae/mbdk_trapezoidal_index3.f90 is its manual): the index-3
 * DAE of a scene integrated by the implicit trapezoidal rule, or another member of the
 * generalized-alpha family (beta, gamma, alpha_m, alpha_f below), with Newton-Raphson. */
enum mbdk_index3_formulation { MBDK_INDEX3_BOOK = 1, MBDK_INDEX3_AUGMENTED = 2 };
/* opt.adaptive: a fixed step, step-size control on the error estimated from differences of the
 * accelerations (second order), or on local Richardson extrapolation (third order: the manual) */
enum mbdk_index3_adaptive { MBDK_INDEX3_FIXED = 0, MBDK_INDEX3_ESTIMATED = 1,
                            MBDK_INDEX3_EXTRAPOLATED = 2 };

typedef struct mbdk_index3_options {
    double h;              /* fixed step, or the first step when adaptive */
    double newton_rtol, newton_atol;   /* on the position update; max |Phi| <= newton_atol */
    double alpha;          /* augmented penalty; 0 = 1e3 max(M) / (h^2/4) at every step */
    double err_rtol, err_atol, dt_out, h_min, h_max;   /* adaptive; h_min, h_max: 0 = automatic */
    volatile int *interrupt;   /* NULL, or a flag set non-zero to stop: MBDK_ERR_INTERRUPTED */
    int formulation;       /* MBDK_INDEX3_BOOK (the book's scheme) or MBDK_INDEX3_AUGMENTED */
    int every;             /* fixed step: keep every k-th step as a sample */
    int newton_max_iter;
    int adaptive;          /* mbdk_index3_adaptive; controlled (augmented only): samples every dt_out */
    volatile double *progress; /* NULL, or where the solve stores the time reached, per step */
    /* the generalized-alpha family (the manual: newmark, hht, generalized_alpha); the defaults
     * 1/4, 1/2, 0, 0 are the trapezoidal rule. beta > 0, gamma > 0, alpha_m < 1, alpha_f < 1 */
    double beta, gamma, alpha_m, alpha_f;
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

/* The element kinds of the scene tables, planar and spatial, in one registry
 * (kernel/src/model/mbdk_elements.f90): jint[j][0] is a joint kind, fint[f][0] a force kind. A
 * name has one code in both kinds of scene (revolute is 1 in a planar and in a spatial scene);
 * the kinds of spatial scenes alone continue the codes after the planar ones. The scene entries
 * of this header build planar scenes, which take the kinds that apply to planar bodies
 * (mbdk_element_kind's on); another kind is MBDK_ERR_INVALID_INPUT. kernel/tests/c_element_table.c
 * checks these enums against the kernel's registry. Table layouts: mbdk_joints.f90,
 * mbdk_force_elements.f90 (planar), mbdk_spatial_model.f90 (spatial). */
enum mbdk_element_class { MBDK_CLASS_JOINT = 1, MBDK_CLASS_FORCE = 2, MBDK_CLASS_EFFECT = 3 };
enum mbdk_joint_kind { MBDK_JOINT_REVOLUTE = 1, MBDK_JOINT_PRISMATIC = 2, MBDK_JOINT_FIXED = 3,
                       MBDK_JOINT_DRIVER = 4, MBDK_JOINT_DISTANCE = 5, MBDK_JOINT_POINT_LINE = 6,
                       MBDK_JOINT_POINT_CURVE = 7, MBDK_JOINT_COUPLING = 8,
                       MBDK_JOINT_ROLLING = 9, MBDK_JOINT_KNIFE_EDGE = 10,
                       MBDK_JOINT_SPHERICAL = 11, MBDK_JOINT_UNIVERSAL = 12,
                       MBDK_JOINT_CYLINDRICAL = 13, MBDK_JOINT_ANGLE_DRIVER = 14,
                       MBDK_JOINT_SLIDE_DRIVER = 15 };
enum mbdk_force_kind { MBDK_FORCE_GRAVITY = 1, MBDK_FORCE_POINT = 2, MBDK_FORCE_TORQUE = 3,
                       MBDK_FORCE_SPRING_DAMPER = 4, MBDK_FORCE_COORDINATE = 5,
                       MBDK_FORCE_SPRING = 6, MBDK_FORCE_DAMPER = 7, MBDK_FORCE_CONTACT = 8,
                       MBDK_FORCE_FRICTION = 9, MBDK_FORCE_SPHERE_PLANE = 11,
                       MBDK_FORCE_SPHERE_SPHERE = 12 };
/* Effects share the force table and its codes, and carry states
 * (kernel/src/model/mbdk_wear.f90): a scene with nw wear elements has the state [q; v; w],
 * 6 nb + nw values per sample (a spatial scene: its bodies' state, then the nw volumes). */
enum mbdk_effect_kind { MBDK_EFFECT_WEAR = 10 };

/* The planar tables, field by field (their home: kernel/src/model/mbdk_joints.f90,
 * mbdk_force_elements.f90, mbdk_contact.f90, mbdk_contact_law.f90, mbdk_wear.f90). Bodies are
 * 1-based, 0 is the ground (its points and axes global); points s are body-fixed (x, y) from the
 * centroid. A time function f is 5 reals (offset, rate, amplitude, omega, phase):
 * f(t) = offset + rate t + amplitude sin(omega t + phase); a constant c is (c, 0, 0, 0, 0).
 *
 * jint[j] = (kind, body1, body2, k4), jreal[j][0..11] (C indices):
 *   REVOLUTE    P1 = P2                  s1 = jreal[0..1], s2 = jreal[2..3]
 *   PRISMATIC   n2.(P1 - P2) = 0, theta1 - theta2 = theta0: points as revolute, axis u2 =
 *               jreal[4..5] fixed in body2, theta0 = jreal[6] (k4 = MBDK_FROM_POSE: from y0)
 *   FIXED       the revolute rows and theta1 - theta2 = theta0 (jreal[6], or from y0)
 *   DRIVER      coordinate k4 (1 x, 2 y, 3 angle) of body1 = f(t), f = jreal[7..11]
 *   DISTANCE    |P1 - P2| = L(t), points as revolute, L = jreal[7..11] (k4 = MBDK_FROM_POSE:
 *               L's offset from y0)
 *   POINT_LINE  s1 of body1 on the line through s2 of body2 along jreal[4..5] (body2's frame)
 *   POINT_CURVE s1 of body1 on the ground curve y = f(x), f = jreal[7..11] taken in x
 *   COUPLING    a . q_body1 + b . q_body2 = c(t), a = jreal[0..2], b = jreal[3..5] on (x, y,
 *               angle), c = jreal[7..11] (k4 = MBDK_FROM_POSE: c's offset from y0)
 *   ROLLING     a disc of radius jreal[6] centred at body1's centroid rolls on the ground line
 *               through jreal[2..3] along the unit jreal[4..5], on its left; no-slip offset c0 =
 *               jreal[7] (k4 = MBDK_FROM_POSE: from y0)
 *   KNIFE_EDGE  s1 = jreal[0..1] of body1 has no velocity across the blade jreal[4..5] (body1's
 *               frame): a nonholonomic row
 * fint[f] = (kind, body1, body2, k4), freal[f][0..11]:
 *   GRAVITY     g = freal[0..1] on every body
 *   POINT       F(t) = freal[2..3] f(t) (global) at s = freal[0..1] of body1, f = freal[7..11]
 *   TORQUE      T(t) = freal[0] f(t) on body1, f = freal[7..11]
 *   SPRING_DAMPER, SPRING, DAMPER  between s1 = freal[0..1] on body1 and s2 = freal[2..3] on
 *               body2: tension k (L - L0) + c L', k = freal[4], L0 = freal[5] (k4 =
 *               MBDK_FROM_POSE: from y0), c = freal[6] (SPRING: c = 0, DAMPER: k = 0)
 *   COORDINATE  on coordinate k4 of body1: -k (q - q0) - c q', k = freal[0], c = freal[1],
 *               q0 = freal[2]
 *   CONTACT     geometry k4: 1 circle (radius r1, 0: a point) on the line through s2 with the
 *               normal angle a (body2's frame), 2 circle on circle r2, 3 circle inside the hollow
 *               circle r2, 4 involute gear pair; freal: s1 [0..1], r1 [2], s2 [3..4], a or r2 [5],
 *               then the IMPACT law: k [6], exponent e >= 1 [7], cmax [8], dmax [9] (the gear
 *               pair: base radii [0..1], tip radii [2..3], base pitch [4], mesh phase [5], the law
 *               [6..9], flank phase [10], hand +1/-1 [11])
 *   FRICTION    regularised Coulomb friction of the contact in column k4 (1-based) of this
 *               table: freal = (mus, mud, vs, vd), 0 < vs < vd
 *   EFFECT_WEAR jint-like fint = (kind, law, load, column): law 1 archard, 2 gear, 3 knee; load 1
 *               the normal force of the contact in column, 2 the force of the friction element
 *               in column; freal[0] = k; gear: freal[1..6] = R, Ts, a_x, t0, Ea, Rg; knee:
 *               freal[1..4] = c0..c3 (S/R(t) = c0 + c1 t + c2 t^2 + c3 t^3). Each carries one
 *               state, its worn volume, after the bodies' in y.
 * The spatial tables (mbdk_stepper_create_spatial; kernel/src/spatial/mbdk_spatial_model.f90):
 * jreal[j][0..16] = s_i (3), s_j (3), a_i (3, body i's frame), a_j (3, body j's frame), a time
 * function (5; ANGLE_DRIVER and SLIDE_DRIVER); freal[f][0..18]: GRAVITY g (3); POINT s (3, body
 * frame), F (3, global); TORQUE n (3, global); SPRING_DAMPER s_i (3), s_j (3), k, c, L0;
 * SPHERE_PLANE, SPHERE_SPHERE s1 [0..2] on body i, r1 [3], s2 [4..6] on body j, the plane's
 * normal n2 [7..9] (body j's frame), r2 [10], the IMPACT law (k, e >= 1, cmax, dmax) [11..14],
 * friction (mus, mud, vs, vd) [15..18] (mus = mud = 0: none). */

/* The 4th integer of a prismatic or fixed joint (jint[j][3]), of a distance joint, or of a
 * spring, damper or spring-damper (fint[f][3]): take the relative angle, the length L(0), or
 * the rest length from the initial pose (y0) instead of the table. */
enum { MBDK_FROM_POSE = 1 };

/* Body kinds (the same file): the coordinates and velocities a body carries, and whether a model
 * of the kernel runs bodies of the kind (available). Planar bodies run in the planar model, the
 * one of this header's planar scene entries; spatial bodies (chapter 5) in the spatial model,
 * which the spatial steppers below and Python (python/mbdk/spatial_model.py) reach. */
enum mbdk_body_kind { MBDK_BODY_PLANAR = 1, MBDK_BODY_SPATIAL = 2 };
enum { MBDK_BODY_KINDS = 2 };
/* The body kinds an element kind applies to, as bits: bit k - 1 for body kind k. */
enum mbdk_body_set { MBDK_ON_PLANAR = 1, MBDK_ON_SPATIAL = 2 };
int mbdk_body_kind(int i, int *code, char *name, int namelen, int *coords, int *velocities,
                   int *available);

/* Entry i (1-based) of the kernel's element registry: class, code, name, the body kinds it
 * applies to (on: MBDK_ON_* bits), its constraint rows on each body kind (rows[k - 1] on body
 * kind k: an array of MBDK_BODY_KINDS), states. MBDK_ERR_INVALID_INPUT past the end. */
int mbdk_element_kind(int i, int *cls, int *code, char *name, int namelen, int *on, int *rows,
                      int *states);

/* Options of a scene model (kernel/src/model/mbdk_model.f90): the formulation of the ODE
 * methods, the linear solver and the formulations' parameters. mbdk_index3_solve uses the
 * defaults. */
enum mbdk_formulation { MBDK_FORM_REDUCED = 1, MBDK_FORM_BAUMGARTE = 2, MBDK_FORM_PENALTY = 3,
                        MBDK_FORM_PROJECTION = 4 };
enum mbdk_solver { MBDK_SOLVER_AUTO = 1, MBDK_SOLVER_SCHUR = 2, MBDK_SOLVER_KKT = 3,
                   MBDK_SOLVER_REVOLUTE = 4, MBDK_SOLVER_SPARSE = 5 };
typedef struct mbdk_model_options {
    double baumgarte_alpha, baumgarte_beta;              /* (3.29) */
    double penalty_alpha, penalty_omega, penalty_mu;     /* Jalon-Bayo (3.35)-(3.40) */
    double projection_tol;        /* max |Phi| after the projection of q (at least its roundoff) */
    int formulation;              /* enum mbdk_formulation */
    int solver;                   /* enum mbdk_solver */
    int small_dense;              /* 0: LAPACK for every factorisation */
    int projection_max_iter;
    /* what a run must keep (kernel/src/model/mbdk_watch.f90): |Phi| per length scale, the
     * velocity residual per size of its terms, the energy balance per energy scale; a run that
     * leaves them ends with MBDK_ERR_CONSTRAINT_DRIFT or MBDK_ERR_ENERGY_DRIFT; <= 0: off.
     * Start from mbdk_model_default_options (a zeroed struct turns the tests off). */
    double watch_position, watch_velocity, watch_energy;
    int watch_every;              /* steps between checks; 0: the default (16) */
    int locate_events;            /* 1: dopri54 and bs32 end a step where a contact closes or opens */
    /* the momenta and angular momenta the scene conserves, per the size of their terms
     * (mbdk_watch.f90 says which); MBDK_ERR_INVARIANT_DRIFT past it; <= 0: off */
    double watch_momentum;
} mbdk_model_options;

/* The defaults of every field; start from them and set what differs. */
void mbdk_model_default_options(mbdk_model_options *opt);

/* Options of a spatial scene's model (kernel/src/spatial/mbdk_spatial_model.f90, whose header
 * is its manual): the formulation of the ODE methods (enum mbdk_formulation, as for planar
 * scenes) with the same parameters, the orientation coordinates and how a quaternion keeps its
 * unit norm, and the watch. Start from mbdk_spatial_default_options. */
enum mbdk_rotation { MBDK_ROT_QUATERNION = 1, MBDK_ROT_EULER313 = 2, MBDK_ROT_CARDAN123 = 3 };
enum mbdk_coordinates { MBDK_COORDS_ABSOLUTE = 0, MBDK_COORDS_JOINT = 1 };
enum mbdk_quaternion_norm { MBDK_NORM_PROJECT = 1, MBDK_NORM_STABILISE = 2, MBDK_NORM_NONE = 3 };
typedef struct mbdk_spatial_options {
    double baumgarte_alpha, baumgarte_beta;              /* (3.29) */
    double penalty_alpha, penalty_omega, penalty_mu;     /* Jalon-Bayo (3.35)-(3.40) */
    /* angle sets: an evaluation within this distance of the gimbal lock (|sin theta| for 3-1-3,
     * |cos beta| for 1-2-3) is MBDK_ERR_SINGULAR_MATRIX; 0: off */
    double lock_guard;
    double norm_gain;             /* MBDK_NORM_STABILISE: k of p' = ... + k (1 - |p|^2) p / 2, 1/s */
    double projection_tol;        /* max |Phi| after a projection */
    /* as mbdk_model_options' (<= 0: off); watch_quaternion: | |p| - 1 | of every quaternion */
    double watch_position, watch_velocity, watch_energy, watch_momentum, watch_quaternion;
    int formulation;              /* enum mbdk_formulation */
    int rotation;                 /* enum mbdk_rotation */
    int norm;                     /* enum mbdk_quaternion_norm */
    int watch_every;              /* steps between checks; 0: the default (16) */
    int locate_events;            /* 1: dopri54 and bs32 end a step where a contact closes or opens */
    /* enum mbdk_coordinates: the bodies' absolute coordinates, or joint coordinates on a
     * spanning tree of the joints (kernel/src/spatial/mbdk_joint_coords.f90), the f2py entry
     * spatial_run's ODE methods only: the steppers return MBDK_ERR_NOT_APPLICABLE for it */
    int coordinates;
} mbdk_spatial_options;

void mbdk_spatial_default_options(mbdk_spatial_options *opt);

/* A spatial scene's tables (the f2py entry spatial_run's, mbdk_spatial_model.f90): nb bodies with
 * mass[nb] and inertia[nb][3][3] (about the centre, body frame); nj joints, jtype[nj] (enum
 * mbdk_joint_kind of a kind on spatial bodies), jbody[nj][2] (1-based, 0 = the ground),
 * jreal[nj][MBDK_SPATIAL_JOINT_REALS] = (s_i, s_j, a_i, a_j, time function); nf forces,
 * ftype[nf], fbody[nf][2], freal[nf][MBDK_SPATIAL_FORCE_REALS]. A wear element is an entry of
 * the force table too (ftype MBDK_EFFECT_WEAR): fbody = (its contact's entry, 1-based; the
 * law, 1 archard or 3 knee), freal = (k, the knee's c0..c3, the load: 1 the contact's normal
 * force, 2 its friction force). The state, body by body: q_b = (r, p), p a quaternion (4,
 * scalar first) or three angles as opt.rotation says, then w_b = (r', Omega), Omega in the
 * body frame: nb (7 + 6) values with quaternions; then the worn volume of each wear element,
 * in table order (none without). */
enum { MBDK_SPATIAL_JOINT_REALS = 17, MBDK_SPATIAL_FORCE_REALS = 19 };

/* The report of the watch's check that stopped a run (kernel/src/model/mbdk_watch.f90):
 * quantity 1 position, 2 velocity, 3 energy, 4 momentum, 5 quaternion norm (0 while nothing
 * failed); row 1-based: the constraint row, the conserved component or the body (0 for energy);
 * value per its scale, the tolerance, t of the failed check, t_good of the last check passed, the
 * value itself (absolute) and its scale. */
typedef struct mbdk_watch_report {
    double value, tol, t, t_good, absolute, scale;
    int quantity, row;
} mbdk_watch_report;

/* The kernel's layout of the structs above, for checking a binding against it: struct id
 * 1 mbdk_stats, 2 mbdk_options, 3 mbdk_index3_options, 4 mbdk_model_options,
 * 5 mbdk_spatial_options, 6 mbdk_watch_report. Field types:
 * 1 int, 2 int64_t, 3 double, 4 pointer. Both return MBDK_ERR_INVALID_INPUT past the end. */
int mbdk_struct_info(int id, char *name, int namelen, int *nbytes, int *nfields);
int mbdk_struct_field(int id, int i, char *name, int namelen, int *offset, int *type);

/* A stepper: a solve advanced by the caller, one step or up to a time at a time
 * (kernel/src/api/mbdk_capi_stepper.f90 is its manual). Steps land on t0 + k opt.h, so a stepper
 * and mbdk_solve_ode give the same bits. A scene stepper integrates model_opt's formulation with
 * a fixed-step ODE method (an error-controlled one is MBDK_ERR_NOT_APPLICABLE: it chooses its
 * own steps over a whole interval, mbdk_solve_ode); an index-3 stepper runs trapezoidal_index3.
 * After a failure the last good state
 * stays readable and further steps return MBDK_ERR_NOT_APPLICABLE; the multipliers are those of
 * the last step attempted. The stepper copies the options, tables and y0, except the options'
 * interrupt flag: it keeps that address, which must stay valid until the stepper is destroyed.
 * Its statistics count work; cpu_time and wall_time stay 0 (the caller times its own loop).
 * A stepper whose arrays cannot be allocated is not created: MBDK_ERR_NO_MEMORY, *stepper NULL
 * (the size asked for is reported by the whole-interval solves only, in mbdk_stats). */
typedef struct mbdk_stepper mbdk_stepper;

int mbdk_stepper_create_ode(mbdk_rhs_fn f, mbdk_jac_fn jac, void *user_data, int n, double t0,
                            const double *y0, const mbdk_options *opt, mbdk_stepper **stepper);
/* y0 = (q, v, w): 6 nb values and then the initial volumes of the scene's wear elements, if
 * any (mbdk_stepper_size gives the state's length). (q, v) must meet the joints, |Phi| and
 * |D v + Phi_t| within 1e-6 of the scene's size: MBDK_ERR_INCONSISTENT_INITIAL otherwise (the
 * stepper does not assemble the state) */
int mbdk_stepper_create_scene(int nb, const double *mass, const double *inertia, int nj,
                              const int *jint, const double *jreal, int nf, const int *fint,
                              const double *freal, const mbdk_model_options *model_opt,
                              const mbdk_options *opt, double t0, const double *y0,
                              mbdk_stepper **stepper);
/* trapezoidal_index3 on a scene, fixed step (opt->adaptive must be 0) */
int mbdk_stepper_create_index3(int nb, const double *mass, const double *inertia, int nj,
                               const int *jint, const double *jreal, int nf, const int *fint,
                               const double *freal, const mbdk_index3_options *opt, double t0,
                               const double *y0, mbdk_stepper **stepper);
/* The same two on a spatial scene (its tables and state as above): an ODE method of opt on the
 * model's formulation, y0 = (q, w) and the initial wear volumes after them, as
 * mbdk_stepper_create_scene takes them; and the index-3 family (trapezoidal_index3, or newmark,
 * hht, generalized_alpha by opt's beta, gamma, alpha_m, alpha_f; fixed step; a scene with wear
 * is MBDK_ERR_NOT_APPLICABLE, its state [q; w] has no place for the volumes). The stepping is
 * the planar steppers' own, over the mechanism interface. */
int mbdk_stepper_create_spatial(int nb, const double *mass, const double *inertia, int nj,
                                const int *jtype, const int *jbody, const double *jreal, int nf,
                                const int *ftype, const int *fbody, const double *freal,
                                const mbdk_spatial_options *spatial_opt, const mbdk_options *opt,
                                double t0, const double *y0, mbdk_stepper **stepper);
int mbdk_stepper_create_spatial_index3(int nb, const double *mass, const double *inertia, int nj,
                                       const int *jtype, const int *jbody, const double *jreal,
                                       int nf, const int *ftype, const int *fbody,
                                       const double *freal,
                                       const mbdk_spatial_options *spatial_opt,
                                       const mbdk_index3_options *opt, double t0,
                                       const double *y0, mbdk_stepper **stepper);
/* A scene's tables from its file (kernel/src/api/mbdk_scene_tables.c): the scene file (TOML, by
 * name) is read by mbdk's one scene reader, whose checks name the file, element, field and value;
 * `mbdk tables SCENE -o FILE` writes its tables and the initial state its runs start from
 * (assembled) as a small TOML file (python/mbdk/tables_file.py lists the keys), which
 * mbdk_scene_tables_read reads into the arrays the stepper constructors above take: planar
 * scenes jint, jreal, fint, freal; spatial scenes jtype, jbody, jreal, ftype, fbody, freal and
 * the rotation (enum mbdk_rotation) of y0's orientation coordinates. n = len(y0): the bodies'
 * coordinates, their rates, then the wear elements' volumes (its length checked against the
 * tables). A malformed file is MBDK_ERR_INVALID_INPUT (a missing one too), memory short of its
 * arrays MBDK_ERR_NO_MEMORY, and message (NUL-terminated, message_len bytes) names the file, the
 * line, the key and the value; nothing stays allocated after a failure.
 * mbdk_scene_tables_free frees what a successful read allocated. */
enum mbdk_scene_kind { MBDK_SCENE_PLANAR = 1, MBDK_SCENE_SPATIAL = 2 };
typedef struct mbdk_scene_tables {
    int kind;                   /* enum mbdk_scene_kind */
    int rotation;               /* spatial: enum mbdk_rotation; planar: 0 */
    int norm;                   /* spatial: enum mbdk_quaternion_norm, the scene's; planar: 0 */
    double norm_gain;           /* spatial: the scene's MBDK_NORM_STABILISE gain, 1/s */
    int nb, nj, nf, n;          /* bodies, joint rows, force rows (wear entries too), len(y0) */
    double t0;                  /* the time y0 is at */
    double *mass, *inertia, *jreal, *freal, *y0;
    int *jint, *fint;                       /* planar scenes (NULL on spatial ones) */
    int *jtype, *jbody, *ftype, *fbody;     /* spatial scenes (NULL on planar ones) */
    char name[128];             /* the scene's name */
} mbdk_scene_tables;
int mbdk_scene_tables_read(const char *path, mbdk_scene_tables *tables, char *message,
                           int message_len);
void mbdk_scene_tables_free(mbdk_scene_tables *tables);
/* A stepper for a fixed-step ODE method (opt: method, h, ...) on the tables' scene from (t0,
 * y0) with the options simulate takes by default: the model's defaults, the formulation given
 * (enum mbdk_formulation; 0: the default), Baumgarte's gains 1/h and sqrt(2)/h, a spatial
 * scene's rotation and quaternion norm as its file says; its steps are simulate's to the bit.
 * Other options: the constructors above with the tables' arrays (the index-3 family:
 * mbdk_stepper_create_index3 / _spatial_index3). */
int mbdk_stepper_create_tables(const mbdk_scene_tables *tables, int formulation,
                               const mbdk_options *opt, mbdk_stepper **stepper);
int mbdk_stepper_step(mbdk_stepper *stepper);                 /* to the next grid point */
/* up to t, landing on it; t before the stepper's time: MBDK_ERR_INVALID_INPUT */
int mbdk_stepper_advance(mbdk_stepper *stepper, double t);
int mbdk_stepper_state(const mbdk_stepper *stepper, double *t, double *y, int n);
int mbdk_stepper_size(const mbdk_stepper *stepper, int *n, int *m);
int mbdk_stepper_multipliers(mbdk_stepper *stepper, double *lam, int m);   /* scenes; evaluates */
int mbdk_stepper_stats(const mbdk_stepper *stepper, mbdk_stats *stats);
/* After MBDK_ERR_CONSTRAINT_DRIFT, MBDK_ERR_ENERGY_DRIFT or MBDK_ERR_INVARIANT_DRIFT (scene and
 * index-3 steppers, planar or spatial): what the watch found. ODE steppers:
 * MBDK_ERR_NOT_APPLICABLE. */
int mbdk_stepper_watch_report(const mbdk_stepper *stepper, mbdk_watch_report *report);
/* At the current state of a scene or index-3 stepper (planar or spatial): out[0..4] = kinetic
 * energy, gravity potential, spring potential (contacts' included), max |Phi|, max |C v +
 * Phi_t|. ODE steppers: MBDK_ERR_NOT_APPLICABLE. */
enum { MBDK_STEPPER_NOUT = 5 };
int mbdk_stepper_outputs(mbdk_stepper *stepper, double *out, int nout);
/* A planar scene's joint reactions reac[nj][3] at the current state: force (x, y) and moment
 * about the joint point that each joint exerts on its first body, global frame, from the
 * stepper's multipliers; nj the table's joints. Spatial or ODE steppers:
 * MBDK_ERR_NOT_APPLICABLE. */
int mbdk_stepper_reactions(mbdk_stepper *stepper, double *reac, int nj);
/* A load's value between steps (a co-simulation's input): slot (1-based) of force-table entry
 * (1-based) becomes value, times the element's time function as in the table. Only a point
 * force's components (planar slots 3, 4; spatial 4..6, space frame) and a torque's (planar 1;
 * spatial 1..3): loads enter no assembly or potential, so an explicit method's next steps are
 * the scene's with that value written in (an implicit method's reused Newton matrix is an
 * approximation until refreshed). The watch then holds the scene to no conserved momentum.
 * Anything else: MBDK_ERR_INVALID_INPUT. */
int mbdk_stepper_set_force(mbdk_stepper *stepper, int entry, int slot, double value);
/* A copy of the whole stepper (state, method history and factors, statistics, watch): the
 * copy's steps are the bits the original's would be. *dst NULL: a new stepper; else *dst (a
 * stepper of the same scene and kind) is overwritten, which is how a co-simulation master's
 * rollback restores a saved stepper. The copy shares user_data and the interrupt flag's
 * address. */
int mbdk_stepper_copy(const mbdk_stepper *src, mbdk_stepper **dst);
int mbdk_stepper_destroy(mbdk_stepper *stepper);              /* NULL: nothing to do */

/* Copies the message of a status into buf (NUL-terminated). */
int mbdk_status_message(int status, char *buf, int buflen);

/* i-th (1-based) entry of the kernel's status table: its code and name ("ERR_NONFINITE").
 * Returns MBDK_ERR_INVALID_INPUT past the end. */
int mbdk_status_entry(int i, int *code, char *name, int namelen);

#ifdef __cplusplus
}
#endif

#endif /* MBDK_H */
