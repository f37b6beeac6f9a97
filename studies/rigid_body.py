"""The torque-free asymmetric rigid body (compiled problem free_rigid_body; Fekete (2023)
chapter 5: Euler's equations (5.1)-(5.3), the quaternion kinematics (5.73)-(5.95)): the
intermediate-axis flip, and what each integrator keeps of the invariants and of |q| = 1.

Body: principal inertias 1, 2, 3 kg m^2, spinning at 1 rad/s about the intermediate axis with a
perturbation of 0.01 rad/s about the others; it flips (Omega_2 reverses; the table's note gives
when). Over 30 s, for each method and step: the largest error of the kinetic energy and of the
space-frame angular momentum L = R(q) J Omega (both exact invariants; relative), the largest
||q| - 1| (the quaternion is not renormalised: its drift is the method's), the final-state error
against a reference (rk4 at h = 1e-4, checked against dopri54 at rtol 1e-13 in the note), the
observed order from two steps, and the CPU time.

The heavy symmetric top (compiled problem heavy_top: J1 = J2 = 0.015, J3 = 0.01 kg m^2 about
the fixed point, m g l = 0.981 N m), released at 30 deg tilt with spin w3 and no precession: it
nutates between 30 deg and a little more while its axis creeps round the vertical. Measured
from an rk4 run (h = 2e-5 s), against the classical fast-top values (Goldstein, Classical
Mechanics, 5.7; Arnold's "fast top"): nutation frequency J3 w3 / J1, mean precession rate
m g l / (J3 w3), nutation amplitude 2 J1 m g l sin(theta0) / (J3 w3)^2. These are the leading
terms in 1 / w3, so the ratios measured / classical go to 1 as the spin grows.

Gimbal lock (and switching sets): the same torque-free motion integrated in three
parametrisations, quaternions
(free_rigid_body), 3-1-3 Euler angles and 1-2-3 Cardan angles (rigid_body_angles, a' =
G_b(a)^-1 Omega), by rk4 (h = 1e-3) and dopri54 (rtol 1e-9): the body (J = 1, 2, 3) starts at
theta = 0.5 rad and turns about its x axis at 1 rad/s with Omega_y = e, so that theta passes
pi within about e: the 3-1-3 rates peak like e / sin(theta) there. Per e: the closest approach
to each sequence's lock, the steps, CPU time and final orientation error (max |R - R_ref|,
against dopri54 at rtol 1e-12 on quaternions) of each. At e = 0 the motion crosses the lock
exactly, where the 3-1-3 rates are 0 / 0: a run stops with SingularMatrixError only if a stage
lands within MBDK_GIMBAL_TOL of it. Beside them, the body as a spatial scene in 3-1-3 angles
that switches to 1-2-3 angles within |sin theta| = 0.1 of the lock (and back near the 1-2-3
lock): the switches, the steps and CPU time, and the error.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import main, progress  # noqa: E402

import mbdk  # noqa: E402
from mbdk.analysis.tables import write_table  # noqa: E402
from mbdk.problems import rigid_body_momentum  # noqa: E402
from mbdk.scene_file import scene_from_dict  # noqa: E402

METHODS = ("explicit_euler", "heun", "rk4", "implicit_euler", "trapezoidal", "bdf2")


def invariants(r, p):
    info = mbdk.problems()["free_rigid_body"]
    e = info.energy(r.y, p)
    big_l = rigid_body_momentum(r.y, p)
    return (float(np.abs(e / e[0] - 1).max()),
            float(np.abs(big_l - big_l[0]).max() / np.linalg.norm(big_l[0])),
            float(np.abs(np.linalg.norm(r.y[:, :4], axis=1) - 1).max()))


def gimbal_rows(quick: bool) -> list[dict]:
    from mbdk import rotations as rot
    t_end = 5.0
    a0 = np.array([0.0, 0.5, 0.0])
    r0 = rot.from_angles(a0, "313")
    q0 = rot.to_quaternion(r0)
    # the same start in 1-2-3 angles: R0 = Rx(a1) Ry(b) Rz(a3)
    c123 = np.array([np.arctan2(-r0[1, 2], r0[2, 2]), np.arcsin(r0[0, 2]),
                     np.arctan2(-r0[0, 1], r0[0, 0])])
    rows = []
    for e in ((1e-2, 1e-3) if quick else (1e-1, 1e-2, 1e-3, 1e-4)):
        w = np.array([1.0, e, 0.0])
        ref = mbdk.solve_ode("free_rigid_body", "dopri54", t_end=t_end, y0=np.r_[q0, w],
                             rtol=1e-12, atol=1e-14, dt_out=1e-3)
        qs = ref.y[:, :4] / np.linalg.norm(ref.y[:, :4], axis=1)[:, None]
        r_end = rot.from_quaternion(qs[-1])
        # the 3-1-3 lock is sin(theta) = 0, theta = acos(R33); the 1-2-3 one cos(beta) = 0
        r33 = qs[:, 0] ** 2 - qs[:, 1] ** 2 - qs[:, 2] ** 2 + qs[:, 3] ** 2
        r13 = 2 * (qs[:, 1] * qs[:, 3] + qs[:, 0] * qs[:, 2])
        for label, problem, y0, params, closest in (
                ("quaternion", "free_rigid_body", np.r_[q0, w], None, None),
                ("313 Euler", "rigid_body_angles", np.r_[a0, w], {"sequence": 313.0},
                 float(np.sqrt(max(0.0, 1 - np.max(r33 ** 2))))),
                ("123 Cardan", "rigid_body_angles", np.r_[c123, w], {"sequence": 123.0},
                 float(np.sqrt(max(0.0, 1 - np.max(r13 ** 2)))))):
            for m, kw in (("rk4", {"h": 1e-3, "every": 5000}),
                          ("dopri54", {"rtol": 1e-9, "atol": 1e-11, "dt_out": t_end})):
                r = mbdk.solve_ode(problem, m, t_end=t_end, y0=y0, params=params,
                                   raise_on_failure=False, **kw)
                done = bool(r.t[-1] == t_end)
                if done:
                    if problem == "free_rigid_body":
                        rr = rot.from_quaternion(r.y[-1, :4] / np.linalg.norm(r.y[-1, :4]))
                    else:
                        rr = rot.from_angles(r.y[-1, :3], str(int(params["sequence"])))
                rows.append({"e": e, "parametrisation": label, "method": m,
                             "closest_to_lock": closest, "status": r.status.name,
                             "steps": r.stats.steps, "cpu_ms": 1e3 * r.cpu_time,
                             "orientation_error": float(np.abs(rr - r_end).max())
                             if done else None})
        # the same body as a spatial scene in 3-1-3 angles that switches to 1-2-3 within 0.1
        # of the lock and back (simulate's switch_angles, mbdk.angle_switch): what passing the
        # lock costs
        sc = scene_from_dict({
            "scene": {"name": "spin", "rotation": "euler313"},
            "body": [{"name": "b", "kind": "spatial", "mass": 1.0, "inertia": [1.0, 2.0, 3.0],
                      "euler313": a0.tolist(), "omega_body": w.tolist()}]}, "spin")
        for m, kw in (("rk4", {"h": 1e-3, "every": 5000}),
                      ("dopri54", {"rtol": 1e-9, "atol": 1e-11, "dt_out": t_end})):
            r = mbdk.simulate(sc, m, t_end=t_end, switch_angles=0.1, raise_on_failure=False,
                              **kw)
            rows.append({"e": e, "parametrisation": "313 Euler, switching to 123 at 0.1",
                         "method": m, "closest_to_lock": None, "status": r.status.name,
                         "steps": r.stats.steps, "cpu_ms": 1e3 * r.cpu_time,
                         "switches": len(r.manifest["switches"]),
                         "orientation_error": float(np.abs(r.orientation("b")[-1] - r_end).max())
                         if r.t[-1] == t_end else None})
    return rows


def heavy_top_rows(quick: bool) -> list[dict]:
    info = mbdk.problems()["heavy_top"]
    p = info.params
    j1, j3, mgl = p["J1"], p["J3"], p["m"] * p["g"] * p["l"]
    th0 = np.radians(30.0)
    q0 = [np.cos(th0 / 2), np.sin(th0 / 2), 0.0, 0.0]
    rows = []
    for w3 in ((50.0, 100.0) if quick else (25.0, 50.0, 100.0, 200.0)):
        t_end = 2.0
        progress(f"heavy top, w3 = {w3:g}")
        r = mbdk.solve_ode("heavy_top", "rk4", h=2e-5, t_end=t_end, every=5,
                           y0=np.r_[q0, 0.0, 0.0, w3])
        q = r.y[:, :4] / np.linalg.norm(r.y[:, :4], axis=1)[:, None]
        ax = np.stack([2 * (q[:, 1] * q[:, 3] + q[:, 0] * q[:, 2]),
                       2 * (q[:, 2] * q[:, 3] - q[:, 0] * q[:, 1]),
                       q[:, 0] ** 2 - q[:, 1] ** 2 - q[:, 2] ** 2 + q[:, 3] ** 2], axis=1)
        theta = np.arccos(np.clip(ax[:, 2], -1, 1))
        phi = np.unwrap(np.arctan2(ax[:, 0], -ax[:, 1]))
        # nutation: theta returns to its start (the top of each loop) once per period
        tops = np.flatnonzero((theta[1:-1] < theta[:-2]) & (theta[1:-1] <= theta[2:]))
        period = np.mean(np.diff(r.t[1:-1][tops])) if tops.size > 2 else np.nan
        e = info.energy(r.y, p)
        rows.append({"w3": w3, "nutation_rad_s": 2 * np.pi / period,
                     "nutation_classical": j3 * w3 / j1,
                     "precession_rad_s": (phi[-1] - phi[0]) / t_end,
                     "precession_classical": mgl / (j3 * w3),
                     "amplitude_deg": np.degrees(theta.max() - theta.min()),
                     "amplitude_classical_deg": np.degrees(2 * j1 * mgl * np.sin(th0)
                                                           / (j3 * w3) ** 2),
                     "energy_rel_error": float(np.abs(e / e[0] - 1).max()),
                     "cpu_ms": 1e3 * r.cpu_time})
    return rows


def run(out: Path, quick: bool = False) -> dict:
    out.mkdir(parents=True, exist_ok=True)
    info = mbdk.problems()["free_rigid_body"]
    p = info.params
    t_end = 15.0 if quick else 30.0
    ref = mbdk.solve_ode("free_rigid_body", "rk4", h=1e-4, t_end=t_end, every=10)
    y_ref = ref.y[-1]
    dp = mbdk.solve_ode("free_rigid_body", "dopri54", t_end=t_end, rtol=1e-13, atol=1e-15)
    ref_check = float(np.abs(dp.y[-1] - y_ref).max())
    steps = (2e-3, 1e-3) if quick else (4e-3, 2e-3, 1e-3)
    rows, runs = [], {}
    for m in METHODS:
        errs = []
        # rk4 at these steps is already at the floor that roundoff, amplified through the flip,
        # sets (about 1e-10): its order shows at ten times larger steps
        for h in (10 * np.array(steps) if m == "rk4" else steps):
            progress(f"{m}, h = {h:g}")
            r = mbdk.solve_ode("free_rigid_body", m, h=h, t_end=t_end, every=10,
                               raise_on_failure=False)
            de, dl, dq = invariants(r, p)
            err = float(np.abs(r.y[-1] - y_ref).max()) if r.t[-1] == t_end else np.inf
            errs.append(err)
            order = (np.log(errs[-2] / errs[-1]) / np.log(2.0)) if len(errs) > 1 else None
            rows.append({"method": m, "h": h, "energy_rel_error": de, "momentum_rel_error": dl,
                         "max_abs_norm_q_minus_1": dq, "final_error": err,
                         "observed_order": order, "cpu_ms": 1e3 * r.cpu_time})
            runs[(m, h)] = r
    for m in ("dopri54", "bdf"):
        for tol in (1e-6, 1e-9):
            r = mbdk.solve_ode("free_rigid_body", m, t_end=t_end, rtol=tol, atol=tol * 1e-2,
                               dt_out=0.01)
            de, dl, dq = invariants(r, p)
            rows.append({"method": f"{m} rtol {tol:g}", "h": None, "energy_rel_error": de,
                         "momentum_rel_error": dl, "max_abs_norm_q_minus_1": dq,
                         "final_error": float(np.abs(r.y[-1] - y_ref).max()),
                         "observed_order": None, "cpu_ms": 1e3 * r.cpu_time,
                         "steps": r.stats.steps})
    flips = np.flatnonzero(np.diff(np.sign(ref.y[:, 5])) != 0)
    tables = [write_table(
        rows, ["method", "h", "steps", "energy_rel_error", "momentum_rel_error",
               "max_abs_norm_q_minus_1", "final_error", "observed_order", "cpu_ms"],
        out, "rigid_body_invariants",
        f"Torque-free body (J = 1, 2, 3), spin near the intermediate axis, 0..{t_end:g} s",
        f"Omega_2 changes sign at t = {', '.join(f'{ref.t[i]:.2f}' for i in flips)} s in the "
        f"reference (the flips). Errors are the largest over the samples; final_error against "
        f"rk4 at h = 1e-4, which dopri54 at rtol 1e-13 meets to {ref_check:.1e}; the quaternion "
        "is never renormalised")]
    tables.append(write_table(
        heavy_top_rows(quick), ["w3", "nutation_rad_s", "nutation_classical",
                                "precession_rad_s", "precession_classical", "amplitude_deg",
                                "amplitude_classical_deg", "energy_rel_error", "cpu_ms"],
        out, "rigid_body_heavy_top",
        "Heavy symmetric top released at 30 deg: nutation and precession against the fast-top "
        "values", "rk4, h = 2e-5 s; the classical values are the leading terms in 1 / w3"))
    tables.append(write_table(
        gimbal_rows(quick), ["e", "parametrisation", "method", "closest_to_lock", "switches",
                             "status", "steps", "cpu_ms", "orientation_error"],
        out, "rigid_body_gimbal",
        "Gimbal lock: one motion passing within about e of the 3-1-3 lock, in three "
        "parametrisations, and in 3-1-3 angles switching sets near the lock",
        "closest_to_lock: the least sin(theta) (3-1-3) or cos(beta) (1-2-3) over the "
        "reference's samples (every 1 ms); quaternions have no lock. The switching runs are "
        "the spatial scene of the same body (mbdk.simulate(..., switch_angles=0.1)): they stop "
        "within 0.1 of the lock and go on in the other set from their last step (fixed step) "
        "or dense-output sample (dopri54), which they take every step or 2000 times a run; "
        "their CPU time is the spatial model's, whose step costs more than the compiled "
        "problem's of the rows above"))
    from mbdk.analysis import plotting
    fig, axes = plotting.plt.subplots(2, 1, figsize=(6.4, 5.6), sharex=True)
    for k in range(3):
        axes[0].plot(ref.t, ref.y[:, 4 + k], lw=0.9, label=f"Omega_{k + 1}")
    axes[0].set_ylabel("rad/s")
    axes[0].set_title("The intermediate-axis flip (reference)")
    axes[0].legend()
    for m in ("explicit_euler", "heun", "implicit_euler", "trapezoidal"):
        r = runs[(m, steps[-1])]
        axes[1].plot(r.t, np.linalg.norm(r.y[:, :4], axis=1) - 1, lw=0.9, label=m)
    # signed: explicit Euler inflates |q|, implicit Euler shrinks it
    axes[1].set_yscale("symlog", linthresh=1e-12)
    axes[1].set_yticks([-1e-2, -1e-6, -1e-10, 0, 1e-10, 1e-6, 1e-2])
    axes[1].minorticks_off()
    axes[1].set_xlabel("t [s]")
    axes[1].set_ylabel("|q| - 1")
    axes[1].set_title(f"Drift of the quaternion's norm, h = {steps[-1]:g}")
    axes[1].legend()
    figs = [{"path": plotting.save(fig, out, "rigid_body_flip"), "caption": (
        "Top: the angular velocities of the torque-free asymmetric body in the reference run, "
        "flipping about its intermediate axis; bottom: how far each method lets the "
        "quaternion's norm leave 1 at the finest step (signed, symmetric log scale). Read: "
        "explicit Euler inflates |q| and implicit Euler shrinks it; the nearer a curve "
        "stays to 0, the better the method keeps the rotation a rotation (the table gives "
        "each method's largest drift at every step).")}]
    return {"title": "The torque-free rigid body: flip, invariants, |q|", "tables": tables,
            "figures": figs, "hard_cases": {"gimbal lock": gimbal_line(tables[-1]["rows"])}}


def gimbal_line(rows: list[dict]) -> str:
    """The closest pass to the lock in a line: each parametrisation's outcome by method."""
    e = min(r["e"] for r in rows)

    def outcome(r):
        err = r["orientation_error"]
        return f"{r['method']} " + (r["status"] if err is None else f"error {err:.1e}")
    parts = {}
    for r in rows:
        if r["e"] == e:
            parts.setdefault(r["parametrisation"], []).append(outcome(r))
    return f"passing within {e:g} of the 3-1-3 lock: " + "; ".join(
        f"{k}: {', '.join(v)}" for k, v in parts.items())


if __name__ == "__main__":
    sys.exit(main(run, "rigid_body"))
