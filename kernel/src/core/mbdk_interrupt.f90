!> The caller's interrupt flag: options carry the address of a C int (or 0) that another
!> thread, or a signal handler, sets non-zero to stop a solve. The drivers poll it once per step
!> (a load of a few nanoseconds) and end with MBDK_ERR_INTERRUPTED, keeping the samples written.
module mbdk_interrupt
  use, intrinsic :: iso_c_binding, only: c_int, c_intptr_t, c_ptr, c_f_pointer
  implicit none
  private
  public :: mbdk_interrupted

contains

  logical function mbdk_interrupted(flag)
    integer(c_intptr_t), intent(in) :: flag
    integer(c_int), pointer, volatile :: p
    type(c_ptr) :: address
    mbdk_interrupted = .false.
    if (flag == 0) return
    address = transfer(flag, address)
    call c_f_pointer(address, p)
    mbdk_interrupted = p /= 0
  end function mbdk_interrupted

end module mbdk_interrupt
