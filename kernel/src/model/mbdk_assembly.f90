!> A scene's initial state: the values its tables take from the initial pose, and initial
!> conditions that satisfy the constraints.
!>
!> Pose defaults. An element may take a value from the initial pose instead of the table: a
!> spring, damper or spring-damper its rest length (freal(6) = the distance of its points),
!> a prismatic or fixed joint its relative angle (jreal(7) = theta1 - theta2), a distance joint
!> its length L(0), a coupling its offset c(0) and a rolling disc its roll offset c0, when the
!> 4th integer of its table entry is MBDK_FROM_POSE (that slot is the coordinate of drivers and
!> coordinate forces, and unused otherwise). mbdk_tables_resolve fills them in at q; a
!> two-point force whose points coincide there has no direction: MBDK_ERR_INVALID_INPUT with the
!> force named (bad_force).
!>
!> Assembly (mbdk_assembly_run). The coordinates the scene does not mark as given move as little
!> as possible: Gauss-Newton on Phi(q, t0) = 0, each correction the minimum-norm least-squares
!> solution of D_free dq = -Phi (D_f^T (D_f D_f^T)^-1 by an in-house LDL^T where the rows are
!> few and independent; else mbdk_least_squares, so redundant constraints are no obstacle:
!> both the same bits on every CPU up to MBDK_FIXED_ORDER_MAX rows and columns), until
!> max |Phi| <= tol (or Phi's roundoff at q, mbdk_phi_floor, where that is larger); then the
!> velocities not given, v_free = least-squares solution of D_free v_free = -Phi_t - D_given
!> v_given. A knife edge's row constrains velocities only: the positions' corrections leave it
!> out (a zero row of the dense D; a scene with knife edges assembles by the dense least
!> squares where D is affordable), the velocities' keep it. A model on the sparse path (more than
!> MBDK_SPARSE_MIN_ROWS rows) takes the same least change through the sparse Schur complement of
!> the free columns, D_f D_f^T (mbdk_constrained), in O(nnz); where the free columns are
!> dependent (redundant joints) it falls back to the dense least squares while D has at most
!> 10^7 entries, and stops with MBDK_ERR_SINGULAR_MATRIX beyond. Either residual above 1e-9 at
!> the end:
!> MBDK_ERR_INCONSISTENT_INITIAL, with the residual rows returned so that the caller can name the
!> joints.
module mbdk_assembly
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_lapack, only: mbdk_least_squares
  use mbdk_small_dense, only: mbdk_small_ldlt_solve_once, MBDK_SMALL_DENSE_MAX
  use mbdk_joints, only: mbdk_body_point, MBDK_JOINT_PRISMATIC, &
    MBDK_JOINT_FIXED, MBDK_JOINT_DISTANCE, MBDK_JOINT_COUPLING, MBDK_JOINT_ROLLING
  use mbdk_force_elements, only: MBDK_FORCE_SPRING_DAMPER, MBDK_FORCE_SPRING, MBDK_FORCE_DAMPER
  use mbdk_elements, only: mbdk_body_kind, MBDK_BODY_PLANAR, MBDK_ELEMENT_NAME_LEN
  use mbdk_model, only: mbdk_model_t, mbdk_model_constraints, mbdk_model_init, &
    mbdk_model_work_t, mbdk_model_options_t, mbdk_phi_floor
  use mbdk_joints, only: mbdk_joints_pattern, MBDK_JOINT_SLOTS
  use mbdk_sparse_schur, only: mbdk_sparse_schur_t, mbdk_sparse_schur_init, mbdk_sparse_d_times
  use mbdk_constrained, only: mbdk_constrained_t, mbdk_constrained_init, &
    mbdk_constrained_solve_once, MBDK_SOLVE_SCHUR_SPARSE, MBDK_CONSTRAINED_SINGULAR_TOL
  implicit none
  private
  public :: mbdk_tables_resolve, mbdk_assembly_run, mbdk_model_start

  !> the 4th integer of a two-point force or a prismatic, fixed, distance, coupling or rolling
  !> joint: take the value from the pose
  integer, parameter, public :: MBDK_FROM_POSE = 1
  !> residuals an assembled state must meet
  real(dp), parameter :: ASSEMBLED_TOL = 1.0e-9_dp

  !> the sparse least change of the assembly: the free columns' weight and its Schur path
  type :: minnorm_t
    real(dp), allocatable :: w(:), zero(:), ones(:), mu(:)
    type(mbdk_sparse_schur_t) :: sp
    type(mbdk_constrained_t) :: cs
  end type minnorm_t

  !> one assembly's buffers: Phi, gamma, Phi_t, the correction dx, and while the dense path
  !> is taken (sparse false) D and the least squares' a and b
  type :: assembly_t
    logical :: sparse = .false.
    real(dp), allocatable :: phi(:), gam(:), phit(:), dx(:), d(:, :), a(:, :), b(:)
  end type assembly_t

contains

  !> Fills in the pose defaults of the tables at q (nc = 3 nb coordinates). bad_joint, bad_force:
  !> the element (1-based) that made it fail, else 0. MBDK_ERR_NO_MEMORY: asked gets the bytes
  !> (mbdk_memory).
  subroutine mbdk_tables_resolve(nb, jint, jreal, fint, freal, q, bad_joint, bad_force, stat, &
                                 asked)
    integer, intent(in) :: nb
    integer, intent(in) :: jint(:, :), fint(:, :)
    real(dp), intent(inout) :: jreal(:, :), freal(:, :)
    real(dp), intent(in) :: q(:)
    integer, intent(out) :: bad_joint, bad_force, stat
    real(dp), intent(inout), optional :: asked
    real(dp), allocatable :: rot(:, :), v(:)
    real(dp) :: p1(2), p2(2), rho(2), pv(2), w, th1, th2, len
    integer :: j, b1, b2
    bad_joint = 0
    bad_force = 0
    stat = MBDK_ERR_INVALID_INPUT
    if (size(q) /= 3 * nb .or. .not. all(abs(q) <= huge(1.0_dp))) return
    allocate (rot(2, nb), v(size(q)), stat=j)
    call mbdk_alloc_status(j, MBDK_REAL_BYTES * (2.0_dp * nb + size(q)), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INVALID_INPUT
    v = 0.0_dp
    ! (mbdk_body_rotations' contiguous q would be a packed copy of the assumed-shape q here, one
    ! that gfortran takes from malloc without a check)
    do j = 1, nb
      rot(:, j) = [cos(q(3 * j)), sin(q(3 * j))]
    end do
    ! a distance joint needs a direction at the start; a marked one takes L(0) from the pose
    do j = 1, size(jint, 2)
      if (jint(1, j) /= MBDK_JOINT_DISTANCE) cycle
      if (jint(2, j) < 1) then
        bad_joint = j
        return
      end if
      len = point_distance(jint(2, j), jint(3, j), jreal(1:2, j), jreal(3:4, j))
      if (.not. (len > 0.0_dp)) then
        bad_joint = j
        return
      end if
      ! L(t) = offset + rate t + amplitude sin(omega t + phase): L(0) = len
      if (jint(4, j) == MBDK_FROM_POSE) jreal(8, j) = len - jreal(10, j) * sin(jreal(12, j))
    end do
    do j = 1, size(jint, 2)
      if (jint(4, j) /= MBDK_FROM_POSE) cycle
      if (jint(1, j) /= MBDK_JOINT_PRISMATIC .and. jint(1, j) /= MBDK_JOINT_FIXED .and. &
          jint(1, j) /= MBDK_JOINT_COUPLING .and. jint(1, j) /= MBDK_JOINT_ROLLING) cycle
      b1 = jint(2, j)
      b2 = jint(3, j)
      if (b1 < 1 .or. b1 > nb .or. b2 < 0 .or. b2 > nb) then
        bad_joint = j
        return
      end if
      select case (jint(1, j))
      case (MBDK_JOINT_COUPLING)
        ! c(0) = offset + amplitude sin(phase) = a . q1 + b . q2 at the pose
        len = dot_product(jreal(1:3, j), q(3 * b1 - 2:3 * b1))
        if (b2 > 0) len = len + dot_product(jreal(4:6, j), q(3 * b2 - 2:3 * b2))
        jreal(8, j) = len - jreal(10, j) * sin(jreal(12, j))
      case (MBDK_JOINT_ROLLING)
        ! the roll's offset c0 = u . c + R theta at the pose
        jreal(8, j) = dot_product(jreal(5:6, j), q(3 * b1 - 2:3 * b1 - 1)) + jreal(7, j) * q(3 * b1)
      case default
        th1 = q(3 * b1)
        th2 = 0.0_dp
        if (b2 > 0) th2 = q(3 * b2)
        jreal(7, j) = th1 - th2
      end select
    end do
    ! every two-point force needs a direction at the start; marked ones take their rest length
    do j = 1, size(fint, 2)
      if (fint(1, j) /= MBDK_FORCE_SPRING_DAMPER .and. fint(1, j) /= MBDK_FORCE_SPRING .and. &
          fint(1, j) /= MBDK_FORCE_DAMPER) cycle
      len = point_distance(fint(2, j), fint(3, j), freal(1:2, j), freal(3:4, j))
      if (.not. (len > 0.0_dp)) then
        bad_force = j
        return
      end if
      if (fint(4, j) == MBDK_FROM_POSE) freal(6, j) = len
    end do
    stat = MBDK_SUCCESS

  contains

    !> The distance at q between point s1 of body b1 and point s2 of body b2 (0: the ground,
    !> its points global); -1 for a body index out of range.
    real(dp) function point_distance(b1, b2, s1, s2) result(dist)
      integer, intent(in) :: b1, b2
      real(dp), intent(in) :: s1(2), s2(2)
      dist = -1.0_dp
      if (b1 < 0 .or. b1 > nb .or. b2 < 0 .or. b2 > nb) return
      call mbdk_body_point(b1, s1, rot, q, v, p1, rho, pv, w)
      call mbdk_body_point(b2, s2, rot, q, v, p2, rho, pv, w)
      dist = sqrt((p1(1) - p2(1))**2 + (p1(2) - p2(2))**2)
    end function point_distance

  end subroutine mbdk_tables_resolve

  !> Assembles (q, v) at t0 in place, moving only the coordinates whose given_q / given_v is
  !> false (see the module header). iterations: Gauss-Newton corrections taken; on failure
  !> resid(m) is the position residual Phi, or (velocity = .true.: the positions assembled) the
  !> velocity residual D v + Phi_t.
  subroutine mbdk_assembly_run(model, t0, q, v, given_q, given_v, tol, max_iter, iterations, &
                               resid, velocity, stat)
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(in) :: t0, tol
    real(dp), intent(inout) :: q(:), v(:)
    logical, intent(in) :: given_q(:), given_v(:)
    integer, intent(in) :: max_iter
    integer, intent(out) :: iterations, stat
    real(dp), intent(out) :: resid(:)
    logical, intent(out) :: velocity
    type(assembly_t) :: as
    type(minnorm_t) :: mq, mv

    iterations = 0
    resid = 0.0_dp
    velocity = .false.
    stat = MBDK_SUCCESS
    if (model%m == 0) return
    call assembly_start(model, as, stat)
    if (stat /= MBDK_SUCCESS) return
    call assemble_positions(model, as, mq, t0, q, v, given_q, tol, max_iter, iterations, stat)
    if (stat /= MBDK_SUCCESS) return
    resid = as%phi
    if (.not. (maxval(abs(as%phi)) <= mbdk_phi_floor(ASSEMBLED_TOL, q))) then
      stat = MBDK_ERR_INCONSISTENT_INITIAL
      return
    end if
    call assemble_velocities(model, as, mv, t0, q, v, given_v, resid, stat)
    if (stat /= MBDK_SUCCESS) return
    velocity = .true.
    if (.not. (maxval(abs(resid)) <= mbdk_phi_floor(ASSEMBLED_TOL, v))) then
      stat = MBDK_ERR_INCONSISTENT_INITIAL
      return
    end if
    resid = 0.0_dp
    velocity = .false.
  end subroutine mbdk_assembly_run

  !> The buffers and the path: sparse (the Schur complement of the free columns) where the
  !> model's projections are; dense least squares (passes redundant joints) where affordable.
  subroutine assembly_start(model, as, stat)
    type(mbdk_model_t), intent(in) :: model
    type(assembly_t), intent(inout) :: as
    integer, intent(out) :: stat
    integer :: m, nc, k
    m = model%m
    nc = model%nc
    as%sparse = model%work%proj%path == MBDK_SOLVE_SCHUR_SPARSE
    if (model%has_pfaffian .and. dense_affordable(model)) as%sparse = .false.
    allocate (as%phi(m), as%gam(m), as%phit(m), as%dx(nc), stat=k)
    call mbdk_alloc_status(k, MBDK_REAL_BYTES * (3.0_dp * m + nc), stat)
    if (stat /= MBDK_SUCCESS) return
    if (.not. as%sparse) then
      allocate (as%d(m, nc), stat=k)
      call mbdk_alloc_status(k, MBDK_REAL_BYTES * real(m, dp) * nc, stat)
    end if
  end subroutine assembly_start

  !> Gauss-Newton on Phi(q, t0) = 0 in the coordinates not given, up to max_iter corrections
  !> or until max |Phi| <= tol (or Phi's roundoff at q); as%phi is Phi at the q it leaves.
  subroutine assemble_positions(model, as, mn, t0, q, v, given_q, tol, max_iter, iterations, &
                                stat)
    type(mbdk_model_t), intent(in) :: model
    type(assembly_t), intent(inout) :: as
    type(minnorm_t), intent(inout) :: mn
    real(dp), intent(in) :: t0, tol
    real(dp), intent(inout) :: q(:)
    real(dp), intent(in) :: v(:)
    logical, intent(in) :: given_q(:)
    integer, intent(in) :: max_iter
    integer, intent(inout) :: iterations
    integer, intent(out) :: stat
    integer :: it, nfree
    stat = MBDK_SUCCESS
    nfree = count(.not. given_q)
    do it = 0, max_iter
      if (as%sparse) then
        call mbdk_model_constraints(model, t0, q, v, as%phi, gam=as%gam, phit=as%phit)
      else
        call mbdk_model_constraints(model, t0, q, v, as%phi, as%d, as%gam, as%phit)
        ! a knife edge's row holds no position (its phi is 0): out of the corrections
        if (model%has_pfaffian) call drop_velocity_rows(model, as%d)
      end if
      if (maxval(abs(as%phi)) <= mbdk_phi_floor(tol, q) .or. it == max_iter .or. nfree == 0) &
        exit
      call least_change(model, as, mn, t0, q, v, given_q, -as%phi, stat)
      if (stat /= MBDK_SUCCESS) return
      q = q + as%dx
      iterations = it + 1
    end do
  end subroutine assemble_positions

  !> The velocities not given, at the assembled q: the least change with D v + Phi_t = 0;
  !> resid = D v + Phi_t at the v it leaves (on failure, D v before the change).
  subroutine assemble_velocities(model, as, mn, t0, q, v, given_v, resid, stat)
    type(mbdk_model_t), intent(in) :: model
    type(assembly_t), intent(inout) :: as
    type(minnorm_t), intent(inout) :: mn
    real(dp), intent(in) :: t0
    real(dp), intent(in) :: q(:)
    real(dp), intent(inout) :: v(:)
    logical, intent(in) :: given_v(:)
    real(dp), intent(inout) :: resid(:)
    integer, intent(out) :: stat
    stat = MBDK_SUCCESS
    ! the knife edges' rows, left out of the positions' D, constrain the velocities
    if (model%has_pfaffian .and. .not. as%sparse) &
      call mbdk_model_constraints(model, t0, q, v, as%phi, as%d, as%gam, as%phit)
    if (.not. all(given_v)) then
      if (as%sparse) then
        call mbdk_sparse_d_times(model%sp, model%work%dz, v, resid, .false.)
      else
        resid = matmul(as%d, v)
      end if
      call least_change(model, as, mn, t0, q, v, given_v, -as%phit - resid, stat)
      if (stat /= MBDK_SUCCESS) return
      v = v + as%dx
    end if
    call mbdk_model_constraints(model, t0, q, v, as%phi, gam=as%gam, phit=as%phit)
    call mbdk_sparse_d_times(model%sp, model%work%dz, v, resid, .false.)
    resid = resid + as%phit
  end subroutine assemble_velocities

  !> as%dx = the least change of the coordinates not given with D dx = c at (q, v): through
  !> the sparse Schur complement while the free columns allow it, else (and from then on) by
  !> the dense least squares, which passes dependent columns, while D is affordable.
  subroutine least_change(model, as, mn, t0, q, v, given, c, st)
    type(mbdk_model_t), intent(in) :: model
    type(assembly_t), intent(inout) :: as
    type(minnorm_t), intent(inout) :: mn
    real(dp), intent(in) :: t0
    real(dp), intent(in) :: q(:), v(:)
    logical, intent(in) :: given(:)
    real(dp), intent(in) :: c(:)
    integer, intent(out) :: st
    integer :: m, nc, k, rk
    integer, allocatable :: fr(:)
    m = model%m
    nc = model%nc
    if (as%sparse) then
      call minnorm(model, mn, given, c, as%dx, st)
      if (st /= MBDK_ERR_SINGULAR_MATRIX .or. .not. dense_affordable(model)) return
      ! dependent free columns: this and the next corrections by the dense least squares
      as%sparse = .false.
      allocate (as%d(m, nc), stat=rk)
      call mbdk_alloc_status(rk, MBDK_REAL_BYTES * real(m, dp) * nc, st)
      if (st /= MBDK_SUCCESS) return
      call mbdk_model_constraints(model, t0, q, v, as%phi, as%d, as%gam, as%phit)
    end if
    fr = pack([(k, k = 1, nc)], .not. given)
    if (allocated(as%a)) deallocate (as%a)
    allocate (as%a(m, size(fr)), as%b(max(m, size(fr))), stat=rk)
    call mbdk_alloc_status(rk, MBDK_REAL_BYTES * (real(m, dp) * size(fr) + max(m, size(fr))), &
                           st)
    if (st /= MBDK_SUCCESS) return
    as%a = as%d(:, fr)
    as%dx = 0.0_dp
    if (small_minnorm(as%a, c, as%b(1:size(fr)))) then
      as%dx(fr) = as%b(1:size(fr))
      deallocate (as%b)
      st = MBDK_SUCCESS
      return
    end if
    as%b(1:m) = c
    call mbdk_least_squares(as%a, as%b, epsilon(1.0_dp) * max(m, size(fr)), rk, st)
    if (st == MBDK_SUCCESS) as%dx(fr) = as%b(1:size(fr))
    deallocate (as%b)
  end subroutine least_change

  !> x = A^T (A A^T)^-1 c, the least change with A x = c where A's rows are independent (the
  !> sparse path's least change, minnorm, in the dense form of a few rows), by the in-house
  !> LDL^T of mbdk_small_dense: every sum in one order, so that a planar start is assembled to
  !> the same bits under every BLAS kernel (a start that differs in its last bits can change
  !> where a run through a singular pose stops, tests/test_same_bits.py). .false. (x
  !> undefined) for more rows than MBDK_SMALL_DENSE_MAX, more rows than columns, or rows that
  !> are dependent (redundant joints) or zero (a knife edge's, in the positions' correction) to
  !> the singular test of the constrained solves: mbdk_least_squares then takes the least
  !> squares (in one order of sums too up to MBDK_FIXED_ORDER_MAX rows and columns, LAPACK's
  !> dgelsd above).
  logical function small_minnorm(a, c, x) result(ok)
    real(dp), intent(in) :: a(:, :), c(:)
    real(dp), intent(out) :: x(:)
    real(dp) :: g(size(a, 1), size(a, 1)), y(size(a, 1))
    integer :: m, i, st
    ok = .false.
    m = size(a, 1)
    if (m == 0 .or. m > MBDK_SMALL_DENSE_MAX .or. m > size(a, 2)) return
    g = matmul(a, transpose(a))
    y = c
    call mbdk_small_ldlt_solve_once(g, m, [(i, i = 1, m + 1)], MBDK_CONSTRAINED_SINGULAR_TOL, y, &
                                    st)
    if (st /= MBDK_SUCCESS) return
    x = matmul(y, a)
    ok = .true.
  end function small_minnorm

  !> The knife edges' rows of the dense D zeroed, for the positions' least squares.
  pure subroutine drop_velocity_rows(model, d)
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(inout) :: d(:, :)
    integer :: r
    do r = 1, model%m
      if (model%pfaffian(r)) d(r, :) = 0.0_dp
    end do
  end subroutine drop_velocity_rows

  !> The dense D of the model and its least squares fit in memory (at most 10^7 entries).
  pure logical function dense_affordable(model)
    type(mbdk_model_t), intent(in) :: model
    dense_affordable = real(model%m, dp) * real(model%nc, dp) <= 1.0e7_dp
  end function dense_affordable

  !> dx = the least change (Euclidean, in the columns not given) with D dx = c at the compact
  !> rows model%work%dz: -W D^T (D W D^T)^-1 (-c) with W the mask of free columns, through
  !> the sparse Schur path (built on first use, for this mask). MBDK_ERR_SINGULAR_MATRIX when
  !> the free columns of D are dependent.
  subroutine minnorm(model, mn, given, c, dx, st)
    type(mbdk_model_t), intent(in) :: model
    type(minnorm_t), intent(inout) :: mn
    logical, intent(in) :: given(:)
    real(dp), intent(in) :: c(:)
    real(dp), intent(out) :: dx(:)
    integer, intent(out) :: st
    integer :: m, nc
    m = model%m
    nc = model%nc
    if (.not. allocated(mn%w)) then
      block
        logical, allocatable :: nz(:, :)
        integer, allocatable :: col(:, :)
        integer :: astat
        allocate (mn%w(nc), mn%zero(nc), mn%ones(nc), mn%mu(m), nz(MBDK_JOINT_SLOTS, m), &
                  col(MBDK_JOINT_SLOTS, m), stat=astat)
        call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (3.0_dp * nc + m) + &
                               2 * MBDK_INT_BYTES * MBDK_JOINT_SLOTS * m, st)
        if (st /= MBDK_SUCCESS) return   ! (the assembly fails: nothing is retried)
        mn%w = merge(0.0_dp, 1.0_dp, given)
        mn%zero = 0.0_dp
        mn%ones = 1.0_dp
        call mbdk_joints_pattern(model%jint, model%jreal, model%row0, col, nz)
        call mbdk_sparse_schur_init(mn%sp, col, nz, mn%w, st)
        if (st == MBDK_SUCCESS) &
          call mbdk_constrained_init(mn%cs, nc, m, .true., .false., .false., mn%sp, 1, st)
        if (st /= MBDK_SUCCESS) return
      end block
    end if
    call mbdk_constrained_solve_once(mn%cs, mn%sp, model%work%dz, model%col, model%blk, &
                                     mn%ones, mn%w, mn%zero, c, dx, mn%mu, st)
  end subroutine minnorm

  !> A run's model at its initial state y = [q; v] (updated in place): with assemble, y is
  !> assembled first (on a model of its own, resolved at the given y: asm_iters, asm_resid,
  !> velocity as mbdk_assembly_run's), then the tables' pose values are taken at y and the run's
  !> model built once there. bad_joint, bad_force: the element a pose value failed on.
  !> MBDK_ERR_NO_MEMORY: asked gets the bytes (mbdk_memory).
  subroutine mbdk_model_start(model, work, mass, inertia, jint, jreal, fint, freal, opt, t0, y, &
                              given_q, given_v, assemble, asm_iters, asm_resid, velocity, &
                              bad_joint, bad_force, stat, kinds, asked)
    type(mbdk_model_t), intent(out) :: model
    type(mbdk_model_work_t), target, intent(inout) :: work
    real(dp), intent(in) :: mass(:), inertia(:), jreal(:, :), freal(:, :), t0
    integer, intent(in) :: jint(:, :), fint(:, :)
    type(mbdk_model_options_t), intent(in) :: opt
    real(dp), intent(inout) :: y(:)
    logical, intent(in) :: given_q(:), given_v(:), assemble
    integer, intent(out) :: asm_iters, bad_joint, bad_force, stat
    real(dp), intent(out) :: asm_resid(:)
    logical, intent(out) :: velocity
    integer, intent(in), optional :: kinds(:)   !< the bodies' kinds (absent: all planar)
    real(dp), intent(inout), optional :: asked
    real(dp), allocatable :: jr(:, :), fr(:, :)
    integer :: nb, nc, b, code, coords, vels
    character(len=MBDK_ELEMENT_NAME_LEN) :: kname
    logical :: available
    nb = size(mass)
    nc = 3 * nb
    asm_iters = 0
    asm_resid = 0.0_dp
    velocity = .false.
    stat = MBDK_ERR_INVALID_INPUT
    ! a kind the planar model does not run (spatial bodies: mbdk_spatial_model) is named as
    ! such before the sizes (which assume planar bodies) are checked
    if (present(kinds)) then
      if (size(kinds) /= nb) return
      do b = 1, nb
        call mbdk_body_kind(kinds(b), code, kname, coords, vels, available)
        if (code == 0) return
        if (code /= MBDK_BODY_PLANAR .or. .not. available) then
          stat = MBDK_ERR_NOT_APPLICABLE
          return
        end if
      end do
    end if
    if (size(y) /= 2 * nc .or. size(given_q) /= nc .or. size(given_v) /= nc) return
    if (assemble) then
      block
        type(mbdk_model_t) :: amodel
        type(mbdk_model_work_t), target :: awork
        call build(amodel, awork)
        if (stat /= MBDK_SUCCESS) return
        stat = MBDK_ERR_INVALID_INPUT
        if (size(asm_resid) < amodel%m) return
        call mbdk_assembly_run(amodel, t0, y(1:nc), y(nc + 1:), given_q, given_v, 1.0e-12_dp, &
                               50, asm_iters, asm_resid(1:amodel%m), velocity, stat)
        if (stat /= MBDK_SUCCESS) return
      end block
    end if
    call build(model, work)

  contains

    subroutine build(mdl, wrk)
      type(mbdk_model_t), intent(out) :: mdl
      type(mbdk_model_work_t), target, intent(inout) :: wrk
      integer :: astat
      if (.not. allocated(jr)) then
        allocate (jr(size(jreal, 1), size(jreal, 2)), fr(size(freal, 1), size(freal, 2)), &
                  stat=astat)
        call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (size(jreal) + size(freal)), stat, asked)
        if (stat /= MBDK_SUCCESS) return
      end if
      jr = jreal
      fr = freal
      call mbdk_tables_resolve(nb, jint, jr, fint, fr, y(1:nc), bad_joint, bad_force, stat, &
                               asked)
      if (stat /= MBDK_SUCCESS) return
      call mbdk_model_init(mdl, mass, inertia, jint, jr, fint, fr, opt, wrk, stat, kinds, asked)
    end subroutine build

  end subroutine mbdk_model_start

end module mbdk_assembly
