!> fortran_embedding.f90 - a Fortran program integrating its own ODE through libmbdk's kernel
!> modules (the same path the C API takes): y' = -y + sin(t), y(0) = 1, whose exact solution is
!> y = 1.5 e^{-t} + (sin t - cos t)/2. Integrated with trapezoidal and rk4; the errors must shrink
!> by the nominal order when h is halved (from h = 0.025: at h = 0.1 the rk4 error on this
!> problem is still pre-asymptotic, ratio 9.8 instead of 16). Then the same problem stepped one
!> step at a time through mbdk_stepper (what mbdk_fixed_step_solve loops over): bdf3's state
!> after 80 steps must equal the whole-interval solve's bit for bit. Last, the error-controlled
!> methods through mbdk_solve_ode (the entry of every method): dopri54, bdf and cvode_bdf at
!> rtol = 1e-9 must end within 1e-7 of the exact y(2). Exit code 0 = pass.
module forced_decay
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS
  use mbdk_problem, only: mbdk_problem_t
  implicit none
  type, extends(mbdk_problem_t) :: forced_decay_t
  contains
    procedure :: rhs => forced_rhs
  end type forced_decay_t
contains
  subroutine forced_rhs(self, t, y, f, stat)
    class(forced_decay_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    real(dp), intent(out), contiguous :: f(:)
    integer, intent(out) :: stat
    f(1) = -y(1) + sin(t)
    stat = MBDK_SUCCESS
  end subroutine forced_rhs
end module forced_decay

program fortran_embedding
  use mbdk_kinds, only: dp, i8
  use mbdk_status, only: MBDK_SUCCESS, mbdk_status_message
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_methods, only: mbdk_method_id
  use mbdk_fixed_step, only: mbdk_step_plan, mbdk_fixed_step_solve
  use mbdk_solve, only: mbdk_solve_ode, mbdk_sample_plan
  use mbdk_stepper, only: mbdk_stepper_t, mbdk_stepper_init, mbdk_stepper_step
  use forced_decay, only: forced_decay_t
  implicit none
  integer :: fails
  fails = 0
  call check('trapezoidal', 2)
  call check('rk4', 4)
  call stepped('bdf3')
  call by_tolerance('dopri54')
  call by_tolerance('bdf')
  call by_tolerance('cvode_bdf')
  if (fails == 0) then
    print '(a)', 'PASS'
  else
    print '(a)', 'FAIL'
    error stop 1
  end if

contains

  subroutine check(method, order)
    character(len=*), intent(in) :: method
    integer, intent(in) :: order
    real(dp) :: e(2), p
    integer :: j
    do j = 1, 2
      e(j) = final_error(method, 0.025_dp / 2**(j - 1))
    end do
    p = log(e(1) / e(2)) / log(2.0_dp)
    print '(a12, a, es10.3, a, es10.3, a, f6.3)', method, ': err(h)=', e(1), '  err(h/2)=', &
      e(2), '  observed order=', p
    if (abs(p - order) > 0.15_dp) fails = fails + 1
  end subroutine check

  subroutine stepped(method)
    character(len=*), intent(in) :: method
    type(forced_decay_t) :: prob
    type(mbdk_options_t) :: opt
    type(mbdk_stats_t) :: st
    type(mbdk_stepper_t) :: s
    real(dp) :: t(2), y(1, 2)
    integer :: k, nw, stat
    prob%n = 1
    opt%method = mbdk_method_id(method)
    opt%h = 0.025_dp
    opt%every = 80
    call mbdk_fixed_step_solve(prob, opt, 0.0_dp, 2.0_dp, [1.0_dp], t, y, nw, st, stat)
    call mbdk_stepper_init(s, prob, opt, 0.0_dp, [1.0_dp], stat)
    do k = 1, 80
      if (stat == MBDK_SUCCESS) call mbdk_stepper_step(s, prob, k * opt%h, stat)
    end do
    print '(a12, a, i0, a, l1)', method, ': stepped 80 steps, status ', stat, &
      ', equal to the solve: ', s%y(1) == y(1, 2)
    if (stat /= MBDK_SUCCESS .or. s%y(1) /= y(1, 2) .or. s%st%steps /= 80) fails = fails + 1
  end subroutine stepped

  subroutine by_tolerance(method)
    character(len=*), intent(in) :: method
    type(forced_decay_t) :: prob
    type(mbdk_options_t) :: opt
    type(mbdk_stats_t) :: st
    real(dp), allocatable :: t(:), y(:, :)
    real(dp) :: err
    integer :: nsamp, nw, stat
    prob%n = 1
    opt%method = mbdk_method_id(method)
    opt%rtol = 1.0e-9_dp
    opt%atol = 1.0e-11_dp
    opt%dt_out = 0.5_dp
    call mbdk_sample_plan(opt, 0.0_dp, 2.0_dp, nsamp, stat)
    allocate (t(nsamp), y(1, nsamp))
    call mbdk_solve_ode(prob, opt, 0.0_dp, 2.0_dp, [1.0_dp], t, y, nw, st, stat)
    err = abs(y(1, nw) - (1.5_dp * exp(-2.0_dp) + 0.5_dp * (sin(2.0_dp) - cos(2.0_dp))))
    print '(a12, a, i0, a, i0, a, i0, a, es10.3)', method, ': status ', stat, ', samples ', nw, &
      ', steps ', st%steps, ', error at t = 2: ', err
    if (stat /= MBDK_SUCCESS .or. nw /= 5 .or. err > 1.0e-7_dp .or. t(5) /= 2.0_dp) &
      fails = fails + 1
  end subroutine by_tolerance

  real(dp) function final_error(method, h) result(err)
    character(len=*), intent(in) :: method
    real(dp), intent(in) :: h
    type(forced_decay_t) :: prob
    type(mbdk_options_t) :: opt
    type(mbdk_stats_t) :: st
    real(dp), allocatable :: t(:), y(:, :)
    integer(i8) :: nsteps
    integer :: nsamp, nw, stat
    logical :: shortened
    prob%n = 1
    opt%method = mbdk_method_id(method)
    opt%h = h
    opt%every = 1
    call mbdk_step_plan(0.0_dp, 2.0_dp, h, 1, nsteps, nsamp, shortened, stat)
    allocate (t(nsamp), y(1, nsamp))
    call mbdk_fixed_step_solve(prob, opt, 0.0_dp, 2.0_dp, [1.0_dp], t, y, nw, st, stat)
    if (stat /= MBDK_SUCCESS) then
      print '(a)', trim(mbdk_status_message(stat))
      fails = fails + 1
      err = huge(1.0_dp)
      return
    end if
    err = abs(y(1, nw) - (1.5_dp * exp(-2.0_dp) + 0.5_dp * (sin(2.0_dp) - cos(2.0_dp))))
  end function final_error

end program fortran_embedding
