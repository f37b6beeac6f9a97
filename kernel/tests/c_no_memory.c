/* c_no_memory.c - running out of memory is a status, not the end of the program (issue 36).
 *
 * The program limits its own address space (setrlimit RLIMIT_AS) to what it has mapped at the
 * start (the libraries, a threaded BLAS's buffers) and ROOM more, so that the kernel's large
 * allocations fail the same way on every machine and nothing outside this process feels them;
 * then
 * 1. mbdk_stepper_create_ode with n = 2^27 states (y0: 1 GiB, which fits): rk4's state, its
 *    copy and its stages, (2 + 4) n doubles = 6 GiB, cannot be had: MBDK_ERR_NO_MEMORY and no
 *    stepper.
 * 2. bdf through mbdk_solve_ode on n = 2^15 states: its dense Newton matrix and LU factors,
 *    2 n^2 doubles (17 GB), cannot be had: MBDK_ERR_NO_MEMORY, and stats.alloc_bytes holds at
 *    least those two matrices' bytes.
 * 3. A scene stepper of 2^24 free bodies (no joints, no forces; mass, inertia and y0: 1 GiB):
 *    its model's arrays (several of 3 or 6 doubles per body) cannot all be had:
 *    MBDK_ERR_NO_MEMORY (or MBDK_ERR_INVALID_INPUT, a size refused), and no stepper.
 * After each, the program goes on: a small stepper made at the end steps as usual.
 * Exit code 0 = pass.
 */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <sys/resource.h>
#include <unistd.h>
#include "mbdk.h"

#define ROOM (2UL << 30)   /* 2 GiB: the inputs below (1 GiB at most), not the kernel's arrays */

/* The address space mapped now (Linux: /proc/self/statm, its first field in pages). */
static unsigned long mapped(void)
{
    unsigned long pages = 0;
    FILE *f = fopen("/proc/self/statm", "r");
    if (f) {
        if (fscanf(f, "%lu", &pages) != 1) pages = 0;
        fclose(f);
    }
    return pages * (unsigned long)sysconf(_SC_PAGESIZE);
}

static int fails = 0;
static void check(int ok, const char *what)
{
    printf("%s: %s\n", ok ? "ok  " : "FAIL", what);
    if (!ok) fails++;
}

static int decay(int n, double t, const double *y, double *dydt, void *user_data)
{
    (void)t; (void)user_data;
    for (int i = 0; i < n; i++) dydt[i] = -y[i];
    return 0;
}

static void huge_ode_stepper(void)
{
    const int n = 1 << 27;
    double *y0 = calloc((size_t)n, sizeof *y0);
    mbdk_options opt;
    mbdk_stepper *s = NULL;
    int status;
    check(y0 != NULL, "y0 of 2^27 states fits the limit");
    if (!y0) return;
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("rk4");
    opt.h = 0.01;
    status = mbdk_stepper_create_ode(decay, NULL, NULL, n, 0.0, y0, &opt, &s);
    printf("      mbdk_stepper_create_ode(n = 2^27): %d\n", status);
    check(status == MBDK_ERR_NO_MEMORY && s == NULL,
          "an ode stepper of 2^27 states is MBDK_ERR_NO_MEMORY, no stepper");
    free(y0);
}

static void dense_bdf(void)
{
    const int n = 1 << 15;
    double *y0 = malloc((size_t)n * sizeof *y0), t_out[2], *y_out = malloc(2 * (size_t)n * 8);
    double matrices = 2.0 * 8.0 * (double)n * (double)n;
    mbdk_options opt;
    mbdk_stats st;
    int nw = -1, status;
    check(y0 && y_out, "bdf's inputs and outputs fit the limit");
    if (!(y0 && y_out)) return;
    for (int i = 0; i < n; i++) y0[i] = 1.0;
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("bdf");
    opt.rtol = 1e-6;
    opt.atol = 1e-8;
    status = mbdk_solve_ode(decay, NULL, NULL, n, 0.0, 1.0, y0, &opt, 2, t_out, y_out, &nw, &st);
    printf("      bdf on 2^15 states: %d, alloc_bytes %.4g (two dense matrices: %.4g)\n", status,
           st.alloc_bytes, matrices);
    check(status == MBDK_ERR_NO_MEMORY, "bdf's dense Newton matrix is MBDK_ERR_NO_MEMORY");
    check(st.alloc_bytes >= matrices && st.alloc_bytes < 1.01 * matrices,
          "stats.alloc_bytes is the size asked for: the Newton matrix and its LU factors");
    check(nw == 1, "the first sample (the initial state) is written");
    free(y0);
    free(y_out);
}

static void huge_scene_stepper(void)
{
    const int nb = 1 << 24;
    double *mass = malloc((size_t)nb * sizeof *mass);
    double *inertia = malloc((size_t)nb * sizeof *inertia);
    double *y0 = calloc(6 * (size_t)nb, sizeof *y0);
    mbdk_model_options mopt;
    mbdk_options opt;
    mbdk_stepper *s = NULL;
    int status;
    check(mass && inertia && y0, "the tables of 2^24 bodies fit the limit");
    if (!(mass && inertia && y0)) return;
    for (int b = 0; b < nb; b++) {
        mass[b] = 1.0;
        inertia[b] = 0.1;
        y0[3 * b] = (double)b;   /* the bodies in a row along x */
    }
    mbdk_model_default_options(&mopt);
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("rk4");
    opt.h = 1e-3;
    status = mbdk_stepper_create_scene(nb, mass, inertia, 0, NULL, NULL, 0, NULL, NULL, &mopt,
                                       &opt, 0.0, y0, &s);
    printf("      mbdk_stepper_create_scene(2^24 bodies): %d\n", status);
    check((status == MBDK_ERR_NO_MEMORY || status == MBDK_ERR_INVALID_INPUT) && s == NULL,
          "a scene stepper of 2^24 bodies is refused by status, no stepper");
    free(mass);
    free(inertia);
    free(y0);
}

static void the_program_goes_on(void)
{
    double y0[2] = {1.0, 2.0}, y[2], t;
    mbdk_options opt;
    mbdk_stepper *s = NULL;
    mbdk_default_options(&opt);
    opt.method = mbdk_method_id("rk4");
    opt.h = 0.01;
    check(mbdk_stepper_create_ode(decay, NULL, NULL, 2, 0.0, y0, &opt, &s) == MBDK_SUCCESS &&
          mbdk_stepper_advance(s, 1.0) == MBDK_SUCCESS &&
          mbdk_stepper_state(s, &t, y, 2) == MBDK_SUCCESS,
          "a small stepper made afterwards runs");
    /* rk4's global error at h = 0.01 on y' = -y over [0, 1] is below 1e-9 */
    check(t == 1.0 && y[0] > 0.3678794 && y[0] < 0.3678795, "and its state is exp(-1) y0");
    mbdk_stepper_destroy(s);
}

int main(void)
{
    unsigned long limit = mapped() + ROOM;
    struct rlimit lim = {limit, limit};
    printf("      address space limited to %.3g GiB\n", limit / 1073741824.0);
    if (setrlimit(RLIMIT_AS, &lim) != 0) {
        perror("setrlimit");
        return 1;
    }
    huge_ode_stepper();
    dense_bdf();
    huge_scene_stepper();
    the_program_goes_on();
    printf("%s\n", fails ? "FAILED" : "all passed");
    return fails != 0;
}
