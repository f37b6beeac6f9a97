"""mbdk: a compiled multibody-dynamics kernel (Fortran) for benchmark studies of integrators.

>>> import mbdk
>>> r = mbdk.solve_ode("damped_oscillator", "rk4", h=0.01, t_end=10)
>>> r.y.shape, r.stats.steps, r.success
((1001, 2), 1000, True)
>>> r = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-3, t_end=1)
>>> r.q.shape
(1001, 6)

``mbdk.__version__`` is the installed package's version.
"""
from . import exact  # noqa: F401
from .errors import (AccuracyWarning, BackendError, CallbackError, ConstraintDriftError,
                     ContactOverrunError, EnergyDriftError, InvariantDriftError,
                     InvalidInputError, MbdkError, NewtonDivergedError, NoMemoryError,
                     NonFiniteSolutionError, NotApplicableError, RedundantConstraintsError,
                     SingularMatrixError, SolveInterrupted, Status, StepTooSmallError,
                     TooManyStepsError, TooMuchAccuracyError,
                     UnknownMethodError, UnknownParameterError, UnknownProblemError)
from .methods import MethodInfo, methods
from .ode import ODESolver, build_info, evaluate_rhs, package_version, solve_ode
from .ivp import solve_ivp
from .problems import ProblemInfo, problems
from .options import Index3Options, ModelOptions, ODEOptions, SpatialOptions
from .result import ODEResult, Result, SceneResult, Stats
from . import stability  # noqa: F401,E402
from .stability import StabilityRegion, stability_region
from .scene import Scene, SceneError
from .scene_file import load_scene, scene, scenes
from .scene_report import SceneReport, scene_report
from .simulate import evaluate, simulate
from .watch import Watch
from .fmu import export_fmu

__all__ = [
    "solve_ode", "solve_ivp", "ODESolver", "evaluate_rhs", "methods", "problems", "build_info", "ODEResult", "Stats", "MethodInfo",
    "ProblemInfo", "Status", "MbdkError", "InvalidInputError", "UnknownMethodError",
    "UnknownProblemError", "UnknownParameterError", "NotApplicableError", "StepTooSmallError",
    "TooManyStepsError", "TooMuchAccuracyError",
    "NewtonDivergedError", "SingularMatrixError", "NonFiniteSolutionError", "CallbackError",
    "BackendError", "stability_region", "StabilityRegion", "Scene", "SceneError", "load_scene",
    "scene", "scenes", "scene_report", "SceneReport", "simulate", "SceneResult", "RedundantConstraintsError", "SolveInterrupted",
    "ODEOptions", "Index3Options", "ModelOptions", "SpatialOptions", "Result", "evaluate", "NoMemoryError",
    "ConstraintDriftError", "EnergyDriftError", "InvariantDriftError", "ContactOverrunError",
    "Watch", "AccuracyWarning", "export_fmu",
]


def __getattr__(name: str):
    # __version__ is read from the package metadata when first asked for: importlib.metadata
    # is slow to import, and `import mbdk` need not pay for it
    if name == "__version__":
        return package_version()
    raise AttributeError(f"module 'mbdk' has no attribute {name!r}")
