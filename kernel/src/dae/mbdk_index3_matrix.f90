!> The Newton matrix of trapezoidal_index3 and its factorisations (mbdk_trapezoidal_index3 is
!> the method's manual; its "Newton matrix" and "Newton" paragraphs describe what is built here).
!>
!>   book:      [M + s (K_c(lambda) + K_f) + (h/2) C_f, D^T; D, 0] in the unknowns (dq, s dlambda)
!>   augmented: M + s (K_c(lam*) + K_f + alpha D^T D) + (h/2) C_f
!>
!> with s = h^2/4, K_f and C_f the tangent stiffness and damping of the force elements
!> (mbdk_forces_tangent) and K_c the geometric stiffness of the joints (mbdk_joints_tangent).
!> mbdk_index3_factors_t factorises it: up to MBDK_SMALL_DENSE_MAX rows in-house (the augmented
!> matrix, when symmetric to roundoff and positive definite, by the block LDL^T with the bodies
!> as 3 x 3 pivot blocks, else by mbdk_lapack's LU with partial pivoting, whose explicit
!> inverse serves from an LU's third solve on; a matrix not finite is refused, as the LU, like
!> dgetrf, would take an infinite pivot and return finite nonsense), otherwise by mbdk_lapack's
!> LU (dgetrf's algorithm, in-house up to 128 unknowns); the
!> augmented matrix of a large scene (more than MBDK_SPARSE_MIN_ROWS constraint rows, or solver
!> sparse) sparse: assembled element by element into the body-block pattern of
!> mbdk_body_pattern (each element's tangent formed on its two bodies alone, by the same
!> routines as the dense matrix) and factorised by AMD + LDL (mbdk_sparse_ldlt), O(N) for a
!> chain. That path factorises the symmetric part (A + A^T)/2: equal to A but for the
!> unsymmetric damping terms of dampers, which then make Newton's matrix an approximation of the
!> Jacobian (as its reuse across iterations and steps already does), costing iterations, not
!> accuracy: the residual is exact and Newton's test unchanged. The book matrix of a large
!> scene is sparse the same way (fa%kkt): [K D^T; D 0] as one symmetric matrix of nc + m rows,
!> K assembled in the body pattern as above (its symmetric part), D from the compact rows, and
!> factorised by LDL^T without pivoting in AMD's order adjusted so that each constraint row is
!> eliminated right after the last coordinate it involves (mbdk_kkt_pattern, which the spatial
!> model's sparse index-3 matrix uses too): every coordinate's pivot is then one
!> of K updated by the rows' contributions, every row's pivot -D K^-1 D^T of what was
!> eliminated before it, both of the right sign and away from zero while K is positive definite
!> (M's for small h: a body without inertia keeps the dense path; at large h a compressed
!> joint's geometric stiffness or a negative spring can make K indefinite, which the pivot
!> test catches where a pivot vanishes) and the rows independent. A chain or tree factorises
!> at O(N) with the Newton iteration of the book's scheme, whose count does not grow with N
!> (the augmented form's multiplier update contracts more slowly as a chain lengthens).
module mbdk_index3_matrix
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_model, only: mbdk_model_t, mbdk_model_constraints
  use mbdk_joints, only: mbdk_joints_tangent, mbdk_joints_scatter, mbdk_joint_rows, &
    MBDK_JOINT_TYPES
  use mbdk_force_elements, only: mbdk_forces_tangent
  use mbdk_lapack, only: mbdk_lu_factor, mbdk_lu_solve
  use mbdk_sparse_schur, only: mbdk_sparse_dtd_add
  use mbdk_small_dense, only: mbdk_small_ldlt_factor, mbdk_small_ldlt_solve, &
    mbdk_small_lu_inverse, mbdk_small_inverse_apply, MBDK_SMALL_DENSE_MAX
  use mbdk_model, only: mbdk_model_sparse
  use mbdk_constrained, only: MBDK_SPARSE_MIN_ROWS
  use mbdk_body_pattern, only: mbdk_body_pattern_t, mbdk_body_pattern_init, &
    mbdk_body_pattern_pos, mbdk_body_pattern_scatter, mbdk_body_pattern_dtd
  use mbdk_kkt_pattern, only: mbdk_kkt_pattern_init
  use mbdk_sparse_ldlt, only: mbdk_sparse_ldlt_t, mbdk_sparse_ldlt_analyze, &
    mbdk_sparse_ldlt_factor, mbdk_sparse_ldlt_solve
  use mbdk_kinds, only: i8
  implicit none
  private
  public :: mbdk_index3_newton_matrix, mbdk_index3_factors_init, mbdk_index3_factor, &
    mbdk_index3_factors_solve

  !> scalings of mbdk_index3_newton_matrix
  integer, parameter, public :: MBDK_INDEX3_UNSCALED = 0, MBDK_INDEX3_SCALED_BOOK = 1, &
    MBDK_INDEX3_SCALED = 2
  !> a pivot of the augmented matrix's LDL^T at or below this times its largest diagonal entry:
  !> not positive definite enough, the LU is used
  real(dp), parameter :: LDLT_TOL = 1.0e-14_dp
  !> an LU that has served this many solves forms its explicit inverse for the next ones
  integer, parameter :: INVERSE_AFTER = 2

  !> The factors of one Newton matrix and how they are held.
  type, public :: mbdk_index3_factors_t
    integer :: nk = 0                  !< order: nc (augmented) or nc + m (book)
    logical :: small = .true.          !< in-house factorisations (nk <= MBDK_SMALL_DENSE_MAX)
    logical :: ldlt = .false.          !< the current factors are a block LDL^T
    logical :: have_inv = .false.      !< the explicit inverse ainv is formed
    integer :: nuse = 0                !< solves served by the current factors
    integer, allocatable :: ipiv(:), body_blk(:)
    real(dp), allocatable :: lu(:, :), ainv(:, :), inv_work(:, :), rinv(:)
    !> the sparse path: the pattern, the factors, and the position of each product of
    !> alpha D^T D (row by row, pairs of the row's nonzeros)
    logical :: sparse = .false.
    type(mbdk_body_pattern_t) :: bp
    type(mbdk_sparse_ldlt_t) :: ldl
    integer, allocatable :: dtd_pos(:)
    !> the book matrix's sparse path (module header): K's values in the body pattern (kx), the
    !> position in the whole matrix of each of them (kpos) and of each nonzero of D, by the
    !> compact rows' order of model%sp, in its rows (dpos_r) and its columns (dpos_c)
    logical :: kkt = .false.
    real(dp), allocatable :: kx(:)
    integer, allocatable :: kpos(:), dpos_r(:), dpos_c(:)
  end type mbdk_index3_factors_t

contains

  !> Factors for a Newton matrix of order nk of a model with nc coordinates (nk = nc: the
  !> augmented matrix, sparse on a large scene). MBDK_ERR_INVALID_INPUT when AMD refuses the
  !> pattern; MBDK_ERR_NO_MEMORY (asked: the bytes, mbdk_memory).
  subroutine mbdk_index3_factors_init(fa, model, nk, stat, asked)
    type(mbdk_index3_factors_t), intent(out) :: fa
    type(mbdk_model_t), intent(in) :: model
    integer, intent(in) :: nk
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: k, nc, choice
    nc = model%nc
    fa%nk = nk
    fa%small = model%small_dense .and. nk <= MBDK_SMALL_DENSE_MAX
    choice = mbdk_model_sparse(model)
    fa%sparse = nk == nc .and. mod(nc, 3) == 0 .and. (choice == 1 .or. &
                (choice == -1 .and. model%m > MBDK_SPARSE_MIN_ROWS))
    ! (a body without inertia leaves K a zero pivot ahead of its rows: the dense LU)
    fa%kkt = nk == nc + model%m .and. model%m > 0 .and. mod(nc, 3) == 0 .and. &
             model%m_positive .and. &
             (choice == 1 .or. (choice == -1 .and. model%m > MBDK_SPARSE_MIN_ROWS))
    stat = MBDK_SUCCESS
    if (fa%sparse .or. fa%kkt) then
      fa%small = .false.
      if (fa%kkt) then
        call kkt_init(fa, model, stat, asked)
      else
        call sparse_init(fa, model, stat, asked)
      end if
      if (stat /= MBDK_SUCCESS) return
      allocate (fa%lu(0, 0), fa%ipiv(0), fa%ainv(0, 0), fa%inv_work(0, 0), fa%rinv(0), &
                fa%body_blk(0), stat=k)
      call mbdk_alloc_status(k, 0.0_dp, stat, asked)
      return
    end if
    allocate (fa%lu(nk, nk), fa%ipiv(nk), fa%ainv(nk, nk), fa%inv_work(nk, nk), fa%rinv(nk), &
              fa%body_blk(merge(nc / 3 + 1, nc + 1, mod(nc, 3) == 0)), stat=k)
    call mbdk_alloc_status(k, MBDK_REAL_BYTES * (3.0_dp * nk * nk + nk) + &
                           MBDK_INT_BYTES * (nk + nc + 1.0_dp), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    ! the augmented matrix's LDL^T pivot blocks: the bodies (x, y, theta)
    do k = 1, size(fa%body_blk)
      fa%body_blk(k) = merge(3 * k - 2, k, mod(nc, 3) == 0)
    end do
  end subroutine mbdk_index3_factors_init

  !> Builds the Newton matrix at (t, q, v, lam) and factorises it: ck the coefficient of the
  !> stiffness and of the multipliers' terms (the trapezoidal rule's s = h^2/4; the
  !> generalized-alpha family's beta h^2 (1 - alpha_f) / (1 - alpha_m)), cd that of the
  !> damping (h/2; gamma h (1 - alpha_f) / (1 - alpha_m)). book: the book
  !> scheme's matrix (d(m, nc) receives the dense D from model%work%dz, the compact rows at q);
  !> otherwise the augmented one with penalty alpha. model%work%rot must hold the rotations at q.
  !> lw(m) is a work array.
  subroutine mbdk_index3_factor(fa, model, book, t, q, v, lam, ck, cd, alpha, d, lw, stat)
    type(mbdk_index3_factors_t), intent(inout) :: fa
    type(mbdk_model_t), intent(in) :: model
    logical, intent(in) :: book
    real(dp), intent(in) :: t, ck, cd, alpha
    real(dp), intent(in), contiguous :: q(:), v(:), lam(:)
    real(dp), intent(inout), contiguous :: d(:, :), lw(:)
    integer, intent(out) :: stat
    fa%ldlt = .false.
    fa%have_inv = .false.
    fa%nuse = 0
    if (fa%sparse) then
      call sparse_matrix(fa, model, t, q, v, lam, ck, cd, alpha, fa%ldl%ax, stat)
      if (stat == MBDK_SUCCESS) call mbdk_sparse_ldlt_factor(fa%ldl, LDLT_TOL, stat)
      return
    end if
    if (fa%kkt) then
      call kkt_matrix(fa, model, t, q, v, lam, ck, cd, stat)
      if (stat == MBDK_SUCCESS) call mbdk_sparse_ldlt_factor(fa%ldl, LDLT_TOL, stat)
      return
    end if
    if (book) then
      if (model%m > 0) call mbdk_joints_scatter(model%col, model%work%dz, d)
      call book_matrix(model, t, q, v, lam, ck, cd, d, lw, fa%lu, stat)
    else
      ! the geometric stiffness of the augmented form takes lam* alone: alpha Phi, large while
      ! the iterate is off the constraints, vanishes at the solution
      call al_matrix(model, t, q, v, lam, ck, cd, alpha, lw, fa%lu, stat)
      if (stat /= MBDK_SUCCESS) return
      if (fa%small) then
        if (symmetric(fa%lu, fa%nk)) then
          call mbdk_small_ldlt_factor(fa%lu, fa%nk, fa%body_blk, LDLT_TOL, stat)
          fa%ldlt = stat == MBDK_SUCCESS
          ! not positive definite: rebuilt for the LU
          if (.not. fa%ldlt) call al_matrix(model, t, q, v, lam, ck, cd, alpha, lw, fa%lu, stat)
        end if
      end if
    end if
    if (stat /= MBDK_SUCCESS .or. fa%ldlt) return
    if (fa%small) then
      stat = MBDK_ERR_SINGULAR_MATRIX
      if (.not. all(abs(fa%lu(1:fa%nk, 1:fa%nk)) <= huge(1.0_dp))) return
    end if
    call mbdk_lu_factor(fa%lu, fa%ipiv, stat)
  end subroutine mbdk_index3_factor

  !> r <- (Newton matrix)^-1 r with the current factors.
  subroutine mbdk_index3_factors_solve(fa, r, stat)
    type(mbdk_index3_factors_t), intent(inout) :: fa
    real(dp), intent(inout), contiguous :: r(:)
    integer, intent(out) :: stat
    stat = MBDK_SUCCESS
    ! an LU that has served two solves is likely to serve many (modified Newton): from the
    ! third on, through its explicit inverse
    if (fa%small .and. .not. fa%ldlt .and. fa%nuse == INVERSE_AFTER) then
      call mbdk_small_lu_inverse(fa%lu, fa%nk, fa%ipiv, fa%ainv, fa%inv_work)
      fa%have_inv = .true.
    end if
    fa%nuse = fa%nuse + 1
    if (fa%sparse .or. fa%kkt) then
      call mbdk_sparse_ldlt_solve(fa%ldl, r)
    else if (fa%have_inv) then
      call mbdk_small_inverse_apply(fa%ainv, fa%nk, r, fa%rinv)
    else if (fa%ldlt) then
      call mbdk_small_ldlt_solve(fa%lu, fa%nk, fa%body_blk, r)
    else
      call mbdk_lu_solve(fa%lu, fa%ipiv, r, stat)
    end if
  end subroutine mbdk_index3_factors_solve

  !> The Newton matrix at (q, v, lam, t) for step h: scaling UNSCALED (rows M a + D^T lam - f and
  !> Phi, unknowns dq, dlam), SCALED_BOOK (both rows times s = h^2/4, (3.15)-(3.16)) or SCALED
  !> (dynamic rows times s, unknown s lam, Phi unscaled: what the solver uses). jac(nc+m, nc+m).
  subroutine mbdk_index3_newton_matrix(model, t, q, v, lam, h, scaling, jac, stat)
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(in) :: t, q(:), v(:), lam(:), h
    integer, intent(in) :: scaling
    real(dp), intent(out) :: jac(:, :)
    integer, intent(out) :: stat
    real(dp) :: s
    real(dp), allocatable :: phi(:), d(:, :), gam(:), phit(:), lw(:), a(:, :)
    integer :: nc, m, astat
    nc = model%nc
    m = model%m
    allocate (phi(m), d(m, nc), gam(m), phit(m), lw(m), a(nc + m, nc + m), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (real(m, dp) * (nc + 4) + &
                                                    (real(nc, dp) + m)**2), stat)
    if (stat /= MBDK_SUCCESS) return
    s = 0.25_dp * h * h
    ! a knife edge's velocity row is no Phi to differentiate (mbdk_index3_init refuses it too)
    if (model%has_pfaffian) then
      stat = MBDK_ERR_NOT_APPLICABLE
      return
    end if
    call mbdk_model_constraints(model, t, q, v, phi, d, gam, phit)
    call book_matrix(model, t, q, v, lam, s, 0.5_dp * h, d, lw, a, stat)
    if (stat /= MBDK_SUCCESS) return
    jac = a
    select case (scaling)
    case (MBDK_INDEX3_UNSCALED)
      jac(1:nc, 1:nc) = jac(1:nc, 1:nc) / s
    case (MBDK_INDEX3_SCALED_BOOK)
      jac(1:nc, nc + 1:) = s * jac(1:nc, nc + 1:)
      jac(nc + 1:, 1:nc) = s * jac(nc + 1:, 1:nc)
    case (MBDK_INDEX3_SCALED)
      continue
    case default
      stat = MBDK_ERR_INVALID_INPUT
    end select
  end subroutine mbdk_index3_newton_matrix

  !> a = 0 but for its leading (nc, nc) block M + ck (K_c(lam) + K_f) + cd C_f at (q, v, lam,
  !> t), the body rotations model%work%rot at q; lw(m) is a work array. a(nc, nc) or larger.
  subroutine dynamic_block(model, t, q, v, lam, ck, cd, lw, a, stat)
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(in) :: t, ck, cd
    real(dp), intent(in), contiguous :: q(:), v(:), lam(:)
    real(dp), intent(out), contiguous :: lw(:), a(:, :)
    integer, intent(out) :: stat
    real(dp) :: s
    integer :: i
    s = ck
    a = 0.0_dp
    call mbdk_forces_tangent(model%fint, model%freal, model%work%rot, q, v, t, s, cd, &
                             a, model%work%visits(MBDK_JOINT_TYPES + 1:), stat)
    if (stat /= MBDK_SUCCESS) return
    if (model%m > 0) then
      lw = s * lam
      call mbdk_joints_tangent(model%jint, model%jreal, model%row0, model%work%rot, q, lw, a, &
                               model%work%visits(1:MBDK_JOINT_TYPES))
    end if
    do i = 1, model%nc
      a(i, i) = a(i, i) + model%mass(i)
    end do
  end subroutine dynamic_block

  !> The book scheme's [M + ck (K_c(lam) + K_f) + cd C_f, D^T; D, 0] (nc+m, nc+m) at (q, v,
  !> lam, t), with D = d given there and the body rotations model%work%rot at q (the callers
  !> evaluate the constraints, or the rotations, at q just before); lw(m) is a work array.
  subroutine book_matrix(model, t, q, v, lam, ck, cd, d, lw, jac, stat)
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(in) :: t, ck, cd
    real(dp), intent(in), contiguous :: q(:), v(:), lam(:), d(:, :)
    real(dp), intent(out), contiguous :: lw(:), jac(:, :)
    integer, intent(out) :: stat
    integer :: nc, m, i, k
    nc = model%nc
    m = model%m
    call dynamic_block(model, t, q, v, lam, ck, cd, lw, jac, stat)
    if (stat /= MBDK_SUCCESS) return
    do k = 1, nc
      do i = 1, m
        jac(nc + i, k) = d(i, k)
        jac(k, nc + i) = d(i, k)
      end do
    end do
  end subroutine book_matrix

  !> The augmented form's M + s (K_c(lam) + K_f + alpha D^T D) + (h/2) C_f (nc, nc) at (q, v,
  !> lam, t): D from its compact rows model%work%dz and the rotations model%work%rot, both at q.
  subroutine al_matrix(model, t, q, v, lam, ck, cd, alpha, lw, a, stat)
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(in) :: t, ck, cd, alpha
    real(dp), intent(in), contiguous :: q(:), v(:), lam(:)
    real(dp), intent(out), contiguous :: lw(:), a(:, :)
    integer, intent(out) :: stat
    call dynamic_block(model, t, q, v, lam, ck, cd, lw, a, stat)
    if (stat /= MBDK_SUCCESS .or. model%m == 0) return
    call mbdk_sparse_dtd_add(model%sp, model%work%dz, ck * alpha, a)
  end subroutine al_matrix

  !> The sparse path's pattern (bodies coupled by a joint or a force element) and its ordering.
  subroutine sparse_init(fa, model, stat, asked)
    type(mbdk_index3_factors_t), intent(inout) :: fa
    type(mbdk_model_t), intent(in) :: model
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    call body_pattern(fa, model, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_body_pattern_dtd(fa%bp, model%sp%rptr, model%sp%rcol, fa%dtd_pos, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_sparse_ldlt_analyze(fa%ldl, model%nc, fa%bp%ap, fa%bp%ai, stat, asked)
  end subroutine sparse_init

  !> fa%bp: the bodies coupled by a joint or a force element.
  subroutine body_pattern(fa, model, stat, asked)
    type(mbdk_index3_factors_t), intent(inout) :: fa
    type(mbdk_model_t), intent(in) :: model
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nj, nf, astat
    integer, allocatable :: pairs(:, :)
    nj = size(model%jint, 2)
    nf = size(model%fint, 2)
    allocate (pairs(2, nj + nf), stat=astat)
    call mbdk_alloc_status(astat, 2 * MBDK_INT_BYTES * (nj + nf), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    pairs(:, 1:nj) = model%jint(2:3, :)
    pairs(:, nj + 1:) = model%fint(2:3, :)
    call mbdk_body_pattern_init(fa%bp, model%nb, pairs, stat, asked)
  end subroutine body_pattern

  !> The book matrix's sparse pattern (module header): K's body pattern, D's nonzeros in both
  !> off-diagonal blocks, the rows' diagonal, and the ordering.
  subroutine kkt_init(fa, model, stat, asked)
    type(mbdk_index3_factors_t), intent(inout) :: fa
    type(mbdk_model_t), intent(in) :: model
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: astat
    call body_pattern(fa, model, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    allocate (fa%kx(fa%bp%nnz), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * fa%bp%nnz, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_kkt_pattern_init(fa%bp%ap, fa%bp%ai(1:fa%bp%nnz), model%sp%rptr, model%sp%rcol, &
                               fa%ldl, fa%kpos, fa%dpos_r, fa%dpos_c, stat, asked)
  end subroutine kkt_init

  !> The book matrix's values (module header) into fa%ldl%ax: K by sparse_matrix, D from its
  !> compact rows model%work%dz, at q.
  subroutine kkt_matrix(fa, model, t, q, v, lam, ck, cd, stat)
    type(mbdk_index3_factors_t), intent(inout) :: fa
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(in) :: t, ck, cd
    real(dp), intent(in), contiguous :: q(:), v(:), lam(:)
    integer, intent(out) :: stat
    integer :: p, j, z
    real(dp) :: x
    call sparse_matrix(fa, model, t, q, v, lam, ck, cd, 0.0_dp, fa%kx, stat)
    if (stat /= MBDK_SUCCESS) return
    associate (ax => fa%ldl%ax, sp => model%sp, dz => model%work%dz)
      ax = 0.0_dp
      do p = 1, size(fa%kx)
        ax(fa%kpos(p)) = ax(fa%kpos(p)) + fa%kx(p)
      end do
      do j = 1, sp%nnz
        z = sp%rz(j)
        x = dz(mod(z - 1, 6) + 1, (z - 1) / 6 + 1)
        ax(fa%dpos_r(j)) = ax(fa%dpos_r(j)) + x
        ax(fa%dpos_c(j)) = ax(fa%dpos_c(j)) + x
      end do
    end associate
  end subroutine kkt_matrix

  !> The augmented matrix into ax (fa%bp's pattern), element by element (see the module
  !> header), then its symmetric part; alpha = 0: K alone. model%work%rot and model%work%dz at q.
  subroutine sparse_matrix(fa, model, t, q, v, lam, ck, cd, alpha, ax, stat)
    type(mbdk_index3_factors_t), intent(inout) :: fa
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(in) :: t, ck, cd, alpha
    real(dp), intent(in), contiguous :: q(:), v(:), lam(:)
    real(dp), intent(out), contiguous :: ax(:)
    integer, intent(out) :: stat
    real(dp) :: s, ke(6, 6), ql(6), vl(6), rl(2, 2), ll(3), x
    integer :: e, b1, b2, k, r, i, j, n, jl(4, 1), row0(1), p, pt
    s = ck
    stat = MBDK_SUCCESS
    associate (w => model%work)
      ax = 0.0_dp
      do e = 1, size(model%fint, 2)
        call local(model%fint(2, e), model%fint(3, e))
        jl(:, 1) = [model%fint(1, e), merge(1, 0, b1 > 0), merge(merge(1, 2, b2 == b1), 0, &
                    b2 > 0), model%fint(4, e)]
        ke = 0.0_dp
        call mbdk_forces_tangent(jl, model%freal(:, e:e), rl, ql, vl, t, s, cd, ke, &
                                 w%visits(MBDK_JOINT_TYPES + 1:), stat)
        if (stat /= MBDK_SUCCESS) return
        call mbdk_body_pattern_scatter(fa%bp, b1, merge(0, b2, b2 == b1), ke, ax)
      end do
      row0 = 1
      do e = 1, size(model%jint, 2)
        call local(model%jint(2, e), model%jint(3, e))
        jl(:, 1) = [model%jint(1, e), 1, merge(merge(1, 2, b2 == b1), 0, b2 > 0), &
                    model%jint(4, e)]
        r = model%row0(e)
        k = mbdk_joint_rows(model%jint(1, e))
        ll = 0.0_dp
        ll(1:k) = s * lam(r:r + k - 1)
        ke = 0.0_dp
        call mbdk_joints_tangent(jl, model%jreal(:, e:e), row0, rl, ql, ll, ke, &
                                 w%visits(1:MBDK_JOINT_TYPES))
        call mbdk_body_pattern_scatter(fa%bp, b1, merge(0, b2, b2 == b1), ke, ax)
      end do
      ! alpha s D^T D, in the order of sparse_init's positions
      n = 0
      if (alpha /= 0.0_dp) then
      do r = 1, model%sp%m
        do j = model%sp%rptr(r), model%sp%rptr(r + 1) - 1
          x = s * alpha * w%dz(mod(model%sp%rz(j) - 1, 6) + 1, (model%sp%rz(j) - 1) / 6 + 1)
          do i = model%sp%rptr(r), model%sp%rptr(r + 1) - 1
            n = n + 1
            ax(fa%dtd_pos(n)) = ax(fa%dtd_pos(n)) + x * &
              w%dz(mod(model%sp%rz(i) - 1, 6) + 1, (model%sp%rz(i) - 1) / 6 + 1)
          end do
        end do
      end do
      end if
      do i = 1, model%nc
        p = mbdk_body_pattern_pos(fa%bp, i, i)
        ax(p) = ax(p) + model%mass(i)
      end do
      ! the symmetric part (see the module header)
      do p = 1, size(ax)
        pt = fa%bp%tpos(p)
        if (pt <= p) cycle
        x = 0.5_dp * (ax(p) + ax(pt))
        ax(p) = x
        ax(pt) = x
      end do
    end associate

  contains

    !> the coordinates, velocities and rotations of bodies c1, c2 as bodies 1, 2 (b1, b2 set)
    subroutine local(c1, c2)
      integer, intent(in) :: c1, c2
      b1 = c1
      b2 = c2
      ql = 0.0_dp
      vl = 0.0_dp
      rl = 0.0_dp
      if (b1 > 0) then
        ql(1:3) = q(3 * b1 - 2:3 * b1)
        vl(1:3) = v(3 * b1 - 2:3 * b1)
        rl(:, 1) = model%work%rot(:, b1)
      end if
      if (b2 > 0 .and. b2 /= b1) then
        ql(4:6) = q(3 * b2 - 2:3 * b2)
        vl(4:6) = v(3 * b2 - 2:3 * b2)
        rl(:, 2) = model%work%rot(:, b2)
      end if
    end subroutine local

  end subroutine sparse_matrix

  !> True when a(n, n) is symmetric to roundoff: |a(i,j) - a(j,i)| <= 1e-13 max_k |a(k,k)|.
  !> (Dampers make the tangent stiffness unsymmetric; springs, joints and D^T D do not, but
  !> their two triangles may differ in the last bits.)
  pure logical function symmetric(a, n)
    integer, intent(in) :: n
    real(dp), intent(in) :: a(n, n)
    real(dp) :: tol
    integer :: i, j
    tol = 0.0_dp
    do i = 1, n
      tol = max(tol, abs(a(i, i)))
    end do
    tol = 1.0e-13_dp * tol
    symmetric = .false.
    do j = 1, n
      do i = j + 1, n
        if (.not. (abs(a(i, j) - a(j, i)) <= tol)) return
      end do
    end do
    symmetric = .true.
  end function symmetric

end module mbdk_index3_matrix
