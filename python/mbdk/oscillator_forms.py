"""Closed forms of the fixed-step ODE methods on the undamped oscillator q'' = -omega^2 q:
the roots of one step at Omega = omega h, which of them is the principal one, and the spectral
radius, numerical damping ratio and relative period error they give.

As a first-order system y = (q, v), y' = A y with the eigenvalues +-i omega, so a one-step
method's step has the roots R(i Omega) and R(-i Omega), R its stability function, and a k-step
linear multistep method's the 2k roots of rho(zeta) -+ i Omega sigma(zeta). The formulas here
come from the literature and from the schemes' definitions, not from the kernel's tables:
mbdk.spectral measures the kernel's compiled steps against them.

    explicit_euler, heun, rk4   R(z) = sum_{j <= s} z^j / j!, s = 1, 2, 4: an explicit
                                Runge-Kutta method with s stages and order s has the degree-s
                                Taylor polynomial of exp(z) as its stability function
                                (Hairer and Wanner, Solving ODE II, IV.2)
    implicit_euler, bdf1        R(z) = 1 / (1 - z)              (Hairer and Wanner II, IV.3:
    trapezoidal                 R(z) = (1 + z/2) / (1 - z/2)     the Pade approximants of exp)
    euler_cromer                v+ = v - h omega^2 q, q+ = q + h v+ (Cromer 1981; Fekete (2023)
                                (4.31)-(4.32); the symplectic Euler method of Hairer, Lubich and
                                Wanner, Geometric Numerical Integration, I.1): on (q, h v) the
                                matrix [[1 - Omega^2, 1], [-Omega^2, 1]], trace 2 - Omega^2,
                                determinant 1, so both roots lie on the unit circle up to
                                Omega = 2 and are real beyond it
    bdf1 .. bdf6                sum_{j=1..k} (1/j) nabla^j y_{n+k} = h f_{n+k} (Hairer, Norsett
                                and Wanner, Solving ODE I, III.1, (1.22')): nabla^j y_{n+k} has
                                the polynomial (zeta - 1)^j zeta^(k-j), so rho(zeta) =
                                sum_j (1/j) (zeta - 1)^j zeta^(k-j) and sigma(zeta) = zeta^k

Which root is reported. The spectral radius is the largest modulus of all roots: it decides
whether the step's error grows. The damping ratio and the period error are those of the
principal root, the one that tends to exp(i Omega) as Omega -> 0, followed by continuation as
Omega grows (a k-step method's k - 1 spurious roots per eigenvalue start at the other roots of
rho, inside the unit circle). At large Omega a spurious root can be the larger one (bdf3 to
bdf6 beyond Omega of a few units: `dominant` says which); the damping ratio and the period
error still describe the principal root, the one that carries the motion. With the principal
root lambda = |lambda| exp(i theta), theta = |arg lambda| in (0, pi]: damping ratio
xi = -ln|lambda| / theta (negative: the step amplifies), period error Omega / theta - 1
(positive: the discrete motion lags); both NaN where the principal root is real (the step has
lost the oscillation: euler_cromer beyond Omega = 2). Beyond Omega = pi the samples of the
exact motion alias too, and the period error compares the discrete motion's apparent period
with the true one.
"""
from __future__ import annotations

import functools
import math

import numpy as np

from .errors import InvalidInputError, NotApplicableError

#: the methods with a closed form here: every fixed-step method of the kernel that integrates
#: y' = F(t, y) (the index-3 family's closed forms are in mbdk.alpha_family)
METHODS = ("explicit_euler", "heun", "rk4", "euler_cromer", "implicit_euler", "trapezoidal",
           "bdf1", "bdf2", "bdf3", "bdf4", "bdf5", "bdf6")
#: the continuation's grid: points per decade of Omega, from OMEGA_START
PER_DECADE = 100
OMEGA_START = 1e-3


def _check(method: str) -> str:
    if method not in METHODS:
        raise NotApplicableError(f"{method!r} has no closed form on the oscillator here; the "
                                 f"fixed-step ODE methods have ({', '.join(METHODS)}), the "
                                 "index-3 family's are in mbdk.alpha_family")
    return method


def _omega(omega_h) -> float:
    try:
        w = float(omega_h)
    except (TypeError, ValueError):
        raise InvalidInputError(f"omega_h = {omega_h!r}: give a positive number") from None
    if not (math.isfinite(w) and w > 0):
        raise InvalidInputError(f"omega_h = {omega_h!r}: give a positive finite number")
    return w


@functools.lru_cache(maxsize=None)
def bdf_polynomials(k: int) -> tuple[np.ndarray, np.ndarray]:
    """(rho, sigma) of bdfk, coefficients from zeta^k down to zeta^0 (numpy's order), from the
    backward-difference form sum_{j=1..k} (1/j) nabla^j y_{n+k} = h f_{n+k}."""
    rho = np.zeros(k + 1)
    for j in range(1, k + 1):
        # (zeta - 1)^j zeta^(k-j): the binomial coefficients of (zeta - 1)^j, shifted by k - j
        rho[: j + 1] += np.poly(np.ones(j)) / j
    sigma = np.zeros(k + 1)
    sigma[0] = 1.0
    rho.setflags(write=False)
    sigma.setflags(write=False)
    return rho, sigma


def _stability_function(method: str, z: complex) -> complex:
    if method in ("explicit_euler", "heun", "rk4"):
        s = {"explicit_euler": 1, "heun": 2, "rk4": 4}[method]
        return sum(z ** j / math.factorial(j) for j in range(s + 1))
    if method in ("implicit_euler", "bdf1"):
        return 1.0 / (1.0 - z)
    return (1.0 + z / 2.0) / (1.0 - z / 2.0)          # trapezoidal


def branch_roots(method: str, omega_h: float) -> np.ndarray:
    """The roots that belong to the eigenvalue +i omega (for euler_cromer, whose step is not a
    function of A alone, both roots of its 2 x 2 matrix)."""
    w = omega_h
    if method == "euler_cromer":
        return np.linalg.eigvals(np.array([[1.0 - w * w, 1.0], [-w * w, 1.0]])).astype(complex)
    if method.startswith("bdf") and method != "bdf1":
        return _bdf_branch_roots(int(method[3:]), np.array([w]))[0]
    return np.array([_stability_function(method, 1j * w)])


def step_roots(method: str, omega_h) -> np.ndarray:
    """Every root of one step at Omega = omega_h: 2 for the one-step methods, 2k for bdfk (the
    eigenvalues of the step's companion matrix on the history of (q, v))."""
    method, w = _check(method), _omega(omega_h)
    r = branch_roots(method, w)
    return r if method == "euler_cromer" else np.concatenate([r, np.conj(r)])


def _bdf_branch_roots(k: int, ws: np.ndarray) -> np.ndarray:
    """The k roots of rho(zeta) - i Omega sigma(zeta) at every Omega of ws, (len(ws), k): the
    eigenvalues of the monic polynomial's companion matrices, in one batch."""
    rho, sigma = bdf_polynomials(k)
    p = rho[None, :] - 1j * ws[:, None] * sigma[None, :]
    p = p / p[:, :1]
    comp = np.zeros((ws.size, k, k), dtype=complex)
    comp[:, 0, :] = -p[:, 1:]
    if k > 1:
        comp[:, np.arange(1, k), np.arange(k - 1)] = 1.0
    return np.linalg.eigvals(comp)


def principal_roots(method: str, omega_h) -> np.ndarray:
    """The principal root at each Omega (array-like). One-step methods have one root per
    eigenvalue, R(i Omega); euler_cromer's principal root is the one of its pair in the upper
    half plane (either, where both are real); bdfk's is followed by continuation from
    exp(i Omega) at Omega = OMEGA_START along a geometric grid of PER_DECADE points per decade
    through the given values: at each point the root nearest the previous one."""
    method = _check(method)
    ws = np.atleast_1d(np.asarray([_omega(w) for w in np.ravel(omega_h)], dtype=float))
    if not method.startswith("bdf") or method == "bdf1":
        out = []
        for w in ws:
            r = branch_roots(method, w)
            out.append(r[np.argmax(r.imag)])
        return np.array(out, dtype=complex)
    start = min(OMEGA_START, ws.min())
    n = max(2, int(math.ceil(PER_DECADE * math.log10(ws.max() / start))) + 1)
    path = np.unique(np.concatenate([np.geomspace(start, ws.max(), n), ws]))
    roots = _bdf_branch_roots(int(method[3:]), path)
    z = roots[0][np.argmin(np.abs(roots[0] - np.exp(1j * path[0])))]
    chosen = np.empty(path.size, dtype=complex)
    for i, r in enumerate(roots):
        z = r[np.argmin(np.abs(r - z))]
        chosen[i] = z
    return chosen[np.searchsorted(path, ws)]


def properties_of(roots, principal: complex, omega_h: float) -> tuple[float, float, float]:
    """(spectral radius, damping ratio, period error) from a step's roots and its principal
    root (the module docstring's definitions)."""
    roots = np.asarray(roots, dtype=complex)
    rho = float(np.abs(roots).max())
    lam = complex(principal)
    if abs(lam.imag) <= 1e-13 * abs(lam):
        return rho, math.nan, math.nan
    theta = abs(math.atan2(lam.imag, lam.real))
    return rho, -math.log(abs(lam)) / theta, omega_h / theta - 1.0


def closed_form_properties(method: str, omega_h) -> tuple[float, float, float]:
    """(spectral radius, damping ratio, period error) of `method` at Omega = omega_h."""
    w = _omega(omega_h)
    return properties_of(step_roots(method, w), principal_roots(method, w)[0], w)


def dominant(method: str, omega_h) -> str:
    """Which root sets the spectral radius: 'principal' (to 1e-12), 'spurious', or 'real pair'
    where the principal root has become real (euler_cromer beyond Omega = 2: its two real roots
    are the pair that was exp(+-i Omega), and neither is spurious)."""
    w = _omega(omega_h)
    rho = np.abs(step_roots(method, w)).max()
    z = principal_roots(method, w)[0]
    if abs(z.imag) <= 1e-13 * abs(z):
        return "real pair"
    return "principal" if abs(z) >= rho * (1 - 1e-12) else "spurious"
