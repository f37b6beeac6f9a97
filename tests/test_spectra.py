"""Spectral radius, numerical damping and period error of every fixed-step method on M q'' + K q
= 0, measured from the kernel's compiled steps on scene runs (mbdk.spectral), against closed
forms; and the pendulum's free and constrained directions under the index-3 family.

Where the closed forms come from (mbdk.oscillator_forms, and restated here where a test types
its own):
- explicit_euler, heun, rk4: the stability function of an explicit Runge-Kutta method with s =
  p stages is the degree-s Taylor polynomial of exp(z) (Hairer and Wanner, Solving ODE II,
  IV.2); on the oscillator its roots are R(+-i Omega);
- implicit_euler (= bdf1), trapezoidal: 1/(1 - z) and (1 + z/2)/(1 - z/2), Pade approximants
  of exp (Hairer and Wanner II, IV.3); the trapezoidal rule's period error Omega / (2
  atan(Omega/2)) - 1 (Hughes, The Finite Element Method, 9.3);
- euler_cromer: v+ = v - h omega^2 q, q+ = q + h v+ (Cromer 1981; Fekete (2023) (4.31)-(4.32)),
  the matrix [[1 - Omega^2, 1], [-Omega^2, 1]] on (q, h v), derived from the scheme;
- bdf1..bdf6: rho(zeta) - i Omega sigma(zeta) with the backward-difference form
  sum_j (1/j) nabla^j y_{n+k} = h f_{n+k} (Hairer, Norsett and Wanner, Solving ODE I, III.1,
  (1.22')), whose expanded coefficients are checked here against the classical table (Gear
  1971; the same reference);
- the index-3 family: mbdk.alpha_family (Chung and Hulbert 1993; Hughes 9.3), and along a
  constraint alpha_family.constrained_amplification, derived from the family's relations with
  the constrained coordinate held (Chung and Hulbert's rho_inf at Omega -> oo; HHT's
  (1 + alpha)/(1 - alpha), Hilber, Hughes and Taylor 1977).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import mbdk
from mbdk import alpha_family as AF
from mbdk import oscillator_forms as OF
from mbdk import spectral

OMEGAS = [0.05, 0.5, 1.5, 3.0, 10.0]


def _close(measured, closed, rtol_radius=1e-10, atol=1e-9):
    """The radius to rtol_radius relative, damping ratio and period error to atol (both NaN:
    the principal root is real in both)."""
    rho, xi, pe = measured
    crho, cxi, cpe = closed
    ok = abs(rho - crho) <= rtol_radius * crho
    for a, b in ((xi, cxi), (pe, cpe)):
        ok &= (math.isnan(a) and math.isnan(b)) or abs(a - b) <= atol
    return ok


@pytest.mark.parametrize("method", OF.METHODS)
@pytest.mark.parametrize("omega_h", OMEGAS)
def test_ode_methods_compiled_steps_have_the_closed_form_spectrum(method, omega_h):
    """Spectral radius (relative 1e-10), damping ratio and period error (1e-9) of the kernel's
    scene runs equal the closed forms; the fitted roots are the closed form's as a set (to
    1e-7 of the radius from Omega = 0.5 on, where bdf5-6's spurious roots are well excited),
    and the recurrence fits the runs to roundoff."""
    s = spectral.measure(method, omega_h)
    cf = OF.closed_form_properties(method, omega_h)
    assert _close(s.properties, cf), (s.properties, cf)
    assert s.roots.size == 2 * mbdk.methods()[method].steps
    assert s.fit_residual < 1e-11
    if omega_h >= 0.5:
        assert s.root_distance <= 1e-7 * max(1.0, s.spectral_radius), s.root_distance
    assert s.cpu_time > 0 and s.steps > 0


def test_closed_forms_against_the_literature_typed_here():
    """The module's closed forms against formulas typed here: rk4's R(i Omega) = 1 + z + z^2/2
    + z^3/6 + z^4/24; Euler-Cromer's roots from its 2 x 2 matrix; the trapezoidal rule's period
    error; BDF's rho from the backward differences against the classical coefficient table
    (Hairer, Norsett and Wanner I, III.1: bdf3 11/6, -3, 3/2, -1/3, ...), and bdf2's principal
    root as the root of (3/2) zeta^2 - 2 zeta + 1/2 = i Omega zeta^2 nearest exp(i Omega)."""
    for w in (0.1, 1.0, 2.5):
        z = 1j * w
        r = 1 + z + z ** 2 / 2 + z ** 3 / 6 + z ** 4 / 24
        assert OF.closed_form_properties("rk4", w)[0] == pytest.approx(abs(r), rel=1e-14)
        ev = np.linalg.eigvals([[1 - w * w, 1.0], [-w * w, 1.0]])
        assert OF.closed_form_properties("euler_cromer", w)[0] == pytest.approx(
            np.abs(ev).max(), rel=1e-14)
        assert OF.closed_form_properties("trapezoidal", w)[2] == pytest.approx(
            w / (2 * math.atan(w / 2)) - 1, rel=1e-12)
    table = {3: [11 / 6, -3, 3 / 2, -1 / 3], 4: [25 / 12, -4, 3, -4 / 3, 1 / 4],
             5: [137 / 60, -5, 5, -10 / 3, 5 / 4, -1 / 5],
             6: [147 / 60, -6, 15 / 2, -20 / 3, 15 / 4, -6 / 5, 1 / 6]}
    for k, coef in table.items():
        assert np.allclose(OF.bdf_polynomials(k)[0], coef, rtol=0, atol=1e-14), k
    for w in (0.05, 0.7):
        roots = np.roots([1.5 - 1j * w, -2.0, 0.5])
        want = roots[np.argmin(np.abs(roots - np.exp(1j * w)))]
        assert OF.principal_roots("bdf2", w)[0] == pytest.approx(want, abs=1e-14)


def test_rk4_amplifies_beyond_two_sqrt_two():
    """|R(i Omega)|^2 = 1 + Omega^6 (Omega^2 - 8)/576 for rk4: the measured spectral radius is
    below 1 up to Omega = 2 sqrt 2 and above it beyond; bisection on measurements alone finds
    the crossing at 2 sqrt 2 to 1e-6."""
    crit = 2 * math.sqrt(2)
    for w in (0.5, 1.0, 2.0, 2.5, crit * (1 - 1e-3)):
        assert spectral.measure("rk4", w).spectral_radius < 1.0, w
    for w in (crit * (1 + 1e-3), 3.0, 5.0):
        assert spectral.measure("rk4", w).spectral_radius > 1.0, w
    lo, hi = 2.5, 3.0
    while hi - lo > 1e-7:
        mid = 0.5 * (lo + hi)
        if spectral.measure("rk4", mid).spectral_radius > 1.0:
            hi = mid
        else:
            lo = mid
    assert abs(lo - crit) < 1e-6


def test_euler_cromer_keeps_unit_radius_below_two():
    """Euler-Cromer's step has determinant 1: both roots on the unit circle, no numerical
    damping, up to Omega = 2; beyond it the roots are real and one amplifies."""
    for w in (0.01, 0.1, 0.5, 1.0, 1.5, 1.9, 1.99):
        s = spectral.measure("euler_cromer", w)
        assert abs(s.spectral_radius - 1.0) < 1e-12 and abs(s.damping_ratio) < 1e-12, w
    for w in (2.01, 3.0):
        s = spectral.measure("euler_cromer", w)
        assert s.spectral_radius > 1.2 and math.isnan(s.period_error), w


def test_bdf2_damps_at_every_omega_and_bdf3_does_not():
    """bdf2 is A-stable: its measured spectral radius on the undamped oscillator stays below 1
    for Omega from 1e-2 to 1e3 (where the closed form's 1 - rho is as small as 2.5e-9), while
    bdf3, not A-stable, amplifies the oscillator at Omega = 1 (radius 1.0436)."""
    for w in np.geomspace(1e-2, 1e3, 16):
        s = spectral.measure("bdf2", w)
        cf = OF.closed_form_properties("bdf2", w)[0]
        assert s.spectral_radius < 1.0 and abs(s.spectral_radius - cf) < 1e-12, w
    assert spectral.measure("bdf3", 1.0).spectral_radius > 1.04


def test_trapezoidal_keeps_radius_one_and_lags_by_omega_squared_over_twelve():
    """The trapezoidal rule (ODE form): radius 1 and no damping at every Omega; period error
    Omega/(2 atan(Omega/2)) - 1 = Omega^2/12 - Omega^4/180 + ..: measured / (Omega^2/12) - 1
    is below Omega^2/10 in size and negative."""
    for w in (0.01, 0.1, 1.0, 10.0):
        s = spectral.measure("trapezoidal", w)
        assert abs(s.spectral_radius - 1.0) < 1e-13 and abs(s.damping_ratio) < 1e-11, w
    for w in (0.01, 0.02, 0.05, 0.1):
        ratio = spectral.measure("trapezoidal", w).period_error / (w * w / 12) - 1
        assert -w * w / 10 < ratio < 0, (w, ratio)


def test_bdf6_reports_its_principal_root_beside_a_dominant_spurious_one():
    """Beyond Omega of about 1, a spurious root of bdf6 has the largest modulus: the spectral
    radius is that root's, the damping ratio and period error the principal root's (the root
    continued from exp(i Omega)), which is then not the largest."""
    s = spectral.measure("bdf6", 3.0)
    assert OF.dominant("bdf6", 3.0) == "spurious" and OF.dominant("bdf6", 0.5) == "principal"
    assert abs(s.principal) < s.spectral_radius - 0.5
    assert s.damping_ratio == pytest.approx(-math.log(abs(s.principal))
                                            / abs(np.angle(s.principal)), rel=1e-12)


def test_measure_refuses_what_it_cannot_measure():
    with pytest.raises(mbdk.NotApplicableError, match="fixed-step"):
        spectral.measure("dopri54", 0.5)
    with pytest.raises(mbdk.InvalidInputError, match="omega_h"):
        spectral.measure("rk4", -1.0)
    with pytest.raises(mbdk.NotApplicableError, match="index-3 family"):
        spectral.pendulum_free_direction("rk4", 0.5)


FAMILY = [("trapezoidal_index3", {}), ("newmark", {"newmark_beta": 0.3025, "newmark_gamma": 0.6}),
          ("hht", {"alpha_hht": -0.1}), ("hht", {"alpha_hht": -1.0 / 3.0}),
          ("generalized_alpha", {"rho_inf": 0.8}), ("generalized_alpha", {"rho_inf": 0.5}),
          ("generalized_alpha", {"rho_inf": 0.0})]


@pytest.mark.parametrize("method, opts", FAMILY)
@pytest.mark.parametrize("formulation", ["index3", "augmented_lagrangian"])
def test_pendulum_free_direction_has_the_oscillators_spectrum(method, opts, formulation):
    """The pendulum's free direction (a swing of 1e-6 rad) at Omega = sqrt(g/l) h has the
    oscillator's closed-form spectral radius, damping ratio and period error to 1e-9 (its
    nonlinearity and roundoff are about 1e-10 there): the constraint does not change them."""
    p = AF.parameters(method, **opts)
    for w in (0.1, 1.0, 3.0):
        s = spectral.pendulum_free_direction(method, w, formulation=formulation, **opts)
        cf = AF.closed_form_properties(p, w)
        assert np.allclose(s.properties, cf, rtol=0, atol=1e-9), (w, s.properties, cf)


@pytest.mark.parametrize("method, opts", FAMILY[:5])
@pytest.mark.parametrize("formulation", ["index3", "augmented_lagrangian"])
def test_pendulum_multiplier_oscillates_with_the_free_directions_damping(method, opts,
                                                                         formulation):
    """The multiplier's oscillation on a swing of 1e-3 rad (its part quadratic in the motion,
    at twice the frequency) has the root lambda_p^2: the free direction's damping ratio and
    period error (closed form) to 2e-5, against the exact 2 omega. Its other roots: the static
    1 and, in the book form of the damped members, the constrained direction's transient."""
    p = AF.parameters(method, **opts)
    w = 1.0
    free = spectral.pendulum_free_direction(method, w, formulation=formulation, **opts)
    ml = spectral.pendulum_multiplier(method, w, free.principal, formulation=formulation,
                                      **opts)
    _, xi, pe = AF.closed_form_properties(p, w)
    assert abs(ml.damping_ratio - xi) < 2e-5 and abs(ml.period_error - pe) < 2e-5, (ml, xi, pe)
    assert np.min(np.abs(ml.roots - 1.0)) < 1e-6


def test_constrained_amplification_matches_the_published_limits():
    """Along a constraint (the relations with the coordinate held): Chung and Hulbert's members
    have all three roots at -rho_inf; HHT has (1 + alpha)/(1 - alpha) twice (its published
    high-frequency radius) and alpha/(1 + alpha); the trapezoidal rule -1 twice with a single
    eigenvector (a linearly growing transient); generalized-alpha at rho_inf = 1 shows -1 twice
    from a consistent start."""
    for r in (0.0, 0.3, 0.8):
        ev = np.linalg.eigvals(AF.constrained_amplification(AF.parameters("generalized_alpha",
                                                                          rho_inf=r)))
        assert np.allclose(ev, -r, atol=1e-5), (r, ev)     # a triple root: to eps^(1/3)
        assert np.allclose(np.poly(ev), np.poly([-r] * 3), atol=1e-12)
    for a in (-0.1, -0.3):
        p = AF.parameters("hht", alpha_hht=a)
        want = [-(1 + a) / (1 - a)] * 2 + [a / (1 + a)]
        assert np.allclose(np.sort(AF.constrained_roots(p).real), np.sort(want), atol=1e-7)
        assert np.allclose(AF.constrained_polynomial(p), np.poly(want), atol=1e-12)
    t = AF.constrained_amplification(AF.parameters("trapezoidal_index3"))
    assert np.allclose(AF.constrained_roots(AF.parameters("trapezoidal_index3")), -1.0)
    assert np.linalg.matrix_rank(t + np.eye(3)) == 2       # -1 twice, one eigenvector
    assert np.allclose(AF.constrained_polynomial(AF.parameters("generalized_alpha",
                                                               rho_inf=1.0)), [1, 2, 1])


@pytest.mark.parametrize("method, opts", FAMILY + [("generalized_alpha", {"rho_inf": 1.0})])
def test_pendulum_constrained_direction_carries_the_closed_form_transient(method, opts):
    """The bob hangs at rest and the rod's length is driven: in the book form (index3) the
    multiplier's transient along the rod has the polynomial of alpha_family.constrained_roots
    (coefficients to 1e-7; the fit resolves the drive's own factor to 1e-10), so its spectral
    radius is the closed form's (to 1e-3: a triple root moves by the cube root of the
    coefficients' error); the projected form carries no transient at all."""
    p = AF.parameters(method, **opts)
    c = spectral.pendulum_constrained_direction(method, formulation="index3", **opts)
    want = AF.constrained_polynomial(p)
    assert c.quotient.size == want.size, (c.roots, AF.constrained_roots(p))
    assert np.abs(c.quotient - want).max() < 1e-7 and c.remainder < 1e-10
    rho = float(np.abs(AF.constrained_roots(p)).max()) if want.size > 1 else 0.0
    assert abs(c.spectral_radius - rho) < 1e-3
    c = spectral.pendulum_constrained_direction(method, formulation="augmented_lagrangian",
                                                **opts)
    assert c.roots.size == 0 and c.remainder < 1e-10


def test_a_run_with_substep_retries_is_not_measured():
    """A Newton limit of three iterations fails steps of the projected form at Omega = 3, which
    are retried in substeps: the samples no longer follow one step's map, and the measurement
    says so by name instead of fitting them (with the default limit it measures them)."""
    kw = dict(rho_inf=0.8, formulation="augmented_lagrangian")
    with pytest.raises(mbdk.NotApplicableError, match="substeps"):
        spectral.pendulum_free_direction("generalized_alpha", 3.0, max_iter=3, **kw)
    assert spectral.pendulum_free_direction("generalized_alpha", 3.0, **kw).steps == 32
