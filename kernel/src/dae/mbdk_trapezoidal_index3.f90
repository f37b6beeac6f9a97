!> trapezoidal_index3: direct integration of the index-3 DAE of a planar scene
!>
!>   M q'' + D(q)^T lambda = f(q, q', t),   Phi(q, t) = 0
!>
!> by the implicit trapezoidal rule (Fekete (2023) 3.2.1). With s = h^2/4 and the trapezoidal
!> relations (3.12)-(3.13),
!>   v+ = (2/h)(q+ - q) - v,     a+ = (4/h^2)(q+ - q) - (4/h) v - a,
!> the equations of motion at t+ = t + h, multiplied by s (3.15), read
!>   r(q+, lambda+) = M (q+ - qhat) + s (D^T lambda+ - f) = 0,   qhat = q + h v + s a.
!>
!> Formulations (mbdk_index3_opt_t%formulation):
!>   1 index3     the book's scheme: Newton-Raphson (3.16) on (q+, lambda+) for r = 0 and
!>                Phi(q+) = 0, multiplier predictor lambda+ = 2 lambda - lambda- (3.11), position
!>                predictor q + h v + (h^2/2) a. v+ and a+ follow from the trapezoidal relations
!>                and do not satisfy Phi' = 0, Phi'' = 0: the weakness the book names.
!>   2 augmented  the index-3 augmented Lagrangian with projections (ALI3-P: Bayo and Ledesma
!>                1996; Cuadrado, Cardenal and Bayo 1997; the family the book cites in [6], [20],
!>                [23]): Newton on q+ alone for
!>                  M (q+ - qhat) + s (D^T (lam* + alpha Phi) - f) = 0,
!>                with lam* <- lam* + alpha Phi after every iteration (lam* starts from the last
!>                step's multipliers), then mass-orthogonal projections of v+ onto D v + Phi_t = 0
!>                and of a+ onto D a = gamma (KKT solves with M). lambda+ = lam* + alpha Phi.
!>                Parameters: alpha (penalty factor, force per unit of Phi; default 1e8: on
!>                the double pendulum at h = 1e-3, alpha = 1e7 needs 17 Newton iterations per
!>                step, 1e8 5.5; on the four-bar at h = 5e-3, alpha >= 1e9 stalls Newton) and
!>                newton_max_iter (default 20).
!>
!> Newton matrix (analytic; tangent stiffness and damping of the force elements from
!> mbdk_forces_tangent, geometric stiffness of the joints from mbdk_joints_tangent):
!>   index3:    [M + s (K_c + K_f) + (h/2) C_f, D^T; D, 0] in the unknowns (dq, s dlambda)
!>   augmented: M + s (K_c + K_f + alpha D^T D) + (h/2) C_f
!> The book scales both rows by s (3.15)-(3.16) with lambda itself as unknown: its matrix
!> [M + .., s D^T; s D, 0] has a condition number growing like h^-4. Scaling the unknown to
!> s lambda and leaving Phi unscaled gives the same Newton iterates (row and column scalings do
!> not change Newton's steps) with a condition number bounded as h -> 0 (studies/index3.py
!> measures both; mbdk_index3_newton_matrix builds all three forms).
!> The matrix is factorised by LAPACK (dgetrf) and reused across iterations and steps while
!> Newton contracts; it is rebuilt at the current iterate when the contraction rate exceeds
!> 0.5, when the step size changes, or when an update grows with an old matrix. A step converges when the weighted update norm
!> (atol + rtol |q|) is below 1 and max |Phi| <= atol; after newton_max_iter iterations with a
!> fresh matrix it fails with MBDK_ERR_NEWTON_DIVERGED (a singular matrix: SINGULAR_MATRIX).
!>
!> Per step the solve records the Newton iterations (iters_out at each sample: those of the step
!> that produced it) and counts factorizations in the stats.
module mbdk_trapezoidal_index3
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_model, only: mbdk_model_t, mbdk_model_constraints, mbdk_model_accelerations
  use mbdk_joints, only: mbdk_joints_tangent
  use mbdk_force_elements, only: mbdk_forces_eval, mbdk_forces_tangent
  use mbdk_lapack, only: mbdk_lu_factor, mbdk_lu_solve
  use mbdk_fixed_step, only: mbdk_step_plan
  implicit none
  private
  public :: mbdk_index3_solve, mbdk_index3_newton_matrix

  integer, parameter, public :: MBDK_INDEX3_BOOK = 1, MBDK_INDEX3_AUGMENTED = 2
  integer, parameter, public :: MBDK_INDEX3_UNSCALED = 0, MBDK_INDEX3_SCALED_BOOK = 1, &
    MBDK_INDEX3_SCALED = 2

  type, public :: mbdk_index3_opt_t
    integer :: formulation = MBDK_INDEX3_BOOK
    real(dp) :: h = 1.0e-3_dp
    integer :: every = 1
    real(dp) :: rtol = 1.0e-10_dp, atol = 1.0e-12_dp
    integer :: newton_max_iter = 20
    real(dp) :: alpha = 1.0e8_dp
  end type mbdk_index3_opt_t

contains

  !> The Newton matrix at (q, v, lam, t) for step h: scaling UNSCALED (rows M a + D^T lam - f and
  !> Phi, unknowns dq, dlam), SCALED_BOOK (both rows times s = h^2/4, (3.15)-(3.16)) or SCALED
  !> (dynamic rows times s, unknown s lam, Phi unscaled: what the solver uses). jac(nc+m, nc+m).
  subroutine mbdk_index3_newton_matrix(model, t, q, v, lam, h, scaling, jac, stat)
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(in) :: t, q(:), v(:), lam(:), h
    integer, intent(in) :: scaling
    real(dp), intent(out) :: jac(:, :)
    integer, intent(out) :: stat
    real(dp) :: s
    integer :: nc, m
    nc = model%nc
    m = model%m
    s = 0.25_dp * h * h
    call book_matrix(model, t, q, v, lam, h, jac, stat)
    if (stat /= MBDK_SUCCESS) return
    select case (scaling)
    case (MBDK_INDEX3_UNSCALED)
      jac(1:nc, 1:nc) = jac(1:nc, 1:nc) / s
    case (MBDK_INDEX3_SCALED_BOOK)
      jac(1:nc, nc + 1:) = s * jac(1:nc, nc + 1:)
      jac(nc + 1:, 1:nc) = s * jac(nc + 1:, 1:nc)
    case (MBDK_INDEX3_SCALED)
      continue
    case default
      stat = MBDK_ERR_INVALID_INPUT
    end select
  end subroutine mbdk_index3_newton_matrix

  !> [M + s (K_c(lam) + K_f) + (h/2) C_f, D^T; D, 0] at (q, v, lam, t).
  subroutine book_matrix(model, t, q, v, lam, h, jac, stat)
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(in) :: t, q(:), v(:), lam(:), h
    real(dp), intent(out) :: jac(:, :)
    integer, intent(out) :: stat
    real(dp) :: kk(model%nc, model%nc), cc(model%nc, model%nc), phi(model%m)
    real(dp) :: d(model%m, model%nc), gam(model%m), phit(model%m), s
    integer :: nc, m, i
    nc = model%nc
    m = model%m
    s = 0.25_dp * h * h
    kk = 0.0_dp
    cc = 0.0_dp
    call mbdk_forces_tangent(model%fint, model%freal, q, v, t, kk, cc, stat)
    if (stat /= MBDK_SUCCESS) return
    if (m > 0) call mbdk_joints_tangent(model%jint, model%jreal, model%row0, q, lam, kk)
    call mbdk_model_constraints(model, t, q, v, phi, d, gam, phit)
    jac = 0.0_dp
    jac(1:nc, 1:nc) = s * kk + 0.5_dp * h * cc
    do i = 1, nc
      jac(i, i) = jac(i, i) + model%mass(i)
    end do
    if (m > 0) then
      jac(nc + 1:nc + m, 1:nc) = d
      jac(1:nc, nc + 1:nc + m) = transpose(d)
    end if
  end subroutine book_matrix

  !> Integrates the scene from (q, v) = y0 over [t0, t_end] with step opt%h. Samples: t_out,
  !> y_out (= [q; v]), a_out, lam_out, iters_out (Newton iterations of the step). nwritten
  !> samples are valid; on failure the samples before it are kept.
  subroutine mbdk_index3_solve(model, opt, t0, t_end, y0, t_out, y_out, a_out, lam_out, &
                               iters_out, nwritten, st, stat)
    type(mbdk_model_t), intent(in) :: model
    type(mbdk_index3_opt_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_end, y0(:)
    real(dp), intent(out) :: t_out(:), y_out(:, :), a_out(:, :), lam_out(:, :)
    integer, intent(out) :: iters_out(:), nwritten
    type(mbdk_stats_t), intent(out) :: st
    integer, intent(out) :: stat
    integer(i8) :: nsteps, i
    integer :: nsamp, nc, m, nk, iters, plan_stat
    logical :: shortened, have_lu
    real(dp) :: q(model%nc), v(model%nc), a(model%nc), lam(model%m), lam_old(model%m)
    real(dp) :: t, tn, h, h_lu, cpu0, cpu1
    real(dp), allocatable :: lu(:, :)
    integer, allocatable :: ipiv(:)

    nwritten = 0
    stat = MBDK_ERR_INVALID_INPUT
    nc = model%nc
    m = model%m
    if (opt%formulation /= MBDK_INDEX3_BOOK .and. opt%formulation /= MBDK_INDEX3_AUGMENTED) return
    if (.not. (opt%rtol >= 0.0_dp .and. opt%atol > 0.0_dp) .or. opt%newton_max_iter < 1) return
    if (opt%formulation == MBDK_INDEX3_AUGMENTED .and. .not. (opt%alpha > 0.0_dp)) return
    if (size(y0) /= 2 * nc) return
    call mbdk_step_plan(t0, t_end, opt%h, opt%every, nsteps, nsamp, shortened, plan_stat)
    if (plan_stat < 0) return
    if (size(t_out) < nsamp .or. size(y_out, 2) < nsamp .or. size(a_out, 2) < nsamp .or. &
        size(lam_out, 2) < nsamp .or. size(iters_out) < nsamp) then
      stat = MBDK_ERR_OUTPUT_SIZE
      return
    end if
    nk = nc
    if (opt%formulation == MBDK_INDEX3_BOOK) nk = nc + m
    allocate (lu(nk, nk), ipiv(nk))
    call cpu_time(cpu0)

    q = y0(1:nc)
    v = y0(nc + 1:)
    t = t0
    ! consistent a and lambda at t0: the reduced formulation's solve
    call mbdk_model_accelerations(model, t, q, v, a, lam, stat)
    if (stat /= MBDK_SUCCESS) return
    lam_old = lam
    st%rhs_evals = 1
    call write_sample(0)
    have_lu = .false.
    h_lu = 0.0_dp
    do i = 1, nsteps
      tn = t0 + real(i, dp) * opt%h
      if (i == nsteps) tn = t_end
      h = tn - t
      if (opt%formulation == MBDK_INDEX3_BOOK) then
        call step_book(stat)
      else
        call step_augmented(stat)
      end if
      if (stat /= MBDK_SUCCESS) exit
      t = tn
      st%steps = st%steps + 1
      if (mod(i, int(opt%every, i8)) == 0 .or. i == nsteps) call write_sample(iters)
    end do
    call cpu_time(cpu1)
    st%cpu_time = cpu1 - cpu0
    if (stat == MBDK_SUCCESS .and. shortened) stat = MBDK_NOTE_LAST_STEP_SHORTENED

  contains

    subroutine write_sample(it)
      integer, intent(in) :: it
      nwritten = nwritten + 1
      t_out(nwritten) = t
      y_out(1:nc, nwritten) = q
      y_out(nc + 1:2 * nc, nwritten) = v
      a_out(1:nc, nwritten) = a
      if (m > 0) lam_out(1:m, nwritten) = lam
      iters_out(nwritten) = it
    end subroutine write_sample

    !> f at (q+, v+, t+) and the constraint quantities; s-scaled residual r(1:nc).
    subroutine residual(qn, vn, lmb, r, phi, d, gam, phit, s, qhat, ierr)
      real(dp), intent(in) :: qn(:), vn(:), lmb(:), s, qhat(:)
      real(dp), intent(out) :: r(:), phi(:), d(:, :), gam(:), phit(:)
      integer, intent(out) :: ierr
      real(dp) :: fq(nc)
      integer :: k
      fq = 0.0_dp
      call mbdk_forces_eval(model%fint, model%freal, model%mass, qn, vn, tn, fq, &
                            model%work%visits(5:), ierr)
      if (ierr /= MBDK_SUCCESS) return
      st%rhs_evals = st%rhs_evals + 1
      d = 0.0_dp
      if (m > 0) call mbdk_model_constraints(model, tn, qn, vn, phi, d, gam, phit)
      do k = 1, nc
        r(k) = model%mass(k) * (qn(k) - qhat(k)) - s * fq(k)
      end do
      if (m > 0) r = r + s * matmul(lmb, d)
    end subroutine residual

    subroutine factor(mat, ierr)
      real(dp), intent(in) :: mat(:, :)
      integer, intent(out) :: ierr
      lu = mat
      call mbdk_lu_factor(lu, ipiv, ierr)
      st%lu_factorizations = st%lu_factorizations + 1
      st%jac_evals = st%jac_evals + 1
      have_lu = ierr == MBDK_SUCCESS
      h_lu = h
    end subroutine factor

    logical function finite_all(x)
      real(dp), intent(in) :: x(:)
      finite_all = all(abs(x) <= huge(1.0_dp))
    end function finite_all

    !> max |Phi| accepted: atol, but not below the roundoff of the coordinates.
    real(dp) function phi_tol(x)
      real(dp), intent(in) :: x(:)
      phi_tol = max(opt%atol, 64.0_dp * epsilon(1.0_dp) * max(1.0_dp, maxval(abs(x))))
    end function phi_tol

    real(dp) function wnorm(dx, x)
      real(dp), intent(in) :: dx(:), x(:)
      wnorm = maxval(abs(dx) / (opt%atol + opt%rtol * abs(x)))
    end function wnorm

    subroutine step_book(ierr)
      integer, intent(out) :: ierr
      real(dp) :: s, qhat(nc), qn(nc), vn(nc), lmb(m), r(nc + m), phi(m), d(m, nc), gam(m)
      real(dp) :: phit(m), jac(nc + m, nc + m), dnorm, dnorm_old, rate
      logical :: fresh
      s = 0.25_dp * h * h
      qhat = q + h * v + s * a
      qn = q + h * v + 0.5_dp * h * h * a
      lmb = 2.0_dp * lam - lam_old                                  ! (3.11)
      if (have_lu .and. abs(h - h_lu) > 1.0e-12_dp * h) have_lu = .false.
      fresh = .false.
      dnorm_old = huge(1.0_dp)
      iters = 0
      do
        vn = (2.0_dp / h) * (qn - q) - v
        call residual(qn, vn, lmb, r(1:nc), phi, d, gam, phit, s, qhat, ierr)
        if (ierr /= MBDK_SUCCESS) return
        r(nc + 1:) = phi
        if (.not. have_lu) then
          call book_matrix(model, tn, qn, vn, lmb, h, jac, ierr)
          if (ierr /= MBDK_SUCCESS) return
          call factor(jac, ierr)
          if (ierr /= MBDK_SUCCESS) return
          fresh = .true.
        end if
        r = -r
        call mbdk_lu_solve(lu, ipiv, r, ierr)
        if (ierr /= MBDK_SUCCESS) return
        if (.not. finite_all(r)) then
          ierr = MBDK_ERR_NONFINITE
          return
        end if
        iters = iters + 1
        st%newton_iterations = st%newton_iterations + 1
        dnorm = wnorm(r(1:nc), qn)
        rate = dnorm / dnorm_old
        if (rate > 1.0_dp .and. iters > 1 .and. dnorm > 1.0_dp .and. .not. fresh) then
          ! growing with an old matrix (not just roundoff below the tolerance): rebuild it at
          ! this iterate and take a true Newton step instead
          have_lu = .false.
          dnorm_old = huge(1.0_dp)
          cycle
        end if
        qn = qn + r(1:nc)
        lmb = lmb + r(nc + 1:) / s
        if (dnorm <= 1.0_dp .and. (m == 0 .or. maxval(abs(phi)) <= phi_tol(qn))) exit
        if (iters >= opt%newton_max_iter) then
          ierr = MBDK_ERR_NEWTON_DIVERGED
          return
        end if
        if (rate > 0.5_dp) have_lu = .false.
        fresh = .false.
        dnorm_old = dnorm
      end do
      ! converged: the last update is below tolerance and Phi, checked before it, was too
      vn = (2.0_dp / h) * (qn - q) - v
      a = (4.0_dp / (h * h)) * (qn - q) - (4.0_dp / h) * v - a
      lam_old = lam
      lam = lmb
      q = qn
      v = vn
      if (.not. (finite_all(q) .and. finite_all(v))) ierr = MBDK_ERR_NONFINITE
    end subroutine step_book

    subroutine step_augmented(ierr)
      integer, intent(out) :: ierr
      real(dp) :: s, qhat(nc), qn(nc), vn(nc), an(nc), lstar(m), r(nc), phi(m), d(m, nc)
      real(dp) :: gam(m), phit(m), jac(nc, nc), dnorm, dnorm_old, rate, lt(m)
      logical :: fresh
      integer :: k
      s = 0.25_dp * h * h
      qhat = q + h * v + s * a
      qn = q + h * v + 0.5_dp * h * h * a
      lstar = lam
      if (have_lu .and. abs(h - h_lu) > 1.0e-12_dp * h) have_lu = .false.
      fresh = .false.
      dnorm_old = huge(1.0_dp)
      iters = 0
      do
        vn = (2.0_dp / h) * (qn - q) - v
        phi = 0.0_dp
        if (m > 0) call mbdk_model_constraints(model, tn, qn, vn, phi, d, gam, phit)
        if (iters > 0) lstar = lstar + opt%alpha * phi
        lt = lstar + opt%alpha * phi
        call residual(qn, vn, lt, r, phi, d, gam, phit, s, qhat, ierr)
        if (ierr /= MBDK_SUCCESS) return
        if (.not. have_lu) then
          call augmented_matrix(qn, vn, lt, d, s, jac, ierr)
          if (ierr /= MBDK_SUCCESS) return
          call factor(jac, ierr)
          if (ierr /= MBDK_SUCCESS) return
          fresh = .true.
        end if
        r = -r
        call mbdk_lu_solve(lu, ipiv, r, ierr)
        if (ierr /= MBDK_SUCCESS) return
        if (.not. finite_all(r)) then
          ierr = MBDK_ERR_NONFINITE
          return
        end if
        iters = iters + 1
        st%newton_iterations = st%newton_iterations + 1
        dnorm = wnorm(r, qn)
        rate = dnorm / dnorm_old
        if (rate > 1.0_dp .and. iters > 1 .and. dnorm > 1.0_dp .and. .not. fresh) then
          have_lu = .false.
          dnorm_old = huge(1.0_dp)
          cycle
        end if
        qn = qn + r
        if (dnorm <= 1.0_dp .and. (m == 0 .or. maxval(abs(phi)) <= phi_tol(qn))) exit
        if (iters >= opt%newton_max_iter) then
          ierr = MBDK_ERR_NEWTON_DIVERGED
          return
        end if
        if (rate > 0.5_dp) have_lu = .false.
        fresh = .false.
        dnorm_old = dnorm
      end do
      vn = (2.0_dp / h) * (qn - q) - v
      an = (4.0_dp / (h * h)) * (qn - q) - (4.0_dp / h) * v - a
      if (m > 0) then
        call mbdk_model_constraints(model, tn, qn, vn, phi, d, gam, phit)
        lam = lstar + opt%alpha * phi
        ! mass-orthogonal projections: v onto D v + Phi_t = 0, a onto D a = gamma
        call project(d, -(matmul(d, vn) + phit), vn, ierr)
        if (ierr /= MBDK_SUCCESS) return
        call mbdk_model_constraints(model, tn, qn, vn, phi, d, gam, phit)
        call project(d, gam - matmul(d, an), an, ierr)
        if (ierr /= MBDK_SUCCESS) return
      end if
      q = qn
      v = vn
      a = an
      do k = 1, nc
        if (.not. abs(q(k)) <= huge(1.0_dp)) ierr = MBDK_ERR_NONFINITE
      end do
    end subroutine step_augmented

    subroutine augmented_matrix(qn, vn, lt, d, s, jac, ierr)
      real(dp), intent(in) :: qn(:), vn(:), lt(:), d(:, :), s
      real(dp), intent(out) :: jac(:, :)
      integer, intent(out) :: ierr
      real(dp) :: full(nc + m, nc + m)
      call book_matrix(model, tn, qn, vn, lt, h, full, ierr)
      if (ierr /= MBDK_SUCCESS) return
      jac = full(1:nc, 1:nc)
      if (m > 0) jac = jac + (s * opt%alpha) * matmul(transpose(d), d)
    end subroutine augmented_matrix

    !> x += dx with M dx + D^T mu = 0, D dx = rc (the mass-orthogonal correction).
    subroutine project(d, rc, x, ierr)
      real(dp), intent(in) :: d(:, :), rc(:)
      real(dp), intent(inout) :: x(:)
      integer, intent(out) :: ierr
      real(dp) :: kkt(nc + m, nc + m), rhs(nc + m)
      integer :: piv(nc + m), k
      kkt = 0.0_dp
      do k = 1, nc
        kkt(k, k) = model%mass(k)
      end do
      kkt(nc + 1:, 1:nc) = d
      kkt(1:nc, nc + 1:) = transpose(d)
      rhs = 0.0_dp
      rhs(nc + 1:) = rc
      call mbdk_lu_factor(kkt, piv, ierr)
      if (ierr /= MBDK_SUCCESS) return
      call mbdk_lu_solve(kkt, piv, rhs, ierr)
      if (ierr /= MBDK_SUCCESS) return
      x = x + rhs(1:nc)
    end subroutine project

  end subroutine mbdk_index3_solve

end module mbdk_trapezoidal_index3
