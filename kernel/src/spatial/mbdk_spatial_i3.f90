!> The spatial model's part of trapezoidal_index3 (mbdk_trapezoidal_index3 is the method's
!> manual; mbdk_mechanism lists what each procedure gives). The evaluation is the model's
!> (frames, forces with the gyroscopic moment, the dense C), and the Newton matrix is the
!> integrator's differences (has_i3_matrix off). The constrained solves are dense:
!>   exact    S = C_a M^-1 C_a^T on the independent rows a the model solves (work%active: all
!>            rows, or the subset a redundant scene keeps), by Cholesky, each pivot against its
!>            row's diagonal at roundoff (SOLVE_RTOL) and, where the caller asks, the geometric
!>            near test of the model (near_test, the rows' C W C^T with rotations at the length
!>            scale); the other rows get no multiplier;
!>   regular  where that fails and the caller allows it (a singular pose): the augmented
!>            Lagrangian iteration of Bayo and Ledesma (1996) on all rows,
!>              (M + beta C^T C) x_k+1 = b - C^T mu_k + beta C^T c,  mu_k+1 = mu_k + beta (C x - c),
!>            beta = AL_KAPPA max(diag M) / max |C_i|^2, its matrix positive definite whatever
!>            C's rank, stopping at roundoff or where the residual stops falling by half (as
!>            mbdk_constrained's, the planar model's).
!> A submodule of mbdk_spatial_model, to keep that module's size in hand.
submodule (mbdk_spatial_model) mbdk_spatial_i3
  implicit none

  !> the regular path: penalty factor per max(diag M) / max |C_i|^2, and the iteration limit
  real(dp), parameter :: AL_KAPPA = 1.0e3_dp
  integer, parameter :: AL_ITER = 30

  type, extends(mbdk_i3_aux_t) :: spatial_i3_aux_t
    !> C at the last evaluation (m x 6 nb), M^-1 C^T, the rows of the exact path and the
    !> Cholesky factor of their S; the regular path's factor and beta
    real(dp), allocatable :: c(:, :), mc(:, :), s(:, :), al(:, :), y(:), x(:), r(:), muk(:)
    integer, allocatable :: rows(:)
    logical :: regular = .false.
    real(dp) :: beta = 0.0_dp
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
      allocate (aux%c(m, nv), aux%mc(nv, m), aux%s(m, m), aux%al(nv, nv), &
                aux%y(last_velocity(self)), aux%x(nv), aux%r(m), aux%muk(m), aux%rows(m), &
                stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (real(m, dp) * (2 * nv + m + 2) + &
                             real(nv, dp) * (nv + 1) + last_velocity(self)) + MBDK_INT_BYTES * m, &
                             stat, asked)
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
    select type (aux)
    type is (spatial_i3_aux_t)
      aux%y(1:self%ncoord) = e%q
      aux%y(self%ncoord + 1:) = e%v
      call frames(self, aux%y, fr, stat)
      if (stat /= MBDK_SUCCESS) return
      if (forces) then
        allocate (fw(3, self%nb), nbd(3, self%nb), stat=astat)
        call mbdk_alloc_status(astat, MBDK_REAL_BYTES * 6.0_dp * self%nb, stat)
        if (stat /= MBDK_SUCCESS) return
        call forces(self, fr, fw, nbd, vg, vs, power, stat)
        if (stat /= MBDK_SUCCESS) return
        call generalized_forces(self, fr, fw, nbd, e%f)
      end if
      if (self%m > 0) then
        e%phi = 0.0_dp
        aux%c = 0.0_dp
        e%gam = 0.0_dp
        e%phit = 0.0_dp
        call constraints(self, fr, t, e%phi, aux%c, e%gam, e%phit)
      end if
    end select
  end procedure spatial_i3_evaluate

  module procedure spatial_i3_residual
    select type (aux)
    type is (spatial_i3_aux_t)
      associate (r => e%r(1:self%nvel))
        call spatial_mass_times(self, e%dd, r)
        if (self%m > 0) then
          r = r - s * (e%f - matmul(e%lt, aux%c))
        else
          r = r - s * e%f
        end if
      end associate
    end select
  end procedure spatial_i3_residual

  module procedure spatial_i3_c_times
    select type (aux)
    type is (spatial_i3_aux_t)
      y = matmul(aux%c, x)
    end select
  end procedure spatial_i3_c_times

  module procedure spatial_i3_ct_times
    select type (aux)
    type is (spatial_i3_aux_t)
      y = matmul(x, aux%c)
    end select
  end procedure spatial_i3_ct_times

  module procedure spatial_i3_cs_factor
    integer :: k, na, astat
    real(dp), allocatable :: diag(:)
    real(dp) :: cmax
    regular = .false.
    stat = MBDK_SUCCESS
    if (self%m == 0) return
    select type (aux)
    type is (spatial_i3_aux_t)
      aux%regular = .false.
      do k = 1, self%m
        call apply_minv(self, aux%c(k, :), aux%mc(:, k))
      end do
      ! the exact path on the model's independent rows
      na = size(self%work%active)
      aux%rows(1:na) = self%work%active
      allocate (diag(na), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * na, stat)
      if (stat /= MBDK_SUCCESS) return
      call gram(self, aux%c, aux%mc, aux%rows(1:na), aux%s(1:na, 1:na), stat)
      if (stat /= MBDK_SUCCESS) return
      diag = [(aux%s(k, k), k = 1, na)]
      call mbdk_chol_factor(aux%s(1:na, 1:na), stat)
      if (stat == MBDK_SUCCESS) then
        do k = 1, na
          if (.not. (aux%s(k, k)**2 > SOLVE_RTOL * diag(k))) stat = MBDK_ERR_SINGULAR_MATRIX
        end do
      else
        stat = MBDK_ERR_SINGULAR_MATRIX
      end if
      if (stat == MBDK_SUCCESS .and. near > 0.0_dp) &
        call near_test(self, aux%c(aux%rows(1:na), :), near, stat)
      if (stat /= MBDK_ERR_SINGULAR_MATRIX .or. .not. regular_ok) return
      ! the regular path's matrix M + beta C^T C (formed in place: an expression's temporary
      ! of 6 nb x 6 nb would be taken without a status)
      cmax = 0.0_dp
      do k = 1, self%m
        cmax = max(cmax, sum(aux%c(k, :)**2))
      end do
      if (.not. (cmax > 0.0_dp)) cmax = 1.0_dp
      call spatial_mass_diagonal(self, aux%x)
      aux%beta = AL_KAPPA * maxval(aux%x) / cmax
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
    real(dp) :: rr, r_best
    stat = MBDK_SUCCESS
    select type (aux)
    type is (spatial_i3_aux_t)
      call apply_minv(self, b, x)
      mu = 0.0_dp
      if (self%m == 0) return
      if (.not. aux%regular) then
        na = size(self%work%active)
        associate (rows => aux%rows(1:na), z => aux%muk(1:na))
          z = matmul(aux%c(rows, :), x) - c(rows)
          call mbdk_chol_solve(aux%s(1:na, 1:na), z, stat)
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
      aux%muk = 0.0_dp
      x = 0.0_dp
      r_best = huge(1.0_dp)
      do k = 1, AL_ITER
        aux%x = b - matmul(aux%muk - aux%beta * c, aux%c)
        call mbdk_chol_solve(aux%al, aux%x, stat)
        if (stat /= MBDK_SUCCESS) return
        aux%r = matmul(aux%c, aux%x) - c
        rr = maxval(abs(aux%r))
        if (.not. (rr < r_best)) exit
        aux%muk = aux%muk + aux%beta * aux%r
        x = aux%x
        mu = aux%muk
        if (rr <= 64.0_dp * epsilon(1.0_dp) * (maxval(abs(c)) + maxval(abs(aux%c)) * &
                                               maxval(abs(x))) .or. rr > 0.5_dp * r_best) exit
        r_best = rr
      end do
    end select
  end procedure spatial_i3_cs_solve

  !> (not called: has_i3_matrix is off, the integrator forms the matrix by differences)
  module procedure spatial_i3_matrix
    stat = MBDK_ERR_NOT_APPLICABLE
  end procedure spatial_i3_matrix

  module procedure spatial_i3_matrix_solve
    stat = MBDK_ERR_NOT_APPLICABLE
  end procedure spatial_i3_matrix_solve

end submodule mbdk_spatial_i3
