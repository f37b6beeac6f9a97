!> Cholesky factorisation and solve for the tiny symmetric positive definite systems of planar
!> mechanisms (the Schur complement D M^-1 D^T of a few constraints), without LAPACK's call
!> overhead. Measured against dpotrf/dpotrs in studies/scene_benchmark.py; the model uses it up
!> to MBDK_SMALL_DENSE_MAX rows unless told otherwise.
!>
!> A pivot below tol * (largest diagonal entry of A) counts as singular: for a Schur complement
!> that means dependent (redundant) constraint rows, reported as MBDK_ERR_SINGULAR_MATRIX.
module mbdk_small_dense
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_SINGULAR_MATRIX
  implicit none
  private
  public :: mbdk_small_chol_factor, mbdk_small_chol_solve
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

end module mbdk_small_dense
