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
    """The power of the test above (no kernel code runs here but the quaternion product): the
    same body integrated in Python with the space-frame kinematics q' = (0, Omega) q / 2, wrong
    for a body-frame Omega, turns L by far more than that test allows."""
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


def test_heavy_top_precesses_steadily_at_the_classical_rate():
    """The Lagrange top started on a steady precession: with theta' = 0 the tilt stays constant
    when m g l = phi' (J3 w3 - J1 phi' cos(theta)) (Goldstein, Classical Mechanics, 5.7; the
    slow root), and the symmetry axis goes round the vertical at phi'. The start is built
    with mbdk.rotations' 3-1-3 angles and their rate map G_b."""
    from mbdk import rotations as rot
    p = mbdk.problems()["heavy_top"].params
    th, w3 = np.radians(40.0), 60.0
    mgl = p["m"] * p["g"] * p["l"]
    c = np.cos(th)
    phid = (p["J3"] * w3 - np.sqrt((p["J3"] * w3) ** 2 - 4 * p["J1"] * c * mgl)) / (2 * p["J1"] * c)
    rates = np.array([phid, 0.0, w3 - phid * c])        # (phi', theta', psi')
    _, gb = rot.angle_rate_maps([0.0, th, 0.0], "313")
    q0 = rot.to_quaternion(rot.from_angles([0.0, th, 0.0], "313"))
    r = mbdk.solve_ode("heavy_top", "rk4", h=2e-4, t_end=2.0, every=50,
                       y0=np.r_[q0, gb @ rates])
    q = r.y[:, :4] / np.linalg.norm(r.y[:, :4], axis=1)[:, None]
    # the symmetry axis in space, R e3 = (sin(phi) sin(theta), -cos(phi) sin(theta), cos(theta))
    ax = np.stack([2 * (q[:, 1] * q[:, 3] + q[:, 0] * q[:, 2]),
                   2 * (q[:, 2] * q[:, 3] - q[:, 0] * q[:, 1]),
                   q[:, 0] ** 2 - q[:, 1] ** 2 - q[:, 2] ** 2 + q[:, 3] ** 2], axis=1)
    assert np.abs(ax[:, 2] - c).max() < 1e-9
    phi = np.unwrap(np.arctan2(ax[:, 0], -ax[:, 1]))
    assert np.abs(phi - phid * r.t).max() < 1e-8


def test_heavy_top_keeps_its_three_invariants():
    """Released from rest in precession (it nutates): the energy, the vertical component of
    the angular momentum about the fixed point (gravity's torque is horizontal) and the spin
    J3 W3 about the symmetry axis (J1 = J2) stay constant."""
    info = mbdk.problems()["heavy_top"]
    r = mbdk.solve_ode("heavy_top", "rk4", h=1e-4, t_end=3.0, every=100)
    e = info.energy(r.y, info.params)
    lz = rigid_body_momentum(r.y, info.params)[:, 2]
    assert np.abs(e - e[0]).max() < 1e-10 * abs(e[0])
    assert np.abs(lz - lz[0]).max() < 1e-10 * abs(lz[0])
    assert np.abs(r.y[:, 6] - r.y[0, 6]).max() < 1e-10 * abs(r.y[0, 6])
    # and it does nutate: the tilt is not constant
    z3 = r.y[:, 0] ** 2 - r.y[:, 1] ** 2 - r.y[:, 2] ** 2 + r.y[:, 3] ** 2
    assert z3.max() - z3.min() > 1e-4


@pytest.mark.parametrize("seq", [313.0, 123.0])
def test_angle_parametrisations_follow_the_quaternion_motion(seq):
    """rigid_body_angles (a' = G_b(a)^-1 Omega) and free_rigid_body (quaternions) from the
    same orientation give the same rotation matrix after 5 s, away from the locks."""
    from mbdk import rotations as rot
    a0 = np.array([0.3, 0.5, -0.2])
    w = [0.01, 1.0, 0.01]
    s = str(int(seq))
    r1 = mbdk.solve_ode("rigid_body_angles", "rk4", h=1e-3, t_end=5.0, y0=np.r_[a0, w],
                        params={"sequence": seq}, every=5000)
    q0 = rot.to_quaternion(rot.from_angles(a0, s))
    r2 = mbdk.solve_ode("free_rigid_body", "rk4", h=1e-3, t_end=5.0, y0=np.r_[q0, w],
                        every=5000)
    ra = rot.from_angles(r1.y[-1, :3], s)
    rq = rot.from_quaternion(r2.y[-1, :4] / np.linalg.norm(r2.y[-1, :4]))
    assert np.abs(ra - rq).max() < 1e-11
    assert np.abs(r1.y[-1, 3:] - r2.y[-1, 4:]).max() < 1e-12


def test_euler_angles_at_their_lock_stop_by_name():
    """Started at theta = 0, the 3-1-3 rates are undefined: the solve stops with
    SingularMatrixError before its first step, not with a NaN state."""
    with pytest.raises(mbdk.SingularMatrixError):
        mbdk.solve_ode("rigid_body_angles", "rk4", h=1e-3, t_end=1.0,
                       y0=[0.0, 0.0, 0.0, 0.1, 0.2, 1.0])
    with pytest.raises(mbdk.InvalidInputError, match="313"):
        mbdk.solve_ode("rigid_body_angles", "rk4", h=1e-3, t_end=1.0,
                       params={"sequence": 321.0})
