!> Wear laws as scene effects (Fekete (2023) chapter 6): each wear element carries one state W,
!> the worn volume, integrated with the dynamics as part of y = [q; v; W] by whichever method
!> runs the scene, so that its accuracy is the run's and no second pass over stored samples is
!> needed. Its rate is
!>   1 archard  dW/dt = k F u                                   (6.3)-(6.4)
!>   2 gear     dW/dt = k F psi(u, Ts) u,  u = R |omega1 - omega2|   (6.7)-(6.10), see below
!>   3 knee     dW/dt = k F u S/R(t)                            (6.11)-(6.13)
!> with F the load: the normal force of a contact (load 1) or the force of a friction element
!> (load 2), and u the contact's sliding speed |slip| (archard, knee) or, for the gear law, the
!> relative angular speed of the contact's two bodies times the radius R the book uses as the
!> distance of the contact from the pitch point. The book writes the gear law's speed as
!> 2 pi R (omega1 + omega2) in (6.5), (6.7) and (6.10) but R (omega1 + omega2) in (6.9): with
!> omega in rad/s the speed is R |omega1 - omega2| (the two gears turn in opposite senses, so
!> that is the sum of their speeds), and the 2 pi belongs to neither (studies/ch6_numbers.py).
!> The lubrication factor (6.8):
!>   psi(u, Ts) = 1 - exp(-(a_x / (u t0)) exp(-Ea / (Rg Ts))),   psi = 1 at u = 0 (its limit).
!> S/R(t) = c0 + c1 t + c2 t^2 + c3 t^3 (table 6.7 gives its coefficients for one squat cycle
!> from t = 0; t is the run's own time, so a run over several cycles extrapolates the cubic).
!>
!> Table entries in the scene's force table: fint = (MBDK_EFFECT_WEAR, law, load, column of the
!> contact (load 1) or of the friction element (load 2)); freal(1) = k; gear: freal(2:7) = R, Ts,
!> a_x, t0, Ea, Rg; knee: freal(2:5) = c0..c3.
!>
!> The laws themselves (mbdk_wear_law: the rate from a load F and a speed u) are one code for
!> both models: the planar contacts take F and u here (mbdk_wear_rate), the spatial model its
!> spheres' normal force and slip speed (mbdk_spatial_model, whose table keeps the reals above;
!> the gear law's u is a planar gear pair's R |omega1 - omega2|, so spatial contacts take
!> archard and knee).
module mbdk_wear
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_NONFINITE
  use mbdk_contact, only: mbdk_contact_t, mbdk_contact_eval
  use mbdk_contact_law, only: mbdk_friction_mu
  implicit none
  private
  public :: mbdk_wear_rate, mbdk_wear_rates, mbdk_wear_psi, mbdk_wear_law

  integer, parameter, public :: MBDK_WEAR_ARCHARD = 1, MBDK_WEAR_GEAR = 2, MBDK_WEAR_KNEE = 3, &
    MBDK_WEAR_LAWS = 3
  integer, parameter, public :: MBDK_WEAR_LOAD_NORMAL = 1, MBDK_WEAR_LOAD_FRICTION = 2

contains

  !> The lubrication factor (6.8) at sliding speed u >= 0; fr = freal of a gear-law entry.
  pure real(dp) function mbdk_wear_psi(u, fr) result(psi)
    real(dp), intent(in) :: u, fr(:)
    real(dp) :: x
    if (.not. (u > 0.0_dp)) then
      psi = 1.0_dp
      return
    end if
    x = fr(4) / (u * fr(5)) * exp(-fr(6) / (fr(7) * fr(3)))
    psi = -expm1_(-x)
  end function mbdk_wear_psi

  !> 1 - exp(-x) without the cancellation of small x (psi is about 1e-7 at the book's values).
  pure real(dp) function expm1_(x) result(e)
    real(dp), intent(in) :: x
    if (abs(x) < 1.0e-5_dp) then
      e = x * (1.0_dp + x * (0.5_dp + x / 6.0_dp))
    else
      e = exp(x) - 1.0_dp
    end if
  end function expm1_

  !> dW/dt of wear entry (fi, fr) at (q, v, t); fint, freal: the table its column refers to.
  !> ok = .false. where the contact has no normal (mbdk_contact_eval).
  pure subroutine mbdk_wear_rate(fi, fr, fint, freal, rot, q, v, t, rate, ok)
    integer, intent(in) :: fi(:), fint(:, :)
    real(dp), intent(in) :: fr(:), freal(:, :), rot(:, :), q(:), v(:), t
    real(dp), intent(out) :: rate
    logical, intent(out) :: ok
    type(mbdk_contact_t) :: ct
    integer :: c, cc, k
    real(dp) :: load, u, w1, w2

    rate = 0.0_dp
    c = fi(4)
    cc = c
    if (fi(3) == MBDK_WEAR_LOAD_FRICTION) cc = fint(4, c)
    call mbdk_contact_eval(fint(:, cc), freal(:, cc), rot, q, v, ct, ok)
    if (.not. ok .or. .not. ct%touching) return
    ! the sum over the touching pairs (a gear mesh has one or two)
    do k = 1, ct%npair
      load = ct%weight(k) * ct%force
      if (fi(3) == MBDK_WEAR_LOAD_FRICTION) &
        load = abs(mbdk_friction_mu(ct%slip(k), freal(:, c))) * load
      if (fi(2) == MBDK_WEAR_GEAR) then
        w1 = 0.0_dp
        w2 = 0.0_dp
        if (fint(2, cc) > 0) w1 = v(3 * fint(2, cc))
        if (fint(3, cc) > 0) w2 = v(3 * fint(3, cc))
        u = fr(2) * abs(w1 - w2)
      else
        u = abs(ct%slip(k))
      end if
      rate = rate + mbdk_wear_law(fi(2), fr, load, u, t)
    end do
  end subroutine mbdk_wear_rate

  !> dW/dt of the law (MBDK_WEAR_*) with the reals fr of its entry (k first) at the load F
  !> and the speed u >= 0 (the sliding speed; the gear law's R |omega1 - omega2|) at time t.
  pure real(dp) function mbdk_wear_law(law, fr, load, u, t) result(rate)
    integer, intent(in) :: law
    real(dp), intent(in) :: fr(:), load, u, t
    select case (law)
    case (MBDK_WEAR_GEAR)
      rate = fr(1) * load * mbdk_wear_psi(u, fr) * u
    case (MBDK_WEAR_KNEE)
      rate = fr(1) * load * u * (fr(2) + t * (fr(3) + t * (fr(4) + t * fr(5))))
    case default
      rate = fr(1) * load * u
    end select
  end function mbdk_wear_law

  !> rates(e) = dW/dt of every wear entry (eint, ereal) at (q, v, t); (fint, freal) the table
  !> their columns refer to, rot the bodies' (cos, sin) at q. MBDK_ERR_NONFINITE where a
  !> contact has no normal.
  subroutine mbdk_wear_rates(eint, ereal, fint, freal, rot, q, v, t, rates, stat)
    integer, intent(in) :: eint(:, :), fint(:, :)
    real(dp), intent(in) :: ereal(:, :), freal(:, :), rot(:, :), q(:), v(:), t
    real(dp), intent(out) :: rates(:)
    integer, intent(out) :: stat
    integer :: e
    logical :: ok
    stat = MBDK_SUCCESS
    do e = 1, size(eint, 2)
      call mbdk_wear_rate(eint(:, e), ereal(:, e), fint, freal, rot, q, v, t, rates(e), ok)
      if (.not. ok) then
        stat = MBDK_ERR_NONFINITE
        return
      end if
    end do
  end subroutine mbdk_wear_rates

end module mbdk_wear
