!> fixed_order.f90 - checks mbdk_fixed_order against the LAPACK routines it stands in for, on
!> random matrices of every order it serves (1 to MBDK_FIXED_ORDER_MAX). Exit code 0 = pass.
!>   LU (dgetrf): the same row interchanges, and factors that agree to 64 n eps max|A| max|U|
!>     (the two differ only in the order of their sums); the solve's residual against
!>     64 n^2 eps max|A| max|x|; an exactly singular matrix (its last column zero) gives
!>     info = n, as dgetrf's.
!>   Cholesky (dpotrf 'L') on A = G^T G + I: factors within 64 n eps max|A| of LAPACK's, the
!>     solve's residual as the LU's; a matrix with a negative diagonal entry gives info > 0.
!>   The Cholesky factor and solve of matrices with exact zeros (a band, a loop's blocks closed
!>     on a moving body, scattered zeros, short chains with columns reaching the last row): the
!>     same bits as the full loops, every product taken (the factor and, with its envelope, the
!>     solve skip the products below each column's last nonzero entry), and an envelope that
!>     ends at each column's last nonzero entry. Its zeros are all +0 (a -0 can come out +0
!>     from the full loops and -0 from the envelope).
!>   Pivoted Cholesky (dpstrf 'L', dstop 1e-10 max diag) on A = G^T G with G of rank r < n: the
!>     same rank and pivot order as LAPACK's, and factors within 64 n eps max|A|.
!>   Least squares (dgelsd, rcond eps max(m, n)) with n unknowns: about n/2 independent rows
!>     with one zeroed (a knife edge's in the positions' correction); about 2n/3 rows, a third
!>     of the entries zero, the last two combinations of the others (a redundant joint's), with
!>     a right-hand side they agree on; n rows, two dependent, with one they do not; about
!>     n + 5 rows, two dependent (overdetermined, rank below n where n allows); and A = 0. The
!>     same rank as dgelsd's and a solution within 1e-9 max|x| of it (two algorithms, both of
!>     the minimum-norm least-squares solution).
program fixed_order
  use mbdk_kinds, only: dp, i8
  use test_draws, only: draws_t, fill, fill_v
  use mbdk_fixed_order
  implicit none
  integer, parameter :: NMAX = MBDK_FIXED_ORDER_MAX
  real(dp) :: a(NMAX, NMAX), f(NMAX, NMAX), g(NMAX, NMAX), b(NMAX), x(NMAX), work(2 * NMAX)
  real(dp) :: tol, dstop
  integer :: ipiv(NMAX), ipiv2(NMAX), piv(NMAX), piv2(NMAX), last(NMAX), n, trial, info, &
    info2, r, rank, &
    rank2, i, j, nfail, m
  real(dp) :: t(NMAX, NMAX + 5), u(NMAX + 5, NMAX + 6), w(4 * NMAX + 15), y(NMAX + 5), &
    cmb(NMAX, NMAX)
  real(dp), allocatable :: lsq_work(:)
  integer, allocatable :: lsq_iwork(:)
  integer :: jpvt(NMAX + 5)
  type(draws_t) :: rnd
  external :: dgetrf, dpotrf, dpstrf, dgelsd
  rnd%seed = 4242_i8
  nfail = 0
  allocate (lsq_work(1000000), lsq_iwork(100000))
  do n = 1, NMAX
    do trial = 1, 4
      ! ---- LU ----
      call fill(rnd, a(1:n, 1:n))
      call fill_v(rnd, b(1:n))
      f(1:n, 1:n) = a(1:n, 1:n)
      g(1:n, 1:n) = a(1:n, 1:n)
      call mbdk_fixed_lu_factor(f(1:n, 1:n), n, ipiv(1:n), info)
      call dgetrf(n, n, g(1:n, 1:n), n, ipiv2(1:n), info2)
      call check(info == 0 .and. info2 == 0, 'LU info', n)
      call check(all(ipiv(1:n) == ipiv2(1:n)), 'LU interchanges', n)
      tol = 64 * n * epsilon(1.0_dp) * maxval(abs(a(1:n, 1:n))) * max(1.0_dp, maxval(abs(g(1:n, 1:n))))
      call check(maxval(abs(f(1:n, 1:n) - g(1:n, 1:n))) <= tol, 'LU factors', n)
      x(1:n) = b(1:n)
      call mbdk_fixed_lu_solve(f(1:n, 1:n), n, ipiv(1:n), x(1:n))
      tol = 64 * n * n * epsilon(1.0_dp) * maxval(abs(a(1:n, 1:n))) * maxval(abs(x(1:n)))
      call check(maxval(abs(matmul(a(1:n, 1:n), x(1:n)) - b(1:n))) <= tol, 'LU solve', n)
      f(1:n, 1:n) = a(1:n, 1:n)
      f(1:n, n) = 0.0_dp
      g(1:n, 1:n) = f(1:n, 1:n)
      call mbdk_fixed_lu_factor(f(1:n, 1:n), n, ipiv(1:n), info)
      call dgetrf(n, n, g(1:n, 1:n), n, ipiv2(1:n), info2)
      call check(info == n .and. info2 == n, 'LU singular', n)
      ! ---- Cholesky ----
      call fill(rnd, g(1:n, 1:n))
      a(1:n, 1:n) = matmul(transpose(g(1:n, 1:n)), g(1:n, 1:n))
      do i = 1, n
        a(i, i) = a(i, i) + 1.0_dp
      end do
      f(1:n, 1:n) = a(1:n, 1:n)
      g(1:n, 1:n) = a(1:n, 1:n)
      call mbdk_fixed_chol_factor(f(1:n, 1:n), n, info)
      call dpotrf('L', n, g(1:n, 1:n), n, info2)
      call check(info == 0 .and. info2 == 0, 'Cholesky info', n)
      tol = 64 * n * epsilon(1.0_dp) * maxval(abs(a(1:n, 1:n)))
      call check(maxval(abs(lower(f(1:n, 1:n)) - lower(g(1:n, 1:n)))) <= tol, 'Cholesky factor', n)
      call check(all(f(1:n, 1:n) == g(1:n, 1:n) .or. lower_mask(n)), 'Cholesky upper kept', n)
      call fill_v(rnd, b(1:n))
      x(1:n) = b(1:n)
      call mbdk_fixed_chol_solve(f(1:n, 1:n), n, x(1:n))
      tol = 64 * n * n * epsilon(1.0_dp) * maxval(abs(a(1:n, 1:n))) * maxval(abs(x(1:n)))
      call check(maxval(abs(matmul(a(1:n, 1:n), x(1:n)) - b(1:n))) <= tol, 'Cholesky solve', n)
      f(1:n, 1:n) = a(1:n, 1:n)
      f(n, n) = -1.0_dp
      call mbdk_fixed_chol_factor(f(1:n, 1:n), n, info)
      call check(info == n, 'Cholesky refusal', n)
      ! ---- Cholesky of a matrix with zeros: the same bits as the full loops ----
      call patterned(n, trial)
      f(1:n, 1:n) = a(1:n, 1:n)
      g(1:n, 1:n) = a(1:n, 1:n)
      call mbdk_fixed_chol_factor(f(1:n, 1:n), n, info, last(1:n))
      call full_chol(g(1:n, 1:n), n)
      call check(info == 0, 'patterned Cholesky info', n)
      call check(all(lower(f(1:n, 1:n)) == lower(g(1:n, 1:n))), 'patterned Cholesky bits', n)
      call check(all([(all(f(last(j) + 1:n, j) == 0.0_dp) .and. &
                       (last(j) == j .or. f(last(j), j) /= 0.0_dp), j = 1, n)]), &
                 'patterned Cholesky envelope', n)
      call fill_v(rnd, b(1:n))
      x(1:n) = b(1:n)
      y(1:n) = b(1:n)
      call mbdk_fixed_chol_solve(f(1:n, 1:n), n, x(1:n), last(1:n))
      call full_chol_solve(g(1:n, 1:n), n, y(1:n))
      call check(all(x(1:n) == y(1:n)), 'patterned Cholesky solve bits', n)
      x(1:n) = b(1:n)
      call mbdk_fixed_chol_solve(f(1:n, 1:n), n, x(1:n))
      call check(all(x(1:n) == y(1:n)), 'patterned Cholesky solve bits, no envelope', n)
      ! ---- pivoted Cholesky of a semidefinite matrix of rank r ----
      r = max(1, n - 1 - mod(trial + n, 3))
      call fill(rnd, g(1:r, 1:n))
      a(1:n, 1:n) = matmul(transpose(g(1:r, 1:n)), g(1:r, 1:n))
      dstop = 1.0e-10_dp * maxval([(a(j, j), j = 1, n)])
      f(1:n, 1:n) = a(1:n, 1:n)
      g(1:n, 1:n) = a(1:n, 1:n)
      call mbdk_fixed_chol_pivoted(f(1:n, 1:n), n, piv(1:n), rank, dstop, work(1:2 * n), info)
      call dpstrf('L', n, g(1:n, 1:n), n, piv2(1:n), rank2, dstop, work(1:2 * n), info2)
      call check(rank == rank2 .and. rank == min(r, n) .and. info == info2, 'pivoted rank', n)
      call check(all(piv(1:n) == piv2(1:n)), 'pivoted order', n)
      tol = 64 * n * epsilon(1.0_dp) * maxval(abs(a(1:n, 1:n)))
      call check(maxval(abs(lower(f(1:n, 1:rank)) - lower(g(1:n, 1:rank)))) <= tol, &
                 'pivoted factor', n)
      ! ---- least squares, n unknowns ----
      select case (trial)
      case (1)
        m = max(1, n / 2)
        call fill(rnd, a(1:m, 1:n))
        if (m >= 2) a(2, 1:n) = 0.0_dp
      case (2)
        m = max(1, (2 * n) / 3)
        call dependent_rows(m, n, 2, sparse=.true.)
      case (3)
        m = n
        call dependent_rows(m, n, 2, sparse=.false.)
      case default
        m = min(NMAX, n + 5)
        call dependent_rows(m, n, 2, sparse=.false.)
      end select
      call fill_v(rnd, y(1:n))
      b(1:m) = matmul(a(1:m, 1:n), y(1:n))
      if (trial >= 3) call fill_v(rnd, b(1:m))
      call compare_least_squares(m, n, 'least squares')
      if (trial == 1) then
        a(1:m, 1:n) = 0.0_dp
        call compare_least_squares(m, n, 'least squares of A = 0')
      end if
    end do
  end do
  if (nfail > 0) then
    print '(a, i0, a)', 'fixed_order: ', nfail, ' checks FAILED'
    error stop 1
  end if
  print '(a, i0, a)', 'fixed_order: LU, Cholesky, pivoted Cholesky and least squares agree with ' &
    // 'LAPACK, n = 1..', NMAX, ': PASS'
contains
  !> a(1:n, 1:n) symmetric, diagonally dominant, with exact zeros by kind: 1 a band of
  !> half-width 1 + mod(n, 9); 2 blocks of five rows coupled to the next around a loop (a closed
  !> chain of joints, the last block coupled to the first); 3 zeros scattered off the diagonal;
  !> 4 groups of three rows coupled in a chain, the group's last column reaching the last row
  !> (an envelope that grows and shrinks from column to column, n in every third, so that a
  !> block of four columns must take the longest of them)
  subroutine patterned(n, kind)
    integer, intent(in) :: n, kind
    integer :: i, j, bi, bj, nblk
    logical :: keep
    call fill(rnd, a(1:n, 1:n))
    nblk = (n + 4) / 5
    do j = 1, n
      do i = j + 1, n
        bi = (i - 1) / 5
        bj = (j - 1) / 5
        select case (kind)
        case (1)
          keep = i - j <= 1 + mod(n, 9)
        case (2)
          keep = bi - bj <= 1 .or. (bj == 0 .and. bi == nblk - 1)
        case (3)
          keep = mod(i * j + 2 * i, 3) /= 0
        case default
          keep = (i - j == 1 .and. mod(j, 3) /= 0) .or. (i == n .and. mod(j, 3) == 0)
        end select
        if (.not. keep) a(i, j) = 0.0_dp
        a(j, i) = a(i, j)
      end do
    end do
    do i = 1, n
      a(i, i) = sum(abs(a(1:n, i))) + 1.0_dp
    end do
  end subroutine patterned
  !> LAPACK's unblocked Cholesky (dpotf2 'L') with every product taken, zero or not
  subroutine full_chol(l, n)
    integer, intent(in) :: n
    real(dp), intent(inout) :: l(n, n)
    integer :: i, j, k
    do j = 1, n
      do k = 1, j - 1
        do i = j, n
          l(i, j) = l(i, j) - l(i, k) * l(j, k)
        end do
      end do
      l(j, j) = sqrt(l(j, j))
      do i = j + 1, n
        l(i, j) = l(i, j) / l(j, j)
      end do
    end do
  end subroutine full_chol
  !> its solve (dpotrs 'L'), every product taken
  subroutine full_chol_solve(l, n, v)
    integer, intent(in) :: n
    real(dp), intent(in) :: l(n, n)
    real(dp), intent(inout) :: v(n)
    integer :: i, k
    do k = 1, n
      v(k) = v(k) / l(k, k)
      do i = k + 1, n
        v(i) = v(i) - l(i, k) * v(k)
      end do
    end do
    do k = n, 1, -1
      do i = k + 1, n
        v(k) = v(k) - l(i, k) * v(i)
      end do
      v(k) = v(k) / l(k, k)
    end do
  end subroutine full_chol_solve
  !> a(1:m, 1:n) random with its last k rows combinations of the others (where m > k), a third
  !> of the entries of those others zero if sparse
  subroutine dependent_rows(m, n, k, sparse)
    integer, intent(in) :: m, n, k
    logical, intent(in) :: sparse
    integer :: r, i, j
    r = merge(m - k, m, m > k)
    call fill(rnd, a(1:r, 1:n))
    if (sparse) then
      do j = 1, n
        do i = 1, r
          if (mod(i + 2 * j, 3) == 0) a(i, j) = 0.0_dp
        end do
      end do
    end if
    if (r < m) then
      call fill(rnd, cmb(1:m - r, 1:r))
      a(r + 1:m, 1:n) = matmul(cmb(1:m - r, 1:r), a(1:r, 1:n))
    end if
  end subroutine dependent_rows
  !> mbdk_fixed_least_squares against dgelsd on a(1:m, 1:n), b(1:m)
  subroutine compare_least_squares(m, n, what)
    integer, intent(in) :: m, n
    character(*), intent(in) :: what
    real(dp) :: xf(NMAX + 5), xl(NMAX + 5), tol
    integer :: rank, rank2, info2
    xf = 0.0_dp
    xf(1:m) = b(1:m)
    call mbdk_fixed_least_squares(a(1:m, 1:n), m, n, xf(1:max(m, n)), &
                                  epsilon(1.0_dp) * max(m, n), rank, t(1:n, 1:m), &
                                  u(1:m, 1:m + 1), w(1:3 * m + n), jpvt(1:m))
    g(1:m, 1:n) = a(1:m, 1:n)
    xl = 0.0_dp
    xl(1:m) = b(1:m)
    call dgelsd(m, n, 1, g(1:m, 1:n), m, xl(1:max(m, n)), max(m, n), work, &
                epsilon(1.0_dp) * max(m, n), rank2, lsq_work, size(lsq_work), lsq_iwork, info2)
    call check(info2 == 0 .and. rank == rank2, what // ' rank', n)
    tol = 1.0e-9_dp * max(1.0_dp, maxval(abs(xl(1:n))))
    call check(maxval(abs(xf(1:n) - xl(1:n))) <= tol, what // ' solution', n)
  end subroutine compare_least_squares
  subroutine check(ok, what, n)
    logical, intent(in) :: ok
    character(*), intent(in) :: what
    integer, intent(in) :: n
    if (.not. ok) then
      nfail = nfail + 1
      print '(a, a, a, i0)', 'FAIL ', what, ' at n = ', n
    end if
  end subroutine check
  !> the lower triangle of m (the upper set to zero)
  function lower(m) result(l)
    real(dp), intent(in) :: m(:, :)
    real(dp) :: l(size(m, 1), size(m, 2))
    integer :: i, j
    do j = 1, size(m, 2)
      do i = 1, size(m, 1)
        l(i, j) = merge(m(i, j), 0.0_dp, i >= j)
      end do
    end do
  end function lower
  !> .true. on and below the diagonal
  function lower_mask(n) result(mk)
    integer, intent(in) :: n
    logical :: mk(n, n)
    integer :: i, j
    do j = 1, n
      do i = 1, n
        mk(i, j) = i >= j
      end do
    end do
  end function lower_mask
end program fixed_order
