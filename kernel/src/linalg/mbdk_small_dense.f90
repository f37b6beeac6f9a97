!> LDL^T factorisations and solves, and the explicit inverse from an LU factor, for the tiny
!> systems of planar mechanisms (the Schur complement D M^-1 D^T of a few constraints, the
!> Newton matrix of trapezoidal_index3), without LAPACK's call overhead (measured against
!> dpotrf/dpotrs and dgetrf/dgetrs in studies/scene_drift.py, table scene_speed, and
!> studies/index3.py); the kernel uses them up to MBDK_SMALL_DENSE_MAX rows unless told
!> otherwise.
!>
!> LDL^T: factor and solve (a matrix serving several solves), or both in one pass
!> (mbdk_small_ldlt_solve_once, one solve: no L is stored or read back).
!> A pivot below tol * (its own row's original diagonal entry) counts as singular: for a Schur
!> complement D W D^T, the part of a row not in the span of the rows before it (the squared sine
!> of its angle to them, in W's metric) below tol, that is dependent (redundant) constraint
!> rows, reported as MBDK_ERR_SINGULAR_MATRIX. Relative to its own row, not to the largest
!> diagonal of A: a joint on a body 1e12 times lighter than another has a diagonal 1e12 times
!> larger without being any closer to dependent, and a fixed joint's angle row (radians) is not
!> measured against its position rows (metres).
!> The LU itself is mbdk_lapack's (mbdk_fixed_order's at these sizes), in LAPACK's storage.
module mbdk_small_dense
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_SINGULAR_MATRIX
  implicit none
  private
  public :: mbdk_small_ldlt_factor, mbdk_small_ldlt_solve, mbdk_small_ldlt_solve_once
  public :: mbdk_small_lu_inverse, mbdk_small_inverse_apply
  integer, parameter, public :: MBDK_SMALL_DENSE_MAX = 12

contains

  !> In place: A = L B L^T, the root-free (block) Cholesky with pivot blocks of 1 to 3 rows:
  !> block k is rows blk(k) .. blk(k+1)-1 (blk(1) = 1, blk(nblk+1) = n+1). With blk = 1..n+1
  !> this is the scalar LDL^T; for a Schur complement D M^-1 D^T the blocks are the joints,
  !> whose rows couple most, and a block costs one division where the scalar form needs one
  !> per row: the critical path of a tiny factorisation is that chain of divisions.
  !> The strict lower triangle outside the pivot blocks becomes that of the unit block-lower
  !> L; each pivot block's lower triangle holds its symmetric inverse (closed form: adjugate
  !> over determinant). Only the lower triangle of A is read.
  !> Singular: a pivot of the scalar LDL^T within a block (the ratio of consecutive leading
  !> minors of the block) at or below tol * (its row's original diagonal entry), or NaN, is
  !> MBDK_ERR_SINGULAR_MATRIX; for a Schur complement that means dependent (redundant)
  !> constraint rows. A block of more than 3 rows is refused as MBDK_ERR_SINGULAR_MATRIX.
  pure subroutine mbdk_small_ldlt_factor(a, n, blk, tol, stat)
    integer, intent(in) :: n, blk(:)
    real(dp), intent(inout) :: a(n, n)
    real(dp), intent(in) :: tol
    integer, intent(out) :: stat
    real(dp) :: unused(1)
    call eliminate(a, n, blk, tol, .true., unused, stat)
  end subroutine mbdk_small_ldlt_factor

  !> Solves L B L^T x = b with the factor of mbdk_small_ldlt_factor (the same blk); b becomes x.
  pure subroutine mbdk_small_ldlt_solve(l, n, blk, b)
    integer, intent(in) :: n, blk(:)
    real(dp), intent(in) :: l(n, n)
    real(dp), intent(inout) :: b(n)
    integer :: i, kb, r0, r1, c, nblk
    real(dp) :: x1, x2, x3
    nblk = size(blk) - 1
    do kb = 1, nblk
      r1 = blk(kb + 1) - 1
      do c = blk(kb), r1
        x1 = b(c)
        do i = r1 + 1, n
          b(i) = b(i) - l(i, c) * x1
        end do
      end do
    end do
    do kb = nblk, 1, -1
      r0 = blk(kb)
      r1 = blk(kb + 1) - 1
      select case (r1 - r0)
      case (0)
        b(r0) = b(r0) * l(r0, r0)
      case (1)
        x1 = b(r0)
        x2 = b(r0 + 1)
        b(r0) = l(r0, r0) * x1 + l(r0 + 1, r0) * x2
        b(r0 + 1) = l(r0 + 1, r0) * x1 + l(r0 + 1, r0 + 1) * x2
      case (2)
        x1 = b(r0)
        x2 = b(r0 + 1)
        x3 = b(r0 + 2)
        b(r0) = l(r0, r0) * x1 + l(r0 + 1, r0) * x2 + l(r0 + 2, r0) * x3
        b(r0 + 1) = l(r0 + 1, r0) * x1 + l(r0 + 1, r0 + 1) * x2 + l(r0 + 2, r0 + 1) * x3
        b(r0 + 2) = l(r0 + 2, r0) * x1 + l(r0 + 2, r0 + 1) * x2 + l(r0 + 2, r0 + 2) * x3
      end select
      do c = r0, r1
        x1 = b(c)
        do i = r1 + 1, n
          x1 = x1 - l(i, c) * b(i)
        end do
        b(c) = x1
      end do
    end do
  end subroutine mbdk_small_ldlt_solve

  !> Solves A x = b for one right-hand side, b becoming x, by the same block LDL^T
  !> elimination as mbdk_small_ldlt_factor (same blk, tol and singular test) without storing
  !> L: the right-hand side is reduced along with the matrix and the back substitution reads
  !> the reduced off-diagonal blocks of A. One pass over A instead of a factorisation and a
  !> solve: what an evaluation that solves once per matrix (the Schur complement of the
  !> reduced accelerations, a projection step) needs. A is overwritten (its pivot blocks by
  !> their inverses).
  pure subroutine mbdk_small_ldlt_solve_once(a, n, blk, tol, b, stat)
    integer, intent(in) :: n, blk(:)
    real(dp), intent(inout) :: a(n, n), b(n)
    real(dp), intent(in) :: tol
    integer, intent(out) :: stat
    integer :: i, kb, r0, r1
    real(dp) :: x1, x2, x3
    call eliminate(a, n, blk, tol, .false., b, stat)
    if (stat /= MBDK_SUCCESS) return
    ! back substitution: x(block) = B^-1 (b(block) - A(below, block)^T x(below))
    do kb = size(blk) - 1, 1, -1
      r0 = blk(kb)
      r1 = blk(kb + 1) - 1
      select case (r1 - r0)
      case (0)
        x1 = b(r0)
        do i = r1 + 1, n
          x1 = x1 - a(i, r0) * b(i)
        end do
        b(r0) = a(r0, r0) * x1
      case (1)
        x1 = b(r0)
        x2 = b(r0 + 1)
        do i = r1 + 1, n
          x1 = x1 - a(i, r0) * b(i)
          x2 = x2 - a(i, r0 + 1) * b(i)
        end do
        b(r0) = a(r0, r0) * x1 + a(r0 + 1, r0) * x2
        b(r0 + 1) = a(r0 + 1, r0) * x1 + a(r0 + 1, r0 + 1) * x2
      case (2)
        x1 = b(r0)
        x2 = b(r0 + 1)
        x3 = b(r0 + 2)
        do i = r1 + 1, n
          x1 = x1 - a(i, r0) * b(i)
          x2 = x2 - a(i, r0 + 1) * b(i)
          x3 = x3 - a(i, r0 + 2) * b(i)
        end do
        b(r0) = a(r0, r0) * x1 + a(r0 + 1, r0) * x2 + a(r0 + 2, r0) * x3
        b(r0 + 1) = a(r0 + 1, r0) * x1 + a(r0 + 1, r0 + 1) * x2 + a(r0 + 2, r0 + 1) * x3
        b(r0 + 2) = a(r0 + 2, r0) * x1 + a(r0 + 2, r0 + 1) * x2 + a(r0 + 2, r0 + 2) * x3
      end select
    end do
  end subroutine mbdk_small_ldlt_solve_once

  !> The block elimination shared by mbdk_small_ldlt_factor (keep_l: L(k, block) =
  !> A(k, block) B^-1 replaces A(k, block)) and mbdk_small_ldlt_solve_once (not keep_l: the
  !> right-hand side b(k) -= L(k, block) b(block) instead, A(k, block) kept for the back
  !> substitution). Pivot blocks inverted in place, trailing update A(i, k) -= A(i, block)
  !> L(k, block)^T for i >= k; the singular test of mbdk_small_ldlt_factor. b is not touched
  !> with keep_l.
  pure subroutine eliminate(a, n, blk, tol, keep_l, b, stat)
    integer, intent(in) :: n, blk(:)
    real(dp), intent(inout) :: a(n, n), b(*)
    real(dp), intent(in) :: tol
    logical, intent(in) :: keep_l
    integer, intent(out) :: stat
    integer :: i, k, kb, r0, nb
    ! the original diagonal, for the pivot test; a fixed size (an automatic array costs a
    ! malloc per call, which is measurable at these sizes). Larger systems, which the callers
    ! do not hand this module, are tested against the largest diagonal entry instead.
    real(dp) :: t(3), l1, l2, l3, d0(MBDK_SMALL_DENSE_MAX), dmax
    stat = MBDK_SUCCESS
    dmax = 0.0_dp
    do i = 1, n
      dmax = max(dmax, a(i, i))
      if (i <= MBDK_SMALL_DENSE_MAX) d0(i) = a(i, i)
    end do
    do kb = 1, size(blk) - 1
      r0 = blk(kb)
      nb = blk(kb + 1) - r0
      if (nb < 1 .or. r0 + nb - 1 > n) then
        stat = MBDK_ERR_SINGULAR_MATRIX
        return
      end if
      if (nb > 3) then
        stat = MBDK_ERR_SINGULAR_MATRIX
        return
      end if
      if (n <= MBDK_SMALL_DENSE_MAX) then
        t(1:nb) = tol * max(d0(r0:r0 + nb - 1), 0.0_dp)
      else
        t(1:nb) = tol * dmax
      end if
      select case (nb)
      case (1)
        call invert1(a, n, r0, t, stat)
        if (stat /= MBDK_SUCCESS) return
        do k = r0 + 1, n
          l1 = a(k, r0) * a(r0, r0)
          do i = k, n
            a(i, k) = a(i, k) - a(i, r0) * l1
          end do
          if (keep_l) then
            a(k, r0) = l1
          else
            b(k) = b(k) - l1 * b(r0)
          end if
        end do
      case (2)
        call invert2(a, n, r0, t, stat)
        if (stat /= MBDK_SUCCESS) return
        do k = r0 + 2, n
          l1 = a(k, r0) * a(r0, r0) + a(k, r0 + 1) * a(r0 + 1, r0)
          l2 = a(k, r0) * a(r0 + 1, r0) + a(k, r0 + 1) * a(r0 + 1, r0 + 1)
          do i = k, n
            a(i, k) = a(i, k) - (a(i, r0) * l1 + a(i, r0 + 1) * l2)
          end do
          if (keep_l) then
            a(k, r0) = l1
            a(k, r0 + 1) = l2
          else
            b(k) = b(k) - (l1 * b(r0) + l2 * b(r0 + 1))
          end if
        end do
      case (3)
        call invert3(a, n, r0, t, stat)
        if (stat /= MBDK_SUCCESS) return
        do k = r0 + 3, n
          l1 = a(k, r0) * a(r0, r0) + a(k, r0 + 1) * a(r0 + 1, r0) + a(k, r0 + 2) * a(r0 + 2, r0)
          l2 = a(k, r0) * a(r0 + 1, r0) + a(k, r0 + 1) * a(r0 + 1, r0 + 1) &
               + a(k, r0 + 2) * a(r0 + 2, r0 + 1)
          l3 = a(k, r0) * a(r0 + 2, r0) + a(k, r0 + 1) * a(r0 + 2, r0 + 1) &
               + a(k, r0 + 2) * a(r0 + 2, r0 + 2)
          do i = k, n
            a(i, k) = a(i, k) - (a(i, r0) * l1 + a(i, r0 + 1) * l2 + a(i, r0 + 2) * l3)
          end do
          if (keep_l) then
            a(k, r0) = l1
            a(k, r0 + 1) = l2
            a(k, r0 + 2) = l3
          else
            b(k) = b(k) - (l1 * b(r0) + l2 * b(r0 + 1) + l3 * b(r0 + 2))
          end if
        end do
      case default
        stat = MBDK_ERR_SINGULAR_MATRIX
        return
      end select
    end do
  end subroutine eliminate

  !> invert1, invert2, invert3: the pivot block a(r0:r0+nb-1, r0:r0+nb-1) (lower triangle)
  !> replaced by its symmetric inverse (adjugate over determinant), with the singular test of
  !> mbdk_small_ldlt_factor: each pivot of the block's scalar LDL^T (ratio of consecutive
  !> leading minors) above t. One small routine per block size, so that gcc inlines them.
  pure subroutine invert1(a, n, r0, t, stat)
    integer, intent(in) :: n, r0
    real(dp), intent(inout) :: a(n, n)
    real(dp), intent(in) :: t(3)
    integer, intent(out) :: stat
    stat = MBDK_ERR_SINGULAR_MATRIX
    if (.not. (a(r0, r0) > t(1))) return
    a(r0, r0) = 1.0_dp / a(r0, r0)
    stat = MBDK_SUCCESS
  end subroutine invert1

  pure subroutine invert2(a, n, r0, t, stat)
    integer, intent(in) :: n, r0
    real(dp), intent(inout) :: a(n, n)
    real(dp), intent(in) :: t(3)
    integer, intent(out) :: stat
    real(dp) :: det, y, c11
    stat = MBDK_ERR_SINGULAR_MATRIX
    if (.not. (a(r0, r0) > t(1))) return
    det = a(r0, r0) * a(r0 + 1, r0 + 1) - a(r0 + 1, r0)**2
    if (.not. (det > t(2) * a(r0, r0))) return
    y = 1.0_dp / det
    c11 = a(r0 + 1, r0 + 1) * y
    a(r0 + 1, r0 + 1) = a(r0, r0) * y
    a(r0, r0) = c11
    a(r0 + 1, r0) = -a(r0 + 1, r0) * y
    stat = MBDK_SUCCESS
  end subroutine invert2

  pure subroutine invert3(a, n, r0, t, stat)
    integer, intent(in) :: n, r0
    real(dp), intent(inout) :: a(n, n)
    real(dp), intent(in) :: t(3)
    integer, intent(out) :: stat
    real(dp) :: c11, c21, c31, c22, c32, c33, det, y
    stat = MBDK_ERR_SINGULAR_MATRIX
    associate (b => a(r0:r0 + 2, r0:r0 + 2))
      if (.not. (b(1, 1) > t(1))) return
      c33 = b(1, 1) * b(2, 2) - b(2, 1)**2
      if (.not. (c33 > t(2) * b(1, 1))) return
      c11 = b(2, 2) * b(3, 3) - b(3, 2)**2
      c21 = b(3, 2) * b(3, 1) - b(2, 1) * b(3, 3)
      c31 = b(2, 1) * b(3, 2) - b(2, 2) * b(3, 1)
      c22 = b(1, 1) * b(3, 3) - b(3, 1)**2
      c32 = b(2, 1) * b(3, 1) - b(1, 1) * b(3, 2)
      det = b(1, 1) * c11 + b(2, 1) * c21 + b(3, 1) * c31
      if (.not. (det > t(3) * c33)) return
      y = 1.0_dp / det
      b(1, 1) = c11 * y
      b(2, 1) = c21 * y
      b(3, 1) = c31 * y
      b(2, 2) = c22 * y
      b(3, 2) = c32 * y
      b(3, 3) = c33 * y
    end associate
    stat = MBDK_SUCCESS
  end subroutine invert3

  !> ainv = A^-1 from an LU factor in LAPACK's storage (mbdk_lu_factor); w(n, n) is a work
  !> array. For a matrix that serves many solves (modified Newton): mbdk_small_inverse_apply
  !> then costs a quarter of an LU solve at n = 10 (a column-oriented product of fixed length n
  !> against two triangular sweeps of varying length). The inverse is formed transposed, as
  !> w = A^-T, so that every operation runs down a contiguous column of w; about one
  !> triangular solve's work per row.
  pure subroutine mbdk_small_lu_inverse(lu, n, ipiv, ainv, w)
    integer, intent(in) :: n, ipiv(n)
    real(dp), intent(in) :: lu(n, n)
    real(dp), intent(out) :: ainv(n, n), w(n, n)
    integer :: i, k, j
    real(dp) :: x
    ! w = (P^T I)^T: the row swaps of the identity become column swaps of w
    w = 0.0_dp
    do i = 1, n
      w(i, i) = 1.0_dp
    end do
    do i = 1, n
      if (ipiv(i) /= i) then
        do j = 1, n
          x = w(j, i)
          w(j, i) = w(j, ipiv(i))
          w(j, ipiv(i)) = x
        end do
      end if
    end do
    ! the forward and backward sweeps of the LU solve, on all n right-hand sides
    do k = 1, n
      do i = k + 1, n
        w(:, i) = w(:, i) - lu(i, k) * w(:, k)
      end do
    end do
    do k = n, 1, -1
      w(:, k) = w(:, k) / lu(k, k)
      do i = 1, k - 1
        w(:, i) = w(:, i) - lu(i, k) * w(:, k)
      end do
    end do
    ainv = transpose(w)
  end subroutine mbdk_small_lu_inverse

  !> b = ainv b for ainv(n, n) (from mbdk_small_lu_inverse); y(n) is a work array.
  pure subroutine mbdk_small_inverse_apply(ainv, n, b, y)
    integer, intent(in) :: n
    real(dp), intent(in) :: ainv(n, n)
    real(dp), intent(inout) :: b(n)
    real(dp), intent(out) :: y(n)
    integer :: k
    y = 0.0_dp
    do k = 1, n
      y = y + ainv(:, k) * b(k)
    end do
    b = y
  end subroutine mbdk_small_inverse_apply

end module mbdk_small_dense
