"""What a scene run must keep, watched in the kernel while it runs
(kernel/src/model/mbdk_watch.f90).

Every run checks, every few steps and at every sample, that the state stays on the constraint
manifold, that the energy balance holds and that what the scene conserves stays conserved::

    position   |Phi_i| <= position * L_i         (L_i: the mechanism's length scale L, or 1 rad)
    velocity   |D v + Phi_t|_i <= velocity * V_i (V_i: the largest size its terms reached)
    energy     |E - E0 - W| <= energy * S        (W: work of dampers, loads and drivers,
                                                 integrated at every step; S: the energy of the
                                                 motion, at least the initial kinetic and
                                                 spring energy plus sum m |g| L_g)
    momentum   |c - c0| <= momentum * S_c        (c: each component of the momentum and
                                                 angular momentum the scene conserves; S_c the
                                                 largest size of its terms, sum m |v| or
                                                 sum |r - c| m |v| + |J w|)
    quaternion ||p| - 1| <= quaternion           (spatial bodies with quaternions)

Which components a scene conserves the kernel decides from its elements (the header of
kernel/src/model/mbdk_watch.f90 gives the rule; result.manifest["invariants"] lists them): a free
body keeps all of its momentum and angular momentum, a heavy top on its tip the vertical angular
momentum about the tip, a pendulum under gravity none.

A run that leaves them stops with ``ConstraintDriftError``, ``EnergyDriftError`` or
``InvariantDriftError`` at the check where it happened, naming the time, the value against its
tolerance and the joint, the invariant or the body; every sample it returns passed its checks
(``raise_on_failure=False`` gives them). ``watch=False`` turns the watch off (a study that shows
a method's drift does so, and says so); ``watch=mbdk.Watch(position=1e-6)`` tightens one test,
``None`` in a field turns that test off.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from numbers import Integral

from .checks import number_problem, show
from .errors import InvalidInputError
from .options import ModelOptions

_DEFAULTS = ModelOptions()
QUANTITIES = {1: "position", 2: "velocity", 3: "energy", 4: "momentum", 5: "quaternion"}
#: the default tolerance of | |p| - 1 | (the spatial model's, kernel/src/spatial)
QUATERNION = 0.1
#: the conserved components' kinds (mbdk_watch.f90: MBDK_INV_*)
_MOMENTUM, _ANGULAR_POINT, _ANGULAR_CENTRE = 1, 2, 3


@dataclass(frozen=True)
class Watch:
    """Tolerances of what a run must keep; the defaults are the kernel's (ModelOptions)."""

    position: float | None = _DEFAULTS.watch_position
    velocity: float | None = _DEFAULTS.watch_velocity
    energy: float | None = _DEFAULTS.watch_energy
    every: int = _DEFAULTS.watch_every
    momentum: float | None = _DEFAULTS.watch_momentum
    quaternion: float | None = QUATERNION

    def options(self) -> dict:
        """The ModelOptions fields (a test turned off is 0 there); quaternion is the spatial
        model's (planar bodies have none)."""
        return {"watch_position": float(self.position or 0.0),
                "watch_velocity": float(self.velocity or 0.0),
                "watch_energy": float(self.energy or 0.0), "watch_every": int(self.every),
                "watch_momentum": float(self.momentum or 0.0)}


OFF = Watch(None, None, None, momentum=None, quaternion=None)


def as_watch(watch) -> Watch:
    """simulate's watch= argument as a Watch: True (the defaults), False or None (off), a Watch,
    or a dict of its fields."""
    if watch is True:
        return Watch()
    if watch is False or watch is None:
        return OFF
    if isinstance(watch, dict):
        bad = {k for k in watch if not isinstance(k, str)} or \
            set(watch) - {f.name for f in fields(Watch)}
        if bad:
            raise InvalidInputError(f"watch: {', '.join(sorted(map(repr, bad)))} unknown; known: "
                                    f"{', '.join(f.name for f in fields(Watch))}")
        watch = Watch(**watch)
    if not isinstance(watch, Watch):
        raise InvalidInputError(f"watch = {watch!r} must be True, False, a mbdk.Watch or a dict "
                                "of its fields")
    for name in ("position", "velocity", "energy", "momentum", "quaternion"):
        v = getattr(watch, name)
        if v is not None and (number_problem(v, in_range=False) or not v > 0):
            raise InvalidInputError(f"watch.{name} = {show(v)} must be a finite number > 0, or "
                                    "None to turn that test off")
    if isinstance(watch.every, bool) or not isinstance(watch.every, Integral) or \
            not 1 <= watch.every <= 2**31 - 1:
        raise InvalidInputError(f"watch.every = {watch.every!r} must be a whole number >= 1")
    return watch


def invariant_names(invariants) -> list[str]:
    """The kernel's conserved components (rows of kind, direction (3), point (3)) in words."""
    def vec(x):   # (a -0 or a roundoff-sized entry printed as 0)
        return "(" + ", ".join(f"{0.0 if abs(c) < 1e-15 else c:.6g}" for c in x) + ")"
    names = []
    for row in invariants:
        kind, e, p = int(round(row[0])), row[1:4], row[4:7]
        unit = tuple(int(round(c)) if abs(abs(c) - 1) < 1e-12 or abs(c) < 1e-12 else 9
                     for c in e)
        axis = {(1, 0, 0): "x", (0, 1, 0): "y", (0, 0, 1): "z"}.get(unit)
        along = f"along {axis}" if axis else f"along {vec(e)}"
        if kind == _MOMENTUM:
            names.append(f"momentum {along}")
        elif kind == _ANGULAR_POINT:
            names.append(f"angular momentum {along} about the fixed point {vec(p)}")
        else:
            names.append(f"angular momentum {along} about the centre of mass")
    return names


def _row_name(report, joint_rows, invariants, bodies):
    """What the report's row counts, in words: (joint, its row) for a constraint row, the
    conserved component for momentum, the body for a quaternion."""
    what, row = report["quantity"], report["row"]
    if row <= 0:
        return None
    if what == 4:
        names = invariant_names(invariants)
        return names[row - 1] if row <= len(names) else None
    if what == 5:
        return bodies[row - 1] if row <= len(bodies) else f"body {row}"
    r = row - 1
    for jname, first, count in joint_rows:
        if first <= r < first + count:
            return (jname, r - first + 1, count)
    return None


def drift_report(report, joint_rows, invariants=(), bodies=()) -> dict:
    """The kernel's report of a failed check (mbdk_watch_report_t, by name) in the result's
    words: quantity ("position", "velocity", "energy", "momentum", "quaternion"), t (of the
    failed check), t_good (of the last check passed), value (relative to its scale), tolerance,
    absolute (the residual, |E - E0 - W|, |c - c0| or | |p| - 1 | itself), scale, for a
    constraint row the joint and its row (1-based), for momentum the invariant (its name), for
    a quaternion the body."""
    what = report["quantity"]
    out = {"quantity": QUANTITIES.get(what, "?"), "t": report["t"], "t_good": report["t_good"],
           "value": report["value"], "tolerance": report["tol"],
           "absolute": report["absolute"], "scale": report["scale"], "joint": None, "row": None}
    name = _row_name(report, joint_rows, invariants, bodies)
    if what == 4:
        out["invariant"] = name
    elif what == 5:
        out["body"] = name
    elif name is not None:
        out["joint"], out["row"] = name[0], name[1]
    return out


def drift_message(report, joint_rows, invariants=(), bodies=()) -> str:
    """The kernel's report of a failed check (mbdk_watch_report_t, by name) in words.
    joint_rows: (joint name, first row, count) of the scene's joints; invariants: the kernel's
    conserved components; bodies: the bodies' names."""
    value, tol, t_bad, t_good = report["value"], report["tol"], report["t"], report["t_good"]
    absolute, scale = report["absolute"], report["scale"]
    name = QUANTITIES.get(report["quantity"], "?")
    where = ""
    row_name = _row_name(report, joint_rows, invariants, bodies)
    if name in ("position", "velocity") and row_name is not None:
        jname, r, count = row_name
        where = f" in joint {jname!r} (its row {r} of {count})"
    what_scale = {"position": f"|Phi| = {absolute:.3g} against the length scale {scale:.3g} "
                              "(m; 1 rad for an angle row)",
                  "velocity": f"|D v + Phi_t| = {absolute:.3g} against the size of its terms "
                              f"{scale:.3g}",
                  "energy": f"|E - E0 - W| = {absolute:.3g} J against the energy scale "
                            f"{scale:.3g} J",
                  "momentum": f"|c - c0| = {absolute:.3g} against the size of its terms "
                              f"{scale:.3g} (kg m/s; kg m^2/s for an angular momentum)",
                  "quaternion": f"| |p| - 1 | = {absolute:.3g}"}.get(name, "")
    if name == "momentum":
        head = (f"the {row_name or 'conserved momentum'}, which the scene conserves, changed "
                f"by {value:.3g} of its scale")
    elif name == "quaternion":
        head = (f"the quaternion of body {row_name!r} left its unit norm by {value:.3g}"
                if row_name else f"a quaternion left its unit norm by {value:.3g}")
    else:
        head = (f"the {name} {'residual' if name != 'energy' else 'balance'} reached "
                f"{value:.3g}")
    return (f"{head} ({what_scale}; tolerance {tol:.3g}) at t = {t_bad:.6g}{where}; the last "
            f"check passed at t = {t_good:.6g}, and the samples returned end there or before")
