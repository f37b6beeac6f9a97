!> Weighted root-mean-square norm, the convergence measure of the Newton iterations.
module mbdk_error_norm
  use mbdk_kinds, only: dp
  implicit none
  private
  public :: mbdk_wrms

contains

  !> sqrt(mean((v_i / (atol + rtol*|y_i|))**2)); with floor, the weights are never below it
  !> (a Newton iteration's roundoff floor, mbdk_newton_floor)
  pure real(dp) function mbdk_wrms(v, y, rtol, atol, floor)
    real(dp), intent(in) :: v(:), y(:), rtol, atol
    real(dp), intent(in), optional :: floor(:)
    if (present(floor)) then
      mbdk_wrms = sqrt(sum((v / max(atol + rtol * abs(y), floor))**2) / real(max(size(v), 1), dp))
    else
      mbdk_wrms = sqrt(sum((v / (atol + rtol * abs(y)))**2) / real(max(size(v), 1), dp))
    end if
  end function mbdk_wrms

end module mbdk_error_norm
