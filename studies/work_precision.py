"""What accuracy costs in time: error against the kernel's CPU time for every method across a
step sweep, one figure per chapter-4 problem (work-precision diagrams).

The grid is studies/grids/work_precision.toml, run by mbdk.sweep: on a local Dask cluster of
MBDK_STUDY_WORKERS processes (default 2; 0 runs it serially here), the same bits either way.
`mbdk sweep studies/grids/work_precision.toml --out wp.csv` runs the same grid from the
command line, on a scheduler's address with --scheduler. The error is the largest absolute
error over 100 samples of the whole interval, against the exact solution where one exists and
otherwise against an rk4 run with 16x more steps than the finest one of the full grid
(trolley_crane, double_pendulum; --quick keeps it). A method that fails at a step (overflow,
Newton) has the exception's name in the table's note column and is left out of the figure
there.
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import main, progress, study_workers  # noqa: E402

import mbdk  # noqa: E402
from mbdk.analysis import plotting  # noqa: E402
from mbdk.analysis.convergence import observed_order  # noqa: E402
from mbdk.analysis.tables import write_table  # noqa: E402
from mbdk.sweep import load_grid, sweep  # noqa: E402

GRID = Path(__file__).resolve().parent / "grids" / "work_precision.toml"
QUICK = ("riccati", "damped_oscillator", "double_pendulum")


def grids(quick: bool) -> list[dict]:
    """The grid file's sweeps; quick: three problems at every other step of the first five."""
    out = load_grid(GRID)
    if quick:
        out = [{**g, "step_counts": g["step_counts"][:5:2]} for g in out
               if g["problems"][0] in QUICK]
    return out


def table_rows(rows) -> list[dict]:
    """The sweep's rows as the study's table: per problem and method, the observed order
    between neighbouring steps."""
    out, prev = [], {}
    for r in rows:
        key = (r["case"], r["method"])
        ok = r["status"] == "SUCCESS"
        err = r["error"] if ok else None
        order = (observed_order(prev[key][1], err, prev[key][0], r["control"])
                 if ok and prev.get(key) else None)
        prev[key] = (r["control"], err) if ok else None
        out.append({"problem": r["case"], "method": r["method"], "h": r["control"],
                    "steps": r["steps"] if ok else None, "max_error": err,
                    "observed_order": order, "cpu_s": r["cpu_time"] if ok else None,
                    "wall_s": r["wall_time"] if ok else None,
                    "nfev": r["nfev"] if ok else None, "note": "" if ok else r["status"]})
    return out


def figure(problem: str, rows, out: Path):
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    styles = {"explicit_rk": "-", "euler_cromer": "-.", "implicit_lmm": "--"}
    infos = mbdk.methods("ode", step="fixed")
    for i, name in enumerate(infos):       # a fixed colour per method across all figures
        pts = [r for r in rows if r["method"] == name and r["max_error"] is not None]
        if not pts:
            continue
        st = styles[infos[name].family]
        kw = dict(ms=3, label=name, color=plt.cm.tab20(i))
        ax[0].loglog([p["cpu_s"] for p in pts], [p["max_error"] for p in pts], "o" + st, **kw)
        ax[1].loglog([p["h"] for p in pts], [p["max_error"] for p in pts], "o" + st, **kw)
    ax[0].set_xlabel("CPU time of the kernel loop (s)")
    ax[0].set_ylabel("max |error| over the interval")
    ax[0].set_title(f"{problem}: what accuracy costs")
    ax[1].set_xlabel("h")
    ax[1].set_ylabel("max |error|")
    ax[1].set_title("error against step (slope = order)")
    ax[1].legend(ncol=2, fontsize=7)
    return plotting.save(fig, out, f"work_precision_{problem}")


def run(out: Path, quick: bool = False) -> dict:
    out = Path(out)
    gs = grids(quick)
    workers = study_workers()
    progress(f"work-precision sweep: {len(gs)} problems on "
             f"{f'{workers} local workers' if workers else 'this process'}")
    result = sweep(gs, workers=workers)
    every = table_rows(result.rows)
    tables, figures, cheapest = [], [], []
    for g in gs:
        p = g["problems"][0]
        rows = [r for r in every if r["problem"] == p]
        figures.append(figure(p, rows, out))
        tables.append(write_table(rows, list(rows[0]), out, f"work_precision_{p}",
                                  f"Work-precision: {p}",
                                  f"{len(result.rows)} runs of one sweep on {result.engine}; "
                                  "cpu_s and wall_s: the solving thread's CPU time and the "
                                  "wall time of the kernel call, per run"))
        for tol in (1e-3, 1e-6):
            ok = [r for r in rows if r["max_error"] is not None and r["max_error"] <= tol]
            if ok:
                best = min(ok, key=lambda r: r["cpu_s"])
                cheapest.append({"problem": p, "tolerance": tol, "cheapest_method": best["method"],
                                 "h": best["h"], "max_error": best["max_error"],
                                 "cpu_s": best["cpu_s"]})
    tables.insert(0, write_table(cheapest, list(cheapest[0]), out, "work_precision_cheapest",
                                 "Cheapest method (on the swept steps) to reach an error",
                                 "Among the swept steps only; a finer sweep moves the numbers, "
                                 "rarely the ranking."))
    return {"title": "What accuracy costs in time", "tables": tables, "figures": figures}


if __name__ == "__main__":
    raise SystemExit(main(run, "work_precision"))
