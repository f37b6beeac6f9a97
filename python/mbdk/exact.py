"""Exact solutions of the textbook problems, where they exist (vectorised numpy).

Each function takes the sample times t, the initial time t0, the initial state y0 and the
parameter dict, and returns an array of shape (len(t), n). Derivations are in the docstrings; the
tests check each against the ODE itself (residual of y' - F(t, y)).
"""
from __future__ import annotations

import numpy as np

from .errors import InvalidInputError


def linear_growth(t, t0, y0, p):
    """y' = a t  =>  y = y0 + a (t^2 - t0^2)/2;  (4.12): y = x^2 + 1 for a = 2, y(0) = 1."""
    return (y0[0] + 0.5 * p["a"] * (t**2 - t0**2))[:, None]


def decay(t, t0, y0, p):
    """y' = -lambda y  =>  y = y0 exp(-lambda (t - t0));  (4.15)."""
    return (y0[0] * np.exp(-p["lambda"] * (t - t0)))[:, None]


def riccati(t, t0, y0, p):
    """x' = a t x^2 + b x is a Bernoulli equation: u = 1/x gives u' = -a t - b u, so
    u = -a t/b + a/b^2 + C e^{-b t} (b /= 0) or u = -a t^2/2 + C (b = 0)."""
    a, b = p["a"], p["b"]
    if y0[0] == 0.0:
        return np.zeros((len(t), 1))
    u0 = 1.0 / y0[0]
    if b != 0.0:
        c = (u0 + a * t0 / b - a / b**2) * np.exp(b * t0)
        u = -a * t / b + a / b**2 + c * np.exp(-b * t)
    else:
        u = u0 - 0.5 * a * (t**2 - t0**2)
    return (1.0 / u)[:, None]


def _moment_integral(t, t0, p):
    """(F/EI) * integral_{t0}^{t} (l - x) dx."""
    return p["F"] / p["EI"] * (p["l"] * (t - t0) - 0.5 * (t**2 - t0**2))


def beam_linear(t, t0, y0, p):
    """phi' = -(F/EI)(l - x)  =>  phi = phi0 - (F/EI)(l x - x^2/2) (from x0);  (4.46)."""
    return (y0[0] - _moment_integral(t, t0, p))[:, None]


def beam_nonlinear(t, t0, y0, p):
    """phi' / (1 + phi^2)^(3/2) = d/dx [phi / sqrt(1 + phi^2)] = -(F/EI)(l - x), so with
    s = phi0/sqrt(1 + phi0^2) - (F/EI)(l x - x^2/2):  phi = s / sqrt(1 - s^2)  (|s| < 1).
    The book says (4.39) has no closed-form solution; for phi(x) it has this one."""
    s = y0[0] / np.sqrt(1.0 + y0[0] ** 2) - _moment_integral(t, t0, p)
    bad = np.flatnonzero(np.abs(s) >= 1.0)
    if bad.size:
        i = bad[0]
        raise InvalidInputError(
            f"beam_nonlinear has no solution past x = {t[i]:g}: there phi/sqrt(1+phi^2) = {s[i]:.4g}"
            " reaches +-1 (the slope turns vertical); reduce F/EI or the interval")
    return (s / np.sqrt(1.0 - s**2))[:, None]


def expm2(a, tau):
    """exp(A tau) for a real 2x2 matrix A and an array tau: with s = tr(A)/2 and
    q^2 = s^2 - det(A), exp(A tau) = e^{s tau} [C I + S (A - s I)], C = cosh(q tau),
    S = sinh(q tau)/q (q^2 > 0); cos / sin (q^2 < 0); 1 / tau (q^2 = 0)."""
    a = np.asarray(a, dtype=float)
    s = 0.5 * np.trace(a)
    q2 = s * s - np.linalg.det(a)
    if q2 > 0:
        q = np.sqrt(q2)
        c, sn = np.cosh(q * tau), np.sinh(q * tau) / q
    elif q2 < 0:
        w = np.sqrt(-q2)
        c, sn = np.cos(w * tau), np.sin(w * tau) / w
    else:
        c, sn = np.ones_like(tau), tau
    e = np.exp(s * tau)
    b = a - s * np.eye(2)
    return e[:, None, None] * (c[:, None, None] * np.eye(2) + sn[:, None, None] * b)


def damped_oscillator(t, t0, y0, p):
    """m y'' + c y' + k y = 0: y(t) = exp(A (t - t0)) y0 with A = [[0, 1], [-k/m, -c/m]]."""
    a = [[0.0, 1.0], [-p["k"] / p["m"], -p["c"] / p["m"]]]
    return expm2(a, t - t0) @ np.asarray(y0, dtype=float)


def pendulum_linear(t, t0, y0, p):
    """phi'' = -w^2 phi, w^2 = 3g/2l: harmonic, exp(A (t - t0)) y0."""
    w2 = 1.5 * p["g"] / p["l"]
    return expm2([[0.0, 1.0], [-w2, 0.0]], t - t0) @ np.asarray(y0, dtype=float)


def pendulum(t, t0, y0, p):
    """phi'' = -w^2 sin(phi) in libration (energy below the separatrix): with
    k = sin(phi_max/2), phi = 2 arcsin(k sn(w (t - t0) + u0 | k^2)), phi' = 2 k w cn(...),
    u0 = F(arcsin(sin(phi0/2)/k) | k^2), reflected to 2K - u0 when phi0' < 0.
    Returns None for rotating motion (no closed form implemented)."""
    # SciPy is an optional dependency (the studies' extra): only this solution needs it
    from scipy.special import ellipj, ellipk, ellipkinc

    w = np.sqrt(1.5 * p["g"] / p["l"])
    phi0, dphi0 = float(y0[0]), float(y0[1])
    k2 = np.sin(0.5 * phi0) ** 2 + (dphi0 / (2.0 * w)) ** 2
    if not k2 < 1.0:
        return None
    if k2 == 0.0:
        return np.zeros((len(t), 2))
    k = np.sqrt(k2)
    u0 = ellipkinc(np.arcsin(np.clip(np.sin(0.5 * phi0) / k, -1.0, 1.0)), k2)
    if dphi0 < 0:
        u0 = 2.0 * ellipk(k2) - u0
    sn, cn, _dn, _ph = ellipj(w * (t - t0) + u0, k2)
    return np.column_stack([2.0 * np.arcsin(k * sn), 2.0 * k * w * cn])


def linear_system(t, t0, y0, p):
    """y' = A y: y = V diag(e^{lambda (t - t0)}) V^{-1} y0 for diagonalisable A, else
    scipy.linalg.expm sample by sample."""
    a = np.asarray(p["A"], dtype=float)
    y0 = np.asarray(y0, dtype=float)
    lam, v = np.linalg.eig(a)
    if np.linalg.cond(v) < 1e8:
        c = np.linalg.solve(v, y0)
        y = (np.exp(np.outer(t - t0, lam)) * c) @ v.T
        return np.real_if_close(y, tol=1e6).real
    # SciPy is optional: only a defective A (no eigenvector basis) needs its expm
    from scipy.linalg import expm
    return np.array([expm(a * (ti - t0)) @ y0 for ti in t])


EXACT = {
    "linear_growth": linear_growth,
    "decay": decay,
    "riccati": riccati,
    "beam_linear": beam_linear,
    "beam_nonlinear": beam_nonlinear,
    "damped_oscillator": damped_oscillator,
    "pendulum_linear": pendulum_linear,
    "pendulum": pendulum,
    "linear_system": linear_system,
}


def exact_solution(problem: str, t, t0, y0, params):
    """Exact solution at times t, or None where the problem has none."""
    fn = EXACT.get(problem)
    if fn is None:
        return None
    return fn(np.asarray(t, dtype=float), float(t0), np.asarray(y0, dtype=float), params)
