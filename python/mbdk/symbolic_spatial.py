"""A spatial scene's equations derived symbolically (SymPy) and compared with the compiled
spatial model (kernel/src/spatial/mbdk_spatial_model.f90) at random states; the spatial half
of mbdk.symbolic.

Each joint is written as the kernel's primitive constraints, from their definitions: a point
on a point P_i - P_j (P = r + R s), two vectors normal, (R_i u_i) . (R_j u_j), a vector normal
to the points' offset, (R_j u_j) . (P_i - P_j), an angle driver's sin(theta - f(t)) =
cos f (u . w) - sin f (u . v) and a slide driver's (R_j a_j) . (P_i - P_j) - f(t); with the
kernel's choice of the vectors (the two normals of an axis, a prismatic joint's and a driver's
reference taken at the initial frames), so that the rows are the same functions. What SymPy derives, and the kernel writes out by hand, is their
derivatives: along the motion r(s) = r + v s, R(s) = R exp(s skew(W)) (W in the body frame,
so exp(s W^) = I + s W^ + s^2 W^2 / 2 to the order needed), t(s) = t + s,
    Phi'(0) = C w + Phi_t,   Phi''(0) = -gamma   (w' = 0),
C the coefficients of w = (v, W) per body. The loads are the kernel's: gravity m g, point
forces at body points and torques (space frame), spring-dampers along their points' line,
and the gyroscopic moment -W x J W of Euler's equations (5.1)-(5.3).

cross_check_spatial compares Phi, C, gamma and Phi_t at random states (random positions,
unit quaternions and rates), and the accelerations (v', W') at states on the joints' manifold
(the initial pose with random admissible velocities, C w + Phi_t = 0), where they are unique
also for redundant joints: the symbolic side solves [M C^T; C 0] [w'; lam] = [f; gamma] by
least squares.
"""
from __future__ import annotations

import time

import numpy as np

from .codes import SPATIAL_FORCE_CODES, SPATIAL_JOINT_CODES
from .errors import InvalidInputError
from .spatial_model import evaluate_spatial, spatial_tables

#: the kinds of the spatial model's tables by their codes (the kernel's element registry)
_JOINTS = {code: name for name, code in SPATIAL_JOINT_CODES.items()}
_FORCES = {code: name for name, code in SPATIAL_FORCE_CODES.items()}


def _normals(a: np.ndarray):
    """Two unit vectors normal to the unit a and to each other: a x e_k, e_k the coordinate
    axis least aligned with a, and a x b1 (the kernel's choice, so that rows compare one to
    one)."""
    k = int(np.argmin(np.abs(a)))
    e = np.zeros(3)
    e[k] = 1.0
    b1 = np.cross(a, e)
    b1 /= np.linalg.norm(b1)
    return b1, np.cross(a, b1)


def _quat_matrix(p):
    p = np.asarray(p, float) / np.linalg.norm(p)
    w, x, y, z = p
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def derive_spatial(sc):
    """(symbols, Phi(s), loads): the symbolic rows along the motion parameter s, and the
    generalised forces, for a quaternion scene. symbols: per body r (3), R (3 x 3 entries), v,
    W (3 each); and t, s."""
    # SymPy: optional (the studies' and tests' extra), slow to import
    import sympy as sp
    if sc.rotation != "quaternion":
        raise InvalidInputError(f"{sc.source}: the symbolic check takes quaternion scenes "
                                f"(rotation = {sc.rotation!r})")
    nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal = spatial_tables(sc)
    y0 = sc.state0()
    rot0 = [_quat_matrix(y0[7 * b + 3:7 * b + 7]) for b in range(nb)]
    t, s = sp.symbols("t s", real=True)
    r = [sp.Matrix(sp.symbols(f"r{b}_0:3", real=True)) for b in range(nb)]
    R = [sp.Matrix(3, 3, sp.symbols(f"R{b}_0:9", real=True)) for b in range(nb)]
    v = [sp.Matrix(sp.symbols(f"v{b}_0:3", real=True)) for b in range(nb)]
    W = [sp.Matrix(sp.symbols(f"W{b}_0:3", real=True)) for b in range(nb)]

    def skew(x):
        return sp.Matrix([[0, -x[2], x[1]], [x[2], 0, -x[0]], [-x[1], x[0], 0]])

    rs = [r[b] + v[b] * s for b in range(nb)]
    Rs = [R[b] * (sp.eye(3) + s * skew(W[b]) + s ** 2 / 2 * skew(W[b]) ** 2) for b in range(nb)]
    ts = t + s

    def rotm(b):          # 1-based body, 0 the ground
        return Rs[b - 1] if b else sp.eye(3)

    def point(b, x):
        x = sp.Matrix(list(x))
        return rs[b - 1] + Rs[b - 1] * x if b else x

    def vec(b, u):
        return rotm(b) * sp.Matrix(list(u))

    rows = []
    for k in range(nj):
        code, (bi, bj), re = int(jtype[k]), jbody[:, k], jreal[:, k]
        typ = _JOINTS.get(code)
        si, sj, ai, aj, fn = re[0:3], re[3:6], re[6:9], re[9:12], re[12:17]
        if typ in ("revolute", "universal", "cylindrical", "prismatic", "angle_driver",
                   "slide_driver"):
            ai, aj = ai / np.linalg.norm(ai), aj / np.linalg.norm(aj)
        b1, b2 = _normals(aj) if np.linalg.norm(aj) > 0 else (np.eye(3)[0], np.eye(3)[1])
        sph = list(point(bi, si) - point(bj, sj))

        def dot1(ui, uj):
            return (vec(bi, ui).T * vec(bj, uj))[0]

        def dot2(uj):
            return (vec(bj, uj).T * (point(bi, si) - point(bj, sj)))[0]
        ri = rot0[bi - 1]
        rj = rot0[bj - 1] if bj else np.eye(3)
        if typ == "spherical":
            rows += sph
        elif typ == "revolute":
            rows += sph + [dot1(ai, b1), dot1(ai, b2)]
        elif typ == "universal":
            rows += sph + [dot1(ai, aj)]
        elif typ in ("cylindrical", "prismatic"):
            rows += [dot1(ai, b1), dot1(ai, b2), dot2(b1), dot2(b2)]
            if typ == "prismatic":
                rows.append(dot1(ri.T @ rj @ b2, b1))
        elif typ == "fixed":
            e = ri.T @ rj
            rows += sph + [dot1(e[:, m], np.eye(3)[(m + 1) % 3]) for m in range(3)]
        elif typ in ("angle_driver", "slide_driver"):
            off, rate, amp, om, ph = (float(x) for x in fn)
            f = off + rate * ts + amp * sp.sin(om * ts + ph)
            if typ == "angle_driver":
                u = vec(bi, ri.T @ rj @ b1)
                rows.append(sp.cos(f) * (u.T * vec(bj, b2))[0]
                            - sp.sin(f) * (u.T * vec(bj, b1))[0])
            else:
                rows.append(dot2(aj) - f)
        else:
            raise InvalidInputError(f"{sc.source}: joint type code {code} ({typ or 'unknown'}) "
                                    "has no symbolic form")

    # loads at s = 0: force (space) and body-frame moment per body
    f = sp.zeros(6 * nb, 1)
    for k in range(nf):
        code, (bi, bj), re = int(ftype[k]), fbody[:, k], freal[:, k]
        typ = _FORCES.get(code)
        if typ == "gravity":
            for b in range(nb):
                f[6 * b:6 * b + 3, 0] += float(mass[b]) * sp.Matrix(list(re[0:3]))
        elif typ == "point_force":
            force = sp.Matrix(list(re[3:6]))
            f[6 * (bi - 1):6 * (bi - 1) + 3, 0] += force
            f[6 * (bi - 1) + 3:6 * bi, 0] += sp.Matrix(list(re[0:3])).cross(R[bi - 1].T * force)
        elif typ == "torque":
            f[6 * (bi - 1) + 3:6 * bi, 0] += R[bi - 1].T * sp.Matrix(list(re[0:3]))
        elif typ == "spring_damper":
            pi = r[bi - 1] + R[bi - 1] * sp.Matrix(list(re[0:3]))
            pj = (r[bj - 1] + R[bj - 1] * sp.Matrix(list(re[3:6]))) if bj else \
                sp.Matrix(list(re[3:6]))
            d = pi - pj
            length = sp.sqrt((d.T * d)[0])
            rate = sp.diff((point(bi, re[0:3]) - point(bj, re[3:6])).norm(), s).subs(s, 0)
            tension = float(re[6]) * (length - float(re[8])) + float(re[7]) * rate
            force = -tension * d / length
            f[6 * (bi - 1):6 * (bi - 1) + 3, 0] += force
            f[6 * (bi - 1) + 3:6 * bi, 0] += sp.Matrix(list(re[0:3])).cross(R[bi - 1].T * force)
            if bj:
                f[6 * (bj - 1):6 * (bj - 1) + 3, 0] -= force
                f[6 * (bj - 1) + 3:6 * bj, 0] -= sp.Matrix(list(re[3:6])).cross(
                    R[bj - 1].T * force)
        else:
            raise InvalidInputError(f"{sc.source}: force type code {code} ({typ or 'unknown'}) "
                                    "has no symbolic form")
    for b in range(nb):
        jb = sp.Matrix(np.asarray(inertia[:, :, b], float))
        f[6 * b + 3:6 * b + 6, 0] -= W[b].cross(jb * W[b])
    syms = {"r": r, "R": R, "v": v, "W": W, "t": t, "s": s}
    return syms, sp.Matrix(rows) if rows else sp.zeros(0, 1), f


def cross_check_spatial(sc, states: int = 5, seed: int = 0, spread: float = 0.1) -> dict:
    """mbdk.symbolic.cross_check for a spatial scene (the module docstring): max relative
    differences of phi, D (the C of w), gamma, phit at random states and of the accelerations
    a = (v', W') at admissible states, compared as M a; lam is not compared (not unique with
    redundant joints), f enters through a."""
    # SymPy: optional (the studies' and tests' extra), slow to import
    import sympy as sp
    c0 = time.process_time()
    syms, phi_s, f_s = derive_spatial(sc)
    nb = len(sc.bodies)
    s, t = syms["s"], syms["t"]
    wsym = [x for b in range(nb) for x in (*syms["v"][b], *syms["W"][b])]
    args = [x for b in range(nb) for x in (*syms["r"][b], *syms["R"][b])] + wsym + [t]
    m = phi_s.shape[0]
    d1 = phi_s.diff(s)
    phi0, d10 = phi_s.subs(s, 0), d1.subs(s, 0)
    gam0 = -d1.diff(s).subs(s, 0)
    phit0 = d10.subs({w: 0 for w in wsym})
    cmat = d10.jacobian(wsym) if m else sp.zeros(0, 6 * nb)
    fn = sp.lambdify(args, [phi0, cmat, gam0, phit0, f_s], "numpy")
    derive_s = time.process_time() - c0
    mass = np.zeros(6 * nb)
    inertia = [np.asarray(b.inertia, float) for b in sc.bodies]
    mmat = np.zeros((6 * nb, 6 * nb))
    for b, body in enumerate(sc.bodies):
        mmat[6 * b:6 * b + 3, 6 * b:6 * b + 3] = body.mass * np.eye(3)
        mmat[6 * b + 3:6 * b + 6, 6 * b + 3:6 * b + 6] = inertia[b]
        mass[6 * b:6 * b + 3] = body.mass
    rng = np.random.default_rng(seed)
    y0 = sc.state0()
    nq = 7 * nb

    def unpack(y, tt):
        vals = []
        for b in range(nb):
            vals += list(y[7 * b:7 * b + 3]) + list(_quat_matrix(y[7 * b + 3:7 * b + 7]).ravel())
        return vals + list(y[nq:]) + [tt]

    def sym_eval(y, tt):
        out = fn(*unpack(y, tt))
        return [np.array(o, float) for o in out]

    worst = {k: 0.0 for k in ("phi", "D", "gamma", "phit", "f", "a", "lam")}

    def rel(a, b):
        a, b = np.asarray(a, float), np.asarray(b, float).reshape(np.shape(a))
        if not np.size(a):
            return 0.0
        return float(np.max(np.abs(a - b))) / max(1.0, float(np.max(np.abs(a))),
                                                  float(np.max(np.abs(b))))
    t_sym = 0.0
    for _ in range(states):
        y = y0.copy()
        for b in range(nb):
            y[7 * b:7 * b + 3] += rng.normal(0, spread, 3)
            p = y[7 * b + 3:7 * b + 7] + rng.normal(0, spread, 4)
            y[7 * b + 3:7 * b + 7] = p / np.linalg.norm(p)
        y[nq:] = rng.normal(0, 1.0, 6 * nb)
        tt = float(rng.uniform(0, 1))
        e = evaluate_spatial(sc, y, tt)
        c1 = time.perf_counter()
        phi, cm, gam, phit, _f = sym_eval(y, tt)
        t_sym += time.perf_counter() - c1
        if m:
            worst["phi"] = max(worst["phi"], rel(phi.ravel(), e["phi"]))
            worst["D"] = max(worst["D"], rel(cm.reshape(m, -1), e["C"]))
            worst["gamma"] = max(worst["gamma"], rel(gam.ravel(), e["gamma"]))
            worst["phit"] = max(worst["phit"], rel(phit.ravel(), e["phi_t"]))
        # an admissible state: the initial pose, w in the null space of C, less Phi_t
        y = y0.copy()
        tt = 0.0
        phi, cm, gam, phit, f = sym_eval(y, tt)
        w = rng.normal(0, 1.0, 6 * nb)
        if m:
            cm = cm.reshape(m, -1)
            w = w - np.linalg.pinv(cm) @ (cm @ w + phit.ravel())
        y[nq:] = w
        e = evaluate_spatial(sc, y, tt)
        phi, cm, gam, phit, f = sym_eval(y, tt)
        f = f.ravel()
        if m:
            cm = cm.reshape(m, -1)
            kkt = np.block([[mmat, cm.T], [cm, np.zeros((m, m))]])
            sol = np.linalg.lstsq(kkt, np.concatenate([f, gam.ravel()]), rcond=None)[0]
            a = sol[:6 * nb]
        else:
            a = np.linalg.solve(mmat, f)
        # as M a: a slender bar's acceleration about its own axis (an inertia 1e-6 of the
        # others) carries roundoff amplified by that ratio on either side
        worst["a"] = max(worst["a"], rel(mmat @ a, mmat @ e["ydot"][nq:]))
    worst["f"] = worst["lam"] = None       # f enters through M a; lam is not unique
    worst["f_from_kernel"] = False
    worst["derive_s"] = derive_s
    worst["kernel_ns"] = None
    worst["symbolic_ns"] = 1e9 * t_sym / states
    return worst
