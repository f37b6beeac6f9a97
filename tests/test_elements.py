"""The element registry exists once, in the kernel (kernel/src/model/mbdk_elements.f90), for
planar and spatial scenes; mbdk.h mirrors its codes (checked in C by
kernel/tests/c_element_table.c) and Python reads it. Here: the header's enums, both scene
formats' element types and the kernel's kinds agree, and the kernel enforces what a kind means
(the planar model takes the kinds of planar scenes only; the spatial model's side:
tests/test_codes.py)."""
import re
from pathlib import Path

import numpy as np
import pytest

import mbdk
from mbdk import _kernel, codes as C, model as M
from mbdk.codes import WEAR_LAWS
from mbdk.scene import FORCE_TYPES, JOINT_TYPES, SPATIAL_FORCE_TYPES, SPATIAL_JOINT_TYPES


def header_kinds(root):
    text = (root / "kernel" / "include" / "mbdk.h").read_text()
    out = {}
    for enum, cls in (("mbdk_joint_kind", 1), ("mbdk_force_kind", 2), ("mbdk_effect_kind", 3)):
        body = re.search(r"enum %s \{(.*?)\};" % enum, text, re.S).group(1)
        for m in re.finditer(r"MBDK_(JOINT|FORCE|EFFECT)_(\w+)\s*=\s*(\d+)", body):
            out[(cls, int(m.group(3)))] = m.group(2).lower()
    return out


#: the enum names that abbreviate a kind's name
ABBREVIATED = {"point": "point_force", "coordinate": "coordinate_spring_damper"}


def test_header_enums_are_the_kernel_registry(root):
    kernel = {(cls, code): name for cls, code, name, _r, _s in C.ELEMENT_KINDS}
    header = {k: ABBREVIATED.get(v, v) for k, v in header_kinds(root).items()}
    assert len(kernel) >= 11 and kernel == header


def _kinds(cls: int, body: str) -> set:
    return {e.name for e in C.ELEMENT_KINDS if e.cls == cls and body in e.rows}


def test_every_scene_type_is_a_kernel_kind_and_back():
    """The planar scene format's types are the registry's kinds of planar bodies, the spatial
    format's its kinds of spatial bodies (a spatial file's spring and damper are spring_dampers,
    its contact a sphere_plane or a sphere_sphere by its second shape)."""
    assert set(JOINT_TYPES) == set(C.JOINT_CODES) == _kinds(C.JOINT_CLASS, "planar")
    # friction is written in its contact's table, not as a [[force]] of its own
    assert set(FORCE_TYPES) | {"friction"} == set(C.FORCE_CODES)
    assert set(C.FORCE_CODES.values()) == {e.code for e in C.ELEMENT_KINDS
                                           if e.cls == C.FORCE_CLASS and "planar" in e.rows}
    assert set(WEAR_LAWS) and set(C.EFFECT_CODES) == {"wear"} == _kinds(C.EFFECT_CLASS,
                                                                         "planar")
    assert SPATIAL_JOINT_TYPES == set(C.SPATIAL_JOINT_CODES) == _kinds(C.JOINT_CLASS, "spatial")
    assert (set(SPATIAL_FORCE_TYPES) - {"spring", "damper", "contact"}) | {
        "sphere_plane", "sphere_sphere"} == set(C.SPATIAL_FORCE_CODES) == _kinds(C.FORCE_CLASS,
                                                                                 "spatial")
    # wear is both models': the spatial format's [[wear]] is the planar one's
    assert _kinds(C.EFFECT_CLASS, "spatial") == {"wear"} == set(C.SPATIAL_EFFECT_CODES)
    assert C.VISIT_NAMES == [e.name for e in C.ELEMENT_KINDS]


def test_a_planar_run_counts_the_kinds_of_planar_scenes():
    """A planar run's visits name every kind of planar scenes, in the registry's order, and no
    kind of spatial scenes alone (which the planar model cannot visit)."""
    r = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-3, t_end=0.01)
    assert list(r.visits) == [e.name for e in C.ELEMENT_KINDS if "planar" in e.rows]
    assert r.visits["revolute"] > 0 and r.visits["gravity"] > 0


def test_the_planar_model_refuses_the_kinds_of_spatial_scenes():
    """Each joint and force-table code of the spatial scenes alone, put in a planar scene's
    tables (a C embedder's slip): invalid input, not some planar kind evaluated; the scene's own
    tables (a revolute joint and gravity, kinds of both) evaluate."""
    sc = mbdk.scene("double_pendulum")
    tab = M.build_tables(sc)
    y = np.concatenate([sc.q0(), sc.v0()])

    def status(jint=tab.jint, fint=tab.fint):
        args = list(tab.args())
        args[4], args[7] = jint, fint
        *_, st = _kernel.model_eval(*args, mbdk.ModelOptions().pack(), tab.m, 0.0, y)
        return st

    assert status() == mbdk.Status.SUCCESS
    joints = [e.code for e in C.ELEMENT_KINDS if e.cls == C.JOINT_CLASS and
              "planar" not in e.rows]
    forces = [e.code for e in C.ELEMENT_KINDS if e.cls != C.JOINT_CLASS and
              "planar" not in e.rows]
    assert joints and forces
    for code in joints:
        jint = tab.jint.copy()
        jint[0, 0] = code
        assert status(jint=jint) == mbdk.Status.ERR_INVALID_INPUT, code
    k = [f.type for f in sc.forces].index("gravity")
    for code in forces:
        fint = tab.fint.copy()
        fint[0, k] = code
        assert status(fint=fint) == mbdk.Status.ERR_INVALID_INPUT, code


def test_joint_rows_are_the_kernels():
    """The rows the registry states are the rows the kernel's Phi has (four-bar: three
    revolute joints and a ground revolute, 8 rows; trolley: prismatic + revolute)."""
    for name in ("four_bar", "trolley_crane", "three_link_pendulum"):
        sc = mbdk.scene(name)
        tab = M.build_tables(sc)
        assert tab.m == sum(C.JOINT_ROWS[j.type] for j in sc.joints)
        assert M.evaluate(tab, sc.q0(), sc.v0())["phi"].size == tab.m


def test_a_spring_with_damping_is_refused_by_the_kernel():
    """A spring is a kind without damping: tables that give one damping (a C embedder's slip)
    are refused, not silently turned into a spring-damper."""
    sc = mbdk.scene("spring_bar")
    tab = M.build_tables(sc)
    k = [f.type for f in sc.forces].index("spring")
    assert tab.fint[0, k] == C.FORCE_CODES["spring"]
    assert M.evaluate(tab, sc.q0(), sc.v0())["status"] == mbdk.Status.SUCCESS
    tab.freal[6, k] = 1.0
    y = np.concatenate([sc.q0(), sc.v0()])
    *_, status = _kernel.model_eval(*tab.args(), mbdk.ModelOptions().pack(), tab.m, 0.0, y)
    assert status == mbdk.Status.ERR_INVALID_INPUT


def test_body_kinds_are_the_kernels_and_the_headers(root):
    """The body kinds: the kernel's table (mbdk_elements), mbdk.h's enum and the scene format
    read the same names and codes; planar bodies carry (x, y, theta), spatial ones a position
    and a quaternion (7) and 6 velocities, and a model of the kernel runs each kind."""
    from mbdk.codes import BODY_KINDS
    text = (root / "kernel" / "include" / "mbdk.h").read_text()
    body = re.search(r"enum mbdk_body_kind \{(.*?)\};", text, re.S).group(1)
    header = {m.group(1).lower(): int(m.group(2))
              for m in re.finditer(r"MBDK_BODY_(\w+)\s*=\s*(\d+)", body)}
    assert header == {name: code for name, (code, *_r) in BODY_KINDS.items()}
    assert BODY_KINDS["planar"] == (1, 3, 3, True)
    assert BODY_KINDS["spatial"] == (2, 7, 6, True)


def test_a_declared_planar_kind_is_the_default_bit_for_bit(tmp_path):
    src = Path(mbdk.scene("double_pendulum").source).read_text()
    assert "kind" not in src
    path = tmp_path / "dp.toml"
    path.write_text(src.replace('[[body]]\n', '[[body]]\nkind = "planar"\n'))
    a = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-3, t_end=0.5)
    b = mbdk.simulate(mbdk.load_scene(path), "rk4", h=1e-3, t_end=0.5)
    assert np.array_equal(a.q, b.q)


@pytest.mark.parametrize("kind,words", [
    # one spatial body makes the file a spatial scene: the joint to a planar body is named
    ("spatial", ["joint 'A'", "'body1'", "'bar2' is a planar body", "spatial"]),
    ("rigid3d", ["body", "'kind'", "'rigid3d'", "is not a body kind", "planar, spatial"])])
def test_a_body_kind_the_kernel_cannot_simulate_is_refused_by_name(tmp_path, kind, words):
    src = Path(mbdk.scene("double_pendulum").source).read_text()
    path = tmp_path / "dp.toml"
    path.write_text(src.replace('[[body]]\n', f'[[body]]\nkind = "{kind}"\n', 1))
    with pytest.raises(mbdk.SceneError) as err:
        mbdk.load_scene(path)
    msg = str(err.value)
    for w in [str(path), *words]:
        assert w in msg, (w, msg)
    # the same kind set on a Scene object after loading: refused before the kernel runs
    sc = mbdk.scene("double_pendulum")
    sc.bodies[1].kind = kind
    with pytest.raises(mbdk.InvalidInputError,
                       match="joint 'O': field 'body1'" if kind == "spatial" else "'kind'"):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.1)


def test_the_kernel_itself_refuses_body_kinds_it_cannot_simulate():
    """Tables from another door (the f2py layer, a future C body table): spatial is named as not
    applicable, an unknown code is invalid input."""
    sc = mbdk.scene("double_pendulum")
    tab = M.build_tables(sc)
    y = np.concatenate([sc.q0(), sc.v0()])
    for code, status in ((1, mbdk.Status.SUCCESS), (2, mbdk.Status.ERR_NOT_APPLICABLE),
                         (0, mbdk.Status.ERR_INVALID_INPUT), (9, mbdk.Status.ERR_INVALID_INPUT)):
        tab.kind = np.array([1, code], np.int32)
        *_, st = _kernel.model_eval(*tab.args(), mbdk.ModelOptions().pack(), tab.m, 0.0, y)
        assert st == status, (code, st)
