"""The run of a spatial scene: the spatial model's tables and initial state, one call of the
f2py entry spatial_run (kernel/src/api/mbdk_f2py.f90) with the plan's options, and the samples
as a SceneResult. Failures are left to mbdk.diagnosis.
"""
from __future__ import annotations

import numpy as np

from . import _compiled, _kernel
from .checks import check_memory, memory_error
from .codes import DENSE_CHOLESKY, DENSE_LU, dae_newton_matrix
from .errors import Status, exception_for, status_message
from .joint_coords import JOINT_SOLVE, describe
from .ode import build_info
from .options import empty, unpack
from .plan import SPATIAL_IDA_FORMS, RunPlan
from .result import CONTACT_FIELDS, KernelRun, SceneResult, Stats
from .run_planar import SCENE_SAMPLE_ADVICE
from .scene import Scene
from .spatial_model import spatial_tables, wear0
from .watch import invariant_names

#: what to change when a spatial run's samples do not fit in memory (it has no outputs to drop)
SPATIAL_SAMPLE_ADVICE = SCENE_SAMPLE_ADVICE.split(", or fewer outputs")[0]
INDEX3_FORMS = {
    "augmented_lagrangian": ("the index-3 DAE by the family's step (mbdk_trapezoidal_index3), "
                             "Newton on the increment dq (a body's rotation by the exponential "
                             "map) with the augmented Lagrangian, then v+ and a+, lam+ "
                             "projected onto the velocity and acceleration constraints"),
    "index3": ("the index-3 DAE by the family's step (mbdk_trapezoidal_index3), Newton on "
               "(dq, lam+) (a body's rotation by the exponential map), no projections")}
SI2_FORM = ("stabilised index-2 DAE (GSTIFF SI2): q' = T(q) (w - M^-1 C^T mu), w' = M^-1 (f - "
            "C^T lam), 0 = Phi, 0 = C w + Phi_t on the independent rows; error test on q and w; "
            "no projection between steps")
I3_FORM = ("index-3 DAE (GSTIFF I3): q' = T(q) w, w' = M^-1 (f - C^T lam), 0 = Phi on the "
           "independent rows; error test on q and h times w; no projection between steps")


def run_spatial(scene: Scene, plan: RunPlan) -> KernelRun:
    """One call of spatial_run: the scene's run as planned."""
    nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal = spatial_tables(scene)
    # the state [q; w; V]: the wear elements' volumes after the bodies' coordinates and rates
    y0 = np.concatenate([scene.state0(), wear0(scene)])
    req = plan.request
    stats, flag = empty("mbdk_stats"), _compiled.new_flag()
    m1 = max(scene.rows, 1)
    nsamp = plan.nsamp
    watch_words = empty("mbdk_watch_report")
    args = (mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal,
            plan.spatial_options.pack(), plan.info.id, plan.dae_form, plan.ode_options.pack(),
            plan.index3_options.pack(), plan.times, flag, np.zeros(0), y0,
            int(bool(req.assemble_initial)),
            float(req.t0), float(req.t_end), nsamp, m1, stats, watch_words)
    # the samples (t, y, the outputs and the multipliers, allocated by the f2py layer): refused
    # before they are allocated where the machine has not that much memory
    nbytes = 8.0 * nsamp * (1 + len(y0) + 8 + m1)   # spatial_run's out(8, nsamp)
    if plan.index3:   # and the index-3 family's accelerations and Newton counts per sample
        nbytes += nsamp * (8.0 * 6 * nb + 4)
    what = f"{plan.method} on spatial scene {scene.name!r} ({nsamp} samples)"
    check_memory(nbytes, what=what, change=SPATIAL_SAMPLE_ADVICE)
    try:
        (t, y, out, lam, nw, moved, invariants, ninv, sparse, status), interrupted = \
            _compiled.call(_kernel.spatial_run, args, flag, plan.steps * len(y0),
                           span=(req.t0, req.t_end))
    except MemoryError as exc:
        raise memory_error(exc, nbytes, what=what, change=SPATIAL_SAMPLE_ADVICE) from None
    status = Status(int(status))
    nq = nb * (7 if scene.rotation == "quaternion" else 6)
    nv = nq + 6 * nb
    ys = y[:, :nw].T
    o = out[:, :nw].T
    inv = invariants[:, :int(ninv)].T
    st = Stats.from_words(stats)
    result = SceneResult(
        t=t[:nw], q=ys[:, :nq], v=ys[:, nq:nv], a=None,
        multipliers=lam[:scene.rows, :nw].T if scene.rows else None, reactions=None,
        energy=o[:, 0] + o[:, 1] + o[:, 2],
        energy_parts={"kinetic": o[:, 0], "potential_gravity": o[:, 1],
                      "potential_springs": o[:, 2], "power": o[:, 3], "work": o[:, 7]},
        residuals=o[:, 4:7], stats=st, status=status,
        message=status_message(status), manifest=_manifest(scene, plan, inv, bool(sparse), st),
        bodies=[b.name for b in scene.bodies], joints=[j.name for j in scene.joints],
        assembly={"moved": float(moved)}, wear={w.name: ys[:, nv + k] for k, w in
                                               enumerate(scene.wear)},
        kind="spatial", rotation=scene.rotation)
    result.contacts = _contacts(scene, plan, y0, y[:, :nw], float(req.t0))
    return KernelRun(result, bool(interrupted), unpack("mbdk_watch_report", watch_words), inv,
                     y0)


def _contacts(scene: Scene, plan: RunPlan, y0, y, t0: float) -> dict:
    """Each contact's penetration, its rate, normal force and friction force at the samples
    (y: states x samples), by name, from the kernel (spatial_contact_states, the model built
    as the run's)."""
    names = [f.name for f in scene.forces if f.type in ("sphere_plane", "sphere_sphere")]
    if not names or not y.shape[1]:
        return {}
    _nb, mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal = spatial_tables(scene)
    out, status = _kernel.spatial_contact_states(
        mass, inertia, nj, jtype, jbody, jreal, nf, ftype, fbody, freal,
        plan.spatial_options.pack(), y0, t0, np.asfortranarray(y), len(names))
    if status != Status.SUCCESS:
        # the run's own tables refused: a defect of mbdk, not of the scene
        raise exception_for(Status(status))(
            f"spatial_contact_states: the contact outputs of scene {scene.name!r} failed: "
            f"{status_message(status)}")
    return {n: {f: out[i, k, :] for i, f in enumerate(CONTACT_FIELDS)}
            for k, n in enumerate(names)}


#: the constrained solves of the ODE formulations by the model's path (kernel/src/spatial/
#: mbdk_spatial_model.f90, MBDK_SPATIAL_SPARSE_ROWS)
SPATIAL_SCHUR = {False: f"dense Schur complement ({DENSE_CHOLESKY})",
                 True: "compact rows and the sparse Schur complement S = C M^-1 C^T "
                       "(SuiteSparse AMD + LDL, kernel/src/linalg/mbdk_compact_schur.f90)"}


#: the index-3 family's Newton matrix by the model's path (kernel/src/spatial/mbdk_spatial_i3.f90)
SPATIAL_INDEX3_MATRIX = {
    False: f"Newton matrix by forward differences over the whole state ({DENSE_LU}), kept "
           "while Newton contracts",
    True: "Newton matrix by differences of colored columns into 6 x 6 body blocks, factorised "
          "by a sparse L D U (AMD, SuiteSparse LDL's analysis), kept while Newton contracts"}


def _manifest(scene: Scene, plan: RunPlan, inv, sparse: bool = False, stats=None) -> dict:
    formulation, w, req = plan.formulation, plan.watch, plan.request
    manifest = {**build_info(), "scene": scene.name, "kind": "spatial", "method": plan.method,
                "formulation": formulation, "rotation": scene.rotation,
                **({"h": req.h, "every": int(req.every)} if not plan.info.adaptive else {}),
                "quaternion_norm": ("none (bdf on the DAE: no projection between its steps)"
                                    if plan.dae_bdf and scene.quaternion_norm == "project"
                                    else scene.quaternion_norm), "t0": req.t0,
                "t_end": req.t_end, **plan.manifest,
                "linear_solve": (f"dense M + alpha_p C^T C ({DENSE_CHOLESKY})"
                                 if formulation == "penalty" else SPATIAL_SCHUR[sparse]),
                "locate_events": bool(req.locate_events) and plan.method in ("dopri54", "bs32"),
                "watch": {"position": w.position, "velocity": w.velocity,
                          "energy": w.energy, "every": w.every, "momentum": w.momentum,
                          "quaternion": w.quaternion},
                "invariants": invariant_names(inv)}
    if scene.wear:
        manifest["wear"] = {w.name: f"{w.law} on {w.load}, k = {w.coefficient:g} m^3/(N m), "
                                    "integrated with the motion" for w in scene.wear}
    if formulation in ("projection", "projected"):
        manifest["projection_tol"] = plan.projection_tol
    if plan.multipliers_note:
        manifest["multipliers"] = plan.multipliers_note
    if plan.index3:
        manifest["form"] = INDEX3_FORMS[formulation]
        manifest["linear_solve"] = SPATIAL_INDEX3_MATRIX[sparse]
    if plan.ida:
        manifest["form"] = SPATIAL_IDA_FORMS[formulation]
        manifest["linear_solve"] = manifest["newton_matrix"] = dae_newton_matrix("ida", stats)
        manifest["quaternion_norm"] = ("none (ida on the DAE: no projection between its steps)"
                                       if scene.quaternion_norm == "project" else
                                       scene.quaternion_norm)
    if plan.dae_bdf:
        manifest["form"] = SI2_FORM if formulation == "si2" else I3_FORM
        manifest["linear_solve"] = manifest["newton_matrix"] = dae_newton_matrix("bdf", stats)
    manifest["coordinates"] = "absolute"
    if plan.joint_split is not None:
        manifest["coordinates"] = "joint"
        manifest["joint_tree"] = describe(plan.joint_split)
        manifest["linear_solve"] = JOINT_SOLVE
        manifest["quaternion_norm"] = ("none needed (joint coordinates: each quaternion is "
                                       "built from the joints' turns, unit to roundoff)")
    return manifest
