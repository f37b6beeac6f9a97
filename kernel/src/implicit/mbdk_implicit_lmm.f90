!> One step of an implicit linear multistep method given by its coefficients (mbdk_lmm_tables):
!>
!>   y_{n+1} = c + h beta_0 F(t_{n+1}, y_{n+1}),   c = -sum_{j=1..k} alpha_j y_{n+1-j} + h beta_1 F_n
!>
!> solved by mbdk_newton (LAPACK LU of I - h beta_0 J). The history hist(:, j) holds y_{n+1-j},
!> j = 1..k (hist(:, 1) = y_n); it is shifted after the step. fn holds F(t_n, y_n) for methods
!> with beta_1 /= 0 (trapezoidal) and is refreshed at the new point. Predictor: y_n.
!>
!> A k-step method needs k-1 start-up values; the driver produces them with RK4 steps, as the
!> book describes for the Gear formula (4.80). Statuses: those of mbdk_newton.
module mbdk_implicit_lmm
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_lmm_tables, only: mbdk_lmm_t
  use mbdk_newton, only: mbdk_newton_work_t, mbdk_newton_solve
  implicit none
  private
  public :: mbdk_implicit_lmm_step

contains

  !> Advances from t_n = t to t + h. y holds y_n on entry and y_{n+1} on exit.
  subroutine mbdk_implicit_lmm_step(prob, tab, opt, t, h, y, hist, fn, c, w, st, stat)
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_lmm_t), intent(in) :: tab
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t, h
    real(dp), intent(inout) :: y(:), hist(:, :), fn(:), c(:)
    type(mbdk_newton_work_t), intent(inout) :: w
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    integer :: j

    c = 0.0_dp
    do j = 1, tab%k
      c = c - tab%alpha(j) * hist(:, j)
    end do
    if (tab%beta1 /= 0.0_dp) c = c + (h * tab%beta1) * fn
    call mbdk_newton_solve(prob, opt, t + h, h * tab%beta0, c, y, w, st, stat)
    if (stat /= MBDK_SUCCESS) return
    do j = size(hist, 2), 2, -1   ! the whole history: a start-up step keeps it for later steps
      hist(:, j) = hist(:, j - 1)
    end do
    hist(:, 1) = y
    if (tab%beta1 /= 0.0_dp) then
      call prob%rhs(t + h, y, fn, stat)
      st%nfev = st%nfev + 1
    end if
  end subroutine mbdk_implicit_lmm_step

end module mbdk_implicit_lmm
