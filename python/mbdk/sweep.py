"""Sweeps: a grid of runs (scenes or compiled problems x methods x formulations x steps or
tolerances) as independent tasks on Dask, gathered into one table with each run's error
against its reference, CPU time and counters.

    >>> grid = {"t_end": 10.0, "scenes": ["double_pendulum"], "methods": ["rk4", "dopri54"],
    ...         "steps": [1e-2, 1e-3], "tolerances": [1e-6, 1e-9]}
    >>> table = mbdk.sweep.sweep(grid)                   # a local cluster of 2 processes
    >>> table = mbdk.sweep.sweep(grid, scheduler="tcp://10.0.0.5:8786")   # an existing one
    >>> table = mbdk.sweep.sweep(grid, workers=0)        # serially, in this process

The grid (a dict, or the [sweep] table of a TOML file for `mbdk sweep GRID.toml`):
  t_end, t0 (default 0)
  scenes (built-in names or scene files) and/or problems (compiled problems' names)
  methods; formulations (scenes; default ["reduced"])
  steps: h for the fixed-step methods; tolerances: rtol for the error-controlled ones (atol =
         rtol * atol_ratio, default 1e-2), each sampled at t_end only
  reference: {method, h or rtol} for a scene's (and a problem without a closed form's) final
         state, default {method = "dopri54", rtol = 1e-12}; problems with an exact solution
         use it
Each task is one run; its row: case, method, formulation, control (h or rtol), status, error
(max |y(t_end) - y_ref(t_end)| over the coordinates, or over the state for a problem), steps,
nfev, cpu_time (the solving thread's), wall_time. A run is deterministic, so a task gives the
same bits on any worker as in a serial loop (tests/test_sweep.py). Bad grids (an unknown
method, case or field) raise InvalidInputError before any task starts.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from .errors import InvalidInputError, MbdkError

FIELDS = {"t_end", "t0", "scenes", "problems", "methods", "formulations", "steps", "tolerances",
          "reference", "atol_ratio"}
COLUMNS = ["case", "method", "formulation", "control", "status", "error", "steps", "nfev",
           "cpu_time", "wall_time"]


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
        import csv
        from pathlib import Path

        from .results_io import _atomic
        path = Path(path)

        def write(tmp):
            with open(tmp, "w", newline="") as fh:
                w = csv.DictWriter(fh, fieldnames=COLUMNS)
                w.writeheader()
                for r in self.rows:
                    w.writerow({k: (repr(r[k]) if isinstance(r[k], float) else r[k])
                                for k in COLUMNS})
        _atomic(path, write)


#: the columns that are the same bits on every engine (the times are not)
RESULT_KEYS = ("case", "method", "formulation", "control", "status", "error", "steps", "nfev")


def same_rows(a: SweepResult, b: SweepResult) -> bool:
    """Whether two sweeps gave the same results, bit for bit (a failed run's NaN error equal
    to the other's)."""
    def key(r):
        return tuple("nan" if isinstance(r[k], float) and math.isnan(r[k]) else r[k]
                     for k in RESULT_KEYS)
    return [key(r) for r in a.rows] == [key(r) for r in b.rows]


def _list(grid, key, default=None):
    v = grid.get(key, default)
    if v is None:
        return []
    if isinstance(v, (str, int, float)):
        return [v]
    if not isinstance(v, (list, tuple)):
        raise InvalidInputError(f"sweep grid: field {key!r} = {v!r} must be a list")
    return list(v)


def tasks_of(grid: dict) -> tuple[list, list]:
    """(references, tasks) of a grid, every entry checked: each a plain dict a worker runs."""
    from .methods import methods
    from .problems import problems
    from .scene import scenes as builtin_scenes
    if not isinstance(grid, dict):
        raise InvalidInputError(f"sweep grid must be a table of fields, got {type(grid).__name__}")
    unknown = sorted(set(grid) - FIELDS)
    if unknown:
        raise InvalidInputError(f"sweep grid: unknown field {unknown[0]!r}; known: "
                                f"{', '.join(sorted(FIELDS))}")
    if "t_end" not in grid:
        raise InvalidInputError("sweep grid: field 't_end' is missing")
    t_end, t0 = float(grid["t_end"]), float(grid.get("t0", 0.0))
    if not t_end > t0:
        raise InvalidInputError(f"sweep grid: t_end = {t_end} must be greater than t0 = {t0}")
    known = methods()
    ms = _list(grid, "methods")
    if not ms:
        raise InvalidInputError("sweep grid: field 'methods' is missing or empty")
    for m in ms:
        if m not in known:
            raise InvalidInputError(f"sweep grid: field 'methods' has {m!r}, not a method; "
                                    f"known: {', '.join(known)}")
    cases = []
    for s in _list(grid, "scenes"):
        if not isinstance(s, str):
            raise InvalidInputError(f"sweep grid: field 'scenes' has {s!r}, not a name or path")
        if s not in builtin_scenes("all") and not s.endswith(".toml"):
            raise InvalidInputError(f"sweep grid: field 'scenes' has {s!r}: no built-in scene "
                                    "of that name, and not a .toml file")
        cases.append(("scene", s))
    for p in _list(grid, "problems"):
        if p not in problems():
            raise InvalidInputError(f"sweep grid: field 'problems' has {p!r}; known: "
                                    f"{', '.join(problems())}")
        cases.append(("problem", p))
    if not cases:
        raise InvalidInputError("sweep grid: give 'scenes' or 'problems'")
    forms = _list(grid, "formulations", ["reduced"])
    steps = [float(h) for h in _list(grid, "steps")]
    tols = [float(t) for t in _list(grid, "tolerances")]
    ratio = float(grid.get("atol_ratio", 1e-2))
    ref = dict(grid.get("reference", {"method": "dopri54", "rtol": 1e-12}))
    if ref.get("method") not in known:
        raise InvalidInputError(f"sweep grid: field 'reference' has method "
                                f"{ref.get('method')!r}; known: {', '.join(known)}")
    refs, tasks = [], []
    for kind, name in cases:
        exact = kind == "problem" and problems()[name].has_exact
        if not exact:
            refs.append({"kind": kind, "case": name, "method": ref["method"],
                         "formulation": "reduced", "h": ref.get("h"), "rtol": ref.get("rtol"),
                         "atol_ratio": ratio, "t0": t0, "t_end": t_end})
        for m in ms:
            adaptive = known[m].adaptive
            controls = tols if adaptive else steps
            if not controls:
                raise InvalidInputError(f"sweep grid: {m} needs "
                                        f"{'tolerances' if adaptive else 'steps'}")
            for f in (forms if kind == "scene" else ["-"]):
                for c in controls:
                    tasks.append({"kind": kind, "case": name, "method": m, "formulation": f,
                                  "h": None if adaptive else c, "rtol": c if adaptive else None,
                                  "atol_ratio": ratio, "t0": t0, "t_end": t_end,
                                  "exact": exact})
    return refs, tasks


def run_task(task: dict, ref_state=None) -> dict:
    """One run of the grid (a worker's whole task): the row of the table."""
    import mbdk
    kw = {"t_end": task["t_end"], "t0": task["t0"]}
    if task["h"] is not None:
        n = max(1, round((task["t_end"] - task["t0"]) / task["h"]))
        kw.update(h=task["h"], every=n)
    else:
        kw.update(rtol=task["rtol"], atol=task["rtol"] * task["atol_ratio"])
    row = {"case": task["case"], "method": task["method"], "formulation": task["formulation"],
           "control": task["h"] if task["h"] is not None else task["rtol"]}
    try:
        if task["kind"] == "scene":
            from .scene import scene_or_file
            r = mbdk.simulate(scene_or_file(task["case"]), task["method"],
                              formulation=task["formulation"], outputs=(), **kw)
            final = r.q[-1]
        else:
            r = mbdk.solve_ode(task["case"], task["method"], **kw)
            final = r.y[-1]
    except MbdkError as exc:
        return {**row, "status": type(exc).__name__, "error": math.nan, "steps": 0, "nfev": 0,
                "cpu_time": 0.0, "wall_time": 0.0, "final": None}
    if task.get("exact"):
        error = float(np.max(np.abs(r.y[-1] - r.exact()[-1])))
    elif ref_state is not None:
        error = float(np.max(np.abs(final - ref_state)))
    else:
        error = math.nan
    return {**row, "status": r.status.name, "error": error, "steps": r.stats.steps,
            "nfev": r.stats.nfev, "cpu_time": r.stats.cpu_time, "wall_time": r.stats.wall_time,
            "final": final.tolist()}


def _reference(task: dict) -> list:
    return run_task(task)["final"]


def sweep(grid: dict, workers: int = 2, scheduler: str | None = None) -> SweepResult:
    """Runs the grid (module docstring): on the Dask scheduler at address scheduler, else on a
    local cluster of workers processes (one thread each), else (workers = 0) serially here."""
    refs, tasks = tasks_of(grid)
    t_start = time.perf_counter()
    if scheduler is None and not workers:
        engine = "serial"
        ref_states = {(r["kind"], r["case"]): _reference(r) for r in refs}
        rows = [run_task(t, ref_states.get((t["kind"], t["case"]))) for t in tasks]
    else:
        try:
            from dask.distributed import Client, LocalCluster
        except ImportError:
            raise InvalidInputError("sweeps on Dask need dask.distributed: pip install "
                                    "'dask[distributed]' (or workers=0 for a serial sweep)") \
                from None
        cluster = None
        if scheduler is None:
            if not (isinstance(workers, int) and workers > 0):
                raise InvalidInputError(f"workers = {workers!r} must be a whole number >= 0")
            cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                   dashboard_address=None)
            engine = f"local cluster of {workers} processes"
        else:
            engine = f"scheduler at {scheduler}"
        try:
            client = Client(cluster if cluster is not None else scheduler, timeout="20s")
        except OSError as exc:
            if cluster is not None:
                cluster.close()
            raise InvalidInputError(f"scheduler = {scheduler!r}: cannot connect ({exc})") \
                from None
        try:
            fr = client.map(_reference, refs, pure=False)
            ref_states = dict(zip([(r["kind"], r["case"]) for r in refs], client.gather(fr)))
            ft = client.map(run_task, tasks,
                            [ref_states.get((t["kind"], t["case"])) for t in tasks], pure=False)
            rows = client.gather(ft)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    for r in rows:
        r.pop("final", None)
    from .ode import build_info
    return SweepResult(rows, engine, time.perf_counter() - t_start,
                       {**build_info(), "grid": grid, "tasks": len(tasks),
                        "references": len(refs)})


def load_grid(path) -> dict:
    """The [sweep] table of a TOML file."""
    import tomllib
    from pathlib import Path
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text())
    except OSError as exc:
        raise InvalidInputError(f"{path}: cannot read the grid file ({exc.strerror})") from None
    except tomllib.TOMLDecodeError as exc:
        raise InvalidInputError(f"{path}: not valid TOML: {exc}") from None
    if "sweep" not in data:
        raise InvalidInputError(f"{path}: no [sweep] table")
    return data["sweep"]
