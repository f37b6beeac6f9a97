"""Every scene run watches what it must keep (kernel/src/model/mbdk_watch.f90, mbdk.watch): the
constraint residuals and the energy balance. Each test here could fail: runs that used to return
SUCCESS with the answer of another mechanism must now stop by name, and sound runs, damped and
driven ones included, must not raise false alarms, whatever the scene's units."""
import math

import numpy as np
import pytest

import mbdk


def _balance(r):
    """E - E0 - W from the run's own outputs (the kernel's energy parts and powers at the
    samples, W by the trapezoidal rule over the samples in Python): an independent computation
    of what the watch tests."""
    p = r.energy_parts
    power = -p["power_dampers"] + p["power_constraints"] + p["power_loads"]
    w = np.concatenate([[0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(r.t))])
    return r.energy - r.energy[0] - w


def test_a_pendulum_spun_to_1e6_rad_per_s_is_not_a_success():
    """rk4 on the reduced form at h = 1e-3 with omega = 1e6 rad/s: h omega = 1000, far outside
    any stability region. Unwatched it returns SUCCESS with the bar thousands of metres off its
    hinge; watched it stops at the first check, naming the hinge."""
    sc = mbdk.scene("physical_pendulum")
    sc.bodies[0].omega = 1e6
    free = mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0, watch=False)
    assert free.success and free.residuals[:, 0].max() > 1e3
    with pytest.raises(mbdk.ConstraintDriftError) as err:
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0)
    msg = str(err.value)
    assert "joint 'hinge'" in msg and "t = 0.001" in msg and "position" in msg
    assert err.value.result.t[-1] == 0.0       # only the initial state passed its check


def test_the_book_index3_scheme_blowing_up_is_named_where_it_starts():
    """The book's scheme on the double pendulum at h = 10/2000 keeps Phi = 0 while its energy
    grows without bound (unwatched: |E| above 1e6 J from 43 J, until at about 9 s its Newton
    iteration diverges, or it reaches 10 s: which one depends on the roundoff of the blown-up
    iterates); the energy watch stops it. Its velocities are the trapezoidal rule's and do not
    satisfy Phi' = 0 (its formulation does not promise them), so the velocity test is not what
    stops it."""
    sc = mbdk.scene("double_pendulum")
    kw = dict(formulation="index3", h=10 / 2000, t_end=10.0, every=10)
    free = mbdk.simulate(sc, "trapezoidal_index3", watch=False, raise_on_failure=False, **kw)
    assert free.t[-1] > 8.0 and np.abs(free.energy).max() > 1e6
    assert free.success or free.status.name == "ERR_NEWTON_DIVERGED"
    # the energy jumps from within its tolerance to 1e7 J in one step near 9 s: either the
    # watch names it there, or Newton diverges in that step (before the watch sees it)
    with pytest.raises((mbdk.EnergyDriftError, mbdk.NewtonDivergedError)) as err:
        mbdk.simulate(sc, "trapezoidal_index3", **kw)
    kept = err.value.result
    assert 0 < kept.t[-1] < 10.0
    assert np.abs(kept.energy - kept.energy[0]).max() < 0.1 * 2 * 43.3   # every sample sound
    if isinstance(err.value, mbdk.NewtonDivergedError):
        jump = free.t[np.argmax(np.abs(free.energy - free.energy[0]) > 0.1 * 43.3)]
        assert jump - 0.1 <= kept.t[-1] <= jump
        return
    # the unwatched run's balance at the failure time is past the tolerance already
    drift = kept.drift
    assert drift["quantity"] == "energy" and drift["t_good"] < drift["t"] <= drift["t_good"] + 0.1
    i = np.searchsorted(free.t, drift["t"])
    assert abs(_balance(free)[i]) > drift["tolerance"] * 43.0


def test_a_1e9_spring_that_loses_its_energy_in_one_step_is_named():
    """spring_bar with k = 1e9 N/m, stretched at t0 (1.25e8 J in the spring), projected index-3
    at h = 1e-3 (h omega ~ 30): unwatched, SUCCESS over 0.1 s with the energy 1e5 times its
    start (from t = 0.015; later, Newton may give up where the run has no meaning left);
    watched, EnergyDriftError at the first step."""
    sc = mbdk.scene("spring_bar")
    sc.forces[0].stiffness = 1e9
    free = mbdk.simulate(sc, "trapezoidal_index3", h=1e-3, t_end=0.1, watch=False)
    assert free.success and np.abs(free.energy).max() > 1e3 * abs(free.energy[0])
    with pytest.raises(mbdk.EnergyDriftError, match="t = 0.001"):
        mbdk.simulate(sc, "trapezoidal_index3", h=1e-3, t_end=1.0)


@pytest.mark.parametrize("name,method,h", [("trolley_crane", "rk4", 1e-3),
                                           ("spring_damper_bar", "rk4", 1e-3),
                                           ("double_pendulum", "trapezoidal_index3", 1e-3)])
def test_sound_runs_with_dampers_and_loads_pass_a_tight_energy_test(name, method, h):
    """The work of dampers is integrated at every step: a sound run keeps the balance to 1e-4 of
    the energy scale (a sign error in a power term, or work integrated only at the checks, would
    fail it: the trolley's damper takes 40 % of its energy within 2 s). The independent balance
    from the outputs agrees."""
    sc = mbdk.scene(name)
    r = mbdk.simulate(sc, method, h=h, t_end=2.0,
                      watch=mbdk.Watch(position=1e-6, velocity=1e-6, energy=1e-4))
    assert r.success
    scale = max(np.abs(r.energy_parts["kinetic"]).max(), np.abs(r.energy).max())
    assert np.abs(_balance(r)).max() < 1e-3 * scale
    if name == "trolley_crane":
        assert r.energy_parts["dissipated_dampers"][-1] > 0.4 * r.energy[0]


def test_a_driven_mechanism_counts_the_drivers_work():
    """A bar on a hinge driven at 2 rad/s (a driver on its angle) against gravity: the driver
    does work, so E = T + V swings by 2 m g (L/2) while E - E0 - W stays at the method's error.
    Without the drivers' power in W the check at 1e-4 would fail within the first turn."""
    from mbdk.scene import Joint
    sc = mbdk.scene("physical_pendulum")
    bar = sc.bodies[0]
    bar.omega = 2.0
    sc.joints.append(Joint("drive", "driver", bar.name, coordinate="angle",
                           function=(bar.angle, 2.0, 0.0, 0.0, 0.0)))
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=3.0, watch=mbdk.Watch(energy=1e-4))
    assert r.success
    assert np.ptp(r.energy) > 1.0                       # the driver moves energy in and out
    assert np.abs(_balance(r)).max() < 1e-3 * np.ptp(r.energy)


def _scaled(factor):
    """The double pendulum with every length times factor (masses kept)."""
    sc = mbdk.scene("double_pendulum")
    for b in sc.bodies:
        b.x *= factor
        b.y *= factor
        b.inertia *= factor ** 2
    for j in sc.joints:
        j.point1 = tuple(c * factor for c in j.point1)
        j.point2 = tuple(c * factor for c in j.point2)
    return sc


def test_the_watch_is_scale_aware():
    """The same motion in millimetres (every length times 1e-3; the time scale sqrt(L/g) shrinks
    by sqrt(1e3), so h does too) passes as it does in metres, and the same drift (explicit Euler
    at a relative step 30 times larger) is named in both."""
    for factor in (1.0, 1e-3):
        sc = _scaled(factor)
        h = 1e-4 * math.sqrt(factor)
        r = mbdk.simulate(sc, "rk4", h=h, t_end=2.0 * math.sqrt(factor), every=100)
        assert r.success
        with pytest.raises((mbdk.ConstraintDriftError, mbdk.EnergyDriftError)) as err:
            mbdk.simulate(sc, "explicit_euler", h=30 * h, t_end=20.0 * math.sqrt(factor))
        assert err.value.result.t[-1] / math.sqrt(factor) < 20.0


def test_the_samples_of_a_stopped_run_all_passed_their_checks():
    """raise_on_failure=False: the result ends at the last sample before the failed check, and
    every sample it holds is within the tolerances (positions against L = 2 m, the pendulum's
    spread)."""
    sc = mbdk.scene("double_pendulum")
    r = mbdk.simulate(sc, "explicit_euler", h=2e-3, t_end=20.0, every=5, raise_on_failure=False)
    assert r.status in (mbdk.Status.ERR_CONSTRAINT_DRIFT, mbdk.Status.ERR_ENERGY_DRIFT)
    assert r.t[-1] < 20.0 and "last check passed" in r.message
    assert r.residuals[:, 0].max() < 1e-2 * 2.0


def test_watch_off_and_other_tolerances_are_recorded_and_checked():
    sc = mbdk.scene("double_pendulum")
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.1, watch=False)
    assert r.manifest["watch"] == {"position": None, "velocity": None, "energy": None,
                                   "every": mbdk.Watch().every, "momentum": None,
                                   "quaternion": None}
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.1, watch={"energy": 1e-6, "every": 1})
    assert r.manifest["watch"]["energy"] == 1e-6 and r.manifest["watch"]["every"] == 1
    for bad, words in (({"energy": -1.0}, "watch.energy = -1.0"),
                       ({"every": 0}, "watch.every = 0"),
                       ({"positon": 1e-3}, "'positon' unknown"),
                       ("yes", "watch = 'yes'")):
        with pytest.raises(mbdk.InvalidInputError, match=words):
            mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.1, watch=bad)


def test_a_driven_redundant_mechanism_runs_watched_with_the_regular_multipliers():
    """The redundant parallelogram with its crank driven at 1 rad/s (and a free body falling
    beside it, so that the 13 rows do not outnumber the coordinates): D has lost a rank, so the
    watch's multipliers for the driver's power come from the regular path (the reduced solve is
    singular there). The run passes, its energy balance holds to 1e-4 of the scale, and the
    watch's own solves leave the visit counters as an unwatched run has them."""
    from mbdk.scene import Body, Joint
    sc = mbdk.scene("parallelogram_redundant")
    sc.bodies.append(Body("free", 1.0, 0.1, x=5.0, y=0.0))
    crank = sc.joints[0].body1
    body = next(b for b in sc.bodies if b.name == crank)
    body.omega = 1.0
    sc.joints.append(Joint("drive", "driver", crank, coordinate="angle",
                           function=(body.angle, 1.0, 0.0, 0.0, 0.0)))
    kw = dict(h=1e-3, t_end=2.0, every=10)
    r = mbdk.simulate(sc, "trapezoidal_index3", watch=mbdk.Watch(energy=1e-4), **kw)
    free = mbdk.simulate(sc, "trapezoidal_index3", watch=False, **kw)
    assert r.success and np.ptp(r.energy) > 1.0
    assert np.abs(_balance(r)).max() < 1e-3 * np.ptp(r.energy)
    assert r.visits == free.visits and np.array_equal(r.q, free.q)
