"""Spectral radius, numerical damping and period error of a compiled integrator, measured on the
undamped oscillator q'' = -omega^2 q from the kernel's own steps, and compared with the closed
forms of mbdk.alpha_family (Hughes, "The Finite Element Method", 9.3; Chung and Hulbert 1993).

The oscillator is a scene: one planar body on a coordinate spring along x (stiffness k = omega^2
m, rest 0, no gravity), released from x = X0 (and, for the second sequence, pushed with
v = omega X0 from x = 0). Its run at h = Omega / omega gives the samples x_n, v_n of every step;
a linear one-step method maps its state by a constant matrix A, so x_n and v_n obey the linear
recurrence of A's characteristic polynomial. Its coefficients, fitted by least squares to both
sequences (Prony's method; the order is the rank of the data, 2 for the members whose
pseudo-acceleration is the acceleration, 3 for the generalized-alpha members), give A's
eigenvalues: the spectral radius is the largest magnitude, the principal root lambda =
exp(Omega_bar (-xi + i)) the damping ratio xi = -ln|lambda| / arg(lambda) and the relative
period error Omega / arg(lambda) - 1.
"""
from __future__ import annotations

import numpy as np

from .alpha_family import properties_from_roots
from .scene_file import scene_from_dict
from .simulate import simulate

#: the release amplitude (m): small beside the body's size, large beside roundoff
X0 = 1e-3
#: the steps fitted (the sequences decay as rho^n: a few steps hold the information)
NSTEPS = 12


def oscillator(v0: float = 0.0, x0: float = X0, omega: float = 1.0):
    """One body (1 kg) on a coordinate spring k = omega^2 along x, free in y and angle."""
    return scene_from_dict({
        "scene": {"name": "oscillator", "description": "q'' = -omega^2 q: a body on a "
                  "coordinate spring (mbdk.spectral)"},
        "body": [{"name": "mass", "mass": 1.0, "shape": {"type": "disc", "radius": 0.1},
                  "x": x0, "y": 0.0, "vx": v0}],
        "force": [{"name": "spring", "type": "coordinate_spring", "body": "mass",
                   "coordinate": "x", "stiffness": omega * omega, "rest": 0.0}]})


def _sequences(method: str, omega_h: float, nsteps: int,
               options: dict) -> tuple[list[np.ndarray], float]:
    """The two runs' x_n and v_n (in units of X0), and their CPU time per step."""
    out, cpu, steps = [], 0.0, 0
    for sc in (oscillator(), oscillator(v0=X0, x0=0.0)):
        r = simulate(sc, method, h=omega_h, t_end=nsteps * omega_h, every=1, outputs=(),
                     watch=False, **options)
        out += [r.q[:, 0] / X0, r.v[:, 0] / X0]
        cpu += r.stats.cpu_time
        steps += r.stats.steps
    return out, cpu / max(steps, 1)


def fit_roots(seqs: list[np.ndarray], max_order: int = 3, rtol: float = 1e-9) -> np.ndarray:
    """The roots of the shortest linear recurrence that all sequences obey (Prony): the order
    is the numerical rank of their stacked Hankel rows, at most max_order."""
    def rows(order):
        a, b = [], []
        for s in seqs:
            for n in range(len(s) - order):
                a.append(s[n:n + order])
                b.append(s[n + order])
        return np.array(a), np.array(b)
    a, _ = rows(max_order + 1)
    sv = np.linalg.svd(a, compute_uv=False)
    order = max(1, min(max_order, int(np.sum(sv > rtol * sv[0]))))
    a, b = rows(order)
    c, *_ = np.linalg.lstsq(a, b, rcond=None)
    # s[n + p] = sum c_k s[n + k]: roots of z^p - c_{p-1} z^{p-1} - ... - c_0
    return np.roots(np.concatenate([[1.0], -c[::-1]]))


def measured_properties(method: str, omega_h: float, nsteps: int = NSTEPS,
                        **options) -> tuple[float, float, float, float]:
    """(spectral radius, damping ratio, period error, the solving thread's CPU seconds per
    step) of the compiled method at Omega = omega_h, from its steps on the oscillator."""
    seqs, cpu = _sequences(method, omega_h, nsteps, options)
    roots = fit_roots(seqs)
    rho, xi, pe = properties_from_roots(roots, omega_h)
    return rho, xi, pe, cpu
