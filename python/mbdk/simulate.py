"""simulate(scene, method, ...): the one entry that runs a scene, of planar or of spatial bodies,
for every method and formulation (its docstring, ``help(mbdk.simulate)``, is the manual). The
kernel builds the model once, integrates it with the whole time loop compiled, and computes the
outputs asked for at the samples, all in one call (kernel/src/api/mbdk_f2py.f90: scene_run for
planar bodies, spatial_run for spatial ones).

A run goes through four steps, each a module: the scene is checked (mbdk.scene_file.checked)
and the arguments planned (mbdk.plan: the method, its formulation, the options, named errors
before the kernel runs); the scene is checked against the plan (mbdk.validate); the kernel runs
it (mbdk.run_planar, mbdk.run_spatial); and its status is told in words (mbdk.diagnosis), raised
as a named exception where it failed. Spatial scenes in angle coordinates pass their gimbal lock
in segments (switch_angles, mbdk.angle_switch).
"""
from __future__ import annotations

from dataclasses import replace

import warnings

import numpy as np

from . import checks
from .codes import FORMULATIONS, OUTPUTS, SOLVERS
from .diagnosis import diagnose
from .errors import (AccuracyWarning, InvalidInputError, NotApplicableError, exception_for,
                     status_message)
from .model import assemble, build_tables, model_options
from .model import evaluate as evaluate_model
from .alpha_family import OPTIONS as FAMILY_OPTIONS
from .plan import INDEX3_ONLY, Request, make_plan
from .angle_switch import switching_run
from .ivp import locate_events, terminal_stop
from .methods import method as method_info
from .result import SceneResult, keep_samples
from .run_planar import prepared, run_planar
from .run_spatial import run_spatial
from .scene import Scene
from .scene_file import checked
from .validate import check_applicable


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
             switch_angles: float | None = None, rho_inf: float | None = None,
             alpha_hht: float | None = None, newmark_beta: float | None = None,
             newmark_gamma: float | None = None, alpha_m: float | None = None,
             alpha_f: float | None = None, t_eval=None, events=None,
             coordinates: str = "absolute", **unknown) -> SceneResult:
    """Integrate a scene with any method and formulation, the time loop compiled.

    Parameters
    ----------
    scene : Scene
        A scene of planar or of spatial bodies (``mbdk.scene(name)``, ``mbdk.load_scene(path)``);
        it is checked again before the run, so fields changed in Python get the errors a file
        would.
    method : str
        A method of ``mbdk.methods()``: a fixed-step ODE method (rk4, bdf4, ...), an
        error-controlled one (dopri54, bs32, bdf, cvode_bdf, cvode_adams), ida, or the index-3
        family (trapezoidal_index3, newmark, hht, generalized_alpha).
    h : float, optional
        The step of the fixed-step methods (required for them); for the error-controlled ones
        the first step (optional).
    t_end : float
        The end of the interval.
    formulation : str, optional
        How the constrained equations reach the method. The ODE methods (Fekete 2023, section 3;
        kernel/src/model/mbdk_model.f90 is their manual): ``"reduced"`` (the default:
        [M D^T; D 0][q''; lambda] = [f; gamma] at every evaluation), ``"baumgarte"`` (gamma -
        2 alpha Phi' - beta^2 Phi), ``"penalty"`` (Jalon-Bayo (3.35)-(3.40)) or
        ``"projection"`` (reduced, then q projected onto Phi = 0 and v onto Phi' = 0 after
        every step). The index-3 family (kernel/src/dae/mbdk_trapezoidal_index3.f90):
        ``"augmented_lagrangian"`` (ALI3-P, the augmented Lagrangian with projections, the
        default) or ``"index3"`` (the book's scheme (3.11)-(3.16), no projections, as HHT-I3 in
        MSC Adams and Chrono). bdf on the DAE itself: ``"i3"`` (the index-3 form, as Adams'
        GSTIFF I3) or ``"si2"`` (the stabilised index-2 form, as its SI2). ida: ``"index1"``
        (the default) or ``"ggl"``. cvode_* run every ODE formulation but projection.
    t0 : float
        The start of the interval (default 0).
    every : int
        Keep every k-th step as a sample (fixed step; default 1).
    outputs : sequence of str
        What to compute at the samples, default all: ``"a"`` accelerations, ``"multipliers"``,
        ``"reactions"`` (per joint: Fx, Fy and the moment about the joint point (a driver's, a
        coupling's: the centroid), exerted by the joint on its body1, global frame: -D_body1^T
        lambda), ``"energy"`` (kinetic + potential, its parts, and the work of dampers,
        constraints and loads as the run integrated it at every step whatever the samples (the
        watch's quadrature, kernel/src/model/mbdk_watch.f90); ``"work"`` their sum W, which
        ``energy_balance()`` takes), ``"residuals"`` (max |Phi|, max |Phi'|, max
        |D a - gamma|). An output not asked for is None in the result; ``outputs=()`` gives
        t, q, v only and costs nothing per sample. Spatial runs compute energy, residuals and
        multipliers at every sample (outputs is checked, not used).
    alpha, beta : float, optional
        Baumgarte's alpha and beta (defaults 1/h and sqrt(2)/h, (3.34); they must be given
        under error control, where there is no fixed h). For the index-3 family's augmented
        Lagrangian, alpha is the penalty factor (default 0: 1e3 max(M) / (h^2/4) per step).
    penalty : tuple of float
        The penalty formulation's (alpha_p, omega_p, mu_p), default (1e7, 10, 1).
    projection_tol : float, optional
        The projection formulation's tolerance (under error control a thousandth of atol by
        default).
    solver : str
        The linear solve of the constrained accelerations (the manifest's ``linear_solve``
        says which one ran): ``"auto"`` (revolute_schur when every joint is revolute, up to 12
        constraint rows, else schur when every body has mass and inertia (in-house dense up to
        12 rows, sparse above), else kkt); ``"revolute_schur"`` (S = D M^-1 D^T in closed 2 x 2
        blocks from the joint points, block LDL^T); ``"schur"`` (S from the nonzeros of D, any
        joint type, dense at any size: in-house block LDL^T up to 12 rows, the general dense
        Cholesky with small_dense=False or more rows); ``"sparse"`` (the same S kept sparse and
        factorised by SuiteSparse's AMD + LDL, O(N) for a chain or tree; trapezoidal_index3's
        augmented Newton matrix likewise, and the assembly of the initial state); ``"kkt"``
        ([M D^T; D 0] by the general dense LU). The general dense factorisations are
        LAPACK's algorithms, written out in one order of sums up to 128 unknowns (the same bits
        on every CPU) and LAPACK's own above. Planar scenes only.
    small_dense : bool
        The factorisations for tiny systems, up to 12 rows (block LDL^T, explicit inverse;
        default True); False takes the general dense ones.
        Planar scenes only.
    assemble_initial : bool
        Move the coordinates not marked ``given`` onto the joints before the run (Gauss-Newton;
        default True).
    startup : str
        The start-up of the multistep methods bdf2-bdf6: ``"rk4"`` (the book's, extrapolated)
        or ``"bdf"`` (a ramp of BDF steps, for stiff scenes).
    newton_rtol, newton_atol : float, optional
        The implicit ODE methods' Newton tolerances: 1e-10/1e-12, but 1e-7/1e-9 for the penalty
        formulation, whose accelerations carry roundoff amplified by alpha_p (~1e-9 at 1e7): a
        tighter test would never pass. The index-3 family: 1e-10/1e-12, and adaptive a hundredth
        of err_rtol/err_atol where that is tighter (Newton then does not cap the accuracy asked
        for).
    max_iter : int, optional
        The index-3 family's Newton iteration limit (default 20).
    adaptive : bool or str, optional
        trapezoidal_index3's step-size control: False (fixed h), True = ``"extrapolated"``
        (local extrapolation, third order) or ``"estimated"`` (second order; also the other
        second-order members'). ``help(mbdk.index3)`` says what they do.
    err_rtol, err_atol, dt_out, h_min, h_max : float, optional
        The index-3 family's step-size control: its tolerances, the samples' spacing and the
        step's bounds. ``dt_out``, ``h_min`` and ``h_max`` are also the error-controlled ODE
        methods' (as in ``mbdk.solve_ode``).
    rtol, atol : float, optional
        The error-controlled methods' tolerances (dopri54, bs32, bdf, cvode_*, ida); atol a
        number.
    t_eval : sequence of float, optional
        The error-controlled ODE methods' sample times themselves (increasing, within [t0,
        t_end]; instead of dt_out), each from the method's dense output; the result holds
        exactly these.
    events : callable or list of callables, optional
        SciPy's events, for the error-controlled ODE methods: each ``g(t, y)`` of the time and
        the state y = [q, v], its zeros located on the method's dense output (as
        ``mbdk.solve_ivp`` locates them: ``help(mbdk.ivp)``), with SciPy's ``terminal`` (True,
        or the count of zeros to pass) and ``direction`` attributes; the result's
        ``t_events`` and ``y_events`` list them per function, and a terminal event ends the
        run there (the run is made again to that time, every output with it).
    max_steps, max_order : int, optional
        The error-controlled methods' step limit (default 10^8) and bdf's highest order.
    watch : bool, Watch or dict
        What the run must keep (``mbdk.Watch``): True for the kernel's tolerances, False to
        turn the checks off, or a Watch or a dict with other tolerances. The constraint
        residuals, the energy balance and the momenta the scene conserves are checked while it
        runs; leaving them ends the run with ConstraintDriftError, EnergyDriftError or
        InvariantDriftError at the check where it happened.
    locate_events : bool
        dopri54 and bs32 end a step where a contact closes or lets go (its force before the
        clip at zero changes sign), so that no step straddles the kink in the force (default
        True; the manifest says whether the run's method located them).
    raise_on_failure : bool
        True (the default) raises a failure as its named exception, carrying the partial
        result (``err.result``); False returns the partial result, ``success`` False.
    switch_angles : float, optional
        Spatial scenes in angle coordinates: stop within this distance of the gimbal lock
        (|sin theta| for 3-1-3, |cos beta| for 1-2-3) and go on in the other angle set.
    coordinates : str
        Spatial scenes: ``"absolute"`` (the default: each body's centre and orientation) or
        ``"joint"``: the turns and slides of a spanning tree of revolute, prismatic,
        cylindrical, spherical and fixed joints, the other joints kept as constraints
        (``help(mbdk.joint_coords)``; the ODE methods on the reduced or baumgarte
        formulation). The samples are the bodies' absolute states either way.
    rho_inf, alpha_hht, newmark_beta, newmark_gamma, alpha_m, alpha_f : float, optional
        The index-3 family's parameters (``help(mbdk.alpha_family)``): newmark takes
        newmark_beta, newmark_gamma (default 1/4, 1/2); hht alpha_hht in [-1/3, 0] (default
        -0.05); generalized_alpha rho_inf in [0, 1] (default 0.8), or newmark_beta,
        newmark_gamma, alpha_m, alpha_f given directly. They take trapezoidal_index3's
        formulations, Newton options and, with ``adaptive="estimated"``, its step-size
        control.

    Returns
    -------
    SceneResult
        ``t``, ``q``, ``v``, the outputs asked for, ``stats``, ``cpu_time``, ``status``,
        ``message``, ``success``, ``manifest``, ``visits``, ``assembly`` and ``drift``.

    Raises
    ------
    InvalidInputError
        A bad argument (an unknown option, a value out of range), before the kernel runs;
        NotApplicableError for an option or form this method or scene does not have.
    SceneError
        A scene that cannot be run (an initial state that cannot be assembled names the joints).
    MbdkError
        A failure inside the kernel, as its named subclass (``mbdk.Status`` lists them), with
        the partial result.

    Notes
    -----
    Spatial scenes (``help(mbdk.spatial_file)`` gives their format and formulations) run the
    same methods but euler_cromer, the index-3 family in both formulations (its Newton matrix
    by differences, a body's rotation turned by the exponential map: the Lie-group form); the
    planar model's options (solver, small_dense) are refused by name.

    Examples
    --------
    >>> sc = mbdk.scene("double_pendulum")
    >>> r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0)
    >>> r.q.shape, r.status.name
    ((1001, 6), 'SUCCESS')
    >>> r = mbdk.simulate(sc, "dopri54", rtol=1e-8, atol=1e-10, t_end=1.0, dt_out=0.1)
    >>> r.t.round(2)
    array([0. , 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1. ])
    """
    if unknown:
        raise InvalidInputError(f"{', '.join(sorted(unknown))}: not an option of simulate; "
                                f"trapezoidal_index3 also takes {', '.join(INDEX3_ONLY)}; "
                                "the index-3 family (newmark, hht, generalized_alpha) takes "
                                f"{', '.join(FAMILY_OPTIONS)}")
    if not isinstance(scene, Scene):
        raise InvalidInputError(f"scene must be an mbdk Scene (mbdk.scene(name) or "
                                f"mbdk.load_scene(path)), got {type(scene).__name__}")
    # re-read through the scene reader's checks, before anything reads its fields: fields
    # changed in Python after loading get the errors a file would (element, field, value)
    scene = checked(scene)
    req = Request(method=method, t_end=t_end, h=h, formulation=formulation, t0=t0, every=every,
                  outputs=outputs, alpha=alpha, beta=beta, penalty=penalty,
                  projection_tol=projection_tol, solver=solver, small_dense=small_dense,
                  assemble_initial=assemble_initial, startup=startup, newton_rtol=newton_rtol,
                  newton_atol=newton_atol, max_iter=max_iter, adaptive=adaptive,
                  err_rtol=err_rtol, err_atol=err_atol, dt_out=dt_out, t_eval=t_eval,
                  h_min=h_min,
                  h_max=h_max, rtol=rtol, atol=atol, max_steps=max_steps, max_order=max_order,
                  watch=watch, locate_events=locate_events, raise_on_failure=raise_on_failure,
                  switch_angles=switch_angles, rho_inf=rho_inf, alpha_hht=alpha_hht,
                  newmark_beta=newmark_beta, newmark_gamma=newmark_gamma, alpha_m=alpha_m,
                  alpha_f=alpha_f, coordinates=coordinates)
    if events is not None:
        check_events(events, method, formulation)
    if scene.kind == "spatial" and switch_angles is not None:
        if events is not None or t_eval is not None:
            what = "events" if events is not None else "t_eval"
            raise NotApplicableError(f"{what} with switch_angles: the angle sets' switches "
                                     f"split the run into segments and {what} takes one run; "
                                     "use dt_out for the samples, or a quaternion rotation "
                                     "(no switches)")
        result, warning = switching_run(scene, req, run_scene)
    else:
        result, warning = run_scene(scene, req)
    if events is not None:
        result, warning = scene_events(scene, req, result, warning, events)
    if warning:
        warnings.warn(warning, AccuracyWarning, stacklevel=2)
    return result


def check_events(events, method: str, formulation) -> None:
    """simulate's events, before the run: functions, and a method with a dense output."""
    evs = [events] if callable(events) else events
    if not isinstance(evs, (list, tuple)) or not evs or not all(callable(e) for e in evs):
        raise InvalidInputError("events must be a function g(t, y) or a list of them")
    info = method_info(method)
    if not info.adaptive or info.family in ("ida", "dae_index3") or formulation in ("i3", "si2"):
        raise NotApplicableError(f"events with {method}: they are located on the dense "
                                 "output of the error-controlled ODE methods (dopri54, bs32, "
                                 "bdf, cvode_*, on a formulation)")


def scene_events(scene: Scene, req: Request, result: SceneResult, warning, events):
    """The run with its events (simulate's events): their zeros located on the method's dense
    output by runs of the same request sampled where the search looks (mbdk.ivp's
    locate_events), t_events and y_events set; a terminal event's run made again to its time."""
    evs = [events] if callable(events) else list(events)

    def run(times):
        r, _ = run_scene(scene, replace(req, t_eval=np.asarray(times), dt_out=None,
                                        raise_on_failure=False))
        return r

    s_end = result.t[-1] if len(result.t) else req.t0
    found = locate_events(evs, None, 1.0, run, req.t0, s_end, max(result.stats.steps, 1))
    stop = terminal_stop(evs, found)
    if stop is not None and stop[0] < s_end:
        found = [[(s, y) for s, y in f if s <= stop[0]] for f in found]
        kept = (None if req.t_eval is None else
                [t for t in np.asarray(req.t_eval, float) if t < stop[0]] or None)
        result, warning = run_scene(scene, replace(req, t_end=float(stop[0]), t_eval=kept))
    if stop is not None:
        # SciPy's status 1, "a termination event occurred": which function ended the run
        result.manifest["terminal_event"] = next(
            k for k, f in enumerate(found) if f and f[-1][0] == stop[0])
    result.t_events = [np.array([s for s, _ in f]) for f in found]
    result.y_events = [np.array([y for _, y in f]).reshape(-1, result.y.shape[1])
                       for f in found]
    return result, warning


def run_scene(scene: Scene, req: Request) -> tuple[SceneResult, str | None]:
    """A checked scene's run as requested: plan, validation against the scene, the kernel's run
    and its diagnosis; (result, the text of an AccuracyWarning or None)."""
    plan = make_plan(scene, req)
    check_applicable(scene, plan)
    if plan.kind == "spatial":
        run = run_spatial(scene, plan)
    else:
        scene = prepared(scene, plan)
        run = run_planar(scene, plan)
    result, warning = diagnose(scene, plan, run)
    return keep_samples(result, plan.keep), warning


def evaluate(scene: Scene, q=None, v=None, t: float = 0.0, formulation: str = "reduced",
             solver: str = "auto", **params) -> dict:
    """A scene at one state, from the kernel: Phi, D, gamma, Phi_t, the generalised forces f,
    the formulation's accelerations a and multipliers lam, and the linear solve it took. q, v
    default to the scene's assembled initial state; values the scene takes from its initial pose
    (rest lengths, relative angles) are taken there. params: alpha, beta, penalty,
    projection_tol, small_dense as for simulate."""
    if not isinstance(scene, Scene):
        raise InvalidInputError(f"scene must be an mbdk Scene, got {type(scene).__name__}")
    checks.choice("formulation", formulation, FORMULATIONS, what="a formulation")
    checks.choice("solver", solver, SOLVERS, what="a linear solve")
    unknown = set(params) - {"alpha", "beta", "penalty", "projection_tol", "small_dense"}
    if unknown:
        raise InvalidInputError(f"{', '.join(sorted(unknown))}: not a parameter of evaluate")
    scene = checked(scene)
    if scene.kind == "spatial":
        raise NotApplicableError(f"scene {scene.name!r} has spatial bodies: "
                                 "mbdk.spatial_model.evaluate_spatial evaluates them")
    q0, v0, _ = assemble(scene, build_tables(scene), t)
    q = q0 if q is None else np.asarray(q, float)
    v = v0 if v is None else np.asarray(v, float)
    if q.shape != q0.shape or v.shape != v0.shape:
        raise InvalidInputError(f"q and v need {q0.size} entries each (3 per body), got "
                                f"{q.size} and {v.size}")
    if not (np.all(np.isfinite(q)) and np.all(np.isfinite(v))):
        raise InvalidInputError("q and v must be finite")
    out = evaluate_model(build_tables(scene, q0), q, v, float(t), formulation,
                         model_options(formulation, solver=solver, **params))
    if out["status"].failed:
        raise exception_for(out["status"])(f"evaluating scene {scene.name!r} ({formulation}): "
                                           f"{status_message(out['status'])}",
                                           status=out["status"])
    return out
