"""The torque-free rigid body (compiled problem free_rigid_body: Euler's equations in the body
frame and the quaternion kinematics of mbdk_rotations) against its closed forms and
invariants."""
import numpy as np
import pytest

import mbdk
from mbdk.problems import rigid_body_momentum


def test_symmetric_body_precesses_at_the_closed_form_rate():
    """J1 = J2: Omega3 stays constant and (Omega1, Omega2) turns at lambda = (J3 - J1) / J1
    Omega3 (Euler's equations solved by hand): Omega1 = a cos(lambda t), Omega2 = a sin."""
    p = {"J1": 1.0, "J2": 1.0, "J3": 1.6}
    w3, a = 2.0, 0.3
    r = mbdk.solve_ode("free_rigid_body", "rk4", h=1e-3, t_end=5.0, params=p, every=100,
                       y0=[1, 0, 0, 0, a, 0, w3])
    lam = (p["J3"] - p["J1"]) / p["J1"] * w3
    assert np.abs(r.y[:, 4] - a * np.cos(lam * r.t)).max() < 1e-10
    assert np.abs(r.y[:, 5] - a * np.sin(lam * r.t)).max() < 1e-10
    assert np.abs(r.y[:, 6] - w3).max() < 1e-13


def test_intermediate_axis_flips_and_keeps_energy_and_angular_momentum():
    """The default start spins near the intermediate axis (J2 = 2 between 1 and 3): Omega2
    reverses (the intermediate-axis, or Dzhanibekov, flip) while the kinetic energy and the
    space-frame angular momentum L = R(q) J Omega stay what they were (the torque-free
    invariants). L constant as a vector also checks the quaternion kinematics: with the
    space-frame rate formula in place of the body-frame one, L would turn."""
    info = mbdk.problems()["free_rigid_body"]
    r = mbdk.solve_ode("free_rigid_body", "rk4", h=1e-3, t_end=30.0, every=10)
    assert r.y[:, 5].min() < -0.9 and r.y[:, 5].max() > 0.9          # flipped and back
    e = info.energy(r.y, info.params)
    assert np.abs(e - e[0]).max() < 1e-9 * e[0]
    big_l = rigid_body_momentum(r.y, info.params)
    assert np.abs(big_l - big_l[0]).max() < 1e-8 * np.linalg.norm(big_l[0])
    assert np.abs(np.linalg.norm(r.y[:, :4], axis=1) - 1).max() < 1e-9


def test_the_wrong_frame_would_be_seen():
    """Independent check of the test above: the same body integrated here in Python with the
    space-frame kinematics q' = (0, Omega) q / 2 (wrong for a body-frame Omega) turns L."""
    from mbdk.rotations import quaternion_product
    p = {"J1": 1.0, "J2": 2.0, "J3": 3.0}
    y = np.array([1.0, 0, 0, 0, 0.4, 1.0, 0.3])
    jv = np.array([1.0, 2.0, 3.0])

    def f(y):
        w = y[4:]
        qd = 0.5 * quaternion_product(np.r_[0.0, w], y[:4])
        return np.r_[qd, np.cross(jv * w, w) / jv]
    h = 1e-3
    l0 = rigid_body_momentum(y, p)[0]
    for _ in range(2000):
        k1 = f(y); k2 = f(y + h / 2 * k1); k3 = f(y + h / 2 * k2); k4 = f(y + h * k3)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    assert np.linalg.norm(rigid_body_momentum(y, p)[0] - l0) > 1e-2


def test_bad_inertias_are_refused():
    with pytest.raises(mbdk.InvalidInputError, match="'J3'.*no rigid body"):
        mbdk.solve_ode("free_rigid_body", "rk4", h=1e-3, t_end=1.0,
                       params={"J1": 1.0, "J2": 1.0, "J3": 3.0})       # J3 > J1 + J2
    with pytest.raises(mbdk.InvalidInputError):
        mbdk.solve_ode("free_rigid_body", "rk4", h=1e-3, t_end=1.0,
                       params={"J1": -1.0, "J2": 2.0, "J3": 2.0})
