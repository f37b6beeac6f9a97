!> The method registry: one id and one spelling per method, with its family and nominal order.
!> The Python registry (python/mbdk/methods.py) reads names and ids from here through the f2py
!> layer, so the spelling exists once.
module mbdk_methods
  implicit none
  private

  integer, parameter, public :: MBDK_FAMILY_EXPLICIT_RK = 1
  integer, parameter, public :: MBDK_FAMILY_EULER_CROMER = 2
  integer, parameter, public :: MBDK_FAMILY_IMPLICIT_LMM = 3
  !> integrates a scene's index-3 DAE itself (mbdk_trapezoidal_index3), not an ODE y' = F(t, y)
  integer, parameter, public :: MBDK_FAMILY_DAE_INDEX3 = 4

  integer, parameter, public :: MBDK_EXPLICIT_EULER = 1
  integer, parameter, public :: MBDK_HEUN = 2
  integer, parameter, public :: MBDK_RK4 = 3
  integer, parameter, public :: MBDK_EULER_CROMER = 4
  integer, parameter, public :: MBDK_IMPLICIT_EULER = 5
  integer, parameter, public :: MBDK_TRAPEZOIDAL = 6
  integer, parameter, public :: MBDK_BDF1 = 7   ! bdfk has id MBDK_BDF1 + k - 1
  integer, parameter, public :: MBDK_BDF6 = 12
  integer, parameter, public :: MBDK_TRAPEZOIDAL_INDEX3 = 13
  integer, parameter, public :: MBDK_METHOD_COUNT = 13
  integer, parameter, public :: MBDK_METHOD_NAME_LEN = 24

  character(len=MBDK_METHOD_NAME_LEN), parameter :: names(MBDK_METHOD_COUNT) = [character( &
    len=MBDK_METHOD_NAME_LEN) :: 'explicit_euler', 'heun', 'rk4', 'euler_cromer', &
    'implicit_euler', 'trapezoidal', 'bdf1', 'bdf2', 'bdf3', 'bdf4', 'bdf5', 'bdf6', &
    'trapezoidal_index3']
  integer, parameter :: families(MBDK_METHOD_COUNT) = [1, 1, 1, 2, 3, 3, 3, 3, 3, 3, 3, 3, 4]
  integer, parameter :: orders(MBDK_METHOD_COUNT) = [1, 2, 4, 1, 1, 2, 1, 2, 3, 4, 5, 6, 2]

  public :: mbdk_method_id, mbdk_method_info

contains

  !> Id of a method name, or 0 if unknown.
  pure integer function mbdk_method_id(name)
    character(len=*), intent(in) :: name
    integer :: i
    mbdk_method_id = 0
    do i = 1, MBDK_METHOD_COUNT
      if (trim(adjustl(name)) == trim(names(i))) then
        mbdk_method_id = i
        return
      end if
    end do
  end function mbdk_method_id

  !> Name, family and nominal order of method id; family = 0 for an unknown id.
  pure subroutine mbdk_method_info(id, name, family, order)
    integer, intent(in) :: id
    character(len=*), intent(out) :: name
    integer, intent(out) :: family, order
    if (id < 1 .or. id > MBDK_METHOD_COUNT) then
      name = ''; family = 0; order = 0
      return
    end if
    name = names(id); family = families(id); order = orders(id)
  end subroutine mbdk_method_info

end module mbdk_methods
