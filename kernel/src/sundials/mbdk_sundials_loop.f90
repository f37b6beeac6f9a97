!> The one-step loop of the SUNDIALS drivers, written once: cvode_bdf and cvode_adams
!> (mbdk_cvode) and ida (mbdk_ida) each extend mbdk_sundials_loop_t with the calls of their
!> solver and the hooks of their problem, and keep only their set-up, teardown and status
!> table.
!>
!> The solver takes one internal step per call and never passes t_end (its stop time). Before
!> each step the interrupt flag is polled (opt%interrupt) and the time reached is stored for the
!> progress bar (opt%progress); opt%max_steps (0: MBDK_ADAPTIVE_MAX_STEPS) bounds the steps taken
!> plus the steps the solver retried after a failure, counted here (the solver's own limit is
!> off): MBDK_ERR_TOO_MANY_STEPS. After each step:
!>   1. a step below mbdk_adaptive_h_floor (opt%h_min, and 10 ulps of t) is
!>      MBDK_ERR_STEP_TOO_SMALL: SUNDIALS' own floor is h_min, 0 by default, and a step that
!>      cannot move t would repeat. The step that lands on t_end is held to the rounding floor
!>      only where landing_floor is set (CVODE), and not at all otherwise (IDA shortens its last
!>      step to land on t_end, whatever its length);
!>   2. the step's order is counted (mbdk_adaptive_count_order; order5_steps also takes Adams'
!>      orders 6..12);
!>   3. the samples inside the step come from the solver's interpolant (dky) and the sample at
!>      the step's end is the step's own state;
!>   4. the state is checked (finite: else MBDK_ERR_NONFINITE);
!>   5. a watch that integrates a work gets the interpolant at the step's Gauss nodes
!>      (MBDK_GAUSS3) and then the driver's accept hook runs the watch (sample = a sample time
!>      fell in the step);
!>   6. t_reached is the step's time: it passed its checks.
!> A failed hook or solver call ends the loop with its status; the driver then frees its solver
!> and adds the solver's counters to the statistics.
module mbdk_sundials_loop
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_problem, only: MBDK_GAUSS3
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_interrupt, only: mbdk_interrupted, mbdk_progress
  use mbdk_adaptive, only: mbdk_adaptive_step_limit, mbdk_adaptive_h_floor, &
    mbdk_adaptive_count_order
  implicit none
  private
  public :: mbdk_sundials_run

  !> A SUNDIALS solver as the loop drives it. y: the solver's state (its vector's own storage);
  !> ydky: the buffer dky writes the interpolant into. Both have the solver's length; the
  !> samples take their first size(y_out, 1) entries, write_extra the rest.
  type, abstract, public :: mbdk_sundials_loop_t
    real(dp), pointer, contiguous :: y(:) => null(), ydky(:) => null()
    !> the step that lands on t_end is held to the rounding floor (see the module header)
    logical :: landing_floor = .true.
  contains
    procedure(step_iface), deferred :: step
    procedure(tries_iface), deferred :: tries
    procedure(last_iface), deferred :: last_step
    procedure(dky_iface), deferred :: dky
    procedure(wants_iface), deferred :: wants_nodes
    procedure(node_iface), deferred :: keep_node
    procedure(nodes_iface), deferred :: watch_nodes
    procedure(accept_iface), deferred :: accept
    procedure :: write_extra => no_extra
  end type mbdk_sundials_loop_t

  abstract interface
    !> One internal step towards t_stop, which it does not pass; t: the time reached. stat: a
    !> callback's failure, or the solver's failure flag as a status (the driver's table).
    subroutine step_iface(self, t_stop, t, stat)
      import :: mbdk_sundials_loop_t, dp
      class(mbdk_sundials_loop_t), intent(inout) :: self
      real(dp), intent(in) :: t_stop
      real(dp), intent(out) :: t
      integer, intent(out) :: stat
    end subroutine step_iface
    !> The steps taken plus the steps retried after a failure, as max_steps counts them.
    integer(i8) function tries_iface(self)
      import :: mbdk_sundials_loop_t, i8
      class(mbdk_sundials_loop_t), intent(inout) :: self
    end function tries_iface
    !> The last step's size and order.
    subroutine last_iface(self, h, q)
      import :: mbdk_sundials_loop_t, dp
      class(mbdk_sundials_loop_t), intent(inout) :: self
      real(dp), intent(out) :: h
      integer, intent(out) :: q
    end subroutine last_iface
    !> The interpolant at t into self%ydky; stat MBDK_ERR_BACKEND where the solver refuses.
    subroutine dky_iface(self, t, stat)
      import :: mbdk_sundials_loop_t, dp
      class(mbdk_sundials_loop_t), intent(inout) :: self
      real(dp), intent(in) :: t
      integer, intent(out) :: stat
    end subroutine dky_iface
    !> Whether the watch integrates a work over each step (the problem's watch_wants_nodes).
    logical function wants_iface(self)
      import :: mbdk_sundials_loop_t
      class(mbdk_sundials_loop_t), intent(inout) :: self
    end function wants_iface
    !> self%ydky holds the state at Gauss node i of the step: keep it for watch_nodes.
    subroutine node_iface(self, i)
      import :: mbdk_sundials_loop_t
      class(mbdk_sundials_loop_t), intent(inout) :: self
      integer, intent(in) :: i
    end subroutine node_iface
    !> The kept node states of the accepted step (t_a, t_b] to the watch.
    subroutine nodes_iface(self, t_a, t_b, stat)
      import :: mbdk_sundials_loop_t, dp
      class(mbdk_sundials_loop_t), intent(inout) :: self
      real(dp), intent(in) :: t_a, t_b
      integer, intent(out) :: stat
    end subroutine nodes_iface
    !> The accepted step's state self%y at t to the watch (sample: a sample time fell in the
    !> step), and whatever else the driver does after a step.
    subroutine accept_iface(self, t, sample, stat)
      import :: mbdk_sundials_loop_t, dp
      class(mbdk_sundials_loop_t), intent(inout) :: self
      real(dp), intent(in) :: t
      logical, intent(in) :: sample
      integer, intent(out) :: stat
    end subroutine accept_iface
  end interface

contains

  !> See the module header. From t0 (the solver initialised there) to t_end = t_out's last time;
  !> t_out: the sample times (sample nwritten, at least the first, written by the caller);
  !> y_out receives the later samples. stat: MBDK_SUCCESS at t_end, else the failure's status.
  subroutine mbdk_sundials_run(lp, opt, t0, t_out, y_out, nwritten, st, stat)
    class(mbdk_sundials_loop_t), intent(inout) :: lp
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_out(:)
    real(dp), intent(inout) :: y_out(:, :)
    integer, intent(inout) :: nwritten
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    integer(i8) :: limit
    integer :: ns, k, q
    real(dp) :: t, told, t_end, hlast
    logical :: sample

    ns = size(t_out)
    t_end = t_out(ns)
    limit = mbdk_adaptive_step_limit(opt)
    k = nwritten + 1           ! the next sample to write
    t = t0
    told = t0
    st%t_reached = t0
    do while (t < t_end)
      if (opt%interrupt /= 0 .and. mbdk_interrupted(opt%interrupt)) then
        stat = MBDK_ERR_INTERRUPTED
        return
      end if
      if (opt%progress /= 0) call mbdk_progress(opt%progress, t)
      if (lp%tries() >= limit) then
        stat = MBDK_ERR_TOO_MANY_STEPS
        return
      end if
      call lp%step(t_end, t, stat)
      if (stat /= MBDK_SUCCESS) return
      call lp%last_step(hlast, q)
      if (too_small(lp, opt, t, t_end, hlast)) then
        stat = MBDK_ERR_STEP_TOO_SMALL
        return
      end if
      call mbdk_adaptive_count_order(st, q)
      call samples_inside(lp, t, t_out, y_out, k, nwritten, sample, stat)
      if (stat /= MBDK_SUCCESS) return
      if (.not. all(abs(lp%y) <= huge(1.0_dp))) then
        stat = MBDK_ERR_NONFINITE
        return
      end if
      if (lp%wants_nodes()) then
        call gauss_nodes(lp, told, t, stat)
        if (stat /= MBDK_SUCCESS) return
      end if
      told = t
      call lp%accept(t, sample, stat)
      if (stat /= MBDK_SUCCESS) return
      st%t_reached = t      ! the step passed its checks
      do while (k <= ns)
        if (t_out(k) > t) exit
        y_out(:, k) = lp%y(1:size(y_out, 1))
        call lp%write_extra(k, lp%y)
        nwritten = k
        k = k + 1
      end do
    end do
    stat = MBDK_SUCCESS
  end subroutine mbdk_sundials_run

  !> Whether the step h that ended at t is below the floor (the module header, item 1).
  logical function too_small(lp, opt, t, t_end, h)
    class(mbdk_sundials_loop_t), intent(in) :: lp
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t, t_end, h
    if (t < t_end) then
      too_small = h < mbdk_adaptive_h_floor(opt, t)
    else
      too_small = .false.
      if (lp%landing_floor) too_small = h < mbdk_adaptive_h_floor(opt, t, landing=.true.)
    end if
  end function too_small

  !> The samples k, k + 1, ... before t from the interpolant; sample: one of them or the
  !> next falls in the step, which ends at t.
  subroutine samples_inside(lp, t, t_out, y_out, k, nwritten, sample, stat)
    class(mbdk_sundials_loop_t), intent(inout) :: lp
    real(dp), intent(in) :: t, t_out(:)
    real(dp), intent(inout) :: y_out(:, :)
    integer, intent(inout) :: k, nwritten
    logical, intent(out) :: sample
    integer, intent(out) :: stat
    integer :: ns
    ns = size(t_out)
    sample = .false.
    stat = MBDK_SUCCESS
    do while (k <= ns)
      if (t_out(k) >= t) exit
      call lp%dky(t_out(k), stat)
      if (stat /= MBDK_SUCCESS) return
      y_out(:, k) = lp%ydky(1:size(y_out, 1))
      call lp%write_extra(k, lp%ydky)
      nwritten = k
      k = k + 1
      sample = .true.
    end do
    if (k <= ns) sample = sample .or. t_out(k) <= t
  end subroutine samples_inside

  !> The watch's work over the step (t_a, t_b]: the interpolant at its Gauss nodes.
  subroutine gauss_nodes(lp, t_a, t_b, stat)
    class(mbdk_sundials_loop_t), intent(inout) :: lp
    real(dp), intent(in) :: t_a, t_b
    integer, intent(out) :: stat
    integer :: i
    do i = 1, 3
      call lp%dky(t_a + MBDK_GAUSS3(i) * (t_b - t_a), stat)
      if (stat /= MBDK_SUCCESS) return
      call lp%keep_node(i)
    end do
    call lp%watch_nodes(t_a, t_b, stat)
  end subroutine gauss_nodes

  !> Default: the samples are y_out's entries of the state and nothing else.
  subroutine no_extra(self, k, src)
    class(mbdk_sundials_loop_t), intent(inout) :: self
    integer, intent(in) :: k
    real(dp), intent(in) :: src(:)
  end subroutine no_extra

end module mbdk_sundials_loop
