"""The plan of a scene run: simulate's arguments checked against the method, the formulation and
the scene's body kind, and turned into what the kernel is given.

make_plan(scene, request) resolves the method's formulation for the scene's kind (planar:
the ODE methods' reduced, baumgarte, penalty, projection, trapezoidal_index3's index3 and
augmented_lagrangian, ida's index1 and ggl, bdf's i3 and si2 on the DAE; spatial: the same but
trapezoidal_index3's projected form), refuses an option that does not apply by name, and
returns a RunPlan: the option structs (ODEOptions, Index3Options, ModelOptions or the spatial
options), the f2py entry's dae_form code, the samples and steps, and the manifest's entries.
Nothing here reads a scene's elements but for the names in its messages and the spatial
scene's rotation and norm (mbdk.validate checks the scene against the plan).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from numbers import Integral

import numpy as np

from . import _kernel, alpha_family, checks
from .checks import show
from .codes import (ADAPTIVE_MODES, DAE_FORMS, DAE_NONE, FORMULATIONS, INDEX3_FORMULATIONS, NORMS,
                    OUTPUTS, ROTATIONS, SOLVERS, SPATIAL_FORMULATIONS, STARTUP)
from .errors import InvalidInputError, NotApplicableError
from .index3 import factorisation
from .joint_coords import COORDINATES, check_coordinates, check_joint_run
from .methods import MethodInfo, method as method_info
from .model import model_options
from .ode import (DEFAULT_MAX_STEPS, RTOL_FLOOR, adaptive_options, plan as step_plan,
                  sample_times)
from .options import (Index3Options, ModelOptions, ODEOptions, SpatialOptions,
                      projection_tol_for)
from .scene import Scene
from .watch import Watch, as_watch

_INT_MAX = 2**31 - 1
#: ida's and bdf's forms of a scene's DAE (the f2py entries' dae_form)
IDA_FORMULATIONS = DAE_FORMS["ida"]
BDF_DAE_FORMULATIONS = DAE_FORMS["bdf"]
BDF_DAE_FORMS = {"i3": "index 3 (GSTIFF I3): q' = v, M v' = f - D^T lam, 0 = Phi, index-scaled "
                       "Newton, error test on q and on h times v (index 2)",
                 "si2": "stabilised index 2 (GSTIFF SI2, GGL): q' = v - D^T mu, "
                        "M v' = f - D^T lam, 0 = Phi, 0 = D v + Phi_t, error test on q and v"}
IDA_FORMS = {"index1": "index 1: M v' + D^T lam = f, D v' = gamma (Phi, Phi' not kept)",
             "ggl": "stabilised index 2 (Gear-Gupta-Leimkuhler): q' = v - D^T mu, "
                    "M v' + D^T lam = f, Phi = 0, D v + Phi_t = 0"}
#: ida's forms on spatial scenes, as the manifest describes them
SPATIAL_IDA_FORMS = {
    "index1": "index 1: q' = T(q) w, w' = M^-1 (f - C^T lam), C w' = gamma on the independent "
              "rows; Phi and C w + Phi_t drift as in the reduced ODE (the watch names it)",
    "ggl": "stabilised index 2 (Gear-Gupta-Leimkuhler): q' = T(q) (w - M^-1 C^T mu), "
           "w' = M^-1 (f - C^T lam), Phi = 0, C w + Phi_t = 0 on the independent rows"}
#: the options of trapezoidal_index3 alone
INDEX3_ONLY = ("adaptive", "err_rtol", "err_atol", "dt_out", "h_min", "h_max", "max_iter")
#: how the index-3 methods' Newton matrix is formed on spatial scenes
SPATIAL_INDEX3_MATRIX = ("by forward differences of the residual (the retraction and the "
                         "gyroscopic moment included), LAPACK LU, reused while Newton contracts")
#: the default of simulate's penalty = (alpha_p, omega_p, mu_p)
DEFAULT_PENALTY = (1e7, 10.0, 1.0)
#: adaptive trapezoidal_index3 without Newton tolerances given: these times err_rtol/err_atol
#: (at most the fixed-step defaults), not below NEWTON_FLOOR
NEWTON_SHARE, NEWTON_FLOOR = 0.01, 64 * float(np.finfo(float).eps)
EXTRAPOLATED_TEXT = ("local Richardson extrapolation: two steps of H/2 against one of H, "
                     "error (y_H/2 - y_H)/3 on q and v, the step's result (4 y_H/2 - y_H)/3 "
                     "projected onto Phi = 0, Phi' = 0")
#: the book scheme's multipliers, as its results and warnings say (studies/index3.py measures it)
BOOK_MULTIPLIERS = (
    "not converged: the book's index-3 scheme (formulation 'index3') leaves v and a off the "
    "derived constraints by a period-2 oscillation amplified by 2/h and 4/h^2, so lambda and the "
    "reactions carry an error that grows as h shrinks (studies/index3.py measures it); "
    "formulation 'augmented_lagrangian' gives them at second order")
#: ida tests its multipliers no tighter than this relative to the largest, in both its forms
#: (the kernel's LAM_RTOL_FLOOR, kernel/src/sundials/mbdk_ida.f90: its iteration's roundoff)
GGL_LAMBDA_RTOL = 1e-8


@dataclass
class Request:
    """simulate's arguments as given (mbdk.simulate documents them); lock_guard is a switching
    run's segment's (mbdk.angle_switch)."""

    method: str
    t_end: float
    h: float | None = None
    formulation: str | None = None
    t0: float = 0.0
    every: int = 1
    outputs: tuple = tuple(OUTPUTS)
    alpha: float | None = None
    beta: float | None = None
    penalty: tuple = DEFAULT_PENALTY
    projection_tol: float | None = None
    solver: str = "auto"
    small_dense: bool = True
    assemble_initial: bool = True
    startup: str = "rk4"
    newton_rtol: float | None = None
    newton_atol: float | None = None
    max_iter: int | None = None
    adaptive: bool | str | None = None
    err_rtol: float | None = None
    err_atol: float | None = None
    dt_out: float | None = None
    t_eval: object = None
    h_min: float | None = None
    h_max: float | None = None
    rtol: float | None = None
    atol: float | None = None
    max_steps: int | None = None
    max_order: int | None = None
    watch: object = True
    locate_events: bool = True
    raise_on_failure: bool = True
    switch_angles: float | None = None
    lock_guard: float = 0.0
    coordinates: str = "absolute"
    rho_inf: float | None = None
    alpha_hht: float | None = None
    newmark_beta: float | None = None
    newmark_gamma: float | None = None
    alpha_m: float | None = None
    alpha_f: float | None = None

    def family_options(self) -> dict:
        """The generalized-alpha family's options given a value (mbdk.alpha_family)."""
        return {k: getattr(self, k) for k in alpha_family.OPTIONS
                if getattr(self, k) is not None}


@dataclass
class RunPlan:
    """What a run does: the method (info) and formulation, the family it runs as (an ODE method
    on a formulation, trapezoidal_index3, ida or bdf on the DAE itself), the kernel's option
    structs, the samples and steps, and the manifest's entries of the plan."""

    kind: str
    method: str
    info: MethodInfo
    formulation: str
    request: Request
    h: float | None
    rtol: float | None
    every: int
    index3: bool = False           # trapezoidal_index3
    ida: bool = False
    dae_bdf: bool = False          # bdf on the DAE itself (i3, si2)
    dae_form: int = DAE_NONE       # the f2py entry's dae_form
    ode_options: ODEOptions = field(default_factory=ODEOptions)
    index3_options: Index3Options = field(default_factory=Index3Options)
    model_options: ModelOptions | None = None      # planar
    spatial_options: SpatialOptions | None = None  # spatial
    want: int = sum(OUTPUTS.values())
    watch: Watch = field(default_factory=Watch)
    projection_tol: float = 0.0
    nsamp: int = 0
    steps: float = 0.0
    adaptive: bool = False         # trapezoidal_index3 under step-size control
    #: t_eval: the kernel's sample times (t0, the times asked for, t_end) and the mask of the
    #: asked ones among them; empty and None without it
    times: np.ndarray = field(default_factory=lambda: np.zeros(0))
    keep: np.ndarray | None = None
    manifest: dict = field(default_factory=dict)
    #: what the manifest and a warning say of multipliers the run does not give to its
    #: tolerance (the book's index-3 scheme, ida's GGL form at a tight rtol); None elsewhere
    multipliers_note: str | None = None
    #: a spatial run in joint coordinates: the split of its joints (mbdk.joint_coords)
    joint_split: dict | None = None

    @property
    def t0(self) -> float:
        return self.request.t0

    @property
    def t_end(self) -> float:
        return self.request.t_end

    @property
    def dae(self) -> bool:
        """ida or bdf on the DAE itself."""
        return self.ida or self.dae_bdf


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


def scene_tolerances(rtol, atol) -> tuple[float, float]:
    """The rtol and atol of an error-controlled scene run, planar or spatial (one check, so that
    both refuse the same values): numbers, rtol in [RTOL_FLOOR, 1) or 0, atol > 0; a per-state
    atol is solve_ode's."""
    return checks.tolerances(rtol, atol, where="a scene run", rtol_floor=RTOL_FLOOR)


def output_bits(outputs) -> int:
    """The kernel's bits of the outputs asked for (OUTPUTS), or a named error."""
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


def is_default_penalty(penalty) -> bool:
    """penalty is simulate's default (1e7, 10, 1), as a tuple, a list or an array."""
    try:
        return tuple(float(p) for p in penalty) == DEFAULT_PENALTY
    except (TypeError, ValueError, OverflowError):
        return False


def ggl_multipliers(method: str, formulation: str, rtol) -> str | None:
    """What a run's manifest and warning say of its multipliers where ida gives them less
    accurately than rtol asks (rtol below GGL_LAMBDA_RTOL, either form); None elsewhere."""
    if method != "ida" or rtol is None or not rtol < GGL_LAMBDA_RTOL:
        return None
    return (f"converged to about {GGL_LAMBDA_RTOL:g} of the largest multiplier, not to rtol = "
            f"{rtol:g}: ida tests them no tighter, the roundoff of its iteration (in its "
            f"{formulation} form as in the other); bdf on the DAE (formulation 'si2') gives them "
            "to the tolerance")


def make_plan(scene: Scene, req: Request) -> RunPlan:
    """The run plan of a checked scene (mbdk.scene_file.checked) for the request: named errors
    for every argument that does not fit the method, the formulation or the scene's kind."""
    check_coordinates(req.coordinates)
    if req.coordinates == "joint" and scene.kind != "spatial":
        check_joint_run(scene, req.method, method_info(req.method).family, "reduced")
    plan = _spatial_plan(scene, req) if scene.kind == "spatial" else _planar_plan(scene, req)
    if req.t_eval is not None:
        _sample_times(plan, req)
    return plan


def _sample_times(plan: RunPlan, req: Request) -> None:
    """t_eval into the plan: the kernel's sample times and the mask of those asked for (an
    error-controlled ODE method's: its dense output samples them; the DAE methods and the
    index-3 family land on their own grid)."""
    if plan.index3 or plan.ida or plan.dae_bdf:
        raise NotApplicableError(f"t_eval with {plan.method}/{plan.formulation}: sample times "
                                 "are the error-controlled ODE methods' (dopri54, bs32, bdf, "
                                 "cvode_*, on a formulation); give dt_out")
    plan.times, plan.keep = sample_times(req.t_eval, plan.info, req.t0, req.t_end,
                                         req.dt_out or 0.0)
    plan.nsamp = len(plan.times)
    plan.manifest["t_eval"] = int(plan.keep.sum())


# ---- planar scenes ---------------------------------------------------------------------------

def _planar_formulation(info_m: MethodInfo, method: str, formulation) -> str:
    """The formulation of a planar run: the method's default, or the one given if the method
    runs it (named errors otherwise, naming the methods that do)."""
    index3, ida = info_m.family == "dae_index3", info_m.family == "ida"
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
    return formulation


def family_parameters(req: Request, info_m: MethodInfo) -> alpha_family.AlphaParameters:
    """The index-3 family member's parameters (mbdk.alpha_family); the family's options given
    to another method are refused by name."""
    given = req.family_options()
    if info_m.family != "dae_index3":
        if given:
            raise InvalidInputError(f"{', '.join(sorted(given))}: options of the index-3 "
                                    "family (newmark, hht, generalized_alpha), not of "
                                    f"{req.method}")
        return alpha_family.AlphaParameters()
    return alpha_family.parameters(req.method, **given)


def _index3_options_given(req: Request, info_m: MethodInfo, index3: bool) -> dict:
    """trapezoidal_index3's own options given a value (refused for other methods, and the
    error-controlled methods' tolerances refused for fixed-step ones)."""
    given3 = {k: v for k, v in dict(adaptive=req.adaptive, err_rtol=req.err_rtol,
                                     err_atol=req.err_atol, dt_out=req.dt_out, h_min=req.h_min,
                                     h_max=req.h_max, max_iter=req.max_iter).items()
              if v is not None}
    given_tol = {k: v for k, v in dict(rtol=req.rtol, atol=req.atol, max_steps=req.max_steps,
                                       max_order=req.max_order).items() if v is not None}
    if given_tol and not info_m.adaptive:
        raise InvalidInputError(f"{', '.join(sorted(given_tol))}: options of the "
                                "error-controlled methods (dopri54, bs32, bdf, cvode_bdf, "
                                f"cvode_adams); {req.method} takes a fixed step h"
                                + (" (trapezoidal_index3's own error control: adaptive=True, "
                                   "err_rtol, err_atol)" if index3 else ""))
    if info_m.adaptive:
        given3 = {k: v for k, v in given3.items() if k not in ("dt_out", "h_min", "h_max")}
    if given3 and not index3:
        raise InvalidInputError(f"{', '.join(sorted(given3))}: options of the index-3 methods "
                                f"only (trapezoidal_index3 and its family: "
                                f"{', '.join(INDEX3_ONLY)})")
    return given3


def _step_and_tolerances(req: Request, info_m: MethodInfo) -> tuple:
    """(h, rtol, atol, every) of a planar run: an error-controlled method's tolerances (h its
    optional first step), a fixed-step method's h."""
    h, rtol, atol, every = req.h, req.rtol, req.atol, req.every
    if info_m.adaptive:
        rtol, atol = scene_tolerances(rtol, atol)
        if every != 1:
            raise InvalidInputError(f"every = {every!r}: {req.method} chooses its own steps; "
                                    "give dt_out (the spacing of the samples) instead")
        if h == 0:
            h = None    # 0: the method chooses its first step, as in solve_ode
        check_run(1.0 if h is None else h, req.t_end, req.t0, every)
    else:
        if h is None:
            raise InvalidInputError(f"{req.method} takes a fixed step: give h (or use an "
                                    "error-controlled method with rtol and atol)")
        check_run(h, req.t_end, req.t0, every)
    return h, rtol, atol, int(every)


def _adaptive_dict(req: Request, h, rtol, atol) -> dict:
    """An error-controlled ODE method's step-size options, as ode_plan takes them."""
    return dict(h=h, rtol=rtol, atol=atol, dt_out=req.dt_out or 0.0, h_min=req.h_min or 0.0,
                h_max=req.h_max or 0.0, max_steps=req.max_steps or 0,
                max_order=req.max_order or 0)


def _dae_plan(req: Request, info_m: MethodInfo, formulation, ida, h, rtol, atol,
              projection_tol, projection_given) -> tuple[dict, ModelOptions]:
    """ida or bdf on the planar DAE itself: the model only evaluates (forces, Phi, D, gamma) and
    gives the consistent initial multipliers by its reduced solve."""
    unused = [name for name, given in (("alpha", req.alpha is not None),
                                       ("beta", req.beta is not None),
                                       ("penalty", not is_default_penalty(req.penalty)),
                                       ("projection_tol", projection_given),
                                       ("startup", req.startup != "rk4"),
                                       ("newton_rtol", req.newton_rtol is not None),
                                       ("newton_atol", req.newton_atol is not None)) if given]
    if unused:
        raise InvalidInputError(
            f"{', '.join(unused)}: not options of {req.method} on the DAE itself (formulation "
            f"{formulation!r}); its Newton iteration follows rtol and atol")
    about = IDA_FORMS if ida else BDF_DAE_FORMS
    plan_ = ode_plan(info_m, "reduced", h if h else 1.0, req.t_end, req.t0, 1, None, None,
                     req.penalty, projection_tol, req.startup, req.newton_rtol, req.newton_atol,
                     adaptive=_adaptive_dict(req, h, rtol, atol))
    plan_["manifest"]["form"] = about[formulation]
    plan_["manifest"].pop("newton", None)   # no Newton option of its own
    mopt = model_options("reduced", 0.0, 0.0, req.penalty, projection_tol, req.solver,
                         req.small_dense)
    return plan_, mopt


def _planar_plan(scene: Scene, req: Request) -> RunPlan:
    if req.switch_angles is not None:
        raise NotApplicableError(f"switch_angles = {req.switch_angles!r}: an option of spatial "
                                 "scenes in angle coordinates; planar scenes have no gimbal lock")
    method = req.method
    info_m = method_info(method)
    index3, ida = info_m.family == "dae_index3", info_m.family == "ida"
    formulation = _planar_formulation(info_m, method, req.formulation)
    given3 = _index3_options_given(req, info_m, index3)
    checks.choice("solver", req.solver, SOLVERS, what="a linear solve")
    checks.choice("startup", req.startup, STARTUP, what="a start-up of the multistep methods")
    want = output_bits(req.outputs)
    watch_ = as_watch(req.watch)
    h, rtol, atol, every = _step_and_tolerances(req, info_m)
    dae_bdf = info_m.family == "variable_bdf" and formulation in BDF_DAE_FORMULATIONS
    dae_form = (IDA_FORMULATIONS.get(formulation, DAE_NONE) if ida else
                BDF_DAE_FORMULATIONS.get(formulation, DAE_NONE) if dae_bdf else DAE_NONE)
    projection_given = req.projection_tol is not None
    projection_tol = projection_tol_for(
        req.projection_tol,
        (ODEOptions.atol if atol is None else atol) if info_m.adaptive else None)
    if not index3:
        family_parameters(req, info_m)      # the family's options refused by name
    if ida or dae_bdf:
        plan_, mopt = _dae_plan(req, info_m, formulation, ida, h, rtol, atol, projection_tol,
                                projection_given)
    elif info_m.adaptive:
        if formulation == "projection" and info_m.family == "cvode":
            raise NotApplicableError(
                f"{method} with formulation 'projection': CVODE keeps its own history of the "
                "state, which a projection after each step would contradict. Use bdf or "
                "dopri54 for projection, or cvode_* with reduced or baumgarte")
        if formulation == "baumgarte" and (req.alpha is None or req.beta is None):
            raise InvalidInputError(f"{method} with formulation 'baumgarte': give alpha and "
                                    "beta (Baumgarte's defaults 1/h and sqrt(2)/h need a fixed "
                                    "step; an error-controlled method has none)")
        plan_ = ode_plan(info_m, formulation, h if h else 1.0, req.t_end, req.t0, 1, req.alpha,
                         req.beta, req.penalty, projection_tol, req.startup, req.newton_rtol,
                         req.newton_atol, adaptive=_adaptive_dict(req, h, rtol, atol))
        mopt = model_options(formulation, plan_["alpha"], plan_["beta"], req.penalty,
                             projection_tol, req.solver, req.small_dense)
    elif index3:
        plan_ = index3_plan(formulation, h, req.t_end, req.t0, every, req.alpha,
                            req.newton_rtol, req.newton_atol, given3, req.small_dense,
                            family_parameters(req, info_m), req.method)
        mopt = model_options(solver=req.solver, small_dense=req.small_dense)
    else:
        plan_ = ode_plan(info_m, formulation, h, req.t_end, req.t0, every, req.alpha, req.beta,
                         req.penalty, projection_tol, req.startup, req.newton_rtol,
                         req.newton_atol)
        mopt = model_options(formulation, plan_["alpha"], plan_["beta"], req.penalty,
                             projection_tol, req.solver, req.small_dense)
    mopt = replace(mopt, **watch_.options(), locate_events=int(bool(req.locate_events)))
    note = None
    if scene.rows > 0:
        note = (ggl_multipliers(method, formulation, rtol)
                or (BOOK_MULTIPLIERS if index3 and formulation == "index3" else None))
    return RunPlan(kind="planar", method=method, info=info_m, formulation=formulation,
                   request=req, h=h, rtol=rtol, every=every, index3=index3, ida=ida,
                   dae_bdf=dae_bdf, dae_form=dae_form, ode_options=plan_["ode"],
                   index3_options=plan_["index3"], model_options=mopt, want=want,
                   watch=watch_, projection_tol=projection_tol, nsamp=plan_["nsamp"],
                   steps=plan_["steps"], adaptive=bool(plan_.get("adaptive", False)),
                   manifest=dict(plan_["manifest"]), multipliers_note=note)


# ---- spatial scenes --------------------------------------------------------------------------

def _spatial_formulation(info_m: MethodInfo, method: str, formulation, scene: Scene) -> str:
    """The formulation of a spatial run: the method's default, or the one given if the spatial
    model runs it with this method (NotApplicableError otherwise)."""
    index3, ida = info_m.family == "dae_index3", info_m.family == "ida"
    ida_forms = list(IDA_FORMULATIONS)
    if formulation is not None and not isinstance(formulation, str):
        checks.choice("formulation", formulation,
                      list(INDEX3_FORMULATIONS) if index3 else ida_forms if ida else
                      list(SPATIAL_FORMULATIONS)
                      + (["i3", "si2"] if info_m.family == "variable_bdf" else []),
                      error=NotApplicableError,
                      what=f"a formulation {method} runs on spatial scenes")
    if index3:
        formulation = "augmented_lagrangian" if formulation is None else formulation
        if formulation not in INDEX3_FORMULATIONS:
            raise NotApplicableError(
                f"formulation {formulation!r} of {method} on spatial scene {scene.name!r}: "
                f"the index-3 methods run {', '.join(INDEX3_FORMULATIONS)}")
    if ida:
        formulation = "index1" if formulation is None else formulation
        if formulation not in ida_forms:
            raise NotApplicableError(
                f"formulation {formulation!r} of ida on spatial scene {scene.name!r}: ida "
                f"integrates the DAE itself, in the forms {', '.join(ida_forms)}")
    formulation = "reduced" if formulation is None else formulation
    dae = formulation in ("i3", "si2") and info_m.family == "variable_bdf"
    if not isinstance(formulation, str) or (formulation not in SPATIAL_FORMULATIONS and not dae
                                            and not index3 and not ida):
        raise NotApplicableError(f"formulation {formulation!r} on spatial scene {scene.name!r}: "
                                 f"spatial scenes run {', '.join(SPATIAL_FORMULATIONS)}, and bdf "
                                 "also 'i3' and 'si2' (the DAE itself)")
    return formulation


def _spatial_method(info_m: MethodInfo, method: str, scene: Scene, joint: bool) -> None:
    """The methods the spatial model does not run, refused by name (joint: in joint
    coordinates, whose state [theta, theta'] has Euler-Cromer's layout)."""
    if info_m.solves != "ode" and info_m.family not in ("dae_index3", "ida"):
        raise NotApplicableError(
            f"{method} on spatial scene {scene.name!r}: it integrates the planar model's DAE; "
            "spatial scenes run the ODE methods (mbdk.methods('ode')) on the reduced, "
            "baumgarte, penalty or projection formulation, bdf on their DAE itself "
            "(formulations 'i3', 'si2'), ida ('index1', 'ggl') and the index-3 methods "
            "(trapezoidal_index3, newmark, hht, generalized_alpha)")
    if info_m.family == "euler_cromer" and not joint:
        raise NotApplicableError(f"euler_cromer on spatial scene {scene.name!r}: its state "
                                 "layout is y = [q, q'], and a spatial body's velocities (v, "
                                 "Omega) are not its coordinates' rates; use coordinates="
                                 "'joint' (the joints' turns and slides and their rates), or "
                                 "rk4 here")


def _spatial_refusals(req: Request, index3: bool) -> None:
    """The planar model's options given a value, refused by name (outputs is checked and
    otherwise moot: a spatial run computes every output it has at its samples); the index-3
    methods' own options are theirs."""
    planar_only = {"solver": None if req.solver == "auto" else req.solver,
                   "small_dense": None if req.small_dense else req.small_dense}
    if not index3:
        planar_only.update(adaptive=req.adaptive, err_rtol=req.err_rtol,
                           err_atol=req.err_atol, max_iter=req.max_iter)
    bad = sorted(k for k, v in planar_only.items() if v is not None)
    if bad:
        raise NotApplicableError(f"{', '.join(bad)}: not options of this spatial scene run "
                                 "(solver and small_dense are the planar model's; adaptive, "
                                 "err_rtol, err_atol and max_iter the index-3 methods')")
    if req.outputs is not None:
        output_bits(req.outputs)


def _spatial_steps(req: Request, info_m: MethodInfo, formulation: str):
    """(h for the plan, rtol, atol, the adaptive options or None) of a spatial run."""
    h, t0, t_end, every = req.h, req.t0, req.t_end, req.every
    if info_m.adaptive:
        if every != 1:
            raise InvalidInputError(f"every = {every!r}: {req.method} chooses its own steps; "
                                    "give dt_out (the spacing of the samples) instead")
        if formulation == "baumgarte" and (req.alpha is None or req.beta is None):
            raise InvalidInputError(f"{req.method} with formulation 'baumgarte': give alpha "
                                    "and beta (Baumgarte's defaults 1/h and sqrt(2)/h need a "
                                    "fixed step; an error-controlled method has none)")
        check_run(1.0 if not h else h, t_end, t0, 1)
        rtol, atol = scene_tolerances(req.rtol, req.atol)
        return 1e-3 * (t_end - t0), rtol, atol, _adaptive_dict(req, h, rtol, atol)
    given = [n for n, v in (("rtol", req.rtol), ("atol", req.atol), ("dt_out", req.dt_out),
                            ("max_steps", req.max_steps), ("max_order", req.max_order)) if v]
    if given:
        raise InvalidInputError(f"{', '.join(given)}: options of the error-controlled "
                                f"methods; {req.method} takes a fixed step h")
    if h is None:
        raise InvalidInputError(f"{req.method} takes a fixed step: give h")
    check_run(h, t_end, t0, every)
    return h, req.rtol, req.atol, None


def _spatial_plan(scene: Scene, req: Request) -> RunPlan:
    method = req.method
    info_m = method_info(method)
    index3, ida = info_m.family == "dae_index3", info_m.family == "ida"
    _spatial_refusals(req, index3)
    family = family_parameters(req, info_m)
    _spatial_method(info_m, method, scene, req.coordinates == "joint")
    formulation = _spatial_formulation(info_m, method, req.formulation, scene)
    dae = formulation in ("i3", "si2") and info_m.family == "variable_bdf"
    penalty = None if is_default_penalty(req.penalty) else req.penalty
    if penalty is not None and formulation != "penalty":
        raise InvalidInputError(f"penalty = {penalty!r}: an option of the penalty formulation; "
                                f"this run's is {formulation!r}")
    penalty = DEFAULT_PENALTY if penalty is None else penalty
    if method.startswith("cvode") and formulation == "projection":
        raise NotApplicableError(f"{method} with the projection formulation: CVODE cannot "
                                 "change the state between its steps; use reduced or baumgarte")
    joint = req.coordinates == "joint"
    split = check_joint_run(scene, method, info_m.family, formulation) if joint else None
    if method.startswith("cvode") and scene.rotation == "quaternion" and \
            scene.quaternion_norm == "project" and not joint:
        raise NotApplicableError(f"{method} on spatial scene {scene.name!r} with "
                                 "quaternion_norm = 'project': CVODE cannot change the state "
                                 "between its steps; set the scene's quaternion_norm to "
                                 "'stabilise' or 'none'")
    if index3:
        given3 = _index3_options_given(req, info_m, index3)
        odes = [n for n, v in (("rtol", req.rtol), ("atol", req.atol),
                               ("max_steps", req.max_steps), ("max_order", req.max_order)) if v]
        if odes:
            raise InvalidInputError(f"{', '.join(odes)}: options of the error-controlled ODE "
                                    f"methods; {method} takes h (and, under step-size control, "
                                    "adaptive, err_rtol and err_atol)")
        if req.h is None:
            raise InvalidInputError(f"{method} takes a step: give h (the fixed step, or the "
                                    "first one under step-size control)")
        check_run(req.h, req.t_end, req.t0, int(req.every))
    href, rtol, atol, adaptive = ((req.h, None, None, None) if index3 else
                                  _spatial_steps(req, info_m, formulation))
    projection_tol = projection_tol_for(
        req.projection_tol,
        (ODEOptions.atol if atol is None else atol) if info_m.adaptive else None)
    if index3:
        plan_ = index3_plan(formulation, req.h, req.t_end, req.t0, int(req.every), req.alpha,
                            req.newton_rtol, req.newton_atol, given3, False, family, method,
                            matrix=SPATIAL_INDEX3_MATRIX)
        plan_.update(alpha=0.0, beta=0.0)
    else:
        plan_ = ode_plan(info_m, formulation, href, req.t_end, req.t0, int(req.every),
                         req.alpha, req.beta, penalty, projection_tol, req.startup,
                         req.newton_rtol, req.newton_atol, adaptive)
    w = as_watch(req.watch)
    model_form = "reduced" if dae or ida else "projection" if index3 else formulation
    sopt = SpatialOptions(
        formulation=SPATIAL_FORMULATIONS[model_form], rotation=ROTATIONS[scene.rotation],
        norm=NORMS[scene.quaternion_norm], baumgarte_alpha=plan_["alpha"],
        baumgarte_beta=plan_["beta"], norm_gain=scene.norm_gain, projection_tol=projection_tol,
        watch_position=w.position or 0.0, watch_velocity=w.velocity or 0.0,
        watch_energy=w.energy or 0.0, watch_every=w.every, penalty_alpha=penalty[0],
        penalty_omega=penalty[1], penalty_mu=penalty[2], lock_guard=float(req.lock_guard),
        watch_momentum=w.momentum or 0.0, watch_quaternion=w.quaternion or 0.0,
        locate_events=int(bool(req.locate_events)),
        coordinates=COORDINATES[req.coordinates])
    return RunPlan(kind="spatial", method=method, info=info_m, formulation=formulation,
                   joint_split=split, request=req, h=req.h, rtol=rtol, every=int(req.every),
                   index3=index3, ida=ida, dae_bdf=dae,
                   dae_form=(IDA_FORMULATIONS[formulation] if ida else
                             BDF_DAE_FORMULATIONS[formulation] if dae else DAE_NONE),
                   ode_options=replace(plan_["ode"], method=info_m.id), spatial_options=sopt,
                   index3_options=plan_.get("index3", Index3Options()),
                   adaptive=bool(plan_.get("adaptive", False)),
                   watch=w, projection_tol=projection_tol, nsamp=plan_["nsamp"],
                   steps=plan_["steps"], manifest=dict(plan_["manifest"]),
                   multipliers_note=(ggl_multipliers(method, formulation, rtol)
                                     or (BOOK_MULTIPLIERS if index3 and formulation == "index3"
                                         else None)) if scene.rows else None)


# ---- the option structs ----------------------------------------------------------------------

def _estimate_text(opt: Index3Options) -> str:
    """The estimated mode's local error in the manifest, with the member's constants (the
    kernel's, mbdk_index3_error_constants: h^2/12 and h^3/12 for the trapezoidal rule)."""
    lte_q, lte_v, _ = _kernel.index3_error_constants(opt.pack())
    return (f"{lte_q:.6g} h^2 |a+ - a| on q, {lte_v:.6g} h^3 |a''| on v (the step's local "
            "errors, the derivatives from divided differences of the accelerations)")


def adaptive_mode(adaptive) -> int:
    """The kernel's code of an adaptive= value: a bool (numpy's too) or a mode's name; other
    values, 0 and 1 included, are refused (1 would read as the kernel's code of 'estimated')."""
    if isinstance(adaptive, np.bool_):
        adaptive = bool(adaptive)
    if isinstance(adaptive, (bool, str)) and adaptive in ADAPTIVE_MODES:
        return ADAPTIVE_MODES[adaptive]
    raise InvalidInputError(f"adaptive = {adaptive!r} must be False, True (= 'extrapolated') "
                            "or 'estimated'")


def _ode_parameters(formulation, h, alpha, beta, penalty, projection_tol, startup):
    """Baumgarte's alpha and beta (defaults 1/h, sqrt(2)/h), checked with the penalty and the
    projection tolerance."""
    checks.choice("startup", startup, STARTUP, what="a start-up of the multistep methods")
    alpha = 1.0 / h if alpha is None else checks.real("alpha", alpha)
    beta = math.sqrt(2.0) / h if beta is None else checks.real("beta", beta)
    if formulation == "baumgarte" and not (alpha >= 0 and beta >= 0 and math.isfinite(alpha)
                                           and math.isfinite(beta)):
        raise InvalidInputError(f"alpha = {alpha}, beta = {beta}: Baumgarte parameters must be "
                                "finite and >= 0")
    if isinstance(penalty, (str, bytes, dict)) or not hasattr(penalty, "__len__") or \
            len(penalty) != 3 or not all(checks.number_problem(p, in_range=False) is None
                                         and p > 0 for p in penalty):
        raise InvalidInputError(f"penalty = {show(penalty)} must be (alpha_p, omega_p, mu_p), "
                                "finite, all > 0")
    if not (checks.real("projection_tol", projection_tol) > 0):
        raise InvalidInputError(f"projection_tol = {projection_tol} must be > 0")
    return alpha, beta


def _ode_newton(formulation, newton_rtol, newton_atol) -> tuple[float, float]:
    """The implicit ODE methods' Newton tolerances: 1e-10/1e-12 by default, 1e-7/1e-9 for the
    penalty formulation (its accelerations carry roundoff amplified by alpha_p)."""
    if newton_rtol is None:
        newton_rtol = 1e-7 if formulation == "penalty" else ODEOptions.newton_rtol
    if newton_atol is None:
        newton_atol = 1e-9 if formulation == "penalty" else ODEOptions.newton_atol
    newton_rtol = checks.real("newton_rtol", newton_rtol)
    newton_atol = checks.real("newton_atol", newton_atol)
    if not (newton_rtol > 0 and newton_atol > 0):
        raise InvalidInputError(f"newton_rtol = {newton_rtol}, newton_atol = {newton_atol} must "
                                "be > 0")
    return newton_rtol, newton_atol


def ode_plan(info_m, formulation, h, t_end, t0, every, alpha, beta, penalty, projection_tol,
             startup, newton_rtol, newton_atol, adaptive: dict | None = None) -> dict:
    """An ODE method's plan on a formulation: {"ode": ODEOptions, "index3": Index3Options(),
    "nsamp", "steps", "manifest", "alpha", "beta"}; adaptive: an error-controlled method's
    step-size options (ode.adaptive_options), None for a fixed step h."""
    alpha, beta = _ode_parameters(formulation, h, alpha, beta, penalty, projection_tol, startup)
    if adaptive is not None:
        ode, nsteps, nsamp, control = adaptive_options(
            info_m, adaptive["h"], t0, t_end, 1, adaptive["rtol"], adaptive["atol"],
            adaptive["dt_out"], adaptive["h_min"], adaptive["h_max"], adaptive["max_steps"],
            adaptive["max_order"], False)
        shortened = False
    else:
        nsteps, nsamp, shortened = step_plan(t0, t_end, h, every)
    if info_m.steps > 1 and shortened:   # the kernel's whole-number test (mbdk_on_grid)
        n_lo = math.floor((t_end - t0) / h)
        raise InvalidInputError(f"{info_m.name} needs equal steps; use h = "
                                f"{(t_end - t0) / max(n_lo, 1):.12g}")
    newton_rtol, newton_atol = _ode_newton(formulation, newton_rtol, newton_atol)
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


def _index3_newton(d: Index3Options, newton_rtol, newton_atol, given3) -> tuple:
    """trapezoidal_index3's Newton tolerances and iteration limit, checked."""
    rtol = d.newton_rtol if newton_rtol is None else checks.real("newton_rtol", newton_rtol)
    atol = d.newton_atol if newton_atol is None else checks.real("newton_atol", newton_atol)
    if not (rtol >= 0 and atol > 0):
        raise InvalidInputError(f"newton_rtol = {rtol}, newton_atol = {atol}: need rtol >= 0 "
                                "and atol > 0")
    max_iter = given3.get("max_iter", d.newton_max_iter)
    if isinstance(max_iter, bool) or not isinstance(max_iter, Integral) or \
            not 1 <= max_iter <= 10**6:
        raise InvalidInputError(f"max_iter = {max_iter!r} must be a whole number from 1 to 1e6")
    return rtol, atol, max_iter


def _index3_control(d: Index3Options, given3, h, every, t0, t_end) -> tuple:
    """trapezoidal_index3's step-size control options (err_rtol, err_atol, dt_out, h_min,
    h_max), checked where the control is on."""
    err_rtol = given3.get("err_rtol", d.err_rtol)
    err_atol = given3.get("err_atol", d.err_atol)
    dt_out = given3.get("dt_out", h * every)
    h_min = given3.get("h_min", d.h_min)
    h_max = given3.get("h_max", d.h_max)
    for name, val, low in (("err_rtol", err_rtol, 0.0), ("err_atol", err_atol, None),
                           ("dt_out", dt_out, None), ("h_min", h_min, 0.0),
                           ("h_max", h_max, 0.0)):
        val = checks.real(name, val)
        if not (val >= low if low is not None else val > 0):
            raise InvalidInputError(f"{name} = {val!r} must be a finite number "
                                    f"{'>= 0' if low is not None else '> 0'}")
    err_rtol, err_atol = float(err_rtol), float(err_atol)
    dt_out, h_min, h_max = float(dt_out), float(h_min), float(h_max)
    if h_max and h_min > h_max:
        raise InvalidInputError(f"h_min = {h_min} exceeds h_max = {h_max}")
    checks.step_bounds(t0, t_end, h_max, 0, default_steps=DEFAULT_MAX_STEPS,
                       has_max_steps=False)
    return err_rtol, err_atol, dt_out, h_min, h_max


def index3_plan(formulation, h, t_end, t0, every, alpha, newton_rtol, newton_atol,
                given3, small_dense, family=None, method="trapezoidal_index3",
                matrix="analytic") -> dict:
    """The index-3 family's plan (trapezoidal_index3, newmark, hht, generalized_alpha; family:
    the member's mbdk.alpha_family parameters): {"ode", "index3": Index3Options, "nsamp",
    "steps", "manifest", "adaptive"} (mbdk.index3 says what the options do). matrix: how the
    mechanism's Newton matrix is formed (planar: analytic; spatial: by differences)."""
    family = alpha_family.AlphaParameters() if family is None else family
    d = Index3Options()
    rtol, atol, max_iter = _index3_newton(d, newton_rtol, newton_atol, given3)
    alpha = d.alpha if alpha is None else checks.real("alpha", alpha)
    if formulation == "augmented_lagrangian" and not (alpha >= 0 and math.isfinite(alpha)):
        raise InvalidInputError(f"alpha = {alpha}: the augmented Lagrangian's penalty factor "
                                "must be finite and > 0, or 0 for the default (1e3 max(M) "
                                "/ s at every step, s the Newton scale: h^2/4 for the "
                                "trapezoidal rule)")
    mode = adaptive_mode(given3.get("adaptive", False))
    adaptive = mode > 0
    if adaptive and formulation == "index3":
        raise NotApplicableError(
            f"adaptive={given3['adaptive']!r} with formulation 'index3': the book's scheme "
            "leaves its velocities "
            "off Phi' = 0 by a period-2 oscillation that grows with time and soon exceeds the "
            "local error, so an error test on q and v would shrink h without end (studies/"
            "index3.py, table index3_long_runs). Use formulation='augmented_lagrangian' for "
            "step-size control, or a fixed h")
    trapezoidal = family.as_options() == alpha_family.AlphaParameters().as_options()
    if adaptive and not family.second_order:
        raise NotApplicableError(
            f"adaptive={given3['adaptive']!r} with {method} ({family.spec}): this member is "
            "first order (gamma != 1/2 - alpha_m + alpha_f), and the step-size control's "
            "estimates are those of a second-order step; run it at a fixed h, or take "
            "gamma = 1/2 - alpha_m + alpha_f")
    if adaptive and not trapezoidal and mode == ADAPTIVE_MODES["extrapolated"]:
        raise NotApplicableError(
            f"adaptive={given3['adaptive']!r} with {method} ({family.spec}): Richardson "
            "extrapolation's macro step is the trapezoidal rule's alone (an extrapolated "
            "state would leave the pseudo-acceleration's history behind); use "
            "adaptive='estimated', the member's own local error estimate")
    if adaptive:
        err_rtol, err_atol, dt_out, h_min, h_max = _index3_control(d, given3, h, every, t0,
                                                                   t_end)
        # Newton's tolerances follow the error test's (a hundredth of it, SUNDIALS' practice
        # of a tenth with a margin), so that a tight err_rtol is not capped by the default
        # Newton tolerance; never below the roundoff of the iterates
        if newton_rtol is None and err_rtol > 0:   # err_rtol = 0: absolute control only
            rtol = max(min(rtol, NEWTON_SHARE * err_rtol), NEWTON_FLOOR)
        if newton_atol is None:
            atol = max(min(atol, NEWTON_SHARE * err_atol), NEWTON_FLOOR)
    else:
        err_rtol = given3.get("err_rtol", d.err_rtol)
        err_atol = given3.get("err_atol", d.err_atol)
        dt_out = given3.get("dt_out", h * every)
        h_min, h_max = given3.get("h_min", d.h_min), given3.get("h_max", d.h_max)
    opt = Index3Options(h=h, newton_rtol=rtol, newton_atol=atol, alpha=alpha,
                        err_rtol=err_rtol, err_atol=err_atol, dt_out=dt_out, h_min=h_min,
                        h_max=h_max, formulation=INDEX3_FORMULATIONS[formulation],
                        every=every, newton_max_iter=int(max_iter), adaptive=mode,
                        **family.as_options())
    nsteps, nsamp, status = _kernel.index3_plan(opt.pack(), t0, t_end)
    if status < 0:
        raise InvalidInputError(
            f"h = {h}, t0 = {t0}, t_end = {t_end}, every = {every}"
            + (f", dt_out = {dt_out}" if adaptive else "")
            + " give no valid plan: need 0 < " + ("dt_out" if adaptive else "h")
            + " <= t_end - t0 and at most 2e9 " + ("samples" if adaptive else "steps"))
    manifest = {"newton": {"rtol": rtol, "atol": atol, "max_iter": int(max_iter),
                           "matrix": ("analytic, reused while Newton contracts; "
                                      + factorisation(formulation, small_dense))
                           if matrix == "analytic" else matrix}}
    if method != "trapezoidal_index3":
        manifest["family"] = {**family.as_options(), "given": family.spec,
                              "second_order": family.second_order}
    if formulation == "augmented_lagrangian":
        scale = ("h^2/4" if family.as_options() == alpha_family.AlphaParameters().as_options()
                 else f"{family.beta:g} h^2 (1 - {family.alpha_f:g}) / (1 - {family.alpha_m:g})")
        manifest["alpha"] = alpha if alpha > 0 else f"1e3 max(M) / ({scale}), per step"
    if adaptive:
        estimated = mode == ADAPTIVE_MODES["estimated"]
        manifest["step_control"] = {"err_rtol": err_rtol, "err_atol": err_atol,
                                    "dt_out": dt_out, "h0": h, "h_min": h_min, "h_max": h_max,
                                    "mode": "estimated" if estimated else "extrapolated",
                                    "estimate": (_estimate_text(opt) if estimated
                                                 else EXTRAPOLATED_TEXT)}
    return {"ode": ODEOptions(), "index3": opt, "nsamp": int(nsamp),
            # adaptive: the steps are not known in advance, the run always counts as long
            # (a worker thread, interruptible)
            "steps": float(nsteps) if not adaptive else math.inf, "manifest": manifest,
            "adaptive": adaptive}
