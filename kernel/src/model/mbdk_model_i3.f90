!> The planar model's part of trapezoidal_index3 (mbdk_trapezoidal_index3 is the method's
!> manual; mbdk_mechanism lists what each procedure gives): its evaluation in the compact rows
!> of mbdk_joints, the constrained solves of mbdk_constrained (the projections; its regular
!> path at a rank loss of D) and the analytic Newton matrix with its factorisations
!> (mbdk_index3_matrix: the closed-form tangents of forces and joints, in-house block LDL^T,
!> LU, LAPACK or the sparse body-block path). A submodule, so that the model's module does not
!> depend on the matrix's (which reads the model).
submodule (mbdk_model) mbdk_model_i3
  use mbdk_sparse_schur, only: mbdk_sparse_w_residual, mbdk_sparse_d_abs_times
  use mbdk_index3_matrix, only: mbdk_index3_factors_t, mbdk_index3_factors_init, &
    mbdk_index3_factor, mbdk_index3_factors_solve
  implicit none

  type, extends(mbdk_i3_aux_t) :: planar_i3_aux_t
    !> the projections' solves (weight M^-1) and the Newton matrix's factors
    type(mbdk_constrained_t) :: cs
    type(mbdk_index3_factors_t) :: fa
    !> the dense D (the book scheme's matrix only), and work of the residual, the matrix and
    !> the velocity projection
    real(dp), allocatable :: d(:, :), lw(:), corr(:), one_nc(:), cv(:), mu(:), zero_nc(:)
  end type planar_i3_aux_t

contains

  !> A scene with contacts or friction (no tangent in the Newton matrix) or a knife edge (no
  !> position row to solve for: its velocity row would be left unkept) is
  !> MBDK_ERR_NOT_APPLICABLE.
  module procedure model_i3_create
    integer :: nc, m, nk, astat
    logical :: dense_d
    stat = MBDK_ERR_NOT_APPLICABLE
    if (self%has_contacts .or. self%has_pfaffian) return
    nc = self%nc
    m = self%m
    nk = nc
    if (book) nk = nc + m
    stat = MBDK_ERR_NO_MEMORY
    allocate (planar_i3_aux_t :: aux, stat=astat)
    if (astat /= 0) return
    select type (aux)
    type is (planar_i3_aux_t)
      call mbdk_constrained_init(aux%cs, nc, m, self%m_positive, &
                                 self%solver == MBDK_SOLVER_KKT, self%small_dense, self%sp, &
                                 mbdk_model_sparse(self), stat, asked)
      if (stat /= MBDK_SUCCESS) return
      call mbdk_index3_factors_init(aux%fa, self, nk, stat, asked)
      if (stat /= MBDK_SUCCESS) return
      ! the dense D serves the book scheme's dense matrix only
      dense_d = book .and. .not. aux%fa%kkt
      allocate (aux%d(merge(m, 0, dense_d), merge(nc, 0, dense_d)), aux%lw(m), aux%corr(nc), &
                aux%one_nc(nc), aux%cv(m), aux%mu(m), aux%zero_nc(nc), stat=astat)
      call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (merge(real(m, dp) * nc, 0.0_dp, &
                             dense_d) + 3.0_dp * m + 3.0_dp * nc), stat, asked)
      if (stat /= MBDK_SUCCESS) return
      aux%one_nc = 1.0_dp
      aux%zero_nc = 0.0_dp
    end select
  end procedure model_i3_create

  !> the rotations (unless same_q) and the joints at (t, e%q, e%v) into work%rot and work%dz,
  !> and the force elements' f (gravity among them, counted at every evaluation)
  module procedure model_i3_evaluate
    if (.not. same_q) call mbdk_body_rotations(e%q, self%work%rot)
    if (self%m > 0) call mbdk_joints_eval(self%jint, self%jreal, self%row0, self%work%rot, e%q, &
                                          e%v, t, e%phi, self%work%dz, e%gam, e%phit, &
                                          self%work%visits(1:MBDK_JOINT_TYPES))
    stat = MBDK_SUCCESS
    if (forces) then
      e%f = 0.0_dp
      call mbdk_forces_eval(self%fint, self%freal, self%mass, self%work%rot, e%q, e%v, t, e%f, &
                            self%work%visits(MBDK_JOINT_TYPES + 1:), stat)
    end if
  end procedure model_i3_evaluate

  !> over the nonzeros of D: corr = f - D^T lt, r = M dd - s corr
  module procedure model_i3_residual
    integer :: k
    select type (aux)
    type is (planar_i3_aux_t)
      call mbdk_sparse_w_residual(self%sp, self%work%dz, aux%one_nc, e%lt, aux%corr, self%nc, &
                                  e%f)
      do k = 1, self%nc
        e%r(k) = self%mass(k) * e%dd(k) - s * aux%corr(k)
      end do
    end select
  end procedure model_i3_residual

  module procedure model_i3_c_times
    logical :: ab
    ab = .false.
    if (present(absolute)) ab = absolute
    if (ab) then
      call mbdk_sparse_d_abs_times(self%sp, self%work%dz, x, y, self%nc, .false.)
    else
      call mbdk_sparse_d_times(self%sp, self%work%dz, x, y, .false.)
    end if
  end procedure model_i3_c_times

  module procedure model_i3_ct_times
    logical :: ab
    ab = .false.
    if (present(absolute)) ab = absolute
    if (ab) then
      call mbdk_sparse_d_abs_times(self%sp, self%work%dz, x, y, self%nc, .true.)
      return
    end if
    select type (aux)
    type is (planar_i3_aux_t)
      call mbdk_sparse_w_residual(self%sp, self%work%dz, aux%one_nc, x, y, self%nc)
      y = -y
    end select
  end procedure model_i3_ct_times

  module procedure model_i3_cs_factor
    regular = .false.
    select type (aux)
    type is (planar_i3_aux_t)
      if (near > 0.0_dp) then
        call mbdk_constrained_factor(aux%cs, self%sp, self%work%dz, self%col, self%blk, &
                                     self%mass, stat, regular=regular_ok, near=near)
      else
        call mbdk_constrained_factor(aux%cs, self%sp, self%work%dz, self%col, self%blk, &
                                     self%mass, stat, regular=regular_ok)
      end if
      regular = aux%cs%regular
    end select
  end procedure model_i3_cs_factor

  module procedure model_i3_cs_solve
    select type (aux)
    type is (planar_i3_aux_t)
      call mbdk_constrained_solve(aux%cs, self%sp, self%work%dz, self%blk, self%winv, b, c, x, &
                                  mu, stat)
    end select
  end procedure model_i3_cs_solve

  !> mbdk_index3_factor at the last evaluation (work%rot and work%dz at q)
  module procedure model_i3_matrix
    select type (aux)
    type is (planar_i3_aux_t)
      call mbdk_index3_factor(aux%fa, self, book, t, e%q, e%v, lam, ck, cd, alpha, aux%d, &
                              aux%lw, stat)
    end select
  end procedure model_i3_matrix

  module procedure model_i3_matrix_solve
    select type (aux)
    type is (planar_i3_aux_t)
      call mbdk_index3_factors_solve(aux%fa, e%r, stat)
    end select
  end procedure model_i3_matrix_solve

  !> the default's C v, its Phi_t and the solve in one call (mbdk_mechanism), over the model's
  !> own arrays
  module procedure model_i3_project_velocity
    select type (aux)
    type is (planar_i3_aux_t)
      call mbdk_sparse_d_times(self%sp, self%work%dz, e%v, aux%cv, .false.)
      aux%cv(:) = aux%cv + e%phit
      call mbdk_constrained_solve(aux%cs, self%sp, self%work%dz, self%blk, self%winv, &
                                  aux%zero_nc, aux%cv, aux%corr, aux%mu, stat)
      if (stat /= MBDK_SUCCESS) return
      e%v(:) = e%v - aux%corr
    end select
  end procedure model_i3_project_velocity

end submodule mbdk_model_i3
