!> The mechanism interface: what every algorithm above the models knows of a scene, planar or
!> spatial (Fekete (2023) (2.54) in the velocity form of chapter 5):
!>
!>   q' = T(q) v,   M v' + C(q)^T lam = f(t, q, v),   Phi(q, t) = 0,
!>   Phi' = C v + Phi_t,   Phi'' = C v' - gamma(t, q, v)
!>
!> q the ncoord coordinates, v the nvel velocities, C = dPhi/dq T the Jacobian in the
!> velocities (m rows), M constant. A planar body is the case T = I, C = D (x, y, theta; its
!> velocities are q'); a spatial body keeps (r, p) with p a quaternion or three angles and
!> v = (r', Omega), Omega in the body frame, so that M = diag(m I, J) is constant and f holds
!> the gyroscopic moment -Omega x J Omega. The ODE state of a mechanism is y = [q; v; w], w the
!> ns states of the scene's effects (wear volumes).
!>
!> The two models (mbdk_model, mbdk_spatial_model) extend this type; the DAE forms of bdf
!> (mbdk_mechanism_dae), ida's residual (mbdk_ida) and the DAE driver (mbdk_solve) are written
!> once against it and never ask which model they have. What the type offers:
!>   sizes        nb, ncoord, nvel, m (constraint rows), ns (effect states); formulation (the
!>                ODE's way of keeping the constraints: MBDK_FORM_*, the same codes in both
!>                models); pfaffian(m): rows that constrain velocities only (a knife edge:
!>                its "Phi" row is C v + Phi_t)
!>   evaluate     f, Phi, C (dense, m x nvel), gamma and Phi_t at (t, q, v)
!>   mass         M x and M^-1 x; diag_mass and mass_diagonal where M is diagonal (planar:
!>                a body without inertia has a zero there, and no M^-1)
!>   rates        q' = T(q) v (with a spatial scene's norm stabilisation where it asks for it)
!>   accelerations  a and lam of the formulation's constrained solve (the reduced ODE's), the
!>                consistent start of a DAE
!>   active_rows  the rows whose multipliers are solved (a redundant spatial scene keeps an
!>                independent subset; the others carry zero)
!>   watch_lam, watch_nodes_lam   the scene's watch (mbdk_watch) at [q; v] with multipliers
!>                given (a DAE's own), for the drivers' power
module mbdk_mechanism
  use mbdk_kinds, only: dp
  use mbdk_problem, only: mbdk_problem_t
  implicit none
  private

  !> the ODE formulations (Fekete (2023) section 3), one code in both models
  integer, parameter, public :: MBDK_FORM_REDUCED = 1, MBDK_FORM_BAUMGARTE = 2, &
    MBDK_FORM_PENALTY = 3, MBDK_FORM_PROJECTION = 4

  type, abstract, extends(mbdk_problem_t), public :: mbdk_mechanism_t
    integer :: nb = 0        !< bodies
    integer :: ncoord = 0    !< coordinates q
    integer :: nvel = 0      !< velocities v
    integer :: m = 0         !< constraint rows
    integer :: ns = 0        !< effect states
    integer :: formulation = MBDK_FORM_REDUCED
    !> M is diagonal (mass_diagonal gives it; it may hold zeros): the DAE forms then keep
    !> M v' on the left, E = diag(I, M, 0), else they apply M^-1 (E = diag(I, I, 0))
    logical :: diag_mass = .false.
    logical :: has_pfaffian = .false.
    logical, allocatable :: pfaffian(:)
  contains
    procedure(evaluate_iface), deferred :: evaluate
    procedure(times_iface), deferred :: mass_times
    procedure(times_iface), deferred :: minv_times
    procedure(diagonal_iface), deferred :: mass_diagonal
    procedure(rates_iface), deferred :: rates
    procedure(accelerations_iface), deferred :: accelerations
    procedure(rows_iface), deferred :: active_rows
    procedure(watch_lam_iface), deferred :: watch_lam
    procedure(watch_nodes_lam_iface), deferred :: watch_nodes_lam
  end type mbdk_mechanism_t

  abstract interface
    !> f (nvel), Phi, C (m x nvel), gamma, Phi_t (m) at (t, q, v). stat: MBDK_ERR_NONFINITE
    !> for a non-finite q or v, a force element's or the rotations' failure.
    subroutine evaluate_iface(self, t, q, v, f, phi, c, gam, phit, stat)
      import :: mbdk_mechanism_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      real(dp), intent(in) :: t
      real(dp), intent(in), contiguous :: q(:), v(:)
      real(dp), intent(out), contiguous :: f(:), phi(:), c(:, :), gam(:), phit(:)
      integer, intent(out) :: stat
    end subroutine evaluate_iface

    !> y = M x (mass_times) or M^-1 x (minv_times), x and y of nvel
    subroutine times_iface(self, x, y)
      import :: mbdk_mechanism_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      real(dp), intent(in) :: x(:)
      real(dp), intent(out) :: y(:)
    end subroutine times_iface

    !> the diagonal of M (nvel), where diag_mass
    subroutine diagonal_iface(self, dm)
      import :: mbdk_mechanism_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      real(dp), intent(out) :: dm(:)
    end subroutine diagonal_iface

    !> qdot = T(q) v. stat: an angle set at its gimbal lock, MBDK_ERR_SINGULAR_MATRIX
    subroutine rates_iface(self, q, v, qdot, stat)
      import :: mbdk_mechanism_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      real(dp), intent(in) :: q(:), v(:)
      real(dp), intent(out) :: qdot(:)
      integer, intent(out) :: stat
    end subroutine rates_iface

    !> a (nvel) and lam (m) of the formulation's constrained solve at (t, q, v)
    subroutine accelerations_iface(self, t, q, v, a, lam, stat)
      import :: mbdk_mechanism_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      real(dp), intent(in) :: t
      real(dp), intent(in), contiguous :: q(:), v(:)
      real(dp), intent(out), contiguous :: a(:), lam(:)
      integer, intent(out) :: stat
    end subroutine accelerations_iface

    !> the rows whose multipliers are solved for now (1..m unless some are redundant)
    subroutine rows_iface(self, rows, stat)
      import :: mbdk_mechanism_t
      class(mbdk_mechanism_t), intent(in) :: self
      integer, allocatable, intent(out) :: rows(:)
      integer, intent(out) :: stat
    end subroutine rows_iface

    !> the watch after a step at y = [q; v] (ncoord + nvel) with the multipliers lam (m);
    !> force: the step is a sample or the last
    subroutine watch_lam_iface(self, t, y, force, lam, stat)
      import :: mbdk_mechanism_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      real(dp), intent(in) :: t, y(:), lam(:)
      logical, intent(in) :: force
      integer, intent(out) :: stat
    end subroutine watch_lam_iface

    !> the watch's work over [t_a, t_b] from the states y(:, k) = [q; v] and multipliers
    !> lam(:, k) at its Gauss nodes (mbdk_problem's MBDK_GAUSS3)
    subroutine watch_nodes_lam_iface(self, t_a, t_b, y, lam, stat)
      import :: mbdk_mechanism_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      real(dp), intent(in) :: t_a, t_b, y(:, :), lam(:, :)
      integer, intent(out) :: stat
    end subroutine watch_nodes_lam_iface
  end interface

end module mbdk_mechanism
