!> cvode_bdf and cvode_adams: SUNDIALS CVODE (6.x) through its Fortran 2003 interface, as a
!> reference for the kernel's own bdf and a second opinion on any problem.
!>
!> CVODE integrates y' = F(t, y) with variable-order, variable-step linear multistep formulas in
!> Nordsieck form (Hindmarsh et al., ACM TOMS 31 (2005) 363; Byrne and Hindmarsh, ACM TOMS 1
!> (1975) 71):
!>   cvode_bdf    BDF of orders 1..5 (max_order <= 5), Newton iteration on SUNDIALS' dense
!>                matrix and dense LU (SUNMatrix_Dense, SUNLinSol_Dense). The Jacobian is the
!>                problem's jac when has_jac and opt%fd_jacobian = 0, otherwise CVODE's own
!>                difference quotients (one F per column). For stiff problems.
!>   cvode_adams  Adams-Moulton of orders 1..12 (max_order <= 12), solved by fixed-point
!>                iteration (SUNNonlinSol_FixedPoint): no Jacobian, no linear algebra. For
!>                non-stiff problems; on a stiff one its steps stay at the stability limit.
!> The local error estimate is kept at WRMS <= 1 with the weights of mbdk_adaptive: rtol with
!> the scalar opt%atol (CVodeSStolerances) or one atol per state (CVodeSVtolerances).
!>
!> Options read: rtol, atol, h (> 0: the first step; 0: CVODE's estimate), h_min and h_max
!> (> 0: CVODE's bounds; 0: CVODE's defaults, no bound), max_order (0: the method's; above 5
!> for bdf or 12 for adams: MBDK_ERR_INVALID_INPUT), max_steps, fd_jacobian, interrupt.
!>
!> The loop is mbdk_sundials_loop's, which this module drives through its hooks (cvode_loop_t):
!> CVODE takes one internal step per call (CV_ONE_STEP) and never passes t_end
!> (CVodeSetStopTime); after each step the samples in it come from CVODE's interpolant
!> (CVodeGetDky), the sample at t_end is the last step's own state, the state is checked
!> (finite, and the watch with force = a sample fell in the step; before it, a watch that
!> integrates a work gets the interpolant at the step's Gauss nodes) and the step's order is
!> counted (order5_steps also takes Adams orders 6..12). max_steps bounds the accepted steps
!> plus the error-test and convergence failures (CVodeGetNumErrTestFails +
!> CVodeGetNumNonlinSolvConvFails), counted there (CVODE's own limit is off):
!> MBDK_ERR_TOO_MANY_STEPS. A step below mbdk_adaptive_h_floor (opt%h_min, and 10 ulps of t;
!> the step that lands on t_end, 10 ulps) is MBDK_ERR_STEP_TOO_SMALL: CVODE itself only warns
!> when t + h = t and goes on. The interrupt flag is polled before each step and in every F
!> evaluation, so a long step of a large model ends within one evaluation.
!>
!> Refused: a problem with has_post_step (the projection formulation) gets
!> MBDK_ERR_NOT_APPLICABLE. Its projection must restart the multistep history, which CVODE
!> allows only through its own projection interface (CVodeSetProjFn, BDF only) with its own
!> error-test correction; binding that is out of scope, and projecting behind CVODE's back
!> would leave the Nordsieck history of the unprojected state.
!>
!> Callbacks: F returning a failure status ends the solve with that status (it is returned to
!> CVODE as unrecoverable, -1, and every later call returns -1 too: SUNDIALS 6.4's fixed-point
!> solver passes a -1 on as a recoverable convergence failure, after which CVODE would step up
!> to the failing t in ever smaller steps); a non-finite F is returned as recoverable (1) and
!> CVODE cuts the step. A jac failure ends the solve likewise; a non-finite Jacobian is
!> recoverable.
!>
!> CVODE's return flags (a callback's own status comes first when one ended the solve):
!>   CV_TOO_MUCH_WORK                              MBDK_ERR_TOO_MANY_STEPS
!>   CV_TOO_MUCH_ACC                               MBDK_ERR_TOO_MUCH_ACCURACY
!>   CV_ERR_FAILURE  (error test failed repeatedly or at h_min)   MBDK_ERR_STEP_TOO_SMALL
!>   CV_CONV_FAILURE                               MBDK_ERR_NEWTON_DIVERGED
!>   CV_LSETUP_FAIL, CV_LSOLVE_FAIL                MBDK_ERR_SINGULAR_MATRIX
!>   CV_RHSFUNC_FAIL, CV_FIRST_RHSFUNC_ERR, CV_REPTD_RHSFUNC_ERR, CV_UNREC_RHSFUNC_ERR
!>                                                 MBDK_ERR_NONFINITE after non-finite F,
!>                                                 else MBDK_ERR_CALLBACK_FAILED
!>   CV_MEM_FAIL                                   MBDK_ERR_NO_MEMORY
!>   CV_ILL_INPUT                                  MBDK_ERR_INVALID_INPUT
!>   any other failure                             MBDK_ERR_BACKEND
!>
!> Statistics, from CVODE's counters (also after a failure):
!>   steps CVodeGetNumSteps; nfev CVodeGetNumRhsEvals + CVodeGetNumLinRhsEvals (the
!>   difference-quotient columns); njev CVodeGetNumJacEvals; nlu CVodeGetNumLinSolvSetups (each
!>   setup factors I - gamma J); newton_iterations CVodeGetNumNonlinSolvIters (fixed-point
!>   iterations for adams); rejected_steps CVodeGetNumErrTestFails; newton_failures
!>   CVodeGetNumNonlinSolvConvFails; order1_steps..order5_steps CVodeGetLastOrder per step.
!>
!> SUNDIALS writes its error messages to stderr by default; CVodeSetErrFile(NULL) silences
!> them, as the kernel never prints. All SUNDIALS objects are freed on every path.
module mbdk_cvode
  use, intrinsic :: iso_c_binding, only: c_ptr, c_null_ptr, c_loc, c_funloc, c_f_pointer, &
    c_associated, c_int, c_long, c_int64_t, c_double, c_intptr_t
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  use mbdk_interrupt, only: mbdk_interrupted
  use mbdk_sundials_loop, only: mbdk_sundials_loop_t, mbdk_sundials_run
  use fsundials_context_mod, only: FSUNContext_Create, FSUNContext_Free
  use fsundials_nvector_mod, only: N_Vector, FN_VDestroy
  use fnvector_serial_mod, only: FN_VMake_Serial
  use fsundials_matrix_mod, only: SUNMatrix, FSUNMatDestroy
  use fsunmatrix_dense_mod, only: FSUNDenseMatrix, FSUNDenseMatrix_Data
  use fsundials_linearsolver_mod, only: SUNLinearSolver, FSUNLinSolFree
  use fsunlinsol_dense_mod, only: FSUNLinSol_Dense
  use fsundials_nonlinearsolver_mod, only: SUNNonlinearSolver, FSUNNonlinSolFree
  use fsunnonlinsol_newton_mod, only: FSUNNonlinSol_Newton
  use fsunnonlinsol_fixedpoint_mod, only: FSUNNonlinSol_FixedPoint
  use fcvode_mod, only: CV_BDF, CV_ADAMS, CV_ONE_STEP, CV_TOO_MUCH_WORK, CV_TOO_MUCH_ACC, &
    CV_ERR_FAILURE, CV_CONV_FAILURE, CV_LSETUP_FAIL, CV_LSOLVE_FAIL, CV_RHSFUNC_FAIL, &
    CV_FIRST_RHSFUNC_ERR, CV_REPTD_RHSFUNC_ERR, CV_UNREC_RHSFUNC_ERR, CV_MEM_FAIL, &
    CV_ILL_INPUT, FCVodeCreate, FCVodeInit, FCVodeFree, FCVodeSStolerances, &
    FCVodeSVtolerances, FCVodeSetUserData, FCVodeSetErrFile, FCVodeSetMaxNumSteps, &
    FCVodeSetStopTime, FCVodeSetMaxOrd, FCVodeSetInitStep, FCVodeSetMinStep, FCVodeSetMaxStep, &
    FCVodeSetLinearSolver, FCVodeSetJacFn, FCVodeSetNonlinearSolver, FCVode, FCVodeGetDky, &
    FCVodeGetLastOrder, FCVodeGetLastStep, FCVodeGetNumSteps, FCVodeGetNumRhsEvals, &
    FCVodeGetNumLinRhsEvals, FCVodeGetNumJacEvals, FCVodeGetNumLinSolvSetups, &
    FCVodeGetNumNonlinSolvIters, FCVodeGetNumErrTestFails, FCVodeGetNumNonlinSolvConvFails
  implicit none
  private
  public :: mbdk_cvode_solve

  integer, parameter :: BDF_MAX_ORDER = 5, ADAMS_MAX_ORDER = 12

  ! SUNDIALS' own accessor, called directly: the Fortran interface's FN_VGetArrayPointer asks
  ! for the length through a second wrapper on every call, a cost that matters next to a small
  ! model's F; the callbacks know n.
  interface
    type(c_ptr) function n_vgetarraypointer(v) bind(C, name='N_VGetArrayPointer')
      import :: c_ptr
      type(c_ptr), value :: v
    end function n_vgetarraypointer
  end interface

  !> What the callbacks reach through CVODE's user data: one per solve, on the solver's stack.
  type :: cvode_context_t
    class(mbdk_problem_t), pointer :: prob => null()
    integer :: n = 0
    !> a callback's failure status that made it return -1 (CVODE then stops)
    integer :: stat = MBDK_SUCCESS
    !> MBDK_ERR_NONFINITE when F was non-finite in the current step (returned as recoverable)
    integer :: soft_stat = MBDK_SUCCESS
    integer(c_intptr_t) :: interrupt = 0
  end type cvode_context_t

  !> One CVODE solve: its SUNDIALS objects (each handle empty until made, so that cvode_free
  !> frees what exists on any path) and the hooks of mbdk_sundials_loop's one-step loop.
  type, extends(mbdk_sundials_loop_t) :: cvode_loop_t
    type(c_ptr) :: sunctx = c_null_ptr, mem = c_null_ptr
    type(N_Vector), pointer :: nv_y => null(), nv_dky => null(), nv_atol => null()
    type(SUNMatrix), pointer :: amat => null()
    type(SUNLinearSolver), pointer :: ls => null()
    type(SUNNonlinearSolver), pointer :: nls => null()
    type(cvode_context_t), pointer :: ctx => null()
    !> the interpolant at the Gauss nodes of a step, for the watch
    real(dp), allocatable :: yn(:, :)
  contains
    procedure :: step => cvode_step
    procedure :: tries => cvode_tries
    procedure :: last_step => cvode_last_step
    procedure :: dky => cvode_dky
    procedure :: wants_nodes => cvode_wants_nodes
    procedure :: keep_node => cvode_keep_node
    procedure :: watch_nodes => cvode_watch_nodes
    procedure :: accept => cvode_accept
  end type cvode_loop_t

contains

  !> See the module header; called by mbdk_solve_ode, which has checked the options and atol,
  !> written sample 1 (nwritten = 1) and the sample times t_out. adams: cvode_adams, else
  !> cvode_bdf. atol: size 0 for the scalar opt%atol, or one per state.
  subroutine mbdk_cvode_solve(prob, opt, adams, t0, y0, atol, t_out, y_out, nwritten, st, stat)
    class(mbdk_problem_t), intent(in), target :: prob
    type(mbdk_options_t), intent(in) :: opt
    logical, intent(in) :: adams
    real(dp), intent(in) :: t0, y0(:), atol(:)
    real(dp), intent(in) :: t_out(:)
    real(dp), intent(inout) :: y_out(:, :)
    integer, intent(inout) :: nwritten
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat

    type(cvode_context_t), target :: ctx
    type(cvode_loop_t) :: lp
    real(dp), allocatable, target :: y(:), ydky(:), atol_v(:)
    integer :: n, ierr

    n = size(y0)
    ! the projection must restart CVODE's history (module header)
    stat = MBDK_ERR_NOT_APPLICABLE
    if (prob%has_post_step) return
    stat = MBDK_ERR_INVALID_INPUT
    if (adams .and. opt%max_order > ADAMS_MAX_ORDER) return
    if (.not. adams .and. opt%max_order > BDF_MAX_ORDER) return
    stat = MBDK_ERR_NO_MEMORY
    allocate (y(n), ydky(n), atol_v(size(atol)), lp%yn(n, 3), stat=ierr)
    call mbdk_alloc_status(ierr, MBDK_REAL_BYTES * (5.0_dp * n + size(atol)), stat, &
                           st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    y = y0
    atol_v = atol

    ctx%prob => prob
    ctx%n = n
    ctx%interrupt = opt%interrupt
    lp%ctx => ctx
    lp%y => y
    lp%ydky => ydky
    call cvode_create(lp, opt, adams, t0, t_out(size(t_out)), y, ydky, atol_v, stat)
    if (stat == MBDK_SUCCESS) call cvode_solvers(lp, opt, adams, n, st, stat)
    if (stat == MBDK_SUCCESS) call mbdk_sundials_run(lp, opt, t0, t_out, y_out, nwritten, st, stat)
    if (c_associated(lp%mem)) call add_stats(lp%mem, adams, st)
    call cvode_free(lp)
  end subroutine mbdk_cvode_solve

  !> CVODE's context, vectors (on y, ydky and atol_v, which outlive the solve) and memory,
  !> initialised at (t0, y) with the options of the module header and the stop time t_end.
  subroutine cvode_create(lp, opt, adams, t0, t_end, y, ydky, atol_v, stat)
    type(cvode_loop_t), intent(inout) :: lp
    type(mbdk_options_t), intent(in) :: opt
    logical, intent(in) :: adams
    real(dp), intent(in) :: t0, t_end
    real(dp), intent(inout), target, contiguous :: y(:), ydky(:), atol_v(:)
    integer, intent(out) :: stat
    integer(c_int) :: flag
    integer(c_int64_t) :: n
    n = int(size(y), c_int64_t)
    stat = MBDK_ERR_BACKEND
    if (FSUNContext_Create(c_null_ptr, lp%sunctx) /= 0) return
    stat = MBDK_ERR_NO_MEMORY
    lp%nv_y => FN_VMake_Serial(n, y, lp%sunctx)
    if (.not. associated(lp%nv_y)) return
    lp%nv_dky => FN_VMake_Serial(n, ydky, lp%sunctx)
    if (.not. associated(lp%nv_dky)) return
    if (adams) then
      lp%mem = FCVodeCreate(CV_ADAMS, lp%sunctx)
    else
      lp%mem = FCVodeCreate(CV_BDF, lp%sunctx)
    end if
    if (.not. c_associated(lp%mem)) return
    ! before anything else can fail: the kernel never prints
    stat = MBDK_ERR_BACKEND
    if (FCVodeSetErrFile(lp%mem, c_null_ptr) /= 0) return

    flag = FCVodeInit(lp%mem, c_funloc(cvode_rhs), t0, lp%nv_y)
    if (flag == 0) then
      if (size(atol_v) == 0) then
        flag = FCVodeSStolerances(lp%mem, opt%rtol, opt%atol)
      else
        lp%nv_atol => FN_VMake_Serial(n, atol_v, lp%sunctx)
        flag = CV_MEM_FAIL
        if (associated(lp%nv_atol)) flag = FCVodeSVtolerances(lp%mem, opt%rtol, lp%nv_atol)
      end if
    end if
    if (flag == 0) flag = FCVodeSetUserData(lp%mem, c_loc(lp%ctx))
    ! the step count is ours (max_steps counts rejections too); CVODE's per-call limit is off
    if (flag == 0) flag = FCVodeSetMaxNumSteps(lp%mem, -1_c_long)
    if (flag == 0) flag = FCVodeSetStopTime(lp%mem, t_end)
    if (flag == 0 .and. opt%max_order > 0) &
      flag = FCVodeSetMaxOrd(lp%mem, int(opt%max_order, c_int))
    if (flag == 0 .and. opt%h > 0.0_dp) flag = FCVodeSetInitStep(lp%mem, opt%h)
    if (flag == 0 .and. opt%h_min > 0.0_dp) flag = FCVodeSetMinStep(lp%mem, opt%h_min)
    if (flag == 0 .and. opt%h_max > 0.0_dp) flag = FCVodeSetMaxStep(lp%mem, opt%h_max)
    stat = MBDK_SUCCESS
    if (flag /= 0) stat = cvode_status(flag, lp%ctx%stat, lp%ctx%soft_stat)
  end subroutine cvode_create

  !> The nonlinear solver: fixed-point iteration for adams; for bdf, Newton on the dense matrix
  !> and dense LU (the problem's jac where it has one and opt%fd_jacobian = 0).
  subroutine cvode_solvers(lp, opt, adams, n, st, stat)
    type(cvode_loop_t), intent(inout) :: lp
    type(mbdk_options_t), intent(in) :: opt
    logical, intent(in) :: adams
    integer, intent(in) :: n
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    integer(c_int) :: flag
    stat = MBDK_ERR_NO_MEMORY
    if (adams) then
      lp%nls => FSUNNonlinSol_FixedPoint(lp%nv_y, 0_c_int, lp%sunctx)
      if (.not. associated(lp%nls)) return
    else
      lp%amat => FSUNDenseMatrix(int(n, c_int64_t), int(n, c_int64_t), lp%sunctx)
      if (.not. associated(lp%amat)) then   ! (the size SUNDIALS asked for: n x n doubles)
        st%alloc_bytes = MBDK_REAL_BYTES * real(n, dp)**2
        return
      end if
      lp%ls => FSUNLinSol_Dense(lp%nv_y, lp%amat, lp%sunctx)
      if (.not. associated(lp%ls)) return
      lp%nls => FSUNNonlinSol_Newton(lp%nv_y, lp%sunctx)
      if (.not. associated(lp%nls)) return
      flag = FCVodeSetLinearSolver(lp%mem, lp%ls, lp%amat)
      if (flag == 0 .and. lp%ctx%prob%has_jac .and. opt%fd_jacobian == 0) &
        flag = FCVodeSetJacFn(lp%mem, c_funloc(cvode_jac))
      if (flag /= 0) then
        stat = MBDK_ERR_BACKEND
        return
      end if
    end if
    stat = MBDK_ERR_BACKEND
    if (FCVodeSetNonlinearSolver(lp%mem, lp%nls) /= 0) return
    stat = MBDK_SUCCESS
  end subroutine cvode_solvers

  !> Frees every SUNDIALS object of the solve that exists.
  subroutine cvode_free(lp)
    type(cvode_loop_t), intent(inout) :: lp
    integer :: ierr
    call FCVodeFree(lp%mem)   ! NULL-safe; also frees CVODE's copy of atol
    if (associated(lp%nls)) ierr = FSUNNonlinSolFree(lp%nls)
    if (associated(lp%ls)) ierr = FSUNLinSolFree(lp%ls)
    if (associated(lp%amat)) call FSUNMatDestroy(lp%amat)
    if (associated(lp%nv_atol)) call FN_VDestroy(lp%nv_atol)
    if (associated(lp%nv_dky)) call FN_VDestroy(lp%nv_dky)
    if (associated(lp%nv_y)) call FN_VDestroy(lp%nv_y)
    if (c_associated(lp%sunctx)) ierr = FSUNContext_Free(lp%sunctx)
  end subroutine cvode_free

  !> One internal step (CV_ONE_STEP) towards t_stop; a callback's failure comes first.
  subroutine cvode_step(self, t_stop, t, stat)
    class(cvode_loop_t), intent(inout) :: self
    real(dp), intent(in) :: t_stop
    real(dp), intent(out) :: t
    integer, intent(out) :: stat
    real(c_double) :: tret(1)
    integer(c_int) :: flag
    self%ctx%soft_stat = MBDK_SUCCESS
    flag = FCVode(self%mem, t_stop, self%nv_y, tret, CV_ONE_STEP)
    t = tret(1)
    if (flag < 0) then
      stat = cvode_status(flag, self%ctx%stat, self%ctx%soft_stat)
      return
    end if
    stat = self%ctx%stat
  end subroutine cvode_step

  !> Steps plus error-test and convergence failures (the module header).
  integer(i8) function cvode_tries(self) result(tries)
    class(cvode_loop_t), intent(inout) :: self
    integer(c_long) :: nst(1), netf(1), ncfn(1)
    integer(c_int) :: flag
    flag = FCVodeGetNumSteps(self%mem, nst)
    flag = FCVodeGetNumErrTestFails(self%mem, netf)
    flag = FCVodeGetNumNonlinSolvConvFails(self%mem, ncfn)
    tries = int(nst(1), i8) + int(netf(1), i8) + int(ncfn(1), i8)
  end function cvode_tries

  subroutine cvode_last_step(self, h, q)
    class(cvode_loop_t), intent(inout) :: self
    real(dp), intent(out) :: h
    integer, intent(out) :: q
    real(c_double) :: hlast(1)
    integer(c_int) :: flag, qlast(1)
    flag = FCVodeGetLastStep(self%mem, hlast)
    flag = FCVodeGetLastOrder(self%mem, qlast)
    h = hlast(1)
    q = int(qlast(1))
  end subroutine cvode_last_step

  subroutine cvode_dky(self, t, stat)
    class(cvode_loop_t), intent(inout) :: self
    real(dp), intent(in) :: t
    integer, intent(out) :: stat
    stat = MBDK_SUCCESS
    if (FCVodeGetDky(self%mem, t, 0_c_int, self%nv_dky) /= 0) stat = MBDK_ERR_BACKEND
  end subroutine cvode_dky

  logical function cvode_wants_nodes(self) result(wants)
    class(cvode_loop_t), intent(inout) :: self
    wants = .false.
    if (self%ctx%prob%has_watch) wants = self%ctx%prob%watch_wants_nodes()
  end function cvode_wants_nodes

  subroutine cvode_keep_node(self, i)
    class(cvode_loop_t), intent(inout) :: self
    integer, intent(in) :: i
    self%yn(:, i) = self%ydky
  end subroutine cvode_keep_node

  subroutine cvode_watch_nodes(self, t_a, t_b, stat)
    class(cvode_loop_t), intent(inout) :: self
    real(dp), intent(in) :: t_a, t_b
    integer, intent(out) :: stat
    call self%ctx%prob%watch_nodes(t_a, t_b, self%yn, stat)
  end subroutine cvode_watch_nodes

  !> The watch (has_post_step was refused: no projection; the loop checked the state).
  subroutine cvode_accept(self, t, sample, stat)
    class(cvode_loop_t), intent(inout) :: self
    real(dp), intent(in) :: t
    logical, intent(in) :: sample
    integer, intent(out) :: stat
    stat = MBDK_SUCCESS
    if (self%ctx%prob%has_watch) call self%ctx%prob%watch(t, self%y, sample, stat)
  end subroutine cvode_accept

  !> CVODE's counters into st (see the module header). The linear-solver counters exist only
  !> with a linear solver (bdf).
  subroutine add_stats(mem, adams, st)
    type(c_ptr), intent(in) :: mem
    logical, intent(in) :: adams
    type(mbdk_stats_t), intent(inout) :: st
    integer(c_long) :: c(1)
    integer(c_int) :: flag
    c = 0
    flag = FCVodeGetNumSteps(mem, c)
    st%steps = st%steps + c(1)
    c = 0
    flag = FCVodeGetNumRhsEvals(mem, c)
    st%nfev = st%nfev + c(1)
    c = 0
    flag = FCVodeGetNumNonlinSolvIters(mem, c)
    st%newton_iterations = st%newton_iterations + c(1)
    c = 0
    flag = FCVodeGetNumErrTestFails(mem, c)
    st%rejected_steps = st%rejected_steps + c(1)
    c = 0
    flag = FCVodeGetNumNonlinSolvConvFails(mem, c)
    st%newton_failures = st%newton_failures + c(1)
    c = 0
    flag = FCVodeGetNumLinSolvSetups(mem, c)
    st%nlu = st%nlu + c(1)
    if (adams) return
    c = 0
    flag = FCVodeGetNumLinRhsEvals(mem, c)
    st%nfev = st%nfev + c(1)
    c = 0
    flag = FCVodeGetNumJacEvals(mem, c)
    st%njev = st%njev + c(1)
  end subroutine add_stats

  !> The status of a failed CVODE call (flag < 0); table in the module header. callback_stat:
  !> the failure a callback reported (it ended the solve, so it is the cause); soft_stat: a
  !> recoverable callback failure of the last step (non-finite F).
  pure integer function cvode_status(flag, callback_stat, soft_stat) result(stat)
    integer(c_int), intent(in) :: flag
    integer, intent(in) :: callback_stat, soft_stat
    if (callback_stat /= MBDK_SUCCESS) then
      stat = callback_stat
      return
    end if
    select case (flag)
    case (CV_TOO_MUCH_WORK)
      stat = MBDK_ERR_TOO_MANY_STEPS
    case (CV_TOO_MUCH_ACC)
      stat = MBDK_ERR_TOO_MUCH_ACCURACY
    case (CV_ERR_FAILURE)
      stat = MBDK_ERR_STEP_TOO_SMALL
    case (CV_CONV_FAILURE)
      stat = MBDK_ERR_NEWTON_DIVERGED
    case (CV_LSETUP_FAIL, CV_LSOLVE_FAIL)
      stat = MBDK_ERR_SINGULAR_MATRIX
    case (CV_RHSFUNC_FAIL, CV_FIRST_RHSFUNC_ERR, CV_REPTD_RHSFUNC_ERR, CV_UNREC_RHSFUNC_ERR)
      stat = MBDK_ERR_CALLBACK_FAILED
      if (soft_stat /= MBDK_SUCCESS) stat = soft_stat
    case (CV_MEM_FAIL)
      stat = MBDK_ERR_NO_MEMORY
    case (CV_ILL_INPUT)
      stat = MBDK_ERR_INVALID_INPUT
    case default
      stat = MBDK_ERR_BACKEND
    end select
  end function cvode_status

  !> CVRhsFn: ydot = F(t, y) on the vectors' own storage. 0: done; 1: F not finite (CVODE cuts
  !> the step); -1: F failed or the solve was interrupted (ctx%stat says which).
  integer(c_int) function cvode_rhs(t, nv_y, nv_ydot, user_data) bind(C, name='') result(ierr)
    real(c_double), value :: t
    type(N_Vector), target :: nv_y, nv_ydot
    type(c_ptr), value :: user_data
    type(cvode_context_t), pointer :: ctx
    real(c_double), pointer, contiguous :: y(:), f(:)
    integer :: stat
    call c_f_pointer(user_data, ctx)
    ierr = -1
    ! sticky: CVODE may treat the first -1 as a recoverable convergence failure (the module
    ! header), so every later evaluation fails too and no step can be accepted after it
    if (ctx%stat /= MBDK_SUCCESS) return
    if (ctx%interrupt /= 0) then
      if (mbdk_interrupted(ctx%interrupt)) then
        ctx%stat = MBDK_ERR_INTERRUPTED
        return
      end if
    end if
    call c_f_pointer(n_vgetarraypointer(c_loc(nv_y)), y, [ctx%n])
    call c_f_pointer(n_vgetarraypointer(c_loc(nv_ydot)), f, [ctx%n])
    call ctx%prob%rhs(t, y, f, stat)
    if (stat /= MBDK_SUCCESS) then
      ctx%stat = stat
      return
    end if
    ierr = 0
    if (.not. all(abs(f) <= huge(1.0_dp))) then
      ctx%soft_stat = MBDK_ERR_NONFINITE
      ierr = 1
    end if
  end function cvode_rhs

  !> CVLsJacFn: J = dF/dy from the problem's jac, written into the dense matrix's column-major
  !> storage. 0: done; 1: J not finite (CVODE cuts the step); -1: jac failed (ctx%stat).
  integer(c_int) function cvode_jac(t, nv_y, nv_fy, jmat, user_data, tmp1, tmp2, tmp3) &
    bind(C, name='') result(ierr)
    real(c_double), value :: t
    type(N_Vector), target :: nv_y, nv_fy, tmp1, tmp2, tmp3
    type(SUNMatrix) :: jmat
    type(c_ptr), value :: user_data
    type(cvode_context_t), pointer :: ctx
    real(c_double), pointer, contiguous :: y(:), jac(:, :)
    real(c_double), pointer :: data(:)
    integer :: stat
    call c_f_pointer(user_data, ctx)
    call c_f_pointer(n_vgetarraypointer(c_loc(nv_y)), y, [ctx%n])
    ! the interface's pointer has length 1 (not n*n): reshape from its first element
    data => FSUNDenseMatrix_Data(jmat)
    call c_f_pointer(c_loc(data(1)), jac, [ctx%n, ctx%n])
    call ctx%prob%jac(t, y, jac, stat)
    ierr = -1
    if (stat /= MBDK_SUCCESS) then
      ctx%stat = stat
      return
    end if
    ierr = 0
    if (.not. all(abs(jac) <= huge(1.0_dp))) ierr = 1
  end function cvode_jac

end module mbdk_cvode
