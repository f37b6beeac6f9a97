!> Kind parameters used everywhere in the kernel.
module mbdk_kinds
  use, intrinsic :: iso_fortran_env, only: real64, int32, int64
  implicit none
  private
  public :: dp, i8
  integer, parameter :: dp = real64   !< working precision (IEEE double)
  integer, parameter :: i8 = int64    !< counters that can exceed 2**31
end module mbdk_kinds
