! sparse_lu.f90 - mbdk_sparse_ldlt_factor_lu (P A P^T = L D U on LDL's analysis) against LAPACK's
! dense LU of the same matrix: random unsymmetric values on symmetric patterns, a body pattern of
! 6 x 6 blocks (a chain of bodies closed into a loop, as the spatial index-3 matrix's K) and the
! book scheme's [K D^T; D 0] in mbdk_kkt_pattern's order (a zero diagonal in every constraint
! row); the solves agree to roundoff (relative 1e-10), and on symmetric values the L D U is the
! L D L^T of mbdk_sparse_ldlt_factor to roundoff. Refused: a pattern with an entry whose
! transpose is missing or with a duplicate (MBDK_ERR_INVALID_INPUT), a zero pivot
! (MBDK_ERR_SINGULAR_MATRIX), factor_lu without the unsymmetric analysis. Exit code 0 = pass.
program sparse_lu
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_SINGULAR_MATRIX, MBDK_ERR_INVALID_INPUT
  use mbdk_sparse_ldlt
  use mbdk_body_pattern, only: mbdk_body_pattern_t, mbdk_body_pattern_init
  use mbdk_kkt_pattern, only: mbdk_kkt_pattern_init
  use mbdk_lapack, only: mbdk_lu_factor, mbdk_lu_solve
  implicit none
  integer :: failures = 0

  call check_body_pattern()
  call check_kkt()
  call check_refusals()
  if (failures > 0) then
    print '(i0, a)', failures, ' checks failed'
    error stop 1
  end if
  print '(a)', 'all checks passed'

contains

  subroutine check(ok, what)
    logical, intent(in) :: ok
    character(len=*), intent(in) :: what
    if (.not. ok) then
      failures = failures + 1
      print '(2a)', 'FAILED: ', what
    end if
  end subroutine check

  !> 7 bodies in a chain closed by a pair (1, 7)
  subroutine loop_pattern(bp)
    type(mbdk_body_pattern_t), intent(out) :: bp
    integer :: pairs(2, 7), k, stat
    do k = 1, 6
      pairs(:, k) = [k, k + 1]
    end do
    pairs(:, 7) = [1, 7]
    call mbdk_body_pattern_init(bp, 7, pairs, stat, bs=6)
    call check(stat == MBDK_SUCCESS, 'body pattern')
  end subroutine loop_pattern

  !> the dense matrix of a CSC pattern (1-based) and its values
  function dense_of(n, ap, ai, ax) result(a)
    integer, intent(in) :: n, ap(:), ai(:)
    real(dp), intent(in) :: ax(:)
    real(dp) :: a(n, n)
    integer :: j, p
    a = 0.0_dp
    do j = 1, n
      do p = ap(j), ap(j + 1) - 1
        a(ai(p), j) = a(ai(p), j) + ax(p)
      end do
    end do
  end function dense_of

  !> x = A^-1 b by factor_lu (the values f%ax set) against LAPACK's LU of the dense A
  subroutine compare_solves(f, n, ap, ai, what)
    type(mbdk_sparse_ldlt_t), intent(inout) :: f
    integer, intent(in) :: n, ap(:), ai(:)
    character(len=*), intent(in) :: what
    real(dp) :: a(n, n), b(n), x(n), y(n)
    integer :: ipiv(n), stat
    a = dense_of(n, ap, ai, f%ax)
    call random_number(b)
    b = b - 0.5_dp
    x = b
    call mbdk_sparse_ldlt_factor_lu(f, 1.0e-14_dp, stat)
    call check(stat == MBDK_SUCCESS, what // ': factor_lu')
    call mbdk_sparse_ldlt_solve(f, x)
    y = b
    call mbdk_lu_factor(a, ipiv, stat)
    call check(stat == MBDK_SUCCESS, what // ': dense LU')
    call mbdk_lu_solve(a, ipiv, y, stat)
    call check(maxval(abs(x - y)) <= 1.0e-10_dp * maxval(abs(y)), what // ': solve')
  end subroutine compare_solves

  subroutine check_body_pattern()
    type(mbdk_body_pattern_t) :: bp
    type(mbdk_sparse_ldlt_t) :: f
    integer :: stat, j, p, n
    real(dp), allocatable :: r(:), xs(:), xu(:)
    call loop_pattern(bp)
    n = bp%nc
    call mbdk_sparse_ldlt_analyze(f, n, bp%ap, bp%ai, stat, unsymmetric=.true.)
    call check(stat == MBDK_SUCCESS, 'analyze (unsymmetric)')
    ! unsymmetric values, the diagonal dominant
    allocate (r(size(f%ax)), xs(n), xu(n))
    call random_number(r)
    f%ax = r - 0.5_dp
    do j = 1, n
      do p = bp%ap(j), bp%ap(j + 1) - 1
        if (bp%ai(p) == j) f%ax(p) = f%ax(p) + 40.0_dp
      end do
    end do
    call compare_solves(f, n, bp%ap, bp%ai, 'loop pattern, unsymmetric')
    ! symmetric values: L D U is L D L^T
    do p = 1, size(f%ax)
      if (bp%tpos(p) > p) f%ax(bp%tpos(p)) = f%ax(p)
    end do
    call compare_solves(f, n, bp%ap, bp%ai, 'loop pattern, symmetric')
    call random_number(xs)
    xu = xs
    call mbdk_sparse_ldlt_solve(f, xu)
    call mbdk_sparse_ldlt_factor(f, 1.0e-14_dp, stat)
    call check(stat == MBDK_SUCCESS, 'symmetric LDL')
    call mbdk_sparse_ldlt_solve(f, xs)
    call check(maxval(abs(xs - xu)) <= 1.0e-12_dp * maxval(abs(xs)), 'L D U = L D L^T')
  end subroutine check_body_pattern

  subroutine check_kkt()
    type(mbdk_body_pattern_t) :: bp
    type(mbdk_sparse_ldlt_t) :: f
    integer, allocatable :: kpos(:), dpos_r(:), dpos_c(:)
    integer :: rptr(13), rcol(12 * 12), rb(2, 12), stat, r, a, j, n, nd, variant, &
      partner(12), pos(12), pos0(12)
    logical :: moved
    moved = .false.
    pos0 = 0
    call loop_pattern(bp)
    ! 12 rows: a spherical joint's three on each of bodies (0, 1), (1, 2), (3, 4), (7, 1)
    rb = reshape([0, 1, 0, 1, 0, 1, 1, 2, 1, 2, 1, 2, 3, 4, 3, 4, 3, 4, 7, 1, 7, 1, 7, 1], [2, 12])
    nd = 0
    do r = 1, 12
      rptr(r) = nd + 1
      do a = 1, 2
        if (rb(a, r) == 0) cycle
        do j = 1, 6
          nd = nd + 1
          rcol(nd) = 6 * (rb(a, r) - 1) + j
        end do
      end do
    end do
    rptr(13) = nd + 1
    ! without partners, then each joint's first row after its last and the other way round
    ! (rows of one joint have the same columns): in one of the two AMD's order is changed
    do variant = 0, 2
      partner = 0
      do r = 1, 12, 3
        if (variant == 1) partner(r) = r + 2
        if (variant == 2) partner(r + 2) = r
      end do
      if (variant == 0) then
        call mbdk_kkt_pattern_init(bp%ap, bp%ai(1:bp%nnz), rptr, rcol(1:nd), f, kpos, dpos_r, &
                                   dpos_c, stat, unsymmetric=.true.)
      else
        call mbdk_kkt_pattern_init(bp%ap, bp%ai(1:bp%nnz), rptr, rcol(1:nd), f, kpos, dpos_r, &
                                   dpos_c, stat, unsymmetric=.true., partner=partner)
      end if
      call check(stat == MBDK_SUCCESS, 'kkt pattern')
      n = bp%nc + 12
      do r = 1, 12
        pos(r) = f%pinv(bp%nc + r)
        if (partner(r) > 0) call check(pos(r) > f%pinv(bp%nc + partner(r)), &
                                       'a row after its partner')
      end do
      if (variant == 0) pos0 = pos
      if (variant > 0) moved = moved .or. any(pos /= pos0)
      call kkt_values(f, bp, kpos, dpos_r, dpos_c, rptr, rcol(1:nd))
      call compare_solves(f, n, f%ap + 1, f%ai + 1, 'kkt, unsymmetric K')
    end do
    call check(moved, 'partners changed the order')
  end subroutine check_kkt

  !> random K (diagonally dominant) and D values (a translation's identity block and random
  !> rotational ones) into the KKT pattern f
  subroutine kkt_values(f, bp, kpos, dpos_r, dpos_c, rptr, rcol)
    type(mbdk_sparse_ldlt_t), intent(inout) :: f
    type(mbdk_body_pattern_t), intent(in) :: bp
    integer, intent(in) :: kpos(:), dpos_r(:), dpos_c(:), rptr(:), rcol(:)
    integer :: p, c, j, r
    real(dp) :: x
    real(dp), allocatable :: kx(:)
    allocate (kx(bp%nnz))
    call random_number(kx)
    kx = kx - 0.5_dp
    do c = 1, bp%nc
      do p = bp%ap(c), bp%ap(c + 1) - 1
        if (bp%ai(p) == c) kx(p) = kx(p) + 40.0_dp
      end do
    end do
    f%ax = 0.0_dp
    do p = 1, bp%nnz
      f%ax(kpos(p)) = kx(p)
    end do
    do j = 1, size(rcol)
      call random_number(x)
      f%ax(dpos_r(j)) = f%ax(dpos_r(j)) + x - 0.5_dp
      f%ax(dpos_c(j)) = f%ax(dpos_c(j)) + x - 0.5_dp
    end do
    do r = 1, size(rptr) - 1
      do j = rptr(r), rptr(r + 1) - 1
        if (mod(rcol(j) - 1, 6) == mod(r - 1, 3)) then
          f%ax(dpos_r(j)) = f%ax(dpos_r(j)) + 1.0_dp
          f%ax(dpos_c(j)) = f%ax(dpos_c(j)) + 1.0_dp
        end if
      end do
    end do
  end subroutine kkt_values

  subroutine check_refusals()
    type(mbdk_sparse_ldlt_t) :: f
    integer :: stat
    ! (2, 1) without (1, 2)
    call mbdk_sparse_ldlt_analyze(f, 2, [1, 3, 4], [1, 2, 2], stat, unsymmetric=.true.)
    call check(stat == MBDK_ERR_INVALID_INPUT, 'missing transpose refused')
    ! a duplicate (2, 1)
    call mbdk_sparse_ldlt_analyze(f, 2, [1, 4, 6], [1, 2, 2, 1, 2], stat, unsymmetric=.true.)
    call check(stat == MBDK_ERR_INVALID_INPUT, 'duplicate refused')
    ! a zero pivot: [[0, 1], [1, 0]] in the identity order
    call mbdk_sparse_ldlt_analyze(f, 2, [1, 3, 5], [1, 2, 1, 2], stat, order=[1, 2], &
                                  unsymmetric=.true.)
    call check(stat == MBDK_SUCCESS, 'analyze 2 x 2')
    f%ax = [0.0_dp, 1.0_dp, 2.0_dp, 0.0_dp]
    call mbdk_sparse_ldlt_factor_lu(f, 1.0e-14_dp, stat)
    call check(stat == MBDK_ERR_SINGULAR_MATRIX, 'zero pivot refused')
    ! factor_lu on a symmetric analysis
    call mbdk_sparse_ldlt_analyze(f, 2, [1, 3, 5], [1, 2, 1, 2], stat)
    f%ax = [2.0_dp, 1.0_dp, 1.0_dp, 2.0_dp]
    call mbdk_sparse_ldlt_factor_lu(f, 1.0e-14_dp, stat)
    call check(stat == MBDK_ERR_INVALID_INPUT, 'factor_lu needs the unsymmetric analysis')
  end subroutine check_refusals

end program sparse_lu
