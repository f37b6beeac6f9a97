!> The spatial model's part of trapezoidal_index3 (mbdk_trapezoidal_index3 is the method's
!> manual; mbdk_mechanism lists what each procedure gives). The evaluation is the model's
!> (frames, forces with the gyroscopic moment, C). Two paths, the model's (model%sparse):
!>
!> Dense (the model's dense path: at most MBDK_SPATIAL_SPARSE_ROWS rows, redundant joints, or
!> a few bodies under many rows): C dense, the Newton matrix the integrator's differences over
!> the whole state (has_i3_matrix off), and the constrained solves:
!>   exact    S = C_a M^-1 C_a^T on the independent rows a the model solves (work%active: all
!>            rows, or the subset a redundant scene keeps), by Cholesky, each pivot against its
!>            row's diagonal at roundoff (SOLVE_RTOL) and, where the caller asks, the geometric
!>            near test of the model (near_test, the rows' C W C^T with rotations at the length
!>            scale; none on a tree of joints without drivers, model%regular_tree); the other
!>            rows get no multiplier;
!>   regular  where that fails and the caller allows it (a singular pose): the augmented
!>            Lagrangian iteration of Bayo and Ledesma (1996) on all rows,
!>              (M + beta C^T C) x_k+1 = b - C^T mu_k + beta C^T c,  mu_k+1 = mu_k + beta (C x - c),
!>            beta = AL_KAPPA max(diag M) / max |C_i|^2, its matrix positive definite whatever
!>            C's rank, stopping at roundoff or where the residual stops falling by half (as
!>            mbdk_constrained's, the planar model's).
!>
!> Sparse (more rows, none redundant: a long chain or tree, a large loop): memory and cost per
!> evaluation O(bodies + rows).
!>   C        in compact rows (twelve values a row on its two bodies), as the ODE path keeps it;
!>   solves   S = C M^-1 C^T by mbdk_compact_schur (its own pattern, built as the model's),
!>            the near test on the geometry's G as the ODE path's (none on a tree of joints
!>            without drivers, model%regular_tree); the augmented form's regular path as the
!>            dense one's, M + beta C^T C in the body pattern by the symmetric LDL^T (the book
!>            form has none: a rank loss is MBDK_ERR_SINGULAR_MATRIX by name);
!>   Newton   the model's own matrix (has_i3_matrix on). K = M - ck dg/dq - cd dg/dv,
!>            g = f - C^T lam, by differences of colored columns: bodies two or more couplings
!>            apart (no body coupled to both: a distance-2 coloring of the body graph, joints
!>            and two-body forces as its edges) are perturbed together, each body's six
!>            velocity components one at a time, q by the retraction (q (+) delta) and v by
!>            (cd/ck) delta, as a step moves them; a body's column then changes only its
!>            neighbours' rows. A chain needs 3 colors (19 evaluations per matrix whatever
!>            its length, with the one at the point itself); the colors are as many as the
!>            largest set of bodies within two couplings of one another: a hub (a body
!>            jointed to many, springs or declared contacts to one body) makes them grow with
!>            its degree, and the matrix's cost with them (O(N^2) for a star). K is kept as it is,
!>            unsymmetric, in 6 x 6 body blocks (mbdk_body_pattern): its skew part (the
!>            gyroscopic and the rotations' geometric terms, about h |Omega| and s |lambda| l)
!>            is small against J but not against a slender bar's axial inertia, where the
!>            symmetric part alone is indefinite and Newton stalls. The book form's matrix
!>            [K C^T; C 0] in mbdk_kkt_pattern's order, the augmented one's K + ck alpha C^T C
!>            in the body pattern under AMD; both factorised by L D U without pivoting on
!>            LDL's analysis (mbdk_sparse_ldlt_factor_lu).
!>            The increments: sqrt(eps) max(|r|, length / 100) for a body's translations (f's
!>            roundoff is eps of the body's own position; not the scene's spread, which would
!>            step a body resting on a stiff contact across its penetration, F / k, and
!>            leave the contact's stiffness out of its column), sqrt(eps) rad for its
!>            rotations. A contact whose penetration is below the increment (about 1e-8 of the
!>            body's coordinates) still gets a softened column: Newton then converges more
!>            slowly or stops by name (MBDK_ERR_NEWTON_DIVERGED), as the dense differences do.
!> A submodule of mbdk_spatial_model, to keep that module's size in hand.
submodule (mbdk_spatial_model) mbdk_spatial_i3
  use mbdk_body_pattern, only: mbdk_body_pattern_t, mbdk_body_pattern_init, &
    mbdk_body_pattern_pos, mbdk_body_pattern_dtd, mbdk_body_pattern_colors
  use mbdk_kkt_pattern, only: mbdk_kkt_pattern_init
  use mbdk_sparse_ldlt, only: mbdk_sparse_ldlt_t, mbdk_sparse_ldlt_analyze, &
    mbdk_sparse_ldlt_factor, mbdk_sparse_ldlt_factor_lu, mbdk_sparse_ldlt_solve
  implicit none

  !> the regular path: penalty factor per max(diag M) / max |C_i|^2, and the iteration limit
  real(dp), parameter :: AL_KAPPA = 1.0e3_dp
  integer, parameter :: AL_ITER = 30
  !> a pivot of the sparse Newton matrix's L D U at or below this of its diagonal entry:
  !> singular (the planar sparse matrix's test)
  real(dp), parameter :: LDLT_TOL = 1.0e-14_dp

  type, extends(mbdk_i3_aux_t) :: spatial_i3_aux_t
    !> C at the last evaluation (m x 6 nb), M^-1 C^T, the rows of the exact path and the
    !> Cholesky factor of their S with its envelope (slast); the regular path's factor and beta
    real(dp), allocatable :: c(:, :), mc(:, :), s(:, :), al(:, :), y(:), x(:), r(:), muk(:)
    integer, allocatable :: rows(:), slast(:)
    logical :: regular = .false.
    real(dp) :: beta = 0.0_dp
    !> the sparse path (module header): C's compact rows at the last evaluation (cc) and at a
    !> perturbed point (ccw); g = f - C^T lam there (g0, gw), the point (qw, vw), the
    !> increments (dlt, per body dl(2, nb)); the evaluation's forces (fwk, nbk) and rows
    !> (phiw, gamw)
    logical :: sparse = .false.
    logical :: book = .false.
    real(dp), allocatable :: cc(:, :), ccw(:, :), g0(:), gw(:), qw(:), vw(:), dlt(:), &
      dl(:, :), fwk(:, :), nbk(:, :), phiw(:), gamw(:), kx(:)
    type(mbdk_compact_schur_t) :: cs
    type(mbdk_body_pattern_t) :: bp
    type(mbdk_sparse_ldlt_t) :: ldl
    !> the augmented form's regular path (has_reg): M + beta C^T C in the body pattern
    logical :: has_reg = .false.
    type(mbdk_sparse_ldlt_t) :: reg
    !> D's nonzeros row by row: their columns (rcol) and slots in a compact row (rslot); the
    !> places of K's values and D's in the book matrix (kpos, dpos_r, dpos_c) or of the
    !> products of C^T C in the augmented one (dtd_pos); the bodies by color
    integer, allocatable :: rptr(:), rcol(:), rslot(:), kpos(:), dpos_r(:), dpos_c(:), &
      dtd_pos(:), color_ptr(:), color_body(:)
  end type spatial_i3_aux_t

contains

  module procedure spatial_i3_create
    integer :: m, nv, astat
    m = self%m
    nv = self%nvel
    stat = MBDK_ERR_NO_MEMORY
    allocate (spatial_i3_aux_t :: aux, stat=astat)
    if (astat /= 0) return
    select type (aux)
    type is (spatial_i3_aux_t)
      if (self%sparse) then
        call sparse_create(self, aux, book, stat, asked)
        return
      end if
      allocate (aux%c(m, nv), aux%mc(nv, m), aux%s(m, m), aux%al(nv, nv), &
                aux%y(last_velocity(self)), aux%x(nv), aux%r(m), aux%muk(m), aux%rows(m), &
                aux%slast(m), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (real(m, dp) * (2 * nv + m + 2) + &
                             real(nv, dp) * (nv + 1) + last_velocity(self)) + &
                             MBDK_INT_BYTES * 2 * m, stat, asked)
      if (stat /= MBDK_SUCCESS) return
      aux%c = 0.0_dp
    end select
  end procedure spatial_i3_create

  !> frames at [q; v], the forces (f with the gyroscopic moment -Omega x J Omega in the body
  !> frame) and the constraints (C into aux)
  module procedure spatial_i3_evaluate
    type(frames_t) :: fr
    real(dp), allocatable :: fw(:, :), nbd(:, :)
    real(dp) :: vg, vs, power
    integer :: astat
    logical :: own
    ! (the dummy forces shares its name with the model's procedure forces, called below: the
    ! flag is read once, before that call, so that no later line names it)
    own = forces
    select type (aux)
    type is (spatial_i3_aux_t)
      aux%y(1:self%ncoord) = e%q
      aux%y(self%ncoord + 1:) = e%v
      call frames(self, aux%y, fr, stat)
      if (stat /= MBDK_SUCCESS) return
      if (own .and. aux%sparse) then
        ! (the sparse path's own buffers: a DAE's colored differences evaluate dozens of times)
        call forces(self, fr, aux%fwk, aux%nbk, vg, vs, power, stat)
        if (stat /= MBDK_SUCCESS) return
        call generalized_forces(self, fr, aux%fwk, aux%nbk, e%f)
      else if (own) then
        allocate (fw(3, self%nb), nbd(3, self%nb), stat=astat)
        call mbdk_alloc_status(astat, MBDK_REAL_BYTES * 6.0_dp * self%nb, stat)
        if (stat /= MBDK_SUCCESS) return
        call forces(self, fr, fw, nbd, vg, vs, power, stat)
        if (stat /= MBDK_SUCCESS) return
        call generalized_forces(self, fr, fw, nbd, e%f)
      end if
      if (self%m > 0) then
        if (aux%sparse) then
          call constraints(self, fr, t, e%phi, aux%cc, e%gam, e%phit, compact=.true.)
        else
          call constraints(self, fr, t, e%phi, aux%c, e%gam, e%phit)
        end if
      end if
    end select
  end procedure spatial_i3_evaluate

  module procedure spatial_i3_residual
    select type (aux)
    type is (spatial_i3_aux_t)
      associate (r => e%r(1:self%nvel))
        call spatial_mass_times(self, e%dd, r)
        if (self%m > 0 .and. aux%sparse) then
          r = r - s * (e%f - compact_ct(self, aux%cc, e%lt))
        else if (self%m > 0) then
          r = r - s * (e%f - matmul(e%lt, aux%c))
        else
          r = r - s * e%f
        end if
      end associate
    end select
  end procedure spatial_i3_residual

  module procedure spatial_i3_c_times
    logical :: ab
    ab = .false.
    if (present(absolute)) ab = absolute
    select type (aux)
    type is (spatial_i3_aux_t)
      if (aux%sparse) then
        y = compact_times(self, aux%cc, x, ab)
      else if (ab) then
        y = matmul(abs(aux%c), abs(x))
      else
        y = matmul(aux%c, x)
      end if
    end select
  end procedure spatial_i3_c_times

  module procedure spatial_i3_ct_times
    logical :: ab
    ab = .false.
    if (present(absolute)) ab = absolute
    select type (aux)
    type is (spatial_i3_aux_t)
      if (aux%sparse) then
        y = compact_ct(self, aux%cc, x, ab)
      else if (ab) then
        y = matmul(abs(x), abs(aux%c))
      else
        y = matmul(x, aux%c)
      end if
    end select
  end procedure spatial_i3_ct_times

  module procedure spatial_i3_cs_factor
    integer :: k, na, astat
    real(dp), allocatable :: diag(:)
    regular = .false.
    stat = MBDK_SUCCESS
    if (self%m == 0) return
    select type (aux)
    type is (spatial_i3_aux_t)
      aux%regular = .false.
      if (aux%sparse) then
        if (near > 0.0_dp .and. .not. self%regular_tree) then
          call compact_factor(self, aux%cs, aux%cc, stat, near)
        else
          call compact_factor(self, aux%cs, aux%cc, stat)
        end if
        if (stat == MBDK_SUCCESS) return
        stat = MBDK_ERR_SINGULAR_MATRIX
        if (.not. (regular_ok .and. aux%has_reg)) return
        call sparse_regular(self, aux, stat)
        if (stat /= MBDK_SUCCESS) then
          stat = MBDK_ERR_SINGULAR_MATRIX
          return
        end if
        aux%regular = .true.
        regular = .true.
        return
      end if
      call minv_ct(self, aux%c, aux%mc)
      ! the exact path on the model's independent rows
      na = size(self%work%active)
      aux%rows(1:na) = self%work%active
      allocate (diag(na), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * na, stat)
      if (stat /= MBDK_SUCCESS) return
      call gram(self, aux%c, aux%mc, aux%rows(1:na), aux%s(1:na, 1:na), stat)
      if (stat /= MBDK_SUCCESS) return
      do k = 1, na
        diag(k) = aux%s(k, k)
      end do
      call mbdk_chol_factor(aux%s(1:na, 1:na), stat, aux%slast(1:na))
      if (stat == MBDK_SUCCESS) then
        do k = 1, na
          if (.not. (aux%s(k, k)**2 > SOLVE_RTOL * diag(k))) stat = MBDK_ERR_SINGULAR_MATRIX
        end do
      else
        stat = MBDK_ERR_SINGULAR_MATRIX
      end if
      if (stat == MBDK_SUCCESS .and. near > 0.0_dp .and. .not. self%regular_tree) then
        if (.not. clear_of_near(self, aux%c, aux%rows(1:na), aux%s(1:na, 1:na), near)) &
          call near_test(self, aux%c, aux%rows(1:na), near, stat)
      end if
      if (stat /= MBDK_ERR_SINGULAR_MATRIX .or. .not. regular_ok) return
      ! the regular path's matrix M + beta C^T C (formed in place: an expression's temporary
      ! of 6 nb x 6 nb would be taken without a status)
      aux%beta = regular_beta(self, aux%c, aux%x)
      aux%al = matmul(transpose(aux%c), aux%c)
      aux%al = aux%beta * aux%al
      call add_mass(aux%al)
      call mbdk_chol_factor(aux%al, stat)
      if (stat /= MBDK_SUCCESS) then
        stat = MBDK_ERR_SINGULAR_MATRIX
        return
      end if
      aux%regular = .true.
      regular = .true.
    end select

  contains

    subroutine add_mass(a)
      real(dp), intent(inout) :: a(:, :)
      integer :: b, o, i
      do b = 1, self%nb
        o = (b - 1) * 6
        do i = 1, 3
          a(o + i, o + i) = a(o + i, o + i) + self%mass(b)
        end do
        a(o + 4:o + 6, o + 4:o + 6) = a(o + 4:o + 6, o + 4:o + 6) + self%inertia(:, :, b)
      end do
    end subroutine add_mass

  end procedure spatial_i3_cs_factor

  module procedure spatial_i3_cs_solve
    integer :: na, k
    real(dp) :: rr, r_best, cabs
    stat = MBDK_SUCCESS
    select type (aux)
    type is (spatial_i3_aux_t)
      call apply_minv(self, b, x)
      mu = 0.0_dp
      if (self%m == 0) return
      if (.not. aux%regular .and. aux%sparse) then
        aux%r = compact_times(self, aux%cc, x, .false.) - c
        call mbdk_compact_schur_solve(aux%cs, aux%r)
        mu = aux%r
        call mbdk_compact_schur_spread(aux%cs, aux%r, aux%x)
        x = x - aux%x
        return
      end if
      if (.not. aux%regular) then
        na = size(self%work%active)
        associate (rows => aux%rows(1:na), z => aux%muk(1:na))
          z = matmul(aux%c(rows, :), x) - c(rows)
          call mbdk_chol_solve(aux%s(1:na, 1:na), z, stat, aux%slast(1:na))
          if (stat /= MBDK_SUCCESS) then
            stat = MBDK_ERR_SINGULAR_MATRIX
            return
          end if
          mu(rows) = z
          x = x - matmul(aux%mc(:, rows), z)
        end associate
        return
      end if
      ! the regular path: the augmented Lagrangian iteration from mu = 0, until C x - c is at
      ! roundoff or no longer falls by half; x and mu those of the smallest residual
      if (aux%sparse) then
        cabs = maxval(abs(aux%cc))
      else
        cabs = maxval(abs(aux%c))
      end if
      aux%muk = 0.0_dp
      x = 0.0_dp
      r_best = huge(1.0_dp)
      do k = 1, AL_ITER
        aux%r = aux%muk - aux%beta * c
        if (aux%sparse) then
          aux%x = b - compact_ct(self, aux%cc, aux%r)
          call mbdk_sparse_ldlt_solve(aux%reg, aux%x)
          aux%r = compact_times(self, aux%cc, aux%x, .false.) - c
        else
          aux%x = b - matmul(aux%r, aux%c)
          call mbdk_chol_solve(aux%al, aux%x, stat)
          if (stat /= MBDK_SUCCESS) return
          aux%r = matmul(aux%c, aux%x) - c
        end if
        rr = maxval(abs(aux%r))
        if (.not. (rr < r_best)) exit
        aux%muk = aux%muk + aux%beta * aux%r
        x = aux%x
        mu = aux%muk
        if (rr <= 64.0_dp * epsilon(1.0_dp) * (maxval(abs(c)) + cabs * maxval(abs(x))) .or. &
            rr > 0.5_dp * r_best) exit
        r_best = rr
      end do
    end select
  end procedure spatial_i3_cs_solve

  !> The sparse path's Newton matrix (module header), factorised.
  module procedure spatial_i3_matrix
    stat = MBDK_ERR_NOT_APPLICABLE
    select type (aux)
    type is (spatial_i3_aux_t)
      if (.not. aux%sparse) return
      if (book) then
        call sparse_k(self, aux, t, e, lam, ck, cd, aux%kx, stat)
        if (stat /= MBDK_SUCCESS) return
        call kkt_values(self, aux)
      else
        ! K kept apart for the penalty's renewal (spatial_i3_matrix_renew)
        call sparse_k(self, aux, t, e, lam, ck, cd, aux%kx, stat)
        if (stat /= MBDK_SUCCESS) return
        aux%ldl%ax = aux%kx
        call add_ctc(aux%cc, aux%rptr, aux%rslot, aux%dtd_pos, ck * alpha, aux%ldl%ax)
      end if
      call mbdk_sparse_ldlt_factor_lu(aux%ldl, LDLT_TOL, stat)
    end select
  end procedure spatial_i3_matrix

  !> The augmented matrix renewed: the last build's K and ck alpha C^T C at the last evaluation.
  module procedure spatial_i3_matrix_renew
    stat = MBDK_ERR_NOT_APPLICABLE
    select type (aux)
    type is (spatial_i3_aux_t)
      if (.not. aux%sparse .or. aux%book) return
      aux%ldl%ax = aux%kx
      call add_ctc(aux%cc, aux%rptr, aux%rslot, aux%dtd_pos, ck * alpha, aux%ldl%ax)
      call mbdk_sparse_ldlt_factor_lu(aux%ldl, LDLT_TOL, stat)
    end select
  end procedure spatial_i3_matrix_renew

  module procedure spatial_i3_matrix_solve
    stat = MBDK_ERR_NOT_APPLICABLE
    select type (aux)
    type is (spatial_i3_aux_t)
      if (.not. aux%sparse) return
      call mbdk_sparse_ldlt_solve(aux%ldl, e%r)
      stat = MBDK_SUCCESS
    end select
  end procedure spatial_i3_matrix_solve

  !> The sparse path's objects (module header): C's compact rows, S's pattern (built as the
  !> model's, an object of its own: the ODE path's solves keep theirs), the body pattern, the
  !> Newton matrix's pattern and symbolic factorisation (the augmented form's: also the
  !> positions of C^T C's products and the regular path's analysis), and the bodies' colors.
  subroutine sparse_create(self, aux, book, stat, asked)
    class(mbdk_spatial_model_t), intent(in) :: self
    type(spatial_i3_aux_t), intent(inout) :: aux
    logical, intent(in) :: book
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    integer :: m, nv, nb, k, a, b, j, n, astat
    integer, allocatable :: pairs(:, :)
    m = self%m
    nv = self%nvel
    nb = self%nb
    aux%sparse = .true.
    aux%book = book
    allocate (aux%cc(m, 12), aux%ccw(m, 12), aux%g0(nv), aux%gw(nv), aux%qw(self%ncoord), &
              aux%vw(nv), aux%dlt(nv), aux%dl(2, nb), aux%fwk(3, nb), aux%nbk(3, nb), &
              aux%phiw(m), aux%gamw(m), aux%y(last_velocity(self)), aux%x(nv), aux%r(m), &
              aux%muk(m), &
              aux%rptr(m + 1), aux%rcol(12 * m), aux%rslot(12 * m), &
              pairs(2, self%nprim + self%nf), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (24.0_dp * m + 7.0_dp * nv + 8.0_dp * nb + &
                           self%ncoord + 4.0_dp * m + last_velocity(self)) + &
                           MBDK_INT_BYTES * (25.0_dp * m + 1 + 2.0_dp * (self%nprim + self%nf)), &
                           stat, asked)
    if (stat /= MBDK_SUCCESS) return
    aux%cc = 0.0_dp
    call mbdk_compact_schur_init(aux%cs, self%work%cs%rbody, nb, 6, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    ! the body graph: joints and the forces that load two bodies
    n = 0
    do k = 1, self%nprim
      n = n + 1
      pairs(:, n) = [self%prim(k)%bi, self%prim(k)%bj]
    end do
    do k = 1, self%nf
      n = n + 1
      pairs(:, n) = self%fbody(1:2, k)
      if (.not. loads_two_bodies(self%ftype(k))) pairs(:, n) = 0
    end do
    call mbdk_body_pattern_init(aux%bp, nb, pairs(:, 1:n), stat, asked, bs=6)
    if (stat /= MBDK_SUCCESS) return
    ! D's nonzeros: each row's blocks on its bodies (none on the ground)
    n = 0
    do k = 1, m
      aux%rptr(k) = n + 1
      do a = 1, 2
        b = aux%cs%rbody(a, k)
        if (b == 0) cycle
        do j = 1, 6
          n = n + 1
          aux%rcol(n) = 6 * (b - 1) + j
          aux%rslot(n) = 6 * (a - 1) + j
        end do
      end do
    end do
    aux%rptr(m + 1) = n + 1
    allocate (aux%kx(aux%bp%nnz), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * aux%bp%nnz, stat, asked)
    if (stat /= MBDK_SUCCESS) return
    if (book) then
      call mbdk_kkt_pattern_init(aux%bp%ap, aux%bp%ai(1:aux%bp%nnz), aux%rptr, aux%rcol(1:n), &
                                 aux%ldl, aux%kpos, aux%dpos_r, aux%dpos_c, stat, asked, &
                                 unsymmetric=.true.)
    else
      call mbdk_body_pattern_dtd(aux%bp, aux%rptr, aux%rcol(1:n), aux%dtd_pos, stat, asked)
      if (stat /= MBDK_SUCCESS) return
      call mbdk_sparse_ldlt_analyze(aux%ldl, nv, aux%bp%ap, aux%bp%ai, stat, asked, &
                                    unsymmetric=.true.)
      if (stat /= MBDK_SUCCESS) return
      ! the augmented form's projections: the regular path's M + beta C^T C, symmetric
      call mbdk_sparse_ldlt_analyze(aux%reg, nv, aux%bp%ap, aux%bp%ai, stat, asked)
      aux%has_reg = .true.
    end if
    if (stat /= MBDK_SUCCESS) return
    call mbdk_body_pattern_colors(aux%bp, aux%color_ptr, aux%color_body, stat, asked)
  end subroutine sparse_create

  !> g = f - C^T lam at (t, q, v) by the model's evaluation (aux's work arrays; C's compact
  !> rows into ccw).
  subroutine sparse_g(self, aux, t, q, v, lam, g, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    type(spatial_i3_aux_t), intent(inout) :: aux
    real(dp), intent(in) :: t, q(:), v(:), lam(:)
    real(dp), intent(out) :: g(:)
    integer, intent(out) :: stat
    type(frames_t) :: fr
    real(dp) :: vg, vs, power
    aux%y(1:self%ncoord) = q
    aux%y(self%ncoord + 1:self%ncoord + self%nvel) = v
    call frames(self, aux%y, fr, stat)
    if (stat /= MBDK_SUCCESS) return
    call forces(self, fr, aux%fwk, aux%nbk, vg, vs, power, stat)
    if (stat /= MBDK_SUCCESS) return
    call generalized_forces(self, fr, aux%fwk, aux%nbk, g)
    call constraints(self, fr, t, aux%phiw, aux%ccw, aux%gamw, compact=.true.)
    g = g - compact_ct(self, aux%ccw, lam)
  end subroutine sparse_g

  !> kx (aux%bp's pattern) = M - ck dg/dq - cd dg/dv at (t, e%q, e%v), g = f - C^T lam (module
  !> header; the augmented form's penalty is added by its caller)
  subroutine sparse_k(self, aux, t, e, lam, ck, cd, kx, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    type(spatial_i3_aux_t), intent(inout) :: aux
    real(dp), intent(in) :: t, ck, cd
    type(mbdk_i3_eval_t), intent(in) :: e
    real(dp), intent(in), contiguous :: lam(:)
    real(dp), intent(out), contiguous :: kx(:)
    integer, intent(out) :: stat
    real(dp) :: h0, x, cv
    integer :: c, d, k, b, a, p, pos, o, j
    associate (bp => aux%bp)
      cv = cd / ck
      call sparse_g(self, aux, t, e%q, e%v, lam, aux%g0, stat)
      if (stat /= MBDK_SUCCESS) return
      h0 = sqrt(epsilon(1.0_dp))
      do b = 1, self%nb
        o = qi(self, b)
        aux%dl(1, b) = h0 * max(1.0e-2_dp * self%length, maxval(abs(e%q(o:o + 2))))
        aux%dl(2, b) = h0
      end do
      kx = 0.0_dp
      aux%dlt = 0.0_dp
      do c = 1, size(aux%color_ptr) - 1
        do d = 1, 6
          do k = aux%color_ptr(c), aux%color_ptr(c + 1) - 1
            b = aux%color_body(k)
            aux%dlt(6 * (b - 1) + d) = aux%dl(merge(1, 2, d <= 3), b)
          end do
          call self%retract(e%q, aux%dlt, aux%qw, stat)
          if (stat /= MBDK_SUCCESS) return
          aux%vw = e%v + cv * aux%dlt
          call sparse_g(self, aux, t, aux%qw, aux%vw, lam, aux%gw, stat)
          if (stat /= MBDK_SUCCESS) return
          do k = aux%color_ptr(c), aux%color_ptr(c + 1) - 1
            b = aux%color_body(k)
            j = 6 * (b - 1) + d
            x = -ck / aux%dlt(j)
            aux%dlt(j) = 0.0_dp
            do p = bp%bptr(b), bp%bptr(b + 1) - 1
              a = bp%nbr(p)
              o = 6 * (a - 1)
              pos = mbdk_body_pattern_pos(bp, o + 1, j)
              kx(pos:pos + 5) = x * (aux%gw(o + 1:o + 6) - aux%g0(o + 1:o + 6))
            end do
          end do
        end do
      end do
      call add_mass_blocks(self, bp, kx)
    end associate
  end subroutine sparse_k

  !> kx += M in the body pattern bp
  subroutine add_mass_blocks(self, bp, kx)
    class(mbdk_spatial_model_t), intent(in) :: self
    type(mbdk_body_pattern_t), intent(in) :: bp
    real(dp), intent(inout) :: kx(:)
    integer :: b, o, i, pos
    do b = 1, self%nb
      o = 6 * (b - 1)
      do i = 1, 3
        pos = mbdk_body_pattern_pos(bp, o + i, o + i)
        kx(pos) = kx(pos) + self%mass(b)
        pos = mbdk_body_pattern_pos(bp, o + 4, o + 3 + i)
        kx(pos:pos + 2) = kx(pos:pos + 2) + self%inertia(:, i, b)
      end do
    end do
  end subroutine add_mass_blocks

  !> kx += w C^T C in the body pattern, C the compact rows of the last evaluation (aux's lists;
  !> kx may be one of aux's arrays, so aux comes in by its parts)
  subroutine add_ctc(cc, rptr, rslot, dtd_pos, w, kx)
    real(dp), intent(in) :: cc(:, :), w
    integer, intent(in) :: rptr(:), rslot(:), dtd_pos(:)
    real(dp), intent(inout) :: kx(:)
    integer :: r, i, j, n
    real(dp) :: x
    n = 0
    do r = 1, size(rptr) - 1
      do j = rptr(r), rptr(r + 1) - 1
        x = w * cc(r, rslot(j))
        do i = rptr(r), rptr(r + 1) - 1
          n = n + 1
          kx(dtd_pos(n)) = kx(dtd_pos(n)) + x * cc(r, rslot(i))
        end do
      end do
    end do
  end subroutine add_ctc

  !> The regular path's beta = AL_KAPPA max(diag M) / max |C_i|^2 from C's rows c (dense or
  !> compact: a row's squares sum alike); w(nvel) a work array.
  real(dp) function regular_beta(self, c, w) result(beta)
    class(mbdk_spatial_model_t), intent(in) :: self
    real(dp), intent(in) :: c(:, :)
    real(dp), intent(inout) :: w(:)
    real(dp) :: cmax
    integer :: k
    cmax = 0.0_dp
    do k = 1, self%m
      cmax = max(cmax, sum(c(k, :)**2))
    end do
    if (.not. (cmax > 0.0_dp)) cmax = 1.0_dp
    call spatial_mass_diagonal(self, w)
    beta = AL_KAPPA * maxval(w) / cmax
  end function regular_beta

  !> The sparse regular path's matrix M + beta C^T C (beta as the dense path's) in aux%reg,
  !> factorised (symmetric, positive definite whatever C's rank).
  subroutine sparse_regular(self, aux, stat)
    class(mbdk_spatial_model_t), intent(in) :: self
    type(spatial_i3_aux_t), intent(inout) :: aux
    integer, intent(out) :: stat
    aux%beta = regular_beta(self, aux%cc, aux%x)
    aux%reg%ax = 0.0_dp
    call add_mass_blocks(self, aux%bp, aux%reg%ax)
    call add_ctc(aux%cc, aux%rptr, aux%rslot, aux%dtd_pos, aux%beta, aux%reg%ax)
    call mbdk_sparse_ldlt_factor(aux%reg, LDLT_TOL, stat)
  end subroutine sparse_regular

  !> The book matrix's values into aux%ldl%ax: K (aux%kx) and C's compact rows at the last
  !> evaluation in both off-diagonal blocks.
  subroutine kkt_values(self, aux)
    class(mbdk_spatial_model_t), intent(in) :: self
    type(spatial_i3_aux_t), intent(inout) :: aux
    integer :: p, r, j
    real(dp) :: x
    associate (ax => aux%ldl%ax)
      ax = 0.0_dp
      do p = 1, size(aux%kx)
        ax(aux%kpos(p)) = ax(aux%kpos(p)) + aux%kx(p)
      end do
      do r = 1, self%m
        do j = aux%rptr(r), aux%rptr(r + 1) - 1
          x = aux%cc(r, aux%rslot(j))
          ax(aux%dpos_r(j)) = ax(aux%dpos_r(j)) + x
          ax(aux%dpos_c(j)) = ax(aux%dpos_c(j)) + x
        end do
      end do
    end associate
  end subroutine kkt_values

end submodule mbdk_spatial_i3
