"""Observed order of every method against its nominal order, on smooth problems with exact
solutions (mbdk.exact, themselves checked in test_problems.py).

Nominal orders are the textbook values (Hairer-Norsett-Wanner I, Hairer-Wanner II), written here
independently of the kernel's registry. The step pairs are in each method's asymptotic range
(found by halving until the ratio settles); tolerance 0.1 on the order.
"""
import math

import numpy as np
import pytest

import mbdk

NOMINAL = {"explicit_euler": 1, "heun": 2, "rk4": 4, "euler_cromer": 1, "implicit_euler": 1,
           "trapezoidal": 2, "bdf1": 1, "bdf2": 2, "bdf3": 3, "bdf4": 4, "bdf5": 5, "bdf6": 6}

# method -> (problem, t_end, coarse number of steps)
CASES = {
    "explicit_euler": ("riccati", 2.0, 160), "heun": ("riccati", 2.0, 320),
    "rk4": ("riccati", 2.0, 160), "implicit_euler": ("riccati", 2.0, 160),
    "trapezoidal": ("riccati", 2.0, 160), "bdf1": ("riccati", 2.0, 160),
    "bdf2": ("riccati", 2.0, 320), "bdf3": ("riccati", 2.0, 160),
    "euler_cromer": ("damped_oscillator", 2.0, 800), "bdf4": ("damped_oscillator", 2.0, 200),
    "bdf5": ("decay", 2.0, 40), "bdf6": ("damped_oscillator", 2.0, 100),
}


def final_error(problem, method, t_end, n):
    r = mbdk.solve_ode(problem, method, h=t_end / n, t_end=t_end, every=n)
    return float(np.max(np.abs(r.y[-1] - r.exact()[-1])))


def test_every_method_is_covered():
    assert set(CASES) == set(mbdk.methods("ode", step="fixed")) == set(NOMINAL)


@pytest.mark.parametrize("method", sorted(NOMINAL))
def test_observed_order_matches_nominal(method):
    problem, t_end, n = CASES[method]
    e1, e2 = final_error(problem, method, t_end, n), final_error(problem, method, t_end, 2 * n)
    p = math.log(e1 / e2) / math.log(2.0)
    assert abs(p - NOMINAL[method]) < 0.1, f"{method}: observed order {p:.3f}"
    assert mbdk.methods()[method].order == NOMINAL[method]


def test_bdf6_with_rk4_startup_keeps_order_6_on_decay():
    """Plain RK4 start values (local error O(h^5)) capped bdf6 at order 5 on y' = -y (observed
    4.4-4.8 before the kernel extrapolated its start-up steps); now it must exceed 5.8."""
    e = [final_error("decay", "bdf6", 2.0, n) for n in (40, 80, 160)]
    p = math.log(e[1] / e[2]) / math.log(2.0)
    assert p > 5.8
