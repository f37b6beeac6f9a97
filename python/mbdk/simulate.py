"""simulate(scene, method, formulation=..., h=..., t_end=...): the one entry that runs a scene,
for every method and formulation. The kernel builds the model once, integrates it with the whole
time loop compiled, and computes the outputs asked for at the samples, all in one call
(kernel/src/api/mbdk_f2py.f90, scene_run).

Methods and formulations (mbdk.methods() lists the methods):
  the ODE methods (rk4, bdf4, ...) on the DAE reduced to an ODE (Fekete 2023, section 3;
  kernel/src/model/mbdk_model.f90 is their manual):
    reduced     [M D^T; D 0][q''; lambda] = [f; gamma] at every evaluation (the default)
    baumgarte   gamma - 2 alpha Phi' - beta^2 Phi (defaults alpha = 1/h, beta = sqrt(2)/h, (3.34))
    penalty     Jalon-Bayo (3.35)-(3.40): alpha_p, omega_p, mu_p = 1e7, 10, 1
    projection  reduced + projection of q onto Phi = 0 and of v onto Phi' = 0 after every step
  trapezoidal_index3 on the index-3 DAE itself (kernel/src/dae/mbdk_trapezoidal_index3.f90):
    augmented_lagrangian  ALI3-P, the augmented Lagrangian with projections (the default)
    index3                the book's scheme (3.11)-(3.16)
    with a fixed step, or adaptive=True (local extrapolation, third order) or "estimated"
    (second order), with err_rtol, err_atol, dt_out, h_min, h_max; and Newton's max_iter
    (default 20).

Linear solves (solver=; the manifest's linear_solve says which one ran):
  auto            revolute_schur when every joint is revolute (up to 12 constraint rows), else
                  schur when every body has mass and inertia (in-house dense up to 12 rows,
                  sparse above), else kkt
  revolute_schur  S = D M^-1 D^T in closed 2 x 2 blocks from the joint points, block LDL^T
  schur           S from the nonzeros of D (any joint type), dense at any size: in-house block
                  LDL^T up to 12 rows (small_dense=False or more rows: LAPACK dpotrf/dpotrs)
  sparse          the same S kept sparse and factorised by SuiteSparse's AMD + LDL, O(N) for a
                  chain or tree; trapezoidal_index3's augmented Newton matrix likewise (its
                  symmetric part), and the assembly of the initial state
  kkt             [M D^T; D 0] by LAPACK's LU

Outputs (outputs=, default all; outputs=() gives t, q, v only and costs nothing per sample):
  "a" accelerations, "multipliers", "reactions" (per joint: Fx, Fy and the moment about the
  joint point (a driver's, a coupling's: the centroid), exerted by the joint on its body1, global
  frame: -D_body1^T lambda), "energy"
  (kinetic + potential, its parts, and the work of dampers, constraints and loads as the run
  integrated it, at every step whatever the samples (the watch's quadrature,
  kernel/src/model/mbdk_watch.f90); "work" their sum W, which energy_balance() takes),
  "residuals" (max |Phi|, max |Phi'|, max |D a - gamma|). An output not asked for is None in
  the result.

What a run must keep (watch=, mbdk.watch): the constraint residuals, the energy balance and the
momenta the scene conserves are checked while it runs; leaving them ends the run with
ConstraintDriftError, EnergyDriftError or InvariantDriftError.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import asdict, replace
from numbers import Integral

import numpy as np

from . import _compiled, _kernel, checks
from .codes import ADAPTIVE_MODES, OUTPUTS, SCENE_DAE_FORMS
from .errors import (AccuracyWarning, InvalidInputError, MbdkError, NotApplicableError,
                     SingularMatrixError, SolveInterrupted, Status, exception_for, failure_text,
                     no_memory_message, status_message, stopped_at)
from .index3 import INDEX3_FORMULATIONS, MAX_CUTS, NEAR_SINGULAR, factorisation

#: ida's forms of the scene's DAE (kernel/src/sundials/mbdk_ida.f90): the code it passes
IDA_FORMULATIONS = SCENE_DAE_FORMS["ida"]
#: bdf on the scene's DAE (kernel/src/dae/mbdk_scene_dae.f90), as MSC Adams' GSTIFF I3 and SI2
BDF_DAE_FORMULATIONS = SCENE_DAE_FORMS["bdf"]
BDF_DAE_FORMS = {"i3": "index 3 (GSTIFF I3): q' = v, M v' = f - D^T lam, 0 = Phi, index-scaled "
                       "Newton, error test on q and on h times v (index 2)",
                 "si2": "stabilised index 2 (GSTIFF SI2, GGL): q' = v - D^T mu, "
                        "M v' = f - D^T lam, 0 = Phi, 0 = D v + Phi_t, error test on q and v"}
IDA_FORMS = {"index1": "index 1: M v' + D^T lam = f, D v' = gamma (Phi, Phi' not kept)",
             "ggl": "stabilised index 2 (Gear-Gupta-Leimkuhler): q' = v - D^T mu, "
                    "M v' + D^T lam = f, Phi = 0, D v + Phi_t = 0"}
from .watch import as_watch, drift_message, drift_report, invariant_names
from .methods import method as _method
from .codes import FORMULATIONS, LINEAR_SOLVES, SOLVERS, VISIT_NAMES
from .model import (DENSE_NAMING_MAX, Tables, assembly_error,
                    assembly_report, build_tables, dependent_rows, given_mask, model_options,
                    pose_error, rows_to_joints, scaled_jacobian)
from .model import evaluate as _evaluate
from .ode import DEFAULT_MAX_STEPS, STARTUP, build_info, plan
from .options import Index3Options, ODEOptions, empty, projection_tol_for
from .result import SceneResult, Stats
from .checks import show
from .scene import GROUND, Scene, SceneError
from .scene_file import checked

_INT_MAX = 2**31 - 1


class RedundantConstraintsError(SingularMatrixError):
    """The constraint Jacobian has dependent rows: the reduced forms have no unique multipliers."""




def check_run(h, t_end, t0, every) -> None:
    """The step, interval and sampling of a scene run, as named errors."""
    for name, val in (("h", h), ("t_end", t_end), ("t0", t0)):
        checks.real(name, val)
    if not h > 0:
        raise InvalidInputError(f"h = {h} is not positive; give a step h > 0")
    if not t_end > t0:
        raise InvalidInputError(f"t_end = {t_end} must be greater than t0 = {t0}")
    if isinstance(every, bool) or not isinstance(every, Integral) or not 1 <= every <= _INT_MAX:
        raise InvalidInputError(f"every = {every!r} must be a whole number from 1 to {_INT_MAX}")


#: what to change when a scene run's samples do not fit in memory
SCENE_SAMPLE_ADVICE = ("fewer samples: a larger every (fixed step) or dt_out (error control), a "
                       "shorter t_end, or fewer outputs (outputs=() keeps t, q and v only)")


def scene_tolerances(rtol, atol) -> tuple[float, float]:
    """The rtol and atol of an error-controlled scene run, planar or spatial (one check, so that
    both refuse the same values): numbers, rtol in [RTOL_FLOOR, 1) or 0, atol > 0; a per-state
    atol is solve_ode's."""
    from .ode import RTOL_FLOOR
    return checks.tolerances(rtol, atol, where="a scene run", rtol_floor=RTOL_FLOOR)


def _want(outputs) -> int:
    if isinstance(outputs, str):
        outputs = (outputs,)
    try:
        names = list(outputs)
    except TypeError:
        raise InvalidInputError(f"outputs = {outputs!r} must be a list of names from "
                                f"{', '.join(OUTPUTS)}") from None
    bad = [o for o in names if not isinstance(o, str) or o not in OUTPUTS]
    if bad:
        raise InvalidInputError(f"outputs: {', '.join(map(show, bad))} unknown; known: "
                                f"{', '.join(OUTPUTS)}")
    return sum({OUTPUTS[o] for o in names})


_INDEX3_ONLY = ("adaptive", "err_rtol", "err_atol", "dt_out", "h_min", "h_max", "max_iter")


def simulate(scene: Scene, method: str, *, h: float | None = None, t_end: float,
             formulation: str | None = None, t0: float = 0.0, every: int = 1,
             outputs=tuple(OUTPUTS), alpha: float | None = None, beta: float | None = None,
             penalty: tuple = (1e7, 10.0, 1.0), projection_tol: float | None = None,
             solver: str = "auto", small_dense: bool = True, assemble_initial: bool = True,
             startup: str = "rk4", newton_rtol: float | None = None,
             newton_atol: float | None = None, max_iter: int | None = None,
             adaptive: bool | str | None = None, err_rtol: float | None = None,
             err_atol: float | None = None, dt_out: float | None = None,
             h_min: float | None = None, h_max: float | None = None,
             rtol: float | None = None, atol: float | None = None,
             max_steps: int | None = None, max_order: int | None = None,
             watch=True, locate_events: bool = True, raise_on_failure: bool = True,
             switch_angles: float | None = None,
             **unknown) -> SceneResult:
    """Integrate a scene. See the module docstring for methods, formulations and outputs.

    formulation: default "reduced" for the ODE methods, "augmented_lagrangian" for
    trapezoidal_index3. alpha: Baumgarte's alpha, or the augmented Lagrangian's penalty factor
    (default 0: 1e3 max(M) / (h^2/4) per step).

    newton_rtol/atol: the ODE methods' Newton (implicit ones) default to 1e-10/1e-12, but
    1e-7/1e-9 for the penalty formulation, whose accelerations carry roundoff amplified by
    alpha_p (~1e-9 at 1e7): a tighter test would never pass. trapezoidal_index3: 1e-10/1e-12,
    adaptive: a hundredth of err_rtol/err_atol where that is tighter (Newton then does not cap
    the accuracy asked for).

    adaptive (False, True = "extrapolated", "estimated"), err_rtol, err_atol, dt_out, h_min,
    h_max, max_iter: trapezoidal_index3 only (step-size control and Newton's iteration limit;
    mbdk.index3 says what they do).

    The error-controlled ODE methods (dopri54, bs32, bdf, cvode_bdf, cvode_adams) run every
    formulation but cvode_* the projection one: rtol, atol (a number), dt_out, h (the first
    step, optional), h_min, h_max, max_steps and max_order as in mbdk.solve_ode. Baumgarte's
    alpha and beta must then be given (their default, 1/h and sqrt(2)/h, needs a fixed step).
    ida integrates the scene's DAE itself (formulation "index1", the default, or "ggl") with
    the same options, and so does bdf with formulation "i3" (the index-3 form, as MSC Adams'
    GSTIFF I3) or "si2" (the stabilised index-2 form, as its SI2).

    watch: what the run must keep (mbdk.watch): True for the kernel's tolerances, False to turn
    the checks off, or a mbdk.Watch / dict with other tolerances. A run that leaves them raises
    ConstraintDriftError or EnergyDriftError at the check where it happened.

    locate_events: dopri54 and bs32 end a step where a contact closes or lets go (its force
    before the clip at zero changes sign), so that no step straddles the kink in the force
    (default True; the manifest says whether the run's method located them)."""
    if unknown:
        raise InvalidInputError(f"{', '.join(sorted(unknown))}: not an option of simulate; "
                                f"trapezoidal_index3 also takes {', '.join(_INDEX3_ONLY)}")
    if not isinstance(scene, Scene):
        raise InvalidInputError(f"scene must be an mbdk Scene (mbdk.scene(name) or "
                                f"mbdk.load_scene(path)), got {type(scene).__name__}")
    # re-read through the scene reader's checks, before anything reads its fields: fields
    # changed in Python after loading get the errors a file would (element, field, value)
    scene = checked(scene)
    from .spatial import simulate_spatial
    if scene.kind == "spatial":       # planar-only options given a value are refused there
        return simulate_spatial(
            scene, method, h=h, t_end=t_end, formulation=formulation, t0=t0, every=every,
            alpha=alpha, beta=beta, projection_tol=projection_tol,
            assemble_initial=assemble_initial, startup=startup, rtol=rtol, atol=atol,
            dt_out=dt_out, h_min=h_min, h_max=h_max, max_steps=max_steps, max_order=max_order,
            watch=watch, raise_on_failure=raise_on_failure, newton_rtol=newton_rtol,
            newton_atol=newton_atol, solver=None if solver == "auto" else solver,
            small_dense=None if small_dense else small_dense,
            penalty=None if _is_default_penalty(penalty) else penalty,
            switch_angles=switch_angles,
            adaptive=adaptive, err_rtol=err_rtol, err_atol=err_atol, max_iter=max_iter,
            outputs=outputs)
    if switch_angles is not None:
        raise NotApplicableError(f"switch_angles = {switch_angles!r}: an option of spatial "
                                 "scenes in angle coordinates; planar scenes have no gimbal lock")
    info_m = _method(method)
    index3 = info_m.family == "dae_index3"
    ida = info_m.family == "ida"
    own = INDEX3_FORMULATIONS if index3 else IDA_FORMULATIONS if ida else FORMULATIONS
    if info_m.family == "variable_bdf":
        own = {**FORMULATIONS, **BDF_DAE_FORMULATIONS}
    if formulation is None:
        formulation = next(iter(own)) if ida else ("augmented_lagrangian" if index3
                                                   else "reduced")
    if not isinstance(formulation, str):
        checks.choice("formulation", formulation, own, what=f"a formulation {method} runs")
    if formulation not in own:
        owners = [("the ODE methods run", FORMULATIONS),
                  ("trapezoidal_index3 runs", INDEX3_FORMULATIONS), ("ida runs", IDA_FORMULATIONS),
                  ("bdf runs", BDF_DAE_FORMULATIONS)]
        owner = next((o for o, forms in owners if formulation in forms), None)
        if owner is None:
            raise InvalidInputError(f"formulation = {formulation!r}; known: "
                                    f"{', '.join(FORMULATIONS)} (the ODE methods), "
                                    f"{', '.join(INDEX3_FORMULATIONS)} (trapezoidal_index3), "
                                    f"{', '.join(IDA_FORMULATIONS)} (ida), "
                                    f"{', '.join(BDF_DAE_FORMULATIONS)} (bdf on the DAE)")
        raise InvalidInputError(
            f"method {method!r} with formulation {formulation!r}: {owner} {formulation!r}; "
            f"{method} runs the formulations {', '.join(own)} and only those")
    given3 = {k: v for k, v in dict(adaptive=adaptive, err_rtol=err_rtol, err_atol=err_atol,
                                     dt_out=dt_out, h_min=h_min, h_max=h_max,
                                     max_iter=max_iter).items() if v is not None}
    given_tol = {k: v for k, v in dict(rtol=rtol, atol=atol, max_steps=max_steps,
                                       max_order=max_order).items() if v is not None}
    if given_tol and not info_m.adaptive:
        raise InvalidInputError(f"{', '.join(sorted(given_tol))}: options of the "
                                "error-controlled methods (dopri54, bs32, bdf, cvode_bdf, "
                                f"cvode_adams); {method} takes a fixed step h"
                                + (" (trapezoidal_index3's own error control: adaptive=True, "
                                   "err_rtol, err_atol)" if index3 else ""))
    if info_m.adaptive:
        given3 = {k: v for k, v in given3.items() if k not in ("dt_out", "h_min", "h_max")}
    if given3 and not index3:
        raise InvalidInputError(f"{', '.join(sorted(given3))}: options of trapezoidal_index3 "
                                f"only ({', '.join(_INDEX3_ONLY)})")
    checks.choice("solver", solver, SOLVERS, what="a linear solve")
    checks.choice("startup", startup, STARTUP, what="a start-up of the multistep methods")
    want = _want(outputs)
    watch_ = as_watch(watch)
    if info_m.adaptive:
        rtol, atol = scene_tolerances(rtol, atol)
        if every != 1:
            raise InvalidInputError(f"every = {every!r}: {method} chooses its own steps; give "
                                    "dt_out (the spacing of the samples) instead")
        if h == 0:
            h = None    # 0: the method chooses its first step, as in solve_ode
        check_run(1.0 if h is None else h, t_end, t0, every)
    else:
        if h is None:
            raise InvalidInputError(f"{method} takes a fixed step: give h (or use an "
                                    "error-controlled method with rtol and atol)")
        check_run(h, t_end, t0, every)
    every = int(every)
    dae_bdf = info_m.family == "variable_bdf" and formulation in BDF_DAE_FORMULATIONS
    dae_form = (IDA_FORMULATIONS.get(formulation, 0) if ida else
                BDF_DAE_FORMULATIONS.get(formulation, 0) if dae_bdf else 0)
    projection_given = projection_tol is not None
    projection_tol = projection_tol_for(
        projection_tol, (ODEOptions.atol if atol is None else atol) if info_m.adaptive else None)
    if ida or dae_bdf:
        unused = [name for name, given in (("alpha", alpha is not None),
                                           ("beta", beta is not None),
                                           ("penalty", not _is_default_penalty(penalty)),
                                           ("projection_tol", projection_given),
                                           ("startup", startup != "rk4"),
                                           ("newton_rtol", newton_rtol is not None),
                                           ("newton_atol", newton_atol is not None)) if given]
        if unused:
            raise InvalidInputError(
                f"{', '.join(unused)}: not options of {method} on the DAE itself (formulation "
                f"{formulation!r}); its Newton iteration follows rtol and atol")
        # the DAE itself: the model only evaluates (forces, Phi, D, gamma) and gives the
        # consistent initial multipliers by its reduced solve
        forms, about = (IDA_FORMULATIONS, IDA_FORMS) if ida else (BDF_DAE_FORMULATIONS,
                                                                  BDF_DAE_FORMS)
        plan_ = _ode_plan(info_m, "reduced", h if h else 1.0, t_end, t0, 1, None, None, penalty,
                          projection_tol, startup, newton_rtol, newton_atol,
                          adaptive=dict(h=h, rtol=rtol, atol=atol, dt_out=dt_out or 0.0,
                                        h_min=h_min or 0.0, h_max=h_max or 0.0,
                                        max_steps=max_steps or 0, max_order=max_order or 0))
        plan_["manifest"]["form"] = about[formulation]
        plan_["manifest"].pop("newton", None)   # no Newton option of its own
        mopt = model_options("reduced", 0.0, 0.0, penalty, projection_tol, solver, small_dense)
    elif info_m.adaptive:
        if formulation == "projection" and info_m.family == "cvode":
            raise NotApplicableError(
                f"{method} with formulation 'projection': CVODE keeps its own history of the "
                "state, which a projection after each step would contradict. Use bdf or "
                "dopri54 for projection, or cvode_* with reduced or baumgarte")
        if formulation == "baumgarte" and (alpha is None or beta is None):
            raise InvalidInputError(f"{method} with formulation 'baumgarte': give alpha and "
                                    "beta (Baumgarte's defaults 1/h and sqrt(2)/h need a fixed "
                                    "step; an error-controlled method has none)")
        plan_ = _ode_plan(info_m, formulation, h if h else 1.0, t_end, t0, 1, alpha, beta,
                          penalty, projection_tol, startup, newton_rtol, newton_atol,
                          adaptive=dict(h=h, rtol=rtol, atol=atol, dt_out=dt_out or 0.0,
                                        h_min=h_min or 0.0, h_max=h_max or 0.0,
                                        max_steps=max_steps or 0, max_order=max_order or 0))
        mopt = model_options(formulation, plan_["alpha"], plan_["beta"], penalty,
                             projection_tol, solver, small_dense)
    elif index3:
        plan_ = _index3_plan(formulation, h, t_end, t0, every, alpha, newton_rtol, newton_atol,
                             given3, small_dense)
        mopt = model_options(solver=solver, small_dense=small_dense)
    else:
        plan_ = _ode_plan(info_m, formulation, h, t_end, t0, every, alpha, beta, penalty,
                          projection_tol, startup, newton_rtol, newton_atol)
        mopt = model_options(formulation, plan_["alpha"], plan_["beta"], penalty,
                             projection_tol, solver, small_dense)
    mopt = replace(mopt, **watch_.options(), locate_events=int(bool(locate_events)))
    if solver == "revolute_schur":
        other = [f"{j.name} ({j.type})" for j in scene.joints if j.type != "revolute"]
        if other:
            raise InvalidInputError(f"{scene.source}: solver = 'revolute_schur' needs every joint "
                                    f"to be revolute; not revolute: {', '.join(other)}. Use "
                                    "solver = 'schur' or 'auto'")
    if solver in ("schur", "revolute_schur", "sparse") and any(b.inertia == 0 for b in scene.bodies):
        raise InvalidInputError(f"solver = {solver!r} needs every body to have inertia; "
                                f"{[b.name for b in scene.bodies if b.inertia == 0]} have none: "
                                "use solver = 'kkt' or 'auto'")

    contacts = [f.name for f in scene.forces if f.type == "contact"]
    if index3 and contacts:
        raise NotApplicableError(
            f"{method} on scene {scene.name!r}: its Newton matrix has no tangent stiffness of "
            f"the contacts ({', '.join(contacts)}); use an ODE method (rk4, dopri54, bdf, "
            "cvode_bdf) with formulation reduced, baumgarte or projection")
    for j in scene.joints:
        if j.type == "distance" and j.length is not None:
            # L(t) must stay positive over the run: at L = 0 the row has no direction
            off, rate, amp, om, ph = j.length
            ts = np.linspace(t0, t_end, 20001)
            low = np.nonzero(off + rate * ts + amp * np.sin(om * ts + ph) <= 0)[0]
            if low.size:
                raise SceneError(
                    f"{scene.source}: joint {j.name!r}: field 'length' = {_fn_text(j.length)} "
                    f"reaches 0 at t = {ts[low[0]]:.6g} s, within the run (t_end = {t_end:g}): "
                    "a distance must stay positive; end the run before, or change L(t)")
    knives = [j.name for j in scene.joints if j.type == "knife_edge"]
    if index3 and knives:
        raise NotApplicableError(
            f"{method} on scene {scene.name!r}: it solves the joints at position level, and the "
            f"knife edges ({', '.join(knives)}) constrain velocities only (nonholonomic); use an "
            "ODE method with formulation reduced, baumgarte or projection, bdf with formulation "
            "'i3' (index 2 in their rows) or ida with formulation 'index1'")
    if dae_form and knives and formulation in ("ggl", "si2"):
        raise NotApplicableError(
            f"{method}/{formulation} on scene {scene.name!r}: its mu stabilises position rows, "
            f"and the knife edges ({', '.join(knives)}) have none (nonholonomic); use "
            f"{'formulation index1' if ida else 'formulation i3'}")
    if method == "euler_cromer" and scene.wear:
        raise NotApplicableError(
            f"euler_cromer on scene {scene.name!r}: it integrates a state [q, v] of positions "
            f"and velocities, which has no place for the wear states "
            f"({', '.join(w.name for w in scene.wear)}); use rk4, heun or an error-controlled "
            "method")
    if dae_form and scene.wear:
        raise NotApplicableError(
            f"{method}/{formulation} on scene {scene.name!r}: the DAE's state [q, v, lambda] has "
            f"no place for the wear states ({', '.join(w.name for w in scene.wear)}); use an ODE "
            "method with formulation reduced, baumgarte or projection")
    if assemble_initial and any(f.type == "contact" and f.shape1[0] == "gear"
                                for f in scene.forces):
        scene = _gears_at_assembled_pose(scene, t0)
    # built once: the kernel fills in the values taken from the pose where it starts the run
    tab = build_tables(scene, resolve=False)
    # the state [q; v; w]: the wear elements' volumes after the bodies' coordinates and rates
    y0 = np.concatenate([np.array(scene.q0(), float), np.array(scene.v0(), float),
                         np.array([w.initial for w in scene.wear], float)])
    given = np.concatenate([given_mask(scene), np.zeros(len(scene.wear), np.int32)])
    nsamp, nc, m = plan_["nsamp"], tab.nc, tab.m

    def cols(bit):   # an output not asked for gets one column the kernel leaves alone
        return nsamp if (want & bit) or index3 or (dae_form and bit == 2) else 1
    # the samples: t and y (allocated by the f2py layer), the outputs' arrays here; refused
    # before they are allocated where the machine has not that much memory
    nbytes = 8.0 * (nsamp * (1 + y0.size) + nc * cols(1) + max(m, 1) * cols(2)
                    + 3 * max(tab.nj, 1) * (nsamp if want & 4 else 1)
                    + 9 * (nsamp if want & 8 else 1) + 3 * (nsamp if want & 16 else 1)
                    + (nsamp / 2 if index3 else 0))
    what = f"{method} on scene {scene.name!r} ({nsamp} samples)"
    checks.check_memory(nbytes, what=what, change=SCENE_SAMPLE_ADVICE)
    try:
        a_out = np.zeros((nc, cols(1)), order="F")
        lam_out = np.zeros((max(m, 1), cols(2)), order="F")
        iters = np.zeros(nsamp if index3 else 1, np.int32)
        reac = np.zeros((3, max(tab.nj, 1), nsamp if want & 4 else 1), order="F")
        energy = np.zeros((9, nsamp if want & 8 else 1), order="F")
        resid = np.zeros((3, nsamp if want & 16 else 1), order="F")
    except MemoryError as exc:
        raise checks.memory_error(exc, nbytes, what=what, change=SCENE_SAMPLE_ADVICE) from None
    stats, visits, flag = empty("mbdk_stats"), np.zeros(len(VISIT_NAMES)), _compiled.new_flag()
    args = (*tab.args(), mopt.pack(), info_m.id, dae_form, plan_["ode"].pack(),
            plan_["index3"].pack(),
            flag, y0, given, int(bool(assemble_initial)), t0, t_end, want, nsamp,
            a_out, lam_out, iters, reac, energy, resid, stats, visits)
    try:
        (t, y, nw, path, asm_iters, asm_resid, asm_velocity, bad_joint, bad_force, watch_report,
         invariants, ninv, status), interrupted = _compiled.call(
             _kernel.scene_run, args, flag, plan_["steps"] * y0.size, span=(t0, t_end))
    except MemoryError as exc:   # t and y, allocated by the f2py layer
        raise checks.memory_error(exc, nbytes, what=what, change=SCENE_SAMPLE_ADVICE) from None
    status = Status(int(status))
    nw = int(nw)
    if bad_joint or bad_force:
        raise pose_error(scene, int(bad_joint), int(bad_force))
    if status == Status.ERR_INCONSISTENT_INITIAL and dae_form and (nw or not assemble_initial):
        raise InvalidInputError(
            f"{method}/{formulation} on scene {scene.name!r}: the initial state does not satisfy "
            "the constraints (Phi = 0, D v + Phi_t = 0) to 1e-10, which the DAE forms need: keep "
            "assemble_initial=True, or give a consistent pose and velocities",
            status=status)
    if status == Status.ERR_INCONSISTENT_INITIAL:
        raise assembly_error(scene, tab, asm_resid, velocity=bool(asm_velocity))
    # the first sample is the (assembled) initial state
    report = (assembly_report(scene, y0[:nc], y0[nc:2 * nc], y[:nc, 0], y[nc:2 * nc, 0],
                              int(asm_iters))
              if assemble_initial and nw else {})
    # the results are views of the arrays the kernel wrote, not copies: a long run's peak
    # memory is its result arrays once (tests/test_pipeline.py measures it)
    t, y = t[:nw], y[:, :nw]
    stats = Stats.from_words(stats)
    manifest = {**build_info(), "scene": scene.name, "source": scene.source, "method": method,
                "formulation": formulation, "h": h, "t0": t0, "t_end": t_end, "every": every,
                "outputs": [o for o in OUTPUTS if want & OUTPUTS[o]],
                "solver": solver, "linear_solve": LINEAR_SOLVES.get(int(path), "not built"),
                "small_dense": small_dense,
                "watch": asdict(watch_),
                "invariants": invariant_names(invariants[:, :int(ninv)].T),
                "locate_events": bool(locate_events) and method in ("dopri54", "bs32"),
                **plan_["manifest"]}
    if index3 or info_m.adaptive:
        manifest["steps"] = stats.steps
    book_lambda = index3 and formulation == "index3" and m > 0
    if book_lambda:
        manifest["multipliers"] = BOOK_MULTIPLIERS
    loose_lambda = ggl_multipliers(method, formulation, rtol) if m > 0 else None
    if loose_lambda:
        manifest["multipliers"] = loose_lambda
    result = SceneResult(
        t=t, q=y[:nc].T, v=y[nc:2 * nc].T,
        a=a_out[:, :nw].T if want & 1 else None,
        multipliers=lam_out[:m, :nw].T if want & 2 else None,
        reactions=np.transpose(reac[:, :tab.nj, :nw], (2, 1, 0)) if want & 4 else None,
        energy=None, energy_parts=None,
        residuals=resid[:, :nw].T if want & 16 else None,
        stats=stats, status=status, message=status_message(status),
        visits=dict(zip(VISIT_NAMES, (int(x) for x in visits))), manifest=manifest,
        assembly=report, joints=[j.name for j in scene.joints],
        bodies=[b.name for b in scene.bodies],
        iterations=np.array(iters[:nw]) if index3 else None,
        wear={w.name: y[2 * nc + k] for k, w in enumerate(scene.wear)}, kind="planar")
    if want & 8:
        kin, vg, vs, pd, pc, pl, wd, wc, wl = energy[:, :nw]
        result.energy = kin + vg + vs
        result.energy_parts = {
            "kinetic": kin, "potential_gravity": vg, "potential_springs": vs,
            "power": pl + pc - pd, "work": wl + wc - wd,
            "power_dampers": pd, "power_constraints": pc, "power_loads": pl,
            "dissipated_dampers": wd, "work_constraints": wc, "work_loads": wl}
    if status == Status.ERR_INTERRUPTED or interrupted:
        raise SolveInterrupted(f"{method}/{formulation} on scene {scene.name!r}: interrupted"
                               + (f" at t = {t[-1]:.6g}" if nw else ""), status=status,
                               result=result)
    if status == Status.ERR_SINGULAR_MATRIX and m and nw <= 1:
        if nw:
            q0, v0 = result.q[0], result.v[0]
        else:   # the consistent start of index3 failed: the state it would start from
            q0, v0 = y0[:nc], y0[nc:2 * nc]
            if assemble_initial:
                from .model import assemble
                q0, v0, _ = assemble(scene, build_tables(scene), t0)
        _refuse_redundant(scene, build_tables(scene, q0), q0, v0, t0, formulation, index3,
                          result, dae=bool(dae_form))
    unstable = ""
    if status in _UNSTABLE_ENDS and not info_m.adaptive and not index3 and not dae_form:
        unstable = _planar_stability_note(scene, method, h, result)
    drifts = (Status.ERR_CONSTRAINT_DRIFT, Status.ERR_ENERGY_DRIFT, Status.ERR_INVARIANT_DRIFT)
    inv = invariants[:, :int(ninv)].T
    if unstable:    # the true cause: the method's step, not the mechanism
        result.message = (f"{method}/{formulation} on scene {scene.name!r}: "
                          f"{failure_text(status, False)} ({stopped_at(result.stats, t0)}): "
                          f"{unstable}")
        if status in drifts:
            result.drift = drift_report(watch_report, tab.rows, inv)
        if raise_on_failure:
            raise exception_for(status)(result.message, status=status, result=result)
    elif status in drifts:
        result.drift = drift_report(watch_report, tab.rows, inv)
        advice = _DRIFT_ADVICE[status]
        if index3:   # it is the index-3 form already: the stabilised ODE forms are no remedy
            advice = advice.replace(" or trapezoidal_index3", "").replace(
                "a stabilised formulation (baumgarte, projection)",
                "formulation = 'augmented_lagrangian' (which projects v and a)")
        note = _singular_note(scene, tab, result)
        if note:   # the check failed next to a singular configuration: that is the cause
            passes = ("" if index3 and formulation == "augmented_lagrangian" else
                      "A formulation that keeps the constraints through it is "
                      "trapezoidal_index3 (augmented_lagrangian); ")
            advice = (f"It failed at a singular configuration: {note}. {passes}a driver or "
                      "load that pushes the mechanism against a dead point has no solution "
                      "there. watch=False accepts the run as it is.")
        result.message = (f"{method}/{formulation} on scene {scene.name!r}: "
                          f"{drift_message(watch_report, tab.rows, inv)}. " + advice)
        if raise_on_failure:
            raise exception_for(status)(result.message, status=status, result=result)
    if status == Status.ERR_NO_MEMORY:
        # the run's dense matrices: the Newton matrix over the method's unknowns, the
        # penalty formulation's over the coordinates
        newton = (2 * nc + m * (2 if formulation in ("si2", "ggl") else 1) if dae_form else
                  nc + m * (formulation == "index3") if index3 else y0.size)
        dense = [(f"the Newton matrix of {method}", newton, "use an explicit method, or "
                  "trapezoidal_index3 (augmented_lagrangian: sparse on large scenes)"),
                 ("the penalty formulation's M + alpha_p D^T D", nc * (formulation == "penalty"),
                  "use formulation reduced, baumgarte or projection (sparse on large scenes)")]
        result.message = (f"{method}/{formulation} on scene {scene.name!r} ({len(scene.bodies)} "
                          f"bodies): " + no_memory_message(stats.alloc_bytes, dense))
        if raise_on_failure:
            raise exception_for(status)(result.message, status=status, result=result)
    if status.failed and raise_on_failure:
        raise exception_for(status)(_failure_message(scene, tab, method, formulation, index3,
                                                     plan_, result), status=status,
                                    result=result)
    if (book_lambda or loose_lambda) and want & (OUTPUTS["multipliers"] | OUTPUTS["reactions"]):
        warnings.warn(f"{method}/{formulation} on scene {scene.name!r}: the multipliers and "
                      f"reactions are {loose_lambda or BOOK_MULTIPLIERS}", AccuracyWarning,
                      stacklevel=2)
    return result


# the reduced formulation refuses a relative pivot of D M^-1 D^T below this (the kernel's)
REDUCED_NEAR_PIVOT = float(_kernel.model_constants())

_DRIFT_ADVICE = {
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


#: adaptive trapezoidal_index3 without Newton tolerances given: these times err_rtol/err_atol
#: (at most the fixed-step defaults), not below NEWTON_FLOOR
NEWTON_SHARE, NEWTON_FLOOR = 0.01, 64 * float(np.finfo(float).eps)


EXTRAPOLATED_TEXT = ("local Richardson extrapolation: two steps of H/2 against one of H, "
                     "error (y_H/2 - y_H)/3 on q and v, the step's result (4 y_H/2 - y_H)/3 "
                     "projected onto Phi = 0, Phi' = 0")


def _adaptive_mode(adaptive) -> int:
    """The kernel's code of an adaptive= value: a bool (numpy's too) or a mode's name; other
    values, 0 and 1 included, are refused (1 would read as the kernel's code of 'estimated')."""
    if isinstance(adaptive, np.bool_):
        adaptive = bool(adaptive)
    if isinstance(adaptive, (bool, str)) and adaptive in ADAPTIVE_MODES:
        return ADAPTIVE_MODES[adaptive]
    raise InvalidInputError(f"adaptive = {adaptive!r} must be False, True (= 'extrapolated') "
                            "or 'estimated'")


def _real(name: str, value) -> float:
    """A number argument as float: a real number (not a bool, a string or None), finite."""
    return checks.real(name, value)


def _ode_plan(info_m, formulation, h, t_end, t0, every, alpha, beta, penalty, projection_tol,
              startup, newton_rtol, newton_atol, adaptive: dict | None = None) -> dict:
    checks.choice("startup", startup, STARTUP, what="a start-up of the multistep methods")
    alpha = 1.0 / h if alpha is None else _real("alpha", alpha)
    beta = math.sqrt(2.0) / h if beta is None else _real("beta", beta)
    if formulation == "baumgarte" and not (alpha >= 0 and beta >= 0 and math.isfinite(alpha)
                                           and math.isfinite(beta)):
        raise InvalidInputError(f"alpha = {alpha}, beta = {beta}: Baumgarte parameters must be "
                                "finite and >= 0")
    if isinstance(penalty, (str, bytes, dict)) or not hasattr(penalty, "__len__") or \
            len(penalty) != 3 or not all(checks.number_problem(p, in_range=False) is None
                                         and p > 0 for p in penalty):
        raise InvalidInputError(f"penalty = {show(penalty)} must be (alpha_p, omega_p, mu_p), "
                                "finite, all > 0")
    if not (_real("projection_tol", projection_tol) > 0):
        raise InvalidInputError(f"projection_tol = {projection_tol} must be > 0")
    if adaptive is not None:
        from .ode import adaptive_options
        ode, nsteps, nsamp, control = adaptive_options(
            info_m, adaptive["h"], t0, t_end, 1, adaptive["rtol"], adaptive["atol"],
            adaptive["dt_out"], adaptive["h_min"], adaptive["h_max"], adaptive["max_steps"],
            adaptive["max_order"], False)
        shortened = False
    else:
        nsteps, nsamp, shortened = plan(t0, t_end, h, every)
    if info_m.steps > 1 and shortened:   # the kernel's whole-number test (mbdk_on_grid)
        n_lo = math.floor((t_end - t0) / h)
        raise InvalidInputError(f"{info_m.name} needs equal steps; use h = "
                                f"{(t_end - t0) / max(n_lo, 1):.12g}")
    if newton_rtol is None:
        newton_rtol = 1e-7 if formulation == "penalty" else ODEOptions.newton_rtol
    if newton_atol is None:
        newton_atol = 1e-9 if formulation == "penalty" else ODEOptions.newton_atol
    newton_rtol = _real("newton_rtol", newton_rtol)
    newton_atol = _real("newton_atol", newton_atol)
    if not (newton_rtol > 0 and newton_atol > 0):
        raise InvalidInputError(f"newton_rtol = {newton_rtol}, newton_atol = {newton_atol} must be > 0")
    if adaptive is not None:
        ode = replace(ode, newton_rtol=newton_rtol, newton_atol=newton_atol)
        manifest = {**control, "newton": {"rtol": newton_rtol, "atol": newton_atol}}
    else:
        ode = ODEOptions(h=h, newton_rtol=newton_rtol, newton_atol=newton_atol, every=every,
                         startup=STARTUP[startup])
        manifest = {"steps": nsteps, "startup": startup,
                    "newton": {"rtol": newton_rtol, "atol": newton_atol,
                               "max_iter": ode.newton_max_iter}}
    if formulation == "baumgarte":
        manifest.update(alpha=alpha, beta=beta)
    if formulation == "penalty":
        manifest.update(alpha_p=penalty[0], omega_p=penalty[1], mu_p=penalty[2])
    if formulation == "projection":
        manifest.update(projection_tol=projection_tol)
    return {"ode": ode, "index3": Index3Options(), "nsamp": nsamp, "steps": nsteps,
            "manifest": manifest, "alpha": alpha, "beta": beta}


def _index3_plan(formulation, h, t_end, t0, every, alpha, newton_rtol, newton_atol,
                 given3, small_dense) -> dict:
    d = Index3Options()
    rtol = d.newton_rtol if newton_rtol is None else _real("newton_rtol", newton_rtol)
    atol = d.newton_atol if newton_atol is None else _real("newton_atol", newton_atol)
    if not (rtol >= 0 and atol > 0):
        raise InvalidInputError(f"newton_rtol = {rtol}, newton_atol = {atol}: need rtol >= 0 "
                                "and atol > 0")
    max_iter = given3.get("max_iter", d.newton_max_iter)
    if isinstance(max_iter, bool) or not isinstance(max_iter, Integral) or \
            not 1 <= max_iter <= 10**6:
        raise InvalidInputError(f"max_iter = {max_iter!r} must be a whole number from 1 to 1e6")
    alpha = d.alpha if alpha is None else _real("alpha", alpha)
    if formulation == "augmented_lagrangian" and not (alpha >= 0 and math.isfinite(alpha)):
        raise InvalidInputError(f"alpha = {alpha}: the augmented Lagrangian's penalty factor "
                                "must be finite and > 0, or 0 for the default (1e3 max(M) "
                                "/ (h^2/4) at every step)")
    mode = _adaptive_mode(given3.get("adaptive", False))
    adaptive = mode > 0
    err_rtol = given3.get("err_rtol", d.err_rtol)
    err_atol = given3.get("err_atol", d.err_atol)
    dt_out = given3.get("dt_out", h * every)
    h_min = given3.get("h_min", d.h_min)
    h_max = given3.get("h_max", d.h_max)
    if adaptive and formulation == "index3":
        raise NotApplicableError(
            f"adaptive={given3['adaptive']!r} with formulation 'index3': the book's scheme "
            "leaves its velocities "
            "off Phi' = 0 by a period-2 oscillation that grows with time and soon exceeds the "
            "local error, so an error test on q and v would shrink h without end (studies/"
            "index3.py, table index3_long_runs). Use formulation='augmented_lagrangian' for "
            "step-size control, or a fixed h")
    if adaptive:
        for name, val, low in (("err_rtol", err_rtol, 0.0), ("err_atol", err_atol, None),
                               ("dt_out", dt_out, None), ("h_min", h_min, 0.0),
                               ("h_max", h_max, 0.0)):
            val = _real(name, val)
            if not (val >= low if low is not None else val > 0):
                raise InvalidInputError(f"{name} = {val!r} must be a finite number "
                                        f"{'>= 0' if low is not None else '> 0'}")
        err_rtol, err_atol = float(err_rtol), float(err_atol)
        dt_out, h_min, h_max = float(dt_out), float(h_min), float(h_max)
        if h_max and h_min > h_max:
            raise InvalidInputError(f"h_min = {h_min} exceeds h_max = {h_max}")
        checks.step_bounds(t0, t_end, h_max, 0, default_steps=DEFAULT_MAX_STEPS,
                           has_max_steps=False)
    if adaptive:
        # Newton's tolerances follow the error test's (a hundredth of it, SUNDIALS' practice
        # of a tenth with a margin), so that a tight err_rtol is not capped by the default
        # Newton tolerance; never below the roundoff of the iterates
        if newton_rtol is None and err_rtol > 0:   # err_rtol = 0: absolute control only
            rtol = max(min(rtol, NEWTON_SHARE * err_rtol), NEWTON_FLOOR)
        if newton_atol is None:
            atol = max(min(atol, NEWTON_SHARE * err_atol), NEWTON_FLOOR)
    opt = Index3Options(h=h, newton_rtol=rtol, newton_atol=atol, alpha=alpha,
                        err_rtol=err_rtol, err_atol=err_atol, dt_out=dt_out, h_min=h_min,
                        h_max=h_max, formulation=INDEX3_FORMULATIONS[formulation],
                        every=every, newton_max_iter=int(max_iter), adaptive=mode)
    nsteps, nsamp, status = _kernel.index3_plan(opt.pack(), t0, t_end)
    if status < 0:
        raise InvalidInputError(
            f"h = {h}, t0 = {t0}, t_end = {t_end}, every = {every}"
            + (f", dt_out = {dt_out}" if adaptive else "")
            + " give no valid plan: need 0 < " + ("dt_out" if adaptive else "h")
            + " <= t_end - t0 and at most 2e9 " + ("samples" if adaptive else "steps"))
    manifest = {"newton": {"rtol": rtol, "atol": atol, "max_iter": int(max_iter),
                           "matrix": "analytic, reused while Newton contracts; "
                                     + factorisation(formulation, small_dense)}}
    if formulation == "augmented_lagrangian":
        manifest["alpha"] = alpha if alpha > 0 else "1e3 max(M) / (h^2/4), per step"
    if adaptive:
        manifest["step_control"] = {"err_rtol": err_rtol, "err_atol": err_atol,
                                    "dt_out": dt_out, "h0": h, "h_min": h_min, "h_max": h_max,
                                    "mode": "estimated" if mode == 1 else "extrapolated",
                                    "estimate": ("h^2/12 |a+ - a| on q, h^3/12 |a''| on v"
                                                 if mode == 1 else EXTRAPOLATED_TEXT)}
    return {"ode": ODEOptions(), "index3": opt, "nsamp": int(nsamp),
            # adaptive: the steps are not known in advance, the run always counts as long
            # (a worker thread, interruptible)
            "steps": float(nsteps) if not adaptive else math.inf, "manifest": manifest,
            "adaptive": adaptive}


def _is_default_penalty(penalty) -> bool:
    """penalty is simulate's default (1e7, 10, 1), as a tuple, a list or an array."""
    try:
        return tuple(float(p) for p in penalty) == (1e7, 10.0, 1.0)
    except (TypeError, ValueError, OverflowError):
        return False


def _fn_text(fn) -> str:
    """A time function as the scene file writes it."""
    keys = ("offset", "rate", "amplitude", "omega", "phase")
    return "{" + ", ".join(f"{k} = {v:g}" for k, v in zip(keys, fn) if v) + "}"


def _distance_note(scene: Scene, r) -> str:
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


def _refuse_redundant(scene, tab, q0, v0, t0, formulation, index3, result, dae=False):
    """A singular solve at the initial state: name the dependent joints, if any (not on a scene
    too large for the dense SVD that finds them)."""
    if _too_large_to_name(tab):
        return
    d0 = scaled_jacobian(tab, _evaluate(tab, q0, v0, t0)["D"])
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


def _too_large_to_name(tab: Tables) -> bool:
    """Whether the dense D of the scene is beyond what an error message may form and decompose
    (mbdk.model.DENSE_NAMING_MAX entries)."""
    return tab.m * 3 * len(tab.mass) > DENSE_NAMING_MAX


def resolved(scene: Scene, r: SceneResult) -> Tables:
    """The tables of a run as the kernel used them: pose values taken at its first sample."""
    return build_tables(scene, r.q[0])


#: the book scheme's multipliers, as its results and warnings say (studies/index3.py measures it)
BOOK_MULTIPLIERS = (
    "not converged: the book's index-3 scheme (formulation 'index3') leaves v and a off the "
    "derived constraints by a period-2 oscillation amplified by 2/h and 4/h^2, so lambda and the "
    "reactions carry an error that grows as h shrinks (studies/index3.py measures it); "
    "formulation 'augmented_lagrangian' gives them at second order")


#: ida's GGL form tests its multipliers no tighter than this relative to the largest (the
#: kernel's LAM_RTOL_FLOOR, kernel/src/sundials/mbdk_ida.f90: the index-2 iteration's roundoff)
GGL_LAMBDA_RTOL = 1e-8


def ggl_multipliers(method: str, formulation: str, rtol) -> str | None:
    """What a run's manifest and warning say of its multipliers where ida's GGL form gives them
    less accurately than rtol asks (rtol below GGL_LAMBDA_RTOL); None elsewhere."""
    if method != "ida" or formulation != "ggl" or rtol is None or not rtol < GGL_LAMBDA_RTOL:
        return None
    return (f"converged to about {GGL_LAMBDA_RTOL:g} of the largest multiplier, not to rtol = "
            f"{rtol:g}: ida's GGL form tests them no tighter, the roundoff of its index-2 "
            "iteration; the index1 form, or bdf's si2 form, gives them to the tolerance")


def _gears_at_assembled_pose(scene: Scene, t0: float) -> Scene:
    """The scene with its bodies at the pose and rates its initial assembly gives. A gear mesh's
    phases, and its check that the gears mesh, are taken from the bodies' poses: they must be
    those where the axle joints put the gears, not those the file writes (an axle joint moving a
    gear out of mesh ran on, or into a non-finite state)."""
    from .model import assemble
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


#: the states whose Jacobian a failure message may form by differences (2 n kernel calls)
STABILITY_NAMING_MAX = 400

#: failures an explicit step beyond its stability limit ends in: an overflow, drift caught by
#: the watch, or a constrained solve at a state the growing mode carried far off
_UNSTABLE_ENDS = (Status.ERR_NONFINITE, Status.ERR_ENERGY_DRIFT, Status.ERR_CONSTRAINT_DRIFT,
                  Status.ERR_INVARIANT_DRIFT, Status.ERR_SINGULAR_MATRIX)


def _stability_note(method, h, f, y, t) -> str:
    """Whether the fixed step h of method lies beyond its stability limit for a mode of the
    scene that does not grow (mbdk.stability.instability_note), from the Jacobian of the reduced
    ODE y' = f(y) at y by central differences; '' where it does not, or f fails there."""
    from .stability import instability_note
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


def _planar_stability_note(scene, method, h, r) -> str:
    """_stability_note at a planar run's last sample, on the reduced ODE [v; a(q, v)]."""
    if not len(r.t) or h is None:
        return ""
    tab = resolved(scene, r)
    nc = r.q.shape[1]

    def f(y):
        out = _evaluate(tab, y[:nc], y[nc:], r.t[-1])
        if out["status"] != Status.SUCCESS:
            raise MbdkError("no evaluation")
        return np.concatenate([y[nc:], out["a"]])

    return _stability_note(method, h, f, np.concatenate([r.q[-1], r.v[-1]]), r.t[-1])


def _singular_note(scene, tab: Tables, r) -> str:
    """Where D is close to losing a rank at the last sample (the state the failed step started
    from): the smallest / largest singular value of the scaled Jacobian and the joints of the
    rows the vanishing direction involves, in words; empty elsewhere."""
    if not (len(r.t) and tab.m) or _too_large_to_name(tab):
        return ""
    if not (np.all(np.isfinite(r.q[-1])) and np.all(np.isfinite(r.v[-1]))):
        return ""   # a blown-up run (watch off): no configuration to speak of
    tab_r = resolved(scene, r)
    d = scaled_jacobian(tab_r, _evaluate(tab_r, r.q[-1], r.v[-1], r.t[-1])["D"])
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


def _failure_message(scene, tab: Tables, method, formulation, index3, plan_, r) -> str:
    nw = len(r.t)
    if not index3:
        where = stopped_at(r.stats, r.manifest.get("t0", 0.0))
        note = ""
        if r.status == Status.ERR_SINGULAR_MATRIX and nw and not _too_large_to_name(tab):
            tab_r = resolved(scene, r)
            dep = dependent_rows(scaled_jacobian(
                tab_r, _evaluate(tab_r, r.q[-1], r.v[-1], r.t[-1])["D"]))
            if dep:
                note = (f": joint(s) {', '.join(rows_to_joints(tab, dep))} became dependent "
                        "(a singular configuration)")
        if not note and r.status == Status.ERR_SINGULAR_MATRIX and formulation == "reduced" \
                and nw and not _singular_note(scene, tab, r):
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
            note = _distance_note(scene, r)
        if not note and r.status == Status.ERR_NONFINITE and contacts:
            note = (f"; a contact may have no normal there ({', '.join(contacts)}): two circles "
                    "whose centres coincide, or gears whose centres came within their base "
                    "circles' sum; a smaller h or a stiffer contact keeps them apart")
        if not note:
            note = _singular_note(scene, tab, r)
            if note:   # a smaller h meets the singular configuration as well
                refuse = (" The reduced formulation refuses a near rank loss (its accelerations "
                          "amplify the drift of v there, and a step across it can land on "
                          "another assembly branch)." if formulation == "reduced" else "")
                note = (f"; there {note}.{refuse} A smaller h meets it too: "
                        "trapezoidal_index3 (augmented_lagrangian) passes singular crossings "
                        "(baumgarte and projection where no stage lands on the rank loss); a "
                        "driver or load that pushes the mechanism against a dead point has no "
                        "solution there")
        text = failure_text(r.status, _method(method).adaptive,
                            formulation in ("i3", "si2", "index1", "ggl"))
        return f"{method}/{formulation} on scene {scene.name!r}: {text} ({where}){note}"
    where = (f"in the step after t = {r.stats.t_reached:.6g}" if r.stats.steps else
             "in the first step")
    if nw and not plan_["adaptive"] and formulation == "augmented_lagrangian" and r.status in (
            Status.ERR_NEWTON_DIVERGED, Status.ERR_NONFINITE, Status.ERR_SINGULAR_MATRIX):
        where += f", also in substeps down to h/{4 ** MAX_CUTS}"
    if plan_["adaptive"] and r.status == Status.ERR_NEWTON_DIVERGED:
        # adaptive, every Newton failure is retried until the budget runs out (extrapolated:
        # steps the error test could only judge next to a rank loss draw on it too)
        judged = plan_["index3"].adaptive == ADAPTIVE_MODES["extrapolated"]
        where += (f"; {r.stats.newton_failures} Newton failures in {r.stats.steps} steps"
                  + (", and steps judged next to a rank loss," if judged else "")
                  + " exhausted the retry budget (more than one attempt in ten failing)")
    note = _singular_note(scene, tab, r)
    remedy = "A smaller h, or a larger max_iter, may get past it"
    if note and plan_["adaptive"] and r.status == Status.ERR_STEP_TOO_SMALL and \
            plan_["index3"].adaptive == ADAPTIVE_MODES["extrapolated"]:
        # the three solves of a macro step differ by what Newton and the projections leave,
        # amplified along the vanishing direction: that difference does not fall with H
        remedy = ("Next to the rank loss the extrapolated control's three solves differ by "
                  "their own residuals, amplified along the vanishing direction, by more than "
                  "err_rtol and err_atol ask, whatever the step: its error estimate is noise "
                  "there. adaptive='estimated' (whose estimate is no difference of solves) "
                  "passes such poses, or looser err_rtol and err_atol do")
    note = f"; there {note}" if note else ""
    return (f"trapezoidal_index3/{formulation} on scene {scene.name!r}: {r.message} ({where})"
            f"{note}. {remedy}")


def evaluate(scene: Scene, q=None, v=None, t: float = 0.0, formulation: str = "reduced",
             solver: str = "auto", **params) -> dict:
    """A scene at one state, from the kernel: Phi, D, gamma, Phi_t, the generalised forces f,
    the formulation's accelerations a and multipliers lam, and the linear solve it took. q, v
    default to the scene's assembled initial state; values the scene takes from its initial pose
    (rest lengths, relative angles) are taken there. params: alpha, beta, penalty,
    projection_tol, small_dense as for simulate."""
    from .model import assemble
    if not isinstance(scene, Scene):
        raise InvalidInputError(f"scene must be an mbdk Scene, got {type(scene).__name__}")
    checks.choice("formulation", formulation, FORMULATIONS, what="a formulation")
    checks.choice("solver", solver, SOLVERS, what="a linear solve")
    unknown = set(params) - {"alpha", "beta", "penalty", "projection_tol", "small_dense"}
    if unknown:
        raise InvalidInputError(f"{', '.join(sorted(unknown))}: not a parameter of evaluate")
    scene = checked(scene)
    q0, v0, _ = assemble(scene, build_tables(scene), t)
    q = q0 if q is None else np.asarray(q, float)
    v = v0 if v is None else np.asarray(v, float)
    if q.shape != q0.shape or v.shape != v0.shape:
        raise InvalidInputError(f"q and v need {q0.size} entries each (3 per body), got "
                                f"{q.size} and {v.size}")
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
        raise InvalidInputError("q and v must be finite")
    out = _evaluate(build_tables(scene, q0), q, v, float(t), formulation,
                    model_options(formulation, solver=solver, **params))
    if out["status"].failed:
        raise exception_for(out["status"])(f"evaluating scene {scene.name!r} ({formulation}): "
                                           f"{status_message(out['status'])}",
                                           status=out["status"])
    return out
