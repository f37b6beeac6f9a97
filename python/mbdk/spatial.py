"""Spatial scenes (chapter 5 of the book): rigid bodies in 3D with spherical, revolute,
universal, cylindrical, prismatic and fixed joints, run by every ODE method of the kernel
(kernel/src/spatial/mbdk_spatial_model.f90 says what the kernel integrates and how).

A spatial scene is a scene file whose bodies say ``kind = "spatial"`` (SI units)::

    [scene]
    name = "heavy_top"
    rotation = "quaternion"        # the orientation coordinates: quaternion | euler313 | cardan123
    quaternion_norm = "project"    # |p| = 1 kept by: project (after each step) | stabilise | none
    norm_gain = 10.0               # stabilise: p' += norm_gain (1 - |p|^2) p / 2, 1/s

    [[body]]
    name = "top"
    kind = "spatial"
    mass = 1.0
    inertia = [0.005, 0.005, 0.01] # principal, about the centre, in the body frame; or a 3 x 3
                                   # matrix [[..], [..], [..]]; or shape = {type = box, size =
                                   # [a, b, c]} | {type = cylinder, radius, length} (axis: body z)
                                   # | {type = sphere, radius} | {type = bar, length} (body x)
    position = [0.0, 0.0, 0.1]     # the centre of mass, space frame
    quaternion = [1.0, 0.0, 0.0, 0.0]   # or euler313 = [phi, theta, psi] (or euler313_deg),
                                        # or cardan123 = [...] (or cardan123_deg); default: none
                                        # a quaternion's norm is 1 to the digits written (within
                                        # 1e-6): the rotation of q / |q| is taken
    velocity = [0.0, 0.0, 0.0]     # of the centre, space frame
    omega_body = [0.0, 0.0, 200.0] # angular velocity in the body frame; or omega (space frame)

    [[joint]]
    type = "spherical"             # spherical | revolute | universal | cylindrical | prismatic
    body1 = "top"                  #   | fixed | angle_driver (body1 turns relative to body2
                                   #   about axis by function(t) from its start, f(t0) = 0;
                                   #   with a revolute joint on that axis) | slide_driver (body1's
                                   #   point slides from body2's along axis by function(t), in
                                   #   metres, f(t0) = 0; with a prismatic joint on that axis)
    body2 = "ground"               # the default
    at = [0.0, 0.0, 0.0]           # the joint's point in space at the start; or point1 (body1
                                   # frame) and point2 (body2 frame; global for the ground)
    axis = [0.0, 0.0, 1.0]         # revolute, cylindrical, prismatic: the axis in space at the
                                   # start; universal: axis1 and axis2 (normal to each other)

    [[force]]
    type = "gravity"               # gravity (g) | point_force (body, point, force: a constant
    g = [0.0, 0.0, -9.81]          # force in space at a body point) | torque (body, torque in
                                   # space) | spring_damper, spring, damper (body1, point1,
                                   # body2, point2 or at1/at2, stiffness, damping, rest_length:
                                   # default the initial length)

Formulations: reduced, baumgarte, penalty (Jalon-Bayo, penalty = (alpha_p, omega_p, mu_p),
default (1e7, 10, 1)), projection; bdf also i3, the index-3 DAE itself
(kernel/src/spatial/mbdk_spatial_dae.f90); trapezoidal_index3 in its projected form
(formulation "projected", the default: kernel/src/spatial/mbdk_spatial_index3.f90, fixed step);
ida in the forms index1 (the default) and ggl (kernel/src/sundials/mbdk_ida.f90,
mbdk_ida_solve_spatial); bdf also on the stabilised index-2 form, "si2" (GGL's mu through
T(q) M^-1 C^T, as in ida's ggl). Drivers: angle_driver and slide_driver. Every ODE method
runs: fixed step and error-controlled (dopri54, bs32, bdf; cvode_* on all but projection);
euler_cromer does not (its layout is y = [q, q'], and a spatial body's velocities are not its
coordinates' rates). Angle sets pass their gimbal lock with switch_angles (simulate_spatial).

Bad scenes raise SceneError naming the file, the element and the field.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import _compiled, _kernel
from .codes import (NORMS, ROTATIONS, SPATIAL_DAE_FORMS, SPATIAL_FORCE_CODES, SPATIAL_FORMULATIONS,
                    SPATIAL_JOINT_CODES, SPATIAL_JOINT_ROWS)
from .errors import (InvalidInputError, NotApplicableError, Status, exception_for,
                     failure_text, status_message, stopped_at)
from .errors import NoMemoryError, format_bytes, no_memory_message
from .methods import method as _method
from .options import ODEOptions, empty, projection_tol_for
from .result import Result, Stats
from .rotations import from_angles, from_quaternion, to_quaternion
from .checks import (NUMBER_MAX, NUMBER_MIN, check_memory, memory_error, number_problem,
                     show)
from .scene import GROUND, SceneError, _Reader, section_items

FORMULATIONS = SPATIAL_FORMULATIONS
#: ida's forms on spatial scenes (the spatial_run's dae_form codes; mbdk_ida_solve_spatial)
IDA_FORMS = {form: code for (family, form), code in SPATIAL_DAE_FORMS.items() if family == "ida"}
IDA_FORM_TEXT = {
    "index1": "index 1: q' = T(q) w, w' = M^-1 (f - C^T lam), C w' = gamma on the independent "
              "rows; Phi and C w + Phi_t drift as in the reduced ODE (the watch names it)",
    "ggl": "stabilised index 2 (Gear-Gupta-Leimkuhler): q' = T(q) (w - M^-1 C^T mu), "
           "w' = M^-1 (f - C^T lam), Phi = 0, C w + Phi_t = 0 on the independent rows"}
JOINT_TYPES, JOINT_ROWS = SPATIAL_JOINT_CODES, SPATIAL_JOINT_ROWS
#: the drivers: rows that follow a time function, f(t0) = 0
DRIVERS = {"angle_driver": "turns body1", "slide_driver": "slides body1's point"}
FORCE_TYPES = SPATIAL_FORCE_CODES
#: how far from 1 the norm of a given quaternion may be (the kernel's MBDK_UNIT_TOL)
UNIT_TOL = 1e-8
#: how far from 1 the norm of a quaternion written in a scene file may be: a unit quaternion
#: written to 6 decimals has each component rounded by up to 5e-7, which moves its norm by up
#: to 5e-7 (|q|_1 <= 2); the reader takes the rotation of q / |q|
WRITTEN_UNIT_TOL = 1e-6
#: how far a given initial state may be off its joints before the run refuses it (a larger
#: offset is a scene error, not roundoff: the assembly would move the bodies visibly)
ASSEMBLY_TOL = 1e-6


@dataclass
class SpatialBody:
    name: str
    mass: float
    inertia: np.ndarray                 # 3 x 3, about the centre, body frame
    position: np.ndarray                # (3,)
    rotation: np.ndarray                # 3 x 3, body to space
    velocity: np.ndarray                # (3,)
    omega_body: np.ndarray              # (3,)


@dataclass
class SpatialJoint:
    name: str
    type: str
    body1: str
    body2: str
    point1: np.ndarray                  # body1 frame
    point2: np.ndarray                  # body2 frame (space for the ground)
    axis1: np.ndarray                   # body1 frame
    axis2: np.ndarray                   # body2 frame
    function: tuple = (0.0, 0.0, 0.0, 0.0, 0.0)   # a driver's time function (angle or slide)


@dataclass
class SpatialForce:
    type: str
    name: str
    body1: str = ""
    body2: str = GROUND
    reals: tuple = ()                   # the kernel's MBDK_SPATIAL_FORCE_REALS


@dataclass
class SpatialScene:
    name: str
    bodies: list
    joints: list = field(default_factory=list)
    forces: list = field(default_factory=list)
    rotation: str = "quaternion"
    quaternion_norm: str = "project"
    norm_gain: float = 10.0
    description: str = ""
    source: str = "<python>"

    def body_index(self, name: str) -> int:
        """1-based index of a body; 0 for the ground."""
        if name == GROUND:
            return 0
        for k, b in enumerate(self.bodies, 1):
            if b.name == name:
                return k
        raise SceneError(f"{self.source}: no body named {name!r}")

    @property
    def rows(self) -> int:
        return sum(JOINT_ROWS[j.type] for j in self.joints)

    def state0(self) -> np.ndarray:
        """The initial state y0 = [q_1 .. q_nb, (v, Omega)_1 .. (v, Omega)_nb]."""
        q, w = [], []
        for b in self.bodies:
            q += list(b.position) + list(orientation_coordinates(b.rotation, self.rotation))
            w += list(b.velocity) + list(b.omega_body)
        return np.array(q + w, dtype=float)


def orientation_coordinates(r: np.ndarray, rotation: str) -> np.ndarray:
    """The orientation coordinates of rotation matrix r: a quaternion (scalar first, q0 >= 0),
    or the 3-1-3 / 1-2-3 angles of the sequence (R = R_i R_j R_k about moving axes)."""
    if rotation == "quaternion":
        return to_quaternion(r)
    if rotation == "euler313":
        # R33 = cos(theta), R13 = sin(theta) sin(phi), R23 = -sin(theta) cos(phi),
        # R31 = sin(theta) sin(psi), R32 = sin(theta) cos(psi)
        # theta from atan2, not acos(R33): acos loses half the digits near the lock
        theta = math.atan2(math.hypot(r[0, 2], r[1, 2]), r[2, 2])
        if math.hypot(r[0, 2], r[1, 2]) > 1e-12:
            a = np.array([math.atan2(r[0, 2], -r[1, 2]), theta, math.atan2(r[2, 0], r[2, 1])])
        else:   # the lock: only phi +- psi is defined; psi = 0, R = R3(phi) R1(theta)
            a = np.array([math.atan2(r[1, 0], r[0, 0]), theta, 0.0])
    else:
        # 1-2-3: R13 = sin(beta), R23 = -sin(alpha) cos(beta), R33 = cos(alpha) cos(beta),
        # R12 = -cos(beta) sin(gamma), R11 = cos(beta) cos(gamma)
        beta = math.atan2(r[0, 2], math.hypot(r[0, 0], r[0, 1]))   # not asin: see theta
        if math.hypot(r[1, 2], r[2, 2]) > 1e-12:
            a = np.array([math.atan2(-r[1, 2], r[2, 2]), beta, math.atan2(-r[0, 1], r[0, 0])])
        else:   # the lock: gamma = 0, R = R1(alpha) R2(beta), whose first column is
            sb = math.copysign(1.0, r[0, 2])   # (cos b, sin a sin b, -cos a sin b)
            a = np.array([math.atan2(r[1, 0] * sb, -r[2, 0] * sb), beta, 0.0])
    if not np.allclose(from_angles(a, rotation[-3:]), r, rtol=0, atol=1e-9):
        raise SceneError(f"the orientation {r.tolist()} has no {rotation} angles to 1e-9 "
                         "(it is not a rotation matrix)")
    return a


# ---- reading --------------------------------------------------------------------------------

class _SpatialReader(_Reader):
    def vec3(self, fld, default=None, required=False, n=3):
        v = self.get(fld, default, required)
        if v is None:
            return None
        if isinstance(v, np.ndarray):
            v = v.tolist()
        if not isinstance(v, (list, tuple)) or len(v) != n:
            raise self.err(fld, f"= {show(v)} must be a list of {n} numbers")
        return np.array(self.entries(fld, v, str(n)))

    def unit3(self, fld, required=False, default=None):
        v = self.vec3(fld, default, required)
        if v is None:
            return None
        if not np.linalg.norm(v) > 0:
            raise self.err(fld, f"= {v.tolist()} has zero length; an axis needs a direction")
        return v / np.linalg.norm(v)


def _inertia(r: _SpatialReader, mass: float) -> np.ndarray:
    if r.has("inertia") and r.has("shape"):
        raise r.err("inertia", "and 'shape' are both given; give one")
    if r.has("shape"):
        shape = r.get("shape")
        kinds = ("box", "cylinder", "sphere", "bar")
        if not isinstance(shape, dict) or shape.get("type") not in kinds:
            raise r.err("shape", f"= {shape!r} must be {{type = {' | '.join(kinds)}, ...}}")
        sr = _SpatialReader(r.source, f"{r.label} shape", 0, shape)
        sr.get("type")
        kind = shape["type"]
        if kind == "box":
            a, b, c = sr.vec3("size", required=True)
            if not min(a, b, c) > 0:
                raise sr.err("size", f"= {[a, b, c]} must be three positive lengths")
            j = mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
        elif kind == "cylinder":
            rad = sr.num("radius", required=True, positive=True)
            ln = sr.num("length", required=True, positive=True)
            jt = mass * (3 * rad * rad + ln * ln) / 12
            j = np.array([jt, jt, mass * rad * rad / 2])
        elif kind == "sphere":
            rad = sr.num("radius", required=True, positive=True)
            j = np.full(3, 0.4 * mass * rad * rad)
        else:
            ln = sr.num("length", required=True, positive=True)
            # a slender bar along body x: a small axial inertia keeps J positive definite
            jt = mass * ln * ln / 12
            j = np.array([1e-6 * jt, jt, jt])
        sr.done()
        with np.errstate(all="ignore"):
            bad = not np.all(np.isfinite(j)) or np.max(j) > NUMBER_MAX or np.min(j) < NUMBER_MIN
        if bad:
            raise r.err("shape", f"= {show(shape)} gives principal inertias {j.tolist()}, out of "
                                 "range (each must lie between 1e-150 and 1e150 kg m^2); give "
                                 "the size in metres and the mass in kg")
        return np.diag(j)
    v = r.get("inertia", None, required=True)
    if isinstance(v, (list, tuple)) and len(v) == 3 and all(isinstance(x, (list, tuple))
                                                           for x in v):
        if any(len(x) != 3 for x in v):
            raise r.err("inertia", f"= {show(v)} is not a 3 x 3 matrix of numbers")
        j = np.array([r.entries("inertia", x, "3 x 3") for x in v])
    else:
        j = np.diag(r.vec3("inertia"))
    return _checked_inertia(r.err, j)


def _checked_inertia(err, j: np.ndarray) -> np.ndarray:
    """A 3 x 3 inertia: entries in range, symmetric, positive definite with eigenvalues in
    range, the triangle inequality. err(field, message) makes the error."""
    with np.errstate(all="ignore"):
        big = np.max(np.abs(j))
    if not np.all(np.isfinite(j)) or big > NUMBER_MAX:
        raise err("inertia", f"= {j.tolist()} is out of range: entries must be finite, of "
                             "magnitude at most 1e150 (kg m^2); give it in SI units")
    scale = big
    if not np.allclose(j, j.T, rtol=0, atol=1e-12 * max(scale, 1e-300)):
        raise err("inertia", f"= {j.tolist()} is not symmetric; an inertia matrix is")
    try:
        ev = np.linalg.eigvalsh(0.5 * (j + j.T))
    except np.linalg.LinAlgError:
        ev = np.full(3, np.nan)
    if not np.all(np.isfinite(ev)):
        raise err("inertia", f"= {j.tolist()}: its principal inertias cannot be computed; give "
                             "it in SI units (kg m^2)")
    if not ev[0] > 0:
        raise err("inertia", f"= {j.tolist()} is not positive definite (eigenvalues "
                             f"{ev.round(12).tolist()}); each principal inertia must be > 0")
    if ev[0] < NUMBER_MIN:
        raise err("inertia", f"= {j.tolist()}: its smallest principal inertia {ev[0]:.3g} is "
                             "below 1e-150 kg m^2, whose inverse the equations of motion form; "
                             "give it in SI units")
    if ev[2] > ev[0] + ev[1] + 1e-12 * ev[2]:
        raise err("inertia", f"= {j.tolist()}: its principal inertias {ev.round(12).tolist()} "
                             "break the triangle inequality (J3 <= J1 + J2), which every "
                             "rigid body keeps")
    return j


def _orientation(r: _SpatialReader) -> np.ndarray:
    given = [f for f in ("quaternion", "euler313", "cardan123")
             if r.has(f) or r.has(f + "_deg")]
    if len(given) > 1:
        raise r.err(given[1], f"and {given[0]!r} are both given; give one orientation")
    if not given:
        return np.eye(3)
    f = given[0]
    if f == "quaternion":
        q = r.vec3("quaternion", n=4)
        norm = float(np.linalg.norm(q))
        if not abs(norm - 1) <= WRITTEN_UNIT_TOL:
            raise r.err("quaternion", f"= {q.tolist()} has norm {norm:.12g}; a rotation's "
                                      "quaternion has norm 1 (to the precision it is written "
                                      f"in: within {WRITTEN_UNIT_TOL:g}); give a unit "
                                      "quaternion, scalar first")
        # written to 6 or more digits: the rotation it stands for is that of q / |q|
        return from_quaternion(q / norm)
    if r.has(f + "_deg"):
        if r.has(f):
            raise r.err(f, f"and {f}_deg are both given; give one")
        a = np.radians(r.vec3(f + "_deg"))
    else:
        a = r.vec3(f)
    return from_angles(a, f[-3:])


def _spatial_body(r: _SpatialReader) -> SpatialBody:
    name = r.name("name")
    kind = r.name("kind", required=False, default="planar")
    if kind != "spatial":
        raise r.err("kind", f"= {kind!r} in a spatial scene: every body of a scene with a "
                            "spatial body is spatial (a planar body's motion is a spatial one "
                            "held in its plane by joints)")
    mass = r.num("mass", required=True, positive=True)
    j = _inertia(r, mass)
    rot = _orientation(r)
    if r.has("omega") and r.has("omega_body"):
        raise r.err("omega", "and 'omega_body' are both given; give one")
    om = r.vec3("omega_body", np.zeros(3))
    if r.has("omega"):
        om = rot.T @ r.vec3("omega")
    b = SpatialBody(name, mass, j, r.vec3("position", np.zeros(3)), rot,
                    r.vec3("velocity", np.zeros(3)), om)
    r.done()
    return b


def _frame(bodies: dict, name: str):
    """(position, rotation) of a body by name at the start; the ground's is the identity."""
    if name == GROUND:
        return np.zeros(3), np.eye(3)
    b = bodies[name]
    return b.position, b.rotation


def _spatial_joint(r: _SpatialReader, bodies: dict) -> SpatialJoint:
    typ = r.name("type")
    if typ not in JOINT_TYPES:
        raise r.err("type", f"= {typ!r} is not a spatial joint type; known: "
                            f"{', '.join(JOINT_TYPES)}")
    name = r.name("name", required=False, default=f"joint{r.index + 1}")
    b1 = r.name("body1")
    b2 = r.name("body2", required=False, default=GROUND)
    for fld, b in (("body1", b1), ("body2", b2)):
        if b != GROUND and b not in bodies:
            raise r.err(fld, f"= {b!r} is not a body of this scene; its bodies: "
                             f"{', '.join(bodies)}")
    if b1 == b2:
        raise r.err("body2", f"= {b2!r} is body1 too; a joint connects two bodies")
    if b1 == GROUND:
        raise r.err("body1", "= 'ground': body1 must be a body (the ground may be body2)")
    (r1, R1), (r2, R2) = _frame(bodies, b1), _frame(bodies, b2)
    if typ == "angle_driver":   # an angle has no point: at, point1 and point2 are refused
        p1 = p2 = np.zeros(3)
    elif r.has("at"):
        if r.has("point1") or r.has("point2"):
            raise r.err("at", "and point1/point2 are both given; give one")
        at = r.vec3("at")
        p1, p2 = R1.T @ (at - r1), R2.T @ (at - r2)
    else:
        p1 = r.vec3("point1", np.zeros(3))
        p2 = r.vec3("point2", np.zeros(3))
    a1 = a2 = np.array([0.0, 0.0, 1.0])
    fn = (0.0, 0.0, 0.0, 0.0, 0.0)
    if typ in DRIVERS:
        fn = r.function("function", None)
        if fn is None:
            what = "angle" if typ == "angle_driver" else "slide (metres)"
            raise r.err("function", f"is missing: a driver needs the {what}'s time "
                                    "function, a number or {offset, rate, amplitude, omega, phase}")
    if typ in ("revolute", "cylindrical", "prismatic", "angle_driver", "slide_driver"):
        ax = r.unit3("axis", required=True)
        a1, a2 = R1.T @ ax, R2.T @ ax
    elif typ == "universal":
        ax1, ax2 = r.unit3("axis1", required=True), r.unit3("axis2", required=True)
        if abs(ax1 @ ax2) > 1e-9:
            raise r.err("axis2", f"= {ax2.tolist()} is not normal to axis1 = {ax1.tolist()} "
                                 f"(cosine {ax1 @ ax2:.3g}); a universal joint's two axes are")
        a1, a2 = R1.T @ ax1, R2.T @ ax2
    j = SpatialJoint(name, typ, b1, b2, p1, p2, a1, a2, fn)
    r.done()
    return j


def _spatial_force(r: _SpatialReader, bodies: dict) -> SpatialForce:
    typ = r.name("type")
    if typ not in FORCE_TYPES:
        raise r.err("type", f"= {typ!r} is not a spatial force type; known: "
                            f"{', '.join(FORCE_TYPES)}")
    name = r.name("name", required=False, default=f"force{r.index + 1}")

    def body(fld, ground_ok=False, default=None):
        b = r.name(fld, required=default is None, default=default)
        if b == GROUND and ground_ok:
            return b
        if b not in bodies:
            raise r.err(fld, f"= {b!r} is not a body of this scene; its bodies: "
                             f"{', '.join(bodies)}")
        return b

    if typ == "gravity":
        return _done(r, SpatialForce(typ, name, reals=tuple(r.vec3("g", [0.0, 0.0, -9.81]))))
    if typ == "point_force":
        b = body("body")
        return _done(r, SpatialForce(typ, name, b, reals=(
            *r.vec3("point", np.zeros(3)), *r.vec3("force", required=True))))
    if typ == "torque":
        b = body("body")
        return _done(r, SpatialForce(typ, name, b, reals=tuple(r.vec3("torque", required=True))))
    b1, b2 = body("body1"), body("body2", ground_ok=True, default=GROUND)
    if b1 == b2:
        raise r.err("body2", f"= {b2!r} is body1 too; a spring joins two bodies")
    (r1, R1), (r2, R2) = _frame(bodies, b1), _frame(bodies, b2)
    p1 = R1.T @ (r.vec3("at1") - r1) if r.has("at1") else r.vec3("point1", np.zeros(3))
    p2 = R2.T @ (r.vec3("at2") - r2) if r.has("at2") else r.vec3("point2", np.zeros(3))
    k = r.num("stiffness", 0.0, required=typ == "spring", nonneg=True) if typ != "damper" else 0.0
    c = r.num("damping", 0.0, required=typ == "damper", nonneg=True) if typ != "spring" else 0.0
    rest = r.num("rest_length", None, nonneg=True)
    if rest is None:
        rest = float(np.linalg.norm(r1 + R1 @ p1 - r2 - R2 @ p2))
    return _done(r, SpatialForce("spring_damper", name, b1, b2,
                                 reals=(*p1, *p2, k, c, rest)))


def _done(r, x):
    r.done()
    return x


def is_spatial(data: dict) -> bool:
    """Whether a parsed scene file is spatial: one of its bodies says kind = "spatial"."""
    bodies = data.get("body", []) if isinstance(data, dict) else []
    return isinstance(bodies, list) and any(isinstance(b, dict) and b.get("kind") == "spatial"
                                            for b in bodies)


def spatial_scene_from_dict(data: dict, source: str = "<dict>") -> SpatialScene:
    """Builds and checks a SpatialScene from the parsed TOML structure."""
    known = {"scene", "body", "joint", "force"}
    extra = [k for k in data if k not in known]
    if extra:
        raise SceneError(f"{source}: unknown section {extra[0]!r}; a scene has "
                         "[scene], [[body]], [[joint]] and [[force]]")
    hr = _SpatialReader(source, "scene", 0, data.get("scene", {}))
    name = hr.name("name", required=False, default=source.rsplit("/", 1)[-1].removesuffix(".toml"))
    desc = hr.get("description", "")
    hr.get("reference")
    rotation = hr.name("rotation", required=False, default="quaternion")
    if rotation not in ROTATIONS:
        raise hr.err("rotation", f"= {rotation!r}; known: {', '.join(ROTATIONS)}")
    norm = hr.name("quaternion_norm", required=False, default="project")
    if norm not in NORMS:
        raise hr.err("quaternion_norm", f"= {norm!r}; known: {', '.join(NORMS)}")
    gain = hr.num("norm_gain", 10.0, nonneg=True)
    hr.done()

    def items(key):
        return section_items(data, key, source)

    raw_bodies = items("body")
    # a joint between a planar and a spatial body is named before the planar body is
    kinds = {t.get("name"): t.get("kind", "planar") for t in raw_bodies
             if isinstance(t, dict) and isinstance(t.get("name"), str)}
    for i, t in enumerate(items("joint")):
        if isinstance(t, dict):
            ends = [e for e in (t.get("body1"), t.get("body2", GROUND)) if isinstance(e, str)]
            if any(kinds.get(e) not in (None, "spatial") for e in ends if e != GROUND):
                jr = _SpatialReader(source, "joint", i, t)
                planar = next(e for e in ends if kinds.get(e) not in (None, "spatial"))
                raise jr.err("body1" if planar == ends[0] else "body2",
                             f"= {planar!r} is a {kinds[planar]} body and the other end a "
                             "spatial one: a joint connects bodies of one kind (make both "
                             "spatial)")
    bodies = {}
    for i, t in enumerate(raw_bodies):
        b = _spatial_body(_SpatialReader(source, "body", i, t))
        if b.name in bodies or b.name == GROUND:
            raise SceneError(f"{source}: body #{i + 1}: name {b.name!r} is "
                             f"{'reserved' if b.name == GROUND else 'used twice'}")
        bodies[b.name] = b
    if not bodies:
        raise SceneError(f"{source}: a scene needs at least one [[body]]")
    joints = [_spatial_joint(_SpatialReader(source, "joint", i, t), bodies)
              for i, t in enumerate(items("joint"))]
    forces = [_spatial_force(_SpatialReader(source, "force", i, t), bodies)
              for i, t in enumerate(items("force"))]
    names = [j.name for j in joints]
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup is not None:
        raise SceneError(f"{source}: joint name {dup!r} is used twice")
    return SpatialScene(name, list(bodies.values()), joints, forces, rotation, norm, gain,
                        desc, source)


# ---- running --------------------------------------------------------------------------------

@dataclass
class SpatialResult(Result):
    """A spatial scene run: t, q (orientation coordinates per the scene's rotation), w = (v,
    Omega) per body, the energy parts, residuals and multipliers at the samples."""

    t: np.ndarray
    q: np.ndarray
    w: np.ndarray
    energy: np.ndarray               # kinetic + gravity + spring potential
    energy_parts: dict
    residuals: np.ndarray            # (nsamp, 3): max |Phi|, max |C w|, max ||p| - 1|
    multipliers: np.ndarray | None
    stats: Stats
    status: Status
    message: str
    manifest: dict = field(default_factory=dict)
    bodies: list = field(default_factory=list)
    joints: list = field(default_factory=list)
    rotation: str = "quaternion"
    assembly: dict = field(default_factory=dict)
    drift: dict | None = None
    #: each sample's angle set, where a run switched sets near a lock (switch_angles)
    rotations: list | None = None

    @property
    def y(self) -> np.ndarray:
        return np.hstack([self.q, self.w])

    def position(self, body: str) -> np.ndarray:
        """(nsamp, 3): the body's centre of mass."""
        k = self.bodies.index(body)
        nqb = 7 if self.rotation == "quaternion" else 6
        return self.q[:, k * nqb:k * nqb + 3]

    def orientation(self, body: str) -> np.ndarray:
        """(nsamp, 3, 3): the body's rotation matrix (body to space)."""
        k = self.bodies.index(body)
        nqb = 7 if self.rotation == "quaternion" else 6
        p = self.q[:, k * nqb + 3:(k + 1) * nqb]
        if self.rotation == "quaternion":
            return np.array([from_quaternion(x / np.linalg.norm(x)) for x in p])
        sets = self.rotations or [self.rotation] * len(p)
        return np.array([from_angles(x, s[-3:]) for x, s in zip(p, sets)])

    def omega_body(self, body: str) -> np.ndarray:
        k = self.bodies.index(body)
        return self.w[:, 6 * k + 3:6 * k + 6]

    def energy_balance(self) -> np.ndarray:
        """E(t) - E(0) - W(t), W the work of dampers, loads and drivers as the run integrated it
        at every step (energy_parts["work"]): zero for an exact solution."""
        return self.energy - self.energy[0] - self.energy_parts["work"]


def _tables(sc: SpatialScene):
    nb = len(sc.bodies)
    mass = np.array([b.mass for b in sc.bodies])
    inertia = np.asfortranarray(np.stack([b.inertia for b in sc.bodies], axis=2))
    nj, nf = len(sc.joints), len(sc.forces)
    jtype = np.zeros(max(nj, 1), dtype=np.int32)
    jbody = np.zeros((2, max(nj, 1)), dtype=np.int32, order="F")
    jreal = np.zeros((17, max(nj, 1)), order="F")
    for k, j in enumerate(sc.joints):
        jtype[k] = JOINT_TYPES[j.type]
        jbody[:, k] = sc.body_index(j.body1), sc.body_index(j.body2)
        jreal[:, k] = np.concatenate([j.point1, j.point2, j.axis1, j.axis2, j.function])
    ftype = np.zeros(max(nf, 1), dtype=np.int32)
    fbody = np.zeros((2, max(nf, 1)), dtype=np.int32, order="F")
    freal = np.zeros((9, max(nf, 1)), order="F")
    for k, f in enumerate(sc.forces):
        ftype[k] = FORCE_TYPES[f.type]
        fbody[:, k] = (sc.body_index(f.body1) if f.body1 else 0,
                       sc.body_index(f.body2) if f.type == "spring_damper" else 0)
        freal[:len(f.reals), k] = f.reals
    return nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal


def _validate(sc: SpatialScene) -> None:
    """The checks of the reader, again on a SpatialScene whose fields were changed in Python
    after it was read: each names the element and the field."""
    if not isinstance(sc.bodies, list) or not sc.bodies:
        raise SceneError(f"{sc.source}: a spatial scene needs a list of at least one body")
    for fld in ("joints", "forces"):
        if not isinstance(getattr(sc, fld), list):
            raise SceneError(f"{sc.source}: scene: field {fld!r} = {getattr(sc, fld)!r} must "
                             "be a list")
    if not isinstance(sc.rotation, str) or not isinstance(sc.quaternion_norm, str) or \
            sc.rotation not in ROTATIONS or sc.quaternion_norm not in NORMS:
        raise SceneError(f"{sc.source}: scene: rotation = {sc.rotation!r} (known: "
                         f"{', '.join(ROTATIONS)}), quaternion_norm = {sc.quaternion_norm!r} "
                         f"(known: {', '.join(NORMS)})")
    if number_problem(sc.norm_gain) or not sc.norm_gain >= 0:
        raise SceneError(f"{sc.source}: scene: norm_gain = {sc.norm_gain!r} must be a finite "
                         "number >= 0")

    def vec(label, fld, v, shape):
        try:
            a = np.asarray(v, dtype=float)
        except (TypeError, ValueError, OverflowError):
            a = None
        if a is None or a.shape != shape or not np.all(np.isfinite(a)) or \
                np.any(np.abs(a) > NUMBER_MAX):
            raise SceneError(f"{sc.source}: {label}: field {fld!r} = {show(v)} must be finite "
                             f"numbers of shape {shape}, of magnitude at most 1e150")
        return a
    names = set()
    for b in sc.bodies:
        label = f"body {getattr(b, 'name', '?')!r}"
        if not isinstance(b, SpatialBody) or not isinstance(b.name, str) or b.name in names:
            raise SceneError(f"{sc.source}: {label} is not a SpatialBody with a name of its own")
        names.add(b.name)
        problem = number_problem(b.mass)
        if problem:
            raise SceneError(f"{sc.source}: {label}: field 'mass' {problem}")
        if not b.mass > 0:
            raise SceneError(f"{sc.source}: {label}: field 'mass' = {b.mass!r} must be > 0")
        _checked_inertia(lambda fld, msg, label=label: SceneError(
            f"{sc.source}: {label}: field {fld!r} {msg}"), vec(label, "inertia", b.inertia,
                                                              (3, 3)))
        rot = vec(label, "rotation", b.rotation, (3, 3))
        if not (np.allclose(rot.T @ rot, np.eye(3), rtol=0, atol=UNIT_TOL)
                and np.linalg.det(rot) > 0):
            raise SceneError(f"{sc.source}: {label}: field 'rotation' (the SpatialBody's "
                             f"orientation matrix) = {rot.tolist()} is not a rotation matrix "
                             "(R^T R = I, det R = 1)")
        for fld in ("position", "velocity", "omega_body"):
            vec(label, fld, getattr(b, fld), (3,))
    for j in sc.joints:
        label = f"joint {getattr(j, 'name', '?')!r}"
        if not isinstance(j, SpatialJoint) or not isinstance(j.type, str) or \
                j.type not in JOINT_TYPES:
            raise SceneError(f"{sc.source}: {label}: field 'type' must be one of "
                             f"{', '.join(JOINT_TYPES)}")
        for fld in ("body1", "body2"):
            if not isinstance(getattr(j, fld), str):
                raise SceneError(f"{sc.source}: {label}: field {fld!r} = {getattr(j, fld)!r} "
                                 "must be a body's name")
            if getattr(j, fld) != GROUND and getattr(j, fld) not in names or \
                    (fld == "body1" and j.body1 == GROUND):
                raise SceneError(f"{sc.source}: {label}: field {fld!r} = "
                                 f"{getattr(j, fld)!r} is not a body of this scene")
        if j.body1 == j.body2:
            raise SceneError(f"{sc.source}: {label}: field 'body2' = {j.body2!r} is body1 too")
        vec(label, "function", j.function, (5,))
        for fld in ("point1", "point2", "axis1", "axis2"):
            a = vec(label, fld, getattr(j, fld), (3,))
            if fld.startswith("axis") and not np.linalg.norm(a) > 0:
                raise SceneError(f"{sc.source}: {label}: field {fld!r} has zero length")
    for f in sc.forces:
        label = f"force {getattr(f, 'name', '?')!r}"
        if not isinstance(f, SpatialForce) or not isinstance(f.type, str) or \
                f.type not in FORCE_TYPES:
            raise SceneError(f"{sc.source}: {label}: field 'type' must be one of "
                             f"{', '.join(FORCE_TYPES)}")
        if f.type in ("spring", "damper"):
            raise SceneError(f"{sc.source}: {label}: field 'type' = {f.type!r}: a SpatialForce "
                             "object's spring or damper has type 'spring_damper'")
        for fld in ("body1", "body2"):
            if not isinstance(getattr(f, fld), str):
                raise SceneError(f"{sc.source}: {label}: field {fld!r} = {getattr(f, fld)!r} "
                                 "must be a body's name")
        want = {"gravity": 3, "point_force": 6, "torque": 3}.get(f.type, 9)
        r = vec(label, "reals", f.reals, (want,))
        if f.type == "spring_damper" and not (r[6] >= 0 and r[7] >= 0 and r[8] >= 0):
            raise SceneError(f"{sc.source}: {label}: stiffness, damping and rest_length "
                             f"{r[6:].tolist()} must be >= 0")
        ends = [f.body1] + ([f.body2] if f.type == "spring_damper" else [])
        if f.type != "gravity" and (f.body1 not in names or any(
                e != GROUND and e not in names for e in ends) or
                (len(ends) == 2 and ends[0] == ends[1])):
            raise SceneError(f"{sc.source}: {label}: its bodies {ends} are not two (or one) "
                             "distinct bodies of this scene")


def joint_rows(sc: SpatialScene) -> list:
    """(joint name, first row, row count) of each joint, in the kernel's row order."""
    out, first = [], 0
    for j in sc.joints:
        out.append((j.name, first, JOINT_ROWS[j.type]))
        first += JOINT_ROWS[j.type]
    return out


def simulate_spatial(sc: SpatialScene, method: str, *, h=None, t_end, formulation=None,
                     t0=0.0, every=1, alpha=None, beta=None, projection_tol=None,
                     assemble_initial=True, startup="rk4", rtol=None, atol=None, dt_out=None,
                     h_min=None, h_max=None, max_steps=None, max_order=None, watch=True,
                     raise_on_failure=True, newton_rtol=None, newton_atol=None,
                     outputs=None, penalty=None, switch_angles=None, _lock_guard=0.0,
                     **unsupported) -> SpatialResult:
    """Runs a spatial scene (mbdk.simulate sends spatial scenes here; see the module
    docstring). Options of the planar path that do not apply are refused by name; outputs is
    checked and otherwise moot: a spatial run computes every output at its samples.

    switch_angles (angle sets only): a distance d from the gimbal lock (|sin theta| for
    3-1-3, |cos beta| for 1-2-3; e.g. 0.1). The run stops where the bodies' angles come within
    d of their set's lock and goes on from its last sample in the other set, whose lock is
    elsewhere (the 3-1-3 lock is an orientation where the 1-2-3 beta is near 0, and back), as
    often as the motion asks; result.rotations gives each sample's set, result.manifest
    ["switches"] the times. Not with drivers (a driver starts from f(t0) = 0)."""
    if switch_angles is not None:
        return _switching_run(sc, method, switch_angles, dict(
            h=h, t_end=t_end, formulation=formulation, t0=t0, every=every, alpha=alpha,
            beta=beta, projection_tol=projection_tol, assemble_initial=assemble_initial,
            startup=startup, rtol=rtol, atol=atol, dt_out=dt_out, h_min=h_min, h_max=h_max,
            max_steps=max_steps, max_order=max_order, watch=watch,
            raise_on_failure=raise_on_failure, newton_rtol=newton_rtol,
            newton_atol=newton_atol, outputs=outputs, penalty=penalty, **unsupported))
    from .ode import build_info
    from .simulate import _ode_plan, check_run, ggl_multipliers, scene_tolerances
    from .watch import as_watch, drift_message, drift_report, invariant_names

    bad = sorted(k for k, v in unsupported.items() if v is not None)
    if bad:
        raise NotApplicableError(f"{', '.join(bad)}: not options of a spatial scene run (its "
                                 "formulations: reduced, baumgarte, penalty, projection; solver "
                                 "and the index-3 options are the planar model's)")
    if outputs is not None:
        from .simulate import _want
        _want(outputs)
    _validate(sc)
    info_m = _method(method)
    index3 = info_m.family == "dae_index3"
    ida = info_m.family == "ida"
    if info_m.solves != "ode" and not index3 and not ida:
        raise NotApplicableError(
            f"{method} on spatial scene {sc.name!r}: it integrates the planar model's DAE; "
            "spatial scenes run the ODE methods (mbdk.methods('ode')) on the reduced, "
            "baumgarte, penalty or projection formulation, bdf on their DAE itself "
            "(formulations 'i3', 'si2'), ida ('index1', 'ggl') and trapezoidal_index3 "
            "(formulation 'projected')")
    if info_m.family == "euler_cromer":
        raise NotApplicableError(f"euler_cromer on spatial scene {sc.name!r}: its state layout "
                                 "is y = [q, q'], and a spatial body's velocities (v, Omega) are "
                                 "not its coordinates' rates; use symplectic methods on planar "
                                 "scenes, or rk4 here")
    if formulation is not None and not isinstance(formulation, str):
        from .checks import choice
        choice("formulation", formulation,
               ["projected"] if index3 else list(IDA_FORMS) if ida else
               list(FORMULATIONS) + (["i3", "si2"] if info_m.family == "variable_bdf" else []),
               error=NotApplicableError, what=f"a formulation {method} runs on spatial scenes")
    if index3:
        formulation = "projected" if formulation is None else formulation
        if formulation != "projected":
            raise NotApplicableError(
                f"formulation {formulation!r} of trapezoidal_index3 on spatial scene "
                f"{sc.name!r}: spatial scenes take its projected form only ('projected', "
                "kernel/src/spatial/mbdk_spatial_index3.f90); the unprojected book scheme "
                "(index3) and the augmented Lagrangian are the planar model's")
    if ida:
        formulation = "index1" if formulation is None else formulation
        if formulation not in IDA_FORMS:
            raise NotApplicableError(
                f"formulation {formulation!r} of ida on spatial scene {sc.name!r}: ida "
                f"integrates the DAE itself, in the forms {', '.join(IDA_FORMS)}")
    formulation = "reduced" if formulation is None else formulation
    dae = formulation in ("i3", "si2") and info_m.family == "variable_bdf"
    if not isinstance(formulation, str) or (formulation not in FORMULATIONS and not dae
                                            and not index3 and not ida):
        raise NotApplicableError(f"formulation {formulation!r} on spatial scene {sc.name!r}: "
                                 f"spatial scenes run {', '.join(FORMULATIONS)}, and bdf also "
                                 "'i3' and 'si2' (the DAE itself)")
    if penalty is not None and formulation != "penalty":
        raise InvalidInputError(f"penalty = {penalty!r}: an option of the penalty formulation; "
                                f"this run's is {formulation!r}")
    penalty = (1e7, 10.0, 1.0) if penalty is None else penalty
    if method.startswith("cvode") and formulation == "projection":
        raise NotApplicableError(f"{method} with the projection formulation: CVODE cannot "
                                 "change the state between its steps; use reduced or baumgarte")
    if method.startswith("cvode") and sc.rotation == "quaternion" and \
            sc.quaternion_norm == "project":
        raise NotApplicableError(f"{method} on spatial scene {sc.name!r} with quaternion_norm = "
                                 "'project': CVODE cannot change the state between its steps; "
                                 "set the scene's quaternion_norm to 'stabilise' or 'none'")
    if info_m.adaptive:
        if every != 1:
            raise InvalidInputError(f"every = {every!r}: {method} chooses its own steps; give "
                                    "dt_out (the spacing of the samples) instead")
        if formulation == "baumgarte" and (alpha is None or beta is None):
            raise InvalidInputError(f"{method} with formulation 'baumgarte': give alpha and "
                                    "beta (Baumgarte's defaults 1/h and sqrt(2)/h need a fixed "
                                    "step; an error-controlled method has none)")
        check_run(1.0 if not h else h, t_end, t0, 1)
        rtol, atol = scene_tolerances(rtol, atol)
        adaptive = dict(h=h, rtol=rtol, atol=atol, dt_out=dt_out or 0.0, h_min=h_min or 0.0,
                        h_max=h_max or 0.0, max_steps=max_steps or 0, max_order=max_order or 0)
        href = 1e-3 * (t_end - t0)
    else:
        given = [n for n, v in (("rtol", rtol), ("atol", atol), ("dt_out", dt_out),
                                ("max_steps", max_steps), ("max_order", max_order)) if v]
        if given:
            raise InvalidInputError(f"{', '.join(given)}: options of the error-controlled "
                                    f"methods; {method} takes a fixed step h")
        if h is None:
            raise InvalidInputError(f"{method} takes a fixed step: give h")
        check_run(h, t_end, t0, every)
        adaptive = None
        href = h
    projection_tol = projection_tol_for(
        projection_tol, (ODEOptions.atol if atol is None else atol) if info_m.adaptive else None)
    plan_ = _ode_plan(info_m, formulation, href, t_end, t0, int(every), alpha, beta,
                      penalty, projection_tol, startup, newton_rtol, newton_atol, adaptive)
    opt = plan_["ode"]
    from dataclasses import replace
    opt = replace(opt, method=info_m.id)
    w = as_watch(watch)
    model_form = "reduced" if dae or ida else "projection" if index3 else formulation
    sopt = np.array([FORMULATIONS[model_form], ROTATIONS[sc.rotation],
                     NORMS[sc.quaternion_norm],
                     plan_["alpha"], plan_["beta"], sc.norm_gain, projection_tol,
                     w.position or 0.0, w.velocity or 0.0, w.energy or 0.0, w.every,
                     *penalty, float(_lock_guard), w.momentum or 0.0, w.quaternion or 0.0],
                    dtype=float)
    nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal = _tables(sc)
    y0 = sc.state0()
    _check_initial(sc, y0, assemble_initial, float(t0))
    stats, flag = empty("mbdk_stats"), _compiled.new_flag()
    m1 = max(sc.rows, 1)
    nsamp = plan_["nsamp"]
    args = (mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal, sopt, opt.pack(),
            flag, np.zeros(0), y0, int(bool(assemble_initial)),
            SPATIAL_DAE_FORMS[(method, formulation)] if index3 or ida or dae else 0, float(t0),
            float(t_end), nsamp, m1, stats)
    # the samples (t, y, the outputs and the multipliers, allocated by the f2py layer): refused
    # before they are allocated where the machine has not that much memory
    from .simulate import SCENE_SAMPLE_ADVICE
    nbytes = 8.0 * nsamp * (1 + len(y0) + 8 + m1)   # spatial_run's out(8, nsamp)
    what = f"{method} on spatial scene {sc.name!r} ({nsamp} samples)"
    advice = SCENE_SAMPLE_ADVICE.split(", or fewer outputs")[0]
    check_memory(nbytes, what=what, change=advice)
    try:
        (t, y, out, lam, nw, moved, report, invariants, ninv, status), interrupted = \
            _compiled.call(_kernel.spatial_run, args, flag, plan_["steps"] * len(y0),
                           span=(t0, t_end))
    except MemoryError as exc:
        raise memory_error(exc, nbytes, what=what, change=advice) from None
    status = Status(int(status))
    nqb = 7 if sc.rotation == "quaternion" else 6
    nq = nb * nqb
    ys = y[:, :nw].T
    o = out[:, :nw].T
    manifest = {**build_info(), "scene": sc.name, "kind": "spatial", "method": method,
                "formulation": formulation, "rotation": sc.rotation,
                **({"h": h, "every": int(every)} if not info_m.adaptive else {}),
                "quaternion_norm": ("none (bdf on the DAE: no projection between its steps)"
                                    if dae and sc.quaternion_norm == "project"
                                    else sc.quaternion_norm), "t0": t0, "t_end": t_end,
                **plan_["manifest"],
                "linear_solve": ("dense M + alpha_p C^T C (LAPACK dpotrf)"
                                 if formulation == "penalty" else
                                 "dense Schur complement (LAPACK dpotrf)"),
                "watch": {"position": w.position, "velocity": w.velocity,
                          "energy": w.energy, "every": w.every, "momentum": w.momentum,
                          "quaternion": w.quaternion},
                "invariants": invariant_names(invariants[:, :int(ninv)].T)}
    if formulation in ("projection", "projected"):
        manifest["projection_tol"] = projection_tol
    loose_lambda = ggl_multipliers(method, formulation, rtol) if sc.rows else None
    if loose_lambda:
        manifest["multipliers"] = loose_lambda
    if index3:
        manifest["form"] = ("trapezoidal rule on the index-3 DAE, Newton on (q+, w+, lam+) "
                            "with the equations of motion at t+, then the projections of "
                            "positions, velocities and the quaternions' norm, and a+, lam+ "
                            "from the constrained solve")
        manifest["linear_solve"] = ("Newton matrix by forward differences (LAPACK LU), kept "
                                    "while Newton contracts")
    if ida:
        manifest["form"] = IDA_FORM_TEXT[formulation]
        manifest["linear_solve"] = "IDA's dense difference quotients, SUNDIALS dense LU"
        manifest["quaternion_norm"] = ("none (ida on the DAE: no projection between its steps)"
                                       if sc.quaternion_norm == "project" else
                                       sc.quaternion_norm)
    if dae and formulation == "si2":
        manifest["form"] = ("stabilised index-2 DAE (GSTIFF SI2): q' = T(q) (w - M^-1 C^T "
                            "mu), w' = M^-1 (f - C^T lam), 0 = Phi, 0 = C w + Phi_t on the "
                            "independent rows; error test on q and w; no projection between "
                            "steps")
        manifest["linear_solve"] = "bdf's Newton matrix E - c J by differences (LAPACK LU)"
    elif dae:
        manifest["form"] = ("index-3 DAE (GSTIFF I3): q' = T(q) w, w' = M^-1 (f - C^T lam), "
                            "0 = Phi on the independent rows; error test on q and h times w; "
                            "no projection between steps")
        manifest["linear_solve"] = "bdf's Newton matrix E - c J by differences (LAPACK LU)"
    result = SpatialResult(
        t=t[:nw], q=ys[:, :nq], w=ys[:, nq:], energy=o[:, 0] + o[:, 1] + o[:, 2],
        energy_parts={"kinetic": o[:, 0], "gravity": o[:, 1], "springs": o[:, 2],
                      "power": o[:, 3], "work": o[:, 7]},
        residuals=o[:, 4:7], multipliers=lam[:sc.rows, :nw].T if sc.rows else None,
        stats=Stats.from_words(stats), status=status, message=status_message(status),
        manifest=manifest, bodies=[b.name for b in sc.bodies],
        joints=[j.name for j in sc.joints], rotation=sc.rotation,
        assembly={"moved": float(moved)})
    unstable = ""
    if status.failed and nw and not info_m.adaptive and not index3 and not dae and not ida:
        from .simulate import _UNSTABLE_ENDS, _stability_note
        if status in _UNSTABLE_ENDS:
            def f(yy):
                out = evaluate_spatial(sc, yy, float(result.t[-1]))
                if out["status"] != Status.SUCCESS:
                    raise InvalidInputError("no evaluation")
                return out["ydot"]
            unstable = _stability_note(method, h, f, np.concatenate([result.q[-1],
                                                                     result.w[-1]]),
                                       float(result.t[-1]))
    if unstable:    # the true cause: the method's step, not the mechanism
        if status in (Status.ERR_CONSTRAINT_DRIFT, Status.ERR_ENERGY_DRIFT,
                      Status.ERR_INVARIANT_DRIFT):
            result.drift = drift_report(report, joint_rows(sc), invariants[:, :int(ninv)].T,
                                        [b.name for b in sc.bodies])
        result.message = (f"{method}/{formulation} on spatial scene {sc.name!r}: "
                          f"{failure_text(status, False)} ({stopped_at(result.stats, t0)}): "
                          f"{unstable}")
    elif status == Status.ERR_CONSTRAINT_DRIFT and int(report[0]) == 0:
        # not the watch: the kernel found the redundant joints' dependent rows independent
        result.message = (f"{method}/{formulation} on spatial scene {sc.name!r} stopped at t = "
                          f"{result.t[-1] if nw else t0:.6g}: the state left the joints so far "
                          "that the rows of its redundant joints, dependent on the others on the "
                          "joints, no longer agree with them; the projection formulation keeps "
                          "the state on the joints, or take a smaller step")
    elif status in (Status.ERR_CONSTRAINT_DRIFT, Status.ERR_ENERGY_DRIFT,
                    Status.ERR_INVARIANT_DRIFT):
        inv = invariants[:, :int(ninv)].T
        bodies = [b.name for b in sc.bodies]
        result.drift = drift_report(report, joint_rows(sc), inv, bodies)
        said = drift_message(report, joint_rows(sc), inv, bodies).replace('D v', 'C w')
        remedy = ("A smaller step (small beside the period of the fastest motion), a "
                  "higher-order method or watch=False (to study the drift) are the remedies"
                  if status == Status.ERR_INVARIANT_DRIFT else
                  "A smaller step, the projection formulation or watch=False (to study the "
                  "drift) are the remedies")
        result.message = (f"{method}/{formulation} on spatial scene {sc.name!r}: {said}. "
                          + remedy)
    elif status == Status.ERR_NO_MEMORY:
        # the run's dense matrices: the Newton matrix over the method's unknowns, the penalty
        # formulation's over the velocities
        newton = (len(y0) + sc.rows * (2 if formulation in ("si2", "ggl") else 1)
                  if dae or ida or index3 else len(y0))
        dense = [(f"the Newton matrix of {method}", newton, "use an explicit method"),
                 ("the penalty formulation's M + alpha_p C^T C",
                  6 * nb * (formulation == "penalty"),
                  "use formulation reduced, baumgarte or projection")]
        result.message = (f"{method}/{formulation} on spatial scene {sc.name!r} ({nb} bodies): "
                          + no_memory_message(result.stats.alloc_bytes, dense))
    elif status == Status.ERR_SINGULAR_MATRIX:
        where = (f"stopped {stopped_at(result.stats, t0)}" if nw else
                 "could not start (the initial state's assembly or first evaluation)")
        lock = _lock_distance(sc, result.q[-1]) if nw else None
        joints = ("the joints' constraint rows lost their rank (a singular pose: rows that "
                  "were independent at the start became dependent), where the multipliers are "
                  "not unique")
        if lock is not None and (lock < 1e-3 or not sc.joints):
            why = (f"the orientation angles reached their gimbal lock ({_LOCK[sc.rotation]} = "
                   f"{lock:.2g} at "
                   "the last sample), where their rates are undefined; rotation = 'quaternion' "
                   "has no such point")
        else:
            why = joints
        result.message = f"{method}/{formulation} on spatial scene {sc.name!r} {where}: {why}"
    elif status.failed:
        text = failure_text(status, info_m.adaptive, dae or ida)
        result.message = (f"{method}/{formulation} on spatial scene {sc.name!r}: "
                          f"{text} ({stopped_at(result.stats, t0)})")
    if interrupted or status == Status.ERR_INTERRUPTED:
        from .errors import SolveInterrupted
        raise SolveInterrupted(result.message, status=status, result=result)
    if status.failed and raise_on_failure:
        raise exception_for(status)(result.message, status=status, result=result)
    if loose_lambda:
        import warnings
        from .errors import AccuracyWarning
        warnings.warn(f"{method}/{formulation} on spatial scene {sc.name!r}: the multipliers "
                      f"are {loose_lambda}", AccuracyWarning, stacklevel=3)
    return result


#: the other angle set, whose lock lies elsewhere
_OTHER_SET = {"euler313": "cardan123", "cardan123": "euler313"}
#: the most switches a run may take (a motion that dwells at the locks of both sets would
#: otherwise restart for ever)
MAX_SWITCHES = 1000


def _restarted(sc: SpatialScene, r: SpatialResult, k: int, rotation: str) -> SpatialScene:
    """sc with its bodies at sample k of r (position, orientation, velocity, body-frame
    angular velocity), in the angle set rotation."""
    from dataclasses import replace
    bodies = [replace(b, position=r.position(b.name)[k].copy(),
                      rotation=r.orientation(b.name)[k].copy(),
                      velocity=r.w[k, 6 * i:6 * i + 3].copy(),
                      omega_body=r.w[k, 6 * i + 3:6 * i + 6].copy())
              for i, b in enumerate(sc.bodies)]
    return replace(sc, bodies=bodies, rotation=rotation)


def _switching_run(sc: SpatialScene, method: str, guard, kw: dict) -> SpatialResult:
    """simulate_spatial with switch_angles (its docstring): segments in alternating angle
    sets, joined into one result."""
    if sc.rotation not in _OTHER_SET:
        raise InvalidInputError(f"switch_angles = {guard!r}: scene {sc.name!r} uses "
                                f"rotation = {sc.rotation!r}, which has no gimbal lock; it "
                                "applies to euler313 and cardan123")
    if not (isinstance(guard, (int, float)) and not isinstance(guard, bool)
            and 0 < guard < 0.5):
        raise InvalidInputError(f"switch_angles = {guard!r} must be a distance from the lock "
                                "between 0 and 0.5 (|sin theta| or |cos beta|; 0.1 is usual)")
    drivers = [j.name for j in sc.joints if j.type in DRIVERS]
    if drivers:
        raise NotApplicableError(f"switch_angles on scene {sc.name!r}: its drivers "
                                 f"({', '.join(drivers)}) start from f(t0) = 0, which a run "
                                 "restarted mid-way cannot keep; use rotation = 'quaternion'")
    from dataclasses import replace
    raise_on_failure = kw.pop("raise_on_failure")
    t0, t_end = float(kw["t0"]), float(kw["t_end"])
    # a segment restarts from its last sample, so the segments sample densely (every step, or
    # 2000 samples of the dense output) and the result keeps the samples asked for
    adaptive = _method(method).adaptive
    if adaptive:
        dt_user = float(kw.get("dt_out") or 0.0)
        inner = (t_end - t0) / 2000
        if dt_user > 0:
            inner = dt_user / max(1, math.ceil(dt_user / inner))
        kw["dt_out"] = inner
    else:
        every_user = int(kw.get("every") or 1)
        kw["every"] = 1
    cur, t_start, segs, switches = sc, float(kw.pop("t0")), [], []
    if _lock_distance(cur, cur.state0()[:6 * len(cur.bodies)]) < guard:
        # a start near the scene's own set's lock: in the other set from the first step
        cur = replace(cur, rotation=_OTHER_SET[cur.rotation])
        switches.append(t_start)
    while True:
        r = simulate_spatial(cur, method, t0=t_start, raise_on_failure=False,
                             _lock_guard=guard, **kw)
        segs.append((cur.rotation, r))
        near = (r.status == Status.ERR_SINGULAR_MATRIX and len(r.t) > 1
                and r.t[-1] > t_start and _lock_distance(cur, r.q[-1]) < 2 * guard)
        if not near or len(switches) >= MAX_SWITCHES:
            break
        # from the last sample, in the other set
        t_start = float(r.t[-1])
        cur = _restarted(cur, r, -1, _OTHER_SET[cur.rotation])
        switches.append(t_start)
    result = _joined(segs, switches)
    n = len(result.t)
    if adaptive:
        grid = (np.zeros(n, bool) if dt_user <= 0 else
                np.abs((result.t - t0) / dt_user - np.round((result.t - t0) / dt_user)) < 1e-6)
    else:
        grid = np.round((result.t - t0) / kw["h"]).astype(np.int64) % every_user == 0
    grid[[0, -1]] = True
    result = _subsampled(result, np.flatnonzero(grid))
    if result.status == Status.SUCCESS or not raise_on_failure:
        return result
    raise exception_for(result.status)(result.message, status=result.status, result=result)


def _subsampled(r: SpatialResult, idx) -> SpatialResult:
    """r at the samples idx."""
    from dataclasses import replace
    return replace(r, t=r.t[idx], q=r.q[idx], w=r.w[idx], energy=r.energy[idx],
                   energy_parts={k: v[idx] for k, v in r.energy_parts.items()},
                   residuals=r.residuals[idx],
                   multipliers=None if r.multipliers is None else r.multipliers[idx],
                   rotations=[r.rotations[i] for i in idx])


def _joined(segs, switches) -> SpatialResult:
    """One result from the segments of a switching run: each segment's last sample is the
    next one's first, kept once."""
    first, last = segs[0][1], segs[-1][1]
    keep = [(rot, r, slice(0, len(r.t) - 1) if i < len(segs) - 1 else slice(None))
            for i, (rot, r) in enumerate(segs)]

    def cat(get):
        parts = [get(r)[s] for _rot, r, s in keep if get(r) is not None]
        return np.concatenate(parts) if parts else None

    def work():   # each segment's work starts at 0 where the one before ended
        parts, before = [], 0.0
        for _rot, r, s in keep:
            w = r.energy_parts["work"]
            parts.append(before + w[s])
            before += float(w[-1]) if len(w) else 0.0
        return np.concatenate(parts)
    stats = Stats(**{f: sum(getattr(r.stats, f) for _rot, r, _s in keep)
                     for f in first.stats.__dataclass_fields__})
    rotations = [rot for rot, r, s in keep for _ in range(len(r.t[s]))]
    manifest = {**first.manifest, "switch_angles": True,
                "switches": [float(x) for x in switches],
                "segments": [{"rotation": rot, "t0": float(r.t[0]) if len(r.t) else None,
                              "steps": r.stats.steps} for rot, r, _s in keep]}
    return SpatialResult(
        t=cat(lambda r: r.t), q=cat(lambda r: r.q), w=cat(lambda r: r.w),
        energy=cat(lambda r: r.energy),
        energy_parts={k: work() if k == "work" else cat(lambda r, k=k: r.energy_parts[k])
                      for k in first.energy_parts},
        residuals=cat(lambda r: r.residuals), multipliers=cat(lambda r: r.multipliers),
        stats=stats, status=last.status, message=last.message, manifest=manifest,
        bodies=first.bodies, joints=first.joints, rotation=first.rotation,
        assembly=first.assembly, drift=last.drift, rotations=rotations)


def evaluate_spatial(sc: SpatialScene, y=None, t: float = 0.0) -> dict:
    """At the state y (default: the scene's initial state) and time t: the energy parts and
    residuals of the outputs, Phi, C (rows x 6 bodies), gamma, Phi_t (a driver's rows), the
    rank of the joints' rows at the initial state (below the row count: redundant joints), the
    reduced formulation's multipliers and y' (ydot), and the status of that solve (SINGULAR
    at a singular pose)."""
    _validate(sc)
    nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal = _tables(sc)
    y0 = sc.state0()
    if y is not None:
        try:
            y = np.asarray(y, dtype=float)
        except (TypeError, ValueError):
            y = None
        if y is None or y.shape != y0.shape or not np.all(np.isfinite(y)):
            raise InvalidInputError(f"y must be a finite state of {y0.size} numbers (the "
                                    f"scene's layout: q then (v, Omega) per body)")
    y = y0 if y is None else y
    m = sc.rows
    run = f"evaluating spatial scene {sc.name!r} ({nb} bodies, {m} constraint rows)"
    try:
        out, phi, c, gam, phit, lam, ydot, rank, asked, status = _kernel.spatial_residuals(
            mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal,
            float(ROTATIONS[sc.rotation]), y0, float(t), y, max(m, 1))
    except MemoryError as exc:   # the arrays f2py allocates, C (rows x 6 nb) the largest
        raise NoMemoryError(f"{run}: its arrays ({format_bytes(8.0 * max(m, 1) * 6 * nb)} for C "
                            f"alone, {m} x {6 * nb}) could not be allocated ({exc}); fewer "
                            "bodies or joints") from exc
    if status == Status.ERR_NO_MEMORY:
        raise NoMemoryError(f"{run}: " + no_memory_message(asked, samples=False))
    return {"kinetic": out[0], "gravity": out[1], "springs": out[2], "power": out[3],
            "phi": phi[:m], "C": c[:m], "gamma": gam[:m], "phi_t": phit[:m],
            "multipliers": lam[:m], "ydot": ydot,
            "rank": int(rank), "status": Status(int(status))}


_LOCK = {"euler313": "min |sin(theta)|", "cardan123": "min |cos(beta)|"}


def _lock_distance(sc: SpatialScene, q) -> float | None:
    """How near the bodies' angles are to their sequence's gimbal lock at coordinates q:
    the least |sin(theta)| (3-1-3) or |cos(beta)| (1-2-3); None for quaternions."""
    if sc.rotation == "quaternion":
        return None
    a = np.asarray(q).reshape(len(sc.bodies), 6)[:, 3:]
    return float(np.min(np.abs(np.sin(a[:, 1]) if sc.rotation == "euler313"
                               else np.cos(a[:, 1]))))


def _check_initial(sc, y0, assemble, t0=0.0):
    """Refuses, naming the joint, an initial state off its joints by more than the assembly
    should move (ASSEMBLY_TOL of the scene's size); without assembly, by more than roundoff."""
    if not sc.joints:
        return
    for j in sc.joints:
        if j.type in DRIVERS:
            c = j.function
            f0 = c[0] + c[1] * t0 + c[2] * math.sin(c[3] * t0 + c[4])
            if abs(f0) > 1e-12:
                raise SceneError(
                    f"{sc.source}: joint {j.name!r}: field 'function' gives f(t0) = {f0:.6g} at "
                    f"t0 = {t0:g}: a driver {DRIVERS[j.type]} by f(t) from where it starts, so "
                    "f(t0) must be 0 (shift the offset or the phase)")
    ev = evaluate_spatial(sc, y0, t0)
    if ev["rank"] == 0 and sc.rows:
        raise exception_for(Status.ERR_SINGULAR_MATRIX)(
            f"{sc.source}: the joints' rows are degenerate at the initial state (a row vanishes: "
            "e.g. a universal joint whose two axes are parallel, or coincident points where a "
            "direction is needed); give a pose where each joint is well defined")
    if ev["status"] not in (Status.SUCCESS, Status.ERR_SINGULAR_MATRIX):
        raise exception_for(ev["status"])(
            f"spatial scene {sc.name!r}: the kernel refused its tables "
            f"({status_message(ev['status'])})")
    phi = ev["phi"]
    size = max(1.0, max(float(np.max(np.abs(j.point1))) for j in sc.joints))
    tol = ASSEMBLY_TOL * size if assemble else 1e-10 * size
    w = y0[len(y0) - 6 * len(sc.bodies):]
    cw = ev["C"] @ w + ev["phi_t"]
    # the velocity rows: against the size of the terms that must cancel (|C| |w|), with a floor
    # of the speeds the scene's size gives to 1 rad/s
    vtol = (ASSEMBLY_TOL if assemble else 1e-10) * max(float(np.max(
        np.abs(ev["C"]) @ np.abs(w) + np.abs(ev["phi_t"]), initial=0.0)), size)
    for name, first, count in joint_rows(sc):
        worst = float(np.max(np.abs(cw[first:first + count])))
        if worst > vtol:
            raise InvalidInputError(
                f"{sc.source}: joint {name!r}: the initial velocities break this joint by "
                f"{worst:.3g} (largest |C w + Phi_t| of its rows; tolerance {vtol:.3g}): give "
                "velocities and angular velocities the joint allows (a body turning about a "
                "fixed point moves its centre at Omega x r)")
    for name, first, count in joint_rows(sc):
        worst = float(np.max(np.abs(phi[first:first + count])))
        if worst > tol:
            raise InvalidInputError(
                f"{sc.source}: joint {name!r}: the initial state is off this joint by "
                f"{worst:.3g} (largest |Phi| of its rows; tolerance {tol:.3g}"
                f"{'' if assemble else ', assemble_initial=False'}): give the bodies positions "
                "and orientations that satisfy it (the joint's 'at' point in space puts both "
                "ends on it)")
