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
!> Wanner, Solving ODEs I, II.4). A stage that is not finite (h far beyond the stability limit),
!> or at which a contact overruns its model (MBDK_ERR_CONTACT_OVERRUN: a trial point that a step
!> too long carried across an impact), counts as a rejection with err = infinity, not as a
!> failure. The first step: opt%h, or
!> mbdk_adaptive_initial_step. h never exceeds opt%h_max or what is left to t_end; the last step
!> lands on t_end exactly. Below mbdk_adaptive_h_floor: MBDK_ERR_STEP_TOO_SMALL, or
!> MBDK_ERR_NONFINITE where the rejection that took it there had stages not finite (F is not
!> finite next to the state: no step is small enough), MBDK_ERR_CONTACT_OVERRUN where it had
!> a stage overrun; F not finite at the initial state:
!> MBDK_ERR_NONFINITE at once.
!>
!> Samples inside a step come from the pair's dense output; a sample at the step's end is the
!> step's state itself. A watching problem that integrates a work gets the dense output at the
!> step's three Gauss nodes too (watch_nodes, mbdk_problem). After a projection
!> (has_post_step) F is evaluated again at the projected state, as the next step's first stage.
!>
!> Events (prob%nevents > 0: a contact's penetration, mbdk_problem). F is not smooth where an
!> event function changes sign (a contact closes or opens), and a step across that point
!> carries a low-order error that the controller meets only by rejecting steps and shrinking h
!> around it. So an accepted step whose end has an event of another sign than its start is
!> searched for the earliest root on the dense output (the Illinois variant of regula falsi on
!> g(y(theta)), to 1e-12 of the step), then taken again, shortened to end just past it; the
!> root then lies on the step boundary, and each step sees F on one side of it only. A root
!> within EVENT_EDGE of either end of a step is taken as it lands (the shortened step's own
!> dense output puts the root a little off its end, and the next step's start sits on it), and
!> so is one whose shortened step would fall below the step floor; a step is shortened at most
!> MAX_REDO times, and a shortened step is not stretched to land on t_end. A contact that closes
!> and opens again within one step leaves no sign change between its ends and is not seen.
module mbdk_embedded_rk
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t, MBDK_GAUSS3
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  use mbdk_interrupt, only: mbdk_interrupted, mbdk_progress
  use mbdk_embedded_pairs, only: mbdk_pair_t, mbdk_pair_table
  use mbdk_adaptive, only: mbdk_adaptive_weights, mbdk_adaptive_wrms, mbdk_adaptive_after_step, &
    mbdk_adaptive_step_limit, mbdk_adaptive_initial_step, mbdk_adaptive_h_floor
  implicit none
  private
  public :: mbdk_embedded_rk_solve

  real(dp), parameter :: SAFETY = 0.9_dp, FAC_MIN = 0.2_dp, FAC_MAX = 10.0_dp
  real(dp), parameter :: EVENT_EDGE = 1.0e-6_dp
  integer, parameter :: MAX_REDO = 3

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
    logical :: found, rejected_last, finite, projected, sample, nonfinite_last, overrun_last
    integer :: n, i, j, ns, k, redo
    integer(i8) :: tries, limit
    real(dp) :: t, t_end, h, hmax, err, expo, fac, theta, t_new, root
    real(dp), allocatable :: y(:), ynew(:), kk(:, :), w(:), e(:), bth(:), g0(:), g1(:), gt(:)
    real(dp), allocatable :: yt(:), yn(:, :)

    n = size(y0)
    ns = size(t_out)
    t_end = t_out(ns)
    call mbdk_pair_table(opt%method, pr, found)
    stat = MBDK_ERR_UNKNOWN_METHOD
    if (.not. found) return
    allocate (y(n), ynew(n), kk(n, pr%s), w(n), e(n), bth(pr%s), g0(prob%nevents), &
              g1(prob%nevents), gt(prob%nevents), yt(n), yn(n, 3), stat=redo)
    call mbdk_alloc_status(redo, MBDK_REAL_BYTES * (real(n, dp) * (pr%s + 8) + pr%s + &
                                                    3.0_dp * prob%nevents), stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    y = y0
    t = t0
    st%t_reached = t0
    if (prob%nevents > 0) then
      call prob%events(t, y, g0, stat)
      if (stat /= MBDK_SUCCESS) return
    end if
    call prob%rhs(t, y, kk(:, 1), stat)
    st%nfev = st%nfev + 1
    if (stat /= MBDK_SUCCESS) return
    ! F not finite at the initial state: no step size helps
    stat = MBDK_ERR_NONFINITE
    if (.not. all(abs(kk(:, 1)) <= huge(1.0_dp))) return
    call mbdk_adaptive_initial_step(prob, opt, atol, pr%est_order, t0, t_end - t0, y, kk(:, 1), &
                                    h, st%nfev, stat)
    if (stat /= MBDK_SUCCESS) return
    hmax = t_end - t0
    if (opt%h_max > 0.0_dp) hmax = min(hmax, opt%h_max)
    expo = -1.0_dp / real(pr%est_order + 1, dp)
    limit = mbdk_adaptive_step_limit(opt)
    tries = 0
    redo = 0
    rejected_last = .false.
    nonfinite_last = .false.
    overrun_last = .false.
    k = nwritten + 1           ! the next sample to write

    do while (t < t_end)
      if (opt%interrupt /= 0 .and. mbdk_interrupted(opt%interrupt)) then
        stat = MBDK_ERR_INTERRUPTED
        return
      end if
      if (opt%progress /= 0) call mbdk_progress(opt%progress, t)
      if (tries >= limit) then
        stat = MBDK_ERR_TOO_MANY_STEPS
        return
      end if
      tries = tries + 1
      h = min(h, hmax)
      t_new = t + h
      ! land on t_end; no sliver of a step is left before it (unless an event shortened it)
      if (t_new >= t_end - 1.0e-3_dp * h .and. redo == 0) t_new = t_end
      if (t_new > t_end) t_new = t_end
      h = t_new - t
      if (h < mbdk_adaptive_h_floor(opt, t, landing=t_new == t_end)) then
        ! a step shrunk to the floor by stages that were not finite: F is not finite next to
        ! this state (a singularity of the model), which is no step-size problem
        stat = MBDK_ERR_STEP_TOO_SMALL
        if (nonfinite_last) stat = MBDK_ERR_NONFINITE
        if (overrun_last) stat = MBDK_ERR_CONTACT_OVERRUN
        return
      end if

      finite = .true.
      overrun_last = .false.
      do i = 2, pr%s
        ynew = y
        do j = 1, i - 1
          if (pr%a(i, j) /= 0.0_dp) ynew = ynew + (h * pr%a(i, j)) * kk(:, j)
        end do
        call prob%rhs(t + pr%c(i) * h, ynew, kk(:, i), stat)
        st%nfev = st%nfev + 1
        ! a stage is a trial point, not the solution: one a contact overruns at (a step too
        ! long across an impact) is a rejected step, as one whose F is not finite; only at the
        ! floor of the step is it the run's failure
        if (stat == MBDK_ERR_CONTACT_OVERRUN) then
          overrun_last = .true.
          finite = .false.
          stat = MBDK_SUCCESS
          exit
        end if
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
      nonfinite_last = .not. finite .and. .not. overrun_last

      if (err > 1.0_dp) then
        st%rejected_steps = st%rejected_steps + 1
        h = h * max(FAC_MIN, SAFETY * err**expo)
        rejected_last = .true.
        cycle
      end if

      ! accepted, unless an event changed sign inside: then again, ending at its root
      if (prob%nevents > 0) then
        call prob%events(t_new, ynew, g1, stat)
        if (stat /= MBDK_SUCCESS) return
        call earliest_root(root, stat)
        if (stat /= MBDK_SUCCESS) return
        if (root > EVENT_EDGE .and. root < 1.0_dp - EVENT_EDGE .and. redo < MAX_REDO .and. &
            root * h >= mbdk_adaptive_h_floor(opt, t, landing=.false.)) then
          h = root * h
          redo = redo + 1
          cycle
        end if
        redo = 0
        g0 = g1
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
      ! the watch's work over the step from the dense output inside it
      if (prob%has_watch) then
        if (prob%watch_wants_nodes()) then
          do i = 1, 3
            do j = 1, pr%s
              bth(j) = dense_weight(pr, j, MBDK_GAUSS3(i))
            end do
            yn(:, i) = y
            do j = 1, pr%s
              if (bth(j) /= 0.0_dp) yn(:, i) = yn(:, i) + (h * bth(j)) * kk(:, j)
            end do
          end do
          call prob%watch_nodes(t, t_new, yn, stat)
          if (stat /= MBDK_SUCCESS) return
        end if
      end if
      call mbdk_adaptive_after_step(prob, t_new, ynew, sample, projected, stat)
      if (stat /= MBDK_SUCCESS) return
      st%steps = st%steps + 1
      t = t_new
      st%t_reached = t
      y = ynew
      if (projected) then
        call prob%rhs(t, y, kk(:, 1), stat)
        st%nfev = st%nfev + 1
        if (stat /= MBDK_SUCCESS) return
        if (prob%nevents > 0) call prob%events(t, y, g0, stat)
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

  contains

    !> The earliest theta in (0, 1] at which an event that changes sign over the step (g0 at
    !> theta = 0, g1 at 1) crosses zero on the dense output; 1 when none does.
    subroutine earliest_root(root, st_)
      real(dp), intent(out) :: root
      integer, intent(out) :: st_
      integer :: ev, it, side
      real(dp) :: a, b, ga, gb, c, gc
      root = 1.0_dp
      st_ = MBDK_SUCCESS
      do ev = 1, size(g0)
        if (.not. ((g0(ev) > 0.0_dp .and. g1(ev) <= 0.0_dp) .or. &
                   (g0(ev) <= 0.0_dp .and. g1(ev) > 0.0_dp))) cycle
        a = 0.0_dp
        b = 1.0_dp
        ga = g0(ev)
        gb = g1(ev)
        side = 0
        do it = 1, 100
          c = (a * gb - b * ga) / (gb - ga)
          if (.not. (c > a .and. c < b)) c = 0.5_dp * (a + b)
          call event_at(c, ev, gc, st_)
          if (st_ /= MBDK_SUCCESS) return
          if ((gc > 0.0_dp) .eqv. (ga > 0.0_dp)) then
            a = c
            ga = gc
            if (side == -1) gb = 0.5_dp * gb
            side = -1
          else
            b = c
            gb = gc
            if (side == 1) ga = 0.5_dp * ga
            side = 1
          end if
          if (b - a < 1.0e-12_dp) exit
        end do
        ! b: the first point past the root, so that the shortened step ends on its other side
        root = min(root, b)
      end do
    end subroutine earliest_root

    !> Event ev at theta of the step, on the dense output.
    subroutine event_at(th, ev, gv, st_)
      real(dp), intent(in) :: th
      integer, intent(in) :: ev
      real(dp), intent(out) :: gv
      integer, intent(out) :: st_
      integer :: jj
      yt = y
      do jj = 1, pr%s
        bth(jj) = dense_weight(pr, jj, th)
        if (bth(jj) /= 0.0_dp) yt = yt + (h * bth(jj)) * kk(:, jj)
      end do
      call prob%events(t + th * h, yt, gt, st_)
      gv = gt(ev)
    end subroutine event_at

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
