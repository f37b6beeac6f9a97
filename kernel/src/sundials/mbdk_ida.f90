!> SUNDIALS IDA (6.x) through its Fortran 2003 interface, integrating a scene's equations of
!> motion (Fekete (2023) (2.54))
!>   M q'' + D^T lam = f(q, v, t),   Phi(q, t) = 0,   D = dPhi/dq,
!>   Phi' = D v + Phi_t,   D a = gamma
!> as a differential-algebraic system F(t, Y, Y') = 0, not as the reduced ODE, in one of two
!> forms, index1 or ggl (ggl refuses knife edges, MBDK_ERR_NOT_APPLICABLE: they have no
!> position row for its mu to stabilise). mbdk_ida_solve_spatial does the same for a spatial
!> scene (mbdk_spatial_model: rotations in q, velocities w, its comment gives the forms);
!> both share ida_run, the SUNDIALS part below.
!>
!> IDA solves F(t, Y, Y') = 0 with variable-order, variable-step BDF formulas (orders 1..5) in
!> fixed-leading-coefficient form (Brenan, Campbell and Petzold, Numerical Solution of IVPs in
!> DAEs, 1996, ch. 5; Hindmarsh et al., ACM TOMS 31 (2005) 363), Newton iteration on
!> dF/dY + cj dF/dY' from IDA's dense difference quotients (N residuals per Jacobian) on
!> SUNDIALS' dense matrix and dense LU (SUNMatrix_Dense, SUNLinSol_Dense). An analytic Jacobian
!> (the mass matrix, D, the force elements' tangents and the joints' geometric stiffness, as
!> mbdk_index3_matrix builds them) is out of scope: it would save the N residuals per setup,
!> not change what is computed.
!>
!> The two forms (nc = 3 nb coordinates, m constraint rows):
!>   index1 (ggl = .false.)  Y = [q; v; lam], N = 2 nc + m:
!>       r_q   = q' - v
!>       r_v   = M v' + D^T lam - f
!>       r_lam = D v' - gamma
!>     the acceleration-level constraint with the multipliers: an index-1 system. Phi and Phi'
!>     are not kept; they drift as in the reduced ODE (formulation 1 of mbdk_model), and the
!>     scene's watch ends the solve by name (MBDK_ERR_CONSTRAINT_DRIFT) where they leave its
!>     tolerances.
!>   ggl (ggl = .true.)      Y = [q; v; lam; mu], N = 2 nc + 2 m: the stabilised index-2 form of
!>     Gear, Gupta and Leimkuhler (J. Comput. Appl. Math. 12 (1985) 77):
!>       r_q   = q' - v + D^T mu
!>       r_v   = M v' + D^T lam - f
!>       r_lam = Phi(q, t)
!>       r_mu  = D v + Phi_t
!>     Phi and Phi' are solved for at every step, so the constraints do not drift and need no
!>     projection; they hold to the Newton tolerance of q and v at the steps (and to the local
!>     error at samples between steps, which come from the interpolant).
!>     mu = 0 in the exact solution and only takes up the part of q' - v the position
!>     constraint needs.
!> lam (and mu) are algebraic: IDASetId marks q and v differential (1) and lam, mu algebraic (0),
!> and IDASetSuppressAlg leaves the algebraic components out of the local error test, so the
!> error test sees positions and velocities only, as index-2 codes do (the local error of an
!> index-2 algebraic variable is an order lower than the formula's, and testing it would hold
!> h down; for index1 the multipliers follow from (q, v) and are left out the same way). The
!> local error of q and v is kept at WRMS <= 1 with the weights of mbdk_adaptive: rtol and the
!> scalar opt%atol.
!> The same weights serve IDA's Newton convergence test, which sees every component: lam with
!> rtol and opt%atol, so that the sampled multipliers are converged (ggl: with an absolute
!> tolerance of max(rtol, LAM_RTOL_FLOOR) times the largest multiplier so far, the roundoff
!> the index-2 iteration leaves in them; ggl_lam_atol), but mu with the absolute tolerance
!> MU_ATOL = 1 (ggl's weights are ida_ewt's, IDAWFtolerances), which takes it out of the
!> test. mu is zero in the
!> exact solution and has no meaning of its own; its Newton updates carry the roundoff of the
!> index-2 iteration matrix, whose condition grows like 1/h^2, so tested at opt%atol they stop
!> converging at small steps (IDA's own first step, 0.5 / |Y'(0)| in the error weights, is
!> tiny for a mechanism released at rest) and the solve ends with IDA_CONV_FAIL. The same
!> tolerance is mu's difference-quotient increment: F is linear in mu, so an increment of 1
!> gives its Jacobian column to roundoff.
!>
!> Initial values. The caller passes a consistent [q0; v0] (assembled: Phi = 0, D v + Phi_t = 0)
!> and a model built with the reduced formulation (another formulation: MBDK_ERR_NOT_APPLICABLE:
!> they are the ODE's ways of keeping the constraints, and the forms here replace them).
!> mbdk_model_accelerations gives a0 and lam0, and
!>   Y(0) = [q0; v0; lam0 (; 0)],   Y'(0) = [v0; a0; 0 (; 0)].
!> That is a consistent pair, so IDACalcIC is not needed: r_q = 0 exactly, r_v and (index1)
!> r_lam are the constrained solve's own residuals, and (ggl) r_lam, r_mu are the assembled
!> residuals; lam and mu appear in F undifferentiated, so lam' = mu' = 0 only seeds the first
!> predictor and is otherwise irrelevant. IDACalcIC would solve the same linear equations
!> again with a Newton stopping test on top. The residual at (Y(0), Y'(0)) is checked row by
!> row against the roundoff of the row's terms (CONSISTENT_ULPS units of eps times the sum of
!> their magnitudes; the position rows Phi also against ASSEMBLED_PHI, the tolerance
!> mbdk_model_start assembles to): a larger one is MBDK_ERR_INCONSISTENT_INITIAL. index1 checks
!> only its own residual, so it does not require Phi(q0) = 0 (nor does the reduced ODE).
!> lam0 is written to lam_out(:, 1).
!>
!> Options read: rtol, atol, h (> 0: the first step, IDASetInitStep; 0: IDA's estimate),
!> h_min and h_max (> 0: IDA's bounds, IDASetMinStep and IDASetMaxStep), max_order (0: 5;
!> above 5: MBDK_ERR_INVALID_INPUT), max_steps, interrupt. The caller has checked the
!> tolerances and step options (mbdk_adaptive_check) and, for a watching model, started the
!> watch at t0 (mbdk_model_watch_start).
!>
!> The loop is mbdk_adaptive's: IDA takes one internal step per call (IDA_ONE_STEP) and never
!> passes t_end (IDASetStopTime); after each step the samples in it come from IDA's
!> interpolant (IDAGetDky: [q; v] into y_out, lam into lam_out), the sample at t_end is the last
!> step's own state, Y is checked (finite: else MBDK_ERR_NONFINITE) and the scene's watch runs
!> (force = a sample fell in the step) with the step's own multipliers for the drivers' power:
!> no model evaluation of IDA's leaves work%lam_rhs current (a watch that integrates a work gets
!> the interpolant at the step's Gauss nodes first, mbdk_model_watch_nodes). The step's order
!> is counted.
!> max_steps bounds the accepted steps plus the steps retried after an error-test or a
!> convergence failure (IDAGetNumErrTestFails + IDAGetNumStepSolveFails), counted here (IDA's
!> own limit is off): MBDK_ERR_TOO_MANY_STEPS. A step below mbdk_adaptive_h_floor
!> (opt%h_min, and 10 ulps of t) is MBDK_ERR_STEP_TOO_SMALL, except the last one, which IDA
!> shortens to land on t_end. The interrupt flag is polled before each step and in every
!> residual, so a long Jacobian of a large model ends within one evaluation.
!>
!> Residual callback. One evaluation: mbdk_model_assemble (forces; counted in the model's visit
!> counters once) and mbdk_model_constraints (Phi, the dense D, gamma, Phi_t into buffers of
!> the context, allocated once per solve; its second pass over the joints is not counted).
!> A model failure (mbdk_model_assemble's stat) or the interrupt is stored and returned as
!> unrecoverable (-1), and every later call returns -1 too (mbdk_cvode's rule: no step can be
!> accepted after a failure even where a solver passes a -1 on as recoverable). IDA 6.4 stops at
!> the first: from the Newton iteration as IDA_RES_FAIL, from the difference-quotient Jacobian
!> as IDA_LSETUP_FAIL; the stored status names the cause either way. A non-finite Y or residual
!> (a diverging Newton iterate) is recoverable (1): IDA cuts the step.
!>
!> IDA's return flags (a residual's own status comes first when one ended the solve):
!>   IDA_TOO_MUCH_WORK                             MBDK_ERR_TOO_MANY_STEPS
!>   IDA_TOO_MUCH_ACC                              MBDK_ERR_TOO_MUCH_ACCURACY
!>   IDA_ERR_FAIL (error test failed repeatedly or at h_min)   MBDK_ERR_STEP_TOO_SMALL
!>   IDA_CONV_FAIL                                 MBDK_ERR_NEWTON_DIVERGED
!>   IDA_LSETUP_FAIL, IDA_LSOLVE_FAIL              MBDK_ERR_SINGULAR_MATRIX
!>   IDA_RES_FAIL, IDA_FIRST_RES_FAIL, IDA_REP_RES_ERR
!>                                                 MBDK_ERR_NONFINITE after a non-finite
!>                                                 residual, else MBDK_ERR_CALLBACK_FAILED
!>   IDA_MEM_FAIL                                  MBDK_ERR_NO_MEMORY
!>   IDA_ILL_INPUT                                 MBDK_ERR_INVALID_INPUT
!>   any other failure (IDA_CONSTR_FAIL, IDA_NLS_FAIL, IDA_LINIT_FAIL, ...)   MBDK_ERR_BACKEND
!>
!> Statistics, from IDA's counters (also after a failure):
!>   steps IDAGetNumSteps; nfev IDAGetNumResEvals + IDAGetNumLinResEvals (the
!>   difference-quotient columns); njev IDAGetNumJacEvals; nlu IDAGetNumLinSolvSetups (each
!>   setup factors dF/dY + cj dF/dY'); newton_iterations IDAGetNumNonlinSolvIters;
!>   rejected_steps IDAGetNumErrTestFails; newton_failures IDAGetNumNonlinSolvConvFails (every
!>   failed Newton attempt, also one that IDA repeats within the step with a fresh Jacobian:
!>   on a smooth problem most of them; a step retried at a smaller h is one of
!>   IDAGetNumStepSolveFails); order1_steps..order5_steps IDAGetLastOrder per step.
!>
!> Out of scope: an analytic Jacobian (above), IDACalcIC (above), the sparse structure of the
!> Newton matrix (dense: O(N^3) per setup, for the scene sizes of the book), per-component
!> tolerances, root finding. SUNDIALS writes its error messages to stderr by default;
!> IDASetErrFile(NULL) silences them, as the kernel never prints. All SUNDIALS objects are freed
!> on every path.
module mbdk_ida
  use, intrinsic :: iso_c_binding, only: c_ptr, c_null_ptr, c_loc, c_funloc, c_f_pointer, &
    c_associated, c_int, c_long, c_int64_t, c_double, c_intptr_t
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_problem, only: MBDK_GAUSS3
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  use mbdk_interrupt, only: mbdk_interrupted, mbdk_progress
  use mbdk_adaptive, only: mbdk_adaptive_step_limit, mbdk_adaptive_h_floor, mbdk_adaptive_count_order
  use mbdk_model, only: mbdk_model_t, mbdk_model_assemble, mbdk_model_constraints, &
    mbdk_model_accelerations, mbdk_model_watch, mbdk_model_watch_nodes, MBDK_FORM_REDUCED
  use mbdk_joints, only: MBDK_JOINT_TYPES
  use mbdk_spatial_model, only: mbdk_spatial_model_t, mbdk_spatial_dae_rhs, &
    mbdk_spatial_constraints, mbdk_spatial_multipliers, mbdk_spatial_watch, &
    mbdk_spatial_watch_nodes, MBDK_SPATIAL_REDUCED
  use mbdk_spatial_dae, only: mbdk_spatial_ggl_rates
  use fsundials_context_mod, only: FSUNContext_Create, FSUNContext_Free
  use fsundials_nvector_mod, only: N_Vector, FN_VDestroy
  use fnvector_serial_mod, only: FN_VMake_Serial
  use fsundials_matrix_mod, only: SUNMatrix, FSUNMatDestroy
  use fsunmatrix_dense_mod, only: FSUNDenseMatrix
  use fsundials_linearsolver_mod, only: SUNLinearSolver, FSUNLinSolFree
  use fsunlinsol_dense_mod, only: FSUNLinSol_Dense
  use fida_mod, only: IDA_ONE_STEP, IDA_TOO_MUCH_WORK, IDA_TOO_MUCH_ACC, &
    IDA_ERR_FAIL, IDA_CONV_FAIL, IDA_LSETUP_FAIL, IDA_LSOLVE_FAIL, IDA_RES_FAIL, &
    IDA_FIRST_RES_FAIL, IDA_REP_RES_ERR, IDA_MEM_FAIL, IDA_ILL_INPUT, FIDACreate, FIDAInit, &
    FIDAFree, FIDASStolerances, FIDASetUserData, FIDASetErrFile, FIDASetMaxNumSteps, &
    FIDASetStopTime, FIDASetMaxOrd, FIDASetInitStep, FIDASetMinStep, FIDASetMaxStep, FIDASetId, &
    FIDASetSuppressAlg, FIDASetLinearSolver, FIDASolve, FIDAGetDky, FIDAGetLastOrder, &
    FIDAGetLastStep, FIDAGetNumSteps, FIDAGetNumResEvals, FIDAGetNumLinResEvals, &
    FIDAGetNumJacEvals, FIDAGetNumLinSolvSetups, FIDAGetNumNonlinSolvIters, &
    FIDAGetNumErrTestFails, FIDAGetNumNonlinSolvConvFails, FIDAGetNumStepSolveFails, &
    FIDAWFtolerances
  implicit none
  private
  public :: mbdk_ida_solve, mbdk_ida_solve_spatial

  integer, parameter :: IDA_MAX_ORDER = 5
  !> a consistent initial residual row is within this many eps of the sum of its terms' sizes:
  !> the roundoff of a constrained solve's residual, with room for a row's few terms and the
  !> conditioning of D M^-1 D^T
  real(dp), parameter :: CONSISTENT_ULPS = 1.0e3_dp
  !> |Phi| an assembled state may keep: mbdk_model_start's assembly tolerance
  real(dp), parameter :: ASSEMBLED_PHI = 1.0e-12_dp
  !> ggl: mu's absolute tolerance, which leaves it out of the Newton test (module header)
  real(dp), parameter :: MU_ATOL = 1.0_dp
  !> ggl: the multipliers' Newton test, relative to the largest initial multiplier, is not
  !> tighter than this (ggl_lam_atol)
  real(dp), parameter :: LAM_RTOL_FLOOR = 1.0e-8_dp
  !> spatial ggl: the least first step, as a fraction of the interval (mbdk_ida_solve_spatial)
  real(dp), parameter :: GGL_FIRST_STEP = 1.0e-6_dp

  ! SUNDIALS' own accessor, called directly (as in mbdk_cvode): the interface's
  ! FN_VGetArrayPointer asks for the length through a second wrapper on every call.
  interface
    type(c_ptr) function n_vgetarraypointer(v) bind(C, name='N_VGetArrayPointer')
      import :: c_ptr
      type(c_ptr), value :: v
    end function n_vgetarraypointer
  end interface

  !> What the residual reaches through IDA's user data: one per solve, on the solver's stack,
  !> with the evaluation's buffers so that an evaluation allocates nothing.
  type :: ida_context_t
    type(mbdk_model_t), pointer :: model => null()
    integer :: nc = 0, m = 0, n = 0
    !> Y = [the differential part (ny); the multipliers (nl); (ggl) mu (nl)]: planar ny = 2 nc,
    !> nl = m; spatial ny = nq + 6 nb, nl = the independent rows (rows)
    integer :: ny = 0, nl = 0
    !> the first step where the caller gave none (0: IDA's own estimate)
    real(dp) :: h0 = 0.0_dp
    logical :: ggl = .false.
    !> ggl: the largest multiplier its tolerance was set from (ggl_lam_atol), and the error
    !> weights' tolerances, which ida_ewt reads (IDA's own IDASVtolerances cannot be called
    !> again once the solve has started: IDA 6.4 leaves its weight function without its data)
    real(dp) :: lam_scale = 0.0_dp, rtol = 0.0_dp
    real(dp), pointer, contiguous :: atol(:) => null()
    logical :: spatial = .false.
    type(mbdk_spatial_model_t), pointer :: smodel => null()
    integer :: nq = 0
    integer, allocatable :: rows(:)
    real(dp), allocatable :: c(:, :), lamfull(:), g(:), g2(:)
    !> spatial: whether the residual also keeps the accelerations' force part in g2
    logical :: want_g2 = .false.
    !> a residual's failure status that made it return -1 (IDA then stops)
    integer :: stat = MBDK_SUCCESS
    !> MBDK_ERR_NONFINITE when a residual was not finite in the current step (recoverable)
    integer :: soft_stat = MBDK_SUCCESS
    integer(c_intptr_t) :: interrupt = 0
    real(dp), allocatable :: phi(:), d(:, :), gam(:), phit(:)
  end type ida_context_t

contains

  !> See the module header. ggl: the stabilised index-2 form, else index1. y0 = [q0; v0];
  !> t_out: the sample times (t_out(1) = t0, written by the caller with nwritten = 1, the last
  !> t_end); y_out(2 nc, >= size(t_out)) receives [q; v] at samples 2, 3, ...; lam_out(>= m, :)
  !> the multipliers at the samples its columns reach (column 1: lam0; no columns: none).
  subroutine mbdk_ida_solve(model, opt, ggl, t0, y0, t_out, y_out, lam_out, nwritten, st, stat)
    type(mbdk_model_t), intent(in), target :: model
    type(mbdk_options_t), intent(in) :: opt
    logical, intent(in) :: ggl
    real(dp), intent(in) :: t0, y0(:)
    real(dp), intent(in) :: t_out(:)
    real(dp), intent(inout) :: y_out(:, :)
    real(dp), intent(inout) :: lam_out(:, :)
    integer, intent(inout) :: nwritten
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat

    type(ida_context_t), target :: ctx
    real(dp), allocatable, target :: y(:), yp(:), ydky(:), id(:), atol_v(:)
    real(dp), allocatable :: r0(:), a0(:), dtl(:)
    integer :: nc, m, n, ns, ierr, nlam
    real(dp) :: t_end

    nc = model%nc
    m = model%m
    ns = size(t_out)
    nlam = size(lam_out, 2)
    stat = MBDK_ERR_NOT_APPLICABLE
    if (model%formulation /= MBDK_FORM_REDUCED) return
    ! GGL's mu stabilises position rows; a knife edge has none (index1 keeps it: D a = gamma)
    if (ggl .and. model%has_pfaffian) return
    stat = MBDK_ERR_INVALID_INPUT
    if (nc < 1 .or. size(y0) /= 2 * nc .or. ns < 2) return
    t_end = t_out(ns)
    if (.not. (t_end > t0)) return
    if (opt%max_order < 0 .or. opt%max_order > IDA_MAX_ORDER) return
    stat = MBDK_ERR_OUTPUT_SIZE
    if (size(y_out, 1) /= 2 * nc .or. size(y_out, 2) < ns) return
    if (nlam > 0 .and. size(lam_out, 1) < m) return
    n = 2 * nc + m
    if (ggl) n = n + m

    stat = MBDK_ERR_NO_MEMORY
    allocate (y(n), yp(n), ydky(n), id(n), atol_v(n), r0(n), a0(nc), dtl(nc), ctx%phi(m), &
              ctx%d(m, nc), ctx%gam(m), ctx%phit(m), stat=ierr)
    call mbdk_alloc_status(ierr, MBDK_REAL_BYTES * (6.0_dp * n + 2 * nc + real(m, dp) * (nc + 3)), &
                           stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    ctx%model => model
    ctx%nc = nc
    ctx%m = m
    ctx%n = n
    ctx%ggl = ggl
    ctx%interrupt = opt%interrupt

    ! consistent initial values (module header): lam0 from the model's constrained solve
    y(1:2 * nc) = y0
    call mbdk_model_accelerations(model, t0, y0(1:nc), y0(nc + 1:2 * nc), a0, &
                                  y(2 * nc + 1:2 * nc + m), stat)
    if (stat /= MBDK_SUCCESS) return
    y(2 * nc + m + 1:) = 0.0_dp
    yp(1:nc) = y0(nc + 1:2 * nc)
    yp(nc + 1:2 * nc) = a0
    yp(2 * nc + 1:) = 0.0_dp
    call dae_residual(ctx, t0, y, yp, r0, stat)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INCONSISTENT_INITIAL
    if (.not. consistent(ctx, y, yp, a0, r0, dtl)) return
    if (nlam >= 1) lam_out(1:m, 1) = y(2 * nc + 1:2 * nc + m)
    id(1:2 * nc) = 1.0_dp
    id(2 * nc + 1:) = 0.0_dp
    atol_v(1:2 * nc + m) = opt%atol
    atol_v(2 * nc + m + 1:) = MU_ATOL
    if (ggl .and. m > 0) then
      atol_v(2 * nc + 1:2 * nc + m) = ggl_lam_atol(opt, y(2 * nc + 1:2 * nc + m))
      ctx%lam_scale = maxval(abs(y(2 * nc + 1:2 * nc + m)))
    end if

    ctx%ny = 2 * nc
    ctx%nl = m
    call ida_run(ctx, opt, t0, t_end, y, yp, ydky, id, atol_v, t_out, y_out, lam_out, nwritten, &
                 st, stat)
  end subroutine mbdk_ida_solve

  !> ida on a spatial scene (mbdk_spatial_model, built with the reduced formulation), with the
  !> state y0 = [q0; w0] (q: centres and quaternions or angles, w: velocities and body-frame
  !> angular velocities) and the multipliers of the independent rows a = model%work%active
  !> (Bricard's linkage keeps 29 of its 30), a(q, w, lam) = M^-1 (f - W x J W - C_a^T lam):
  !>   index1  Y = [q; w; lam_a]:
  !>       r_q = q' - T(q) w,   r_w = w' - a(q, w, lam),   r_lam = C_a w' - gamma_a
  !>   ggl     Y = [q; w; lam_a; mu_a]:
  !>       r_q = q' - T(q) (w - M^-1 C_a^T mu),   r_w = w' - a(q, w, lam),
  !>       r_lam = Phi_a(q, t),   r_mu = C_a w + Phi_t,a
  !>     GGL's mu acts through the rates T(q) of the velocities M^-1 C^T mu, since the spatial
  !>     model forms C in w, not dPhi/dq in q: Phi' = C (w - M^-1 C^T mu) + Phi_t, so with
  !>     C w + Phi_t = 0 and Phi = 0 held, mu = 0 (C M^-1 C^T is regular on the independent
  !>     rows). M^-1 C^T mu comes from a's linearity in lam, a(lam - mu) - a(lam), and its rates
  !>     from T(q) at the same q: three model evaluations and the constraints per residual
  !>     (index1: one and the constraints).
  !> The rest is mbdk_ida_solve's (the module header): consistent Y(0) = [q0; w0; lam0 (; 0)],
  !> Y'(0) = [T(q0) w0; a0; 0 (; 0)] from the model's constrained solve, the error test on q
  !> and w, mu out of the Newton test, the same statuses and counters. The quaternions' norm
  !> is not projected (IDA's history forbids it); the rotation is read from p / |p|.
  subroutine mbdk_ida_solve_spatial(model, opt, ggl, t0, y0, t_out, y_out, lam_out, nwritten, &
                                    st, stat)
    type(mbdk_spatial_model_t), intent(in), target :: model
    type(mbdk_options_t), intent(in) :: opt
    logical, intent(in) :: ggl
    real(dp), intent(in) :: t0, y0(:)
    real(dp), intent(in) :: t_out(:)
    real(dp), intent(inout) :: y_out(:, :)
    real(dp), intent(inout) :: lam_out(:, :)
    integer, intent(inout) :: nwritten
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat

    type(ida_context_t), target :: ctx
    real(dp), allocatable, target :: y(:), yp(:), ydky(:), id(:), atol_v(:)
    real(dp), allocatable :: r0(:), phi(:), gam(:), phit(:), sizes(:)
    integer :: ny, nq, m, na, n, ns, ierr, nlam, i, k
    real(dp) :: t_end, tol, s

    ny = size(y0)
    nq = ny - 6 * model%nb
    m = model%m
    ns = size(t_out)
    nlam = size(lam_out, 2)
    stat = MBDK_ERR_NOT_APPLICABLE
    if (model%opt%formulation /= MBDK_SPATIAL_REDUCED) return
    stat = MBDK_ERR_INVALID_INPUT
    if (ny /= model%n .or. nq < 1 .or. ns < 2) return
    t_end = t_out(ns)
    if (.not. (t_end > t0)) return
    if (opt%max_order < 0 .or. opt%max_order > IDA_MAX_ORDER) return
    stat = MBDK_ERR_OUTPUT_SIZE
    if (size(y_out, 1) /= ny .or. size(y_out, 2) < ns) return
    if (nlam > 0 .and. size(lam_out, 1) < m) return
    stat = MBDK_ERR_NO_MEMORY
    allocate (phi(m), gam(m), phit(m), ctx%c(m, ny - nq), ctx%lamfull(m), ctx%phi(m), &
              ctx%gam(m), ctx%phit(m), ctx%g(ny), ctx%g2(ny), stat=ierr)
    call mbdk_alloc_status(ierr, MBDK_REAL_BYTES * (real(m, dp) * (ny - nq + 7) + 2.0_dp * ny), &
                           stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    ! the rows after the model's solve at t0, which may move a redundant scene to another set
    if (m > 0) then
      call mbdk_spatial_multipliers(model, t0, y0, ctx%lamfull, stat)
      if (stat /= MBDK_SUCCESS) return
    end if
    ctx%rows = model%work%active
    na = size(ctx%rows)
    n = ny + na
    if (ggl) n = n + na
    stat = MBDK_ERR_NO_MEMORY
    allocate (y(n), yp(n), ydky(n), id(n), atol_v(n), r0(n), stat=ierr)
    call mbdk_alloc_status(ierr, MBDK_REAL_BYTES * 6.0_dp * n, stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    ctx%smodel => model
    ctx%spatial = .true.
    ctx%m = m
    ctx%n = n
    ctx%ny = ny
    ctx%nq = nq
    ctx%nl = na
    ctx%ggl = ggl
    ctx%interrupt = opt%interrupt

    ! consistent initial values: the reduced formulation's rates and multipliers
    y(1:ny) = y0
    y(ny + 1:) = 0.0_dp
    if (m > 0) y(ny + 1:ny + na) = ctx%lamfull(ctx%rows)
    call model%rhs(t0, y0, yp(1:ny), stat)
    if (stat /= MBDK_SUCCESS) return
    yp(ny + 1:) = 0.0_dp
    ctx%want_g2 = .true.          ! the force part, for the test below only
    call dae_residual(ctx, t0, y, yp, r0, stat)
    ctx%want_g2 = .false.
    if (stat /= MBDK_SUCCESS) return
    ! every row within roundoff of its terms' sizes (the rates', the accelerations', C's)
    stat = MBDK_ERR_INCONSISTENT_INITIAL
    tol = CONSISTENT_ULPS * epsilon(1.0_dp)
    s = maxval(abs(yp(1:nq))) + maxval(abs(ctx%g(1:nq)))
    if (.not. all(abs(r0(1:nq)) <= tol * s)) return
    s = maxval(abs(yp(nq + 1:ny))) + maxval(abs(ctx%g2(nq + 1:ny))) + tiny(1.0_dp)
    if (.not. all(abs(r0(nq + 1:ny)) <= tol * s)) return
    call mbdk_spatial_constraints(model, t0, y0, phi, ctx%c, gam, phit, stat)
    if (stat /= MBDK_SUCCESS) return
    ! the constraint rows within roundoff of the largest row's terms: a row whose own terms are
    ! all zero (a mechanism at rest) still carries the roundoff of gamma's
    allocate (sizes(na), stat=ierr)
    call mbdk_alloc_status(ierr, MBDK_REAL_BYTES * na, stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INCONSISTENT_INITIAL
    do i = 1, na
      k = ctx%rows(i)
      if (ggl) then
        if (.not. (abs(r0(ny + i)) <= max(ASSEMBLED_PHI, model%opt%projection_tol))) return
        sizes(i) = sum(abs(ctx%c(k, :) * y0(nq + 1:))) + abs(phit(k))
      else
        ! C a = gamma with a = M^-1 (f - C^T lam): a's roundoff is that of its two parts,
        ! which nearly cancel in a mechanism at rest under gravity
        sizes(i) = sum(abs(ctx%c(k, :)) * (abs(yp(nq + 1:ny)) + abs(ctx%g2(nq + 1:ny)) + &
                                           abs(ctx%g(nq + 1:ny) - ctx%g2(nq + 1:ny)))) + &
                   abs(gam(k))
      end if
    end do
    if (na > 0) then
      if (.not. all(abs(r0(ny + merge(na, 0, ggl) + 1:ny + merge(na, 0, ggl) + na)) <= &
                    tol * max(maxval(sizes), 1.0_dp))) return
    end if
    if (nlam >= 1 .and. m > 0) call put_lam(ctx, y(ny + 1:ny + na), lam_out(:, 1))
    id(1:ny) = 1.0_dp
    id(ny + 1:) = 0.0_dp
    atol_v(1:ny + na) = opt%atol
    atol_v(ny + na + 1:) = MU_ATOL
    if (ggl .and. na > 0) then
      atol_v(ny + 1:ny + na) = ggl_lam_atol(opt, y(ny + 1:ny + na))
      ctx%lam_scale = maxval(abs(y(ny + 1:ny + na)))
    end if
    if (ggl) then
      ! IDA's first step, 0.5 / ||Y'(0)|| in its error weights, at least GGL_FIRST_STEP of the
      ! interval: the index-2 Newton matrix's condition grows like 1/h^2, and a fast start
      ! (a spinning body) at a tight rtol would make that estimate so small that the matrix is
      ! singular to roundoff
      s = sqrt(sum((yp(1:ny) / (opt%rtol * abs(y0) + opt%atol))**2) / ny)
      ctx%h0 = (t_end - t0) * GGL_FIRST_STEP
      if (s > 0.0_dp) ctx%h0 = min(max(0.5_dp / s, ctx%h0), 1.0e-3_dp * (t_end - t0))
    end if
    call ida_run(ctx, opt, t0, t_end, y, yp, ydky, id, atol_v, t_out, y_out, lam_out, nwritten, &
                 st, stat)
  end subroutine mbdk_ida_solve_spatial

  !> F(t, Y, Y') of a spatial scene's form (mbdk_ida_solve_spatial) into r; ctx%g holds
  !> [T(q) w; a] (ggl: [T(q) (w - M^-1 C^T mu); a]) and, when want_g2, ctx%g2 the
  !> accelerations' force part M^-1 (f - W x J W) for the consistency test.
  subroutine spatial_residual(ctx, t, y, yp, r, stat)
    type(ida_context_t), intent(inout) :: ctx
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:), yp(:)
    real(dp), intent(out), contiguous :: r(:)
    integer, intent(out) :: stat
    integer :: ny, nq, na, i, k
    ny = ctx%ny
    nq = ctx%nq
    na = ctx%nl
    ctx%lamfull = 0.0_dp
    if (ctx%want_g2) then          ! the force part alone (lam = 0)
      call mbdk_spatial_dae_rhs(ctx%smodel, t, y(1:ny), ctx%lamfull, ctx%g2, ctx%phi, stat)
      if (stat /= MBDK_SUCCESS) return
    end if
    ctx%lamfull(ctx%rows) = y(ny + 1:ny + na)
    call mbdk_spatial_dae_rhs(ctx%smodel, t, y(1:ny), ctx%lamfull, ctx%g, ctx%phi, stat)
    if (stat /= MBDK_SUCCESS) return
    r(nq + 1:ny) = yp(nq + 1:ny) - ctx%g(nq + 1:ny)
    if (ctx%ggl) then          ! T(q) (w - M^-1 C^T mu)
      ctx%lamfull(ctx%rows) = y(ny + 1:ny + na) - y(ny + na + 1:ny + 2 * na)
      call mbdk_spatial_ggl_rates(ctx%smodel, t, y(1:ny), nq, ctx%lamfull, ctx%g(nq + 1:ny), &
                                  ctx%g(1:nq), stat)
      if (stat /= MBDK_SUCCESS) return
    end if
    r(1:nq) = yp(1:nq) - ctx%g(1:nq)
    if (na == 0) return
    call mbdk_spatial_constraints(ctx%smodel, t, y(1:ny), ctx%phi, ctx%c, ctx%gam, ctx%phit, &
                                  stat)
    if (stat /= MBDK_SUCCESS) return
    do i = 1, na
      k = ctx%rows(i)
      if (ctx%ggl) then
        r(ny + i) = ctx%phi(k)
        r(ny + na + i) = dot_product(ctx%c(k, :), y(nq + 1:ny)) + ctx%phit(k)
      else
        r(ny + i) = dot_product(ctx%c(k, :), yp(nq + 1:ny)) - ctx%gam(k)
      end if
    end do
  end subroutine spatial_residual

  !> The SUNDIALS part of a solve (the module header), for either model: IDA from the
  !> consistent (y, yp) of the context's form to t_out's last time, samples and multipliers out.
  subroutine ida_run(ctx, opt, t0, t_end, y, yp, ydky, id, atol_v, t_out, y_out, lam_out, &
                     nwritten, st, stat)
    type(ida_context_t), intent(inout), target :: ctx
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_end
    real(dp), intent(inout), target, contiguous :: y(:), yp(:), ydky(:), id(:), atol_v(:)
    real(dp), intent(in) :: t_out(:)
    real(dp), intent(inout) :: y_out(:, :), lam_out(:, :)
    integer, intent(inout) :: nwritten
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    type(c_ptr) :: sunctx, mem
    type(N_Vector), pointer :: nv_y, nv_yp, nv_dky, nv_id
    type(SUNMatrix), pointer :: amat
    type(SUNLinearSolver), pointer :: ls
    real(c_double) :: tret(1), hlast(1), told
    integer(c_int) :: flag, qlast(1)
    integer(c_long) :: nst(1), netf(1), ncfn(1)
    integer(i8) :: limit
    integer :: n, ns, k, ierr, nlam, ny, nl, i
    logical :: sample, nodes
    real(dp), allocatable :: yn(:, :), lamn(:, :)
    n = ctx%n
    ny = ctx%ny
    nl = ctx%nl
    ns = size(t_out)
    nlam = size(lam_out, 2)
    ! every handle starts empty so that the release below frees what exists on any path
    sunctx = c_null_ptr
    mem = c_null_ptr
    nullify (nv_y, nv_yp, nv_dky, nv_id, amat, ls)

    run: block
      stat = MBDK_ERR_BACKEND
      if (FSUNContext_Create(c_null_ptr, sunctx) /= 0) exit run
      stat = MBDK_ERR_NO_MEMORY
      nv_y => FN_VMake_Serial(int(n, c_int64_t), y, sunctx)
      if (.not. associated(nv_y)) exit run
      nv_yp => FN_VMake_Serial(int(n, c_int64_t), yp, sunctx)
      if (.not. associated(nv_yp)) exit run
      nv_dky => FN_VMake_Serial(int(n, c_int64_t), ydky, sunctx)
      if (.not. associated(nv_dky)) exit run
      nv_id => FN_VMake_Serial(int(n, c_int64_t), id, sunctx)
      if (.not. associated(nv_id)) exit run
      mem = FIDACreate(sunctx)
      if (.not. c_associated(mem)) exit run
      ! before anything else can fail: the kernel never prints
      stat = MBDK_ERR_BACKEND
      if (FIDASetErrFile(mem, c_null_ptr) /= 0) exit run

      flag = FIDAInit(mem, c_funloc(ida_res), t0, nv_y, nv_yp)
      if (flag == 0) then
        if (ctx%ggl) then
          ctx%rtol = opt%rtol
          ctx%atol => atol_v
          flag = FIDAWFtolerances(mem, c_funloc(ida_ewt))
        else
          flag = FIDASStolerances(mem, opt%rtol, opt%atol)
        end if
      end if
      if (flag == 0) flag = FIDASetUserData(mem, c_loc(ctx))
      ! the error test sees q and v only (module header); IDA copies id
      if (flag == 0) flag = FIDASetId(mem, nv_id)
      if (flag == 0) flag = FIDASetSuppressAlg(mem, 1_c_int)
      ! the step count is ours (max_steps counts failures too); IDA's per-call limit is off
      if (flag == 0) flag = FIDASetMaxNumSteps(mem, -1_c_long)
      if (flag == 0) flag = FIDASetStopTime(mem, t_end)
      if (flag == 0 .and. opt%max_order > 0) &
        flag = FIDASetMaxOrd(mem, int(opt%max_order, c_int))
      if (flag == 0 .and. opt%h > 0.0_dp) then
        flag = FIDASetInitStep(mem, opt%h)
      else if (flag == 0 .and. ctx%h0 > 0.0_dp) then
        flag = FIDASetInitStep(mem, ctx%h0)
      end if
      if (flag == 0 .and. opt%h_min > 0.0_dp) flag = FIDASetMinStep(mem, opt%h_min)
      if (flag == 0 .and. opt%h_max > 0.0_dp) flag = FIDASetMaxStep(mem, opt%h_max)
      if (flag /= 0) then
        stat = ida_status(flag, ctx%stat, ctx%soft_stat)
        exit run
      end if

      stat = MBDK_ERR_NO_MEMORY
      amat => FSUNDenseMatrix(int(n, c_int64_t), int(n, c_int64_t), sunctx)
      if (.not. associated(amat)) then   ! (the size SUNDIALS asked for: n x n doubles)
        st%alloc_bytes = MBDK_REAL_BYTES * real(n, dp)**2
        exit run
      end if
      ls => FSUNLinSol_Dense(nv_y, amat, sunctx)
      if (.not. associated(ls)) exit run
      ! no Jacobian function: IDA's dense difference quotients
      stat = MBDK_ERR_BACKEND
      if (FIDASetLinearSolver(mem, ls, amat) /= 0) exit run

      limit = mbdk_adaptive_step_limit(opt)
      k = nwritten + 1           ! the next sample to write
      tret(1) = t0
      told = t0
      st%t_reached = t0
      allocate (yn(ny, 3), lamn(ctx%m, 3), stat=ierr)
      call mbdk_alloc_status(ierr, MBDK_REAL_BYTES * 3.0_dp * (ny + ctx%m), stat, &
                             st%alloc_bytes)
      if (stat /= MBDK_SUCCESS) exit run
      do while (tret(1) < t_end)
        if (opt%interrupt /= 0 .and. mbdk_interrupted(opt%interrupt)) then
          stat = MBDK_ERR_INTERRUPTED
          exit run
        end if
        if (opt%progress /= 0) call mbdk_progress(opt%progress, tret(1))
        flag = FIDAGetNumSteps(mem, nst)
        flag = FIDAGetNumErrTestFails(mem, netf)
        flag = FIDAGetNumStepSolveFails(mem, ncfn)
        if (int(nst(1), i8) + int(netf(1), i8) + int(ncfn(1), i8) >= limit) then
          stat = MBDK_ERR_TOO_MANY_STEPS
          exit run
        end if
        ctx%soft_stat = MBDK_SUCCESS
        flag = FIDASolve(mem, t_end, tret, nv_y, nv_yp, IDA_ONE_STEP)
        if (flag < 0) then
          stat = ida_status(flag, ctx%stat, ctx%soft_stat)
          exit run
        end if
        stat = ctx%stat
        if (stat /= MBDK_SUCCESS) exit run
        ! IDA's own floor is h_min (0 by default): a step that cannot move t would repeat. The
        ! step IDA shortened to land on t_end is the last one, whatever its length.
        flag = FIDAGetLastStep(mem, hlast)
        if (tret(1) < t_end .and. hlast(1) < mbdk_adaptive_h_floor(opt, tret(1))) then
          stat = MBDK_ERR_STEP_TOO_SMALL
          exit run
        end if
        flag = FIDAGetLastOrder(mem, qlast)
        call mbdk_adaptive_count_order(st, int(qlast(1)))

        ! samples inside the step from IDA's interpolant
        sample = .false.
        do while (k <= ns)
          if (t_out(k) >= tret(1)) exit
          if (FIDAGetDky(mem, t_out(k), 0_c_int, nv_dky) /= 0) then
            stat = MBDK_ERR_BACKEND
            exit run
          end if
          y_out(:, k) = ydky(1:ny)
          if (nlam >= k) call put_lam(ctx, ydky(ny + 1:ny + nl), lam_out(:, k))
          nwritten = k
          k = k + 1
          sample = .true.
        end do
        if (k <= ns) sample = sample .or. t_out(k) <= tret(1)
        if (.not. all(abs(y) <= huge(1.0_dp))) then
          stat = MBDK_ERR_NONFINITE
          exit run
        end if
        ! the watch's work over the step from IDA's interpolant at its Gauss nodes
        if (ctx%spatial) then
          nodes = ctx%smodel%watch_wants_nodes()
        else
          nodes = ctx%model%watch_wants_nodes()
        end if
        if (nodes) then
          do i = 1, 3
            if (FIDAGetDky(mem, told + MBDK_GAUSS3(i) * (tret(1) - told), 0_c_int, &
                           nv_dky) /= 0) then
              stat = MBDK_ERR_BACKEND
              exit run
            end if
            yn(:, i) = ydky(1:ny)
            call put_lam(ctx, ydky(ny + 1:ny + nl), lamn(:, i))
          end do
          if (ctx%spatial) then
            call mbdk_spatial_watch_nodes(ctx%smodel, told, tret(1), yn, stat, lamn)
          else
            call mbdk_model_watch_nodes(ctx%model, told, tret(1), yn(1:ny / 2, :), &
                                        yn(ny / 2 + 1:ny, :), stat, lamn)
          end if
          if (stat /= MBDK_SUCCESS) exit run
        end if
        told = tret(1)
        if (ctx%spatial) then
          if (ctx%smodel%has_watch) then
            call put_lam(ctx, y(ny + 1:ny + nl), ctx%lamfull)
            call mbdk_spatial_watch(ctx%smodel, tret(1), y(1:ny), sample, stat, &
                                    lam=ctx%lamfull)
            if (stat /= MBDK_SUCCESS) exit run
          end if
        else if (ctx%model%has_watch) then
          call mbdk_model_watch(ctx%model, tret(1), y(1:ny / 2), y(ny / 2 + 1:ny), sample, &
                                stat, lam=y(ny + 1:ny + nl))
          if (stat /= MBDK_SUCCESS) exit run
        end if
        st%t_reached = tret(1)      ! the step passed its checks
        if (ctx%ggl .and. ctx%nl > 0) then
          ! multipliers that grew (from rest, or a load ramped up) raise their tolerance
          if (maxval(abs(y(ctx%ny + 1:ctx%ny + ctx%nl))) > 2.0_dp * ctx%lam_scale) then
            ctx%lam_scale = maxval(abs(y(ctx%ny + 1:ctx%ny + ctx%nl)))
            atol_v(ctx%ny + 1:ctx%ny + ctx%nl) = ggl_lam_atol(opt, y(ctx%ny + 1:ctx%ny + ctx%nl))
          end if
        end if
        do while (k <= ns)
          if (t_out(k) > tret(1)) exit
          y_out(:, k) = y(1:ny)
          if (nlam >= k) call put_lam(ctx, y(ny + 1:ny + nl), lam_out(:, k))
          nwritten = k
          k = k + 1
        end do
      end do
      stat = MBDK_SUCCESS
    end block run

    if (c_associated(mem)) call add_stats(mem, st)
    call FIDAFree(mem)   ! NULL-safe; also frees IDA's copy of id
    if (associated(ls)) ierr = FSUNLinSolFree(ls)
    if (associated(amat)) call FSUNMatDestroy(amat)
    if (associated(nv_id)) call FN_VDestroy(nv_id)
    if (associated(nv_dky)) call FN_VDestroy(nv_dky)
    if (associated(nv_yp)) call FN_VDestroy(nv_yp)
    if (associated(nv_y)) call FN_VDestroy(nv_y)
    if (c_associated(sunctx)) ierr = FSUNContext_Free(sunctx)
  end subroutine ida_run

  !> The multipliers of Y (the context's nl) as the model's m rows into dst (the spatial model's
  !> dependent rows: 0).
  subroutine put_lam(ctx, src, dst)
    type(ida_context_t), intent(in) :: ctx
    real(dp), intent(in) :: src(:)
    real(dp), intent(inout) :: dst(:)
    if (ctx%spatial) then
      dst(1:ctx%m) = 0.0_dp
      dst(ctx%rows) = src
    else
      dst(1:ctx%m) = src
    end if
  end subroutine put_lam

  !> Whether the residual r of the initial values (y, yp) is within roundoff, row by row (see
  !> the module header); ctx holds the evaluation at those values, a the accelerations. dtl(nc):
  !> work (the caller's: an automatic array would be taken from malloc unchecked).
  logical function consistent(ctx, y, yp, a, r, dtl)
    type(ida_context_t), intent(in) :: ctx
    real(dp), intent(in) :: y(:), yp(:), a(:), r(:)
    real(dp), intent(out) :: dtl(:)
    real(dp) :: s, smax, tol
    integer :: nc, m, i, k
    nc = ctx%nc
    m = ctx%m
    tol = CONSISTENT_ULPS * epsilon(1.0_dp)
    associate (mass => ctx%model%mass, winv => ctx%model%winv, fq => ctx%model%work%fq, &
               d => ctx%d, lam => y(2 * nc + 1:2 * nc + m))
      consistent = .false.
      do k = 1, nc
        dtl(k) = sum(abs(d(:, k) * lam))     ! the sizes of the terms of D^T lam
        if (.not. (abs(r(k)) <= tol * (abs(yp(k)) + abs(y(nc + k))))) return
        if (.not. (abs(r(nc + k)) <= tol * (abs(mass(k) * yp(nc + k)) + dtl(k) + abs(fq(k))))) &
          return
      end do
      ! ggl's velocity rows against the largest row's terms: a row whose own terms are all
      ! zero (a slider's, while the crank turns) still carries the roundoff of the assembly's
      ! velocity solve, which is that of the largest
      smax = 0.0_dp
      if (ctx%ggl) then
        do i = 1, m
          smax = max(smax, sum(abs(d(i, :) * y(nc + 1:2 * nc))) + abs(ctx%phit(i)))
        end do
      end if
      do i = 1, m
        if (ctx%ggl) then
          s = sum(abs(d(i, :) * y(1:nc)))
          if (.not. (abs(r(2 * nc + i)) <= max(tol * s, ASSEMBLED_PHI))) return
          if (.not. (abs(r(2 * nc + m + i)) <= tol * smax)) return
        else
          ! D a = gamma with a = M^-1 (f - D^T lam): a's roundoff is that of its terms, which
          ! may nearly cancel (a mechanism at rest under gravity)
          s = abs(ctx%gam(i))
          do k = 1, nc
            s = s + abs(d(i, k)) * (abs(a(k)) + winv(k) * (abs(fq(k)) + dtl(k)))
          end do
          if (.not. (abs(r(2 * nc + i)) <= tol * s)) return
        end if
      end do
      consistent = .true.
    end associate
  end function consistent

  !> F(t, Y, Y') of the form (module header) into r; ctx%phi, d, gam, phit and the model's
  !> work%fq are left at (t, q, v). stat: mbdk_model_assemble's.
  subroutine dae_residual(ctx, t, y, yp, r, stat)
    type(ida_context_t), intent(inout) :: ctx
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:), yp(:)
    real(dp), intent(out), contiguous :: r(:)
    integer, intent(out) :: stat
    integer(i8) :: visits(MBDK_JOINT_TYPES)
    integer :: nc, m, i, k, ol, om
    real(dp) :: s, vk

    if (ctx%spatial) then
      call spatial_residual(ctx, t, y, yp, r, stat)
      return
    end if
    nc = ctx%nc
    m = ctx%m
    ol = 2 * nc        ! lam(i) = y(ol + i)
    om = 2 * nc + m    ! mu(i) = y(om + i)
    call mbdk_model_assemble(ctx%model, t, y(1:nc), y(nc + 1:2 * nc), stat)
    if (stat /= MBDK_SUCCESS) return
    if (m > 0) then
      ! the joints were visited by the assembly: this pass for the dense D is not counted
      visits = ctx%model%work%visits(1:MBDK_JOINT_TYPES)
      call mbdk_model_constraints(ctx%model, t, y(1:nc), y(nc + 1:2 * nc), ctx%phi, ctx%d, &
                                  ctx%gam, ctx%phit)
      ctx%model%work%visits(1:MBDK_JOINT_TYPES) = visits
    end if
    associate (d => ctx%d, mass => ctx%model%mass, fq => ctx%model%work%fq)
      ! column by column of D (its storage order): D^T lam, D^T mu, D v and D v' together
      if (ctx%ggl) then
        do i = 1, m
          r(ol + i) = ctx%phi(i)
          r(om + i) = ctx%phit(i)
        end do
      else
        do i = 1, m
          r(ol + i) = -ctx%gam(i)
        end do
      end if
      do k = 1, nc
        s = mass(k) * yp(nc + k) - fq(k)
        do i = 1, m
          s = s + d(i, k) * y(ol + i)
        end do
        r(nc + k) = s
        s = yp(k) - y(nc + k)
        if (ctx%ggl) then
          vk = y(nc + k)
          do i = 1, m
            s = s + d(i, k) * y(om + i)
            r(om + i) = r(om + i) + d(i, k) * vk
          end do
        else
          vk = yp(nc + k)
          do i = 1, m
            r(ol + i) = r(ol + i) + d(i, k) * vk
          end do
        end if
        r(k) = s
      end do
    end associate
  end subroutine dae_residual

  !> IDA's counters into st (see the module header).
  subroutine add_stats(mem, st)
    type(c_ptr), intent(in) :: mem
    type(mbdk_stats_t), intent(inout) :: st
    integer(c_long) :: c(1)
    integer(c_int) :: flag
    c = 0
    flag = FIDAGetNumSteps(mem, c)
    st%steps = st%steps + c(1)
    c = 0
    flag = FIDAGetNumResEvals(mem, c)
    st%nfev = st%nfev + c(1)
    c = 0
    flag = FIDAGetNumLinResEvals(mem, c)
    st%nfev = st%nfev + c(1)
    c = 0
    flag = FIDAGetNumJacEvals(mem, c)
    st%njev = st%njev + c(1)
    c = 0
    flag = FIDAGetNumLinSolvSetups(mem, c)
    st%nlu = st%nlu + c(1)
    c = 0
    flag = FIDAGetNumNonlinSolvIters(mem, c)
    st%newton_iterations = st%newton_iterations + c(1)
    c = 0
    flag = FIDAGetNumErrTestFails(mem, c)
    st%rejected_steps = st%rejected_steps + c(1)
    c = 0
    flag = FIDAGetNumNonlinSolvConvFails(mem, c)
    st%newton_failures = st%newton_failures + c(1)
  end subroutine add_stats

  !> The status of a failed IDA call (flag < 0); table in the module header. callback_stat: the
  !> failure a residual reported (it ended the solve, so it is the cause); soft_stat: a
  !> recoverable residual failure of the last step (non-finite).
  pure integer function ida_status(flag, callback_stat, soft_stat) result(stat)
    integer(c_int), intent(in) :: flag
    integer, intent(in) :: callback_stat, soft_stat
    if (callback_stat /= MBDK_SUCCESS) then
      stat = callback_stat
      return
    end if
    select case (flag)
    case (IDA_TOO_MUCH_WORK)
      stat = MBDK_ERR_TOO_MANY_STEPS
    case (IDA_TOO_MUCH_ACC)
      stat = MBDK_ERR_TOO_MUCH_ACCURACY
    case (IDA_ERR_FAIL)
      stat = MBDK_ERR_STEP_TOO_SMALL
    case (IDA_CONV_FAIL)
      stat = MBDK_ERR_NEWTON_DIVERGED
    case (IDA_LSETUP_FAIL, IDA_LSOLVE_FAIL)
      stat = MBDK_ERR_SINGULAR_MATRIX
    case (IDA_RES_FAIL, IDA_FIRST_RES_FAIL, IDA_REP_RES_ERR)
      stat = MBDK_ERR_CALLBACK_FAILED
      if (soft_stat /= MBDK_SUCCESS) stat = soft_stat
    case (IDA_MEM_FAIL)
      stat = MBDK_ERR_NO_MEMORY
    case (IDA_ILL_INPUT)
      stat = MBDK_ERR_INVALID_INPUT
    case default
      stat = MBDK_ERR_BACKEND
    end select
  end function ida_status

  !> IDAResFn: r = F(t, Y, Y') on the vectors' own storage. 0: done; 1: Y or r not finite (IDA
  !> cuts the step); -1: the model failed or the solve was interrupted (ctx%stat says which).
  !> The error weights of the ggl form (IDAWFtolerances): 1 / (rtol |y_i| + atol_i), atol from
  !> ctx%atol, whose multipliers' entries the loop raises as they grow (ggl_lam_atol). -1
  !> (IDA stops) where a weight would not be positive and finite.
  integer(c_int) function ida_ewt(nv_y, nv_ewt, user_data) bind(C, name='') result(ierr)
    type(N_Vector), target :: nv_y, nv_ewt
    type(c_ptr), value :: user_data
    type(ida_context_t), pointer :: ctx
    real(c_double), pointer, contiguous :: y(:), ewt(:)
    real(dp) :: tol
    integer :: i
    call c_f_pointer(user_data, ctx)
    call c_f_pointer(n_vgetarraypointer(c_loc(nv_y)), y, [ctx%n])
    call c_f_pointer(n_vgetarraypointer(c_loc(nv_ewt)), ewt, [ctx%n])
    ierr = -1
    do i = 1, ctx%n
      tol = ctx%rtol * abs(y(i)) + ctx%atol(i)
      if (.not. (tol > 0.0_dp .and. tol <= huge(1.0_dp))) return
      ewt(i) = 1.0_dp / tol
    end do
    ierr = 0
  end function ida_ewt

  integer(c_int) function ida_res(t, nv_y, nv_yp, nv_r, user_data) bind(C, name='') result(ierr)
    real(c_double), value :: t
    type(N_Vector), target :: nv_y, nv_yp, nv_r
    type(c_ptr), value :: user_data
    type(ida_context_t), pointer :: ctx
    real(c_double), pointer, contiguous :: y(:), yp(:), r(:)
    integer :: stat
    call c_f_pointer(user_data, ctx)
    ierr = -1
    ! sticky: no step may be accepted after a failure, wherever a -1 is passed on as
    ! recoverable (module header)
    if (ctx%stat /= MBDK_SUCCESS) return
    if (ctx%interrupt /= 0) then
      if (mbdk_interrupted(ctx%interrupt)) then
        ctx%stat = MBDK_ERR_INTERRUPTED
        return
      end if
    end if
    call c_f_pointer(n_vgetarraypointer(c_loc(nv_y)), y, [ctx%n])
    call c_f_pointer(n_vgetarraypointer(c_loc(nv_yp)), yp, [ctx%n])
    call c_f_pointer(n_vgetarraypointer(c_loc(nv_r)), r, [ctx%n])
    ! a diverging Newton iterate: recoverable, before the model calls it a failure
    if (.not. (all(abs(y) <= huge(1.0_dp)) .and. all(abs(yp) <= huge(1.0_dp)))) then
      ctx%soft_stat = MBDK_ERR_NONFINITE
      ierr = 1
      return
    end if
    call dae_residual(ctx, t, y, yp, r, stat)
    if (stat /= MBDK_SUCCESS) then
      ctx%stat = stat
      return
    end if
    ierr = 0
    if (.not. all(abs(r) <= huge(1.0_dp))) then
      ctx%soft_stat = MBDK_ERR_NONFINITE
      ierr = 1
    end if
  end function ida_res

  !> ggl's absolute tolerance of the multipliers lam (their values at the start, and again after
  !> a step where the largest has doubled): max(atol, max(rtol, LAM_RTOL_FLOOR) max |lam|). In
  !> the index-2 iteration the multipliers carry roundoff of the order of eps times the largest
  !> one times the iteration matrix's condition, which grows like 1/h^2; tested at atol alone,
  !> or at rtol near eps, that roundoff keeps Newton from converging (IDA_CONV_FAIL) on stiff
  !> scenes at tight tolerances, and whether it does then depends on where the steps fall.
  pure function ggl_lam_atol(opt, lam0) result(a)
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: lam0(:)
    real(dp) :: a
    a = max(opt%atol, max(opt%rtol, LAM_RTOL_FLOOR) * maxval(abs(lam0)))
  end function ggl_lam_atol

end module mbdk_ida
