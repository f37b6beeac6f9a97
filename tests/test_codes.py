"""Every code Python passes to the kernel (python/mbdk/codes.py, and the method ids and status
codes Python reads from it) against the kernel.

First by name: the kernel's named integer constants, read from their Fortran parameter
definitions in kernel/src (the f2py module exports tables only for the element kinds, body
kinds, methods and statuses, and those registries are compared too), table by table: each
Python code is its constant's value, and each constant of the kernel's set (every constant of
its prefix, or the codes 1..its count constant) has its Python name, so that a code the kernel
adds or renumbers fails here.

The element registry holds the kinds of planar and spatial scenes in one table: every name has
one code in both, Python's tables of both models are read from it, and the spatial model takes
exactly its spatial kinds (every other code refused with MBDK_ERR_INVALID_INPUT).

Then by what the kernel does with the codes the f2py entries take as bare numbers (ida's forms,
spatial_run's dae_form and options, rotation_matrix's kind) or that a constant alone cannot
check: a scene of each spatial joint type evaluated (the motions the joint leaves free, the rows
it adds), each spatial force and contact (the accelerations and energies it gives), each
orientation set
(the kernel's rotation of the coordinates Python wrote), each quaternion-norm treatment, each
formulation and each form of the DAE (their signatures in a run), the outputs' bits, the linear
solves, and the positions of spatial_run's options in the f2py entry's source."""
import ast
import re
from pathlib import Path

import numpy as np
import pytest

import mbdk
from mbdk import _kernel, codes, rotations
from mbdk.errors import Status, decode_text
from mbdk.scene_file import scene_from_dict
from mbdk.spatial_model import evaluate_spatial, spatial_tables

# ---- the kernel's named constants -----------------------------------------------------------

_DECLARATION = re.compile(r"^\s*integer\s*(?:\([^)]*\))?\s*,[^:]*\bparameter\b[^:]*::(.*)$",
                          re.I)


def _code(line: str) -> str:
    """A Fortran line without its comment (a ! outside a character literal)."""
    quote = None
    for i, ch in enumerate(line):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "'\"":
            quote = ch
        elif ch == "!":
            return line[:i]
    return line


def _statements(text: str):
    """The free-form statements of a Fortran file, continuation lines joined."""
    joined = ""
    for line in text.splitlines():
        code = _code(line).strip()
        if joined and code.startswith("&"):
            code = code[1:]
        if code.endswith("&"):
            joined += code[:-1] + " "
            continue
        yield joined + code
        joined = ""


def _entities(text: str) -> list[str]:
    """A declaration's entities, split at the commas outside brackets."""
    out, depth, cur = [], 0, ""
    for ch in text:
        depth += (ch in "([") - (ch in ")]")
        if ch == "," and depth == 0:
            out.append(cur)
            cur = ""
        else:
            cur += ch
    return out + [cur]


def _value(expr: str, known: dict):
    """An integer constant expression (literals with a kind, names of constants, + - *, an
    array constructor); KeyError where it names a constant not known yet."""
    def ev(n):
        if isinstance(n, ast.Constant) and type(n.value) is int:
            return n.value
        if isinstance(n, ast.Name):
            return known[n.id.upper()]
        if isinstance(n, ast.UnaryOp) and isinstance(n.op, ast.USub):
            return -ev(n.operand)
        if isinstance(n, ast.BinOp) and type(n.op) in (ast.Add, ast.Sub, ast.Mult):
            a, b = ev(n.left), ev(n.right)
            return {ast.Add: a + b, ast.Sub: a - b, ast.Mult: a * b}[type(n.op)]
        if isinstance(n, ast.List):
            return [ev(e) for e in n.elts]
        raise KeyError(ast.dump(n))
    return ev(ast.parse(re.sub(r"(\d)_[A-Za-z]\w*", r"\1", expr.strip()), mode="eval").body)


def fortran_constants(src: Path) -> dict:
    """Every integer named constant of the Fortran files under src (upper case) -> its value,
    an int or a list; a name declared twice, or whose value is not a constant expression of
    the kinds above, is left out."""
    exprs = {}
    for path in sorted(src.rglob("*.f90")):
        for statement in _statements(path.read_text()):
            m = _DECLARATION.match(statement)
            for entity in _entities(m.group(1)) if m else []:
                name, eq, expr = entity.partition("=")
                if eq:
                    exprs.setdefault(re.sub(r"\(.*", "", name).strip().upper(), []).append(expr)
    known, pending = {}, {k: v[0] for k, v in exprs.items() if len(v) == 1}
    while True:
        done = {}
        for name, expr in pending.items():
            try:
                done[name] = _value(expr, known)
            except (KeyError, SyntaxError):
                pass
        if not done:
            return known
        known.update(done)
        pending = {k: v for k, v in pending.items() if k not in done}


@pytest.fixture(scope="module")
def kernel(root):
    return fortran_constants(root / "kernel" / "src")


def _named(prefix: str, names) -> dict:
    return {n: prefix + n.upper() for n in names}


#: the force table's kinds of planar and of spatial scenes -> the kernel constant of each
PLANAR_FORCES = {**_named("MBDK_FORCE_", ["gravity", "torque", "spring_damper", "spring",
                                           "damper", "contact", "friction"]),
                 "point_force": "MBDK_FORCE_POINT",
                 "coordinate_spring_damper": "MBDK_FORCE_COORDINATE",
                 "coordinate_spring": "MBDK_FORCE_COORDINATE",
                 "coordinate_damper": "MBDK_FORCE_COORDINATE"}
SPATIAL_FORCES = {**_named("MBDK_FORCE_", ["gravity", "torque", "spring_damper", "sphere_plane",
                                            "sphere_sphere"]), "point_force": "MBDK_FORCE_POINT"}

#: Python's table -> (its codes by the kernel constant each mirrors, the kernel's set of codes:
#: a prefix every constant of which the table must name (but those listed after it), or the
#: constant that counts the codes 1..N). A table read from the kernel's registries is here too;
#: the planar and the spatial joints, and the force table's kinds of both (forces and effects),
#: are each the kernel's codes 1..N together.
TABLES = {
    "JOINT_CODES": (_named("MBDK_JOINT_", codes.JOINT_CODES), None),
    "SPATIAL_JOINT_CODES": (_named("MBDK_JOINT_", codes.SPATIAL_JOINT_CODES), None),
    "ALL_JOINT_CODES": (_named("MBDK_JOINT_", [*codes.JOINT_CODES, *codes.SPATIAL_JOINT_CODES]),
                        "MBDK_JOINT_TYPES"),
    "FORCE_CODES": (PLANAR_FORCES, None),
    "SPATIAL_FORCE_CODES": (SPATIAL_FORCES, None),
    "EFFECT_CODES": ({"wear": "MBDK_EFFECT_WEAR"}, ("MBDK_EFFECT_", "MBDK_EFFECT_TYPES")),
    "SPATIAL_EFFECT_CODES": ({"wear": "MBDK_EFFECT_WEAR"}, ("MBDK_EFFECT_", "MBDK_EFFECT_TYPES")),
    "FORCE_TABLE_CODES": ({**PLANAR_FORCES, **SPATIAL_FORCES, "wear": "MBDK_EFFECT_WEAR"},
                          "MBDK_FORCE_TYPES"),
    "BODY_CODES": (_named("MBDK_BODY_", ["planar", "spatial"]), "MBDK_BODY_KINDS"),
    "STRUCT_IDS": ({"mbdk_stats": "MBDK_STRUCT_STATS", "mbdk_options": "MBDK_STRUCT_OPTIONS",
                    "mbdk_index3_options": "MBDK_STRUCT_INDEX3_OPTIONS",
                    "mbdk_model_options": "MBDK_STRUCT_MODEL_OPTIONS",
                    "mbdk_spatial_options": "MBDK_STRUCT_SPATIAL_OPTIONS",
                    "mbdk_watch_report": "MBDK_STRUCT_WATCH_REPORT"}, "MBDK_STRUCT_COUNT"),
    "FIELD_TYPE_CODES": (_named("MBDK_FIELD_", ["int", "int64", "double", "pointer"]),
                         ("MBDK_FIELD_",)),
    "METHOD_FAMILY_CODES": (_named("MBDK_FAMILY_", codes.METHOD_FAMILIES.values()),
                            ("MBDK_FAMILY_",)),
    "FORMULATIONS": (_named("MBDK_FORM_", ["reduced", "baumgarte", "penalty", "projection"]),
                     ("MBDK_FORM_",)),
    "SOLVERS": ({**_named("MBDK_SOLVER_", ["auto", "schur", "kkt", "sparse"]),
                 "revolute_schur": "MBDK_SOLVER_REVOLUTE"}, ("MBDK_SOLVER_",)),
    "OUTPUTS": ({"a": "MBDK_OUT_ACCELERATIONS", **_named("MBDK_OUT_", ["multipliers",
                 "reactions", "energy", "residuals"])}, ("MBDK_OUT_", "MBDK_OUT_ALL")),
    "CONTACT_GEOMETRY": ({"line": "MBDK_CONTACT_LINE", "circle": "MBDK_CONTACT_CIRCLES",
                          "ring": "MBDK_CONTACT_INSIDE", "gear": "MBDK_CONTACT_GEAR"},
                         ("MBDK_CONTACT_", "MBDK_CONTACT_PAIRS")),
    "WEAR_LAWS": (_named("MBDK_WEAR_", ["archard", "gear", "knee"]), "MBDK_WEAR_LAWS"),
    "WEAR_LOADS": ({"normal_force": "MBDK_WEAR_LOAD_NORMAL",
                    "friction_force": "MBDK_WEAR_LOAD_FRICTION"}, ("MBDK_WEAR_LOAD_",)),
    "INDEX3_FORMULATIONS": ({"index3": "MBDK_INDEX3_BOOK",
                             "augmented_lagrangian": "MBDK_INDEX3_AUGMENTED"}, None),
    "ADAPTIVE_MODES": ({True: "MBDK_INDEX3_EXTRAPOLATED", "extrapolated":
                        "MBDK_INDEX3_EXTRAPOLATED", "estimated": "MBDK_INDEX3_ESTIMATED"}, None),
    "INDEX3_SCALINGS": ({"unscaled": "MBDK_INDEX3_UNSCALED", "book": "MBDK_INDEX3_SCALED_BOOK",
                         "scaled": "MBDK_INDEX3_SCALED"}, None),
    "STARTUP": (_named("MBDK_STARTUP_", ["rk4", "bdf"]), ("MBDK_STARTUP_",)),
    "BDF_DAE_FORMS": (_named("MBDK_DAE_", ["none", "i3", "si2"]), ("MBDK_DAE_",)),
    "ROTATIONS": (_named("MBDK_ROT_", ["quaternion", "euler313", "cardan123"]), ("MBDK_ROT_",)),
    "NORMS": (_named("MBDK_NORM_", ["project", "stabilise", "none"]), ("MBDK_NORM_",)),
    "SPATIAL_FORMULATIONS": (_named("MBDK_FORM_", ["reduced", "baumgarte", "penalty",
                                                   "projection"]), ("MBDK_FORM_",)),
}

#: Python's single codes and sizes -> the kernel constant each mirrors
SCALARS = {"FROM_POSE": "MBDK_FROM_POSE", "SPARSE_MIN_ROWS": "MBDK_SPARSE_MIN_ROWS",
           "SPATIAL_JOINT_REALS": "MBDK_SPATIAL_JOINT_REALS",
           "SPATIAL_FORCE_REALS": "MBDK_SPATIAL_FORCE_REALS",
           "FIXED_ORDER_MAX": "MBDK_FIXED_ORDER_MAX"}


def _python_table(name: str) -> dict:
    """The table TABLES names, as name -> code (inverted where Python keys it by code)."""
    if name == "BODY_CODES":
        return {k: v[0] for k, v in codes.BODY_KINDS.items()}
    if name == "FIELD_TYPE_CODES":
        kinds = {np.intc: "int", np.int64: "int64", np.float64: "double", np.uintp: "pointer"}
        return {kinds[t]: k for k, t in codes.FIELD_TYPES.items()}
    if name == "METHOD_FAMILY_CODES":
        return {v: k for k, v in codes.METHOD_FAMILIES.items()}
    if name == "BDF_DAE_FORMS":
        return {**codes.DAE_FORMS["bdf"], "none": codes.DAE_NONE}
    if name == "ALL_JOINT_CODES":       # a name of both kinds with two codes: the last wins,
        return {**codes.JOINT_CODES, **codes.SPATIAL_JOINT_CODES}    # and its constant differs
    if name == "FORCE_TABLE_CODES":
        return {**codes.FORCE_CODES, **codes.SPATIAL_FORCE_CODES, **codes.EFFECT_CODES}
    table = dict(getattr(codes, name))
    if name == "ADAPTIVE_MODES":     # False: no step-size control, the kernel's opt%adaptive 0
        assert table.pop(False) == 0
    return table


def mismatches(table: dict, names: dict, whole, kernel: dict) -> list[str]:
    """How a Python table (name -> code) differs from the kernel's constants it mirrors (names:
    name -> constant; whole: TABLES' second entry); empty where they agree."""
    out = [f"{k!r}: no kernel constant named" for k in set(table) - set(names)]
    out += [f"{k!r}: missing (the kernel has {c})" for k, c in names.items() if k not in table]
    for k in set(table) & set(names):
        if names[k] not in kernel:
            out.append(f"{k!r}: the kernel has no constant {names[k]}")
        elif table[k] != kernel[names[k]]:
            out.append(f"{k!r} = {table[k]}, the kernel's {names[k]} = {kernel[names[k]]}")
    if isinstance(whole, str):
        if sorted(set(table.values())) != list(range(1, kernel[whole] + 1)):
            out.append(f"codes {sorted(set(table.values()))}, the kernel's are 1..{whole} = "
                       f"{kernel[whole]}")
    elif whole:
        prefix, *others = whole
        out += [f"the kernel's {c} = {v} has no Python name" for c, v in kernel.items()
                if c.startswith(prefix) and c not in others and c not in names.values()]
    return out


def test_the_kernels_constants_are_read():
    """The reader finds the constants it is meant to, values resolved through other names."""
    k = fortran_constants(Path(__file__).resolve().parents[1] / "kernel" / "src")
    family = {name: code for code, name in codes.METHOD_FAMILIES.items()}
    by_id = sorted(mbdk.methods().values(), key=lambda m: m.id)
    assert k["FAMILIES"] == [family[m.family] for m in by_id]     # an array, continued
    assert k["MBDK_ERR_INTERRUPTED"] == -60 and k["MBDK_SUCCESS"] == 0
    assert k["MBDK_ELEMENT_KINDS"] == k["MBDK_JOINT_TYPES"] + k["MBDK_FORCE_TYPES"]
    assert k["MBDK_SPARSE_MIN_ROWS"] == k["MBDK_SMALL_DENSE_MAX"]      # a constant's name


@pytest.mark.parametrize("name", list(TABLES))
def test_a_code_table_is_the_kernels(name, kernel):
    names, whole = TABLES[name]
    assert not mismatches(_python_table(name), names, whole, kernel)


def test_a_wrong_table_is_found_wrong(kernel):
    """The comparison fails on a code renumbered, a name the kernel lacks, a name Python lacks
    and a kernel code without a Python name."""
    names, whole = TABLES["FORMULATIONS"]
    table = _python_table("FORMULATIONS")
    assert not mismatches(table, names, whole, kernel)
    assert mismatches({**table, "penalty": 5}, names, whole, kernel)
    assert mismatches({**table, "index9": 9}, names, whole, kernel)
    assert mismatches({k: v for k, v in table.items() if k != "penalty"}, names, whole, kernel)
    assert mismatches(table, names, whole, {**kernel, "MBDK_FORM_NEW": 5})
    names, whole = TABLES["ALL_JOINT_CODES"]
    table = _python_table("ALL_JOINT_CODES")
    assert not mismatches(table, names, whole, kernel)
    assert mismatches(table, names, whole, {**kernel, "MBDK_JOINT_TYPES": 16})
    # the spatial model's own numbering of before (spherical 1, revolute 2, ...)
    assert mismatches({**table, "spherical": 1, "revolute": 2}, names, whole, kernel)


@pytest.mark.parametrize("name", list(SCALARS))
def test_a_single_code_is_the_kernels(name, kernel):
    assert getattr(codes, name) == kernel[SCALARS[name]]


def test_a_joint_has_rows_on_exactly_the_body_kinds_it_applies_to():
    """Each registry row applies to body kinds the kernel has; a joint adds constraint rows on
    each of them (a revolute joint 2 in a planar scene, 5 in a spatial one), a force or an
    effect none; Python's row tables are the registry's, kind by kind."""
    for e in codes.ELEMENT_KINDS:
        assert e.rows and set(e.rows) <= set(codes.BODY_KINDS), e
        assert all((rows > 0) == (e.cls == codes.JOINT_CLASS) for rows in e.rows.values()), e
    assert codes.JOINT_ROWS == {e.name: e.rows["planar"] for e in codes.ELEMENT_KINDS
                                if e.cls == codes.JOINT_CLASS and "planar" in e.rows}
    assert codes.SPATIAL_JOINT_ROWS == {e.name: e.rows["spatial"] for e in codes.ELEMENT_KINDS
                                        if e.cls == codes.JOINT_CLASS and "spatial" in e.rows}
    assert (codes.JOINT_ROWS["revolute"], codes.SPATIAL_JOINT_ROWS["revolute"]) == (2, 5)


def test_every_element_name_has_one_code_in_both_kinds_of_scene():
    """One registry for planar and spatial scenes: every name once, every code once in its table
    (the joints', or the force table's forces and effects), and every table of codes Python
    passes to either model gives a name the one code the registry gives it. The kinds both
    models have are one row each (revolute, prismatic and fixed joints; gravity, point forces,
    torques, spring-dampers; wear); the spatial model's others continue the codes after the planar
    ones'."""
    names = [e.name for e in codes.ELEMENT_KINDS]
    assert len(set(names)) == len(names)
    table = {codes.JOINT_CLASS: "joints", codes.FORCE_CLASS: "forces",
             codes.EFFECT_CLASS: "forces"}
    keys = [(table[e.cls], e.code) for e in codes.ELEMENT_KINDS]
    assert len(set(keys)) == len(keys)
    registry = {e.name: e.code for e in codes.ELEMENT_KINDS}
    python = {}
    for tab in (codes.JOINT_CODES, codes.SPATIAL_JOINT_CODES, codes.FORCE_CODES,
                codes.SPATIAL_FORCE_CODES, codes.EFFECT_CODES, codes.SPATIAL_EFFECT_CODES):
        for name, code in tab.items():
            python.setdefault(name, set()).add(code)
    assert {n: c for n, c in python.items() if len(c) > 1} == {}
    assert {n: c for n, c in python.items() if n in registry and c != {registry[n]}} == {}
    # the planar scene format's aliases of coordinate_spring_damper are the only other names
    assert set(python) - set(registry) == {"coordinate_spring", "coordinate_damper"}
    both = {e.name for e in codes.ELEMENT_KINDS if set(e.rows) == {"planar", "spatial"}}
    assert both == {"revolute", "prismatic", "fixed", "gravity", "point_force", "torque",
                    "spring_damper", "wear"}
    for t in ("joints", "forces"):
        kinds = [e for e in codes.ELEMENT_KINDS if table[e.cls] == t]
        planar = max(e.code for e in kinds if "planar" in e.rows)
        assert all(e.code > planar for e in kinds if "planar" not in e.rows), t


def test_the_coordinates_and_the_output_bits_fit_the_kernels(kernel):
    """A planar body's coordinates are 1..MBDK_PLANAR_COORDS (no constant names each); the
    output bits are distinct powers of two that sum to MBDK_OUT_ALL."""
    assert sorted(codes.COORDS.values()) == list(range(1, kernel["MBDK_PLANAR_COORDS"] + 1))
    assert codes.BODY_KINDS["planar"][1] == kernel["MBDK_PLANAR_COORDS"]
    bits = list(codes.OUTPUTS.values())
    assert all(b & (b - 1) == 0 for b in bits) and sum(bits) == kernel["MBDK_OUT_ALL"]


def test_the_method_ids_are_the_kernels(kernel):
    """mbdk.methods' ids (read from the kernel's registry) against the method constants, and
    one method per id up to MBDK_METHOD_COUNT."""
    special = {"bdf": "MBDK_BDF_VARIABLE"}
    found = mbdk.methods()
    for name, info in found.items():
        if re.fullmatch(r"bdf[1-6]", name):
            assert info.id == kernel["MBDK_BDF1"] + int(name[3:]) - 1, name
        else:
            assert info.id == kernel[special.get(name, "MBDK_" + name.upper())], name
        assert info.family == codes.METHOD_FAMILIES[int(_kernel.method_info(info.id)[1])]
    assert sorted(m.id for m in found.values()) == list(range(1, kernel["MBDK_METHOD_COUNT"] + 1))
    assert found["bdf6"].id == kernel["MBDK_BDF6"]


def test_the_status_codes_are_the_kernels(kernel):
    """mbdk.Status against the status constants of kernel/src/core/mbdk_status.f90 (the f2py
    table and mbdk.h: tests/test_status.py)."""
    assert {s.name: s.value for s in Status} == {
        c.removeprefix("MBDK_"): v for c, v in kernel.items()
        if re.fullmatch(r"MBDK_(SUCCESS|NOTE_\w+|ERR_\w+)", c)}
    assert len(Status) == kernel["MBDK_STATUS_COUNT"]


def test_the_element_registry_is_the_kernels_constants(kernel):
    """The f2py registry codes.py reads (element kinds, body kinds) against the constants
    behind it: every kind once, by class, with its rows."""
    classes = {1: "JOINT", 2: "FORCE", 3: "EFFECT"}
    assert (codes.JOINT_CLASS, codes.FORCE_CLASS, codes.EFFECT_CLASS) == tuple(
        kernel[f"MBDK_CLASS_{c}"] for c in classes.values())
    assert len(codes.ELEMENT_KINDS) == kernel["MBDK_ELEMENT_KINDS"]
    count = {cls: sum(e.cls == cls for e in codes.ELEMENT_KINDS) for cls in classes}
    assert count[codes.JOINT_CLASS] == kernel["MBDK_JOINT_TYPES"]
    assert count[codes.FORCE_CLASS] + count[codes.EFFECT_CLASS] == kernel["MBDK_FORCE_TYPES"]
    assert count[codes.EFFECT_CLASS] == kernel["MBDK_EFFECT_TYPES"]
    # a kind's position is its visit counter: the joints by code, then the force table's codes
    for k, e in enumerate(codes.ELEMENT_KINDS, 1):
        assert k == e.code + (0 if e.cls == codes.JOINT_CLASS else kernel["MBDK_JOINT_TYPES"]), e
    # the body kinds' bits (MBDK_ON_*): bit k - 1 for body kind k
    for n in ("planar", "spatial"):
        assert kernel[f"MBDK_ON_{n.upper()}"] == 1 << (kernel[f"MBDK_BODY_{n.upper()}"] - 1)
    assert kernel["MBDK_ON_BOTH"] == kernel["MBDK_ON_PLANAR"] | kernel["MBDK_ON_SPATIAL"]
    i, kinds = 1, {}
    while (entry := _kernel.body_kind(i))[0] != 0:
        kinds[decode_text(entry[1])] = int(entry[0])
        i += 1
    assert kinds == {n: kernel[f"MBDK_BODY_{n.upper()}"] for n in kinds}


def test_the_rotation_kinds_are_the_f2py_entrys(root):
    """rotation_matrix takes its parametrisation as a bare number: each Python code's case
    calls that parametrisation's routine (the matrices themselves: tests/test_rotations.py)."""
    src = (root / "kernel" / "src" / "api" / "mbdk_f2py.f90").read_text()
    body = src[src.index("subroutine rotation_matrix("):src.index("end subroutine rotation_matrix")]
    cases = {int(k): call for k, call in re.findall(r"case \((\d+)\)\s+call (\w+)", body)}
    assert cases == {codes.ROTATION_PARAMETRISATIONS[n]: r for n, r in
                     (("angles", "mbdk_angles_matrix"), ("quaternion", "mbdk_quat_matrix"),
                      ("axis_angle", "mbdk_rodrigues"))}
    for entry in ("angle_rates", "quaternion_ops", "quaternion_omega"):
        body = src[src.index(f"subroutine {entry}("):src.index(f"end subroutine {entry}")]
        assert "body /= 0" in body and "(body = 1: body frame" in body, entry
    assert codes.FRAMES == {"space": 0, "body": 1}


# ---- what the kernel does with the codes ----------------------------------------------------

A = np.array([1.0, 2.0, 2.0]) / 3.0             # the joints' axis (space)
B = np.array([2.0, -1.0, 0.0]) / np.sqrt(5.0)   # normal to it
C = np.cross(A, B)
P = np.array([0.1, 0.0, 0.3])                   # the joints' point (space)
PLANE_N = np.array([0.0, 0.6, 0.8])             # a contact's ground plane (through 0), normal
BALL = np.array([0.3, 0.4, 0.1])                # a contact's ground sphere, its centre
ANGLES = [0.3, 0.4, 0.5]                        # the body's 3-1-3 angles


def _body(**kw):
    return {"name": "b", "kind": "spatial", "mass": 2.0, "shape": {"type": "box",
            "size": [0.4, 0.3, 0.2]}, "position": [0.3, -0.2, 0.5], "euler313": ANGLES, **kw}


def _joint(typ):
    j = {"type": typ, "name": "j", "body1": "b"}
    if typ == "universal":
        j.update(at=list(P), axis1=list(A), axis2=list(B))
    elif typ == "angle_driver":
        j.update(axis=list(A), function={"rate": 0.5})
    else:
        j["at"] = list(P)
        if typ in ("revolute", "cylindrical", "prismatic", "slide_driver"):
            j["axis"] = list(A)
        if typ == "slide_driver":
            j["function"] = {"rate": 0.5}
    return j


def _rot(sc, u):
    """(v, Omega_body) of the body turning about the axis u through P."""
    b = sc.bodies[0]
    return np.concatenate([np.cross(u, b.position - P), b.rotation.T @ u])


def _trans(u):
    return np.concatenate([u, np.zeros(3)])


#: per joint type: the motions it leaves free and those it does not (the kernel's C w)
MOTIONS = {
    "spherical": (["rot A", "rot B", "rot C"], ["trans A", "trans B"]),
    "revolute": (["rot A"], ["rot B", "trans A", "trans B"]),
    "universal": (["rot A", "rot B"], ["rot C", "trans A"]),
    "cylindrical": (["rot A", "trans A"], ["rot B", "trans B"]),
    "prismatic": (["trans A"], ["rot A", "rot B", "trans B"]),
    "fixed": ([], ["rot A", "rot B", "trans A", "trans B"]),
    "angle_driver": (["trans A", "trans B"], ["rot A"]),
    "slide_driver": (["rot A", "trans B"], ["trans A"]),
}


def test_every_spatial_joint_type_has_a_row_of_motions():
    assert set(MOTIONS) == set(codes.SPATIAL_JOINT_CODES) == set(codes.SPATIAL_JOINT_ROWS)


def _spatial_status(sc, jtype=None, ftype=None) -> int:
    """The status of the spatial model built from a scene's tables (spatial_residuals at its
    initial state), with the first joint's or force's code replaced."""
    nb, mass, inertia, nj, jt, jbody, jreal, nf, ft, fbody, freal = spatial_tables(sc)
    if jtype is not None:
        jt[0] = jtype
    if ftype is not None:
        ft[0] = ftype
    y0 = sc.state0()
    *_, status = _kernel.spatial_residuals(mass, inertia, nj, jt, jbody, jreal, nf, ft, fbody,
                                           freal, codes.ROTATIONS[sc.rotation], y0, 0.0,
                                           y0, 6)
    return int(status)


def test_the_spatial_model_takes_exactly_the_registrys_spatial_joints():
    """Every joint code of the registry and one past each end, in a joint's table whose reals
    every spatial joint kind can take (a point, two axes): the spatial model builds the kinds
    that apply to spatial bodies and refuses every other code, the planar joints' included, as
    invalid input."""
    sc = scene_from_dict({"body": [_body()], "joint": [_joint("revolute")]}, "probe.toml")
    spatial = set(codes.SPATIAL_JOINT_CODES.values())
    n = max(e.code for e in codes.ELEMENT_KINDS if e.cls == codes.JOINT_CLASS)
    got = {c: _spatial_status(sc, jtype=c) for c in range(-1, n + 2)}
    assert got == {c: Status.SUCCESS if c in spatial else Status.ERR_INVALID_INPUT
                   for c in range(-1, n + 2)}
    assert spatial and set(codes.JOINT_CODES.values()) - spatial   # both sides were probed


def test_the_spatial_model_takes_exactly_the_registrys_spatial_forces():
    """The same for the force table: a contact's reals (which every spatial force kind can take),
    every code of the force table (forces and effects) and one past each end."""
    contact = {"type": "contact", "name": "f", "body1": "b", "stiffness": 1e3,
               "shape1": {"type": "sphere", "radius": 0.6},
               "shape2": {"type": "plane", "normal": [0.0, 0.0, 1.0]}}
    sc = scene_from_dict({"body": [_body()], "force": [contact]}, "probe.toml")
    spatial = set(codes.SPATIAL_FORCE_CODES.values())
    n = max(e.code for e in codes.ELEMENT_KINDS if e.cls != codes.JOINT_CLASS)
    got = {c: _spatial_status(sc, ftype=c) for c in range(-1, n + 2)}
    assert got == {c: Status.SUCCESS if c in spatial else Status.ERR_INVALID_INPUT
                   for c in range(-1, n + 2)}
    assert spatial and set(codes.FORCE_CODES.values()) - spatial


@pytest.mark.parametrize("typ", list(MOTIONS))
def test_a_spatial_joint_code_is_the_joint_the_kernel_builds(typ):
    """Python's code and row count of a joint type, against the kernel's evaluation of a scene
    with that joint: the rank of its rows and the motions its C lets through."""
    sc = scene_from_dict({"body": [_body()], "joint": [_joint(typ)]}, f"{typ}.toml")
    e = evaluate_spatial(sc)
    assert e["status"] == mbdk.Status.SUCCESS
    assert e["rank"] == sc.rows == codes.SPATIAL_JOINT_ROWS[typ]
    c = np.asarray(e["C"])
    assert c.shape == (sc.rows, 6)
    motion = {"rot A": _rot(sc, A), "rot B": _rot(sc, B), "rot C": _rot(sc, C),
              "trans A": _trans(A), "trans B": _trans(B)}
    free, held = MOTIONS[typ]
    for name in free:
        assert np.abs(c @ motion[name]).max() < 1e-12, (typ, name)
    for name in held:
        assert np.abs(c @ motion[name]).max() > 1e-3, (typ, name)


#: the spatial force types of a scene file whose forces the test below computes by hand
SPATIAL_FORCE_CASES = ["gravity", "point_force", "torque", "spring", "damper", "spring_damper",
                       "sphere_plane", "sphere_sphere"]


def test_every_spatial_force_kind_is_computed_by_hand():
    """The cases below cover every force kind of the registry's spatial ones (a file's spring
    and damper are spring_dampers)."""
    assert set(SPATIAL_FORCE_CASES) - {"spring", "damper"} == set(codes.SPATIAL_FORCE_CODES)


@pytest.mark.parametrize("typ", SPATIAL_FORCE_CASES)
def test_a_spatial_force_code_is_the_force_the_kernel_applies(typ):
    """The accelerations and potential energies of one free body under each force type (at
    rest: no gyroscopic term, a damper's force zero), against Newton-Euler by hand. A contact
    (sphere on a tilted ground plane, or on a ground sphere off to the side) pushes the body
    along its normal n with k delta^e through the sphere's centre (no moment, the body at rest:
    no damping, no friction), its potential k delta^(e+1)/(e+1) (mbdk_contact3d)."""
    g, f, s, tau = (np.array([0.1, -0.2, -9.81]), np.array([1.0, 2.0, 3.0]),
                    np.array([0.1, 0.2, 0.0]), np.array([0.1, 0.2, 0.3]))
    at2, k, rest = np.array([0.0, 0.0, 1.5]), 10.0, 0.5
    force = {"type": typ, "name": "f"}
    if typ == "gravity":
        force["g"] = list(g)
    elif typ == "point_force":
        force.update(body="b", point=list(s), force=list(f))
    elif typ == "torque":
        force.update(body="b", torque=list(tau))
    elif typ == "sphere_plane":
        force.update(type="contact", body1="b", stiffness=k, exponent=1.5,
                     shape1={"type": "sphere", "radius": 0.6},
                     shape2={"type": "plane", "normal": list(PLANE_N)})
    elif typ == "sphere_sphere":
        force.update(type="contact", body1="b", stiffness=k, exponent=1.5,
                     shape1={"type": "sphere", "radius": 0.3},
                     shape2={"type": "sphere", "centre": list(BALL), "radius": 0.5})
    else:
        force.update(body1="b", at2=list(at2), rest_length=rest)
        if typ != "damper":
            force["stiffness"] = k
        if typ != "spring":
            force["damping"] = 3.0
    sc = scene_from_dict({"body": [_body()], "force": [force]}, f"{typ}.toml")
    b = sc.bodies[0]
    m, rot, jb = b.mass, b.rotation, b.inertia
    e = evaluate_spatial(sc)
    acc = np.asarray(e["ydot"])[-6:]
    stretch = np.linalg.norm(b.position - at2) - rest
    expect = {
        "gravity": (g, np.zeros(3), -m * g @ b.position, 0.0),
        "point_force": (f / m, np.linalg.solve(jb, np.cross(s, rot.T @ f)), 0.0, 0.0),
        "torque": (np.zeros(3), np.linalg.solve(jb, rot.T @ tau), 0.0, 0.0),
        "damper": (np.zeros(3), np.zeros(3), 0.0, 0.0)}
    spring_force = -k * stretch * (b.position - at2) / np.linalg.norm(b.position - at2) / m
    expect["spring"] = expect["spring_damper"] = (spring_force, np.zeros(3), 0.0,
                                                  0.5 * k * stretch ** 2)
    if typ in ("sphere_plane", "sphere_sphere"):
        assert [f.type for f in sc.forces] == [typ]
        if typ == "sphere_plane":
            n = PLANE_N
            delta = 0.6 - n @ b.position
        else:
            n = (b.position - BALL) / np.linalg.norm(b.position - BALL)
            delta = 0.8 - np.linalg.norm(b.position - BALL)
        assert delta > 0.05
        expect[typ] = (k * delta ** 1.5 * n / m, np.zeros(3), 0.0, k * delta ** 2.5 / 2.5)
    v_dot, w_dot, vg, vs = expect[typ]
    assert np.abs(acc[:3] - v_dot).max() < 1e-12 and np.abs(acc[3:] - w_dot).max() < 1e-12
    assert abs(e["potential_gravity"] - vg) < 1e-12 and abs(e["potential_springs"] - vs) < 1e-12


@pytest.mark.parametrize("rotation", list(codes.ROTATIONS))
def test_a_rotation_code_is_the_orientation_the_kernel_reads(rotation):
    """The coordinates Python writes for a body's orientation in each set, read by the kernel:
    a spherical joint at an offset point holds at the start (the kernel's R(q) is Python's) and
    the coordinates' rates are Python's rate maps of the body-frame angular velocity."""
    om = np.array([0.3, -0.2, 0.5])
    sc = scene_from_dict({"scene": {"rotation": rotation},
                          "body": [_body(omega_body=list(om))],
                          "joint": [{"type": "spherical", "body1": "b", "at": list(P)}]},
                         f"{rotation}.toml")
    y0 = sc.state0()
    e = evaluate_spatial(sc)
    assert np.abs(e["phi"]).max() < 1e-14
    q = y0[3:7] if rotation == "quaternion" else y0[3:6]
    rates = np.asarray(e["ydot"])[3:3 + q.size]
    expect = (rotations.quaternion_rates(q, om, frame="body") if rotation == "quaternion" else
              rotations.angle_rates(q, om, rotation[-3:], frame="body"))
    assert np.abs(rates - expect).max() < 1e-13


def _tumbling(norm, gain=10.0):
    sc = mbdk.scene("free_body")
    sc.quaternion_norm, sc.norm_gain = norm, gain
    r = mbdk.simulate(sc, "rk4", h=5e-2, t_end=5.0, watch=False)
    return r.residuals[:, 2].max(), r.q


def test_the_quaternion_norm_codes_are_the_kernels_treatments():
    """project keeps |p| = 1 at roundoff; none lets it drift whatever the gain; stabilise
    follows its gain (the intermediate-axis flip at h = 0.05 s: rk4 drifts |p| by 1e-5)."""
    assert set(codes.NORMS) == {"project", "stabilise", "none"}
    assert _tumbling("project")[0] < 1e-14
    (drift, q), (_, q2) = _tumbling("none"), _tumbling("none", 20.0)
    assert drift > 1e-8 and np.array_equal(q, q2)
    (_, q), (_, q2) = _tumbling("stabilise"), _tumbling("stabilise", 20.0)
    assert np.abs(q - q2).max() > 1e-9


@pytest.mark.parametrize("name", ["double_pendulum", "spatial_double_pendulum"])
def test_the_formulation_codes_are_the_kernels_formulations(name):
    """Each formulation's signature, planar and spatial: projection keeps Phi at roundoff;
    reduced ignores alpha and beta and drifts; baumgarte follows alpha and beta; penalty follows
    its penalty and ignores alpha and beta."""
    sc = mbdk.scene(name)

    def run(formulation, **kw):
        return mbdk.simulate(sc, "rk4", formulation=formulation, h=2e-2, t_end=5.0,
                             watch=False, **kw)
    other = dict(alpha=5.0, beta=7.0)
    assert run("projection").residuals[:, 0].max() < 1e-12
    red = run("reduced")
    assert red.residuals[:, 0].max() > 1e-9 and np.array_equal(red.q, run("reduced", **other).q)
    assert np.abs(run("baumgarte").q - run("baumgarte", **other).q).max() > 1e-6
    pen = run("penalty")
    assert np.array_equal(pen.q, run("penalty", **other).q)
    assert np.abs(pen.q - run("penalty", penalty=(1e5, 10.0, 1.0)).q).max() > 1e-6


@pytest.mark.parametrize("name", ["double_pendulum", "spatial_double_pendulum"])
@pytest.mark.parametrize("method,form", [("ida", "index1"), ("ida", "ggl"), ("bdf", "i3"),
                                         ("bdf", "si2")])
def test_the_dae_form_codes_are_the_kernels_forms(name, method, form):
    """Each form of the DAE by its signature, planar (scene_run) and spatial (spatial_run):
    index1 (acceleration level) lets Phi drift; GGL holds Phi and D v + Phi_t (to its Newton
    tolerance); I3 holds Phi, not the velocity rows; SI2 holds both to the tolerance (rtol
    1e-6, 5 s: the margins are more than an order of magnitude)."""
    r = mbdk.simulate(mbdk.scene(name), method, formulation=form, rtol=1e-6, atol=1e-8,
                      t_end=5.0, watch=False)
    pos, vel = np.abs(r.residuals[:, :2]).max(axis=0)
    if form == "index1":
        assert pos > 1e-7
    elif form == "ggl":
        assert pos < 1e-8 and vel < 1e-8
    elif form == "i3":
        assert pos < 1e-8 and vel > 1e-7
    else:
        assert pos < 1e-8 and vel < 1e-7


def test_the_index3_family_runs_with_no_dae_form_in_both_entries():
    """The index-3 family takes dae_form MBDK_DAE_NONE in scene_run and spatial_run alike (one
    rule, kernel/src/api/mbdk_entry.f90): fixed steps of h, the constraints at their
    projection's roundoff."""
    r = mbdk.simulate(mbdk.scene("spatial_double_pendulum"), "trapezoidal_index3", h=1e-2,
                      t_end=1.0)
    assert r.stats.steps == 100 and r.residuals[:, 0].max() < 1e-12
    p = mbdk.simulate(mbdk.scene("double_pendulum"), "trapezoidal_index3", h=1e-2, t_end=1.0)
    assert p.stats.steps == 100


def test_each_output_bit_is_the_output_the_kernel_computes():
    """One output at a time: its array is the one a run of all outputs gives; the others are
    not computed."""
    sc = mbdk.scene("double_pendulum")
    every = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.2)
    attr = {"a": "a", "multipliers": "multipliers", "reactions": "reactions",
            "energy": "energy", "residuals": "residuals"}
    assert set(attr) == set(codes.OUTPUTS)
    for name in codes.OUTPUTS:
        r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.2, outputs=(name,))
        assert np.abs(getattr(every, attr[name])).max() > 0
        assert np.array_equal(getattr(r, attr[name]), getattr(every, attr[name])), name
        assert all(getattr(r, attr[o]) is None for o in attr if o != name)


@pytest.mark.parametrize("solver", list(codes.SOLVERS))
def test_each_solver_code_is_the_linear_solve_the_kernel_takes(solver):
    """The kernel names the path it took (LINEAR_SOLVES by its code): the one asked for (auto:
    the closed form of an all-revolute chain)."""
    took = mbdk.evaluate(mbdk.scene("double_pendulum"), solver=solver)["solve"]
    assert took.startswith("revolute_schur:" if solver == "auto" else f"{solver}:"), took


def test_spatial_run_refuses_a_dae_form_its_method_does_not_take():
    """One rule for both entries: rk4 with a DAE form, ida without one, a form past SI2 and the
    index-3 family with one are MBDK_ERR_INVALID_INPUT in spatial_run as in scene_run, before
    anything runs."""
    from mbdk import _compiled
    from mbdk.options import SpatialOptions, empty
    sc = mbdk.scene("heavy_top")
    nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal = spatial_tables(sc)
    y0 = sc.state0()
    ids = mbdk.methods()

    def status(method, form):
        out = _kernel.spatial_run(mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal,
                                  SpatialOptions().pack(), ids[method].id, form,
                                  mbdk.ODEOptions(h=1e-3).pack(), mbdk.Index3Options().pack(),
                                  np.zeros(0), _compiled.new_flag(), np.zeros(0), y0, 0, 0.0,
                                  0.01, 11,
                                  max(sc.rows, 1), empty("mbdk_stats"),
                                  empty("mbdk_watch_report"))
        return Status(int(out[-1]))

    assert status("rk4", 0) == Status.SUCCESS
    for method, form in (("rk4", 1), ("ida", 0), ("bdf", 3), ("trapezoidal_index3", 1)):
        assert status(method, form) == Status.ERR_INVALID_INPUT, (method, form)
