!> trapezoidal_index3: direct integration of the index-3 DAE of a mechanism, planar or spatial
!> (mbdk_mechanism, whose velocity form is written here: q' = T(q) v, C = dPhi/dq T)
!>
!>   M v' + C(q)^T lambda = f(q, v, t),   Phi(q, t) = 0
!>
!> by the implicit trapezoidal rule (Fekete (2023) 3.2.1). The unknown of a step is its
!> increment dq in the velocities' coordinates, q+ = q (+) dq (the mechanism's retraction:
!> q + dq for planar bodies, for a spatial body its position moved by dr and its orientation
!> turned by the body-frame rotation dtheta, R+ = R exp(dtheta); the trapezoidal dtheta =
!> (h/2)(Omega + Omega+) is the rotation over the step to its O(h^3)). With s = h^2/4 and the
!> trapezoidal relations (3.12)-(3.13),
!>   v+ = (2/h) dq - v,     a+ = (4/h^2) dq - (4/h) v - a,
!> the equations of motion at t+ = t + h, multiplied by s (3.15), read
!>   r(dq, lambda+) = M (dq - dqhat) + s (C^T lambda+ - f) = 0,   dqhat = h v + s a.
!> (An increment, not q+ itself, carries the roundoff of the step's motion, not of the
!> coordinates: eps |q| / h in the velocities from positions far from the origin would not
!> shrink with h.) For planar bodies this is the book's scheme on q+ = q + dq.
!>
!> The generalized-alpha family (opt%beta, gamma, alpha_m, alpha_f; Chung and Hulbert 1993 in
!> the form of Arnold and Bruls 2007, which keeps the equations of motion at t+ and carries the
!> alphas in a pseudo-acceleration ap; on spatial bodies with the retraction above, the Lie-group
!> form of Bruls and Cardona 2010):
!>   dq = h v + h^2 (1/2 - beta) ap + h^2 beta ap+,   v+ = v + h (1 - gamma) ap + h gamma ap+,
!>   (1 - alpha_m) ap+ + alpha_m ap = (1 - alpha_f) a+ + alpha_f a,
!>   M a+ + C^T lambda+ = f(q+, v+, t+),   Phi(q+) = 0.
!> Times cs = beta h^2 (1 - alpha_f) / (1 - alpha_m) the equations of motion read r = M (dq -
!> dqhat) + cs (C^T lambda+ - f) with dqhat = h v + h^2 (1/2 - beta) ap - beta h^2 (alpha_m ap -
!> alpha_f a) / (1 - alpha_m), and v+ depends on dq through gamma / (beta h): the same Newton,
!> matrix (stiffness and multipliers times cs, damping times gamma h (1 - alpha_f) /
!> (1 - alpha_m)), projections and rank-loss handling as below serve every member. The members
!> (Python's method names set the parameters):
!>   trapezoidal_index3   beta 1/4, gamma 1/2, alpha_m = alpha_f = 0 (ap = a): the book's rule,
!>                        its coefficients computed as its own (2/h, 4/h^2, h^2/4) to the bit
!>   newmark              beta, gamma; alpha_m = alpha_f = 0 (gamma > 1/2 damps, first order)
!>   hht                  alpha in [-1/3, 0]: alpha_m = 0, alpha_f = -alpha, gamma = 1/2 - alpha,
!>                        beta = (1 - alpha)^2 / 4 (HHT's linear spectral properties; the forces
!>                        are not weighted in time as in Hilber, Hughes and Taylor's own form)
!>   generalized_alpha    rho_inf in [0, 1]: alpha_m = (2 rho - 1) / (rho + 1), alpha_f = rho /
!>                        (rho + 1), gamma = 1/2 - alpha_m + alpha_f, beta = (1 - alpha_m +
!>                        alpha_f)^2 / 4; rho_inf = 1 is the trapezoidal rule again (ap = a
!>                        from a consistent start), to roundoff
!> Second order in q and v for gamma = 1/2 - alpha_m + alpha_f. The pseudo-acceleration starts
!> at its shifted time (shifted_start), and moves with it where h changes (attempt). Step-size
!> control: the estimated mode (opt%adaptive = 1) on every second-order member, with the
!> member's own local error constants (mbdk_index3_error_constants); the extrapolated mode on the
!> trapezoidal rule alone.
!>
!> Formulations (mbdk_index3_options_t%formulation):
!>   1 index3     the book's scheme: Newton-Raphson (3.16) on (dq, lambda+) for r = 0 and
!>                Phi(q+) = 0, multiplier predictor (3.11) lambda+ = lambda + (h/h-)(lambda -
!>                lambda-), increment predictor h v + (h^2/2) a. v+ and a+ follow from the
!>                trapezoidal relations and do not satisfy Phi' = 0, Phi'' = 0: the weakness the
!>                book names. Worse, the errors of v and a in the constraint directions
!>                alternate in sign from step to step with a growing amplitude (the trapezoidal
!>                rule on an index-3 system is unstable there: Cardona and Geradin 1989): on the
!>                double pendulum, the four-bar and the crane |C a - gamma| grows about 15-fold
!>                per 1.4 s whatever h, until Newton fails after a few seconds (5.0 s on the
!>                four-bar, 10.7 s on the double pendulum at h = 1e-3: studies/index3.py).
!>   2 augmented  the index-3 augmented Lagrangian with projections (ALI3-P: Bayo and Ledesma
!>                1996; Cuadrado, Cardenal and Bayo 1997; the family the book cites in [6], [20],
!>                [23]): Newton on dq alone for
!>                  M (dq - dqhat) + s (C^T (lam* + alpha Phi) - f) = 0,
!>                with lam* <- lam* + alpha Phi after every iteration, from the predictor
!>                h v + s (a + a_x), a_x = a + (h/h-)(a - a-) (the rule itself with a+
!>                extrapolated: O(h^4)) and lam* extrapolated likewise. Then the mass-orthogonal
!>                projections of v+ onto C v + Phi_t = 0 and of a+ onto C a = gamma (one
!>                factorisation of [M C^T; C 0], through C M^-1 C^T when M > 0; where C has
!>                lost a rank, redundant joints or a singular configuration, the regular
!>                augmented Lagrangian path of the mechanism's solve, and likewise for the
!>                consistent a and lambda at t0), computed so that
!>                the Newton error of q+ is not amplified: P removes every M^-1 C^T term, so
!>                  v+ = P (v + (h/2)(a + a~)),  a~ any solution of M a~ = f - C^T (..),
!>                equals P ((2/h) dq - v) once Newton has converged, without its 2/h times
!>                the Newton error; and a+, lambda+ solve M a + C^T lambda = f, C a = gamma(q+,
!>                v+), the projection of a+ with its multipliers (second order), without the
!>                4/h^2 times the Newton error of the trapezoidal a+ (taken from the
!>                relations, v+ and a+ would carry Newton's tolerance amplified by 2/h and
!>                4/h^2, an error that grows as h shrinks). Without constraints the same path
!>                gives a+ = M^-1 f.
!>                Parameters: alpha, the penalty factor (force per unit of Phi). Default
!>                alpha = 0: at every step alpha = KAPPA max(M) / s, KAPPA = 1e3 (s: cs below
!>                for the family's members), so that s alpha
!>                C^T C outweighs M a thousandfold whatever h; then Phi shrinks about 1000-fold
!>                per multiplier update. A fixed alpha (the literature's 1e7-1e9) converges
!>                slowly at small h (s alpha ~ M: the step-size controller then stalls) and
!>                makes the matrix ill-conditioned at large h. newton_max_iter: default 20.
!>
!> Newton matrix. Planar scenes (the model's has_i3_matrix: mbdk_index3_matrix) analytic;
!> tangent stiffness and damping of the force elements from mbdk_forces_tangent, geometric
!> stiffness of the joints from mbdk_joints_tangent:
!>   index3:    [M + s (K_c(lambda) + K_f) + (h/2) C_f, C^T; C, 0] in the unknowns (dq, s dlambda)
!>   augmented: M + s (K_c(lam*) + K_f + alpha C^T C) + (h/2) C_f. K_c takes lam* without
!>              alpha Phi: that term vanishes at the solution, and far from it (the predictor)
!>              it inflates the geometric stiffness until Newton's first step overshoots.
!> The book scales both rows by s (3.15)-(3.16) with lambda itself as unknown: its matrix
!> [M + .., s C^T; s C, 0] has a condition number growing like h^-4. Scaling the unknown to
!> s lambda and leaving Phi unscaled gives the same Newton iterates (row and column scalings do
!> not change Newton's steps) with a condition number bounded as h -> 0 (studies/index3.py
!> measures both; mbdk_index3_newton_matrix builds all three forms). A mechanism without its own
!> tangents (spatial scenes: the gyroscopic moment, the rotations' retraction and the contacts
!> make them long to write) gets the residual's Jacobian by forward differences in each
!> component of dq (build_matrix: one evaluation per column, the multipliers' update
!> lam* + alpha Phi and the retraction included; the book form's columns of s lambda are C^T),
!> factorised by mbdk_lapack's LU; it is reused as the analytic one is.
!>
!> Newton. On planar scenes, up to MBDK_SMALL_DENSE_MAX rows the matrix is factorised by the
!> tiny-system routines (a call's overhead dominates such systems; model%small_dense = false,
!> or more rows, take mbdk_lapack's general LU): the augmented form's matrix, when symmetric
!> to roundoff (no dampers: their tangent stiffness is unsymmetric) and positive definite, by
!> the block LDL^T with the bodies as 3 x 3 pivot blocks (symmetry halves the LU's work);
!> otherwise by the LU with partial pivoting. An LU that has served two solves forms its
!> explicit inverse for the next ones (a fixed-length column product, a quarter of the
!> triangular sweeps at 10 rows: the book scheme's matrix serves about 30 solves; stats%nlu
!> counts either kind). The matrix is reused across iterations and steps
!> while Newton contracts. It is rebuilt at the current iterate when the contraction rate exceeds
!> 0.5 or two more iterations at the current rate would not reach the tolerance (an iteration
!> costs about a factorisation), and when h changes. When an update grows with an old matrix, the
!> step restarts once from the predictor with a matrix built there (the augmented form's
!> multiplier update can spoil the iterate beyond repair), and the next 8 steps start with fresh
!> matrices, twice as many after each such failure until a step is served by an old matrix again
!> (with alpha C^T C a thousand times M, a matrix from the last step fails once h |omega| is above
!> about 1e-3). A step converges when the update computed at an iterate is below 1 in the weighted
!> norm (atol + rtol |q|; for a spatial body's rotation, atol + rtol: its coordinates' size is
!> 1, the mechanism's coord_weights) and max |Phi| <= atol there (not below 64 eps max|q|; a step whose
!> multipliers were frozen at a rank loss: below), or, in the book form, where the update's
!> roundoff floor lies above that tolerance (a long chain, whose matrix's conditioning grows with
!> its length), when an update from a matrix built at its iterate no longer halves and is within
!> NOISE tolerances (the matrix of a scene with dampers is its symmetric part on the sparse
!> path: an approximation whose linear rate can look like such a stall, accepted within those
!> NOISE tolerances too). That
!> last update is applied. In the
!> augmented form the update's target is tighter where the step's local error is small: what
!> Newton leaves (the update times rate/(1 - rate)) below LOCAL_SHARE of the local error
!> estimate, so that it does not add up over the 1/h steps (newton_converged); and where the
!> last update leaves |Phi| at q+ above atol, one projection of q+ follows (keep_joints). At least two
!> evaluations per step, so both tests are made on evaluated residuals, never on predicted ones.
!> After newton_max_iter updates it fails with MBDK_ERR_NEWTON_DIVERGED (a singular matrix:
!> SINGULAR_MATRIX).
!>
!> Singular configurations (augmented form). Where C is close to losing a rank (a four-bar
!> chain's flat pose, a dead point) a multiplier update reduces Phi along the vanishing direction
!> by only 1/(1 + alpha s sigma^2 / m) instead of a thousandfold: Newton converges linearly or
!> not at all, and the trapezoidal step's own multiplier there grows like 1/sigma. Three
!> measures pass such steps:
!>   - the iteration watches its progress, max(update / tolerance, |Phi| / atol). When an update
!>     computed with a matrix built at its iterate leaves more than STALL_RATE of it, the step
!>     multiplies alpha by BOOST (the multiplier update that follows still takes the old alpha,
!>     which produced this Phi: with the new one it overshoots BOOST-fold and Phi stays); at a
!>     second stall, with |Phi| within FROZEN_PHI times its tolerance, lam* is frozen: Newton
!>     then solves the penalty problem, which stays regular, quadratically. A frozen step
!>     converges with |Phi| up to FROZEN_PHI times atol (the part of Phi no multiplier reaches),
!>     and also when its update no longer shrinks within NOISE tolerances (the roundoff floor of
!>     the stiffer matrix). A stall also happens on regular mechanisms now and then (a fresh
!>     matrix contracting slowly); there the boost alone ends it.
!>   - the projections take the regular augmented Lagrangian path of the mechanism's
!>     constrained solve (i3_cs_factor: mbdk_constrained for planar scenes, the spatial model's
!>     dense one) already below a relative pivot of NEAR_PIVOT of C M^-1 C^T, not only where
!>     it is singular: exact
!>     projections amplify the part of gamma (and of C v) that the vanishing direction cannot
!>     meet by up to 1/sigma^2, and the jump in a and v spoils the steps after it.
!>   - after such a projection the next step's lam* starts from the projection's multipliers,
!>     not from its own: with C rank-deficient lam* is not unique, and its updates accumulate
!>     the part of Phi that C cannot remove from step to step without bound.
!> Where no pose exists (a driver pushing a loop past its dead point) Newton still fails there.
!> studies/index3.py (table index3_crossings) measures the IFToMM A02 chains of 1 to 40 loops.
!>
!> Step size. Fixed: opt%h, samples every opt%every steps (mbdk_step_plan). In the augmented
!> form a step whose Newton iteration fails (diverges, meets a singular matrix or a non-finite
!> iterate: typically near a singular configuration, where C loses rank) is retried in
!> substeps, quartered at each failure (stats%newton_failures) and doubled back after each
!> success, down to h / 4^5; the samples stay on the grid. Only below that is the failure
!> returned. The book's scheme is not retried: its failures come from the growing oscillation
!> of its v and a, which substeps do not cure (retried, it went on for 100 s on the double
!> pendulum with |Phi| = 0.08 and the energy lost).
!>
!> Adaptive (opt%adaptive, augmented form only), from the initial step opt%h; errors of q and v
!> (multipliers excluded, as index-3 codes do) in the weighted RMS norm (err_atol + err_rtol
!> |y|), err <= 1 accepting the step. Two modes:
!>   2 extrapolated (MBDK_INDEX3_EXTRAPOLATED; Python's adaptive=True): local Richardson
!>     extrapolation. A macro step of H is one step of H and two of H/2 from the same state; the
!>     local error C H^3 of the second order rule makes their difference 3/4 C H^3, so the
!>     half-steps' error is (y_H/2 - y_H)/3, the controller's err. The step keeps the
!>     extrapolated (4 y_H/2 - y_H)/3, whose local error is O(H^4): the solution is third
!>     order (projected, the rule is not symmetric, so no h^4 cancellation beyond). q is
!>     extrapolated in its coordinates (a quaternion then normalised) and projected onto
!>     Phi = 0 (Gauss-Newton), v onto C v + Phi_t = 0, and a, lambda come from
!>     the constrained solve there, as at the end of every step. The predictors' history is
!>     the half-step grid. PI control (mbdk_step_controller, ki = 0.7, kp = 0.4). Why: with a
!>     second order method step-size control cannot pay on motions that are about equally
!>     hard throughout: on the double pendulum P1 no distribution of second order steps saves
!>     much over the best fixed step (studies/step_control.py derives the bound), while the
!>     third order macro step needs a fraction of its trapezoidal solves (table step_control). A macro step costs three solves; stats%steps counts
!>     macro steps. Extrapolation costs A-stability: the macro step amplifies a mode with
!>     h lambda = z by (4 R(z/2)^2 - R(z))/3, R(z) = (1 + z/2)/(1 - z/2), which tends to 5/3 as
!>     z -> -inf; a stiff mode's part in the difference of the solutions is twice its amplitude,
!>     so the error test keeps stiff modes resolved instead (bdf does not need to).
!>     Next to a rank loss of C (a solve froze its multipliers) the difference of the
!>     solutions measures what the frozen iteration leaves, not the truncation error: there a
!>     macro step the difference would reject, up to NEAR_FLOOR, is judged by mode 1's
!>     estimate instead, scaled to H, and if accepted draws on the retry budget below, so that
!>     a crawl along a dead point ends by name (extrapolated_attempt). The watch checks every
!>     macro step, and when it refuses one the samples end with its start. iters_out counts
!>     the Newton iterations of all three solves.
!>   1 estimated (MBDK_INDEX3_ESTIMATED; adaptive='estimated'): one step, its local error
!>     -h^3/12 q(3) on q and -h^3/12 q(4) on v, with the derivatives from divided differences of
!>     the step-mean accelerations; I control. Second order and a third of the cost per step,
!>     but no distribution of its steps beats the bound above.
!> The next h = h min(5, max(0.2, 0.9 err^(-1/3) ..)), held while that would grow it by less
!> than 20 % (a reused matrix stays valid; a change of 5 % or less keeps the old matrix too). A
!> rejected step is retried with that h (stats%rejected_steps); a Newton failure retries at h/4
!> (stats%newton_failures), within a retry budget (RETRY_BUDGET below: sustained failures end
!> the run with MBDK_ERR_NEWTON_DIVERGED); below h_min (default 1e-12 of the interval) the
!> solve ends with MBDK_ERR_STEP_TOO_SMALL. Samples every opt%dt_out, landed on exactly (a step
!> within 1.1 h of a sample is stretched to it, within 2 h halved). The book's scheme is refused
!> (MBDK_ERR_NOT_APPLICABLE): its velocity error in the constraint directions grows without
!> bound, and any error test on v would shrink h forever.
!>
!> The caller's interrupt flag (opt%interrupt) is polled before every step (fixed: every output
!> step); set, the solve ends with MBDK_ERR_INTERRUPTED and keeps its samples.
!>
!> Per step the solve records the Newton iterations (iters_out at each sample: those of the step
!> that produced it; every update computed, the last, converged one included) and counts
!> factorizations in the stats.
!>
!> Code layout. What the mechanism gives (its evaluation, the constrained solves, the Newton
!> matrix where it has tangents) is mbdk_mechanism's i3_ procedures, implemented by
!> mbdk_model_i3 (planar: mbdk_index3_matrix, mbdk_constrained) and mbdk_spatial_i3; the
!> step-size controller is mbdk_step_controller_t. Here, once for both: the solver's state
!> between steps (mbdk_index3_t), one step (mbdk_index3_step: from t to a given tn, not
!> retried; attempt = predictors, newton, finish_step), a fixed-step advance with the substep
!> retries (mbdk_index3_advance), and the whole-interval driver (mbdk_index3_solve: set-up,
!> then fixed_loop or adaptive_loop, each writing its samples, and the sample where a failed
!> solve stopped). An embedder steps through mbdk_index3_init and
!> mbdk_index3_advance (or the C stepper, mbdk_stepper_create_index3).
module mbdk_trapezoidal_index3
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use, intrinsic :: iso_c_binding, only: c_int, c_double, c_intptr_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_clock, only: mbdk_timer_t, mbdk_timer_start, mbdk_timer_stop
  use mbdk_interrupt, only: mbdk_interrupted, mbdk_progress
  use mbdk_mechanism, only: mbdk_mechanism_t, mbdk_i3_aux_t, mbdk_i3_eval_t
  use mbdk_lapack, only: mbdk_lu_factor, mbdk_lu_solve
  use mbdk_step_controller, only: mbdk_step_controller_t, mbdk_controller_init, &
    mbdk_controller_next_step, mbdk_controller_accept, mbdk_controller_reject, &
    mbdk_controller_newton_failure, mbdk_controller_too_small
  use mbdk_fixed_step, only: mbdk_step_plan
  implicit none
  private
  public :: mbdk_index3_solve, mbdk_index3_plan, mbdk_index3_init, mbdk_index3_step, &
    mbdk_index3_advance, mbdk_index3_is_trapezoidal, mbdk_index3_is_second_order, &
    mbdk_index3_error_constants

  integer, parameter, public :: MBDK_INDEX3_BOOK = 1, MBDK_INDEX3_AUGMENTED = 2
  !> opt%adaptive: 1 the local error estimate from differences, 2 local Richardson extrapolation
  integer, parameter, public :: MBDK_INDEX3_ESTIMATED = 1, MBDK_INDEX3_EXTRAPOLATED = 2
  !> alpha = 0 (the default): alpha = KAPPA max(M) / s at every step, so that the penalty term
  !> s alpha C^T C outweighs the mass matrix by KAPPA whatever h (see the module header).
  real(dp), parameter, public :: MBDK_INDEX3_KAPPA = 1.0e3_dp
  !> fixed step: a step whose Newton iteration fails is retried in substeps down to h / 4^this
  integer, parameter, public :: MBDK_INDEX3_MAX_CUTS = 5
  !> Newton: a matrix is rebuilt when the contraction rate exceeds this
  real(dp), parameter :: REBUILD_RATE = 0.5_dp
  !> augmented form: the update's target, a share of the step's local error estimate (below)
  real(dp), parameter :: LOCAL_SHARE = 1.0e-1_dp
  !> and not below this share of the options' tolerance (a state at rest has no local error)
  real(dp), parameter :: TAU_MIN = 1.0e-3_dp
  !> an old matrix's stall within STALL_ACCEPT times the last roundoff stall is accepted; that
  !> level decays by NOISE_DECAY per step
  real(dp), parameter :: STALL_ACCEPT = 2.0_dp, NOISE_DECAY = 0.9_dp
  !> augmented form, near a rank loss of C (see "Singular configurations" in the header): an
  !> iteration whose progress, computed with a matrix built at the iterate before, falls by less
  !> than STALL_RATE has stalled; the first stall multiplies alpha by BOOST, the second freezes
  !> lam*; a frozen step converges with max |Phi| up to FROZEN_PHI times its tolerance, and on
  !> an update that no longer shrinks within NOISE tolerances (the roundoff of the stiffer
  !> matrix)
  real(dp), parameter :: STALL_RATE = 0.25_dp, BOOST = 1.0e3_dp, NOISE = 1.0e2_dp, &
    FROZEN_PHI = 1.0e3_dp
  !> the projections take the regular path below this relative pivot of C M^-1 C^T
  real(dp), parameter :: NEAR_PIVOT = 1.0e-6_dp
  !> after a failed reuse, this many steps start with fresh matrices (doubled after each further
  !> failure, up to COOL_MAX)
  integer, parameter :: COOL_START = 8, COOL_MAX = 1024
  !> adaptive: a step within this fraction of the last matrix's h keeps the matrix
  real(dp), parameter :: KEEP_MATRIX = 0.05_dp
  !> adaptive, extrapolated: Gauss-Newton iterations of the projection of the extrapolated q
  !> (it starts within the square of the step's error of Phi = 0: one or two suffice)
  integer, parameter :: PROJECT_MAX_ITER = 10
  !> adaptive, extrapolated: next to a rank loss of C, an error norm of the macro step up to
  !> this is taken for the noise of the frozen Newton iteration (extrapolated_attempt): above
  !> the noise the A02 chains' crossings leave, below the disagreement of steps that run into
  !> a dead point (studies/index3.py, table index3_crossings; tests/test_hard_cases.py)
  real(dp), parameter :: NEAR_FLOOR = 1.0e3_dp
  !> adaptive: Newton failures, each retried with a quarter of the step (and, extrapolated,
  !> macro steps accepted on the weaker test next to a rank loss), draw on a budget of
  !> RETRY_BUDGET failures that every accepted step refills by RETRY_REFILL. A run that fails
  !> in more than one attempt in ten for long, the controller circling a configuration it
  !> cannot pass (at a singular crossing it can otherwise retry without end), ends with
  !> MBDK_ERR_NEWTON_DIVERGED instead of spending its time there; an isolated hard step still
  !> has its 20 retries. (Fixed step needs none: a grid step's substeps end at h / 4^5.)
  real(dp), parameter, public :: MBDK_INDEX3_RETRY_BUDGET = 20.0_dp
  real(dp), parameter :: RETRY_BUDGET = MBDK_INDEX3_RETRY_BUDGET, RETRY_REFILL = 0.1_dp

  type, bind(C), public :: mbdk_index3_options_t
    real(c_double) :: h = 1.0e-3_c_double              !< fixed step, or the first step (adaptive)
    real(c_double) :: newton_rtol = 1.0e-10_c_double   !< on the position update
    real(c_double) :: newton_atol = 1.0e-12_c_double   !< and max |Phi| <= newton_atol
    real(c_double) :: alpha = 0.0_c_double             !< augmented penalty; 0: KAPPA max(M) / s per step
    real(c_double) :: err_rtol = 1.0e-6_c_double       !< adaptive: local error tolerances on q and v
    real(c_double) :: err_atol = 1.0e-8_c_double
    real(c_double) :: dt_out = 0.0_c_double            !< adaptive: sample interval
    real(c_double) :: h_min = 0.0_c_double             !< adaptive: 0 = 1e-12 of the interval
    real(c_double) :: h_max = 0.0_c_double             !< adaptive: 0 = the interval
    !> address of a C int the caller may set non-zero to stop the solve (MBDK_ERR_INTERRUPTED)
    integer(c_intptr_t) :: interrupt = 0
    integer(c_int) :: formulation = MBDK_INDEX3_BOOK   !< MBDK_INDEX3_BOOK or MBDK_INDEX3_AUGMENTED
    integer(c_int) :: every = 1                        !< fixed step: keep every k-th step
    integer(c_int) :: newton_max_iter = 20
    !> step-size control (augmented only): 0 none, MBDK_INDEX3_ESTIMATED, MBDK_INDEX3_EXTRAPOLATED
    integer(c_int) :: adaptive = 0
    !> address of a C double the solve stores the time reached in, once per step; 0: none
    integer(c_intptr_t) :: progress = 0
    !> the generalized-alpha family's parameters (the module header); the defaults are the
    !> trapezoidal rule
    real(c_double) :: beta = 0.25_c_double
    real(c_double) :: gamma = 0.5_c_double
    real(c_double) :: alpha_m = 0.0_c_double
    real(c_double) :: alpha_f = 0.0_c_double
  end type mbdk_index3_options_t


  !> The solver's state between steps: the accepted state (t, q, v, a, lam) with the history
  !> the predictors and the error estimate use, the Newton matrix and its reuse policy, the work
  !> arrays of a step (allocated once), the mechanism's part (aux) and the statistics. Sizes:
  !> q of ncq coordinates, v, a and the increments of nv velocities, m multipliers, nk Newton
  !> unknowns.
  type, public :: mbdk_index3_t
    type(mbdk_index3_options_t) :: opt
    integer :: ncq = 0, nv = 0, m = 0, nk = 0
    logical :: book = .true.
    !> T = I: q (+) dq = q + dq, weights |q| (the mechanism's identity_kinematics)
    logical :: identity = .false.
    !> the Newton matrix by differences here (the mechanism has no tangents of its own)
    logical :: fd_matrix = .false.
    real(dp) :: t = 0.0_dp, tn = 0.0_dp, h = 0.0_dp, h_prev = 0.0_dp, h_prev2 = 0.0_dp
    real(dp) :: alpha = 0.0_dp, h_lu = 0.0_dp, mmax = 0.0_dp
    !> max(1, max |qn|), set with qn (move_point): the scale of Phi's roundoff there
    real(dp) :: qn_size = 1.0_dp
    !> the update's target within the options' tolerance: min(1, LOCAL_SHARE e) (newton)
    real(dp) :: tau = 1.0_dp
    !> the step's coefficients (set_coefficients): cs the Newton scale beta h^2 (1 - alpha_f) /
    !> (1 - alpha_m) (s = h^2/4 for the trapezoidal rule), cd the damping's gamma h (1 -
    !> alpha_f) / (1 - alpha_m), bh2 = beta h^2, cq = h^2 (1/2 - beta); v+ = cv dq + kv1 v +
    !> kv2 ap; ap+ = ca dq + ka1 v + ka2 ap; cg = (1 - gamma) / gamma; ra = -beta h^2 /
    !> (1 - alpha_m)
    real(dp) :: cs = 0.0_dp, cd = 0.0_dp, bh2 = 0.0_dp, cq = 0.0_dp, cv = 0.0_dp, kv1 = 0.0_dp, &
                kv2 = 0.0_dp, ca = 0.0_dp, ka1 = 0.0_dp, ka2 = 0.0_dp, cg = 0.0_dp, ra = 0.0_dp
    !> alpha_m or alpha_f nonzero: the pseudo-acceleration ap differs from a
    logical :: alpha_terms = .false.
    !> the local errors' constants of q and v (error_estimate): h^3 q''' times lte_q, h^3 q''''
    !> times lte_v
    real(dp) :: lte_q = 0.0_dp, lte_v = 0.0_dp
    !> the update's norm where a matrix built in its step last stalled (roundoff), decaying
    real(dp) :: noise = 0.0_dp
    !> the matrix was built with a stiffened alpha (a stalled step's): no other step takes it
    logical :: lu_boosted = .false.
    !> the projection of the accepted state (regular) and of the attempted one (regular_n) took
    !> the regular path: C is (nearly) rank-deficient there
    logical :: regular = .false., regular_n = .false.
    logical :: have_lu = .false.
    !> the last attempted step's Newton iteration froze lam* (after two stalls: next to a rank
    !> loss of C, where a multiplier no longer reaches the vanishing direction)
    logical :: stalled = .false.
    integer :: cool = 0, cool_len = COOL_START
    integer :: iters = 0                !< Newton iterations of the last attempted step
    real(dp) :: retries = RETRY_BUDGET  !< what is left of the retry budget
    type(mbdk_stats_t) :: st
    class(mbdk_i3_aux_t), allocatable :: aux
    !> the point the mechanism evaluates, the attempted step's end (qn = e%q, vn = e%v), what
    !> it gives there (f, phi, gam, phit), and the residual there (lt, dd, r)
    type(mbdk_i3_eval_t) :: e
    real(dp), allocatable :: q(:), qs(:)
    real(dp), allocatable :: v(:), a(:), a_prev(:), a_prev2(:), an(:), dq(:), dqhat(:), &
      dqp(:), corr(:), w(:), zero_nv(:)
    !> the generalized-alpha family's pseudo-acceleration (= a for the trapezoidal rule), of the
    !> state, the last state and the attempted step
    real(dp), allocatable :: ap(:), ap_prev(:), apn(:)
    real(dp), allocatable :: lam(:), lam_old(:), ln(:), lst(:), lstn(:), lst_old(:), lp(:), &
      rc(:), mu(:), zero_m(:)
    real(dp), allocatable :: y(:)
    !> fd_matrix: the matrix and its LU, and the evaluation it was built around
    real(dp), allocatable :: jm(:, :), r0(:), f0(:), phi0(:), gam0(:), phit0(:), col(:)
    !> fd_matrix, augmented form: the matrix by differences less the penalty's cs alpha C^T C
    !> at its iterate (penalty_matrix adds it at another), its h, a work vector; have_fd also
    !> where the mechanism keeps its own matrix's tangent for the renewal (has_i3_renew)
    real(dp), allocatable :: jfd(:, :), wv(:)
    real(dp) :: h_fd = 0.0_dp
    logical :: have_fd = .false.
    !> steps left in which the penalty's renewal is not tried (it failed in a step lately: the
    !> differences' part itself had gone stale, as under a fast spin)
    integer :: no_renewal = 0
    integer, allocatable :: ipiv(:)
  end type mbdk_index3_t

  !> adaptive = MBDK_INDEX3_EXTRAPOLATED: the accepted state a macro step starts from (restored
  !> when it is rejected or fails) and the end of its full step
  type :: mbdk_index3_snapshot_t
    real(dp) :: t = 0.0_dp, h_prev = 0.0_dp, h_prev2 = 0.0_dp, retries = 0.0_dp
    logical :: regular = .false.
    integer :: cool = 0, cool_len = 0
    integer(i8) :: steps = 0
    real(dp), allocatable :: q(:), v(:), a(:), lam(:), lst(:), lam_old(:), lst_old(:), &
      a_prev(:), a_prev2(:), qf(:), vf(:)
  end type mbdk_index3_snapshot_t

  !> The samples of a whole-interval solve: the caller's output arrays (mbdk_index3_solve's
  !> t_out, y_out, a_out, lam_out, iters_out) and how many rows are written (n)
  type :: samples_t
    real(dp), pointer :: t(:) => null(), y(:, :) => null(), a(:, :) => null(), &
      lam(:, :) => null()
    integer, pointer :: iters(:) => null()
    integer :: n = 0
  end type samples_t

contains

  !> A solver at (t0, y0 = [q; v]) with options opt: validates them, allocates the work arrays
  !> and the mechanism's part, and computes the consistent a and lambda at t0 (the constrained
  !> solve there; where C has lost a rank, the augmented form's regular path).
  !> MBDK_ERR_INVALID_INPUT, MBDK_ERR_NOT_APPLICABLE (adaptive with the book's scheme, a
  !> mechanism with effect states (wear), or one that cannot take the scheme), or the failure of that first solve
  !> (MBDK_ERR_SINGULAR_MATRIX with dependent constraints in the book's scheme).
  subroutine mbdk_index3_init(s, mech, opt, t0, y0, stat)
    type(mbdk_index3_t), intent(out) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    type(mbdk_index3_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, y0(:)
    integer, intent(out) :: stat

    stat = MBDK_ERR_INVALID_INPUT
    if (opt%formulation /= MBDK_INDEX3_BOOK .and. opt%formulation /= MBDK_INDEX3_AUGMENTED) return
    if (.not. (opt%newton_rtol >= 0.0_dp .and. opt%newton_atol > 0.0_dp) .or. &
        opt%newton_max_iter < 1) return
    if (opt%formulation == MBDK_INDEX3_AUGMENTED .and. .not. (opt%alpha >= 0.0_dp)) return
    if (.not. (opt%beta > 0.0_dp .and. opt%beta <= huge(1.0_dp) .and. opt%gamma > 0.0_dp .and. &
               opt%gamma <= huge(1.0_dp) .and. opt%alpha_m < 1.0_dp .and. &
               opt%alpha_m >= -huge(1.0_dp) .and. opt%alpha_f < 1.0_dp .and. &
               opt%alpha_f >= -huge(1.0_dp))) return
    if (mech%ns > 0) then
      ! the family's state [q; v] (Newton on its increment) has no place for effect states
      stat = MBDK_ERR_NOT_APPLICABLE
      return
    end if
    if (size(y0) /= mech%ncoord + mech%nvel) return
    if (.not. all(abs(y0) <= huge(1.0_dp)) .or. .not. abs(t0) <= huge(1.0_dp)) return
    if (opt%adaptive < 0 .or. opt%adaptive > MBDK_INDEX3_EXTRAPOLATED) return
    ! step-size control: the estimated local error holds for the second-order members, the
    ! extrapolation's macro step for the trapezoidal rule alone (its extrapolated state would
    ! leave the pseudo-acceleration's history behind), neither for the book's scheme
    if (opt%adaptive /= 0 .and. (opt%formulation == MBDK_INDEX3_BOOK .or. &
        (opt%adaptive == MBDK_INDEX3_EXTRAPOLATED .and. .not. mbdk_index3_is_trapezoidal(opt)) &
        .or. .not. mbdk_index3_is_second_order(opt))) then
      stat = MBDK_ERR_NOT_APPLICABLE
      return
    end if
    s%opt = opt
    s%book = opt%formulation == MBDK_INDEX3_BOOK
    call mech%i3_create(s%aux, s%book, stat, s%st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    call allocate_state(s, mech, stat)
    if (stat /= MBDK_SUCCESS) return
    s%q = y0(1:s%ncq)
    s%v = y0(s%ncq + 1:)
    s%t = t0
    s%st%t_reached = t0
    ! consistent a and lambda at t0: the constrained solve; where C has lost a rank (redundant
    ! joints, or a start at a singular configuration) the augmented form takes the regular
    ! path of its projections instead (lambda is then one of many)
    s%e%q(:) = s%q
    s%e%v(:) = s%v
    call mech%i3_evaluate(s%aux, s%t, s%e, .true., .false., stat)
    if (stat /= MBDK_SUCCESS) return
    call mech%i3_cs_factor(s%aux, 0.0_dp, .not. s%book, s%regular, stat)
    if (stat /= MBDK_SUCCESS) return
    call mech%i3_cs_solve(s%aux, s%e%f, s%e%gam, s%a, s%lam, stat)
    if (stat /= MBDK_SUCCESS) return
    s%lam_old = s%lam
    s%lst = s%lam
    s%lstn = s%lam
    s%lst_old = s%lam
    s%a_prev = s%a
    s%a_prev2 = s%a
    s%ap = s%a
    s%ap_prev = s%a
    s%alpha_terms = opt%alpha_m /= 0.0_dp .or. opt%alpha_f /= 0.0_dp
    call mbdk_index3_error_constants(opt, s%lte_q, s%lte_v)
    s%st%nfev = 1
    if (opt%alpha_m /= opt%alpha_f) call shifted_start(s, mech, t0, stat)
    if (stat /= MBDK_SUCCESS) return
    s%y(1:s%ncq) = s%q
    s%y(s%ncq + 1:) = s%v
    call mech%watch_begin(s%t, s%y, .not. s%book, stat)
  end subroutine mbdk_index3_init

  !> The start of the pseudo-acceleration (Arnold and Bruls 2007, "perturbed starting values"):
  !> ap approximates the acceleration at t + (alpha_m - alpha_f) h, and started from a(t0) its
  !> O(h) error (alpha_m - alpha_f) h q''' dies out only as the powers of the spurious root
  !> -alpha_m / (1 - alpha_m): the first steps' v then carry O(h^2) local errors and their a
  !> and lambda O(h) ones, which a start at rest (q''' = 0 there) does not show. The
  !> acceleration of the constrained solve at the Taylor state (q (+) (d v + d^2/2 a), v + d a)
  !> at t0 + d, d = (alpha_m - alpha_f) opt%h, is that value to O(h^2). The evaluation at t0
  !> is made again afterwards (the step's first iterations use its C); where the shifted state
  !> has no regular solve, ap stays a(t0).
  subroutine shifted_start(s, mech, t0, stat)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    real(dp), intent(in) :: t0
    integer, intent(out) :: stat
    real(dp) :: d
    integer :: ierr
    d = (s%opt%alpha_m - s%opt%alpha_f) * s%opt%h
    s%dq(:) = d * s%v + (0.5_dp * d * d) * s%a
    s%e%q(:) = s%q
    call move_by(s, mech, s%e%q, s%dq, ierr)
    s%e%v(:) = s%v + d * s%a
    if (ierr == MBDK_SUCCESS) call mech%i3_evaluate(s%aux, t0 + d, s%e, .true., .false., ierr)
    if (ierr == MBDK_SUCCESS) call mech%i3_cs_factor(s%aux, 0.0_dp, .not. s%book, s%regular, ierr)
    if (ierr == MBDK_SUCCESS) call mech%i3_cs_solve(s%aux, s%e%f, s%e%gam, s%an, s%ln, ierr)
    if (ierr == MBDK_SUCCESS .and. finite_all(s%an)) s%ap(:) = s%an
    s%st%nfev = s%st%nfev + 2
    s%e%q(:) = s%q
    s%e%v(:) = s%v
    call mech%i3_evaluate(s%aux, t0, s%e, .true., .false., stat)
    if (stat /= MBDK_SUCCESS) return
    call mech%i3_cs_factor(s%aux, 0.0_dp, .not. s%book, s%regular, stat)
  end subroutine shifted_start

  !> The work arrays of a solve (and, for a mechanism without its own Newton matrix, the
  !> differences' matrix), sized from the mechanism; the mass scale of the default alpha.
  subroutine allocate_state(s, mech, stat)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    integer, intent(out) :: stat
    integer :: ncq, nv, m, nk, astat
    ncq = mech%ncoord
    nv = mech%nvel
    m = mech%m
    nk = nv
    if (s%book) nk = nv + m
    s%ncq = ncq
    s%nv = nv
    s%m = m
    s%nk = nk
    s%identity = mech%identity_kinematics
    s%fd_matrix = .not. mech%has_i3_matrix
    allocate (s%q(ncq), s%e%q(ncq), s%qs(ncq), s%v(nv), s%a(nv), s%a_prev(nv), s%a_prev2(nv), &
              s%e%v(nv), s%an(nv), s%dq(nv), s%dqhat(nv), s%dqp(nv), s%e%dd(nv), s%e%f(nv), &
              s%corr(nv), s%w(nv), s%zero_nv(nv), s%lam(m), s%lam_old(m), s%ln(m), s%lst(m), &
              s%lstn(m), s%lst_old(m), s%lp(m), s%e%lt(m), s%e%phi(m), s%e%gam(m), s%e%phit(m), &
              s%rc(m), s%mu(m), s%zero_m(m), s%e%r(nk), s%y(ncq + nv), s%ap(nv), s%ap_prev(nv), &
              s%apn(nv), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (4.0_dp * ncq + 18.0_dp * nv + 14.0_dp * m + &
                           nk), stat, s%st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    if (s%fd_matrix) then
      allocate (s%jm(nk, nk), s%ipiv(nk), s%r0(nk), s%f0(nv), s%phi0(m), s%gam0(m), &
                s%phit0(m), s%col(nk), s%jfd(nk, nk), s%wv(nv), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (real(nk, dp) * (2 * nk + 2) + &
                             2.0_dp * nv + 3.0_dp * m) + MBDK_INT_BYTES * nk, stat, &
                             s%st%alloc_bytes)
      if (stat /= MBDK_SUCCESS) return
    end if
    s%zero_nv = 0.0_dp
    s%zero_m = 0.0_dp
    s%e%phi = 0.0_dp
    s%e%gam = 0.0_dp
    s%e%phit = 0.0_dp
    s%e%f = 0.0_dp
    call mech%mass_diagonal(s%e%f)
    s%mmax = maxval(s%e%f)
    s%e%f = 0.0_dp
  end subroutine allocate_state

  !> Accepts the attempted step: (qn, vn, an, ln) at tn becomes the state, the state the
  !> history. (One pass per length: the vectors are a few components long, and a pass's set-up
  !> costs about as much as its copies.)
  subroutine commit(s)
    type(mbdk_index3_t), intent(inout) :: s
    integer :: k
    s%h_prev2 = s%h_prev
    s%h_prev = s%h
    do k = 1, s%nv
      s%a_prev2(k) = s%a_prev(k)
      s%a_prev(k) = s%a(k)
      s%ap_prev(k) = s%ap(k)
      s%v(k) = s%e%v(k)
      s%a(k) = s%an(k)
      s%ap(k) = s%apn(k)
    end do
    s%q(:) = s%e%q
    do k = 1, s%m
      s%lam_old(k) = s%lam(k)
      s%lst_old(k) = s%lst(k)
      s%lam(k) = s%ln(k)
      s%lst(k) = s%lstn(k)
    end do
    s%regular = s%regular_n
    s%t = s%tn
    s%st%steps = s%st%steps + 1
    s%st%t_reached = s%t
    if (s%cool > 0) s%cool = s%cool - 1
    s%retries = min(s%retries + RETRY_REFILL, RETRY_BUDGET)
  end subroutine commit

  !> A Newton failure to be retried: counted, and drawn from the budget (.false.: exhausted).
  logical function retry_allowed(s)
    type(mbdk_index3_t), intent(inout) :: s
    s%st%newton_failures = s%st%newton_failures + 1
    s%retries = s%retries - 1.0_dp
    retry_allowed = s%retries >= 0.0_dp
  end function retry_allowed

  !> One step from s%t to tn, accepted on success; on failure the state stays at s%t.
  !> No retries (mbdk_index3_advance retries in substeps).
  subroutine mbdk_index3_step(s, mech, tn, stat)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    real(dp), intent(in) :: tn
    integer, intent(out) :: stat
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. (tn > s%t .and. tn - s%t <= huge(1.0_dp))) return
    s%tn = tn
    s%h = tn - s%t
    call attempt(s, mech, stat)
    if (stat == MBDK_SUCCESS) then
      call commit(s)
      call watch_step(s, mech, .false., stat)
    end if
  end subroutine mbdk_index3_step

  !> Fixed step: from s%t to t_s in one step of h = t_s - t or, when Newton fails (diverged,
  !> singular matrix, non-finite iterate) in the augmented form, in substeps: each failure
  !> quarters the substep (stats%newton_failures), each success doubles it back up to the
  !> full step. Below h / 4^MBDK_INDEX3_MAX_CUTS the failure is returned.
  subroutine mbdk_index3_advance(s, mech, t_s, ierr, sample_at_end)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    real(dp), intent(in) :: t_s
    integer, intent(out) :: ierr
    !> the state at t_s will be sampled: the watch checks it
    logical, intent(in), optional :: sample_at_end
    real(dp) :: h_full, h_sub
    logical :: sample
    sample = .false.
    if (present(sample_at_end)) sample = sample_at_end
    h_full = t_s - s%t
    h_sub = h_full
    ierr = MBDK_SUCCESS
    do while (s%t < t_s)
      s%tn = s%t + h_sub
      if (t_s - s%tn <= 1.0e-9_dp * h_full) s%tn = t_s
      s%h = s%tn - s%t
      call attempt(s, mech, ierr)
      if (newton_failed(ierr)) then
        if (s%book) return
        s%st%newton_failures = s%st%newton_failures + 1
        s%have_lu = .false.
        h_sub = 0.25_dp * s%h
        if (h_sub < h_full * 0.25_dp**MBDK_INDEX3_MAX_CUTS) return
        cycle
      end if
      if (ierr /= MBDK_SUCCESS) return
      call commit(s)
      call watch_step(s, mech, sample .and. s%t == t_s, ierr)
      if (ierr /= MBDK_SUCCESS) return
      h_sub = min(2.0_dp * h_sub, h_full)
    end do
  end subroutine mbdk_index3_advance

  !> The mechanism's watch after an accepted step: with the projected form's multipliers
  !> (exact at the state) for the drivers' power; the book scheme's are not accurate enough
  !> (they grow as h shrinks), so the watch solves for them.
  subroutine watch_step(s, mech, force, stat)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    logical, intent(in) :: force
    integer, intent(out) :: stat
    s%y(1:s%ncq) = s%q
    s%y(s%ncq + 1:) = s%v
    if (s%book) then
      call mech%watch_solve(s%t, s%y, force, stat)
    else
      call mech%watch_lam(s%t, s%y, force, s%lam, stat)
    end if
  end subroutine watch_step

  logical function watch_status(ierr)
    integer, intent(in) :: ierr
    watch_status = ierr == MBDK_ERR_CONSTRAINT_DRIFT .or. ierr == MBDK_ERR_ENERGY_DRIFT .or. &
      ierr == MBDK_ERR_INVARIANT_DRIFT
  end function watch_status

  logical function newton_failed(ierr)
    integer, intent(in) :: ierr
    newton_failed = ierr == MBDK_ERR_NEWTON_DIVERGED .or. ierr == MBDK_ERR_NONFINITE .or. &
      ierr == MBDK_ERR_SINGULAR_MATRIX
  end function newton_failed

  !> Integrates the mechanism from (q, v) = y0 over [t0, t_end]: with the fixed step opt%h, or,
  !> when opt%adaptive, with the step-size controller from the initial step opt%h and samples
  !> every opt%dt_out. Samples: t_out, y_out (= [q; v]), a_out, lam_out, iters_out (Newton
  !> iterations of the step that produced the sample). nwritten samples are valid; on failure
  !> the samples before it are kept, and the last one is the state the failed step started
  !> from.
  subroutine mbdk_index3_solve(mech, opt, t0, t_end, y0, t_out, y_out, a_out, lam_out, &
                               iters_out, nwritten, st, stat)
    class(mbdk_mechanism_t), intent(in) :: mech
    type(mbdk_index3_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_end, y0(:)
    real(dp), intent(out), target :: t_out(:), y_out(:, :), a_out(:, :), lam_out(:, :)
    integer, intent(out), target :: iters_out(:)
    integer, intent(out) :: nwritten
    type(mbdk_stats_t), intent(out) :: st
    integer, intent(out) :: stat
    integer(i8) :: nsteps
    integer :: nsamp, plan_stat
    logical :: shortened
    type(mbdk_timer_t) :: timer
    type(mbdk_index3_t) :: s
    type(samples_t) :: out

    nwritten = 0
    call mbdk_index3_plan(opt, t0, t_end, nsteps, nsamp, shortened, plan_stat)
    stat = MBDK_ERR_INVALID_INPUT
    if (plan_stat < 0) return
    if (size(t_out) < nsamp .or. size(y_out, 2) < nsamp .or. size(a_out, 2) < nsamp .or. &
        size(lam_out, 2) < nsamp .or. size(iters_out) < nsamp) then
      stat = MBDK_ERR_OUTPUT_SIZE
      return
    end if
    call mbdk_timer_start(timer)
    call mbdk_index3_init(s, mech, opt, t0, y0, stat)
    if (stat /= MBDK_SUCCESS) then
      st = s%st
      return
    end if
    out%t => t_out
    out%y => y_out
    out%a => a_out
    out%lam => lam_out
    out%iters => iters_out
    call put_sample(out, s)
    if (opt%adaptive /= 0) then
      call adaptive_loop(s, mech, t0, t_end, nsamp, out, stat)
    else
      call fixed_loop(s, mech, t0, t_end, nsteps, out, stat)
      if (stat == MBDK_SUCCESS .and. shortened) stat = MBDK_NOTE_LAST_STEP_SHORTENED
    end if
    if (mbdk_is_failure(stat)) call sample_where_stopped(s, mech, out, stat)
    nwritten = out%n
    st = s%st
    call mbdk_timer_stop(timer, st)
  end subroutine mbdk_index3_solve

  !> Fixed step: nsteps steps of opt%h from t0, the last one ending at t_end; a sample every
  !> opt%every steps and after the last. The interrupt flag is polled before every step.
  subroutine fixed_loop(s, mech, t0, t_end, nsteps, out, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    real(dp), intent(in) :: t0, t_end
    integer(i8), intent(in) :: nsteps
    type(samples_t), intent(inout) :: out
    integer, intent(out) :: ierr
    integer(i8) :: i
    real(dp) :: t_s
    logical :: sample
    ierr = MBDK_SUCCESS
    do i = 1, nsteps
      t_s = t0 + real(i, dp) * s%opt%h
      if (i == nsteps) t_s = t_end
      if (s%opt%interrupt /= 0 .and. mbdk_interrupted(s%opt%interrupt)) then
        ierr = MBDK_ERR_INTERRUPTED
        return
      end if
      if (s%opt%progress /= 0) call mbdk_progress(s%opt%progress, t_s)
      sample = mod(i, int(s%opt%every, i8)) == 0 .or. i == nsteps
      call mbdk_index3_advance(s, mech, t_s, ierr, sample)
      if (ierr /= MBDK_SUCCESS) return
      if (sample) call put_sample(out, s)
    end do
  end subroutine fixed_loop

  !> The step-size controller (see the module header and mbdk_step_controller) over nsamp - 1
  !> sample intervals; samples land on t0 + k dt_out and t_end.
  subroutine adaptive_loop(s, mech, t0, t_end, nsamp, out, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    real(dp), intent(in) :: t0, t_end
    integer, intent(in) :: nsamp
    type(samples_t), intent(inout) :: out
    integer, intent(out) :: ierr
    integer :: k
    real(dp) :: err, h_ctl, t_s
    logical :: extrapolated
    type(mbdk_step_controller_t) :: ctl
    type(mbdk_index3_snapshot_t) :: x0
    extrapolated = s%opt%adaptive == MBDK_INDEX3_EXTRAPOLATED
    call mbdk_controller_init(ctl, s%opt%h, s%opt%h_min, s%opt%h_max, t0, t_end, 2)
    if (extrapolated) then
      ctl%ki = 0.7_dp
      ctl%kp = 0.4_dp
    end if
    if (extrapolated) then
      call snapshot_init(x0, s%ncq, s%nv, s%m, ierr, s%st%alloc_bytes)
      if (ierr /= MBDK_SUCCESS) return
    end if
    ierr = MBDK_SUCCESS
    do k = 1, nsamp - 1
      t_s = t0 + real(k, dp) * s%opt%dt_out
      if (k == nsamp - 1) t_s = t_end
      do while (s%t < t_s)
        if (s%opt%interrupt /= 0 .and. mbdk_interrupted(s%opt%interrupt)) then
          ierr = MBDK_ERR_INTERRUPTED
          return
        end if
        if (s%opt%progress /= 0) call mbdk_progress(s%opt%progress, s%t)
        s%tn = mbdk_controller_next_step(ctl, s%t, t_s)
        s%h = s%tn - s%t
        ! the controller judges the step from t to tn (extrapolated: the macro step, whose
        ! half-steps leave their own h in s%h for the predictors' history)
        h_ctl = s%h
        if (extrapolated) then
          call extrapolated_attempt(s, mech, x0, err, ierr)
        else
          call hold_matrix(s)
          call attempt(s, mech, ierr)
          if (ierr == MBDK_SUCCESS) err = error_estimate(s, mech)
        end if
        ! (an extrapolated step judged next to a rank loss exhausted the budget)
        if (ierr == MBDK_ERR_NEWTON_DIVERGED .and. s%retries < 0.0_dp) return
        if (newton_failed(ierr)) then
          if (.not. retry_allowed(s)) then
            ierr = MBDK_ERR_NEWTON_DIVERGED
            return
          end if
          s%have_lu = .false.
          call mbdk_controller_newton_failure(ctl, h_ctl)
        else if (ierr /= MBDK_SUCCESS) then
          return
        else
          if (err <= 1.0_dp) then
            call commit(s)
            call mbdk_controller_accept(ctl, h_ctl, err)
            ! extrapolated: the watch checks every macro step (three solves make a check
            ! cheap beside it), so that the macro step's start passed when it refuses the
            ! end; the samples then end there, where the run stopped (next to a dead point
            ! the last sample on the dt_out grid can be far from it)
            call watch_step(s, mech, extrapolated .or. s%t >= t_s, ierr)
            if (ierr /= MBDK_SUCCESS) then
              ! the macro step's start as the last sample (its Newton iterations unknown: 0)
              if (extrapolated .and. out%n < size(out%t)) then
                if (x0%t > out%t(out%n)) call put_row(out, x0%t, x0%q, x0%v, x0%a, x0%lam, 0)
              end if
              return
            end if
            cycle
          end if
          s%st%rejected_steps = s%st%rejected_steps + 1
          call mbdk_controller_reject(ctl, h_ctl, err)
        end if
        ierr = MBDK_SUCCESS
        if (mbdk_controller_too_small(ctl)) then
          ierr = MBDK_ERR_STEP_TOO_SMALL
          return
        end if
      end do
      call put_sample(out, s)
    end do
  end subroutine adaptive_loop

  !> After a failure (stat), the state where the solve stopped as the last sample: the state
  !> the failed step started from. A state the watch refused is not a sample (the last sample
  !> passed its checks; adaptive, extrapolated: the start of the refused macro step, written by
  !> adaptive_loop).
  subroutine sample_where_stopped(s, mech, out, stat)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    type(samples_t), intent(inout) :: out
    integer, intent(inout) :: stat
    integer :: wstat
    if (out%n >= size(out%t) .or. watch_status(stat)) return
    if (.not. s%t > out%t(out%n)) return
    ! the watch checks every few steps: the state where it stopped is checked before it
    ! becomes a sample (a step that blew up just before a failed one is named as such)
    call watch_step(s, mech, .true., wstat)
    if (watch_status(wstat)) then
      stat = wstat
    else
      call put_sample(out, s)
    end if
  end subroutine sample_where_stopped

  !> The solver's state as the next sample (with the Newton iterations of its step).
  subroutine put_sample(out, s)
    type(samples_t), intent(inout) :: out
    type(mbdk_index3_t), intent(in) :: s
    call put_row(out, s%t, s%q, s%v, s%a, s%lam, s%iters)
  end subroutine put_sample

  subroutine put_row(out, t, q, v, a, lam, iters)
    type(samples_t), intent(inout) :: out
    real(dp), intent(in) :: t, q(:), v(:), a(:), lam(:)
    integer, intent(in) :: iters
    integer :: ncq, nv, m
    ncq = size(q)
    nv = size(v)
    m = size(lam)
    out%n = out%n + 1
    out%t(out%n) = t
    out%y(1:ncq, out%n) = q
    out%y(ncq + 1:ncq + nv, out%n) = v
    out%a(1:nv, out%n) = a
    if (m > 0) out%lam(1:m, out%n) = lam
    out%iters(out%n) = iters
  end subroutine put_row

  subroutine snapshot_init(x, ncq, nv, m, stat, asked)
    type(mbdk_index3_snapshot_t), intent(out) :: x
    integer, intent(in) :: ncq, nv, m
    integer, intent(out) :: stat
    real(dp), intent(inout) :: asked
    integer :: astat
    allocate (x%q(ncq), x%v(nv), x%a(nv), x%lam(m), x%lst(m), x%lam_old(m), x%lst_old(m), &
              x%a_prev(nv), x%a_prev2(nv), x%qf(ncq), x%vf(nv), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (2.0_dp * ncq + 5.0_dp * nv + 4.0_dp * m), &
                           stat, asked)
  end subroutine snapshot_init

  !> The accepted state and everything commit moves into x (save) or back from x (restore).
  subroutine snapshot(s, x, save)
    type(mbdk_index3_t), intent(inout) :: s
    type(mbdk_index3_snapshot_t), intent(inout) :: x
    logical, intent(in) :: save
    if (save) then
      x%t = s%t
      x%h_prev = s%h_prev
      x%h_prev2 = s%h_prev2
      x%retries = s%retries
      x%regular = s%regular
      x%cool = s%cool
      x%cool_len = s%cool_len
      x%steps = s%st%steps
      x%q = s%q
      x%v = s%v
      x%a = s%a
      x%lam = s%lam
      x%lst = s%lst
      x%lam_old = s%lam_old
      x%lst_old = s%lst_old
      x%a_prev = s%a_prev
      x%a_prev2 = s%a_prev2
    else
      s%t = x%t
      s%st%t_reached = x%t
      s%h_prev = x%h_prev
      s%h_prev2 = x%h_prev2
      s%retries = x%retries
      s%regular = x%regular
      s%cool = x%cool
      s%cool_len = x%cool_len
      s%st%steps = x%steps
      s%q = x%q
      s%v = x%v
      s%a = x%a
      s%lam = x%lam
      s%lst = x%lst
      s%lam_old = x%lam_old
      s%lst_old = x%lst_old
      s%a_prev = x%a_prev
      s%a_prev2 = x%a_prev2
      ! adaptive runs the trapezoidal rule only, whose pseudo-acceleration is a
      s%ap = s%a
      s%ap_prev = s%a_prev
    end if
  end subroutine snapshot

  !> adaptive = MBDK_INDEX3_EXTRAPOLATED: the macro step from s%t to s%tn = s%t + H by local
  !> Richardson extrapolation (module header). On success (qn, vn, an, ln) at tn hold the
  !> extrapolated, projected state, to be committed as one step (the first half-step is
  !> committed already, so that the history the predictors use is the half-step grid), and err
  !> is the error norm of the half-step solution. When the step is rejected (err > 1) or a solve
  !> fails, the state is restored to s%t.
  subroutine extrapolated_attempt(s, mech, x, err, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    type(mbdk_index3_snapshot_t), intent(inout) :: x
    real(dp), intent(out) :: err
    integer, intent(out) :: ierr
    real(dp) :: t_end
    integer :: iters
    logical :: near
    err = huge(1.0_dp)
    t_end = s%tn
    call snapshot(s, x, .true.)
    ! the full step. Each change between H and H/2 rebuilds the Newton matrix; a second matrix
    ! kept for the other size would not be reused either: at the steps this control takes,
    ! h |omega| is above the 1e-3 where a matrix from the step before fails (module header)
    s%h = t_end - s%t
    call hold_matrix(s)
    call attempt(s, mech, ierr)
    if (ierr /= MBDK_SUCCESS) return
    x%qf = s%e%q
    x%vf = s%e%v
    iters = s%iters
    near = s%stalled
    ! two half-steps
    s%tn = s%t + 0.5_dp * (t_end - s%t)
    s%h = s%tn - s%t
    call hold_matrix(s)
    call attempt(s, mech, ierr)
    if (ierr /= MBDK_SUCCESS) return
    near = near .or. s%stalled
    iters = iters + s%iters
    call commit(s)
    ! the macro step is one step: counted, and refilling the retry budget, once
    s%st%steps = x%steps
    s%retries = x%retries
    s%tn = t_end
    s%h = t_end - s%t
    call hold_matrix(s)
    call attempt(s, mech, ierr)
    if (ierr /= MBDK_SUCCESS) then
      call snapshot(s, x, .false.)
      return
    end if
    s%iters = iters + s%iters
    ! the half-steps' error is (y_half - y_full) / 3 (local error C h^3: C H^3 / 4 against
    ! C H^3), measured as error_estimate's, on q and v
    err = half_step_error(s, x)
    if (err > 1.0_dp .and. err <= NEAR_FLOOR .and. (near .or. s%stalled)) then
      ! next to a rank loss of C (a solve froze its multipliers) the three solutions differ by
      ! the |Phi| up to FROZEN_PHI tolerances that frozen Newton steps leave along the
      ! vanishing direction, whatever H: there the difference is no estimate of the truncation
      ! error, up to NEAR_FLOOR (beyond it the solutions disagree by more than such a floor:
      ! the step is rejected as any other). The half-steps stand, unextrapolated, judged by
      ! the estimate from differences (error_estimate) of the second, scaled by 2^3 to a step
      ! of H (the controller's step): what the estimated mode would ask of a step of H, for a
      ! solution whose error is a quarter of that step's.
      err = 8.0_dp * error_estimate(s, mech)
      if (.not. err <= 1.0_dp) then
        call snapshot(s, x, .false.)
        return
      end if
      ! a step accepted on this weaker test draws on the retry budget as a Newton failure does,
      ! so that a run cannot go on by such steps alone (as it could along a dead point, where no
      ! pose follows and each tiny step stays within the frozen iteration's |Phi|). The run
      ! then ends here, where the macro step started.
      s%retries = s%retries - 1.0_dp
      if (s%retries < 0.0_dp) then
        call snapshot(s, x, .false.)
        s%retries = -1.0_dp
        ierr = MBDK_ERR_NEWTON_DIVERGED
      end if
      return
    end if
    if (.not. err <= 1.0_dp) then
      call snapshot(s, x, .false.)
      return
    end if
    ! (extrapolated coordinates leave a quaternion's unit norm: normalised before the
    ! projection)
    s%e%q = s%e%q + (s%e%q - x%qf) / 3.0_dp
    s%e%v = s%e%v + (s%e%v - x%vf) / 3.0_dp
    if (.not. s%identity) call mech%normalise(s%e%q)
    call consistent_end(s, mech, ierr)
    if (ierr /= MBDK_SUCCESS) call snapshot(s, x, .false.)
  end subroutine extrapolated_attempt

  !> The weighted RMS over the coordinates and velocities of (y_half - y_full) / 3 (module
  !> header), with the half-steps' solution in (qn, vn) and the full step's in x.
  real(dp) function half_step_error(s, x) result(err)
    type(mbdk_index3_t), intent(in) :: s
    type(mbdk_index3_snapshot_t), intent(in) :: x
    real(dp) :: wq, wv, sum2
    integer :: k
    sum2 = 0.0_dp
    do k = 1, max(s%ncq, s%nv)
      if (k <= s%ncq) then
        wq = s%opt%err_atol + s%opt%err_rtol * max(abs(x%q(k)), abs(s%e%q(k)))
        sum2 = sum2 + ((s%e%q(k) - x%qf(k)) / (3.0_dp * wq))**2
      end if
      if (k <= s%nv) then
        wv = s%opt%err_atol + s%opt%err_rtol * max(abs(x%v(k)), abs(s%e%v(k)))
        sum2 = sum2 + ((s%e%v(k) - x%vf(k)) / (3.0_dp * wv))**2
      end if
    end do
    err = sqrt(sum2 / real(s%ncq + s%nv, dp))
  end function half_step_error

  !> Keeps the current matrix for a step s%h within KEEP_MATRIX of the one it was built for
  !> (modified Newton absorbs the difference).
  subroutine hold_matrix(s)
    type(mbdk_index3_t), intent(inout) :: s
    if (s%have_lu .and. abs(s%h - s%h_lu) <= KEEP_MATRIX * s%h_lu) s%h_lu = s%h
  end subroutine hold_matrix

  !> (qn, vn) onto Phi = 0 (Gauss-Newton on the least mass-weighted change, as the projection
  !> formulation's) and C v + Phi_t = 0, then an, ln from M a + C^T lambda = f, C a = gamma
  !> there: the solves of a step's end (finish_step), on the regular path where C is (nearly)
  !> rank-deficient.
  subroutine consistent_end(s, mech, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    integer, intent(out) :: ierr
    integer :: it
    real(dp) :: phi_tol
    phi_tol = max(s%opt%newton_atol, 64.0_dp * epsilon(1.0_dp) * max(1.0_dp, maxval(abs(s%e%q))))
    do it = 0, PROJECT_MAX_ITER
      call mech%i3_evaluate(s%aux, s%tn, s%e, .false., .false., ierr)
      if (ierr /= MBDK_SUCCESS) return
      call mech%i3_cs_factor(s%aux, NEAR_PIVOT, .true., s%regular_n, ierr)
      if (ierr /= MBDK_SUCCESS) return
      if (s%m == 0) exit
      if (maxval(abs(s%e%phi)) <= phi_tol) exit
      ! at a rank loss the part of Phi that C cannot reach stays, as in a frozen Newton step
      if (s%regular_n .and. it > 0 .and. maxval(abs(s%e%phi)) <= FROZEN_PHI * phi_tol) exit
      if (it == PROJECT_MAX_ITER) then
        ierr = MBDK_ERR_NEWTON_DIVERGED
        return
      end if
      call mech%i3_cs_solve(s%aux, s%zero_nv, s%e%phi, s%corr, s%mu, ierr)
      if (ierr /= MBDK_SUCCESS) return
      call move_by(s, mech, s%e%q, -s%corr, ierr)
      if (ierr /= MBDK_SUCCESS) return
    end do
    if (s%m > 0) then
      call mech%i3_project_velocity(s%aux, s%e, ierr)
      if (ierr /= MBDK_SUCCESS) return
    end if
    call mech%i3_evaluate(s%aux, s%tn, s%e, .true., .true., ierr)
    if (ierr /= MBDK_SUCCESS) return
    s%st%nfev = s%st%nfev + 1
    call mech%i3_cs_solve(s%aux, s%e%f, s%e%gam, s%an, s%ln, ierr)
    if (ierr /= MBDK_SUCCESS) return
    s%apn(:) = s%an
    if (.not. (finite_all(s%e%q) .and. finite_all(s%e%v) .and. finite_all(s%an))) &
      ierr = MBDK_ERR_NONFINITE
  end subroutine consistent_end

  !> q moved in place by the increment dq (the mechanism's retraction; q + dq where T = I).
  subroutine move_by(s, mech, q, dq, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    real(dp), intent(inout) :: q(:)
    real(dp), intent(in) :: dq(:)
    integer, intent(out) :: ierr
    ierr = MBDK_SUCCESS
    if (s%identity) then
      q = q + dq
    else
      s%qs = q
      call mech%retract(s%qs, dq, q, ierr)
    end if
  end subroutine move_by

  !> Weighted RMS over q and v (multipliers excluded) of the step's local errors, lte_q h^3 q(3)
  !> and lte_v h^3 q(4) (the trapezoidal rule's 1/12 and 1/12; mbdk_index3_error_constants), in the
  !> velocities' coordinates (a spatial body's rotation in radians). The derivatives are divided differences of the step mean
  !> accelerations (a_k + a_k+1)/2, placed at the step midpoints: the mean cancels the
  !> period-2 oscillation of the book scheme's accelerations, which would otherwise dominate.
  !> The first two steps have no q(4) from history: it is taken as q(3) / (h + h_prev)
  !> (large, so those steps are judged conservatively).
  real(dp) function error_estimate(s, mech)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    real(dp) :: eq, ev, wq, wv, d1, d0, sum2, b2, b1, b0, h
    integer :: k
    h = s%h
    sum2 = 0.0_dp
    if (.not. s%identity) call mech%coord_weights(s%e%q, s%w)
    do k = 1, s%nv
      b2 = 0.5_dp * (s%a(k) + s%an(k))
      if (s%h_prev > 0.0_dp) then
        b1 = 0.5_dp * (s%a_prev(k) + s%a(k))
        d1 = (b2 - b1) / (0.5_dp * (h + s%h_prev))                   ! q(3)
      else
        b1 = 0.0_dp                     ! (unused: no h_prev2 without h_prev)
        d1 = (s%an(k) - s%a(k)) / h
      end if
      eq = h**3 * s%lte_q * d1
      if (s%h_prev2 > 0.0_dp) then
        b0 = 0.5_dp * (s%a_prev2(k) + s%a_prev(k))
        d0 = (b1 - b0) / (0.5_dp * (s%h_prev + s%h_prev2))
        ev = h**3 * s%lte_v * (d1 - d0) / (0.5_dp * h + s%h_prev + 0.5_dp * s%h_prev2) * 2.0_dp
      else
        ev = h**3 * s%lte_v * d1 / (h + s%h_prev)
      end if
      if (s%identity) then
        wq = s%opt%err_atol + s%opt%err_rtol * max(abs(s%q(k)), abs(s%e%q(k)))
      else
        wq = s%opt%err_atol + s%opt%err_rtol * s%w(k)
      end if
      wv = s%opt%err_atol + s%opt%err_rtol * max(abs(s%v(k)), abs(s%e%v(k)))
      sum2 = sum2 + (eq / wq)**2 + (ev / wv)**2
    end do
    error_estimate = sqrt(sum2 / real(2 * s%nv, dp))
  end function error_estimate

  logical function finite_all(x)
    real(dp), intent(in) :: x(:)
    finite_all = all(abs(x) <= huge(1.0_dp))
  end function finite_all

  !> One step from (t, q, v, a, lam) to tn = t + h into (qn, vn, an, ln), not committed:
  !> the predictors (here), Newton on the increment (newton), and the step's end (finish_step).
  subroutine attempt(s, mech, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    integer, intent(out) :: ierr
    real(dp) :: h, c3, e3, wk
    integer :: k

    h = s%h
    call set_coefficients(s, h)
    ! the pseudo-acceleration is the acceleration at t + (alpha_m - alpha_f) h to O(h^2) (Arnold
    ! and Bruls 2007): where h changes (a substep retry, and back), it is moved to the new
    ! step's shift along the accelerations' slope
    if (s%alpha_terms .and. s%h_prev > 0.0_dp .and. &
        abs(h - s%h_prev) > sqrt(epsilon(1.0_dp)) * h) &
      s%ap = s%ap + ((s%opt%alpha_m - s%opt%alpha_f) * (h - s%h_prev) / s%h_prev) * &
                    (s%a - s%a_prev)
    ! Newmark's part of the increment, h v + h^2 (1/2 - beta) ap; dq = that + beta h^2 ap+
    s%dqhat(:) = h * s%v + s%cq * s%ap
    if (s%book .or. s%h_prev <= 0.0_dp) then
      s%dqp(:) = h * s%v + 0.5_dp * h * h * s%ap
      s%lp(:) = s%lst
    else
      ! the step's rule itself with ap+ and lam* extrapolated linearly: O(h^4) in q
      s%dqp(:) = s%dqhat + s%bh2 * (s%ap + (h / s%h_prev) * (s%ap - s%ap_prev))
      s%lp(:) = s%lst + (h / s%h_prev) * (s%lst - s%lst_old)
      ! where the accepted state's projection found C (nearly) rank-deficient, lam* is (nearly)
      ! not unique: its updates add the part of Phi that C cannot remove, which carried from
      ! step to step grows without bound. There the projection's multipliers (bounded) start it.
      if (s%regular) s%lp = s%lam + (h / s%h_prev) * (s%lam - s%lam_old)
    end if
    ! the residual's dqhat: with the alpha terms, M (dq - dqhat) = cs M a+ (the module header)
    if (s%alpha_terms) s%dqhat = s%dqhat + s%ra * (s%opt%alpha_m * s%ap - s%opt%alpha_f * s%a)
    if (s%book) s%lp = s%lam
    if (s%book .and. s%h_prev > 0.0_dp) s%lp = s%lam + (h / s%h_prev) * (s%lam - s%lam_old)  ! (3.11)
    ! a new h takes a new matrix; h = tn - t jitters by the rounding of t (ulp(t) / h: 2e-9 at
    ! t = 10 s, h = 1e-6), which does not make one
    if (s%have_lu .and. (abs(h - s%h_lu) > sqrt(epsilon(1.0_dp)) * h .or. s%cool > 0 .or. &
                         s%lu_boosted)) s%have_lu = .false.
    if (.not. s%identity .or. s%fd_matrix) call mech%coord_weights(s%q, s%w)
    ! the augmented form's target for what Newton leaves: LOCAL_SHARE times the step's local
    ! error, estimated by what the third-order predictor adds to the second-order one,
    ! beta h^2 (h/h-)(ap - ap-) ~ h^3 q'''/4 (three times the trapezoidal rule's h^3 q'''/12),
    ! in the weights of the update's test. With the options' tolerance alone, what Newton
    ! leaves per step adds up over the 1/h steps and stops the second order as h shrinks; the
    ! share keeps it below a third of the truncation error (a smaller share costs iterations
    ! and buys no accuracy that shows). The first step has no estimate: the options' alone.
    s%tau = 1.0_dp
    s%noise = NOISE_DECAY * s%noise
    if (s%no_renewal > 0) s%no_renewal = s%no_renewal - 1
    if (.not. s%book .and. s%h_prev > 0.0_dp) then
      c3 = s%bh2 * (h / s%h_prev)
      e3 = -huge(1.0_dp)
      do k = 1, s%nv
        if (s%identity) then
          wk = abs(s%q(k))
        else
          wk = s%w(k)
        end if
        e3 = max(e3, abs(c3 * (s%ap(k) - s%ap_prev(k))) / &
                     (s%opt%newton_atol + s%opt%newton_rtol * wk))
      end do
      s%tau = min(1.0_dp, LOCAL_SHARE * e3)
    end if
    call newton(s, mech, ierr)
    if (ierr /= MBDK_SUCCESS) return
    call finish_step(s, mech, ierr)
  end subroutine attempt

  !> Newton on the step's increment dq (qn = q (+) dq) as in the module header; both
  !> formulations share this loop. On success dq and qn are the step's end, vn its trapezoidal
  !> velocity, f the forces of the last evaluation and ln (book) or lstn (augmented) its
  !> multipliers.
  subroutine newton(s, mech, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    integer, intent(out) :: ierr
    real(dp) :: sh, dnorm, dnorm_old, rate, h, phi_tol, phin, alpha_upd, prog, prog_old, alpha0
    logical :: fresh, restarted, book, reused, frozen, upd_fresh, boosted, own, stall_own, &
               penalty_renewed
    integer :: k, nv, m, stalls

    nv = s%nv
    m = s%m
    h = s%h
    book = s%book
    sh = s%cs
    alpha0 = s%opt%alpha
    if (alpha0 == 0.0_dp) alpha0 = MBDK_INDEX3_KAPPA * s%mmax / sh
    s%alpha = alpha0
    reused = s%have_lu
    s%dq(:) = s%dqp
    s%ln(:) = s%lp
    restarted = .false.
    fresh = .false.
    own = .false.
    penalty_renewed = .false.
    dnorm_old = huge(1.0_dp)
    s%iters = 0
    k = 0
    s%e%phi(:) = 0.0_dp
    frozen = .false.
    boosted = .false.
    stalls = 0
    upd_fresh = .false.
    prog_old = huge(1.0_dp)
    do
      call evaluate_at(s, mech, ierr)
      if (ierr /= MBDK_SUCCESS) return
      phin = 0.0_dp
      if (m > 0) phin = maxval(abs(s%e%phi))
      ! max |Phi| accepted: atol, but not below the roundoff of the coordinates
      phi_tol = max(s%opt%newton_atol, 64.0_dp * epsilon(1.0_dp) * s%qn_size)
      ! the multiplier update takes the alpha that produced this Phi: with a stiffened one it
      ! would overshoot BOOST-fold and leave Phi where it was
      alpha_upd = s%alpha
      if (stalls > 0 .and. .not. frozen) call stall_response(s, phin, phi_tol, stalls, boosted, &
                                                             frozen, upd_fresh, dnorm_old)
      call residual_multipliers(s, k > 0 .and. .not. frozen, alpha_upd)
      call residual(s, mech, sh)
      if (.not. s%have_lu) then
        call new_matrix(s, mech, boosted, penalty_renewed, fresh, ierr)
        if (ierr /= MBDK_SUCCESS) return
        own = own .or. fresh
        reused = .false.
      end if
      s%e%r(:) = -s%e%r
      if (s%fd_matrix) then
        call mbdk_lu_solve(s%jm, s%ipiv, s%e%r, ierr)
      else
        call mech%i3_matrix_solve(s%aux, s%e, ierr)
      end if
      if (ierr /= MBDK_SUCCESS) return
      if (.not. finite_all(s%e%r)) then
        ierr = MBDK_ERR_NONFINITE
        return
      end if
      s%iters = s%iters + 1
      k = k + 1
      s%st%newton_iterations = s%st%newton_iterations + 1
      if (s%identity) then
        dnorm = maxval(abs(s%e%r(1:nv)) / (s%opt%newton_atol + s%opt%newton_rtol * abs(s%e%q)))
      else
        dnorm = maxval(abs(s%e%r(1:nv)) / (s%opt%newton_atol + s%opt%newton_rtol * s%w))
      end if
      ! progress: the distance from convergence, in tolerances of the update and of Phi. A
      ! stall counts only after an update from a matrix built at its iterate (an old matrix
      ! contracts slowly for reasons of its own).
      prog = max(dnorm, phin / phi_tol)
      if (.not. book .and. upd_fresh .and. prog > STALL_RATE * prog_old .and. prog > 1.0_dp) &
        stalls = stalls + 1
      prog_old = prog
      ! converged: the update from this iterate is below tolerance, and so is Phi here (frozen:
      ! up to FROZEN_PHI times its tolerance; or the update is at the roundoff floor of the
      ! stiffer matrix).
      ! The update is applied (the Newton error left in q is then its square, or the rate times
      ! it); f keeps this evaluation, the step's end evaluates C at the final q+.
      if (newton_converged(s, k, frozen, phin, phi_tol, dnorm, dnorm_old, own, fresh, &
                           stall_own)) then
        if (stall_own) s%noise = dnorm
        s%dq(:) = s%dq + s%e%r(1:nv)
        if (book) s%ln = s%ln + s%e%r(nv + 1:) / sh
        exit
      end if
      if (s%iters >= s%opt%newton_max_iter) then
        ierr = MBDK_ERR_NEWTON_DIVERGED
        return
      end if
      rate = dnorm / dnorm_old
      if (rate > 1.0_dp .and. k > 1 .and. dnorm > 1.0_dp .and. .not. fresh) then
        ! growing with an old matrix (not roundoff below the tolerance). The first time the
        ! iterate may be spoilt (the augmented form's multiplier update amplifies it), so
        ! restart from the predictor with a matrix built there, and build fresh matrices
        ! for the next steps; later, rebuild the matrix at this iterate.
        s%have_lu = .false.
        dnorm_old = huge(1.0_dp)
        if (.not. restarted) then
          restarted = .true.
          ! fresh matrices for cool_len steps, twice as many after each failed reuse
          s%cool = s%cool_len
          s%cool_len = min(2 * s%cool_len, COOL_MAX)
          reused = .false.
          s%dq(:) = s%dqp
          s%ln(:) = s%lp
          k = 0
          frozen = .false.
          boosted = .false.
          s%alpha = alpha0
          prog_old = huge(1.0_dp)
          stalls = 0
        end if
        upd_fresh = .false.
        cycle
      end if
      s%dq(:) = s%dq + s%e%r(1:nv)
      if (book) s%ln = s%ln + s%e%r(nv + 1:) / sh
      ! rebuild the matrix when two more iterations at this rate would not reach the
      ! options' tolerance (an iteration costs about as much as a factorisation)
      if (rate > REBUILD_RATE .or. dnorm * rate * rate > 1.0_dp) s%have_lu = .false.
      upd_fresh = fresh
      fresh = .false.
      dnorm_old = dnorm
    end do
    ! a matrix carried over from an earlier step served the whole step: reuse pays again
    if (reused) s%cool_len = COOL_START
    s%stalled = frozen
    call move_point(s, mech, ierr)
    if (ierr /= MBDK_SUCCESS) return
    if (.not. book) s%lstn = s%ln

  end subroutine newton

  !> A matrix for Newton at the current iterate (fresh: built there). One by differences, or a
  !> mechanism's own that is costly to build (has_i3_renew), first has its penalty renewed at
  !> the iterate, once per step (what an old augmented matrix loses first: cs alpha C^T C is a
  !> thousand times M); where that did not serve a step, the next COOL_START steps build theirs
  !> anew.
  subroutine new_matrix(s, mech, boosted, penalty_renewed, fresh, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    logical, intent(in) :: boosted
    logical, intent(inout) :: penalty_renewed
    logical, intent(out) :: fresh
    integer, intent(out) :: ierr
    fresh = .false.
    if (s%have_fd .and. .not. (s%book .or. penalty_renewed) .and. s%no_renewal == 0 .and. &
        abs(s%h - s%h_fd) <= sqrt(epsilon(1.0_dp)) * s%h) then
      if (s%fd_matrix) then
        call penalty_matrix(s, mech, ierr)
      else
        call mech%i3_matrix_renew(s%aux, s%cs, s%alpha, ierr)
      end if
      penalty_renewed = .true.
    else
      if (penalty_renewed) s%no_renewal = COOL_START
      call build_matrix(s, mech, ierr)
      s%st%njev = s%st%njev + 1
      s%h_lu = s%h
      fresh = .true.
    end if
    s%st%nlu = s%st%nlu + 1
    if (ierr /= MBDK_SUCCESS) return
    s%have_lu = .true.
    s%lu_boosted = boosted
  end subroutine new_matrix

  !> A stall (measured after the solve) stiffens the penalty BOOST-fold (a new matrix), and at
  !> the next one freezes lam* where |Phi| is within what a frozen step may accept (a larger
  !> Phi stalls for another reason, a stiff force's nonlinearity, and the multipliers go on);
  !> the noise test of a frozen step compares frozen updates only.
  subroutine stall_response(s, phin, phi_tol, stalls, boosted, frozen, upd_fresh, dnorm_old)
    type(mbdk_index3_t), intent(inout) :: s
    real(dp), intent(in) :: phin, phi_tol
    integer, intent(inout) :: stalls
    logical, intent(inout) :: boosted, frozen, upd_fresh
    real(dp), intent(inout) :: dnorm_old
    stalls = 0
    if (.not. boosted) then
      boosted = .true.
      s%alpha = s%alpha * BOOST
      s%have_lu = .false.
      upd_fresh = .false.
    else
      frozen = phin <= FROZEN_PHI * phi_tol
      if (frozen) dnorm_old = huge(1.0_dp)
    end if
  end subroutine stall_response

  !> Newton's stopping test after the update r computed at iterate k (the step's test, in the
  !> module header): the update's norm dnorm (the last one's dnorm_old) and |Phi| (phin against
  !> phi_tol) there. own: the matrix was built in this step; stall_own: set when a stall of such
  !> a matrix is what passes (its level is then the step's roundoff, s%noise).
  logical function newton_converged(s, k, frozen, phin, phi_tol, dnorm, dnorm_old, own, fresh, &
                                  stall_own) result(converged)
    type(mbdk_index3_t), intent(in) :: s
    integer, intent(in) :: k
    logical, intent(in) :: frozen, own, fresh
    real(dp), intent(in) :: phin, phi_tol, dnorm, dnorm_old
    logical, intent(out) :: stall_own
    real(dp) :: left, qsize
    converged = .false.
    stall_own = .false.
    if (k < 2) return
    if (frozen .and. phin <= FROZEN_PHI * phi_tol) then
      converged = dnorm <= 1.0_dp .or. (dnorm <= NOISE .and. dnorm > 0.5_dp * dnorm_old)
    else if (s%m == 0 .or. phin <= phi_tol) then
      converged = dnorm <= 1.0_dp
      if (.not. converged) then
        ! the book form (no multiplier update that stalls near a rank loss, which the
        ! augmented form's own measures handle): the update's roundoff floor above its
        ! tolerance (the matrix of a long chain, whose conditioning grows with its length). An
        ! update from a matrix built at this very iterate (Newton's own rate, not a reused
        ! matrix's slower one) that no longer halves, within NOISE tolerances, is as small as
        ! floating point makes it; once such a floor was met, an update from a matrix built at
        ! its iterate at or below that level (decaying by NOISE_DECAY per step) is too.
        stall_own = s%book .and. fresh .and. dnorm_old < huge(1.0_dp) .and. &
                    dnorm > REBUILD_RATE * dnorm_old .and. dnorm <= NOISE
        converged = stall_own .or. (s%book .and. fresh .and. dnorm <= s%noise)
        return
      end if
      if (s%tau >= 1.0_dp) return
      ! below 1, the step's target (augmented form, small h) on what Newton leaves after this
      ! update, rate / (1 - rate) times it at the contraction rate of the last two updates
      ! (the update itself where no rate is known); or an update from a matrix built in this
      ! step that no longer halves (the roundoff of the increment: an old matrix contracting
      ! slowly is rebuilt instead), or from an old one within STALL_ACCEPT times the level
      ! where a matrix of its own last stalled (noise: decaying by NOISE_DECAY per step, so
      ! that the rebuild at every step that meets roundoff is not repeated in vain); or the
      ! last iteration allowed; or an update within the roundoff of the coordinates (16 eps
      ! of their size: what Phi's roundoff moves them by, which no matrix removes)
      if (s%identity) then
        qsize = max(1.0_dp, maxval(abs(s%e%q)))
      else
        qsize = max(1.0_dp, maxval(s%w))
      end if
      left = dnorm
      if (dnorm_old < huge(1.0_dp)) then
        left = huge(1.0_dp)
        if (dnorm < dnorm_old) left = dnorm * dnorm / (dnorm_old - dnorm)
      end if
      stall_own = own .and. dnorm > REBUILD_RATE * dnorm_old
      converged = left <= max(s%tau, TAU_MIN) .or. stall_own .or. &
                  (dnorm > REBUILD_RATE * dnorm_old .and. dnorm <= STALL_ACCEPT * s%noise) .or. &
                  s%iters >= s%opt%newton_max_iter .or. &
                  maxval(abs(s%e%r(1:s%nv))) <= 16.0_dp * epsilon(1.0_dp) * qsize
    end if
  end function newton_converged

  !> qn = q (+) dq
  subroutine move_to(s, mech, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    integer, intent(out) :: ierr
    ierr = MBDK_SUCCESS
    if (s%identity) then
      s%e%q(:) = s%q + s%dq
    else
      call mech%retract(s%q, s%dq, s%e%q, ierr)
    end if
  end subroutine move_to

  !> The point of the increment dq: qn = q (+) dq, vn from dq (velocity), the residual's mass
  !> term dd = dq - dqhat, and qn_size.
  subroutine move_point(s, mech, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    integer, intent(out) :: ierr
    integer :: k
    real(dp) :: cv, kv1, kv2, qsize
    ierr = MBDK_SUCCESS
    if (s%identity) then
      ! qn = q + dq: the four in one pass (the step's vectors are a few components long, and
      ! a pass's set-up costs about as much as its arithmetic); vn as velocity's
      cv = s%cv
      kv1 = s%kv1
      kv2 = s%kv2
      qsize = 1.0_dp
      if (kv2 == 0.0_dp) then
        do k = 1, s%nv
          s%e%q(k) = s%q(k) + s%dq(k)
          s%e%v(k) = cv * s%dq(k) + kv1 * s%v(k)
          s%e%dd(k) = s%dq(k) - s%dqhat(k)
          qsize = max(qsize, abs(s%e%q(k)))
        end do
      else
        do k = 1, s%nv
          s%e%q(k) = s%q(k) + s%dq(k)
          s%e%v(k) = cv * s%dq(k) + kv1 * s%v(k) + kv2 * s%ap(k)
          s%e%dd(k) = s%dq(k) - s%dqhat(k)
          qsize = max(qsize, abs(s%e%q(k)))
        end do
      end if
      s%qn_size = qsize
    else
      call move_to(s, mech, ierr)
      if (ierr /= MBDK_SUCCESS) return
      call velocity(s)
      s%e%dd(:) = s%dq - s%dqhat
      s%qn_size = max(1.0_dp, maxval(abs(s%e%q)))
    end if
  end subroutine move_point

  !> The evaluation at the iterate dq: its point (move_point), and f, Phi, gamma, Phi_t there
  !> (C kept by the mechanism).
  subroutine evaluate_at(s, mech, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    integer, intent(out) :: ierr
    call move_point(s, mech, ierr)
    if (ierr /= MBDK_SUCCESS) return
    call mech%i3_evaluate(s%aux, s%tn, s%e, .true., .false., ierr)
    s%st%nfev = s%st%nfev + 1
  end subroutine evaluate_at

  !> The residual's multipliers lt at the iterate just evaluated: the book form's ln; the
  !> augmented form's lam* + alpha Phi, after lam* <- lam* + alpha_upd Phi where update (the
  !> two in one pass: a few components each)
  subroutine residual_multipliers(s, update, alpha_upd)
    type(mbdk_index3_t), intent(inout) :: s
    logical, intent(in) :: update
    real(dp), intent(in) :: alpha_upd
    real(dp) :: alpha
    integer :: i
    alpha = s%alpha
    if (s%book) then
      s%e%lt(:) = s%ln
    else if (update) then
      do i = 1, s%m
        s%ln(i) = s%ln(i) + alpha_upd * s%e%phi(i)
        s%e%lt(i) = s%ln(i) + alpha * s%e%phi(i)
      end do
    else
      s%e%lt(:) = s%ln + alpha * s%e%phi
    end if
  end subroutine residual_multipliers

  !> r = M (dq - dqhat) - s (f - C^T lt) at the last evaluation (the equations of motion at
  !> t+ times s, (3.15); dd = dq - dqhat from evaluate_at), and the book scheme's Phi rows.
  subroutine residual(s, mech, sh)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    real(dp), intent(in) :: sh
    call mech%i3_residual(s%aux, s%e, sh)
    if (s%book) s%e%r(s%nv + 1:) = s%e%phi
  end subroutine residual

  !> The Newton matrix at the current iterate: the mechanism's own (has_i3_matrix) or, for a
  !> mechanism without tangents, forward differences of the residual in each component of dq
  !> (the multipliers' update lt = ln + alpha Phi and the retraction included, so that the
  !> matrix is the residual's Jacobian; one evaluation per column, counted in nfev), the book
  !> scheme's columns of s lambda being C^T; factorised by mbdk_lapack's LU. The evaluation and
  !> the residual at the iterate are restored after.
  subroutine build_matrix(s, mech, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    integer, intent(out) :: ierr
    real(dp) :: sh, dlt, keep, wmax
    integer :: j, nv, m
    if (.not. s%fd_matrix) then
      ! (a build that fails part-way leaves no tangent to renew)
      s%have_fd = .false.
      call mech%i3_matrix(s%aux, s%book, s%tn, s%e, s%ln, s%cs, s%cd, s%alpha, ierr)
      ! a model's matrix costly to build keeps its tangent for the penalty's renewal
      if (ierr == MBDK_SUCCESS .and. mech%has_i3_renew .and. .not. s%book) then
        s%h_fd = s%h
        s%have_fd = .true.
      end if
      return
    end if
    nv = s%nv
    m = s%m
    sh = s%cs
    s%r0 = s%e%r
    s%f0 = s%e%f
    s%phi0 = s%e%phi
    s%gam0 = s%e%gam
    s%phit0 = s%e%phit
    s%jm = 0.0_dp
    wmax = max(1.0_dp, maxval(s%w))
    do j = 1, nv
      keep = s%dq(j)
      ! the increment: sqrt(eps) of the coordinates' size (wmax, the largest of the
      ! mechanism's coordinate sizes: q+ resolves eps of it, and Phi(q+) and r with it; an
      ! increment scaled to the component's own motion or size, h v + s a or |q_j|, falls
      ! below that for a coordinate at rest, at 0 or at small h, and leaves its column to
      ! roundoff: a singular matrix), or of the increment itself where larger
      dlt = sqrt(epsilon(1.0_dp)) * max(abs(keep), s%h * abs(s%v(j)) + s%bh2 * abs(s%ap(j)), wmax)
      s%dq(j) = keep + dlt
      dlt = s%dq(j) - keep
      call evaluate_at(s, mech, ierr)
      if (ierr /= MBDK_SUCCESS) then
        s%dq(j) = keep
        return
      end if
      if (s%book) then
        s%e%lt = s%ln
      else
        s%e%lt = s%ln + s%alpha * s%e%phi
      end if
      call residual(s, mech, sh)
      s%dq(j) = keep
      s%jm(:, j) = (s%e%r - s%r0) / dlt
    end do
    ! back to the iterate (its C for the multipliers' columns and the solves after)
    call evaluate_at(s, mech, ierr)
    if (ierr /= MBDK_SUCCESS) return
    s%e%f = s%f0
    s%e%phi = s%phi0
    s%e%gam = s%gam0
    s%e%phit = s%phit0
    s%e%r = s%r0
    if (s%book) then
      s%e%lt = s%ln
      do j = 1, m
        s%col(1:m) = 0.0_dp
        s%col(j) = 1.0_dp
        call mech%i3_ct_times(s%aux, s%col(1:m), s%jm(1:nv, nv + j))
      end do
    else
      s%e%lt = s%ln + s%alpha * s%e%phi
      ! what the penalty's renewal keeps: the matrix less cs alpha C^T C at this iterate (the
      ! rest of the penalty's derivative, the retraction's turn of C by about h |Omega|,
      ! changes slowly and stays in)
      s%jfd = s%jm
      call penalty_add(s, mech, -1.0_dp, s%jfd)
      s%h_fd = s%h
      s%have_fd = .true.
    end if
    call mbdk_lu_factor(s%jm, s%ipiv, ierr)
    if (ierr /= MBDK_SUCCESS) ierr = MBDK_ERR_SINGULAR_MATRIX
  end subroutine build_matrix

  !> a = a + sgn cs alpha C^T C in its velocities' block, C of the last evaluation
  subroutine penalty_add(s, mech, sgn, a)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    real(dp), intent(in) :: sgn
    real(dp), intent(inout) :: a(:, :)
    integer :: j
    if (s%m == 0) return
    do j = 1, s%nv
      s%wv = 0.0_dp
      s%wv(j) = 1.0_dp
      call mech%i3_c_times(s%aux, s%wv, s%rc)
      call mech%i3_ct_times(s%aux, s%rc, s%wv)
      a(1:s%nv, j) = a(1:s%nv, j) + (sgn * s%cs * s%alpha) * s%wv
    end do
  end subroutine penalty_add

  !> The renewal of a matrix by differences at the iterate: jm = jfd + cs alpha C^T C with C
  !> of the last evaluation (the augmented form's penalty, a thousand times M, is what an old
  !> matrix loses first as the mechanism turns), factorised; jfd is kept
  subroutine penalty_matrix(s, mech, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    integer, intent(out) :: ierr
    s%jm = s%jfd
    call penalty_add(s, mech, 1.0_dp, s%jm)
    call mbdk_lu_factor(s%jm, s%ipiv, ierr)
    if (ierr /= MBDK_SUCCESS) ierr = MBDK_ERR_SINGULAR_MATRIX
  end subroutine penalty_matrix

  !> The end of a converged step: the book scheme's v+ and a+ from the trapezoidal relations;
  !> the augmented form's projections (module header).
  subroutine finish_step(s, mech, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    integer, intent(out) :: ierr
    real(dp) :: h
    h = s%h
    ierr = MBDK_SUCCESS
    if (s%book) then
      ! Newmark's ap+ from dq, and the acceleration from the alpha relation
      s%apn(:) = s%ca * s%dq + s%ka1 * s%v + s%ka2 * s%ap
      if (s%alpha_terms) then
        s%an(:) = ((1.0_dp - s%opt%alpha_m) * s%apn + s%opt%alpha_m * s%ap - &
                   s%opt%alpha_f * s%a) / (1.0_dp - s%opt%alpha_f)
      else
        s%an(:) = s%apn
      end if
    else
      call mech%i3_evaluate(s%aux, s%tn, s%e, .false., .false., ierr)
      if (ierr /= MBDK_SUCCESS) return
      ! at a rank loss of C (a singular crossing, redundant joints) the projections take the
      ! regular augmented Lagrangian path instead of failing
      call mech%i3_cs_factor(s%aux, NEAR_PIVOT, .true., s%regular_n, ierr)
      if (ierr /= MBDK_SUCCESS) return
      call keep_joints(s, mech, ierr)
      if (ierr /= MBDK_SUCCESS) return
      if (mech%velocity_forces .and. s%m > 0) then
        ! forces that depend on v (dampers, the gyroscopic moment) taken at P vn, not at the
        ! trapezoidal vn = (2/h) dq - v: Newton's last update, at the roundoff of Phi (about
        ! eps |q| across the joints), is in vn 2/h times larger, and f(vn) would carry it into
        ! a~ and v+ at every step: an error floor that does not shrink with h
        call mech%i3_project_velocity(s%aux, s%e, ierr)
        if (ierr /= MBDK_SUCCESS) return
        call mech%i3_evaluate(s%aux, s%tn, s%e, .true., .true., ierr)
        if (ierr /= MBDK_SUCCESS) return
      end if
      ! v+ = P (v + (h/2)(a + a~)), P the projection onto C v + Phi_t = 0 and a~ any
      ! solution of M a~ = f - C^T (anything): P removes M^-1 C^T terms, so this is P v+ of
      ! the trapezoidal rule (a+ differs from a~ by such a term once Newton has converged),
      ! without the Newton error that v+ = (2/h) dq - v would carry amplified by 2/h.
      ! Then a+ and lambda+ from M a + C^T lambda = f, C a = gamma(q+, v+): the projection
      ! of a+ onto the acceleration constraints, with its multipliers, free of the Newton
      ! error (4/h^2) that a+ = (4/h^2) dq - .. would carry.
      call mech%i3_cs_solve(s%aux, s%e%f, s%zero_m, s%an, s%ln, ierr)
      if (ierr /= MBDK_SUCCESS) return
      ! v+ = v + h ((1 - gamma) ap + gamma ap~), ap~ the pseudo-acceleration of a~
      if (s%alpha_terms) s%an = ((1.0_dp - s%opt%alpha_f) * s%an + s%opt%alpha_f * s%a - &
                                 s%opt%alpha_m * s%ap) / (1.0_dp - s%opt%alpha_m)
      s%e%v(:) = s%v + (s%opt%gamma * h) * (s%cg * s%ap + s%an)
      ! vn onto C v + Phi_t = 0 (mass-orthogonal)
      call mech%i3_project_velocity(s%aux, s%e, ierr)
      if (ierr /= MBDK_SUCCESS) return
      ! q+ is unchanged: C, Phi are the same; only gamma changes with v+
      if (s%m > 0) then
        call mech%i3_evaluate(s%aux, s%tn, s%e, .false., .true., ierr)
        if (ierr /= MBDK_SUCCESS) return
      end if
      call mech%i3_cs_solve(s%aux, s%e%f, s%e%gam, s%an, s%ln, ierr)
      if (ierr /= MBDK_SUCCESS) return
      ! the pseudo-acceleration of the projected a+ (the alpha relation)
      if (s%alpha_terms) then
        s%apn(:) = ((1.0_dp - s%opt%alpha_f) * s%an + s%opt%alpha_f * s%a - &
                    s%opt%alpha_m * s%ap) / (1.0_dp - s%opt%alpha_m)
      else
        s%apn(:) = s%an
      end if
    end if
    if (.not. (finite_all(s%e%q) .and. finite_all(s%e%v) .and. finite_all(s%an))) &
      ierr = MBDK_ERR_NONFINITE
  end subroutine finish_step

  !> Newton tested |Phi| at its last iterate and then applied the last update, which leaves
  !> |Phi| at q+ above the tolerance now and then (an old matrix's update, or a renewed
  !> penalty's: penalty_matrix). There one Gauss-Newton projection of q+ onto Phi = 0 (the
  !> mass-orthogonal correction with the factorisation just made) brings it back to what its
  !> residual leaves, the square of what it corrects. A frozen step keeps what Newton accepted
  !> (up to FROZEN_PHI times the tolerance).
  subroutine keep_joints(s, mech, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    class(mbdk_mechanism_t), intent(in) :: mech
    integer, intent(out) :: ierr
    real(dp) :: phi_tol
    ierr = MBDK_SUCCESS
    if (s%m == 0 .or. s%stalled) return
    ! (qn is Newton's, whose qn_size newton's move_point set)
    phi_tol = max(s%opt%newton_atol, 64.0_dp * epsilon(1.0_dp) * s%qn_size)
    if (maxval(abs(s%e%phi)) <= phi_tol) return
    call mech%i3_cs_solve(s%aux, s%zero_nv, s%e%phi, s%corr, s%mu, ierr)
    if (ierr /= MBDK_SUCCESS) return
    call move_by(s, mech, s%e%q, -s%corr, ierr)
    if (ierr /= MBDK_SUCCESS) return
    call mech%i3_evaluate(s%aux, s%tn, s%e, .true., .false., ierr)
    if (ierr /= MBDK_SUCCESS) return
    s%st%nfev = s%st%nfev + 1
    call mech%i3_cs_factor(s%aux, NEAR_PIVOT, .true., s%regular_n, ierr)
  end subroutine keep_joints

  !> vn from the increment: v + h (1 - gamma) ap + h gamma ap+ with Newmark's ap+ (for the
  !> trapezoidal rule (2/h) dq - v)
  subroutine velocity(s)
    type(mbdk_index3_t), intent(inout) :: s
    if (s%kv2 == 0.0_dp) then
      s%e%v(:) = s%cv * s%dq + s%kv1 * s%v
    else
      s%e%v(:) = s%cv * s%dq + s%kv1 * s%v + s%kv2 * s%ap
    end if
  end subroutine velocity

  !> The step's coefficients for h (the type's comment); for the trapezoidal rule's parameters
  !> they are its own to the last bit (h^2/4, 2/h, 4/h^2, ...)
  subroutine set_coefficients(s, h)
    type(mbdk_index3_t), intent(inout) :: s
    real(dp), intent(in) :: h
    real(dp) :: beta, gamma, rs
    beta = s%opt%beta
    gamma = s%opt%gamma
    rs = (1.0_dp - s%opt%alpha_f) / (1.0_dp - s%opt%alpha_m)
    s%bh2 = beta * h * h
    s%cs = s%bh2 * rs
    s%cd = gamma * h * rs
    s%cq = h * h * (0.5_dp - beta)
    s%cv = gamma / (beta * h)
    s%kv1 = 1.0_dp - gamma / beta
    s%kv2 = h * (1.0_dp - gamma - gamma * (0.5_dp - beta) / beta)
    s%ca = 1.0_dp / (beta * h * h)
    s%ka1 = -1.0_dp / (beta * h)
    s%ka2 = -(0.5_dp - beta) / beta
    s%cg = (1.0_dp - gamma) / gamma
    s%ra = -s%bh2 / (1.0_dp - s%opt%alpha_m)
  end subroutine set_coefficients

  !> The options' parameters are the trapezoidal rule's (beta 1/4, gamma 1/2, no alphas)
  !> The options' parameters give a second-order member: gamma = 1/2 - alpha_m + alpha_f (to
  !> the roundoff of the members' formulas)
  logical function mbdk_index3_is_second_order(opt) result(yes)
    type(mbdk_index3_options_t), intent(in) :: opt
    yes = abs(opt%gamma - (0.5_dp - opt%alpha_m + opt%alpha_f)) <= 64.0_dp * epsilon(1.0_dp)
  end function mbdk_index3_is_second_order

  !> The constants of the step's local errors in q and v, from the Taylor expansion of one step
  !> from the exact solution with the pseudo-acceleration at its shift d = alpha_m - alpha_f,
  !> ap = q''(t + d h) + c h^2 q'''' (the alpha relation fixes c = (1 - alpha_f)/2 -
  !> ((1 - alpha_m)(1 + d)^2 + alpha_m d^2)/2):
  !>   q: h^3 q''' (beta + d/2 - 1/6)
  !>   v: h^3 q'''' ((1 - gamma) d^2/2 + gamma (1 + d)^2/2 + c - 1/6)
  !> (Geradin and Cardona's estimate h^2 (beta - 1/6)(a+ - a) of Newmark's rule is the first
  !> with d = 0). generalized_alpha's q constant is 1/12 + d^2/4. The trapezoidal rule's are
  !> 1/12 and 1/12, taken as written so that its estimate keeps its bits. Newmark's linear
  !> acceleration rule (beta 1/6, gamma 1/2) has lte_q = 0: its q is third order per step, and
  !> the step is controlled by the v error alone (whose constant, 1/12, is not zero).
  subroutine mbdk_index3_error_constants(opt, lte_q, lte_v)
    type(mbdk_index3_options_t), intent(in) :: opt
    real(dp), intent(out) :: lte_q, lte_v
    real(dp) :: d, c, am, af, beta, gamma
    if (mbdk_index3_is_trapezoidal(opt)) then
      lte_q = 1.0_dp / 12.0_dp
      lte_v = 1.0_dp / 12.0_dp
      return
    end if
    am = opt%alpha_m
    af = opt%alpha_f
    beta = opt%beta
    gamma = opt%gamma
    d = am - af
    c = 0.5_dp * (1.0_dp - af) - 0.5_dp * ((1.0_dp - am) * (1.0_dp + d)**2 + am * d * d)
    lte_q = beta + 0.5_dp * d - 1.0_dp / 6.0_dp
    lte_v = 0.5_dp * (1.0_dp - gamma) * d * d + 0.5_dp * gamma * (1.0_dp + d)**2 + c - &
            1.0_dp / 6.0_dp
  end subroutine mbdk_index3_error_constants

  logical function mbdk_index3_is_trapezoidal(opt) result(yes)
    type(mbdk_index3_options_t), intent(in) :: opt
    yes = opt%beta == 0.25_dp .and. opt%gamma == 0.5_dp .and. opt%alpha_m == 0.0_dp .and. &
      opt%alpha_f == 0.0_dp
  end function mbdk_index3_is_trapezoidal

  !> Steps and samples of a solve: fixed step, as mbdk_step_plan (h, every); adaptive, samples
  !> at t0 + k dt_out and t_end (nsteps is then the number of sample intervals).
  subroutine mbdk_index3_plan(opt, t0, t_end, nsteps, nsamp, shortened, stat)
    type(mbdk_index3_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_end
    integer(i8), intent(out) :: nsteps
    integer, intent(out) :: nsamp, stat
    logical, intent(out) :: shortened
    if (opt%adaptive /= 0) then
      stat = MBDK_ERR_INVALID_INPUT
      nsteps = 0
      nsamp = 0
      shortened = .false.
      if (.not. (opt%h > 0.0_dp .and. opt%err_rtol >= 0.0_dp .and. opt%err_atol > 0.0_dp)) return
      if (.not. (opt%h_min >= 0.0_dp .and. opt%h_max >= 0.0_dp)) return
      if (opt%h_max > 0.0_dp .and. opt%h_min > opt%h_max) return
      call mbdk_step_plan(t0, t_end, opt%dt_out, 1, nsteps, nsamp, shortened, stat)
      if (stat > 0) stat = MBDK_SUCCESS
    else
      call mbdk_step_plan(t0, t_end, opt%h, opt%every, nsteps, nsamp, shortened, stat)
    end if
  end subroutine mbdk_index3_plan

end module mbdk_trapezoidal_index3
