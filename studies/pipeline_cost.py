"""What a scene run costs beyond its time loop, and what each effect adds: the promise that the
kernel visits only what a scene declares, measured.

1. effects_cost: ns per rk4 step (reduced formulation, h = 1e-4) of the double pendulum, alone
   and with one more force element of each kind (point force, torque, spring, damper,
   spring-damper, coordinate spring-damper), each timed in the same run, with the element's
   visits per step and the step's cost against the bare scene; and each unwatched
   (watch=False): what the watch of constraints and energy adds (every 16 steps, and the power
   of dampers and loads at every step, where the scene has them).
2. outputs_cost: the same scene sampled at every step (every = 1), with no outputs, with each
   output alone and with all of them (the default): seconds of the whole simulate() call
   against the kernel's time loop, per sample.
3. simulate_overhead: simulate(..., outputs=()) over runs from 100 to 1e5 steps: the whole
   call's wall time minus the kernel loop's, which should stay a constant (table building,
   initial assembly, checks), not grow with the run.
4. threads: two solves (double pendulum, four-bar) one after the other, and in two Python
   threads at once (the solves release the GIL): wall time of both, and the results compared
   bit for bit. On a machine with two or more cores the threaded pair should take about as long
   as the longer solve.
5. call_overhead: a 1 000-step rk4 solve of the double pendulum (3.64) by solve_ode, by a
   prepared mbdk.ODESolver and by the bare f2py entry: the call's wall time minus the kernel
   loop's CPU time, over 2 100 calls each in 7 rounds of 300 of each kind in turn (10th
   percentile, median, 90th, and each round's median: a busy machine's other load lands in the
   difference too, so the quietest round's median is the call's own cost), and Python's own
   share with the kernel entry replaced by one that returns its outputs (best of 7 x 2 100).
"""
from __future__ import annotations

import sys
import threading
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import main, progress  # noqa: E402

import mbdk  # noqa: E402
from mbdk.analysis.tables import write_table  # noqa: E402
from mbdk.scene_file import scene_from_dict  # noqa: E402
from mbdk.codes import OUTPUTS  # noqa: E402

try:                      # Python 3.11+
    import tomllib
except ImportError:       # pragma: no cover
    import tomli as tomllib

#: one force element of each kind, added to the double pendulum's bar2
EFFECTS = {
    "point_force": {"type": "point_force", "body": "bar2", "point": [1.0, 0.0],
                    "force": [1.0, 0.5]},
    "torque": {"type": "torque", "body": "bar2", "torque": 0.3},
    "spring": {"type": "spring", "body1": "bar2", "point1": [1.0, 0.0], "body2": "ground",
               "point2": [1.0, 0.0], "stiffness": 5.0},
    "damper": {"type": "damper", "body1": "bar2", "point1": [1.0, 0.0], "body2": "ground",
               "point2": [1.0, 0.0], "damping": 0.5},
    "spring_damper": {"type": "spring_damper", "body1": "bar2", "point1": [1.0, 0.0],
                      "body2": "ground", "point2": [1.0, 0.0], "stiffness": 5.0,
                      "damping": 0.5},
    "coordinate_spring_damper": {"type": "coordinate_spring_damper", "body": "bar2",
                                 "coordinate": "angle", "stiffness": 2.0, "damping": 0.1,
                                 "rest": -1.5},
}


def base_dict() -> dict:
    return tomllib.loads((Path(mbdk.__file__).parent / "scenes" / "double_pendulum.toml")
                         .read_text())


def with_effect(kind: str | None):
    d = base_dict()
    if kind:
        d["force"].append({"name": kind, **EFFECTS[kind]})
    return scene_from_dict(d, f"double_pendulum + {kind or 'nothing'}")


def best_ns(sc, t_end, reps, **kw):
    rs = [mbdk.simulate(sc, "rk4", h=1e-4, t_end=t_end, every=10**7, outputs=(), **kw)
          for _ in range(reps)]
    r = min(rs, key=lambda r: r.cpu_time)
    return 1e9 * r.cpu_time / r.stats.steps, r


def effects_cost(out: Path, quick: bool):
    t_end, reps = (2.0, 3) if quick else (20.0, 5)
    rows = []
    base_ns = None
    for kind in [None, *EFFECTS]:
        progress(f"effect {kind or 'none'}")
        ns, r = best_ns(with_effect(kind), t_end, reps)
        ns_free, _ = best_ns(with_effect(kind), t_end, reps, watch=False)
        base_ns = ns if kind is None else base_ns
        key = kind
        rows.append({"scene": "double pendulum" + (f" + {kind}" if kind else ""),
                     "ns_per_step": ns, "ratio_to_bare": ns / base_ns,
                     "ns_per_step_unwatched": ns_free, "watch_share": 1.0 - ns_free / ns,
                     "element_visits_per_step": (r.visits[key] / r.stats.steps) if kind else 0,
                     "revolute_visits_per_step": r.visits["revolute"] / r.stats.steps,
                     "steps": r.stats.steps, "cpu_s": r.cpu_time})
    return write_table(rows, ["scene", "ns_per_step", "ratio_to_bare", "ns_per_step_unwatched",
                              "watch_share", "element_visits_per_step",
                              "revolute_visits_per_step", "steps", "cpu_s"], out, "effects_cost",
                       "Cost of each effect: rk4 (reduced, h = 1e-4) on the double pendulum with "
                       "one more force element",
                       "The kernel visits an element only where the scene declares it: each "
                       "element kind adds its own visits (4 per rk4 step) and nothing else; the "
                       "bare scene visits none of them. Best of several runs; CPU time of the "
                       "solving thread. watch_share: the part of the step the watch of "
                       "constraints and energy takes (kernel/src/model/mbdk_watch.f90); an "
                       "element with power (dampers, loads) has it evaluated at every step, and "
                       "the watch's passes are not counted as visits.")


def outputs_cost(out: Path, quick: bool):
    sc = mbdk.scene("double_pendulum")
    t_end, reps = (0.5, 3) if quick else (5.0, 5)
    sets = [("none", ()), *[(o, (o,)) for o in OUTPUTS], ("all (default)", tuple(OUTPUTS))]
    rows = []
    for label, outputs in sets:
        progress(f"outputs {label}")
        best = None
        for _ in range(reps):
            w0 = time.perf_counter()
            r = mbdk.simulate(sc, "rk4", h=1e-4, t_end=t_end, outputs=outputs)
            wall = time.perf_counter() - w0
            if best is None or wall < best:
                best, loop = wall, r.stats.wall_time
        ns = len(r.t)
        rows.append({"outputs": label, "samples": ns, "simulate_s": best, "kernel_loop_s": loop,
                     "beyond_loop_us_per_sample": 1e6 * (best - loop) / ns,
                     "loop_ns_per_step": 1e9 * r.cpu_time / r.stats.steps})
    return write_table(rows, ["outputs", "samples", "simulate_s", "kernel_loop_s",
                              "beyond_loop_us_per_sample", "loop_ns_per_step"], out,
                       "outputs_cost", "Outputs on request: rk4 on the double pendulum sampled "
                       "at every step (every = 1), h = 1e-4",
                       "simulate_s: wall time of the whole call (best of several); kernel_loop_s:"
                       " the kernel's time loop alone. The difference is the output pass "
                       "(in the kernel, at the samples) and the copying of the arrays to "
                       "Python; with outputs=() only the copy of t, q, v remains.")


def simulate_overhead(out: Path, quick: bool):
    sc = mbdk.scene("double_pendulum")
    rows = []
    for steps in ([100, 1000, 10000] if quick else [100, 1000, 10000, 100000]):
        progress(f"overhead, {steps} steps")
        best = None
        for _ in range(5):
            w0 = time.perf_counter()
            r = mbdk.simulate(sc, "rk4", h=1e-4, t_end=1e-4 * steps, every=steps, outputs=())
            wall = time.perf_counter() - w0
            if best is None or wall - r.stats.wall_time < best[0]:
                best = (wall - r.stats.wall_time, wall, r.stats.wall_time)
        rows.append({"steps": steps, "simulate_s": best[1], "kernel_loop_s": best[2],
                     "beyond_loop_ms": 1e3 * best[0]})
    return write_table(rows, ["steps", "simulate_s", "kernel_loop_s", "beyond_loop_ms"], out,
                       "simulate_overhead", "simulate(..., outputs=()) against the kernel's "
                       "time loop (rk4, double pendulum, h = 1e-4)",
                       "beyond_loop_ms: what simulate spends outside the compiled loop (tables, "
                       "initial assembly, checks, a worker thread for long runs): a constant, "
                       "whatever the length of the run.")


def threads(out: Path, quick: bool):
    t_end = 2.0 if quick else 10.0
    scenes = [mbdk.scene("double_pendulum"), mbdk.scene("four_bar")]

    def run(sc):
        return mbdk.simulate(sc, "rk4", h=1e-5, t_end=t_end, every=10**7, outputs=())
    progress("two solves, serial")
    w0 = time.perf_counter()
    serial = [run(sc) for sc in scenes]
    t_serial = time.perf_counter() - w0
    progress("two solves, two threads")
    par = [None, None]

    def target(i):
        par[i] = run(scenes[i])
    ths = [threading.Thread(target=target, args=(i,)) for i in range(2)]
    w0 = time.perf_counter()
    for th in ths:
        th.start()
    for th in ths:
        th.join()
    t_par = time.perf_counter() - w0
    same = all(np.array_equal(a.q, b.q) and np.array_equal(a.v, b.v)
               for a, b in zip(serial, par))
    rows = [{"run": "one after the other", "wall_s": t_serial,
             "cpu_s_of_solves": sum(r.cpu_time for r in serial), "speedup": 1.0,
             "bitwise_equal": True},
            {"run": "two Python threads", "wall_s": t_par,
             "cpu_s_of_solves": sum(r.cpu_time for r in par), "speedup": t_serial / t_par,
             "bitwise_equal": same}]
    return write_table(rows, ["run", "wall_s", "cpu_s_of_solves", "speedup", "bitwise_equal"],
                       out, "threads", f"Two rk4 solves (double pendulum, four-bar; h = 1e-5, "
                       f"{t_end:g} s each) serial and in two threads",
                       "The compiled solves release the GIL. cpu_s_of_solves: the solving "
                       "threads' own CPU time.")


def call_overhead(out: Path, quick: bool):
    """Section 5 of the module docstring."""
    import timeit

    from mbdk import _kernel, ode
    from mbdk.options import empty, unpack
    progress("call overhead")
    solver = mbdk.ODESolver("double_pendulum", "rk4", h=0.01, t_end=10.0, every=1000)
    args = (solver._id, solver.y0, 0.0, 10.0, solver._pvec, solver._opt)

    def bare():
        stats = empty("mbdk_stats")
        _kernel.solve_problem(*args, np.zeros(4, np.int32), solver._atol, np.zeros(0),
                              solver._nsamp, stats)
        return unpack("mbdk_stats", stats)["cpu_time"]

    calls = {"solve_ode": lambda: mbdk.solve_ode("double_pendulum", "rk4", h=0.01, t_end=10.0,
                                                 every=1000).stats.cpu_time,
             "ODESolver.solve": lambda: solver.solve().stats.cpu_time,
             "bare f2py entry": bare}
    rounds, per = (3, 100) if quick else (7, 300)
    n = rounds * per
    gaps = {k: [] for k in calls}
    round_medians = {k: [] for k in calls}
    for _ in range(rounds):
        for k, f in calls.items():
            g = []
            for _ in range(per):
                w0 = time.perf_counter()
                cpu = f()
                g.append(time.perf_counter() - w0 - cpu)
            gaps[k] += g
            round_medians[k].append(float(np.median(g)))
    # Python's share alone: the kernel entry answers at once with a real solve's outputs
    canned = _kernel.solve_problem(*args, np.zeros(4, np.int32), solver._atol, np.zeros(0),
                                   solver._nsamp, empty("mbdk_stats"))

    class Canned:
        def __getattr__(self, name):
            return getattr(_kernel, name)

        @staticmethod
        def solve_problem(*a):
            return canned
    share = {}
    ode._kernel = Canned()
    try:
        for k in ("solve_ode", "ODESolver.solve"):
            share[k] = min(timeit.repeat(calls[k], number=n, repeat=7)) / n
    finally:
        ode._kernel = _kernel
    rows = []
    for k, g in gaps.items():
        p10, p50, p90 = np.percentile(np.array(g) * 1e6, [10, 50, 90])
        rows.append({"call": k, "p10_us": p10, "median_us": p50, "p90_us": p90,
                     "quietest_round_median_us": 1e6 * min(round_medians[k]),
                     "round_medians_us": " ".join(f"{1e6 * m:.1f}" for m in round_medians[k]),
                     "python_share_us": 1e6 * share[k] if k in share else None})
    return write_table(rows, ["call", "p10_us", "median_us", "p90_us",
                              "quietest_round_median_us", "round_medians_us",
                              "python_share_us"], out,
                       "call_overhead", "The call's cost beyond the kernel loop: a 1 000-step rk4 "
                       "solve of the double pendulum (3.64), h = 0.01, one sample at the end",
                       "p10/median/p90: wall time of the call minus the kernel loop's CPU time "
                       f"over {n} calls each, in {rounds} rounds of {per} calls of each kind in "
                       "turn; the medians of the rounds beside them (on a shared machine they "
                       "differ by the other load: the quietest round's is the call's own cost). "
                       "The difference is outside the kernel's timer (its own wall and CPU "
                       "time agree within 1 us), and its median grows with the loop's length "
                       "(2.6 us after 1 step, 9-12 us after 1 000, measured on the bare entry): "
                       "most likely Python's code and data coming back into caches that the "
                       "0.3 ms loop left to other work. "
                       "python_share_us: the same call with the kernel entry answering at once "
                       "(best of 7). ODESolver checks its arguments and packs its options once, "
                       "at construction.")


def run(out: Path, quick: bool = False) -> dict:
    out = Path(out)
    tables = [effects_cost(out, quick), outputs_cost(out, quick), simulate_overhead(out, quick),
              threads(out, quick), call_overhead(out, quick)]
    return {"title": "What a run costs: effects, outputs, the call, threads", "tables": tables,
            "figures": []}


if __name__ == "__main__":
    raise SystemExit(main(run, "pipeline_cost"))
