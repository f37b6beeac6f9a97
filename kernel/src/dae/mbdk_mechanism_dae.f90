!> A mechanism's equations of motion (mbdk_mechanism: planar or spatial, q' = T(q) v) as a
!> semi-explicit DAE  E Y' = G(t, Y)  with a diagonal E, for bdf in the manner of MSC Adams'
!> GSTIFF (the book, 4.4.2): the BDF formulas applied to the DAE itself, not to the reduced ODE.
!> Two forms (nq coordinates, nv velocities; the multipliers of the rows a the mechanism solves,
!> active_rows: all rows, or the independent subset a redundant spatial scene keeps, taken once
!> at the start: the DAE does not switch sets, and one nearing a rank loss of its own makes
!> Newton's matrix singular, so the run stops by name):
!>   i3  (index 3, GSTIFF I3)   Y = [q; v; lam_a]:
!>         q' = T(q) v,   M v' = f - C_a^T lam,   0 = Phi_a(q, t)
!>       (a knife edge's row, which constrains velocities only, reads 0 = C v + Phi_t: the form
!>       is index 2 in that row, the index-2 form of nonholonomic scenes)
!>   si2 (stabilised index 2, the GGL form as in GSTIFF SI2)  Y = [q; v; lam_a; mu_a]:
!>         q' = T(q) (v - C_a^T mu),   M v' = f - C_a^T lam,   0 = Phi_a(q, t),
!>         0 = C_a v + Phi_t,a
!>       (refused for knife edges, MBDK_ERR_NOT_APPLICABLE: they have no position row for mu).
!>       With dPhi/dq T = C, Phi' = C (v - C^T mu) + Phi_t: where both rows hold, mu = 0.
!> E = diag(I, M, 0 (, 0)) where M is diagonal (a planar scene: a body without inertia has a
!> zero in M, so its rotation's velocity row is algebraic too, which the same E expresses);
!> otherwise (a spatial body's inertia tensor) E = diag(I, I, 0 (, 0)) and the velocity rows
!> read v' = M^-1 (f - C_a^T lam), M^-1 applied body by body.
!> G is the rhs of this problem type; mbdk_variable_bdf takes E as its mass argument and tests
!> the local error of q and v only (lam and mu are algebraic). The quaternions' norm is kept by
!> the kinematic equation (with the scene's stabilising term where it asks for one), not by a
!> projection between steps, which would corrupt BDF's history; the rotation is taken from
!> p / |p|. The watch uses the DAE's own multipliers (the drivers' power).
module mbdk_mechanism_dae
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_mechanism, only: mbdk_mechanism_t
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  implicit none
  private
  public :: mbdk_mechanism_dae_init

  !> the forms of a mechanism's DAE (the f2py entries' dae_form, mbdk_entry): none (an ODE
  !> method, or the index-3 family with its own), index 3, stabilised index 2 (ida's index1 and
  !> GGL forms take the codes 1 and 2)
  integer, parameter, public :: MBDK_DAE_NONE = 0, MBDK_DAE_I3 = 1, MBDK_DAE_SI2 = 2

  !> evaluation buffers (the problem is intent(in) in rhs: they live behind a pointer)
  type :: dae_work_t
    real(dp), allocatable :: f(:), phi(:), c(:, :), gam(:), phit(:), lam(:), mu(:), g(:), &
      x(:), lamn(:, :)
  end type dae_work_t

  type, extends(mbdk_problem_t), public :: mbdk_mechanism_dae_t
    class(mbdk_mechanism_t), pointer :: mech => null()
    integer :: form = MBDK_DAE_I3
    !> Y = [q (ncq); v (nv); lam (na); (si2) mu (na)], ny = ncq + nv
    integer :: ncq = 0, nv = 0, ny = 0, na = 0
    integer, allocatable :: rows(:)
    type(dae_work_t), pointer :: work => null()
  contains
    procedure :: rhs => dae_rhs
    procedure :: watch_start => dae_watch_start
    procedure :: watch => dae_watch
    procedure :: watch_wants_nodes => dae_wants_nodes
    procedure :: watch_nodes => dae_watch_nodes
    final :: dae_free
  end type mbdk_mechanism_dae_t

contains

  !> The DAE of mech in form (MBDK_DAE_*), on the rows mech solves now (call its
  !> accelerations first: a redundant scene's solve there may choose the set); mass(N) receives
  !> the diagonal of E. mech must outlive the problem. A scene with effect states (wear), or
  !> si2 with a knife edge: MBDK_ERR_NOT_APPLICABLE. MBDK_ERR_NO_MEMORY: asked gets the bytes
  !> (mbdk_memory).
  subroutine mbdk_mechanism_dae_init(self, mech, form, mass, stat, asked)
    type(mbdk_mechanism_dae_t), intent(out) :: self
    class(mbdk_mechanism_t), intent(in), target :: mech
    integer, intent(in) :: form
    real(dp), allocatable, intent(out) :: mass(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nv, m, astat
    stat = MBDK_ERR_INVALID_INPUT
    if (form /= MBDK_DAE_I3 .and. form /= MBDK_DAE_SI2) return
    ! the DAE's state is [q; v; lambda]: a scene with effect states (wear) is not one. The
    ! GGL form stabilises position rows; a knife edge has none (its mu would be undetermined)
    if (mech%ns > 0 .or. (form == MBDK_DAE_SI2 .and. mech%has_pfaffian)) then
      stat = MBDK_ERR_NOT_APPLICABLE
      return
    end if
    call mech%active_rows(self%rows, stat)
    if (stat /= MBDK_SUCCESS) return
    nv = mech%nvel
    m = mech%m
    self%mech => mech
    self%form = form
    self%ncq = mech%ncoord
    self%nv = nv
    self%ny = mech%ncoord + nv
    self%na = size(self%rows)
    self%n = self%ny + self%na
    if (form == MBDK_DAE_SI2) self%n = self%n + self%na
    self%has_watch = mech%has_watch
    allocate (self%work, stat=astat)
    if (astat == 0) allocate (self%work%f(nv), self%work%phi(m), self%work%c(m, nv), &
                              self%work%gam(m), self%work%phit(m), self%work%lam(m), &
                              self%work%mu(m), self%work%g(nv), self%work%x(nv), &
                              self%work%lamn(m, 3), mass(self%n), stat=astat)
    ! (self%work, if allocated, is freed by the finaliser)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (real(m, dp) * (nv + 8) + 3.0_dp * nv + &
                           self%n), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    mass = 0.0_dp
    mass(1:self%ny) = 1.0_dp
    if (mech%diag_mass) call mech%mass_diagonal(mass(self%ncq + 1:self%ny))
    stat = MBDK_SUCCESS
  end subroutine mbdk_mechanism_dae_init

  subroutine dae_free(self)
    type(mbdk_mechanism_dae_t), intent(inout) :: self
    if (associated(self%work)) deallocate (self%work)
  end subroutine dae_free

  subroutine dae_rhs(self, t, y, f, stat)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    real(dp), intent(out), contiguous :: f(:)
    integer, intent(out) :: stat
    integer :: ncq, ny, na, i, j
    ncq = self%ncq
    ny = self%ny
    na = self%na
    associate (q => y(1:ncq), v => y(ncq + 1:ny), w => self%work, mech => self%mech)
      call mech%evaluate(t, q, v, w%f, w%phi, w%c, w%gam, w%phit, stat)
      if (stat /= MBDK_SUCCESS) return
      if (self%mech%m == 0) then
        w%g = w%f
      else
        w%lam = 0.0_dp
        w%lam(self%rows) = y(ny + 1:ny + na)
        w%g = w%f - matmul(w%lam, w%c)
      end if
      if (mech%diag_mass) then
        f(ncq + 1:ny) = w%g
      else
        call mech%minv_times(w%g, f(ncq + 1:ny))
      end if
      if (self%form == MBDK_DAE_SI2 .and. mech%m > 0) then
        w%mu = 0.0_dp
        w%mu(self%rows) = y(ny + na + 1:ny + 2 * na)
        w%x = v - matmul(w%mu, w%c)
        call mech%rates(q, w%x, f(1:ncq), stat)
      else
        call mech%rates(q, v, f(1:ncq), stat)
      end if
      if (stat /= MBDK_SUCCESS) return
      do i = 1, na
        j = self%rows(i)
        f(ny + i) = w%phi(j)
        ! a knife edge's row is its velocity constraint (index 2 in that row)
        if (mech%has_pfaffian) then
          if (mech%pfaffian(j)) f(ny + i) = dot_product(w%c(j, :), v) + w%phit(j)
        end if
        if (self%form == MBDK_DAE_SI2) f(ny + na + i) = dot_product(w%c(j, :), v) + w%phit(j)
      end do
    end associate
  end subroutine dae_rhs

  subroutine dae_watch_start(self, t, y, stat)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    integer, intent(out) :: stat
    call self%mech%watch_start(t, y(1:self%ny), stat)
  end subroutine dae_watch_start

  subroutine dae_watch(self, t, y, force, stat)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    associate (lam => self%work%lam)
      lam = 0.0_dp
      lam(self%rows) = y(self%ny + 1:self%ny + self%na)
      call self%mech%watch_lam(t, y(1:self%ny), force, lam, stat)
    end associate
  end subroutine dae_watch

  logical function dae_wants_nodes(self)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    dae_wants_nodes = self%mech%watch_wants_nodes()
  end function dae_wants_nodes

  !> The work at the nodes of a step with the DAE's own multipliers there.
  subroutine dae_watch_nodes(self, t_a, t_b, y, stat)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    real(dp), intent(in) :: t_a, t_b, y(:, :)
    integer, intent(out) :: stat
    associate (lamn => self%work%lamn)
      lamn = 0.0_dp
      lamn(self%rows, :) = y(self%ny + 1:self%ny + self%na, :)
      call self%mech%watch_nodes_lam(t_a, t_b, y(1:self%ny, :), lamn, stat)
    end associate
  end subroutine dae_watch_nodes

end module mbdk_mechanism_dae
