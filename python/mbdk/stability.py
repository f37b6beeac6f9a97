"""Stability regions, computed from the kernel's own stepping code.

Every number here comes from step matrices measured by the kernel
(kernel/src/analysis/mbdk_step_matrix.f90): the method's own step routine, run on y' = A y
from unit vectors. There is no second copy of any method's formula in Python, so a change to a
Butcher table, a multistep coefficient or a step routine changes the regions.

Definitions used throughout (z = h*lambda):

- One-step methods (explicit_euler, heun, rk4, implicit_euler, trapezoidal, bdf1): the test
  equation y' = lambda*y as the real 2 x 2 system A = [[Re, -Im], [Im, Re]]. The step matrix is
  [[Re R, -Im R], [Im R, Re R]], which gives the amplification factor R(z) itself.
- k-step methods (bdf2..bdf6): the same 2 x 2 system on the stacked history
  [y_n; ...; y_{n-k+1}]; the step matrix is the (2k x 2k) companion matrix, whose spectral radius
  is the largest root modulus of rho(zeta) - z*sigma(zeta).
- euler_cromer assumes y = [q; v] with q' = v, so it is defined on second-order systems only.
  Its region is that of the oscillator q'' - 2 Re(lambda) q' + |lambda|^2 q = 0, whose
  characteristic roots are lambda and conj(lambda); for the other methods that definition gives
  the same spectral radius as the first one (tests/test_stability.py checks it), so the regions
  are comparable. On the negative real axis it means the critically damped oscillator.

A point is stable when the spectral radius is at most 1 + STABLE_TOL.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from . import _kernel, checks
from .checks import show
from .errors import InvalidInputError, NotApplicableError, Status, exception_for
from .methods import method as _any_method
from .ode import evaluate_rhs, solve_ode, state_vector
from .problems import problem as _problem

STABLE_TOL = 1e-9
#: Newton tolerances for the implicit steps; the problems are linear with the exact Jacobian,
#: so one iteration solves them to rounding and the second only confirms it.
NEWTON_RTOL, NEWTON_ATOL = 1e-12, 1e-14
_CHUNK = 20000


def _method(method: str):
    """The method's registry entry; a method with no step on y' = A y (trapezoidal_index3
    integrates a scene's DAE) has no stability region here: a named error."""
    info = _any_method(method)
    if info.solves != "ode":
        raise NotApplicableError(f"{method} integrates a scene's index-3 DAE and has no step on "
                                 "y' = A y; its stability in the constrained directions is "
                                 "studied on scenes (studies/index3.py)")
    return info


def _array(name: str, value, dtype=float, *, positive: bool = False) -> np.ndarray:
    """An array argument of numbers (dtype float or complex), finite (and > 0 if positive),
    or a named error."""
    try:
        a = np.asarray(value, dtype=dtype)
    except (TypeError, ValueError, OverflowError):
        a = None
    if a is None or (a.dtype == object):
        raise InvalidInputError(f"{name} = {show(value)} is not an array of numbers")
    if a.size == 0:
        raise InvalidInputError(f"{name} is empty; give at least one value")
    bad = np.flatnonzero(~np.isfinite(a).ravel() | ((a.ravel().real <= 0) if positive else False))
    if bad.size:
        raise InvalidInputError(f"{name}: entry {bad[0]} = {a.ravel()[bad[0]]} must be "
                                f"{'positive and ' if positive else ''}finite")
    return a


def _positive(name: str, value) -> float:
    return checks.real(name, value, positive=True)


def history_length(method: str) -> int:
    """Past states one step reads: k for bdfk (k >= 2), 1 for one-step methods."""
    return int(_kernel.step_history_length(_method(method).id))


def step_matrices(method: str, a, h) -> np.ndarray:
    """Step matrices of `method` on y' = A y: a has shape (n, n) or (npts, n, n), h is a scalar
    or has npts entries. Returns (npts, n*k, n*k) (or (n*k, n*k) for a single A).

    Where I - h*beta0*A is singular the amplification factor has a pole: those matrices are
    returned as inf. Any other kernel failure raises its named exception."""
    info = _method(method)
    try:
        a = np.asarray(a, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InvalidInputError(f"A = {show(a)} is not a square matrix of numbers") from None
    single = a.ndim == 2
    if single:
        a = a[None]
    if a.ndim != 3 or a.shape[1] != a.shape[2] or a.shape[1] < 1:
        raise InvalidInputError(f"A must be square, (n, n) or (npts, n, n); got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise InvalidInputError("A has entries that are not finite")
    npts, n = a.shape[0], a.shape[1]
    try:
        h = np.broadcast_to(np.asarray(h, dtype=float), (npts,))
    except (TypeError, ValueError, OverflowError):
        raise InvalidInputError(f"h = {show(h)} must be a step (a number) or one step per "
                                f"matrix ({npts})") from None
    bad = np.flatnonzero(~(np.isfinite(h) & (h > 0)))
    if bad.size:
        raise InvalidInputError(f"h[{bad[0]}] = {h[bad[0]]} must be positive and finite")
    if info.family == "euler_cromer" and n % 2:
        raise NotApplicableError(f"euler_cromer needs y = [q; v] (an even state size); A is {n} x {n}")
    nk = n * history_length(method)
    out = np.empty((npts, nk, nk))
    for s in range(0, npts, _CHUNK):
        e = min(npts, s + _CHUNK)
        m, status = _kernel.step_matrices(info.id, nk, np.asfortranarray(a[s:e].transpose(1, 2, 0)),
                                          np.ascontiguousarray(h[s:e]), NEWTON_RTOL, NEWTON_ATOL)
        m = m.transpose(2, 0, 1)
        pole = status == Status.ERR_SINGULAR_MATRIX
        m[pole] = np.inf
        other = np.flatnonzero((status != Status.SUCCESS) & ~pole)
        if other.size:
            p = s + other[0]
            code = Status(int(status[other[0]]))
            raise exception_for(code)(
                f"step matrix of {method} at point {p} (h = {h[p]}, A = {a[p].tolist()}): "
                f"kernel status {code.name}")
        out[s:e] = m
    return out[0] if single else out


def _realified(z: np.ndarray) -> np.ndarray:
    a = np.empty(z.shape + (2, 2))
    a[..., 0, 0] = a[..., 1, 1] = z.real
    a[..., 0, 1] = -z.imag
    a[..., 1, 0] = z.imag
    return a


def oscillator_matrix(omega, zeta) -> np.ndarray:
    """A = [[0, 1], [-omega^2, -2 zeta omega]] for q'' + 2 zeta omega q' + omega^2 q = 0."""
    omega, zeta = np.broadcast_arrays(np.asarray(omega, float), np.asarray(zeta, float))
    a = np.zeros(omega.shape + (2, 2))
    a[..., 0, 1] = 1.0
    a[..., 1, 0] = -omega ** 2
    a[..., 1, 1] = -2.0 * zeta * omega
    return a


def _test_matrices(method: str, z: np.ndarray) -> np.ndarray:
    if _method(method).family == "euler_cromer":
        a = np.zeros(z.shape + (2, 2))
        a[..., 0, 1] = 1.0
        a[..., 1, 0] = -np.abs(z) ** 2
        a[..., 1, 1] = 2.0 * z.real
        return a
    return _realified(z)


def spectral_radius(method: str, z) -> np.ndarray:
    """Spectral radius of the step matrix at z = h*lambda (array-like, complex)."""
    z = _array("z", z, complex)
    m = step_matrices(method, _test_matrices(method, z.ravel()).reshape(-1, 2, 2), 1.0)
    return _radius(m).reshape(z.shape)


def _radius(m: np.ndarray) -> np.ndarray:
    finite = np.all(np.isfinite(m), axis=(1, 2))
    r = np.full(m.shape[0], np.inf)
    if finite.any():
        r[finite] = np.abs(np.linalg.eigvals(m[finite])).max(axis=1)
    return r


def amplification_factor(method: str, z) -> np.ndarray:
    """R(z) of a one-step method for y' = lambda*y, read off the kernel's step matrix."""
    info = _method(method)
    if info.family == "euler_cromer" or history_length(method) != 1:
        raise NotApplicableError(
            f"{method} has no scalar amplification factor: "
            + ("it is defined on second-order systems only" if info.family == "euler_cromer"
               else "it is a multistep method") + "; use spectral_radius()")
    z = _array("z", z, complex)
    m = step_matrices(method, _realified(z.ravel()).reshape(-1, 2, 2), 1.0)
    return (m[:, 0, 0] + 1j * m[:, 1, 0]).reshape(z.shape)


def _first_crossing(f, lo: float, hi: float, iters: int = 80) -> float:
    """Bisection between lo (f <= 0) and hi (f > 0)."""
    for _ in range(iters):
        mid = 0.5 * (lo + hi)
        if f(mid) > 0:
            hi = mid
        else:
            lo = mid
        if abs(hi - lo) <= 1e-15 * max(abs(lo), abs(hi)):
            break
    return lo


def real_interval(method: str, reach: float = 1e8) -> tuple[float, float]:
    """(a, 0): the stability interval on the negative real axis that contains 0-, to about 13
    digits; a = -inf when the whole axis up to -reach is stable."""
    _method(method)
    reach = _positive("reach", reach)
    if reach <= 1e-6:
        raise InvalidInputError(f"reach = {reach:g} must exceed 1e-6 (the search starts there)")
    x = -np.logspace(-6, math.log10(reach), 1401)
    r = spectral_radius(method, x)
    bad = np.flatnonzero(r > 1 + STABLE_TOL)
    if bad.size == 0:
        return (-math.inf, 0.0)
    i = bad[0]
    if i == 0:
        return (0.0, 0.0)
    # bisect on |x| between the last stable and the first unstable grid point
    # (the crossing of rho = 1 itself: rho is transversal there, and STABLE_TOL would bias a)
    mag = _first_crossing(lambda s: spectral_radius(method, [-s])[0] - 1 - 1e-14,
                          -x[i - 1], -x[i])
    return (-mag, 0.0)


def _ray_excess(method: str, psi: float, rs: np.ndarray) -> float:
    """max over the ray z = r*exp(i(pi - psi)) of spectral radius - 1, refined around the
    maximum of the grid rs (log-spaced)."""
    d = np.exp(1j * (math.pi - psi))
    r = spectral_radius(method, rs * d)
    for _ in range(3):
        i = int(np.argmax(r))
        lo, hi = rs[max(i - 1, 0)], rs[min(i + 1, len(rs) - 1)]
        rs = np.geomspace(lo, hi, 101)
        r = spectral_radius(method, rs * d)
    return float(r.max()) - 1.0


def a_alpha(method: str, r_min: float = 1e-4, r_max: float = 1e4) -> float:
    """The A(alpha) angle in degrees: the largest alpha such that the sector |arg(-z)| < alpha
    is stable (90 = A-stable). Found by bisection on the ray angle; each ray is searched for its
    most unstable point on a log grid from r_min to r_max with three refinements."""
    _method(method)
    r_min, r_max = _positive("r_min", r_min), _positive("r_max", r_max)
    if not r_min < r_max:
        raise InvalidInputError(f"r_min = {r_min:g} must be below r_max = {r_max:g}")
    rs = np.geomspace(r_min, r_max, 801)
    if _ray_excess(method, 0.0, rs) > STABLE_TOL:
        return 0.0
    if _ray_excess(method, math.pi / 2, rs) <= STABLE_TOL:
        return 90.0
    lo, hi = 0.0, math.pi / 2
    while hi - lo > 1e-10:   # bisect on the crossing itself (STABLE_TOL would bias the angle)
        mid = 0.5 * (lo + hi)
        if _ray_excess(method, mid, rs) > 1e-13:
            hi = mid
        else:
            lo = mid
    return math.degrees(lo)


@dataclass
class StabilityRegion:
    """The stability region of one method, computed from the kernel.

    x, y: the grid axes (Re z, Im z); rho[j, i]: spectral radius at x[i] + 1j*y[j];
    boundary: the curves rho = 1 inside the window, as complex arrays;
    real_interval: (a, 0), the stable part of the negative real axis containing 0-;
    a_stable / alpha_deg: for implicit methods, A-stability and the A(alpha) angle (degrees);
    definition: which test system the region refers to (see the module docstring)."""

    method: str
    x: np.ndarray
    y: np.ndarray
    rho: np.ndarray = field(repr=False)
    boundary: list = field(repr=False)
    real_interval: tuple
    a_stable: bool | None
    alpha_deg: float | None
    definition: str
    cpu_time: float

    @property
    def stable(self) -> np.ndarray:
        return self.rho <= 1 + STABLE_TOL


def default_window(method: str) -> tuple[tuple[float, float], tuple[float, float]]:
    info = _method(method)
    if history_length(method) >= 5:         # bdf5, bdf6: larger unstable regions
        return (-12.0, 36.0), (-26.0, 26.0)
    if info.implicit:
        return (-8.0, 16.0), (-12.0, 12.0)
    return (-4.5, 1.5), (-3.5, 3.5)


def stability_region(method: str, re: tuple[float, float] | None = None,
                     im: tuple[float, float] | None = None, n: int = 301) -> StabilityRegion:
    """The stability region of `method` on an n x n grid of z = h*lambda, with its boundary,
    its real-axis interval and, for implicit methods, the A(alpha) angle."""
    info = _method(method)
    wre, wim = default_window(method)
    re = wre if re is None else _window("re", re)
    im = wim if im is None else _window("im", im)
    if isinstance(n, bool) or not isinstance(n, int) or not 3 <= n <= 4001:
        raise InvalidInputError(f"n = {show(n)} must be a whole number from 3 to 4001")
    t0 = time.process_time()
    x = np.linspace(re[0], re[1], n)
    y = np.linspace(im[0], im[1], n)
    z = x[None, :] + 1j * y[:, None]
    rho = spectral_radius(method, z)
    boundary = _level_curves(x, y, rho, 1.0)
    interval = real_interval(method)
    a_st, alpha = None, None
    if info.implicit:
        alpha = a_alpha(method)
        a_st = alpha >= 90.0
    definition = ("oscillator q'' - 2 Re(z) q' + |z|^2 q = 0 (roots z, conj z)"
                  if info.family == "euler_cromer" else
                  "y' = lambda y as a 2 x 2 real system" + (
                      f", companion form of the {history_length(method)}-step history"
                      if history_length(method) > 1 else ""))
    return StabilityRegion(method, x, y, rho, boundary, interval, a_st, alpha, definition,
                           time.process_time() - t0)


def _window(name: str, w) -> tuple[float, float]:
    """A window side (lo, hi): two finite numbers, lo < hi, or a named error."""
    if isinstance(w, (str, bytes, dict)) or not hasattr(w, "__len__") or len(w) != 2:
        raise InvalidInputError(f"{name} = {show(w)} must be a pair (lo, hi) of finite numbers, "
                                "lo < hi")
    lo, hi = (checks.real(f"{name}[{i}]", x) for i, x in enumerate(w))
    if not lo < hi:
        raise InvalidInputError(f"{name} = {show(w)} must be a pair (lo, hi) of finite numbers, "
                                "lo < hi")
    return lo, hi


def _level_curves(x, y, values, level):
    # contourpy comes with matplotlib, an optional dependency: only the regions' curves need it
    import contourpy
    v = np.where(np.isfinite(values), values, 1e300)
    lines = contourpy.contour_generator(x, y, v).lines(level)
    return [seg[:, 0] + 1j * seg[:, 1] for seg in lines if len(seg) > 1]


# ---------------------------------------------------------------------------------------------
# The second-order view: q'' + 2 zeta omega q' + omega^2 q = 0


@dataclass
class OscillatorResponse:
    """Per step ratio h/T (T = 2 pi/omega, the undamped period) at one zeta:
    spectral_radius (all roots), principal (the root that approximates exp(h lambda)),
    damping_ratio (of the discrete motion, from log(principal)/h), numerical_damping
    (damping_ratio - zeta), period_error (discrete damped period / exact - 1; NaN where the
    principal root is real or h exceeds half a period, so no period can be read)."""

    method: str
    zeta: float
    h_over_T: np.ndarray
    spectral_radius: np.ndarray
    principal: np.ndarray
    damping_ratio: np.ndarray
    numerical_damping: np.ndarray
    period_error: np.ndarray


def oscillator_response(method: str, h_over_T, zeta: float = 0.0) -> OscillatorResponse:
    """Spectral radius, numerical damping and period error of `method` on the damped oscillator
    (omega = 1), from the kernel's step matrices."""
    zeta = checks.real("zeta", zeta)
    if not 0 <= zeta < 1:
        raise InvalidInputError(f"zeta = {zeta} must be in [0, 1) (an oscillating system)")
    hT = np.atleast_1d(_array("h_over_T", h_over_T, positive=True))
    h = 2 * math.pi * hT
    m = step_matrices(method, oscillator_matrix(np.ones_like(h), zeta), h)
    lam = complex(-zeta, math.sqrt(1 - zeta ** 2))
    rad = np.full(h.size, np.inf)
    princ = np.full(h.size, np.nan + 0j)
    for i in range(h.size):
        if not np.all(np.isfinite(m[i])):
            continue
        ev = np.linalg.eigvals(m[i])
        rad[i] = np.abs(ev).max()
        target = np.exp(h[i] * lam)
        princ[i] = ev[np.argmin(np.abs(ev - target))]
    with np.errstate(divide="ignore", invalid="ignore"):
        lam_h = np.log(princ) / h
        ratio = -lam_h.real / np.abs(lam_h)
        wd = np.abs(lam_h.imag)
        period = np.where((wd > 0) & (np.abs(np.angle(princ)) < math.pi * (1 - 1e-12)),
                          math.sqrt(1 - zeta ** 2) / wd - 1, np.nan)
    return OscillatorResponse(method, zeta, hT, rad, princ, ratio, ratio - zeta, period)


def oscillator_map(method: str, h_omega, zeta) -> np.ndarray:
    """Spectral radius on the grid (zeta[j], h_omega[i]) of the damped oscillator."""
    hw, zz = np.meshgrid(_array("h_omega", h_omega, positive=True), _array("zeta", zeta))
    m = step_matrices(method, oscillator_matrix(np.ones(hw.size), zz.ravel()), hw.ravel())
    return _radius(m).reshape(hw.shape)


def oscillator_limit(method: str, zeta: float = 0.0, reach: float = 1e4) -> float:
    """Largest h*omega with spectral radius <= 1 on the oscillator at damping zeta (inf when
    stable up to `reach`). 0.0 when the method is unstable for every h > 0: a weak instability
    (rho - 1 = O((h omega)^(p+1)), heun on the undamped oscillator) hides below STABLE_TOL at
    small h, so a limit is only accepted if rho <= 1 + 1e-13 at half of it."""
    _method(method)
    zeta = checks.real("zeta", zeta)
    reach = _positive("reach", reach)
    if reach <= 1e-4:
        raise InvalidInputError(f"reach = {reach:g} must exceed 1e-4 (the search starts there)")
    hw = np.logspace(-4, math.log10(reach), 1201)
    r = oscillator_map(method, hw, [zeta])[0]
    bad = np.flatnonzero(r > 1 + STABLE_TOL)
    if bad.size == 0:
        return math.inf
    if bad[0] == 0:
        return 0.0
    lim = _first_crossing(lambda s: oscillator_map(method, [s], [zeta])[0, 0] - 1 - STABLE_TOL,
                          hw[bad[0] - 1], hw[bad[0]])
    below = oscillator_map(method, np.linspace(0.05, 0.5, 10) * lim, [zeta])[0]
    return 0.0 if np.any(below > 1 + 1e-13) else lim


# ---------------------------------------------------------------------------------------------
# Stability in practice: the largest step on the real nonlinear model against the prediction


@dataclass
class StepLimit:
    """The largest step `method` tolerates on `problem` over t_span, found by bisection on runs
    of the compiled model, with the step that failed and why.

    h: the largest step found stable (a run of ceil(t_span/h) steps stays finite, Newton
    converges, and every component stays within growth x its reference amplitude, the max |y_i|
    of an accurate rk4 run (h = 1e-3) over the first min(t_span, 20) s); h_fail: the smallest step found unstable
    (None when h reached h_cap); reason: how h_fail failed; solves/cpu_time: the runs the
    search made and their kernel CPU time."""

    problem: str
    method: str
    t_span: float
    growth: float
    h: float
    h_fail: float | None
    reason: str
    solves: int
    cpu_time: float


def _reference_scale(problem, params, y0, t_span):
    """Per-component amplitude of the motion: max |y_i| of an rk4 run with h = 1e-3 over
    min(t_span, 20) s (every state component, so that angles and rates are each compared with
    their own size)."""
    t = min(t_span, 20.0)
    r = solve_ode(problem, "rk4", h=1e-3, t_end=t, every=10, params=params, y0=y0)
    scale = np.abs(r.y).max(axis=0)
    return np.maximum(scale, 1e-6 * scale.max())


def _run_is_stable(problem, method, h, t_span, growth, params, y0, scale):
    n = max(1, math.ceil(t_span / h - 1e-9))
    every = max(1, n // 4000)
    r = solve_ode(problem, method, h=h, t_end=n * h, every=every, params=params, y0=y0,
                  raise_on_failure=False)
    cpu = r.cpu_time
    if r.status.failed:
        return False, r.status.name.removeprefix("ERR_").lower(), cpu
    ratio = np.abs(r.y).max(axis=0) / scale
    i = int(np.argmax(ratio))
    if ratio[i] > growth:
        name = _problem(problem).states[i]
        return False, f"growth: max abs({name}) = {ratio[i]:.3g} x its reference amplitude", cpu
    return True, "", cpu


def largest_stable_step(problem: str, method: str, *, t_span: float = 100.0,
                        growth: float = 10.0, h_cap: float = 1.0, rtol: float = 1e-3,
                        h_start: float = 1e-3, params: dict | None = None,
                        y0=None) -> StepLimit:
    """The largest h below which every step tried is stable: doubles h from h_start (halving
    first if h_start itself fails) up to the first failure, then bisects geometrically between
    the last stable and the first unstable step until they differ by less than rtol.

    Scanning upwards matters: stability regions need not be connected along a ray (bdf4 on the
    damped oscillator is unstable at h = 0.3 and stable again at h = 1), and a step that only
    works beyond an unstable band is no step a user can rely on."""
    _method(method)
    t_span, growth, h_cap, rtol, h_start = (
        checks.real(name, v) for name, v in (("t_span", t_span), ("growth", growth),
                                             ("h_cap", h_cap), ("rtol", rtol),
                                             ("h_start", h_start)))
    if not (t_span > 0 and growth > 1 and h_cap > 0 and 0 < rtol < 1 and 0 < h_start <= h_cap):
        raise InvalidInputError(f"need t_span > 0, growth > 1, h_cap > 0, 0 < rtol < 1, "
                                f"0 < h_start <= h_cap; got t_span = {t_span}, growth = {growth}, "
                                f"h_cap = {h_cap}, rtol = {rtol}, h_start = {h_start}")
    scale = _reference_scale(problem, params, y0, t_span)
    solves, cpu = 0, 0.0

    def trial(h):
        nonlocal solves, cpu
        ok, why, c = _run_is_stable(problem, method, h, t_span, growth, params, y0, scale)
        solves, cpu = solves + 1, cpu + c
        return ok, why

    lo, hi, reason = None, None, ""
    h = h_start
    ok, why = trial(h)
    while not ok:                       # h_start fails: go down
        hi, reason = h, why
        h /= 2
        if h < 1e-7:
            return StepLimit(problem, method, t_span, growth, 0.0, hi, reason, solves, cpu)
        ok, why = trial(h)
    lo = h
    while hi is None:                   # go up to the first failure or the cap
        h = min(2 * lo, h_cap)
        ok, why = trial(h)
        if ok:
            lo = h
            if h >= h_cap:
                return StepLimit(problem, method, t_span, growth, h_cap, None,
                                 "stable at h_cap", solves, cpu)
        else:
            hi, reason = h, why
    while hi / lo > 1 + rtol:
        mid = math.sqrt(lo * hi)
        ok, why = trial(mid)
        if ok:
            lo = mid
        else:
            hi, reason = mid, why
    return StepLimit(problem, method, t_span, growth, lo, hi, reason, solves, cpu)


def equilibrium(problem: str, params: dict | None = None, y0=None) -> np.ndarray:
    """The rest state nearest y0 (velocities zero), by Newton on the compiled right-hand side."""
    # SciPy is an optional dependency (the studies' extra): only this Newton needs it
    from scipy.optimize import root
    info = _problem(problem)
    y = state_vector("y0", y0 if y0 is not None else info.y0, info.n if info.n > 0 else None).copy()
    nq = y.size // 2 if info.second_order else 0
    if nq:
        y[nq:] = 0.0

        def g(q):
            return evaluate_rhs(problem, 0.0, np.concatenate([q, np.zeros(nq)]), params)[nq:]
        sol = root(g, y[:nq], tol=1e-14)
        y[:nq] = sol.x
    else:
        sol = root(lambda v: evaluate_rhs(problem, 0.0, v, params), y, tol=1e-14)
        y = sol.x
    if np.abs(evaluate_rhs(problem, 0.0, y, params)).max() > 1e-8:
        raise InvalidInputError(f"{problem}: no rest state found near y0 = {list(y)}")
    return y


def linearisation(problem: str, params: dict | None = None, y0=None) -> tuple[np.ndarray, np.ndarray]:
    """(y_eq, J): the rest state and the Jacobian of the compiled right-hand side there
    (central differences)."""
    y = equilibrium(problem, params, y0)
    n = y.size
    jac = np.empty((n, n))
    for j in range(n):
        d = 1e-6 * max(1.0, abs(y[j]))
        e = np.zeros(n)
        e[j] = d
        jac[:, j] = (evaluate_rhs(problem, 0.0, y + e, params)
                     - evaluate_rhs(problem, 0.0, y - e, params)) / (2 * d)
    return y, jac


def linear_step_limits(method: str, jac: np.ndarray, *, t_span: float = 100.0,
                       growth: float = 10.0, h_cap: float = 1.0) -> tuple[float, float]:
    """The predictions from the linearisation y' = J y, from the kernel's step matrices:
    (largest h with spectral radius <= 1, i.e. bounded for ever; largest h with
    rho(h)^ceil(t_span/h) <= growth, i.e. bounded by `growth` over t_span). h_cap when stable
    up to h_cap; 0.0 when unstable for every h > 0 (see oscillator_limit)."""
    _method(method)
    jac = _array("jac", jac)
    if jac.ndim != 2 or jac.shape[0] != jac.shape[1]:
        raise InvalidInputError(f"jac has shape {jac.shape}; give a square matrix (n, n)")
    t_span, growth, h_cap = (_positive(name, v) for name, v in (
        ("t_span", t_span), ("growth", growth), ("h_cap", h_cap)))
    if not growth > 1:
        raise InvalidInputError(f"growth = {growth:g} must exceed 1")
    if not h_cap > 1e-5:
        raise InvalidInputError(f"h_cap = {h_cap:g} must exceed 1e-5 (the search starts there)")
    hs = np.logspace(-5, math.log10(h_cap), 1001)
    rho = _radius(step_matrices(method, np.broadcast_to(jac, (hs.size,) + jac.shape), hs))

    def radius(h):
        return _radius(step_matrices(method, jac[None], [h]))[0]

    bad = np.flatnonzero(rho > 1 + STABLE_TOL)
    if bad.size == 0:
        forever = h_cap
    elif bad[0] == 0:
        forever = 0.0
    else:
        forever = _first_crossing(lambda h: radius(h) - 1 - STABLE_TOL, hs[bad[0] - 1], hs[bad[0]])
        below = _radius(step_matrices(method, np.broadcast_to(jac, (10,) + jac.shape),
                                      np.linspace(0.05, 0.5, 10) * forever))
        if np.any(below > 1 + 1e-13):
            forever = 0.0

    def excess(h):
        r = radius(h)
        return math.ceil(t_span / h - 1e-9) * math.log(r) - math.log(growth) if np.isfinite(r) else 1.0

    ex = np.array([math.ceil(t_span / h - 1e-9) * math.log(r) - math.log(growth)
                   if np.isfinite(r) else 1.0 for h, r in zip(hs, rho)])
    bad = np.flatnonzero(ex > 0)
    if bad.size == 0:
        horizon = h_cap
    elif bad[0] == 0:
        horizon = 0.0
    else:
        horizon = _first_crossing(excess, hs[bad[0] - 1], hs[bad[0]])
    return forever, horizon


def unstable_mode(method: str, h: float, jac, min_growth: float = 1.0 + 1e-6) -> dict | None:
    """The mode of a linearised scene that the fixed step h of method amplifies although the
    scene does not (an eigenvalue lambda of jac, the Jacobian of y' = F(t, y) at a state, with
    Re lambda <= 0 and spectral radius of the step matrix at h lambda above 1); None if there is
    none. The worst such mode: lambda, h lambda, the growth per step and h_max, the largest step
    at which that mode is stable (bisection on the method's own step matrix). A run that fails
    by overflow or drift with such a mode failed because h lies beyond the method's stability
    limit, not because of the mechanism. min_growth: the growth per step above which a mode
    counts."""
    info = _method(method)
    if info.family == "euler_cromer" or info.adaptive:
        return None
    jac = np.asarray(jac, dtype=float)
    if jac.ndim != 2 or jac.shape[0] != jac.shape[1] or not np.all(np.isfinite(jac)):
        return None
    lam = np.linalg.eigvals(jac)
    lam = lam[(lam.real <= 1e-9 * np.abs(lam)) & (np.abs(lam) > 0)]
    if lam.size == 0:
        return None
    r = spectral_radius(method, h * lam)
    bad = np.flatnonzero(r > min_growth)
    if bad.size == 0:
        return None
    k = bad[np.argmax(np.abs(lam[bad]))]
    z = h * lam[k]
    # the fraction s of h below which every step is stable for this mode: the first unstable
    # point of a fine scan (a multistep method's region need not hold a whole segment of the
    # ray: bdf4's is not star-shaped), then bisection within that bracket
    s = np.geomspace(1e-8, 1.0, 400)
    unstable = np.flatnonzero(spectral_radius(method, s * z) > 1.0 + 1e-9)
    first = unstable[0] if unstable.size else s.size - 1
    lo, hi = (s[first - 1] if first > 0 else 0.0), s[first]
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if spectral_radius(method, [mid * z])[0] <= 1.0 + 1e-9:
            lo = mid
        else:
            hi = mid
    return {"lambda": complex(lam[k]), "z": complex(z), "growth": float(r[k]),
            "h_max": float(lo * h)}


#: a failure is blamed on the step only where a mode grows this much per step: a slower growth
#: (explicit Euler on an undamped oscillation, 1.003 per step) is the method's accuracy, which
#: the drift the watch names already says
BLAME_GROWTH = 1.5


def instability_note(method: str, h: float, jac) -> str:
    """unstable_mode as a sentence for a failure message ('' if none)."""
    mode = unstable_mode(method, h, jac, BLAME_GROWTH)
    if mode is None:
        return ""
    lam = mode["lambda"]
    return (f"h = {h:g} lies beyond {method}'s stability limit for a mode of the scene that "
            f"does not grow (lambda = {lam.real:.3g}{lam.imag:+.3g}j 1/s, h lambda = "
            f"{mode['z'].real:.3g}{mode['z'].imag:+.3g}j: it grows {mode['growth']:.3g}-fold "
            f"per step); a step below {mode['h_max']:.3g} s keeps it stable, or an implicit or "
            "error-controlled method (bdf, trapezoidal_index3, dopri54) follows it")
