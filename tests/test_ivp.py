"""mbdk.solve_ivp, SciPy's front over mbdk's kernel (issue 39, item 2): SciPy's own
solve_ivp examples (its documentation's: exponential decay with t_eval, the cannon with a
terminal and a non-terminal event and dense output, Lotka-Volterra with args and dense output)
and a stiff one (Robertson's reaction with BDF) through both, the answers compared; SciPy's
fields and shapes; backward integration; compiled problems by name; the refusals by name.
References: SciPy's solve_ivp run here (skipped without SciPy), the closed forms named in each
test."""
import math

import numpy as np
import pytest

import mbdk

scipy_integrate = pytest.importorskip("scipy.integrate")


def exponential_decay(t, y):
    return -0.5 * y


def test_exponential_decay_at_t_eval():
    """SciPy's first example: the states at t_eval, as (states, points); RK45 is the same
    Dormand-Prince pair, so the two agree far inside the tolerance; both within 1e-2 (rtol
    1e-3 over 10 s) of the closed form y0 exp(-t/2)."""
    t_eval = [0, 1, 2, 4, 10]
    ours = mbdk.solve_ivp(exponential_decay, [0, 10], [2, 4, 8], t_eval=t_eval)
    theirs = scipy_integrate.solve_ivp(exponential_decay, [0, 10], [2, 4, 8], t_eval=t_eval)
    assert ours.success and ours.status == 0 and ours.y.shape == (3, 5)
    assert np.array_equal(ours.t, theirs.t)
    exact = np.outer([2, 4, 8], np.exp(-0.5 * np.array(t_eval, float)))
    assert np.abs(ours.y - exact).max() < 1e-2 * np.abs(exact).max()
    assert np.abs(ours.y - theirs.y).max() < 1e-6
    assert ours.nfev > 0 and ours.sol is None and ours.t_events is None


def test_the_cannon_with_a_terminal_event_and_dense_output():
    """SciPy's second example: y = (height, speed), y'' = -0.5 from (0, 10): the apex at t = 20
    (speed 0) and the ground at t = 40 (height 0, falling: direction -1, terminal), in closed
    form; the result ends there with status 1, and sol evaluates between."""
    def upward_cannon(t, y):
        return [y[1], -0.5]

    def hit_ground(t, y):
        return y[0]
    hit_ground.terminal = True
    hit_ground.direction = -1

    def apex(t, y):
        return y[1]
    ours = mbdk.solve_ivp(upward_cannon, [0, 100], [0, 10], events=(hit_ground, apex),
                          dense_output=True)
    theirs = scipy_integrate.solve_ivp(upward_cannon, [0, 100], [0, 10],
                                       events=(hit_ground, apex), dense_output=True)
    assert ours.status == 1 == theirs.status and ours.message == theirs.message
    for mine, scipy_t, exact in zip(ours.t_events, theirs.t_events, (40.0, 20.0)):
        assert mine.shape == scipy_t.shape == (1,) and abs(mine[0] - exact) < 1e-9
    assert abs(ours.y_events[1][0, 0] - 100.0) < 1e-9       # the apex's height, 10^2 / (2 0.5)
    assert ours.t[-1] == pytest.approx(40.0, abs=1e-9) and abs(ours.y[0, -1]) < 1e-9
    t = np.array([5.0, 20.0, 35.0])
    assert np.allclose(ours.sol(t)[0], 10 * t - 0.25 * t * t, atol=1e-9)
    assert ours.sol(20.0).shape == (2,)


def lotkavolterra(t, z, a, b, c, d):
    x, y = z
    return [a * x - b * x * y, -c * y + d * x * y]


def test_lotka_volterra_with_args_and_dense_output():
    """SciPy's third example: args reach fun, and sol(t) on 300 points agrees with SciPy's
    dense output (the same pair and controller: to 1e-9 here); both carry the same error
    against a tight run, which is the tolerance's, not the front's."""
    t = np.linspace(0, 15, 300)
    kw = dict(args=(1.5, 1, 3, 1), dense_output=True)
    ours = mbdk.solve_ivp(lotkavolterra, [0, 15], [10, 5], **kw)
    theirs = scipy_integrate.solve_ivp(lotkavolterra, [0, 15], [10, 5], **kw)
    assert ours.sol(t).shape == (2, 300)
    assert np.abs(ours.sol(t) - theirs.sol(t)).max() < 1e-9
    tight = mbdk.solve_ivp(lotkavolterra, [0, 15], [10, 5], args=(1.5, 1, 3, 1), rtol=1e-11,
                           atol=1e-12, t_eval=t)
    e_ours = np.abs(ours.sol(t) - tight.y).max()
    e_theirs = np.abs(theirs.sol(t) - tight.y).max()
    assert e_ours == pytest.approx(e_theirs, rel=1e-6)


def test_robertson_with_bdf_agrees_with_scipy():
    """A stiff problem (Robertson's reaction) with BDF at rtol 1e-6: the two BDF codes agree
    to about 1e-6 relative of the largest species, and the species' sum stays 1 (conserved)."""
    def rob(t, y):
        return [-0.04 * y[0] + 1e4 * y[1] * y[2],
                0.04 * y[0] - 1e4 * y[1] * y[2] - 3e7 * y[1] ** 2, 3e7 * y[1] ** 2]
    kw = dict(method="BDF", rtol=1e-6, atol=1e-10)
    ours = mbdk.solve_ivp(rob, [0, 100], [1, 0, 0], **kw)
    theirs = scipy_integrate.solve_ivp(rob, [0, 100], [1, 0, 0], **kw)
    assert ours.success
    assert np.abs(ours.y[:, -1] - theirs.y[:, -1]).max() < 1e-5
    assert abs(ours.y[:, -1].sum() - 1.0) < 1e-8


def test_backward_integration_and_compiled_problems():
    """t_span decreasing: y' = -y from y(1) = 1 back to t = 0 gives e (closed form); t and
    t_eval run backwards as SciPy's do. A compiled problem by name keeps the whole solve in
    the kernel (decay with lambda = 0.5: y0 exp(-t/2))."""
    back = mbdk.solve_ivp(lambda t, y: -y, [1, 0], [1.0], t_eval=[1, 0.5, 0], rtol=1e-10,
                          atol=1e-12)
    assert np.array_equal(back.t, [1.0, 0.5, 0.0])
    assert back.y[0, -1] == pytest.approx(math.e, rel=1e-9)
    comp = mbdk.solve_ivp("decay", [0, 2], [3.0], t_eval=[2.0], rtol=1e-10, atol=1e-12,
                          params={"lambda": 0.5})
    assert comp.y[0, -1] == pytest.approx(3 * math.exp(-1.0), rel=1e-9)
    fixed = mbdk.solve_ivp(exponential_decay, [0, 1], [1.0], method="rk4", first_step=0.01)
    assert fixed.y.shape == (1, 101) and fixed.y[0, -1] == pytest.approx(math.exp(-0.5),
                                                                       rel=1e-9)


@pytest.mark.parametrize("kw, error, text", [
    ({"method": "Radau"}, mbdk.NotApplicableError, "bdf or cvode_bdf"),
    ({"method": "trapezoidal_index3"}, mbdk.NotApplicableError, "DAE"),
    ({"t_span": [1, 1]}, mbdk.InvalidInputError, "two different finite times"),
    ({"method": "rk4"}, mbdk.InvalidInputError, "first_step"),
    ({"args": [1.0]}, mbdk.InvalidInputError, "tuple"),
    ({"t_eval": [0.5, 0.2]}, mbdk.InvalidInputError, "direction of t_span"),
])
def test_refusals_are_named(kw, error, text):
    args = dict(fun=exponential_decay, t_span=[0, 1], y0=[1.0])
    args.update(kw)
    if "args" in kw:
        args["fun"] = lambda t, y, a: -a * y
    with pytest.raises(error, match=text):
        mbdk.solve_ivp(**args)


def test_events_after_a_terminal_one_are_not_reported():
    """A ball thrown up (y'' = -1 from (0, 1)): its height crosses 0.3 twice (t = 0.36754 and
    1.63246, the roots of t - t^2/2 = 0.3) and lands at t = 2; with the landing terminal and a
    first crossing of 0.3 counted as terminal too (terminal = 1), the run ends at the first
    crossing and reports nothing after it, as SciPy does."""
    def f(t, y):
        return [y[1], -1.0]

    def level(t, y):
        return y[0] - 0.3
    level.terminal = 1

    def ground(t, y):
        return y[0]
    ground.terminal = True
    ground.direction = -1
    r = mbdk.solve_ivp(f, [0, 5], [0.0, 1.0], events=[level, ground], rtol=1e-9, atol=1e-12)
    first = 1 - math.sqrt(1 - 0.6)
    assert r.status == 1 and r.t_events[0] == pytest.approx([first], abs=1e-9)
    assert r.t_events[1].size == 0 and r.t[-1] == pytest.approx(first, abs=1e-9)
    s = scipy_integrate.solve_ivp(f, [0, 5], [0.0, 1.0], events=[level, ground], rtol=1e-9,
                                  atol=1e-12)
    assert [e.size for e in s.t_events] == [e.size for e in r.t_events]


def test_a_failed_solve_returns_status_minus_one_as_scipy_does():
    """y' = y^2 from y(0) = 1 blows up at t = 1 (closed form y = 1/(1 - t)): both SciPy and
    mbdk return status -1 with the samples up to where the step size vanished, just before
    t = 1, also with t_eval (the times before the blow-up). A right-hand side that is NaN at
    once fails in the first step: status -1 with y0 alone."""
    blow = lambda t, y: y ** 2  # noqa: E731
    for kw in ({}, {"t_eval": np.linspace(0, 2, 5)}):
        ours = mbdk.solve_ivp(blow, (0, 2), [1.0], **kw)
        theirs = scipy_integrate.solve_ivp(blow, (0, 2), [1.0], **kw)
        assert ours.status == theirs.status == -1 and not ours.success
        assert ours.t[-1] == pytest.approx(theirs.t[-1], abs=1e-3) and ours.t[-1] < 1.0
    assert list(ours.t) == [0.0, 0.5]
    nan = mbdk.solve_ivp(lambda t, y: np.array([np.nan]), (0, 1), [1.0])
    assert nan.status == -1 and list(nan.t) == [0.0] and nan.y.tolist() == [[1.0]]
    assert "NaN" in nan.message


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_event_direction_on_a_backward_span_agrees_with_scipy(direction):
    """From t = 10 back to 0 on the harmonic oscillator (y = cos(t - 10)), y[0] = 0 at
    t = 10 - pi/2 - k pi. SciPy reads direction along the integration (rising as it runs,
    here as t decreases), and so does mbdk: the same roots for either direction."""
    osc = lambda t, y: [y[1], -y[0]]  # noqa: E731

    def height(t, y):
        return y[0]
    height.direction = direction
    kw = dict(events=height, rtol=1e-10, atol=1e-12)
    ours = mbdk.solve_ivp(osc, (10, 0), [1.0, 0.0], **kw)
    theirs = scipy_integrate.solve_ivp(osc, (10, 0), [1.0, 0.0], **kw)
    assert len(ours.t_events[0]) == len(theirs.t_events[0]) >= 1
    assert np.allclose(ours.t_events[0], theirs.t_events[0], atol=1e-7)
    exact = [10 - math.pi / 2 - k * math.pi for k in range(4)]
    assert all(min(abs(t - e) for e in exact) < 1e-8 for t in ours.t_events[0])
