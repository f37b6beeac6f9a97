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
!>   body_graph   the bodies of the coordinates, velocities and rows, and the pairs the
!>                elements couple: the pattern of the DAE's Jacobian (compact_rows: a large
!>                scene, whose DAE forms then evaluate by the index-3 procedures below)
!>   mass         M x and M^-1 x; diag_mass and mass_diagonal where M is diagonal (planar:
!>                a body without inertia has a zero there, and no M^-1)
!>   rates        q' = T(q) v (with a spatial scene's norm stabilisation where it asks for it)
!>   accelerations  a and lam of the formulation's constrained solve (the reduced ODE's), the
!>                consistent start of a DAE
!>   active_rows  the rows whose multipliers are solved (a redundant spatial scene keeps an
!>                independent subset; the others carry zero)
!>   watch_lam, watch_nodes_lam   the scene's watch (mbdk_watch) at [q; v] with multipliers
!>                given (a DAE's own), for the drivers' power; watch_solve with multipliers
!>                solved for at the state; watch_begin starts it (velocity: whether the
!>                integrator promises the velocity constraints)
!>   retract      q (+) dq: the coordinates moved by an increment dq in the velocities (q + dq
!>                for a planar body; a spatial body's orientation turned by the body-frame
!>                rotation dq), identity_kinematics where T = I and the update is q + dq
!>   normalise    a quaternion's unit norm (and any other coordinate invariant)
!>   coord_weights  per velocity component, the size of the coordinates it moves (a planar
!>                coordinate's |q|; a spatial body's |r| and 1 for its rotations), for tests
!>                on increments
!>   near_rank_loss  whether the pose lies within MBDK_RANK_LOSS_WINDOW of a rank loss of given
!>                rows, on the geometry (mbdk_rank_margin; no masses, no counts or state of the
!>                model touched): the cause a DAE form's failure is named by
!> and for the index-3 integrator (mbdk_trapezoidal_index3), with an mbdk_i3_aux_t the model
!> creates for each solve (i3_create: its constrained-solve object and Newton factors):
!>   i3_evaluate  f, Phi, gamma, Phi_t at (t, q, v) into an mbdk_i3_eval_t, C kept for the
!>                products and solves below
!>   i3_residual  r = M dd - s (f - C^T lt), the trapezoidal equations of motion (in the
!>                mbdk_i3_eval_t)
!>   i3_c_times, i3_ct_times   C x and C^T x (or |C| |x| and |C|^T |x|)
!>   i3_cs_factor, i3_cs_solve   M x + C^T mu = b, C x = c at the last evaluation (the
!>                projections); on a regular path (an augmented Lagrangian iteration) where C
!>                has lost a rank, when the caller allows it
!>   i3_project_velocity   the evaluation's v onto C v + Phi_t = 0 through those (a default
!>                here from i3_c_times and i3_cs_solve; a model may do it in one call of its own)
!>   i3_matrix, i3_matrix_solve   the Newton matrix, where the model has its tangents
!>                (has_i3_matrix); otherwise the integrator forms it by differences
!>   i3_matrix_renew   where the model's matrix is costly to build (has_i3_renew): the
!>                augmented form's matrix at the last evaluation's C from the last build's
!>                tangent, its penalty ck alpha C^T C renewed (a default here: not offered)
module mbdk_mechanism
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_NOT_APPLICABLE
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  use mbdk_problem, only: mbdk_problem_t
  implicit none
  private

  !> the ODE formulations (Fekete (2023) section 3), one code in both models
  integer, parameter, public :: MBDK_FORM_REDUCED = 1, MBDK_FORM_BAUMGARTE = 2, &
    MBDK_FORM_PENALTY = 3, MBDK_FORM_PROJECTION = 4
  !> near_rank_loss's window: a relative pivot of the rows' geometric Gram matrix
  !> (mbdk_rank_margin) at or below this is next to a rank loss. The DAE forms give up well
  !> before a singular pose (their Newton matrix's Jacobian moves fast there): on IFToMM A02
  !> (1 m bars) the pivot falls as the square of the time to a flat pose (4.3e-4 at 3 ms,
  !> 8.4e-3 at 15 ms, 3.1e-2 at 30 ms, one loop; 2e-2 is 24 ms before, 28 ms on two loops),
  !> and bdf's and ida's forms stopped from 24 ms before one (rtol 1e-10) to just past it,
  !> while the regular poses of the built-in mechanisms (the four-bar, the double and
  !> three-link pendulums, the trolley crane, over 5 s of motion) stay above 0.48.
  real(dp), parameter, public :: MBDK_RANK_LOSS_WINDOW = 2.0e-2_dp
  !> near_rank_loss looks at most this many rows (its Gram matrix is dense); a larger scene's
  !> DAE failures keep the name their solver gave them
  integer, parameter, public :: MBDK_RANK_LOSS_MAX_ROWS = 300

  !> What a mechanism keeps for one index-3 solve; each model extends it (i3_create).
  type, abstract, public :: mbdk_i3_aux_t
    !> the default i3_project_velocity's work (C v + Phi_t, the correction, its multipliers, a
    !> zero right-hand side), allocated at its first call
    real(dp), allocatable :: pv_c(:), pv_x(:), pv_mu(:), pv_zero(:)
  end type mbdk_i3_aux_t

  !> An index-3 evaluation and the Newton residual there, which the integrator owns: the point
  !> it sets (q of ncoord, v of nvel), what i3_evaluate gives there (f of nvel; phi, gam, phit
  !> of m), the residual's multipliers lt (m) and mass term dd (nvel) it sets, and r (the
  !> Newton unknowns': the residual, i3_residual's in its first nvel, then the Newton update).
  !> Allocatable components, so that a model hands them on to its own routines as they are: a
  !> dummy array handed on takes a new descriptor at every call, several per Newton iteration.
  type, public :: mbdk_i3_eval_t
    real(dp), allocatable :: q(:), v(:), f(:), phi(:), gam(:), phit(:), lt(:), dd(:), r(:)
  end type mbdk_i3_eval_t

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
    !> T = I, ncoord = nvel and q (+) dq = q + dq: callers may add increments themselves
    logical :: identity_kinematics = .false.
    !> i3_matrix builds the index-3 Newton matrix from the model's tangents
    logical :: has_i3_matrix = .false.
    !> i3_matrix_renew renews the augmented matrix's penalty without a new tangent
    logical :: has_i3_renew = .false.
    !> forces that depend on the velocities (dampers, friction, the gyroscopic moment): the
    !> index-3 step evaluates them at projected velocities
    logical :: velocity_forces = .true.
    !> the model keeps C in compact rows (a large scene: its constrained solves are sparse):
    !> the DAE forms of bdf then evaluate through the index-3 procedures and factorise their
    !> Newton matrix sparse, in the pattern of body_graph (mbdk_mechanism_dae)
    logical :: compact_rows = .false.
  contains
    procedure(evaluate_iface), deferred :: evaluate
    procedure(body_graph_iface), deferred :: body_graph
    procedure(times_iface), deferred :: mass_times
    procedure(times_iface), deferred :: minv_times
    procedure(diagonal_iface), deferred :: mass_diagonal
    procedure(rates_iface), deferred :: rates
    procedure(accelerations_iface), deferred :: accelerations
    procedure(rows_iface), deferred :: active_rows
    procedure(watch_lam_iface), deferred :: watch_lam
    procedure(watch_nodes_lam_iface), deferred :: watch_nodes_lam
    procedure(watch_begin_iface), deferred :: watch_begin
    procedure(watch_solve_iface), deferred :: watch_solve
    procedure(retract_iface), deferred :: retract
    procedure(normalise_iface), deferred :: normalise
    procedure(weights_iface), deferred :: coord_weights
    procedure(i3_create_iface), deferred :: i3_create
    procedure(i3_evaluate_iface), deferred :: i3_evaluate
    procedure(i3_residual_iface), deferred :: i3_residual
    procedure(i3_times_iface), deferred :: i3_c_times
    procedure(i3_times_iface), deferred :: i3_ct_times
    procedure(i3_cs_factor_iface), deferred :: i3_cs_factor
    procedure(i3_cs_solve_iface), deferred :: i3_cs_solve
    procedure(i3_matrix_iface), deferred :: i3_matrix
    procedure(i3_matrix_solve_iface), deferred :: i3_matrix_solve
    procedure :: i3_project_velocity => mechanism_i3_project_velocity
    procedure :: i3_matrix_renew => mechanism_i3_matrix_renew
    procedure(near_rank_loss_iface), deferred :: near_rank_loss
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

    !> The body graph: the body of each coordinate (qbody, ncoord) and velocity (vbody,
    !> nvel), the pairs of bodies an element couples (pairs(2, k): each joint, each force
    !> that loads two bodies; 0 the ground) and each constraint row's velocity columns
    !> (rcol(rptr(r) .. rptr(r+1)-1), r = 1..m). Every term of the equations of motion of a
    !> body depends on the coordinates and velocities of the body, of the bodies paired with
    !> it, and on the multipliers of the rows with a column on it; a row on the coordinates
    !> and velocities of its columns' bodies. MBDK_ERR_NO_MEMORY (asked: the bytes).
    subroutine body_graph_iface(self, qbody, vbody, pairs, rptr, rcol, stat, asked)
      import :: mbdk_mechanism_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      integer, allocatable, intent(out) :: qbody(:), vbody(:), pairs(:, :), rptr(:), rcol(:)
      integer, intent(out) :: stat
      real(dp), intent(inout), optional :: asked
    end subroutine body_graph_iface

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

    !> the watch started at t with y = [q; v]; velocity: the velocity constraints are tested
    subroutine watch_begin_iface(self, t, y, velocity, stat)
      import :: mbdk_mechanism_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      real(dp), intent(in) :: t, y(:)
      logical, intent(in) :: velocity
      integer, intent(out) :: stat
    end subroutine watch_begin_iface

    !> the watch after a step at y = [q; v], the multipliers (the drivers' power) solved for
    subroutine watch_solve_iface(self, t, y, force, stat)
      import :: mbdk_mechanism_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      real(dp), intent(in) :: t, y(:)
      logical, intent(in) :: force
      integer, intent(out) :: stat
    end subroutine watch_solve_iface

    !> qn = q (+) dq (dq of nvel). stat: an angle set at its gimbal lock
    subroutine retract_iface(self, q, dq, qn, stat)
      import :: mbdk_mechanism_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      real(dp), intent(in) :: q(:), dq(:)
      real(dp), intent(out) :: qn(:)
      integer, intent(out) :: stat
    end subroutine retract_iface

    subroutine normalise_iface(self, q)
      import :: mbdk_mechanism_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      real(dp), intent(inout) :: q(:)
    end subroutine normalise_iface

    !> w (nvel): the size of the coordinates each velocity component moves, at q
    subroutine weights_iface(self, q, w)
      import :: mbdk_mechanism_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      real(dp), intent(in) :: q(:)
      real(dp), intent(out) :: w(:)
    end subroutine weights_iface

    !> the model's part of an index-3 solve; book: the book scheme's (its Newton matrix has
    !> the multipliers' rows). MBDK_ERR_NOT_APPLICABLE where the model cannot take the scheme
    !> (elements without a tangent, velocity-only rows); asked: bytes of a failed allocation
    subroutine i3_create_iface(self, aux, book, stat, asked)
      import :: mbdk_mechanism_t, mbdk_i3_aux_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      class(mbdk_i3_aux_t), allocatable, intent(out) :: aux
      logical, intent(in) :: book
      integer, intent(out) :: stat
      real(dp), intent(inout), optional :: asked
    end subroutine i3_create_iface

    !> e%phi, e%gam, e%phit and, with forces, e%f (else left as it is) at (t, e%q, e%v); C
    !> kept in aux. same_q: e%q is that of the last evaluation (only e%v changed)
    subroutine i3_evaluate_iface(self, aux, t, e, forces, same_q, stat)
      import :: mbdk_mechanism_t, mbdk_i3_aux_t, mbdk_i3_eval_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in) :: t
      type(mbdk_i3_eval_t), intent(inout) :: e
      logical, intent(in) :: forces, same_q
      integer, intent(out) :: stat
    end subroutine i3_evaluate_iface

    !> e%r(1:nvel) = M e%dd - s (e%f - C^T e%lt) at the last evaluation (e)
    subroutine i3_residual_iface(self, aux, e, s)
      import :: mbdk_mechanism_t, mbdk_i3_aux_t, mbdk_i3_eval_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      type(mbdk_i3_eval_t), intent(inout) :: e
      real(dp), intent(in) :: s
    end subroutine i3_residual_iface

    !> y = C x (i3_c_times: x of nvel, y of m) or C^T x (i3_ct_times) at the last evaluation;
    !> absolute: |C| |x| (|C|^T |x|), the sizes of the products' terms (roundoff bounds)
    subroutine i3_times_iface(self, aux, x, y, absolute)
      import :: mbdk_mechanism_t, mbdk_i3_aux_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in), contiguous :: x(:)
      real(dp), intent(out), contiguous :: y(:)
      logical, intent(in), optional :: absolute
    end subroutine i3_times_iface

    !> factorises the constrained system at the last evaluation. near > 0: a relative pivot of
    !> C M^-1 C^T below it counts as singular; regular_ok: where it is (nearly) singular, the
    !> regular path instead of MBDK_ERR_SINGULAR_MATRIX; regular: that path was taken
    subroutine i3_cs_factor_iface(self, aux, near, regular_ok, regular, stat)
      import :: mbdk_mechanism_t, mbdk_i3_aux_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in) :: near
      logical, intent(in) :: regular_ok
      logical, intent(out) :: regular
      integer, intent(out) :: stat
    end subroutine i3_cs_factor_iface

    !> x (nvel), mu (m) with M x + C^T mu = b, C x = c from the factors
    subroutine i3_cs_solve_iface(self, aux, b, c, x, mu, stat)
      import :: mbdk_mechanism_t, mbdk_i3_aux_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      real(dp), intent(in), contiguous :: b(:), c(:)
      real(dp), intent(out), contiguous :: x(:), mu(:)
      integer, intent(out) :: stat
    end subroutine i3_cs_solve_iface

    !> builds and factorises the Newton matrix M + ck (K + alpha C^T C) + cd D_f at (t, e%q,
    !> e%v, lam) of the last evaluation (book: [.., C^T; C, 0] with the multipliers' rows and
    !> no alpha; ck, cd: the step's coefficients, h^2/4 and h/2 for the trapezoidal rule)
    subroutine i3_matrix_iface(self, aux, book, t, e, lam, ck, cd, alpha, stat)
      import :: mbdk_mechanism_t, mbdk_i3_aux_t, mbdk_i3_eval_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      logical, intent(in) :: book
      real(dp), intent(in) :: t, ck, cd, alpha
      type(mbdk_i3_eval_t), intent(in) :: e
      real(dp), intent(in), contiguous :: lam(:)
      integer, intent(out) :: stat
    end subroutine i3_matrix_iface

    !> e%r overwritten by the solution of the Newton matrix's system
    subroutine i3_matrix_solve_iface(self, aux, e, stat)
      import :: mbdk_mechanism_t, mbdk_i3_aux_t, mbdk_i3_eval_t
      class(mbdk_mechanism_t), intent(in) :: self
      class(mbdk_i3_aux_t), intent(inout) :: aux
      type(mbdk_i3_eval_t), intent(inout) :: e
      integer, intent(out) :: stat
    end subroutine i3_matrix_solve_iface
    !> Whether the pose of y = [q; v] lies within MBDK_RANK_LOSS_WINDOW of a rank loss of the
    !> given rows (mbdk_rank_margin, with the model's geometric weights): what a DAE form's
    !> failure is named by (mbdk_mechanism_dae, mbdk_ida). .false. for more than
    !> MBDK_RANK_LOSS_MAX_ROWS rows, or where the evaluation fails.
    logical function near_rank_loss_iface(self, t, y, rows)
      import :: mbdk_mechanism_t, dp
      class(mbdk_mechanism_t), intent(in) :: self
      real(dp), intent(in) :: t, y(:)
      integer, intent(in) :: rows(:)
    end function near_rank_loss_iface
  end interface

contains

  !> The augmented Newton matrix M + ck (K + alpha C^T C) + cd D_f with the tangent K, D_f of
  !> the last i3_matrix and C of the last evaluation, factorised (has_i3_renew). The default:
  !> MBDK_ERR_NOT_APPLICABLE (a model without it builds the whole matrix).
  subroutine mechanism_i3_matrix_renew(self, aux, ck, alpha, stat)
    class(mbdk_mechanism_t), intent(in) :: self
    class(mbdk_i3_aux_t), intent(inout) :: aux
    real(dp), intent(in) :: ck, alpha
    integer, intent(out) :: stat
    stat = MBDK_ERR_NOT_APPLICABLE
  end subroutine mechanism_i3_matrix_renew

  !> e%v overwritten by its mass-orthogonal projection onto C v + Phi_t = 0 (Phi_t: e%phit) at
  !> the last evaluation and factorisation: v - x, M x + C^T mu = 0, C x = C v + Phi_t.
  !> MBDK_ERR_NO_MEMORY, or i3_cs_solve's failure (v then unchanged).
  subroutine mechanism_i3_project_velocity(self, aux, e, stat)
    class(mbdk_mechanism_t), intent(in) :: self
    class(mbdk_i3_aux_t), intent(inout) :: aux
    type(mbdk_i3_eval_t), intent(inout) :: e
    integer, intent(out) :: stat
    real(dp), allocatable :: cv(:), x(:), mu(:), zero(:)
    integer :: astat
    ! aux's work arrays are taken out of it for the calls below, which also take aux (a part
    ! of aux changed through another argument would break the rules on arguments), and put
    ! back after
    call move_alloc(aux%pv_c, cv)
    call move_alloc(aux%pv_x, x)
    call move_alloc(aux%pv_mu, mu)
    call move_alloc(aux%pv_zero, zero)
    if (.not. allocated(zero)) then
      allocate (cv(self%m), x(self%nvel), mu(self%m), zero(self%nvel), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * 2.0_dp * (self%m + self%nvel), stat)
      if (stat /= MBDK_SUCCESS) return
      zero = 0.0_dp
    end if
    call self%i3_c_times(aux, e%v, cv)
    cv(:) = cv + e%phit
    call self%i3_cs_solve(aux, zero, cv, x, mu, stat)
    if (stat == MBDK_SUCCESS) e%v = e%v - x
    call move_alloc(cv, aux%pv_c)
    call move_alloc(x, aux%pv_x)
    call move_alloc(mu, aux%pv_mu)
    call move_alloc(zero, aux%pv_zero)
  end subroutine mechanism_i3_project_velocity

end module mbdk_mechanism
