!> A step-size controller for error-controlled integration: the step it proposes, how it lands
!> on sample times, and how it reacts to an accepted step, a rejected one and a Newton failure.
!> The constants are named components with defaults, so that a driver (trapezoidal_index3's
!> adaptive loop today) states its choices once.
!>
!> After a step with error norm err (the weighted RMS of the local error estimate, 1 = the
!> tolerance) of a method whose error estimate is of order p + 1 in h:
!>   accepted (err <= 1): fac = safety err^(-ki/(p+1)) err_prev^(kp/(p+1)), err_prev the last
!>                        accepted step's (I control: ki = 1, kp = 0, the default; PI control,
!>                        Gustafsson's: ki = 0.7, kp = 0.4), limited to fac_max (1 right after a
!>                        rejection); h is held while fac is within [1, hold] (a driver that
!>                        reuses its Newton matrix keeps it valid), else h_next = fac h, at
!>                        least fac_min h, at most fac_max times the larger of h and the last
!>                        proposal, and at most h_max;
!>   rejected (err > 1):  h_next = max(fac_min, fac) h;
!>   Newton failure:      h_next = newton_cut h.
!> Below h_min the driver ends with MBDK_ERR_STEP_TOO_SMALL (mbdk_controller_too_small).
!> Landing on a sample time t_s from t: a step within land_stretch h of t_s is stretched to it,
!> one within land_halve h is halved, so that no sliver of a step is left before a sample.
module mbdk_step_controller
  use mbdk_kinds, only: dp
  implicit none
  private
  public :: mbdk_controller_init, mbdk_controller_next_step, mbdk_controller_accept, &
    mbdk_controller_reject, mbdk_controller_newton_failure, mbdk_controller_too_small

  type, public :: mbdk_step_controller_t
    real(dp) :: safety = 0.9_dp        !< fraction of the step the error estimate allows
    real(dp) :: fac_min = 0.2_dp       !< smallest change of h after one step
    real(dp) :: fac_max = 5.0_dp       !< largest growth of h after one step
    real(dp) :: hold = 1.2_dp          !< growth up to this factor keeps h unchanged
    real(dp) :: hold_tol = 0.999_dp    !< h counts as the proposal when at least this fraction of it
    real(dp) :: newton_cut = 0.25_dp   !< h after a Newton failure, as a fraction of the failed h
    real(dp) :: land_stretch = 1.1_dp  !< a step within this many h of a sample is stretched to it
    real(dp) :: land_halve = 2.0_dp    !< within this many h, the remainder is split in two
    real(dp) :: err_floor = 1.0e-10_dp !< error norms below this count as this (bounded growth)
    real(dp) :: exponent = 1.0_dp / 3.0_dp   !< 1/(p+1): error estimate O(h^(p+1))
    real(dp) :: h_min = 0.0_dp, h_max = 0.0_dp
    real(dp) :: h_next = 0.0_dp        !< the controller's proposal for the next step
    real(dp) :: growth_limit = 5.0_dp  !< fac_max, or 1 right after a rejection
    !> PI control (Gustafsson 1991; Hairer, Norsett and Wanner I, II.4): an accepted step's
    !> factor is safety err^(-ki exponent) err_prev^(kp exponent); ki = 1, kp = 0 is the I
    !> controller, ki = 0.7, kp = 0.4 the PI controller they recommend
    real(dp) :: ki = 1.0_dp, kp = 0.0_dp
    real(dp) :: err_prev = 1.0_dp      !< the error norm of the last accepted step
  end type mbdk_step_controller_t

contains

  !> From the first step h0 over [t0, t_end]; h_min = 0 takes 1e-12 of the interval's scale,
  !> h_max = 0 the whole interval; p: order of the method (error estimate O(h^(p+1))).
  subroutine mbdk_controller_init(c, h0, h_min, h_max, t0, t_end, p)
    type(mbdk_step_controller_t), intent(out) :: c
    real(dp), intent(in) :: h0, h_min, h_max, t0, t_end
    integer, intent(in) :: p
    real(dp) :: span
    span = t_end - t0
    c%exponent = 1.0_dp / real(p + 1, dp)
    c%h_max = span
    if (h_max > 0.0_dp) c%h_max = min(h_max, span)
    c%h_min = 1.0e-12_dp * max(abs(t0), abs(t_end), span)
    if (h_min > 0.0_dp) c%h_min = max(h_min, c%h_min)
    c%h_next = min(h0, c%h_max)
    c%growth_limit = c%fac_max
  end subroutine mbdk_controller_init

  !> The step from t towards the sample time t_s: the proposal, stretched or halved so as to
  !> land on t_s; returns the end time tn of the step (exactly t_s when it lands there).
  real(dp) function mbdk_controller_next_step(c, t, t_s) result(tn)
    type(mbdk_step_controller_t), intent(in) :: c
    real(dp), intent(in) :: t, t_s
    real(dp) :: h
    h = c%h_next
    if (t_s - t <= c%land_stretch * h) then
      h = t_s - t
    else if (t_s - t < c%land_halve * h) then
      h = 0.5_dp * (t_s - t)
    end if
    tn = t + h
    if (t_s - tn <= 1.0e-12_dp * max(1.0_dp, abs(t_s))) tn = t_s
  end function mbdk_controller_next_step

  !> The growth factor the error norm err allows.
  pure real(dp) function factor(c, err)
    type(mbdk_step_controller_t), intent(in) :: c
    real(dp), intent(in) :: err
    factor = c%safety * max(err, c%err_floor)**(-c%exponent)
  end function factor

  !> After an accepted step of size h with error norm err (<= 1).
  subroutine mbdk_controller_accept(c, h, err)
    type(mbdk_step_controller_t), intent(inout) :: c
    real(dp), intent(in) :: h, err
    real(dp) :: fac
    fac = c%safety * max(err, c%err_floor)**(-c%ki * c%exponent) * &
      c%err_prev**(c%kp * c%exponent)
    fac = min(fac, c%growth_limit)
    c%err_prev = max(err, c%err_floor)
    c%growth_limit = c%fac_max
    ! hold h while the controller asks for up to hold times more (a reused matrix stays valid)
    if (.not. (h >= c%hold_tol * c%h_next .and. fac >= 1.0_dp .and. fac <= c%hold)) &
      c%h_next = min(max(fac * h, c%fac_min * h), c%fac_max * max(c%h_next, h), c%h_max)
  end subroutine mbdk_controller_accept

  !> After a step of size h rejected with error norm err (> 1).
  subroutine mbdk_controller_reject(c, h, err)
    type(mbdk_step_controller_t), intent(inout) :: c
    real(dp), intent(in) :: h, err
    c%h_next = max(c%fac_min, factor(c, err)) * h
    c%growth_limit = 1.0_dp
  end subroutine mbdk_controller_reject

  !> After a step of size h whose Newton iteration failed.
  subroutine mbdk_controller_newton_failure(c, h)
    type(mbdk_step_controller_t), intent(inout) :: c
    real(dp), intent(in) :: h
    c%h_next = c%newton_cut * h
    c%growth_limit = 1.0_dp
  end subroutine mbdk_controller_newton_failure

  logical function mbdk_controller_too_small(c)
    type(mbdk_step_controller_t), intent(in) :: c
    mbdk_controller_too_small = c%h_next < c%h_min
  end function mbdk_controller_too_small

end module mbdk_step_controller
