!> trapezoidal_index3 on a spatial scene: direct integration of its index-3 DAE by the implicit
!> trapezoidal rule with Newton-Raphson, then projections (the planar twin is
!> mbdk_trapezoidal_index3; Fekete (2023) 3.2.1 for the scheme, Bayo and Ledesma (1996) for the
!> projections). With the state of mbdk_spatial_model, y = [q; w] (q: centres and quaternions or
!> angles, w: velocities and body-frame angular velocities), q' = T(q) w, and
!>   a(q, w, lam) = M^-1 (f - W x J W - C_a^T lam)      (mbdk_spatial_dae_rhs)
!> on the independent rows a of model%work%active, one step from t to t+ = t + h solves for
!> (q+, w+, lam+):
!>   q+ - q - (h/2) (T(q) w + T(q+) w+)           = 0
!>   w+ - w - (h/2) (a + a(q+, w+, lam+))         = 0
!>   Phi_a(q+, t+)                                = 0
!> The equations of motion hold at t+ with the multipliers of t+ (as the planar scheme's
!> (3.15): the trapezoidal rule averages the accelerations, not the multipliers, so lam+ has no
!> alternating mode of its own). The trapezoidal q' is the average of the rotation rates, so the
!> quaternions' norm drifts at the order of the step's error; the rotation is read from
!> p / |p| and the projection below restores |p| = 1.
!>
!> Projected form. After Newton the state is projected as the projection formulation does it
!> (mbdk_spatial_model's post_step: positions onto |Phi| <= projection_tol, velocities onto
!> C w + Phi_t = 0, quaternions to unit norm), and a+ and lam+ are the model's constrained
!> solve at (q+, w+): a+ keeps C a = gamma, and the next step starts from it. Without these
!> projections the trapezoidal velocities and accelerations violate the velocity and
!> acceleration rows with errors that alternate in sign and grow (Cardona and Geradin 1989;
!> the planar index3 formulation shows it), so the spatial form is offered projected only.
!> It is second order in q and w (tests/test_spatial.py measures it).
!>
!> Newton. The unknowns are the step's increments and the scaled multipliers, x = [q+ - q;
!> w+ - w; s lam+], s = h^2/4. With lam+ itself the multipliers' pivots are O(h^2) and the
!> matrix's condition grows like h^-2 (the planar scheme scales its unknown the same way).
!> With q+ itself, the residual q+ - q - (h/2)(..) carries the roundoff of q+, eps |q|, and
!> the velocities, which follow from positions as (2/h)(q+ - q), inherit 2 eps |q| / h, which
!> passes any fixed tolerance as h shrinks and, the rounding of slowly varying positions being
!> correlated from step to step, adds up; the increments carry eps |dq|.
!> The predictor is second order, h q' + (h^2/2) q'' with q'' from the last two steps' rates
!> (likewise w and lam); the first step's is h q', h a, lam. The residual's Jacobian by
!> forward differences (one residual evaluation per column), factorised by LAPACK's LU and
!> kept across iterations and steps while Newton contracts: rebuilt at the current iterate
!> when what is judged below grows by more than half or converges too slowly for the
!> iterations left, and when a try fails with an old matrix (the step then restarts from the
!> first-order predictor with a matrix built there). A fast spin turns the multipliers'
!> columns M^-1 C^T with the bodies and makes old matrices fail sooner
!> (studies/spatial_scenes.py counts them as njev).
!> The stopping test. A step converges when max |Phi_a| <= newton_atol at the iterate (not
!> below 64 eps times the model's length) and the update computed there, that last update
!> applied, is small in the norm max |dx_i| / (tau (newton_atol + newton_rtol |y+_i|)) over q
!> and w (not below CORRECTION_SHARE newton_atol: a state at zero by symmetry has no scale of
!> its own), where tau = min(1, CORRECTION_SHARE c), c the largest correction of the positions
!> from their predictor in the same weights: below what the options ask, Newton's error is
!> held to a thousandth of the step's own correction (an estimate of its local error), so
!> that what Newton leaves per step, which adds up over the 1/h steps, stays below the
!> truncation error as h shrinks (a fixed relative tolerance left per step adds up to N times
!> it, growing like 1/h). Where the constraint rows hold and the update
!> does not pass, what is judged is its part from the kinematic and dynamic rows alone (the
!> constraint rows' roundoff eps L moves the velocities across the constraints by (2/h) eps L,
!> and the velocity projection after the step takes that away), against a tolerance never
!> below that part's floor (mbdk_newton_floor, from the roundoff of the rows' terms, the
!> model's acc_abs, and of y + dy, estimated once per try with the current matrix; and a few
!> ulps of y + dy itself, which the state cannot resolve below). An
!> iteration that stops contracting within the options' tolerance has met roundoff the
!> floor's estimate misses: it is accepted when the matrix is fresh, and when old if the
!> stall lies within STALL_ACCEPT times the tolerance or the level a fresh matrix last
!> stalled at (decaying back by STALL_DECAY per step), so that old matrices are not rebuilt
!> in vain. So each h from 1e-2 to 1e-6 converges at second order down to the roundoff
!> plateau on the built-in scenes (tests/test_floor.py, from 1e-3; studies/spatial_scenes.py,
!> table spatial_index3_small_steps), on any BLAS kernel.
!> Each try takes
!> at most max(newton_max_iter, 20) updates (the simplified iteration converges linearly); two
!> failed tries: MBDK_ERR_NEWTON_DIVERGED; a singular matrix (rows lost their rank):
!> MBDK_ERR_SINGULAR_MATRIX.
!>
!> Fixed step only (opt%h, opt%every); the interrupt flag and the progress store are polled once
!> per step, the watch is called after every step. stats: steps, nfev (residual evaluations,
!> difference columns included), njev (Jacobians), nlu, newton_iterations, newton_failures.
module mbdk_spatial_index3
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_clock, only: mbdk_timer_t, mbdk_timer_start, mbdk_timer_stop
  use mbdk_interrupt, only: mbdk_interrupted, mbdk_progress
  use mbdk_lapack, only: mbdk_lu_factor, mbdk_lu_solve
  use mbdk_newton_floor, only: mbdk_floor_solve, mbdk_floor_from_probes, mbdk_floor_cap, &
    MBDK_FLOOR_FACTOR
  use mbdk_fixed_step, only: mbdk_step_plan
  use mbdk_spatial_model, only: mbdk_spatial_model_t, mbdk_spatial_dae_rhs, &
    mbdk_spatial_multipliers
  use mbdk_mechanism, only: MBDK_FORM_PROJECTION
  implicit none
  private
  public :: mbdk_spatial_index3_solve

  !> an update larger than this fraction of the previous one rebuilds the Newton matrix
  real(dp), parameter :: CONTRACTION_MAX = 0.5_dp
  !> steps between estimates of the update's floor (and at every new matrix)
  integer, parameter :: FLOOR_REFRESH = 16
  !> Newton updates per try at least (the options' newton_max_iter where larger): the simplified
  !> iteration with an old matrix converges linearly
  integer, parameter :: MAXIT_LEAST = 20
  !> a constraint row's roundoff in units of eps times the larger of the model's length and the
  !> positions (a joint's rows add and subtract a few such terms)
  real(dp), parameter :: PHI_ROUNDOFF = 4.0_dp
  !> Newton's error is held to this share of the step's correction from its predictor (an
  !> estimate of the local error) where that is below the options' tolerance
  real(dp), parameter :: CORRECTION_SHARE = 1.0e-3_dp
  !> an iteration whose updates stop contracting within this many times its tolerance has
  !> met roundoff the floor's estimate missed, not a matrix too old (at least: the level
  !> is learnt from stalls with fresh matrices, and decays back by STALL_DECAY per step)
  real(dp), parameter :: STALL_ACCEPT = 16.0_dp, STALL_DECAY = 0.999_dp

contains

  !> Integrates model (built with the projection formulation) from (t0, y0), a consistent state,
  !> to t_end with step opt%h; t_out(nsamp), y_out(n, nsamp) receive the samples every opt%every
  !> steps and the last.
  subroutine mbdk_spatial_index3_solve(model, opt, t0, t_end, y0, t_out, y_out, nwritten, st, &
                                       stat)
    type(mbdk_spatial_model_t), intent(in) :: model
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_end, y0(:)
    real(dp), intent(out) :: t_out(:), y_out(:, :)
    integer, intent(out) :: nwritten
    type(mbdk_stats_t), intent(out) :: st
    integer, intent(out) :: stat

    integer :: ny, nq, na, nx, nsamp, plan_stat, maxit, it, tries
    integer(i8) :: nsteps, i, floor_step
    logical :: shortened, sample, fresh, have_lu, done, have_prev, phi_ok, phi_was_ok, have_floor
    real(dp) :: t, t1, h, rtol, atol, phi_tol, dnorm, dprev, hprev, dtol, stall_level
    real(dp), allocatable :: y(:), f(:), x(:), r(:), dx(:), jac(:, :), lam(:), lamfull(:), &
      phi(:), xp(:), rp(:), fprev(:), lamprev(:), floor(:), floor_probe(:), wt(:), wt_strict(:), &
      e(:), b1(:), b2(:), dyn(:), e_state(:), g(:), gabs(:)
    integer, allocatable :: ipiv(:), rows(:)
    type(mbdk_timer_t) :: timer

    nwritten = 0
    ny = size(y0)
    nq = ny - 6 * model%nb
    stat = MBDK_ERR_NOT_APPLICABLE
    if (model%opt%formulation /= MBDK_FORM_PROJECTION) return
    stat = MBDK_ERR_INVALID_INPUT
    if (ny /= model%n .or. nq < 1) return
    call mbdk_step_plan(t0, t_end, opt%h, opt%every, nsteps, nsamp, shortened, plan_stat)
    if (mbdk_is_failure(plan_stat)) then
      stat = plan_stat
      return
    end if
    stat = MBDK_ERR_OUTPUT_SIZE
    if (size(t_out) < nsamp .or. size(y_out, 1) /= ny .or. size(y_out, 2) < nsamp) return
    rows = model%work%active
    na = size(rows)
    nx = ny + na
    rtol = opt%newton_rtol
    atol = opt%newton_atol
    maxit = max(opt%newton_max_iter, MAXIT_LEAST)
    stall_level = STALL_ACCEPT
    have_floor = .false.
    floor_step = 0
    phi_tol = max(atol, 64.0_dp * epsilon(1.0_dp) * model%length)
    allocate (y(ny), f(ny), x(nx), r(nx), dx(nx), jac(nx, nx), lam(na), lamfull(model%m), &
              phi(model%m), xp(nx), rp(nx), ipiv(nx), fprev(ny), lamprev(na), floor(ny), &
              floor_probe(ny), wt(ny), wt_strict(ny), e(nx), b1(nx), b2(nx), &
              dyn(nx), e_state(nx), g(ny), gabs(6 * model%nb), stat=it)
    call mbdk_alloc_status(it, MBDK_REAL_BYTES * (real(nx, dp) * (nx + 10) + 8.0_dp * ny + &
                           2.0_dp * na + 2.0_dp * model%m + 6.0_dp * model%nb) + &
                           MBDK_INT_BYTES * nx, stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return

    call mbdk_timer_start(timer)
    call run(stat)
    call mbdk_timer_stop(timer, st)
    if (stat == MBDK_SUCCESS .and. shortened) stat = MBDK_NOTE_LAST_STEP_SHORTENED

  contains

    !> the time loop (the module header)
    subroutine run(s)
      integer, intent(out) :: s
      t = t0
      st%t_reached = t0
      y = y0
      call start_of_step(t, y, f, lam, s)
      if (s /= MBDK_SUCCESS) return
      if (model%has_watch) then
        call model%watch_start(t0, y, s)
        if (s /= MBDK_SUCCESS) return
      end if
      nwritten = 1
      t_out(1) = t0
      y_out(:, 1) = y0
      have_lu = .false.
      have_prev = .false.
      do i = 1, nsteps
        if (opt%interrupt /= 0 .and. mbdk_interrupted(opt%interrupt)) then
          s = MBDK_ERR_INTERRUPTED
          return
        end if
        t1 = t0 + real(i, dp) * opt%h
        if (opt%progress /= 0) call mbdk_progress(opt%progress, t1)
        if (i == nsteps) t1 = t_end
        h = t1 - t
        sample = mod(i, int(opt%every, i8)) == 0 .or. i == nsteps
        stall_level = max(STALL_ACCEPT, STALL_DECAY * stall_level)
        call newton(done, s)
        if (s /= MBDK_SUCCESS) return
        if (.not. done) then
          s = MBDK_ERR_NEWTON_DIVERGED
          return
        end if
        y = y + x(1:ny)
        t = t1
        fprev = f
        lamprev = lam
        hprev = h
        have_prev = .true.
        call model%post_step(t, y, s)
        if (s /= MBDK_SUCCESS) return
        call start_of_step(t, y, f, lam, s)
        if (s /= MBDK_SUCCESS) return
        st%steps = st%steps + 1
        if (model%has_watch) then
          call model%watch(t, y, sample, s)
          if (s /= MBDK_SUCCESS) return
        end if
        st%t_reached = t            ! the step passed its checks
        if (sample) then
          nwritten = nwritten + 1
          t_out(nwritten) = t
          y_out(:, nwritten) = y
        end if
      end do
    end subroutine run

    !> One step's Newton iteration from the predictor into x (the increments of y and s lam+);
    !> converged: whether it did. With an old matrix that stops contracting, the matrix is
    !> rebuilt at the iterate; a try that still fails restarts once from the predictor with a
    !> matrix built there.
    subroutine newton(converged, s)
      logical, intent(out) :: converged
      integer, intent(out) :: s
      real(dp) :: tau
      converged = .false.
      s = MBDK_SUCCESS
      do tries = 1, 2
        if (have_prev .and. tries == 1) then     ! second order: f' taken from the last step
          xp(1:ny) = h * f + 0.5_dp * h * (h / hprev) * (f - fprev)
          xp(ny + 1:) = lam + (h / hprev) * (lam - lamprev)
        else
          xp(1:ny) = h * f
          xp(ny + 1:) = lam
        end if
        xp(ny + 1:) = 0.25_dp * h * h * xp(ny + 1:)    ! the unknown is (h^2/4) lam
        x = xp
        fresh = .false.
        if (.not. have_lu) then
          call build_matrix(x, s)
          if (s /= MBDK_SUCCESS) return
          have_lu = .true.
          fresh = .true.
        end if
        dprev = huge(1.0_dp)
        phi_was_ok = .false.
        ! the floor, estimated once per matrix and FLOOR_REFRESH steps (the residual's terms
        ! change little from step to step; two solves each time)
        if (i - floor_step >= FLOOR_REFRESH) have_floor = .false.
        do it = 1, maxit
          call residual(x, r, s, e)
          if (s /= MBDK_SUCCESS) return
          dx = -r
          call mbdk_lu_solve(jac, ipiv, dx, s)
          if (s /= MBDK_SUCCESS) return
          st%newton_iterations = st%newton_iterations + 1
          x = x + dx
          ! the tolerance: the options', or a share of the step's correction where that is
          ! smaller (module header)
          wt = atol + rtol * abs(y + x(1:ny))
          tau = min(1.0_dp, CORRECTION_SHARE * maxval(abs(x(1:nq) - xp(1:nq)) / wt(1:nq)))
          wt_strict = max(tau * wt, CORRECTION_SHARE * atol)
          dnorm = maxval(abs(dx(1:ny)) / wt_strict)
          dtol = huge(1.0_dp)
          phi_ok = maxval(abs(r(ny + 1:))) <= phi_tol
          if (phi_ok .and. dnorm > 1.0_dp) then
            ! the constraint rows hold, and the update does not pass: its part from the
            ! constraint rows' roundoff moves the velocities across the constraints by up to
            ! (2/h) eps L, which the velocity projection after the step takes away; what is
            ! judged is the rest, from the kinematic and dynamic rows alone, against a
            ! tolerance never below its floor
            dyn(1:ny) = -r(1:ny)
            dyn(ny + 1:) = 0.0_dp
            call mbdk_lu_solve(jac, ipiv, dyn, s)
            if (s /= MBDK_SUCCESS) return
            if (.not. have_floor) then
              call update_floor(s)
              if (s /= MBDK_SUCCESS) return
              have_floor = .true.
              floor_step = i
            end if
            ! the floor: the update's roundoff (the probes), and the state's own: y + dy is not
            ! resolved below a few ulps of it
            floor = max(floor_probe, MBDK_FLOOR_FACTOR * epsilon(1.0_dp) * abs(y + x(1:ny)))
            dtol = maxval(abs(dyn(1:ny)) / max(wt, floor))
            dnorm = maxval(abs(dyn(1:ny)) / max(wt_strict, floor))
          end if
          if (dnorm <= 1.0_dp .and. phi_ok) then
            converged = .true.
            return
          end if
          ! the contraction: of what is judged, from the iterate where the constraint rows
          ! first hold (before that the whole update, dominated by them, contracts)
          if (phi_ok .neqv. phi_was_ok) dprev = huge(1.0_dp)
          phi_was_ok = phi_ok
          ! rebuilt when contracting slowly, or too slowly to converge in the iterations left
          if (it > 1 .and. (dnorm > CONTRACTION_MAX * dprev .or. &
                            dnorm * (dnorm / dprev)**(maxit - it) > 1.0_dp)) then
            ! stalled where updates have stalled before (roundoff that the floor's estimate
            ! misses), or with a matrix of this step, within the options' tolerance; the
            ! level a fresh matrix stalls at is remembered, so that an old one stalling there
            ! is not rebuilt in vain
            if (phi_ok .and. dtol <= 1.0_dp .and. (dnorm <= stall_level .or. fresh)) then
              if (fresh) stall_level = max(stall_level, 2.0_dp * dnorm)
              converged = .true.
              return
            end if
            if (fresh) exit                 ! a matrix of this step: no better one to build
            call build_matrix(x, s)         ! an old matrix: rebuilt where Newton stands
            if (s /= MBDK_SUCCESS) return
            fresh = .true.
            have_floor = .false.
            dprev = huge(1.0_dp)
            cycle
          end if
          dprev = dnorm
        end do
        st%newton_failures = st%newton_failures + 1
        have_lu = .false.
      end do
    end subroutine newton

    !> f = [T(q) w; a] and the multipliers of the independent rows at a consistent (t, y)
    subroutine start_of_step(ts, ys, fs, lams, s)
      real(dp), intent(in) :: ts, ys(:)
      real(dp), intent(out) :: fs(:), lams(:)
      integer, intent(out) :: s
      call model%rhs(ts, ys, fs, s)
      st%nfev = st%nfev + 1
      if (s /= MBDK_SUCCESS .or. na == 0) return
      call mbdk_spatial_multipliers(model, ts, ys, lamfull, s)
      if (s /= MBDK_SUCCESS) return
      ! a redundant scene's model moves to another set of independent rows where the one it
      ! keeps nears a rank loss: Newton follows it (a one-step method has no history to keep)
      if (size(model%work%active) /= na) then
        s = MBDK_ERR_SINGULAR_MATRIX
        return
      end if
      if (any(model%work%active /= rows)) then
        rows = model%work%active
        have_lu = .false.
        have_prev = .false.
      end if
      lams = lamfull(rows)
    end subroutine start_of_step

    !> the step's residual at xs = [dq; dw; s lam+] (t, y, f, h, t1 of the host), and on
    !> request the roundoff of its evaluation: eps times the magnitudes of each row's terms
    subroutine residual(xs, rs, s, noise)
      real(dp), intent(in) :: xs(:)
      real(dp), intent(out) :: rs(:)
      integer, intent(out) :: s
      real(dp), intent(out), optional :: noise(:)
      lamfull = 0.0_dp
      lamfull(rows) = xs(ny + 1:) / (0.25_dp * h * h)
      call mbdk_spatial_dae_rhs(model, t1, y + xs(1:ny), lamfull, g, phi, s, gabs)
      st%nfev = st%nfev + 1
      if (s /= MBDK_SUCCESS) return
      rs(1:ny) = xs(1:ny) - 0.5_dp * h * (f + g)
      rs(ny + 1:) = phi(rows)
      if (present(noise)) then
        noise(1:ny) = abs(xs(1:ny)) + 0.5_dp * h * (abs(f) + abs(g))
        noise(nq + 1:ny) = noise(nq + 1:ny) + h * gabs      ! the accelerations' terms, both ends
        noise(1:ny) = epsilon(1.0_dp) * noise(1:ny) + e_state(1:ny)
        noise(ny + 1:) = PHI_ROUNDOFF * epsilon(1.0_dp) * &
                         max(model%length, maxval(abs(y(1:nq))))
      end if
    end subroutine residual

    !> the floor of the update's dynamic part (mbdk_newton_floor) from the roundoff e of the
    !> kinematic and dynamic rows, with the current matrix
    subroutine update_floor(s)
      integer, intent(out) :: s
      e(ny + 1:) = 0.0_dp
      call mbdk_floor_solve(e, jac, ipiv, b1, b2, s)
      if (s /= MBDK_SUCCESS) return
      call mbdk_floor_from_probes(b1(1:ny), b2(1:ny), floor_probe)
      call mbdk_floor_cap(y + x(1:ny), floor_probe)
    end subroutine update_floor

    !> the residual's Jacobian at xs by forward differences, factorised
    subroutine build_matrix(xs, s)
      real(dp), intent(in) :: xs(:)
      integer, intent(out) :: s
      real(dp), allocatable :: r0(:), xj(:)
      real(dp) :: del
      integer :: j
      allocate (r0(nx), xj(nx), stat=j)
      call mbdk_alloc_status(j, 2 * MBDK_REAL_BYTES * nx, s)
      if (s /= MBDK_SUCCESS) return
      call residual(xs, r0, s)
      if (s /= MBDK_SUCCESS) return
      xj = xs
      do j = 1, nx
        del = sqrt(epsilon(1.0_dp)) * max(abs(xs(j)), 1.0_dp)
        xj(j) = xs(j) + del
        call residual(xj, rp, s)
        if (s /= MBDK_SUCCESS) return
        jac(:, j) = (rp - r0) / del
        xj(j) = xs(j)
      end do
      ! the rounding of y + dy, eps |y|, in the residual's rows: |J - I| eps |y|
      e_state = 0.0_dp
      do j = 1, ny
        del = epsilon(1.0_dp) * abs(y(j))
        e_state = e_state + del * abs(jac(:, j))
        e_state(j) = e_state(j) + del * (abs(jac(j, j) - 1.0_dp) - abs(jac(j, j)))
      end do
      st%njev = st%njev + 1
      call mbdk_lu_factor(jac, ipiv, s)
      st%nlu = st%nlu + 1
    end subroutine build_matrix

  end subroutine mbdk_spatial_index3_solve

end module mbdk_spatial_index3
