!> What a Newton iteration can reach in floating point, and the stopping test scaled to it.
!>
!> A Newton update dx = -J^-1 r computed at the solution is not zero: r carries the roundoff of
!> its own evaluation, e_i ~ eps (sum of the magnitudes of row i's terms), and the solve carries
!> it into dx with J^-1. Where J^-1 amplifies, the update's floor lies far above eps |x|: in the
!> index-3 trapezoidal step a velocity follows from positions as (2/h)(q+ - q), so position
!> roundoff eps L reappears in the velocity's update as 2 eps L / h; at h = 1e-4 that is about
!> 4e-12, above a velocity tolerance of 1e-12. A test below that floor stops a converged
!> iteration by chance (on one BLAS kernel and not on another) and fails for good as h shrinks.
!>
!> The floor of the update, component by component, is estimated as |J^-1| e, from two solves
!> with the Newton matrix already factorised: J z1 = e and J z2 = e with alternating signs
!> (either alone can cancel in a component; their larger magnitude bounds the typical case),
!>   floor_i = MBDK_FLOOR_FACTOR max(|z1_i|, |z2_i|),
!> and a component's tolerance is never below its floor: the stopping test takes the weights
!>   wt_i = max(atol + rtol |x_i|, floor_i),
!> so an iteration stops where its updates reach the tolerance asked for or, below that, the
!> roundoff it cannot beat, and fails only when it stops contracting above both (the caller's
!> contraction test: a diverging or singular iteration, a step too large). Two solves per
!> factorisation: far less than the factorisation. The factor leaves room for the iteration's
!> own roundoff beyond the evaluation's (a few ulps per update). Hairer and Wanner (Solving
!> ODE II, IV.8) bound their Newton tolerance below by 10 eps / rtol for the same reason.
!> The floor is capped at sqrt(eps) times the size of the state (mbdk_floor_cap): a larger one
!> is no roundoff but a nearly singular matrix, and an iteration stalled there fails as before
!> instead of being accepted.
!>
!> Usage: fill e with the residual's roundoff, solve the probes (mbdk_floor_solve, with the
!> caller's LU factorisation, or mbdk_floor_probes and the caller's own solves), then
!> mbdk_floor_from_probes gives the floor and mbdk_floor_cap limits it; mbdk_floor_weights the
!> weights.
module mbdk_newton_floor
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS
  use mbdk_lapack, only: mbdk_lu_solve
  implicit none
  private
  public :: mbdk_floor_probes, mbdk_floor_solve, mbdk_floor_from_probes, mbdk_floor_cap, &
    mbdk_floor_weights, MBDK_FLOOR_FACTOR

  !> the floor is this many times the estimated roundoff of one update
  real(dp), parameter :: MBDK_FLOOR_FACTOR = 16.0_dp

contains

  !> The two right-hand sides of the floor's solves: b1 = e, b2 = e with alternating signs.
  pure subroutine mbdk_floor_probes(e, b1, b2)
    real(dp), intent(in) :: e(:)
    real(dp), intent(out) :: b1(:), b2(:)
    integer :: i
    b1 = abs(e)
    do i = 1, size(e)
      b2(i) = merge(b1(i), -b1(i), mod(i, 2) == 1)
    end do
  end subroutine mbdk_floor_probes

  !> The probes of e solved with an LU factorisation (mbdk_lapack's): z1, z2 for
  !> mbdk_floor_from_probes.
  subroutine mbdk_floor_solve(e, lu, ipiv, z1, z2, stat)
    real(dp), intent(in) :: e(:), lu(:, :)
    integer, intent(in) :: ipiv(:)
    real(dp), intent(out) :: z1(:), z2(:)
    integer, intent(out) :: stat
    call mbdk_floor_probes(e, z1, z2)
    call mbdk_lu_solve(lu, ipiv, z1, stat)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_lu_solve(lu, ipiv, z2, stat)
  end subroutine mbdk_floor_solve

  !> floor limited to sqrt(eps) max |x|, x the iteration's state (the module header)
  pure subroutine mbdk_floor_cap(x, floor)
    real(dp), intent(in) :: x(:)
    real(dp), intent(inout) :: floor(:)
    floor = min(floor, sqrt(epsilon(1.0_dp)) * maxval(abs(x)))
  end subroutine mbdk_floor_cap

  !> floor = MBDK_FLOOR_FACTOR max(|z1|, |z2|), z1 and z2 the probes solved with the Newton
  !> matrix; a non-finite solve (a nearly singular matrix) gives no floor (zero): the test then
  !> asks for the tolerance itself.
  pure subroutine mbdk_floor_from_probes(z1, z2, floor)
    real(dp), intent(in) :: z1(:), z2(:)
    real(dp), intent(out) :: floor(:)
    floor = MBDK_FLOOR_FACTOR * max(abs(z1), abs(z2))
    where (.not. (floor <= huge(1.0_dp))) floor = 0.0_dp
  end subroutine mbdk_floor_from_probes

  !> The stopping test's weights: wt = max(atol + rtol |x|, floor).
  pure subroutine mbdk_floor_weights(x, rtol, atol, floor, wt)
    real(dp), intent(in) :: x(:), rtol, atol, floor(:)
    real(dp), intent(out) :: wt(:)
    wt = max(atol + rtol * abs(x), floor)
  end subroutine mbdk_floor_weights

end module mbdk_newton_floor
