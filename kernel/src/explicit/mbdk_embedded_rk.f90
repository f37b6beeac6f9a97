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

  !> One solve's state: the pair, the step (from t with h to t_new), the stages kk (kk(:, 1) =
  !> F(t, y)), the error estimate err, and the events at the step's start (g0) and end (g1).
  type :: rk_t
    type(mbdk_pair_t) :: pr
    real(dp) :: t = 0.0_dp, t_end = 0.0_dp, t_new = 0.0_dp, h = 0.0_dp, hmax = 0.0_dp
    !> err: the last step's WRMS error estimate (huge where a stage failed); expo = -1/(q+1)
    real(dp) :: err = 0.0_dp, expo = 0.0_dp
    integer(i8) :: tries = 0, limit = 0
    !> how often this step has been shortened to end at an event's root
    integer :: redo = 0
    !> the last step was rejected; its stages were not finite; a contact overran at one
    logical :: rejected_last = .false., nonfinite_last = .false., overrun_last = .false.
    real(dp), allocatable :: y(:), ynew(:), kk(:, :), w(:), e(:), bth(:), g0(:), g1(:), gt(:)
    !> the dense output at an event's trial point, and at the Gauss nodes of a step
    real(dp), allocatable :: yt(:), yn(:, :)
  end type rk_t

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
    type(rk_t) :: r
    integer :: k
    logical :: shortened

    call rk_start(r, prob, opt, atol, t0, y0, t_out(size(t_out)), st, stat)
    if (stat /= MBDK_SUCCESS) return
    k = nwritten + 1           ! the next sample to write
    do while (r%t < r%t_end)
      if (opt%interrupt /= 0 .and. mbdk_interrupted(opt%interrupt)) then
        stat = MBDK_ERR_INTERRUPTED
        return
      end if
      if (opt%progress /= 0) call mbdk_progress(opt%progress, r%t)
      if (r%tries >= r%limit) then
        stat = MBDK_ERR_TOO_MANY_STEPS
        return
      end if
      r%tries = r%tries + 1
      call aim_step(r, opt, stat)
      if (stat /= MBDK_SUCCESS) return
      call stages_and_error(r, prob, opt, atol, st, stat)
      if (stat /= MBDK_SUCCESS) return
      if (r%err > 1.0_dp) then
        st%rejected_steps = st%rejected_steps + 1
        r%h = r%h * max(FAC_MIN, SAFETY * r%err**r%expo)
        r%rejected_last = .true.
        cycle
      end if
      ! accepted, unless an event changed sign inside: then again, ending at its root
      if (prob%nevents > 0) then
        call shorten_at_event(r, prob, opt, shortened, stat)
        if (stat /= MBDK_SUCCESS) return
        if (shortened) cycle
      end if
      call accept_step(r, prob, t_out, y_out, k, nwritten, st, stat)
      if (stat /= MBDK_SUCCESS) return
    end do
    stat = MBDK_SUCCESS
  end subroutine mbdk_embedded_rk_solve

  !> The pair, the solve's storage, the events and F at (t0, y0) (F not finite there:
  !> MBDK_ERR_NONFINITE, no step size helps), and the first step.
  subroutine rk_start(r, prob, opt, atol, t0, y0, t_end, st, stat)
    type(rk_t), intent(inout) :: r
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: atol(:), t0, y0(:), t_end
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    logical :: found
    integer :: n, s, astat

    n = size(y0)
    r%t_end = t_end
    call mbdk_pair_table(opt%method, r%pr, found)
    stat = MBDK_ERR_UNKNOWN_METHOD
    if (.not. found) return
    s = r%pr%s
    allocate (r%y(n), r%ynew(n), r%kk(n, s), r%w(n), r%e(n), r%bth(s), r%g0(prob%nevents), &
              r%g1(prob%nevents), r%gt(prob%nevents), r%yt(n), r%yn(n, 3), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (real(n, dp) * (s + 8) + s + &
                                                     3.0_dp * prob%nevents), stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    r%y = y0
    r%t = t0
    st%t_reached = t0
    if (prob%nevents > 0) then
      call prob%events(r%t, r%y, r%g0, stat)
      if (stat /= MBDK_SUCCESS) return
    end if
    call prob%rhs(r%t, r%y, r%kk(:, 1), stat)
    st%nfev = st%nfev + 1
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_NONFINITE
    if (.not. all(abs(r%kk(:, 1)) <= huge(1.0_dp))) return
    call mbdk_adaptive_initial_step(prob, opt, atol, r%pr%est_order, t0, t_end - t0, r%y, &
                                    r%kk(:, 1), r%h, st%nfev, stat)
    if (stat /= MBDK_SUCCESS) return
    r%hmax = t_end - t0
    if (opt%h_max > 0.0_dp) r%hmax = min(r%hmax, opt%h_max)
    r%expo = -1.0_dp / real(r%pr%est_order + 1, dp)
    r%limit = mbdk_adaptive_step_limit(opt)
    r%tries = 0
    r%redo = 0
    r%rejected_last = .false.
    r%nonfinite_last = .false.
    r%overrun_last = .false.
  end subroutine rk_start

  !> The step from t: h within h_max, landing on t_end with no sliver left before it (unless an
  !> event shortened it). Below mbdk_adaptive_h_floor the solve ends: MBDK_ERR_STEP_TOO_SMALL,
  !> or the cause of the rejections that took h there (stages not finite: F is not finite next
  !> to this state, a singularity of the model, no step-size problem; a contact overrun).
  subroutine aim_step(r, opt, stat)
    type(rk_t), intent(inout) :: r
    type(mbdk_options_t), intent(in) :: opt
    integer, intent(out) :: stat
    r%h = min(r%h, r%hmax)
    r%t_new = r%t + r%h
    if (r%t_new >= r%t_end - 1.0e-3_dp * r%h .and. r%redo == 0) r%t_new = r%t_end
    if (r%t_new > r%t_end) r%t_new = r%t_end
    r%h = r%t_new - r%t
    stat = MBDK_SUCCESS
    if (r%h < mbdk_adaptive_h_floor(opt, r%t, landing=r%t_new == r%t_end)) then
      stat = MBDK_ERR_STEP_TOO_SMALL
      if (r%nonfinite_last) stat = MBDK_ERR_NONFINITE
      if (r%overrun_last) stat = MBDK_ERR_CONTACT_OVERRUN
    end if
  end subroutine aim_step

  !> The stages K_2 .. K_s of the step (y_new in r%ynew: the last stage is F at y_new, a(s, :)
  !> = b) and the WRMS norm of its error estimate, r%err; huge where a stage was not finite or
  !> a contact overran at it (a rejection, r%nonfinite_last or r%overrun_last).
  subroutine stages_and_error(r, prob, opt, atol, st, stat)
    type(rk_t), intent(inout) :: r
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: atol(:)
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    logical :: finite
    integer :: i, j
    finite = .true.
    r%overrun_last = .false.
    stat = MBDK_SUCCESS
    associate (pr => r%pr, h => r%h, kk => r%kk, ynew => r%ynew)
      do i = 2, pr%s
        ynew = r%y
        do j = 1, i - 1
          if (pr%a(i, j) /= 0.0_dp) ynew = ynew + (h * pr%a(i, j)) * kk(:, j)
        end do
        call prob%rhs(r%t + pr%c(i) * h, ynew, kk(:, i), stat)
        st%nfev = st%nfev + 1
        ! a stage is a trial point, not the solution: one a contact overruns at (a step too
        ! long across an impact) is a rejected step, as one whose F is not finite; only at the
        ! floor of the step is it the run's failure
        if (stat == MBDK_ERR_CONTACT_OVERRUN) then
          r%overrun_last = .true.
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
      if (finite) then
        r%e = 0.0_dp
        do j = 1, pr%s
          if (pr%e(j) /= 0.0_dp) r%e = r%e + (h * pr%e(j)) * kk(:, j)
        end do
        call mbdk_adaptive_weights(opt, atol, max(abs(r%y), abs(ynew)), r%w)
        r%err = mbdk_adaptive_wrms(r%e, r%w)
        finite = r%err <= huge(1.0_dp)
      end if
    end associate
    if (.not. finite) r%err = huge(1.0_dp)
    r%nonfinite_last = .not. finite .and. .not. r%overrun_last
  end subroutine stages_and_error

  !> Events at the end of a step that passed the error test; shortened: an event changed sign
  !> inside it, and the step is to be taken again ending just past the earliest root (the
  !> module header: not within EVENT_EDGE of an end, at most MAX_REDO times, not below the
  !> step floor). Otherwise the end's events become the next step's start.
  subroutine shorten_at_event(r, prob, opt, shortened, stat)
    type(rk_t), intent(inout) :: r
    class(mbdk_problem_t), intent(in) :: prob
    type(mbdk_options_t), intent(in) :: opt
    logical, intent(out) :: shortened
    integer, intent(out) :: stat
    real(dp) :: root
    shortened = .false.
    call prob%events(r%t_new, r%ynew, r%g1, stat)
    if (stat /= MBDK_SUCCESS) return
    call earliest_root(r, prob, root, stat)
    if (stat /= MBDK_SUCCESS) return
    if (root > EVENT_EDGE .and. root < 1.0_dp - EVENT_EDGE .and. r%redo < MAX_REDO .and. &
        root * r%h >= mbdk_adaptive_h_floor(opt, r%t, landing=.false.)) then
      r%h = root * r%h
      r%redo = r%redo + 1
      shortened = .true.
      return
    end if
    r%redo = 0
    r%g0 = r%g1
  end subroutine shorten_at_event

  !> The accepted step: the samples inside it from the dense output, the watch's Gauss nodes,
  !> the projection, finite check and watch (mbdk_adaptive_after_step), then t_new becomes t
  !> (F again at a projected state, as the next step's first stage; else FSAL), the sample at
  !> t, and the next step's size.
  subroutine accept_step(r, prob, t_out, y_out, k, nwritten, st, stat)
    type(rk_t), intent(inout) :: r
    class(mbdk_problem_t), intent(in) :: prob
    real(dp), intent(in) :: t_out(:)
    real(dp), intent(inout) :: y_out(:, :)
    integer, intent(inout) :: k, nwritten
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    logical :: sample, projected
    real(dp) :: fac
    call samples_inside(r, t_out, y_out, k, nwritten, sample)
    if (prob%has_watch) then
      if (prob%watch_wants_nodes()) then
        call watch_nodes(r, prob, stat)
        if (stat /= MBDK_SUCCESS) return
      end if
    end if
    call mbdk_adaptive_after_step(prob, r%t_new, r%ynew, sample, projected, stat)
    if (stat /= MBDK_SUCCESS) return
    st%steps = st%steps + 1
    r%t = r%t_new
    st%t_reached = r%t
    r%y = r%ynew
    if (projected) then
      call prob%rhs(r%t, r%y, r%kk(:, 1), stat)
      st%nfev = st%nfev + 1
      if (stat /= MBDK_SUCCESS) return
      if (prob%nevents > 0) call prob%events(r%t, r%y, r%g0, stat)
      if (stat /= MBDK_SUCCESS) return
    else
      r%kk(:, 1) = r%kk(:, r%pr%s)
    end if
    do while (k <= size(t_out))
      if (t_out(k) > r%t) exit
      y_out(:, k) = r%y
      nwritten = k
      k = k + 1
    end do
    fac = FAC_MAX
    if (r%rejected_last) fac = 1.0_dp
    if (r%err > 0.0_dp) fac = min(fac, SAFETY * r%err**r%expo)
    r%h = r%h * max(FAC_MIN, fac)
    r%rejected_last = .false.
  end subroutine accept_step

  !> The samples k, k + 1, ... inside (t, t_new) from the pair's dense output; sample: one of
  !> them or the next falls in the step.
  subroutine samples_inside(r, t_out, y_out, k, nwritten, sample)
    type(rk_t), intent(inout) :: r
    real(dp), intent(in) :: t_out(:)
    real(dp), intent(inout) :: y_out(:, :)
    integer, intent(inout) :: k, nwritten
    logical, intent(out) :: sample
    integer :: ns
    ns = size(t_out)
    sample = .false.
    do while (k <= ns)
      if (t_out(k) >= r%t_new) exit
      call dense_output(r%pr, r%h, r%y, r%kk, (t_out(k) - r%t) / r%h, r%bth, y_out(:, k))
      nwritten = k
      k = k + 1
      sample = .true.
    end do
    if (k <= ns) sample = sample .or. t_out(k) <= r%t_new
  end subroutine samples_inside

  !> The watch's work over the step (t, t_new]: the dense output at its Gauss nodes.
  subroutine watch_nodes(r, prob, stat)
    type(rk_t), intent(inout) :: r
    class(mbdk_problem_t), intent(in) :: prob
    integer, intent(out) :: stat
    integer :: i
    do i = 1, 3
      call dense_output(r%pr, r%h, r%y, r%kk, MBDK_GAUSS3(i), r%bth, r%yn(:, i))
    end do
    call prob%watch_nodes(r%t, r%t_new, r%yn, stat)
  end subroutine watch_nodes

  !> The earliest theta in (0, 1] at which an event that changes sign over the step (g0 at
  !> theta = 0, g1 at 1) crosses zero on the dense output, by the Illinois variant of regula
  !> falsi to 1e-12 of the step; 1 when none does.
  subroutine earliest_root(r, prob, root, stat)
    type(rk_t), intent(inout) :: r
    class(mbdk_problem_t), intent(in) :: prob
    real(dp), intent(out) :: root
    integer, intent(out) :: stat
    integer :: ev, it, side
    real(dp) :: a, b, ga, gb, c, gc
    root = 1.0_dp
    stat = MBDK_SUCCESS
    do ev = 1, size(r%g0)
      if (.not. ((r%g0(ev) > 0.0_dp .and. r%g1(ev) <= 0.0_dp) .or. &
                 (r%g0(ev) <= 0.0_dp .and. r%g1(ev) > 0.0_dp))) cycle
      a = 0.0_dp
      b = 1.0_dp
      ga = r%g0(ev)
      gb = r%g1(ev)
      side = 0
      do it = 1, 100
        c = (a * gb - b * ga) / (gb - ga)
        if (.not. (c > a .and. c < b)) c = 0.5_dp * (a + b)
        call event_at(r, prob, c, ev, gc, stat)
        if (stat /= MBDK_SUCCESS) return
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
  subroutine event_at(r, prob, th, ev, gv, stat)
    type(rk_t), intent(inout) :: r
    class(mbdk_problem_t), intent(in) :: prob
    real(dp), intent(in) :: th
    integer, intent(in) :: ev
    real(dp), intent(out) :: gv
    integer, intent(out) :: stat
    call dense_output(r%pr, r%h, r%y, r%kk, th, r%bth, r%yt)
    call prob%events(r%t + th * r%h, r%yt, r%gt, stat)
    gv = r%gt(ev)
  end subroutine event_at

  !> yy = y + h sum_j b_j(theta) K_j: the dense output of the step from y with h at theta
  !> (bth: the weights b_j(theta)).
  subroutine dense_output(pr, h, y, kk, theta, bth, yy)
    type(mbdk_pair_t), intent(in) :: pr
    real(dp), intent(in) :: h, y(:), kk(:, :), theta
    real(dp), intent(out) :: bth(:), yy(:)
    integer :: j
    do j = 1, pr%s
      bth(j) = dense_weight(pr, j, theta)
    end do
    yy = y
    do j = 1, pr%s
      if (bth(j) /= 0.0_dp) yy = yy + (h * bth(j)) * kk(:, j)
    end do
  end subroutine dense_output

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
