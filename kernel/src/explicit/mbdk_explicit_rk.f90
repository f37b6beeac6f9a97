!> One step of an explicit Runge-Kutta method given by its Butcher tableau (mbdk_butcher).
!>
!>   k_i = F(t + c_i h, y + h sum_{j<i} a_ij k_j),   y+ = y + h sum_i b_i k_i
!>
!> Zero entries of the tableau are skipped, so the generic step does the arithmetic of a
!> hand-written one. Statuses: MBDK_SUCCESS, or whatever the right-hand side returned.
module mbdk_explicit_rk
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_butcher, only: mbdk_butcher_t
  use mbdk_stats, only: mbdk_stats_t
  implicit none
  private
  public :: mbdk_explicit_rk_step

contains

  !> y is advanced in place from t to t + h. k(n, stages) and ytmp(n) are work arrays.
  subroutine mbdk_explicit_rk_step(prob, tab, t, h, y, k, ytmp, st, stat)
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_butcher_t), intent(in) :: tab
    real(dp), intent(in) :: t, h
    real(dp), intent(inout), contiguous :: y(:)
    real(dp), intent(inout), contiguous :: k(:, :), ytmp(:)
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    integer :: i, j

    do i = 1, tab%stages
      ytmp = y
      do j = 1, i - 1
        if (tab%a(i, j) /= 0.0_dp) ytmp = ytmp + (h * tab%a(i, j)) * k(:, j)
      end do
      call prob%rhs(t + tab%c(i) * h, ytmp, k(:, i), stat)
      st%nfev = st%nfev + 1
      if (stat /= MBDK_SUCCESS) return
    end do
    do i = 1, tab%stages
      if (tab%b(i) /= 0.0_dp) y = y + (h * tab%b(i)) * k(:, i)
    end do
  end subroutine mbdk_explicit_rk_step

end module mbdk_explicit_rk
