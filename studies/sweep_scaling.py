"""Sweeps on Dask (mbdk.sweep): a work-precision grid run serially, on a local cluster of one
worker process and of two, the same table from each (checked), with the time each took; and,
from those measurements, what a 1 000-task sweep would cost on N workers.

1. The grid: the double pendulum and the four-bar (scenes), rk4 at five steps from 1e-2 to
   2e-5 s and dopri54 and bdf at four tolerances from 1e-4 to 1e-10, over 20 s (--quick: 2 s,
   fewer runs); each run's error against dopri54 at rtol 1e-12, its steps and the solving
   thread's CPU time (the table), and the sweep's wall time per engine with the speed-up of
   two workers over one (both including their cluster's start).
2. On paper: T(N) = S + F + ceil(1000 / N) (tau + p) + 8 o, with S the measured start of a
   local cluster, o Dask's scheduling per task measured on a warm worker (each worker gets 8
   batches of runs), tau the mean CPU time of a run of this grid, p the serial sweep's time
   outside the kernel per run (set-up, results and the reference runs), and F the rest of the
   one-worker sweep's time (the worker's first import, closing); the speed-up T(1) / T(N) and
   the efficiency. A real cluster adds its network's latency to o; the table is a model, not
   a measurement.
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import main, progress  # noqa: E402

from mbdk.analysis.tables import write_table  # noqa: E402
from mbdk.sweep import same_rows, sweep  # noqa: E402

BATCHES = 8   # mbdk.sweep's batches per worker thread (its default)


def grid(quick: bool) -> dict:
    return {"t_end": 2.0 if quick else 20.0, "scenes": ["double_pendulum", "four_bar"],
            "methods": ["rk4", "dopri54", "bdf"],
            "steps": [1e-2, 1e-3] if quick else [1e-2, 1e-3, 1e-4, 5e-5, 2e-5],
            "tolerances": [1e-4, 1e-8] if quick else [1e-4, 1e-6, 1e-8, 1e-10]}


def _noop(x):
    return x


def cluster_costs(n: int = 200) -> tuple[float, float]:
    """(seconds to start a local cluster of one worker and connect to it, seconds of Dask's
    scheduling per task on it once warm: n tasks that do nothing)."""
    from dask.distributed import Client, LocalCluster
    t = time.perf_counter()
    cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                           dashboard_address=None)
    client = Client(cluster)
    start = time.perf_counter() - t
    client.submit(_noop, 0).result()
    t = time.perf_counter()
    client.gather(client.map(_noop, range(n), pure=False))
    per_task = (time.perf_counter() - t) / n
    client.close()
    cluster.close()
    return start, per_task


def run(out: Path, quick: bool = False) -> dict:
    g = grid(quick)
    runs = {}
    for label, kw in (("serial", dict(workers=0)), ("1 worker", dict(workers=1)),
                      ("2 workers", dict(workers=2))):
        progress(f"sweep: {label}")
        runs[label] = sweep(g, **kw)
    base = runs["serial"]
    for label, r in runs.items():
        if not same_rows(r, base):
            raise RuntimeError(f"sweep on {label} differs from the serial run")
    rows = [{**x, "cpu_ms": 1e3 * x["cpu_time"]} for x in base.rows]
    tables = [write_table(rows, ["case", "method", "control", "status", "error", "steps",
                                 "cpu_ms"], out, "sweep_grid",
                          "The grid's runs (the same bits serially and on 1 and 2 workers)",
                          "error: max |q(t_end) - q_ref(t_end)| against dopri54 at rtol 1e-12")]
    progress("sweep: cluster start and scheduling per task")
    start, o = cluster_costs()
    tasks = len(base.rows)
    tau = sum(x["cpu_time"] for x in base.rows) / tasks
    p = max((base.wall_time - tasks * tau) / tasks, 0.0)
    t1, t2 = runs["1 worker"].wall_time, runs["2 workers"].wall_time
    engines = [{"engine": label, "wall_s": r.wall_time, "speed_up_over_1_worker": t1 / r.wall_time}
               for label, r in runs.items()]
    tables.append(write_table(
        engines, ["engine", "wall_s", "speed_up_over_1_worker"], out, "sweep_engines",
        f"The sweep's wall time per engine ({tasks} runs; CPU time of the runs "
        f"{tasks * tau:.3g} s)",
        f"the local clusters' times include their start, measured alone at {start:.2f} s; the "
        "machine has 2 cores"))
    per = BATCHES
    fixed = max(t1 - start - tasks * (tau + p) - per * o, 0.0)
    paper = []
    t_one = start + fixed + 1000 * (tau + p) + per * o
    for n in (1, 2, 8, 32, 128, 512):
        tn = start + fixed + math.ceil(1000 / n) * (tau + p) + per * o
        paper.append({"workers": n, "predicted_s": tn, "speed_up": t_one / tn,
                      "efficiency": t_one / tn / n})
    tables.append(write_table(
        paper, ["workers", "predicted_s", "speed_up", "efficiency"], out, "sweep_on_paper",
        "On paper: a 1 000-task sweep of this grid's mean task on N workers",
        f"T(N) = S + F + ceil(1000/N) (tau + p) + {per} o: S = {start:.2f} s (a local cluster's "
        f"start), F = {fixed:.2f} s (the rest of the one-worker sweep's fixed cost: the "
        f"worker's first import, closing), tau = {1e3 * tau:.3g} ms (mean "
        f"CPU time of a run), p = {1e3 * p:.3g} ms (the serial sweep's time outside the "
        f"kernel per run: set-up, results, the reference runs), o = {1e3 * o:.3g} ms (Dask's "
        f"scheduling per task, measured on a warm worker; each worker gets {per} batches of "
        "runs). A networked cluster adds its latency to o; the table is a model, not a "
        "measurement"))
    return {"title": "Sweeps on Dask: the same bits on every engine, and what workers buy",
            "tables": tables, "figures": [],
            "verdict": f"2 workers: {t1 / t2:.2f}x the speed of 1 on {tasks} runs"}


if __name__ == "__main__":
    sys.exit(main(run, "sweep_scaling"))
