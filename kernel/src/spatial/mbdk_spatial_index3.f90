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
!> Newton. The unknowns x = [q+; w+; s lam+], s = h^2/4: with lam+ itself the multipliers'
!> pivots are O(h^2) and the matrix's condition grows like h^-2, so that at small steps the
!> roundoff of the updates exceeds the tolerance (the planar scheme scales its unknown the same
!> way). The predictor is second order, q + h q' + (h^2/2) q'' with q'' from
!> the last two steps' rates (likewise w and lam); the first step's is q + h q', w + h a, lam.
!> The residual's Jacobian by forward differences (one residual evaluation per column),
!> factorised by LAPACK's LU and kept across iterations and steps while Newton contracts:
!> rebuilt at the current iterate when an update is more than half the previous one or too
!> slow to converge within the iterations left, and when a try fails with an old matrix (the
!> step then restarts from the first-order predictor with a matrix built there). A fast spin
!> turns the multipliers' columns M^-1 C^T with the bodies and makes old matrices fail sooner
!> (studies/spatial_scenes.py counts them as njev). A step converges when an update is below 1
!> in the norm max |dx_i| / (newton_atol + newton_rtol |x_i|) over q and w and max |Phi_a| <=
!> newton_atol there (not below 64 eps times the model's length), that last update applied.
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
  use mbdk_fixed_step, only: mbdk_step_plan
  use mbdk_spatial_model, only: mbdk_spatial_model_t, mbdk_spatial_dae_rhs, &
    mbdk_spatial_multipliers, MBDK_SPATIAL_PROJECTION
  implicit none
  private
  public :: mbdk_spatial_index3_solve

  !> an update larger than this fraction of the previous one rebuilds the Newton matrix
  real(dp), parameter :: CONTRACTION_MAX = 0.5_dp
  !> Newton updates per try at least (the options' newton_max_iter where larger): the simplified
  !> iteration with an old matrix converges linearly
  integer, parameter :: MAXIT_LEAST = 20

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
    integer(i8) :: nsteps, i
    logical :: shortened, sample, fresh, have_lu, done, have_prev
    real(dp) :: t, t1, h, rtol, atol, phi_tol, dnorm, dprev, hprev
    real(dp), allocatable :: y(:), f(:), x(:), r(:), dx(:), jac(:, :), lam(:), lamfull(:), &
      phi(:), xp(:), rp(:), fprev(:), lamprev(:)
    integer, allocatable :: ipiv(:), rows(:)
    type(mbdk_timer_t) :: timer

    nwritten = 0
    ny = size(y0)
    nq = ny - 6 * model%nb
    stat = MBDK_ERR_NOT_APPLICABLE
    if (model%opt%formulation /= MBDK_SPATIAL_PROJECTION) return
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
    phi_tol = max(atol, 64.0_dp * epsilon(1.0_dp) * model%length)
    allocate (y(ny), f(ny), x(nx), r(nx), dx(nx), jac(nx, nx), lam(na), lamfull(model%m), &
              phi(model%m), xp(nx), rp(nx), ipiv(nx), fprev(ny), lamprev(na), stat=it)
    call mbdk_alloc_status(it, MBDK_REAL_BYTES * (real(nx, dp) * (nx + 5) + 3.0_dp * ny + &
                           2.0_dp * na + 2.0_dp * model%m) + MBDK_INT_BYTES * nx, stat, &
                           st%alloc_bytes)
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
        call newton(done, s)
        if (s /= MBDK_SUCCESS) return
        if (.not. done) then
          s = MBDK_ERR_NEWTON_DIVERGED
          return
        end if
        y = x(1:ny)
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
        if (sample) then
          nwritten = nwritten + 1
          t_out(nwritten) = t
          y_out(:, nwritten) = y
        end if
      end do
    end subroutine run

    !> One step's Newton iteration from the predictor into x; converged: whether it did. With
    !> an old matrix that stops contracting, the matrix is rebuilt at the iterate; a try that
    !> still fails restarts once from the predictor with a matrix built there.
    subroutine newton(converged, s)
      logical, intent(out) :: converged
      integer, intent(out) :: s
      converged = .false.
      s = MBDK_SUCCESS
      do tries = 1, 2
        if (have_prev .and. tries == 1) then     ! second order: f' taken from the last step
          xp(1:ny) = y + h * f + 0.5_dp * h * (h / hprev) * (f - fprev)
          xp(ny + 1:) = lam + (h / hprev) * (lam - lamprev)
        else
          xp(1:ny) = y + h * f
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
        do it = 1, maxit
          call residual(x, r, s)
          if (s /= MBDK_SUCCESS) return
          dx = -r
          call mbdk_lu_solve(jac, ipiv, dx, s)
          if (s /= MBDK_SUCCESS) return
          st%newton_iterations = st%newton_iterations + 1
          dnorm = maxval(abs(dx(1:ny)) / (atol + rtol * abs(x(1:ny))))
          x = x + dx
          if (dnorm <= 1.0_dp .and. maxval(abs(r(ny + 1:))) <= phi_tol) then
            converged = .true.
            return
          end if
          ! rebuilt when contracting slowly, or too slowly to converge in the iterations left
          if (it > 1 .and. (dnorm > CONTRACTION_MAX * dprev .or. &
                            dnorm * (dnorm / dprev)**(maxit - it) > 1.0_dp)) then
            if (fresh) exit                 ! a matrix of this step: no better one to build
            call build_matrix(x, s)         ! an old matrix: rebuilt where Newton stands
            if (s /= MBDK_SUCCESS) return
            fresh = .true.
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

    !> the step's residual at xs = [q+; w+; lam+] (t, y, f, h, t1 of the host)
    subroutine residual(xs, rs, s)
      real(dp), intent(in) :: xs(:)
      real(dp), intent(out) :: rs(:)
      integer, intent(out) :: s
      real(dp), allocatable :: g(:)
      integer :: astat
      allocate (g(ny), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * ny, s)
      if (s /= MBDK_SUCCESS) return
      lamfull = 0.0_dp
      lamfull(rows) = xs(ny + 1:) / (0.25_dp * h * h)
      call mbdk_spatial_dae_rhs(model, t1, xs(1:ny), lamfull, g, phi, s)
      st%nfev = st%nfev + 1
      if (s /= MBDK_SUCCESS) return
      rs(1:ny) = xs(1:ny) - y - 0.5_dp * h * (f + g)
      rs(ny + 1:) = phi(rows)
    end subroutine residual

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
      st%njev = st%njev + 1
      call mbdk_lu_factor(jac, ipiv, s)
      st%nlu = st%nlu + 1
    end subroutine build_matrix

  end subroutine mbdk_spatial_index3_solve

end module mbdk_spatial_index3
