"""The Python API: results, manifest, reproducibility, sampling, the callback path, listings."""
import numpy as np
import pytest

import mbdk


def test_issue_example():
    r = mbdk.solve_ode("damped_oscillator", "explicit_euler", h=0.01, t_end=10, y0=[5, 1])
    # explicit Euler is y_{n+1} = (I + hA) y_n: 1000 matrix products, computed independently
    a = np.array([[0.0, 1.0], [-10.0, -0.5]])
    want = np.linalg.matrix_power(np.eye(2) + 0.01 * a, 1000) @ [5.0, 1.0]
    assert np.allclose(r.y[-1], want, rtol=1e-11)
    assert r.success and r.status == mbdk.Status.SUCCESS and r.message == "success"
    assert r.stats.steps == 1000 and r.stats.nfev == 1000 and r.cpu_time >= 0


@pytest.mark.parametrize("problem", sorted(mbdk.problems()))
@pytest.mark.parametrize("method", sorted(mbdk.methods("ode", step="fixed")))
def test_every_method_and_problem_by_name(problem, method):
    info = mbdk.problems()[problem]
    if method == "euler_cromer" and not info.second_order:
        with pytest.raises(mbdk.NotApplicableError):
            mbdk.solve_ode(problem, method, h=0.1, t_end=1.0)
        return
    t_end = 100.0 if problem.startswith("beam") else 0.1
    r = mbdk.solve_ode(problem, method, h=t_end / 20, t_end=t_end, startup="bdf")
    assert r.success and r.y.shape == (21, len(info.y0)) and np.all(np.isfinite(r.y))
    assert r.t[-1] == t_end


def test_sampling_every_k_steps_keeps_the_last_point():
    r = mbdk.solve_ode("decay", "rk4", h=0.1, t_end=1.05, every=4)
    # 11 steps (the last one shortened): samples at steps 0, 4, 8 and 11
    assert np.allclose(r.t, [0.0, 0.4, 0.8, 1.05])
    assert r.status == mbdk.Status.NOTE_LAST_STEP_SHORTENED and r.success
    assert r.y[-1, 0] == pytest.approx(np.exp(-1.05), rel=1e-6)


def test_reproducible_bit_for_bit_with_manifest():
    a = mbdk.solve_ode("double_pendulum", "bdf4", h=1e-3, t_end=2.0)
    b = mbdk.solve_ode("double_pendulum", "bdf4", h=1e-3, t_end=2.0)
    assert np.array_equal(a.y, b.y) and a.stats.steps == b.stats.steps
    m = a.manifest
    for key in ("version", "method", "h", "compiler", "compiler_flags", "problem", "params"):
        assert key in m
    assert m["method"] == "bdf4" and m["h"] == 1e-3 and "-O" in m["compiler_flags"]


def test_python_callback_matches_compiled_problem():
    def f(t, y):
        return [y[1], -10.0 * y[0] - 0.5 * y[1]]
    for method in ("rk4", "bdf3", "euler_cromer", "trapezoidal"):
        rc = mbdk.solve_ode("damped_oscillator", method, h=0.01, t_end=2.0)
        rp = mbdk.solve_ode(f, method, h=0.01, t_end=2.0, y0=[5.0, 1.0], nq=1)
        assert np.allclose(rc.y, rp.y, rtol=1e-9, atol=1e-12), method
        assert rp.stats.steps == rc.stats.steps


def test_listings_carry_properties():
    ms = mbdk.methods()
    assert ms["rk4"].order == 4 and not ms["rk4"].implicit
    assert ms["bdf4"].implicit and ms["bdf4"].steps == 4 and "4.80" in ms["bdf4"].reference
    ps = mbdk.problems()
    assert ps["double_pendulum"].second_order and ps["double_pendulum"].n == 4
    assert "3.64" in ps["double_pendulum"].reference


def test_newton_statistics_are_counted():
    r = mbdk.solve_ode("damped_oscillator", "implicit_euler", h=0.01, t_end=1.0)
    s = r.stats
    assert s.steps == 100 and s.njev >= 100 and s.nlu >= 100
    # a linear problem: the first Newton update is exact, the second confirms it
    assert 100 <= s.newton_iterations <= 200
    fd = mbdk.solve_ode("damped_oscillator", "implicit_euler", h=0.01, t_end=1.0,
                        fd_jacobian=True)
    assert np.allclose(fd.y, r.y, rtol=1e-7) and fd.stats.nfev > s.nfev


def test_a_short_error_controlled_solve_stays_in_the_calling_thread(monkeypatch):
    """An error-controlled solve is tried in the calling thread within a short budget of steps
    (its steps are not known before), so a tiny dopri54 solve costs no hand-off to the worker
    thread; one that needs more steps than the budget runs again, whole, in the worker, with
    the bits a solve in this thread gives (a solve is deterministic)."""
    from mbdk import _compiled
    calls = []
    real = _compiled.call

    def spy(*a, **kw):
        calls.append(a[0])
        return real(*a, **kw)
    monkeypatch.setattr(_compiled, "call", spy)
    r = mbdk.solve_ode("decay", "dopri54", t_end=1.0, rtol=1e-6, atol=1e-8)
    assert r.success and not calls
    monkeypatch.setattr(_compiled, "LONG_WORK", 200)     # a budget of 200 state-steps
    long = mbdk.ODESolver("double_pendulum", "dopri54", t_end=2.0, rtol=1e-9, atol=1e-11)
    a = long.solve()
    assert calls and a.stats.steps > 200 // 4 and a.success
    monkeypatch.setattr(_compiled, "LONG_WORK", 10**9)   # the whole solve in this thread
    b = mbdk.ODESolver("double_pendulum", "dopri54", t_end=2.0, rtol=1e-9, atol=1e-11).solve()
    assert np.array_equal(a.y, b.y) and a.stats.steps == b.stats.steps
