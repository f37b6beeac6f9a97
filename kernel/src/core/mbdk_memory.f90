!> Memory the kernel asks for. Every allocate in the kernel takes stat= and turns a failure into
!> MBDK_ERR_NO_MEMORY through mbdk_alloc_status, which also hands the bytes the statement asked
!> for to the caller (asked: the statistics' alloc_bytes, where the routine's caller has them), so
!> that the user learns how much was asked for, not only that it failed. Sizes are counted in
!> doubles: a count of bytes that no integer holds is still a count (and is refused by the
!> allocate). Arrays sized by the problem are allocatable, never automatic: gfortran takes an
!> automatic array from malloc without a check, so a failure there would be a segmentation fault.
!> mbdk_count_fits refuses, before any allocation, an element count that the kernel's default
!> integers (and LAPACK's) cannot index.
module mbdk_memory
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_NO_MEMORY
  implicit none
  private
  public :: mbdk_alloc_status, mbdk_count_fits

  !> bytes of one real(dp), and of one default integer or logical
  real(dp), parameter, public :: MBDK_REAL_BYTES = 8.0_dp, MBDK_INT_BYTES = 4.0_dp

contains

  !> The status of an allocate whose stat= gave astat: MBDK_SUCCESS, or MBDK_ERR_NO_MEMORY with
  !> bytes (what the statement asked for) stored in asked when it is present (asked is left as
  !> it was on success).
  pure subroutine mbdk_alloc_status(astat, bytes, stat, asked)
    integer, intent(in) :: astat
    real(dp), intent(in) :: bytes
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    stat = MBDK_SUCCESS
    if (astat == 0) return
    stat = MBDK_ERR_NO_MEMORY
    if (present(asked)) asked = bytes
  end subroutine mbdk_alloc_status

  !> Whether an array of count elements (a product of sizes, counted in a double) can be indexed
  !> by a default integer: the kernel's loops, its sizes and LAPACK's arguments are such.
  pure logical function mbdk_count_fits(count)
    real(dp), intent(in) :: count
    mbdk_count_fits = count <= real(huge(0), dp)
  end function mbdk_count_fits

end module mbdk_memory
