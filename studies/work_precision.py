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

The index-3 DAE of mechanisms (issue 38): the same measure on five scenes, P1 (the double
pendulum scene), the four-bar, the IFToMM A02 loop through its flat poses, Bricard's linkage
and the stiff flyball governor, for the index-3 family at fixed steps (trapezoidal_index3, which
is generalized_alpha with rho_inf = 1 to roundoff; newmark with gamma = 0.6, beta = 0.3025, the
damped and first-order rule; hht with alpha = -0.1; generalized_alpha with rho_inf = 0.8 and
0.5 (hht with alpha = -1/3 has rho_inf = 0.5's parameters); each in its default formulation)
beside the error-controlled DAE solvers bdf (i3: the index-3 form as GSTIFF I3; si2: the
stabilised index-2 form) and ida (index1) at tolerances rtol 1e-3..1e-10 (atol = rtol/100). The
error is the largest |q - q_ref| over the coordinates at 20 samples of the interval, against
A02's exact motion (mbdk.benchmarks.a02_crank) or dopri54 on the reduced formulation at rtol
1e-12, itself checked against bdf (reduced, rtol 1e-12): a target error below five times that
difference is not scored. CPU: the solving thread's, the least of three runs for a run under
50 ms. A run that stops has its exception's name in the note. The table "cheapest method per
target error" takes for each scene and target (1e-2, 1e-4, 1e-6, 1e-8) the method with the
least CPU time to reach it, interpolated between neighbouring runs in log-log
(mbdk.analysis.work_precision), and the runner-up; a last table gives what numerical damping
costs in accuracy: each damped member's error over the trapezoidal rule's at the same h.
"""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import main, progress, study_workers  # noqa: E402

import math  # noqa: E402
import statistics  # noqa: E402
import warnings  # noqa: E402

import numpy as np  # noqa: E402

import mbdk  # noqa: E402
from mbdk.analysis import plotting  # noqa: E402
from mbdk.analysis.convergence import observed_order  # noqa: E402
from mbdk.analysis.tables import write_table  # noqa: E402
from mbdk.analysis.work_precision import cheapest, error_ratios  # noqa: E402
from mbdk.benchmarks import a02_chain, a02_crank  # noqa: E402
from mbdk.errors import AccuracyWarning, MbdkError  # noqa: E402
from mbdk.sweep import load_grid, sweep  # noqa: E402

GRID = Path(__file__).resolve().parent / "grids" / "work_precision.toml"
QUICK = ("riccati", "damped_oscillator", "double_pendulum")
TARGETS = (1e-2, 1e-4, 1e-6, 1e-8)

#: the scenes: label -> (scene, t_end, step counts of the fixed-step methods, stiff)
SCENES = {"P1 double_pendulum": ("double_pendulum", 2.0, [100 * 2 ** k for k in range(11)], False),
          "four_bar": ("four_bar", 2.0, [100 * 2 ** k for k in range(11)], False),
          "A02 (1 loop)": ("a02_n1", 2.0, [100 * 2 ** k for k in range(11)], False),
          "bricard": ("bricard", 2.0, [100 * 2 ** k for k in range(7)], False),
          "flyball_governor": ("flyball_governor", 1.0, [100 * 2 ** k for k in range(7)], True)}
QUICK_SCENES = {"P1 double_pendulum": ("double_pendulum", 1.0, [100, 400, 1600], False)}
TOLERANCES = [10.0 ** -k for k in range(3, 11)]
QUICK_TOLERANCES = [1e-4, 1e-7]
SAMPLES = 20
#: the methods on the scenes: label -> (method, options); the first is the undamped member
SCENE_METHODS = {
    "trapezoidal_index3": ("trapezoidal_index3", {}),
    "newmark (gamma 0.6)": ("newmark", {"newmark_beta": 0.3025, "newmark_gamma": 0.6}),
    "hht (alpha -0.1)": ("hht", {"alpha_hht": -0.1}),
    "generalized_alpha (rho_inf 0.8)": ("generalized_alpha", {"rho_inf": 0.8}),
    "generalized_alpha (rho_inf 0.5)": ("generalized_alpha", {"rho_inf": 0.5}),
    "bdf i3": ("bdf", {"formulation": "i3"}),
    "bdf si2": ("bdf", {"formulation": "si2"}),
    "ida": ("ida", {}),
}
ERROR_CONTROLLED = ("bdf", "ida")


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
        kw = dict(ms=4, mfc="none", label=name, ls=st, **plotting.line_style(i))
        ax[0].loglog([p["cpu_s"] for p in pts], [p["max_error"] for p in pts], **kw)
        ax[1].loglog([p["h"] for p in pts], [p["max_error"] for p in pts], **kw)
    ax[0].set_xlabel("CPU time of the kernel loop (s)")
    ax[0].set_ylabel("max |error| over the interval")
    ax[0].set_title(f"{problem}: what accuracy costs")
    ax[1].set_xlabel("h")
    ax[1].set_ylabel("max |error|")
    ax[1].set_title("error against step (slope = order)")
    ax[1].legend(ncol=2, fontsize=7)
    return plotting.save(fig, out, f"work_precision_{problem}")


def scene_of(name: str):
    return a02_chain(int(name[len("a02_n"):])) if name.startswith("a02_n") else mbdk.scene(name)


def a02_exact_q(n: int, t) -> np.ndarray:
    """The A02 chain's coordinates (x, y, angle per body: cranks, then couplers) at times t,
    from its exact crank angle: crank i turns about its hinge (i, 0), coupler i translates with
    the crank tips."""
    th, _ = a02_crank(n, t)
    c, s = np.cos(th), np.sin(th)
    cols = []
    for i in range(n + 1):
        cols += [i + 0.5 * c, 0.5 * s, th]
    for i in range(n):
        cols += [i + 0.5 + c, s, np.zeros_like(th)]
    return np.column_stack(cols)


def flat_poses(n: int, t_end: float) -> np.ndarray:
    """The times at which the A02 chain is flat (its crank angle a multiple of pi) before
    t_end, to 1e-5 s."""
    t = np.linspace(0.0, t_end, int(round(t_end * 1e5)) + 1)
    k = np.floor(a02_crank(n, t)[0] / np.pi)
    return t[1:][np.diff(k) != 0]


def scene_reference(name: str, scene, t_end: float) -> tuple[np.ndarray, float, str]:
    """(q at the samples, the reference's own accuracy, what it is). A02: exact (its accuracy
    that of the elliptic functions, taken as 0); otherwise dopri54 on the reduced formulation at
    rtol 1e-12, its accuracy estimated by its largest difference from bdf at rtol 1e-12."""
    if name.startswith("a02_n"):
        n = int(name[len("a02_n"):])
        flat = ", ".join(f"{t:.3f}" for t in flat_poses(n, t_end))
        return a02_exact_q(n, np.linspace(0.0, t_end, SAMPLES + 1)), 0.0, \
            f"exact (mbdk.benchmarks.a02_crank); flat poses at t = {flat} s"
    kw = dict(t_end=t_end, dt_out=t_end / SAMPLES, outputs=(), formulation="reduced")
    ref = mbdk.simulate(scene, "dopri54", rtol=1e-12, atol=1e-14, **kw)
    check = mbdk.simulate(scene, "bdf", rtol=1e-12, atol=1e-14, **kw)
    return ref.q, float(np.max(np.abs(ref.q - check.q))), "dopri54 rtol 1e-12"


def timed_run(scene, method: str, **kw):
    """(result, thread CPU, wall): the least of three runs when one takes under 50 ms (runs are
    deterministic: every repetition gives the same result)."""
    r = mbdk.simulate(scene, method, **kw)
    cpu, wall = r.cpu_time, r.wall_time
    if cpu < 0.05:
        for _ in range(2):
            again = mbdk.simulate(scene, method, **kw)
            cpu, wall = min(cpu, again.cpu_time), min(wall, again.wall_time)
    return r, cpu, wall


def scene_rows(label: str, name: str, t_end: float, counts, tolerances) -> tuple[list, float, str]:
    """One scene's runs: every method of SCENE_METHODS at every step or tolerance."""
    scene = scene_of(name)
    ref, ref_acc, ref_kind = scene_reference(name, scene, t_end)
    rows = []
    for mlabel, (method, opts) in SCENE_METHODS.items():
        adaptive = method in ERROR_CONTROLLED
        prev = None
        for c in (tolerances if adaptive else counts):
            kw = dict(t_end=t_end, outputs=(), **opts)
            if adaptive:
                kw.update(rtol=c, atol=c * 1e-2, dt_out=t_end / SAMPLES)
            else:
                kw.update(h=t_end / c, every=c // SAMPLES)
            row = {"scene": label, "method": mlabel, "h": None if adaptive else t_end / c,
                   "rtol": c if adaptive else None}
            try:
                with warnings.catch_warnings():
                    # the book form's multipliers are flagged; q, the compared part, is not
                    warnings.simplefilter("ignore", AccuracyWarning)
                    r, cpu, wall = timed_run(scene, method, **kw)
            except MbdkError as exc:
                rows.append({**row, "max_error": None, "note": type(exc).__name__})
                prev = None
                continue
            if r.q.shape != ref.shape:
                raise RuntimeError(f"{label}/{mlabel}: {r.q.shape[0]} samples against the "
                                   f"reference's {ref.shape[0]}")
            err = float(np.max(np.abs(r.q - ref)))
            order = (observed_order(prev[1], err, prev[0], row["h"])
                     if prev is not None and not adaptive else None)
            prev = (row["h"], err)
            rows.append({**row, "steps": r.stats.steps, "max_error": err,
                         "observed_order": order, "cpu_s": cpu, "wall_s": wall, "note": ""})
    return rows, ref_acc, ref_kind


def curves(rows) -> dict:
    """{method: [(cpu, error or None), ...]} in sweep order."""
    out = {}
    for r in rows:
        out.setdefault(r["method"], []).append((r.get("cpu_s"), r["max_error"]))
    return out


def cheapest_rows(case: str, rows, floor: float = 0.0) -> list[dict]:
    """Per target: the cheapest method to reach it, how many of its runs on the case stopped
    (a method that reaches the target at some tolerances may stop at others), and the
    runner-up; a target within five times the reference's own accuracy is not scored."""
    out = []
    for target in TARGETS:
        row = {"case": case, "target_error": target}
        if target < 5.0 * floor:
            out.append({**row, "note": f"below 5x the reference's accuracy ({floor:.1e})"})
            continue
        ranked = cheapest(curves(rows), target)
        if not ranked:
            out.append({**row, "note": "no method reaches it on the swept steps"})
            continue
        (m1, r1), rest = ranked[0], ranked[1:]
        stopped = sum(1 for r in rows if r["method"] == m1 and r["note"])
        row.update({"cheapest_method": m1, "cpu_s": r1.cpu, "how": r1.how,
                    "its runs stopped": stopped})
        if rest:
            row.update({"runner_up": rest[0][0], "runner_up_cpu_s": rest[0][1].cpu,
                        "runner_up / cheapest": rest[0][1].cpu / r1.cpu})
        out.append({**row, "note": ""})
    return out


def damping_rows(rows, stiff: bool) -> list[dict]:
    """Each damped member's error over the trapezoidal rule's at the same h on one scene."""
    by = {}
    for r in rows:
        if r["h"] is not None:
            by.setdefault(r["method"], {})[r["h"]] = r["max_error"]
    base = by.get("trapezoidal_index3", {})
    out = []
    for m, errs in by.items():
        if m == "trapezoidal_index3":
            continue
        ratios = error_ratios(errs, base)
        if ratios:
            finest = min(h for h in errs if errs[h] is not None and base.get(h) is not None)
            out.append({"scene": rows[0]["scene"], "stiff": stiff, "method": m,
                        "median error ratio": statistics.median(ratios),
                        "min": min(ratios), "max": max(ratios), "steps compared": len(ratios),
                        "ratio at the finest h": errs[finest] / base[finest],
                        "finest h": finest})
    return out


def damping_sentence(rows: list[dict]) -> str:
    """What numerical damping costs in accuracy on the non-stiff scenes, from the ratios."""
    soft = [r for r in rows if not r["stiff"]]
    if not soft:
        return ""
    parts = []
    for m in dict.fromkeys(r["method"] for r in soft):
        meds = [r["median error ratio"] for r in soft if r["method"] == m]
        parts.append(f"{m} {statistics.median(meds):.2g}x" + (
            f" (the scenes' medians {min(meds):.2g} to {max(meds):.2g})" if len(meds) > 1
            else ""))
    text = ("What numerical damping costs in accuracy on the non-stiff scenes ("
            + ", ".join(dict.fromkeys(r["scene"] for r in soft)) + "): at the same h, the "
            "error over the trapezoidal rule's (rho_inf = 1) is " + "; ".join(parts) + ".")
    stiff = [r for r in rows if r["stiff"]]
    if stiff:
        text += (" On the stiff " + ", ".join(dict.fromkeys(r["scene"] for r in stiff))
                 + ": " + "; ".join(f"{r['method']} {r['median error ratio']:.2g}x"
                                    for r in stiff) + ".")
    return text


def scene_figure(case: str, rows, out: Path, slug: str):
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(1, 2, figsize=(12, 4.5))
    for i, m in enumerate(SCENE_METHODS):
        pts = [r for r in rows if r["method"] == m and r["max_error"] is not None]
        if not pts:
            continue
        st = "--" if SCENE_METHODS[m][0] in ERROR_CONTROLLED else "-"
        kw = dict(ms=4, mfc="none", label=m, ls=st, **plotting.line_style(i))
        ax[0].loglog([p["cpu_s"] for p in pts], [p["max_error"] for p in pts], **kw)
        ax[1].loglog([p["steps"] for p in pts], [p["max_error"] for p in pts], **kw)
    from matplotlib.ticker import NullFormatter
    for a in ax:
        for t in TARGETS:
            a.axhline(t, color="0.7", lw=0.6, zorder=0)
        a.xaxis.set_minor_formatter(NullFormatter())
    ax[0].set_xlabel("CPU time of the solving thread (s)")
    ax[0].set_ylabel("max |q - q_ref| over 20 samples")
    ax[0].set_title(f"{case}: what accuracy costs (index-3 DAE)")
    ax[1].set_xlabel("steps taken")
    ax[1].set_title("error against steps (dashed: error-controlled)")
    ax[1].legend(fontsize=7)
    return plotting.save(fig, out, f"work_precision_scene_{slug}")


SCENE_CAPTION = (
    "{case}, index-3 DAE. Left: the largest coordinate error against the solving thread's CPU "
    "time, one curve per method (solid: fixed step, swept over the step count; dashed: "
    "error-controlled, swept over rtol); right: the same error against the steps taken. Grey "
    "lines: the target errors 1e-2..1e-8. Read: at a target, the leftmost curve on the left is "
    "the cheapest method (the table 'cheapest method per target' gives it); on the right the "
    "slope of a fixed-step curve is its order.")
PROBLEM_CAPTION = (
    "{problem}: every fixed-step ODE method over a step sweep. Left: the largest error over "
    "the interval against the kernel loop's CPU time; right: against h (solid: explicit "
    "Runge-Kutta, dash-dot: Euler-Cromer, dashed: implicit multistep). Read: lower-left is "
    "better on the left (the cheapest method for an accuracy is the leftmost at that height); "
    "on the right a curve's slope is the method's observed order.")


def cheapest_finding(best: list[dict], target: float) -> str:
    """One line: the cheapest method per case at one target error."""
    hits = [f"{r['case']}: {r['cheapest_method']}" for r in best
            if r["target_error"] == target and r.get("cheapest_method")]
    return f"cheapest to error {target:g}: " + "; ".join(hits) if hits else ""


def run_scenes(out: Path, quick: bool) -> tuple[list, list, list]:
    cases = QUICK_SCENES if quick else SCENES
    tols = QUICK_TOLERANCES if quick else TOLERANCES
    tables, figures, best, damping = [], [], [], []
    for label, (name, t_end, counts, stiff) in cases.items():
        progress(f"work-precision on the index-3 DAE: {label}")
        rows, floor, ref_kind = scene_rows(label, name, t_end, counts, tols)
        slug = name
        figures.append({"path": scene_figure(label, rows, out, slug),
                        "caption": SCENE_CAPTION.format(case=label)})
        tables.append(write_table(
            rows, ["scene", "method", "h", "rtol", "steps", "max_error", "observed_order",
                   "cpu_s", "wall_s", "note"], out, f"work_precision_scene_{slug}",
            f"Work-precision on the index-3 DAE: {label}, {t_end:g} s",
            f"Reference: {ref_kind}"
            + (f" (its difference from bdf at rtol 1e-12: {floor:.1e})" if floor else "")
            + "; cpu_s: the solving thread's CPU time, the least of three runs under 50 ms; "
              "wall_s beside it."))
        best += cheapest_rows(label, rows, floor)
        damping += damping_rows(rows, stiff)
    sentence = damping_sentence(damping)
    tables.insert(0, write_table(
        best, ["case", "target_error", "cheapest_method", "cpu_s", "how", "its runs stopped",
               "runner_up", "runner_up_cpu_s", "runner_up / cheapest", "note"], out,
        "work_precision_scene_cheapest",
        "Cheapest method per target error on the index-3 DAE of mechanisms",
        "The least CPU time at which each method's curve reaches the target, interpolated "
        "linearly in log(cpu) against log(error) between neighbouring runs of its sweep "
        "('interpolated'), or a run's own ('measured'; 'first run': the sweep's coarsest "
        "reached it, so the cost is at most this); never extrapolated. " + sentence))
    tables.insert(1, write_table(
        damping, ["scene", "stiff", "method", "median error ratio", "min", "max",
                  "steps compared", "ratio at the finest h", "finest h"], out,
        "work_precision_scene_damping",
        "What numerical damping costs: error over the trapezoidal rule's at the same h",
        sentence))
    return tables, figures, best


def run(out: Path, quick: bool = False) -> dict:
    out = Path(out)
    gs = grids(quick)
    workers = study_workers()
    progress(f"work-precision sweep: {len(gs)} problems on "
             f"{f'{workers} local workers' if workers else 'this process'}")
    result = sweep(gs, workers=workers)
    every = table_rows(result.rows)
    tables, figures, best = [], [], []
    for g in gs:
        p = g["problems"][0]
        rows = [r for r in every if r["problem"] == p]
        figures.append({"path": figure(p, rows, out),
                        "caption": PROBLEM_CAPTION.format(problem=p)})
        tables.append(write_table(rows, list(rows[0]), out, f"work_precision_{p}",
                                  f"Work-precision: {p}",
                                  f"{len(result.rows)} runs of one sweep on {result.engine}; "
                                  "cpu_s and wall_s: the solving thread's CPU time and the "
                                  "wall time of the kernel call, per run"))
        best += cheapest_rows(p, rows)
    tables.insert(0, write_table(
        best, ["case", "target_error", "cheapest_method", "cpu_s", "how", "runner_up",
               "runner_up_cpu_s", "runner_up / cheapest", "note"], out,
        "work_precision_cheapest", "Cheapest method per target error (chapter-4 problems)",
        "The least CPU time at which each method's curve reaches the target, interpolated "
        "linearly in log(cpu) against log(error) between neighbouring swept steps, or a run's "
        "own; never extrapolated: a finer sweep moves the numbers, rarely the ranking."))
    scene_tables, scene_figures, scene_best = run_scenes(out, quick)
    found = [f for f in (cheapest_finding(scene_best, 1e-6), cheapest_finding(best, 1e-6)) if f]
    return {"title": "What accuracy costs in time", "tables": scene_tables + tables,
            "figures": scene_figures + figures, "findings": found}


if __name__ == "__main__":
    raise SystemExit(main(run, "work_precision"))
