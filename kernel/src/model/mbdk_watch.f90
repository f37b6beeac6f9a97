!> What a scene run must keep, watched while it runs: the position and velocity constraints and
!> the energy balance. A run that leaves them stops with MBDK_ERR_CONSTRAINT_DRIFT or
!> MBDK_ERR_ENERGY_DRIFT at the check where it happened, instead of returning success with the
!> answer of another mechanism (an unstabilised formulation drifting off the manifold, an
!> explicit method gaining energy, the book's index-3 scheme blowing up with its positions still
!> on the constraints, a driver's work diverging at a dead point).
!>
!> The model (mbdk_model_watch) evaluates the quantities at an accepted state; this module keeps
!> the bookkeeping and the tests, so that it depends on no model:
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
!>              work of dampers, loads and drivers integrated by the trapezoidal rule over the
!>              checks, S the energy scale: the initial kinetic and spring energy plus
!>              sum m_b |g| L, or the largest T + |V_springs| + |V_g - V_g0| + |W| + G seen so
!>              far, G the gross work that has flowed (the integral of |loads| + |drivers| +
!>              dissipation, where the model gives it): the quadrature of W errs in proportion
!>              to that flow, not to the net W, which a machine running steadily against its
!>              load keeps near zero while hundreds of watts pass through its gears.
!>
!> A tolerance <= 0 turns its test off. Checks happen every `every` steps and at every sample.
!> A scene whose energy balance has power terms (dampers, loads, drivers) has its power
!> evaluated at every step (mbdk_watch_power), because the trapezoidal rule over the checks
!> alone would not resolve a power that oscillates within `every` steps. A failure leaves its
!> report in the
!> watch: the quantity, the worst row, the value relative to its scale, the tolerance, the time
!> of the failed check and of the last good one. Samples are checked before they are written,
!> so every sample of a failed run passed its checks.
module mbdk_watch
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  implicit none
  private
  public :: mbdk_watch_start, mbdk_watch_due, mbdk_watch_power, mbdk_watch_test

  integer, parameter, public :: MBDK_WATCH_POSITION = 1, MBDK_WATCH_VELOCITY = 2, &
    MBDK_WATCH_ENERGY = 3
  !> what a step owes the watch (mbdk_watch_due)
  integer, parameter, public :: MBDK_WATCH_NOTHING = 0, MBDK_WATCH_POWER_ONLY = 1, &
    MBDK_WATCH_CHECK = 2
  !> steps between checks by default: a check costs about a third of an rk4 step of a small
  !> scene, so every 16 steps adds a few per cent
  integer, parameter, public :: MBDK_WATCH_EVERY = 16
  !> the report of a failed check, as scene_run returns it (MBDK_WATCH_REPORT words)
  integer, parameter, public :: MBDK_WATCH_REPORT = 8

  type, public :: mbdk_watch_t
    logical :: on = .false.
    real(dp) :: tol_position = 0.0_dp, tol_velocity = 0.0_dp, tol_energy = 0.0_dp
    integer :: every = 1
    logical :: power = .false.      !< the energy balance has power terms: check every step
    integer :: since = 0            !< steps since the last check
    real(dp) :: length = 1.0_dp     !< L
    real(dp), allocatable :: row_scale(:)   !< L_i
    real(dp), allocatable :: vel_scale(:)   !< V_i (running)
    real(dp) :: e0 = 0.0_dp, vg0 = 0.0_dp, work = 0.0_dp, p_prev = 0.0_dp, t_prev = 0.0_dp
    real(dp) :: gross = 0.0_dp, g_prev = 0.0_dp   !< G and its last power (module header)
    real(dp) :: e_scale = 0.0_dp    !< S (running)
    real(dp) :: mass = 1.0_dp       !< sum m_b (the velocity floor sqrt(2 S / sum m_b))
    real(dp) :: t_good = 0.0_dp     !< the time of the last check passed
    !> the failure: quantity (MBDK_WATCH_*), worst row (1-based; 0 for energy), value relative
    !> to its scale, tolerance, time, the value itself and its scale (m or rad, m/s or rad/s, J)
    integer :: what = 0, row = 0
    real(dp) :: value = 0.0_dp, tol = 0.0_dp, t_bad = 0.0_dp, absolute = 0.0_dp, scale = 0.0_dp
  end type mbdk_watch_t

contains

  !> Starts watching at the initial state. row_angular(i): row i is an angle; length: L;
  !> energy parts at t0: kinetic, gravity and spring potential, the power of dampers, loads and
  !> drivers, and the static part of the energy scale (sum m_b |g| L).
  subroutine mbdk_watch_start(w, tol_position, tol_velocity, tol_energy, every, power, length, &
                              row_angular, t0, kinetic, v_gravity, v_springs, power0, &
                              gravity_scale, mass, stat)
    type(mbdk_watch_t), intent(inout) :: w
    real(dp), intent(in) :: tol_position, tol_velocity, tol_energy, length, t0, kinetic, &
      v_gravity, v_springs, power0, gravity_scale, mass
    integer, intent(in) :: every
    logical, intent(in) :: power, row_angular(:)
    integer, intent(out) :: stat   !< MBDK_SUCCESS, or MBDK_ERR_NO_MEMORY
    integer :: m, astat
    m = size(row_angular)
    w%tol_position = max(tol_position, 0.0_dp)
    w%tol_velocity = max(tol_velocity, 0.0_dp)
    w%tol_energy = max(tol_energy, 0.0_dp)
    w%on = (m > 0 .and. (w%tol_position > 0.0_dp .or. w%tol_velocity > 0.0_dp)) .or. &
      w%tol_energy > 0.0_dp
    w%every = max(every, 1)
    w%power = power
    w%since = 0
    w%length = length
    if (allocated(w%row_scale)) deallocate (w%row_scale, w%vel_scale)
    allocate (w%row_scale(m), w%vel_scale(m), stat=astat)
    call mbdk_alloc_status(astat, 2 * MBDK_REAL_BYTES * m, stat)
    if (stat /= MBDK_SUCCESS) return
    w%row_scale = merge(1.0_dp, length, row_angular)
    w%mass = mass
    w%e0 = kinetic + v_gravity + v_springs
    w%vg0 = v_gravity
    w%work = 0.0_dp
    w%gross = 0.0_dp
    w%g_prev = 0.0_dp
    w%p_prev = power0
    w%t_prev = t0
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

  !> Counts a step; what it owes the watch (MBDK_WATCH_*): a check (every `every` steps, or
  !> force: a sample, or the last step), the power alone (scenes with power terms, between
  !> checks), or nothing.
  integer function mbdk_watch_due(w, force)
    type(mbdk_watch_t), intent(inout) :: w
    logical, intent(in) :: force
    mbdk_watch_due = MBDK_WATCH_NOTHING
    if (.not. w%on) return
    w%since = w%since + 1
    if (force .or. w%since >= w%every) then
      mbdk_watch_due = MBDK_WATCH_CHECK
    else if (w%power .and. w%tol_energy > 0.0_dp) then
      mbdk_watch_due = MBDK_WATCH_POWER_ONLY
    end if
  end function mbdk_watch_due

  !> The power of dampers, loads and drivers at an accepted state at time t: its work since the
  !> last evaluation, by the trapezoidal rule.
  subroutine mbdk_watch_power(w, t, power, gross)
    type(mbdk_watch_t), intent(inout) :: w
    real(dp), intent(in) :: t, power
    real(dp), intent(in), optional :: gross   !< |loads| + |drivers| + dissipation at t
    if (.not. w%power) return
    w%work = w%work + 0.5_dp * (w%p_prev + power) * (t - w%t_prev)
    w%p_prev = power
    if (present(gross)) then
      w%gross = w%gross + 0.5_dp * (w%g_prev + gross) * (t - w%t_prev)
      w%g_prev = gross
    end if
    w%t_prev = t
  end subroutine mbdk_watch_power

  !> The tests at an accepted state at time t: phi (m), the velocity residual vres = D v + Phi_t
  !> and its terms' size vterm (m), the energy parts and the power of dampers, loads and drivers
  !> (its work accumulated here unless mbdk_watch_power already took it at t).
  !> MBDK_SUCCESS, or the drift status with the report filled in.
  subroutine mbdk_watch_test(w, t, phi, vres, vterm, kinetic, v_gravity, v_springs, power, stat, &
                             gross)
    type(mbdk_watch_t), intent(inout) :: w
    real(dp), intent(in) :: t, phi(:), vres(:), vterm(:), kinetic, v_gravity, v_springs, power
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: gross
    integer :: worst
    real(dp) :: rmax, e_err
    stat = MBDK_SUCCESS
    w%since = 0
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
      w%e_scale = max(w%e_scale, kinetic + abs(v_springs) + abs(v_gravity - w%vg0) + &
                                 abs(w%work))
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
      if (t /= w%t_prev) call mbdk_watch_power(w, t, power, gross)
      w%e_scale = max(w%e_scale, kinetic + abs(v_springs) + abs(v_gravity - w%vg0) + &
                                 abs(w%work) + w%gross)
      e_err = abs(kinetic + v_gravity + v_springs - w%e0 - w%work) / w%e_scale
      if (.not. (e_err <= w%tol_energy)) then
        call fail(MBDK_WATCH_ENERGY, 0, e_err, w%tol_energy, w%e_scale, MBDK_ERR_ENERGY_DRIFT)
        return
      end if
    end if
    w%t_good = t

  contains

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

end module mbdk_watch
