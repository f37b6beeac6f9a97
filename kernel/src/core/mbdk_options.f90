!> Options of a fixed-step solve, by name with defaults.
module mbdk_options
  use mbdk_kinds, only: dp
  implicit none
  private

  type, public :: mbdk_options_t
    integer :: method = 0                  !< method id (mbdk_methods)
    real(dp) :: h = 0.0_dp                 !< step size
    integer :: every = 1                   !< keep every k-th step as a sample (the last point always)
    real(dp) :: newton_rtol = 1.0e-10_dp   !< Newton: stop when the weighted RMS of the update < 1
    real(dp) :: newton_atol = 1.0e-12_dp
    integer :: newton_max_iter = 10
    logical :: fd_jacobian = .false.       !< force finite differences even if F has a Jacobian
  end type mbdk_options_t

end module mbdk_options
