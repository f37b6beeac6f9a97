!> The clocks of a solve (mbdk_clock.c): the calling thread's CPU time and a monotonic wall
!> clock, in seconds. A solve starts a timer before its loop and stops it into its statistics
!> (mbdk_stats_t%cpu_time, wall_time) on every way out.
module mbdk_clock
  use, intrinsic :: iso_c_binding, only: c_double
  use mbdk_stats, only: mbdk_stats_t
  implicit none
  private
  public :: mbdk_thread_cpu_seconds, mbdk_wall_seconds, mbdk_timer_start, mbdk_timer_stop

  type, public :: mbdk_timer_t
    real(c_double) :: cpu0 = 0.0_c_double, wall0 = 0.0_c_double
  end type mbdk_timer_t

  interface
    real(c_double) function mbdk_thread_cpu_seconds() bind(C, name='mbdk_thread_cpu_seconds')
      import :: c_double
    end function mbdk_thread_cpu_seconds
    real(c_double) function mbdk_wall_seconds() bind(C, name='mbdk_wall_seconds')
      import :: c_double
    end function mbdk_wall_seconds
  end interface

contains

  subroutine mbdk_timer_start(timer)
    type(mbdk_timer_t), intent(out) :: timer
    timer%cpu0 = mbdk_thread_cpu_seconds()
    timer%wall0 = mbdk_wall_seconds()
  end subroutine mbdk_timer_start

  !> st%cpu_time, st%wall_time = the time since mbdk_timer_start
  subroutine mbdk_timer_stop(timer, st)
    type(mbdk_timer_t), intent(in) :: timer
    type(mbdk_stats_t), intent(inout) :: st
    st%cpu_time = mbdk_thread_cpu_seconds() - timer%cpu0
    st%wall_time = mbdk_wall_seconds() - timer%wall0
  end subroutine mbdk_timer_stop

end module mbdk_clock
