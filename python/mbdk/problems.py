"""The compiled textbook problems (kernel/src/problems/mbdk_textbook.f90): parameter names in
the kernel's order, defaults as printed in the book, the state layout and where each comes from.

The book states the damped oscillator's coefficients two ways: (4.53)-(4.54) and (4.57)-(4.58)
give y'' + 0.5 y' + 10 y = 0 (m = 10, c = 5, k = 100), while (4.56) prints
y'' = -5 y - 0.01 y'. The worked steps (4.60) and (4.68) and tables 4.6 and 4.7 are reproduced by
the first (studies/ch4_tables.py shows both), so that is the default here.
"""
from __future__ import annotations

import math

from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from . import _kernel
from .checks import show
from .errors import InvalidInputError, UnknownParameterError, UnknownProblemError, decode_text
from .exact import EXACT


@dataclass(frozen=True)
class ProblemInfo:
    name: str
    id: int
    n: int                      # state size (0: given by y0)
    params: dict                # name -> default, in the kernel's order
    y0: tuple | None            # default initial state (None: must be given)
    t_end: float                # the book's interval
    states: tuple               # names of the state components
    equation: str
    reference: str
    second_order: bool          # y = [q; v], euler_cromer applies
    positive: tuple = ()        # parameters that must be > 0
    nonzero: tuple = ()         # parameters that must be /= 0
    energy: Callable | None = field(default=None, repr=False, compare=False)

    @property
    def has_exact(self) -> bool:
        return self.name in EXACT


def _pendulum_energy(y, p):
    """Energy per unit moment of inertia: phi'^2/2 - (3g/2l) cos(phi)."""
    w2 = 1.5 * p["g"] / p["l"]
    return 0.5 * y[:, 1] ** 2 - w2 * np.cos(y[:, 0])


def _pendulum_linear_energy(y, p):
    w2 = 1.5 * p["g"] / p["l"]
    return 0.5 * y[:, 1] ** 2 + 0.5 * w2 * y[:, 0] ** 2


def _oscillator_energy(y, p):
    return 0.5 * p["m"] * y[:, 1] ** 2 + 0.5 * p["k"] * y[:, 0] ** 2


def _crane_energy(y, p):
    """Kinetic + spring + gravity energy of the trolley crane (J); coupling as in the kernel."""
    m1, m2, l, g, s, c = p["m1"], p["m2"], p["l"], p["g"], p["s"], p["coupling"]
    x, phi, v, w = y[:, 0], y[:, 1], y[:, 2], y[:, 3]
    kin = 0.5 * (m1 + m2) * v**2 - c * 0.5 * m2 * l * np.sin(phi) * v * w + m2 * l**2 * w**2 / 6
    return kin + 0.5 * s * x**2 + m2 * g * 0.5 * l * np.sin(phi)


def _double_pendulum_energy(y, p):
    m1, m2, l1, l2, g = p["m1"], p["m2"], p["l1"], p["l2"], p["g"]
    p1, p2, w1, w2 = y[:, 0], y[:, 1], y[:, 2], y[:, 3]
    kin = (0.5 * (m1 / 3 + m2) * l1**2 * w1**2 + m2 * l2**2 * w2**2 / 6
           + 0.5 * m2 * l1 * l2 * np.cos(p1 - p2) * w1 * w2)
    pot = m1 * g * 0.5 * l1 * np.sin(p1) + m2 * g * (l1 * np.sin(p1) + 0.5 * l2 * np.sin(p2))
    return kin + pot


_FOUR_BAR = {"a": 0.6, "b": 1.8, "c": 1.2, "d": 2.0, "m1": 0.6, "m2": 1.8, "m3": 1.2, "g": 9.81,
             "alpha": 0.0, "beta": 0.0}


def four_bar_points(p: dict, crank: float) -> tuple[np.ndarray, np.ndarray]:
    """Joints B and C of the four-bar at crank angle `crank` (rad), on the branch with C above
    the line BD (the built-in scene 'four_bar' is assembled on the same branch)."""
    a, b, c, d = p["a"], p["b"], p["c"], p["d"]
    rb = np.array([a * np.cos(crank), a * np.sin(crank)])
    rd = np.array([d, 0.0])
    bd = rd - rb
    L = float(np.hypot(*bd))
    if not abs(b - c) < L < b + c:
        raise InvalidInputError(f"the four-bar cannot be assembled at crank = {crank} rad: "
                                f"|BD| = {L:.6g} is outside ({abs(b - c):.6g}, {b + c:.6g})")
    u = bd / L
    along = (b**2 - c**2 + L**2) / (2 * L)
    across = np.sqrt(b**2 - along**2)
    rc = rb + along * u + across * np.array([-u[1], u[0]])
    return rb, rc


def four_bar_state(form: str, p: dict | None = None, crank: float = np.pi / 3) -> tuple:
    """Consistent state at rest at crank angle `crank` for form 'relative' or 'natural'."""
    p = {**_FOUR_BAR, **(p or {})}
    rb, rc = four_bar_points(p, crank)
    if form == "relative":
        e2 = rc - rb
        e3 = np.array([p["d"], 0.0]) - rc
        return (crank, float(np.arctan2(e2[1], e2[0])), float(np.arctan2(e3[1], e3[0])),
                0.0, 0.0, 0.0)
    if form == "natural":
        return (*map(float, rb), *map(float, rc), 0.0, 0.0, 0.0, 0.0)
    raise InvalidInputError(f"four-bar form {form!r} must be 'relative' or 'natural'")


def _four_bar_relative_energy(y, p):
    a, b, c, m1, m2, m3, g = (p[k] for k in ("a", "b", "c", "m1", "m2", "m3", "g"))
    p1, p2, p3, w1, w2, w3 = y.T
    kin = (0.5 * (m1 / 3 + m2) * a**2 * w1**2 + m2 * b**2 * w2**2 / 6 + m3 * c**2 * w3**2 / 6
           + 0.5 * m2 * a * b * np.cos(p1 - p2) * w1 * w2)
    pot = g * ((0.5 * m1 + m2) * a * np.sin(p1) + 0.5 * m2 * b * np.sin(p2)
               - 0.5 * m3 * c * np.sin(p3))
    return kin + pot


def _four_bar_natural_energy(y, p):
    m1, m2, m3, g = (p[k] for k in ("m1", "m2", "m3", "g"))
    vb, vc = y[:, 4:6], y[:, 6:8]
    kin = ((m1 + m2) / 6 * (vb**2).sum(1) + (m2 + m3) / 6 * (vc**2).sum(1)
           + m2 / 6 * (vb * vc).sum(1))
    pot = 0.5 * g * ((m1 + m2) * y[:, 1] + (m2 + m3) * y[:, 3])
    return kin + pot


def _rigid_body_energy(y, p):
    """Kinetic energy of the torque-free body: (J1 W1^2 + J2 W2^2 + J3 W3^2) / 2."""
    y = np.atleast_2d(y)
    return 0.5 * (p["J1"] * y[:, 4] ** 2 + p["J2"] * y[:, 5] ** 2 + p["J3"] * y[:, 6] ** 2)


def _heavy_top_energy(y, p):
    """Kinetic energy plus m g l times the height of the body's 3-axis (R33 of q / |q|)."""
    y = np.atleast_2d(y)
    q = y[:, :4] / np.linalg.norm(y[:, :4], axis=1)[:, None]
    z3 = q[:, 0] ** 2 - q[:, 1] ** 2 - q[:, 2] ** 2 + q[:, 3] ** 2
    return _rigid_body_energy(y, p) + p["m"] * p["g"] * p["l"] * z3


def _rigid_body_angles_energy(y, p):
    y = np.atleast_2d(y)
    return 0.5 * (p["J1"] * y[:, 3] ** 2 + p["J2"] * y[:, 4] ** 2 + p["J3"] * y[:, 5] ** 2)


def rigid_body_momentum(y, p) -> np.ndarray:
    """The space-frame angular momentum L = R(q) J Omega of free_rigid_body states (one row
    per state; q normalised for R, so that a drift of |q| does not show up as one of L)."""
    y = np.atleast_2d(y)
    q = y[:, :4] / np.linalg.norm(y[:, :4], axis=1)[:, None]
    s, v = q[:, 0], q[:, 1:]
    jw = y[:, 4:] * np.array([p["J1"], p["J2"], p["J3"]])
    # R x = x + 2 s (v x x) + 2 v x (v x x)
    t = np.cross(v, jw)
    return jw + 2.0 * s[:, None] * t + 2.0 * np.cross(v, t)


_SPECS = {
    "linear_growth": dict(params={"a": 2.0}, y0=(1.0,), t_end=10.0, states=("y",),
                          equation="y' = a t", reference="Fekete (2023) (4.8)"),
    "decay": dict(params={"lambda": 1.0}, y0=(1.0,), t_end=10.0, states=("y",),
                  equation="y' = -lambda y", reference="Fekete (2023) (4.14)"),
    "riccati": dict(params={"a": 1.0, "b": 2.0}, y0=(-5.0,), t_end=5.0, states=("x",),
                    equation="x' = a t x^2 + b x", reference="Fekete (2023) (4.25)"),
    "beam_linear": dict(params={"F": 5000.0, "l": 1000.0, "EI": 4.2e10}, y0=(0.0,), t_end=1000.0,
                        states=("phi",), equation="phi' = -(F/EI)(l - x)   [x in mm]",
                        reference="Fekete (2023) (4.42)", nonzero=("EI",)),
    "beam_nonlinear": dict(params={"F": 5000.0, "l": 1000.0, "EI": 4.2e10}, y0=(0.0,),
                           t_end=1000.0, states=("phi",),
                           equation="phi' = -(F/EI)(l - x)(1 + phi^2)^(3/2)",
                           reference="Fekete (2023) (4.50)", nonzero=("EI",)),
    "damped_oscillator": dict(params={"m": 10.0, "c": 5.0, "k": 100.0}, y0=(5.0, 1.0), t_end=20.0,
                              states=("y", "y'"), equation="m y'' + c y' + k y = 0",
                              reference="Fekete (2023) (4.53)-(4.58)", positive=("m",),
                              energy=_oscillator_energy),
    "pendulum": dict(params={"g": 9.81, "l": 1.0}, y0=(0.5235987755982988, 0.0), t_end=5.0,
                     states=("phi", "phi'"), equation="phi'' = -(3g/2l) sin(phi)",
                     reference="Fekete (2023) (4.69)", positive=("l",), energy=_pendulum_energy),
    "pendulum_linear": dict(params={"g": 9.81, "l": 1.0}, y0=(0.5235987755982988, 0.0), t_end=5.0,
                            states=("phi", "phi'"), equation="phi'' = -(3g/2l) phi",
                            reference="Fekete (2023) (4.77)", positive=("l",),
                            energy=_pendulum_linear_energy),
    "trolley_crane": dict(params={"m1": 10.0, "m2": 1.0, "l": 1.0, "g": 9.81, "k": 50.0,
                                  "s": 3000.0, "coupling": -1.0},
                          y0=(0.5, -0.5235987755982988, 0.0, 0.0), t_end=5.0,
                          states=("x1", "phi", "x1'", "phi'"),
                          equation="(4.78); coupling=-1 as printed, +1 the consistent mechanism",
                          reference="Fekete (2023) (4.78), (3.57)", positive=("m1", "m2", "l"),
                          energy=_crane_energy),
    "double_pendulum": dict(params={"m1": 1.0, "m2": 2.0, "l1": 1.0, "l2": 2.0, "g": 9.81},
                            y0=(-1.308, -1.57, 0.0, 0.0), t_end=5.0,
                            states=("phi1", "phi2", "phi1'", "phi2'"),
                            equation="(3.64), angles from the horizontal",
                            reference="Fekete (2023) (3.64), 4.4.2",
                            positive=("m1", "m2", "l1", "l2"), energy=_double_pendulum_energy),
    "linear_system": dict(params={"A": ((0.0, 1.0), (-10.0, -0.5))}, y0=(5.0, 1.0), t_end=20.0,
                          states=(), equation="y' = A y", reference="Fekete (2023) (4.58)"),
    "four_bar_relative": dict(params=dict(_FOUR_BAR), y0=four_bar_state("relative"), t_end=5.0,
                              states=("phi1", "phi2", "phi3", "phi1'", "phi2'", "phi3'"),
                              equation="four-bar, relative coordinates: (3.28) with Phi of (1.29); "
                                       "phi3 is the direction C->D",
                              reference="Fekete (2023) (1.28)-(1.29)",
                              positive=("a", "b", "c", "d", "m1", "m2", "m3"),
                              energy=_four_bar_relative_energy),
    "four_bar_natural": dict(params=dict(_FOUR_BAR), y0=four_bar_state("natural"), t_end=5.0,
                             states=("xB", "yB", "xC", "yC", "xB'", "yB'", "xC'", "yC'"),
                             equation="four-bar, natural coordinates: (3.28) with Phi of (1.31)",
                             reference="Fekete (2023) (1.30)-(1.31)",
                             positive=("a", "b", "c", "d", "m1", "m2", "m3"),
                             energy=_four_bar_natural_energy),
    "free_rigid_body": dict(params={"J1": 1.0, "J2": 2.0, "J3": 3.0},
                            y0=(1.0, 0.0, 0.0, 0.0, 0.01, 1.0, 0.01), t_end=30.0,
                            states=("q0", "q1", "q2", "q3", "W1", "W2", "W3"),
                            equation="J W' = (J W) x W, q' = q (0, W) / 2 (body frame W, "
                                     "torque-free; default: a spin near the intermediate axis, "
                                     "which flips)",
                            reference="Fekete (2023) (5.1)-(5.3), (5.73)-(5.95)",
                            positive=("J1", "J2", "J3"), energy=_rigid_body_energy),
    "heavy_top": dict(params={"J1": 0.015, "J2": 0.015, "J3": 0.01, "m": 1.0, "g": 9.81,
                              "l": 0.1},
                      y0=(0.9659258262890683, 0.25881904510252074, 0.0, 0.0, 0.0, 0.0, 100.0),
                      t_end=10.0, states=("q0", "q1", "q2", "q3", "W1", "W2", "W3"),
                      equation="J W' = (J W) x W + m g l (z2, -z1, 0), z = R(q)^T e_z, "
                               "q' = q (0, W) / 2 (J about the fixed point; the centre at l on "
                               "body axis 3; default: tilted 30 deg, spinning at 100 rad/s)",
                      reference="Fekete (2023) (5.1)-(5.3); the Lagrange top",
                      positive=("J1", "J2", "J3", "m"), energy=_heavy_top_energy),
    "rigid_body_angles": dict(params={"J1": 1.0, "J2": 2.0, "J3": 3.0, "sequence": 313.0},
                              y0=(0.0, 0.5, 0.0, 0.01, 1.0, 0.01), t_end=30.0,
                              states=("a1", "a2", "a3", "W1", "W2", "W3"),
                              equation="free_rigid_body with the angles of sequence 313 (Euler) "
                                       "or 123 (Cardan): a' = G_b(a)^-1 W (5.43); a gimbal "
                                       "lock stops the run (SingularMatrixError)",
                              reference="Fekete (2023) (5.40)-(5.45)",
                              positive=("J1", "J2", "J3"), energy=_rigid_body_angles_energy),
}


def _load() -> dict[str, ProblemInfo]:
    out = {}
    i = 1
    while True:
        name, n, np_ = _kernel.problem_info(i)
        if n < 0:
            break
        name = decode_text(name)
        spec = dict(_SPECS[name])
        if name != "linear_system" and len(spec["params"]) != np_:
            raise RuntimeError(f"problem {name}: kernel has {np_} parameters, registry "
                               f"{len(spec['params'])}")
        out[name] = ProblemInfo(name=name, id=i, n=int(n),
                                second_order=name in ("damped_oscillator", "pendulum",
                                                      "pendulum_linear", "trolley_crane",
                                                      "double_pendulum", "four_bar_relative",
                                                      "four_bar_natural"),
                                **spec)
        i += 1
    return out


_REGISTRY = _load()


def problems() -> dict[str, ProblemInfo]:
    """Every compiled problem, by name."""
    return dict(_REGISTRY)


def problem(name: str) -> ProblemInfo:
    try:
        return _REGISTRY[name]
    except (KeyError, TypeError):
        raise UnknownProblemError(
            f"unknown problem {name!r}; known problems: {', '.join(_REGISTRY)}") from None


def resolve_params(info: ProblemInfo, params: dict | None, n: int) -> tuple[dict, np.ndarray]:
    """Defaults overridden by params; returns the merged dict and the flat vector for the kernel."""
    merged = dict(info.params)
    if params is not None:
        if not isinstance(params, dict):
            raise InvalidInputError(f"params must be a dict of parameter values, got "
                                    f"{type(params).__name__}")
        for key, value in params.items():
            if key not in merged:
                raise UnknownParameterError(
                    f"problem {info.name!r} has no parameter {key!r}; its parameters are: "
                    f"{', '.join(merged)}")
            merged[key] = value
    if info.name == "linear_system":
        try:
            a = np.array(merged["A"], dtype=float)
        except (TypeError, ValueError, OverflowError):
            raise InvalidInputError("params['A'] is not a matrix of numbers in floating-point "
                                    "range") from None
        if a.ndim != 2 or a.shape != (n, n):
            raise InvalidInputError(f"params['A'] must be a {n}x{n} matrix to match y0 of size "
                                    f"{n}, got shape {a.shape}")
        if not np.all(np.isfinite(a)):
            raise InvalidInputError("params['A'] has a non-finite entry; give finite numbers")
        merged["A"] = a
        return merged, np.asfortranarray(a).ravel(order="F")
    vec = []
    for key, value in merged.items():
        try:
            v = float(value)
        except (TypeError, ValueError, OverflowError):
            raise InvalidInputError(f"params[{key!r}] = {show(value)} is not a number in "
                                    "floating-point range") from None
        if not math.isfinite(v):
            raise InvalidInputError(f"params[{key!r}] = {v} is not finite; give a finite number")
        if key in info.positive and not v > 0:
            raise InvalidInputError(f"params[{key!r}] = {v} must be > 0 for problem {info.name!r}")
        if key in info.nonzero and v == 0:
            raise InvalidInputError(f"params[{key!r}] = {v} must not be zero for problem "
                                    f"{info.name!r}")
        merged[key] = v
        vec.append(v)
    if info.name == "trolley_crane" and merged["coupling"] not in (-1.0, 1.0):
        raise InvalidInputError(f"params['coupling'] = {merged['coupling']} must be -1 (the book's "
                                "(4.78)) or +1 (the consistent mechanism)")
    if info.name == "rigid_body_angles" and merged["sequence"] not in (313.0, 123.0):
        raise InvalidInputError(f"params['sequence'] = {merged['sequence']}: 313 (Euler angles) "
                                "or 123 (Cardan angles)")
    if info.name in ("free_rigid_body", "heavy_top", "rigid_body_angles"):
        for a, b, c in (("J1", "J2", "J3"), ("J2", "J3", "J1"), ("J3", "J1", "J2")):
            if merged[a] > merged[b] + merged[c]:
                raise InvalidInputError(
                    f"params[{a!r}] = {merged[a]} exceeds {b} + {c} = "
                    f"{merged[b] + merged[c]}: no rigid body has these principal inertias "
                    "(each is at most the sum of the other two)")
    return merged, np.array(vec, dtype=float)
