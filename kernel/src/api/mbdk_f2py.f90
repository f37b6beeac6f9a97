! The f2py-facing layer: plain external subroutines with double precision scalars and
! explicit-shape arrays only, so that numpy.f2py can wrap them as mbdk._kernel. They translate
! to the kernel's modules and derived types and return statuses; nothing here prints or stops.
! Python calls these only through python/mbdk (ode.py, methods.py, errors.py).

subroutine solve_problem(problem_id, method_id, n, y0, t0, t_end, h, every, np, params, &
                         newton_rtol, newton_atol, newton_max_iter, fd_jacobian, startup, nsamp, &
                         t_out, y_out, stats, nwritten, status)
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t, mbdk_stats_to_array
  use mbdk_textbook, only: mbdk_textbook_t, mbdk_textbook_init
  use mbdk_fixed_step, only: mbdk_fixed_step_solve
  implicit none
  integer, intent(in) :: problem_id, method_id, n, every, np, nsamp, newton_max_iter, fd_jacobian
  integer, intent(in) :: startup
  double precision, intent(in) :: y0(n), t0, t_end, h, params(np), newton_rtol, newton_atol
  double precision, intent(out) :: t_out(nsamp), y_out(n, nsamp), stats(7)
  integer, intent(out) :: nwritten, status
!f2py integer intent(hide), depend(y0) :: n = len(y0)
!f2py integer intent(hide), depend(params) :: np = len(params)
  type(mbdk_textbook_t) :: prob
  type(mbdk_options_t) :: opt
  type(mbdk_stats_t) :: st

  nwritten = 0
  stats = 0.0d0
  t_out = 0.0d0
  y_out = 0.0d0
  call mbdk_textbook_init(prob, problem_id, n, params, status)
  if (status /= MBDK_SUCCESS) return
  opt%method = method_id
  opt%h = h
  opt%every = every
  opt%newton_rtol = newton_rtol
  opt%newton_atol = newton_atol
  opt%newton_max_iter = newton_max_iter
  opt%fd_jacobian = fd_jacobian /= 0
  opt%startup = startup
  call mbdk_fixed_step_solve(prob, opt, t0, t_end, y0, t_out, y_out, nwritten, st, status)
  stats = mbdk_stats_to_array(st)
end subroutine solve_problem

subroutine eval_problem(problem_id, n, np, params, t, y, f, status)
  ! One evaluation of F(t, y) of a compiled problem (for tests and post-processing).
  use mbdk_status, only: MBDK_SUCCESS
  use mbdk_textbook, only: mbdk_textbook_t, mbdk_textbook_init
  implicit none
  integer, intent(in) :: problem_id, n, np
  double precision, intent(in) :: params(np), t, y(n)
  double precision, intent(out) :: f(n)
  integer, intent(out) :: status
!f2py integer intent(hide), depend(y) :: n = len(y)
!f2py integer intent(hide), depend(params) :: np = len(params)
  type(mbdk_textbook_t) :: prob
  f = 0.0d0
  call mbdk_textbook_init(prob, problem_id, n, params, status)
  if (status /= MBDK_SUCCESS) return
  call prob%rhs(t, y, f, status)
end subroutine eval_problem

subroutine solve_callback(fun, n, y0, t0, t_end, h, method_id, every, nq, newton_rtol, &
                          newton_atol, newton_max_iter, startup, nsamp, t_out, y_out, stats, &
                          nwritten, status)
  ! The slow path: F is a Python function fun(t, y, dydt, flag) filling dydt in place
  ! (f2py hides n); flag(1) = 1 reports a failure.
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t, mbdk_stats_to_array
  use mbdk_callback_problem, only: mbdk_proc_problem_t, mbdk_proc_problem_init
  use mbdk_fixed_step, only: mbdk_fixed_step_solve
  implicit none
  external fun
  integer, intent(in) :: n, method_id, every, nq, nsamp, newton_max_iter, startup
  double precision, intent(in) :: y0(n), t0, t_end, h, newton_rtol, newton_atol
  double precision, intent(out) :: t_out(nsamp), y_out(n, nsamp), stats(7)
  integer, intent(out) :: nwritten, status
!f2py integer intent(hide), depend(y0) :: n = len(y0)
  ! The callback's signature for f2py: its first argument is named n so that the bounds of
  ! cb_y and cb_dydt refer to the callback's own argument.
  integer :: cb_flag(1)
  double precision :: cb_t, cb_y(n), cb_dydt(n)
!f2py call fun(n, cb_t, cb_y, cb_dydt, cb_flag)
  type(mbdk_proc_problem_t) :: prob
  type(mbdk_options_t) :: opt
  type(mbdk_stats_t) :: st

  nwritten = 0
  stats = 0.0d0
  t_out = 0.0d0
  y_out = 0.0d0
  call mbdk_proc_problem_init(prob, fun, n, nq)
  opt%method = method_id
  opt%h = h
  opt%every = every
  opt%newton_rtol = newton_rtol
  opt%newton_atol = newton_atol
  opt%newton_max_iter = newton_max_iter
  opt%startup = startup
  call mbdk_fixed_step_solve(prob, opt, t0, t_end, y0, t_out, y_out, nwritten, st, status)
  stats = mbdk_stats_to_array(st)
end subroutine solve_callback

subroutine sample_count(t0, t_end, h, every, nsteps, nsamp, status)
  use mbdk_kinds, only: i8
  use mbdk_fixed_step, only: mbdk_step_plan
  implicit none
  double precision, intent(in) :: t0, t_end, h
  integer, intent(in) :: every
  double precision, intent(out) :: nsteps
  integer, intent(out) :: nsamp, status
  integer(i8) :: ns
  logical :: shortened
  call mbdk_step_plan(t0, t_end, h, every, ns, nsamp, shortened, status)
  nsteps = dble(ns)
end subroutine sample_count

subroutine step_history_length(method_id, k)
  ! Past states one step of the method reads (k of a k-step method, 1 otherwise, 0 unknown).
  use mbdk_step_matrix, only: mbdk_step_history_length
  implicit none
  integer, intent(in) :: method_id
  integer, intent(out) :: k
  k = mbdk_step_history_length(method_id)
end subroutine step_history_length

subroutine step_matrices(method_id, n, npts, nk, a, h, newton_rtol, newton_atol, m, status)
  ! m(:, :, p) = the step matrix of the method with step h(p) on y' = a(:, :, p) y, from the
  ! kernel's own step routine (mbdk_step_matrix); status(p) per matrix.
  use mbdk_options, only: mbdk_options_t
  use mbdk_step_matrix, only: mbdk_step_matrix_eval
  implicit none
  integer, intent(in) :: method_id, n, npts, nk
  double precision, intent(in) :: a(n, n, npts), h(npts), newton_rtol, newton_atol
  double precision, intent(out) :: m(nk, nk, npts)
  integer, intent(out) :: status(npts)
!f2py integer intent(hide), depend(a) :: n = shape(a, 0)
!f2py integer intent(hide), depend(a) :: npts = shape(a, 2)
  type(mbdk_options_t) :: opt
  integer :: p
  opt%newton_rtol = newton_rtol
  opt%newton_atol = newton_atol
  do p = 1, npts
    call mbdk_step_matrix_eval(method_id, a(:, :, p), h(p), opt, m(:, :, p), status(p))
  end do
end subroutine step_matrices

subroutine method_id(name, id)
  use mbdk_methods, only: mbdk_method_id
  implicit none
  character(len=*), intent(in) :: name
  integer, intent(out) :: id
  id = mbdk_method_id(name)
end subroutine method_id

subroutine method_info(id, name, family, order)
  use mbdk_methods, only: mbdk_method_info
  implicit none
  integer, intent(in) :: id
  character(len=24), intent(out) :: name
  integer, intent(out) :: family, order
  call mbdk_method_info(id, name, family, order)
end subroutine method_info

subroutine problem_id(name, id)
  use mbdk_textbook, only: mbdk_problem_id
  implicit none
  character(len=*), intent(in) :: name
  integer, intent(out) :: id
  id = mbdk_problem_id(name)
end subroutine problem_id

subroutine problem_info(id, name, n, np)
  use mbdk_textbook, only: mbdk_problem_info
  implicit none
  integer, intent(in) :: id
  character(len=24), intent(out) :: name
  integer, intent(out) :: n, np
  call mbdk_problem_info(id, name, n, np)
end subroutine problem_info

subroutine status_entry(i, code, name, message)
  use mbdk_status, only: mbdk_status_entry
  implicit none
  integer, intent(in) :: i
  integer, intent(out) :: code
  character(len=32), intent(out) :: name
  character(len=120), intent(out) :: message
  call mbdk_status_entry(i, code, name, message)
end subroutine status_entry

subroutine butcher_tableau(id, a, b, c, stages, order, ok)
  use mbdk_butcher, only: mbdk_butcher_t, mbdk_butcher_table
  implicit none
  integer, intent(in) :: id
  double precision, intent(out) :: a(4, 4), b(4), c(4)
  integer, intent(out) :: stages, order, ok
  type(mbdk_butcher_t) :: tab
  logical :: found
  call mbdk_butcher_table(id, tab, found)
  a = tab%a; b = tab%b; c = tab%c
  stages = tab%stages; order = tab%order
  ok = merge(1, 0, found)
end subroutine butcher_tableau

subroutine lmm_coefficients(id, alpha, beta0, beta1, k, order, ok)
  use mbdk_lmm_tables, only: mbdk_lmm_t, mbdk_lmm_table
  implicit none
  integer, intent(in) :: id
  double precision, intent(out) :: alpha(7), beta0, beta1
  integer, intent(out) :: k, order, ok
  type(mbdk_lmm_t) :: tab
  logical :: found
  call mbdk_lmm_table(id, tab, found)
  alpha = tab%alpha; beta0 = tab%beta0; beta1 = tab%beta1
  k = tab%k; order = tab%order
  ok = merge(1, 0, found)
end subroutine lmm_coefficients

subroutine build_info(compiler, options)
  use, intrinsic :: iso_fortran_env, only: compiler_version, compiler_options
  implicit none
  character(len=256), intent(out) :: compiler
  character(len=1024), intent(out) :: options
  compiler = compiler_version()
  options = compiler_options()
end subroutine build_info
