!> The only file that names LAPACK: dense LU factorisation and solve (dgetrf / dgetrs),
!> Cholesky factorisation and solve of symmetric positive definite matrices (dpotrf / dpotrs),
!> the rank-revealing Cholesky factorisation of semidefinite ones (dpstrf),
!> and minimum-norm least squares through the SVD (dgelsd), rank-deficient systems included.
!> Up to MBDK_FIXED_ORDER_MAX unknowns (rows and columns) these are mbdk_fixed_order's instead,
!> written out in one order of operations: the factorisations and solves with LAPACK's
!> algorithms and storage, the least squares by a QR with column pivoting (the same solution
!> for exactly rank-deficient A). The same bits under every OpenBLAS kernel, and faster at
!> these sizes.
module mbdk_lapack
  use mbdk_kinds, only: dp
  use mbdk_memory, only: mbdk_alloc_status, mbdk_count_fits, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_SINGULAR_MATRIX, MBDK_ERR_INVALID_INPUT, &
    MBDK_ERR_NONFINITE, MBDK_ERR_NO_MEMORY
  use mbdk_fixed_order, only: mbdk_fixed_lu_factor, mbdk_fixed_lu_solve, &
    mbdk_fixed_chol_factor, mbdk_fixed_chol_solve, mbdk_fixed_chol_pivoted, &
    mbdk_fixed_least_squares, MBDK_FIXED_ORDER_MAX
  implicit none
  private
  public :: mbdk_lu_factor, mbdk_lu_solve, mbdk_chol_factor, mbdk_chol_solve, &
    mbdk_least_squares, mbdk_chol_pivoted

  interface
    subroutine dgetrf(m, n, a, lda, ipiv, info)
      import :: dp
      integer, intent(in) :: m, n, lda
      real(dp), intent(inout) :: a(lda, *)
      integer, intent(out) :: ipiv(*), info
    end subroutine dgetrf
    subroutine dgetrs(trans, n, nrhs, a, lda, ipiv, b, ldb, info)
      import :: dp
      character(len=1), intent(in) :: trans
      integer, intent(in) :: n, nrhs, lda, ldb
      real(dp), intent(in) :: a(lda, *)
      integer, intent(in) :: ipiv(*)
      real(dp), intent(inout) :: b(ldb, *)
      integer, intent(out) :: info
    end subroutine dgetrs
    subroutine dpotrf(uplo, n, a, lda, info)
      import :: dp
      character(len=1), intent(in) :: uplo
      integer, intent(in) :: n, lda
      real(dp), intent(inout) :: a(lda, *)
      integer, intent(out) :: info
    end subroutine dpotrf
    subroutine dpotrs(uplo, n, nrhs, a, lda, b, ldb, info)
      import :: dp
      character(len=1), intent(in) :: uplo
      integer, intent(in) :: n, nrhs, lda, ldb
      real(dp), intent(in) :: a(lda, *)
      real(dp), intent(inout) :: b(ldb, *)
      integer, intent(out) :: info
    end subroutine dpotrs
    subroutine dpstrf(uplo, n, a, lda, piv, rank, tol, work, info)
      import :: dp
      character(len=1), intent(in) :: uplo
      integer, intent(in) :: n, lda
      real(dp), intent(inout) :: a(lda, *)
      integer, intent(out) :: piv(*), rank, info
      real(dp), intent(in) :: tol
      real(dp), intent(out) :: work(*)
    end subroutine dpstrf
    subroutine dgelsd(m, n, nrhs, a, lda, b, ldb, s, rcond, rank, work, lwork, iwork, info)
      import :: dp
      integer, intent(in) :: m, n, nrhs, lda, ldb, lwork
      real(dp), intent(inout) :: a(lda, *), b(ldb, *)
      real(dp), intent(out) :: s(*), work(*)
      real(dp), intent(in) :: rcond
      integer, intent(out) :: rank, iwork(*), info
    end subroutine dgelsd
  end interface

contains

  !> The minimum-norm x minimising |A x - b| (A m x n, any rank): b(1:m) on entry, x = b(1:n)
  !> on exit (b has max(m, n) entries); rank is the effective rank, rcond its relative
  !> threshold (rcond <= 0 or >= 1: machine precision, as dgelsd takes it). Up to
  !> MBDK_FIXED_ORDER_MAX rows and columns by mbdk_fixed_least_squares (a QR with column
  !> pivoting of A^T, every sum in one order; R's diagonal entries at or below rcond times the
  !> first count as zero), above by LAPACK's dgelsd (singular values at or below rcond times
  !> the largest; A overwritten). Both give the minimum-norm least-squares solution; for rows
  !> near dependent but not exactly, the two rank tests may decide otherwise.
  !> MBDK_ERR_NO_MEMORY when the workspace cannot be had.
  subroutine mbdk_least_squares(a, b, rcond, rank, stat)
    real(dp), intent(inout) :: a(:, :), b(:)
    real(dp), intent(in) :: rcond
    integer, intent(out) :: rank, stat
    integer :: m, n, info, lwork, liwork, astat
    real(dp) :: wq(1)
    integer :: iq(1)
    real(dp), allocatable :: sv(:), work(:), t(:, :), u(:, :), w(:)
    integer, allocatable :: iwork(:), jpvt(:)
    m = size(a, 1)
    n = size(a, 2)
    rank = 0
    stat = MBDK_ERR_INVALID_INPUT
    if (size(b) < max(m, n, 1)) return
    stat = MBDK_SUCCESS
    if (m == 0 .or. n == 0) then
      b(1:n) = 0.0_dp
      return
    end if
    ! refused on both paths: dgelsd scales by the norms of A and b, and a NaN there is an illegal
    ! argument to DLASCL, which LAPACK's error handler reports by printing (and may stop the
    ! process); the QR's pivot choice passes NaN norms over
    if (.not. (all(abs(a) <= huge(1.0_dp)) .and. all(abs(b(1:m)) <= huge(1.0_dp)))) then
      stat = MBDK_ERR_NONFINITE
      return
    end if
    if (max(m, n) <= MBDK_FIXED_ORDER_MAX) then
      allocate (t(n, m), u(m, m + 1), w(3 * m + n), jpvt(m), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (real(n, dp) * m + real(m, dp) * (m + 1) + &
                             3 * m + n) + MBDK_INT_BYTES * m, stat)
      if (stat /= MBDK_SUCCESS) return
      call mbdk_fixed_least_squares(a, m, n, b, &
                                    merge(epsilon(1.0_dp), rcond, rcond <= 0.0_dp .or. &
                                          rcond >= 1.0_dp), rank, t, u, w, jpvt)
      return
    end if
    allocate (sv(min(m, n)), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * min(m, n), stat)
    if (stat /= MBDK_SUCCESS) return
    call dgelsd(m, n, 1, a, m, b, size(b), sv, rcond, rank, wq, -1, iq, info)
    ! a workspace LAPACK's default integers cannot index is refused as such
    stat = MBDK_ERR_NO_MEMORY
    if (.not. mbdk_count_fits(wq(1))) return
    lwork = max(1, int(wq(1)))
    liwork = max(1, iq(1))
    allocate (work(lwork), iwork(liwork), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * lwork + MBDK_INT_BYTES * liwork, stat)
    if (stat /= MBDK_SUCCESS) return
    call dgelsd(m, n, 1, a, m, b, size(b), sv, rcond, rank, work, lwork, iwork, info)
    if (info /= 0) stat = MBDK_ERR_SINGULAR_MATRIX   ! the SVD did not converge
  end subroutine mbdk_least_squares

  !> In-place LU with partial pivoting; MBDK_ERR_SINGULAR_MATRIX when a pivot is exactly zero.
  subroutine mbdk_lu_factor(a, ipiv, stat)
    real(dp), intent(inout) :: a(:, :)
    integer, intent(out) :: ipiv(:)
    integer, intent(out) :: stat
    integer :: info, n
    n = size(a, 1)
    if (n <= MBDK_FIXED_ORDER_MAX) then
      call mbdk_fixed_lu_factor(a, n, ipiv, info)
    else
      call dgetrf(n, n, a, n, ipiv, info)
    end if
    if (info > 0) then
      stat = MBDK_ERR_SINGULAR_MATRIX
    else if (info < 0) then
      stat = MBDK_ERR_INVALID_INPUT
    else
      stat = MBDK_SUCCESS
    end if
  end subroutine mbdk_lu_factor

  !> Solves A x = b with the factors of mbdk_lu_factor; b is overwritten by x.
  subroutine mbdk_lu_solve(lu, ipiv, b, stat)
    real(dp), intent(in) :: lu(:, :)
    integer, intent(in) :: ipiv(:)
    real(dp), intent(inout) :: b(:)
    integer, intent(out) :: stat
    integer :: info, n
    n = size(lu, 1)
    if (n <= MBDK_FIXED_ORDER_MAX) then
      call mbdk_fixed_lu_solve(lu, n, ipiv, b)
      stat = MBDK_SUCCESS
      return
    end if
    call dgetrs('N', n, 1, lu, n, ipiv, b, n, info)
    stat = merge(MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT, info == 0)
  end subroutine mbdk_lu_solve

  !> In-place Cholesky (lower); MBDK_ERR_SINGULAR_MATRIX when A is not positive definite.
  !> last (n), where given: the envelope of the factor for mbdk_chol_solve (column k of L has
  !> no nonzero entry below row last(k); every entry n where n > MBDK_FIXED_ORDER_MAX), defined
  !> where stat is MBDK_SUCCESS.
  subroutine mbdk_chol_factor(a, stat, last)
    real(dp), intent(inout) :: a(:, :)
    integer, intent(out) :: stat
    integer, intent(out), optional :: last(:)
    integer :: info, n
    n = size(a, 1)
    if (n <= MBDK_FIXED_ORDER_MAX) then
      call mbdk_fixed_chol_factor(a, n, info, last)
    else
      if (present(last)) last(1:n) = n
      call dpotrf('L', n, a, n, info)
    end if
    stat = merge(MBDK_SUCCESS, MBDK_ERR_SINGULAR_MATRIX, info == 0)
  end subroutine mbdk_chol_factor

  !> In-place Cholesky with complete pivoting of a symmetric positive semidefinite A (lower):
  !> P^T A P = L L^T with L's first rank columns nonzero, stopping at the first pivot at or
  !> below rtol times A's largest diagonal entry. piv(k): the row of A in position k.
  subroutine mbdk_chol_pivoted(a, piv, rank, rtol, stat)
    real(dp), intent(inout) :: a(:, :)
    integer, intent(out) :: piv(:), rank, stat
    real(dp), intent(in) :: rtol
    real(dp), allocatable :: work(:)
    real(dp) :: big
    integer :: info, n, k
    n = size(a, 1)
    rank = 0
    stat = MBDK_SUCCESS
    if (n == 0) return
    allocate (work(2 * n), stat=k)
    call mbdk_alloc_status(k, 2 * MBDK_REAL_BYTES * n, stat)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_NONFINITE
    if (.not. all(abs(a) <= huge(1.0_dp))) return
    big = a(1, 1)
    do k = 2, n
      big = max(big, a(k, k))
    end do
    stat = MBDK_ERR_SINGULAR_MATRIX
    if (.not. (big > 0.0_dp)) return
    if (n <= MBDK_FIXED_ORDER_MAX) then
      call mbdk_fixed_chol_pivoted(a, n, piv, rank, rtol * big, work, info)
    else
      call dpstrf('L', n, a, n, piv, rank, rtol * big, work, info)
    end if
    stat = merge(MBDK_SUCCESS, MBDK_ERR_SINGULAR_MATRIX, info >= 0)
  end subroutine mbdk_chol_pivoted

  !> Solves A x = b with the factor of mbdk_chol_factor (and its envelope last, where it gave
  !> one); b is overwritten by x.
  subroutine mbdk_chol_solve(l, b, stat, last)
    real(dp), intent(in) :: l(:, :)
    real(dp), intent(inout) :: b(:)
    integer, intent(out) :: stat
    integer, intent(in), optional :: last(:)
    integer :: info, n
    n = size(l, 1)
    if (n <= MBDK_FIXED_ORDER_MAX) then
      call mbdk_fixed_chol_solve(l, n, b, last)
      stat = MBDK_SUCCESS
      return
    end if
    call dpotrs('L', n, 1, l, n, b, n, info)
    stat = merge(MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT, info == 0)
  end subroutine mbdk_chol_solve

end module mbdk_lapack
