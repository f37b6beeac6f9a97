!> A sparse symmetric matrix factorised as P A P^T = L D L^T, by SuiteSparse's AMD (the
!> fill-reducing ordering P) and LDL (Davis 2005, "Algorithm 849: a concise sparse Cholesky
!> factorization package"), both from Debian's libsuitesparse-dev.
!>
!> Why these two and not CHOLMOD or KLU: every array they use is the caller's, so the factors
!> live in Fortran allocatables owned by the object that holds them, freed with it, and an
!> evaluation allocates nothing. LDL is the up-looking, non-supernodal Cholesky: for the
!> matrices of a mechanism (a few nonzeros per row, the fill of a chain or tree zero under AMD,
!> a closed loop a little) its cost is O(nnz(L)) and its constant is small; a supernodal
!> factorisation pays off on denser matrices than these.
!>
!> Use: mbdk_sparse_ldlt_analyze once per pattern (the full pattern, both triangles, as CSC:
!> LDL reads the upper triangle of P A P^T, which is in either triangle of A), then for each
!> set of values mbdk_sparse_ldlt_factor and any number of mbdk_sparse_ldlt_solve.
!> Pivoting is the symmetric ordering only, as for the in-house block LDL^T. D W D^T is positive
!> definite (or singular, refused); trapezoidal_index3's M + s (K + alpha D^T D) is near the
!> solution, and an indefinite one is factorised as it is, which is stable as long as no pivot
!> is small: a pivot |d_k| at or below tol times its row's own diagonal |A_kk| (the part of row
!> k independent of the rows eliminated before it, whatever the rows' scales: the test of the
!> in-house LDL^T and of the LAPACK path), or a non-finite one, is MBDK_ERR_SINGULAR_MATRIX (for
!> S = D W D^T: dependent constraint rows). The least ratio |d_k| / |A_kk| is returned for the
!> callers' own, wider tests.
!>
!> A matrix symmetric in pattern but not in values (a Newton matrix whose tangent has a skew
!> part too large to drop: a spatial body's gyroscopic and rotational geometric terms against a
!> slender bar's small axial inertia) is factorised P A P^T = L D U by
!> mbdk_sparse_ldlt_factor_lu, on the same analysis (analyze with unsymmetric): without
!> pivoting, the fill of L D U is that of L D L^T and U^T has L's pattern, so U is kept in
!> L's positions (ux) and the solves are LDL's own with U's values for L^T's. Its numeric
!> phase is LDL's up-looking loop (ldl_numeric) done twice per row, for the column of D U
!> above the diagonal and the row of L D left of it; LDL has none for unsymmetric values, and
!> KLU or UMFPACK keep their factors in allocations of their own (see above).
module mbdk_sparse_ldlt
  use, intrinsic :: iso_c_binding, only: c_int, c_double, c_ptr, c_null_ptr
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_SINGULAR_MATRIX, MBDK_ERR_INVALID_INPUT, &
    MBDK_ERR_NO_MEMORY
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  implicit none
  private
  public :: mbdk_sparse_ldlt_analyze, mbdk_sparse_ldlt_factor, mbdk_sparse_ldlt_solve, &
    mbdk_sparse_ldlt_near, mbdk_sparse_ldlt_amd, mbdk_sparse_ldlt_factor_lu

  !> the least pivot ratio at which mbdk_sparse_ldlt_near keeps a caller's window whole
  real(dp), parameter, public :: MBDK_SPARSE_NEAR_BASELINE = 0.5_dp

  !> n, the pattern (0-based CSC, both triangles) and its values, the ordering and the factors
  type, public :: mbdk_sparse_ldlt_t
    integer :: n = 0
    integer(c_int), allocatable :: ap(:), ai(:)
    real(c_double), allocatable :: ax(:)
    integer(c_int), allocatable :: p(:), pinv(:), lp(:), parent(:), lnz(:), flag(:), &
      pattern(:), li(:)
    !> position in ax of each diagonal entry (0: structurally zero)
    integer, allocatable :: dpos(:)
    real(c_double), allocatable :: lx(:), d(:), y(:)
    !> unsymmetric values (analyze's unsymmetric): U in L's positions, the work vector of the
    !> rows of L D, the position in ax of each entry's transpose (1-based); lu: the current
    !> factors are L D U
    logical :: lu = .false.
    real(c_double), allocatable :: ux(:), z(:)
    integer, allocatable :: tpos(:)
  end type mbdk_sparse_ldlt_t

  interface
    integer(c_int) function amd_order(n, ap, ai, p, control, info) bind(C, name="amd_order")
      import :: c_int, c_ptr
      integer(c_int), value :: n
      integer(c_int), intent(in) :: ap(*), ai(*)
      integer(c_int), intent(out) :: p(*)
      type(c_ptr), value :: control, info
    end function amd_order
    subroutine ldl_symbolic(n, ap, ai, lp, parent, lnz, flag, p, pinv) bind(C, name="ldl_symbolic")
      import :: c_int
      integer(c_int), value :: n
      integer(c_int), intent(in) :: ap(*), ai(*), p(*)
      integer(c_int), intent(out) :: lp(*), parent(*), lnz(*), flag(*), pinv(*)
    end subroutine ldl_symbolic
    integer(c_int) function ldl_numeric(n, ap, ai, ax, lp, parent, lnz, li, lx, d, y, pattern, &
                                        flag, p, pinv) bind(C, name="ldl_numeric")
      import :: c_int, c_double
      integer(c_int), value :: n
      integer(c_int), intent(in) :: ap(*), ai(*), lp(*), parent(*), p(*), pinv(*)
      real(c_double), intent(in) :: ax(*)
      integer(c_int), intent(inout) :: lnz(*), li(*), pattern(*), flag(*)
      real(c_double), intent(inout) :: lx(*), d(*), y(*)
    end function ldl_numeric
    subroutine ldl_lsolve(n, x, lp, li, lx) bind(C, name="ldl_lsolve")
      import :: c_int, c_double
      integer(c_int), value :: n
      real(c_double), intent(inout) :: x(*)
      integer(c_int), intent(in) :: lp(*), li(*)
      real(c_double), intent(in) :: lx(*)
    end subroutine ldl_lsolve
    subroutine ldl_ltsolve(n, x, lp, li, lx) bind(C, name="ldl_ltsolve")
      import :: c_int, c_double
      integer(c_int), value :: n
      real(c_double), intent(inout) :: x(*)
      integer(c_int), intent(in) :: lp(*), li(*)
      real(c_double), intent(in) :: lx(*)
    end subroutine ldl_ltsolve
    subroutine ldl_dsolve(n, x, d) bind(C, name="ldl_dsolve")
      import :: c_int, c_double
      integer(c_int), value :: n
      real(c_double), intent(inout) :: x(*)
      real(c_double), intent(in) :: d(*)
    end subroutine ldl_dsolve
    subroutine ldl_perm(n, x, b, p) bind(C, name="ldl_perm")
      import :: c_int, c_double
      integer(c_int), value :: n
      real(c_double), intent(out) :: x(*)
      real(c_double), intent(in) :: b(*)
      integer(c_int), intent(in) :: p(*)
    end subroutine ldl_perm
    subroutine ldl_permt(n, x, b, p) bind(C, name="ldl_permt")
      import :: c_int, c_double
      integer(c_int), value :: n
      real(c_double), intent(out) :: x(*)
      real(c_double), intent(in) :: b(*)
      integer(c_int), intent(in) :: p(*)
    end subroutine ldl_permt
  end interface

contains

  !> AMD's ordering perm(n) (1-based: perm(k) the k-th node eliminated) of the pattern ap, ai
  !> (as mbdk_sparse_ldlt_analyze takes it), for a caller that adjusts it before the analysis.
  !> MBDK_ERR_INVALID_INPUT for a pattern AMD refuses, MBDK_ERR_NO_MEMORY for its workspace.
  subroutine mbdk_sparse_ldlt_amd(n, ap, ai, perm, stat)
    integer, intent(in) :: n, ap(:), ai(:)
    integer, intent(out) :: perm(:), stat
    integer(c_int), allocatable :: ap0(:), ai0(:), p0(:)
    integer :: astat, k
    integer, parameter :: AMD_OUT_OF_MEMORY = -1
    stat = MBDK_ERR_INVALID_INPUT
    if (n < 1 .or. size(ap) /= n + 1 .or. size(perm) /= n) return
    allocate (ap0(n + 1), ai0(ap(n + 1) - 1), p0(n), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (2.0_dp * n + ap(n + 1)), stat)
    if (stat /= MBDK_SUCCESS) return
    ap0 = ap - 1
    ai0 = ai(1:ap(n + 1) - 1) - 1
    k = amd_order(n, ap0, ai0, p0, c_null_ptr, c_null_ptr)
    stat = MBDK_ERR_INVALID_INPUT
    if (k == AMD_OUT_OF_MEMORY) stat = MBDK_ERR_NO_MEMORY
    if (k < 0) return
    perm = p0 + 1
    stat = MBDK_SUCCESS
  end subroutine mbdk_sparse_ldlt_amd

  !> The ordering and the pattern of L for the n x n matrix of pattern ap(n+1), ai(nnz) (1-based
  !> CSC, both triangles, each column's rows in any order, no duplicates). The values go into
  !> f%ax in the same order. The ordering is AMD's, or order(n) (1-based, the k-th node
  !> eliminated) where the caller gives one. unsymmetric: mbdk_sparse_ldlt_factor_lu may be
  !> used too (the pattern must then be symmetric: MBDK_ERR_INVALID_INPUT where an entry has
  !> no transpose). MBDK_ERR_INVALID_INPUT for a pattern AMD refuses; MBDK_ERR_NO_MEMORY
  !> (asked: the bytes, mbdk_memory; AMD's own workspace: 0, not known).
  subroutine mbdk_sparse_ldlt_analyze(f, n, ap, ai, stat, asked, order, unsymmetric)
    type(mbdk_sparse_ldlt_t), intent(out) :: f
    integer, intent(in) :: n, ap(:), ai(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer, intent(in), optional :: order(:)
    logical, intent(in), optional :: unsymmetric
    integer :: nnz, j, k, astat
    !> amd_order's status when its workspace could not be had (amd.h)
    integer, parameter :: AMD_OUT_OF_MEMORY = -1
    stat = MBDK_ERR_INVALID_INPUT
    if (n < 1 .or. size(ap) /= n + 1) return
    nnz = ap(n + 1) - 1
    if (size(ai) < nnz) return
    f%n = n
    allocate (f%ap(n + 1), f%ai(nnz), f%ax(nnz), f%p(n), f%pinv(n), f%lp(n + 1), f%parent(n), &
              f%lnz(n), f%flag(n), f%pattern(n), f%d(n), f%y(n), f%dpos(n), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (9.0_dp * n + 2 + nnz) + &
                           MBDK_REAL_BYTES * (nnz + 2.0_dp * n), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INVALID_INPUT
    f%ap = ap - 1
    f%ai = ai(1:nnz) - 1
    f%dpos = 0
    do j = 1, n
      do k = ap(j), ap(j + 1) - 1
        if (ai(k) == j) f%dpos(j) = k
      end do
    end do
    if (present(order)) then
      ! a permutation of 1..n, or refused
      if (size(order) /= n) return
      f%flag = 0
      do k = 1, n
        if (order(k) < 1 .or. order(k) > n) return
        if (f%flag(order(k)) /= 0) return
        f%flag(order(k)) = 1
      end do
      f%p = order - 1
    else
      ! AMD_OK 0, AMD_OK_BUT_JUMBLED 1 (unsorted rows in a column: allowed)
      k = amd_order(n, f%ap, f%ai, f%p, c_null_ptr, c_null_ptr)
      if (k == AMD_OUT_OF_MEMORY) stat = MBDK_ERR_NO_MEMORY
      if (k < 0) return
    end if
    call ldl_symbolic(n, f%ap, f%ai, f%lp, f%parent, f%lnz, f%flag, f%p, f%pinv)
    allocate (f%li(max(1, f%lp(n + 1))), f%lx(max(1, f%lp(n + 1))), stat=astat)
    call mbdk_alloc_status(astat, (MBDK_INT_BYTES + MBDK_REAL_BYTES) * max(1, f%lp(n + 1)), &
                           stat, asked)
    if (stat /= MBDK_SUCCESS) return
    f%ax = 0.0_dp
    if (present(unsymmetric)) then
      if (unsymmetric) then
        allocate (f%ux(max(1, f%lp(n + 1))), f%z(n), f%tpos(nnz), stat=astat)
        call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (max(1, f%lp(n + 1)) + n) + &
                               MBDK_INT_BYTES * nnz, stat, asked)
        if (stat /= MBDK_SUCCESS) return
        call transpose_positions(n, ap, ai, f%tpos, stat, asked)
        if (stat /= MBDK_SUCCESS) return
      end if
    end if
    stat = MBDK_SUCCESS
  end subroutine mbdk_sparse_ldlt_analyze

  !> tpos(p): the position of the transpose of entry p of the pattern ap, ai (1-based), found
  !> by a binary search in its row's entries listed by column; MBDK_ERR_INVALID_INPUT where
  !> one has none or a row holds a column twice (a duplicate entry), MBDK_ERR_NO_MEMORY.
  subroutine transpose_positions(n, ap, ai, tpos, stat, asked)
    integer, intent(in) :: n, ap(:), ai(:)
    integer, intent(out) :: tpos(:), stat
    real(dp), intent(inout), optional :: asked
    integer, allocatable :: rptr(:), rcol(:), rpos(:), next(:)
    integer :: nnz, j, p, i, q, lo, hi, mid, astat
    nnz = ap(n + 1) - 1
    allocate (rptr(n + 1), rcol(nnz), rpos(nnz), next(n), stat=astat)
    call mbdk_alloc_status(astat, MBDK_INT_BYTES * (2.0_dp * n + 1 + 2.0_dp * nnz), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    rptr = 0
    do p = 1, nnz
      rptr(ai(p) + 1) = rptr(ai(p) + 1) + 1
    end do
    rptr(1) = 1
    do i = 1, n
      rptr(i + 1) = rptr(i + 1) + rptr(i)
    end do
    next = rptr(1:n)
    ! each row's entries in ascending column order
    do j = 1, n
      do p = ap(j), ap(j + 1) - 1
        i = ai(p)
        rcol(next(i)) = j
        rpos(next(i)) = p
        next(i) = next(i) + 1
      end do
    end do
    stat = MBDK_ERR_INVALID_INPUT
    do i = 1, n
      do q = rptr(i) + 1, rptr(i + 1) - 1
        if (rcol(q) == rcol(q - 1)) return
      end do
    end do
    do j = 1, n
      do p = ap(j), ap(j + 1) - 1
        ! the entry (j, ai(p)): row j's entry in column ai(p)
        i = ai(p)
        lo = rptr(j)
        hi = rptr(j + 1) - 1
        q = 0
        do while (lo <= hi)
          mid = (lo + hi) / 2
          if (rcol(mid) == i) then
            q = rpos(mid)
            exit
          else if (rcol(mid) < i) then
            lo = mid + 1
          else
            hi = mid - 1
          end if
        end do
        if (q == 0) return
        tpos(p) = q
      end do
    end do
    stat = MBDK_SUCCESS
  end subroutine transpose_positions

  !> P A P^T = L D U of the values in f%ax (module header; analyze with unsymmetric), with the
  !> pivot test of mbdk_sparse_ldlt_factor. mbdk_sparse_ldlt_solve then solves with it.
  subroutine mbdk_sparse_ldlt_factor_lu(f, tol, stat, rmin)
    type(mbdk_sparse_ldlt_t), intent(inout) :: f
    real(dp), intent(in) :: tol
    integer, intent(out) :: stat
    real(dp), intent(out), optional :: rmin
    integer :: n, k, kk, p, p2, i, top, len
    real(dp) :: yi, zi
    stat = MBDK_ERR_SINGULAR_MATRIX
    f%lu = .false.
    if (present(rmin)) rmin = 0.0_dp
    if (.not. allocated(f%tpos)) then
      stat = MBDK_ERR_INVALID_INPUT
      return
    end if
    n = f%n
    ! (0-based values in the integer arrays, as LDL keeps them)
    associate (y => f%y, z => f%z, flag => f%flag, pattern => f%pattern, lnz => f%lnz, &
               lp => f%lp, li => f%li, lx => f%lx, ux => f%ux, d => f%d)
      do k = 0, n - 1
        y(k + 1) = 0.0_dp
        z(k + 1) = 0.0_dp
        top = n
        flag(k + 1) = k
        lnz(k + 1) = 0
        kk = f%p(k + 1)
        ! column k of P A P^T above the diagonal into y, row k left of it into z; the pattern
        ! of row k of L (of column k of U) by the elimination tree, in topological order
        do p = f%ap(kk + 1), f%ap(kk + 2) - 1
          i = f%pinv(f%ai(p + 1) + 1)
          if (i > k) cycle
          y(i + 1) = y(i + 1) + f%ax(p + 1)
          z(i + 1) = z(i + 1) + f%ax(f%tpos(p + 1))
          len = 0
          do while (flag(i + 1) /= k)
            len = len + 1
            pattern(len) = i
            flag(i + 1) = k
            i = f%parent(i + 1)
          end do
          do while (len > 0)
            top = top - 1
            pattern(top + 1) = pattern(len)
            len = len - 1
          end do
        end do
        d(k + 1) = y(k + 1)
        y(k + 1) = 0.0_dp
        z(k + 1) = 0.0_dp
        do while (top < n)
          i = pattern(top + 1)
          yi = y(i + 1)
          zi = z(i + 1)
          y(i + 1) = 0.0_dp
          z(i + 1) = 0.0_dp
          p2 = lp(i + 1) + lnz(i + 1)
          do p = lp(i + 1), p2 - 1
            y(li(p + 1) + 1) = y(li(p + 1) + 1) - lx(p + 1) * yi
            z(li(p + 1) + 1) = z(li(p + 1) + 1) - ux(p + 1) * zi
          end do
          li(p2 + 1) = k
          lx(p2 + 1) = zi / d(i + 1)
          ux(p2 + 1) = yi / d(i + 1)
          d(k + 1) = d(k + 1) - lx(p2 + 1) * yi
          lnz(i + 1) = lnz(i + 1) + 1
          top = top + 1
        end do
        if (d(k + 1) == 0.0_dp) return
      end do
    end associate
    call pivots_ok(f, tol, stat, rmin)
    f%lu = stat == MBDK_SUCCESS
  end subroutine mbdk_sparse_ldlt_factor_lu

  !> L D L^T of the values in f%ax. A pivot |d_k| <= tol |A_kk|, or non-finite:
  !> MBDK_ERR_SINGULAR_MATRIX. rmin: the least |d_k| / |A_kk| (on success).
  subroutine mbdk_sparse_ldlt_factor(f, tol, stat, rmin)
    type(mbdk_sparse_ldlt_t), intent(inout) :: f
    real(dp), intent(in) :: tol
    integer, intent(out) :: stat
    real(dp), intent(out), optional :: rmin
    integer :: k
    stat = MBDK_ERR_SINGULAR_MATRIX
    if (present(rmin)) rmin = 0.0_dp
    f%lu = .false.
    k = ldl_numeric(f%n, f%ap, f%ai, f%ax, f%lp, f%parent, f%lnz, f%li, f%lx, f%d, f%y, &
                    f%pattern, f%flag, f%p, f%pinv)
    if (k /= f%n) return
    call pivots_ok(f, tol, stat, rmin)
  end subroutine mbdk_sparse_ldlt_factor

  !> The factors' pivot test (mbdk_sparse_ldlt_factor's): a pivot |d_k| <= tol |A_kk| or a
  !> non-finite one is MBDK_ERR_SINGULAR_MATRIX; rmin the least |d_k| / |A_kk|.
  subroutine pivots_ok(f, tol, stat, rmin)
    type(mbdk_sparse_ldlt_t), intent(in) :: f
    real(dp), intent(in) :: tol
    integer, intent(out) :: stat
    real(dp), intent(out), optional :: rmin
    integer :: k, c
    real(dp) :: dmax, akk, r
    stat = MBDK_ERR_SINGULAR_MATRIX
    if (present(rmin)) rmin = 0.0_dp
    dmax = maxval(abs(f%d))
    if (.not. (dmax <= huge(1.0_dp))) return
    r = huge(1.0_dp)
    do k = 1, f%n
      c = f%p(k) + 1
      akk = 0.0_dp
      if (f%dpos(c) > 0) akk = abs(f%ax(f%dpos(c)))
      if (.not. (abs(f%d(k)) > tol * akk)) return
      if (akk > 0.0_dp) r = min(r, abs(f%d(k)) / akk)
    end do
    if (present(rmin)) rmin = r
    stat = MBDK_SUCCESS
  end subroutine pivots_ok

  !> b <- A^-1 b with the factors of mbdk_sparse_ldlt_factor or mbdk_sparse_ldlt_factor_lu.
  subroutine mbdk_sparse_ldlt_solve(f, b)
    type(mbdk_sparse_ldlt_t), intent(inout) :: f
    real(dp), intent(inout), contiguous :: b(:)
    call ldl_perm(f%n, f%y, b, f%p)
    call ldl_lsolve(f%n, f%y, f%lp, f%li, f%lx)
    call ldl_dsolve(f%n, f%y, f%d)
    if (f%lu) then
      ! U x = y: U^T is stored as L is, so L^T's solve with U's values
      call ldl_ltsolve(f%n, f%y, f%lp, f%li, f%ux)
    else
      call ldl_ltsolve(f%n, f%y, f%lp, f%li, f%lx)
    end if
    call ldl_permt(f%n, b, f%y, f%p)
  end subroutine mbdk_sparse_ldlt_solve

  !> Whether a factorisation's least pivot ratio rmin is near singular for a caller's window
  !> tol, judged against the largest least ratio met so far (rmin_max, the caller's record,
  !> this factorisation's included): a pivot's ratio to its row's diagonal depends on the
  !> elimination order, and in the order AMD picks, a long regular chain's least ratio is about
  !> 2 / m (a tail of k rows eliminated before a joint leaves it 2 / k), which a fixed window
  !> would call near singular beyond a few thousand bodies. A mechanism whose least ratio
  !> reaches baseline (the small ones, loops of any size, away from their singular poses) keeps
  !> the full window; a rank loss drives its pivot to zero, like the square of the distance to
  !> it, from whatever baseline. The window is never narrower than min_rows / m of tol: a run
  !> that starts near a singular pose has that narrow window until it has moved away, and the
  !> full one from then on.
  pure logical function mbdk_sparse_ldlt_near(rmin, rmin_max, tol, m, min_rows, baseline) &
      result(near)
    real(dp), intent(in) :: rmin, rmin_max, tol, baseline
    integer, intent(in) :: m, min_rows
    near = .not. (rmin > tol * min(1.0_dp, max(real(min_rows, dp) / real(m, dp), &
                                               rmin_max / baseline)))
  end function mbdk_sparse_ldlt_near

end module mbdk_sparse_ldlt
