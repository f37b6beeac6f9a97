!> One entry for every ODE solve: a fixed-step method goes to mbdk_fixed_step (step opt%h,
!> every-th step sampled), an error-controlled one (mbdk_method_adaptive: dopri54, bs32, bdf,
!> cvode_bdf, cvode_adams) to its own driver with the samples of mbdk_adaptive (rtol, atol,
!> dt_out). The C API, the f2py layer and the scene runner call this, so a new method is one
!> case here and one registry line.
!>
!> For an error-controlled method this routine checks the options and atol, writes the sample
!> times into t_out and the first sample, starts a watching problem's watch at t0, and times the
!> solve (the thread's CPU time and the wall time in st); the method writes samples 2, 3, ...
!> mbdk_solve_dae does the same for ida and for bdf on a mechanism's DAE itself (ida is a
!> method of a mechanism only, not of y' = F(t, y): mbdk_solve_ode refuses it,
!> MBDK_ERR_NOT_APPLICABLE).
module mbdk_solve
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_clock, only: mbdk_timer_t, mbdk_timer_start, mbdk_timer_stop
  use mbdk_methods, only: mbdk_method_info, mbdk_method_adaptive, MBDK_FAMILY_EMBEDDED_RK, &
    MBDK_FAMILY_VARIABLE_BDF, MBDK_FAMILY_CVODE, MBDK_FAMILY_IDA, MBDK_CVODE_ADAMS, &
    MBDK_METHOD_NAME_LEN
  use mbdk_fixed_step, only: mbdk_fixed_step_solve, mbdk_step_plan
  use mbdk_adaptive, only: mbdk_adaptive_plan, mbdk_adaptive_times, mbdk_adaptive_check
  use mbdk_embedded_rk, only: mbdk_embedded_rk_solve
  use mbdk_variable_bdf, only: mbdk_variable_bdf_solve
  use mbdk_cvode, only: mbdk_cvode_solve
  use mbdk_mechanism, only: mbdk_mechanism_t, MBDK_FORM_REDUCED
  use mbdk_ida, only: mbdk_ida_solve
  use mbdk_mechanism_dae, only: mbdk_mechanism_dae_t, mbdk_mechanism_dae_init, &
    mbdk_mechanism_dae_residuals, MBDK_DAE_I3, &
    MBDK_DAE_SI2
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  implicit none
  private
  public :: mbdk_solve_ode, mbdk_sample_plan, mbdk_solve_dae

  !> bdf on a mechanism's DAE: |Phi(q0)| and |C v0 + Phi_t| (per unit of |v0|) a consistent start
  !> keeps; the assembly of mbdk_model_start reaches 1e-12
  real(dp), parameter :: CONSISTENT_PHI = 1.0e-10_dp

contains

  !> Samples a solve with opt over [t0, t_end] writes (fixed step: mbdk_step_plan with opt%h and
  !> opt%every; error-controlled: mbdk_adaptive_plan with opt%dt_out). stat: as those.
  subroutine mbdk_sample_plan(opt, t0, t_end, nsamp, stat)
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_end
    integer, intent(out) :: nsamp, stat
    integer(i8) :: nsteps
    logical :: shortened
    if (mbdk_method_adaptive(opt%method)) then
      call mbdk_adaptive_plan(t0, t_end, opt%dt_out, nsamp, stat)
    else
      call mbdk_step_plan(t0, t_end, opt%h, opt%every, nsteps, nsamp, shortened, stat)
    end if
  end subroutine mbdk_sample_plan

  !> Integrates prob from (t0, y0) to t_end with opt%method. t_out(nsamp), y_out(n, nsamp)
  !> receive the samples (nsamp from mbdk_sample_plan); nwritten: how many were written (fewer
  !> only on failure). atol (optional, error-controlled methods): one absolute tolerance per
  !> state instead of opt%atol. times (optional, error-controlled methods; size 0: absent): the
  !> sample times themselves instead of opt%dt_out's grid, strictly increasing from t0 to
  !> t_end (nsamp = size(times)), each written from the method's dense output as the grid's
  !> are; MBDK_ERR_INVALID_INPUT otherwise, and for a fixed-step method.
  subroutine mbdk_solve_ode(prob, opt, t0, t_end, y0, t_out, y_out, nwritten, st, stat, atol, &
                            times)
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_end
    real(dp), intent(in) :: y0(:)
    real(dp), intent(out) :: t_out(:)
    real(dp), intent(out) :: y_out(:, :)
    integer, intent(out) :: nwritten
    type(mbdk_stats_t), intent(out) :: st
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: atol(:), times(:)

    character(len=MBDK_METHOD_NAME_LEN) :: name
    integer :: family, order, nsamp, astat
    real(dp), allocatable :: atol_v(:)
    type(mbdk_timer_t) :: timer
    logical :: given

    given = .false.
    if (present(times)) given = size(times) > 0
    if (.not. mbdk_method_adaptive(opt%method)) then
      stat = MBDK_ERR_INVALID_INPUT
      nwritten = 0
      if (present(atol)) then
        if (size(atol) > 0) return   ! a tolerance means nothing to a fixed step
      end if
      if (given) return              ! its samples are on its grid of steps
      call mbdk_fixed_step_solve(prob, opt, t0, t_end, y0, t_out, y_out, nwritten, st, stat)
      return
    end if

    call mbdk_method_info(opt%method, name, family, order)
    nwritten = 0
    stat = MBDK_ERR_NOT_APPLICABLE   ! ida integrates a mechanism's DAE: mbdk_solve_dae
    if (family == MBDK_FAMILY_IDA) return
    stat = MBDK_ERR_INVALID_INPUT    ! a one-order method has no max_order to cap
    if (opt%max_order > max_order_of(family, order)) return
    if (present(atol)) then
      allocate (atol_v(size(atol)), stat=astat)
    else
      allocate (atol_v(0), stat=astat)
    end if
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * size(atol_v), stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    if (present(atol)) atol_v = atol
    if (given) then
      call prologue(prob, opt, t0, t_end, y0, atol_v, t_out, y_out, nwritten, nsamp, timer, &
                    stat, times)
    else
      call prologue(prob, opt, t0, t_end, y0, atol_v, t_out, y_out, nwritten, nsamp, timer, &
                    stat)
    end if
    if (stat /= MBDK_SUCCESS .or. nwritten == 0) return
    select case (family)
    case (MBDK_FAMILY_EMBEDDED_RK)
      call mbdk_embedded_rk_solve(prob, opt, t0, y0, atol_v, t_out(1:nsamp), y_out, nwritten, &
                                  st, stat)
    case (MBDK_FAMILY_VARIABLE_BDF)
      call mbdk_variable_bdf_solve(prob, opt, t0, y0, atol_v, t_out(1:nsamp), y_out, nwritten, &
                                   st, stat)
    case (MBDK_FAMILY_CVODE)
      call mbdk_cvode_solve(prob, opt, opt%method == MBDK_CVODE_ADAMS, t0, y0, atol_v, &
                            t_out(1:nsamp), y_out, nwritten, st, stat)
    case default
      stat = MBDK_ERR_UNKNOWN_METHOD
    end select
    call mbdk_timer_stop(timer, st)
  end subroutine mbdk_solve_ode

  !> A mechanism's DAE itself (mbdk_mechanism_dae, mbdk_ida): ida in form 1 (index 1) or 2
  !> (GGL), or bdf in form 1 (index 3, as GSTIFF I3) or 2 (stabilised index 2, as SI2).
  !> y0 = [q0; v0] consistent (assembled); samples [q; v] in y_out and the multipliers in
  !> lam_out (m rows, zero on the rows a redundant scene leaves out; the columns it has). The
  !> mechanism must be built with the reduced formulation, whose solve gives the consistent
  !> initial accelerations and multipliers. bdf: a start off the joints (|Phi| or
  !> |C v + Phi_t| above CONSISTENT_PHI) is MBDK_ERR_INCONSISTENT_INITIAL; ida checks its own
  !> form's residual (mbdk_ida: index1 not Phi).
  subroutine mbdk_solve_dae(mech, opt, form, t0, t_end, y0, t_out, y_out, lam_out, nwritten, &
                            st, stat)
    class(mbdk_mechanism_t), intent(in), target :: mech
    type(mbdk_options_t), intent(in) :: opt
    integer, intent(in) :: form
    real(dp), intent(in) :: t0, t_end, y0(:)
    real(dp), intent(out) :: t_out(:), y_out(:, :)
    real(dp), intent(inout) :: lam_out(:, :)
    integer, intent(out) :: nwritten
    type(mbdk_stats_t), intent(out) :: st
    integer, intent(out) :: stat
    character(len=MBDK_METHOD_NAME_LEN) :: name
    integer :: family, order, nsamp
    real(dp) :: no_atol(0)
    type(mbdk_timer_t) :: timer
    nwritten = 0
    call mbdk_method_info(opt%method, name, family, order)
    stat = MBDK_ERR_NOT_APPLICABLE
    if (family /= MBDK_FAMILY_IDA .and. family /= MBDK_FAMILY_VARIABLE_BDF) return
    stat = MBDK_ERR_INVALID_INPUT
    if (form /= MBDK_DAE_I3 .and. form /= MBDK_DAE_SI2) return
    if (opt%max_order > max_order_of(family, order)) return
    call prologue(mech, opt, t0, t_end, y0, no_atol, t_out, y_out, nwritten, nsamp, timer, stat)
    if (stat /= MBDK_SUCCESS .or. nwritten == 0) return
    if (family == MBDK_FAMILY_IDA) then
      call mbdk_ida_solve(mech, opt, form == MBDK_DAE_SI2, t0, y0, t_out(1:nsamp), y_out, &
                          lam_out, nwritten, st, stat)
    else
      call bdf_on_dae(stat)
    end if
    call mbdk_timer_stop(timer, st)

  contains

    !> bdf on E Y' = G(t, Y) of mbdk_mechanism_dae, from the consistent Y(0) and Y'(0) of the
    !> reduced solve; [q; v] and the multipliers copied out of the DAE's samples.
    subroutine bdf_on_dae(s)
      integer, intent(out) :: s
      type(mbdk_mechanism_dae_t) :: dae
      real(dp), allocatable :: mass(:), yd(:), ypd(:), ys(:, :), lam0(:)
      real(dp) :: phi_max, cv_max
      integer :: nq, nv, ny, m, na, k, astat
      nq = mech%ncoord
      nv = mech%nvel
      ny = nq + nv
      m = mech%m
      if (mech%formulation /= MBDK_FORM_REDUCED) then
        s = MBDK_ERR_NOT_APPLICABLE
        return
      end if
      allocate (lam0(m), ypd(ny), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (real(m, dp) + ny), s, st%alloc_bytes)
      if (s /= MBDK_SUCCESS) return
      ! the consistent rates and multipliers; the rows after this solve, which may move a
      ! redundant scene to another set of independent rows
      call mech%accelerations(t0, y0(1:nq), y0(nq + 1:ny), ypd(nq + 1:ny), lam0, s)
      if (s /= MBDK_SUCCESS) return
      call mech%rates(y0(1:nq), y0(nq + 1:ny), ypd(1:nq), s)
      if (s /= MBDK_SUCCESS) return
      call mbdk_mechanism_dae_init(dae, mech, form, mass, s, st%alloc_bytes)
      if (s /= MBDK_SUCCESS) return
      ! a start off the constraints would be projected by the first Newton iteration into a
      ! correction no error test accepts: refused, as ida refuses it
      call mbdk_mechanism_dae_residuals(dae, t0, y0, phi_max, cv_max, s)
      if (s /= MBDK_SUCCESS) return
      s = MBDK_ERR_INCONSISTENT_INITIAL
      if (phi_max > CONSISTENT_PHI) return
      if (cv_max > CONSISTENT_PHI * max(1.0_dp, maxval(abs(y0(nq + 1:ny))))) return
      na = dae%na
      allocate (yd(dae%n), ys(dae%n, nsamp), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * real(dae%n, dp) * (nsamp + 1), s, &
                             st%alloc_bytes)
      if (s /= MBDK_SUCCESS) return
      yd = 0.0_dp
      yd(1:ny) = y0
      yd(ny + 1:ny + na) = lam0(dae%rows)
      ypd = [ypd, spread(0.0_dp, 1, dae%n - ny)]
      ys(:, 1) = yd
      if (form == MBDK_DAE_I3) then
        ! the index-3 form's velocities are index-2 variables: after a rejection their
        ! correction grows like 1/h (the rescaled history misses the constraint by
        ! O(h_old^(q+1))), so i3 tests the positions and h times the velocities' error (the
        ! index-2 practice), not the multipliers'; si2, whose velocities are constrained
        ! themselves, tests both
        call mbdk_variable_bdf_solve(dae, opt, t0, yd, no_atol, t_out(1:nsamp), ys, nwritten, &
                                     st, s, mass=mass, yp0=ypd, ntest=nq, nindex2=nv)
      else
        call mbdk_variable_bdf_solve(dae, opt, t0, yd, no_atol, t_out(1:nsamp), ys, nwritten, &
                                     st, s, mass=mass, yp0=ypd, ntest=ny)
      end if
      do k = 1, nwritten
        y_out(:, k) = ys(1:ny, k)
        if (k <= size(lam_out, 2) .and. size(lam_out, 1) >= m) then
          lam_out(1:m, k) = 0.0_dp
          lam_out(dae%rows, k) = ys(ny + 1:ny + na, k)
        end if
      end do
    end subroutine bdf_on_dae

  end subroutine mbdk_solve_dae

  !> The largest max_order a method takes: its top order for the variable-order ones (bdf,
  !> cvode_*, ida), 0 for the explicit pairs (their order is fixed).
  pure integer function max_order_of(family, order) result(top)
    integer, intent(in) :: family, order
    top = 0
    if (family == MBDK_FAMILY_VARIABLE_BDF .or. family == MBDK_FAMILY_CVODE .or. &
        family == MBDK_FAMILY_IDA) top = order
  end function max_order_of

  !> What every error-controlled solve does before its first step (the module header); on
  !> success nwritten = 1 and the timer runs.
  subroutine prologue(prob, opt, t0, t_end, y0, atol, t_out, y_out, nwritten, nsamp, timer, &
                      stat, times)
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_end, y0(:), atol(:)
    real(dp), intent(out) :: t_out(:), y_out(:, :)
    integer, intent(out) :: nwritten, nsamp, stat
    type(mbdk_timer_t), intent(out) :: timer
    real(dp), intent(in), optional :: times(:)
    integer :: n
    nwritten = 0
    nsamp = 0
    n = prob%n
    stat = MBDK_ERR_INVALID_INPUT
    if (n < 1 .or. size(y0) /= n) return
    if (.not. all(abs(y0) <= huge(1.0_dp))) return
    stat = mbdk_adaptive_check(opt, n, atol)
    if (stat /= MBDK_SUCCESS) return
    if (present(times)) then
      ! the caller's sample times: t0 first, t_end last, strictly increasing (so finite)
      stat = MBDK_ERR_INVALID_INPUT
      nsamp = size(times)
      if (nsamp < 2) return
      if (times(1) /= t0 .or. times(nsamp) /= t_end) return
      if (.not. all(times(2:) > times(:nsamp - 1))) return
    else
      call mbdk_adaptive_plan(t0, t_end, opt%dt_out, nsamp, stat)
      if (stat /= MBDK_SUCCESS) return
    end if
    stat = MBDK_ERR_OUTPUT_SIZE
    if (size(t_out) < nsamp .or. size(y_out, 1) /= n .or. size(y_out, 2) < nsamp) return
    call mbdk_timer_start(timer)
    if (present(times)) then
      t_out(1:nsamp) = times
    else
      call mbdk_adaptive_times(t0, t_end, opt%dt_out, t_out(1:nsamp))
    end if
    stat = MBDK_SUCCESS
    if (prob%has_watch) call prob%watch_start(t0, y0, stat)
    if (stat /= MBDK_SUCCESS) return
    nwritten = 1
    y_out(:, 1) = y0
  end subroutine prologue

end module mbdk_solve
