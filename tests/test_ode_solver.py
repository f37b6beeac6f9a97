"""mbdk.ODESolver, the lean path for many short solves (issue 20, item 4): checked once,
run many times, and every run the bits solve_ode gives for the same arguments."""
import numpy as np
import pytest

import mbdk
from mbdk import InvalidInputError, NotApplicableError


def same(a, b):
    return (np.array_equal(a.t, b.t) and np.array_equal(a.y, b.y) and a.status == b.status
            and a.stats.steps == b.stats.steps and a.stats.nfev == b.stats.nfev)


@pytest.mark.parametrize("method, kw", [
    ("rk4", dict(h=0.01, every=10)),
    ("bdf4", dict(h=0.01)),
    ("dopri54", dict(rtol=1e-8, atol=1e-10, dt_out=0.1)),
    ("bdf", dict(rtol=1e-6, atol=[1e-8, 1e-8, 1e-6, 1e-6])),
])
def test_a_prepared_solve_gives_solve_odes_bits(method, kw):
    """From the problem's own y0 and from another, twice each: the bits of solve_ode with the
    same arguments, the manifest naming the initial state of that run."""
    solver = mbdk.ODESolver("double_pendulum", method, t_end=2.0, **kw)
    y1 = [0.3, -0.2, 0.0, 1.0]
    for _ in range(2):
        assert same(solver.solve(), mbdk.solve_ode("double_pendulum", method, t_end=2.0, **kw))
        r = solver.solve(y0=y1)
        assert same(r, mbdk.solve_ode("double_pendulum", method, t_end=2.0, y0=y1, **kw))
        assert r.manifest["y0"] == y1 and solver.solve().manifest["y0"] != y1


def test_parameters_and_the_exact_solution_go_with_the_result():
    """A decay with lambda = 3 against exp(-3 t): the params reach the kernel and the result's
    exact() uses them."""
    solver = mbdk.ODESolver("decay", "rk4", h=1e-3, t_end=1.0, params={"lambda": 3.0},
                            y0=[2.0])
    r = solver.solve()
    assert r.y[-1, 0] == pytest.approx(2.0 * np.exp(-3.0), rel=1e-12)
    assert r.max_error() < 1e-12 and r.manifest["params"]["lambda"] == 3.0


def test_a_long_prepared_solve_runs_where_ctrl_c_reaches_it():
    """Over LONG_WORK state-steps the run goes through the worker thread, as solve_ode's would,
    with the same bits."""
    from mbdk import _compiled
    solver = mbdk.ODESolver("double_pendulum", "rk4", h=1e-4, t_end=10.0, every=10**5)
    assert solver._work >= _compiled.LONG_WORK
    assert same(solver.solve(), mbdk.solve_ode("double_pendulum", "rk4", h=1e-4, t_end=10.0,
                                               every=10**5))


@pytest.mark.parametrize("args, kw, error, text", [
    (("double_pendulum", "rk4"), dict(t_end=1.0), InvalidInputError, "give h"),
    (("double_pendulum", "rk4"), dict(h=-1.0, t_end=1.0), InvalidInputError, "h = -1.0"),
    (("nothing", "rk4"), dict(h=0.1, t_end=1.0), InvalidInputError, "nothing"),
    ((lambda t, y: y, "rk4"), dict(h=0.1, t_end=1.0, y0=[1.0]), NotApplicableError,
     "compiled problems"),
    (("riccati", "euler_cromer"), dict(h=0.1, t_end=1.0), NotApplicableError, "second-order"),
    (("decay", "rk4"), dict(h=0.1, t_end=1.0, jac=lambda t, y: [[-1.0]]), InvalidInputError,
     "own Jacobian"),
])
def test_bad_arguments_are_named_at_construction(args, kw, error, text):
    with pytest.raises(error, match=text):
        mbdk.ODESolver(*args, **kw)


@pytest.mark.parametrize("y0, text", [([1.0, 2.0], "2 entries"), ([0, 0, np.nan, 0], "y0\\[2\\]"),
                                      ("abc", "not a vector")])
def test_a_bad_initial_state_is_named_at_the_run(y0, text):
    solver = mbdk.ODESolver("double_pendulum", "rk4", h=0.01, t_end=1.0)
    with pytest.raises(InvalidInputError, match=text):
        solver.solve(y0=y0)


def test_a_failure_raises_or_returns_as_asked():
    """The stiff decay by explicit Euler at 3x its stability limit overflows: raised by name,
    or returned with its status when raise_on_failure=False (as solve_ode does)."""
    kw = dict(h=0.06, t_end=2000.0, params={"lambda": 100.0}, y0=[1.0])
    with pytest.raises(mbdk.MbdkError):
        mbdk.ODESolver("decay", "explicit_euler", **kw).solve()
    r = mbdk.ODESolver("decay", "explicit_euler", raise_on_failure=False, **kw).solve()
    ref = mbdk.solve_ode("decay", "explicit_euler", raise_on_failure=False, **kw)
    assert not r.success and r.status == ref.status and np.array_equal(r.y, ref.y)
