"""Chapter 5's printed rotation formulas (Fekete 2023, (5.1)-(5.95)) against the kernel's own
(kernel/src/spatial/mbdk_rotations.f90 through mbdk.rotations, itself tested against SciPy and
against differences of R(t) in tests/test_rotations.py): each formula as printed and, where it
is wrong, as corrected, evaluated at random states; the table gives the largest difference from
the kernel, the verdict and the reason. Seed lines refer to ../shared/seed/000_*.txt.

The book's conventions are the kernel's: R = R_{t->a} maps body (t) to space (a) components,
3-1-3 Euler angles R = Rz(phi) Rx(theta) Rz(psi) about moving axes, skew(w_a) = R' R^T,
w_t = R^T w_a, quaternions scalar first with x_a = q x_t q*. Rows marked "notation" are misprints
of a symbol or a label that no number can show; they are listed with what the text needs.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import main  # noqa: E402

from mbdk import rotations as rot  # noqa: E402
from mbdk.analysis.tables import write_table  # noqa: E402

RNG = np.random.default_rng(5)
SAMPLES = 50


def skew(w):
    return np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])


def vex(w):
    return 0.5 * np.array([w[2, 1] - w[1, 2], w[0, 2] - w[2, 0], w[1, 0] - w[0, 1]])


def angles():
    """Random 3-1-3 angles, theta kept off its singular values 0 and pi."""
    return np.array([RNG.uniform(-np.pi, np.pi), RNG.uniform(0.2, np.pi - 0.2),
                     RNG.uniform(-np.pi, np.pi)])


def unit_quat():
    q = RNG.standard_normal(4)
    q = q / np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def pure(v):
    return np.r_[0.0, v]


def euler_printed(a):                          # (5.9), seed line 3253
    f, t, p = a
    cf, sf, ct, st, cp, sp = np.cos(f), np.sin(f), np.cos(t), np.sin(t), np.cos(p), np.sin(p)
    return np.array([[cf * cp - sf * ct * sp, -cf * sp - sf * ct * cp, sf * st],
                     [sf * cp + cf * ct * sp, -sf * sp + cf * ct * cp, -cf * st],
                     [st * sp, st * cp, ct]])


def a_printed(a):                              # (5.29), (5.33): w_a = A e'
    f, t, _ = a
    return np.array([[0, np.cos(f), np.sin(f) * np.sin(t)],
                     [0, np.sin(f), -np.cos(f) * np.sin(t)], [1, 0, np.cos(t)]])


def b_printed(a):                              # (5.40): w_t = B e'
    _, t, p = a
    return np.array([[np.sin(p) * np.sin(t), np.cos(p), 0],
                     [np.cos(p) * np.sin(t), -np.sin(p), 0], [np.cos(t), 0, 1]])


def binv(a, printed):                          # (5.44), seed line 3447
    _, t, p = a
    s, c, sp, cp = np.sin(t), np.cos(t), np.sin(p), np.cos(p)
    m32 = -cp * s if printed else -cp * c
    return np.array([[sp, cp, 0], [cp * s, -sp * s, 0], [-sp * c, m32, s]]) / s


def block(q, top_sign, col_sign, skew_sign):
    """[q0, top_sign q^T; col_sign q, q0 E + skew_sign q~] (the 4 x 4 forms of (5.54)-(5.87))."""
    m = np.zeros((4, 4))
    m[0, 0] = q[0]
    m[0, 1:] = top_sign * q[1:]
    m[1:, 0] = col_sign * q[1:]
    m[1:, 1:] = q[0] * np.eye(3) + skew_sign * skew(q[1:])
    return m


def worst(f):
    return max(float(np.max(np.abs(f()))) for _ in range(SAMPLES))


def rows_() -> list[dict]:
    out = []

    def row(eq, line, what, printed, corrected, reason):
        verdict = "correct" if printed is not None and printed < 1e-12 else (
            "notation" if printed is None else "WRONG")
        out.append({"eq": eq, "seed_line": line, "formula": what,
                    "printed_vs_kernel": printed, "corrected_vs_kernel": corrected,
                    "verdict": verdict, "reason": reason})

    row("5.9", 3253, "3-1-3 Euler rotation matrix R = Rz(phi) Rx(theta) Rz(psi)",
        worst(lambda: (lambda a: euler_printed(a) - rot.from_angles(a, "313"))(angles())), None,
        "")

    def w24(printed):
        a, ad = angles(), RNG.standard_normal(3)
        d = 1e-6
        rd = (rot.from_angles(a + d * ad, "313") - rot.from_angles(a - d * ad, "313")) / (2 * d)
        r = rot.from_angles(a, "313")
        gs, _ = rot.angle_rate_maps(a, "313")
        w = r @ rd.T if printed else rd @ r.T
        return (vex(w) - gs @ ad) / max(1.0, np.linalg.norm(ad))
    row("5.24", 3349, "skew(w_a) = W", worst(lambda: w24(True)), worst(lambda: w24(False)),
        "printed R R'^T is W^T = -skew(w_a) (by (5.22)); W = R' R^T, as (5.26) has it (the "
        "corrected row is at the 1e-10 of the central difference)")
    row("5.29", 3375, "w_a = A(phi, theta) e'",
        worst(lambda: (lambda a: a_printed(a) - rot.angle_rate_maps(a, "313")[0])(angles())),
        None, "")
    row("5.33", 3397, "the same in matrix form", None, None,
        "the 3 x 3 skew matrix of w_a is set equal to the vector A e'; the left side is "
        "(w_ax, w_ay, w_az)^T")
    row("5.40", 3431, "w_t = B(theta, psi) e'",
        worst(lambda: (lambda a: b_printed(a) - rot.angle_rate_maps(a, "313")[1])(angles())),
        None, "")

    def e44(printed):
        a, w = angles(), RNG.standard_normal(3)
        return (binv(a, printed) @ w - rot.angle_rates(a, w, "313", "body")) * np.sin(a[1])
    row("5.44", 3447, "e' = B^-1 w_t", worst(lambda: e44(True)), worst(lambda: e44(False)),
        "entry (3, 2) is -cos(psi) cos(theta) / sin(theta), not -cos(psi) sin(theta) / "
        "sin(theta): psi' = w3 - cot(theta) (sin(psi) w1 + cos(psi) w2). Integrated by (5.45) "
        "the printed matrix drifts off the motion (residuals scaled by sin(theta))")
    dets = {th: abs(np.linalg.det(rot.angle_rate_maps([0.3, np.radians(th), -0.4], "313")[0]))
            for th in (0.0, 90.0, 180.0)}
    row("5.45", 3453, "where the Euler-angle rates are singular (the remark after (5.45))",
        dets[90.0], max(dets[0.0], dets[180.0]),
        f"the text puts gimbal lock at theta = 90 deg; det B = -sin(theta) (kernel: |det| = "
        f"{dets[90.0]:.3g} at 90 deg, {dets[0.0]:.1g} at 0, {dets[180.0]:.1g} at 180): the "
        "singularity is at theta = 0 and 180 deg, where the first and third axes coincide "
        "(90 deg is the 1-2-3 Cardan angles' lock). Columns: |det| at the printed angle, at "
        "the true ones")

    def r49():
        n = RNG.standard_normal(3)
        n /= np.linalg.norm(n)
        f = RNG.uniform(-np.pi, np.pi)
        k = skew(n)
        return np.eye(3) + (1 - np.cos(f)) * k @ k + np.sin(f) * k - rot.from_axis_angle(n, f)
    row("5.49", 3488, "Rodrigues R = E + (1 - cos f) n~ n~ + sin f n~", worst(r49), None, "")

    def pq54(printed):
        p, q = RNG.standard_normal(4), RNG.standard_normal(4)
        m = block(p, -1, 1, -1 if printed else 1)
        return m @ q - rot.quaternion_product(p, q)
    row("5.54", 3558, "p o q as a matrix times q", worst(lambda: pq54(True)),
        worst(lambda: pq54(False)),
        "[p0 -p^T; p p0 E - p~] q is q o p; p o q = [p0 -p^T; p p0 E + p~] q")

    def s63(printed):
        q, x = unit_quat(), RNG.standard_normal(3)
        ref = rot.quaternion_product(q * [1, -1, -1, -1], pure(x))
        v = q[0] * x - np.cross(q[1:], x)
        return (pure(v) if printed else np.r_[q[1:] @ x, v]) - ref
    row("5.63", 3608, "q* o x_a", worst(lambda: s63(True)), worst(lambda: s63(False)),
        "the printed second form drops the scalar part q . x_a, which is not zero (the "
        "expansion that follows uses the full quaternion)")
    row("5.71", 3654, "x_t = (0, x_t) = ...", None, None,
        "labelled x_t = (0, x_a); the right-hand side is right")

    def v78(printed):
        q, w = unit_quat(), RNG.standard_normal(3)
        qd = rot.quaternion_rates(q, w, "space")
        qc, qdc = q * [1, -1, -1, -1], qd * [1, -1, -1, -1]
        v = rot.quaternion_product(q, qdc) if printed else rot.quaternion_product(qd, qc)
        return 2 * v[1:] - w
    row("5.78", 3694, "v with w_a = 2 vec(v)", worst(lambda: v78(True)),
        worst(lambda: v78(False)),
        "printed v = q o q*' = -q' o q* has the opposite sign; v = q' o q* = -q o q*', which "
        "(5.79) uses")

    def w83(printed):
        q, w = unit_quat(), RNG.standard_normal(3)
        qd = rot.quaternion_rates(q, w, "space")
        return 2 * block(q, 1, -1, -1 if printed else 1) @ qd - pure(w)
    row("5.83", 3716, "(0, w_a) = 2 [q0 q^T; -q q0 E -+ q~] q'", worst(lambda: w83(True)),
        worst(lambda: w83(False)),
        "the skew block's sign: + q~, as the 4 x 4 matrix of (5.84) has it")

    def q86(printed):
        q, w = unit_quat(), RNG.standard_normal(3)
        qd = rot.quaternion_rates(q, w, "space")
        right = qd if printed else pure(w)
        return 0.5 * block(q, -1, 1, -1) @ right - qd
    row("5.86", 3728, "q' = (1/2) [q0 -q^T; q q0 E - q~] (0, w_a)", worst(lambda: q86(True)),
        worst(lambda: q86(False)),
        "printed with q' on both sides; the vector on the right is (0, w_a), as in (5.87)")
    row("5.95", 3766, "q_i+1 = q_i + int q' dt", None, None,
        "printed e_i+1 = e_i + int q' dt = int (1/2) q o w_t dt: it is the quaternion that is "
        "integrated, not the Euler angles, and the last member lacks q_i")
    row("5.1", 3145, "Newton-Euler, rotational part", None, None,
        "printed I_s'' = M_s; the rate of the angular momentum, Pi_s' = M_s, as (2.2)")
    return out


def run(out: Path, quick: bool = False) -> dict:
    rows = rows_()
    wrong = [r["eq"] for r in rows if r["verdict"] != "correct"]
    tables = [write_table(
        rows, ["eq", "seed_line", "formula", "printed_vs_kernel", "corrected_vs_kernel",
               "verdict", "reason"], out, "ch5_formulas",
        "Chapter 5's rotation formulas as printed against the kernel",
        f"Largest difference over {SAMPLES} random states. Misprinted: {', '.join(wrong)}. The "
        "other formulas of (5.1)-(5.95) (rotation matrices, Rodrigues, quaternion algebra and "
        "sandwich product, (5.84)-(5.94)) agree with the kernel and SciPy to roundoff; the "
        "rows here are those the kernel computes")]
    return {"title": "Chapter 5: the printed rotation formulas", "tables": tables,
            "figures": []}


if __name__ == "__main__":
    sys.exit(main(run, "ch5_formulas"))
