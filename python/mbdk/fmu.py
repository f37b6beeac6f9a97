"""A scene as an FMI 3.0 co-simulation FMU (``mbdk fmu``, :func:`export_fmu`), for the tools that
embed a mechanism in a larger system model (Dymola, OpenModelica, Simulink, FMPy and other
co-simulation masters).

The FMU's binary is the kernel itself (``mbdk_fmi3``, built with it: kernel/src/fmi/mbdk_fmi3.c
is its manual), with no Python inside; its resources are the scene's tables and initial state
(the file ``mbdk tables`` writes: :mod:`mbdk.tables_file`) and ``fmu.txt``, the run's option
structs exactly as :func:`mbdk.simulate` fills them and the variables. So the FMU steps
simulate's steps: its outputs at the communication points are ``simulate(scene, method, h=h,
dt_out=...)``'s samples, bit for bit.

Variables (names are flat; units in modelDescription.xml):

- parameters (fixed: set before initialisation ends): every body's ``mass`` (planar bodies'
  ``inertia`` too), the stiffness and damping of springs and dampers (a spatial
  spring-damper's ``rest_length``), the loads not declared as inputs, and ``step`` (the
  kernel's step h);
- inputs: the loads named in ``inputs``: a point force's components (``NAME.force.x``, ...) and
  a torque's (planar ``NAME.torque``, spatial ``NAME.torque.x``, ...), times the element's time
  function, acting from the communication point they are set at (the watch then holds the
  scene to no conserved momentum);
- outputs: each body's coordinates and velocities (planar ``x y angle vx vy omega``; spatial
  ``x y z``, the orientation coordinates ``p0..p3`` or ``angle1..3``, ``vx vy vz`` and the
  body-frame ``wx wy wz``), each wear element's ``volume``, each joint row's multiplier
  (``JOINT.lambda[k]``), planar joints' reactions on their first body (``JOINT.reaction.Fx``,
  ``.Fy``, ``.M``), ``energy.kinetic``, ``energy.gravity``, ``energy.spring``,
  ``energy.total`` and the constraints' residuals ``residual.position``, ``residual.velocity``.

Methods: the fixed-step ODE methods on any formulation and the index-3 family (error-controlled
methods choose their own steps over a whole interval and are refused by name; so are ida and
bdf on the DAE). The FMU's state can be saved and restored (``canGetAndSetFMUState``: the whole
stepper is copied), not serialised. A kernel failure (drift, a singular pose) is ``fmi3Error``
with the status's name and message through the logger; the last good state stays readable.

``bundle=True`` (the default) copies the shared libraries the binary needs beyond the C
library (gfortran's runtime, LAPACK and its BLAS, SUNDIALS, SuiteSparse) into the FMU, so it
runs on a Linux x86-64 machine without them.
"""
from __future__ import annotations

import datetime
import hashlib
import re
import shutil
import subprocess
import sys
import tempfile
import uuid
import zipfile
from dataclasses import dataclass, fields
from pathlib import Path
from xml.sax.saxutils import quoteattr

import numpy as np

from . import _kernel, checks
from .codes import FORCE_CODES, SPATIAL_FORCE_CODES, STRUCT_IDS
from .errors import InvalidInputError, NotApplicableError
from .ode import package_version
from .plan import Request, make_plan
from .results_io import check_writable, write_atomic
from .scene import Scene
from .scene_file import checked, scene_or_file
from .tables_file import scene_tables, write_tables

#: the binary every FMU carries, built with the kernel (meson.build: mbdk_fmi3)
BINARY = "mbdk_fmi3.so"
PLATFORM = "x86_64-linux"
#: libraries every Linux has (the C library and its loader): never bundled
SYSTEM_LIBS = ("linux-vdso", "libc.so", "libm.so", "libpthread", "libdl.so", "librt.so",
               "ld-linux", "libgcc_s")

#: units (FMI 3.0 BaseUnit exponents)
UNITS = {"s": dict(s=1), "m": dict(m=1), "rad": dict(rad=1), "m/s": dict(m=1, s=-1),
         "rad/s": dict(rad=1, s=-1), "kg": dict(kg=1), "kg.m2": dict(kg=1, m=2),
         "N": dict(kg=1, m=1, s=-2), "N.m": dict(kg=1, m=2, s=-2), "J": dict(kg=1, m=2, s=-2),
         "N/m": dict(kg=1, s=-2), "N.s/m": dict(kg=1, s=-1), "m3": dict(m=3)}

#: a force element's values by kind: (field, slot in its table row (0-based, as mbdk.h lists
#: them), unit, a load); loads can be inputs (mbdk_stepper_set_force takes them), the rest are
#: fixed parameters
PLANAR_FIELDS = {
    FORCE_CODES["point_force"]: [("force.x", 2, "N", True), ("force.y", 3, "N", True)],
    FORCE_CODES["torque"]: [("torque", 0, "N.m", True)],
    FORCE_CODES["spring_damper"]: [("stiffness", 4, "N/m", False),
                                   ("damping", 6, "N.s/m", False)],
    FORCE_CODES["spring"]: [("stiffness", 4, "N/m", False)],
    FORCE_CODES["damper"]: [("damping", 6, "N.s/m", False)],
    # a coordinate's spring: N/m or N.m/rad as the coordinate is a length or an angle
    FORCE_CODES["coordinate_spring_damper"]: [("stiffness", 0, None, False),
                                              ("damping", 1, None, False)],
}
SPATIAL_FIELDS = {
    SPATIAL_FORCE_CODES["point_force"]: [(f"force.{c}", 3 + k, "N", True)
                                         for k, c in enumerate("xyz")],
    SPATIAL_FORCE_CODES["torque"]: [(f"torque.{c}", k, "N.m", True) for k, c in enumerate("xyz")],
    SPATIAL_FORCE_CODES["spring_damper"]: [("stiffness", 6, "N/m", False),
                                           ("damping", 7, "N.s/m", False),
                                           ("rest_length", 8, "m", False)],
}
#: mbdk_stepper_outputs' values (mbdk.h), and 5: their energy sum
OUTPUTS = [("energy.kinetic", 0, "J"), ("energy.gravity", 1, "J"), ("energy.spring", 2, "J"),
           ("energy.total", 5, "J"), ("residual.position", 3, None),
           ("residual.velocity", 4, None)]


@dataclass
class Variable:
    name: str
    kind: str               # fmu.txt's KIND (kernel/src/fmi/mbdk_fmi3.c)
    i: int = 0
    j: int = 0
    causality: str = "output"
    unit: str | None = None
    start: float | None = None
    description: str = ""


def binary_path() -> Path:
    """The FMU binary built with this copy of mbdk (beside its compiled kernel)."""
    path = Path(_kernel.__file__).parent / BINARY
    if not path.exists():
        raise InvalidInputError(f"{path}: mbdk's FMU binary is missing; this copy of mbdk was "
                                "built without it (meson.build's mbdk_fmi3): rebuild mbdk")
    return path


def export_fmu(scene, out, method: str = "rk4", h: float | None = None,
               formulation: str | None = None, inputs=(), t0: float = 0.0,
               stop_time: float = 1.0, step_size: float | None = None, bundle: bool = True,
               **options) -> Path:
    """Write scene (a :class:`~mbdk.scene.Scene`, a built-in scene's name or a scene file) as an
    FMI 3.0 co-simulation FMU at out (``.fmu``), whole or not at all.

    method, h, formulation and options are :func:`mbdk.simulate`'s (a fixed-step ODE method or
    the index-3 family); inputs names the loads that become inputs (a force element's name, all
    its load components, or ``NAME.FIELD``); t0 is the time of the FMU's initial state;
    stop_time and step_size (the communication step: a multiple of h, 0.01 s by default) go to
    the model description's default experiment; bundle copies the binary's shared libraries
    into the FMU (module docstring). Returns out."""
    sc = checked(scene_or_file(scene) if not isinstance(scene, Scene) else scene)
    out = check_writable(Path(out), (".fmu",))
    t0 = checks.real("t0", t0)
    stop_time = checks.real("stop_time", stop_time, positive=True)
    try:
        req = Request(method=method, t_end=t0 + stop_time, h=h, formulation=formulation, t0=t0,
                      **options)
    except TypeError as exc:
        raise InvalidInputError(f"export_fmu: {exc}; the options are simulate's") from None
    if req.coordinates != "absolute":
        raise NotApplicableError(f"export_fmu: coordinates = {req.coordinates!r}: an FMU steps "
                                 "its scene by the kernel's C stepper, in absolute coordinates; "
                                 "leave coordinates out")
    plan = make_plan(sc, req)
    _check_plan(plan, method)
    h = plan.index3_options.h if plan.index3 else plan.ode_options.h
    if step_size is None:
        step_size = h * max(1, round(0.01 / h))
    step_size = checks.real("step_size", step_size, positive=True)
    if abs(step_size / h - round(step_size / h)) > 1e-9 or round(step_size / h) < 1:
        raise InvalidInputError(f"step_size = {step_size!r}: give a multiple of h = {h!r} (the "
                                "default experiment's communication step)")
    variables = _variables(sc, _input_set(sc, inputs), h)
    binary = binary_path()
    ident = _identifier(sc.name)
    with tempfile.TemporaryDirectory() as tmp:
        tables = write_tables(sc, Path(tmp) / "scene.tables.toml", t0)
        run = _run_text(plan, variables)
        token = str(uuid.uuid5(uuid.NAMESPACE_URL, "mbdk-fmu:" + hashlib.sha256(
            tables.read_bytes() + run.encode()).hexdigest()))
        xml = _model_description(sc, plan, variables, ident, token, t0, stop_time, step_size, h)
        libs = _bundled_libraries(binary) if bundle else []

        def write(path):
            with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED, compresslevel=6) as z:
                z.writestr("modelDescription.xml", xml)
                if libs:
                    z.writestr(f"binaries/{PLATFORM}/{ident}.so", _origin_first(binary))
                else:
                    z.write(binary, f"binaries/{PLATFORM}/{ident}.so")
                for name, lib in libs:
                    z.write(lib, f"binaries/{PLATFORM}/{name}")
                z.write(tables, "resources/scene.tables.toml")
                z.writestr("resources/fmu.txt", run)
        write_atomic(out, write)
    return out


def _check_plan(plan, method: str) -> None:
    if plan.dae:
        raise InvalidInputError(
            f"method {method!r} solves the DAE over a whole interval: an FMU steps with a "
            "fixed-step ODE method (rk4, heun, euler, ...) on a formulation, or the index-3 "
            "family (trapezoidal_index3, newmark, hht, generalized_alpha)")
    if plan.adaptive or (not plan.index3 and plan.info.adaptive):
        raise InvalidInputError(
            f"method {method!r} controls its own steps over a whole interval: an FMU steps with "
            "a fixed step h (rk4, heun, euler, ... or the index-3 family without adaptive)")
    if plan.times.size:
        raise InvalidInputError("t_eval does not apply to an FMU: its master chooses the "
                                "communication points")


def _identifier(name: str) -> str:
    ident = re.sub(r"\W", "_", name) or "scene"
    return ident if not ident[0].isdigit() else "scene_" + ident


def _input_set(sc: Scene, inputs) -> set:
    """(force index, field) of every input asked for; unknown names refused by name."""
    if isinstance(inputs, str):
        inputs = [inputs]
    fields_of = SPATIAL_FIELDS if sc.kind == "spatial" else PLANAR_FIELDS
    codes = SPATIAL_FORCE_CODES if sc.kind == "spatial" else FORCE_CODES
    names = {_force_name(f, k): k for k, f in enumerate(sc.forces)}
    chosen = set()
    for item in inputs:
        elem, _, fld = str(item).partition(".")
        if str(item) in names:
            elem, fld = str(item), ""
        k = names.get(elem)
        if k is None:
            raise InvalidInputError(f"inputs: {sc.source} has no force element named {elem!r} "
                                    f"(its forces: {', '.join(names) or 'none'})")
        loads = [f for f, _s, _u, load in fields_of.get(codes.get(sc.forces[k].type), [])
                 if load]
        if not loads:
            raise InvalidInputError(
                f"inputs: {elem!r} is a {sc.forces[k].type}: only point forces and torques can "
                "be inputs (their values enter no assembly and no potential)")
        if fld and fld not in loads:
            raise InvalidInputError(f"inputs: {elem!r} has no load field {fld!r} (its fields: "
                                    f"{', '.join(loads)})")
        chosen.update((k, f) for f in loads if not fld or f == fld)
    return chosen


def _force_name(f, k: int) -> str:
    return f.name or f"force{k + 1}"


def _variables(sc: Scene, inputs: set, h: float) -> list:
    """Every variable of the FMU, time first (value reference = position)."""
    spatial = sc.kind == "spatial"
    tab = scene_tables(sc)
    v = [Variable("time", "time", causality="independent", unit="s")]
    for b, body in enumerate(sc.bodies):
        v.append(Variable(f"{body.name}.mass", "mass", b, causality="parameter", unit="kg",
                          start=float(tab["mass"][b])))
        if not spatial:
            v.append(Variable(f"{body.name}.inertia", "inertia", b, causality="parameter",
                              unit="kg.m2", start=float(tab["inertia"][b])))
    freal = np.asarray(tab["freal"], float).reshape(tab["nf"], 19 if spatial else 12)
    ftype = (np.asarray(tab["ftype"]) if spatial
             else np.asarray(tab["fint"]).reshape(tab["nf"], -1)[:, 0])
    table = SPATIAL_FIELDS if spatial else PLANAR_FIELDS
    for k, f in enumerate(sc.forces):
        for fld, slot, unit, load in table.get(int(ftype[k]), []):
            is_input = (k, fld) in inputs
            v.append(Variable(f"{_force_name(f, k)}.{fld}", "input" if is_input else "freal", k,
                              slot, "input" if is_input else "parameter", unit,
                              float(freal[k, slot]),
                              f"{f.type} {'load' if load else 'value'} (force table row "
                              f"{k + 1}, slot {slot + 1})"))
    v.append(Variable("step", "step", causality="parameter", unit="s", start=h,
                      description="the kernel's step h (communication steps are cut into it)"))
    for i, (name, unit, description) in enumerate(state_components(sc)):
        v.append(Variable(name, "y", i, unit=unit, description=description))
    for name, first, count in sc.joint_rows():
        for r in range(count):
            v.append(Variable(f"{name}.lambda[{r + 1}]", "lambda", first + r,
                              description="the joint row's Lagrange multiplier"))
    if not spatial:
        for j, joint in enumerate(sc.joints):
            for c, (comp, unit) in enumerate([("Fx", "N"), ("Fy", "N"), ("M", "N.m")]):
                v.append(Variable(f"{joint.name}.reaction.{comp}", "reaction", j, c, unit=unit,
                                  description="on its first body, global frame; the moment "
                                              "about the joint point"))
    for name, idx, unit in OUTPUTS:
        v.append(Variable(name, "out", idx, unit=unit))
    seen = set()
    for x in v:
        if x.name in seen:
            raise InvalidInputError(f"{sc.source}: two FMU variables would be named {x.name!r}: "
                                    "give the scene's elements distinct names")
        seen.add(x.name)
    return v


def state_components(sc: Scene) -> list:
    """(name, unit, description) of each component of the FMU's state outputs, in the kernel's
    order: the bodies' coordinates, their velocities, the wear elements' volumes."""
    if sc.kind == "spatial":
        orient = ([("p0", None), ("p1", None), ("p2", None), ("p3", None)]
                  if sc.rotation == "quaternion"
                  else [("angle1", "rad"), ("angle2", "rad"), ("angle3", "rad")])
        q = [("x", "m", ""), ("y", "m", ""), ("z", "m", ""), *((o, u, "") for o, u in orient)]
        v = [("vx", "m/s", ""), ("vy", "m/s", ""), ("vz", "m/s", ""),
             *((f"w{c}", "rad/s", "body frame") for c in "xyz")]
    else:
        q = [("x", "m", ""), ("y", "m", ""), ("angle", "rad", "")]
        v = [("vx", "m/s", ""), ("vy", "m/s", ""), ("omega", "rad/s", "")]
    return ([(f"{b.name}.{c}", u, d) for part in (q, v) for b in sc.bodies for c, u, d in part]
            + [(f"{w.name}.volume", "m3", "worn volume") for w in sc.wear])


def _run_text(plan, variables: list) -> str:
    structs = [plan.index3_options if plan.index3 else plan.ode_options,
               plan.spatial_options if plan.kind == "spatial" else plan.model_options]
    lines = [f"mbdk-fmu 1", f"# mbdk {package_version()}: method {plan.method}, formulation "
             f"{plan.formulation}", f"index3 {int(plan.index3)}"]
    for s in structs:
        sid = STRUCT_IDS[s._cname]
        for f in fields(s):
            name, value = f.name, getattr(s, f.name)
            if isinstance(value, (bool, np.bool_)):
                value = int(value)
            if isinstance(value, (float, np.floating)):
                text = repr(float(value))
            elif isinstance(value, (int, np.integer)):
                text = str(int(value))
            else:
                continue
            lines.append(f"opt {sid} {name} {text}")
    if not plan.index3:
        # the method travels beside the struct in simulate's call (the f2py entry's method_id)
        lines.append(f"opt {STRUCT_IDS['mbdk_options']} method {plan.info.id}")
    lines += [f"var {vr} {x.kind} {x.i} {x.j}" for vr, x in enumerate(variables)]
    return "\n".join(lines) + "\n"


def _model_description(sc, plan, variables, ident, token, t0, stop_time, step_size, h) -> str:
    now = datetime.datetime.now(datetime.timezone.utc).replace(microsecond=0).isoformat()
    # a method of several past steps takes whole steps of h only (communication points on the
    # grid t0 + k h)
    variable = "false" if plan.info.steps > 1 else "true"
    used = sorted({x.unit for x in variables if x.unit})
    desc = (sc.description or sc.name) + f" (mbdk {plan.method}, {plan.formulation}, h = {h:g} s)"
    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f'<fmiModelDescription fmiVersion="3.0" modelName={quoteattr(sc.name)} '
           f'instantiationToken="{{{token}}}" description={quoteattr(desc)} '
           f'generationTool="mbdk {package_version()}" generationDateAndTime="{now}" '
           'variableNamingConvention="flat">',
           f'  <CoSimulation modelIdentifier="{ident}" canHandleVariableCommunicationStepSize='
           f'"{variable}" canGetAndSetFMUState="true" canSerializeFMUState="false" '
           f'fixedInternalStepSize="{h!r}" hasEventMode="false" '
           'providesIntermediateUpdate="false" canReturnEarlyAfterIntermediateUpdate="false"/>',
           '  <UnitDefinitions>']
    for u in used:
        exps = " ".join(f'{k}="{e}"' for k, e in UNITS[u].items())
        out.append(f'    <Unit name="{u}"><BaseUnit {exps}/></Unit>')
    out += ['  </UnitDefinitions>',
            '  <LogCategories>',
            '    <Category name="logStatusError" description="the kernel\'s failures: status, '
            'message, the watch\'s report"/>',
            '  </LogCategories>',
            f'  <DefaultExperiment startTime="{t0!r}" stopTime="{t0 + stop_time!r}" '
            f'stepSize="{step_size!r}"/>',
            '  <ModelVariables>']
    for vr, x in enumerate(variables):
        attrs = [f'name={quoteattr(x.name)}', f'valueReference="{vr}"']
        if x.description:
            attrs.append(f"description={quoteattr(x.description)}")
        attrs.append(f'causality="{x.causality}"')
        if x.causality == "parameter":
            attrs.append('variability="fixed"')
        else:
            attrs.append('variability="continuous"')
        if x.unit:
            attrs.append(f'unit="{x.unit}"')
        if x.start is not None:
            attrs.append(f'start="{float(x.start)!r}"')
        out.append(f'    <Float64 {" ".join(attrs)}/>')
    out += ['  </ModelVariables>', '  <ModelStructure>']
    outputs = [vr for vr, x in enumerate(variables) if x.causality == "output"]
    out += [f'    <Output valueReference="{vr}"/>' for vr in outputs]
    out += [f'    <InitialUnknown valueReference="{vr}"/>' for vr in outputs]
    out += ['  </ModelStructure>', '</fmiModelDescription>']
    return "\n".join(out) + "\n"


def _bundled_libraries(binary: Path) -> list:
    """(name, path) of the shared libraries the binary loads beyond SYSTEM_LIBS, by ldd."""
    if not sys.platform.startswith("linux"):
        raise InvalidInputError("bundle=True reads the binary's libraries with ldd (Linux): "
                                "give bundle=False")
    ldd = shutil.which("ldd")
    if ldd is None:
        raise InvalidInputError("bundle=True needs ldd to find the binary's libraries: install "
                                "libc-bin, or give bundle=False")
    run = subprocess.run([ldd, str(binary)], capture_output=True, text=True, check=False)
    libs = []
    for line in run.stdout.splitlines():
        name, arrow, rest = line.strip().partition(" => ")
        if not arrow or any(name.startswith(s) for s in SYSTEM_LIBS):
            continue
        path = rest.split(" (")[0].strip()
        if path == "not found" or not Path(path).exists():
            raise InvalidInputError(f"{binary}: its library {name} is not found (ldd): the FMU "
                                    "could not carry it")
        libs.append((name, Path(path).resolve()))
    return libs


def _origin_first(binary: Path) -> bytes:
    """The binary with $ORIGIN first in its RPATH, so that the libraries bundled beside it win
    over a system's copies in the folders the build put ahead of it (meson.build). The
    RPATH's folders are reordered in place: the string keeps its length and offset."""
    data = binary.read_bytes()
    found = list(re.finditer(rb"([^\0]*)\$ORIGIN\0", data))
    if len(found) != 1:
        raise InvalidInputError(f"{binary}: its RPATH with $ORIGIN was not found once (found "
                                f"{len(found)}): the bundled libraries could not be put first")
    m = found[0]
    parts = m.group(0)[:-1].split(b":")
    new = b":".join([b"$ORIGIN", *(p for p in parts if p != b"$ORIGIN")])
    assert len(new) == len(m.group(0)) - 1
    return data[:m.start()] + new + data[m.end() - 1:]


def fields_of(kind: str) -> dict:
    """The parameter and input fields by force kind (documentation and tests)."""
    return SPATIAL_FIELDS if kind == "spatial" else PLANAR_FIELDS


__all__ = ["export_fmu", "binary_path", "fields_of", "state_components"]
