!> bdf: Gear's backward differentiation formulas with variable step and variable order 1-5 and
!> error control, in the quasi-constant step-size form (Byrne and Hindmarsh 1975; Shampine and
!> Reichelt, The MATLAB ODE suite, 1997, with their NDF coefficients kappa set to 0: the
!> classical BDF of Gear and of MSC Adams' GSTIFF).
!>
!> History. The method keeps the backward differences of the solution on an equally spaced grid
!> of the current step h: D_0 = y_n, D_j = nabla^j y_n (j = 1 .. q+2), in the columns of d.
!> When h changes by a factor r, the differences are re-interpolated onto the new grid
!> (D <- (R(r) U)^T D, the matrices of Shampine and Reichelt's paper): the interpolating
!> polynomial is unchanged, so the formula keeps its fixed-step coefficients. This is the same
!> strategy as a Nordsieck array rescaled on a step change (CVODE, LSODE), in differences.
!>
!> A step of order q from t_n to t_n + h:
!>   predictor   y_p = sum_{j=0..q} D_j
!>   corrector   the BDF formula in the form  y = y_p + d,  (h / a_q) F(t_{n+1}, y) - psi - d = 0,
!>               a_q = gamma_q = sum_{j=1..q} 1/j,  psi = sum_{j=1..q} gamma_j D_j / a_q,
!>               solved by simplified Newton with M = I - (h / a_q) J (LAPACK LU)
!>   error       e = d / (q + 1): the local error constant of BDF-q times nabla^(q+1) y_{n+1}
!> The step is accepted when WRMS(e) <= 1 (weights 1/(atol + rtol |y_{n+1}|), mbdk_adaptive),
!> else h shrinks by max(0.2, safety WRMS(e)^(-1/(q+1))). After q + 1 steps of one h, the
!> orders q - 1, q and q + 1 are compared by their error estimates (nabla^q, nabla^(q+1) and
!> nabla^(q+2) of the same history) and the one that allows the largest step is taken, h grown
!> by at most 10. safety = 0.9 (2 m + 1)/(2 m + iterations), m = NEWTON_MAX_ITER: a step that
!> needed many Newton iterations is followed by a smaller one.
!>
!> Newton. At most NEWTON_MAX_ITER = 4 iterations; convergence is judged by the contraction rate
!> rho of successive updates, remembered across steps as CVODE does (crate = max(0.3 crate, rho),
!> 1 after each factorisation): converged when |dy| min(1, crate) < tol, so a step whose first
!> update is already small costs one evaluation of F; abandoned when rho >= 1 or the rate cannot
!> reach tol in the iterations left. tol = 0.1 (q + 1): a tenth of the correction the error
!> test accepts (CVODE's choice; the norm is the error test's).
!> The Jacobian is reused across steps and orders: it is evaluated again only when an iteration
!> with an old one fails (analytic from the problem's jac, or forward differences, mbdk_newton's
!> mbdk_jacobian; opt%fd_jacobian forces differences). M is factorised again when h/a_q has
!> moved more than 30 % from the value it was built with (CVODE's rule: a change of order or
!> step that keeps c within that band keeps the matrix), and after a Newton failure. A Newton
!> failure with a fresh Jacobian halves h (stats: newton_failures), and the shorter step
!> evaluates J again at its own predictor before its first iteration (CVODE's rule after a
!> convergence failure, CV_FAIL_OTHER): a Jacobian taken where the longer step began to fail
!> can be far from the one at the new predictor, as next to a singular pose, where it moves
!> fast enough that no shorter step converges with the old one. Below mbdk_adaptive_h_floor:
!> MBDK_ERR_STEP_TOO_SMALL, or MBDK_ERR_NONFINITE where the last failure met F not finite (and at
!> once where F is not finite at the initial state): no step is small enough for a singularity.
!>
!> Start: order 1 (implicit Euler) with the first step of mbdk_adaptive_initial_step, D_1 = h F.
!> Dense output: the interpolating polynomial of the history, degree q:
!>   y(t) = D_0 + sum_{j=1..q} D_j prod_{m=0..j-1} (t - (t_n - m h)) / ((m + 1) h).
!> A watching problem that integrates a work gets it at the accepted step's three Gauss nodes
!> (watch_nodes, mbdk_problem) before its watch. opt%max_order (1..5; 0 = 5) caps the order.
!> Statistics: steps at each order (order1_steps .. order5_steps), rejected steps, Newton
!> failures and iterations, nfev, njev, nlu.
!> A projection (has_post_step) after a step enters the history as part of the correction d.
!>
!> DAE. Given mass (the diagonal of E), yp0 and ntest, bdf integrates E y' = F(t, y), a scene's
!> equations of motion themselves (mbdk_scene_dae: the index-3 form as MSC Adams' GSTIFF I3,
!> or the stabilised index-2 form as its SI2). The corrector becomes c F - E (psi + d) = 0 with
!> the matrix E - c J; the algebraic rows (E_ii = 0) are divided by c and the algebraic
!> unknowns scaled by c, so that no entry grows like 1/c as h shrinks (the index scaling of
!> GSTIFF I3). The error test and Newton's norm see the first ntest components, then nindex2
!> components weighted by h (the index-3 form's velocities: index-2 variables, whose
!> correction after a step change carries O(1/h) from the constraints), and not the rest (the
!> multipliers: algebraic, their local error an order or two lower), and Newton stops at
!> a thousandth of the error test (not a tenth) judged by this step's own contraction rate: the
!> constraints hold only as far as Newton converged, and a leftover returns in the next
!> predictor as a correction that no smaller step removes, so that the error test would reject
!> every smaller step after a rejection. The first step comes from yp0 (1 % of |y|/|y'|, or
!> opt%h); the Jacobian is by differences (N + 1 evaluations of F), or the problem's own
!> (has_newton_matrix, mbdk_problem: a large mechanism's DAE forms E - c J sparse by colored
!> differences and factorises it by a sparse L D U, mbdk_mechanism_dae; stats: nlu_sparse). That
!> factorisation does not pivot: a zero pivot there is a failed iteration (h halves), and the
!> cause (MBDK_ERR_SINGULAR_MATRIX) if the steps shrink to the floor.
!> Roundoff floor. A corrector that stalls or runs out of iterations is tested against the
!> floor of its update (mbdk_newton_floor, with the current matrix, in the error test's
!> norm): an ODE's iterate at that floor is accepted (it is as good as double precision makes
!> it); a DAE's is not (its Newton tolerance is a thousandth of the error test's, and its
!> matrix worsens as h shrinks), and if the steps then shrink below mbdk_adaptive_h_floor the
!> solve ends with MBDK_ERR_TOO_MUCH_ACCURACY instead of MBDK_ERR_STEP_TOO_SMALL, as it does
!> where the roundoff of the error estimate is a tenth of the error test or more
!> (ERROR_FLOOR_SHARE): the tolerances lie below what the formulation reaches in double
!> precision (bdf i3 at rtol 1e-13, atol 1e-15 on the built-in mechanisms).
module mbdk_variable_bdf
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t, MBDK_GAUSS3
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_interrupt, only: mbdk_interrupted, mbdk_progress
  use mbdk_lapack, only: mbdk_lu_factor, mbdk_lu_solve
  use mbdk_newton, only: mbdk_newton_work_t, mbdk_newton_work_init, mbdk_jacobian
  use mbdk_newton_floor, only: mbdk_floor_solve, mbdk_floor_probes, mbdk_floor_from_probes, &
    mbdk_floor_cap, MBDK_FLOOR_FACTOR
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_adaptive, only: mbdk_adaptive_weights, mbdk_adaptive_wrms, mbdk_adaptive_after_step, &
    mbdk_adaptive_step_limit, mbdk_adaptive_initial_step, mbdk_adaptive_h_floor, &
    mbdk_adaptive_count_order
  implicit none
  private
  public :: mbdk_variable_bdf_solve

  integer, parameter, public :: MBDK_BDF_MAX_ORDER = 5
  integer, parameter :: NEWTON_MAX_ITER = 4
  real(dp), parameter :: FAC_MIN = 0.2_dp, FAC_MAX = 10.0_dp
  !> M = I - c J is factorised again when c moved by more than this fraction
  real(dp), parameter :: C_CHANGE = 0.3_dp
  !> the remembered contraction rate decays by this factor per iteration (CVODE's CRDOWN)
  real(dp), parameter :: CRATE_DOWN = 0.3_dp
  !> Newton stops when its remaining error is this fraction of what the error test accepts
  !> (CVODE's nlscoef)
  real(dp), parameter :: NEWTON_SHARE = 0.1_dp
  !> a DAE's: its constraints hold only as far as Newton converged, and what is left over is in
  !> the next step's predictor, a correction that does not shrink with h (the module header)
  real(dp), parameter :: NEWTON_SHARE_DAE = 1.0e-3_dp
  !> a step size gone to nothing is named MBDK_ERR_TOO_MUCH_ACCURACY where the error estimate's
  !> roundoff is this share of the error test or more
  real(dp), parameter :: ERROR_FLOOR_SHARE = 0.1_dp
  !> a DAE step whose corrector stalled at its roundoff floor this often, each time retried at
  !> half the step, ends the solve by name (a smaller step's matrix is worse conditioned)
  integer, parameter :: MAX_FLOOR_STALLS = 6

  !> One solve's state: the history, the step and order, Newton's matrix and contraction rate,
  !> and the vectors of the step being tried (the module header says what each is).
  type :: bdf_t
    integer :: n = 0, q = 1, qmax = MBDK_BDF_MAX_ORDER
    !> steps taken since h last changed; Newton iterations of the last corrector
    integer :: n_equal = 0, iters = 0
    !> the error test's components: the nt leading ones, then n2 index-2 ones weighted by h
    integer :: nt = 0, n2 = 0
    !> how often a corrector of this step stalled at its roundoff floor (a DAE's)
    integer :: floor_stalls = 0
    integer(i8) :: tries = 0, limit = 0
    !> dae: E y' = F(t, y) with E = diag(em) (the module header's section "DAE")
    logical :: dae = .false.
    !> the problem forms and factorises M itself (has_newton_matrix: a large mechanism's DAE,
    !> sparse); else J and M are dense here. singular: its last factorisation met a zero pivot
    logical :: own_matrix = .false., singular = .false.
    !> the next attempt evaluates J at its predictor first (a Newton failure with a fresh J)
    logical :: refresh_jac = .false.
    logical :: have_lu = .false., jac_current = .false., converged = .false.
    !> the last corrector met F not finite; a corrector of this step stalled at its floor
    logical :: nonfinite = .false., at_floor = .false.
    !> t_new: the end of the step being tried; c = h / a_q, c_lu: the c that M was built with;
    !> tol: Newton's; err: the accepted step's error estimate; safety: its step-size factor
    real(dp) :: t = 0.0_dp, t_new = 0.0_dp, t_end = 0.0_dp, h = 0.0_dp, hmax = 0.0_dp
    !> the solve's start (a stop before any accepted step is not named by the pose)
    real(dp) :: t0 = 0.0_dp
    real(dp) :: c = 0.0_dp, c_lu = 0.0_dp, tol = 0.0_dp, err = 0.0_dp, safety = 0.0_dp
    real(dp) :: crate = 1.0_dp
    !> gam(j) = gamma_j = sum_{i=1..j} 1/i; errc(j) = 1/(j + 1), BDF-j's error constant
    real(dp) :: gam(0:MBDK_BDF_MAX_ORDER), errc(0:MBDK_BDF_MAX_ORDER + 1)
    !> d(:, j) = D_j; yp the predictor, ynew the iterate, corr = ynew - yp; w the weights
    real(dp), allocatable :: d(:, :), yp(:), psi(:), ynew(:), corr(:), w(:), f(:), dy(:)
    real(dp), allocatable :: em(:)
    logical, allocatable :: alg(:)
    type(mbdk_newton_work_t) :: nw
  end type bdf_t

contains

  !> See the module header; called by mbdk_solve_ode, which has checked the options, written
  !> sample 1 (nwritten = 1) and the sample times t_out.
  !> A DAE E y' = F(t, y) with E = diag(mass) (mbdk_scene_dae): mass, yp0 (a consistent y'(0))
  !> and ntest (the leading components the error test sees) are given together; the module
  !> header's section "DAE" says what changes.
  subroutine mbdk_variable_bdf_solve(prob, opt, t0, y0, atol, t_out, y_out, nwritten, st, stat, &
                                     mass, yp0, ntest, nindex2)
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, y0(:), atol(:), t_out(:)
    real(dp), intent(inout) :: y_out(:, :)
    integer, intent(inout) :: nwritten
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: mass(:), yp0(:)
    integer, intent(in), optional :: ntest, nindex2
    type(bdf_t) :: b
    integer :: k

    b%own_matrix = prob%has_newton_matrix
    call bdf_init(b, opt, t0, y0, t_out(size(t_out)), st, stat, mass, yp0, ntest, nindex2)
    if (stat /= MBDK_SUCCESS) return
    call bdf_start(b, prob, opt, atol, y0, st, stat, yp0)
    if (stat /= MBDK_SUCCESS) return
    k = nwritten + 1
    do while (b%t < b%t_end)
      if (opt%interrupt /= 0 .and. mbdk_interrupted(opt%interrupt)) then
        stat = MBDK_ERR_INTERRUPTED
        return
      end if
      if (opt%progress /= 0) call mbdk_progress(opt%progress, b%t)
      call aim_step(b)
      call take_step(b, prob, opt, atol, st, stat)
      if (stat /= MBDK_SUCCESS) return
      call accept_step(b, prob, t_out, k, st, stat)
      if (stat /= MBDK_SUCCESS) return
      if (b%n_equal >= b%q + 1 .and. b%t < b%t_end) call choose_order(b)
      call write_samples(b, t_out, y_out, k, nwritten)
    end do
    stat = MBDK_SUCCESS
  end subroutine mbdk_variable_bdf_solve

  !> The solve's storage, its formula's coefficients, the DAE's arguments checked, and the
  !> history at t0 (D_0 = y0; D_1 comes with the first step, bdf_start).
  subroutine bdf_init(b, opt, t0, y0, t_end, st, stat, mass, yp0, ntest, nindex2)
    type(bdf_t), intent(inout) :: b
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, y0(:), t_end
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: mass(:), yp0(:)
    integer, intent(in), optional :: ntest, nindex2
    integer :: n, j, astat

    n = size(y0)
    b%n = n
    b%t_end = t_end
    b%qmax = MBDK_BDF_MAX_ORDER
    stat = MBDK_ERR_INVALID_INPUT
    if (opt%max_order > MBDK_BDF_MAX_ORDER) return
    if (opt%max_order > 0) b%qmax = opt%max_order

    b%gam(0) = 0.0_dp
    do j = 1, MBDK_BDF_MAX_ORDER
      b%gam(j) = b%gam(j - 1) + 1.0_dp / real(j, dp)
    end do
    do j = 0, MBDK_BDF_MAX_ORDER + 1
      b%errc(j) = 1.0_dp / real(j + 1, dp)
    end do

    allocate (b%d(n, 0:MBDK_BDF_MAX_ORDER + 2), b%yp(n), b%psi(n), b%ynew(n), b%corr(n), &
              b%w(n), b%f(n), b%dy(n), b%em(n), b%alg(n), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (MBDK_BDF_MAX_ORDER + 11.0_dp) * n + &
                           MBDK_INT_BYTES * n, stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    b%dae = present(mass) .and. present(yp0) .and. present(ntest)
    b%em = 1.0_dp
    b%nt = n
    b%n2 = 0
    if (b%dae) then
      stat = MBDK_ERR_INVALID_INPUT
      if (size(mass) /= n .or. size(yp0) /= n .or. ntest < 1 .or. ntest > n) return
      b%em = mass
      b%nt = ntest
      if (present(nindex2)) b%n2 = nindex2
      if (b%n2 < 0 .or. b%nt + b%n2 > n) return
    end if
    b%alg = b%em == 0.0_dp
    call mbdk_newton_work_init(b%nw, n, stat, st%alloc_bytes, no_matrix=b%own_matrix)
    if (stat /= MBDK_SUCCESS) return
    b%t = t0
    b%t0 = t0
    st%t_reached = t0
    b%d = 0.0_dp
    b%d(:, 0) = y0
    b%hmax = t_end - t0
    if (opt%h_max > 0.0_dp) b%hmax = min(b%hmax, opt%h_max)
  end subroutine bdf_init

  !> The first step (order 1, implicit Euler): its size, D_1 = h F(t0, y0), and the first
  !> Jacobian. An ODE's h from mbdk_adaptive_initial_step; a DAE's from its given slope yp0:
  !> the explicit-Euler probe of the ODE guess means nothing for the algebraic rows, so the
  !> first step is 1 % of the time |y|/|y'| takes (Hairer's h0).
  subroutine bdf_start(b, prob, opt, atol, y0, st, stat, yp0)
    type(bdf_t), intent(inout) :: b
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: atol(:), y0(:)
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: yp0(:)
    real(dp) :: d0, d1

    if (b%dae) then
      b%f = yp0
      ! (the weights scale the index-2 components by h, which is not chosen yet: unscaled here)
      b%h = 1.0_dp
      call error_weights(opt, atol, y0, b%h, b%nt, b%n2, b%w)
      d0 = mbdk_adaptive_wrms(y0, b%w)
      d1 = mbdk_adaptive_wrms(b%f, b%w)
      b%h = 1.0e-6_dp
      if (d0 >= 1.0e-5_dp .and. d1 >= 1.0e-5_dp) b%h = 0.01_dp * d0 / d1
      if (opt%h > 0.0_dp) b%h = opt%h
      b%h = min(max(b%h, opt%h_min), b%hmax)
    else
      call prob%rhs(b%t, y0, b%f, stat)
      st%nfev = st%nfev + 1
      if (stat /= MBDK_SUCCESS) return
      ! F not finite at the initial state: no step size helps
      stat = MBDK_ERR_NONFINITE
      if (.not. all(abs(b%f) <= huge(1.0_dp))) return
      call mbdk_adaptive_initial_step(prob, opt, atol, 1, b%t, b%t_end - b%t, y0, b%f, b%h, &
                                      st%nfev, stat)
      if (stat /= MBDK_SUCCESS) return
    end if
    b%h = min(b%h, b%hmax)
    b%d(:, 1) = b%h * b%f
    b%q = 1
    b%n_equal = 0
    b%have_lu = .false.
    b%at_floor = .false.
    b%floor_stalls = 0
    b%c_lu = 0.0_dp
    b%crate = 1.0_dp
    call jacobian(b, prob, opt, b%t, y0, st, stat)
    if (stat /= MBDK_SUCCESS) return
    b%jac_current = .true.
    b%limit = mbdk_adaptive_step_limit(opt)
    b%tries = 0
    b%nonfinite = .false.
  end subroutine bdf_start

  !> The next step within h_max, landing on t_end without leaving a sliver before it.
  subroutine aim_step(b)
    type(bdf_t), intent(inout) :: b
    if (b%h > b%hmax) call rescale(b, b%hmax / b%h)
    b%t_new = b%t + b%h
    if (b%t_new >= b%t_end - 1.0e-3_dp * b%h) then
      b%t_new = b%t_end
      if (b%t_new - b%t /= b%h) call rescale(b, (b%t_new - b%t) / b%h)
    end if
  end subroutine aim_step

  !> Tries the step from b%t until one passes the corrector and the error test (then b%ynew at
  !> b%t_new, the correction b%corr, its estimate b%err), each failure shrinking h; stat: why
  !> none did (max_steps, the step floor, the roundoff floor, a callback).
  subroutine take_step(b, prob, opt, atol, st, stat)
    type(bdf_t), intent(inout) :: b
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: atol(:)
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    do
      if (b%tries >= b%limit) then
        stat = MBDK_ERR_TOO_MANY_STEPS
        return
      end if
      b%tries = b%tries + 1
      if (b%floor_stalls >= MAX_FLOOR_STALLS) then
        stat = MBDK_ERR_TOO_MUCH_ACCURACY
        call pose_cause(b, prob, stat)
        return
      end if
      if (b%h < mbdk_adaptive_h_floor(opt, b%t, landing=b%t + b%h >= b%t_end)) then
        call too_small_status(b, prob, stat)
        return
      end if
      b%t_new = b%t + b%h
      if (abs(b%t_new - b%t_end) <= 4.0_dp * spacing(b%t_end)) b%t_new = b%t_end
      call predict(b, opt, atol)
      call solve_corrector(b, prob, opt, st, stat)
      if (stat /= MBDK_SUCCESS) return
      if (.not. b%converged) then
        st%newton_failures = st%newton_failures + 1
        call rescale(b, 0.5_dp)
        b%have_lu = .false.
        ! a Jacobian taken where F was not finite is no use at the shorter step: take it
        ! again there, should the iteration fail once more
        if (b%nonfinite) b%jac_current = .false.
        ! a failure with this step's fresh Jacobian: the shorter step's predictor gets its own
        ! (CVODE's CV_FAIL_OTHER); one taken where the step started to fail can be far from
        ! what holds at the new predictor (next to a singular pose, J moves fast)
        if (b%jac_current) b%refresh_jac = .true.
        cycle
      end if
      if (error_test_passes(b, opt, atol, st)) exit
    end do
    stat = MBDK_SUCCESS
  end subroutine take_step

  !> Why the step shrank to nothing: halved by corrector iterates whose F was not finite (F is
  !> not finite next to this state, a singularity of the model: MBDK_ERR_NONFINITE); or
  !> because the tolerance lies below the corrector's roundoff (its Newton stalled there, or
  !> the error estimate, a share of the correction, carries a tenth of the tolerance in
  !> roundoff: MBDK_ERR_TOO_MUCH_ACCURACY); or for another reason (MBDK_ERR_STEP_TOO_SMALL);
  !> either of the last two next to a singular pose is named by it (pose_cause).
  subroutine too_small_status(b, prob, stat)
    type(bdf_t), intent(inout) :: b
    class(mbdk_problem_t), intent(in) :: prob
    integer, intent(out) :: stat
    real(dp) :: fl
    if (b%nonfinite .and. .not. b%at_floor) then
      stat = MBDK_ERR_NONFINITE
      return
    end if
    if (b%singular) then
      stat = MBDK_ERR_SINGULAR_MATRIX
      return
    end if
    if (.not. b%at_floor .and. b%have_lu) then
      call floor_norm(b, prob, fl, stat)
      if (stat /= MBDK_SUCCESS) return
      b%at_floor = b%errc(b%q) * fl >= ERROR_FLOOR_SHARE
    end if
    stat = MBDK_ERR_STEP_TOO_SMALL
    if (b%at_floor) stat = MBDK_ERR_TOO_MUCH_ACCURACY
    call pose_cause(b, prob, stat)
  end subroutine too_small_status

  !> The predictor y_p = sum_{j=0..q} D_j, psi, c = h / a_q, Newton's tolerance and the
  !> weights at y_p (the module header).
  subroutine predict(b, opt, atol)
    type(bdf_t), intent(inout) :: b
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: atol(:)
    integer :: j
    b%yp = sum(b%d(:, 0:b%q), dim=2)
    b%psi = 0.0_dp
    do j = 1, b%q
      b%psi = b%psi + b%gam(j) * b%d(:, j)
    end do
    b%psi = b%psi / b%gam(b%q)
    b%c = b%h / b%gam(b%q)
    b%tol = NEWTON_SHARE / b%errc(b%q)
    if (b%dae) b%tol = NEWTON_SHARE_DAE / b%errc(b%q)
    call error_weights(opt, atol, b%yp, b%h, b%nt, b%n2, b%w)
  end subroutine predict

  !> The corrector of the step, with M factorised again where c has moved (C_CHANGE) and, if it
  !> fails with an old Jacobian, once more with a fresh one; b%converged says how it ended.
  subroutine solve_corrector(b, prob, opt, st, stat)
    type(bdf_t), intent(inout) :: b
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    if (b%refresh_jac) then
      b%refresh_jac = .false.
      call fresh_jacobian(b, prob, opt, st, stat)
      if (stat /= MBDK_SUCCESS .or. b%nonfinite) return
    end if
    do
      if (.not. b%have_lu .or. abs(b%c - b%c_lu) > C_CHANGE * b%c_lu) then
        call factor_matrix(b, prob, st, stat)
        ! the problem's own factorisation has no pivoting: a body's block M - c D - c^2 K
        ! can pass through zero at one c while E - c J is regular (a compressed chain's
        ! geometric stiffness), so its zero pivot is a failed iteration, retried at a smaller
        ! step, and the cause if the steps shrink to nothing (too_small_status)
        if (stat == MBDK_ERR_SINGULAR_MATRIX .and. b%own_matrix) then
          call failed_iteration(b, singular=.true., stat=stat)
          return
        end if
        if (stat /= MBDK_SUCCESS) return
        b%singular = .false.
      end if
      call corrector(b, prob, st, stat)
      if (stat /= MBDK_SUCCESS) return
      if (b%converged .or. b%jac_current) exit
      call fresh_jacobian(b, prob, opt, st, stat)
      if (stat /= MBDK_SUCCESS .or. b%nonfinite) return
    end do
  end subroutine solve_corrector

  !> J at the step's predictor, to be factorised before the next iteration. The problem's own
  !> Jacobian names G not finite a difference increment away (the dense one carries it into
  !> its matrix, and the corrector meets it): a failed iteration too (b%nonfinite, stat
  !> MBDK_SUCCESS), retried at a smaller step, as where the corrector met it.
  subroutine fresh_jacobian(b, prob, opt, st, stat)
    type(bdf_t), intent(inout) :: b
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    b%nonfinite = .false.
    call jacobian(b, prob, opt, b%t_new, b%yp, st, stat)
    if (stat == MBDK_ERR_NONFINITE .and. b%own_matrix) then
      call failed_iteration(b, singular=.false., stat=stat)
      return
    end if
    if (stat /= MBDK_SUCCESS) return
    b%jac_current = .true.
    b%have_lu = .false.
  end subroutine fresh_jacobian

  !> A stop (stat) after at least one accepted step whose last state lies next to a singular
  !> pose of the problem's constraints (prob%singular_at: a mechanism's DAE) becomes
  !> MBDK_ERR_SINGULAR_MATRIX: the pose is the cause (there the DAE's rows lose a rank together
  !> and its Newton matrix's Jacobian moves fast), not the step or the tolerance.
  subroutine pose_cause(b, prob, stat)
    type(bdf_t), intent(in) :: b
    class(mbdk_problem_t), intent(in) :: prob
    integer, intent(inout) :: stat
    if (b%t > b%t0) then
      if (prob%singular_at(b%t, b%d(:, 0))) stat = MBDK_ERR_SINGULAR_MATRIX
    end if
  end subroutine pose_cause

  !> The problem's own Newton matrix failed this iteration (a zero pivot: singular; else G not
  !> finite next to the predictor): not converged, retried at a smaller step; stat SUCCESS.
  subroutine failed_iteration(b, singular, stat)
    type(bdf_t), intent(inout) :: b
    logical, intent(in) :: singular
    integer, intent(out) :: stat
    b%singular = singular
    b%nonfinite = .not. singular
    b%converged = .false.
    stat = MBDK_SUCCESS
  end subroutine failed_iteration

  !> The error test of a converged step (WRMS(e) <= 1, e = errc(q) corr, at the weights of
  !> y_new); a failed one is a rejection, h shrunk by max(FAC_MIN, safety err^(-1/(q+1))).
  logical function error_test_passes(b, opt, atol, st) result(passes)
    type(bdf_t), intent(inout) :: b
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: atol(:)
    type(mbdk_stats_t), intent(inout) :: st
    b%safety = 0.9_dp * real(2 * NEWTON_MAX_ITER + 1, dp) / &
      real(2 * NEWTON_MAX_ITER + b%iters, dp)
    call error_weights(opt, atol, b%ynew, b%h, b%nt, b%n2, b%w)
    b%err = mbdk_adaptive_wrms(b%errc(b%q) * b%corr, b%w)
    passes = b%err <= 1.0_dp
    if (passes) return
    st%rejected_steps = st%rejected_steps + 1
    call rescale(b, max(FAC_MIN, b%safety * b%err**(-1.0_dp / real(b%q + 1, dp))))
  end function error_test_passes

  !> The accepted step to (t_new, y_new): the watch's Gauss nodes, then the projection, finite
  !> check and watch (mbdk_adaptive_after_step; a projection's move enters the history as part
  !> of d), the statistics, and the differences of the new point. k: the next sample.
  subroutine accept_step(b, prob, t_out, k, st, stat)
    type(bdf_t), intent(inout) :: b
    class(mbdk_problem_t), intent(in) :: prob
    real(dp), intent(in) :: t_out(:)
    integer, intent(in) :: k
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    logical :: sample, projected
    integer :: i
    b%at_floor = .false.
    b%floor_stalls = 0
    sample = .false.
    if (k <= size(t_out)) sample = t_out(k) <= b%t_new
    if (prob%has_watch) then
      if (prob%watch_wants_nodes()) then
        call watch_nodes(b, prob, st, stat)
        if (stat /= MBDK_SUCCESS) return
      end if
    end if
    call mbdk_adaptive_after_step(prob, b%t_new, b%ynew, sample, projected, stat)
    if (stat /= MBDK_SUCCESS) return
    if (projected) b%corr = b%corr + (b%ynew - (b%yp + b%corr))
    st%steps = st%steps + 1
    call mbdk_adaptive_count_order(st, b%q)
    b%jac_current = .false.
    ! the differences of the new point: nabla^(q+1) y_{n+1} = d, and downwards
    b%d(:, b%q + 2) = b%corr - b%d(:, b%q + 1)
    b%d(:, b%q + 1) = b%corr
    do i = b%q, 0, -1
      b%d(:, i) = b%d(:, i) + b%d(:, i + 1)
    end do
    b%t = b%t_new
    st%t_reached = b%t
    b%n_equal = b%n_equal + 1
  end subroutine accept_step

  !> After q + 1 steps of one h: orders q - 1, q and q + 1 compared by their error estimates
  !> from the same history, the one allowing the largest step taken, h grown at most FAC_MAX.
  subroutine choose_order(b)
    type(bdf_t), intent(inout) :: b
    real(dp) :: norms(3), facs(3), factor
    integer :: i, best
    norms = huge(1.0_dp)
    if (b%q > 1) norms(1) = mbdk_adaptive_wrms(b%errc(b%q - 1) * b%d(:, b%q), b%w)
    norms(2) = b%err
    if (b%q < b%qmax) norms(3) = mbdk_adaptive_wrms(b%errc(b%q + 1) * b%d(:, b%q + 2), b%w)
    do i = 1, 3
      if (norms(i) >= huge(1.0_dp)) then
        facs(i) = 0.0_dp
      else
        facs(i) = max(norms(i), 1.0e-10_dp)**(-1.0_dp / real(b%q + i - 1, dp))
      end if
    end do
    best = maxloc(facs, dim=1)
    b%q = b%q + best - 2
    factor = min(FAC_MAX, b%safety * facs(best))
    call rescale(b, factor)
  end subroutine choose_order

  !> The samples k, k + 1, ... in (t_old, t]: the history's polynomial (at t: the state).
  subroutine write_samples(b, t_out, y_out, k, nwritten)
    type(bdf_t), intent(in) :: b
    real(dp), intent(in) :: t_out(:)
    real(dp), intent(inout) :: y_out(:, :)
    integer, intent(inout) :: k, nwritten
    do while (k <= size(t_out))
      if (t_out(k) > b%t) exit
      if (t_out(k) >= b%t) then
        y_out(:, k) = b%d(:, 0)
      else
        call interpolate(b, t_out(k), y_out(:, k))
      end if
      nwritten = k
      k = k + 1
    end do
  end subroutine write_samples

  !> J at (t, y): the problem's own (has_newton_matrix: it keeps J, sparse) or mbdk_jacobian's.
  subroutine jacobian(b, prob, opt, t, y, st, stat)
    type(bdf_t), intent(inout) :: b
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t, y(:)
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    integer :: nfev
    if (b%own_matrix) then
      st%njev = st%njev + 1
      call prob%newton_jacobian(t, y, nfev, stat)
      st%nfev = st%nfev + nfev
    else
      call mbdk_jacobian(prob, opt, t, y, b%nw, st, stat)
    end if
  end subroutine jacobian

  !> x <- M^-1 x with the last factorisation
  subroutine newton_solve(b, prob, x, s)
    type(bdf_t), intent(inout) :: b
    class(mbdk_problem_t), intent(in) :: prob
    real(dp), intent(inout), contiguous :: x(:)
    integer, intent(out) :: s
    if (b%own_matrix) then
      call prob%newton_solve(x, s)
    else
      call mbdk_lu_solve(b%nw%lu, b%nw%ipiv, x, s)
    end if
  end subroutine newton_solve

  !> M = E - c J, factorised (a DAE's index-scaled): the problem's own (has_newton_matrix),
  !> else dense by LAPACK.
  subroutine factor_matrix(b, prob, st, s)
    type(bdf_t), intent(inout) :: b
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: s
    integer :: ii
    if (b%own_matrix) then
      call prob%newton_factor(b%c, b%em, b%alg, s)
      st%nlu = st%nlu + 1
      st%nlu_sparse = st%nlu_sparse + 1
      b%have_lu = s == MBDK_SUCCESS
      b%c_lu = b%c
      b%crate = 1.0_dp
      return
    end if
    b%nw%lu = -b%c * b%nw%jac
    do ii = 1, b%n
      b%nw%lu(ii, ii) = b%nw%lu(ii, ii) + b%em(ii)
    end do
    if (b%dae) then
      ! index scaling: the algebraic rows divided by c, the algebraic unknowns multiplied by
      ! it (the solve returns c dy there), so that no entry grows like 1/c as h -> 0 (the
      ! condition number still grows like 1/c; GSTIFF I3's scaling of rows and columns)
      do ii = 1, b%n
        if (b%alg(ii)) then
          b%nw%lu(ii, :) = b%nw%lu(ii, :) / b%c
          b%nw%lu(:, ii) = b%nw%lu(:, ii) / b%c
        end if
      end do
    end if
    call mbdk_lu_factor(b%nw%lu, b%nw%ipiv, s)
    st%nlu = st%nlu + 1
    b%have_lu = s == MBDK_SUCCESS
    b%c_lu = b%c
    b%crate = 1.0_dp
  end subroutine factor_matrix

  !> Simplified Newton on c F(t_new, yp + corr) - psi - corr = 0 (module header).
  subroutine corrector(b, prob, st, s)
    type(bdf_t), intent(inout) :: b
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: s
    integer :: it
    real(dp) :: dnorm, dnorm_old, rate
    logical :: stop_here
    real(dp) :: fl
    b%converged = .false.
    b%nonfinite = .false.
    rate = 1.0_dp
    b%corr = 0.0_dp
    b%ynew = b%yp
    dnorm_old = -1.0_dp
    b%iters = 0
    s = MBDK_SUCCESS
    do it = 1, NEWTON_MAX_ITER
      call prob%rhs(b%t_new, b%ynew, b%f, s)
      st%nfev = st%nfev + 1
      if (s /= MBDK_SUCCESS) return
      if (.not. all(abs(b%f) <= huge(1.0_dp))) then
        b%nonfinite = .true.
        exit
      end if
      b%dy = b%c * b%f - b%em * (b%psi + b%corr)
      if (b%dae) where (b%alg) b%dy = b%f      ! the row divided by c
      call newton_solve(b, prob, b%dy, s)
      if (s /= MBDK_SUCCESS) return
      if (b%dae) where (b%alg) b%dy = b%dy / b%c
      b%iters = it
      st%newton_iterations = st%newton_iterations + 1
      dnorm = mbdk_adaptive_wrms(b%dy, b%w)
      if (.not. (dnorm <= huge(1.0_dp))) then
        b%nonfinite = .true.      ! F or its Jacobian not finite where the iterates went
        exit
      end if
      if (dnorm_old > 0.0_dp) then
        rate = dnorm / dnorm_old
        stop_here = rate >= 1.0_dp
        if (.not. stop_here) stop_here = &
          rate**(NEWTON_MAX_ITER - it + 1) / (1.0_dp - rate) * dnorm > b%tol
        if (stop_here .or. it == NEWTON_MAX_ITER) then
          ! stalled, or out of iterations, with the update at its roundoff floor: an ODE's
          ! iterate is then as good as double precision makes it. A DAE's (whose tolerance
          ! is a thousandth of the error test's) is noted: the step is retried smaller as
          ! after any failure, and after MAX_FLOOR_STALLS such stalls in one step, or if the
          ! steps shrink to the floor, the cause is named (MBDK_ERR_TOO_MUCH_ACCURACY): a
          ! smaller step's matrix is worse conditioned
          call floor_norm(b, prob, fl, s)
          if (s /= MBDK_SUCCESS) return
          if (dnorm <= fl) then
            if (b%dae) then
              b%at_floor = .true.
              b%floor_stalls = b%floor_stalls + 1
              exit
            end if
            b%ynew = b%ynew + b%dy
            b%corr = b%corr + b%dy
            b%converged = .true.
            exit
          end if
        end if
        if (stop_here) exit
        b%crate = max(CRATE_DOWN * b%crate, rate)
      end if
      b%ynew = b%ynew + b%dy
      b%corr = b%corr + b%dy
      ! a DAE trusts only this step's own rate: a remembered small one would accept a first
      ! iterate that leaves the constraints unmet, and the leftover returns in the next
      ! predictor as a correction that no smaller step removes
      if (dnorm * min(1.0_dp, merge(rate, b%crate, b%dae .and. it == 1)) < b%tol) then
        b%converged = .true.
        exit
      end if
      dnorm_old = dnorm
    end do
  end subroutine corrector

  !> fl: the weighted norm of the Newton update's roundoff floor (mbdk_newton_floor) with the
  !> current matrix, from the corrector's terms at the iterate (b%f, psi, corr, ynew): the
  !> residual's rows (an algebraic row, divided by c, carries eps times the largest tested
  !> component: its terms are positions) through the matrix, plus the rounding of the iterate
  !> itself, capped (mbdk_floor_cap). The Newton work's vectors hold the probes.
  subroutine floor_norm(b, prob, fl, s)
    type(bdf_t), intent(inout) :: b
    class(mbdk_problem_t), intent(in) :: prob
    real(dp), intent(out) :: fl
    integer, intent(out) :: s
    real(dp) :: ymax
    fl = huge(1.0_dp)
    associate (nw => b%nw)
      ymax = maxval(abs(b%ynew(1:b%nt)))
      nw%ytmp = abs(b%c * b%f) + b%em * (abs(b%psi) + abs(b%corr))
      if (b%dae) where (b%alg) nw%ytmp = abs(b%f) + ymax
      nw%ytmp = epsilon(1.0_dp) * nw%ytmp
      if (b%own_matrix) then
        call mbdk_floor_probes(nw%ytmp, nw%b1, nw%b2)
        call newton_solve(b, prob, nw%b1, s)
        if (s /= MBDK_SUCCESS) return
        call newton_solve(b, prob, nw%b2, s)
      else
        call mbdk_floor_solve(nw%ytmp, nw%lu, nw%ipiv, nw%b1, nw%b2, s)
      end if
      if (s /= MBDK_SUCCESS) return
      if (b%dae) then
        where (b%alg)
          nw%b1 = nw%b1 / b%c
          nw%b2 = nw%b2 / b%c
        end where
      end if
      call mbdk_floor_from_probes(nw%b1, nw%b2, nw%floor)
      nw%floor = nw%floor + MBDK_FLOOR_FACTOR * epsilon(1.0_dp) * abs(b%ynew)
      call mbdk_floor_cap(b%ynew, nw%floor)
      fl = mbdk_adaptive_wrms(nw%floor, b%w)
    end associate
  end subroutine floor_norm

  !> The error weights w at yy; a DAE's index-2 components (the n2 after the nt tested ones)
  !> are weighted by h, as Radau5 and DASSL's index-2 practice do: their correction after a
  !> step change carries O(1/h) from the constraints, h times it is what converges; the
  !> untested components (the multipliers) get weight 0, and the norm stays the mean over the
  !> weighted ones.
  subroutine error_weights(opt, atol, yy, h, nt, n2, w)
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: atol(:), yy(:), h
    integer, intent(in) :: nt, n2
    real(dp), intent(inout) :: w(:)
    integer :: n
    n = size(w)
    call mbdk_adaptive_weights(opt, atol, yy, w)
    if (nt < n) then
      w(nt + 1:nt + n2) = w(nt + 1:nt + n2) * h
      w(nt + n2 + 1:) = 0.0_dp
      w = w * sqrt(real(n, dp) / real(nt + n2, dp))
    end if
  end subroutine error_weights

  !> h <- r h: the differences re-interpolated onto the new grid, D <- (R(r) U)^T D.
  subroutine rescale(b, r)
    type(bdf_t), intent(inout) :: b
    real(dp), intent(in) :: r
    real(dp) :: rr(0:MBDK_BDF_MAX_ORDER, 0:MBDK_BDF_MAX_ORDER)
    real(dp) :: uu(0:MBDK_BDF_MAX_ORDER, 0:MBDK_BDF_MAX_ORDER)
    real(dp) :: ru(0:MBDK_BDF_MAX_ORDER, 0:MBDK_BDF_MAX_ORDER)
    real(dp), allocatable :: dn(:, :)
    integer :: q
    q = b%q
    call r_matrix(q, r, rr)
    call r_matrix(q, 1.0_dp, uu)
    ru(0:q, 0:q) = matmul(rr(0:q, 0:q), uu(0:q, 0:q))
    dn = matmul(b%d(:, 0:q), ru(0:q, 0:q))
    b%d(:, 0:q) = dn
    b%h = b%h * r
    b%n_equal = 0
  end subroutine rescale

  !> The watch's work over the accepted step (t, t_new]: the states at its Gauss nodes
  !> (MBDK_GAUSS3) from the polynomial of the history with the new point. The update in
  !> accept_step makes its differences D'_i = sum_{l >= i} D_l + corr; so its polynomial at tt,
  !> sum_j c_j D'_j, is sum_l (c_0 + .. + c_l) D_l + (c_0 + .. + c_q) corr, with no copy of D.
  subroutine watch_nodes(b, prob, st, s)
    type(bdf_t), intent(in) :: b
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: s
    real(dp), allocatable :: yn(:, :)
    real(dp) :: lag, csum
    integer :: ii, jj, astat
    allocate (yn(b%n, 3), stat=astat)
    call mbdk_alloc_status(astat, 3.0_dp * MBDK_REAL_BYTES * b%n, s, st%alloc_bytes)
    if (s /= MBDK_SUCCESS) return
    do ii = 1, 3
      lag = 1.0_dp
      csum = 1.0_dp
      yn(:, ii) = b%d(:, 0)
      do jj = 1, b%q
        lag = lag * (b%t + MBDK_GAUSS3(ii) * (b%t_new - b%t) - &
                     (b%t_new - real(jj - 1, dp) * b%h)) / (real(jj, dp) * b%h)
        csum = csum + lag
        yn(:, ii) = yn(:, ii) + csum * b%d(:, jj)
      end do
      yn(:, ii) = yn(:, ii) + csum * b%corr
    end do
    call prob%watch_nodes(b%t, b%t_new, yn, s)
  end subroutine watch_nodes

  !> The history's polynomial at time tt (t_old <= tt < t).
  subroutine interpolate(b, tt, yy)
    type(bdf_t), intent(in) :: b
    real(dp), intent(in) :: tt
    real(dp), intent(out) :: yy(:)
    real(dp) :: p
    integer :: jj
    yy = b%d(:, 0)
    p = 1.0_dp
    do jj = 1, b%q
      p = p * (tt - (b%t - real(jj - 1, dp) * b%h)) / (real(jj, dp) * b%h)
      yy = yy + p * b%d(:, jj)
    end do
  end subroutine interpolate

  !> Shampine and Reichelt's R(r) of order q: R(i, j) = prod_{m=1..i} (m - 1 - r j)/m, i, j >= 1,
  !> R(0, j) = 1, R(i, 0) = 0 (i >= 1).
  pure subroutine r_matrix(q, r, rr)
    integer, intent(in) :: q
    real(dp), intent(in) :: r
    real(dp), intent(out) :: rr(0:, 0:)
    integer :: i, j
    rr = 0.0_dp
    rr(0, 0:q) = 1.0_dp
    do j = 1, q
      do i = 1, q
        rr(i, j) = rr(i - 1, j) * (real(i - 1, dp) - r * real(j, dp)) / real(i, dp)
      end do
    end do
  end subroutine r_matrix

end module mbdk_variable_bdf
