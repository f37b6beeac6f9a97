"""Reading work-precision curves: what a method's CPU time is at a given error, and which method
of several reaches an error for the least time.

A curve is a method's runs in the order of its sweep (coarse to fine steps, loose to tight
tolerances), each a point (cpu, error), error None where the run failed. The cost of reaching
a target error is interpolated between neighbouring runs, linearly in log(cpu) against
log(error) (exact for a power law: error ~ h^p at cost ~ 1/h is a straight line there), at
every place where the curve crosses the target downwards; a run that reaches it is a candidate
too, at its own cost (where that is the curve's first run, only a bound: a coarser run might
have reached it for less). Nothing is extrapolated beyond the runs, and no segment spans a failed
run: a target no run reaches is not reached.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Reach:
    """The least CPU time at which a curve has reached an error target: interpolated between
    the runs at index - 1 and index, or measured at the run index; "first run" where that is
    the curve's first run with an error (its cost is then at most this: a coarser run might
    have reached the target too)."""

    cpu: float
    how: str            # "interpolated", "measured" or "first run"
    index: int


def _ok(p) -> bool:
    cpu, err = p
    return (err is not None and cpu is not None and math.isfinite(err) and err > 0
            and math.isfinite(cpu) and cpu > 0)


def cost_to_reach(points, target: float) -> Reach | None:
    """The least CPU time at which the curve `points` ([(cpu, error or None), ...] in sweep
    order) reaches error <= target (module docstring), or None."""
    if not (target > 0 and math.isfinite(target)):
        raise ValueError(f"target = {target!r}: give a positive error")
    best = None
    first = next((i for i, p in enumerate(points) if _ok(p)), None)
    for i, p in enumerate(points):
        if not _ok(p):
            continue
        cpu, err = p
        if err <= target and (best is None or cpu < best.cpu):
            best = Reach(cpu, "first run" if i == first else "measured", i)
        if i and _ok(points[i - 1]):
            c0, e0 = points[i - 1]
            if e0 > target >= err and e0 != err:
                w = math.log(target / e0) / math.log(err / e0)
                c = math.exp(math.log(c0) + w * math.log(cpu / c0))
                if best is None or c < best.cpu:
                    best = Reach(c, "interpolated", i)
    return best


def cheapest(curves: dict, target: float) -> list[tuple[str, Reach]]:
    """The methods whose curves reach the target, cheapest first: [(name, Reach), ...] from
    curves = {name: points}."""
    reached = [(name, r) for name, pts in curves.items()
               if (r := cost_to_reach(pts, target)) is not None]
    return sorted(reached, key=lambda nr: nr[1].cpu)


def error_ratios(a: dict, b: dict) -> list[float]:
    """err_a / err_b at every control (step or tolerance) where both curves have a run with an
    error: a = {control: error or None}, b likewise."""
    out = []
    for c, ea in a.items():
        eb = b.get(c)
        if ea is not None and eb is not None and ea > 0 and eb > 0 and \
                math.isfinite(ea) and math.isfinite(eb):
            out.append(ea / eb)
    return out
