!> Whether the rows of a constraint Jacobian lie within a window of a rank loss, measured on
!> the geometry: G = C diag(w) C^T with w weights of the velocity components (a body's rotations
!> as the displacements they give at its own reach, so that neither the unit of length, nor the
!> masses, nor where the mechanism stands sways it), factorised by Cholesky (mbdk_lapack), and
!> each pivot against its own row's diagonal entry (the squared sine of the row's angle to the
!> rows before it, in that metric: invariant to the scale of the row itself, so that an angle
!> row in radians is measured as a position row in metres). Dense: G has one row per
!> constraint row.
module mbdk_rank_margin
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS
  use mbdk_lapack, only: mbdk_chol_factor
  implicit none
  private
  public :: mbdk_near_rank_loss, mbdk_pivots_near

contains

  !> .true. where a relative pivot of C diag(w) C^T is at or below window (or the Cholesky
  !> factorisation fails: the rows are dependent); .false. also where G cannot be allocated.
  logical function mbdk_near_rank_loss(c, w, window) result(near)
    real(dp), intent(in) :: c(:, :), w(:), window
    real(dp), allocatable :: g(:, :), wc(:, :)
    integer :: i, m, st
    near = .false.
    m = size(c, 1)
    if (m == 0) return
    allocate (g(m, m), wc(size(c, 2), m), stat=st)
    if (st /= 0) return
    do i = 1, m
      wc(:, i) = w * c(i, :)
    end do
    g = matmul(c, wc)
    near = mbdk_pivots_near(g, window)
  end function mbdk_near_rank_loss

  !> .true. where a Cholesky pivot of the Gram matrix g (its lower triangle; overwritten by
  !> the factor) is at or below window times its row's diagonal entry, or the factorisation
  !> fails.
  logical function mbdk_pivots_near(g, window) result(near)
    real(dp), intent(inout) :: g(:, :)
    real(dp), intent(in) :: window
    real(dp), allocatable :: diag(:)
    integer :: j, m, st
    near = .true.
    m = size(g, 1)
    allocate (diag(m), stat=st)
    if (st /= 0) return
    do j = 1, m
      diag(j) = g(j, j)
    end do
    call mbdk_chol_factor(g, st)
    if (st /= MBDK_SUCCESS) return
    do j = 1, m
      if (.not. (g(j, j)**2 > window * diag(j))) return
    end do
    near = .false.
  end function mbdk_pivots_near

end module mbdk_rank_margin
