"""Spatial scenes (Fekete (2023) chapter 5): accuracy and CPU time of each
formulation and method on the heavy top and on the double pendulum built from spatial bodies,
the quaternion norm by the user's choice, and what a spatial body costs beside a planar one.

1. Formulations. The scene heavy_top (a spherical joint to the ground) and the scene
   spatial_double_pendulum (two spherical joints), over 2 s, by rk4 at two steps and by dopri54
   and bdf at two tolerances, each on the reduced, baumgarte (alpha = 1/h, beta = sqrt(2)/h;
   for the error-controlled methods 1/(1 ms) and sqrt(2)/(1 ms)), penalty (Jalon-Bayo, the
   defaults alpha_p = 1e7, omega_p = 10, mu_p = 1) and projection formulations, and bdf also
   on the DAE itself (formulation i3, as GSTIFF I3, and si2, the stabilised index-2 form);
   trapezoidal_index3 at the rk4
   steps (the one integrator of planar and spatial scenes, augmented Lagrangian with the
   projections of v and a, its Jacobian by differences here; second order); ida (SUNDIALS) on the DAE itself in its index1 and GGL forms.
   Baumgarte's gains of order 1/h make the constraint's own error dynamics as fast as the step,
   which rk4 then does not resolve: its forces of beta^2 Phi perturb the motion far more than
   the reduced form's drift does (the same holds on planar scenes, studies/scene_drift.py).
   The error is the largest state difference at the samples (every 10 ms) against a reference:
   the compiled problem heavy_top (Euler's equations in quaternions with the tip fixed, rk4 at
   h = 1e-5) for the top, the planar double pendulum scene (rk4, reduced, h = 1e-5) for the
   spatial one; beside it the steps, the solving thread's CPU time, max |Phi| and max ||p| - 1|.
2. The quaternion norm. free_body (the intermediate-axis flip) by explicit Euler, heun and rk4
   with |p| kept by projection, by the stabilisation term (norm_gain 10 1/s) and not at all:
   the largest ||p| - 1| and of |R^T R - I| over 10 s. R is formed from p / |p|, so the state's
   drift of |p| never scales the body; the study shows how large it grows. The stabilised norm
   settles at 1 - O(h^p), whatever the gain: the method's stages evaluate the term off the
   sphere (Heun's predictor has |p|^2 = 1 + h^2 |Omega|^2 / 4), which pulls every step inward
   by as much as the gain pushes back (Heun: -h^2 |Omega|^2 / 16); so for Heun and rk4 the
   stabilisation leaves |p| further from 1 than no treatment at all, and projection is the one
   that keeps it at roundoff.
3. Two IFToMM benchmark mechanisms (the scenes bricard and flyball_governor; their files give
   the geometry and where it comes from; the benchmark's own reference values were not
   available to us, so the references here are our own tightest runs, which agree with an
   independent Exudyn run to a few 1e-9: tests/test_spatial.py and benchmarks/exudyn_*.py).
   Bricard's linkage (A04) has 30 joint rows of rank 29: the kernel solves the 29 found
   independent at the start (another set where those degenerate) and the watch checks all 30.
   Released from rest it swings (P3 from x = 1 to about -0.78 and back within 5 s); the runs
   cover the benchmark's 10 s (5 s in the quick report). The flyball governor (A05) is stiff: dampers of 4e4 N s/m on 5 kg balls put an
   eigenvalue near -1.3e4 1/s, so rk4 needs h < 2e-4 s while bdf takes steps of its own choice;
   the sleeve's height at the end is the benchmark's output.
4. Cost. The same double pendulum as the planar scene (3 coordinates per body, closed-form
   Schur complement) and as the spatial one (7 + 6 states per body, dense Schur complement):
   the rk4 step's CPU time of each, measured in one run. The planar path has no code in common
   with the spatial model but the integrators: a planar scene does not pay for 3D.
5. trapezoidal_index3 down to h = 1e-6 on the four built-in mechanisms: the error at t = 5 ms
   (20 ms in the full run) against dopri54 (rtol 1e-13, projection), its ratio to the next
   larger h's (16 for second order at a quarter of h), Newton iterations per step and the CPU
   time. Newton stops at a hundredth of each step's local error estimate, or at its roundoff
   floor (kernel/src/dae/mbdk_trapezoidal_index3.f90): the order holds until the roundoff
   plateau, where it used to stop with NewtonDivergedError below h = 2e-4 (on some BLAS
   kernels at 3.125e-4). Also as a figure, error against h and against CPU time.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import main, progress  # noqa: E402

import mbdk  # noqa: E402
from mbdk.analysis.tables import write_table  # noqa: E402

FORMULATIONS = ("reduced", "baumgarte", "penalty", "projection")
T_END = 2.0


def top_reference(sc):
    b = sc.bodies[0]
    q0 = mbdk.rotations.to_quaternion(b.rotation)
    r = mbdk.solve_ode("heavy_top", "rk4", h=1e-5, t_end=T_END, every=1000,
                       y0=[*q0, *b.omega_body],
                       params=dict(J1=0.015, J2=0.015, J3=0.01, m=1.0, g=9.81, l=0.1))
    return r.y          # [q, Omega]: compared with the scene's [p, Omega]


def top_error(r, ref):
    return float(max(np.abs(r.q[:, 3:7] - ref[:, :4]).max(),
                     np.abs(r.v[:, 3:6] - ref[:, 4:]).max()))


def pendulum_setup():
    planar = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-5, t_end=T_END,
                           every=1000)
    sc = mbdk.scene("spatial_double_pendulum")
    for k, b in enumerate(sc.bodies):   # the planar run's assembled start
        x, y, a = planar.q[0, 3 * k:3 * k + 3]
        b.position = np.array([x, y, 0.0])
        b.rotation = mbdk.rotations.from_angles([0.0, 0.0, a], "123")
    return sc, planar


def pendulum_error(r, planar):
    err = 0.0
    for k, name in enumerate(("bar1", "bar2")):
        rot = r.orientation(name)
        ang = np.unwrap(np.arctan2(rot[:, 1, 0], rot[:, 0, 0]))
        err = max(err, np.abs(ang - planar.q[:, 3 * k + 2]).max(),
                  np.abs(r.position(name)[:, :2] - planar.q[:, 3 * k:3 * k + 2]).max())
    return float(err)


def runs(quick: bool):
    steps = (2e-3, 1e-3) if quick else (2e-3, 1e-3, 5e-4)
    tols = (1e-6, 1e-9)
    for m in ("rk4", "trapezoidal_index3"):
        for h in steps:
            yield m, {"h": h, "every": int(round(0.01 / h))}, f"h = {h:g}"
    for m in ("dopri54", "bdf", "ida"):
        for tol in tols:
            yield m, {"rtol": tol, "atol": tol * 1e-2, "dt_out": 0.01,
                      "alpha": 1e3, "beta": 2 ** 0.5 * 1e3}, f"rtol = {tol:g}"


def run_case(sc, scene_name, method, kw, control, form, t_end, measure):
    """One run of the tables: a row with its status, and if it succeeded, measure(r)'s fields
    beside the steps and the solving thread's CPU time. Baumgarte's alpha and beta are given to
    the error-controlled methods only (rk4 takes its default, 1/h and sqrt(2)/h)."""
    args = dict(kw)
    if form != "baumgarte" or method == "rk4":
        args.pop("alpha", None)
        args.pop("beta", None)
    progress(f"{scene_name} {method} {control} {form}")
    row = {"scene": scene_name, "method": method, "control": control, "formulation": form}
    try:
        r = mbdk.simulate(sc, method, t_end=t_end, formulation=form, **args)
    except mbdk.MbdkError as exc:
        return {**row, "status": type(exc).__name__}
    return {**row, "status": "ok", "steps": r.stats.steps, "cpu_ms": 1e3 * r.cpu_time,
            "max_abs_phi": float(r.residuals[:, 0].max()), **measure(r)}


def formulation_rows(quick: bool) -> list[dict]:
    rows = []
    top = mbdk.scene("heavy_top")
    top_ref = top_reference(top)
    pend, planar = pendulum_setup()
    for scene_name, sc, err_fn, ref in (("heavy_top", top, top_error, top_ref),
                                        ("spatial_double_pendulum", pend, pendulum_error,
                                         planar)):
        for method, kw, control in runs(quick):
            # bdf also integrates the index-3 DAE itself; trapezoidal_index3 has its projected
            # form only
            forms = (("augmented_lagrangian",) if method == "trapezoidal_index3" else
                     ("index1", "ggl") if method == "ida" else
                     FORMULATIONS + (("i3", "si2") if method == "bdf" else ()))
            for form in forms:
                rows.append(run_case(
                    sc, scene_name, method, kw, control, form, T_END,
                    lambda r: {"error": err_fn(r, ref),
                               "max_norm_drift": float(r.residuals[:, 2].max())}))
    return rows


def norm_rows(quick: bool) -> list[dict]:
    rows = []
    t_end = 5.0 if quick else 10.0
    for method, h in (("explicit_euler", 1e-3), ("heun", 1e-3), ("rk4", 1e-2)):
        for norm in ("project", "stabilise", "none"):
            sc = mbdk.scene("free_body")
            sc.quaternion_norm = norm
            r = mbdk.simulate(sc, method, h=h, t_end=t_end, every=max(1, int(0.05 / h)),
                              watch=False)
            p = r.q[:, 3:7]
            rot = np.array([mbdk.rotations.from_quaternion(x / np.linalg.norm(x)) for x in p])
            orth = np.abs(np.einsum("kji,kjl->kil", rot, rot) - np.eye(3)).max()
            rows.append({"method": method, "h": h, "quaternion_norm": norm,
                         "max_norm_drift": float(r.residuals[:, 2].max()),
                         "max_RtR_minus_I": float(orth),
                         "energy_rel_error": float(np.abs(r.energy / r.energy[0] - 1).max()),
                         "cpu_ms": 1e3 * r.cpu_time})
    return rows


def cost_rows(quick: bool) -> list[dict]:
    n = 2000 if quick else 20000
    h = 1e-4
    pend, _ = pendulum_setup()
    best = {}
    for _ in range(5):   # the least of five, the two taken in turn
        for name, sc in (("planar scene double_pendulum", mbdk.scene("double_pendulum")),
                         ("spatial scene spatial_double_pendulum", pend)):
            r = mbdk.simulate(sc, "rk4", h=h, t_end=n * h, every=n, watch=False)
            best[name] = min(best.get(name, np.inf), r.cpu_time / n)
    planar = best["planar scene double_pendulum"]
    return [{"scene": k, "states": 6 if k.startswith("planar") else 26,
             "us_per_rk4_step": 1e6 * v, "ratio_to_planar": v / planar}
            for k, v in best.items()]


def benchmark_rows(quick: bool) -> list[dict]:
    from mbdk.spatial_model import evaluate_spatial
    rows = []
    sc = mbdk.scene("bricard")
    rank = evaluate_spatial(sc)["rank"]
    t_end = 2.0 if quick else 10.0
    ref = mbdk.simulate(sc, "dopri54", rtol=1e-12, atol=1e-14, t_end=t_end,
                        formulation="projection")
    cases = [("rk4", {"h": h, "every": int(round(t_end / h))}, f"h = {h:g}")
             for h in ((4e-3, 1e-3) if quick else (4e-3, 2e-3, 1e-3))]
    # the error-controlled runs are capped: Baumgarte's gains of 1e3 1/s make the explicit pair
    # take steps of a millisecond, which at tight tolerances would dominate the study's time
    cases += [(m, {"rtol": tol, "atol": tol * 1e-2, "alpha": 1e3, "beta": 2 ** 0.5 * 1e3,
                   "max_steps": 4000 if quick else 20000},
               f"rtol = {tol:g}") for m in ("dopri54", "bdf") for tol in (1e-6, 1e-9)]
    cases += [("trapezoidal_index3", {"h": h, "every": int(round(t_end / h))}, f"h = {h:g}")
              for h in ((4e-3,) if quick else (4e-3, 2e-3))]
    cases += [("ida", {"rtol": tol, "atol": tol * 1e-2}, f"rtol = {tol:g}")
              for tol in (1e-6, 1e-9)]
    for method, kw, control in cases:
        for form in (("augmented_lagrangian",) if method == "trapezoidal_index3" else
                     ("index1", "ggl") if method == "ida" else FORMULATIONS):
            rows.append(run_case(
                sc, "bricard", method, kw, control, form, t_end,
                lambda r: {"error": float(np.abs(r.q[-1] - ref.q[-1]).max()),
                           "energy_error": float(np.abs(r.energy - r.energy[0]).max()),
                           "output": float(r.position("rod2")[-1, 0] + (
                               r.orientation("rod2")[-1] @ [0.0, -0.5, 0.0])[0])}))
    p3 = ref.position("rod2")[-1] + ref.orientation("rod2")[-1] @ [0.0, -0.5, 0.0]
    notes_b = (f"bricard: rank {rank} of {sc.rows} rows; from rest, {t_end:g} s; the "
               "error-controlled runs stop at 4000 steps (quick) or 20 000 (TooManyStepsError "
               "in the table); error: "
               "max |q - q_ref| at the end against dopri54 (rtol 1e-12, projection), whose P3 "
               f"(rod2's far end, initially (1, -1, 0)) ends at ({p3[0]:.8f}, {p3[1]:.8f}, "
               f"{p3[2]:.8f}); output: P3's x at the end")
    fly = mbdk.scene("flyball_governor")
    t_fly = 0.5 if quick else 2.0
    ref = mbdk.simulate(fly, "bdf", rtol=1e-11, atol=1e-13, t_end=t_fly,
                        formulation="projection")
    s_ref = float(ref.position("slider")[-1, 2])
    cases = [("bdf", {"rtol": tol, "atol": tol * 1e-2}, f"rtol = {tol:g}")
             for tol in (1e-6, 1e-8)]
    cases += [("cvode_bdf", {"rtol": tol, "atol": tol * 1e-2}, f"rtol = {tol:g}")
              for tol in (1e-6, 1e-8)]
    cases += [("ida", {"rtol": tol, "atol": tol * 1e-2}, f"rtol = {tol:g}")
              for tol in (1e-6, 1e-8)]
    if not quick:
        cases.append(("rk4", {"h": 1e-4, "every": int(round(t_fly / 1e-4))}, "h = 1e-4"))
    for method, kw, control in cases:
        for form in (("index1", "ggl") if method == "ida" else ("reduced", "projection")):
            if method.startswith("cvode") and form == "projection":
                continue
            sc_f = mbdk.scene("flyball_governor")
            if method.startswith("cvode"):
                sc_f.quaternion_norm = "stabilise"
            rows.append(run_case(
                sc_f, "flyball_governor", method, kw, control, form, t_fly,
                lambda r: {"error": abs(float(r.position("slider")[-1, 2]) - s_ref),
                           "output": float(r.position("slider")[-1, 2])}))
    notes_f = (f"flyball_governor: {t_fly:g} s; output: the sleeve's height s at the end "
               f"(reference {s_ref:.10f} m from bdf at rtol 1e-11, projection); error: "
               "|s - s_ref|; cvode_bdf runs with quaternion_norm = 'stabilise' (CVODE cannot "
               "project between its steps); energy is not conserved (dampers)")
    return rows, notes_b + ". " + notes_f


def joint_rows(quick: bool) -> tuple[list[dict], str]:
    """The two IFToMM mechanisms in joint and in absolute coordinates: the same methods and
    steps, error against each mechanism's reference, steps and CPU time."""
    rows = []
    t_b = 2.0 if quick else 10.0
    scenes = {"bricard": (t_b, lambda r: r.q[-1]), "flyball_governor": (0.5, lambda r: r.q[-1])}
    for name, (t_end, final) in scenes.items():
        sc = mbdk.scene(name)
        ref = final(mbdk.simulate(sc, "dopri54", rtol=1e-12, atol=1e-14, t_end=t_end,
                                  dt_out=t_end, formulation="projection"))
        hs = (8e-3, 4e-3) if name == "bricard" else (1e-4, 5e-5)
        cases = [("rk4", {"h": h, "every": int(round(t_end / h))}, f"h = {h:g}") for h in hs]
        cases += [("dopri54", {"rtol": tol, "atol": tol * 1e-2, "dt_out": t_end},
                   f"rtol = {tol:g}") for tol in (1e-6, 1e-9)]
        for method, kw, control in cases:
            for coords in ("absolute", "joint"):
                progress(f"{name} {method} {control} {coords}")
                row = {"scene": name, "method": method, "control": control,
                       "coordinates": coords}
                try:
                    r = mbdk.simulate(sc, method, t_end=t_end, coordinates=coords, **kw)
                except mbdk.MbdkError as exc:
                    rows.append({**row, "status": type(exc).__name__})
                    continue
                rows.append({**row, "status": "ok", "steps": r.stats.steps,
                             "error": float(np.abs(final(r) - ref).max()),
                             "cpu_ms": 1e3 * r.cpu_time,
                             "max_abs_phi": float(r.residuals[:, 0].max())})
    notes = (f"bricard over {t_b:g} s, flyball_governor over 0.5 s, reduced formulation; "
             "error: max |q - q_ref| at the end (q the bodies' absolute coordinates, which a "
             "joint run samples too) against dopri54 at rtol 1e-12 on the projection form; "
             "max_abs_phi: the largest residual of any joint's rows at the samples (in joint "
             "coordinates only Bricard's cut joint F can drift); cpu_ms: the solving thread's "
             "CPU time, samples and outputs included")
    return rows, notes


def small_step_rows(quick: bool) -> tuple[list[dict], float]:
    """Section 5: trapezoidal_index3 from h = 1e-2 to 1e-6 (quick: to 1e-5)."""
    t_end = 0.005 if quick else 0.02
    steps = [1e-2 / 4 ** k for k in range(5)] + [1e-5, 3e-6, 1e-6]
    if quick:
        steps = [h for h in steps if h >= 1e-5]
    rows = []
    for name in ("heavy_top", "spatial_double_pendulum", "bricard", "flyball_governor"):
        sc = mbdk.scene(name)
        ref = mbdk.simulate(sc, "dopri54", formulation="projection", rtol=1e-13, atol=1e-15,
                            t_end=t_end, dt_out=t_end)
        prev = None
        for h in steps:
            n = max(1, int(round(t_end / h)))
            row = {"scene": name, "h": t_end / n, "steps": n}
            try:
                r = mbdk.simulate(sc, "trapezoidal_index3", h=t_end / n, t_end=t_end, every=n,
                                  outputs=())
            except mbdk.MbdkError as exc:
                rows.append({**row, "status": type(exc).__name__})
                prev = None
                continue
            err = float(max(np.abs(r.q[-1] - ref.q[-1]).max(),
                            np.abs(r.v[-1] - ref.v[-1]).max()))
            rows.append({**row, "status": "ok", "error": err,
                         "ratio": prev[1] / err if prev else None,
                         "order": (float(np.log(prev[1] / err) / np.log(prev[0] / row["h"]))
                                   if prev else None),
                         "newton_per_step": r.stats.newton_iterations / r.stats.steps,
                         "njev": r.stats.njev, "cpu_ms": 1e3 * r.cpu_time})
            prev = (row["h"], err)
    return rows, t_end


def run(out: Path, quick: bool = False) -> dict:
    out = Path(out)
    progress("formulations")
    f_rows = formulation_rows(quick)
    tables = [write_table(
        f_rows, ["scene", "method", "control", "formulation", "status", "error", "steps",
                 "cpu_ms", "max_abs_phi", "max_norm_drift"], out, "spatial_formulations",
        "Spatial scenes: error, steps and CPU time per method and formulation",
        "error: the largest difference at the samples from the compiled heavy_top (rk4, "
        "h = 1e-5) or from the planar double pendulum scene (rk4, h = 1e-5); cpu_ms: the "
        "solving thread's CPU time; max_norm_drift: ||p| - 1| (quaternion_norm = project)")]
    progress("quaternion norm")
    tables.append(write_table(
        norm_rows(quick), ["method", "h", "quaternion_norm", "max_norm_drift",
                           "max_RtR_minus_I", "energy_rel_error", "cpu_ms"],
        out, "spatial_quaternion_norm",
        "The quaternion's norm on free_body, kept by projection, by stabilisation or not at all",
        "max_RtR_minus_I: of R formed from p / |p|, at roundoff whatever |p| does"))
    progress("IFToMM mechanisms")
    b_rows, b_notes = benchmark_rows(quick)
    tables.append(write_table(
        b_rows, ["scene", "method", "control", "formulation", "status", "error", "steps",
                 "cpu_ms", "max_abs_phi", "energy_error", "output"], out,
        "spatial_benchmarks",
        "IFToMM A04 (Bricard, redundant) and A05 (stiff flyball governor): accuracy and CPU "
        "time per method and formulation", b_notes))
    progress("joint coordinates")
    j_rows, j_notes = joint_rows(quick)
    tables.append(write_table(
        j_rows, ["scene", "method", "control", "coordinates", "status", "error", "steps",
                 "cpu_ms", "max_abs_phi"], out, "spatial_joint_coordinates",
        "IFToMM A04 and A05 in joint coordinates (a spanning tree's turns and slides) and in "
        "absolute coordinates: accuracy and CPU time", j_notes))
    progress("cost against the planar scene")
    tables.append(write_table(
        cost_rows(quick), ["scene", "states", "us_per_rk4_step", "ratio_to_planar"], out,
        "spatial_cost", "The double pendulum as a planar and as a spatial scene: rk4 step",
        "thread CPU time per step, the least of five runs taken in turn"))
    from mbdk.analysis import plotting
    fig, axes = plotting.plt.subplots(1, 2, figsize=(10, 4))
    for ax, scene_name in zip(axes, ("heavy_top", "spatial_double_pendulum")):
        for form, marker in zip(FORMULATIONS, "osd^"):
            for method, ls in (("rk4", "-"), ("dopri54", "--"), ("bdf", ":")):
                pts = [(r["cpu_ms"], r["error"]) for r in f_rows
                       if r["scene"] == scene_name and r["formulation"] == form
                       and r["method"] == method and r["status"] == "ok"]
                if pts:
                    x, y = zip(*sorted(pts))
                    ax.loglog(x, y, ls, marker=marker, label=f"{method} {form}", ms=4)
        ax.set_xlabel("CPU time [ms]")
        ax.set_ylabel("max error")
        ax.set_title(scene_name)
    axes[0].legend(fontsize=7)
    figs = [plotting.save(fig, out, "spatial_work_precision")]
    progress("trapezoidal_index3 down to h = 1e-6")
    s_rows, s_t = small_step_rows(quick)
    tables.append(write_table(
        s_rows, ["scene", "h", "steps", "status", "error", "ratio", "order",
                 "newton_per_step", "njev", "cpu_ms"], out, "spatial_index3_small_steps",
        f"trapezoidal_index3 down to h = {min(r['h'] for r in s_rows):g}: second order to the "
        "roundoff plateau", f"error: max |y - y_ref| at t = {s_t:g} s against dopri54 (rtol "
        "1e-13, projection); ratio: the error of the next larger h over this one's; order: "
        "log(ratio) / log(h ratio); cpu_ms: the solving thread's CPU time"))
    fig, axes = plotting.plt.subplots(1, 2, figsize=(10, 4))
    for name in dict.fromkeys(r["scene"] for r in s_rows):
        pts = [(r["h"], r["error"], r["cpu_ms"]) for r in s_rows
               if r["scene"] == name and r["status"] == "ok" and r["error"] > 0]
        if pts:
            h, e, c = zip(*pts)
            axes[0].loglog(h, e, "o-", ms=4, label=name)
            axes[1].loglog(c, e, "o-", ms=4, label=name)
    axes[0].set_xlabel("h [s]")
    axes[1].set_xlabel("CPU time [ms]")
    for ax in axes:
        ax.set_ylabel(f"max error at t = {s_t:g} s")
    axes[0].set_title("trapezoidal_index3: error against h")
    axes[1].set_title("error against CPU time")
    axes[0].legend(fontsize=7)
    figs.append(plotting.save(fig, out, "spatial_index3_small_steps"))
    caps = [
        "The heavy top (left) and the spatial double pendulum (right): the largest error "
        "against the CPU time, one marker per formulation and one line style per method "
        "(solid rk4, dashed dopri54, dotted bdf). Read: at a given error the leftmost curve "
        "is the cheapest formulation and method; a missing curve is a run that stopped (the "
        "table says why).",
        "trapezoidal_index3 on the spatial scenes down to very small steps: the error against "
        "h (left) and against the CPU time (right). Read: a slope of 2 on the left is second "
        "order; where the curve turns flat it has reached roundoff, and smaller steps only "
        "cost time."]
    return {"title": "Spatial scenes: formulations, the quaternion norm, cost", "tables": tables,
            "figures": [{"path": f, "caption": c} for f, c in zip(figs, caps)]}


if __name__ == "__main__":
    sys.exit(main(run, "spatial_scenes"))
