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

  !> The three Gauss-Legendre nodes of a step (fractions of it), at which a driver with a dense
  !> output hands the watch the state (watch_nodes): the work of dampers, loads and drivers is
  !> then integrated over the step to sixth order, by points inside it, rather than by the
  !> trapezoidal rule on its ends (a located event leaves its kink on a step's end), and a
  !> sample inside the step takes it from the quadratic through the three.
  real(dp), parameter, public :: MBDK_GAUSS3(3) = [0.5_dp - sqrt(0.15_dp), 0.5_dp, &
                                                  0.5_dp + sqrt(0.15_dp)]

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
    !> .true.: the problem forms, factorises and solves the Newton matrix E - c J of an
    !> implicit method itself (newton_jacobian, newton_factor, newton_solve: a large
    !> mechanism's DAE, whose matrix is sparse, mbdk_mechanism_dae); bdf then keeps no dense
    !> n x n matrix
    logical :: has_newton_matrix = .false.
  contains

    procedure(rhs_iface), deferred :: rhs
    procedure :: jac => no_jac
    procedure :: post_step => no_post_step
    procedure :: watch_start => no_watch_start
    procedure :: watch => no_watch
    procedure :: watch_wants_nodes => no_wants_nodes
    procedure :: watch_nodes => no_watch_nodes
    procedure :: events => no_events
    procedure :: newton_jacobian => no_newton_jacobian
    procedure :: newton_factor => no_newton_factor
    procedure :: newton_solve => no_newton_solve
    procedure :: singular_at => no_singular_at
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

  !> Default: no states inside a step are wanted (a watching problem whose work needs them
  !> says so: a driver with a dense output then calls watch_nodes before watch).
  logical function no_wants_nodes(self)
    class(mbdk_problem_t), intent(in) :: self
    no_wants_nodes = .false.
  end function no_wants_nodes

  !> Default: nothing to do with the states y(:, k) at t_a + MBDK_GAUSS3(k) (t_b - t_a) of the
  !> accepted step [t_a, t_b], which the watch's call for t_b follows.
  subroutine no_watch_nodes(self, t_a, t_b, y, stat)
    class(mbdk_problem_t), intent(in) :: self
    real(dp), intent(in) :: t_a, t_b, y(:, :)
    integer, intent(out) :: stat
    stat = MBDK_SUCCESS
  end subroutine no_watch_nodes

  !> Default: nothing watched. force: the step is a sample (or the last one): check it.
  subroutine no_watch(self, t, y, force, stat)
    class(mbdk_problem_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    stat = MBDK_SUCCESS
  end subroutine no_watch

  !> Default (has_newton_matrix false): J = dF/dy at (t, y) is not kept here; nfev: the
  !> evaluations of F it took.
  subroutine no_newton_jacobian(self, t, y, nfev, stat)
    class(mbdk_problem_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    integer, intent(out) :: nfev
    integer, intent(out) :: stat
    nfev = 0
    stat = MBDK_ERR_NOT_APPLICABLE
  end subroutine no_newton_jacobian

  !> Default: no matrix. The problem's own: E - c J (E = diag(em)) of the last
  !> newton_jacobian factorised, with the rows and columns of alg (E_ii = 0) divided by c
  !> (mbdk_variable_bdf's index scaling); MBDK_ERR_SINGULAR_MATRIX where a pivot vanishes.
  subroutine no_newton_factor(self, c, em, alg, stat)
    class(mbdk_problem_t), intent(in) :: self
    real(dp), intent(in) :: c, em(:)
    logical, intent(in) :: alg(:)
    integer, intent(out) :: stat
    stat = MBDK_ERR_NOT_APPLICABLE
  end subroutine no_newton_factor

  !> Default: no matrix. The problem's own: x overwritten by the solution of the last
  !> newton_factor's system.
  subroutine no_newton_solve(self, x, stat)
    class(mbdk_problem_t), intent(in) :: self
    real(dp), intent(inout), contiguous :: x(:)
    integer, intent(out) :: stat
    stat = MBDK_ERR_NOT_APPLICABLE
  end subroutine no_newton_solve

  !> Default: no state is a singular configuration. A problem with constraints says whether y
  !> lies next to a rank loss of them (a mechanism's DAE: mbdk_mechanism_dae), so that bdf
  !> names a stop there by that cause.
  logical function no_singular_at(self, t, y)
    class(mbdk_problem_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    no_singular_at = .false.
  end function no_singular_at

end module mbdk_problem
