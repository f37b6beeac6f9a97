!> What every error-controlled ODE method shares (dopri54 and bs32 in mbdk_embedded_rk, bdf in
!> mbdk_variable_bdf, cvode_bdf and cvode_adams in mbdk_cvode): checking the tolerances and step
!> options, the sample times, the error weights, and what happens after an accepted step.
!>
!> Tolerances. The local error estimate e of a step is accepted when
!>   WRMS(e) = sqrt(mean((e_i w_i)^2)) <= 1,   w_i = 1 / (atol_i + rtol |y_i|),
!> SUNDIALS' and SciPy's norm. atol is the scalar opt%atol, or a vector of one entry per state
!> (the solvers' optional argument atol). rtol >= 0 and atol_i > 0, finite (a zero atol_i
!> would give a state passing through 0 an infinite weight), and a positive rtol below 100 eps
!> asks for more than double precision holds: these are MBDK_ERR_INVALID_INPUT, checked before
!> the first step.
!>
!> Samples. Every method steps at its own pace and writes the state at t0, t0 + dt_out,
!> t0 + 2 dt_out, ... and t_end (opt%dt_out = 0: at t0 and t_end only) from its dense output,
!> so a sample costs no step. The last sample is the state of the last step itself.
!>
!> After each accepted step: a problem with has_post_step gets post_step (the projection
!> formulation of scenes; the explicit pairs continue from the projected state with F
!> evaluated there, bdf takes the projection's move into its correction, CVODE refuses such a
!> problem), a non-finite state ends the solve with MBDK_ERR_NONFINITE, and a watching problem
!> checks the step (force = a sample fell in it). The interrupt flag is polled before each step.
!> opt%max_steps (0: MBDK_ADAPTIVE_MAX_STEPS) bounds the accepted and rejected steps together:
!> MBDK_ERR_TOO_MANY_STEPS.
module mbdk_adaptive
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_fixed_step, only: mbdk_step_plan
  implicit none
  private
  public :: mbdk_adaptive_plan, mbdk_adaptive_times, mbdk_adaptive_check, mbdk_adaptive_weights, &
    mbdk_adaptive_after_step, mbdk_adaptive_step_limit, mbdk_adaptive_wrms, &
    mbdk_adaptive_initial_step, mbdk_adaptive_h_floor, mbdk_adaptive_count_order

  !> the default of opt%max_steps
  integer(i8), parameter, public :: MBDK_ADAPTIVE_MAX_STEPS = 100000000_i8
  !> rtol below this many eps asks for more digits than double precision holds
  real(dp), parameter, public :: MBDK_RTOL_FLOOR = 100.0_dp * epsilon(1.0_dp)

contains

  !> Number of samples of an error-controlled solve over [t0, t_end] with spacing dt_out.
  pure subroutine mbdk_adaptive_plan(t0, t_end, dt_out, nsamp, stat)
    real(dp), intent(in) :: t0, t_end, dt_out
    integer, intent(out) :: nsamp, stat
    integer(i8) :: nsteps
    logical :: shortened
    nsamp = 0
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. (abs(t0) <= huge(1.0_dp) .and. abs(t_end) <= huge(1.0_dp))) return
    if (.not. (t_end > t0)) return
    if (.not. (dt_out >= 0.0_dp)) return
    if (dt_out == 0.0_dp .or. dt_out >= t_end - t0) then
      nsamp = 2
      stat = MBDK_SUCCESS
      return
    end if
    call mbdk_step_plan(t0, t_end, dt_out, 1, nsteps, nsamp, shortened, stat)
    if (stat == MBDK_NOTE_LAST_STEP_SHORTENED) stat = MBDK_SUCCESS
  end subroutine mbdk_adaptive_plan

  !> The sample times: t0 + (k-1) dt_out by multiplication, the last one t_end.
  pure subroutine mbdk_adaptive_times(t0, t_end, dt_out, t_out)
    real(dp), intent(in) :: t0, t_end, dt_out
    real(dp), intent(out) :: t_out(:)
    integer :: k, ns
    ns = size(t_out)
    do k = 1, ns
      t_out(k) = t0 + real(k - 1, dp) * dt_out
    end do
    t_out(ns) = t_end
  end subroutine mbdk_adaptive_times

  !> The options an error-controlled method reads, and atol (a scalar: size 0, or one per state).
  pure integer function mbdk_adaptive_check(opt, n, atol) result(stat)
    type(mbdk_options_t), intent(in) :: opt
    integer, intent(in) :: n
    real(dp), intent(in) :: atol(:)
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. (opt%rtol >= 0.0_dp .and. opt%rtol < 1.0_dp)) return
    if (size(atol) == 0) then
      if (.not. (opt%atol > 0.0_dp .and. opt%atol <= huge(1.0_dp))) return
    else
      if (size(atol) /= n) return
      if (.not. all(atol > 0.0_dp .and. atol <= huge(1.0_dp))) return
    end if
    if (opt%rtol > 0.0_dp .and. opt%rtol < MBDK_RTOL_FLOOR) return
    if (.not. (opt%h >= 0.0_dp .and. opt%h <= huge(1.0_dp))) return
    if (.not. (opt%h_min >= 0.0_dp .and. opt%h_min <= huge(1.0_dp))) return
    if (.not. (opt%h_max >= 0.0_dp .and. opt%h_max <= huge(1.0_dp))) return
    if (opt%h_max > 0.0_dp .and. opt%h_min > opt%h_max) return
    if (opt%max_steps < 0 .or. opt%max_order < 0) return
    stat = MBDK_SUCCESS
  end function mbdk_adaptive_check

  !> w = 1 / (atol + rtol |y|).
  pure subroutine mbdk_adaptive_weights(opt, atol, y, w)
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: atol(:), y(:)
    real(dp), intent(out) :: w(:)
    if (size(atol) == 0) then
      w = 1.0_dp / (opt%atol + opt%rtol * abs(y))
    else
      w = 1.0_dp / (atol + opt%rtol * abs(y))
    end if
  end subroutine mbdk_adaptive_weights

  !> sqrt(mean((e w)^2))
  pure real(dp) function mbdk_adaptive_wrms(e, w)
    real(dp), intent(in) :: e(:), w(:)
    mbdk_adaptive_wrms = sqrt(sum((e * w)**2) / real(max(size(e), 1), dp))
  end function mbdk_adaptive_wrms

  !> The most steps (accepted and rejected) a solve may take.
  pure integer(i8) function mbdk_adaptive_step_limit(opt)
    type(mbdk_options_t), intent(in) :: opt
    mbdk_adaptive_step_limit = MBDK_ADAPTIVE_MAX_STEPS
    if (opt%max_steps > 0) mbdk_adaptive_step_limit = opt%max_steps
  end function mbdk_adaptive_step_limit

  !> The first step when opt%h = 0: Hairer, Norsett and Wanner's (Solving ODEs I, II.4) guess
  !> for a method whose error estimate is O(h^(p+1)): h0 = 0.01 |y0|/|f0| in the weighted norm,
  !> one explicit Euler step of h0 to see how fast f changes (one evaluation of F), and
  !> h1 = (0.01 / max(|f0|, |f1 - f0|/h0))^(1/(p+1)); h = min(100 h0, h1), raised to h_min
  !> and cut to span and h_max. opt%h > 0 is taken as given (within span and h_max).
  subroutine mbdk_adaptive_initial_step(prob, opt, atol, p, t0, span, y0, f0, h, nfev, stat)
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: atol(:), t0, span, y0(:), f0(:)
    integer, intent(in) :: p
    real(dp), intent(out) :: h
    integer(i8), intent(inout) :: nfev
    integer, intent(out) :: stat
    real(dp), allocatable :: w(:), y1(:), f1(:)
    real(dp) :: d0, d1, d2, h0, h1, hmax
    stat = MBDK_SUCCESS
    hmax = span
    if (opt%h_max > 0.0_dp) hmax = min(hmax, opt%h_max)
    if (opt%h > 0.0_dp) then
      h = min(opt%h, hmax)
      return
    end if
    allocate (w(size(y0)), y1(size(y0)), f1(size(y0)), stat=stat)
    if (stat /= 0) then
      stat = MBDK_ERR_NO_MEMORY
      return
    end if
    call mbdk_adaptive_weights(opt, atol, y0, w)
    d0 = mbdk_adaptive_wrms(y0, w)
    d1 = mbdk_adaptive_wrms(f0, w)
    if (d0 < 1.0e-5_dp .or. d1 < 1.0e-5_dp) then
      h0 = 1.0e-6_dp
    else
      h0 = 0.01_dp * d0 / d1
    end if
    h0 = min(h0, hmax)
    y1 = y0 + h0 * f0
    call prob%rhs(t0 + h0, y1, f1, stat)
    nfev = nfev + 1
    if (stat /= MBDK_SUCCESS) return
    d2 = mbdk_adaptive_wrms(f1 - f0, w) / h0
    if (.not. (d2 <= huge(1.0_dp))) then
      h = h0     ! F blew up over h0: the method's rejections take it from here
    else if (max(d1, d2) <= 1.0e-15_dp) then
      h = min(100.0_dp * h0, max(1.0e-6_dp, 1.0e-3_dp * h0))
    else
      h1 = (0.01_dp / max(d1, d2))**(1.0_dp / real(p + 1, dp))
      h = min(100.0_dp * h0, h1)
    end if
    h = min(max(h, opt%h_min), hmax)   ! a step the caller forbids is no first step
  end subroutine mbdk_adaptive_initial_step

  !> The smallest step at t: opt%h_min, and never below about 10 ulps of t (a step that cannot
  !> move t); 20 eps |t| rather than spacing(), which costs a frexp and an ldexp per step.
  !> landing: the step ends on t_end, cut to what is left: only the rounding floor applies.
  pure real(dp) function mbdk_adaptive_h_floor(opt, t, landing)
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t
    logical, intent(in), optional :: landing
    mbdk_adaptive_h_floor = max(20.0_dp * epsilon(1.0_dp) * abs(t), tiny(1.0_dp))
    if (present(landing)) then
      if (landing) return
    end if
    mbdk_adaptive_h_floor = max(opt%h_min, mbdk_adaptive_h_floor)
  end function mbdk_adaptive_h_floor

  !> One accepted step of order q in the statistics (orders above 5, Adams', in order5_steps).
  pure subroutine mbdk_adaptive_count_order(st, q)
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(in) :: q
    select case (q)
    case (:1)
      st%order1_steps = st%order1_steps + 1
    case (2)
      st%order2_steps = st%order2_steps + 1
    case (3)
      st%order3_steps = st%order3_steps + 1
    case (4)
      st%order4_steps = st%order4_steps + 1
    case default
      st%order5_steps = st%order5_steps + 1
    end select
  end subroutine mbdk_adaptive_count_order

  !> After an accepted step to (t, y): projection (projected = .true. when post_step ran), the
  !> finite check and the watch (sample: a sample time fell in this step).
  subroutine mbdk_adaptive_after_step(prob, t, y, sample, projected, stat)
    class(mbdk_problem_t), intent(in) :: prob
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: y(:)
    logical, intent(in) :: sample
    logical, intent(out) :: projected
    integer, intent(out) :: stat
    projected = .false.
    stat = MBDK_SUCCESS
    if (prob%has_post_step) then
      call prob%post_step(t, y, stat)
      if (stat /= MBDK_SUCCESS) return
      projected = .true.
    end if
    if (.not. all(abs(y) <= huge(1.0_dp))) then
      stat = MBDK_ERR_NONFINITE
      return
    end if
    if (prob%has_watch) call prob%watch(t, y, sample, stat)
  end subroutine mbdk_adaptive_after_step

end module mbdk_adaptive
