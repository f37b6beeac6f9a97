!> Statistics of one solve, counted inside the kernel.
module mbdk_stats
  use mbdk_kinds, only: dp, i8
  implicit none
  private
  public :: mbdk_stats_t, MBDK_NSTATS, mbdk_stats_to_array

  type, public :: mbdk_stats_t
    integer(i8) :: steps = 0          !< accepted steps (including start-up steps)
    integer(i8) :: rhs_evals = 0      !< evaluations of F(t, y), finite-difference columns included
    integer(i8) :: jac_evals = 0      !< Jacobian evaluations (analytic or by finite differences)
    integer(i8) :: lu_factorizations = 0 !< factorisations of a Newton matrix (LU or LDL^T)
    integer(i8) :: newton_iterations = 0
    integer(i8) :: startup_steps = 0  !< steps taken by the start-up method of a multistep method
    integer(i8) :: rejected_steps = 0 !< step-size control: steps rejected by the error test
    integer(i8) :: newton_failures = 0 !< step-size control: steps retried because Newton failed
    real(dp) :: cpu_time = 0.0_dp     !< CPU seconds of the time loop, measured in the kernel
  end type mbdk_stats_t

  integer, parameter :: MBDK_NSTATS = 9

contains

  !> Flat view for the f2py layer: steps, rhs, jac, lu, newton, startup, cpu_time, rejected,
  !> newton_failures.
  pure function mbdk_stats_to_array(s) result(a)
    type(mbdk_stats_t), intent(in) :: s
    real(dp) :: a(MBDK_NSTATS)
    a = [real(s%steps, dp), real(s%rhs_evals, dp), real(s%jac_evals, dp), &
         real(s%lu_factorizations, dp), real(s%newton_iterations, dp), &
         real(s%startup_steps, dp), s%cpu_time, real(s%rejected_steps, dp), &
         real(s%newton_failures, dp)]
  end function mbdk_stats_to_array

end module mbdk_stats
