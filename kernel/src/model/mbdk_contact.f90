!> Compliant contact and regularised Coulomb friction between planar shapes (Fekete (2023) 6.1.2:
!> the commercial codes' IMPACT contact with Coulomb friction; the unilateral constraint of
!> (1.21)-(1.22) as a contact).
!>
!> Geometry (fint(4) of a contact; body2 = 0 is the ground, its points global):
!>   1 point/circle on line   the circle of radius r1 >= 0 (0: a point) centred at s1 on body1,
!>                            the line through s2 on body2 with the unit normal (cos a, sin a),
!>                            a = freal(6), in body2's frame, pointing to the side body1 belongs
!>                            to. Penetration delta = r1 - n . (P1 - P2).
!>   2 circle on circle       circles r1 (body1, centre s1) and r2 = freal(6) (body2, centre s2),
!>                            outside each other: delta = r1 + r2 - |P1 - P2|.
!>   3 circle in circle       circle r1 inside the hollow circle r2 > r1 of body2 (a particle held
!>                            in a ring, (1.22)): delta = |P1 - P2| + r1 - r2.
!>   4 involute gear pair     the spur gears of bodies 1 and 2 (both bodies; each gear centred at
!>                            its body's origin), below.
!> The normal n points from body2 into body1 (the direction the force pushes body1); the contact
!> point c is body1's deepest point, P1 - r1 n. The contact force F n acts on body1 at c and -F n
!> on body2 at the same point. Since F n passes through P1 (and, for the circles, through P2 as
!> well), its generalised force is exactly -grad of the potential below: the contact conserves
!> energy without damping, whatever its exponent.
!>
!> Normal force: the IMPACT law of mbdk_contact_law, F = max(0, k delta^e + step(delta; 0, 0,
!> dmax, cmax) delta') while delta > 0, with delta' the penetration rate; potential
!> k delta^(e+1)/(e+1), dissipated power (F - k delta^e) delta' >= 0.
!> freal: 1:2 s1, 3 r1, 4:5 s2, 6 a or r2, 7 k, 8 e (>= 1), 9 cmax, 10 dmax.
!>
!> Involute gear pair (geometry 4; freal: 1 rb1, 2 rb2 the base radii, 3 ra1, 4 ra2 the tip radii,
!> 5 pb the base pitch pi m cos(alpha0), 6 c0 the mesh phase, 7:10 as above, 11 psi1 gear 1's
!> flank phase, 12 the hand h = +1 or -1). With the centres C1, C2 at distance a > rb1 + rb2,
!> e = (C2 - C1)/a at the angle phi_e, the working pressure angle alpha' = acos((rb1 + rb2)/a),
!> the drive flanks meet on the line of action through the tangent points T1 = C1 + rb1 (cos
!> alpha' e - h sin alpha' perp(e)) and T2, direction d = sin alpha' e + h cos alpha' perp(e)
!> (h = +1: the flanks gear 1 pushes when it turns counter-clockwise). By the involute's rolling
!> property every pair in contact has the same penetration along d,
!>   delta = h (rb1 theta1 + rb2 theta2) - (rb1 + rb2)(h phi_e - alpha') - a sin alpha' + c0,
!> taken modulo pb into [-pb/2, pb/2) (the nearest pair of flanks), whose gradient is exactly
!> the force F d on gear 2 at the contact point and -F d on gear 1: the mesh conserves energy
!> between pair changes. Gear 1's flanks cross the line of action at the distances
!> L = rb1 (h theta1 - h phi_e + alpha') + psi1 + k pb from T1; a flank is in contact where L lies
!> on the path of contact [s_A, s_E], between a sin alpha' - sqrt(ra2^2 - rb2^2) (gear 2's tip)
!> and sqrt(ra1^2 - rb1^2) (gear 1's tip): one or two pairs for a contact ratio between 1 and 2.
!> A pair carries w(L) F, its weight w rising from 0 to 1 over the first MBDK_GEAR_RELIEF base
!> pitches of the path and falling back over the last ones (step3: the tip relief of real teeth,
!> which lets a pair take up its load gradually). Without it the stiffness would jump where a
!> pair enters or leaves, F and the mesh energy with it, and the balance drifts by about F
!> delta at every pair change. With it the potential is sum w(L_k, a) k delta^(e+1)/(e+1), and
!> its exact gradient adds per pair the force -(dw/dL dL/dq + dw/da da/dq) k delta^(e+1)/(e+1),
!> on gear 1's angle and on both centres: through phi_e and alpha' (L) and through the path's
!> start, which moves with the centre distance a as d s_A/d a = 1/sin alpha'. The undamped,
!> frictionless mesh conserves energy to the integrator's accuracy, its centres fixed or not.
!> Each pair's slip is its own (zero at the pitch point, changing sign there). A mesh whose base
!> circles overlap (a <= rb1 + rb2) has no line of action: MBDK_ERR_NONFINITE. One entry is one
!> side of the teeth: the scene reader enters a mesh as two, the drive flanks (h = +1) and the
!> coast flanks (h = -1) with their own phases, so that a load that reverses meets the other
!> flanks across the backlash (below half a base pitch, within which delta does not wrap). A side
!> that penetrates beyond a quarter of the base pitch (about a millimetre at module 1.35) has
!> left what the model covers, and the run stops there: MBDK_ERR_CONTACT_OVERRUN.
!>
!> Friction (an element of its own, fint(4) = the column of its contact in the same table):
!> the slip speed u = t . (v1(c) - v2(c)) along t = perp(n), the force -mu(u) F t on body1 at c
!> and the opposite on body2, mu the regularised Coulomb law of mbdk_contact_law (Adams' law with
!> its stiction and transition speeds). Its dissipated power is |mu| F |u| >= 0. freal: 1 mus,
!> 2 mud, 3 vs > 0, 4 vd > vs.
!>
!> A circle on circle whose centres coincide has no normal while it penetrates:
!> MBDK_ERR_NONFINITE, as for a spring of zero length.
module mbdk_contact
  use mbdk_kinds, only: dp, i8
  use mbdk_joints, only: mbdk_body_point
  use mbdk_elements, only: FRICTION => MBDK_FORCE_FRICTION, MBDK_FORCE_CONTACT
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_NONFINITE, MBDK_ERR_CONTACT_OVERRUN, &
    MBDK_ERR_NO_MEMORY
  use mbdk_contact_law, only: mbdk_step3, mbdk_contact_normal, mbdk_contact_potential, &
    mbdk_friction_mu
  implicit none
  private
  public :: mbdk_contact_states
  public :: mbdk_contact_t, mbdk_contact_eval, mbdk_contact_apply, mbdk_contact_forces, &
    mbdk_contact_forces_all

  integer, parameter, public :: MBDK_CONTACT_LINE = 1, MBDK_CONTACT_CIRCLES = 2, &
    MBDK_CONTACT_INSIDE = 3, MBDK_CONTACT_GEAR = 4
  !> pairs of flanks a gear mesh can have in contact at once (contact ratio below 3)
  integer, parameter, public :: MBDK_CONTACT_PAIRS = 3
  !> the length over which a gear pair takes up and sheds its load, in base pitches
  real(dp), parameter, public :: MBDK_GEAR_RELIEF = 0.1_dp

  !> One contact's state at (q, v): penetration and its rate, the normal force of a fully loaded
  !> pair and its elastic part, the normal, each pair's contact point, slip speed along perp(n),
  !> weight (pair k carries weight(k) * force) and the weight's derivative along the path, the
  !> path coordinate's gradient (gear 1's angle, both centres: gear meshes only), the number of
  !> touching pairs (one for the shapes 1-3) and whether any touches.
  type :: mbdk_contact_t
    real(dp) :: delta = 0.0_dp, rate = 0.0_dp, force = 0.0_dp, elastic = 0.0_dp
    !> the force before the clip at 0 (negative where the damping would pull)
    real(dp) :: unclipped = 0.0_dp
    real(dp) :: n(2) = 0.0_dp, c(2, MBDK_CONTACT_PAIRS) = 0.0_dp, slip(MBDK_CONTACT_PAIRS) = 0.0_dp
    real(dp) :: weight(MBDK_CONTACT_PAIRS) = 1.0_dp, dweight(MBDK_CONTACT_PAIRS) = 0.0_dp
    !> d weight / d a (the path's start moves with the centre distance a), and d a / d C2
    real(dp) :: dweight_a(MBDK_CONTACT_PAIRS) = 0.0_dp, da_c2(2) = 0.0_dp
    real(dp) :: dl_th1 = 0.0_dp, dl_c1(2) = 0.0_dp, dl_c2(2) = 0.0_dp
    integer :: npair = 0
    logical :: touching = .false.
    !> a gear side penetrated beyond a quarter base pitch (MBDK_ERR_CONTACT_OVERRUN)
    logical :: overrun = .false.
  end type mbdk_contact_t

contains

  !> The contact of table entry (fi, fr) at (q, v), rot the bodies' (cos, sin). ok = .false.
  !> where a penetrating contact has no normal (coincident centres).
  pure subroutine mbdk_contact_eval(fi, fr, rot, q, v, ct, ok)
    integer, intent(in) :: fi(:)
    real(dp), intent(in) :: fr(:), rot(:, :), q(:), v(:)
    type(mbdk_contact_t), intent(out) :: ct
    logical, intent(out) :: ok
    real(dp) :: p1(2), p2(2), rho(2), pv(2), w, d(2), dist, nb(2), u(2)
    integer :: b1, b2

    ok = .true.
    b1 = fi(2)
    b2 = fi(3)
    if (fi(4) == MBDK_CONTACT_GEAR) then
      call gear_mesh(ct, ok)
      return
    end if
    call mbdk_body_point(b1, fr(1:2), rot, q, v, p1, rho, pv, w)
    call mbdk_body_point(b2, fr(4:5), rot, q, v, p2, rho, pv, w)
    d = p1 - p2
    select case (fi(4))
    case (MBDK_CONTACT_LINE)
      nb = [cos(fr(6)), sin(fr(6))]
      if (b2 > 0) then
        ct%n = [rot(1, b2) * nb(1) - rot(2, b2) * nb(2), rot(2, b2) * nb(1) + rot(1, b2) * nb(2)]
      else
        ct%n = nb
      end if
      ct%delta = fr(3) - dot_product(ct%n, d)
    case (MBDK_CONTACT_CIRCLES)
      dist = norm2(d)
      ct%delta = fr(3) + fr(6) - dist
      if (ct%delta <= 0.0_dp) return
      if (.not. (dist > 0.0_dp)) then
        ok = .false.
        return
      end if
      ct%n = d / dist
    case default   ! MBDK_CONTACT_INSIDE
      dist = norm2(d)
      ct%delta = dist + fr(3) - fr(6)
      if (ct%delta <= 0.0_dp) return
      ct%n = -d / dist
    end select
    if (.not. (ct%delta > 0.0_dp)) return
    ct%touching = .true.
    ct%npair = 1
    ct%c(:, 1) = p1 - fr(3) * ct%n
    u = point_velocity(b1, ct%c(:, 1)) - point_velocity(b2, ct%c(:, 1))
    ct%rate = -dot_product(ct%n, u)
    ct%slip(1) = -ct%n(2) * u(1) + ct%n(1) * u(2)
    call normal_force(ct)

  contains

    pure subroutine normal_force(ct)
      type(mbdk_contact_t), intent(inout) :: ct
      call mbdk_contact_normal(ct%delta, ct%rate, fr(7:10), ct%elastic, ct%unclipped, ct%force)
    end subroutine normal_force

    !> The involute pair (the module header): delta, the touching pairs' points and slips.
    pure subroutine gear_mesh(ct, ok)
      type(mbdk_contact_t), intent(inout) :: ct
      logical, intent(out) :: ok
      real(dp) :: u(2), c1(2), c2(2), e(2), ep(2), a, rsum, ca, sa, alpha, phie, h, dd(2), t1(2)
      real(dp) :: raw, l, s_start, s_end, pb, ramp, up, down, dup, ddown, ds_start
      integer :: k
      ok = .false.
      c1 = q(3 * b1 - 2:3 * b1 - 1)
      c2 = q(3 * b2 - 2:3 * b2 - 1)
      e = c2 - c1
      a = norm2(e)
      rsum = fr(1) + fr(2)
      if (.not. (a > rsum)) return
      ok = .true.
      e = e / a
      ep = [-e(2), e(1)]
      h = fr(12)
      pb = fr(5)
      ca = rsum / a
      sa = sqrt((1.0_dp - ca) * (1.0_dp + ca))
      alpha = atan2(sa, ca)
      phie = atan2(e(2), e(1))
      raw = h * (fr(1) * q(3 * b1) + fr(2) * q(3 * b2)) - rsum * (h * phie - alpha) - a * sa + fr(6)
      ct%delta = raw - pb * anint(raw / pb)
      ! a penetration beyond a quarter pitch is no tooth's any more: the flanks overran (or the
      ! other side's did, and this side's delta wrapped around)
      ct%overrun = ct%delta > 0.25_dp * pb
      if (.not. (ct%delta > 0.0_dp)) return
      dd = sa * e + h * ca * ep
      ct%n = -dd
      t1 = c1 + fr(1) * (ca * e - h * sa * ep)
      s_start = a * sa - sqrt(max(0.0_dp, fr(4)**2 - fr(2)**2))
      ! d s_start / d a = sin alpha' + a cos alpha' d alpha'/d a = 1 / sin alpha'
      ds_start = 1.0_dp / sa
      if (s_start < 0.0_dp) then
        s_start = 0.0_dp
        ds_start = 0.0_dp
      end if
      s_end = sqrt(max(0.0_dp, fr(3)**2 - fr(1)**2))
      l = fr(1) * (h * q(3 * b1) - h * phie + alpha) + fr(11)
      l = l - pb * floor((l - s_start) / pb)
      ramp = MBDK_GEAR_RELIEF * pb
      ! dL/dq: h rb1 on theta1; through phi_e (d phi_e/d C2 = perp(e)/a) and alpha'
      ! (d alpha'/d a = (rb1 + rb2)/(a^2 sin alpha'), d a/d C2 = e) on the centres
      ct%dl_th1 = h * fr(1)
      ct%da_c2 = e
      ct%dl_c2 = fr(1) * (-h * ep / a + e * rsum / (a * a * sa))
      ct%dl_c1 = -ct%dl_c2
      do k = 1, MBDK_CONTACT_PAIRS
        if (l > s_end) exit
        ct%npair = k
        up = mbdk_step3(l, s_start, s_start + ramp)
        down = mbdk_step3(l, s_end - ramp, s_end)
        dup = dstep3(l, s_start, s_start + ramp)
        ddown = dstep3(l, s_end - ramp, s_end)
        ct%weight(k) = up * (1.0_dp - down)
        ct%dweight(k) = dup * (1.0_dp - down) - up * ddown
        ct%dweight_a(k) = -dup * (1.0_dp - down) * ds_start
        ct%c(:, k) = t1 + l * dd
        u = point_velocity(b1, ct%c(:, k)) - point_velocity(b2, ct%c(:, k))
        ct%slip(k) = -ct%n(2) * u(1) + ct%n(1) * u(2)
        if (k == 1) ct%rate = -dot_product(ct%n, u)
        l = l + pb
      end do
      if (ct%npair == 0) return
      ct%touching = .true.
      call normal_force(ct)
    end subroutine gear_mesh

    !> Velocity of body b's material point at the global point x (0 on the ground).
    pure function point_velocity(b, x) result(vx)
      integer, intent(in) :: b
      real(dp), intent(in) :: x(2)
      real(dp) :: vx(2)
      if (b == 0) then
        vx = 0.0_dp
      else
        vx = [v(3 * b - 2) - v(3 * b) * (x(2) - q(3 * b - 1)), &
              v(3 * b - 1) + v(3 * b) * (x(1) - q(3 * b - 2))]
      end if
    end function point_velocity

  end subroutine mbdk_contact_eval

  !> d/dx of mbdk_step3 (0 outside (x0, x1)).
  pure real(dp) function dstep3(x, x0, x1) result(ds)
    real(dp), intent(in) :: x, x0, x1
    real(dp) :: s
    ds = 0.0_dp
    if (x <= x0 .or. x >= x1) return
    s = (x - x0) / (x1 - x0)
    ds = 6.0_dp * s * (1.0_dp - s) / (x1 - x0)
  end function dstep3

  !> f += the generalised force of the force fv acting at the global point c on body b1 and of
  !> -fv on body b2 (bodies 0, the ground, take nothing).
  pure subroutine mbdk_contact_apply(b1, b2, c, fv, q, f)
    integer, intent(in) :: b1, b2
    real(dp), intent(in) :: c(2), fv(2), q(:)
    real(dp), intent(inout) :: f(:)
    if (b1 > 0) then
      f(3 * b1 - 2) = f(3 * b1 - 2) + fv(1)
      f(3 * b1 - 1) = f(3 * b1 - 1) + fv(2)
      f(3 * b1) = f(3 * b1) + (c(1) - q(3 * b1 - 2)) * fv(2) - (c(2) - q(3 * b1 - 1)) * fv(1)
    end if
    if (b2 > 0) then
      f(3 * b2 - 2) = f(3 * b2 - 2) - fv(1)
      f(3 * b2 - 1) = f(3 * b2 - 1) - fv(2)
      f(3 * b2) = f(3 * b2) - ((c(1) - q(3 * b2 - 2)) * fv(2) - (c(2) - q(3 * b2 - 1)) * fv(1))
    end if
  end subroutine mbdk_contact_apply

  !> f += the generalised forces of the contact or friction element in column e of the table
  !> (fint, freal).
  subroutine mbdk_contact_forces(fint, freal, e, rot, q, v, f, stat)
    integer, intent(in), contiguous :: fint(:, :)
    real(dp), intent(in), contiguous :: freal(:, :), rot(:, :), q(:), v(:)
    integer, intent(in) :: e
    real(dp), intent(inout), contiguous :: f(:)
    integer, intent(out) :: stat
    type(mbdk_contact_t) :: ct
    logical :: ok
    integer :: b, k, c
    real(dp) :: ften, pot

    stat = MBDK_SUCCESS
    c = e
    if (fint(1, e) == FRICTION) c = fint(4, e)
    call mbdk_contact_eval(fint(:, c), freal(:, c), rot, q, v, ct, ok)
    if (.not. ok) then
      stat = MBDK_ERR_NONFINITE
      return
    end if
    if (ct%overrun) then
      stat = MBDK_ERR_CONTACT_OVERRUN
      return
    end if
    do k = 1, ct%npair
      if (fint(1, e) == FRICTION) then
        ften = -mbdk_friction_mu(ct%slip(k), freal(:, e)) * ct%weight(k) * ct%force
        call mbdk_contact_apply(fint(2, c), fint(3, c), ct%c(:, k), ften * [-ct%n(2), ct%n(1)], &
                                q, f)
        cycle
      end if
      call mbdk_contact_apply(fint(2, e), fint(3, e), ct%c(:, k), &
                              ct%weight(k) * ct%force * ct%n, q, f)
      ! a gear pair's weight changes along the path and with the centre distance: its
      ! potential's gradient there
      if (ct%dweight(k) /= 0.0_dp .or. ct%dweight_a(k) /= 0.0_dp) then
        pot = mbdk_contact_potential(ct%elastic, ct%delta, freal(8, e))
        ften = -ct%dweight(k) * pot
        b = fint(2, e)
        f(3 * b - 2:3 * b - 1) = f(3 * b - 2:3 * b - 1) + ften * ct%dl_c1 &
                                 + ct%dweight_a(k) * pot * ct%da_c2
        f(3 * b) = f(3 * b) + ften * ct%dl_th1
        b = fint(3, e)
        f(3 * b - 2:3 * b - 1) = f(3 * b - 2:3 * b - 1) + ften * ct%dl_c2 &
                                 - ct%dweight_a(k) * pot * ct%da_c2
      end if
    end do
  end subroutine mbdk_contact_forces

  !> f += the generalised forces of every entry of a table of contacts and friction (their
  !> columns refer to this table); visits(code) counts them.
  subroutine mbdk_contact_forces_all(fint, freal, rot, q, v, f, visits, stat)
    integer, intent(in), contiguous :: fint(:, :)
    real(dp), intent(in), contiguous :: freal(:, :), rot(:, :), q(:), v(:)
    real(dp), intent(inout), contiguous :: f(:)
    integer(i8), intent(inout), contiguous :: visits(:)
    integer, intent(out) :: stat
    integer :: e
    stat = MBDK_SUCCESS
    do e = 1, size(fint, 2)
      visits(fint(1, e)) = visits(fint(1, e)) + 1
      call mbdk_contact_forces(fint, freal, e, rot, q, v, f, stat)
      if (stat /= MBDK_SUCCESS) return
    end do
  end subroutine mbdk_contact_forces_all

  !> What each contact of a force table carries at one state, for the outputs:
  !> out(:, k) of the table's k-th contact entry (in table order) = (penetration delta, its rate,
  !> the normal force, the friction force of the friction elements on it), the forces summed
  !> over a gear mesh's pairs in contact, each |mu(slip)| w F. Entries of other kinds are
  !> skipped. stat: MBDK_ERR_NONFINITE where a penetrating contact has no normal.
  subroutine mbdk_contact_states(fint, freal, q, v, out, stat)
    integer, intent(in) :: fint(:, :)
    real(dp), intent(in) :: freal(:, :), q(:), v(:)
    real(dp), intent(out) :: out(:, :)
    integer, intent(out) :: stat
    real(dp), allocatable :: rot(:, :)
    integer, allocatable :: slot(:)
    type(mbdk_contact_t) :: ct
    logical :: ok
    integer :: e, b, k, c, n
    out = 0.0_dp
    stat = MBDK_ERR_NO_MEMORY
    allocate (rot(2, size(q) / 3), slot(size(fint, 2)), stat=k)
    if (k /= 0) return
    do b = 1, size(rot, 2)
      rot(:, b) = [cos(q(3 * b)), sin(q(3 * b))]
    end do
    stat = MBDK_SUCCESS
    n = 0
    slot = 0
    do e = 1, size(fint, 2)
      if (fint(1, e) /= MBDK_FORCE_CONTACT) cycle
      n = n + 1
      slot(e) = n
      call mbdk_contact_eval(fint(:, e), freal(:, e), rot, q, v, ct, ok)
      if (.not. ok) then
        stat = MBDK_ERR_NONFINITE
        return
      end if
      out(1:2, n) = [ct%delta, ct%rate]
      out(3, n) = ct%force * sum(ct%weight(1:ct%npair))
    end do
    do e = 1, size(fint, 2)
      if (fint(1, e) /= FRICTION) cycle
      c = fint(4, e)
      if (c < 1 .or. c > size(fint, 2)) cycle
      if (slot(c) == 0) cycle
      call mbdk_contact_eval(fint(:, c), freal(:, c), rot, q, v, ct, ok)
      if (.not. ok) cycle
      do k = 1, ct%npair
        out(4, slot(c)) = out(4, slot(c)) + &
          abs(mbdk_friction_mu(ct%slip(k), freal(:, e))) * ct%weight(k) * ct%force
      end do
    end do
  end subroutine mbdk_contact_states

end module mbdk_contact
