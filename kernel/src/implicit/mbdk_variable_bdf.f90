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
!> failure with a fresh Jacobian halves h (stats: newton_failures). Below mbdk_adaptive_h_floor:
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
!> every smaller step after a rejection. The first step comes from yp0 (1 % of |y|/|y'|, or opt%h); the Jacobian is by
!> differences (N + 1 evaluations of F).
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
  use mbdk_newton_floor, only: mbdk_floor_solve, mbdk_floor_from_probes, mbdk_floor_cap, &
    MBDK_FLOOR_FACTOR
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

    integer :: n, ns, k, q, qmax, n_equal, iters, i, j, best
    integer(i8) :: tries, limit
    logical :: have_lu, jac_current, converged, projected, sample, nonfinite
    logical :: at_floor   !< a corrector of this step stalled at its roundoff floor (a DAE's)
    integer :: floor_stalls   !< how often, in this step
    real(dp) :: t, t_end, h, hmax, t_new, c, c_lu, tol, err, safety, factor, crate
    real(dp) :: gam(0:MBDK_BDF_MAX_ORDER), errc(0:MBDK_BDF_MAX_ORDER + 1), norms(3), facs(3)
    real(dp), allocatable :: d(:, :), yp(:), psi(:), ynew(:), corr(:), w(:), f(:), dy(:)
    real(dp), allocatable :: em(:)
    logical, allocatable :: alg(:)
    logical :: dae
    integer :: nt, n2, astat
    real(dp) :: d0, d1
    type(mbdk_newton_work_t) :: nw

    n = size(y0)
    ns = size(t_out)
    t_end = t_out(ns)
    qmax = MBDK_BDF_MAX_ORDER
    stat = MBDK_ERR_INVALID_INPUT
    if (opt%max_order > MBDK_BDF_MAX_ORDER) return
    if (opt%max_order > 0) qmax = opt%max_order

    gam(0) = 0.0_dp
    do j = 1, MBDK_BDF_MAX_ORDER
      gam(j) = gam(j - 1) + 1.0_dp / real(j, dp)
    end do
    do j = 0, MBDK_BDF_MAX_ORDER + 1
      errc(j) = 1.0_dp / real(j + 1, dp)
    end do

    allocate (d(n, 0:MBDK_BDF_MAX_ORDER + 2), yp(n), psi(n), ynew(n), corr(n), w(n), f(n), dy(n), &
              em(n), alg(n), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (MBDK_BDF_MAX_ORDER + 11.0_dp) * n + &
                           MBDK_INT_BYTES * n, stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    dae = present(mass) .and. present(yp0) .and. present(ntest)
    em = 1.0_dp
    nt = n
    n2 = 0
    if (dae) then
      stat = MBDK_ERR_INVALID_INPUT
      if (size(mass) /= n .or. size(yp0) /= n .or. ntest < 1 .or. ntest > n) return
      em = mass
      nt = ntest
      if (present(nindex2)) n2 = nindex2
      if (n2 < 0 .or. nt + n2 > n) return
    end if
    alg = em == 0.0_dp
    call mbdk_newton_work_init(nw, n, stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    t = t0
    st%t_reached = t0
    d = 0.0_dp
    d(:, 0) = y0
    hmax = t_end - t0
    if (opt%h_max > 0.0_dp) hmax = min(hmax, opt%h_max)
    if (dae) then
      ! the slope is given; the explicit-Euler probe of the ODE guess means nothing for the
      ! algebraic rows, so the first step is 1 % of the time |y|/|y'| takes (Hairer's h0)
      f = yp0
      ! (weights scales the index-2 components by h, which is not chosen yet: unscaled here)
      h = 1.0_dp
      call weights(y0)
      d0 = mbdk_adaptive_wrms(y0, w)
      d1 = mbdk_adaptive_wrms(f, w)
      h = 1.0e-6_dp
      if (d0 >= 1.0e-5_dp .and. d1 >= 1.0e-5_dp) h = 0.01_dp * d0 / d1
      if (opt%h > 0.0_dp) h = opt%h
      h = min(max(h, opt%h_min), hmax)
    else
      call prob%rhs(t, y0, f, stat)
      st%nfev = st%nfev + 1
      if (stat /= MBDK_SUCCESS) return
      ! F not finite at the initial state: no step size helps
      stat = MBDK_ERR_NONFINITE
      if (.not. all(abs(f) <= huge(1.0_dp))) return
      call mbdk_adaptive_initial_step(prob, opt, atol, 1, t0, t_end - t0, y0, f, h, st%nfev, &
                                      stat)
      if (stat /= MBDK_SUCCESS) return
    end if
    h = min(h, hmax)
    d(:, 1) = h * f
    q = 1
    n_equal = 0
    have_lu = .false.
    at_floor = .false.
    floor_stalls = 0
    c_lu = 0.0_dp
    crate = 1.0_dp
    call mbdk_jacobian(prob, opt, t, y0, nw, st, stat)
    if (stat /= MBDK_SUCCESS) return
    jac_current = .true.
    limit = mbdk_adaptive_step_limit(opt)
    tries = 0
    k = nwritten + 1
    nonfinite = .false.

    do while (t < t_end)
      if (opt%interrupt /= 0 .and. mbdk_interrupted(opt%interrupt)) then
        stat = MBDK_ERR_INTERRUPTED
        return
      end if
      if (opt%progress /= 0) call mbdk_progress(opt%progress, t)
      ! the step: within h_max, landing on t_end without leaving a sliver
      if (h > hmax) call rescale(hmax / h)
      t_new = t + h
      if (t_new >= t_end - 1.0e-3_dp * h) then
        t_new = t_end
        if (t_new - t /= h) call rescale((t_new - t) / h)
      end if

      step: do
        if (tries >= limit) then
          stat = MBDK_ERR_TOO_MANY_STEPS
          return
        end if
        tries = tries + 1
        if (floor_stalls >= MAX_FLOOR_STALLS) then
          stat = MBDK_ERR_TOO_MUCH_ACCURACY
          return
        end if
        if (h < mbdk_adaptive_h_floor(opt, t, landing=t + h >= t_end)) then
          ! the step shrank to nothing: halved by corrector iterates whose F was not finite
          ! (F is not finite next to this state, a singularity of the model); or because the
          ! tolerance lies below the corrector's roundoff (its Newton stalled there, or the
          ! error estimate, a share of the correction, carries a tenth of the tolerance in
          ! roundoff); or for another reason
          if (nonfinite .and. .not. at_floor) then
            stat = MBDK_ERR_NONFINITE
            return
          end if
          if (.not. at_floor .and. have_lu) then
            call floor_norm(err, stat)
            if (stat /= MBDK_SUCCESS) return
            at_floor = errc(q) * err >= ERROR_FLOOR_SHARE
          end if
          stat = MBDK_ERR_STEP_TOO_SMALL
          if (at_floor) stat = MBDK_ERR_TOO_MUCH_ACCURACY
          return
        end if
        t_new = t + h
        if (abs(t_new - t_end) <= 4.0_dp * spacing(t_end)) t_new = t_end
        yp = sum(d(:, 0:q), dim=2)
        psi = 0.0_dp
        do j = 1, q
          psi = psi + gam(j) * d(:, j)
        end do
        psi = psi / gam(q)
        c = h / gam(q)
        tol = NEWTON_SHARE / errc(q)
        if (dae) tol = NEWTON_SHARE_DAE / errc(q)
        call weights(yp)
        do
          if (.not. have_lu .or. abs(c - c_lu) > C_CHANGE * c_lu) then
            call factor_matrix(stat)
            if (stat /= MBDK_SUCCESS) return
          end if
          call corrector(stat)
          if (stat /= MBDK_SUCCESS) return
          if (converged .or. jac_current) exit
          call mbdk_jacobian(prob, opt, t_new, yp, nw, st, stat)
          if (stat /= MBDK_SUCCESS) return
          jac_current = .true.
          have_lu = .false.
        end do
        if (.not. converged) then
          st%newton_failures = st%newton_failures + 1
          call rescale(0.5_dp)
          have_lu = .false.
          ! a Jacobian taken where F was not finite is no use at the shorter step: take it
          ! again there, should the iteration fail once more
          if (nonfinite) jac_current = .false.
          cycle step
        end if
        safety = 0.9_dp * real(2 * NEWTON_MAX_ITER + 1, dp) / real(2 * NEWTON_MAX_ITER + iters, dp)
        call weights(ynew)
        err = mbdk_adaptive_wrms(errc(q) * corr, w)
        if (err > 1.0_dp) then
          st%rejected_steps = st%rejected_steps + 1
          call rescale(max(FAC_MIN, safety * err**(-1.0_dp / real(q + 1, dp))))
          cycle step
        end if
        exit step
      end do step

      ! accepted. A projection moves y_{n+1}; the history takes the move as part of d.
      at_floor = .false.
      floor_stalls = 0
      sample = .false.
      if (k <= ns) sample = t_out(k) <= t_new
      if (prob%has_watch) then
        if (prob%watch_wants_nodes()) then
          call watch_nodes(stat)
          if (stat /= MBDK_SUCCESS) return
        end if
      end if
      call mbdk_adaptive_after_step(prob, t_new, ynew, sample, projected, stat)
      if (stat /= MBDK_SUCCESS) return
      if (projected) corr = corr + (ynew - (yp + corr))
      st%steps = st%steps + 1
      call mbdk_adaptive_count_order(st, q)
      jac_current = .false.
      ! the differences of the new point: nabla^(q+1) y_{n+1} = d, and downwards
      d(:, q + 2) = corr - d(:, q + 1)
      d(:, q + 1) = corr
      do i = q, 0, -1
        d(:, i) = d(:, i) + d(:, i + 1)
      end do
      t = t_new
      st%t_reached = t
      n_equal = n_equal + 1

      if (n_equal >= q + 1 .and. t < t_end) then
        ! orders q - 1, q, q + 1 from the same history
        norms = huge(1.0_dp)
        if (q > 1) norms(1) = mbdk_adaptive_wrms(errc(q - 1) * d(:, q), w)
        norms(2) = err
        if (q < qmax) norms(3) = mbdk_adaptive_wrms(errc(q + 1) * d(:, q + 2), w)
        do i = 1, 3
          if (norms(i) >= huge(1.0_dp)) then
            facs(i) = 0.0_dp
          else
            facs(i) = max(norms(i), 1.0e-10_dp)**(-1.0_dp / real(q + i - 1, dp))
          end if
        end do
        best = maxloc(facs, dim=1)
        q = q + best - 2
        factor = min(FAC_MAX, safety * facs(best))
        call rescale(factor)
      end if

      ! samples in (t_old, t]: the history's polynomial (t itself: the state)
      do while (k <= ns)
        if (t_out(k) > t) exit
        if (t_out(k) >= t) then
          y_out(:, k) = d(:, 0)
        else
          call interpolate(t_out(k), y_out(:, k))
        end if
        nwritten = k
        k = k + 1
      end do
    end do
    stat = MBDK_SUCCESS

  contains

    !> M = I - c J, factorised.
    subroutine factor_matrix(s)
      integer, intent(out) :: s
      integer :: ii
      nw%lu = -c * nw%jac
      do ii = 1, n
        nw%lu(ii, ii) = nw%lu(ii, ii) + em(ii)
      end do
      if (dae) then
        ! index scaling: the algebraic rows divided by c, the algebraic unknowns multiplied by
        ! it (the solve returns c dy there), so that no entry grows like 1/c as h -> 0 (the
        ! condition number still grows like 1/c; GSTIFF I3's scaling of rows and columns)
        do ii = 1, n
          if (alg(ii)) then
            nw%lu(ii, :) = nw%lu(ii, :) / c
            nw%lu(:, ii) = nw%lu(:, ii) / c
          end if
        end do
      end if
      call mbdk_lu_factor(nw%lu, nw%ipiv, s)
      st%nlu = st%nlu + 1
      have_lu = s == MBDK_SUCCESS
      c_lu = c
      crate = 1.0_dp
    end subroutine factor_matrix

    !> Simplified Newton on c F(t_new, yp + corr) - psi - corr = 0 (module header).
    subroutine corrector(s)
      integer, intent(out) :: s
      integer :: it
      real(dp) :: dnorm, dnorm_old, rate
      logical :: stop_here
      real(dp) :: fl
      converged = .false.
      nonfinite = .false.
      rate = 1.0_dp
      corr = 0.0_dp
      ynew = yp
      dnorm_old = -1.0_dp
      iters = 0
      s = MBDK_SUCCESS
      do it = 1, NEWTON_MAX_ITER
        call prob%rhs(t_new, ynew, f, s)
        st%nfev = st%nfev + 1
        if (s /= MBDK_SUCCESS) return
        if (.not. all(abs(f) <= huge(1.0_dp))) then
          nonfinite = .true.
          exit
        end if
        dy = c * f - em * (psi + corr)
        if (dae) where (alg) dy = f      ! the row divided by c
        call mbdk_lu_solve(nw%lu, nw%ipiv, dy, s)
        if (s /= MBDK_SUCCESS) return
        if (dae) where (alg) dy = dy / c
        iters = it
        st%newton_iterations = st%newton_iterations + 1
        dnorm = mbdk_adaptive_wrms(dy, w)
        if (.not. (dnorm <= huge(1.0_dp))) then
          nonfinite = .true.      ! F or its Jacobian not finite where the iterates went
          exit
        end if
        if (dnorm_old > 0.0_dp) then
          rate = dnorm / dnorm_old
          stop_here = rate >= 1.0_dp
          if (.not. stop_here) stop_here = &
            rate**(NEWTON_MAX_ITER - it + 1) / (1.0_dp - rate) * dnorm > tol
          if (stop_here .or. it == NEWTON_MAX_ITER) then
            ! stalled, or out of iterations, with the update at its roundoff floor: an ODE's
            ! iterate is then as good as double precision makes it. A DAE's (whose tolerance
            ! is a thousandth of the error test's) is noted: the step is retried smaller as
            ! after any failure, and after MAX_FLOOR_STALLS such stalls in one step, or if the
            ! steps shrink to the floor, the cause is named (MBDK_ERR_TOO_MUCH_ACCURACY): a
            ! smaller step's matrix is worse conditioned
            call floor_norm(fl, s)
            if (s /= MBDK_SUCCESS) return
            if (dnorm <= fl) then
              if (dae) then
                at_floor = .true.
                floor_stalls = floor_stalls + 1
                exit
              end if
              ynew = ynew + dy
              corr = corr + dy
              converged = .true.
              exit
            end if
          end if
          if (stop_here) exit
          crate = max(CRATE_DOWN * crate, rate)
        end if
        ynew = ynew + dy
        corr = corr + dy
        ! a DAE trusts only this step's own rate: a remembered small one would accept a first
        ! iterate that leaves the constraints unmet, and the leftover returns in the next
        ! predictor as a correction that no smaller step removes
        if (dnorm * min(1.0_dp, merge(rate, crate, dae .and. it == 1)) < tol) then
          converged = .true.
          exit
        end if
        dnorm_old = dnorm
      end do
    end subroutine corrector

    !> fl: the weighted norm of the Newton update's roundoff floor (mbdk_newton_floor) with the
    !> current matrix, from the corrector's terms at the iterate (f, psi, corr, ynew of the
    !> host): the residual's rows (an algebraic row, divided by c, carries eps times the largest
    !> tested component: its terms are positions) through the matrix, plus the rounding of the
    !> iterate itself, capped (mbdk_floor_cap). The Newton work's vectors hold the probes.
    subroutine floor_norm(fl, s)
      real(dp), intent(out) :: fl
      integer, intent(out) :: s
      real(dp) :: ymax
      fl = huge(1.0_dp)
      ymax = maxval(abs(ynew(1:nt)))
      nw%ytmp = abs(c * f) + em * (abs(psi) + abs(corr))
      if (dae) where (alg) nw%ytmp = abs(f) + ymax
      nw%ytmp = epsilon(1.0_dp) * nw%ytmp
      call mbdk_floor_solve(nw%ytmp, nw%lu, nw%ipiv, nw%b1, nw%b2, s)
      if (s /= MBDK_SUCCESS) return
      if (dae) then
        where (alg)
          nw%b1 = nw%b1 / c
          nw%b2 = nw%b2 / c
        end where
      end if
      call mbdk_floor_from_probes(nw%b1, nw%b2, nw%floor)
      nw%floor = nw%floor + MBDK_FLOOR_FACTOR * epsilon(1.0_dp) * abs(ynew)
      call mbdk_floor_cap(ynew, nw%floor)
      fl = mbdk_adaptive_wrms(nw%floor, w)
    end subroutine floor_norm

    !> The error weights at yy; a DAE's index-2 components (after the ntest tested ones) are
    !> weighted by h, as Radau5 and DASSL's index-2 practice do: their correction after a step
    !> change carries O(1/h) from the constraints, h times it is what converges; the
    !> untested components (the multipliers) get weight 0, and the norm stays the mean over the
    !> weighted ones.
    subroutine weights(yy)
      real(dp), intent(in) :: yy(:)
      call mbdk_adaptive_weights(opt, atol, yy, w)
      if (nt < n) then
        w(nt + 1:nt + n2) = w(nt + 1:nt + n2) * h
        w(nt + n2 + 1:) = 0.0_dp
        w = w * sqrt(real(n, dp) / real(nt + n2, dp))
      end if
    end subroutine weights

    !> h <- r h: the differences re-interpolated onto the new grid, D <- (R(r) U)^T D.
    subroutine rescale(r)
      real(dp), intent(in) :: r
      real(dp) :: rr(0:MBDK_BDF_MAX_ORDER, 0:MBDK_BDF_MAX_ORDER)
      real(dp) :: uu(0:MBDK_BDF_MAX_ORDER, 0:MBDK_BDF_MAX_ORDER)
      real(dp) :: ru(0:MBDK_BDF_MAX_ORDER, 0:MBDK_BDF_MAX_ORDER)
      real(dp), allocatable :: dn(:, :)
      call r_matrix(q, r, rr)
      call r_matrix(q, 1.0_dp, uu)
      ru(0:q, 0:q) = matmul(rr(0:q, 0:q), uu(0:q, 0:q))
      dn = matmul(d(:, 0:q), ru(0:q, 0:q))
      d(:, 0:q) = dn
      h = h * r
      n_equal = 0
    end subroutine rescale

    !> The watch's work over the accepted step (t, t_new]: the states at its Gauss nodes
    !> (MBDK_GAUSS3) from the polynomial of the history with the new point. The update below
    !> makes its differences D'_i = sum_{l >= i} D_l + corr; so its polynomial at tt, sum_j
    !> c_j D'_j, is sum_l (c_0 + .. + c_l) D_l + (c_0 + .. + c_q) corr, with no copy of D.
    subroutine watch_nodes(s)
      integer, intent(out) :: s
      real(dp), allocatable :: yn(:, :)
      real(dp) :: lag, csum
      integer :: ii, jj, astat
      allocate (yn(n, 3), stat=astat)
      call mbdk_alloc_status(astat, 3.0_dp * MBDK_REAL_BYTES * n, s, st%alloc_bytes)
      if (s /= MBDK_SUCCESS) return
      do ii = 1, 3
        lag = 1.0_dp
        csum = 1.0_dp
        yn(:, ii) = d(:, 0)
        do jj = 1, q
          lag = lag * (t + MBDK_GAUSS3(ii) * (t_new - t) - (t_new - real(jj - 1, dp) * h)) / &
            (real(jj, dp) * h)
          csum = csum + lag
          yn(:, ii) = yn(:, ii) + csum * d(:, jj)
        end do
        yn(:, ii) = yn(:, ii) + csum * corr
      end do
      call prob%watch_nodes(t, t_new, yn, s)
    end subroutine watch_nodes

    !> The history's polynomial at time tt (t_old <= tt < t).
    subroutine interpolate(tt, yy)
      real(dp), intent(in) :: tt
      real(dp), intent(out) :: yy(:)
      real(dp) :: p
      integer :: jj
      yy = d(:, 0)
      p = 1.0_dp
      do jj = 1, q
        p = p * (tt - (t - real(jj - 1, dp) * h)) / (real(jj, dp) * h)
        yy = yy + p * d(:, jj)
      end do
    end subroutine interpolate

  end subroutine mbdk_variable_bdf_solve

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
