!> Joints of planar scenes in absolute coordinates: constraint vector Phi(q, t), Jacobian
!> D = dPhi/dq (analytic), gamma = -(dD/dt) v - Phi_tt (analytic, so that Phi'' = D a - gamma)
!> and Phi_t. Fekete (2023) sections 1.3 and 2.2: (2.54) D q'' = gamma.
!>
!> Coordinates: body b (1-based) owns q(3b-2:3b) = (x, y, theta) of its centroid; body 0 is the
!> ground. A body-fixed point s has the global offset rho = A(theta) s and dP/dtheta = perp(rho)
!> = (-rho_y, rho_x).
!>
!> Table jint(4, nj) = (type, body1, body2, coordinate); jreal(12, nj):
!>   1 revolute   (2 rows)  P1 - P2 = 0,           s1 = jreal(1:2), s2 = jreal(3:4) (for the
!>                                                    ground: the global point)
!>   2 prismatic  (2 rows)  theta1 - theta2 - theta0 = 0 and n2 . (P1 - P2) = 0, with the axis
!>                          u2 = A2 jreal(5:6) fixed in body 2 (global for the ground; unit),
!>                          n2 = perp(u2), theta0 = jreal(7)
!>   3 fixed      (3 rows)  the revolute rows and theta1 - theta2 - theta0 = 0
!>   4 driver     (1 row)   q(3 body1 - 3 + coordinate) - f(t) = 0, f = time function jreal(8:12)
!> Row order is the table order; the caller gives each joint's first row.
module mbdk_joints
  use mbdk_kinds, only: dp, i8
  use mbdk_time_function, only: mbdk_time_fn
  implicit none
  private
  public :: mbdk_joint_rows, mbdk_joints_eval, mbdk_body_point, mbdk_joints_tangent

  integer, parameter, public :: MBDK_JOINT_REVOLUTE = 1, MBDK_JOINT_PRISMATIC = 2, &
    MBDK_JOINT_FIXED = 3, MBDK_JOINT_DRIVER = 4, MBDK_JOINT_TYPES = 4

contains

  pure integer function mbdk_joint_rows(jtype)
    integer, intent(in) :: jtype
    select case (jtype)
    case (MBDK_JOINT_REVOLUTE, MBDK_JOINT_PRISMATIC)
      mbdk_joint_rows = 2
    case (MBDK_JOINT_FIXED)
      mbdk_joint_rows = 3
    case (MBDK_JOINT_DRIVER)
      mbdk_joint_rows = 1
    case default
      mbdk_joint_rows = 0
    end select
  end function mbdk_joint_rows

  !> Global position p, offset rho = A s, velocity pv and angular velocity w of the point s of
  !> body b (b = 0: the ground, s is global).
  pure subroutine mbdk_body_point(b, s, q, v, p, rho, pv, w)
    integer, intent(in) :: b
    real(dp), intent(in) :: s(2), q(:), v(:)
    real(dp), intent(out) :: p(2), rho(2), pv(2), w
    real(dp) :: c, sn
    if (b == 0) then
      p = s
      rho = s
      pv = 0.0_dp
      w = 0.0_dp
      return
    end if
    c = cos(q(3 * b))
    sn = sin(q(3 * b))
    rho = [c * s(1) - sn * s(2), sn * s(1) + c * s(2)]
    p = q(3 * b - 2:3 * b - 1) + rho
    w = v(3 * b)
    pv = v(3 * b - 2:3 * b - 1) + w * [-rho(2), rho(1)]
  end subroutine mbdk_body_point

  !> phi(m), d(m, nc) (only the joints' entries are written: zero it first), gam(m), phit(m).
  !> visits(1:4) counts the evaluations per joint type.
  subroutine mbdk_joints_eval(jint, jreal, row0, q, v, t, phi, d, gam, phit, visits)
    integer, intent(in) :: jint(:, :), row0(:)
    real(dp), intent(in) :: jreal(:, :), q(:), v(:), t
    real(dp), intent(out) :: phi(:), gam(:), phit(:)
    real(dp), intent(inout) :: d(:, :)
    integer(i8), intent(inout) :: visits(:)
    integer :: j, r, b1, b2, k
    real(dp) :: p1(2), p2(2), rho1(2), rho2(2), pv1(2), pv2(2), w1, w2, dd(2), ddot(2)
    real(dp) :: u2(2), n2(2), c, sn, f, fd, fdd

    do j = 1, size(jint, 2)
      r = row0(j)
      b1 = jint(2, j)
      b2 = jint(3, j)
      visits(jint(1, j)) = visits(jint(1, j)) + 1
      select case (jint(1, j))
      case (MBDK_JOINT_REVOLUTE, MBDK_JOINT_FIXED)
        call mbdk_body_point(b1, jreal(1:2, j), q, v, p1, rho1, pv1, w1)
        call mbdk_body_point(b2, jreal(3:4, j), q, v, p2, rho2, pv2, w2)
        phi(r:r + 1) = p1 - p2
        phit(r:r + 1) = 0.0_dp
        gam(r:r + 1) = w1**2 * rho1 - w2**2 * rho2
        if (b1 > 0) then
          d(r, 3 * b1 - 2) = 1.0_dp
          d(r + 1, 3 * b1 - 1) = 1.0_dp
          d(r, 3 * b1) = -rho1(2)
          d(r + 1, 3 * b1) = rho1(1)
        end if
        if (b2 > 0) then
          d(r, 3 * b2 - 2) = -1.0_dp
          d(r + 1, 3 * b2 - 1) = -1.0_dp
          d(r, 3 * b2) = rho2(2)
          d(r + 1, 3 * b2) = -rho2(1)
        end if
        if (jint(1, j) == MBDK_JOINT_FIXED) call angle_row(r + 2)
      case (MBDK_JOINT_PRISMATIC)
        call angle_row(r)
        call mbdk_body_point(b1, jreal(1:2, j), q, v, p1, rho1, pv1, w1)
        call mbdk_body_point(b2, jreal(3:4, j), q, v, p2, rho2, pv2, w2)
        if (b2 > 0) then
          c = cos(q(3 * b2))
          sn = sin(q(3 * b2))
          u2 = [c * jreal(5, j) - sn * jreal(6, j), sn * jreal(5, j) + c * jreal(6, j)]
        else
          u2 = jreal(5:6, j)
        end if
        n2 = [-u2(2), u2(1)]
        dd = p1 - p2
        ddot = pv1 - pv2
        phi(r + 1) = dot_product(n2, dd)
        phit(r + 1) = 0.0_dp
        ! perp(n2) = -u2;  D v-dot terms: n2.(-w1^2 rho1 + w2^2 rho2) + 2 w2 perp(n2).ddot
        !                                 - w2^2 n2.dd
        gam(r + 1) = -(dot_product(n2, -w1**2 * rho1 + w2**2 * rho2) &
                       - 2.0_dp * w2 * dot_product(u2, ddot) - w2**2 * dot_product(n2, dd))
        if (b1 > 0) then
          d(r + 1, 3 * b1 - 2:3 * b1 - 1) = n2
          d(r + 1, 3 * b1) = n2(1) * (-rho1(2)) + n2(2) * rho1(1)
        end if
        if (b2 > 0) then
          d(r + 1, 3 * b2 - 2:3 * b2 - 1) = -n2
          d(r + 1, 3 * b2) = -dot_product(u2, dd) - (n2(1) * (-rho2(2)) + n2(2) * rho2(1))
        end if
      case (MBDK_JOINT_DRIVER)
        k = 3 * b1 - 3 + jint(4, j)
        call mbdk_time_fn(jreal(8:12, j), t, f, fd, fdd)
        phi(r) = q(k) - f
        phit(r) = -fd
        gam(r) = fdd
        d(r, k) = 1.0_dp
      end select
    end do

  contains

    subroutine angle_row(rr)
      integer, intent(in) :: rr
      real(dp) :: th1, th2
      th1 = 0.0_dp
      th2 = 0.0_dp
      if (b1 > 0) th1 = q(3 * b1)
      if (b2 > 0) th2 = q(3 * b2)
      phi(rr) = th1 - th2 - jreal(7, j)
      phit(rr) = 0.0_dp
      gam(rr) = 0.0_dp
      if (b1 > 0) d(rr, 3 * b1) = 1.0_dp
      if (b2 > 0) d(rr, 3 * b2) = -1.0_dp
    end subroutine angle_row

  end subroutine mbdk_joints_eval

  !> kc(nc, nc) += d(D^T lam)/dq: the geometric stiffness of the constraint forces at fixed
  !> multipliers lam (the second derivatives of Phi, weighted by lam), for the Newton matrix of
  !> the index-3 integrators. Angle rows and drivers are linear in q and contribute nothing.
  !> With d = P1 - P2, perp(x) = (-x2, x1), dP/dtheta = perp(rho), d perp(rho)/dtheta = -rho:
  !>   revolute/fixed: (th1, th1) -= rho1 . lam(r:r+1);  (th2, th2) += rho2 . lam(r:r+1)
  !>   prismatic row n2 . d (n2 turns with body 2, dn2/dth2 = -u2, du2/dth2 = n2), times lam:
  !>     (th1, th1) -n2.rho1;  (r1, th2) -u2;  (th1, th2) -u2.perp(rho1);  (r2, th2) +u2;
  !>     (th2, th2) -n2.d + 2 u2.perp(rho2) + n2.rho2   (symmetric)
  subroutine mbdk_joints_tangent(jint, jreal, row0, q, lam, kc)
    integer, intent(in) :: jint(:, :), row0(:)
    real(dp), intent(in) :: jreal(:, :), q(:), lam(:)
    real(dp), intent(inout) :: kc(:, :)
    integer :: j, r, b1, b2, i1, i2, c
    real(dp) :: p1(2), p2(2), rho1(2), rho2(2), pv1(2), pv2(2), w1, w2, u2(2), n2(2), dd(2)
    real(dp) :: l, cs, sn, zero(size(q)), x

    zero = 0.0_dp
    do j = 1, size(jint, 2)
      r = row0(j)
      b1 = jint(2, j)
      b2 = jint(3, j)
      i1 = 3 * b1
      i2 = 3 * b2
      select case (jint(1, j))
      case (MBDK_JOINT_REVOLUTE, MBDK_JOINT_FIXED)
        call mbdk_body_point(b1, jreal(1:2, j), q, zero, p1, rho1, pv1, w1)
        call mbdk_body_point(b2, jreal(3:4, j), q, zero, p2, rho2, pv2, w2)
        if (b1 > 0) kc(i1, i1) = kc(i1, i1) - dot_product(rho1, lam(r:r + 1))
        if (b2 > 0) kc(i2, i2) = kc(i2, i2) + dot_product(rho2, lam(r:r + 1))
      case (MBDK_JOINT_PRISMATIC)
        l = lam(r + 1)
        call mbdk_body_point(b1, jreal(1:2, j), q, zero, p1, rho1, pv1, w1)
        call mbdk_body_point(b2, jreal(3:4, j), q, zero, p2, rho2, pv2, w2)
        if (b2 > 0) then
          cs = cos(q(i2))
          sn = sin(q(i2))
          u2 = [cs * jreal(5, j) - sn * jreal(6, j), sn * jreal(5, j) + cs * jreal(6, j)]
        else
          u2 = jreal(5:6, j)
        end if
        n2 = [-u2(2), u2(1)]
        dd = p1 - p2
        kc(i1, i1) = kc(i1, i1) - l * dot_product(n2, rho1)
        if (b2 > 0) then
          do c = 1, 2
            kc(i1 - 3 + c, i2) = kc(i1 - 3 + c, i2) - l * u2(c)
            kc(i2, i1 - 3 + c) = kc(i2, i1 - 3 + c) - l * u2(c)
            kc(i2 - 3 + c, i2) = kc(i2 - 3 + c, i2) + l * u2(c)
            kc(i2, i2 - 3 + c) = kc(i2, i2 - 3 + c) + l * u2(c)
          end do
          x = -l * dot_product(u2, [-rho1(2), rho1(1)])
          kc(i1, i2) = kc(i1, i2) + x
          kc(i2, i1) = kc(i2, i1) + x
          kc(i2, i2) = kc(i2, i2) + l * (-dot_product(n2, dd) &
                       + 2.0_dp * dot_product(u2, [-rho2(2), rho2(1)]) + dot_product(n2, rho2))
        end if
      end select
    end do
  end subroutine mbdk_joints_tangent

end module mbdk_joints
