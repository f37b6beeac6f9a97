!> Rotations in three dimensions (Fekete (2023) chapter 5): rotation matrices from Euler and
!> Cardan angles, the Euler axis (Rodrigues) and unit quaternions, the skew matrix of angular
!> velocity, and the maps between the rates of each parametrisation and angular velocity in the
!> space and the body frame, with their inverses.
!>
!> Conventions (each stated once here; the tests check them against independent constructions):
!>   - R maps body components to space components, r = R r_body.
!>   - Angle sequences are rotations about moving axes: the sequence (i, j, k) with angles
!>     (a1, a2, a3) is R = R_i(a1) R_j(a2) R_k(a3), R_1 = R_x etc. 3-1-3 Euler angles
!>     (phi, theta, psi): R = R_z(phi) R_x(theta) R_z(psi); 1-2-3 Cardan angles: R_x R_y R_z.
!>   - Angular velocity: W = R' R^T = skew(omega) in the space frame, R^T R' = skew(Omega) in
!>     the body frame, Omega = R^T omega.
!>   - Quaternions are scalar first, q = (s, v); the rotation by a unit q is the sandwich
!>     (0, R x) = q (0, x) q*, R = (s^2 - v.v) I + 2 v v^T + 2 s skew(v).
!>
!> Angle rates and angular velocity: omega = G_s(a) a', Omega = G_b(a) a' with the columns of
!> G_s the space-frame axes of the three elementary rotations, [e_i, R_i(a1) e_j,
!> R_i(a1) R_j(a2) e_k], and G_b = R^T G_s. det G_s = det G_b is -sin(a2) for proper Euler
!> sequences (i = k; 3-1-3: singular at theta = 0 and pi) and +-cos(a2) for Cardan sequences
!> (1-2-3: singular at beta = +-90 deg): at |det| <= MBDK_GIMBAL_TOL the inverse maps return
!> MBDK_ERR_SINGULAR_MATRIX (gimbal lock), never a rate of 1/0.
!> Quaternion rates: q' = (1/2) (0, omega) q = (1/2) q (0, Omega); back, omega = 2 vec(q' q*),
!> Omega = 2 vec(q* q').
!>
!> Every routine is pure and allocates nothing. The ones that return a status refuse bad input
!> with MBDK_ERR_INVALID_INPUT: an angle sequence that is not one of the twelve, a quaternion
!> whose norm differs from 1 by more than MBDK_UNIT_TOL (the matrix and the sandwich product),
!> an axis of zero length, a matrix that is not a rotation. The product and the rate maps of
!> quaternions are algebra on any quaternion (an integrator's state drifts off |q| = 1; what
!> that costs is for the caller to measure or correct).
module mbdk_rotations
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT, MBDK_ERR_SINGULAR_MATRIX
  implicit none
  private
  public :: mbdk_cross, mbdk_skew, mbdk_unskew, mbdk_axis_rotation, mbdk_angles_matrix, &
    mbdk_angles_rate_maps, mbdk_angles_rates, mbdk_quat_mul, mbdk_quat_conj, &
    mbdk_quat_matrix, mbdk_quat_matrix_of, mbdk_quat_from_matrix, mbdk_quat_rotate, mbdk_quat_rates, &
    mbdk_quat_omega, mbdk_rodrigues, mbdk_axis_angle_from_matrix, mbdk_is_rotation

  !> the angle sequences of the scene file: 3-1-3 Euler, 1-2-3 Cardan
  integer, parameter, public :: MBDK_SEQ_EULER313(3) = [3, 1, 3], MBDK_SEQ_CARDAN123(3) = [1, 2, 3]
  !> |det G| at or below which the angle rates are undefined (gimbal lock)
  real(dp), parameter, public :: MBDK_GIMBAL_TOL = 1.0e-12_dp
  !> how far from 1 the norm of a unit quaternion, or R^T R from I, may be
  real(dp), parameter, public :: MBDK_UNIT_TOL = 1.0e-8_dp

contains

  !> skew(w) x = w x x.
  pure function mbdk_skew(w) result(k)
    real(dp), intent(in) :: w(3)
    real(dp) :: k(3, 3)
    ! element by element: a reshape of a constructor is a library call in the inner loops
    k(1, 1) = 0.0_dp
    k(2, 1) = w(3)
    k(3, 1) = -w(2)
    k(1, 2) = -w(3)
    k(2, 2) = 0.0_dp
    k(3, 2) = w(1)
    k(1, 3) = w(2)
    k(2, 3) = -w(1)
    k(3, 3) = 0.0_dp
  end function mbdk_skew

  !> The vector of the skew-symmetric part of k: w with skew(w) = (k - k^T) / 2.
  pure function mbdk_unskew(k) result(w)
    real(dp), intent(in) :: k(3, 3)
    real(dp) :: w(3)
    w = 0.5_dp * [k(3, 2) - k(2, 3), k(1, 3) - k(3, 1), k(2, 1) - k(1, 2)]
  end function mbdk_unskew

  !> The elementary rotation about coordinate axis i (1, 2, 3) by angle a.
  pure function mbdk_axis_rotation(i, a) result(r)
    integer, intent(in) :: i
    real(dp), intent(in) :: a
    real(dp) :: r(3, 3), c, s
    integer :: j, k
    c = cos(a)
    s = sin(a)
    j = mod(i, 3) + 1
    k = mod(i + 1, 3) + 1
    r = 0.0_dp
    r(i, i) = 1.0_dp
    r(j, j) = c
    r(k, k) = c
    r(k, j) = s
    r(j, k) = -s
  end function mbdk_axis_rotation

  !> A valid sequence: three axes in 1..3, neighbours different.
  pure logical function valid_sequence(seq)
    integer, intent(in) :: seq(3)
    valid_sequence = all(seq >= 1 .and. seq <= 3) .and. seq(1) /= seq(2) .and. &
      seq(2) /= seq(3)
  end function valid_sequence

  !> R = R_seq(1)(a(1)) R_seq(2)(a(2)) R_seq(3)(a(3)).
  pure subroutine mbdk_angles_matrix(seq, a, r, stat)
    integer, intent(in) :: seq(3)
    real(dp), intent(in) :: a(3)
    real(dp), intent(out) :: r(3, 3)
    integer, intent(out) :: stat
    real(dp) :: r1(3, 3), r2(3, 3), r3(3, 3), r12(3, 3)
    r = 0.0_dp
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. valid_sequence(seq) .or. .not. all(abs(a) <= huge(1.0_dp))) return
    ! (products of named matrices: gfortran inlines those, not a product of products)
    r1 = mbdk_axis_rotation(seq(1), a(1))
    r2 = mbdk_axis_rotation(seq(2), a(2))
    r3 = mbdk_axis_rotation(seq(3), a(3))
    r12 = matmul(r1, r2)
    r = matmul(r12, r3)
    stat = MBDK_SUCCESS
  end subroutine mbdk_angles_matrix

  !> G_s and G_b of the header (omega = G_s a', Omega = G_b a') and det = det G_s.
  pure subroutine mbdk_angles_rate_maps(seq, a, gs, gb, det, stat)
    integer, intent(in) :: seq(3)
    real(dp), intent(in) :: a(3)
    real(dp), intent(out) :: gs(3, 3), gb(3, 3), det
    integer, intent(out) :: stat
    real(dp) :: r1(3, 3), r12(3, 3), r(3, 3)
    gs = 0.0_dp
    gb = 0.0_dp
    det = 0.0_dp
    call mbdk_angles_matrix(seq, a, r, stat)
    if (stat /= MBDK_SUCCESS) return
    r1 = mbdk_axis_rotation(seq(1), a(1))
    r12 = matmul(r1, mbdk_axis_rotation(seq(2), a(2)))
    gs(seq(1), 1) = 1.0_dp
    gs(:, 2) = r1(:, seq(2))
    gs(:, 3) = r12(:, seq(3))
    gb = matmul(transpose(r), gs)
    det = gs(1, 1) * (gs(2, 2) * gs(3, 3) - gs(3, 2) * gs(2, 3)) &
        - gs(1, 2) * (gs(2, 1) * gs(3, 3) - gs(3, 1) * gs(2, 3)) &
        + gs(1, 3) * (gs(2, 1) * gs(3, 2) - gs(3, 1) * gs(2, 2))
  end subroutine mbdk_angles_rate_maps

  !> The angle rates ad from an angular velocity w, given in the space frame (body = .false.)
  !> or the body frame: ad = G^-1 w. |det G| <= MBDK_GIMBAL_TOL: MBDK_ERR_SINGULAR_MATRIX.
  pure subroutine mbdk_angles_rates(seq, a, w, body, ad, stat)
    integer, intent(in) :: seq(3)
    real(dp), intent(in) :: a(3), w(3)
    logical, intent(in) :: body
    real(dp), intent(out) :: ad(3)
    integer, intent(out) :: stat
    real(dp) :: gs(3, 3), gb(3, 3), g(3, 3), det, adj(3, 3)
    ad = 0.0_dp
    call mbdk_angles_rate_maps(seq, a, gs, gb, det, stat)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. all(abs(w) <= huge(1.0_dp))) return
    stat = MBDK_ERR_SINGULAR_MATRIX
    if (.not. (abs(det) > MBDK_GIMBAL_TOL)) return
    g = gs
    if (body) g = gb
    ! the inverse of a 3 x 3 matrix with unit columns by its adjugate (det G_b = det G_s)
    adj(1, :) = mbdk_cross(g(:, 2), g(:, 3))
    adj(2, :) = mbdk_cross(g(:, 3), g(:, 1))
    adj(3, :) = mbdk_cross(g(:, 1), g(:, 2))
    ad = matmul(adj, w) / dot_product(g(:, 1), mbdk_cross(g(:, 2), g(:, 3)))
    stat = MBDK_SUCCESS
  end subroutine mbdk_angles_rates

  !> The cross product x × y.
  pure function mbdk_cross(x, y) result(z)
    real(dp), intent(in) :: x(3), y(3)
    real(dp) :: z(3)
    z = [x(2) * y(3) - x(3) * y(2), x(3) * y(1) - x(1) * y(3), x(1) * y(2) - x(2) * y(1)]
  end function mbdk_cross

  !> The quaternion product p q (scalar first).
  pure function mbdk_quat_mul(p, q) result(r)
    real(dp), intent(in) :: p(4), q(4)
    real(dp) :: r(4)
    r(1) = p(1) * q(1) - dot_product(p(2:4), q(2:4))
    r(2:4) = p(1) * q(2:4) + q(1) * p(2:4) + mbdk_cross(p(2:4), q(2:4))
  end function mbdk_quat_mul

  pure function mbdk_quat_conj(q) result(r)
    real(dp), intent(in) :: q(4)
    real(dp) :: r(4)
    r = [q(1), -q(2:4)]
  end function mbdk_quat_conj

  !> The rotation matrix of a unit quaternion; its norm off 1 by more than MBDK_UNIT_TOL:
  !> MBDK_ERR_INVALID_INPUT (a scene normalises nothing silently).
  pure subroutine mbdk_quat_matrix(q, r, stat)
    real(dp), intent(in) :: q(4)
    real(dp), intent(out) :: r(3, 3)
    integer, intent(out) :: stat
    integer :: i, j
    r = 0.0_dp
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. (abs(norm2(q) - 1.0_dp) <= MBDK_UNIT_TOL)) return
    r = mbdk_quat_matrix_of(q)
    stat = MBDK_SUCCESS
  end subroutine mbdk_quat_matrix

  !> The rotation matrix of the quaternion q, taken as unit without a check (the callers have
  !> checked or normalised it): (q0^2 - |v|^2) I + 2 v v^T + 2 q0 skew(v).
  pure function mbdk_quat_matrix_of(q) result(r)
    real(dp), intent(in) :: q(4)
    real(dp) :: r(3, 3)
    integer :: i, j
    do j = 1, 3
      do i = 1, 3
        r(i, j) = 2.0_dp * q(i + 1) * q(j + 1)
      end do
      r(j, j) = r(j, j) + q(1)**2 - sum(q(2:4)**2)
    end do
    r = r + 2.0_dp * q(1) * mbdk_skew(q(2:4))
  end function mbdk_quat_matrix_of

  !> R x by the sandwich product (0, R x) = q (0, x) q* of a unit quaternion.
  pure subroutine mbdk_quat_rotate(q, x, y, stat)
    real(dp), intent(in) :: q(4), x(3)
    real(dp), intent(out) :: y(3)
    integer, intent(out) :: stat
    real(dp) :: t(4)
    y = 0.0_dp
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. (abs(norm2(q) - 1.0_dp) <= MBDK_UNIT_TOL)) return
    t = mbdk_quat_mul(mbdk_quat_mul(q, [0.0_dp, x]), mbdk_quat_conj(q))
    y = t(2:4)
    stat = MBDK_SUCCESS
  end subroutine mbdk_quat_rotate

  !> Whether r is a rotation: R^T R = I within MBDK_UNIT_TOL and det R = +1.
  pure logical function mbdk_is_rotation(r)
    real(dp), intent(in) :: r(3, 3)
    real(dp) :: e(3, 3)
    integer :: i
    e = matmul(transpose(r), r)
    do i = 1, 3
      e(i, i) = e(i, i) - 1.0_dp
    end do
    mbdk_is_rotation = all(abs(e) <= MBDK_UNIT_TOL) .and. &
      dot_product(r(:, 1), mbdk_cross(r(:, 2), r(:, 3))) > 0.0_dp
  end function mbdk_is_rotation

  !> The unit quaternion of a rotation matrix with s >= 0 (Shepperd's method: from the largest
  !> of 1 + tr R, 1 + 2 R_ii - tr R, so that no component comes from a small difference).
  pure subroutine mbdk_quat_from_matrix(r, q, stat)
    real(dp), intent(in) :: r(3, 3)
    real(dp), intent(out) :: q(4)
    integer, intent(out) :: stat
    real(dp) :: t(4), f
    integer :: k, i, j, l
    q = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]
    stat = MBDK_ERR_INVALID_INPUT
    if (.not. mbdk_is_rotation(r)) return
    t(1) = 1.0_dp + r(1, 1) + r(2, 2) + r(3, 3)
    t(2) = 1.0_dp + 2.0_dp * r(1, 1) - (r(1, 1) + r(2, 2) + r(3, 3))
    t(3) = 1.0_dp + 2.0_dp * r(2, 2) - (r(1, 1) + r(2, 2) + r(3, 3))
    t(4) = 1.0_dp + 2.0_dp * r(3, 3) - (r(1, 1) + r(2, 2) + r(3, 3))
    k = maxloc(t, 1)
    f = 0.5_dp * sqrt(t(k))       ! |q_k|
    q(k) = f
    if (k == 1) then
      q(2) = (r(3, 2) - r(2, 3)) / (4.0_dp * f)
      q(3) = (r(1, 3) - r(3, 1)) / (4.0_dp * f)
      q(4) = (r(2, 1) - r(1, 2)) / (4.0_dp * f)
    else
      i = k - 1                   ! the vector component found, and the other two
      j = mod(i, 3) + 1
      l = mod(i + 1, 3) + 1
      q(1) = (r(l, j) - r(j, l)) / (4.0_dp * f)
      q(j + 1) = (r(j, i) + r(i, j)) / (4.0_dp * f)
      q(l + 1) = (r(l, i) + r(i, l)) / (4.0_dp * f)
    end if
    if (q(1) < 0.0_dp) q = -q
    q = q / norm2(q)
    stat = MBDK_SUCCESS
  end subroutine mbdk_quat_from_matrix

  !> The quaternion rates of an angular velocity w in the space frame (body = .false.:
  !> q' = (1/2) (0, w) q) or the body frame (q' = (1/2) q (0, w)).
  pure function mbdk_quat_rates(q, w, body) result(qd)
    real(dp), intent(in) :: q(4), w(3)
    logical, intent(in) :: body
    real(dp) :: qd(4)
    if (body) then
      qd = 0.5_dp * mbdk_quat_mul(q, [0.0_dp, w])
    else
      qd = 0.5_dp * mbdk_quat_mul([0.0_dp, w], q)
    end if
  end function mbdk_quat_rates

  !> The angular velocity of quaternion rates qd at a unit q: space frame 2 vec(qd q*), body
  !> frame 2 vec(q* qd).
  pure function mbdk_quat_omega(q, qd, body) result(w)
    real(dp), intent(in) :: q(4), qd(4)
    logical, intent(in) :: body
    real(dp) :: w(3), t(4)
    if (body) then
      t = mbdk_quat_mul(mbdk_quat_conj(q), qd)
    else
      t = mbdk_quat_mul(qd, mbdk_quat_conj(q))
    end if
    w = 2.0_dp * t(2:4)
  end function mbdk_quat_omega

  !> The rotation by angle phi about the axis e (any length but zero; normalised here):
  !> R = I + sin(phi) K + (1 - cos(phi)) K^2, K = skew(e / |e|).
  pure subroutine mbdk_rodrigues(e, phi, r, stat)
    real(dp), intent(in) :: e(3), phi
    real(dp), intent(out) :: r(3, 3)
    integer, intent(out) :: stat
    real(dp) :: k(3, 3), n
    integer :: i
    r = 0.0_dp
    stat = MBDK_ERR_INVALID_INPUT
    n = norm2(e)
    if (.not. (n > 0.0_dp .and. n <= huge(1.0_dp) .and. abs(phi) <= huge(1.0_dp))) return
    k = mbdk_skew(e / n)
    r = sin(phi) * k + (1.0_dp - cos(phi)) * matmul(k, k)
    do i = 1, 3
      r(i, i) = r(i, i) + 1.0_dp
    end do
    stat = MBDK_SUCCESS
  end subroutine mbdk_rodrigues

  !> The axis (unit) and angle in [0, pi] of a rotation matrix, through its quaternion (exact
  !> near pi, where acos((tr R - 1)/2) loses the axis); angle 0: the axis (1, 0, 0).
  pure subroutine mbdk_axis_angle_from_matrix(r, e, phi, stat)
    real(dp), intent(in) :: r(3, 3)
    real(dp), intent(out) :: e(3), phi
    integer, intent(out) :: stat
    real(dp) :: q(4), n
    e = [1.0_dp, 0.0_dp, 0.0_dp]
    phi = 0.0_dp
    call mbdk_quat_from_matrix(r, q, stat)
    if (stat /= MBDK_SUCCESS) return
    n = norm2(q(2:4))
    phi = 2.0_dp * atan2(n, q(1))
    if (n > 0.0_dp) e = q(2:4) / n
  end subroutine mbdk_axis_angle_from_matrix

end module mbdk_rotations
