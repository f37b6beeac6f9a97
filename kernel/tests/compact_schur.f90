! compact_schur.f90 - mbdk_compact_schur against the dense product it replaces: random compact rows
! on a chain and on a loop of bodies (rows on two bodies, on a body and the ground), random
! symmetric positive definite W blocks (general, and a rigid body's: diagonal translations, a 3 x 3
! rotational block); S = C W C^T from the compact form equals the dense C W C^T built from the
! same values to roundoff, its solve agrees with LAPACK's dense solve, W C^T x with the dense
! product; a row of zeros is MBDK_ERR_SINGULAR_MATRIX; bad bodies are MBDK_ERR_INVALID_INPUT.
! With an argument N: the instructions' worth of one factorisation on a chain of N spherical
! joints is timed (not a check). Exit code 0 = pass.
program compact_schur
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_SINGULAR_MATRIX, MBDK_ERR_INVALID_INPUT
  use mbdk_compact_schur
  implicit none
  integer :: failures = 0
  character(len=32) :: arg

  if (command_argument_count() > 0) then
    call get_command_argument(1, arg)
    call timing(read_int(arg))
    stop
  end if
  call check_case(nb=7, loop=.false., rigid=.false.)
  call check_case(nb=7, loop=.true., rigid=.false.)
  call check_case(nb=9, loop=.false., rigid=.true.)
  call check_refusals()
  if (failures > 0) then
    print '(i0, a)', failures, ' checks failed'
    error stop 1
  end if
  print '(a)', 'all checks passed'

contains

  integer function read_int(s) result(n)
    character(len=*), intent(in) :: s
    read (s, *) n
  end function read_int

  subroutine check(ok, what)
    logical, intent(in) :: ok
    character(len=*), intent(in) :: what
    if (.not. ok) then
      print '(2a)', 'FAIL: ', what
      failures = failures + 1
    end if
  end subroutine check

  !> rows of a chain of nb bodies (three per joint, joint 1 on the ground), and with loop one
  !> more joint closing body nb to body 1 (three rows)
  subroutine chain_rows(nb, loop, rbody)
    integer, intent(in) :: nb
    logical, intent(in) :: loop
    integer, allocatable, intent(out) :: rbody(:, :)
    integer :: k, r, m
    m = 3 * nb + merge(3, 0, loop)
    allocate (rbody(2, m))
    r = 0
    do k = 1, nb
      rbody(:, r + 1:r + 3) = spread([k, k - 1], 2, 3)
      r = r + 3
    end do
    if (loop) rbody(:, r + 1:r + 3) = spread([nb, 1], 2, 3)
  end subroutine chain_rows

  subroutine blocks(nb, rigid, w)
    integer, intent(in) :: nb
    logical, intent(in) :: rigid
    real(dp), intent(out) :: w(6, 6, nb)
    real(dp) :: a(6, 6)
    integer :: b, i
    do b = 1, nb
      call random_number(a)
      w(:, :, b) = matmul(a, transpose(a))
      do i = 1, 6
        w(i, i, b) = w(i, i, b) + 1.0_dp
      end do
      if (rigid) then
        w(1:3, 4:6, b) = 0.0_dp
        w(4:6, 1:3, b) = 0.0_dp
        w(1, 2:3, b) = 0.0_dp
        w(2, [1, 3], b) = 0.0_dp
        w(3, 1:2, b) = 0.0_dp
      end if
    end do
  end subroutine blocks

  subroutine check_case(nb, loop, rigid)
    integer, intent(in) :: nb
    logical, intent(in) :: loop, rigid
    type(mbdk_compact_schur_t) :: s
    integer, allocatable :: rbody(:, :), ipiv(:)
    real(dp), allocatable :: cc(:, :), c(:, :), wfull(:, :), sd(:, :), x(:), xd(:), dx(:)
    real(dp) :: w(6, 6, nb), tol
    integer :: m, k, a, b, stat, info
    character(len=80) :: label
    write (label, '(a, i0, a, l1, a, l1)') 'nb ', nb, ' loop ', loop, ' rigid ', rigid
    call chain_rows(nb, loop, rbody)
    m = size(rbody, 2)
    allocate (cc(m, 12), c(m, 6 * nb), wfull(6 * nb, 6 * nb), sd(m, m), x(m), xd(m), &
              dx(6 * nb), ipiv(m))
    call random_number(cc)
    cc = cc - 0.5_dp
    call blocks(nb, rigid, w)
    c = 0.0_dp
    wfull = 0.0_dp
    do k = 1, m
      do a = 1, 2
        b = rbody(a, k)
        if (b == 0) then
          cc(k, 6 * a - 5:6 * a) = 0.0_dp       ! the ground's columns are never read
          cycle
        end if
        c(k, 6 * b - 5:6 * b) = cc(k, 6 * a - 5:6 * a)
      end do
    end do
    do b = 1, nb
      wfull(6 * b - 5:6 * b, 6 * b - 5:6 * b) = w(:, :, b)
    end do
    sd = matmul(c, matmul(wfull, transpose(c)))
    call mbdk_compact_schur_init(s, rbody, nb, 6, stat)
    call check(stat == MBDK_SUCCESS, 'init ' // label)
    call mbdk_compact_schur_factor(s, cc, w, 64 * epsilon(1.0_dp), stat, rigid=rigid)
    call check(stat == MBDK_SUCCESS, 'factor ' // label)
    ! S's stored values against the dense product, entry by entry (and the pattern holds every
    ! nonzero: the dense product's entries outside it are zero)
    tol = 64 * epsilon(1.0_dp) * maxval(abs(sd))
    block
      real(dp) :: stored(m, m)
      integer :: j, e
      stored = 0.0_dp
      do j = 1, m
        do e = s%ap(j), s%ap(j + 1) - 1
          stored(s%ai(e), j) = s%ldlt%ax(e)
        end do
      end do
      call check(maxval(abs(stored - sd)) <= tol, 'S = C W C^T ' // label)
    end block
    call random_number(x)
    xd = x
    call mbdk_compact_schur_solve(s, x)
    call dgesv(m, 1, sd, m, ipiv, xd, m, info)
    call check(info == 0 .and. maxval(abs(x - xd)) <= 1e-10_dp * maxval(abs(xd)), &
               'solve ' // label)
    call mbdk_compact_schur_spread(s, x, dx)
    call check(maxval(abs(dx - matmul(wfull, matmul(transpose(c), x)))) <= &
               1e-12_dp * maxval(abs(dx)), 'spread ' // label)
  end subroutine check_case

  subroutine check_refusals()
    type(mbdk_compact_schur_t) :: s
    integer :: rbody(2, 6), stat
    real(dp) :: cc(6, 12), w(6, 6, 2)
    rbody = reshape([1, 0, 1, 0, 1, 0, 2, 1, 2, 1, 2, 1], [2, 6])
    call mbdk_compact_schur_init(s, reshape([1, 1], [2, 1]), 2, 6, stat)
    call check(stat == MBDK_ERR_INVALID_INPUT, 'a row on one body twice')
    call mbdk_compact_schur_init(s, reshape([3, 0], [2, 1]), 2, 6, stat)
    call check(stat == MBDK_ERR_INVALID_INPUT, 'a body beyond nb')
    call mbdk_compact_schur_init(s, rbody, 2, 6, stat)
    call check(stat == MBDK_SUCCESS, 'init of two bodies')
    call random_number(cc)
    cc(4, :) = 0.0_dp
    call blocks(2, .true., w)
    call mbdk_compact_schur_factor(s, cc, w, 64 * epsilon(1.0_dp), stat, rigid=.true.)
    call check(stat == MBDK_ERR_SINGULAR_MATRIX, 'a row of zeros is singular')
  end subroutine check_refusals

  subroutine timing(nb)
    integer, intent(in) :: nb
    type(mbdk_compact_schur_t) :: s
    integer, allocatable :: rbody(:, :)
    real(dp), allocatable :: cc(:, :), w(:, :, :)
    integer :: k, stat
    integer(8) :: t0, t1, rate
    call chain_rows(nb, .false., rbody)
    allocate (cc(size(rbody, 2), 12), w(6, 6, nb))
    call random_number(cc)
    call blocks(nb, .true., w)
    call mbdk_compact_schur_init(s, rbody, nb, 6, stat)
    print '(a, i0, a, i0)', 'rows ', size(rbody, 2), ', stored entries of S ', size(s%ai)
    call system_clock(t0, rate)
    do k = 1, 200
      call mbdk_compact_schur_factor(s, cc, w, 0.0_dp, stat, rigid=.true.)
    end do
    call system_clock(t1)
    print '(a, f10.2, a)', 'factor ', real(t1 - t0, dp) / rate / 200 * 1e6_dp, ' us'
  end subroutine timing

end program compact_schur
