!> Step matrices: the linear map that one step of a kernel method applies to the linear system
!> y' = A y, measured by running that method's own step routine, not a formula for it.
!>
!> On y' = A y every method of the kernel is linear in its inputs, so one step is a matrix:
!>
!>   one-step methods (explicit RK, Euler-Cromer, implicit Euler, trapezoidal):
!>       y_{n+1} = M y_n,                                   M is n x n;
!>   k-step methods (bdf2..bdf6): the companion form on the stacked history
!>       s_n = [y_n; y_{n-1}; ...; y_{n-k+1}],  s_{n+1} = M s_n,   M is (n k) x (n k).
!>
!> Column j of M is the result of one step (mbdk_explicit_rk_step, mbdk_euler_cromer_step or
!> mbdk_implicit_lmm_step, the routines the fixed-step driver calls) started from the j-th unit
!> vector. The implicit steps solve their stage equation with the kernel's Newton iteration; with
!> the exact Jacobian A it converges in one iteration, so M is exact to rounding. Nothing here
!> restates a method's formula: if a Butcher table, a multistep coefficient or a step routine
!> changes, M changes with it.
!>
!> Stability follows from the eigenvalues of M (spectral radius <= 1). For the test equation
!> y' = lambda y with complex lambda, pass A = [[Re, -Im], [Im, Re]] (h lambda = z with h = 1);
!> for a one-step method M is then [[Re R(z), -Im R(z)], [Im R(z), Re R(z)]]. Euler-Cromer
!> assumes y = [q; v] with q' = v, so it needs a second-order system: pass the oscillator
!> A = [[0, 1], [-|lambda|^2, 2 Re lambda]], whose characteristic roots are lambda and conj(lambda).
!>
!> Statuses per matrix: MBDK_SUCCESS; MBDK_ERR_UNKNOWN_METHOD; MBDK_ERR_INVALID_INPUT (A not
!> square, M of the wrong size, h not positive and finite, Euler-Cromer with odd n); those of
!> the Newton solver (MBDK_ERR_SINGULAR_MATRIX where I - h beta0 A is singular: the amplification
!> factor has a pole there).
module mbdk_step_matrix
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_memory, only: mbdk_alloc_status, mbdk_count_fits, MBDK_REAL_BYTES
  use mbdk_methods, only: mbdk_method_info, MBDK_FAMILY_EXPLICIT_RK, MBDK_FAMILY_EULER_CROMER, &
    MBDK_FAMILY_IMPLICIT_LMM, MBDK_FAMILY_DAE_INDEX3, MBDK_METHOD_NAME_LEN
  use mbdk_butcher, only: mbdk_butcher_t, mbdk_butcher_table, MBDK_MAX_STAGES
  use mbdk_explicit_rk, only: mbdk_explicit_rk_step
  use mbdk_euler_cromer, only: mbdk_euler_cromer_step
  use mbdk_lmm_tables, only: mbdk_lmm_t, mbdk_lmm_table
  use mbdk_implicit_lmm, only: mbdk_implicit_lmm_step
  use mbdk_newton, only: mbdk_newton_work_t, mbdk_newton_work_init
  use mbdk_textbook, only: mbdk_textbook_t, mbdk_textbook_init, mbdk_problem_id
  implicit none
  private
  public :: mbdk_step_history_length, mbdk_step_matrix_eval

contains

  !> Number of past states one step of the method reads: k for a k-step method, 1 for a
  !> one-step method, 0 for an unknown id.
  integer function mbdk_step_history_length(method)
    integer, intent(in) :: method
    character(len=MBDK_METHOD_NAME_LEN) :: name
    integer :: family, order
    type(mbdk_lmm_t) :: lmm
    logical :: ok
    call mbdk_method_info(method, name, family, order)
    select case (family)
    case (MBDK_FAMILY_EXPLICIT_RK, MBDK_FAMILY_EULER_CROMER)
      mbdk_step_history_length = 1
    case (MBDK_FAMILY_IMPLICIT_LMM)
      call mbdk_lmm_table(method, lmm, ok)
      mbdk_step_history_length = lmm%k
    case default
      mbdk_step_history_length = 0
    end select
  end function mbdk_step_history_length

  !> m (n k x n k) = the step matrix of method with step h on y' = a y (a is n x n).
  !> opt supplies the Newton settings of the implicit methods; its method and h are ignored.
  subroutine mbdk_step_matrix_eval(method, a, h, opt, m, stat)
    integer, intent(in) :: method
    real(dp), intent(in) :: a(:, :), h
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(out) :: m(:, :)
    integer, intent(out) :: stat

    character(len=MBDK_METHOD_NAME_LEN) :: name
    integer :: family, order, n, k, j, l, astat
    logical :: ok
    type(mbdk_textbook_t) :: prob
    type(mbdk_butcher_t) :: rk
    type(mbdk_lmm_t) :: lmm
    type(mbdk_newton_work_t) :: nw
    type(mbdk_stats_t) :: st
    real(dp), allocatable :: y(:), ytmp(:), kst(:, :), hist(:, :), fn(:), c(:), s(:)

    m = 0.0_dp
    call mbdk_method_info(method, name, family, order)
    stat = MBDK_ERR_UNKNOWN_METHOD
    if (family == 0) return
    stat = MBDK_ERR_NOT_APPLICABLE   ! no step on y' = A y: the method integrates index-3 DAEs
    if (family == MBDK_FAMILY_DAE_INDEX3) return
    n = size(a, 1)
    k = mbdk_step_history_length(method)
    stat = MBDK_ERR_INVALID_INPUT
    if (n < 1 .or. size(a, 2) /= n) return
    ! the state of k steps (n k) and A's entries (n^2) are indexed by default integers
    if (.not. (mbdk_count_fits(real(n, dp) * k) .and. mbdk_count_fits(real(n, dp) * n))) return
    if (size(m, 1) /= n * k .or. size(m, 2) /= n * k) return
    if (.not. (h > 0.0_dp .and. h <= huge(1.0_dp))) return
    if (.not. all(abs(a) <= huge(1.0_dp))) return
    if (family == MBDK_FAMILY_EULER_CROMER .and. mod(n, 2) /= 0) return
    call mbdk_textbook_init(prob, mbdk_problem_id('linear_system'), n, reshape(a, [n * n]), stat)
    if (stat /= MBDK_SUCCESS) return
    if (family == MBDK_FAMILY_EULER_CROMER) prob%nq = n / 2

    allocate (y(n), ytmp(n), s(n * k), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * real(n, dp) * (k + 2), stat)
    if (stat /= MBDK_SUCCESS) return
    select case (family)
    case (MBDK_FAMILY_EXPLICIT_RK)
      call mbdk_butcher_table(method, rk, ok)
      allocate (kst(n, MBDK_MAX_STAGES), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * real(n, dp) * MBDK_MAX_STAGES, stat)
    case (MBDK_FAMILY_IMPLICIT_LMM)
      call mbdk_lmm_table(method, lmm, ok)
      call mbdk_newton_work_init(nw, n, stat)
      if (stat /= MBDK_SUCCESS) return
      allocate (hist(n, k), fn(n), c(n), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * real(n, dp) * (k + 2), stat)
    end select
    if (stat /= MBDK_SUCCESS) return

    do j = 1, n * k
      s = 0.0_dp
      s(j) = 1.0_dp
      select case (family)
      case (MBDK_FAMILY_EXPLICIT_RK)
        y = s
        call mbdk_explicit_rk_step(prob, rk, 0.0_dp, h, y, kst, ytmp, st, stat)
        s = y
      case (MBDK_FAMILY_EULER_CROMER)
        y = s
        call mbdk_euler_cromer_step(prob, 0.0_dp, h, y, ytmp, st, stat)
        s = y
      case (MBDK_FAMILY_IMPLICIT_LMM)
        do l = 1, k
          hist(:, l) = s((l - 1) * n + 1:l * n)
        end do
        y = hist(:, 1)
        if (lmm%beta1 /= 0.0_dp) call prob%rhs(0.0_dp, y, fn, stat)
        call mbdk_implicit_lmm_step(prob, lmm, opt, 0.0_dp, h, y, hist, fn, c, nw, st, stat)
        do l = 1, k
          s((l - 1) * n + 1:l * n) = hist(:, l)
        end do
      end select
      if (stat /= MBDK_SUCCESS) return
      m(:, j) = s
    end do
  end subroutine mbdk_step_matrix_eval

end module mbdk_step_matrix
