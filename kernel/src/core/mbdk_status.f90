!> The one table of status codes. Mirrored by kernel/include/mbdk.h and python/mbdk/errors.py;
!> tests/test_status.py checks that the three agree.
!>
!>   0      success
!>   > 0    success with a note (the result is complete and usable)
!>   < 0    failure, grouped by cause: -1..-9 invalid input, -10..-19 step control,
!>          -20..-29 nonlinear / linear algebra, -30..-39 solution, -40..-49 user callback,
!>          -50..-59 backends (SUNDIALS), -60..-69 the caller
!>
!> The kernel never prints and never stops the process: every public routine returns one of these.
module mbdk_status
  implicit none
  private

  integer, parameter, public :: MBDK_SUCCESS = 0
  integer, parameter, public :: MBDK_NOTE_LAST_STEP_SHORTENED = 1
  integer, parameter, public :: MBDK_ERR_INVALID_INPUT = -1
  integer, parameter, public :: MBDK_ERR_UNKNOWN_METHOD = -2
  integer, parameter, public :: MBDK_ERR_UNKNOWN_PROBLEM = -3
  integer, parameter, public :: MBDK_ERR_NOT_APPLICABLE = -4
  integer, parameter, public :: MBDK_ERR_OUTPUT_SIZE = -5
  integer, parameter, public :: MBDK_ERR_INCONSISTENT_INITIAL = -6
  integer, parameter, public :: MBDK_ERR_NO_MEMORY = -7
  integer, parameter, public :: MBDK_ERR_STEP_TOO_SMALL = -10
  integer, parameter, public :: MBDK_ERR_TOO_MANY_STEPS = -11
  integer, parameter, public :: MBDK_ERR_TOO_MUCH_ACCURACY = -12
  integer, parameter, public :: MBDK_ERR_NEWTON_DIVERGED = -20
  integer, parameter, public :: MBDK_ERR_SINGULAR_MATRIX = -21
  integer, parameter, public :: MBDK_ERR_NONFINITE = -30
  integer, parameter, public :: MBDK_ERR_CONSTRAINT_DRIFT = -31
  integer, parameter, public :: MBDK_ERR_ENERGY_DRIFT = -32
  integer, parameter, public :: MBDK_ERR_CONTACT_OVERRUN = -33
  integer, parameter, public :: MBDK_ERR_INVARIANT_DRIFT = -34
  integer, parameter, public :: MBDK_ERR_CALLBACK_FAILED = -40
  integer, parameter, public :: MBDK_ERR_BACKEND = -50
  integer, parameter, public :: MBDK_ERR_INTERRUPTED = -60

  integer, parameter, public :: MBDK_STATUS_COUNT = 22
  integer, parameter, public :: MBDK_STATUS_NAME_LEN = 32
  integer, parameter, public :: MBDK_STATUS_MSG_LEN = 120

  type :: status_entry
    integer :: code
    character(len=MBDK_STATUS_NAME_LEN) :: name
    character(len=MBDK_STATUS_MSG_LEN) :: message
  end type status_entry

  type(status_entry), parameter :: table(MBDK_STATUS_COUNT) = [ &
    status_entry(MBDK_SUCCESS, 'SUCCESS', 'success'), &
    status_entry(MBDK_NOTE_LAST_STEP_SHORTENED, 'NOTE_LAST_STEP_SHORTENED', &
      'success; the interval is not a whole number of steps, so the last step was shortened'), &
    status_entry(MBDK_ERR_INVALID_INPUT, 'ERR_INVALID_INPUT', &
      'invalid input: a size, step, interval or option is out of range'), &
    status_entry(MBDK_ERR_UNKNOWN_METHOD, 'ERR_UNKNOWN_METHOD', 'unknown method id or name'), &
    status_entry(MBDK_ERR_UNKNOWN_PROBLEM, 'ERR_UNKNOWN_PROBLEM', 'unknown problem id or name'), &
    status_entry(MBDK_ERR_NOT_APPLICABLE, 'ERR_NOT_APPLICABLE', &
      'the method does not apply to this problem (e.g. euler_cromer needs a second-order system)'), &
    status_entry(MBDK_ERR_OUTPUT_SIZE, 'ERR_OUTPUT_SIZE', &
      'the output arrays are too small for the requested samples'), &
    status_entry(MBDK_ERR_INCONSISTENT_INITIAL, 'ERR_INCONSISTENT_INITIAL', &
      'the initial state cannot be made to satisfy the constraints (assembly failed)'), &
    status_entry(MBDK_ERR_NO_MEMORY, 'ERR_NO_MEMORY', &
      'the memory this run needs could not be allocated; fewer samples or a smaller model'), &
    status_entry(MBDK_ERR_STEP_TOO_SMALL, 'ERR_STEP_TOO_SMALL', 'the step size became too small'), &
    status_entry(MBDK_ERR_TOO_MANY_STEPS, 'ERR_TOO_MANY_STEPS', &
      'error control took max_steps steps before t_end; loosen rtol/atol or raise max_steps'), &
    status_entry(MBDK_ERR_TOO_MUCH_ACCURACY, 'ERR_TOO_MUCH_ACCURACY', &
      'the tolerances ask for more accuracy than double precision gives; loosen rtol/atol'), &
    status_entry(MBDK_ERR_NEWTON_DIVERGED, 'ERR_NEWTON_DIVERGED', &
      'Newton-Raphson iteration did not converge; reduce the step h'), &
    status_entry(MBDK_ERR_SINGULAR_MATRIX, 'ERR_SINGULAR_MATRIX', &
      'a singular linear system: a Newton matrix, or D M^-1 D^T where constraints are dependent'), &
    status_entry(MBDK_ERR_NONFINITE, 'ERR_NONFINITE', &
      'the solution overflowed to inf or NaN (the method is unstable at this step); reduce h'), &
    status_entry(MBDK_ERR_CONSTRAINT_DRIFT, 'ERR_CONSTRAINT_DRIFT', &
      'the state left the constraint manifold beyond the run''s tolerance'), &
    status_entry(MBDK_ERR_ENERGY_DRIFT, 'ERR_ENERGY_DRIFT', &
      'the energy balance was broken beyond the run''s tolerance'), &
    status_entry(MBDK_ERR_CONTACT_OVERRUN, 'ERR_CONTACT_OVERRUN', &
      'a contact penetrated beyond what its model covers (gear flanks by a quarter base pitch)'), &
    status_entry(MBDK_ERR_INVARIANT_DRIFT, 'ERR_INVARIANT_DRIFT', &
      'a momentum the scene conserves, or a quaternion''s unit norm, drifted beyond the run''s &
      &tolerance'), &
    status_entry(MBDK_ERR_CALLBACK_FAILED, 'ERR_CALLBACK_FAILED', &
      'the user right-hand side returned a failure'), &
    status_entry(MBDK_ERR_BACKEND, 'ERR_BACKEND', 'a backend (SUNDIALS) reported an error'), &
    status_entry(MBDK_ERR_INTERRUPTED, 'ERR_INTERRUPTED', &
      'interrupted by the caller; the samples up to the interruption are kept') ]

  public :: mbdk_status_entry, mbdk_status_message, mbdk_is_failure

contains

  !> i-th entry of the table (1-based); code = huge(0) when i is out of range.
  pure subroutine mbdk_status_entry(i, code, name, message)
    integer, intent(in) :: i
    integer, intent(out) :: code
    character(len=*), intent(out) :: name, message
    if (i < 1 .or. i > MBDK_STATUS_COUNT) then
      code = huge(0); name = ''; message = ''
      return
    end if
    code = table(i)%code
    name = table(i)%name
    message = table(i)%message
  end subroutine mbdk_status_entry

  pure function mbdk_status_message(code) result(msg)
    integer, intent(in) :: code
    character(len=MBDK_STATUS_MSG_LEN) :: msg
    integer :: i
    msg = 'unknown status code'
    do i = 1, MBDK_STATUS_COUNT
      if (table(i)%code == code) then
        msg = table(i)%message
        return
      end if
    end do
  end function mbdk_status_message

  pure logical function mbdk_is_failure(code)
    integer, intent(in) :: code
    mbdk_is_failure = code < 0
  end function mbdk_is_failure

end module mbdk_status
