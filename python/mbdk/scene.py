"""A scene: bodies, joints, force elements and effects, as Python objects.

One Scene holds bodies of either kind: planar bodies (x, y, angle; chapters 2-4 of the book)
with the planar joints, forces, contacts and wear, or spatial bodies (a centre and an
orientation; chapter 5) with the spatial joints, forces, contacts and wear. A scene's bodies
are of one kind (Scene.kind); a scene that mixes them is refused by name where it is read or
run. The scene
file format and its reader are python/mbdk/planar_file.py and spatial_file.py, reached through
python/mbdk/scene_file.py (mbdk.load_scene, mbdk.scene, mbdk.scenes).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .codes import BODY_KINDS, JOINT_ROWS, SPATIAL_JOINT_CODES, SPATIAL_JOINT_ROWS
from .errors import InvalidInputError
from .rotations import from_angles, to_quaternion

GROUND = "ground"


class SceneError(InvalidInputError):
    """A scene that cannot be simulated: the message names the file, element and field."""


@dataclass
class Body:
    name: str
    mass: float
    inertia: float
    x: float = 0.0
    y: float = 0.0
    angle: float = 0.0
    vx: float = 0.0
    vy: float = 0.0
    omega: float = 0.0
    given: tuple = ()
    kind: str = "planar"


@dataclass
class Joint:
    name: str
    type: str
    body1: str
    body2: str = GROUND
    point1: tuple = (0.0, 0.0)
    point2: tuple = (0.0, 0.0)
    axis: tuple = (1.0, 0.0)
    angle0: float | None = None
    coordinate: str = "angle"
    function: tuple = (0.0, 0.0, 0.0, 0.0, 0.0)
    #: a distance joint's L(t) as a time function; None: the initial distance, constant
    length: tuple | None = None
    #: a point_curve joint's ground curve y = f(x), f of the time-function family taken in x
    curve: tuple | None = None
    #: a coupling's second coordinate and its ratio: q2 - q2(0) = ratio (q1 - q1(0))
    coordinate2: str = "angle"
    ratio: float = 1.0
    #: a rolling disc's radius
    radius: float = 0.0


@dataclass
class Force:
    type: str
    name: str = ""
    body1: str = ""
    body2: str = GROUND
    point1: tuple = (0.0, 0.0)
    point2: tuple = (0.0, 0.0)
    g: tuple = (0.0, -9.81)
    force: tuple = (0.0, 0.0)
    torque: float = 0.0
    stiffness: float = 0.0
    damping: float = 0.0
    rest_length: float | None = None
    rest: float = 0.0
    coordinate: str = "x"
    function: tuple = (1.0, 0.0, 0.0, 0.0, 0.0)
    #: contacts: each shape as ("point" | "circle" | "line" | "ring", point, radius or normal)
    shape1: tuple = ()
    shape2: tuple = ()
    exponent: float = 1.0
    damping_depth: float = 0.0
    #: (static, dynamic, stiction_speed, transition_speed), or None: no friction
    friction: tuple | None = None
    #: gear meshes: the backlash along the line of action (the coast flanks' gap at the start;
    #: the drive flanks, those gear 1 pushes turning counter-clockwise, start in touch)
    backlash: float = 0.0


@dataclass
class Wear:
    name: str
    law: str
    load: str                    # "CONTACT.normal_force" or "CONTACT.friction_force"
    coefficient: float
    radius: float = 0.0
    temperature: float = 293.0
    a_x: float = 3e-10
    t0: float = 3e-12
    activation_energy: float = 49e3
    gas_constant: float = 8.31
    slide_roll: tuple = (1.0, 0.0, 0.0, 0.0)
    initial: float = 0.0

    @property
    def contact(self) -> str:
        return self.load.rpartition(".")[0]

    @property
    def quantity(self) -> str:
        return self.load.rpartition(".")[2]


@dataclass
class SpatialBody:
    name: str
    mass: float
    inertia: np.ndarray                 # 3 x 3, about the centre, body frame
    position: np.ndarray                # (3,)
    rotation: np.ndarray                # 3 x 3, body to space
    velocity: np.ndarray                # (3,)
    omega_body: np.ndarray              # (3,)

    @property
    def kind(self) -> str:
        return "spatial"


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
class Scene:
    """A mechanism: bodies of one kind (planar Body or SpatialBody), the joints and forces of
    that kind, and the wear of its contacts. rotation, quaternion_norm and norm_gain are the spatial
    bodies' orientation coordinates and how their quaternions keep |p| = 1
    (python/mbdk/spatial_file.py); planar scenes ignore them."""

    name: str
    bodies: list
    joints: list = field(default_factory=list)
    forces: list = field(default_factory=list)
    description: str = ""
    source: str = "<python>"
    wear: list = field(default_factory=list)
    rotation: str = "quaternion"
    quaternion_norm: str = "project"
    norm_gain: float = 10.0

    @property
    def kind(self) -> str:
        """"spatial" where a body is spatial, else "planar" (a scene that mixes the kinds is
        refused where it is read or run: mbdk.scene_file.checked)."""
        bodies = self.bodies if isinstance(self.bodies, list) else []
        return "spatial" if any(body_kind(b) == "spatial" for b in bodies) else "planar"

    def body_index(self, name: str) -> int:
        """1-based index of a body; 0 for the ground."""
        if name == GROUND:
            return 0
        # a name -> index table, rebuilt when the bodies changed under it (a scene of 10^4
        # bodies looks up two names per joint: a linear search made that quadratic)
        idx = self.__dict__.get("_body_index")
        i = idx.get(name) if idx is not None else None
        if i is None or i > len(self.bodies) or self.bodies[i - 1].name != name \
                or len(idx) > len(self.bodies):
            idx = {}
            for k, b in enumerate(self.bodies, 1):
                idx.setdefault(b.name, k)
            self.__dict__["_body_index"] = idx
            i = idx.get(name)
        if i is None:
            raise SceneError(f"{self.source}: no body named {name!r}")
        return i

    def q0(self) -> list:
        """The initial coordinates: x, y, angle per planar body; the centre and the orientation
        coordinates (the scene's rotation) per spatial body."""
        if self.kind == "spatial":
            return [float(x) for b in self.bodies
                    for x in (*b.position, *orientation_coordinates(b.rotation, self.rotation))]
        out = []
        for b in self.bodies:
            out += [b.x, b.y, b.angle]
        return out

    def v0(self) -> list:
        """The initial velocities: vx, vy, omega per planar body; the centre's velocity and the
        body-frame angular velocity per spatial body."""
        if self.kind == "spatial":
            return [float(x) for b in self.bodies for x in (*b.velocity, *b.omega_body)]
        out = []
        for b in self.bodies:
            out += [b.vx, b.vy, b.omega]
        return out

    def state0(self) -> np.ndarray:
        """The initial state y0 = [q, v] (the bodies' coordinates, then their velocities)."""
        return np.array(self.q0() + self.v0(), dtype=float)

    @property
    def rows(self) -> int:
        """The constraint rows of the joints."""
        return sum(count for _name, _first, count in self.joint_rows())

    def joint_rows(self) -> list:
        """(joint name, first row, row count) of each joint, in the kernel's row order."""
        table = SPATIAL_JOINT_ROWS if self.kind == "spatial" else JOINT_ROWS
        out, first = [], 0
        for j in self.joints:
            out.append((j.name, first, table[j.type]))
            first += table[j.type]
        return out


def body_kind(body) -> str | None:
    """A body's kind ("spatial", or a planar Body's kind field, "" where that is no name), or
    None for an object that is no body."""
    if isinstance(body, SpatialBody):
        return "spatial"
    if isinstance(body, Body):
        return body.kind if isinstance(body.kind, str) else ""
    return None


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


def body_kind_problem(kind) -> str | None:
    """Why a body of this kind cannot be simulated (the end of an error message), or None."""
    if not isinstance(kind, str) or kind not in BODY_KINDS:
        return f"= {kind!r} is not a body kind; known: {', '.join(BODY_KINDS)}"
    _code, coords, vels, available = BODY_KINDS[kind]
    if kind == "spatial":
        return (f"= {kind!r} in a planar scene: spatial bodies ({coords} coordinates, {vels} "
                "velocities) run in spatial scenes (python/mbdk/spatial_file.py), where every "
                "body is spatial; make this body 'planar', or all of the scene's bodies "
                "'spatial'")
    if not available:
        return (f"= {kind!r}: the kernel declares this kind ({coords} coordinates, {vels} "
                "velocities) but the planar model cannot simulate it; use 'planar'")
    return None


#: the planar joint and force types (their codes and rows: mbdk.codes, from the kernel)
JOINT_TYPES = {"revolute", "prismatic", "fixed", "driver", "distance", "point_line",
               "point_curve", "coupling", "rolling", "knife_edge"}
#: joints fixed to the ground by their nature (no body2)
GROUND_JOINTS = {"driver", "point_curve", "rolling", "knife_edge"}
FORCE_TYPES = {"gravity", "point_force", "torque", "spring", "damper", "spring_damper",
               "coordinate_spring", "coordinate_damper", "coordinate_spring_damper", "contact"}

#: the spatial joint and force types (their codes: mbdk.codes)
SPATIAL_JOINT_TYPES = set(SPATIAL_JOINT_CODES)
#: the spatial force types a scene file writes (a contact is stored as sphere_plane or
#: sphere_sphere, by its second shape)
SPATIAL_FORCE_TYPES = ("gravity", "point_force", "torque", "spring_damper", "spring", "damper",
                       "contact")
#: the spatial force types between two bodies (body2 may be the ground)
SPATIAL_TWO_BODY_FORCES = ("spring_damper", "sphere_plane", "sphere_sphere")
#: the drivers: rows that follow a time function, f(t0) = 0
DRIVERS = {"angle_driver": "turns body1", "slide_driver": "slides body1's point"}
