!> Joint coordinates for a spatial scene: the relative coordinates of the book's section 1.3
!> ((1.28)-(1.29), the four-bar) carried to 3D bodies, as a problem y' = F(t, y) for every ODE
!> integrator.
!>
!> The scene's joints are split, once at the start, into a spanning tree and the joints left
!> over. A tree grows from the ground in sweeps over the joint table in its order: a joint
!> joins it where it reaches a body not yet reached from one that is (reached earlier in the
!> same sweep or before), so that the split is the same on every run. Revolute, prismatic,
!> cylindrical, spherical and fixed joints can be tree joints; the others (universal, the
!> drivers) and any joint between two bodies already reached are cut. Each tree joint gives
!> its body the coordinates its motion relative to its parent has, measured from the initial
!> pose, and as many rates (dofs):
!>   revolute     theta, the turn about the joint's axis through its point (1, 1)
!>   prismatic    s, the slide along the axis (1, 1)
!>   cylindrical  theta, then s along the same axis (2, 2)
!>   spherical    p, the quaternion of the body's turn relative to its initial orientation on
!>                its parent, and Omega, the body's angular velocity relative to its parent in
!>                its own frame: p' = p (0, Omega) / 2 + k (1 - |p|^2) p / 2 (4, 3)
!>   fixed        none (the body rides on its parent)
!> so that the state is y = [q; v] (nc coordinates, ndof rates; without a spherical joint
!> q' = v, and Euler-Cromer applies). A spherical joint's turn is taken from p / |p|, so that
!> its norm plays no part, and its norm is held by the stabilisation term, k the scene's
!> norm_gain, whatever its quaternion_norm (no step changes the state: every ODE method
!> takes it). Every body must hang on the tree; a body reached only through a universal joint,
!> or no joint, is MBDK_ERR_NOT_APPLICABLE (the absolute coordinates of mbdk_spatial_model
!> take it).
!>
!> The kinematics run from the root: a body's quaternion is its parent's times the joint's
!> turn (about the axis in the parent's frame) times the initial relative orientation (a
!> spherical joint's turn after it, in the body's frame), its centre follows from the joint's
!> point, and its velocity and the accelerations at theta'' = 0 (the bias) follow by the
!> recursive formulas of rigid motion (Featherstone, Rigid Body Dynamics Algorithms, 2008, ch. 3;
!> Shabana, Computational Dynamics, 2010, 8.3), in the space frame. With xi = (r', Omega)
!> the absolute model's velocities of every body, xi = J theta' and xi' = J theta'' + b,
!> column k of J on a body the dof moves being (u x (r - P), R^T u) for a turn about the unit
!> axis u through P (a spherical joint's three: its body's axes through the joint's point)
!> and (u, 0) for a slide. The absolute model's Newton-Euler equations
!> M xi' = f - C_c^T lambda (mbdk_spatial_model: M = diag(m I, J), f with the gyroscopic
!> moment) projected on J (virtual power) give
!>
!>   (J^T M J) theta'' + G^T lambda = J^T (f - M b),   G theta'' = gamma_c - C_c b
!>
!> with G = C_c J the cut joints' rows in the joint coordinates. The tree's joints hold by
!> construction, at every state, to roundoff; the cut rows drift as the absolute reduced
!> formulation's do. The equations are evaluated by pairs of a body and a dof that moves it
!> (the path from the root): O(sum of depths^2) for J^T M J, which a mechanism of a few tens
!> of bodies keeps small; a long chain is the absolute model's sparse path. Solved by
!> Cholesky (mbdk_lapack), J^T M J and then S = G (J^T M J)^-1 G^T on the cut rows kept:
!> those found independent at the start (a complete-pivoting Cholesky of the geometry's
!> Gs Gs^T, Gs = G with slides and the rows of lengths at the mechanism's length scale, each
!> row of unit length), so that a loop closed by a redundant joint (Bricard's linkage: 5 rows
!> of rank 4 in joint space) keeps a fixed set. A row with no gradient at the start is held by
!> the tree itself (two joints on one axis) where it has none at a second pose either, and is
!> left out; one that has one there (a dead-centre start) or a driver's row left out is
!> MBDK_ERR_SINGULAR_MATRIX. Formulations (the mbdk_mechanism codes):
!>   reduced    G theta'' = gamma_c - C_c b; a relative pivot of the geometry's Gs Gs^T on the
!>              rows kept below MBDK_SPATIAL_NEAR_PIVOT is a singular pose,
!>              MBDK_ERR_SINGULAR_MATRIX, as in the absolute model (the geometry, not S: a
!>              light or slender body would make S's pivots small at a regular pose); it is
!>              formed only where a pivot of S falls below that window of its diagonal
!>   baumgarte  the same, less 2 alpha Phi_c' + beta^2 Phi_c (3.29); stops only at a pivot of S
!>              at roundoff
!> A tree has no cut rows, and then its ODE is the whole model: no constraint to drift.
!>
!> The scene's forces (gravity, point forces, torques, spring-dampers, contacts) and the cut
!> joints' rows are the absolute model's own routines (forces, constraints), evaluated on the
!> bodies' frames: the cut model is an mbdk_spatial_model_t of the scene with only its cut
!> joints. The full model (every joint) is the caller's; through it the run's watch (every
!> row's Phi, C w + Phi_t, the energy balance, the conserved momenta), the contacts' events
!> and the outputs see the absolute state (to_absolute) of each joint state, so that a joint
!> run is checked against the same joints as an absolute one. The start must be on the
!> tree's joints (their rows at MBDK_JOINT_START_RTOL of the length scale) and its velocities
!> fitted by the joint rates (FIT_RTOL), else MBDK_ERR_INCONSISTENT_INITIAL: the tree is
!> built from the start's pose, and would freeze an offset from a joint into the motion. Not
!> taken here (MBDK_ERR_NOT_APPLICABLE): angle sets (a joint run's orientations are
!> quaternions, built from the joint turns), wear states, the penalty and projection
!> formulations.
module mbdk_joint_coords
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_mechanism, only: MBDK_FORM_REDUCED, MBDK_FORM_BAUMGARTE
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_lapack, only: mbdk_chol_factor, mbdk_chol_solve, mbdk_chol_pivoted
  use mbdk_sparse_schur, only: mbdk_sort_ints
  use mbdk_rotations, only: mbdk_quat_conj, mbdk_quat_matrix_of
  use mbdk_elements, only: MBDK_JOINT_REVOLUTE, MBDK_JOINT_PRISMATIC, MBDK_JOINT_CYLINDRICAL, &
    MBDK_JOINT_FIXED, MBDK_JOINT_SPHERICAL, MBDK_JOINT_ANGLE_DRIVER, MBDK_JOINT_SLIDE_DRIVER, &
    mbdk_joint_rows, MBDK_BODY_SPATIAL
  use mbdk_spatial_model, only: mbdk_spatial_model_t, mbdk_spatial_work_t, &
    mbdk_spatial_options_t, mbdk_spatial_init, frames_t, frames, forces, constraints, &
    MBDK_ROT_QUATERNION, MBDK_SPATIAL_NEAR_PIVOT
  implicit none
  private
  public :: mbdk_joint_init, mbdk_joint_to_absolute, mbdk_joint_tree

  !> the kinds of a tree joint (mbdk_joint_tree reports them)
  integer, parameter, public :: MBDK_TREE_TURN = 1, MBDK_TREE_SLIDE = 2, MBDK_TREE_CYLINDER = 3, &
    MBDK_TREE_FIXED = 4, MBDK_TREE_BALL = 5
  !> a pivot of S at or below this fraction of its row's diagonal is a singular solve at
  !> roundoff (the absolute model's SOLVE_RTOL)
  real(dp), parameter :: SOLVE_RTOL = 64.0_dp * epsilon(1.0_dp)
  !> the start's velocities are fitted by the joint rates in the mass-weighted least squares;
  !> a fit off them by more than this fraction of the largest speed (rotations at the length
  !> scale, and at least the length scale's speed at 1 rad/s) is an inconsistent start (the
  !> Python layer refuses starts off their joints by more than its assembly's tolerance, 1e-6,
  !> and assembles them to roundoff)
  real(dp), parameter :: FIT_RTOL = 1.0e-8_dp
  !> the tree's joints' rows at the start, in the length scale (the rows of lengths) and in
  !> radians, at most this: else the start is off a tree joint
  real(dp), parameter, public :: MBDK_JOINT_START_RTOL = 1.0e-8_dp
  !> cut rows whose pivot in the complete-pivoting Cholesky of the unit-diagonal G G^T at the
  !> start falls to this are dependent (the absolute model's REDUNDANT_RTOL)
  real(dp), parameter :: REDUNDANT_RTOL = 1.0e-10_dp

  !> what an evaluation computes, owned by the caller (the model is read-only in rhs)
  type, public :: mbdk_joint_work_t
    type(frames_t) :: fr
    type(mbdk_spatial_work_t) :: cut_work
    !> per body (0: the ground): quaternion, angular velocity (space), bias accelerations
    real(dp), allocatable :: quat(:, :), omw(:, :), a0(:, :), al0(:, :)
    !> per dof: its axis and point in space (a turn's line; a slide's axis)
    real(dp), allocatable :: u(:, :), pt(:, :)
    !> per (body, dof) pair: J's column on the body, space-frame translation, body-frame rotation
    real(dp), allocatable :: lin(:, :), ang(:, :)
    real(dp), allocatable :: mq(:, :), dinv(:), qv(:), fw(:, :), nbd(:, :), phi(:), c(:, :), &
      gam(:), phit(:), g(:, :), yg(:, :), s(:, :), lam(:), sdiag(:), yabs(:), yabs3(:, :)
    !> the geometric near test (close_loops): the kept rows of G scaled, their Gram matrix
    real(dp), allocatable :: gs(:, :), gg(:, :)
  end type mbdk_joint_work_t

  !> The joint-coordinate model of a spatial scene: n = nc + ndof, nq = ndof where nc = ndof
  !> (no spherical joint on the tree).
  type, extends(mbdk_problem_t), public :: mbdk_joint_model_t
    integer :: nb = 0, ndof = 0, nc = 0, mc = 0, nact = 0, formulation = MBDK_FORM_REDUCED
    real(dp) :: alpha = 0.0_dp, beta = 0.0_dp, norm_gain = 0.0_dp
    !> bodies from the root (parents first), and per body its parent (0: the ground), tree
    !> joint (table column), kind (MBDK_TREE_*) and first dof
    integer, allocatable :: order(:), parent(:), tjoint(:), kind(:), dof(:)
    !> per body, its first coordinate in y
    integer, allocatable :: qoff(:)
    !> per dof: .true. for a turn, .false. for a slide
    logical, allocatable :: turn(:)
    !> per body: the dofs that move it (the path from the root), pairs pptr(b) .. pptr(b+1)-1
    integer, allocatable :: pptr(:), pdof(:)
    !> per body, in its parent's frame: the joint's axis and point, the centre at the start
    !> (c0); in its own frame: from the joint's point to its centre (dch); the initial relative
    !> orientation (e0, a quaternion)
    real(dp), allocatable :: axis(:, :), spt(:, :), c0(:, :), dch(:, :), e0(:, :)
    !> (0, axis) e0, so that a turn's (cos, sin axis) e0 is cos e0 + sin ae0
    real(dp), allocatable :: ae0(:, :)
    !> per cut row, its two bodies (0: the ground), where its C has entries, and whether it
    !> is a driver's
    integer, allocatable :: rbody(:, :)
    logical, allocatable :: driver(:)
    real(dp), allocatable :: mass(:), inertia(:, :, :)
    !> the cut joints (table columns) and the cut rows solved (of the cut model's rows)
    integer, allocatable :: cut(:), active(:)
    real(dp) :: length = 1.0_dp
    type(mbdk_spatial_model_t) :: cutm
    type(mbdk_spatial_model_t), pointer :: full => null()
    type(mbdk_joint_work_t), pointer :: work => null()
  contains
    procedure :: rhs => joint_rhs
    procedure :: watch_start => joint_watch_start
    procedure :: watch => joint_watch
    procedure :: watch_wants_nodes => joint_wants_nodes
    procedure :: watch_nodes => joint_watch_nodes
    procedure :: events => joint_events
  end type mbdk_joint_model_t

contains

  !> The joint model of the scene whose full absolute model (every joint, built at the start
  !> y0 and t0 with options so) is full: the tree split, the references taken at y0, the cut
  !> model built (its tables: the scene's with only the cut joints), the cut rows kept and the
  !> initial joint state y0j = [q_0; v_0] (q_0 every turn and slide 0 and every spherical
  !> joint's quaternion the identity, v_0 fitted to y0's velocities). work:
  !> the caller's (its arrays made here), outliving the model. MBDK_ERR_NOT_APPLICABLE: a
  !> body off the tree, angle sets, wear, a formulation other than reduced or baumgarte, no
  !> dof; MBDK_ERR_INCONSISTENT_INITIAL: y0 off the tree's joints (MBDK_JOINT_START_RTOL) or
  !> its velocities (FIT_RTOL); MBDK_ERR_SINGULAR_MATRIX: a cut row the start leaves no
  !> gradient that has one elsewhere, or a driver's row left out (choose_cut_rows).
  subroutine mbdk_joint_init(jm, work, full, so, mass, inertia, jtype, jbody, jreal, ftype, &
                             fbody, freal, t0, y0, y0j, stat, asked)
    type(mbdk_joint_model_t), intent(out) :: jm
    type(mbdk_joint_work_t), intent(out), target :: work
    type(mbdk_spatial_model_t), intent(in), target :: full
    type(mbdk_spatial_options_t), intent(in) :: so
    real(dp), intent(in) :: mass(:), inertia(:, :, :), jreal(:, :), freal(:, :), t0, y0(:)
    integer, intent(in) :: jtype(:), jbody(:, :), ftype(:), fbody(:, :)
    real(dp), allocatable, intent(out) :: y0j(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    type(mbdk_spatial_options_t) :: co
    integer :: nb, nj, astat, k, i, r, ncut
    logical, allocatable :: used(:)

    stat = MBDK_ERR_NOT_APPLICABLE
    if (so%rotation /= MBDK_ROT_QUATERNION .or. full%ns > 0) return
    if (so%formulation /= MBDK_FORM_REDUCED .and. so%formulation /= MBDK_FORM_BAUMGARTE) return
    nb = full%nb
    nj = size(jtype)
    jm%nb = nb
    jm%formulation = so%formulation
    jm%alpha = so%baumgarte_alpha
    jm%beta = so%baumgarte_beta
    jm%norm_gain = so%norm_gain
    jm%length = full%geo_length
    jm%full => full
    allocate (jm%order(nb), jm%parent(nb), jm%tjoint(nb), jm%kind(nb), jm%dof(nb), &
              jm%qoff(nb), &
              jm%axis(3, nb), jm%spt(3, nb), jm%c0(3, nb), jm%dch(3, nb), jm%e0(4, nb), &
              jm%ae0(4, nb), &
              jm%mass(nb), jm%inertia(3, 3, nb), jm%pptr(nb + 1), used(nj), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * 32.0_dp * nb + MBDK_INT_BYTES * &
                           (7.0_dp * nb + nj), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    jm%mass = mass
    jm%inertia = inertia
    call grow_tree(jm, jtype, jbody, used, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    ! the cut model: the scene with only its cut joints (and every force)
    ncut = count(.not. used)
    allocate (jm%cut(ncut), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * real(ncut, dp), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    jm%cut = pack([(k, k = 1, nj)], .not. used)
    co = so
    co%formulation = MBDK_FORM_REDUCED
    co%watch_position = 0.0_dp
    co%watch_velocity = 0.0_dp
    co%watch_energy = 0.0_dp
    co%watch_momentum = 0.0_dp
    co%watch_quaternion = 0.0_dp
    call mbdk_spatial_init(jm%cutm, work%cut_work, co, mass, inertia, jtype(jm%cut), &
                           jbody(:, jm%cut), jreal(:, jm%cut), ftype, fbody, freal, t0, y0, &
                           stat, asked)
    if (stat /= MBDK_SUCCESS) return
    jm%mc = jm%cutm%m
    ! the cut model's rows run joint by joint in its table's order (mbdk_spatial_model)
    allocate (jm%rbody(2, jm%mc), jm%driver(jm%mc), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * 3.0_dp * jm%mc, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    r = 0
    do k = 1, size(jm%cut)
      do i = 1, mbdk_joint_rows(jtype(jm%cut(k)), MBDK_BODY_SPATIAL)
        jm%rbody(:, r + i) = jbody(:, jm%cut(k))
        jm%driver(r + i) = jtype(jm%cut(k)) == MBDK_JOINT_ANGLE_DRIVER .or. &
          jtype(jm%cut(k)) == MBDK_JOINT_SLIDE_DRIVER
      end do
      r = r + mbdk_joint_rows(jtype(jm%cut(k)), MBDK_BODY_SPATIAL)
    end do
    call start_on_tree(full, jtype, used, t0, y0, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call take_references(jm, jbody, jreal, y0, stat)
    if (stat /= MBDK_SUCCESS) return
    call paths(jm, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call scratch(jm, work, y0, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    jm%work => work
    jm%n = jm%nc + jm%ndof
    jm%nq = merge(jm%ndof, 0, jm%nc == jm%ndof)
    jm%has_watch = full%has_watch
    jm%nevents = full%nevents
    allocate (y0j(jm%n), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * jm%n, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    ! the start: every turn and slide 0, every spherical joint's turn the identity
    y0j = 0.0_dp
    do k = 1, nb
      if (jm%kind(k) == MBDK_TREE_BALL) y0j(jm%qoff(k)) = 1.0_dp
    end do
    call fit_rates(jm, y0, y0j, stat)
    if (stat /= MBDK_SUCCESS) return
    call choose_cut_rows(jm, t0, y0j, stat, asked)
  end subroutine mbdk_joint_init

  !> The tree from the ground over the joints (jtype, jbody: the scene's table), in sweeps
  !> over the table in its order: per body (nb) its tree joint (table column; 0: the body hangs on
  !> none), kind (MBDK_TREE_*), parent (0: the ground) and place in order (parents first,
  !> order(1:count)); ndof the coordinates. MBDK_ERR_NOT_APPLICABLE where a body is left off
  !> the tree or there is no coordinate. The f2py entry spatial_joint_tree reports it, so
  !> that the Python layer names the bodies and joints from this one split.
  pure subroutine mbdk_joint_tree(nb, jtype, jbody, tjoint, kind, parent, order, ndof, stat)
    integer, intent(in) :: nb, jtype(:), jbody(:, :)
    integer, intent(out) :: tjoint(nb), kind(nb), parent(nb), order(nb), ndof, stat
    logical :: reached(0:nb), grew, used(size(jtype))
    integer :: k, i, j, child, par, count, kd
    used = .false.
    reached = .false.
    reached(0) = .true.
    tjoint = 0
    kind = 0
    parent = 0
    order = 0
    count = 0
    ndof = 0
    grew = .true.
    do while (grew)
      grew = .false.
      do k = 1, size(jtype)
        if (used(k)) cycle
        select case (jtype(k))
        case (MBDK_JOINT_REVOLUTE)
          kd = MBDK_TREE_TURN
        case (MBDK_JOINT_PRISMATIC)
          kd = MBDK_TREE_SLIDE
        case (MBDK_JOINT_CYLINDRICAL)
          kd = MBDK_TREE_CYLINDER
        case (MBDK_JOINT_FIXED)
          kd = MBDK_TREE_FIXED
        case (MBDK_JOINT_SPHERICAL)
          kd = MBDK_TREE_BALL
        case default
          cycle
        end select
        i = jbody(1, k)
        j = jbody(2, k)
        if (i < 1 .or. i > nb .or. j < 0 .or. j > nb) cycle
        if (reached(j) .and. .not. reached(i)) then
          child = i
          par = j
        else if (j > 0 .and. reached(i) .and. .not. reached(j)) then
          child = j
          par = i
        else
          cycle
        end if
        used(k) = .true.
        reached(child) = .true.
        count = count + 1
        order(count) = child
        parent(child) = par
        tjoint(child) = k
        kind(child) = kd
        ndof = ndof + dofs_of_kind(kd)
        grew = .true.
      end do
    end do
    stat = MBDK_ERR_NOT_APPLICABLE
    if (count < nb .or. ndof == 0) return
    stat = MBDK_SUCCESS
  end subroutine mbdk_joint_tree

  !> The tree (mbdk_joint_tree) into jm: its first dof per body and which dofs turn; used(k)
  !> for the tree's joints.
  subroutine grow_tree(jm, jtype, jbody, used, stat, asked)
    type(mbdk_joint_model_t), intent(inout) :: jm
    integer, intent(in) :: jtype(:), jbody(:, :)
    logical, intent(out) :: used(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: i, k, b
    call mbdk_joint_tree(jm%nb, jtype, jbody, jm%tjoint, jm%kind, jm%parent, jm%order, &
                         jm%ndof, stat)
    if (stat /= MBDK_SUCCESS) return
    used = .false.
    used(jm%tjoint) = .true.
    allocate (jm%turn(jm%ndof), stat=k)
    call mbdk_alloc_status(k, 4.0_dp * jm%ndof, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    k = 1
    jm%nc = 0
    do i = 1, jm%nb
      b = jm%order(i)
      jm%dof(b) = k
      jm%qoff(b) = jm%nc + 1
      select case (jm%kind(b))
      case (MBDK_TREE_TURN)
        jm%turn(k) = .true.
      case (MBDK_TREE_SLIDE)
        jm%turn(k) = .false.
      case (MBDK_TREE_CYLINDER)
        jm%turn(k) = .true.
        jm%turn(k + 1) = .false.
      case (MBDK_TREE_BALL)
        jm%turn(k:k + 2) = .true.
      end select
      k = k + ndof_of(jm, b)
      jm%nc = jm%nc + merge(4, ndof_of(jm, b), jm%kind(b) == MBDK_TREE_BALL)
    end do
  end subroutine grow_tree

  !> MBDK_ERR_INCONSISTENT_INITIAL where a tree joint's rows of the full model (in table
  !> order, each joint's in turn) at the start exceed MBDK_JOINT_START_RTOL (rows of lengths at
  !> the length scale): the tree is built from the start's pose.
  subroutine start_on_tree(full, jtype, used, t0, y0, stat, asked)
    type(mbdk_spatial_model_t), intent(in) :: full
    integer, intent(in) :: jtype(:)
    logical, intent(in) :: used(:)
    real(dp), intent(in) :: t0, y0(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    type(frames_t) :: fr
    real(dp), allocatable :: phi(:), c(:, :), gam(:)
    integer :: k, r, i, nr, astat
    call frames(full, y0, fr, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    allocate (phi(full%m), c(full%m, 6 * full%nb), gam(full%m), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * full%m * (6.0_dp * full%nb + 2.0_dp), &
                           stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call constraints(full, fr, t0, phi, c, gam)
    stat = MBDK_ERR_INCONSISTENT_INITIAL
    r = 0
    do k = 1, size(jtype)
      nr = mbdk_joint_rows(jtype(k), MBDK_BODY_SPATIAL)
      if (used(k)) then
        do i = r + 1, r + nr
          if (.not. (abs(phi(i)) <= MBDK_JOINT_START_RTOL * &
                     merge(1.0_dp, full%length, full%row_angular(i)))) return
        end do
      end if
      r = r + nr
    end do
    stat = MBDK_SUCCESS
  end subroutine start_on_tree

  !> Each tree joint's axis and point on its parent (the table's on the parent's side), the
  !> child's centre and orientation relative to the parent at y0.
  subroutine take_references(jm, jbody, jreal, y0, stat)
    type(mbdk_joint_model_t), intent(inout) :: jm
    integer, intent(in) :: jbody(:, :)
    real(dp), intent(in) :: jreal(:, :), y0(:)
    integer, intent(out) :: stat
    real(dp) :: rp(3), rotp(3, 3), qp(4), rc(3), rotc(3, 3), qc(4), a(3)
    integer :: b, p, k
    stat = MBDK_ERR_INVALID_INPUT
    do b = 1, jm%nb
      p = jm%parent(b)
      k = jm%tjoint(b)
      call pose0(p, rp, rotp, qp)
      call pose0(b, rc, rotc, qc)
      if (jbody(2, k) == p) then
        jm%spt(:, b) = jreal(4:6, k)
        a = jreal(10:12, k)
      else
        jm%spt(:, b) = jreal(1:3, k)
        a = jreal(7:9, k)
      end if
      ! a fixed joint has no axis; the others' are checked non-zero by the model's init
      jm%axis(:, b) = 0.0_dp
      if (jm%kind(b) /= MBDK_TREE_FIXED .and. jm%kind(b) /= MBDK_TREE_BALL) then
        if (.not. (norm2(a) > 0.0_dp)) return
        jm%axis(:, b) = a / norm2(a)
      end if
      jm%e0(:, b) = qmul(mbdk_quat_conj(qp), qc)
      jm%ae0(:, b) = qmul([0.0_dp, jm%axis(:, b)], jm%e0(:, b))
      jm%c0(:, b) = rtmul(rotp, rc - rp)
      jm%dch(:, b) = rtmul(rotc, rc - (rp + rmul(rotp, jm%spt(:, b))))
    end do
    stat = MBDK_SUCCESS
  contains
    subroutine pose0(b, r, rot, q)
      integer, intent(in) :: b
      real(dp), intent(out) :: r(3), rot(3, 3), q(4)
      integer :: o
      if (b == 0) then
        r = 0.0_dp
        q = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]
      else
        o = (b - 1) * 7
        r = y0(o + 1:o + 3)
        q = y0(o + 4:o + 7) / norm2(y0(o + 4:o + 7))
      end if
      rot = mbdk_quat_matrix_of(q)
    end subroutine pose0
  end subroutine take_references

  !> The dofs that move each body, root first (pptr, pdof).
  subroutine paths(jm, stat, asked)
    type(mbdk_joint_model_t), intent(inout) :: jm
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: b, a, n, astat, k
    jm%pptr(1) = 1
    do b = 1, jm%nb
      n = 0
      a = b
      do while (a > 0)
        n = n + ndof_of(jm, a)
        a = jm%parent(a)
      end do
      jm%pptr(b + 1) = jm%pptr(b) + n
    end do
    allocate (jm%pdof(jm%pptr(jm%nb + 1) - 1), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * real(size(jm%pdof), dp), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    do b = 1, jm%nb
      n = jm%pptr(b + 1)
      a = b
      do while (a > 0)
        do k = ndof_of(jm, a) - 1, 0, -1
          n = n - 1
          jm%pdof(n) = jm%dof(a) + k
        end do
        a = jm%parent(a)
      end do
    end do
  end subroutine paths

  pure integer function ndof_of(jm, b)
    type(mbdk_joint_model_t), intent(in) :: jm
    integer, intent(in) :: b
    ndof_of = dofs_of_kind(jm%kind(b))
  end function ndof_of

  !> the rates a tree joint of kind kd gives its body
  pure integer function dofs_of_kind(kd)
    integer, intent(in) :: kd
    select case (kd)
    case (MBDK_TREE_CYLINDER)
      dofs_of_kind = 2
    case (MBDK_TREE_FIXED)
      dofs_of_kind = 0
    case (MBDK_TREE_BALL)
      dofs_of_kind = 3
    case default
      dofs_of_kind = 1
    end select
  end function dofs_of_kind

  !> The work arrays, sized once; the frames by the full model's frames at its start y0, which
  !> sizes them and sets the ground's (kinematics reads it as the root's parent).
  subroutine scratch(jm, w, y0, stat, asked)
    type(mbdk_joint_model_t), intent(in) :: jm
    type(mbdk_joint_work_t), intent(inout) :: w
    real(dp), intent(in) :: y0(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nb, nd, mc, np, astat
    nb = jm%nb
    nd = jm%ndof
    mc = jm%mc
    np = size(jm%pdof)
    allocate (w%quat(4, 0:nb), w%omw(3, 0:nb), w%a0(3, 0:nb), w%al0(3, 0:nb), w%u(3, nd), &
              w%pt(3, nd), w%lin(3, np), w%ang(3, np), w%mq(nd, nd), w%dinv(nd), w%qv(nd), &
              w%fw(3, nb), &
              w%nbd(3, nb), w%phi(mc), w%c(mc, 6 * nb), w%gam(mc), w%phit(mc), w%g(mc, nd), &
              w%yg(nd, mc), w%s(mc, mc), w%lam(mc), w%sdiag(mc), w%gs(mc, nd), w%gg(mc, mc), &
              w%yabs(13 * nb), &
              w%yabs3(13 * nb, 3), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (13.0_dp * (nb + 1) + 6.0_dp * nd + &
                           6.0_dp * np + nd * (nd + 2.0_dp) + 6.0_dp * nb + mc * (6.0_dp * nb + &
                           3.0_dp * nd + 2.0_dp * mc + 5.0_dp) + 52.0_dp * nb), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call frames(jm%full, y0, w%fr, stat, asked)
  end subroutine scratch

  !> The kinematics at y = [q; v] (the first nc + ndof): every body's frame (w%fr), its
  !> quaternion and angular velocity in space, each dof's axis and point, and with bias the
  !> accelerations at theta'' = 0 (w%a0, w%al0). The work is done by kinematics_of on
  !> explicit-shape arrays, as are columns' and project_mass': the compiler then knows that
  !> they do not alias, and reloads no descriptor of an allocatable component in the loops.
  pure subroutine kinematics(jm, y, w, bias)
    type(mbdk_joint_model_t), intent(in) :: jm
    real(dp), intent(in) :: y(:)
    type(mbdk_joint_work_t), intent(inout) :: w
    logical, intent(in) :: bias
    call kinematics_of(jm%nb, jm%nc, jm%ndof, jm%order, jm%parent, jm%kind, jm%dof, jm%qoff, &
                       jm%axis, jm%spt, jm%c0, jm%dch, jm%e0, jm%ae0, y, bias, w%quat, w%fr%r, &
                       w%fr%rot, w%fr%v, w%fr%om, w%omw, w%a0, w%al0, w%u, w%pt)
  end subroutine kinematics

  pure subroutine kinematics_of(nb, nc, nd, order, parent, kind, dof, qoff, axis, spt, c0, dch, &
                                e0, ae0, y, bias, quat, r, rot, v, om, omw, a0, al0, u, pt)
    integer, intent(in) :: nb, nc, nd, order(nb), parent(nb), kind(nb), dof(nb), qoff(nb)
    real(dp), intent(in) :: axis(3, nb), spt(3, nb), c0(3, nb), dch(3, nb), e0(4, nb), &
      ae0(4, nb), y(nc + nd)
    logical, intent(in) :: bias
    real(dp), intent(inout) :: quat(4, 0:nb), r(3, 0:nb), rot(3, 3, 0:nb), v(3, 0:nb), &
      om(3, 0:nb), omw(3, 0:nb), a0(3, 0:nb), al0(3, 0:nb), u(3, nd), pt(3, nd)
    real(dp) :: rp(3), vp(3), wp(3), ub(3), pnt(3), rb(3), rho(3), del(3), vb(3), wb(3), &
      pdot(3), wu(3), h(4), th, thd, sl, sld, ap(3), alp(3), sw(3)
    integer :: i, b, p, k, c
    quat(:, 0) = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]
    omw(:, 0) = 0.0_dp
    a0(:, 0) = 0.0_dp
    al0(:, 0) = 0.0_dp
    do i = 1, nb
      b = order(i)
      p = parent(b)
      k = dof(b)
      c = qoff(b)
      rp = r(:, p)
      vp = v(:, p)
      wp = omw(:, p)
      ap = a0(:, p)
      alp = al0(:, p)
      ub = rmul(rot(:, :, p), axis(:, b))
      wu = cross(wp, ub)
      select case (kind(b))
      case (MBDK_TREE_TURN, MBDK_TREE_CYLINDER)
        th = y(c)
        thd = y(nc + k)
        sl = 0.0_dp
        sld = 0.0_dp
        if (kind(b) == MBDK_TREE_CYLINDER) then
          sl = y(c + 1)
          sld = y(nc + k + 1)
          u(:, k + 1) = ub
        end if
        h = cos(0.5_dp * th) * e0(:, b) + sin(0.5_dp * th) * ae0(:, b)
        quat(:, b) = qmul(quat(:, p), h)
        rot(:, :, b) = qmat(quat(:, b))
        pnt = rp + rmul(rot(:, :, p), spt(:, b)) + sl * ub
        rb = pnt + rmul(rot(:, :, b), dch(:, b))
        rho = rb - rp
        del = rb - pnt
        wb = wp + thd * ub
        vb = vp + cross(wp, rho) + thd * cross(ub, del) + sld * ub
        u(:, k) = ub
        pt(:, k) = pnt
        if (bias) then
          pdot = vp + cross(wp, pnt - rp) + sld * ub
          al0(:, b) = alp + thd * wu
          a0(:, b) = ap + cross(alp, rho) + cross(wp, vb - vp) + &
            thd * (cross(wu, del) + cross(ub, vb - pdot)) + sld * wu
        end if
      case (MBDK_TREE_BALL)
        ! the turn p / |p| after the initial relative orientation; Omega (body frame) the
        ! rates: omega = omega_p + R Omega, whose derivative at Omega' = 0 is omega_p x omega
        h = y(c:c + 3) / norm2(y(c:c + 3))
        quat(:, b) = qmul(quat(:, p), qmul(e0(:, b), h))
        rot(:, :, b) = qmat(quat(:, b))
        sw = rmul(rot(:, :, p), spt(:, b))
        pnt = rp + sw
        del = rmul(rot(:, :, b), dch(:, b))
        rb = pnt + del
        wb = wp + rmul(rot(:, :, b), y(nc + k:nc + k + 2))
        pdot = cross(wb, del)
        vb = vp + cross(wp, sw) + pdot
        u(:, k:k + 2) = rot(:, :, b)
        pt(:, k) = pnt
        pt(:, k + 1) = pnt
        pt(:, k + 2) = pnt
        if (bias) then
          al0(:, b) = alp + cross(wp, wb)
          a0(:, b) = ap + cross(alp, sw) + cross(wp, cross(wp, sw)) + cross(al0(:, b), del) + &
            cross(wb, pdot)
        end if
      case default   ! a slide, or fixed (no dof: sl = sld = 0)
        sl = 0.0_dp
        sld = 0.0_dp
        if (kind(b) == MBDK_TREE_SLIDE) then
          sl = y(c)
          sld = y(nc + k)
          u(:, k) = ub
          pt(:, k) = rp
        end if
        quat(:, b) = qmul(quat(:, p), e0(:, b))
        rot(:, :, b) = qmat(quat(:, b))
        rb = rp + rmul(rot(:, :, p), c0(:, b)) + sl * ub
        rho = rb - rp
        wb = wp
        vb = vp + cross(wp, rho) + sld * ub
        if (bias) then
          al0(:, b) = alp
          a0(:, b) = ap + cross(alp, rho) + cross(wp, vb - vp) + sld * wu
        end if
      end select
      r(:, b) = rb
      v(:, b) = vb
      omw(:, b) = wb
      om(:, b) = rtmul(rot(:, :, b), wb)
    end do
  end subroutine kinematics_of

  !> J's columns on each body: per (body, dof) pair, the body's translation (space) and
  !> rotation (body frame) for a unit rate of the dof.
  pure subroutine columns(jm, w)
    type(mbdk_joint_model_t), intent(in) :: jm
    type(mbdk_joint_work_t), intent(inout) :: w
    call columns_of(jm%nb, jm%ndof, size(jm%pdof), jm%pptr, jm%pdof, jm%turn, w%u, w%pt, &
                    w%fr%r, w%fr%rot, w%lin, w%ang)
  end subroutine columns

  pure subroutine columns_of(nb, nd, np, pptr, pdof, turn, u, pt, r, rot, lin, ang)
    integer, intent(in) :: nb, nd, np, pptr(nb + 1), pdof(np)
    logical, intent(in) :: turn(nd)
    real(dp), intent(in) :: u(3, nd), pt(3, nd), r(3, 0:nb), rot(3, 3, 0:nb)
    real(dp), intent(out) :: lin(3, np), ang(3, np)
    integer :: b, p, k
    do b = 1, nb
      do p = pptr(b), pptr(b + 1) - 1
        k = pdof(p)
        if (turn(k)) then
          lin(:, p) = cross(u(:, k), r(:, b) - pt(:, k))
          ang(:, p) = rtmul(rot(:, :, b), u(:, k))
        else
          lin(:, p) = u(:, k)
          ang(:, p) = 0.0_dp
        end if
      end do
    end do
  end subroutine columns_of

  !> J^T M J into w%mq (its lower triangle) and J^T (e, n) into w%qv, e and n per body a force
  !> in space and a moment in the body frame.
  pure subroutine project_mass(jm, w, e, n)
    type(mbdk_joint_model_t), intent(in) :: jm
    type(mbdk_joint_work_t), intent(inout) :: w
    real(dp), intent(in) :: e(:, :), n(:, :)
    call project_of(jm%nb, jm%ndof, size(jm%pdof), jm%pptr, jm%pdof, jm%mass, jm%inertia, &
                    w%lin, w%ang, e, n, w%mq, w%qv)
  end subroutine project_mass

  pure subroutine project_of(nb, nd, np, pptr, pdof, mass, inertia, lin, ang, e, n, mq, qv)
    integer, intent(in) :: nb, nd, np, pptr(nb + 1), pdof(np)
    real(dp), intent(in) :: mass(nb), inertia(3, 3, nb), lin(3, np), ang(3, np), e(3, nb), &
      n(3, nb)
    real(dp), intent(out) :: mq(nd, nd), qv(nd)
    real(dp) :: jl(3), ml(3)
    integer :: b, p1, p2, k1, k2
    mq = 0.0_dp
    qv = 0.0_dp
    do b = 1, nb
      do p2 = pptr(b), pptr(b + 1) - 1
        k2 = pdof(p2)
        jl = rmul(inertia(:, :, b), ang(:, p2))
        ml = mass(b) * lin(:, p2)
        qv(k2) = qv(k2) + lin(1, p2) * e(1, b) + lin(2, p2) * e(2, b) + &
          lin(3, p2) * e(3, b) + ang(1, p2) * n(1, b) + ang(2, p2) * n(2, b) + &
          ang(3, p2) * n(3, b)
        ! the path is root first, so k1 <= k2 below: the lower triangle is (k2, k1)
        do p1 = pptr(b), p2
          k1 = pdof(p1)
          mq(k2, k1) = mq(k2, k1) + lin(1, p1) * ml(1) + lin(2, p1) * ml(2) + &
            lin(3, p1) * ml(3) + ang(1, p1) * jl(1) + ang(2, p1) * jl(2) + ang(3, p1) * jl(3)
        end do
      end do
    end do
  end subroutine project_of

  !> y' = F(t, y): theta'' from the projected equations and the cut rows kept.
  subroutine joint_rhs(self, t, y, f, stat)
    class(mbdk_joint_model_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    real(dp), intent(out), contiguous :: f(:)
    integer, intent(out) :: stat
    real(dp) :: vg, vs, power
    integer :: nd, nc, i
    logical :: look
    nd = self%ndof
    nc = self%nc
    f = 0.0_dp
    stat = MBDK_ERR_NONFINITE
    if (.not. all(abs(y(1:nc + nd)) <= huge(1.0_dp))) return
    associate (w => self%work)
      call kinematics(self, y, w, .true.)
      call columns(self, w)
      call forces(self%cutm, w%fr, w%fw, w%nbd, vg, vs, power, stat)
      if (stat /= MBDK_SUCCESS) return
      call residual_loads(self%nb, self%mass, self%inertia, w%fr%rot, w%fr%om, w%a0, w%al0, &
                          w%fw, w%nbd)
      call project_mass(self, w, w%fw, w%nbd)
      call mbdk_chol_factor(w%mq, stat)
      if (stat /= MBDK_SUCCESS) return
      do i = 1, nd
        w%dinv(i) = 1.0_dp / w%mq(i, i)
      end do
      call forward(nd, w%mq, w%dinv, w%qv)
      if (self%nact > 0) then
        call cut_rows(self, t, w)
        call close_loops(nd, self%nact, self%formulation == MBDK_FORM_REDUCED, w%mq, w%dinv, &
                         w%g, w%gam, w%yg, w%s, w%sdiag, w%lam, w%qv, look, stat)
        if (stat /= MBDK_SUCCESS) return
        stat = MBDK_ERR_SINGULAR_MATRIX
        if (look) then
          if (near_geometry(self, w)) return
        end if
      end if
      call backward(nd, w%mq, w%dinv, w%qv)
      call coordinate_rates(self, y, f)
      f(nc + 1:nc + nd) = w%qv
    end associate
    stat = MBDK_ERR_NONFINITE
    if (.not. all(abs(f) <= huge(1.0_dp))) return
    stat = MBDK_SUCCESS
  end subroutine joint_rhs

  !> q' of the coordinates at y = [q; v]: a turn's and a slide's their rate, a spherical
  !> joint's p' = p (0, Omega) / 2 + k (1 - |p|^2) p / 2 (k = norm_gain).
  pure subroutine coordinate_rates(jm, y, f)
    type(mbdk_joint_model_t), intent(in) :: jm
    real(dp), intent(in) :: y(:)
    real(dp), intent(inout) :: f(:)
    integer :: b, c, k, n
    real(dp) :: p(4)
    do b = 1, jm%nb
      c = jm%qoff(b)
      k = jm%nc + jm%dof(b)
      n = ndof_of(jm, b)
      if (jm%kind(b) == MBDK_TREE_BALL) then
        p = y(c:c + 3)
        f(c:c + 3) = 0.5_dp * qmul(p, [0.0_dp, y(k:k + 2)]) + &
          0.5_dp * jm%norm_gain * (1.0_dp - dot_product(p, p)) * p
      else
        f(c:c + n - 1) = y(k:k + n - 1)
      end if
    end do
  end subroutine coordinate_rates

  !> The loads left at theta'' = 0, f - M b per body: fw (space) less m a0, nbd (body frame)
  !> less the gyroscopic moment Omega x J Omega and J R^T alpha0.
  pure subroutine residual_loads(nb, mass, inertia, rot, om, a0, al0, fw, nbd)
    integer, intent(in) :: nb
    real(dp), intent(in) :: mass(nb), inertia(3, 3, nb), rot(3, 3, 0:nb), om(3, 0:nb), &
      a0(3, 0:nb), al0(3, 0:nb)
    real(dp), intent(inout) :: fw(3, nb), nbd(3, nb)
    integer :: b
    do b = 1, nb
      fw(:, b) = fw(:, b) - mass(b) * a0(:, b)
      nbd(:, b) = nbd(:, b) - cross(om(:, b), rmul(inertia(:, :, b), om(:, b))) - &
        rmul(inertia(:, :, b), rtmul(rot(:, :, b), al0(:, b)))
    end do
  end subroutine residual_loads

  !> The closed loops' part of theta'': with M = J^T M J = L L^T (L in mq, dinv its
  !> diagonal's reciprocals) and qv = L^-1 Q on entry, Z = L^-1 G^T on the nact rows kept,
  !> S = Z^T Z, lambda from S lambda = Z^T qv - gamma', and qv = L^-1 Q - Z lambda on return
  !> (theta'' = L^-T qv, the caller's backward substitution). A pivot of S at roundoff is
  !> MBDK_ERR_SINGULAR_MATRIX; look: on the reduced formulation (near), a pivot below
  !> MBDK_SPATIAL_NEAR_PIVOT of its row's diagonal, for the caller's test on the geometry
  !> (near_geometry: S's pivots weigh the rows by the masses, small at a regular pose where a
  !> body is light or slender).
  subroutine close_loops(nd, na, near, mq, dinv, g, gam, z, s, sdiag, lam, qv, look, stat)
    integer, intent(in) :: nd, na
    logical, intent(in) :: near
    real(dp), intent(in) :: mq(nd, nd), dinv(nd), g(:, :), gam(:)
    real(dp), intent(inout) :: z(nd, na), s(na, na), sdiag(na), lam(na), qv(nd)
    logical, intent(out) :: look
    integer, intent(out) :: stat
    integer :: i, k
    do i = 1, na
      z(:, i) = g(i, 1:nd)
      call forward(nd, mq, dinv, z(:, i))
    end do
    look = .false.
    do i = 1, na
      do k = 1, i
        s(i, k) = dot_product(z(:, i), z(:, k))
      end do
      sdiag(i) = s(i, i)
      lam(i) = dot_product(z(:, i), qv) - gam(i)
    end do
    call mbdk_chol_factor(s, stat)
    if (stat /= MBDK_SUCCESS) then
      stat = MBDK_ERR_SINGULAR_MATRIX
      return
    end if
    look = .false.
    stat = MBDK_ERR_SINGULAR_MATRIX
    do i = 1, na
      if (.not. (s(i, i)**2 > SOLVE_RTOL * sdiag(i))) return
      if (near .and. .not. (s(i, i)**2 > MBDK_SPATIAL_NEAR_PIVOT * sdiag(i))) look = .true.
    end do
    call mbdk_chol_solve(s, lam, stat)
    if (stat /= MBDK_SUCCESS) return
    do i = 1, na
      qv = qv - lam(i) * z(:, i)
    end do
  end subroutine close_loops

  !> b <- L^-1 b and b <- L^-T b, L lower triangular (the Cholesky factor of J^T M J in its
  !> lower triangle) with dinv its diagonal's reciprocals: a solve of the projected equations
  !> takes 2 + nact of these substitutions per evaluation, and a division on their chain of
  !> dependent operations costs several multiplications' latency
  pure subroutine forward(n, l, dinv, b)
    integer, intent(in) :: n
    real(dp), intent(in) :: l(n, n), dinv(n)
    real(dp), intent(inout) :: b(n)
    integer :: k
    do k = 1, n
      b(k) = b(k) * dinv(k)
      b(k + 1:n) = b(k + 1:n) - l(k + 1:n, k) * b(k)
    end do
  end subroutine forward

  pure subroutine backward(n, l, dinv, b)
    integer, intent(in) :: n
    real(dp), intent(in) :: l(n, n), dinv(n)
    real(dp), intent(inout) :: b(n)
    integer :: k
    do k = n, 1, -1
      b(k) = (b(k) - dot_product(l(k + 1:n, k), b(k + 1:n))) * dinv(k)
    end do
  end subroutine backward

  !> The cut rows kept, at the frames and bias of w: G = C_c J into w%g(1:nact, :) and the
  !> right-hand side gamma_c - C_c b (less Baumgarte's terms) into w%gam(1:nact).
  subroutine cut_rows(jm, t, w)
    type(mbdk_joint_model_t), intent(in) :: jm
    real(dp), intent(in) :: t
    type(mbdk_joint_work_t), intent(inout) :: w
    call constraints(jm%cutm, w%fr, t, w%phi, w%c, w%gam, w%phit)
    call cut_rows_of(jm%nb, jm%ndof, size(jm%pdof), jm%mc, jm%nact, jm%active, jm%rbody, &
                     jm%pptr, jm%pdof, w%c, w%lin, w%ang, w%a0, w%al0, w%fr%rot, w%fr%v, w%fr%om, &
                     w%phi, w%phit, jm%formulation == MBDK_FORM_BAUMGARTE, jm%alpha, jm%beta, &
                     w%g, w%gam)
  end subroutine cut_rows

  pure subroutine cut_rows_of(nb, nd, np, mc, na, active, rbody, pptr, pdof, c, lin, ang, a0, &
                              al0, rot, v, om, phi, phit, baumgarte, alpha, beta, g, gam)
    integer, intent(in) :: nb, nd, np, mc, na, active(na), rbody(2, mc), pptr(nb + 1), &
      pdof(np)
    real(dp), intent(in) :: c(mc, 6 * nb), lin(3, np), ang(3, np), a0(3, 0:nb), al0(3, 0:nb), &
      rot(3, 3, 0:nb), v(3, 0:nb), om(3, 0:nb), phi(mc), phit(mc), alpha, beta
    logical, intent(in) :: baumgarte
    real(dp), intent(inout) :: g(mc, nd), gam(mc)
    real(dp) :: alb(3), cl(3), ca(3), cb, pd
    integer :: i, r, b, o, p, j
    ! row i of the rows kept goes to i <= active(i): gam(active(i)) is read before row i is
    ! written, and never after
    do i = 1, na
      r = active(i)
      g(i, :) = 0.0_dp
      cb = 0.0_dp
      pd = phit(r)
      do j = 1, 2
        b = rbody(j, r)
        if (b == 0) cycle
        o = 6 * (b - 1)
        cl = c(r, o + 1:o + 3)
        ca = c(r, o + 4:o + 6)
        do p = pptr(b), pptr(b + 1) - 1
          g(i, pdof(p)) = g(i, pdof(p)) + cl(1) * lin(1, p) + cl(2) * lin(2, p) + &
            cl(3) * lin(3, p) + ca(1) * ang(1, p) + ca(2) * ang(2, p) + ca(3) * ang(3, p)
        end do
        alb = rtmul(rot(:, :, b), al0(:, b))
        cb = cb + dot_product(cl, a0(:, b)) + dot_product(ca, alb)
        pd = pd + dot_product(cl, v(:, b)) + dot_product(ca, om(:, b))
      end do
      gam(i) = gam(r) - cb
      if (baumgarte) gam(i) = gam(i) - 2.0_dp * alpha * pd - beta**2 * phi(r)
    end do
  end subroutine cut_rows_of

  !> theta'_0: the joint rates whose motion is nearest to y0's velocities in the kinetic
  !> energy's norm (J^T M J theta' = J^T M xi0); MBDK_ERR_INCONSISTENT_INITIAL where that
  !> motion is off them by more than FIT_RTOL of the largest speed.
  subroutine fit_rates(jm, y0, y0j, stat)
    type(mbdk_joint_model_t), intent(in) :: jm
    real(dp), intent(in) :: y0(:)
    real(dp), intent(inout), target :: y0j(:)   !< its coordinates given, its rates set
    integer, intent(out) :: stat
    real(dp) :: e(3, jm%nb), n(3, jm%nb), dv(3), dw(3), off, big
    real(dp), pointer :: rates(:)
    integer :: b, o, p
    rates => y0j(jm%nc + 1:jm%nc + jm%ndof)
    rates = 0.0_dp
    associate (w => jm%work)
      call kinematics(jm, y0j, w, .false.)
      call columns(jm, w)
      do b = 1, jm%nb
        o = jm%full%ncoord + 6 * (b - 1)
        e(:, b) = jm%mass(b) * y0(o + 1:o + 3)
        n(:, b) = matmul(jm%inertia(:, :, b), y0(o + 4:o + 6))
      end do
      call project_mass(jm, w, e, n)
      call mbdk_chol_factor(w%mq, stat)
      if (stat /= MBDK_SUCCESS) return
      rates = w%qv
      call mbdk_chol_solve(w%mq, rates, stat)
      if (stat /= MBDK_SUCCESS) return
      off = 0.0_dp
      big = 0.0_dp
      do b = 1, jm%nb
        o = jm%full%ncoord + 6 * (b - 1)
        dv = y0(o + 1:o + 3)
        dw = y0(o + 4:o + 6)
        big = max(big, norm2(dv), jm%length * norm2(dw))
        do p = jm%pptr(b), jm%pptr(b + 1) - 1
          dv = dv - rates(jm%pdof(p)) * w%lin(:, p)
          dw = dw - rates(jm%pdof(p)) * w%ang(:, p)
        end do
        off = max(off, norm2(dv), jm%length * norm2(dw))
      end do
      stat = MBDK_ERR_INCONSISTENT_INITIAL
      if (.not. (off <= FIT_RTOL * max(big, jm%length))) return
      stat = MBDK_SUCCESS
    end associate
  end subroutine fit_rates

  !> The cut rows kept (jm%active): those independent in the joint coordinates at the start,
  !> by a complete-pivoting Cholesky of the geometry's Gs Gs^T (scaled_rows, each row of unit
  !> length), in the order of the table. A row with no gradient (below the square root of
  !> REDUNDANT_RTOL) is left out where a second pose of the tree (each turn 0.5 rad on, each
  !> slide a tenth of the length scale, each spherical joint turned by about 0.8 rad) leaves it
  !> none either: the tree holds it. Where it has
  !> one there, the start is a dead centre of the loop; that, and a driver's row left out
  !> (its motion would be lost), is MBDK_ERR_SINGULAR_MATRIX.
  subroutine choose_cut_rows(jm, t0, y0j, stat, asked)
    type(mbdk_joint_model_t), intent(inout) :: jm
    real(dp), intent(in) :: t0, y0j(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    real(dp), allocatable :: gs(:, :), g2(:, :), gg(:, :), y2(:)
    integer, allocatable :: piv(:), cand(:)
    integer :: i, k, rank, astat, mc, nc, nd
    real(dp) :: nr
    mc = jm%mc
    nd = jm%ndof
    stat = MBDK_SUCCESS
    jm%nact = 0
    allocate (jm%active(mc), gs(mc, nd), g2(mc, nd), gg(mc, mc), y2(size(y0j)), piv(mc), &
              cand(mc), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (mc * (2.0_dp * nd + mc + 2.0_dp) + &
                           size(y0j)), stat, asked)
    if (stat /= MBDK_SUCCESS .or. mc == 0) return
    ! every row, in the order of the table, to take G at the start and at a second pose
    jm%active = [(i, i = 1, mc)]
    jm%nact = mc
    call scaled_rows(jm, t0, y0j, gs)
    y2 = y0j
    do i = 1, jm%nb
      k = jm%qoff(i)
      select case (jm%kind(i))
      case (MBDK_TREE_TURN)
        y2(k) = y2(k) + 0.5_dp
      case (MBDK_TREE_SLIDE)
        y2(k) = y2(k) + 0.1_dp * jm%length
      case (MBDK_TREE_CYLINDER)
        y2(k:k + 1) = y2(k:k + 1) + [0.5_dp, 0.1_dp * jm%length]
      case (MBDK_TREE_BALL)
        y2(k:k + 3) = [0.9_dp, 0.3_dp, -0.2_dp, 0.25_dp]
      end select
    end do
    call scaled_rows(jm, t0, y2, g2)
    nc = 0
    stat = MBDK_ERR_SINGULAR_MATRIX
    do i = 1, mc
      nr = norm2(gs(i, :))
      if (.not. (nr > sqrt(REDUNDANT_RTOL))) then
        if (norm2(g2(i, :)) > sqrt(REDUNDANT_RTOL) .or. jm%driver(i)) return
        cycle
      end if
      nc = nc + 1
      cand(nc) = i
      gs(nc, :) = gs(i, :) / nr
    end do
    stat = MBDK_SUCCESS
    jm%nact = 0
    if (nc > 0) then
      gg(1:nc, 1:nc) = matmul(gs(1:nc, :), transpose(gs(1:nc, :)))
      call mbdk_chol_pivoted(gg(1:nc, 1:nc), piv(1:nc), rank, REDUNDANT_RTOL, stat)
      if (stat /= MBDK_SUCCESS) return
      jm%nact = rank
      jm%active(1:rank) = cand(piv(1:rank))
      call mbdk_sort_ints(jm%active(1:rank))
    end if
    stat = MBDK_ERR_SINGULAR_MATRIX
    do i = 1, mc
      if (jm%driver(i) .and. .not. any(jm%active(1:jm%nact) == i)) return
    end do
    rank = jm%nact
    deallocate (jm%work%s, jm%work%lam, jm%work%sdiag, jm%work%gs, jm%work%gg)
    allocate (jm%work%s(rank, rank), jm%work%lam(rank), jm%work%sdiag(rank), &
              jm%work%gs(rank, nd), jm%work%gg(rank, rank), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * rank * (2.0_dp * rank + nd + 2.0_dp), &
                           stat, asked)
  end subroutine choose_cut_rows

  !> The rows kept (all, while choose_cut_rows looks at them) of G at (t, y), scaled to the
  !> geometry: a slide's column times the length scale (a length per length), a row of
  !> lengths over it (radians per radian).
  subroutine scaled_rows(jm, t, y, gs)
    type(mbdk_joint_model_t), intent(in) :: jm
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: gs(:, :)
    integer :: i, k
    call kinematics(jm, y, jm%work, .true.)
    call columns(jm, jm%work)
    call cut_rows(jm, t, jm%work)
    do i = 1, jm%nact
      gs(i, :) = jm%work%g(i, :)
      if (.not. jm%cutm%row_angular(jm%active(i))) gs(i, :) = gs(i, :) / jm%length
    end do
    do k = 1, jm%ndof
      if (.not. jm%turn(k)) gs(1:jm%nact, k) = gs(1:jm%nact, k) * jm%length
    end do
  end subroutine scaled_rows

  !> The reduced form's near test of a rank loss on the geometry, where a pivot of S fell
  !> into the window: the relative pivots of Gs Gs^T on the rows kept (w%g at the last
  !> evaluation, scaled as scaled_rows scales them, each row of unit length), below
  !> MBDK_SPATIAL_NEAR_PIVOT at a pose next to a rank loss.
  logical function near_geometry(jm, w) result(near)
    type(mbdk_joint_model_t), intent(in) :: jm
    type(mbdk_joint_work_t), intent(inout) :: w
    integer :: i, k, stat
    real(dp) :: nr
    near = .true.
    do i = 1, jm%nact
      w%gs(i, :) = w%g(i, :)
      if (.not. jm%cutm%row_angular(jm%active(i))) w%gs(i, :) = w%gs(i, :) / jm%length
      do k = 1, jm%ndof
        if (.not. jm%turn(k)) w%gs(i, k) = w%gs(i, k) * jm%length
      end do
      nr = norm2(w%gs(i, :))
      if (.not. (nr > 0.0_dp)) return
      w%gs(i, :) = w%gs(i, :) / nr
    end do
    do i = 1, jm%nact
      do k = 1, i
        w%gg(i, k) = dot_product(w%gs(i, :), w%gs(k, :))
      end do
    end do
    call mbdk_chol_factor(w%gg, stat)
    if (stat /= MBDK_SUCCESS) return
    do i = 1, jm%nact
      if (.not. (w%gg(i, i)**2 > MBDK_SPATIAL_NEAR_PIVOT)) return
    end do
    near = .false.
  end function near_geometry

  ! x × y, the quaternion product and a unit quaternion's rotation matrix, as mbdk_rotations'
  ! (mbdk_cross, mbdk_quat_mul, mbdk_quat_matrix_of): a function of another module is never
  ! inlined, and these are most of the kinematics' arithmetic (the spatial model keeps its own
  ! cross for the same reason)
  pure function cross(x, y) result(z)
    real(dp), intent(in) :: x(3), y(3)
    real(dp) :: z(3)
    z(1) = x(2) * y(3) - x(3) * y(2)
    z(2) = x(3) * y(1) - x(1) * y(3)
    z(3) = x(1) * y(2) - x(2) * y(1)
  end function cross

  !> R x and R^T x, written out (as the spatial model's rmul and rtmul)
  pure function rmul(r, x) result(y)
    real(dp), intent(in) :: r(3, 3), x(3)
    real(dp) :: y(3)
    y = r(:, 1) * x(1) + r(:, 2) * x(2) + r(:, 3) * x(3)
  end function rmul

  pure function rtmul(r, x) result(y)
    real(dp), intent(in) :: r(3, 3), x(3)
    real(dp) :: y(3)
    y(1) = r(1, 1) * x(1) + r(2, 1) * x(2) + r(3, 1) * x(3)
    y(2) = r(1, 2) * x(1) + r(2, 2) * x(2) + r(3, 2) * x(3)
    y(3) = r(1, 3) * x(1) + r(2, 3) * x(2) + r(3, 3) * x(3)
  end function rtmul

  pure function qmul(p, q) result(r)
    real(dp), intent(in) :: p(4), q(4)
    real(dp) :: r(4)
    r(1) = p(1) * q(1) - p(2) * q(2) - p(3) * q(3) - p(4) * q(4)
    r(2:4) = p(1) * q(2:4) + q(1) * p(2:4) + cross(p(2:4), q(2:4))
  end function qmul

  pure function qmat(q) result(r)
    real(dp), intent(in) :: q(4)
    real(dp) :: r(3, 3)
    real(dp) :: d
    d = q(1)**2 - q(2)**2 - q(3)**2 - q(4)**2
    r(1, 1) = d + 2.0_dp * q(2)**2
    r(2, 2) = d + 2.0_dp * q(3)**2
    r(3, 3) = d + 2.0_dp * q(4)**2
    r(1, 2) = 2.0_dp * (q(2) * q(3) - q(1) * q(4))
    r(2, 1) = 2.0_dp * (q(2) * q(3) + q(1) * q(4))
    r(1, 3) = 2.0_dp * (q(2) * q(4) + q(1) * q(3))
    r(3, 1) = 2.0_dp * (q(2) * q(4) - q(1) * q(3))
    r(2, 3) = 2.0_dp * (q(3) * q(4) - q(1) * q(2))
    r(3, 2) = 2.0_dp * (q(3) * q(4) + q(1) * q(2))
  end function qmat

  !> The absolute state [q; w] of the full model (quaternions) at the joint state y.
  subroutine mbdk_joint_to_absolute(jm, y, yabs)
    type(mbdk_joint_model_t), intent(in) :: jm
    real(dp), intent(in) :: y(:)
    real(dp), intent(out) :: yabs(:)
    integer :: b, o
    call kinematics(jm, y, jm%work, .false.)
    do b = 1, jm%nb
      o = 7 * (b - 1)
      yabs(o + 1:o + 3) = jm%work%fr%r(:, b)
      yabs(o + 4:o + 7) = jm%work%quat(:, b)
      o = jm%full%ncoord + 6 * (b - 1)
      yabs(o + 1:o + 3) = jm%work%fr%v(:, b)
      yabs(o + 4:o + 6) = jm%work%fr%om(:, b)
    end do
  end subroutine mbdk_joint_to_absolute

  ! ---- the full model's watch and events, at the absolute state ---------------------------

  subroutine joint_watch_start(self, t, y, stat)
    class(mbdk_joint_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    integer, intent(out) :: stat
    call mbdk_joint_to_absolute(self, y, self%work%yabs)
    call self%full%watch_start(t, self%work%yabs, stat)
  end subroutine joint_watch_start

  subroutine joint_watch(self, t, y, force, stat)
    class(mbdk_joint_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    call mbdk_joint_to_absolute(self, y, self%work%yabs)
    call self%full%watch(t, self%work%yabs, force, stat)
  end subroutine joint_watch

  logical function joint_wants_nodes(self)
    class(mbdk_joint_model_t), intent(in) :: self
    joint_wants_nodes = self%full%watch_wants_nodes()
  end function joint_wants_nodes

  subroutine joint_watch_nodes(self, t_a, t_b, y, stat)
    class(mbdk_joint_model_t), intent(in) :: self
    real(dp), intent(in) :: t_a, t_b, y(:, :)
    integer, intent(out) :: stat
    integer :: k
    do k = 1, 3
      call mbdk_joint_to_absolute(self, y(:, k), self%work%yabs3(:, k))
    end do
    call self%full%watch_nodes(t_a, t_b, self%work%yabs3, stat)
  end subroutine joint_watch_nodes

  subroutine joint_events(self, t, y, g, stat)
    class(mbdk_joint_model_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: g(:)
    integer, intent(out) :: stat
    call mbdk_joint_to_absolute(self, y, self%work%yabs)
    call self%full%events(t, self%work%yabs, g, stat)
  end subroutine joint_events

end module mbdk_joint_coords
