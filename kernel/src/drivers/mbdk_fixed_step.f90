!> The fixed-step driver: the whole time loop of every fixed-step method, compiled. Each step is
!> one call of mbdk_stepper_step (mbdk_stepper holds the method's state between steps).
!>
!> Steps t_i = t0 + i h, i = 1..N (computed by multiplication, not accumulation). When
!> (t_end - t0)/h is not a whole number (mbdk_on_grid), N = ceiling and the last step
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
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_clock, only: mbdk_timer_t, mbdk_timer_start, mbdk_timer_stop
  use mbdk_interrupt, only: mbdk_interrupted, mbdk_progress
  use mbdk_methods, only: mbdk_method_info, MBDK_FAMILY_IMPLICIT_LMM, MBDK_FAMILY_DAE_INDEX3, &
    MBDK_METHOD_NAME_LEN
  use mbdk_lmm_tables, only: mbdk_lmm_t, mbdk_lmm_table
  use mbdk_stepper, only: mbdk_stepper_t, mbdk_stepper_init, mbdk_stepper_step
  implicit none
  private
  public :: mbdk_step_plan, mbdk_fixed_step_solve, mbdk_on_grid

  !> the most steps one solve takes (a sample index must fit a default integer)
  integer(i8), parameter, public :: MBDK_MAX_STEPS = 2000000000_i8

contains

  !> Whether (t1 - t0)/h, computed in floating point, is a whole number of steps: within 1e-9,
  !> or within the rounding of the division where the count is large, plus the rounding of
  !> t1 - t0 itself (an ulp of t0 and of t1, per h: large far from t = 0). Looser would let a
  !> k-step method's last step differ from h by more than its rounding (1e-9 N h at N steps);
  !> the stepper accepts a step of h within 1e-9 h plus the rounding of t.
  elemental logical function mbdk_on_grid(t0, t1, h)
    real(dp), intent(in) :: t0, t1, h
    real(dp) :: ratio
    ratio = (t1 - t0) / h
    mbdk_on_grid = abs(ratio - anint(ratio)) <= max(1.0e-9_dp, 16.0_dp * epsilon(1.0_dp) * &
                                                     abs(ratio)) + &
      4.0_dp * (spacing(t0) + spacing(t1)) / h
  end function mbdk_on_grid

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
    if (ratio < 1.0_dp - 1.0e-9_dp .or. ratio > real(MBDK_MAX_STEPS, dp)) return
    nsteps = nint(ratio, i8)
    if (.not. mbdk_on_grid(t0, t_end, h)) then
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
    integer :: family, order, n, nsamp, plan_stat
    integer(i8) :: nsteps, i
    logical :: shortened, found, sample
    type(mbdk_stepper_t) :: s
    type(mbdk_lmm_t) :: lmm
    real(dp) :: t_next
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
    call mbdk_step_plan(t0, t_end, opt%h, opt%every, nsteps, nsamp, shortened, plan_stat)
    if (mbdk_is_failure(plan_stat)) then
      stat = plan_stat
      return
    end if
    if (family == MBDK_FAMILY_IMPLICIT_LMM) then
      call mbdk_lmm_table(opt%method, lmm, found)
      if (lmm%k > 1 .and. shortened) return   ! k-step methods need equal steps
    end if
    stat = MBDK_ERR_OUTPUT_SIZE
    if (size(t_out) < nsamp .or. size(y_out, 1) /= n .or. size(y_out, 2) < nsamp) return

    call mbdk_timer_start(timer)
    call mbdk_stepper_init(s, prob, opt, t0, y0, stat)
    if (stat /= MBDK_SUCCESS) then
      st = s%st
      return
    end if
    nwritten = 1
    t_out(1) = t0
    y_out(:, 1) = y0
    do i = 1, nsteps
      if (opt%interrupt /= 0 .and. mbdk_interrupted(opt%interrupt)) then
        stat = MBDK_ERR_INTERRUPTED
        exit
      end if
      t_next = t0 + real(i, dp) * opt%h
      if (opt%progress /= 0) call mbdk_progress(opt%progress, t_next)
      if (i == nsteps) t_next = t_end
      sample = mod(i, int(opt%every, i8)) == 0 .or. i == nsteps
      call mbdk_stepper_step(s, prob, t_next, stat, sample)
      if (stat /= MBDK_SUCCESS) exit
      if (sample) then
        nwritten = nwritten + 1
        t_out(nwritten) = t_next
        y_out(:, nwritten) = s%y
      end if
    end do
    st = s%st
    call mbdk_timer_stop(timer, st)
    if (stat == MBDK_SUCCESS .and. shortened) stat = MBDK_NOTE_LAST_STEP_SHORTENED
  end subroutine mbdk_fixed_step_solve

end module mbdk_fixed_step
