!> test_draws.f90 - reproducible random matrices for the kernel's test programs: the minimal
!> standard generator (Park and Miller 1988) in 64-bit integers (no overflow, the same draws on
!> every machine), its state in the caller's draws_t.
module test_draws
  use mbdk_kinds, only: dp, i8
  implicit none
  private
  public :: draws_t, draw, fill, fill_v

  type :: draws_t
    integer(i8) :: seed = 12345_i8
  end type draws_t

contains

  !> uniform in (-1, 1)
  real(dp) function draw(d)
    type(draws_t), intent(inout) :: d
    d%seed = mod(16807_i8 * d%seed, 2147483647_i8)
    draw = 2.0_dp * real(d%seed, dp) / 2147483647.0_dp - 1.0_dp
  end function draw

  subroutine fill(d, m)
    type(draws_t), intent(inout) :: d
    real(dp), intent(out) :: m(:, :)
    integer :: i, j
    do j = 1, size(m, 2)
      do i = 1, size(m, 1)
        m(i, j) = draw(d)
      end do
    end do
  end subroutine fill

  subroutine fill_v(d, v)
    type(draws_t), intent(inout) :: d
    real(dp), intent(out) :: v(:)
    integer :: i
    do i = 1, size(v)
      v(i) = draw(d)
    end do
  end subroutine fill_v

end module test_draws
