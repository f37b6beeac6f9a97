"""trapezoidal_index3: direct integration of a scene's index-3 DAE by the implicit trapezoidal
rule with Newton-Raphson (Fekete 2023, 3.2.1), in the kernel
(kernel/src/dae/mbdk_trapezoidal_index3.f90 is its manual).

    mbdk.simulate(scene, "trapezoidal_index3", formulation="index3", h=..., t_end=...)

Formulations:
  index3                the book's scheme: Newton on (q, lambda), multiplier predictor (3.11);
                        v and a come from the trapezoidal relations and drift off Phi' = 0,
                        Phi'' = 0.
  augmented_lagrangian  the index-3 augmented Lagrangian with mass-orthogonal projections of
                        v and a (ALI3-P); alpha is its penalty factor (default 0: at every
                        step 1e3 max(M) / (h^2/4), so the penalty outweighs the mass matrix
                        1000-fold whatever h). v and a come from the equations of
                        motion (projected), so the Newton tolerance does not limit the
                        accuracy.

Newton: converged when the update computed at an iterate is within rtol/atol (defaults 1e-10,
1e-12; simulate's newton_rtol/newton_atol) and max |Phi| <= atol there; max_iter updates
(default 20). small_dense=False takes LAPACK's LU instead of the in-house one for the Newton
and projection matrices. The result's `a` and `multipliers` are the integrator's own;
`iterations` holds the Newton iterations of the step behind each sample.

Step size: fixed (h, every) by default. adaptive=True starts from h and controls the step by a
local-error estimate on q and v (multipliers excluded) against err_rtol/err_atol (defaults
1e-6, 1e-8); samples every dt_out (default h * every), each one landed on exactly. Rejected
steps and Newton failures (the step is retried at h/4) are counted in stats.
"""
from __future__ import annotations

import math
from numbers import Integral

import numpy as np

from . import _kernel
from .errors import InvalidInputError, NotApplicableError, Status, exception_for, status_message
from .model import VISIT_NAMES, assemble, build_tables, dependent_rows, evaluate, fpar_vector, \
    rows_to_joints
from .ode import build_info
from .result import Stats
from .scene import Scene

INDEX3_FORMULATIONS = {"index3": 1, "augmented_lagrangian": 2}
SCALINGS = {"unscaled": 0, "book": 1, "scaled": 2}
DEFAULT_ALPHA = 0.0   # 0: per step, 1e3 max(M) / (h^2/4) (kernel's MBDK_INDEX3_KAPPA)
INDEX3_OPTIONS = {"adaptive", "err_rtol", "err_atol", "dt_out", "h_min", "h_max", "max_iter"}
NEWTON_RTOL, NEWTON_ATOL, NEWTON_MAX_ITER = 1e-10, 1e-12, 20
# a failed step's report calls D near-singular where its smallest singular value is below this
# fraction of its largest (the collinear four-bar fails within about 1e-3 of its rank loss)
NEAR_SINGULAR = 1e-2
MAX_CUTS = 5          # fixed step, augmented form: a failed step is retried in substeps down
                      # to h / 4^5 (kernel's MBDK_INDEX3_MAX_CUTS)


def simulate_index3(scene: Scene, formulation: str, *, h: float, t_end: float, t0: float = 0.0,
                    every: int = 1, rtol: float | None = None, atol: float | None = None,
                    max_iter: int = NEWTON_MAX_ITER, alpha: float | None = None,
                    adaptive: bool = False, err_rtol: float = 1e-6, err_atol: float = 1e-8,
                    dt_out: float | None = None, h_min: float = 0.0, h_max: float = 0.0,
                    small_dense: bool = True, assemble_initial: bool = True,
                    raise_on_failure: bool = True):
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
    if formulation == "augmented_lagrangian" and not (alpha >= 0 and math.isfinite(alpha)):
        raise InvalidInputError(f"alpha = {alpha}: the augmented Lagrangian's penalty factor "
                                "must be finite and > 0, or 0 for the default (1e3 max(M) "
                                "/ (h^2/4) at every step)")
    every = int(every)
    dt_out = h * every if dt_out is None else dt_out
    if adaptive and formulation == "index3":
        raise NotApplicableError(
            "adaptive=True with formulation 'index3': the book's scheme leaves its velocities "
            "off Phi' = 0 by a period-2 oscillation that grows with time and soon exceeds the "
            "local error, so an error test on q and v would shrink h without end (studies/"
            "index3.py, table index3_long_runs). Use formulation='augmented_lagrangian' for "
            "step-size control, or a fixed h")
    if adaptive:
        for name, val, low in (("err_rtol", err_rtol, 0.0), ("err_atol", err_atol, None),
                               ("dt_out", dt_out, None), ("h_min", h_min, 0.0),
                               ("h_max", h_max, 0.0)):
            ok = isinstance(val, (int, float)) and not isinstance(val, bool) and \
                math.isfinite(val) and (val >= low if low is not None else val > 0)
            if not ok:
                raise InvalidInputError(f"{name} = {val!r} must be a finite number "
                                        f"{'>= 0' if low is not None else '> 0'}")
        if h_max and h_min > h_max:
            raise InvalidInputError(f"h_min = {h_min} exceeds h_max = {h_max}")
    nsteps, nsamp, status = _kernel.index3_plan(t0, t_end, h, every, int(adaptive), err_rtol,
                                                err_atol, dt_out, h_min, h_max)
    if status < 0:
        raise InvalidInputError(
            f"h = {h}, t0 = {t0}, t_end = {t_end}, every = {every}"
            + (f", dt_out = {dt_out}" if adaptive else "")
            + " give no valid plan: need 0 < " + ("dt_out" if adaptive else "h")
            + " <= t_end - t0 and at most 2e9 " + ("samples" if adaptive else "steps"))
    tab = build_tables(scene)
    if assemble_initial:
        q0, v0, report = assemble(scene, tab, t0)
    else:
        q0, v0, report = np.array(scene.q0(), float), np.array(scene.v0(), float), {}
    tab = build_tables(scene, q0)
    fpar = fpar_vector(small_dense=small_dense)
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
    m1 = max(tab.m, 1)
    t, y, a, lam, iters, nw, stats, visits, status = _kernel.model_index3_solve(
        *tab.args(), fpar, INDEX3_FORMULATIONS[formulation], y0, t0, t_end, h, every, rtol,
        atol, int(max_iter), alpha, int(adaptive), err_rtol, err_atol, dt_out, h_min, h_max,
        nsamp, m1)
    status = Status(int(status))
    nw = int(nw)
    t, y = np.array(t[:nw]), np.array(y[:, :nw])
    a, lam = np.array(a[:, :nw]), np.array(lam[:tab.m, :nw])
    out = _outputs(tab, "reduced", fpar, t, y, given=(a, lam))
    nc = tab.nc
    manifest = {**build_info(), "scene": scene.name, "source": scene.source,
                "method": "trapezoidal_index3", "formulation": formulation, "h": h, "t0": t0,
                "t_end": t_end, "every": every, "steps": int(stats[0]),
                "newton": {"rtol": rtol, "atol": atol, "max_iter": int(max_iter),
                           "matrix": "analytic, reused while Newton contracts; "
                                     + _factorisation(formulation, small_dense)}}
    if formulation == "augmented_lagrangian":
        manifest["alpha"] = alpha if alpha > 0 else "1e3 max(M) / (h^2/4), per step"
    if adaptive:
        manifest["step_control"] = {"err_rtol": err_rtol, "err_atol": err_atol,
                                    "dt_out": dt_out, "h0": h, "h_min": h_min, "h_max": h_max,
                                    "estimate": "h^2/12 |a+ - a| on q, h^3/12 |a''| on v"}
    result = SceneResult(
        t=t, q=y[:nc].T, v=y[nc:].T, a=a.T, multipliers=lam.T, reactions=out["reac"],
        energy=out["energy"], energy_parts=out["parts"], residuals=out["resid"],
        stats=Stats.from_array(stats), status=status, message=status_message(status),
        visits=dict(zip(VISIT_NAMES, (int(x) for x in visits))), manifest=manifest,
        assembly=report, joints=[j.name for j in scene.joints],
        bodies=[b.name for b in scene.bodies], iterations=np.array(iters[:nw]))
    if status.failed and raise_on_failure:
        where = f"in the step after t = {t[-1]:.6g}" if nw else "before the first step"
        if nw and not adaptive and formulation == "augmented_lagrangian" and status in (
                Status.ERR_NEWTON_DIVERGED, Status.ERR_NONFINITE, Status.ERR_SINGULAR_MATRIX):
            where += f", also in substeps down to h/{4 ** MAX_CUTS}"
        note = ""
        if nw and tab.m:
            # the last sample is the state the failed step started from
            u, sv, _ = np.linalg.svd(evaluate(tab, y[:nc, -1], y[nc:, -1], t[-1])["D"])
            ratio = sv[-1] / sv[0] if sv.size == tab.m and sv[0] > 0 else 1.0
            if ratio < NEAR_SINGULAR:
                rows = [i for i in range(tab.m) if abs(u[i, -1]) > 0.1]
                note = (f"; there D is close to losing a rank (smallest / largest singular value "
                        f"{ratio:.1e}): joint(s) {', '.join(rows_to_joints(tab, rows))} are "
                        "nearly dependent, a singular configuration of the mechanism")
        raise exception_for(status)(f"trapezoidal_index3/{formulation} on scene {scene.name!r}: "
                                    f"{result.message} ({where}){note}. A smaller h, or a "
                                    "larger max_iter, may get past it", status=status,
                                    result=result)
    return result


def _factorisation(formulation: str, small_dense: bool) -> str:
    """How the kernel factorises the Newton matrix (mbdk_trapezoidal_index3.f90, factor_matrix)."""
    if not small_dense:
        return "LU, LAPACK"
    lu = "LU (its explicit inverse from the third solve on)"
    if formulation == "augmented_lagrangian":
        return ("in-house up to 12 rows: block LDL^T with the bodies as pivot blocks when the "
                f"matrix is symmetric positive definite (no dampers), else {lu}")
    return f"in-house up to 12 rows: {lu}"


def newton_matrix(tab, q, v, lam, h: float, scaling: str = "scaled", t: float = 0.0):
    """The Newton matrix of trapezoidal_index3 at (q, v, lambda) for step h: 'unscaled',
    'book' ((3.15)-(3.16): both rows times h^2/4) or 'scaled' (the solver's)."""
    y = np.concatenate([np.asarray(q, float), np.asarray(v, float)])
    jac, status = _kernel.model_index3_matrix(*tab.args(), fpar_vector(), float(t), y,
                                              np.asarray(lam, float), float(h), SCALINGS[scaling])
    if status != 0:
        raise exception_for(Status(int(status)))(f"Newton matrix: {Status(int(status)).name}")
    return jac
