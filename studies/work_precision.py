"""What accuracy costs in time: error against the kernel's CPU time for every method across a
step sweep, one figure per chapter-4 problem (work-precision diagrams).

The error is the largest absolute error over 100 samples of the whole interval, against the exact
solution where one exists and otherwise against an rk4 run with 16x more steps than the finest
one shown (trolley_crane, double_pendulum). A method that fails at a step (overflow, Newton)
has the exception's name in the table's note column and is left out of the figure there.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import main, progress  # noqa: E402

import mbdk  # noqa: E402
from mbdk.analysis import plotting  # noqa: E402
from mbdk.analysis.convergence import observed_order  # noqa: E402
from mbdk.analysis.tables import write_table  # noqa: E402
from mbdk.analysis.timing import solve_timed  # noqa: E402

# problem -> (t_end, params, coarsest number of steps)
PROBLEMS = {
    "riccati": (5.0, None, 100),
    "beam_nonlinear": (1000.0, None, 10),
    "damped_oscillator": (10.0, None, 200),
    "pendulum": (5.0, None, 100),
    "pendulum_linear": (5.0, None, 100),
    "trolley_crane": (5.0, None, 400),
    "double_pendulum": (5.0, None, 400),
}


def sweep(problem: str, quick: bool):
    t_end, params, n0 = PROBLEMS[problem]
    info = mbdk.problems()[problem]
    levels = [0, 2, 4] if quick else list(range(7))
    ns = [n0 * 2**k for k in levels]
    samples = 100
    ref = None
    if not info.has_exact:
        nref = ns[-1] * 16
        ref = mbdk.solve_ode(problem, "rk4", h=t_end / nref, t_end=t_end, params=params,
                             every=nref // samples).y
    rows = []
    for name, m in mbdk.methods("ode", step="fixed").items():
        if m.family == "euler_cromer" and not info.second_order:
            continue
        if name == "bdf1":      # the same formula as implicit_euler
            continue
        prev = None
        for n in ns:
            h = t_end / n
            try:
                r, cpu = solve_timed(problem, name, h=h, t_end=t_end, params=params,
                                     every=max(1, n // samples), min_cpu=0.01, max_reps=20)
            except mbdk.MbdkError as exc:
                rows.append({"problem": problem, "method": name, "h": h, "steps": n,
                             "max_error": None, "observed_order": None, "cpu_s": None,
                             "nfev": None, "note": f"{type(exc).__name__}"})
                prev = None
                continue
            if ref is not None:
                err = float(np.max(np.abs(r.y - ref)))
            else:
                err = float(np.max(np.abs(r.y - r.exact())))
            order = observed_order(prev[1], err, prev[0], h) if prev else None
            prev = (h, err)
            rows.append({"problem": problem, "method": name, "h": h, "steps": n,
                         "max_error": err, "observed_order": order, "cpu_s": cpu,
                         "nfev": r.stats.nfev, "note": ""})
    return rows


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
    tables, figures, cheapest = [], [], []
    probs = ["riccati", "damped_oscillator", "double_pendulum"] if quick else list(PROBLEMS)
    for p in probs:
        progress(f"work-precision sweep: {p}")
        rows = sweep(p, quick)
        figures.append(figure(p, rows, out))
        tables.append(write_table(rows, list(rows[0]), out, f"work_precision_{p}",
                                  f"Work-precision: {p}"))
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
