"""CPU time of short solves: the kernel measures its loop with cpu_time (about 1 us resolution),
so a solve shorter than a few ms is repeated until the summed kernel CPU time reaches min_cpu,
and the mean per solve is reported. Every repetition returns the same numbers (the kernel's runs
are deterministic, error-controlled ones included)."""
from __future__ import annotations

from ..ode import solve_ode
from ..simulate import simulate


def solve_timed(problem, method, *, min_cpu: float = 0.02, max_reps: int = 20000, **kw):
    """(result, CPU seconds per solve)."""
    r = solve_ode(problem, method, **kw)
    total, reps = r.cpu_time, 1
    while total < min_cpu and reps < max_reps:
        total += solve_ode(problem, method, **kw).cpu_time
        reps += 1
    return r, total / reps


def simulate_timed(scene, method, *, min_cpu: float = 0.02, max_reps: int = 2000, **kw):
    """(result, CPU seconds per run) of a scene run, repeated as solve_timed does."""
    r = simulate(scene, method, **kw)
    total, reps = r.cpu_time, 1
    while total < min_cpu and reps < max_reps:
        total += simulate(scene, method, **kw).cpu_time
        reps += 1
    return r, total / reps
