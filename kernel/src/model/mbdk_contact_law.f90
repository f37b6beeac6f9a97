!> The laws of a compliant contact, written once for every geometry that uses them: the planar
!> shapes (mbdk_contact) and the spatial spheres and planes (mbdk_contact3d). A geometry gives
!> the penetration delta >= 0, its rate delta' and the slip speed; these give the forces.
!>
!> Normal force (IMPACT, Fekete (2023) 6.1.2; law = (k, e, cmax, dmax)): for delta > 0
!>   F = max(0, k delta^e + step(delta; 0, 0, dmax, cmax) delta'),  F = 0 for delta <= 0,
!> step the cubic 3 x^2 - 2 x^3 on x = delta/dmax clipped to [0, 1] (dmax = 0: the full cmax at
!> once, a Kelvin-Voigt contact). The ramp keeps F continuous where the contact closes; the clip
!> keeps a contact from pulling (a damped contact otherwise ends with a tensile force). Its
!> potential is k delta^(e+1)/(e+1) (mbdk_contact_potential); the dissipated power
!> (F - k delta^e) delta' is >= 0 in both branches.
!>
!> Friction (regularised Coulomb; law = (mus, mud, vs, vd), 0 < vs < vd): the coefficient at
!> slip speed u, signed as u,
!>   |u| <= vs:       mu = mus step(|u|; 0, 0, vs, 1) sign(u)      (stiction, regularised)
!>   vs < |u| < vd:   mu = (mus + (mud - mus) step(|u|; vs, 0, vd, 1)) sign(u)
!>   |u| >= vd:       mu = mud sign(u)
!> (Adams' friction law with its stiction and friction transition speeds); the friction force
!> is -mu F along the slip, its dissipated power |mu| F |u| >= 0.
!>
!> Event functions, whose sign changes the error-controlled pairs end a step on
!> (mbdk_embedded_rk): mbdk_contact_event, continuous across the contact's closing and letting
!> go, changes sign at both; mbdk_contact_parting where the surfaces of a contact that let go
!> part (delta = 0 on the way out). Between the two a damped contact that let go holds no force
!> but a potential k delta^(e+1)/(e+1), dissipated at the rate -k delta^e delta' until delta = 0,
!> where that power has a kink a long step of the free flight would otherwise hold: the watch's
!> quadrature of the work then misses a part in a thousand of a bounce's loss.
module mbdk_contact_law
  use mbdk_kinds, only: dp
  implicit none
  private
  public :: mbdk_step3, mbdk_contact_normal, mbdk_contact_potential, mbdk_friction_mu, &
    mbdk_contact_event, mbdk_contact_parting

contains

  !> The cubic step: 0 at x <= x0, 1 at x >= x1, 3 s^2 - 2 s^3 between (s = (x - x0)/(x1 - x0));
  !> a jump at x0 when x1 <= x0.
  pure real(dp) function mbdk_step3(x, x0, x1) result(s)
    real(dp), intent(in) :: x, x0, x1
    if (x <= x0) then
      s = 0.0_dp
    else if (x >= x1) then
      s = 1.0_dp
    else
      s = (x - x0) / (x1 - x0)
      s = s * s * (3.0_dp - 2.0_dp * s)
    end if
  end function mbdk_step3

  !> The normal force of a penetrating contact (delta > 0) at the rate delta': its elastic part
  !> k delta^e, the force before the clip at zero (negative where the damping would pull) and
  !> the force itself. law = (k, e, cmax, dmax).
  pure subroutine mbdk_contact_normal(delta, rate, law, elastic, unclipped, force)
    real(dp), intent(in) :: delta, rate, law(4)
    real(dp), intent(out) :: elastic, unclipped, force
    elastic = law(1) * delta**law(2)
    unclipped = elastic + law(3) * mbdk_step3(delta, 0.0_dp, law(4)) * rate
    force = max(0.0_dp, unclipped)
  end subroutine mbdk_contact_normal

  !> The potential k delta^(e+1)/(e+1) of the normal force, from its elastic part k delta^e.
  pure real(dp) function mbdk_contact_potential(elastic, delta, e) result(v)
    real(dp), intent(in) :: elastic, delta, e
    v = elastic * delta / (e + 1.0_dp)
  end function mbdk_contact_potential

  !> The signed friction coefficient at slip speed u; fr(1:4) = (mus, mud, vs, vd).
  pure real(dp) function mbdk_friction_mu(u, fr) result(mu)
    real(dp), intent(in) :: u, fr(:)
    real(dp) :: a
    a = abs(u)
    if (a <= fr(3)) then
      mu = fr(1) * mbdk_step3(a, 0.0_dp, fr(3))
    else if (a < fr(4)) then
      mu = fr(1) + (fr(2) - fr(1)) * mbdk_step3(a, fr(3), fr(4))
    else
      mu = fr(2)
    end if
    mu = sign(mu, u)
  end function mbdk_friction_mu

  !> The event function of a contact at penetration delta (law = (k, e, cmax, dmax); unclipped:
  !> the normal force before its clip, where delta > 0): that force while it touches, extended
  !> by -k |delta|^e where it does not (delta itself for k = 0). Continuous, it changes sign
  !> where the contact closes and where it lets go: at delta = 0, or, damped, where the force
  !> would turn into a pull and the clip cuts it (a ball's exit, delta still > 0).
  pure real(dp) function mbdk_contact_event(delta, unclipped, law) result(g)
    real(dp), intent(in) :: delta, unclipped, law(4)
    if (delta > 0.0_dp) then
      g = unclipped
    else if (law(1) > 0.0_dp) then
      g = -law(1) * abs(delta)**law(2)
    else
      g = delta
    end if
  end function mbdk_contact_event

  !> The parting event at penetration delta and rate delta': delta while the surfaces separate
  !> (delta' <= 0), |delta| while they approach, so that its sign changes where they part
  !> (delta = 0, delta' < 0) and not where they meet (where mbdk_contact_event's does, and a
  !> second root there, at the normal force's jump, could end the step on the wrong side of it).
  !> Continuous but at the turning point of a flight apart (delta < 0, delta' = 0: a ball's
  !> apex), where its spurious sign change only ends a step.
  pure real(dp) function mbdk_contact_parting(delta, rate) result(g)
    real(dp), intent(in) :: delta, rate
    if (rate <= 0.0_dp) then
      g = delta
    else
      g = abs(delta)
    end if
  end function mbdk_contact_parting

end module mbdk_contact_law
