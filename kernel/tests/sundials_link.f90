!> sundials_link.f90 - proves the SUNDIALS Fortran 2003 interface (Debian's 6.x) links and runs:
!> creates a context, a serial vector and a CVODE memory, then frees them. Exit code 0 = pass.
program sundials_link
  use, intrinsic :: iso_c_binding
  use fsundials_context_mod
  use fsundials_nvector_mod, only: N_Vector, FN_VDestroy
  use fnvector_serial_mod
  use fcvode_mod
  use fida_mod
  implicit none
  type(c_ptr) :: ctx, cvode_mem, ida_mem
  type(N_Vector), pointer :: v
  real(c_double) :: y(3)
  integer(c_int) :: ierr
  ierr = FSUNContext_Create(c_null_ptr, ctx)
  if (ierr /= 0) error stop 1
  y = 1.0_c_double
  v => FN_VMake_Serial(3_c_int64_t, y, ctx)
  if (.not. associated(v)) error stop 2
  cvode_mem = FCVodeCreate(CV_BDF, ctx)
  if (.not. c_associated(cvode_mem)) error stop 3
  ida_mem = FIDACreate(ctx)
  if (.not. c_associated(ida_mem)) error stop 4
  call FCVodeFree(cvode_mem)
  call FIDAFree(ida_mem)
  call FN_VDestroy(v)
  ierr = FSUNContext_Free(ctx)
  print '(a)', 'SUNDIALS 6 Fortran interface: context, N_Vector, CVODE and IDA memory OK: PASS'
end program sundials_link
