!> The four-bar linkage of Fekete (2023) 1.3 in the two coordinate sets besides absolute
!> coordinates: relative (1.28)-(1.29) and natural (1.30)-(1.31). The absolute form is the
!> built-in scene 'four_bar' (kernel/src/model); these two are the same mechanism written by hand,
!> so that the three descriptions can be cross-checked against each other.
!>
!> Mechanism: ground pivots A = (0, 0) and D = (d, 0); crank AB (length a, mass m1), coupler BC
!> (b, m2), rocker CD (c, m3), all uniform bars; gravity g along -y.
!> Parameters p = [a, b, c, d, m1, m2, m3, g, alpha, beta]; alpha, beta are Baumgarte terms
!> (0, 0: the plain reduction 3.28).
!>
!> relative, y = [phi1, phi2, phi3, phi1', phi2', phi3'] (n = 6). phi_i is the direction of the
!>   loop vector A->B, B->C, C->D, as in (1.29):
!>   Phi = [a cos phi1 + b cos phi2 + c cos phi3 - d;  a sin phi1 + b sin phi2 + c sin phi3].
!>   So phi3 is the rocker's absolute angle (D->C) plus pi. The mass matrix depends on q:
!>   M = [m1 a^2/3 + m2 a^2, m2 a b/2 cos(phi1-phi2), 0; ., m2 b^2/3, 0; 0, 0, m3 c^2/3],
!>   with the velocity terms k sin(phi1-phi2) [phi2'^2, -phi1'^2, 0], k = m2 a b / 2 (Lagrange).
!> natural, y = [xB, yB, xC, yC, xB', yB', xC', yC'] (n = 8), with (1.31):
!>   Phi = [|B - A|^2 - a^2;  |C - B|^2 - b^2;  |C - D|^2 - c^2].
!>   A uniform bar between points P, Q has T = (m/6)(|P'|^2 + P'.Q' + |Q'|^2), so M is constant:
!>   M = [(m1 + m2)/3 I, m2/6 I; m2/6 I, (m2 + m3)/3 I], and there are no velocity terms.
!>
!> Both are evaluated as the reduction (3.28): [M D^T; D 0][q''; lambda] = [Q - c; gamma - 2 alpha
!> Phi' - beta^2 Phi], solved with LAPACK's LU. The multipliers belong to these constraint
!> equations and are not the joint reactions of the absolute form (the natural form's rows are
!> squared lengths), so the cross-checks compare motion and energy, not multipliers.
module mbdk_four_bar_forms
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS
  use mbdk_lapack, only: mbdk_lu_factor, mbdk_lu_solve
  implicit none
  private

  public :: mbdk_four_bar_relative_rhs, mbdk_four_bar_natural_rhs, mbdk_four_bar_params_ok

contains

  !> True when there are 10 parameters and the lengths, pivot distance and masses are positive.
  pure logical function mbdk_four_bar_params_ok(p)
    real(dp), intent(in) :: p(:)
    mbdk_four_bar_params_ok = size(p) == 10
    if (.not. mbdk_four_bar_params_ok) return
    mbdk_four_bar_params_ok = all(p(1:7) > 0.0_dp)
  end function mbdk_four_bar_params_ok

  !> y' for the relative-coordinate form (n = 6).
  subroutine mbdk_four_bar_relative_rhs(p, y, f, stat)
    real(dp), intent(in) :: p(10), y(6)
    real(dp), intent(out) :: f(6)
    integer, intent(out) :: stat
    real(dp) :: a, b, c, d, m1, m2, m3, g, al, be, k, s12
    real(dp) :: cs(3), sn(3), w(3), len(3), kkt(5, 5), rhs(5), phi(2), dphi(2)
    integer :: ipiv(5)

    a = p(1); b = p(2); c = p(3); d = p(4); m1 = p(5); m2 = p(6); m3 = p(7); g = p(8)
    al = p(9); be = p(10)
    cs = cos(y(1:3)); sn = sin(y(1:3)); w = y(4:6); len = [a, b, c]
    k = 0.5_dp * m2 * a * b
    s12 = sin(y(1) - y(2))

    kkt = 0.0_dp
    kkt(1, 1) = m1 * a**2 / 3.0_dp + m2 * a**2
    kkt(1, 2) = k * cos(y(1) - y(2))
    kkt(2, 1) = kkt(1, 2)
    kkt(2, 2) = m2 * b**2 / 3.0_dp
    kkt(3, 3) = m3 * c**2 / 3.0_dp
    ! D = dPhi/dq, rows 4:5 and its transpose in columns 4:5
    kkt(4, 1:3) = -len * sn
    kkt(5, 1:3) = len * cs
    kkt(1:3, 4) = kkt(4, 1:3)
    kkt(1:3, 5) = kkt(5, 1:3)

    ! Q - c: gravity (-dV/dq) and the velocity terms of the coupler's kinetic energy
    rhs(1) = -g * cs(1) * (0.5_dp * m1 * a + m2 * a) - k * s12 * w(2)**2
    rhs(2) = -g * 0.5_dp * m2 * b * cs(2) + k * s12 * w(1)**2
    rhs(3) = g * 0.5_dp * m3 * c * cs(3)
    ! gamma = -(D' q'), then the Baumgarte terms
    phi = [sum(len * cs) - d, sum(len * sn)]
    dphi = [-sum(len * sn * w), sum(len * cs * w)]
    rhs(4) = sum(len * cs * w**2) - 2.0_dp * al * dphi(1) - be**2 * phi(1)
    rhs(5) = sum(len * sn * w**2) - 2.0_dp * al * dphi(2) - be**2 * phi(2)

    call mbdk_lu_factor(kkt, ipiv, stat)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_lu_solve(kkt, ipiv, rhs, stat)
    if (stat /= MBDK_SUCCESS) return
    f(1:3) = w
    f(4:6) = rhs(1:3)
  end subroutine mbdk_four_bar_relative_rhs

  !> y' for the natural-coordinate form (n = 8).
  subroutine mbdk_four_bar_natural_rhs(p, y, f, stat)
    real(dp), intent(in) :: p(10), y(8)
    real(dp), intent(out) :: f(8)
    integer, intent(out) :: stat
    real(dp) :: a, b, c, d, m1, m2, m3, g, al, be
    real(dp) :: rb(2), rc(2), vb(2), vc(2), e1(2), e2(2), e3(2), kkt(7, 7), rhs(7)
    real(dp) :: phi(3), dphi(3)
    integer :: ipiv(7), i

    a = p(1); b = p(2); c = p(3); d = p(4); m1 = p(5); m2 = p(6); m3 = p(7); g = p(8)
    al = p(9); be = p(10)
    rb = y(1:2); rc = y(3:4); vb = y(5:6); vc = y(7:8)
    e1 = rb; e2 = rc - rb; e3 = rc - [d, 0.0_dp]

    kkt = 0.0_dp
    do i = 1, 2
      kkt(i, i) = (m1 + m2) / 3.0_dp
      kkt(i + 2, i + 2) = (m2 + m3) / 3.0_dp
      kkt(i, i + 2) = m2 / 6.0_dp
      kkt(i + 2, i) = m2 / 6.0_dp
    end do
    kkt(5, 1:2) = 2.0_dp * e1
    kkt(6, 1:2) = -2.0_dp * e2
    kkt(6, 3:4) = 2.0_dp * e2
    kkt(7, 3:4) = 2.0_dp * e3
    kkt(1:4, 5:7) = transpose(kkt(5:7, 1:4))

    rhs(1:4) = [0.0_dp, -0.5_dp * g * (m1 + m2), 0.0_dp, -0.5_dp * g * (m2 + m3)]
    phi = [dot_product(e1, e1) - a**2, dot_product(e2, e2) - b**2, dot_product(e3, e3) - c**2]
    dphi = 2.0_dp * [dot_product(e1, vb), dot_product(e2, vc - vb), dot_product(e3, vc)]
    rhs(5:7) = -2.0_dp * [dot_product(vb, vb), dot_product(vc - vb, vc - vb), dot_product(vc, vc)] &
               - 2.0_dp * al * dphi - be**2 * phi

    call mbdk_lu_factor(kkt, ipiv, stat)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_lu_solve(kkt, ipiv, rhs, stat)
    if (stat /= MBDK_SUCCESS) return
    f(1:4) = y(5:8)
    f(5:8) = rhs(1:4)
  end subroutine mbdk_four_bar_natural_rhs

end module mbdk_four_bar_forms
