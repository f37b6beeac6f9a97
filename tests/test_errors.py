"""Bad input raises a named exception naming the field and the value, before the kernel runs;
failures inside the kernel come back as statuses and are raised as named exceptions."""
import math

import numpy as np
import pytest

import mbdk


def solve(**kw):
    args = dict(problem="damped_oscillator", method="rk4", h=0.01, t_end=1.0)
    args.update(kw)
    return mbdk.solve_ode(args.pop("problem"), args.pop("method"), **args)


@pytest.mark.parametrize("kw,exc,words", [
    (dict(method="rk5"), mbdk.UnknownMethodError, ["'rk5'", "rk4"]),
    (dict(problem="pendulm"), mbdk.UnknownProblemError, ["'pendulm'", "pendulum"]),
    (dict(h=0.0), mbdk.InvalidInputError, ["h = 0.0", "positive"]),
    (dict(h=-0.1), mbdk.InvalidInputError, ["h = -0.1"]),
    (dict(h=math.nan), mbdk.InvalidInputError, ["h = nan", "finite"]),
    (dict(h=math.inf), mbdk.InvalidInputError, ["h = inf"]),
    (dict(h=2.0), mbdk.InvalidInputError, ["h = 2.0", "larger than the interval"]),
    (dict(h="0.1"), mbdk.InvalidInputError, ["h = '0.1'"]),
    (dict(t_end=0.0), mbdk.InvalidInputError, ["t_end = 0.0", "t0 = 0.0"]),
    (dict(t_end=math.inf), mbdk.InvalidInputError, ["t_end = inf"]),
    (dict(every=0), mbdk.InvalidInputError, ["every = 0"]),
    (dict(every=10**12), mbdk.InvalidInputError, ["every = 1000000000000"]),
    (dict(h=1e-12), mbdk.InvalidInputError, ["h = 1e-12", "1e+12 steps", "larger h"]),
    (dict(y0=[[5.0, 1.0]]), mbdk.InvalidInputError, ["y0 must be a flat vector", "(1, 2)"]),
    (dict(y0=[1.0, 2.0, 3.0]), mbdk.InvalidInputError, ["y0 has 3 entries", "2 states"]),
    (dict(y0=[1.0, math.nan]), mbdk.InvalidInputError, ["y0[1] = nan"]),
    (dict(y0="ab"), mbdk.InvalidInputError, ["y0"]),
    (dict(params={"mass": 1.0}), mbdk.UnknownParameterError, ["'mass'", "m, c, k"]),
    (dict(params={"m": 0.0}), mbdk.InvalidInputError, ["params['m'] = 0.0", "> 0"]),
    (dict(params={"k": math.inf}), mbdk.InvalidInputError, ["params['k'] = inf"]),
    (dict(params={"k": "stiff"}), mbdk.InvalidInputError, ["params['k'] = 'stiff'"]),
    (dict(problem="beam_linear", method="euler_cromer", h=100.0, t_end=1000.0),
     mbdk.NotApplicableError, ["euler_cromer", "first order"]),
    (dict(method="bdf4", h=0.0075, t_end=10.0), mbdk.InvalidInputError,
     ["bdf4 needs equal steps", "1333.33"]),
    (dict(problem="linear_system", y0=[1.0, 2.0], params={"A": [[1.0]]}),
     mbdk.InvalidInputError, ["params['A']", "2x2"]),
    (dict(problem="trolley_crane", params={"coupling": 0.5}), mbdk.InvalidInputError,
     ["params['coupling'] = 0.5"]),
    (dict(startup="euler"), mbdk.InvalidInputError, ["startup = 'euler'"]),
])
def test_bad_input_raises_named_error(kw, exc, words):
    with pytest.raises(exc) as info:
        solve(**kw)
    msg = str(info.value)
    for w in words:
        assert w in msg, f"{w!r} not in {msg!r}"
    assert isinstance(info.value, mbdk.MbdkError)


def test_newton_divergence_is_a_named_error():
    """Implicit Euler on x' = t x^2 + 2x from x0 = 5 at h = 0.5: the first step's equation
    x = 5 + 0.5 (0.5 x^2 + 2 x) reduces to 0.25 x^2 + 5 = 0, which has no real root."""
    with pytest.raises(mbdk.NewtonDivergedError) as info:
        mbdk.solve_ode("riccati", "implicit_euler", h=0.5, t_end=1.0, y0=[5.0])
    assert "reduce the step" in str(info.value)
    assert info.value.result.t.tolist() == [0.0]


def test_singular_newton_matrix_is_a_named_error():
    """y' = 10 y with h = 0.1: I - h A = 1 - 1 = 0 exactly."""
    with pytest.raises(mbdk.SingularMatrixError):
        mbdk.solve_ode("linear_system", "implicit_euler", h=0.1, t_end=1.0, y0=[1.0],
                       params={"A": [[10.0]]})


def test_overflow_is_a_named_error_and_partial_result_on_request():
    with pytest.raises(mbdk.NonFiniteSolutionError):
        mbdk.solve_ode("decay", "explicit_euler", h=0.01, t_end=10.0, params={"lambda": 1000.0})
    r = mbdk.solve_ode("decay", "explicit_euler", h=0.01, t_end=10.0,
                       params={"lambda": 1000.0}, raise_on_failure=False)
    assert not r.success and r.status == mbdk.Status.ERR_NONFINITE
    assert np.all(np.isfinite(r.y)) and 0 < r.t[-1] < 10.0
    assert "inf or NaN" in r.message


def test_callback_exception_becomes_callback_error_with_cause():
    def f(t, y):
        if t > 0.05:
            raise ZeroDivisionError("user bug")
        return [-y[0]]
    with pytest.raises(mbdk.CallbackError) as info:
        mbdk.solve_ode(f, "rk4", h=0.01, t_end=1.0, y0=[1.0])
    assert isinstance(info.value.__cause__, ZeroDivisionError)
    assert "user bug" in str(info.value)


def test_callback_returning_wrong_size_is_reported():
    with pytest.raises(mbdk.CallbackError):
        mbdk.solve_ode(lambda t, y: [1.0, 2.0, 3.0], "heun", h=0.1, t_end=1.0, y0=[1.0, 1.0])


@pytest.mark.parametrize("kw", [dict(h=1e-3, t0=1e4, t_end=1e4 + 1.0),
                                dict(h=1e-5, t_end=70.0, every=1_000_000)])
def test_multistep_runs_far_from_t0_keep_their_equal_steps(kw):
    """A k-step method's steps end at t0 + i h, computed in floating point: far from zero the
    difference of two such times is off from h by an ulp of t (more than 1e-9 h once t/h passes
    about 4.5e6). The run must take its steps of h and finish, as bdf1 does. Reference: the
    damped oscillator integrated by bdf2 from t = 0 over the same span (the problem is
    autonomous), which has no large t."""
    r = solve(method="bdf2", y0=[1.0, 0.0], **kw)
    assert r.success and r.stats.steps == round((kw["t_end"] - kw.get("t0", 0.0)) / kw["h"])
    if "t0" in kw:
        ref = solve(method="bdf2", y0=[1.0, 0.0], h=kw["h"], t_end=kw["t_end"] - kw["t0"])
        assert np.allclose(r.y[:, -1], ref.y[:, -1], rtol=0, atol=1e-12)


def test_a_multistep_interval_that_is_not_whole_steps_is_refused_by_name():
    """(t_end - t0)/h = 1e6 + 1e-4: not a whole number of steps beyond rounding, so the last
    step of bdf2 would not be h."""
    with pytest.raises(mbdk.InvalidInputError, match="bdf2 needs equal steps"):
        solve(method="bdf2", h=1e-3, t_end=1000.0000001, every=100_000)


def test_a_whole_number_of_steps_far_from_zero_is_recognised():
    """t0 = 1000.3, t_end = 1001.3, h = 1e-5: (t_end - t0)/h is 1e5 up to the rounding of
    t_end - t0 (an ulp of 1000, 1e-8 steps), which is not a reason to refuse bdf2 or to add a
    sliver of a last step."""
    r = solve(method="bdf2", y0=[1.0, 0.0], h=1e-5, t0=1000.3, t_end=1001.3, every=10_000)
    assert r.success and r.status == mbdk.Status.SUCCESS and r.stats.steps == 100_000
