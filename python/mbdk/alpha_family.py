"""The generalized-alpha family of index-3 integrators: parameters from a method's name and
options, and the family's closed-form amplification on the undamped oscillator.

One stepping routine integrates every member (kernel/src/dae/mbdk_trapezoidal_index3.f90, whose
header is the manual: Chung and Hulbert (1993) in the form of Arnold and Bruls (2007), with a
pseudo-acceleration ap)::

    dq  = h v + h^2 (1/2 - beta) ap + h^2 beta ap+
    v+  = v + h (1 - gamma) ap + h gamma ap+
    (1 - alpha_m) ap+ + alpha_m ap = (1 - alpha_f) a+ + alpha_f a

and the members differ only in (beta, gamma, alpha_m, alpha_f)::

    trapezoidal_index3   1/4, 1/2, 0, 0
    newmark              newmark_beta, newmark_gamma (default 1/4, 1/2), 0, 0
    hht                  alpha_hht in [-1/3, 0] (default -0.05): (1 - alpha)^2 / 4,
                         1/2 - alpha, 0, -alpha
    generalized_alpha    rho_inf in [0, 1] (default 0.8): alpha_m = (2 rho - 1) / (rho + 1),
                         alpha_f = rho / (rho + 1), gamma = 1/2 - alpha_m + alpha_f,
                         beta = (1 - alpha_m + alpha_f)^2 / 4; or the four given directly

`amplification(params, omega_h)` is the one-step map of (q, h v, h^2 ap) on q'' = -omega^2 q,
solved from the three relations above with a = -omega^2 q (the equations of motion at each
step's end): an independent computation of what the compiled step does, against which
mbdk.spectral measures the kernel's steps. Its eigenvalues give the spectral radius, the
numerical damping ratio and the relative period error (Hughes, "The Finite Element Method",
9.3; Chung and Hulbert 1993, section 3).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InvalidInputError

#: the members and the options of simulate each takes (newmark_beta and newmark_gamma: simulate's
#: beta and alpha are Baumgarte's)
MEMBERS = {"trapezoidal_index3": (), "newmark": ("newmark_beta", "newmark_gamma"),
           "hht": ("alpha_hht",),
           "generalized_alpha": ("rho_inf", "newmark_beta", "newmark_gamma", "alpha_m",
                                 "alpha_f")}
#: every option of the family, as simulate names them
OPTIONS = ("rho_inf", "alpha_hht", "newmark_beta", "newmark_gamma", "alpha_m", "alpha_f")


@dataclass(frozen=True)
class AlphaParameters:
    """(beta, gamma, alpha_m, alpha_f) of one member, and how they were asked for."""

    beta: float = 0.25
    gamma: float = 0.5
    alpha_m: float = 0.0
    alpha_f: float = 0.0
    spec: str = "trapezoidal rule"

    def as_options(self) -> dict:
        """The fields of mbdk_index3_options."""
        return {"beta": self.beta, "gamma": self.gamma, "alpha_m": self.alpha_m,
                "alpha_f": self.alpha_f}

    @property
    def second_order(self) -> bool:
        """gamma = 1/2 - alpha_m + alpha_f (to roundoff): second order in q and v."""
        return abs(self.gamma - (0.5 - self.alpha_m + self.alpha_f)) <= 1e-12


def _real(name: str, value, method: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
        raise InvalidInputError(f"{name} = {value!r}: {method} takes a real number")
    x = float(value)
    if not math.isfinite(x):
        raise InvalidInputError(f"{name} = {value!r}: {method} takes a finite number")
    return x


def generalized_alpha_from_rho(rho_inf: float) -> AlphaParameters:
    """Chung and Hulbert's optimal parameters for a spectral radius rho_inf at Omega -> inf."""
    rho = rho_inf
    am = (2.0 * rho - 1.0) / (rho + 1.0)
    af = rho / (rho + 1.0)
    return AlphaParameters(beta=0.25 * (1.0 - am + af) ** 2, gamma=0.5 - am + af, alpha_m=am,
                           alpha_f=af, spec=f"rho_inf = {rho_inf:g}")


def parameters(method: str, rho_inf=None, alpha_hht=None, newmark_beta=None,
               newmark_gamma=None, alpha_m=None, alpha_f=None) -> AlphaParameters:
    """The member's parameters from its options (None: not given), checked; a bad value or an
    option the member does not take is an InvalidInputError naming it and what to give."""
    given = {k: v for k, v in dict(rho_inf=rho_inf, alpha_hht=alpha_hht, beta=newmark_beta,
                                   gamma=newmark_gamma, alpha_m=alpha_m,
                                   alpha_f=alpha_f).items() if v is not None}
    if method not in MEMBERS:
        raise InvalidInputError(f"{method!r} is not a method of the generalized-alpha family "
                                f"({', '.join(MEMBERS)})")
    named = {"beta": "newmark_beta", "gamma": "newmark_gamma"}
    extra = sorted(named.get(k, k) for k in set(given)
                   if named.get(k, k) not in MEMBERS[method])
    if extra:
        takes = ", ".join(MEMBERS[method]) or "none of these"
        raise InvalidInputError(f"{', '.join(extra)}: not options of {method} (it takes "
                                f"{takes})")
    vals = {k: _real(named.get(k, k), v, method) for k, v in given.items()}
    if method == "trapezoidal_index3":
        return AlphaParameters()
    if method == "newmark":
        b = vals.get("beta", 0.25)
        g = vals.get("gamma", 0.5)
        if not (g >= 0.5 and b >= 0.5 * g):
            raise InvalidInputError(f"newmark with newmark_beta = {b:g}, newmark_gamma = {g:g}: "
                                    "give 2 newmark_beta >= newmark_gamma >= 1/2, where Newmark's "
                                    "rule is unconditionally stable (gamma < 1/2 amplifies every "
                                    "mode; 2 beta < gamma amplifies the high frequencies)")
        return AlphaParameters(beta=b, gamma=g, spec=f"beta = {b:g}, gamma = {g:g}")
    if method == "hht":
        a = vals.get("alpha_hht", -0.05)
        if not -1.0 / 3.0 <= a <= 0.0:
            raise InvalidInputError(f"hht with alpha_hht = {a:g}: give alpha_hht in [-1/3, 0] "
                                    "(0 is the trapezoidal rule, -1/3 the most damping)")
        return AlphaParameters(beta=0.25 * (1.0 - a) ** 2, gamma=0.5 - a, alpha_m=0.0,
                               alpha_f=-a, spec=f"alpha = {a:g}")
    direct = [named.get(k, k) for k in ("beta", "gamma", "alpha_m", "alpha_f") if k in vals]
    if "rho_inf" in vals and direct:
        raise InvalidInputError(f"generalized_alpha: give rho_inf or {', '.join(direct)}, not "
                                "both")
    if direct:
        if len(direct) != 4:
            missing = sorted({"newmark_beta", "newmark_gamma", "alpha_m", "alpha_f"}
                             - set(direct))
            raise InvalidInputError(f"generalized_alpha given {', '.join(direct)}: give all "
                                    f"four parameters (missing {', '.join(missing)}), or "
                                    "rho_inf alone")
        p = AlphaParameters(beta=vals["beta"], gamma=vals["gamma"], alpha_m=vals["alpha_m"],
                            alpha_f=vals["alpha_f"], spec="given")
        if not stable(p):
            raise InvalidInputError(f"generalized_alpha with newmark_beta = {p.beta:g}, "
                                    f"newmark_gamma = {p.gamma:g}, alpha_m = {p.alpha_m:g}, "
                                    f"alpha_f = {p.alpha_f:g}: outside the unconditionally "
                                    "stable set alpha_m <= alpha_f <= 1/2, newmark_gamma >= "
                                    "1/2 - alpha_m + alpha_f, 2 newmark_beta >= newmark_gamma "
                                    "(Chung and Hulbert 1993); or give rho_inf alone")
        return p
    rho = vals.get("rho_inf", 0.8)
    if not 0.0 <= rho <= 1.0:
        raise InvalidInputError(f"generalized_alpha with rho_inf = {rho:g}: give rho_inf in "
                                "[0, 1] (1: no numerical damping, 0: the most)")
    return generalized_alpha_from_rho(rho)


def stable(p: AlphaParameters) -> bool:
    """Whether the parameters lie in the family's unconditionally stable set: alpha_m <=
    alpha_f <= 1/2, gamma >= 1/2 - alpha_m + alpha_f, 2 beta >= gamma (Chung and Hulbert 1993
    for gamma at its second-order value; Newmark's 2 beta >= gamma >= 1/2 for the alphas 0).
    Every member that `parameters` builds from rho_inf or alpha_hht lies in it."""
    return (p.alpha_m <= p.alpha_f <= 0.5 and p.gamma >= 0.5 - p.alpha_m + p.alpha_f - 1e-14
            and 2.0 * p.beta >= p.gamma - 1e-14)


def amplification(p: AlphaParameters, omega_h: float) -> np.ndarray:
    """The one-step map of x = (q, h v, h^2 ap) on q'' = -omega^2 q at Omega = omega h (3 x 3),
    from the family's relations with a = -Omega^2 q / h^2 at both ends of the step."""
    w2 = omega_h * omega_h
    b, g, am, af = p.beta, p.gamma, p.alpha_m, p.alpha_f
    # unknowns (q+, hv+, h2ap+); the relations, all times h^0 after scaling by powers of h:
    #   q+ - b h2ap+                               = q + hv + (1/2 - b) h2ap
    #   hv+ - g h2ap+                              = hv + (1 - g) h2ap
    #   (1 - am) h2ap+ + (1 - af) w2 q+            = -am h2ap - af w2 q
    lhs = np.array([[1.0, 0.0, -b], [0.0, 1.0, -g], [(1.0 - af) * w2, 0.0, 1.0 - am]])
    rhs = np.array([[1.0, 1.0, 0.5 - b], [0.0, 1.0, 1.0 - g], [-af * w2, 0.0, -am]])
    return np.linalg.solve(lhs, rhs)


def properties_from_roots(roots, omega_h: float) -> tuple[float, float, float]:
    """(spectral radius, damping ratio, relative period error) from a step's eigenvalues:
    the principal root is the one nearest exp(i Omega) in the upper half plane, lambda =
    exp(Omega_bar (-xi_bar + i)); xi_bar = -ln|lambda| / arg(lambda), period error
    Omega / arg(lambda) - 1 (NaN where no root is complex: the method has lost the
    oscillation)."""
    roots = np.asarray(roots, dtype=complex)
    rho = float(np.abs(roots).max())
    upper = roots[roots.imag > 1e-14 * np.abs(roots).clip(min=1e-300)]
    if upper.size == 0:
        return rho, math.nan, math.nan
    lam = upper[np.argmin(np.abs(upper - np.exp(1j * omega_h)))]
    arg = math.atan2(lam.imag, lam.real)
    xi = -math.log(abs(lam)) / arg
    return rho, xi, omega_h / arg - 1.0


def closed_form_properties(p: AlphaParameters, omega_h: float) -> tuple[float, float, float]:
    """Spectral radius, damping ratio and period error of the member at Omega = omega h, from
    the eigenvalues of `amplification` (for ap = a members the third eigenvalue is the
    spurious 0 of a state that does not exist)."""
    a = amplification(p, omega_h)
    roots = np.linalg.eigvals(a)
    if p.alpha_m == 0.0 and p.alpha_f == 0.0:
        # ap = a = -Omega^2 q / h^2: the map on (q, hv) alone; its third root is 0
        roots = roots[np.argsort(-np.abs(roots))][:2]
    return properties_from_roots(roots, omega_h)


def constrained_amplification(p: AlphaParameters) -> np.ndarray:
    """The step's map of x = (h v, h^2 ap, h^2 a) along a constrained direction (3 x 3): the
    book form (formulation index3) solves Phi(q+) = 0 with q+, so along the constraint's normal
    the step's increment is the one the constraint prescribes, and the relations above become,
    with that increment zero (what a prescribed motion adds is a forcing, not a root),
        h^2 beta ap+ = -(h v + h^2 (1/2 - beta) ap),   h v+ = h v + h^2 ((1 - gamma) ap + gamma ap+),
        (1 - alpha_f) h^2 a+ = (1 - alpha_m) h^2 ap+ + alpha_m h^2 ap - alpha_f h^2 a,
    the multiplier following a+ (M a+ + C^T lambda+ = f). Its eigenvalues: the roots of
    z^2 - (2 - (gamma + 1/2)/beta) z + (1/2 + beta - gamma)/beta (from the first two) and
    -alpha_f / (1 - alpha_f). For Chung and Hulbert's members all three are -rho_inf, HHT's are
    (1 + alpha)/(1 - alpha) twice and alpha/(1 + alpha), and the trapezoidal rule's -1 twice
    with one eigenvector: a transient that grows linearly, the weak instability of the book's
    index-3 scheme (Cardona and Geradin 1989). It is the family's amplification at Omega -> oo
    with q held: a constraint is an infinitely stiff spring whose position the step keeps.
    The projected form (augmented_lagrangian) projects v+ and a+ onto the constraints and
    takes lambda+ with them, so it carries nothing along a constraint: no root."""
    b, g, am, af = p.beta, p.gamma, p.alpha_m, p.alpha_f
    ap_next = np.array([-1.0 / b, -(0.5 - b) / b, 0.0])
    v_next = np.array([1.0, 1.0 - g, 0.0]) + g * ap_next
    a_next = ((1.0 - am) * ap_next + np.array([0.0, am, -af])) / (1.0 - af)
    return np.array([v_next, ap_next, a_next])


def constrained_roots(p: AlphaParameters) -> np.ndarray:
    """The roots of the multiplier's transient along a constraint from a consistent start (ap
    = a): the nonzero eigenvalues of constrained_amplification (a zero one dies within the
    first steps and leaves no rate to measure), less -alpha_f / (1 - alpha_f) where alpha_m =
    alpha_f: there it is the rate of ap - a alone ((1 - alpha)(ap+ - a+) + alpha (ap - a) = 0),
    which a consistent start never excites (generalized_alpha at rho_inf = 1)."""
    ev = np.linalg.eigvals(constrained_amplification(p))
    ev = ev[np.abs(ev) > 1e-12]
    if p.alpha_m == p.alpha_f and p.alpha_f != 0.0 and ev.size:
        k = np.argmin(np.abs(ev + p.alpha_f / (1.0 - p.alpha_f)))
        ev = np.delete(ev, k)
    return ev


def constrained_polynomial(p: AlphaParameters) -> np.ndarray:
    """The monic polynomial (numpy's order) of constrained_roots, real: [1.0] where there is
    none."""
    r = constrained_roots(p)
    return np.real(np.poly(r)) if r.size else np.array([1.0])
