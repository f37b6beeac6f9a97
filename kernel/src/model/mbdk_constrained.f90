!> The constrained linear systems of a scene, one object for all their users:
!>
!>   W^-1 x + D^T mu = b,   D x = c            (W diagonal: M^-1, or a projection's weight)
!>
!> the reduced, Baumgarte and projection formulations' accelerations (b = f, c = gamma or its
!> stabilised form: x = a, mu = lambda), the projection formulation's corrections of q and v
!> (b = 0, c = -residual), and trapezoidal_index3's projections of v and a. D comes in the
!> compact rows of mbdk_joints (dz, with its pattern in mbdk_sparse_schur_t, whose row weights
!> are W). Paths (MBDK_SOLVE_*, named in a run's manifest), chosen once at init:
!>   SCHUR_SMALL   S = D W D^T from the nonzeros of D (mbdk_sparse_schur), the in-house block
!>                 LDL^T with the joints as pivot blocks (up to MBDK_SMALL_DENSE_MAX rows:
!>                 LAPACK's call overhead dominates such systems); solve_once eliminates the
!>                 right-hand side with the matrix, storing no L (what an evaluation that solves
!>                 once per matrix wants)
!>   SCHUR_LAPACK  the same S by LAPACK's dpotrf/dpotrs (more rows, or small_dense off)
!>   SCHUR_SPARSE  the same S kept sparse (mbdk_sparse_schur_csc: both triangles, CSC) and
!>                 factorised by SuiteSparse's AMD + LDL (mbdk_sparse_ldlt): O(nnz) for the
!>                 block tridiagonal S of a chain and the block tree of a tree, little fill for
!>                 loops; the path of more than MBDK_SPARSE_MIN_ROWS rows (or asked for). No
!>                 matrix of the size of the system is formed on it but the regular path's
!>                 below (a few steps at a singular crossing, up to REGULAR_DENSE_MAX
!>                 coordinates; a larger scene stops there by name).
!>   KKT           [W^-1 D^T; D 0] by LAPACK's LU, for a W^-1 = M with zero entries (a body
!>                 without inertia) or when asked for (solver kkt)
!> Dependent rows of D make S or the KKT matrix singular: a pivot at or below
!> MBDK_CONSTRAINED_SINGULAR_TOL of the largest gives MBDK_ERR_SINGULAR_MATRIX. (The closed-form
!> blocks of all-revolute scenes, mbdk_revolute_schur, are the model's own faster path for the
!> accelerations.)
!>
!> A caller that must pass through such a configuration (trapezoidal_index3's projections at a
!> singular crossing of a mechanism, or redundant joints) asks mbdk_constrained_factor for the
!> regular path instead of the error: the augmented Lagrangian iteration of Bayo and Ledesma
!> (1996) on the mass-orthogonal projection,
!>   (W^-1 + beta D^T D) x_k+1 = b - D^T mu_k + beta D^T c,   mu_k+1 = mu_k + beta (D x_k+1 - c),
!> whose matrix stays positive definite whatever D's rank (W^-1 > 0). It converges to the
!> solution where one exists (c in the range of D) and otherwise to the x that meets the
!> constraints in the least-squares sense, in the norm of W^-1: the part of c that no x can
!> meet is left, not amplified by the inverse of a vanishing singular value. beta = 1e3
!> max(W^-1) / max |D_i|^2 contracts a regular direction about a thousandfold per iteration;
!> directions near the rank loss converge slower and stop when the residual no longer falls
!> (at most MBDK_CONSTRAINED_AL_ITER iterations). The dense matrix is factorised by LAPACK's
!> dpotrf: this path serves the few steps near a crossing, not every evaluation. A caller may
!> take it before D is singular (mbdk_constrained_factor's near: a relative pivot below which
!> the exact solve counts as singular): trapezoidal_index3's projections do, because the exact
!> solve amplifies what the vanishing direction cannot meet.
module mbdk_constrained
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_joints, only: mbdk_joints_scatter
  use mbdk_lapack, only: mbdk_lu_factor, mbdk_lu_solve, mbdk_chol_factor, mbdk_chol_solve
  use mbdk_small_dense, only: mbdk_small_ldlt_factor, mbdk_small_ldlt_solve, &
    mbdk_small_ldlt_solve_once, MBDK_SMALL_DENSE_MAX
  use mbdk_sparse_schur, only: mbdk_sparse_schur_t, mbdk_sparse_schur_assemble, &
    mbdk_sparse_d_times, mbdk_sparse_w_residual, mbdk_sparse_schur_csc, &
    mbdk_sparse_schur_assemble_csc
  use mbdk_sparse_ldlt, only: mbdk_sparse_ldlt_t, mbdk_sparse_ldlt_analyze, &
    mbdk_sparse_ldlt_factor, mbdk_sparse_ldlt_solve, mbdk_sparse_ldlt_near, &
    MBDK_SPARSE_NEAR_BASELINE
  implicit none
  private
  public :: mbdk_constrained_init, mbdk_constrained_factor, mbdk_constrained_solve, &
    mbdk_constrained_solve_once, mbdk_constrained_path

  !> the linear solve a model's evaluation takes (mbdk_model_linear_solve); the penalty codes
  !> belong to the penalty formulation's own matrix
  integer, parameter, public :: MBDK_SOLVE_NONE = 0, MBDK_SOLVE_REVOLUTE = 1, &
    MBDK_SOLVE_SCHUR_SMALL = 2, MBDK_SOLVE_SCHUR_LAPACK = 3, MBDK_SOLVE_KKT = 4, &
    MBDK_SOLVE_PENALTY_SMALL = 5, MBDK_SOLVE_PENALTY_LAPACK = 6, MBDK_SOLVE_SCHUR_SPARSE = 7
  !> Above this many rows the Schur complement is solved sparse (solver auto); up to it, by the
  !> in-house dense LDL^T. AMD + LDL beats LAPACK's dense Cholesky from the first size LAPACK
  !> would take (benchmarks/run.py measures both paths on chains).
  integer, parameter, public :: MBDK_SPARSE_MIN_ROWS = MBDK_SMALL_DENSE_MAX
  !> relative pivot below which S = D W D^T (or the KKT matrix) counts as singular
  real(dp), parameter, public :: MBDK_CONSTRAINED_SINGULAR_TOL = 1.0e-11_dp
  !> the regular path: penalty factor per max(W^-1) / max |D_i|^2, and the iteration limit
  real(dp), parameter :: AL_KAPPA = 1.0e3_dp
  integer, parameter, public :: MBDK_CONSTRAINED_AL_ITER = 30
  !> the largest nc whose dense regular-path matrix a sparse-path scene forms (72 MB)
  integer, parameter :: REGULAR_DENSE_MAX = 3000

  type, public :: mbdk_constrained_t
    integer :: path = MBDK_SOLVE_NONE
    integer :: nc = 0, m = 0
    real(dp), allocatable :: s(:, :)                 !< S, then its factors
    real(dp), allocatable :: kkt(:, :), rhs(:), d(:, :)
    integer, allocatable :: ipiv(:)
    !> the regular path, when the last factorisation took it: W^-1 + beta D^T D (its Cholesky
    !> factor), the dense D, beta, and the iterations of the last solve
    logical :: regular = .false.
    real(dp), allocatable :: al(:, :), ald(:, :), alx(:), alr(:)
    real(dp) :: beta = 0.0_dp
    integer :: al_iters = 0
    !> the sparse path: S's factors, and where each entry of S goes in their values
    type(mbdk_sparse_ldlt_t) :: ldl
    integer, allocatable :: slo(:), sup(:)
    !> the largest least pivot ratio of the factorisations so far: the near tests' baseline
    !> (see factor_exact)
    real(dp) :: rmin_max = 0.0_dp
  end type mbdk_constrained_t

contains

  !> The path for nc coordinates and m rows: a Schur path when W is a positive weight
  !> (w_positive) and kkt is not asked for (in-house up to MBDK_SMALL_DENSE_MAX rows when
  !> small_dense, sparse above MBDK_SPARSE_MIN_ROWS or when sparse is asked for, LAPACK
  !> between), the KKT path otherwise. sparse: 1 always, 0 never, -1 by size.
  pure integer function mbdk_constrained_path(m, w_positive, kkt, small_dense, sparse) &
      result(path)
    integer, intent(in) :: m, sparse
    logical, intent(in) :: w_positive, kkt, small_dense
    if (m == 0) then
      path = MBDK_SOLVE_NONE
    else if (w_positive .and. .not. kkt) then
      if (sparse == 1 .or. (sparse == -1 .and. m > MBDK_SPARSE_MIN_ROWS)) then
        path = MBDK_SOLVE_SCHUR_SPARSE
      else if (small_dense .and. m <= MBDK_SMALL_DENSE_MAX) then
        path = MBDK_SOLVE_SCHUR_SMALL
      else
        path = MBDK_SOLVE_SCHUR_LAPACK
      end if
    else
      path = MBDK_SOLVE_KKT
    end if
  end function mbdk_constrained_path

  !> The object for nc coordinates and m rows on the path of mbdk_constrained_path; sp is the
  !> pattern of D (the sparse path's S is analysed from it here, once).
  !> MBDK_ERR_INVALID_INPUT when AMD refuses the pattern, MBDK_ERR_NO_MEMORY when a dense path
  !> cannot have its matrix (asked: the bytes, mbdk_memory).
  subroutine mbdk_constrained_init(cs, nc, m, w_positive, kkt, small_dense, sp, sparse, stat, &
                                   asked)
    type(mbdk_constrained_t), intent(out) :: cs
    integer, intent(in) :: nc, m, sparse
    logical, intent(in) :: w_positive, kkt, small_dense
    type(mbdk_sparse_schur_t), intent(in) :: sp
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: astat
    integer, allocatable :: ap(:), ai(:)
    real(dp) :: nk
    cs%nc = nc
    cs%m = m
    cs%path = mbdk_constrained_path(m, w_positive, kkt, small_dense, sparse)
    stat = MBDK_SUCCESS
    select case (cs%path)
    case (MBDK_SOLVE_KKT)
      nk = real(nc, dp) + m
      allocate (cs%kkt(nc + m, nc + m), cs%rhs(nc + m), cs%ipiv(nc + m), cs%d(m, nc), &
                cs%s(0, 0), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (nk * nk + nk + real(m, dp) * nc) + &
                             MBDK_INT_BYTES * nk, stat, asked)
    case (MBDK_SOLVE_SCHUR_SPARSE)
      allocate (cs%s(0, 0), cs%kkt(0, 0), cs%rhs(0), cs%ipiv(0), cs%d(0, 0), stat=astat)
      call mbdk_alloc_status(astat, 0.0_dp, stat, asked)
      if (stat /= MBDK_SUCCESS) return
      call mbdk_sparse_schur_csc(sp, ap, ai, cs%slo, cs%sup, stat, asked)
      if (stat /= MBDK_SUCCESS) return
      call mbdk_sparse_ldlt_analyze(cs%ldl, m, ap, ai, stat, asked)
    case default
      allocate (cs%s(m, m), cs%kkt(0, 0), cs%rhs(0), cs%ipiv(0), cs%d(0, 0), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * real(m, dp) * m, stat, asked)
    end select
  end subroutine mbdk_constrained_init

  !> Factorises the system at D (compact rows dz; col their columns, blk the pivot blocks, wm the
  !> diagonal W^-1). regular: where the system is singular, take the regular path (see the
  !> module header) instead of returning MBDK_ERR_SINGULAR_MATRIX. near: the relative pivot of
  !> S below which it counts as singular (default and floor MBDK_CONSTRAINED_SINGULAR_TOL; the
  !> KKT path tests it on S formed densely, where every body has inertia).
  subroutine mbdk_constrained_factor(cs, sp, dz, col, blk, wm, stat, regular, near)
    type(mbdk_constrained_t), intent(inout) :: cs
    type(mbdk_sparse_schur_t), intent(in) :: sp
    real(dp), intent(in), contiguous :: dz(:, :), wm(:)
    integer, intent(in), contiguous :: col(:, :), blk(:)
    integer, intent(out) :: stat
    logical, intent(in), optional :: regular
    real(dp), intent(in), optional :: near
    real(dp) :: tol
    tol = MBDK_CONSTRAINED_SINGULAR_TOL
    if (present(near)) tol = max(tol, near)
    call factor_exact(cs, sp, dz, col, blk, wm, tol, stat)
    cs%regular = .false.
    if (stat /= MBDK_ERR_SINGULAR_MATRIX .or. .not. present(regular)) return
    if (regular) call factor_regular(cs, dz, col, wm, stat)
  end subroutine mbdk_constrained_factor

  !> The regular path's matrix W^-1 + beta D^T D, factorised.
  subroutine factor_regular(cs, dz, col, wm, stat)
    type(mbdk_constrained_t), intent(inout) :: cs
    real(dp), intent(in), contiguous :: dz(:, :), wm(:)
    integer, intent(in), contiguous :: col(:, :)
    integer, intent(out) :: stat
    integer :: i, nc, m, astat
    real(dp) :: dmax
    nc = cs%nc
    m = cs%m
    stat = MBDK_ERR_SINGULAR_MATRIX
    if (.not. all(wm > 0.0_dp)) return   ! a body without inertia: no positive definite matrix
    ! the regular path's matrix is dense: a large scene on the sparse path has none
    if (cs%path == MBDK_SOLVE_SCHUR_SPARSE .and. nc > REGULAR_DENSE_MAX) return
    if (.not. allocated(cs%al)) then
      allocate (cs%al(nc, nc), cs%ald(m, nc), cs%alx(nc), cs%alr(m), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (real(nc + m, dp) * nc + nc + m), stat)
      if (stat /= MBDK_SUCCESS) then
        ! (a half-made set would pass the allocated test next time)
        if (allocated(cs%al)) deallocate (cs%al)
        return
      end if
    end if
    call mbdk_joints_scatter(col, dz, cs%ald)
    dmax = 0.0_dp
    do i = 1, m
      dmax = max(dmax, sum(cs%ald(i, :)**2))
    end do
    if (.not. (dmax > 0.0_dp)) dmax = 1.0_dp
    cs%beta = AL_KAPPA * maxval(wm) / dmax
    ! formed in place: an expression's temporary of nc x nc would be taken without a status
    cs%al = matmul(transpose(cs%ald), cs%ald)
    cs%al = cs%beta * cs%al
    do i = 1, nc
      cs%al(i, i) = cs%al(i, i) + wm(i)
    end do
    call mbdk_chol_factor(cs%al, stat)
    if (stat /= MBDK_SUCCESS) then
      stat = MBDK_ERR_SINGULAR_MATRIX
      return
    end if
    cs%regular = .true.
  end subroutine factor_regular

  !> The regular path's solve: the augmented Lagrangian iteration from mu = 0, until D x - c
  !> is at roundoff or no longer falls by half; x and mu are those of the smallest residual
  !> (an iterate after the stall, and the multiplier update it brings, are not taken).
  subroutine solve_regular(cs, b, c, x, mu, stat)
    type(mbdk_constrained_t), intent(inout) :: cs
    real(dp), intent(in), contiguous :: b(:), c(:)
    real(dp), intent(out), contiguous :: x(:), mu(:)
    integer, intent(out) :: stat
    integer :: k
    real(dp) :: r, r_best
    real(dp), allocatable :: mu_k(:)
    allocate (mu_k(size(mu)), stat=k)
    call mbdk_alloc_status(k, MBDK_REAL_BYTES * size(mu), stat)
    if (stat /= MBDK_SUCCESS) return
    mu_k = 0.0_dp
    mu = 0.0_dp
    x = 0.0_dp
    r_best = huge(1.0_dp)
    cs%al_iters = 0
    do k = 1, MBDK_CONSTRAINED_AL_ITER
      cs%alx = b - matmul(mu_k - cs%beta * c, cs%ald)   ! D^T x as x^T D (meson.build)
      call mbdk_chol_solve(cs%al, cs%alx, stat)
      if (stat /= MBDK_SUCCESS) return
      cs%al_iters = k
      cs%alr = matmul(cs%ald, cs%alx) - c
      r = maxval(abs(cs%alr))
      if (.not. (r < r_best)) exit
      mu_k = mu_k + cs%beta * cs%alr
      x = cs%alx
      mu = mu_k
      if (r <= 64.0_dp * epsilon(1.0_dp) * (maxval(abs(c)) + maxval(abs(cs%ald)) * &
                                           maxval(abs(x))) .or. r > 0.5_dp * r_best) exit
      r_best = r
    end do
  end subroutine solve_regular

  subroutine factor_exact(cs, sp, dz, col, blk, wm, tol, stat)
    type(mbdk_constrained_t), intent(inout) :: cs
    type(mbdk_sparse_schur_t), intent(in) :: sp
    real(dp), intent(in), contiguous :: dz(:, :), wm(:)
    real(dp), intent(in) :: tol
    integer, intent(in), contiguous :: col(:, :), blk(:)
    integer, intent(out) :: stat
    integer :: i, j, k, nc, m, nk
    real(dp) :: umax, umin, rmin
    nc = cs%nc
    m = cs%m
    stat = MBDK_SUCCESS
    select case (cs%path)
    case (MBDK_SOLVE_SCHUR_SMALL)
      call mbdk_sparse_schur_assemble(sp, dz, cs%s)
      call mbdk_small_ldlt_factor(cs%s, m, blk, tol, stat)
    case (MBDK_SOLVE_SCHUR_LAPACK)
      call mbdk_sparse_schur_assemble(sp, dz, cs%s)
      ! each pivot L_ii^2 against its row's own diagonal S_ii (as the in-house LDL^T): the part
      ! of row i independent of the rows before it, whatever the rows' mass scales
      block
        real(dp), allocatable :: d0(:)
        allocate (d0(m), stat=i)
        call mbdk_alloc_status(i, MBDK_REAL_BYTES * m, stat)
        if (stat /= MBDK_SUCCESS) return
        do i = 1, m
          d0(i) = cs%s(i, i)
        end do
        call mbdk_chol_factor(cs%s, stat)
        if (stat /= MBDK_SUCCESS) return
        do i = 1, m
          if (.not. (cs%s(i, i)**2 > tol * d0(i))) &
            stat = MBDK_ERR_SINGULAR_MATRIX
        end do
      end block
    case (MBDK_SOLVE_SCHUR_SPARSE)
      call mbdk_sparse_schur_assemble_csc(sp, dz, cs%slo, cs%sup, cs%ldl%ax)
      call mbdk_sparse_ldlt_factor(cs%ldl, MBDK_CONSTRAINED_SINGULAR_TOL, stat, rmin)
      if (stat /= MBDK_SUCCESS) return
      ! A caller's near test (a window wider than the singular one) is taken relative to the
      ! largest least pivot ratio the object has met so far (its baseline, rmin_max; the rule
      ! and its why: mbdk_sparse_ldlt_near)
      cs%rmin_max = max(cs%rmin_max, rmin)
      if (tol > MBDK_CONSTRAINED_SINGULAR_TOL) then
        if (mbdk_sparse_ldlt_near(rmin, cs%rmin_max, tol, m, MBDK_SPARSE_MIN_ROWS, &
                                  MBDK_SPARSE_NEAR_BASELINE)) stat = MBDK_ERR_SINGULAR_MATRIX
      end if
    case (MBDK_SOLVE_KKT)
      call mbdk_joints_scatter(col, dz, cs%d)
      nk = nc + m
      cs%kkt = 0.0_dp
      do i = 1, nc
        cs%kkt(i, i) = wm(i)
      end do
      do k = 1, nc
        do j = 1, m
          cs%kkt(nc + j, k) = cs%d(j, k)
          cs%kkt(k, nc + j) = cs%d(j, k)
        end do
      end do
      call mbdk_lu_factor(cs%kkt, cs%ipiv, stat)
      if (stat /= MBDK_SUCCESS) return
      umax = 0.0_dp
      umin = huge(1.0_dp)
      do i = 1, nk
        umax = max(umax, abs(cs%kkt(i, i)))
        umin = min(umin, abs(cs%kkt(i, i)))
      end do
      if (umin <= MBDK_CONSTRAINED_SINGULAR_TOL * umax * max(1.0_dp, maxval(wm))) &
        stat = MBDK_ERR_SINGULAR_MATRIX
      ! the LU's pivots are not those of D M^-1 D^T: a caller's near test (a wider window than
      ! the singular one) is made on S itself, formed densely, where every body has inertia
      if (stat == MBDK_SUCCESS .and. tol > MBDK_CONSTRAINED_SINGULAR_TOL .and. &
          all(wm > 0.0_dp)) call near_test_dense(cs%d, wm, tol, stat)
    end select
  end subroutine factor_exact

  !> The near test of the Schur paths on the dense D and W^-1 = wm: each Cholesky pivot of
  !> S = D W D^T, squared, against tol times its row's own diagonal; MBDK_ERR_SINGULAR_MATRIX
  !> below it.
  subroutine near_test_dense(d, wm, tol, stat)
    real(dp), intent(in) :: d(:, :), wm(:), tol
    integer, intent(out) :: stat
    real(dp), allocatable :: s(:, :), d0(:)
    integer :: i, j, astat
    ! allocated, not automatic: S of a large scene does not belong on a thread's stack
    allocate (s(size(d, 1), size(d, 1)), d0(size(d, 1)), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * real(size(d, 1), dp) * (size(d, 1) + 1), stat)
    if (stat /= MBDK_SUCCESS) return
    do j = 1, size(d, 1)
      do i = j, size(d, 1)
        s(i, j) = sum(d(i, :) * d(j, :) / wm)
      end do
      d0(j) = s(j, j)
    end do
    call mbdk_chol_factor(s, stat)
    if (stat /= MBDK_SUCCESS) then
      stat = MBDK_ERR_SINGULAR_MATRIX
      return
    end if
    do i = 1, size(d, 1)
      if (.not. (s(i, i)**2 > tol * d0(i))) stat = MBDK_ERR_SINGULAR_MATRIX
    end do
  end subroutine near_test_dense

  !> x, mu from the factors of mbdk_constrained_factor (the same dz): W^-1 x + D^T mu = b,
  !> D x = c, with w = W (on the regular path, as its iteration converges: see the header).
  subroutine mbdk_constrained_solve(cs, sp, dz, blk, w, b, c, x, mu, stat)
    type(mbdk_constrained_t), intent(inout) :: cs
    type(mbdk_sparse_schur_t), intent(in) :: sp
    real(dp), intent(in), contiguous :: dz(:, :), w(:), b(:), c(:)
    integer, intent(in), contiguous :: blk(:)
    real(dp), intent(out), contiguous :: x(:), mu(:)
    integer, intent(out) :: stat
    integer :: nc
    nc = cs%nc
    stat = MBDK_SUCCESS
    if (cs%regular) then
      call solve_regular(cs, b, c, x, mu, stat)
      return
    end if
    select case (cs%path)
    case (MBDK_SOLVE_SCHUR_SMALL, MBDK_SOLVE_SCHUR_LAPACK, MBDK_SOLVE_SCHUR_SPARSE)
      call mbdk_sparse_d_times(sp, dz, b, mu, .true.)
      mu = mu - c
      if (cs%path == MBDK_SOLVE_SCHUR_SMALL) then
        call mbdk_small_ldlt_solve(cs%s, cs%m, blk, mu)
      else if (cs%path == MBDK_SOLVE_SCHUR_SPARSE) then
        call mbdk_sparse_ldlt_solve(cs%ldl, mu)
      else
        call mbdk_chol_solve(cs%s, mu, stat)
        if (stat /= MBDK_SUCCESS) return
      end if
      call mbdk_sparse_w_residual(sp, dz, w, mu, x, nc, b)
    case (MBDK_SOLVE_KKT)
      cs%rhs(1:nc) = b
      cs%rhs(nc + 1:) = c
      call mbdk_lu_solve(cs%kkt, cs%ipiv, cs%rhs, stat)
      x = cs%rhs(1:nc)
      mu = cs%rhs(nc + 1:)
    case default
      x = w * b
    end select
  end subroutine mbdk_constrained_solve

  !> Factor and solve for one right-hand side: on the small Schur path in one pass (the
  !> right-hand side eliminated with S, no L stored), otherwise mbdk_constrained_factor then
  !> mbdk_constrained_solve.
  subroutine mbdk_constrained_solve_once(cs, sp, dz, col, blk, wm, w, b, c, x, mu, stat, near)
    type(mbdk_constrained_t), intent(inout) :: cs
    type(mbdk_sparse_schur_t), intent(in) :: sp
    real(dp), intent(in), contiguous :: dz(:, :), wm(:), w(:), b(:), c(:)
    integer, intent(in), contiguous :: col(:, :), blk(:)
    real(dp), intent(out), contiguous :: x(:), mu(:)
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: near   !< as for mbdk_constrained_factor
    real(dp) :: tol
    tol = MBDK_CONSTRAINED_SINGULAR_TOL
    if (present(near)) tol = max(tol, near)
    if (cs%path == MBDK_SOLVE_SCHUR_SMALL) then
      call mbdk_sparse_schur_assemble(sp, dz, cs%s)
      call mbdk_sparse_d_times(sp, dz, b, mu, .true.)
      mu = mu - c
      call mbdk_small_ldlt_solve_once(cs%s, cs%m, blk, tol, mu, stat)
      if (stat /= MBDK_SUCCESS) return
      call mbdk_sparse_w_residual(sp, dz, w, mu, x, cs%nc, b)
      return
    end if
    call mbdk_constrained_factor(cs, sp, dz, col, blk, wm, stat, near=tol)
    if (stat == MBDK_SUCCESS) call mbdk_constrained_solve(cs, sp, dz, blk, w, b, c, x, mu, stat)
  end subroutine mbdk_constrained_solve_once

end module mbdk_constrained
