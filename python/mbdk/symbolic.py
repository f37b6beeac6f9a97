"""A scene's equations derived symbolically (SymPy), as the book does by hand and in MATLAB in
sections 3.4-3.5, and compared with the compiled assembly at random states.

>>> import mbdk.symbolic
>>> sm = mbdk.symbolic.derive(mbdk.scene("double_pendulum"))
>>> sm.D.shape                            # D = dPhi/dq, a SymPy matrix in q
(4, 6)
>>> diff = mbdk.symbolic.cross_check(mbdk.scene("double_pendulum"))   # max differences
>>> all(diff[k] < 1e-12 for k in ("phi", "D", "gamma", "phit", "f", "a", "lam"))
True

derive() writes each joint's constraint from its definition, independently of the kernel's
hand-derived rows (kernel/src/model/mbdk_joints.f90): Phi(q, t) for the holonomic kinds, and
for a knife edge its velocity form A(q) v (the velocity of its point across the blade). From
them SymPy differentiates D = dPhi/dq, Phi_t, and::

    gamma = -(d(D v)/dq) v - 2 (dD/dt) v - Phi_tt        (holonomic rows, (2.147))
    gamma = -(d(A v)/dq) v - (dA/dt) v                   (velocity rows)

so that D q'' = gamma on the motion. The forces f(q, v, t) are the generalised forces of the
scene's loads written from their definitions: gravity m g, point forces F f(t) at a
body point (F . dP/dq), torques, springs and dampers as -dV/dq and -c l' dl/dq (the principle
of virtual power, section 2.3) and the coordinate spring-dampers. Contacts are compliant
forces whose symbolic form (IMPACT law, involute meshes) is not derived here: for a scene with
contacts f is taken from the kernel, and the comparison says so (f_from_kernel).

cross_check() evaluates the derivation (lambdified) and the kernel (mbdk.model.evaluate) at
random states around the assembled pose and compares Phi, D, gamma, Phi_t, f and the reduced
accelerations and multipliers, [M D^T; D 0] [a; lam] = [f; gamma], the symbolic side solved
by numpy on its own matrices. Spatial scenes are derived by mbdk.symbolic.derive_spatial.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from . import model as M
from .codes import COORDS
from .errors import InvalidInputError, MbdkError
from .scene import GROUND, Scene
from .scene_file import checked
from .symbolic_spatial import cross_check_spatial


def _sympy():
    try:
        # SymPy: optional (the studies' and tests' extra), slow to import
        import sympy
    except ImportError:      # pragma: no cover - sympy is in the test and study extras
        raise InvalidInputError("mbdk.symbolic needs SymPy: pip install sympy") from None
    return sympy


@dataclass
class SymbolicModel:
    """A planar scene's equations in SymPy: q, v (symbols per body: x, y, theta and their
    rates), t; Phi, D, gamma, Phi_t (m rows), M (diagonal), f (nc; None where a force has no
    symbolic form here: contacts), pfaffian (rows that constrain velocities only)."""
    q: list
    v: list
    t: object
    phi: object
    D: object
    gamma: object
    phit: object
    M: object
    f: object
    pfaffian: list = field(default_factory=list)
    rows: list = field(default_factory=list)     # (joint name, first row, rows)


def _time_fn(sp, c, t):
    """The time-function family offset + rate t + amplitude sin(omega t + phase) at t."""
    off, rate, amp, om, ph = (float(x) for x in c)
    return off + rate * t + amp * sp.sin(om * t + ph)


def derive(sc: Scene, q0=None) -> SymbolicModel:
    """The symbolic equations of a planar scene. Values the scene leaves to its initial pose (a
    prismatic or fixed joint's relative angle, a distance's length, a coupling's or a rolling
    disc's offset, a spring's rest length) are taken at q0 (default: the assembled pose)."""
    sp = _sympy()
    if not isinstance(sc, Scene):
        raise InvalidInputError(f"derive takes a planar Scene, got {type(sc).__name__} (spatial "
                                "scenes: derive_spatial)")
    if q0 is None:
        q0 = M.assemble(sc, M.build_tables(sc))[0]
    q0 = np.asarray(q0, float)
    nb = len(sc.bodies)
    t = sp.Symbol("t", real=True)
    q, v = [], []
    for b in sc.bodies:
        for c in ("x", "y", "th"):
            q.append(sp.Symbol(f"{c}_{b.name}", real=True))
            v.append(sp.Symbol(f"d{c}_{b.name}", real=True))
    idx = {b.name: k for k, b in enumerate(sc.bodies)}

    def coords(name):
        if name == GROUND:
            return 0, 0, 0
        k = 3 * idx[name]
        return q[k], q[k + 1], q[k + 2]

    def rates(name):
        if name == GROUND:
            return 0, 0, 0
        k = 3 * idx[name]
        return v[k], v[k + 1], v[k + 2]

    def rot(th, s):
        return sp.Matrix([sp.cos(th) * s[0] - sp.sin(th) * s[1],
                          sp.sin(th) * s[0] + sp.cos(th) * s[1]])

    def point(name, s):
        s = [float(c) for c in s]
        if name == GROUND:
            return sp.Matrix(s)
        x, y, th = coords(name)
        return sp.Matrix([x, y]) + rot(th, s)

    def angle(name):
        return coords(name)[2]

    def at_q0(expr):
        return float(expr.subs(dict(zip(q, q0))))

    rows, kinds, names = [], [], []
    for j in sc.joints:
        r0 = len(rows)
        if j.type in ("revolute", "fixed"):
            d = point(j.body1, j.point1) - point(j.body2, j.point2)
            rows += [d[0], d[1]]
            kinds += ["q", "q"]
            if j.type == "fixed":
                rel = angle(j.body1) - angle(j.body2)
                th0 = j.angle0 if j.angle0 is not None else at_q0(sp.sympify(rel))
                rows.append(rel - th0)
                kinds.append("q")
        elif j.type in ("prismatic", "point_line"):
            u = rot(angle(j.body2), j.axis) if j.body2 != GROUND else sp.Matrix(j.axis)
            n = sp.Matrix([-u[1], u[0]])
            if j.type == "prismatic":
                rel = angle(j.body1) - angle(j.body2)
                th0 = j.angle0 if j.angle0 is not None else at_q0(sp.sympify(rel))
                rows.append(rel - th0)
                kinds.append("q")
            rows.append((n.T * (point(j.body1, j.point1) - point(j.body2, j.point2)))[0])
            kinds.append("q")
        elif j.type == "driver":
            rows.append(coords(j.body1)[COORDS[j.coordinate] - 1] - _time_fn(sp, j.function, t))
            kinds.append("q")
        elif j.type == "distance":
            d = point(j.body1, j.point1) - point(j.body2, j.point2)
            dist = sp.sqrt(d[0] ** 2 + d[1] ** 2)
            length = (_time_fn(sp, j.length, t) if j.length is not None else at_q0(dist))
            rows.append(dist - length)
            kinds.append("q")
        elif j.type == "point_curve":
            p = point(j.body1, j.point1)
            rows.append(p[1] - _time_fn(sp, j.curve, p[0]))
            kinds.append("q")
        elif j.type == "coupling":
            expr = coords(j.body2)[COORDS[j.coordinate2] - 1] - \
                j.ratio * coords(j.body1)[COORDS[j.coordinate] - 1]
            rows.append(expr - at_q0(sp.sympify(expr)))
            kinds.append("q")
        elif j.type == "rolling":
            x, y, th = coords(j.body1)
            u = sp.Matrix(j.axis)
            n = sp.Matrix([-u[1], u[0]])
            c = sp.Matrix([x, y])
            roll = (u.T * c)[0] + j.radius * th
            rows += [(n.T * (c - sp.Matrix(j.point2)))[0] - j.radius, roll - at_q0(roll)]
            kinds += ["q", "q"]
        elif j.type == "knife_edge":
            p = point(j.body1, j.point1)
            pdot = p.jacobian(q) * sp.Matrix(v)
            u = rot(angle(j.body1), j.axis)
            rows.append((sp.Matrix([-u[1], u[0]]).T * pdot)[0])
            kinds.append("v")
        else:
            raise InvalidInputError(f"{sc.source}: joint {j.name!r}: type {j.type!r} has no "
                                    "symbolic form in mbdk.symbolic")
        names.append((j.name, r0, len(rows) - r0))

    qv, vv = sp.Matrix(q), sp.Matrix(v)
    m = len(rows)
    phi = sp.zeros(m, 1)
    dmat = sp.zeros(m, 3 * nb)
    gam = sp.zeros(m, 1)
    phit = sp.zeros(m, 1)
    for i, (e, k) in enumerate(zip(rows, kinds)):
        if k == "q":
            e = sp.sympify(e)
            dr = sp.Matrix([e]).jacobian(qv)
            dv = (dr * vv)[0]
            phi[i] = e
            dmat[i, :] = dr
            phit[i] = sp.diff(e, t)
            gam[i] = -((sp.Matrix([dv]).jacobian(qv) * vv)[0] + 2 * sp.diff(dv, t)
                       + sp.diff(e, t, 2))
        else:          # A(q) v: D = A, Phi = 0, Phi_t = 0 (b = 0), gamma = -d(A v)/dt at a = 0
            a = sp.Matrix([e]).jacobian(vv)
            dmat[i, :] = a
            av = (a * vv)[0]
            gam[i] = -((sp.Matrix([av]).jacobian(qv) * vv)[0] + sp.diff(av, t))

    mass = sp.diag(*[c for b in sc.bodies for c in (b.mass, b.mass, b.inertia)])
    f = sp.zeros(3 * nb, 1)
    for fo in sc.forces:
        if fo.type == "gravity":
            for b in sc.bodies:
                k = 3 * idx[b.name]
                f[k] += b.mass * fo.g[0]
                f[k + 1] += b.mass * fo.g[1]
        elif fo.type == "point_force":
            p = point(fo.body1, fo.point1)
            load = sp.Matrix(fo.force) * _time_fn(sp, fo.function, t)
            f += p.jacobian(qv).T * load
        elif fo.type == "torque":
            f[3 * idx[fo.body1] + 2] += fo.torque * _time_fn(sp, fo.function, t)
        elif fo.type in ("spring", "damper", "spring_damper"):
            d = point(fo.body1, fo.point1) - point(fo.body2, fo.point2)
            length = sp.sqrt(d[0] ** 2 + d[1] ** 2)
            grad = sp.Matrix([length]).jacobian(qv)
            rate = (grad * vv)[0]
            force = 0
            if fo.type != "damper":
                rest = fo.rest_length if fo.rest_length is not None else at_q0(length)
                force += fo.stiffness * (length - rest)
            if fo.type != "spring":
                force += fo.damping * rate
            f -= grad.T * force
        elif fo.type.startswith("coordinate"):
            k = 3 * idx[fo.body1] + COORDS[fo.coordinate] - 1
            f[k] += -fo.stiffness * (q[k] - fo.rest) - fo.damping * v[k]
        elif fo.type == "contact":
            f = None
            break
        else:
            raise InvalidInputError(f"{sc.source}: force {fo.name!r}: type {fo.type!r} has no "
                                    "symbolic form in mbdk.symbolic")
    return SymbolicModel(q, v, t, phi, dmat, gam, phit, mass, f,
                         [k == "v" for k in kinds], names)


def _scale(a, b):
    return max(1.0, float(np.max(np.abs(a))) if np.size(a) else 1.0,
               float(np.max(np.abs(b))) if np.size(b) else 1.0)


def cross_check(sc, states: int = 5, seed: int = 0, spread: float = 0.1) -> dict:
    """Max differences between the symbolic derivation and the kernel at `states` random
    states (q = the assembled pose + N(0, spread), v = N(0, 1), t in [0, 1]), each relative to
    the larger magnitude of the two sides (at least 1): {"phi", "D", "gamma", "phit", "f", "a",
    "lam"}, with "f_from_kernel" (a scene with contacts), "derive_s" (SymPy's derivation and
    lambdification, CPU seconds), "kernel_ns" (the kernel's assembly of Phi, D, gamma and f,
    timed inside it; None where no state evaluates) and "symbolic_ns" (the lambdified
    expressions, one state)."""
    if isinstance(sc, Scene) and sc.kind == "spatial":
        return cross_check_spatial(sc, states, seed, spread)
    sp = _sympy()
    sc = checked(sc)
    tab = M.build_tables(sc)
    q0 = M.assemble(sc, tab)[0]
    tab = M.build_tables(sc, q0)
    c0 = time.process_time()
    sm = derive(sc, q0)
    args = [*sm.q, *sm.v, sm.t]
    fns = {k: sp.lambdify(args, getattr(sm, k), "numpy")
           for k in ("phi", "D", "gamma", "phit")}
    f_sym = sp.lambdify(args, sm.f, "numpy") if sm.f is not None else None
    derive_s = time.process_time() - c0
    mass = np.diag(np.array(sm.M, float))
    rng = np.random.default_rng(seed)
    nc, m = len(sm.q), sm.phi.shape[0]
    worst = {k: 0.0 for k in ("phi", "D", "gamma", "phit", "f", "a", "lam")}
    t_sym = 0.0
    for _ in range(states):
        q = q0 + rng.normal(0.0, spread, nc)
        v = rng.normal(0.0, 1.0, nc)
        t = float(rng.uniform(0.0, 1.0))
        e = M.evaluate(tab, q, v, t)
        c2 = time.perf_counter()
        vals = {k: np.array(fn(*q, *v, t), float).reshape(getattr(sm, k).shape)
                for k, fn in fns.items()}
        f = (np.array(f_sym(*q, *v, t), float).ravel() if f_sym is not None
             else np.asarray(e["f"], float))
        t_sym += time.perf_counter() - c2
        ker = {"phi": e["phi"], "D": e["D"], "gamma": e["gamma"], "phit": e["phit"],
               "f": e["f"]}
        sym = {"phi": vals["phi"].ravel(), "D": vals["D"], "gamma": vals["gamma"].ravel(),
               "phit": vals["phit"].ravel(), "f": f}
        if m:
            kkt = np.block([[np.diag(mass), vals["D"].T], [vals["D"], np.zeros((m, m))]])
            sol = np.linalg.solve(kkt, np.concatenate([f, sym["gamma"]]))
            sym["a"], sym["lam"] = sol[:nc], sol[nc:]
        else:
            sym["a"], sym["lam"] = f / mass, np.zeros(0)
        ker["a"], ker["lam"] = e["a"], e["lam"]
        for k in worst:
            a, b = np.asarray(sym[k], float), np.asarray(ker[k], float).reshape(np.shape(sym[k]))
            if np.size(a):
                worst[k] = max(worst[k], float(np.max(np.abs(a - b))) / _scale(a, b))
    worst["f_from_kernel"] = f_sym is None
    worst["derive_s"] = derive_s
    # the kernel's own assembly (Phi, D, gamma, f), timed inside it, against one evaluation of
    # the lambdified expressions through numpy
    worst["kernel_ns"] = None
    for qq in (q0, q):      # a state whose full evaluation succeeds (the parallelogram's
        try:                # assembled pose is singular, a random one may overrun a contact)
            worst["kernel_ns"] = M.profile(tab, qq, v, t, nrep=20000)["assembly_ns"]
            break
        except MbdkError:
            pass
    worst["symbolic_ns"] = 1e9 * t_sym / states
    return worst
