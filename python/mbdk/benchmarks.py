"""Public benchmark mechanisms built by parameter, with their exact solutions.

IFToMM A02 (the IFToMM library of computational benchmark problems for multibody systems,
lim.ii.udc.es/mbsbenchmark, problem A02 "N four-bar mechanism"): N loops in a row, every bar 1 m and
1 kg (a uniform bar: inertia 1/12 kg m^2 about its centre). N + 1 cranks are hinged to the
ground at x = 0, 1, .., N, start vertical (angle 90 deg) and turn at -1 rad/s; N couplers join
the tips of neighbouring cranks, start horizontal at y = 1 and move at 1 m/s along x; gravity is
-9.81 m/s^2 along y. Every loop is a square parallelogram: each time the cranks pass the
horizontal (first at t = 0.71 s, a little later the longer the chain) the whole chain is flat
and D loses N ranks at once (a singular configuration, where the parallelogram may turn into the
crossed branch).

The chain moves as one crank: every crank has the angle theta, every coupler translates with the
crank tips. Lagrange's equation for theta, with the kinetic energy (1/2) J theta'^2 (a crank
about its hinge m L^2 / 3, a coupler m L^2) and the potential c g sin(theta) (a crank's centre
at L/2 sin(theta), a coupler's at L sin(theta)):

    J theta'' = -c g cos(theta),   J = m L^2 ((N + 1)/3 + N),   c = m L ((N + 1)/2 + N).

With psi = theta + pi/2 this is the pendulum psi'' = -w^2 sin(psi), w^2 = c g / J, started at
the top (psi = pi) with psi' = -1: a rotation (energy above the separatrix, k^2 =
sin^2(psi0/2) + (psi0'/(2 w))^2 > 1). With m = 1/k^2, phi = psi/2 obeys phi' = -w k sqrt(1 - m
sin^2 phi), so F(phi | m) = F(phi0 | m) - w k t and

    theta(t) = 2 am(u | m) - pi/2,   theta'(t) = -2 w k dn(u | m),   u = K(m) - w k t

(phi0 = pi/2, F(pi/2 | m) = K(m); am, dn, K from scipy.special, accurate to roundoff).

The driven slider (driven_slider): a block of mass m on a horizontal guide (a prismatic joint
with the ground along x), its x driven as A sin(omega t) (a driver joint), pulled back to x = 0
by a spring of stiffness k, under gravity. Its motion is the drive's, and every force is in
closed form: x'' = -A omega^2 sin(omega t); the drive carries m x'' + k x = A (k - m omega^2)
sin(omega t) (the multiplier of its row is the negative: M a + D^T lambda = f), the guide the
weight m g. Every integrator meets the joints with q exactly: its errors in v, a and lambda are
the constraint directions' alone (the index-3 form's weak spot), with nothing else in the way.
"""
from __future__ import annotations

import numpy as np

from .errors import InvalidInputError
from .rotations import dot_fixed, norm_fixed
from .scene_file import scene_from_dict

G = 9.81


def bar_chain(n: int, angle_deg: float = 0.0):
    """An open chain of n uniform bars (1 m, 1 kg: inertia 1/12 kg m^2 about the centre) on
    revolute joints under gravity (-9.81 m/s^2 along y): bar b0's left end is hinged to the
    ground at the origin, bar b{i}'s left end to the right end of b{i-1}; all at angle_deg,
    at rest. 2 n constraint rows: the scaling benchmark of the sparse path."""
    if isinstance(n, bool) or not (isinstance(n, int) and n >= 1):
        raise InvalidInputError(f"bar_chain: n = {n!r}; the chain needs a whole number of "
                                "bars, 1 or more")
    c, s = np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))
    bodies, joints = [], []
    for i in range(n):
        bodies.append({"name": f"b{i}", "mass": 1.0, "shape": {"type": "bar", "length": 1.0},
                       "x": (i + 0.5) * c, "y": (i + 0.5) * s, "angle_deg": angle_deg})
        joints.append({"name": f"J{i}", "type": "revolute", "body1": f"b{i}",
                       "point1": [-0.5, 0.0], "body2": f"b{i - 1}" if i else "ground",
                       "point2": [0.5, 0.0] if i else [0.0, 0.0]})
    return scene_from_dict({
        "scene": {"name": f"bar_chain_n{n}",
                  "description": f"an open chain of {n} uniform bars (1 m, 1 kg) on revolute "
                                 "joints, hinged to the ground at the origin"},
        "body": bodies, "joint": joints, "force": [{"type": "gravity", "g": [0.0, -G]}]})


def spatial_chain_elements(n: int, bend: float = 0.3) -> tuple[list, list]:
    """spatial_chain's bodies and joints as scene-file dicts (n checked by spatial_chain), for a
    scene that adds elements of its own to the chain."""
    ex = np.array([1.0, 0.0, 0.0])
    bodies, joints, p = [], [], np.zeros(3)
    for i in range(n):
        a = bend if i % 2 else -bend
        d = np.array([np.cos(a), 0.5 * np.sin(a), 0.5 * np.sin(a)])
        d /= norm_fixed(d)
        half = (ex + d) / norm_fixed(ex + d)     # the quaternion turning x onto d
        bodies.append({"name": f"b{i}", "kind": "spatial", "mass": 1.0,
                       "shape": {"type": "bar", "length": 1.0},
                       "position": (p + 0.5 * d).tolist(),
                       "quaternion": [dot_fixed(half, ex), *np.cross(ex, half).tolist()]})
        joint = {"name": f"S{i}", "type": "spherical", "body1": f"b{i}",
                 "point1": [-0.5, 0.0, 0.0]}
        if i:
            joint.update(body2=f"b{i - 1}", point2=[0.5, 0.0, 0.0])
        joints.append(joint)
        p = p + d
    return bodies, joints


def spatial_chain(n: int, bend: float = 0.3):
    """An open chain of n uniform spatial bars (1 m, 1 kg) on spherical joints under gravity
    (-9.81 m/s^2 along y), released at rest from a zigzag out of the x-y plane: bar i points
    along (cos a, sin(a)/2, sin(a)/2) normalised, a = +-bend alternating; bar b0's first end is
    at the origin (a spherical joint with the ground), bar b{i}'s first end at the far end of
    b{i-1}. 3 n constraint rows, none redundant: the scaling benchmark of the spatial model's
    sparse path (benchmarks/spatial_chain.py)."""
    if isinstance(n, bool) or not (isinstance(n, int) and n >= 1):
        raise InvalidInputError(f"spatial_chain: n = {n!r}; the chain needs a whole number of "
                                "bars, 1 or more")
    bodies, joints = spatial_chain_elements(n, bend)
    return scene_from_dict({
        "scene": {"name": f"spatial_chain_n{n}", "rotation": "quaternion",
                  "description": f"an open chain of {n} spatial bars (1 m, 1 kg) on spherical "
                                 "joints, released from a zigzag"},
        "body": bodies, "joint": joints, "force": [{"type": "gravity", "g": [0.0, -G, 0.0]}]})


def a02_chain(n: int):
    """The IFToMM A02 chain of n four-bar loops as a scene: bodies crank0..crank{n} and
    coupler0..coupler{n-1}, revolute joints G{i} (crank i to the ground), L{i} and R{i} (coupler
    i to cranks i and i + 1). Crank 0 keeps its angle and angular velocity when the initial
    state is assembled."""
    if isinstance(n, bool) or not (isinstance(n, int) and n >= 1):
        raise InvalidInputError(f"a02_chain: n = {n!r}; the chain needs a whole number of "
                                "loops, 1 or more")
    bodies, joints = [], []
    for i in range(n + 1):
        bodies.append({"name": f"crank{i}", "mass": 1.0, "shape": {"type": "bar", "length": 1.0},
                       "x": float(i), "y": 0.5, "angle_deg": 90.0, "vx": 0.5, "omega": -1.0,
                       "given": ["angle", "omega"] if i == 0 else []})
        joints.append({"name": f"G{i}", "type": "revolute", "body1": f"crank{i}",
                       "point1": [-0.5, 0.0], "body2": "ground", "point2": [float(i), 0.0]})
    for i in range(n):
        bodies.append({"name": f"coupler{i}", "mass": 1.0,
                       "shape": {"type": "bar", "length": 1.0},
                       "x": i + 0.5, "y": 1.0, "angle_deg": 0.0, "vx": 1.0})
        joints.append({"name": f"L{i}", "type": "revolute", "body1": f"coupler{i}",
                       "point1": [-0.5, 0.0], "body2": f"crank{i}", "point2": [0.5, 0.0]})
        joints.append({"name": f"R{i}", "type": "revolute", "body1": f"coupler{i}",
                       "point1": [0.5, 0.0], "body2": f"crank{i + 1}", "point2": [0.5, 0.0]})
    return scene_from_dict({
        "scene": {"name": f"a02_n{n}",
                  "description": f"IFToMM A02: a chain of {n} four-bar loop(s), 1 m and 1 kg bars"},
        "body": bodies, "joint": joints,
        "force": [{"type": "gravity", "g": [0.0, -G]}]})


def a02_crank(n: int, t) -> tuple[np.ndarray, np.ndarray]:
    """The exact crank angle theta(t) (rad, unwrapped) and angular velocity theta'(t) of the A02
    chain of n loops (the module's derivation)."""
    # SciPy is an optional dependency (the studies' extra): only the exact solution needs it
    from scipy.special import ellipj, ellipk

    t = np.asarray(t, dtype=float)
    big_j = (n + 1) / 3.0 + n
    c = (n + 1) / 2.0 + n
    w = np.sqrt(c * G / big_j)
    k2 = 1.0 + (1.0 / (2.0 * w)) ** 2          # sin^2(pi/2) + (psi0' / 2w)^2, psi0' = -1
    k = np.sqrt(k2)
    m = 1.0 / k2
    u = ellipk(m) - w * k * t
    _sn, _cn, dn, am = ellipj(u, m)
    return 2.0 * am - 0.5 * np.pi, -2.0 * w * k * dn


#: the driven slider's parameters: mass (kg), inertia (kg m^2), spring (N/m), drive amplitude (m)
#: and frequency (rad/s); k != m omega^2, so that the drive carries a force
SLIDER = {"m": 2.0, "j": 0.05, "k": 20.0, "amplitude": 0.1, "omega": 5.0}


def driven_slider():
    """The driven slider of the module header (SLIDER's parameters), at x = 0 moving at
    A omega."""
    p = SLIDER
    return scene_from_dict({
        "scene": {"name": "driven_slider",
                  "description": "a block on a guide, driven along it as A sin(omega t), with "
                                 "a spring to x = 0 (mbdk.benchmarks: every force in closed "
                                 "form)"},
        "body": [{"name": "slider", "mass": p["m"], "inertia": p["j"], "x": 0.0, "y": 0.0,
                  "vx": p["amplitude"] * p["omega"], "given": ["x", "y", "angle", "vx"]}],
        "joint": [{"name": "guide", "type": "prismatic", "body1": "slider", "body2": "ground",
                   "axis": [1.0, 0.0]},
                  {"name": "drive", "type": "driver", "body1": "slider", "coordinate": "x",
                   "function": {"amplitude": p["amplitude"], "omega": p["omega"]}}],
        "force": [{"type": "gravity", "g": [0.0, -G]},
                  {"type": "coordinate_spring_damper", "body": "slider", "coordinate": "x",
                   "stiffness": p["k"], "damping": 0.0, "rest": 0.0}]})


def driven_slider_exact(t) -> dict:
    """The driven slider's exact q, v, a (one row per time: x, y, angle) and multipliers in the
    scene's row order (the guide's angle and y rows, then the drive's x row; M a + D^T lambda
    = f with those rows' D = the unit rows of angle, y and x): (0, -m g, -(m x'' + k x))."""
    p = SLIDER
    t = np.asarray(t, dtype=float)
    a_, w = p["amplitude"], p["omega"]
    zero = np.zeros_like(t)
    x = a_ * np.sin(w * t)
    acc = -a_ * w * w * np.sin(w * t)
    return {"q": np.stack([x, zero, zero], axis=-1),
            "v": np.stack([a_ * w * np.cos(w * t), zero, zero], axis=-1),
            "a": np.stack([acc, zero, zero], axis=-1),
            "multipliers": np.stack([zero, -p["m"] * G + zero, -(p["m"] * acc + p["k"] * x)],
                                    axis=-1)}
