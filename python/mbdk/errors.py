"""Status codes (mirror of kernel/src/core/mbdk_status.f90 and mbdk.h) and the exceptions.

Every failure has a named exception whose message says which field had which value and what to
change. Failures found before the kernel runs raise at once; failures inside the kernel come back
as a status and are raised by :func:`raise_for_status`.
"""
from __future__ import annotations

from enum import IntEnum
from functools import lru_cache

from . import _kernel


class Status(IntEnum):
    """The kernel's status table; tests/test_status.py checks it against Fortran and C."""

    SUCCESS = 0
    NOTE_LAST_STEP_SHORTENED = 1
    ERR_INVALID_INPUT = -1
    ERR_UNKNOWN_METHOD = -2
    ERR_UNKNOWN_PROBLEM = -3
    ERR_NOT_APPLICABLE = -4
    ERR_OUTPUT_SIZE = -5
    ERR_INCONSISTENT_INITIAL = -6
    ERR_NO_MEMORY = -7
    ERR_STEP_TOO_SMALL = -10
    ERR_TOO_MANY_STEPS = -11
    ERR_TOO_MUCH_ACCURACY = -12
    ERR_NEWTON_DIVERGED = -20
    ERR_SINGULAR_MATRIX = -21
    ERR_NONFINITE = -30
    ERR_CONSTRAINT_DRIFT = -31
    ERR_ENERGY_DRIFT = -32
    ERR_CONTACT_OVERRUN = -33
    ERR_INVARIANT_DRIFT = -34
    ERR_CALLBACK_FAILED = -40
    ERR_BACKEND = -50
    ERR_INTERRUPTED = -60

    @property
    def failed(self) -> bool:
        return self.value < 0


class MbdkError(Exception):
    """Base of every mbdk error; ``status`` is the kernel status it stands for."""

    status = Status.ERR_INVALID_INPUT

    def __init__(self, message: str, *, status: Status | None = None, result=None):
        super().__init__(message)
        if status is not None:
            self.status = status
        #: the partial result (samples written before the failure), for kernel failures
        self.result = result


class InvalidInputError(MbdkError, ValueError):
    """A value given to mbdk is out of range, of the wrong size or not finite."""


class UnknownMethodError(InvalidInputError, KeyError):
    """A method name the kernel does not have; the message lists the known ones
    (``mbdk.methods()``)."""

    status = Status.ERR_UNKNOWN_METHOD

    def __str__(self) -> str:  # KeyError would quote the message
        return self.args[0]


class UnknownProblemError(InvalidInputError, KeyError):
    """A compiled problem's name the kernel does not have; the message lists the known ones
    (``mbdk.problems()``)."""

    status = Status.ERR_UNKNOWN_PROBLEM

    def __str__(self) -> str:
        return self.args[0]


class UnknownParameterError(InvalidInputError, KeyError):
    """A parameter (``params=``) the problem does not have; the message lists its parameters."""

    def __str__(self) -> str:
        return self.args[0]


class NotApplicableError(InvalidInputError):
    """An option, formulation or element that exists but does not apply here: a method on a
    formulation it cannot integrate, a joint the method cannot keep (a knife edge under
    trapezoidal_index3), an option of another method; the message says what does apply."""

    status = Status.ERR_NOT_APPLICABLE


class StepTooSmallError(MbdkError):
    """Error control cut the step below its smallest (``h_min``, or the roundoff of t): the
    solution changes faster than the tolerances can follow there (a singularity, a
    discontinuity, or tolerances near double precision)."""

    status = Status.ERR_STEP_TOO_SMALL


class TooManyStepsError(MbdkError):
    """Error control took max_steps steps before t_end."""

    status = Status.ERR_TOO_MANY_STEPS


class TooMuchAccuracyError(MbdkError, ArithmeticError):
    """The tolerances ask for more than double precision gives."""

    status = Status.ERR_TOO_MUCH_ACCURACY


class NewtonDivergedError(MbdkError, ArithmeticError):
    """An implicit method's Newton iteration did not converge (also at the smallest steps an
    error-controlled method tried): reduce h or loosen the tolerances, or the model is singular
    there; the message says where the run stopped."""

    status = Status.ERR_NEWTON_DIVERGED


class SingularMatrixError(MbdkError, ArithmeticError):
    """A matrix the run must factorise is singular: the mechanism at a singular configuration
    (D loses rank), an angle set at its gimbal lock, or a Newton matrix without inverse; the
    message names the joints or the pose."""

    status = Status.ERR_SINGULAR_MATRIX


class RedundantConstraintsError(SingularMatrixError):
    """The constraint Jacobian has dependent rows: the reduced forms have no unique multipliers."""


class NonFiniteSolutionError(MbdkError, FloatingPointError):
    """The solution overflowed to inf or NaN: the method is unstable at this step."""

    status = Status.ERR_NONFINITE


class NoMemoryError(MbdkError, MemoryError):
    """The kernel could not allocate what the run needs (samples, model buffers)."""

    status = Status.ERR_NO_MEMORY


class ConstraintDriftError(MbdkError, ArithmeticError):
    """The state left the constraint manifold (position or velocity residual) beyond the
    run's tolerance: the result would satisfy the equations of another mechanism."""

    status = Status.ERR_CONSTRAINT_DRIFT


class EnergyDriftError(MbdkError, ArithmeticError):
    """The energy balance (kinetic + potential - work of dissipative forces and drivers) moved
    beyond the run's tolerance: the method added or removed energy the model does not."""

    status = Status.ERR_ENERGY_DRIFT


class ContactOverrunError(MbdkError, ArithmeticError):
    """A contact penetrated beyond what its compliant model covers (a gear mesh's flanks by a
    quarter of the base pitch, where the next tooth would be met): the load or the impact is
    too large for the contact's stiffness."""

    status = Status.ERR_CONTACT_OVERRUN


class InvariantDriftError(MbdkError, ArithmeticError):
    """A momentum or angular momentum the scene conserves (no force or moment of its elements
    along it), or a quaternion's unit norm, moved beyond the run's tolerance: the method does
    not keep what the mechanics keeps (mbdk.watch names the invariant)."""

    status = Status.ERR_INVARIANT_DRIFT


class CallbackError(MbdkError):
    """A user's right-hand side or Jacobian (a Python function, or a C callback returning
    non-zero) failed; a Python exception raised in it is chained as the cause."""

    status = Status.ERR_CALLBACK_FAILED


class BackendError(MbdkError):
    """SUNDIALS (cvode_*, ida) failed in a way no other status names (its constraint,
    nonlinear-solver or linear-solver set-up failures, an interpolation it refused)."""

    status = Status.ERR_BACKEND


class AccuracyWarning(UserWarning):
    """A successful run whose result has a part that its method does not compute accurately
    (the book's index-3 scheme's multipliers and reactions, whose error grows as h shrinks):
    the run says so in a warning and in its manifest, instead of returning the numbers
    without a word."""


class SolveInterrupted(KeyboardInterrupt):
    """A solve stopped by Ctrl-C (or its interrupt flag): a KeyboardInterrupt, so that code which
    catches Exception does not swallow it, carrying the partial result (the samples up to the
    interruption) and the kernel status ERR_INTERRUPTED."""

    status = Status.ERR_INTERRUPTED

    def __init__(self, message: str, *, status: Status | None = None, result=None):
        super().__init__(message)
        self.result = result


_BY_STATUS = {
    Status.ERR_INVALID_INPUT: InvalidInputError,
    Status.ERR_UNKNOWN_METHOD: UnknownMethodError,
    Status.ERR_UNKNOWN_PROBLEM: UnknownProblemError,
    Status.ERR_NOT_APPLICABLE: NotApplicableError,
    Status.ERR_OUTPUT_SIZE: InvalidInputError,
    Status.ERR_INCONSISTENT_INITIAL: InvalidInputError,
    Status.ERR_NO_MEMORY: NoMemoryError,
    Status.ERR_STEP_TOO_SMALL: StepTooSmallError,
    Status.ERR_TOO_MANY_STEPS: TooManyStepsError,
    Status.ERR_TOO_MUCH_ACCURACY: TooMuchAccuracyError,
    Status.ERR_NEWTON_DIVERGED: NewtonDivergedError,
    Status.ERR_SINGULAR_MATRIX: SingularMatrixError,
    Status.ERR_NONFINITE: NonFiniteSolutionError,
    Status.ERR_CONSTRAINT_DRIFT: ConstraintDriftError,
    Status.ERR_ENERGY_DRIFT: EnergyDriftError,
    Status.ERR_CONTACT_OVERRUN: ContactOverrunError,
    Status.ERR_INVARIANT_DRIFT: InvariantDriftError,
    Status.ERR_CALLBACK_FAILED: CallbackError,
    Status.ERR_BACKEND: BackendError,
    Status.ERR_INTERRUPTED: SolveInterrupted,
}


def stopped_at(stats, t0: float) -> str:
    """Where a failed solve stopped: after its last accepted step (stats.t_reached; the failure
    lies in the step after it), not at its last sample, which may lie far before."""
    if not stats.steps:
        return f"at t = {t0:.6g}, in the first step"
    return f"after t = {stats.t_reached:.6g}"


def failure_text(status: Status, adaptive: bool, dae: bool = False) -> str:
    """The kernel's message for a failure status, with the advice that fits the kind of method:
    an error-controlled method chooses its own steps, so "reduce the step h" would ask for what
    it already tried."""
    status = Status(status)
    if adaptive and status == Status.ERR_NEWTON_DIVERGED:
        return ("Newton-Raphson iteration did not converge, also at the smallest steps the "
                "method tried: the tolerances may lie below what the iteration reaches in "
                "double precision (loosen rtol and atol)"
                + (", or the DAE's start or the mechanism is singular there" if dae else
                   ", or the model is singular there"))
    if adaptive and status == Status.ERR_NONFINITE:
        return "the solution overflowed to inf or NaN"
    if adaptive and status == Status.ERR_STEP_TOO_SMALL:
        return ("the step size became too small: the solution changes faster than the "
                "tolerances can follow there (a singularity, a discontinuity, or tolerances "
                "near double precision)")
    return status_message(status)


def format_bytes(n: float) -> str:
    """A size in bytes as people read it: three significant digits, decimal units (48.7 GB)."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= scale:
            return f"{n / scale:.3g} {unit}"
    return f"{n:.0f} bytes"


def _count(k: int) -> str:
    return f"{k:,}".replace(",", " ")


def no_memory_message(alloc_bytes: float, matrices=(), smaller: str = "fewer bodies",
                      samples: bool = True) -> str:
    """What ERR_NO_MEMORY says: the bytes the kernel asked for (Stats.alloc_bytes; 0 where the
    kernel could not tell), what they were where the size tells it, and what to change.
    matrices: (what, order, advice) of the run's dense square matrices (the Newton matrix of an
    implicit method over its unknowns, the penalty formulation's over the coordinates, ...): an
    allocation of at least one of them is named as the largest such, with its advice. samples:
    the run has samples, whose number is a remedy too."""
    text = (f"the kernel could not allocate {format_bytes(alloc_bytes)}" if alloc_bytes > 0 else
            "the kernel ran out of memory (the size it asked for is not known)")
    fits = [m for m in matrices if m[1] and alloc_bytes >= 0.99 * 8.0 * m[1] * m[1]]
    if not fits:
        return text + f"; {smaller}" + (", or fewer samples (a larger every or dt_out, a shorter "
                                         "t_end)" if samples else "")
    what, order, advice = max(fits, key=lambda m: m[1])
    k, n = max(1, round(alloc_bytes / (8.0 * order * order))), _count(order)
    return (text + f" ({'a' if k == 1 else k} dense {n} x {n} matri{'x' if k == 1 else 'ces'}: "
            f"{what}{'' if k == 1 else ' and its factors'}); {advice}, or {smaller}")


def exception_for(status: Status) -> type:
    """The exception class that stands for a failure status."""
    return _BY_STATUS.get(Status(status), MbdkError)


def status_message(status: int) -> str:
    """The kernel's own message for a status code."""
    msg = _kernel_messages().get(int(status))
    return msg if msg is not None else f"unknown status code {status}"


@lru_cache(maxsize=1)
def _kernel_messages() -> dict:
    table = {}
    for i in range(1, len(Status) + 1):
        code, _name, msg = _kernel.status_entry(i)
        table[int(code)] = decode_text(msg)
    return table


def decode_text(b) -> str:
    """A name or message from the kernel (a Fortran character array, padded) as a str."""
    if isinstance(b, bytes):
        return b.decode("ascii", "replace").strip()
    if hasattr(b, "tobytes"):
        return b.tobytes().decode("ascii", "replace").strip("\x00 ")
    return str(b).strip()
