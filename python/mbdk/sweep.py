"""Sweeps: a grid of runs (scenes or compiled problems x methods x formulations x steps or
tolerances) as independent tasks on Dask, gathered into one table with each run's error
against its reference, CPU time and counters.

>>> import mbdk.sweep
>>> grid = {"t_end": 1.0, "problems": ["pendulum"], "methods": ["rk4", "heun"],
...         "steps": [1e-2, 5e-3]}
>>> table = mbdk.sweep.sweep(grid, workers=0)        # serially, in this process
>>> [(r["method"], r["control"], r["status"]) for r in table.rows]    # doctest: +NORMALIZE_WHITESPACE
[('rk4', 0.01, 'SUCCESS'), ('rk4', 0.005, 'SUCCESS'), ('heun', 0.01, 'SUCCESS'),
 ('heun', 0.005, 'SUCCESS')]

On Dask (``workers`` local processes, or an existing cluster's scheduler)::

    table = mbdk.sweep.sweep(grid)                   # a local cluster of 2 processes
    table = mbdk.sweep.sweep(grid, scheduler="tcp://10.0.0.5:8786")   # an existing one

A grid is a dict (the ``[sweep]`` table of a TOML file for ``mbdk sweep GRID.toml``), or a list
of them (an array of ``[[sweep]]`` tables), run as one set of tasks: a study whose cases differ
in interval or steps (studies/grids/work_precision.toml) is one sweep. Its fields:

t_end, t0
    the interval (t0 default 0)
scenes, problems
    built-in scene names or scene files, and/or compiled problems' names
params
    a table of the problems' parameters (default theirs)
label
    the name of the case in the table (default the scene's or problem's name)
methods, formulations
    the methods; the formulations of scenes (default ``["reduced"]``)
steps, step_counts, tolerances
    ``steps``: h for the fixed-step methods, or ``step_counts``: numbers of steps over the
    interval; ``tolerances``: rtol for the error-controlled ones (atol = rtol * atol_ratio,
    default 1e-2)
samples
    the error is the largest over this many equal intervals of [t0, t_end] (their ends; a
    fixed-step run must land on them when compared with a reference run); default: at t_end
    only
reference
    {method, h, step_count or rtol} for a scene's (and a problem without a closed form's)
    states, default {method = "dopri54", rtol = 1e-12}; problems with an exact solution use it
min_cpu, max_reps
    a run shorter than min_cpu seconds of CPU (default 0) is repeated, at most max_reps times
    (default 20), and its times are the mean per run (the kernel's clock ticks in
    microseconds; every repetition gives the same numbers)

Each task is one run; its row has the columns of COLUMNS, in this order in the CSV:

case, method, formulation, control
    the case's label, the method, the formulation and the run's h or rtol
status
    the method's status name (SUCCESS, NOTE_LAST_STEP_SHORTENED) for a run that gave a
    result; the class name of the exception that stopped it otherwise (ConstraintDriftError,
    SceneError for a scene file that is missing or does not build, or any other exception's
    class, ZeroDivisionError say); "reference <class name>" where the run gave a result but its
    case's reference run failed
error
    max |y - y_ref| over the coordinates (over the state for a problem) and the samples; NaN
    where there is no error to give (a failed run or reference)
steps, nfev, cpu_time, wall_time, rejected, njev, nlu, orders, reps
    the run's counters (0 and "" for a failed run): cpu_time is the solving thread's, per
    repetition; orders the steps taken at each order, "1:12 2:40", for the variable-order
    methods
wear
    a scene's worn volumes at the end of the run, "name volume" per wear element (m^3),
    separated by "; " (empty without wear elements, and for a failed run)
error_message
    empty where the run and its reference gave results; otherwise the message, on one line
    ("the reference run: ..." for a failed reference)

Every case gives its rows: a case that fails when loaded or run stops only its own runs, never
the sweep, serially and on Dask alike. Ctrl-C (KeyboardInterrupt, SolveInterrupted) stops the
sweep. A run is deterministic, so a task gives the same bits on any worker as in a serial loop
(tests/test_sweep.py). Bad grid fields (an unknown field, method, problem or built-in scene,
numbers out of range) raise InvalidInputError before any task starts, and so does a scheduler
address that is malformed or cannot be reached.
"""
from __future__ import annotations

import csv
import logging
import math
import signal
import threading
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import ode
from ._compiled import interrupt_all, progress_bar
from .errors import InvalidInputError
from .methods import methods
from .problems import problems
from .results_io import write_atomic
from .scene_file import scene_or_file, scenes as builtin_scenes
from .simulate import simulate

FIELDS = {"t_end", "t0", "scenes", "problems", "params", "label", "methods", "formulations",
          "steps", "step_counts", "tolerances", "samples", "reference", "atol_ratio", "min_cpu",
          "max_reps"}
REFERENCE_FIELDS = {"method", "h", "step_count", "rtol"}
COLUMNS = ["case", "method", "formulation", "control", "status", "error", "steps", "nfev",
           "cpu_time", "wall_time", "rejected", "njev", "nlu", "orders", "reps", "wear",
           "error_message"]


@dataclass
class SweepResult:
    rows: list
    engine: str                       # "serial", "local cluster of N processes", or the address
    wall_time: float                  # the whole sweep, tasks and gathering
    manifest: dict = field(default_factory=dict)

    def column(self, name):
        return [r[name] for r in self.rows]

    def to_csv(self, path) -> None:
        """The table as CSV, written under a temporary name and renamed."""
        path = Path(path)

        def write(tmp):
            with open(tmp, "w", newline="") as fh:
                w = csv.DictWriter(fh, fieldnames=COLUMNS)
                w.writeheader()
                for r in self.rows:
                    w.writerow({k: (repr(r[k]) if isinstance(r[k], float) else r[k])
                                for k in COLUMNS})
        write_atomic(path, write)


#: the columns that are the same bits on every engine (the times and repetitions are not)
RESULT_KEYS = ("case", "method", "formulation", "control", "status", "error", "steps", "nfev",
               "rejected", "njev", "nlu", "orders", "wear", "error_message")


def same_rows(a: SweepResult, b: SweepResult) -> bool:
    """Whether two sweeps gave the same results, bit for bit (a failed run's NaN error equal
    to the other's)."""
    def key(r):
        return tuple("nan" if isinstance(r[k], float) and math.isnan(r[k]) else r[k]
                     for k in RESULT_KEYS)
    return [key(r) for r in a.rows] == [key(r) for r in b.rows]


def order_histogram(stats) -> str:
    """The steps taken at each order, "1:12 2:40" (empty for a fixed-order method)."""
    counts = [stats.order1_steps, stats.order2_steps, stats.order3_steps, stats.order4_steps,
              stats.order5_steps]
    return " ".join(f"{k + 1}:{c}" for k, c in enumerate(counts) if c)


def _list(grid, key, where, default=None):
    v = grid.get(key, default)
    if v is None:
        return []
    if isinstance(v, (str, int, float)):
        return [v]
    if not isinstance(v, (list, tuple)):
        raise InvalidInputError(f"{where}: field {key!r} = {v!r} must be a list")
    return list(v)


def _positive(v, key, where, integer=False):
    ok = (isinstance(v, int) and not isinstance(v, bool)) if integer else \
        isinstance(v, (int, float)) and not isinstance(v, bool)
    if not ok or not v > 0 or (not integer and not math.isfinite(v)):
        raise InvalidInputError(f"{where}: field {key!r} has {v!r}, not a positive "
                                f"{'whole number' if integer else 'number'}")
    return v


def _number(v, key, where) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise InvalidInputError(f"{where}: field {key!r} has {v!r}, not a finite number")
    return float(v)


def _span_steps(span, h, key, where, samples, compared):
    """The number of fixed steps of size h over span, checked against the samples: compared
    with a reference at its samples, the steps must fill the interval (the kernel shortens a
    last step that does not, which would move the samples off the reference's times) and land
    on the samples."""
    n = max(1, round(span / h))
    if samples and compared and abs(span / h - n) > 1e-9 * max(n, 1):
        raise InvalidInputError(f"{where}: field {key!r} has {h!r}, which does not divide the "
                                f"interval {span!r} into whole steps; its samples would miss "
                                "the reference's times (give step_counts, or such an h)")
    if samples and compared and n % samples:
        raise InvalidInputError(f"{where}: field {key!r} has {h!r}, {n} steps, which do not "
                                f"land on the {samples} samples compared with the reference "
                                f"(give a multiple of {samples} steps)")
    return n


def _one(grid, where: str, gi: int) -> tuple[list, list]:
    if not isinstance(grid, dict):
        raise InvalidInputError(f"{where} must be a table of fields, got "
                                f"{type(grid).__name__}")
    unknown = sorted(set(grid) - FIELDS)
    if unknown:
        raise InvalidInputError(f"{where}: unknown field {unknown[0]!r}; known: "
                                f"{', '.join(sorted(FIELDS))}")
    if "t_end" not in grid:
        raise InvalidInputError(f"{where}: field 't_end' is missing")
    t_end, t0 = _number(grid["t_end"], "t_end", where), _number(grid.get("t0", 0.0), "t0", where)
    if not t_end > t0:
        raise InvalidInputError(f"{where}: t_end = {t_end} must be greater than t0 = {t0}")
    span = t_end - t0
    known = methods()
    ms = _list(grid, "methods", where)
    if not ms:
        raise InvalidInputError(f"{where}: field 'methods' is missing or empty")
    for m in ms:
        if m not in known:
            raise InvalidInputError(f"{where}: field 'methods' has {m!r}, not a method; "
                                    f"known: {', '.join(known)}")
    params = grid.get("params")
    if params is not None and not isinstance(params, dict):
        raise InvalidInputError(f"{where}: field 'params' = {params!r} must be a table")
    cases = []
    for s in _list(grid, "scenes", where):
        if not isinstance(s, str):
            raise InvalidInputError(f"{where}: field 'scenes' has {s!r}, not a name or path")
        if s not in builtin_scenes("all") and not s.endswith(".toml"):
            raise InvalidInputError(f"{where}: field 'scenes' has {s!r}: no built-in scene "
                                    "of that name, and not a .toml file")
        if params:
            raise InvalidInputError(f"{where}: field 'params' is for problems; a scene's "
                                    "parameters are in its file")
        cases.append(("scene", s))
    for p in _list(grid, "problems", where):
        if p not in problems():
            raise InvalidInputError(f"{where}: field 'problems' has {p!r}; known: "
                                    f"{', '.join(problems())}")
        bad = sorted(set(params or {}) - set(problems()[p].params))
        if bad:
            raise InvalidInputError(f"{where}: field 'params' has {bad[0]!r}, not a parameter "
                                    f"of {p}; its parameters: {', '.join(problems()[p].params)}")
        cases.append(("problem", p))
    if not cases:
        raise InvalidInputError(f"{where}: give 'scenes' or 'problems'")
    label = grid.get("label")
    if label is not None and (not isinstance(label, str) or len(cases) != 1):
        raise InvalidInputError(f"{where}: field 'label' = {label!r} names the grid's one case "
                                "(a string, with one scene or problem)")
    samples = grid.get("samples")
    if samples is not None:
        _positive(samples, "samples", where, integer=True)
    forms = _list(grid, "formulations", where, ["reduced"])
    if "steps" in grid and "step_counts" in grid:
        raise InvalidInputError(f"{where}: give 'steps' or 'step_counts', not both")
    steps = [float(_positive(h, "steps", where)) for h in _list(grid, "steps", where)]
    counts = [_positive(n, "step_counts", where, integer=True)
              for n in _list(grid, "step_counts", where)]
    tols = [float(_positive(t, "tolerances", where)) for t in _list(grid, "tolerances", where)]
    ratio = float(_positive(grid.get("atol_ratio", 1e-2), "atol_ratio", where))
    min_cpu = _number(grid.get("min_cpu", 0.0), "min_cpu", where)
    if not min_cpu >= 0:
        raise InvalidInputError(f"{where}: field 'min_cpu' has {min_cpu!r}, not a number >= 0")
    max_reps = _positive(grid.get("max_reps", 20), "max_reps", where, integer=True)
    ref = dict(grid.get("reference", {"method": "dopri54", "rtol": 1e-12}))
    bad = sorted(set(ref) - REFERENCE_FIELDS)
    if bad:
        raise InvalidInputError(f"{where}: field 'reference' has {bad[0]!r}; known: "
                                f"{', '.join(sorted(REFERENCE_FIELDS))}")
    if ref.get("method") not in known:
        raise InvalidInputError(f"{where}: field 'reference' has method "
                                f"{ref.get('method')!r}; known: {', '.join(known)}")
    common = {"atol_ratio": ratio, "t0": t0, "t_end": t_end, "params": params,
              "samples": samples, "min_cpu": min_cpu, "max_reps": max_reps}
    refs, tasks = [], []
    for kind, name in cases:
        exact = kind == "problem" and problems()[name].has_exact
        key = None
        if not exact:
            key = f"{gi}:{kind}:{name}"
            if known[ref["method"]].adaptive:
                rh, rrtol = None, float(_positive(ref.get("rtol", 1e-12), "reference.rtol",
                                                  where))
            else:
                if "step_count" in ref:
                    rn = _positive(ref["step_count"], "reference.step_count", where, True)
                elif "h" in ref:
                    rn = _span_steps(span, _positive(ref["h"], "reference.h", where),
                                     "reference.h", where, samples, True)
                else:
                    raise InvalidInputError(f"{where}: field 'reference' names the fixed-step "
                                            f"method {ref['method']!r}: give its h or "
                                            "step_count")
                if samples and rn % samples:
                    raise InvalidInputError(f"{where}: the reference's {rn} steps do not land "
                                            f"on the {samples} samples")
                rh, rrtol = span / rn, None
            refs.append({"kind": kind, "case": name, "label": name, "key": key,
                         "method": ref["method"], "formulation": "reduced", "h": rh,
                         "rtol": rrtol, **common, "min_cpu": 0.0})
        for m in ms:
            adaptive = known[m].adaptive
            if adaptive:
                controls = [(None, t) for t in tols]
            else:
                hs = [span / n for n in counts] if counts else steps
                for n, h in zip(counts or [None] * len(hs), hs):
                    if n is not None and samples and not exact and n % samples:
                        raise InvalidInputError(f"{where}: field 'step_counts' has {n}, which "
                                                f"does not land on the {samples} samples")
                    if n is None:
                        _span_steps(span, h, "steps", where, samples, not exact)
                controls = [(h, None) for h in hs]
            if not controls:
                raise InvalidInputError(f"{where}: {m} needs "
                                        f"{'tolerances' if adaptive else 'steps'}")
            for f in (forms if kind == "scene" else ["-"]):
                for h, rtol in controls:
                    tasks.append({"kind": kind, "case": name, "label": label or name,
                                  "method": m, "formulation": f, "h": h, "rtol": rtol,
                                  "exact": exact, "ref": key, **common})
    return refs, tasks


def tasks_of(grid) -> tuple[list, list]:
    """(references, tasks) of a grid or a list of grids, every entry checked: each a plain
    dict a worker runs."""
    if isinstance(grid, (list, tuple)):
        if not grid:
            raise InvalidInputError("sweep grid: an empty list of grids")
        refs, tasks = [], []
        for i, g in enumerate(grid):
            r, t = _one(g, f"sweep grid {i + 1} of {len(grid)}", i)
            refs += r
            tasks += t
        return refs, tasks
    return _one(grid, "sweep grid", 0)


def _compared(task, r):
    """The states a run's error is taken over: every sample, or the last one."""
    y = r.q if task["kind"] == "scene" else r.y
    return y if task["samples"] else y[-1:]


def one_line(text: str) -> str:
    """A message on one line (a table cell, a command line's error line)."""
    return " ".join(part.strip() for part in str(text).splitlines() if part.strip())


def _failed(row: dict, status: str, message: str) -> dict:
    """The row of a run that gave no result: its status and message, no error, no counts."""
    return {**row, "status": status, "error": math.nan, "steps": 0, "nfev": 0,
            "cpu_time": 0.0, "wall_time": 0.0, "rejected": 0, "njev": 0, "nlu": 0,
            "orders": "", "reps": 0, "wear": "", "error_message": message, "states": None}


def run_task(task: dict, ref_states=None) -> dict:
    """One run of the grid (a worker's whole task): the row of the table, and under "states"
    the states its error is taken over (a reference's whole answer). A case that fails when it
    is loaded or run, with an mbdk error or any other Exception, is a row too (status: the
    exception's class name, error_message: its message); KeyboardInterrupt (SolveInterrupted,
    Ctrl-C) is not an Exception and stops the sweep."""
    row = {"case": task["label"], "method": task["method"],
           "formulation": task["formulation"],
           "control": task["h"] if task["h"] is not None else task["rtol"]}
    try:
        return _run(task, ref_states, row)
    except Exception as exc:
        return _failed(row, type(exc).__name__, one_line(exc) or type(exc).__name__)


def _run(task: dict, ref_states, row: dict) -> dict:
    kw = {"t_end": task["t_end"], "t0": task["t0"]}
    span = task["t_end"] - task["t0"]
    samples = task["samples"]
    if task["h"] is not None:
        n = max(1, round(span / task["h"]))
        kw.update(h=task["h"], every=max(1, n // samples) if samples else n)
    else:
        kw.update(rtol=task["rtol"], atol=task["rtol"] * task["atol_ratio"])
        if samples:
            kw.update(dt_out=span / samples)
    if task["kind"] == "scene":
        target = scene_or_file(task["case"])

        def once():
            return simulate(target, task["method"], formulation=task["formulation"],
                            outputs=(), **kw)
    else:
        def once():
            # looked up at the call: a test puts a failing stand-in there, on every worker
            return ode.solve_ode(task["case"], task["method"], params=task["params"], **kw)
    r = once()
    cpu, wall, reps = r.stats.cpu_time, r.stats.wall_time, 1
    while cpu < task["min_cpu"] and reps < task["max_reps"]:
        again = once()
        cpu, wall, reps = cpu + again.stats.cpu_time, wall + again.stats.wall_time, reps + 1
    states = _compared(task, r)
    st = r.stats
    counts = {"steps": st.steps, "nfev": st.nfev, "cpu_time": cpu / reps,
              "wall_time": wall / reps, "rejected": st.rejected_steps, "njev": st.njev,
              "nlu": st.nlu, "orders": order_histogram(st), "reps": reps,
              "wear": "; ".join(f"{name} {float(w[-1])!r}"
                                for name, w in getattr(r, "wear", {}).items())}
    if isinstance(ref_states, tuple):     # the reference run failed: no error to give
        status, message = ref_states
        return {**row, "status": f"reference {status}", "error": math.nan, **counts,
                "error_message": f"the reference run: {message}", "states": None}
    if task.get("exact"):
        ex = r.exact()
        error = float(np.max(np.abs(states - (ex if samples else ex[-1:]))))
    elif ref_states is not None and np.shape(ref_states) == states.shape:
        error = float(np.max(np.abs(states - ref_states)))
    else:
        error = math.nan
    return {**row, "status": r.status.name, "error": error, **counts, "error_message": "",
            "states": states}


def _reference(task: dict):
    """A case's reference states, or (the class name, the message) of the exception that
    stopped its run."""
    row = run_task(task)
    return row["states"] if row["states"] is not None else (row["status"],
                                                             row["error_message"])


def _run_batch(batch: list) -> list:
    """A worker's share: (task, reference states) pairs run one after the other. Its solves
    are interrupted only by the sweep's own Ctrl-C, which abandons the sweep: nothing to
    return then (a KeyboardInterrupt would end the worker's task loop with a traceback)."""
    try:
        return [run_task(t, ref) for t, ref in batch]
    except KeyboardInterrupt:
        return None


def _reference_on_worker(task: dict):
    """_reference as a Dask task (see _run_batch)."""
    try:
        return _reference(task)
    except KeyboardInterrupt:
        return None


def _batches(items: list, count: int) -> list:
    """items dealt round-robin into count batches, so that each holds coarse and fine runs
    alike; _unbatch restores the order."""
    return [items[k::count] for k in range(count)]


def _unbatch(batches: list, n: int) -> list:
    out = [None] * n
    count = len(batches)
    for k, b in enumerate(batches):
        out[k::count] = b
    return out


def _worker_ignores_sigint() -> bool:
    """Run on each worker process of a local cluster: Ctrl-C at the terminal reaches the
    whole process group, and the sweep's process handles it (it stops the workers' solves and
    closes the cluster); a worker that raised KeyboardInterrupt itself would only print its
    traceback."""
    if threading.current_thread() is not threading.main_thread():
        return False
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return True


def _interrupt_worker_solves() -> int:
    return interrupt_all()


def _tick(bar, n: int) -> None:
    if bar is not None:
        bar.update(n)


def sweep(grid, workers: int = 2, scheduler: str | None = None,
          batches_per_worker: int = 8) -> SweepResult:
    """Runs the grid, or the list of grids (the module docstring, ``help(mbdk.sweep)``, gives
    their fields and the table's columns).

    Parameters
    ----------
    grid : dict or list of dict
        The ``[sweep]`` table (or ``[[sweep]]`` tables) as parsed TOML; ``load_grid`` reads a
        file.
    workers : int
        Local worker processes (one thread each) when no scheduler is given; 0 runs the grid
        serially in this process, with a bar of the runs done on a terminal after a second
        (MBDK_PROGRESS as for a solve).
    scheduler : str, optional
        The address of an existing Dask scheduler, ``tcp://host:port``.
    batches_per_worker : int
        The runs go to the workers in this many batches per worker thread, dealt round-robin: a
        Dask task's scheduling costs milliseconds (studies/sweep_scaling.py measures it), more
        than most runs of a work-precision grid.

    Returns
    -------
    SweepResult
        ``rows`` (one dict per run, the columns of COLUMNS), ``engine``, ``wall_time`` and the
        ``manifest``; ``to_csv(path)`` writes the table.
    """
    refs, tasks = tasks_of(grid)
    if not (isinstance(batches_per_worker, int) and batches_per_worker > 0):
        raise InvalidInputError(f"batches_per_worker = {batches_per_worker!r} must be a whole "
                                "number > 0")
    t_start = time.perf_counter()
    if scheduler is None and not workers:
        engine = "serial"
        bar = progress_bar(len(refs) + len(tasks), "sweep", "run")
        ref_states = {}
        for r in refs:
            ref_states[r["key"]] = _reference(r)
            _tick(bar, 1)
        rows = []
        for t in tasks:
            rows.append(run_task(t, ref_states.get(t["ref"])))
            _tick(bar, 1)
    else:
        try:
            # Dask: optional (the sweep extra), slow to import, only a cluster needs it
            from dask.distributed import Client, LocalCluster, as_completed
        except ImportError:
            raise InvalidInputError("sweeps on Dask need dask.distributed: pip install "
                                    "'dask[distributed]' (or workers=0 for a serial sweep)") \
                from None
        cluster = None
        if scheduler is None:
            if not (isinstance(workers, int) and workers > 0):
                raise InvalidInputError(f"workers = {workers!r} must be a whole number >= 0")
            # the workers' and nannies' warnings (a cancelled task, a worker killed when the
            # cluster closes after Ctrl-C) are not the sweep's output; errors still show
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR)
            engine = f"local cluster of {workers} processes"
        else:
            engine = f"scheduler at {scheduler}"
        try:
            client = Client(cluster if cluster is not None else scheduler, timeout="20s")
        except (OSError, ValueError, TypeError) as exc:    # unreachable; not an address
            if cluster is not None:
                cluster.close()
            raise InvalidInputError(f"scheduler = {scheduler!r}: cannot connect "
                                    f"({one_line(exc)}); give a Dask scheduler's address, "
                                    "tcp://host:port") from None
        bar = progress_bar(len(refs) + len(tasks), "sweep", "run")
        try:
            if cluster is not None:
                client.run(_worker_ignores_sigint)
            fr = client.map(_reference_on_worker, refs, pure=False)
            for _ in as_completed(fr):
                _tick(bar, 1)
            ref_states = dict(zip([r["key"] for r in refs], client.gather(fr)))
            threads = max(1, sum(client.nthreads().values()))
            count = max(1, min(len(tasks), batches_per_worker * threads))
            pairs = [(t, ref_states.get(t["ref"])) for t in tasks]
            batches = _batches(pairs, count)
            ft = client.map(_run_batch, batches, pure=False)
            size = {f.key: len(b) for f, b in zip(ft, batches)}
            for f in as_completed(ft):
                _tick(bar, size[f.key])
            rows = _unbatch(client.gather(ft), len(tasks))
        except KeyboardInterrupt:
            # Ctrl-C: the local workers' solves stop within a step, so that the cluster
            # closes at once rather than killing them (a remote cluster's other work is left
            # alone: its tasks are cancelled when the client closes)
            if cluster is not None:
                try:
                    client.run(_interrupt_worker_solves)
                except Exception:   # noqa: BLE001 - closing goes on regardless
                    pass
            raise
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
            if bar is not None:
                bar.close()
        bar = None
    for r in rows:
        r.pop("states", None)
    return SweepResult(rows, engine, time.perf_counter() - t_start,
                       {**ode.build_info(), "grid": grid, "tasks": len(tasks),
                        "references": len(refs)})


def load_grid(path):
    """The [sweep] table of a TOML file, or the list of its [[sweep]] tables."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except OSError as exc:
        raise InvalidInputError(f"{path}: cannot read the grid file ({exc.strerror})") from None
    except UnicodeDecodeError as exc:
        raise InvalidInputError(f"{path}: not a TOML text file: byte {exc.object[exc.start]:#04x} "
                                f"at offset {exc.start} is not UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:
        raise InvalidInputError(f"{path}: not valid TOML: {exc}") from None
    if "sweep" not in data:
        raise InvalidInputError(f"{path}: no [sweep] table")
    return data["sweep"]
