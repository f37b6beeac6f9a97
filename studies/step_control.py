"""What step-size control can save on trapezoidal_index3, and what it does save: the steps and
CPU time the best fixed step and the error-controlled runs need for a target error at t_end, and
the bound on the saving that no distribution of second order steps can beat.

For each case (the double pendulum P1 over 10 s, the four-bar released from 60 deg over 5 s, the
spring-damper bar over 2 s, and the same with a spring a hundred times stiffer), the error is
the largest difference of the coordinates at t_end from a reference (the same method at h_ref
and h_ref / 2, Richardson-extrapolated for its order 2). The fixed step is the largest on a grid
h0 2^(-k/4) that reaches the target; the error-controlled runs the loosest tolerance (err_rtol =
err_atol) on a grid 10^(-k/4) that does: adaptive="estimated" (one step, its error estimated
from differences of the accelerations; second order) and adaptive="extrapolated" (the default of
adaptive=True: a macro step of one step of H and two of H/2, locally Richardson-extrapolated,
third order, PI control). The extrapolated run's cost is counted in trapezoidal solves (three
per macro step tried) beside its macro steps, against the fixed step's steps (one solve each).

The bound: a second-order method's local error is about h^3 |q'''| / 12 per step. Where those
errors add up without amplification, the steps that reach a global error E fall with h(t) ~
|q'''(t)|^(-1/3) (the optimum of N = int dt / h under int h^2 |q'''| dt = const), and

    N_opt / N_fixed = (int |q'''|^(1/3) dt)^(3/2) / (T (int |q'''| dt)^(1/2))  <= 1

(Hoelder): 1 for a motion equally hard everywhere, small where the hard part is short. It is
computed from q''' of the reference run (its accelerations, differenced). A controller that
keeps the local error per step at a tolerance approaches this optimum; no controller of local
errors can beat it by much on a problem whose errors add up (on a chaotic one, where early
errors grow, it does worse than the bound).

What pays instead is order: the extrapolated macro step, and in the last columns bdf on the
scene's DAE itself (variable step and order 1-5, as MSC Adams' GSTIFF), on the index-3 form (i3)
and on the stabilised index-2 form (si2), at the loosest rtol (atol = rtol/100) on the same grid
that reaches the target, with their steps and CPU time beside the fixed-step trapezoidal rule's.
The trapezoidal rule with a variable step also loses its symmetry: its energy error, bounded at
a fixed step, drifts, and on the four-bar the phase error that follows makes the estimated run
take more steps than the fixed one (time-reversible step selection, Hairer and Soederlind 2005,
is the known remedy for a second order controller; it is not built, as the bound caps what it
could gain).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import main, progress  # noqa: E402

import mbdk  # noqa: E402
from mbdk.analysis.tables import write_table  # noqa: E402

#: case name, scene, t_end, first fixed step h0, reference step h_ref, spring stiffness (None:
#: the scene's)
CASES = [("double_pendulum (P1)", "double_pendulum", 10.0, 1e-3, 2.5e-5, None),
         ("four_bar", "four_bar", 5.0, 1e-2, 2.5e-5, None),
         ("spring_damper_bar", "spring_damper_bar", 2.0, 1e-2, 1e-5, None),
         # a hundred times the spring, lightly damped: sqrt(3 k) = 245 rad/s at the start (the
         # spring stands across the bar's tip, I = m l^2 / 3 about the hinge) against 24
         ("spring_damper_bar, k = 2e4", "spring_damper_bar", 2.0, 1e-3, 1e-5, 2e4)]


def case_scene(name, stiffness):
    sc = mbdk.scene(name)
    if stiffness is not None:
        for f in sc.forces:
            if f.type == "spring":
                f.stiffness = stiffness
    return sc


def final_q(sc, t_end, **kw):
    # coarse steps may leave the energy balance: the sweep measures their error instead
    r = mbdk.simulate(sc, "trapezoidal_index3", t_end=t_end, outputs=(), watch=False,
                      raise_on_failure=False, **kw)
    if r.status < 0 or not len(r.t) or abs(r.t[-1] - t_end) > 1e-9:
        return np.full(r.q.shape[1], np.inf), r
    return r.q[-1], r


def least_cpu(run, first) -> float:
    """The least CPU time of first and two more runs of the same configuration: on a shared
    machine one run's time varies by up to twofold (the runs are deterministic, so only their
    time differs)."""
    return min([first.cpu_time] + [run().cpu_time for _ in range(2)])


def solves(r) -> int:
    """Trapezoidal steps an extrapolated run solved, at most: three per macro step accepted or
    rejected (one of H, two of H/2) and three per Newton failure (the failed solve and up to two
    before it in its macro step)."""
    return 3 * (r.stats.steps + r.stats.rejected_steps + r.stats.newton_failures)


def bound_ratio(sc, t_end, h):
    """N_opt / N_fixed from q''' of a fixed-step run at step h (module header)."""
    r = mbdk.simulate(sc, "trapezoidal_index3", h=h, t_end=t_end, every=1, outputs=("a",))
    w = np.max(np.abs(np.gradient(r.a, h, axis=0)), axis=1)
    return float(np.sum(w ** (1 / 3) * h) ** 1.5 / (t_end * np.sqrt(np.sum(w * h)))), r.t, w


def controlled(sc, t_end, qref, target, mode, h0):
    """(tol, steps, error, CPU s, rejected steps, solves) of the adaptive mode at the loosest
    err_rtol = err_atol on 10^(-k/4) that reaches target at t_end, or None."""
    for k in range(4, 48):
        tol = 10.0 ** (-k / 4)
        q, r = final_q(sc, t_end, adaptive=mode, h=h0, err_rtol=tol, err_atol=tol,
                       dt_out=t_end)
        err = float(np.max(np.abs(q - qref)))
        if err <= target:
            cpu = least_cpu(lambda: final_q(sc, t_end, adaptive=mode, h=h0, err_rtol=tol,
                                            err_atol=tol, dt_out=t_end)[1], r)
            return tol, r.stats.steps, err, cpu, r.stats.rejected_steps, solves(r)
    return None


def variable_order(sc, t_end, qref, target, form):
    """(rtol, steps, error, CPU s) of bdf on the DAE form at the loosest rtol on 10^(-k/4) that
    reaches target at t_end, or None."""
    for k in range(12, 52):
        tol = 10.0 ** (-k / 4)
        try:
            r = mbdk.simulate(sc, "bdf", formulation=form, rtol=tol, atol=tol * 1e-2,
                              t_end=t_end, outputs=(), watch=False)
        except mbdk.MbdkError:
            continue
        err = float(np.max(np.abs(r.q[-1] - qref)))
        if err <= target:
            cpu = least_cpu(lambda: mbdk.simulate(sc, "bdf", formulation=form, rtol=tol,
                                                  atol=tol * 1e-2, t_end=t_end, outputs=(),
                                                  watch=False), r)
            return tol, r.stats.steps, err, cpu
    return None


def run(out: Path, quick: bool = False) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    target = 1e-4 if quick else 1e-6
    cases = CASES[1:2] if quick else CASES
    rows, figs, series = [], [], []
    for label, name, t_end, h0, h_ref, stiffness in cases:
        sc = case_scene(name, stiffness)
        if quick:
            t_end, h_ref = 1.0, 1e-4
        progress(f"{label}: reference")
        q1, _ = final_q(sc, t_end, h=h_ref, every=round(t_end / h_ref))
        q2, _ = final_q(sc, t_end, h=2 * h_ref, every=round(t_end / (2 * h_ref)))
        qref = q1 + (q1 - q2) / 3.0
        fixed = None
        for k in range(40):
            h = h0 * 2.0 ** (-k / 4)
            q, r = final_q(sc, t_end, h=h, every=max(1, round(t_end / h)))
            err = float(np.max(np.abs(q - qref)))
            if err <= target:
                cpu = least_cpu(lambda: final_q(sc, t_end, h=h,
                                                every=max(1, round(t_end / h)))[1], r)
                fixed = (h, r.stats.steps, err, cpu)
                break
        progress(f"{label}: estimated error control")
        adapt = controlled(sc, t_end, qref, target, "estimated", h0 / 10)
        progress(f"{label}: extrapolated error control")
        extra = controlled(sc, t_end, qref, target, "extrapolated", h0 / 10)
        progress(f"{label}: bdf on the DAE")
        vo = {form: variable_order(sc, t_end, qref, target, form) for form in ("i3", "si2")}
        ratio, tw, w = bound_ratio(sc, t_end, h_ref * 4)
        series.append((label, tw, w))
        row = {"case": label, "t_end": t_end, "target": target,
               "fixed h": fixed and fixed[0], "fixed steps": fixed and fixed[1],
               "fixed error": fixed and fixed[2],
               "fixed ms": fixed and 1e3 * fixed[3],
               "estimated tol": adapt and adapt[0], "estimated steps": adapt and adapt[1],
               "rejected": adapt and adapt[4], "estimated error": adapt and adapt[2],
               "estimated ms": adapt and 1e3 * adapt[3],
               "estimated steps / fixed": (adapt[1] / fixed[1]) if fixed and adapt else None,
               "bound N_opt/N_fixed": ratio,
               "extrapolated tol": extra and extra[0],
               "extrapolated steps": extra and extra[1],
               "extrapolated solves": extra and extra[5],
               "extrapolated error": extra and extra[2],
               "extrapolated ms": extra and 1e3 * extra[3],
               "extrapolated solves / fixed": (extra[5] / fixed[1]) if fixed and extra
               else None}
        for form, found in vo.items():
            row[f"bdf {form} rtol"] = found and found[0]
            row[f"bdf {form} steps"] = found and found[1]
            row[f"bdf {form} ms"] = found and 1e3 * found[3]
            row[f"bdf {form} steps / fixed"] = (found[1] / fixed[1]) if found and fixed else None
        rows.append(row)
    cols = list(rows[0].keys())
    tables = [write_table(
        rows, cols, out, "step_control",
        f"trapezoidal_index3: best fixed step against error control, to {target:g} at t_end",
        "estimated: adaptive='estimated' (second order); the bound is what the best distribution "
        "of second order steps for additive local errors would give (the module header derives "
        "it); extrapolated: adaptive=True, macro steps and trapezoidal solves (three per macro "
        "step tried, an upper bound); bdf i3/si2: bdf on the DAE itself, variable step and "
        "order (the module header); ms: CPU time of the solving thread, least of 3 runs")]
    from mbdk.analysis import plotting
    fig, ax = plotting.plt.subplots(figsize=(6.4, 3.8))
    for label, tw, w in series:
        ax.semilogy(tw, w / np.max(w), lw=0.8, label=label)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("|q'''| / max |q'''|")
    ax.set_title("How evenly hard each motion is (a controller's step ~ |q'''|^(-1/3))")
    ax.legend()
    figs.append({"path": plotting.save(fig, out, "step_control_difficulty"), "caption": (
        "How hard each motion is over time: the size of the third derivative of the "
        "coordinates, scaled to its largest value (log scale); an error controller's step "
        "follows it to the power -1/3. Read: a flat curve means a fixed step is already the "
        "best distribution and control can save little; deep dips (easy stretches) are where "
        "control saves steps.")})
    saved = [f"{r['case']}: {r['estimated steps / fixed']:.2g} "
             f"(bound {r['bound N_opt/N_fixed']:.2g})" for r in rows
             if r["estimated steps / fixed"] and r["bound N_opt/N_fixed"]]
    summary = ["error control's steps over the best fixed step's: " + "; ".join(saved)]
    return {"title": "Step-size control: what it can save and what it saves", "tables": tables,
            "figures": figs, "findings": summary if saved else []}


if __name__ == "__main__":
    sys.exit(main(run, "step_control"))
