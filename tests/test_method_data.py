"""The methods' data in the kernel (Butcher tables, multistep coefficients) satisfy the order
conditions of their nominal order, and the multistep methods are zero-stable.

Order conditions: Hairer-Norsett-Wanner I, II.2 (Butcher trees up to order 4) and III.2
(linear multistep: sum_j alpha_j (1-j)^q = q sum_j beta_j (1-j)^(q-1), q = 0..p)."""
import numpy as np
import pytest

import mbdk
from mbdk import _kernel


def tableau(name):
    a, b, c, s, order, ok = _kernel.butcher_tableau(mbdk.methods()[name].id)
    assert ok == 1
    return a[:s, :s], b[:s], c[:s], order


@pytest.mark.parametrize("name,p", [("explicit_euler", 1), ("heun", 2), ("rk4", 4)])
def test_butcher_order_conditions(name, p):
    a, b, c, order = tableau(name)
    assert order == p
    assert np.allclose(a.sum(axis=1), c)              # row-sum condition
    conds = [(1, b.sum(), 1.0)]
    if p >= 2:
        conds.append((2, b @ c, 1 / 2))
    if p >= 3:
        conds += [(3, b @ c**2, 1 / 3), (3, b @ a @ c, 1 / 6)]
    if p >= 4:
        conds += [(4, b @ c**3, 1 / 4), (4, (b * c) @ a @ c, 1 / 8), (4, b @ a @ c**2, 1 / 12),
                  (4, b @ a @ a @ c, 1 / 24)]
    for _q, got, want in conds:
        assert got == pytest.approx(want, abs=1e-15)
    # and the next order fails (the order is exactly p)
    if p == 1:
        assert b @ c != pytest.approx(0.5)
    if p == 2:
        assert b @ c**2 != pytest.approx(1 / 3)
    if p == 4:
        assert b @ c**4 != pytest.approx(1 / 5)


LMM = ["implicit_euler", "trapezoidal", "bdf1", "bdf2", "bdf3", "bdf4", "bdf5", "bdf6"]


def coefficients(name):
    alpha, beta0, beta1, k, order, ok = _kernel.lmm_coefficients(mbdk.methods()[name].id)
    assert ok == 1
    beta = np.zeros(k + 1)
    beta[0], beta[1] = beta0, beta1 if k >= 1 else 0.0
    return alpha[: k + 1], beta, k, order


@pytest.mark.parametrize("name", LMM)
def test_multistep_order_conditions(name):
    alpha, beta, k, order = coefficients(name)
    j = np.arange(k + 1)
    x = 1.0 - j                                   # y_{n+1-j} at times (1 - j) h
    for q in range(order + 1):
        lhs = np.sum(alpha * x**q)
        rhs = q * np.sum(beta * x ** max(q - 1, 0)) if q > 0 else 0.0
        scale = np.sum(np.abs(alpha * x**q)) + 1.0
        assert lhs == pytest.approx(rhs, abs=1e-14 * scale), f"{name}: condition q={q}"
    q = order + 1
    assert np.sum(alpha * x**q) != pytest.approx(q * np.sum(beta * x ** (q - 1)), abs=1e-9)


def test_bdf4_is_the_books_gear_formula():
    """(4.80): y_{i+1} = (48 y_i - 36 y_{i-1} + 16 y_{i-2} - 3 y_{i-3} + 12 h f_{i+1}) / 25."""
    alpha, beta, k, _ = coefficients("bdf4")
    assert k == 4
    assert np.allclose(-alpha[1:] * 25, [48, -36, 16, -3])
    assert beta[0] * 25 == pytest.approx(12)


@pytest.mark.parametrize("name", LMM)
def test_zero_stability(name):
    """Roots of rho(z) = sum_j alpha_j z^(k-j): |z| <= 1, the root 1 simple."""
    alpha, _beta, _k, _ = coefficients(name)
    roots = np.roots(alpha)
    assert np.all(np.abs(roots) <= 1 + 1e-9)
    assert np.sum(np.abs(roots - 1) < 1e-6) == 1
