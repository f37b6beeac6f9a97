"""Error-controlled methods (dopri54, bs32, bdf, cvode_bdf, cvode_adams): orders, tolerances,
dense output, stiffness, statistics and named errors.

Reference values: the problems' closed-form solutions (mbdk.exact: y' = -y, the damped
oscillator, the Riccati equation); the orders are the published ones of the formulas
(Dormand and Prince 1980: 5 with an order-4 estimate; Bogacki and Shampine 1989: 3 with an
order-2 estimate; BDF-k: order k).
"""
import math

import numpy as np
import pytest

import mbdk
from mbdk import _kernel

ADAPTIVE = ["dopri54", "bs32", "bdf", "cvode_bdf", "cvode_adams"]
EXPLICIT_PAIRS = {"dopri54": (5, 4), "bs32": (3, 2)}   # (order, order of the estimate)


def slope(x, y):
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def test_registry_lists_the_error_controlled_methods():
    adaptive = mbdk.methods("ode", step="adaptive")
    assert sorted(adaptive) == sorted(ADAPTIVE)
    assert not set(adaptive) & set(mbdk.methods("ode", step="fixed"))
    assert all(m.adaptive for m in adaptive.values())
    assert mbdk.methods()["bdf"].implicit and not mbdk.methods()["dopri54"].implicit


@pytest.mark.parametrize("method", sorted(EXPLICIT_PAIRS))
def test_pair_reaches_its_order_at_a_fixed_step_and_so_does_its_dense_output(method):
    """rtol = 0 and an atol no error reaches accept every step; h = h_max then holds the step
    fixed, so the error at t_end and at samples between steps (dense output) converge with the
    pair's order: Shampine's order-4 extension of dopri54 and the cubic Hermite of bs32 add an
    interpolation error of one order more than the step's."""
    p = EXPLICIT_PAIRS[method][0]
    ends, alls, hs = [], [], [0.1, 0.05, 0.025]
    for h in hs:
        r = mbdk.solve_ode("damped_oscillator", method, t_end=4.0, h=h, h_max=h, rtol=0.0,
                           atol=1e300, dt_out=0.37)
        assert r.stats.rejected_steps == 0 and r.stats.steps == round(4.0 / h)
        ends.append(np.max(np.abs(r.y[-1] - r.exact()[-1])))
        alls.append(np.max(np.abs(r.y - r.exact())))
    assert slope(hs, ends) == pytest.approx(p, abs=0.15)
    assert slope(hs, alls) == pytest.approx(p, abs=0.15)


@pytest.mark.parametrize("method", sorted(EXPLICIT_PAIRS))
def test_step_count_follows_the_order_of_the_error_estimate(method):
    """Local error ~ C h^(q+1) held at the tolerance gives N ~ tol^(-1/(q+1)) steps, q the order
    of the embedded estimate: a wrong estimate (or a wrong e) changes the slope."""
    q = EXPLICIT_PAIRS[method][1]
    tols = [1e-5, 1e-7, 1e-9]
    steps = [mbdk.solve_ode("decay", method, t_end=10.0, rtol=t, atol=t * 1e-3).stats.steps
             for t in tols]
    assert slope(tols, steps) == pytest.approx(-1.0 / (q + 1), rel=0.15)


@pytest.mark.parametrize("k", [1, 2, 3, 4, 5])
def test_bdf_with_max_order_k_takes_steps_as_order_k(k):
    """Capped at order k, the variable-step BDF's steps grow as tol^(-1/(k+1)) at tight
    tolerances, and every step beyond the start-up is of order <= k."""
    tols = [1e-6, 1e-8, 1e-10]
    rs = [mbdk.solve_ode("damped_oscillator", "bdf", t_end=10.0, rtol=t, atol=t * 1e-2,
                         max_order=k) for t in tols]
    counts = [getattr(rs[-1].stats, f"order{j}_steps") for j in range(1, 6)]
    assert sum(counts[k:]) == 0 and counts[k - 1] > 0.9 * rs[-1].stats.steps
    assert slope(tols, [r.stats.steps for r in rs]) == pytest.approx(-1.0 / (k + 1), rel=0.2)
    assert sum(counts) == rs[-1].stats.steps


@pytest.mark.parametrize("method", ADAPTIVE)
@pytest.mark.parametrize("problem", ["decay", "damped_oscillator", "riccati"])
def test_global_error_follows_the_tolerance(method, problem):
    """The local error is held at the tolerance; the global error over the interval follows it
    down: within 300 tol at every sample for every method (BDF's error estimates are
    asymptotic and its errors accumulate over the oscillator's 5 periods), and 1000 times
    tighter tolerances give at least 100 times smaller errors."""
    errs = []
    for tol in (1e-5, 1e-8):
        r = mbdk.solve_ode(problem, method, t_end=10.0, rtol=tol, atol=tol * 1e-2, dt_out=0.25)
        assert r.success and r.t[-1] == 10.0 and len(r.t) == 41
        assert np.allclose(r.t, np.linspace(0.0, 10.0, 41), rtol=0, atol=1e-12)
        err = float(np.max(np.abs(r.y - r.exact())))
        scale = max(1.0, float(np.max(np.abs(r.exact()))))
        assert err <= 300 * tol * scale, f"{method} {problem} tol {tol}: {err:.2e}"
        errs.append(err)
    assert errs[1] < errs[0] / 100


@pytest.mark.parametrize("method", ["bdf", "cvode_bdf"])
def test_stiff_decay_costs_the_bdf_few_steps_and_the_explicit_pair_many(method):
    """y' = -1e4 y over 10 s: an explicit pair's step is held at its stability limit
    (about 3.3/1e4 for dopri54: some 30 000 steps), the BDF's grows with the solution's
    smoothness (A-stable orders 1-2, A(alpha) with the real axis for 3-5)."""
    kw = dict(t_end=10.0, rtol=1e-6, atol=1e-10, params={"lambda": 1.0e4})
    rb = mbdk.solve_ode("decay", method, **kw)
    re = mbdk.solve_ode("decay", "dopri54", **kw)
    assert rb.success and re.success
    assert re.stats.steps > 20000
    assert rb.stats.steps < re.stats.steps / 50
    assert abs(rb.y[-1, 0]) < 1e-9 and np.all(np.abs(rb.y) <= 1.0 + 1e-9)


def test_bdf_reuses_its_jacobian_and_matrix_across_steps():
    r = mbdk.solve_ode("double_pendulum", "bdf", t_end=5.0, rtol=1e-8, atol=1e-10)
    assert r.success
    assert r.stats.njev < r.stats.steps / 10
    assert r.stats.nlu < r.stats.steps / 2
    assert r.stats.newton_iterations >= r.stats.steps


@pytest.mark.parametrize("method", ["bdf", "cvode_bdf"])
def test_finite_difference_jacobian_gives_the_same_answer(method):
    """The pendulum has an analytic Jacobian; fd_jacobian=True replaces it by differences,
    which cost evaluations of F (one per column at least) and give the same solution."""
    kw = dict(t_end=5.0, rtol=1e-8, atol=1e-10, y0=[2.0, 0.0])
    a = mbdk.solve_ode("pendulum", method, **kw)
    b = mbdk.solve_ode("pendulum", method, fd_jacobian=True, **kw)
    assert a.success and b.success and a.stats.njev > 0
    assert np.max(np.abs(a.y[-1] - b.y[-1])) < 1e-5
    assert b.stats.nfev >= a.stats.nfev - 10 * a.stats.njev + 2 * b.stats.njev


def test_per_component_atol_is_honoured():
    """With rtol = 0 the steps are set by atol alone: a vector of equal entries is the scalar,
    a tight atol on one state and a loose one on the other costs fewer steps than tight on both
    and more than loose on both, and which state is tight matters (position and velocity of
    the oscillator have different scales: |v| is up to sqrt(10) |y|). An atol that were read
    as its first entry only, or as a scalar, fails one of these."""
    kw = dict(t_end=10.0, rtol=0.0, y0=[1.0, 0.0])
    same = mbdk.solve_ode("damped_oscillator", "dopri54", atol=[1e-8, 1e-8], **kw)
    scalar = mbdk.solve_ode("damped_oscillator", "dopri54", atol=1e-8, **kw)
    assert np.array_equal(same.y, scalar.y)
    loose = mbdk.solve_ode("damped_oscillator", "dopri54", atol=[1e-2, 1e-2], **kw)
    tight_y = mbdk.solve_ode("damped_oscillator", "dopri54", atol=[1e-8, 1e-2], **kw)
    tight_v = mbdk.solve_ode("damped_oscillator", "dopri54", atol=[1e-2, 1e-8], **kw)
    for r in (tight_y, tight_v):
        assert loose.stats.steps < r.stats.steps <= scalar.stats.steps
    assert tight_y.stats.steps != tight_v.stats.steps


@pytest.mark.parametrize("method", ADAPTIVE)
def test_callback_path_matches_compiled_problem(method):
    def f(t, y):
        return [y[1], -10.0 * y[0] - 0.5 * y[1]]
    kw = dict(t_end=3.0, rtol=1e-8, atol=1e-10, dt_out=0.5)
    rc = mbdk.solve_ode("damped_oscillator", method, **kw)
    rp = mbdk.solve_ode(f, method, y0=rc.y[0], **kw)
    assert np.allclose(rc.y, rp.y, rtol=1e-6, atol=1e-8)
    assert rp.manifest["rtol"] == 1e-8 and rp.manifest["method"] == method


@pytest.mark.parametrize("method", ADAPTIVE)
def test_reproducible_bit_for_bit(method):
    kw = dict(t_end=5.0, rtol=1e-7, atol=1e-9, dt_out=0.1)
    a = mbdk.solve_ode("double_pendulum", method, **kw)
    b = mbdk.solve_ode("double_pendulum", method, **kw)
    assert np.array_equal(a.y, b.y) and a.stats.steps == b.stats.steps
    assert a.manifest["rtol"] == 1e-7 and a.manifest["atol"] == 1e-9


@pytest.mark.parametrize("bad, field", [
    (dict(rtol=-1e-6), "rtol"), (dict(rtol=float("nan")), "rtol"), (dict(rtol=1e-20), "rtol"),
    (dict(rtol=2.0), "rtol"), (dict(atol=-1.0), "atol"), (dict(atol=[1e-8, 1e-8, 1e-8]), "atol"),
    (dict(atol=[1e-8, float("inf")]), "atol[1]"), (dict(rtol=0.0, atol=0.0), "atol"),
    (dict(atol=[1e-8, 0.0]), "atol[1]"), (dict(atol="x"), "atol"),
    (dict(dt_out=-0.1), "dt_out"), (dict(every=5), "every"), (dict(h_min=1.0, h_max=0.1), "h_min"),
    (dict(max_order=6), "max_order"), (dict(max_steps=-3), "max_steps")])
def test_bad_tolerances_and_options_are_named(bad, field):
    with pytest.raises(mbdk.InvalidInputError, match=field.replace("[", r"\[")):
        mbdk.solve_ode("damped_oscillator", "bdf", t_end=1.0, **bad)


def test_fixed_step_methods_refuse_tolerances_and_adaptive_ones_need_no_h():
    with pytest.raises(mbdk.InvalidInputError, match="rtol"):
        mbdk.solve_ode("decay", "rk4", h=0.1, t_end=1.0, rtol=1e-6)
    with pytest.raises(mbdk.InvalidInputError, match="atol"):
        mbdk.solve_ode("damped_oscillator", "rk4", h=0.1, t_end=1.0, atol=np.array([1e-6, 1e-6]))
    with pytest.raises(mbdk.InvalidInputError, match="give h"):
        mbdk.solve_ode("decay", "rk4", t_end=1.0)
    with pytest.raises(mbdk.InvalidInputError, match="max_order"):
        mbdk.solve_ode("decay", "dopri54", t_end=1.0, max_order=3)


def test_kernel_refuses_bad_tolerances_on_its_own():
    """The kernel checks what Python checks: a caller of the f2py layer (or of the C API) that
    skips Python gets ERR_INVALID_INPUT, not a run."""
    from mbdk.options import ODEOptions, empty
    from mbdk import _compiled
    info = mbdk.problems()["decay"]
    pvec = np.array([1.0])
    for fields in (dict(rtol=-1.0), dict(rtol=1e-20), dict(atol=0.0), dict(atol=float("nan")),
                   dict(max_order=6)):
        opt = ODEOptions(method=mbdk.methods()["bdf"].id, **fields)
        t, y, nw, status = _kernel.solve_problem(info.id, np.array([1.0]), 0.0, 1.0, pvec,
                                                 opt.pack(), _compiled.new_flag(), np.zeros(0),
                                                 np.zeros(0), 2, empty("mbdk_stats"))
        assert status == mbdk.Status.ERR_INVALID_INPUT, fields
    opt = ODEOptions(method=mbdk.methods()["dopri54"].id)
    *_, status = _kernel.solve_problem(info.id, np.array([1.0]), 0.0, 1.0, pvec, opt.pack(),
                                       _compiled.new_flag(), np.ones(2), np.zeros(0), 2,
                                       empty("mbdk_stats"))
    assert status == mbdk.Status.ERR_INVALID_INPUT    # atol of the wrong size
    opt = ODEOptions(method=mbdk.methods()["dopri54"].id, max_order=3)
    *_, status = _kernel.solve_problem(info.id, np.array([1.0]), 0.0, 1.0, pvec, opt.pack(),
                                       _compiled.new_flag(), np.zeros(0), np.zeros(0), 2,
                                       empty("mbdk_stats"))
    assert status == mbdk.Status.ERR_INVALID_INPUT    # an explicit pair has one order
    # sample times the kernel cannot take: not from t0, not to t_end, not increasing, and any
    # for a fixed-step method
    opt = ODEOptions(method=mbdk.methods()["dopri54"].id)
    for times in ([0.1, 1.0], [0.0, 0.9], [0.0, 0.5, 0.5, 1.0], [0.0, float("nan"), 1.0]):
        *_, status = _kernel.solve_problem(info.id, np.array([1.0]), 0.0, 1.0, pvec, opt.pack(),
                                           _compiled.new_flag(), np.zeros(0), np.array(times),
                                           len(times), empty("mbdk_stats"))
        assert status == mbdk.Status.ERR_INVALID_INPUT, times
    opt = ODEOptions(method=mbdk.methods()["rk4"].id, h=0.5)
    *_, status = _kernel.solve_problem(info.id, np.array([1.0]), 0.0, 1.0, pvec, opt.pack(),
                                       _compiled.new_flag(), np.zeros(0), np.array([0.0, 1.0]),
                                       3, empty("mbdk_stats"))
    assert status == mbdk.Status.ERR_INVALID_INPUT


@pytest.mark.parametrize("method", ADAPTIVE)
def test_step_limit_and_step_floor_are_named_errors(method):
    with pytest.raises(mbdk.TooManyStepsError) as exc:
        mbdk.solve_ode("double_pendulum", method, t_end=10.0, rtol=1e-10, atol=1e-12,
                       max_steps=20, dt_out=0.01)
    partial = exc.value.result
    assert not partial.success and 1 <= len(partial.t) < 1001 and partial.t[-1] < 10.0
    assert np.all(np.isfinite(partial.y))
    # the first step is raised to h_min = 0.5, where the tolerance cannot be met: the kernel's
    # methods end at the step floor; CVODE, which keeps h at h_min, first fails its Newton
    # iteration there
    named = (mbdk.StepTooSmallError, mbdk.NewtonDivergedError) if method.startswith("cvode") \
        else mbdk.StepTooSmallError
    with pytest.raises(named):
        mbdk.solve_ode("double_pendulum", method, t_end=10.0, rtol=1e-10, atol=1e-12,
                       h_min=0.5)


@pytest.mark.parametrize("method", ADAPTIVE)
def test_h_min_is_honoured_and_the_landing_step_may_be_shorter(method):
    """h_min = 0.01 raises an automatic first step below it; the last step, cut to land on
    t_end, may be shorter than h_min (h = h_max = 0.4 over [0, 1] leaves 0.2)."""
    r = mbdk.solve_ode("decay", method, t_end=1.0, h_min=0.01, rtol=1e-3, atol=1e-6)
    assert r.success and r.y[-1, 0] == pytest.approx(math.exp(-1.0), rel=1e-2)
    # a loose tolerance accepts every step of 0.4 (even bdf's first, of order 1)
    r = mbdk.solve_ode("decay", method, t_end=1.0, h=0.4, h_min=0.3, h_max=0.4, rtol=0.5,
                       atol=0.5)
    assert r.success and r.t[-1] == 1.0 and r.stats.steps == 3


@pytest.mark.parametrize("method", ["dopri54", "bs32", "bdf", "cvode_bdf"])
def test_non_finite_f_is_a_rejected_step_not_a_failure(method):
    """y' = -sqrt(y) is NaN below y = 0; from y(0) = 1 the exact y = (1 - t/2)^2 reaches 0 at
    t = 2. Over [0, 1.9] a step that overshoots into y < 0 gives a NaN stage, which an
    error-controlled method rejects and retries smaller (from Python too)."""
    r = mbdk.solve_ode(lambda t, y: [-math.sqrt(y[0]) if y[0] >= 0 else float("nan")], method,
                       y0=[1.0], t_end=1.9, rtol=1e-8, atol=1e-10)
    assert r.success and r.y[-1, 0] == pytest.approx((1 - 1.9 / 2) ** 2, rel=1e-4)


def test_callback_failure_keeps_the_samples_before_it():
    def f(t, y):
        if t > 1.0:
            raise RuntimeError("model broke")
        return [-y[0]]
    with pytest.raises(mbdk.CallbackError, match="model broke") as exc:
        mbdk.solve_ode(f, "dopri54", y0=[1.0], t_end=3.0, dt_out=0.1)
    r = exc.value.result
    assert 0.9 <= r.t[-1] <= 1.0 and np.allclose(r.y[:, 0], np.exp(-r.t), rtol=1e-5)


@pytest.mark.parametrize("formulation", ["reduced", "projection", "penalty", "baumgarte"])
@pytest.mark.parametrize("method", ["dopri54", "bdf", "cvode_bdf"])
def test_scene_runs_by_tolerance_on_every_formulation(method, formulation):
    """The double pendulum scene, 3 s: against an rk4 run of h = 1e-4 (error ~1e-12 at that
    step) the error-controlled runs agree to their tolerance's order, keep the constraints the
    formulation promises (the watch is on), and sample at dt_out. cvode_* refuse the
    projection formulation by name (CVODE keeps its own history of the state)."""
    sc = mbdk.scene("double_pendulum")
    kw = dict(formulation=formulation, t_end=3.0, rtol=1e-8, atol=1e-10, dt_out=0.5)
    if formulation == "baumgarte":
        kw.update(alpha=20.0, beta=20.0)
    if method == "cvode_bdf" and formulation == "projection":
        with pytest.raises(mbdk.NotApplicableError, match="projection"):
            mbdk.simulate(sc, method, **kw)
        return
    r = mbdk.simulate(sc, method, **kw)
    ref = mbdk.simulate(sc, "rk4", t_end=3.0, h=1e-4, every=5000)
    assert r.success and np.allclose(r.t, ref.t, atol=1e-12)
    tol = 1e-4 if formulation == "penalty" else 1e-5   # penalty: an O(1/alpha_p) model error
    assert np.max(np.abs(r.q - ref.q)) < tol
    assert r.manifest["rtol"] == 1e-8 and r.manifest["steps"] == r.stats.steps


def test_scene_options_are_named():
    sc = mbdk.scene("double_pendulum")
    with pytest.raises(mbdk.InvalidInputError, match="rtol"):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0, rtol=1e-6)
    with pytest.raises(mbdk.InvalidInputError, match="alpha and beta"):
        mbdk.simulate(sc, "dopri54", formulation="baumgarte", t_end=1.0)
    with pytest.raises(mbdk.InvalidInputError, match="give h"):
        mbdk.simulate(sc, "rk4", t_end=1.0)
    with pytest.raises(mbdk.NotApplicableError, match="number"):
        mbdk.simulate(sc, "dopri54", t_end=1.0, atol=[1e-8] * 12)


@pytest.mark.parametrize("form", ["index1", "ggl"])
def test_ida_integrates_the_scene_dae_in_both_forms(form):
    """ida on the double pendulum scene, 5 s at rtol 1e-8: q agrees with rk4 at h = 1e-4 (its
    own error ~1e-12) to 1e-6; the GGL form keeps Phi and Phi' at its Newton tolerance
    (below 1e-9) at every sample, the index-1 form lets them drift (above that, below the
    watch's 1e-2); the multipliers are those of the reduced solve at the sampled state."""
    sc = mbdk.scene("double_pendulum")
    r = mbdk.simulate(sc, "ida", formulation=form, t_end=5.0, rtol=1e-8, atol=1e-10,
                      dt_out=0.5)
    ref = mbdk.simulate(sc, "rk4", h=1e-4, t_end=5.0, every=5000)
    assert r.success and np.allclose(r.t, ref.t, atol=1e-12)
    assert np.max(np.abs(r.q - ref.q)) < 1e-6
    drift = np.max(np.abs(r.residuals[:, :2]))
    if form == "ggl":
        assert drift < 1e-9
    else:
        assert 1e-9 < drift < 1e-4
    assert np.allclose(r.multipliers, ref.multipliers, rtol=1e-5, atol=1e-5)
    assert r.manifest["formulation"] == form and "form" in r.manifest
    counts = [getattr(r.stats, f"order{k}_steps") for k in range(1, 6)]
    assert sum(counts) == r.stats.steps and r.stats.njev > 0


def test_ida_index1_drift_is_caught_by_the_watch_and_ggl_keeps_the_constraints():
    """At a loose tolerance over 40 s the index-1 form's constraint drift grows until the
    watch stops the run by name; the GGL form, whose Phi = 0 and D v + Phi_t = 0 are
    equations of the DAE, runs through without growth (the samples come from IDA's
    interpolant, which meets the constraints to the local error, not to roundoff)."""
    sc = mbdk.scene("double_pendulum")
    kw = dict(t_end=40.0, rtol=1e-4, atol=1e-6, dt_out=0.5)
    with pytest.raises(mbdk.ConstraintDriftError):
        mbdk.simulate(sc, "ida", formulation="index1", **kw)
    r = mbdk.simulate(sc, "ida", formulation="ggl", **kw)
    res = np.max(np.abs(r.residuals[:, :2]), axis=1)
    assert r.success and np.max(res) < 1e-4
    assert np.max(res[r.t > 30.0]) < 10 * np.max(res[r.t < 10.0])


def test_ida_options_are_named():
    sc = mbdk.scene("double_pendulum")
    with pytest.raises(mbdk.InvalidInputError, match="index1, ggl"):
        mbdk.simulate(sc, "ida", formulation="reduced", t_end=1.0)
    with pytest.raises(mbdk.NotApplicableError, match="scene"):
        mbdk.solve_ode("decay", "ida", t_end=1.0)
    with pytest.raises(mbdk.InvalidInputError, match="max_order"):
        mbdk.simulate(sc, "ida", t_end=1.0, max_order=6)
    with pytest.raises(mbdk.TooManyStepsError):
        mbdk.simulate(sc, "ida", t_end=1.0, max_steps=5)
    assert mbdk.methods()["ida"].solves == "dae" and "ida" not in mbdk.methods("ode")


@pytest.mark.parametrize("form, tol_q", [("i3", 2e-5), ("si2", 2e-6)])
def test_bdf_on_the_scene_dae_as_gstiff_i3_and_si2(form, tol_q):
    """bdf on the double pendulum's DAE itself (mbdk_scene_dae), 5 s at rtol 1e-8, against rk4
    at h = 1e-4: the index-3 form tests the positions' error only (its velocities are index-2
    variables), so it is the less accurate; the stabilised index-2 form keeps Phi' too. Both
    keep the constraints at the samples (interpolated between steps) to well within the
    watch's tolerances, and count their steps by order."""
    sc = mbdk.scene("double_pendulum")
    r = mbdk.simulate(sc, "bdf", formulation=form, t_end=5.0, rtol=1e-8, atol=1e-10,
                      dt_out=0.5)
    ref = mbdk.simulate(sc, "rk4", h=1e-4, t_end=5.0, every=5000)
    assert r.success and np.allclose(r.t, ref.t, atol=1e-12)
    assert np.max(np.abs(r.q - ref.q)) < tol_q
    assert np.max(np.abs(r.residuals[:, 0])) < 1e-7
    counts = [getattr(r.stats, f"order{k}_steps") for k in range(1, 6)]
    assert sum(counts) == r.stats.steps and counts[4] > r.stats.steps / 4
    assert "GSTIFF" in r.manifest["form"] and r.manifest["formulation"] == form


@pytest.mark.parametrize("form", ["i3", "si2"])
@pytest.mark.parametrize("k", [1, 2])
def test_bdf_on_the_scene_dae_converges_at_low_order(form, k):
    """Capped at order k, the DAE forms converge as their order says: a local error held at
    tol ~ h^(k+1) leaves a global error ~ h^k ~ tol^(k/(k+1)), so 100 times tighter tolerances
    give errors 100^(k/(k+1)) times smaller (10 for k = 1, 21.5 for k = 2; half of that is
    asked), and the run never fails (Newton keeps the constraints, so no step-size collapse
    after a rejection)."""
    sc = mbdk.scene("physical_pendulum")
    ref = mbdk.simulate(sc, "rk4", h=1e-4, t_end=2.0, every=5000)
    errs = []
    for tol in (1e-4, 1e-6):
        r = mbdk.simulate(sc, "bdf", formulation=form, t_end=2.0, rtol=tol, atol=tol * 1e-2,
                          dt_out=0.5, max_order=k)
        assert r.success
        errs.append(np.max(np.abs(r.q - ref.q)))
    assert errs[1] < errs[0] / (0.5 * 100 ** (k / (k + 1)))


def _driven_pendulum():
    from mbdk.scene import Joint
    sc = mbdk.scene("physical_pendulum")
    bar = sc.bodies[0]
    sc.joints.append(Joint("drive", "driver", bar.name, coordinate="angle",
                           function=(bar.angle, 2.0, 0.0, 0.0, 0.0)))
    for b in sc.bodies:
        b.given = ()
    return sc


def test_bdf_i3_velocities_follow_the_tolerance_and_si2_keeps_them():
    """A bar driven at 2 rad/s about its hinge: the velocity constraint D v + Phi_t = 0 at
    every millisecond. The index-3 form tests h times the velocities' error (index 2), so its
    velocities are the looser (worst in the first, order-1 steps) but converge with the
    tolerance; the stabilised index-2 form solves for them."""
    sc = _driven_pendulum()
    kw = dict(t_end=1.0, dt_out=1e-3)
    res = {}
    for form in ("i3", "si2"):
        for tol in (1e-6, 1e-8):
            r = mbdk.simulate(sc, "bdf", formulation=form, rtol=tol, atol=tol * 1e-2, **kw)
            assert r.success and np.allclose(r.v[:, 2], 2.0, atol=1e-9)
            res[form, tol] = np.max(np.abs(r.residuals[:, 1]))
    assert res["i3", 1e-8] < res["i3", 1e-6] / 50 and res["i3", 1e-6] < 1e-2
    assert res["si2", 1e-6] < 1e-6 and res["si2", 1e-8] < 1e-8


@pytest.mark.parametrize("method, form", [("ida", "index1"), ("ida", "ggl"), ("bdf", "i3"),
                                          ("bdf", "si2")])
def test_dae_multipliers_are_the_integrators_own(method, form):
    """The multipliers a DAE run returns are its own unknowns at the samples, not a reduced
    solve at the sampled state: they differ from it (by the integrator's error, not by zero)
    and agree with it to that error."""
    sc = mbdk.scene("double_pendulum")
    r = mbdk.simulate(sc, method, formulation=form, t_end=2.0, rtol=1e-8, atol=1e-10,
                      dt_out=0.25)
    reduced = np.array([mbdk.evaluate(sc, q, v, t)["lam"] for q, v, t in zip(r.q, r.v, r.t)])
    diff = np.max(np.abs(r.multipliers[1:] - reduced[1:]))
    assert 0.0 < diff < 1e-3 * np.max(np.abs(reduced))


@pytest.mark.parametrize("method, form", [("ida", "ggl"), ("bdf", "si2"), ("bdf", "i3")])
def test_dae_forms_refuse_an_inconsistent_start_and_options_they_do_not_read(method, form):
    sc = mbdk.scene("double_pendulum")
    sc.bodies[1].x += 1e-4
    with pytest.raises(mbdk.InvalidInputError, match="does not satisfy the constraints"):
        mbdk.simulate(sc, method, formulation=form, t_end=1.0, assemble_initial=False)
    sc = mbdk.scene("double_pendulum")
    with pytest.raises(mbdk.InvalidInputError, match="alpha"):
        mbdk.simulate(sc, method, formulation=form, t_end=1.0, alpha=5.0)
    with pytest.raises(mbdk.InvalidInputError, match="newton_rtol"):
        mbdk.simulate(sc, method, formulation=form, t_end=1.0, newton_rtol=1e-9)
    with pytest.raises(mbdk.RedundantConstraintsError, match="trapezoidal_index3"):
        mbdk.simulate(mbdk.scene("parallelogram_redundant"), method, formulation=form,
                      t_end=1.0)


def test_dae_forms_belong_to_their_methods():
    sc = mbdk.scene("double_pendulum")
    with pytest.raises(mbdk.InvalidInputError, match="ida runs 'ggl'"):
        mbdk.simulate(sc, "bdf", formulation="ggl", t_end=1.0)
    with pytest.raises(mbdk.InvalidInputError, match="bdf runs 'i3'"):
        mbdk.simulate(sc, "ida", formulation="i3", t_end=1.0)
    with pytest.raises(mbdk.InvalidInputError, match="bdf runs 'si2'"):
        mbdk.simulate(sc, "dopri54", formulation="si2", t_end=1.0)


@pytest.mark.parametrize("method", ["bdf", "cvode_bdf", "implicit_euler"])
def test_python_jacobian_is_used_and_its_size_checked(method):
    """A Python right-hand side with its Jacobian: the implicit methods call jac instead of
    differencing F (each Jacobian by differences costs n + 1 evaluations of F here, or n in
    CVODE), give the same solution, and count every call; a Jacobian of the wrong size is a
    named error before the first step, one that raises later a CallbackError."""
    a_mat = np.array([[-1.0e3, 1.0], [0.0, -2.0]])
    calls = []

    def f(t, y):
        return a_mat @ y

    def jac(t, y):
        calls.append(t)
        return a_mat

    kw = dict(h=1e-2) if method == "implicit_euler" else dict(rtol=1e-8, atol=1e-10)
    fd = mbdk.solve_ode(f, method, y0=[1.0, 1.0], t_end=1.0, **kw)
    an = mbdk.solve_ode(f, method, y0=[1.0, 1.0], t_end=1.0, jac=jac, **kw)
    assert np.allclose(an.y, fd.y, rtol=1e-8, atol=1e-12)
    assert an.stats.njev == len(calls) - 1     # one call more: the shape check at t0
    per_jac = 2 if method == "cvode_bdf" else 3
    assert an.stats.nfev == fd.stats.nfev - per_jac * fd.stats.njev or method == "cvode_bdf"
    assert an.stats.nfev < fd.stats.nfev and an.manifest["jacobian"] == "python jac"
    with pytest.raises(mbdk.InvalidInputError, match=r"shape \(3, 3\).*2 x 2"):
        mbdk.solve_ode(f, method, y0=[1.0, 1.0], t_end=1.0, jac=lambda t, y: np.eye(3), **kw)

    seen = []

    def late(t, y):       # passes the shape check, fails in the kernel's first call
        seen.append(t)
        if len(seen) > 1:
            raise RuntimeError("no Jacobian here")
        return a_mat
    with pytest.raises(mbdk.CallbackError, match="no Jacobian here"):
        mbdk.solve_ode(f, method, y0=[1.0, 1.0], t_end=1.0, jac=late, **kw)
    with pytest.raises(mbdk.InvalidInputError, match="compiled problem"):
        mbdk.solve_ode("decay", method, t_end=1.0, jac=jac, **kw)
