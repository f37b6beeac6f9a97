!> Compliant contact with regularised Coulomb friction between spatial bodies: the geometry of a
!> sphere on a plane and of two spheres, the laws of mbdk_contact_law (IMPACT normal force,
!> Adams' friction), as the planar contacts of mbdk_contact have them in 2D.
!>
!> Geometry (a table entry's reals, MBDK_CONTACT3D_REALS; body2 may be the ground, whose points
!> and normal are global):
!>   MBDK_CONTACT3D_PLANE    the sphere of radius r1 >= 0 (0: a point) centred at s1 on body1,
!>                           the plane through s2 on body2 with the unit normal n2 (body2's
!>                           frame), pointing to the side body1 is on: delta = r1 - n . (P1 - P2)
!>   MBDK_CONTACT3D_SPHERES  the spheres r1 (body1, centre s1) and r2 (body2, centre s2), outside
!>                           each other: delta = r1 + r2 - |P1 - P2|, n = (P1 - P2)/|P1 - P2|
!> with P = r + R s the points in space and n = R2 n2 the normal, from body2 into body1. The
!> contact point c = P1 - r1 n is body1's deepest point; the contact force acts there on body1
!> and, opposite, on body2. The relative velocity of the bodies' material points at c is
!>   u = (v1 + w1 x (c - r1)) - (v2 + w2 x (c - r2)),   w = R Omega (space frame),
!> its normal part -n . u = delta' (exactly: for the plane the terms of n' = w2 x n cancel
!> against those of the points' offset along n, for the spheres c - P1 and c - P2 lie along n)
!> and its tangential part the slip s = u - (n . u) n, of speed |s| (n, c and delta' are
!> evaluated apart as well, for the events).
!>
!> Forces: the normal force F n (mbdk_contact_normal on delta and delta'), and the friction
!> -mu(|s|) F s/|s| (mbdk_friction_mu, >= 0 at a speed |s| >= 0; zero without slip, where the
!> regularised coefficient vanishes). Their sum f acts on body1 at c and -f on body2 there: per
!> body the force f (space frame) and the moment about its centre R^T ((c - r) x f) in its own
!> frame, the spatial model's loads. Since F n passes through P1 (and through P2 for two
!> spheres), and its power is -F delta' for every motion, the normal force without damping is
!> -grad of the potential k delta^(e+1)/(e+1): the contact conserves energy, whatever its
!> exponent. The power the contact dissipates is (F - k delta^e) delta' + mu F |s| >= 0.
!> Equal and opposite at one point, a contact between two bodies conserves their momenta.
!>
!> Reals: 1:3 s1, 4 r1, 5:7 s2, 8:10 n2 (plane; the model normalises it), 11 r2 (spheres),
!> 12:15 the normal law (k, e >= 1, cmax, dmax), 16:19 the friction law (mus, mud, vs, vd;
!> mus = mud = 0: none).
!> Two penetrating spheres whose centres coincide have no normal: ok = .false. (the model
!> returns MBDK_ERR_NONFINITE), as a planar circle pair has.
module mbdk_contact3d
  use mbdk_kinds, only: dp
  use mbdk_rotations, only: mbdk_cross
  use mbdk_contact_law, only: mbdk_contact_normal, mbdk_contact_potential, mbdk_friction_mu, &
    mbdk_contact_event, mbdk_contact_parting
  implicit none
  private
  public :: mbdk_contact3d_eval, mbdk_contact3d_loads, mbdk_contact3d_events, &
    mbdk_contact3d_rough

  integer, parameter, public :: MBDK_CONTACT3D_PLANE = 1, MBDK_CONTACT3D_SPHERES = 2
  integer, parameter, public :: MBDK_CONTACT3D_REALS = 19

  !> One contact at a state: penetration and its rate, the normal (space frame), the contact
  !> point, the slip (the tangential relative velocity) and its speed, the normal force's elastic
  !> part, the force before its clip and the force, the friction coefficient, the total force f
  !> on body1 at c, the normal force's potential and the power dissipated.
  type, public :: mbdk_contact3d_t
    real(dp) :: delta = 0.0_dp, rate = 0.0_dp, n(3) = 0.0_dp, c(3) = 0.0_dp
    real(dp) :: slip(3) = 0.0_dp, speed = 0.0_dp
    real(dp) :: elastic = 0.0_dp, unclipped = 0.0_dp, force = 0.0_dp, mu = 0.0_dp
    real(dp) :: f(3) = 0.0_dp, potential = 0.0_dp, dissipation = 0.0_dp
    logical :: touching = .false.
  end type mbdk_contact3d_t

contains

  !> Whether the entry's friction law has a coefficient (mus or mud > 0).
  pure logical function mbdk_contact3d_rough(fr)
    real(dp), intent(in) :: fr(:)
    mbdk_contact3d_rough = fr(16) > 0.0_dp .or. fr(17) > 0.0_dp
  end function mbdk_contact3d_rough

  !> The contact of geometry kind and reals fr between body1 at (r1, rot1, v1, om1) and body2 at
  !> (r2, rot2, v2, om2) (r the centre, rot body to space, v the centre's velocity, om the
  !> angular velocity in the body frame; the ground: zeros and the identity). ok = .false.
  !> where two penetrating spheres have no normal (coincident centres).
  pure subroutine mbdk_contact3d_eval(kind, fr, r1, rot1, v1, om1, r2, rot2, v2, om2, ct, ok)
    integer, intent(in) :: kind
    real(dp), intent(in) :: fr(:), r1(3), rot1(3, 3), v1(3), om1(3), r2(3), rot2(3, 3), &
      v2(3), om2(3)
    type(mbdk_contact3d_t), intent(out) :: ct
    logical, intent(out) :: ok
    real(dp) :: p1(3), p2(3), d(3), dist, u(3), un
    ok = .true.
    p1 = r1 + matmul(rot1, fr(1:3))
    p2 = r2 + matmul(rot2, fr(5:7))
    d = p1 - p2
    if (kind == MBDK_CONTACT3D_PLANE) then
      ct%n = matmul(rot2, fr(8:10))
      ct%delta = fr(4) - dot_product(ct%n, d)
    else
      dist = norm2(d)
      ct%delta = fr(4) + fr(11) - dist
      if (.not. (dist > 0.0_dp)) then
        ! r1 + r2 > 0 (the model's check): coincident centres penetrate
        ok = .false.
        return
      end if
      ct%n = d / dist
    end if
    ! the kinematics also apart (the parting event reads the rate there)
    ct%c = p1 - fr(4) * ct%n
    u = v1 + mbdk_cross(matmul(rot1, om1), ct%c - r1) - &
        (v2 + mbdk_cross(matmul(rot2, om2), ct%c - r2))
    un = dot_product(ct%n, u)
    ct%rate = -un
    if (.not. (ct%delta > 0.0_dp)) return
    ct%touching = .true.
    ct%slip = u - un * ct%n
    ct%speed = norm2(ct%slip)
    call mbdk_contact_normal(ct%delta, ct%rate, fr(12:15), ct%elastic, ct%unclipped, ct%force)
    ct%potential = mbdk_contact_potential(ct%elastic, ct%delta, fr(13))
    ct%dissipation = (ct%force - ct%elastic) * ct%rate
    ct%f = ct%force * ct%n
    if (mbdk_contact3d_rough(fr) .and. ct%speed > 0.0_dp) then
      ct%mu = mbdk_friction_mu(ct%speed, fr(16:19))
      ct%f = ct%f - (ct%mu * ct%force / ct%speed) * ct%slip
      ct%dissipation = ct%dissipation + ct%mu * ct%force * ct%speed
    end if
  end subroutine mbdk_contact3d_eval

  !> The loads of a touching contact: the force f1 (space frame) on body1 and the moment m1 about
  !> its centre in its own frame, f2 and m2 on body2 (whose r2, rot2 the ground's: zeros and the
  !> identity).
  pure subroutine mbdk_contact3d_loads(ct, r1, rot1, r2, rot2, f1, m1, f2, m2)
    type(mbdk_contact3d_t), intent(in) :: ct
    real(dp), intent(in) :: r1(3), rot1(3, 3), r2(3), rot2(3, 3)
    real(dp), intent(out) :: f1(3), m1(3), f2(3), m2(3)
    real(dp) :: x(3)
    f1 = ct%f
    x = mbdk_cross(ct%c - r1, ct%f)
    m1 = matmul(x, rot1)          ! R^T x as x^T R, of a variable: gfortran inlines it (meson.build)
    f2 = -ct%f
    x = mbdk_cross(ct%c - r2, ct%f)
    m2 = -matmul(x, rot2)
  end subroutine mbdk_contact3d_loads

  !> The contact's two event functions: the law's (mbdk_contact_event: the normal force before
  !> its clip while it touches, continued where it does not; changes sign where the contact
  !> closes and where it lets go) and the parting one (mbdk_contact_parting: where the surfaces
  !> part, delta = 0 on the way out). ok = .false. (no normal): the penetration, twice.
  pure function mbdk_contact3d_events(ct, ok, fr) result(g)
    type(mbdk_contact3d_t), intent(in) :: ct
    logical, intent(in) :: ok
    real(dp), intent(in) :: fr(:)
    real(dp) :: g(2)
    if (.not. ok) then
      g = ct%delta
    else
      g = [mbdk_contact_event(ct%delta, ct%unclipped, fr(12:15)), &
           mbdk_contact_parting(ct%delta, ct%rate)]
    end if
  end function mbdk_contact3d_events

end module mbdk_contact3d
