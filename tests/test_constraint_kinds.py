"""Constraint kinds of chapter 1 beyond the four-bar's (kernel/src/model/mbdk_joints.f90): the
distance between two points, constant (the mathematical pendulum (1.5)) or following L(t) (the
pendulum of changing length (1.6), rheonomic), against SciPy integrations of the pendulums'
own ODEs in polar form, finite differences of Phi, and the energy balance with the work the
changing length does."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import mbdk
from mbdk import model as M
from mbdk.scene import SceneError, scene_from_dict

G = 9.81


def pendulum(length=None, th0=0.5, l0=1.0):
    d = {"scene": {"name": "pendulum"},
         "body": [{"name": "bob", "mass": 1.0, "inertia": 1e-3, "x": l0 * math.sin(th0),
                   "y": -l0 * math.cos(th0)}],
         "joint": [{"type": "distance", "name": "rod", "body1": "bob"}],
         "force": [{"type": "gravity", "g": [0, -G]}]}
    if length is not None:
        d["joint"][0]["length"] = length
    return scene_from_dict(d, "pendulum.toml")


def polar(t, rate=0.0, th0=0.5):
    """theta'' = -(2 L'/L) theta' - (g/L) sin theta with L = 1 + rate t (the point mass in polar
    coordinates), integrated by SciPy at rtol 1e-12."""
    def f(s, y):
        ln = 1.0 + rate * s
        return [y[1], -2 * rate / ln * y[1] - G / ln * math.sin(y[0])]
    return solve_ivp(f, (0, t[-1]), [th0, 0.0], t_eval=t, rtol=1e-12, atol=1e-12).y[0]


def test_mathematical_pendulum():
    """A distance of the initial length to the ground origin: the bob moves as the pendulum
    theta'' = -(g/L) sin theta, and keeps its length and its energy."""
    r = mbdk.simulate(pendulum(), "rk4", h=1e-3, t_end=5, every=10,
                      outputs=("energy", "residuals"))
    th = np.arctan2(r.q[:, 0], -r.q[:, 1])
    assert np.abs(th - polar(r.t)).max() < 1e-9
    assert r.residuals[:, 0].max() < 1e-9
    assert np.abs(r.energy_balance()).max() < 1e-9


@pytest.mark.parametrize("method, kw, tol", [
    ("rk4", dict(h=1e-3, every=1), 1e-9),
    ("dopri54", dict(rtol=1e-10, atol=1e-12, dt_out=0.01), 1e-8),
    ("trapezoidal_index3", dict(h=1e-3), 1e-5),
])
def test_pendulum_of_changing_length(method, kw, tol):
    """L(t) = 1 + 0.2 t (1.6): the angle follows the polar ODE, the length follows L(t), and the
    energy changes by exactly the work the constraint does as it reels the bob out (the
    multiplier times Phi_t, in energy_balance's work of the constraints)."""
    r = mbdk.simulate(pendulum({"offset": 1.0, "rate": 0.2}), method, t_end=3, **kw,
                      outputs=("energy",))
    th = np.arctan2(r.q[:, 0], -r.q[:, 1])
    assert np.abs(th - polar(r.t, rate=0.2)).max() < tol
    assert np.abs(np.hypot(r.q[:, 0], r.q[:, 1]) - (1 + 0.2 * r.t)).max() < tol
    if method == "rk4":
        work = r.energy_parts["work_constraints"]
        assert abs(work[-1]) > 1.0                    # the driver's work is not negligible
        assert np.abs(r.energy_balance()).max() < 1e-6 * abs(work[-1])


def test_distance_rows_against_finite_differences():
    """Between two moving bodies, off their centroids, with L(t) = 0.8 + 0.3 sin(2 t): D against
    central differences of Phi in q, Phi_t in t, and gamma = -(dD/dt) v - Phi_tt."""
    d = {"scene": {"name": "two"},
         "body": [{"name": "a", "mass": 1.0, "inertia": 0.1, "x": 0.1, "y": 0.2, "angle": 0.4},
                  {"name": "b", "mass": 1.0, "inertia": 0.1, "x": 0.9, "y": 0.5, "angle": 0.7}],
         "joint": [{"type": "distance", "name": "link", "body1": "a", "point1": [0.2, -0.1],
                    "body2": "b", "point2": [-0.1, 0.3],
                    "length": {"offset": 0.8, "amplitude": 0.3, "omega": 2.0}}]}
    sc = scene_from_dict(d)
    tab = M.build_tables(sc)
    rng = np.random.default_rng(2)
    q = np.array(sc.q0()) + rng.normal(0, 0.05, 6)
    v = rng.normal(0, 1.0, 6)
    t, eps = 0.3, 1e-6
    e = M.evaluate(tab, q, v, t)
    fd = np.array([(M.evaluate(tab, q + eps * np.eye(6)[k], v, t)["phi"]
                    - M.evaluate(tab, q - eps * np.eye(6)[k], v, t)["phi"]) / (2 * eps)
                   for k in range(6)]).T
    assert np.abs(fd - e["D"]).max() < 1e-8
    phit = (M.evaluate(tab, q, v, t + eps)["phi"] - M.evaluate(tab, q, v, t - eps)["phi"]) / (2 * eps)
    assert np.abs(phit - e["phit"]).max() < 1e-8
    # Phi'' along q(s) = q + s v (a = 0): d2/ds2 Phi(q + s v, t + s) = -gamma
    phi = [M.evaluate(tab, q + s * v, v, t + s)["phi"] for s in (-1e-4, 0.0, 1e-4)]
    second = (phi[0] - 2 * phi[1] + phi[2]) / 1e-8
    assert np.abs(second + e["gamma"]).max() < 1e-5


@pytest.mark.parametrize("change, text", [
    (lambda d: d["joint"][0].update(length=-1.0), "must be positive"),
    (lambda d: d["joint"][0].update(length={"offset": 0.1, "amplitude": -0.5,
                                            "phase": 1.5707963}), "must be positive"),
    (lambda d: d["body"][0].update(x=0.0, y=0.0), "coincide"),
    (lambda d: d["joint"][0].update(length={"offset": 1.0, "speed": 2.0}), "speed"),
])
def test_bad_distances_are_named(change, text):
    d = {"scene": {"name": "bad"},
         "body": [{"name": "bob", "mass": 1.0, "inertia": 1e-3, "x": 0.5, "y": -0.8}],
         "joint": [{"type": "distance", "name": "rod", "body1": "bob"}]}
    change(d)
    with pytest.raises(SceneError) as exc:
        mbdk.simulate(scene_from_dict(d, "bad.toml"), "rk4", h=1e-3, t_end=0.01)
    msg = str(exc.value)
    assert "bad.toml" in msg and "rod" in msg and text in msg, msg


#: degrees of freedom of the built-in scenes, from the mechanisms themselves: a pendulum 1,
#: the double and the three-link pendulum 2 and 3, the trolley and its pendulum 2, the four-bar
#: and the parallelogram 1 (Grubler's count gives the parallelogram 0: its third link is
#: redundant), the gear pair 2 (two axles; the mesh is a compliant contact, not a row), a free
#: particle in a ring 3, the heavy top 3 (a spherical joint), a free body 6, the spatial double
#: pendulum 6 (two spherical joints), Bricard's linkage 1 (six hinges, Grubler's count 0)
DOF = {"physical_pendulum": 1, "spring_bar": 1, "spring_damper_bar": 1, "double_pendulum": 2,
       "three_link_pendulum": 3, "trolley_crane": 2, "four_bar": 1,
       "parallelogram_redundant": 1, "pla_gears": 2, "particle_in_ring": 3, "heavy_top": 3,
       "free_body": 6, "spatial_double_pendulum": 6, "bricard": 1}


@pytest.mark.parametrize("name", sorted(DOF))
def test_scene_report_degrees_of_freedom(name):
    r = mbdk.scene_report(mbdk.scene(name))
    assert r.dof == DOF[name]
    assert r.dof == r.velocities - r.rank
    assert r.index == (3 if r.rows else 0)
    redundant = r.rows - r.rank
    assert redundant == (1 if name in ("parallelogram_redundant", "bricard") else 0)
    assert bool(r.redundant) == bool(redundant)
    assert f"{r.dof} degrees of freedom" in str(r)


def test_scene_report_classifies_the_book_examples():
    """The mathematical pendulum (1.5), holonomic and scleronomic: the book's point mass has one
    freedom; the bob here is a planar body whose own rotation, free since the rod holds its
    centroid, is a second. The pendulum of changing length (1.6): rheonomic. Contacts are
    unilateral and take no row."""
    r = mbdk.scene_report(pendulum())
    assert r.dof == 2 and r.rows == r.rank == 1
    assert [c.kind() for c in r.constraints] == ["holonomic, scleronomic, bilateral"]
    r = mbdk.scene_report(pendulum({"offset": 1.0, "rate": 0.2}))
    assert r.dof == 2 and r.constraints[0].rheonomic
    r = mbdk.scene_report(mbdk.scene("pla_gears"))
    assert r.contacts == ["mesh"] and r.effects == ["gear_law", "archard"]
    assert "unilateral" in str(r)


def test_scene_report_of_a_scene_that_does_not_assemble_is_named():
    """A bar hinged at the origin cannot reach a tie of 0.5 m to a point 3 m away: the report
    names the file and the joints the assembly could not close."""
    d = {"scene": {"name": "torn"},
         "body": [{"name": "bar", "mass": 1.0, "shape": {"type": "bar", "length": 1.0},
                   "x": 0.5}],
         "joint": [{"type": "revolute", "name": "left", "body1": "bar", "point1": [-0.5, 0],
                    "point2": [0, 0]},
                   {"type": "distance", "name": "tie", "body1": "bar", "point1": [0.5, 0],
                    "point2": [3, 0], "length": 0.5}]}
    with pytest.raises(SceneError) as exc:
        mbdk.scene_report(scene_from_dict(d, "torn.toml"))
    msg = str(exc.value)
    assert "torn.toml" in msg and "tie" in msg and "cannot be assembled" in msg, msg
