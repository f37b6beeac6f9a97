"""The run of a planar scene: the kernel's tables and initial state, the sample arrays, one call
of the f2py entry scene_run (kernel/src/api/mbdk_f2py.f90) with the plan's option structs, and
the samples as a SceneResult. An initial state the kernel cannot assemble, or an element whose
value it cannot take from the pose, is a SceneError here; every other failure is left to
mbdk.diagnosis.
"""
from __future__ import annotations

from dataclasses import asdict, replace

import numpy as np

from . import _compiled, _kernel, checks
from .codes import dae_newton_matrix, LINEAR_SOLVES, OUTPUTS, PLANAR_VISITS, VISIT_NAMES
from .errors import InvalidInputError, Status, exception_for, status_message
from .model import (assemble, assembly_error, assembly_report, build_tables, given_mask,
                    pose_error)
from .ode import build_info
from .options import empty, unpack
from .plan import RunPlan
from .result import CONTACT_FIELDS, KernelRun, SceneResult, Stats
from .scene import Scene, SceneError
from .watch import invariant_names

#: what to change when a scene run's samples do not fit in memory
SCENE_SAMPLE_ADVICE = ("fewer samples: a larger every (fixed step) or dt_out (error control), a "
                       "shorter t_end, or fewer outputs (outputs=() keeps t, q and v only)")


def gears_at_assembled_pose(scene: Scene, t0: float) -> Scene:
    """The scene with its bodies at the pose and rates its initial assembly gives. A gear mesh's
    phases, and its check that the gears mesh, are taken from the bodies' poses: they must be
    those where the axle joints put the gears, not those the file writes (an axle joint moving a
    gear out of mesh ran on, or into a non-finite state)."""
    joints_only = replace(scene, forces=[], wear=[])
    q, v, _ = assemble(joints_only, build_tables(joints_only), t0)
    bodies = [replace(b, x=float(q[3 * i]), y=float(q[3 * i + 1]), angle=float(q[3 * i + 2]),
                      vx=float(v[3 * i]), vy=float(v[3 * i + 1]), omega=float(v[3 * i + 2]))
              for i, b in enumerate(scene.bodies)]
    moved = replace(scene, bodies=bodies)
    try:
        build_tables(moved, resolve=False)
    except SceneError as exc:
        moved_by = float(np.max(np.abs(q - np.asarray(scene.q0(), float)))) if q.size else 0.0
        raise SceneError(f"{exc} (at the pose the joints assemble, {moved_by:.3g} m or rad "
                         "from the one the file writes)") from None
    return moved


def prepared(scene: Scene, plan: RunPlan) -> Scene:
    """The scene as the run starts it: gear meshes taken at the pose the joints assemble."""
    if plan.request.assemble_initial and any(f.type == "contact" and f.shape1[0] == "gear"
                                             for f in scene.forces):
        return gears_at_assembled_pose(scene, plan.t0)
    return scene


def _output_arrays(plan: RunPlan, tab, y0, what: str) -> tuple:
    """The outputs' arrays the kernel fills (t and y are the f2py layer's), refused before they
    are allocated where the machine has not that much memory; an output not asked for gets one
    column the kernel leaves alone."""
    nsamp, nc, m, want = plan.nsamp, tab.nc, tab.m, plan.want

    def cols(bit):
        return nsamp if (want & bit) or plan.index3 or (plan.dae_form and bit == 2) else 1
    nbytes = 8.0 * (nsamp * (1 + y0.size) + nc * cols(1) + max(m, 1) * cols(2)
                    + 3 * max(tab.nj, 1) * (nsamp if want & 4 else 1)
                    + 9 * (nsamp if want & 8 else 1) + 3 * (nsamp if want & 16 else 1)
                    + (nsamp / 2 if plan.index3 else 0))
    checks.check_memory(nbytes, what=what, change=SCENE_SAMPLE_ADVICE)
    try:
        return nbytes, (np.zeros((nc, cols(1)), order="F"),
                        np.zeros((max(m, 1), cols(2)), order="F"),
                        np.zeros(nsamp if plan.index3 else 1, np.int32),
                        np.zeros((3, max(tab.nj, 1), nsamp if want & 4 else 1), order="F"),
                        np.zeros((9, nsamp if want & 8 else 1), order="F"),
                        np.zeros((3, nsamp if want & 16 else 1), order="F"))
    except MemoryError as exc:
        raise checks.memory_error(exc, nbytes, what=what, change=SCENE_SAMPLE_ADVICE) from None


def run_planar(scene: Scene, plan: RunPlan) -> KernelRun:
    """One call of scene_run: the scene's run as planned (scene: as prepared)."""
    # built once: the kernel fills in the values taken from the pose where it starts the run
    tab = build_tables(scene, resolve=False)
    # the state [q; v; w]: the wear elements' volumes after the bodies' coordinates and rates
    y0 = np.concatenate([np.array(scene.q0(), float), np.array(scene.v0(), float),
                         np.array([w.initial for w in scene.wear], float)])
    given = np.concatenate([given_mask(scene), np.zeros(len(scene.wear), np.int32)])
    what = f"{plan.method} on scene {scene.name!r} ({plan.nsamp} samples)"
    nbytes, arrays = _output_arrays(plan, tab, y0, what)
    a_out, lam_out, iters, reac, energy, resid = arrays
    stats, visits, flag = empty("mbdk_stats"), np.zeros(len(VISIT_NAMES)), _compiled.new_flag()
    watch_words = empty("mbdk_watch_report")
    req = plan.request
    args = (*tab.args(), plan.model_options.pack(), plan.info.id, plan.dae_form,
            plan.ode_options.pack(), plan.index3_options.pack(), plan.times, flag, y0, given,
            int(bool(req.assemble_initial)), req.t0, req.t_end, plan.want, plan.nsamp,
            *arrays, stats, visits, watch_words)
    try:
        (t, y, nw, path, asm_iters, asm_resid, asm_velocity, bad_joint, bad_force, invariants,
         ninv, status), interrupted = _compiled.call(
             _kernel.scene_run, args, flag, plan.steps * y0.size, span=(req.t0, req.t_end))
    except MemoryError as exc:   # t and y, allocated by the f2py layer
        raise checks.memory_error(exc, nbytes, what=what, change=SCENE_SAMPLE_ADVICE) from None
    status, nw = Status(int(status)), int(nw)
    _check_start(scene, plan, tab, status, nw, bad_joint, bad_force, asm_resid, asm_velocity)
    nc, m, want = tab.nc, tab.m, plan.want
    # the first sample is the (assembled) initial state
    report = (assembly_report(scene, y0[:nc], y0[nc:2 * nc], y[:nc, 0], y[nc:2 * nc, 0],
                              int(asm_iters))
              if req.assemble_initial and nw else {})
    # the results are views of the arrays the kernel wrote, not copies: a long run's peak
    # memory is its result arrays once (tests/test_pipeline.py measures it)
    t, y = t[:nw], y[:, :nw]
    stats = Stats.from_words(stats)
    inv = invariants[:, :int(ninv)].T
    result = SceneResult(
        t=t, q=y[:nc].T, v=y[nc:2 * nc].T,
        a=a_out[:, :nw].T if want & 1 else None,
        multipliers=lam_out[:m, :nw].T if want & 2 else None,
        reactions=np.transpose(reac[:, :tab.nj, :nw], (2, 1, 0)) if want & 4 else None,
        energy=None, energy_parts=None,
        residuals=resid[:, :nw].T if want & 16 else None,
        stats=stats, status=status, message=status_message(status),
        visits={name: int(visits[k]) for k, name in PLANAR_VISITS},
        manifest=_manifest(scene, plan, stats, int(path), inv),
        assembly=report, joints=[j.name for j in scene.joints],
        bodies=[b.name for b in scene.bodies],
        iterations=np.array(iters[:nw]) if plan.index3 else None,
        wear={w.name: y[2 * nc + k] for k, w in enumerate(scene.wear)}, kind="planar")
    if want & 8:
        kin, vg, vs, pd, pc, pl, wd, wc, wl = energy[:, :nw]
        result.energy = kin + vg + vs
        result.energy_parts = {
            "kinetic": kin, "potential_gravity": vg, "potential_springs": vs,
            "power": pl + pc - pd, "work": wl + wc - wd,
            "power_dampers": pd, "power_constraints": pc, "power_loads": pl,
            "dissipated_dampers": wd, "work_constraints": wc, "work_loads": wl}
    result.contacts = contact_outputs(scene, y, nw)
    return KernelRun(result, bool(interrupted), unpack("mbdk_watch_report", watch_words), inv, y0,
                     tab)


def contact_outputs(scene: Scene, y: np.ndarray, nw: int) -> dict:
    """Each contact's penetration, its rate, normal force and friction force at the run's nw
    samples (y: the kernel's (states, samples) array), by name, from the kernel
    (contact_states); the tables' pose values taken at the first sample, as the run's."""
    # the kernel's contact columns: the scene's contacts, then each gear mesh's coast flanks
    # (mbdk.model.build_tables), named '<mesh>.coast'
    names = [f.name for f in scene.forces if f.type == "contact"]
    names += [f"{f.name}.coast" for f in scene.forces
              if f.type == "contact" and f.shape1[0] == "gear"]
    if not names or nw == 0:
        return {}
    nc = 3 * len(scene.bodies)
    tab = build_tables(scene, y[:nc, 0])
    out, status = _kernel.contact_states(tab.nf, tab.fint, tab.freal, nc, y[:, :nw], len(names))
    if status != Status.SUCCESS:
        # the run's own tables refused: a defect of mbdk, not of the scene
        raise exception_for(Status(status))(
            f"contact_states: the contact outputs of scene {scene.name!r} failed: "
            f"{status_message(status)}")
    return {n: {f: out[i, k, :] for i, f in enumerate(CONTACT_FIELDS)}
            for k, n in enumerate(names)}


def _check_start(scene, plan, tab, status, nw, bad_joint, bad_force, asm_resid, asm_velocity):
    """The kernel's refusals of the initial state, as named errors."""
    if bad_joint or bad_force:
        raise pose_error(scene, int(bad_joint), int(bad_force))
    if status == Status.ERR_INCONSISTENT_INITIAL and plan.dae_form and \
            (nw or not plan.request.assemble_initial):
        raise InvalidInputError(
            f"{plan.method}/{plan.formulation} on scene {scene.name!r}: the initial state does "
            "not satisfy the constraints (Phi = 0, D v + Phi_t = 0) to 1e-10, which the DAE "
            "forms need: keep assemble_initial=True, or give a consistent pose and velocities",
            status=status)
    if status == Status.ERR_INCONSISTENT_INITIAL:
        raise assembly_error(scene, tab, asm_resid, velocity=bool(asm_velocity))


def _manifest(scene: Scene, plan: RunPlan, stats: Stats, path: int, inv) -> dict:
    req = plan.request
    manifest = {**build_info(), "scene": scene.name, "kind": "planar", "source": scene.source,
                "method": plan.method, "formulation": plan.formulation, "h": plan.h,
                "t0": req.t0, "t_end": req.t_end, "every": plan.every,
                "outputs": [o for o in OUTPUTS if plan.want & OUTPUTS[o]],
                "solver": req.solver, "linear_solve": LINEAR_SOLVES.get(path, "not built"),
                "small_dense": req.small_dense, "watch": asdict(plan.watch),
                "invariants": invariant_names(inv),
                "locate_events": bool(req.locate_events) and plan.method in ("dopri54", "bs32"),
                **plan.manifest}
    if plan.index3 or plan.info.adaptive:
        manifest["steps"] = stats.steps
    # (linear_solve is the model's constrained solve, which the DAE methods take at the start)
    if plan.dae_bdf or plan.ida:
        manifest["newton_matrix"] = dae_newton_matrix("ida" if plan.ida else "bdf", stats)
    if plan.multipliers_note:
        manifest["multipliers"] = plan.multipliers_note
    return manifest
