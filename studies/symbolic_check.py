"""Symbolic cross-check (SymPy) of the scenes' equations and of the book's printed matrices
(Fekete 2023, sections 2.1, 2.4.2, 3.4-3.5).

1. Every built-in scene, planar and spatial, and one scene of each constraint kind of chapter
   1 (the car's knife edge, a bead on a curve, a slider, gears, a rack, a rolling disc):
   mbdk.symbolic derives Phi, D, gamma, Phi_t and f from the scene's definitions, and the
   reduced accelerations and multipliers from [M D^T; D 0] [a; lam] = [f; gamma]; they are
   compared with the compiled assembly at 5 random states. The largest difference, relative to the
   magnitude of the values, and what each side costs: SymPy's derivation (CPU s), one
   evaluation of the lambdified expressions, and the kernel's assembly (timed inside it).
2. The book's printed matrices, each against its derivation by SymPy from the book's own
   constraint vector ((2.23) for the double pendulum, (2.143) for the trolley crane) and its
   mechanism (the masses of the bodies that own the coordinates; gravity along -y as (2.33),
   (3.59) and (3.52) put it; reactions F = -lambda as (2.27) and (3.59) write them): D, D^T,
   gamma, M, f, the Newton-Euler rows (2.27), the DAE (2.151), and the reduced accelerations of
   (3.64) at random states.
"""
from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import main, progress  # noqa: E402

import sympy as sp  # noqa: E402

import mbdk  # noqa: E402
from mbdk import symbolic  # noqa: E402
from mbdk.analysis import plotting  # noqa: E402
from mbdk.analysis.tables import write_table  # noqa: E402
from mbdk.scene_file import scene_from_dict  # noqa: E402

G = 9.81


def kind_scenes() -> dict:
    """One small scene per constraint kind added for chapter 1 (the tests' own scenes)."""
    two = [{"name": "a", "mass": 1.0, "inertia": 0.1, "x": 0.1, "y": 0.2, "angle": 0.4},
           {"name": "b", "mass": 2.0, "inertia": 0.3, "x": 0.9, "y": 0.5, "angle": 0.7}]
    grav = [{"type": "gravity", "g": [0, -G]}]
    out = {
        "car (knife edge, steered)": {
            "body": [{"name": "car", "mass": 1000.0, "inertia": 1500.0, "vx": 10.0,
                      "given": ["x", "y", "angle", "vx"]}],
            "joint": [{"name": "wheels", "type": "knife_edge", "body1": "car"},
                      {"name": "steer", "type": "driver", "body1": "car", "coordinate": "angle",
                       "function": {"amplitude": 0.4, "omega": 1.3}}]},
        "skate (knife edge off the centroid)": {
            "body": [two[0]],
            "joint": [{"name": "blade", "type": "knife_edge", "body1": "a", "point1": [-0.3, 0],
                       "axis": [0.6, 0.8]}], "force": grav},
        "bead on a sine track (point_curve)": {
            "body": [two[0]],
            "joint": [{"name": "track", "type": "point_curve", "body1": "a",
                       "point1": [0.2, -0.1], "curve": {"offset": 0.1, "rate": 0.3,
                                                        "amplitude": 0.2, "omega": 3.0}}],
            "force": grav},
        "slider on a moving line (point_line)": {
            "body": two,
            "joint": [{"name": "rail", "type": "point_line", "body1": "a", "point1": [0.2, -0.1],
                       "body2": "b", "point2": [-0.1, 0.3], "axis": [0.6, 0.8]},
                      {"name": "hinge", "type": "revolute", "body1": "b", "point1": [0.3, 0],
                       "point2": [1.2, 0.5]}],
            "force": grav + [{"type": "spring_damper", "body1": "a", "body2": "ground",
                              "point2": [0, 1], "stiffness": 50.0, "damping": 2.0}]},
        "gears and rack (couplings)": {
            "body": two + [{"name": "c", "mass": 4.0, "inertia": 0.1, "y": -0.3}],
            "joint": [{"name": "axle1", "type": "revolute", "body1": "a",
                       "point2": [0.1, 0.2]},
                      {"name": "axle2", "type": "revolute", "body1": "b",
                       "point2": [0.9, 0.5]},
                      {"name": "mesh", "type": "coupling", "body1": "a", "body2": "b",
                       "ratio": -0.5},
                      {"name": "teeth", "type": "coupling", "body1": "b", "body2": "c",
                       "coordinate2": "x", "ratio": -0.2}],
            "force": [{"type": "torque", "body": "a", "torque": 2.0,
                       "function": {"offset": 1.0, "amplitude": 0.5, "omega": 3.0}}]},
        "rolling disc on an incline": {
            "body": [{"name": "disc", "mass": 2.0, "inertia": 0.0625, "x": -0.125,
                      "y": 0.2165}],
            "joint": [{"name": "roll", "type": "rolling", "body1": "disc", "radius": 0.25,
                       "direction": [0.8660254, -0.5]}],
            "force": grav},
        "pendulum of changing length (distance)": {
            "body": [{"name": "bob", "mass": 1.0, "inertia": 1e-3, "x": 0.5, "y": -0.8}],
            "joint": [{"name": "rod", "type": "distance", "body1": "bob",
                       "length": {"offset": 1.0, "rate": 0.2, "amplitude": 0.1,
                                  "omega": 2.0}}],
            "force": grav},
    }
    return {k: scene_from_dict({"scene": {"name": k.split(" ")[0]}, **d}, k)
            for k, d in out.items()}


def scene_table(out: Path, quick: bool) -> dict:
    rows = []
    cases = ([(n, mbdk.scene(n)) for n in mbdk.scenes("all")]
             + list(kind_scenes().items()))
    for name, sc in cases:
        progress(f"symbolic cross-check: {name}")
        r = symbolic.cross_check(sc, states=3 if quick else 5)
        rows.append({"scene": name,
                     "Phi, D, gamma, Phi_t": max(r["phi"], r["D"], r["gamma"], r["phit"]),
                     "f": ("kernel's (contacts)" if r["f_from_kernel"] else
                           "in M a" if r["f"] is None else r["f"]),
                     "a, lambda": max(r["a"], r["lam"] or 0.0),
                     "SymPy derive (s)": r["derive_s"],
                     "lambdified (us)": r["symbolic_ns"] / 1e3,
                     "kernel assembly (us)": (r["kernel_ns"] / 1e3 if r["kernel_ns"]
                                              else None)})
    return write_table(rows, list(rows[0]), out, "scenes",
                       "Symbolic derivation against the compiled assembly (max relative "
                       "difference over random states)",
                       "Relative to the larger magnitude of the two sides (at least 1). Spatial "
                       "scenes (mbdk.symbolic_spatial): C on the velocities (v, Omega), "
                       "accelerations at admissible states compared as M a (the multipliers of "
                       "redundant joints are not unique), no in-kernel timing of their assembly. "
                       "The parallelogram's rows are redundant on the manifold and nearly so at "
                       "the random states beside it: its accelerations carry the roundoff of a "
                       "near-singular solve. The kernel evaluates its assembly in nanoseconds "
                       "where SymPy's lambdified expressions take tens of microseconds through "
                       "numpy, and the derivation itself up to seconds (the spatial scenes' "
                       "joints of quaternion frames).")


def _close(a, b, args, rng, n=20):
    """a and b (SymPy expressions in args) agree at n random points."""
    fa, fb = sp.lambdify(args, a, "math"), sp.lambdify(args, b, "math")
    for _ in range(n):
        x = rng.uniform(0.3, 2.0, len(args))
        va, vb = float(fa(*x)), float(fb(*x))
        if abs(va - vb) > 1e-9 * max(1.0, abs(va), abs(vb)):
            return False
    return True


def book_items() -> list[dict]:
    """Each printed entry that differs from its derivation, and a summary row per equation
    whose entries agree."""
    rng = np.random.default_rng(1)
    rows = []

    def compare(eq, what, printed, derived, args, why_wrong="", why_right=""):
        printed, derived = sp.Matrix(printed), sp.Matrix(derived)
        bad = []
        for i in range(printed.rows):
            for j in range(printed.cols):
                if not _close(printed[i, j], derived[i, j], args, rng):
                    bad.append((i, j))
        if not bad:
            rows.append({"equation": eq, "item": what, "printed": "as derived",
                         "derived": f"{printed.rows} x {printed.cols} entries agree",
                         "verdict": "OK", "why": why_right})
        for i, j in bad:
            pos = f"[{i + 1}, {j + 1}]" if printed.cols > 1 else f"row {i + 1}"
            rows.append({"equation": eq, "item": f"{what} {pos}",
                         "printed": sp.sstr(printed[i, j]), "derived": sp.sstr(derived[i, j]),
                         "verdict": "WRONG", "why": why_wrong})

    # double pendulum, section 2.1: coordinates (x1, y1, f1, x2, y2, f2)
    x1, y1, f1, x2, y2, f2 = sp.symbols("x1 y1 phi1 x2 y2 phi2", real=True)
    w1, w2 = sp.symbols("dphi1 dphi2", real=True)
    dx = sp.symbols("dx1 dy1 dphi1_ dx2 dy2 dphi2_", real=True)
    l1, l2, m1, m2, g = sp.symbols("l1 l2 m1 m2 g", positive=True)
    fax, fay, fbx, fby = sp.symbols("F_Ax F_Ay F_Bx F_By", real=True)
    q = sp.Matrix([x1, y1, f1, x2, y2, f2])
    v = sp.Matrix([dx[0], dx[1], w1, dx[3], dx[4], w2])
    s1, c1, s2, c2 = sp.sin(f1), sp.cos(f1), sp.sin(f2), sp.cos(f2)
    phi = sp.Matrix([x1 - l1 / 2 * c1, y1 - l1 / 2 * s1,
                     x2 - x1 - l1 / 2 * c1 - l2 / 2 * c2, y2 - y1 - l1 / 2 * s1 - l2 / 2 * s2])
    d = phi.jacobian(q)
    gam = -(d * v).jacobian(q) * v
    args = [x1, y1, f1, x2, y2, f2, *v, l1, l2, m1, m2, g, fax, fay, fbx, fby]
    compare("(2.31)", "D of (2.23)", [[1, 0, l1 / 2 * s1, 0, 0, 0],
                                      [0, 1, -l1 / 2 * c1, 0, 0, 0],
                                      [-1, 0, l1 / 2 * s1, 1, 0, l2 / 2 * s2],
                                      [0, -1, -l1 / 2 * c1, 0, 1, -l2 / 2 * c2]], d, args)
    compare("(2.32)", "D^T", [[1, 0, -1, 0], [0, 1, 0, -1],
                              [l1 / 2 * s1, -l1 / 2 * c1, l1 / 2 * s1, -l1 / 2 * c1],
                              [0, 0, 1, 0], [0, 0, 0, 1], [0, 0, l2 / 2 * s2, -l2 / 2 * c2]],
            d.T, args)
    compare("(2.33)", "gamma, rows 7-10 of f",
            [-l1 / 2 * c1 * w1 ** 2, -l1 / 2 * s1 * w1 ** 2,
             -l1 / 2 * c1 * w1 ** 2 - l2 / 2 * c2 * w2 ** 2,
             -l1 / 2 * s1 * w1 ** 2 - l2 / 2 * s2 * w2 ** 2], gam, args)
    f = sp.Matrix([0, -m1 * g, 0, 0, -m2 * g, 0])
    lam = -sp.Matrix([fax, fay, fbx, fby])
    newton = f - d.T * lam
    compare("(2.27)", "Newton-Euler right-hand sides",
            [fax + m1 * g - fbx, fay - fby,
             -(fay + fby) * l1 / 2 * c1 + (fax + fbx) * l1 / 2 * s1,
             fbx + m2 * g, fby, -fby * l2 / 2 * c2 + fbx * l2 / 2 * s2], newton, args,
            why_wrong="gravity, m g, is in the x rows; the book's own f (2.33) and its MATLAB "
                      "(3.59) have -m g in the y rows, and the scene's bodies hang along -y")
    # (3.64): the reduced angular accelerations of the book's DAE (2.28)-(2.33), J = m l^2/12
    mass = sp.diag(m1, m1, m1 * l1 ** 2 / 12, m2, m2, m2 * l2 ** 2 / 12)
    num = sp.lambdify([q, v, l1, l2, m1, m2, g], (mass, d, f, gam), "numpy")
    p1 = ((-9 * m2 * l1 * sp.sin(2 * f1 - 2 * f2) * w1 ** 2
           - 12 * m2 * l2 * sp.sin(f1 - f2) * w2 ** 2 + 9 * m2 * g * sp.cos(f1 - 2 * f2)
           - g * c1 * (12 * m1 + 15 * m2))
          / (l1 * (8 * m1 + 15 * m2 - 9 * m2 * sp.cos(2 * f1 - 2 * f2))))
    p2 = ((-g * c2 * (3 * m1 + 18 * m2) + g * sp.cos(2 * f1 - f2) * (9 * m1 + 18 * m2)
           + 9 * m2 * l2 * sp.sin(2 * f1 - 2 * f2) * w2 ** 2
           + w1 ** 2 * l1 * sp.sin(f1 - f2) * (12 * m1 + 36 * m2))
          / (l2 * (8 * m1 + 15 * m2 - 9 * m2 * sp.cos(2 * f1 - 2 * f2))))
    printed = sp.lambdify([f1, f2, w1, w2, l1, l2, m1, m2, g], [p1, p2], "math")
    worst = 0.0
    for _ in range(20):
        a1, a2, o1, o2 = rng.uniform(-3, 3, 4)
        pars = rng.uniform(0.5, 2.0, 5)
        qq = np.array([pars[0] / 2 * math.cos(a1), pars[0] / 2 * math.sin(a1), a1,
                       pars[0] * math.cos(a1) + pars[1] / 2 * math.cos(a2),
                       pars[0] * math.sin(a1) + pars[1] / 2 * math.sin(a2), a2])
        vv = np.zeros(6)
        vv[2], vv[5] = o1, o2
        mm, dd, ff, gg = (np.array(x, float) for x in num(qq, vv, *pars))
        kkt = np.block([[mm, dd.T], [dd, np.zeros((4, 4))]])
        sol = np.linalg.solve(kkt, np.concatenate([ff.ravel(), gg.ravel()]))
        book = printed(a1, a2, o1, o2, *pars)
        worst = max(worst, abs(sol[2] - book[0]) / max(1, abs(book[0])),
                    abs(sol[5] - book[1]) / max(1, abs(book[1])))
    rows.append({"equation": "(3.64)", "item": "phi1'', phi2'' of the DAE (2.28)-(2.33)",
                 "printed": "closed form", "derived": f"max rel. difference {worst:.1e}",
                 "verdict": "OK" if worst < 1e-9 else "WRONG",
                 "why": "at 20 random states and parameter sets, on the constraint manifold"})

    # trolley crane, section 2.4.2: q = (x1, x2, y2, phi)
    xa, xb, yb, ph, wp = sp.symbols("x1 x2 y2 phi dphi", real=True)
    va, vb, vc = sp.symbols("dx1 dx2 dy2", real=True)
    l, s_, k_ = sp.symbols("l s k", positive=True)
    qt, vt = sp.Matrix([xa, xb, yb, ph]), sp.Matrix([va, vb, vc, wp])
    sph, cph = sp.sin(ph), sp.cos(ph)
    phit = sp.Matrix([xa + xb - l / 2 * cph, yb - l / 2 * sph])
    dt = phit.jacobian(qt)
    gt = -(dt * vt).jacobian(qt) * vt
    args = [xa, xb, yb, ph, va, vb, vc, wp, l, s_, k_, m1, m2, g]
    mt = sp.diag(m1, m2, m2, m2 * l ** 2 / 12)
    compare("(2.146)", "D of (2.143)", [[1, 1, 0, l / 2 * sph], [0, 0, 1, -l / 2 * cph]], dt,
            args)
    compare("(2.146)", "D^T", [[1, 0], [1, 1], [0, 1], [l / 2 * sph, -l / 2 * cph]], dt.T,
            args, why_wrong="the transpose of the D printed beside it has 0 there: x2 appears "
                            "in the first row of (2.143) only")
    compare("(2.145)", "M", sp.diag(m1, m1, m1, m2 * l ** 2 / 12), mt, args,
            why_wrong="x2 and y2 are the pendulum's centroid: its mass m2, as (2.151) and the "
                      "MATLAB M of (3.52) have it")
    compare("(2.150)", "gamma", [-l / 2 * cph * wp ** 2, -l / 2 * sph * wp ** 2], gt, args)
    compare("(2.151)", "[M D^T; D 0]",
            [[m1, 0, 0, 0, 1, 0], [0, m2, 0, 0, 1, 0], [0, 0, m2, 0, 0, 1],
             [0, 0, 0, m2 * l ** 2 / 12, l / 2 * sph, -l / 2 * cph],
             [1, 1, 0, l / 2 * sph, 0, 0], [0, 0, 1, -l / 2 * cph, 0, 0]],
            sp.Matrix(sp.BlockMatrix([[mt, dt.T], [dt, sp.zeros(2, 2)]])), args)
    compare("(2.151)", "right-hand side [f; gamma]",
            [-s_ * xa - k_ * va, 0, -m2 * g, 0, l / 2 * cph * wp ** 2, -l / 2 * sph * wp ** 2],
            sp.Matrix([-s_ * xa - k_ * va, 0, -m2 * g, 0, gt[0], gt[1]]), args,
            why_wrong="gamma's first row lost its minus sign between (2.150) and (2.151); the "
                      "MATLAB f of (3.52) has it")
    return rows


def figure(out: Path, table: dict) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    rows = table["rows"]
    names = [r["scene"] for r in rows]
    diff = [max(r["Phi, D, gamma, Phi_t"], r["a, lambda"], 1e-17) for r in rows]
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 0.32 * len(rows) + 1.5), sharey=True)
    y = np.arange(len(rows))
    ax1.barh(y, diff, color="tab:blue")
    ax1.set_xscale("log")
    ax1.set_yticks(y, names, fontsize=8)
    ax1.set_xlabel("max relative difference, symbolic vs kernel")
    ax1.axvline(1e-12, color="grey", lw=0.8, ls="--")
    ax2.barh(y - 0.2, [r["kernel assembly (us)"] or 0.0 for r in rows], 0.4,
             label="kernel assembly")
    ax2.barh(y + 0.2, [r["lambdified (us)"] for r in rows], 0.4, label="SymPy, lambdified")
    ax2.set_xscale("log")
    ax2.set_xlabel("one evaluation (us)")
    ax2.legend(fontsize=8)
    fig.suptitle("Symbolic cross-check of every scene: agreement and cost")
    return plotting.save(fig, out, "symbolic_check")


def run(out: Path, quick: bool = False) -> dict:
    t0 = time.process_time()
    scenes = scene_table(out, quick)
    book = write_table(book_items(), ["equation", "item", "printed", "derived", "verdict", "why"],
                       out, "book", "The book's printed matrices against SymPy's derivations",
                       "Derived from the book's own constraint vectors (2.23) and (2.143) and "
                       "the mechanisms; each entry compared at 20 random points. "
                       f"CPU time of the study: {time.process_time() - t0:.1f} s.")
    wrong = sorted({r["equation"] for r in book["rows"] if r["verdict"] == "WRONG"})
    return {"title": "Symbolic cross-check of the scenes and of the book's matrices",
            "tables": [scenes, book], "figures": [{"path": figure(out, scenes), "caption": (
                "Every scene's constraint terms and accelerations derived by SymPy against the "
                "kernel's: the largest relative difference (left; dashed: 1e-12) and the "
                "cost of one evaluation by the kernel and by SymPy's lambdified expressions "
                "(right), log scales. Read: every bar left of the dashed line means the "
                "kernel's assembly matches the derivation to roundoff; the right panel says "
                "how much faster the compiled assembly is.")}],
            "verdict": f"printed forms that differ from their derivation: {', '.join(wrong)}"}


if __name__ == "__main__":
    sys.exit(main(run, "symbolic_check"))
