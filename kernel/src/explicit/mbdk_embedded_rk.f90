!> dopri54 and bs32: explicit Runge-Kutta pairs with error control and dense output. The pairs
!> are data (mbdk_embedded_pairs); this is the one stepping loop for all of them.
!>
!> A step from (t, y) with h computes the stages K_1 .. K_s (K_1 = F(t, y) is the previous
!> step's last stage: FSAL), y_new = y + h b.K (the higher order, local extrapolation) and the
!> error estimate h e.K. Its weighted RMS norm (mbdk_adaptive, weights from max(|y|, |y_new|))
!> decides:
!>   err <= 1: accepted; h_next = h min(fac_max, max(fac_min, 0.9 err^(-1/(q+1))))
!>   err > 1:  rejected; h = h max(fac_min, 0.9 err^(-1/(q+1))), and the next accepted step may
!>             not grow h (fac_max = 1 once)
!> with q the order of the embedded solution, fac_min = 0.2, fac_max = 10 (Hairer, Norsett and
!> Wanner, Solving ODEs I, II.4). A stage that is not finite (h far beyond the stability limit)
!> counts as a rejection with err = infinity, not as a failure. The first step: opt%h, or
!> mbdk_adaptive_initial_step. h never exceeds opt%h_max or what is left to t_end; the last step
!> lands on t_end exactly. Below mbdk_adaptive_h_floor: MBDK_ERR_STEP_TOO_SMALL.
!>
!> Samples inside a step come from the pair's dense output; a sample at the step's end is the
!> step's state itself. After a projection (has_post_step) F is evaluated again at the
!> projected state, as the next step's first stage.
module mbdk_embedded_rk
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_interrupt, only: mbdk_interrupted
  use mbdk_embedded_pairs, only: mbdk_pair_t, mbdk_pair_table
  use mbdk_adaptive, only: mbdk_adaptive_weights, mbdk_adaptive_wrms, mbdk_adaptive_after_step, &
    mbdk_adaptive_step_limit, mbdk_adaptive_initial_step, mbdk_adaptive_h_floor
  implicit none
  private
  public :: mbdk_embedded_rk_solve

  real(dp), parameter :: SAFETY = 0.9_dp, FAC_MIN = 0.2_dp, FAC_MAX = 10.0_dp

contains

  !> See the module header; called by mbdk_solve_ode, which has checked the options, written
  !> sample 1 (nwritten = 1) and the sample times t_out.
  subroutine mbdk_embedded_rk_solve(prob, opt, t0, y0, atol, t_out, y_out, nwritten, st, stat)
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, y0(:), atol(:), t_out(:)
    real(dp), intent(inout) :: y_out(:, :)
    integer, intent(inout) :: nwritten
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat

    type(mbdk_pair_t) :: pr
    logical :: found, rejected_last, finite, projected, sample
    integer :: n, i, j, ns, k
    integer(i8) :: tries, limit
    real(dp) :: t, t_end, h, hmax, err, expo, fac, theta, t_new
    real(dp), allocatable :: y(:), ynew(:), kk(:, :), w(:), e(:), bth(:)

    n = size(y0)
    ns = size(t_out)
    t_end = t_out(ns)
    call mbdk_pair_table(opt%method, pr, found)
    stat = MBDK_ERR_UNKNOWN_METHOD
    if (.not. found) return
    allocate (y(n), ynew(n), kk(n, pr%s), w(n), e(n), bth(pr%s))
    y = y0
    t = t0
    call prob%rhs(t, y, kk(:, 1), stat)
    st%nfev = st%nfev + 1
    if (stat /= MBDK_SUCCESS) return
    call mbdk_adaptive_initial_step(prob, opt, atol, pr%est_order, t0, t_end - t0, y, kk(:, 1), &
                                    h, st%nfev, stat)
    if (stat /= MBDK_SUCCESS) return
    hmax = t_end - t0
    if (opt%h_max > 0.0_dp) hmax = min(hmax, opt%h_max)
    expo = -1.0_dp / real(pr%est_order + 1, dp)
    limit = mbdk_adaptive_step_limit(opt)
    tries = 0
    rejected_last = .false.
    k = nwritten + 1           ! the next sample to write

    do while (t < t_end)
      if (opt%interrupt /= 0 .and. mbdk_interrupted(opt%interrupt)) then
        stat = MBDK_ERR_INTERRUPTED
        return
      end if
      if (tries >= limit) then
        stat = MBDK_ERR_TOO_MANY_STEPS
        return
      end if
      tries = tries + 1
      h = min(h, hmax)
      t_new = t + h
      ! land on t_end; no sliver of a step is left before it
      if (t_new >= t_end - 1.0e-3_dp * h) t_new = t_end
      h = t_new - t
      if (h < mbdk_adaptive_h_floor(opt, t, landing=t_new == t_end)) then
        stat = MBDK_ERR_STEP_TOO_SMALL
        return
      end if

      finite = .true.
      do i = 2, pr%s
        ynew = y
        do j = 1, i - 1
          if (pr%a(i, j) /= 0.0_dp) ynew = ynew + (h * pr%a(i, j)) * kk(:, j)
        end do
        call prob%rhs(t + pr%c(i) * h, ynew, kk(:, i), stat)
        st%nfev = st%nfev + 1
        if (stat /= MBDK_SUCCESS) return
        if (.not. all(abs(kk(:, i)) <= huge(1.0_dp))) then
          finite = .false.
          exit
        end if
      end do
      ! the last stage is F at y_new (a(s, :) = b): ynew holds y_new
      if (finite) then
        e = 0.0_dp
        do j = 1, pr%s
          if (pr%e(j) /= 0.0_dp) e = e + (h * pr%e(j)) * kk(:, j)
        end do
        call mbdk_adaptive_weights(opt, atol, max(abs(y), abs(ynew)), w)
        err = mbdk_adaptive_wrms(e, w)
        finite = err <= huge(1.0_dp)
      end if
      if (.not. finite) err = huge(1.0_dp)

      if (err > 1.0_dp) then
        st%rejected_steps = st%rejected_steps + 1
        h = h * max(FAC_MIN, SAFETY * err**expo)
        rejected_last = .true.
        cycle
      end if

      ! accepted: samples inside (t, t_new) from the dense output
      sample = .false.
      do while (k <= ns)
        if (t_out(k) >= t_new) exit
        theta = (t_out(k) - t) / h
        do j = 1, pr%s
          bth(j) = dense_weight(pr, j, theta)
        end do
        y_out(:, k) = y
        do j = 1, pr%s
          if (bth(j) /= 0.0_dp) y_out(:, k) = y_out(:, k) + (h * bth(j)) * kk(:, j)
        end do
        nwritten = k
        k = k + 1
        sample = .true.
      end do
      if (k <= ns) sample = sample .or. t_out(k) <= t_new
      call mbdk_adaptive_after_step(prob, t_new, ynew, sample, projected, stat)
      if (stat /= MBDK_SUCCESS) return
      st%steps = st%steps + 1
      t = t_new
      y = ynew
      if (projected) then
        call prob%rhs(t, y, kk(:, 1), stat)
        st%nfev = st%nfev + 1
        if (stat /= MBDK_SUCCESS) return
      else
        kk(:, 1) = kk(:, pr%s)
      end if
      do while (k <= ns)
        if (t_out(k) > t) exit
        y_out(:, k) = y
        nwritten = k
        k = k + 1
      end do
      fac = FAC_MAX
      if (rejected_last) fac = 1.0_dp
      if (err > 0.0_dp) fac = min(fac, SAFETY * err**expo)
      h = h * max(FAC_MIN, fac)
      rejected_last = .false.
    end do
    stat = MBDK_SUCCESS
  end subroutine mbdk_embedded_rk_solve

  !> sum_m p(j, m) theta^m: stage j's weight in the dense output at theta.
  pure real(dp) function dense_weight(pr, j, theta) result(wj)
    type(mbdk_pair_t), intent(in) :: pr
    integer, intent(in) :: j
    real(dp), intent(in) :: theta
    integer :: m
    wj = 0.0_dp
    do m = pr%degree, 1, -1
      wj = (wj + pr%p(j, m)) * theta
    end do
  end function dense_weight

end module mbdk_embedded_rk
