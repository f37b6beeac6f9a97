"""simulate(scene, method, formulation=..., h=..., t_end=...): a planar scene integrated by any
fixed-step kernel method on any chapter-3 formulation, the whole time loop compiled.

Formulations (Fekete 2023, section 3; kernel/src/model/mbdk_model.f90 is their manual):
  reduced     DAE -> ODE: [M D^T; D 0][q''; lambda] = [f; gamma] at every evaluation
  baumgarte   gamma - 2 alpha Phi' - beta^2 Phi (defaults alpha = 1/h, beta = sqrt(2)/h, (3.34))
  penalty     Jalon-Bayo (3.35)-(3.40): alpha_p, omega_p, mu_p = 1e7, 10, 1
  projection  reduced + projection of q onto Phi = 0 and of v onto Phi' = 0 after every step

Linear solves (solver=; the manifest's linear_solve says which one ran):
  auto            revolute_schur when every joint is revolute (up to 12 constraint rows), else
                  schur when every body has mass and inertia, else kkt
  revolute_schur  S = D M^-1 D^T in closed 2 x 2 blocks from the joint points, block LDL^T
  schur           S from the nonzeros of D (any joint type), in-house block LDL^T up to 12 rows
                  (small_dense=False or more rows: LAPACK dpotrf/dpotrs)
  kkt             [M D^T; D 0] by LAPACK's LU

Outputs, one row per sample: t, q, v, a, multipliers, reactions (per joint: Fx, Fy and the
moment about the joint point, exerted by the joint on its body1, global frame: -D_body1^T
lambda), energy (kinetic + potential) with its parts, the work of dampers, constraints and
loads accumulated by the trapezoidal rule over the samples (exact only as every -> 1), and
residuals (max |Phi|, max |Phi'|, max |D a - gamma|).
"""
from __future__ import annotations

import math
from numbers import Integral
from dataclasses import dataclass, field

import numpy as np

from . import _kernel
from .errors import InvalidInputError, SingularMatrixError, Status, exception_for, status_message
from .methods import method as _method
from .model import (FORMULATIONS, SOLVERS, VISIT_NAMES, Tables, assemble, build_tables,
                    dependent_rows, evaluate, fpar_vector, rows_to_joints)
from .ode import NEWTON_ATOL, NEWTON_MAX_ITER, NEWTON_RTOL, _INT_MAX, _STARTUP, build_info, plan
from .result import Stats
from .scene import Scene


class RedundantConstraintsError(SingularMatrixError):
    """The constraint Jacobian has dependent rows: the reduced forms have no unique multipliers."""


@dataclass
class SceneResult:
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    a: np.ndarray
    multipliers: np.ndarray
    reactions: np.ndarray          # (nsamp, njoints, 3)
    energy: np.ndarray             # kinetic + potential, one per sample
    energy_parts: dict
    residuals: np.ndarray          # (nsamp, 3): position, velocity, acceleration
    stats: Stats
    status: Status
    message: str
    visits: dict
    manifest: dict = field(default_factory=dict)
    assembly: dict = field(default_factory=dict)
    joints: list = field(default_factory=list)
    bodies: list = field(default_factory=list)
    iterations: np.ndarray | None = None   # trapezoidal_index3: Newton iterations per sample

    @property
    def success(self) -> bool:
        return not self.status.failed

    @property
    def cpu_time(self) -> float:
        return self.stats.cpu_time

    def reaction(self, joint: str) -> np.ndarray:
        """(nsamp, 3): Fx, Fy, moment of the named joint on its body1."""
        return self.reactions[:, self.joints.index(joint), :]

    def energy_balance(self) -> np.ndarray:
        """E(t) + damper work - load work - constraint work - E(0): zero for an exact solution."""
        p = self.energy_parts
        return (self.energy + p["dissipated_dampers"] - p["work_loads"] - p["work_constraints"]
                - self.energy[0])


def _cumtrapz(t, p):
    out = np.zeros_like(p)
    if len(t) > 1:
        with np.errstate(invalid="ignore", over="ignore"):
            out[1:] = np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(t))
    return out


def check_run(h, t_end, t0, every) -> None:
    """The step, interval and sampling of a scene run, as named errors."""
    for name, val in (("h", h), ("t_end", t_end), ("t0", t0)):
        if isinstance(val, bool) or not isinstance(val, (int, float)) or not math.isfinite(val):
            raise InvalidInputError(f"{name} = {val!r} must be a finite number")
    if not h > 0:
        raise InvalidInputError(f"h = {h} is not positive; give a step h > 0")
    if not t_end > t0:
        raise InvalidInputError(f"t_end = {t_end} must be greater than t0 = {t0}")
    if isinstance(every, bool) or not isinstance(every, Integral) or not 1 <= every <= _INT_MAX:
        raise InvalidInputError(f"every = {every!r} must be a whole number from 1 to {_INT_MAX}")


def simulate(scene: Scene, method: str, *, h: float, t_end: float, formulation: str = "reduced",
             t0: float = 0.0, every: int = 1, alpha: float | None = None,
             beta: float | None = None, penalty: tuple = (1e7, 10.0, 1.0),
             projection_tol: float = 1e-12, solver: str = "auto", small_dense: bool = True,
             assemble_initial: bool = True, startup: str = "rk4",
             newton_rtol: float | None = None, newton_atol: float | None = None,
             raise_on_failure: bool = True, **index3_options) -> SceneResult:
    """Integrate a scene. See the module docstring for formulations and outputs.

    newton_rtol/atol (implicit methods): default 1e-10/1e-12, but 1e-7/1e-9 for the penalty
    formulation, whose accelerations carry roundoff amplified by alpha_p (~1e-9 at 1e7): a
    tighter test would never pass.

    index3_options (method trapezoidal_index3 only): adaptive, err_rtol, err_atol, dt_out,
    h_min, h_max (step-size control) and max_iter (Newton); see mbdk.index3."""
    if not isinstance(scene, Scene):
        raise InvalidInputError(f"scene must be an mbdk Scene (mbdk.scene(name) or "
                                f"mbdk.load_scene(path)), got {type(scene).__name__}")
    from .index3 import INDEX3_FORMULATIONS, INDEX3_OPTIONS, simulate_index3
    if method == "trapezoidal_index3" or formulation in INDEX3_FORMULATIONS:
        if method != "trapezoidal_index3" or formulation not in INDEX3_FORMULATIONS:
            raise InvalidInputError(
                f"method {method!r} with formulation {formulation!r}: trapezoidal_index3 runs "
                f"the formulations {', '.join(INDEX3_FORMULATIONS)} and only those; the ODE "
                f"methods run {', '.join(FORMULATIONS)}")
        unknown = set(index3_options) - INDEX3_OPTIONS
        if unknown:
            raise InvalidInputError(f"{', '.join(sorted(unknown))}: not an option of simulate; "
                                    f"trapezoidal_index3 also takes {', '.join(sorted(INDEX3_OPTIONS))}")
        return simulate_index3(scene, formulation, h=h, t_end=t_end, t0=t0, every=every,
                               rtol=newton_rtol, atol=newton_atol, alpha=alpha,
                               small_dense=small_dense, assemble_initial=assemble_initial,
                               raise_on_failure=raise_on_failure, **index3_options)
    if index3_options:
        raise InvalidInputError(f"{', '.join(sorted(index3_options))}: options of "
                                "trapezoidal_index3 only (adaptive, err_rtol, err_atol, dt_out, "
                                "h_min, h_max, max_iter)")
    if formulation not in FORMULATIONS:
        raise InvalidInputError(f"formulation = {formulation!r}; known: {', '.join(FORMULATIONS)}"
                                ", and index3 / augmented_lagrangian with method "
                                "trapezoidal_index3")
    if solver not in SOLVERS:
        raise InvalidInputError(f"solver = {solver!r}; known: {', '.join(SOLVERS)}")
    if startup not in _STARTUP:
        raise InvalidInputError(f"startup = {startup!r} must be one of {', '.join(_STARTUP)}")
    info_m = _method(method)
    check_run(h, t_end, t0, every)
    every = int(every)
    alpha = 1.0 / h if alpha is None else float(alpha)
    beta = math.sqrt(2.0) / h if beta is None else float(beta)
    if formulation == "baumgarte" and not (alpha >= 0 and beta >= 0 and math.isfinite(alpha)
                                           and math.isfinite(beta)):
        raise InvalidInputError(f"alpha = {alpha}, beta = {beta}: Baumgarte parameters must be "
                                "finite and >= 0")
    if len(penalty) != 3 or not all(isinstance(p, (int, float)) and math.isfinite(p) and p > 0
                                    for p in penalty):
        raise InvalidInputError(f"penalty = {penalty!r} must be (alpha_p, omega_p, mu_p), all > 0")
    if not (projection_tol > 0):
        raise InvalidInputError(f"projection_tol = {projection_tol} must be > 0")
    if info_m.steps > 1 and abs((t_end - t0) / h - round((t_end - t0) / h)) > 1e-9 * (t_end - t0) / h:
        n_lo = math.floor((t_end - t0) / h)
        raise InvalidInputError(f"{method} needs equal steps; use h = {(t_end - t0) / max(n_lo, 1):.12g}")

    if newton_rtol is None:
        newton_rtol = 1e-7 if formulation == "penalty" else NEWTON_RTOL
    if newton_atol is None:
        newton_atol = 1e-9 if formulation == "penalty" else NEWTON_ATOL
    if not (newton_rtol > 0 and newton_atol > 0):
        raise InvalidInputError(f"newton_rtol = {newton_rtol}, newton_atol = {newton_atol} must be > 0")
    tab = build_tables(scene)
    fpar = fpar_vector(alpha, beta, tuple(float(p) for p in penalty), projection_tol, solver,
                       small_dense)
    if solver == "revolute_schur":
        other = [f"{j.name} ({j.type})" for j in scene.joints if j.type != "revolute"]
        if other:
            raise InvalidInputError(f"{scene.source}: solver = 'revolute_schur' needs every joint "
                                    f"to be revolute; not revolute: {', '.join(other)}. Use "
                                    "solver = 'schur' or 'auto'")
    if solver in ("schur", "revolute_schur") and np.any(tab.inertia == 0):
        raise InvalidInputError(f"solver = {solver!r} needs every body to have inertia; "
                                f"{[b.name for b in scene.bodies if b.inertia == 0]} have none: "
                                "use solver = 'kkt' or 'auto'")
    if assemble_initial:
        q0, v0, report = assemble(scene, tab, t0)
    else:
        q0, v0, report = np.array(scene.q0(), float), np.array(scene.v0(), float), {}
    tab = build_tables(scene, q0)   # rest lengths and joint angles at the assembled pose
    e0 = evaluate(tab, q0, v0, t0, formulation, fpar)
    if formulation != "penalty" and tab.m:
        d0 = e0["D"]
        dep = dependent_rows(d0)
        if dep:
            names = rows_to_joints(tab, dep)
            rank = np.linalg.matrix_rank(d0, tol=1e-9 * max(1.0, np.abs(d0).max()))
            raise RedundantConstraintsError(
                f"{scene.source}: the constraints of joint(s) {', '.join(names)} are dependent "
                f"(redundant) at the initial pose: D has rank {rank} < {tab.m} rows, so the "
                f"{formulation} formulation has no unique multipliers. "
                "Remove the redundant joint or use formulation = 'penalty', which handles it",
                status=Status.ERR_SINGULAR_MATRIX)

    y0 = np.concatenate([q0, v0])
    nsteps, nsamp, _ = plan(t0, t_end, h, every)
    t, y, nw, stats, visits, status = _kernel.model_solve(
        *tab.args(), FORMULATIONS[formulation], fpar, info_m.id, y0, t0, t_end, h, every,
        newton_rtol, newton_atol, NEWTON_MAX_ITER, _STARTUP[startup], nsamp)
    status = Status(int(status))
    nw = int(nw)
    t, y = np.array(t[:nw]), np.array(y[:, :nw])
    out = _outputs(tab, formulation, fpar, t, y)
    nc = tab.nc
    manifest = {**build_info(), "scene": scene.name, "source": scene.source, "method": method,
                "formulation": formulation, "h": h, "t0": t0, "t_end": t_end, "every": every,
                "steps": nsteps, "solver": solver, "linear_solve": e0["solve"],
                "small_dense": small_dense, "startup": startup,
                "newton": {"rtol": newton_rtol, "atol": newton_atol, "max_iter": NEWTON_MAX_ITER}}
    if formulation == "baumgarte":
        manifest.update(alpha=alpha, beta=beta)
    if formulation == "penalty":
        manifest.update(alpha_p=penalty[0], omega_p=penalty[1], mu_p=penalty[2])
    if formulation == "projection":
        manifest.update(projection_tol=projection_tol)
    result = SceneResult(
        t=t, q=y[:nc].T, v=y[nc:].T, a=out["a"], multipliers=out["lam"],
        reactions=out["reac"], energy=out["energy"], energy_parts=out["parts"],
        residuals=out["resid"], stats=Stats.from_array(stats), status=status,
        message=status_message(status), visits=dict(zip(VISIT_NAMES, (int(x) for x in visits))),
        manifest=manifest, assembly=report, joints=[j.name for j in scene.joints],
        bodies=[b.name for b in scene.bodies])
    if status.failed and raise_on_failure:
        where = f"at t = {t[-1]:.6g}" if nw else "before the first step"
        note = ""
        if status == Status.ERR_SINGULAR_MATRIX and nw:
            dep = dependent_rows(evaluate(tab, y[:nc, -1], y[nc:, -1], t[-1])["D"])
            if dep:
                note = (f": joint(s) {', '.join(rows_to_joints(tab, dep))} became dependent "
                        "(a singular configuration)")
        raise exception_for(status)(f"{method}/{formulation} on scene {scene.name!r}: "
                                    f"{result.message} ({where}){note}", status=status,
                                    result=result)
    return result


def _outputs(tab: Tables, formulation: str, fpar, t, y, given=None) -> dict:
    """Sampled outputs; given = (a, lambda) of an integrator that computes its own (index-3)."""
    ns = len(t)
    if ns == 0:
        z = np.zeros((0,))
        return {"a": np.zeros((0, tab.nc)), "lam": np.zeros((0, tab.m)),
                "reac": np.zeros((0, tab.nj, 3)), "energy": z, "resid": np.zeros((0, 3)),
                "parts": {}}
    if given is None:
        acc = np.zeros((tab.nc, ns), order="F")
        lam = np.zeros((tab.m, ns), order="F")
    else:
        acc = np.asfortranarray(given[0], dtype=float)
        lam = np.asfortranarray(given[1], dtype=float)
    reac, energy, resid, nok, status = _kernel.model_outputs(
        *tab.args(), FORMULATIONS[formulation], fpar, t, np.asfortranarray(y),
        0 if given is None else 1, acc, lam)
    kin, vg, vs, pd, pc, pl = energy
    parts = {"kinetic": kin, "potential_gravity": vg, "potential_springs": vs,
             "power_dampers": pd, "power_constraints": pc, "power_loads": pl,
             "dissipated_dampers": _cumtrapz(t, pd), "work_constraints": _cumtrapz(t, pc),
             "work_loads": _cumtrapz(t, pl)}
    return {"a": acc.T, "lam": lam.T, "reac": np.transpose(reac[:, :tab.nj, :], (2, 1, 0)),
            "energy": kin + vg + vs, "resid": resid.T, "parts": parts}
