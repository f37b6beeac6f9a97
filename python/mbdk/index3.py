"""trapezoidal_index3: direct integration of a scene's index-3 DAE by the implicit trapezoidal
rule with Newton-Raphson (Fekete 2023, 3.2.1), in the kernel
(kernel/src/dae/mbdk_trapezoidal_index3.f90 is its manual)::

    mbdk.simulate(scene, "trapezoidal_index3", formulation="index3", h=..., t_end=...)

simulate (python/mbdk/simulate.py) runs it; this module holds what is particular to it: the
formulation codes, the description of its factorisations for the manifest, and its Newton
matrix at a state (for studies and tests).

Formulations:

index3
    the book's scheme: Newton on (q, lambda), multiplier predictor (3.11); v and a come from
    the trapezoidal relations and drift off Phi' = 0, Phi'' = 0.
augmented_lagrangian
    the index-3 augmented Lagrangian with mass-orthogonal projections of v and a (ALI3-P);
    alpha is its penalty factor (default 0: at every step 1e3 max(M) / (h^2/4), so the penalty
    outweighs the mass matrix 1000-fold whatever h). v and a come from the equations of motion
    (projected), so the Newton tolerance does not limit the accuracy.

Newton: converged when the update computed at an iterate is within rtol/atol (defaults 1e-10,
1e-12; simulate's newton_rtol/newton_atol) and max |Phi| <= atol there; max_iter updates
(default 20). small_dense=False takes the general dense LU (mbdk_lapack) instead of the
tiny-system one (block LDL^T, explicit inverse) for the Newton and projection matrices. The
result's `a` and `multipliers` are the integrator's own; `iterations` holds the Newton
iterations of the step behind each sample.

Step size: fixed (h, every) by default. adaptive=True (= "extrapolated") starts from h and
controls the step on q and v (multipliers excluded) against err_rtol/err_atol (defaults 1e-6,
1e-8) by local Richardson extrapolation: each macro step is one step of H and two of H/2, their
difference the error estimate, and the extrapolated, projected state the result (third order;
stats.steps counts macro steps, three trapezoidal solves each; PI control). adaptive="estimated"
takes one step with its local error estimated from differences of the accelerations (second
order: on motions about equally hard throughout, no distribution of its steps saves much over
the best fixed step; studies/step_control.py); it is also the step-size control of the
second-order newmark, hht and generalized_alpha members, with each member's own local error
constants (the kernel's mbdk_index3_error_constants), while extrapolation is the trapezoidal
rule's alone. Samples every dt_out (default h * every), each
one landed on exactly. Rejected steps and Newton failures (the step is retried at h/4) are
counted in stats.
"""
from __future__ import annotations

import numpy as np

from . import _kernel
from .codes import DENSE_LU, INDEX3_SCALINGS
from .errors import Status, exception_for
from .options import ModelOptions

# a failed step's report calls D near-singular where its smallest singular value is below this
# fraction of its largest (the collinear four-bar fails within about 1e-3 of its rank loss)
NEAR_SINGULAR = 1e-2
# fixed step, augmented form: a failed step is retried in substeps down to h / 4^MAX_CUTS; a run
# gives up when its retries exhaust RETRY_BUDGET (the kernel's constants)
MAX_CUTS, RETRY_BUDGET = (int(x) for x in _kernel.index3_constants())


def factorisation(formulation: str, small_dense: bool) -> str:
    """How the kernel factorises the Newton matrix (kernel/src/dae/mbdk_index3_matrix.f90,
    mbdk_index3_factor)."""
    if not small_dense:
        return DENSE_LU
    lu = "LU (its explicit inverse from the third solve on)"
    if formulation == "augmented_lagrangian":
        return ("in-house up to 12 rows: block LDL^T with the bodies as pivot blocks when the "
                f"matrix is symmetric positive definite (no dampers), else {lu}")
    return f"in-house up to 12 rows: {lu}"


def newton_matrix(tab, q, v, lam, h: float, scaling: str = "scaled", t: float = 0.0):
    """The Newton matrix of trapezoidal_index3 at (q, v, lambda) for step h: 'unscaled',
    'book' ((3.15)-(3.16): both rows times h^2/4) or 'scaled' (the solver's)."""
    y = np.concatenate([np.asarray(q, float), np.asarray(v, float)])
    jac, status = _kernel.model_index3_matrix(*tab.args(), ModelOptions().pack(), float(t), y,
                                              np.asarray(lam, float), float(h),
                                              INDEX3_SCALINGS[scaling])
    if status != 0:
        raise exception_for(Status(int(status)))(f"Newton matrix: {Status(int(status)).name}")
    return jac
