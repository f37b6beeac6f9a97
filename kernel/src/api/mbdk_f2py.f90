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
  double precision, intent(out) :: t_out(nsamp), y_out(n, nsamp), stats(9)
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
  double precision, intent(out) :: t_out(nsamp), y_out(n, nsamp), stats(9)
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

! ---------------------------------------------------------------------------------------------
! Scenes (kernel/src/model): the tables of mbdk_joints and mbdk_force_elements, built by
! python/mbdk/model.py. nj and nf may be 0; the tables then have one unused column.

subroutine model_solve(nb, mass, inertia, nj, nj1, jint, jreal, nf, nf1, fint, freal, &
                       formulation, fpar, method_id, n, y0, t0, t_end, h, every, newton_rtol, &
                       newton_atol, newton_max_iter, startup, nsamp, t_out, y_out, nwritten, &
                       stats, visits, status)
  ! Integrates a scene with a fixed-step method; the whole loop is compiled.
  use mbdk_kinds, only: i8
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t, mbdk_stats_to_array
  use mbdk_model, only: mbdk_model_t, mbdk_model_init, mbdk_model_work_t
  use mbdk_fixed_step, only: mbdk_fixed_step_solve
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, formulation, method_id, n, every
  integer, intent(in) :: newton_max_iter, startup, nsamp
  double precision, intent(in) :: mass(nb), inertia(nb), jreal(12, nj1), freal(12, nf1), fpar(8)
  integer, intent(in) :: jint(4, nj1), fint(4, nf1)
  double precision, intent(in) :: y0(n), t0, t_end, h, newton_rtol, newton_atol
  double precision, intent(out) :: t_out(nsamp), y_out(n, nsamp), stats(9), visits(9)
  integer, intent(out) :: nwritten, status
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jint) :: nj1 = shape(jint, 1)
!f2py integer intent(hide), depend(fint) :: nf1 = shape(fint, 1)
!f2py integer intent(hide), depend(y0) :: n = len(y0)
  type(mbdk_model_t) :: model
  type(mbdk_options_t) :: opt
  type(mbdk_stats_t) :: st
  type(mbdk_model_work_t), target :: work

  nwritten = 0
  stats = 0.0d0
  visits = 0.0d0
  t_out = 0.0d0
  y_out = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (nj < 0 .or. nj > nj1 .or. nf < 0 .or. nf > nf1 .or. n /= 6 * nb) return
  call mbdk_model_init(model, mass, inertia, jint(:, 1:nj), jreal(:, 1:nj), fint(:, 1:nf), &
                       freal(:, 1:nf), formulation, fpar, work, status)
  if (status /= MBDK_SUCCESS) return
  opt%method = method_id
  opt%h = h
  opt%every = every
  opt%newton_rtol = newton_rtol
  opt%newton_atol = newton_atol
  opt%newton_max_iter = newton_max_iter
  opt%startup = startup
  call mbdk_fixed_step_solve(model, opt, t0, t_end, y0, t_out, y_out, nwritten, st, status)
  stats = mbdk_stats_to_array(st)
  visits = dble(work%visits(1:9))
end subroutine model_solve

subroutine model_eval(nb, mass, inertia, nj, nj1, jint, jreal, nf, nf1, fint, freal, &
                      formulation, fpar, m, nc, t, y, phi, d, gam, phit, fq, acc, lam, path, status)
  ! Phi, D, gamma, Phi_t, the generalised forces and the formulation's accelerations and
  ! multipliers at one state: for assembly, diagnosis and tests. path: the linear solve the
  ! evaluation took (MBDK_SOLVE_* of mbdk_model).
  use mbdk_kinds, only: i8
  use mbdk_model, only: mbdk_model_t, mbdk_model_init, mbdk_model_constraints, &
    mbdk_model_accelerations, mbdk_model_work_t, mbdk_model_assemble, mbdk_model_linear_solve
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, formulation, m, nc
  double precision, intent(in) :: mass(nb), inertia(nb), jreal(12, nj1), freal(12, nf1), fpar(8)
  integer, intent(in) :: jint(4, nj1), fint(4, nf1)
  double precision, intent(in) :: t, y(2 * nc)
  double precision, intent(out) :: phi(m), d(m, nc), gam(m), phit(m), fq(nc), acc(nc), lam(m)
  integer, intent(out) :: path, status
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jint) :: nj1 = shape(jint, 1)
!f2py integer intent(hide), depend(fint) :: nf1 = shape(fint, 1)
!f2py integer intent(hide), depend(mass) :: nc = 3 * len(mass)
  type(mbdk_model_t) :: model
  type(mbdk_model_work_t), target :: work

  path = -1
  phi = 0.0d0; d = 0.0d0; gam = 0.0d0; phit = 0.0d0; fq = 0.0d0; acc = 0.0d0; lam = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (nj < 0 .or. nj > nj1 .or. nf < 0 .or. nf > nf1) return
  call mbdk_model_init(model, mass, inertia, jint(:, 1:nj), jreal(:, 1:nj), fint(:, 1:nf), &
                       freal(:, 1:nf), formulation, fpar, work, status)
  if (status /= MBDK_SUCCESS) return
  path = mbdk_model_linear_solve(model)
  status = MBDK_ERR_INVALID_INPUT
  if (model%m /= m) return
  call mbdk_model_constraints(model, t, y(1:nc), y(nc + 1:), phi, d, gam, phit)
  call mbdk_model_assemble(model, t, y(1:nc), y(nc + 1:), status)
  if (status /= MBDK_SUCCESS) return
  fq = work%fq
  call mbdk_model_accelerations(model, t, y(1:nc), y(nc + 1:), acc, lam, status)
end subroutine model_eval

subroutine model_outputs(nb, mass, inertia, nj, nj1, jint, jreal, nf, nf1, fint, freal, &
                         formulation, fpar, m, nc, ns, t, y, given, acc, lam, reac, energy, &
                         resid, nok, status)
  ! The sampled outputs (accelerations, multipliers, reactions, energy parts, residuals) at
  ! every sample of a trajectory; nok samples were evaluated before a failure. given /= 0: acc
  ! and lam are inputs (an index-3 integrator's own), not recomputed.
  use mbdk_kinds, only: i8
  use mbdk_model, only: mbdk_model_t, mbdk_model_init, mbdk_model_outputs, mbdk_model_work_t
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, formulation, m, nc, ns, given
  double precision, intent(in) :: mass(nb), inertia(nb), jreal(12, nj1), freal(12, nf1), fpar(8)
  integer, intent(in) :: jint(4, nj1), fint(4, nf1)
  double precision, intent(in) :: t(ns), y(2 * nc, ns)
  double precision, intent(in out) :: acc(nc, ns), lam(m, ns)
  double precision, intent(out) :: reac(3, nj1, ns), energy(6, ns)
  double precision, intent(out) :: resid(3, ns)
  integer, intent(out) :: nok, status
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jint) :: nj1 = shape(jint, 1)
!f2py integer intent(hide), depend(fint) :: nf1 = shape(fint, 1)
!f2py integer intent(hide), depend(mass) :: nc = 3 * len(mass)
!f2py integer intent(hide), depend(t) :: ns = len(t)
  type(mbdk_model_t) :: model
  type(mbdk_model_work_t), target :: work
  integer :: k

  if (given == 0) then
    acc = 0.0d0; lam = 0.0d0
  end if
  reac = 0.0d0; energy = 0.0d0; resid = 0.0d0
  nok = 0
  status = MBDK_ERR_INVALID_INPUT
  if (nj < 0 .or. nj > nj1 .or. nf < 0 .or. nf > nf1) return
  call mbdk_model_init(model, mass, inertia, jint(:, 1:nj), jreal(:, 1:nj), fint(:, 1:nf), &
                       freal(:, 1:nf), formulation, fpar, work, status)
  if (status /= MBDK_SUCCESS) return
  status = MBDK_ERR_INVALID_INPUT
  if (model%m /= m) return
  status = MBDK_SUCCESS
  do k = 1, ns
    call mbdk_model_outputs(model, t(k), y(:, k), acc(:, k), lam(:, k), reac(:, 1:nj, k), &
                            energy(:, k), resid(:, k), status, given /= 0)
    if (status /= MBDK_SUCCESS) return
    nok = k
  end do
end subroutine model_outputs

subroutine model_profile(nb, mass, inertia, nj, nj1, jint, jreal, nf, nf1, fint, freal, &
                         formulation, fpar, nc, t, y, nrep, seconds, status)
  ! Where an evaluation's time goes: seconds(1) = nrep evaluations of the assembly alone
  ! (rotations, forces, Phi, D in compact rows, gamma: mbdk_model_assemble), seconds(2) = nrep
  ! full evaluations (assembly + the formulation's linear solve). The linear solve is the
  ! difference; the integrator's share follows from a timed run (studies/scene_drift.py).
  use mbdk_model, only: mbdk_model_t, mbdk_model_init, mbdk_model_assemble, &
    mbdk_model_accelerations, mbdk_model_work_t
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, formulation, nc, nrep
  double precision, intent(in) :: mass(nb), inertia(nb), jreal(12, nj1), freal(12, nf1), fpar(8)
  integer, intent(in) :: jint(4, nj1), fint(4, nf1)
  double precision, intent(in) :: t, y(2 * nc)
  double precision, intent(out) :: seconds(2)
  integer, intent(out) :: status
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jint) :: nj1 = shape(jint, 1)
!f2py integer intent(hide), depend(fint) :: nf1 = shape(fint, 1)
!f2py integer intent(hide), depend(mass) :: nc = 3 * len(mass)
  type(mbdk_model_t) :: model
  type(mbdk_model_work_t), target :: work
  double precision :: c0, c1, acc(nc)
  double precision, allocatable :: lam(:)
  integer :: k

  seconds = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (nj < 0 .or. nj > nj1 .or. nf < 0 .or. nf > nf1 .or. nrep < 1) return
  call mbdk_model_init(model, mass, inertia, jint(:, 1:nj), jreal(:, 1:nj), fint(:, 1:nf), &
                       freal(:, 1:nf), formulation, fpar, work, status)
  if (status /= MBDK_SUCCESS) return
  allocate (lam(model%m))
  call cpu_time(c0)
  do k = 1, nrep
    call mbdk_model_assemble(model, t, y(1:nc), y(nc + 1:), status)
  end do
  call cpu_time(c1)
  seconds(1) = c1 - c0
  call cpu_time(c0)
  do k = 1, nrep
    call mbdk_model_accelerations(model, t, y(1:nc), y(nc + 1:), acc, lam, status)
  end do
  call cpu_time(c1)
  seconds(2) = c1 - c0
end subroutine model_profile

subroutine model_index3_solve(nb, mass, inertia, nj, nj1, jint, jreal, nf, nf1, fint, freal, &
                              fpar, variant, n, y0, t0, t_end, h, every, rtol, atol, max_iter, &
                              alpha, adaptive, err_rtol, err_atol, dt_out, h_min, h_max, &
                              nsamp, m1, t_out, y_out, a_out, lam_out, iters_out, &
                              nwritten, stats, visits, status)
  ! trapezoidal_index3 on a scene (kernel/src/dae/mbdk_trapezoidal_index3.f90): variant 1 =
  ! the book's index-3 scheme, 2 = augmented Lagrangian with projections. m1 = max(m, 1).
  ! adaptive /= 0: step-size control (err_rtol, err_atol on q and v), samples every dt_out.
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t, mbdk_stats_to_array
  use mbdk_model, only: mbdk_model_t, mbdk_model_init, mbdk_model_work_t, MBDK_FORM_REDUCED
  use mbdk_trapezoidal_index3, only: mbdk_index3_solve, mbdk_index3_opt_t
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, variant, n, every, max_iter, nsamp, m1, adaptive
  double precision, intent(in) :: mass(nb), inertia(nb), jreal(12, nj1), freal(12, nf1), fpar(8)
  integer, intent(in) :: jint(4, nj1), fint(4, nf1)
  double precision, intent(in) :: y0(n), t0, t_end, h, rtol, atol, alpha
  double precision, intent(in) :: err_rtol, err_atol, dt_out, h_min, h_max
  double precision, intent(out) :: t_out(nsamp), y_out(n, nsamp), a_out(n / 2, nsamp)
  double precision, intent(out) :: lam_out(m1, nsamp), stats(9), visits(9)
  integer, intent(out) :: iters_out(nsamp), nwritten, status
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jint) :: nj1 = shape(jint, 1)
!f2py integer intent(hide), depend(fint) :: nf1 = shape(fint, 1)
!f2py integer intent(hide), depend(y0) :: n = len(y0)
  type(mbdk_model_t) :: model
  type(mbdk_model_work_t), target :: work
  type(mbdk_index3_opt_t) :: opt
  type(mbdk_stats_t) :: st

  nwritten = 0
  stats = 0.0d0
  visits = 0.0d0
  t_out = 0.0d0; y_out = 0.0d0; a_out = 0.0d0; lam_out = 0.0d0; iters_out = 0
  status = MBDK_ERR_INVALID_INPUT
  if (nj < 0 .or. nj > nj1 .or. nf < 0 .or. nf > nf1 .or. n /= 6 * nb) return
  call mbdk_model_init(model, mass, inertia, jint(:, 1:nj), jreal(:, 1:nj), fint(:, 1:nf), &
                       freal(:, 1:nf), MBDK_FORM_REDUCED, fpar, work, status)
  if (status /= MBDK_SUCCESS) return
  status = MBDK_ERR_INVALID_INPUT
  if (m1 /= max(model%m, 1)) return
  opt%formulation = variant
  opt%h = h
  opt%every = every
  opt%rtol = rtol
  opt%atol = atol
  opt%newton_max_iter = max_iter
  opt%alpha = alpha
  opt%adaptive = adaptive /= 0
  opt%err_rtol = err_rtol
  opt%err_atol = err_atol
  opt%dt_out = dt_out
  opt%h_min = h_min
  opt%h_max = h_max
  call mbdk_index3_solve(model, opt, t0, t_end, y0, t_out, y_out, a_out, lam_out(1:model%m, :), &
                         iters_out, nwritten, st, status)
  stats = mbdk_stats_to_array(st)
  visits = dble(work%visits(1:9))
end subroutine model_index3_solve

subroutine model_index3_matrix(nb, mass, inertia, nj, nj1, jint, jreal, nf, nf1, fint, freal, &
                               fpar, nc, m, t, y, lam, h, scaling, jac, status)
  ! The Newton matrix of trapezoidal_index3 at (q, v, lambda): scaling 0 unscaled, 1 the
  ! book's (3.15)-(3.16), 2 the solver's (dynamic rows times h^2/4, unknown h^2/4 lambda).
  use mbdk_model, only: mbdk_model_t, mbdk_model_init, mbdk_model_work_t, MBDK_FORM_REDUCED
  use mbdk_trapezoidal_index3, only: mbdk_index3_newton_matrix
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, nc, m, scaling
  double precision, intent(in) :: mass(nb), inertia(nb), jreal(12, nj1), freal(12, nf1), fpar(8)
  integer, intent(in) :: jint(4, nj1), fint(4, nf1)
  double precision, intent(in) :: t, y(2 * nc), lam(m), h
  double precision, intent(out) :: jac(nc + m, nc + m)
  integer, intent(out) :: status
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jint) :: nj1 = shape(jint, 1)
!f2py integer intent(hide), depend(fint) :: nf1 = shape(fint, 1)
!f2py integer intent(hide), depend(mass) :: nc = 3 * len(mass)
!f2py integer intent(hide), depend(lam) :: m = len(lam)
  type(mbdk_model_t) :: model
  type(mbdk_model_work_t), target :: work

  jac = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (nj < 0 .or. nj > nj1 .or. nf < 0 .or. nf > nf1) return
  call mbdk_model_init(model, mass, inertia, jint(:, 1:nj), jreal(:, 1:nj), fint(:, 1:nf), &
                       freal(:, 1:nf), MBDK_FORM_REDUCED, fpar, work, status)
  if (status /= MBDK_SUCCESS) return
  status = MBDK_ERR_INVALID_INPUT
  if (model%m /= m) return
  call mbdk_index3_newton_matrix(model, t, y(1:nc), y(nc + 1:), lam, h, scaling, jac, status)
end subroutine model_index3_matrix

subroutine index3_plan(t0, t_end, h, every, adaptive, err_rtol, err_atol, dt_out, h_min, h_max, &
                       nsteps, nsamp, status)
  ! Steps (fixed) or sample intervals (adaptive) and samples of a trapezoidal_index3 solve.
  use mbdk_kinds, only: i8
  use mbdk_trapezoidal_index3, only: mbdk_index3_plan, mbdk_index3_opt_t
  implicit none
  double precision, intent(in) :: t0, t_end, h, err_rtol, err_atol, dt_out, h_min, h_max
  integer, intent(in) :: every, adaptive
  double precision, intent(out) :: nsteps
  integer, intent(out) :: nsamp, status
  type(mbdk_index3_opt_t) :: opt
  integer(i8) :: ns
  logical :: shortened
  opt%h = h
  opt%every = every
  opt%adaptive = adaptive /= 0
  opt%err_rtol = err_rtol
  opt%err_atol = err_atol
  opt%dt_out = dt_out
  opt%h_min = h_min
  opt%h_max = h_max
  call mbdk_index3_plan(opt, t0, t_end, ns, nsamp, shortened, status)
  nsteps = dble(ns)
end subroutine index3_plan
