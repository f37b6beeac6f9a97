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
!> Formulations (mbdk_index3_options_t%formulation):
!>   1 index3     the book's scheme: Newton-Raphson (3.16) on (q+, lambda+) for r = 0 and
!>                Phi(q+) = 0, multiplier predictor (3.11) lambda+ = lambda + (h/h-)(lambda -
!>                lambda-), position predictor q + h v + (h^2/2) a. v+ and a+ follow from the
!>                trapezoidal relations and do not satisfy Phi' = 0, Phi'' = 0: the weakness the
!>                book names. Worse, the errors of v and a in the constraint directions
!>                alternate in sign from step to step with a growing amplitude (the trapezoidal
!>                rule on an index-3 system is unstable there: Cardona and Geradin 1989): on the
!>                double pendulum, the four-bar and the crane |D a - gamma| grows about 15-fold
!>                per 1.4 s whatever h, until Newton fails after a few seconds (5.0 s on the
!>                four-bar, 10.7 s on the double pendulum at h = 1e-3: studies/index3.py).
!>   2 augmented  the index-3 augmented Lagrangian with projections (ALI3-P: Bayo and Ledesma
!>                1996; Cuadrado, Cardenal and Bayo 1997; the family the book cites in [6], [20],
!>                [23]): Newton on q+ alone for
!>                  M (q+ - qhat) + s (D^T (lam* + alpha Phi) - f) = 0,
!>                with lam* <- lam* + alpha Phi after every iteration, from the predictor
!>                q + h v + s (a + a_x), a_x = a + (h/h-)(a - a-) (the rule itself with a+
!>                extrapolated: O(h^4)) and lam* extrapolated likewise. Then the mass-orthogonal
!>                projections of v+ onto D v + Phi_t = 0 and of a+ onto D a = gamma (one
!>                factorisation of [M D^T; D 0], through D M^-1 D^T when M > 0), computed so that
!>                the Newton error of q+ is not amplified: P removes every M^-1 D^T term, so
!>                  v+ = P (v + (h/2)(a + a~)),  a~ any solution of M a~ = f - D^T (..),
!>                equals P (2/h (q+ - q) - v) once Newton has converged, without its 2/h times
!>                the Newton error; and a+, lambda+ solve M a + D^T lambda = f, D a = gamma(q+,
!>                v+), the projection of a+ with its multipliers (second order), without the
!>                4/h^2 times the Newton error of the trapezoidal a+. Taken from the relations,
!>                a Newton tolerance of 1e-10 capped the error at 1e-5 on the double pendulum
!>                (10 s) and made it grow as h fell below 3e-4; now the error is second order
!>                down to h = 6e-5 (1.9e-7) and the Newton tolerance adds below 2 %. Without
!>                constraints the same path gives a+ = M^-1 f.
!>                Parameters: alpha, the penalty factor (force per unit of Phi). Default
!>                alpha = 0: at every step alpha = KAPPA max(M) / s, KAPPA = 1e3, so that s alpha
!>                D^T D outweighs M a thousandfold whatever h; then Phi shrinks about 1000-fold
!>                per multiplier update. A fixed alpha (the literature's 1e7-1e9) converges
!>                slowly at small h (s alpha ~ M: the step-size controller then stalls) and
!>                makes the matrix ill-conditioned at large h. newton_max_iter: default 20.
!>
!> Newton matrix (analytic; tangent stiffness and damping of the force elements from
!> mbdk_forces_tangent, geometric stiffness of the joints from mbdk_joints_tangent):
!>   index3:    [M + s (K_c(lambda) + K_f) + (h/2) C_f, D^T; D, 0] in the unknowns (dq, s dlambda)
!>   augmented: M + s (K_c(lam*) + K_f + alpha D^T D) + (h/2) C_f. K_c takes lam* without
!>              alpha Phi: that term vanishes at the solution, and far from it (the predictor)
!>              it inflates the geometric stiffness until Newton's first step overshoots.
!> The book scales both rows by s (3.15)-(3.16) with lambda itself as unknown: its matrix
!> [M + .., s D^T; s D, 0] has a condition number growing like h^-4. Scaling the unknown to
!> s lambda and leaving Phi unscaled gives the same Newton iterates (row and column scalings do
!> not change Newton's steps) with a condition number bounded as h -> 0 (studies/index3.py
!> measures both; mbdk_index3_newton_matrix builds all three forms).
!>
!> Newton. Up to MBDK_SMALL_DENSE_MAX rows the matrix is factorised in-house (LAPACK's call
!> overhead dominates such systems; model%small_dense = false, or more rows, take LAPACK's
!> dgetrf/dgetrs): the augmented form's matrix, when symmetric to roundoff (no dampers: their
!> tangent stiffness is unsymmetric) and positive definite, by the block LDL^T with the bodies as
!> 3 x 3 pivot blocks (half the cost of the LU: 0.76 us per step on the double pendulum at
!> h = 1e-3 against 1.2 us); otherwise by the LU with partial pivoting. An LU that has served two
!> solves forms its explicit inverse for the next ones (a fixed-length column product, a quarter
!> of the triangular sweeps at 10 rows: the book scheme's matrix serves about 30 solves;
!> stats%nlu counts either kind). The matrix is reused across iterations and steps
!> while Newton contracts. It is rebuilt at the current iterate when the contraction rate exceeds
!> 0.5 or two more iterations at the current rate would not reach the tolerance (an iteration
!> costs about a factorisation), and when h changes. When an update grows with an old matrix, the
!> step restarts once from the predictor with a matrix built there (the augmented form's
!> multiplier update can spoil the iterate beyond repair), and the next 8 steps start with fresh
!> matrices, twice as many after each such failure until a step is served by an old matrix again
!> (with alpha D^T D a thousand times M, a matrix from the last step fails once h |omega| is above
!> about 1e-3). A step converges when the update computed at an iterate is below 1 in the weighted
!> norm (atol + rtol |q|) and max |Phi| <= atol there (not below 64 eps max|q|); that last update
!> is applied. At least two evaluations per step, so both tests are made on evaluated residuals,
!> never on predicted ones. After newton_max_iter updates it fails with MBDK_ERR_NEWTON_DIVERGED
!> (a singular matrix: SINGULAR_MATRIX).
!>
!> Step size. Fixed: opt%h, samples every opt%every steps (mbdk_step_plan). In the augmented
!> form a step whose Newton iteration fails (diverges, meets a singular matrix or a non-finite
!> iterate: typically near a singular configuration, where D loses rank) is retried in
!> substeps, quartered at each failure (stats%newton_failures) and doubled back after each
!> success, down to h / 4^5; the samples stay on the grid. Only below that is the failure
!> returned. The book's scheme is not retried: its failures come from the growing oscillation
!> of its v and a, which substeps do not cure (retried, it went on for 100 s on the double
!> pendulum with |Phi| = 0.08 and the energy lost). Adaptive
!> (opt%adaptive, augmented form only): from the initial step opt%h, the local error of q and
!> v (multipliers excluded, as index-3 codes do), -h^3/12 q(3) and -h^3/12 q(4) with the
!> derivatives from divided differences of the step-mean accelerations, is measured in the
!> weighted RMS norm (err_atol + err_rtol |y|). err <= 1 accepts the step; the next
!> h = h min(5, max(0.2, 0.9 err^(-1/3))), held while that would grow it by less than 20 %
!> (the matrix stays valid; a change of 5 % or less keeps the old matrix too). A rejected step is
!> retried with that h (stats%rejected_steps); a Newton failure retries at h/4
!> (stats%newton_failures); below h_min (default 1e-12 of the interval) the solve ends with
!> MBDK_ERR_STEP_TOO_SMALL. Samples every opt%dt_out, landed on exactly (a step within 1.1 h of
!> a sample is stretched to it, within 2 h halved). The book's scheme is refused
!> (MBDK_ERR_NOT_APPLICABLE): its velocity error in the constraint directions grows without
!> bound, and any error test on v would shrink h forever.
!>
!> The caller's interrupt flag (opt%interrupt) is polled before every step (fixed: every output
!> step); set, the solve ends with MBDK_ERR_INTERRUPTED and keeps its samples.
!>
!> Per step the solve records the Newton iterations (iters_out at each sample: those of the step
!> that produced it; every update computed, the last, converged one included) and counts
!> factorizations in the stats.
module mbdk_trapezoidal_index3
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use, intrinsic :: iso_c_binding, only: c_int, c_double, c_intptr_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_clock, only: mbdk_timer_t, mbdk_timer_start, mbdk_timer_stop
  use mbdk_interrupt, only: mbdk_interrupted
  use mbdk_model, only: mbdk_model_t, mbdk_model_constraints, mbdk_model_accelerations, &
    MBDK_MODEL_SINGULAR_TOL
  use mbdk_joints, only: mbdk_joints_tangent, mbdk_joints_eval, mbdk_joints_scatter, &
    mbdk_body_rotations, MBDK_JOINT_TYPES
  use mbdk_force_elements, only: mbdk_forces_eval, mbdk_forces_tangent
  use mbdk_lapack, only: mbdk_lu_factor, mbdk_lu_solve
  use mbdk_sparse_schur, only: mbdk_sparse_schur_assemble, mbdk_sparse_d_times, &
    mbdk_sparse_w_residual, mbdk_sparse_dtd_add
  use mbdk_small_dense, only: mbdk_small_ldlt_factor, mbdk_small_ldlt_solve, mbdk_small_lu_factor, &
    mbdk_small_lu_solve, mbdk_small_lu_inverse, mbdk_small_inverse_apply, MBDK_SMALL_DENSE_MAX
  use mbdk_fixed_step, only: mbdk_step_plan
  implicit none
  private
  public :: mbdk_index3_solve, mbdk_index3_newton_matrix, mbdk_index3_plan

  integer, parameter, public :: MBDK_INDEX3_BOOK = 1, MBDK_INDEX3_AUGMENTED = 2
  !> alpha = 0 (the default): alpha = KAPPA max(M) / s at every step, so that the penalty term
  !> s alpha D^T D outweighs the mass matrix by KAPPA whatever h (see the module header).
  real(dp), parameter, public :: MBDK_INDEX3_KAPPA = 1.0e3_dp
  !> fixed step: a step whose Newton iteration fails is retried in substeps down to h / 4^this
  integer, parameter, public :: MBDK_INDEX3_MAX_CUTS = 5
  !> a pivot of the augmented matrix's LDL^T at or below this times its largest diagonal entry:
  !> not positive definite enough, the LU is used
  real(dp), parameter :: LDLT_TOL = 1.0e-14_dp
  integer, parameter, public :: MBDK_INDEX3_UNSCALED = 0, MBDK_INDEX3_SCALED_BOOK = 1, &
    MBDK_INDEX3_SCALED = 2

  !> Options of a solve, by name with defaults. bind(C): the same struct is struct
  !> mbdk_index3_options in mbdk.h and mbdk.options.Index3Options in Python (tests/test_structs.py
  !> and kernel/tests/c_struct_layout.c check that the three agree field by field).
  type, bind(C), public :: mbdk_index3_options_t
    real(c_double) :: h = 1.0e-3_c_double              !< fixed step, or the first step (adaptive)
    real(c_double) :: newton_rtol = 1.0e-10_c_double   !< on the position update
    real(c_double) :: newton_atol = 1.0e-12_c_double   !< and max |Phi| <= newton_atol
    real(c_double) :: alpha = 0.0_c_double             !< augmented penalty; 0: KAPPA max(M) / s per step
    real(c_double) :: err_rtol = 1.0e-6_c_double       !< adaptive: local error tolerances on q and v
    real(c_double) :: err_atol = 1.0e-8_c_double
    real(c_double) :: dt_out = 0.0_c_double            !< adaptive: sample interval
    real(c_double) :: h_min = 0.0_c_double             !< adaptive: 0 = 1e-12 of the interval
    real(c_double) :: h_max = 0.0_c_double             !< adaptive: 0 = the interval
    !> address of a C int the caller may set non-zero to stop the solve (MBDK_ERR_INTERRUPTED)
    integer(c_intptr_t) :: interrupt = 0
    integer(c_int) :: formulation = MBDK_INDEX3_BOOK   !< MBDK_INDEX3_BOOK or MBDK_INDEX3_AUGMENTED
    integer(c_int) :: every = 1                        !< fixed step: keep every k-th step
    integer(c_int) :: newton_max_iter = 20
    integer(c_int) :: adaptive = 0                     !< non-zero: step-size control (augmented only)
  end type mbdk_index3_options_t

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
    real(dp) :: s, phi(model%m), d(model%m, model%nc), gam(model%m), phit(model%m)
    real(dp) :: lw(model%m), a(model%nc + model%m, model%nc + model%m)
    integer :: nc, m
    nc = model%nc
    m = model%m
    s = 0.25_dp * h * h
    call mbdk_model_constraints(model, t, q, v, phi, d, gam, phit)
    call book_matrix(model, t, q, v, lam, h, d, lw, a, stat)
    if (stat /= MBDK_SUCCESS) return
    jac = a
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

  !> a = 0 but for its leading (nc, nc) block M + s (K_c(lam) + K_f) + (h/2) C_f at (q, v, lam,
  !> t), the body rotations model%work%rot at q; lw(m) is a work array. a(nc, nc) or larger.
  subroutine dynamic_block(model, t, q, v, lam, h, lw, a, stat)
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(in) :: t, h
    real(dp), intent(in), contiguous :: q(:), v(:), lam(:)
    real(dp), intent(out), contiguous :: lw(:), a(:, :)
    integer, intent(out) :: stat
    real(dp) :: s
    integer :: i
    s = 0.25_dp * h * h
    a = 0.0_dp
    call mbdk_forces_tangent(model%fint, model%freal, model%work%rot, q, v, t, s, 0.5_dp * h, &
                             a, stat)
    if (stat /= MBDK_SUCCESS) return
    if (model%m > 0) then
      lw = s * lam
      call mbdk_joints_tangent(model%jint, model%jreal, model%row0, model%work%rot, q, lw, a)
    end if
    do i = 1, model%nc
      a(i, i) = a(i, i) + model%mass(i)
    end do
  end subroutine dynamic_block

  !> The book scheme's [M + s (K_c(lam) + K_f) + (h/2) C_f, D^T; D, 0] (nc+m, nc+m) at (q, v,
  !> lam, t), with D = d given there and the body rotations model%work%rot at q (the callers
  !> evaluate the constraints, or the rotations, at q just before); lw(m) is a work array.
  subroutine book_matrix(model, t, q, v, lam, h, d, lw, jac, stat)
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(in) :: t, h
    real(dp), intent(in), contiguous :: q(:), v(:), lam(:), d(:, :)
    real(dp), intent(out), contiguous :: lw(:), jac(:, :)
    integer, intent(out) :: stat
    integer :: nc, m, i, k
    nc = model%nc
    m = model%m
    call dynamic_block(model, t, q, v, lam, h, lw, jac, stat)
    if (stat /= MBDK_SUCCESS) return
    do k = 1, nc
      do i = 1, m
        jac(nc + i, k) = d(i, k)
        jac(k, nc + i) = d(i, k)
      end do
    end do
  end subroutine book_matrix

  !> The augmented form's M + s (K_c(lam) + K_f + alpha D^T D) + (h/2) C_f (nc, nc) at (q, v,
  !> lam, t): D from its compact rows model%work%dz and the rotations model%work%rot, both at q.
  subroutine al_matrix(model, t, q, v, lam, h, alpha, lw, a, stat)
    type(mbdk_model_t), intent(in) :: model
    real(dp), intent(in) :: t, h, alpha
    real(dp), intent(in), contiguous :: q(:), v(:), lam(:)
    real(dp), intent(out), contiguous :: lw(:), a(:, :)
    integer, intent(out) :: stat
    call dynamic_block(model, t, q, v, lam, h, lw, a, stat)
    if (stat /= MBDK_SUCCESS .or. model%m == 0) return
    call mbdk_sparse_dtd_add(model%sp, model%work%dz, 0.25_dp * h * h * alpha, a)
  end subroutine al_matrix

  !> True when a(n, n) is symmetric to roundoff: |a(i,j) - a(j,i)| <= 1e-13 max_k |a(k,k)|.
  !> (Dampers make the tangent stiffness unsymmetric; springs, joints and D^T D do not, but
  !> their two triangles may differ in the last bits.)
  pure logical function symmetric(a, n)
    integer, intent(in) :: n
    real(dp), intent(in) :: a(n, n)
    real(dp) :: tol
    integer :: i, j
    tol = 0.0_dp
    do i = 1, n
      tol = max(tol, abs(a(i, i)))
    end do
    tol = 1.0e-13_dp * tol
    symmetric = .false.
    do j = 1, n
      do i = j + 1, n
        if (.not. (abs(a(i, j) - a(j, i)) <= tol)) return
      end do
    end do
    symmetric = .true.
  end function symmetric

  !> Integrates the scene from (q, v) = y0 over [t0, t_end]: with the fixed step opt%h, or, when
  !> opt%adaptive, with the step-size controller from the initial step opt%h and samples every
  !> opt%dt_out. Samples: t_out, y_out (= [q; v]), a_out, lam_out, iters_out (Newton iterations
  !> of the step that produced the sample). nwritten samples are valid; on failure the samples
  !> before it are kept, and the last one is the state the failed step started from.
  subroutine mbdk_index3_solve(model, opt, t0, t_end, y0, t_out, y_out, a_out, lam_out, &
                               iters_out, nwritten, st, stat)
    type(mbdk_model_t), intent(in) :: model
    type(mbdk_index3_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_end, y0(:)
    real(dp), intent(out) :: t_out(:), y_out(:, :), a_out(:, :), lam_out(:, :)
    integer, intent(out) :: iters_out(:), nwritten
    type(mbdk_stats_t), intent(out) :: st
    integer, intent(out) :: stat
    integer(i8) :: nsteps, i
    integer :: nsamp, nc, m, nk, iters, plan_stat, cool, cool_len, k
    logical :: shortened, have_lu
    real(dp) :: q(model%nc), v(model%nc), a(model%nc), lam(model%m), lam_old(model%m)
    real(dp) :: a_prev(model%nc), a_prev2(model%nc), qn(model%nc), vn(model%nc), an(model%nc)
    real(dp) :: ln(model%m), lst(model%m), lstn(model%m), lst_old(model%m)
    real(dp) :: t, tn, t_s, h, h_lu, h_prev, h_prev2, alpha
    type(mbdk_timer_t) :: timer
    real(dp) :: ks(model%m, model%m), kkt(model%nc + model%m, &
      model%nc + model%m), zero_nc(model%nc), zero_m(model%m), one_nc(model%nc)
    integer :: kpiv(model%nc + model%m)
    logical :: schur, small_lu, ldlt, have_inv
    integer :: nuse
    ! the step's work arrays, allocated once per solve
    real(dp) :: qhat(model%nc), qp(model%nc), lp(model%m), lt(model%m), fq(model%nc)
    real(dp) :: phi(model%m), d(model%m, model%nc), gam(model%m)
    real(dp) :: phit(model%m), lw(model%m), krhs(model%nc + model%m)
    real(dp) :: rc(model%m), corr(model%nc), mu(model%m)
    real(dp), allocatable :: lu(:, :), r(:), ainv(:, :), inv_work(:, :), rinv(:)
    integer, allocatable :: ipiv(:), body_blk(:)

    nwritten = 0
    stat = MBDK_ERR_INVALID_INPUT
    nc = model%nc
    m = model%m
    if (opt%formulation /= MBDK_INDEX3_BOOK .and. opt%formulation /= MBDK_INDEX3_AUGMENTED) return
    if (.not. (opt%newton_rtol >= 0.0_dp .and. opt%newton_atol > 0.0_dp) .or. opt%newton_max_iter < 1) return
    if (opt%formulation == MBDK_INDEX3_AUGMENTED .and. .not. (opt%alpha >= 0.0_dp)) return
    if (size(y0) /= 2 * nc) return
    if (.not. all(abs(y0) <= huge(1.0_dp))) return
    if (opt%adaptive /= 0 .and. opt%formulation == MBDK_INDEX3_BOOK) then
      stat = MBDK_ERR_NOT_APPLICABLE
      return
    end if
    call mbdk_index3_plan(opt, t0, t_end, nsteps, nsamp, shortened, plan_stat)
    if (plan_stat < 0) return
    if (size(t_out) < nsamp .or. size(y_out, 2) < nsamp .or. size(a_out, 2) < nsamp .or. &
        size(lam_out, 2) < nsamp .or. size(iters_out) < nsamp) then
      stat = MBDK_ERR_OUTPUT_SIZE
      return
    end if
    nk = nc
    if (opt%formulation == MBDK_INDEX3_BOOK) nk = nc + m
    allocate (lu(nk, nk), ipiv(nk), r(nk), ainv(nk, nk), inv_work(nk, nk), rinv(nk))
    schur = model%m_positive .and. model%small_dense .and. m <= MBDK_SMALL_DENSE_MAX
    small_lu = model%small_dense .and. nk <= MBDK_SMALL_DENSE_MAX
    ! the augmented matrix's LDL^T pivot blocks: the bodies (x, y, theta)
    if (mod(nc, 3) == 0) then
      body_blk = [(3 * k - 2, k = 1, nc / 3 + 1)]
    else
      body_blk = [(k, k = 1, nc + 1)]
    end if
    ldlt = .false.
    have_inv = .false.
    nuse = 0
    zero_nc = 0.0_dp
    zero_m = 0.0_dp
    one_nc = 1.0_dp
    call mbdk_timer_start(timer)

    q = y0(1:nc)
    v = y0(nc + 1:)
    t = t0
    ! consistent a and lambda at t0: the reduced formulation's solve
    call mbdk_model_accelerations(model, t, q, v, a, lam, stat)
    if (stat /= MBDK_SUCCESS) return
    lam_old = lam
    lst = lam
    lstn = lam
    lst_old = lam
    a_prev = a
    a_prev2 = a
    h_prev = 0.0_dp
    h_prev2 = 0.0_dp
    st%nfev = 1
    iters = 0
    call write_sample()
    have_lu = .false.
    h_lu = 0.0_dp
    cool = 0
    cool_len = 8
    if (opt%adaptive /= 0) then
      call adaptive_loop(stat)
    else
      do i = 1, nsteps
        t_s = t0 + real(i, dp) * opt%h
        if (i == nsteps) t_s = t_end
        if (opt%interrupt /= 0 .and. mbdk_interrupted(opt%interrupt)) then
          stat = MBDK_ERR_INTERRUPTED
          exit
        end if
        call advance_to(t_s, stat)
        if (stat /= MBDK_SUCCESS) exit
        if (mod(i, int(opt%every, i8)) == 0 .or. i == nsteps) call write_sample()
      end do
      if (stat == MBDK_SUCCESS .and. shortened) stat = MBDK_NOTE_LAST_STEP_SHORTENED
    end if
    ! on failure the last sample is the state the failed step started from (where it stopped)
    if (mbdk_is_failure(stat) .and. nwritten < size(t_out)) then
      if (t > t_out(nwritten)) call write_sample()
    end if
    call mbdk_timer_stop(timer, st)

  contains

    subroutine write_sample()
      nwritten = nwritten + 1
      t_out(nwritten) = t
      y_out(1:nc, nwritten) = q
      y_out(nc + 1:2 * nc, nwritten) = v
      a_out(1:nc, nwritten) = a
      if (m > 0) lam_out(1:m, nwritten) = lam
      iters_out(nwritten) = iters
    end subroutine write_sample

    subroutine commit()
      a_prev2 = a_prev
      h_prev2 = h_prev
      a_prev = a
      h_prev = h
      lam_old = lam
      lst_old = lst
      q = qn
      v = vn
      a = an
      lam = ln
      lst = lstn
      t = tn
      st%steps = st%steps + 1
      if (cool > 0) cool = cool - 1
    end subroutine commit

    !> Fixed step: from t to t_s in one step of h = t_s - t or, when Newton fails (diverged,
    !> singular matrix, non-finite iterate) in the augmented form, in substeps: each failure
    !> quarters the substep (stats%newton_failures), each success doubles it back up to the
    !> full step. Below h / 4^MBDK_INDEX3_MAX_CUTS the failure is returned.
    subroutine advance_to(t_s, ierr)
      real(dp), intent(in) :: t_s
      integer, intent(out) :: ierr
      real(dp) :: h_full, h_sub
      h_full = t_s - t
      h_sub = h_full
      ierr = MBDK_SUCCESS
      do while (t < t_s)
        tn = t + h_sub
        if (t_s - tn <= 1.0e-9_dp * h_full) tn = t_s
        h = tn - t
        call attempt(ierr)
        if (ierr == MBDK_ERR_NEWTON_DIVERGED .or. ierr == MBDK_ERR_NONFINITE .or. &
            ierr == MBDK_ERR_SINGULAR_MATRIX) then
          if (opt%formulation == MBDK_INDEX3_BOOK) return
          st%newton_failures = st%newton_failures + 1
          have_lu = .false.
          h_sub = 0.25_dp * h
          if (h_sub < h_full * 0.25_dp**MBDK_INDEX3_MAX_CUTS) return
          cycle
        end if
        if (ierr /= MBDK_SUCCESS) return
        call commit()
        h_sub = min(2.0_dp * h_sub, h_full)
      end do
    end subroutine advance_to

    !> The step-size controller (see the module header). Samples land on t0 + k dt_out.
    subroutine adaptive_loop(ierr)
      integer, intent(out) :: ierr
      integer :: k
      real(dp) :: t_s, h_nat, h_min, h_max, err, fac, facmax, span
      logical :: retry
      span = t_end - t0
      h_max = span
      if (opt%h_max > 0.0_dp) h_max = min(opt%h_max, span)
      h_min = 1.0e-12_dp * max(abs(t0), abs(t_end), span)
      if (opt%h_min > 0.0_dp) h_min = max(opt%h_min, h_min)
      h_nat = min(opt%h, h_max)
      facmax = 5.0_dp
      ierr = MBDK_SUCCESS
      do k = 1, nsamp - 1
        t_s = t0 + real(k, dp) * opt%dt_out
        if (k == nsamp - 1) t_s = t_end
        do while (t < t_s)
          if (opt%interrupt /= 0 .and. mbdk_interrupted(opt%interrupt)) then
            ierr = MBDK_ERR_INTERRUPTED
            return
          end if
          h = h_nat
          if (t_s - t <= 1.1_dp * h) then
            h = t_s - t
          else if (t_s - t < 2.0_dp * h) then
            h = 0.5_dp * (t_s - t)
          end if
          tn = t + h
          if (t_s - tn <= 1.0e-12_dp * max(1.0_dp, abs(t_s))) tn = t_s
          h = tn - t
          ! keep the last matrix when the step changed little (modified Newton absorbs it)
          if (have_lu .and. abs(h - h_lu) <= 0.05_dp * h_lu) h_lu = h
          call attempt(ierr)
          retry = .true.
          if (ierr == MBDK_ERR_NEWTON_DIVERGED .or. ierr == MBDK_ERR_NONFINITE .or. &
              ierr == MBDK_ERR_SINGULAR_MATRIX) then
            st%newton_failures = st%newton_failures + 1
            have_lu = .false.
            h_nat = 0.25_dp * h
          else if (ierr /= MBDK_SUCCESS) then
            return
          else
            err = error_estimate()
            fac = 0.9_dp * max(err, 1.0e-10_dp)**(-1.0_dp / 3.0_dp)
            retry = err > 1.0_dp
            if (retry) then
              st%rejected_steps = st%rejected_steps + 1
              h_nat = max(0.2_dp, fac) * h
            end if
          end if
          if (retry) then
            facmax = 1.0_dp
            ierr = MBDK_SUCCESS
            if (h_nat < h_min) then
              ierr = MBDK_ERR_STEP_TOO_SMALL
              return
            end if
            cycle
          end if
          call commit()
          fac = min(fac, facmax)
          facmax = 5.0_dp
          ! hold h while the controller asks for up to 20 % more: the matrix stays valid
          if (.not. (h >= 0.999_dp * h_nat .and. fac >= 1.0_dp .and. fac <= 1.2_dp)) &
            h_nat = min(max(fac * h, 0.2_dp * h), 5.0_dp * max(h_nat, h), h_max)
        end do
        call write_sample()
      end do
    end subroutine adaptive_loop

    !> Weighted RMS over q and v (multipliers excluded) of the local errors of the trapezoidal
    !> rule, -h^3/12 q(3) and -h^3/12 q(4). The derivatives are divided differences of the step
    !> mean accelerations (a_k + a_k+1)/2, placed at the step midpoints: the mean cancels the
    !> period-2 oscillation of the book scheme's accelerations, which would otherwise dominate.
    !> The first two steps have no q(4) from history: it is taken as q(3) / (h + h_prev)
    !> (large, so those steps are judged conservatively).
    real(dp) function error_estimate()
      real(dp) :: eq, ev, wq, wv, d1, d0, sum2, b2, b1, b0
      integer :: k
      sum2 = 0.0_dp
      do k = 1, nc
        b2 = 0.5_dp * (a(k) + an(k))
        if (h_prev > 0.0_dp) then
          b1 = 0.5_dp * (a_prev(k) + a(k))
          d1 = (b2 - b1) / (0.5_dp * (h + h_prev))                     ! q(3)
        else
          b1 = 0.0_dp                     ! (unused: no h_prev2 without h_prev)
          d1 = (an(k) - a(k)) / h
        end if
        eq = h**3 / 12.0_dp * d1
        if (h_prev2 > 0.0_dp) then
          b0 = 0.5_dp * (a_prev2(k) + a_prev(k))
          d0 = (b1 - b0) / (0.5_dp * (h_prev + h_prev2))
          ev = h**3 / 12.0_dp * (d1 - d0) / (0.5_dp * h + h_prev + 0.5_dp * h_prev2) * 2.0_dp
        else
          ev = h**3 / 12.0_dp * d1 / (h + h_prev)
        end if
        wq = opt%err_atol + opt%err_rtol * max(abs(q(k)), abs(qn(k)))
        wv = opt%err_atol + opt%err_rtol * max(abs(v(k)), abs(vn(k)))
        sum2 = sum2 + (eq / wq)**2 + (ev / wv)**2
      end do
      error_estimate = sqrt(sum2 / real(2 * nc, dp))
    end function error_estimate

    logical function finite_all(x)
      real(dp), intent(in) :: x(:)
      finite_all = all(abs(x) <= huge(1.0_dp))
    end function finite_all

    !> max |Phi| accepted: atol, but not below the roundoff of the coordinates.
    real(dp) function phi_tol(x)
      real(dp), intent(in) :: x(:)
      phi_tol = max(opt%newton_atol, 64.0_dp * epsilon(1.0_dp) * max(1.0_dp, maxval(abs(x))))
    end function phi_tol

    real(dp) function wnorm(dx, x)
      real(dp), intent(in) :: dx(:), x(:)
      wnorm = maxval(abs(dx) / (opt%newton_atol + opt%newton_rtol * abs(x)))
    end function wnorm

    !> One step from (t, q, v, a, lam) to tn = t + h into (qn, vn, an, ln), not committed.
    !> Newton as in the module header; both formulations share this loop.
    subroutine attempt(ierr)
      integer, intent(out) :: ierr
      real(dp) :: s, dnorm, dnorm_old, rate
      logical :: fresh, restarted, book, reused
      integer :: k, kk
      book = opt%formulation == MBDK_INDEX3_BOOK
      s = 0.25_dp * h * h
      alpha = opt%alpha
      if (alpha == 0.0_dp) alpha = MBDK_INDEX3_KAPPA * maxval(model%mass) / s
      qhat = q + h * v + s * a
      if (book .or. h_prev <= 0.0_dp) then
        qp = q + h * v + 0.5_dp * h * h * a
        lp = lst
      else
        ! the trapezoidal rule itself with a+ and lam* extrapolated linearly: O(h^4) in q
        qp = qhat + s * (a + (h / h_prev) * (a - a_prev))
        lp = lst + (h / h_prev) * (lst - lst_old)
      end if
      if (book) lp = lam
      if (book .and. h_prev > 0.0_dp) lp = lam + (h / h_prev) * (lam - lam_old)   ! (3.11)
      if (have_lu .and. (abs(h - h_lu) > 1.0e-12_dp * h .or. cool > 0)) have_lu = .false.
      reused = have_lu
      qn = qp
      ln = lp
      restarted = .false.
      fresh = .false.
      dnorm_old = huge(1.0_dp)
      iters = 0
      k = 0
      phi = 0.0_dp
      do
        vn = (2.0_dp / h) * (qn - q) - v
        ! (leaves work%rot and work%dz at qn, for the forces and the matrix)
        call constraints_at()
        fq = 0.0_dp
        call mbdk_forces_eval(model%fint, model%freal, model%mass, model%work%rot, qn, vn, tn, fq, &
                              model%work%visits(5:), ierr)
        if (ierr /= MBDK_SUCCESS) return
        st%nfev = st%nfev + 1
        lt = ln
        if (.not. book) then
          if (k > 0) ln = ln + alpha * phi
          lt = ln + alpha * phi
        end if
        ! corr = f - D^T lt over the nonzeros of D
        call mbdk_sparse_w_residual(model%sp, model%work%dz, one_nc, lt, corr, nc, fq)
        do kk = 1, nc
          r(kk) = model%mass(kk) * (qn(kk) - qhat(kk)) - s * corr(kk)
        end do
        if (book) r(nc + 1:) = phi
        if (.not. have_lu) then
          call factor_matrix(ierr)
          st%nlu = st%nlu + 1
          st%njev = st%njev + 1
          if (ierr /= MBDK_SUCCESS) return
          have_lu = .true.
          h_lu = h
          fresh = .true.
          reused = .false.
        end if
        r = -r
        ! an LU that has served two solves is likely to serve many (modified Newton): from
        ! the third on, through its explicit inverse
        if (small_lu .and. .not. ldlt .and. nuse == 2) then
          call mbdk_small_lu_inverse(lu, nk, ipiv, ainv, inv_work)
          have_inv = .true.
        end if
        nuse = nuse + 1
        if (have_inv) then
          call mbdk_small_inverse_apply(ainv, nk, r, rinv)
        else if (ldlt) then
          call mbdk_small_ldlt_solve(lu, nk, body_blk, r)
        else if (small_lu) then
          call mbdk_small_lu_solve(lu, nk, ipiv, r)
        else
          call mbdk_lu_solve(lu, ipiv, r, ierr)
          if (ierr /= MBDK_SUCCESS) return
        end if
        if (.not. finite_all(r)) then
          ierr = MBDK_ERR_NONFINITE
          return
        end if
        iters = iters + 1
        k = k + 1
        st%newton_iterations = st%newton_iterations + 1
        dnorm = wnorm(r(1:nc), qn)
        ! converged: the update from this iterate is below tolerance, and so is Phi here. The
        ! update is applied (the Newton error left in q is then its square, or the rate times
        ! it); f keeps this evaluation, the step's end evaluates D at the final q+.
        if (k > 1 .and. dnorm <= 1.0_dp .and. (m == 0 .or. maxval(abs(phi)) <= phi_tol(qn))) then
          qn = qn + r(1:nc)
          if (book) ln = ln + r(nc + 1:) / s
          exit
        end if
        if (iters >= opt%newton_max_iter) then
          ierr = MBDK_ERR_NEWTON_DIVERGED
          return
        end if
        rate = dnorm / dnorm_old
        if (rate > 1.0_dp .and. k > 1 .and. dnorm > 1.0_dp .and. .not. fresh) then
          ! growing with an old matrix (not roundoff below the tolerance). The first time the
          ! iterate may be spoilt (the augmented form's multiplier update amplifies it), so
          ! restart from the predictor with a matrix built there, and build fresh matrices
          ! for the next steps; later, rebuild the matrix at this iterate.
          have_lu = .false.
          dnorm_old = huge(1.0_dp)
          if (.not. restarted) then
            restarted = .true.
            ! fresh matrices for cool_len steps, twice as many after each failed reuse
            cool = cool_len
            cool_len = min(2 * cool_len, 1024)
            reused = .false.
            qn = qp
            ln = lp
            k = 0
          end if
          cycle
        end if
        qn = qn + r(1:nc)
        if (book) ln = ln + r(nc + 1:) / s
        ! rebuild the matrix when two more iterations at this rate would not reach the
        ! tolerance (an iteration costs about as much as a factorisation)
        if (rate > 0.5_dp .or. dnorm * rate * rate > 1.0_dp) have_lu = .false.
        fresh = .false.
        dnorm_old = dnorm
      end do
      ! a matrix carried over from an earlier step served the whole step: reuse pays again
      if (reused) cool_len = 8
      if (book) then
        vn = (2.0_dp / h) * (qn - q) - v
        an = (4.0_dp / (h * h)) * (qn - q) - (4.0_dp / h) * v - a
      else
        lstn = ln
        vn = (2.0_dp / h) * (qn - q) - v
        call constraints_at()
        if (.not. schur .and. m > 0) call mbdk_joints_scatter(model%col, model%work%dz, d)
        call kkt_factor(d, ierr)
        if (ierr /= MBDK_SUCCESS) return
        ! v+ = P (v + (h/2)(a + a~)), P the projection onto D v + Phi_t = 0 and a~ any
        ! solution of M a~ = f - D^T (anything): P removes M^-1 D^T terms, so this is P v+ of
        ! the trapezoidal rule (a+ differs from a~ by such a term once Newton has converged),
        ! without the Newton error that v+ = (2/h)(q+ - q) - v would carry amplified by 2/h.
        ! Then a+ and lambda+ from M a + D^T lambda = f, D a = gamma(q+, v+): the projection
        ! of a+ onto the acceleration constraints, with its multipliers, free of the Newton
        ! error (4/h^2) that a+ = (4/h^2)(q+ - q) - .. would carry.
        call kkt_solve(d, fq, zero_m, an, ln)
        vn = v + (0.5_dp * h) * (a + an)
        call project_v(d, phit)
        ! q+ is unchanged: work%rot still holds its sin/cos and D, Phi are the same; only gamma
        ! changes with v+
        if (m > 0) call mbdk_joints_eval(model%jint, model%jreal, model%row0, model%work%rot, qn, &
                                         vn, tn, phi, model%work%dz, gam, phit, &
                                         model%work%visits(1:MBDK_JOINT_TYPES))
        call kkt_solve(d, fq, gam, an, ln)
      end if
      if (.not. (finite_all(qn) .and. finite_all(vn) .and. finite_all(an))) &
        ierr = MBDK_ERR_NONFINITE
    end subroutine attempt

    !> Rotations and constraints at (tn, qn, vn): model%work%rot, phi, D's compact rows
    !> model%work%dz, gam, phit (the dense d only where it is needed: scattered by the caller).
    subroutine constraints_at()
      call mbdk_body_rotations(qn, model%work%rot)
      if (m > 0) call mbdk_joints_eval(model%jint, model%jreal, model%row0, model%work%rot, qn, &
                                       vn, tn, phi, model%work%dz, gam, phit, &
                                       model%work%visits(1:MBDK_JOINT_TYPES))
    end subroutine constraints_at

    !> Builds and factorises the Newton matrix at (tn, qn, vn, ln) into lu (constraints_at
    !> there first). The augmented matrix, when symmetric (no dampers) and positive definite,
    !> by the block LDL^T with the bodies as pivot blocks (ldlt = .true.; half the cost of the
    !> LU); otherwise, and for the book scheme's indefinite matrix, by the LU.
    subroutine factor_matrix(ierr)
      integer, intent(out) :: ierr
      ldlt = .false.
      have_inv = .false.
      nuse = 0
      if (opt%formulation == MBDK_INDEX3_BOOK) then
        if (m > 0) call mbdk_joints_scatter(model%col, model%work%dz, d)
        call book_matrix(model, tn, qn, vn, ln, h, d, lw, lu, ierr)
      else
        ! the geometric stiffness of the augmented form takes lam* alone: alpha Phi, large
        ! while the iterate is off the constraints, vanishes at the solution
        call al_matrix(model, tn, qn, vn, ln, h, alpha, lw, lu, ierr)
        if (ierr /= MBDK_SUCCESS) return
        if (small_lu) then
          if (symmetric(lu, nk)) then
            call mbdk_small_ldlt_factor(lu, nk, body_blk, LDLT_TOL, ierr)
            ldlt = ierr == MBDK_SUCCESS
            ! not positive definite: rebuilt for the LU
            if (.not. ldlt) call al_matrix(model, tn, qn, vn, ln, h, alpha, lw, lu, ierr)
          end if
        end if
      end if
      if (ierr /= MBDK_SUCCESS .or. ldlt) return
      if (small_lu) then
        call mbdk_small_lu_factor(lu, nk, ipiv, ierr)
      else
        call mbdk_lu_factor(lu, ipiv, ierr)
      end if
    end subroutine factor_matrix

    !> vn onto D v + Phi_t = 0 (mass-orthogonal), with the factors of kkt_factor.
    subroutine project_v(d, phit)
      real(dp), intent(in), contiguous :: d(:, :), phit(:)
      call mbdk_sparse_d_times(model%sp, model%work%dz, vn, rc, .false.)
      rc = rc + phit
      call kkt_solve(d, zero_nc, rc, corr, mu)
      vn = vn - corr
    end subroutine project_v

    !> Factorises [M D^T; D 0] for kkt_solve: through the Schur complement D M^-1 D^T, from
    !> the compact rows of D in model%work%dz (the last mbdk_model_constraints call, at the
    !> same q as d), and the in-house LDL^T when M is positive and m small (as the reduced
    !> formulation), else by LAPACK's LU of the whole matrix. Dependent rows:
    !> MBDK_ERR_SINGULAR_MATRIX.
    subroutine kkt_factor(d, ierr)
      real(dp), intent(in) :: d(:, :)
      integer, intent(out) :: ierr
      integer :: k
      if (schur) then
        call mbdk_sparse_schur_assemble(model%sp, model%work%dz, ks)
        call mbdk_small_ldlt_factor(ks, m, model%blk, MBDK_MODEL_SINGULAR_TOL, ierr)
        return
      end if
      kkt = 0.0_dp
      do k = 1, nc
        kkt(k, k) = model%mass(k)
      end do
      kkt(nc + 1:, 1:nc) = d
      kkt(1:nc, nc + 1:) = transpose(d)
      call mbdk_lu_factor(kkt, kpiv, ierr)
    end subroutine kkt_factor

    !> M x + D^T mu = b, D x = c with the factors of kkt_factor (D: d, or its compact rows in
    !> model%work%dz, unchanged since kkt_factor).
    subroutine kkt_solve(d, b, c, x, mu)
      real(dp), intent(in), contiguous :: d(:, :), b(:), c(:)
      real(dp), intent(out), contiguous :: x(:), mu(:)
      integer :: ierr
      if (schur) then
        call mbdk_sparse_d_times(model%sp, model%work%dz, b, mu, .true.)
        mu = mu - c
        call mbdk_small_ldlt_solve(ks, m, model%blk, mu)
        call mbdk_sparse_w_residual(model%sp, model%work%dz, model%winv, mu, x, nc, b)
        return
      end if
      krhs(1:nc) = b
      krhs(nc + 1:) = c
      call mbdk_lu_solve(kkt, kpiv, krhs, ierr)
      x = krhs(1:nc)
      mu = krhs(nc + 1:)
    end subroutine kkt_solve

  end subroutine mbdk_index3_solve

  !> Steps and samples of a solve: fixed step, as mbdk_step_plan (h, every); adaptive, samples
  !> at t0 + k dt_out and t_end (nsteps is then the number of sample intervals).
  subroutine mbdk_index3_plan(opt, t0, t_end, nsteps, nsamp, shortened, stat)
    type(mbdk_index3_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, t_end
    integer(i8), intent(out) :: nsteps
    integer, intent(out) :: nsamp, stat
    logical, intent(out) :: shortened
    if (opt%adaptive /= 0) then
      stat = MBDK_ERR_INVALID_INPUT
      nsteps = 0
      nsamp = 0
      shortened = .false.
      if (.not. (opt%h > 0.0_dp .and. opt%err_rtol >= 0.0_dp .and. opt%err_atol > 0.0_dp)) return
      if (.not. (opt%h_min >= 0.0_dp .and. opt%h_max >= 0.0_dp)) return
      if (opt%h_max > 0.0_dp .and. opt%h_min > opt%h_max) return
      call mbdk_step_plan(t0, t_end, opt%dt_out, 1, nsteps, nsamp, shortened, stat)
      if (stat > 0) stat = MBDK_SUCCESS
    else
      call mbdk_step_plan(t0, t_end, opt%h, opt%every, nsteps, nsamp, shortened, stat)
    end if
  end subroutine mbdk_index3_plan

end module mbdk_trapezoidal_index3
