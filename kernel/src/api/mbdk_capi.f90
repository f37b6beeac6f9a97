!> The C API (bind(C) only). kernel/include/mbdk.h is its hand-written mirror.
!> Every function returns a status (or an id) and never prints or stops the process. Pointer
!> arguments are `optional` (Fortran 2018's interoperable optional dummies): a NULL pointer is an
!> absent argument, refused with MBDK_ERR_INVALID_INPUT before anything is read or written
!> (kernel/tests/c_null_args.c passes NULL in every position).
module mbdk_capi
  use, intrinsic :: iso_c_binding, only: c_int, c_int64_t, c_double, c_char, c_ptr, c_funptr, &
    c_null_char, c_associated
  use mbdk_kinds, only: dp, i8
  use mbdk_status
  use mbdk_options, only: mbdk_options_t
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_memory, only: mbdk_alloc_status, MBDK_REAL_BYTES, MBDK_INT_BYTES
  use mbdk_methods, only: mbdk_method_id
  use mbdk_fixed_step, only: mbdk_step_plan
  use mbdk_solve, only: mbdk_solve_ode, mbdk_sample_plan
  use mbdk_callback_problem, only: mbdk_c_problem_t, mbdk_c_problem_init
  use mbdk_model, only: mbdk_model_t, mbdk_model_init, mbdk_model_work_t, mbdk_model_options_t
  use mbdk_trapezoidal_index3, only: mbdk_index3_options_t, mbdk_index3_solve, mbdk_index3_plan
  use mbdk_structs, only: mbdk_struct_info, mbdk_struct_field, MBDK_STRUCT_NAME_LEN
  use mbdk_elements, only: mbdk_element_kind, mbdk_body_kind, MBDK_ELEMENT_NAME_LEN, &
    MBDK_BODY_KINDS
  use mbdk_c_tables, only: mbdk_c_tables_read
  use mbdk_spatial_model, only: mbdk_spatial_options_t
  implicit none
  private

contains

  subroutine mbdk_c_index3_default_options(opt) bind(C, name='mbdk_index3_default_options')
    type(mbdk_index3_options_t), intent(out), optional :: opt
    type(mbdk_index3_options_t) :: d
    if (present(opt)) opt = d
  end subroutine mbdk_c_index3_default_options

  subroutine mbdk_c_model_default_options(opt) bind(C, name='mbdk_model_default_options')
    type(mbdk_model_options_t), intent(out), optional :: opt
    type(mbdk_model_options_t) :: d
    if (present(opt)) opt = d
  end subroutine mbdk_c_model_default_options

  subroutine mbdk_c_spatial_default_options(opt) bind(C, name='mbdk_spatial_default_options')
    type(mbdk_spatial_options_t), intent(out), optional :: opt
    type(mbdk_spatial_options_t) :: d
    if (present(opt)) opt = d
  end subroutine mbdk_c_spatial_default_options

  integer(c_int) function mbdk_c_index3_sample_count(opt, t0, t_end, nsamp) &
      bind(C, name='mbdk_index3_sample_count')
    type(mbdk_index3_options_t), intent(in), optional :: opt
    real(c_double), value :: t0, t_end
    integer(c_int), intent(out), optional :: nsamp
    integer(kind=8) :: nsteps
    integer :: ns, stat
    logical :: shortened
    mbdk_c_index3_sample_count = MBDK_ERR_INVALID_INPUT
    if (.not. (present(opt) .and. present(nsamp))) return
    call mbdk_index3_plan(opt, t0, t_end, nsteps, ns, shortened, stat)
    nsamp = int(ns, c_int)
    mbdk_c_index3_sample_count = int(stat, c_int)
  end function mbdk_c_index3_sample_count

  !> trapezoidal_index3 on a scene given by its tables (layouts in mbdk_joints.f90 and
  !> mbdk_force_elements.f90; row-major C arrays jint[nj][4] are Fortran jint(4, nj)). jint and
  !> jreal may be NULL when nj = 0, fint and freal when nf = 0, lam_out when there are no
  !> constraints; any other NULL is refused.
  integer(c_int) function mbdk_c_index3_solve(nb, mass, inertia, nj, jint, jreal, nf, fint, &
      freal, opt, t0, t_end, y0, nsamp, t_out, y_out, a_out, lam_out, iters_out, nwritten, &
      stats) bind(C, name='mbdk_index3_solve')
    integer(c_int), value :: nb, nj, nf, nsamp
    real(c_double), intent(in), optional :: mass(*), inertia(*), jreal(*), freal(*), y0(*)
    integer(c_int), intent(in), optional :: jint(*), fint(*)
    type(mbdk_index3_options_t), intent(in), optional :: opt
    real(c_double), value :: t0, t_end
    real(c_double), intent(out), optional :: t_out(*), y_out(*), a_out(*), lam_out(*)
    integer(c_int), intent(out), optional :: iters_out(*), nwritten
    type(mbdk_stats_t), intent(out), optional :: stats
    type(mbdk_model_t) :: model
    type(mbdk_model_work_t), target :: work
    type(mbdk_stats_t) :: st
    type(mbdk_model_options_t) :: mopt
    integer :: stat, nw, nc, m
    integer, allocatable :: ji(:, :), fi(:, :), it(:)
    real(dp), allocatable :: jr(:, :), fr(:, :), lam(:, :)

    mbdk_c_index3_solve = int(MBDK_ERR_INVALID_INPUT, c_int)
    if (.not. (present(nwritten) .and. present(stats))) return
    nwritten = 0
    stats = st
    if (.not. (present(opt) .and. present(t_out) .and. present(y_out) .and. present(a_out) .and. &
               present(iters_out)) .or. nsamp < 1) return
    call mbdk_c_tables_read(nb, mass, inertia, nj, jint, jreal, nf, fint, freal, y0, ji, jr, fi, &
                            fr, stat, st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) then
      stats = st
      mbdk_c_index3_solve = int(stat, c_int)
      return
    end if
    ! the model's defaults: its reduced formulation gives only the consistent a, lambda at t0
    call mbdk_model_init(model, mass(1:nb), inertia(1:nb), ji, jr, fi, fr, mopt, work, stat, &
                         asked=st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) then
      stats = st
      mbdk_c_index3_solve = int(stat, c_int)
      return
    end if
    nc = model%nc
    m = model%m
    if (m > 0 .and. .not. present(lam_out)) return
    ! the caller's buffers hold nsamp samples of 2 nc, nc and m values: their sizes must be
    ! indexable
    if (int(2 * nc, i8) * int(nsamp, i8) > huge(0) .or. &
        int(max(m, 1), i8) * int(nsamp, i8) > huge(0)) then
      mbdk_c_index3_solve = int(MBDK_ERR_OUTPUT_SIZE, c_int)
      return
    end if
    allocate (lam(max(m, 1), nsamp), it(nsamp), stat=nw)
    call mbdk_alloc_status(nw, (MBDK_REAL_BYTES * max(m, 1) + MBDK_INT_BYTES) * nsamp, stat, &
                           st%alloc_bytes)
    if (stat /= MBDK_SUCCESS) then
      stats = st
      mbdk_c_index3_solve = int(stat, c_int)
      return
    end if
    call solve(y_out(1:2 * nc * nsamp), a_out(1:nc * nsamp))
    if (m > 0) lam_out(1:m * nw) = reshape(lam(1:m, 1:nw), [m * nw])
    iters_out(1:nw) = int(it(1:nw), c_int)
    nwritten = int(nw, c_int)
    stats = st
    mbdk_c_index3_solve = int(stat, c_int)

  contains

    subroutine solve(yflat, aflat)
      real(c_double), intent(inout), target :: yflat(2 * nc, nsamp), aflat(nc, nsamp)
      call mbdk_index3_solve(model, opt, t0, t_end, y0(1:2 * nc), &
                             t_out(1:nsamp), yflat, aflat, lam(1:m, :), it, nw, st, stat)
    end subroutine solve

  end function mbdk_c_index3_solve

  subroutine mbdk_default_options(opt) bind(C, name='mbdk_default_options')
    type(mbdk_options_t), intent(out), optional :: opt
    type(mbdk_options_t) :: d
    if (present(opt)) opt = d
  end subroutine mbdk_default_options

  integer(c_int) function mbdk_c_method_id(name) bind(C, name='mbdk_method_id')
    character(kind=c_char), intent(in), optional :: name(*)
    mbdk_c_method_id = 0
    if (present(name)) mbdk_c_method_id = int(mbdk_method_id(from_c(name)), c_int)
  end function mbdk_c_method_id

  integer(c_int) function mbdk_c_sample_count(t0, t_end, h, every, nsamp) &
      bind(C, name='mbdk_sample_count')
    real(c_double), value :: t0, t_end, h
    integer(c_int), value :: every
    integer(c_int), intent(out), optional :: nsamp
    integer(kind=8) :: nsteps
    integer :: ns, stat
    logical :: shortened
    mbdk_c_sample_count = MBDK_ERR_INVALID_INPUT
    if (.not. present(nsamp)) return
    call mbdk_step_plan(t0, t_end, h, int(every), nsteps, ns, shortened, stat)
    nsamp = int(ns, c_int)
    mbdk_c_sample_count = int(stat, c_int)
  end function mbdk_c_sample_count

  !> Samples a solve with opt writes over [t0, t_end], whatever its method: fixed step (h,
  !> every) or error-controlled (dt_out).
  integer(c_int) function mbdk_c_solve_sample_count(t0, t_end, opt, nsamp) &
      bind(C, name='mbdk_solve_sample_count')
    real(c_double), value :: t0, t_end
    type(mbdk_options_t), intent(in), optional :: opt
    integer(c_int), intent(out), optional :: nsamp
    integer :: ns, stat
    mbdk_c_solve_sample_count = MBDK_ERR_INVALID_INPUT
    if (.not. (present(nsamp) .and. present(opt))) return
    call mbdk_sample_plan(opt, t0, t_end, ns, stat)
    nsamp = int(ns, c_int)
    mbdk_c_solve_sample_count = int(stat, c_int)
  end function mbdk_c_solve_sample_count

  !> jac: NULL, or the analytic Jacobian of f (column-major), used by the implicit methods
  integer(c_int) function mbdk_c_solve_ode(f, jac, user_data, n, t0, t_end, y0, opt, nsamp, &
      t_out, y_out, nwritten, stats) bind(C, name='mbdk_solve_ode')
    type(c_funptr), value :: f, jac
    type(c_ptr), value :: user_data
    integer(c_int), value :: n, nsamp
    real(c_double), value :: t0, t_end
    real(c_double), intent(in), optional :: y0(*)
    type(mbdk_options_t), intent(in), optional :: opt
    real(c_double), intent(out), optional :: t_out(*)
    real(c_double), intent(out), optional :: y_out(*)
    integer(c_int), intent(out), optional :: nwritten
    type(mbdk_stats_t), intent(out), optional :: stats
    type(mbdk_c_problem_t) :: prob
    type(mbdk_stats_t) :: st
    integer :: stat, nw

    mbdk_c_solve_ode = MBDK_ERR_INVALID_INPUT
    if (.not. (present(nwritten) .and. present(stats))) return
    nwritten = 0
    stats = st
    if (.not. (present(y0) .and. present(opt) .and. present(t_out) .and. present(y_out))) return
    if (n < 1 .or. nsamp < 1 .or. .not. c_associated(f)) then
      mbdk_c_solve_ode = MBDK_ERR_INVALID_INPUT
      return
    end if
    if (int(n, i8) * int(nsamp, i8) > huge(0)) then
      mbdk_c_solve_ode = MBDK_ERR_OUTPUT_SIZE
      return
    end if
    if (opt%nq < 0 .or. (opt%nq > 0 .and. 2 * opt%nq /= n)) then
      mbdk_c_solve_ode = MBDK_ERR_INVALID_INPUT
      return
    end if
    call mbdk_c_problem_init(prob, f, user_data, int(n), int(opt%nq), jac)
    call solve(y_out(1:n * nsamp))
    nwritten = int(nw, c_int)
    stats = st
    mbdk_c_solve_ode = int(stat, c_int)

  contains

    subroutine solve(yflat)
      real(c_double), intent(inout), target :: yflat(n, nsamp)
      call mbdk_solve_ode(prob, opt, t0, t_end, y0(1:n), t_out(1:nsamp), yflat, nw, st, stat)
    end subroutine solve

  end function mbdk_c_solve_ode

  !> Copies the message of a status into buf (NUL-terminated, truncated to buflen - 1).
  integer(c_int) function mbdk_c_status_message(status, buf, buflen) &
      bind(C, name='mbdk_status_message')
    integer(c_int), value :: status, buflen
    character(kind=c_char), intent(out), optional :: buf(*)
    mbdk_c_status_message = MBDK_ERR_INVALID_INPUT
    if (buflen < 1 .or. .not. present(buf)) return
    call to_c(mbdk_status_message(int(status)), buf, int(buflen))
    mbdk_c_status_message = MBDK_SUCCESS
  end function mbdk_c_status_message

  !> i-th entry (1-based) of the status table: code and name. Returns MBDK_ERR_INVALID_INPUT past
  !> the end; used by tests/examples to check the header against the table.
  integer(c_int) function mbdk_c_status_entry(i, code, name, namelen) &
      bind(C, name='mbdk_status_entry')
    integer(c_int), value :: i, namelen
    integer(c_int), intent(out), optional :: code
    character(kind=c_char), intent(out), optional :: name(*)
    character(len=MBDK_STATUS_NAME_LEN) :: nm
    character(len=MBDK_STATUS_MSG_LEN) :: msg
    integer :: c
    mbdk_c_status_entry = MBDK_ERR_INVALID_INPUT
    if (namelen < 1 .or. .not. (present(code) .and. present(name))) return
    code = 0
    call mbdk_status_entry(int(i), c, nm, msg)
    if (c == huge(0)) return
    code = int(c, c_int)
    call to_c(nm, name, int(namelen))
    mbdk_c_status_entry = MBDK_SUCCESS
  end function mbdk_c_status_entry

  !> Struct id (1-based; MBDK_STRUCT_* of mbdk_structs): its C name, size and field count.
  !> MBDK_ERR_INVALID_INPUT past the last struct. Lets a C program (kernel/tests/
  !> c_struct_layout.c) check mbdk.h's structs against the kernel's own layout.
  integer(c_int) function mbdk_c_struct_info(id, name, namelen, nbytes, nfields) &
      bind(C, name='mbdk_struct_info')
    integer(c_int), value :: id, namelen
    character(kind=c_char), intent(out), optional :: name(*)
    integer(c_int), intent(out), optional :: nbytes, nfields
    character(len=MBDK_STRUCT_NAME_LEN) :: nm
    integer :: nb, nf
    mbdk_c_struct_info = MBDK_ERR_INVALID_INPUT
    if (.not. (present(name) .and. present(nbytes) .and. present(nfields))) return
    call mbdk_struct_info(int(id), nm, nb, nf)
    nbytes = int(nb, c_int)
    nfields = int(nf, c_int)
    if (nf == 0 .or. namelen < 1) return
    call to_c(nm, name, int(namelen))
    mbdk_c_struct_info = MBDK_SUCCESS
  end function mbdk_c_struct_info

  !> Field i (1-based) of struct id: name, byte offset and type (1 int, 2 int64_t, 3 double,
  !> 4 pointer). MBDK_ERR_INVALID_INPUT past the last field.
  integer(c_int) function mbdk_c_struct_field(id, i, name, namelen, offset, ftype) &
      bind(C, name='mbdk_struct_field')
    integer(c_int), value :: id, i, namelen
    character(kind=c_char), intent(out), optional :: name(*)
    integer(c_int), intent(out), optional :: offset, ftype
    character(len=MBDK_STRUCT_NAME_LEN) :: nm
    integer :: off, ft
    mbdk_c_struct_field = MBDK_ERR_INVALID_INPUT
    if (.not. (present(name) .and. present(offset) .and. present(ftype))) return
    call mbdk_struct_field(int(id), int(i), nm, off, ft)
    offset = int(off, c_int)
    ftype = int(ft, c_int)
    if (ft == 0 .or. namelen < 1) return
    call to_c(nm, name, int(namelen))
    mbdk_c_struct_field = MBDK_SUCCESS
  end function mbdk_c_struct_field

  !> Entry i (1-based) of the element registry (mbdk_elements): class, code, name, the body
  !> kinds it applies to (MBDK_ON_* bits), its constraint rows on each body kind (rows[k - 1]
  !> on kind k, MBDK_BODY_KINDS of them), states.
  integer(c_int) function mbdk_c_element_kind(i, cls, code, name, namelen, on, rows, states) &
      bind(C, name='mbdk_element_kind')
    integer(c_int), value :: i, namelen
    integer(c_int), intent(out), optional :: cls, code, on, states
    integer(c_int), intent(out), optional :: rows(MBDK_BODY_KINDS)
    character(kind=c_char), intent(out), optional :: name(*)
    character(len=MBDK_ELEMENT_NAME_LEN) :: nm
    integer :: c, k, b, r(MBDK_BODY_KINDS), st
    mbdk_c_element_kind = MBDK_ERR_INVALID_INPUT
    if (.not. (present(cls) .and. present(code) .and. present(on) .and. present(rows) .and. &
               present(states) .and. present(name)) .or. namelen < 1) return
    call mbdk_element_kind(int(i), c, k, nm, b, r, st)
    cls = int(c, c_int)
    code = int(k, c_int)
    on = int(b, c_int)
    rows = int(r, c_int)
    states = int(st, c_int)
    if (c == 0) return
    call to_c(nm, name, int(namelen))
    mbdk_c_element_kind = MBDK_SUCCESS
  end function mbdk_c_element_kind

  !> Entry i (1-based) of the body kinds (mbdk_elements): code, name, coordinates, velocities,
  !> available (0: declared, not yet simulated by any model).
  integer(c_int) function mbdk_c_body_kind(i, code, name, namelen, coords, velocities, &
                                           available) bind(C, name='mbdk_body_kind')
    integer(c_int), value :: i, namelen
    integer(c_int), intent(out), optional :: code, coords, velocities, available
    character(kind=c_char), intent(out), optional :: name(*)
    character(len=MBDK_ELEMENT_NAME_LEN) :: nm
    integer :: k, nq, nv
    logical :: avail
    mbdk_c_body_kind = MBDK_ERR_INVALID_INPUT
    if (.not. (present(code) .and. present(coords) .and. present(velocities) .and. &
               present(available) .and. present(name)) .or. namelen < 1) return
    call mbdk_body_kind(int(i), k, nm, nq, nv, avail)
    code = int(k, c_int)
    coords = int(nq, c_int)
    velocities = int(nv, c_int)
    available = merge(1_c_int, 0_c_int, avail)
    if (k == 0) return
    call to_c(nm, name, int(namelen))
    mbdk_c_body_kind = MBDK_SUCCESS
  end function mbdk_c_body_kind

  !> s (trimmed) into buf as a NUL-terminated string of at most buflen bytes
  subroutine to_c(s, buf, buflen)
    character(len=*), intent(in) :: s
    character(kind=c_char), intent(out) :: buf(*)
    integer, intent(in) :: buflen
    integer :: j, m
    m = min(len_trim(s), buflen - 1)
    do j = 1, m
      buf(j) = s(j:j)
    end do
    buf(m + 1) = c_null_char
  end subroutine to_c

  !> A C string (its first 256 characters), blank-padded: a fixed length needs no allocation
  function from_c(s) result(r)
    character(kind=c_char), intent(in) :: s(*)
    character(len=256) :: r
    integer :: i
    r = ''
    i = 0
    do while (s(i + 1) /= c_null_char .and. i < 256)
      i = i + 1
      r(i:i) = s(i)
    end do
  end function from_c

end module mbdk_capi
