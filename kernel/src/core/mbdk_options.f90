!> Options of a fixed-step solve, by name with defaults.
module mbdk_options
  use mbdk_kinds, only: dp
  implicit none
  private

  !> Start-up of a k-step method: RK4 steps of the same h (the book, (4.80)), or BDF steps of
  !> rising order 1, 2, ..., k-1 (self-starting, stable on stiff problems where RK4 is not).
  integer, parameter, public :: MBDK_STARTUP_RK4 = 0
  integer, parameter, public :: MBDK_STARTUP_BDF = 1

  type, public :: mbdk_options_t
    integer :: method = 0                  !< method id (mbdk_methods)
    real(dp) :: h = 0.0_dp                 !< step size
    integer :: every = 1                   !< keep every k-th step as a sample (the last point always)
    real(dp) :: newton_rtol = 1.0e-10_dp   !< Newton: stop when the weighted RMS of the update < 1
    real(dp) :: newton_atol = 1.0e-12_dp
    integer :: newton_max_iter = 10
    logical :: fd_jacobian = .false.       !< force finite differences even if F has a Jacobian
    integer :: startup = MBDK_STARTUP_RK4  !< how a k-step method gets its first k-1 values
  end type mbdk_options_t

end module mbdk_options
