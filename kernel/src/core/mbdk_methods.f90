!> The method registry: one id and one spelling per method, with its family and nominal order.
!> The Python registry (python/mbdk/methods.py) reads names and ids from here through the f2py
!> layer, so the spelling exists once.
module mbdk_methods
  implicit none
  private

  integer, parameter, public :: MBDK_FAMILY_EXPLICIT_RK = 1
  integer, parameter, public :: MBDK_FAMILY_EULER_CROMER = 2
  integer, parameter, public :: MBDK_FAMILY_IMPLICIT_LMM = 3
  !> integrates a scene's index-3 DAE itself (mbdk_trapezoidal_index3: the trapezoidal rule and
  !> the generalized-alpha family, one stepping routine with the family's parameters in
  !> mbdk_index3_options), not an ODE y' = F(t, y)
  integer, parameter, public :: MBDK_FAMILY_DAE_INDEX3 = 4
  !> error-controlled (rtol, atol; mbdk_adaptive): embedded Runge-Kutta pairs with dense output
  integer, parameter, public :: MBDK_FAMILY_EMBEDDED_RK = 5
  !> error-controlled: Gear's BDF of variable step and order 1-5 (mbdk_variable_bdf)
  integer, parameter, public :: MBDK_FAMILY_VARIABLE_BDF = 6
  !> error-controlled: SUNDIALS CVODE through its Fortran 2003 interface (mbdk_cvode)
  integer, parameter, public :: MBDK_FAMILY_CVODE = 7
  !> error-controlled, scenes only: SUNDIALS IDA on the scene's DAE (mbdk_ida), index 1 or GGL
  integer, parameter, public :: MBDK_FAMILY_IDA = 8

  integer, parameter, public :: MBDK_EXPLICIT_EULER = 1
  integer, parameter, public :: MBDK_HEUN = 2
  integer, parameter, public :: MBDK_RK4 = 3
  integer, parameter, public :: MBDK_EULER_CROMER = 4
  integer, parameter, public :: MBDK_IMPLICIT_EULER = 5
  integer, parameter, public :: MBDK_TRAPEZOIDAL = 6
  integer, parameter, public :: MBDK_BDF1 = 7   ! bdfk has id MBDK_BDF1 + k - 1
  integer, parameter, public :: MBDK_BDF6 = 12
  integer, parameter, public :: MBDK_TRAPEZOIDAL_INDEX3 = 13
  integer, parameter, public :: MBDK_DOPRI54 = 14
  integer, parameter, public :: MBDK_BS32 = 15
  integer, parameter, public :: MBDK_BDF_VARIABLE = 16
  integer, parameter, public :: MBDK_CVODE_BDF = 17
  integer, parameter, public :: MBDK_CVODE_ADAMS = 18
  integer, parameter, public :: MBDK_IDA = 19
  integer, parameter, public :: MBDK_NEWMARK = 20
  integer, parameter, public :: MBDK_HHT = 21
  integer, parameter, public :: MBDK_GENERALIZED_ALPHA = 22
  integer, parameter, public :: MBDK_METHOD_COUNT = 22
  integer, parameter, public :: MBDK_METHOD_NAME_LEN = 24

  character(len=MBDK_METHOD_NAME_LEN), parameter :: names(MBDK_METHOD_COUNT) = [character( &
    len=MBDK_METHOD_NAME_LEN) :: 'explicit_euler', 'heun', 'rk4', 'euler_cromer', &
    'implicit_euler', 'trapezoidal', 'bdf1', 'bdf2', 'bdf3', 'bdf4', 'bdf5', 'bdf6', &
    'trapezoidal_index3', 'dopri54', 'bs32', 'bdf', 'cvode_bdf', 'cvode_adams', 'ida', &
    'newmark', 'hht', 'generalized_alpha']
  integer, parameter :: families(MBDK_METHOD_COUNT) = [1, 1, 1, 2, 3, 3, 3, 3, 3, 3, 3, 3, 4, &
                                                        5, 5, 6, 7, 7, 8, 4, 4, 4]
  !> the nominal order; for bdf and cvode_* the highest order they select; newmark's with its
  !> default gamma = 1/2 (gamma > 1/2 is first order)
  integer, parameter :: orders(MBDK_METHOD_COUNT) = [1, 2, 4, 1, 1, 2, 1, 2, 3, 4, 5, 6, 2, &
                                                      5, 3, 5, 5, 12, 5, 2, 2, 2]

  public :: mbdk_method_id, mbdk_method_info, mbdk_method_adaptive

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

  !> Whether method id controls its step by rtol/atol (families 5-8) rather than taking h.
  pure logical function mbdk_method_adaptive(id)
    integer, intent(in) :: id
    mbdk_method_adaptive = .false.
    if (id < 1 .or. id > MBDK_METHOD_COUNT) return
    mbdk_method_adaptive = families(id) >= MBDK_FAMILY_EMBEDDED_RK
  end function mbdk_method_adaptive

end module mbdk_methods
