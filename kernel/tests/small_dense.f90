!> small_dense.f90 - checks the in-house factorisations of mbdk_small_dense against the
!> definitions, on random matrices of every size the kernel uses them for (1 to
!> MBDK_SMALL_DENSE_MAX rows). Exit code 0 = pass.
!>   LU with partial pivoting (mbdk_fixed_order's, whose factor the explicit inverse takes;
!>     general matrices, pivoting needed): the residual of the solve,
!>     max |A x - b| <= 64 n^2 eps max|A| max|x| (the usual n eps |A||x| backward-error bound,
!>     with n for the max norms and 64 as margin), and the explicit inverse, max |A Ainv - I|
!>     <= 64 n^2 eps max|A| max|Ainv|; applying the inverse agrees with the solve to that bound
!>     times max|b|.
!>   Block LDL^T (pivot blocks of 3 rows, as the bodies of trapezoidal_index3's augmented
!>     matrix, of 2 rows, as the revolute joints of a Schur complement, and of 1 row): the
!>     residual of the solve on symmetric positive definite matrices, for factor + solve and
!>     for the one-pass mbdk_small_ldlt_solve_once, which must also agree with factor + solve
!>     within 64 n^2 eps cond(A) max|x| (the forward error the residual bound allows); an
!>     indefinite matrix is refused as MBDK_ERR_SINGULAR_MATRIX by both.
program small_dense
  use mbdk_kinds, only: dp
  use test_draws, only: draws_t, fill, fill_v
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_SINGULAR_MATRIX
  use mbdk_small_dense
  use mbdk_fixed_order, only: mbdk_fixed_lu_factor, mbdk_fixed_lu_solve
  implicit none
  integer, parameter :: NMAX = MBDK_SMALL_DENSE_MAX
  real(dp) :: a(NMAX, NMAX), f(NMAX, NMAX), ainv(NMAX, NMAX), w(NMAX, NMAX), g(NMAX, NMAX)
  real(dp) :: b(NMAX), x(NMAX), y(NMAX), tol
  integer :: ipiv(NMAX), n, trial, stat, i, nfail, k
  integer, allocatable :: blk(:)
  type(draws_t) :: rnd
  nfail = 0
  do n = 1, NMAX
    do trial = 1, 20
      ! ---- LU: a general matrix (entries in [-1, 1]: pivoting happens) ----
      call fill(rnd, a(1:n, 1:n))
      call fill_v(rnd, b(1:n))
      f(1:n, 1:n) = a(1:n, 1:n)
      call mbdk_fixed_lu_factor(f(1:n, 1:n), n, ipiv(1:n), stat)
      if (stat /= 0) cycle          ! (a singular draw: not the point here)
      x(1:n) = b(1:n)
      call mbdk_fixed_lu_solve(f(1:n, 1:n), n, ipiv(1:n), x(1:n))
      tol = 64 * n * epsilon(1.0_dp) * maxval(abs(a(1:n, 1:n))) * maxval(abs(x(1:n))) * n
      call check(maxval(abs(matmul(a(1:n, 1:n), x(1:n)) - b(1:n))) <= tol, 'LU solve', n)
      call mbdk_small_lu_inverse(f(1:n, 1:n), n, ipiv(1:n), ainv(1:n, 1:n), w(1:n, 1:n))
      g(1:n, 1:n) = matmul(a(1:n, 1:n), ainv(1:n, 1:n))
      do i = 1, n
        g(i, i) = g(i, i) - 1.0_dp
      end do
      tol = 64 * n * epsilon(1.0_dp) * maxval(abs(a(1:n, 1:n))) * maxval(abs(ainv(1:n, 1:n))) * n
      call check(maxval(abs(g(1:n, 1:n))) <= tol, 'LU inverse', n)
      y(1:n) = b(1:n)
      call mbdk_small_inverse_apply(ainv(1:n, 1:n), n, y(1:n), w(1:n, 1))
      call check(maxval(abs(y(1:n) - x(1:n))) <= tol * maxval(abs(b(1:n))), 'inverse apply', n)
      ! ---- block LDL^T: symmetric positive definite a = G^T G + I ----
      call fill(rnd, g(1:n, 1:n))
      a(1:n, 1:n) = matmul(transpose(g(1:n, 1:n)), g(1:n, 1:n))
      do i = 1, n
        a(i, i) = a(i, i) + 1.0_dp
      end do
      do k = 1, 3
        select case (k)
        case (1)
          blk = [(i, i = 1, n, 3), n + 1]       ! blocks of 3 rows (the last one shorter)
        case (2)
          blk = [(i, i = 1, n, 2), n + 1]       ! blocks of 2 rows (the joints of a chain)
        case default
          blk = [(i, i = 1, n + 1)]
        end select
        f(1:n, 1:n) = a(1:n, 1:n)
        call mbdk_small_ldlt_factor(f(1:n, 1:n), n, blk, 1.0e-14_dp, stat)
        call check(stat == MBDK_SUCCESS, 'LDL^T of an SPD matrix', n)
        x(1:n) = b(1:n)
        call mbdk_small_ldlt_solve(f(1:n, 1:n), n, blk, x(1:n))
        tol = 64 * n * epsilon(1.0_dp) * maxval(abs(a(1:n, 1:n))) * maxval(abs(x(1:n))) * n
        call check(maxval(abs(matmul(a(1:n, 1:n), x(1:n)) - b(1:n))) <= tol, 'LDL^T solve', n)
        ! the one-pass elimination with the right-hand side: the same residual bound, and the
        ! same solution as factor + solve to roundoff (same pivots, other summation order)
        f(1:n, 1:n) = a(1:n, 1:n)
        y(1:n) = b(1:n)
        call mbdk_small_ldlt_solve_once(f(1:n, 1:n), n, blk, 1.0e-14_dp, y(1:n), stat)
        call check(stat == MBDK_SUCCESS, 'one-pass LDL^T of an SPD matrix', n)
        call check(maxval(abs(matmul(a(1:n, 1:n), y(1:n)) - b(1:n))) <= tol, &
                   'one-pass LDL^T solve', n)
        call check(maxval(abs(y(1:n) - x(1:n))) <= tol * maxval(abs(x(1:n))) &
                   / maxval(abs(b(1:n))), 'one-pass LDL^T = factor + solve', n)
        ! indefinite: the last diagonal entry negated (then the last pivot, a(n,n) minus a
        ! positive semidefinite term, is negative)
        f(1:n, 1:n) = a(1:n, 1:n)
        f(n, n) = -f(n, n)
        call mbdk_small_ldlt_factor(f(1:n, 1:n), n, blk, 1.0e-14_dp, stat)
        call check(stat == MBDK_ERR_SINGULAR_MATRIX, 'LDL^T refuses an indefinite matrix', n)
        f(1:n, 1:n) = a(1:n, 1:n)
        f(n, n) = -f(n, n)
        y(1:n) = b(1:n)
        call mbdk_small_ldlt_solve_once(f(1:n, 1:n), n, blk, 1.0e-14_dp, y(1:n), stat)
        call check(stat == MBDK_ERR_SINGULAR_MATRIX, 'one-pass LDL^T refuses it too', n)
      end do
    end do
  end do
  if (nfail > 0) then
    print '(i0, a)', nfail, ' check(s) FAILED'
    error stop 1
  end if
  print '(a)', 'small_dense: LU solve and inverse, block LDL^T (factor + solve, one pass) and refusal, n = 1..12: PASS'

contains

  subroutine check(ok, what, n)
    logical, intent(in) :: ok
    character(*), intent(in) :: what
    integer, intent(in) :: n
    if (.not. ok) then
      nfail = nfail + 1
      print '(a, a, i0)', what, ' failed at n = ', n
    end if
  end subroutine check

end program small_dense
