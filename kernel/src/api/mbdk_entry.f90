!> What the f2py entries scene_run and spatial_run (mbdk_f2py.f90) share, written once so that
!> a planar and a spatial scene reach the same integrators by the same rule:
!>
!>   mbdk_entry_options    the option structs from their bytes (a size that is not the
!>                         struct's is MBDK_ERR_INVALID_INPUT), the method and the caller's
!>                         interrupt and progress words set in them
!>   mbdk_entry_integrate  the driver the method's family and the DAE form choose, on any
!>                         mechanism (mbdk_mechanism):
!>                           family dae_index3 (trapezoidal_index3, newmark, hht,
!>                             generalized_alpha): mbdk_index3_solve, its form and parameters in
!>                             mbdk_index3_options_t; its own a and multipliers
!>                           ida, or bdf with dae_form MBDK_DAE_I3 or MBDK_DAE_SI2: the
!>                             mechanism's DAE (mbdk_solve_dae; ida's forms index1 and GGL are
!>                             the codes 1 and 2 too); its own multipliers
!>                           any other method, dae_form MBDK_DAE_NONE: the ODE of the model's
!>                             formulation (mbdk_solve_ode)
!>                         ida with MBDK_DAE_NONE, or a form past SI2, is
!>                         MBDK_ERR_INVALID_INPUT; so is trapezoidal_index3 with another
!>                         member's parameters.
!>   mbdk_entry_planar_start   a planar scene's model built at its (assembled) start, with the
!>                         work record its energy output needs; mbdk_entry_planar_sizes_ok its
!>                         output arrays against what the run writes
!>   mbdk_entry_planar_outputs, mbdk_entry_spatial_outputs   a run's outputs at its samples
module mbdk_entry
  use, intrinsic :: iso_c_binding, only: c_sizeof, c_intptr_t
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use mbdk_kinds, only: dp
  use mbdk_status, only: MBDK_SUCCESS, MBDK_ERR_INVALID_INPUT, MBDK_ERR_NO_MEMORY, &
    MBDK_ERR_NOT_APPLICABLE, MBDK_ERR_OUTPUT_SIZE, mbdk_is_failure
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_methods, only: mbdk_method_info, MBDK_FAMILY_DAE_INDEX3, MBDK_FAMILY_IDA, &
    MBDK_FAMILY_VARIABLE_BDF, MBDK_METHOD_NAME_LEN, MBDK_TRAPEZOIDAL_INDEX3
  use mbdk_mechanism, only: mbdk_mechanism_t
  use mbdk_mechanism_dae, only: MBDK_DAE_NONE, MBDK_DAE_I3, MBDK_DAE_SI2
  use mbdk_solve, only: mbdk_solve_ode, mbdk_solve_dae
  use mbdk_trapezoidal_index3, only: mbdk_index3_solve, mbdk_index3_options_t, &
    mbdk_index3_is_trapezoidal
  use mbdk_watch, only: mbdk_watch_work_at, mbdk_watch_reserve
  use mbdk_assembly, only: mbdk_model_start
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES
  use mbdk_model, only: mbdk_model_t, mbdk_model_work_t, mbdk_model_outputs, &
    MBDK_OUT_ACCELERATIONS, MBDK_OUT_MULTIPLIERS, MBDK_OUT_REACTIONS, MBDK_OUT_ENERGY, &
    MBDK_OUT_RESIDUALS, mbdk_model_options_t
  use mbdk_spatial_model, only: mbdk_spatial_model_t, mbdk_spatial_work_t, &
    mbdk_spatial_outputs, mbdk_spatial_multipliers, MBDK_SPATIAL_NOUT, &
    mbdk_spatial_options_t, mbdk_spatial_init
  use mbdk_joint_coords, only: mbdk_joint_model_t, mbdk_joint_work_t, mbdk_joint_init, &
    mbdk_joint_to_absolute
  implicit none
  private
  public :: mbdk_entry_options, mbdk_entry_integrate, mbdk_entry_route, &
    mbdk_entry_planar_outputs, mbdk_entry_spatial_outputs, mbdk_entry_planar_start, &
    mbdk_entry_planar_sizes_ok, mbdk_entry_spatial_model, mbdk_entry_joint_integrate

  !> how a run is integrated (mbdk_entry_route)
  integer, parameter, public :: MBDK_ROUTE_ODE = 1, MBDK_ROUTE_DAE = 2, MBDK_ROUTE_INDEX3 = 3

contains

  !> opt and i3 from their bytes, with the method, the interrupt flag's and the progress
  !> word's addresses set in both.
  subroutine mbdk_entry_options(method_id, optbuf, i3buf, flag, progress, opt, i3, stat)
    integer, intent(in) :: method_id
    real(dp), intent(in) :: optbuf(:), i3buf(:)
    integer(c_intptr_t), intent(in) :: flag, progress
    type(mbdk_options_t), intent(out) :: opt
    type(mbdk_index3_options_t), intent(out) :: i3
    integer, intent(out) :: stat
    stat = MBDK_ERR_INVALID_INPUT
    if (8 * size(optbuf) /= c_sizeof(opt) .or. 8 * size(i3buf) /= c_sizeof(i3)) return
    opt = transfer(optbuf, opt)
    i3 = transfer(i3buf, i3)
    opt%method = method_id
    opt%interrupt = flag
    opt%progress = progress
    i3%interrupt = flag
    i3%progress = progress
    stat = MBDK_SUCCESS
  end subroutine mbdk_entry_options

  !> The route (MBDK_ROUTE_*) of a method and DAE form, 0 for a pair no driver takes.
  integer function mbdk_entry_route(method_id, dae_form) result(route)
    integer, intent(in) :: method_id, dae_form
    character(len=MBDK_METHOD_NAME_LEN) :: name
    integer :: family, order
    route = 0
    call mbdk_method_info(method_id, name, family, order)
    if (dae_form < MBDK_DAE_NONE .or. dae_form > MBDK_DAE_SI2) return
    if (family == MBDK_FAMILY_DAE_INDEX3) then
      if (dae_form == MBDK_DAE_NONE) route = MBDK_ROUTE_INDEX3
    else if (family == MBDK_FAMILY_IDA .or. (family == MBDK_FAMILY_VARIABLE_BDF .and. &
             dae_form /= MBDK_DAE_NONE)) then
      if (dae_form == MBDK_DAE_I3 .or. dae_form == MBDK_DAE_SI2) route = MBDK_ROUTE_DAE
    else if (family > 0 .and. dae_form == MBDK_DAE_NONE) then
      route = MBDK_ROUTE_ODE
    end if
  end function mbdk_entry_route

  !> mech integrated from (t0, y) to t_end on the route of (opt%method, dae_form); the samples
  !> in t_out, y_out, and where the integrator has its own, a_out, lam_out and iters_out (the
  !> index-3 family: all three; a DAE: lam_out, NaN past the samples written). atol: the ODE
  !> methods' per-state absolute tolerances, where given; times: the ODE methods' sample times
  !> (mbdk_solve_ode), where given (size 0: opt's grid; the other routes take none).
  subroutine mbdk_entry_integrate(mech, opt, i3, dae_form, t0, t_end, y, t_out, y_out, a_out, &
                                  lam_out, iters_out, nwritten, st, stat, atol, times)
    class(mbdk_mechanism_t), intent(in), target :: mech
    type(mbdk_options_t), intent(in) :: opt
    type(mbdk_index3_options_t), intent(in) :: i3
    integer, intent(in) :: dae_form
    real(dp), intent(in) :: t0, t_end
    real(dp), intent(inout) :: y(:)
    real(dp), intent(out) :: t_out(:), y_out(:, :)
    real(dp), intent(inout) :: a_out(:, :), lam_out(:, :)
    integer, intent(inout) :: iters_out(:)
    integer, intent(out) :: nwritten
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: atol(:), times(:)
    integer :: route
    nwritten = 0
    stat = MBDK_ERR_INVALID_INPUT
    route = mbdk_entry_route(opt%method, dae_form)
    if (present(times)) then
      if (size(times) > 0 .and. route /= MBDK_ROUTE_ODE) return
    end if
    select case (route)
    case (MBDK_ROUTE_INDEX3)
      ! trapezoidal_index3 is the family's member with its own parameters (newmark, hht and
      ! generalized_alpha carry theirs: mbdk_index3_options)
      if (opt%method == MBDK_TRAPEZOIDAL_INDEX3 .and. .not. mbdk_index3_is_trapezoidal(i3)) &
        return
      call mbdk_index3_solve(mech, i3, t0, t_end, y, t_out, y_out, a_out, lam_out, iters_out, &
                             nwritten, st, stat)
    case (MBDK_ROUTE_DAE)
      call mbdk_solve_dae(mech, opt, dae_form, t0, t_end, y, t_out, y_out, lam_out, nwritten, &
                          st, stat)
      if (nwritten < size(lam_out, 2)) &
        lam_out(:, nwritten + 1:) = ieee_value(0.0_dp, ieee_quiet_nan)
    case (MBDK_ROUTE_ODE)
      call mbdk_solve_ode(mech, opt, t0, t_end, y, t_out, y_out, nwritten, st, stat, atol, &
                          times)
    end select
  end subroutine mbdk_entry_integrate

  !> A spatial scene's ODE in joint coordinates (mbdk_joint_coords): the joint model of the
  !> full model (every joint, built at the assembled start y with options so, which ask for
  !> joint coordinates) and the scene's tables (jtype .. freal, the first nj and nf columns),
  !> integrated by opt's ODE method from t0 to t_end (mbdk_solve_ode; times: its sample times,
  !> where given), its samples written as the full model's absolute states y_out(:, 1:
  !> nwritten), so that the run's outputs, multipliers and contacts are the absolute model's
  !> at them. A route other than the ODE's is MBDK_ERR_NOT_APPLICABLE.
  subroutine mbdk_entry_joint_integrate(full, so, mass, inertia, nj, jtype, jbody, jreal, nf, &
                                        ftype, fbody, freal, opt, dae_form, t0, t_end, y, &
                                        t_out, y_out, nwritten, st, stat, times)
    type(mbdk_spatial_model_t), intent(in), target :: full
    type(mbdk_spatial_options_t), intent(in) :: so
    real(dp), intent(in) :: mass(:), inertia(:, :, :), jreal(:, :), freal(:, :), t0, t_end, &
      y(:)
    integer, intent(in) :: nj, nf, jtype(:), jbody(:, :), ftype(:), fbody(:, :), dae_form
    type(mbdk_options_t), intent(in) :: opt
    real(dp), intent(out) :: t_out(:), y_out(:, :)
    integer, intent(out) :: nwritten
    type(mbdk_stats_t), intent(inout) :: st
    integer, intent(out) :: stat
    real(dp), intent(in), optional :: times(:)
    type(mbdk_joint_model_t) :: jm
    type(mbdk_joint_work_t), target :: jw
    real(dp), allocatable :: y0j(:), yj(:, :)
    real(dp) :: asked
    integer :: k, astat
    nwritten = 0
    t_out = 0.0_dp
    y_out = 0.0_dp
    stat = MBDK_ERR_NOT_APPLICABLE
    if (mbdk_entry_route(opt%method, dae_form) /= MBDK_ROUTE_ODE) return
    asked = 0.0_dp
    call mbdk_joint_init(jm, jw, full, so, mass, inertia, jtype(1:nj), jbody(:, 1:nj), &
                         jreal(:, 1:nj), ftype(1:nf), fbody(:, 1:nf), freal(:, 1:nf), t0, y, &
                         y0j, stat, asked)
    if (stat == MBDK_ERR_NO_MEMORY) st%alloc_bytes = st%alloc_bytes + asked
    if (stat /= MBDK_SUCCESS) return
    allocate (yj(jm%n, size(y_out, 2)), stat=astat)
    call mbdk_alloc_status(astat, MBDK_REAL_BYTES * real(jm%n, dp) * size(y_out, 2), stat, &
                           st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    call mbdk_solve_ode(jm, opt, t0, t_end, y0j, t_out, yj, nwritten, st, stat, times=times)
    do k = 1, nwritten
      call mbdk_joint_to_absolute(jm, yj(:, k), y_out(:, k))
    end do
  end subroutine mbdk_entry_joint_integrate

  !> The planar model of the tables (mbdk_model_start: the pose defaults filled in at y, the
  !> state assembled where assemble, moving the coordinates not given), checked against the
  !> state's length and the multipliers' rows m1 (MBDK_ERR_INVALID_INPUT,
  !> MBDK_ERR_OUTPUT_SIZE); with the energy asked for (want), the watch records the work at
  !> every step for nsamp samples (mbdk_watch_reserve).
  subroutine mbdk_entry_planar_start(model, work, mass, inertia, kinds, jint, jreal, fint, &
                                     freal, mopt, t0, y, given, assemble, want, nsamp, m1, &
                                     asm_iters, asm_resid, velocity, bad_joint, bad_force, st, &
                                     stat)
    type(mbdk_model_t), intent(out) :: model
    type(mbdk_model_work_t), target, intent(inout) :: work
    real(dp), intent(in) :: mass(:), inertia(:), jreal(:, :), freal(:, :), t0
    integer, intent(in) :: kinds(:), jint(:, :), fint(:, :), want, nsamp, m1
    type(mbdk_model_options_t), intent(in) :: mopt
    real(dp), intent(inout) :: y(:)
    logical, intent(in) :: given(:), assemble
    integer, intent(out) :: asm_iters, bad_joint, bad_force, stat
    real(dp), intent(out) :: asm_resid(:)
    logical, intent(out) :: velocity
    type(mbdk_stats_t), intent(inout) :: st
    integer :: nc
    nc = 3 * size(mass)
    call mbdk_model_start(model, work, mass, inertia, jint, jreal, fint, freal, mopt, t0, &
                          y(1:2 * nc), given(1:nc), given(nc + 1:2 * nc), assemble, asm_iters, &
                          asm_resid, velocity, bad_joint, bad_force, stat, kinds, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) return
    stat = MBDK_ERR_INVALID_INPUT
    if (size(y) /= model%n) return
    stat = MBDK_ERR_OUTPUT_SIZE
    if (m1 < max(model%m, 1)) return
    ! the energy asked for: the watch integrates the work at every step, and the samples take it
    model%record_work = iand(want, MBDK_OUT_ENERGY) /= 0
    model%has_watch = model%has_watch .or. model%record_work
    stat = MBDK_SUCCESS
    if (model%record_work) call mbdk_watch_reserve(work%watch, nsamp, stat)
  end subroutine mbdk_entry_planar_start

  !> The spatial model of an f2py entry's tables, whose arrays have room for nj joints and nf
  !> forces in their first columns (MBDK_ERR_INVALID_INPUT where they have not), built at its
  !> initial state (t0, y0) with options so (mbdk_spatial_init; asked: MBDK_ERR_NO_MEMORY's
  !> bytes).
  subroutine mbdk_entry_spatial_model(model, work, so, mass, inertia, nj, jtype, jbody, jreal, &
                                      nf, ftype, fbody, freal, t0, y0, stat, asked)
    type(mbdk_spatial_model_t), intent(out) :: model
    type(mbdk_spatial_work_t), target, intent(inout) :: work
    type(mbdk_spatial_options_t), intent(in) :: so
    real(dp), intent(in) :: mass(:), inertia(:, :, :), jreal(:, :), freal(:, :), t0, y0(:)
    integer, intent(in) :: nj, nf, jtype(:), jbody(:, :), ftype(:), fbody(:, :)
    integer, intent(out) :: stat
    real(dp), intent(inout), optional :: asked
    stat = MBDK_ERR_INVALID_INPUT
    if (nj < 0 .or. nj > size(jtype) .or. nf < 0 .or. nf > size(ftype)) return
    call mbdk_spatial_init(model, work, so, mass, inertia, jtype(1:nj), jbody(:, 1:nj), &
                           jreal(:, 1:nj), ftype(1:nf), fbody(:, 1:nf), freal(:, 1:nf), t0, &
                           y0, stat, asked)
  end subroutine mbdk_entry_spatial_model

  !> Whether a planar run's output arrays have the columns (na, nl, ni, nr, ne, nrs) for nsamp
  !> samples of what it writes: the index-3 family always a, lam and its iterations, a DAE its
  !> lam, and every output want asks for.
  logical function mbdk_entry_planar_sizes_ok(route, want, nsamp, na, nl, ni, nr, ne, nrs) &
      result(ok)
    integer, intent(in) :: route, want, nsamp, na, nl, ni, nr, ne, nrs
    logical :: index3
    index3 = route == MBDK_ROUTE_INDEX3
    ok = .not. ((index3 .or. iand(want, MBDK_OUT_ACCELERATIONS) /= 0) .and. na < nsamp)
    ok = ok .and. .not. ((route /= MBDK_ROUTE_ODE .or. iand(want, MBDK_OUT_MULTIPLIERS) /= 0) &
                         .and. nl < nsamp)
    ok = ok .and. .not. (index3 .and. ni < nsamp)
    ok = ok .and. .not. (iand(want, MBDK_OUT_REACTIONS) /= 0 .and. nr < nsamp)
    ok = ok .and. .not. (iand(want, MBDK_OUT_ENERGY) /= 0 .and. ne < nsamp)
    ok = ok .and. .not. (iand(want, MBDK_OUT_RESIDUALS) /= 0 .and. nrs < nsamp)
  end function mbdk_entry_planar_sizes_ok

  !> A planar run's outputs (want: MBDK_OUT_* bits of mbdk_model) at its nwritten samples, from
  !> the model at each sampled state: a_out and lam_out where the integrator has none of its
  !> own (index3: the index-3 family's a and lam, which the outputs take; dae: a DAE's lam), the
  !> joints' reactions, the energy parts with the work the watch integrated at every step
  !> (energy(7:9, k): mbdk_watch_work_at), the residuals. A sample whose outputs cannot be
  !> computed (the state a failed run stopped at) gets NaN; outputs that cannot be allocated
  !> set stat to MBDK_ERR_NO_MEMORY where the run itself succeeded.
  subroutine mbdk_entry_planar_outputs(model, work, t_out, y_out, nwritten, want, index3, dae, &
                                       nj, a_out, lam_out, reac, energy, resid, stat, st)
    type(mbdk_model_t), intent(inout) :: model
    type(mbdk_model_work_t), intent(in) :: work
    real(dp), intent(in) :: t_out(:), y_out(:, :)
    integer, intent(in) :: nwritten, want, nj
    logical, intent(in) :: index3, dae
    real(dp), intent(inout) :: a_out(:, :), lam_out(:, :), reac(:, :, :), energy(:, :), &
      resid(:, :)
    integer, intent(inout) :: stat
    type(mbdk_stats_t), intent(inout) :: st
    real(dp), allocatable :: a_s(:), lam_s(:), reac_s(:, :), en_s(:), res_s(:)
    real(dp) :: nan
    integer :: k, krec, m, nc, astat, ostat
    nan = ieee_value(nan, ieee_quiet_nan)
    m = model%m
    nc = model%nc
    allocate (a_s(nc), lam_s(m), reac_s(3, max(nj, 1)), en_s(6), res_s(3), stat=astat)
    if (astat /= 0) then
      ! the run's own status first: the outputs are missing only where it succeeded
      if (.not. mbdk_is_failure(stat)) &
        call mbdk_alloc_status(astat, MBDK_REAL_BYTES * (nc + m + 3.0_dp * max(nj, 1) + 9), &
                               stat, st%alloc_bytes)
      return
    end if
    krec = 0
    do k = 1, nwritten
      if (index3) then
        a_s = a_out(:, k)
        lam_s = lam_out(1:m, k)
      end if
      call mbdk_model_outputs(model, t_out(k), y_out(:, k), index3, want, a_s, lam_s, &
                              reac_s(:, 1:nj), en_s, res_s, ostat)
      if (ostat /= MBDK_SUCCESS) then
        a_s = nan; lam_s = nan; reac_s = nan; en_s = nan; res_s = nan
        ! NaN stands for a state that has no outputs, not for memory that was not there
        if (ostat == MBDK_ERR_NO_MEMORY .and. .not. mbdk_is_failure(stat)) stat = ostat
      end if
      if (.not. index3 .and. iand(want, MBDK_OUT_ACCELERATIONS) /= 0) a_out(:, k) = a_s
      ! a DAE integrator's multipliers are its own (like the index-3 family's); the reactions
      ! come from the model's solve at the sampled state
      if (.not. (index3 .or. dae) .and. iand(want, MBDK_OUT_MULTIPLIERS) /= 0) &
        lam_out(1:m, k) = lam_s
      if (iand(want, MBDK_OUT_REACTIONS) /= 0) reac(:, 1:nj, k) = reac_s(:, 1:nj)
      if (iand(want, MBDK_OUT_ENERGY) /= 0) then
        energy(1:6, k) = en_s
        call mbdk_watch_work_at(work%watch, t_out(k), krec, energy(7:9, k))
      end if
      if (iand(want, MBDK_OUT_RESIDUALS) /= 0) resid(:, k) = res_s
    end do
  end subroutine mbdk_entry_planar_outputs

  !> A spatial run's outputs at its nwritten samples: out(1:MBDK_SPATIAL_NOUT, k) from
  !> mbdk_spatial_outputs (NaN where a sample has none), with the integrator's multipliers
  !> lam_out where own_lam (a DAE's, the projected index-3 form's) or else solved for at the
  !> sample; the last row the work of dampers, loads and drivers as the watch integrated it.
  !> solve_lam: the run has no multipliers of its own, and lam_out(:, k) gets the reduced
  !> form's at the sample (NaN where its solve fails).
  subroutine mbdk_entry_spatial_outputs(model, work, t_out, y_out, nwritten, own_lam, &
                                        solve_lam, out, lam_out)
    type(mbdk_spatial_model_t), intent(in) :: model
    type(mbdk_spatial_work_t), intent(in) :: work
    real(dp), intent(in) :: t_out(:), y_out(:, :)
    integer, intent(in) :: nwritten
    logical, intent(in) :: own_lam, solve_lam
    real(dp), intent(inout) :: out(:, :), lam_out(:, :)
    real(dp) :: parts(3), nan
    integer :: k, krec, stat
    nan = ieee_value(0.0_dp, ieee_quiet_nan)
    krec = 0
    do k = 1, nwritten
      call mbdk_watch_work_at(work%watch, t_out(k), krec, parts)
      out(MBDK_SPATIAL_NOUT + 1, k) = parts(3)
      if (own_lam) then
        call mbdk_spatial_outputs(model, t_out(k), y_out(:, k), out(1:MBDK_SPATIAL_NOUT, k), &
                                  stat, lam_in=lam_out(1:model%m, k))
      else
        call mbdk_spatial_outputs(model, t_out(k), y_out(:, k), out(1:MBDK_SPATIAL_NOUT, k), &
                                  stat)
      end if
      if (stat /= MBDK_SUCCESS) then
        out(1:MBDK_SPATIAL_NOUT, k) = nan
        cycle
      end if
      if (solve_lam .and. model%m > 0) then
        call mbdk_spatial_multipliers(model, t_out(k), y_out(:, k), lam_out(1:model%m, k), stat)
        if (stat /= MBDK_SUCCESS) lam_out(:, k) = nan
      end if
    end do
  end subroutine mbdk_entry_spatial_outputs

end module mbdk_entry
