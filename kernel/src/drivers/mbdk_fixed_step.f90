!> The fixed-step driver: the whole time loop of every fixed-step method, compiled.
!>
!> Steps t_i = t0 + i h, i = 1..N (computed by multiplication, not accumulation). When
!> (t_end - t0)/h is not a whole number (within 1e-9 relative), N = ceiling and the last step
!> is shortened to land on t_end; the solve then returns MBDK_NOTE_LAST_STEP_SHORTENED.
!> Multistep methods with k > 1 (bdf2..bdf6) need equal steps and refuse such an interval
!> (MBDK_ERR_INVALID_INPUT). Samples: the initial point, every `every`-th step and the last one.
!>
!> Start-up of a k-step method: the first k-1 steps are RK4 steps of the same h (the book's
!> remark on the Gear formula (4.80)), each extrapolated from one step h and two steps h/2
!> (y = y_{h/2} + (y_{h/2} - y_h)/15, local error O(h^6)): plain RK4 start values (local error
!> O(h^5)) would cap bdf6 at order 5. Or, with opt%startup = MBDK_STARTUP_BDF, BDF steps of
!> order 1, 2, ..., k-1 (stable on stiff problems, where RK4 start-up steps amplify by |R(h*lambda)|
!> each). They are counted in stats%startup_steps.
!>
!> A problem with has_post_step (the projection formulation of scenes) gets post_step(t, y)
!> after every step; a multistep history then continues from the projected state.
!>
!> After every step the state is checked: inf or NaN ends the solve with MBDK_ERR_NONFINITE,
!> keeping the samples written so far. The caller's interrupt flag (opt%interrupt) is polled
!> before every step: set, the solve ends with MBDK_ERR_INTERRUPTED, keeping the samples written.
!> The loop's CPU time (of the calling thread) and wall time are in the statistics.
module mbdk_fixed_step
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_options, only: mbdk_options_t, MBDK_STARTUP_RK4, MBDK_STARTUP_BDF
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_clock, only: mbdk_timer_t, mbdk_timer_start, mbdk_timer_stop
  use mbdk_interrupt, only: mbdk_interrupted
  use mbdk_methods, only: mbdk_method_info, MBDK_FAMILY_EXPLICIT_RK, MBDK_FAMILY_EULER_CROMER, &
    MBDK_FAMILY_IMPLICIT_LMM, MBDK_FAMILY_DAE_INDEX3, MBDK_RK4, MBDK_BDF1, MBDK_METHOD_NAME_LEN
  use mbdk_butcher, only: mbdk_butcher_t, mbdk_butcher_table, MBDK_MAX_STAGES
  use mbdk_explicit_rk, only: mbdk_explicit_rk_step
  use mbdk_euler_cromer, only: mbdk_euler_cromer_step
  use mbdk_lmm_tables, only: mbdk_lmm_t, mbdk_lmm_table
  use mbdk_implicit_lmm, only: mbdk_implicit_lmm_step
  use mbdk_newton, only: mbdk_newton_work_t, mbdk_newton_work_init
  implicit none
  private
  public :: mbdk_step_plan, mbdk_fixed_step_solve

  integer(i8), parameter :: MAX_STEPS = 2000000000_i8

contains

  !> Number of steps and samples for an interval; checks h, the interval and every.
  pure subroutine mbdk_step_plan(t0, t_end, h, every, nsteps, nsamp, shortened, stat)
    real(dp), intent(in) :: t0, t_end, h
    integer, intent(in) :: every
    integer(i8), intent(out) :: nsteps
    integer, intent(out) :: nsamp
    logical, intent(out) :: shortened
    integer, intent(out) :: stat
    real(dp) :: ratio
    nsteps = 0; nsamp = 0; shortened = .false.
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. (abs(t0) <= huge(1.0_dp) .and. abs(t_end) <= huge(1.0_dp))) return
    if (.not. (h > 0.0_dp .and. h <= huge(1.0_dp))) return
    if (.not. (t_end > t0) .or. every < 1) return
    ratio = (t_end - t0) / h
    if (ratio < 1.0_dp - 1.0e-9_dp .or. ratio > real(MAX_STEPS, dp)) return
    nsteps = nint(ratio, i8)
    if (abs(ratio - real(nsteps, dp)) > 1.0e-9_dp * max(1.0_dp, ratio)) then
      nsteps = ceiling(ratio, i8)
      shortened = .true.
    end if
    if (nsteps / every + 2 > huge(0)) return
    nsamp = int(nsteps / every) + 1
    if (mod(nsteps, int(every, i8)) /= 0) nsamp = nsamp + 1
    stat = merge(MBDK_NOTE_LAST_STEP_SHORTENED, MBDK_SUCCESS, shortened)
  end subroutine mbdk_step_plan

  !> Integrates prob from (t0, y0) to t_end with opt%method and step opt%h.
  !> t_out(nsamp), y_out(n, nsamp) receive the samples; nwritten says how many were written
  !> (fewer than planned only on failure).
  subroutine mbdk_fixed_step_solve(prob, opt, t0, t_end, y0, t_out, y_out, nwritten, st, stat)
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_end
    real(dp), intent(in) :: y0(:)
    real(dp), intent(out) :: t_out(:)
    real(dp), intent(out) :: y_out(:, :)
    integer, intent(out) :: nwritten
    type(mbdk_stats_t), intent(out) :: st
    integer, intent(out) :: stat

    character(len=MBDK_METHOD_NAME_LEN) :: name
    integer :: family, order, n, nsamp, plan_stat, nstart
    integer(i8) :: nsteps, i
    logical :: shortened, ok
    type(mbdk_butcher_t) :: rk, rk_start
    type(mbdk_lmm_t) :: lmm, lmm_start
    type(mbdk_newton_work_t) :: nw
    real(dp), allocatable :: k(:, :), ytmp(:), y(:), hist(:, :), fn(:), c(:), yfull(:)
    real(dp) :: t, hi
    type(mbdk_timer_t) :: timer

    nwritten = 0
    n = prob%n
    call mbdk_method_info(opt%method, name, family, order)
    stat = MBDK_ERR_UNKNOWN_METHOD
    if (family == 0) return
    stat = MBDK_ERR_NOT_APPLICABLE   ! an index-3 DAE method integrates scenes, not ODEs
    if (family == MBDK_FAMILY_DAE_INDEX3) return
    stat = MBDK_ERR_INVALID_INPUT
    if (n < 1 .or. size(y0) /= n) return
    if (.not. all(abs(y0) <= huge(1.0_dp))) return
    call mbdk_step_plan(t0, t_end, opt%h, opt%every, nsteps, nsamp, shortened, plan_stat)
    if (mbdk_is_failure(plan_stat)) then
      stat = plan_stat
      return
    end if
    stat = MBDK_ERR_OUTPUT_SIZE
    if (size(t_out) < nsamp .or. size(y_out, 1) /= n .or. size(y_out, 2) < nsamp) return

    allocate (y(n), ytmp(n), k(n, MBDK_MAX_STAGES))
    nstart = 0
    select case (family)
    case (MBDK_FAMILY_EXPLICIT_RK)
      call mbdk_butcher_table(opt%method, rk, ok)
    case (MBDK_FAMILY_EULER_CROMER)
      stat = MBDK_ERR_NOT_APPLICABLE
      if (prob%nq < 1 .or. 2 * prob%nq /= n) return
    case (MBDK_FAMILY_IMPLICIT_LMM)
      call mbdk_lmm_table(opt%method, lmm, ok)
      stat = MBDK_ERR_INVALID_INPUT
      if (lmm%k > 1 .and. shortened) return
      if (opt%startup /= MBDK_STARTUP_RK4 .and. opt%startup /= MBDK_STARTUP_BDF) return
      if (opt%newton_max_iter < 1 .or. .not. (opt%newton_rtol > 0.0_dp) .or. &
          .not. (opt%newton_atol > 0.0_dp)) return
      nstart = lmm%k - 1
      call mbdk_butcher_table(MBDK_RK4, rk_start, ok)
      call mbdk_newton_work_init(nw, n)
      allocate (hist(n, lmm%k), fn(n), c(n), yfull(n))
      hist(:, 1) = y0
    end select

    call mbdk_timer_start(timer)
    y = y0
    t = t0
    nwritten = 1
    t_out(1) = t0
    y_out(:, 1) = y0
    stat = MBDK_SUCCESS
    if (family == MBDK_FAMILY_IMPLICIT_LMM .and. lmm%beta1 /= 0.0_dp) then
      call prob%rhs(t0, y, fn, stat)
      st%nfev = st%nfev + 1
    end if

    do i = 1, nsteps
      if (stat /= MBDK_SUCCESS) exit
      if (mbdk_interrupted(opt%interrupt)) then
        stat = MBDK_ERR_INTERRUPTED
        exit
      end if
      hi = opt%h
      if (i == nsteps .and. shortened) hi = t_end - t
      select case (family)
      case (MBDK_FAMILY_EXPLICIT_RK)
        call mbdk_explicit_rk_step(prob, rk, t, hi, y, k, ytmp, st, stat)
      case (MBDK_FAMILY_EULER_CROMER)
        call mbdk_euler_cromer_step(prob, t, hi, y, ytmp, st, stat)
      case (MBDK_FAMILY_IMPLICIT_LMM)
        if (i <= nstart .and. opt%startup == MBDK_STARTUP_BDF) then
          call mbdk_lmm_table(MBDK_BDF1 + int(i) - 1, lmm_start, ok)
          call mbdk_implicit_lmm_step(prob, lmm_start, opt, t, hi, y, hist, fn, c, nw, st, stat)
          st%startup_steps = st%startup_steps + 1
        else if (i <= nstart) then
          yfull = y
          call mbdk_explicit_rk_step(prob, rk_start, t, hi, yfull, k, ytmp, st, stat)
          if (stat == MBDK_SUCCESS) &
            call mbdk_explicit_rk_step(prob, rk_start, t, 0.5_dp * hi, y, k, ytmp, st, stat)
          if (stat == MBDK_SUCCESS) &
            call mbdk_explicit_rk_step(prob, rk_start, t + 0.5_dp * hi, 0.5_dp * hi, y, k, ytmp, &
                                       st, stat)
          y = y + (y - yfull) / 15.0_dp
          hist(:, 2:lmm%k) = hist(:, 1:lmm%k - 1)
          hist(:, 1) = y
          st%startup_steps = st%startup_steps + 1
        else
          call mbdk_implicit_lmm_step(prob, lmm, opt, t, hi, y, hist, fn, c, nw, st, stat)
        end if
      end select
      if (stat /= MBDK_SUCCESS) exit
      if (prob%has_post_step) then   ! e.g. projection onto the constraint manifold
        if (i == nsteps) then
          call prob%post_step(t_end, y, stat)
        else
          call prob%post_step(t0 + real(i, dp) * opt%h, y, stat)
        end if
        if (stat /= MBDK_SUCCESS) exit
        if (family == MBDK_FAMILY_IMPLICIT_LMM) then
          hist(:, 1) = y
          if (lmm%beta1 /= 0.0_dp) then
            call prob%rhs(t0 + real(i, dp) * opt%h, y, fn, stat)
            st%nfev = st%nfev + 1
            if (stat /= MBDK_SUCCESS) exit
          end if
        end if
      end if
      if (.not. all(abs(y) <= huge(1.0_dp))) then
        stat = MBDK_ERR_NONFINITE
        exit
      end if
      st%steps = i
      if (i == nsteps) then
        t = t_end
      else
        t = t0 + real(i, dp) * opt%h
      end if
      if (mod(i, int(opt%every, i8)) == 0 .or. i == nsteps) then
        nwritten = nwritten + 1
        t_out(nwritten) = t
        y_out(:, nwritten) = y
      end if
    end do
    call mbdk_timer_stop(timer, st)
    if (stat == MBDK_SUCCESS .and. shortened) stat = MBDK_NOTE_LAST_STEP_SHORTENED
  end subroutine mbdk_fixed_step_solve

end module mbdk_fixed_step
