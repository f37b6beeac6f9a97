!> Butcher tableaux of the explicit Runge-Kutta methods, as data.
!>
!>   explicit_euler  order 1, 1 stage   (4.6)  y+ = y + h F(t, y)
!>   heun            order 2, 2 stages  (4.23) the book's RK2: average of the slopes at both ends
!>   rk4             order 4, 4 stages  (4.24) classic Runge-Kutta
!>
!> Reference: Fekete (2023) section 4.1; Hairer, Norsett, Wanner, Solving ODE I, II.1.
!> The order conditions of these tables are checked in tests/test_method_data.py.
module mbdk_butcher
  use mbdk_kinds, only: dp
  use mbdk_methods, only: MBDK_EXPLICIT_EULER, MBDK_HEUN, MBDK_RK4
  implicit none
  private

  integer, parameter, public :: MBDK_MAX_STAGES = 4

  type, public :: mbdk_butcher_t
    integer :: stages = 0
    integer :: order = 0
    real(dp) :: a(MBDK_MAX_STAGES, MBDK_MAX_STAGES) = 0.0_dp
    real(dp) :: b(MBDK_MAX_STAGES) = 0.0_dp
    real(dp) :: c(MBDK_MAX_STAGES) = 0.0_dp
  end type mbdk_butcher_t

  public :: mbdk_butcher_table

contains

  !> The tableau of method id; ok = .false. if id is not an explicit Runge-Kutta method.
  pure subroutine mbdk_butcher_table(id, tab, ok)
    integer, intent(in) :: id
    type(mbdk_butcher_t), intent(out) :: tab
    logical, intent(out) :: ok
    ok = .true.
    select case (id)
    case (MBDK_EXPLICIT_EULER)
      tab%stages = 1; tab%order = 1
      tab%b(1) = 1.0_dp
    case (MBDK_HEUN)
      tab%stages = 2; tab%order = 2
      tab%a(2, 1) = 1.0_dp
      tab%b(1:2) = [0.5_dp, 0.5_dp]
      tab%c(1:2) = [0.0_dp, 1.0_dp]
    case (MBDK_RK4)
      tab%stages = 4; tab%order = 4
      tab%a(2, 1) = 0.5_dp
      tab%a(3, 2) = 0.5_dp
      tab%a(4, 3) = 1.0_dp
      tab%b = [1.0_dp, 2.0_dp, 2.0_dp, 1.0_dp] / 6.0_dp
      tab%c = [0.0_dp, 0.5_dp, 0.5_dp, 1.0_dp]
    case default
      ok = .false.
    end select
  end subroutine mbdk_butcher_table

end module mbdk_butcher
