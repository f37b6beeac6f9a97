!> The caller's interrupt flag: options carry the address of a C int (or 0) that another
!> thread, or a signal handler, sets non-zero to stop a solve. The drivers poll it once per step
!> (a load of a few nanoseconds) and end with MBDK_ERR_INTERRUPTED, keeping the samples written.
!>
!> The progress of a solve: options may carry the address of a C double (or 0) into which the
!> drivers store the time reached, once per step beside the interrupt poll (a store), so that
!> another thread can show how far a long solve has come (Python's progress bar, mbdk._compiled).
module mbdk_interrupt
  use, intrinsic :: iso_c_binding, only: c_int, c_intptr_t, c_ptr, c_f_pointer
  implicit none
  private
  public :: mbdk_interrupted, mbdk_progress

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

  !> Stores t at the address progress (a C double; 0: nowhere).
  subroutine mbdk_progress(progress, t)
    use, intrinsic :: iso_c_binding, only: c_double
    integer(c_intptr_t), intent(in) :: progress
    real(c_double), intent(in) :: t
    real(c_double), pointer, volatile :: p
    type(c_ptr) :: address
    if (progress == 0) return
    address = transfer(progress, address)
    call c_f_pointer(address, p)
    p = t
  end subroutine mbdk_progress

end module mbdk_interrupt
