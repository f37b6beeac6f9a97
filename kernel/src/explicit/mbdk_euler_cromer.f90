!> Euler-Cromer (semi-implicit Euler) for second-order systems q'' = f(t, q, q'),
!> exactly as the book's scheme (4.31)-(4.32), Fekete (2023) section 4.1.4:
!>
!>   a_i     = f(t_i, q_i, v_i)
!>   v_{i+1} = v_i + h a_i
!>   q_{i+1} = q_i + h v_{i+1}
!>
!> Order 1; symplectic for separable Hamiltonian systems (energy error bounded, no drift).
!> Needs a problem with y = [q; v] layout (nq > 0), else MBDK_ERR_NOT_APPLICABLE is returned
!> by the driver before the loop. Reference: Cromer, Am. J. Phys. 49 (1981) 455.
module mbdk_euler_cromer
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_stats, only: mbdk_stats_t
  implicit none
  private
  public :: mbdk_euler_cromer_step

contains

  !> f(n) is a work array; one evaluation of F per step.
  subroutine mbdk_euler_cromer_step(prob, t, h, y, f, st, stat)
    class(mbdk_problem_t), intent(in) :: prob
    real(dp), intent(in) :: t, h
    real(dp), intent(inout) :: y(:)
    real(dp), intent(inout) :: f(:)
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    integer :: nq

    nq = prob%nq
    call prob%rhs(t, y, f, stat)
    st%nfev = st%nfev + 1
    if (stat /= MBDK_SUCCESS) return
    y(nq + 1:2 * nq) = y(nq + 1:2 * nq) + h * f(nq + 1:2 * nq)
    y(1:nq) = y(1:nq) + h * y(nq + 1:2 * nq)
  end subroutine mbdk_euler_cromer_step

end module mbdk_euler_cromer
