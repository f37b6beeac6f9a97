"""Each hard case of issue 36 gives a correct result or a named error that names its true cause:
where a failed run stopped, the advice that fits the method, a step beyond a method's stability
limit, a stage landing on a rank loss, a stage overrunning a contact, the extrapolated index-3
control next to a rank loss, gears out of mesh at the assembled pose, the book scheme's
multipliers. References say where they come from."""
from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

import mbdk
from mbdk.benchmarks import a02_chain, a02_crank
from mbdk.scene_file import scene_from_dict
from mbdk.spatial_model import evaluate_spatial
from mbdk.stability import spectral_radius, unstable_mode


def test_failure_names_where_the_run_stopped_not_its_last_sample():
    """rk4 on the flyball governor at h = 1e-3 with samples every 1000 steps: the last sample
    is t = 0, yet the run reached the step after which it failed; stats.t_reached gives it
    and the message names it (it said "t = 0" before)."""
    with pytest.raises(mbdk.MbdkError) as exc:
        mbdk.simulate(mbdk.scene("flyball_governor"), "rk4", h=1e-3, t_end=1.0, every=1000)
    r = exc.value.result
    assert r.t[-1] == 0.0 and r.stats.steps >= 1
    assert r.stats.t_reached == pytest.approx(r.stats.steps * 1e-3)
    assert f"after t = {r.stats.t_reached:.6g}" in str(exc.value)


def test_stats_t_reached_of_successful_runs():
    """t_reached is the last step's time on every driver: fixed step, error control, SUNDIALS,
    index-3."""
    assert mbdk.solve_ode("double_pendulum", "rk4", h=0.01, t_end=0.5).stats.t_reached == 0.5
    sc = mbdk.scene("double_pendulum")
    for method, kw in (("dopri54", {"rtol": 1e-8}), ("bdf", {"rtol": 1e-8}),
                       ("cvode_bdf", {"rtol": 1e-8}), ("ida", {"rtol": 1e-8}),
                       ("trapezoidal_index3", {"h": 1e-3})):
        r = mbdk.simulate(sc, method, t_end=0.25, outputs=(), **kw)
        assert r.stats.t_reached == pytest.approx(0.25), method


def test_error_controlled_failures_do_not_advise_a_smaller_step():
    """ida and bdf choose their own steps: their Newton failures advise the tolerances, not
    "reduce the step h" (which asked ida for what it had tried)."""
    with pytest.raises(mbdk.NewtonDivergedError) as exc:
        mbdk.simulate(mbdk.scene("flyball_governor"), "ida", formulation="ggl", rtol=1e-13,
                      atol=1e-15, t_end=1.5, dt_out=0.5)
    assert "reduce the step h" not in str(exc.value)
    assert "loosen rtol and atol" in str(exc.value)


def test_spatial_baumgarte_under_error_control_asks_for_its_gains():
    """Spatial baumgarte under an error-controlled method took alpha = 1/(1e-3 (t_end - t0)),
    gains that depended on t_end; it is refused as on planar scenes."""
    with pytest.raises(mbdk.InvalidInputError, match="give alpha and beta"):
        mbdk.simulate(mbdk.scene("heavy_top"), "dopri54", formulation="baumgarte", rtol=1e-6,
                      t_end=1.0)
    r = mbdk.simulate(mbdk.scene("heavy_top"), "dopri54", formulation="baumgarte", rtol=1e-6,
                      t_end=0.1, alpha=20.0, beta=20.0, outputs=())
    assert r.success and r.manifest["alpha"] == 20.0


def test_a_step_beyond_the_stability_limit_is_named():
    """rk4 on the flyball governor at h = 1e-3 failed, said to be a rank loss at t = 0; its
    stiff dampers' mode lies beyond rk4's stability interval at that h. The message names the
    mode and the largest stable h, which agrees with rk4's real stability limit (-2.785, the
    root of |R(z)| = 1 on the real axis) over that mode's eigenvalue, computed here from the
    Jacobian of the scene's reduced ODE by numpy."""
    with pytest.raises(mbdk.MbdkError) as exc:
        mbdk.simulate(mbdk.scene("flyball_governor"), "rk4", h=1e-3, t_end=0.5)
    text = str(exc.value)
    assert "beyond rk4's stability limit" in text and "rank" not in text
    r = exc.value.result
    y = np.concatenate([r.q[-1], r.v[-1]])
    sc = mbdk.scene("flyball_governor")
    jac = np.empty((y.size, y.size))
    for j in range(y.size):                 # central differences of the reduced ODE
        d = 1e-7 * max(abs(y[j]), 1.0)
        yp, ym = y.copy(), y.copy()
        yp[j] += d
        ym[j] -= d
        jac[:, j] = (evaluate_spatial(sc, yp, r.t[-1])["ydot"] -
                     evaluate_spatial(sc, ym, r.t[-1])["ydot"]) / (2 * d)
    lam = np.linalg.eigvals(jac)
    fastest = lam[np.argmin(lam.real)]
    assert abs(fastest.imag) < 1e-6 * abs(fastest)          # the dampers: a real mode
    limit = -2.785293563405282 / fastest.real
    h_max = float(re.search(r"a step below ([0-9.e+-]+) s", text).group(1))
    assert h_max == pytest.approx(limit, rel=1e-2) and limit < 1e-3


def test_unstable_mode_from_a_jacobian():
    """mbdk.stability.unstable_mode on a damped oscillator (lambda = -1000 and -1 j 1/s):
    explicit_euler at h = 3e-3 amplifies the damped mode (|1 - 3| > 1), its largest stable
    step is 2e-3 (the interval [-2, 0]); implicit_euler amplifies nothing; a growing mode
    (Re lambda > 0) is not the method's fault."""
    jac = np.diag([-1000.0, -1.0])
    m = unstable_mode("explicit_euler", 3e-3, jac)
    assert m["lambda"] == pytest.approx(-1000.0) and m["h_max"] == pytest.approx(2e-3, rel=1e-6)
    assert m["growth"] == pytest.approx(2.0)
    assert unstable_mode("implicit_euler", 3e-3, jac) is None
    assert unstable_mode("explicit_euler", 1e-3, np.diag([50.0, -1.0])) is None
    assert spectral_radius("explicit_euler", [m["h_max"] * -1000.0])[0] == pytest.approx(1.0)


def test_rk4_projection_passes_a_stage_on_the_flat_pose():
    """The IFToMM A02 loop with rk4 and the projection formulation at h = 1e-4: a stage landing
    on the flat pose met a singular D M^-1 D^T (SingularMatrixError, blaming "a Newton matrix"
    an explicit method has not). The projection and Baumgarte forms take the regular path of
    the constrained solve there; the crank angle agrees with the exact one (Jacobi elliptic
    functions, mbdk.benchmarks.a02_crank) over several flat poses."""
    sc = a02_chain(1)
    r = mbdk.simulate(sc, "rk4", formulation="projection", h=1e-4, t_end=3.0, every=1000,
                      outputs=())
    theta, _ = a02_crank(1, r.t)
    assert r.q[-1, 2] < -np.pi                      # through the flat poses at 0.71 s and on
    assert np.abs(r.q[:, 2] - theta).max() < 1e-6


def test_dopri54_rejects_a_stage_that_overruns_a_contact():
    """The PLA gear pair with dopri54: a trial stage of a step too long across the mesh's load
    changes overran the flanks, and the run ended with ContactOverrunError at t = 0.13 at every
    rtol (rk4 at h = 2e-6 runs through). dopri54 now rejects such a step and agrees with rk4
    at h = 2e-6 at t = 0.3 s (gear 2 has turned 33 rad)."""
    sc = mbdk.scene("pla_gears")
    ref = mbdk.simulate(sc, "rk4", h=2e-6, t_end=0.3, every=150000, outputs=())
    r = mbdk.simulate(sc, "dopri54", rtol=1e-8, atol=1e-10, t_end=0.3, dt_out=0.3, outputs=())
    assert np.abs(r.q[-1] - ref.q[-1]).max() < 1e-7 * np.abs(ref.q[-1]).max()   # 33 rad turned


def test_extrapolated_index3_next_to_a_rank_loss_names_the_remedy():
    """The two-loop A02 chain with the extrapolated control at err_rtol = err_atol = 1e-8 stops
    at its first flat pose (t = 0.7145): there the three solves of a macro step differ by their
    residuals amplified along the vanishing direction, whatever H. The error says so and names
    what passes: adaptive='estimated' at the same tolerance runs through, and its crank angle
    agrees with the exact one."""
    sc = a02_chain(2)
    with pytest.raises(mbdk.StepTooSmallError) as exc:
        mbdk.simulate(sc, "trapezoidal_index3", h=1e-3, t_end=2.0, adaptive=True, err_rtol=1e-8,
                      err_atol=1e-8, dt_out=0.01)
    assert "adaptive='estimated'" in str(exc.value) and "losing a rank" in str(exc.value)
    assert exc.value.result.stats.t_reached == pytest.approx(0.7145, abs=1e-3)
    r = mbdk.simulate(sc, "trapezoidal_index3", h=1e-3, t_end=2.0, adaptive="estimated",
                      err_rtol=1e-8, err_atol=1e-8, dt_out=0.1)
    theta, _ = a02_crank(2, r.t)
    assert np.abs(r.q[:, 2] - theta).max() < 1e-3


def _gears(axle_x):
    src = mbdk.scene("pla_gears")
    d = {"scene": {"name": "gears", "description": "pla_gears with gear 2's axle moved"},
         "body": [{"name": b.name, "mass": b.mass, "inertia": b.inertia, "x": b.x, "y": b.y,
                   "given": ["angle"]} for b in src.bodies],
         "joint": [{"name": "axle1", "type": "revolute", "body1": "gear1"},
                   {"name": "axle2", "type": "revolute", "body1": "gear2",
                    "point2": [axle_x, 0.0]}],
         "force": [{"name": "drive", "type": "torque", "body": "gear1", "torque": 0.1},
                   {"name": "mesh", "type": "contact", "body1": "gear1", "body2": "gear2",
                    "shape1": {"type": "gear", "teeth": 80, "module": 1.35e-3},
                    "shape2": {"type": "gear", "teeth": 40, "module": 1.35e-3},
                    "stiffness": 1e8, "exponent": 1.5, "damping": 10.0,
                    "damping_depth": 1e-6, "backlash": 1e-4}]}
    return scene_from_dict(d)


@pytest.mark.parametrize("axle_x, what", [(0.09, "path of contact"),
                                          (0.0675, "base radii")])
def test_gears_are_checked_where_the_axles_put_them(axle_x, what):
    """Gear 2 written at x = 0.081 m (the standard centre distance) but on an axle at 0.09 m
    (out of mesh: the run returned SUCCESS) or 0.0675 m (inside the base circles: it ended
    NonFiniteSolutionError advising a smaller h): the mesh is checked at the assembled pose
    and refused by name."""
    with pytest.raises(mbdk.SceneError, match=what) as exc:
        mbdk.simulate(_gears(axle_x), "rk4", h=1e-5, t_end=0.01)
    assert "'mesh'" in str(exc.value) and "assemble" in str(exc.value)
    assert mbdk.simulate(_gears(0.081), "rk4", h=1e-5, t_end=0.01, outputs=()).success


def test_book_scheme_multipliers_are_flagged():
    """The book's index-3 scheme's multipliers carry an error that grows as h shrinks: a run
    that returns them warns (AccuracyWarning) and its manifest says so; the augmented Lagrangian
    form's do not."""
    sc = mbdk.scene("physical_pendulum")
    with pytest.warns(mbdk.AccuracyWarning, match="grows as h shrinks"):
        r = mbdk.simulate(sc, "trapezoidal_index3", formulation="index3", h=1e-3, t_end=0.1)
    assert "not converged" in r.manifest["multipliers"]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = mbdk.simulate(sc, "trapezoidal_index3", h=1e-3, t_end=0.1)
        mbdk.simulate(sc, "trapezoidal_index3", formulation="index3", h=1e-3, t_end=0.1,
                      outputs=("energy",))
    assert "multipliers" not in r.manifest


def test_ggl_multipliers_below_their_floor_are_flagged():
    """ida tests its multipliers no tighter than 1e-8 of the largest, in both forms (the
    roundoff of its iteration: at rtol 1e-11 the flyball governor's index1 run passed or
    stalled depending on the last bits of its tolerances): a run at rtol 1e-10 that returns
    them warns and says so in its manifest, and its multipliers agree with bdf's si2 form's
    (tested to the tolerance) to that floor, not to rtol; at rtol 1e-7 nothing is said."""
    sc = mbdk.scene("double_pendulum")
    kw = dict(rtol=1e-10, atol=1e-12, t_end=0.3, dt_out=0.3)
    si2 = mbdk.simulate(sc, "bdf", formulation="si2", **kw)
    scale = np.abs(si2.multipliers[-1]).max()
    for form in ("ggl", "index1"):
        with pytest.warns(mbdk.AccuracyWarning, match="1e-08 of the largest multiplier"):
            r = mbdk.simulate(sc, "ida", formulation=form, **kw)
        assert "rtol = 1e-10" in r.manifest["multipliers"]
        assert np.abs(r.multipliers[-1] - si2.multipliers[-1]).max() < 1e-6 * scale
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = mbdk.simulate(sc, "ida", formulation="ggl", rtol=1e-7, atol=1e-9, t_end=0.3)
    assert "multipliers" not in r.manifest


def test_the_largest_stable_step_along_a_mode():
    """unstable_mode's largest stable step is the first loss of stability along the mode's
    ray from h = 0, found by a scan and bisection on the method's own step matrix. bdf2 is
    A-stable: no damped mode is unstable at any h. rk4 on an undamped oscillation (omega =
    10 1/s) at h omega = 2.9 lies beyond its imaginary-axis limit 2 sqrt(2) (the root of
    |R(i y)| = 1 for rk4's polynomial R), so h_max = 2 sqrt(2) / 10."""
    osc = np.array([[0.0, 1.0], [-100.0, -0.2]])
    assert unstable_mode("bdf2", 0.5, osc) is None
    m = unstable_mode("rk4", 0.29, np.array([[0.0, 1.0], [-100.0, 0.0]]))
    assert m is not None
    assert m["h_max"] * 10.0 == pytest.approx(2.0 * np.sqrt(2.0), rel=1e-6)
