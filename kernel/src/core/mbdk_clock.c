/* The clocks a solve reports: the CPU time of the calling thread (not of the process, so that
 * two solves in two threads each report their own) and a monotonic wall clock. Fortran's
 * cpu_time gives the process's CPU time, which counts every thread. Used through mbdk_clock.f90. */
#define _POSIX_C_SOURCE 199309L
#include <time.h>

double mbdk_thread_cpu_seconds(void)
{
    struct timespec ts;
    if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts) != 0) return 0.0;
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

double mbdk_wall_seconds(void)
{
    struct timespec ts;
    if (clock_gettime(CLOCK_MONOTONIC, &ts) != 0) return 0.0;
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
