!> The C API's stepper (bind(C) only; mirrored in mbdk.h): a solve the caller advances one step,
!> or to a time, at a time, reading the state, the multipliers and the statistics in between.
!>
!>   mbdk_stepper *s;
!>   mbdk_stepper_create_ode(f, jac, user_data, n, t0, y0, &opt, &s)        or
!>   mbdk_stepper_create_scene(nb, mass, ..., &model_opt, &opt, t0, y0, &s)  or
!>   mbdk_stepper_create_index3(nb, mass, ..., &index3_opt, t0, y0, &s)           or
!>   mbdk_stepper_create_spatial(nb, mass, ..., &spatial_opt, &opt, t0, y0, &s)    or
!>   mbdk_stepper_create_spatial_index3(nb, mass, ..., &spatial_opt, &index3_opt, t0, y0, &s)
!>   mbdk_stepper_step(s)              one step of opt.h
!>   mbdk_stepper_advance(s, t)        steps of opt.h up to t, the last one shortened to land on t
!>   mbdk_stepper_state(s, &t, y, n)   mbdk_stepper_multipliers(s, lam, m)   mbdk_stepper_stats(s, &st)
!>   mbdk_stepper_outputs(s, out, MBDK_STEPPER_NOUT)   mbdk_stepper_reactions(s, reac, nj)
!>   mbdk_stepper_set_force(s, entry, slot, value)       a load's value between steps
!>   mbdk_stepper_copy(s, &saved)      the whole stepper, to go back to (mbdk_stepper_copy(saved, &s))
!>   mbdk_stepper_destroy(s)
!>
!> A scene stepper integrates the model's formulation (reduced, baumgarte, penalty, projection:
!> model_opt.formulation) with any ODE method; an index-3 stepper runs trapezoidal_index3 (the
!> book's scheme or the augmented Lagrangian, fixed step: its opt.adaptive must be 0) with the
!> substep retries of mbdk_index3_advance, and its multipliers are the integrator's own. The
!> spatial pair does the same on a spatial scene (mbdk_spatial_model; its tables as the f2py
!> entry spatial_run takes them): the stepping above the mechanism interface is one code for
!> both kinds of scene, and only the model behind b%mech differs. Steps
!> land on t0 + k h as in the whole-interval drivers, so a stepper and mbdk_solve_ode (or
!> mbdk_index3_solve) give the same bits.
!>
!> After a failed step the stepper keeps the last good state (t, y) readable and refuses further
!> steps with MBDK_ERR_NOT_APPLICABLE. Every pointer is checked: NULL gives
!> MBDK_ERR_INVALID_INPUT. The handle owns all its memory; nothing points into the caller's
!> arrays after create returns, except user_data and the options' interrupt flag, whose address
!> it polls at every advance (mbdk.h: the flag must outlive the stepper). The multipliers read
!> after a failed step are those of the step attempted; the statistics count work and leave the
!> clock fields 0 (the caller's loop is not the kernel's to time).
module mbdk_capi_stepper
  use, intrinsic :: iso_c_binding, only: c_int, c_double, c_ptr, c_funptr, c_loc, c_f_pointer, &
    c_associated, c_null_ptr, c_intptr_t
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_interrupt, only: mbdk_interrupted
  use mbdk_stepper, only: mbdk_stepper_t, mbdk_stepper_init, mbdk_stepper_step
  use mbdk_fixed_step, only: mbdk_on_grid
  use mbdk_callback_problem, only: mbdk_c_problem_t, mbdk_c_problem_init
  use mbdk_model, only: mbdk_model_t, mbdk_model_init, mbdk_model_work_t, mbdk_model_options_t, &
    mbdk_model_accelerations, mbdk_model_constraints, mbdk_model_outputs, MBDK_OUT_ENERGY, &
    MBDK_OUT_RESIDUALS, MBDK_OUT_REACTIONS, MBDK_ENERGY_PARTS, MBDK_RESIDUALS
  use mbdk_methods, only: mbdk_method_info, MBDK_FAMILY_IMPLICIT_LMM, MBDK_METHOD_NAME_LEN
  use mbdk_lmm_tables, only: mbdk_lmm_t, mbdk_lmm_table
  use mbdk_trapezoidal_index3, only: mbdk_index3_t, mbdk_index3_options_t, mbdk_index3_init, &
    mbdk_index3_advance
  use mbdk_c_tables, only: mbdk_c_tables_read
  use mbdk_mechanism, only: mbdk_mechanism_t, MBDK_FORM_PROJECTION
  use mbdk_spatial_model, only: mbdk_spatial_model_t, mbdk_spatial_work_t, &
    mbdk_spatial_options_t, mbdk_spatial_init, MBDK_SPATIAL_JOINT_REALS, &
    MBDK_SPATIAL_FORCE_REALS, mbdk_spatial_outputs, MBDK_SPATIAL_NOUT, MBDK_COORDS_ABSOLUTE
  use mbdk_watch, only: mbdk_watch_report_t, mbdk_watch_report_of
  use mbdk_elements, only: MBDK_EFFECT_WEAR, MBDK_FORCE_POINT, MBDK_FORCE_TORQUE, &
    MBDK_FORCE_GRAVITY, MBDK_FORCE_CONTACT, MBDK_FORCE_FRICTION
  implicit none
  private

  integer, parameter :: KIND_ODE = 1, KIND_SCENE = 2, KIND_INDEX3 = 3
  !> mbdk_stepper_outputs' values (mbdk.h: MBDK_STEPPER_NOUT)
  integer, parameter :: STEPPER_NOUT = 5

  !> What a handle points to. Allocated through a pointer, so the model may point at its work
  !> and mech at the model of the scene's kind (planar or spatial) that it holds.
  type :: stepper_box
    integer :: kind = 0
    type(mbdk_c_problem_t) :: cprob
    type(mbdk_model_t) :: model
    type(mbdk_model_work_t) :: work
    type(mbdk_spatial_model_t) :: smodel
    type(mbdk_spatial_work_t) :: swork
    class(mbdk_mechanism_t), pointer :: mech => null()
    type(mbdk_stepper_t) :: s
    type(mbdk_index3_t) :: i3
    real(dp) :: h = 0.0_dp          !< the grid's step
    real(dp) :: t0 = 0.0_dp
    integer(i8) :: grid_steps = 0   !< steps of opt%h on the grid t0 + k h taken so far
    logical :: equal_steps = .false. !< a k-step method: only whole steps of opt%h
    real(dp) :: t_good = 0.0_dp     !< the last good state (kept across a failed step)
    real(dp), allocatable :: y_good(:)
    logical :: failed_i3 = .false.  !< an index-3 step failed: no further steps
    logical :: spatial = .false.    !< the scene's model is smodel (else model)
  end type stepper_box

contains

  !> The box behind a handle, or null for a NULL handle.
  function box_of(handle) result(b)
    type(c_ptr), intent(in) :: handle
    type(stepper_box), pointer :: b
    b => null()
    if (c_associated(handle)) call c_f_pointer(handle, b)
  end function box_of

  !> Stepper for y' = f(t, y) (jac may be NULL) from (t0, y0[n]) with opt (method, h, ...).
  integer(c_int) function mbdk_c_stepper_create_ode(f, jac, user_data, n, t0, y0, opt, handle) &
      bind(C, name='mbdk_stepper_create_ode')
    type(c_funptr), value :: f, jac
    type(c_ptr), value :: user_data
    integer(c_int), value :: n
    real(c_double), value :: t0
    real(c_double), intent(in), optional :: y0(*)
    type(mbdk_options_t), intent(in), optional :: opt
    type(c_ptr), intent(out), optional :: handle
    type(stepper_box), pointer :: b
    integer :: stat

    mbdk_c_stepper_create_ode = MBDK_ERR_INVALID_INPUT
    if (.not. present(handle)) return
    handle = c_null_ptr
    if (.not. (present(y0) .and. present(opt)) .or. .not. c_associated(f) .or. n < 1) return
    if (opt%nq < 0 .or. (opt%nq > 0 .and. 2 * opt%nq /= n)) return
    allocate (b, stat=stat)
    if (stat /= 0) then
      mbdk_c_stepper_create_ode = MBDK_ERR_NO_MEMORY
      return
    end if
    b%kind = KIND_ODE
    call mbdk_c_problem_init(b%cprob, f, user_data, int(n), int(opt%nq), jac)
    call start(b, opt, t0, y0(1:n), stat)
    mbdk_c_stepper_create_ode = finish_create(b, stat, handle)
  end function mbdk_c_stepper_create_ode

  !> Stepper for a scene given by its tables (as mbdk_index3_solve takes them) and the model's
  !> options (formulation, solver), from (t0, y0[6 nb + nw] = (q, v, w)) with opt (method, h,
  !> ...): w the initial volumes of the scene's nw wear elements (mbdk_wear), none without.
  integer(c_int) function mbdk_c_stepper_create_scene(nb, mass, inertia, nj, jint, jreal, nf, &
      fint, freal, mopt, opt, t0, y0, handle) bind(C, name='mbdk_stepper_create_scene')
    integer(c_int), value :: nb, nj, nf
    real(c_double), intent(in), optional :: mass(*), inertia(*), jreal(*), freal(*), y0(*)
    integer(c_int), intent(in), optional :: jint(*), fint(*)
    type(mbdk_model_options_t), intent(in), optional :: mopt
    type(mbdk_options_t), intent(in), optional :: opt
    real(c_double), value :: t0
    type(c_ptr), intent(out), optional :: handle
    type(stepper_box), pointer :: b
    integer :: stat

    mbdk_c_stepper_create_scene = MBDK_ERR_INVALID_INPUT
    if (.not. present(handle)) return
    handle = c_null_ptr
    if (.not. (present(mopt) .and. present(opt) .and. present(y0))) return
    allocate (b, stat=stat)
    if (stat /= 0) then
      mbdk_c_stepper_create_scene = MBDK_ERR_NO_MEMORY
      return
    end if
    b%kind = KIND_SCENE
    call build_model(b, nb, mass, inertia, nj, jint, jreal, nf, fint, freal, mopt, y0, stat)
    if (stat == MBDK_SUCCESS) call check_start(b, t0, y0(1:6 * nb), stat)
    if (stat == MBDK_SUCCESS) call start(b, opt, t0, y0(1:6 * nb + b%model%ns), stat)
    mbdk_c_stepper_create_scene = finish_create(b, stat, handle)
  end function mbdk_c_stepper_create_scene

  !> Stepper running trapezoidal_index3 on a scene (fixed step opt.h; opt.adaptive must be 0:
  !> MBDK_ERR_NOT_APPLICABLE otherwise) from (t0, y0[6 nb]).
  integer(c_int) function mbdk_c_stepper_create_index3(nb, mass, inertia, nj, jint, jreal, nf, &
      fint, freal, opt, t0, y0, handle) bind(C, name='mbdk_stepper_create_index3')
    integer(c_int), value :: nb, nj, nf
    real(c_double), intent(in), optional :: mass(*), inertia(*), jreal(*), freal(*), y0(*)
    integer(c_int), intent(in), optional :: jint(*), fint(*)
    type(mbdk_index3_options_t), intent(in), optional :: opt
    real(c_double), value :: t0
    type(c_ptr), intent(out), optional :: handle
    type(stepper_box), pointer :: b
    type(mbdk_model_options_t) :: mopt
    integer :: stat

    mbdk_c_stepper_create_index3 = MBDK_ERR_INVALID_INPUT
    if (.not. present(handle)) return
    handle = c_null_ptr
    if (.not. (present(opt) .and. present(y0))) return
    if (opt%adaptive /= 0) then
      mbdk_c_stepper_create_index3 = MBDK_ERR_NOT_APPLICABLE
      return
    end if
    if (.not. (opt%h > 0.0_dp .and. opt%h <= huge(1.0_dp))) return
    allocate (b, stat=stat)
    if (stat /= 0) then
      mbdk_c_stepper_create_index3 = MBDK_ERR_NO_MEMORY
      return
    end if
    b%kind = KIND_INDEX3
    ! the model's defaults: its reduced formulation gives only the consistent a, lambda at t0
    call build_model(b, nb, mass, inertia, nj, jint, jreal, nf, fint, freal, mopt, y0, stat)
    if (stat == MBDK_SUCCESS) call start_index3(b, opt, t0, y0(1:6 * nb), stat)
    mbdk_c_stepper_create_index3 = finish_create(b, stat, handle)
  end function mbdk_c_stepper_create_index3

  !> Stepper for a spatial scene (mbdk_spatial_model) given by its tables, as the f2py entry
  !> spatial_run takes them (C row-major: inertia[nb][3][3], jbody[nj][2],
  !> jreal[nj][MBDK_SPATIAL_JOINT_REALS], fbody[nf][2], freal[nf][MBDK_SPATIAL_FORCE_REALS]),
  !> and its options (formulation, rotation, the norm's keeping, the watch), integrated by the
  !> ODE method of opt from (t0, y0 = (q, w, V)): per body q_b = (r, p), p 4 or 3 values as
  !> sopt%rotation says, then w_b = (r', Omega) per body, then the initial volumes V of the
  !> table's wear elements (MBDK_EFFECT_WEAR entries, in table order; none without).
  integer(c_int) function mbdk_c_stepper_create_spatial(nb, mass, inertia, nj, jtype, jbody, &
      jreal, nf, ftype, fbody, freal, sopt, opt, t0, y0, handle) &
      bind(C, name='mbdk_stepper_create_spatial')
    integer(c_int), value :: nb, nj, nf
    real(c_double), intent(in), optional :: mass(*), inertia(*), jreal(*), freal(*), y0(*)
    integer(c_int), intent(in), optional :: jtype(*), jbody(*), ftype(*), fbody(*)
    type(mbdk_spatial_options_t), intent(in), optional :: sopt
    type(mbdk_options_t), intent(in), optional :: opt
    real(c_double), value :: t0
    type(c_ptr), intent(out), optional :: handle
    type(stepper_box), pointer :: b
    integer :: stat, n

    mbdk_c_stepper_create_spatial = MBDK_ERR_INVALID_INPUT
    if (.not. present(handle)) return
    handle = c_null_ptr
    if (.not. (present(sopt) .and. present(opt) .and. present(y0))) return
    allocate (b, stat=stat)
    if (stat /= 0) then
      mbdk_c_stepper_create_spatial = MBDK_ERR_NO_MEMORY
      return
    end if
    b%kind = KIND_SCENE
    call build_spatial(b, nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal, &
                       sopt, t0, y0, n, stat)
    if (stat == MBDK_SUCCESS) call check_start_mech(b, t0, y0(1:n), stat)
    if (stat == MBDK_SUCCESS) call start(b, opt, t0, y0(1:n), stat)
    mbdk_c_stepper_create_spatial = finish_create(b, stat, handle)
  end function mbdk_c_stepper_create_spatial

  !> Stepper running a member of the index-3 family (trapezoidal_index3 with opt's defaults,
  !> or newmark, hht, generalized_alpha by opt's beta, gamma, alpha_m, alpha_f) on a spatial
  !> scene, fixed step (opt.adaptive must be 0: MBDK_ERR_NOT_APPLICABLE otherwise); tables,
  !> options and y0 as mbdk_stepper_create_spatial's (a table with wear elements:
  !> MBDK_ERR_NOT_APPLICABLE, the family's state [q; v] has no place for their volumes). The
  !> model's formulation plays no part in the index-3 step; the model is built with the
  !> projection formulation's, as simulate builds it, so that the two give the same bits.
  integer(c_int) function mbdk_c_stepper_create_spatial_index3(nb, mass, inertia, nj, jtype, &
      jbody, jreal, nf, ftype, fbody, freal, sopt, opt, t0, y0, handle) &
      bind(C, name='mbdk_stepper_create_spatial_index3')
    integer(c_int), value :: nb, nj, nf
    real(c_double), intent(in), optional :: mass(*), inertia(*), jreal(*), freal(*), y0(*)
    integer(c_int), intent(in), optional :: jtype(*), jbody(*), ftype(*), fbody(*)
    type(mbdk_spatial_options_t), intent(in), optional :: sopt
    type(mbdk_index3_options_t), intent(in), optional :: opt
    real(c_double), value :: t0
    type(c_ptr), intent(out), optional :: handle
    type(stepper_box), pointer :: b
    type(mbdk_spatial_options_t) :: so
    integer :: stat, n

    mbdk_c_stepper_create_spatial_index3 = MBDK_ERR_INVALID_INPUT
    if (.not. present(handle)) return
    handle = c_null_ptr
    if (.not. (present(sopt) .and. present(opt) .and. present(y0))) return
    if (opt%adaptive /= 0) then
      mbdk_c_stepper_create_spatial_index3 = MBDK_ERR_NOT_APPLICABLE
      return
    end if
    if (.not. (opt%h > 0.0_dp .and. opt%h <= huge(1.0_dp))) return
    allocate (b, stat=stat)
    if (stat /= 0) then
      mbdk_c_stepper_create_spatial_index3 = MBDK_ERR_NO_MEMORY
      return
    end if
    b%kind = KIND_INDEX3
    so = sopt
    so%formulation = MBDK_FORM_PROJECTION
    call build_spatial(b, nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal, &
                       so, t0, y0, n, stat)
    if (stat == MBDK_SUCCESS) call check_start_mech(b, t0, y0(1:n), stat)
    if (stat == MBDK_SUCCESS) call start_index3(b, opt, t0, y0(1:n), stat)
    mbdk_c_stepper_create_spatial_index3 = finish_create(b, stat, handle)
  end function mbdk_c_stepper_create_spatial_index3

  !> b%smodel from the C tables (copied into Fortran's column order) and b%mech pointing at
  !> it; n the state's length (the bodies', then one per wear element).
  subroutine build_spatial(b, nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, &
                           freal, so, t0, y0, n, stat)
    type(stepper_box), intent(inout), target :: b
    integer(c_int), intent(in) :: nb, nj, nf
    real(c_double), intent(in), optional :: mass(*), inertia(*), jreal(*), freal(*), y0(*)
    integer(c_int), intent(in), optional :: jtype(*), jbody(*), ftype(*), fbody(*)
    type(mbdk_spatial_options_t), intent(in) :: so
    real(dp), intent(in) :: t0
    integer, intent(out) :: n
    integer, intent(out) :: stat
    integer, parameter :: NJR = MBDK_SPATIAL_JOINT_REALS, NFR = MBDK_SPATIAL_FORCE_REALS
    integer, allocatable :: jt(:), jb(:, :), ft(:), fb(:, :)
    real(dp), allocatable :: jr(:, :), fr(:, :), inert(:, :, :)
    integer :: astat
    n = 0
    ! joint coordinates are the f2py entry spatial_run's (mbdk_joint_coords); a stepper keeps
    ! the absolute state its readers index
    stat = MBDK_ERR_NOT_APPLICABLE
    if (so%coordinates /= MBDK_COORDS_ABSOLUTE) return
    stat = MBDK_ERR_INVALID_INPUT
    ! counts whose tables no default integer indexes are refused before anything is allocated
    if (nb < 1 .or. nj < 0 .or. nf < 0 .or. nb > huge(1) / 13 .or. nj > huge(1) / NJR .or. &
        nf > huge(1) / NFR) return
    if (.not. (present(mass) .and. present(inertia))) return
    if (nj > 0 .and. .not. (present(jtype) .and. present(jbody) .and. present(jreal))) return
    if (nf > 0 .and. .not. (present(ftype) .and. present(fbody) .and. present(freal))) return
    n = nb * (merge(7, 6, so%rotation == 1) + 6)
    if (nf > 0) n = n + count(ftype(1:nf) == MBDK_EFFECT_WEAR)
    allocate (jt(nj), jb(2, nj), jr(NJR, nj), ft(nf), fb(2, nf), fr(NFR, nf), &
              inert(3, 3, nb), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (NJR * real(nj, dp) + NFR * real(nf, dp) &
                           + 9.0_dp * nb) + 12.0_dp * (nj + nf), stat)
    if (stat /= MBDK_SUCCESS) return
    ! C's inertia[b][i][j] is Fortran's (j, i, b): the transpose, which a symmetric J does not
    ! see (and an asymmetric one is refused by the model either way)
    inert = reshape(inertia(1:9 * nb), [3, 3, nb])
    if (nj > 0) then
      jt = jtype(1:nj)
      jb = reshape(jbody(1:2 * nj), [2, nj])
      jr = reshape(jreal(1:NJR * nj), [NJR, nj])
    end if
    if (nf > 0) then
      ft = ftype(1:nf)
      fb = reshape(fbody(1:2 * nf), [2, nf])
      fr = reshape(freal(1:NFR * nf), [NFR, nf])
    end if
    call mbdk_spatial_init(b%smodel, b%swork, so, mass(1:nb), inert, jt, jb, jr, ft, fb, fr, &
                           t0, y0(1:n), stat)
    if (stat /= MBDK_SUCCESS) return
    b%spatial = .true.
    b%mech => b%smodel
  end subroutine build_spatial

  !> b%model from the C tables, their pose values taken at y0 (mbdk_c_tables).
  subroutine build_model(b, nb, mass, inertia, nj, jint, jreal, nf, fint, freal, mopt, y0, stat)
    type(stepper_box), intent(inout), target :: b
    integer(c_int), intent(in) :: nb, nj, nf
    real(c_double), intent(in), optional :: mass(*), inertia(*), jreal(*), freal(*), y0(*)
    integer(c_int), intent(in), optional :: jint(*), fint(*)
    type(mbdk_model_options_t), intent(in) :: mopt
    integer, intent(out) :: stat
    integer, allocatable :: ji(:, :), fi(:, :)
    real(dp), allocatable :: jr(:, :), fr(:, :)
    call mbdk_c_tables_read(nb, mass, inertia, nj, jint, jreal, nf, fint, freal, y0, ji, jr, fi, &
                            fr, stat)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_model_init(b%model, mass(1:nb), inertia(1:nb), ji, jr, fi, fr, mopt, b%work, stat)
    if (stat == MBDK_SUCCESS) b%mech => b%model
  end subroutine build_model

  !> A scene stepper's initial state (q, v) against its joints: |Phi| within START_TOL of the
  !> scene's size (the largest |q| or joint point, at least 1), |D v + Phi_t| within START_TOL
  !> of the terms that must cancel (|D| |v| + |Phi_t|, at least the size per second).
  !> MBDK_ERR_INCONSISTENT_INITIAL otherwise: the stepper does not assemble the state (Python's
  !> simulate does), and a start off the joints would only fail later, at the watch. Non-finite
  !> values: MBDK_ERR_NONFINITE.
  subroutine check_start(b, t0, y, stat)
    type(stepper_box), intent(inout) :: b
    real(dp), intent(in) :: t0, y(:)
    integer, intent(out) :: stat
    !> a larger offset is a wrong state, not the roundoff of a consistent one
    real(dp), parameter :: START_TOL = 1.0e-6_dp
    real(dp), allocatable :: phi(:), gam(:), phit(:), dv(:), scale_v(:)
    real(dp) :: size_
    integer :: nc, m, r, k, c
    stat = MBDK_SUCCESS
    nc = b%model%nc
    m = b%model%m
    if (m == 0) return
    stat = MBDK_ERR_NONFINITE
    if (.not. all(abs(y) <= huge(1.0_dp))) return
    allocate (phi(m), gam(m), phit(m), dv(m), scale_v(m), stat=k)
    call mbdk_alloc_status(k, 5 * MBDK_REAL_BYTES * m, stat)
    if (stat /= MBDK_SUCCESS) return
    associate (q => y(1:nc), v => y(nc + 1:2 * nc))
      call mbdk_model_constraints(b%model, t0, q, v, phi, gam=gam, phit=phit)
      dv = phit
      scale_v = abs(phit)
      do r = 1, m
        do k = 1, size(b%model%col, 1)
          c = b%model%col(k, r)
          if (c <= 0) cycle
          dv(r) = dv(r) + b%model%work%dz(k, r) * v(c)
          scale_v(r) = scale_v(r) + abs(b%model%work%dz(k, r) * v(c))
        end do
      end do
      size_ = max(1.0_dp, maxval(abs(q)), maxval(abs(b%model%jreal(1:4, :))))
    end associate
    stat = MBDK_ERR_INCONSISTENT_INITIAL
    if (.not. all(abs(phi) <= START_TOL * size_)) return
    if (.not. all(abs(dv) <= START_TOL * max(scale_v, size_))) return
    stat = MBDK_SUCCESS
  end subroutine check_start

  !> check_start's test on any mechanism (a spatial scene), from its dense evaluation: |Phi|
  !> within START_TOL of the scene's size (the largest |q|, at least the model's length scale),
  !> |C v + Phi_t| within START_TOL of its terms.
  subroutine check_start_mech(b, t0, y, stat)
    type(stepper_box), intent(inout) :: b
    real(dp), intent(in) :: t0, y(:)
    integer, intent(out) :: stat
    real(dp), parameter :: START_TOL = 1.0e-6_dp
    real(dp), allocatable :: f(:), phi(:), c(:, :), gam(:), phit(:)
    real(dp) :: size_
    integer :: nq, nv, m, k
    stat = MBDK_SUCCESS
    m = b%mech%m
    if (m == 0) return
    nq = b%mech%ncoord
    nv = b%mech%nvel
    stat = MBDK_ERR_NONFINITE
    if (.not. all(abs(y) <= huge(1.0_dp))) return
    allocate (f(nv), phi(m), gam(m), phit(m), c(m, nv), stat=k)
    call mbdk_alloc_status(k, MBDK_REAL_BYTES * (nv + 3.0_dp * m + real(m, dp) * nv), stat)
    if (stat /= MBDK_SUCCESS) return
    associate (q => y(1:nq), v => y(nq + 1:nq + nv))
      call b%mech%evaluate(t0, q, v, f, phi, c, gam, phit, stat)
      if (stat /= MBDK_SUCCESS) return
      size_ = max(1.0_dp, maxval(abs(q)), b%smodel%length)
      stat = MBDK_ERR_INCONSISTENT_INITIAL
      if (.not. all(abs(phi) <= START_TOL * size_)) return
      if (.not. all(abs(matmul(c, v) + phit) <= START_TOL * &
                    max(matmul(abs(c), abs(v)) + abs(phit), size_))) return
    end associate
    stat = MBDK_SUCCESS
  end subroutine check_start_mech

  subroutine start(b, opt, t0, y0, stat)
    type(stepper_box), intent(inout) :: b
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, y0(:)
    integer, intent(out) :: stat
    character(len=MBDK_METHOD_NAME_LEN) :: name
    integer :: family, order
    type(mbdk_lmm_t) :: lmm
    logical :: found
    select case (b%kind)
    case (KIND_ODE)
      call mbdk_stepper_init(b%s, b%cprob, opt, t0, y0, stat)
    case default
      call mbdk_stepper_init(b%s, b%mech, opt, t0, y0, stat)
    end select
    if (stat /= MBDK_SUCCESS) return
    b%h = opt%h
    b%t0 = t0
    b%t_good = t0
    call keep_y0(b, y0, stat)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_method_info(opt%method, name, family, order)
    if (family == MBDK_FAMILY_IMPLICIT_LMM) then
      call mbdk_lmm_table(opt%method, lmm, found)
      b%equal_steps = lmm%k > 1
    end if
  end subroutine start

  !> The index-3 family's solve on b%mech from (t0, y0), on the grid of opt%h.
  subroutine start_index3(b, opt, t0, y0, stat)
    type(stepper_box), intent(inout) :: b
    type(mbdk_index3_options_t), intent(in) :: opt
    real(dp), intent(in) :: t0, y0(:)
    integer, intent(out) :: stat
    call mbdk_index3_init(b%i3, b%mech, opt, t0, y0, stat)
    b%h = opt%h
    b%t0 = t0
    b%t_good = t0
    if (stat == MBDK_SUCCESS) call keep_y0(b, y0, stat)
  end subroutine start_index3

  !> b%y_good = y0, allocated with its status (MBDK_ERR_NO_MEMORY)
  subroutine keep_y0(b, y0, stat)
    type(stepper_box), intent(inout) :: b
    real(dp), intent(in) :: y0(:)
    integer, intent(out) :: stat
    integer :: astat
    allocate (b%y_good(size(y0)), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * size(y0), stat)
    if (stat == MBDK_SUCCESS) b%y_good = y0
  end subroutine keep_y0

  integer(c_int) function finish_create(b, stat, handle)
    type(stepper_box), pointer, intent(inout) :: b
    integer, intent(in) :: stat
    type(c_ptr), intent(out) :: handle
    finish_create = int(stat, c_int)
    if (stat /= MBDK_SUCCESS) then
      deallocate (b)
      handle = c_null_ptr
      return
    end if
    handle = c_loc(b)
  end function finish_create

  !> One step of the stepper's problem to t_next; keeps the last good state on failure, and
  !> counts the grid points t0 + k h passed (within 1e-9 h).
  subroutine step_to(b, t_next, stat)
    type(stepper_box), intent(inout) :: b
    real(dp), intent(in) :: t_next
    integer, intent(out) :: stat
    select case (b%kind)
    case (KIND_ODE)
      call mbdk_stepper_step(b%s, b%cprob, t_next, stat)
    case (KIND_SCENE)
      call mbdk_stepper_step(b%s, b%mech, t_next, stat)
    case default
      stat = MBDK_ERR_NOT_APPLICABLE
      if (b%failed_i3) return
      call mbdk_index3_advance(b%i3, b%mech, t_next, stat)
      b%failed_i3 = stat /= MBDK_SUCCESS
    end select
    if (stat /= MBDK_SUCCESS) return
    if (b%kind == KIND_INDEX3) then
      b%t_good = b%i3%t
      b%y_good(1:b%i3%ncq) = b%i3%q
      b%y_good(b%i3%ncq + 1:) = b%i3%v
    else
      b%t_good = b%s%t
      b%y_good = b%s%y
    end if
    b%grid_steps = floor((t_next - b%t0) / b%h + 1.0e-9_dp, i8)
  end subroutine step_to

  !> One step to the next point t0 + k opt.h of the grid (a full step of opt.h unless an
  !> advance ended off the grid).
  integer(c_int) function mbdk_c_stepper_step(handle) bind(C, name='mbdk_stepper_step')
    type(c_ptr), value :: handle
    type(stepper_box), pointer :: b
    integer :: stat
    mbdk_c_stepper_step = MBDK_ERR_INVALID_INPUT
    b => box_of(handle)
    if (.not. associated(b)) return
    call step_to(b, b%t0 + real(b%grid_steps + 1, dp) * b%h, stat)
    mbdk_c_stepper_step = int(stat, c_int)
  end function mbdk_c_stepper_step

  !> Steps of opt.h up to t (the grid t0 + k h), the last one shortened to land on t when t is
  !> not on the grid (one-step methods only: a k-step method needs t on the grid,
  !> MBDK_ERR_INVALID_INPUT otherwise). t at the current time: nothing to do; before it:
  !> MBDK_ERR_INVALID_INPUT (a stepper does not go back). The options' interrupt flag is polled
  !> before every step.
  integer(c_int) function mbdk_c_stepper_advance(handle, t) bind(C, name='mbdk_stepper_advance')
    type(c_ptr), value :: handle
    real(c_double), value :: t
    type(stepper_box), pointer :: b
    real(dp) :: h, t_next
    integer :: stat
    mbdk_c_stepper_advance = MBDK_ERR_INVALID_INPUT
    b => box_of(handle)
    if (.not. associated(b)) return
    if (.not. abs(t) <= huge(1.0_dp)) return
    if (t < b%t_good) return
    h = b%h
    if (b%equal_steps .and. .not. mbdk_on_grid(b%t0, t, h)) return
    stat = MBDK_SUCCESS
    if (failed(b)) stat = MBDK_ERR_NOT_APPLICABLE
    do while (stat == MBDK_SUCCESS .and. b%t_good < t)
      if (interrupt_of(b) /= 0 .and. mbdk_interrupted(interrupt_of(b))) then
        stat = MBDK_ERR_INTERRUPTED
        exit
      end if
      t_next = b%t0 + real(b%grid_steps + 1, dp) * h
      ! within 1e-9 h of t (or past it): land on t
      if (t_next >= t - 1.0e-9_dp * h) t_next = t
      call step_to(b, t_next, stat)
    end do
    mbdk_c_stepper_advance = int(stat, c_int)
  end function mbdk_c_stepper_advance

  logical function failed(b)
    type(stepper_box), intent(in) :: b
    if (b%kind == KIND_INDEX3) then
      failed = b%failed_i3
    else
      failed = b%s%failed
    end if
  end function failed

  !> The interrupt flag's address of the stepper's options.
  integer(c_intptr_t) function interrupt_of(b)
    type(stepper_box), intent(in) :: b
    if (b%kind == KIND_INDEX3) then
      interrupt_of = b%i3%opt%interrupt
    else
      interrupt_of = b%s%opt%interrupt
    end if
  end function interrupt_of

  !> The current time and state (the last good one after a failure); n must be the state size.
  integer(c_int) function mbdk_c_stepper_state(handle, t, y, n) bind(C, name='mbdk_stepper_state')
    type(c_ptr), value :: handle
    real(c_double), intent(out), optional :: t
    real(c_double), intent(out), optional :: y(*)
    integer(c_int), value :: n
    type(stepper_box), pointer :: b
    mbdk_c_stepper_state = MBDK_ERR_INVALID_INPUT
    b => box_of(handle)
    if (.not. (associated(b) .and. present(t) .and. present(y))) return
    if (n /= size(b%y_good)) return
    t = b%t_good
    y(1:n) = b%y_good
    mbdk_c_stepper_state = MBDK_SUCCESS
  end function mbdk_c_stepper_state

  !> State size n and constraint rows m (0 for an ODE).
  integer(c_int) function mbdk_c_stepper_size(handle, n, m) bind(C, name='mbdk_stepper_size')
    type(c_ptr), value :: handle
    integer(c_int), intent(out), optional :: n, m
    type(stepper_box), pointer :: b
    mbdk_c_stepper_size = MBDK_ERR_INVALID_INPUT
    b => box_of(handle)
    if (.not. (associated(b) .and. present(n) .and. present(m))) return
    n = int(size(b%y_good), c_int)
    m = 0
    if (b%kind /= KIND_ODE) m = int(b%mech%m, c_int)
    mbdk_c_stepper_size = MBDK_SUCCESS
  end function mbdk_c_stepper_size

  !> A scene's multipliers lam[m] at the current state: by the model's formulation (one
  !> evaluation), or trapezoidal_index3's own. MBDK_ERR_NOT_APPLICABLE for an ODE stepper.
  integer(c_int) function mbdk_c_stepper_multipliers(handle, lam, m) &
      bind(C, name='mbdk_stepper_multipliers')
    type(c_ptr), value :: handle
    real(c_double), intent(out), optional :: lam(*)
    integer(c_int), value :: m
    type(stepper_box), pointer :: b
    real(dp), allocatable :: a(:), l(:)
    integer :: stat, nq, nv
    mbdk_c_stepper_multipliers = MBDK_ERR_INVALID_INPUT
    b => box_of(handle)
    if (.not. associated(b)) return
    if (b%kind == KIND_ODE) then
      mbdk_c_stepper_multipliers = MBDK_ERR_NOT_APPLICABLE
      return
    end if
    if (m /= b%mech%m .or. (m > 0 .and. .not. present(lam))) return
    if (b%kind == KIND_INDEX3) then
      if (m > 0) lam(1:m) = b%i3%lam
      mbdk_c_stepper_multipliers = MBDK_SUCCESS
      return
    end if
    nq = b%mech%ncoord
    nv = b%mech%nvel
    allocate (a(nv), l(m), stat=stat)
    if (stat /= 0) then
      mbdk_c_stepper_multipliers = MBDK_ERR_NO_MEMORY
      return
    end if
    call b%mech%accelerations(b%t_good, b%y_good(1:nq), b%y_good(nq + 1:nq + nv), a, l, stat)
    if (stat == MBDK_SUCCESS .and. m > 0) lam(1:m) = l
    mbdk_c_stepper_multipliers = int(stat, c_int)
  end function mbdk_c_stepper_multipliers

  integer(c_int) function mbdk_c_stepper_stats(handle, st) bind(C, name='mbdk_stepper_stats')
    type(c_ptr), value :: handle
    type(mbdk_stats_t), intent(out), optional :: st
    type(stepper_box), pointer :: b
    mbdk_c_stepper_stats = MBDK_ERR_INVALID_INPUT
    b => box_of(handle)
    if (.not. (associated(b) .and. present(st))) return
    if (b%kind == KIND_INDEX3) then
      st = b%i3%st
    else
      st = b%s%st
    end if
    mbdk_c_stepper_stats = MBDK_SUCCESS
  end function mbdk_c_stepper_stats

  !> The report of the watch's check that stopped a scene or index-3 stepper with
  !> MBDK_ERR_CONSTRAINT_DRIFT, MBDK_ERR_ENERGY_DRIFT or MBDK_ERR_INVARIANT_DRIFT, by name
  !> (mbdk_watch_report_t; quantity 0 while nothing failed). An ODE stepper has no watch:
  !> MBDK_ERR_NOT_APPLICABLE.
  integer(c_int) function mbdk_c_stepper_watch_report(handle, report) &
      bind(C, name='mbdk_stepper_watch_report')
    type(c_ptr), value :: handle
    type(mbdk_watch_report_t), intent(out), optional :: report
    type(stepper_box), pointer :: b
    mbdk_c_stepper_watch_report = MBDK_ERR_INVALID_INPUT
    b => box_of(handle)
    if (.not. (associated(b) .and. present(report))) return
    mbdk_c_stepper_watch_report = MBDK_ERR_NOT_APPLICABLE
    if (b%kind == KIND_ODE) return
    if (b%spatial) then
      report = mbdk_watch_report_of(b%swork%watch)
    else
      report = mbdk_watch_report_of(b%work%watch)
    end if
    mbdk_c_stepper_watch_report = MBDK_SUCCESS
  end function mbdk_c_stepper_watch_report

  !> A copy of the whole stepper src: its state, its method's history and factors, its
  !> statistics and its watch, so that the copy's steps are the bits src's would be. *dst NULL:
  !> a new stepper (destroyed by the caller); else the stepper *dst is overwritten (a stepper of
  !> the same scene, as a co-simulation master's rollback takes it: mbdk_stepper_copy(saved,
  !> &live)). An ODE stepper's copy shares its user_data, a stepper's copies its interrupt
  !> flag's address. The copy is Fortran's intrinsic assignment of the stepper, which allocates
  !> as it copies (memory short of a copy ends the process, as every such assignment does).
  integer(c_int) function mbdk_c_stepper_copy(src, dst) bind(C, name='mbdk_stepper_copy')
    type(c_ptr), value :: src
    type(c_ptr), intent(inout), optional :: dst
    type(stepper_box), pointer :: a, b
    integer :: stat
    mbdk_c_stepper_copy = MBDK_ERR_INVALID_INPUT
    a => box_of(src)
    if (.not. (associated(a) .and. present(dst))) return
    b => box_of(dst)
    if (associated(b, a)) then
      mbdk_c_stepper_copy = MBDK_SUCCESS
      return
    end if
    if (associated(b)) then
      ! the same kind of scene and state: a stepper of another scene is not overwritten
      if (b%kind /= a%kind .or. (b%spatial .neqv. a%spatial) .or. &
          size(b%y_good) /= size(a%y_good)) return
    else
      allocate (b, stat=stat)
      if (stat /= 0) then
        mbdk_c_stepper_copy = MBDK_ERR_NO_MEMORY
        return
      end if
    end if
    b = a
    ! the copy's pointers to its own parts: the model's work, and the mechanism it steps
    b%mech => null()
    if (b%kind /= KIND_ODE) then
      if (b%spatial) then
        b%smodel%work => b%swork
        b%mech => b%smodel
      else
        b%model%work => b%work
        b%mech => b%model
      end if
    end if
    dst = c_loc(b)
    mbdk_c_stepper_copy = MBDK_SUCCESS
  end function mbdk_c_stepper_copy

  !> A load's value between steps, as a co-simulation's input sets it: slot (1-based) of the
  !> force table's entry (1-based, as the stepper's tables list them) becomes value. A point
  !> force's components (planar slots 3, 4; spatial 4 .. 6, in space) and a torque's (planar 1;
  !> spatial 1 .. 3) only: loads enter no assembly and no potential, so an explicit method's
  !> next step is the scene's with that value written in (an implicit method's reused Newton
  !> matrix, where a point force's moment arm enters it, is an approximation until its next
  !> refresh: iterations, not accuracy). Any other entry or slot, a non-finite value, an ODE
  !> stepper: MBDK_ERR_INVALID_INPUT. The watch's work counts the load's power at the value in
  !> force at each step, and the watch no longer holds the scene to a conserved momentum.
  integer(c_int) function mbdk_c_stepper_set_force(handle, entry, slot, value) &
      bind(C, name='mbdk_stepper_set_force')
    type(c_ptr), value :: handle
    integer(c_int), value :: entry, slot
    real(c_double), value :: value
    type(stepper_box), pointer :: b
    integer :: k, e, kind
    mbdk_c_stepper_set_force = MBDK_ERR_INVALID_INPUT
    b => box_of(handle)
    if (.not. associated(b)) return
    if (b%kind == KIND_ODE .or. .not. abs(value) <= huge(1.0_dp) .or. entry < 1) return
    if (b%spatial) then
      if (entry > b%smodel%nf) return
      kind = b%smodel%ftype(entry)
      if (.not. ((kind == MBDK_FORCE_POINT .and. slot >= 4 .and. slot <= 6) .or. &
                 (kind == MBDK_FORCE_TORQUE .and. slot >= 1 .and. slot <= 3))) return
      b%smodel%freal(slot, entry) = value
      ! a load the caller drives conserves no momentum: the watch (whose conserved components
      ! were found at init from the table's values, a zero load ruling nothing out) stops
      ! holding the scene to any
      b%smodel%ninv = 0
      b%swork%watch%ninv = 0
    else
      if (entry > size(b%model%fint, 2)) return
      kind = b%model%fint(1, entry)
      if (.not. ((kind == MBDK_FORCE_POINT .and. (slot == 3 .or. slot == 4)) .or. &
                 (kind == MBDK_FORCE_TORQUE .and. slot == 1))) return
      b%model%freal(slot, entry) = value
      ! the evaluation's copy of the visited elements (mbdk_model: split_forces keeps the
      ! table's order among them)
      k = 0
      do e = 1, entry
        if (.not. any(b%model%fint(1, e) == [MBDK_FORCE_GRAVITY, MBDK_EFFECT_WEAR, &
                                             MBDK_FORCE_CONTACT, MBDK_FORCE_FRICTION])) k = k + 1
      end do
      if (k < 1 .or. k > size(b%model%freal_v, 2)) return
      if (b%model%fint_v(1, k) /= kind) return
      b%model%freal_v(slot, k) = value
      b%model%ninv = 0
      b%work%watch%ninv = 0
    end if
    mbdk_c_stepper_set_force = MBDK_SUCCESS
  end function mbdk_c_stepper_set_force

  !> At the current state of a scene or index-3 stepper, out[MBDK_STEPPER_NOUT] = the kinetic
  !> energy, the gravity potential, the spring potential (contacts' included), max |Phi| and
  !> max |C v + Phi_t| (the constraints' residuals; 0 without joints). An ODE stepper:
  !> MBDK_ERR_NOT_APPLICABLE; a state where the model cannot be evaluated: its status.
  integer(c_int) function mbdk_c_stepper_outputs(handle, out, nout) &
      bind(C, name='mbdk_stepper_outputs')
    type(c_ptr), value :: handle
    real(c_double), intent(out), optional :: out(*)
    integer(c_int), value :: nout
    type(stepper_box), pointer :: b
    real(dp) :: so(MBDK_SPATIAL_NOUT), en(MBDK_ENERGY_PARTS), res(MBDK_RESIDUALS), reac(3, 1)
    real(dp), allocatable :: a(:), lam(:)
    integer :: stat
    mbdk_c_stepper_outputs = MBDK_ERR_INVALID_INPUT
    b => box_of(handle)
    if (.not. (associated(b) .and. present(out)) .or. nout /= STEPPER_NOUT) return
    mbdk_c_stepper_outputs = MBDK_ERR_NOT_APPLICABLE
    if (b%kind == KIND_ODE) return
    if (b%spatial) then
      call mbdk_spatial_outputs(b%smodel, b%t_good, b%y_good, so, stat)
      if (stat == MBDK_SUCCESS) out(1:STEPPER_NOUT) = so([1, 2, 3, 5, 6])
    else
      allocate (a(b%model%nc), lam(b%model%m), stat=stat)
      if (stat /= 0) then
        mbdk_c_stepper_outputs = MBDK_ERR_NO_MEMORY
        return
      end if
      a = 0.0_dp
      lam = 0.0_dp
      ! a and lam given (zeros): neither the energy's first three parts nor the first two
      ! residuals need them, so no constrained solve is paid for
      call mbdk_model_outputs(b%model, b%t_good, b%y_good, .true., &
                              MBDK_OUT_ENERGY + MBDK_OUT_RESIDUALS, a, lam, reac, en, res, stat)
      if (stat == MBDK_SUCCESS) out(1:STEPPER_NOUT) = [en(1:3), res(1:2)]
    end if
    mbdk_c_stepper_outputs = int(stat, c_int)
  end function mbdk_c_stepper_outputs

  !> A planar scene's joint reactions at the current state, reac[nj][3]: the force (x, y) and
  !> the moment about the joint point that each joint of the table exerts on its first body,
  !> global frame, from the stepper's multipliers (mbdk_stepper_multipliers'). nj must be the
  !> table's joint count; a spatial or ODE stepper: MBDK_ERR_NOT_APPLICABLE.
  integer(c_int) function mbdk_c_stepper_reactions(handle, reac, nj) &
      bind(C, name='mbdk_stepper_reactions')
    type(c_ptr), value :: handle
    real(c_double), intent(out), optional :: reac(3, *)
    integer(c_int), value :: nj
    type(stepper_box), pointer :: b
    real(dp) :: en(MBDK_ENERGY_PARTS), res(MBDK_RESIDUALS)
    real(dp), allocatable :: a(:), lam(:), r(:, :)
    integer :: stat
    mbdk_c_stepper_reactions = MBDK_ERR_INVALID_INPUT
    b => box_of(handle)
    if (.not. associated(b)) return
    mbdk_c_stepper_reactions = MBDK_ERR_NOT_APPLICABLE
    if (b%kind == KIND_ODE .or. b%spatial) return
    mbdk_c_stepper_reactions = MBDK_ERR_INVALID_INPUT
    if (nj /= size(b%model%jint, 2) .or. (nj > 0 .and. .not. present(reac))) return
    mbdk_c_stepper_reactions = MBDK_SUCCESS
    if (nj == 0) return
    allocate (a(b%model%nc), lam(b%model%m), r(3, nj), stat=stat)
    if (stat /= 0) then
      mbdk_c_stepper_reactions = MBDK_ERR_NO_MEMORY
      return
    end if
    a = 0.0_dp
    stat = mbdk_c_stepper_multipliers(handle, lam, int(b%model%m, c_int))
    if (stat == MBDK_SUCCESS) &
      call mbdk_model_outputs(b%model, b%t_good, b%y_good, .true., MBDK_OUT_REACTIONS, a, lam, &
                              r, en, res, stat)
    if (stat == MBDK_SUCCESS) reac(:, 1:nj) = r
    mbdk_c_stepper_reactions = int(stat, c_int)
  end function mbdk_c_stepper_reactions

  !> Frees the stepper; a NULL handle is nothing to free (MBDK_SUCCESS).
  integer(c_int) function mbdk_c_stepper_destroy(handle) bind(C, name='mbdk_stepper_destroy')
    type(c_ptr), value :: handle
    type(stepper_box), pointer :: b
    b => box_of(handle)
    if (associated(b)) deallocate (b)
    mbdk_c_stepper_destroy = MBDK_SUCCESS
  end function mbdk_c_stepper_destroy

end module mbdk_capi_stepper
