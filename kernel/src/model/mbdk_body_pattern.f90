!> The sparsity of a matrix over the bodies' coordinates (nc x nc, bs x bs blocks: bs = 3 for a
!> planar body's x, y, theta, 6 for a spatial body's velocities): block (a, b) is there when
!> a = b or an element couples bodies a and b (a joint, a two-point force). The tangent
!> matrices of a scene (M + s (K + alpha D^T D) + (h/2) C of trapezoidal_index3) have this
!> pattern: D^T D couples the bodies of each joint, K and C those of each element.
!>
!> The pattern is CSC with both triangles (what mbdk_sparse_ldlt takes): scalar column
!> j = bs (b - 1) + c holds, for each neighbour a of body b in ascending order, the rows
!> bs (a - 1) + 1..bs. mbdk_body_pattern_pos finds (i, j) by a binary search among the
!> neighbours of j's body; mbdk_body_pattern_scatter adds a planar element's dense 6 x 6 matrix
!> over the coordinates of its two bodies; mbdk_body_pattern_dtd gives the positions of the
!> products of a D^T D whose rows are listed by their columns. Building it costs
!> O(bodies + elements).
module mbdk_body_pattern
  use mbdk_kinds, only: dp
  use mbdk_sparse_schur, only: mbdk_sort_ints
  use mbdk_status, only: MBDK_SUCCESS
  use mbdk_memory, only: mbdk_alloc_status, MBDK_INT_BYTES
  implicit none
  private
  public :: mbdk_body_pattern_init, mbdk_body_pattern_pos, mbdk_body_pattern_scatter, &
    mbdk_body_pattern_dtd, mbdk_body_pattern_colors, mbdk_group_by, mbdk_first_fit

  type, public :: mbdk_body_pattern_t
    integer :: nb = 0, nc = 0, nnz = 0, bs = 3
    !> neighbours of body b (itself included): nbr(bptr(b) .. bptr(b+1)-1), ascending
    integer, allocatable :: bptr(:), nbr(:)
    !> CSC of the scalar matrix (1-based), and the position of the transpose of each entry
    integer, allocatable :: ap(:), ai(:), tpos(:)
  end type mbdk_body_pattern_t

contains

  !> The pattern of nb bodies of bs coordinates (default 3) coupled by the pairs pairs(2, k) (0:
  !> the ground, no coupling). stat: MBDK_SUCCESS or MBDK_ERR_NO_MEMORY (asked: the bytes,
  !> mbdk_memory).
  subroutine mbdk_body_pattern_init(bp, nb, pairs, stat, asked, bs)
    type(mbdk_body_pattern_t), intent(out) :: bp
    integer, intent(in) :: nb, pairs(:, :)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer, intent(in), optional :: bs
    integer :: k, a, b, n, j, c, i, p, astat, nd
    integer, allocatable :: cnt(:), fill(:)
    nd = 3
    if (present(bs)) nd = bs
    bp%bs = nd
    bp%nb = nb
    bp%nc = nd * nb
    ! adjacency, both directions, then sorted and made unique per body
    allocate (cnt(nb + 1), bp%bptr(nb + 1), fill(nb), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (3.0_dp * nb + 2), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    cnt = 1     ! the body itself
    do k = 1, size(pairs, 2)
      a = pairs(1, k)
      b = pairs(2, k)
      if (a < 1 .or. b < 1 .or. a == b) cycle
      cnt(a) = cnt(a) + 1
      cnt(b) = cnt(b) + 1
    end do
    bp%bptr(1) = 1
    do b = 1, nb
      bp%bptr(b + 1) = bp%bptr(b) + cnt(b)
    end do
    allocate (bp%nbr(bp%bptr(nb + 1) - 1), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (bp%bptr(nb + 1) - 1), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    fill = bp%bptr(1:nb)
    do b = 1, nb
      bp%nbr(fill(b)) = b
      fill(b) = fill(b) + 1
    end do
    do k = 1, size(pairs, 2)
      a = pairs(1, k)
      b = pairs(2, k)
      if (a < 1 .or. b < 1 .or. a == b) cycle
      bp%nbr(fill(a)) = b
      fill(a) = fill(a) + 1
      bp%nbr(fill(b)) = a
      fill(b) = fill(b) + 1
    end do
    ! sort and drop duplicates in place (two elements on the same pair of bodies)
    n = 0
    do b = 1, nb
      call mbdk_sort_ints(bp%nbr(bp%bptr(b):bp%bptr(b + 1) - 1))
      a = n
      do k = bp%bptr(b), bp%bptr(b + 1) - 1
        if (n > a) then
          if (bp%nbr(n) == bp%nbr(k)) cycle
        end if
        n = n + 1
        bp%nbr(n) = bp%nbr(k)
      end do
      bp%bptr(b) = a + 1
      cnt(b) = n - a
    end do
    bp%bptr(nb + 1) = n + 1
    bp%nbr = bp%nbr(1:n)
    ! the scalar CSC: nd columns per body, nd rows per neighbour
    bp%nnz = nd * nd * n
    allocate (bp%ap(bp%nc + 1), bp%ai(bp%nnz), bp%tpos(bp%nnz), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (bp%nc + 1.0_dp + 2.0_dp * bp%nnz), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    p = 1
    do b = 1, nb
      do c = 1, nd
        j = nd * (b - 1) + c
        bp%ap(j) = p
        do k = bp%bptr(b), bp%bptr(b + 1) - 1
          do i = 1, nd
            bp%ai(p) = nd * (bp%nbr(k) - 1) + i
            p = p + 1
          end do
        end do
      end do
    end do
    bp%ap(bp%nc + 1) = p
    do j = 1, bp%nc
      do p = bp%ap(j), bp%ap(j + 1) - 1
        bp%tpos(p) = mbdk_body_pattern_pos(bp, j, bp%ai(p))
      end do
    end do
  end subroutine mbdk_body_pattern_init

  !> The position of entry (i, j) in the values (0 when the pattern has no such entry).
  pure integer function mbdk_body_pattern_pos(bp, i, j) result(p)
    type(mbdk_body_pattern_t), intent(in) :: bp
    integer, intent(in) :: i, j
    integer :: a, b, lo, hi, mid
    a = (i - 1) / bp%bs + 1
    b = (j - 1) / bp%bs + 1
    lo = bp%bptr(b)
    hi = bp%bptr(b + 1) - 1
    p = 0
    do while (lo <= hi)
      mid = (lo + hi) / 2
      if (bp%nbr(mid) == a) then
        p = bp%ap(j) + bp%bs * (mid - bp%bptr(b)) + (i - bp%bs * (a - 1)) - 1
        return
      else if (bp%nbr(mid) < a) then
        lo = mid + 1
      else
        hi = mid - 1
      end if
    end do
  end function mbdk_body_pattern_pos

  !> ax += the element matrix ke(6, 6) over (x, y, theta) of body b1, then of body b2 (either
  !> 0: the ground, its rows and columns dropped; b1 = b2: both halves on that body); a planar
  !> pattern's (bs = 3).
  pure subroutine mbdk_body_pattern_scatter(bp, b1, b2, ke, ax)
    type(mbdk_body_pattern_t), intent(in) :: bp
    integer, intent(in) :: b1, b2
    real(dp), intent(in) :: ke(6, 6)
    real(dp), intent(inout) :: ax(:)
    integer :: bi, bj, ei, ej, i, j, p, bb(2)
    bb = [b1, b2]
    do ej = 1, 2
      bj = bb(ej)
      if (bj < 1) cycle
      do ei = 1, 2
        bi = bb(ei)
        if (bi < 1) cycle
        do j = 1, 3
          p = mbdk_body_pattern_pos(bp, 3 * (bi - 1) + 1, 3 * (bj - 1) + j)
          do i = 1, 3
            ax(p + i - 1) = ax(p + i - 1) + ke(3 * (ei - 1) + i, 3 * (ej - 1) + j)
          end do
        end do
      end do
    end do
  end subroutine mbdk_body_pattern_scatter

  !> The position in the values of each product of D^T D: row r of D has its nonzeros in the
  !> columns rcol(rptr(r) .. rptr(r+1)-1); pos lists, row by row, for each of its nonzeros j and
  !> then each i, the entry (rcol(i), rcol(j)). stat: MBDK_SUCCESS or MBDK_ERR_NO_MEMORY (asked:
  !> the bytes, mbdk_memory).
  subroutine mbdk_body_pattern_dtd(bp, rptr, rcol, pos, stat, asked)
    type(mbdk_body_pattern_t), intent(in) :: bp
    integer, intent(in) :: rptr(:), rcol(:)
    integer, allocatable, intent(out) :: pos(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: r, i, j, n, astat
    n = 0
    do r = 1, size(rptr) - 1
      n = n + (rptr(r + 1) - rptr(r))**2
    end do
    allocate (pos(n), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * n, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    n = 0
    do r = 1, size(rptr) - 1
      do j = rptr(r), rptr(r + 1) - 1
        do i = rptr(r), rptr(r + 1) - 1
          n = n + 1
          pos(n) = mbdk_body_pattern_pos(bp, rcol(i), rcol(j))
        end do
      end do
    end do
  end subroutine mbdk_body_pattern_dtd

  !> A distance-2 coloring of the body graph (greedy, in body order): no two bodies of a color
  !> are neighbours or share one, so that differences of the columns of a color's bodies
  !> taken together do not mix in any row (the index-3 and DAE Newton matrices). The bodies
  !> of color c: body(ptr(c) .. ptr(c+1)-1).
  subroutine mbdk_body_pattern_colors(bp, ptr, body, stat, asked)
    type(mbdk_body_pattern_t), intent(in) :: bp
    integer, allocatable, intent(out) :: ptr(:), body(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nb, b, a, c, p, p2, ncol, astat
    integer, allocatable :: color(:), seen(:)
    nb = bp%nb
    allocate (color(nb), seen(nb + 1), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (2.0_dp * nb + 1), stat, asked)
    if (astat /= 0) return
    color(:) = 0
    seen(:) = 0
    ncol = 0
    do b = 1, nb
      do p = bp%bptr(b), bp%bptr(b + 1) - 1
        a = bp%nbr(p)
        if (color(a) > 0) seen(color(a)) = b
        do p2 = bp%bptr(a), bp%bptr(a + 1) - 1
          c = bp%nbr(p2)
          if (color(c) > 0) seen(color(c)) = b
        end do
      end do
      color(b) = mbdk_first_fit(seen, b)
      ncol = max(ncol, color(b))
    end do
    call mbdk_group_by(color, ncol, ptr, body, stat, asked)
  end subroutine mbdk_body_pattern_colors

  !> A greedy coloring's choice for the item that marked with mark the colors it may not take
  !> (seen(c) = mark): the least color left. seen must have a color beyond the marked ones.
  pure integer function mbdk_first_fit(seen, mark) result(k)
    integer, intent(in) :: seen(:), mark
    k = 1
    do while (seen(k) == mark)
      k = k + 1
    end do
  end function mbdk_first_fit

  !> The items i = 1..size(key) grouped by key(i) in 1..nkey, in ascending order within a group
  !> (a counting sort): the items of key k are item(ptr(k) .. ptr(k+1)-1). stat: MBDK_SUCCESS
  !> or MBDK_ERR_NO_MEMORY (asked: the bytes).
  subroutine mbdk_group_by(key, nkey, ptr, item, stat, asked)
    integer, intent(in) :: key(:), nkey
    integer, allocatable, intent(out) :: ptr(:), item(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer, allocatable :: next(:)
    integer :: i, k, astat
    allocate (ptr(nkey + 1), item(size(key)), next(nkey), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (2.0_dp * nkey + 1 + size(key)), stat, asked)
    if (astat /= 0) return
    ptr = 0
    do i = 1, size(key)
      ptr(key(i) + 1) = ptr(key(i) + 1) + 1
    end do
    ptr(1) = 1
    do k = 1, nkey
      ptr(k + 1) = ptr(k + 1) + ptr(k)
    end do
    next = ptr(1:nkey)
    do i = 1, size(key)
      item(next(key(i))) = i
      next(key(i)) = next(key(i)) + 1
    end do
  end subroutine mbdk_group_by

end module mbdk_body_pattern
