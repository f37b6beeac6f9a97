!> A spatial multibody scene (the book's chapter 5) as a problem y' = F(t, y) for every ODE
!> integrator of the kernel. Planar scenes never come here (mbdk_model): they keep their own
!> path and pay nothing for 3D.
!>
!> State, body by body: y = [q_1 .. q_nb, w_1 .. w_nb, V_1 .. V_ns] with
!>   q_b = (r, p)  r the centre of mass in the space frame, p the orientation: a quaternion
!>                 (4, scalar first; rotation = quaternion) or three angles of the 3-1-3 Euler or
!>                 1-2-3 Cardan sequence (rotation = euler313 | cardan123; mbdk_rotations);
!>   w_b = (v, W)  v = r', W the angular velocity in the body frame;
!>   V_e           the worn volume of the scene's wear element e (none in a scene without).
!> Velocities are not q' (the orientation's rates follow from W, (5.43) and (5.95)), so the mass
!> matrix is constant and block diagonal, M = diag(m I, J) per body, J the inertia about the
!> centre in the body frame, and the equations of motion are Newton-Euler's (5.1)-(5.3):
!>
!>   M w' + C^T lambda = (f, n - W x J W),   C w' = gamma      (the planar model's signs)
!>
!> with f and n the applied force (space frame) and moment (body frame), C the constraint
!> Jacobian in the velocities w (Phi' = C w: a rotation R -> R (I + skew(dtheta)) in the body
!> frame moves Phi by C_W dtheta) and gamma = -(C' w), the terms of Phi'' quadratic in w. The
!> multipliers come from the Schur complement S = C M^-1 C^T: dense, by Cholesky, on a few rows
!> (at most MBDK_SPATIAL_SPARSE_ROWS, or up to MBDK_SPATIAL_DENSE_MAX_ROWS where S would be
!> more than three quarters full: a few bodies under many joints); above, with no row redundant and not
!> the penalty formulation, by C in compact rows (each row's twelve columns on its two bodies)
!> and the sparse LDL^T of S under AMD (mbdk_compact_schur: no fill on a chain or tree), so that
!> an evaluation's cost and memory grow as the rows do (benchmarks/spatial_chain.py measures it);
!> a joint tree's rows are then checked for independence connection by connection
!> (tree_rows) instead of on the whole dense C (a loop's still are on C). The manifest names
!> the path. Redundant joints (rows found dependent at the start, on the geometry:
!> select_rows) keep the dense path and are passed, a fixed set of independent rows carrying
!> the multipliers (schur_solve); on the reduced form a rank lost along the motion (a
!> singular pose) stops the run with MBDK_ERR_SINGULAR_MATRIX. Formulations (Fekete (2023)
!> section 3, as for planar scenes):
!>   1 reduced      C w' = gamma
!>   2 baumgarte    C w' = gamma - 2 alpha Phi' - beta^2 Phi
!>   3 penalty      (M + ap C^T C) w' = f - ap C^T (-gamma + 2 mu om Phi' + om^2 Phi),
!>                  lam = ap (C w' - gamma + 2 mu om Phi' + om^2 Phi)   (Jalon-Bayo (3.35)-(3.40);
!>                  definite with redundant joints, so no rows are chosen)
!>   4 projection   reduced, then after every step the positions are moved back onto Phi = 0
!>                  (Gauss-Newton with the least mass-weighted change, dr and the body-frame
!>                  rotation dtheta) and the velocities onto C w + Phi_t = 0.
!> The unit norm of a quaternion (rotation = quaternion) is kept by the user's choice (norm):
!>   1 project      p / |p| after every step (with the projection of the projection formulation)
!>   2 stabilise    p' = p (0, W) / 2 + k (1 - |p|^2) p / 2: the constraint |p| = 1 stabilised in
!>                  the kinematic equation (norm_gain k, 1/s), no step changes the state after it
!>   3 none         nothing: |p| drifts as the integrator lets it (what a study measures);
!> the rotation matrix is always taken from p / |p|, so a drift of |p| does not scale the body.
!> An angle set at its gimbal lock (3-1-3: sin(theta) = 0; 1-2-3: cos(beta) = 0) has no angle
!> rates: the evaluation returns MBDK_ERR_SINGULAR_MATRIX and the run stops there, by name.
!>
!> Joints (type, body i, body j; j = 0 is the ground, whose points and axes are global; the type
!> is the element registry's code, mbdk_elements, of a kind of spatial bodies, and the registry
!> states its rows here, those below). Each is a set of the primitive constraints of Haug's
!> spatial kinematics, written in body-fixed points s and unit vectors u:
!>   spherical   3 rows  r_i + R_i s_i - r_j - R_j s_j = 0
!>   revolute    5 rows  spherical, and the axis a_i normal to two vectors normal to a_j
!>   universal   4 rows  spherical, and a_i . a_j = 0 (the cross's two axes)
!>   cylindrical 4 rows  a_i parallel to a_j, and the joint points' offset normal to a_j's normals
!>   prismatic   5 rows  cylindrical, and the rotation about the axis kept at its initial value
!>   fixed       6 rows  spherical, and the relative orientation kept at its initial value
!>   slide_driver 1 row  the offset of body i's point from body j's along the axis a_j (body j
!>                       frame; with a prismatic or cylindrical joint on that axis) follows
!>                       f(t): Phi = (R_j a_j) . (P_i - P_j) - f(t), the points together at the
!>                       start (f(t0) = 0); the drive of a slider, a translation's twin of
!>                       angle_driver
!>   angle_driver 1 row  the rotation of body i relative to body j about the axis (a_i in i,
!>                       a_j in j; with a revolute joint on that axis) from its initial value
!>                       follows f(t): Phi = sin(theta - f(t)), theta measured with two vectors
!>                       normal to the axis, equal at the start (so f(t0) = 0 is consistent)
!> A joint's reals (MBDK_SPATIAL_JOINT_REALS): s_i (3), s_j (3), a_i (3, body i frame), a_j (3,
!> body j frame), the time function (5; mbdk_time_function, drivers only); axes are normalised
!> here, one of zero length is MBDK_ERR_INVALID_INPUT. A driver makes the rows rheonomic: Phi' =
!> C w + Phi_t, and the energy balance counts the drivers' power lambda . Phi_t.
!> Forces (type, body i, body j; reals MBDK_SPATIAL_FORCE_REALS; the registry's codes, as the
!> joints'):
!>   gravity        g (3)                            on every body
!>   point_force    s (3, body frame), f (3, space)  a constant force at a body point
!>   torque         n (3, space)                     a constant moment
!>   spring_damper  s_i (3), s_j (3), k, c, l0       along the line of the two points
!>   sphere_plane,  compliant contact with friction between a sphere on body i and a plane or
!>   sphere_sphere  a sphere on body j (the ground or a body): mbdk_contact3d (geometry, reals)
!>                  over mbdk_contact_law (the IMPACT normal force, regularised Coulomb friction)
!>   wear           an effect (mbdk_elements' third class) with a state of its own, the worn
!>                  volume V of a contact of this table: V' = the law of mbdk_wear (archard or
!>                  knee, the planar contacts' code: mbdk_wear_law) at the contact's normal
!>                  force, or its friction force mu F, and its slip speed |s|. Its entry: fbody =
!>                  (the contact's column in this table, the law MBDK_WEAR_ARCHARD or
!>                  MBDK_WEAR_KNEE), freal = (k, knee: c0 .. c3 (S/R(t) = c0 + c1 t + c2 t^2 +
!>                  c3 t^3), the load: 1 normal force (MBDK_WEAR_LOAD_NORMAL), 2 friction force);
!>                  k >= 0, a friction load on a contact with friction. Wear takes no energy of
!>                  its own: the contact's friction dissipates what the balance counts, as on
!>                  planar scenes. The gear law (its speed R |omega1 - omega2| is a planar gear
!>                  pair's) is MBDK_ERR_INVALID_INPUT here.
!> Only the elements a scene declares are visited (a scene without wear has ns = 0 states after
!> its bodies' and its evaluation never reaches the wear code). A contact's potential is part of
!> the spring energy, the power its damping and friction dissipate part of the dampers' power; with
!> locate_events, dopri54 and bs32 end a step where a contact closes or lets go (spatial_events:
!> the law's event function and the penetration per contact, in table order).
!>
!> The watch (mbdk_watch) checks Phi, C w + Phi_t and the energy balance as on planar scenes
!> (a driven scene pays a constrained solve per step for its drivers' power); rows of
!> the direction constraints (a dot product of unit vectors) are measured in radians, the others
!> in the mechanism's length scale. Outputs (mbdk_spatial_outputs): kinetic, gravity and spring
!> energy, the power of dampers, loads and drivers, max |Phi|, max |C w + Phi_t|, max ||p| - 1|.
module mbdk_spatial_model
  use, intrinsic :: iso_c_binding, only: c_int, c_double
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t, MBDK_GAUSS3
  use mbdk_mechanism, only: mbdk_mechanism_t, mbdk_i3_aux_t, mbdk_i3_eval_t, MBDK_FORM_REDUCED, &
    MBDK_FORM_BAUMGARTE, MBDK_FORM_PENALTY, MBDK_FORM_PROJECTION, MBDK_RANK_LOSS_WINDOW, &
    MBDK_RANK_LOSS_MAX_ROWS
  use mbdk_rank_margin, only: mbdk_near_rank_loss, mbdk_pivots_near
  use mbdk_lapack, only: mbdk_chol_factor, mbdk_chol_solve, mbdk_chol_pivoted
  use mbdk_compact_schur, only: mbdk_compact_schur_t, mbdk_compact_schur_init, &
    mbdk_compact_schur_factor, mbdk_compact_schur_solve, mbdk_compact_schur_spread
  use mbdk_rotations, only: mbdk_skew, mbdk_angles_matrix, mbdk_angles_rates, mbdk_quat_mul, &
    mbdk_quat_rates, mbdk_quat_matrix_of, MBDK_SEQ_EULER313, MBDK_SEQ_CARDAN123
  use mbdk_time_function, only: mbdk_time_fn
  use mbdk_watch, only: mbdk_watch_t, mbdk_watch_start, mbdk_watch_due, mbdk_watch_test, &
    mbdk_watch_power, MBDK_WATCH_NOTHING, MBDK_WATCH_POWER_ONLY, MBDK_WATCH_EVERY, &
    mbdk_watch_start_invariants, mbdk_watch_nodes, mbdk_inv_rule_t, mbdk_inv_external, &
    mbdk_inv_gravity, mbdk_inv_pivot, mbdk_inv_result, mbdk_inv_force, mbdk_inv_moment, &
    MBDK_INV_MAX, MBDK_INV_WORDS, MBDK_INV_ANGULAR_POINT
  use mbdk_memory, only: mbdk_alloc_status, mbdk_count_fits, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_contact3d, only: mbdk_contact3d_t, mbdk_contact3d_eval, mbdk_contact3d_loads, &
    mbdk_contact3d_events, mbdk_contact3d_rough, MBDK_CONTACT3D_PLANE, MBDK_CONTACT3D_SPHERES, &
    MBDK_CONTACT3D_REALS
  ! the joint and force types, their codes and rows: the element registry's, one code per name
  ! in planar and spatial scenes; this model takes the kinds that apply to spatial bodies
  use mbdk_elements, only: mbdk_element_applies, mbdk_joint_rows, MBDK_CLASS_JOINT, &
    MBDK_CLASS_FORCE, MBDK_BODY_SPATIAL, MBDK_JOINT_SPHERICAL, MBDK_JOINT_REVOLUTE, &
    MBDK_JOINT_UNIVERSAL, MBDK_JOINT_CYLINDRICAL, MBDK_JOINT_PRISMATIC, MBDK_JOINT_FIXED, &
    MBDK_JOINT_ANGLE_DRIVER, MBDK_JOINT_SLIDE_DRIVER, MBDK_FORCE_GRAVITY, MBDK_FORCE_POINT, &
    MBDK_FORCE_TORQUE, MBDK_FORCE_SPRING_DAMPER, MBDK_FORCE_SPHERE_PLANE, &
    MBDK_FORCE_SPHERE_SPHERE, MBDK_EFFECT_WEAR
  use mbdk_wear, only: mbdk_wear_law, MBDK_WEAR_ARCHARD, MBDK_WEAR_KNEE, &
    MBDK_WEAR_LOAD_NORMAL, MBDK_WEAR_LOAD_FRICTION
  implicit none
  private
  public :: mbdk_spatial_contact_states
  public :: mbdk_spatial_init, mbdk_spatial_outputs, mbdk_spatial_assemble, &
    mbdk_spatial_multipliers, mbdk_spatial_constraints, mbdk_spatial_dae_rhs, mbdk_spatial_watch, &
    mbdk_spatial_watch_nodes
  ! for the submodule mbdk_spatial_i3: gfortran gives a private module procedure local linkage
  ! (and clones it), so that a submodule compiled on its own cannot link to it
  public :: frames, forces, constraints, apply_minv, minv_ct, gram, near_test, clear_of_near, &
    generalized_forces, last_velocity, compact_times, compact_ct, compact_factor, qi, &
    loads_two_bodies

  !> a force's reals: as many as a contact has (mbdk_contact3d), the other kinds use the first
  integer, parameter, public :: MBDK_SPATIAL_JOINT_REALS = 17, &
    MBDK_SPATIAL_FORCE_REALS = MBDK_CONTACT3D_REALS
  integer, parameter, public :: MBDK_ROT_QUATERNION = 1, MBDK_ROT_EULER313 = 2, &
    MBDK_ROT_CARDAN123 = 3
  integer, parameter, public :: MBDK_NORM_PROJECT = 1, MBDK_NORM_STABILISE = 2, &
    MBDK_NORM_NONE = 3
  !> the coordinates of a run (mbdk_spatial_options_t%coordinates): the bodies' absolute ones
  !> (this model), or joint coordinates (mbdk_joint_coords)
  integer, parameter, public :: MBDK_COORDS_ABSOLUTE = 0, MBDK_COORDS_JOINT = 1
  !> outputs per sample (mbdk_spatial_outputs)
  integer, parameter, public :: MBDK_SPATIAL_NOUT = 7
  !> Gauss-Newton iterations of a position projection before it gives up (it converges
  !> quadratically from a step's drift: two or three are the rule)
  integer, parameter :: PROJECTION_MAX_ITER = 20
  !> pivots of the rank-revealing Cholesky factorisation of the geometric G = C W C^T (scaled to
  !> a unit diagonal; select_rows) at or below this count as zero: a dependent row leaves
  !> roundoff there (1e-16), and a regular pose of a sound mechanism keeps its least pivot far
  !> above
  real(dp), parameter :: REDUNDANT_RTOL = 1.0e-10_dp
  !> select_rows' ties: values within this fraction of each other are equal (a symmetric
  !> mechanism ties exactly, and a pick by the largest alone would go by roundoff, which the
  !> mechanism's place or another CPU's sums change)
  real(dp), parameter :: SELECT_TIE_RTOL = 1.0e-8_dp
  !> a pivot of the mass-weighted S at or below this fraction of its row's diagonal is a
  !> numerically singular solve
  real(dp), parameter :: SOLVE_RTOL = 64.0_dp * epsilon(1.0_dp)
  !> The reduced formulation refuses a relative pivot below this (MBDK_ERR_SINGULAR_MATRIX): a
  !> near rank loss, where its accelerations amplify the drift in the vanishing direction and a
  !> fixed step across a singular pose can leave the mechanism on another assembly branch. The
  !> planar model's window (MBDK_MODEL_NEAR_PIVOT, whose comment says why it is this wide); the
  !> stabilised formulations keep the constraints through such a step, and test REDUNDANT_RTOL.
  real(dp), parameter, public :: MBDK_SPATIAL_NEAR_PIVOT = 1.0e-4_dp
  !> above this many constraint rows (and none redundant, and not the penalty formulation) the
  !> constrained solves of the ODE formulations go by compact rows and the sparse LDL^T of
  !> S = C M^-1 C^T (mbdk_compact_schur), whose cost grows as the rows do; at or below it, by
  !> the dense Cholesky, whose m^3/6 is cheaper than the sparse factor's ordering and
  !> symbolic set-up on so few rows (the break-even of a spherical chain; the planar model's
  !> threshold is the same)
  integer, parameter, public :: MBDK_SPATIAL_SPARSE_ROWS = 12
  !> ... but up to this many rows, an S more than three quarters full keeps the dense path
  !> (choose_sparse)
  integer, parameter, public :: MBDK_SPATIAL_DENSE_MAX_ROWS = 60
  integer, parameter :: PRIM_SPH = 1, PRIM_DOT1 = 2, PRIM_DOT2 = 3, PRIM_ANGLE = 4, &
    PRIM_SLIDE = 5

  !> Options of a spatial model, by name with defaults. bind(C): the same struct is struct
  !> mbdk_spatial_options in mbdk.h and mbdk.options.SpatialOptions in Python (tests/
  !> test_structs.py and kernel/tests/c_struct_layout.c check that the three agree field by
  !> field); the formulations' parameters carry the planar mbdk_model_options_t's names.
  type, bind(C), public :: mbdk_spatial_options_t
    real(c_double) :: baumgarte_alpha = 0.0_dp, baumgarte_beta = 0.0_dp   !< (3.29)
    !> Jalon-Bayo's penalty (3.35)-(3.40): alpha_p, omega_p, mu_p
    real(c_double) :: penalty_alpha = 1.0e7_dp, penalty_omega = 10.0_dp, penalty_mu = 1.0_dp
    !> angle sets: an evaluation within this distance of the set's gimbal lock (|sin theta| for
    !> 3-1-3, |cos beta| for 1-2-3) returns MBDK_ERR_SINGULAR_MATRIX, so that the caller can
    !> switch to the other set before the rates blow up (mbdk.angle_switch); 0: off
    real(c_double) :: lock_guard = 0.0_dp
    real(c_double) :: norm_gain = 10.0_dp               !< norm = stabilise, 1/s
    real(c_double) :: projection_tol = 1.0e-12_dp       !< |Phi| (m, or rad) a projection reaches
    real(c_double) :: watch_position = 1.0e-2_dp, watch_velocity = 1.0e-2_dp, &
      watch_energy = 1.0e-1_dp, watch_momentum = 1.0e-2_dp, watch_quaternion = 1.0e-1_dp
    integer(c_int) :: formulation = MBDK_FORM_REDUCED   !< the codes of mbdk_mechanism
    integer(c_int) :: rotation = MBDK_ROT_QUATERNION
    integer(c_int) :: norm = MBDK_NORM_PROJECT
    integer(c_int) :: watch_every = MBDK_WATCH_EVERY
    !> /= 0: the contacts' events, for the error-controlled Runge-Kutta pairs (mbdk_problem)
    integer(c_int) :: locate_events = 1
    !> MBDK_COORDS_ABSOLUTE: the bodies' absolute coordinates (this model); MBDK_COORDS_JOINT:
    !> joint coordinates on a spanning tree of the joints (mbdk_joint_coords), the ODE methods
    !> of the f2py entry spatial_run only
    integer(c_int) :: coordinates = MBDK_COORDS_ABSOLUTE
  end type mbdk_spatial_options_t

  !> one primitive constraint: rows row .. row + 2 (spherical) or row (a dot product)
  type :: prim_t
    integer :: kind = 0, bi = 0, bj = 0, row = 0
    real(dp) :: si(3) = 0.0_dp, sj(3) = 0.0_dp, ui(3) = 0.0_dp, uj(3) = 0.0_dp
    !> PRIM_ANGLE: the second reference vector on body j (a_j x uj) and the time function;
    !> PRIM_SLIDE: the time function
    real(dp) :: wj(3) = 0.0_dp, fn(5) = 0.0_dp
    integer :: joint = 0      !< the joint (table column) it belongs to
  end type prim_t

  !> the kinematics of every body at one state (index 0: the ground): r the centre, rot the
  !> rotation matrix (body to space), v the centre's velocity (space frame), om the angular
  !> velocity (body frame). Public with frames, forces and constraints: the joint-coordinate
  !> model (mbdk_joint_coords) sets them from its own coordinates and evaluates the scene's
  !> forces and its cut joints' rows through them.
  type, public :: frames_t
    real(dp), allocatable :: r(:, :), rot(:, :, :), v(:, :), om(:, :)
  end type frames_t

  !> what the caller owns and the model points to (rhs receives the model read-only)
  type, public :: mbdk_spatial_work_t
    type(mbdk_watch_t) :: watch
    !> redundant joints: the rows solved now (the model's initial set until it nears a rank loss
    !> of its own, then the set chosen there, kept until it nears one in turn) and how often the
    !> set changed
    integer, allocatable :: active(:)
    integer :: switches = 0
    !> spatial_accelerations' arrays, sized once at init (the frames at the first evaluation;
    !> ten allocations per evaluation cost about a sixth of an rk4 step of the heavy top). That
    !> routine is the only user, and never runs inside itself.
    real(dp), allocatable :: fw(:, :), nbd(:, :), acc(:), gen(:), phi(:), c(:, :), gam(:), &
      l(:), mc(:, :), phit(:), rhs(:)
    type(frames_t) :: fr
    !> the sparse path (model%sparse): C in compact rows (m, 12), a correction W C^T lam (6 nb)
    !> and S's pattern and factors; c and mc are then empty
    real(dp), allocatable :: cc(:, :), dx(:)
    type(mbdk_compact_schur_t) :: cs
    !> solve_rows' S, right-hand side and diagonal, sized at its first call to the rows solved
    !> (all, or a redundant scene's independent set, whose count stays rank0); not at init, as
    !> the paths that never solve rows densely (sparse, penalty) would hold an m x m S for nothing
    real(dp), allocatable :: s(:, :), sx(:), sdiag(:)
    integer, allocatable :: slast(:)   !< the envelope of S's factor (mbdk_chol_factor)
  end type mbdk_spatial_work_t

  !> The spatial model: a mechanism (mbdk_mechanism) with q = [r, p per body], v = [r', Omega
  !> per body], ncoord = nqb nb, nvel = 6 nb, M block diagonal (not diagonal: J).
  type, extends(mbdk_mechanism_t), public :: mbdk_spatial_model_t
    type(mbdk_spatial_options_t) :: opt
    integer :: nqb = 7, nprim = 0, nf = 0
    integer :: ncontacts = 0   !< contact elements (the events, in table order)
    integer :: seq(3) = 0
    real(dp), allocatable :: mass(:), inertia(:, :, :), inv_inertia(:, :, :)
    type(prim_t), allocatable :: prim(:)
    logical, allocatable :: row_angular(:)
    integer, allocatable :: ftype(:), fbody(:, :)
    real(dp), allocatable :: freal(:, :)
    !> the force table's columns of the wear elements, whose states are y's last ns
    integer, allocatable :: wear(:)
    logical :: has_power = .false.
    logical :: has_drivers = .false.   !< rheonomic rows: Phi_t and the drivers' power
    real(dp) :: length = 1.0_dp, gscale = 0.0_dp
    !> the length at which the reduced form's tests of a rank loss (select_rows, near_test,
    !> tree_rows, geo_blk) see rotations: length's, with the ground's points measured from the
    !> bodies' centre instead of the origin, so that where the mechanism stands does not sway
    !> them (length itself keeps the coordinates' size, whose roundoff the watch's floors meet)
    real(dp) :: geo_length = 1.0_dp
    !> the components of the momentum and angular momentum the scene conserves, found at init
    !> from its elements (mbdk_watch's rule)
    integer :: ninv = 0
    real(dp) :: inv(MBDK_INV_WORDS, MBDK_INV_MAX) = 0.0_dp
    !> the run samples its work as the watch integrates it at every step (set by the caller)
    logical :: record_work = .false.
    !> the rank of C at the initial state, and the rows found independent there (rank-revealing
    !> Cholesky): below m, the joints are redundant, and these rows alone are solved
    integer :: rank0 = 0
    integer, allocatable :: active(:)
    !> the constrained solves by compact rows and a sparse S (MBDK_SPATIAL_SPARSE_ROWS), with
    !> the blocks of M^-1 and of the geometry's weight (near_test's) per body
    logical :: sparse = .false.
    !> a tree of joints with independent rows at the start (two on one pair of bodies are not:
    !> six rows of rank five) and no drivers: C keeps its full rank along the motion, and the
    !> near test of a rank loss (the geometry's G, a second factorisation per evaluation) is
    !> skipped. Ordered from the root, C is block triangular, each joint's block on the body
    !> away from the root of full rank: a spherical joint's three rows have the identity on its
    !> translation at every pose; the rotation rows of a revolute, universal, cylindrical,
    !> prismatic or fixed joint (two body vectors kept normal) have the gradients u x v of
    !> unit vectors held normal, of length 1 and, within a joint, normal to one another on the
    !> joint (a_i x b1 and a_i x b2 with a_i along b1 x b2; a prismatic's fifth row along a_j;
    !> a fixed joint's e1, e2, e3), so independent near it too (they degenerate only where the
    !> joint is broken by tens of degrees); a prismatic or cylindrical joint's offset rows have
    !> two normal unit vectors on its translation. A driver's angle or slide row is left
    !> out: an angle measured about an axis the joint does not hold can lose its gradient.
    logical :: regular_tree = .false.
    !> kappa with W >= kappa M^-1 body by body, W the geometry's weight of the near test
    !> (diag(I, I / geo_length^2)): the least of a body's mass and of a lower bound of its
    !> inertia's least eigenvalue over geo_length^2 (clear_of_near)
    real(dp) :: near_kappa = 0.0_dp
    real(dp), allocatable :: minv_blk(:, :, :), geo_blk(:, :, :)
    integer, allocatable :: all_rows(:)   !< 1 .. m, the index of every row
    integer, allocatable :: rbody(:, :)   !< (2, m): the two bodies of each row (0: the ground)
    type(mbdk_spatial_work_t), pointer :: work => null()
  contains
    procedure :: rhs => spatial_rhs
    procedure :: post_step => spatial_post_step
    procedure :: watch_start => spatial_watch_start
    procedure :: watch => spatial_watch
    procedure :: watch_wants_nodes => spatial_wants_nodes
    procedure :: watch_nodes => spatial_watch_nodes
    procedure :: events => spatial_events
    procedure :: evaluate => spatial_evaluate
    procedure :: body_graph => spatial_body_graph
    procedure :: mass_times => spatial_mass_times
    procedure :: minv_times => spatial_minv_times
    procedure :: mass_diagonal => spatial_mass_diagonal
    procedure :: rates => spatial_rates
    procedure :: accelerations => spatial_accelerations_of
    procedure :: active_rows => spatial_active_rows
    procedure :: watch_lam => spatial_watch_lam
    procedure :: watch_nodes_lam => spatial_watch_nodes_lam
    procedure :: watch_begin => spatial_watch_begin
    procedure :: watch_solve => spatial_watch_solve
    procedure :: retract => spatial_retract
    procedure :: normalise => spatial_normalise
    procedure :: coord_weights => spatial_coord_weights
    procedure :: near_rank_loss => spatial_near_rank_loss
    ! trapezoidal_index3's part (the submodule mbdk_spatial_i3)
    procedure :: i3_create => spatial_i3_create
    procedure :: i3_evaluate => spatial_i3_evaluate
    procedure :: i3_residual => spatial_i3_residual
    procedure :: i3_c_times => spatial_i3_c_times
    procedure :: i3_ct_times => spatial_i3_ct_times
    procedure :: i3_cs_factor => spatial_i3_cs_factor
    procedure :: i3_cs_solve => spatial_i3_cs_solve
    procedure :: i3_matrix => spatial_i3_matrix
    procedure :: i3_matrix_solve => spatial_i3_matrix_solve
    procedure :: i3_matrix_renew => spatial_i3_matrix_renew
  end type mbdk_spatial_model_t

  interface
    module subroutine spatial_i3_create(self, aux, book, stat, asked)
      class(mbdk_spatial_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), allocatable, intent(out) :: aux
      logical, intent(in) :: book
      integer, intent(out) :: stat
      real(dp), intent(inout), optional :: asked
    end subroutine spatial_i3_create
    module subroutine spatial_i3_evaluate(self, aux, t, e, forces, same_q, stat)
      class(mbdk_spatial_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in) :: t
      type(mbdk_i3_eval_t), intent(inout) :: e
      logical, intent(in) :: forces, same_q
      integer, intent(out) :: stat
    end subroutine spatial_i3_evaluate
    module subroutine spatial_i3_residual(self, aux, e, s)
      class(mbdk_spatial_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      type(mbdk_i3_eval_t), intent(inout) :: e
      real(dp), intent(in) :: s
    end subroutine spatial_i3_residual
    module subroutine spatial_i3_c_times(self, aux, x, y, absolute)
      class(mbdk_spatial_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in), contiguous :: x(:)
      real(dp), intent(out), contiguous :: y(:)
      logical, intent(in), optional :: absolute
    end subroutine spatial_i3_c_times
    module subroutine spatial_i3_ct_times(self, aux, x, y, absolute)
      class(mbdk_spatial_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in), contiguous :: x(:)
      real(dp), intent(out), contiguous :: y(:)
      logical, intent(in), optional :: absolute
    end subroutine spatial_i3_ct_times
    module subroutine spatial_i3_cs_factor(self, aux, near, regular_ok, regular, stat)
      class(mbdk_spatial_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in) :: near
      logical, intent(in) :: regular_ok
      logical, intent(out) :: regular
      integer, intent(out) :: stat
    end subroutine spatial_i3_cs_factor
    module subroutine spatial_i3_cs_solve(self, aux, b, c, x, mu, stat)
      class(mbdk_spatial_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in), contiguous :: b(:), c(:)
      real(dp), intent(out), contiguous :: x(:), mu(:)
      integer, intent(out) :: stat
    end subroutine spatial_i3_cs_solve
    module subroutine spatial_i3_matrix(self, aux, book, t, e, lam, ck, cd, alpha, stat)
      class(mbdk_spatial_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      logical, intent(in) :: book
      real(dp), intent(in) :: t, ck, cd, alpha
      type(mbdk_i3_eval_t), intent(in) :: e
      real(dp), intent(in), contiguous :: lam(:)
      integer, intent(out) :: stat
    end subroutine spatial_i3_matrix
    module subroutine spatial_i3_matrix_renew(self, aux, ck, alpha, stat)
      class(mbdk_spatial_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in) :: ck, alpha
      integer, intent(out) :: stat
    end subroutine spatial_i3_matrix_renew
    module subroutine spatial_i3_matrix_solve(self, aux, e, stat)
      class(mbdk_spatial_model_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      type(mbdk_i3_eval_t), intent(inout) :: e
      integer, intent(out) :: stat
    end subroutine spatial_i3_matrix_solve
  end interface

contains

  !> Builds the model. mass(nb), inertia(3, 3, nb) (symmetric positive definite), joints:
  !> jtype(nj), jbody(2, nj), jreal(MBDK_SPATIAL_JOINT_REALS, nj); forces: ftype(nf), fbody(2,
  !> nf), freal(MBDK_SPATIAL_FORCE_REALS, nf); y0 the initial state, the bodies' and then one
  !> volume per wear entry of the force table (its orientations fix the reference of prismatic
  !> and fixed joints). work: owned by the caller, outliving the model's
  !> use. MBDK_ERR_INVALID_INPUT for a bad table entry (the Python layer names it first), or for
  !> counts whose sizes (13 nb, 5 nj) no default integer holds; MBDK_ERR_NO_MEMORY (asked: the
  !> bytes, mbdk_memory). The steps check and allocate in one fixed order, so that an input
  !> with more than one fault always gets the same status (and a failed allocation the same
  !> bytes).
  subroutine mbdk_spatial_init(model, work, opt, mass, inertia, jtype, jbody, jreal, ftype, &
                               fbody, freal, t0, y0, stat, asked)
    type(mbdk_spatial_model_t), intent(out) :: model
    type(mbdk_spatial_work_t), intent(inout), target :: work
    type(mbdk_spatial_options_t), intent(in) :: opt
    real(dp), intent(in) :: mass(:), inertia(:, :, :), jreal(:, :), freal(:, :), t0, y0(:)
    integer, intent(in) :: jtype(:), jbody(:, :), ftype(:), fbody(:, :)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: astat
    type(frames_t) :: fr

    stat = MBDK_ERR_INVALID_INPUT
    if (.not. spatial_tables_ok(mass, inertia, jtype, jbody, jreal, ftype, fbody, freal)) return
    if (.not. spatial_options_ok(opt)) return
    call lay_out_spatial_state(model, opt, size(mass), count(ftype == MBDK_EFFECT_WEAR))
    if (size(y0) /= model%n .or. .not. all(abs(y0) <= huge(1.0_dp))) return
    call take_bodies(model, mass, inertia, y0, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    ! the frames at y0: the reference orientations of prismatic, fixed and driven joints
    call frames(model, y0, fr, stat, asked)
    if (stat == MBDK_ERR_NO_MEMORY) return
    if (stat /= MBDK_SUCCESS) then
      stat = MBDK_ERR_INVALID_INPUT
      return
    end if
    call count_joint_rows(model, jtype, jbody, stat)
    if (stat /= MBDK_SUCCESS) return
    call build_primitives(model, jtype, jbody, jreal, fr, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call take_forces(model, ftype, fbody, freal, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call watch_scales(model, fr)
    model%near_kappa = weight_bound(model)
    call spatial_invariants(jtype, jbody, jreal, ftype, fbody, freal, model%inv, model%ninv)
    call choose_active_rows(model, fr, t0, jbody, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    if (allocated(work%active)) deallocate (work%active)
    allocate (work%active(size(model%active)), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * size(model%active), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    work%active = model%active
    work%switches = 0
    call choose_sparse(model, work, stat, asked)
    ! the index-3 Newton matrix: the model's own on the sparse path (mbdk_spatial_i3), the
    ! integrator's differences over the dense evaluation otherwise
    model%has_i3_matrix = model%sparse
    model%has_i3_renew = model%sparse
    model%compact_rows = model%sparse
    if (stat /= MBDK_SUCCESS) return
    call accelerations_scratch(model, work, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    model%nq = 0
    model%has_post_step = opt%formulation == MBDK_FORM_PROJECTION .or. &
      (opt%rotation == MBDK_ROT_QUATERNION .and. opt%norm == MBDK_NORM_PROJECT)
    model%has_watch = opt%watch_position > 0.0_dp .or. opt%watch_velocity > 0.0_dp .or. &
      opt%watch_energy > 0.0_dp .or. (model%ninv > 0 .and. opt%watch_momentum > 0.0_dp) .or. &
      (opt%rotation == MBDK_ROT_QUATERNION .and. opt%watch_quaternion > 0.0_dp)
    model%work => work
    stat = MBDK_SUCCESS
  end subroutine mbdk_spatial_init

  !> The tables' shapes and finite reals, at least one body, and counts that default integers
  !> hold (the state: 13 nb values and a wear element's; the primitives: 5 a joint).
  pure logical function spatial_tables_ok(mass, inertia, jtype, jbody, jreal, ftype, fbody, &
                                          freal) result(ok)
    real(dp), intent(in) :: mass(:), inertia(:, :, :), jreal(:, :), freal(:, :)
    integer, intent(in) :: jtype(:), jbody(:, :), ftype(:), fbody(:, :)
    integer :: nb, nj
    ok = .false.
    nb = size(mass)
    nj = size(jtype)
    if (nb < 1 .or. any(shape(inertia) /= [3, 3, nb])) return
    if (.not. (mbdk_count_fits(13.0_dp * nb + size(ftype)) .and. mbdk_count_fits(5.0_dp * nj))) &
      return
    if (size(jbody, 1) /= 2 .or. size(jbody, 2) /= nj .or. size(jreal, 1) /= &
        MBDK_SPATIAL_JOINT_REALS .or. size(jreal, 2) /= nj) return
    if (size(fbody, 1) /= 2 .or. size(fbody, 2) /= size(ftype) .or. size(freal, 1) /= &
        MBDK_SPATIAL_FORCE_REALS .or. size(freal, 2) /= size(ftype)) return
    ok = all(abs(jreal) <= huge(1.0_dp)) .and. all(abs(freal) <= huge(1.0_dp))
  end function spatial_tables_ok

  !> The options: known codes of the formulation, rotation and norm, penalty parameters
  !> positive and finite (when the formulation is penalty), the other parameters in range.
  pure logical function spatial_options_ok(opt) result(ok)
    type(mbdk_spatial_options_t), intent(in) :: opt
    ok = .false.
    if (opt%formulation < MBDK_FORM_REDUCED .or. opt%formulation > &
        MBDK_FORM_PROJECTION) return
    if (opt%formulation == MBDK_FORM_PENALTY .and. .not. (opt%penalty_alpha > 0.0_dp .and. &
        opt%penalty_omega > 0.0_dp .and. opt%penalty_mu > 0.0_dp .and. &
        opt%penalty_alpha <= huge(1.0_dp) .and. opt%penalty_omega <= huge(1.0_dp) .and. &
        opt%penalty_mu <= huge(1.0_dp))) return
    if (opt%rotation < MBDK_ROT_QUATERNION .or. opt%rotation > MBDK_ROT_CARDAN123) return
    if (opt%norm < MBDK_NORM_PROJECT .or. opt%norm > MBDK_NORM_NONE) return
    if (opt%coordinates /= MBDK_COORDS_ABSOLUTE .and. opt%coordinates /= MBDK_COORDS_JOINT) &
      return
    ok = opt%baumgarte_alpha >= 0.0_dp .and. opt%baumgarte_beta >= 0.0_dp .and. &
         opt%norm_gain >= 0.0_dp .and. opt%projection_tol > 0.0_dp .and. &
         all(abs([opt%watch_position, opt%watch_velocity, opt%watch_energy, &
                  opt%watch_momentum, opt%watch_quaternion, opt%norm_gain]) <= huge(1.0_dp)) &
         .and. opt%watch_every >= 0 .and. opt%lock_guard >= 0.0_dp .and. &
         opt%lock_guard < 1.0_dp
  end function spatial_options_ok

  !> The options into the model and the state's layout: nqb coordinates per body (7 for a
  !> quaternion, 6 for angles; seq the angle sequence), 6 velocities, then the ns states of the
  !> effects (wear).
  subroutine lay_out_spatial_state(model, opt, nb, ns)
    type(mbdk_spatial_model_t), intent(inout) :: model
    type(mbdk_spatial_options_t), intent(in) :: opt
    integer, intent(in) :: nb, ns
    model%opt = opt
    ! 0: the default, as in mbdk_model_options_t
    if (opt%watch_every == 0) model%opt%watch_every = MBDK_WATCH_EVERY
    model%nb = nb
    model%nqb = merge(7, 6, opt%rotation == MBDK_ROT_QUATERNION)
    if (opt%rotation == MBDK_ROT_EULER313) model%seq = MBDK_SEQ_EULER313
    if (opt%rotation == MBDK_ROT_CARDAN123) model%seq = MBDK_SEQ_CARDAN123
    model%ns = ns
    model%n = nb * (model%nqb + 6) + ns
    model%ncoord = nb * model%nqb
    model%nvel = 6 * nb
    model%formulation = opt%formulation
  end subroutine lay_out_spatial_state

  !> The bodies' masses (positive, finite) and inertias (symmetric to roundoff, symmetrised,
  !> positive definite) and the inverse inertias; with quaternions, y0's of unit norm.
  subroutine take_bodies(model, mass, inertia, y0, stat, asked)
    type(mbdk_spatial_model_t), intent(inout) :: model
    real(dp), intent(in) :: mass(:), inertia(:, :, :), y0(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nb, b, k, info, astat
    real(dp) :: jb(3, 3)
    nb = model%nb
    allocate (model%mass(nb), model%inertia(3, 3, nb), model%inv_inertia(3, 3, nb), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * 19.0_dp * nb, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INVALID_INPUT
    do b = 1, nb
      if (.not. (mass(b) > 0.0_dp .and. mass(b) <= huge(1.0_dp))) return
      if (.not. all(abs(inertia(:, :, b)) <= huge(1.0_dp))) return
      jb = inertia(:, :, b)
      if (any(abs(jb - transpose(jb)) > 1.0e-12_dp * maxval(abs(jb)))) return
      model%mass(b) = mass(b)
      model%inertia(:, :, b) = 0.5_dp * (jb + transpose(jb))
      jb = model%inertia(:, :, b)
      call mbdk_chol_factor(jb, info)
      if (info /= MBDK_SUCCESS) return            ! not positive definite
      do k = 1, 3
        model%inv_inertia(:, k, b) = unit(k)
        call mbdk_chol_solve(jb, model%inv_inertia(:, k, b), info)
        if (info /= MBDK_SUCCESS) return
      end do
      if (model%opt%rotation == MBDK_ROT_QUATERNION) then
        if (.not. (abs(norm2(y0(qi(model, b) + 3:qi(model, b) + 6)) - 1.0_dp) <= 1.0e-8_dp)) return
      end if
    end do
    stat = MBDK_SUCCESS
  end subroutine take_bodies

  !> The joint table's types and bodies (body 1 a body, body 2 another or the ground), and m,
  !> the rows of the joints.
  subroutine count_joint_rows(model, jtype, jbody, stat)
    type(mbdk_spatial_model_t), intent(inout) :: model
    integer, intent(in) :: jtype(:), jbody(:, :)
    integer, intent(out) :: stat
    integer :: j
    stat = MBDK_ERR_INVALID_INPUT
    model%m = 0
    model%nprim = 0
    do j = 1, size(jtype)
      ! a joint of spatial scenes (the registry's kinds; a planar one is refused)
      if (.not. mbdk_element_applies(MBDK_CLASS_JOINT, jtype(j), MBDK_BODY_SPATIAL)) return
      if (jbody(1, j) < 1 .or. jbody(1, j) > model%nb .or. jbody(2, j) < 0 .or. &
          jbody(2, j) > model%nb) return
      if (jbody(1, j) == jbody(2, j)) return
      model%m = model%m + mbdk_joint_rows(jtype(j), MBDK_BODY_SPATIAL)
    end do
    stat = MBDK_SUCCESS
  end subroutine count_joint_rows

  !> The joints as primitive constraints (prim, and which rows are angles: row_angular), in
  !> table order, their rows in sequence. MBDK_ERR_INVALID_INPUT for an axis of zero length.
  subroutine build_primitives(model, jtype, jbody, jreal, fr, stat, asked)
    type(mbdk_spatial_model_t), intent(inout) :: model
    integer, intent(in) :: jtype(:), jbody(:, :)
    real(dp), intent(in) :: jreal(:, :)
    type(frames_t), intent(in) :: fr
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nj, j, row, astat, first
    nj = size(jtype)
    ! prismatic: 5 primitives
    allocate (model%prim(5 * nj), model%row_angular(model%m), stat=astat)
    call mbdk_alloc_status(astat, real(storage_size(model%prim), dp) / 8.0_dp * 5.0_dp * nj + &
                           MBDK_INT_BYTES * model%m, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    model%row_angular = .false.
    row = 1
    do j = 1, nj
      first = model%nprim + 1
      call add_joint_primitives(model, jtype(j), jbody(1, j), jbody(2, j), jreal(:, j), fr, &
                                row, stat)
      if (stat /= MBDK_SUCCESS) return
      model%prim(first:model%nprim)%joint = j
    end do
  end subroutine build_primitives

  !> Adds the primitives of one joint (type jt between bodies bi and bj, reals r) from row on.
  !> MBDK_ERR_INVALID_INPUT for an axis of zero length where the type needs one.
  subroutine add_joint_primitives(model, jt, bi, bj, r, fr, row, stat)
    type(mbdk_spatial_model_t), intent(inout) :: model
    integer, intent(in) :: jt, bi, bj
    real(dp), intent(in) :: r(:)
    type(frames_t), intent(in) :: fr
    integer, intent(inout) :: row
    integer, intent(out) :: stat
    real(dp) :: ai(3), aj(3), b1(3), b2(3), e(3, 3)
    real(dp), parameter :: zero3(3) = 0.0_dp
    integer :: k
    stat = MBDK_ERR_INVALID_INPUT
    ai = r(7:9)
    aj = r(10:12)
    if (any(jt == [MBDK_JOINT_REVOLUTE, MBDK_JOINT_UNIVERSAL, MBDK_JOINT_CYLINDRICAL, &
                   MBDK_JOINT_PRISMATIC, MBDK_JOINT_ANGLE_DRIVER, &
                   MBDK_JOINT_SLIDE_DRIVER])) then
      if (.not. (norm2(ai) > 0.0_dp .and. norm2(aj) > 0.0_dp)) return
      ai = ai / norm2(ai)
      aj = aj / norm2(aj)
    end if
    call normals(aj, b1, b2)
    select case (jt)
    case (MBDK_JOINT_SPHERICAL)
      call add(PRIM_SPH, r(1:3), r(4:6), zero3, zero3)
    case (MBDK_JOINT_REVOLUTE)
      call add(PRIM_SPH, r(1:3), r(4:6), zero3, zero3)
      call add(PRIM_DOT1, r(1:3), r(4:6), ai, b1)
      call add(PRIM_DOT1, r(1:3), r(4:6), ai, b2)
    case (MBDK_JOINT_UNIVERSAL)
      call add(PRIM_SPH, r(1:3), r(4:6), zero3, zero3)
      call add(PRIM_DOT1, r(1:3), r(4:6), ai, aj)
    case (MBDK_JOINT_CYLINDRICAL, MBDK_JOINT_PRISMATIC)
      call add(PRIM_DOT1, r(1:3), r(4:6), ai, b1)
      call add(PRIM_DOT1, r(1:3), r(4:6), ai, b2)
      call add(PRIM_DOT2, r(1:3), r(4:6), zero3, b1)
      call add(PRIM_DOT2, r(1:3), r(4:6), zero3, b2)
      ! the rotation about the axis: body i's image of b2 stays normal to b1
      if (jt == MBDK_JOINT_PRISMATIC) &
        call add(PRIM_DOT1, r(1:3), r(4:6), &
                 rtmul(fr%rot(:, :, bi), rmul(fr%rot(:, :, bj), b2)), b1)
    case (MBDK_JOINT_ANGLE_DRIVER)
      ! u on body i: body j's b1 as body i sees it at the start; v = b1, w = a_j x b1 on j
      call add(PRIM_ANGLE, zero3, zero3, &
               rtmul(fr%rot(:, :, bi), rmul(fr%rot(:, :, bj), b1)), b1)
      model%prim(model%nprim)%wj = b2
      model%prim(model%nprim)%fn = r(13:17)
      model%has_drivers = .true.
    case (MBDK_JOINT_SLIDE_DRIVER)
      ! the offset of the joint points along a_j (on body j) follows f(t)
      call add(PRIM_SLIDE, r(1:3), r(4:6), zero3, aj)
      model%prim(model%nprim)%fn = r(13:17)
      model%has_drivers = .true.
    case (MBDK_JOINT_FIXED)
      call add(PRIM_SPH, r(1:3), r(4:6), zero3, zero3)
      ! body i's images of body j's axes e_k at the start: e1'.e2 = e2'.e3 = e3'.e1 = 0
      ! lock the three relative rotations
      e = matmul(transpose(fr%rot(:, :, bi)), fr%rot(:, :, bj))
      do k = 1, 3
        call add(PRIM_DOT1, r(1:3), r(4:6), e(:, k), unit(mod(k, 3) + 1))
      end do
    end select
    stat = MBDK_SUCCESS

  contains

    subroutine add(kind, si, sj, ui, uj)
      integer, intent(in) :: kind
      real(dp), intent(in) :: si(3), sj(3), ui(3), uj(3)
      model%nprim = model%nprim + 1
      model%prim(model%nprim) = prim_t(kind, bi, bj, row, si, sj, ui, uj)
      if (kind == PRIM_DOT1 .or. kind == PRIM_ANGLE) model%row_angular(row) = .true.
      row = row + merge(3, 1, kind == PRIM_SPH)
    end subroutine add

  end subroutine add_joint_primitives

  !> The force table, checked, into the model (planes' normals made unit), whether the scene
  !> has power to integrate, its contacts (events with locate_events) and its wear elements.
  subroutine take_forces(model, ftype, fbody, freal, stat, asked)
    type(mbdk_spatial_model_t), intent(inout) :: model
    integer, intent(in) :: ftype(:), fbody(:, :)
    real(dp), intent(in) :: freal(:, :)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: k, astat
    model%nf = size(ftype)
    allocate (model%ftype(model%nf), model%fbody(2, model%nf), &
              model%freal(MBDK_SPATIAL_FORCE_REALS, model%nf), model%wear(model%ns), stat=astat)
    call mbdk_alloc_status(astat, (3.0_dp * MBDK_INT_BYTES + MBDK_SPATIAL_FORCE_REALS * &
                                   MBDK_REAL_BYTES) * model%nf + MBDK_INT_BYTES * model%ns, &
                           stat, asked)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. spatial_forces_ok(model%nb, ftype, fbody, freal)) return
    ! loads and springs; of the contacts, those with damping or friction (an undamped,
    ! frictionless contact does no net work); wear exerts no force
    model%has_power = any(ftype /= MBDK_FORCE_GRAVITY .and. .not. is_contact(ftype) .and. &
                          ftype /= MBDK_EFFECT_WEAR)
    do k = 1, model%nf
      if (is_contact(ftype(k)) .and. (freal(14, k) /= 0.0_dp .or. &
          mbdk_contact3d_rough(freal(:, k)))) model%has_power = .true.
    end do
    if (model%has_drivers) model%has_power = .true.
    model%ftype = ftype
    model%fbody = fbody
    model%freal = freal
    do k = 1, model%nf
      if (ftype(k) == MBDK_FORCE_SPHERE_PLANE) &
        model%freal(8:10, k) = freal(8:10, k) / norm2(freal(8:10, k))
    end do
    model%ncontacts = count(is_contact(ftype))
    if (model%opt%locate_events /= 0) model%nevents = 2 * model%ncontacts
    model%wear = pack([(k, k = 1, model%nf)], ftype == MBDK_EFFECT_WEAR)
    stat = MBDK_SUCCESS
  end subroutine take_forces

  !> Each force's type and bodies (a point force or torque on a body; a spring-damper between
  !> two, one of them possibly the ground, with k, c, l0 >= 0; contacts: spatial_contact_ok;
  !> wear: spatial_wear_ok).
  pure logical function spatial_forces_ok(nb, ftype, fbody, freal) result(ok)
    integer, intent(in) :: nb
    integer, intent(in) :: ftype(:), fbody(:, :)
    real(dp), intent(in) :: freal(:, :)
    integer :: k
    ok = .false.
    do k = 1, size(ftype)
      if (.not. mbdk_element_applies(MBDK_CLASS_FORCE, ftype(k), MBDK_BODY_SPATIAL)) return
      select case (ftype(k))
      case (MBDK_FORCE_POINT, MBDK_FORCE_TORQUE)
        if (fbody(1, k) < 1 .or. fbody(1, k) > nb) return
      case (MBDK_FORCE_SPRING_DAMPER)
        if (fbody(1, k) < 1 .or. fbody(1, k) > nb .or. fbody(2, k) < 0 .or. &
            fbody(2, k) > nb .or. fbody(1, k) == fbody(2, k)) return
        if (.not. all(freal(7:9, k) >= 0.0_dp)) return
      case (MBDK_FORCE_SPHERE_PLANE, MBDK_FORCE_SPHERE_SPHERE)
        if (.not. spatial_contact_ok(nb, ftype(k), fbody(:, k), freal(:, k))) return
      case (MBDK_EFFECT_WEAR)
        if (.not. spatial_wear_ok(ftype, fbody(:, k), freal, k)) return
      end select
    end do
    ok = .true.
  end function spatial_forces_ok

  !> Wear entry k (the model's header): its column a contact of the table, its law archard or
  !> knee, its load a normal force or, on a contact with friction, a friction force; k >= 0.
  pure logical function spatial_wear_ok(ftype, fb, freal, k) result(ok)
    integer, intent(in) :: ftype(:), fb(2), k
    real(dp), intent(in) :: freal(:, :)
    integer :: c
    ok = .false.
    c = fb(1)
    if (c < 1 .or. c > size(ftype)) return
    if (.not. is_contact(ftype(c))) return
    if (fb(2) /= MBDK_WEAR_ARCHARD .and. fb(2) /= MBDK_WEAR_KNEE) return
    if (.not. freal(1, k) >= 0.0_dp) return
    if (freal(6, k) == real(MBDK_WEAR_LOAD_FRICTION, dp)) then
      if (.not. mbdk_contact3d_rough(freal(:, c))) return
    else if (freal(6, k) /= real(MBDK_WEAR_LOAD_NORMAL, dp)) then
      return
    end if
    ok = .true.
  end function spatial_wear_ok

  !> A contact of type ft (sphere_plane, sphere_sphere) between bodies fb, reals r: body1 a
  !> body, body2 the ground or another body; radii >= 0 (two spheres: not both 0), a plane's
  !> normal of nonzero length, k >= 0, e >= 1, cmax, dmax >= 0; mus, mud >= 0 and 0 < vs < vd.
  pure logical function spatial_contact_ok(nb, ft, fb, r) result(ok)
    integer, intent(in) :: nb, ft, fb(2)
    real(dp), intent(in) :: r(:)
    ok = .false.
    if (fb(1) < 1 .or. fb(1) > nb .or. fb(2) < 0 .or. fb(2) > nb .or. fb(1) == fb(2)) return
    if (.not. (r(4) >= 0.0_dp .and. r(11) >= 0.0_dp .and. r(12) >= 0.0_dp .and. &
               r(13) >= 1.0_dp .and. r(14) >= 0.0_dp .and. r(15) >= 0.0_dp .and. &
               r(16) >= 0.0_dp .and. r(17) >= 0.0_dp .and. r(18) > 0.0_dp .and. &
               r(19) > r(18))) return
    if (ft == MBDK_FORCE_SPHERE_PLANE .and. .not. (norm2(r(8:10)) > 0.0_dp)) return
    if (ft == MBDK_FORCE_SPHERE_SPHERE .and. .not. (r(4) + r(11) > 0.0_dp)) return
    ok = .true.
  end function spatial_contact_ok

  !> Whether a force type is a contact (its events, its length in the watch's scale, its power
  !> where it is damped or rough).
  elemental logical function is_contact(ft)
    integer, intent(in) :: ft
    is_contact = ft == MBDK_FORCE_SPHERE_PLANE .or. ft == MBDK_FORCE_SPHERE_SPHERE
  end function is_contact

  !> Whether a force type may load two bodies (its fbody(1:2), either the ground: 0), as forces
  !> applies it: the couplings of the body graph (the sparse index-3 matrix's pattern and
  !> colors). A sphere-plane contact's plane may sit on a second body.
  elemental logical function loads_two_bodies(ft)
    integer, intent(in) :: ft
    loads_two_bodies = ft == MBDK_FORCE_SPRING_DAMPER .or. is_contact(ft)
  end function loads_two_bodies

  !> The watch's scales: the length (joint and spring points, spheres, the bodies' spread; else
  !> 1) and gscale, gravity's energy over that length or a radius of gyration (not the 1); and
  !> geo_length, the same length with the ground's points (which are in space) taken from the
  !> bodies' centre.
  subroutine watch_scales(model, fr)
    type(mbdk_spatial_model_t), intent(inout) :: model
    type(frames_t), intent(in) :: fr
    integer :: k, b, nb
    real(dp) :: reach, centre(3), local, spread
    nb = model%nb
    centre = 0.0_dp
    if (nb > 0) centre = sum(fr%r(:, 1:nb), 2) / nb
    model%length = 0.0_dp
    model%geo_length = 0.0_dp
    do k = 1, model%nprim
      associate (p => model%prim(k))
        model%length = max(model%length, norm2(p%si), norm2(p%sj))
        if (p%kind == PRIM_ANGLE) cycle          ! (its si, sj are no points)
        local = norm2(p%sj)
        if (p%bj == 0) local = norm2(p%sj - centre)
        model%geo_length = max(model%geo_length, norm2(p%si), local)
      end associate
    end do
    associate (ftype => model%ftype, freal => model%freal)
      do k = 1, model%nf
        if (ftype(k) == MBDK_FORCE_SPRING_DAMPER) then
          model%length = max(model%length, norm2(freal(1:3, k)), norm2(freal(4:6, k)))
          local = norm2(freal(4:6, k))
          if (model%fbody(2, k) == 0) local = norm2(freal(4:6, k) - centre)
          model%geo_length = max(model%geo_length, norm2(freal(1:3, k)), local)
        end if
        if (is_contact(ftype(k))) then
          model%length = max(model%length, norm2(freal(1:3, k)) + freal(4, k))
          model%geo_length = max(model%geo_length, norm2(freal(1:3, k)) + freal(4, k))
        end if
      end do
      spread = 0.0_dp
      do b = 1, nb
        spread = max(spread, 2.0_dp * norm2(fr%r(:, b) - centre))
      end do
      model%length = max(model%length, spread)
      model%geo_length = max(model%geo_length, spread)
      if (.not. (model%geo_length > 0.0_dp)) model%geo_length = 1.0_dp
      reach = model%length
      do b = 1, nb
        reach = max(reach, sqrt((model%inertia(1, 1, b) + model%inertia(2, 2, b) + &
                                 model%inertia(3, 3, b)) / (2.0_dp * model%mass(b))))
      end do
      if (.not. (model%length > 0.0_dp)) model%length = 1.0_dp
      model%gscale = 0.0_dp
      do k = 1, model%nf
        if (ftype(k) == MBDK_FORCE_GRAVITY) model%gscale = model%gscale + norm2(freal(1:3, k))
      end do
      model%gscale = model%gscale * sum(model%mass) * reach
    end associate
  end subroutine watch_scales

  !> The rows solved (active) and rank0: with redundant joints the independent rows the
  !> rank-revealing Cholesky picks at t0 (any rank accepted there), else every row; with them
  !> each row's bodies (rbody) and whether the joints form a regular tree (regular_tree).
  subroutine choose_active_rows(model, fr, t0, jbody, stat, asked)
    type(mbdk_spatial_model_t), intent(inout) :: model
    type(frames_t), intent(in) :: fr
    real(dp), intent(in) :: t0
    integer, intent(in) :: jbody(:, :)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: k, astat
    integer, allocatable :: rows(:), rbody(:, :)
    real(dp), allocatable :: phi(:), c(:, :), gam(:)
    integer, allocatable :: edge(:)
    logical :: independent, tree
    allocate (model%all_rows(model%m), rbody(2, model%m), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * 3.0_dp * model%m, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call row_bodies(model, rbody)
    call move_alloc(rbody, model%rbody)
    do k = 1, model%m
      model%all_rows(k) = k
    end do
    model%rank0 = model%m
    ! many rows on a tree of joints: each joint's rows on its own (the whole C has the rank of
    ! its joints' then), so that neither a dense C nor its factorisation is ever formed
    independent = .false.
    tree = .false.
    if (model%m > 0) then
      call joint_edges(jbody, model%nb, edge, tree, stat, asked)
      if (stat /= MBDK_SUCCESS) return
    end if
    if (model%m > MBDK_SPATIAL_SPARSE_ROWS .and. tree) then
      call tree_rows(model, fr, t0, edge, independent, stat, asked)
      if (stat /= MBDK_SUCCESS) return
    end if
    if (independent) then
      allocate (model%active(model%m), stat=astat)
      call mbdk_alloc_status(astat, MBDK_INT_BYTES * model%m, stat, asked)
      if (stat /= MBDK_SUCCESS) return
      model%active = model%all_rows
    else if (model%m > 0) then
      allocate (phi(model%m), c(model%m, 6 * model%nb), gam(model%m), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * real(model%m, dp) * &
                             (6.0_dp * model%nb + 2), stat, asked)
      if (stat /= MBDK_SUCCESS) return
      call constraints(model, fr, t0, phi, c, gam)
      model%rank0 = 0                     ! any rank is accepted at the start
      call select_rows(model, c, rows, stat, asked)
      if (stat /= MBDK_SUCCESS) return
      call move_alloc(rows, model%active)
      model%rank0 = size(model%active)
      independent = model%rank0 == model%m
    else
      allocate (model%active(0), stat=astat)
      call mbdk_alloc_status(astat, 0.0_dp, stat, asked)
    end if
    model%regular_tree = tree .and. independent .and. &
      .not. model%has_drivers
  end subroutine choose_active_rows

  !> The joints jbody(2, nj) (0: the ground) as edges between bodies: edge(k) of joint k, the
  !> same for joints on the same two bodies (a driver and the joint it drives: one connection),
  !> and whether the edges form a tree (a forest: none closes a loop of the others; union-find
  !> over the bodies and the ground). A joint's partner bodies are looked up in per-body lists,
  !> so the cost grows as the joints do.
  subroutine joint_edges(jbody, nb, edge, tree, stat, asked)
    integer, intent(in) :: jbody(:, :), nb
    integer, allocatable, intent(out) :: edge(:)
    logical, intent(out) :: tree
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer, allocatable :: parent(:), head(:), nxt(:), partner(:), pedge(:)
    integer :: nj, k, a, b, x, y, node, ne, astat
    nj = size(jbody, 2)
    tree = .false.
    allocate (edge(nj), parent(0:nb), head(0:nb), nxt(nj), partner(nj), pedge(nj), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (5.0_dp * nj + 2.0_dp * (nb + 1)), stat, &
                           asked)
    if (stat /= MBDK_SUCCESS) return
    parent = [(k, k = 0, nb)]
    head = 0
    ne = 0
    do k = 1, nj
      a = min(jbody(1, k), jbody(2, k))
      b = max(jbody(1, k), jbody(2, k))
      ! a connection a-b made before: this joint is part of it
      edge(k) = 0
      node = head(b)
      do while (node /= 0)
        if (partner(node) == a) then
          edge(k) = pedge(node)
          exit
        end if
        node = nxt(node)
      end do
      if (edge(k) /= 0) cycle
      x = root(a)
      y = root(b)
      if (x == y) return                   ! a loop
      parent(x) = y
      ne = ne + 1
      edge(k) = ne
      nxt(k) = head(b)
      partner(k) = a
      pedge(k) = ne
      head(b) = k
    end do
    tree = .true.
  contains
    integer function root(z) result(r)
      integer, intent(in) :: z
      r = z
      do while (parent(r) /= r)
        r = parent(r)
      end do
    end function root
  end subroutine joint_edges

  !> On a tree of joints, whether each connection's rows (a joint's, with a driver's on the
  !> same two bodies; edge) are independent (then all the rows are), judged as select_rows
  !> judges the whole C (the geometry's Gram matrix at unit diagonal, pivoted Cholesky,
  !> REDUNDANT_RTOL). A connection of more than 6 rows, or dependent ones, leaves the verdict
  !> to the dense test (independent false); a vanishing row is MBDK_ERR_SINGULAR_MATRIX, as
  !> there.
  subroutine tree_rows(model, fr, t0, edge, independent, stat, asked)
    type(mbdk_spatial_model_t), intent(in) :: model
    type(frames_t), intent(in) :: fr
    real(dp), intent(in) :: t0
    integer, intent(in) :: edge(:)
    logical, intent(out) :: independent
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    real(dp), allocatable :: phi(:), cc(:, :), gam(:)
    integer, allocatable :: redge(:), start(:), list(:)
    real(dp) :: g(6, 6), w(6), d(6)
    integer :: piv(6), rows(6), k, n, i, j, e, ne, astat, rk, a, b
    independent = .false.
    ne = 0
    if (size(edge) > 0) ne = maxval(edge)
    allocate (phi(model%m), cc(model%m, 12), gam(model%m), redge(model%m), start(ne + 1), &
              list(model%m), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * 14.0_dp * model%m + &
                           MBDK_INT_BYTES * (2.0_dp * model%m + ne + 1), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call constraints(model, fr, t0, phi, cc, gam, compact=.true.)
    do k = 1, model%nprim
      n = merge(3, 1, model%prim(k)%kind == PRIM_SPH)
      do i = model%prim(k)%row, model%prim(k)%row + n - 1
        redge(i) = edge(model%prim(k)%joint)
      end do
    end do
    ! the rows of each connection, bucketed (a driver's row need not follow its joint's)
    start = 0
    do i = 1, model%m
      start(redge(i) + 1) = start(redge(i) + 1) + 1
    end do
    start(1) = 1
    do e = 1, ne
      start(e + 1) = start(e + 1) + start(e)
    end do
    do i = 1, model%m
      list(start(redge(i))) = i
      start(redge(i)) = start(redge(i)) + 1
    end do
    do e = ne, 1, -1                     ! back to each bucket's first entry
      start(e + 1) = start(e)
    end do
    start(1) = 1
    ! the geometry's weight: rotations as the displacements they give at the length scale
    w = [1.0_dp, 1.0_dp, 1.0_dp, 1.0_dp / model%geo_length**2, 1.0_dp / model%geo_length**2, &
         1.0_dp / model%geo_length**2]
    do e = 1, ne
      n = start(e + 1) - start(e)
      stat = MBDK_SUCCESS
      if (n == 0) cycle
      if (n > 6) return                  ! more than a joint can hold: the dense test decides
      rows(1:n) = list(start(e):start(e + 1) - 1)
      ! G's entries body by body: the rows of one connection are on its two bodies, in either
      ! slot (a driver may list them the other way round from the joint it drives)
      g = 0.0_dp
      do j = 1, n
        do i = 1, n
          do a = 1, 2
            do b = 1, 2
              if (model%rbody(a, rows(i)) == 0 .or. &
                  model%rbody(a, rows(i)) /= model%rbody(b, rows(j))) cycle
              g(i, j) = g(i, j) + sum(cc(rows(i), 6 * a - 5:6 * a) * w * &
                                      cc(rows(j), 6 * b - 5:6 * b))
            end do
          end do
        end do
      end do
      stat = MBDK_ERR_SINGULAR_MATRIX
      do i = 1, n
        if (.not. (g(i, i) > 0.0_dp)) return
      end do
      d(1:n) = 1.0_dp / sqrt([(g(i, i), i = 1, n)])
      do j = 1, n
        g(1:n, j) = g(1:n, j) * d(1:n) * d(j)
      end do
      call mbdk_chol_pivoted(g(1:n, 1:n), piv(1:n), rk, REDUNDANT_RTOL, stat)
      if (stat /= MBDK_SUCCESS) return
      stat = MBDK_SUCCESS
      if (rk < n) return                 ! dependent rows: the dense test chooses among them
    end do
    independent = .true.
    stat = MBDK_SUCCESS

  end subroutine tree_rows

  !> The components of the momentum and angular momentum a spatial scene conserves, from its
  !> elements alone (mbdk_watch's rule): inv(:, 1:ninv).
  subroutine spatial_invariants(jtype, jbody, jreal, ftype, fbody, freal, inv, ninv)
    integer, intent(in) :: jtype(:), jbody(:, :), ftype(:), fbody(:, :)
    real(dp), intent(in) :: jreal(:, :), freal(:, :)
    real(dp), intent(out) :: inv(MBDK_INV_WORDS, MBDK_INV_MAX)
    integer, intent(out) :: ninv
    type(mbdk_inv_rule_t) :: rule
    integer :: j, k
    real(dp) :: a(3), b1(3), b2(3)
    do j = 1, size(jtype)
      if (jbody(2, j) /= 0 .and. jtype(j) /= MBDK_JOINT_ANGLE_DRIVER .and. &
          jtype(j) /= MBDK_JOINT_SLIDE_DRIVER) cycle   ! between two bodies: internal
      select case (jtype(j))
      case (MBDK_JOINT_SPHERICAL)
        ! a force at the ground point (global)
        call mbdk_inv_pivot(rule, jreal(4:6, j))
      case (MBDK_JOINT_REVOLUTE)
        ! and moments normal to the axis (global for the ground)
        call mbdk_inv_pivot(rule, jreal(4:6, j), jreal(10:12, j))
      case (MBDK_JOINT_CYLINDRICAL, MBDK_JOINT_PRISMATIC)
        ! forces across the axis (and moments)
        a = jreal(10:12, j)
        if (.not. (norm2(a) > 0.0_dp)) then
          call mbdk_inv_external(rule)
          cycle
        end if
        call normals(a / norm2(a), b1, b2)
        call mbdk_inv_force(rule, b1)
        call mbdk_inv_force(rule, b2)
      case default   ! fixed and universal joints to the ground, drivers
        call mbdk_inv_external(rule)
      end select
    end do
    do k = 1, size(ftype)
      select case (ftype(k))
      case (MBDK_FORCE_GRAVITY)
        call mbdk_inv_gravity(rule, freal(1:3, k))
      case (MBDK_FORCE_SPRING_DAMPER)
        ! along the line of its points: to the ground, through the ground point
        if (fbody(2, k) == 0) call mbdk_inv_pivot(rule, freal(4:6, k))
      case (MBDK_FORCE_POINT)
        call mbdk_inv_force(rule, freal(4:6, k))
      case (MBDK_FORCE_TORQUE)
        call mbdk_inv_moment(rule)
      case (MBDK_EFFECT_WEAR)
        cycle              ! a state of its own, no force
      case (MBDK_FORCE_SPHERE_PLANE, MBDK_FORCE_SPHERE_SPHERE)
        ! between two bodies: equal and opposite at one point, internal; to the ground without
        ! friction: along the ground plane's normal, or through the ground sphere's centre
        if (fbody(2, k) /= 0) cycle
        if (mbdk_contact3d_rough(freal(:, k))) then
          call mbdk_inv_external(rule)
        else if (ftype(k) == MBDK_FORCE_SPHERE_PLANE) then
          call mbdk_inv_force(rule, freal(8:10, k))
        else
          call mbdk_inv_pivot(rule, freal(5:7, k))
        end if
      case default
        call mbdk_inv_external(rule)
      end select
    end do
    call mbdk_inv_result(rule, .false., inv, ninv)
  end subroutine spatial_invariants

  !> The momentum p = sum m_b v_b and the angular momentum H = sum (r_b - c) x m_b v_b +
  !> R_b J_b W_b (mom = (p, H)) about the point of the scene's conserved components (a fixed
  !> point, or the centre of mass c), and their scales msc = (sum m_b |v_b|, sum |r_b - c| m_b
  !> |v_b - v_c| + |J_b W_b|) (mbdk_watch).
  pure subroutine spatial_momenta(model, fr, mom, msc)
    type(mbdk_spatial_model_t), intent(in) :: model
    type(frames_t), intent(in) :: fr
    real(dp), intent(out) :: mom(6), msc(2)
    real(dp) :: c(3), vc(3), d(3), jw(3), total
    integer :: b
    mom = 0.0_dp
    msc = 0.0_dp
    c = 0.0_dp
    total = sum(model%mass)
    do b = 1, model%nb
      mom(1:3) = mom(1:3) + model%mass(b) * fr%v(:, b)
      msc(1) = msc(1) + model%mass(b) * norm2(fr%v(:, b))
      c = c + model%mass(b) * fr%r(:, b)
    end do
    if (model%ninv > 0 .and. nint(model%inv(1, model%ninv)) == MBDK_INV_ANGULAR_POINT) then
      c = model%inv(5:7, model%ninv)
      vc = 0.0_dp
    else
      c = c / total
      vc = mom(1:3) / total
    end if
    do b = 1, model%nb
      d = fr%r(:, b) - c
      jw = rmul(model%inertia(:, :, b), fr%om(:, b))
      mom(4:6) = mom(4:6) + model%mass(b) * cross(d, fr%v(:, b)) + &
        rmul(fr%rot(:, :, b), jw)
      msc(2) = msc(2) + model%mass(b) * norm2(d) * norm2(fr%v(:, b) - vc) + norm2(jw)
    end do
  end subroutine spatial_momenta

  pure function unit(k) result(e)
    integer, intent(in) :: k
    real(dp) :: e(3)
    e = 0.0_dp
    e(k) = 1.0_dp
  end function unit

  !> Two unit vectors normal to the unit vector a and to each other.
  pure subroutine normals(a, b1, b2)
    real(dp), intent(in) :: a(3)
    real(dp), intent(out) :: b1(3), b2(3)
    integer :: k
    if (.not. (norm2(a) > 0.0_dp)) then
      b1 = unit(1)
      b2 = unit(2)
      return
    end if
    k = minloc(abs(a), 1)               ! the coordinate axis least aligned with a
    b1 = cross(a, unit(k))
    b1 = b1 / norm2(b1)
    b2 = cross(a, b1)
  end subroutine normals


  !> index in y of body b's first coordinate; of its first velocity
  pure integer function qi(model, b)
    type(mbdk_spatial_model_t), intent(in) :: model
    integer, intent(in) :: b
    qi = (b - 1) * model%nqb + 1
  end function qi

  pure integer function wi(model, b)
    type(mbdk_spatial_model_t), intent(in) :: model
    integer, intent(in) :: b
    wi = model%nb * model%nqb + (b - 1) * 6 + 1
  end function wi

  !> index in y of the bodies' last velocity: the effects' states (wear) follow it
  pure integer function last_velocity(model)
    type(mbdk_spatial_model_t), intent(in) :: model
    last_velocity = model%ncoord + model%nvel
  end function last_velocity

  !> The rotation matrix of body b's orientation coordinates (a quaternion taken as p / |p|).
  pure subroutine orientation(model, p, rot, stat)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: p(:)
    real(dp), intent(out) :: rot(3, 3)
    integer, intent(out) :: stat
    real(dp) :: u(4)
    if (model%opt%rotation == MBDK_ROT_QUATERNION) then
      stat = MBDK_ERR_NONFINITE
      rot = 0.0_dp
      if (.not. (norm2(p(1:4)) > 0.0_dp)) return
      u = p(1:4) / norm2(p(1:4))
      rot = mbdk_quat_matrix_of(u)
      stat = MBDK_SUCCESS
    else
      call mbdk_angles_matrix(model%seq, p(1:3), rot, stat)
    end if
  end subroutine orientation

  !> Positions, rotations and velocities of every body at y (column 0: the ground).
  !> MBDK_ERR_NO_MEMORY: asked gets the bytes (mbdk_memory).
  pure subroutine frames(model, y, fr, stat, asked)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: y(:)
    type(frames_t), intent(inout) :: fr   !< its arrays kept where already of the model's size
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: b, k
    k = 0
    if (allocated(fr%r)) then
      if (size(fr%r, 2) /= model%nb + 1) deallocate (fr%r)
    end if
    ! (all four or none: an allocation that failed part-way is redone whole)
    if (.not. (allocated(fr%r) .and. allocated(fr%rot) .and. allocated(fr%v) .and. &
               allocated(fr%om))) then
      if (allocated(fr%r)) deallocate (fr%r)
      if (allocated(fr%rot)) deallocate (fr%rot)
      if (allocated(fr%v)) deallocate (fr%v)
      if (allocated(fr%om)) deallocate (fr%om)
      allocate (fr%r(3, 0:model%nb), fr%rot(3, 3, 0:model%nb), fr%v(3, 0:model%nb), &
                fr%om(3, 0:model%nb), stat=k)
    end if
    stat = MBDK_ERR_NO_MEMORY
    if (k /= 0) then
      if (present(asked)) asked = MBDK_REAL_BYTES * 18.0_dp * (model%nb + 1)
      return
    end if
    fr%r(:, 0) = 0.0_dp
    fr%rot(:, :, 0) = 0.0_dp
    do k = 1, 3
      fr%rot(k, k, 0) = 1.0_dp
    end do
    fr%v(:, 0) = 0.0_dp
    fr%om(:, 0) = 0.0_dp
    stat = MBDK_SUCCESS
    do b = 1, model%nb
      k = qi(model, b)
      fr%r(:, b) = y(k:k + 2)
      call orientation(model, y(k + 3:k + model%nqb - 1), fr%rot(:, :, b), stat)
      if (stat /= MBDK_SUCCESS) return
      k = wi(model, b)
      fr%v(:, b) = y(k:k + 2)
      fr%om(:, b) = y(k + 3:k + 5)
    end do
  end subroutine frames

  ! ---- the constraints ---------------------------------------------------------------------

  !> Phi (m), C (m x 6 nb), gamma (the terms of Phi'' other than C w': -(C' w), and for a driver
  !> -(2 C_t w + Phi_tt)) and, if asked, Phi_t at time t and the frames: primitive by primitive,
  !> each kind's rows by a routine of its own.
  pure subroutine constraints(model, fr, t, phi, c, gam, phit, compact)
    type(mbdk_spatial_model_t), intent(in) :: model
    type(frames_t), intent(in) :: fr
    real(dp), intent(in) :: t
    real(dp), intent(out) :: phi(:), c(:, :), gam(:)
    real(dp), intent(out), optional :: phit(:)
    !> c in compact rows (m, 12): each row's columns of its body i, then of its body j
    !> (rbody), the same values as C's
    logical, intent(in), optional :: compact
    integer :: k, r, oi, oj
    real(dp) :: f, fd, fdd, pt
    logical :: cmp
    cmp = .false.
    if (present(compact)) cmp = compact
    phi = 0.0_dp
    c = 0.0_dp
    gam = 0.0_dp
    if (present(phit)) phit = 0.0_dp
    do k = 1, model%nprim
      associate (pr => model%prim(k))
        r = pr%row
        if (cmp) then
          oi = 0
          oj = 6
        else
          oi = 6 * (pr%bi - 1)
          oj = 6 * (pr%bj - 1)
        end if
        select case (pr%kind)
        case (PRIM_SPH)
          call sph_rows(pr, fr, oi, oj, phi(r:r + 2), c(r:r + 2, :), gam(r:r + 2))
        case (PRIM_DOT1)
          call dot1_row(pr, fr, oi, oj, phi(r), c(r, :), gam(r))
        case (PRIM_DOT2)
          call dot2_row(pr, fr, oi, oj, phi(r), c(r, :), gam(r))
        case (PRIM_SLIDE)
          ! Phi = d . h - f(t), d = R_j u_j, h = P_i - P_j: PRIM_DOT2 less the slide f(t)
          call mbdk_time_fn(pr%fn, t, f, fd, fdd)
          call dot2_row(pr, fr, oi, oj, phi(r), c(r, :), gam(r))
          phi(r) = phi(r) - f
          if (present(phit)) phit(r) = -fd
          gam(r) = gam(r) + fdd
        case (PRIM_ANGLE)
          call angle_row(pr, fr, oi, oj, t, phi(r), c(r, :), gam(r), pt)
          if (present(phit)) phit(r) = pt
        end select
      end associate
    end do
  end subroutine constraints

  !> A point on a point (PRIM_SPH), three rows: Phi = P_i - P_j with P = r + R s.
  pure subroutine sph_rows(pr, fr, oi, oj, phi, c, gam)
    type(prim_t), intent(in) :: pr
    type(frames_t), intent(in) :: fr
    integer, intent(in) :: oi, oj
    real(dp), intent(out) :: phi(3), gam(3)
    real(dp), intent(inout) :: c(:, :)
    real(dp) :: pi(3), pj(3)
    associate (i => pr%bi, j => pr%bj)
      pi = fr%r(:, i) + rmul(fr%rot(:, :, i), pr%si)
      pj = fr%r(:, j) + rmul(fr%rot(:, :, j), pr%sj)
      phi = pi - pj
      call point_cols(fr, c, i, oi, pr%si, 1.0_dp)
      call point_cols(fr, c, j, oj, pr%sj, -1.0_dp)
      gam = -(pquad(fr, i, pr%si) - pquad(fr, j, pr%sj))
    end associate
  end subroutine sph_rows

  !> Two body vectors normal (PRIM_DOT1), one row: Phi = (R_i u_i) . (R_j u_j).
  pure subroutine dot1_row(pr, fr, oi, oj, phi, cr, gam)
    type(prim_t), intent(in) :: pr
    type(frames_t), intent(in) :: fr
    integer, intent(in) :: oi, oj
    real(dp), intent(out) :: phi, gam
    real(dp), intent(inout) :: cr(:)
    real(dp) :: di(3), dj(3), ddi(3), ddj(3)
    associate (i => pr%bi, j => pr%bj)
      di = rmul(fr%rot(:, :, i), pr%ui)
      dj = rmul(fr%rot(:, :, j), pr%uj)
      phi = dot_product(di, dj)
      call vec_cols(fr, cr, i, oi, pr%ui, dj)
      call vec_cols(fr, cr, j, oj, pr%uj, di)
      ddi = vvel(fr, i, pr%ui)
      ddj = vvel(fr, j, pr%uj)
      gam = -(dot_product(dj, vquad(fr, i, pr%ui)) + dot_product(di, vquad(fr, j, pr%uj)) + &
              2.0_dp * dot_product(ddi, ddj))
    end associate
  end subroutine dot1_row

  !> A vector of body j normal to the joint points' offset (PRIM_DOT2), one row:
  !> Phi = d . h, d = R_j u_j, h = P_i - P_j.
  pure subroutine dot2_row(pr, fr, oi, oj, phi, cr, gam)
    type(prim_t), intent(in) :: pr
    type(frames_t), intent(in) :: fr
    integer, intent(in) :: oi, oj
    real(dp), intent(out) :: phi, gam
    real(dp), intent(inout) :: cr(:)
    real(dp) :: pi(3), pj(3), dj(3), h(3), hd(3)
    associate (i => pr%bi, j => pr%bj)
      dj = rmul(fr%rot(:, :, j), pr%uj)
      pi = fr%r(:, i) + rmul(fr%rot(:, :, i), pr%si)
      pj = fr%r(:, j) + rmul(fr%rot(:, :, j), pr%sj)
      h = pi - pj
      phi = dot_product(dj, h)
      call point_row(fr, cr, i, oi, pr%si, dj)
      call point_row(fr, cr, j, oj, pr%sj, -dj)
      call vec_cols(fr, cr, j, oj, pr%uj, h)
      hd = pvel(fr, i, pr%si) - pvel(fr, j, pr%sj)
      gam = -(dot_product(vquad(fr, j, pr%uj), h) + 2.0_dp * dot_product(vvel(fr, j, pr%uj), hd) &
              + dot_product(dj, pquad(fr, i, pr%si) - pquad(fr, j, pr%sj)))
    end associate
  end subroutine dot2_row

  !> The driven angle (PRIM_ANGLE), one row: Phi = cos f A - sin f B = sin(theta - f), with
  !> A = u . w = sin theta, B = u . v = cos theta (u = R_i ui, v = R_j uj, w = R_j wj); phit.
  pure subroutine angle_row(pr, fr, oi, oj, t, phi, cr, gam, phit)
    type(prim_t), intent(in) :: pr
    type(frames_t), intent(in) :: fr
    integer, intent(in) :: oi, oj
    real(dp), intent(in) :: t
    real(dp), intent(out) :: phi, gam, phit
    real(dp), intent(inout) :: cr(:)
    real(dp) :: di(3), ddi(3), dv(3), dw(3), f, fd, fdd, cf, sf, a, b, qa, qb, da, db
    associate (i => pr%bi, j => pr%bj)
      call mbdk_time_fn(pr%fn, t, f, fd, fdd)
      cf = cos(f)
      sf = sin(f)
      di = rmul(fr%rot(:, :, i), pr%ui)
      dv = rmul(fr%rot(:, :, j), pr%uj)
      dw = rmul(fr%rot(:, :, j), pr%wj)
      a = dot_product(di, dw)
      b = dot_product(di, dv)
      phi = cf * a - sf * b
      call vec_cols(fr, cr, i, oi, pr%ui, cf * dw - sf * dv)
      call vec_cols(fr, cr, j, oj, pr%wj, cf * di)
      call vec_cols(fr, cr, j, oj, pr%uj, -sf * di)
      ddi = vvel(fr, i, pr%ui)
      qa = dot_product(dw, vquad(fr, i, pr%ui)) + dot_product(di, vquad(fr, j, pr%wj)) + &
        2.0_dp * dot_product(ddi, vvel(fr, j, pr%wj))
      qb = dot_product(dv, vquad(fr, i, pr%ui)) + dot_product(di, vquad(fr, j, pr%uj)) + &
        2.0_dp * dot_product(ddi, vvel(fr, j, pr%uj))
      da = dot_product(ddi, dw) + dot_product(di, vvel(fr, j, pr%wj))
      db = dot_product(ddi, dv) + dot_product(di, vvel(fr, j, pr%uj))
      ! Phi_t = -f' (sin f A + cos f B); C_t w = -f' (sin f A' + cos f B');
      ! Phi_tt = -f'' (sin f A + cos f B) - f'^2 (cos f A - sin f B)
      phit = -fd * (sf * a + cf * b)
      gam = -(cf * qa - sf * qb - 2.0_dp * fd * (sf * da + cf * db) &
              - fdd * (sf * a + cf * b) - fd**2 * (cf * a - sf * b))
    end associate
  end subroutine angle_row

  ! ---- body points and vectors in the frames fr (body 0, the ground, has no columns in C; o:
  ! the body's first column less one: 6 (b - 1) in C, 0 or 6 in a compact row) ----

  !> rows of a body point's velocity v + R (W x s) = v - R skew(s) W, times sgn
  pure subroutine point_cols(fr, cc, b, o, s, sgn)
    type(frames_t), intent(in) :: fr
    real(dp), intent(inout) :: cc(:, :)
    integer, intent(in) :: b, o
    real(dp), intent(in) :: s(3), sgn
    integer :: d
    if (b == 0) return
    do d = 1, 3
      cc(d, o + d) = cc(d, o + d) + sgn
    end do
    ! R skew(s), column by column: R (s x e_k)
    associate (r => fr%rot(:, :, b))
      cc(:, o + 4) = cc(:, o + 4) - sgn * (s(3) * r(:, 2) - s(2) * r(:, 3))
      cc(:, o + 5) = cc(:, o + 5) - sgn * (s(1) * r(:, 3) - s(3) * r(:, 1))
      cc(:, o + 6) = cc(:, o + 6) - sgn * (s(2) * r(:, 1) - s(1) * r(:, 2))
    end associate
  end subroutine point_cols

  !> the row x . (point velocity)
  pure subroutine point_row(fr, cr, b, o, s, x)
    type(frames_t), intent(in) :: fr
    real(dp), intent(inout) :: cr(:)
    integer, intent(in) :: b, o
    real(dp), intent(in) :: s(3), x(3)
    if (b == 0) return
    cr(o + 1:o + 3) = cr(o + 1:o + 3) + x
    ! -x^T R skew(s) W = W . (s x R^T x)
    cr(o + 4:o + 6) = cr(o + 4:o + 6) + cross(s, rtmul(fr%rot(:, :, b), x))
  end subroutine point_row

  !> the row x . d' of a body vector d = R u: d' = R (W x u), x . d' = W . (u x R^T x)
  pure subroutine vec_cols(fr, cr, b, o, u, x)
    type(frames_t), intent(in) :: fr
    real(dp), intent(inout) :: cr(:)
    integer, intent(in) :: b, o
    real(dp), intent(in) :: u(3), x(3)
    if (b == 0) return
    cr(o + 4:o + 6) = cr(o + 4:o + 6) + cross(u, rtmul(fr%rot(:, :, b), x))
  end subroutine vec_cols

  !> the velocity of body b's point s
  pure function pvel(fr, b, s) result(x)
    type(frames_t), intent(in) :: fr
    integer, intent(in) :: b
    real(dp), intent(in) :: s(3)
    real(dp) :: x(3)
    x = fr%v(:, b) + rmul(fr%rot(:, :, b), cross(fr%om(:, b), s))
  end function pvel

  !> the acceleration of body b's point s quadratic in its angular velocity, R (W x (W x s))
  pure function pquad(fr, b, s) result(x)
    type(frames_t), intent(in) :: fr
    integer, intent(in) :: b
    real(dp), intent(in) :: s(3)
    real(dp) :: x(3)
    x = rmul(fr%rot(:, :, b), cross(fr%om(:, b), cross(fr%om(:, b), s)))
  end function pquad

  !> the rate of body b's vector R u
  pure function vvel(fr, b, u) result(x)
    type(frames_t), intent(in) :: fr
    integer, intent(in) :: b
    real(dp), intent(in) :: u(3)
    real(dp) :: x(3)
    x = rmul(fr%rot(:, :, b), cross(fr%om(:, b), u))
  end function vvel

  !> the terms of the second derivative of body b's vector R u quadratic in W: a point's (pquad)
  pure function vquad(fr, b, u) result(x)
    type(frames_t), intent(in) :: fr
    integer, intent(in) :: b
    real(dp), intent(in) :: u(3)
    real(dp) :: x(3)
    x = pquad(fr, b, u)
  end function vquad

  !> x × y, as mbdk_cross: a function of another module is never inlined (each source is its own
  !> unit; no link-time optimisation), and the joints' rows, the forces and the Newton-Euler
  !> terms call it at every evaluation
  pure function cross(x, y) result(z)
    real(dp), intent(in) :: x(3), y(3)
    real(dp) :: z(3)
    z = [x(2) * y(3) - x(3) * y(2), x(3) * y(1) - x(1) * y(3), x(1) * y(2) - x(2) * y(1)]
  end function cross

  !> R x for a body's rotation (or inertia): explicit shapes, so that the compiler unrolls it
  !> (matmul on an array section of unknown shape goes to the library, with a temporary)
  pure function rmul(r, x) result(y)
    real(dp), intent(in) :: r(3, 3), x(3)
    real(dp) :: y(3)
    y = r(:, 1) * x(1) + r(:, 2) * x(2) + r(:, 3) * x(3)
  end function rmul

  !> W x for a body's 6 x 6 block (explicit shapes, as rmul)
  pure function blk6(w, x) result(y)
    real(dp), intent(in) :: w(6, 6), x(6)
    real(dp) :: y(6)
    integer :: k
    y = w(:, 1) * x(1)
    do k = 2, 6
      y = y + w(:, k) * x(k)
    end do
  end function blk6

  !> R^T x (as rmul)
  pure function rtmul(r, x) result(y)
    real(dp), intent(in) :: r(3, 3), x(3)
    real(dp) :: y(3)
    y(1) = r(1, 1) * x(1) + r(2, 1) * x(2) + r(3, 1) * x(3)
    y(2) = r(1, 2) * x(1) + r(2, 2) * x(2) + r(3, 2) * x(3)
    y(3) = r(1, 3) * x(1) + r(2, 3) * x(2) + r(3, 3) * x(3)
  end function rtmul

  !> M^-1 x for x in the velocity layout (6 per body).
  pure subroutine apply_minv(model, x, y)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: x(:)
    real(dp), intent(out) :: y(:)
    integer :: b, o
    do b = 1, model%nb
      o = (b - 1) * 6
      y(o + 1:o + 3) = x(o + 1:o + 3) / model%mass(b)
      y(o + 4:o + 6) = rmul(model%inv_inertia(:, :, b), x(o + 4:o + 6))
    end do
  end subroutine apply_minv

  !> mc = M^-1 C^T (6 nb x m), each row of C on its two bodies only (model%rbody): the other
  !> columns of a row are zero.
  pure subroutine minv_ct(model, c, mc)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: c(:, :)
    real(dp), intent(out) :: mc(:, :)
    integer :: k, a, b, o
    mc = 0.0_dp
    do k = 1, size(c, 1)
      do a = 1, 2
        b = model%rbody(a, k)
        if (b == 0) cycle
        if (a == 2 .and. b == model%rbody(1, k)) cycle
        o = (b - 1) * 6
        mc(o + 1:o + 3, k) = c(k, o + 1:o + 3) / model%mass(b)
        mc(o + 4:o + 6, k) = rmul(model%inv_inertia(:, :, b), c(k, o + 4:o + 6))
      end do
    end do
  end subroutine minv_ct

  !> lam solving (C M^-1 C^T) lam = rhs, and mc = M^-1 C^T, by Cholesky; a pivot at roundoff of
  !> its row's diagonal entry (SOLVE_RTOL) is a singular solve: MBDK_ERR_SINGULAR_MATRIX
  !> (a singular pose). Redundant joints (rank0 < m; Bricard's linkage, a planar loop of
  !> revolute joints built in 3D): only the rows chosen at the initial state (select_rows: those
  !> with the greatest margin) are solved, and the others get no multiplier: a rigid mechanism's reactions on redundant
  !> joints are not determined, and these are one valid set. A fixed set of rows, not one chosen
  !> afresh at every evaluation, keeps F(y) smooth: the stages of a Runge-Kutta step lie off the
  !> constraint manifold by O(h^2), where the dependent rows no longer agree with the others,
  !> and a choice that changed from stage to stage (or a least-squares fit of all rows) would
  !> put that disagreement into the accelerations and cut rk4 to second order. On the manifold
  !> the active rows imply the others; the watch checks every row, so a run that leaves them
  !> stops with MBDK_ERR_CONSTRAINT_DRIFT, and a position projection iterates until every row
  !> holds. Where the set kept nears a rank loss of its own (near_test) while all the rows keep
  !> rank0, the set select_rows chooses at that state takes over and is kept (work%active; the
  !> switches are counted): F is smooth again away from the switch.
  subroutine schur_solve(model, c, rhs, lam, mc, stat, near)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: c(:, :), rhs(:)
    real(dp), intent(out) :: lam(:), mc(:, :)
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: near   !< the window of near_test, if any
    integer, allocatable :: rows(:)
    integer :: m
    m = size(c, 1)
    call minv_ct(model, c, mc)
    if (model%rank0 == m) then
      call solve_rows(model, c, rhs, mc, model%all_rows, lam, stat, near)
      return
    end if
    ! redundant joints: the rows chosen at the start while they stay well clear of a rank loss
    ! (the near window, whatever the formulation: a subset near its own degeneration amplifies
    ! the disagreement of the rows it leaves out) ...
    call solve_rows(model, c, rhs, mc, model%work%active, lam, stat, MBDK_SPATIAL_NEAR_PIVOT)
    if (stat == MBDK_SUCCESS) return
    ! ... and where they near one while the rows as a whole keep their rank (another subset
    ! spans them), the subset with the greatest margin here, kept from now on (a set chosen
    ! afresh at every evaluation flips between near-equal choices, and F with it)
    call select_rows(model, c, rows, stat)
    if (stat /= MBDK_SUCCESS) return
    call move_alloc(rows, model%work%active)
    model%work%switches = model%work%switches + 1
    call solve_rows(model, c, rhs, mc, model%work%active, lam, stat, near)
  end subroutine schur_solve

  !> schur_solve on the given rows of C (the others get no multiplier).
  subroutine solve_rows(model, c, rhs, mc, rows, lam, stat, near)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: c(:, :), rhs(:), mc(:, :)
    integer, intent(in) :: rows(:)
    real(dp), intent(out) :: lam(:)
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: near
    integer :: info, r
    r = size(rows)
    stat = MBDK_SUCCESS
    associate (w => model%work)
      ! all four or none: an allocation that failed part way leaves some of them allocated
      if (.not. (allocated(w%s) .and. allocated(w%sx) .and. allocated(w%sdiag) .and. &
                 allocated(w%slast))) then
        if (allocated(w%s)) deallocate (w%s)
        if (allocated(w%sx)) deallocate (w%sx)
        if (allocated(w%sdiag)) deallocate (w%sdiag)
        if (allocated(w%slast)) deallocate (w%slast)
      else if (size(w%s, 1) /= r) then
        deallocate (w%s, w%sx, w%sdiag, w%slast)
      end if
      if (.not. allocated(w%s)) then
        allocate (w%s(r, r), w%sx(r), w%sdiag(r), w%slast(r), stat=info)
        call mbdk_alloc_status(info, MBDK_REAL_BYTES * real(r, dp) * (r + 2) + &
                               MBDK_INT_BYTES * real(r, dp), stat)
        if (stat /= MBDK_SUCCESS) return
      end if
      call solve_rows_in(w%s, w%sx, w%sdiag, w%slast)
    end associate

  contains

    !> the solve in the scratch s (r x r), x (r), diag (r) and last (r, the factor's envelope)
    subroutine solve_rows_in(s, x, diag, last)
      real(dp), intent(out) :: s(:, :), x(:), diag(:)
      integer, intent(out) :: last(:)
      integer :: k
      call gram(model, c, mc, rows, s, stat)
      if (stat /= MBDK_SUCCESS) return
      x = rhs(rows)
      lam = 0.0_dp
      do k = 1, r
        diag(k) = s(k, k)
      end do
      call mbdk_chol_factor(s, info, last)
      stat = MBDK_ERR_SINGULAR_MATRIX
      if (info /= MBDK_SUCCESS) return
      ! each pivot against its own row's diagonal, at roundoff: which rows are dependent is
      ! the geometry's to say (select_rows, near_test); S mixes 1/m and 1/J, and a near point
      ! mass (J = 1e-10 on a lever of 1 m) leaves relative pivots of 1e-10 at a regular pose
      do k = 1, r
        if (.not. (s(k, k)**2 > SOLVE_RTOL * diag(k))) return
      end do
      if (present(near)) then
        if (.not. clear_of_near(model, c, rows, s, near)) then
          call near_test(model, c, rows, near, stat)
          if (stat /= MBDK_SUCCESS) return
        end if
      end if
      call mbdk_chol_solve(s, x, stat, last)
      if (stat /= MBDK_SUCCESS) then
        stat = MBDK_ERR_SINGULAR_MATRIX
        return
      end if
      lam(rows) = x
    end subroutine solve_rows_in

  end subroutine solve_rows

  !> The lower triangle of S = C(rows, :) X C(rows, :)^T from xc = X C^T (X block diagonal by
  !> body), body block by body block: a row of C touches at most two bodies (model%rbody), so
  !> only rows that share a body meet (a quarter of the dense product's work on the flyball
  !> governor, less on longer chains). The upper triangle is left zero (the Cholesky
  !> factorisations read the lower).
  pure subroutine gram(model, c, xc, rows, s, stat)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: c(:, :), xc(:, :)
    integer, intent(in) :: rows(:)
    real(dp), intent(out) :: s(:, :)
    integer, intent(out) :: stat
    integer :: b, o, i, j, ii, jj, n
    integer, allocatable :: list(:)
    allocate (list(size(rows)), stat=i)
    call mbdk_alloc_status(i, MBDK_INT_BYTES * size(rows), stat)
    if (stat /= MBDK_SUCCESS) return
    s = 0.0_dp
    do b = 1, model%nb
      o = 6 * (b - 1)
      n = 0
      do i = 1, size(rows)
        if (any(model%rbody(:, rows(i)) == b)) then
          n = n + 1
          list(n) = i
        end if
      end do
      do jj = 1, n
        j = list(jj)
        do ii = jj, n
          i = list(ii)
          s(i, j) = s(i, j) + dot_product(c(rows(i), o + 1:o + 6), xc(o + 1:o + 6, rows(j)))
        end do
      end do
    end do
  end subroutine gram

  !> The independent rows of C with the greatest margin (in their order in C), judged on the
  !> geometry G = C W C^T (W = diag(1, 1, 1, 1/L^2, 1/L^2, 1/L^2) per body, L = geo_length:
  !> rotations as the displacements they give at the mechanism's size, so that neither the unit
  !> of length, nor where the mechanism stands, nor a light or slender body sways the test)
  !> scaled to a unit diagonal. The rank-revealing Cholesky (mbdk_chol_pivoted, dpstrf's
  !> algorithm; pivots at or below REDUNDANT_RTOL are zero) gives the rank r and the
  !> dependencies of the m - r remaining rows on the others: the left null vectors Y of the
  !> scaled C. The rows left out are then chosen by pivoting on the rows of Y (the subset
  !> selection of Golub, Klema and Stewart): those with the largest share in the dependencies,
  !> whose removal leaves the others furthest from dependent. dpstrf's own choice breaks the ties
  !> of a unit diagonal by order and can leave a set that nears a rank loss of its own along the
  !> motion (on Bricard's linkage it did, once per swing). With rank0 set: a rank above it is
  !> MBDK_ERR_CONSTRAINT_DRIFT (the state left the joints far enough that their dependent rows
  !> disagree), one below MBDK_ERR_SINGULAR_MATRIX (a singular pose); a vanishing row is
  !> MBDK_ERR_SINGULAR_MATRIX too.
  !> MBDK_ERR_NO_MEMORY: asked gets the bytes (mbdk_memory).
  subroutine select_rows(model, c, rows, stat, asked)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: c(:, :)
    integer, allocatable, intent(out) :: rows(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    real(dp), allocatable :: g(:, :), wc(:, :), d(:), y(:, :), l11(:, :), g0(:, :)
    real(dp) :: big, spread, least
    integer :: k, j, l, m, r, nd, b, best, col
    integer, allocatable :: piv(:)
    logical, allocatable :: keep(:)
    m = size(c, 1)
    allocate (g(m, m), wc(size(c, 2), m), d(m), y(m, m), l11(m, m), g0(m, m), piv(m), keep(m), &
              stat=k)
    call mbdk_alloc_status(k, MBDK_REAL_BYTES * real(m, dp) * (4.0_dp * m + size(c, 2) + 1) + &
                           2 * MBDK_INT_BYTES * m, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    wc = transpose(c)
    do b = 1, model%nb
      wc(6 * b - 2:6 * b, :) = wc(6 * b - 2:6 * b, :) / model%geo_length**2
    end do
    call gram(model, c, wc, [(k, k = 1, m)], g, stat)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_SINGULAR_MATRIX
    do k = 1, m
      if (.not. (g(k, k) > 0.0_dp)) return
    end do
    d = 1.0_dp / sqrt([(g(k, k), k = 1, m)])
    do k = 1, m
      g(:, k) = g(:, k) * d * d(k)
    end do
    g0 = g
    call mbdk_chol_pivoted(g, piv, r, REDUNDANT_RTOL, stat)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_SINGULAR_MATRIX
    if (r < 1) return
    if (model%rank0 > 0 .and. r /= model%rank0) then
      if (r > model%rank0) stat = MBDK_ERR_CONSTRAINT_DRIFT
      return
    end if
    keep = .true.
    nd = m - r
    if (nd > 0) then
      ! Y(:, k), k = 1..nd: a dependency of permuted row r + k on the first r, [-a; e_k] with
      ! L11^T a = L21(k, :)^T, mapped back to the rows' own order
      l11(1:r, 1:r) = g(1:r, 1:r)
      y = 0.0_dp
      do k = 1, nd
        y(piv(1:r), k) = -lower_transpose_solve(l11(1:r, 1:r), g(r + k, 1:r))
        y(piv(r + k), k) = 1.0_dp
      end do
      ! Gaussian elimination with complete pivoting on Y's rows: leave out the row holding the
      ! largest remaining entry, take it out of the other columns, repeat; the rows left out
      ! then make Y(out, :) nonsingular, which is what leaves the kept rows independent. Rows
      ! whose entries tie (SELECT_TIE_RTOL; Bricard's linkage has four at its start) leave sets
      ! of the same volume (a principal minor of G is its pseudo-determinant times y_j^2), but
      ! not equally far from a rank loss, and the reduced form's drift follows that distance:
      ! the last pick among them takes the set with the least trace of its G^-1, and every other
      ! tie goes to the first row in C's order
      do k = 1, nd
        big = -1.0_dp
        do l = k, nd
          do j = 1, m
            if (keep(j)) big = max(big, abs(y(j, l)))
          end do
        end do
        stat = MBDK_ERR_SINGULAR_MATRIX
        if (.not. (big > 0.0_dp)) return
        best = 0
        col = k
        least = huge(1.0_dp)
        candidates: do j = 1, m
          do l = k, nd
            if (keep(j) .and. abs(y(j, l)) >= (1.0_dp - SELECT_TIE_RTOL) * big) then
              if (best == 0) then
                best = j
                col = l
              end if
              if (k < nd) exit candidates
              call inverse_trace(g0, keep, j, spread, stat, asked)
              if (stat /= MBDK_SUCCESS) return
              if (spread < (1.0_dp - SELECT_TIE_RTOL) * least) then
                least = spread
                best = j
                col = l
              end if
              exit
            end if
          end do
        end do candidates
        stat = MBDK_ERR_SINGULAR_MATRIX
        if (best == 0) return
        keep(best) = .false.
        if (col /= k) then
          d = y(:, k)
          y(:, k) = y(:, col)
          y(:, col) = d
        end if
        do l = k + 1, nd
          y(:, l) = y(:, l) - (y(best, l) / y(best, k)) * y(:, k)
        end do
      end do
    end if
    rows = pack([(k, k = 1, m)], keep)
    stat = MBDK_SUCCESS
  contains
    !> x solving L^T x = bvec for the lower triangular L.
    pure function lower_transpose_solve(l, bvec) result(x)
      real(dp), intent(in) :: l(:, :), bvec(:)
      real(dp) :: x(size(bvec))
      integer :: i
      do i = size(bvec), 1, -1
        x(i) = (bvec(i) - dot_product(l(i + 1:, i), x(i + 1:))) / l(i, i)
      end do
    end function lower_transpose_solve
  end subroutine select_rows

  !> spread: the trace of G^-1 over the rows kept but j (G's lower triangle in g0, scaled to a
  !> unit diagonal; huge where it is not positive definite), the sum of its inverse
  !> eigenvalues: a set's distance from a rank loss that, unlike the order-bound pivots, no
  !> ordering of its rows changes (select_rows' ties). MBDK_ERR_NO_MEMORY: asked gets the bytes.
  subroutine inverse_trace(g0, keep, j, spread, stat, asked)
    real(dp), intent(in) :: g0(:, :)
    logical, intent(in) :: keep(:)
    integer, intent(in) :: j
    real(dp), intent(out) :: spread
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    real(dp), allocatable :: gk(:, :), z(:)
    integer, allocatable :: idx(:)
    integer :: n, p, q, i, st
    spread = huge(1.0_dp)
    n = count(keep) - merge(1, 0, keep(j))
    allocate (gk(n, n), z(n), idx(n), stat=st)
    call mbdk_alloc_status(st, MBDK_REAL_BYTES * real(n, dp) * (n + 1) + &
                           MBDK_INT_BYTES * n, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    n = 0
    do i = 1, size(keep)
      if (keep(i) .and. i /= j) then
        n = n + 1
        idx(n) = i
      end if
    end do
    do q = 1, n
      do p = q, n
        gk(p, q) = g0(idx(p), idx(q))         ! idx ascends: g0's lower triangle
      end do
    end do
    call mbdk_chol_factor(gk, st)
    if (st /= MBDK_SUCCESS) return
    spread = 0.0_dp
    do i = 1, n                                ! |L^-1 e_i|^2, by forward substitution
      z(i) = 1.0_dp / gk(i, i)
      do p = i + 1, n
        z(p) = -dot_product(gk(p, i:p - 1), z(i:p - 1)) / gk(p, p)
      end do
      spread = spread + sum(z(i:n)**2)
    end do
  end subroutine inverse_trace

  !> Whether near_test would pass the rows, known from the factor of S = C M^-1 C^T on the same
  !> rows in the same order (s: its Cholesky factor, pivots on the diagonal), without forming
  !> and factoring the geometry's G = C W C^T. W and M^-1 are block diagonal by body with
  !> W >= kappa M^-1 (model%near_kappa), so G >= kappa S; a pivot of the Cholesky factor
  !> squared is a Schur complement, the least of x^T A x over the x whose last nonzero entry is
  !> a 1 at that row, so G's is at least kappa times S's. Where kappa pivot(S)^2 exceeds twice
  !> the window times G's diagonal entry (a row's weighted squared length, a few products) for
  !> every row, G has no pivot within the window: near_test's verdict, with a factor 2 for the
  !> roundoff of either factorisation (and of J^-1's symmetry in weight_bound). Otherwise
  !> near_test decides. The bound gives away the spread of the weights (kappa against the
  !> masses and the inertias over L^2): it decides where S's pivots clear the window by that
  !> much more, and a body far lighter in rotation than in translation (a slender bar's
  !> axial inertia) leaves more poses to near_test.
  pure logical function clear_of_near(model, c, rows, s, near) result(clear)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: c(:, :), s(:, :), near
    integer, intent(in) :: rows(:)
    real(dp) :: dg, l2
    integer :: k, a, b, o
    clear = .false.
    if (.not. (model%near_kappa > 0.0_dp)) return
    l2 = model%geo_length**2
    do k = 1, size(rows)
      dg = 0.0_dp
      do a = 1, 2
        b = model%rbody(a, rows(k))
        if (b == 0) cycle
        if (a == 2 .and. b == model%rbody(1, rows(k))) cycle
        o = 6 * (b - 1)
        dg = dg + sum(c(rows(k), o + 1:o + 3)**2) + sum(c(rows(k), o + 4:o + 6)**2) / l2
      end do
      if (.not. (model%near_kappa * s(k, k)**2 > 2.0_dp * near * dg)) return
    end do
    clear = .true.
  end function clear_of_near

  !> kappa with W >= kappa M^-1 on every body (clear_of_near): W - kappa M^-1 is
  !> diag((1 - kappa / m) I, I / geo_length^2 - kappa J^-1), semidefinite for kappa at most m
  !> and lambda_min(J) / geo_length^2; lambda_min(J) = 1 / lambda_max(J^-1) is bounded below by
  !> Gershgorin's bound on J^-1's rows (exact for a diagonal J; inv_inertia is symmetric to
  !> roundoff, which the factor 2 of clear_of_near covers). 0 where a body has no finite bound
  !> (the near test then always runs).
  pure real(dp) function weight_bound(model) result(kappa)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp) :: g
    integer :: b, i
    kappa = huge(1.0_dp)
    do b = 1, model%nb
      g = 0.0_dp
      do i = 1, 3
        g = max(g, sum(abs(model%inv_inertia(i, :, b))))
      end do
      if (.not. (g > 0.0_dp .and. g <= huge(1.0_dp))) then
        kappa = 0.0_dp
        return
      end if
      kappa = min(kappa, model%mass(b), 1.0_dp / (g * model%geo_length**2))
    end do
    if (.not. (kappa > 0.0_dp .and. kappa < huge(1.0_dp))) kappa = 0.0_dp
  end function weight_bound

  !> MBDK_ERR_SINGULAR_MATRIX when the rows of C tested (the active ones) are near a rank loss:
  !> a relative pivot (to its row's diagonal) of C W C^T below near, W = diag(1, 1, 1, 1/L^2,
  !> 1/L^2, 1/L^2) per body (L = geo_length: rotations as the displacements they give at the
  !> mechanism's size, so that the test depends neither on the unit of length nor on where the
  !> mechanism stands). The geometry alone, not the masses: with M^-1 in its place a slender
  !> body's small axial inertia (a bar's) makes rows look near dependent at a regular pose.
  subroutine near_test(model, c, rows, near, stat)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: c(:, :), near
    integer, intent(in) :: rows(:)            !< the rows to test
    integer, intent(out) :: stat
    real(dp), allocatable :: g(:, :), wc(:, :)
    integer :: info, m
    m = size(rows)
    allocate (g(m, m), wc(size(c, 2), size(c, 1)), stat=info)
    call mbdk_alloc_status(info, MBDK_REAL_BYTES * (real(m, dp) * m + &
                           real(size(c, 1), dp) * size(c, 2)), stat)
    if (stat /= MBDK_SUCCESS) return
    call near_test_in(g, wc)

  contains

    !> the test in the scratch g (m x m) and wc (6 nb x rows of c; only the tested columns set)
    subroutine near_test_in(g, wc)
      real(dp), intent(out) :: g(:, :), wc(:, :)
      real(dp) :: l2
      integer :: k, b
      l2 = model%geo_length**2
      do k = 1, m
        wc(:, rows(k)) = c(rows(k), :)
        do b = 1, model%nb
          wc(6 * b - 2:6 * b, rows(k)) = wc(6 * b - 2:6 * b, rows(k)) / l2
        end do
      end do
      call gram(model, c, wc, rows, g, stat)
      if (stat /= MBDK_SUCCESS) return
      stat = merge(MBDK_ERR_SINGULAR_MATRIX, MBDK_SUCCESS, mbdk_pivots_near(g, near))
    end subroutine near_test_in

  end subroutine near_test



  ! ---- forces --------------------------------------------------------------------------------

  !> Applied forces (space frame) and moments (body frame) on every body, with the energy parts:
  !> gravity's potential vg, the springs' and contacts' vs, and the power of dampers, contacts
  !> and loads. MBDK_ERR_NONFINITE where two penetrating spheres have no normal.
  pure subroutine forces(model, fr, fw, nb_, vg, vs, power, stat)
    type(mbdk_spatial_model_t), intent(in) :: model
    type(frames_t), intent(in) :: fr
    real(dp), intent(out) :: fw(:, :), nb_(:, :), vg, vs, power
    integer, intent(out) :: stat
    integer :: k, b, i, j
    real(dp) :: pi(3), pj(3), d(3), len, e(3), ldot, f, fv(3), vi(3), vj(3), m1(3), f2(3), m2(3)
    type(mbdk_contact3d_t) :: ct
    logical :: ok
    fw = 0.0_dp
    nb_ = 0.0_dp
    vg = 0.0_dp
    vs = 0.0_dp
    power = 0.0_dp
    stat = MBDK_SUCCESS
    do k = 1, model%nf
      associate (r => model%freal(:, k))
        select case (model%ftype(k))
        case (MBDK_FORCE_GRAVITY)
          do b = 1, model%nb
            fw(:, b) = fw(:, b) + model%mass(b) * r(1:3)
            vg = vg - model%mass(b) * dot_product(r(1:3), fr%r(:, b))
          end do
        case (MBDK_FORCE_POINT)
          b = model%fbody(1, k)
          fw(:, b) = fw(:, b) + r(4:6)
          nb_(:, b) = nb_(:, b) + cross(r(1:3), rtmul(fr%rot(:, :, b), r(4:6)))
          power = power + dot_product(r(4:6), fr%v(:, b) + &
                                      rmul(fr%rot(:, :, b), cross(fr%om(:, b), r(1:3))))
        case (MBDK_FORCE_TORQUE)
          b = model%fbody(1, k)
          nb_(:, b) = nb_(:, b) + rtmul(fr%rot(:, :, b), r(1:3))
          power = power + dot_product(r(1:3), rmul(fr%rot(:, :, b), fr%om(:, b)))
        case (MBDK_FORCE_SPRING_DAMPER)
          i = model%fbody(1, k)
          j = model%fbody(2, k)
          pi = fr%r(:, i) + rmul(fr%rot(:, :, i), r(1:3))
          pj = fr%r(:, j) + rmul(fr%rot(:, :, j), r(4:6))
          vi = fr%v(:, i) + rmul(fr%rot(:, :, i), cross(fr%om(:, i), r(1:3)))
          vj = fr%v(:, j) + rmul(fr%rot(:, :, j), cross(fr%om(:, j), r(4:6)))
          d = pi - pj
          len = norm2(d)
          vs = vs + 0.5_dp * r(7) * (len - r(9))**2
          if (.not. (len > 0.0_dp)) cycle       ! coincident points: no direction, no force
          e = d / len
          ldot = dot_product(e, vi - vj)
          f = r(7) * (len - r(9)) + r(8) * ldot
          power = power - r(8) * ldot**2
          fv = -f * e                            ! on body i
          fw(:, i) = fw(:, i) + fv
          nb_(:, i) = nb_(:, i) + cross(r(1:3), rtmul(fr%rot(:, :, i), fv))
          if (j > 0) then
            fw(:, j) = fw(:, j) - fv
            nb_(:, j) = nb_(:, j) - cross(r(4:6), rtmul(fr%rot(:, :, j), fv))
          end if
        case (MBDK_FORCE_SPHERE_PLANE, MBDK_FORCE_SPHERE_SPHERE)
          i = model%fbody(1, k)
          j = model%fbody(2, k)
          call contact_at(model, fr, k, ct, ok)
          if (.not. ok) then
            stat = MBDK_ERR_NONFINITE
            return
          end if
          if (.not. ct%touching) cycle
          vs = vs + ct%potential
          power = power - ct%dissipation
          call mbdk_contact3d_loads(ct, fr%r(:, i), fr%rot(:, :, i), fr%r(:, j), &
                                    fr%rot(:, :, j), fv, m1, f2, m2)
          fw(:, i) = fw(:, i) + fv
          nb_(:, i) = nb_(:, i) + m1
          if (j > 0) then
            fw(:, j) = fw(:, j) + f2
            nb_(:, j) = nb_(:, j) + m2
          end if
        end select
      end associate
    end do
  end subroutine forces

  !> Contact k of the force table at the frames fr (mbdk_contact3d_eval).
  pure subroutine contact_at(model, fr, k, ct, ok)
    type(mbdk_spatial_model_t), intent(in) :: model
    type(frames_t), intent(in) :: fr
    integer, intent(in) :: k
    type(mbdk_contact3d_t), intent(out) :: ct
    logical, intent(out) :: ok
    integer :: i, j
    i = model%fbody(1, k)
    j = model%fbody(2, k)
    call mbdk_contact3d_eval(merge(MBDK_CONTACT3D_PLANE, MBDK_CONTACT3D_SPHERES, &
                                   model%ftype(k) == MBDK_FORCE_SPHERE_PLANE), &
                             model%freal(:, k), fr%r(:, i), fr%rot(:, :, i), fr%v(:, i), &
                             fr%om(:, i), fr%r(:, j), fr%rot(:, :, j), fr%v(:, j), &
                             fr%om(:, j), ct, ok)
  end subroutine contact_at

  !> The events of a scene with contacts (nevents = 2 ncontacts with locate_events), two per
  !> contact in table order (mbdk_contact3d_events): the law's, where the contact closes and
  !> where its force would turn into a pull and the clip lets it go, and the parting one, where
  !> the surfaces of a contact that let go part (mbdk_contact_law says why that point too).
  subroutine spatial_events(self, t, y, g, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: g(:)
    integer, intent(out) :: stat
    type(frames_t) :: fr
    type(mbdk_contact3d_t) :: ct
    logical :: ok
    integer :: k, e
    g = 0.0_dp
    call frames(self, y, fr, stat)
    if (stat /= MBDK_SUCCESS) return
    e = 0
    do k = 1, self%nf
      if (.not. is_contact(self%ftype(k))) cycle
      e = e + 2
      call contact_at(self, fr, k, ct, ok)
      g(e - 1:e) = mbdk_contact3d_events(ct, ok, self%freal(:, k))
    end do
  end subroutine spatial_events

  !> What each contact carries at (t, y), for the outputs: out(:, k) of the k-th contact in
  !> table order = (penetration delta, its rate, the normal force, the friction force's
  !> magnitude, |f - (f . n) n| of the contact's force f on body i). stat: the frames' failure
  !> (a gimbal lock); NaN in a contact's column where a penetrating contact has no normal.
  subroutine mbdk_spatial_contact_states(model, y, out, stat)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: y(:)
    real(dp), intent(out) :: out(:, :)
    integer, intent(out) :: stat
    type(frames_t) :: fr
    type(mbdk_contact3d_t) :: ct
    logical :: ok
    integer :: k, e
    out = 0.0_dp
    call frames(model, y, fr, stat)
    if (stat /= MBDK_SUCCESS) return
    e = 0
    do k = 1, model%nf
      if (.not. is_contact(model%ftype(k))) cycle
      e = e + 1
      call contact_at(model, fr, k, ct, ok)
      if (.not. ok) then
        out(:, e) = ieee_value(0.0_dp, ieee_quiet_nan)
        cycle
      end if
      out(:, e) = [ct%delta, ct%rate, ct%force, norm2(ct%f - dot_product(ct%f, ct%n) * ct%n)]
    end do
  end subroutine mbdk_spatial_contact_states

  ! ---- the problem ---------------------------------------------------------------------------

  !> F(t, y): the bodies' rates and accelerations, then, in a scene with wear, the rates of the
  !> worn volumes
  subroutine spatial_rhs(self, t, y, f, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    real(dp), intent(out), contiguous :: f(:)
    integer, intent(out) :: stat
    call spatial_accelerations(self, t, y, f, stat)
    if (self%ns > 0 .and. stat == MBDK_SUCCESS) &
      call wear_rates(self, t, y, f(last_velocity(self) + 1:), stat)
  end subroutine spatial_rhs

  !> rates(e) = V_e' of every wear element at (t, y): the law (mbdk_wear_law) at its contact's
  !> normal force F, or friction force mu F, and slip speed; 0 where the contact is apart.
  !> MBDK_ERR_NONFINITE where the contact has no normal (two penetrating spheres' centres
  !> coincide).
  subroutine wear_rates(self, t, y, rates, stat)
    type(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: rates(:)
    integer, intent(out) :: stat
    type(frames_t) :: fr
    type(mbdk_contact3d_t) :: ct
    real(dp) :: load
    logical :: ok
    integer :: e, k
    rates = 0.0_dp
    call frames(self, y, fr, stat)
    if (stat /= MBDK_SUCCESS) return
    do e = 1, self%ns
      k = self%wear(e)
      call contact_at(self, fr, self%fbody(1, k), ct, ok)
      if (.not. ok) then
        stat = MBDK_ERR_NONFINITE
        return
      end if
      if (.not. ct%touching) cycle
      load = ct%force
      if (self%freal(6, k) == real(MBDK_WEAR_LOAD_FRICTION, dp)) load = ct%mu * ct%force
      rates(e) = mbdk_wear_law(self%fbody(2, k), self%freal(:, k), load, ct%speed, t)
    end do
  end subroutine wear_rates

  !> The sparse path (model%sparse) where the rows are many (MBDK_SPATIAL_SPARSE_ROWS), none
  !> redundant (a redundant set keeps the dense path, whose row selection it needs), the
  !> formulation not the penalty one (its matrix is M + alpha C^T C, not S) and, up to
  !> MBDK_SPATIAL_DENSE_MAX_ROWS rows, S no more than three quarters full: S's pattern from
  !> the rows' bodies, and the per-body blocks of M^-1 and of the geometry's weight.
  subroutine choose_sparse(model, work, stat, asked)
    type(mbdk_spatial_model_t), intent(inout) :: model
    type(mbdk_spatial_work_t), intent(inout) :: work
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: k, b, astat
    stat = MBDK_SUCCESS
    model%sparse = model%m > MBDK_SPATIAL_SPARSE_ROWS .and. model%rank0 == model%m .and. &
      model%opt%formulation /= MBDK_FORM_PENALTY
    if (.not. model%sparse) return
    allocate (model%minv_blk(6, 6, model%nb), model%geo_blk(6, 6, model%nb), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * 72.0_dp * model%nb, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    model%minv_blk = 0.0_dp
    model%geo_blk = 0.0_dp
    do b = 1, model%nb
      do k = 1, 3
        model%minv_blk(k, k, b) = 1.0_dp / model%mass(b)
        model%geo_blk(k, k, b) = 1.0_dp
        model%geo_blk(k + 3, k + 3, b) = 1.0_dp / model%geo_length**2
      end do
      model%minv_blk(4:6, 4:6, b) = model%inv_inertia(:, :, b)
    end do
    call mbdk_compact_schur_init(work%cs, model%rbody, model%nb, 6, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    ! a few bodies under many rows (the flyball governor: 4 bodies, 20 rows) make S nearly
    ! full, where the dense Cholesky is cheaper than the sparse assembly and LDL^T; a chain's S,
    ! half full at 15 rows, is still cheaper sparse (the performance guide has the figures)
    if (model%m <= MBDK_SPATIAL_DENSE_MAX_ROWS) then
      if (4 * size(work%cs%ai) > 3 * model%m**2) model%sparse = .false.
    end if
  end subroutine choose_sparse

  !> rbody(:, r): the two bodies of row r (0: the ground), its primitive's
  pure subroutine row_bodies(model, rbody)
    type(mbdk_spatial_model_t), intent(in) :: model
    integer, intent(out) :: rbody(:, :)
    integer :: k, r, nrows
    do k = 1, model%nprim
      nrows = merge(3, 1, model%prim(k)%kind == PRIM_SPH)
      do r = model%prim(k)%row, model%prim(k)%row + nrows - 1
        rbody(:, r) = [model%prim(k)%bi, model%prim(k)%bj]
      end do
    end do
  end subroutine row_bodies

  !> The body graph (mbdk_mechanism): nqb coordinates and 6 velocities per body, the joints'
  !> primitives and the forces that load two bodies as pairs, each row's 6 velocity columns
  !> on each of its bodies.
  subroutine spatial_body_graph(self, qbody, vbody, pairs, rptr, rcol, stat, asked)
    class(mbdk_spatial_model_t), intent(in) :: self
    integer, allocatable, intent(out) :: qbody(:), vbody(:), pairs(:, :), rptr(:), rcol(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: i, k, a, b, n, astat
    n = 6 * count(self%rbody > 0)
    allocate (qbody(self%ncoord), vbody(self%nvel), pairs(2, self%nprim + self%nf), &
              rptr(self%m + 1), rcol(n), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (real(self%ncoord, dp) + self%nvel + &
                           2 * (self%nprim + self%nf) + self%m + 1.0_dp + n), stat, asked)
    if (astat /= 0) return
    do i = 1, self%ncoord
      qbody(i) = (i - 1) / self%nqb + 1
    end do
    do i = 1, self%nvel
      vbody(i) = (i - 1) / 6 + 1
    end do
    do k = 1, self%nprim
      pairs(:, k) = [self%prim(k)%bi, self%prim(k)%bj]
    end do
    do k = 1, self%nf
      pairs(:, self%nprim + k) = self%fbody(1:2, k)
      if (.not. loads_two_bodies(self%ftype(k))) pairs(:, self%nprim + k) = 0
    end do
    n = 0
    do k = 1, self%m
      rptr(k) = n + 1
      do a = 1, 2
        b = self%rbody(a, k)
        if (b == 0) cycle
        rcol(n + 1:n + 6) = [(6 * (b - 1) + i, i = 1, 6)]
        n = n + 6
      end do
    end do
    rptr(self%m + 1) = n + 1
  end subroutine spatial_body_graph

  !> C x for C in compact rows cc (the sparse path); absolute: |C| |x|
  pure function compact_times(model, cc, x, absolute) result(y)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: cc(:, :), x(:)
    logical, intent(in) :: absolute
    real(dp) :: y(size(cc, 1))
    integer :: k, a, b
    y = 0.0_dp
    do k = 1, size(cc, 1)
      do a = 1, 2
        b = model%work%cs%rbody(a, k)
        if (b == 0) cycle
        if (absolute) then
          y(k) = y(k) + dot_product(abs(cc(k, 6 * a - 5:6 * a)), abs(x(6 * b - 5:6 * b)))
        else
          y(k) = y(k) + dot_product(cc(k, 6 * a - 5:6 * a), x(6 * b - 5:6 * b))
        end if
      end do
    end do
  end function compact_times

  !> M^-1 C^T x for C in compact rows (the sparse path); absolute: |M^-1| |C^T| |x|
  pure function compact_minv_ct(model, cc, x, absolute) result(dx)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: cc(:, :), x(:)
    logical, intent(in) :: absolute
    real(dp) :: dx(6 * model%nb)
    integer :: b
    dx = compact_ct(model, cc, x, absolute)
    do b = 1, model%nb
      if (absolute) then
        dx(6 * b - 5:6 * b) = blk6(abs(model%minv_blk(:, :, b)), dx(6 * b - 5:6 * b))
      else
        dx(6 * b - 5:6 * b) = blk6(model%minv_blk(:, :, b), dx(6 * b - 5:6 * b))
      end if
    end do
  end function compact_minv_ct

  !> The sparse path's schur_solve: lam solving (C M^-1 C^T) lam = rhs and dx = M^-1 C^T lam,
  !> from C's compact rows cc. A pivot at roundoff of its row's diagonal entry (SOLVE_RTOL)
  !> is MBDK_ERR_SINGULAR_MATRIX; with near, the geometry G = C W C^T (near_test's weight: S
  !> mixes 1/m and 1/J, and a slender bar's axial inertia leaves S's relative pivots small at
  !> a regular pose) is factorised first, and a least pivot ratio of G inside that window,
  !> taken against the ratios G had before, is one too (mbdk_sparse_ldlt_near: in AMD's order
  !> a long regular chain's least ratio is about 2 / m, which a fixed window would call near
  !> singular; the planar sparse path tests so).
  subroutine sparse_schur(model, cc, rhs, lam, dx, stat, near)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: cc(:, :), rhs(:)
    real(dp), intent(out) :: lam(:), dx(:)
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: near
    lam = 0.0_dp
    dx = 0.0_dp
    call compact_factor(model, model%work%cs, cc, stat, near)
    if (stat /= MBDK_SUCCESS) return
    lam = rhs
    call mbdk_compact_schur_solve(model%work%cs, lam)
    call mbdk_compact_schur_spread(model%work%cs, lam, dx)
  end subroutine sparse_schur

  !> S = C M^-1 C^T from C's compact rows cc factorised into cs, with sparse_schur's tests (near:
  !> the geometry's G first); cs's spread is then M^-1 C^T.
  subroutine compact_factor(model, cs, cc, stat, near)
    type(mbdk_spatial_model_t), intent(in) :: model
    type(mbdk_compact_schur_t), intent(inout) :: cs
    real(dp), intent(in) :: cc(:, :)
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: near
    if (present(near)) then
      call mbdk_compact_schur_factor(cs, cc, model%geo_blk, SOLVE_RTOL, stat, rigid=.true., &
                                     near=near, near_rows=MBDK_SPATIAL_SPARSE_ROWS)
      if (stat /= MBDK_SUCCESS) return
    end if
    call mbdk_compact_schur_factor(cs, cc, model%minv_blk, SOLVE_RTOL, stat, rigid=.true.)
  end subroutine compact_factor

  !> C^T x (6 nb) for C in compact rows cc (the sparse path); absolute: |C^T| |x|
  pure function compact_ct(model, cc, x, absolute) result(y)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: cc(:, :), x(:)
    logical, intent(in), optional :: absolute
    real(dp) :: y(6 * model%nb)
    integer :: k, a, b
    logical :: ab
    ab = .false.
    if (present(absolute)) ab = absolute
    y = 0.0_dp
    do k = 1, size(cc, 1)
      do a = 1, 2
        b = model%work%cs%rbody(a, k)
        if (b == 0) cycle
        if (ab) then
          y(6 * b - 5:6 * b) = y(6 * b - 5:6 * b) + abs(cc(k, 6 * a - 5:6 * a)) * abs(x(k))
        else
          y(6 * b - 5:6 * b) = y(6 * b - 5:6 * b) + cc(k, 6 * a - 5:6 * a) * x(k)
        end if
      end do
    end do
  end function compact_ct

  !> work's arrays of spatial_accelerations, for nb bodies and m rows
  subroutine accelerations_scratch(model, work, stat, asked)
    type(mbdk_spatial_model_t), intent(in) :: model
    type(mbdk_spatial_work_t), intent(inout) :: work
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nb, m, k, mc_, cc_
    nb = model%nb
    m = model%m
    if (allocated(work%fw)) deallocate (work%fw, work%nbd, work%acc, work%gen, work%phi, &
                                        work%c, work%gam, work%l, work%mc, work%phit, &
                                        work%cc, work%dx, work%rhs)
    ! dense C and M^-1 C^T, or their compact rows (the sparse path)
    mc_ = merge(0, m, model%sparse)
    cc_ = merge(m, 0, model%sparse)
    allocate (work%fw(3, nb), work%nbd(3, nb), work%acc(6 * nb), work%gen(6 * nb), &
              work%phi(m), work%c(mc_, 6 * nb), work%gam(m), work%l(m), work%mc(6 * nb, mc_), &
              work%phit(m), work%cc(cc_, 12), work%dx(6 * nb), work%rhs(m), stat=k)
    call mbdk_alloc_status(k, MBDK_REAL_BYTES * (24.0_dp * nb + real(mc_, dp) * 12.0_dp * nb + &
                                                 5.0_dp * m + 12.0_dp * cc_), stat, asked)
  end subroutine accelerations_scratch

  !> F(t, y) and, optionally, the multipliers lam (m). With lam_in (m) the multipliers are
  !> given, not solved for (the DAE form, mbdk_spatial_dae_rhs), phi_out receives Phi and
  !> acc_abs (6 nb) the magnitudes of the accelerations' terms, |M^-1 (f - W x J W)| +
  !> |M^-1 C^T| |lam| (their sum can cancel: a body resting on its joint)
  subroutine spatial_accelerations(self, t, y, f, stat, lam, lam_in, phi_out, acc_abs)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: f(:)
    integer, intent(out) :: stat
    real(dp), intent(out), optional :: lam(:)
    real(dp), intent(in), optional :: lam_in(:)
    real(dp), intent(out), optional :: phi_out(:), acc_abs(:)
    real(dp) :: vg, vs, power
    integer :: nb, m
    f = 0.0_dp
    nb = self%nb
    m = self%m
    associate (fw => self%work%fw, nbd => self%work%nbd, acc => self%work%acc, &
               gen => self%work%gen, phi => self%work%phi, c => self%work%c, &
               gam => self%work%gam, l => self%work%l, mc => self%work%mc, &
               phit => self%work%phit, cc => self%work%cc, dx => self%work%dx, &
               fr => self%work%fr, rhs => self%work%rhs)
    call frames(self, y, fr, stat)
    if (stat /= MBDK_SUCCESS) return
    call forces(self, fr, fw, nbd, vg, vs, power, stat)
    if (stat /= MBDK_SUCCESS) return
    call generalized_forces(self, fr, fw, nbd, gen)
    call apply_minv(self, gen, acc)
    if (present(acc_abs)) acc_abs = abs(acc)
    if (self%m > 0 .and. self%sparse) then
      call sparse_accelerations(stat)
      if (stat /= MBDK_SUCCESS) return
    else if (self%m > 0 .and. present(lam_in)) then
      call constraints(self, fr, t, phi, c, gam, phit)
      call minv_ct(self, c, mc)
      acc = acc - matmul(mc, lam_in)
      if (present(phi_out)) phi_out = phi
      if (present(acc_abs)) acc_abs = acc_abs + matmul(abs(mc), abs(lam_in))
    else if (self%m > 0 .and. self%opt%formulation == MBDK_FORM_PENALTY) then
      call constraints(self, fr, t, phi, c, gam, phit)
      call penalty_solve(stat)
      if (stat /= MBDK_SUCCESS) return
      if (present(lam)) lam = l
    else if (self%m > 0) then
      call constraints(self, fr, t, phi, c, gam, phit)
      if (self%opt%formulation == MBDK_FORM_BAUMGARTE) &
        gam = gam - 2.0_dp * self%opt%baumgarte_alpha * &
              (matmul(c, y(wi(self, 1):last_velocity(self))) + phit) - &
              self%opt%baumgarte_beta**2 * phi
      ! (C acc - gamma and M^-1 C^T lam in the scratch: an expression's temporary would be
      ! allocated at every evaluation)
      rhs = matmul(c, acc)
      rhs = rhs - gam
      if (self%opt%formulation == MBDK_FORM_REDUCED .and. .not. self%regular_tree) then
        call schur_solve(self, c, rhs, l, mc, stat, MBDK_SPATIAL_NEAR_PIVOT)
      else
        call schur_solve(self, c, rhs, l, mc, stat)
      end if
      if (stat /= MBDK_SUCCESS) return
      dx = matmul(mc, l)
      acc = acc - dx
      if (present(lam)) lam = l
    end if
    ! the kinematic equations
    call body_rates(self, y(1:self%ncoord), y(self%ncoord + 1:last_velocity(self)), &
                    f(1:self%ncoord), stat)
    if (stat /= MBDK_SUCCESS) return
    f(wi(self, 1):last_velocity(self)) = acc
    stat = MBDK_SUCCESS
    end associate

  contains

    !> The constrained accelerations by compact rows (model%sparse): as below, with
    !> sparse_schur for schur_solve (the DAE's multipliers lam_in applied as they are)
    subroutine sparse_accelerations(st)
      integer, intent(out) :: st
      associate (cc => self%work%cc, dx => self%work%dx, acc => self%work%acc, &
                 phi => self%work%phi, gam => self%work%gam, phit => self%work%phit, &
                 l => self%work%l, fr => self%work%fr)
        st = MBDK_SUCCESS
        call constraints(self, fr, t, phi, cc, gam, phit, compact=.true.)
        if (present(lam_in)) then
          acc = acc - compact_minv_ct(self, cc, lam_in, .false.)
          if (present(phi_out)) phi_out = phi
          if (present(acc_abs)) acc_abs = acc_abs + compact_minv_ct(self, cc, lam_in, .true.)
          return
        end if
        if (self%opt%formulation == MBDK_FORM_BAUMGARTE) &
          gam = gam - 2.0_dp * self%opt%baumgarte_alpha * &
                (compact_times(self, cc, y(wi(self, 1):last_velocity(self)), .false.) + phit) - &
                self%opt%baumgarte_beta**2 * phi
        if (self%opt%formulation == MBDK_FORM_REDUCED .and. .not. self%regular_tree) then
          call sparse_schur(self, cc, compact_times(self, cc, acc, .false.) - gam, l, dx, st, &
                            MBDK_SPATIAL_NEAR_PIVOT)
        else
          call sparse_schur(self, cc, compact_times(self, cc, acc, .false.) - gam, l, dx, st)
        end if
        if (st /= MBDK_SUCCESS) return
        acc = acc - dx
        if (present(lam)) lam = l
      end associate
    end subroutine sparse_accelerations

    !> Jalon-Bayo (3.35)-(3.40) on the velocities w: (M + ap C^T C) w' = gen - ap C^T r with
    !> r = -gamma + 2 mu omega (C w + Phi_t) + omega^2 Phi, lam = ap (C w' + r); M + ap C^T C
    !> is definite whatever the rank of C, so redundant joints need no choice of rows
    subroutine penalty_solve(st)
      integer, intent(out) :: st
      real(dp), allocatable :: a(:, :), r(:)
      integer :: bb, oo, kk
      allocate (a(6 * nb, 6 * nb), r(m), stat=kk)
      call mbdk_alloc_status(kk, MBDK_REAL_BYTES * (36.0_dp * nb * nb + m), st)
      if (st /= MBDK_SUCCESS) return
      associate (ap => self%opt%penalty_alpha, om => self%opt%penalty_omega, &
                 mu => self%opt%penalty_mu, c => self%work%c, gam => self%work%gam, &
                 phit => self%work%phit, phi => self%work%phi, acc => self%work%acc, &
                 gen => self%work%gen, l => self%work%l)
        r = -gam + 2.0_dp * mu * om * (matmul(c, y(wi(self, 1):last_velocity(self))) + phit) + &
            om**2 * phi
        ! formed in place: an expression's temporary of 6 nb x 6 nb would be taken without a
        ! status
        a = matmul(transpose(c), c)
        a = ap * a
        do bb = 1, self%nb
          oo = (bb - 1) * 6
          do kk = 1, 3
            a(oo + kk, oo + kk) = a(oo + kk, oo + kk) + self%mass(bb)
          end do
          a(oo + 4:oo + 6, oo + 4:oo + 6) = a(oo + 4:oo + 6, oo + 4:oo + 6) + &
                                            self%inertia(:, :, bb)
        end do
        acc = gen - ap * matmul(r, c)                 ! C^T r as r^T C (meson.build)
        call mbdk_chol_factor(a, st)
        if (st /= MBDK_SUCCESS) then
          st = MBDK_ERR_SINGULAR_MATRIX
          return
        end if
        call mbdk_chol_solve(a, acc, st)
        if (st /= MBDK_SUCCESS) return
        l = ap * (matmul(c, acc) + r)
      end associate
    end subroutine penalty_solve

  end subroutine spatial_accelerations

  !> Whether the pose of y = [q; w] lies within MBDK_RANK_LOSS_WINDOW of a rank loss of the rows
  !> (mbdk_rank_margin): C at q with a body's rotations weighted by 1/reach^2, its reach the
  !> largest distance of its joints' points from its centre (the largest body's where it has
  !> none). The model's buffers are left as they were.
  logical function spatial_near_rank_loss(self, t, y, rows) result(near)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    integer, intent(in) :: rows(:)
    type(frames_t) :: fr
    real(dp), allocatable :: phi(:), c(:, :), gam(:), w(:), reach(:)
    integer :: b, k, st
    near = .false.
    if (size(rows) == 0 .or. size(rows) > MBDK_RANK_LOSS_MAX_ROWS) return
    call frames(self, y, fr, st)
    if (st /= MBDK_SUCCESS) return
    allocate (phi(self%m), c(self%m, 6 * self%nb), gam(self%m), w(6 * self%nb), &
              reach(0:self%nb), stat=st)
    if (st /= 0) return
    call constraints(self, fr, t, phi, c, gam)
    ! (body j = 0 is the ground, whose points are global: not a reach)
    reach = 0.0_dp
    do k = 1, self%nprim
      associate (p => self%prim(k))
        reach(p%bi) = max(reach(p%bi), norm2(p%si))
        if (p%bj > 0) reach(p%bj) = max(reach(p%bj), norm2(p%sj))
      end associate
    end do
    reach(0) = maxval(reach(1:))
    if (.not. (reach(0) > 0.0_dp)) reach(0) = self%geo_length
    w = 1.0_dp
    do b = 1, self%nb
      if (.not. (reach(b) > 0.0_dp)) reach(b) = reach(0)
      w(6 * b - 2:6 * b) = 1.0_dp / reach(b)**2
    end do
    near = mbdk_near_rank_loss(c(rows, :), w, MBDK_RANK_LOSS_WINDOW)
  end function spatial_near_rank_loss

  !> The DAE form's right-hand side at (t, y = [q; w]) with the multipliers lam (m; zero on
  !> the rows a redundant scene leaves out): f = [q'; w'], w' = M^-1 (f - C^T lam - W x J W
  !> terms as Newton-Euler's), and phi = Phi (m) (mbdk_spatial_dae); acc_abs (6 nb): the
  !> magnitudes of w''s terms (spatial_accelerations), for a roundoff estimate.
  subroutine mbdk_spatial_dae_rhs(model, t, y, lam, f, phi, stat, acc_abs)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: t, y(:), lam(:)
    real(dp), intent(out) :: f(:), phi(:)
    integer, intent(out) :: stat
    real(dp), intent(out), optional :: acc_abs(:)
    phi = 0.0_dp
    call spatial_accelerations(model, t, y, f, stat, lam_in=lam, phi_out=phi, acc_abs=acc_abs)
  end subroutine mbdk_spatial_dae_rhs

  !> Phi (m), C (m x 6 nb), gamma (m) and Phi_t (m) at (t, y) (tests check C, gamma and Phi_t
  !> against differences of Phi along the motion).
  subroutine mbdk_spatial_constraints(model, t, y, phi, c, gam, phit, stat)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: phi(:), c(:, :), gam(:), phit(:)
    integer, intent(out) :: stat
    type(frames_t) :: fr
    phi = 0.0_dp
    c = 0.0_dp
    gam = 0.0_dp
    phit = 0.0_dp
    call frames(model, y, fr, stat)
    if (stat /= MBDK_SUCCESS) return
    call constraints(model, fr, t, phi, c, gam, phit)
  end subroutine mbdk_spatial_constraints

  !> The multipliers lam (m) of the formulation's constrained solve at (t, y).
  subroutine mbdk_spatial_multipliers(model, t, y, lam, stat)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: lam(:)
    integer, intent(out) :: stat
    real(dp), allocatable :: f(:)
    integer :: astat
    allocate (f(size(y)), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * size(y), stat)
    if (stat /= MBDK_SUCCESS) return
    call spatial_accelerations(model, t, y, f, stat, lam)
  end subroutine mbdk_spatial_multipliers

  !> After a step: quaternions back to unit norm (norm = project), and with the projection
  !> formulation positions onto Phi = 0 and velocities onto C w + Phi_t = 0.
  subroutine spatial_post_step(self, t, y, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: y(:)
    integer, intent(out) :: stat
    call spatial_project(self, t, y, self%opt%formulation == MBDK_FORM_PROJECTION, stat)
  end subroutine spatial_post_step

  !> Normalises the quaternions, and with constrained: the least mass-weighted change of
  !> positions (Gauss-Newton in dr and the body-frame rotation dtheta) that makes |Phi| <=
  !> projection_tol at time t, then of velocities that makes C w + Phi_t = 0. A projection that
  !> does not converge: MBDK_ERR_NEWTON_DIVERGED; dependent rows: MBDK_ERR_SINGULAR_MATRIX.
  subroutine spatial_project(self, t, y, constrained, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: y(:)
    logical, intent(in) :: constrained
    integer, intent(out) :: stat
    type(frames_t) :: fr
    real(dp), allocatable :: phi(:), c(:, :), gam(:), l(:), mc(:, :), d(:), phit(:)
    real(dp) :: tol
    integer :: it, b, k, m, nb
    stat = MBDK_SUCCESS
    if (self%opt%rotation == MBDK_ROT_QUATERNION .and. self%opt%norm == MBDK_NORM_PROJECT) &
      call normalise(self, y)
    if (.not. constrained .or. self%m == 0) return
    m = self%m
    nb = self%nb
    if (self%sparse) then
      call sparse_project(stat)
      return
    end if
    allocate (phi(m), c(m, 6 * nb), gam(m), l(m), mc(6 * nb, m), d(6 * nb), phit(m), stat=k)
    call mbdk_alloc_status(k, MBDK_REAL_BYTES * (real(m, dp) * (12.0_dp * nb + 4) + 6.0_dp * nb), &
                           stat)
    if (stat /= MBDK_SUCCESS) return
    tol = max(self%opt%projection_tol, 16.0_dp * epsilon(1.0_dp) * self%length)
    do it = 1, PROJECTION_MAX_ITER + 1
      call frames(self, y, fr, stat)
      if (stat /= MBDK_SUCCESS) return
      call constraints(self, fr, t, phi, c, gam, phit)
      if (maxval(abs(phi)) <= tol) exit
      stat = MBDK_ERR_NEWTON_DIVERGED
      if (it > PROJECTION_MAX_ITER) return
      call schur_solve(self, c, phi, l, mc, stat)
      if (stat /= MBDK_SUCCESS) return
      d = -matmul(mc, l)
      do b = 1, self%nb
        k = qi(self, b)
        y(k:k + 2) = y(k:k + 2) + d((b - 1) * 6 + 1:(b - 1) * 6 + 3)
        call rotate_by(self, y(k + 3:k + self%nqb - 1), d((b - 1) * 6 + 4:(b - 1) * 6 + 6), stat)
        if (stat /= MBDK_SUCCESS) return
      end do
    end do
    ! velocities: w - M^-1 C^T S^-1 (C w + Phi_t)
    call schur_solve(self, c, matmul(c, y(wi(self, 1):last_velocity(self))) + phit, l, mc, stat)
    if (stat /= MBDK_SUCCESS) return
    y(wi(self, 1):last_velocity(self)) = y(wi(self, 1):last_velocity(self)) - matmul(mc, l)

  contains

    !> the same by compact rows and sparse_schur (model%sparse)
    subroutine sparse_project(st)
      integer, intent(out) :: st
      real(dp), allocatable :: cc(:, :)
      allocate (phi(m), cc(m, 12), gam(m), l(m), d(6 * nb), phit(m), stat=k)
      call mbdk_alloc_status(k, MBDK_REAL_BYTES * (16.0_dp * m + 6.0_dp * nb), st)
      if (st /= MBDK_SUCCESS) return
      tol = max(self%opt%projection_tol, 16.0_dp * epsilon(1.0_dp) * self%length)
      do it = 1, PROJECTION_MAX_ITER + 1
        call frames(self, y, fr, st)
        if (st /= MBDK_SUCCESS) return
        call constraints(self, fr, t, phi, cc, gam, phit, compact=.true.)
        if (maxval(abs(phi)) <= tol) exit
        st = MBDK_ERR_NEWTON_DIVERGED
        if (it > PROJECTION_MAX_ITER) return
        call sparse_schur(self, cc, phi, l, d, st)
        if (st /= MBDK_SUCCESS) return
        d = -d
        do b = 1, nb
          k = qi(self, b)
          y(k:k + 2) = y(k:k + 2) + d((b - 1) * 6 + 1:(b - 1) * 6 + 3)
          call rotate_by(self, y(k + 3:k + self%nqb - 1), d((b - 1) * 6 + 4:(b - 1) * 6 + 6), st)
          if (st /= MBDK_SUCCESS) return
        end do
      end do
      call sparse_schur(self, cc, compact_times(self, cc, y(wi(self, 1):last_velocity(self)), &
                                                .false.) + phit, l, d, st)
      if (st /= MBDK_SUCCESS) return
      y(wi(self, 1):last_velocity(self)) = y(wi(self, 1):last_velocity(self)) - d
    end subroutine sparse_project

  end subroutine spatial_project

  subroutine normalise(self, y)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(inout) :: y(:)
    integer :: b, k
    real(dp) :: s
    do b = 1, self%nb
      k = qi(self, b) + 3
      s = norm2(y(k:k + 3))
      if (s > 0.0_dp) y(k:k + 3) = y(k:k + 3) / s
    end do
  end subroutine normalise

  !> The orientation coordinates p turned by the small body-frame rotation dth: a quaternion
  !> p (1, dth / 2), renormalised to its own norm; angles by G_b^-1 dth.
  subroutine rotate_by(self, p, dth, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(inout) :: p(:)
    real(dp), intent(in) :: dth(3)
    integer, intent(out) :: stat
    real(dp) :: s, da(3)
    stat = MBDK_SUCCESS
    if (self%opt%rotation == MBDK_ROT_QUATERNION) then
      s = norm2(p(1:4))
      p(1:4) = mbdk_quat_mul(p(1:4), [1.0_dp, 0.5_dp * dth])
      p(1:4) = p(1:4) * (s / norm2(p(1:4)))
    else
      call mbdk_angles_rates(self%seq, p(1:3), dth, .true., da, stat)
      if (stat /= MBDK_SUCCESS) return
      p(1:3) = p(1:3) + da
    end if
  end subroutine rotate_by

  !> The initial state made consistent: the projection of positions and velocities (with the
  !> quaternions normalised when norm = project). moved: the largest change of a coordinate.
  subroutine mbdk_spatial_assemble(model, t, y, moved, stat)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: y(:)
    real(dp), intent(out) :: moved
    integer, intent(out) :: stat
    real(dp), allocatable :: y0(:)
    integer :: astat
    moved = 0.0_dp
    allocate (y0(size(y)), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * size(y), stat)
    if (stat /= MBDK_SUCCESS) return
    y0 = y
    call spatial_project(model, t, y, .true., stat)
    moved = maxval(abs(y - y0))
  end subroutine mbdk_spatial_assemble

  !> The energy parts and residuals at (t, y) (MBDK_SPATIAL_NOUT values): kinetic, gravity and
  !> spring energy, the power of dampers, loads and drivers (lambda . Phi_t, the multipliers from
  !> the model's constrained solve there), max |Phi|, max |C w + Phi_t|, max ||p| - 1|.
  subroutine mbdk_spatial_outputs(model, t, y, out, stat, phi_out, vres_out, vterm_out, lam_in, &
                                  mom, msc)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: out(MBDK_SPATIAL_NOUT)
    !> the multipliers of the drivers' power, where the caller has them (the DAE form's own);
    !> absent: the model's constrained solve at (t, y)
    real(dp), intent(in), optional :: lam_in(:)
    integer, intent(out) :: stat
    real(dp), intent(out), optional :: phi_out(:), vres_out(:), vterm_out(:)
    !> the momenta and their scales (spatial_momenta), for the watch
    real(dp), intent(out), optional :: mom(6), msc(2)
    type(frames_t) :: fr
    real(dp), allocatable :: fw(:, :), nbd(:, :), phi(:), c(:, :), gam(:), w(:), phit(:), &
      lam(:), f(:)
    real(dp) :: kin, qn
    integer :: b, k, m, nb
    out = 0.0_dp
    m = model%m
    nb = model%nb
    ! C dense, or in compact rows on the sparse path (the same residuals, summed in another
    ! order)
    allocate (fw(3, nb), nbd(3, nb), phi(m), c(m, merge(12, 6 * nb, model%sparse)), gam(m), &
              w(6 * nb), phit(m), lam(m), f(size(y)), stat=k)
    call mbdk_alloc_status(k, MBDK_REAL_BYTES * (12.0_dp * nb + real(m, dp) * &
                                                 (merge(12.0_dp, 6.0_dp * nb, model%sparse) + 4) &
                                                 + size(y)), stat)
    if (stat /= MBDK_SUCCESS) return
    call frames(model, y, fr, stat)
    if (stat /= MBDK_SUCCESS) return
    call forces(model, fr, fw, nbd, out(2), out(3), out(4), stat)
    if (stat /= MBDK_SUCCESS) return
    kin = 0.0_dp
    qn = 0.0_dp
    do b = 1, model%nb
      kin = kin + 0.5_dp * model%mass(b) * dot_product(fr%v(:, b), fr%v(:, b)) + &
        0.5_dp * dot_product(fr%om(:, b), rmul(model%inertia(:, :, b), fr%om(:, b)))
      if (model%opt%rotation == MBDK_ROT_QUATERNION) then
        k = qi(model, b) + 3
        qn = max(qn, abs(norm2(y(k:k + 3)) - 1.0_dp))
      end if
    end do
    out(1) = kin
    out(7) = qn
    if (present(mom) .and. present(msc)) call spatial_momenta(model, fr, mom, msc)
    if (model%m > 0) then
      call constraints(model, fr, t, phi, c, gam, phit, compact=model%sparse)
      w = y(wi(model, 1):last_velocity(model))
      out(5) = maxval(abs(phi))
      if (model%sparse) then
        gam = compact_times(model, c, w, .false.) + phit   ! gam's storage: C w + Phi_t
        out(6) = maxval(abs(gam))
        if (present(vres_out)) vres_out = gam
        if (present(vterm_out)) vterm_out = compact_times(model, c, w, .true.) + abs(phit)
      else
        out(6) = maxval(abs(matmul(c, w) + phit))
        if (present(vres_out)) vres_out = matmul(c, w) + phit
        if (present(vterm_out)) vterm_out = matmul(abs(c), abs(w)) + abs(phit)
      end if
      if (present(phi_out)) phi_out = phi
      if (model%has_drivers) then
        if (present(lam_in)) then
          lam = lam_in
        else
          call spatial_accelerations(model, t, y, f, stat, lam)
          if (stat /= MBDK_SUCCESS) return
        end if
        out(4) = out(4) + dot_product(lam, phit)
      end if
    end if
  end subroutine mbdk_spatial_outputs

  !> The power of dampers, loads and drivers alone at (t, y), for the watch's work between its
  !> checks and at a step's Gauss nodes: the forces' power, and a driven scene's lambda . Phi_t
  !> (lam_in: the caller's multipliers, else the model's constrained solve), as in
  !> mbdk_spatial_outputs, without the rest of its outputs.
  subroutine spatial_power(model, t, y, power, stat, lam_in)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: power
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: lam_in(:)
    type(frames_t) :: fr
    real(dp), allocatable :: fw(:, :), nbd(:, :), phi(:), c(:, :), gam(:), phit(:), lam(:), &
      f(:)
    real(dp) :: vg, vs
    integer :: m, nb, k
    power = 0.0_dp
    m = model%m
    nb = model%nb
    allocate (fw(3, nb), nbd(3, nb), stat=k)
    call mbdk_alloc_status(k, MBDK_REAL_BYTES * 6.0_dp * nb, stat)
    if (stat /= MBDK_SUCCESS) return
    call frames(model, y, fr, stat)
    if (stat /= MBDK_SUCCESS) return
    call forces(model, fr, fw, nbd, vg, vs, power, stat)
    if (stat /= MBDK_SUCCESS) return
    if (.not. (model%has_drivers .and. m > 0)) return
    ! Phi_t alone is wanted: C in compact rows, whatever the path
    allocate (phi(m), c(m, 12), gam(m), phit(m), lam(m), f(size(y)), stat=k)
    call mbdk_alloc_status(k, MBDK_REAL_BYTES * (16.0_dp * m + size(y)), stat)
    if (stat /= MBDK_SUCCESS) return
    call constraints(model, fr, t, phi, c, gam, phit, compact=.true.)
    if (present(lam_in)) then
      lam = lam_in
    else
      call spatial_accelerations(model, t, y, f, stat, lam)
      if (stat /= MBDK_SUCCESS) return
    end if
    power = power + dot_product(lam, phit)
  end subroutine spatial_power

  subroutine spatial_watch_start(self, t, y, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    integer, intent(out) :: stat
    call spatial_watch_begin(self, t, y, .true., stat)
  end subroutine spatial_watch_start

  !> The watch started at (t, y); velocity = .false.: the integrator does not promise the
  !> velocity constraints (the book's index-3 scheme), so they are not tested.
  subroutine spatial_watch_begin(self, t, y, velocity, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: velocity
    integer, intent(out) :: stat
    real(dp) :: out(MBDK_SPATIAL_NOUT), mom(6), msc(2)
    call mbdk_spatial_outputs(self, t, y, out, stat, mom=mom, msc=msc)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_watch_start(self%work%watch, self%opt%watch_position, &
                          merge(self%opt%watch_velocity, 0.0_dp, velocity), &
                          self%opt%watch_energy, self%opt%watch_every, self%has_power, &
                          self%length, self%row_angular, t, out(1), out(2), out(3), &
                          [0.0_dp, 0.0_dp, out(4)], self%gscale, sum(self%mass), stat, &
                          self%record_work)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_watch_start_invariants(self%work%watch, self%opt%watch_momentum, self%inv, &
                                     self%ninv, mom, msc, self%opt%watch_quaternion, &
                                     merge(self%nb, 0, self%opt%rotation == MBDK_ROT_QUATERNION))
  end subroutine spatial_watch_begin

  !> The watch with the multipliers of the drivers' power solved for at (t, y).
  subroutine spatial_watch_solve(self, t, y, force, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    call mbdk_spatial_watch(self, t, y, force, stat)
  end subroutine spatial_watch_solve

  !> q (+) dq body by body: r + dr, and the orientation turned by the body-frame rotation
  !> dtheta, R+ = R exp(skew(dtheta)): a quaternion multiplied by exp(dtheta / 2) (its norm
  !> kept), an angle set moved along its rates by the midpoint rule (exact to O(|dtheta|^3),
  !> the order of a trapezoidal step's own error; at the set's gimbal lock
  !> MBDK_ERR_SINGULAR_MATRIX).
  subroutine spatial_retract(self, q, dq, qn, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: q(:), dq(:)
    real(dp), intent(out) :: qn(:)
    integer, intent(out) :: stat
    real(dp) :: th, e(4), da(3), am(3)
    integer :: b, k, o
    stat = MBDK_SUCCESS
    do b = 1, self%nb
      k = qi(self, b)
      o = (b - 1) * 6
      qn(k:k + 2) = q(k:k + 2) + dq(o + 1:o + 3)
      associate (dth => dq(o + 4:o + 6))
        if (self%opt%rotation == MBDK_ROT_QUATERNION) then
          th = norm2(dth)
          e(1) = cos(0.5_dp * th)
          if (th > 0.0_dp) then
            e(2:4) = (sin(0.5_dp * th) / th) * dth
          else
            e(2:4) = 0.0_dp
          end if
          qn(k + 3:k + 6) = mbdk_quat_mul(q(k + 3:k + 6), e)
        else
          call mbdk_angles_rates(self%seq, q(k + 3:k + 5), dth, .true., da, stat)
          if (stat /= MBDK_SUCCESS) return
          am = q(k + 3:k + 5) + 0.5_dp * da
          call mbdk_angles_rates(self%seq, am, dth, .true., da, stat)
          if (stat /= MBDK_SUCCESS) return
          qn(k + 3:k + 5) = q(k + 3:k + 5) + da
        end if
      end associate
    end do
  end subroutine spatial_retract

  !> the quaternions to unit norm (angle sets have nothing to keep)
  subroutine spatial_normalise(self, q)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(inout) :: q(:)
    integer :: b, k
    real(dp) :: n
    if (self%opt%rotation /= MBDK_ROT_QUATERNION) return
    do b = 1, self%nb
      k = qi(self, b) + 3
      n = norm2(q(k:k + 3))
      if (n > 0.0_dp) q(k:k + 3) = q(k:k + 3) / n
    end do
  end subroutine spatial_normalise

  !> |r| component by component for the translations, 1 (a rotation of the body's unit frame)
  !> for the rotations
  subroutine spatial_coord_weights(self, q, w)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: q(:)
    real(dp), intent(out) :: w(:)
    integer :: b, k, o
    do b = 1, self%nb
      k = qi(self, b)
      o = (b - 1) * 6
      w(o + 1:o + 3) = abs(q(k:k + 2))
      w(o + 4:o + 6) = 1.0_dp
    end do
  end subroutine spatial_coord_weights

  !> Whether the watch integrates a work the run reports (the states inside a step serve it).
  logical function spatial_wants_nodes(self)
    class(mbdk_spatial_model_t), intent(in) :: self
    spatial_wants_nodes = .false.
    if (self%has_watch) spatial_wants_nodes = self%work%watch%power .and. self%work%watch%record
  end function spatial_wants_nodes

  subroutine spatial_watch_nodes(self, t_a, t_b, y, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t_a, t_b, y(:, :)
    integer, intent(out) :: stat
    call mbdk_spatial_watch_nodes(self, t_a, t_b, y, stat)
  end subroutine spatial_watch_nodes

  !> The power of dampers, loads and drivers at the states y(:, k) = [q; w] of the accepted step
  !> [t_a, t_b] at its Gauss nodes (MBDK_GAUSS3), for the watch's integral over the step; lam(:,
  !> k): the multipliers there where the caller has its own (a DAE form's).
  subroutine mbdk_spatial_watch_nodes(self, t_a, t_b, y, stat, lam)
    type(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t_a, t_b, y(:, :)
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: lam(:, :)
    real(dp) :: p(3, 3), tn(3)
    integer :: k
    stat = MBDK_SUCCESS
    if (.not. self%has_watch) return
    if (.not. self%work%watch%power) return
    tn = t_a + MBDK_GAUSS3 * (t_b - t_a)
    p = 0.0_dp
    do k = 1, 3
      if (present(lam)) then
        call spatial_power(self, tn(k), y(:, k), p(3, k), stat, lam(:, k))
      else
        call spatial_power(self, tn(k), y(:, k), p(3, k), stat)
      end if
      if (stat /= MBDK_SUCCESS) return
    end do
    call mbdk_watch_nodes(self%work%watch, t_a, t_b, tn, p)
  end subroutine mbdk_spatial_watch_nodes

  subroutine spatial_watch(self, t, y, force, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    call mbdk_spatial_watch(self, t, y, force, stat)
  end subroutine spatial_watch

  !> The watch at (t, y = [q; w]); lam: the multipliers of the drivers' power where the caller
  !> has its own (the DAE form), else the model's constrained solve gives them. The power
  !> (dampers, loads and drivers together) is the third of the watch's work parts.
  subroutine mbdk_spatial_watch(self, t, y, force, stat, lam)
    type(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: lam(:)
    real(dp) :: out(MBDK_SPATIAL_NOUT), mom(6), msc(2)
    real(dp), allocatable :: phi(:), vres(:), vterm(:), qdev(:)
    real(dp) :: p
    integer :: due, astat, b, k
    stat = MBDK_SUCCESS
    due = mbdk_watch_due(self%work%watch, force)
    if (due == MBDK_WATCH_NOTHING) return
    if (due == MBDK_WATCH_POWER_ONLY) then
      call spatial_power(self, t, y, p, stat, lam)
      if (stat == MBDK_SUCCESS) call mbdk_watch_power(self%work%watch, t, [0.0_dp, 0.0_dp, p])
      return
    end if
    allocate (phi(self%m), vres(self%m), vterm(self%m), qdev(self%nb), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (3.0_dp * self%m + self%nb), stat)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_spatial_outputs(self, t, y, out, stat, phi, vres, vterm, lam, mom, msc)
    if (stat /= MBDK_SUCCESS) return
    qdev = 0.0_dp
    if (self%opt%rotation == MBDK_ROT_QUATERNION) then
      do b = 1, self%nb
        k = qi(self, b) + 3
        qdev(b) = abs(norm2(y(k:k + 3)) - 1.0_dp)
      end do
    end if
    call mbdk_watch_test(self%work%watch, t, phi, vres, vterm, out(1), out(2), out(3), &
                         [0.0_dp, 0.0_dp, out(4)], stat, mom=mom, mom_scale=msc, qdev=qdev)
  end subroutine mbdk_spatial_watch

  !> q' = T(q) v body by body: r' = v, and the orientation's rates from Omega (5.43), (5.95),
  !> with a quaternion's norm stabilisation where the scene asks for it (norm = stabilise);
  !> an angle set within lock_guard of its gimbal lock, or at it: MBDK_ERR_SINGULAR_MATRIX.
  subroutine body_rates(self, q, v, qdot, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: q(:), v(:)
    real(dp), intent(out) :: qdot(:)
    integer, intent(out) :: stat
    real(dp) :: p(4)
    integer :: b, k, o
    stat = MBDK_SUCCESS
    do b = 1, self%nb
      k = qi(self, b)
      o = (b - 1) * 6
      qdot(k:k + 2) = v(o + 1:o + 3)
      if (self%opt%rotation == MBDK_ROT_QUATERNION) then
        p = q(k + 3:k + 6)
        qdot(k + 3:k + 6) = mbdk_quat_rates(p, v(o + 4:o + 6), .true.)
        if (self%opt%norm == MBDK_NORM_STABILISE) qdot(k + 3:k + 6) = qdot(k + 3:k + 6) + &
          0.5_dp * self%opt%norm_gain * (1.0_dp - dot_product(p, p)) * p
      else
        if (self%opt%lock_guard > 0.0_dp) then
          if (merge(abs(sin(q(k + 4))), abs(cos(q(k + 4))), &
                    self%opt%rotation == MBDK_ROT_EULER313) < self%opt%lock_guard) then
            stat = MBDK_ERR_SINGULAR_MATRIX
            return
          end if
        end if
        call mbdk_angles_rates(self%seq, q(k + 3:k + 5), v(o + 4:o + 6), .true., &
                               qdot(k + 3:k + 5), stat)
        if (stat /= MBDK_SUCCESS) return
      end if
    end do
  end subroutine body_rates

  ! ----- the mechanism interface (mbdk_mechanism) -----


  !> f (6 nb) of the equations of motion in the body frames: the forces fw and the moments nbd
  !> with the gyroscopic moment -Omega x J Omega
  subroutine generalized_forces(self, fr, fw, nbd, f)
    class(mbdk_spatial_model_t), intent(in) :: self
    type(frames_t), intent(in) :: fr
    real(dp), intent(in) :: fw(:, :), nbd(:, :)
    real(dp), intent(out) :: f(:)
    real(dp) :: jw(3)
    integer :: b, o
    do b = 1, self%nb
      o = (b - 1) * 6
      jw = rmul(self%inertia(:, :, b), fr%om(:, b))
      f(o + 1:o + 3) = fw(:, b)
      f(o + 4:o + 6) = nbd(:, b) - cross(fr%om(:, b), jw)
    end do
  end subroutine generalized_forces
  !> f = (force, moment - Omega x J Omega) per body, and Phi, C, gamma, Phi_t at (t, q, v).
  subroutine spatial_evaluate(self, t, q, v, f, phi, c, gam, phit, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: q(:), v(:)
    real(dp), intent(out), contiguous :: f(:), phi(:), c(:, :), gam(:), phit(:)
    integer, intent(out) :: stat
    type(frames_t) :: fr
    real(dp), allocatable :: y(:), fw(:, :), nbd(:, :)
    real(dp) :: vg, vs, power
    integer :: astat
    stat = MBDK_ERR_NONFINITE
    if (.not. (all(abs(q) <= huge(1.0_dp)) .and. all(abs(v) <= huge(1.0_dp)))) return
    allocate (y(last_velocity(self)), fw(3, self%nb), nbd(3, self%nb), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (last_velocity(self) + 6.0_dp * self%nb), &
                           stat)
    if (stat /= MBDK_SUCCESS) return
    y(1:self%ncoord) = q
    y(self%ncoord + 1:) = v
    call frames(self, y, fr, stat)
    if (stat /= MBDK_SUCCESS) return
    call forces(self, fr, fw, nbd, vg, vs, power, stat)
    if (stat /= MBDK_SUCCESS) return
    call generalized_forces(self, fr, fw, nbd, f)
    if (self%m == 0) return
    phi = 0.0_dp
    c = 0.0_dp
    gam = 0.0_dp
    phit = 0.0_dp
    call constraints(self, fr, t, phi, c, gam, phit)
  end subroutine spatial_evaluate

  !> M x body by body: m x_r, J x_Omega
  subroutine spatial_mass_times(self, x, y)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: x(:)
    real(dp), intent(out) :: y(:)
    integer :: b, o
    do b = 1, self%nb
      o = (b - 1) * 6
      y(o + 1:o + 3) = self%mass(b) * x(o + 1:o + 3)
      y(o + 4:o + 6) = rmul(self%inertia(:, :, b), x(o + 4:o + 6))
    end do
  end subroutine spatial_mass_times

  subroutine spatial_minv_times(self, x, y)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: x(:)
    real(dp), intent(out) :: y(:)
    call apply_minv(self, x, y)
  end subroutine spatial_minv_times

  !> M's diagonal (M itself is not diagonal where an inertia tensor is not: diag_mass is off)
  subroutine spatial_mass_diagonal(self, dm)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(out) :: dm(:)
    integer :: b, o, k
    do b = 1, self%nb
      o = (b - 1) * 6
      dm(o + 1:o + 3) = self%mass(b)
      do k = 1, 3
        dm(o + 3 + k) = self%inertia(k, k, b)
      end do
    end do
  end subroutine spatial_mass_diagonal

  subroutine spatial_rates(self, q, v, qdot, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: q(:), v(:)
    real(dp), intent(out) :: qdot(:)
    integer, intent(out) :: stat
    call body_rates(self, q, v, qdot, stat)
  end subroutine spatial_rates

  !> the formulation's accelerations and multipliers (a redundant scene's solve may move it to
  !> another set of independent rows: active_rows after this)
  subroutine spatial_accelerations_of(self, t, q, v, a, lam, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: q(:), v(:)
    real(dp), intent(out), contiguous :: a(:), lam(:)
    integer, intent(out) :: stat
    real(dp), allocatable :: y(:), f(:)
    integer :: astat
    allocate (y(last_velocity(self)), f(last_velocity(self)), stat=astat)
    call mbdk_alloc_status(astat, 2 * MBDK_REAL_BYTES * last_velocity(self), stat)
    if (stat /= MBDK_SUCCESS) return
    y(1:self%ncoord) = q
    y(self%ncoord + 1:) = v
    if (self%m > 0) then
      call spatial_accelerations(self, t, y, f, stat, lam)
    else
      call spatial_accelerations(self, t, y, f, stat)
    end if
    if (stat /= MBDK_SUCCESS) return
    a = f(self%ncoord + 1:)
  end subroutine spatial_accelerations_of

  !> the independent rows the model solves now (work%active)
  subroutine spatial_active_rows(self, rows, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    integer, allocatable, intent(out) :: rows(:)
    integer, intent(out) :: stat
    integer :: astat
    allocate (rows(size(self%work%active)), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * size(self%work%active), stat)
    if (stat /= MBDK_SUCCESS) return
    rows = self%work%active
  end subroutine spatial_active_rows

  subroutine spatial_watch_lam(self, t, y, force, lam, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:), lam(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    call mbdk_spatial_watch(self, t, y, force, stat, lam)
  end subroutine spatial_watch_lam

  subroutine spatial_watch_nodes_lam(self, t_a, t_b, y, lam, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: t_a, t_b, y(:, :), lam(:, :)
    integer, intent(out) :: stat
    call mbdk_spatial_watch_nodes(self, t_a, t_b, y, stat, lam)
  end subroutine spatial_watch_nodes_lam

end module mbdk_spatial_model
