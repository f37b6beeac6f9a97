!> One step at a time: the state of a fixed-step method between steps (its tables, work arrays,
!> multistep history and statistics) and the one routine that advances it. The fixed-step
!> driver (mbdk_fixed_step) loops over mbdk_stepper_step; embedders drive it themselves through
!> the C API (mbdk_stepper_* in mbdk.h) or from Fortran:
!>
!>   call mbdk_stepper_init(s, prob, opt, t0, y0, stat)     ! validates method and options
!>   call mbdk_stepper_step(s, prob, t0 + opt%h, stat)      ! one step to the given time
!>   s%t, s%y, s%st                                          ! time, state, statistics
!>
!> The problem is passed to every step (not stored), so the stepper holds no pointer into the
!> caller's data. A step goes from s%t to t_next: any h for a one-step method; a k-step method
!> (bdf2..bdf6) needs h = opt%h (within 1e-9 relative) and takes its first k-1 steps with its
!> start-up (opt%startup: Richardson-extrapolated RK4 steps, the book's (4.80), or BDF steps of
!> rising order; mbdk_fixed_step's header says why). A problem with has_post_step gets
!> post_step(t_next, y) after each step (the projection formulation of scenes), and a multistep
!> history continues from the projected state. A non-finite state ends the step with
!> MBDK_ERR_NONFINITE. After a failure s%t is still the time before the step but s%y holds what
!> the failed step left (the driver keeps its samples; the C stepper keeps a copy of the last good
!> state), and the stepper refuses further steps (MBDK_ERR_NOT_APPLICABLE).
module mbdk_stepper
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_options, only: mbdk_options_t, MBDK_STARTUP_RK4, MBDK_STARTUP_BDF
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_methods, only: mbdk_method_info, MBDK_FAMILY_EXPLICIT_RK, MBDK_FAMILY_EULER_CROMER, &
    MBDK_FAMILY_IMPLICIT_LMM, MBDK_FAMILY_DAE_INDEX3, MBDK_RK4, MBDK_BDF1, MBDK_METHOD_NAME_LEN, &
    mbdk_method_adaptive
  use mbdk_butcher, only: mbdk_butcher_t, mbdk_butcher_table, MBDK_MAX_STAGES
  use mbdk_explicit_rk, only: mbdk_explicit_rk_step
  use mbdk_euler_cromer, only: mbdk_euler_cromer_step
  use mbdk_lmm_tables, only: mbdk_lmm_t, mbdk_lmm_table
  use mbdk_implicit_lmm, only: mbdk_implicit_lmm_step
  use mbdk_newton, only: mbdk_newton_work_t, mbdk_newton_work_init
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  implicit none
  private
  public :: mbdk_stepper_init, mbdk_stepper_step

  type, public :: mbdk_stepper_t
    type(mbdk_options_t) :: opt
    integer :: family = 0
    integer :: nstart = 0             !< start-up steps of a k-step method (k - 1)
    logical :: failed = .false.
    real(dp) :: t = 0.0_dp            !< time of the state y
    real(dp), allocatable :: y(:)
    type(mbdk_stats_t) :: st
    type(mbdk_butcher_t) :: rk, rk_start
    type(mbdk_lmm_t) :: lmm
    type(mbdk_newton_work_t) :: nw
    real(dp), allocatable :: k(:, :), ytmp(:), hist(:, :), fn(:), c(:), yfull(:)
  end type mbdk_stepper_t

contains

  !> A stepper for prob with opt%method at (t0, y0). MBDK_ERR_UNKNOWN_METHOD, MBDK_ERR_NOT_APPLICABLE
  !> (trapezoidal_index3, which steps scenes itself; an error-controlled method, which runs whole
  !> intervals through mbdk_solve; euler_cromer on a first-order problem),
  !> MBDK_ERR_INVALID_INPUT (sizes, a non-finite y0, h, Newton options, startup),
  !> MBDK_ERR_NO_MEMORY (s%st%alloc_bytes: what was asked for), or a failure of the first
  !> evaluation of F that a multistep method needs.
  subroutine mbdk_stepper_init(s, prob, opt, t0, y0, stat)
    type(mbdk_stepper_t), intent(out) :: s
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, y0(:)
    integer, intent(out) :: stat
    character(len=MBDK_METHOD_NAME_LEN) :: name
    integer :: order, n, astat
    logical :: ok

    s%failed = .true.
    n = prob%n
    call mbdk_method_info(opt%method, name, s%family, order)
    stat = MBDK_ERR_UNKNOWN_METHOD
    if (s%family == 0) return
    stat = MBDK_ERR_NOT_APPLICABLE   ! an index-3 DAE method integrates scenes, not ODEs
    if (s%family == MBDK_FAMILY_DAE_INDEX3) return
    ! an error-controlled method chooses its own steps: it runs whole intervals (mbdk_solve)
    if (mbdk_method_adaptive(opt%method)) return
    stat = MBDK_ERR_INVALID_INPUT
    if (n < 1 .or. size(y0) /= n) return
    if (.not. all(abs(y0) <= huge(1.0_dp)) .or. .not. abs(t0) <= huge(1.0_dp)) return
    if (.not. (opt%h > 0.0_dp .and. opt%h <= huge(1.0_dp)) .or. opt%every < 1) return
    s%opt = opt
    allocate (s%y(n), s%ytmp(n), s%k(n, MBDK_MAX_STAGES), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (MBDK_MAX_STAGES + 2.0_dp) * n, stat, &
                           s%st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INVALID_INPUT
    select case (s%family)
    case (MBDK_FAMILY_EXPLICIT_RK)
      call mbdk_butcher_table(opt%method, s%rk, ok)
    case (MBDK_FAMILY_EULER_CROMER)
      stat = MBDK_ERR_NOT_APPLICABLE
      if (prob%nq < 1 .or. 2 * prob%nq /= n) return
    case (MBDK_FAMILY_IMPLICIT_LMM)
      call mbdk_lmm_table(opt%method, s%lmm, ok)
      if (opt%startup /= MBDK_STARTUP_RK4 .and. opt%startup /= MBDK_STARTUP_BDF) return
      if (opt%newton_max_iter < 1 .or. .not. (opt%newton_rtol > 0.0_dp) .or. &
          .not. (opt%newton_atol > 0.0_dp)) return
      s%nstart = s%lmm%k - 1
      call mbdk_butcher_table(MBDK_RK4, s%rk_start, ok)
      call mbdk_newton_work_init(s%nw, n, stat, s%st%alloc_bytes)
      if (stat /= MBDK_SUCCESS) return
      allocate (s%hist(n, s%lmm%k), s%fn(n), s%c(n), s%yfull(n), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (s%lmm%k + 3.0_dp) * n, stat, &
                             s%st%alloc_bytes)
      if (stat /= MBDK_SUCCESS) return
      s%hist(:, 1) = y0
    end select
    s%y = y0
    s%t = t0
    s%st%t_reached = t0
    stat = MBDK_SUCCESS
    if (s%family == MBDK_FAMILY_IMPLICIT_LMM .and. s%lmm%beta1 /= 0.0_dp) then
      call prob%rhs(t0, s%y, s%fn, stat)
      s%st%nfev = s%st%nfev + 1
      if (stat /= MBDK_SUCCESS) return
    end if
    if (prob%has_watch) then
      call prob%watch_start(t0, s%y, stat)
      if (stat /= MBDK_SUCCESS) return
    end if
    s%failed = .false.
  end subroutine mbdk_stepper_init

  !> One step from s%t to t_next > s%t (see the module header). On success s%t = t_next and
  !> s%y the new state. sample: the state will be sampled, so a watching problem checks it.
  subroutine mbdk_stepper_step(s, prob, t_next, stat, sample)
    type(mbdk_stepper_t), intent(inout) :: s
    class(mbdk_problem_t), intent(in) :: prob
    real(dp), intent(in) :: t_next
    integer, intent(out) :: stat
    logical, intent(in), optional :: sample
    real(dp) :: h
    integer(i8) :: i
    logical :: ok

    stat = MBDK_ERR_NOT_APPLICABLE
    if (s%failed) return
    h = t_next - s%t
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. (h > 0.0_dp .and. h <= huge(1.0_dp))) return
    i = s%st%steps + 1
    if (s%family == MBDK_FAMILY_IMPLICIT_LMM .and. s%lmm%k > 1) then
      ! a k-step method's coefficients hold for its own step only. t_next - t, the difference
      ! of two rounded times, is off from it by up to an ulp of t: the step taken is opt%h
      ! itself, and t_next is accepted as its end within that rounding
      if (abs(h - s%opt%h) > 1.0e-9_dp * s%opt%h + &
          64.0_dp * spacing(max(abs(s%t), abs(t_next)))) return
      h = s%opt%h
    end if
    select case (s%family)
    case (MBDK_FAMILY_EXPLICIT_RK)
      call mbdk_explicit_rk_step(prob, s%rk, s%t, h, s%y, s%k, s%ytmp, s%st, stat)
    case (MBDK_FAMILY_EULER_CROMER)
      call mbdk_euler_cromer_step(prob, s%t, h, s%y, s%ytmp, s%st, stat)
    case (MBDK_FAMILY_IMPLICIT_LMM)
      if (i <= s%nstart .and. s%opt%startup == MBDK_STARTUP_BDF) then
        block
          type(mbdk_lmm_t) :: lmm_start
          call mbdk_lmm_table(MBDK_BDF1 + int(i) - 1, lmm_start, ok)
          call mbdk_implicit_lmm_step(prob, lmm_start, s%opt, s%t, h, s%y, s%hist, s%fn, s%c, &
                                      s%nw, s%st, stat)
        end block
        s%st%startup_steps = s%st%startup_steps + 1
      else if (i <= s%nstart) then
        s%yfull = s%y
        call mbdk_explicit_rk_step(prob, s%rk_start, s%t, h, s%yfull, s%k, s%ytmp, s%st, stat)
        if (stat == MBDK_SUCCESS) &
          call mbdk_explicit_rk_step(prob, s%rk_start, s%t, 0.5_dp * h, s%y, s%k, s%ytmp, &
                                     s%st, stat)
        if (stat == MBDK_SUCCESS) &
          call mbdk_explicit_rk_step(prob, s%rk_start, s%t + 0.5_dp * h, 0.5_dp * h, s%y, s%k, &
                                     s%ytmp, s%st, stat)
        s%y = s%y + (s%y - s%yfull) / 15.0_dp
        s%hist(:, 2:s%lmm%k) = s%hist(:, 1:s%lmm%k - 1)
        s%hist(:, 1) = s%y
        s%st%startup_steps = s%st%startup_steps + 1
      else
        call mbdk_implicit_lmm_step(prob, s%lmm, s%opt, s%t, h, s%y, s%hist, s%fn, s%c, s%nw, &
                                    s%st, stat)
      end if
    end select
    if (stat == MBDK_SUCCESS .and. prob%has_post_step) then   ! e.g. projection onto Phi = 0
      call prob%post_step(t_next, s%y, stat)
      if (stat == MBDK_SUCCESS .and. s%family == MBDK_FAMILY_IMPLICIT_LMM) then
        s%hist(:, 1) = s%y
        if (s%lmm%beta1 /= 0.0_dp) then
          call prob%rhs(t_next, s%y, s%fn, stat)
          s%st%nfev = s%st%nfev + 1
        end if
      end if
    end if
    if (stat == MBDK_SUCCESS .and. .not. all(abs(s%y) <= huge(1.0_dp))) stat = MBDK_ERR_NONFINITE
    if (stat == MBDK_SUCCESS .and. prob%has_watch) then
      if (present(sample)) then
        call prob%watch(t_next, s%y, sample, stat)
      else
        call prob%watch(t_next, s%y, .false., stat)
      end if
    end if
    if (stat /= MBDK_SUCCESS) then
      s%failed = .true.
      return
    end if
    s%st%steps = i
    s%t = t_next
    s%st%t_reached = t_next
  end subroutine mbdk_stepper_step

end module mbdk_stepper
