"""Spectral radius, numerical damping and period error of a compiled integrator, measured from
the kernel's own steps on scenes, and compared with closed forms: mbdk.oscillator_forms for the
fixed-step ODE methods, mbdk.alpha_family for the index-3 family (Hughes, "The Finite Element
Method", 9.3; Chung and Hulbert 1993).

The measurement. A linear method's step maps its state by a constant matrix, so every sampled
coordinate obeys the linear recurrence of that matrix's characteristic (or minimal)
polynomial. Its coefficients, fitted by least squares to the samples of a few runs (Prony's
method), give the step's roots. Each row of the fit is scaled to unit size, so that a growing
root (rk4 beyond Omega = 2 sqrt 2, bdf6's spurious root) does not drown the decaying ones: every
row then carries roundoff of the same relative size. Every run is a scene run of the kernel's
time loop (mbdk.simulate, one sample per step); nothing is stepped in Python.

1. The oscillator (`measure`): one body on a coordinate spring along x, q'' = -omega^2 q,
   released from x = X0 and, in a second run, pushed with v = omega X0 from x = 0, at
   h = Omega / omega. The ODE methods' runs give x_n and v_n; a k-step method's recurrence has
   order 2k (its companion matrix on the history of (q, v)), and its spurious roots must be
   excited to be seen: bdf2..bdf6 start with their BDF ramp (orders 1, 2, .., k-1), whose start
   values lie off the principal motion by O(Omega^2), where the book's extrapolated RK4 start
   would leave them O(Omega^6) off it. The index-3 family's order is the rank of the data: 2 for
   the members whose pseudo-acceleration is the acceleration, 3 for the others.
2. The pendulum, a point mass on a distance constraint of length L below a pivot (index-3
   family only): its free direction, swinging with the amplitude EPS_FREE (rad), is the
   oscillator at Omega = sqrt(g/L) h to O(EPS_FREE^2) (`pendulum_free_direction`); its
   multiplier's oscillation, quadratic in the swing, has the root lambda_p^2 of the free
   direction's principal root (`pendulum_multiplier`); and its constrained (radial) direction,
   driven through a rod length L(t) = L + A sin(omega_d t), carries the step's own transient in
   the multiplier (`pendulum_constrained_direction`), against
   mbdk.alpha_family.constrained_amplification.

Which root is reported: the spectral radius is the largest modulus of all fitted roots; the
damping ratio and the period error are those of the principal root (mbdk.oscillator_forms'
docstring). For the ODE methods the principal root among the measured ones is the one nearest
the closed form's principal root: the measured roots agree with the closed form's as a set
(`Spectrum.root_distance`, the largest distance between a root and the nearest one of the
other set), so the closed form only names which measured root is which.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np

from . import alpha_family as AF
from . import oscillator_forms as OF
from .errors import AccuracyWarning, InvalidInputError, NotApplicableError
from .methods import method as _method_info
from .scene_file import scene_from_dict
from .simulate import simulate

#: the release amplitude (m): small beside the body's size, large beside roundoff
X0 = 1e-3
#: the steps fitted for a one-step method (the sequences decay as rho^n: a few steps hold the
#: information); a k-step method takes 4 k + NSTEPS (2k unknowns, and its spurious roots)
NSTEPS = 12
#: the pendulum: gravity (m/s^2) and rod length (m)
G, LENGTH = 9.81, 1.0
#: the free direction's swing (rad): its O(EPS^2) nonlinearity and the roundoff of a motion
#: of that size (Newton's tolerances act on it) are both about 1e-10 of the roots here
EPS_FREE = 1e-6
#: the swing for the multiplier's oscillation, which is quadratic in it: 1e-3 rad makes it
#: 1e-6 of the static multiplier, far above its roundoff, with O(EPS^2) = 1e-6 nonlinearity
EPS_MULTIPLIER = 1e-3
#: the radial drive of the constrained direction: amplitude (m) and angular frequency (rad/s).
#: The step's transient is excited by how far the drive's sampled motion is from what the step
#: can follow, which grows with omega_d h: at h = 0.1 (omega_d h = 0.5) it is a few percent of
#: the drive, and the book form's growing transient (the trapezoidal rule's) stays small beside
#: the rod over the run (a larger one turns the bob over the pivot, the other root of Phi = 0)
DRIVE_AMPLITUDE, DRIVE_OMEGA = 0.05, 5.0
#: samples dropped before a multiplier's fit: a root 0 of multiplicity m (the step's nilpotent
#: part) shows only in the first m samples and has no rate to measure
SKIP = 3


@dataclass
class Spectrum:
    """One method at one Omega = omega h: the fitted roots, the spectral radius (largest
    modulus), the principal root and its damping ratio and period error; fit_residual the
    largest residual of the fitted recurrence (each row scaled to unit size); root_distance
    the largest distance between a measured root and the nearest closed-form root and back
    (NaN where not computed); cpu_time the runs' solving-thread CPU seconds, steps their
    steps."""

    method: str
    omega_h: float
    roots: np.ndarray = field(repr=False)
    principal: complex
    spectral_radius: float
    damping_ratio: float
    period_error: float
    fit_residual: float
    root_distance: float
    cpu_time: float
    steps: int

    @property
    def properties(self) -> tuple[float, float, float]:
        return self.spectral_radius, self.damping_ratio, self.period_error


def oscillator(v0: float = 0.0, x0: float = X0, omega: float = 1.0):
    """One body (1 kg) on a coordinate spring k = omega^2 along x, free in y and angle."""
    return scene_from_dict({
        "scene": {"name": "oscillator", "description": "q'' = -omega^2 q: a body on a "
                  "coordinate spring (mbdk.spectral)"},
        "body": [{"name": "mass", "mass": 1.0, "shape": {"type": "disc", "radius": 0.1},
                  "x": x0, "y": 0.0, "vx": v0}],
        "force": [{"name": "spring", "type": "coordinate_spring", "body": "mass",
                   "coordinate": "x", "stiffness": omega * omega, "rest": 0.0}]})


def pendulum(x0: float = 0.0, vx0: float = 0.0, length=None):
    """A point mass (1 kg, a disc of radius 0.05 m) on a distance constraint to the pivot
    (0, LENGTH), under gravity G: at rest it hangs at the origin, so that its coordinates are
    as small as its motion. x0: the horizontal offset (on the circle), vx0 the horizontal
    velocity; length: the rod's length, a number or a time function table (default LENGTH)."""
    y0 = LENGTH - math.sqrt(LENGTH * LENGTH - x0 * x0)
    joint = {"type": "distance", "name": "rod", "body1": "bob", "point2": [0.0, LENGTH]}
    if length is not None:
        joint["length"] = length
    return scene_from_dict({
        "scene": {"name": "pendulum", "description": "a point mass on a distance constraint "
                  "(mbdk.spectral)"},
        "body": [{"name": "bob", "mass": 1.0, "shape": {"type": "disc", "radius": 0.05},
                  "x": x0, "y": y0, "vx": vx0}],
        "joint": [joint],
        "force": [{"type": "gravity", "g": [0.0, -G]}]})


def _rows(seqs, order):
    a, b = [], []
    for s in seqs:
        for n in range(len(s) - order):
            w = np.abs(s[n:n + order + 1]).max()
            if w > 0:
                a.append(s[n:n + order] / w)
                b.append(s[n + order] / w)
    return np.array(a).reshape(-1, order), np.array(b)


def fit_recurrence(seqs: list[np.ndarray], order: int | None = None, max_order: int = 3,
                   rtol: float = 1e-9) -> tuple[np.ndarray, float]:
    """The monic polynomial (numpy's order, highest power first) of the shortest linear
    recurrence that all sequences obey, and its largest row residual (Prony). order: given, or
    the numerical rank (singular values above rtol times the largest) of the stacked rows of
    max_order + 1 samples, at most max_order."""
    if order is None:
        a, _ = _rows(seqs, max_order + 1)
        sv = np.linalg.svd(a, compute_uv=False)
        order = max(1, min(max_order, int(np.sum(sv > rtol * sv[0]))))
    a, b = _rows(seqs, order)
    if a.shape[0] < order:
        raise InvalidInputError(f"{a.shape[0]} rows for a recurrence of order {order}: give "
                                "longer sequences")
    c, *_ = np.linalg.lstsq(a, b, rcond=None)
    residual = float(np.abs(a @ c - b).max())
    # s[n + p] = sum c_k s[n + k]: z^p - c_{p-1} z^{p-1} - ... - c_0
    return np.concatenate([[1.0], -c[::-1]]), residual


def fit_roots(seqs: list[np.ndarray], max_order: int = 3, rtol: float = 1e-9) -> np.ndarray:
    """The roots of the shortest linear recurrence that all sequences obey (fit_recurrence)."""
    return np.roots(fit_recurrence(seqs, max_order=max_order, rtol=rtol)[0])


def _hausdorff(a, b) -> float:
    a, b = np.asarray(a, complex), np.asarray(b, complex)
    if a.size == 0 or b.size == 0:
        return 0.0 if a.size == b.size else math.inf
    d = np.abs(a[:, None] - b[None, :])
    return float(max(d.min(axis=1).max(), d.min(axis=0).max()))


def _family(method: str) -> bool:
    return method in AF.MEMBERS


def _one_map(r, method: str, h: float):
    """A run whose steps were all one step of h: a step retried in substeps (Newton failed)
    is another map, and the fitted recurrence would mix the two."""
    if r.stats.newton_failures:
        raise NotApplicableError(f"{method} at h = {h:g}: {r.stats.newton_failures} step(s) "
                                 "were retried in substeps after Newton failed, so the samples "
                                 "are not one step's map; measure at a smaller Omega")
    return r


def _runs(method, h, nsteps, options, scenes, scales):
    """x_n and v_x,n of each run (over its scale: position, velocity), their CPU time and
    steps."""
    out, cpu, steps = [], 0.0, 0
    for sc, (sq, sv) in zip(scenes, scales):
        r = _one_map(simulate(sc, method, h=h, t_end=nsteps * h, every=1, outputs=(),
                              watch=False, **options), method, h)
        out += [r.q[:, 0] / sq, r.v[:, 0] / sv]
        cpu += r.stats.cpu_time
        steps += r.stats.steps
    return out, cpu, steps


def _positive(name: str, value) -> float:
    try:
        x = float(value)
    except (TypeError, ValueError):
        x = math.nan
    if not (math.isfinite(x) and x > 0):
        raise InvalidInputError(f"{name} = {value!r}: give a positive finite number")
    return x


def measure(method: str, omega_h: float, nsteps: int | None = None, **options) -> Spectrum:
    """The spectrum of a compiled fixed-step method at Omega = omega_h on the oscillator (the
    module docstring); nsteps: the steps of each run (default: the method's, above); options
    go to simulate (the family's parameters, its formulation)."""
    info = _method_info(method)
    w = _positive("omega_h", omega_h)
    if nsteps is not None and (isinstance(nsteps, bool) or not isinstance(nsteps, int)
                               or nsteps < 4):
        raise InvalidInputError(f"nsteps = {nsteps!r}: give a whole number of at least 4")
    scenes = (oscillator(), oscillator(v0=X0, x0=0.0))
    if _family(method):
        seqs, cpu, steps = _runs(method, w, nsteps or NSTEPS, options, scenes, [(X0, X0)] * 2)
        poly, res = fit_recurrence(seqs, max_order=3)
        roots = np.roots(poly)
        rho, xi, pe = AF.properties_from_roots(roots, w)
        upper = roots[roots.imag > 0]
        principal = (upper[np.argmin(np.abs(upper - np.exp(1j * w)))] if upper.size
                     else complex(roots[np.argmax(np.abs(roots))]))
        p = AF.parameters(method, **{k: v for k, v in options.items() if k in AF.OPTIONS})
        cf = np.linalg.eigvals(AF.amplification(p, w))
        if roots.size < 3:
            cf = cf[np.argsort(-np.abs(cf))][:roots.size]
        return Spectrum(method, w, roots, complex(principal), rho, xi, pe, res,
                        _hausdorff(roots, cf), cpu, steps)
    if method not in OF.METHODS:
        raise NotApplicableError(f"{method} has no fixed step to measure on the oscillator; "
                                 f"the fixed-step methods are {', '.join(OF.METHODS)} and "
                                 f"{', '.join(AF.MEMBERS)}")
    k = info.steps
    opts = dict(options)
    if k > 1:
        opts.setdefault("startup", "bdf")
    nsteps = nsteps or (NSTEPS if k == 1 else 4 * k + NSTEPS)
    seqs, cpu, steps = _runs(method, w, nsteps, opts, scenes, [(X0, X0)] * 2)
    poly, res = fit_recurrence(seqs, order=2 * k)
    roots = np.roots(poly)
    zc = OF.principal_roots(method, w)[0]
    d = np.minimum(np.abs(roots - zc), np.abs(roots - np.conj(zc)))
    principal = complex(roots[np.argmin(d)])
    rho, xi, pe = OF.properties_of(roots, principal, w)
    return Spectrum(method, w, roots, principal, rho, xi, pe, res,
                    _hausdorff(roots, OF.step_roots(method, w)), cpu, steps)


def measured_properties(method: str, omega_h: float, nsteps: int | None = None,
                        **options) -> tuple[float, float, float, float]:
    """(spectral radius, damping ratio, period error, the solving thread's CPU seconds per
    step) of the compiled method at Omega = omega_h, from its steps on the oscillator."""
    s = measure(method, omega_h, nsteps=nsteps, **options)
    return s.spectral_radius, s.damping_ratio, s.period_error, s.cpu_time / max(s.steps, 1)


def closed_form(method: str, omega_h, **options) -> np.ndarray:
    """The closed-form (spectral radius, damping ratio, period error) of any method `measure`
    takes (mbdk.oscillator_forms or mbdk.alpha_family): shape (3,) for one Omega, (n, 3) for
    an array of them (one continuation along them for bdfk)."""
    ws = np.atleast_1d(np.asarray(omega_h, dtype=float))
    if _family(method):
        p = AF.parameters(method, **{k: v for k, v in options.items() if k in AF.OPTIONS})
        out = np.array([AF.closed_form_properties(p, w) for w in ws])
    else:
        zs = OF.principal_roots(method, ws)
        out = np.array([OF.properties_of(OF.step_roots(method, w), z, w)
                        for w, z in zip(ws, zs)])
    return out[0] if np.ndim(omega_h) == 0 else out


def _family_only(method: str, what: str):
    if not _family(method):
        raise NotApplicableError(f"{method}: {what} is measured for the index-3 family "
                                 f"({', '.join(AF.MEMBERS)}), which integrates the pendulum's "
                                 "DAE itself")


def pendulum_free_direction(method: str, omega_h: float, eps: float = EPS_FREE,
                            **options) -> Spectrum:
    """The spectrum of the pendulum's free direction at Omega = sqrt(G/LENGTH) h: x_n and
    v_x,n of a release from the angle eps and of a push with v = eps omega LENGTH from rest,
    fitted as on the oscillator (order the rank of the data, at most 3)."""
    _family_only(method, "the pendulum's free direction")
    w = _positive("omega_h", omega_h)
    omega = math.sqrt(G / LENGTH)
    h = w / omega
    amp = eps * LENGTH
    out, cpu, steps = [], 0.0, 0
    for sc in (pendulum(x0=amp), pendulum(vx0=amp * omega)):
        r = _one_map(simulate(sc, method, h=h, t_end=16 * h, every=1, outputs=(), watch=False,
                              **options), method, h)
        out += [r.q[:, 0] / amp, r.v[:, 0] / (amp * omega)]
        cpu += r.stats.cpu_time
        steps += r.stats.steps
    poly, res = fit_recurrence(out, max_order=3)
    roots = np.roots(poly)
    rho, xi, pe = AF.properties_from_roots(roots, w)
    upper = roots[roots.imag > 0]
    principal = (upper[np.argmin(np.abs(upper - np.exp(1j * w)))] if upper.size
                 else complex(roots[np.argmax(np.abs(roots))]))
    return Spectrum(method, w, roots, complex(principal), rho, xi, pe, res, math.nan, cpu,
                    steps)


@dataclass
class MultiplierSpectrum:
    """The pendulum's multiplier on a small swing: roots of its fitted recurrence (from
    sample SKIP on); oscillation the root nearest the square of the free direction's principal
    root; its damping ratio (-ln|root| / arg root) and period error against the exact
    oscillation of the multiplier at 2 omega (2 Omega / arg root - 1); cpu_time, steps."""

    method: str
    omega_h: float
    roots: np.ndarray = field(repr=False)
    oscillation: complex
    damping_ratio: float
    period_error: float
    cpu_time: float
    steps: int


def pendulum_multiplier(method: str, omega_h: float, principal: complex,
                        eps: float = EPS_MULTIPLIER, **options) -> MultiplierSpectrum:
    """The multiplier's oscillation on a swing of eps (rad) at Omega = sqrt(G/LENGTH) h. Its
    deviation from the static value is quadratic in the motion, so its roots are products of
    the free direction's (lambda_p^2 the one that oscillates at twice the frequency), with the
    constrained direction's transient beside them; `principal` (the free direction's measured
    principal root) names which one is the oscillation."""
    _family_only(method, "the pendulum's multiplier")
    w = _positive("omega_h", omega_h)
    h = w / math.sqrt(G / LENGTH)
    with warnings.catch_warnings():
        # the book form's multipliers carry its error: what is measured here
        warnings.simplefilter("ignore", AccuracyWarning)
        r = _one_map(simulate(pendulum(x0=eps * LENGTH), method, h=h, t_end=60 * h, every=1,
                              outputs=("multipliers",), watch=False, **options), method, h)
    lam = r.multipliers[SKIP:, 0]
    poly, _ = fit_recurrence([lam], max_order=12, rtol=1e-9)
    roots = np.roots(poly)
    target = complex(principal) ** 2
    z = roots[np.argmin(np.minimum(np.abs(roots - target), np.abs(roots - np.conj(target))))]
    theta = abs(math.atan2(z.imag, z.real))
    if theta == 0.0:
        xi = pe = math.nan
    else:
        xi, pe = -math.log(abs(z)) / theta, 2.0 * w / theta - 1.0
    return MultiplierSpectrum(method, w, roots, complex(z), xi, pe, r.stats.cpu_time,
                              r.stats.steps)


@dataclass
class ConstrainedSpectrum:
    """The constrained direction of the pendulum driven through its rod length: the
    multiplier's fitted recurrence divided by the drive's own factor (z - 1)(z^2 - 2 cos(omega_d
    h) z + 1), the remainder of that division (relative: the drive's roots must be in the fit),
    the quotient's roots (the step's transient along the constraint; none where the step
    carries nothing along it) and their largest modulus; cpu_time, steps."""

    method: str
    h: float
    quotient: np.ndarray = field(repr=False)
    remainder: float
    roots: np.ndarray
    spectral_radius: float
    cpu_time: float
    steps: int


def pendulum_constrained_direction(method: str, h: float = 0.1,
                                   amplitude: float = DRIVE_AMPLITUDE,
                                   omega_d: float = DRIVE_OMEGA,
                                   **options) -> ConstrainedSpectrum:
    """The step's transient along the pendulum's rod (mbdk.alpha_family.
    constrained_amplification): the bob hangs at rest and the rod's length follows LENGTH +
    amplitude sin(omega_d t), so the bob moves along the constraint only and the multiplier
    (the rod's tension, with a constant gradient there) holds the static load, the drive at
    omega_d and the transient the step's start leaves along the constraint."""
    _family_only(method, "the pendulum's constrained direction")
    h = _positive("h", h)
    length = {"offset": LENGTH, "amplitude": amplitude, "omega": omega_d}
    sc = pendulum(length=length)
    with warnings.catch_warnings():
        # the book form's multipliers carry its error: what is measured here
        warnings.simplefilter("ignore", AccuracyWarning)
        r = _one_map(simulate(sc, method, h=h, t_end=40 * h, every=1,
                              outputs=("multipliers",), watch=False, **options), method, h)
    lam = r.multipliers[SKIP:, 0]
    poly, _ = fit_recurrence([lam], max_order=9, rtol=1e-10)
    drive = np.polymul([1.0, -1.0], [1.0, -2.0 * math.cos(omega_d * h), 1.0])
    if poly.size < drive.size:
        raise NotApplicableError(f"{method}: the multiplier's fit has order {poly.size - 1}, "
                                 "below the drive's 3: the drive is not resolved")
    quot, rem = np.polydiv(poly, drive)
    remainder = float(np.abs(rem).max()) if rem.size else 0.0
    roots = np.roots(quot) if quot.size > 1 else np.zeros(0, complex)
    rho = float(np.abs(roots).max()) if roots.size else 0.0
    return ConstrainedSpectrum(method, h, quot, remainder, roots, rho, r.stats.cpu_time,
                               r.stats.steps)
