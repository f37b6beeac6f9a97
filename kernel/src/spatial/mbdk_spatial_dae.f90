!> A spatial scene's equations of motion as the semi-explicit index-3 DAE  E Y' = G(t, Y)  that
!> bdf integrates as MSC Adams' GSTIFF I3 does (the book, 4.4.2); mbdk_scene_dae is the planar
!> twin. With the state of mbdk_spatial_model (q: centres and quaternions or angles, w: the
!> velocities and body-frame angular velocities) and the multipliers lam of the independent
!> rows (model%active: all rows, or the subset a redundant scene keeps, whose Phi = 0 implies
!> the others on the joints):
!>   Y = [q; w; lam],  E = diag(I, I, 0):
!>     q' = T(q) w                                  (the quaternion or angle rates)
!>     w' = M^-1 (f - W x J W - C_a^T lam)          (Newton-Euler, M block diagonal)
!>     0  = Phi_a(q, t)
!> w' is written explicit (M^-1 applied body by body) because E must be diagonal and a body's
!> inertia need not be. The quaternions' norm is kept by the kinematic equation (with the
!> scene's stabilising term where it asks for one), not by a projection between steps, which
!> would corrupt BDF's history; the rotation is taken from p / |p|, so the drift of |p|, of the
!> order of the BDF's error, does not scale the bodies. The watch and the drivers' power use
!> the DAE's own multipliers. The stabilised
!> index-2 (GGL) form is not offered: its mu enters q' through dPhi/dq in the coordinates q,
!> which the spatial model (C is in w) does not form.
module mbdk_spatial_dae
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_spatial_model, only: mbdk_spatial_model_t, mbdk_spatial_dae_rhs, mbdk_spatial_watch
  implicit none
  private
  public :: mbdk_spatial_dae_init

  type, extends(mbdk_problem_t), public :: mbdk_spatial_dae_t
    type(mbdk_spatial_model_t), pointer :: model => null()
    integer :: ny = 0      !< size of [q; w]
    integer :: na = 0      !< multipliers: the independent rows model%active
    integer, allocatable :: rows(:)
  contains
    procedure :: rhs => sdae_rhs
    procedure :: watch_start => sdae_watch_start
    procedure :: watch => sdae_watch
  end type mbdk_spatial_dae_t

contains

  !> The DAE of model; mass(N) receives the diagonal of E. The model must outlive the problem.
  subroutine mbdk_spatial_dae_init(self, model, ny, mass, stat)
    type(mbdk_spatial_dae_t), intent(out) :: self
    type(mbdk_spatial_model_t), intent(in), target :: model
    integer, intent(in) :: ny
    real(dp), allocatable, intent(out) :: mass(:)
    integer, intent(out) :: stat
    self%model => model
    self%ny = ny
    ! the rows the model solves now (the initial set, or the one its assembly moved to), which
    ! its multipliers at the start are given on; kept for the run (the DAE does not switch
    ! sets: one nearing a rank loss of its own makes Newton's matrix singular, and the run
    ! stops by name)
    self%rows = model%work%active
    self%na = size(self%rows)
    self%n = ny + self%na
    self%has_watch = model%has_watch
    allocate (mass(self%n))
    mass = 0.0_dp
    mass(1:ny) = 1.0_dp
    stat = MBDK_SUCCESS
  end subroutine mbdk_spatial_dae_init

  subroutine sdae_rhs(self, t, y, f, stat)
    class(mbdk_spatial_dae_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    real(dp), intent(out), contiguous :: f(:)
    integer, intent(out) :: stat
    real(dp) :: lam(self%model%m), phi(self%model%m)
    lam = 0.0_dp
    lam(self%rows) = y(self%ny + 1:)
    call mbdk_spatial_dae_rhs(self%model, t, y(1:self%ny), lam, f(1:self%ny), phi, stat)
    if (stat /= MBDK_SUCCESS) return
    f(self%ny + 1:) = phi(self%rows)
  end subroutine sdae_rhs

  subroutine sdae_watch_start(self, t, y, stat)
    class(mbdk_spatial_dae_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    integer, intent(out) :: stat
    call self%model%watch_start(t, y(1:self%ny), stat)
  end subroutine sdae_watch_start

  subroutine sdae_watch(self, t, y, force, stat)
    class(mbdk_spatial_dae_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    real(dp) :: lam(self%model%m)
    ! the drivers' power with the DAE's own multipliers
    lam = 0.0_dp
    lam(self%rows) = y(self%ny + 1:)
    call mbdk_spatial_watch(self%model, t, y(1:self%ny), force, stat, lam)
  end subroutine sdae_watch

end module mbdk_spatial_dae
