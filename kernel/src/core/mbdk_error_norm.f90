!> Weighted root-mean-square norm, the convergence measure of the Newton iterations.
module mbdk_error_norm
  use mbdk_kinds, only: dp
  implicit none
  private
  public :: mbdk_wrms

contains

  !> sqrt(mean((v_i / (atol + rtol*|y_i|))**2))
  pure real(dp) function mbdk_wrms(v, y, rtol, atol)
    real(dp), intent(in) :: v(:), y(:), rtol, atol
    mbdk_wrms = sqrt(sum((v / (atol + rtol * abs(y)))**2) / real(max(size(v), 1), dp))
  end function mbdk_wrms

end module mbdk_error_norm
