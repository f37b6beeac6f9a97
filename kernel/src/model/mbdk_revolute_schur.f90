!> The constrained accelerations of scenes whose joints are all revolute, with the Schur
!> complement in closed form (the fast path of mbdk_model; the table-driven mbdk_sparse_schur
!> is the general one, and the two are checked against each other in tests/test_scenes.py).
!>
!> A revolute joint j between body b1 and body b2 (b2 = 0: the ground) has two rows,
!> Phi_j = P1 - P2 (Fekete (2023) section 1.3), and its rows of D are, per end e on body b with sign
!> sigma_e = +1 (body1) or -1 (body2),
!>
!>   D_je = sigma_e [ I2, p_e ],     p_e = perp(rho_e) = (-rho_y, rho_x),  rho_e = A(theta_b) s_e
!>
!> so with the diagonal weight W = M^-1 (w_m = 1/m_b twice, w_I = 1/J_b) every 2 x 2 block of
!> S = D W D^T is a sum over the bodies two joints share,
!>
!>   S_jk = sum_{e in j, f in k, body(e) = body(f) = b} sigma_e sigma_f (w_m,b I2 + w_I,b p_e p_f^T)
!>
!> (one term per pair of joint ends on a common body: a chain's S is block tridiagonal), and
!>
!>   S lam = D W f - r,    a = W (f - D^T lam),    (D^T lam)_b = sum_e sigma_e (lam_j, p_e . lam_j).
!>
!> mbdk_revolute_schur_init lists the pairs of ends of two different joints on a common body,
!> once per model, with their weights sigma_e sigma_f w; an evaluation
!> (mbdk_revolute_kinematics, then mbdk_revolute_solve) sums each diagonal block joint by
!> joint and each off-diagonal one pair by pair: the arithmetic of a hand-written reduction
!> of the mechanism, with no per-nonzero index lists and no compact rows of D. The solve is the
!> block LDL^T of mbdk_small_dense with the joints as 2 x 2 pivot blocks, written out for that
!> size (same singular test: dependent rows are MBDK_ERR_SINGULAR_MATRIX). A joint between a
!> body and itself (which scenes refuse) is left to the general path.
module mbdk_revolute_schur
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_SINGULAR_MATRIX
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_joints, only: MBDK_JOINT_REVOLUTE
  implicit none
  private
  public :: mbdk_revolute_schur_init, mbdk_revolute_kinematics, mbdk_revolute_solve

  type, public :: mbdk_revolute_schur_t
    integer :: nj = 0, npair = 0
    !> bodies of the two ends of each joint (b2 may be 0) and the points s1, s2 (for the
    !> ground end, the global point)
    integer, allocatable :: b(:, :)
    real(dp), allocatable :: pt(:, :)
    !> pairs of ends of joints j > k on a common body: flat position of the block S_jk in the
    !> storage of block2_solve, the two ends (2 j - 1 or 2 j: end 1 or 2 of joint j), and
    !> sigma_e sigma_f w_m, sigma_e sigma_f w_I of the body
    integer, allocatable :: ppos(:), pe(:), pf(:)
    real(dp), allocatable :: pwm(:), pwi(:)
  end type mbdk_revolute_schur_t

contains

  !> The lists of a model with joint table jint(4, nj), jreal(12, nj) (layout of mbdk_joints)
  !> and weights winv(3 nb). ok = .false. when a joint is not revolute or joins a body to
  !> itself (the caller then takes the general path). stat: MBDK_SUCCESS or MBDK_ERR_NO_MEMORY
  !> (asked: the bytes, mbdk_memory).
  subroutine mbdk_revolute_schur_init(rs, jint, jreal, winv, ok, stat, asked)
    type(mbdk_revolute_schur_t), intent(out) :: rs
    integer, intent(in) :: jint(:, :)
    real(dp), intent(in) :: jreal(:, :), winv(:)
    logical, intent(out) :: ok
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nj, j, k, e, f, bj, pass, np, astat
    real(dp) :: sg
    nj = size(jint, 2)
    stat = MBDK_SUCCESS
    ok = all(jint(1, :) == MBDK_JOINT_REVOLUTE .and. jint(2, :) /= jint(3, :))
    if (.not. ok) return
    rs%nj = nj
    allocate (rs%b(2, nj), rs%pt(4, nj), stat=astat)
    call mbdk_alloc_status(astat, (2 * MBDK_INT_BYTES + 4 * MBDK_REAL_BYTES) * nj, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    rs%b = jint(2:3, :)
    rs%pt = jreal(1:4, :)
    ! two passes: count, then fill
    do pass = 1, 2
      np = 0
      do j = 2, nj
        do k = 1, j - 1
          do e = 2 * j - 1, 2 * j
            bj = rs%b(2 - mod(e, 2), j)
            if (bj == 0) cycle
            do f = 2 * k - 1, 2 * k
              if (rs%b(2 - mod(f, 2), k) /= bj) cycle
              np = np + 1
              if (pass == 1) cycle
              sg = merge(1.0_dp, -1.0_dp, mod(e, 2) == mod(f, 2))
              rs%ppos(np) = 4 * ((j * (j - 1)) / 2 + k) - 3
              rs%pe(np) = e
              rs%pf(np) = f
              rs%pwm(np) = sg * winv(3 * bj - 2)
              rs%pwi(np) = sg * winv(3 * bj)
            end do
          end do
        end do
      end do
      if (pass == 1) then
        allocate (rs%ppos(np), rs%pe(np), rs%pf(np), rs%pwm(np), rs%pwi(np), stat=astat)
        call mbdk_alloc_status(astat, (3 * MBDK_INT_BYTES + 2 * MBDK_REAL_BYTES) * np, stat, &
                               asked)
        if (stat /= MBDK_SUCCESS) return
      end if
    end do
    rs%npair = np
  end subroutine mbdk_revolute_schur_init

  !> At (q, v), rot from mbdk_body_rotations: pp(2, 2 nj) = perp(rho) of every joint end (0
  !> on the ground), phi(m) = P1 - P2, gam(m) = w1^2 rho1 - w2^2 rho2 (so that Phi'' = D a -
  !> gamma) and the right-hand side rc(m) = gam - kv D v - kp phi of D a = rc (kv = kp = 0:
  !> the reduced form; 2 alpha and beta^2: Baumgarte's; D v = P1' - P2'). The joint points'
  !> kinematics of mbdk_body_point written out in scalars: through mbdk_body_point (two calls
  !> with small arrays per joint) the rk4 step measured 610-660 ns instead of 470-490.
  pure subroutine mbdk_revolute_kinematics(rs, rot, q, v, kv, kp, pp, phi, gam, rc)
    type(mbdk_revolute_schur_t), intent(in) :: rs
    real(dp), intent(in) :: rot(:, :), q(:), v(:), kv, kp
    real(dp), intent(out) :: pp(2, *), phi(*), gam(*), rc(*)
    integer :: j, b1, b2, r
    real(dp) :: c, sn, r1x, r1y, r2x, r2y, w1, w2, p1, p2, g1, g2, d1, d2
    do j = 1, rs%nj
      r = 2 * j - 1
      b1 = rs%b(1, j)
      b2 = rs%b(2, j)
      c = rot(1, b1)
      sn = rot(2, b1)
      r1x = c * rs%pt(1, j) - sn * rs%pt(2, j)
      r1y = sn * rs%pt(1, j) + c * rs%pt(2, j)
      w1 = v(3 * b1)
      pp(1, r) = -r1y
      pp(2, r) = r1x
      p1 = q(3 * b1 - 2) + r1x
      p2 = q(3 * b1 - 1) + r1y
      g1 = w1**2 * r1x
      g2 = w1**2 * r1y
      d1 = v(3 * b1 - 2) - w1 * r1y
      d2 = v(3 * b1 - 1) + w1 * r1x
      if (b2 > 0) then
        c = rot(1, b2)
        sn = rot(2, b2)
        r2x = c * rs%pt(3, j) - sn * rs%pt(4, j)
        r2y = sn * rs%pt(3, j) + c * rs%pt(4, j)
        w2 = v(3 * b2)
        pp(1, r + 1) = -r2y
        pp(2, r + 1) = r2x
        p1 = p1 - (q(3 * b2 - 2) + r2x)
        p2 = p2 - (q(3 * b2 - 1) + r2y)
        g1 = g1 - w2**2 * r2x
        g2 = g2 - w2**2 * r2y
        d1 = d1 - (v(3 * b2 - 2) - w2 * r2y)
        d2 = d2 - (v(3 * b2 - 1) + w2 * r2x)
      else
        pp(1, r + 1) = 0.0_dp
        pp(2, r + 1) = 0.0_dp
        p1 = p1 - rs%pt(3, j)
        p2 = p2 - rs%pt(4, j)
      end if
      phi(r) = p1
      phi(r + 1) = p2
      gam(r) = g1
      gam(r + 1) = g2
      rc(r) = g1 - kv * d1 - kp * p1
      rc(r + 1) = g2 - kv * d2 - kp * p2
    end do
  end subroutine mbdk_revolute_kinematics

  !> M a + D^T lam = f, D a = rc, with pp from mbdk_revolute_kinematics and winv = M^-1 (the
  !> weights of mbdk_revolute_schur_init): S lam = D W f - rc by block LDL^T, then
  !> a = W (f - D^T lam). s is a work array of at least 2 nj (nj + 1) entries (the block
  !> storage of block2_solve); tol the relative pivot of the singular test. Dependent rows:
  !> MBDK_ERR_SINGULAR_MATRIX, with a and lam undefined.
  pure subroutine mbdk_revolute_solve(rs, nc, pp, f, winv, rc, s, tol, a, lam, stat)
    type(mbdk_revolute_schur_t), intent(in) :: rs
    integer, intent(in) :: nc
    real(dp), intent(in) :: pp(2, *), f(nc), winv(nc), rc(*), tol
    real(dp), intent(inout) :: s(*)
    real(dp), intent(out) :: a(nc), lam(*)
    integer, intent(out) :: stat
    integer :: j, n, b, r, e, g, kk
    real(dp) :: x1, x2, c, w1, w2, wi
    ! per joint: the right-hand side D W f - rc and the diagonal block of S, end by end
    kk = 1
    do j = 1, rs%nj
      r = 2 * j - 1
      b = rs%b(1, j)
      w1 = winv(3 * b - 2)
      w2 = winv(3 * b - 1)
      wi = winv(3 * b)
      x1 = wi * f(3 * b)
      lam(r) = w1 * f(3 * b - 2) + x1 * pp(1, r) - rc(r)
      lam(r + 1) = w2 * f(3 * b - 1) + x1 * pp(2, r) - rc(r + 1)
      x1 = wi * pp(1, r)
      x2 = wi * pp(2, r)
      s(kk) = w1 + x1 * pp(1, r)
      s(kk + 1) = x1 * pp(2, r)
      s(kk + 3) = w2 + x2 * pp(2, r)
      b = rs%b(2, j)
      if (b > 0) then
        w1 = winv(3 * b - 2)
        w2 = winv(3 * b - 1)
        wi = winv(3 * b)
        x1 = wi * f(3 * b)
        lam(r) = lam(r) - (w1 * f(3 * b - 2) + x1 * pp(1, r + 1))
        lam(r + 1) = lam(r + 1) - (w2 * f(3 * b - 1) + x1 * pp(2, r + 1))
        x1 = wi * pp(1, r + 1)
        x2 = wi * pp(2, r + 1)
        s(kk) = s(kk) + (w1 + x1 * pp(1, r + 1))
        s(kk + 1) = s(kk + 1) + x1 * pp(2, r + 1)
        s(kk + 3) = s(kk + 3) + (w2 + x2 * pp(2, r + 1))
      end if
      kk = kk + 4 * (j + 1)
      ! the off-diagonal blocks of block row j + 1 (j of them), cleared for the pairs
      if (j < rs%nj) s(kk - 4 * j:kk - 1) = 0.0_dp
    end do
    ! the off-diagonal blocks: one 2 x 2 term per pair of ends of two joints on a common body
    do n = 1, rs%npair
      g = rs%ppos(n)
      e = rs%pe(n)
      r = rs%pf(n)
      c = rs%pwi(n)
      x1 = c * pp(1, r)
      x2 = c * pp(2, r)
      s(g) = s(g) + rs%pwm(n) + pp(1, e) * x1
      s(g + 1) = s(g + 1) + pp(2, e) * x1
      s(g + 2) = s(g + 2) + pp(1, e) * x2
      s(g + 3) = s(g + 3) + rs%pwm(n) + pp(2, e) * x2
    end do
    call block2_solve(s, rs%nj, tol, lam, stat)
    if (stat /= MBDK_SUCCESS) return
    ! a = W (f - D^T lam)
    a = f * winv
    do j = 1, rs%nj
      r = 2 * j - 1
      x1 = lam(r)
      x2 = lam(r + 1)
      b = rs%b(1, j)
      a(3 * b - 2) = a(3 * b - 2) - winv(3 * b - 2) * x1
      a(3 * b - 1) = a(3 * b - 1) - winv(3 * b - 1) * x2
      a(3 * b) = a(3 * b) - winv(3 * b) * (pp(1, r) * x1 + pp(2, r) * x2)
      b = rs%b(2, j)
      if (b > 0) then
        a(3 * b - 2) = a(3 * b - 2) + winv(3 * b - 2) * x1
        a(3 * b - 1) = a(3 * b - 1) + winv(3 * b - 1) * x2
        a(3 * b) = a(3 * b) + winv(3 * b) * (pp(1, r + 1) * x1 + pp(2, r + 1) * x2)
      end if
    end do
  end subroutine mbdk_revolute_solve

  !> Solves S x = b, b becoming x, by the block LDL^T of mbdk_small_ldlt_solve_once with 2 x 2
  !> pivot blocks, written out for that block size: the same arithmetic, the same singular test
  !> (a pivot of a block's scalar LDL^T at or below tol * its own row's original diagonal entry
  !> of S, so that a light body beside a heavy one is not taken for a dependent row). The
  !> lower block triangle of S is stored block by block, row by row: block (i, c), c <= i, is
  !> sb(1:4, i (i - 1) / 2 + c) = its entries 11, 21, 12, 22 (the diagonal blocks' 12 unread);
  !> b(1:2, i) is the right-hand side of joint i. sb is overwritten.
  pure subroutine block2_solve(sb, nj, tol, b, stat)
    integer, intent(in) :: nj
    real(dp), intent(inout) :: sb(4, *), b(2, nj)
    real(dp), intent(in) :: tol
    integer, intent(out) :: stat
    integer :: i, k, c, kk, ik, ic, ck
    ! the blocks' original diagonals, for the pivot test, in a fixed-size array (an automatic
    ! one costs a malloc per solve); beyond it (a revolute_schur solver forced on a long chain)
    ! the test takes the largest diagonal entry of S
    integer, parameter :: NKEEP = 32
    real(dp) :: t1, t2, det, y, i11, i21, i22, l11, l12, l21, l22, x1, x2, d0(2, NKEEP), dmax
    stat = MBDK_ERR_SINGULAR_MATRIX
    if (nj <= NKEEP) then
      kk = 0
      do k = 1, nj
        kk = kk + k
        d0(1, k) = tol * max(sb(1, kk), 0.0_dp)
        d0(2, k) = tol * max(sb(4, kk), 0.0_dp)
      end do
    else
      kk = 0
      dmax = 0.0_dp
      do k = 1, nj
        kk = kk + k
        dmax = max(dmax, sb(1, kk), sb(4, kk))
      end do
    end if
    kk = 0
    do k = 1, nj
      kk = kk + k                       ! block (k, k)
      if (nj <= NKEEP) then
        t1 = d0(1, k)
        t2 = d0(2, k)
      else
        t1 = tol * dmax
        t2 = t1
      end if
      if (.not. (sb(1, kk) > t1)) return
      det = sb(1, kk) * sb(4, kk) - sb(2, kk)**2
      if (.not. (det > t2 * sb(1, kk))) return
      y = 1.0_dp / det
      i11 = sb(4, kk) * y
      i21 = -sb(2, kk) * y
      i22 = sb(1, kk) * y
      sb(1, kk) = i11
      sb(2, kk) = i21
      sb(4, kk) = i22
      ik = kk + k                       ! block (k + 1, k); (i + 1, k) follows (i, k) by i
      do i = k + 1, nj
        ! L = S(i, k) B^-1; S(i, c) -= L S(c, k)^T for k < c <= i; b(i) -= L b(k)
        l11 = sb(1, ik) * i11 + sb(3, ik) * i21
        l12 = sb(1, ik) * i21 + sb(3, ik) * i22
        l21 = sb(2, ik) * i11 + sb(4, ik) * i21
        l22 = sb(2, ik) * i21 + sb(4, ik) * i22
        ic = ik                         ! block (i, c) = (i, k) + (c - k)
        ck = kk + k                     ! block (c, k)
        do c = k + 1, i
          ic = ic + 1
          sb(1, ic) = sb(1, ic) - (l11 * sb(1, ck) + l12 * sb(3, ck))
          sb(2, ic) = sb(2, ic) - (l21 * sb(1, ck) + l22 * sb(3, ck))
          sb(3, ic) = sb(3, ic) - (l11 * sb(2, ck) + l12 * sb(4, ck))
          sb(4, ic) = sb(4, ic) - (l21 * sb(2, ck) + l22 * sb(4, ck))
          ck = ck + c
        end do
        b(1, i) = b(1, i) - (l11 * b(1, k) + l12 * b(2, k))
        b(2, i) = b(2, i) - (l21 * b(1, k) + l22 * b(2, k))
        ik = ik + i
      end do
    end do
    ! back substitution: x(k) = B^-1 (b(k) - sum_{i > k} S(i, k)^T x(i))
    do k = nj, 1, -1
      kk = (k * (k + 1)) / 2
      x1 = b(1, k)
      x2 = b(2, k)
      ik = kk + k
      do i = k + 1, nj
        x1 = x1 - (sb(1, ik) * b(1, i) + sb(2, ik) * b(2, i))
        x2 = x2 - (sb(3, ik) * b(1, i) + sb(4, ik) * b(2, i))
        ik = ik + i
      end do
      b(1, k) = sb(1, kk) * x1 + sb(2, kk) * x2
      b(2, k) = sb(2, kk) * x1 + sb(4, kk) * x2
    end do
    stat = MBDK_SUCCESS
  end subroutine block2_solve

end module mbdk_revolute_schur
