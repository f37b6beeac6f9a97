"""The diagnosis of a scene run: what the kernel's status means for this scene, method and
formulation, in words, and the exception a failure raises.

A failure's message names where the run stopped (mbdk.errors.stopped_at) and its cause where
one can be told: a fixed step beyond the method's stability limit for a mode of the scene
(mbdk.stability), a singular configuration or dependent (redundant) joints, a distance or a
contact without a direction, gear flanks overrun, an angle set at its gimbal lock, memory that
could not be had (the dense matrices of the run, named), or the watch's drift report
(mbdk.watch). diagnose() returns the result, or raises the status's exception carrying it; a
run that succeeds with multipliers below its tolerance says so (AccuracyWarning's text).
"""
from __future__ import annotations

import math

import numpy as np

from . import _kernel
from .codes import ADAPTIVE_MODES, OUTPUTS
from .errors import (MbdkError, RedundantConstraintsError, SolveInterrupted, Status,
                     exception_for, failure_text, no_memory_message, stopped_at)
from .index3 import MAX_CUTS, NEAR_SINGULAR
from .model import (DENSE_NAMING_MAX, Tables, assemble, build_tables, dependent_rows,
                    rows_to_joints, scaled_jacobian)
from .model import evaluate as evaluate_model
from .plan import RunPlan
from .result import KernelRun, SceneResult
from .scene import GROUND, Scene
from .spatial_model import LOCK_MEASURE, evaluate_spatial, lock_distance
from .stability import instability_note
from .watch import drift_message, drift_report

# the reduced formulation refuses a relative pivot of D M^-1 D^T below this (the kernel's)
# and a DAE form's stop is named by a singular pose within this relative pivot of the geometry
REDUCED_NEAR_PIVOT, RANK_LOSS_WINDOW = (float(x) for x in _kernel.model_constants())


DRIFT_ADVICE = {
    Status.ERR_CONSTRAINT_DRIFT: "The state left the constraints: a smaller h, a stabilised "
    "formulation (baumgarte, projection) or trapezoidal_index3 keeps them; near a singular "
    "configuration the mechanism may have changed branch. watch=mbdk.Watch(...) sets other "
    "tolerances, watch=False accepts the drift.",
    Status.ERR_ENERGY_DRIFT: "The method added or removed energy the model does not: a smaller "
    "h, or a method whose stability region covers h times the system's eigenvalues (implicit "
    "for stiff elements). watch=mbdk.Watch(energy=...) sets another tolerance, watch=False "
    "accepts it.",
    Status.ERR_INVARIANT_DRIFT: "The method does not keep what the mechanics conserves here: a "
    "smaller h (small beside the period of the fastest motion), or a higher-order method. "
    "watch=mbdk.Watch(momentum=...) sets another tolerance, watch=False accepts it."}


#: the states whose Jacobian a failure message may form by differences (2 n kernel calls)
STABILITY_NAMING_MAX = 400


#: failures an explicit step beyond its stability limit ends in: an overflow, drift caught by
#: the watch, or a constrained solve at a state the growing mode carried far off
UNSTABLE_ENDS = (Status.ERR_NONFINITE, Status.ERR_ENERGY_DRIFT, Status.ERR_CONSTRAINT_DRIFT,
                  Status.ERR_INVARIANT_DRIFT, Status.ERR_SINGULAR_MATRIX)


def stability_note(method, h, f, y, t) -> str:
    """Whether the fixed step h of method lies beyond its stability limit for a mode of the
    scene that does not grow (mbdk.stability.instability_note), from the Jacobian of the reduced
    ODE y' = f(y) at y by central differences; '' where it does not, or f fails there."""
    y = np.asarray(y, dtype=float)
    if y.size > STABILITY_NAMING_MAX or not np.all(np.isfinite(y)):
        return ""
    jac = np.empty((y.size, y.size))
    try:
        with np.errstate(all="ignore"):     # a non-finite column leaves no note (below)
            for j in range(y.size):
                d = np.sqrt(np.finfo(float).eps) * max(abs(y[j]), 1.0)
                yp, ym = y.copy(), y.copy()
                yp[j] += d
                ym[j] -= d
                jac[:, j] = (f(yp) - f(ym)) / (2.0 * d)
    except (MbdkError, ValueError, FloatingPointError):
        return ""
    return instability_note(method, h, jac)


def planar_stability_note(scene, method, h, r) -> str:
    """stability_note at a planar run's last sample, on the reduced ODE [v; a(q, v)]."""
    if not len(r.t) or h is None:
        return ""
    tab = resolved(scene, r)
    nc = r.q.shape[1]

    def f(y):
        out = evaluate_model(tab, y[:nc], y[nc:], r.t[-1])
        if out["status"] != Status.SUCCESS:
            raise MbdkError("no evaluation")
        return np.concatenate([y[nc:], out["a"]])

    return stability_note(method, h, f, np.concatenate([r.q[-1], r.v[-1]]), r.t[-1])


def singular_note(scene, tab: Tables, r) -> str:
    """Where D is close to losing a rank at the last sample (the state the failed step started
    from): the smallest / largest singular value of the scaled Jacobian and the joints of the
    rows the vanishing direction involves, in words; empty elsewhere."""
    if not (len(r.t) and tab.m) or too_large_to_name(tab):
        return ""
    if not (np.all(np.isfinite(r.q[-1])) and np.all(np.isfinite(r.v[-1]))):
        return ""   # a blown-up run (watch off): no configuration to speak of
    tab_r = resolved(scene, r)
    d = scaled_jacobian(tab_r, evaluate_model(tab_r, r.q[-1], r.v[-1], r.t[-1])["D"])
    if not np.all(np.isfinite(d)):
        return ""
    u, sv, _ = np.linalg.svd(d)
    ratio = sv[-1] / sv[0] if sv.size == tab.m and sv[0] > 0 else 1.0
    if ratio >= NEAR_SINGULAR:
        return ""
    rows = [i for i in range(tab.m) if abs(u[i, -1]) > 0.1]
    return (f"D is close to losing a rank (smallest / largest singular value {ratio:.1e}): "
            f"joint(s) {', '.join(rows_to_joints(tab, rows))} are nearly dependent, a singular "
            "configuration of the mechanism")


def distance_note(scene: Scene, r) -> str:
    """A distance joint whose points met (its row has no direction there, and the solve
    returns NaN): named, with its points' distance at the last finite sample."""
    dist = [j for j in scene.joints if j.type == "distance"]
    finite = [k for k in range(len(r.t)) if np.all(np.isfinite(r.q[k]))]
    if not dist or not finite:
        return ""
    q = r.q[finite[-1]]

    def point(body, s):
        if body == GROUND:
            return np.asarray(s, float)
        i = 3 * scene.body_index(body) - 3
        c, sn = math.cos(q[i + 2]), math.sin(q[i + 2])
        return q[i:i + 2] + np.array([c * s[0] - sn * s[1], sn * s[0] + c * s[1]])
    gaps = sorted((float(np.linalg.norm(point(j.body1, j.point1) - point(j.body2, j.point2))),
                   j.name) for j in dist)
    gap, name = gaps[0]
    return (f"; distance joint {name!r}: its points were {gap:.3g} m apart at t = "
            f"{r.t[finite[-1]]:.6g} s, and where they meet the distance has no direction (its "
            "length L(t) reached 0, or the motion carried one point through the other); keep "
            "L(t) positive, or use a revolute joint where the points coincide")


def refuse_redundant(scene, tab, q0, v0, t0, formulation, index3, result, dae=False):
    """A singular solve at the initial state: name the dependent joints, if any (not on a scene
    too large for the dense SVD that finds them)."""
    if too_large_to_name(tab):
        return
    d0 = scaled_jacobian(tab, evaluate_model(tab, q0, v0, t0)["D"])
    dep = dependent_rows(d0)
    if not dep:
        return
    names = rows_to_joints(tab, dep)
    sv = np.linalg.svd(d0, compute_uv=False)
    rank = int(np.sum(sv > 1e-9 * max(sv[0], 1e-300)))
    if index3:
        what = ("the book scheme's Newton matrix [M + .., D^T; D, 0] is singular. Use "
                "formulation = 'augmented_lagrangian', which runs redundant joints, remove the "
                "redundant joint, or use an ODE method with formulation = 'penalty'")
    elif dae:
        what = (f"so the {formulation} form of the DAE has no unique multipliers. Remove the "
                "redundant joint, or use trapezoidal_index3 (augmented_lagrangian) or an ODE "
                "method with formulation = 'penalty', which run redundant joints")
    else:
        what = (f"so the {formulation} formulation has no unique multipliers. Remove the "
                "redundant joint or use formulation = 'penalty', which handles it")
    raise RedundantConstraintsError(
        f"{scene.source}: the constraints of joint(s) {', '.join(names)} are dependent "
        f"(redundant) at the initial pose: D has rank {rank} < {tab.m} rows, {what}",
        status=Status.ERR_SINGULAR_MATRIX, result=result)


def too_large_to_name(tab: Tables) -> bool:
    """Whether the dense D of the scene is beyond what an error message may form and decompose
    (mbdk.model.DENSE_NAMING_MAX entries)."""
    return tab.m * 3 * len(tab.mass) > DENSE_NAMING_MAX


def resolved(scene: Scene, r: SceneResult) -> Tables:
    """The tables of a run as the kernel used them: pose values taken at its first sample."""
    return build_tables(scene, r.q[0])


#: the DAE forms (bdf's i3, si2; ida's ggl) and what passes a singular pose where they stop
DAE_FORMS = ("i3", "si2", "ggl")
DAE_REMEDY = {"i3": "trapezoidal_index3 passes such poses; looser tolerances may step over it",
              "si2": "bdf with formulation='i3' or trapezoidal_index3 pass such poses; looser "
                     "tolerances may step over it"}
DAE_REMEDY["ggl"] = DAE_REMEDY["si2"]


def dae_singular_text(formulation: str) -> str:
    """What a DAE form's SINGULAR_MATRIX after its first step means: the kernel names a stop so
    where its last accepted state lies within RANK_LOSS_WINDOW of a rank loss of the rows it
    solves (their geometry, kernel/src/linalg/mbdk_rank_margin.f90), or where a Newton matrix
    had a zero pivot; and the remedy."""
    form = "index-3" if formulation == "i3" else "stabilised index-2"
    return (f"the {form} form stopped at a rank loss: its last accepted state lies next to a "
            f"singular pose of the constraints (a relative pivot of their geometry below "
            f"{RANK_LOSS_WINDOW:g}), or a Newton matrix had a zero pivot. "
            f"{DAE_REMEDY[formulation]}")


def _ode_failure_note(scene: Scene, tab: Tables, formulation: str, r: SceneResult) -> str:
    """What a planar ODE or DAE run's failure message adds to the status's text: dependent
    joints, an ill-conditioned regular pose, gear flanks overrun, a distance or a contact without
    a direction, or a singular configuration nearby."""
    nw = len(r.t)
    note = ""
    if r.status == Status.ERR_SINGULAR_MATRIX and nw and not too_large_to_name(tab):
        tab_r = resolved(scene, r)
        dep = dependent_rows(scaled_jacobian(
            tab_r, evaluate_model(tab_r, r.q[-1], r.v[-1], r.t[-1])["D"]))
        if dep:
            note = (f": joint(s) {', '.join(rows_to_joints(tab, dep))} became dependent "
                    "(a singular configuration)")
    if not note and r.status == Status.ERR_SINGULAR_MATRIX and formulation == "reduced" \
            and nw and not singular_note(scene, tab, r):
        note = ("; the pose is regular, but D M^-1 D^T is ill-conditioned there (bodies of "
                "very different masses or inertias): the reduced formulation refuses a "
                f"relative pivot below {REDUCED_NEAR_PIVOT:g}, where its accelerations "
                "amplify the drift of v. "
                "baumgarte, projection or trapezoidal_index3 run it")
    contacts = [f.name for f in scene.forces if f.type == "contact"]
    gears = [f.name for f in scene.forces if f.type == "contact" and f.shape1[0] == "gear"]
    if r.status == Status.ERR_CONTACT_OVERRUN and gears:
        note = (f"; the flanks of {', '.join(gears)} penetrated by a quarter of the base "
                "pitch, where the next tooth would be met: the load or the impact across "
                "the backlash is beyond the mesh's stiffness. A stiffer mesh, damping, a "
                "smaller backlash or a load applied gradually keeps it within")
    if not note and r.status == Status.ERR_NONFINITE:
        note = distance_note(scene, r)
    if not note and r.status == Status.ERR_NONFINITE and contacts:
        note = (f"; a contact may have no normal there ({', '.join(contacts)}): two circles "
                "whose centres coincide, or gears whose centres came within their base "
                "circles' sum; a smaller h or a stiffer contact keeps them apart")
    if r.status == Status.ERR_SINGULAR_MATRIX and formulation in DAE_FORMS and r.stats.steps:
        # the joints named above, or those the last sample finds nearly dependent, then the cause
        found = "" if note else singular_note(scene, tab, r)
        note += "; " + dae_singular_text(formulation) + (
            f" (at the last sample {found})" if found else "")
    if not note and r.status == Status.ERR_SINGULAR_MATRIX and formulation == "index1":
        found = singular_note(scene, tab, r)
        note = ("; ida's index-1 form stops where the mechanism nears a singular pose (the "
                "reduced solve's pivot, looked for at four points of every step)"
                + (f": {found}" if found else "") + ". There its acceleration rows hold on "
                "either branch, and without Phi kept it can leave the motion's branch "
                "unseen; formulation='ggl', bdf with 'i3' or trapezoidal_index3 "
                "(augmented_lagrangian) pass such poses")
    if not note:
        note = singular_note(scene, tab, r)
        if note:   # a smaller h meets the singular configuration as well
            refuse = (" The reduced formulation refuses a near rank loss (its accelerations "
                      "amplify the drift of v there, and a step across it can land on "
                      "another assembly branch)." if formulation == "reduced" else "")
            note = (f"; there {note}.{refuse} A smaller h meets it too: "
                    "trapezoidal_index3 (augmented_lagrangian) passes singular crossings "
                    "(baumgarte and projection where no stage lands on the rank loss); a "
                    "driver or load that pushes the mechanism against a dead point has no "
                    "solution there")
    return note


#: from this many constraint rows a failed augmented-Lagrangian run names the book's scheme
#: (docs/guide/index3.md, "Long chains")
LONG_CHAIN_ROWS = 1000


def _index3_failure_message(scene: Scene, tab: Tables, plan: RunPlan, r: SceneResult) -> str:
    """A planar trapezoidal_index3 run's failure: where (its substeps, its retry budget), a
    singular configuration nearby, and what may get past it."""
    nw, formulation = len(r.t), plan.formulation
    extrapolated = plan.index3_options.adaptive == ADAPTIVE_MODES["extrapolated"]
    where = (f"in the step after t = {r.stats.t_reached:.6g}" if r.stats.steps else
             "in the first step")
    if nw and not plan.adaptive and formulation == "augmented_lagrangian" and r.status in (
            Status.ERR_NEWTON_DIVERGED, Status.ERR_NONFINITE, Status.ERR_SINGULAR_MATRIX):
        where += f", also in substeps down to h/{4 ** MAX_CUTS}"
    if plan.adaptive and r.status == Status.ERR_NEWTON_DIVERGED:
        # adaptive, every Newton failure is retried until the budget runs out (extrapolated:
        # steps the error test could only judge next to a rank loss draw on it too)
        judged = extrapolated
        where += (f"; {r.stats.newton_failures} Newton failures in {r.stats.steps} steps"
                  + (", and steps judged next to a rank loss," if judged else "")
                  + " exhausted the retry budget (more than one attempt in ten failing)")
    note = singular_note(scene, tab, r)
    remedy = "A smaller h, or a larger max_iter, may get past it"
    if note and plan.adaptive and r.status == Status.ERR_STEP_TOO_SMALL and extrapolated:
        # the three solves of a macro step differ by what Newton and the projections leave,
        # amplified along the vanishing direction: that difference does not fall with H
        remedy = ("Next to the rank loss the extrapolated control's three solves differ by "
                  "their own residuals, amplified along the vanishing direction, by more than "
                  "err_rtol and err_atol ask, whatever the step: its error estimate is noise "
                  "there. adaptive='estimated' (whose estimate is no difference of solves) "
                  "passes such poses, or looser err_rtol and err_atol do")
    if (not note and formulation == "augmented_lagrangian" and r.status ==
            Status.ERR_NEWTON_DIVERGED and scene.rows >= LONG_CHAIN_ROWS):
        # measured on bar chains: its iterations grow with the length, and it fails from about
        # 5000 bars, where the book's scheme runs at 4.5 iterations per step
        remedy += (f". On {scene.rows} constraint rows: the augmented form's multiplier update "
                   "contracts more slowly as a chain lengthens (its Newton iterations grow "
                   "with N); formulation = 'index3' (the book's scheme, Newton on the "
                   "multipliers) keeps its iteration count on long chains")
    note = f"; there {note}" if note else ""
    return (f"trapezoidal_index3/{formulation} on scene {scene.name!r}: {r.message} ({where})"
            f"{note}. {remedy}")

#: the watch's statuses
DRIFTS = (Status.ERR_CONSTRAINT_DRIFT, Status.ERR_ENERGY_DRIFT, Status.ERR_INVARIANT_DRIFT)


def _ida_first_step_note(plan: RunPlan, r: SceneResult) -> str:
    """ida ggl's Newton failing in its first step, no first step given: IDA's estimate from
    rest (the velocities' tolerance over their accelerations) falls below its floor, 1e-6 of
    the interval (kernel/src/sundials/mbdk_ida.f90, GGL_FIRST_STEP), where the index-2 Newton
    matrix of a long chain is singular to roundoff (planar chains from about 800 bars from rest
    to 0.01 s; h = 1e-4 runs them to 10 000 bars, tests/test_dae_scale.py)."""
    if not (plan.ida and plan.formulation == "ggl" and r.status == Status.ERR_NEWTON_DIVERGED
            and r.stats.steps == 0 and not plan.h):
        return ""
    return ("; IDA's own first step from rest (the velocities' tolerance over their "
            "accelerations) fell to its floor, a millionth of the interval, where the index-2 "
            "Newton matrix can be singular to roundoff: give the first step, h (h = 1e-4 runs "
            "planar chains of 800 to 10 000 bars from rest), or take bdf with "
            "formulation='si2', the same equations")


def _ode_failure_message(scene: Scene, tab: Tables, plan: RunPlan, r: SceneResult) -> str:
    """A planar ODE (or DAE) run's failure: the status's text, where it stopped, and the note."""
    where = stopped_at(r.stats, r.manifest.get("t0", 0.0))
    note = _ode_failure_note(scene, tab, plan.formulation, r) + _ida_first_step_note(plan, r)
    text = failure_text(r.status, plan.info.adaptive,
                        plan.formulation in ("i3", "si2", "index1", "ggl"))
    return f"{plan.method}/{plan.formulation} on scene {scene.name!r}: {text} ({where}){note}"


def _planar_drift_message(scene: Scene, plan: RunPlan, run: KernelRun) -> str:
    """The watch's report in words, and the remedy (a singular configuration, where the check
    failed next to one, is the cause)."""
    r, index3, formulation = run.result, plan.index3, plan.formulation
    advice = DRIFT_ADVICE[r.status]
    if index3:   # it is the index-3 form already: the stabilised ODE forms are no remedy
        advice = advice.replace(" or trapezoidal_index3", "").replace(
            "a stabilised formulation (baumgarte, projection)",
            "formulation = 'augmented_lagrangian' (which projects v and a)")
    note = singular_note(scene, run.tables, r)
    if note:   # the check failed next to a singular configuration: that is the cause
        passes = ("" if index3 and formulation == "augmented_lagrangian" else
                  "A formulation that keeps the constraints through it is "
                  "trapezoidal_index3 (augmented_lagrangian); ")
        advice = (f"It failed at a singular configuration: {note}. {passes}a driver or "
                  "load that pushes the mechanism against a dead point has no solution "
                  "there. watch=False accepts the run as it is.")
    return (f"{plan.method}/{formulation} on scene {scene.name!r}: "
            f"{drift_message(run.watch_report, run.tables.rows, run.invariants)}. " + advice)


def _planar_no_memory(scene: Scene, plan: RunPlan, run: KernelRun) -> str:
    """The run's dense matrices, named: the Newton matrix over the method's unknowns, the
    penalty formulation's over the coordinates."""
    nc, m, formulation = run.tables.nc, run.tables.m, plan.formulation
    newton = (2 * nc + m * (2 if formulation in ("si2", "ggl") else 1) if plan.dae_form else
              nc + m * (formulation == "index3") if plan.index3 else run.y0.size)
    dense = [(f"the Newton matrix of {plan.method}", newton, "use an explicit method, or "
              "trapezoidal_index3 (augmented_lagrangian: sparse on large scenes)"),
             ("the penalty formulation's M + alpha_p D^T D", nc * (formulation == "penalty"),
              "use formulation reduced, baumgarte or projection (sparse on large scenes)")]
    return (f"{plan.method}/{formulation} on scene {scene.name!r} ({len(scene.bodies)} "
            f"bodies): " + no_memory_message(run.result.stats.alloc_bytes, dense))


def _refuse_redundant_start(scene: Scene, plan: RunPlan, run: KernelRun) -> None:
    """A singular solve at the start: the dependent joints named (RedundantConstraintsError)."""
    r, tab, t0 = run.result, run.tables, plan.t0
    nc = tab.nc
    if len(r.t):
        q0, v0 = r.q[0], r.v[0]
    else:   # the consistent start of index3 failed: the state it would start from
        q0, v0 = run.y0[:nc], run.y0[nc:2 * nc]
        if plan.request.assemble_initial:
            q0, v0, _ = assemble(scene, build_tables(scene), t0)
    refuse_redundant(scene, build_tables(scene, q0), q0, v0, t0, plan.formulation, plan.index3,
                     r, dae=bool(plan.dae_form))


def _diagnose_planar(scene: Scene, plan: RunPlan, run: KernelRun) -> SceneResult:
    r, status = run.result, run.result.status
    method, formulation, raise_on_failure = (plan.method, plan.formulation,
                                             plan.request.raise_on_failure)
    if status == Status.ERR_INTERRUPTED or run.interrupted:
        raise SolveInterrupted(f"{method}/{formulation} on scene {scene.name!r}: interrupted"
                               + (f" at t = {r.t[-1]:.6g}" if len(r.t) else ""), status=status,
                               result=r)
    if status == Status.ERR_SINGULAR_MATRIX and run.tables.m and len(r.t) <= 1:
        _refuse_redundant_start(scene, plan, run)
    unstable = ""
    if status in UNSTABLE_ENDS and not plan.info.adaptive and not plan.index3 and \
            not plan.dae_form:
        unstable = planar_stability_note(scene, method, plan.h, r)
    if unstable:    # the true cause: the method's step, not the mechanism
        r.message = (f"{method}/{formulation} on scene {scene.name!r}: "
                     f"{failure_text(status, False)} ({stopped_at(r.stats, plan.t0)}): "
                     f"{unstable}")
        if status in DRIFTS:
            r.drift = drift_report(run.watch_report, run.tables.rows, run.invariants)
        if raise_on_failure:
            raise exception_for(status)(r.message, status=status, result=r)
    elif status in DRIFTS:
        r.drift = drift_report(run.watch_report, run.tables.rows, run.invariants)
        r.message = _planar_drift_message(scene, plan, run)
        if raise_on_failure:
            raise exception_for(status)(r.message, status=status, result=r)
    if status == Status.ERR_NO_MEMORY:
        r.message = _planar_no_memory(scene, plan, run)
        if raise_on_failure:
            raise exception_for(status)(r.message, status=status, result=r)
    if status.failed and raise_on_failure:
        message = (_index3_failure_message(scene, run.tables, plan, r) if plan.index3 else
                   _ode_failure_message(scene, run.tables, plan, r))
        raise exception_for(status)(message, status=status, result=r)
    return r


def _spatial_stability_note(scene: Scene, plan: RunPlan, r: SceneResult) -> str:
    """stability_note at a spatial fixed-step ODE run's last sample."""
    if not (r.status.failed and len(r.t) and not plan.info.adaptive and not plan.index3
            and not plan.dae) or r.status not in UNSTABLE_ENDS:
        return ""

    def f(yy):
        out = evaluate_spatial(scene, yy, float(r.t[-1]))
        if out["status"] != Status.SUCCESS:
            raise MbdkError("no evaluation")
        return out["ydot"]
    return stability_note(plan.method, plan.h, f, np.concatenate([r.q[-1], r.v[-1]]),
                          float(r.t[-1]))


def _spatial_drift_message(scene: Scene, plan: RunPlan, run: KernelRun) -> str:
    r, status = run.result, run.result.status
    head = f"{plan.method}/{plan.formulation} on spatial scene {scene.name!r}"
    if status == Status.ERR_CONSTRAINT_DRIFT and run.watch_report["quantity"] == 0:
        # not the watch: the kernel found the redundant joints' dependent rows independent
        return (f"{head} stopped at t = {r.t[-1] if len(r.t) else plan.t0:.6g}: the state left "
                "the joints so far that the rows of its redundant joints, dependent on the "
                "others on the joints, no longer agree with them; the projection formulation "
                "keeps the state on the joints, or take a smaller step")
    bodies = [b.name for b in scene.bodies]
    r.drift = drift_report(run.watch_report, scene.joint_rows(), run.invariants, bodies)
    said = drift_message(run.watch_report, scene.joint_rows(), run.invariants,
                         bodies).replace('D v', 'C w')
    remedy = ("A smaller step (small beside the period of the fastest motion), a "
              "higher-order method or watch=False (to study the drift) are the remedies"
              if status == Status.ERR_INVARIANT_DRIFT else
              "A smaller step, the projection formulation or watch=False (to study the "
              "drift) are the remedies")
    return f"{head}: {said}. " + remedy


def _spatial_failure_message(scene: Scene, plan: RunPlan, run: KernelRun) -> str:
    """A spatial run's failure other than drift, in words (memory, a singular pose or an angle
    set's lock, or the status's text)."""
    r, status, formulation = run.result, run.result.status, plan.formulation
    head = f"{plan.method}/{formulation} on spatial scene {scene.name!r}"
    nb = len(scene.bodies)
    if status == Status.ERR_NO_MEMORY:
        # the run's dense matrices: the Newton matrix over the method's unknowns, the penalty
        # formulation's over the velocities
        newton = (len(run.y0) + scene.rows * (2 if formulation in ("si2", "ggl") else 1)
                  if plan.dae or plan.index3 else len(run.y0))
        dense = [(f"the Newton matrix of {plan.method}", newton, "use an explicit method"),
                 ("the penalty formulation's M + alpha_p C^T C",
                  6 * nb * (formulation == "penalty"),
                  "use formulation reduced, baumgarte or projection")]
        return f"{head} ({nb} bodies): " + no_memory_message(r.stats.alloc_bytes, dense)
    if status == Status.ERR_SINGULAR_MATRIX:
        where = (f"stopped {stopped_at(r.stats, plan.t0)}" if len(r.t) else
                 "could not start (the initial state's assembly or first evaluation)")
        lock = lock_distance(scene, r.q[-1]) if len(r.t) else None
        if lock is not None and (lock < 1e-3 or not scene.joints):
            why = (f"the orientation angles reached their gimbal lock "
                   f"({LOCK_MEASURE[scene.rotation]} = {lock:.2g} at the last sample), where "
                   "their rates are undefined; rotation = 'quaternion' has no such point")
        elif formulation in DAE_FORMS and r.stats.steps:
            why = dae_singular_text(formulation)
        else:
            why = ("the joints' constraint rows lost their rank (a singular pose: rows that "
                   "were independent at the start became dependent), where the multipliers "
                   "are not unique")
        return f"{head} {where}: {why}"
    text = failure_text(status, plan.info.adaptive, plan.dae)
    return f"{head}: {text} ({stopped_at(r.stats, plan.t0)}){_ida_first_step_note(plan, r)}"


def _diagnose_spatial(scene: Scene, plan: RunPlan, run: KernelRun) -> SceneResult:
    r, status = run.result, run.result.status
    unstable = _spatial_stability_note(scene, plan, r)
    if unstable:    # the true cause: the method's step, not the mechanism
        if status in DRIFTS:
            r.drift = drift_report(run.watch_report, scene.joint_rows(), run.invariants,
                                   [b.name for b in scene.bodies])
        r.message = (f"{plan.method}/{plan.formulation} on spatial scene {scene.name!r}: "
                     f"{failure_text(status, False)} ({stopped_at(r.stats, plan.t0)}): "
                     f"{unstable}")
    elif status in DRIFTS:
        r.message = _spatial_drift_message(scene, plan, run)
    elif status.failed:
        r.message = _spatial_failure_message(scene, plan, run)
    if run.interrupted or status == Status.ERR_INTERRUPTED:
        raise SolveInterrupted(r.message, status=status, result=r)
    if status.failed and plan.request.raise_on_failure:
        raise exception_for(status)(r.message, status=status, result=r)
    return r


def diagnose(scene: Scene, plan: RunPlan, run: KernelRun) -> tuple[SceneResult, str | None]:
    """The run's result with its failure, if any, in words: raised as the status's exception
    (carrying the result) unless the plan asks for failures as results; and the text of the
    AccuracyWarning a successful run's multipliers call for, or None."""
    if plan.kind == "spatial":
        r = _diagnose_spatial(scene, plan, run)
        what = "the multipliers are"
        place = f"spatial scene {scene.name!r}"
        warn = plan.multipliers_note is not None
    else:
        r = _diagnose_planar(scene, plan, run)
        what = "the multipliers and reactions are"
        place = f"scene {scene.name!r}"
        warn = plan.multipliers_note is not None and \
            bool(plan.want & (OUTPUTS["multipliers"] | OUTPUTS["reactions"]))
    if not warn:
        return r, None
    return r, f"{plan.method}/{plan.formulation} on {place}: {what} {plan.multipliers_note}"
