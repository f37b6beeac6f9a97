"""solve_ode: the compiled textbook ODEs and users' own right-hand sides, integrated by the
kernel's fixed-step methods with the whole time loop in Fortran.

A Python function f(t, y) is accepted too. That path calls back into Python at every
evaluation of F (about 1 us each): it is the documented slow path, for convenience only.
"""
from __future__ import annotations

import math
import platform
import threading
from dataclasses import replace
from functools import lru_cache
from numbers import Integral

import numpy as np

from . import _compiled, _kernel, checks
from .codes import STARTUP
from .errors import (CallbackError, InvalidInputError, NotApplicableError, SolveInterrupted,
                     Status, decode_text, exception_for, failure_text, status_message, stopped_at)
from .errors import no_memory_message
from .methods import method as _method, methods
from .options import ODEOptions, empty
from .problems import problem as _problem, resolve_params
from .result import ODEResult, Stats

# f2py's callback machinery keeps the Python function in module state: one callback solve at a
# time (compiled problems need no lock), and none started from inside a callback (the inner one
# would wait for the lock its own caller holds).
_CALLBACK_LOCK = threading.Lock()
_IN_CALLBACK = threading.local()

MAX_STEPS = int(_kernel.max_steps())   # the kernel's limit (mbdk_fixed_step: MBDK_MAX_STEPS)
_INT_MAX = 2**31 - 1
_STATUS = {int(s): s for s in Status}
_STATS_WORDS = empty("mbdk_stats").size


@lru_cache(maxsize=1)
def package_version() -> str:
    """mbdk's version, from the installed package's metadata (pyproject.toml's ``version``):
    ``mbdk.__version__``, ``mbdk --version`` and every manifest's ``version``."""
    try:
        # importlib.metadata is slow to import, and only the version needs it
        from importlib.metadata import version
        return version("mbdk")
    except Exception:  # pragma: no cover - running from a source tree without metadata
        return "0+unknown"


@lru_cache(maxsize=1)
def build_info() -> dict:
    """What built and runs this copy: mbdk's version, the Fortran compiler and its flags, the
    numpy and Python versions and the machine (every result's manifest carries them)."""
    compiler, options = _kernel.build_info()
    return {"version": package_version(), "compiler": decode_text(compiler),
            "compiler_flags": decode_text(options),
            "numpy": np.__version__, "python": platform.python_version(),
            "machine": platform.machine()}


def _real(name: str, value) -> float:
    if type(value) is float and math.isfinite(value):   # the common case, without ABC checks
        return value
    return checks.real(name, value)


def plan(t0: float, t_end: float, h: float, every: int = 1) -> tuple[int, int, bool]:
    """(steps, samples, last_step_shortened) for an interval, as the kernel will take them."""
    steps = (t_end - t0) / h if h > 0 else math.inf
    if steps > MAX_STEPS:
        raise InvalidInputError(f"h = {h} gives {steps:.3g} steps over t_end - t0 = {t_end - t0}; "
                                f"the kernel takes at most {MAX_STEPS:.0e}: give a larger h")
    nsteps, nsamp, status = _kernel.sample_count(t0, t_end, h, every)
    if status < 0:
        raise InvalidInputError(f"h = {h}, t0 = {t0}, t_end = {t_end}, every = {every} give no "
                                "valid step plan (need 0 < h <= t_end - t0 and every >= 1)")
    return int(nsteps), int(nsamp), status == Status.NOTE_LAST_STEP_SHORTENED


def solve_ode(problem, method: str, *, h: float | None = None, t_end: float, t0: float = 0.0,
              y0=None, params: dict | None = None, every: int = 1, nq: int = 0,
              fd_jacobian: bool = False, startup: str = "rk4", rtol: float | None = None,
              atol=None, dt_out: float = 0.0, h_min: float = 0.0, h_max: float = 0.0,
              max_steps: int = 0, max_order: int = 0, jac=None, t_eval=None,
              raise_on_failure: bool = True) -> ODEResult:
    """Integrate a compiled textbook problem (by name) or a Python f(t, y), the time loop in the
    kernel: with a fixed step h, or with error control (mbdk.methods(step="adaptive")).

    Parameters
    ----------
    problem : str or callable
        A name from mbdk.problems(), or a callable f(t, y) -> dy/dt (the slow path: y0
        needed; nq > 0 declares y = [q; v] for euler_cromer).
    method : str
        A name from mbdk.methods("ode").
    h : float, optional
        Fixed step (rk4, bdf4, ...): the step. Error-controlled: the first step (default:
        chosen by the method).
    t_end, t0 : float
        The interval (t0 default 0).
    y0 : array_like, optional
        The initial state (default: the problem's).
    params : dict, optional
        Overrides of the problem's parameters, by name.
    every : int
        Fixed step: keep every k-th step (and the last) as a sample.
    nq : int
        With a Python f: the number of positions q in y = [q; v] (euler_cromer needs it).
    fd_jacobian : bool
        Take the Jacobian of a compiled problem by differences even where it has its own.
    startup : str
        How bdf2..bdf6 get their first values: "rk4" (RK4 steps, the book's (4.80),
        Richardson-extrapolated so that bdf6 keeps order 6) or "bdf" (BDF steps of rising
        order 1..k-1: stable on stiff problems, where RK4 steps blow up, but the order-1 first
        step limits the global order to 2).
    rtol, atol : float or array_like, optional
        Error-controlled (dopri54, bs32, bdf, cvode_bdf, cvode_adams): each step's local error
        estimate e is kept at sqrt(mean((e_i / (atol_i + rtol abs(y_i)))^2)) <= 1 (defaults
        1e-6 and 1e-8; atol a number or one value per state).
    dt_out : float
        Error-controlled: a sample every dt_out from the dense output (0: t0 and t_end only).
    t_eval : array_like, optional
        Error-controlled: the sample times themselves (increasing, within [t0, t_end]), each
        from the method's dense output as dt_out's are; the result holds exactly these.
    h_min, h_max : float
        Error-controlled: bounds of the step (0: none).
    max_steps : int
        Error-controlled: the most steps, rejected ones included (0: 10^8).
    max_order : int
        bdf and cvode_bdf 1-5, cvode_adams 1-12 (0: the highest).
    jac : callable, optional
        With a Python f, its Jacobian jac(t, y) -> n x n array dF_i/dy_j, used by the implicit
        methods' Newton iterations instead of finite differences (compiled problems carry their
        own where they have one).
    raise_on_failure : bool
        A failure inside the kernel raises its named exception (default); with False the
        partial result is returned with its status.

    Returns
    -------
    ODEResult
        ``t``, ``y`` (samples x states), ``stats``, ``cpu_time``, ``status``, ``message``,
        ``success``, ``manifest``; ``exact()`` and ``max_error()`` where the problem has an
        exact solution.

    Examples
    --------
    >>> r = mbdk.solve_ode("pendulum", "rk4", h=0.01, t_end=5)
    >>> r.y.shape, r.max_error() < 1e-6
    ((501, 2), True)
    """
    if not callable(problem):
        return ODESolver(problem, method, h=h, t_end=t_end, t0=t0, y0=y0, params=params,
                         every=every, fd_jacobian=fd_jacobian, startup=startup, rtol=rtol,
                         atol=atol, dt_out=dt_out, h_min=h_min, h_max=h_max,
                         max_steps=max_steps, max_order=max_order, jac=jac, t_eval=t_eval,
                         raise_on_failure=raise_on_failure).solve()
    info_m, opt, nsteps, nsamp, control, t0, t_end = _plan_of(
        method, h, t_end, t0, every, startup, rtol, atol, dt_out, h_min, h_max, max_steps,
        max_order, fd_jacobian)
    times, keep = sample_times(t_eval, info_m, t0, t_end, dt_out)
    if keep is not None:
        nsamp, control = len(times), {**control, "t_eval": int(keep.sum())}
    if jac is not None and not callable(jac):
        raise InvalidInputError(f"jac = {jac!r} must be a function jac(t, y) returning the "
                                "n x n Jacobian")
    return kept(_solve_callback(problem, info_m, opt, t0, t_end, y0, nq, nsamp,
                                raise_on_failure, atol, control, jac, times), keep)


def sample_times(t_eval, info_m, t0: float, t_end: float, dt_out) -> tuple:
    """(the kernel's sample times, a mask of the requested ones among them) for t_eval;
    (empty, None) without it. The kernel samples t0 and t_end too (its first and last
    states)."""
    if t_eval is None:
        return np.zeros(0), None
    if not info_m.adaptive:
        raise InvalidInputError(f"t_eval: {info_m.name} takes a fixed step and samples its own "
                                "grid (every); t_eval is for the error-controlled methods, "
                                "which sample their dense output")
    if dt_out:
        raise InvalidInputError(f"t_eval and dt_out = {dt_out!r}: give one of the two")
    try:
        te = np.asarray(t_eval, dtype=float)
    except (TypeError, ValueError):
        raise InvalidInputError(f"t_eval = {checks.show(t_eval)} must be a list of times") \
            from None
    if te.ndim != 1 or te.size == 0 or not np.all(np.isfinite(te)):
        raise InvalidInputError(f"t_eval must be a non-empty list of finite times, got shape "
                                f"{te.shape}")
    if np.any(np.diff(te) <= 0):
        raise InvalidInputError("t_eval must be strictly increasing")
    if te[0] < t0 or te[-1] > t_end:
        raise InvalidInputError(f"t_eval runs from {te[0]:g} to {te[-1]:g}, outside "
                                f"[t0, t_end] = [{t0:g}, {t_end:g}]")
    times = np.unique(np.concatenate([[t0], te, [t_end]]))
    return times, np.isin(times, te)


def kept(result: ODEResult, keep) -> ODEResult:
    """The result's samples at the times asked for (keep: their mask among the kernel's; None:
    all)."""
    if keep is not None:
        k = keep[:len(result.t)]
        result.t, result.y = result.t[k], result.y[k]
    return result


def _plan_of(method, h, t_end, t0, every, startup, rtol, atol, dt_out, h_min, h_max, max_steps,
             max_order, fd_jacobian):
    """The checked method and options of a solve: (method info, ODEOptions, steps (inf when
    error-controlled), samples, the manifest's entries, t0, t_end)."""
    checks.choice("startup", startup, STARTUP, what="a start-up of the multistep methods")
    info_m = _method(method)
    if info_m.solves != "ode":
        kind = "index-3 DAE" if info_m.family == "dae_index3" else "DAE"
        raise NotApplicableError(f"{method} integrates a scene's {kind}, not an ODE: use "
                                 f"mbdk.simulate(scene, {method!r}, ...); for ODEs one of "
                                 f"{', '.join(methods('ode'))}")
    t0 = _real("t0", t0)
    t_end = _real("t_end", t_end)
    if not t_end > t0:
        raise InvalidInputError(f"t_end = {t_end} must be greater than t0 = {t0}")
    if not (type(every) is int or (not isinstance(every, bool) and isinstance(every, Integral))) \
            or not 1 <= every <= _INT_MAX:
        raise InvalidInputError(f"every = {every!r} must be a whole number from 1 to {_INT_MAX}")
    if info_m.adaptive:
        opt, nsteps, nsamp, control = adaptive_options(
            info_m, h, t0, t_end, every, rtol, atol, dt_out, h_min, h_max, max_steps, max_order,
            fd_jacobian)
    else:
        for name, value, default in (("rtol", rtol, None), ("atol", atol, None),
                                     ("dt_out", dt_out, 0.0), ("h_min", h_min, 0.0),
                                     ("h_max", h_max, 0.0), ("max_steps", max_steps, 0),
                                     ("max_order", max_order, 0)):
            unset = value is None or (default is not None and type(value) in (int, float)
                                      and value == default) or (
                                      default is not None and np.ndim(value) == 0
                                      and not isinstance(value, (str, bytes))
                                      and value == default)
            if not unset:
                raise InvalidInputError(
                    f"{name} = {value!r}: {method} takes a fixed step h and no {name}; for error "
                    f"control use one of {', '.join(methods('ode', step='adaptive'))}")
        if h is None:
            raise InvalidInputError(f"{method} takes a fixed step: give h (or use an "
                                    "error-controlled method with rtol and atol)")
        h = _real("h", h)
        if not h > 0:
            raise InvalidInputError(f"h = {h} is not positive; give a step h > 0")
        if h > (t_end - t0) * (1 + 1e-12):
            raise InvalidInputError(f"h = {h} is larger than the interval t_end - t0 = "
                                    f"{t_end - t0}; give a step no larger than the interval")
        nsteps, nsamp, shortened = plan(t0, t_end, h, int(every))
        opt = ODEOptions(h=h, method=info_m.id, every=int(every), startup=STARTUP[startup],
                         fd_jacobian=int(bool(fd_jacobian)))
        control = {"h": h, "every": int(every), "steps": nsteps, "startup": startup}
        if shortened and info_m.steps > 1:
            n_lo = math.floor((t_end - t0) / h)
            raise InvalidInputError(
                f"{method} needs equal steps, but (t_end - t0)/h = {(t_end - t0) / h:.6g} is not "
                f"a whole number; use h = {(t_end - t0) / max(n_lo, 1):.12g} or "
                f"h = {(t_end - t0) / (n_lo + 1):.12g}")

    return info_m, opt, nsteps, nsamp, control, t0, t_end


class ODESolver:
    """A compiled problem's solve, checked once and run as often as wanted: the lean path for
    many short solves (a parameter study, an optimiser's inner loop, a Monte-Carlo of initial
    states). The arguments are solve_ode's (a compiled problem only; nq does not apply);
    solve(y0=None) runs it, from the given initial state or the one given here, and returns
    the ODEResult solve_ode would. Python's share of a 1 000-step rk4 solve is then a few
    microseconds beside the f2py call (studies/pipeline_cost.py measures it)."""

    def __init__(self, problem, method: str, *, h: float | None = None, t_end: float,
                 t0: float = 0.0, y0=None, params: dict | None = None, every: int = 1,
                 fd_jacobian: bool = False, startup: str = "rk4", rtol: float | None = None,
                 atol=None, dt_out: float = 0.0, h_min: float = 0.0, h_max: float = 0.0,
                 max_steps: int = 0, max_order: int = 0, jac=None, t_eval=None,
                 raise_on_failure: bool = True):
        info_m, opt, nsteps, nsamp, control, t0, t_end = _plan_of(
            method, h, t_end, t0, every, startup, rtol, atol, dt_out, h_min, h_max, max_steps,
            max_order, fd_jacobian)
        self._times, self._keep = sample_times(t_eval, info_m, t0, t_end, dt_out)
        if self._keep is not None:
            nsamp, control = len(self._times), {**control, "t_eval": int(self._keep.sum())}
        if callable(problem):
            raise NotApplicableError("ODESolver runs compiled problems; a Python f(t, y) goes "
                                     "to solve_ode (the slow path)")
        if jac is not None and not callable(jac):
            raise InvalidInputError(f"jac = {jac!r} must be a function jac(t, y) returning the "
                                    "n x n Jacobian")
        if jac is not None:
            raise InvalidInputError(f"jac: {problem!r} is a compiled problem, with its own "
                                    "Jacobian where it has one (fd_jacobian=True replaces it by "
                                    "differences); jac goes with a Python right-hand side")
        info_p = _problem(problem)
        if y0 is None:
            if info_p.y0 is None:
                raise InvalidInputError(f"problem {problem!r} has no default y0; give y0")
            y0 = info_p.y0
        y0 = state_vector("y0", y0, info_p.n if info_p.n > 0 else None)
        if info_m.family == "euler_cromer" and not info_p.second_order:
            raise NotApplicableError(f"euler_cromer needs a second-order problem (y = [q, q']); "
                                     f"{problem!r} is first order. Use explicit_euler, heun or "
                                     "rk4")
        self._atol = _atol_vector(atol, len(y0), opt.rtol) if info_m.adaptive else np.zeros(0)
        merged, self._pvec = resolve_params(info_p, params, len(y0))
        self.problem, self.method, self.t0, self.t_end = problem, method, t0, t_end
        y0.setflags(write=False)     # every result of the default start shares it
        self.params, self.y0 = merged, y0
        self._id, self._opt, self._nsamp = info_p.id, opt.pack(), nsamp
        self._n, self._nsteps, self._raise = len(y0), nsteps, raise_on_failure
        self._bytes = sample_bytes(nsamp, len(y0), method)
        self._work = nsteps * len(y0)
        # an error-controlled solve's steps are not known before it runs: it is tried in this
        # thread within a budget of steps whose work is short (LONG_WORK), and only a solve that
        # needs more is run again, whole, in the worker thread (the same bits: a solve is
        # deterministic); a tiny solve then costs no thread hand-off. A budget the caller set
        # that is smaller needs no probe.
        self._probe = None
        if math.isinf(nsteps):
            budget = max(1, _compiled.LONG_WORK // len(y0))
            if not opt.max_steps or opt.max_steps > budget:
                self._probe = replace(opt, max_steps=budget).pack()
        self._y0_list = y0.tolist()
        self._manifest = {
            **build_info(), "problem": problem, "method": method, "t0": t0, "t_end": t_end,
            **control,
            "params": {k: (v.tolist() if isinstance(v, np.ndarray) else v)
                       for k, v in merged.items()},
            "jacobian": "finite differences" if fd_jacobian else "analytic where available",
            "newton": {"rtol": opt.newton_rtol, "atol": opt.newton_atol,
                       "max_iter": opt.newton_max_iter}}

    def solve(self, y0=None) -> ODEResult:
        """One solve, from y0 (checked: n finite numbers) or the initial state given at
        construction."""
        y0 = self.y0 if y0 is None else state_vector("y0", y0, self._n)
        stats, flag = np.zeros(_STATS_WORDS), _compiled.new_flag()
        args = (self._id, y0, self.t0, self.t_end, self._pvec, self._opt, flag, self._atol,
                self._times, self._nsamp, stats)
        try:
            done = False
            if self._probe is not None:
                probe = (*args[:5], self._probe, *args[6:])
                (t, y, nw, status), interrupted = _kernel.solve_problem(*probe), False
                done = status != Status.ERR_TOO_MANY_STEPS
                if not done:
                    stats = np.zeros(_STATS_WORDS)
                    args = (*args[:-1], stats)
            if done:
                pass
            elif self._work < _compiled.LONG_WORK:      # short: in this thread (as call() would)
                (t, y, nw, status), interrupted = _kernel.solve_problem(*args), False
            else:
                (t, y, nw, status), interrupted = _compiled.call(
                    _kernel.solve_problem, args, flag, self._work, span=(self.t0, self.t_end))
        except MemoryError as exc:   # the sample arrays, allocated by the f2py layer
            raise checks.memory_error(exc, self._bytes[0], what=self._bytes[1],
                                      change=SAMPLE_ADVICE) from None
        manifest = dict(self._manifest)
        manifest["y0"] = self._y0_list if y0 is self.y0 else y0.tolist()
        return kept(_finish(t, y, stats, nw, status, manifest, self.problem, self.method,
                            dict(self.params), self.t0, y0, self._raise, None, interrupted),
                    self._keep)


#: what to change when a solve's samples do not fit in memory
SAMPLE_ADVICE = ("fewer samples: a larger every (fixed step) or dt_out (error control), or a "
                 "shorter t_end")


def sample_bytes(nsamp: int, n: int, method: str) -> tuple[float, str]:
    """(bytes, a description) of an ODE solve's sample arrays (t and y: n + 1 doubles each),
    refused with NoMemoryError before they are allocated when the machine has not that much
    memory available."""
    nbytes = 8.0 * nsamp * (n + 1)
    what = f"{method}: {nsamp} samples of {n} states"
    checks.check_memory(nbytes, what=what, change=SAMPLE_ADVICE)
    return nbytes, what


def _nonneg(name: str, value, default: float = 0.0) -> float:
    v = _real(name, default if value is None else value)
    if v < 0:
        raise InvalidInputError(f"{name} = {v} is negative; give a value >= 0")
    return v


def _count(name: str, value, upper: int) -> int:
    if isinstance(value, bool) or not isinstance(value, Integral) or not 0 <= value <= upper:
        raise InvalidInputError(f"{name} = {value!r} must be a whole number from 0 to {upper}")
    return int(value)


#: the kernel's max_steps when the options say 0 (mbdk_adaptive)
DEFAULT_MAX_STEPS = 10**8
#: the highest order each error-controlled multistep method can select
MAX_ORDER = {"bdf": 5, "cvode_bdf": 5, "cvode_adams": 12, "ida": 5}
RTOL_FLOOR = 100 * np.finfo(float).eps   # the kernel's MBDK_RTOL_FLOOR (mbdk_adaptive)


def adaptive_options(info_m, h, t0, t_end, every, rtol, atol, dt_out, h_min, h_max,
                      max_steps, max_order, fd_jacobian):
    """ODEOptions, a step estimate, the sample count and the manifest's entries of an
    error-controlled solve; every value is checked here with a message that names it."""
    method = info_m.name
    if every != 1:
        raise InvalidInputError(f"every = {every}: {method} chooses its own steps; give "
                                "dt_out (the spacing of the samples) instead")
    if isinstance(atol, (str, bytes)):
        raise InvalidInputError(f"atol = {atol!r} is neither a number nor a vector of numbers")
    rtol = _nonneg("rtol", rtol, 1e-6)
    if rtol >= 1:
        raise InvalidInputError(f"rtol = {rtol} must be below 1 (1e-6 keeps about 6 digits)")
    if 0 < rtol < RTOL_FLOOR:
        raise InvalidInputError(f"rtol = {rtol:g} asks for more digits than double precision "
                                f"holds; give rtol >= {RTOL_FLOOR:.1e} (or 0 with atol > 0)")
    scalar_atol = atol is None or np.ndim(atol) == 0
    atol_s = _real("atol", 1e-8 if atol is None else atol) if scalar_atol else 1e-8
    if not atol_s > 0:
        raise InvalidInputError(f"atol = {atol_s} must be > 0 (a state passing through 0 would "
                                "get an infinite weight; 1e-8 is the default)")
    span = t_end - t0
    h0 = 0.0 if h is None else _nonneg("h", h)
    dt_out = _nonneg("dt_out", dt_out)
    h_min = _nonneg("h_min", h_min)
    h_max = _nonneg("h_max", h_max)
    if h_max and h_min > h_max:
        raise InvalidInputError(f"h_min = {h_min} is larger than h_max = {h_max}")
    max_steps = _count("max_steps", max_steps, 2**62)
    checks.step_bounds(t0, t_end, h_max, max_steps, default_steps=DEFAULT_MAX_STEPS)
    if h_min and h_min > span:
        raise InvalidInputError(f"h_min = {h_min:g} is longer than the interval t_end - t0 = "
                                f"{span:g}: no step of the run could be that long; give a "
                                "smaller h_min (or 0: none)")
    top = MAX_ORDER.get(method, 0)
    if max_order and not top:
        raise InvalidInputError(f"max_order = {max_order}: {method} has one order "
                                f"({info_m.order}); max_order applies to {', '.join(MAX_ORDER)}")
    max_order = _count("max_order", max_order, top)
    nsamp, status = _kernel.adaptive_sample_count(t0, t_end, dt_out)
    if status < 0 or nsamp < 2:
        raise InvalidInputError(f"dt_out = {dt_out} over t_end - t0 = {span} gives no valid "
                                "sample plan")
    if nsamp > 10**8:
        raise InvalidInputError(f"dt_out = {dt_out} asks for {nsamp} samples; give a larger "
                                "dt_out")
    opt = ODEOptions(h=h0, method=info_m.id, rtol=rtol, atol=atol_s, dt_out=dt_out, h_min=h_min,
                     h_max=h_max, max_steps=max_steps, max_order=max_order,
                     fd_jacobian=int(bool(fd_jacobian)))
    control = {"rtol": rtol, "atol": atol_s if scalar_atol else np.asarray(atol).tolist(),
               "dt_out": dt_out, "h0": h0 or "automatic", "h_min": h_min, "h_max": h_max,
               "max_steps": max_steps or "10^8", "max_order": max_order or top or info_m.order}
    # an error-controlled solve's length is unknown: it runs where Ctrl-C can reach it
    return opt, math.inf, int(nsamp), control


def _atol_vector(atol, n: int, rtol: float) -> np.ndarray:
    """Empty (the scalar atol of the options) or one absolute tolerance per state."""
    if atol is None or np.ndim(atol) == 0:
        return np.zeros(0)
    try:
        a = np.array(atol, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InvalidInputError(f"atol = {atol!r} is neither a number nor a vector of numbers") \
            from None
    if a.ndim != 1 or a.size != n:
        raise InvalidInputError(f"atol has shape {a.shape}; give one number or {n} (one per "
                                "state)")
    bad = np.flatnonzero(~(np.isfinite(a) & (a > 0)))
    if bad.size:
        raise InvalidInputError(f"atol[{bad[0]}] = {a[bad[0]]} must be finite and > 0 (a state "
                                "passing through 0 would get an infinite weight)")
    return a


def state_vector(name: str, value, n: int | None) -> np.ndarray:
    try:
        y = np.array(value, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InvalidInputError(f"{name} = {checks.show(value)} is not a vector of numbers "
                                "(finite, in floating-point range)") from None
    if y.ndim > 1:
        raise InvalidInputError(f"{name} must be a flat vector, got an array of shape {y.shape}")
    y = y.ravel()
    if n is not None and y.size != n:
        raise InvalidInputError(f"{name} has {y.size} entries, the problem has {n} states")
    if y.size == 0:
        raise InvalidInputError(f"{name} is empty")
    if not np.isfinite(y).all():
        bad = np.flatnonzero(~np.isfinite(y))
        raise InvalidInputError(f"{name}[{bad[0]}] = {y[bad[0]]} is not finite")
    return y


def _finish(t, y, stats, nw, status, manifest, problem, method, params, t0, y0,
            raise_on_failure, failure_note, interrupted=False):
    code = int(status)
    status = _STATUS.get(code)
    if status is None:
        status = Status(code)
    # every field is set here, so the instance is filled directly: the generated __init__
    # costs a short solve more than its own kernel call's overhead
    result = object.__new__(ODEResult)
    result.__dict__.update(t=t[:nw], y=y[:, :nw].T, stats=Stats.from_words(stats),
                           status=status, message=status_message(status), manifest=manifest,
                           problem=problem if isinstance(problem, str) else "",
                           method=method, params=params, t0=t0, y0=y0)
    if status == Status.ERR_NO_MEMORY:
        n = 0 if y0 is None else len(y0)
        result.message = no_memory_message(
            result.stats.alloc_bytes, [(f"the Newton matrix of {method}", n,
                                        "use an explicit method")], "a smaller system")
    if status == Status.ERR_INTERRUPTED or interrupted:
        # Ctrl-C is honoured whatever raise_on_failure says; the partial result goes with it
        raise SolveInterrupted(f"{method}: interrupted at t = {result.t[-1]:.6g}" if nw else
                               f"{method}: interrupted", status=status, result=result)
    if status == Status.ERR_NONFINITE and _method(method).adaptive:
        # error control shrinks a step whose values overflow: at its floor, F itself is not
        # finite next to the state (mbdk_embedded_rk, mbdk_variable_bdf)
        failure_note = ((failure_note + "; ") if failure_note else "") + (
            "the right-hand side returned inf or NaN next to this state, which no step size "
            "avoids: a singularity of the model or of its parameters there")
    if status.failed and raise_on_failure:
        where = stopped_at(result.stats, t0)
        text = (result.message if status == Status.ERR_NO_MEMORY else
                failure_text(status, _method(method).adaptive))
        on = problem if isinstance(problem, str) else "the callback"
        msg = f"{method} on {on}: {text} ({where})"
        if failure_note:
            msg += f": {failure_note}"
        raise exception_for(status)(msg, status=status, result=result)
    return result


def _solve_callback(fun, info_m, opt, t0, t_end, y0, nq, nsamp, raise_on_failure, atol,
                    control, jac=None, times=None):
    if getattr(_IN_CALLBACK, "active", False):
        raise NotApplicableError(
            "solve_ode with a Python right-hand side was called from inside a Python right-hand "
            "side: nested callback solves are refused (f2py keeps one Python callback per "
            "solve). Use a compiled problem for the inner solve, or run it outside the callback")
    if y0 is None:
        raise InvalidInputError("a Python right-hand side needs y0")
    y0 = state_vector("y0", y0, None)
    n = y0.size
    if isinstance(nq, bool) or not isinstance(nq, Integral) or nq < 0 or (nq and 2 * nq != n):
        raise InvalidInputError(f"nq = {nq!r} must be 0 or half the state size {n}")
    if info_m.family == "euler_cromer" and nq == 0:
        raise NotApplicableError("euler_cromer needs y = [q, q']: pass nq = len(y0) // 2")
    atol_v = _atol_vector(atol, n, opt.rtol) if info_m.adaptive else np.zeros(0)
    if jac is not None:
        # its shape is checked once here, by name, before the kernel relies on it
        try:
            j0 = np.asarray(jac(t0, y0.copy()), dtype=float)
        except Exception as exc:
            raise CallbackError(f"jac(t0, y0) raised {type(exc).__name__}: {exc}") from exc
        if j0.shape != (n, n):
            raise InvalidInputError(f"jac(t0, y0) returned an array of shape {j0.shape}; the "
                                    f"Jacobian of {n} states is {n} x {n}")
    failure = []

    def cb(t, y, dydt, flag):
        try:
            out = np.asarray(fun(t, y), dtype=float)
            # numpy would broadcast one value over the state, or cut a longer one: refuse both
            if out.shape != dydt.shape:
                raise ValueError(f"the right-hand side returned an array of shape {out.shape} "
                                 f"for a state of {dydt.size} entries at t = {t:.6g}")
            # an error-controlled method rejects a step whose F is not finite and retries a
            # smaller one (its step was too large for the model); a fixed step cannot
            if not info_m.adaptive and not np.all(np.isfinite(out)):
                raise ValueError(f"the right-hand side returned non-finite values at "
                                 f"t = {t:.6g}: {out.tolist()}")
            dydt[:] = out
        except BaseException as exc:  # reported as a status; re-raised below with its cause
            flag[0] = 1
            if not failure:
                failure.append(exc)

    def cb_jac(t, y, dfdy, flag):
        try:
            out = np.asarray(jac(t, y), dtype=float)
            if out.shape != dfdy.shape:
                raise ValueError(f"jac returned an array of shape {out.shape} at t = {t:.6g}; "
                                 f"the Jacobian of {n} states is {n} x {n}")
            dfdy[:, :] = out
        except BaseException as exc:
            flag[0] = 1
            if not failure:
                failure.append(exc)

    opt = replace(opt, nq=int(nq))
    stats = empty("mbdk_stats")
    nbytes, what = sample_bytes(nsamp, n, info_m.name)
    with _CALLBACK_LOCK:
        _IN_CALLBACK.active = True
        try:
            t, y, nw, status = _kernel.solve_callback(
                cb, cb_jac, int(jac is not None), y0, t0, t_end, opt.pack(), atol_v,
                np.zeros(0) if times is None else times, nsamp, stats)
        except MemoryError as exc:   # the sample arrays, allocated by the f2py layer
            raise checks.memory_error(exc, nbytes, what=what, change=SAMPLE_ADVICE) from None
        finally:
            _IN_CALLBACK.active = False
    manifest = {**build_info(), "problem": "python callback (slow path)", "method": info_m.name,
                "t0": t0, "t_end": t_end, **control, "y0": y0.tolist(),
                "jacobian": "python jac" if jac is not None else "finite differences"}
    note = f"{type(failure[0]).__name__}: {failure[0]}" if failure else None
    try:
        return _finish(t, y, stats, nw, status, manifest, fun, info_m.name, {}, t0, y0,
                       raise_on_failure, note,
                       bool(failure) and isinstance(failure[0], KeyboardInterrupt))
    except CallbackError as exc:
        raise exc from (failure[0] if failure else None)


def evaluate_rhs(problem: str, t: float, y, params: dict | None = None) -> np.ndarray:
    """One evaluation of F(t, y) of a compiled problem, e.g. the accelerations of a worked step."""
    info = _problem(problem)
    y = state_vector("y", y, info.n if info.n > 0 else None)
    _merged, pvec = resolve_params(info, params, len(y))
    f, status = _kernel.eval_problem(info.id, pvec, _real("t", t), y)
    if status < 0:
        raise exception_for(Status(status))(f"evaluating {problem}: {status_message(status)}")
    return np.array(f)
