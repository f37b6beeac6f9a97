!> Force elements of planar scenes, as generalised forces f(q, v, t) by virtual power
!> (Fekete (2023) section 2.3: the spring bar (2.95)-(2.99) and the spring-and-damper bar
!> (2.120)-(2.126)), with their potential energy and power.
!>
!> Table fint(4, nf) = (type, body1, body2, coordinate or flag); freal(12, nf), time function in
!> 8:12. The 4th integer is the coordinate of a coordinate spring-damper; for the two-point kinds
!> MBDK_FROM_POSE (1) takes the rest length L0 from the initial pose (mbdk_assembly):
!>   1 gravity              g = freal(1:2) on every body (only when the scene declares it)
!>   2 point force          F(t) = freal(3:4) * f(t) at the body-fixed point freal(1:2) of body1
!>   3 torque               T(t) = freal(1) * f(t) on body1
!>   4 spring-damper        between s1 = freal(1:2) on body1 and s2 = freal(3:4) on body2 (0:
!>                          ground, global point); tension F = k (L - L0) + c dL/dt with
!>                          k = freal(5), L0 = freal(6), c = freal(7); pulls the points together
!>                          when positive.
!>   6 spring, 7 damper     the same element with c = 0, or k = 0: kinds of their own, so that a
!>                          scene's visit counters say which it has (mbdk_elements)
!>   5 coordinate spring-damper on q(3 body1 - 3 + coordinate): -k (q - q0) - c q',
!>                          k = freal(1), c = freal(2), q0 = freal(3) (the trolley's -s x1 - k x1')
!>   8 contact              compliant contact between two bodies' shapes (mbdk_contact: layout
!>                          and law); fint(4) = its geometry
!>   9 friction             Coulomb friction of a contact (mbdk_contact); fint(4) = the column
!>                          of that contact in the same table
!> mbdk_forces_eval skips contacts and friction: the model evaluates them from a table of their
!> own (mbdk_contact_forces_all), so that the force loop of a scene without them holds no
!> contact code and sets up no contact state; their energy and power are here. Wear elements (mbdk_wear) share
!> the table; the model takes them out of it (they carry states and are no forces).
!> A spring-damper whose two points coincide has no direction: MBDK_ERR_NONFINITE, and so has a
!> penetrating contact of two circles with coincident centres.
!> Every routine takes the rotations rot(2, nb) of the bodies at q (mbdk_joints).
module mbdk_force_elements
  use mbdk_elements, only: MBDK_FORCE_GRAVITY, MBDK_FORCE_POINT, MBDK_FORCE_TORQUE, &
    MBDK_FORCE_SPRING_DAMPER, MBDK_FORCE_COORDINATE, MBDK_FORCE_SPRING, MBDK_FORCE_DAMPER, &
    MBDK_FORCE_CONTACT, MBDK_FORCE_FRICTION, MBDK_FORCE_TYPES
  use mbdk_contact, only: mbdk_contact_t, mbdk_contact_eval
  use mbdk_contact_law, only: mbdk_friction_mu
  use mbdk_kinds, only: dp, i8
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_NONFINITE
  use mbdk_time_function, only: mbdk_time_fn
  use mbdk_joints, only: mbdk_body_point
  implicit none
  private
  public :: mbdk_forces_eval, mbdk_forces_energy, mbdk_forces_tangent

  ! the force types are the element registry's (mbdk_elements)
  public :: MBDK_FORCE_GRAVITY, MBDK_FORCE_POINT, MBDK_FORCE_TORQUE, MBDK_FORCE_SPRING_DAMPER, &
    MBDK_FORCE_COORDINATE, MBDK_FORCE_SPRING, MBDK_FORCE_DAMPER, MBDK_FORCE_CONTACT, &
    MBDK_FORCE_FRICTION, MBDK_FORCE_TYPES

contains

  !> f(nc) += the generalised forces of every element; visits(1:5) counts them per type.
  subroutine mbdk_forces_eval(fint, freal, mass, rot, q, v, t, f, visits, stat)
    integer, intent(in), contiguous :: fint(:, :)
    real(dp), intent(in), contiguous :: freal(:, :), mass(:), rot(:, :), q(:), v(:)
    real(dp), intent(in) :: t
    real(dp), intent(inout), contiguous :: f(:)
    integer(i8), intent(inout), contiguous :: visits(:)
    integer, intent(out) :: stat
    integer :: e, b, nb, k
    real(dp) :: p1(2), rho1(2), rho2(2), pv1(2), w1, w2, el(2), gv(2)
    real(dp) :: len, ldot, ften, tf, tfd, tfdd, fv(2)

    stat = MBDK_SUCCESS
    nb = size(mass) / 3
    do e = 1, size(fint, 2)
      ! contacts and friction: mbdk_contact_forces_all, over the model's table of them
      if (fint(1, e) >= MBDK_FORCE_CONTACT) cycle
      visits(fint(1, e)) = visits(fint(1, e)) + 1
      select case (fint(1, e))
      case (MBDK_FORCE_GRAVITY)
        do b = 1, nb
          f(3 * b - 2) = f(3 * b - 2) + mass(3 * b - 2) * freal(1, e)
          f(3 * b - 1) = f(3 * b - 1) + mass(3 * b - 1) * freal(2, e)
        end do
      case (MBDK_FORCE_POINT)
        b = fint(2, e)
        call mbdk_time_fn(freal(8:12, e), t, tf, tfd, tfdd)
        call mbdk_body_point(b, freal(1:2, e), rot, q, v, p1, rho1, pv1, w1)
        fv = freal(3:4, e) * tf
        f(3 * b - 2:3 * b - 1) = f(3 * b - 2:3 * b - 1) + fv
        f(3 * b) = f(3 * b) + rho1(1) * fv(2) - rho1(2) * fv(1)
      case (MBDK_FORCE_TORQUE)
        b = fint(2, e)
        call mbdk_time_fn(freal(8:12, e), t, tf, tfd, tfdd)
        f(3 * b) = f(3 * b) + freal(1, e) * tf
      case (MBDK_FORCE_SPRING_DAMPER, MBDK_FORCE_SPRING, MBDK_FORCE_DAMPER)
        call spring_state(fint(:, e), freal(:, e), rot, q, v, rho1, rho2, w1, w2, gv, len, el, &
                          ldot)
        if (.not. (len > 0.0_dp)) then
          stat = MBDK_ERR_NONFINITE
          return
        end if
        ften = freal(5, e) * (len - freal(6, e)) + freal(7, e) * ldot
        fv = -ften * el                       ! on point 1; the opposite on point 2
        b = fint(2, e)
        if (b > 0) then
          f(3 * b - 2:3 * b - 1) = f(3 * b - 2:3 * b - 1) + fv
          f(3 * b) = f(3 * b) + rho1(1) * fv(2) - rho1(2) * fv(1)
        end if
        b = fint(3, e)
        if (b > 0) then
          f(3 * b - 2:3 * b - 1) = f(3 * b - 2:3 * b - 1) - fv
          f(3 * b) = f(3 * b) - (rho2(1) * fv(2) - rho2(2) * fv(1))
        end if
      case (MBDK_FORCE_COORDINATE)
        k = 3 * fint(2, e) - 3 + fint(4, e)
        f(k) = f(k) - freal(1, e) * (q(k) - freal(3, e)) - freal(2, e) * v(k)
      end select
    end do
  end subroutine mbdk_forces_eval


  !> Potential energy of gravity and of the springs, the power dissipated by the dampers (>= 0)
  !> and the power of the applied loads (point forces and torques).
  subroutine mbdk_forces_energy(fint, freal, mass, rot, q, v, t, v_gravity, v_springs, p_damp, &
                                p_load)
    integer, intent(in) :: fint(:, :)
    real(dp), intent(in) :: freal(:, :), mass(:), rot(:, :), q(:), v(:), t
    real(dp), intent(out) :: v_gravity, v_springs, p_damp, p_load
    integer :: e, b, nb, k
    real(dp) :: p1(2), rho1(2), rho2(2), pv1(2), w1, w2, el(2), gv(2), len, ldot
    real(dp) :: tf, tfd, tfdd
    type(mbdk_contact_t) :: ct
    logical :: ok

    v_gravity = 0.0_dp
    v_springs = 0.0_dp
    p_damp = 0.0_dp
    p_load = 0.0_dp
    nb = size(mass) / 3
    do e = 1, size(fint, 2)
      select case (fint(1, e))
      case (MBDK_FORCE_GRAVITY)
        do b = 1, nb
          v_gravity = v_gravity - mass(3 * b - 2) * dot_product(freal(1:2, e), q(3 * b - 2:3 * b - 1))
        end do
      case (MBDK_FORCE_POINT)
        b = fint(2, e)
        call mbdk_time_fn(freal(8:12, e), t, tf, tfd, tfdd)
        call mbdk_body_point(b, freal(1:2, e), rot, q, v, p1, rho1, pv1, w1)
        p_load = p_load + dot_product(freal(3:4, e) * tf, pv1)
      case (MBDK_FORCE_TORQUE)
        call mbdk_time_fn(freal(8:12, e), t, tf, tfd, tfdd)
        p_load = p_load + freal(1, e) * tf * v(3 * fint(2, e))
      case (MBDK_FORCE_SPRING_DAMPER, MBDK_FORCE_SPRING, MBDK_FORCE_DAMPER)
        call spring_state(fint(:, e), freal(:, e), rot, q, v, rho1, rho2, w1, w2, gv, len, el, &
                          ldot)
        v_springs = v_springs + 0.5_dp * freal(5, e) * (len - freal(6, e))**2
        p_damp = p_damp + freal(7, e) * ldot**2
      case (MBDK_FORCE_COORDINATE)
        k = 3 * fint(2, e) - 3 + fint(4, e)
        v_springs = v_springs + 0.5_dp * freal(1, e) * (q(k) - freal(3, e))**2
        p_damp = p_damp + freal(2, e) * v(k)**2
      case (MBDK_FORCE_CONTACT)
        call mbdk_contact_eval(fint(:, e), freal(:, e), rot, q, v, ct, ok)
        if (ok .and. ct%touching) then
          do b = 1, ct%npair
            v_springs = v_springs + ct%weight(b) * ct%elastic * ct%delta / (freal(8, e) + 1.0_dp)
            p_damp = p_damp + ct%weight(b) * (ct%force - ct%elastic) * ct%rate
          end do
        end if
      case (MBDK_FORCE_FRICTION)
        k = fint(4, e)
        call mbdk_contact_eval(fint(:, k), freal(:, k), rot, q, v, ct, ok)
        if (ok) then
          do b = 1, ct%npair
            p_damp = p_damp + mbdk_friction_mu(ct%slip(b), freal(:, e)) * ct%weight(b) * &
                              ct%force * ct%slip(b)
          end do
        end if
      end select
    end do
  end subroutine mbdk_forces_energy

  !> a += ks K + cs C with the tangent stiffness K = -df/dq and damping C = -df/dv of every
  !> element (a(nc, nc) or larger: only rows and columns 1..nc are touched), for the Newton
  !> matrix of the index-3 integrators. Gravity and torques are constant in q and v.
  !> Point force at rho: (th, th) += rho . F. Spring-damper with G = dd/dq (2 x nc: I, perp(rho1)
  !> at body 1; -I, -perp(rho2) at body 2), e = d/L, tension T = k (L - L0) + c L', f = -T G^T e:
  !>   C = c (G^T e)(G^T e)^T
  !>   K = (G^T e)(k G^T e + c dL'/dq)^T + T [G^T (I - e e^T) G / L + (e.-rho1 at th1,th1;
  !>        e.rho2 at th2,th2)],  dL'/dq = G^T (I - e e^T) G v / L + H^T e,
  !>   H = d(G v)/dq: -w1 rho1 in column th1, +w2 rho2 in column th2.
  !> Coordinate spring-damper: K(k, k) = k, C(k, k) = c.
  !> G lives on the six coordinates of the element's two bodies (O(36) per element, no
  !> allocation), scattered into a. K is symmetric without dampers (c = 0); C always is.
  subroutine mbdk_forces_tangent(fint, freal, rot, q, v, t, ks, cs, a, visits, stat)
    integer, intent(in), contiguous :: fint(:, :)
    real(dp), intent(in), contiguous :: freal(:, :), rot(:, :), q(:), v(:)
    real(dp), intent(in) :: t, ks, cs
    real(dp), intent(inout), contiguous :: a(:, :)
    integer(i8), intent(inout), contiguous :: visits(:)
    integer, intent(out) :: stat
    integer :: e, b, k, i, j, col(6)
    real(dp) :: p1(2), rho1(2), rho2(2), pv1(2), w1, w2, el(2)
    real(dp) :: len, ldot, ten, tf, tfd, tfdd, pe(2, 2), gv(2)
    ! G on the six coordinates of the two bodies (x, y, theta of body1, then of body2)
    real(dp) :: g(2, 6), ge(6), pg(2, 6), dldq(6)

    stat = MBDK_SUCCESS
    do e = 1, size(fint, 2)
      ! gravity and torques have no tangent: only the elements with one are visited
      if (fint(1, e) == MBDK_FORCE_GRAVITY .or. fint(1, e) == MBDK_FORCE_TORQUE) cycle
      ! contacts, friction and effects have none here: trapezoidal_index3 refuses their scenes
      if (fint(1, e) >= MBDK_FORCE_CONTACT) cycle
      visits(fint(1, e)) = visits(fint(1, e)) + 1
      select case (fint(1, e))
      case (MBDK_FORCE_POINT)
        b = fint(2, e)
        call mbdk_time_fn(freal(8:12, e), t, tf, tfd, tfdd)
        call mbdk_body_point(b, freal(1:2, e), rot, q, v, p1, rho1, pv1, w1)
        a(3 * b, 3 * b) = a(3 * b, 3 * b) + ks * dot_product(rho1, freal(3:4, e) * tf)
      case (MBDK_FORCE_SPRING_DAMPER, MBDK_FORCE_SPRING, MBDK_FORCE_DAMPER)
        call spring_state(fint(:, e), freal(:, e), rot, q, v, rho1, rho2, w1, w2, gv, len, el, &
                          ldot)
        if (.not. (len > 0.0_dp)) then
          stat = MBDK_ERR_NONFINITE
          return
        end if
        col = 0
        if (fint(2, e) > 0) col(1:3) = [(3 * fint(2, e) - 3 + k, k = 1, 3)]
        if (fint(3, e) > 0) col(4:6) = [(3 * fint(3, e) - 3 + k, k = 1, 3)]
        g(:, 1) = [1.0_dp, 0.0_dp]
        g(:, 2) = [0.0_dp, 1.0_dp]
        g(:, 3) = [-rho1(2), rho1(1)]
        g(:, 4:6) = -g(:, 1:3)
        g(:, 6) = [rho2(2), -rho2(1)]
        ten = freal(5, e) * (len - freal(6, e)) + freal(7, e) * ldot
        ge = matmul(el, g)
        pe(:, 1) = ([1.0_dp, 0.0_dp] - el(1) * el) / len
        pe(:, 2) = ([0.0_dp, 1.0_dp] - el(2) * el) / len
        pg = matmul(pe, g)
        dldq = matmul(gv, pg)
        dldq(3) = dldq(3) - w1 * dot_product(el, rho1)
        dldq(6) = dldq(6) + w2 * dot_product(el, rho2)
        do j = 1, 6
          if (col(j) == 0) cycle
          do i = 1, 6
            if (col(i) == 0) cycle
            a(col(i), col(j)) = a(col(i), col(j)) + cs * freal(7, e) * ge(i) * ge(j) &
                                + ks * (ge(i) * (freal(5, e) * ge(j) + freal(7, e) * dldq(j)) &
                                        + ten * dot_product(g(:, i), pg(:, j)))
          end do
        end do
        if (col(3) > 0) a(col(3), col(3)) = a(col(3), col(3)) - ks * ten * dot_product(el, rho1)
        if (col(6) > 0) a(col(6), col(6)) = a(col(6), col(6)) + ks * ten * dot_product(el, rho2)
      case (MBDK_FORCE_COORDINATE)
        k = 3 * fint(2, e) - 3 + fint(4, e)
        a(k, k) = a(k, k) + ks * freal(1, e) + cs * freal(2, e)
      end select
    end do
  end subroutine mbdk_forces_tangent

  !> A spring-damper's geometry at (q, v): the offsets rho and angular velocities w of its two
  !> points, their relative velocity gv, the length len, the unit vector el from point 2 to
  !> point 1 and dL/dt = el . gv (el = 0 and ldot = 0 when len = 0: the caller decides).
  pure subroutine spring_state(fi, fr, rot, q, v, rho1, rho2, w1, w2, gv, len, el, ldot)
    integer, intent(in) :: fi(:)
    real(dp), intent(in) :: fr(:), rot(:, :), q(:), v(:)
    real(dp), intent(out) :: rho1(2), rho2(2), w1, w2, gv(2), len, el(2), ldot
    real(dp) :: p1(2), p2(2), pv1(2), pv2(2), dd(2)
    call mbdk_body_point(fi(2), fr(1:2), rot, q, v, p1, rho1, pv1, w1)
    call mbdk_body_point(fi(3), fr(3:4), rot, q, v, p2, rho2, pv2, w2)
    dd = p1 - p2
    gv = pv1 - pv2
    len = norm2(dd)
    el = 0.0_dp
    ldot = 0.0_dp
    if (len > 0.0_dp) then
      el = dd / len
      ldot = dot_product(el, gv)
    end if
  end subroutine spring_state

end module mbdk_force_elements
