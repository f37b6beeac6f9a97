"""W, the work of dampers, loads and drivers, is the work the run integrated (issue 36): the
watch integrates it at every accepted step (error-controlled methods by the three-point Gauss
rule on their dense output inside each step, fixed-step ones by the trapezoidal rule on their
steps), and every sample, energy_balance(), `mbdk run`'s balance and the results files take
that W, not a quadrature over the samples, which measured the sampling: on a bouncing ball
max |E - E0 - W| went from 1 J at dt_out = 0.01 to 0.014 J at 1e-4 (E0 = 5.4 J)."""
import numpy as np
import pytest

import mbdk
from mbdk.scene import Joint
from mbdk.scene_file import scene_from_dict

G = 9.81


def bouncing_ball(depth=0.0):
    """A ball of 1 kg, radius 0.1 m, dropped from rest with its centre at 0.55 m (E0 = m g
    0.55 = 5.3955 J) onto a damped floor (k = 1e5 N/m, c = 20 N s/m: it loses energy at every
    bounce); depth > 0 ramps the damping in over that penetration."""
    return scene_from_dict({
        "scene": {"name": "bouncing_ball"},
        "body": [{"name": "ball", "mass": 1.0, "inertia": 0.004, "y": 0.55}],
        "force": [{"type": "contact", "name": "floor", "body1": "ball",
                   "shape1": {"type": "circle", "radius": 0.1},
                   "shape2": {"type": "line", "point": [0, 0], "normal": [0, 1]},
                   "stiffness": 1e5, "damping": 20.0, "damping_depth": depth},
                  {"type": "gravity", "g": [0, -G]}]}, "bouncing_ball.toml")


def sampled_work(r):
    """The work by the trapezoidal rule over the samples (what energy_balance used to take)."""
    p = r.energy_parts
    power = -p["power_dampers"] + p["power_constraints"] + p["power_loads"]
    return np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(r.t))])


def test_the_balance_of_a_bouncing_ball_does_not_depend_on_the_sampling():
    """dopri54 at rtol 1e-8 over 2 s (three bounces, 2.4 J dissipated): max |E - E0 - W| is the
    same at dt_out = 0.01, 1e-3 and 1e-4, below 1e-3 E0, where the quadrature over the samples
    gives 1 J at dt_out = 0.01. Its floor is the clipped contact's kink where the ball leaves
    (the potential k d^2/2 goes as the force stays 0, a kink no event marks); with the damping
    ramped in over 1 mm, the balance is 2e-5 E0 at every dt_out."""
    e0 = G * 0.55
    bal, old = {}, {}
    for dt in (0.01, 1e-3, 1e-4):
        r = mbdk.simulate(bouncing_ball(), "dopri54", rtol=1e-8, atol=1e-10, t_end=2.0,
                          dt_out=dt, outputs=("energy",))
        assert r.energy[0] == pytest.approx(e0) and r.energy[0] - r.energy[-1] > 2.0
        bal[dt] = np.abs(r.energy_balance()).max()
        old[dt] = np.abs(r.energy - r.energy[0] - sampled_work(r)).max()
    assert max(bal.values()) < 1.05 * min(bal.values()) and max(bal.values()) < 1e-3 * e0
    assert old[0.01] > 0.1 * e0 and old[0.01] > 100 * bal[0.01] and old[1e-3] > 10 * bal[1e-3]
    for dt in (0.01, 1e-3, 1e-4):
        r = mbdk.simulate(bouncing_ball(depth=1e-3), "dopri54", rtol=1e-8, atol=1e-10,
                          t_end=2.0, dt_out=dt, outputs=("energy",))
        assert np.abs(r.energy_balance()).max() < 2e-5 * e0, dt


def test_the_work_is_the_same_however_often_the_run_samples():
    """The same steps give the same W, bit for bit, whatever the sampling: rk4 sampled at every
    step and every 1000th, dopri54 at dt_out = 0.01 and 1e-4 (its steps do not depend on
    dt_out; the last sample is the last step's)."""
    a = mbdk.simulate(bouncing_ball(), "rk4", h=1e-5, t_end=1.0, every=1, outputs=("energy",))
    b = mbdk.simulate(bouncing_ball(), "rk4", h=1e-5, t_end=1.0, every=1000,
                      outputs=("energy",))
    assert np.array_equal(a.energy_parts["work"][::1000], b.energy_parts["work"])
    assert b.energy_parts["work"][-1] < -0.5                  # the floor's damper took its share
    c = mbdk.simulate(bouncing_ball(), "dopri54", rtol=1e-8, atol=1e-10, t_end=1.0,
                      dt_out=0.01)
    d = mbdk.simulate(bouncing_ball(), "dopri54", rtol=1e-8, atol=1e-10, t_end=1.0,
                      dt_out=1e-4)
    assert c.stats.steps == d.stats.steps
    assert c.energy_parts["work"][-1] == d.energy_parts["work"][-1]
    # the parts add up to W
    p = d.energy_parts
    assert np.allclose(p["work"], p["work_loads"] + p["work_constraints"]
                       - p["dissipated_dampers"], rtol=0, atol=1e-14)


def driven_pendulum():
    """The physical pendulum driven at 2 rad/s by a driver on its angle: the driver's work
    swings E by 2 m g (L/2) each turn."""
    sc = mbdk.scene("physical_pendulum")
    bar = sc.bodies[0]
    bar.omega = 2.0
    sc.joints.append(Joint("drive", "driver", bar.name, coordinate="angle",
                           function=(bar.angle, 2.0, 0.0, 0.0, 0.0)))
    return sc


@pytest.mark.parametrize("method, kw", [
    ("dopri54", {}), ("bs32", {}), ("bdf", {}), ("cvode_bdf", {}),
    ("ida", {"formulation": "index1"}), ("ida", {"formulation": "ggl"}),
    ("bdf", {"formulation": "i3"}), ("bdf", {"formulation": "si2"})])
def test_every_error_controlled_method_integrates_the_drivers_work(method, kw):
    """The driven pendulum over 3 s at rtol 1e-9: max |E - E0 - W| stays below 1e-5 of E's
    swing (10 J) at dt_out = 0.1 and 1e-3, and W at their common times agrees to 1e-7 of it
    (the same steps; a sample inside a step takes W from the quadratic through the step's
    nodes); the drivers' power in W is the model's, at the step's Gauss nodes (the DAE forms:
    with their own multipliers). The quadrature over the samples at dt_out = 0.1 is off by
    more than 1e-3."""
    sc = driven_pendulum()
    runs = [mbdk.simulate(sc, method, rtol=1e-9, atol=1e-11, t_end=3.0, dt_out=dt, **kw)
            for dt in (0.1, 1e-3)]
    swing = np.ptp(runs[0].energy)
    assert swing > 5.0
    for r in runs:
        assert np.abs(r.energy_balance()).max() < 1e-5 * swing
    assert np.abs(runs[0].energy_parts["work"] -
                  runs[1].energy_parts["work"][::100]).max() < 1e-7 * swing
    assert np.abs(runs[0].energy - runs[0].energy[0] - sampled_work(runs[0])).max() > 1e-3


def test_fixed_step_and_index3_runs_take_the_trapezoidal_rule_on_their_steps():
    """rk4 and trapezoidal_index3 on the spring-and-damper bar, sampled every 50 steps: W's
    error is the rule's O(h^2) over the steps, so halving h quarters the balance."""
    for method in ("rk4", "trapezoidal_index3"):
        bal = [np.abs(mbdk.simulate(mbdk.scene("spring_damper_bar"), method, h=h, t_end=2.0,
                                    every=50).energy_balance()).max() for h in (2e-3, 1e-3)]
        assert 3.5 < bal[0] / bal[1] < 4.5, (method, bal)


def spatial_damped():
    """A body on a spherical joint hanging from a spring-damper to the ground, under gravity."""
    return scene_from_dict({
        "body": [{"name": "x", "kind": "spatial", "mass": 2.0, "inertia": [0.02, 0.03, 0.04],
                  "position": [0.3, 0.0, 0.0], "omega_body": [0.0, 0.0, 1.0],
                  "velocity": [0.0, 0.3, 0.0]}],
        "joint": [{"name": "s", "type": "spherical", "body1": "x", "at": [0.0, 0.0, 0.0]}],
        "force": [{"type": "gravity", "g": [0.0, 0.0, -G]},
                  {"type": "spring_damper", "body1": "x", "point1": [0.3, 0.0, 0.0],
                   "at2": [0.6, 0.4, 0.2], "stiffness": 50.0, "damping": 2.0,
                   "rest_length": 0.2}]}, "damped.toml")


@pytest.mark.parametrize("method, kw", [("dopri54", {}), ("bdf", {"formulation": "i3"}),
                                        ("ida", {"formulation": "index1"})])
def test_spatial_runs_report_the_work_they_integrated(method, kw):
    """A spatial scene's energy_parts["work"] is the kernel's too: the balance at dt_out = 0.1
    and 1e-3 is below 1e-6 J beside the damper's 0.5 J or more, and W at their common times
    agrees to 1e-7 J."""
    runs = [mbdk.simulate(spatial_damped(), method, rtol=1e-9, atol=1e-11, t_end=2.0,
                          dt_out=dt, **kw) for dt in (0.1, 1e-3)]
    for r in runs:
        assert r.energy_parts["work"][-1] < -0.5
        assert np.abs(r.energy_balance()).max() < 1e-6
    assert np.abs(runs[0].energy_parts["work"] -
                  runs[1].energy_parts["work"][::100]).max() < 1e-7
