!> Options of an ODE solve, by name with defaults: a fixed-step method reads h and every; an
!> error-controlled one (dopri54, bs32, bdf, cvode_*) reads rtol, atol, dt_out, h (its first step,
!> 0 = chosen by the method), h_min, h_max, max_steps and max_order. bind(C): the same struct is struct
!> mbdk_options in mbdk.h and mbdk.options.ODEOptions in Python (tests/test_structs.py and
!> kernel/tests/c_struct_layout.c check that the three agree field by field).
module mbdk_options
  use, intrinsic :: iso_c_binding, only: c_int, c_double, c_intptr_t, c_int64_t
  implicit none
  private

  !> Start-up of a k-step method: RK4 steps of the same h (the book, (4.80)), or BDF steps of
  !> rising order 1, 2, ..., k-1 (self-starting, stable on stiff problems where RK4 is not).
  integer, parameter, public :: MBDK_STARTUP_RK4 = 0
  integer, parameter, public :: MBDK_STARTUP_BDF = 1

  type, bind(C), public :: mbdk_options_t
    real(c_double) :: h = 0.0_c_double               !< step size
    real(c_double) :: newton_rtol = 1.0e-10_c_double !< Newton: stop when the weighted RMS of the update < 1
    real(c_double) :: newton_atol = 1.0e-12_c_double
    !> error control: the local error estimate e is kept at WRMS(e / (atol + rtol |y|)) <= 1
    !> (rtol >= 0, atol > 0)
    real(c_double) :: rtol = 1.0e-6_c_double
    real(c_double) :: atol = 1.0e-8_c_double
    real(c_double) :: dt_out = 0.0_c_double          !< samples every dt_out (dense output); 0: t0 and t_end
    real(c_double) :: h_min = 0.0_c_double           !< 0: none (a step must still move t by ~10 ulps)
    real(c_double) :: h_max = 0.0_c_double           !< 0: the interval
    !> address of a C int the caller may set non-zero from another thread (or a signal handler)
    !> to stop the solve at the next step with MBDK_ERR_INTERRUPTED; 0 (NULL): never interrupted.
    !> An address, not a type(c_ptr): gfortran 12 rejects c_null_ptr as a default initialiser in
    !> scopes that use this type without iso_c_binding.
    integer(c_intptr_t) :: interrupt = 0
    integer(c_int64_t) :: max_steps = 0              !< error control: the most steps; 0 = 10^8
    integer(c_int) :: method = 0                     !< method id (mbdk_methods)
    integer(c_int) :: every = 1                      !< keep every k-th step as a sample (the last always)
    integer(c_int) :: newton_max_iter = 10
    integer(c_int) :: fd_jacobian = 0                !< non-zero: finite differences even if F has a Jacobian
    integer(c_int) :: nq = 0                         !< > 0: y = [q; v] with n = 2 nq (C callbacks; euler_cromer)
    integer(c_int) :: startup = MBDK_STARTUP_RK4     !< how a k-step method gets its first k-1 values
    integer(c_int) :: max_order = 0                  !< bdf, cvode_*: the highest order; 0 = the method's
    !> address of a C double the drivers store the time reached in, once per step (for a
    !> progress display in another thread); 0 (NULL): none. Last, so that initialisers written
    !> for the fields before it still fill those.
    integer(c_intptr_t) :: progress = 0
  end type mbdk_options_t

end module mbdk_options
