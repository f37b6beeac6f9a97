"""Planar scene files: TOML -> a Scene of planar bodies, joints, forces and wear, and back.

A scene file (SI units; angles in radians unless a field ends in _deg)::

    [scene]
    name = "physical_pendulum"
    description = "a uniform bar hinged at one end (Fekete 2023, 2.4.1)"

    [[body]]
    name = "bar"
    kind = "planar"                           # the default; the kernel's body kinds
    mass = 1.0
    shape = { type = "bar", length = 1.0 }    # or: inertia = 0.0833 (centroidal, kg m^2)
    x = 0.25                                  # centroid and angle; vx, vy, omega: their rates
    y = -0.4330127
    angle_deg = -60
    given = ["angle", "omega"]                # kept when the initial state is assembled

    [[joint]]
    name = "hinge"
    type = "revolute"                         # revolute | prismatic | fixed | driver | ...
    body1 = "bar"
    point1 = [-0.5, 0.0]                      # body-fixed, from the centroid
    body2 = "ground"                          # ground points are global
    point2 = [0.0, 0.0]

    [[force]]
    type = "gravity"                          # only when declared
    g = [0.0, -9.81]

Bodies: planar (x, y, angle). A scene with a body of kind "spatial" is a spatial scene (chapter 5
of the book): python/mbdk/spatial_file.py reads it and gives its format.

Joints: revolute (body1, point1, body2, point2); prismatic (the same, plus axis: a unit vector
fixed in body2, global for the ground, and the relative angle kept at its initial value or
angle0); fixed (revolute plus the relative angle); driver (body1, coordinate = x | y | angle,
function: the coordinate follows f(t)); distance (body1, point1, body2, point2, length: the
points' distance, a number or a time function L(t), by default the initial distance; the
mathematical pendulum (1.5) and the pendulum of changing length (1.6)); point_line (body1,
point1 on the line through point2 of body2 along axis: a slider that turns freely);
point_curve (body1, point1 on the ground curve y = f(x), curve a time-function table taken in
x); coupling (body1, coordinate1, body2, coordinate2, ratio: q2 - q2(0) = ratio (q1 - q1(0));
gears on fixed axles: the angles with ratio -R1/R2, or +R1/R2 for an internal gear; a rack
along x driven by a pinion: coordinate1 = "angle", coordinate2 = "x", ratio -R for a rack
above the pinion, +R below it); rolling
(body1 a disc of radius rolling without slip on the ground line through point along
direction, on its left: (1.15)-(1.20), integrated to the position rows of x = R phi and y =
R); knife_edge (body1, point1, axis: the point has no velocity across the body-fixed axis, a
nonholonomic constraint: the car of (1.7)-(1.14) at the centroid, a skate off it).

Forces: gravity (g); point_force (body, point, force = [Fx, Fy] global, function); torque
(body, torque, function); spring (body1, point1, body2, point2, stiffness, rest_length: default
the initial length); damper (same points, damping); spring_damper (both); coordinate_spring,
coordinate_damper, coordinate_spring_damper (body, coordinate, stiffness, damping, rest: the
trolley's -s x1 - k x1'); contact (below).

A contact (kernel/src/model/mbdk_contact.f90: the IMPACT normal force with Coulomb friction)::

    [[force]]
    type = "contact"
    name = "floor"
    body1 = "ball"
    shape1 = { type = "circle", radius = 0.1 }            # or { type = "point" }; centre = [x, y]
    body2 = "ground"
    shape2 = { type = "line", point = [0, 0], normal = [0, 1] }
    #        or { type = "circle", radius, centre }: two circles outside each other
    #        or { type = "ring", radius, centre }: body1's circle held inside (Fekete 2023, (1.22))
    stiffness = 1e6              # F = k delta^exponent + damping step(delta) delta'
    exponent = 1.5               # >= 1 (default 1)
    damping = 50.0               # default 0
    damping_depth = 1e-4         # where the damping is fully in (step: 0 at delta = 0; 0: at once)
    friction = { static = 0.3, dynamic = 0.2, stiction_speed = 1e-3, transition_speed = 2e-3 }

Points and normals of a shape are in its body's frame (global on the ground); a line's normal
points to the side body1 is on. Friction is optional (dynamic defaults to static, the speeds to
1e-3 and 2e-3 m/s).

Wear (kernel/src/model/mbdk_wear.f90: the laws of chapter 6), a state of its own integrated with
the motion; the result's wear[name] is the worn volume against time::

    [[wear]]
    name = "plateau"
    law = "archard"              # archard | gear | knee
    load = "floor.normal_force"  # CONTACT.normal_force or CONTACT.friction_force
    coefficient = 1.3e-15        # k: volume per newton and metre of sliding (m^3/(N m))
    # gear: radius (R of (6.6)), temperature (K), and a_x, t0, activation_energy, gas_constant
    #       (defaults: table 6.4's 3e-10 m, 3e-12 s, 49e3 J/mol, 8.31 J/(mol K))
    # knee: slide_roll = [c0, c1, c2, c3], S/R(t) = c0 + c1 t + c2 t^2 + c3 t^3 (table 6.7)

A time function is a table {offset, rate, amplitude, omega, phase}: f(t) = offset + rate t +
amplitude sin(omega t + phase); a number is a constant. Loads are multiplied by f(t) (default 1).

Bad scenes raise SceneError naming the file, the element and the field.
"""
from __future__ import annotations

import math
from pathlib import Path

from .checks import NUMBER_MAX, NUMBER_MIN, length_scale, show
from .codes import JOINT_ROWS
from .scene import (FORCE_TYPES, GROUND, GROUND_JOINTS, JOINT_TYPES, Body, Force, Joint, Scene,
                    SceneError, body_kind_problem)
from .scene_fields import (FieldReader, check_wear_contacts, read_friction, read_wear,
                           section_items, wear_table)


def _body(r: FieldReader) -> Body:
    name = r.name("name")
    body_kind = r.name("kind", required=False, default="planar")
    problem = body_kind_problem(body_kind)
    if problem:
        raise r.err("kind", problem)
    mass = r.num("mass", required=True, positive=True)
    if r.has("inertia") and r.has("shape"):
        raise r.err("inertia", "and 'shape' are both given; give one")
    if r.has("shape"):
        shape = r.get("shape")
        if not isinstance(shape, dict) or shape.get("type") not in ("bar", "point", "disc",
                                                                     "rectangle"):
            raise r.err("shape", f"= {shape!r} must be {{type = bar | point | disc | rectangle, ...}}")
        sr = FieldReader(r.source, f"{r.label} shape", 0, shape)
        sr.get("type")
        kind = shape["type"]
        try:
            if kind == "bar":
                inertia = mass * sr.num("length", required=True, positive=True) ** 2 / 12
            elif kind == "disc":
                inertia = mass * sr.num("radius", required=True, positive=True) ** 2 / 2
            elif kind == "rectangle":
                inertia = mass * (sr.num("width", required=True, positive=True) ** 2
                                  + sr.num("height", required=True, positive=True) ** 2) / 12
            else:
                inertia = 0.0
        except OverflowError:
            inertia = math.inf
        if not math.isfinite(inertia) or inertia > NUMBER_MAX or 0 < inertia < NUMBER_MIN:
            raise r.err("shape", f"= {show(shape)} gives an inertia of {inertia:.3g}, out of "
                                 "range (a nonzero inertia must lie between 1e-150 and 1e150); "
                                 "give the body's size in metres and its mass in kg")
        sr.done()
    else:
        inertia = r.num("inertia", required=True, nonneg=True)
    given = r.get("given", [])
    ok = {"x", "y", "angle", "vx", "vy", "omega"}
    if not isinstance(given, list) or any(g not in ok for g in given):
        raise r.err("given", f"= {given!r} must list some of {', '.join(sorted(ok))}")
    b = Body(name, mass, inertia, r.num("x", 0.0), r.num("y", 0.0), r.angle("angle"),
             r.num("vx", 0.0), r.num("vy", 0.0), r.num("omega", 0.0), tuple(given), body_kind)
    r.done()
    return b


def _unit(r: FieldReader, fld: str, default) -> tuple:
    """A direction: the vector fld made unit (required when default is None)."""
    ax = r.vec(fld, default, required=default is None)
    n = math.hypot(*ax)
    if n == 0:
        raise r.err(fld, "= [0, 0] has no direction")
    return (ax[0] / n, ax[1] / n)


def _joint(r: FieldReader) -> Joint:
    typ = r.name("type")
    if typ not in JOINT_TYPES:
        raise r.err("type", f"= {typ!r} is not a joint type; known: {', '.join(sorted(JOINT_TYPES))}")
    name = r.name("name", required=False, default=f"joint{r.index + 1}")
    if typ == "driver":
        j = Joint(name, typ, r.name("body1"), coordinate=r.coordinate("coordinate", "angle"),
                  function=r.function("function", None))
        if j.function is None:
            raise r.err("function", "is missing (the driven coordinate's f(t))")
    elif typ == "point_curve":
        j = Joint(name, typ, r.name("body1"), point1=r.vec("point1", (0.0, 0.0)),
                  curve=r.function("curve", None))
        if j.curve is None:
            raise r.err("curve", "is missing (the ground curve y = f(x): a table {offset, rate, "
                                 "amplitude, omega, phase})")
    elif typ == "coupling":
        j = Joint(name, typ, r.name("body1"), r.name("body2"),
                  coordinate=r.coordinate("coordinate1", "angle"),
                  coordinate2=r.coordinate("coordinate2", "angle"),
                  ratio=r.num("ratio", required=True))
        if j.ratio == 0:
            raise r.err("ratio", "= 0 couples nothing: body2's coordinate would be fixed; use a "
                                 "driver or a fixed joint")
    elif typ == "rolling":
        j = Joint(name, typ, r.name("body1"), point2=r.vec("point", (0.0, 0.0)),
                  radius=r.num("radius", required=True))
        if not j.radius > 0:
            raise r.err("radius", f"= {j.radius:g} must be positive (the disc's rolling radius)")
        j.axis = _unit(r, "direction", (1.0, 0.0))
    elif typ == "knife_edge":
        j = Joint(name, typ, r.name("body1"), point1=r.vec("point1", (0.0, 0.0)))
        j.axis = _unit(r, "axis", (1.0, 0.0))
    else:
        j = Joint(name, typ, r.name("body1"), r.name("body2", required=False, default=GROUND),
                  r.vec("point1", (0.0, 0.0)), r.vec("point2", (0.0, 0.0)))
        if typ in ("prismatic", "point_line"):
            j.axis = _unit(r, "axis", None)
        if typ in ("prismatic", "fixed") and (r.has("angle0") or r.has("angle0_deg")):
            j.angle0 = r.angle("angle0")
        if typ == "distance":
            j.length = r.function("length", None)
            if j.length is not None:
                off, _rate, amp, _om, ph = j.length
                if not off + amp * math.sin(ph) > 0:
                    raise r.err("length", f"= {r.get('length')!r} gives L(0) = "
                                          f"{off + amp * math.sin(ph):g}: a distance must be "
                                          "positive")
    r.done()
    return j


def _force(r: FieldReader) -> Force:
    typ = r.name("type")
    if typ not in FORCE_TYPES:
        raise r.err("type", f"= {typ!r} is not a force type; known: {', '.join(sorted(FORCE_TYPES))}")
    f = Force(typ, r.name("name", required=False, default=f"{typ}{r.index + 1}"))
    if typ == "gravity":
        f.g = r.vec("g", required=True)
    elif typ == "point_force":
        f.body1 = r.name("body")
        f.point1 = r.vec("point", (0.0, 0.0))
        f.force = r.vec("force", required=True)
        f.function = r.function("function", f.function)
    elif typ == "torque":
        f.body1 = r.name("body")
        f.torque = r.num("torque", required=True)
        f.function = r.function("function", f.function)
    elif typ in ("spring", "damper", "spring_damper"):
        f.body1 = r.name("body1")
        f.point1 = r.vec("point1", (0.0, 0.0))
        f.body2 = r.name("body2", required=False, default=GROUND)
        f.point2 = r.vec("point2", (0.0, 0.0))
        if typ != "damper":
            f.stiffness = r.num("stiffness", required=True, nonneg=True)
            f.rest_length = r.num("rest_length", None, nonneg=True)
        if typ != "spring":
            f.damping = r.num("damping", required=True, nonneg=True)
    elif typ == "contact":
        f.body1 = r.name("body1")
        f.body2 = r.name("body2", required=False, default=GROUND)
        f.shape1 = _shape(r, "shape1", ("point", "circle", "gear"))
        f.shape2 = _shape(r, "shape2", ("line", "circle", "ring", "gear"))
        if (f.shape1[0] == "gear") != (f.shape2[0] == "gear"):
            raise r.err("shape2", f"= {f.shape2[0]!r} against shape1 = {f.shape1[0]!r}: a gear "
                                  "meshes only with a gear")
        if f.shape1[0] == "gear":
            z1, m1, a1, _ = f.shape1[2]
            z2, m2, a2, _ = f.shape2[2]
            if abs(m1 * math.cos(a1) - m2 * math.cos(a2)) > 1e-12 * m1:
                raise r.err("shape2", f"module {m2} and pressure angle {math.degrees(a2):g} deg "
                                      f"against gear 1's {m1} and {math.degrees(a1):g} deg: "
                                      "involute gears mesh only with the same base pitch "
                                      "pi m cos(alpha)")
            if f.body2 == GROUND:
                raise r.err("body2", "= 'ground': a gear mesh is between two bodies, each gear "
                                     "centred at its body's origin")
            f.backlash = r.num("backlash", 0.0, nonneg=True)
        f.stiffness = r.num("stiffness", required=True, nonneg=True)
        f.exponent = r.num("exponent", 1.0)
        if f.exponent < 1:
            raise r.err("exponent", f"= {f.exponent} must be at least 1 (below 1 the force's "
                                    "slope is infinite where the contact closes)")
        f.damping = r.num("damping", 0.0, nonneg=True)
        f.damping_depth = r.num("damping_depth", 0.0, nonneg=True)
        if f.shape2[0] == "ring" and not f.shape2[2] > f.shape1[2]:
            raise r.err("shape2", f"= ring of radius {f.shape2[2]} must be larger than body1's "
                                  f"circle (radius {f.shape1[2]}) to hold it")
        if r.has("friction"):
            f.friction = read_friction(r)
    else:
        f.body1 = r.name("body")
        f.coordinate = r.coordinate("coordinate", "x")
        if typ != "coordinate_damper":
            f.stiffness = r.num("stiffness", required=True, nonneg=True)
            f.rest = r.num("rest", 0.0)
        if typ != "coordinate_spring":
            f.damping = r.num("damping", required=True, nonneg=True)
    r.done()
    return f


def _shape(r: FieldReader, fld: str, kinds: tuple) -> tuple:
    """A contact's shape table as (type, point, radius or normal)."""
    v = r.get(fld, required=True)
    if not isinstance(v, dict) or v.get("type") not in kinds:
        raise r.err(fld, f"= {v!r} must be a table {{type = {' | '.join(kinds)}, ...}}")
    sr = FieldReader(r.source, f"{r.label} {fld}", 0, v)
    typ = sr.get("type")
    if typ == "line":
        point = sr.vec("point", (0.0, 0.0))
        n = sr.vec("normal", required=True)
        ln = math.hypot(*n)
        if not ln > 0:
            raise r.err(fld, f"normal = {list(n)} has no direction")
        out = (typ, point, (n[0] / ln, n[1] / ln))
    elif typ == "point":
        out = (typ, sr.vec("point", (0.0, 0.0)), 0.0)
    elif typ == "gear":
        z = sr.num("teeth", required=True, positive=True)
        if z != int(z) or z < 3:
            raise r.err(fld, f"teeth = {z} must be a whole number of at least 3")
        alpha = math.radians(sr.num("pressure_angle_deg", 20.0))
        if not 0 < alpha < math.pi / 2:
            raise r.err(fld, f"pressure_angle_deg = {math.degrees(alpha)} must lie between 0 "
                             "and 90")
        out = (typ, (0.0, 0.0), (int(z), sr.num("module", required=True, positive=True), alpha,
                                 sr.num("addendum", 1.0, positive=True)))
    else:
        out = (typ, sr.vec("centre", (0.0, 0.0)), sr.num("radius", required=True, positive=True))
    try:
        sr.done()
    except SceneError:
        extra = [k for k in v if k not in sr.used]
        raise r.err(fld, f"entry {extra[0]!r} is not a field of a {typ} "
                         f"(a {typ} has {', '.join(sorted(sr.used))})") from None
    return out


def planar_scene_from_dict(data: dict, source: str = "<dict>") -> Scene:
    """Builds and checks a Scene of planar bodies from the parsed TOML structure."""
    known = {"scene", "body", "joint", "force", "wear"}
    extra = [k for k in data if k not in known]
    if extra:
        raise SceneError(f"{source}: unknown section {extra[0]!r}; a scene has "
                         "[scene], [[body]], [[joint]], [[force]] and [[wear]]")
    head = data.get("scene", {})
    hr = FieldReader(source, "scene", 0, head)
    name = hr.name("name", required=False, default=Path(source).stem)
    desc = hr.get("description", "")
    hr.get("reference")
    hr.done()

    def items(key):
        return section_items(data, key, source)

    bodies = [_body(FieldReader(source, "body", i, t)) for i, t in enumerate(items("body"))]
    joints = [_joint(FieldReader(source, "joint", i, t)) for i, t in enumerate(items("joint"))]
    forces = [_force(FieldReader(source, "force", i, t)) for i, t in enumerate(items("force"))]
    wear = [read_wear(FieldReader(source, "wear", i, t)) for i, t in enumerate(items("wear"))]
    sc = Scene(name, bodies, joints, forces, desc, source, wear)
    check_scene(sc)
    sc._read_as = _snapshot(sc)   # what checked() compares against
    return sc


_FN_KEYS = ("offset", "rate", "amplitude", "omega", "phase")


def _fn(v):
    """A time function as the file writes it (a table), or the value as it is (the reader
    names what is wrong with it)."""
    if isinstance(v, (tuple, list)) and len(v) == 5:
        return dict(zip(_FN_KEYS, v))
    return dict(v) if isinstance(v, dict) else v


def _seq(v):
    """A copy, so that a snapshot does not change with the scene's own lists."""
    return list(v) if isinstance(v, (tuple, list)) else v


def planar_scene_to_dict(sc: Scene) -> dict:
    """A planar scene as the parsed TOML structure the reader takes (the inverse of
    planar_scene_from_dict): each element with exactly the fields its type has. Values are passed as
    they are, so that reading the result checks a Scene changed in Python with the reader's own
    rules and messages."""
    bodies = [{"name": b.name, "kind": b.kind, "mass": b.mass, "inertia": b.inertia, "x": b.x,
               "y": b.y, "angle": b.angle, "vx": b.vx, "vy": b.vy, "omega": b.omega,
               "given": _seq(b.given)} for b in sc.bodies]
    joints = []
    for j in sc.joints:
        d = {"name": j.name, "type": j.type, "body1": j.body1}
        t = j.type if isinstance(j.type, str) else None
        if t == "driver":
            d.update(coordinate=j.coordinate, function=_fn(j.function))
        elif t == "point_curve":
            d.update(point1=_seq(j.point1), curve=_fn(j.curve))
        elif t == "coupling":
            d.update(body2=j.body2, coordinate1=j.coordinate, coordinate2=j.coordinate2,
                     ratio=j.ratio)
        elif t == "rolling":
            d.update(point=_seq(j.point2), direction=_seq(j.axis), radius=j.radius)
        elif t == "knife_edge":
            d.update(point1=_seq(j.point1), axis=_seq(j.axis))
        else:
            d.update(body2=j.body2, point1=_seq(j.point1), point2=_seq(j.point2))
            if isinstance(j.type, str) and j.type in ("prismatic", "point_line"):
                d["axis"] = _seq(j.axis)
            if isinstance(j.type, str) and j.type in ("prismatic", "fixed") and \
                    j.angle0 is not None:
                d["angle0"] = j.angle0
            if isinstance(j.type, str) and j.type == "distance" and j.length is not None:
                d["length"] = _fn(j.length)
        joints.append(d)
    forces = []
    for f in sc.forces:
        t = f.type if isinstance(f.type, str) else None
        d = {"name": f.name, "type": f.type}
        if t == "gravity":
            d["g"] = _seq(f.g)
        elif t == "point_force":
            d.update(body=f.body1, point=_seq(f.point1), force=_seq(f.force),
                     function=_fn(f.function))
        elif t == "torque":
            d.update(body=f.body1, torque=f.torque, function=_fn(f.function))
        elif t in ("spring", "damper", "spring_damper"):
            d.update(body1=f.body1, point1=_seq(f.point1), body2=f.body2,
                     point2=_seq(f.point2))
            if t != "damper":
                d["stiffness"] = f.stiffness
                if f.rest_length is not None:
                    d["rest_length"] = f.rest_length
            if t != "spring":
                d["damping"] = f.damping
        elif t == "contact":
            d.update(body1=f.body1, body2=f.body2, shape1=_shape_dict(f.shape1),
                     shape2=_shape_dict(f.shape2), stiffness=f.stiffness, exponent=f.exponent,
                     damping=f.damping, damping_depth=f.damping_depth)
            if isinstance(f.shape1, (tuple, list)) and f.shape1 and f.shape1[0] == "gear":
                d["backlash"] = f.backlash
            if f.friction is not None:
                d["friction"] = (dict(zip(("static", "dynamic", "stiction_speed",
                                           "transition_speed"), f.friction))
                                 if isinstance(f.friction, (tuple, list)) and len(f.friction) == 4
                                 else f.friction)
        elif t is not None and t.startswith("coordinate_"):
            d.update(body=f.body1, coordinate=f.coordinate)
            if t != "coordinate_damper":
                d.update(stiffness=f.stiffness, rest=f.rest)
            if t != "coordinate_spring":
                d["damping"] = f.damping
        forces.append(d)
    wear = [wear_table(w) for w in sc.wear]
    out = {"scene": {"name": sc.name, "description": sc.description}, "body": bodies,
           "joint": joints, "force": forces}
    if wear:
        out["wear"] = wear
    return out


def _shape_dict(sh):
    """A contact shape as the file writes it (the reader names what is wrong with an odd one)."""
    if not (isinstance(sh, (tuple, list)) and len(sh) == 3):
        return sh
    typ, point, third = sh
    if typ == "line":
        return {"type": typ, "point": _seq(point), "normal": _seq(third)}
    if typ == "point":
        return {"type": typ, "point": _seq(point)}
    if typ == "gear" and isinstance(third, (tuple, list)) and len(third) == 4:
        return {"type": typ, "teeth": third[0], "module": third[1],
                "pressure_angle_deg": math.degrees(third[2]), "addendum": third[3]}
    return {"type": typ, "centre": _seq(point), "radius": third}


def checked_planar(sc: Scene, reread) -> Scene:
    """A planar scene re-read through the reader's checks: a Scene whose fields were changed in
    Python after it was read (or built by hand) gets the errors a file would, naming the
    element and field, instead of failing somewhere inside the pipeline. A scene unchanged since
    the reader made it (its snapshot, compared in a few microseconds) is returned as it is.
    reread(data, source): the reader of the scene's dict (mbdk.scene_file.scene_from_dict,
    which sends a body of kind "spatial" to the spatial reader)."""
    read_as = getattr(sc, "_read_as", None)
    if read_as is not None:
        try:
            if read_as == _snapshot(sc):
                return sc
        except (TypeError, ValueError):   # an array or an odd object in a field: changed
            pass
    return reread(planar_scene_to_dict(sc), sc.source)


def _snapshot(sc: Scene):
    """Every field of every element: what checked() compares (fields a type does not use
    included, since the tables are built from the objects). The reader stores only immutable
    values (numbers, strings, tuples), so its snapshot cannot change behind its back; a list a
    user puts in a field never equals the tuple it replaced."""
    return (sc.name, sc.description, sc.source,
            *(tuple((type(o), tuple(vars(o).values())) for o in items)
              for items in (sc.bodies, sc.joints, sc.forces, sc.wear)))


def _point_at(sc: Scene, body: str, p) -> tuple:
    """A body point's global position at the scene's initial pose (a ground point as it is)."""
    if body == GROUND:
        return p
    b = sc.bodies[sc.body_index(body) - 1]
    c, s = math.cos(b.angle), math.sin(b.angle)
    return (b.x + c * p[0] - s * p[1], b.y + s * p[0] + c * p[1])


def check_lengths(sc: Scene) -> None:
    """The scene's coordinates, offsets and lengths against its length scale (mbdk.checks.
    length_scale): a distance, a radius or a point offset too small to be resolved next to the
    scene's largest coordinate is refused, naming the element and field."""
    sizes = []

    def put(label, fld, body, p, kind="offset"):
        sizes.append((label, fld, math.hypot(*p),
                      "coordinate" if body == GROUND and kind == "offset" else kind))
    for b in sc.bodies:
        sizes.append((f"body {b.name!r}", "x", math.hypot(b.x, b.y), "coordinate"))
    for j in sc.joints:
        label = f"joint {j.name!r}"
        if j.type in ("driver", "coupling"):
            continue
        if j.type == "rolling":
            put(label, "point", GROUND, j.point2)
            sizes.append((label, "radius", j.radius, "length"))
            continue
        put(label, "point1", j.body1, j.point1)
        if j.type not in ("point_curve", "knife_edge"):
            put(label, "point2", j.body2, j.point2)
        if j.type == "distance":
            if j.length is not None:
                off, _rate, amp, _om, ph = j.length
                sizes.append((label, "length", off + amp * math.sin(ph), "length"))
            else:
                p1 = _point_at(sc, j.body1, j.point1)
                p2 = _point_at(sc, j.body2, j.point2)
                sizes.append((label, "point2 (the points' initial distance, its length)",
                              math.hypot(p1[0] - p2[0], p1[1] - p2[1]), "length",
                              "its points coincide (or nearly) at the initial pose, where a "
                              "distance has no direction: give the bodies a pose where they "
                              "are apart, or use a revolute joint where the points coincide"))
    for f in sc.forces:
        label = f"force {f.name!r}"
        if f.type in ("point_force",):
            put(label, "point", f.body1, f.point1)
        elif f.type in ("spring", "damper", "spring_damper"):
            put(label, "point1", f.body1, f.point1)
            put(label, "point2", f.body2, f.point2)
        elif f.type == "contact":
            for fld, body, sh in (("shape1", f.body1, f.shape1), ("shape2", f.body2, f.shape2)):
                typ, point, third = sh
                if typ == "gear":
                    sizes.append((label, fld + " module", third[1], "length"))
                    continue
                put(label, fld, body, point)
                if typ in ("circle", "ring"):
                    sizes.append((label, fld + " radius", third, "length"))
    length_scale(sizes, sc.source, SceneError)


def check_scene(sc: Scene) -> None:
    """References, duplicates and counts; raises SceneError naming the element and field."""
    src = sc.source
    if not sc.bodies:
        raise SceneError(f"{src}: the scene has no [[body]]")
    seen = {}
    for kind, items in (("body", sc.bodies), ("joint", sc.joints), ("force", sc.forces)):
        for e in items:
            key = (kind, e.name)
            if e.name and key in seen:
                raise SceneError(f"{src}: {kind} {e.name!r}: field 'name' is used twice")
            seen[key] = True
            if kind == "body" and e.name == GROUND:
                raise SceneError(f"{src}: body 'ground': field 'name' is reserved for the ground")
    names = [b.name for b in sc.bodies]
    for kind, items in (("joint", sc.joints), ("force", sc.forces)):
        for e in items:
            for fld in ("body1", "body2"):
                v = getattr(e, fld)
                if kind == "force" and e.type in ("gravity",):
                    continue
                if kind == "joint" and e.type in GROUND_JOINTS and fld == "body2":
                    continue
                if kind == "joint" and e.type == "coupling" and v == GROUND:
                    raise SceneError(f"{src}: joint {e.name!r}: field 'body2' = 'ground' must "
                                     "name a body: a coupling joins two bodies' coordinates "
                                     "(to follow a function of time, use a driver)")
                if kind == "force" and fld == "body2" and e.type not in (
                        "spring", "damper", "spring_damper", "contact"):
                    continue
                shown = fld if not (kind == "force" and e.type in (
                    "point_force", "torque") or e.type.startswith("coordinate")) else "body"
                if v != GROUND and v not in names:
                    raise SceneError(f"{src}: {kind} {e.name!r}: field {shown!r} = {v!r} names no "
                                     f"body; bodies: {', '.join(names)}, ground")
                if v == GROUND and fld == "body1":
                    raise SceneError(f"{src}: {kind} {e.name!r}: field {shown!r} must name a "
                                     "body, not the ground")
            if kind == "joint" and e.type not in GROUND_JOINTS and e.body1 == e.body2:
                raise SceneError(f"{src}: joint {e.name!r}: field 'body2' = {e.body2!r} is body1 "
                                 "itself")
    contacts = {f.name: f for f in sc.forces if f.type == "contact"}
    for f in contacts.values():
        if f.body1 == f.body2:
            raise SceneError(f"{src}: force {f.name!r}: field 'body2' = {f.body2!r} is body1 "
                             "itself")
    check_wear_contacts(sc, {f.name: f.friction is not None for f in contacts.values()}, seen)
    check_lengths(sc)
    rows = sum(JOINT_ROWS[j.type] for j in sc.joints)
    if rows > 3 * len(sc.bodies):
        raise SceneError(f"{src}: {rows} constraint equations for {3 * len(sc.bodies)} coordinates "
                         f"({len(sc.bodies)} bodies): more constraints than coordinates")
