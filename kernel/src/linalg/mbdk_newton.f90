!> Newton-Raphson for the implicit stage equation of every implicit method in the kernel:
!>
!>   G(y) = y - c - h*gamma*F(t, y) = 0,      iteration matrix  I - h*gamma*J,  J = dF/dy
!>
!> Simplified Newton: J is evaluated (analytically when the problem has it, else by forward
!> differences) and I - h*gamma*J factorised with LAPACK once per step at the predictor. If the
!> iteration stalls or diverges, J is re-evaluated at the current iterate and the iteration
!> restarted once (full Newton from then on). Converged when the weighted RMS norm of the update
!> is below 1 (weights atol + rtol*|y|). An iteration that stalls is tested once more with the
!> weights never below the update's roundoff floor (mbdk_newton_floor, from the residual's
!> terms eps (|y| + |c| + |h gamma F|) and the matrix), so that a tolerance asked below what
!> double precision reaches stops at that floor instead of failing on one CPU and not on
!> another; the floor costs two solves, and only where an iteration stalls.
!>
!> Statuses: MBDK_SUCCESS, MBDK_ERR_NEWTON_DIVERGED, MBDK_ERR_SINGULAR_MATRIX, or the
!> right-hand side's failure. Reference: Hairer & Wanner, Solving ODE II, IV.8.
module mbdk_newton
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_NEWTON_DIVERGED
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_lapack, only: mbdk_lu_factor, mbdk_lu_solve
  use mbdk_error_norm, only: mbdk_wrms
  use mbdk_newton_floor, only: mbdk_floor_solve, mbdk_floor_from_probes, mbdk_floor_cap
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  implicit none
  private
  public :: mbdk_newton_work_t, mbdk_newton_work_init, mbdk_newton_solve, mbdk_jacobian

  !> Work arrays of the Newton solver, allocated once per solve.
  type :: mbdk_newton_work_t
    real(dp), allocatable :: jac(:, :), lu(:, :), f(:), f0(:), r(:), ytmp(:), ypred(:)
    real(dp), allocatable :: floor(:), b1(:), b2(:)   !< the update's roundoff floor, probes
    integer, allocatable :: ipiv(:)
  end type mbdk_newton_work_t

contains

  !> stat: MBDK_SUCCESS or MBDK_ERR_NO_MEMORY (asked: the bytes of the two dense n x n
  !> matrices and the vectors, mbdk_memory). no_matrix: the vectors alone (a problem that
  !> keeps its own Newton matrix, mbdk_problem's has_newton_matrix)
  subroutine mbdk_newton_work_init(w, n, stat, asked, no_matrix)
    type(mbdk_newton_work_t), intent(out) :: w
    integer, intent(in) :: n
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    logical, intent(in), optional :: no_matrix
    integer :: astat, nm
    nm = n
    if (present(no_matrix)) then
      if (no_matrix) nm = 0
    end if
    allocate (w%jac(nm, nm), w%lu(nm, nm), w%f(n), w%f0(n), w%r(n), w%ytmp(n), w%ypred(n), &
              w%ipiv(nm), w%floor(n), w%b1(n), w%b2(n), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (2.0_dp * nm * nm + 8.0_dp * n) + &
                           MBDK_INT_BYTES * nm, stat, asked)
  end subroutine mbdk_newton_work_init

  !> J = dF/dy at (t, y): analytic if available (and not overridden), else forward differences.
  subroutine mbdk_jacobian(prob, opt, t, y, w, st, stat)
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t, y(:)
    type(mbdk_newton_work_t), intent(inout) :: w
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    integer :: j
    real(dp) :: delta

    st%njev = st%njev + 1
    if (prob%has_jac .and. opt%fd_jacobian == 0) then
      call prob%jac(t, y, w%jac, stat)
      return
    end if
    call prob%rhs(t, y, w%f0, stat)
    st%nfev = st%nfev + 1
    if (stat /= MBDK_SUCCESS) return
    do j = 1, size(y)
      w%ytmp = y
      delta = sqrt(epsilon(1.0_dp)) * max(abs(y(j)), 1.0_dp)
      w%ytmp(j) = y(j) + delta
      delta = w%ytmp(j) - y(j)   ! the increment actually representable
      call prob%rhs(t, w%ytmp, w%f, stat)
      st%nfev = st%nfev + 1
      if (stat /= MBDK_SUCCESS) return
      w%jac(:, j) = (w%f - w%f0) / delta
    end do
  end subroutine mbdk_jacobian

  !> Solves y = c + hg*F(t, y) for y; on entry y holds the predictor, on exit the solution.
  subroutine mbdk_newton_solve(prob, opt, t, hg, c, y, w, st, stat)
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t, hg
    real(dp), intent(in) :: c(:)
    real(dp), intent(inout) :: y(:)
    type(mbdk_newton_work_t), intent(inout) :: w
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    integer :: attempt, it
    logical :: full
    real(dp) :: dnorm, dnorm_old

    full = .false.
    w%ypred = y
    do attempt = 1, 2
      if (attempt == 2) y = w%ypred
      call factor_at(y, stat)
      if (stat /= MBDK_SUCCESS) return
      dnorm_old = huge(1.0_dp)
      do it = 1, opt%newton_max_iter
        call prob%rhs(t, y, w%f, stat)
        st%nfev = st%nfev + 1
        if (stat /= MBDK_SUCCESS) return
        w%r = -(y - c - hg * w%f)
        call mbdk_lu_solve(w%lu, w%ipiv, w%r, stat)
        if (stat /= MBDK_SUCCESS) return
        y = y + w%r
        st%newton_iterations = st%newton_iterations + 1
        dnorm = mbdk_wrms(w%r, y, opt%newton_rtol, opt%newton_atol)
        if (.not. ieee_is_finite(dnorm)) exit
        if (dnorm <= 1.0_dp) then
          stat = MBDK_SUCCESS
          return
        end if
        if (it >= 2 .and. dnorm > 0.9_dp * dnorm_old) then   ! stalled or diverging
          call floor_at(stat)                                ! or at the roundoff floor
          if (stat /= MBDK_SUCCESS) return
          if (mbdk_wrms(w%r, y, opt%newton_rtol, opt%newton_atol, w%floor) <= 1.0_dp) return
          exit
        end if
        dnorm_old = dnorm
        if (full) then
          call factor_at(y, stat)
          if (stat /= MBDK_SUCCESS) return
        end if
      end do
      full = .true.   ! second attempt: fresh Jacobian at every iterate
    end do
    stat = MBDK_ERR_NEWTON_DIVERGED

  contains

    subroutine factor_at(yy, s)
      real(dp), intent(in) :: yy(:)
      integer, intent(out) :: s
      integer :: i
      call mbdk_jacobian(prob, opt, t, yy, w, st, s)
      if (s /= MBDK_SUCCESS) return
      w%lu = -hg * w%jac
      do i = 1, size(yy)
        w%lu(i, i) = w%lu(i, i) + 1.0_dp
      end do
      call mbdk_lu_factor(w%lu, w%ipiv, s)
      st%nlu = st%nlu + 1
    end subroutine factor_at

    !> the update's roundoff floor with the current matrix, from the residual's terms at the
    !> last iterate (w%f: F there)
    subroutine floor_at(s)
      integer, intent(out) :: s
      w%ytmp = epsilon(1.0_dp) * (abs(y) + abs(c) + abs(hg * w%f))
      call mbdk_floor_solve(w%ytmp, w%lu, w%ipiv, w%b1, w%b2, s)
      if (s /= MBDK_SUCCESS) return
      call mbdk_floor_from_probes(w%b1, w%b2, w%floor)
      call mbdk_floor_cap(y, w%floor)
    end subroutine floor_at

  end subroutine mbdk_newton_solve

end module mbdk_newton
