"""Whether a scene can be run as planned: the refusals that read the scene's elements (a linear
solve the joints do not allow, contacts or knife edges a form cannot take, wear states a state
layout has no place for, a distance that reaches zero within the run, a spatial initial state
off its joints), each naming the element and what to change. mbdk.plan has checked the
arguments; mbdk.scene_file.checked the scene itself.
"""
from __future__ import annotations

import numpy as np

from .errors import InvalidInputError, NotApplicableError, RedundantConstraintsError, Status
from .plan import RunPlan
from .scene import Scene, SceneError
from .spatial_model import check_initial, start_residuals


def check_applicable(scene: Scene, plan: RunPlan) -> None:
    """Refuses, by name, a scene the plan cannot run."""
    if plan.kind == "spatial":
        _check_wear_states(scene, plan)
        check_initial(scene, plan.request.assemble_initial, float(plan.t0))
        if plan.index3 and plan.formulation == "index3" and scene.rows:
            # (from the linear-memory start check: evaluate_spatial returns C, rows x 6 bodies)
            rank = start_residuals(scene, float(plan.t0))["rank"]
            if rank < scene.rows:
                raise RedundantConstraintsError(
                    f"{scene.source}: the joints' {scene.rows} rows have rank {rank} at the "
                    f"initial pose (redundant joints): {plan.method}'s formulation 'index3' "
                    "solves for every multiplier, and its Newton matrix [M + .., C^T; C, 0] is "
                    "singular. Use formulation = 'augmented_lagrangian', which runs redundant "
                    "joints", status=Status.ERR_SINGULAR_MATRIX)
        return
    _check_solver(scene, plan.request.solver)
    _check_elements(scene, plan)


def _check_solver(scene: Scene, solver: str) -> None:
    """The linear solves that need revolute joints or bodies with inertia."""
    if solver == "revolute_schur":
        other = [f"{j.name} ({j.type})" for j in scene.joints if j.type != "revolute"]
        if other:
            raise InvalidInputError(f"{scene.source}: solver = 'revolute_schur' needs every "
                                    f"joint to be revolute; not revolute: {', '.join(other)}. "
                                    "Use solver = 'schur' or 'auto'")
    if solver in ("schur", "revolute_schur", "sparse") and \
            any(b.inertia == 0 for b in scene.bodies):
        raise InvalidInputError(f"solver = {solver!r} needs every body to have inertia; "
                                f"{[b.name for b in scene.bodies if b.inertia == 0]} have none: "
                                "use solver = 'kkt' or 'auto'")


def fn_text(fn) -> str:
    """A time function as the scene file writes it."""
    keys = ("offset", "rate", "amplitude", "omega", "phase")
    return "{" + ", ".join(f"{k} = {v:g}" for k, v in zip(keys, fn) if v) + "}"


def _check_distances(scene: Scene, t0: float, t_end: float) -> None:
    """A distance joint's L(t) must stay positive over the run: at L = 0 its row has no
    direction."""
    for j in scene.joints:
        if j.type == "distance" and j.length is not None:
            off, rate, amp, om, ph = j.length
            ts = np.linspace(t0, t_end, 20001)
            low = np.nonzero(off + rate * ts + amp * np.sin(om * ts + ph) <= 0)[0]
            if low.size:
                raise SceneError(
                    f"{scene.source}: joint {j.name!r}: field 'length' = {fn_text(j.length)} "
                    f"reaches 0 at t = {ts[low[0]]:.6g} s, within the run (t_end = {t_end:g}): "
                    "a distance must stay positive; end the run before, or change L(t)")


def _check_elements(scene: Scene, plan: RunPlan) -> None:
    """Contacts, knife edges and wear against the method and its form."""
    method, formulation = plan.method, plan.formulation
    contacts = [f.name for f in scene.forces if f.type == "contact"]
    if plan.index3 and contacts:
        raise NotApplicableError(
            f"{method} on scene {scene.name!r}: its Newton matrix has no tangent stiffness of "
            f"the contacts ({', '.join(contacts)}); use an ODE method (rk4, dopri54, bdf, "
            "cvode_bdf) with formulation reduced, baumgarte or projection")
    _check_distances(scene, plan.t0, plan.t_end)
    knives = [j.name for j in scene.joints if j.type == "knife_edge"]
    if plan.index3 and knives:
        raise NotApplicableError(
            f"{method} on scene {scene.name!r}: it solves the joints at position level, and the "
            f"knife edges ({', '.join(knives)}) constrain velocities only (nonholonomic); use an "
            "ODE method with formulation reduced, baumgarte or projection, bdf with formulation "
            "'i3' (index 2 in their rows) or ida with formulation 'index1'")
    if plan.dae_form and knives and formulation in ("ggl", "si2"):
        raise NotApplicableError(
            f"{method}/{formulation} on scene {scene.name!r}: its mu stabilises position rows, "
            f"and the knife edges ({', '.join(knives)}) have none (nonholonomic); use "
            f"{'formulation index1' if plan.ida else 'formulation i3'}")
    if method == "euler_cromer" and scene.wear:
        raise NotApplicableError(
            f"euler_cromer on scene {scene.name!r}: it integrates a state [q, v] of positions "
            f"and velocities, which has no place for the wear states "
            f"({', '.join(w.name for w in scene.wear)}); use rk4, heun or an error-controlled "
            "method")
    _check_wear_states(scene, plan)


def _check_wear_states(scene: Scene, plan: RunPlan) -> None:
    """The forms whose state has no place for wear states, planar or spatial: the DAE's [q, v,
    lambda] and the index-3 family's [q, v] (a planar scene's contacts have refused it first)."""
    if not scene.wear:
        return
    names = ", ".join(w.name for w in scene.wear)
    if plan.dae_form:
        raise NotApplicableError(
            f"{plan.method}/{plan.formulation} on scene {scene.name!r}: the DAE's state [q, v, "
            f"lambda] has no place for the wear states ({names}); use an ODE method with "
            "formulation reduced, baumgarte or projection")
    if plan.index3:
        raise NotApplicableError(
            f"{plan.method} on scene {scene.name!r}: the index-3 family's state [q, v] (Newton "
            f"on its increment) has no place for the wear states ({names}); use an ODE method "
            "with formulation reduced, baumgarte or projection")
