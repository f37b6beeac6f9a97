"""A scene's tables as a file, for programs that embed the kernel from C (or Fortran): the
arrays the steppers take (mbdk.h: mbdk_stepper_create_scene, _index3, _spatial,
_spatial_index3, mbdk_stepper_create_tables) and the initial state a run starts from, written
by ``mbdk tables SCENE -o FILE`` and read in C by ``mbdk_scene_tables_read``
(kernel/src/api/mbdk_scene_tables.c).

The scene file itself is read by one reader, this package's, whose checks name the file, the
element, the field and the value; the tables file carries its result, so a C program runs the
very tables Python runs (the same bits, tests/test_c_scene_file.py) and the kernel has no
second scene reader to drift from the first.

The format is TOML, one ``key = value`` per line (any TOML reader reads it; the C reader reads
this subset: numbers, strings without escapes, one-line lists of numbers). Keys, each once:

``format`` ``"mbdk-scene-tables"``; ``version`` 1; ``scene`` the scene's name; ``source`` its
file; ``kind`` ``"planar"`` or ``"spatial"``; ``rotation`` a spatial scene's orientation
coordinates (1 quaternion, 2 euler313, 3 cardan123; 0 on planar scenes); ``nb``, ``nj``,
``nf`` the bodies, joint rows and force rows (friction, coast-flank and wear entries included);
``n`` the state's length; ``t0`` the time of ``y0``;
``mass`` (nb); ``inertia`` (planar: nb; spatial: nb 3x3 matrices, row-major);
planar: ``jint`` (nj x 4), ``jreal`` (nj x 12), ``fint`` (nf x 4), ``freal`` (nf x 12), values
the scene leaves to the pose marked as the kernel's MBDK_FROM_POSE, filled in by the stepper at
y0; spatial: ``jtype`` (nj), ``jbody`` (nj x 2), ``jreal`` (nj x 17), ``ftype`` (nf),
``fbody`` (nf x 2), ``freal`` (nf x 19), ``norm`` how its quaternions keep |p| = 1 (1 project,
2 stabilise, 3 none) and ``norm_gain`` the stabilisation's gain; every table row-major, one row
per element, as mbdk.h documents its fields;
``y0`` (n): the bodies' coordinates, their rates, then the wear elements' volumes, at the pose
the run starts from (the scene's assembled, as ``simulate`` assembles it by default).
"""
from __future__ import annotations

import tomllib
from pathlib import Path

import numpy as np

from . import checks
from .codes import NORMS
from .errors import InvalidInputError, RedundantConstraintsError
from .ode import package_version
from .model import build_tables
from .results_io import check_writable, write_atomic
from .run_planar import gears_at_assembled_pose
from .scene import Scene
from .scene_file import checked
from .simulate import simulate
from .spatial_model import ROTATIONS, spatial_tables

FORMAT = "mbdk-scene-tables"
VERSION = 1


def scene_tables(scene: Scene, t0: float = 0.0) -> dict:
    """The tables file's keys and values for a scene (module docstring): its kernel tables as
    the run builds them, and the assembled initial state at t0."""
    if not isinstance(scene, Scene):
        raise InvalidInputError(f"scene must be an mbdk Scene, got {type(scene).__name__}")
    t0 = checks.real("t0", t0)
    # the scene's fields through the reader's checks, as simulate takes them
    scene = checked(scene)
    start = _start(scene, t0)
    wear = [start.wear[w.name][0] for w in scene.wear]
    y0 = np.concatenate([start.q[0], start.v[0], np.array(wear, float)])
    head = {"format": FORMAT, "version": VERSION, "scene": scene.name,
            "source": _source(scene), "kind": scene.kind}
    if scene.kind == "spatial":
        nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal = \
            spatial_tables(scene)
        return {**head, "rotation": ROTATIONS[scene.rotation], "norm": NORMS[scene.quaternion_norm],
                "norm_gain": float(scene.norm_gain), "nb": nb, "nj": nj, "nf": nf,
                "n": y0.size, "t0": float(t0), "mass": mass,
                "inertia": np.transpose(inertia, (2, 0, 1)),
                "jtype": jtype[:nj], "jbody": jbody[:, :nj].T, "jreal": jreal[:, :nj].T,
                "ftype": ftype[:nf], "fbody": fbody[:, :nf].T, "freal": freal[:, :nf].T,
                "y0": y0}
    if any(f.type == "contact" and f.shape1[0] == "gear" for f in scene.forces):
        scene = gears_at_assembled_pose(scene, t0)
    tab = build_tables(scene, resolve=False)
    return {**head, "rotation": 0, "nb": len(scene.bodies), "nj": tab.nj, "nf": tab.nf,
            "n": y0.size, "t0": float(t0), "mass": tab.mass, "inertia": tab.inertia,
            "jint": tab.jint[:, :tab.nj].T, "jreal": tab.jreal[:, :tab.nj].T,
            "fint": tab.fint[:, :tab.nf].T, "freal": tab.freal[:, :tab.nf].T, "y0": y0}


def _start(scene: Scene, t0: float):
    """The state a run starts from at t0: the first sample of one tiny step, the kernel's own
    assembly (by rk4; on a scene whose joints are redundant, which the ODE formulations refuse,
    by trapezoidal_index3)."""
    t_end = t0 + 1e-9 * max(1.0, abs(t0))
    h = t_end - t0          # what t0 + h is in floating point: exactly one step
    try:
        return simulate(scene, "rk4", h=h, t0=t0, t_end=t_end, outputs=(), watch=False)
    except RedundantConstraintsError:
        return simulate(scene, "trapezoidal_index3", h=h, t0=t0, t_end=t_end, outputs=(),
                        watch=False)


def _source(scene: Scene) -> str:
    """The scene's file; a built-in scene's relative to the package (the same on every
    machine)."""
    if scene.source is None:
        return "<python>"
    src = Path(str(scene.source))
    package = Path(__file__).resolve().parent
    try:
        return "mbdk/" + src.resolve().relative_to(package).as_posix()
    except (ValueError, OSError):
        return str(scene.source)


def _toml(value) -> str:
    if isinstance(value, str):
        if '"' in value or "\\" in value or "\n" in value:
            raise InvalidInputError(f"tables file: the text {value!r} has a quote, a backslash "
                                    "or a line break; rename the scene or its file")
        return f'"{value}"'
    if isinstance(value, np.ndarray):
        flat = value.ravel()
        if flat.dtype.kind in "iu":
            return "[" + ", ".join(str(int(x)) for x in flat) + "]"
        if not np.all(np.isfinite(flat)):
            raise InvalidInputError("tables file: a table holds a non-finite value")
        return "[" + ", ".join(repr(float(x)) for x in flat) + "]"   # repr: every bit
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    return repr(float(value))


def write_tables(scene: Scene, path, t0: float = 0.0) -> Path:
    """Write the scene's tables file (module docstring) to path, whole or not at all."""
    path = Path(path)
    check_writable(path, (".toml",))
    keys = scene_tables(scene, t0)
    lines = [f"# mbdk {package_version()}: the kernel's tables of scene {scene.name!r} "
             f"({_source(scene)}),",
             "# read from C by mbdk_scene_tables_read (mbdk.h); keys: python/mbdk/tables_file.py",
             *(f"{k} = {_toml(v)}" for k, v in keys.items())]
    write_atomic(path, lambda tmp: tmp.write_text("\n".join(lines) + "\n", encoding="utf-8"))
    return path


def read_tables(path) -> dict:
    """A tables file's keys, arrays as numpy arrays in the shapes scene_tables gives (for
    checks from Python; C reads the file with mbdk_scene_tables_read)."""
    with open(path, "rb") as f:
        data = tomllib.load(f)
    if data.get("format") != FORMAT or data.get("version") != VERSION:
        raise InvalidInputError(f"{path}: not a version {VERSION} {FORMAT} file")
    widths = {"jint": 4, "fint": 4, "jbody": 2, "fbody": 2,
              "jreal": 12 if data["kind"] == "planar" else 17,
              "freal": 12 if data["kind"] == "planar" else 19}
    out = {}
    for k, v in data.items():
        if isinstance(v, list):
            a = np.array(v, dtype=np.int32 if k in ("jint", "fint", "jtype", "jbody", "ftype",
                                                     "fbody") else float)
            if k in widths:
                a = a.reshape(-1, widths[k])
            elif k == "inertia" and data["kind"] == "spatial":
                a = a.reshape(-1, 3, 3)
            out[k] = a
        else:
            out[k] = v
    return out
