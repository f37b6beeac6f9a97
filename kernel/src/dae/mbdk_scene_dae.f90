!> A scene's equations of motion as a semi-explicit DAE  E Y' = G(t, Y)  with a diagonal E, for
!> bdf in the manner of MSC Adams' GSTIFF (the book, 4.4.2): the BDF formulas applied to the DAE
!> itself, not to the reduced ODE. Two forms (nc = 3 nb coordinates, m constraint rows):
!>   i3  (index 3, GSTIFF I3)   Y = [q; v; lam], E = diag(I, M, 0):
!>         q' = v,   M v' = f - D^T lam,   0 = Phi(q, t)
!>       (a knife edge's row, which constrains velocities only, reads 0 = D v + Phi_t: the form
!>       is index 2 in that row, the index-2 form of nonholonomic scenes)
!>   si2 (stabilised index 2, the GGL form as in GSTIFF SI2)  Y = [q; v; lam; mu],
!>       E = diag(I, M, 0, 0):
!>         q' = v - D^T mu,   M v' = f - D^T lam,   0 = Phi(q, t),   0 = D v + Phi_t
!>       (refused for knife edges, MBDK_ERR_NOT_APPLICABLE: they have no position row for mu)
!> G is the rhs of this problem type; mbdk_variable_bdf takes E as its mass argument and tests
!> the local error of q and v only (lam and mu are algebraic). A body without inertia has a
!> zero in M: its rotation's velocity row is algebraic too, which the same E expresses.
!> The watch delegates to the scene model's (mbdk_model_watch with the step's own multipliers).
module mbdk_scene_dae
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_model, only: mbdk_model_t, mbdk_model_assemble, mbdk_model_constraints, &
    mbdk_model_watch, mbdk_model_watch_start, mbdk_model_watch_nodes
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  implicit none
  private
  public :: mbdk_scene_dae_init

  integer, parameter, public :: MBDK_DAE_I3 = 1, MBDK_DAE_SI2 = 2

  !> evaluation buffers (the problem is intent(in) in rhs: they live behind a pointer)
  type :: dae_work_t
    real(dp), allocatable :: phi(:), d(:, :), gam(:), phit(:)
  end type dae_work_t

  type, extends(mbdk_problem_t), public :: mbdk_scene_dae_t
    type(mbdk_model_t), pointer :: model => null()
    integer :: form = MBDK_DAE_I3, nc = 0, m = 0
    type(dae_work_t), pointer :: work => null()
  contains
    procedure :: rhs => dae_rhs
    procedure :: watch_start => dae_watch_start
    procedure :: watch => dae_watch
    procedure :: watch_wants_nodes => dae_wants_nodes
    procedure :: watch_nodes => dae_watch_nodes
    final :: dae_free
  end type mbdk_scene_dae_t

contains

  !> The DAE of model in form (MBDK_DAE_*); mass(N) receives the diagonal of E. The model must
  !> outlive the problem. MBDK_ERR_NO_MEMORY: asked gets the bytes (mbdk_memory).
  subroutine mbdk_scene_dae_init(self, model, form, mass, stat, asked)
    type(mbdk_scene_dae_t), intent(out) :: self
    type(mbdk_model_t), intent(in), target :: model
    integer, intent(in) :: form
    real(dp), allocatable, intent(out) :: mass(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nc, m, astat
    stat = MBDK_ERR_INVALID_INPUT
    if (form /= MBDK_DAE_I3 .and. form /= MBDK_DAE_SI2) return
    ! the DAE's state is [q; v; lambda]: a scene with effect states (wear) is not one. The
    ! GGL form stabilises position rows; a knife edge has none (its mu would be undetermined)
    if (model%ns > 0 .or. (form == MBDK_DAE_SI2 .and. model%has_pfaffian)) then
      stat = MBDK_ERR_NOT_APPLICABLE
      return
    end if
    nc = model%nc
    m = model%m
    self%model => model
    self%form = form
    self%nc = nc
    self%m = m
    self%n = 2 * nc + m
    if (form == MBDK_DAE_SI2) self%n = self%n + m
    self%has_watch = model%has_watch
    allocate (self%work, stat=astat)
    if (astat == 0) allocate (self%work%phi(m), self%work%d(m, nc), self%work%gam(m), &
                              self%work%phit(m), mass(self%n), stat=astat)
    ! (self%work, if allocated, is freed by the finaliser)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (real(m, dp) * (nc + 3) + self%n), stat, &
                           asked)
    if (stat /= MBDK_SUCCESS) return
    mass = 0.0_dp
    mass(1:nc) = 1.0_dp
    mass(nc + 1:2 * nc) = model%mass
    stat = MBDK_SUCCESS
  end subroutine mbdk_scene_dae_init

  subroutine dae_free(self)
    type(mbdk_scene_dae_t), intent(inout) :: self
    if (associated(self%work)) deallocate (self%work)
  end subroutine dae_free

  subroutine dae_rhs(self, t, y, f, stat)
    class(mbdk_scene_dae_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    real(dp), intent(out), contiguous :: f(:)
    integer, intent(out) :: stat
    integer :: nc, m
    nc = self%nc
    m = self%m
    associate (q => y(1:nc), v => y(nc + 1:2 * nc), w => self%work)
      call mbdk_model_assemble(self%model, t, q, v, stat)
      if (stat /= MBDK_SUCCESS) return
      call mbdk_model_constraints(self%model, t, q, v, w%phi, w%d, w%gam, w%phit)
      f(1:nc) = v
      f(nc + 1:2 * nc) = self%model%work%fq
      if (m == 0) return
      f(nc + 1:2 * nc) = f(nc + 1:2 * nc) - matmul(y(2 * nc + 1:2 * nc + m), w%d)
      f(2 * nc + 1:2 * nc + m) = w%phi
      ! a knife edge's row is its velocity constraint (index 2 in that row)
      if (self%model%has_pfaffian) &
        f(2 * nc + 1:2 * nc + m) = merge(matmul(w%d, v) + w%phit, w%phi, self%model%pfaffian)
      if (self%form == MBDK_DAE_SI2) then
        f(1:nc) = f(1:nc) - matmul(y(2 * nc + m + 1:2 * nc + 2 * m), w%d)
        f(2 * nc + m + 1:2 * nc + 2 * m) = matmul(w%d, v) + w%phit
      end if
    end associate
  end subroutine dae_rhs

  subroutine dae_watch_start(self, t, y, stat)
    class(mbdk_scene_dae_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    integer, intent(out) :: stat
    call mbdk_model_watch_start(self%model, t, y(1:self%nc), y(self%nc + 1:2 * self%nc), stat)
  end subroutine dae_watch_start

  subroutine dae_watch(self, t, y, force, stat)
    class(mbdk_scene_dae_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    integer :: nc
    nc = self%nc
    call mbdk_model_watch(self%model, t, y(1:nc), y(nc + 1:2 * nc), force, stat, &
                          lam=y(2 * nc + 1:2 * nc + self%m))
  end subroutine dae_watch

  logical function dae_wants_nodes(self)
    class(mbdk_scene_dae_t), intent(in) :: self
    dae_wants_nodes = self%model%watch_wants_nodes()
  end function dae_wants_nodes

  !> The work at the nodes of a step with the DAE's own multipliers there.
  subroutine dae_watch_nodes(self, t_a, t_b, y, stat)
    class(mbdk_scene_dae_t), intent(in) :: self
    real(dp), intent(in) :: t_a, t_b, y(:, :)
    integer, intent(out) :: stat
    integer :: nc
    nc = self%nc
    call mbdk_model_watch_nodes(self%model, t_a, t_b, y(1:nc, :), y(nc + 1:2 * nc, :), stat, &
                                lam=y(2 * nc + 1:2 * nc + self%m, :))
  end subroutine dae_watch_nodes

end module mbdk_scene_dae
