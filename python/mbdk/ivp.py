"""solve_ivp: SciPy's front (scipy.integrate.solve_ivp's arguments and result) over mbdk's
compiled integrators, for a user who has SciPy code to port or compare.

>>> import mbdk
>>> sol = mbdk.solve_ivp(lambda t, y: -0.5 * y, [0, 10], [2, 4, 8], t_eval=[0, 5, 10])
>>> sol.y.shape                       # (states, points), as SciPy's
(3, 3)

fun is ``f(t, y, *args)`` (the slow path: Python is called at every evaluation) or the name of a
compiled problem (mbdk.problems(); then the whole solve stays in Fortran). method: SciPy's
names map onto mbdk's pairs and formulas, RK45 -> dopri54 (the same Dormand-Prince pair),
RK23 -> bs32 (Bogacki-Shampine), BDF -> bdf (mbdk's variable-order BDF), LSODA ->
cvode_bdf (SUNDIALS' BDF, without LSODA's switch to Adams); any error-controlled mbdk method
by its own name too (cvode_adams, ...), and a fixed-step one (rk4, bdf3, ...) with the step
given as first_step (its samples are then its steps). Radau and DOP853 have no counterpart
here: NotApplicableError names the nearest.

What differs from SciPy, and why:

- the kernel returns the states at the times asked for, not at its own steps: with t_eval
  None, t holds one evenly spaced point per step the method took over t_span (a second run
  samples them from the method's dense output), not the step points themselves;
- sol (dense_output=True) evaluates by running the solve again with samples at the times
  asked for: the same steps (the solve is deterministic) and the method's own continuous
  extension, so sol(t) equals what t_eval=t gives; each call is one run (microseconds for a
  compiled problem, the Python evaluations again for a callable);
- events are located on that dense output: sign changes of each event function on a grid of
  four points per step, each refined to the root by repeated subdivision of its cell (a
  root that enters and leaves within a quarter step is missed, as SciPy misses one within a
  step); terminal events end the result there (status 1), as SciPy's do;
- a failed solve (a blow-up, a step size too small) returns status -1 with the kernel's
  message and the samples up to where it stopped, as SciPy does; it does not raise.

Backward integration (t_span decreasing) runs s = -t forwards: callables only (a compiled
problem's right-hand side cannot be turned around from here).
"""
from __future__ import annotations

import math

import numpy as np

from . import checks
from .errors import InvalidInputError, NotApplicableError, MbdkError
from .methods import method as method_info
from .ode import solve_ode

#: SciPy's method names and mbdk's counterparts (None: none)
SCIPY_METHODS = {"RK45": "dopri54", "RK23": "bs32", "BDF": "bdf", "LSODA": "cvode_bdf",
                 "Radau": None, "DOP853": None}
#: what to use instead of the SciPy methods mbdk has no counterpart of
NEAREST = {"Radau": "bdf or cvode_bdf (stiff problems)", "DOP853": "dopri54 at a tighter rtol"}
#: grid points per step on which event functions are tried for sign changes
EVENT_GRID = 4
#: subdivisions of an event's cell per refinement round, and the rounds
EVENT_SPLIT, EVENT_ROUNDS = 64, 7


class OdeResult(dict):
    """SciPy's result object: its fields as keys and attributes (t, y, sol, t_events,
    y_events, nfev, njev, nlu, status, message, success), and mbdk's stats and manifest."""

    def __getattr__(self, name):
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None


class DenseSolution:
    """sol(t): the solution at t (a number: shape (n,); an array: (n, len(t))), from the
    method's dense output by a run with samples there (module docstring)."""

    def __init__(self, run, t_min: float, t_max: float, sign: float):
        self._run, self.t_min, self.t_max, self._sign = run, t_min, t_max, sign

    def __call__(self, t):
        t = np.asarray(t, dtype=float)
        flat = np.atleast_1d(t).ravel()
        if flat.size and (flat.min() < self.t_min - 1e-12 * abs(self.t_min) or
                          flat.max() > self.t_max + 1e-12 * abs(self.t_max)):
            raise InvalidInputError(f"sol(t): t must lie within [{self.t_min:g}, "
                                    f"{self.t_max:g}], where the solution was computed")
        # in run time s = sign t, kept within the run (a t on its end to roundoff)
        lo, hi = sorted((self._sign * self.t_min, self._sign * self.t_max))
        s = np.clip(self._sign * flat, lo, hi)
        order = np.argsort(s)
        ys = self._values(s[order])
        out = np.empty((ys.shape[0], flat.size))
        out[:, order] = ys
        return out[:, 0] if t.ndim == 0 else out

    def _values(self, s):
        """(n, len(s)) at the sorted run times s (duplicates allowed)."""
        uniq, inverse = np.unique(s, return_inverse=True)
        r = self._run(uniq)
        if len(r.t) < len(uniq):
            raise InvalidInputError("sol(t): the solve stopped before some of these times")
        return r.y.T[:, inverse]


def solve_ivp(fun, t_span, y0, method: str = "RK45", t_eval=None, dense_output: bool = False,
              events=None, vectorized: bool = False, args=None, first_step=None,
              max_step=math.inf, min_step: float = 0.0, rtol: float = 1e-3, atol=1e-6,
              jac=None, **options) -> OdeResult:
    """scipy.integrate.solve_ivp's call on mbdk's kernel (the module docstring says what
    differs). options: mbdk's own solve_ode options (params of a compiled problem, max_order,
    max_steps, ...). vectorized is accepted and changes nothing: the kernel evaluates fun one
    state at a time."""
    t0, tf = _span(t_span)
    sign = 1.0 if tf > t0 else -1.0
    name = _method_name(method)
    info = method_info(name)
    if callable(fun):
        call = _wrapped(fun, args, sign)
    else:
        if args is not None:
            raise InvalidInputError("args go with a Python fun; a compiled problem takes its "
                                    "parameters as params={...}")
        if sign < 0:
            raise NotApplicableError(f"t_span {t_span!r} runs backwards: a compiled problem's "
                                     "right-hand side cannot be turned around; give a Python "
                                     "fun")
        call = fun
    if jac is not None and callable(fun):
        # the Jacobian of the run's f in s = sign t: sign J(sign s, y)
        j, extra = jac, tuple(args or ())
        jac = lambda s, y: sign * np.asarray(j(sign * s, y, *extra), dtype=float)  # noqa: E731
    kw = dict(options)
    if y0 is not None or callable(fun):
        kw["y0"] = y0
    if info.adaptive:
        kw.update(rtol=rtol, atol=atol, h_min=min_step,
                  h_max=0.0 if math.isinf(max_step) else float(max_step))
        if first_step is not None:
            kw["h"] = float(first_step)
    else:
        if first_step is None:
            raise InvalidInputError(f"{name} takes a fixed step: give first_step (its h)")
        kw["h"] = float(first_step)
        if t_eval is not None or dense_output or events:
            raise NotApplicableError(f"{name} takes a fixed step and samples every step: "
                                     "t_eval, dense_output and events need an "
                                     "error-controlled method (RK45, RK23, BDF, ...)")
    s0, s1 = sign * t0, sign * tf
    if jac is not None:
        kw["jac"] = jac

    def run(times=None):
        extra = {} if times is None else {"t_eval": times}
        return solve_ode(call, name, t0=s0, t_end=s1, raise_on_failure=False, **kw, **extra)

    main = run()
    # a failed solve ends after its last accepted step; one that failed in its first step has
    # only y0 to give (status -1 with that sample, as SciPy's)
    reached = (main.t[-1] if len(main.t) else s0) if main.success else main.stats.t_reached
    if reached == s0:
        y0v = np.atleast_1d(np.asarray(y0, dtype=float))
        st = main.stats
        return OdeResult(t=np.array([t0]), y=y0v.reshape(-1, 1), sol=None,
                         t_events=None if events is None else
                         [np.zeros(0) for _ in ([events] if callable(events) else events)],
                         y_events=None if events is None else
                         [np.zeros((0, y0v.size)) for _ in
                          ([events] if callable(events) else events)],
                         nfev=st.nfev, njev=st.njev, nlu=st.nlu, status=-1,
                         message=main.message, success=False, stats=st,
                         manifest={**main.manifest, "scipy_method": method})
    if info.adaptive:
        grid = np.linspace(s0, reached, max(main.stats.steps, 1) + 1)
        sampled = run(grid)
    else:
        sampled = main
    sol = DenseSolution(lambda s: run(s), min(t0, sign * reached), max(t0, sign * reached),
                        sign) if info.adaptive else None
    status, message = ((0, "The solver successfully reached the end of the integration "
                        "interval.") if main.success else (-1, main.message))
    ts, ys = sampled.t, sampled.y
    t_events = y_events = None
    if events is not None:
        evs = [events] if callable(events) else list(events)
        found = locate_events(evs, args, sign, run, s0, reached, max(main.stats.steps, 1))
        t_events = [np.array([sign * s for s, _ in f]) for f in found]
        y_events = [np.array([y for _, y in f]).reshape(-1, len(ys[0]) if len(ys) else 0)
                    for f in found]
        stop = terminal_stop(evs, found)
        if stop is not None:
            s_stop, y_stop = stop
            # the integration ends there, as SciPy's: no event after it
            found = [[(s, y) for s, y in f if s <= s_stop] for f in found]
            t_events = [np.array([sign * s for s, _ in f]) for f in found]
            y_events = [np.array([y for _, y in f]).reshape(-1, len(y_stop)) for f in found]
            keep = ts < s_stop
            ts, ys = np.append(ts[keep], s_stop), np.vstack([ys[keep], y_stop])
            status, message = 1, "A termination event occurred."
            sol = DenseSolution(lambda s: run(s), min(t0, sign * s_stop),
                                max(t0, sign * s_stop), sign)
    if t_eval is not None:
        # SciPy's t_eval runs in the direction of the integration: increasing in s
        req = sign * np.asarray(t_eval, dtype=float)
        if req.ndim != 1 or np.any(np.diff(req) <= 0):
            raise InvalidInputError("t_eval must be a list of times in the direction of t_span")
        if req.size and (req[0] < s0 or req[-1] > s1):
            raise InvalidInputError(f"t_eval must lie within t_span {tuple(t_span)}")
        req = req[req <= ts[-1]] if len(ts) else req[:0]   # up to where the run ended
        ys = run(req).y if req.size else np.zeros((0, len(ys[0]) if len(ys) else 0))
        ts = req[:len(ys)]
    st = main.stats
    return OdeResult(t=sign * np.asarray(ts), y=np.asarray(ys).T, sol=sol if dense_output else None,
                     t_events=t_events, y_events=y_events, nfev=st.nfev, njev=st.njev,
                     nlu=st.nlu, status=status, message=message, success=status >= 0,
                     stats=st, manifest={**main.manifest, "scipy_method": method})


def _span(t_span):
    try:
        t0, tf = (float(x) for x in t_span)
    except (TypeError, ValueError):
        raise InvalidInputError(f"t_span = {checks.show(t_span)} must be two numbers "
                                "(t0, tf)") from None
    if not (math.isfinite(t0) and math.isfinite(tf)) or t0 == tf:
        raise InvalidInputError(f"t_span = ({t0}, {tf}) must be two different finite times")
    return t0, tf


def _method_name(method) -> str:
    if isinstance(method, str) and method in SCIPY_METHODS:
        name = SCIPY_METHODS[method]
        if name is None:
            raise NotApplicableError(f"method {method!r}: mbdk has no counterpart; use "
                                     f"{NEAREST[method]}")
        return name
    try:
        info = method_info(method)
    except MbdkError:
        raise InvalidInputError(f"method {checks.show(method)}: one of SciPy's "
                                f"{', '.join(SCIPY_METHODS)} or an mbdk ODE method") from None
    if info.solves != "ode":
        raise NotApplicableError(f"method {method!r} integrates a scene's DAE: "
                                 "mbdk.simulate runs it")
    return info.name


def _wrapped(fun, args, sign: float):
    """f(s, y) of the run in s = sign t: sign f(sign s, y, *args)."""
    extra = tuple(args) if args is not None else ()
    if args is not None and not isinstance(args, tuple):
        raise InvalidInputError(f"args = {checks.show(args)} must be a tuple")
    if sign > 0:
        return (lambda s, y: fun(s, y, *extra)) if extra else fun
    return lambda s, y: -np.asarray(fun(-s, y, *extra), dtype=float)


def locate_events(evs, args, sign, run, s0, s1, steps):
    """Per event function, the (s, y) of its roots over [s0, s1] in run time s, in order, each
    on its direction (module docstring)."""
    extra = tuple(args) if args is not None else ()
    grid = np.linspace(s0, s1, EVENT_GRID * steps + 1)
    r = run(grid)
    g_all = [np.array([float(ev(sign * s, y, *extra)) for s, y in zip(r.t, r.y)])
             for ev in evs]
    found = []
    for ev, g in zip(evs, g_all):
        # SciPy's direction is that of g along the integration (rising as it runs, whichever
        # way t goes), and g is sampled here in the run's order: no sign to apply
        direction = float(getattr(ev, "direction", 0.0))
        roots = []
        for k in range(len(g) - 1):
            a, b = g[k], g[k + 1]
            if not (a * b < 0 or (b == 0 and a != 0)):
                continue
            rising = b > a
            if direction > 0 and not rising or direction < 0 and rising:
                continue
            roots.append(_refine(ev, extra, sign, run, r.t[k], r.t[k + 1], a, b))
        found.append(roots)
    return found


def _refine(ev, extra, sign, run, lo, hi, g_lo, g_hi):
    """The root of ev in [lo, hi] (a sign change from g_lo to g_hi): the cell split
    EVENT_SPLIT-fold for up to EVENT_ROUNDS rounds, then the secant of the last cell; (s, y)
    there."""
    for _ in range(EVENT_ROUNDS):
        if hi - lo <= 4 * np.spacing(max(abs(lo), abs(hi), 1.0)):
            break
        pts = np.linspace(lo, hi, EVENT_SPLIT + 1)
        r = run(pts)
        if len(r.t) < len(pts):
            break
        g = np.array([float(ev(sign * t, y, *extra)) for t, y in zip(r.t, r.y)])
        change = np.nonzero((g[:-1] * g[1:] < 0) | ((g[1:] == 0) & (g[:-1] != 0)))[0]
        if not change.size:
            break
        k = int(change[0])
        lo, hi, g_lo, g_hi = pts[k], pts[k + 1], g[k], g[k + 1]
    s = hi if g_hi == 0 else lo - g_lo * (hi - lo) / (g_hi - g_lo)
    at = run(np.array([s]))
    if not len(at.y):
        raise MbdkError(f"event search: the solve, run again, failed before t = "
                          f"{sign * s:.17g}, which the first run passed ({at.message})")
    return s, at.y[0]


def terminal_stop(evs, found):
    """(s, y) of the first root of a terminal event function (terminal True, or a count of
    roots to pass), or None."""
    stops = []
    for ev, roots in zip(evs, found):
        term = getattr(ev, "terminal", False)
        count = 1 if term is True else int(term) if term else 0
        if count and len(roots) >= count:
            stops.append(roots[count - 1])
    return min(stops, key=lambda p: p[0]) if stops else None
