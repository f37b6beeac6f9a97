! no_memory.f90 - a failed allocation inside the kernel, seen from Fortran (issue 36).
!
! The program limits its own address space (setrlimit RLIMIT_AS to LIMIT bytes; Linux's
! RLIMIT_AS = 9), then asks mbdk_newton_work_init for the Newton work of n = 2^15 unknowns: two
! dense n x n matrices (17 GB) cannot be had, so the status is MBDK_ERR_NO_MEMORY and asked holds
! at least those two matrices' bytes (counted here from n). The same work object is then made
! for n = 100, which succeeds and leaves asked as it was (a success reports no size), and
! mbdk_count_fits refuses a count beyond the default integers. Exit code 0 = pass.
program no_memory
  use, intrinsic :: iso_c_binding, only: c_int, c_long
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_NO_MEMORY
  use mbdk_memory, only: mbdk_count_fits
  use mbdk_newton, only: mbdk_newton_work_t, mbdk_newton_work_init
  implicit none

  interface
    integer(c_int) function setrlimit(resource, rlim) bind(C, name='setrlimit')
      import :: c_int, c_long
      integer(c_int), value :: resource
      integer(c_long), intent(in) :: rlim(2)   ! struct rlimit: rlim_cur, rlim_max
    end function setrlimit
  end interface

  integer(c_int), parameter :: RLIMIT_AS = 9
  integer(c_long), parameter :: LIMIT = 2_c_long**31   ! the program, not the Newton matrix
  type(mbdk_newton_work_t) :: w
  integer :: stat, fails, n
  real(dp) :: asked, matrices

  fails = 0
  if (setrlimit(RLIMIT_AS, [LIMIT, LIMIT]) /= 0) then
    print '(a)', 'FAIL: setrlimit'
    stop 1
  end if

  n = 2**15
  matrices = 2.0_dp * 8.0_dp * real(n, dp)**2
  asked = 0.0_dp
  call mbdk_newton_work_init(w, n, stat, asked)
  call check(stat == MBDK_ERR_NO_MEMORY, 'the Newton work of 2^15 unknowns is MBDK_ERR_NO_MEMORY')
  call check(asked >= matrices .and. asked < 1.01_dp * matrices, &
             'asked: the bytes of the two dense matrices and the vectors')
  print '(6x, a, es10.4, a, es10.4)', 'asked ', asked, ', two matrices ', matrices

  call mbdk_newton_work_init(w, 100, stat, asked)
  call check(stat == MBDK_SUCCESS .and. size(w%jac, 1) == 100, &
             'the same work made for 100 unknowns afterwards')
  call check(asked >= matrices, 'a success leaves asked alone')

  call check(mbdk_count_fits(real(huge(0), dp)) .and. &
             .not. mbdk_count_fits(real(huge(0), dp) + 1.0_dp), &
             'mbdk_count_fits: huge(0) elements fit, one more does not')

  if (fails > 0) then
    print '(a)', 'FAILED'
    stop 1
  end if
  print '(a)', 'all passed'

contains

  subroutine check(ok, what)
    logical, intent(in) :: ok
    character(len=*), intent(in) :: what
    if (ok) then
      print '(a)', 'ok  : ' // what
    else
      print '(a)', 'FAIL: ' // what
      fails = fails + 1
    end if
  end subroutine check

end program no_memory
