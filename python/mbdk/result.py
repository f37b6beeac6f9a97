"""Results of a solve: samples, statistics measured in the kernel, status and a manifest."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import Status
from .options import unpack as _unpack


@dataclass(frozen=True)
class Stats:
    """struct mbdk_stats, counted inside the kernel (kernel/src/core/mbdk_stats.f90; the counters
    SciPy users know keep SciPy's names). cpu_time is the solving thread's CPU time of the
    compiled time loop, wall_time its wall-clock time."""

    steps: int = 0
    nfev: int = 0                  # evaluations of F, finite-difference columns included
    njev: int = 0                  # Jacobian evaluations
    nlu: int = 0                   # factorisations of a Newton matrix (LU or LDL^T)
    newton_iterations: int = 0
    startup_steps: int = 0
    rejected_steps: int = 0        # step-size control: steps rejected by the error test
    newton_failures: int = 0       # steps retried because Newton failed
    order1_steps: int = 0          # bdf, cvode_*: accepted steps at order 1..5
    order2_steps: int = 0
    order3_steps: int = 0
    order4_steps: int = 0
    order5_steps: int = 0          # (cvode_adams: order 5 and above)
    cpu_time: float = 0.0
    wall_time: float = 0.0
    t_reached: float = 0.0         # the last accepted step's time (where a failed solve stopped)
    alloc_bytes: float = 0.0       # ERR_NO_MEMORY: the failed allocation's bytes (0: not known)

    @classmethod
    def from_words(cls, words) -> "Stats":
        """From the kernel's struct bytes (8-byte words), field by field by name."""
        # every field comes from the kernel's struct, so the frozen instance is filled directly:
        # the generated __init__ sets each field one by one through object.__setattr__, which
        # cost more than a short solve's kernel call
        stats = object.__new__(cls)
        stats.__dict__.update(_unpack("mbdk_stats", words))
        return stats


class Result:
    """What every solve returns (solve_ode: ODEResult, simulate: SceneResult): samples t and the
    state y (one row per sample), stats, status, message, manifest; success is False only when
    the caller asked for failures as results (raise_on_failure=False), and then the samples are
    those written before the failure."""

    @property
    def success(self) -> bool:
        return not self.status.failed

    @property
    def cpu_time(self) -> float:
        """CPU seconds of the solving thread in the compiled time loop."""
        return self.stats.cpu_time

    @property
    def wall_time(self) -> float:
        return self.stats.wall_time


@dataclass
class ODEResult(Result):
    """t (nsamp,), y (nsamp, n): one row per sample (see Result)."""

    t: np.ndarray
    y: np.ndarray
    stats: Stats
    status: Status
    message: str
    manifest: dict = field(default_factory=dict)
    problem: str = ""
    method: str = ""
    params: dict = field(default_factory=dict)
    t0: float = 0.0
    y0: np.ndarray | None = None

    def exact(self) -> np.ndarray | None:
        """The exact solution at the sample times, or None where the problem has none."""
        from .exact import exact_solution
        return exact_solution(self.problem, self.t, self.t0, self.y0, self.params)

    def max_error(self, component: int | None = None) -> float | None:
        """Largest absolute error over the samples (all components, or one), or None."""
        ex = self.exact()
        if ex is None:
            return None
        d = np.abs(self.y - ex)
        return float(np.max(d if component is None else d[:, component]))

    def final_error(self, component: int = 0) -> float | None:
        ex = self.exact()
        return None if ex is None else float(abs(self.y[-1, component] - ex[-1, component]))

    def energy(self) -> np.ndarray | None:
        from .problems import problems
        info = problems().get(self.problem)
        if info is None or info.energy is None:
            return None
        return info.energy(self.y, self.params)
