!> The time functions of scenes (driven coordinates, time-varying loads):
!>
!>   f(t) = c(1) + c(2) t + c(3) sin(c(4) t + c(5))      (offset, rate, amplitude, omega, phase)
!>
!> with its first and second derivatives. A constant is (value, 0, 0, 0, 0).
module mbdk_time_function
  use mbdk_kinds, only: dp
  implicit none
  private
  public :: mbdk_time_fn

contains

  pure subroutine mbdk_time_fn(c, t, f, fd, fdd)
    real(dp), intent(in) :: c(5), t
    real(dp), intent(out) :: f, fd, fdd
    real(dp) :: s, co
    s = sin(c(4) * t + c(5))
    co = cos(c(4) * t + c(5))
    f = c(1) + c(2) * t + c(3) * s
    fd = c(2) + c(3) * c(4) * co
    fdd = -c(3) * c(4)**2 * s
  end subroutine mbdk_time_fn

end module mbdk_time_function
