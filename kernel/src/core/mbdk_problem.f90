!> The abstract first-order problem y' = F(t, y) every integrator works on.
!>
!> A problem with nq > 0 is a second-order system in first-order layout: y = [q; v] with
!> n = 2*nq and q' = v; Euler-Cromer needs this structure. rhs returns a status through stat
!> (MBDK_SUCCESS or a failure code such as MBDK_ERR_CALLBACK_FAILED); it must not print or stop.
!> rhs receives y and returns f as contiguous arrays (declared so: an implementation repeats
!> the attribute): a model can hand slices of them on without copies, which is measurable when
!> an evaluation costs a hundred nanoseconds (the scenes' reduced rk4 step, issue 3).
module mbdk_problem
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_ERR_NOT_APPLICABLE, MBDK_SUCCESS
  implicit none
  private

  type, abstract, public :: mbdk_problem_t
    integer :: n = 0             !< number of states
    integer :: nq = 0            !< > 0: y = [q; v], q' = v, n = 2*nq
    logical :: has_jac = .false. !< .true. when jac gives the analytic dF/dy
    logical :: has_post_step = .false. !< .true.: the driver calls post_step after every step
    !> .true.: the driver calls watch_start at t0 and watch after every accepted step (a scene
    !> watching its constraints and energy, mbdk_watch)
    logical :: has_watch = .false.
    !> > 0: events g(t, y) whose sign changes the error-controlled Runge-Kutta pairs locate and
    !> end a step on (a contact that closes or opens: F is not smooth there)
    integer :: nevents = 0
  contains

    procedure(rhs_iface), deferred :: rhs
    procedure :: jac => no_jac
    procedure :: post_step => no_post_step
    procedure :: watch_start => no_watch_start
    procedure :: watch => no_watch
    procedure :: events => no_events
  end type mbdk_problem_t

  abstract interface
    subroutine rhs_iface(self, t, y, f, stat)
      import :: mbdk_problem_t, dp
      class(mbdk_problem_t), intent(in) :: self
      real(dp), intent(in) :: t
      real(dp), intent(in), contiguous :: y(:)
      real(dp), intent(out), contiguous :: f(:)
      integer, intent(out) :: stat
    end subroutine rhs_iface
  end interface

contains

  !> Default: no analytic Jacobian (the Newton solver then uses finite differences).
  subroutine no_jac(self, t, y, jac, stat)
    class(mbdk_problem_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: jac(:, :)
    integer, intent(out) :: stat
    jac = 0.0_dp
    stat = MBDK_ERR_NOT_APPLICABLE  ! callers check has_jac first
  end subroutine no_jac

  !> Default: nothing to do after a step (a projection onto a manifold overrides this).
  subroutine no_post_step(self, t, y, stat)
    class(mbdk_problem_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: y(:)
    integer, intent(out) :: stat
    stat = MBDK_SUCCESS
  end subroutine no_post_step

  !> Default: nothing watched.
  subroutine no_watch_start(self, t, y, stat)
    class(mbdk_problem_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    integer, intent(out) :: stat
    stat = MBDK_SUCCESS
  end subroutine no_watch_start

  !> Default: no events (nevents = 0).
  subroutine no_events(self, t, y, g, stat)
    class(mbdk_problem_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: g(:)
    integer, intent(out) :: stat
    g = 0.0_dp
    stat = MBDK_SUCCESS
  end subroutine no_events

  !> Default: nothing watched. force: the step is a sample (or the last one): check it.
  subroutine no_watch(self, t, y, force, stat)
    class(mbdk_problem_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    stat = MBDK_SUCCESS
  end subroutine no_watch

end module mbdk_problem
