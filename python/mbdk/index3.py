"""trapezoidal_index3: direct integration of a scene's index-3 DAE by the implicit trapezoidal
rule with Newton-Raphson (Fekete 2023, 3.2.1), in the kernel
(kernel/src/dae/mbdk_trapezoidal_index3.f90 is its manual).

    mbdk.simulate(scene, "trapezoidal_index3", formulation="index3", h=..., t_end=...)

Formulations:
  index3                the book's scheme: Newton on (q, lambda), multiplier predictor (3.11);
                        v and a come from the trapezoidal relations and drift off Phi' = 0,
                        Phi'' = 0.
  augmented_lagrangian  the index-3 augmented Lagrangian with mass-orthogonal projections of
                        v and a (ALI3-P); alpha is its penalty factor (default 1e8).

Newton: rtol/atol on the position update (defaults 1e-10, 1e-12) and max |Phi| <= atol;
max_iter iterations (default 20). The result's `a` and `multipliers` are the integrator's own;
`iterations` holds the Newton iterations of the step behind each sample.
"""
from __future__ import annotations

import math
from numbers import Integral

import numpy as np

from . import _kernel
from .errors import InvalidInputError, Status, exception_for, status_message
from .model import VISIT_NAMES, assemble, build_tables, dependent_rows, evaluate, fpar_vector, \
    rows_to_joints
from .ode import build_info, plan
from .result import Stats
from .scene import Scene

INDEX3_FORMULATIONS = {"index3": 1, "augmented_lagrangian": 2}
SCALINGS = {"unscaled": 0, "book": 1, "scaled": 2}
DEFAULT_ALPHA = 1e8
NEWTON_RTOL, NEWTON_ATOL, NEWTON_MAX_ITER = 1e-10, 1e-12, 20


def simulate_index3(scene: Scene, formulation: str, *, h: float, t_end: float, t0: float = 0.0,
                    every: int = 1, rtol: float | None = None, atol: float | None = None,
                    max_iter: int = NEWTON_MAX_ITER, alpha: float | None = None,
                    assemble_initial: bool = True, raise_on_failure: bool = True):
    from .simulate import SceneResult, _outputs, check_run
    if formulation not in INDEX3_FORMULATIONS:
        raise InvalidInputError(f"formulation = {formulation!r}; trapezoidal_index3 runs "
                                f"{', '.join(INDEX3_FORMULATIONS)}")
    check_run(h, t_end, t0, every)
    rtol = NEWTON_RTOL if rtol is None else float(rtol)
    atol = NEWTON_ATOL if atol is None else float(atol)
    if not (rtol >= 0 and atol > 0):
        raise InvalidInputError(f"newton_rtol = {rtol}, newton_atol = {atol}: need rtol >= 0 "
                                "and atol > 0")
    if isinstance(max_iter, bool) or not isinstance(max_iter, Integral) or max_iter < 1:
        raise InvalidInputError(f"max_iter = {max_iter!r} must be a whole number >= 1")
    alpha = DEFAULT_ALPHA if alpha is None else float(alpha)
    if formulation == "augmented_lagrangian" and not (alpha > 0 and math.isfinite(alpha)):
        raise InvalidInputError(f"alpha = {alpha}: the augmented Lagrangian's penalty factor "
                                "must be finite and > 0 (default 1e8)")
    every = int(every)
    tab = build_tables(scene)
    if assemble_initial:
        q0, v0, report = assemble(scene, tab, t0)
    else:
        q0, v0, report = np.array(scene.q0(), float), np.array(scene.v0(), float), {}
    tab = build_tables(scene, q0)
    fpar = fpar_vector()
    if tab.m:
        d0 = evaluate(tab, q0, v0, t0)["D"]
        dep = dependent_rows(d0)
        if dep:
            raise exception_for(Status.ERR_SINGULAR_MATRIX)(
                f"{scene.source}: the constraints of joint(s) "
                f"{', '.join(rows_to_joints(tab, dep))} are dependent (redundant) at the initial "
                "pose: the index-3 Newton matrix is singular. Remove the redundant joint, or use "
                "an ODE method with formulation = 'penalty'", status=Status.ERR_SINGULAR_MATRIX)
    y0 = np.concatenate([q0, v0])
    nsteps, nsamp, _ = plan(t0, t_end, h, every)
    m1 = max(tab.m, 1)
    t, y, a, lam, iters, nw, stats, visits, status = _kernel.model_index3_solve(
        *tab.args(), fpar, INDEX3_FORMULATIONS[formulation], y0, t0, t_end, h, every, rtol,
        atol, int(max_iter), alpha, nsamp, m1)
    status = Status(int(status))
    nw = int(nw)
    t, y = np.array(t[:nw]), np.array(y[:, :nw])
    a, lam = np.array(a[:, :nw]), np.array(lam[:tab.m, :nw])
    out = _outputs(tab, "reduced", fpar, t, y, given=(a, lam))
    nc = tab.nc
    manifest = {**build_info(), "scene": scene.name, "source": scene.source,
                "method": "trapezoidal_index3", "formulation": formulation, "h": h, "t0": t0,
                "t_end": t_end, "every": every, "steps": nsteps,
                "newton": {"rtol": rtol, "atol": atol, "max_iter": int(max_iter),
                           "matrix": "analytic, LAPACK LU, reused while Newton contracts"}}
    if formulation == "augmented_lagrangian":
        manifest["alpha"] = alpha
    result = SceneResult(
        t=t, q=y[:nc].T, v=y[nc:].T, a=a.T, multipliers=lam.T, reactions=out["reac"],
        energy=out["energy"], energy_parts=out["parts"], residuals=out["resid"],
        stats=Stats.from_array(stats), status=status, message=status_message(status),
        visits=dict(zip(VISIT_NAMES, (int(x) for x in visits))), manifest=manifest,
        assembly=report, joints=[j.name for j in scene.joints],
        bodies=[b.name for b in scene.bodies], iterations=np.array(iters[:nw]))
    if status.failed and raise_on_failure:
        where = f"in the step after t = {t[-1]:.6g}" if nw else "before the first step"
        note = ""
        if nw and tab.m:
            dep = dependent_rows(evaluate(tab, y[:nc, -1], y[nc:, -1], t[-1])["D"], tol=1e-6)
            if dep:
                note = (f"; joint(s) {', '.join(rows_to_joints(tab, dep))} are close to "
                        "dependent there (a singular configuration)")
        raise exception_for(status)(f"trapezoidal_index3/{formulation} on scene {scene.name!r}: "
                                    f"{result.message} ({where}){note}. A smaller h, or a "
                                    "larger max_iter, may get past it", status=status,
                                    result=result)
    return result


def newton_matrix(tab, q, v, lam, h: float, scaling: str = "scaled", t: float = 0.0):
    """The Newton matrix of trapezoidal_index3 at (q, v, lambda) for step h: 'unscaled',
    'book' ((3.15)-(3.16): both rows times h^2/4) or 'scaled' (the solver's)."""
    y = np.concatenate([np.asarray(q, float), np.asarray(v, float)])
    jac, status = _kernel.model_index3_matrix(*tab.args(), fpar_vector(), float(t), y,
                                              np.asarray(lam, float), float(h), SCALINGS[scaling])
    if status != 0:
        raise exception_for(Status(int(status)))(f"Newton matrix: {Status(int(status)).name}")
    return jac
