!> The Schur complement S = D W D^T of a sparse constraint Jacobian and a diagonal weight W
!> (W = M^-1 for the constrained accelerations, the projection weight for projections), built
!> from the nonzeros of D only.
!>
!>   M a + D^T lam = f,  D a = r   <=>   S lam = D W f - r,  a = W (f - D^T lam)
!>
!> D comes in the compact rows of mbdk_joints: dz(6, m), slot k of row r in column col(k, r).
!> mbdk_sparse_schur_init turns the pattern (col, nz) into lists, once per model: the nonzeros
!> of each row, and every entry S(i, j), i >= j, that two rows sharing a column make nonzero,
!> with its terms dz(k, i) W(c) dz(l, j). A double pendulum's D (4 x 6) has 12 nonzeros and
!> its S 21 terms, against 4 x 6 x 10 = 240 products of the dense S = D W D^T; the assembly
!> then costs a few dozen multiply-adds whatever the number of bodies not involved.
!> Two slots of one row in the same column (a joint between a body and itself) add up, as D.
module mbdk_sparse_schur
  use mbdk_kinds, only: dp, i8
  use mbdk_status, only: MBDK_SUCCESS
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  implicit none
  private
  public :: mbdk_sparse_schur_init, mbdk_sparse_schur_assemble, mbdk_sparse_d_times, &
    mbdk_sparse_d_abs_times, mbdk_sparse_schur_csc, mbdk_sparse_schur_assemble_csc, &
    mbdk_sort_ints, mbdk_sparse_w_residual, mbdk_sparse_dtd_add

  integer, parameter :: SLOTS = 6

  type, public :: mbdk_sparse_schur_t
    integer :: m = 0, nnz = 0, nent = 0
    !> nonzeros of row r: rptr(r) .. rptr(r+1)-1; flat index into dz, column, W of the column
    integer, allocatable :: rptr(:), rz(:), rcol(:)
    real(dp), allocatable :: rw(:)
    !> the same nonzeros by column c: cptr(c) .. cptr(c+1)-1; flat index into dz, row
    integer, allocatable :: cptr(:), cz(:), crow(:)
    !> entries S(ei(e), ej(e)), ei >= ej, column by column with rows ascending: terms
    !> eptr(e) .. eptr(e+1)-1, each the product dz(ta) * dz(tb) * tw
    integer, allocatable :: eptr(:), ei(:), ej(:), ta(:), tb(:)
    real(dp), allocatable :: tw(:)
  end type mbdk_sparse_schur_t

contains

  !> The lists from the pattern col(6, m), nz(6, m) of mbdk_joints_pattern and the weight w(nc).
  !> stat: MBDK_SUCCESS or MBDK_ERR_NO_MEMORY (asked: the bytes, mbdk_memory).
  subroutine mbdk_sparse_schur_init(sp, col, nz, w, stat, asked)
    type(mbdk_sparse_schur_t), intent(out) :: sp
    integer, intent(in) :: col(:, :)
    logical, intent(in) :: nz(:, :)
    real(dp), intent(in) :: w(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: m, r, k, i, j, a, b, ne, nt, pass, c, nc, nl, astat
    integer, allocatable :: next(:), mark(:), first(:)
    m = size(col, 2)
    sp%m = m
    sp%nnz = count(nz)
    nc = size(w)
    allocate (sp%rptr(m + 1), sp%rz(sp%nnz), sp%rcol(sp%nnz), sp%rw(sp%nnz), sp%cptr(nc + 1), &
              sp%cz(sp%nnz), sp%crow(sp%nnz), next(nc + 1), mark(m), first(m), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (3.0_dp * m + 2.0_dp * nc + 5.0_dp * sp%nnz &
                                                    + 3) + MBDK_REAL_BYTES * sp%nnz, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    a = 0
    do r = 1, m
      sp%rptr(r) = a + 1
      do k = 1, SLOTS
        if (.not. nz(k, r)) cycle
        a = a + 1
        sp%rz(a) = (r - 1) * SLOTS + k
        sp%rcol(a) = col(k, r)
        sp%rw(a) = w(col(k, r))
      end do
    end do
    sp%rptr(m + 1) = a + 1
    ! the nonzeros by column: a counting sort of the row lists (rows ascending in a column)
    sp%cptr = 0
    do a = 1, sp%nnz
      sp%cptr(sp%rcol(a) + 1) = sp%cptr(sp%rcol(a) + 1) + 1
    end do
    sp%cptr(1) = 1
    do c = 1, nc
      sp%cptr(c + 1) = sp%cptr(c + 1) + sp%cptr(c)
    end do
    next = sp%cptr
    do r = 1, m
      do a = sp%rptr(r), sp%rptr(r + 1) - 1
        c = sp%rcol(a)
        sp%cz(next(c)) = sp%rz(a)
        sp%crow(next(c)) = r
        next(c) = next(c) + 1
      end do
    end do
    ! the entries S(i, j), i >= j, column j by column j: the rows i that share a column of D
    ! with row j, each once (mark(i) = j), with the terms of every shared column. Two passes:
    ! count, then fill. The cost is the sum over the columns of D of their nonzeros squared,
    ! O(nnz) for a mechanism (a column of D has as many nonzeros as joints on its body).
    do pass = 1, 2
      mark = 0
      ne = 0
      nt = 0
      do j = 1, m
        ! the rows i >= j sharing a column with row j, in order of first meeting
        nl = 0
        do b = sp%rptr(j), sp%rptr(j + 1) - 1
          c = sp%rcol(b)
          do k = sp%cptr(c), sp%cptr(c + 1) - 1
            i = sp%crow(k)
            if (i < j .or. mark(i) == j) cycle
            mark(i) = j
            nl = nl + 1
            first(nl) = i
          end do
        end do
        call mbdk_sort_ints(first(1:nl))
        do k = 1, nl
          i = first(k)
          ne = ne + 1
          if (pass == 2) then
            sp%eptr(ne) = nt + 1
            sp%ei(ne) = i
            sp%ej(ne) = j
          end if
          do a = sp%rptr(i), sp%rptr(i + 1) - 1
            do b = sp%rptr(j), sp%rptr(j + 1) - 1
              if (sp%rcol(a) /= sp%rcol(b)) cycle
              nt = nt + 1
              if (pass == 2) then
                sp%ta(nt) = sp%rz(a)
                sp%tb(nt) = sp%rz(b)
                sp%tw(nt) = sp%rw(a)
              end if
            end do
          end do
        end do
      end do
      if (pass == 1) then
        sp%nent = ne
        allocate (sp%eptr(ne + 1), sp%ei(ne), sp%ej(ne), sp%ta(nt), sp%tb(nt), sp%tw(nt), &
                  stat=astat)
        call mbdk_alloc_status(astat, MBDK_INT_BYTES * (3.0_dp * ne + 2.0_dp * nt + 1) + &
                               MBDK_REAL_BYTES * nt, stat, asked)
        if (stat /= MBDK_SUCCESS) return
      end if
    end do
    sp%eptr(ne + 1) = nt + 1
  end subroutine mbdk_sparse_schur_init

  !> The lower triangle of S = D W D^T into s (m x m, every other entry 0).
  pure subroutine mbdk_sparse_schur_assemble(sp, dz, s)
    type(mbdk_sparse_schur_t), intent(in) :: sp
    real(dp), intent(in) :: dz(*)
    real(dp), intent(out) :: s(*)
    integer :: e, t
    real(dp) :: x
    s(1:int(sp%m, i8) * sp%m) = 0.0_dp
    do e = 1, sp%nent
      x = 0.0_dp
      do t = sp%eptr(e), sp%eptr(e + 1) - 1
        x = x + dz(sp%ta(t)) * dz(sp%tb(t)) * sp%tw(t)
      end do
      s(sp%ei(e) + (sp%ej(e) - 1) * int(sp%m, i8)) = x
    end do
  end subroutine mbdk_sparse_schur_assemble

  !> The pattern of S, both triangles, as CSC (ap(m+1), ai) for mbdk_sparse_ldlt, and where
  !> each entry e goes in its values: lo(e) for S(ei, ej), up(e) for S(ej, ei) (the same slot on
  !> the diagonal).
  !> stat: MBDK_SUCCESS or MBDK_ERR_NO_MEMORY (asked: the bytes, mbdk_memory).
  subroutine mbdk_sparse_schur_csc(sp, ap, ai, lo, up, stat, asked)
    type(mbdk_sparse_schur_t), intent(in) :: sp
    integer, allocatable, intent(out) :: ap(:), ai(:), lo(:), up(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: e, i, j, k, astat
    integer, allocatable :: next(:)
    allocate (ap(sp%m + 1), lo(sp%nent), up(sp%nent), next(sp%m + 1), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (2.0_dp * sp%m + 2.0_dp * sp%nent + 2), stat, &
                           asked)
    if (stat /= MBDK_SUCCESS) return
    ap = 0
    do e = 1, sp%nent
      ap(sp%ej(e) + 1) = ap(sp%ej(e) + 1) + 1
      if (sp%ei(e) /= sp%ej(e)) ap(sp%ei(e) + 1) = ap(sp%ei(e) + 1) + 1
    end do
    ap(1) = 1
    do k = 1, sp%m
      ap(k + 1) = ap(k + 1) + ap(k)
    end do
    allocate (ai(ap(sp%m + 1) - 1), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (ap(sp%m + 1) - 1), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    next = ap
    do e = 1, sp%nent
      i = sp%ei(e)
      j = sp%ej(e)
      ai(next(j)) = i
      lo(e) = next(j)
      next(j) = next(j) + 1
      if (i /= j) then
        ai(next(i)) = j
        up(e) = next(i)
        next(i) = next(i) + 1
      else
        up(e) = lo(e)
      end if
    end do
  end subroutine mbdk_sparse_schur_csc

  !> The values of S = D W D^T into ax, in the layout of mbdk_sparse_schur_csc.
  pure subroutine mbdk_sparse_schur_assemble_csc(sp, dz, lo, up, ax)
    type(mbdk_sparse_schur_t), intent(in) :: sp
    real(dp), intent(in) :: dz(*)
    integer, intent(in) :: lo(:), up(:)
    real(dp), intent(inout) :: ax(:)
    integer :: e, t
    real(dp) :: x
    do e = 1, sp%nent
      x = 0.0_dp
      do t = sp%eptr(e), sp%eptr(e + 1) - 1
        x = x + dz(sp%ta(t)) * dz(sp%tb(t)) * sp%tw(t)
      end do
      ax(lo(e)) = x
      ax(up(e)) = x
    end do
  end subroutine mbdk_sparse_schur_assemble_csc

  !> Sorts a short list of integers ascending (insertion sort: the lists are a row's or a
  !> body's neighbours, a handful).
  pure subroutine mbdk_sort_ints(x)
    integer, intent(inout) :: x(:)
    integer :: i, k, v
    do i = 2, size(x)
      v = x(i)
      k = i - 1
      do while (k >= 1)
        if (x(k) <= v) exit
        x(k + 1) = x(k)
        k = k - 1
      end do
      x(k + 1) = v
    end do
  end subroutine mbdk_sort_ints

  !> y = D x, or y = D W x when weighted.
  pure subroutine mbdk_sparse_d_times(sp, dz, x, y, weighted)
    type(mbdk_sparse_schur_t), intent(in) :: sp
    real(dp), intent(in) :: dz(*), x(*)
    real(dp), intent(out) :: y(*)
    logical, intent(in) :: weighted
    integer :: r, a
    real(dp) :: z
    do r = 1, sp%m
      z = 0.0_dp
      if (weighted) then
        do a = sp%rptr(r), sp%rptr(r + 1) - 1
          z = z + dz(sp%rz(a)) * sp%rw(a) * x(sp%rcol(a))
        end do
      else
        do a = sp%rptr(r), sp%rptr(r + 1) - 1
          z = z + dz(sp%rz(a)) * x(sp%rcol(a))
        end do
      end if
      y(r) = z
    end do
  end subroutine mbdk_sparse_d_times

  !> y = |D| |x| (y of m), or with transpose |D|^T |x| (y of nc): the sizes of the products'
  !> terms, for roundoff bounds
  pure subroutine mbdk_sparse_d_abs_times(sp, dz, x, y, nc, transpose)
    type(mbdk_sparse_schur_t), intent(in) :: sp
    real(dp), intent(in) :: dz(*), x(*)
    real(dp), intent(out) :: y(*)
    integer, intent(in) :: nc
    logical, intent(in) :: transpose
    integer :: r, a, c, k
    if (transpose) then
      do c = 1, nc
        y(c) = 0.0_dp
        do k = sp%cptr(c), sp%cptr(c + 1) - 1
          y(c) = y(c) + abs(dz(sp%cz(k)) * x(sp%crow(k)))
        end do
      end do
    else
      do r = 1, sp%m
        y(r) = 0.0_dp
        do a = sp%rptr(r), sp%rptr(r + 1) - 1
          y(r) = y(r) + abs(dz(sp%rz(a)) * x(sp%rcol(a)))
        end do
      end do
    end if
  end subroutine mbdk_sparse_d_abs_times

  !> a = W (f - D^T lam), a(nc) (f absent: 0): with f the forces and lam the multipliers of
  !> S lam = D W f - r, the constrained accelerations; without f and with lam = S^-1 r, the
  !> least change (in the W^-1 norm) that moves D x by -r.
  pure subroutine mbdk_sparse_w_residual(sp, dz, w, lam, a, nc, f)
    type(mbdk_sparse_schur_t), intent(in) :: sp
    integer, intent(in) :: nc
    real(dp), intent(in) :: dz(*), w(nc), lam(*)
    real(dp), intent(out) :: a(nc)
    real(dp), intent(in), optional :: f(nc)
    integer :: c, k
    real(dp) :: x
    do c = 1, nc
      x = 0.0_dp
      if (present(f)) x = f(c)
      do k = sp%cptr(c), sp%cptr(c + 1) - 1
        x = x - dz(sp%cz(k)) * lam(sp%crow(k))
      end do
      a(c) = w(c) * x
    end do
  end subroutine mbdk_sparse_w_residual

  !> a(1:nc, 1:nc) += w D^T D, row by row over the pairs of nonzeros of each row (the penalty
  !> term of the augmented Lagrangian: a row with k nonzeros costs k^2, not nc^2 m).
  pure subroutine mbdk_sparse_dtd_add(sp, dz, w, a)
    type(mbdk_sparse_schur_t), intent(in) :: sp
    real(dp), intent(in) :: dz(*), w
    real(dp), intent(inout) :: a(:, :)
    integer :: r, i, j
    real(dp) :: x
    do r = 1, sp%m
      do j = sp%rptr(r), sp%rptr(r + 1) - 1
        x = w * dz(sp%rz(j))
        do i = sp%rptr(r), sp%rptr(r + 1) - 1
          a(sp%rcol(i), sp%rcol(j)) = a(sp%rcol(i), sp%rcol(j)) + dz(sp%rz(i)) * x
        end do
      end do
    end do
  end subroutine mbdk_sparse_dtd_add

end module mbdk_sparse_schur
