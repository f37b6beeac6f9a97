"""The compiled problems against independent formulas: the book's closed forms as printed
((3.64), (4.78)), a Lagrange derivation of the consistent trolley crane, energy conservation, and
the exact solutions (mbdk.exact) against the ODEs they solve."""
import math

import numpy as np
import pytest

import mbdk

rng = np.random.default_rng(20231)


def book_3_64(y, m1, m2, l1, l2, g):
    """(3.64) exactly as printed."""
    p1, p2, w1, w2 = y
    d = p1 - p2
    den = 8 * m1 + 15 * m2 - 9 * m2 * math.cos(2 * d)
    a1 = (-9 * m2 * l1 * math.sin(2 * d) * w1**2 - 12 * m2 * l2 * math.sin(d) * w2**2
          + 9 * m2 * g * math.cos(p1 - 2 * p2) - g * math.cos(p1) * (12 * m1 + 15 * m2)) / (l1 * den)
    a2 = (-g * math.cos(p2) * (3 * m1 + 18 * m2) + g * math.cos(2 * p1 - p2) * (9 * m1 + 18 * m2)
          + 9 * m2 * l2 * math.sin(2 * d) * w2**2
          + w1**2 * l1 * math.sin(d) * (12 * m1 + 36 * m2)) / (l2 * den)
    return np.array([w1, w2, a1, a2])


def book_4_78(y, m1, m2, l, g, k, s):
    """(4.78) exactly as printed."""
    x, p, v, w = y
    d = 4 * m1 + m2 + 3 * m2 * math.cos(p) ** 2
    a = (-2 * m2 * l * math.cos(p) * w**2 - 4 * k * v - 4 * s * x
         + 1.5 * m2 * g * math.sin(2 * p)) / d
    b = (3 * m2 * l * math.cos(p) * math.sin(p) * w**2 + 6 * math.sin(p) * (s * x + k * v)
         - 6 * g * math.cos(p) * (m1 + m2)) / (l * d)
    return np.array([v, w, a, b])


def lagrange_crane(y, m1, m2, l, g, k, s):
    """Trolley m1 at x on spring s and damper k; uniform bar (m2, l) hinged at the trolley,
    centre at (x + l/2 cos p, l/2 sin p). T = (m1+m2) v^2/2 - m2 l/2 sin(p) v w + m2 l^2 w^2/6,
    V = s x^2/2 + m2 g l/2 sin(p); Lagrange's equations solved for (x'', p'')."""
    x, p, v, w = y
    a = m2 * l / 2
    mm = np.array([[m1 + m2, -a * math.sin(p)], [-a * math.sin(p), m2 * l**2 / 3]])
    rhs = np.array([a * math.cos(p) * w**2 - s * x - k * v, -a * g * math.cos(p)])
    return np.concatenate([[v, w], np.linalg.solve(mm, rhs)])


def test_double_pendulum_is_the_books_3_64():
    for _ in range(20):
        y = rng.normal(size=4) * [2, 2, 3, 3]
        p = dict(m1=rng.uniform(0.5, 3), m2=rng.uniform(0.5, 3), l1=rng.uniform(0.5, 2),
                 l2=rng.uniform(0.5, 2), g=9.81)
        got = mbdk.evaluate_rhs("double_pendulum", 0.0, y, p)
        assert np.allclose(got, book_3_64(y, **p), rtol=1e-11, atol=1e-11)


def test_trolley_crane_default_is_the_books_4_78():
    p = dict(m1=10.0, m2=1.0, l=1.0, g=9.81, k=50.0, s=3000.0)
    for _ in range(20):
        y = rng.normal(size=4) * [0.5, 2, 1, 3]
        got = mbdk.evaluate_rhs("trolley_crane", 0.0, y)
        assert np.allclose(got, book_4_78(y, **p), rtol=1e-12, atol=1e-10)


def test_trolley_crane_coupling_plus_one_is_the_lagrange_derivation():
    p = dict(m1=10.0, m2=1.0, l=1.0, g=9.81, k=50.0, s=3000.0)
    for _ in range(20):
        y = rng.normal(size=4) * [0.5, 2, 1, 3]
        got = mbdk.evaluate_rhs("trolley_crane", 0.0, y, {"coupling": 1.0})
        assert np.allclose(got, lagrange_crane(y, **p), rtol=1e-12, atol=1e-10)
        # and the book's equation is not that mechanism
    y = np.array([0.5, -math.pi / 6, 0.0, 0.0])
    assert not np.allclose(book_4_78(y, **p), lagrange_crane(y, **p))


@pytest.mark.parametrize("problem,params", [
    ("trolley_crane", {"k": 0.0, "coupling": -1.0}), ("trolley_crane", {"k": 0.0, "coupling": 1.0}),
    ("double_pendulum", None), ("pendulum", None), ("damped_oscillator", {"c": 0.0}),
])
def test_energy_is_conserved_without_damping(problem, params):
    """With no damping the mechanical energy is a first integral; rk4 at a small step must keep
    it to 1e-8 of its scale (rk4's energy error ~ h^4)."""
    r = mbdk.solve_ode(problem, "rk4", h=1e-4, t_end=2.0, params=params, every=100)
    e = r.energy()
    scale = max(np.ptp(e), abs(e[0]), 1.0)
    assert np.max(np.abs(e - e[0])) / scale < 1e-8


@pytest.mark.parametrize("problem", sorted(mbdk.exact.EXACT))
def test_exact_solutions_solve_their_odes(problem):
    info = mbdk.problems()[problem]
    y0 = np.array(info.y0, dtype=float)
    params = dict(info.params)
    t_end = min(info.t_end, 2.0) if problem not in ("beam_linear", "beam_nonlinear") else 1000.0
    t = np.linspace(0.0, t_end, 41)[1:-1]
    ex = mbdk.exact.exact_solution(problem, np.concatenate([[0.0], t]), 0.0, y0, params)
    assert np.allclose(ex[0], y0, atol=1e-12)
    dt = t_end * 1e-5
    plus = mbdk.exact.exact_solution(problem, t + dt, 0.0, y0, params)
    minus = mbdk.exact.exact_solution(problem, t - dt, 0.0, y0, params)
    deriv = (plus - minus) / (2 * dt)
    for i, ti in enumerate(t):
        f = mbdk.evaluate_rhs(problem, ti, ex[i + 1], params)
        scale = np.max(np.abs(f)) + 1e-12
        assert np.max(np.abs(deriv[i] - f)) / scale < 1e-6, (problem, ti)


def test_pendulum_exact_solution_against_scipy_quadrature_period():
    """The elliptic solution's period equals 4 * integral_0^phi0 dphi / sqrt(2 w^2 (cos phi -
    cos phi0)), computed by scipy's quad (an independent formula)."""
    from scipy.integrate import quad
    w2 = 1.5 * 9.81
    phi0 = math.radians(60)
    th = lambda u: phi0 * math.sin(u)  # noqa: E731  substitution removing the endpoint singularity
    period = 4 * quad(lambda u: phi0 * math.cos(u) / math.sqrt(2 * w2 * (math.cos(th(u)) - math.cos(phi0))),
                      0, math.pi / 2)[0]
    t = np.array([0.0, period])
    ex = mbdk.exact.pendulum(t, 0.0, [phi0, 0.0], {"g": 9.81, "l": 1.0})
    assert ex[1, 0] == pytest.approx(phi0, abs=1e-9)
    assert ex[1, 1] == pytest.approx(0.0, abs=1e-8)


def test_nonlinear_beam_exact_solution_refuses_past_vertical():
    """s = -(F/EI)(l x - x^2/2) reaches -1 for F/EI = 2e-6 at x = 1000 - sqrt(1e6 - 1e6) = 1000."""
    with pytest.raises(mbdk.InvalidInputError, match="no solution past x"):
        mbdk.exact.beam_nonlinear(np.linspace(0, 1000, 11), 0.0, [0.0],
                                  {"F": 2.0, "EI": 1.0e6, "l": 1000.0})
