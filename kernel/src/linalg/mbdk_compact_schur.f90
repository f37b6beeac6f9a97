!> S = C W C^T and its solves for a constraint Jacobian C whose rows each touch at most two
!> bodies, kept in compact rows: row k holds its nd values for body rbody(1, k), then its nd
!> values for body rbody(2, k) (body 0, the ground, has none: those values are zero and never
!> read); W is block diagonal by body (nd x nd blocks). A spatial chain's C, stored dense, is
!> 3N x 6N and S = C W C^T a dense 3N x 3N: memory N^2 and a factorisation N^3. In compact
!> rows C is 12 values a row, S has a nonzero only where two rows share a body (nine a row on a
!> chain of spherical joints), and its LDL^T under AMD (mbdk_sparse_ldlt) has no fill on a tree
!> and little on a loop: an evaluation costs O(m).
!>
!> Use: mbdk_compact_schur_init once per set of rows (the pattern of S, its ordering and
!> symbolic factorisation), then per evaluation mbdk_compact_schur_factor with C's values and a
!> W (any number of times, with different Ws: the pattern stays), mbdk_compact_schur_solve for
!> S x = b, and mbdk_compact_schur_spread for W C^T x (the correction of the velocities or
!> accelerations a multiplier vector makes). A pivot |d_k| at or below tol times S's own
!> diagonal entry of that row is MBDK_ERR_SINGULAR_MATRIX (mbdk_sparse_ldlt_factor): dependent
!> rows. With near, a least pivot ratio inside that wider window counts too, against the
!> ratios met before (mbdk_sparse_ldlt_near). The pivots are taken in AMD's order, not C's:
!> the ratios, and so where a near test trips on the way to a rank loss, differ from a dense
!> Cholesky's in C's order: driven towards a rank loss, the two paths may name it a step
!> apart, each at a pose whose pivots have fallen to the same window.
module mbdk_compact_schur
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT, MBDK_ERR_SINGULAR_MATRIX
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_sparse_ldlt, only: mbdk_sparse_ldlt_t, mbdk_sparse_ldlt_analyze, &
    mbdk_sparse_ldlt_factor, mbdk_sparse_ldlt_solve, mbdk_sparse_ldlt_near, &
    MBDK_SPARSE_NEAR_BASELINE
  implicit none
  private

  public :: mbdk_compact_schur_init, mbdk_compact_schur_factor, mbdk_compact_schur_solve, &
    mbdk_compact_schur_spread

  type, public :: mbdk_compact_schur_t
    integer :: m = 0, nd = 0, nb = 0
    integer, allocatable :: rbody(:, :)      !< (2, m): the bodies of each row's two blocks
    integer, allocatable :: ap(:), ai(:)     !< S's pattern, CSC 1-based, both triangles
    !> per stored entry (i = ai(e), j its column): the block pairs (a, b) of rows i and j on
    !> the same body, a of row i, b of row j, twice at most (a row pair on the same two
    !> bodies); 0: none
    integer, allocatable :: pair(:, :)
    !> per stored entry (i, j), the entry (j, i): S is symmetric, its upper triangle is copied
    integer, allocatable :: mirror(:)
    real(dp), allocatable :: wc(:, :)        !< (2 nd, m): W times each row's blocks
    real(dp), allocatable :: ct(:, :)        !< (2 nd, m): the rows themselves, by column
    logical :: split = .false.               !< the last factorisation's W a rigid body's
    !> the largest least pivot ratio of the factorisations tested for nearness so far: their
    !> baseline (mbdk_compact_schur_factor's near, mbdk_sparse_ldlt_near)
    real(dp) :: rmin_max = 0.0_dp
    type(mbdk_sparse_ldlt_t) :: ldlt
  end type mbdk_compact_schur_t

contains

  !> The pattern of S for rows on the bodies rbody(2, m) (0: the ground; nb bodies, nd columns
  !> a body), its ordering and symbolic factorisation. A row on two ground blocks, or on one
  !> body twice, is MBDK_ERR_INVALID_INPUT. MBDK_ERR_NO_MEMORY: asked gets the bytes.
  subroutine mbdk_compact_schur_init(s, rbody, nb, nd, stat, asked)
    type(mbdk_compact_schur_t), intent(out) :: s
    integer, intent(in) :: rbody(:, :), nb, nd
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer, allocatable :: first(:), next(:), mark(:)
    integer :: m, i, j, k, a, b, e, nnz, astat, body
    stat = MBDK_ERR_INVALID_INPUT
    m = size(rbody, 2)
    if (m < 1 .or. size(rbody, 1) /= 2 .or. nd < 1 .or. nb < 1) return
    if (any(rbody < 0) .or. any(rbody > nb)) return
    do k = 1, m
      if (rbody(1, k) == rbody(2, k)) return
    end do
    s%m = m
    s%nd = nd
    s%nb = nb
    ! the rows on each body, as linked lists (first(b), next(2 (k - 1) + a) for block a of row k)
    allocate (s%rbody(2, m), first(nb), next(2 * m), mark(m), s%ap(m + 1), s%wc(2 * nd, m), &
              s%ct(2 * nd, m), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (real(nb, dp) + 6.0_dp * m + 1) + &
                           MBDK_REAL_BYTES * 4.0_dp * nd * m, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    s%rbody = rbody
    first = 0
    do k = m, 1, -1
      do a = 2, 1, -1
        body = rbody(a, k)
        if (body == 0) cycle
        next(2 * (k - 1) + a) = first(body)
        first(body) = 2 * (k - 1) + a
      end do
    end do
    ! column j of S: every row sharing a body with row j, counted, then listed
    mark = 0
    nnz = 0
    do j = 1, m
      call visit(j, count_only=.true.)
    end do
    allocate (s%ai(nnz), s%pair(4, nnz), s%mirror(nnz), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * 6.0_dp * nnz, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    s%pair = 0
    mark = 0
    e = 0
    s%ap(1) = 1
    do j = 1, m
      call visit(j, count_only=.false.)
      s%ap(j + 1) = e + 1
    end do
    ! the mirror of each entry: the pattern is symmetric, so (j, i) is in column i
    do j = 1, m
      do e = s%ap(j), s%ap(j + 1) - 1
        i = s%ai(e)
        do k = s%ap(i), s%ap(i + 1) - 1
          if (s%ai(k) == j) exit
        end do
        s%mirror(e) = k
      end do
    end do
    call mbdk_sparse_ldlt_analyze(s%ldlt, m, s%ap, s%ai, stat, asked)

  contains

    !> the rows meeting row j on one of its bodies: counted (nnz), or stored as column j
    !> with their block pairs (e)
    subroutine visit(jj, count_only)
      integer, intent(in) :: jj
      logical, intent(in) :: count_only
      integer :: bj, node, ii, ai_, slot, col0
      col0 = 0
      if (.not. count_only) col0 = e
      do bj = 1, 2
        body = rbody(bj, jj)
        if (body == 0) cycle
        node = first(body)
        do while (node /= 0)
          ii = (node - 1) / 2 + 1
          ai_ = node - 2 * (ii - 1)
          if (count_only) then
            if (mark(ii) /= jj) then
              mark(ii) = jj
              nnz = nnz + 1
            end if
          else
            if (mark(ii) /= jj) then
              mark(ii) = jj
              e = e + 1
              s%ai(e) = ii
              slot = e
            else
              do slot = col0 + 1, e
                if (s%ai(slot) == ii) exit
              end do
            end if
            if (s%pair(1, slot) == 0) then
              s%pair(1:2, slot) = [ai_, bj]
            else
              s%pair(3:4, slot) = [ai_, bj]
            end if
          end if
          node = next(node)
        end do
      end do
    end subroutine visit

  end subroutine mbdk_compact_schur_init

  !> S = C W C^T from C's compact rows cc(m, 2 nd) and W's blocks w(nd, nd, nb), factorised;
  !> a pivot at or below tol of its row's diagonal entry: MBDK_ERR_SINGULAR_MATRIX (rmin: the
  !> least ratio).
  subroutine mbdk_compact_schur_factor(s, cc, w, tol, stat, rmin, rigid, near, near_rows)
    type(mbdk_compact_schur_t), intent(inout) :: s
    real(dp), intent(in) :: cc(:, :), w(:, :, :), tol
    integer, intent(out) :: stat
    real(dp), intent(out), optional :: rmin
    !> a window wider than tol in which the least pivot ratio also counts as singular (a pose
    !> near a rank loss), taken against the ratios met before (mbdk_sparse_ldlt_near, whose
    !> narrowest window is near_rows / m of it: the caller's sparse threshold)
    real(dp), intent(in), optional :: near
    integer, intent(in), optional :: near_rows
    !> W's blocks are a rigid body's (nd = 6): diagonal in the translations, nothing between
    !> translations and rotations; only those entries are read
    logical, intent(in), optional :: rigid
    integer :: k, a, b, e, j, nd, o, p, q, i, ra, rb
    real(dp) :: x, r
    nd = s%nd
    s%split = .false.
    if (present(rigid)) s%split = rigid .and. nd == 6
    associate (ct => s%ct, wc => s%wc, ax => s%ldlt%ax, ai => s%ai, pair => s%pair, &
               rbody => s%rbody)
      ! the rows by column (cc's rows are strided), and W times each block
      ct = transpose(cc)
      do k = 1, s%m
        do a = 1, 2
          o = nd * (a - 1)
          b = rbody(a, k)
          if (b == 0) then
            wc(o + 1:o + nd, k) = 0.0_dp
            cycle
          end if
          if (s%split) then
            ! W's block diag(w11, w22, w33) (+) its 3 x 3 rotational block
            do i = 1, 3
              wc(o + i, k) = w(i, i, b) * ct(o + i, k)
            end do
            do i = 4, 6
              wc(o + i, k) = w(i, 4, b) * ct(o + 4, k) + w(i, 5, b) * ct(o + 5, k) + &
                             w(i, 6, b) * ct(o + 6, k)
            end do
          else
            do i = 1, nd
              x = 0.0_dp
              do q = 1, nd
                x = x + w(i, q, b) * ct(o + q, k)
              end do
              wc(o + i, k) = x
            end do
          end if
        end do
      end do
      ! the lower triangle and the diagonal, then the upper one by symmetry
      do j = 1, s%m
        do e = s%ap(j), s%ap(j + 1) - 1
          x = 0.0_dp
          i = ai(e)
          if (i < j) cycle
          do p = 1, 3, 2
            a = pair(p, e)
            if (a == 0) exit
            ra = nd * (a - 1)
            rb = nd * (pair(p + 1, e) - 1)
            if (nd == 6) then          ! a rigid body's six columns: the sum written out
              x = x + ct(ra + 1, i) * wc(rb + 1, j) + ct(ra + 2, i) * wc(rb + 2, j) + &
                  ct(ra + 3, i) * wc(rb + 3, j) + ct(ra + 4, i) * wc(rb + 4, j) + &
                  ct(ra + 5, i) * wc(rb + 5, j) + ct(ra + 6, i) * wc(rb + 6, j)
            else
              do q = 1, nd
                x = x + ct(ra + q, i) * wc(rb + q, j)
              end do
            end if
          end do
          ax(e) = x
        end do
      end do
      do j = 1, s%m
        do e = s%ap(j), s%ap(j + 1) - 1
          if (ai(e) < j) ax(e) = ax(s%mirror(e))
        end do
      end do
    end associate
    call mbdk_sparse_ldlt_factor(s%ldlt, tol, stat, r)
    if (present(rmin)) rmin = r
    if (stat /= MBDK_SUCCESS .or. .not. present(near)) return
    ! the record is of the factorisations tested for nearness (one W, the caller's choice)
    s%rmin_max = max(s%rmin_max, r)
    k = s%m
    if (present(near_rows)) k = near_rows
    if (mbdk_sparse_ldlt_near(r, s%rmin_max, near, s%m, k, MBDK_SPARSE_NEAR_BASELINE)) &
      stat = MBDK_ERR_SINGULAR_MATRIX
  end subroutine mbdk_compact_schur_factor

  !> x = S^-1 x with the factors of the last mbdk_compact_schur_factor.
  subroutine mbdk_compact_schur_solve(s, x)
    type(mbdk_compact_schur_t), intent(inout) :: s
    real(dp), intent(inout), contiguous :: x(:)
    call mbdk_sparse_ldlt_solve(s%ldlt, x)
  end subroutine mbdk_compact_schur_solve

  !> dx = W C^T x (nd nb values, body by body) with the W of the last factorisation.
  pure subroutine mbdk_compact_schur_spread(s, x, dx)
    type(mbdk_compact_schur_t), intent(in) :: s
    real(dp), intent(in) :: x(:)
    real(dp), intent(out) :: dx(:)
    integer :: k, a, b, nd
    nd = s%nd
    dx = 0.0_dp
    do k = 1, s%m
      do a = 1, 2
        b = s%rbody(a, k)
        if (b == 0) cycle
        dx(nd * (b - 1) + 1:nd * b) = dx(nd * (b - 1) + 1:nd * b) + &
                                      s%wc(nd * (a - 1) + 1:nd * a, k) * x(k)
      end do
    end do
  end subroutine mbdk_compact_schur_spread

end module mbdk_compact_schur
