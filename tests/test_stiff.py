"""Stiffness: y' = -1000 y, y(0) = 1 at h = 0.01 (h*lambda = -10).

Explicit methods' amplification factors at z = -10 are |1 + z| = 9 (Euler), |1 + z + z^2/2| = 41
(Heun), |R_4(z)| = 291 (RK4): each exceeds 1, so the solution must overflow. The implicit methods
are A-stable (implicit Euler, trapezoidal, bdf1-2) or A(alpha)-stable with the negative real axis
inside (bdf3-6), so the solution must stay bounded by |y0| and decay.
"""
import numpy as np
import pytest

import mbdk

STIFF = dict(h=0.01, t_end=10.0, params={"lambda": 1000.0})


@pytest.mark.parametrize("method", ["explicit_euler", "heun", "rk4"])
def test_explicit_methods_blow_up(method):
    with pytest.raises(mbdk.NonFiniteSolutionError) as exc:
        mbdk.solve_ode("decay", method, **STIFF)
    partial = exc.value.result
    assert partial is not None and not partial.success
    assert partial.t[-1] < 10.0 and np.all(np.isfinite(partial.y))


@pytest.mark.parametrize("method", ["implicit_euler", "trapezoidal", "bdf1", "bdf2", "bdf3",
                                    "bdf4", "bdf5", "bdf6"])
def test_implicit_methods_stay_bounded(method):
    r = mbdk.solve_ode("decay", method, startup="bdf", **STIFF)
    assert r.success
    assert np.max(np.abs(r.y)) <= 1.0 + 1e-12
    assert abs(r.y[-1, 0]) < 1e-10


def test_amplification_factor_of_the_trapezoidal_rule():
    """One step: R(z) = (1 + z/2)/(1 - z/2) = -2/3 at z = -10 (exact rational)."""
    r = mbdk.solve_ode("decay", "trapezoidal", h=0.01, t_end=0.01, params={"lambda": 1000.0})
    assert r.y[-1, 0] == pytest.approx(-2.0 / 3.0, rel=1e-12)


def test_rk4_startup_of_bdf_amplifies_as_predicted():
    """With the book's RK4 start-up the k-1 start-up steps are explicit: each multiplies by the
    extrapolated RK4 factor, so max|y| is far above 1 before BDF damps it. (Documented; the
    'bdf' start-up above avoids it.)"""
    r = mbdk.solve_ode("decay", "bdf3", **STIFF)
    assert np.max(np.abs(r.y)) > 1e3
    assert abs(r.y[-1, 0]) < 1e-10
