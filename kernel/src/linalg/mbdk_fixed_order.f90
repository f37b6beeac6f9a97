!> Dense factorisations of LAPACK's unblocked routines (dgetf2, dpotf2, dpstf2) with their
!> solves, and a minimum-norm least squares (dgelsd's solution, by dlaqp2's QR with column
!> pivoting), written out with every sum in one fixed order, for the systems of up to
!> MBDK_FIXED_ORDER_MAX unknowns that mbdk_lapack routes here. Two reasons:
!>   - the same bits on every CPU: OpenBLAS picks the kernels under LAPACK (dgemv, dtrsm,
!>     dswap, ...) by CPU, and they order their sums differently, so a mechanism's Newton
!>     matrix or Schur complement factorised under another kernel moved bdf's steps and where
!>     a run next to a singular pose stopped (tests/test_same_bits.py runs both kinds);
!>   - up to about 64 unknowns the call into LAPACK costs more than the work. From there to
!>     128 LAPACK's blocked LU is faster, and the bound takes that cost for the DAE forms of the
!>     small closed loops (Bricard's linkage, 95 unknowns; the flyball governor, 72), whose runs
!>     it makes the same under every kernel.
!> Each factorisation follows its LAPACK namesake's algorithm, storage and tests: the LU keeps U on
!> and above the diagonal and the unit lower L below it, row j swapped with ipiv(j) at step j
!> (the first largest magnitude in the column, as idamax), and stops at an exactly zero pivot;
!> the Cholesky factorisations read and write the lower triangle only and stop at a pivot that
!> is not positive (or NaN), the unpivoted one keeping to its factor's envelope (the same
!> values: see mbdk_fixed_chol_factor); the pivoted one takes the first largest remaining
!> diagonal entry and stops at one at or below dstop (dpstf2's rule, its running dot products
!> included). The least squares reaches dgelsd's solution by another road (an SVD in fixed
!> order would be far more code): see mbdk_fixed_least_squares. Like LAPACK's, the LU takes a
!> NaN or infinite entry as it comes: a caller that must refuse one tests its matrix
!> (mbdk_index3_matrix's small path does; mbdk_least_squares refuses one before either path).
module mbdk_fixed_order
  use mbdk_kinds, only: dp
  implicit none
  private
  public :: mbdk_fixed_lu_factor, mbdk_fixed_lu_solve, mbdk_fixed_chol_factor, &
    mbdk_fixed_chol_solve, mbdk_fixed_chol_pivoted, mbdk_fixed_least_squares

  !> the largest order mbdk_lapack factorises here (see the module header)
  integer, parameter, public :: MBDK_FIXED_ORDER_MAX = 128

contains

  !> A = P L U in place (dgetf2); info = 0, or j where U(j, j) is exactly zero (the factor is
  !> then incomplete).
  pure subroutine mbdk_fixed_lu_factor(a, n, ipiv, info)
    integer, intent(in) :: n
    real(dp), intent(inout) :: a(n, n)
    integer, intent(out) :: ipiv(n), info
    integer :: i, j, k, p
    real(dp) :: amax, x, r, x0, x1, x2, x3
    info = 0
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
      if (a(p, j) == 0.0_dp) then
        info = j
        return
      end if
      if (p /= j) then
        do k = 1, n
          x = a(j, k)
          a(j, k) = a(p, k)
          a(p, k) = x
        end do
      end if
      if (abs(a(j, j)) >= tiny(1.0_dp)) then
        r = 1.0_dp / a(j, j)
        do i = j + 1, n
          a(i, j) = a(i, j) * r
        end do
      else
        do i = j + 1, n
          a(i, j) = a(i, j) / a(j, j)
        end do
      end if
      ! the trailing update four columns at a pass over column j (each entry still takes its
      ! one product per step, so the sums are those of a column at a time)
      k = j + 1
      do while (k + 3 <= n)
        x0 = a(j, k)
        x1 = a(j, k + 1)
        x2 = a(j, k + 2)
        x3 = a(j, k + 3)
        do i = j + 1, n
          a(i, k) = a(i, k) - a(i, j) * x0
          a(i, k + 1) = a(i, k + 1) - a(i, j) * x1
          a(i, k + 2) = a(i, k + 2) - a(i, j) * x2
          a(i, k + 3) = a(i, k + 3) - a(i, j) * x3
        end do
        k = k + 4
      end do
      do while (k <= n)
        x = a(j, k)
        do i = j + 1, n
          a(i, k) = a(i, k) - a(i, j) * x
        end do
        k = k + 1
      end do
    end do
  end subroutine mbdk_fixed_lu_factor

  !> b <- A^-1 b with the factor of mbdk_fixed_lu_factor (dgetrs, one right-hand side).
  pure subroutine mbdk_fixed_lu_solve(lu, n, ipiv, b)
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
      b(k) = b(k) / lu(k, k)
      x = b(k)
      do i = 1, k - 1
        b(i) = b(i) - lu(i, k) * x
      end do
    end do
  end subroutine mbdk_fixed_lu_solve

  !> A = L L^T in the lower triangle (dpotf2 'L'); info = 0, or j where the leading minor of
  !> order j is not positive definite (-1: n above MBDK_FIXED_ORDER_MAX). Within the envelope
  !> of L: each column k of L is used down to its last nonzero entry only, and the zeros below
  !> it are not divided. A product with a zero leaves an entry as it is, so every value is the
  !> full loops' (a zero's sign aside: -0 - (-0) is +0, where the envelope leaves -0). last(k),
  !> where asked (for mbdk_fixed_chol_solve): column k of L has no nonzero entry below row
  !> last(k); defined where info = 0. The Schur complement of joints along a chain, or around
  !> a loop whose two ends are on the ground (Bricard's), is banded in its rows' order, and
  !> its factor keeps to that band; a loop closed on a moving body fills its columns to the
  !> last row.
  pure subroutine mbdk_fixed_chol_factor(a, n, info, last)
    integer, intent(in) :: n
    real(dp), intent(inout) :: a(n, n)
    integer, intent(out) :: info
    integer, intent(out), optional :: last(:)
    integer :: i, j, k, ie
    ! (a fixed size: gfortran takes an automatic array from the heap, at every call)
    integer :: lst(MBDK_FIXED_ORDER_MAX)
    real(dp) :: ajj, x, x1, x2, x3
    info = -1
    if (n > MBDK_FIXED_ORDER_MAX) return
    info = 0
    do j = 1, n
      ! column j less the columns before it, k = 1 .. j - 1 in turn (down a contiguous column),
      ! four of them at a pass over column j: each entry still takes them one at a time, in
      ! that order, and is loaded and stored once per pass. A column k that ends above row j
      ! has a zero there and does nothing.
      k = 1
      do while (k + 3 <= j - 1)
        x = a(j, k)
        x1 = a(j, k + 1)
        x2 = a(j, k + 2)
        x3 = a(j, k + 3)
        ie = max(lst(k), lst(k + 1), lst(k + 2), lst(k + 3))
        do i = j, ie
          a(i, j) = (((a(i, j) - a(i, k) * x) - a(i, k + 1) * x1) - a(i, k + 2) * x2) - &
                    a(i, k + 3) * x3
        end do
        k = k + 4
      end do
      do k = k, j - 1
        x = a(j, k)
        do i = j, lst(k)
          a(i, j) = a(i, j) - a(i, k) * x
        end do
      end do
      ajj = a(j, j)
      if (.not. (ajj > 0.0_dp)) then
        info = j
        return
      end if
      ajj = sqrt(ajj)
      a(j, j) = ajj
      ! (divided down to the last nonzero entry: a zero divided is the same zero, and a
      ! division costs more than the rest of a banded factor's work per entry)
      lst(j) = j
      do i = n, j + 1, -1
        if (a(i, j) /= 0.0_dp) then
          lst(j) = i
          exit
        end if
      end do
      do i = j + 1, lst(j)
        a(i, j) = a(i, j) / ajj
      end do
    end do
    if (present(last)) last(1:n) = lst(1:n)
  end subroutine mbdk_fixed_chol_factor

  !> b <- A^-1 b with the factor of mbdk_fixed_chol_factor (dpotrs 'L', one right-hand side);
  !> with that factor's last, each column of L down to last(k) only: the full loops' values
  !> (a zero's sign aside, and a non-finite b spreads only where L has entries), and the back
  !> substitution's chain of dependent products shorter by the zeros.
  pure subroutine mbdk_fixed_chol_solve(l, n, b, last)
    integer, intent(in) :: n
    real(dp), intent(in) :: l(n, n)
    real(dp), intent(inout) :: b(n)
    integer, intent(in), optional :: last(:)
    integer :: i, k, ie
    real(dp) :: x
    do k = 1, n
      b(k) = b(k) / l(k, k)
      x = b(k)
      ie = n
      if (present(last)) ie = last(k)
      do i = k + 1, ie
        b(i) = b(i) - l(i, k) * x
      end do
    end do
    do k = n, 1, -1
      x = b(k)
      ie = n
      if (present(last)) ie = last(k)
      do i = k + 1, ie
        x = x - l(i, k) * b(i)
      end do
      b(k) = x / l(k, k)
    end do
  end subroutine mbdk_fixed_chol_solve

  !> P^T A P = L L^T in the lower triangle with complete pivoting (dpstf2 'L'): piv(k) the row
  !> of A in position k, rank the pivots taken; it stops at the first largest remaining
  !> diagonal entry at or below dstop, or NaN (info = 1, that entry left in A(rank+1, rank+1)),
  !> and at a largest diagonal entry of A not positive (rank 0, info = 1). work(2 n).
  pure subroutine mbdk_fixed_chol_pivoted(a, n, piv, rank, dstop, work, info)
    integer, intent(in) :: n
    real(dp), intent(inout) :: a(n, n)
    integer, intent(out) :: piv(n), rank, info
    real(dp), intent(in) :: dstop
    real(dp), intent(out) :: work(2 * n)
    integer :: i, j, k, p, itmp
    real(dp) :: ajj, x
    do i = 1, n
      piv(i) = i
    end do
    info = 0
    rank = 0
    if (n == 0) return
    p = first_max([(a(i, i), i = 1, n)])
    ajj = a(p, p)
    if (.not. (ajj > 0.0_dp)) then
      info = 1
      return
    end if
    work(1:n) = 0.0_dp
    do j = 1, n
      do i = j, n
        if (j > 1) work(i) = work(i) + a(i, j - 1)**2
        work(n + i) = a(i, i) - work(i)
      end do
      if (j > 1) then
        p = j - 1 + first_max(work(n + j:2 * n))
        ajj = work(n + p)
        if (ajj <= dstop .or. ajj /= ajj) then
          a(j, j) = ajj
          rank = j - 1
          info = 1
          return
        end if
      end if
      if (j /= p) then
        a(p, p) = a(j, j)
        do k = 1, j - 1
          x = a(j, k)
          a(j, k) = a(p, k)
          a(p, k) = x
        end do
        do k = p + 1, n
          x = a(k, j)
          a(k, j) = a(k, p)
          a(k, p) = x
        end do
        do k = j + 1, p - 1
          x = a(k, j)
          a(k, j) = a(p, k)
          a(p, k) = x
        end do
        x = work(j)
        work(j) = work(p)
        work(p) = x
        itmp = piv(p)
        piv(p) = piv(j)
        piv(j) = itmp
      end if
      ajj = sqrt(ajj)
      a(j, j) = ajj
      do k = 1, j - 1
        x = a(j, k)
        do i = j + 1, n
          a(i, j) = a(i, j) - a(i, k) * x
        end do
      end do
      do i = j + 1, n
        a(i, j) = a(i, j) / ajj
      end do
    end do
    rank = n
  end subroutine mbdk_fixed_chol_pivoted

  !> The minimum-norm x minimising |A x - b| for A (m x n) of any rank: dgelsd's solution for
  !> an A of exact rank (redundant joints), reached another way; rows near dependent but not
  !> exactly may be ranked otherwise than by its singular values. A^T P = Q R by Householder
  !> reflectors with column pivoting (dlaqp2:
  !> the first largest remaining column norm, norms downdated, and recomputed where the
  !> downdate has lost half the digits); the rank is the number of leading |R(i, i)| above
  !> rcond |R(1, 1)| (rank 0: x = 0). Then x = Q1 z lies in the range of A^T, and z minimises
  !> |R1^T z - P^T b| (R1 the first rank rows of R; an m x rank problem of full column rank, by
  !> an unpivoted Householder QR): that is the minimum-norm least-squares solution, whether
  !> the rows of A (A's dependent rows, a redundant joint's) agree or not. b(1:m) on entry,
  !> x = b(1:n) on exit (b has max(m, n) entries). Scratch: t (n x m), u (m x (m + 1)),
  !> w (3 m + n), jpvt (m).
  pure subroutine mbdk_fixed_least_squares(a, m, n, b, rcond, rank, t, u, w, jpvt)
    integer, intent(in) :: m, n
    real(dp), intent(in) :: a(m, n), rcond
    real(dp), intent(inout) :: b(:)
    integer, intent(out) :: rank, jpvt(m)
    real(dp), intent(out) :: t(n, m), u(m, m + 1), w(3 * m + n)
    integer :: i, j, k, p, itmp
    real(dp) :: temp, temp2, x
    ! w: vn1 (m), vn2 (m), tau (m, first min(m, n) used), then the solution's n entries
    associate (vn1 => w(1:m), vn2 => w(m + 1:2 * m), tau => w(2 * m + 1:3 * m), &
               xs => w(3 * m + 1:3 * m + n))
      t = transpose(a)
      do j = 1, m
        jpvt(j) = j
        vn1(j) = norm2(t(:, j))
        vn2(j) = vn1(j)
      end do
      k = min(m, n)
      do i = 1, k
        p = i - 1 + first_max(vn1(i:m))
        if (p /= i) then
          do j = 1, n
            x = t(j, p)
            t(j, p) = t(j, i)
            t(j, i) = x
          end do
          itmp = jpvt(p)
          jpvt(p) = jpvt(i)
          jpvt(i) = itmp
          vn1(p) = vn1(i)
          vn2(p) = vn2(i)
        end if
        call reflect(t(i:n, i), tau(i))
        call apply_reflector(t(i:n, i), tau(i), t(i:n, i + 1:m))
        do j = i + 1, m
          if (vn1(j) == 0.0_dp) cycle
          temp = max(0.0_dp, 1.0_dp - (abs(t(i, j)) / vn1(j))**2)
          temp2 = temp * (vn1(j) / vn2(j))**2
          if (temp2 <= sqrt(0.5_dp * epsilon(1.0_dp))) then     ! dlaqp2's tol3z
            if (i < n) then
              vn1(j) = norm2(t(i + 1:n, j))
            else
              vn1(j) = 0.0_dp
            end if
            vn2(j) = vn1(j)
          else
            vn1(j) = vn1(j) * sqrt(temp)
          end if
        end do
      end do
      rank = 0
      do i = 1, k
        if (.not. (abs(t(i, i)) > rcond * abs(t(1, 1)))) exit
        rank = i
      end do
      xs = 0.0_dp
      if (rank > 0) then
        ! z: the least squares of R1^T z = P^T b, in u (m x rank) and b's permuted copy
        u(:, 1:rank) = 0.0_dp
        do i = 1, rank
          do j = i, m
            u(j, i) = t(i, j)
          end do
        end do
        do j = 1, m
          u(j, rank + 1) = b(jpvt(j))
        end do
        do i = 1, rank
          call reflect(u(i:m, i), temp)
          call apply_reflector(u(i:m, i), temp, u(i:m, i + 1:rank + 1))
        end do
        do i = rank, 1, -1
          x = u(i, rank + 1)
          do j = i + 1, rank
            x = x - u(i, j) * xs(j)
          end do
          xs(i) = x / u(i, i)
        end do
        ! x = H(1) ... H(rank) [z; 0]
        do i = rank, 1, -1
          call apply_reflector_v(t(i:n, i), tau(i), xs(i:n))
        end do
      end if
      b(1:n) = xs
    end associate
  end subroutine mbdk_fixed_least_squares

  !> dlarfg on x: H = I - tau v v^T with v = [1; x(2:)] (returned in x(2:)) takes x to
  !> [beta; 0] (beta in x(1)), beta = -sign(|x|, x(1)); tau = 0 (H = I) where x(2:) is zero.
  pure subroutine reflect(x, tau)
    real(dp), intent(inout) :: x(:)
    real(dp), intent(out) :: tau
    real(dp) :: beta
    tau = 0.0_dp
    if (size(x) < 2) return
    if (all(x(2:) == 0.0_dp)) return
    beta = -sign(norm2(x), x(1))
    tau = (beta - x(1)) / beta
    x(2:) = x(2:) / (x(1) - beta)
    x(1) = beta
  end subroutine reflect

  !> c <- H c for each column of c, H = I - tau v v^T, v = [1; x(2:)] (dlarf from the left).
  pure subroutine apply_reflector(x, tau, c)
    real(dp), intent(in) :: x(:), tau
    real(dp), intent(inout) :: c(:, :)
    integer :: j
    do j = 1, size(c, 2)
      call apply_reflector_v(x, tau, c(:, j))
    end do
  end subroutine apply_reflector

  !> c <- H c for one vector c (apply_reflector's column).
  pure subroutine apply_reflector_v(x, tau, c)
    real(dp), intent(in) :: x(:), tau
    real(dp), intent(inout) :: c(:)
    real(dp) :: s
    integer :: l
    if (tau == 0.0_dp) return
    s = c(1)
    do l = 2, size(x)
      s = s + x(l) * c(l)
    end do
    s = tau * s
    c(1) = c(1) - s
    do l = 2, size(x)
      c(l) = c(l) - s * x(l)
    end do
  end subroutine apply_reflector_v

  !> The index of the first largest entry of x (MAXLOC's choice; NaN entries are passed over).
  pure integer function first_max(x)
    real(dp), intent(in) :: x(:)
    integer :: i
    first_max = 1
    do i = 2, size(x)
      if (x(i) > x(first_max) .or. x(first_max) /= x(first_max)) first_max = i
    end do
  end function first_max

end module mbdk_fixed_order
