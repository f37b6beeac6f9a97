!> A planar multibody scene as a problem y' = F(t, y) for every integrator of the kernel:
!> y = [q; v; w], q = (x, y, theta) per body in absolute coordinates (nq = 3 bodies), w the
!> states of the scene's effects (one worn volume per wear element, mbdk_wear: none in a scene
!> that declares none), and
!>
!>   M q'' + D^T lambda = f(q, v, t),        Phi(q, t) = 0          (Fekete (2023) (2.54))
!>
!> turned into accelerations by the formulation (Fekete (2023) section 3):
!>   1 reduced     D q'' = gamma                                            (3.18)-(3.28)
!>   2 baumgarte   D q'' = gamma - 2 alpha Phi' - beta^2 Phi                 (3.29)-(3.34)
!>   3 penalty     (M + ap D^T D) q'' = f - ap D^T (-gamma + 2 mu w Phi' + w^2 Phi),
!>                 lambda = ap (D q'' - gamma + 2 mu w Phi' + w^2 Phi)       (3.35)-(3.40)
!>   4 projection  reduced, then after every step q is projected onto Phi = 0 and v onto
!>                 Phi' = 0 (mass-weighted least change; Euclidean if a body has zero inertia)
!> with Phi' = D v + Phi_t.
!>
!> Options: mbdk_model_options_t (formulation, solver and the formulations' parameters).
!>
!> Linear solves (options%solver): when M is positive (every body has mass and inertia) the
!> constrained systems are solved through the Schur complement S = D M^-1 D^T (M diagonal):
!>   - every joint revolute (solver auto up to MBDK_SMALL_DENSE_MAX rows, or solver revolute):
!>     S in closed form, 2 x 2 block by block, from the joint points' offsets, and its block
!>     LDL^T written out for 2 x 2 pivots (mbdk_revolute_schur); the right-hand side of
!>     D a = rc comes out of the same pass over the joints as gamma;
!>   - otherwise S assembled from the nonzeros of D (mbdk_sparse_schur): with solver auto up
!>     to MBDK_SMALL_DENSE_MAX rows, or solver schur, dense, by an in-house root-free Cholesky
!>     (LDL^T) with the joints as pivot blocks, eliminating the right-hand side along with the
!>     matrix in one pass (mbdk_small_ldlt_solve_once: S serves one solve; LAPACK's call
!>     overhead dominates such tiny systems), or by mbdk_lapack's Cholesky for more rows (solver
!>     schur) or small_dense off; with solver auto above MBDK_SMALL_DENSE_MAX rows, or solver
!>     sparse, kept sparse and factorised by AMD + LDL (mbdk_constrained's sparse path);
!>   - otherwise (or solver kkt) the KKT matrix [M D^T; D 0] is factorised by mbdk_lapack's LU.
!> Dependent (redundant) constraint rows make S or the KKT matrix singular:
!> MBDK_ERR_SINGULAR_MATRIX. The penalty matrix M + ap D^T D stays definite with redundant rows.
!> Solver schur or revolute without M positive, or revolute with a joint of another type:
!> MBDK_ERR_INVALID_INPUT at mbdk_model_init.
!>
!> An evaluation (mbdk_model_assemble) computes the sin/cos of every body's angle once, the
!> forces, and Phi, gamma, Phi_t and D in the compact rows of mbdk_joints (on the revolute
!> path: Phi, gamma, the joint points' offsets and the right-hand side rc instead of D); a
!> dense D is scattered from those rows only where a dense matrix is built from it (the
!> penalty formulation's work%d, the KKT path's own copy, the index-3 book scheme, the DAE
!> forms of ida and bdf): the other paths and the outputs work on the compact rows.
!>
!> Only the elements a scene declares are visited; work%visits(:) counts the evaluations of each
!> element kind of the registry (joints 1..MBDK_JOINT_TYPES, then the force table's forces and
!> effects: mbdk_elements; the kinds of spatial scenes alone stay at 0) so that a test can show
!> that absent effects cost nothing. Gravity, constant in (q, v, t), is summed once at init and counted at every
!> evaluation that starts from it. The counters and the evaluation buffers live in a
!> mbdk_model_work_t that the caller owns and the model points to (rhs receives the problem
!> read-only): an evaluation allocates nothing, which matters at a hundred nanoseconds per
!> evaluation.
module mbdk_model
  use, intrinsic :: iso_c_binding, only: c_int, c_double
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t, MBDK_GAUSS3
  use mbdk_mechanism, only: mbdk_mechanism_t, mbdk_i3_aux_t, mbdk_i3_eval_t, MBDK_FORM_REDUCED, &
    MBDK_FORM_BAUMGARTE, MBDK_FORM_PENALTY, MBDK_FORM_PROJECTION, MBDK_RANK_LOSS_WINDOW, &
    MBDK_RANK_LOSS_MAX_ROWS
  use mbdk_rank_margin, only: mbdk_near_rank_loss
  use mbdk_joints, only: mbdk_joint_rows, mbdk_joints_eval, mbdk_joints_pattern, &
    mbdk_joints_scatter, MBDK_JOINT_TYPES, MBDK_JOINT_DRIVER, MBDK_JOINT_REVOLUTE, &
    MBDK_JOINT_DISTANCE, MBDK_JOINT_POINT_LINE, MBDK_JOINT_POINT_CURVE, MBDK_JOINT_COUPLING, &
    MBDK_JOINT_ROLLING, MBDK_JOINT_KNIFE_EDGE, mbdk_joints_pfaffian, &
    MBDK_JOINT_PRISMATIC, MBDK_JOINT_FIXED, &
    MBDK_JOINT_SLOTS, mbdk_body_rotations, mbdk_body_point
  use mbdk_force_elements, only: mbdk_forces_eval, mbdk_forces_energy, MBDK_FORCE_TYPES, &
    MBDK_FORCE_GRAVITY, MBDK_FORCE_SPRING, MBDK_FORCE_DAMPER, MBDK_FORCE_POINT, &
    MBDK_FORCE_TORQUE, MBDK_FORCE_COORDINATE, MBDK_FORCE_SPRING_DAMPER
  use mbdk_elements, only: mbdk_body_kind, mbdk_element_applies, MBDK_BODY_PLANAR, &
    MBDK_BODY_KINDS, MBDK_PLANAR_COORDS, MBDK_ELEMENT_NAME_LEN, MBDK_ELEMENT_KINDS, &
    MBDK_CLASS_FORCE, MBDK_FORCE_CONTACT, MBDK_FORCE_FRICTION, MBDK_EFFECT_WEAR
  use mbdk_contact, only: MBDK_CONTACT_LINE, MBDK_CONTACT_INSIDE, MBDK_CONTACT_GEAR, &
    mbdk_contact_forces_all, mbdk_contact_t, mbdk_contact_eval
  use mbdk_contact_law, only: mbdk_contact_event, mbdk_contact_parting
  use mbdk_wear, only: mbdk_wear_rates, MBDK_WEAR_LAWS, MBDK_WEAR_GEAR, MBDK_WEAR_LOAD_NORMAL, &
    MBDK_WEAR_LOAD_FRICTION
  use mbdk_lapack, only: mbdk_chol_factor, mbdk_chol_solve
  use mbdk_memory, only: mbdk_alloc_status, mbdk_count_fits, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_watch, only: mbdk_watch_t, mbdk_watch_start, mbdk_watch_due, mbdk_watch_test, &
    mbdk_watch_power, MBDK_WATCH_NOTHING, MBDK_WATCH_POWER_ONLY, MBDK_WATCH_EVERY, &
    mbdk_watch_start_invariants, mbdk_watch_nodes, mbdk_inv_rule_t, mbdk_inv_external, &
    mbdk_inv_gravity, mbdk_inv_pivot, mbdk_inv_result, mbdk_inv_force, mbdk_inv_moment, &
    MBDK_INV_MAX, MBDK_INV_WORDS, MBDK_INV_ANGULAR_POINT, MBDK_INV_ANGULAR_CENTRE, &
    MBDK_WORK_PARTS
  use mbdk_small_dense, only: mbdk_small_ldlt_solve_once, MBDK_SMALL_DENSE_MAX
  use mbdk_sparse_schur, only: mbdk_sparse_schur_t, mbdk_sparse_schur_init, mbdk_sparse_d_times
  use mbdk_revolute_schur, only: mbdk_revolute_schur_t, mbdk_revolute_schur_init, &
    mbdk_revolute_kinematics, mbdk_revolute_solve
  use mbdk_constrained, only: mbdk_constrained_t, mbdk_constrained_init, &
    mbdk_constrained_solve_once, mbdk_constrained_factor, mbdk_constrained_solve, &
    mbdk_constrained_path, MBDK_CONSTRAINED_SINGULAR_TOL, MBDK_SOLVE_NONE, &
    MBDK_SOLVE_REVOLUTE, MBDK_SOLVE_SCHUR_SMALL, MBDK_SOLVE_SCHUR_LAPACK, MBDK_SOLVE_KKT, &
    MBDK_SOLVE_PENALTY_SMALL, MBDK_SOLVE_PENALTY_LAPACK, MBDK_SOLVE_SCHUR_SPARSE
  implicit none
  private
  public :: mbdk_model_init, mbdk_model_accelerations, mbdk_model_outputs, mbdk_model_constraints
  public :: mbdk_model_assemble, mbdk_model_linear_solve, mbdk_model_watch_start, &
    mbdk_model_watch, mbdk_model_watch_nodes, mbdk_model_sparse, mbdk_phi_floor

  ! the formulations' codes are the mechanism interface's
  public :: MBDK_FORM_REDUCED, MBDK_FORM_BAUMGARTE, MBDK_FORM_PENALTY, MBDK_FORM_PROJECTION
  integer, parameter, public :: MBDK_SOLVER_AUTO = 1, MBDK_SOLVER_SCHUR = 2, MBDK_SOLVER_KKT = 3, &
    MBDK_SOLVER_REVOLUTE = 4, MBDK_SOLVER_SPARSE = 5
  ! the linear solve an evaluation takes (mbdk_model_linear_solve): mbdk_constrained's codes
  public :: MBDK_SOLVE_NONE, MBDK_SOLVE_REVOLUTE, MBDK_SOLVE_SCHUR_SMALL, MBDK_SOLVE_SCHUR_LAPACK, &
    MBDK_SOLVE_KKT, MBDK_SOLVE_PENALTY_SMALL, MBDK_SOLVE_PENALTY_LAPACK, MBDK_SOLVE_SCHUR_SPARSE
  integer, parameter, public :: MBDK_VISIT_COUNT = MBDK_ELEMENT_KINDS
  !> outputs per sample: energy parts and residuals
  integer, parameter, public :: MBDK_ENERGY_PARTS = 6, MBDK_RESIDUALS = 3
  !> the outputs a run asks for (mbdk_model_outputs' want, a sum of these bits); a run computes
  !> only those, at its samples
  integer, parameter, public :: MBDK_OUT_ACCELERATIONS = 1, MBDK_OUT_MULTIPLIERS = 2, &
    MBDK_OUT_REACTIONS = 4, MBDK_OUT_ENERGY = 8, MBDK_OUT_RESIDUALS = 16, MBDK_OUT_ALL = 31
  !> relative pivot below which S = D M^-1 D^T (or the KKT matrix) counts as singular
  real(dp), parameter, public :: MBDK_MODEL_SINGULAR_TOL = MBDK_CONSTRAINED_SINGULAR_TOL
  real(dp), parameter :: SINGULAR_TOL = MBDK_MODEL_SINGULAR_TOL
  !> The reduced formulation's right-hand side refuses a relative pivot of D M^-1 D^T below
  !> this (MBDK_ERR_SINGULAR_MATRIX), a near rank loss and not only a singular D: there its
  !> accelerations amplify the drift of v in the vanishing direction up to 1/pivot-fold, and a
  !> fixed step across a singular crossing can leave the mechanism on another assembly branch
  !> with its residuals within the watch's tolerances. The window is wide (the pivot falls like
  !> the square of the distance to the crossing, so this is about 1 % of the way there) because
  !> a step has to land a stage inside it: at 1e-6, steps of 2.5e-3 s strode over the IFToMM A02
  !> chain's flat pose unseen. The stabilised formulations (Baumgarte, projection) and penalty
  !> keep the constraints through such a step: they pass it, or stop by name.
  real(dp), parameter, public :: MBDK_MODEL_NEAR_PIVOT = 1.0e-4_dp

  !> Options of a model, by name with defaults. bind(C): the same struct is struct
  !> mbdk_model_options in mbdk.h and mbdk.options.ModelOptions in Python (tests/test_structs.py
  !> and kernel/tests/c_struct_layout.c check that the three agree field by field).
  type, bind(C), public :: mbdk_model_options_t
    real(c_double) :: baumgarte_alpha = 0.0_c_double    !< (3.29): 2 alpha Phi'
    real(c_double) :: baumgarte_beta = 0.0_c_double     !< (3.29): beta^2 Phi
    real(c_double) :: penalty_alpha = 1.0e7_c_double    !< Jalon-Bayo (3.35)-(3.40)
    real(c_double) :: penalty_omega = 10.0_c_double
    real(c_double) :: penalty_mu = 1.0_c_double
    !> max |Phi| after the projection of q (raised to Phi's roundoff at q: mbdk_phi_floor)
    real(c_double) :: projection_tol = 1.0e-12_c_double
    integer(c_int) :: formulation = MBDK_FORM_REDUCED   !< MBDK_FORM_*
    integer(c_int) :: solver = MBDK_SOLVER_AUTO         !< MBDK_SOLVER_*
    integer(c_int) :: small_dense = 1                   !< 0: LAPACK for every factorisation
    integer(c_int) :: projection_max_iter = 20          !< Gauss-Newton iterations of the projection of q
    !> what a run must keep (mbdk_watch): |Phi| per length scale, the velocity residual per
    !> size of its terms, the energy balance per energy scale; <= 0 turns a test off. Last in
    !> the struct, so that initialisers written for the fields before them still fill those.
    real(c_double) :: watch_position = 1.0e-2_c_double
    real(c_double) :: watch_velocity = 1.0e-2_c_double
    real(c_double) :: watch_energy = 1.0e-1_c_double
    integer(c_int) :: watch_every = MBDK_WATCH_EVERY    !< steps between checks; 0: the default
    !> 1: the contacts' penetrations are events (mbdk_problem), which dopri54 and bs32 locate
    !> and end a step on; 0: off
    integer(c_int) :: locate_events = 1
    !> the momenta and angular momenta the scene conserves (mbdk_watch): their change per the
    !> size of their terms; <= 0 turns the test off
    real(c_double) :: watch_momentum = 1.0e-2_c_double
  end type mbdk_model_options_t

  !> Visit counters and the buffers of one evaluation, sized at mbdk_model_init.
  type, public :: mbdk_model_work_t
    real(dp), allocatable :: fq(:), phi(:), d(:, :), gam(:), phit(:), rc(:)
    real(dp), allocatable :: rot(:, :), dz(:, :)  !< (cos, sin) per body; D in compact rows
    real(dp), allocatable :: pp(:, :)   !< perp(rho) of the joint ends (revolute path)
    real(dp), allocatable :: lam_rhs(:)   !< multipliers of rhs calls; never read inside them
    !> the copy of the state post_step projects (y is returned only when both projections
    !> succeed)
    real(dp), allocatable :: y_post(:)
    real(dp), allocatable :: xc(:), pm(:, :), zero_nc(:)
    !> the constrained solves of the evaluations (weight M^-1) and of the projection
    !> formulation's corrections (weight winv)
    type(mbdk_constrained_t) :: cs, proj
    integer(i8) :: visits(MBDK_VISIT_COUNT) = 0
    !> the watch's state and its buffers: the velocity residual, its terms' size, a and lambda
    !> (for the drivers' power)
    type(mbdk_watch_t) :: watch
    real(dp), allocatable :: wres(:), wterm(:), wa(:), wlam(:)
  end type mbdk_model_work_t

  !> The planar model: a mechanism (mbdk_mechanism) with T = I, ncoord = nvel = nc, and a
  !> diagonal M.
  type, extends(mbdk_mechanism_t), public :: mbdk_model_t
    integer :: nc = 0
    !> each body's kind (mbdk_elements) and the index of its first coordinate in q
    integer, allocatable :: body_kind(:), qoff(:)
    real(dp), allocatable :: mass(:), winv(:)     !< diagonal of M (nc) and of the projection weight
    logical :: m_positive = .false.
    integer, allocatable :: jint(:, :), row0(:), fint(:, :)
    integer, allocatable :: col(:, :)             !< column of D of each compact slot
    !> pivot blocks of the LDL^T factorisations: the joints' rows for S = D M^-1 D^T, the
    !> single rows for M + ap D^T D
    integer, allocatable :: blk(:), row_blk(:)
    type(mbdk_sparse_schur_t) :: sp               !< pattern of D and of S = D M^-1 D^T
    real(dp), allocatable :: jreal(:, :), freal(:, :)
    integer :: solver = MBDK_SOLVER_AUTO
    logical :: small_dense = .true.
    real(dp) :: alpha = 0.0_dp, beta = 0.0_dp               !< Baumgarte
    real(dp) :: pen_alpha = 1.0e7_dp, pen_omega = 10.0_dp, pen_mu = 1.0_dp   !< Jalon-Bayo
    real(dp) :: proj_tol = 1.0e-12_dp
    integer :: proj_max_iter = 20
    real(dp) :: watch_tol(4) = 0.0_dp   !< position, velocity, energy, momentum (mbdk_watch)
    integer :: watch_every = MBDK_WATCH_EVERY
    !> the components of the momentum and angular momentum the scene conserves, found at init
    !> from its elements (mbdk_inv_result)
    integer :: ninv = 0
    real(dp) :: inv(MBDK_INV_WORDS, MBDK_INV_MAX) = 0.0_dp
    !> the run samples the work of dampers, loads and drivers as the watch integrates it at
    !> every step (mbdk_watch_work_at; set by the caller before the run)
    logical :: record_work = .false.
    logical :: has_drivers = .false.    !< rheonomic rows: their power needs the multipliers
    ! pfaffian(:): the rows that constrain velocities only (knife edges: mbdk_joints_pfaffian)
    !> a power term needs the bodies' rotations (a point force, a two-point damper)
    logical :: power_rot = .false.
    type(mbdk_model_work_t), pointer :: work => null()
    !> effect states (wear elements: eint/ereal, their columns referring to fint_c) and whether
    !> the scene has contacts or friction (no tangent for trapezoidal_index3's Newton matrix)
    integer, allocatable :: eint(:, :)
    real(dp), allocatable :: ereal(:, :)
    logical :: has_contacts = .false.
    !> every joint revolute and S solved in-house: the closed-form Schur complement
    logical :: revolute = .false.
    type(mbdk_revolute_schur_t) :: rs
    !> gravity's generalised force (constant: summed once at init) and how many gravity
    !> elements it holds; the other force elements, which an evaluation visits
    real(dp), allocatable :: fconst(:)
    integer :: ngrav = 0
    integer, allocatable :: fint_v(:, :), fint_c(:, :)
    real(dp), allocatable :: freal_v(:, :), freal_c(:, :)
  contains
    procedure :: rhs => model_rhs
    !> the rhs of a scene with effects (a type-bound call, so that it is not inlined into rhs)
    procedure :: rhs_effects => rhs_with_effects
    procedure :: post_step => model_post_step
    procedure :: watch_start => model_watch_start
    procedure :: watch => model_watch
    procedure :: watch_wants_nodes => model_wants_nodes
    procedure :: watch_nodes => model_watch_nodes
    procedure :: events => model_events
    procedure :: evaluate => model_evaluate
    procedure :: body_graph => model_body_graph
    procedure :: mass_times => model_mass_times
    procedure :: minv_times => model_minv_times
    procedure :: mass_diagonal => model_mass_diagonal
    procedure :: rates => model_rates
    procedure :: accelerations => model_accelerations
    procedure :: active_rows => model_active_rows
    procedure :: watch_lam => model_watch_lam
    procedure :: watch_nodes_lam => model_watch_nodes_lam
    procedure :: watch_begin => model_watch_begin
    procedure :: watch_solve => model_watch_solve
    procedure :: retract => model_retract
    procedure :: normalise => model_normalise
    procedure :: coord_weights => model_coord_weights
    procedure :: near_rank_loss => model_near_rank_loss
    ! trapezoidal_index3's part (the submodule mbdk_model_i3)
    procedure :: i3_create => model_i3_create
    procedure :: i3_evaluate => model_i3_evaluate
    procedure :: i3_residual => model_i3_residual
    procedure :: i3_c_times => model_i3_c_times
    procedure :: i3_ct_times => model_i3_ct_times
    procedure :: i3_cs_factor => model_i3_cs_factor
    procedure :: i3_cs_solve => model_i3_cs_solve
    procedure :: i3_matrix => model_i3_matrix
    procedure :: i3_matrix_solve => model_i3_matrix_solve
    procedure :: i3_project_velocity => model_i3_project_velocity
  end type mbdk_model_t

  interface
    module subroutine model_i3_create(self, aux, book, stat, asked)
      class(mbdk_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), allocatable, intent(out) :: aux
      logical, intent(in) :: book
      integer, intent(out) :: stat
      real(dp), intent(inout), optional :: asked
    end subroutine model_i3_create
    module subroutine model_i3_evaluate(self, aux, t, e, forces, same_q, stat)
      class(mbdk_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in) :: t
      type(mbdk_i3_eval_t), intent(inout) :: e
      logical, intent(in) :: forces, same_q
      integer, intent(out) :: stat
    end subroutine model_i3_evaluate
    module subroutine model_i3_residual(self, aux, e, s)
      class(mbdk_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      type(mbdk_i3_eval_t), intent(inout) :: e
      real(dp), intent(in) :: s
    end subroutine model_i3_residual
    module subroutine model_i3_c_times(self, aux, x, y, absolute)
      class(mbdk_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in), contiguous :: x(:)
      real(dp), intent(out), contiguous :: y(:)
      logical, intent(in), optional :: absolute
    end subroutine model_i3_c_times
    module subroutine model_i3_ct_times(self, aux, x, y, absolute)
      class(mbdk_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in), contiguous :: x(:)
      real(dp), intent(out), contiguous :: y(:)
      logical, intent(in), optional :: absolute
    end subroutine model_i3_ct_times
    module subroutine model_i3_cs_factor(self, aux, near, regular_ok, regular, stat)
      class(mbdk_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in) :: near
      logical, intent(in) :: regular_ok
      logical, intent(out) :: regular
      integer, intent(out) :: stat
    end subroutine model_i3_cs_factor
    module subroutine model_i3_cs_solve(self, aux, b, c, x, mu, stat)
      class(mbdk_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in), contiguous :: b(:), c(:)
      real(dp), intent(out), contiguous :: x(:), mu(:)
      integer, intent(out) :: stat
    end subroutine model_i3_cs_solve
    module subroutine model_i3_matrix(self, aux, book, t, e, lam, ck, cd, alpha, stat)
      class(mbdk_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      logical, intent(in) :: book
      real(dp), intent(in) :: t, ck, cd, alpha
      type(mbdk_i3_eval_t), intent(in) :: e
      real(dp), intent(in), contiguous :: lam(:)
      integer, intent(out) :: stat
    end subroutine model_i3_matrix
    module subroutine model_i3_matrix_solve(self, aux, e, stat)
      class(mbdk_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      type(mbdk_i3_eval_t), intent(inout) :: e
      integer, intent(out) :: stat
    end subroutine model_i3_matrix_solve
    module subroutine model_i3_project_velocity(self, aux, e, stat)
      class(mbdk_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      type(mbdk_i3_eval_t), intent(inout) :: e
      integer, intent(out) :: stat
    end subroutine model_i3_project_velocity
  end interface

contains

  !> Builds the model from its tables (see mbdk_joints and mbdk_force_elements for the layouts).
  !> kinds: each body's kind (mbdk_elements; absent: all planar). opt: formulation, solver and
  !> their parameters. work must outlive the model.
  !> MBDK_ERR_INVALID_INPUT for inconsistent tables (or counts whose sizes no default integer
  !> holds), MBDK_ERR_NOT_APPLICABLE for a body kind the kernel declares but cannot simulate yet;
  !> the Python layer names the element. MBDK_ERR_NO_MEMORY: asked gets the bytes (mbdk_memory).
  !> The steps below check and allocate in one fixed order, so that an input with more than one
  !> fault always gets the same status (and a failed allocation the same bytes).
  subroutine mbdk_model_init(model, mass, inertia, jint, jreal, fint, freal, opt, work, stat, &
                             kinds, asked)
    type(mbdk_model_t), intent(out) :: model
    real(dp), intent(in) :: mass(:), inertia(:), jreal(:, :), freal(:, :)
    integer, intent(in) :: jint(:, :), fint(:, :)
    type(mbdk_model_options_t), intent(in) :: opt
    type(mbdk_model_work_t), target, intent(inout) :: work
    integer, intent(out) :: stat
    integer, intent(in), optional :: kinds(:)
    real(dp), intent(inout), optional :: asked

    stat = MBDK_ERR_INVALID_INPUT
    model%nb = size(mass)
    if (.not. body_table_ok(mass, inertia, size(jint, 2), size(fint, 2))) return
    if (opt%formulation < MBDK_FORM_REDUCED .or. opt%formulation > MBDK_FORM_PROJECTION) return
    call lay_out_state(model, mass, inertia, count(fint(1, :) == MBDK_EFFECT_WEAR), &
                       size(jint, 2), stat, asked, kinds)
    if (stat /= MBDK_SUCCESS) return
    call validate_joint_table(model, jint, jreal, stat)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. force_table_ok(model%nb, fint, freal)) return
    if (.not. parameters_ok(opt)) return
    call copy_tables(model, jint, jreal, fint, freal, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call take_options(model, opt, stat)
    if (stat /= MBDK_SUCCESS) return
    call classify_elements(model, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. solver_ok(model)) return
    call choose_solver_path(model, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call allocate_work(model, work, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    model%work => work
    model%compact_rows = work%cs%path == MBDK_SOLVE_SCHUR_SPARSE
    model%has_jac = .false.
    call split_forces(model, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    ! events: two per contact but the gear meshes (whose penetration wraps around the base
    ! pitch; their pairs take up their load smoothly): model_events
    if (opt%locate_events /= 0 .and. model%has_contacts) &
      model%nevents = 2 * count(model%fint_c(1, :) == MBDK_FORCE_CONTACT .and. &
                                model%fint_c(4, :) /= MBDK_CONTACT_GEAR)
  end subroutine mbdk_model_init

  !> The body table (masses > 0, inertias >= 0) and counts that default integers index: the
  !> state [q; v; w] (6 nb + nf values) and the tables (12 entries per joint or force).
  pure logical function body_table_ok(mass, inertia, nj, nf) result(ok)
    real(dp), intent(in) :: mass(:), inertia(:)
    integer, intent(in) :: nj, nf
    ok = .false.
    if (size(mass) < 1 .or. size(inertia) /= size(mass)) return
    if (.not. (mbdk_count_fits(6.0_dp * size(mass) + nf) .and. mbdk_count_fits(12.0_dp * nj) &
               .and. mbdk_count_fits(12.0_dp * nf))) return
    if (any(.not. (mass > 0.0_dp)) .or. any(.not. (inertia >= 0.0_dp))) return
    ok = .true.
  end function body_table_ok

  !> The state's layout y = [q; v; w] by body kind (qoff, nc, ns), M's diagonal and winv;
  !> MBDK_ERR_NOT_APPLICABLE for a kind it cannot lay out. row0 is allocated with M (one
  !> statement, whose bytes a failure reports).
  subroutine lay_out_state(model, mass, inertia, ns, nj, stat, asked, kinds)
    type(mbdk_model_t), intent(inout) :: model
    real(dp), intent(in) :: mass(:), inertia(:)
    integer, intent(in) :: ns, nj
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer, intent(in), optional :: kinds(:)
    integer :: b, code, coords, vels, astat
    character(len=MBDK_ELEMENT_NAME_LEN) :: kname
    logical :: available
    allocate (model%body_kind(model%nb), model%qoff(model%nb), stat=astat)
    call mbdk_alloc_status(astat, 2 * MBDK_INT_BYTES * model%nb, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INVALID_INPUT
    model%body_kind = MBDK_BODY_PLANAR
    if (present(kinds)) then
      if (size(kinds) /= model%nb) return
      if (any(kinds < 1 .or. kinds > MBDK_BODY_KINDS)) return
      model%body_kind = kinds
    end if
    model%nc = 0
    do b = 1, model%nb
      call mbdk_body_kind(model%body_kind(b), code, kname, coords, vels, available)
      ! the joints and forces index a body's coordinates as a planar body's (3 b - 2 .. 3 b):
      ! other kinds run in their own model (spatial bodies: mbdk_spatial_model)
      if (code /= MBDK_BODY_PLANAR .or. .not. available .or. coords /= MBDK_PLANAR_COORDS) then
        stat = MBDK_ERR_NOT_APPLICABLE
        return
      end if
      model%qoff(b) = model%nc + 1
      model%nc = model%nc + coords
    end do
    model%ns = ns
    model%n = 2 * model%nc + model%ns
    model%nq = model%nc
    model%ncoord = model%nc
    model%nvel = model%nc
    model%diag_mass = .true.
    model%identity_kinematics = .true.
    model%has_i3_matrix = .true.
    allocate (model%mass(model%nc), model%winv(model%nc), model%row0(nj), stat=astat)
    call mbdk_alloc_status(astat, 2 * MBDK_REAL_BYTES * model%nc + MBDK_INT_BYTES * nj, stat, &
                           asked)
    if (stat /= MBDK_SUCCESS) return
    do b = 1, model%nb
      model%mass(model%qoff(b):model%qoff(b) + 1) = mass(b)
      model%mass(model%qoff(b) + 2) = inertia(b)
    end do
    model%m_positive = all(model%mass > 0.0_dp)
    if (model%m_positive) then
      model%winv = 1.0_dp / model%mass
    else
      model%winv = 1.0_dp
    end if
  end subroutine lay_out_state

  !> The joint table: its shape, finite reals, each joint's type, bodies and coordinate, the
  !> geometry its kind needs; numbers the rows (row0, m: no more rows than coordinates).
  subroutine validate_joint_table(model, jint, jreal, stat)
    type(mbdk_model_t), intent(inout) :: model
    integer, intent(in) :: jint(:, :)
    real(dp), intent(in) :: jreal(:, :)
    integer, intent(out) :: stat
    integer :: j, rows
    stat = MBDK_ERR_INVALID_INPUT
    if (size(jreal, 1) /= 12 .or. size(jreal, 2) /= size(jint, 2)) return
    if (.not. all(abs(jreal) <= huge(1.0_dp))) return
    rows = 0
    do j = 1, size(jint, 2)
      ! a joint of planar scenes: the registry gives a spatial one no planar rows
      if (mbdk_joint_rows(jint(1, j)) == 0) return
      if (jint(2, j) < 0 .or. jint(2, j) > model%nb .or. jint(3, j) < 0 .or. &
          jint(3, j) > model%nb) return
      if (jint(2, j) == 0) return
      if (jint(4, j) < 0 .or. jint(4, j) > 3) return
      ! a driver drives one coordinate of its body: x, y or theta
      if (jint(1, j) == MBDK_JOINT_DRIVER .and. jint(4, j) == 0) return
      ! curves, rolling lines and knife edges are the ground's; a coupling joins two bodies
      if ((jint(1, j) == MBDK_JOINT_POINT_CURVE .or. jint(1, j) == MBDK_JOINT_ROLLING .or. &
           jint(1, j) == MBDK_JOINT_KNIFE_EDGE) .and. jint(3, j) /= 0) return
      if (jint(1, j) == MBDK_JOINT_COUPLING .and. jint(3, j) == jint(2, j)) return
      if (jint(1, j) == MBDK_JOINT_ROLLING .and. .not. (jreal(7, j) > 0.0_dp .and. &
          abs(norm2(jreal(5:6, j)) - 1.0_dp) <= 1.0e-12_dp)) return
      if (jint(1, j) == MBDK_JOINT_KNIFE_EDGE .and. .not. (norm2(jreal(5:6, j)) > 0.0_dp)) return
      model%row0(j) = rows + 1
      rows = rows + mbdk_joint_rows(jint(1, j))
    end do
    model%m = rows
    if (model%m > model%nc) return
    stat = MBDK_SUCCESS
  end subroutine validate_joint_table

  !> The force table (forces and effects) of a scene of nb bodies: its shape, finite reals, each
  !> entry's kind, bodies and coordinate, and the parameters its kind restricts.
  pure logical function force_table_ok(nb, fint, freal) result(ok)
    integer, intent(in) :: nb
    integer, intent(in) :: fint(:, :)
    real(dp), intent(in) :: freal(:, :)
    integer :: j
    ok = .false.
    if (size(freal, 1) /= 12 .or. size(freal, 2) /= size(fint, 2)) return
    if (.not. all(abs(freal) <= huge(1.0_dp))) return
    do j = 1, size(fint, 2)
      ! a force or an effect of planar scenes (the registry's; spatial contacts are not)
      if (.not. mbdk_element_applies(MBDK_CLASS_FORCE, fint(1, j), MBDK_BODY_PLANAR)) return
      if (fint(1, j) == MBDK_FORCE_CONTACT .or. fint(1, j) == MBDK_FORCE_FRICTION .or. &
          fint(1, j) == MBDK_EFFECT_WEAR) then
        if (.not. contact_entry_ok(nb, fint, freal, j)) return
        cycle
      end if
      ! a spring has no damping, a damper no stiffness (their own kinds: mbdk_elements)
      if (fint(1, j) == MBDK_FORCE_SPRING .and. freal(7, j) /= 0.0_dp) return
      if (fint(1, j) == MBDK_FORCE_DAMPER .and. freal(5, j) /= 0.0_dp) return
      ! a point force, torque or coordinate force acts on a body (1-based), a coordinate force
      ! on one of its coordinates: body or coordinate 0 would index outside q
      if ((fint(1, j) == MBDK_FORCE_POINT .or. fint(1, j) == MBDK_FORCE_TORQUE .or. &
           fint(1, j) == MBDK_FORCE_COORDINATE) .and. fint(2, j) < 1) return
      if (fint(1, j) == MBDK_FORCE_COORDINATE .and. fint(4, j) < 1) return
      if (fint(2, j) < 0 .or. fint(2, j) > nb .or. fint(3, j) < 0 .or. &
          fint(3, j) > nb .or. fint(4, j) < 0 .or. fint(4, j) > 3) return
    end do
    ok = .true.
  end function force_table_ok

  !> Entry e of the force table, a contact (geometry 1..3, two distinct bodies, radii >= 0 with
  !> the ring larger than its circle, k >= 0, exponent >= 1, damping >= 0), friction (refers to
  !> a contact; mus, mud >= 0, 0 < vs < vd) or wear entry (law, load, and a column of the right
  !> kind; k >= 0).
  pure logical function contact_entry_ok(nb, fint, freal, e) result(ok)
    integer, intent(in) :: nb, e
    integer, intent(in) :: fint(:, :)
    real(dp), intent(in) :: freal(:, :)
    integer :: c
    ok = .false.
    select case (fint(1, e))
    case (MBDK_FORCE_CONTACT)
      if (fint(2, e) < 1 .or. fint(2, e) > nb .or. fint(3, e) < 0 .or. &
          fint(3, e) > nb .or. fint(2, e) == fint(3, e)) return
      if (fint(4, e) < MBDK_CONTACT_LINE .or. fint(4, e) > MBDK_CONTACT_GEAR) return
      if (freal(3, e) < 0.0_dp .or. freal(7, e) < 0.0_dp .or. freal(8, e) < 1.0_dp .or. &
          freal(9, e) < 0.0_dp .or. freal(10, e) < 0.0_dp) return
      if (fint(4, e) == MBDK_CONTACT_GEAR) then
        ! two gears (no ground), base radii below the tip radii, a base pitch, a hand
        if (fint(3, e) < 1 .or. .not. (freal(1, e) > 0.0_dp .and. freal(2, e) > 0.0_dp .and. &
            freal(3, e) > freal(1, e) .and. freal(4, e) > freal(2, e) .and. &
            freal(5, e) > 0.0_dp .and. abs(freal(12, e)) == 1.0_dp)) return
      else if (fint(4, e) /= MBDK_CONTACT_LINE .and. freal(6, e) < 0.0_dp) then
        return
      end if
      if (fint(4, e) == MBDK_CONTACT_INSIDE .and. .not. (freal(6, e) > freal(3, e))) return
    case (MBDK_FORCE_FRICTION)
      c = fint(4, e)
      if (fint(2, e) /= 0 .or. fint(3, e) /= 0) return
      if (c < 1 .or. c > size(fint, 2)) return
      if (fint(1, c) /= MBDK_FORCE_CONTACT) return
      if (freal(1, e) < 0.0_dp .or. freal(2, e) < 0.0_dp .or. .not. (freal(3, e) > 0.0_dp) &
          .or. .not. (freal(4, e) > freal(3, e))) return
    case (MBDK_EFFECT_WEAR)
      c = fint(4, e)
      if (fint(2, e) < 1 .or. fint(2, e) > MBDK_WEAR_LAWS) return
      if (c < 1 .or. c > size(fint, 2)) return
      if (fint(3, e) == MBDK_WEAR_LOAD_NORMAL) then
        if (fint(1, c) /= MBDK_FORCE_CONTACT) return
      else if (fint(3, e) == MBDK_WEAR_LOAD_FRICTION) then
        if (fint(1, c) /= MBDK_FORCE_FRICTION) return
      else
        return
      end if
      if (freal(1, e) < 0.0_dp) return
      if (fint(2, e) == MBDK_WEAR_GEAR .and. .not. (freal(2, e) >= 0.0_dp .and. &
          freal(3, e) > 0.0_dp .and. freal(5, e) > 0.0_dp .and. freal(7, e) > 0.0_dp)) return
    end select
    ok = .true.
  end function contact_entry_ok

  !> The formulations' parameters finite, projection_max_iter >= 1; the watch's and the
  !> solver's options are checked later (take_options, solver_ok), where they always were.
  pure logical function parameters_ok(opt) result(ok)
    type(mbdk_model_options_t), intent(in) :: opt
    ok = abs(opt%baumgarte_alpha) <= huge(1.0_dp) .and. abs(opt%baumgarte_beta) <= &
         huge(1.0_dp) .and. abs(opt%penalty_alpha) <= huge(1.0_dp) .and. &
         abs(opt%penalty_omega) <= huge(1.0_dp) .and. abs(opt%penalty_mu) <= huge(1.0_dp) &
         .and. abs(opt%projection_tol) <= huge(1.0_dp) .and. opt%projection_max_iter >= 1
  end function parameters_ok

  !> The model's own copy of the joint and force tables (checked).
  subroutine copy_tables(model, jint, jreal, fint, freal, stat, asked)
    type(mbdk_model_t), intent(inout) :: model
    integer, intent(in) :: jint(:, :), fint(:, :)
    real(dp), intent(in) :: jreal(:, :), freal(:, :)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nj, nf, astat
    nj = size(jint, 2)
    nf = size(fint, 2)
    allocate (model%jint(4, nj), model%jreal(12, nj), model%fint(4, nf), model%freal(12, nf), &
              stat=astat)
    call mbdk_alloc_status(astat, (4 * MBDK_INT_BYTES + 12 * MBDK_REAL_BYTES) * (nj + nf), stat, &
                           asked)
    if (stat /= MBDK_SUCCESS) return
    model%jint = jint
    model%jreal = jreal
    model%fint = fint
    model%freal = freal
  end subroutine copy_tables

  !> The options into the model; the watch's checked here (finite tolerances, watch_every >= 0).
  subroutine take_options(model, opt, stat)
    type(mbdk_model_t), intent(inout) :: model
    type(mbdk_model_options_t), intent(in) :: opt
    integer, intent(out) :: stat
    stat = MBDK_ERR_INVALID_INPUT
    model%formulation = opt%formulation
    model%alpha = opt%baumgarte_alpha
    model%beta = opt%baumgarte_beta
    model%pen_alpha = opt%penalty_alpha
    model%pen_omega = opt%penalty_omega
    model%pen_mu = opt%penalty_mu
    model%proj_tol = opt%projection_tol
    model%proj_max_iter = opt%projection_max_iter
    model%solver = opt%solver
    model%small_dense = opt%small_dense /= 0
    model%has_post_step = opt%formulation == MBDK_FORM_PROJECTION .and. model%m > 0
    model%watch_tol = [opt%watch_position, opt%watch_velocity, opt%watch_energy, &
                       opt%watch_momentum]
    model%watch_every = opt%watch_every
    if (opt%watch_every == 0) model%watch_every = MBDK_WATCH_EVERY
    if (.not. all(abs(model%watch_tol) <= huge(1.0_dp)) .or. opt%watch_every < 0) return
    model%has_watch = any(model%watch_tol > 0.0_dp)
    stat = MBDK_SUCCESS
  end subroutine take_options

  !> What the elements imply for the algorithms: conserved momenta, rheonomic and pfaffian
  !> rows, power terms that need rotations, contacts, velocity-dependent forces.
  subroutine classify_elements(model, stat, asked)
    type(mbdk_model_t), intent(inout) :: model
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: j, astat
    call planar_invariants(model%jint, model%jreal, model%fint, model%freal, model%inv, &
                           model%ninv)
    associate (jint => model%jint, jreal => model%jreal, fint => model%fint, &
               freal => model%freal)
      model%has_contacts = any(fint(1, :) >= MBDK_FORCE_CONTACT)
      model%velocity_forces = any(fint(1, :) == MBDK_FORCE_SPRING_DAMPER .or. &
                                  fint(1, :) == MBDK_FORCE_COORDINATE .or. &
                                  fint(1, :) >= MBDK_FORCE_DAMPER)
      ! rheonomic rows: drivers, and distances and couplings that change in time
      model%has_drivers = any(jint(1, :) == MBDK_JOINT_DRIVER .or. ((jint(1, :) == &
                              MBDK_JOINT_DISTANCE .or. jint(1, :) == MBDK_JOINT_COUPLING) .and. &
                              (jreal(9, :) /= 0.0_dp .or. jreal(10, :) /= 0.0_dp)))
      allocate (model%pfaffian(model%m), stat=astat)
      call mbdk_alloc_status(astat, MBDK_INT_BYTES * model%m, stat, asked)
      if (stat /= MBDK_SUCCESS) return
      call mbdk_joints_pfaffian(jint, model%row0, model%pfaffian)
      model%has_pfaffian = any(model%pfaffian)
      do j = 1, size(fint, 2)
        if (fint(1, j) == MBDK_FORCE_POINT .or. ((fint(1, j) == MBDK_FORCE_DAMPER .or. &
            fint(1, j) == MBDK_FORCE_SPRING_DAMPER) .and. freal(7, j) /= 0.0_dp) .or. &
            (fint(1, j) == MBDK_FORCE_CONTACT .and. freal(9, j) /= 0.0_dp) .or. &
            fint(1, j) == MBDK_FORCE_FRICTION) &
          model%power_rot = .true.
      end do
    end associate
  end subroutine classify_elements

  !> The solver option against the model (schur, revolute and sparse need M positive) and the
  !> parameters the formulation divides by or iterates to (penalty alpha, projection tol).
  pure logical function solver_ok(model) result(ok)
    type(mbdk_model_t), intent(in) :: model
    ok = .false.
    if (model%solver < MBDK_SOLVER_AUTO .or. model%solver > MBDK_SOLVER_SPARSE) return
    if ((model%solver == MBDK_SOLVER_SCHUR .or. model%solver == MBDK_SOLVER_REVOLUTE .or. &
         model%solver == MBDK_SOLVER_SPARSE) .and. .not. model%m_positive) return
    if (model%formulation == MBDK_FORM_PENALTY .and. .not. (model%pen_alpha > 0.0_dp)) return
    if (model%formulation == MBDK_FORM_PROJECTION .and. .not. (model%proj_tol > 0.0_dp)) return
    ok = .true.
  end function solver_ok

  !> The constrained solves' structures: the patterns of D and S = D M^-1 D^T, the revolute
  !> closed form where the solver takes it (refused for other joints), the pivot blocks.
  subroutine choose_solver_path(model, stat, asked)
    type(mbdk_model_t), intent(inout) :: model
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: j, nj, nc, m, astat
    logical, allocatable :: nz(:, :)
    nj = size(model%jint, 2)
    nc = model%nc
    m = model%m
    allocate (model%col(MBDK_JOINT_SLOTS, m), nz(MBDK_JOINT_SLOTS, m), model%blk(nj + 1), &
              model%row_blk(nc + 1), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (2.0_dp * MBDK_JOINT_SLOTS * m + nj + nc + &
                                                    2), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_joints_pattern(model%jint, model%jreal, model%row0, model%col, nz)
    call mbdk_sparse_schur_init(model%sp, model%col, nz, model%winv, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INVALID_INPUT
    if (model%m > 0 .and. model%formulation /= MBDK_FORM_PENALTY .and. &
        (model%solver == MBDK_SOLVER_REVOLUTE .or. (model%solver == MBDK_SOLVER_AUTO .and. &
         model%m_positive .and. model%small_dense .and. model%m <= MBDK_SMALL_DENSE_MAX))) then
      call mbdk_revolute_schur_init(model%rs, model%jint, model%jreal, model%winv, &
                                    model%revolute, stat, asked)
      if (stat /= MBDK_SUCCESS) return
      stat = MBDK_ERR_INVALID_INPUT
      if (model%solver == MBDK_SOLVER_REVOLUTE .and. .not. model%revolute) return
    end if
    model%blk(1:nj) = model%row0
    model%blk(nj + 1) = m + 1
    do j = 1, nc + 1
      model%row_blk(j) = j
    end do
    stat = MBDK_SUCCESS
  end subroutine choose_solver_path

  !> The evaluations' buffers in work (dense D and M + ap D^T D for penalty only) and the
  !> constrained solves' objects: the evaluations' (weight M^-1), the projections' (winv).
  subroutine allocate_work(model, work, stat, asked)
    type(mbdk_model_t), intent(in) :: model
    type(mbdk_model_work_t), intent(inout) :: work
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nj, nc, m, astat
    nj = size(model%jint, 2)
    nc = model%nc
    m = model%m
    work%visits = 0
    if (allocated(work%fq)) deallocate (work%fq, work%phi, work%d, work%gam, work%phit, &
                                        work%rc, work%rot, work%dz, work%lam_rhs, work%xc, &
                                        work%pm, work%y_post, work%pp, work%zero_nc, &
                                        work%wres, work%wterm, work%wa, work%wlam)
    ! the dense D only where the penalty formulation builds its matrix from it (the KKT path
    ! keeps its own copy): a large scene has none
    if (model%formulation == MBDK_FORM_PENALTY) then
      allocate (work%d(m, nc), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * real(m, dp) * nc, stat, asked)
      if (stat /= MBDK_SUCCESS) return
    else
      allocate (work%d(0, 0), stat=astat)
      call mbdk_alloc_status(astat, 0.0_dp, stat, asked)
      if (stat /= MBDK_SUCCESS) return
    end if
    allocate (work%fq(nc), work%phi(m), work%gam(m), work%phit(m), work%rc(m), &
              work%rot(2, model%nb), work%dz(MBDK_JOINT_SLOTS, m), work%lam_rhs(m), &
              work%xc(nc), work%y_post(model%n), work%pp(2, 2 * nj), work%zero_nc(nc), &
              work%wres(m), work%wterm(m), work%wa(nc), work%wlam(m), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (4.0_dp * nc + real(m, dp) * &
                           (MBDK_JOINT_SLOTS + 9) + 2.0_dp * model%nb + model%n + 4.0_dp * nj), &
                           stat, asked)
    if (stat /= MBDK_SUCCESS) return
    work%zero_nc = 0.0_dp
    work%phit = 0.0_dp
    if (model%formulation == MBDK_FORM_PENALTY) then
      ! the penalty matrix M + ap D^T D is dense: a scene too large for it is refused by status
      allocate (work%pm(nc, nc), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * real(nc, dp) * nc, stat, asked)
      if (stat /= MBDK_SUCCESS) return
    else
      allocate (work%pm(0, 0), stat=astat)
      call mbdk_alloc_status(astat, 0.0_dp, stat, asked)
      if (stat /= MBDK_SUCCESS) return
    end if
    call mbdk_constrained_init(work%cs, nc, m, model%m_positive, &
                               model%solver == MBDK_SOLVER_KKT, model%small_dense, model%sp, &
                               sparse_choice(model%solver), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    ! the projections' weight winv is positive (M^-1, or the identity): always a Schur path;
    ! the same pattern, and its weights are the model's when M is (else the identity's)
    call mbdk_constrained_init(work%proj, nc, m, .true., .false., model%small_dense, model%sp, &
                               sparse_choice(model%solver), stat, asked)
  end subroutine allocate_work

  !> Gravity does not depend on (q, v, t): its generalised force is summed once (fconst, by
  !> mbdk_forces_eval itself) and an evaluation starts from it, visiting only the other
  !> elements (fint_v, freal_v, in table order). Contacts and friction go to a table of their
  !> own (fint_c, freal_c; mbdk_contact_forces_all), wear to eint, ereal: a scene without them
  !> visits none of their code. Friction and wear refer to columns, which are renumbered to
  !> fint_c's.
  subroutine split_forces(model, stat, asked)
    type(mbdk_model_t), intent(inout) :: model
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: e, nf, astat
    integer(i8) :: unused(MBDK_FORCE_TYPES)
    logical, allocatable :: grav(:)
    integer, allocatable :: idx(:)
    real(dp), allocatable :: rot(:, :), y0(:)
    integer, allocatable :: newcol(:)
    logical, allocatable :: visit(:), wear(:), cont(:)
    nf = size(model%fint, 2)
    allocate (rot(2, model%nb), y0(model%nc), newcol(nf), visit(nf), wear(nf), cont(nf), &
              model%fconst(model%nc), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (2.0_dp * model%nb + 2.0_dp * model%nc) + &
                           4 * MBDK_INT_BYTES * nf, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    grav = model%fint(1, :) == MBDK_FORCE_GRAVITY
    wear = model%fint(1, :) == MBDK_EFFECT_WEAR
    cont = model%fint(1, :) == MBDK_FORCE_CONTACT .or. model%fint(1, :) == MBDK_FORCE_FRICTION
    visit = .not. (grav .or. wear .or. cont)
    idx = [(e, e = 1, nf)]
    model%ngrav = count(grav)
    model%fint_v = model%fint(:, pack(idx, visit))
    model%freal_v = model%freal(:, pack(idx, visit))
    model%fint_c = model%fint(:, pack(idx, cont))
    model%freal_c = model%freal(:, pack(idx, cont))
    model%eint = model%fint(:, pack(idx, wear))
    model%ereal = model%freal(:, pack(idx, wear))
    newcol = 0
    newcol(pack(idx, cont)) = [(e, e = 1, count(cont))]
    do e = 1, size(model%fint_c, 2)
      if (model%fint_c(1, e) == MBDK_FORCE_FRICTION) &
        model%fint_c(4, e) = newcol(model%fint_c(4, e))
    end do
    do e = 1, model%ns
      model%eint(4, e) = newcol(model%eint(4, e))
    end do
    model%fconst = 0.0_dp
    rot = 0.0_dp
    y0 = 0.0_dp
    call mbdk_forces_eval(model%fint(:, pack(idx, grav)), model%freal(:, pack(idx, grav)), &
                          model%mass, rot, y0, y0, 0.0_dp, model%fconst, unused, stat)
  end subroutine split_forces

  !> The sparse argument of mbdk_constrained_path for a solver option: sparse always (solver
  !> sparse), by size (auto), never (schur, kkt, revolute).
  pure integer function sparse_choice(solver)
    integer, intent(in) :: solver
    sparse_choice = 0
    if (solver == MBDK_SOLVER_SPARSE) sparse_choice = 1
    if (solver == MBDK_SOLVER_AUTO) sparse_choice = -1
  end function sparse_choice

  !> Whether the model's large solves go sparse: 1 always, 0 never, -1 by size (above
  !> MBDK_SPARSE_MIN_ROWS constraint rows), from its solver option.
  pure integer function mbdk_model_sparse(self)
    class(mbdk_model_t), intent(in) :: self
    mbdk_model_sparse = sparse_choice(self%solver)
  end function mbdk_model_sparse

  !> A tolerance on |Phi| raised to the roundoff Phi carries at q: a joint's Phi is a difference
  !> of positions of size |q|, exact only to a few ulps of them (16 eps max |q|), so a scene far
  !> from the origin (a chain of 10^4 one-metre bars reaches 10^4 m) cannot meet 1e-12 m.
  pure real(dp) function mbdk_phi_floor(tol, q) result(t)
    real(dp), intent(in) :: tol, q(:)
    t = max(tol, 16.0_dp * epsilon(1.0_dp) * maxval(abs(q)))
  end function mbdk_phi_floor

  !> Which linear solve mbdk_model_accelerations takes (MBDK_SOLVE_*), as solve_constrained
  !> and the penalty branch decide it: for the manifest of a run.
  pure integer function mbdk_model_linear_solve(self) result(path)
    class(mbdk_model_t), intent(in) :: self
    if (self%m == 0) then
      path = MBDK_SOLVE_NONE
    else if (self%formulation == MBDK_FORM_PENALTY) then
      path = merge(MBDK_SOLVE_PENALTY_SMALL, MBDK_SOLVE_PENALTY_LAPACK, &
                   self%small_dense .and. self%nc <= MBDK_SMALL_DENSE_MAX)
    else if (self%revolute) then
      path = MBDK_SOLVE_REVOLUTE
    else
      path = mbdk_constrained_path(self%m, self%m_positive, self%solver == MBDK_SOLVER_KKT, &
                                   self%small_dense, sparse_choice(self%solver))
    end if
  end function mbdk_model_linear_solve

  !> Phi, the dense D (m x nc, when d is present), gamma, Phi_t at (q, v, t). Leaves work%rot
  !> and work%dz (D in compact rows) at q (work%rot also when there are no constraints).
  subroutine mbdk_model_constraints(self, t, q, v, phi, d, gam, phit)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: q(:), v(:)
    real(dp), intent(out), contiguous :: phi(:), gam(:), phit(:)
    real(dp), intent(out), contiguous, optional :: d(:, :)
    call mbdk_body_rotations(q, self%work%rot)
    if (self%m == 0) return
    call mbdk_joints_eval(self%jint, self%jreal, self%row0, self%work%rot, q, v, t, phi, &
                          self%work%dz, gam, phit, self%work%visits(1:MBDK_JOINT_TYPES))
    if (present(d)) call mbdk_joints_scatter(self%col, self%work%dz, d)
  end subroutine mbdk_model_constraints

  !> One evaluation's assembly at (t, q, v) into the work buffers: rot (one sin/cos pair per
  !> body), fq, and phi, dz (D in compact rows), gam, phit; on the revolute path phi, gam, pp
  !> (the joint points' perp(rho)) and rc (the right-hand side of D a = rc) instead of dz and
  !> phit. Non-finite q or v:
  !> MBDK_ERR_NONFINITE; a force element's failure is passed on.
  subroutine mbdk_model_assemble(self, t, q, v, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: q(:), v(:)
    integer, intent(out) :: stat
    if (.not. (all(abs(q) <= huge(1.0_dp)) .and. all(abs(v) <= huge(1.0_dp)))) then
      stat = MBDK_ERR_NONFINITE
      return
    end if
    associate (w => self%work)
      call mbdk_body_rotations(q, w%rot)
      w%fq = self%fconst
      w%visits(MBDK_JOINT_TYPES + MBDK_FORCE_GRAVITY) = &
        w%visits(MBDK_JOINT_TYPES + MBDK_FORCE_GRAVITY) + self%ngrav
      stat = MBDK_SUCCESS
      if (size(self%fint_v, 2) > 0) &
        call mbdk_forces_eval(self%fint_v, self%freal_v, self%mass, w%rot, q, v, t, w%fq, &
                              w%visits(MBDK_JOINT_TYPES + 1:), stat)
      if (stat /= MBDK_SUCCESS) return
      if (self%has_contacts) then
        call mbdk_contact_forces_all(self%fint_c, self%freal_c, w%rot, q, v, w%fq, &
                                     w%visits(MBDK_JOINT_TYPES + 1:), stat)
        if (stat /= MBDK_SUCCESS) return
      end if
      if (self%m == 0) return
      if (self%revolute) then
        w%visits(MBDK_JOINT_REVOLUTE) = w%visits(MBDK_JOINT_REVOLUTE) + self%rs%nj
        if (self%formulation == MBDK_FORM_BAUMGARTE) then
          call mbdk_revolute_kinematics(self%rs, w%rot, q, v, 2.0_dp * self%alpha, &
                                        self%beta**2, w%pp, w%phi, w%gam, w%rc)
        else
          call mbdk_revolute_kinematics(self%rs, w%rot, q, v, 0.0_dp, 0.0_dp, w%pp, w%phi, &
                                        w%gam, w%rc)
        end if
        return
      end if
      call mbdk_joints_eval(self%jint, self%jreal, self%row0, w%rot, q, v, t, w%phi, w%dz, &
                            w%gam, w%phit, w%visits(1:MBDK_JOINT_TYPES))
    end associate
  end subroutine mbdk_model_assemble

  subroutine model_rhs(self, t, y, f, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    real(dp), intent(out), contiguous :: f(:)
    integer, intent(out) :: stat
    integer :: nc, i
    ! a scene with effects takes a routine of its own, called through the type (not inlined):
    ! with their code after the solve here, every scene's evaluation would keep registers
    ! across the solve, and the plain path has to end in it (so the solve below repeats there)
    if (self%ns > 0) then
      call self%rhs_effects(t, y, f, stat)
      return
    end if
    nc = self%nc
    ! y and f contiguous (mbdk_problem): the accelerations are written into f in place
    ! the reduced formulation refuses a near rank loss of D (see MBDK_MODEL_NEAR_PIVOT)
    if (self%formulation == MBDK_FORM_REDUCED) then
      call mbdk_model_accelerations(self, t, y(1:nc), y(nc + 1:2 * nc), f(nc + 1:2 * nc), &
                                    self%work%lam_rhs, stat, MBDK_MODEL_NEAR_PIVOT)
    else
      call mbdk_model_accelerations(self, t, y(1:nc), y(nc + 1:2 * nc), f(nc + 1:2 * nc), &
                                    self%work%lam_rhs, stat)
    end if
    do i = 1, nc
      f(i) = y(nc + i)
    end do
  end subroutine model_rhs

  !> Whether the pose of y = [q; v] lies within MBDK_RANK_LOSS_WINDOW of a rank loss of the rows
  !> (mbdk_rank_margin): D at q with a body's rotation column weighted by 1/reach^2
  !> (body_reach; the largest body's where it has none). The joints' visit counts and the
  !> model's buffers are left as they were. (A scene whose rows are dependent at every pose,
  !> redundant joints, never gets here: the DAE forms refuse it at the start.)
  logical function model_near_rank_loss(self, t, y, rows) result(near)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    integer, intent(in) :: rows(:)
    real(dp), allocatable :: rot(:, :), dz(:, :), phi(:), gam(:), phit(:), d(:, :), w(:), &
      v0(:), reach(:)
    integer(i8) :: visits(MBDK_JOINT_TYPES)
    real(dp) :: big
    integer :: nc, b, st
    near = .false.
    nc = self%nc
    if (size(rows) == 0 .or. size(rows) > MBDK_RANK_LOSS_MAX_ROWS .or. size(y) < nc) return
    allocate (rot, mold=self%work%rot, stat=st)
    if (st == 0) allocate (dz, mold=self%work%dz, stat=st)
    if (st == 0) allocate (phi(self%m), gam(self%m), phit(self%m), d(self%m, nc), w(nc), &
                           v0(nc), stat=st)
    if (st /= 0) return
    v0 = 0.0_dp
    visits = 0
    call mbdk_body_rotations(y(1:nc), rot)
    call mbdk_joints_eval(self%jint, self%jreal, self%row0, rot, y(1:nc), v0, t, phi, dz, gam, &
                          phit, visits)
    call mbdk_joints_scatter(self%col, dz, d)
    reach = body_reach(self)
    big = max(0.0_dp, maxval(reach))
    if (.not. (big > 0.0_dp)) big = 1.0_dp
    w = 1.0_dp
    do b = 1, self%nb
      if (.not. (reach(b) > 0.0_dp)) reach(b) = big
      w(3 * b) = 1.0_dp / reach(b)**2
    end do
    near = mbdk_near_rank_loss(d(rows, :), w, MBDK_RANK_LOSS_WINDOW)
  end function model_near_rank_loss

  !> Each body's reach: the largest distance from its centre of the points its joints hold it
  !> at (a driver's and a coupling's reals are no points, nor a rolling disc's first two: its
  !> radius stands for them). 0 for a body no joint point is on.
  pure function body_reach(self) result(reach)
    class(mbdk_model_t), intent(in) :: self
    real(dp) :: reach(self%nb)
    integer :: j, typ, b1, b2
    reach = 0.0_dp
    do j = 1, size(self%jint, 2)
      typ = self%jint(1, j)
      if (typ == MBDK_JOINT_DRIVER .or. typ == MBDK_JOINT_COUPLING) cycle
      b1 = self%jint(2, j)
      b2 = self%jint(3, j)
      if (b1 > 0 .and. typ /= MBDK_JOINT_ROLLING) reach(b1) = max(reach(b1), &
                                                                  norm2(self%jreal(1:2, j)))
      if (b1 > 0 .and. typ == MBDK_JOINT_ROLLING) reach(b1) = max(reach(b1), self%jreal(7, j))
      if (b2 > 0) reach(b2) = max(reach(b2), norm2(self%jreal(3:4, j)))
    end do
  end function body_reach

  !> model_rhs of a scene with effects: the accelerations, then the effects' rates
  !> f(2 nc + 1:), after the evaluation has left work%rot at q.
  subroutine rhs_with_effects(self, t, y, f, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    real(dp), intent(inout), contiguous :: f(:)
    integer, intent(out) :: stat
    integer :: nc
    nc = self%nc
    if (self%formulation == MBDK_FORM_REDUCED) then
      call mbdk_model_accelerations(self, t, y(1:nc), y(nc + 1:2 * nc), f(nc + 1:2 * nc), &
                                    self%work%lam_rhs, stat, MBDK_MODEL_NEAR_PIVOT)
    else
      call mbdk_model_accelerations(self, t, y(1:nc), y(nc + 1:2 * nc), f(nc + 1:2 * nc), &
                                    self%work%lam_rhs, stat)
    end if
    f(1:nc) = y(nc + 1:2 * nc)
    if (stat /= MBDK_SUCCESS) return
    self%work%visits(MBDK_JOINT_TYPES + MBDK_EFFECT_WEAR) = &
      self%work%visits(MBDK_JOINT_TYPES + MBDK_EFFECT_WEAR) + self%ns
    call mbdk_wear_rates(self%eint, self%ereal, self%fint_c, self%freal_c, self%work%rot, &
                         y(1:nc), y(nc + 1:2 * nc), t, f(2 * nc + 1:), stat)
  end subroutine rhs_with_effects


  !> Accelerations a and multipliers lam at (t, q, v) by the model's formulation. lam may be
  !> self%work%lam_rhs; no argument may alias the other work buffers. near: the relative pivot
  !> of D M^-1 D^T below which the solve counts as singular (default and floor SINGULAR_TOL).
  subroutine mbdk_model_accelerations(self, t, q, v, a, lam, stat, near)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: q(:), v(:)
    real(dp), intent(out), contiguous :: a(:), lam(:)
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: near
    integer :: nc, m, i, k, r
    real(dp) :: w2, tmu, x, tol

    nc = self%nc
    m = self%m
    tol = SINGULAR_TOL
    if (present(near)) tol = max(tol, near)
    call mbdk_model_assemble(self, t, q, v, stat)
    if (stat /= MBDK_SUCCESS) return
    associate (w => self%work)
      if (m == 0) then
        if (.not. self%m_positive) then
          stat = MBDK_ERR_SINGULAR_MATRIX
          return
        end if
        a = w%fq * self%winv
        return
      end if
      if (self%revolute) then   ! rc from mbdk_model_assemble
        call mbdk_revolute_solve(self%rs, nc, w%pp, w%fq, self%winv, w%rc, w%cs%s, tol, &
                                 a, lam, stat)
        if (stat == MBDK_ERR_SINGULAR_MATRIX .and. passes_rank_loss()) then
          ! the closed form has no D in compact rows: the general joints' evaluation gives it
          call mbdk_joints_eval(self%jint, self%jreal, self%row0, w%rot, q, v, t, w%phi, &
                                w%dz, w%gam, w%phit, w%visits(1:MBDK_JOINT_TYPES))
          call stabilised_rc()
          call regular_solve()
        end if
        return
      end if
      select case (self%formulation)
      case (MBDK_FORM_REDUCED, MBDK_FORM_PROJECTION)
        w%rc = w%gam
      case (MBDK_FORM_BAUMGARTE)
        call mbdk_sparse_d_times(self%sp, w%dz, v, w%rc, .false.)
        w%rc = w%gam - 2.0_dp * self%alpha * (w%rc + w%phit) - self%beta**2 * w%phi
      case (MBDK_FORM_PENALTY)
        call mbdk_joints_scatter(self%col, w%dz, w%d)
        w2 = self%pen_omega**2
        tmu = 2.0_dp * self%pen_mu * self%pen_omega
        do r = 1, m
          x = w%phit(r)
          do k = 1, nc
            x = x + w%d(r, k) * v(k)
          end do
          w%rc(r) = -w%gam(r) + tmu * x + w2 * w%phi(r)
        end do
        do k = 1, nc
          a(k) = w%fq(k) - self%pen_alpha * dot_product(w%rc, w%d(:, k))
          do i = k, nc
            w%pm(i, k) = self%pen_alpha * dot_product(w%d(:, i), w%d(:, k))
            w%pm(k, i) = w%pm(i, k)
          end do
          w%pm(k, k) = w%pm(k, k) + self%mass(k)
        end do
        if (self%small_dense .and. nc <= MBDK_SMALL_DENSE_MAX) then
          call mbdk_small_ldlt_solve_once(w%pm, nc, self%row_blk, 1.0e-15_dp, a, stat)
        else
          call mbdk_chol_factor(w%pm, stat)
          if (stat == MBDK_SUCCESS) call mbdk_chol_solve(w%pm, a, stat)
        end if
        if (stat /= MBDK_SUCCESS) return
        do r = 1, m
          lam(r) = self%pen_alpha * (dot_product(w%d(r, :), a) + w%rc(r))
        end do
        return
      end select
      call solve_constrained(self, w, a, lam, stat, tol)
      if (stat == MBDK_ERR_SINGULAR_MATRIX .and. passes_rank_loss()) call regular_solve()
    end associate

  contains

    !> Where D has lost a rank (a singular pose, dependent rows) the accelerations are still
    !> defined when gamma is consistent, the multipliers are not unique: the formulations that
    !> keep the constraints through such a pose (baumgarte and projection: their stabilisation
    !> or projection restores what the stage's solve cannot meet) take the regular path of
    !> mbdk_constrained there, so that an explicit method's stage landing on the rank loss does
    !> not end the run. The reduced formulation refuses it (MBDK_MODEL_NEAR_PIVOT), as does a
    !> caller asking for a near-singular test (near).
    logical function passes_rank_loss()
      passes_rank_loss = .not. present(near) .and. &
        (self%formulation == MBDK_FORM_PROJECTION .or. self%formulation == MBDK_FORM_BAUMGARTE)
    end function passes_rank_loss

    !> rc of the general path (w%dz, w%gam, w%phit, w%phi current): gamma, or Baumgarte's
    subroutine stabilised_rc()
      associate (w => self%work)
        w%rc = w%gam
        if (self%formulation == MBDK_FORM_BAUMGARTE) then
          call mbdk_sparse_d_times(self%sp, w%dz, v, w%rc, .false.)
          w%rc = w%gam - 2.0_dp * self%alpha * (w%rc + w%phit) - self%beta**2 * w%phi
        end if
      end associate
    end subroutine stabilised_rc

    subroutine regular_solve()
      associate (w => self%work)
        call mbdk_constrained_factor(w%cs, self%sp, w%dz, self%col, self%blk, self%mass, &
                                     stat, regular=.true.)
        if (stat == MBDK_SUCCESS) &
          call mbdk_constrained_solve(w%cs, self%sp, w%dz, self%blk, self%winv, w%fq, w%rc, &
                                      a, lam, stat)
      end associate
    end subroutine regular_solve

  end subroutine mbdk_model_accelerations

  !> M a + D^T lam = fq, D a = rc (from w): the model's constrained solve (mbdk_constrained:
  !> Schur complement, assembled sparse, when M is positive and not forced to KKT; KKT LU).
  subroutine solve_constrained(self, w, a, lam, stat, tol)
    class(mbdk_model_t), intent(in) :: self
    type(mbdk_model_work_t), intent(inout) :: w
    real(dp), intent(out), contiguous :: a(:), lam(:)
    integer, intent(out) :: stat
    real(dp), intent(in) :: tol
    call mbdk_constrained_solve_once(w%cs, self%sp, w%dz, self%col, self%blk, self%mass, &
                                     self%winv, w%fq, w%rc, a, lam, stat, tol)
  end subroutine solve_constrained

  !> Projection after a step: q onto Phi(q, t) = 0 by Gauss-Newton with the weight W (M^-1, or
  !> the identity when a body has zero inertia), then v onto D v + Phi_t = 0; each correction
  !> is -W D^T S^-1 r with S = D W D^T from the nonzeros of D (mbdk_sparse_schur). A knife
  !> edge's row (Phi = 0) stays in S with its residual 0: the positions' correction is the least
  !> one that moves as the blades allow (A dq = 0), which after a step's drift differs from the
  !> least change onto Phi = 0 by the order of that drift; the velocities' keeps A v = 0.
  subroutine model_post_step(self, t, y, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: y(:)
    integer, intent(out) :: stat
    integer :: nc, m, it

    nc = self%nc
    m = self%m
    stat = MBDK_SUCCESS
    ! on a contiguous copy (y may be strided), returned only when both projections succeed
    associate (w => self%work, yc => self%work%y_post)
      yc = y
      do it = 0, self%proj_max_iter
        call mbdk_model_constraints(self, t, yc(1:nc), yc(nc + 1:2 * nc), w%phi, gam=w%gam, &
                                    phit=w%phit)
        if (it > 0 .and. maxval(abs(w%phi)) <= mbdk_phi_floor(self%proj_tol, yc(1:nc))) exit
        if (it == self%proj_max_iter) then
          stat = MBDK_ERR_NEWTON_DIVERGED
          return
        end if
        w%rc = w%phi
        call correct(stat)
        if (stat /= MBDK_SUCCESS) return
        yc(1:nc) = yc(1:nc) + w%xc
        if (it == 0 .and. maxval(abs(w%phi)) <= mbdk_phi_floor(self%proj_tol, yc(1:nc))) exit
      end do
      call mbdk_model_constraints(self, t, yc(1:nc), yc(nc + 1:2 * nc), w%phi, gam=w%gam, &
                                  phit=w%phit)
      w%xc = yc(nc + 1:2 * nc)
      call mbdk_sparse_d_times(self%sp, w%dz, w%xc, w%rc, .false.)
      w%rc = w%rc + w%phit
      call correct(stat)
      if (stat /= MBDK_SUCCESS) return
      yc(nc + 1:2 * nc) = yc(nc + 1:2 * nc) + w%xc
      y = yc
    end associate

  contains

    !> xc = -W D^T S^-1 rc at the current compact rows: the least change (W^-1 norm) that
    !> moves D x by -rc (mbdk_constrained with b = 0, c = -rc)
    subroutine correct(st)
      integer, intent(out) :: st
      associate (w => self%work)
        w%rc = -w%rc
        call mbdk_constrained_solve_once(w%proj, self%sp, w%dz, self%col, self%blk, self%mass, &
                                         self%winv, w%zero_nc, w%rc, w%xc, w%lam_rhs, st)
      end associate
    end subroutine correct

  end subroutine model_post_step

  !> What a run samples at (t, y), as far as want (MBDK_OUT_* bits) asks: accelerations a(nc),
  !> multipliers lam(m), reac(3, nj) = the force (x, y) and the moment about the joint point that
  !> each joint exerts on its first body, global frame (-D_body1^T lam), energy(6) = kinetic,
  !> gravity potential, spring potential, damper power (dissipated), constraint power (-lam . D v:
  !> the work rate of the constraint forces, nonzero only through drift, stabilisation and
  !> drivers), load power; resid(3) = max |Phi|, max |D v + Phi_t|, max |D a - gamma| (gamma of
  !> the reduced form). With given = .true., a and lam are inputs (an integrator's own, as
  !> trapezoidal_index3 produces them) and are not recomputed; otherwise they are computed by the
  !> model's formulation when anything asked for needs them. Arrays not asked for are untouched.
  subroutine mbdk_model_outputs(self, t, y, given, want, a, lam, reac, energy, resid, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: given
    integer, intent(in) :: want
    real(dp), intent(inout) :: a(:), lam(:), reac(:, :), energy(MBDK_ENERGY_PARTS), &
      resid(MBDK_RESIDUALS)
    integer, intent(out) :: stat
    integer :: nc, m, j, r, k, b1, c, i
    real(dp), allocatable :: phi(:), gam(:), phit(:), dx(:)
    real(dp) :: p(2), rho(2), pv(2), w, qf(3)
    logical :: need_a, need_d

    nc = self%nc
    m = self%m
    stat = MBDK_SUCCESS
    associate (q => y(1:nc), v => y(nc + 1:2 * nc))
    need_a = iand(want, MBDK_OUT_ACCELERATIONS + MBDK_OUT_MULTIPLIERS + MBDK_OUT_REACTIONS) /= 0 &
      .or. (m > 0 .and. iand(want, MBDK_OUT_ENERGY + MBDK_OUT_RESIDUALS) /= 0)
    if (need_a .and. .not. given) then
      call mbdk_model_accelerations(self, t, q, v, a, lam, stat)
      if (stat /= MBDK_SUCCESS) return
    end if
    ! D stays in its compact rows (work%dz): products with it cost O(nnz), whatever the size
    need_d = m > 0 .and. iand(want, MBDK_OUT_REACTIONS + MBDK_OUT_ENERGY + MBDK_OUT_RESIDUALS) /= 0
    allocate (phi(m), gam(m), phit(m), dx(m), stat=i)
    call mbdk_alloc_status(i, 4 * MBDK_REAL_BYTES * m, stat)
    if (stat /= MBDK_SUCCESS) return
    if (need_d) call mbdk_model_constraints(self, t, q, v, phi, gam=gam, phit=phit)
    if (iand(want, MBDK_OUT_ENERGY) /= 0) then
      energy(1) = 0.5_dp * sum(self%mass * v**2)
      call mbdk_body_rotations(q, self%work%rot)
      call mbdk_forces_energy(self%fint, self%freal, self%mass, self%work%rot, q, v, t, &
                              energy(2), energy(3), energy(4), energy(6))
      energy(5) = 0.0_dp
      if (m > 0) then
        call mbdk_sparse_d_times(self%sp, self%work%dz, v, dx, .false.)
        energy(5) = -dot_product(lam, dx)
      end if
    end if
    if (iand(want, MBDK_OUT_RESIDUALS) /= 0) then
      resid = 0.0_dp
      if (m > 0) then
        resid(1) = maxval(abs(phi))
        call mbdk_sparse_d_times(self%sp, self%work%dz, v, dx, .false.)
        resid(2) = maxval(abs(dx + phit))
        call mbdk_sparse_d_times(self%sp, self%work%dz, a, dx, .false.)
        resid(3) = maxval(abs(dx - gam))
      end if
    end if
    if (iand(want, MBDK_OUT_REACTIONS) == 0) return
    reac = 0.0_dp
    if (m == 0) return
    call mbdk_body_rotations(q, self%work%rot)
    do j = 1, size(self%jint, 2)
      r = self%row0(j)
      k = mbdk_joint_rows(self%jint(1, j))
      b1 = self%jint(2, j)
      ! -D_body1^T lam: slots 1..3 of a compact row are body1's (x, y, theta), 4..6 body2's,
      ! which add up when both ends are the same body (as D's columns do)
      do c = 1, 3
        qf(c) = 0.0_dp
        do i = r, r + k - 1
          qf(c) = qf(c) - self%work%dz(c, i) * lam(i)
          if (self%jint(3, j) == b1) qf(c) = qf(c) - self%work%dz(c + 3, i) * lam(i)
        end do
      end do
      ! about the joint point; a driver's or coupling's moment about the centroid (their reals
      ! are no points), a rolling disc's about its centre, the centroid
      rho = 0.0_dp
      if (self%jint(1, j) /= MBDK_JOINT_DRIVER .and. self%jint(1, j) /= MBDK_JOINT_COUPLING &
          .and. self%jint(1, j) /= MBDK_JOINT_ROLLING) &
        call mbdk_body_point(b1, self%jreal(1:2, j), self%work%rot, q, v, p, rho, pv, w)
      reac(1:2, j) = qf(1:2)
      reac(3, j) = qf(3) - (rho(1) * qf(2) - rho(2) * qf(1))
    end do
    end associate
  end subroutine mbdk_model_outputs

  !> The events of a scene, two per contact (not gear meshes) in table order, as spatial
  !> contacts have them (mbdk_contact3d_events): the law's event function (mbdk_contact_event),
  !> the normal force before its clip while the contact touches, extended continuously where it
  !> does not, which changes sign where the contact closes and where it lets go; and the parting
  !> one (mbdk_contact_parting), where its surfaces part. Between letting go and parting a damped
  !> contact dissipates its potential, a power whose kink at the parting a step of the flight
  !> would otherwise hold, and the watch's quadrature of the work would miss a part in a
  !> thousand of each bounce's loss.
  subroutine model_events(self, t, y, g, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: g(:)
    integer, intent(out) :: stat
    integer :: e, k, nc
    type(mbdk_contact_t) :: ct
    logical :: ok
    nc = self%nc
    stat = MBDK_SUCCESS
    call mbdk_body_rotations(y(1:nc), self%work%rot)
    k = 0
    do e = 1, size(self%fint_c, 2)
      if (self%fint_c(1, e) /= MBDK_FORCE_CONTACT .or. &
          self%fint_c(4, e) == MBDK_CONTACT_GEAR) cycle
      k = k + 1
      call mbdk_contact_eval(self%fint_c(:, e), self%freal_c(:, e), self%work%rot, y(1:nc), &
                             y(nc + 1:2 * nc), ct, ok)
      if (.not. ok) then     ! no normal: the evaluation itself reports it
        g(2 * k - 1:2 * k) = ct%delta
      else
        g(2 * k - 1) = mbdk_contact_event(ct%delta, ct%unclipped, self%freal_c(7:10, e))
        g(2 * k) = mbdk_contact_parting(ct%delta, ct%rate)
      end if
    end do
  end subroutine model_events

  subroutine model_watch_start(self, t, y, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    integer, intent(out) :: stat
    call mbdk_model_watch_start(self, t, y(1:self%nc), y(self%nc + 1:2 * self%nc), stat)
  end subroutine model_watch_start

  subroutine model_watch(self, t, y, force, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    call mbdk_model_watch(self, t, y(1:self%nc), y(self%nc + 1:2 * self%nc), force, stat)
  end subroutine model_watch

  !> Whether the watch integrates a work the run reports (mbdk_watch_nodes: the states inside a
  !> step serve it; the energy test alone takes the trapezoidal rule).
  logical function model_wants_nodes(self)
    class(mbdk_model_t), intent(in) :: self
    model_wants_nodes = .false.
    if (self%has_watch) model_wants_nodes = self%work%watch%power .and. self%work%watch%record
  end function model_wants_nodes

  subroutine model_watch_nodes(self, t_a, t_b, y, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t_a, t_b, y(:, :)
    integer, intent(out) :: stat
    call mbdk_model_watch_nodes(self, t_a, t_b, y(1:self%nc, :), &
                                y(self%nc + 1:2 * self%nc, :), stat)
  end subroutine model_watch_nodes

  !> The powers of the work parts at the states (q(:, k), v(:, k)) of the accepted step
  !> [t_a, t_b] at its Gauss nodes (MBDK_GAUSS3), for the watch's integral over the step
  !> (mbdk_watch_nodes). lam(:, k): the integrator's own multipliers there (a DAE form's);
  !> otherwise a driven scene's come from a constrained solve at each node.
  subroutine mbdk_model_watch_nodes(self, t_a, t_b, q, v, stat, lam)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t_a, t_b, q(:, :), v(:, :)
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: lam(:, :)
    real(dp) :: kin, vg, vs, p(MBDK_WORK_PARTS, 3), tn(3)
    integer :: k
    stat = MBDK_SUCCESS
    if (.not. self%has_watch) return
    if (.not. self%work%watch%power) return
    tn = t_a + MBDK_GAUSS3 * (t_b - t_a)
    do k = 1, 3
      if (present(lam)) then
        call watch_quantities(self, tn(k), q(:, k), v(:, k), .true., .true., kin, vg, vs, &
                              p(:, k), stat, lam(:, k))
      else
        call watch_quantities(self, tn(k), q(:, k), v(:, k), .true., .true., kin, vg, vs, &
                              p(:, k), stat)
      end if
      if (stat /= MBDK_SUCCESS) return
    end do
    call mbdk_watch_nodes(self%work%watch, t_a, t_b, tn, p)
  end subroutine mbdk_model_watch_nodes

  !> Starts the watch (mbdk_watch) at the initial state: the length scale L, which rows are
  !> angles, whether the energy balance has power terms, the energies at t0, the momenta the
  !> scene conserves. velocity = .false.: the integrator does not promise the velocity
  !> constraints (the book's index-3 scheme, whose velocities are the trapezoidal rule's on q),
  !> so they are not tested.
  subroutine mbdk_model_watch_start(self, t, q, v, stat, velocity)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t, q(:), v(:)
    integer, intent(out) :: stat
    logical, intent(in), optional :: velocity
    logical, allocatable :: angular(:)
    logical :: power, ok
    real(dp) :: length, reach, kin, vg, vs, p(MBDK_WORK_PARTS), gscale, rmean(2), tol_v, &
      mom(6), msc(2)
    integer :: j, e, r, typ, b, nb, astat
    type(mbdk_contact_t) :: ct
    stat = MBDK_SUCCESS
    if (.not. self%has_watch) return
    allocate (angular(self%m), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * self%m, stat)
    if (stat /= MBDK_SUCCESS) return
    nb = self%nb
    length = 0.0_dp
    power = .false.
    length = max(0.0_dp, maxval(body_reach(self)))
    do j = 1, size(self%jint, 2)
      typ = self%jint(1, j)
      r = self%row0(j)
      select case (typ)
      case (MBDK_JOINT_REVOLUTE)
        angular(r:r + 1) = .false.
      case (MBDK_JOINT_PRISMATIC)
        angular(r) = .true.
        angular(r + 1) = .false.
      case (MBDK_JOINT_FIXED)
        angular(r:r + 1) = .false.
        angular(r + 2) = .true.
      case (MBDK_JOINT_DISTANCE)
        angular(r) = .false.
        if (self%jreal(9, j) /= 0.0_dp .or. self%jreal(10, j) /= 0.0_dp) power = .true.
      case (MBDK_JOINT_POINT_LINE, MBDK_JOINT_POINT_CURVE, MBDK_JOINT_KNIFE_EDGE)
        angular(r) = .false.
      case (MBDK_JOINT_ROLLING)
        angular(r:r + 1) = .false.
      case (MBDK_JOINT_COUPLING)
        ! in the unit of body 2's coordinate (radians for gears, metres for a rack)
        angular(r) = self%jreal(6, j) /= 0.0_dp .or. (self%jint(3, j) == 0 .and. &
                                                    self%jreal(3, j) /= 0.0_dp)
        if (self%jreal(9, j) /= 0.0_dp .or. self%jreal(10, j) /= 0.0_dp) power = .true.
      case default   ! a driver: of x, y or theta
        angular(r) = self%jint(4, j) == 3
        power = .true.
      end select
    end do
    gscale = 0.0_dp
    do e = 1, size(self%fint, 2)
      select case (self%fint(1, e))
      case (MBDK_FORCE_GRAVITY)
        gscale = gscale + norm2(self%freal(1:2, e))
      case (MBDK_FORCE_POINT, MBDK_FORCE_TORQUE)
        power = .true.
        if (self%fint(1, e) == MBDK_FORCE_POINT) length = max(length, norm2(self%freal(1:2, e)))
      case (MBDK_FORCE_SPRING, MBDK_FORCE_DAMPER, MBDK_FORCE_SPRING_DAMPER)
        if (self%fint(2, e) > 0) length = max(length, norm2(self%freal(1:2, e)))
        if (self%fint(3, e) > 0) length = max(length, norm2(self%freal(3:4, e)))
        if (self%freal(7, e) /= 0.0_dp) power = .true.
      case (MBDK_FORCE_COORDINATE)
        if (self%freal(2, e) /= 0.0_dp) power = .true.
      case (MBDK_FORCE_CONTACT)
        if (self%freal(9, e) /= 0.0_dp) power = .true.
      case (MBDK_FORCE_FRICTION)
        power = .true.
      end select
    end do
    ! the spread of the bodies: twice the largest distance from their mean position
    rmean = [sum(q(self%qoff(:))), sum(q(self%qoff(:) + 1))] / nb
    do b = 1, nb
      length = max(length, 2.0_dp * norm2(q(self%qoff(b):self%qoff(b) + 1) - rmean))
    end do
    ! what gravity can move the bodies by (mbdk_watch): the mechanism's length, each contact's
    ! initial gap, each body's radius of gyration; the fallback below, a length the scene may
    ! not have (1 m, or the distance from the origin), serves the position rows only
    reach = length
    do b = 1, nb
      reach = max(reach, sqrt(self%mass(self%qoff(b) + 2) / self%mass(self%qoff(b))))
    end do
    call mbdk_body_rotations(q, self%work%rot)
    do e = 1, size(self%fint, 2)
      if (self%fint(1, e) /= MBDK_FORCE_CONTACT .or. self%fint(4, e) == MBDK_CONTACT_GEAR) cycle
      call mbdk_contact_eval(self%fint(:, e), self%freal(:, e), self%work%rot, q, v, ct, ok)
      if (ok .and. -ct%delta <= huge(1.0_dp)) reach = max(reach, -ct%delta)
    end do
    if (.not. (length > 0.0_dp)) length = max(norm2(rmean), 1.0_dp)
    gscale = gscale * sum(self%mass(self%qoff(:))) * reach
    call watch_quantities(self, t, q, v, power, .false., kin, vg, vs, p, stat)
    if (stat /= MBDK_SUCCESS) return
    tol_v = self%watch_tol(2)
    if (present(velocity)) then
      if (.not. velocity) tol_v = 0.0_dp
    end if
    call mbdk_watch_start(self%work%watch, self%watch_tol(1), tol_v, self%watch_tol(3), &
                          self%watch_every, power, length, angular, t, kin, vg, vs, p, gscale, &
                          sum(self%mass(self%qoff(:))), stat, self%record_work)
    if (stat /= MBDK_SUCCESS) return
    if (self%ninv > 0 .and. self%watch_tol(4) > 0.0_dp) then
      call planar_momenta(self, q, v, mom, msc)
      call mbdk_watch_start_invariants(self%work%watch, self%watch_tol(4), self%inv, self%ninv, &
                                       mom, msc, 0.0_dp, 0)
    end if
  end subroutine mbdk_model_watch_start

  !> The watch after an accepted step at (t, q, v): when a check is due (every watch_every
  !> steps, force, or every step with power terms), the constraint residuals, the energy
  !> balance and the conserved momenta against their tolerances. MBDK_ERR_CONSTRAINT_DRIFT,
  !> MBDK_ERR_ENERGY_DRIFT or MBDK_ERR_INVARIANT_DRIFT with the report in work%watch.
  !> The drivers' power needs the multipliers at (t, q, v). lam: the integrator's own, exact
  !> at the state (trapezoidal_index3's projected form). Otherwise a step that only owes its
  !> power takes those of the model's last evaluation (an ODE method's last stage, within
  !> O(h^2) of the state: the order of the trapezoidal rule that integrates the power) instead
  !> of a constrained solve per step, unless solve_lam (an integrator that does not evaluate
  !> the model's accelerations, or whose multipliers are not accurate: the book's scheme);
  !> checks always solve.
  subroutine mbdk_model_watch(self, t, q, v, force, stat, lam, solve_lam)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t, q(:), v(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: lam(:)
    logical, intent(in), optional :: solve_lam
    real(dp) :: kin, vg, vs, p(MBDK_WORK_PARTS), g, mom(6), msc(2)
    integer :: due
    logical :: reuse
    stat = MBDK_SUCCESS
    if (.not. self%has_watch) return
    due = mbdk_watch_due(self%work%watch, force)
    if (due == MBDK_WATCH_NOTHING) return
    reuse = due == MBDK_WATCH_POWER_ONLY
    if (present(solve_lam)) reuse = reuse .and. .not. solve_lam
    call watch_quantities(self, t, q, v, self%work%watch%power, due == MBDK_WATCH_POWER_ONLY, &
                          kin, vg, vs, p, stat, lam, reuse, g)
    if (stat /= MBDK_SUCCESS) return
    associate (w => self%work)
      if (due == MBDK_WATCH_POWER_ONLY) then
        call mbdk_watch_power(w%watch, t, p, g)
      else if (w%watch%ninv > 0) then
        call planar_momenta(self, q, v, mom, msc)
        call mbdk_watch_test(w%watch, t, w%phi, w%wres, w%wterm, kin, vg, vs, p, stat, g, &
                             mom, msc)
      else
        call mbdk_watch_test(w%watch, t, w%phi, w%wres, w%wterm, kin, vg, vs, p, stat, g)
      end if
    end associate
  end subroutine mbdk_model_watch

  !> The momentum p = sum m_b v_b and the angular momentum H = sum (r_b - c) x m_b v_b +
  !> I_b w_b (along z; mom = (p, H) as 3-vectors) about the point of the scene's conserved
  !> components (mbdk_inv_result: a fixed point, or the centre of mass c), and their scales
  !> msc = (sum m_b |v_b|, sum |r_b - c| m_b |v_b - v_c| + |I_b w_b|) (mbdk_watch).
  subroutine planar_momenta(self, q, v, mom, msc)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: q(:), v(:)
    real(dp), intent(out) :: mom(6), msc(2)
    real(dp) :: c(2), vc(2), m, d(2), total
    integer :: b, k
    mom = 0.0_dp
    msc = 0.0_dp
    c = 0.0_dp
    vc = 0.0_dp
    total = 0.0_dp
    do b = 1, self%nb
      k = self%qoff(b)
      m = self%mass(k)
      mom(1:2) = mom(1:2) + m * v(k:k + 1)
      msc(1) = msc(1) + m * norm2(v(k:k + 1))
      c = c + m * q(k:k + 1)
      total = total + m
    end do
    if (any(nint(self%inv(1, 1:self%ninv)) == MBDK_INV_ANGULAR_POINT)) then
      c = self%inv(5:6, self%ninv)
    else
      c = c / total
      vc = mom(1:2) / total
    end if
    do b = 1, self%nb
      k = self%qoff(b)
      m = self%mass(k)
      d = q(k:k + 1) - c
      mom(6) = mom(6) + m * (d(1) * v(k + 1) - d(2) * v(k)) + self%mass(k + 2) * v(k + 2)
      msc(2) = msc(2) + m * norm2(d) * norm2(v(k:k + 1) - vc) + abs(self%mass(k + 2) * v(k + 2))
    end do
  end subroutine planar_momenta

  !> The components of the momentum and angular momentum a planar scene conserves, from its
  !> elements alone (mbdk_watch's rule): inv(:, 1:ninv).
  subroutine planar_invariants(jint, jreal, fint, freal, inv, ninv)
    integer, intent(in) :: jint(:, :), fint(:, :)
    real(dp), intent(in) :: jreal(:, :), freal(:, :)
    real(dp), intent(out) :: inv(MBDK_INV_WORDS, MBDK_INV_MAX)
    integer, intent(out) :: ninv
    type(mbdk_inv_rule_t) :: rule
    integer :: j, e, c
    logical :: rough(size(fint, 2))
    do j = 1, size(jint, 2)
      select case (jint(1, j))
      case (MBDK_JOINT_REVOLUTE, MBDK_JOINT_DISTANCE)
        ! to the ground: the reaction passes through the ground point (global)
        if (jint(3, j) == 0) call mbdk_inv_pivot(rule, [jreal(3:4, j), 0.0_dp])
      case (MBDK_JOINT_PRISMATIC, MBDK_JOINT_POINT_LINE)
        ! to the ground: a force across the ground line u = jreal(5:6) (and a moment)
        if (jint(3, j) == 0) call mbdk_inv_force(rule, [-jreal(6, j), jreal(5, j), 0.0_dp])
      case (MBDK_JOINT_FIXED)
        if (jint(3, j) == 0) call mbdk_inv_external(rule)
      case default   ! drivers, couplings, and the ground's curves, rolling and knife edges
        call mbdk_inv_external(rule)
      end select
    end do
    ! the contacts with friction (a friction element names its contact's column)
    rough = .false.
    do e = 1, size(fint, 2)
      if (fint(1, e) /= MBDK_FORCE_FRICTION) cycle
      c = fint(4, e)
      if (c < 1 .or. c > size(fint, 2)) then
        call mbdk_inv_external(rule)
      else
        rough(c) = .true.
      end if
    end do
    do e = 1, size(fint, 2)
      select case (fint(1, e))
      case (MBDK_FORCE_GRAVITY)
        call mbdk_inv_gravity(rule, [freal(1:2, e), 0.0_dp])
      case (MBDK_FORCE_SPRING, MBDK_FORCE_DAMPER, MBDK_FORCE_SPRING_DAMPER)
        ! along the line of its points: to the ground, through the ground point (the table
        ! allows the ground as either body: point2, or point1, is then global)
        if (fint(3, e) == 0) then
          call mbdk_inv_pivot(rule, [freal(3:4, e), 0.0_dp])
        else if (fint(2, e) == 0) then
          call mbdk_inv_pivot(rule, [freal(1:2, e), 0.0_dp])
        end if
      case (MBDK_FORCE_POINT)
        call mbdk_inv_force(rule, [freal(3:4, e), 0.0_dp])
      case (MBDK_FORCE_TORQUE)
        call mbdk_inv_moment(rule)
      case (MBDK_FORCE_COORDINATE)
        select case (fint(4, e))
        case (1)
          call mbdk_inv_force(rule, [1.0_dp, 0.0_dp, 0.0_dp])
        case (2)
          call mbdk_inv_force(rule, [0.0_dp, 1.0_dp, 0.0_dp])
        case default
          call mbdk_inv_moment(rule)
        end select
      case (MBDK_FORCE_CONTACT)
        if (fint(4, e) == MBDK_CONTACT_GEAR) then
          ! its tooth-relief terms are not checked for a moment (gears turn on axles anyway)
          call mbdk_inv_external(rule)
        else if (fint(3, e) == 0 .and. rough(e)) then
          call mbdk_inv_external(rule)
        else if (fint(3, e) == 0 .and. fint(4, e) == MBDK_CONTACT_LINE) then
          ! along the ground line's normal (cos a, sin a), a = freal(6)
          call mbdk_inv_force(rule, [cos(freal(6, e)), sin(freal(6, e)), 0.0_dp])
        else if (fint(3, e) == 0) then
          ! a ground circle or ring: along the line through its centre s2 (global)
          call mbdk_inv_pivot(rule, [freal(4:5, e), 0.0_dp])
        end if
      case (MBDK_FORCE_FRICTION, MBDK_EFFECT_WEAR)
        ! friction: with its contact above; wear: a state of its own, no force
      case default
        call mbdk_inv_external(rule)
      end select
    end do
    call mbdk_inv_result(rule, .true., inv, ninv)
  end subroutine planar_invariants

  !> What the watch tests at (t, q, v): work%phi, work%wres = D v + Phi_t and work%wterm (the
  !> size of its terms), the kinetic, gravity and spring energy and, with power, the powers of
  !> the work parts p = (dissipated by dampers, of the constraints, of the loads; mbdk_watch)
  !> (power_only: those alone). The passes are not counted in
  !> the visit counters: they are the watch's, not the integration's.
  subroutine watch_quantities(self, t, q, v, power, power_only, kin, vg, vs, p, stat, lam, &
                              reuse_lam, gross)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t, q(:), v(:)
    logical, intent(in) :: power, power_only
    real(dp), intent(in), optional :: lam(:)
    logical, intent(in), optional :: reuse_lam
    real(dp), intent(out), optional :: gross   !< |loads| + |drivers| + dissipation
    real(dp), intent(out) :: kin, vg, vs, p(MBDK_WORK_PARTS)
    integer, intent(out) :: stat
    integer(i8) :: unused(MBDK_JOINT_TYPES), visits(MBDK_VISIT_COUNT)
    real(dp) :: pd, pl, pc
    integer :: r, k, c
    stat = MBDK_SUCCESS
    pc = 0.0_dp
    if (present(gross)) gross = 0.0_dp
    associate (w => self%work)
      ! the drivers' power -lambda . D v needs the multipliers: one constrained solve, only
      ! where a driver makes the balance have power terms. Where D has lost a rank (redundant
      ! joints, a singular pose) the regular path of mbdk_constrained gives them. The solve's
      ! visits are the watch's: the counters are put back.
      if (power .and. self%has_drivers .and. present(lam)) then
        w%wlam = lam
      else if (power .and. self%has_drivers .and. present(reuse_lam)) then
        if (reuse_lam) then
          w%wlam = w%lam_rhs
        else
          call exact_lam()
        end if
        if (stat /= MBDK_SUCCESS) return
      else if (power .and. self%has_drivers) then
        call exact_lam()
        if (stat /= MBDK_SUCCESS) return
      else
        w%wlam = 0.0_dp
      end if
      ! a step that owes only its power skips the rotations where no power term needs them (a
      ! coordinate damper, a torque): the spring potentials it then computes are not used
      if (.not. power_only .or. self%has_drivers .or. self%power_rot) &
        call mbdk_body_rotations(q, w%rot)
      if (self%m > 0 .and. (.not. power_only .or. self%has_drivers)) then
        call mbdk_joints_eval(self%jint, self%jreal, self%row0, w%rot, q, v, t, w%phi, w%dz, &
                              w%gam, w%phit, unused)
        call mbdk_sparse_d_times(self%sp, w%dz, v, w%wres, .false.)
        pc = -dot_product(w%wlam, w%wres)
      end if
      if (self%m > 0 .and. .not. power_only) then
        w%wterm = abs(w%phit)
        do r = 1, self%m
          do k = 1, MBDK_JOINT_SLOTS
            c = self%col(k, r)
            if (c > 0) w%wterm(r) = w%wterm(r) + abs(w%dz(k, r) * v(c))
          end do
        end do
        w%wres = w%wres + w%phit
      end if
      kin = 0.0_dp
      do c = 1, self%nc
        kin = kin + self%mass(c) * v(c)**2
      end do
      kin = 0.5_dp * kin
      call mbdk_forces_energy(self%fint, self%freal, self%mass, w%rot, q, v, t, vg, vs, pd, pl)
      p = [pd, pc, pl]
      if (present(gross)) gross = abs(pl) + abs(pc) + abs(pd)
    end associate

  contains

    !> The multipliers at (t, q, v) by the model's solve; where D has lost a rank, by the
    !> regular path. The solve's visits are the watch's: the counters are put back.
    subroutine exact_lam()
      associate (w => self%work)
        visits = w%visits
        call mbdk_model_accelerations(self, t, q, v, w%wa, w%wlam, stat)
        if (stat == MBDK_ERR_SINGULAR_MATRIX .and. .not. self%revolute) then
          call mbdk_constrained_factor(w%cs, self%sp, w%dz, self%col, self%blk, self%mass, &
                                       stat, regular=.true.)
          if (stat == MBDK_SUCCESS) &
            call mbdk_constrained_solve(w%cs, self%sp, w%dz, self%blk, self%winv, w%fq, w%gam, &
                                        w%wa, w%wlam, stat)
        end if
        w%visits = visits
      end associate
    end subroutine exact_lam
  end subroutine watch_quantities

  ! ----- the mechanism interface (mbdk_mechanism): T = I, M diagonal -----

  !> f = the force elements' generalised force, and Phi, the dense D, gamma, Phi_t at (t, q, v).
  !> The joints' second pass (for the dense D) is not counted: one visit per element and
  !> evaluation, as the ODE's.
  subroutine model_evaluate(self, t, q, v, f, phi, c, gam, phit, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: q(:), v(:)
    real(dp), intent(out), contiguous :: f(:), phi(:), c(:, :), gam(:), phit(:)
    integer, intent(out) :: stat
    integer(i8) :: visits(MBDK_JOINT_TYPES)
    call mbdk_model_assemble(self, t, q, v, stat)
    if (stat /= MBDK_SUCCESS) return
    f = self%work%fq
    if (self%m == 0) return
    visits = self%work%visits(1:MBDK_JOINT_TYPES)
    call mbdk_model_constraints(self, t, q, v, phi, c, gam, phit)
    self%work%visits(1:MBDK_JOINT_TYPES) = visits
  end subroutine model_evaluate

  !> The body graph (mbdk_mechanism): coordinate and velocity 3 (b - 1) + k are body b's,
  !> joints and force elements (contacts among them) pair their two bodies (friction and wear
  !> entries refer to a contact's column, not to bodies: no pair of their own), the rows'
  !> columns are those of the compact rows (sp).
  subroutine model_body_graph(self, qbody, vbody, pairs, rptr, rcol, stat, asked)
    class(mbdk_model_t), intent(in) :: self
    integer, allocatable, intent(out) :: qbody(:), vbody(:), pairs(:, :), rptr(:), rcol(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nj, nf, i, astat
    nj = size(self%jint, 2)
    nf = size(self%fint, 2)
    allocate (qbody(self%nc), vbody(self%nc), pairs(2, nj + nf), rptr(self%m + 1), &
              rcol(size(self%sp%rcol)), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (2.0_dp * self%nc + 2 * (nj + nf) + &
                           self%m + 1 + size(self%sp%rcol)), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    do i = 1, self%nc
      qbody(i) = (i - 1) / 3 + 1
    end do
    vbody = qbody
    pairs(:, 1:nj) = self%jint(2:3, :)
    pairs(:, nj + 1:) = self%fint(2:3, :)
    do i = 1, nf
      if (self%fint(1, i) == MBDK_FORCE_FRICTION .or. self%fint(1, i) == MBDK_EFFECT_WEAR) &
        pairs(:, nj + i) = 0
    end do
    rptr = self%sp%rptr(1:self%m + 1)
    rcol = self%sp%rcol
  end subroutine model_body_graph

  subroutine model_mass_times(self, x, y)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: x(:)
    real(dp), intent(out) :: y(:)
    y = self%mass * x
  end subroutine model_mass_times

  !> M^-1 x, 0 in the rows of a body without inertia (M has no inverse there: the DAE forms
  !> keep M on the left, diag_mass)
  subroutine model_minv_times(self, x, y)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: x(:)
    real(dp), intent(out) :: y(:)
    y = merge(x / self%mass, 0.0_dp, self%mass > 0.0_dp)
  end subroutine model_minv_times

  subroutine model_mass_diagonal(self, dm)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(out) :: dm(:)
    dm = self%mass
  end subroutine model_mass_diagonal

  subroutine model_rates(self, q, v, qdot, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: q(:), v(:)
    real(dp), intent(out) :: qdot(:)
    integer, intent(out) :: stat
    qdot = v
    stat = MBDK_SUCCESS
  end subroutine model_rates

  subroutine model_accelerations(self, t, q, v, a, lam, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: q(:), v(:)
    real(dp), intent(out), contiguous :: a(:), lam(:)
    integer, intent(out) :: stat
    call mbdk_model_accelerations(self, t, q, v, a, lam, stat)
  end subroutine model_accelerations

  !> every row: a planar scene's multipliers are solved on all of them
  subroutine model_active_rows(self, rows, stat)
    class(mbdk_model_t), intent(in) :: self
    integer, allocatable, intent(out) :: rows(:)
    integer, intent(out) :: stat
    integer :: i, astat
    allocate (rows(self%m), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * self%m, stat)
    if (stat /= MBDK_SUCCESS) return
    rows = [(i, i = 1, self%m)]
  end subroutine model_active_rows

  subroutine model_watch_lam(self, t, y, force, lam, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:), lam(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    call mbdk_model_watch(self, t, y(1:self%nc), y(self%nc + 1:2 * self%nc), force, stat, &
                          lam=lam)
  end subroutine model_watch_lam

  subroutine model_watch_nodes_lam(self, t_a, t_b, y, lam, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t_a, t_b, y(:, :), lam(:, :)
    integer, intent(out) :: stat
    call mbdk_model_watch_nodes(self, t_a, t_b, y(1:self%nc, :), y(self%nc + 1:2 * self%nc, :), &
                                stat, lam=lam)
  end subroutine model_watch_nodes_lam

  subroutine model_watch_begin(self, t, y, velocity, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: velocity
    integer, intent(out) :: stat
    call mbdk_model_watch_start(self, t, y(1:self%nc), y(self%nc + 1:2 * self%nc), stat, &
                                velocity=velocity)
  end subroutine model_watch_begin

  subroutine model_watch_solve(self, t, y, force, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    call mbdk_model_watch(self, t, y(1:self%nc), y(self%nc + 1:2 * self%nc), force, stat, &
                          solve_lam=.true.)
  end subroutine model_watch_solve

  subroutine model_retract(self, q, dq, qn, stat)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: q(:), dq(:)
    real(dp), intent(out) :: qn(:)
    integer, intent(out) :: stat
    qn = q + dq
    stat = MBDK_SUCCESS
  end subroutine model_retract

  !> nothing to keep: planar coordinates are free
  subroutine model_normalise(self, q)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(inout) :: q(:)
  end subroutine model_normalise

  subroutine model_coord_weights(self, q, w)
    class(mbdk_model_t), intent(in) :: self
    real(dp), intent(in) :: q(:)
    real(dp), intent(out) :: w(:)
    w = abs(q)
  end subroutine model_coord_weights

end module mbdk_model
