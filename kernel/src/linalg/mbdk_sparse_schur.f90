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
  use mbdk_kinds, only: dp
  implicit none
  private
  public :: mbdk_sparse_schur_init, mbdk_sparse_schur_assemble, mbdk_sparse_d_times, &
    mbdk_sparse_w_residual, mbdk_sparse_dtd_add

  integer, parameter :: SLOTS = 6

  type, public :: mbdk_sparse_schur_t
    integer :: m = 0, nnz = 0, nent = 0
    !> nonzeros of row r: rptr(r) .. rptr(r+1)-1; flat index into dz, column, W of the column
    integer, allocatable :: rptr(:), rz(:), rcol(:)
    real(dp), allocatable :: rw(:)
    !> the same nonzeros by column c: cptr(c) .. cptr(c+1)-1; flat index into dz, row
    integer, allocatable :: cptr(:), cz(:), crow(:)
    !> entries of S: flat index epos(e) into s(m, m), terms eptr(e) .. eptr(e+1)-1, each the
    !> product dz(ta) * dz(tb) * tw
    integer, allocatable :: eptr(:), epos(:), ta(:), tb(:)
    real(dp), allocatable :: tw(:)
  end type mbdk_sparse_schur_t

contains

  !> The lists from the pattern col(6, m), nz(6, m) of mbdk_joints_pattern and the weight w(nc).
  subroutine mbdk_sparse_schur_init(sp, col, nz, w)
    type(mbdk_sparse_schur_t), intent(out) :: sp
    integer, intent(in) :: col(:, :)
    logical, intent(in) :: nz(:, :)
    real(dp), intent(in) :: w(:)
    integer :: m, r, k, i, j, a, b, ne, nt, pass, c
    m = size(col, 2)
    sp%m = m
    sp%nnz = count(nz)
    allocate (sp%rptr(m + 1), sp%rz(sp%nnz), sp%rcol(sp%nnz), sp%rw(sp%nnz))
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
    allocate (sp%cptr(size(w) + 1), sp%cz(sp%nnz), sp%crow(sp%nnz))
    b = 0
    do c = 1, size(w)
      sp%cptr(c) = b + 1
      do r = 1, m
        do a = sp%rptr(r), sp%rptr(r + 1) - 1
          if (sp%rcol(a) /= c) cycle
          b = b + 1
          sp%cz(b) = sp%rz(a)
          sp%crow(b) = r
        end do
      end do
    end do
    sp%cptr(size(w) + 1) = b + 1
    ! two passes: count, then fill
    do pass = 1, 2
      ne = 0
      nt = 0
      do j = 1, m
        do i = j, m
          if (pass == 2) sp%eptr(ne + 1) = nt + 1
          k = nt
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
          if (nt > k) then
            ne = ne + 1
            if (pass == 2) sp%epos(ne) = (j - 1) * m + i
          end if
        end do
      end do
      if (pass == 1) then
        sp%nent = ne
        allocate (sp%eptr(ne + 1), sp%epos(ne), sp%ta(nt), sp%tb(nt), sp%tw(nt))
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
    s(1:sp%m * sp%m) = 0.0_dp
    do e = 1, sp%nent
      x = 0.0_dp
      do t = sp%eptr(e), sp%eptr(e + 1) - 1
        x = x + dz(sp%ta(t)) * dz(sp%tb(t)) * sp%tw(t)
      end do
      s(sp%epos(e)) = x
    end do
  end subroutine mbdk_sparse_schur_assemble

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
