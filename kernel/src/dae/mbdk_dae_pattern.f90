!> The sparsity of a mechanism's DAE Jacobian, Y = [q; v; lam_a (; mu_a)], from its body graph
!> (mbdk_mechanism's body_graph), and the colorings that let differences fill it: what bdf's
!> own Newton matrix (mbdk_mechanism_dae) and ida's sparse one (mbdk_ida) are built on.
!>
!>   unknowns   a body's coordinates, then its velocities (bidx(bptr(b) .. bptr(b+1)-1)); each
!>              active row's one or two bodies rb(:, i) (from its velocity columns)
!>   pattern    K over [q; v] in CSC (kap, kai: both triangles): a body's unknowns against its
!>              own and its neighbours' (the pairs an element couples: joints and two-body
!>              forces); D: nsets sets of na rows (lam, then mu), row k on all unknowns of
!>              its bodies (drcol(drptr(k) .. drptr(k+1)-1)). [K D^T; D 0] is then every
!>              term's dependence: a body's equations on its and its neighbours' unknowns and
!>              on the multipliers of the rows on it, a row's on its bodies' unknowns
!>              (mbdk_kkt_pattern orders or lists it)
!>   colors     of the bodies, distance-2 (mbdk_body_pattern_colors: the k-th unknown of all
!>              bodies of a color perturbed together changes no row twice), the bodies of
!>              color c cbody(cptr(c) .. cptr(c+1)-1); of the rows, no two of a color on one
!>              body (rrow(rptr(c) .. rptr(c+1)-1)): their multipliers perturbed together
!>              change each body's equations by one row's column
!> A chain has 3 body colors and (spherical joints) 6 row colors whatever its length; a hub,
!> a body coupled to many, makes the colors grow with its degree.
module mbdk_dae_pattern
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_mechanism, only: mbdk_mechanism_t
  use mbdk_memory, only: mbdk_alloc_status, MBDK_INT_BYTES
  use mbdk_body_pattern, only: mbdk_body_pattern_t, mbdk_body_pattern_init, &
    mbdk_body_pattern_colors, mbdk_group_by, mbdk_first_fit
  implicit none
  private
  public :: mbdk_dae_pattern_init

  type, public :: mbdk_dae_pattern_t
    !> bodies, [q; v] unknowns, active rows, sets of rows in D (1: lam; 2: lam and mu), the
    !> most unknowns of one body
    integer :: nb = 0, ny = 0, na = 0, nsets = 1, dmax = 0
    integer, allocatable :: bptr(:), bidx(:), rb(:, :)
    integer, allocatable :: kap(:), kai(:), drptr(:), drcol(:)
    integer, allocatable :: cptr(:), cbody(:), rptr(:), rrow(:)
  end type mbdk_dae_pattern_t

contains

  !> The pattern of mech's DAE with the active rows rows(na) and nsets sets of multipliers
  !> (module header). MBDK_ERR_NO_MEMORY (asked: the bytes).
  subroutine mbdk_dae_pattern_init(pat, mech, rows, nsets, stat, asked)
    type(mbdk_dae_pattern_t), intent(out) :: pat
    class(mbdk_mechanism_t), intent(in) :: mech
    integer, intent(in) :: rows(:), nsets
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer, allocatable :: qbody(:), vbody(:), pairs(:, :), grptr(:), grcol(:), fill(:)
    type(mbdk_body_pattern_t) :: bp
    integer :: nb, ncq, ny, na, i, j, b, r, astat
    call mech%body_graph(qbody, vbody, pairs, grptr, grcol, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    nb = mech%nb
    ncq = mech%ncoord
    ny = ncq + mech%nvel
    na = size(rows)
    pat%nb = nb
    pat%ny = ny
    pat%na = na
    pat%nsets = nsets
    allocate (pat%bptr(nb + 1), pat%bidx(ny), pat%rb(2, na), fill(nb), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (2.0_dp * nb + 1 + ny + 2.0_dp * na), stat, &
                           asked)
    if (astat /= 0) return
    ! each body's unknowns, its coordinates then its velocities
    pat%bptr = 0
    do i = 1, mech%nvel
      pat%bptr(vbody(i) + 1) = pat%bptr(vbody(i) + 1) + 1
    end do
    do i = 1, ncq
      pat%bptr(qbody(i) + 1) = pat%bptr(qbody(i) + 1) + 1
    end do
    pat%bptr(1) = 1
    do b = 1, nb
      pat%bptr(b + 1) = pat%bptr(b + 1) + pat%bptr(b)
    end do
    pat%dmax = maxval(pat%bptr(2:) - pat%bptr(:nb))
    fill = pat%bptr(1:nb)
    do i = 1, ny
      b = merge(qbody(min(i, ncq)), vbody(max(i - ncq, 1)), i <= ncq)
      pat%bidx(fill(b)) = i
      fill(b) = fill(b) + 1
    end do
    ! the bodies of each active row (from its columns: one or two)
    do i = 1, na
      r = rows(i)
      pat%rb(:, i) = 0
      do j = grptr(r), grptr(r + 1) - 1
        b = vbody(grcol(j))
        if (pat%rb(1, i) == 0) then
          pat%rb(1, i) = b
        else if (pat%rb(1, i) /= b) then
          pat%rb(2, i) = b
        end if
      end do
    end do
    ! (the rows' pairs are joints: in pairs already)
    call mbdk_body_pattern_init(bp, nb, pairs, stat, asked, bs=1)
    if (stat /= MBDK_SUCCESS) return
    call k_pattern(pat, bp, qbody, vbody, ncq, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call d_rows(pat, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_body_pattern_colors(bp, pat%cptr, pat%cbody, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    call color_rows(na, pat%rb, nb, pat%rptr, pat%rrow, stat, asked)
  end subroutine mbdk_dae_pattern_init

  !> K's CSC over [q; v]: column j, an unknown of body b, holds the unknowns of b's neighbours
  !> (b among them) in the body pattern bp
  subroutine k_pattern(pat, bp, qbody, vbody, ncq, stat, asked)
    type(mbdk_dae_pattern_t), intent(inout) :: pat
    type(mbdk_body_pattern_t), intent(in) :: bp
    integer, intent(in) :: qbody(:), vbody(:), ncq
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nnz, b, a, p, j, k, na_, astat
    nnz = 0
    do b = 1, pat%nb
      do p = bp%bptr(b), bp%bptr(b + 1) - 1
        a = bp%nbr(p)
        nnz = nnz + (pat%bptr(b + 1) - pat%bptr(b)) * (pat%bptr(a + 1) - pat%bptr(a))
      end do
    end do
    allocate (pat%kap(pat%ny + 1), pat%kai(nnz), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (pat%ny + 1.0_dp + nnz), stat, asked)
    if (astat /= 0) return
    p = 0
    do j = 1, pat%ny
      pat%kap(j) = p + 1
      b = merge(qbody(min(j, ncq)), vbody(max(j - ncq, 1)), j <= ncq)
      do k = bp%bptr(b), bp%bptr(b + 1) - 1
        a = bp%nbr(k)
        na_ = pat%bptr(a + 1) - pat%bptr(a)
        pat%kai(p + 1:p + na_) = pat%bidx(pat%bptr(a):pat%bptr(a + 1) - 1)
        p = p + na_
      end do
    end do
    pat%kap(pat%ny + 1) = p + 1
  end subroutine k_pattern

  !> D's rows: nsets sets of the na rows, each on all unknowns of its bodies
  subroutine d_rows(pat, stat, asked)
    type(mbdk_dae_pattern_t), intent(inout) :: pat
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nd, k, i, j, b, p, nb_, astat
    nd = pat%nsets * pat%na
    p = 0
    do i = 1, pat%na
      do j = 1, 2
        if (pat%rb(j, i) > 0) p = p + pat%bptr(pat%rb(j, i) + 1) - pat%bptr(pat%rb(j, i))
      end do
    end do
    allocate (pat%drptr(nd + 1), pat%drcol(p * pat%nsets), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (nd + 1.0_dp + real(p, dp) * pat%nsets), &
                           stat, asked)
    if (astat /= 0) return
    p = 0
    do k = 1, nd
      i = mod(k - 1, pat%na) + 1
      pat%drptr(k) = p + 1
      do j = 1, 2
        b = pat%rb(j, i)
        if (b == 0) cycle
        nb_ = pat%bptr(b + 1) - pat%bptr(b)
        pat%drcol(p + 1:p + nb_) = pat%bidx(pat%bptr(b):pat%bptr(b + 1) - 1)
        p = p + nb_
      end do
    end do
    pat%drptr(nd + 1) = p + 1
  end subroutine d_rows

  !> A coloring of the rows i = 1..na on the bodies rb(:, i) (0: the ground; nb bodies),
  !> greedy: no two rows of a color on one body. The rows of color k: rrow(rptr(k) ..
  !> rptr(k+1)-1).
  subroutine color_rows(na, rb, nb, rptr, rrow, stat, asked)
    integer, intent(in) :: na, rb(2, na), nb
    integer, allocatable, intent(out) :: rptr(:), rrow(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer, allocatable :: color(:), seen(:), brptr(:), brow(:), key(:), item(:)
    integer :: i, j, b, p, ncol, n, astat
    allocate (color(na), seen(na + 1), key(2 * na), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (4.0_dp * na + 1), stat, asked)
    if (astat /= 0) return
    ! each body's rows: the row's bodies grouped (item k is row (k + 1) / 2's j-th body, j =
    ! 2 - mod(k, 2); the ground's entries, key nb + 1, fall in a group of their own)
    do i = 1, na
      do j = 1, 2
        key(2 * (i - 1) + j) = merge(rb(j, i), nb + 1, rb(j, i) > 0)
      end do
    end do
    call mbdk_group_by(key, nb + 1, brptr, item, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    n = size(item)
    allocate (brow(n), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * real(n, dp), stat, asked)
    if (astat /= 0) return
    brow = (item + 1) / 2
    color = 0
    seen = 0
    ncol = 0
    do i = 1, na
      do j = 1, 2
        b = rb(j, i)
        if (b == 0) cycle
        do p = brptr(b), brptr(b + 1) - 1
          if (color(brow(p)) > 0) seen(color(brow(p))) = i
        end do
      end do
      color(i) = mbdk_first_fit(seen, i)
      ncol = max(ncol, color(i))
    end do
    call mbdk_group_by(color, ncol, rptr, rrow, stat, asked)
  end subroutine color_rows

end module mbdk_dae_pattern
