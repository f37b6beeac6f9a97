"""Spatial scene files (chapter 5 of the book): rigid bodies in 3D with spherical, revolute,
universal, cylindrical, prismatic and fixed joints, read into a Scene of spatial bodies
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

    [[force]]
    type = "contact"               # compliant contact (kernel/src/spatial/mbdk_contact3d.f90)
    name = "floor"
    body1 = "top"
    shape1 = { type = "sphere", radius = 0.001, centre = [0.0, 0.0, -0.1] }   # body1 frame;
                                   # or { type = "point", point = [...] } (radius 0)
    body2 = "ground"               # the default; or a body
    shape2 = { type = "plane", point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }
                                   # body2's frame (global on the ground), the normal pointing
                                   # to body1's side; or { type = "sphere", radius, centre }
    stiffness = 1e6                # F = k delta^exponent + damping step(delta) delta', >= 0
    exponent = 1.0                 # >= 1 (1.5: Hertz)
    damping = 1000.0               # default 0; never pulls
    damping_depth = 0.0            # the damping is fully in at this depth (0: at once)
    friction = { static = 0.5, dynamic = 0.5, stiction_speed = 1e-4, transition_speed = 2e-4 }
                                   # optional: regularised Coulomb friction on the slip at the
                                   # contact point (dynamic defaults to static, the speeds to
                                   # 1e-3 and 2e-3 m/s)

Formulations: reduced, baumgarte, penalty (Jalon-Bayo, penalty = (alpha_p, omega_p, mu_p),
default (1e7, 10, 1)), projection; bdf also i3, the index-3 DAE itself
(kernel/src/dae/mbdk_mechanism_dae.f90); trapezoidal_index3 in its augmented, projected form
(formulation "projected", the default: kernel/src/dae/mbdk_trapezoidal_index3.f90, fixed step);
ida in the forms index1 (the default) and ggl (kernel/src/sundials/mbdk_ida.f90); bdf also on
the stabilised index-2 form, "si2" (GGL's mu through T(q) M^-1 C^T, as in ida's ggl). Drivers: angle_driver and slide_driver. Every ODE method
runs: fixed step and error-controlled (dopri54, bs32, bdf; cvode_* on all but projection);
euler_cromer does not (its layout is y = [q, q'], and a spatial body's velocities are not its
coordinates' rates). Angle sets pass their gimbal lock with switch_angles
(python/mbdk/angle_switch.py).

Contacts use the planar contacts' laws (kernel/src/model/mbdk_contact_law.f90): the normal force
acts along the normal through the sphere's centre, friction at the contact point against the
slip of the two bodies' material points there. Their potential is part of the energy's
"springs", their damping and friction part of "power"; with locate_events (the default) dopri54
and bs32 end a step where a contact closes, where it lets go and where the surfaces of a contact
that let go part. A contact is stored as a SpatialForce of type sphere_plane or sphere_sphere
with the kernel's 19 reals (centre 1, radius 1, point or centre 2, normal, radius 2, stiffness,
exponent, damping, damping_depth, static, dynamic, stiction_speed, transition_speed).

Wear of a contact (kernel/src/model/mbdk_wear.f90's laws, the planar scenes' code): a state of
its own, the worn volume, integrated with the motion after the bodies' states; the result's
wear[name] is the volume against time. The entry is a planar scene's ([[wear]] in
python/mbdk/planar_file.py, with its fields and errors)::

    [[wear]]
    name = "ball"
    law = "archard"                # archard | knee: V' = k F |s| (times S/R(t) for knee)
    load = "floor.normal_force"    # CONTACT.normal_force or CONTACT.friction_force (mu F)
    coefficient = 5e-13            # k: volume per newton and metre of slip (m^3/(N m)), K/H
                                   # in Archard's form K F s / H

with |s| the slip speed at the contact point. The gear law is the planar gear pairs' (its speed
is R |omega1 - omega2|, not a slip): a spatial contact refuses it by name. Wear takes no energy
of its own (the contact's friction dissipates what the energy balance counts).

Bad scenes raise SceneError naming the file, the element and the field.
"""
from __future__ import annotations

import numpy as np

from .checks import NUMBER_MAX, NUMBER_MIN, number_problem, show
from .codes import (NORMS, ROTATIONS, SPATIAL_FORCE_CODES, SPATIAL_FORCE_REALS,
                    SPATIAL_JOINT_CODES, WEAR_LAWS)
from .rotations import from_angles, from_quaternion, matvec_fixed, norm_fixed
from .scene import (DRIVERS, GROUND, SPATIAL_FORCE_TYPES, SPATIAL_TWO_BODY_FORCES, Body, Scene,
                    SceneError, SpatialBody, SpatialForce, SpatialJoint, Wear)
from .scene_fields import (FieldReader, check_wear_contacts, read_friction, read_wear,
                           section_items, wear_table)


#: how far from 1 the norm of a given quaternion may be (the kernel's MBDK_UNIT_TOL)
UNIT_TOL = 1e-8


#: how far from 1 the norm of a quaternion written in a scene file may be: a unit quaternion
#: written to 6 decimals has each component rounded by up to 5e-7, which moves its norm by up
#: to 5e-7 (|q|_1 <= 2); the reader takes the rotation of q / |q|
WRITTEN_UNIT_TOL = 1e-6


#: the friction law of a contact without friction (mus = mud = 0; the speeds only valid)
NO_FRICTION = (0.0, 0.0, 1e-3, 2e-3)


class _SpatialReader(FieldReader):
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
        return v / norm_fixed(v)


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
        norm = norm_fixed(q)
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
        om = matvec_fixed(rot.T, r.vec3("omega"))
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
    if typ not in SPATIAL_JOINT_CODES:
        raise r.err("type", f"= {typ!r} is not a spatial joint type; known: "
                            f"{', '.join(SPATIAL_JOINT_CODES)}")
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
        p1, p2 = matvec_fixed(R1.T, at - r1), matvec_fixed(R2.T, at - r2)
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
        a1, a2 = matvec_fixed(R1.T, ax), matvec_fixed(R2.T, ax)
    elif typ == "universal":
        ax1, ax2 = r.unit3("axis1", required=True), r.unit3("axis2", required=True)
        if abs(ax1 @ ax2) > 1e-9:
            raise r.err("axis2", f"= {ax2.tolist()} is not normal to axis1 = {ax1.tolist()} "
                                 f"(cosine {ax1 @ ax2:.3g}); a universal joint's two axes are")
        a1, a2 = matvec_fixed(R1.T, ax1), matvec_fixed(R2.T, ax2)
    j = SpatialJoint(name, typ, b1, b2, p1, p2, a1, a2, fn)
    r.done()
    return j


def _spatial_force(r: _SpatialReader, bodies: dict) -> SpatialForce:
    typ = r.name("type")
    if typ not in SPATIAL_FORCE_TYPES:
        raise r.err("type", f"= {typ!r} is not a spatial force type; known: "
                            f"{', '.join(SPATIAL_FORCE_TYPES)}")
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
    if typ == "contact":
        return _done(r, _spatial_contact(r, name, b1, b2))
    if b1 == b2:
        raise r.err("body2", f"= {b2!r} is body1 too; a spring joins two bodies")
    (r1, R1), (r2, R2) = _frame(bodies, b1), _frame(bodies, b2)
    p1 = (matvec_fixed(R1.T, r.vec3("at1") - r1) if r.has("at1") else
          r.vec3("point1", np.zeros(3)))
    p2 = (matvec_fixed(R2.T, r.vec3("at2") - r2) if r.has("at2") else
          r.vec3("point2", np.zeros(3)))
    k = r.num("stiffness", 0.0, required=typ == "spring", nonneg=True) if typ != "damper" else 0.0
    c = r.num("damping", 0.0, required=typ == "damper", nonneg=True) if typ != "spring" else 0.0
    rest = r.num("rest_length", None, nonneg=True)
    if rest is None:
        rest = norm_fixed(r1 + matvec_fixed(R1, p1) - r2 - matvec_fixed(R2, p2))
    return _done(r, SpatialForce("spring_damper", name, b1, b2,
                                 reals=(*p1, *p2, k, c, rest)))


def _done(r, x):
    r.done()
    return x


def _spatial_contact(r: _SpatialReader, name: str, b1: str, b2: str) -> SpatialForce:
    """A contact (the module docstring): sphere_plane or sphere_sphere, with the reals of
    kernel/src/spatial/mbdk_contact3d.f90."""
    if b1 == b2:
        raise r.err("body2", f"= {b2!r} is body1 too; a contact is between two bodies (or a "
                             "body and the ground)")
    c1, r1 = _contact_shape(r, "shape1", ("sphere", "point"))
    kind2 = _contact_shape(r, "shape2", ("plane", "sphere"))
    if len(kind2) == 3:               # a plane: point, normal
        p2, n2, r2, typ = kind2[0], kind2[1], 0.0, "sphere_plane"
    else:
        p2, r2 = kind2
        n2, typ = np.zeros(3), "sphere_sphere"
        if not r1 + r2 > 0:
            raise r.err("shape2", "is a sphere of radius 0 against a point: two points never "
                                  "touch; give one of them a radius")
    k = r.num("stiffness", required=True, nonneg=True)
    e = r.num("exponent", 1.0)
    if e < 1:
        raise r.err("exponent", f"= {e} must be at least 1 (below 1 the force's slope is "
                                "infinite where the contact closes)")
    c = r.num("damping", 0.0, nonneg=True)
    depth = r.num("damping_depth", 0.0, nonneg=True)
    fric = read_friction(r) if r.has("friction") else NO_FRICTION
    return SpatialForce(typ, name, b1, b2, reals=(*c1, r1, *p2, *n2, r2, k, e, c, depth, *fric))


def _contact_shape(r: _SpatialReader, fld: str, kinds: tuple):
    """A contact's shape in its body's frame (global on the ground): a sphere or a point as
    (centre, radius), a plane as (point, unit normal, "plane")."""
    v = r.get(fld, required=True)
    if not isinstance(v, dict) or v.get("type") not in kinds:
        raise r.err(fld, f"= {show(v)} must be a table {{type = {' | '.join(kinds)}, ...}}")
    sr = _SpatialReader(r.source, f"{r.label} {fld}", 0, v)
    typ = sr.get("type")
    if typ == "plane":
        out = (sr.vec3("point", np.zeros(3)), sr.unit3("normal", required=True), "plane")
    elif typ == "point":
        out = (sr.vec3("point", np.zeros(3)), 0.0)
    else:
        out = (sr.vec3("centre", np.zeros(3)), sr.num("radius", required=True, positive=True))
    extra = [k for k in v if k not in sr.used]
    if extra:
        raise r.err(fld, f"entry {extra[0]!r} is not a field of a {typ} (a {typ} has "
                         f"{', '.join(sorted(sr.used))})")
    return out


def is_spatial(data: dict) -> bool:
    """Whether a parsed scene file is spatial: one of its bodies says kind = "spatial"."""
    bodies = data.get("body", []) if isinstance(data, dict) else []
    return isinstance(bodies, list) and any(isinstance(b, dict) and b.get("kind") == "spatial"
                                            for b in bodies)


def spatial_scene_from_dict(data: dict, source: str = "<dict>") -> Scene:
    """Builds and checks a Scene of spatial bodies from the parsed TOML structure."""
    known = {"scene", "body", "joint", "force", "wear"}
    extra = [k for k in data if k not in known]
    if extra:
        raise SceneError(f"{source}: unknown section {extra[0]!r}; a scene has "
                         "[scene], [[body]], [[joint]], [[force]] and [[wear]]")
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
    wear = [read_wear(FieldReader(source, "wear", i, t)) for i, t in enumerate(items("wear"))]
    names = [j.name for j in joints]
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup is not None:
        raise SceneError(f"{source}: joint name {dup!r} is used twice")
    sc = Scene(name, list(bodies.values()), joints, forces, description=desc, source=source,
               wear=wear, rotation=rotation, quaternion_norm=norm, norm_gain=gain)
    _check_wear(sc)
    return sc


#: the force types of spatial contacts, the ones wear can name
CONTACT_TYPES = ("sphere_plane", "sphere_sphere")


def _check_wear(sc: Scene) -> None:
    """The wear elements against the scene's contacts (as a planar scene's, check_wear_contacts)
    and the laws a spatial contact takes; a contact that wear names has a name of its own."""
    contacts = {}
    for f in sc.forces:
        if isinstance(f, SpatialForce) and f.type in CONTACT_TYPES:
            if f.name in contacts and any(w.contact == f.name for w in sc.wear):
                raise SceneError(f"{sc.source}: force {f.name!r}: field 'name' is used by two "
                                 "contacts, and a wear element names it; give each contact a "
                                 "name of its own")
            # mus or mud > 0 (mbdk_contact3d_rough): the contact has friction
            contacts[f.name] = len(f.reals) == SPATIAL_FORCE_REALS and \
                (f.reals[15] > 0 or f.reals[16] > 0)
    for w in sc.wear:
        if w.law == "gear":
            raise SceneError(f"{sc.source}: wear {w.name!r}: field 'law' = 'gear': the gear "
                             "law's speed is a planar gear pair's R |omega1 - omega2| (Fekete "
                             "(2023) (6.9)), which a sphere contact has not; use archard or knee, "
                             "whose speed is the contact's slip")
    check_wear_contacts(sc, contacts, {})


def validate_spatial(sc: Scene) -> None:
    """The checks of the reader, again on a spatial Scene whose fields were changed in Python
    after it was read (or that was built in Python): each names the element and the field."""
    if not isinstance(sc.bodies, list) or not sc.bodies:
        raise SceneError(f"{sc.source}: a spatial scene needs a list of at least one body")
    for fld in ("joints", "forces"):
        if not isinstance(getattr(sc, fld), list):
            raise SceneError(f"{sc.source}: scene: field {fld!r} = {getattr(sc, fld)!r} must "
                             "be a list")
    if not isinstance(sc.wear, list):
        raise SceneError(f"{sc.source}: scene: field 'wear' = {sc.wear!r} must be a list")
    for i, w in enumerate(sc.wear):
        if not isinstance(w, Wear):
            raise SceneError(f"{sc.source}: wear #{i + 1} = {w!r} is not a Wear (known laws: "
                             f"{', '.join(WEAR_LAWS)})")
        # the file's own checks and errors, field by field
        read_wear(FieldReader(sc.source, "wear", i, wear_table(w)))
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
        if isinstance(b, Body):
            raise SceneError(f"{sc.source}: {label} is a planar body in a scene of spatial "
                             "bodies: a scene's bodies are of one kind; make it a SpatialBody "
                             "(a planar motion is a spatial one held in its plane by joints)")
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
                j.type not in SPATIAL_JOINT_CODES:
            raise SceneError(f"{sc.source}: {label}: field 'type' must be one of "
                             f"{', '.join(SPATIAL_JOINT_CODES)}")
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
        if isinstance(f, SpatialForce) and isinstance(f.type, str) and \
                f.type in ("spring", "damper"):
            raise SceneError(f"{sc.source}: {label}: field 'type' = {f.type!r}: a SpatialForce "
                             "object's spring or damper has type 'spring_damper'")
        if not isinstance(f, SpatialForce) or not isinstance(f.type, str) or \
                f.type not in SPATIAL_FORCE_CODES:
            raise SceneError(f"{sc.source}: {label}: field 'type' must be one of "
                             f"{', '.join(SPATIAL_FORCE_CODES)}")
        for fld in ("body1", "body2"):
            if not isinstance(getattr(f, fld), str):
                raise SceneError(f"{sc.source}: {label}: field {fld!r} = {getattr(f, fld)!r} "
                                 "must be a body's name")
        want = {"gravity": 3, "point_force": 6, "torque": 3, "sphere_plane": SPATIAL_FORCE_REALS,
                "sphere_sphere": SPATIAL_FORCE_REALS}.get(f.type, 9)
        r = vec(label, "reals", f.reals, (want,))
        if f.type == "spring_damper" and not (r[6] >= 0 and r[7] >= 0 and r[8] >= 0):
            raise SceneError(f"{sc.source}: {label}: stiffness, damping and rest_length "
                             f"{r[6:].tolist()} must be >= 0")
        if f.type in ("sphere_plane", "sphere_sphere"):
            _validate_contact(sc, label, f.type, r)
        ends = [f.body1] + ([f.body2] if f.type in SPATIAL_TWO_BODY_FORCES else [])
        if f.type != "gravity" and (f.body1 not in names or any(
                e != GROUND and e not in names for e in ends) or
                (len(ends) == 2 and ends[0] == ends[1])):
            raise SceneError(f"{sc.source}: {label}: its bodies {ends} are not two (or one) "
                             "distinct bodies of this scene")
    _check_wear(sc)


def _validate_contact(sc: Scene, label: str, typ: str, r: np.ndarray) -> None:
    """A contact's reals (mbdk_contact3d's layout), each wrong one named."""
    def bad(what, msg):
        return SceneError(f"{sc.source}: {label}: {what} {msg}")
    if not (r[3] >= 0 and r[10] >= 0):
        raise bad("the radii", f"{r[3]}, {r[10]} must be >= 0")
    if typ == "sphere_plane" and not np.linalg.norm(r[7:10]) > 0:
        raise bad("the plane's normal", f"{r[7:10].tolist()} has no direction")
    if typ == "sphere_sphere" and not r[3] + r[10] > 0:
        raise bad("the radii", "are both 0: two points never touch")
    for i, fld, low in ((11, "stiffness", 0.0), (12, "exponent", 1.0), (13, "damping", 0.0),
                        (14, "damping_depth", 0.0), (15, "friction static", 0.0),
                        (16, "friction dynamic", 0.0)):
        if not r[i] >= low:
            raise bad(f"field {fld!r}", f"= {r[i]} must be at least {low:g}")
    if not 0 < r[17] < r[18]:
        raise bad("the friction's speeds", f"stiction_speed = {r[17]}, transition_speed = "
                                           f"{r[18]} must satisfy 0 < stiction < transition")
