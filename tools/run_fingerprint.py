"""Prints every number of a broad set of runs with repr(), so that two builds can be compared
bit for bit: run it before a change that must not change results (a refactoring) and after,
and diff the two outputs (cpu_time and wall_time are left out; everything else, statistics
included, must be identical).

    .venv/bin/python tools/run_fingerprint.py > before.txt
    ... change, rebuild ...
    .venv/bin/python tools/run_fingerprint.py > after.txt
    diff before.txt after.txt

The runs: every built-in planar and spatial scene (and a knife-edge car, and chains on the
dense and sparse paths started off their joints, so that the assembly iterates) with rk4 at a
fixed h on each formulation, dopri54, bdf (ODE and DAE forms), trapezoidal_index3 and ida; the
planar solver paths (auto, schur, kkt, revolute, sparse, small_dense off); the spatial
rotations (quaternion with each norm treatment, euler313, cardan123); the kernel's entries
called directly with broken tables and options (the statuses and the bytes its model builds
return); invalid arguments (their error messages); and the fixed-seed fuzz subset of
tests/test_fuzz.py (each case's outcome and message).
"""
from __future__ import annotations

import dataclasses
import math
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "studies"))

import mbdk  # noqa: E402
from mbdk import _kernel  # noqa: E402
from mbdk.codes import ROTATIONS  # noqa: E402
from mbdk.model import build_tables, given_mask  # noqa: E402
from mbdk.scene_file import scene_from_dict  # noqa: E402
from mbdk.spatial_model import spatial_tables  # noqa: E402

SKIP = {"cpu_time", "wall_time", "seconds"}
OUT = []


def emit(*parts):
    OUT.append(" ".join(str(p) for p in parts))


def canon(x):
    """Nested text of a value, every float by repr (exact), timings left out."""
    if dataclasses.is_dataclass(x) and not isinstance(x, type):
        return "{" + ", ".join(f"{f.name}: {canon(getattr(x, f.name))}"
                               for f in dataclasses.fields(x) if f.name not in SKIP) + "}"
    if isinstance(x, dict):
        return "{" + ", ".join(f"{k!r}: {canon(v)}" for k, v in x.items()
                               if k not in SKIP) + "}"
    if isinstance(x, np.ndarray):
        return f"array{x.shape}{x.dtype}" + repr(x.tolist())
    if isinstance(x, (list, tuple)):
        return "[" + ", ".join(canon(v) for v in x) + "]"
    if isinstance(x, (np.floating, float)):
        return repr(float(x))
    if isinstance(x, (np.integer,)):
        return repr(int(x))
    return repr(x)


def record(label, fn):
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            r = fn()
        emit(label, "->", canon(r))
        for w in caught:
            emit(label, "warning", type(w.message).__name__, str(w.message))
    except Exception as exc:  # noqa: BLE001 -- the error's type and text are the fingerprint
        emit(label, "-> raised", type(exc).__name__, str(exc))


def car(steer, v0=10.0):
    d = {"scene": {"name": "car"},
         "body": [{"name": "car", "mass": 1000.0, "inertia": 1500.0, "vx": v0,
                   "given": ["x", "y", "angle", "vx"]}],
         "joint": [{"name": "wheels", "type": "knife_edge", "body1": "car",
                    "point1": [0.0, 0.0]},
                   {"name": "steer", "type": "driver", "body1": "car", "coordinate": "angle",
                    "function": steer}]}
    return scene_from_dict(d, "car.toml")


def bent_chain(n, redundant=False):
    """A chain of n bars started off its joints (each body moved and turned a little), so that
    the assembly iterates: 2 n rows, dense up to 6 bars, sparse beyond; redundant: the ground
    hinge twice (dependent rows: the sparse least change falls back to the dense one)."""
    bodies, joints = [], []
    for i in range(n):
        bodies.append({"name": f"b{i}", "mass": 1.0 + 0.1 * i,
                       "shape": {"type": "bar", "length": 1.0},
                       "x": i + 0.5 + 0.01 * (i % 3), "y": 0.02 * i, "angle_deg": 3.0 * i,
                       "omega": 0.1 * i, "given": ["angle"] if i == 0 else []})
        joints.append({"name": f"J{i}", "type": "revolute", "body1": f"b{i}",
                       "point1": [-0.5, 0.0], "body2": f"b{i - 1}" if i else "ground",
                       "point2": [0.5, 0.0] if i else [0.0, 0.0]})
    if redundant:
        joints.append(dict(joints[0], name="J0_again"))
    return scene_from_dict({"scene": {"name": f"bent_chain_{n}"}, "body": bodies,
                            "joint": joints,
                            "force": [{"type": "gravity", "g": [0.0, -9.81]}]})


def planar_runs(name, sc, t_end=0.3, h=1e-3):
    for form in ("reduced", "baumgarte", "penalty", "projection"):
        record(f"{name} rk4 {form}", lambda: mbdk.simulate(
            sc, "rk4", h=h, t_end=t_end, every=25, formulation=form, raise_on_failure=False))
    for solver in ("schur", "kkt", "revolute_schur", "sparse"):
        record(f"{name} rk4 reduced solver={solver}", lambda: mbdk.simulate(
            sc, "rk4", h=h, t_end=t_end, every=25, solver=solver, raise_on_failure=False))
    record(f"{name} rk4 reduced small_dense=False", lambda: mbdk.simulate(
        sc, "rk4", h=h, t_end=t_end, every=25, small_dense=False, raise_on_failure=False))
    record(f"{name} rk4 penalty small_dense=False", lambda: mbdk.simulate(
        sc, "rk4", h=h, t_end=t_end, every=25, formulation="penalty", small_dense=False,
        raise_on_failure=False))
    record(f"{name} dopri54", lambda: mbdk.simulate(
        sc, "dopri54", t_end=t_end, rtol=1e-8, atol=1e-10, dt_out=0.05,
        raise_on_failure=False))
    record(f"{name} dopri54 projection", lambda: mbdk.simulate(
        sc, "dopri54", t_end=t_end, rtol=1e-8, atol=1e-10, dt_out=0.05,
        formulation="projection", raise_on_failure=False))
    record(f"{name} bdf", lambda: mbdk.simulate(
        sc, "bdf", t_end=t_end, rtol=1e-7, atol=1e-9, dt_out=0.05, raise_on_failure=False))
    for form in ("i3", "si2"):
        record(f"{name} bdf {form}", lambda: mbdk.simulate(
            sc, "bdf", t_end=t_end, rtol=1e-7, atol=1e-9, dt_out=0.05, formulation=form,
            raise_on_failure=False))
    for form in ("index3", "augmented_lagrangian"):
        record(f"{name} trapezoidal_index3 {form}", lambda: mbdk.simulate(
            sc, "trapezoidal_index3", h=h, t_end=t_end, every=25, formulation=form,
            raise_on_failure=False))
    record(f"{name} trapezoidal_index3 adaptive", lambda: mbdk.simulate(
        sc, "trapezoidal_index3", h=h, t_end=t_end, adaptive=True, err_rtol=1e-5,
        err_atol=1e-7, dt_out=0.05, raise_on_failure=False))
    for form in ("index1", "ggl"):
        record(f"{name} ida {form}", lambda: mbdk.simulate(
            sc, "ida", t_end=t_end, rtol=1e-7, atol=1e-9, dt_out=0.05, formulation=form,
            raise_on_failure=False))


def spatial_runs(name, sc, t_end=0.2, h=1e-3):
    for form in ("reduced", "baumgarte", "penalty", "projection"):
        record(f"{name} rk4 {form}", lambda: mbdk.simulate(
            sc, "rk4", h=h, t_end=t_end, every=25, formulation=form, raise_on_failure=False))
    record(f"{name} dopri54", lambda: mbdk.simulate(
        sc, "dopri54", t_end=t_end, rtol=1e-8, atol=1e-10, dt_out=0.05,
        raise_on_failure=False))
    record(f"{name} bdf", lambda: mbdk.simulate(
        sc, "bdf", t_end=t_end, rtol=1e-7, atol=1e-9, dt_out=0.05, raise_on_failure=False))
    for form in ("i3", "si2"):
        record(f"{name} bdf {form}", lambda: mbdk.simulate(
            sc, "bdf", t_end=t_end, rtol=1e-7, atol=1e-9, dt_out=0.05, formulation=form,
            raise_on_failure=False))
    record(f"{name} trapezoidal_index3", lambda: mbdk.simulate(
        sc, "trapezoidal_index3", h=h, t_end=t_end, every=25, raise_on_failure=False))
    for form in ("index1", "ggl"):
        record(f"{name} ida {form}", lambda: mbdk.simulate(
            sc, "ida", t_end=t_end, rtol=1e-7, atol=1e-9, dt_out=0.05, formulation=form,
            raise_on_failure=False))


def planar_kernel_doors(name, sc):
    """model_eval and model_assemble with one table entry or option broken at a time: the
    statuses of the model's build (and its evaluation where the build passes)."""
    tab = build_tables(sc)
    y = np.concatenate([np.array(sc.q0(), float), np.array(sc.v0(), float)])

    def ev(label, mass=None, inertia=None, kind=None, jint=None, jreal=None, fint=None,
           freal=None, opt=None):
        args = [tab.mass if mass is None else mass, tab.inertia if inertia is None else inertia,
                tab.kind if kind is None else kind, tab.nj,
                tab.jint if jint is None else jint, tab.jreal if jreal is None else jreal,
                tab.nf, tab.fint if fint is None else fint,
                tab.freal if freal is None else freal]
        o = mbdk.ModelOptions() if opt is None else opt
        record(f"{name} model_eval {label}",
               lambda: _kernel.model_eval(*args, o.pack(), tab.m, 0.0, y))

    ev("as built")
    for form in (1, 2, 3, 4):
        for solver in (1, 2, 3, 4, 5):
            ev(f"formulation {form} solver {solver}",
               opt=mbdk.ModelOptions(formulation=form, solver=solver))
    for field, value in (("formulation", 0), ("formulation", 5), ("solver", 0), ("solver", 6),
                         ("penalty_alpha", 0.0), ("penalty_alpha", math.inf),
                         ("projection_tol", 0.0), ("projection_max_iter", 0),
                         ("watch_every", -1), ("watch_energy", math.nan),
                         ("baumgarte_alpha", math.inf)):
        extra = {"formulation": 3} if field == "penalty_alpha" else \
            {"formulation": 4} if field == "projection_tol" else {}
        ev(f"{field}={value!r}", opt=mbdk.ModelOptions(**{field: value, **extra}))
    m = tab.mass.copy()
    m[0] = -1.0
    ev("mass<0", mass=m)
    i = tab.inertia.copy()
    i[-1] = math.nan
    ev("inertia nan", inertia=i)
    if tab.kind is not None and len(tab.kind):
        k = np.array(tab.kind).copy()
        k[0] = 2
        ev("kind 2", kind=k)
        k[0] = 99
        ev("kind 99", kind=k)
    for col in range(tab.nj):
        for row, value in ((0, 99), (1, 0), (1, 999), (2, -1), (3, 7)):
            j = tab.jint.copy()
            j[row, col] = value
            ev(f"jint[{row},{col}]={value}", jint=j)
        r = tab.jreal.copy()
        r[4:7, col] = math.nan
        ev(f"jreal[4:7,{col}]=nan", jreal=r)
    for col in range(tab.nf):
        for row, value in ((0, 0), (0, 99), (1, -1), (1, 999), (2, 999), (3, 9)):
            f = tab.fint.copy()
            f[row, col] = value
            ev(f"fint[{row},{col}]={value}", fint=f)
        for row in (0, 2, 4, 6, 7, 8):
            r = tab.freal.copy()
            r[row, col] = -1.0
            ev(f"freal[{row},{col}]=-1", freal=r)
    def assemble(q, v):
        q, v = q.copy(), v.copy()
        out = _kernel.model_assemble(*tab.args(), 0.0, q, v, given_mask(sc), max(tab.m, 1))
        return [out, q, v]

    q = np.array(sc.q0(), float)
    v = np.array(sc.v0(), float)
    record(f"{name} model_assemble as given", lambda: assemble(q, v))
    record(f"{name} model_assemble moved", lambda: assemble(
        q + 1e-3 * np.sin(np.arange(q.size) + 1.0), v + 0.1 * np.cos(np.arange(v.size))))
    record(f"{name} model_assemble far", lambda: assemble(q + 0.5 * np.sin(np.arange(q.size)),
                                                         v))


def spatial_kernel_doors(name, sc):
    nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal = spatial_tables(sc)
    y0 = sc.state0()
    rot = ROTATIONS[sc.rotation]
    m = max(sc.rows, 1)

    def ev(label, **kw):
        a = dict(mass=mass, inertia=inertia, jtype=jtype, jbody=jbody, jreal=jreal, ftype=ftype,
                 fbody=fbody, freal=freal, rot=rot, y0=y0)
        a.update(kw)
        record(f"{name} spatial_residuals {label}", lambda: _kernel.spatial_residuals(
            a["mass"], a["inertia"], nj, a["jtype"], a["jbody"], a["jreal"], nf, a["ftype"],
            a["fbody"], a["freal"], a["rot"], a["y0"], 0.0, a["y0"], m))

    ev("as built")
    mm = mass.copy()
    mm[0] = 0.0
    ev("mass 0", mass=mm)
    ii = inertia.copy()
    ii[0, 1, 0] += 1.0
    ev("inertia asymmetric", inertia=ii)
    ii = inertia.copy()
    ii[:, :, -1] = -ii[:, :, -1]
    ev("inertia negative", inertia=ii)
    ev("rotation 0", rot=0.0)
    yy = y0.copy()
    yy[3] *= 2.0
    ev("quaternion not unit", y0=yy)
    for k in range(nj):
        for row, value in ((0, 0), (0, 99), (1, 0), (1, 999), (2, -1)):
            jt, jb = jtype.copy(), jbody.copy()
            if row == 0:
                jt[k] = value
            else:
                jb[row - 1, k] = value
            ev(f"joint {k} [{row}]={value}", jtype=jt, jbody=jb)
        jr = jreal.copy()
        jr[6:12, k] = 0.0
        ev(f"joint {k} axes 0", jreal=jr)
        jr = jreal.copy()
        jr[0, k] = math.inf
        ev(f"joint {k} inf", jreal=jr)
    for k in range(nf):
        for value in (0, 99):
            ft = ftype.copy()
            ft[k] = value
            ev(f"force {k} type={value}", ftype=ft)
        for row, value in ((0, 0), (0, 999), (1, -1), (1, 999)):
            fb = fbody.copy()
            fb[row, k] = value
            ev(f"force {k} body[{row}]={value}", fbody=fb)
        for row in (3, 6, 7, 8, 12, 17):
            fr = freal.copy()
            fr[row, k] = -1.0
            ev(f"force {k} freal[{row}]=-1", freal=fr)


def invalid_arguments():
    fb = mbdk.scene("four_bar")
    top = mbdk.scene("heavy_top")
    cases = [
        ("h<0", lambda: mbdk.simulate(fb, "rk4", h=-1e-3, t_end=0.1)),
        ("formulation unknown", lambda: mbdk.simulate(fb, "rk4", h=1e-3, t_end=0.1,
                                                      formulation="nope")),
        ("solver unknown", lambda: mbdk.simulate(fb, "rk4", h=1e-3, t_end=0.1, solver="x")),
        ("revolute solver on a slider", lambda: mbdk.simulate(
            mbdk.scene("trolley_crane"), "rk4", h=1e-3, t_end=0.1, solver="revolute")),
        ("penalty alpha 0", lambda: mbdk.simulate(fb, "rk4", h=1e-3, t_end=0.1,
                                                  formulation="penalty", penalty=(0.0, 1, 1))),
        ("projection_tol 0", lambda: mbdk.simulate(fb, "rk4", h=1e-3, t_end=0.1,
                                                   formulation="projection",
                                                   projection_tol=0.0)),
        ("spatial solver", lambda: mbdk.simulate(top, "rk4", h=1e-3, t_end=0.1,
                                                 solver="kkt")),
        ("spatial formulation", lambda: mbdk.simulate(top, "rk4", h=1e-3, t_end=0.1,
                                                      formulation="index3")),
        ("spatial penalty 0", lambda: mbdk.simulate(top, "rk4", h=1e-3, t_end=0.1,
                                                    formulation="penalty",
                                                    penalty=(0.0, 1.0, 1.0))),
        ("planar mass -1", lambda: mbdk.simulate(
            dataclasses.replace(fb, bodies=[dataclasses.replace(fb.bodies[0], mass=-1.0)]
                                + fb.bodies[1:]), "rk4", h=1e-3, t_end=0.1)),
        ("spatial mass 0", lambda: mbdk.simulate(
            dataclasses.replace(top, bodies=[dataclasses.replace(top.bodies[0], mass=0.0)]),
            "rk4", h=1e-3, t_end=0.1)),
        ("watch negative", lambda: mbdk.simulate(fb, "rk4", h=1e-3, t_end=0.1,
                                                 watch={"position": -1.0, "every": -3})),
    ]
    for label, fn in cases:
        record(f"invalid {label}", fn)


def main():
    np.set_printoptions(floatmode="unique")
    for name in mbdk.scenes("planar"):
        sc = mbdk.scene(name)
        planar_runs(name, sc)
        planar_kernel_doors(name, sc)
    for name, sc in (("car", car({"amplitude": 0.4, "omega": 1.3})), ("bent3", bent_chain(3)),
                     ("bent9", bent_chain(9)), ("redundant9", bent_chain(9, True))):
        planar_runs(name, sc)
        planar_kernel_doors(name, sc)
    for name in mbdk.scenes("spatial"):
        sc = mbdk.scene(name)
        spatial_runs(name, sc)
        spatial_kernel_doors(name, sc)
        for rotation, norm in (("quaternion", "stabilise"), ("quaternion", "none"),
                               ("euler313", "project"), ("cardan123", "project")):
            if sc.rotation == rotation and sc.quaternion_norm == norm:
                continue
            other = dataclasses.replace(sc, rotation=rotation, quaternion_norm=norm)
            label = f"{name}[{rotation},{norm}]"
            for form in ("reduced", "projection"):
                record(f"{label} rk4 {form}", lambda: mbdk.simulate(
                    other, "rk4", h=1e-3, t_end=0.2, every=25, formulation=form,
                    raise_on_failure=False))
            record(f"{label} trapezoidal_index3", lambda: mbdk.simulate(
                other, "trapezoidal_index3", h=1e-3, t_end=0.2, every=25,
                raise_on_failure=False))
            spatial_kernel_doors(label, other)
    invalid_arguments()
    import fuzz
    with tempfile.TemporaryDirectory() as tmp:
        for r in fuzz.fuzz(Path(tmp), n_scenes=160, n_args=90):
            emit("fuzz", r["door"], "|", str(r["case"]).replace(tmp, "<tmp>"), "|",
                 r["outcome"], "|", str(r["detail"]).replace(tmp, "<tmp>"))
    sys.stdout.write("\n".join(OUT) + "\n")


if __name__ == "__main__":
    main()
