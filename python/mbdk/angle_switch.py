"""Spatial runs in angle coordinates past their gimbal lock (simulate's switch_angles): segments
in alternating angle sets, joined into one result.

switch_angles (angle sets only) is a distance d from the gimbal lock (|sin theta| for 3-1-3,
|cos beta| for 1-2-3; e.g. 0.1). The run stops where the bodies' angles come within d of their
set's lock and goes on from its last sample in the other set, whose lock is elsewhere (the 3-1-3
lock is an orientation where the 1-2-3 beta is near 0, and back), as often as the motion asks;
result.rotations gives each sample's set, result.manifest["switches"] the times. Not with
drivers (a driver starts from f(t0) = 0).
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import Callable

import numpy as np

from .errors import InvalidInputError, NotApplicableError, Status, exception_for
from .methods import method as method_info
from .plan import Request
from .result import SceneResult, Stats
from .scene import DRIVERS, Scene
from .spatial_model import lock_distance

#: runs one segment: (scene, request) -> (result, the text of an AccuracyWarning or None)
SegmentRunner = Callable[[Scene, Request], tuple]


#: the other angle set, whose lock lies elsewhere
_OTHER_SET = {"euler313": "cardan123", "cardan123": "euler313"}


#: the most switches a run may take (a motion that dwells at the locks of both sets would
#: otherwise restart for ever)
MAX_SWITCHES = 1000


def _restarted(sc: Scene, r: SceneResult, k: int, rotation: str) -> Scene:
    """sc with its bodies at sample k of r (position, orientation, velocity, body-frame
    angular velocity), in the angle set rotation, and its wear volumes there."""
    bodies = [replace(b, position=r.position(b.name)[k].copy(),
                      rotation=r.orientation(b.name)[k].copy(),
                      velocity=r.v[k, 6 * i:6 * i + 3].copy(),
                      omega_body=r.v[k, 6 * i + 3:6 * i + 6].copy())
              for i, b in enumerate(sc.bodies)]
    wear = [replace(w, initial=float(r.wear[w.name][k])) for w in sc.wear]
    return replace(sc, bodies=bodies, rotation=rotation, wear=wear)


def _subsampled(r: SceneResult, idx) -> SceneResult:
    """r at the samples idx."""
    return replace(r, t=r.t[idx], q=r.q[idx], v=r.v[idx], energy=r.energy[idx],
                   energy_parts={k: v[idx] for k, v in r.energy_parts.items()},
                   residuals=r.residuals[idx],
                   multipliers=None if r.multipliers is None else r.multipliers[idx],
                   wear={k: v[idx] for k, v in r.wear.items()},
                   contacts={n: {f: v[idx] for f, v in c.items()}
                             for n, c in r.contacts.items()},
                   rotations=[r.rotations[i] for i in idx])


def _joined(segs, switches) -> SceneResult:
    """One result from the segments of a switching run: each segment's last sample is the
    next one's first, kept once."""
    first, last = segs[0][1], segs[-1][1]
    keep = [(rot, r, slice(0, len(r.t) - 1) if i < len(segs) - 1 else slice(None))
            for i, (rot, r) in enumerate(segs)]

    def cat(get):
        parts = [get(r)[s] for _rot, r, s in keep if get(r) is not None]
        return np.concatenate(parts) if parts else None

    def work():   # each segment's work starts at 0 where the one before ended
        parts, before = [], 0.0
        for _rot, r, s in keep:
            w = r.energy_parts["work"]
            parts.append(before + w[s])
            before += float(w[-1]) if len(w) else 0.0
        return np.concatenate(parts)
    stats = Stats(**{f: sum(getattr(r.stats, f) for _rot, r, _s in keep)
                     for f in first.stats.__dataclass_fields__})
    rotations = [rot for rot, r, s in keep for _ in range(len(r.t[s]))]
    manifest = {**first.manifest, "switch_angles": True,
                "switches": [float(x) for x in switches],
                "segments": [{"rotation": rot, "t0": float(r.t[0]) if len(r.t) else None,
                              "steps": r.stats.steps} for rot, r, _s in keep]}
    return SceneResult(
        t=cat(lambda r: r.t), q=cat(lambda r: r.q), v=cat(lambda r: r.v), a=None,
        multipliers=cat(lambda r: r.multipliers), reactions=None,
        energy=cat(lambda r: r.energy),
        energy_parts={k: work() if k == "work" else cat(lambda r, k=k: r.energy_parts[k])
                      for k in first.energy_parts},
        residuals=cat(lambda r: r.residuals), stats=stats, status=last.status,
        message=last.message, manifest=manifest, bodies=first.bodies, joints=first.joints,
        assembly=first.assembly, drift=last.drift, kind="spatial", rotation=first.rotation,
        wear={k: cat(lambda r, k=k: r.wear[k]) for k in first.wear},
        contacts={n: {f: cat(lambda r, n=n, f=f: r.contacts[n][f]) for f in c}
                  for n, c in first.contacts.items()},
        rotations=rotations)



def _check_switching(sc: Scene, guard) -> None:
    """switch_angles on a scene it applies to, as named errors."""
    if sc.rotation not in _OTHER_SET:
        raise InvalidInputError(f"switch_angles = {guard!r}: scene {sc.name!r} uses "
                                f"rotation = {sc.rotation!r}, which has no gimbal lock; it "
                                "applies to euler313 and cardan123")
    if not (isinstance(guard, (int, float)) and not isinstance(guard, bool)
            and 0 < guard < 0.5):
        raise InvalidInputError(f"switch_angles = {guard!r} must be a distance from the lock "
                                "between 0 and 0.5 (|sin theta| or |cos beta|; 0.1 is usual)")
    drivers = [j.name for j in sc.joints if j.type in DRIVERS]
    if drivers:
        raise NotApplicableError(f"switch_angles on scene {sc.name!r}: its drivers "
                                 f"({', '.join(drivers)}) start from f(t0) = 0, which a run "
                                 "restarted mid-way cannot keep; use rotation = 'quaternion'")


def switching_run(sc: Scene, req: Request, run_segment: SegmentRunner) -> tuple:
    """A run with switch_angles (the module docstring): (result, warning text or None)."""
    guard = req.switch_angles
    _check_switching(sc, guard)
    t0, t_end = float(req.t0), float(req.t_end)
    # a segment restarts from its last sample, so the segments sample densely (every step, or
    # 2000 samples of the dense output) and the result keeps the samples asked for
    adaptive = method_info(req.method).adaptive
    seg = replace(req, switch_angles=None, raise_on_failure=False, lock_guard=guard)
    if adaptive:
        dt_user = float(req.dt_out or 0.0)
        inner = (t_end - t0) / 2000
        if dt_user > 0:
            inner = dt_user / max(1, math.ceil(dt_user / inner))
        seg = replace(seg, dt_out=inner)
    else:
        every_user = int(req.every or 1)
        seg = replace(seg, every=1)
    cur, t_start, segs, switches, warning = sc, t0, [], [], None
    if lock_distance(cur, cur.state0()[:6 * len(cur.bodies)]) < guard:
        # a start near the scene's own set's lock: in the other set from the first step
        cur = replace(cur, rotation=_OTHER_SET[cur.rotation])
        switches.append(t_start)
    while True:
        r, said = run_segment(cur, replace(seg, t0=t_start))
        warning = warning or said
        segs.append((cur.rotation, r))
        near = (r.status == Status.ERR_SINGULAR_MATRIX and len(r.t) > 1
                and r.t[-1] > t_start and lock_distance(cur, r.q[-1]) < 2 * guard)
        if not near or len(switches) >= MAX_SWITCHES:
            break
        # from the last sample, in the other set
        t_start = float(r.t[-1])
        cur = _restarted(cur, r, -1, _OTHER_SET[cur.rotation])
        switches.append(t_start)
    result = _joined(segs, switches)
    n = len(result.t)
    if adaptive:
        grid = (np.zeros(n, bool) if dt_user <= 0 else
                np.abs((result.t - t0) / dt_user - np.round((result.t - t0) / dt_user)) < 1e-6)
    else:
        grid = np.round((result.t - t0) / req.h).astype(np.int64) % every_user == 0
    grid[[0, -1]] = True
    result = _subsampled(result, np.flatnonzero(grid))
    if result.status == Status.SUCCESS or not req.raise_on_failure:
        return result, warning
    raise exception_for(result.status)(result.message, status=result.status, result=result)
