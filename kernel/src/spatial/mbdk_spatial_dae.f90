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
!> the DAE's own multipliers.
!> form 2 is the stabilised index-2 form (GGL, as GSTIFF SI2), Y = [q; w; lam; mu]:
!>     q' = T(q) (w - M^-1 C_a^T mu),  w' = M^-1 (f - W x J W - C_a^T lam),
!>     0  = Phi_a(q, t),  0 = C_a w + Phi_t,a
!> mu acts through the rates of the velocities M^-1 C^T mu, since the spatial model forms C in
!> w, not dPhi/dq in q: Phi' = C (w - M^-1 C^T mu) + Phi_t, so mu = 0 where both rows hold.
!> M^-1 C^T mu comes from the accelerations' linearity in lam, a(lam - mu) - a(lam), and its
!> rates from T(q) at the same q: three model evaluations and the constraints per F.
module mbdk_spatial_dae
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_spatial_model, only: mbdk_spatial_model_t, mbdk_spatial_dae_rhs, mbdk_spatial_watch, &
    mbdk_spatial_constraints, mbdk_spatial_watch_nodes
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  implicit none
  private
  public :: mbdk_spatial_dae_init, mbdk_spatial_ggl_rates

  type, extends(mbdk_problem_t), public :: mbdk_spatial_dae_t
    type(mbdk_spatial_model_t), pointer :: model => null()
    integer :: ny = 0      !< size of [q; w]
    integer :: na = 0      !< multipliers: the independent rows model%active
    integer :: npos = 0    !< positions and rotation coordinates (q)
    integer :: form = 1    !< 1: index 3 (I3), 2: stabilised index 2 (SI2, with mu)
    integer, allocatable :: rows(:)
  contains
    procedure :: rhs => sdae_rhs
    procedure :: watch_start => sdae_watch_start
    procedure :: watch => sdae_watch
    procedure :: watch_wants_nodes => sdae_wants_nodes
    procedure :: watch_nodes => sdae_watch_nodes
  end type mbdk_spatial_dae_t

contains

  !> The DAE of model; mass(N) receives the diagonal of E. The model must outlive the problem.
  !> stat: MBDK_SUCCESS or MBDK_ERR_NO_MEMORY (asked: the bytes, mbdk_memory).
  subroutine mbdk_spatial_dae_init(self, model, ny, mass, stat, form, asked)
    type(mbdk_spatial_dae_t), intent(out) :: self
    type(mbdk_spatial_model_t), intent(in), target :: model
    integer, intent(in) :: ny
    integer, intent(in), optional :: form
    real(dp), allocatable, intent(out) :: mass(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: astat, na
    self%model => model
    self%ny = ny
    ! the rows the model solves now (the initial set, or the one its assembly moved to), which
    ! its multipliers at the start are given on; kept for the run (the DAE does not switch
    ! sets: one nearing a rank loss of its own makes Newton's matrix singular, and the run
    ! stops by name)
    na = size(model%work%active)
    self%na = na
    self%npos = ny - 6 * model%nb
    if (present(form)) self%form = form
    self%n = ny + na
    if (self%form == 2) self%n = ny + 2 * na
    self%has_watch = model%has_watch
    allocate (self%rows(na), mass(self%n), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * na + MBDK_REAL_BYTES * self%n, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    self%rows = model%work%active
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
    real(dp), allocatable :: lam(:), phi(:), c(:, :), gam(:), phit(:)
    integer :: ny, nq, na, i, m, astat
    ny = self%ny
    nq = self%npos
    na = self%na
    m = self%model%m
    allocate (lam(m), phi(m), stat=astat)
    call mbdk_alloc_status(astat, 2 * MBDK_REAL_BYTES * m, stat)
    if (stat /= MBDK_SUCCESS) return
    lam = 0.0_dp
    lam(self%rows) = y(ny + 1:ny + na)
    call mbdk_spatial_dae_rhs(self%model, t, y(1:ny), lam, f(1:ny), phi, stat)
    if (stat /= MBDK_SUCCESS) return
    f(ny + 1:ny + na) = phi(self%rows)
    if (self%form /= 2) return
    lam(self%rows) = y(ny + 1:ny + na) - y(ny + na + 1:ny + 2 * na)
    call mbdk_spatial_ggl_rates(self%model, t, y(1:ny), nq, lam, f(nq + 1:ny), f(1:nq), stat)
    if (stat /= MBDK_SUCCESS) return
    allocate (c(m, ny - nq), gam(m), phit(m), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * real(m, dp) * (ny - nq + 2), stat)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_spatial_constraints(self%model, t, y(1:ny), phi, c, gam, phit, stat)
    if (stat /= MBDK_SUCCESS) return
    do i = 1, na
      f(ny + na + i) = dot_product(c(self%rows(i), :), y(nq + 1:ny)) + phit(self%rows(i))
    end do
  end subroutine sdae_rhs

  !> The GGL forms' position rates qdot = T(q) (w - M^-1 C^T mu) at y = [q; w] (nq positions),
  !> given lam_mu = lam - mu on the model's rows and a = a(lam), the accelerations already
  !> evaluated there: by a's linearity in the multipliers, M^-1 C^T mu = a(lam - mu) - a(lam),
  !> and T(q) is applied by one more evaluation at [q; w - that]. Shared by bdf's si2 form and
  !> ida's ggl form on spatial scenes.
  subroutine mbdk_spatial_ggl_rates(model, t, y, nq, lam_mu, a, qdot, stat)
    type(mbdk_spatial_model_t), intent(in) :: model
    real(dp), intent(in) :: t, y(:), lam_mu(:), a(:)
    integer, intent(in) :: nq
    real(dp), intent(out) :: qdot(:)
    integer, intent(out) :: stat
    real(dp), allocatable :: g(:), ys(:), phi(:), zero(:)
    integer :: astat
    allocate (g(size(y)), ys(size(y)), phi(model%m), zero(model%m), stat=astat)
    call mbdk_alloc_status(astat, 2 * MBDK_REAL_BYTES * (size(y) + model%m), stat)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_spatial_dae_rhs(model, t, y, lam_mu, g, phi, stat)
    if (stat /= MBDK_SUCCESS) return
    ys(1:nq) = y(1:nq)
    ys(nq + 1:) = y(nq + 1:) + a - g(nq + 1:)
    zero = 0.0_dp
    call mbdk_spatial_dae_rhs(model, t, ys, zero, g, phi, stat)
    if (stat /= MBDK_SUCCESS) return
    qdot = g(1:nq)
  end subroutine mbdk_spatial_ggl_rates

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
    real(dp), allocatable :: lam(:)
    integer :: astat
    allocate (lam(self%model%m), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * self%model%m, stat)
    if (stat /= MBDK_SUCCESS) return
    ! the drivers' power with the DAE's own multipliers
    lam = 0.0_dp
    lam(self%rows) = y(self%ny + 1:self%ny + self%na)
    call mbdk_spatial_watch(self%model, t, y(1:self%ny), force, stat, lam)
  end subroutine sdae_watch

  logical function sdae_wants_nodes(self)
    class(mbdk_spatial_dae_t), intent(in) :: self
    sdae_wants_nodes = self%model%watch_wants_nodes()
  end function sdae_wants_nodes

  !> The work at the nodes of a step with the DAE's own multipliers there.
  subroutine sdae_watch_nodes(self, t_a, t_b, y, stat)
    class(mbdk_spatial_dae_t), intent(in) :: self
    real(dp), intent(in) :: t_a, t_b, y(:, :)
    integer, intent(out) :: stat
    real(dp), allocatable :: lam(:, :)
    integer :: astat
    allocate (lam(self%model%m, size(y, 2)), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * self%model%m * size(y, 2), stat)
    if (stat /= MBDK_SUCCESS) return
    lam = 0.0_dp
    lam(self%rows, :) = y(self%ny + 1:self%ny + self%na, :)
    call mbdk_spatial_watch_nodes(self%model, t_a, t_b, y(1:self%ny, :), stat, lam)
  end subroutine sdae_watch_nodes

end module mbdk_spatial_dae
