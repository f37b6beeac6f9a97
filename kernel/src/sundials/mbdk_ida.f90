!> SUNDIALS IDA (6.x) through its Fortran 2003 interface, integrating a mechanism's equations
!> of motion (Fekete (2023) (2.54), in the velocity form of mbdk_mechanism: q' = T(q) v, T = I
!> for a planar scene)
!>   M v' + C^T lam = f(t, q, v),   Phi(q, t) = 0,   Phi' = C v + Phi_t,   C v' = gamma
!> as a differential-algebraic system F(t, Y, Y') = 0, not as the reduced ODE, in one of two
!> forms, index1 or ggl (ggl refuses knife edges, MBDK_ERR_NOT_APPLICABLE: they have no
!> position row for its mu to stabilise). Written once above the mechanism interface: planar
!> and spatial scenes take the same code.
!>
!> IDA solves F(t, Y, Y') = 0 with variable-order, variable-step BDF formulas (orders 1..5) in
!> fixed-leading-coefficient form (Brenan, Campbell and Petzold, Numerical Solution of IVPs in
!> DAEs, 1996, ch. 5; Hindmarsh et al., ACM TOMS 31 (2005) 363), Newton iteration on
!> dF/dY + cj dF/dY' from IDA's dense difference quotients (N residuals per Jacobian) on
!> SUNDIALS' dense matrix and dense LU (SUNMatrix_Dense, SUNLinSol_Dense); a large scene's are
!> sparse (below, "Large scenes"). An analytic Jacobian
!> (the mass matrix, C, the force elements' tangents and the joints' geometric stiffness, as
!> mbdk_index3_matrix builds them) is out of scope: it would save the N residuals per setup,
!> not change what is computed.
!>
!> The two forms (nq coordinates, nv velocities; the multipliers of the rows a the mechanism
!> solves, active_rows: all m rows, or the independent subset a redundant spatial scene keeps,
!> whose Phi = 0 implies the others: Bricard's linkage keeps 29 of its 30):
!>   index1 (ggl = .false.)  Y = [q; v; lam_a], N = nq + nv + na:
!>       r_q   = q' - T(q) v
!>       r_v   = M v' + C_a^T lam - f           (M diagonal: a planar scene, whose bodies
!>                                              without inertia leave a zero there)
!>             = v' - M^-1 (f - C_a^T lam)      (otherwise: a spatial body's inertia tensor)
!>       r_lam = C_a v' - gamma_a
!>     the acceleration-level constraint with the multipliers: an index-1 system. Phi and Phi'
!>     are not kept; they drift as in the reduced ODE (formulation 1 of mbdk_model), and the
!>     scene's watch ends the solve by name (MBDK_ERR_CONSTRAINT_DRIFT) where they leave its
!>     tolerances.
!>   ggl (ggl = .true.)      Y = [q; v; lam_a; mu_a], N = nq + nv + 2 na: the stabilised index-2
!>     form of Gear, Gupta and Leimkuhler (J. Comput. Appl. Math. 12 (1985) 77):
!>       r_q   = q' - T(q) (v - C_a^T mu)
!>       r_v   as index1
!>       r_lam = Phi_a(q, t)
!>       r_mu  = C_a v + Phi_t,a
!>     Phi and Phi' are solved for at every step, so the constraints do not drift and need no
!>     projection; they hold to the Newton tolerance of q and v at the steps (and to the local
!>     error at samples between steps, which come from the interpolant). Since dPhi/dq T = C,
!>     Phi' = C (v - C^T mu) + Phi_t: with both rows held, C C^T mu = 0, so mu = 0 in the exact
!>     solution (C_a has full rank) and only takes up the part of q' - T v the position
!>     constraint needs. The quaternions' norm is not projected (IDA's history forbids it); a
!>     rotation is read from p / |p|.
!> lam (and mu) are algebraic: IDASetId marks q and v differential (1) and lam, mu algebraic (0),
!> and IDASetSuppressAlg leaves the algebraic components out of the local error test, so the
!> error test sees positions and velocities only, as index-2 codes do (the local error of an
!> index-2 algebraic variable is an order lower than the formula's, and testing it would hold
!> h down; for index1 the multipliers follow from (q, v) and are left out the same way). The
!> local error of q and v is kept at WRMS <= 1 with the weights of mbdk_adaptive: rtol and the
!> scalar opt%atol.
!> The same weights serve IDA's Newton convergence test, which sees every component (the
!> weights are ida_ewt's, IDAWFtolerances): lam with rtol and an absolute tolerance of
!> max(atol, max(rtol, LAM_RTOL_FLOOR) times the largest multiplier so far), so that the
!> sampled multipliers are converged to the roundoff the iteration leaves in them and no
!> further (lam_atol: tested at atol alone the flyball governor's index1 run at rtol 1e-11
!> passed or stalled at steps of 1e-9 s depending on the last bits of its tolerances), but mu
!> with the absolute tolerance MU_ATOL = 1, which takes it out of the test. mu is zero in the
!> exact solution and has no meaning of its own; its Newton updates carry the roundoff of the
!> index-2 iteration matrix, whose condition grows like 1/h^2, so tested at opt%atol they stop
!> converging at small steps (IDA's own first step, 0.5 / |Y'(0)| in the error weights, is
!> tiny for a mechanism released at rest) and the solve ends with IDA_CONV_FAIL. The same
!> tolerance is mu's difference-quotient increment: F is linear in mu, so an increment of 1
!> gives its Jacobian column to roundoff.
!>
!> Initial values. The caller passes a consistent [q0; v0] (assembled: Phi = 0, C v + Phi_t = 0)
!> and a mechanism built with the reduced formulation (another formulation:
!> MBDK_ERR_NOT_APPLICABLE: they are the ODE's ways of keeping the constraints, and the forms
!> here replace them; a scene with effect states, wear, likewise). The mechanism's
!> accelerations give a0 and lam0, and
!>   Y(0) = [q0; v0; lam0_a (; 0)],   Y'(0) = [T(q0) v0; a0; 0 (; 0)].
!> That is a consistent pair, so IDACalcIC is not needed: r_q = 0 exactly, r_v and (index1)
!> r_lam are the constrained solve's own residuals, and (ggl) r_lam, r_mu are the assembled
!> residuals; lam and mu appear in F undifferentiated, so lam' = mu' = 0 only seeds the first
!> predictor and is otherwise irrelevant. IDACalcIC would solve the same linear equations
!> again with a Newton stopping test on top. The residual at (Y(0), Y'(0)) is checked row by
!> row against the roundoff of the row's terms (CONSISTENT_ULPS units of eps times the sum of
!> their magnitudes, or of the largest row's where M^-1 or the assembly mixes rows; the
!> position rows Phi against ASSEMBLED_PHI, the tolerance an assembly reaches, or the roundoff
!> of the positions): a larger one is MBDK_ERR_INCONSISTENT_INITIAL. index1 checks
!> only its own residual, so it does not require Phi(q0) = 0 (nor does the reduced ODE).
!> lam0 is written to lam_out(:, 1).
!>
!> Options read: rtol, atol, h (> 0: the first step, IDASetInitStep; 0: IDA's estimate),
!> h_min and h_max (> 0: IDA's bounds, IDASetMinStep and IDASetMaxStep), max_order (0: 5;
!> above 5: MBDK_ERR_INVALID_INPUT), max_steps, interrupt. The caller has checked the
!> tolerances and step options (mbdk_adaptive_check) and, for a watching mechanism, started the
!> watch at t0 (its watch_start). ggl's first step, where the caller gives none: IDA's own
!> estimate (0.5 / |Y'(0)| in the error weights, at most a thousandth of the interval), but not
!> below GGL_FIRST_STEP of the interval: the index-2 Newton matrix's condition grows like
!> 1/h^2, and a fast start (a spinning body) at a tight rtol makes the estimate so small that
!> the matrix is singular to roundoff.
!>
!> The loop is mbdk_sundials_loop's, which this module drives through its hooks (ida_loop_t):
!> IDA takes one internal step per call (IDA_ONE_STEP) and never passes t_end
!> (IDASetStopTime); after each step the samples in it come from IDA's interpolant (IDAGetDky:
!> [q; v] into y_out, lam into lam_out), the sample at t_end is the last step's own state, Y is
!> checked (finite: else MBDK_ERR_NONFINITE) and the scene's watch runs (force = a sample fell
!> in the step) with the step's own multipliers for the drivers' power: no evaluation of IDA's
!> leaves the model's multipliers current (a watch that integrates a work gets the
!> interpolant at the step's Gauss nodes first, watch_nodes_lam). The step's order is counted.
!> max_steps bounds the accepted steps plus the steps retried after an error-test or a
!> convergence failure (IDAGetNumErrTestFails + IDAGetNumStepSolveFails), counted there (IDA's
!> own limit is off): MBDK_ERR_TOO_MANY_STEPS. A step below mbdk_adaptive_h_floor
!> (opt%h_min, and 10 ulps of t) is MBDK_ERR_STEP_TOO_SMALL, except the last one, which IDA
!> shortens to land on t_end. The interrupt flag is polled before each step and in every
!> residual, so a long Jacobian of a large model ends within one evaluation.
!>
!> Residual callback. One evaluation of the mechanism (evaluate: f, Phi, the dense C, gamma,
!> Phi_t into buffers of the context, allocated once per solve; each element counted once; on
!> the sparse path the index-3 evaluation and C's compact products),
!> its rates T(q) v and, for a non-diagonal M, one product with M^-1.
!> A mechanism's failure (evaluate's stat) or the interrupt is stored and returned as
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
!> A solve that ends with MBDK_ERR_STEP_TOO_SMALL, MBDK_ERR_NEWTON_DIVERGED or
!> MBDK_ERR_TOO_MUCH_ACCURACY after its first step, its last accepted state next to a singular
!> pose, ends with MBDK_ERR_SINGULAR_MATRIX instead (singular_stop).
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
!> Large scenes. Where the model keeps its constraint rows compact (mbdk_mechanism's
!> compact_rows: its solves are sparse), no knife edge, and the mechanism has an index-3 object
!> for the scene (a planar one with contacts has none), nothing is dense: the residual comes
!> from the index-3 procedures (f, Phi, gamma, Phi_t and the products C x, C^T x from the
!> compact rows: compact_residual), the Newton matrix dF/dY + cj dF/dY' is a SUNDIALS CSC
!> matrix in the pattern of mbdk_dae_pattern ([K D^T; D 0] over the bodies' unknowns and the
!> rows' multipliers, mbdk_kkt_pattern_csc) factorised by SUNDIALS' KLU (sparse LU; KLU
!> pivots at its first factorisation, preferring the diagonal, and refactors in that order),
!> and its values come from ida_jac: IDA's difference quotients (its increment rule), but
!> colored: the k-th unknown of every body of a distance-2 color, or the multipliers of a
!> color of rows, perturbed together (a chain's matrix costs 22 to 51 residuals at every
!> length, against one per unknown). The consistency check takes |C| |x|
!> from the compact rows too. stats: nlu_sparse = nlu; nfev includes ida_jac's residuals.
!>
!> Out of scope: an analytic Jacobian (above), IDACalcIC (above), per-component tolerances,
!> root finding. SUNDIALS writes its error messages to stderr by default;
!> IDASetErrFile(NULL) silences them, as the kernel never prints. All SUNDIALS objects are freed
!> on every path.
module mbdk_ida
  use, intrinsic :: iso_c_binding, only: c_ptr, c_null_ptr, c_loc, c_funloc, c_f_pointer, &
    c_associated, c_int, c_long, c_int64_t, c_double, c_intptr_t
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_interrupt, only: mbdk_interrupted
  use mbdk_sundials_loop, only: mbdk_sundials_loop_t, mbdk_sundials_run
  use mbdk_mechanism, only: mbdk_mechanism_t, mbdk_i3_aux_t, mbdk_i3_eval_t, MBDK_FORM_REDUCED
  use mbdk_dae_pattern, only: mbdk_dae_pattern_t, mbdk_dae_pattern_init
  use mbdk_kkt_pattern, only: mbdk_kkt_pattern_csc
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
    FIDAWFtolerances, FIDASetJacFn, FIDAGetCurrentStep
  implicit none
  private
  public :: mbdk_ida_solve

  integer, parameter :: IDA_MAX_ORDER = 5
  !> a consistent initial residual row is within this many eps of the sum of its terms' sizes:
  !> the roundoff of a constrained solve's residual, with room for a row's few terms and the
  !> conditioning of D M^-1 D^T
  real(dp), parameter :: CONSISTENT_ULPS = 1.0e3_dp
  !> |Phi| an assembled state may keep: the assembly's tolerance (mbdk_model_start, and a
  !> spatial scene's projection)
  real(dp), parameter :: ASSEMBLED_PHI = 1.0e-12_dp
  !> ggl: mu's absolute tolerance, which leaves it out of the Newton test (module header)
  real(dp), parameter :: MU_ATOL = 1.0_dp
  !> the multipliers' Newton test, relative to the largest multiplier, is not tighter than this
  !> (lam_atol; Python's GGL_LAMBDA_RTOL)
  real(dp), parameter :: LAM_RTOL_FLOOR = 1.0e-8_dp
  !> index1: the points of an accepted step where a singular pose is looked for
  !> (singular_pose): their spacing, a quarter of the step, lands within the reduced solve's
  !> pivot threshold of the flat poses A02's steps stride over at rtol 1e-4 .. 1e-8 (each
  !> probe is one evaluation of the reduced ODE: about a quarter more CPU on a regular scene)
  integer, parameter :: SINGULAR_PROBES = 4
  !> ggl: the least first step, as a fraction of the interval (the module header)
  real(dp), parameter :: GGL_FIRST_STEP = 1.0e-6_dp
  !> SUNDIALS' CSC_MAT (sunmatrix_sparse.h)
  integer(c_int), parameter :: CSC_MAT = 0_c_int

  ! SUNDIALS' own accessor, called directly (as in mbdk_cvode): the interface's
  ! FN_VGetArrayPointer asks for the length through a second wrapper on every call.
  interface
    ! the sparse matrix and SUNDIALS' KLU solver, by their C entry points (no Fortran module
    ! of theirs is needed for these few calls)
    type(c_ptr) function sun_sparse_matrix(m, n, nnz, sparsetype, sunctx) &
        bind(C, name='SUNSparseMatrix')
      import :: c_ptr, c_int64_t, c_int
      integer(c_int64_t), value :: m, n, nnz
      integer(c_int), value :: sparsetype
      type(c_ptr), value :: sunctx
    end function sun_sparse_matrix
    type(c_ptr) function sun_sparse_data(a) bind(C, name='SUNSparseMatrix_Data')
      import :: c_ptr
      type(c_ptr), value :: a
    end function sun_sparse_data
    type(c_ptr) function sun_sparse_indexvalues(a) bind(C, name='SUNSparseMatrix_IndexValues')
      import :: c_ptr
      type(c_ptr), value :: a
    end function sun_sparse_indexvalues
    type(c_ptr) function sun_sparse_indexpointers(a) bind(C, name='SUNSparseMatrix_IndexPointers')
      import :: c_ptr
      type(c_ptr), value :: a
    end function sun_sparse_indexpointers
    type(c_ptr) function sun_linsol_klu(y, a, sunctx) bind(C, name='SUNLinSol_KLU')
      import :: c_ptr
      type(c_ptr), value :: y, a, sunctx
    end function sun_linsol_klu
    type(c_ptr) function n_vgetarraypointer(v) bind(C, name='N_VGetArrayPointer')
      import :: c_ptr
      type(c_ptr), value :: v
    end function n_vgetarraypointer
  end interface

  !> What the residual reaches through IDA's user data: one per solve, on the solver's stack,
  !> with the evaluation's buffers so that an evaluation allocates nothing.
  type :: ida_context_t
    class(mbdk_mechanism_t), pointer :: mech => null()
    !> Y = [q (nq); v (nv); lam (nl); (ggl) mu (nl)], ny = nq + nv, nl = size(rows) <= m
    integer :: nq = 0, nv = 0, ny = 0, m = 0, nl = 0, n = 0
    integer, allocatable :: rows(:)
    !> the first step where the caller gave none (0: IDA's own estimate)
    real(dp) :: h0 = 0.0_dp
    logical :: ggl = .false.
    !> the largest multiplier its tolerance was set from (lam_atol), and the error
    !> weights' tolerances, which ida_ewt reads (IDA's own IDASVtolerances cannot be called
    !> again once the solve has started: IDA 6.4 leaves its weight function without its data)
    real(dp) :: lam_scale = 0.0_dp, rtol = 0.0_dp
    real(dp), pointer, contiguous :: atol(:) => null()
    !> a residual's failure status that made it return -1 (IDA then stops)
    integer :: stat = MBDK_SUCCESS
    !> MBDK_ERR_NONFINITE when a residual was not finite in the current step (recoverable)
    integer :: soft_stat = MBDK_SUCCESS
    integer(c_intptr_t) :: interrupt = 0
    !> one evaluation: f, Phi, C, gamma, Phi_t; lam and mu on every row; g = f - C^T lam,
    !> x = v - C^T mu (ggl), M^-1 g (a non-diagonal M), the rates; M's diagonal (diag_mass)
    real(dp), allocatable :: f(:), phi(:), c(:, :), gam(:), phit(:), lamfull(:), mufull(:), &
      g(:), x(:), ming(:), qd(:), dm(:)
    !> index1: the reduced ODE's y' at a probe of singular_pose
    real(dp), allocatable :: ydot(:)
    !> the sparse path (module header): the index-3 object and point, the DAE's pattern and
    !> the CSC of [K D^T; D 0] (1-based), the difference quotients' residuals, perturbed
    !> state and increments, C x, the residual evaluations of the Jacobians, IDA's memory
    logical :: sparse = .false.
    class(mbdk_i3_aux_t), allocatable :: aux
    type(mbdk_i3_eval_t) :: e
    type(mbdk_dae_pattern_t) :: pat
    integer, allocatable :: ap(:), ai(:)
    real(dp), allocatable :: r1(:), yw(:), ypw(:), del(:), cv(:), tv(:)
    integer(i8) :: jac_nfev = 0
    type(c_ptr) :: mem = c_null_ptr
  end type ida_context_t

  !> One IDA solve: its SUNDIALS objects (each handle empty until made, so that ida_run frees
  !> what exists on any path) and the hooks of mbdk_sundials_loop's one-step loop.
  type, extends(mbdk_sundials_loop_t) :: ida_loop_t
    type(c_ptr) :: sunctx = c_null_ptr, mem = c_null_ptr
    type(N_Vector), pointer :: nv_y => null(), nv_yp => null(), nv_dky => null(), &
      nv_id => null()
    type(SUNMatrix), pointer :: amat => null()
    type(SUNLinearSolver), pointer :: ls => null()
    type(ida_context_t), pointer :: ctx => null()
    !> the solve's options (the multipliers' tolerance, lam_atol)
    type(mbdk_options_t) :: opt
    !> the multipliers at the samples (mbdk_ida_solve's lam_out)
    real(dp), pointer :: lam_out(:, :) => null()
    !> the interpolant's [q; v] and multipliers at the Gauss nodes of a step, for the watch
    real(dp), allocatable :: yn(:, :), lamn(:, :)
  contains
    procedure :: step => ida_step
    procedure :: tries => ida_tries
    procedure :: last_step => ida_last_step
    procedure :: dky => ida_dky
    procedure :: write_extra => ida_write_extra
    procedure :: wants_nodes => ida_wants_nodes
    procedure :: keep_node => ida_keep_node
    procedure :: watch_nodes => ida_watch_nodes
    procedure :: accept => ida_accept
  end type ida_loop_t

contains

  !> See the module header. ggl: the stabilised index-2 form, else index1. y0 = [q0; v0];
  !> t_out: the sample times (t_out(1) = t0, written by the caller with nwritten = 1, the last
  !> t_end); y_out(nq + nv, >= size(t_out)) receives [q; v] at samples 2, 3, ...; lam_out(>= m,
  !> :) the multipliers at the samples its columns reach (column 1: lam0; zero on the rows a
  !> redundant scene leaves out; no columns: none).
  subroutine mbdk_ida_solve(mech, opt, ggl, t0, y0, t_out, y_out, lam_out, nwritten, st, stat)
    class(mbdk_mechanism_t), intent(in), target :: mech
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
    real(dp), allocatable :: r0(:), lam0(:)
    integer :: nq, nv, ny, m, nl, n, ns, ierr, nlam, mc
    real(dp) :: t_end, s
    logical :: want_sparse

    nq = mech%ncoord
    nv = mech%nvel
    ny = nq + nv
    m = mech%m
    ns = size(t_out)
    nlam = size(lam_out, 2)
    stat = MBDK_ERR_NOT_APPLICABLE
    if (mech%formulation /= MBDK_FORM_REDUCED .or. mech%ns > 0) return
    ! GGL's mu stabilises position rows; a knife edge has none (index1 keeps it: C a = gamma)
    if (ggl .and. mech%has_pfaffian) return
    stat = MBDK_ERR_INVALID_INPUT
    if (nq < 1 .or. size(y0) /= ny .or. ns < 2) return
    t_end = t_out(ns)
    if (.not. (t_end > t0)) return
    if (opt%max_order < 0 .or. opt%max_order > IDA_MAX_ORDER) return
    stat = MBDK_ERR_OUTPUT_SIZE
    if (size(y_out, 1) /= ny .or. size(y_out, 2) < ns) return
    if (nlam > 0 .and. size(lam_out, 1) < m) return

    ! a scene whose rows the model keeps compact: no dense C (the sparse path, module header;
    ! the dense one where the mechanism has no index-3 object for it)
    want_sparse = mech%compact_rows .and. m > 0 .and. .not. mech%has_pfaffian
    mc = merge(0, m, want_sparse)
    stat = MBDK_ERR_NO_MEMORY
    allocate (ctx%f(nv), ctx%phi(m), ctx%c(mc, merge(0, nv, want_sparse)), ctx%gam(m), &
              ctx%phit(m), ctx%lamfull(m), ctx%mufull(m), ctx%g(nv), ctx%x(nv), ctx%ming(nv), &
              ctx%qd(nq), ctx%dm(nv), lam0(m), ctx%ydot(nq + nv), stat=ierr)
    call mbdk_alloc_status(ierr, MBDK_REAL_BYTES * (real(mc, dp) * nv + 6.0_dp * m + &
                           7.0_dp * nv + 2.0_dp * nq), stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    ctx%mech => mech
    ctx%nq = nq
    ctx%nv = nv
    ctx%ny = ny
    ctx%m = m
    ctx%ggl = ggl
    ctx%interrupt = opt%interrupt
    if (mech%diag_mass) call mech%mass_diagonal(ctx%dm)

    ! consistent initial values (module header): a0 and lam0 from the mechanism's solve, which
    ! may move a redundant scene to another set of rows: the rows are asked for after it
    allocate (yp(ny), stat=ierr)
    call mbdk_alloc_status(ierr, MBDK_REAL_BYTES * ny, stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    call mech%accelerations(t0, y0(1:nq), y0(nq + 1:ny), yp(nq + 1:ny), lam0, stat)
    if (stat /= MBDK_SUCCESS) return
    call mech%rates(y0(1:nq), y0(nq + 1:ny), yp(1:nq), stat)
    if (stat /= MBDK_SUCCESS) return
    call mech%active_rows(ctx%rows, stat)
    if (stat /= MBDK_SUCCESS) return
    nl = size(ctx%rows)
    n = ny + nl
    if (ggl) n = n + nl
    ctx%nl = nl
    ctx%n = n
    if (want_sparse) then
      call sparse_setup(ctx, stat, st%alloc_bytes)
      if (stat == MBDK_ERR_NOT_APPLICABLE) then
        deallocate (ctx%c)
        allocate (ctx%c(m, nv), stat=ierr)
        call mbdk_alloc_status(ierr, MBDK_REAL_BYTES * real(m, dp) * nv, stat, st%alloc_bytes)
      end if
      if (stat /= MBDK_SUCCESS) return
    end if
    yp = [yp, spread(0.0_dp, 1, n - ny)]
    stat = MBDK_ERR_NO_MEMORY
    allocate (y(n), ydky(n), id(n), atol_v(n), r0(n), stat=ierr)
    call mbdk_alloc_status(ierr, MBDK_REAL_BYTES * 5.0_dp * n, stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    y(1:ny) = y0
    y(ny + 1:) = 0.0_dp
    y(ny + 1:ny + nl) = lam0(ctx%rows)
    call dae_residual(ctx, t0, y, yp, r0, stat)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INCONSISTENT_INITIAL
    if (.not. consistent(ctx, y, yp, r0)) return
    if (nlam >= 1) call put_lam(ctx, y(ny + 1:ny + nl), lam_out(:, 1))
    id(1:ny) = 1.0_dp
    id(ny + 1:) = 0.0_dp
    atol_v(1:ny + nl) = opt%atol
    atol_v(ny + nl + 1:) = MU_ATOL
    if (nl > 0) then
      atol_v(ny + 1:ny + nl) = lam_atol(opt, y(ny + 1:ny + nl))
      ctx%lam_scale = maxval(abs(y(ny + 1:ny + nl)))
    end if
    if (ggl) then
      ! IDA's own first step unless it falls below GGL_FIRST_STEP of the interval (header)
      s = sqrt(sum((yp(1:ny) / (opt%rtol * abs(y0) + opt%atol))**2) / ny)
      if (s > 0.0_dp) then
        if (0.5_dp / s < GGL_FIRST_STEP * (t_end - t0)) ctx%h0 = GGL_FIRST_STEP * (t_end - t0)
      end if
    end if
    call ida_run(ctx, opt, t0, t_end, y, yp, ydky, id, atol_v, t_out, y_out, lam_out, nwritten, &
                 st, stat)
  end subroutine mbdk_ida_solve


  !> The sparse path's objects (module header): the index-3 object (MBDK_ERR_NOT_APPLICABLE
  !> where the mechanism has none for the scene), the point, the pattern and its CSC, and the
  !> difference quotients' vectors.
  subroutine sparse_setup(ctx, stat, asked)
    type(ida_context_t), intent(inout) :: ctx
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer, allocatable :: kpos(:), dpos_r(:), dpos_c(:)
    integer :: m, nv, n, astat
    associate (mech => ctx%mech)
      call mech%i3_create(ctx%aux, .false., stat, asked)
      if (stat /= MBDK_SUCCESS) return
      call mbdk_dae_pattern_init(ctx%pat, mech, ctx%rows, merge(2, 1, ctx%ggl), stat, asked)
      if (stat /= MBDK_SUCCESS) return
      call mbdk_kkt_pattern_csc(ctx%pat%kap, ctx%pat%kai, ctx%pat%drptr, ctx%pat%drcol, &
                                ctx%ap, ctx%ai, kpos, dpos_r, dpos_c, stat, asked)
      if (stat /= MBDK_SUCCESS) return
      m = ctx%m
      nv = ctx%nv
      n = ctx%n
      allocate (ctx%e%q(ctx%nq), ctx%e%v(nv), ctx%e%f(nv), ctx%e%phi(m), ctx%e%gam(m), &
                ctx%e%phit(m), ctx%e%lt(m), ctx%e%dd(nv), ctx%e%r(nv + m), ctx%r1(n), &
                ctx%yw(n), ctx%ypw(n), ctx%del(n), ctx%cv(m), ctx%tv(nv), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (real(ctx%nq, dp) + 5.0_dp * nv + &
                             6.0_dp * m + 4.0_dp * n), stat, asked)
      if (astat /= 0) return
      ctx%e%lt = 0.0_dp
      ctx%e%dd = 0.0_dp
      ctx%sparse = .true.
    end associate
  end subroutine sparse_setup

  !> The SUNDIALS part of a solve (the module header): IDA from the consistent (y, yp) of the
  !> context's form to t_out's last time, samples and multipliers out.
  subroutine ida_run(ctx, opt, t0, t_end, y, yp, ydky, id, atol_v, t_out, y_out, lam_out, &
                     nwritten, st, stat)
    type(ida_context_t), intent(inout), target :: ctx
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_end
    real(dp), intent(inout), target, contiguous :: y(:), yp(:), ydky(:), id(:), atol_v(:)
    real(dp), intent(in) :: t_out(:)
    real(dp), intent(inout) :: y_out(:, :)
    real(dp), intent(inout), target :: lam_out(:, :)
    integer, intent(inout) :: nwritten
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    type(ida_loop_t) :: lp
    integer :: ierr
    lp%ctx => ctx
    lp%y => y
    lp%ydky => ydky
    lp%lam_out => lam_out
    lp%landing_floor = .false.    ! IDA shortens its last step to land on t_end
    lp%opt = opt
    call ida_create(lp, opt, t0, t_end, y, yp, ydky, id, atol_v, st, stat)
    if (stat == MBDK_SUCCESS) then
      st%t_reached = t0
      allocate (lp%yn(ctx%ny, 3), lp%lamn(ctx%m, 3), stat=ierr)
      call mbdk_alloc_status(ierr, MBDK_REAL_BYTES * 3.0_dp * (ctx%ny + ctx%m), stat, &
                             st%alloc_bytes)
    end if
    if (stat == MBDK_SUCCESS) call mbdk_sundials_run(lp, opt, t0, t_out, y_out, nwritten, st, stat)
    if (stat == MBDK_ERR_STEP_TOO_SMALL .or. stat == MBDK_ERR_NEWTON_DIVERGED .or. &
        stat == MBDK_ERR_TOO_MUCH_ACCURACY) call singular_stop(lp, st%t_reached, t0, stat)
    if (c_associated(lp%mem)) call add_stats(lp%mem, st, ctx)
    call FIDAFree(lp%mem)   ! NULL-safe; also frees IDA's copy of id
    if (associated(lp%ls)) ierr = FSUNLinSolFree(lp%ls)
    if (associated(lp%amat)) call FSUNMatDestroy(lp%amat)
    if (associated(lp%nv_id)) call FN_VDestroy(lp%nv_id)
    if (associated(lp%nv_dky)) call FN_VDestroy(lp%nv_dky)
    if (associated(lp%nv_yp)) call FN_VDestroy(lp%nv_yp)
    if (associated(lp%nv_y)) call FN_VDestroy(lp%nv_y)
    if (c_associated(lp%sunctx)) ierr = FSUNContext_Free(lp%sunctx)
  end subroutine ida_run

  !> IDA's context, vectors (on y, yp, ydky and id, which outlive the solve), memory and dense
  !> linear solver, initialised at (t0, y, yp) with the weights of ida_ewt on atol_v, the
  !> options of the module header and the stop time t_end.
  subroutine ida_create(lp, opt, t0, t_end, y, yp, ydky, id, atol_v, st, stat)
    type(ida_loop_t), intent(inout) :: lp
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_end
    real(dp), intent(inout), target, contiguous :: y(:), yp(:), ydky(:), id(:), atol_v(:)
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    integer(c_int) :: flag
    integer(c_int64_t) :: n
    n = int(lp%ctx%n, c_int64_t)
    stat = MBDK_ERR_BACKEND
    if (FSUNContext_Create(c_null_ptr, lp%sunctx) /= 0) return
    stat = MBDK_ERR_NO_MEMORY
    lp%nv_y => FN_VMake_Serial(n, y, lp%sunctx)
    if (.not. associated(lp%nv_y)) return
    lp%nv_yp => FN_VMake_Serial(n, yp, lp%sunctx)
    if (.not. associated(lp%nv_yp)) return
    lp%nv_dky => FN_VMake_Serial(n, ydky, lp%sunctx)
    if (.not. associated(lp%nv_dky)) return
    lp%nv_id => FN_VMake_Serial(n, id, lp%sunctx)
    if (.not. associated(lp%nv_id)) return
    lp%mem = FIDACreate(lp%sunctx)
    if (.not. c_associated(lp%mem)) return
    ! before anything else can fail: the kernel never prints
    stat = MBDK_ERR_BACKEND
    if (FIDASetErrFile(lp%mem, c_null_ptr) /= 0) return

    flag = FIDAInit(lp%mem, c_funloc(ida_res), t0, lp%nv_y, lp%nv_yp)
    if (flag == 0) then
      lp%ctx%rtol = opt%rtol
      lp%ctx%atol => atol_v
      flag = FIDAWFtolerances(lp%mem, c_funloc(ida_ewt))
    end if
    if (flag == 0) flag = FIDASetUserData(lp%mem, c_loc(lp%ctx))
    ! the error test sees q and v only (module header); IDA copies id
    if (flag == 0) flag = FIDASetId(lp%mem, lp%nv_id)
    if (flag == 0) flag = FIDASetSuppressAlg(lp%mem, 1_c_int)
    ! the step count is ours (max_steps counts failures too); IDA's per-call limit is off
    if (flag == 0) flag = FIDASetMaxNumSteps(lp%mem, -1_c_long)
    if (flag == 0) flag = FIDASetStopTime(lp%mem, t_end)
    if (flag == 0 .and. opt%max_order > 0) &
      flag = FIDASetMaxOrd(lp%mem, int(opt%max_order, c_int))
    if (flag == 0 .and. opt%h > 0.0_dp) then
      flag = FIDASetInitStep(lp%mem, opt%h)
    else if (flag == 0 .and. lp%ctx%h0 > 0.0_dp) then
      flag = FIDASetInitStep(lp%mem, lp%ctx%h0)
    end if
    if (flag == 0 .and. opt%h_min > 0.0_dp) flag = FIDASetMinStep(lp%mem, opt%h_min)
    if (flag == 0 .and. opt%h_max > 0.0_dp) flag = FIDASetMaxStep(lp%mem, opt%h_max)
    if (flag /= 0) then
      stat = ida_status(flag, lp%ctx%stat, lp%ctx%soft_stat)
      return
    end if

    stat = MBDK_ERR_NO_MEMORY
    if (lp%ctx%sparse) then
      call sparse_solver(lp, st, stat)
      return
    end if
    lp%amat => FSUNDenseMatrix(n, n, lp%sunctx)
    if (.not. associated(lp%amat)) then   ! (the size SUNDIALS asked for: n x n doubles)
      st%alloc_bytes = MBDK_REAL_BYTES * real(n, dp)**2
      return
    end if
    lp%ls => FSUNLinSol_Dense(lp%nv_y, lp%amat, lp%sunctx)
    if (.not. associated(lp%ls)) return
    ! no Jacobian function: IDA's dense difference quotients
    stat = MBDK_ERR_BACKEND
    if (FIDASetLinearSolver(lp%mem, lp%ls, lp%amat) /= 0) return
    stat = MBDK_SUCCESS
  end subroutine ida_create

  !> The sparse path's linear solver (module header): a CSC matrix of the pattern's size,
  !> SUNDIALS' KLU on it, and ida_jac as IDA's Jacobian.
  subroutine sparse_solver(lp, st, stat)
    type(ida_loop_t), intent(inout) :: lp
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    type(c_ptr) :: a, ls
    integer(c_int64_t) :: n, nnz
    n = int(lp%ctx%n, c_int64_t)
    nnz = int(lp%ctx%ap(lp%ctx%n + 1) - 1, c_int64_t)
    stat = MBDK_ERR_NO_MEMORY
    a = sun_sparse_matrix(n, n, nnz, CSC_MAT, lp%sunctx)
    if (.not. c_associated(a)) then   ! (what SUNDIALS asked for: the values and the indices)
      st%alloc_bytes = (MBDK_REAL_BYTES + 8.0_dp) * real(nnz, dp) + 8.0_dp * real(n + 1, dp)
      return
    end if
    call c_f_pointer(a, lp%amat)
    call put_pattern(lp%ctx, a)
    ls = sun_linsol_klu(c_loc(lp%nv_y), a, lp%sunctx)
    if (.not. c_associated(ls)) return
    call c_f_pointer(ls, lp%ls)
    stat = MBDK_ERR_BACKEND
    if (FIDASetLinearSolver(lp%mem, lp%ls, lp%amat) /= 0) return
    if (FIDASetJacFn(lp%mem, c_funloc(ida_jac)) /= 0) return
    lp%ctx%mem = lp%mem
    stat = MBDK_SUCCESS
  end subroutine sparse_solver

  !> The CSC pattern (ctx%ap, ai) into the sparse matrix a, 0-based (SUNMatZero_Sparse clears
  !> it with the values: written again before every Jacobian)
  subroutine put_pattern(ctx, a)
    type(ida_context_t), intent(in) :: ctx
    type(c_ptr), intent(in) :: a
    integer(c_int64_t), pointer :: iptr(:), ival(:)
    integer :: nnz
    nnz = ctx%ap(ctx%n + 1) - 1
    call c_f_pointer(sun_sparse_indexpointers(a), iptr, [ctx%n + 1])
    call c_f_pointer(sun_sparse_indexvalues(a), ival, [nnz])
    iptr = int(ctx%ap(1:ctx%n + 1) - 1, c_int64_t)
    ival = int(ctx%ai(1:nnz) - 1, c_int64_t)
  end subroutine put_pattern

  !> One internal step (IDA_ONE_STEP) towards t_stop; a residual's failure comes first.
  subroutine ida_step(self, t_stop, t, stat)
    class(ida_loop_t), intent(inout) :: self
    real(dp), intent(in) :: t_stop
    real(dp), intent(out) :: t
    integer, intent(out) :: stat
    real(c_double) :: tret(1)
    integer(c_int) :: flag
    self%ctx%soft_stat = MBDK_SUCCESS
    flag = FIDASolve(self%mem, t_stop, tret, self%nv_y, self%nv_yp, IDA_ONE_STEP)
    t = tret(1)
    if (flag < 0) then
      stat = ida_status(flag, self%ctx%stat, self%ctx%soft_stat)
      return
    end if
    stat = self%ctx%stat
  end subroutine ida_step

  !> Steps plus steps retried after an error-test or convergence failure (the module header).
  integer(i8) function ida_tries(self) result(tries)
    class(ida_loop_t), intent(inout) :: self
    integer(c_long) :: nst(1), netf(1), ncfn(1)
    integer(c_int) :: flag
    flag = FIDAGetNumSteps(self%mem, nst)
    flag = FIDAGetNumErrTestFails(self%mem, netf)
    flag = FIDAGetNumStepSolveFails(self%mem, ncfn)
    tries = int(nst(1), i8) + int(netf(1), i8) + int(ncfn(1), i8)
  end function ida_tries

  subroutine ida_last_step(self, h, q)
    class(ida_loop_t), intent(inout) :: self
    real(dp), intent(out) :: h
    integer, intent(out) :: q
    real(c_double) :: hlast(1)
    integer(c_int) :: flag, qlast(1)
    flag = FIDAGetLastStep(self%mem, hlast)
    flag = FIDAGetLastOrder(self%mem, qlast)
    h = hlast(1)
    q = int(qlast(1))
  end subroutine ida_last_step

  subroutine ida_dky(self, t, stat)
    class(ida_loop_t), intent(inout) :: self
    real(dp), intent(in) :: t
    integer, intent(out) :: stat
    stat = MBDK_SUCCESS
    if (FIDAGetDky(self%mem, t, 0_c_int, self%nv_dky) /= 0) stat = MBDK_ERR_BACKEND
  end subroutine ida_dky

  !> A sample's multipliers (its [q; v] the loop has written): src's lam into lam_out(:, k),
  !> where lam_out has that column.
  subroutine ida_write_extra(self, k, src)
    class(ida_loop_t), intent(inout) :: self
    integer, intent(in) :: k
    real(dp), intent(in) :: src(:)
    if (size(self%lam_out, 2) >= k) &
      call put_lam(self%ctx, src(self%ctx%ny + 1:self%ctx%ny + self%ctx%nl), self%lam_out(:, k))
  end subroutine ida_write_extra

  logical function ida_wants_nodes(self) result(wants)
    class(ida_loop_t), intent(inout) :: self
    wants = self%ctx%mech%watch_wants_nodes()
  end function ida_wants_nodes

  subroutine ida_keep_node(self, i)
    class(ida_loop_t), intent(inout) :: self
    integer, intent(in) :: i
    associate (ny => self%ctx%ny, nl => self%ctx%nl)
      self%yn(:, i) = self%ydky(1:ny)
      call put_lam(self%ctx, self%ydky(ny + 1:ny + nl), self%lamn(:, i))
    end associate
  end subroutine ida_keep_node

  subroutine ida_watch_nodes(self, t_a, t_b, stat)
    class(ida_loop_t), intent(inout) :: self
    real(dp), intent(in) :: t_a, t_b
    integer, intent(out) :: stat
    call self%ctx%mech%watch_nodes_lam(t_a, t_b, self%yn, self%lamn, stat)
  end subroutine ida_watch_nodes

  !> The watch with the step's own multipliers (the module header); then multipliers that grew
  !> (from rest, or a load ramped up) raise their tolerance (lam_atol). The index1 form first
  !> looks for a singular pose in the step (singular_pose).
  subroutine ida_accept(self, t, sample, stat)
    class(ida_loop_t), intent(inout) :: self
    real(dp), intent(in) :: t
    logical, intent(in) :: sample
    integer, intent(out) :: stat
    associate (ctx => self%ctx, y => self%y, ny => self%ctx%ny, nl => self%ctx%nl)
      stat = MBDK_SUCCESS
      if (.not. ctx%ggl .and. ctx%m > 0) then
        call singular_pose(self, t, stat)
        if (stat /= MBDK_SUCCESS) return
      end if
      if (ctx%mech%has_watch) then
        call put_lam(ctx, y(ny + 1:ny + nl), ctx%lamfull)
        call ctx%mech%watch_lam(t, y(1:ny), sample, ctx%lamfull, stat)
        if (stat /= MBDK_SUCCESS) return
      end if
      if (nl > 0) then
        if (maxval(abs(y(ny + 1:ny + nl))) > 2.0_dp * ctx%lam_scale) then
          ctx%lam_scale = maxval(abs(y(ny + 1:ny + nl)))
          ctx%atol(ny + 1:ny + nl) = lam_atol(self%opt, y(ny + 1:ny + nl))
        end if
      end if
    end associate
  end subroutine ida_accept

  !> The index1 form at a singular pose: there the acceleration-level rows hold on either
  !> branch of the mechanism, and with Phi not kept it can leave the motion's branch for another
  !> without a residual or the energy showing it (IFToMM A02's parallelogram turned crossed at
  !> its second flat pose, 5.6 rad off the exact crank angle at t = 5 s, and reported success).
  !> So it stops there by name, MBDK_ERR_SINGULAR_MATRIX, as the reduced ODE does: the
  !> mechanism's reduced ODE (rhs; the mechanism of a DAE solve is built with the reduced
  !> formulation, which refuses a relative pivot of C M^-1 C^T below its threshold) at
  !> SINGULAR_PROBES points of the accepted step, from IDA's interpolant (a step strides over
  !> a pose its end points miss).
  !> The ggl form keeps Phi = 0: it passes such poses on the motion's branch, or stops next to
  !> one by name (singular_stop).
  subroutine singular_pose(self, t, stat)
    class(ida_loop_t), intent(inout) :: self
    real(dp), intent(in) :: t
    integer, intent(out) :: stat
    real(dp) :: h, tk
    integer :: k, q
    associate (ctx => self%ctx, nq => self%ctx%nq, ny => self%ctx%ny)
      call self%last_step(h, q)
      do k = 1, SINGULAR_PROBES
        tk = t - h + (real(k, dp) / SINGULAR_PROBES) * h
        if (k < SINGULAR_PROBES) then
          call self%dky(tk, stat)
          if (stat /= MBDK_SUCCESS) return
          call ctx%mech%rhs(tk, self%ydky(1:ny), ctx%ydot, stat)
        else
          call ctx%mech%rhs(t, self%y(1:ny), ctx%ydot, stat)
        end if
        if (stat == MBDK_ERR_SINGULAR_MATRIX) return
      end do
      stat = MBDK_SUCCESS
    end associate
  end subroutine singular_pose

  !> A solve whose steps shrank to nothing (or whose Newton iteration failed at every step)
  !> after the last accepted state at t > t0 lying next to a singular pose of the rows it
  !> solves (the mechanism's near_rank_loss): MBDK_ERR_SINGULAR_MATRIX, the cause. There the
  !> DAE's rows lose a rank together and the Jacobian of its Newton matrix moves fast; whether
  !> the steps get past depends on where they land (IFToMM A02's flat poses).
  subroutine singular_stop(lp, t, t0, stat)
    type(ida_loop_t), intent(inout) :: lp
    real(dp), intent(in) :: t, t0
    integer, intent(inout) :: stat
    integer :: dstat
    if (t <= t0 .or. lp%ctx%m == 0) return
    call lp%dky(t, dstat)      ! IDA's state at its last step, as its failure left it
    if (dstat /= MBDK_SUCCESS) return
    if (lp%ctx%mech%near_rank_loss(t, lp%ydky(1:lp%ctx%ny), lp%ctx%rows)) &
      stat = MBDK_ERR_SINGULAR_MATRIX
  end subroutine singular_stop

  !> The multipliers of Y (the context's nl, on its rows) as the mechanism's m rows into dst
  !> (the rows a redundant scene leaves out: 0).
  subroutine put_lam(ctx, src, dst)
    type(ida_context_t), intent(in) :: ctx
    real(dp), intent(in) :: src(:)
    real(dp), intent(inout) :: dst(:)
    dst(1:ctx%m) = 0.0_dp
    dst(ctx%rows) = src
  end subroutine put_lam

  !> Whether the residual r of the initial values (y, yp) is within roundoff, row by row (see
  !> the module header); ctx holds the evaluation at those values (dae_residual).
  logical function consistent(ctx, y, yp, r)
    type(ida_context_t), intent(inout) :: ctx
    real(dp), intent(in) :: y(:), yp(:), r(:)
    real(dp), allocatable :: ts(:), mlam(:), sz(:), cabs(:)
    real(dp) :: tol, s
    integer :: nq, nv, ny, nl, i, j, k, astat
    nq = ctx%nq
    nv = ctx%nv
    ny = ctx%ny
    nl = ctx%nl
    tol = CONSISTENT_ULPS * epsilon(1.0_dp)
    consistent = .false.
    allocate (ts(nv), mlam(nv), sz(max(nl, 1)), cabs(ctx%m), stat=astat)
    if (astat /= 0) return
    ! the kinematic rows: the rates are the same function of the same numbers (0 exactly)
    if (.not. all(abs(r(1:nq)) <= tol * (abs(yp(1:nq)) + abs(ctx%qd)))) return
    ! the velocity rows; ts: the sizes of the terms of each acceleration (M^-1 f and
    ! M^-1 C^T lam, which nearly cancel in a mechanism at rest under gravity)
    associate (v => y(nq + 1:ny), a => yp(nq + 1:ny), rv => r(nq + 1:ny))
      if (ctx%sparse) then
        call ctx%mech%i3_ct_times(ctx%aux, ctx%lamfull, mlam, absolute=.true.)
      else
        do k = 1, nv
          mlam(k) = sum(abs(ctx%c(:, k) * ctx%lamfull))   ! |C^T lam| term by term
        end do
      end if
      if (ctx%mech%diag_mass) then
        do k = 1, nv
          if (.not. (abs(rv(k)) <= tol * (abs(ctx%dm(k) * a(k)) + mlam(k) + abs(ctx%f(k))))) &
            return
          ts(k) = 0.0_dp
          if (ctx%dm(k) > 0.0_dp) ts(k) = (abs(ctx%f(k)) + mlam(k)) / ctx%dm(k)
        end do
      else
        ! M^-1 mixes a body's rows: against the largest terms
        call ctx%mech%minv_times(ctx%f, ts)
        call ctx%mech%minv_times(ctx%f - ctx%g, mlam)
        ts = abs(ts) + abs(mlam)
        if (.not. all(abs(rv) <= tol * (maxval(abs(a)) + maxval(ts)))) return
      end if
      ! the constraint rows against the largest row's terms: a row whose own terms are all
      ! zero (a slider's, while the crank turns) still carries the roundoff of the assembly's
      ! solve, which is that of the largest
      ! (cabs: |C| |v|, or |C| (|a| + ts), on every row)
      if (ctx%sparse .and. nl > 0) then
        if (ctx%ggl) then
          call ctx%mech%i3_c_times(ctx%aux, v, cabs, absolute=.true.)
        else
          call ctx%mech%i3_c_times(ctx%aux, abs(a) + ts, cabs, absolute=.true.)
        end if
      end if
      do i = 1, nl
        j = ctx%rows(i)
        if (ctx%ggl) then
          if (ctx%sparse) then
            sz(i) = cabs(j) + abs(ctx%phit(j))
          else
            sz(i) = sum(abs(ctx%c(j, :) * v)) + abs(ctx%phit(j))
          end if
          if (.not. (abs(r(ny + i)) <= max(ASSEMBLED_PHI, tol * maxval(abs(y(1:nq)))))) return
        else
          ! C a = gamma: a's roundoff is that of its terms
          if (ctx%sparse) then
            sz(i) = abs(ctx%gam(j)) + cabs(j)
          else
            sz(i) = abs(ctx%gam(j)) + sum(abs(ctx%c(j, :)) * (abs(a) + ts))
          end if
        end if
      end do
      if (nl > 0) then
        s = tol * maxval(sz(1:nl))
        k = ny + merge(nl, 0, ctx%ggl)
        if (.not. all(abs(r(k + 1:k + nl)) <= s)) return
      end if
    end associate
    consistent = .true.
  end function consistent

  !> F(t, Y, Y') of the form (module header) into r; the context's f, phi, c, gam, phit,
  !> lamfull, g (= f - C^T lam) and qd (the rates) are left at (t, q, v). stat: the
  !> mechanism's.
  subroutine dae_residual(ctx, t, y, yp, r, stat)
    type(ida_context_t), intent(inout) :: ctx
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:), yp(:)
    real(dp), intent(out), contiguous :: r(:)
    integer, intent(out) :: stat
    integer :: nq, nv, ny, nl, i, j, k, ol, om
    real(dp) :: s, u

    if (ctx%sparse) then
      call compact_residual(ctx, t, y, yp, r, stat)
      return
    end if
    nq = ctx%nq
    nv = ctx%nv
    ny = ctx%ny
    nl = ctx%nl
    ol = ny          ! lam(i) = y(ol + i)
    om = ny + nl     ! mu(i) = y(om + i)
    associate (q => y(1:nq), v => y(nq + 1:ny), c => ctx%c)
      call ctx%mech%evaluate(t, q, v, ctx%f, ctx%phi, c, ctx%gam, ctx%phit, stat)
      if (stat /= MBDK_SUCCESS) return
      ctx%lamfull = 0.0_dp
      ctx%lamfull(ctx%rows) = y(ol + 1:ol + nl)
      if (ctx%ggl) then
        ctx%mufull = 0.0_dp
        ctx%mufull(ctx%rows) = y(om + 1:om + nl)
      end if
      ! column by column of C (its storage order): g = f - C^T lam, x = v - C^T mu
      do k = 1, nv
        s = ctx%f(k)
        do i = 1, ctx%m
          s = s - c(i, k) * ctx%lamfull(i)
        end do
        ctx%g(k) = s
        if (ctx%ggl) then
          u = v(k)
          do i = 1, ctx%m
            u = u - c(i, k) * ctx%mufull(i)
          end do
          ctx%x(k) = u
        end if
      end do
      if (ctx%mech%diag_mass) then
        r(nq + 1:ny) = ctx%dm * yp(nq + 1:ny) - ctx%g
      else
        call ctx%mech%minv_times(ctx%g, ctx%ming)
        r(nq + 1:ny) = yp(nq + 1:ny) - ctx%ming
      end if
      if (ctx%ggl) then
        call ctx%mech%rates(q, ctx%x, ctx%qd, stat)
      else
        call ctx%mech%rates(q, v, ctx%qd, stat)
      end if
      if (stat /= MBDK_SUCCESS) return
      r(1:nq) = yp(1:nq) - ctx%qd
      do i = 1, nl
        j = ctx%rows(i)
        if (ctx%ggl) then
          r(ol + i) = ctx%phi(j)
          r(om + i) = dot_product(c(j, :), v) + ctx%phit(j)
        else
          r(ol + i) = dot_product(c(j, :), yp(nq + 1:ny)) - ctx%gam(j)
        end if
      end do
    end associate
  end subroutine dae_residual

  !> dae_residual on the sparse path: the index-3 evaluation (f, Phi, gamma, Phi_t, C kept in
  !> compact rows) and C's products; the same context fields left at (t, q, v).
  subroutine compact_residual(ctx, t, y, yp, r, stat)
    type(ida_context_t), intent(inout) :: ctx
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:), yp(:)
    real(dp), intent(out), contiguous :: r(:)
    integer, intent(out) :: stat
    integer :: nq, ny, nl, ol, om
    nq = ctx%nq
    ny = ctx%ny
    nl = ctx%nl
    ol = ny
    om = ny + nl
    associate (q => y(1:nq), v => y(nq + 1:ny), e => ctx%e, mech => ctx%mech)
      e%q = q
      e%v = v
      ! (ida_res has checked Y; forces not finite at a finite state reach r, which it checks)
      call mech%i3_evaluate(ctx%aux, t, e, .true., .false., stat)
      if (stat /= MBDK_SUCCESS) return
      ctx%f = e%f
      ctx%phi = e%phi
      ctx%gam = e%gam
      ctx%phit = e%phit
      ctx%lamfull = 0.0_dp
      ctx%lamfull(ctx%rows) = y(ol + 1:ol + nl)
      call mech%i3_ct_times(ctx%aux, ctx%lamfull, ctx%tv)
      ctx%g = ctx%f - ctx%tv
      if (mech%diag_mass) then
        r(nq + 1:ny) = ctx%dm * yp(nq + 1:ny) - ctx%g
      else
        call mech%minv_times(ctx%g, ctx%ming)
        r(nq + 1:ny) = yp(nq + 1:ny) - ctx%ming
      end if
      if (ctx%ggl) then
        ctx%mufull = 0.0_dp
        ctx%mufull(ctx%rows) = y(om + 1:om + nl)
        call mech%i3_ct_times(ctx%aux, ctx%mufull, ctx%tv)
        ctx%x = v - ctx%tv
        call mech%rates(q, ctx%x, ctx%qd, stat)
      else
        call mech%rates(q, v, ctx%qd, stat)
      end if
      if (stat /= MBDK_SUCCESS) return
      r(1:nq) = yp(1:nq) - ctx%qd
      if (ctx%ggl) then
        r(ol + 1:ol + nl) = ctx%phi(ctx%rows)
        call mech%i3_c_times(ctx%aux, v, ctx%cv)
        r(om + 1:om + nl) = ctx%cv(ctx%rows) + ctx%phit(ctx%rows)
      else
        call mech%i3_c_times(ctx%aux, yp(nq + 1:ny), ctx%cv)
        r(ol + 1:ol + nl) = ctx%cv(ctx%rows) - ctx%gam(ctx%rows)
      end if
    end associate
  end subroutine compact_residual

  !> IDA's counters into st (see the module header).
  subroutine add_stats(mem, st, ctx)
    type(c_ptr), intent(in) :: mem
    type(mbdk_stats_t), intent(inout) :: st
    type(ida_context_t), intent(in) :: ctx
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
    if (ctx%sparse) then
      ! the sparse path's setups are KLU's; its difference quotients are residuals of ours
      st%nlu_sparse = st%nlu_sparse + c(1)
      st%nfev = st%nfev + ctx%jac_nfev
    end if
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
  !> The error weights (IDAWFtolerances): 1 / (rtol |y_i| + atol_i), atol from ctx%atol,
  !> whose multipliers' entries the loop raises as they grow (lam_atol). -1
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

  !> IDALsJacFn on the sparse path: J = dF/dY + cj dF/dY' into the CSC matrix jac by colored
  !> difference quotients (module header): the k-th unknown of every body of a color, or the
  !> multiplier of every row of a color (lam, then mu), moved together by IDA's increment rule
  !> (max(sqrt(eps) max(|y_j|, |h y'_j|), 1 / ewt_j), with the sign of h y'_j; ewt_j here at
  !> the iterate, IDA's at the last step) in Y and cj times it in Y'; r is F at (Y, Y'). 0, or
  !> ida_res's 1 and -1.
  integer(c_int) function ida_jac(t, cj, nv_y, nv_yp, nv_r, jac, user_data, t1, t2, t3) &
      bind(C, name='') result(ierr)
    real(c_double), value :: t, cj
    type(N_Vector), target :: nv_y, nv_yp, nv_r
    type(c_ptr), value :: jac, user_data, t1, t2, t3
    type(ida_context_t), pointer :: ctx
    real(c_double), pointer, contiguous :: y(:), yp(:), r(:), jx(:)
    real(dp) :: h(1), inc
    integer :: c, d, k, b, j, p, set, stat, nn
    logical :: moved
    call c_f_pointer(user_data, ctx)
    ierr = -1
    if (ctx%stat /= MBDK_SUCCESS) return
    nn = ctx%n
    call c_f_pointer(n_vgetarraypointer(c_loc(nv_y)), y, [nn])
    call c_f_pointer(n_vgetarraypointer(c_loc(nv_yp)), yp, [nn])
    call c_f_pointer(n_vgetarraypointer(c_loc(nv_r)), r, [nn])
    call put_pattern(ctx, jac)
    call c_f_pointer(sun_sparse_data(jac), jx, [ctx%ap(nn + 1) - 1])
    h = 0.0_dp
    if (FIDAGetCurrentStep(ctx%mem, h) /= 0) then
      ctx%stat = MBDK_ERR_BACKEND
      return
    end if
    ctx%yw = y
    ctx%ypw = yp
    associate (pat => ctx%pat)
      ! the bodies' columns
      do c = 1, size(pat%cptr) - 1
        do d = 1, pat%dmax
          moved = .false.
          do k = pat%cptr(c), pat%cptr(c + 1) - 1
            b = pat%cbody(k)
            if (pat%bptr(b) + d - 1 >= pat%bptr(b + 1)) cycle
            call move(pat%bidx(pat%bptr(b) + d - 1))
            moved = .true.
          end do
          if (.not. moved) cycle
          call quotients(stat)
          if (stat /= 0) then
            ierr = stat
            return
          end if
          do k = pat%cptr(c), pat%cptr(c + 1) - 1
            b = pat%cbody(k)
            if (pat%bptr(b) + d - 1 >= pat%bptr(b + 1)) cycle
            call fill(pat%bidx(pat%bptr(b) + d - 1))
          end do
        end do
      end do
      ! the multipliers' columns, row color by row color, lam's then mu's
      do set = 0, pat%nsets - 1
        do c = 1, size(pat%rptr) - 1
          do k = pat%rptr(c), pat%rptr(c + 1) - 1
            call move(ctx%ny + set * ctx%nl + pat%rrow(k))
          end do
          call quotients(stat)
          if (stat /= 0) then
            ierr = stat
            return
          end if
          do k = pat%rptr(c), pat%rptr(c + 1) - 1
            call fill(ctx%ny + set * ctx%nl + pat%rrow(k))
          end do
        end do
      end do
    end associate
    ierr = 0

  contains

    !> Y_j and Y'_j moved by IDA's increment (the function's header)
    subroutine move(jj)
      integer, intent(in) :: jj
      inc = max(sqrt(epsilon(1.0_dp)) * max(abs(y(jj)), abs(h(1) * yp(jj))), &
                ctx%rtol * abs(y(jj)) + ctx%atol(jj))
      if (h(1) * yp(jj) < 0.0_dp) inc = -inc
      ctx%yw(jj) = y(jj) + inc
      ctx%del(jj) = ctx%yw(jj) - y(jj)     ! the increment actually representable
      ctx%ypw(jj) = yp(jj) + cj * ctx%del(jj)
    end subroutine move

    !> F at the moved state into ctx%r1 (counted); s: ida_res's convention
    subroutine quotients(s)
      integer, intent(out) :: s
      integer :: st_
      s = -1
      ! (ida_res's poll: a long Jacobian of a large scene ends within one evaluation)
      if (ctx%interrupt /= 0) then
        if (mbdk_interrupted(ctx%interrupt)) then
          ctx%stat = MBDK_ERR_INTERRUPTED
          return
        end if
      end if
      ctx%jac_nfev = ctx%jac_nfev + 1
      call dae_residual(ctx, t, ctx%yw, ctx%ypw, ctx%r1, st_)
      if (st_ /= MBDK_SUCCESS) then
        ctx%stat = st_
        return
      end if
      s = 0
      if (.not. all(abs(ctx%r1) <= huge(1.0_dp))) then
        ctx%soft_stat = MBDK_ERR_NONFINITE
        s = 1
      end if
    end subroutine quotients

    !> column jj from the quotients, Y_j and Y'_j put back
    subroutine fill(jj)
      integer, intent(in) :: jj
      do p = ctx%ap(jj), ctx%ap(jj + 1) - 1
        j = ctx%ai(p)
        jx(p) = (ctx%r1(j) - r(j)) / ctx%del(jj)
      end do
      ctx%yw(jj) = y(jj)
      ctx%ypw(jj) = yp(jj)
    end subroutine fill

  end function ida_jac

  !> The absolute tolerance of the multipliers lam (their values at the start, and again after
  !> a step where the largest has doubled): max(atol, max(rtol, LAM_RTOL_FLOOR) max |lam|). In
  !> the iteration the multipliers carry roundoff of the order of eps times the largest one
  !> times the iteration matrix's condition, which grows as h shrinks; tested at atol alone,
  !> or at rtol near eps, that roundoff keeps Newton from converging (IDA_CONV_FAIL) on stiff
  !> scenes at tight tolerances, and whether it does then depends on where the steps fall.
  pure function lam_atol(opt, lam0) result(a)
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: lam0(:)
    real(dp) :: a
    a = max(opt%atol, max(opt%rtol, LAM_RTOL_FLOOR) * maxval(abs(lam0)))
  end function lam_atol

end module mbdk_ida
