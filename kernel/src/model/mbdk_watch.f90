!> What a scene run must keep, watched while it runs: the position and velocity constraints, the
!> energy balance, the momenta and angular momenta the scene conserves and the unit norm of its
!> quaternions. A run that leaves them stops with MBDK_ERR_CONSTRAINT_DRIFT,
!> MBDK_ERR_ENERGY_DRIFT or MBDK_ERR_INVARIANT_DRIFT at the check where it happened, instead of
!> returning success with the answer of another mechanism (an unstabilised formulation drifting
!> off the manifold, an explicit method gaining energy, the book's index-3 scheme blowing up with
!> its positions still on the constraints, a driver's work diverging at a dead point, a free
!> body's angular momentum turning under a method that does not keep it).
!>
!> The model (mbdk_model_watch, mbdk_spatial_watch) evaluates the quantities at an accepted
!> state; this module keeps the bookkeeping and the tests, so that it depends on no model:
!>
!>   position   |Phi_i| <= tol_position * L_i, L_i = the mechanism's length scale L for a row
!>              in metres, 1 for a row in radians (an angle of a prismatic, fixed or driver row).
!>              L: the largest body-fixed point of the joints and two-point forces, or the
!>              spread of the initial body positions, whichever is larger (a scene in millimetres
!>              is watched in millimetres).
!>   velocity   |(D v + Phi_t)_i| <= tol_velocity * V_i, V_i the largest value of
!>              sum_j |D_ij v_j| + |Phi_t,i| seen so far in the run (the size of the terms that
!>              must cancel; a running maximum, so that a mechanism passing through rest does not
!>              turn the residual it carries into an alarm), at least the velocity the energy
!>              scale gives the mechanism, sqrt(2 S / sum m_b), per L for an angle row (so that
!>              a run starting from rest is measured against the speeds it will reach).
!>   energy     |E - E0 - W| <= tol_energy * S, E = kinetic + gravity + spring potential, W the
!>              work of dampers, loads and drivers integrated over every accepted step (below),
!>              S the energy scale of the motion: the initial
!>              kinetic and spring energy plus sum m_b |g| L_g, or the largest T + |V_springs| +
!>              |W| + G seen so far, G the gross work that has flowed (the integral of |loads| +
!>              |drivers| + dissipation, where the model gives it: the quadrature of W errs in
!>              proportion to that flow, not to the net W, which a machine running steadily
!>              against its load keeps near zero while hundreds of watts pass through its gears).
!>              L_g is what gravity can move the bodies by: the mechanism's length scale, each
!>              contact's initial gap, each body's radius of gyration (never a length the scene
!>              does not have: a ball dropped 0.2 m onto a floor is measured against m g 0.2 m);
!>              it is the floor of a run that starts from rest, whose first checks would otherwise
!>              compare a first step's error with the energy of that one step. The gravity
!>              potential is not a term of the running scale: without work, V_g - V_g0 =
!>              -(dT + dV_springs), so counting it would count the motion's energy twice.
!>   momentum   |c_k - c_k0| <= tol_momentum * S_k for each component c_k of the momentum p =
!>              sum m_b v_b and of the angular momentum H = sum (r_b - c) x m_b v_b + J_b w_b that
!>              the scene conserves (below), S_k the largest sum_b m_b |v_b| (momentum) or
!>              sum_b |r_b - c| m_b |v_b - v_c| + |J_b w_b| (angular momentum; v_c = 0 about a
!>              fixed point) seen so far: the size of the terms of the sum, from the run's own
!>              motion.
!>   quaternion | |p_b| - 1 | <= tol_quaternion for each body whose orientation is a quaternion
!>              (spatial scenes): kept by a projection after each step (quaternion_norm =
!>              "project" on the ODE forms), held near 1 by a stabilisation term, or left to
!>              drift (quaternion_norm = "none", and the DAE forms, which do not project between
!>              their steps).
!>
!> Which components are conserved is decided once, from the scene's declared elements alone
!> (mbdk_inv_* below, fed by the model's init), by a conservative rule: an element whose forces
!> are not known to leave a component alone makes it unwatched, so the watch may watch fewer
!> invariants than the scene has, never one it does not have. p along e is conserved when no
!> force of an element has a component along e; H about a point along e when no element has a
!> moment about that axis.
!>   - Joints and force elements between two bodies (spherical, revolute, universal, cylindrical,
!>     prismatic and fixed joints, planar distance and point-line joints, two-point springs and
!>     dampers, contacts other than gear meshes and their friction) are internal: their rows, or
!>     their potential, do not change when every body is moved by one rigid motion, so their
!>     forces have no resultant and no moment, and they conserve p and H (a contact's force acts
!>     on both bodies at the same point). Gear meshes (their tooth-relief terms are not checked
!>     for a moment; gears turn on axles to the ground anyway), couplings and drivers (not
!>     invariant under a rigid motion) are taken to conserve nothing.
!>   - Gravity (a uniform field g) has no component across g and no moment about the centre of
!>     mass, nor about any axis along g.
!>   - A tie to the ground whose reaction passes through a fixed point P (a spherical or planar
!>     revolute joint at P, a planar distance joint, a two-point spring or damper anchored at P,
!>     a frictionless contact with a ground circle or ring centred at P) has no moment about P;
!>     a spatial revolute joint at P has none about its axis through P. It may push along any
!>     direction: no p.
!>   - A force along a fixed direction d at a point that moves (a frictionless contact with a
!>     ground line, along its normal; a point on a ground line, a prismatic or cylindrical joint
!>     to the ground, across the line or axis; a point force; a coordinate spring on x or y)
!>     leaves p across d and no H; a torque, or a coordinate spring on an angle, leaves p and no
!>     H. Every other tie to the ground (fixed, universal, a point on a curve, rolling, knife
!>     edges, contacts with friction or on gear teeth) conserves nothing.
!> So: nothing external: all of p and H about the centre of mass; gravity alone: p across g, H
!> about the centre of mass; ties that all pass through one point P and nothing else: H about P
!> along the axes their moments leave free (all, or a revolute axis), and with gravity only along
!> g (in the plane, gravity's moment about P is along the one axis there is: nothing). The heavy
!> top (a spherical joint at its tip, gravity) keeps its vertical angular momentum about the
!> tip; a free body all of p and H; a bar sliding on a horizontal ground line the momentum
!> along the line; a pendulum under gravity nothing.
!>
!> The work W. A scene whose energy balance has power terms (dampers, loads, drivers) has its
!> power evaluated at every accepted step (mbdk_watch_power), because a rule over the checks
!> alone would not resolve a power that oscillates within `every` steps; so has a run that
!> reports its work (record: the run samples W, mbdk_watch_work_at, which is then the work the
!> run integrated, not a quadrature over its samples: a sample's W does not depend on how
!> often the run samples), the energy test off or not. The rule over a step: where the run
!> reports W and the driver has a dense output (dopri54, bs32, bdf, cvode_*, ida) it hands the
!> states at the step's three Gauss nodes (watch_nodes of mbdk_problem, mbdk_watch_nodes), and
!> the step's work is the three-point Gauss-Legendre rule, of sixth order, which also never
!> takes a power on a step's end (a located event leaves a contact's kink there); a sample
!> inside the step takes the integral of the quadratic through the three. Otherwise, and for
!> the fixed-step methods, whose steps the user sets, the trapezoidal rule on the steps' ends
!> (second order, the order of trapezoidal_index3 itself): the energy test at its tolerance
!> does not need more than the three power evaluations a step would cost.
!>
!> A tolerance <= 0 turns its test off. Checks happen every `every` steps and at every sample.
!> A failure leaves its report in the watch: the quantity, the worst row (body, or invariant),
!> the value relative to its scale, the tolerance, the time of the failed check and of the last
!> good one. Samples are checked before they are written, so every sample of a failed run passed
!> its checks.
module mbdk_watch
  use, intrinsic :: iso_c_binding, only: c_int, c_double
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  implicit none
  private
  public :: mbdk_watch_start, mbdk_watch_start_invariants, mbdk_watch_due, mbdk_watch_power, &
    mbdk_watch_test, mbdk_watch_work_at, mbdk_watch_nodes, mbdk_watch_reserve, &
    mbdk_watch_report_of
  public :: mbdk_inv_external, mbdk_inv_gravity, mbdk_inv_force, mbdk_inv_moment, &
    mbdk_inv_pivot, mbdk_inv_result

  integer, parameter, public :: MBDK_WATCH_POSITION = 1, MBDK_WATCH_VELOCITY = 2, &
    MBDK_WATCH_ENERGY = 3, MBDK_WATCH_MOMENTUM = 4, MBDK_WATCH_QUATERNION = 5
  !> what a step owes the watch (mbdk_watch_due)
  integer, parameter, public :: MBDK_WATCH_NOTHING = 0, MBDK_WATCH_POWER_ONLY = 1, &
    MBDK_WATCH_CHECK = 2
  !> steps between checks by default: a check costs about a third of an rk4 step of a small
  !> scene, so every 16 steps adds a few per cent
  integer, parameter, public :: MBDK_WATCH_EVERY = 16
  !> the conserved components (mbdk_inv_result): at most 3 of p and 3 of H, each described by
  !> MBDK_INV_WORDS words: kind (MBDK_INV_*), the unit direction e (3), the fixed point P (3)
  integer, parameter, public :: MBDK_INV_MAX = 6, MBDK_INV_WORDS = 7
  integer, parameter, public :: MBDK_INV_MOMENTUM = 1, MBDK_INV_ANGULAR_POINT = 2, &
    MBDK_INV_ANGULAR_CENTRE = 3
  !> the work parts integrated at every step: dissipated by dampers, of the constraints (drivers),
  !> of the loads; W = -(1) + (2) + (3)
  integer, parameter, public :: MBDK_WORK_PARTS = 3
  !> the words of one record of the work (t_a, t_b, tau(3), W_a(3), P(3, 3): the powers at the
  !> tau): a step that ended at a forced check, which holds the samples written in it, with
  !> three points its powers follow a quadratic through (its Gauss nodes, or for the
  !> trapezoidal rule its ends and their mean at its middle: a line)
  integer, parameter :: REC_WORDS = 17
  !> the weights of the three-point Gauss-Legendre rule (nodes: MBDK_GAUSS3 of mbdk_problem)
  real(dp), parameter :: GAUSS_W(3) = [5.0_dp, 8.0_dp, 5.0_dp] / 18.0_dp

  !> The report of the check that stopped a run, by name (mbdk_watch_report_of): quantity
  !> (MBDK_WATCH_* kind: 1 position, 2 velocity, 3 energy, 4 momentum, 5 quaternion; 0 while
  !> nothing failed), row (1-based: the constraint row, the conserved component, the body; 0 for
  !> energy), value relative to its scale, tolerance, t (of the failed check), t_good (of the
  !> last check passed), the value itself and its scale. bind(C): struct mbdk_watch_report in
  !> mbdk.h, read by name in Python (mbdk.options.unpack; tests/test_structs.py and
  !> kernel/tests/c_struct_layout.c check the mirrors).
  type, bind(C), public :: mbdk_watch_report_t
    real(c_double) :: value = 0.0_dp, tol = 0.0_dp, t = 0.0_dp, t_good = 0.0_dp, &
      absolute = 0.0_dp, scale = 0.0_dp
    integer(c_int) :: quantity = 0, row = 0
  end type mbdk_watch_report_t

  !> What the scene's elements leave conserved, gathered element by element (mbdk_inv_*) and
  !> turned into the components to watch by mbdk_inv_result (the module header gives the rule).
  type, public :: mbdk_inv_rule_t
    logical :: broken = .false.   !< an element that conserves nothing
    !> the directions along which a force may act (an orthonormal basis of nforb): no momentum
    integer :: nforb = 0
    real(dp) :: forb(3, 3) = 0.0_dp
    logical :: no_angular = .false.   !< a force at a moving point, or a moment: no H
    logical :: pivot = .false.    !< the ties pass through one point P: angular momentum about it
    real(dp) :: point(3) = 0.0_dp
    integer :: naxes = 3          !< axes the ties' moments about P leave free: 3 all, 1 axis, 0
    real(dp) :: axis(3) = 0.0_dp
    real(dp) :: g(3) = 0.0_dp     !< gravity's field, summed
  end type mbdk_inv_rule_t

  type, public :: mbdk_watch_t
    logical :: on = .false.
    real(dp) :: tol_position = 0.0_dp, tol_velocity = 0.0_dp, tol_energy = 0.0_dp
    real(dp) :: tol_momentum = 0.0_dp, tol_quaternion = 0.0_dp
    integer :: every = 1
    !> the work is integrated at every step: the balance has power terms, and the energy test
    !> or the record needs it
    logical :: power = .false.
    logical :: record = .false.     !< the run samples its work (mbdk_watch_work_at)
    logical :: forced = .false.     !< the step being watched holds a sample (mbdk_watch_due)
    integer :: since = 0            !< steps since the last check
    real(dp) :: length = 1.0_dp     !< L
    real(dp), allocatable :: row_scale(:)   !< L_i
    real(dp), allocatable :: vel_scale(:)   !< V_i (running)
    real(dp) :: e0 = 0.0_dp, work = 0.0_dp, t_prev = 0.0_dp, t0 = 0.0_dp
    !> the work parts (MBDK_WORK_PARTS) integrated so far and their powers at t_prev
    real(dp) :: wpart(MBDK_WORK_PARTS) = 0.0_dp, p_prev(MBDK_WORK_PARTS) = 0.0_dp
    real(dp) :: gross = 0.0_dp, g_prev = 0.0_dp   !< G and its last power (module header)
    !> the powers at the Gauss nodes tn of the step [t_a, t_b] (mbdk_watch_nodes), which its
    !> mbdk_watch_power then integrates with, in place of the trapezoidal rule
    logical :: pending = .false.
    real(dp) :: pend_t(2) = 0.0_dp, pend_tn(3) = 0.0_dp, pend_p(MBDK_WORK_PARTS, 3) = 0.0_dp
    real(dp) :: e_scale = 0.0_dp    !< S (running)
    real(dp) :: mass = 1.0_dp       !< sum m_b (the velocity floor sqrt(2 S / sum m_b))
    !> the conserved components (mbdk_inv_result), their values at t0 and the running scales
    !> of p and H (module header)
    integer :: ninv = 0
    real(dp) :: inv(MBDK_INV_WORDS, MBDK_INV_MAX) = 0.0_dp, inv0(MBDK_INV_MAX) = 0.0_dp
    real(dp) :: mom_scale(2) = 0.0_dp
    integer :: nquat = 0            !< bodies whose orientation is a quaternion
    !> the records of the work (REC_WORDS each), nrec of them; rec_lost: one could not be
    !> allocated (the caller reports MBDK_ERR_NO_MEMORY: the samples' work is incomplete)
    real(dp), allocatable :: rec(:, :)
    integer :: nrec = 0
    logical :: rec_lost = .false.
    real(dp) :: t_good = 0.0_dp     !< the time of the last check passed
    !> the failure: quantity (MBDK_WATCH_*), worst row (1-based: the constraint row, the
    !> invariant, the body; 0 for energy), value relative to its scale, tolerance, time, the
    !> value itself and its scale (m or rad, m/s or rad/s, J, kg m/s or kg m^2/s, 1)
    integer :: what = 0, row = 0
    real(dp) :: value = 0.0_dp, tol = 0.0_dp, t_bad = 0.0_dp, absolute = 0.0_dp, scale = 0.0_dp
  end type mbdk_watch_t

contains

  !> The watch's report of its failed check (all 0 while none failed).
  function mbdk_watch_report_of(w) result(r)
    type(mbdk_watch_t), intent(in) :: w
    type(mbdk_watch_report_t) :: r
    r = mbdk_watch_report_t(value=w%value, tol=w%tol, t=w%t_bad, t_good=w%t_good, &
                            absolute=w%absolute, scale=w%scale, quantity=w%what, row=w%row)
  end function mbdk_watch_report_of

  !> Starts watching at the initial state. row_angular(i): row i is an angle; length: L;
  !> energy parts at t0: kinetic, gravity and spring potential, the powers of the work parts
  !> (MBDK_WORK_PARTS), and the static part of the energy scale (sum m_b |g| L_g). power: the
  !> balance has power terms; record: the run samples its work (mbdk_watch_work_at).
  subroutine mbdk_watch_start(w, tol_position, tol_velocity, tol_energy, every, power, length, &
                              row_angular, t0, kinetic, v_gravity, v_springs, power0, &
                              gravity_scale, mass, stat, record)
    type(mbdk_watch_t), intent(inout) :: w
    real(dp), intent(in) :: tol_position, tol_velocity, tol_energy, length, t0, kinetic, &
      v_gravity, v_springs, power0(MBDK_WORK_PARTS), gravity_scale, mass
    integer, intent(in) :: every
    logical, intent(in) :: power, row_angular(:)
    integer, intent(out) :: stat   !< MBDK_SUCCESS, or MBDK_ERR_NO_MEMORY
    logical, intent(in), optional :: record
    integer :: m, astat
    m = size(row_angular)
    w%tol_position = max(tol_position, 0.0_dp)
    w%tol_velocity = max(tol_velocity, 0.0_dp)
    w%tol_energy = max(tol_energy, 0.0_dp)
    w%record = .false.
    if (present(record)) w%record = record
    w%power = power .and. (w%tol_energy > 0.0_dp .or. w%record)
    w%on = (m > 0 .and. (w%tol_position > 0.0_dp .or. w%tol_velocity > 0.0_dp)) .or. &
      w%tol_energy > 0.0_dp .or. w%power
    w%tol_momentum = 0.0_dp
    w%tol_quaternion = 0.0_dp
    w%ninv = 0
    w%nquat = 0
    w%every = max(every, 1)
    w%since = 0
    w%forced = .false.
    w%length = length
    if (allocated(w%row_scale)) deallocate (w%row_scale, w%vel_scale)
    allocate (w%row_scale(m), w%vel_scale(m), stat=astat)
    call mbdk_alloc_status(astat, 2 * MBDK_REAL_BYTES * m, stat)
    if (stat /= MBDK_SUCCESS) return
    w%row_scale = merge(1.0_dp, length, row_angular)
    w%mass = mass
    w%e0 = kinetic + v_gravity + v_springs
    w%work = 0.0_dp
    w%wpart = 0.0_dp
    w%gross = 0.0_dp
    w%g_prev = 0.0_dp
    w%p_prev = power0
    w%t_prev = t0
    w%t0 = t0
    w%nrec = 0
    w%rec_lost = .false.
    w%pending = .false.
    w%e_scale = kinetic + abs(v_springs) + gravity_scale
    if (.not. (w%e_scale > 0.0_dp)) w%e_scale = tiny(1.0_dp)
    w%vel_scale = w%row_scale / length * sqrt(2.0_dp * w%e_scale / mass)
    w%t_good = t0
    w%what = 0
    w%row = 0
    w%value = 0.0_dp
    w%tol = 0.0_dp
    w%t_bad = t0
    w%absolute = 0.0_dp
    w%scale = 0.0_dp
  end subroutine mbdk_watch_start

  !> After mbdk_watch_start: the conserved components inv(:, 1:ninv) (mbdk_inv_result) with the
  !> momentum and angular momentum at t0, mom0 = (p, H) (H about the components' point, or the
  !> centre of mass), and their scales (module header); nquat bodies with quaternions.
  subroutine mbdk_watch_start_invariants(w, tol_momentum, inv, ninv, mom0, mom_scale0, &
                                         tol_quaternion, nquat)
    type(mbdk_watch_t), intent(inout) :: w
    real(dp), intent(in) :: tol_momentum, inv(:, :), mom0(6), mom_scale0(2), tol_quaternion
    integer, intent(in) :: ninv, nquat
    integer :: k
    w%tol_momentum = max(tol_momentum, 0.0_dp)
    w%tol_quaternion = max(tol_quaternion, 0.0_dp)
    w%ninv = 0
    if (w%tol_momentum > 0.0_dp) w%ninv = min(ninv, MBDK_INV_MAX)
    w%nquat = 0
    if (w%tol_quaternion > 0.0_dp) w%nquat = nquat
    do k = 1, w%ninv
      w%inv(:, k) = inv(:, k)
      w%inv0(k) = component(w%inv(:, k), mom0)
    end do
    w%mom_scale = mom_scale0
    w%on = w%on .or. w%ninv > 0 .or. w%nquat > 0
  end subroutine mbdk_watch_start_invariants

  !> The value of the conserved component described by d (MBDK_INV_WORDS) in mom = (p, H).
  pure real(dp) function component(d, mom)
    real(dp), intent(in) :: d(MBDK_INV_WORDS), mom(6)
    if (nint(d(1)) == MBDK_INV_MOMENTUM) then
      component = dot_product(d(2:4), mom(1:3))
    else
      component = dot_product(d(2:4), mom(4:6))
    end if
  end function component

  !> Counts a step; what it owes the watch (MBDK_WATCH_*): a check (every `every` steps, or
  !> force: a sample, or the last step), the power alone (scenes with power terms, between
  !> checks), or nothing.
  integer function mbdk_watch_due(w, force)
    type(mbdk_watch_t), intent(inout) :: w
    logical, intent(in) :: force
    mbdk_watch_due = MBDK_WATCH_NOTHING
    w%forced = force
    if (.not. w%on) return
    w%since = w%since + 1
    if (force .or. w%since >= w%every) then
      mbdk_watch_due = MBDK_WATCH_CHECK
    else if (w%power) then
      mbdk_watch_due = MBDK_WATCH_POWER_ONLY
    end if
  end function mbdk_watch_due

  !> The powers p(:, k) of the work parts at the states of the accepted step [t_a, t_b] at its
  !> Gauss nodes tn(k) (MBDK_GAUSS3 of mbdk_problem): the step's work by the three-point
  !> Gauss-Legendre rule, of sixth order, which mbdk_watch_power for t_b takes.
  subroutine mbdk_watch_nodes(w, t_a, t_b, tn, p)
    type(mbdk_watch_t), intent(inout) :: w
    real(dp), intent(in) :: t_a, t_b, tn(3), p(MBDK_WORK_PARTS, 3)
    w%pending = w%power
    w%pend_t = [t_a, t_b]
    w%pend_tn = tn
    w%pend_p = p
  end subroutine mbdk_watch_nodes

  !> The powers of the work parts (MBDK_WORK_PARTS: dissipated by dampers, of the constraints,
  !> of the loads) at an accepted state at time t: their work since the last evaluation, by the
  !> Gauss rule of the step where mbdk_watch_nodes gave it, else by the trapezoidal rule. A step
  !> that holds a sample (forced) is recorded for mbdk_watch_work_at.
  subroutine mbdk_watch_power(w, t, power, gross)
    type(mbdk_watch_t), intent(inout) :: w
    real(dp), intent(in) :: t, power(MBDK_WORK_PARTS)
    real(dp), intent(in), optional :: gross   !< |loads| + |drivers| + dissipation at t
    real(dp) :: tau(3), pt(MBDK_WORK_PARTS, 3)
    integer :: k
    if (.not. w%power) return
    if (w%pending .and. w%pend_t(1) == w%t_prev .and. w%pend_t(2) == t) then
      tau = w%pend_tn
      pt = w%pend_p
    else
      tau = [w%t_prev, 0.5_dp * (w%t_prev + t), t]
      pt(:, 1) = w%p_prev
      pt(:, 3) = power
      pt(:, 2) = 0.5_dp * (pt(:, 1) + pt(:, 3))
    end if
    if (w%record .and. w%forced .and. t > w%t_prev) call add_record()
    if (w%pending .and. w%pend_t(1) == w%t_prev .and. w%pend_t(2) == t) then
      do k = 1, 3
        w%wpart = w%wpart + (GAUSS_W(k) * (t - w%t_prev)) * pt(:, k)
      end do
    else
      w%wpart = w%wpart + 0.5_dp * (pt(:, 1) + pt(:, 3)) * (t - w%t_prev)
    end if
    w%pending = .false.
    w%work = w%wpart(3) + w%wpart(2) - w%wpart(1)
    w%p_prev = power
    if (present(gross)) then
      w%gross = w%gross + 0.5_dp * (w%g_prev + gross) * (t - w%t_prev)
      w%g_prev = gross
    end if
    w%t_prev = t

  contains

    subroutine add_record()
      real(dp), allocatable :: grown(:, :)
      integer :: astat
      if (.not. allocated(w%rec)) then
        allocate (w%rec(REC_WORDS, 64), stat=astat)
        if (astat /= 0) w%rec_lost = .true.
        if (astat /= 0) return
      end if
      if (w%nrec >= size(w%rec, 2)) then
        allocate (grown(REC_WORDS, 2 * size(w%rec, 2)), stat=astat)
        if (astat /= 0) w%rec_lost = .true.
        if (astat /= 0) return
        grown(:, 1:w%nrec) = w%rec(:, 1:w%nrec)
        call move_alloc(grown, w%rec)
      end if
      w%nrec = w%nrec + 1
      w%rec(:, w%nrec) = [w%t_prev, t, tau, w%wpart, pt(:, 1), pt(:, 2), pt(:, 3)]
    end subroutine add_record

  end subroutine mbdk_watch_power

  !> Room for the records of n steps that hold samples, before the run (mbdk_watch_start keeps
  !> it): MBDK_SUCCESS or MBDK_ERR_NO_MEMORY. More records grow it as they come.
  subroutine mbdk_watch_reserve(w, n, stat)
    type(mbdk_watch_t), intent(inout) :: w
    integer, intent(in) :: n
    integer, intent(out) :: stat
    integer :: astat
    stat = MBDK_SUCCESS
    if (allocated(w%rec)) deallocate (w%rec)
    allocate (w%rec(REC_WORDS, max(n, 1)), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * REC_WORDS * max(n, 1), stat)
  end subroutine mbdk_watch_reserve

  !> The work parts at a sample time t of the run (after it, samples in increasing t): at t0
  !> zero; in a recorded step [t_a, t_b] (one that held a sample) W_a plus the integral of the
  !> quadratic through the powers at the record's three points (its Gauss nodes, whose rule
  !> integrates it over the step to the step's work; or the trapezoidal rule's line), so that at
  !> t_b it is W_b; at the last state watched its work. A sample past every record
  !> (the states a step that failed after writing its samples leaves) extrapolates the last
  !> power: no sample is left without its work. k: the record to search from (0 at the first
  !> sample), updated. Without power terms the work is zero.
  subroutine mbdk_watch_work_at(w, t, k, parts)
    type(mbdk_watch_t), intent(in) :: w
    real(dp), intent(in) :: t
    integer, intent(inout) :: k
    real(dp), intent(out) :: parts(MBDK_WORK_PARTS)
    parts = 0.0_dp
    if (.not. w%power .or. t <= w%t0) return
    k = max(k, 1)
    do while (k <= w%nrec)
      if (w%rec(2, k) >= t) exit
      k = k + 1
    end do
    if (k <= w%nrec) then
      if (w%rec(1, k) <= t) then
        parts = w%rec(6:8, k) + quad_integral(w%rec(:, k), t)
        return
      end if
    end if
    if (t == w%t_prev) then
      parts = w%wpart
    else if (k > 1 .and. w%nrec > 0 .and. t < w%t_prev) then
      associate (r => w%rec(:, min(k - 1, w%nrec)))
        parts = r(6:8) + quad_integral(r, r(2)) + (t - r(2)) * quad_at(r, r(2))
      end associate
    else
      parts = w%wpart + (t - w%t_prev) * w%p_prev
    end if

  contains

    !> the integral from t_a to s of the quadratic of record r (the three-point Gauss rule on
    !> [t_a, s] is exact for it)
    pure function quad_integral(r, s) result(v)
      real(dp), intent(in) :: r(REC_WORDS), s
      real(dp) :: v(MBDK_WORK_PARTS), nodes(3)
      integer :: i
      nodes = 0.5_dp - sqrt(0.15_dp) * [1.0_dp, 0.0_dp, -1.0_dp]
      v = 0.0_dp
      do i = 1, 3
        v = v + (GAUSS_W(i) * (s - r(1))) * quad_at(r, r(1) + nodes(i) * (s - r(1)))
      end do
    end function quad_integral

    !> the quadratic of record r (Lagrange, through its three points) at s
    pure function quad_at(r, s) result(v)
      real(dp), intent(in) :: r(REC_WORDS), s
      real(dp) :: v(MBDK_WORK_PARTS), l
      integer :: i, j
      v = 0.0_dp
      do i = 1, 3
        l = 1.0_dp
        do j = 1, 3
          if (j /= i) l = l * (s - r(2 + j)) / (r(2 + i) - r(2 + j))
        end do
        v = v + l * r(6 + 3 * i:8 + 3 * i)
      end do
    end function quad_at

  end subroutine mbdk_watch_work_at

  !> The tests at an accepted state at time t: phi (m), the velocity residual vres = D v + Phi_t
  !> and its terms' size vterm (m), the energy parts and the powers of the work parts (their
  !> work accumulated here unless mbdk_watch_power already took it at t); mom = (p, H) and their
  !> scales (module header), where the scene conserves any of them; qdev(b) = | |p_b| - 1 | of
  !> the bodies with quaternions. MBDK_SUCCESS, or the drift status with the report filled in.
  subroutine mbdk_watch_test(w, t, phi, vres, vterm, kinetic, v_gravity, v_springs, power, stat, &
                             gross, mom, mom_scale, qdev)
    type(mbdk_watch_t), intent(inout) :: w
    real(dp), intent(in) :: t, phi(:), vres(:), vterm(:), kinetic, v_gravity, v_springs, &
      power(MBDK_WORK_PARTS)
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: gross, mom(6), mom_scale(2), qdev(:)
    integer :: worst, k, j
    real(dp) :: rmax, e_err, r, c
    stat = MBDK_SUCCESS
    w%since = 0
    ! the work first, so that a sample's step has its record whatever the tests find
    if (t /= w%t_prev) call mbdk_watch_power(w, t, power, gross)
    w%e_scale = max(w%e_scale, motion_energy())
    if (w%tol_position > 0.0_dp .and. size(phi) > 0) then
      call worst_ratio(phi, w%row_scale, rmax, worst)
      if (.not. (rmax <= w%tol_position)) then
        call fail(MBDK_WATCH_POSITION, worst, rmax, w%tol_position, w%row_scale(max(worst, 1)), &
                  MBDK_ERR_CONSTRAINT_DRIFT)
        return
      end if
    end if
    if (w%tol_velocity > 0.0_dp .and. size(vres) > 0) then
      ! the floor from the energy reached so far, this state's included: a scene started at
      ! rest (gears spun up by a torque about joints at their centroids) has terms of roundoff
      ! size only, and its first check would measure roundoff against roundoff
      w%vel_scale = max(w%vel_scale, vterm, w%row_scale / w%length * &
                        sqrt(2.0_dp * w%e_scale / w%mass))
      call worst_ratio(vres, w%vel_scale, rmax, worst)
      if (.not. (rmax <= w%tol_velocity)) then
        call fail(MBDK_WATCH_VELOCITY, worst, rmax, w%tol_velocity, w%vel_scale(max(worst, 1)), &
                  MBDK_ERR_CONSTRAINT_DRIFT)
        return
      end if
    end if
    if (w%tol_energy > 0.0_dp) then
      e_err = abs(kinetic + v_gravity + v_springs - w%e0 - w%work) / w%e_scale
      if (.not. (e_err <= w%tol_energy)) then
        call fail(MBDK_WATCH_ENERGY, 0, e_err, w%tol_energy, w%e_scale, MBDK_ERR_ENERGY_DRIFT)
        return
      end if
    end if
    if (w%ninv > 0 .and. present(mom) .and. present(mom_scale)) then
      w%mom_scale = max(w%mom_scale, mom_scale)
      rmax = 0.0_dp
      worst = 0
      do k = 1, w%ninv
        j = merge(1, 2, nint(w%inv(1, k)) == MBDK_INV_MOMENTUM)
        c = abs(component(w%inv(:, k), mom) - w%inv0(k))
        r = c / max(w%mom_scale(j), tiny(1.0_dp))
        if (.not. (r <= rmax)) then
          rmax = r
          worst = k
        end if
      end do
      if (.not. (rmax <= w%tol_momentum)) then
        j = merge(1, 2, nint(w%inv(1, worst)) == MBDK_INV_MOMENTUM)
        call fail(MBDK_WATCH_MOMENTUM, worst, rmax, w%tol_momentum, &
                  max(w%mom_scale(j), tiny(1.0_dp)), MBDK_ERR_INVARIANT_DRIFT)
        return
      end if
    end if
    if (w%nquat > 0 .and. present(qdev)) then
      rmax = 0.0_dp
      worst = 0
      do k = 1, min(w%nquat, size(qdev))
        if (.not. (qdev(k) <= rmax)) then
          rmax = qdev(k)
          worst = k
        end if
      end do
      if (.not. (rmax <= w%tol_quaternion)) then
        call fail(MBDK_WATCH_QUATERNION, worst, rmax, w%tol_quaternion, 1.0_dp, &
                  MBDK_ERR_INVARIANT_DRIFT)
        return
      end if
    end if
    w%t_good = t

  contains

    !> the running part of the energy scale (module header)
    real(dp) function motion_energy()
      motion_energy = kinetic + abs(v_springs) + abs(w%work) + w%gross
    end function motion_energy

    !> The largest |x_i| / scale_i and its row (NaN counts as the worst).
    pure subroutine worst_ratio(x, scale, rmax, worst)
      real(dp), intent(in) :: x(:), scale(:)
      real(dp), intent(out) :: rmax
      integer, intent(out) :: worst
      integer :: i
      real(dp) :: r
      worst = 0
      rmax = 0.0_dp
      do i = 1, size(x)
        r = abs(x(i)) / scale(i)
        if (.not. (r <= rmax)) then
          rmax = r
          worst = i
        end if
      end do
    end subroutine worst_ratio

    subroutine fail(what, row, value, tol, scale, code)
      integer, intent(in) :: what, row, code
      real(dp), intent(in) :: value, tol, scale
      w%what = what
      w%row = row
      w%value = value
      w%tol = tol
      w%t_bad = t
      w%scale = scale
      w%absolute = value * scale
      stat = code
    end subroutine fail

  end subroutine mbdk_watch_test

  ! ---- the conserved components (the module header's rule) -------------------------------

  !> An element that conserves none of them.
  subroutine mbdk_inv_external(rule)
    type(mbdk_inv_rule_t), intent(inout) :: rule
    rule%broken = .true.
  end subroutine mbdk_inv_external

  !> A uniform gravity field g.
  subroutine mbdk_inv_gravity(rule, g)
    type(mbdk_inv_rule_t), intent(inout) :: rule
    real(dp), intent(in) :: g(3)
    rule%g = rule%g + g
    call forbid(rule, g)
  end subroutine mbdk_inv_gravity

  !> A force on a body along the fixed direction d only (a ground line's normal, a point
  !> force), at a point that moves: no momentum along d, no angular momentum.
  subroutine mbdk_inv_force(rule, d)
    type(mbdk_inv_rule_t), intent(inout) :: rule
    real(dp), intent(in) :: d(3)
    call forbid(rule, d)
    rule%no_angular = .true.
  end subroutine mbdk_inv_force

  !> A moment on a body (a torque): no angular momentum.
  subroutine mbdk_inv_moment(rule)
    type(mbdk_inv_rule_t), intent(inout) :: rule
    rule%no_angular = .true.
  end subroutine mbdk_inv_moment

  !> A tie to the ground whose reaction has no moment about the fixed point p, or only about
  !> the axis through p when axis is given (a spatial revolute joint): no momentum.
  subroutine mbdk_inv_pivot(rule, p, axis)
    type(mbdk_inv_rule_t), intent(inout) :: rule
    real(dp), intent(in) :: p(3)
    real(dp), intent(in), optional :: axis(3)
    real(dp) :: a(3)
    integer :: k
    do k = 1, 3
      call forbid(rule, unit(k))
    end do
    if (.not. rule%pivot) then
      rule%pivot = .true.
      rule%point = p
    else if (.not. (norm2(p - rule%point) <= 1.0e-12_dp * max(norm2(p), norm2(rule%point)))) then
      rule%naxes = 0       ! ties through two points: no moment-free axis is known
    end if
    if (.not. present(axis) .or. rule%naxes == 0) return
    if (.not. (norm2(axis) > 0.0_dp)) then
      rule%naxes = 0
      return
    end if
    a = axis / norm2(axis)
    if (rule%naxes == 3) then
      rule%naxes = 1
      rule%axis = a
    else if (.not. (norm2(cross(a, rule%axis)) <= 1.0e-12_dp)) then
      rule%naxes = 0
    end if
  end subroutine mbdk_inv_pivot

  !> d joins the directions along which a force may act (an orthonormal basis, Gram-Schmidt).
  subroutine forbid(rule, d)
    type(mbdk_inv_rule_t), intent(inout) :: rule
    real(dp), intent(in) :: d(3)
    real(dp) :: x(3)
    integer :: k
    if (.not. (norm2(d) > 0.0_dp) .or. rule%nforb >= 3) return
    x = d / norm2(d)
    do k = 1, rule%nforb
      x = x - dot_product(x, rule%forb(:, k)) * rule%forb(:, k)
    end do
    if (.not. (norm2(x) > 1.0e-9_dp)) return
    rule%nforb = rule%nforb + 1
    rule%forb(:, rule%nforb) = x / norm2(x)
  end subroutine forbid

  !> The components to watch (inv(:, 1:ninv), MBDK_INV_WORDS each; the module header's rule).
  !> planar: the bodies move in the x-y plane (p has x and y, H only z).
  subroutine mbdk_inv_result(rule, planar, inv, ninv)
    type(mbdk_inv_rule_t), intent(in) :: rule
    logical, intent(in) :: planar
    real(dp), intent(out) :: inv(MBDK_INV_WORDS, MBDK_INV_MAX)
    integer, intent(out) :: ninv
    type(mbdk_inv_rule_t) :: lin
    real(dp) :: g(3), gn, x(3)
    integer :: k, j
    inv = 0.0_dp
    ninv = 0
    if (rule%broken) return
    ! the momentum: the directions no force may act along, the complement of the forbidden
    lin = rule
    if (planar) call forbid(lin, unit(3))
    do k = 1, 3
      x = unit(k)
      do j = 1, lin%nforb
        x = x - dot_product(x, lin%forb(:, j)) * lin%forb(:, j)
      end do
      if (norm2(x) > 1.0e-9_dp) then
        call add(MBDK_INV_MOMENTUM, x / norm2(x), [0.0_dp, 0.0_dp, 0.0_dp])
        call forbid(lin, x)
      end if
    end do
    if (rule%no_angular) return
    g = rule%g
    if (planar) g(3) = 0.0_dp
    gn = norm2(g)
    if (gn > 0.0_dp) g = g / gn
    if (.not. rule%pivot) then
      ! no tie to the ground: about the centre of mass, which gravity has no moment about
      do k = merge(3, 1, planar), 3
        call add(MBDK_INV_ANGULAR_CENTRE, unit(k), [0.0_dp, 0.0_dp, 0.0_dp])
      end do
      return
    end if
    if (rule%naxes == 0) return
    if (planar) then
      ! the one axis, z: a tie's moment about it is free, gravity's in the plane is not
      if (gn > 0.0_dp) return
      if (rule%naxes == 1 .and. .not. (abs(abs(rule%axis(3)) - 1.0_dp) <= 1.0e-12_dp)) return
      call add(MBDK_INV_ANGULAR_POINT, unit(3), rule%point)
    else if (rule%naxes == 1) then
      if (gn > 0.0_dp .and. .not. (norm2(cross(rule%axis, g)) <= 1.0e-12_dp)) return
      call add(MBDK_INV_ANGULAR_POINT, rule%axis, rule%point)
    else if (gn > 0.0_dp) then
      call add(MBDK_INV_ANGULAR_POINT, g, rule%point)
    else
      do k = 1, 3
        call add(MBDK_INV_ANGULAR_POINT, unit(k), rule%point)
      end do
    end if

  contains

    !> (a component along -e is the one along e: e is given its largest entry positive)
    subroutine add(kind, e, p)
      integer, intent(in) :: kind
      real(dp), intent(in) :: e(3), p(3)
      ninv = ninv + 1
      inv(:, ninv) = [real(kind, dp), sign(1.0_dp, e(maxloc(abs(e), 1))) * e, p]
    end subroutine add

  end subroutine mbdk_inv_result

  pure function unit(k) result(e)
    integer, intent(in) :: k
    real(dp) :: e(3)
    e = 0.0_dp
    e(k) = 1.0_dp
  end function unit

  pure function cross(a, b) result(c)
    real(dp), intent(in) :: a(3), b(3)
    real(dp) :: c(3)
    c = [a(2) * b(3) - a(3) * b(2), a(3) * b(1) - a(1) * b(3), a(1) * b(2) - a(2) * b(1)]
  end function cross

  !> Two unit vectors normal to the unit vector a and to each other.
  pure subroutine normals(a, e1, e2)
    real(dp), intent(in) :: a(3)
    real(dp), intent(out) :: e1(3), e2(3)
    integer :: k
    k = minloc(abs(a), 1)
    e1 = cross(a, unit(k))
    e1 = e1 / norm2(e1)
    e2 = cross(a, e1)
  end subroutine normals

end module mbdk_watch
