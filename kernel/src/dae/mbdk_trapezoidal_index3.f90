!> trapezoidal_index3: direct integration of the index-3 DAE of a planar scene
!>
!>   M q'' + D(q)^T lambda = f(q, q', t),   Phi(q, t) = 0
!>
!> by the implicit trapezoidal rule (Fekete (2023) 3.2.1). With s = h^2/4 and the trapezoidal
!> relations (3.12)-(3.13),
!>   v+ = (2/h)(q+ - q) - v,     a+ = (4/h^2)(q+ - q) - (4/h) v - a,
!> the equations of motion at t+ = t + h, multiplied by s (3.15), read
!>   r(q+, lambda+) = M (q+ - qhat) + s (D^T lambda+ - f) = 0,   qhat = q + h v + s a.
!>
!> Formulations (mbdk_index3_options_t%formulation):
!>   1 index3     the book's scheme: Newton-Raphson (3.16) on (q+, lambda+) for r = 0 and
!>                Phi(q+) = 0, multiplier predictor (3.11) lambda+ = lambda + (h/h-)(lambda -
!>                lambda-), position predictor q + h v + (h^2/2) a. v+ and a+ follow from the
!>                trapezoidal relations and do not satisfy Phi' = 0, Phi'' = 0: the weakness the
!>                book names. Worse, the errors of v and a in the constraint directions
!>                alternate in sign from step to step with a growing amplitude (the trapezoidal
!>                rule on an index-3 system is unstable there: Cardona and Geradin 1989): on the
!>                double pendulum, the four-bar and the crane |D a - gamma| grows about 15-fold
!>                per 1.4 s whatever h, until Newton fails after a few seconds (5.0 s on the
!>                four-bar, 10.7 s on the double pendulum at h = 1e-3: studies/index3.py).
!>   2 augmented  the index-3 augmented Lagrangian with projections (ALI3-P: Bayo and Ledesma
!>                1996; Cuadrado, Cardenal and Bayo 1997; the family the book cites in [6], [20],
!>                [23]): Newton on q+ alone for
!>                  M (q+ - qhat) + s (D^T (lam* + alpha Phi) - f) = 0,
!>                with lam* <- lam* + alpha Phi after every iteration, from the predictor
!>                q + h v + s (a + a_x), a_x = a + (h/h-)(a - a-) (the rule itself with a+
!>                extrapolated: O(h^4)) and lam* extrapolated likewise. Then the mass-orthogonal
!>                projections of v+ onto D v + Phi_t = 0 and of a+ onto D a = gamma (one
!>                factorisation of [M D^T; D 0], through D M^-1 D^T when M > 0; where D has
!>                lost a rank, redundant joints or a singular configuration, the regular
!>                augmented Lagrangian path of mbdk_constrained, and likewise for the
!>                consistent a and lambda at t0), computed so that
!>                the Newton error of q+ is not amplified: P removes every M^-1 D^T term, so
!>                  v+ = P (v + (h/2)(a + a~)),  a~ any solution of M a~ = f - D^T (..),
!>                equals P (2/h (q+ - q) - v) once Newton has converged, without its 2/h times
!>                the Newton error; and a+, lambda+ solve M a + D^T lambda = f, D a = gamma(q+,
!>                v+), the projection of a+ with its multipliers (second order), without the
!>                4/h^2 times the Newton error of the trapezoidal a+. Taken from the relations,
!>                a Newton tolerance of 1e-10 capped the error at 1e-5 on the double pendulum
!>                (10 s) and made it grow as h fell below 3e-4; now the error is second order
!>                down to h = 6e-5 (1.9e-7) and the Newton tolerance adds below 2 %. Without
!>                constraints the same path gives a+ = M^-1 f.
!>                Parameters: alpha, the penalty factor (force per unit of Phi). Default
!>                alpha = 0: at every step alpha = KAPPA max(M) / s, KAPPA = 1e3, so that s alpha
!>                D^T D outweighs M a thousandfold whatever h; then Phi shrinks about 1000-fold
!>                per multiplier update. A fixed alpha (the literature's 1e7-1e9) converges
!>                slowly at small h (s alpha ~ M: the step-size controller then stalls) and
!>                makes the matrix ill-conditioned at large h. newton_max_iter: default 20.
!>
!> Newton matrix (analytic; tangent stiffness and damping of the force elements from
!> mbdk_forces_tangent, geometric stiffness of the joints from mbdk_joints_tangent):
!>   index3:    [M + s (K_c(lambda) + K_f) + (h/2) C_f, D^T; D, 0] in the unknowns (dq, s dlambda)
!>   augmented: M + s (K_c(lam*) + K_f + alpha D^T D) + (h/2) C_f. K_c takes lam* without
!>              alpha Phi: that term vanishes at the solution, and far from it (the predictor)
!>              it inflates the geometric stiffness until Newton's first step overshoots.
!> The book scales both rows by s (3.15)-(3.16) with lambda itself as unknown: its matrix
!> [M + .., s D^T; s D, 0] has a condition number growing like h^-4. Scaling the unknown to
!> s lambda and leaving Phi unscaled gives the same Newton iterates (row and column scalings do
!> not change Newton's steps) with a condition number bounded as h -> 0 (studies/index3.py
!> measures both; mbdk_index3_newton_matrix builds all three forms).
!>
!> Newton. Up to MBDK_SMALL_DENSE_MAX rows the matrix is factorised in-house (LAPACK's call
!> overhead dominates such systems; model%small_dense = false, or more rows, take LAPACK's
!> dgetrf/dgetrs): the augmented form's matrix, when symmetric to roundoff (no dampers: their
!> tangent stiffness is unsymmetric) and positive definite, by the block LDL^T with the bodies as
!> 3 x 3 pivot blocks (half the cost of the LU: 0.76 us per step on the double pendulum at
!> h = 1e-3 against 1.2 us); otherwise by the LU with partial pivoting. An LU that has served two
!> solves forms its explicit inverse for the next ones (a fixed-length column product, a quarter
!> of the triangular sweeps at 10 rows: the book scheme's matrix serves about 30 solves;
!> stats%nlu counts either kind). The matrix is reused across iterations and steps
!> while Newton contracts. It is rebuilt at the current iterate when the contraction rate exceeds
!> 0.5 or two more iterations at the current rate would not reach the tolerance (an iteration
!> costs about a factorisation), and when h changes. When an update grows with an old matrix, the
!> step restarts once from the predictor with a matrix built there (the augmented form's
!> multiplier update can spoil the iterate beyond repair), and the next 8 steps start with fresh
!> matrices, twice as many after each such failure until a step is served by an old matrix again
!> (with alpha D^T D a thousand times M, a matrix from the last step fails once h |omega| is above
!> about 1e-3). A step converges when the update computed at an iterate is below 1 in the weighted
!> norm (atol + rtol |q|) and max |Phi| <= atol there (not below 64 eps max|q|; a step whose
!> multipliers were frozen at a rank loss: below). That last update is applied. At least two
!> evaluations per step, so both tests are made on evaluated residuals, never on predicted ones.
!> After newton_max_iter updates it fails with MBDK_ERR_NEWTON_DIVERGED (a singular matrix:
!> SINGULAR_MATRIX).
!>
!> Singular configurations (augmented form). Where D is close to losing a rank (a four-bar
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
!>   - the projections take the regular augmented Lagrangian path of mbdk_constrained already
!>     below a relative pivot of NEAR_PIVOT of D M^-1 D^T, not only where it is singular: exact
!>     projections amplify the part of gamma (and of D v) that the vanishing direction cannot
!>     meet by up to 1/sigma^2, and the jump in a and v spoils the steps after it.
!>   - after such a projection the next step's lam* starts from the projection's multipliers,
!>     not from its own: with D rank-deficient lam* is not unique, and its updates accumulate
!>     the part of Phi that D cannot remove from step to step without bound.
!> Where no pose exists (a driver pushing a loop past its dead point) Newton still fails there.
!> studies/index3.py (table index3_crossings) measures the IFToMM A02 chains of 1 to 40 loops.
!>
!> Step size. Fixed: opt%h, samples every opt%every steps (mbdk_step_plan). In the augmented
!> form a step whose Newton iteration fails (diverges, meets a singular matrix or a non-finite
!> iterate: typically near a singular configuration, where D loses rank) is retried in
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
!>     projected onto Phi = 0 (Gauss-Newton), v onto D v + Phi_t = 0, and a, lambda come from
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
!>     Next to a rank loss of D (a solve froze its multipliers) the difference of the
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
!> Code layout. The Newton matrix and its factorisations are mbdk_index3_matrix; the step-size
!> controller is mbdk_step_controller_t. Here: the solver's state between steps (mbdk_index3_t),
!> one step (mbdk_index3_step: from t to a given tn, not retried), a fixed-step advance with the
!> substep retries (mbdk_index3_advance), and the whole-interval driver with sampling, fixed or
!> adaptive (mbdk_index3_solve). An embedder steps through mbdk_index3_init and
!> mbdk_index3_advance (or the C stepper, mbdk_stepper_create_index3).
module mbdk_trapezoidal_index3
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use, intrinsic :: iso_c_binding, only: c_int, c_double, c_intptr_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  use mbdk_clock, only: mbdk_timer_t, mbdk_timer_start, mbdk_timer_stop
  use mbdk_interrupt, only: mbdk_interrupted, mbdk_progress
  use mbdk_model, only: mbdk_model_t, mbdk_model_accelerations, MBDK_SOLVER_KKT, mbdk_model_sparse, &
    mbdk_model_watch_start, mbdk_model_watch
  use mbdk_constrained, only: mbdk_constrained_t, mbdk_constrained_init, &
    mbdk_constrained_factor, mbdk_constrained_solve
  use mbdk_joints, only: mbdk_joints_eval, mbdk_body_rotations, MBDK_JOINT_TYPES
  use mbdk_force_elements, only: mbdk_forces_eval
  use mbdk_sparse_schur, only: mbdk_sparse_d_times, mbdk_sparse_w_residual
  use mbdk_index3_matrix, only: mbdk_index3_factors_t, mbdk_index3_factors_init, &
    mbdk_index3_factor, mbdk_index3_factors_solve, mbdk_index3_newton_matrix, &
    MBDK_INDEX3_UNSCALED, MBDK_INDEX3_SCALED_BOOK, MBDK_INDEX3_SCALED
  use mbdk_step_controller, only: mbdk_step_controller_t, mbdk_controller_init, &
    mbdk_controller_next_step, mbdk_controller_accept, mbdk_controller_reject, &
    mbdk_controller_newton_failure, mbdk_controller_too_small
  use mbdk_fixed_step, only: mbdk_step_plan
  implicit none
  private
  public :: mbdk_index3_solve, mbdk_index3_newton_matrix, mbdk_index3_plan, mbdk_index3_init, &
    mbdk_index3_step, mbdk_index3_advance
  public :: MBDK_INDEX3_UNSCALED, MBDK_INDEX3_SCALED_BOOK, MBDK_INDEX3_SCALED

  integer, parameter, public :: MBDK_INDEX3_BOOK = 1, MBDK_INDEX3_AUGMENTED = 2
  !> opt%adaptive: 1 the local error estimate from differences, 2 local Richardson extrapolation
  integer, parameter, public :: MBDK_INDEX3_ESTIMATED = 1, MBDK_INDEX3_EXTRAPOLATED = 2
  !> alpha = 0 (the default): alpha = KAPPA max(M) / s at every step, so that the penalty term
  !> s alpha D^T D outweighs the mass matrix by KAPPA whatever h (see the module header).
  real(dp), parameter, public :: MBDK_INDEX3_KAPPA = 1.0e3_dp
  !> fixed step: a step whose Newton iteration fails is retried in substeps down to h / 4^this
  integer, parameter, public :: MBDK_INDEX3_MAX_CUTS = 5
  !> Newton: a matrix is rebuilt when the contraction rate exceeds this
  real(dp), parameter :: REBUILD_RATE = 0.5_dp
  !> augmented form, near a rank loss of D (see "Singular configurations" in the header): an
  !> iteration whose progress, computed with a matrix built at the iterate before, falls by less
  !> than STALL_RATE has stalled; the first stall multiplies alpha by BOOST, the second freezes
  !> lam*; a frozen step converges with max |Phi| up to FROZEN_PHI times its tolerance, and on
  !> an update that no longer shrinks within NOISE tolerances (the roundoff of the stiffer
  !> matrix)
  real(dp), parameter :: STALL_RATE = 0.25_dp, BOOST = 1.0e3_dp, NOISE = 1.0e2_dp, &
    FROZEN_PHI = 1.0e3_dp
  !> the projections take the regular path below this relative pivot of D M^-1 D^T
  real(dp), parameter :: NEAR_PIVOT = 1.0e-6_dp
  !> after a failed reuse, this many steps start with fresh matrices (doubled after each further
  !> failure, up to COOL_MAX)
  integer, parameter :: COOL_START = 8, COOL_MAX = 1024
  !> adaptive: a step within this fraction of the last matrix's h keeps the matrix
  real(dp), parameter :: KEEP_MATRIX = 0.05_dp
  !> adaptive, extrapolated: Gauss-Newton iterations of the projection of the extrapolated q
  !> (it starts within the square of the step's error of Phi = 0: one or two suffice)
  integer, parameter :: PROJECT_MAX_ITER = 10
  !> adaptive, extrapolated: next to a rank loss of D, an error norm of the macro step up to
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
  end type mbdk_index3_options_t


  !> The solver's state between steps: the accepted state (t, q, v, a, lam) with the history
  !> the predictors and the error estimate use, the Newton matrix and its reuse policy, the work
  !> arrays of a step (allocated once) and the statistics.
  type, public :: mbdk_index3_t
    type(mbdk_index3_options_t) :: opt
    integer :: nc = 0, m = 0, nk = 0
    logical :: book = .true.
    real(dp) :: t = 0.0_dp, tn = 0.0_dp, h = 0.0_dp, h_prev = 0.0_dp, h_prev2 = 0.0_dp
    real(dp) :: alpha = 0.0_dp, h_lu = 0.0_dp
    !> the matrix was built with a stiffened alpha (a stalled step's): no other step takes it
    logical :: lu_boosted = .false.
    !> the projection of the accepted state (regular) and of the attempted one (regular_n) took
    !> the regular path: D is (nearly) rank-deficient there
    logical :: regular = .false., regular_n = .false.
    logical :: have_lu = .false.
    !> the last attempted step's Newton iteration froze lam* (after two stalls: next to a rank
    !> loss of D, where a multiplier no longer reaches the vanishing direction)
    logical :: stalled = .false.
    integer :: cool = 0, cool_len = COOL_START
    integer :: iters = 0                !< Newton iterations of the last attempted step
    real(dp) :: retries = RETRY_BUDGET  !< what is left of the retry budget
    type(mbdk_stats_t) :: st
    type(mbdk_index3_factors_t) :: fa
    real(dp), allocatable :: q(:), v(:), a(:), lam(:), lam_old(:), a_prev(:), a_prev2(:)
    real(dp), allocatable :: qn(:), vn(:), an(:), ln(:), lst(:), lstn(:), lst_old(:)
    real(dp), allocatable :: qhat(:), qp(:), lp(:), lt(:), fq(:), phi(:), d(:, :), gam(:)
    real(dp), allocatable :: phit(:), lw(:), rc(:), corr(:), mu(:), r(:)
    real(dp), allocatable :: zero_nc(:), zero_m(:), one_nc(:)
    !> the projections of v and a (mbdk_constrained, weight M^-1)
    type(mbdk_constrained_t) :: cs
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

contains

  !> A solver at (t0, y0 = [q; v]) with options opt: validates them, allocates the work arrays
  !> and computes the consistent a and lambda at t0 (the reduced formulation's solve).
  !> MBDK_ERR_INVALID_INPUT, MBDK_ERR_NOT_APPLICABLE (adaptive with the book's scheme), or the
  !> failure of that first solve (MBDK_ERR_SINGULAR_MATRIX with dependent constraints).
  subroutine mbdk_index3_init(s, model, opt, t0, y0, stat)
    type(mbdk_index3_t), intent(out) :: s
    type(mbdk_model_t), intent(in) :: model
    type(mbdk_index3_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, y0(:)
    integer, intent(out) :: stat
    integer :: nc, m, nk, astat

    stat = MBDK_ERR_INVALID_INPUT
    nc = model%nc
    m = model%m
    if (opt%formulation /= MBDK_INDEX3_BOOK .and. opt%formulation /= MBDK_INDEX3_AUGMENTED) return
    if (.not. (opt%newton_rtol >= 0.0_dp .and. opt%newton_atol > 0.0_dp) .or. &
        opt%newton_max_iter < 1) return
    if (opt%formulation == MBDK_INDEX3_AUGMENTED .and. .not. (opt%alpha >= 0.0_dp)) return
    ! the Newton matrix has no tangent of contacts and friction, and the state no effects; a
    ! knife edge has no position row to solve for (its velocity row would be left unkept)
    if (model%has_contacts .or. model%has_pfaffian) then
      stat = MBDK_ERR_NOT_APPLICABLE
      return
    end if
    if (size(y0) /= 2 * nc) return
    if (.not. all(abs(y0) <= huge(1.0_dp)) .or. .not. abs(t0) <= huge(1.0_dp)) return
    if (opt%adaptive < 0 .or. opt%adaptive > MBDK_INDEX3_EXTRAPOLATED) return
    if (opt%adaptive /= 0 .and. opt%formulation == MBDK_INDEX3_BOOK) then
      stat = MBDK_ERR_NOT_APPLICABLE
      return
    end if
    s%opt = opt
    s%nc = nc
    s%m = m
    s%book = opt%formulation == MBDK_INDEX3_BOOK
    nk = nc
    if (s%book) nk = nc + m
    s%nk = nk
    call mbdk_constrained_init(s%cs, nc, m, model%m_positive, &
                               model%solver == MBDK_SOLVER_KKT, model%small_dense, model%sp, &
                               mbdk_model_sparse(model), stat, s%st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_index3_factors_init(s%fa, model, nk, stat, s%st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    allocate (s%q(nc), s%v(nc), s%a(nc), s%lam(m), s%lam_old(m), s%a_prev(nc), s%a_prev2(nc), &
              s%qn(nc), s%vn(nc), s%an(nc), s%ln(m), s%lst(m), s%lstn(m), s%lst_old(m), &
              s%qhat(nc), s%qp(nc), s%lp(m), s%lt(m), s%fq(nc), s%phi(m), s%gam(m), &
              s%phit(m), s%lw(m), s%rc(m), s%corr(nc), s%mu(m), s%r(nk), s%zero_nc(nc), &
              s%zero_m(m), s%one_nc(nc), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (14.0_dp * nc + 15.0_dp * m + nk), stat, &
                           s%st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    ! the dense D serves the book scheme's matrix only
    if (s%book) then
      allocate (s%d(m, nc), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * real(m, dp) * nc, stat, s%st%alloc_bytes)
    else
      allocate (s%d(0, 0), stat=astat)
      call mbdk_alloc_status(astat, 0.0_dp, stat, s%st%alloc_bytes)
    end if
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INVALID_INPUT
    s%zero_nc = 0.0_dp
    s%zero_m = 0.0_dp
    s%one_nc = 1.0_dp
    s%q = y0(1:nc)
    s%v = y0(nc + 1:)
    s%t = t0
    s%st%t_reached = t0
    ! consistent a and lambda at t0: the reduced formulation's solve; where D has lost a rank
    ! (redundant joints, or a start at a singular configuration) the augmented form takes the
    ! regular path of its projections instead (lambda is then one of many)
    call mbdk_model_accelerations(model, s%t, s%q, s%v, s%a, s%lam, stat)
    if (stat == MBDK_ERR_SINGULAR_MATRIX .and. .not. s%book) then
      s%qn = s%q
      s%vn = s%v
      s%tn = s%t
      call constraints_at(s, model)
      s%fq = 0.0_dp
      call mbdk_forces_eval(model%fint, model%freal, model%mass, model%work%rot, s%q, s%v, s%t, &
                            s%fq, model%work%visits(MBDK_JOINT_TYPES + 1:), stat)
      if (stat /= MBDK_SUCCESS) return
      call mbdk_constrained_factor(s%cs, model%sp, model%work%dz, model%col, model%blk, &
                                   model%mass, stat, regular=.true.)
      if (stat /= MBDK_SUCCESS) return
      call mbdk_constrained_solve(s%cs, model%sp, model%work%dz, model%blk, model%winv, s%fq, &
                                  s%gam, s%a, s%lam, stat)
    end if
    if (stat /= MBDK_SUCCESS) return
    s%regular = s%cs%regular
    s%lam_old = s%lam
    s%lst = s%lam
    s%lstn = s%lam
    s%lst_old = s%lam
    s%a_prev = s%a
    s%a_prev2 = s%a
    s%st%nfev = 1
    call mbdk_model_watch_start(model, s%t, s%q, s%v, stat, velocity=.not. s%book)
  end subroutine mbdk_index3_init

  !> Accepts the attempted step: (qn, vn, an, ln) at tn becomes the state.
  subroutine commit(s)
    type(mbdk_index3_t), intent(inout) :: s
    s%a_prev2 = s%a_prev
    s%h_prev2 = s%h_prev
    s%a_prev = s%a
    s%h_prev = s%h
    s%lam_old = s%lam
    s%lst_old = s%lst
    s%q = s%qn
    s%v = s%vn
    s%a = s%an
    s%lam = s%ln
    s%lst = s%lstn
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
  subroutine mbdk_index3_step(s, model, tn, stat)
    type(mbdk_index3_t), intent(inout) :: s
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(in) :: tn
    integer, intent(out) :: stat
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. (tn > s%t .and. tn - s%t <= huge(1.0_dp))) return
    s%tn = tn
    s%h = tn - s%t
    call attempt(s, model, stat)
    if (stat == MBDK_SUCCESS) then
      call commit(s)
      call watch_step(s, model, .false., stat)
    end if
  end subroutine mbdk_index3_step

  !> Fixed step: from s%t to t_s in one step of h = t_s - t or, when Newton fails (diverged,
  !> singular matrix, non-finite iterate) in the augmented form, in substeps: each failure
  !> quarters the substep (stats%newton_failures), each success doubles it back up to the
  !> full step. Below h / 4^MBDK_INDEX3_MAX_CUTS the failure is returned.
  subroutine mbdk_index3_advance(s, model, t_s, ierr, sample_at_end)
    type(mbdk_index3_t), intent(inout) :: s
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(in) :: t_s
    integer, intent(out) :: ierr
    !> the state at t_s will be sampled: the watch checks it (mbdk_model_watch)
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
      call attempt(s, model, ierr)
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
      call watch_step(s, model, sample .and. s%t == t_s, ierr)
      if (ierr /= MBDK_SUCCESS) return
      h_sub = min(2.0_dp * h_sub, h_full)
    end do
  end subroutine mbdk_index3_advance

  !> The model's watch after an accepted step: with the projected form's multipliers (exact at
  !> the state) for the drivers' power; the book scheme's are not accurate enough (they grow as
  !> h shrinks), so the watch solves for them.
  subroutine watch_step(s, model, force, stat)
    type(mbdk_index3_t), intent(in) :: s
    type(mbdk_model_t), intent(in) :: model
    logical, intent(in) :: force
    integer, intent(out) :: stat
    if (s%book) then
      call mbdk_model_watch(model, s%t, s%q, s%v, force, stat, solve_lam=.true.)
    else
      call mbdk_model_watch(model, s%t, s%q, s%v, force, stat, lam=s%lam)
    end if
  end subroutine watch_step

  logical function newton_failed(ierr)
    integer, intent(in) :: ierr
    newton_failed = ierr == MBDK_ERR_NEWTON_DIVERGED .or. ierr == MBDK_ERR_NONFINITE .or. &
      ierr == MBDK_ERR_SINGULAR_MATRIX
  end function newton_failed

  !> Integrates the scene from (q, v) = y0 over [t0, t_end]: with the fixed step opt%h, or, when
  !> opt%adaptive, with the step-size controller from the initial step opt%h and samples every
  !> opt%dt_out. Samples: t_out, y_out (= [q; v]), a_out, lam_out, iters_out (Newton iterations
  !> of the step that produced the sample). nwritten samples are valid; on failure the samples
  !> before it are kept, and the last one is the state the failed step started from.
  subroutine mbdk_index3_solve(model, opt, t0, t_end, y0, t_out, y_out, a_out, lam_out, &
                               iters_out, nwritten, st, stat)
    type(mbdk_model_t), intent(in) :: model
    type(mbdk_index3_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_end, y0(:)
    real(dp), intent(out) :: t_out(:), y_out(:, :), a_out(:, :), lam_out(:, :)
    integer, intent(out) :: iters_out(:), nwritten
    type(mbdk_stats_t), intent(out) :: st
    integer, intent(out) :: stat
    integer(i8) :: nsteps, i
    integer :: nsamp, plan_stat
    logical :: shortened, sample
    real(dp) :: t_s
    type(mbdk_timer_t) :: timer
    type(mbdk_index3_t) :: s

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
    call mbdk_index3_init(s, model, opt, t0, y0, stat)
    if (stat /= MBDK_SUCCESS) then
      st = s%st
      return
    end if
    call write_sample()
    if (opt%adaptive /= 0) then
      call adaptive_loop(stat)
    else
      do i = 1, nsteps
        t_s = t0 + real(i, dp) * opt%h
        if (i == nsteps) t_s = t_end
        if (opt%interrupt /= 0 .and. mbdk_interrupted(opt%interrupt)) then
          stat = MBDK_ERR_INTERRUPTED
          exit
        end if
        if (opt%progress /= 0) call mbdk_progress(opt%progress, t_s)
        sample = mod(i, int(opt%every, i8)) == 0 .or. i == nsteps
        call mbdk_index3_advance(s, model, t_s, stat, sample)
        if (stat /= MBDK_SUCCESS) exit
        if (sample) call write_sample()
      end do
      if (stat == MBDK_SUCCESS .and. shortened) stat = MBDK_NOTE_LAST_STEP_SHORTENED
    end if
    ! on failure the last sample is the state the failed step started from (where it stopped);
    ! a state the watch refused is not a sample (the last sample passed its checks; adaptive,
    ! extrapolated: the start of the refused macro step, written by adaptive_loop)
    if (mbdk_is_failure(stat) .and. nwritten < size(t_out) .and. &
        stat /= MBDK_ERR_CONSTRAINT_DRIFT .and. stat /= MBDK_ERR_ENERGY_DRIFT) then
      if (s%t > t_out(nwritten)) call write_sample()
    end if
    st = s%st
    call mbdk_timer_stop(timer, st)

  contains

    subroutine write_sample()
      call write_row(s%t, s%q, s%v, s%a, s%lam, s%iters)
    end subroutine write_sample

    !> A saved state as the next sample (its Newton iterations unknown: 0).
    subroutine write_state(x)
      type(mbdk_index3_snapshot_t), intent(in) :: x
      call write_row(x%t, x%q, x%v, x%a, x%lam, 0)
    end subroutine write_state

    subroutine write_row(t, q, v, a, lam, iters)
      real(dp), intent(in) :: t, q(:), v(:), a(:), lam(:)
      integer, intent(in) :: iters
      nwritten = nwritten + 1
      t_out(nwritten) = t
      y_out(1:s%nc, nwritten) = q
      y_out(s%nc + 1:2 * s%nc, nwritten) = v
      a_out(1:s%nc, nwritten) = a
      if (s%m > 0) lam_out(1:s%m, nwritten) = lam
      iters_out(nwritten) = iters
    end subroutine write_row

    !> The step-size controller (see the module header and mbdk_step_controller). Samples land
    !> on t0 + k dt_out.
    subroutine adaptive_loop(ierr)
      integer, intent(out) :: ierr
      integer :: k
      real(dp) :: err, h_ctl
      logical :: extrapolated
      type(mbdk_step_controller_t) :: ctl
      type(mbdk_index3_snapshot_t) :: x0
      extrapolated = opt%adaptive == MBDK_INDEX3_EXTRAPOLATED
      call mbdk_controller_init(ctl, opt%h, opt%h_min, opt%h_max, t0, t_end, 2)
      if (extrapolated) then
        ctl%ki = 0.7_dp
        ctl%kp = 0.4_dp
      end if
      if (extrapolated) then
        call snapshot_init(x0, s%nc, s%m, ierr, s%st%alloc_bytes)
        if (ierr /= MBDK_SUCCESS) return
      end if
      ierr = MBDK_SUCCESS
      do k = 1, nsamp - 1
        t_s = t0 + real(k, dp) * opt%dt_out
        if (k == nsamp - 1) t_s = t_end
        do while (s%t < t_s)
          if (opt%interrupt /= 0 .and. mbdk_interrupted(opt%interrupt)) then
            ierr = MBDK_ERR_INTERRUPTED
            return
          end if
          if (opt%progress /= 0) call mbdk_progress(opt%progress, s%t)
          s%tn = mbdk_controller_next_step(ctl, s%t, t_s)
          s%h = s%tn - s%t
          ! the controller judges the step from t to tn (extrapolated: the macro step, whose
          ! half-steps leave their own h in s%h for the predictors' history)
          h_ctl = s%h
          if (extrapolated) then
            call extrapolated_attempt(s, model, x0, err, ierr)
          else
            call hold_matrix(s)
            call attempt(s, model, ierr)
            if (ierr == MBDK_SUCCESS) err = error_estimate(s)
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
              call watch_step(s, model, extrapolated .or. s%t >= t_s, ierr)
              if (ierr /= MBDK_SUCCESS) then
                if (extrapolated .and. nwritten < size(t_out) .and. x0%t > t_out(nwritten)) &
                  call write_state(x0)
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
        call write_sample()
      end do
    end subroutine adaptive_loop

  end subroutine mbdk_index3_solve

  subroutine snapshot_init(x, nc, m, stat, asked)
    type(mbdk_index3_snapshot_t), intent(out) :: x
    integer, intent(in) :: nc, m
    integer, intent(out) :: stat
    real(dp), intent(inout) :: asked
    integer :: astat
    allocate (x%q(nc), x%v(nc), x%a(nc), x%lam(m), x%lst(m), x%lam_old(m), x%lst_old(m), &
              x%a_prev(nc), x%a_prev2(nc), x%qf(nc), x%vf(nc), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (7.0_dp * nc + 4.0_dp * m), stat, asked)
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
    end if
  end subroutine snapshot

  !> adaptive = MBDK_INDEX3_EXTRAPOLATED: the macro step from s%t to s%tn = s%t + H by local
  !> Richardson extrapolation (module header). On success (qn, vn, an, ln) at tn hold the
  !> extrapolated, projected state, to be committed as one step (the first half-step is
  !> committed already, so that the history the predictors use is the half-step grid), and err
  !> is the error norm of the half-step solution. When the step is rejected (err > 1) or a solve
  !> fails, the state is restored to s%t.
  subroutine extrapolated_attempt(s, model, x, err, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    type(mbdk_model_t), intent(in) :: model
    type(mbdk_index3_snapshot_t), intent(inout) :: x
    real(dp), intent(out) :: err
    integer, intent(out) :: ierr
    real(dp) :: t_end, wq, wv, sum2
    integer :: k, nc, iters
    logical :: near
    nc = s%nc
    err = huge(1.0_dp)
    t_end = s%tn
    call snapshot(s, x, .true.)
    ! the full step. Each change between H and H/2 rebuilds the Newton matrix; a second matrix
    ! kept for the other size would not be reused either: at the steps this control takes,
    ! h |omega| is above the 1e-3 where a matrix from the step before fails (module header)
    s%h = t_end - s%t
    call hold_matrix(s)
    call attempt(s, model, ierr)
    if (ierr /= MBDK_SUCCESS) return
    x%qf = s%qn
    x%vf = s%vn
    iters = s%iters
    near = s%stalled
    ! two half-steps
    s%tn = s%t + 0.5_dp * (t_end - s%t)
    s%h = s%tn - s%t
    call hold_matrix(s)
    call attempt(s, model, ierr)
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
    call attempt(s, model, ierr)
    if (ierr /= MBDK_SUCCESS) then
      call snapshot(s, x, .false.)
      return
    end if
    s%iters = iters + s%iters
    ! the half-steps' error is (y_half - y_full) / 3 (local error C h^3: C H^3 / 4 against
    ! C H^3), measured as error_estimate's, on q and v
    sum2 = 0.0_dp
    do k = 1, nc
      wq = s%opt%err_atol + s%opt%err_rtol * max(abs(x%q(k)), abs(s%qn(k)))
      wv = s%opt%err_atol + s%opt%err_rtol * max(abs(x%v(k)), abs(s%vn(k)))
      sum2 = sum2 + ((s%qn(k) - x%qf(k)) / (3.0_dp * wq))**2 + &
        ((s%vn(k) - x%vf(k)) / (3.0_dp * wv))**2
    end do
    err = sqrt(sum2 / real(2 * nc, dp))
    if (err > 1.0_dp .and. err <= NEAR_FLOOR .and. (near .or. s%stalled)) then
      ! next to a rank loss of D (a solve froze its multipliers) the three solutions differ by
      ! the |Phi| up to FROZEN_PHI tolerances that frozen Newton steps leave along the
      ! vanishing direction, whatever H: there the difference is no estimate of the truncation
      ! error, up to NEAR_FLOOR (beyond it the solutions disagree by more than such a floor:
      ! the step is rejected as any other). The half-steps stand, unextrapolated, judged by
      ! the estimate from differences (error_estimate) of the second, scaled by 2^3 to a step
      ! of H (the controller's step): what the estimated mode would ask of a step of H, for a
      ! solution whose error is a quarter of that step's.
      err = 8.0_dp * error_estimate(s)
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
    s%qn = s%qn + (s%qn - x%qf) / 3.0_dp
    s%vn = s%vn + (s%vn - x%vf) / 3.0_dp
    call consistent_end(s, model, ierr)
    if (ierr /= MBDK_SUCCESS) call snapshot(s, x, .false.)
  end subroutine extrapolated_attempt

  !> Keeps the current matrix for a step s%h within KEEP_MATRIX of the one it was built for
  !> (modified Newton absorbs the difference).
  subroutine hold_matrix(s)
    type(mbdk_index3_t), intent(inout) :: s
    if (s%have_lu .and. abs(s%h - s%h_lu) <= KEEP_MATRIX * s%h_lu) s%h_lu = s%h
  end subroutine hold_matrix

  !> (qn, vn) onto Phi = 0 (Gauss-Newton, as the projection formulation's) and D v + Phi_t = 0,
  !> both mass-orthogonal, then an, ln from M a + D^T lambda = f, D a = gamma there: the solves
  !> of a step's end (attempt), on its regular path where D is (nearly) rank-deficient.
  subroutine consistent_end(s, model, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    type(mbdk_model_t), intent(in) :: model
    integer, intent(out) :: ierr
    integer :: it
    real(dp) :: phi_tol
    phi_tol = max(s%opt%newton_atol, 64.0_dp * epsilon(1.0_dp) * max(1.0_dp, maxval(abs(s%qn))))
    do it = 0, PROJECT_MAX_ITER
      call constraints_at(s, model)
      call mbdk_constrained_factor(s%cs, model%sp, model%work%dz, model%col, model%blk, &
                                   model%mass, ierr, regular=.true., near=NEAR_PIVOT)
      if (ierr /= MBDK_SUCCESS) return
      if (s%m == 0) exit
      if (maxval(abs(s%phi)) <= phi_tol) exit
      ! at a rank loss the part of Phi that D cannot reach stays, as in a frozen Newton step
      if (s%cs%regular .and. it > 0 .and. maxval(abs(s%phi)) <= FROZEN_PHI * phi_tol) exit
      if (it == PROJECT_MAX_ITER) then
        ierr = MBDK_ERR_NEWTON_DIVERGED
        return
      end if
      call mbdk_constrained_solve(s%cs, model%sp, model%work%dz, model%blk, model%winv, &
                                  s%zero_nc, s%phi, s%corr, s%mu, ierr)
      if (ierr /= MBDK_SUCCESS) return
      s%qn = s%qn - s%corr
    end do
    s%regular_n = s%cs%regular
    if (s%m > 0) then
      call mbdk_sparse_d_times(model%sp, model%work%dz, s%vn, s%rc, .false.)
      s%rc = s%rc + s%phit
      call mbdk_constrained_solve(s%cs, model%sp, model%work%dz, model%blk, model%winv, &
                                  s%zero_nc, s%rc, s%corr, s%mu, ierr)
      if (ierr /= MBDK_SUCCESS) return
      s%vn = s%vn - s%corr
      call mbdk_joints_eval(model%jint, model%jreal, model%row0, model%work%rot, s%qn, s%vn, &
                            s%tn, s%phi, model%work%dz, s%gam, s%phit, &
                            model%work%visits(1:MBDK_JOINT_TYPES))
    end if
    s%fq = 0.0_dp
    call mbdk_forces_eval(model%fint, model%freal, model%mass, model%work%rot, s%qn, s%vn, &
                          s%tn, s%fq, model%work%visits(MBDK_JOINT_TYPES + 1:), ierr)
    if (ierr /= MBDK_SUCCESS) return
    s%st%nfev = s%st%nfev + 1
    call mbdk_constrained_solve(s%cs, model%sp, model%work%dz, model%blk, model%winv, s%fq, &
                                s%gam, s%an, s%ln, ierr)
    if (ierr /= MBDK_SUCCESS) return
    if (.not. (finite_all(s%qn) .and. finite_all(s%vn) .and. finite_all(s%an))) &
      ierr = MBDK_ERR_NONFINITE
  end subroutine consistent_end

  !> Weighted RMS over q and v (multipliers excluded) of the local errors of the trapezoidal
  !> rule, -h^3/12 q(3) and -h^3/12 q(4). The derivatives are divided differences of the step
  !> mean accelerations (a_k + a_k+1)/2, placed at the step midpoints: the mean cancels the
  !> period-2 oscillation of the book scheme's accelerations, which would otherwise dominate.
  !> The first two steps have no q(4) from history: it is taken as q(3) / (h + h_prev)
  !> (large, so those steps are judged conservatively).
  real(dp) function error_estimate(s)
    type(mbdk_index3_t), intent(in) :: s
    real(dp) :: eq, ev, wq, wv, d1, d0, sum2, b2, b1, b0, h
    integer :: k
    h = s%h
    sum2 = 0.0_dp
    do k = 1, s%nc
      b2 = 0.5_dp * (s%a(k) + s%an(k))
      if (s%h_prev > 0.0_dp) then
        b1 = 0.5_dp * (s%a_prev(k) + s%a(k))
        d1 = (b2 - b1) / (0.5_dp * (h + s%h_prev))                   ! q(3)
      else
        b1 = 0.0_dp                     ! (unused: no h_prev2 without h_prev)
        d1 = (s%an(k) - s%a(k)) / h
      end if
      eq = h**3 / 12.0_dp * d1
      if (s%h_prev2 > 0.0_dp) then
        b0 = 0.5_dp * (s%a_prev2(k) + s%a_prev(k))
        d0 = (b1 - b0) / (0.5_dp * (s%h_prev + s%h_prev2))
        ev = h**3 / 12.0_dp * (d1 - d0) / (0.5_dp * h + s%h_prev + 0.5_dp * s%h_prev2) * 2.0_dp
      else
        ev = h**3 / 12.0_dp * d1 / (h + s%h_prev)
      end if
      wq = s%opt%err_atol + s%opt%err_rtol * max(abs(s%q(k)), abs(s%qn(k)))
      wv = s%opt%err_atol + s%opt%err_rtol * max(abs(s%v(k)), abs(s%vn(k)))
      sum2 = sum2 + (eq / wq)**2 + (ev / wv)**2
    end do
    error_estimate = sqrt(sum2 / real(2 * s%nc, dp))
  end function error_estimate

  logical function finite_all(x)
    real(dp), intent(in) :: x(:)
    finite_all = all(abs(x) <= huge(1.0_dp))
  end function finite_all

  !> One step from (t, q, v, a, lam) to tn = t + h into (qn, vn, an, ln), not committed.
  !> Newton as in the module header; both formulations share this loop.
  subroutine attempt(s, model, ierr)
    type(mbdk_index3_t), intent(inout) :: s
    type(mbdk_model_t), intent(in) :: model
    integer, intent(out) :: ierr
    real(dp) :: sh, dnorm, dnorm_old, rate, h, phi_tol, phin, alpha_upd, prog, prog_old, alpha0
    logical :: fresh, restarted, book, reused, frozen, upd_fresh, boosted
    integer :: k, kk, nc, m, stalls

    nc = s%nc
    m = s%m
    h = s%h
    book = s%book
    sh = 0.25_dp * h * h
    alpha0 = s%opt%alpha
    if (alpha0 == 0.0_dp) alpha0 = MBDK_INDEX3_KAPPA * maxval(model%mass) / sh
    s%alpha = alpha0
    s%qhat = s%q + h * s%v + sh * s%a
    if (book .or. s%h_prev <= 0.0_dp) then
      s%qp = s%q + h * s%v + 0.5_dp * h * h * s%a
      s%lp = s%lst
    else
      ! the trapezoidal rule itself with a+ and lam* extrapolated linearly: O(h^4) in q
      s%qp = s%qhat + sh * (s%a + (h / s%h_prev) * (s%a - s%a_prev))
      s%lp = s%lst + (h / s%h_prev) * (s%lst - s%lst_old)
      ! where the accepted state's projection found D (nearly) rank-deficient, lam* is (nearly)
      ! not unique: its updates add the part of Phi that D cannot remove, which carried from
      ! step to step grows without bound. There the projection's multipliers (bounded) start it.
      if (s%regular) s%lp = s%lam + (h / s%h_prev) * (s%lam - s%lam_old)
    end if
    if (book) s%lp = s%lam
    if (book .and. s%h_prev > 0.0_dp) s%lp = s%lam + (h / s%h_prev) * (s%lam - s%lam_old)  ! (3.11)
    if (s%have_lu .and. (abs(h - s%h_lu) > 1.0e-12_dp * h .or. s%cool > 0 .or. &
                         s%lu_boosted)) s%have_lu = .false.
    reused = s%have_lu
    s%qn = s%qp
    s%ln = s%lp
    restarted = .false.
    fresh = .false.
    dnorm_old = huge(1.0_dp)
    s%iters = 0
    k = 0
    s%phi = 0.0_dp
    frozen = .false.
    boosted = .false.
    stalls = 0
    upd_fresh = .false.
    prog_old = huge(1.0_dp)
    do
      s%vn = (2.0_dp / h) * (s%qn - s%q) - s%v
      ! (leaves work%rot and work%dz at qn, for the forces and the matrix)
      call constraints_at(s, model)
      s%fq = 0.0_dp
      call mbdk_forces_eval(model%fint, model%freal, model%mass, model%work%rot, s%qn, s%vn, &
                            s%tn, s%fq, model%work%visits(MBDK_JOINT_TYPES + 1:), ierr)
      if (ierr /= MBDK_SUCCESS) return
      s%st%nfev = s%st%nfev + 1
      s%lt = s%ln
      phin = 0.0_dp
      if (m > 0) phin = maxval(abs(s%phi))
      ! max |Phi| accepted: atol, but not below the roundoff of the coordinates
      phi_tol = max(s%opt%newton_atol, 64.0_dp * epsilon(1.0_dp) * max(1.0_dp, maxval(abs(s%qn))))
      ! a stall (measured below, after the solve) stiffens the penalty, then freezes lam*. The
      ! multiplier update takes the alpha that produced this Phi: with the new one it would
      ! overshoot BOOST-fold and leave Phi where it was.
      alpha_upd = s%alpha
      if (stalls > 0 .and. .not. frozen) then
        stalls = 0
        if (.not. boosted) then
          boosted = .true.
          s%alpha = s%alpha * BOOST
          s%have_lu = .false.
          upd_fresh = .false.
        else
          ! freeze only what a frozen step may accept: a larger Phi stalls for another reason
          ! (a stiff force's nonlinearity) and the multipliers go on
          frozen = phin <= FROZEN_PHI * phi_tol
          ! the noise test of a frozen step compares frozen updates only
          if (frozen) dnorm_old = huge(1.0_dp)
        end if
      end if
      if (.not. book) then
        if (k > 0 .and. .not. frozen) s%ln = s%ln + alpha_upd * s%phi
        s%lt = s%ln + s%alpha * s%phi
      end if
      ! corr = f - D^T lt over the nonzeros of D
      call mbdk_sparse_w_residual(model%sp, model%work%dz, s%one_nc, s%lt, s%corr, nc, s%fq)
      do kk = 1, nc
        s%r(kk) = model%mass(kk) * (s%qn(kk) - s%qhat(kk)) - sh * s%corr(kk)
      end do
      if (book) s%r(nc + 1:) = s%phi
      if (.not. s%have_lu) then
        call mbdk_index3_factor(s%fa, model, book, s%tn, s%qn, s%vn, s%ln, h, s%alpha, s%d, &
                                s%lw, ierr)
        s%st%nlu = s%st%nlu + 1
        s%st%njev = s%st%njev + 1
        if (ierr /= MBDK_SUCCESS) return
        s%have_lu = .true.
        s%h_lu = h
        s%lu_boosted = boosted
        fresh = .true.
        reused = .false.
      end if
      s%r = -s%r
      call mbdk_index3_factors_solve(s%fa, s%r, ierr)
      if (ierr /= MBDK_SUCCESS) return
      if (.not. finite_all(s%r)) then
        ierr = MBDK_ERR_NONFINITE
        return
      end if
      s%iters = s%iters + 1
      k = k + 1
      s%st%newton_iterations = s%st%newton_iterations + 1
      dnorm = maxval(abs(s%r(1:nc)) / (s%opt%newton_atol + s%opt%newton_rtol * abs(s%qn)))
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
      ! it); f keeps this evaluation, the step's end evaluates D at the final q+.
      if (converged()) then
        s%qn = s%qn + s%r(1:nc)
        if (book) s%ln = s%ln + s%r(nc + 1:) / sh
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
          s%qn = s%qp
          s%ln = s%lp
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
      s%qn = s%qn + s%r(1:nc)
      if (book) s%ln = s%ln + s%r(nc + 1:) / sh
      ! rebuild the matrix when two more iterations at this rate would not reach the
      ! tolerance (an iteration costs about as much as a factorisation)
      if (rate > REBUILD_RATE .or. dnorm * rate * rate > 1.0_dp) s%have_lu = .false.
      upd_fresh = fresh
      fresh = .false.
      dnorm_old = dnorm
    end do
    ! a matrix carried over from an earlier step served the whole step: reuse pays again
    if (reused) s%cool_len = COOL_START
    s%stalled = frozen
    if (book) then
      s%vn = (2.0_dp / h) * (s%qn - s%q) - s%v
      s%an = (4.0_dp / (h * h)) * (s%qn - s%q) - (4.0_dp / h) * s%v - s%a
    else
      s%lstn = s%ln
      s%vn = (2.0_dp / h) * (s%qn - s%q) - s%v
      call constraints_at(s, model)
      ! at a rank loss of D (a singular crossing, redundant joints) the projections take the
      ! regular augmented Lagrangian path of mbdk_constrained instead of failing
      call mbdk_constrained_factor(s%cs, model%sp, model%work%dz, model%col, model%blk, &
                                   model%mass, ierr, regular=.true., near=NEAR_PIVOT)
      if (ierr /= MBDK_SUCCESS) return
      s%regular_n = s%cs%regular
      ! v+ = P (v + (h/2)(a + a~)), P the projection onto D v + Phi_t = 0 and a~ any
      ! solution of M a~ = f - D^T (anything): P removes M^-1 D^T terms, so this is P v+ of
      ! the trapezoidal rule (a+ differs from a~ by such a term once Newton has converged),
      ! without the Newton error that v+ = (2/h)(q+ - q) - v would carry amplified by 2/h.
      ! Then a+ and lambda+ from M a + D^T lambda = f, D a = gamma(q+, v+): the projection
      ! of a+ onto the acceleration constraints, with its multipliers, free of the Newton
      ! error (4/h^2) that a+ = (4/h^2)(q+ - q) - .. would carry.
      call mbdk_constrained_solve(s%cs, model%sp, model%work%dz, model%blk, model%winv, s%fq, &
                                  s%zero_m, s%an, s%ln, ierr)
      if (ierr /= MBDK_SUCCESS) return
      s%vn = s%v + (0.5_dp * h) * (s%a + s%an)
      ! vn onto D v + Phi_t = 0 (mass-orthogonal)
      call mbdk_sparse_d_times(model%sp, model%work%dz, s%vn, s%rc, .false.)
      s%rc = s%rc + s%phit
      call mbdk_constrained_solve(s%cs, model%sp, model%work%dz, model%blk, model%winv, &
                                  s%zero_nc, s%rc, s%corr, s%mu, ierr)
      if (ierr /= MBDK_SUCCESS) return
      s%vn = s%vn - s%corr
      ! q+ is unchanged: work%rot still holds its sin/cos and D, Phi are the same; only gamma
      ! changes with v+
      if (m > 0) call mbdk_joints_eval(model%jint, model%jreal, model%row0, model%work%rot, &
                                       s%qn, s%vn, s%tn, s%phi, model%work%dz, s%gam, s%phit, &
                                       model%work%visits(1:MBDK_JOINT_TYPES))
      call mbdk_constrained_solve(s%cs, model%sp, model%work%dz, model%blk, model%winv, s%fq, &
                                  s%gam, s%an, s%ln, ierr)
      if (ierr /= MBDK_SUCCESS) return
    end if
    if (.not. (finite_all(s%qn) .and. finite_all(s%vn) .and. finite_all(s%an))) &
      ierr = MBDK_ERR_NONFINITE

  contains

    logical function converged()
      converged = .false.
      if (k < 2) return
      if (frozen .and. phin <= FROZEN_PHI * phi_tol) then
        converged = dnorm <= 1.0_dp .or. (dnorm <= NOISE .and. dnorm > 0.5_dp * dnorm_old)
      else if (m == 0 .or. phin <= phi_tol) then
        converged = dnorm <= 1.0_dp
      end if
    end function converged

  end subroutine attempt

  !> Rotations and constraints at (tn, qn, vn): model%work%rot, phi, D's compact rows
  !> model%work%dz, gam, phit (the dense d only where it is needed: scattered by the caller).
  subroutine constraints_at(s, model)
    type(mbdk_index3_t), intent(inout) :: s
    type(mbdk_model_t), intent(in) :: model
    call mbdk_body_rotations(s%qn, model%work%rot)
    if (s%m > 0) call mbdk_joints_eval(model%jint, model%jreal, model%row0, model%work%rot, &
                                       s%qn, s%vn, s%tn, s%phi, model%work%dz, s%gam, s%phit, &
                                       model%work%visits(1:MBDK_JOINT_TYPES))
  end subroutine constraints_at

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
