!> A mechanism's equations of motion (mbdk_mechanism: planar or spatial, q' = T(q) v) as a
!> semi-explicit DAE  E Y' = G(t, Y)  with a diagonal E, for bdf in the manner of MSC Adams'
!> GSTIFF (the book, 4.4.2): the BDF formulas applied to the DAE itself, not to the reduced ODE.
!> Two forms (nq coordinates, nv velocities; the multipliers of the rows a the mechanism solves,
!> active_rows: all rows, or the independent subset a redundant spatial scene keeps, taken once
!> at the start: the DAE does not switch sets, and one nearing a rank loss of its own makes
!> Newton's matrix singular, so the run stops by name):
!>   i3  (index 3, GSTIFF I3)   Y = [q; v; lam_a]:
!>         q' = T(q) v,   M v' = f - C_a^T lam,   0 = Phi_a(q, t)
!>       (a knife edge's row, which constrains velocities only, reads 0 = C v + Phi_t: the form
!>       is index 2 in that row, the index-2 form of nonholonomic scenes)
!>   si2 (stabilised index 2, the GGL form as in GSTIFF SI2)  Y = [q; v; lam_a; mu_a]:
!>         q' = T(q) (v - C_a^T mu),   M v' = f - C_a^T lam,   0 = Phi_a(q, t),
!>         0 = C_a v + Phi_t,a
!>       (refused for knife edges, MBDK_ERR_NOT_APPLICABLE: they have no position row for mu).
!>       With dPhi/dq T = C, Phi' = C (v - C^T mu) + Phi_t: where both rows hold, mu = 0.
!> E = diag(I, M, 0 (, 0)) where M is diagonal (a planar scene: a body without inertia has a
!> zero in M, so its rotation's velocity row is algebraic too, which the same E expresses);
!> otherwise (a spatial body's inertia tensor) E = diag(I, I, 0 (, 0)) and the velocity rows
!> read v' = M^-1 (f - C_a^T lam), M^-1 applied body by body.
!> G is the rhs of this problem type; mbdk_variable_bdf takes E as its mass argument and tests
!> the local error of q and v only (lam and mu are algebraic). The quaternions' norm is kept by
!> the kinematic equation (with the scene's stabilising term where it asks for one), not by a
!> projection between steps, which would corrupt BDF's history; the rotation is taken from
!> p / |p|. The watch uses the DAE's own multipliers (the drivers' power).
!>
!> Large scenes (the mechanism's compact_rows: its constrained solves are sparse) keep nothing
!> dense. G is evaluated through the index-3 procedures (f, Phi, Phi_t and the products C x,
!> C^T x from the model's compact rows; i3_create's object, which a planar scene with contacts
!> refuses, and no knife edge, whose velocity row G would read as a position row: those keep
!> the dense path), and the problem forms, factorises and solves bdf's Newton matrix E - c J
!> itself (mbdk_problem's has_newton_matrix):
!>   pattern   J's columns of a body's coordinates and velocities have rows on the bodies
!>             paired with it and on the rows with a column on it; a multiplier's column has
!>             rows on its row's bodies (mbdk_dae_pattern, from mbdk_mechanism's body_graph;
!>             ida's sparse matrix has the same pattern). That is the KKT shape
!>             [K D^T; D 0] of mbdk_kkt_pattern with K over [q; v] and D the rows of lam
!>             (and mu), in its order: AMD's, each multiplier after the last unknown of its
!>             bodies, so that L D U without pivoting (mbdk_sparse_ldlt_factor_lu) meets
!>             pivots near 1 on the bodies' unknowns (E's identity and M: a planar body
!>             without inertia keeps the dense path) and c C M^-1 C^T, scaled, on the rows'
!>   values    the bodies' columns by forward differences of G, colored: a distance-2
!>             coloring of the body graph (mbdk_dae_pattern) perturbs the k-th unknown of
!>             every body of a color at once, so a chain's matrix costs about 3 x 13
!>             evaluations whatever its length, each O(N) (a hub, a body coupled to many,
!>             makes the colors grow with its degree); increments sqrt(eps) max(|y_j|, 1),
!>             mbdk_jacobian's. The multipliers' columns exactly, G being linear in them: a
!>             coloring of the rows (no two of a color on one body) gives -M^-1 C^T e (v rows)
!>             and, si2, -T(q) C^T e (q rows) for all rows of a color by one product
!>   factor    the values E - c J with the algebraic rows and columns divided by c (bdf's
!>             index scaling) into L D U; a vanishing pivot is MBDK_ERR_SINGULAR_MATRIX (bdf
!>             retries the step smaller). Without pivoting a body's pivot shrinks where a
!>             stiff element's c^2 K nears its mass, and the solve loses digits to that growth:
!>             each solve takes one step of iterative refinement with the matrix itself (a
!>             product and a second solve), which restores them (tests/test_dae_scale.py: the
!>             stiff spring bar then takes the dense LU's steps and iterations, or close).
!> The start's consistency (mbdk_mechanism_dae_residuals) is measured the same way.
module mbdk_mechanism_dae
  use mbdk_kinds, only: dp
  use mbdk_status
  use mbdk_problem, only: mbdk_problem_t
  use mbdk_mechanism, only: mbdk_mechanism_t, mbdk_i3_aux_t, mbdk_i3_eval_t
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_dae_pattern, only: mbdk_dae_pattern_t, mbdk_dae_pattern_init
  use mbdk_kkt_pattern, only: mbdk_kkt_pattern_init
  use mbdk_sparse_ldlt, only: mbdk_sparse_ldlt_t, mbdk_sparse_ldlt_factor_lu, &
    mbdk_sparse_ldlt_solve
  implicit none
  private
  public :: mbdk_mechanism_dae_init, mbdk_mechanism_dae_residuals

  !> a pivot of the sparse L D U at most this share of its diagonal entry is singular
  real(dp), parameter :: PIVOT_TOL = 1.0e-14_dp

  !> the forms of a mechanism's DAE (the f2py entries' dae_form, mbdk_entry): none (an ODE
  !> method, or the index-3 family with its own), index 3, stabilised index 2 (ida's index1 and
  !> GGL forms take the codes 1 and 2)
  integer, parameter, public :: MBDK_DAE_NONE = 0, MBDK_DAE_I3 = 1, MBDK_DAE_SI2 = 2

  !> evaluation buffers (the problem is intent(in) in rhs: they live behind a pointer); the
  !> sparse path's (module header): the index-3 object and point, the factors of the KKT
  !> pattern and J's values in their layout (jx), the pattern and colorings
  !> (mbdk_dae_pattern), and vectors
  type :: dae_work_t
    real(dp), allocatable :: f(:), phi(:), c(:, :), gam(:), phit(:), lam(:), mu(:), g(:), &
      x(:), lamn(:, :)
    class(mbdk_i3_aux_t), allocatable :: aux
    type(mbdk_i3_eval_t) :: e
    type(mbdk_sparse_ldlt_t) :: ldl
    real(dp), allocatable :: jx(:), g0(:), g1(:), yw(:), del(:), z(:), zq(:), rq0(:), cv(:)
    type(mbdk_dae_pattern_t) :: pat
  end type dae_work_t

  type, extends(mbdk_problem_t), public :: mbdk_mechanism_dae_t
    class(mbdk_mechanism_t), pointer :: mech => null()
    integer :: form = MBDK_DAE_I3
    !> Y = [q (ncq); v (nv); lam (na); (si2) mu (na)], ny = ncq + nv
    integer :: ncq = 0, nv = 0, ny = 0, na = 0
    integer, allocatable :: rows(:)
    !> the sparse path (module header)
    logical :: sparse = .false.
    type(dae_work_t), pointer :: work => null()
  contains
    procedure :: rhs => dae_rhs
    procedure :: newton_jacobian => dae_newton_jacobian
    procedure :: newton_factor => dae_newton_factor
    procedure :: newton_solve => dae_newton_solve
    procedure :: watch_start => dae_watch_start
    procedure :: watch => dae_watch
    procedure :: watch_wants_nodes => dae_wants_nodes
    procedure :: watch_nodes => dae_watch_nodes
    procedure :: singular_at => dae_singular_at
    final :: dae_free
  end type mbdk_mechanism_dae_t

contains

  !> The DAE of mech in form (MBDK_DAE_*), on the rows mech solves now (call its
  !> accelerations first: a redundant scene's solve there may choose the set); mass(N) receives
  !> the diagonal of E. mech must outlive the problem. A scene with effect states (wear), or
  !> si2 with a knife edge: MBDK_ERR_NOT_APPLICABLE. MBDK_ERR_NO_MEMORY: asked gets the bytes
  !> (mbdk_memory).
  subroutine mbdk_mechanism_dae_init(self, mech, form, mass, stat, asked)
    type(mbdk_mechanism_dae_t), intent(out) :: self
    class(mbdk_mechanism_t), intent(in), target :: mech
    integer, intent(in) :: form
    real(dp), allocatable, intent(out) :: mass(:)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: nv, m, astat
    stat = MBDK_ERR_INVALID_INPUT
    if (form /= MBDK_DAE_I3 .and. form /= MBDK_DAE_SI2) return
    ! the DAE's state is [q; v; lambda]: a scene with effect states (wear) is not one. The
    ! GGL form stabilises position rows; a knife edge has none (its mu would be undetermined)
    if (mech%ns > 0 .or. (form == MBDK_DAE_SI2 .and. mech%has_pfaffian)) then
      stat = MBDK_ERR_NOT_APPLICABLE
      return
    end if
    call mech%active_rows(self%rows, stat)
    if (stat /= MBDK_SUCCESS) return
    nv = mech%nvel
    m = mech%m
    self%mech => mech
    self%form = form
    self%ncq = mech%ncoord
    self%nv = nv
    self%ny = mech%ncoord + nv
    self%na = size(self%rows)
    self%n = self%ny + self%na
    if (form == MBDK_DAE_SI2) self%n = self%n + self%na
    self%has_watch = mech%has_watch
    allocate (self%work, stat=astat)
    if (astat == 0) allocate (self%work%f(nv), self%work%phi(m), self%work%gam(m), &
                              self%work%phit(m), self%work%lam(m), self%work%mu(m), &
                              self%work%g(nv), self%work%x(nv), self%work%lamn(m, 3), &
                              mass(self%n), stat=astat)
    ! (self%work, if allocated, is freed by the finaliser)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (real(m, dp) * 8 + 3.0_dp * nv + &
                           self%n), stat, asked)
    if (stat /= MBDK_SUCCESS) return
    mass = 0.0_dp
    mass(1:self%ny) = 1.0_dp
    if (mech%diag_mass) call mech%mass_diagonal(mass(self%ncq + 1:self%ny))
    ! (compact_g reads every row as a position row: a knife edge's keeps the dense path)
    if (mech%compact_rows .and. m > 0 .and. .not. mech%has_pfaffian .and. &
        all(mass(self%ncq + 1:self%ny) > 0.0_dp)) then
      call sparse_init(self, stat, asked)
      if (stat /= MBDK_SUCCESS .and. stat /= MBDK_ERR_NOT_APPLICABLE) return
      self%sparse = stat == MBDK_SUCCESS
      self%has_newton_matrix = self%sparse
    end if
    if (.not. self%sparse) then
      allocate (self%work%c(m, nv), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * real(m, dp) * nv, stat, asked)
      if (stat /= MBDK_SUCCESS) return
    end if
    stat = MBDK_SUCCESS
  end subroutine mbdk_mechanism_dae_init

  !> The sparse path's objects (module header). MBDK_ERR_NOT_APPLICABLE where the mechanism
  !> has no index-3 object for the scene (the dense path then serves).
  subroutine sparse_init(self, stat, asked)
    type(mbdk_mechanism_dae_t), intent(inout) :: self
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer, allocatable :: kpos(:), dpos_r(:), dpos_c(:), partner(:)
    integer :: ncq, na, nd, m, i, astat
    stat = MBDK_ERR_NOT_APPLICABLE
    if (self%na == 0) return
    associate (w => self%work, mech => self%mech)
      call mech%i3_create(w%aux, .false., stat, asked)
      if (stat /= MBDK_SUCCESS) return
      m = mech%m
      ncq = self%ncq
      na = self%na
      nd = merge(2 * na, na, self%form == MBDK_DAE_SI2)
      call mbdk_dae_pattern_init(w%pat, mech, self%rows, nd / na, stat, asked)
      if (stat /= MBDK_SUCCESS) return
      allocate (w%e%q(ncq), w%e%v(self%nv), w%e%f(self%nv), w%e%phi(m), w%e%gam(m), &
                w%e%phit(m), w%e%lt(m), w%e%dd(self%nv), w%e%r(self%nv + m), w%g0(self%n), &
                w%g1(self%n), w%yw(self%n), w%del(self%n), w%z(self%nv), w%zq(ncq), &
                w%rq0(ncq), w%cv(m), partner(nd), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (6.0_dp * m + 5.0_dp * self%nv + &
                             3.0_dp * ncq + 4.0_dp * self%n) + MBDK_INT_BYTES * nd, stat, asked)
      if (astat /= 0) return
      w%e%lt = 0.0_dp
      w%e%dd = 0.0_dp
      ! (si2: each mu row after its lam row, module header)
      partner = 0
      do i = na + 1, nd
        partner(i) = i - na
      end do
      call mbdk_kkt_pattern_init(w%pat%kap, w%pat%kai, w%pat%drptr, w%pat%drcol, w%ldl, kpos, &
                                 dpos_r, dpos_c, stat, asked, unsymmetric=.true., &
                                 partner=partner)
      if (stat /= MBDK_SUCCESS) return
      allocate (w%jx(size(w%ldl%ax)), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * size(w%ldl%ax), stat, asked)
    end associate
  end subroutine sparse_init

  subroutine dae_free(self)
    type(mbdk_mechanism_dae_t), intent(inout) :: self
    if (associated(self%work)) deallocate (self%work)
  end subroutine dae_free

  subroutine dae_rhs(self, t, y, f, stat)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    real(dp), intent(out), contiguous :: f(:)
    integer, intent(out) :: stat
    integer :: ncq, ny, na, i, j
    if (self%sparse) then
      call compact_g(self, t, y, f, stat)
      return
    end if
    ncq = self%ncq
    ny = self%ny
    na = self%na
    associate (q => y(1:ncq), v => y(ncq + 1:ny), w => self%work, mech => self%mech)
      call mech%evaluate(t, q, v, w%f, w%phi, w%c, w%gam, w%phit, stat)
      if (stat /= MBDK_SUCCESS) return
      if (self%mech%m == 0) then
        w%g = w%f
      else
        w%lam = 0.0_dp
        w%lam(self%rows) = y(ny + 1:ny + na)
        w%g = w%f - matmul(w%lam, w%c)
      end if
      if (mech%diag_mass) then
        f(ncq + 1:ny) = w%g
      else
        call mech%minv_times(w%g, f(ncq + 1:ny))
      end if
      if (self%form == MBDK_DAE_SI2 .and. mech%m > 0) then
        w%mu = 0.0_dp
        w%mu(self%rows) = y(ny + na + 1:ny + 2 * na)
        w%x = v - matmul(w%mu, w%c)
        call mech%rates(q, w%x, f(1:ncq), stat)
      else
        call mech%rates(q, v, f(1:ncq), stat)
      end if
      if (stat /= MBDK_SUCCESS) return
      do i = 1, na
        j = self%rows(i)
        f(ny + i) = w%phi(j)
        ! a knife edge's row is its velocity constraint (index 2 in that row)
        if (mech%has_pfaffian) then
          if (mech%pfaffian(j)) f(ny + i) = dot_product(w%c(j, :), v) + w%phit(j)
        end if
        if (self%form == MBDK_DAE_SI2) f(ny + na + i) = dot_product(w%c(j, :), v) + w%phit(j)
      end do
    end associate
  end subroutine dae_rhs

  !> G(t, y) on the sparse path (module header): the index-3 evaluation and C's products
  subroutine compact_g(self, t, y, f, stat)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    real(dp), intent(out), contiguous :: f(:)
    integer, intent(out) :: stat
    integer :: ncq, ny, na
    ncq = self%ncq
    ny = self%ny
    na = self%na
    associate (w => self%work, mech => self%mech, e => self%work%e)
      e%q = y(1:ncq)
      e%v = y(ncq + 1:ny)
      ! a non-finite state is named, as the dense evaluate names it (the index-3 one leaves it
      ! to its caller); forces not finite at a finite state reach f, which bdf checks
      stat = MBDK_ERR_NONFINITE
      if (.not. all(abs(y(1:ny)) <= huge(1.0_dp))) return
      call mech%i3_evaluate(w%aux, t, e, .true., .false., stat)
      if (stat /= MBDK_SUCCESS) return
      w%lam = 0.0_dp
      w%lam(self%rows) = y(ny + 1:ny + na)
      call mech%i3_ct_times(w%aux, w%lam, w%x)
      w%g = e%f - w%x
      if (mech%diag_mass) then
        f(ncq + 1:ny) = w%g
      else
        call mech%minv_times(w%g, f(ncq + 1:ny))
      end if
      if (self%form == MBDK_DAE_SI2) then
        w%mu = 0.0_dp
        w%mu(self%rows) = y(ny + na + 1:ny + 2 * na)
        call mech%i3_ct_times(w%aux, w%mu, w%x)
        w%x = e%v - w%x
        call mech%rates(e%q, w%x, f(1:ncq), stat)
        if (stat /= MBDK_SUCCESS) return
        call mech%i3_c_times(w%aux, e%v, w%cv)
        f(ny + na + 1:ny + 2 * na) = w%cv(self%rows) + e%phit(self%rows)
      else
        call mech%rates(e%q, e%v, f(1:ncq), stat)
        if (stat /= MBDK_SUCCESS) return
      end if
      f(ny + 1:ny + na) = e%phi(self%rows)
    end associate
  end subroutine compact_g

  !> J at (t, y) into the KKT layout (module header): the bodies' columns by colored
  !> differences, the multipliers' exactly. nfev: the evaluations of G.
  subroutine dae_newton_jacobian(self, t, y, nfev, stat)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: y(:)
    integer, intent(out) :: nfev
    integer, intent(out) :: stat
    integer :: c, d, k, b, j, p, i, row, ncq, ny, na, dmax
    logical :: any_col
    nfev = 0
    stat = MBDK_ERR_NOT_APPLICABLE
    if (.not. self%sparse) return
    ncq = self%ncq
    ny = self%ny
    na = self%na
    associate (w => self%work, mech => self%mech, ap => self%work%ldl%ap, &
               ai => self%work%ldl%ai)
      call compact_g(self, t, y, w%g0, stat)
      nfev = 1
      if (stat /= MBDK_SUCCESS) return
      stat = MBDK_ERR_NONFINITE
      if (.not. all(abs(w%g0) <= huge(1.0_dp))) return
      w%jx = 0.0_dp
      ! the multipliers' columns, with C of the evaluation at y (the last)
      if (self%form == MBDK_DAE_SI2) then
        w%z = 0.0_dp
        call mech%rates(w%e%q, w%z, w%rq0, stat)
        if (stat /= MBDK_SUCCESS) return
      end if
      do c = 1, size(w%pat%rptr) - 1
        w%lam = 0.0_dp
        do k = w%pat%rptr(c), w%pat%rptr(c + 1) - 1
          w%lam(self%rows(w%pat%rrow(k))) = 1.0_dp
        end do
        call mech%i3_ct_times(w%aux, w%lam, w%x)
        if (mech%diag_mass) then
          w%z = w%x
        else
          call mech%minv_times(w%x, w%z)
        end if
        if (self%form == MBDK_DAE_SI2) then
          w%x = -w%x
          call mech%rates(w%e%q, w%x, w%zq, stat)
          if (stat /= MBDK_SUCCESS) return
          w%zq = w%zq - w%rq0
        end if
        do k = w%pat%rptr(c), w%pat%rptr(c + 1) - 1
          i = w%pat%rrow(k)
          j = ny + i
          do p = ap(j) + 1, ap(j + 1)
            row = ai(p) + 1
            if (row > ncq .and. row <= ny) w%jx(p) = -w%z(row - ncq)
          end do
          if (self%form /= MBDK_DAE_SI2) cycle
          j = ny + na + i
          do p = ap(j) + 1, ap(j + 1)
            row = ai(p) + 1
            if (row <= ncq) w%jx(p) = w%zq(row)
          end do
        end do
      end do
      ! the bodies' columns, the k-th unknown of every body of a color at once
      dmax = w%pat%dmax
      w%yw = y
      do c = 1, size(w%pat%cptr) - 1
        do d = 1, dmax
          any_col = .false.
          do k = w%pat%cptr(c), w%pat%cptr(c + 1) - 1
            b = w%pat%cbody(k)
            if (w%pat%bptr(b) + d - 1 >= w%pat%bptr(b + 1)) cycle
            j = w%pat%bidx(w%pat%bptr(b) + d - 1)
            w%yw(j) = y(j) + sqrt(epsilon(1.0_dp)) * max(abs(y(j)), 1.0_dp)
            w%del(j) = w%yw(j) - y(j)    ! the increment actually representable
            any_col = .true.
          end do
          if (.not. any_col) cycle
          call compact_g(self, t, w%yw, w%g1, stat)
          nfev = nfev + 1
          if (stat /= MBDK_SUCCESS) return
          ! (G not finite a difference increment away: a singularity there, named)
          stat = MBDK_ERR_NONFINITE
          if (.not. all(abs(w%g1) <= huge(1.0_dp))) return
          stat = MBDK_SUCCESS
          do k = w%pat%cptr(c), w%pat%cptr(c + 1) - 1
            b = w%pat%cbody(k)
            if (w%pat%bptr(b) + d - 1 >= w%pat%bptr(b + 1)) cycle
            j = w%pat%bidx(w%pat%bptr(b) + d - 1)
            w%yw(j) = y(j)
            do p = ap(j) + 1, ap(j + 1)
              row = ai(p) + 1
              w%jx(p) = (w%g1(row) - w%g0(row)) / w%del(j)
            end do
          end do
        end do
      end do
    end associate
  end subroutine dae_newton_jacobian

  !> E - c J with the algebraic rows and columns divided by c, factorised (module header)
  subroutine dae_newton_factor(self, c, em, alg, stat)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    real(dp), intent(in) :: c, em(:)
    logical, intent(in) :: alg(:)
    integer, intent(out) :: stat
    integer :: j, p, row
    real(dp) :: x
    stat = MBDK_ERR_NOT_APPLICABLE
    if (.not. self%sparse) return
    associate (w => self%work, ap => self%work%ldl%ap, ai => self%work%ldl%ai)
      do j = 1, self%n
        do p = ap(j) + 1, ap(j + 1)
          row = ai(p) + 1
          x = -c * w%jx(p)
          if (row == j) x = x + em(j)
          if (alg(row)) x = x / c
          if (alg(j)) x = x / c
          w%ldl%ax(p) = x
        end do
      end do
      call mbdk_sparse_ldlt_factor_lu(w%ldl, PIVOT_TOL, stat)
    end associate
  end subroutine dae_newton_factor

  subroutine dae_newton_solve(self, x, stat)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    real(dp), intent(inout), contiguous :: x(:)
    integer, intent(out) :: stat
    integer :: j, p
    stat = MBDK_ERR_NOT_APPLICABLE
    if (.not. self%sparse) return
    associate (w => self%work, ap => self%work%ldl%ap, ai => self%work%ldl%ai)
      w%yw = x
      call mbdk_sparse_ldlt_solve(w%ldl, x)
      w%g1 = w%yw
      do j = 1, self%n
        do p = ap(j) + 1, ap(j + 1)
          w%g1(ai(p) + 1) = w%g1(ai(p) + 1) - w%ldl%ax(p) * x(j)
        end do
      end do
      call mbdk_sparse_ldlt_solve(w%ldl, w%g1)
      x = x + w%g1
    end associate
    stat = MBDK_SUCCESS
  end subroutine dae_newton_solve

  !> How far y = [q; v; ..] is from the constraints: phi_max = max |Phi| over the position
  !> rows, cv_max = max |C v + Phi_t| over all rows (dense or compact, as the DAE evaluates).
  subroutine mbdk_mechanism_dae_residuals(self, t, y, phi_max, cv_max, stat)
    type(mbdk_mechanism_dae_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    real(dp), intent(out) :: phi_max, cv_max
    integer, intent(out) :: stat
    integer :: ncq, ny
    phi_max = 0.0_dp
    cv_max = 0.0_dp
    stat = MBDK_SUCCESS
    if (self%mech%m == 0) return
    ncq = self%ncq
    ny = self%ny
    associate (w => self%work, mech => self%mech)
      if (self%sparse) then
        w%e%q = y(1:ncq)
        w%e%v = y(ncq + 1:ny)
        call mech%i3_evaluate(w%aux, t, w%e, .false., .false., stat)
        if (stat /= MBDK_SUCCESS) return
        w%phi = w%e%phi
        w%phit = w%e%phit
        call mech%i3_c_times(w%aux, w%e%v, w%cv)
      else
        call mech%evaluate(t, y(1:ncq), y(ncq + 1:ny), w%f, w%phi, w%c, w%gam, w%phit, stat)
        if (stat /= MBDK_SUCCESS) return
        w%x = y(ncq + 1:ny)
        w%lam = matmul(w%c, w%x)
      end if
      if (mech%has_pfaffian) w%phi = merge(0.0_dp, w%phi, mech%pfaffian)
      phi_max = maxval(abs(w%phi))
      if (self%sparse) then
        cv_max = maxval(abs(w%cv + w%phit))
      else
        cv_max = maxval(abs(w%lam + w%phit))
      end if
    end associate
  end subroutine mbdk_mechanism_dae_residuals

  subroutine dae_watch_start(self, t, y, stat)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    integer, intent(out) :: stat
    call self%mech%watch_start(t, y(1:self%ny), stat)
  end subroutine dae_watch_start

  subroutine dae_watch(self, t, y, force, stat)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    logical, intent(in) :: force
    integer, intent(out) :: stat
    associate (lam => self%work%lam)
      lam = 0.0_dp
      lam(self%rows) = y(self%ny + 1:self%ny + self%na)
      call self%mech%watch_lam(t, y(1:self%ny), force, lam, stat)
    end associate
  end subroutine dae_watch

  logical function dae_wants_nodes(self)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    dae_wants_nodes = self%mech%watch_wants_nodes()
  end function dae_wants_nodes

  !> The work at the nodes of a step with the DAE's own multipliers there.
  subroutine dae_watch_nodes(self, t_a, t_b, y, stat)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    real(dp), intent(in) :: t_a, t_b, y(:, :)
    integer, intent(out) :: stat
    associate (lamn => self%work%lamn)
      lamn = 0.0_dp
      lamn(self%rows, :) = y(self%ny + 1:self%ny + self%na, :)
      call self%mech%watch_nodes_lam(t_a, t_b, y(1:self%ny, :), lamn, stat)
    end associate
  end subroutine dae_watch_nodes

  !> Whether the state's pose is next to a rank loss of the constraints (mbdk_mechanism's
  !> near_rank_loss). There the DAE's rows lose a rank together and bdf's Newton iteration may
  !> fail at every step (IFToMM A02's flat poses at tight tolerances), so bdf names that cause,
  !> not the step.
  logical function dae_singular_at(self, t, y)
    class(mbdk_mechanism_dae_t), intent(in) :: self
    real(dp), intent(in) :: t, y(:)
    dae_singular_at = self%mech%near_rank_loss(t, y(1:self%ny), self%rows)
  end function dae_singular_at

end module mbdk_mechanism_dae
