"""The scene reader's field access: one element's table read field by field, every error naming
the file, the element and the field (planar_file.py and spatial_file.py read their elements
with it), and the tables both readers share: a contact's friction and a wear element."""
from __future__ import annotations

import math

from .checks import number_problem, show
from .codes import COORDS, WEAR_LAWS, WEAR_LOADS
from .scene import SceneError, Wear


class FieldReader:
    """Reads one element's table, naming file, element and field in every error."""

    def __init__(self, source: str, kind: str, index: int, table: dict):
        if not isinstance(table, dict):
            raise SceneError(f"{source}: {kind} #{index + 1} = {table!r} is not a table; write it "
                             f"as [[{kind}]] with its fields")
        self.source, self.kind, self.index, self.t = source, kind, index, table
        self.used = set()
        nm = table.get("name")
        self.label = f"{kind} {nm!r}" if isinstance(nm, str) else f"{kind} #{index + 1}"

    def err(self, fld, msg):
        return SceneError(f"{self.source}: {self.label}: field {fld!r} {msg}")

    def has(self, fld):
        return fld in self.t

    def get(self, fld, default=None, required=False):
        self.used.add(fld)
        if fld not in self.t:
            if required:
                raise self.err(fld, "is missing")
            return default
        v = self.t[fld]
        if v is None and (required or default is not None):   # a Scene object's field
            raise self.err(fld, "= None; give a value (or, in a file, leave the field out for "
                                "its default)")
        return v

    def num(self, fld, default=None, required=False, positive=False, nonneg=False):
        v = self.get(fld, default, required)
        if v is None:
            return None
        problem = number_problem(v)
        if problem:
            raise self.err(fld, problem)
        v = float(v)
        if positive and not v > 0:
            raise self.err(fld, f"= {v} must be positive")
        if nonneg and v < 0:
            raise self.err(fld, f"= {v} must not be negative")
        return v

    def angle(self, fld, default=0.0):
        if fld + "_deg" in self.t:
            if fld in self.t:
                raise self.err(fld, f"and {fld}_deg are both given; give one")
            return math.radians(self.num(fld + "_deg"))
        return self.num(fld, default)

    def vec(self, fld, default=None, required=False):
        v = self.get(fld, default, required)
        if v is None:
            return None
        if not isinstance(v, (list, tuple)) or len(v) != 2:
            raise self.err(fld, f"= {show(v)} must be a pair [x, y]")
        return tuple(self.entries(fld, v, "two"))

    def entries(self, fld, v, count: str) -> list:
        """The numbers of a list field, each finite and in range, or an error naming the entry."""
        out = []
        for i, c in enumerate(v):
            problem = number_problem(c)
            if problem:
                raise self.err(fld, f"= {show(v)} must hold {count} finite numbers in range; "
                                    f"entry {i} {problem}")
            out.append(float(c))
        return out

    def name(self, fld, required=True, default=None):
        v = self.get(fld, default, required)
        if v is not None and not isinstance(v, str):
            raise self.err(fld, f"= {v!r} must be a name (a string)")
        if v is not None and not v.strip():
            raise self.err(fld, f"= {v!r} is empty; give a name")
        return v

    def coordinate(self, fld, default):
        v = self.name(fld, required=False, default=default)
        if v not in COORDS:
            raise self.err(fld, f"= {v!r} must be one of x, y, angle")
        return v

    def function(self, fld, default):
        v = self.get(fld, None)
        if v is None:
            return default
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            problem = number_problem(v)
            if problem:
                raise self.err(fld, problem)
            return (float(v), 0.0, 0.0, 0.0, 0.0)
        if not isinstance(v, dict):
            raise self.err(fld, f"= {v!r} must be a number or a table {{offset, rate, amplitude, "
                                "omega, phase}")
        keys = ["offset", "rate", "amplitude", "omega", "phase"]
        bad = [k for k in v if k not in keys]
        if bad:
            raise self.err(fld, f"has unknown entry {bad[0]!r}; known: {', '.join(keys)}")
        out = []
        for k in keys:
            c = v.get(k, 0.0)
            problem = number_problem(c)
            if problem:
                raise self.err(fld, f"entry {k!r} {problem}")
            out.append(float(c))
        return tuple(out)

    def done(self):
        extra = [k for k in self.t if k not in self.used and k.removesuffix("_deg") not in self.used]
        if extra:
            raise self.err(extra[0], "is not a field of this element type")


def section_items(data: dict, key: str, source: str) -> list:
    """A scene file's array of tables [[key]] (empty when absent), or a SceneError."""
    v = data.get(key, [])
    if not isinstance(v, list):
        raise SceneError(f"{source}: '{key}' must be an array of tables ([[{key}]])")
    return v


def read_friction(r: FieldReader) -> tuple:
    """A contact's friction table (static, dynamic, stiction_speed, transition_speed), as the
    planar and the spatial readers take it."""
    v = r.get("friction")
    if not isinstance(v, dict):
        raise r.err("friction", f"= {v!r} must be a table {{static, dynamic, stiction_speed, "
                                "transition_speed}")
    fr = FieldReader(r.source, f"{r.label} friction", 0, v)
    st = fr.num("static", required=True, nonneg=True)
    dy = fr.num("dynamic", st, nonneg=True)
    vs = fr.num("stiction_speed", 1e-3, positive=True)
    vd = fr.num("transition_speed", 2 * vs, positive=True)
    if not vd > vs:
        raise r.err("friction", f"transition_speed = {vd} must exceed stiction_speed = {vs}")
    extra = [k for k in v if k not in fr.used]
    if extra:
        raise r.err("friction", f"entry {extra[0]!r} is not known; known: static, dynamic, "
                                "stiction_speed, transition_speed")
    return (st, dy, vs, vd)


def read_wear(r: FieldReader) -> Wear:
    """A [[wear]] entry (planar_file.py's docstring shows it), as both readers take it; the
    contact it names is checked against the scene's (check_wear_contacts)."""
    name = r.name("name", required=False, default=f"wear{r.index + 1}")
    law = r.name("law")
    if law not in WEAR_LAWS:
        raise r.err("law", f"= {law!r} is not a wear law; known: {', '.join(WEAR_LAWS)}")
    load = r.name("load")
    contact, _, qty = load.rpartition(".")
    if not contact or qty not in WEAR_LOADS:
        raise r.err("load", f"= {load!r} must be CONTACT.normal_force or CONTACT.friction_force")
    w = Wear(name, law, load, r.num("coefficient", required=True, nonneg=True),
             initial=r.num("initial", 0.0, nonneg=True))
    if law == "gear":
        w.radius = r.num("radius", required=True, nonneg=True)
        w.temperature = r.num("temperature", required=True, positive=True)
        w.a_x = r.num("a_x", w.a_x, positive=True)
        w.t0 = r.num("t0", w.t0, positive=True)
        w.activation_energy = r.num("activation_energy", w.activation_energy, nonneg=True)
        w.gas_constant = r.num("gas_constant", w.gas_constant, positive=True)
    elif law == "knee":
        c = r.get("slide_roll", required=True)
        if not isinstance(c, list) or len(c) != 4:
            raise r.err("slide_roll", f"= {show(c)} must be four finite numbers [c0, c1, c2, c3]")
        w.slide_roll = tuple(r.entries("slide_roll", c, "four"))
    r.done()
    return w


def wear_table(w: Wear) -> dict:
    """A wear element as the file writes it (read_wear's inverse): its values as they are, so
    that read_wear checks one changed in Python with the file's errors."""
    d = {"name": w.name, "law": w.law, "load": w.load, "coefficient": w.coefficient,
         "initial": w.initial}
    if w.law == "gear":
        d.update(radius=w.radius, temperature=w.temperature, a_x=w.a_x, t0=w.t0,
                 activation_energy=w.activation_energy, gas_constant=w.gas_constant)
    elif w.law == "knee":
        # a copy, so that a snapshot does not change with the scene's own list
        d["slide_roll"] = list(w.slide_roll) if isinstance(w.slide_roll, (tuple, list)) \
            else w.slide_roll
    return d


def check_wear_contacts(sc, contacts: dict, seen: dict) -> None:
    """Each wear element of sc: a name of its own (seen: the (kind, name) pairs so far) and a
    load on a contact of the scene (contacts: name -> whether it has friction), the friction
    force only where there is friction."""
    src = sc.source
    for w in sc.wear:
        if ("wear", w.name) in seen:
            raise SceneError(f"{src}: wear {w.name!r}: field 'name' is used twice")
        seen[("wear", w.name)] = True
        if w.contact not in contacts:
            raise SceneError(f"{src}: wear {w.name!r}: field 'load' = {w.load!r} names no contact"
                             f"; contacts: {', '.join(contacts) or 'none'}")
        if w.quantity == "friction_force" and not contacts[w.contact]:
            raise SceneError(f"{src}: wear {w.name!r}: field 'load' = {w.load!r}: contact "
                             f"{w.contact!r} has no friction; give it a friction table, or use "
                             f"'{w.contact}.normal_force'")
