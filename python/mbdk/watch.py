"""What a scene run must keep, watched in the kernel while it runs
(kernel/src/model/mbdk_watch.f90).

Every run checks, every few steps and at every sample, that the state stays on the constraint
manifold and that the energy balance holds:

    position   |Phi_i| <= position * L_i         (L_i: the mechanism's length scale L, or 1 rad)
    velocity   |D v + Phi_t|_i <= velocity * V_i (V_i: the largest size its terms reached)
    energy     |E - E0 - W| <= energy * S        (W: work of dampers, loads and drivers;
                                                 S: the energy scale, at least sum m |g| L)

A run that leaves them stops with ``ConstraintDriftError`` or ``EnergyDriftError`` at the check
where it happened, naming the time, the value against its tolerance and the joint; every
sample it returns passed its checks (``raise_on_failure=False`` gives them). ``watch=False``
turns the watch off (a study that shows a method's drift does so, and says so);
``watch=mbdk.Watch(position=1e-6)`` tightens one test, ``None`` in a field turns that test off.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from numbers import Integral

from .checks import number_problem, show
from .errors import InvalidInputError
from .options import ModelOptions

_DEFAULTS = ModelOptions()
QUANTITIES = {1: "position", 2: "velocity", 3: "energy"}


@dataclass(frozen=True)
class Watch:
    """Tolerances of what a run must keep; the defaults are the kernel's (ModelOptions)."""

    position: float | None = _DEFAULTS.watch_position
    velocity: float | None = _DEFAULTS.watch_velocity
    energy: float | None = _DEFAULTS.watch_energy
    every: int = _DEFAULTS.watch_every

    def options(self) -> dict:
        """The ModelOptions fields (a test turned off is 0 there)."""
        return {"watch_position": float(self.position or 0.0),
                "watch_velocity": float(self.velocity or 0.0),
                "watch_energy": float(self.energy or 0.0), "watch_every": int(self.every)}


OFF = Watch(None, None, None)


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
    for name in ("position", "velocity", "energy"):
        v = getattr(watch, name)
        if v is not None and (number_problem(v, in_range=False) or not v > 0):
            raise InvalidInputError(f"watch.{name} = {show(v)} must be a finite number > 0, or "
                                    "None to turn that test off")
    if isinstance(watch.every, bool) or not isinstance(watch.every, Integral) or \
            not 1 <= watch.every <= 2**31 - 1:
        raise InvalidInputError(f"watch.every = {watch.every!r} must be a whole number >= 1")
    return watch


def drift_report(report, joint_rows) -> dict:
    """The kernel's report of a failed check as a dict: quantity ("position", "velocity",
    "energy"), t (of the failed check), t_good (of the last check passed), value (relative to
    its scale), tolerance, absolute (the residual or |E - E0 - W| itself), scale, and for a
    constraint row the joint and its row (1-based)."""
    what, row, value, tol, t_bad, t_good, absolute, scale = (float(x) for x in report)
    out = {"quantity": QUANTITIES.get(int(what), "?"), "t": t_bad, "t_good": t_good,
           "value": value, "tolerance": tol, "absolute": absolute, "scale": scale,
           "joint": None, "row": None}
    if int(row) > 0:
        r = int(row) - 1
        for jname, first, count in joint_rows:
            if first <= r < first + count:
                out["joint"], out["row"] = jname, r - first + 1
    return out


def drift_message(report, joint_rows) -> str:
    """The kernel's report of a failed check (what, row, value, tol, t, t_good, the value itself,
    its scale) in words. joint_rows: (joint name, first row, count) of the scene's joints."""
    what, row, value, tol, t_bad, t_good, absolute, scale = (float(x) for x in report)
    name = QUANTITIES.get(int(what), "?")
    where = ""
    if int(row) > 0:
        r = int(row) - 1
        for jname, first, count in joint_rows:
            if first <= r < first + count:
                where = f" in joint {jname!r} (its row {r - first + 1} of {count})"
    what_scale = {"position": f"|Phi| = {absolute:.3g} against the length scale {scale:.3g} "
                              "(m; 1 rad for an angle row)",
                  "velocity": f"|D v + Phi_t| = {absolute:.3g} against the size of its terms "
                              f"{scale:.3g}",
                  "energy": f"|E - E0 - W| = {absolute:.3g} J against the energy scale "
                            f"{scale:.3g} J"}.get(name, "")
    return (f"the {name} {'residual' if name != 'energy' else 'balance'} reached {value:.3g} "
            f"({what_scale}; tolerance {tol:.3g}) at t = {t_bad:.6g}{where}; the last check "
            f"passed at t = {t_good:.6g}, and the samples returned end there or before")
