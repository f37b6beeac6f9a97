!> Joints of planar scenes in absolute coordinates: constraint vector Phi(q, t), Jacobian
!> D = dPhi/dq (analytic), gamma = -(dD/dt) v - Phi_tt (analytic, so that Phi'' = D a - gamma)
!> and Phi_t. Fekete (2023) sections 1.3 and 2.2: (2.54) D q'' = gamma.
!>
!> Coordinates: body b (1-based) owns q(3b-2:3b) = (x, y, theta) of its centroid; body 0 is the
!> ground. A body-fixed point s has the global offset rho = A(theta) s and dP/dtheta = perp(rho)
!> = (-rho_y, rho_x). The rotation of every body is computed once per evaluation
!> (mbdk_body_rotations: one sin/cos pair per body, rot(1:2, b) = (cos, sin) of theta_b) and
!> handed to every joint and force element that needs it (mbdk_body_point), so that a body
!> with several joints and springs pays for one sin/cos. (The body kinematics live in this
!> module so that gfortran inlines them into the joint evaluation.)
!>
!> D is produced in compact rows: row r of D is dz(1:6, r) = the derivatives by (x, y, theta) of
!> body1 (slots 1-3) and of body2 (slots 4-6). mbdk_joints_pattern gives each slot's column of
!> D (0 for the ground) and whether it can be nonzero at all; mbdk_joints_scatter makes the
!> dense D. The compact rows are what the sparse Schur complement (mbdk_sparse_schur) reads.
!>
!> Table jint(4, nj) = (type, body1, body2, coordinate or flag); jreal(12, nj). The 4th integer is
!> the driven coordinate of a driver; for prismatic, fixed, distance, coupling and rolling joints
!> MBDK_FROM_POSE (1) takes the value the row keeps (theta0, L(0), c(0), c0) from the initial
!> pose (mbdk_assembly). Types and rows: mbdk_elements.
!>   1 revolute   (2 rows)  P1 - P2 = 0,           s1 = jreal(1:2), s2 = jreal(3:4) (for the
!>                                                    ground: the global point)
!>   2 prismatic  (2 rows)  theta1 - theta2 - theta0 = 0 and n2 . (P1 - P2) = 0, with the axis
!>                          u2 = A2 jreal(5:6) fixed in body 2 (global for the ground; unit),
!>                          n2 = perp(u2), theta0 = jreal(7)
!>   3 fixed      (3 rows)  the revolute rows and theta1 - theta2 - theta0 = 0
!>   4 driver     (1 row)   q(3 body1 - 3 + coordinate) - f(t) = 0, f = time function jreal(8:12)
!>   5 distance   (1 row)   |P1 - P2| - L(t) = 0, L = time function jreal(8:12) (a constant: the
!>                          mathematical pendulum (1.5); L0 + v t, or a sine: the pendulum of
!>                          changing length (1.6), rheonomic); MBDK_FROM_POSE takes L's offset
!>                          from the initial pose. With e = (P1 - P2)/|P1 - P2|:
!>                          D = e^T [I, perp(rho1) | -I, -perp(rho2)], Phi_t = -L',
!>                          gamma = e.(w1^2 rho1 - w2^2 rho2) - (|d'|^2 - (e.d')^2)/|d| + L''.
!>                          In metres, as the other rows (the book's squared form (1.5) has the
!>                          same zero set, but in m^2). Points that coincide have no direction:
!>                          Phi = 0 there has no Jacobian, and the assembly refuses them.
!>   6 point_line (1 row)   n2 . (P1 - P2) = 0: the point s1 of body 1 on the line through s2 of
!>                          body 2 along u2 = A2 jreal(5:6) (a prismatic joint's second row
!>                          alone: the point slides along the line and turns freely)
!>   7 point_curve (1 row)  P1y - f(P1x) = 0: the point s1 of body 1 on the ground curve y = f(x),
!>                          f the time-function family jreal(8:12) taken in x (a line, or a
!>                          sine track: c0 + c1 x + a sin(k x + phase)). With g = (-f', 1):
!>                          D = g^T [I, perp(rho1)], gamma = g.(w1^2 rho1) + f'' P1x'^2
!>   8 coupling   (1 row)   a . q_b1 + b . q_b2 - c(t) = 0, a = jreal(1:3) on (x, y, theta) of
!>                          body 1, b = jreal(4:6) on body 2, c = time function jreal(8:12)
!>                          (MBDK_FROM_POSE: c's offset from the initial pose). Python writes
!>                          q2 - ratio q1 - c (b a unit vector), in the unit of body 2's
!>                          coordinate, which the watch takes for the row's (radians where
!>                          b(3) /= 0): gear pairs on fixed axles (theta2 + (R1/R2) theta1 = c),
!>                          a rack above its pinion (x2 + R theta1 = c; below it x2 - R theta1);
!>                          linear in q: gamma = c'', Phi_t = -c'
!>   9 rolling    (2 rows)  the disc of radius R = jreal(7) centred at body 1's centroid rolls
!>                          without slip on the ground line through jreal(3:4) along the unit
!>                          u = jreal(5:6), the disc on the side of n = perp(u):
!>                            n . (c - p0) - R = 0   (contact, (1.19)-(1.20))
!>                            u . c + R theta - c0 = 0   (no slip: the contact point's velocity
!>                          u . c' + R theta' = 0 of (1.15)-(1.17) integrated, (1.18); c0 =
!>                          jreal(8), MBDK_FROM_POSE: from the initial pose). The book's x =
!>                          R phi counts phi clockwise; theta is counterclockwise, hence the +.
!>  10 knife_edge (1 row)   n1 . P1' = 0: the point s1 of body 1 has no velocity across the blade
!>                          u1 = A1 jreal(5:6), n1 = perp(u1) (the car of (1.7)-(1.14): s1 the
!>                          centroid; a skate or Chaplygin's sleigh: s1 off it). Nonholonomic
!>                          (Pfaffian, A(q) v = 0, not integrable): no position row, Phi = 0 and
!>                          Phi_t = 0 in its place, so that Phi' = D v + Phi_t is the constraint
!>                          itself and every formulation that keeps Phi' keeps it; D = A =
!>                          n1^T [I, perp(rho1)], gamma = w1^2 n1.rho1 + w1 u1.P1'
!>                          (d(A v)/dt = A a - gamma). mbdk_joints_pfaffian marks its rows.
!> Row order is the table order; the caller gives each joint's first row.
module mbdk_joints
  use mbdk_elements, only: mbdk_joint_rows, MBDK_PLANAR_JOINT_ROWS, MBDK_JOINT_REVOLUTE, &
    MBDK_JOINT_PRISMATIC, MBDK_JOINT_FIXED, MBDK_JOINT_DRIVER, MBDK_JOINT_DISTANCE, &
    MBDK_JOINT_POINT_LINE, MBDK_JOINT_POINT_CURVE, MBDK_JOINT_COUPLING, MBDK_JOINT_ROLLING, &
    MBDK_JOINT_KNIFE_EDGE, MBDK_JOINT_TYPES
  use mbdk_kinds, only: dp, i8
  use mbdk_time_function, only: mbdk_time_fn
  implicit none
  private
  public :: mbdk_joint_rows, mbdk_joints_eval, mbdk_joints_tangent, mbdk_joints_pattern, &
    mbdk_joints_scatter, mbdk_body_rotations, mbdk_body_point, mbdk_joints_pfaffian

  ! the joint types and their rows are the element registry's (mbdk_elements)
  public :: MBDK_JOINT_REVOLUTE, MBDK_JOINT_PRISMATIC, MBDK_JOINT_FIXED, MBDK_JOINT_DRIVER, &
    MBDK_JOINT_DISTANCE, MBDK_JOINT_POINT_LINE, MBDK_JOINT_POINT_CURVE, MBDK_JOINT_COUPLING, &
    MBDK_JOINT_ROLLING, MBDK_JOINT_KNIFE_EDGE, MBDK_JOINT_TYPES
  !> slots of a compact row of D: (x, y, theta) of body1, then of body2
  integer, parameter, public :: MBDK_JOINT_SLOTS = 6

contains

  !> rot(1:2, b) = (cos, sin) of theta_b for b = 1..size(rot, 2).
  pure subroutine mbdk_body_rotations(q, rot)
    real(dp), intent(in), contiguous :: q(:)
    real(dp), intent(out), contiguous :: rot(:, :)
    integer :: b
    do b = 1, size(rot, 2)
      rot(1, b) = cos(q(3 * b))
      rot(2, b) = sin(q(3 * b))
    end do
  end subroutine mbdk_body_rotations

  !> Global position p, offset rho = A s, velocity pv and angular velocity w of the point s of
  !> body b (b = 0: the ground, s is global), with rot from mbdk_body_rotations at q.
  pure subroutine mbdk_body_point(b, s, rot, q, v, p, rho, pv, w)
    integer, intent(in) :: b
    real(dp), intent(in) :: s(2), rot(:, :), q(:), v(:)
    real(dp), intent(out) :: p(2), rho(2), pv(2), w
    if (b == 0) then
      p = s
      rho = s
      pv = 0.0_dp
      w = 0.0_dp
      return
    end if
    rho(1) = rot(1, b) * s(1) - rot(2, b) * s(2)
    rho(2) = rot(2, b) * s(1) + rot(1, b) * s(2)
    p(1) = q(3 * b - 2) + rho(1)
    p(2) = q(3 * b - 1) + rho(2)
    w = v(3 * b)
    pv(1) = v(3 * b - 2) - w * rho(2)
    pv(2) = v(3 * b - 1) + w * rho(1)
  end subroutine mbdk_body_point

  !> The unit axis u2 of a prismatic joint in the global frame: A(theta_b2) axis, or the
  !> axis itself on the ground (b2 = 0).
  pure function prismatic_axis(b2, axis, rot) result(u2)
    integer, intent(in) :: b2
    real(dp), intent(in) :: axis(2), rot(:, :)
    real(dp) :: u2(2)
    if (b2 > 0) then
      u2 = [rot(1, b2) * axis(1) - rot(2, b2) * axis(2), rot(2, b2) * axis(1) + rot(1, b2) * axis(2)]
    else
      u2 = axis
    end if
  end function prismatic_axis

  !> The sparsity of D in compact rows: col(k, r) is the column of D of slot k of row r (0 when
  !> the slot belongs to the ground), nz(k, r) whether it can be nonzero: the revolute rows do
  !> not depend on theta when the joint point is the centroid (s = 0), angle rows depend on the
  !> angles only, a driver on its coordinate only.
  pure subroutine mbdk_joints_pattern(jint, jreal, row0, col, nz)
    integer, intent(in) :: jint(:, :), row0(:)
    real(dp), intent(in) :: jreal(:, :)
    integer, intent(out) :: col(:, :)
    logical, intent(out) :: nz(:, :)
    integer :: j, r, b1, b2, k
    logical :: rot1, rot2
    col = 0
    nz = .false.
    do j = 1, size(jint, 2)
      r = row0(j)
      b1 = jint(2, j)
      b2 = jint(3, j)
      rot1 = any(jreal(1:2, j) /= 0.0_dp)
      rot2 = any(jreal(3:4, j) /= 0.0_dp)
      do k = r, r + mbdk_joint_rows(jint(1, j)) - 1
        if (b1 > 0) col(1:3, k) = [3 * b1 - 2, 3 * b1 - 1, 3 * b1]
        if (b2 > 0) col(4:6, k) = [3 * b2 - 2, 3 * b2 - 1, 3 * b2]
      end do
      select case (jint(1, j))
      case (MBDK_JOINT_REVOLUTE, MBDK_JOINT_FIXED)
        nz(:, r) = [.true., .false., rot1, .true., .false., rot2]
        nz(:, r + 1) = [.false., .true., rot1, .false., .true., rot2]
        if (jint(1, j) == MBDK_JOINT_FIXED) nz(:, r + 2) = [.false., .false., .true., .false., &
                                                             .false., .true.]
      case (MBDK_JOINT_PRISMATIC)
        nz(:, r) = [.false., .false., .true., .false., .false., .true.]
        nz(:, r + 1) = [.true., .true., rot1, .true., .true., .true.]
      case (MBDK_JOINT_DRIVER)
        nz(jint(4, j), r) = .true.
      case (MBDK_JOINT_DISTANCE)
        nz(:, r) = [.true., .true., rot1, .true., .true., rot2]
      case (MBDK_JOINT_POINT_LINE)
        nz(:, r) = [.true., .true., rot1, .true., .true., .true.]
      case (MBDK_JOINT_POINT_CURVE, MBDK_JOINT_KNIFE_EDGE)
        nz(:, r) = [.true., .true., rot1, .false., .false., .false.]
      case (MBDK_JOINT_COUPLING)
        nz(:, r) = jreal(1:6, j) /= 0.0_dp
      case (MBDK_JOINT_ROLLING)
        nz(:, r) = [.true., .true., .false., .false., .false., .false.]
        nz(:, r + 1) = [.true., .true., .true., .false., .false., .false.]
      end select
    end do
    nz = nz .and. col > 0
  end subroutine mbdk_joints_pattern

  !> Dense d(m, nc) from the compact rows dz and the columns col of mbdk_joints_pattern.
  pure subroutine mbdk_joints_scatter(col, dz, d)
    integer, intent(in) :: col(:, :)
    real(dp), intent(in) :: dz(:, :)
    real(dp), intent(out) :: d(:, :)
    integer :: r, k
    d = 0.0_dp
    do r = 1, size(dz, 2)
      do k = 1, MBDK_JOINT_SLOTS
        if (col(k, r) > 0) d(r, col(k, r)) = d(r, col(k, r)) + dz(k, r)
      end do
    end do
  end subroutine mbdk_joints_scatter

  !> pf(m): .true. for the rows that constrain velocities only (nonholonomic, Pfaffian: their
  !> Phi is 0 and Phi' = D v + Phi_t is the constraint).
  pure subroutine mbdk_joints_pfaffian(jint, row0, pf)
    integer, intent(in) :: jint(:, :), row0(:)
    logical, intent(out) :: pf(:)
    integer :: j
    pf = .false.
    do j = 1, size(jint, 2)
      if (jint(1, j) == MBDK_JOINT_KNIFE_EDGE) pf(row0(j)) = .true.
    end do
  end subroutine mbdk_joints_pfaffian

  !> phi(m), the compact rows dz(6, m) of D (every slot written; ground slots 0), gam(m),
  !> phit(m) at (q, v, t); rot from mbdk_body_rotations at q. visits(1:MBDK_JOINT_TYPES)
  !> counts the evaluations per joint type.
  subroutine mbdk_joints_eval(jint, jreal, row0, rot, q, v, t, phi, dz, gam, phit, visits)
    integer, intent(in), contiguous :: jint(:, :), row0(:)
    real(dp), intent(in), contiguous :: jreal(:, :), rot(:, :), q(:), v(:)
    real(dp), intent(in) :: t
    real(dp), intent(out), contiguous :: phi(:), dz(:, :), gam(:), phit(:)
    integer(i8), intent(inout), contiguous :: visits(:)
    integer :: j, r, b1, b2
    real(dp) :: p1(2), p2(2), rho1(2), rho2(2), pv1(2), pv2(2), w1, w2, dd(2), ddot(2)
    real(dp) :: u2(2), n2(2), f, fd, fdd, len, el(2), edot

    do j = 1, size(jint, 2)
      r = row0(j)
      b1 = jint(2, j)
      b2 = jint(3, j)
      visits(jint(1, j)) = visits(jint(1, j)) + 1
      select case (jint(1, j))
      case (MBDK_JOINT_REVOLUTE, MBDK_JOINT_FIXED)
        call mbdk_body_point(b1, jreal(1:2, j), rot, q, v, p1, rho1, pv1, w1)
        call mbdk_body_point(b2, jreal(3:4, j), rot, q, v, p2, rho2, pv2, w2)
        phi(r) = p1(1) - p2(1)
        phi(r + 1) = p1(2) - p2(2)
        phit(r) = 0.0_dp
        phit(r + 1) = 0.0_dp
        gam(r) = w1**2 * rho1(1) - w2**2 * rho2(1)
        gam(r + 1) = w1**2 * rho1(2) - w2**2 * rho2(2)
        dz(:, r) = [1.0_dp, 0.0_dp, -rho1(2), -1.0_dp, 0.0_dp, rho2(2)]
        dz(:, r + 1) = [0.0_dp, 1.0_dp, rho1(1), 0.0_dp, -1.0_dp, -rho2(1)]
        if (jint(1, j) == MBDK_JOINT_FIXED) call angle_row(r + 2)
      case (MBDK_JOINT_PRISMATIC)
        call angle_row(r)
        call line_row(r + 1)
      case (MBDK_JOINT_POINT_LINE)
        call line_row(r)
      case (MBDK_JOINT_POINT_CURVE)
        call mbdk_body_point(b1, jreal(1:2, j), rot, q, v, p1, rho1, pv1, w1)
        call mbdk_time_fn(jreal(8:12, j), p1(1), f, fd, fdd)
        phi(r) = p1(2) - f
        phit(r) = 0.0_dp
        gam(r) = -fd * w1**2 * rho1(1) + w1**2 * rho1(2) + fdd * pv1(1)**2
        dz(:, r) = [-fd, 1.0_dp, fd * rho1(2) + rho1(1), 0.0_dp, 0.0_dp, 0.0_dp]
      case (MBDK_JOINT_COUPLING)
        call mbdk_time_fn(jreal(8:12, j), t, f, fd, fdd)
        phi(r) = -f
        if (b1 > 0) phi(r) = phi(r) + dot_product(jreal(1:3, j), q(3 * b1 - 2:3 * b1))
        if (b2 > 0) phi(r) = phi(r) + dot_product(jreal(4:6, j), q(3 * b2 - 2:3 * b2))
        phit(r) = -fd
        gam(r) = fdd
        dz(:, r) = jreal(1:6, j)
      case (MBDK_JOINT_ROLLING)
        u2 = jreal(5:6, j)
        n2 = [-u2(2), u2(1)]
        phi(r) = n2(1) * (q(3 * b1 - 2) - jreal(3, j)) + n2(2) * (q(3 * b1 - 1) - jreal(4, j)) &
                 - jreal(7, j)
        phi(r + 1) = u2(1) * q(3 * b1 - 2) + u2(2) * q(3 * b1 - 1) + jreal(7, j) * q(3 * b1) &
                     - jreal(8, j)
        phit(r:r + 1) = 0.0_dp
        gam(r:r + 1) = 0.0_dp
        dz(:, r) = [n2(1), n2(2), 0.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]
        dz(:, r + 1) = [u2(1), u2(2), jreal(7, j), 0.0_dp, 0.0_dp, 0.0_dp]
      case (MBDK_JOINT_KNIFE_EDGE)
        call mbdk_body_point(b1, jreal(1:2, j), rot, q, v, p1, rho1, pv1, w1)
        u2 = prismatic_axis(b1, jreal(5:6, j), rot)
        n2 = [-u2(2), u2(1)]
        phi(r) = 0.0_dp
        phit(r) = 0.0_dp
        gam(r) = w1**2 * dot_product(n2, rho1) + w1 * dot_product(u2, pv1)
        dz(:, r) = [n2(1), n2(2), -n2(1) * rho1(2) + n2(2) * rho1(1), 0.0_dp, 0.0_dp, 0.0_dp]
      case (MBDK_JOINT_DRIVER)
        call mbdk_time_fn(jreal(8:12, j), t, f, fd, fdd)
        phi(r) = q(3 * b1 - 3 + jint(4, j)) - f
        phit(r) = -fd
        gam(r) = fdd
        dz(:, r) = 0.0_dp
        dz(jint(4, j), r) = 1.0_dp
      case (MBDK_JOINT_DISTANCE)
        call mbdk_time_fn(jreal(8:12, j), t, f, fd, fdd)
        call mbdk_body_point(b1, jreal(1:2, j), rot, q, v, p1, rho1, pv1, w1)
        call mbdk_body_point(b2, jreal(3:4, j), rot, q, v, p2, rho2, pv2, w2)
        dd = p1 - p2
        ddot = pv1 - pv2
        len = norm2(dd)
        ! coinciding points: no direction (NaN rows, which the solve and the watch report)
        el = dd / len
        edot = dot_product(el, ddot)
        phi(r) = len - f
        phit(r) = -fd
        gam(r) = dot_product(el, w1**2 * rho1 - w2**2 * rho2) &
                 - (dot_product(ddot, ddot) - edot**2) / len + fdd
        dz(:, r) = [el(1), el(2), -el(1) * rho1(2) + el(2) * rho1(1), -el(1), -el(2), &
                    el(1) * rho2(2) - el(2) * rho2(1)]
      end select
      ! (the types were checked at mbdk_model_init)
      if (b2 == 0) dz(4:6, r:r + MBDK_PLANAR_JOINT_ROWS(jint(1, j)) - 1) = 0.0_dp
    end do

  contains

    !> n2 . (P1 - P2) = 0 in row rr: P1 on the line through P2 along u2 (fixed in body 2)
    subroutine line_row(rr)
      integer, intent(in) :: rr
      call mbdk_body_point(b1, jreal(1:2, j), rot, q, v, p1, rho1, pv1, w1)
      call mbdk_body_point(b2, jreal(3:4, j), rot, q, v, p2, rho2, pv2, w2)
      u2 = prismatic_axis(b2, jreal(5:6, j), rot)
      n2 = [-u2(2), u2(1)]
      dd = p1 - p2
      ddot = pv1 - pv2
      phi(rr) = dot_product(n2, dd)
      phit(rr) = 0.0_dp
      ! perp(n2) = -u2;  D v-dot terms: n2.(-w1^2 rho1 + w2^2 rho2) + 2 w2 perp(n2).ddot
      !                                 - w2^2 n2.dd
      gam(rr) = -(dot_product(n2, -w1**2 * rho1 + w2**2 * rho2) &
                  - 2.0_dp * w2 * dot_product(u2, ddot) - w2**2 * dot_product(n2, dd))
      dz(:, rr) = [n2(1), n2(2), n2(1) * (-rho1(2)) + n2(2) * rho1(1), -n2(1), -n2(2), &
                   -dot_product(u2, dd) - (n2(1) * (-rho2(2)) + n2(2) * rho2(1))]
    end subroutine line_row

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
      dz(:, rr) = [0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp, 0.0_dp, -1.0_dp]
    end subroutine angle_row

  end subroutine mbdk_joints_eval

  !> kc(nc, nc) += d(D^T lam)/dq: the geometric stiffness of the constraint forces at fixed
  !> multipliers lam (the second derivatives of Phi, weighted by lam), for the Newton matrix of
  !> the index-3 integrators; rot from mbdk_body_rotations at q. Angle rows, drivers, couplings
  !> and rolling rows are linear in q and contribute nothing; knife edges have no position row
  !> (the index-3 integrators refuse them).
  !> With d = P1 - P2, perp(x) = (-x2, x1), dP/dtheta = perp(rho), d perp(rho)/dtheta = -rho:
  !>   revolute/fixed: (th1, th1) -= rho1 . lam(r:r+1);  (th2, th2) += rho2 . lam(r:r+1)
  !>   prismatic (or point_line) row n2 . d (n2 turns with body 2, dn2/dth2 = -u2,
  !>   du2/dth2 = n2), times lam:
  !>     (th1, th1) -n2.rho1;  (r1, th2) -u2;  (th1, th2) -u2.perp(rho1);  (r2, th2) +u2;
  !>     (th2, th2) -n2.d + 2 u2.perp(rho2) + n2.rho2   (symmetric)
  !>   point_curve row P1y - f(P1x) (D = g^T G, g = (-f', 1), G = [I, perp(rho1)]):
  !>     lam [-f'' G1^T G1; (th1, th1) -= g.rho1]
  !>   distance row |d| - L, G = dd/dq on the six coordinates (I, perp(rho1); -I, -perp(rho2)):
  !>     lam [G^T (I - e e^T) G / |d|; (th1, th1) -= e.rho1; (th2, th2) += e.rho2]
  subroutine mbdk_joints_tangent(jint, jreal, row0, rot, q, lam, kc, visits)
    integer, intent(in), contiguous :: jint(:, :), row0(:)
    real(dp), intent(in), contiguous :: jreal(:, :), rot(:, :), q(:), lam(:)
    real(dp), intent(inout), contiguous :: kc(:, :)
    integer(i8), intent(inout), contiguous :: visits(:)
    integer :: j, r, b1, b2, i1, i2, c
    real(dp) :: p1(2), p2(2), rho1(2), rho2(2), pv1(2), pv2(2), w1, w2, u2(2), n2(2), dd(2)
    real(dp) :: l, x, g(2, 6), pg(2, 6), el(2), len, fd, fdd
    integer :: col(6), a, bb

    ! mbdk_body_point gets q in place of v: only the positions p and offsets rho are used
    do j = 1, size(jint, 2)
      visits(jint(1, j)) = visits(jint(1, j)) + 1
      r = row0(j)
      b1 = jint(2, j)
      b2 = jint(3, j)
      i1 = 3 * b1
      i2 = 3 * b2
      select case (jint(1, j))
      case (MBDK_JOINT_REVOLUTE, MBDK_JOINT_FIXED)
        call mbdk_body_point(b1, jreal(1:2, j), rot, q, q, p1, rho1, pv1, w1)
        call mbdk_body_point(b2, jreal(3:4, j), rot, q, q, p2, rho2, pv2, w2)
        if (b1 > 0) kc(i1, i1) = kc(i1, i1) - dot_product(rho1, lam(r:r + 1))
        if (b2 > 0) kc(i2, i2) = kc(i2, i2) + dot_product(rho2, lam(r:r + 1))
      case (MBDK_JOINT_PRISMATIC, MBDK_JOINT_POINT_LINE)
        l = lam(r)
        if (jint(1, j) == MBDK_JOINT_PRISMATIC) l = lam(r + 1)
        call mbdk_body_point(b1, jreal(1:2, j), rot, q, q, p1, rho1, pv1, w1)
        call mbdk_body_point(b2, jreal(3:4, j), rot, q, q, p2, rho2, pv2, w2)
        u2 = prismatic_axis(b2, jreal(5:6, j), rot)
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
      case (MBDK_JOINT_DISTANCE)
        l = lam(r)
        call mbdk_body_point(b1, jreal(1:2, j), rot, q, q, p1, rho1, pv1, w1)
        call mbdk_body_point(b2, jreal(3:4, j), rot, q, q, p2, rho2, pv2, w2)
        dd = p1 - p2
        len = norm2(dd)
        el = dd / len
        col = 0
        if (b1 > 0) col(1:3) = [i1 - 2, i1 - 1, i1]
        if (b2 > 0) col(4:6) = [i2 - 2, i2 - 1, i2]
        g(:, 1) = [1.0_dp, 0.0_dp]
        g(:, 2) = [0.0_dp, 1.0_dp]
        g(:, 3) = [-rho1(2), rho1(1)]
        g(:, 4:5) = -g(:, 1:2)
        g(:, 6) = [rho2(2), -rho2(1)]
        ! (I - e e^T) G / |d|
        pg(1, :) = ((1.0_dp - el(1)**2) * g(1, :) - el(1) * el(2) * g(2, :)) / len
        pg(2, :) = (-el(1) * el(2) * g(1, :) + (1.0_dp - el(2)**2) * g(2, :)) / len
        do bb = 1, 6
          if (col(bb) == 0) cycle
          do a = 1, 6
            if (col(a) == 0) cycle
            kc(col(a), col(bb)) = kc(col(a), col(bb)) + l * dot_product(g(:, a), pg(:, bb))
          end do
        end do
        if (b1 > 0) kc(i1, i1) = kc(i1, i1) - l * dot_product(el, rho1)
        if (b2 > 0) kc(i2, i2) = kc(i2, i2) + l * dot_product(el, rho2)
      case (MBDK_JOINT_POINT_CURVE)
        l = lam(r)
        call mbdk_body_point(b1, jreal(1:2, j), rot, q, q, p1, rho1, pv1, w1)
        call mbdk_time_fn(jreal(8:12, j), p1(1), x, fd, fdd)
        ! D = g^T G, g = (-f'(P1x), 1), G = [I, perp(rho1)]: dg/dq = (-f'' G(1, :), 0) and
        ! d perp(rho1)/dtheta = -rho1
        g(1, 1:3) = [1.0_dp, 0.0_dp, -rho1(2)]
        do bb = 1, 3
          do a = 1, 3
            kc(i1 - 3 + a, i1 - 3 + bb) = kc(i1 - 3 + a, i1 - 3 + bb) &
                                          - l * fdd * g(1, a) * g(1, bb)
          end do
        end do
        kc(i1, i1) = kc(i1, i1) - l * (-fd * rho1(1) + rho1(2))
      end select
    end do
  end subroutine mbdk_joints_tangent

end module mbdk_joints
