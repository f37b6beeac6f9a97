!> Cholesky and LU factorisations and solves for the tiny systems of planar mechanisms (the
!> Schur complement D M^-1 D^T of a few constraints, the Newton matrix of trapezoidal_index3),
!> without LAPACK's call overhead. Measured against dpotrf/dpotrs and dgetrf/dgetrs in
!> studies/scene_benchmark.py and studies/index3.py; the kernel uses them up to
!> MBDK_SMALL_DENSE_MAX rows unless told otherwise.
!>
!> Cholesky: a pivot below tol * (largest diagonal entry of A) counts as singular: for a Schur
!> complement that means dependent (redundant) constraint rows, reported as
!> MBDK_ERR_SINGULAR_MATRIX. LU: partial pivoting as dgetf2; a zero or non-finite pivot is
!> MBDK_ERR_SINGULAR_MATRIX (as dgetrf's info > 0).
module mbdk_small_dense
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_SINGULAR_MATRIX
  implicit none
  private
  public :: mbdk_small_chol_factor, mbdk_small_chol_solve, mbdk_small_lu_factor, mbdk_small_lu_solve
  integer, parameter, public :: MBDK_SMALL_DENSE_MAX = 12

contains

  !> In place: the strict lower triangle of a becomes that of L with A = L L^T, and the diagonal
  !> holds 1 / L(j, j) (so that the solve multiplies instead of dividing).
  pure subroutine mbdk_small_chol_factor(a, n, tol, stat)
    integer, intent(in) :: n
    real(dp), intent(inout) :: a(n, n)
    real(dp), intent(in) :: tol
    integer, intent(out) :: stat
    integer :: i, j, k
    real(dp) :: s, dmax
    dmax = 0.0_dp
    do i = 1, n
      dmax = max(dmax, a(i, i))
    end do
    stat = MBDK_ERR_SINGULAR_MATRIX
    do j = 1, n
      s = a(j, j)
      do k = 1, j - 1
        s = s - a(j, k)**2
      end do
      if (.not. (s > tol * dmax)) return
      a(j, j) = 1.0_dp / sqrt(s)
      do i = j + 1, n
        s = a(i, j)
        do k = 1, j - 1
          s = s - a(i, k) * a(j, k)
        end do
        a(i, j) = s * a(j, j)
      end do
    end do
    stat = MBDK_SUCCESS
  end subroutine mbdk_small_chol_factor

  !> Solves L L^T x = b with the factor of mbdk_small_chol_factor; b is overwritten by x.
  pure subroutine mbdk_small_chol_solve(l, n, b)
    integer, intent(in) :: n
    real(dp), intent(in) :: l(n, n)
    real(dp), intent(inout) :: b(n)
    integer :: i, k
    do i = 1, n
      do k = 1, i - 1
        b(i) = b(i) - l(i, k) * b(k)
      end do
      b(i) = b(i) * l(i, i)
    end do
    do i = n, 1, -1
      do k = i + 1, n
        b(i) = b(i) - l(k, i) * b(k)
      end do
      b(i) = b(i) * l(i, i)
    end do
  end subroutine mbdk_small_chol_solve

  !> In place: A = P L U with unit lower L below the diagonal and U on and above it; ipiv(j) is
  !> the row swapped with row j at step j (as dgetrf), and the diagonal holds 1 / U(j, j).
  pure subroutine mbdk_small_lu_factor(a, n, ipiv, stat)
    integer, intent(in) :: n
    real(dp), intent(inout) :: a(n, n)
    integer, intent(out) :: ipiv(n), stat
    integer :: i, j, k, p
    real(dp) :: amax, x
    stat = MBDK_ERR_SINGULAR_MATRIX
    do j = 1, n
      p = j
      amax = abs(a(j, j))
      do i = j + 1, n
        if (abs(a(i, j)) > amax) then
          amax = abs(a(i, j))
          p = i
        end if
      end do
      ipiv(j) = p
      if (.not. (amax > 0.0_dp .and. amax <= huge(1.0_dp))) return
      if (p /= j) then
        do k = 1, n
          x = a(j, k)
          a(j, k) = a(p, k)
          a(p, k) = x
        end do
      end if
      a(j, j) = 1.0_dp / a(j, j)
      do i = j + 1, n
        a(i, j) = a(i, j) * a(j, j)
      end do
      do k = j + 1, n
        x = a(j, k)
        do i = j + 1, n
          a(i, k) = a(i, k) - a(i, j) * x
        end do
      end do
    end do
    stat = MBDK_SUCCESS
  end subroutine mbdk_small_lu_factor

  !> Solves A x = b with the factor of mbdk_small_lu_factor; b is overwritten by x.
  pure subroutine mbdk_small_lu_solve(lu, n, ipiv, b)
    integer, intent(in) :: n, ipiv(n)
    real(dp), intent(in) :: lu(n, n)
    real(dp), intent(inout) :: b(n)
    integer :: i, k
    real(dp) :: x
    do i = 1, n
      if (ipiv(i) /= i) then
        x = b(i)
        b(i) = b(ipiv(i))
        b(ipiv(i)) = x
      end if
    end do
    do k = 1, n
      x = b(k)
      do i = k + 1, n
        b(i) = b(i) - lu(i, k) * x
      end do
    end do
    do k = n, 1, -1
      b(k) = b(k) * lu(k, k)
      x = b(k)
      do i = 1, k - 1
        b(i) = b(i) - lu(i, k) * x
      end do
    end do
  end subroutine mbdk_small_lu_solve

end module mbdk_small_dense
