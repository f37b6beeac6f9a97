"""Spatial scenes (kernel/src/spatial/mbdk_spatial_model.f90): the kinematics of
every joint against differences of Phi, the scenes against the compiled chapter-5 problems and
the planar model, closed forms for the joints, the quaternion norm, gimbal lock and bad input.

References: free_rigid_body and heavy_top are the compiled problems (Euler's equations with the
quaternion kinematics, tests/test_rigid_body.py checks them against closed forms); the planar
double pendulum is the planar model (tests/test_scenes.py); the sliding and falling bodies are
x = g t^2 / 2 along the free direction; the physical pendulum's small-angle period is
2 pi sqrt(J_O / (m g d))."""
import copy
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

import mbdk
from mbdk.rotations import quaternion_product
from mbdk.scene import GROUND
from mbdk.scene_file import scene_from_dict
from mbdk.spatial_model import evaluate_spatial

G = 9.81


def body(name, mass=1.0, inertia=(0.1, 0.2, 0.25), **kw):
    return {"name": name, "kind": "spatial", "mass": mass, "inertia": list(inertia), **kw}


def every_joint_scene(rotation="quaternion"):
    """Six bodies, one joint of each type, in general positions (the rows need not hold: the
    kinematics is checked off the manifold as well)."""
    return scene_from_dict({
        "scene": {"name": "joints", "rotation": rotation},
        "body": [body("a", position=[0.1, 0.2, 0.3], cardan123=[0.3, -0.2, 0.5],
                      omega_body=[0.4, -0.3, 0.9], velocity=[0.2, 0.1, -0.3]),
                 body("b", 2.0, (0.3, 0.2, 0.4), position=[0.8, 0.1, -0.2],
                      cardan123=[-0.4, 0.6, 0.1]),
                 body("c", position=[0.2, -0.7, 0.5], cardan123=[0.2, 0.2, -0.9]),
                 body("d", position=[-0.5, 0.4, 0.1], cardan123=[1.0, -0.3, 0.2]),
                 body("e", position=[0.3, 0.9, -0.6], cardan123=[-0.7, 0.1, 0.4]),
                 body("f", position=[-0.2, -0.3, 0.8], cardan123=[0.5, 0.4, -0.3])],
        "joint": [{"name": "s", "type": "spherical", "body1": "a", "at": [0.3, 0.2, 0.1]},
                  {"name": "r", "type": "revolute", "body1": "b", "body2": "a",
                   "at": [0.5, 0.1, 0.0], "axis": [0.0, 0.6, 0.8]},
                  {"name": "u", "type": "universal", "body1": "c", "body2": "b",
                   "at": [0.4, -0.3, 0.2], "axis1": [1.0, 0.0, 0.0], "axis2": [0.0, 0.0, 1.0]},
                  {"name": "cyl", "type": "cylindrical", "body1": "d", "body2": "c",
                   "at": [-0.1, 0.0, 0.3], "axis": [0.6, 0.0, 0.8]},
                  {"name": "p", "type": "prismatic", "body1": "e", "body2": "d",
                   "at": [0.1, 0.6, -0.2], "axis": [0.0, 1.0, 0.0]},
                  {"name": "fx", "type": "fixed", "body1": "f", "body2": "e",
                   "at": [0.0, 0.2, 0.3]}],
        "force": [{"type": "gravity", "g": [0.0, 0.0, -G]}]}, "joints.toml")


def moved(sc, y, w, eps):
    """The state y carried a time eps along the velocities w: r + eps v, the orientation turned
    by eps Omega in the body frame (a curve whose tangent is w, which is all that a central
    difference of Phi or of C w sees)."""
    y = y.copy()
    nqb = 7 if sc.rotation == "quaternion" else 6
    nq = nqb * len(sc.bodies)
    for b in range(len(sc.bodies)):
        k = b * nqb
        v, om = w[6 * b:6 * b + 3], w[6 * b + 3:6 * b + 6]
        y[k:k + 3] += eps * v
        if sc.rotation == "quaternion":
            th = eps * om
            ang = np.linalg.norm(th)
            dq = np.concatenate([[math.cos(ang / 2)],
                                 (math.sin(ang / 2) / ang if ang else 0.5) * th])
            y[k + 3:k + 7] = quaternion_product(y[k + 3:k + 7], dq)
        else:
            y[k + 3:k + 6] += eps * mbdk.rotations.angle_rates(y[k + 3:k + 6], om,
                                                               sc.rotation[-3:], frame="body")
    y[nq:] = w
    return y


@pytest.mark.parametrize("rotation", ["quaternion", "cardan123", "euler313"])
def test_jacobian_and_gamma_of_every_joint_against_differences_of_phi(rotation):
    sc = every_joint_scene(rotation)
    rng = np.random.default_rng(7)
    y = sc.state0()
    nq = len(y) - 6 * len(sc.bodies)
    y = moved(sc, y, rng.normal(0, 0.3, 6 * len(sc.bodies)), 1.0)   # off the manifold
    w = rng.normal(0, 1.0, 6 * len(sc.bodies))
    y[nq:] = w
    e = evaluate_spatial(sc, y)
    eps = 1e-6
    plus, minus = evaluate_spatial(sc, moved(sc, y, w, eps)), evaluate_spatial(sc, moved(sc, y, w, -eps))
    # Phi' = C w, and gamma = -(C' w): the terms of Phi'' quadratic in w
    assert np.max(np.abs((plus["phi"] - minus["phi"]) / (2 * eps) - e["C"] @ w)) < 1e-8
    cdot_w = (plus["C"] @ w - minus["C"] @ w) / (2 * eps)
    assert np.max(np.abs(e["gamma"] + cdot_w)) < 1e-6 * max(1.0, np.abs(e["gamma"]).max())
    assert e["C"].shape == (5 + 4 + 4 + 5 + 6 + 3, 36)


def test_the_free_body_scene_follows_the_compiled_free_rigid_body():
    sc = mbdk.scene("free_body")
    j = np.diag(sc.bodies[0].inertia)
    om0 = sc.bodies[0].omega_body
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=4.0, every=50)
    ref = mbdk.solve_ode("free_rigid_body", "rk4", h=1e-3, t_end=4.0, every=50,
                         y0=[1, 0, 0, 0, *om0], params=dict(J1=j[0], J2=j[1], J3=j[2]))
    assert np.max(np.abs(r.q[:, 3:7] - ref.y[:, :4])) < 1e-10
    assert np.max(np.abs(r.v[:, 3:6] - ref.y[:, 4:])) < 1e-10
    # the invariants: kinetic energy, and the angular momentum in space R J Omega
    assert np.max(np.abs(r.energy - r.energy[0])) < 1e-9 * r.energy[0]
    lw = np.array([rr @ (j * om) for rr, om in zip(r.orientation("box"), r.omega_body("box"))])
    assert np.max(np.abs(lw - lw[0])) < 1e-9 * np.linalg.norm(lw[0])
    # the intermediate axis is unstable: the spin about body y reverses within 4 s
    assert r.omega_body("box")[:, 1].min() < -0.9 * om0[1]


@pytest.mark.parametrize("formulation,tol", [("reduced", 1e-10), ("projection", 1e-10),
                                             ("baumgarte", 1e-3)])
def test_the_heavy_top_scene_follows_the_compiled_heavy_top(formulation, tol):
    sc = mbdk.scene("heavy_top")
    b = sc.bodies[0]
    q0 = mbdk.rotations.to_quaternion(b.rotation)
    r = mbdk.simulate(sc, "rk4", h=2e-4, t_end=1.0, every=50, formulation=formulation)
    ref = mbdk.solve_ode("heavy_top", "rk4", h=2e-4, t_end=1.0, every=50, y0=[*q0, *b.omega_body],
                         params=dict(J1=0.015, J2=0.015, J3=0.01, m=1.0, g=G, l=0.1))
    assert np.max(np.abs(r.q[:, 3:7] - ref.y[:, :4])) < tol
    assert np.max(np.abs(r.v[:, 3:6] - ref.y[:, 4:])) < tol * 50
    assert np.max(np.abs(r.energy_balance())) < 1e-6
    # the tip stays at the origin; the multipliers are the tip's force: on average the weight
    assert np.max(r.residuals[:, 0]) < (1e-9 if formulation != "baumgarte" else 1e-6)
    assert r.multipliers.shape == (r.t.size, 3)


@pytest.mark.parametrize("rotation", ["quaternion", "cardan123"])
def test_a_spatial_double_pendulum_on_spherical_joints_agrees_with_the_planar_one(rotation):
    planar = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-3, t_end=3.0, every=20)
    sc = mbdk.scene("spatial_double_pendulum")
    sc.rotation = rotation
    for k, b in enumerate(sc.bodies):   # the planar run's assembled start (the file's is rounded)
        x, y, a = planar.q[0, 3 * k:3 * k + 3]
        b.position = np.array([x, y, 0.0])
        b.rotation = mbdk.rotations.from_angles([0.0, 0.0, a], "123")
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=3.0, every=20)
    for k, name in enumerate(("bar1", "bar2")):
        rot = r.orientation(name)
        angle = np.unwrap(np.arctan2(rot[:, 1, 0], rot[:, 0, 0]))
        assert np.max(np.abs(angle - planar.q[:, 3 * k + 2])) < 1e-10
        assert np.max(np.abs(r.position(name)[:, :2] - planar.q[:, 3 * k:3 * k + 2])) < 1e-10
        assert np.max(np.abs(r.position(name)[:, 2])) < 1e-14      # it stays in its plane
    assert np.max(np.abs(r.energy - planar.energy)) < 1e-9


def _one_body(joint, g=(0.0, 0.0, -G), **kw):
    return scene_from_dict({"body": [body("x", 2.0, (0.02, 0.03, 0.04), **kw)],
                                    "joint": [joint],
                                    "force": [{"type": "gravity", "g": list(g)}]}, "one.toml")


def test_prismatic_and_cylindrical_joints_let_the_body_fall_along_the_axis_only():
    axis = np.array([0.0, 0.6, 0.8])
    sc = _one_body({"name": "p", "type": "prismatic", "body1": "x", "at": [0, 0, 0],
                    "axis": axis.tolist()}, omega_body=[0.0, 0.0, 0.0])
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0, every=100)
    s = 0.5 * (-G * axis[2]) * r.t**2                 # g along the axis: -9.81 * 0.8
    assert np.max(np.abs(r.position("x") - np.outer(s, axis))) < 1e-12
    assert np.max(np.abs(r.omega_body("x"))) < 1e-12    # no turn at all
    # cylindrical: the same fall, and a spin about the axis kept
    sc = scene_from_dict({"body": [body("x", 2.0, (0.03, 0.03, 0.04),
                                                omega_body=[0.0, 0.0, 3.0])],
                                  "joint": [{"name": "c", "type": "cylindrical", "body1": "x",
                                             "at": [0, 0, 0], "axis": [0.0, 0.0, 1.0]}],
                                  "force": [{"type": "gravity", "g": [0.0, 0.0, -G]}]})
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0, every=100)
    assert np.max(np.abs(r.position("x")[:, 2] + 0.5 * G * r.t**2)) < 1e-12
    assert np.max(np.abs(r.omega_body("x") - [0.0, 0.0, 3.0])) < 1e-12


def test_a_revolute_pendulum_swings_with_the_physical_pendulum_period():
    # a box hanging 0.5 m below a horizontal hinge (axis z, gravity -y), amplitude 0.01 rad:
    # the period 2 pi sqrt(J_O / (m g d)) (1 + th0^2 / 16), measured between up-crossings
    m, d, jz, th0 = 2.0, 0.5, 0.04, 0.01
    pos = [d * math.sin(th0), -d * math.cos(th0), 0.0]
    sc = scene_from_dict({
        "body": [body("x", m, (0.02, 0.03, jz), position=pos, cardan123=[0.0, 0.0, th0])],
        "joint": [{"name": "h", "type": "revolute", "body1": "x", "at": [0, 0, 0],
                   "axis": [0.0, 0.0, 1.0]}],
        "force": [{"type": "gravity", "g": [0.0, -G, 0.0]}]})
    period = 2 * math.pi * math.sqrt((jz + m * d * d) / (m * G * d)) * (1 + th0 ** 2 / 16)
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=2.5 * period, every=1)
    ang = np.arctan2(r.position("x")[:, 0], -r.position("x")[:, 1])
    up = [r.t[k] - ang[k] * (r.t[k + 1] - r.t[k]) / (ang[k + 1] - ang[k])
          for k in range(len(ang) - 1) if ang[k] < 0 <= ang[k + 1]]
    assert len(up) == 2
    assert abs((up[1] - up[0]) / period - 1) < 1e-5
    assert np.max(np.abs(r.position("x")[:, 2])) < 1e-12


def test_forces_torques_and_spring_dampers_keep_the_energy_balance():
    """A body on a spherical joint with a point force, a torque and a spring-damper to the
    ground: E - E0 - (work of the loads and the damper) falls as h^4 (rk4), and without the
    damper and loads the energy itself is kept."""
    def scene(loads=True):
        forces = [{"type": "gravity", "g": [0.0, 0.0, -G]},
                  {"type": "spring_damper", "body1": "x", "point1": [0.3, 0.0, 0.0],
                   "at2": [0.6, 0.4, 0.2], "stiffness": 50.0, "damping": 2.0 if loads else 0.0,
                   "rest_length": 0.2}]
        if loads:
            forces += [{"type": "point_force", "body": "x", "point": [0.0, 0.2, 0.0],
                        "force": [1.0, -2.0, 0.5]},
                       {"type": "torque", "body": "x", "torque": [0.0, 0.3, -0.2]}]
        return scene_from_dict({
            "body": [body("x", 2.0, (0.02, 0.03, 0.04), position=[0.3, 0.1, -0.2],
                          cardan123=[0.2, -0.1, 0.4], omega_body=[1.0, -0.5, 2.0])],
            "joint": [{"name": "s", "type": "spherical", "body1": "x", "at": [0.0, 0.0, 0.0]}],
            "force": forces})
    sc = scene()
    v0 = sc.bodies[0].rotation @ np.cross(sc.bodies[0].omega_body,
                                          sc.bodies[0].rotation.T @ -sc.bodies[0].position)
    sc.bodies[0].velocity = -v0                      # the centre turns about the fixed point
    bal = []
    for h in (2e-3, 1e-3):
        # energy_balance's W: the kernel's trapezoidal rule over rk4's steps, whose O(h^2)
        # error then sets the balance's
        r = mbdk.simulate(sc, "rk4", h=h, t_end=1.0, every=1)
        bal.append(np.max(np.abs(r.energy_balance())))
    assert 3.0 < bal[0] / bal[1] < 5.0 and bal[1] < 1e-5
    assert np.ptp(r.energy) > 1e-2                   # the loads do work: E is not constant
    sc = scene(loads=False)
    sc.bodies[0].velocity = -v0
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0, every=10)
    assert np.max(np.abs(r.energy - r.energy[0])) < 1e-8


def test_a_prismatic_joint_holds_a_torque_about_its_axis_a_cylindrical_one_turns():
    torque = {"type": "torque", "body": "x", "torque": [0.0, 0.0, 0.5]}
    for typ, turns in (("prismatic", False), ("cylindrical", True)):
        sc = scene_from_dict({
            "body": [body("x", 2.0, (0.03, 0.03, 0.04))],
            "joint": [{"name": "j", "type": typ, "body1": "x", "at": [0, 0, 0],
                       "axis": [0.0, 0.0, 1.0]}],
            "force": [torque]})
        r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0, every=100)
        # J_z w' = 0.5 about the axis when it may turn (w = 0.5 t / 0.04), nothing when not
        expect = 0.5 * r.t / 0.04 if turns else 0 * r.t
        assert np.max(np.abs(r.omega_body("x")[:, 2] - expect)) < 1e-10, typ
        if not turns:   # the joint's rows carry the torque: C^T lambda balances it
            e = evaluate_spatial(sc, r.y[-1])
            assert np.allclose(e["C"].T @ r.multipliers[-1], [0, 0, 0, 0, 0, 0.5], atol=1e-10)


def test_a_fixed_joint_holds_the_body_and_its_multipliers_carry_the_weight():
    sc = _one_body({"name": "f", "type": "fixed", "body1": "x", "at": [0.1, 0.2, 0.3]},
                   position=[0.1, 0.2, 0.0], cardan123=[0.3, 0.2, 0.1])
    r = mbdk.simulate(sc, "rk4", h=1e-2, t_end=1.0, every=10)
    assert np.max(np.abs(r.y - r.y[0])) < 1e-13
    # M w' + C^T lambda = f with C's position rows +I on body x: at rest lambda = m g
    assert np.allclose(r.multipliers[:, :3], [0.0, 0.0, -2.0 * G], atol=1e-10)


def test_a_universal_joint_keeps_its_rows_and_the_energy():
    sc = _one_body({"name": "u", "type": "universal", "body1": "x", "at": [0, 0, 0.3],
                    "axis1": [1.0, 0.0, 0.0], "axis2": [0.0, 1.0, 0.0]},
                   position=[0.0, 0.0, 0.0], omega_body=[0.5, 0.0, 0.0],
                   velocity=[0.0, 0.15, 0.0])
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=2.0, every=50, formulation="projection")
    assert np.max(r.residuals[:, :2]) < 1e-10
    assert np.max(np.abs(r.energy - r.energy[0])) < 1e-8
    rot = r.orientation("x")
    # the cross: body x's first axis stays normal to the ground's second
    assert np.max(np.abs(rot[:, :, 0] @ [0.0, 1.0, 0.0])) < 1e-10


def test_the_quaternion_norm_is_kept_by_the_users_choice():
    drift = {}
    for norm in ("project", "stabilise", "none"):
        sc = mbdk.scene("free_body")
        sc.quaternion_norm = norm
        r = mbdk.simulate(sc, "explicit_euler", h=2e-3, t_end=2.0, every=50, watch=False)
        drift[norm] = np.max(r.residuals[:, 2])
    # explicit Euler grows |p| by a factor 1 + h^2 |Omega|^2 / 8 per step (1.3 % over 1000
    # steps here, |Omega| = 5 rad/s); the stabilisation term holds it where growth and decay balance, about
    # (h |Omega|^2 / 8) / norm_gain = 6e-4; the projection at roundoff
    assert drift["none"] > 1e-2
    assert 1e-4 < drift["stabilise"] < 1e-3
    assert drift["project"] < 1e-15


def test_euler_angles_stop_by_name_at_their_gimbal_lock_and_quaternions_pass_it():
    sc = scene_from_dict({"scene": {"rotation": "euler313"},
                                  "body": [body("x", euler313=[0.0, 0.05, 0.0],
                                                omega_body=[-1.0, 0.0, 0.0])]})
    with pytest.raises(mbdk.SingularMatrixError, match="gimbal lock") as err:
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0)
    assert 0.0 < err.value.result.t[-1] < 0.06     # theta = 0 at t = 0.05
    sc.rotation = "quaternion"
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0)
    assert r.success


def spatial_from_planar(name, q0):
    """A planar scene of bars on revolute joints rebuilt from spatial bars (axes z) at the planar
    run's assembled state q0: its 3D joints add rows that keep the motion planar, dependent on
    the others for a closed loop."""
    sc = mbdk.scene(name)
    bodies = [body(b.name, b.mass, position=[q0[3 * k], q0[3 * k + 1], 0.0],
                   cardan123=[0.0, 0.0, q0[3 * k + 2]]) | {
                       "inertia": None, "shape": {"type": "bar",
                                                  "length": math.sqrt(12 * b.inertia / b.mass)}}
              for k, b in enumerate(sc.bodies)]
    for b in bodies:
        del b["inertia"]
    joints = [{"name": j.name, "type": "revolute", "body1": j.body1, "body2": j.body2,
               "point1": [*j.point1, 0.0], "point2": [*j.point2, 0.0], "axis": [0, 0, 1]}
              for j in sc.joints]
    forces = [{"type": "gravity", "g": [*f.g, 0.0]} for f in sc.forces if f.type == "gravity"]
    return scene_from_dict({"body": bodies, "joint": joints, "force": forces},
                                   f"{name}_3d.toml")


def test_redundant_joints_are_passed_and_agree_with_the_planar_mechanism():
    # the four-bar in 3D: 20 rows, rank 17 (the loop's out-of-plane rows repeat each other)
    planar = mbdk.simulate(mbdk.scene("four_bar"), "rk4", h=1e-3, t_end=2.0, every=20,
                           formulation="projection")
    sc = spatial_from_planar("four_bar", planar.q[0])
    e = evaluate_spatial(sc)
    assert (sc.rows, e["rank"]) == (20, 17)
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=2.0, every=20, formulation="projection")
    rot = r.orientation("crank")
    assert np.max(np.abs(np.unwrap(np.arctan2(rot[:, 1, 0], rot[:, 0, 0]))
                         - planar.q[:, 2])) < 1e-8
    assert np.max(r.residuals[:, :2]) < 1e-11
    # two hinges on one axis: the same motion as one hinge, to roundoff
    one = _one_body({"name": "h1", "type": "revolute", "body1": "x", "at": [0, 0, 0],
                     "axis": [0, 0, 1]}, g=(0.0, -G, 0.0), position=[0.5, 0.0, 0.0])
    two = _one_body({"name": "h1", "type": "revolute", "body1": "x", "at": [0, 0, 0],
                     "axis": [0, 0, 1]}, g=(0.0, -G, 0.0), position=[0.5, 0.0, 0.0])
    two.joints.append(scene_from_dict({
        "body": [body("x", 2.0, (0.02, 0.03, 0.04), position=[0.5, 0.0, 0.0])],
        "joint": [{"name": "h2", "type": "revolute", "body1": "x", "at": [0, 0, 0.2],
                   "axis": [0, 0, 1]}]}).joints[0])
    assert (evaluate_spatial(two)["rank"], two.rows) == (5, 10)
    a = mbdk.simulate(one, "rk4", h=1e-3, t_end=1.0, every=100)
    b = mbdk.simulate(two, "rk4", h=1e-3, t_end=1.0, every=100)
    assert np.max(np.abs(a.y - b.y)) < 1e-12


def test_bricard_linkage_runs_with_its_redundant_row_at_the_method_order():
    """IFToMM A04: 30 rows of rank 29, one degree of freedom. Released from rest it swings (P3
    from x = 1 to about -0.78 in 2 s), and rk4 converges at its order to dopri54 at rtol 1e-12
    (on the projection form it reaches that reference's own accuracy already at h = 1e-3): with a fixed set of rows F is smooth off the manifold, where
    RK stages lie (a least-squares fit of all rows, or a set chosen afresh at every evaluation,
    gave order 2 and errors 1000 times larger)."""
    sc = mbdk.scene("bricard")
    assert (sc.rows, evaluate_spatial(sc)["rank"]) == (30, 29)
    ref = mbdk.simulate(sc, "dopri54", rtol=1e-12, atol=1e-14, t_end=2.0,
                        formulation="projection")
    errs = []
    for h in (4e-3, 1e-3):
        r = mbdk.simulate(sc, "rk4", h=h, t_end=2.0, every=int(round(0.01 / h)))
        errs.append(np.max(np.abs(r.q[-1] - ref.q[-1])))
    # the reduced form, whose errors stay well above the reference's: between order 3 and 4.5
    # over a factor 4 in h (where the rows chosen at the start degenerate another set takes
    # over, which costs a little of the order there)
    assert 4 ** 3 < errs[0] / errs[1] < 4 ** 4.5 and errs[1] < 1e-9
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=2.0, every=10, formulation="projection")
    assert np.max(np.abs(r.q[-1] - ref.q[-1])) < 1e-10
    assert np.max(np.abs(r.energy - r.energy[0])) < 1e-8
    assert np.max(r.residuals[:, 0]) < 1e-11 and np.max(r.residuals[:, 1]) < 1e-9
    p3 = r.position("rod2") + np.einsum("kij,j->ki", r.orientation("rod2"), [0.0, -0.5, 0.0])
    assert p3[:, 0].min() < -0.7          # it swings


def revolute_chain(n, x0=0.0):
    """n bars of 1 m along x from (x0, 0, 0), on revolute joints about z and y in turn, the first
    to the ground, the last one's angle driven (f(t) = 0.1 (cos 2t - 1)): 5 n + 1 rows, a tree
    with a driver, so the reduced form tests its rows' rank at every evaluation (a tree without
    drivers skips that test; 8 bars, 41 rows: on the sparse path)."""
    bodies, joints = [], []
    for i in range(n):
        bodies.append({"name": f"b{i}", "kind": "spatial", "mass": 1.0,
                       "shape": {"type": "bar", "length": 1.0},
                       "position": [x0 + i + 0.5, 0.0, 0.0]})
        joints.append({"name": f"R{i}", "type": "revolute", "body1": f"b{i}",
                       "at": [x0 + i, 0.0, 0.0], "axis": [0.0, 0.0, 1.0] if i % 2 == 0
                       else [0.0, 1.0, 0.0], **({"body2": f"b{i - 1}"} if i else {})})
    joints.append({"name": "drive", "type": "angle_driver", "body1": f"b{n - 1}",
                   "axis": [0.0, 0.0, 1.0] if (n - 1) % 2 == 0 else [0.0, 1.0, 0.0],
                   "function": {"offset": -0.1, "amplitude": 0.1, "omega": 2.0,
                                "phase": math.pi / 2},
                   **({"body2": f"b{n - 2}"} if n > 1 else {})})
    return scene_from_dict({"scene": {"name": f"revolute_chain_{n}"}, "body": bodies,
                            "joint": joints, "force": [{"type": "gravity", "g": [0.0, -G, 0.0]}]})


def moved_along_x(sc, dx):
    sc = copy.deepcopy(sc)
    for b in sc.bodies:
        b.position = b.position + [dx, 0.0, 0.0]
    for j in sc.joints:
        if j.body2 == GROUND:           # the ground's points are in space
            j.point2 = j.point2 + [dx, 0.0, 0.0]
    return sc


def driven_bricard():
    """Bricard's linkage with its one degree of freedom driven: rod1 turns against the ground
    about joint A's axis by f(t) = 0.2 (cos 3t - 1), from rest (an angle driver's row has no
    point, and the ground's side of it none in space)."""
    d = tomllib.loads((Path(mbdk.__file__).parent / "scenes/spatial/bricard.toml").read_text())
    d["joint"].append({"name": "drive", "type": "angle_driver", "body1": "rod1",
                       "axis": [0.0, 1.0, 0.0],
                       "function": {"offset": -0.2, "amplitude": 0.2, "omega": 3.0,
                                    "phase": math.pi / 2}})
    return scene_from_dict(d)


@pytest.mark.parametrize("name", ["bricard", "driven_bricard", "revolute_chain"])
@pytest.mark.parametrize("dx", [100.0, 1e4])
def test_a_mechanism_far_from_the_origin_moves_as_it_does_there(name, dx):
    """Where a mechanism stands does not change its motion: the reduced form's tests of a rank
    loss see rotations at the mechanism's size, the ground's points measured from the bodies'
    centre, not from the origin. Moved 100 m and 10 km along x, Bricard's linkage (dense, 29 of
    its 30 rows solved, chosen by margin among rows that tie by symmetry, and changed where
    they near a rank loss of their own), the same driven against the ground, and a chain of 8
    revolute bars (the sparse path, its rows tested at every evaluation) move as at the origin
    to the roundoff of their coordinates (eps dx is 2.2e-14 and 2.2e-12 m; measured on
    Bricard's bodies 4.5e-13 and 5.0e-11 m). A wrong length stops one of them at its start
    with SingularMatrixError, and a set of rows chosen by roundoff parts the motions by the
    method's error (about 1e-9 m)."""
    sc = {"bricard": lambda: mbdk.scene("bricard"), "driven_bricard": driven_bricard,
          "revolute_chain": lambda: revolute_chain(8)}[name]()
    t_end = 1.0 if name == "revolute_chain" else 2.0
    here = mbdk.simulate(sc, "rk4", h=1e-3, t_end=t_end, every=100)
    there = mbdk.simulate(moved_along_x(sc, dx), "rk4", h=1e-3, t_end=t_end, every=100)
    assert here.manifest["formulation"] == there.manifest["formulation"] == "reduced"
    assert there.t[-1] == pytest.approx(t_end)
    for b in sc.bodies:
        assert np.max(np.abs(there.position(b.name) - [dx, 0.0, 0.0] - here.position(b.name))) \
            < 1e-13 * dx, b.name
    assert max(np.ptp(here.position(b.name), axis=0).max() for b in sc.bodies) > 0.3  # it moves


def test_a_singular_pose_stops_by_name_naming_the_rank_not_a_gimbal_lock():
    # the parallelogram with a third crank (redundant) reaches its flat pose, crank angle 0
    planar = mbdk.simulate(mbdk.scene("parallelogram_redundant"), "rk4", h=1e-3, t_end=1.0,
                           formulation="penalty")
    sc = spatial_from_planar("parallelogram_redundant", planar.q[0])
    sc.rotation = "cardan123"
    with pytest.raises(mbdk.SingularMatrixError, match="lost their rank") as err:
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0)
    r = err.value.result
    rot = r.orientation("crank1")
    assert abs(np.arctan2(rot[-1, 1, 0], rot[-1, 0, 0])) < 0.05
    assert "gimbal" not in str(err.value)


def driven_parallelogram(redundant: bool, variant: int = 0):
    """The planar parallelogram (its third crank where redundant, else an RSSR loop with
    spherical joints at the coupler) in 3D, its crank driven at -1 rad/s from 60 degrees, so
    that it reaches its flat pose at t = pi / 3; its motion is the driver's: the crank's angle
    pi / 3 - t, the coupler's centre at (1 + cos, sin) of it, translating. variant: the bodies'
    mass distribution (0 slender bars, 1 spheres, 2 boxes and a heavy crank with a light
    coupler, 3 fat boxes of 10 kg)."""
    planar = mbdk.scene("parallelogram_redundant")
    links = [b.name for b in planar.bodies if redundant or b.name != "crank3"]
    q0 = planar.q0()
    bodies = []
    for k, b in enumerate(planar.bodies):
        if b.name not in links:
            continue
        length = math.sqrt(12 * b.inertia / b.mass)
        d = body(b.name, b.mass, position=[q0[3 * k], q0[3 * k + 1], 0.0],
                 cardan123=[0.0, 0.0, q0[3 * k + 2]])
        # the driver's motion: the cranks turn at -1 rad/s, the coupler translates
        if b.name == "coupler":
            d["velocity"] = [math.sqrt(3) / 2, -0.5, 0.0]
        else:
            d["velocity"] = [math.sqrt(3) / 4, -0.25, 0.0]
            d["omega_body"] = [0.0, 0.0, -1.0]
        shape = [{"type": "bar", "length": length},
                 {"type": "sphere", "radius": 0.3},
                 {"type": "box", "size": [length, 0.1, 0.1]},
                 {"type": "box", "size": [length, 0.3, 0.3]}][variant]
        if variant == 2 and b.name in ("crank1", "coupler"):
            d["mass"], d["inertia"] = ((1e3, [1.0, 1e2, 1e2]) if b.name == "crank1" else
                                       (1e-3, [1e-6, 1e-3, 1e-3]))
        else:
            del d["inertia"]
            d["shape"] = shape
            d["mass"] = 10.0 if variant == 3 else b.mass
        bodies.append(d)
    joints = []
    for j in planar.joints:
        if j.body1 not in links or j.body2 not in links + [GROUND]:
            continue
        spherical = not redundant and j.name in ("B", "C")
        joints.append({"name": j.name, "type": "spherical" if spherical else "revolute",
                       "body1": j.body1, "body2": j.body2, "point1": [*j.point1, 0.0],
                       "point2": [*j.point2, 0.0]} | ({} if spherical else {"axis": [0, 0, 1]}))
    joints.append({"name": "drive", "type": "angle_driver", "body1": "crank1",
                   "axis": [0, 0, 1], "function": {"rate": -1.0}})
    sc = scene_from_dict({"body": bodies, "joint": joints,
                          "force": [{"type": "gravity", "g": [0.0, -G, 0.0]}]},
                         "driven_parallelogram.toml")
    assert (sc.rows, evaluate_spatial(sc)["rank"]) == ((31, 24) if redundant else (17, 17))
    return sc


@pytest.mark.parametrize("redundant", [False, True])
def test_a_driven_loop_stops_at_its_flat_pose_at_one_step_whatever_its_masses(redundant):
    """The reduced form refuses a near rank loss by the geometry's G = C W C^T, not by S =
    C M^-1 C^T. The driven parallelogram in 3D (driven_parallelogram) through its flat pose:
    the motion is the driver's whatever the masses, and G the geometry's, so the step at
    which the run stops must not depend on them. Masses from 1e-3 to 1e3 kg, inertias from
    1e-6 to 1e2 kg m^2, slender bars (axial 1e-6 of transverse), boxes and spheres.
    With the third crank (31 rows of rank 24) the solve is dense, and skips near_test's
    factorisation of G where S's pivots, already at hand, prove it clear (clear_of_near:
    W >= kappa M^-1, so G >= kappa S): with kappa ten times too large the bound clears poses
    the near test would refuse, and the spheres stop steps later than the others.
    As an RSSR loop (spherical joints at the coupler, 17 independent rows) S is sparse enough
    for compact rows, whose near test factorises G on its own (mbdk_compact_schur)."""
    stops = []
    for variant in range(4):
        sc = driven_parallelogram(redundant, variant)
        with pytest.raises(mbdk.SingularMatrixError, match="lost their rank") as err:
            mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.2)
        r = err.value.result
        assert r.manifest["linear_solve"].startswith("dense" if redundant else "compact rows")
        rot = r.orientation("crank1")
        # stopped before the flat pose (crank angle 0), within a few hundredths of a radian
        assert 0.0 < np.arctan2(rot[-1, 1, 0], rot[-1, 0, 0]) < 0.05
        stops.append(len(r.t))
    assert len(set(stops)) == 1, stops


@pytest.mark.parametrize("method", ["trapezoidal_index3", "generalized_alpha"])
def test_the_index3_family_passes_a_flat_pose_that_a_step_ends_next_to(method):
    """The index-3 family passes a singular pose: its projections at a step's end take the
    regular path (the augmented Lagrangian) where the rows near a rank loss, judged on the
    geometry (near_test, within NEAR_PIVOT). The redundant driven parallelogram (31 rows of
    rank 24, the dense path), its steps sized so that one ends 1e-5, 1e-7 rad from the flat
    pose or on it: the run goes on through the pose on the parallelogram's branch, and its
    motion is the driver's (driven_parallelogram: an analytic reference) to Newton's
    tolerance away from the pose. Within a few steps of it the joints hold the coupler's
    rotation to second order only (Phi ~ phi^2 against that tolerance): some 1e-5 rad there.
    At those step ends the geometry's relative pivot is the square of the distance to the
    pose, far inside NEAR_PIVOT, so the regular path is taken there whatever the step's
    placement within 1e-5 rad. Without the near test in spatial_i3_cs_factor the exact path
    solves with S's pivots next to roundoff, and the runs stop off the joints
    (ConstraintDriftError or EnergyDriftError just before the pose)."""
    sc = driven_parallelogram(redundant=True)
    for delta in (1e-5, 1e-7, 0.0):
        h = (math.pi / 3 + delta) / 1000
        r = mbdk.simulate(sc, method, h=h, t_end=1100 * h)
        assert r.t[-1] == pytest.approx(1100 * h)
        angle = np.pi / 3 - r.t
        rot = r.orientation("crank1")
        assert np.max(np.abs(np.arctan2(rot[:, 1, 0], rot[:, 0, 0]) - angle)) < 1e-9, delta
        centre = np.column_stack([1.0 + np.cos(angle), np.sin(angle), 0.0 * angle])
        rc = r.orientation("coupler")
        dev = np.maximum(np.max(np.abs(r.position("coupler") - centre), axis=1),
                         np.abs(np.arctan2(rc[:, 1, 0], rc[:, 0, 0])))
        near = np.abs(r.t - np.pi / 3) < 5 * h
        assert np.max(dev[~near]) < 1e-9, delta
        assert np.max(dev[near]) < 1e-4, delta


def test_error_controlled_methods_run_spatial_scenes():
    sc = mbdk.scene("heavy_top")
    ref = mbdk.simulate(sc, "rk4", h=1e-4, t_end=0.5, every=5000)
    for method in ("dopri54", "bdf"):
        r = mbdk.simulate(sc, method, rtol=1e-9, atol=1e-11, t_end=0.5)
        assert np.max(np.abs(r.y[-1] - ref.y[-1])) < 1e-6, method
        assert r.stats.steps < 5000


def test_the_watch_stops_a_drifting_run_naming_the_joint():
    sc = mbdk.scene("spatial_double_pendulum")
    with pytest.raises(mbdk.ConstraintDriftError, match="joint 'O'|joint 'A'"):
        mbdk.simulate(sc, "explicit_euler", h=1e-2, t_end=10.0, watch={"position": 1e-3})


@pytest.mark.parametrize("change,field", [
    (lambda d: d["body"][0].update(quaternion=[1.0, 0.1, 0.0, 0.0]), "'quaternion'"),
    (lambda d: d["body"][0].update(inertia=[[1, 0.2, 0], [0, 1, 0], [0, 0, 1]]), "'inertia'"),
    (lambda d: d["body"][0].update(inertia=[1.0, 1.0, -1.0]), "positive definite"),
    (lambda d: d["body"][0].update(inertia=[1.0, 1.0, 3.0]), "triangle"),
    (lambda d: d["joint"].append({"name": "r", "type": "revolute", "body1": "x",
                                  "at": [0, 0, 0], "axis": [0, 0, 0]}), "'axis'"),
    (lambda d: d["body"].append({"name": "flat", "mass": 1.0, "inertia": 0.1}) or
     d["joint"].append({"name": "mixed", "type": "spherical", "body1": "flat",
                        "body2": "x"}), "joint 'mixed'"),
    (lambda d: d["scene"].update(rotation="euler123"), "'rotation'"),
    (lambda d: d["joint"].append({"name": "off", "type": "spherical", "body1": "x",
                                  "point1": [0, 0, 0], "point2": [1, 1, 1]}), "joint 'off'"),
])
def test_bad_spatial_scenes_name_the_element_and_field(change, field):
    d = {"scene": {"name": "bad"}, "body": [body("x")], "joint": []}
    change(d)
    with pytest.raises(mbdk.InvalidInputError, match=field):
        sc = scene_from_dict(d, "bad.toml")
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01)


@pytest.mark.parametrize("method,kw", [("trapezoidal_index3", {"formulation": "augmented"}),
                                       ("euler_cromer", {}),
                                       ("bdf", {"formulation": "ggl"}),
                                       ("rk4", {"solver": "kkt"})])
def test_what_spatial_scenes_do_not_run_is_refused_by_name(method, kw):
    with pytest.raises(mbdk.NotApplicableError, match="spatial"):
        mbdk.simulate(mbdk.scene("heavy_top"), method, h=1e-3, t_end=0.01, **kw)


def test_built_in_spatial_scenes_load_and_run_reproducibly():
    assert set(mbdk.scenes("spatial")) >= {"heavy_top", "free_body", "spatial_double_pendulum"}
    assert not set(mbdk.scenes()) & set(mbdk.scenes("spatial"))
    for name in mbdk.scenes("spatial"):
        # the flyball governor's dampers are stiff (c / m ~ 1e4 1/s): an implicit method
        kw = dict(rtol=1e-6, atol=1e-8) if name == "flyball_governor" else dict(h=1e-3)
        method = "bdf" if name == "flyball_governor" else "rk4"
        a = mbdk.simulate(mbdk.scene(name), method, t_end=0.2, **kw)
        b = mbdk.simulate(mbdk.scene(name), method, t_end=0.2, **kw)
        assert np.array_equal(a.y, b.y) and a.manifest["kind"] == "spatial"


def test_the_flyball_governor_rises_and_explicit_and_implicit_runs_agree():
    """IFToMM A05: 20 independent rows; the springs start at their free length; spinning at
    2 pi rad/s the balls fly out and the sleeve rises. rk4 at h = 1e-4 (inside its stability
    bound for the dampers) and bdf at rtol 1e-9 agree on the sleeve's height."""
    sc = mbdk.scene("flyball_governor")
    e = evaluate_spatial(sc)
    assert (sc.rows, e["rank"], e["potential_springs"]) == (20, 20, 0.0)
    a = mbdk.simulate(sc, "rk4", h=1e-4, t_end=0.3, every=300, formulation="projection")
    b = mbdk.simulate(sc, "bdf", rtol=1e-9, atol=1e-11, t_end=0.3, dt_out=0.03,
                      formulation="projection")
    s_a, s_b = a.position("slider")[:, 2], b.position("slider")[:, 2]
    assert np.max(np.abs(s_a - s_b)) < 1e-6
    assert s_a[-1] > s_a[0] + 0.01
    assert b.stats.steps < a.stats.steps / 3


def test_spatial_scenes_changed_in_python_get_named_errors_or_sound_results():
    """A fixed-seed fuzz of the Python door (studies/fuzz.py does the file door for spatial
    scenes too): any field of a body, joint, force or the scene set to a bad value gives a
    named error or a finite run, never a generic Python exception."""
    import random
    import sys
    from pathlib import Path
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "studies"))
    import fuzz
    rng = random.Random(5)
    seen = {"named": 0, "success": 0}
    for _ in range(150):
        sc = mbdk.scene(rng.choice(["heavy_top", "free_body", "spatial_double_pendulum"]))
        lists = [x for x in (sc.bodies, sc.joints, sc.forces) if x]
        obj = rng.choice([sc] + [rng.choice(x) for x in lists])
        fld = rng.choice([k for k in vars(obj) if k not in ("description", "source")])
        setattr(obj, fld, rng.choice(fuzz.BAD_VALUES + [2 * np.eye(3), np.zeros(3)]))
        outcome, detail = fuzz.classify(lambda: mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.005))
        assert outcome in seen, (type(obj).__name__, fld, detail)
        seen[outcome] += 1
    assert seen["named"] > 50 and seen["success"] > 5


def test_cvode_runs_spatial_scenes_whose_norm_needs_no_projection():
    sc = mbdk.scene("heavy_top")
    with pytest.raises(mbdk.NotApplicableError, match="quaternion_norm"):
        mbdk.simulate(sc, "cvode_bdf", rtol=1e-8, atol=1e-10, t_end=0.1)
    sc.quaternion_norm = "stabilise"
    ref = mbdk.simulate(sc, "rk4", h=1e-4, t_end=0.2, every=2000)
    r = mbdk.simulate(sc, "cvode_bdf", rtol=1e-9, atol=1e-11, t_end=0.2)
    assert np.max(np.abs(r.y[-1] - ref.y[-1])) < 1e-5


def test_orientations_near_a_lock_keep_their_angles():
    from mbdk.scene import orientation_coordinates
    for seq, a in (("313", [0.3, 1e-8, 0.5]), ("123", [0.3, math.pi / 2 - 1e-8, 0.5])):
        r = mbdk.rotations.from_angles(a, seq)
        got = orientation_coordinates(r, "euler313" if seq == "313" else "cardan123")
        assert np.allclose(mbdk.rotations.from_angles(got, seq), r, atol=1e-14)


def test_initial_velocities_off_the_joints_are_refused_naming_the_joint():
    sc = mbdk.scene("heavy_top")
    sc.bodies[0].velocity = np.array([0.5, 0.0, 0.0])
    with pytest.raises(mbdk.InvalidInputError, match="joint 'tip'.*velocities"):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01)


def test_bad_arguments_to_spatial_runs_are_named():
    sc = mbdk.scene("heavy_top")
    with pytest.raises(mbdk.InvalidInputError, match="y must"):
        evaluate_spatial(sc, [1.0, 2.0])
    with pytest.raises(mbdk.InvalidInputError, match="formulation"):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01, formulation=["x"])
    with pytest.raises(mbdk.InvalidInputError, match="outputs"):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01, outputs=("nonsense",))
    sc.bodies[0].mass = np.int64(1)
    assert mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01).success


def test_the_rank_test_is_on_the_geometry_not_on_masses_or_units():
    """A near point mass on a hinge keeps all 5 rows (a mass-weighted test called one of them
    dependent, and the hinge then let the body tilt); the same pendulum in millimetres, its
    angle driven (a driver keeps the near-singular test, which a tree without drivers skips),
    runs on the reduced form exactly as in metres (a near-singular test with rotations weighted
    by L^2 refused it at t = 0)."""
    def pendulum(scale, j, driven=False):
        drive = [{"name": "drive", "type": "angle_driver", "body1": "x", "axis": [0, 0, 1],
                  "function": {"offset": -0.3, "amplitude": 0.3, "omega": 2.0,
                               "phase": math.pi / 2}}]
        return scene_from_dict({
            "body": [body("x", 1.0, (j * scale ** 2,) * 3, position=[scale, 0.0, 0.0])],
            "joint": [{"name": "h", "type": "revolute", "body1": "x", "at": [0, 0, 0],
                       "axis": [0, 0, 1]}] + (drive if driven else []),
            "force": [{"type": "gravity", "g": [0.0, -G * scale, 0.0]},
                      {"type": "torque", "body": "x", "torque": [0.0, 1e-9 * scale ** 2, 0.0]}]})
    point = pendulum(1.0, 1e-10)
    assert evaluate_spatial(point)["rank"] == 5
    r = mbdk.simulate(point, "rk4", h=1e-3, t_end=0.5)
    # S's condition of 1e10 leaves its roundoff in the drift: 1e-8 over 0.5 s, against 2e-5 (and
    # a tilt rate of 2e-3 rad/s) with a row left out
    assert np.max(r.residuals[:, 0]) < 1e-7 and np.max(np.abs(r.omega_body("x")[:, :2])) < 1e-6
    m, mm = (mbdk.simulate(pendulum(s, 0.01, driven=True), "rk4", h=1e-3, t_end=1.0, every=100)
             for s in (1.0, 1000.0))
    assert np.allclose(mm.position("x") / 1000.0, m.position("x"), rtol=0, atol=1e-12)


def test_bricard_over_the_benchmarks_ten_seconds_on_the_reduced_form():
    """The rows left out are chosen by margin: the set kept never nears a rank loss along the
    motion, so the reduced form's drift stays at its truncation level over the whole 10 s (with
    the last row left out, as a plain pivoting order had it, the drift grew a hundredfold every
    2.5 s and the watch stopped the run at t = 8.6)."""
    r = mbdk.simulate(mbdk.scene("bricard"), "rk4", h=1e-3, t_end=10.0, every=100)
    assert np.max(r.residuals[:, 0]) < 1e-9
    assert np.max(np.abs(r.energy - r.energy[0])) < 1e-8


def test_the_iftomm_mechanisms_agree_with_an_independent_exudyn_reference():
    """Bricard's P3 and the governor's sleeve height against Exudyn 1.13.6 (generalized-alpha,
    index 3; benchmarks/exudyn_bricard.py and exudyn_flyball.py), run at h = 1.25e-4 (Bricard)
    and 6.25e-5 (governor), Richardson-extrapolated from the step before where marked:
    converged to about 2e-8 and 1e-8 (each halving of h changed them by a quarter as much as
    the last). Our
    runs: dopri54 and bdf at tight tolerances on the projection form."""
    exudyn_p3 = {2.0: (-0.778135373, -0.980352683, -0.197252671),      # extrapolated
                 10.0: (0.999730990, -0.999999964, -0.000268974)}     # h = 1.25e-4
    r = mbdk.simulate(mbdk.scene("bricard"), "dopri54", rtol=1e-10, atol=1e-12, t_end=10.0,
                      dt_out=2.0, formulation="projection")
    p3 = r.position("rod2") + np.einsum("kij,j->ki", r.orientation("rod2"), [0.0, -0.5, 0.0])
    for t, ref in exudyn_p3.items():
        k = int(np.argmin(np.abs(r.t - t)))
        assert np.max(np.abs(p3[k] - ref)) < 5e-8, (t, p3[k], ref)
    # s(0.5) at h = 6.25e-5 (its last halving changed it by 3.7e-9); s(2) extrapolated
    exudyn_s = {0.5: 0.7432494260, 2.0: 0.5059092943}
    r = mbdk.simulate(mbdk.scene("flyball_governor"), "bdf", rtol=1e-10, atol=1e-12,
                      t_end=2.0, dt_out=0.5, formulation="projection")
    for t, ref in exudyn_s.items():
        k = int(np.argmin(np.abs(r.t - t)))
        assert abs(r.position("slider")[k, 2] - ref) < 3e-8, (t, r.position("slider")[k, 2], ref)


def _driven_crank(rate=2.0, amplitude=0.0):
    """A box on a hinge about z at the origin, its centre 0.5 m out along x, gravity -y, its
    angle driven by f(t) = rate t + amplitude sin(3 t), turning at f'(0) from the start."""
    m, d = 2.0, 0.5
    w0 = rate + 3.0 * amplitude
    return scene_from_dict({
        "body": [body("x", m, (0.02, 0.03, 0.04), position=[d, 0.0, 0.0],
                      omega_body=[0.0, 0.0, w0], velocity=[0.0, w0 * d, 0.0])],
        "joint": [{"name": "h", "type": "revolute", "body1": "x", "at": [0, 0, 0],
                   "axis": [0, 0, 1]},
                  {"name": "drive", "type": "angle_driver", "body1": "x", "axis": [0, 0, 1],
                   "function": {"rate": rate, "amplitude": amplitude, "omega": 3.0}}],
        "force": [{"type": "gravity", "g": [0.0, -G, 0.0]}]}, "crank.toml")


def test_an_angle_driver_has_the_time_derivatives_of_its_phi():
    """Phi' = C w + Phi_t and gamma = -d/dt (C w + Phi_t) at fixed w, both by central
    differences along (t, q(t)), at a state off the manifold."""
    e = check_rows_by_differences(_driven_crank(rate=0.7, amplitude=0.4), seed=3)
    assert abs(e["phi_t"][-1]) > 0.1                    # the driver row is rheonomic


def check_rows_by_differences(sc, seed, t=0.4, eps=1e-6):
    """At a random state off the manifold (the pose moved, random w): Phi' = C w + Phi_t and
    gamma = -d/dt (C w + Phi_t) at fixed w, both by central differences along (t, q(t));
    returns the evaluation there."""
    rng = np.random.default_rng(seed)
    nw = 6 * len(sc.bodies)
    y = moved(sc, sc.state0(), rng.normal(0, 0.2, nw), 1.0)
    w = rng.normal(0, 1.0, nw)
    y[len(y) - nw:] = w
    e = evaluate_spatial(sc, y, t)
    p, mnus = (evaluate_spatial(sc, moved(sc, y, w, s * eps), t + s * eps) for s in (1, -1))
    assert np.max(np.abs((p["phi"] - mnus["phi"]) / (2 * eps) - (e["C"] @ w + e["phi_t"]))) < 1e-8
    rate = ((p["C"] @ w + p["phi_t"]) - (mnus["C"] @ w + mnus["phi_t"])) / (2 * eps)
    assert np.max(np.abs(e["gamma"] + rate)) < 1e-6
    return e


def test_a_driven_crank_turns_as_told_and_its_driver_carries_gravitys_moment():
    sc = _driven_crank(rate=2.0)
    # energy_balance's W: the kernel's trapezoidal rule over rk4's steps
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=2.0, every=1)
    rot = r.orientation("x")
    angle = np.unwrap(np.arctan2(rot[:, 1, 0], rot[:, 0, 0]))
    assert np.max(np.abs(angle - 2.0 * r.t)) < 1e-10
    # M w' + C^T lambda = f: at constant rate the driver's row (C = +1 on Omega_z) holds
    # gravity's moment about the hinge, -m g d cos(2 t), so lambda = that moment
    assert np.allclose(r.multipliers[:, -1], -2.0 * G * 0.5 * np.cos(2.0 * r.t), atol=1e-8)
    # the energy balance counts the driver's work: E - E0 - W stays at the method's error
    assert np.ptp(r.energy) > 1.0 and np.max(np.abs(r.energy_balance())) < 1e-5
    # a function that does not start at 0 would put the start off the driver: named
    sc.joints[-1].function = (0.3, 2.0, 0.0, 0.0, 0.0)
    with pytest.raises(mbdk.InvalidInputError, match="joint 'drive': field 'function'.*f.t0."):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.1)


@pytest.mark.parametrize("formulation", ["baumgarte", "projection"])
def test_a_driven_crank_on_the_stabilised_forms_and_from_a_later_start(formulation):
    """Phi_t where the stabilised forms use it (Baumgarte's 2 alpha (C w + Phi_t), the velocity
    projection onto C w + Phi_t = 0): with a sign slip there the crank would lag or lead its
    driver. Started at t0 = pi/2 with f = t - pi/2 (f(t0) = 0, and cos f(0) = 0: the rows are
    chosen at t0, where the driver's row is whole)."""
    sc = _driven_crank(rate=1.0)
    sc.joints[-1].function = (-math.pi / 2, 1.0, 0.0, 0.0, 0.0)
    t0 = math.pi / 2
    sc.bodies[0].omega_body = np.array([0.0, 0.0, 1.0])
    sc.bodies[0].velocity = np.array([0.0, 0.5, 0.0])
    r = mbdk.simulate(sc, "rk4", h=1e-3, t0=t0, t_end=t0 + 2.0, every=100,
                      formulation=formulation)
    rot = r.orientation("x")
    angle = np.unwrap(np.arctan2(rot[:, 1, 0], rot[:, 0, 0]))
    tol = 1e-6 if formulation == "baumgarte" else 1e-10
    assert np.max(np.abs(angle - (r.t - t0))) < tol
    # Baumgarte's multipliers carry its stabilising terms (beta^2 Phi with beta ~ 1/h)
    assert np.allclose(r.multipliers[:, -1], -2.0 * G * 0.5 * np.cos(r.t - t0),
                       atol=1e-2 if formulation == "baumgarte" else 1e-8)


def _driven_slider(amplitude=0.2, omega=3.0, axis=(0.6, 0.0, 0.8)):
    """A box on a prismatic joint along the unit axis u = (0.6, 0, 0.8) through the origin,
    gravity -z, its slide driven by f(t) = amplitude sin(omega t), moving at f'(0) from the
    start."""
    u = np.array(axis)
    v0 = amplitude * omega * u
    return scene_from_dict({
        "body": [body("s", 3.0, (0.02, 0.03, 0.04), position=[0.0, 0.0, 0.0],
                      velocity=v0.tolist())],
        "joint": [{"name": "guide", "type": "prismatic", "body1": "s", "at": [0, 0, 0],
                   "axis": u.tolist()},
                  {"name": "drive", "type": "slide_driver", "body1": "s", "at": [0, 0, 0],
                   "axis": u.tolist(),
                   "function": {"amplitude": amplitude, "omega": omega}}],
        "force": [{"type": "gravity", "g": [0.0, 0.0, -G]}]}, "slider.toml")


@pytest.mark.parametrize("method, formulation, tol", [
    ("rk4", "reduced", 1e-10), ("rk4", "projection", 1e-12), ("dopri54", "baumgarte", 1e-7)])
def test_a_slide_driver_moves_its_slider_as_told(method, formulation, tol):
    """s(t) = 0.2 sin 3t along u: the centre follows s u. The driver's row (C = u on the box's
    v) carries the force along u: M w' + C^T lambda = f gives m s'' + lambda = m g . u, so
    lambda = m g . u - m s'' (the guide's rows take the rest). The energy balance counts the
    driver's work."""
    sc = _driven_slider()
    kw = dict(h=1e-3, every=10) if method == "rk4" else dict(rtol=1e-10, atol=1e-12,
                                                             dt_out=0.01)
    if formulation == "baumgarte":
        kw.update(alpha=5.0, beta=5.0)
    r = mbdk.simulate(sc, method, formulation=formulation, t_end=2.0, **kw)
    u = np.array([0.6, 0.0, 0.8])
    s = 0.2 * np.sin(3.0 * r.t)
    assert np.max(np.abs(r.position("s") - s[:, None] * u)) < tol
    sdd = -0.2 * 9.0 * np.sin(3.0 * r.t)
    lam = 3.0 * (np.array([0.0, 0.0, -G]) @ u) - 3.0 * sdd
    assert np.max(np.abs(r.multipliers[:, -1] - lam)) < 1e-6
    if method == "rk4":
        assert np.max(np.abs(r.energy_balance())) < 1e-4 * np.ptp(r.energy)


def test_a_slide_driver_has_the_time_derivatives_of_its_phi():
    """Phi' = C w + Phi_t and gamma = -d/dt (C w + Phi_t) at fixed w by central differences,
    off the manifold; and f(t0) must be 0, named."""
    sc = _driven_slider(amplitude=0.3, omega=2.0)
    sc.joints[-1].function = (0.0, 0.4, 0.3, 2.0, 0.0)
    e = check_rows_by_differences(sc, seed=4)
    assert abs(e["phi_t"][-1] + (0.4 + 0.6 * math.cos(0.8))) < 1e-12
    sc.joints[-1].function = (0.1, 0.0, 0.0, 0.0, 0.0)
    with pytest.raises(mbdk.InvalidInputError, match="joint 'drive': field 'function'.*f.t0."):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.1)


@pytest.mark.parametrize("name", ["spatial_double_pendulum", "bricard"])
def test_the_penalty_formulation_converges_to_the_constrained_motion(name):
    """Jalon-Bayo's penalty on spatial scenes (M + alpha_p C^T C, definite also with Bricard's
    redundant joint). As alpha_p grows, C w' tends to gamma - 2 mu_p omega_p Phi' - omega_p^2
    Phi: the Baumgarte form with alpha = mu_p omega_p and beta = omega_p, which it approaches
    as 1 / alpha_p (measured: 5.1e-6 m at 1e5, 5.1e-8 at 1e7 on the double pendulum; 6.8e-6
    and 6.8e-8 on Bricard). Beyond about 1e8 the conditioning of M + alpha_p C^T C (of the
    order of alpha_p) sets a floor near 1e-8. The constraint residual stays at that order."""
    sc = mbdk.scene(name)
    ref = mbdk.simulate(sc, "rk4", formulation="baumgarte", alpha=10.0, beta=10.0, h=1e-4,
                        t_end=0.5, every=100)
    err = []
    for ap in (1e5, 1e7):
        r = mbdk.simulate(sc, "rk4", formulation="penalty", penalty=(ap, 10.0, 1.0), h=1e-4,
                          t_end=0.5, every=100)
        assert r.manifest["alpha_p"] == ap and "alpha_p C^T C" in r.manifest["linear_solve"]
        err.append(np.abs(r.q - ref.q).max())
        assert r.residuals[:, 0].max() < 1e-6 * 1e7 / ap
    assert err[1] < 1e-7 and 80 < err[0] / err[1] < 120


def test_the_penalty_formulation_is_refused_its_options_elsewhere_and_named():
    sc = mbdk.scene("heavy_top")
    with pytest.raises(mbdk.InvalidInputError, match="penalty = .*an option of the penalty"):
        mbdk.simulate(sc, "rk4", formulation="reduced", penalty=(1e6, 10.0, 1.0), h=1e-3,
                      t_end=0.01)
    with pytest.raises(mbdk.InvalidInputError, match="penalty = .*all > 0"):
        mbdk.simulate(sc, "rk4", formulation="penalty", penalty=(0.0, 10.0, 1.0), h=1e-3,
                      t_end=0.01)


def test_a_driven_crank_on_the_penalty_formulation():
    """The driver's multiplier on the penalty form: gravity's moment -m g d cos 2t to the
    penalty's O(1/alpha_p); the crank follows its driver to the same order."""
    sc = _driven_crank(rate=2.0)
    r = mbdk.simulate(sc, "rk4", formulation="penalty", h=1e-3, t_end=1.0, every=10)
    rot = r.orientation("x")
    angle = np.unwrap(np.arctan2(rot[:, 1, 0], rot[:, 0, 0]))
    assert np.max(np.abs(angle - 2.0 * r.t)) < 1e-6
    assert np.allclose(r.multipliers[:, -1], -2.0 * G * 0.5 * np.cos(2.0 * r.t), atol=1e-4)


@pytest.mark.parametrize("name", ["heavy_top", "spatial_double_pendulum", "bricard",
                                  "flyball_governor"])
def test_bdf_on_the_spatial_index3_dae(name):
    """bdf with formulation 'i3' integrates the spatial scene's DAE itself (q' = T(q) w,
    w' = M^-1 (f - C^T lam), 0 = Phi on the independent rows: Bricard's too). Against the
    projected rk4 run at h = 1e-4: the error falls with the tolerance (measured 6e-5 .. 2e-6
    at 1e-6, 3e-7 .. 1e-8 at 1e-9), Phi stays at the Newton tolerance, and the DAE's own
    multipliers match the reduced model's at the samples (on the non-redundant scenes, where
    they are unique)."""
    sc = mbdk.scene(name)
    ref = mbdk.simulate(sc, "rk4", formulation="projection", h=1e-4, t_end=1.0, every=1000)
    err = []
    for tol in (1e-6, 1e-9):
        r = mbdk.simulate(sc, "bdf", formulation="i3", rtol=tol, atol=tol * 1e-2, t_end=1.0,
                          dt_out=0.1)
        assert "GSTIFF I3" in r.manifest["form"]
        err.append(np.abs(r.q[[0, -1]] - ref.q[[0, -1]]).max())
        assert r.residuals[:, 0].max() < 1e2 * tol
    assert err[1] < 1e-6 and err[1] < err[0] / 10
    if name != "bricard":
        red = evaluate_spatial(sc, np.concatenate([r.q[-1], r.v[-1]]), 1.0)["multipliers"]
        assert np.abs(r.multipliers[-1] - red).max() < 1e-4 * max(1.0, np.abs(red).max())


def test_bdf_i3_on_a_spatial_scene_is_reproducible():
    """The same run twice in one process, with other runs between, gives the same bits (the
    DAE's first step once read an unset step size: it varied from run to run)."""
    sc = mbdk.scene("heavy_top")
    a = mbdk.simulate(sc, "bdf", formulation="i3", rtol=1e-6, atol=1e-8, t_end=0.5, dt_out=0.1)
    mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.1)
    mbdk.simulate(mbdk.scene("double_pendulum"), "bdf", formulation="i3", rtol=1e-6,
                  atol=1e-8, t_end=0.1)
    b = mbdk.simulate(sc, "bdf", formulation="i3", rtol=1e-6, atol=1e-8, t_end=0.5, dt_out=0.1)
    assert np.array_equal(a.y, b.y) and a.stats.steps == b.stats.steps


def _slide_between_moving_bodies():
    """A slide driver between two bodies in general positions, both moving and turning, its
    points off their centres (every term of the row: body i's and body j's rotations and
    velocities), f(t) = 0.3 t + 0.1 sin(2 t)."""
    return scene_from_dict({
        "body": [body("a", position=[0.1, 0.2, 0.3], cardan123=[0.3, -0.2, 0.5],
                      omega_body=[0.4, -0.3, 0.9], velocity=[0.2, 0.1, -0.3]),
                 body("b", 2.0, (0.3, 0.2, 0.4), position=[0.8, 0.1, -0.2],
                      cardan123=[-0.4, 0.6, 0.1], omega_body=[-0.5, 0.2, 0.3],
                      velocity=[-0.1, 0.4, 0.2])],
        "joint": [{"name": "slide", "type": "slide_driver", "body1": "b", "body2": "a",
                   "at": [0.5, 0.1, 0.0], "axis": [0.0, 0.6, 0.8],
                   "function": {"rate": 0.3, "amplitude": 0.1, "omega": 2.0}}],
        "force": [{"type": "gravity", "g": [0.0, 0.0, -G]}]}, "slide.toml")


def test_a_slide_driver_between_moving_bodies_has_the_derivatives_of_its_phi():
    e = check_rows_by_differences(_slide_between_moving_bodies(), seed=6)
    # every block of the row is in play: body b's v and Omega, body a's v and Omega
    assert all(np.abs(e["C"][0, k:k + 3]).max() > 1e-3 for k in (0, 3, 6, 9))


def check_driven_slider(r, pos_tol, lam_tol):
    """_driven_slider's run: its slide follows f(t) = 0.2 sin 3t along u, and its driver's
    multiplier is the driving force m g . u - m s'' (m = 3)."""
    u = np.array([0.6, 0.0, 0.8])
    s = 0.2 * np.sin(3.0 * r.t)
    assert np.max(np.abs(r.position("s") - s[:, None] * u)) < pos_tol
    lam = 3.0 * (np.array([0.0, 0.0, -G]) @ u) + 3.0 * 0.2 * 9.0 * np.sin(3.0 * r.t)
    assert np.max(np.abs(r.multipliers[:, -1] - lam)) < lam_tol


def test_bdf_i3_on_a_driven_slider():
    """The DAE form with a rheonomic row: the slide follows f(t), and the DAE's own multiplier
    is the driving force m g . u - m s'' (the watch's drivers' power takes it too)."""
    sc = _driven_slider()
    r = mbdk.simulate(sc, "bdf", formulation="i3", rtol=1e-9, atol=1e-11, t_end=2.0,
                      dt_out=0.1)
    check_driven_slider(r, 1e-9, 1e-5)
    assert "no projection" in r.manifest["form"] and r.manifest["quaternion_norm"].startswith(
        "none")


@pytest.mark.parametrize("method, kw, error, text", [
    ("rk4", dict(formulation="i3", h=1e-3), mbdk.NotApplicableError, "'i3'"),
    ("bdf", dict(formulation="i3", penalty=(1e6, 10.0, 1.0), rtol=1e-6, atol=1e-8),
     mbdk.InvalidInputError, "penalty"),
])
def test_the_dae_form_is_bdfs_and_named(method, kw, error, text):
    with pytest.raises(error, match=text):
        mbdk.simulate(mbdk.scene("heavy_top"), method, t_end=0.1, **kw)


def _spinning_body(rotation="euler313", e=1e-3):
    """The torque-free body (J = 1, 2, 3) of studies/rigid_body.py's gimbal table: theta0 =
    0.5 rad, turning about its x axis at 1 rad/s with Omega_y = e, so that theta passes pi
    within about e, near the 3-1-3 lock."""
    return scene_from_dict({
        "scene": {"name": "spin", "rotation": rotation},
        "body": [body("b", 1.0, (1.0, 2.0, 3.0), euler313=[0.0, 0.5, 0.0],
                      omega_body=[1.0, e, 0.0])]}, "spin.toml")


@pytest.mark.parametrize("method, kw, tol", [
    ("rk4", dict(h=1e-3, every=10), 1e-11), ("dopri54", dict(rtol=1e-10, atol=1e-12,
                                                            dt_out=0.05), 1e-9)])
def test_switching_angle_sets_passes_the_gimbal_lock(method, kw, tol):
    """3-1-3 angles within e = 1e-3 of their lock: plain rk4 loses 2e-5 of the orientation
    there (its rates peak like e / sin theta); switching to 1-2-3 angles within 0.1 of the lock
    keeps the quaternion run's orientation to rk4's error (measured 2e-14) and dopri54's
    tolerance, with one switch, the samples asked for, and the energy kept."""
    ref = mbdk.simulate(_spinning_body("quaternion"), "dopri54", rtol=1e-12, atol=1e-14,
                        t_end=5.0, dt_out=0.05)
    r = mbdk.simulate(_spinning_body(), method, t_end=5.0, switch_angles=0.1, **kw)
    assert len(r.manifest["switches"]) == 1 and 2.0 < r.manifest["switches"][0] < 3.0
    assert set(r.rotations) == {"euler313", "cardan123"} and len(r.rotations) == len(r.t)
    if method == "rk4":
        assert len(r.t) == 501 and r.stats.steps == 5000
        plain = mbdk.simulate(_spinning_body(), "rk4", t_end=5.0, **kw)
        assert np.abs(plain.orientation("b")[-1] - ref.orientation("b")[-1]).max() > 1e-6
        k = slice(None, None, 5)
        assert np.abs(r.orientation("b")[k] - ref.orientation("b")).max() < tol
    else:
        assert np.allclose(r.t, ref.t)
        assert np.abs(r.orientation("b") - ref.orientation("b")).max() < tol
    assert np.abs(r.energy - r.energy[0]).max() < 1e-9


@pytest.mark.parametrize("scene, kw, error, text", [
    (lambda: _spinning_body("quaternion"), dict(switch_angles=0.1), mbdk.InvalidInputError,
     "no gimbal lock"),
    (lambda: _spinning_body(), dict(switch_angles=0.7), mbdk.InvalidInputError,
     "between 0 and 0.5"),
    (lambda: mbdk.scene("double_pendulum"), dict(switch_angles=0.1),
     mbdk.NotApplicableError, "planar scenes have no gimbal lock"),
])
def test_switch_angles_is_refused_where_it_cannot_apply(scene, kw, error, text):
    with pytest.raises(error, match=text):
        mbdk.simulate(scene(), "rk4", h=1e-3, t_end=0.1, **kw)


@pytest.mark.parametrize("name, t_end", [("heavy_top", 1.0), ("spatial_double_pendulum", 1.0),
                                         ("bricard", 0.5)])
def test_trapezoidal_index3_on_spatial_scenes_is_second_order_and_keeps_the_joints(name, t_end):
    """The index-3 trapezoidal rule (mbdk_trapezoidal_index3, augmented) against dopri54 at rtol
    1e-12 on the projection formulation: the error falls fourfold per halving of h (measured
    3.98-4.00 on all three, Bricard's redundant row included), the joints' position and
    velocity rows and the quaternions' norm stay at roundoff, and the energy's drift falls with
    h too."""
    sc = mbdk.scene(name)
    ref = mbdk.simulate(sc, "dopri54", formulation="projection", rtol=1e-12, atol=1e-14,
                        t_end=t_end, dt_out=0.05)
    errs, drifts = [], []
    for h in (5e-3, 2.5e-3, 1.25e-3):
        r = mbdk.simulate(sc, "trapezoidal_index3", h=h, t_end=t_end, every=round(0.05 / h))
        assert r.manifest["formulation"] == "augmented_lagrangian"
        assert "augmented Lagrangian" in r.manifest["form"]
        errs.append(max(np.abs(r.q - ref.q).max(), np.abs(r.v - ref.v).max()))
        drifts.append(np.ptp(r.energy))
        # the joints to Newton's atol (1e-12: no projection of q after the step), the
        # velocity rows to roundoff (v+ is projected)
        assert r.residuals[:, 0].max() < 1e-12 and r.residuals[:, 1].max() < 1e-12
        assert r.residuals[:, 2].max() < 1e-14           # |p| - 1
        assert r.stats.steps == round(t_end / h) and r.stats.njev >= 1
    ratios = np.array(errs[:-1]) / np.array(errs[1:])
    assert np.all((ratios > 3.6) & (ratios < 4.4)), ratios
    assert drifts[2] < drifts[0] / 8


def test_trapezoidal_index3_on_a_spatial_pendulum_matches_the_planar_scene():
    """The spatial double pendulum in its plane against the planar scene's own solution (rk4,
    h = 1e-5): the spatial trapezoidal run's angle error is the method's O(h^2), 4x smaller per
    halving, and it stays in its plane."""
    planar = mbdk.simulate(mbdk.scene("double_pendulum"), "rk4", h=1e-5, t_end=1.0, every=5000)
    sc = mbdk.scene("spatial_double_pendulum")
    for k, b in enumerate(sc.bodies):
        x, y, a = planar.q[0, 3 * k:3 * k + 3]
        b.position = np.array([x, y, 0.0])
        b.rotation = mbdk.rotations.from_angles([0.0, 0.0, a], "123")
    errs = []
    for h in (2e-3, 1e-3):
        r = mbdk.simulate(sc, "trapezoidal_index3", h=h, t_end=1.0, every=round(0.05 / h))
        e = 0.0
        for k, name in enumerate(("bar1", "bar2")):
            rot = r.orientation(name)
            angle = np.unwrap(np.arctan2(rot[:, 1, 0], rot[:, 0, 0]))
            e = max(e, np.abs(angle - planar.q[:, 3 * k + 2]).max())
            assert np.abs(r.position(name)[:, 2]).max() < 1e-14
        errs.append(e)
    assert errs[0] < 1e-3 and 3.6 < errs[0] / errs[1] < 4.4


def test_trapezoidal_index3_on_a_driven_slider():
    """A rheonomic row: the slide follows f(t) to roundoff at every step, and the multiplier
    (from the constrained solve after the projections) is the driving force m g . u - m s''."""
    r = mbdk.simulate(_driven_slider(), "trapezoidal_index3", h=1e-3, t_end=2.0, every=100)
    check_driven_slider(r, 1e-12, 1e-9)


@pytest.mark.parametrize("kw, error, text", [
    (dict(formulation="reduced", h=1e-3), mbdk.NotApplicableError,
     "index3, augmented_lagrangian"),
    (dict(rtol=1e-6, h=1e-3), mbdk.InvalidInputError, "rtol"),
    (dict(solver="kkt", h=1e-3), mbdk.NotApplicableError, "solver"),
    (dict(), mbdk.InvalidInputError, "give h"),
])
def test_trapezoidal_index3_on_spatial_scenes_refuses_what_it_does_not_do(kw, error, text):
    with pytest.raises(error, match=text):
        mbdk.simulate(mbdk.scene("heavy_top"), "trapezoidal_index3", t_end=0.1, **kw)


@pytest.mark.parametrize("h", [6.25e-4, 3.125e-4])
def test_trapezoidal_index3_on_spatial_scenes_at_small_steps(h):
    """The Newton unknown is (h^2/4) lam: with lam itself the matrix's condition grows like
    h^-2, and at h = 6.25e-4 the spatial double pendulum's updates stalled at roundoff above
    the tolerance (NewtonDivergedError at t = 0.465). Past that point, on the joints."""
    r = mbdk.simulate(mbdk.scene("spatial_double_pendulum"), "trapezoidal_index3", h=h,
                      t_end=0.6, every=round(0.05 / h))
    assert r.success and r.t[-1] == pytest.approx(0.6)
    assert r.residuals[:, 0].max() < 1e-13 and r.residuals[:, 1].max() < 1e-12


@pytest.mark.parametrize("name, t_end, tols", [
    ("heavy_top", 1.0, (1e-6, 1e-9)), ("spatial_double_pendulum", 1.0, (1e-6, 1e-9)),
    ("bricard", 1.0, (1e-6, 1e-9)), ("flyball_governor", 0.5, (1e-6, 1e-8))])
def test_ida_on_spatial_scenes(name, t_end, tols):
    """SUNDIALS IDA on the spatial DAE itself (mbdk_ida_solve_spatial), in the index1 and GGL
    forms, against dopri54 at rtol 1e-12 on the projection formulation (bdf at 1e-11 for the
    stiff governor): the error falls with the tolerance, GGL holds Phi to its tolerance (index1
    lets it drift, as the reduced ODE does), and the multipliers at the end are the reduced
    model's there (Bricard's: on the 29 rows it keeps)."""
    sc = mbdk.scene(name)
    ref = (mbdk.simulate(sc, "bdf", rtol=1e-11, atol=1e-13, t_end=t_end, dt_out=0.1,
                         formulation="projection") if name == "flyball_governor" else
           mbdk.simulate(sc, "dopri54", rtol=1e-12, atol=1e-14, t_end=t_end, dt_out=0.1,
                         formulation="projection"))
    for form in ("index1", "ggl"):
        errs = []
        for tol in tols:
            r = mbdk.simulate(sc, "ida", formulation=form, rtol=tol, atol=tol * 1e-2,
                              t_end=t_end, dt_out=0.1)
            assert r.manifest["formulation"] == form and "IDA" in r.manifest["linear_solve"]
            errs.append(max(np.abs(r.q - ref.q).max(), np.abs(r.v - ref.v).max()))
            red = evaluate_spatial(sc, np.concatenate([r.q[-1], r.v[-1]]), t_end)["multipliers"]
            scale = max(1.0, np.abs(red).max())
            assert np.abs(r.multipliers[-1] - red).max() < 1e3 * tol * scale, (form, tol)
            if form == "ggl":
                assert r.residuals[:, 0].max() < 10 * tol
        assert errs[1] < errs[0] / 10, (form, errs)


def test_ida_ggl_on_a_driven_slider():
    """The GGL form with a rheonomic row: the slide follows f(t) to the tolerance, and the
    multiplier is the driving force m g . u - m s''."""
    r = mbdk.simulate(_driven_slider(), "ida", formulation="ggl", rtol=1e-9, atol=1e-11,
                      t_end=2.0, dt_out=0.1)
    check_driven_slider(r, 1e-8, 1e-5)


@pytest.mark.parametrize("kw, error, text", [
    (dict(formulation="i3"), mbdk.NotApplicableError, "index1, ggl"),
    (dict(formulation="projection"), mbdk.NotApplicableError, "index1, ggl"),
    (dict(every=5), mbdk.InvalidInputError, "dt_out"),
])
def test_ida_on_spatial_scenes_refuses_what_it_does_not_do(kw, error, text):
    with pytest.raises(error, match=text):
        mbdk.simulate(mbdk.scene("heavy_top"), "ida", t_end=0.1, **kw)


@pytest.mark.parametrize("name, t_end, tols", [
    ("heavy_top", 1.0, (1e-6, 1e-9)), ("spatial_double_pendulum", 1.0, (1e-6, 1e-9)),
    ("bricard", 1.0, (1e-6, 1e-9)), ("flyball_governor", 0.5, (1e-6, 1e-8))])
def test_bdf_on_the_spatial_stabilised_index2_dae(name, t_end, tols):
    """bdf with formulation 'si2' (GGL's mu through T(q) M^-1 C^T): the error against the
    projected reference falls with the tolerance (measured 5e-6 .. 4e-5 at 1e-6 and 2e-8 .. 3e-7
    at the tighter one, below i3's), and both the position and the velocity rows hold to the
    tolerance (i3 lets the velocity rows drift by 6e-5 on the governor at 1e-6)."""
    sc = mbdk.scene(name)
    ref = (mbdk.simulate(sc, "bdf", rtol=1e-11, atol=1e-13, t_end=t_end, dt_out=0.1,
                         formulation="projection") if name == "flyball_governor" else
           mbdk.simulate(sc, "dopri54", rtol=1e-12, atol=1e-14, t_end=t_end, dt_out=0.1,
                         formulation="projection"))
    errs = []
    for tol in tols:
        r = mbdk.simulate(sc, "bdf", formulation="si2", rtol=tol, atol=tol * 1e-2, t_end=t_end,
                          dt_out=0.1)
        assert "SI2" in r.manifest["form"]
        errs.append(max(np.abs(r.q - ref.q).max(), np.abs(r.v - ref.v).max()))
        assert r.residuals[:, 0].max() < 100 * tol and r.residuals[:, 1].max() < 100 * tol
        red = evaluate_spatial(sc, np.concatenate([r.q[-1], r.v[-1]]), t_end)["multipliers"]
        assert np.abs(r.multipliers[-1] - red).max() < 1e3 * tol * max(1.0, np.abs(red).max())
    assert errs[1] < errs[0] / 10


@pytest.mark.parametrize("mode", ["extrapolated", "estimated"])
def test_trapezoidal_index3_controls_its_step_on_spatial_scenes(mode):
    """Step-size control runs spatial scenes as planar ones (one integrator, issue 37): on the
    heavy top against dopri54 at rtol 1e-12, the error at err_rtol = 1e-7 is a tenth of the one
    at 1e-5 or less, with more steps, the joint held at every sample to 1e-12; the samples lie
    on the dt_out grid."""
    sc = mbdk.scene("heavy_top")
    ref = mbdk.simulate(sc, "dopri54", formulation="projection", rtol=1e-12, atol=1e-14,
                        t_end=1.0, dt_out=0.1)
    runs = {}
    for tol in (1e-5, 1e-7):
        r = mbdk.simulate(sc, "trapezoidal_index3", h=1e-2, t_end=1.0, adaptive=mode,
                          err_rtol=tol, err_atol=tol, dt_out=0.1)
        assert r.success and np.allclose(r.t, ref.t)
        assert r.residuals[:, 0].max() < 1e-12
        runs[tol] = (max(np.abs(r.q - ref.q).max(), np.abs(r.v - ref.v).max()), r.stats.steps)
    assert runs[1e-7][0] < 0.1 * runs[1e-5][0] and runs[1e-7][1] > runs[1e-5][1], runs


@pytest.mark.parametrize("length", [0.5, 1.0, 2.0])
def test_a_tree_of_joints_keeps_the_margin_its_skipped_near_test_would_check(length):
    """A tree of joints without drivers skips the reduced form's near test of a rank loss
    (model%regular_tree: C is block triangular with blocks of full rank along the motion). On
    the flyball governor (revolute, prismatic and two revolute joints on a tree, the dense path),
    the smallest relative Cholesky pivot of the geometry's G = C W C^T (rotations weighted
    1/L^2; the skipped test's form, in C's order) stays far above the test's window of 1e-4
    over two seconds of motion, for length scales L around the mechanism's: skipping the test
    changes no outcome. (A rank loss of the tree itself would take this to zero.)"""
    sc = mbdk.scene("flyball_governor")
    r = mbdk.simulate(sc, "rk4", h=1e-4, t_end=2.0, every=400, formulation="reduced")
    w = np.tile([1.0, 1.0, 1.0, length**-2, length**-2, length**-2], len(sc.bodies))
    worst = 1.0
    for y in r.y:
        c = evaluate_spatial(sc, y)["C"]
        g = (c * w) @ c.T
        lc = np.linalg.cholesky(g)
        worst = min(worst, float((np.diag(lc) ** 2 / np.diag(g)).min()))
    assert worst > 1e-2, worst
