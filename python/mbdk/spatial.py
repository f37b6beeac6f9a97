"""Spatial scene runs (chapter 5 of the book): simulate_spatial, which mbdk.simulate sends a scene
of spatial bodies to. The file format: python/mbdk/spatial_file.py.
"""
from __future__ import annotations

import math

import numpy as np

from . import _compiled, _kernel
from .codes import SPATIAL_DAE_FORMS, SPATIAL_FORMULATIONS
from .errors import (InvalidInputError, NotApplicableError, Status, exception_for,
                     failure_text, status_message, stopped_at)
from .errors import no_memory_message
from .methods import method as _method
from .options import ODEOptions, empty, projection_tol_for
from .result import SceneResult, Stats
from .checks import check_memory, memory_error
from .codes import NORMS, ROTATIONS
from .scene import DRIVERS, Scene
from .spatial_file import validate_spatial
from .spatial_model import (LOCK_MEASURE, check_initial, evaluate_spatial, lock_distance,
                            spatial_tables)


FORMULATIONS = SPATIAL_FORMULATIONS


#: ida's forms on spatial scenes (the spatial_run's dae_form codes; mbdk_ida_solve_spatial)
IDA_FORMS = {form: code for (family, form), code in SPATIAL_DAE_FORMS.items() if family == "ida"}


IDA_FORM_TEXT = {
    "index1": "index 1: q' = T(q) w, w' = M^-1 (f - C^T lam), C w' = gamma on the independent "
              "rows; Phi and C w + Phi_t drift as in the reduced ODE (the watch names it)",
    "ggl": "stabilised index 2 (Gear-Gupta-Leimkuhler): q' = T(q) (w - M^-1 C^T mu), "
           "w' = M^-1 (f - C^T lam), Phi = 0, C w + Phi_t = 0 on the independent rows"}




def simulate_spatial(sc: Scene, method: str, *, h=None, t_end, formulation=None,
                     t0=0.0, every=1, alpha=None, beta=None, projection_tol=None,
                     assemble_initial=True, startup="rk4", rtol=None, atol=None, dt_out=None,
                     h_min=None, h_max=None, max_steps=None, max_order=None, watch=True,
                     raise_on_failure=True, newton_rtol=None, newton_atol=None,
                     outputs=None, penalty=None, switch_angles=None, _lock_guard=0.0,
                     **unsupported) -> SceneResult:
    """Runs a spatial scene (mbdk.simulate sends spatial scenes here; see the module
    docstring). Options of the planar path that do not apply are refused by name; outputs is
    checked and otherwise moot: a spatial run computes every output at its samples.

    switch_angles (angle sets only): a distance d from the gimbal lock (|sin theta| for
    3-1-3, |cos beta| for 1-2-3; e.g. 0.1). The run stops where the bodies' angles come within
    d of their set's lock and goes on from its last sample in the other set, whose lock is
    elsewhere (the 3-1-3 lock is an orientation where the 1-2-3 beta is near 0, and back), as
    often as the motion asks; result.rotations gives each sample's set, result.manifest
    ["switches"] the times. Not with drivers (a driver starts from f(t0) = 0)."""
    if switch_angles is not None:
        return _switching_run(sc, method, switch_angles, dict(
            h=h, t_end=t_end, formulation=formulation, t0=t0, every=every, alpha=alpha,
            beta=beta, projection_tol=projection_tol, assemble_initial=assemble_initial,
            startup=startup, rtol=rtol, atol=atol, dt_out=dt_out, h_min=h_min, h_max=h_max,
            max_steps=max_steps, max_order=max_order, watch=watch,
            raise_on_failure=raise_on_failure, newton_rtol=newton_rtol,
            newton_atol=newton_atol, outputs=outputs, penalty=penalty, **unsupported))
    from .ode import build_info
    from .simulate import _ode_plan, check_run, ggl_multipliers, scene_tolerances
    from .watch import as_watch, drift_message, drift_report, invariant_names

    bad = sorted(k for k, v in unsupported.items() if v is not None)
    if bad:
        raise NotApplicableError(f"{', '.join(bad)}: not options of a spatial scene run (its "
                                 "formulations: reduced, baumgarte, penalty, projection; solver "
                                 "and the index-3 options are the planar model's)")
    if outputs is not None:
        from .simulate import _want
        _want(outputs)
    validate_spatial(sc)
    info_m = _method(method)
    index3 = info_m.family == "dae_index3"
    ida = info_m.family == "ida"
    if info_m.solves != "ode" and not index3 and not ida:
        raise NotApplicableError(
            f"{method} on spatial scene {sc.name!r}: it integrates the planar model's DAE; "
            "spatial scenes run the ODE methods (mbdk.methods('ode')) on the reduced, "
            "baumgarte, penalty or projection formulation, bdf on their DAE itself "
            "(formulations 'i3', 'si2'), ida ('index1', 'ggl') and trapezoidal_index3 "
            "(formulation 'projected')")
    if info_m.family == "euler_cromer":
        raise NotApplicableError(f"euler_cromer on spatial scene {sc.name!r}: its state layout "
                                 "is y = [q, q'], and a spatial body's velocities (v, Omega) are "
                                 "not its coordinates' rates; use symplectic methods on planar "
                                 "scenes, or rk4 here")
    if formulation is not None and not isinstance(formulation, str):
        from .checks import choice
        choice("formulation", formulation,
               ["projected"] if index3 else list(IDA_FORMS) if ida else
               list(FORMULATIONS) + (["i3", "si2"] if info_m.family == "variable_bdf" else []),
               error=NotApplicableError, what=f"a formulation {method} runs on spatial scenes")
    if index3:
        formulation = "projected" if formulation is None else formulation
        if formulation != "projected":
            raise NotApplicableError(
                f"formulation {formulation!r} of trapezoidal_index3 on spatial scene "
                f"{sc.name!r}: spatial scenes take its projected form only ('projected', "
                "kernel/src/spatial/mbdk_spatial_index3.f90); the unprojected book scheme "
                "(index3) and the augmented Lagrangian are the planar model's")
    if ida:
        formulation = "index1" if formulation is None else formulation
        if formulation not in IDA_FORMS:
            raise NotApplicableError(
                f"formulation {formulation!r} of ida on spatial scene {sc.name!r}: ida "
                f"integrates the DAE itself, in the forms {', '.join(IDA_FORMS)}")
    formulation = "reduced" if formulation is None else formulation
    dae = formulation in ("i3", "si2") and info_m.family == "variable_bdf"
    if not isinstance(formulation, str) or (formulation not in FORMULATIONS and not dae
                                            and not index3 and not ida):
        raise NotApplicableError(f"formulation {formulation!r} on spatial scene {sc.name!r}: "
                                 f"spatial scenes run {', '.join(FORMULATIONS)}, and bdf also "
                                 "'i3' and 'si2' (the DAE itself)")
    if penalty is not None and formulation != "penalty":
        raise InvalidInputError(f"penalty = {penalty!r}: an option of the penalty formulation; "
                                f"this run's is {formulation!r}")
    penalty = (1e7, 10.0, 1.0) if penalty is None else penalty
    if method.startswith("cvode") and formulation == "projection":
        raise NotApplicableError(f"{method} with the projection formulation: CVODE cannot "
                                 "change the state between its steps; use reduced or baumgarte")
    if method.startswith("cvode") and sc.rotation == "quaternion" and \
            sc.quaternion_norm == "project":
        raise NotApplicableError(f"{method} on spatial scene {sc.name!r} with quaternion_norm = "
                                 "'project': CVODE cannot change the state between its steps; "
                                 "set the scene's quaternion_norm to 'stabilise' or 'none'")
    if info_m.adaptive:
        if every != 1:
            raise InvalidInputError(f"every = {every!r}: {method} chooses its own steps; give "
                                    "dt_out (the spacing of the samples) instead")
        if formulation == "baumgarte" and (alpha is None or beta is None):
            raise InvalidInputError(f"{method} with formulation 'baumgarte': give alpha and "
                                    "beta (Baumgarte's defaults 1/h and sqrt(2)/h need a fixed "
                                    "step; an error-controlled method has none)")
        check_run(1.0 if not h else h, t_end, t0, 1)
        rtol, atol = scene_tolerances(rtol, atol)
        adaptive = dict(h=h, rtol=rtol, atol=atol, dt_out=dt_out or 0.0, h_min=h_min or 0.0,
                        h_max=h_max or 0.0, max_steps=max_steps or 0, max_order=max_order or 0)
        href = 1e-3 * (t_end - t0)
    else:
        given = [n for n, v in (("rtol", rtol), ("atol", atol), ("dt_out", dt_out),
                                ("max_steps", max_steps), ("max_order", max_order)) if v]
        if given:
            raise InvalidInputError(f"{', '.join(given)}: options of the error-controlled "
                                    f"methods; {method} takes a fixed step h")
        if h is None:
            raise InvalidInputError(f"{method} takes a fixed step: give h")
        check_run(h, t_end, t0, every)
        adaptive = None
        href = h
    projection_tol = projection_tol_for(
        projection_tol, (ODEOptions.atol if atol is None else atol) if info_m.adaptive else None)
    plan_ = _ode_plan(info_m, formulation, href, t_end, t0, int(every), alpha, beta,
                      penalty, projection_tol, startup, newton_rtol, newton_atol, adaptive)
    opt = plan_["ode"]
    from dataclasses import replace
    opt = replace(opt, method=info_m.id)
    w = as_watch(watch)
    model_form = "reduced" if dae or ida else "projection" if index3 else formulation
    sopt = np.array([FORMULATIONS[model_form], ROTATIONS[sc.rotation],
                     NORMS[sc.quaternion_norm],
                     plan_["alpha"], plan_["beta"], sc.norm_gain, projection_tol,
                     w.position or 0.0, w.velocity or 0.0, w.energy or 0.0, w.every,
                     *penalty, float(_lock_guard), w.momentum or 0.0, w.quaternion or 0.0],
                    dtype=float)
    nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal = spatial_tables(sc)
    y0 = sc.state0()
    check_initial(sc, y0, assemble_initial, float(t0))
    stats, flag = empty("mbdk_stats"), _compiled.new_flag()
    m1 = max(sc.rows, 1)
    nsamp = plan_["nsamp"]
    args = (mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal, sopt, opt.pack(),
            flag, np.zeros(0), y0, int(bool(assemble_initial)),
            SPATIAL_DAE_FORMS[(method, formulation)] if index3 or ida or dae else 0, float(t0),
            float(t_end), nsamp, m1, stats)
    # the samples (t, y, the outputs and the multipliers, allocated by the f2py layer): refused
    # before they are allocated where the machine has not that much memory
    from .simulate import SCENE_SAMPLE_ADVICE
    nbytes = 8.0 * nsamp * (1 + len(y0) + 8 + m1)   # spatial_run's out(8, nsamp)
    what = f"{method} on spatial scene {sc.name!r} ({nsamp} samples)"
    advice = SCENE_SAMPLE_ADVICE.split(", or fewer outputs")[0]
    check_memory(nbytes, what=what, change=advice)
    try:
        (t, y, out, lam, nw, moved, report, invariants, ninv, status), interrupted = \
            _compiled.call(_kernel.spatial_run, args, flag, plan_["steps"] * len(y0),
                           span=(t0, t_end))
    except MemoryError as exc:
        raise memory_error(exc, nbytes, what=what, change=advice) from None
    status = Status(int(status))
    nqb = 7 if sc.rotation == "quaternion" else 6
    nq = nb * nqb
    ys = y[:, :nw].T
    o = out[:, :nw].T
    manifest = {**build_info(), "scene": sc.name, "kind": "spatial", "method": method,
                "formulation": formulation, "rotation": sc.rotation,
                **({"h": h, "every": int(every)} if not info_m.adaptive else {}),
                "quaternion_norm": ("none (bdf on the DAE: no projection between its steps)"
                                    if dae and sc.quaternion_norm == "project"
                                    else sc.quaternion_norm), "t0": t0, "t_end": t_end,
                **plan_["manifest"],
                "linear_solve": ("dense M + alpha_p C^T C (LAPACK dpotrf)"
                                 if formulation == "penalty" else
                                 "dense Schur complement (LAPACK dpotrf)"),
                "watch": {"position": w.position, "velocity": w.velocity,
                          "energy": w.energy, "every": w.every, "momentum": w.momentum,
                          "quaternion": w.quaternion},
                "invariants": invariant_names(invariants[:, :int(ninv)].T)}
    if formulation in ("projection", "projected"):
        manifest["projection_tol"] = projection_tol
    loose_lambda = ggl_multipliers(method, formulation, rtol) if sc.rows else None
    if loose_lambda:
        manifest["multipliers"] = loose_lambda
    if index3:
        manifest["form"] = ("trapezoidal rule on the index-3 DAE, Newton on (q+, w+, lam+) "
                            "with the equations of motion at t+, then the projections of "
                            "positions, velocities and the quaternions' norm, and a+, lam+ "
                            "from the constrained solve")
        manifest["linear_solve"] = ("Newton matrix by forward differences (LAPACK LU), kept "
                                    "while Newton contracts")
    if ida:
        manifest["form"] = IDA_FORM_TEXT[formulation]
        manifest["linear_solve"] = "IDA's dense difference quotients, SUNDIALS dense LU"
        manifest["quaternion_norm"] = ("none (ida on the DAE: no projection between its steps)"
                                       if sc.quaternion_norm == "project" else
                                       sc.quaternion_norm)
    if dae and formulation == "si2":
        manifest["form"] = ("stabilised index-2 DAE (GSTIFF SI2): q' = T(q) (w - M^-1 C^T "
                            "mu), w' = M^-1 (f - C^T lam), 0 = Phi, 0 = C w + Phi_t on the "
                            "independent rows; error test on q and w; no projection between "
                            "steps")
        manifest["linear_solve"] = "bdf's Newton matrix E - c J by differences (LAPACK LU)"
    elif dae:
        manifest["form"] = ("index-3 DAE (GSTIFF I3): q' = T(q) w, w' = M^-1 (f - C^T lam), "
                            "0 = Phi on the independent rows; error test on q and h times w; "
                            "no projection between steps")
        manifest["linear_solve"] = "bdf's Newton matrix E - c J by differences (LAPACK LU)"
    result = SceneResult(
        t=t[:nw], q=ys[:, :nq], v=ys[:, nq:], a=None,
        multipliers=lam[:sc.rows, :nw].T if sc.rows else None, reactions=None,
        energy=o[:, 0] + o[:, 1] + o[:, 2],
        energy_parts={"kinetic": o[:, 0], "potential_gravity": o[:, 1],
                      "potential_springs": o[:, 2], "power": o[:, 3], "work": o[:, 7]},
        residuals=o[:, 4:7], stats=Stats.from_words(stats), status=status,
        message=status_message(status), manifest=manifest, bodies=[b.name for b in sc.bodies],
        joints=[j.name for j in sc.joints], assembly={"moved": float(moved)}, kind="spatial",
        rotation=sc.rotation)
    unstable = ""
    if status.failed and nw and not info_m.adaptive and not index3 and not dae and not ida:
        from .simulate import _UNSTABLE_ENDS, _stability_note
        if status in _UNSTABLE_ENDS:
            def f(yy):
                out = evaluate_spatial(sc, yy, float(result.t[-1]))
                if out["status"] != Status.SUCCESS:
                    raise InvalidInputError("no evaluation")
                return out["ydot"]
            unstable = _stability_note(method, h, f, np.concatenate([result.q[-1],
                                                                     result.v[-1]]),
                                       float(result.t[-1]))
    if unstable:    # the true cause: the method's step, not the mechanism
        if status in (Status.ERR_CONSTRAINT_DRIFT, Status.ERR_ENERGY_DRIFT,
                      Status.ERR_INVARIANT_DRIFT):
            result.drift = drift_report(report, sc.joint_rows(), invariants[:, :int(ninv)].T,
                                        [b.name for b in sc.bodies])
        result.message = (f"{method}/{formulation} on spatial scene {sc.name!r}: "
                          f"{failure_text(status, False)} ({stopped_at(result.stats, t0)}): "
                          f"{unstable}")
    elif status == Status.ERR_CONSTRAINT_DRIFT and int(report[0]) == 0:
        # not the watch: the kernel found the redundant joints' dependent rows independent
        result.message = (f"{method}/{formulation} on spatial scene {sc.name!r} stopped at t = "
                          f"{result.t[-1] if nw else t0:.6g}: the state left the joints so far "
                          "that the rows of its redundant joints, dependent on the others on the "
                          "joints, no longer agree with them; the projection formulation keeps "
                          "the state on the joints, or take a smaller step")
    elif status in (Status.ERR_CONSTRAINT_DRIFT, Status.ERR_ENERGY_DRIFT,
                    Status.ERR_INVARIANT_DRIFT):
        inv = invariants[:, :int(ninv)].T
        bodies = [b.name for b in sc.bodies]
        result.drift = drift_report(report, sc.joint_rows(), inv, bodies)
        said = drift_message(report, sc.joint_rows(), inv, bodies).replace('D v', 'C w')
        remedy = ("A smaller step (small beside the period of the fastest motion), a "
                  "higher-order method or watch=False (to study the drift) are the remedies"
                  if status == Status.ERR_INVARIANT_DRIFT else
                  "A smaller step, the projection formulation or watch=False (to study the "
                  "drift) are the remedies")
        result.message = (f"{method}/{formulation} on spatial scene {sc.name!r}: {said}. "
                          + remedy)
    elif status == Status.ERR_NO_MEMORY:
        # the run's dense matrices: the Newton matrix over the method's unknowns, the penalty
        # formulation's over the velocities
        newton = (len(y0) + sc.rows * (2 if formulation in ("si2", "ggl") else 1)
                  if dae or ida or index3 else len(y0))
        dense = [(f"the Newton matrix of {method}", newton, "use an explicit method"),
                 ("the penalty formulation's M + alpha_p C^T C",
                  6 * nb * (formulation == "penalty"),
                  "use formulation reduced, baumgarte or projection")]
        result.message = (f"{method}/{formulation} on spatial scene {sc.name!r} ({nb} bodies): "
                          + no_memory_message(result.stats.alloc_bytes, dense))
    elif status == Status.ERR_SINGULAR_MATRIX:
        where = (f"stopped {stopped_at(result.stats, t0)}" if nw else
                 "could not start (the initial state's assembly or first evaluation)")
        lock = lock_distance(sc, result.q[-1]) if nw else None
        joints = ("the joints' constraint rows lost their rank (a singular pose: rows that "
                  "were independent at the start became dependent), where the multipliers are "
                  "not unique")
        if lock is not None and (lock < 1e-3 or not sc.joints):
            why = (f"the orientation angles reached their gimbal lock ({LOCK_MEASURE[sc.rotation]} = "
                   f"{lock:.2g} at "
                   "the last sample), where their rates are undefined; rotation = 'quaternion' "
                   "has no such point")
        else:
            why = joints
        result.message = f"{method}/{formulation} on spatial scene {sc.name!r} {where}: {why}"
    elif status.failed:
        text = failure_text(status, info_m.adaptive, dae or ida)
        result.message = (f"{method}/{formulation} on spatial scene {sc.name!r}: "
                          f"{text} ({stopped_at(result.stats, t0)})")
    if interrupted or status == Status.ERR_INTERRUPTED:
        from .errors import SolveInterrupted
        raise SolveInterrupted(result.message, status=status, result=result)
    if status.failed and raise_on_failure:
        raise exception_for(status)(result.message, status=status, result=result)
    if loose_lambda:
        import warnings
        from .errors import AccuracyWarning
        warnings.warn(f"{method}/{formulation} on spatial scene {sc.name!r}: the multipliers "
                      f"are {loose_lambda}", AccuracyWarning, stacklevel=3)
    return result


#: the other angle set, whose lock lies elsewhere
_OTHER_SET = {"euler313": "cardan123", "cardan123": "euler313"}


#: the most switches a run may take (a motion that dwells at the locks of both sets would
#: otherwise restart for ever)
MAX_SWITCHES = 1000


def _restarted(sc: Scene, r: SceneResult, k: int, rotation: str) -> Scene:
    """sc with its bodies at sample k of r (position, orientation, velocity, body-frame
    angular velocity), in the angle set rotation."""
    from dataclasses import replace
    bodies = [replace(b, position=r.position(b.name)[k].copy(),
                      rotation=r.orientation(b.name)[k].copy(),
                      velocity=r.v[k, 6 * i:6 * i + 3].copy(),
                      omega_body=r.v[k, 6 * i + 3:6 * i + 6].copy())
              for i, b in enumerate(sc.bodies)]
    return replace(sc, bodies=bodies, rotation=rotation)


def _switching_run(sc: Scene, method: str, guard, kw: dict) -> SceneResult:
    """simulate_spatial with switch_angles (its docstring): segments in alternating angle
    sets, joined into one result."""
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
    from dataclasses import replace
    raise_on_failure = kw.pop("raise_on_failure")
    t0, t_end = float(kw["t0"]), float(kw["t_end"])
    # a segment restarts from its last sample, so the segments sample densely (every step, or
    # 2000 samples of the dense output) and the result keeps the samples asked for
    adaptive = _method(method).adaptive
    if adaptive:
        dt_user = float(kw.get("dt_out") or 0.0)
        inner = (t_end - t0) / 2000
        if dt_user > 0:
            inner = dt_user / max(1, math.ceil(dt_user / inner))
        kw["dt_out"] = inner
    else:
        every_user = int(kw.get("every") or 1)
        kw["every"] = 1
    cur, t_start, segs, switches = sc, float(kw.pop("t0")), [], []
    if lock_distance(cur, cur.state0()[:6 * len(cur.bodies)]) < guard:
        # a start near the scene's own set's lock: in the other set from the first step
        cur = replace(cur, rotation=_OTHER_SET[cur.rotation])
        switches.append(t_start)
    while True:
        r = simulate_spatial(cur, method, t0=t_start, raise_on_failure=False,
                             _lock_guard=guard, **kw)
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
        grid = np.round((result.t - t0) / kw["h"]).astype(np.int64) % every_user == 0
    grid[[0, -1]] = True
    result = _subsampled(result, np.flatnonzero(grid))
    if result.status == Status.SUCCESS or not raise_on_failure:
        return result
    raise exception_for(result.status)(result.message, status=result.status, result=result)


def _subsampled(r: SceneResult, idx) -> SceneResult:
    """r at the samples idx."""
    from dataclasses import replace
    return replace(r, t=r.t[idx], q=r.q[idx], v=r.v[idx], energy=r.energy[idx],
                   energy_parts={k: v[idx] for k, v in r.energy_parts.items()},
                   residuals=r.residuals[idx],
                   multipliers=None if r.multipliers is None else r.multipliers[idx],
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
        rotations=rotations)
