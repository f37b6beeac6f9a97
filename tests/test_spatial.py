"""Spatial scenes (mbdk.spatial, kernel/src/spatial/mbdk_spatial_model.f90): the kinematics of
every joint against differences of Phi, the scenes against the compiled chapter-5 problems and
the planar model, closed forms for the joints, the quaternion norm, gimbal lock and bad input.

References: free_rigid_body and heavy_top are the compiled problems (Euler's equations with the
quaternion kinematics, tests/test_rigid_body.py checks them against closed forms); the planar
double pendulum is the planar model (tests/test_scenes.py); the sliding and falling bodies are
x = g t^2 / 2 along the free direction; the physical pendulum's small-angle period is
2 pi sqrt(J_O / (m g d))."""
import math

import numpy as np
import pytest

import mbdk
from mbdk.rotations import from_quaternion, quaternion_product
from mbdk.spatial import evaluate_spatial, spatial_scene_from_dict

G = 9.81


def body(name, mass=1.0, inertia=(0.1, 0.2, 0.25), **kw):
    return {"name": name, "kind": "spatial", "mass": mass, "inertia": list(inertia), **kw}


def every_joint_scene(rotation="quaternion"):
    """Six bodies, one joint of each type, in general positions (the rows need not hold: the
    kinematics is checked off the manifold as well)."""
    return spatial_scene_from_dict({
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
    assert np.max(np.abs(r.w[:, 3:6] - ref.y[:, 4:])) < 1e-10
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
    assert np.max(np.abs(r.w[:, 3:6] - ref.y[:, 4:])) < tol * 50
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
    return spatial_scene_from_dict({"body": [body("x", 2.0, (0.02, 0.03, 0.04), **kw)],
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
    sc = spatial_scene_from_dict({"body": [body("x", 2.0, (0.03, 0.03, 0.04),
                                                omega_body=[0.0, 0.0, 3.0])],
                                  "joint": [{"name": "c", "type": "cylindrical", "body1": "x",
                                             "at": [0, 0, 0], "axis": [0.0, 0.0, 1.0]}],
                                  "force": [{"type": "gravity", "g": [0.0, 0.0, -G]}]})
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0, every=100)
    assert np.max(np.abs(r.position("x")[:, 2] + 0.5 * G * r.t**2)) < 1e-12
    assert np.max(np.abs(r.omega_body("x") - [0.0, 0.0, 3.0])) < 1e-12


def test_a_revolute_pendulum_swings_with_the_physical_pendulum_period():
    # a box hanging 0.5 m below a horizontal hinge (axis z, gravity -y), small amplitude
    m, d = 2.0, 0.5
    jz = 0.04
    th0 = 0.01
    pos = [d * math.sin(th0), -d * math.cos(th0), 0.0]
    sc = spatial_scene_from_dict({
        "body": [body("x", m, (0.02, 0.03, jz), position=pos, cardan123=[0.0, 0.0, th0])],
        "joint": [{"name": "h", "type": "revolute", "body1": "x", "at": [0, 0, 0],
                   "axis": [0.0, 0.0, 1.0]}],
        "force": [{"type": "gravity", "g": [0.0, -G, 0.0]}]})
    period = 2 * math.pi * math.sqrt((jz + m * d * d) / (m * G * d))
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=period, every=1)
    ang = np.arctan2(r.position("x")[:, 0], -r.position("x")[:, 1])
    assert abs(ang[-1] - th0) < 1e-5 * th0 * 10   # back after one small-angle period
    assert np.max(np.abs(r.position("x")[:, 2])) < 1e-12
    assert np.min(ang) < -0.99 * th0


def test_a_fixed_joint_holds_the_body_and_its_multipliers_carry_the_weight():
    sc = _one_body({"name": "f", "type": "fixed", "body1": "x", "at": [0.1, 0.2, 0.3]},
                   position=[0.1, 0.2, 0.0], cardan123=[0.3, 0.2, 0.1])
    r = mbdk.simulate(sc, "rk4", h=1e-2, t_end=1.0, every=10)
    assert np.max(np.abs(r.y - r.y[0])) < 1e-13
    # C's position rows are +I on body x: m a = m g + lambda_r... reaction = -lambda
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
    # explicit Euler grows |p| by a factor 1 + h^2 |Omega|^2 / 8 per step (2.5 % over 1000
    # steps here); the stabilisation term holds it where growth and decay balance, about
    # (h |Omega|^2 / 8) / norm_gain = 6e-4; the projection at roundoff
    assert drift["none"] > 1e-2
    assert 1e-4 < drift["stabilise"] < 1e-3
    assert drift["project"] < 1e-15


def test_euler_angles_stop_by_name_at_their_gimbal_lock_and_quaternions_pass_it():
    sc = spatial_scene_from_dict({"scene": {"rotation": "euler313"},
                                  "body": [body("x", euler313=[0.0, 0.05, 0.0],
                                                omega_body=[-1.0, 0.0, 0.0])]})
    with pytest.raises(mbdk.SingularMatrixError, match="gimbal lock") as err:
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0)
    assert 0.0 < err.value.result.t[-1] < 0.06     # theta = 0 at t = 0.05
    sc.rotation = "quaternion"
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.0)
    assert r.success


def test_redundant_joints_stop_by_name():
    sc = spatial_scene_from_dict({
        "body": [body("x", position=[0.5, 0.0, 0.0])],
        "joint": [{"name": "h1", "type": "revolute", "body1": "x", "at": [0, 0, 0],
                   "axis": [0, 0, 1]},
                  {"name": "h2", "type": "revolute", "body1": "x", "at": [0, 0, 0.2],
                   "axis": [0, 0, 1]}],
        "force": [{"type": "gravity", "g": [0.0, -G, 0.0]}]})
    with pytest.raises(mbdk.SingularMatrixError, match="dependent"):
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.1)


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
        sc = spatial_scene_from_dict(d, "bad.toml")
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=0.01)


@pytest.mark.parametrize("method,kw", [("trapezoidal_index3", {}), ("euler_cromer", {}),
                                       ("rk4", {"formulation": "penalty"}),
                                       ("rk4", {"solver": "kkt"})])
def test_what_spatial_scenes_do_not_run_is_refused_by_name(method, kw):
    with pytest.raises(mbdk.NotApplicableError, match="spatial"):
        mbdk.simulate(mbdk.scene("heavy_top"), method, h=1e-3, t_end=0.01, **kw)


def test_built_in_spatial_scenes_load_and_run_reproducibly():
    assert set(mbdk.scenes("spatial")) >= {"heavy_top", "free_body", "spatial_double_pendulum"}
    assert not set(mbdk.scenes()) & set(mbdk.scenes("spatial"))
    for name in mbdk.scenes("spatial"):
        a = mbdk.simulate(mbdk.scene(name), "rk4", h=1e-3, t_end=0.2)
        b = mbdk.simulate(mbdk.scene(name), "rk4", h=1e-3, t_end=0.2)
        assert np.array_equal(a.y, b.y) and a.manifest["kind"] == "spatial"


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
