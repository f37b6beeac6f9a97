!> The layout of the structs that cross the kernel's boundary (options and statistics): for each,
!> its C name, its size and, field by field, the name, byte offset and type, as the Fortran
!> compiler lays out the bind(C) type. The C test kernel/tests/c_struct_layout.c compares this
!> table with offsetof() on mbdk.h; Python builds its numpy view of each struct from it
!> (python/mbdk/options.py) and tests/test_structs.py checks its dataclasses against it. So the
!> three mirrors cannot drift apart unnoticed, and nothing crosses a boundary by array position.
module mbdk_structs
  use, intrinsic :: iso_c_binding, only: c_loc, c_intptr_t, c_sizeof, c_double
  use mbdk_stats, only: mbdk_stats_t
  use mbdk_options, only: mbdk_options_t
  use mbdk_trapezoidal_index3, only: mbdk_index3_options_t
  use mbdk_model, only: mbdk_model_options_t
  use mbdk_spatial_model, only: mbdk_spatial_options_t
  use mbdk_watch, only: mbdk_watch_report_t
  implicit none
  private
  public :: mbdk_struct_info, mbdk_struct_field, mbdk_struct_defaults

  integer, parameter, public :: MBDK_STRUCT_STATS = 1, MBDK_STRUCT_OPTIONS = 2, &
    MBDK_STRUCT_INDEX3_OPTIONS = 3, MBDK_STRUCT_MODEL_OPTIONS = 4, &
    MBDK_STRUCT_SPATIAL_OPTIONS = 5, MBDK_STRUCT_WATCH_REPORT = 6, MBDK_STRUCT_COUNT = 6
  integer, parameter, public :: MBDK_STRUCT_NAME_LEN = 32
  !> field types: C int, int64_t, double, a pointer
  integer, parameter, public :: MBDK_FIELD_INT = 1, MBDK_FIELD_INT64 = 2, MBDK_FIELD_DOUBLE = 3, &
    MBDK_FIELD_POINTER = 4
  integer, parameter :: MAX_FIELDS = 24

  type :: field_t
    character(len=MBDK_STRUCT_NAME_LEN) :: name = ''
    integer :: offset = 0, ftype = 0
  end type field_t

contains

  !> C name, size in bytes and number of fields of struct id (nfields = 0: no such struct).
  subroutine mbdk_struct_info(id, cname, nbytes, nfields)
    integer, intent(in) :: id
    character(len=*), intent(out) :: cname
    integer, intent(out) :: nbytes, nfields
    type(field_t) :: f(MAX_FIELDS)
    call layout(id, cname, nbytes, f, nfields)
  end subroutine mbdk_struct_info

  !> Field i (1-based) of struct id: name, byte offset, type (MBDK_FIELD_*); ftype = 0 past
  !> the end.
  subroutine mbdk_struct_field(id, i, name, offset, ftype)
    integer, intent(in) :: id, i
    character(len=*), intent(out) :: name
    integer, intent(out) :: offset, ftype
    type(field_t) :: f(MAX_FIELDS)
    character(len=MBDK_STRUCT_NAME_LEN) :: cname
    integer :: nbytes, nf
    call layout(id, cname, nbytes, f, nf)
    name = ''
    offset = 0
    ftype = 0
    if (i < 1 .or. i > nf) return
    name = f(i)%name
    offset = f(i)%offset
    ftype = f(i)%ftype
  end subroutine mbdk_struct_field

  !> The default-initialised struct id as raw bytes, in 8-byte words (every struct's size is a
  !> multiple of 8: its last field or padding ends on a double's boundary).
  subroutine mbdk_struct_defaults(id, buf)
    integer, intent(in) :: id
    real(c_double), intent(out) :: buf(:)
    type(mbdk_stats_t) :: st
    type(mbdk_options_t) :: op
    type(mbdk_index3_options_t) :: i3
    type(mbdk_model_options_t) :: mo
    type(mbdk_spatial_options_t) :: so
    type(mbdk_watch_report_t) :: wr
    buf = 0.0_c_double
    select case (id)
    case (MBDK_STRUCT_STATS)
      buf = transfer(st, buf, size(buf))
    case (MBDK_STRUCT_OPTIONS)
      buf = transfer(op, buf, size(buf))
    case (MBDK_STRUCT_INDEX3_OPTIONS)
      buf = transfer(i3, buf, size(buf))
    case (MBDK_STRUCT_MODEL_OPTIONS)
      buf = transfer(mo, buf, size(buf))
    case (MBDK_STRUCT_SPATIAL_OPTIONS)
      buf = transfer(so, buf, size(buf))
    case (MBDK_STRUCT_WATCH_REPORT)
      buf = transfer(wr, buf, size(buf))
    end select
  end subroutine mbdk_struct_defaults

  subroutine layout(id, cname, nbytes, f, nf)
    integer, intent(in) :: id
    character(len=*), intent(out) :: cname
    integer, intent(out) :: nbytes, nf
    type(field_t), intent(out) :: f(MAX_FIELDS)
    type(mbdk_stats_t), target :: st
    type(mbdk_options_t), target :: op
    type(mbdk_index3_options_t), target :: i3
    integer(c_intptr_t) :: base
    nf = 0
    nbytes = 0
    cname = ''
    select case (id)
    case (MBDK_STRUCT_STATS)
      cname = 'mbdk_stats'
      nbytes = int(c_sizeof(st))
      base = transfer(c_loc(st), base)
      call add('steps', transfer(c_loc(st%steps), base), MBDK_FIELD_INT64)
      call add('nfev', transfer(c_loc(st%nfev), base), MBDK_FIELD_INT64)
      call add('njev', transfer(c_loc(st%njev), base), MBDK_FIELD_INT64)
      call add('nlu', transfer(c_loc(st%nlu), base), MBDK_FIELD_INT64)
      call add('newton_iterations', transfer(c_loc(st%newton_iterations), base), MBDK_FIELD_INT64)
      call add('startup_steps', transfer(c_loc(st%startup_steps), base), MBDK_FIELD_INT64)
      call add('rejected_steps', transfer(c_loc(st%rejected_steps), base), MBDK_FIELD_INT64)
      call add('newton_failures', transfer(c_loc(st%newton_failures), base), MBDK_FIELD_INT64)
      call add('order1_steps', transfer(c_loc(st%order1_steps), base), MBDK_FIELD_INT64)
      call add('order2_steps', transfer(c_loc(st%order2_steps), base), MBDK_FIELD_INT64)
      call add('order3_steps', transfer(c_loc(st%order3_steps), base), MBDK_FIELD_INT64)
      call add('order4_steps', transfer(c_loc(st%order4_steps), base), MBDK_FIELD_INT64)
      call add('order5_steps', transfer(c_loc(st%order5_steps), base), MBDK_FIELD_INT64)
      call add('nlu_sparse', transfer(c_loc(st%nlu_sparse), base), MBDK_FIELD_INT64)
      call add('cpu_time', transfer(c_loc(st%cpu_time), base), MBDK_FIELD_DOUBLE)
      call add('wall_time', transfer(c_loc(st%wall_time), base), MBDK_FIELD_DOUBLE)
      call add('t_reached', transfer(c_loc(st%t_reached), base), MBDK_FIELD_DOUBLE)
      call add('alloc_bytes', transfer(c_loc(st%alloc_bytes), base), MBDK_FIELD_DOUBLE)
    case (MBDK_STRUCT_OPTIONS)
      cname = 'mbdk_options'
      nbytes = int(c_sizeof(op))
      base = transfer(c_loc(op), base)
      call add('h', transfer(c_loc(op%h), base), MBDK_FIELD_DOUBLE)
      call add('newton_rtol', transfer(c_loc(op%newton_rtol), base), MBDK_FIELD_DOUBLE)
      call add('newton_atol', transfer(c_loc(op%newton_atol), base), MBDK_FIELD_DOUBLE)
      call add('rtol', transfer(c_loc(op%rtol), base), MBDK_FIELD_DOUBLE)
      call add('atol', transfer(c_loc(op%atol), base), MBDK_FIELD_DOUBLE)
      call add('dt_out', transfer(c_loc(op%dt_out), base), MBDK_FIELD_DOUBLE)
      call add('h_min', transfer(c_loc(op%h_min), base), MBDK_FIELD_DOUBLE)
      call add('h_max', transfer(c_loc(op%h_max), base), MBDK_FIELD_DOUBLE)
      call add('interrupt', transfer(c_loc(op%interrupt), base), MBDK_FIELD_POINTER)
      call add('max_steps', transfer(c_loc(op%max_steps), base), MBDK_FIELD_INT64)
      call add('method', transfer(c_loc(op%method), base), MBDK_FIELD_INT)
      call add('every', transfer(c_loc(op%every), base), MBDK_FIELD_INT)
      call add('newton_max_iter', transfer(c_loc(op%newton_max_iter), base), MBDK_FIELD_INT)
      call add('fd_jacobian', transfer(c_loc(op%fd_jacobian), base), MBDK_FIELD_INT)
      call add('nq', transfer(c_loc(op%nq), base), MBDK_FIELD_INT)
      call add('startup', transfer(c_loc(op%startup), base), MBDK_FIELD_INT)
      call add('max_order', transfer(c_loc(op%max_order), base), MBDK_FIELD_INT)
      call add('progress', transfer(c_loc(op%progress), base), MBDK_FIELD_POINTER)
    case (MBDK_STRUCT_INDEX3_OPTIONS)
      cname = 'mbdk_index3_options'
      nbytes = int(c_sizeof(i3))
      base = transfer(c_loc(i3), base)
      call add('h', transfer(c_loc(i3%h), base), MBDK_FIELD_DOUBLE)
      call add('newton_rtol', transfer(c_loc(i3%newton_rtol), base), MBDK_FIELD_DOUBLE)
      call add('newton_atol', transfer(c_loc(i3%newton_atol), base), MBDK_FIELD_DOUBLE)
      call add('alpha', transfer(c_loc(i3%alpha), base), MBDK_FIELD_DOUBLE)
      call add('err_rtol', transfer(c_loc(i3%err_rtol), base), MBDK_FIELD_DOUBLE)
      call add('err_atol', transfer(c_loc(i3%err_atol), base), MBDK_FIELD_DOUBLE)
      call add('dt_out', transfer(c_loc(i3%dt_out), base), MBDK_FIELD_DOUBLE)
      call add('h_min', transfer(c_loc(i3%h_min), base), MBDK_FIELD_DOUBLE)
      call add('h_max', transfer(c_loc(i3%h_max), base), MBDK_FIELD_DOUBLE)
      call add('interrupt', transfer(c_loc(i3%interrupt), base), MBDK_FIELD_POINTER)
      call add('formulation', transfer(c_loc(i3%formulation), base), MBDK_FIELD_INT)
      call add('every', transfer(c_loc(i3%every), base), MBDK_FIELD_INT)
      call add('newton_max_iter', transfer(c_loc(i3%newton_max_iter), base), MBDK_FIELD_INT)
      call add('adaptive', transfer(c_loc(i3%adaptive), base), MBDK_FIELD_INT)
      call add('progress', transfer(c_loc(i3%progress), base), MBDK_FIELD_POINTER)
      call add('beta', transfer(c_loc(i3%beta), base), MBDK_FIELD_DOUBLE)
      call add('gamma', transfer(c_loc(i3%gamma), base), MBDK_FIELD_DOUBLE)
      call add('alpha_m', transfer(c_loc(i3%alpha_m), base), MBDK_FIELD_DOUBLE)
      call add('alpha_f', transfer(c_loc(i3%alpha_f), base), MBDK_FIELD_DOUBLE)
    case default
      call scene_layout(id, cname, nbytes, f, nf)
    end select

  contains

    subroutine add(name, address, ftype)
      character(len=*), intent(in) :: name
      integer(c_intptr_t), intent(in) :: address
      integer, intent(in) :: ftype
      nf = nf + 1
      f(nf) = field_t(name, int(address - base), ftype)
    end subroutine add

  end subroutine layout

  !> layout's structs of a scene's options and the watch's report
  subroutine scene_layout(id, cname, nbytes, f, nf)
    integer, intent(in) :: id
    character(len=*), intent(inout) :: cname
    integer, intent(inout) :: nbytes, nf
    type(field_t), intent(inout) :: f(MAX_FIELDS)
    type(mbdk_model_options_t), target :: mo
    type(mbdk_spatial_options_t), target :: so
    type(mbdk_watch_report_t), target :: wr
    integer(c_intptr_t) :: base
    select case (id)
    case (MBDK_STRUCT_MODEL_OPTIONS)
      cname = 'mbdk_model_options'
      nbytes = int(c_sizeof(mo))
      base = transfer(c_loc(mo), base)
      call add('baumgarte_alpha', transfer(c_loc(mo%baumgarte_alpha), base), MBDK_FIELD_DOUBLE)
      call add('baumgarte_beta', transfer(c_loc(mo%baumgarte_beta), base), MBDK_FIELD_DOUBLE)
      call add('penalty_alpha', transfer(c_loc(mo%penalty_alpha), base), MBDK_FIELD_DOUBLE)
      call add('penalty_omega', transfer(c_loc(mo%penalty_omega), base), MBDK_FIELD_DOUBLE)
      call add('penalty_mu', transfer(c_loc(mo%penalty_mu), base), MBDK_FIELD_DOUBLE)
      call add('projection_tol', transfer(c_loc(mo%projection_tol), base), MBDK_FIELD_DOUBLE)
      call add('formulation', transfer(c_loc(mo%formulation), base), MBDK_FIELD_INT)
      call add('solver', transfer(c_loc(mo%solver), base), MBDK_FIELD_INT)
      call add('small_dense', transfer(c_loc(mo%small_dense), base), MBDK_FIELD_INT)
      call add('projection_max_iter', transfer(c_loc(mo%projection_max_iter), base), &
               MBDK_FIELD_INT)
      call add('watch_position', transfer(c_loc(mo%watch_position), base), MBDK_FIELD_DOUBLE)
      call add('watch_velocity', transfer(c_loc(mo%watch_velocity), base), MBDK_FIELD_DOUBLE)
      call add('watch_energy', transfer(c_loc(mo%watch_energy), base), MBDK_FIELD_DOUBLE)
      call add('watch_every', transfer(c_loc(mo%watch_every), base), MBDK_FIELD_INT)
      call add('locate_events', transfer(c_loc(mo%locate_events), base), MBDK_FIELD_INT)
      call add('watch_momentum', transfer(c_loc(mo%watch_momentum), base), MBDK_FIELD_DOUBLE)
    case (MBDK_STRUCT_SPATIAL_OPTIONS)
      cname = 'mbdk_spatial_options'
      nbytes = int(c_sizeof(so))
      base = transfer(c_loc(so), base)
      call add('baumgarte_alpha', transfer(c_loc(so%baumgarte_alpha), base), MBDK_FIELD_DOUBLE)
      call add('baumgarte_beta', transfer(c_loc(so%baumgarte_beta), base), MBDK_FIELD_DOUBLE)
      call add('penalty_alpha', transfer(c_loc(so%penalty_alpha), base), MBDK_FIELD_DOUBLE)
      call add('penalty_omega', transfer(c_loc(so%penalty_omega), base), MBDK_FIELD_DOUBLE)
      call add('penalty_mu', transfer(c_loc(so%penalty_mu), base), MBDK_FIELD_DOUBLE)
      call add('lock_guard', transfer(c_loc(so%lock_guard), base), MBDK_FIELD_DOUBLE)
      call add('norm_gain', transfer(c_loc(so%norm_gain), base), MBDK_FIELD_DOUBLE)
      call add('projection_tol', transfer(c_loc(so%projection_tol), base), MBDK_FIELD_DOUBLE)
      call add('watch_position', transfer(c_loc(so%watch_position), base), MBDK_FIELD_DOUBLE)
      call add('watch_velocity', transfer(c_loc(so%watch_velocity), base), MBDK_FIELD_DOUBLE)
      call add('watch_energy', transfer(c_loc(so%watch_energy), base), MBDK_FIELD_DOUBLE)
      call add('watch_momentum', transfer(c_loc(so%watch_momentum), base), MBDK_FIELD_DOUBLE)
      call add('watch_quaternion', transfer(c_loc(so%watch_quaternion), base), MBDK_FIELD_DOUBLE)
      call add('formulation', transfer(c_loc(so%formulation), base), MBDK_FIELD_INT)
      call add('rotation', transfer(c_loc(so%rotation), base), MBDK_FIELD_INT)
      call add('norm', transfer(c_loc(so%norm), base), MBDK_FIELD_INT)
      call add('watch_every', transfer(c_loc(so%watch_every), base), MBDK_FIELD_INT)
      call add('locate_events', transfer(c_loc(so%locate_events), base), MBDK_FIELD_INT)
      call add('coordinates', transfer(c_loc(so%coordinates), base), MBDK_FIELD_INT)
    case (MBDK_STRUCT_WATCH_REPORT)
      cname = 'mbdk_watch_report'
      nbytes = int(c_sizeof(wr))
      base = transfer(c_loc(wr), base)
      call add('value', transfer(c_loc(wr%value), base), MBDK_FIELD_DOUBLE)
      call add('tol', transfer(c_loc(wr%tol), base), MBDK_FIELD_DOUBLE)
      call add('t', transfer(c_loc(wr%t), base), MBDK_FIELD_DOUBLE)
      call add('t_good', transfer(c_loc(wr%t_good), base), MBDK_FIELD_DOUBLE)
      call add('absolute', transfer(c_loc(wr%absolute), base), MBDK_FIELD_DOUBLE)
      call add('scale', transfer(c_loc(wr%scale), base), MBDK_FIELD_DOUBLE)
      call add('quantity', transfer(c_loc(wr%quantity), base), MBDK_FIELD_INT)
      call add('row', transfer(c_loc(wr%row), base), MBDK_FIELD_INT)
    end select

  contains

    subroutine add(name, address, ftype)
      character(len=*), intent(in) :: name
      integer(c_intptr_t), intent(in) :: address
      integer, intent(in) :: ftype
      nf = nf + 1
      f(nf) = field_t(name, int(address - base), ftype)
    end subroutine add

  end subroutine scene_layout

end module mbdk_structs
