!> The sparse pattern and elimination order of the book scheme's Newton matrix
!>
!>   [K D^T; D 0]   (nc + m rows)
!>
!> as one symmetric matrix for mbdk_sparse_ldlt: K in a pattern given as CSC (a body pattern of
!> mbdk_body_pattern, any block size: planar and spatial bodies alike; or the coordinates and
!> velocities of a DAE's bodies, mbdk_dae_pattern), D's nonzeros given row by row by their
!> columns, and each row's own diagonal entry (zero). mbdk_kkt_pattern_csc gives the pattern
!> alone (ida's sparse matrix, which KLU orders and pivots itself). LDL^T without pivoting meets a zero pivot on a
!> constraint row taken before any coordinate it involves, so the order is AMD's on the whole
!> pattern with each constraint row moved to just after the last of its coordinates: every
!> coordinate's pivot is then one of K updated by the rows' contributions, every row's pivot
!> -D K^-1 D^T of what was eliminated before it, both of the right sign and away from zero
!> while K is positive definite and the rows independent (the index-3 Newton matrices of
!> mbdk_index3_matrix and of the spatial model's submodule mbdk_spatial_i3). A chain or tree
!> keeps AMD's fill: the factorisation is O(N).
module mbdk_kkt_pattern
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_sparse_ldlt, only: mbdk_sparse_ldlt_t, mbdk_sparse_ldlt_analyze, mbdk_sparse_ldlt_amd
  implicit none
  private
  public :: mbdk_kkt_pattern_init, mbdk_kkt_pattern_csc

contains

  !> The pattern of [K D^T; D 0] (K's of nc = size(kap) - 1 columns in kap, kai: CSC with
  !> both triangles, a diagonal entry in every column; row r of D with its nonzeros in the
  !> columns rcol(rptr(r) .. rptr(r+1)-1)), its order (module header) and ldl's symbolic
  !> factorisation. kpos(size(kai)): the place in ldl%ax of each of K's values; dpos_r and
  !> dpos_c (size(rcol)): of each nonzero of D in its row's column and in its coordinate's
  !> column (two nonzeros of a row in one column share their place). unsymmetric: ldl may
  !> factorise unsymmetric values too (mbdk_sparse_ldlt_factor_lu). stat: MBDK_SUCCESS,
  !> MBDK_ERR_INVALID_INPUT (AMD refused the pattern) or MBDK_ERR_NO_MEMORY (asked: the bytes).
  !> partner(r) = s > 0: row r, whose columns are row s's, is eliminated after s (where AMD
  !> put it before, the two trade places, which keeps the fill: the stabilised index-2 DAE's
  !> mu row after its lam row, mbdk_mechanism_dae, whose pivot is otherwise nearly zero).
  subroutine mbdk_kkt_pattern_init(kap, kai, rptr, rcol, ldl, kpos, dpos_r, dpos_c, stat, &
                                   asked, unsymmetric, partner)
    integer, intent(in) :: kap(:), kai(:), rptr(:), rcol(:)
    type(mbdk_sparse_ldlt_t), intent(out) :: ldl
    integer, allocatable, intent(out) :: kpos(:), dpos_r(:), dpos_c(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    logical, intent(in), optional :: unsymmetric
    integer, intent(in), optional :: partner(:)
    integer :: nc, m, n, c, r, j, k, p, astat
    integer, allocatable :: ap(:), ai(:), mark(:), perm(:), order(:), last(:), at(:), brow(:)
    nc = size(kap) - 1
    m = size(rptr) - 1
    n = nc + m
    call mbdk_kkt_pattern_csc(kap, kai, rptr, rcol, ap, ai, kpos, dpos_r, dpos_c, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    allocate (mark(n), perm(n), order(n), last(n), at(n), brow(n), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * 6.0_dp * n, stat, asked)
    if (astat /= 0) return
    p = ap(n + 1)
    ! AMD's order, each row moved to just after the last of its coordinates
    call mbdk_sparse_ldlt_amd(n, ap, ai(1:p - 1), perm, stat)
    if (stat /= MBDK_SUCCESS) return
    do k = 1, n
      at(perm(k)) = k
    end do
    last = 0
    do r = 1, m
      do j = rptr(r), rptr(r + 1) - 1
        last(nc + r) = max(last(nc + r), at(rcol(j)))
      end do
    end do
    ! a counting sort of the rows by last, stable in AMD's order (bucket k: at(mark(k) ..
    ! brow(k)-1)); then the nodes in AMD's order, each coordinate followed by its bucket
    mark = 0
    do k = 1, n
      if (perm(k) > nc) mark(max(1, last(perm(k)))) = mark(max(1, last(perm(k)))) + 1
    end do
    p = 1
    do k = 1, n
      j = mark(k)
      mark(k) = p
      p = p + j
    end do
    brow(1:n) = mark(1:n)
    do k = 1, n
      c = perm(k)
      if (c <= nc) cycle
      j = max(1, last(c))
      at(brow(j)) = c
      brow(j) = brow(j) + 1
    end do
    j = 0
    do k = 1, n
      c = perm(k)
      if (c <= nc) then
        j = j + 1
        order(j) = c
      end if
      do p = mark(k), brow(k) - 1
        j = j + 1
        order(j) = at(p)
      end do
    end do
    if (present(partner)) call after_partners(nc, partner, order, at)
    call mbdk_sparse_ldlt_analyze(ldl, n, ap, ai(1:ap(n + 1) - 1), stat, asked, order, &
                                  unsymmetric)

  end subroutine mbdk_kkt_pattern_init

  !> The CSC pattern ap(n+1), ai of [K D^T; D 0] (n = nc + m; K's of nc = size(kap) - 1
  !> columns in kap, kai, both triangles; row r of D with its nonzeros in the columns
  !> rcol(rptr(r) .. rptr(r+1)-1)), each column's K entries first, then its rows' (once each:
  !> two nonzeros of one row in one column share their place), a row's column its columns
  !> then its own diagonal. kpos, dpos_r, dpos_c as mbdk_kkt_pattern_init's. stat:
  !> MBDK_SUCCESS or MBDK_ERR_NO_MEMORY (asked: the bytes).
  subroutine mbdk_kkt_pattern_csc(kap, kai, rptr, rcol, ap, ai, kpos, dpos_r, dpos_c, stat, &
                                  asked)
    integer, intent(in) :: kap(:), kai(:), rptr(:), rcol(:)
    integer, allocatable, intent(out) :: ap(:), ai(:), kpos(:), dpos_r(:), dpos_c(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nc, knz, m, n, nnz, nd, c, r, j, k, p, astat
    integer, allocatable :: mark(:), brow(:), cptr(:), crow(:)
    nc = size(kap) - 1
    knz = size(kai)
    m = size(rptr) - 1
    n = nc + m
    nd = size(rcol)
    nnz = knz + 2 * nd + m
    allocate (ap(n + 1), ai(nnz), mark(n), brow(n), cptr(nc + 1), crow(nd), kpos(knz), &
              dpos_r(nd), dpos_c(nd), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (3.0_dp * n + nnz + knz + 3.0_dp * nd + &
                           nc + 2), stat, asked)
    if (astat /= 0) return
    ! D by columns (rows ascending in each)
    cptr = 0
    do j = 1, nd
      cptr(rcol(j) + 1) = cptr(rcol(j) + 1) + 1
    end do
    cptr(1) = 1
    do c = 1, nc
      cptr(c + 1) = cptr(c + 1) + cptr(c)
    end do
    brow(1:nc) = cptr(1:nc)
    do r = 1, m
      do j = rptr(r), rptr(r + 1) - 1
        crow(brow(rcol(j))) = r
        brow(rcol(j)) = brow(rcol(j)) + 1
      end do
    end do
    ! columns 1..nc: K's rows, then the constraint rows with a nonzero there (once each: two
    ! nonzeros of one row in one column add up)
    mark = 0
    p = 1
    do c = 1, nc
      ap(c) = p
      do k = kap(c), kap(c + 1) - 1
        ai(p) = kai(k)
        kpos(k) = p
        p = p + 1
      end do
      do k = cptr(c), cptr(c + 1) - 1
        r = nc + crow(k)
        if (mark(r) == c) cycle
        mark(r) = c
        ai(p) = r
        p = p + 1
      end do
    end do
    ! columns nc+1..n: each row's coordinates and its diagonal
    mark = 0
    do r = 1, m
      ap(nc + r) = p
      do j = rptr(r), rptr(r + 1) - 1
        c = rcol(j)
        if (mark(c) == r) cycle
        mark(c) = r
        ai(p) = c
        p = p + 1
      end do
      ai(p) = nc + r
      p = p + 1
    end do
    ap(n + 1) = p
    do r = 1, m
      do j = rptr(r), rptr(r + 1) - 1
        c = rcol(j)
        dpos_r(j) = find(ap(nc + r), ap(nc + r + 1) - 1, c)
        dpos_c(j) = find(ap(c), ap(c + 1) - 1, nc + r)
      end do
    end do

  contains

    !> the position of row i in ai(lo .. hi)
    integer function find(lo, hi, i)
      integer, intent(in) :: lo, hi, i
      do find = lo, hi
        if (ai(find) == i) return
      end do
      find = 0
    end function find

  end subroutine mbdk_kkt_pattern_csc

  !> order (the k-th node eliminated) with each row r (node nc + r) after its partner's row
  !> where it came before: the two trade places. at: work of size(order).
  pure subroutine after_partners(nc, partner, order, at)
    integer, intent(in) :: nc, partner(:)
    integer, intent(inout) :: order(:)
    integer, intent(out) :: at(:)
    integer :: k, j, r
    do k = 1, size(order)
      at(order(k)) = k
    end do
    do r = 1, size(partner)
      if (partner(r) < 1) cycle
      j = at(nc + partner(r))
      k = at(nc + r)
      if (k > j) cycle
      order(k) = nc + partner(r)
      order(j) = nc + r
      at(nc + r) = j
      at(nc + partner(r)) = k
    end do
  end subroutine after_partners

end module mbdk_kkt_pattern
