!> Statistics of one solve, counted inside the kernel. bind(C): the same struct is struct
!> mbdk_stats in mbdk.h and mbdk.Stats in Python (tests/test_structs.py and
!> kernel/tests/c_struct_layout.c check that the three agree field by field). The counters SciPy
!> users know keep SciPy's names (nfev, njev, nlu).
module mbdk_stats
  use, intrinsic :: iso_c_binding, only: c_int64_t, c_double
  implicit none
  private

  type, bind(C), public :: mbdk_stats_t
    integer(c_int64_t) :: steps = 0             !< accepted steps (including start-up steps)
    integer(c_int64_t) :: nfev = 0              !< evaluations of F(t, y), finite-difference columns included
    integer(c_int64_t) :: njev = 0              !< Jacobian evaluations (analytic or by finite differences)
    integer(c_int64_t) :: nlu = 0               !< factorisations of a Newton matrix (LU or LDL^T)
    integer(c_int64_t) :: newton_iterations = 0
    integer(c_int64_t) :: startup_steps = 0     !< steps of the start-up method of a multistep method
    integer(c_int64_t) :: rejected_steps = 0    !< step-size control: steps rejected by the error test
    integer(c_int64_t) :: newton_failures = 0   !< steps retried because Newton failed
    !> error-controlled multistep methods (bdf, cvode_*): accepted steps taken at order k
    integer(c_int64_t) :: order1_steps = 0, order2_steps = 0, order3_steps = 0, &
                          order4_steps = 0, order5_steps = 0
    !> of nlu, the factorisations of a DAE method's sparse Newton matrix (a large scene's DAE:
    !> bdf's own L D U, mbdk_mechanism_dae; ida's KLU, mbdk_ida); 0 for the other methods
    !> (the index-3 family's manifest names its matrix)
    integer(c_int64_t) :: nlu_sparse = 0
    real(c_double) :: cpu_time = 0.0_c_double   !< CPU seconds of the solving thread in the time loop
    real(c_double) :: wall_time = 0.0_c_double  !< wall-clock seconds of the time loop
    !> the time the solve reached: its last accepted step (a failed solve: where it stopped,
    !> the failure lies in the step after), t0 before the first
    real(c_double) :: t_reached = 0.0_c_double
    !> MBDK_ERR_NO_MEMORY: the bytes of the allocation that failed (0 where it was not known),
    !> else 0 (mbdk_memory)
    real(c_double) :: alloc_bytes = 0.0_c_double
  end type mbdk_stats_t

end module mbdk_stats
