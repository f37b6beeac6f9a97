!> A scene's tables as C hands them over (mbdk.h: row-major jint[nj][4], jreal[nj][12],
!> fint[nf][4], freal[nf][12], which are Fortran's jint(4, nj) ... in memory), read into the
!> kernel's arrays with the values the scene leaves to the pose (MBDK_FROM_POSE) taken at the
!> initial state y0. The tables may be NULL where their count is 0; mass, inertia and y0 may not.
!> Counts above MBDK_C_MAX_ROWS are refused before any size is computed from them (12 nj must
!> fit a default integer); a failed allocation is MBDK_ERR_NO_MEMORY.
module mbdk_c_tables
  use, intrinsic :: iso_c_binding, only: c_int, c_double
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_assembly, only: mbdk_tables_resolve
  implicit none
  private
  public :: mbdk_c_tables_read

  integer, parameter, public :: MBDK_C_MAX_ROWS = 100000000

contains

  subroutine mbdk_c_tables_read(nb, mass, inertia, nj, jint, jreal, nf, fint, freal, y0, ji, &
                                jr, fi, fr, stat)
    integer(c_int), intent(in) :: nb, nj, nf
    real(c_double), intent(in), optional :: mass(*), inertia(*), jreal(*), freal(*), y0(*)
    integer(c_int), intent(in), optional :: jint(*), fint(*)
    integer, allocatable, intent(out) :: ji(:, :), fi(:, :)
    real(dp), allocatable, intent(out) :: jr(:, :), fr(:, :)
    integer, intent(out) :: stat
    integer :: bad_joint, bad_force, astat
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. (present(mass) .and. present(inertia) .and. present(y0))) return
    if (nb < 1 .or. nj < 0 .or. nf < 0) return
    if (nb > MBDK_C_MAX_ROWS .or. nj > MBDK_C_MAX_ROWS .or. nf > MBDK_C_MAX_ROWS) return
    if (nj > 0 .and. .not. (present(jint) .and. present(jreal))) return
    if (nf > 0 .and. .not. (present(fint) .and. present(freal))) return
    allocate (ji(4, nj), jr(12, nj), fi(4, nf), fr(12, nf), stat=astat)
    if (astat /= 0) then
      stat = MBDK_ERR_NO_MEMORY
      return
    end if
    if (nj > 0) then
      ji = reshape(int(jint(1:4 * nj)), [4, int(nj)])
      jr = reshape(jreal(1:12 * nj), [12, int(nj)])
    end if
    if (nf > 0) then
      fi = reshape(int(fint(1:4 * nf)), [4, int(nf)])
      fr = reshape(freal(1:12 * nf), [12, int(nf)])
    end if
    call mbdk_tables_resolve(int(nb), ji, jr, fi, fr, y0(1:3 * nb), bad_joint, bad_force, stat)
  end subroutine mbdk_c_tables_read

end module mbdk_c_tables
