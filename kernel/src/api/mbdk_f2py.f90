! The f2py-facing layer: plain external subroutines with double precision scalars and
! explicit-shape arrays only, so that numpy.f2py can wrap them as mbdk._kernel. They translate
! to the kernel's modules and derived types and return statuses; nothing here prints or stops.
! Python calls these only through python/mbdk.
!
! Options and statistics cross as the raw bytes of the kernel's bind(C) structs, in 8-byte words
! (optbuf, statbuf): Python lays them out by name from the kernel's own table (struct_field,
! python/mbdk/options.py), so no field travels by array position. A size that does not match the
! struct is refused (MBDK_ERR_INVALID_INPUT).
!
! The solves are marked threadsafe: f2py releases the GIL around them, so two Python threads run
! two solves at once. interrupt(1) is a flag Python may set from another thread to stop a solve
! (the options' interrupt field points at it); interrupt(3:4) hold a double, 8-byte aligned (numpy
! aligns its arrays), where the solve stores the time it has reached (the progress field). The callback solve keeps the GIL: it calls Python.

subroutine solve_problem(problem_id, n, y0, t0, t_end, np, params, noptw, optbuf, interrupt, &
                         natol, atol, ntimes, times, nsamp, t_out, y_out, nstatw, statbuf, &
                         nwritten, status)
  ! atol: empty, or one absolute tolerance per state for an error-controlled method; times:
  ! empty, or its sample times (mbdk_solve_ode), nsamp of them
  use, intrinsic :: iso_c_binding, only: c_loc, c_sizeof, c_intptr_t
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_textbook, only: mbdk_textbook_t, mbdk_textbook_init
  use mbdk_solve, only: mbdk_solve_ode
  implicit none
  integer, intent(in) :: problem_id, n, np, noptw, nsamp, nstatw, natol, ntimes
  double precision, intent(in) :: y0(n), t0, t_end, params(np), optbuf(noptw), atol(natol), &
    times(ntimes)
  integer, intent(in), target :: interrupt(4)
  double precision, intent(out) :: t_out(nsamp), y_out(n, nsamp)
  double precision, intent(inout) :: statbuf(nstatw)
  integer, intent(out) :: nwritten, status
!f2py threadsafe
!f2py integer intent(hide), depend(y0) :: n = len(y0)
!f2py integer intent(hide), depend(params) :: np = len(params)
!f2py integer intent(hide), depend(optbuf) :: noptw = len(optbuf)
!f2py integer intent(hide), depend(atol) :: natol = len(atol)
!f2py integer intent(hide), depend(times) :: ntimes = len(times)
!f2py integer intent(hide), depend(statbuf) :: nstatw = len(statbuf)
  type(mbdk_textbook_t) :: prob
  type(mbdk_options_t) :: opt
  type(mbdk_stats_t) :: st

  nwritten = 0
  t_out = 0.0d0
  y_out = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (8 * noptw /= c_sizeof(opt) .or. 8 * nstatw /= c_sizeof(st)) return
  opt = transfer(optbuf, opt)
  opt%interrupt = transfer(c_loc(interrupt), 0_c_intptr_t)
  opt%progress = transfer(c_loc(interrupt(3)), 0_c_intptr_t)
  call mbdk_textbook_init(prob, problem_id, n, params, status)
  if (status /= MBDK_SUCCESS) return
  call mbdk_solve_ode(prob, opt, t0, t_end, y0, t_out, y_out, nwritten, st, status, atol, times)
  statbuf = transfer(st, statbuf, nstatw)
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

subroutine solve_callback(fun, jfun, use_jac, n, y0, t0, t_end, noptw, optbuf, natol, atol, &
                          ntimes, times, nsamp, t_out, y_out, nstatw, statbuf, nwritten, status)
  ! The slow path: F is a Python function fun(t, y, dydt, flag) filling dydt in place
  ! (f2py hides n); flag(1) = 1 reports a failure. With use_jac /= 0, jfun(t, y, dfdy, flag)
  ! fills its Jacobian dfdy (n x n) in place for the implicit methods' Newton (else jfun is
  ! never called: finite differences). times: as solve_problem's. Not threadsafe: it calls
  ! Python.
  use, intrinsic :: iso_c_binding, only: c_sizeof
  use mbdk_status, only: MBDK_ERR_INVALID_INPUT
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_callback_problem, only: mbdk_proc_problem_t, mbdk_proc_problem_init
  use mbdk_solve, only: mbdk_solve_ode
  implicit none
  external fun, jfun
  integer, intent(in) :: n, noptw, nsamp, nstatw, natol, use_jac, ntimes
  double precision, intent(in) :: y0(n), t0, t_end, optbuf(noptw), atol(natol), times(ntimes)
  double precision, intent(out) :: t_out(nsamp), y_out(n, nsamp)
  double precision, intent(inout) :: statbuf(nstatw)
  integer, intent(out) :: nwritten, status
!f2py integer intent(hide), depend(y0) :: n = len(y0)
!f2py integer intent(hide), depend(optbuf) :: noptw = len(optbuf)
!f2py integer intent(hide), depend(atol) :: natol = len(atol)
!f2py integer intent(hide), depend(times) :: ntimes = len(times)
!f2py integer intent(hide), depend(statbuf) :: nstatw = len(statbuf)
  ! The callback's signature for f2py: its first argument is named n so that the bounds of
  ! cb_y and cb_dydt refer to the callback's own argument.
  integer :: cb_flag(1)
  double precision :: cb_t, cb_y(n), cb_dydt(n)
!f2py call fun(n, cb_t, cb_y, cb_dydt, cb_flag)
  double precision :: cb_jac(n, n)
!f2py call jfun(n, cb_t, cb_y, cb_jac, cb_flag)
  type(mbdk_proc_problem_t) :: prob
  type(mbdk_options_t) :: opt
  type(mbdk_stats_t) :: st

  nwritten = 0
  t_out = 0.0d0
  y_out = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (8 * noptw /= c_sizeof(opt) .or. 8 * nstatw /= c_sizeof(st)) return
  opt = transfer(optbuf, opt)
  if (use_jac /= 0) then
    call mbdk_proc_problem_init(prob, fun, n, int(opt%nq), jfun)
  else
    call mbdk_proc_problem_init(prob, fun, n, int(opt%nq))
  end if
  call mbdk_solve_ode(prob, opt, t0, t_end, y0, t_out, y_out, nwritten, st, status, atol, times)
  statbuf = transfer(st, statbuf, nstatw)
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

subroutine adaptive_sample_count(t0, t_end, dt_out, nsamp, status)
  ! Samples of an error-controlled solve: t0, every dt_out, t_end (mbdk_adaptive).
  use mbdk_adaptive, only: mbdk_adaptive_plan
  implicit none
  double precision, intent(in) :: t0, t_end, dt_out
  integer, intent(out) :: nsamp, status
  call mbdk_adaptive_plan(t0, t_end, dt_out, nsamp, status)
end subroutine adaptive_sample_count

subroutine max_steps(n)
  ! The most steps one fixed-step solve takes (mbdk_fixed_step), for Python's messages.
  use mbdk_fixed_step, only: MBDK_MAX_STEPS
  implicit none
  double precision, intent(out) :: n
  n = dble(MBDK_MAX_STEPS)
end subroutine max_steps

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

subroutine scene_run(nb, mass, inertia, bkind, nj, nj1, jint, jreal, nf, nf1, fint, freal, nmow, &
                     mobuf, method_id, dae_form, noptw, optbuf, ni3w, i3buf, ntimes, times, &
                     interrupt, n, y0, given, assemble, t0, t_end, want, nsamp, nc, m1, na, nl, &
                     ni, nr, ne, nrs, t_out, y_out, a_out, lam_out, iters_out, reac, energy, &
                     resid, nwritten, nstatw, statbuf, nvis, visits, linear_solve, asm_iters, &
                     asm_resid, asm_velocity, bad_joint, bad_force, nwrw, wrbuf, invariants, &
                     ninv, status)
  ! The one entry that runs a planar scene. The model is built and its initial state assembled
  ! (mbdk_entry_planar_start: the coordinates whose given(:) is 0 move; asm_iters corrections;
  ! on failure, MBDK_ERR_INCONSISTENT_INITIAL, asm_resid holds the residual rows, of the
  ! velocities when asm_velocity /= 0; bad_joint, bad_force: the element a pose default failed
  ! on), the method integrates it on the route of (method_id, dae_form) (mbdk_entry) from the
  ! assembled state (the first sample; times: an ODE method's sample times, none: opt's grid),
  ! and the outputs want asks for (MBDK_OUT_* bits) are computed at the samples
  ! (mbdk_entry_planar_outputs; energy(9, :): kinetic, gravity and spring energy, the powers of
  ! dampers, constraints and loads, and their work). An output array not asked for may have
  ! one column. visits: the model's visit counters over the call;
  ! linear_solve: the path of the model's solves (MBDK_SOLVE_*); wrbuf: a drift failure's
  ! report (mbdk_watch_report_t); invariants(:, 1:ninv): the components of the momentum and
  ! angular momentum the scene conserves (mbdk_watch), which a momentum failure's row counts.
  use, intrinsic :: iso_c_binding, only: c_loc, c_sizeof, c_intptr_t
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_model, only: mbdk_model_t, mbdk_model_work_t, mbdk_model_options_t, &
    mbdk_model_linear_solve, MBDK_OUT_ALL, MBDK_VISIT_COUNT
  use mbdk_trapezoidal_index3, only: mbdk_index3_options_t
  use mbdk_entry, only: mbdk_entry_options, mbdk_entry_integrate, mbdk_entry_route, &
    mbdk_entry_planar_start, mbdk_entry_planar_sizes_ok, mbdk_entry_planar_outputs, &
    MBDK_ROUTE_DAE, MBDK_ROUTE_INDEX3
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT, MBDK_ERR_OUTPUT_SIZE, &
    MBDK_ERR_NO_MEMORY, mbdk_is_failure
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  use mbdk_watch, only: mbdk_watch_report_t, mbdk_watch_report_of
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, nmow, method_id, dae_form, noptw, ni3w, n, want, ntimes
  integer, intent(in) :: nsamp
  integer, intent(in) :: nc, m1, na, nl, ni, nr, ne, nrs, nstatw, nvis, nwrw
  double precision, intent(in) :: mass(nb), inertia(nb), jreal(12, nj1), freal(12, nf1)
  integer, intent(in) :: bkind(nb)
  integer, intent(in) :: jint(4, nj1), fint(4, nf1)
  double precision, intent(in) :: mobuf(nmow), optbuf(noptw), i3buf(ni3w), times(ntimes)
  integer, intent(in), target :: interrupt(4)
  double precision, intent(in) :: y0(n), t0, t_end
  integer, intent(in) :: given(n), assemble
  double precision, intent(out) :: t_out(nsamp), y_out(n, nsamp)
  double precision, intent(inout) :: a_out(nc, na), lam_out(m1, nl), reac(3, nj1, nr)
  double precision, intent(inout) :: energy(9, ne), resid(3, nrs), statbuf(nstatw), visits(nvis)
  double precision, intent(inout) :: wrbuf(nwrw)
  integer, intent(inout) :: iters_out(ni)
  integer, intent(out) :: nwritten, linear_solve, status, asm_iters, asm_velocity, bad_joint
  integer, intent(out) :: bad_force
  double precision, intent(out) :: asm_resid(m1), invariants(7, 6)
  integer, intent(out) :: ninv
!f2py threadsafe
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jint) :: nj1 = shape(jint, 1)
!f2py integer intent(hide), depend(fint) :: nf1 = shape(fint, 1)
!f2py integer intent(hide), depend(mobuf) :: nmow = len(mobuf)
!f2py integer intent(hide), depend(optbuf) :: noptw = len(optbuf)
!f2py integer intent(hide), depend(i3buf) :: ni3w = len(i3buf)
!f2py integer intent(hide), depend(times) :: ntimes = len(times)
!f2py integer intent(hide), depend(y0) :: n = len(y0)
!f2py integer intent(hide), depend(a_out) :: nc = shape(a_out, 0)
!f2py integer intent(hide), depend(a_out) :: na = shape(a_out, 1)
!f2py integer intent(hide), depend(lam_out) :: m1 = shape(lam_out, 0)
!f2py integer intent(hide), depend(lam_out) :: nl = shape(lam_out, 1)
!f2py integer intent(hide), depend(iters_out) :: ni = len(iters_out)
!f2py integer intent(hide), depend(reac) :: nr = shape(reac, 2)
!f2py integer intent(hide), depend(energy) :: ne = shape(energy, 1)
!f2py integer intent(hide), depend(resid) :: nrs = shape(resid, 1)
!f2py integer intent(hide), depend(statbuf) :: nstatw = len(statbuf)
!f2py integer intent(hide), depend(visits) :: nvis = len(visits)
!f2py integer intent(hide), depend(wrbuf) :: nwrw = len(wrbuf)
  type(mbdk_model_t) :: model
  type(mbdk_model_work_t), target :: work
  type(mbdk_model_options_t) :: mopt
  type(mbdk_options_t) :: opt
  type(mbdk_index3_options_t) :: i3
  type(mbdk_stats_t) :: st
  type(mbdk_watch_report_t) :: wr
  integer :: m, astat, route, ka, ki
  logical :: index3
  double precision, allocatable :: ys(:)
  logical :: vel

  nwritten = 0
  linear_solve = -1
  invariants = 0.0d0
  ninv = 0
  asm_iters = 0
  asm_resid = 0.0d0
  asm_velocity = 0
  bad_joint = 0
  bad_force = 0
  t_out = 0.0d0
  y_out = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (8 * nmow /= c_sizeof(mopt) .or. 8 * nstatw /= c_sizeof(st) .or. &
      8 * nwrw /= c_sizeof(wr)) return
  wrbuf = transfer(wr, wrbuf, nwrw)
  ! y = [q; v; w]: the effects' states w after the bodies' (mbdk_model), checked once it is built
  if (nj < 0 .or. nj > nj1 .or. nf < 0 .or. nf > nf1 .or. n < 6 * nb .or. nc /= 3 * nb) return
  if (want < 0 .or. want > MBDK_OUT_ALL .or. nvis /= MBDK_VISIT_COUNT) return
  route = mbdk_entry_route(method_id, dae_form)
  if (route == 0) return
  index3 = route == MBDK_ROUTE_INDEX3
  call mbdk_entry_options(method_id, optbuf, i3buf, transfer(c_loc(interrupt), 0_c_intptr_t), &
                          transfer(c_loc(interrupt(3)), 0_c_intptr_t), opt, i3, status)
  if (status /= MBDK_SUCCESS) return
  mopt = transfer(mobuf, mopt)
  ! a failure from here on reports its statistics (alloc_bytes: MBDK_ERR_NO_MEMORY's size)
  allocate (ys(n), stat=astat)
  call mbdk_alloc_status(astat, MBDK_REAL_BYTES * n, status, st%alloc_bytes)
  if (status /= MBDK_SUCCESS) then
    statbuf = transfer(st, statbuf, nstatw)
    return
  end if
  ys = y0
  call mbdk_entry_planar_start(model, work, mass, inertia, bkind, jint(:, 1:nj), jreal(:, 1:nj), &
                               fint(:, 1:nf), freal(:, 1:nf), mopt, t0, ys, given /= 0, &
                               assemble /= 0, want, nsamp, m1, asm_iters, asm_resid, vel, &
                               bad_joint, bad_force, st, status)
  asm_velocity = merge(1, 0, vel)
  if (status /= MBDK_SUCCESS) then
    statbuf = transfer(st, statbuf, nstatw)
    return
  end if
  linear_solve = mbdk_model_linear_solve(model)
  ninv = model%ninv
  invariants = model%inv
  m = model%m
  status = MBDK_ERR_OUTPUT_SIZE
  if (.not. mbdk_entry_planar_sizes_ok(route, want, nsamp, na, nl, ni, nr, ne, nrs)) return
  ! the index-3 family writes its a, lam and iterations at every sample, a DAE its lam
  ka = merge(nsamp, min(na, 1), index3)
  ki = merge(nsamp, min(ni, 1), index3)
  call mbdk_entry_integrate(model, opt, i3, dae_form, t0, t_end, ys, t_out, y_out, a_out(:, 1:ka), &
                            lam_out(1:m, 1:merge(nsamp, nl, index3)), iters_out(1:ki), nwritten, &
                            st, status, times=times)
  if (want /= 0 .and. nwritten > 0) &
    call mbdk_entry_planar_outputs(model, work, t_out, y_out, nwritten, want, index3, &
                                   route == MBDK_ROUTE_DAE, nj, a_out, lam_out, reac, energy, &
                                   resid, status, st)
  ! a record of the work that could not be allocated: the samples' W is incomplete
  if (work%watch%rec_lost .and. .not. mbdk_is_failure(status)) status = MBDK_ERR_NO_MEMORY
  statbuf = transfer(st, statbuf, nstatw)
  visits = dble(work%visits)
  wrbuf = transfer(mbdk_watch_report_of(work%watch), wrbuf, nwrw)
end subroutine scene_run

subroutine tables_resolve(nb, nj, nj1, jint, jreal, nf, nf1, fint, freal, nc, q, bad_joint, &
                          bad_force, status)
  ! The tables' pose defaults filled in at q (mbdk_assembly): rest lengths of two-point forces
  ! and relative angles of prismatic and fixed joints marked MBDK_FROM_POSE.
  use mbdk_status, only: MBDK_ERR_INVALID_INPUT
  use mbdk_assembly, only: mbdk_tables_resolve
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, nc
  integer, intent(in) :: jint(4, nj1), fint(4, nf1)
  double precision, intent(inout) :: jreal(12, nj1), freal(12, nf1)
  double precision, intent(in) :: q(nc)
  integer, intent(out) :: bad_joint, bad_force, status
!f2py integer intent(hide), depend(jint) :: nj1 = shape(jint, 1)
!f2py integer intent(hide), depend(fint) :: nf1 = shape(fint, 1)
!f2py integer intent(hide), depend(q) :: nc = len(q)
  bad_joint = 0
  bad_force = 0
  status = MBDK_ERR_INVALID_INPUT   ! counts beyond the arrays
  if (nj < 0 .or. nj > nj1 .or. nf < 0 .or. nf > nf1) return
  call mbdk_tables_resolve(nb, jint(:, 1:nj), jreal(:, 1:nj), fint(:, 1:nf), freal(:, 1:nf), q, &
                           bad_joint, bad_force, status)
end subroutine tables_resolve

subroutine model_assemble(nb, mass, inertia, bkind, nj, nj1, jint, jreal, nf, nf1, fint, freal, nc, &
                          t0, q, v, given, m1, iterations, resid, velocity, status)
  ! Initial conditions from the scene's (q, v) that satisfy the constraints (mbdk_assembly):
  ! the coordinates whose given(:) is 0 move; q and v are updated in place.
  use, intrinsic :: iso_c_binding, only: c_sizeof
  use mbdk_model, only: mbdk_model_t, mbdk_model_init, mbdk_model_work_t, mbdk_model_options_t
  use mbdk_assembly, only: mbdk_assembly_run
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, nc, m1
  double precision, intent(in) :: mass(nb), inertia(nb), jreal(12, nj1), freal(12, nf1), t0
  integer, intent(in) :: bkind(nb)
  integer, intent(in) :: jint(4, nj1), fint(4, nf1), given(2 * nc)
  double precision, intent(inout) :: q(nc), v(nc)
  integer, intent(out) :: iterations, velocity, status
  double precision, intent(out) :: resid(m1)
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jint) :: nj1 = shape(jint, 1)
!f2py integer intent(hide), depend(fint) :: nf1 = shape(fint, 1)
!f2py integer intent(hide), depend(q) :: nc = len(q)
  type(mbdk_model_t) :: model
  type(mbdk_model_work_t), target :: work
  type(mbdk_model_options_t) :: mopt
  logical :: vel

  iterations = 0
  velocity = 0
  resid = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (nj < 0 .or. nj > nj1 .or. nf < 0 .or. nf > nf1 .or. nc /= 3 * nb) return
  call mbdk_model_init(model, mass, inertia, jint(:, 1:nj), jreal(:, 1:nj), fint(:, 1:nf), &
                       freal(:, 1:nf), mopt, work, status, bkind)
  if (status /= MBDK_SUCCESS) return
  status = MBDK_ERR_INVALID_INPUT
  if (m1 < max(model%m, 1)) return
  call mbdk_assembly_run(model, t0, q, v, given(1:nc) /= 0, given(nc + 1:) /= 0, 1.0d-12, 50, &
                         iterations, resid(1:model%m), vel, status)
  velocity = merge(1, 0, vel)
end subroutine model_assemble

subroutine element_kind(i, cls, code, name, on, rows, states)
  ! Entry i of the element registry (mbdk_elements); cls = 0 past the end. on: the body kinds
  ! it applies to (bit k - 1: body kind k), rows(k): its constraint rows on body kind k. The
  ! i-th entry's name is also the name of scene_run's visits(i).
  use mbdk_elements, only: mbdk_element_kind
  implicit none
  integer, intent(in) :: i
  ! rows(2): MBDK_BODY_KINDS (f2py reads no constant of the kernel's modules; a mismatch is a
  ! compile-time error here, the sizes being known)
  integer, intent(out) :: cls, code, on, rows(2), states
  character(len=32), intent(out) :: name
  call mbdk_element_kind(i, cls, code, name, on, rows, states)
end subroutine element_kind

subroutine body_kind(i, code, name, coords, velocities, available)
  ! Entry i of the body kinds (mbdk_elements); code = 0 past the end. available = 0: declared,
  ! not yet simulated by any model.
  use mbdk_elements, only: mbdk_body_kind
  implicit none
  integer, intent(in) :: i
  integer, intent(out) :: code, coords, velocities, available
  character(len=32), intent(out) :: name
  logical :: avail
  call mbdk_body_kind(i, code, name, coords, velocities, avail)
  available = merge(1, 0, avail)
end subroutine body_kind

subroutine struct_info(id, cname, nbytes, nfields)
  ! The kernel's bind(C) struct id (mbdk_structs): C name, size in bytes, field count (0: none).
  use mbdk_structs, only: mbdk_struct_info
  implicit none
  integer, intent(in) :: id
  character(len=32), intent(out) :: cname
  integer, intent(out) :: nbytes, nfields
  call mbdk_struct_info(id, cname, nbytes, nfields)
end subroutine struct_info

subroutine struct_field(id, i, name, offset, ftype)
  use mbdk_structs, only: mbdk_struct_field
  implicit none
  integer, intent(in) :: id, i
  character(len=32), intent(out) :: name
  integer, intent(out) :: offset, ftype
  call mbdk_struct_field(id, i, name, offset, ftype)
end subroutine struct_field

subroutine struct_defaults(id, nw, buf)
  ! The default-initialised struct as bytes (nw 8-byte words).
  use mbdk_structs, only: mbdk_struct_defaults
  implicit none
  integer, intent(in) :: id, nw
  double precision, intent(out) :: buf(nw)
  call mbdk_struct_defaults(id, buf)
end subroutine struct_defaults

subroutine model_eval(nb, mass, inertia, bkind, nj, nj1, jint, jreal, nf, nf1, fint, freal, &
                      nmow, mobuf, m, nc, t, y, phi, d, gam, phit, fq, acc, lam, path, status)
  ! Phi, D, gamma, Phi_t, the generalised forces and the formulation's accelerations and
  ! multipliers at one state: for assembly, diagnosis and tests. path: the linear solve the
  ! evaluation took (MBDK_SOLVE_* of mbdk_model).
  use mbdk_kinds, only: i8
  use, intrinsic :: iso_c_binding, only: c_sizeof
  use mbdk_model, only: mbdk_model_t, mbdk_model_init, mbdk_model_constraints, &
    mbdk_model_accelerations, mbdk_model_work_t, mbdk_model_assemble, mbdk_model_linear_solve, &
    mbdk_model_options_t
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, nmow, m, nc
  double precision, intent(in) :: mass(nb), inertia(nb), jreal(12, nj1), freal(12, nf1), mobuf(nmow)
  integer, intent(in) :: bkind(nb)
  integer, intent(in) :: jint(4, nj1), fint(4, nf1)
  double precision, intent(in) :: t, y(2 * nc)
  double precision, intent(out) :: phi(m), d(m, nc), gam(m), phit(m), fq(nc), acc(nc), lam(m)
  integer, intent(out) :: path, status
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jint) :: nj1 = shape(jint, 1)
!f2py integer intent(hide), depend(fint) :: nf1 = shape(fint, 1)
!f2py integer intent(hide), depend(mobuf) :: nmow = len(mobuf)
!f2py integer intent(hide), depend(mass) :: nc = 3 * len(mass)
  type(mbdk_model_t) :: model
  type(mbdk_model_work_t), target :: work
  type(mbdk_model_options_t) :: mopt

  path = -1
  phi = 0.0d0; d = 0.0d0; gam = 0.0d0; phit = 0.0d0; fq = 0.0d0; acc = 0.0d0; lam = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (nj < 0 .or. nj > nj1 .or. nf < 0 .or. nf > nf1) return
  if (8 * nmow /= c_sizeof(mopt)) return
  mopt = transfer(mobuf, mopt)
  call mbdk_model_init(model, mass, inertia, jint(:, 1:nj), jreal(:, 1:nj), fint(:, 1:nf), &
                       freal(:, 1:nf), mopt, work, status, bkind)
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

subroutine contact_states(ny, nf, nf1, fint, freal, nc, nsamp, y, nct, out, status)
  ! Each contact's penetration, its rate, normal force and friction force at the samples y(:,
  ! k) = [q; v; ...] of a planar run (mbdk_contact_states; fint, freal: the scene's force table
  ! as the run's model took it, pose values resolved): out(4, nct, nsamp), nct contacts in table
  ! order. NaN where a sample has none (a penetrating contact without a normal).
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use mbdk_contact, only: mbdk_contact_states
  use mbdk_elements, only: MBDK_FORCE_CONTACT
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT, MBDK_ERR_NONFINITE
  implicit none
  integer, intent(in) :: ny, nf, nf1, nc, nsamp, nct
  integer, intent(in) :: fint(4, nf1)
  double precision, intent(in) :: freal(12, nf1), y(ny, nsamp)
  double precision, intent(out) :: out(4, nct, nsamp)
  integer, intent(out) :: status
!f2py integer intent(hide), depend(fint) :: nf1 = shape(fint, 1)
!f2py integer intent(hide), depend(y) :: ny = shape(y, 0)
!f2py integer intent(hide), depend(y) :: nsamp = shape(y, 1)
  integer :: k, s
  out = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (nf < 0 .or. nf > nf1 .or. nc < 3 .or. 2 * nc > ny .or. nct < 0) return
  if (count(fint(1, 1:nf) == MBDK_FORCE_CONTACT) /= nct) return
  status = MBDK_SUCCESS
  do k = 1, nsamp
    call mbdk_contact_states(fint(:, 1:nf), freal(:, 1:nf), y(1:nc, k), y(nc + 1:2 * nc, k), &
                             out(:, :, k), s)
    if (s == MBDK_ERR_NONFINITE) then
      out(:, :, k) = ieee_value(0.0d0, ieee_quiet_nan)
    else if (s /= MBDK_SUCCESS) then
      status = s
      return
    end if
  end do
end subroutine contact_states

subroutine model_profile(nb, mass, inertia, bkind, nj, nj1, jint, jreal, nf, nf1, fint, freal, &
                         nmow, mobuf, nc, t, y, nrep, seconds, status)
  ! Where an evaluation's time goes: seconds(1) = nrep evaluations of the assembly alone
  ! (rotations, forces, Phi, D in compact rows, gamma: mbdk_model_assemble), seconds(2) = nrep
  ! full evaluations (assembly + the formulation's linear solve). The linear solve is the
  ! difference; the integrator's share follows from a timed run (studies/scene_drift.py).
  use, intrinsic :: iso_c_binding, only: c_sizeof
  use mbdk_clock, only: mbdk_thread_cpu_seconds
  use mbdk_model, only: mbdk_model_t, mbdk_model_init, mbdk_model_assemble, &
    mbdk_model_accelerations, mbdk_model_work_t, mbdk_model_options_t
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT, MBDK_ERR_NO_MEMORY
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, nmow, nc, nrep
  double precision, intent(in) :: mass(nb), inertia(nb), jreal(12, nj1), freal(12, nf1), mobuf(nmow)
  integer, intent(in) :: bkind(nb)
  integer, intent(in) :: jint(4, nj1), fint(4, nf1)
  double precision, intent(in) :: t, y(2 * nc)
  double precision, intent(out) :: seconds(2)
  integer, intent(out) :: status
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jint) :: nj1 = shape(jint, 1)
!f2py integer intent(hide), depend(fint) :: nf1 = shape(fint, 1)
!f2py integer intent(hide), depend(mobuf) :: nmow = len(mobuf)
!f2py integer intent(hide), depend(mass) :: nc = 3 * len(mass)
  type(mbdk_model_t) :: model
  type(mbdk_model_work_t), target :: work
  type(mbdk_model_options_t) :: mopt
  double precision :: c0, c1
  double precision, allocatable :: lam(:), acc(:)
  integer :: k

  seconds = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (nj < 0 .or. nj > nj1 .or. nf < 0 .or. nf > nf1 .or. nrep < 1) return
  if (8 * nmow /= c_sizeof(mopt)) return
  mopt = transfer(mobuf, mopt)
  call mbdk_model_init(model, mass, inertia, jint(:, 1:nj), jreal(:, 1:nj), fint(:, 1:nf), &
                       freal(:, 1:nf), mopt, work, status, bkind)
  if (status /= MBDK_SUCCESS) return
  allocate (lam(model%m), acc(nc), stat=k)
  if (k /= 0) then
    status = MBDK_ERR_NO_MEMORY
    return
  end if
  c0 = mbdk_thread_cpu_seconds()
  do k = 1, nrep
    call mbdk_model_assemble(model, t, y(1:nc), y(nc + 1:), status)
  end do
  c1 = mbdk_thread_cpu_seconds()
  seconds(1) = c1 - c0
  c0 = mbdk_thread_cpu_seconds()
  do k = 1, nrep
    call mbdk_model_accelerations(model, t, y(1:nc), y(nc + 1:), acc, lam, status)
  end do
  c1 = mbdk_thread_cpu_seconds()
  seconds(2) = c1 - c0
end subroutine model_profile

subroutine model_index3_matrix(nb, mass, inertia, bkind, nj, nj1, jint, jreal, nf, nf1, fint, freal, &
                               nmow, mobuf, nc, m, t, y, lam, h, scaling, jac, status)
  ! The Newton matrix of trapezoidal_index3 at (q, v, lambda): scaling 0 unscaled, 1 the
  ! book's (3.15)-(3.16), 2 the solver's (dynamic rows times h^2/4, unknown h^2/4 lambda).
  use, intrinsic :: iso_c_binding, only: c_sizeof
  use mbdk_model, only: mbdk_model_t, mbdk_model_init, mbdk_model_work_t, mbdk_model_options_t
  use mbdk_index3_matrix, only: mbdk_index3_newton_matrix
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, nmow, nc, m, scaling
  double precision, intent(in) :: mass(nb), inertia(nb), jreal(12, nj1), freal(12, nf1), mobuf(nmow)
  integer, intent(in) :: bkind(nb)
  integer, intent(in) :: jint(4, nj1), fint(4, nf1)
  double precision, intent(in) :: t, y(2 * nc), lam(m), h
  double precision, intent(out) :: jac(nc + m, nc + m)
  integer, intent(out) :: status
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jint) :: nj1 = shape(jint, 1)
!f2py integer intent(hide), depend(fint) :: nf1 = shape(fint, 1)
!f2py integer intent(hide), depend(mobuf) :: nmow = len(mobuf)
!f2py integer intent(hide), depend(mass) :: nc = 3 * len(mass)
!f2py integer intent(hide), depend(lam) :: m = len(lam)
  type(mbdk_model_t) :: model
  type(mbdk_model_work_t), target :: work
  type(mbdk_model_options_t) :: mopt

  jac = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (nj < 0 .or. nj > nj1 .or. nf < 0 .or. nf > nf1) return
  if (8 * nmow /= c_sizeof(mopt)) return
  mopt = transfer(mobuf, mopt)
  call mbdk_model_init(model, mass, inertia, jint(:, 1:nj), jreal(:, 1:nj), fint(:, 1:nf), &
                       freal(:, 1:nf), mopt, work, status, bkind)
  if (status /= MBDK_SUCCESS) return
  status = MBDK_ERR_INVALID_INPUT
  if (model%m /= m) return
  call mbdk_index3_newton_matrix(model, t, y(1:nc), y(nc + 1:), lam, h, scaling, jac, status)
end subroutine model_index3_matrix

subroutine index3_constants(max_cuts, retry_budget)
  ! The index-3 solver's retry limits, for the messages Python writes: substeps down to
  ! h / 4^max_cuts (fixed step), and the retry budget (failures before a run gives up).
  use mbdk_trapezoidal_index3, only: MBDK_INDEX3_MAX_CUTS, MBDK_INDEX3_RETRY_BUDGET
  implicit none
  integer, intent(out) :: max_cuts, retry_budget
  max_cuts = MBDK_INDEX3_MAX_CUTS
  retry_budget = nint(MBDK_INDEX3_RETRY_BUDGET)
end subroutine index3_constants

subroutine model_constants(near_pivot, rank_window)
  ! For the messages Python writes: the relative pivot of D M^-1 D^T below which the reduced
  ! formulation refuses a pose, and the window in which a DAE form's stop is named by a
  ! singular pose (mbdk_mechanism).
  use mbdk_model, only: MBDK_MODEL_NEAR_PIVOT
  use mbdk_mechanism, only: MBDK_RANK_LOSS_WINDOW
  implicit none
  double precision, intent(out) :: near_pivot, rank_window
  near_pivot = MBDK_MODEL_NEAR_PIVOT
  rank_window = MBDK_RANK_LOSS_WINDOW
end subroutine model_constants

subroutine index3_error_constants(ni3w, i3buf, lte_q, lte_v, status)
  ! The constants of the index-3 family's local errors in q and v (h^3 q''' lte_q, h^3 q''''
  ! lte_v) for the options' parameters: what its step-size control estimates with.
  use, intrinsic :: iso_c_binding, only: c_sizeof
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT
  use mbdk_trapezoidal_index3, only: mbdk_index3_error_constants, mbdk_index3_options_t
  implicit none
  integer, intent(in) :: ni3w
  double precision, intent(in) :: i3buf(ni3w)
  double precision, intent(out) :: lte_q, lte_v
  integer, intent(out) :: status
!f2py integer intent(hide), depend(i3buf) :: ni3w = len(i3buf)
  type(mbdk_index3_options_t) :: opt
  lte_q = 0.0d0
  lte_v = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (8 * ni3w /= c_sizeof(opt)) return
  opt = transfer(i3buf, opt)
  call mbdk_index3_error_constants(opt, lte_q, lte_v)
  status = MBDK_SUCCESS
end subroutine index3_error_constants

subroutine index3_plan(ni3w, i3buf, t0, t_end, nsteps, nsamp, status)
  ! Steps (fixed) or sample intervals (adaptive) and samples of a trapezoidal_index3 solve.
  use, intrinsic :: iso_c_binding, only: c_sizeof
  use mbdk_kinds, only: i8
  use mbdk_status, only: MBDK_ERR_INVALID_INPUT
  use mbdk_trapezoidal_index3, only: mbdk_index3_plan, mbdk_index3_options_t
  implicit none
  integer, intent(in) :: ni3w
  double precision, intent(in) :: i3buf(ni3w), t0, t_end
  double precision, intent(out) :: nsteps
  integer, intent(out) :: nsamp, status
!f2py integer intent(hide), depend(i3buf) :: ni3w = len(i3buf)
  type(mbdk_index3_options_t) :: opt
  integer(i8) :: ns
  logical :: shortened
  nsteps = 0.0d0
  nsamp = 0
  status = MBDK_ERR_INVALID_INPUT
  if (8 * ni3w /= c_sizeof(opt)) return
  opt = transfer(i3buf, opt)
  call mbdk_index3_plan(opt, t0, t_end, ns, nsamp, shortened, status)
  nsteps = dble(ns)
end subroutine index3_plan

subroutine rotation_matrix(kind, x, seq, r, status)
  ! The rotation matrix of a parametrisation (mbdk_rotations): kind 1 angles x(1:3) in the
  ! sequence seq, 2 a quaternion x (scalar first), 3 an axis x(1:3) and angle x(4).
  use mbdk_rotations, only: mbdk_angles_matrix, mbdk_quat_matrix, mbdk_rodrigues
  use mbdk_status, only: MBDK_ERR_INVALID_INPUT
  implicit none
  integer, intent(in) :: kind, seq(3)
  double precision, intent(in) :: x(4)
  double precision, intent(out) :: r(3, 3)
  integer, intent(out) :: status
  r = 0.0d0
  select case (kind)
  case (1)
    call mbdk_angles_matrix(seq, x(1:3), r, status)
  case (2)
    call mbdk_quat_matrix(x, r, status)
  case (3)
    call mbdk_rodrigues(x(1:3), x(4), r, status)
  case default
    status = MBDK_ERR_INVALID_INPUT
  end select
end subroutine rotation_matrix

subroutine rotation_from_matrix(r, q, axis, angle, status)
  ! A rotation matrix's unit quaternion (scalar first, s >= 0) and its axis and angle.
  use mbdk_rotations, only: mbdk_quat_from_matrix, mbdk_axis_angle_from_matrix
  use mbdk_status, only: MBDK_SUCCESS
  implicit none
  double precision, intent(in) :: r(3, 3)
  double precision, intent(out) :: q(4), axis(3), angle
  integer, intent(out) :: status
  call mbdk_quat_from_matrix(r, q, status)
  if (status == MBDK_SUCCESS) call mbdk_axis_angle_from_matrix(r, axis, angle, status)
end subroutine rotation_from_matrix

subroutine angle_rate_maps(seq, a, gs, gb, det, status)
  ! omega = gs a', Omega = gb a' for the angles a in the sequence seq (mbdk_rotations).
  use mbdk_rotations, only: mbdk_angles_rate_maps
  implicit none
  integer, intent(in) :: seq(3)
  double precision, intent(in) :: a(3)
  double precision, intent(out) :: gs(3, 3), gb(3, 3), det
  integer, intent(out) :: status
  call mbdk_angles_rate_maps(seq, a, gs, gb, det, status)
end subroutine angle_rate_maps

subroutine angle_rates(seq, a, w, body, ad, status)
  ! The angle rates of an angular velocity w (body = 1: body frame); gimbal lock:
  ! ERR_SINGULAR_MATRIX.
  use mbdk_rotations, only: mbdk_angles_rates
  implicit none
  integer, intent(in) :: seq(3), body
  double precision, intent(in) :: a(3), w(3)
  double precision, intent(out) :: ad(3)
  integer, intent(out) :: status
  call mbdk_angles_rates(seq, a, w, body /= 0, ad, status)
end subroutine angle_rates

subroutine quaternion_ops(p, q, w, body, pq, qd, wq, status)
  ! The product p q, the rates qd of q under the angular velocity w, and back from qd the
  ! angular velocity wq (body = 1: body frame), for a unit q.
  use mbdk_rotations, only: mbdk_quat_mul, mbdk_quat_rates, mbdk_quat_omega, MBDK_UNIT_TOL
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT
  implicit none
  double precision, intent(in) :: p(4), q(4), w(3)
  integer, intent(in) :: body
  double precision, intent(out) :: pq(4), qd(4), wq(3)
  integer, intent(out) :: status
  pq = mbdk_quat_mul(p, q)
  qd = 0.0d0
  wq = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (.not. (abs(norm2(q) - 1.0d0) <= MBDK_UNIT_TOL)) return
  qd = mbdk_quat_rates(q, w, body /= 0)
  wq = mbdk_quat_omega(q, qd, body /= 0)
  status = MBDK_SUCCESS
end subroutine quaternion_ops

subroutine quaternion_rotate(q, x, y, status)
  ! R x by the sandwich product q (0, x) q* of a unit quaternion.
  use mbdk_rotations, only: mbdk_quat_rotate
  implicit none
  double precision, intent(in) :: q(4), x(3)
  double precision, intent(out) :: y(3)
  integer, intent(out) :: status
  call mbdk_quat_rotate(q, x, y, status)
end subroutine quaternion_rotate

subroutine quaternion_omega(q, qd, body, w, status)
  ! The angular velocity of the quaternion rates qd at a unit q (body = 1: body frame).
  use mbdk_rotations, only: mbdk_quat_omega, MBDK_UNIT_TOL
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT
  implicit none
  double precision, intent(in) :: q(4), qd(4)
  integer, intent(in) :: body
  double precision, intent(out) :: w(3)
  integer, intent(out) :: status
  w = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (.not. (abs(norm2(q) - 1.0d0) <= MBDK_UNIT_TOL)) return
  w = mbdk_quat_omega(q, qd, body /= 0)
  status = MBDK_SUCCESS
end subroutine quaternion_omega

subroutine spatial_run(nb, mass, inertia, nj, nj1, jtype, jbody, jreal, nf, nf1, ftype, fbody, &
                       freal, nsow, sobuf, method_id, dae_form, noptw, optbuf, ni3w, i3buf, &
                       ntimes, times, interrupt, natol, atol, n, y0, assemble, t0, t_end, nsamp, &
                       m1, t_out, &
                       y_out, out, lam_out, nwritten, nstatw, statbuf, nwrw, wrbuf, moved, &
                       invariants, ninv, sparse, status)
  ! A spatial scene (mbdk_spatial_model, its options sobuf: mbdk_spatial_options_t) run by
  ! method_id as scene_run runs a planar one, by the same rule (mbdk_entry): the ODE of the
  ! model's formulation (optbuf: mbdk_options_t), the index-3 family (i3buf:
  ! mbdk_index3_options_t) or, with dae_form MBDK_DAE_I3 or MBDK_DAE_SI2, bdf or ida on the
  ! scene's DAE. The tables have nj1 = max(nj, 1) columns (nf1 likewise). y0 (n): the bodies'
  ! state, then the initial volume of each wear entry of the force table. With assemble /= 0
  ! the initial state is projected onto the constraints first (moved: the largest change of a
  ! state; the volumes are not moved). out(MBDK_SPATIAL_NOUT + 1, nsamp) and lam_out(m1, nsamp): the outputs and
  ! multipliers at the samples (NaN where a failed run's last state has none), the last row
  ! the work of dampers, loads and drivers as the run integrated it at every step
  ! (mbdk_watch_work_at). The multipliers are the integrator's own where it has them (a DAE,
  ! the index-3 family), else the reduced form's at the sample. wrbuf (mbdk_watch_report_t),
  ! invariants and ninv as scene_run's. sparse: 1 where the model's constrained solves go by
  ! compact rows and a sparse S (MBDK_SPATIAL_SPARSE_ROWS), else 0.
  use, intrinsic :: iso_c_binding, only: c_loc, c_sizeof, c_intptr_t
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT, MBDK_ERR_NO_MEMORY, &
    MBDK_ERR_NOT_APPLICABLE
  use mbdk_watch, only: mbdk_watch_reserve, mbdk_watch_report_t, mbdk_watch_report_of
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_trapezoidal_index3, only: mbdk_index3_options_t, MBDK_INDEX3_BOOK
  use mbdk_entry, only: mbdk_entry_options, mbdk_entry_integrate, mbdk_entry_route, &
    mbdk_entry_spatial_model, mbdk_entry_joint_integrate, &
    mbdk_entry_spatial_outputs, MBDK_ROUTE_ODE, MBDK_ROUTE_INDEX3
  use mbdk_spatial_model
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, nsow, noptw, natol, n, assemble, nsamp, m1, nstatw
  integer, intent(in) :: method_id, dae_form, ni3w, nwrw, ntimes
  double precision, intent(in) :: mass(nb), inertia(3, 3, nb), jreal(17, nj1), freal(19, nf1)
  integer, intent(in) :: jtype(nj1), jbody(2, nj1), ftype(nf1), fbody(2, nf1)
  double precision, intent(in) :: sobuf(nsow), optbuf(noptw), atol(natol), y0(n), t0, t_end, &
    i3buf(ni3w), times(ntimes)
  integer, intent(in), target :: interrupt(4)
  double precision, intent(out) :: t_out(nsamp), y_out(n, nsamp), out(8, nsamp), &
    lam_out(m1, nsamp), moved, invariants(7, 6)
  double precision, intent(inout) :: statbuf(nstatw), wrbuf(nwrw)
  integer, intent(out) :: nwritten, status, ninv, sparse
!f2py threadsafe
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jtype) :: nj1 = len(jtype)
!f2py integer intent(hide), depend(ftype) :: nf1 = len(ftype)
!f2py integer intent(hide), depend(sobuf) :: nsow = len(sobuf)
!f2py integer intent(hide), depend(optbuf) :: noptw = len(optbuf)
!f2py integer intent(hide), depend(i3buf) :: ni3w = len(i3buf)
!f2py integer intent(hide), depend(times) :: ntimes = len(times)
!f2py integer intent(hide), depend(atol) :: natol = len(atol)
!f2py integer intent(hide), depend(y0) :: n = len(y0)
!f2py integer intent(hide), depend(statbuf) :: nstatw = len(statbuf)
!f2py integer intent(hide), depend(wrbuf) :: nwrw = len(wrbuf)
  type(mbdk_spatial_model_t), target :: model
  type(mbdk_spatial_work_t), target :: work
  type(mbdk_spatial_options_t) :: so
  type(mbdk_options_t) :: opt
  type(mbdk_index3_options_t) :: i3
  type(mbdk_stats_t) :: st
  type(mbdk_watch_report_t) :: wr
  double precision :: before
  double precision, allocatable :: y(:), a_out(:, :)
  integer, allocatable :: iters(:)
  integer :: k, s, route, na

  nwritten = 0
  t_out = 0.0d0
  y_out = 0.0d0
  out = ieee_value(0.0d0, ieee_quiet_nan)
  lam_out = ieee_value(0.0d0, ieee_quiet_nan)
  moved = 0.0d0
  invariants = 0.0d0
  ninv = 0
  sparse = 0
  status = MBDK_ERR_INVALID_INPUT
  if (8 * nstatw /= c_sizeof(st) .or. 8 * nsow /= c_sizeof(so) .or. 8 * nwrw /= c_sizeof(wr)) &
    return
  wrbuf = transfer(wr, wrbuf, nwrw)
  if (nj < 0 .or. nj > nj1 .or. nf < 0 .or. nf > nf1) return
  route = mbdk_entry_route(method_id, dae_form)
  if (route == 0) return
  call mbdk_entry_options(method_id, optbuf, i3buf, transfer(c_loc(interrupt), 0_c_intptr_t), &
                          transfer(c_loc(interrupt(3)), 0_c_intptr_t), opt, i3, status)
  if (status /= MBDK_SUCCESS) return
  so = transfer(sobuf, so)
  ! a failure from here on reports its statistics (alloc_bytes: MBDK_ERR_NO_MEMORY's size)
  call mbdk_entry_spatial_model(model, work, so, mass, inertia, nj, jtype, jbody, jreal, nf, &
                                ftype, fbody, freal, t0, y0, status, st%alloc_bytes)
  ninv = model%ninv
  sparse = merge(1, 0, model%sparse)
  invariants = model%inv
  ! a spatial run samples its energy: the watch integrates the work at every step
  model%record_work = .true.
  model%has_watch = .true.
  if (status == MBDK_SUCCESS) call mbdk_watch_reserve(work%watch, nsamp, status)
  if (status == MBDK_SUCCESS .and. m1 < max(model%m, 1)) status = MBDK_ERR_INVALID_INPUT
  if (status == MBDK_SUCCESS) then
    ! the index-3 family's accelerations and Newton iterations, which this entry does not return
    na = merge(nsamp, 1, route == MBDK_ROUTE_INDEX3)
    allocate (y(n), a_out(model%nvel, na), iters(na), stat=k)
    call mbdk_alloc_status(k, MBDK_REAL_BYTES * (n + real(model%nvel, kind(1.0d0)) * na) + &
                           MBDK_INT_BYTES * na, status, st%alloc_bytes)
  end if
  if (status /= MBDK_SUCCESS) then
    statbuf = transfer(st, statbuf, nstatw)
    return
  end if
  y = y0
  if (assemble /= 0) then
    call mbdk_spatial_assemble(model, t0, y, moved, status)
    if (status /= MBDK_SUCCESS) return
  end if
  ! the index-3 solve's statistics replace st: what was asked here is added back
  before = st%alloc_bytes
  if (so%coordinates == MBDK_COORDS_JOINT) then
    ! joint coordinates (their samples the absolute states; per-state tolerances are an
    ! absolute state's: refused)
    status = MBDK_ERR_NOT_APPLICABLE
    if (natol == 0) call mbdk_entry_joint_integrate(model, so, mass, inertia, nj, jtype, jbody, &
                                                    jreal, nf, ftype, fbody, freal, opt, &
                                                    dae_form, t0, t_end, y, t_out, y_out, &
                                                    nwritten, st, status, times)
  else
    call mbdk_entry_integrate(model, opt, i3, dae_form, t0, t_end, y, t_out, y_out, a_out, &
                              lam_out(1:model%m, :), iters, nwritten, st, status, atol, times)
  end if
  if (route == MBDK_ROUTE_INDEX3) st%alloc_bytes = st%alloc_bytes + before
  s = status
  ! the drivers' power with the integrator's own multipliers, but the book scheme's (the index3
  ! form of the index-3 family: not accurate enough, they grow as h shrinks) are solved for
  call mbdk_entry_spatial_outputs(model, work, t_out, y_out, nwritten, own_lam=route /= &
                                  MBDK_ROUTE_ODE .and. .not. (route == MBDK_ROUTE_INDEX3 .and. &
                                  i3%formulation == MBDK_INDEX3_BOOK), &
                                  solve_lam=route == MBDK_ROUTE_ODE, out=out, lam_out=lam_out)
  status = s
  ! a record of the work that could not be allocated: the samples' W is incomplete
  if (work%watch%rec_lost .and. status >= 0) status = MBDK_ERR_NO_MEMORY
  statbuf = transfer(st, statbuf, nstatw)
  wrbuf = transfer(mbdk_watch_report_of(work%watch), wrbuf, nwrw)
end subroutine spatial_run

subroutine spatial_joint_tree(nb, nj, nj1, jtype, jbody, tjoint, kind, parent, ndof, status)
  ! The spanning tree that joint coordinates (mbdk_joint_coords) grow over a spatial scene's
  ! joint table (jtype, jbody: its first nj columns): per body its tree joint (1-based table
  ! column; 0: the body hangs on none), its kind (1 turn, 2 slide, 3 cylinder, 4 fixed,
  ! 5 ball) and parent (0: the ground); ndof the joint rates. status MBDK_ERR_NOT_APPLICABLE where a
  ! body is off the tree or there is no coordinate; the joints on no body's row are cut.
  use mbdk_status, only: MBDK_ERR_INVALID_INPUT
  use mbdk_joint_coords, only: mbdk_joint_tree
  implicit none
  integer, intent(in) :: nb, nj, nj1
  integer, intent(in) :: jtype(nj1), jbody(2, nj1)
  integer, intent(out) :: tjoint(nb), kind(nb), parent(nb), ndof, status
!f2py integer intent(hide), depend(jtype) :: nj1 = len(jtype)
  integer :: order(nb)
  tjoint = 0
  kind = 0
  parent = 0
  ndof = 0
  status = MBDK_ERR_INVALID_INPUT
  if (nj < 0 .or. nj > nj1 .or. nb < 1) return
  call mbdk_joint_tree(nb, jtype(1:nj), jbody(:, 1:nj), tjoint, kind, parent, order, ndof, &
                       status)
end subroutine spatial_joint_tree

subroutine spatial_contact_states(nb, mass, inertia, nj, nj1, jtype, jbody, jreal, nf, nf1, &
                                  ftype, fbody, freal, nsow, sobuf, n, y0, t0, nsamp, y, nct, &
                                  out, status)
  ! Each contact's penetration, its rate, normal force and friction force at the samples y(:,
  ! k) of a spatial run (mbdk_spatial_contact_states), the model built as the run's (its options
  ! sobuf, y0 its initial state at t0): out(4, nct, nsamp), nct contacts in table order.
  use, intrinsic :: iso_c_binding, only: c_sizeof
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT
  use mbdk_entry, only: mbdk_entry_spatial_model
  use mbdk_spatial_model
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, nsow, n, nsamp, nct
  double precision, intent(in) :: mass(nb), inertia(3, 3, nb), jreal(17, nj1), freal(19, nf1)
  integer, intent(in) :: jtype(nj1), jbody(2, nj1), ftype(nf1), fbody(2, nf1)
  double precision, intent(in) :: sobuf(nsow), y0(n), t0, y(n, nsamp)
  double precision, intent(out) :: out(4, nct, nsamp)
  integer, intent(out) :: status
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jtype) :: nj1 = len(jtype)
!f2py integer intent(hide), depend(ftype) :: nf1 = len(ftype)
!f2py integer intent(hide), depend(sobuf) :: nsow = len(sobuf)
!f2py integer intent(hide), depend(y0) :: n = len(y0)
!f2py integer intent(hide), depend(y) :: nsamp = shape(y, 1)
  type(mbdk_spatial_model_t) :: model
  type(mbdk_spatial_work_t), target :: work
  type(mbdk_spatial_options_t) :: so
  integer :: k, s
  out = 0.0d0
  status = MBDK_ERR_INVALID_INPUT
  if (8 * nsow /= c_sizeof(so)) return
  so = transfer(sobuf, so)
  call mbdk_entry_spatial_model(model, work, so, mass, inertia, nj, jtype, jbody, jreal, nf, &
                                ftype, fbody, freal, t0, y0, status)
  if (status /= MBDK_SUCCESS) return
  status = MBDK_ERR_INVALID_INPUT
  if (model%ncontacts /= nct) return
  ! a sample whose frames fail (non-finite, as a blown-up run's last one, or an angle set at its
  ! lock) has no contact state: NaN there, the other samples kept
  status = MBDK_SUCCESS
  do k = 1, nsamp
    call mbdk_spatial_contact_states(model, y(:, k), out(:, :, k), s)
    if (s /= MBDK_SUCCESS) out(:, :, k) = ieee_value(0.0d0, ieee_quiet_nan)
  end do
end subroutine spatial_contact_states

subroutine spatial_start_residuals(nb, mass, inertia, nj, nj1, jtype, jbody, jreal, nf, nf1, &
                                   ftype, fbody, freal, rotation, n, y0, t, m1, phi, vres, &
                                   vterm, rank, asked, status)
  ! What a spatial scene's start is checked on, in memory and time that grow as its rows do
  ! (spatial_residuals' C is m x 6 nb): at its initial state (t, y0), Phi, C w + Phi_t and the
  ! size of that sum's terms |C| |w| + |Phi_t| (rows 1..m), the rank of the joints' rows
  ! (below m: redundant joints; 0 with status MBDK_ERR_SINGULAR_MATRIX: a row vanishes), and
  ! asked: MBDK_ERR_NO_MEMORY's bytes.
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT, MBDK_ERR_SINGULAR_MATRIX
  use mbdk_entry, only: mbdk_entry_spatial_model
  use mbdk_spatial_model
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, n, m1, rotation
  double precision, intent(in) :: mass(nb), inertia(3, 3, nb), jreal(17, nj1), freal(19, nf1)
  integer, intent(in) :: jtype(nj1), jbody(2, nj1), ftype(nf1), fbody(2, nf1)
  double precision, intent(in) :: y0(n), t
  double precision, intent(out) :: phi(m1), vres(m1), vterm(m1), asked
  integer, intent(out) :: rank, status
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jtype) :: nj1 = len(jtype)
!f2py integer intent(hide), depend(ftype) :: nf1 = len(ftype)
!f2py integer intent(hide), depend(y0) :: n = len(y0)
  type(mbdk_spatial_model_t) :: model
  type(mbdk_spatial_work_t), target :: work
  type(mbdk_spatial_options_t) :: so
  double precision :: out(MBDK_SPATIAL_NOUT)
  asked = 0.0d0
  phi = 0.0d0
  vres = 0.0d0
  vterm = 0.0d0
  rank = 0
  so%rotation = rotation
  call mbdk_entry_spatial_model(model, work, so, mass, inertia, nj, jtype, jbody, jreal, nf, &
                                ftype, fbody, freal, t, y0, status, asked)
  if (status /= MBDK_SUCCESS) return
  status = MBDK_ERR_INVALID_INPUT
  if (m1 < model%m) return
  rank = model%rank0
  if (model%m == 0) then
    status = MBDK_SUCCESS
    return
  end if
  call mbdk_spatial_outputs(model, t, y0, out, status, phi_out=phi(1:model%m), &
                            vres_out=vres(1:model%m), vterm_out=vterm(1:model%m))
end subroutine spatial_start_residuals

subroutine spatial_residuals(nb, mass, inertia, nj, nj1, jtype, jbody, jreal, nf, nf1, ftype, &
                             fbody, freal, rotation, n, y0, t, y, m1, out, phi, c, gam, &
                             phit, lam, ydot, rank, asked, status)
  ! At the state (t, y) of a spatial scene whose model is built at its initial state y0 (the
  ! reference of prismatic and fixed joints; rotation: 1 quaternion, 2 euler313, 3 cardan123):
  ! the outputs (MBDK_SPATIAL_NOUT), Phi, C (m1 x 6 nb), gamma, the rank of the joints' rows at
  ! y0 (below m: redundant joints), the reduced formulation's multipliers (rows 1..m; lam is 0
  ! where the solve failed, and status then says why) and its y' = F(t, y) (0 likewise).
  ! asked: MBDK_ERR_NO_MEMORY's bytes (the model's build), else 0.
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT, MBDK_ERR_SINGULAR_MATRIX
  use mbdk_entry, only: mbdk_entry_spatial_model
  use mbdk_spatial_model
  implicit none
  integer, intent(in) :: nb, nj, nj1, nf, nf1, n, m1, rotation
  double precision, intent(in) :: mass(nb), inertia(3, 3, nb), jreal(17, nj1), freal(19, nf1)
  integer, intent(in) :: jtype(nj1), jbody(2, nj1), ftype(nf1), fbody(2, nf1)
  double precision, intent(in) :: y0(n), t, y(n)
  double precision, intent(out) :: out(7), phi(m1), c(m1, 6 * nb), gam(m1), phit(m1), lam(m1)
  double precision, intent(out) :: ydot(n), asked
  integer, intent(out) :: rank, status
!f2py integer intent(hide), depend(mass) :: nb = len(mass)
!f2py integer intent(hide), depend(jtype) :: nj1 = len(jtype)
!f2py integer intent(hide), depend(ftype) :: nf1 = len(ftype)
!f2py integer intent(hide), depend(y0) :: n = len(y0)
  type(mbdk_spatial_model_t) :: model
  type(mbdk_spatial_work_t), target :: work
  type(mbdk_spatial_options_t) :: so
  asked = 0.0d0
  out = 0.0d0
  phi = 0.0d0
  c = 0.0d0
  gam = 0.0d0
  lam = 0.0d0
  phit = 0.0d0
  ydot = 0.0d0
  rank = 0
  so%rotation = rotation
  call mbdk_entry_spatial_model(model, work, so, mass, inertia, nj, jtype, jbody, jreal, nf, &
                                ftype, fbody, freal, t, y0, status, asked)
  if (status /= MBDK_SUCCESS) return
  status = MBDK_ERR_INVALID_INPUT
  if (m1 < model%m) return
  rank = model%rank0
  call mbdk_spatial_outputs(model, t, y, out, status)
  if (status /= MBDK_SUCCESS .and. status /= MBDK_ERR_SINGULAR_MATRIX) return
  call mbdk_spatial_constraints(model, t, y, phi(1:model%m), c(1:model%m, :), gam(1:model%m), &
                                phit(1:model%m), status)
  if (status /= MBDK_SUCCESS) return
  call model%rhs(t, y, ydot, status)
  if (status /= MBDK_SUCCESS) ydot = 0.0d0
  if (status /= MBDK_SUCCESS .or. model%m == 0) return
  call mbdk_spatial_multipliers(model, t, y, lam(1:model%m), status)
  if (status /= MBDK_SUCCESS) lam = 0.0d0
end subroutine spatial_residuals
