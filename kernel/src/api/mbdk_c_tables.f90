!> A scene's tables as C hands them over (mbdk.h: row-major jint[nj][4], jreal[nj][12],
!> fint[nf][4], freal[nf][12], which are Fortran's jint(4, nj) ... in memory), read into the
!> kernel's arrays with the values the scene leaves to the pose (MBDK_FROM_POSE) taken at the
!> initial state y0. The tables may be NULL where their count is 0; mass, inertia and y0 may not.
!> Counts above MBDK_C_MAX_ROWS are refused before any size is computed from them (12 nj must
!> fit a default integer); a failed allocation is MBDK_ERR_NO_MEMORY (asked: its bytes,
!> mbdk_memory).
module mbdk_c_tables
  use, intrinsic :: iso_c_binding, only: c_int, c_double
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_assembly, only: mbdk_tables_resolve
  implicit none
  private
  public :: mbdk_c_tables_read

  integer, parameter, public :: MBDK_C_MAX_ROWS = 100000000

contains

  subroutine mbdk_c_tables_read(nb, mass, inertia, nj, jint, jreal, nf, fint, freal, y0, ji, &
                                jr, fi, fr, stat, asked)
    integer(c_int), intent(in) :: nb, nj, nf
    real(c_double), intent(in), optional :: mass(*), inertia(*), jreal(*), freal(*), y0(*)
    integer(c_int), intent(in), optional :: jint(*), fint(*)
    integer, allocatable, intent(out) :: ji(:, :), fi(:, :)
    real(dp), allocatable, intent(out) :: jr(:, :), fr(:, :)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: bad_joint, bad_force, astat, j
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. (present(mass) .and. present(inertia) .and. present(y0))) return
    if (nb < 1 .or. nj < 0 .or. nf < 0) return
    if (nb > MBDK_C_MAX_ROWS .or. nj > MBDK_C_MAX_ROWS .or. nf > MBDK_C_MAX_ROWS) return
    if (nj > 0 .and. .not. (present(jint) .and. present(jreal))) return
    if (nf > 0 .and. .not. (present(fint) .and. present(freal))) return
    allocate (ji(4, nj), jr(12, nj), fi(4, nf), fr(12, nf), stat=astat)
    call mbdk_alloc_status(astat, (4 * MBDK_INT_BYTES + 12 * MBDK_REAL_BYTES) * &
                           (real(nj, dp) + nf), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    ! column by column: no temporary of the whole table
    do j = 1, nj
      ji(:, j) = int(jint(4 * j - 3:4 * j))
      jr(:, j) = jreal(12 * j - 11:12 * j)
    end do
    do j = 1, nf
      fi(:, j) = int(fint(4 * j - 3:4 * j))
      fr(:, j) = freal(12 * j - 11:12 * j)
    end do
    call mbdk_tables_resolve(int(nb), ji, jr, fi, fr, y0(1:3 * nb), bad_joint, bad_force, stat, &
                             asked)
  end subroutine mbdk_c_tables_read

end module mbdk_c_tables
