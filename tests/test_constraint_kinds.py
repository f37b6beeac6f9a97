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
from mbdk.scene import SceneError
from mbdk.scene_file import scene_from_dict

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
    check_rows_by_differences(scene_from_dict(d), seed=2)


def check_rows_by_differences(sc, seed, tab=None):
    """At a random state near the scene's pose: D against central differences of Phi in q,
    Phi_t in t, and gamma against Phi's second difference along q + s v, t + s (a = 0)."""
    tab = M.build_tables(sc) if tab is None else tab
    rng = np.random.default_rng(seed)
    n = len(sc.q0())
    q = np.array(sc.q0()) + rng.normal(0, 0.05, n)
    v = rng.normal(0, 1.0, n)
    t, eps = 0.3, 1e-6
    e = M.evaluate(tab, q, v, t)
    fd = np.array([(M.evaluate(tab, q + eps * np.eye(n)[k], v, t)["phi"]
                    - M.evaluate(tab, q - eps * np.eye(n)[k], v, t)["phi"]) / (2 * eps)
                   for k in range(n)]).T
    assert np.abs(fd - e["D"]).max() < 1e-8
    phit = (M.evaluate(tab, q, v, t + eps)["phi"]
            - M.evaluate(tab, q, v, t - eps)["phi"]) / (2 * eps)
    assert np.abs(phit - e["phit"]).max() < 1e-8
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
    assert f"{r.dof} degree{'' if r.dof == 1 else 's'} of freedom" in str(r)


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


# ---- point on a line or curve, couplings, rolling, knife edges (issue 23) ----------------

def car(steer, v0=10.0, point=(0.0, 0.0), driver=True):
    """The car of (1.7)-(1.14): a knife edge at point (its centroid for the book's car), the
    heading steered by a driver of the angle (steer: a time function) or free."""
    d = {"scene": {"name": "car"},
         "body": [{"name": "car", "mass": 1000.0, "inertia": 1500.0, "vx": v0,
                   "given": ["x", "y", "angle", "vx"]}],
         "joint": [{"name": "wheels", "type": "knife_edge", "body1": "car",
                    "point1": list(point)}]}
    if driver:
        d["joint"].append({"name": "steer", "type": "driver", "body1": "car",
                           "coordinate": "angle", "function": steer})
    return scene_from_dict(d, "car.toml")


@pytest.mark.parametrize("method, formulation, kw, tol, force_tol", [
    ("rk4", "reduced", dict(h=1e-3, every=10), 1e-10, 1e-9),
    ("rk4", "baumgarte", dict(h=1e-3, every=10, alpha=5.0, beta=5.0), 1e-10, 1e-6),
    ("rk4", "projection", dict(h=1e-3, every=10), 1e-10, 1e-9),
    ("dopri54", "reduced", dict(rtol=1e-10, atol=1e-12, dt_out=0.05), 1e-7, 1e-5),
    ("bdf", "i3", dict(rtol=1e-8, atol=1e-10, dt_out=0.05), 1e-4, 0.1),
    ("ida", "index1", dict(rtol=1e-9, atol=1e-11, dt_out=0.05), 1e-5, 2e-3),
])
def test_car_follows_its_steering_law(method, formulation, kw, tol, force_tol):
    """Steered at phi = 0.4 sin(1.3 t) with v0 = 10 m/s: the knife edge lets the car move only
    along its heading, no force along it, so its speed stays v0 and its path is
    x = int v0 cos phi, y = int v0 sin phi (SciPy quadrature); the lateral reaction is the
    centripetal force m v0 phi' (the multiplier, on the blade's normal; its amplitude 5200 N,
    kept to force_tol N: the methods' errors measured at 4.5e-11, 1.9e-8 (Baumgarte), 7e-7,
    0.020 (bdf, i3) and 4.2e-4 N (ida))."""
    a, w, v0 = 0.4, 1.3, 10.0
    r = mbdk.simulate(car({"amplitude": a, "omega": w}), method, formulation=formulation,
                      t_end=4.0, **kw)
    ref = solve_ivp(lambda t, y: [v0 * math.cos(a * math.sin(w * t)),
                                  v0 * math.sin(a * math.sin(w * t))], (0, 4.0), [0.0, 0.0],
                    t_eval=r.t, rtol=1e-12, atol=1e-12).y
    assert np.abs(r.q[:, 0] - ref[0]).max() < tol * 100
    assert np.abs(r.q[:, 1] - ref[1]).max() < tol * 100
    assert np.abs(np.hypot(r.v[:, 0], r.v[:, 1]) - v0).max() < tol * 100
    # the blade's normal n = (-sin phi, cos phi), its multiplier lam: the force -lam n on the car
    lateral = -r.multipliers[:, 0]
    assert np.abs(lateral - 1000.0 * v0 * a * w * np.cos(w * r.t)).max() < force_tol


def test_car_on_a_circle():
    """phi = Omega t: the circle of radius v0 / Omega through the start, to rk4's truncation
    error (1.1e-8 m after 50 s, eight laps, at h = 1e-3), and the energy at its start (the
    knife edge does no work, the driver none at constant speed). The residual of the velocity
    constraint drifts on the reduced form (1.1e-9 m/s after 50 s) and stays at roundoff with
    the projection."""
    om, v0 = 1.0, 10.0
    for formulation, resid in (("reduced", 1e-8), ("projection", 1e-12)):
        r = mbdk.simulate(car({"rate": om}, v0), "rk4", formulation=formulation, h=1e-3,
                          t_end=50.0, every=100)
        x, y = v0 / om * np.sin(om * r.t), v0 / om * (1 - np.cos(om * r.t))
        assert np.abs(r.q[:, 0] - x).max() < 3e-8 and np.abs(r.q[:, 1] - y).max() < 3e-8
        assert r.residuals[:, 1].max() < resid
        assert np.abs(r.energy_balance()).max() < 1e-6


def sleigh_reference(t, a, m, inertia, v0, w0):
    """Chaplygin's sleigh (a skate), blade at distance a behind the centroid, in the body's
    forward speed u of the centroid and the turn rate w: m u' = m a w^2,
    (I + m a^2) w' = -m a u w (the lateral speed of the centroid is a w); with the heading and
    the centroid's path, integrated by SciPy at rtol 1e-12."""
    def f(_t, s):
        u, w, ph = s[0], s[1], s[2]
        vy = a * w
        return [a * w * w, -m * a * u * w / (inertia + m * a * a), w,
                u * math.cos(ph) - vy * math.sin(ph), u * math.sin(ph) + vy * math.cos(ph)]
    return solve_ivp(f, (0, t[-1]), [v0, w0, 0.0, 0.0, 0.0], t_eval=t, rtol=1e-12,
                     atol=1e-12).y


@pytest.mark.parametrize("method, kw, tol", [
    ("rk4", dict(h=1e-3, every=20), 1e-9),
    ("dopri54", dict(rtol=1e-11, atol=1e-13, dt_out=0.02), 1e-7),
])
def test_skate_against_chaplygins_sleigh(method, kw, tol):
    """A knife edge 0.3 m behind the centroid, no steering: the skate turns, then runs out
    straight (u grows to sqrt(u^2 + (a^2 + I/m) w^2)); its path against SciPy's integration of
    the sleigh's own equations, its energy kept, its blade never slipping."""
    a, m, inertia, v0, w0 = 0.3, 2.0, 0.05, 1.0, 3.0
    d = {"scene": {"name": "skate"},
         "body": [{"name": "skate", "mass": m, "inertia": inertia, "vx": v0, "vy": a * w0,
                   "omega": w0, "given": ["x", "y", "angle", "vx", "vy", "omega"]}],
         "joint": [{"name": "blade", "type": "knife_edge", "body1": "skate",
                    "point1": [-a, 0.0]}]}
    r = mbdk.simulate(scene_from_dict(d, "skate.toml"), method, t_end=6.0, **kw)
    ref = sleigh_reference(r.t, a, m, inertia, v0, w0)
    assert np.abs(r.q[:, 2] - ref[2]).max() < tol * 10
    assert np.abs(r.q[:, 0] - ref[3]).max() < tol * 10
    assert np.abs(r.q[:, 1] - ref[4]).max() < tol * 10
    assert abs(r.v[-1, 2]) < 0.1 * w0      # it has run out straight
    assert np.abs(r.energy_balance()).max() < tol * 10
    assert r.residuals[:, 1].max() < 1e-9


def bead(curve, method="rk4", **kw):
    d = {"scene": {"name": "bead"},
         "body": [{"name": "bead", "mass": 0.5, "inertia": 1e-4, "x": 0.3, "y": 0.5,
                   "given": ["x", "vx"]}],
         "joint": [{"name": "track", "type": "point_curve", "body1": "bead", "curve": curve}],
         "force": [{"type": "gravity", "g": [0, -G]}]}
    return mbdk.simulate(scene_from_dict(d, "bead.toml"), method, t_end=3.0, **kw)


@pytest.mark.parametrize("method, kw, tol", [
    ("rk4", dict(h=1e-3, every=10), 1e-9),
    ("trapezoidal_index3", dict(h=2e-4, every=50), 1e-4),
])
def test_bead_on_a_sine_track(method, kw, tol):
    """A bead on y = 0.1 + 0.2 sin(3 x) under gravity (the curve's point_curve row, and its
    geometric stiffness in trapezoidal_index3's Newton matrix): x'' (1 + f'^2) = -f' (g +
    f'' x'^2), from SciPy; the bead stays on the track and keeps its energy."""
    f = {"offset": 0.1, "amplitude": 0.2, "omega": 3.0}
    r = bead(f, method, **kw)
    def rhs(_t, s):
        fp, fpp = 0.6 * math.cos(3 * s[0]), -1.8 * math.sin(3 * s[0])
        return [s[1], -fp * (G + fpp * s[1] ** 2) / (1 + fp * fp)]
    ref = solve_ivp(rhs, (0, 3.0), [0.3, 0.0], t_eval=r.t, rtol=1e-12, atol=1e-12).y[0]
    assert np.abs(r.q[:, 0] - ref).max() < tol
    assert np.abs(r.q[:, 1] - (0.1 + 0.2 * np.sin(3 * r.q[:, 0]))).max() < 1e-9
    assert np.abs(r.energy_balance()).max() < tol


def test_slider_pendulum_keeps_its_momentum():
    """A bar whose end slides on a frictionless horizontal line (point_line to the ground):
    nothing acts along the line, so the horizontal momentum stays at its start, 0.3 kg m/s, and
    the energy is kept; the end stays on the line (the reduced form drifts off it by 1.9e-9 m
    in 4 s)."""
    d = {"scene": {"name": "slider"},
         "body": [{"name": "bar", "mass": 1.0, "shape": {"type": "bar", "length": 1.0},
                   "x": 0.5 * math.cos(-1.0), "y": 0.5 * math.sin(-1.0), "angle": -1.0,
                   "vx": 0.3, "given": ["angle", "vx"]}],
         "joint": [{"name": "rail", "type": "point_line", "body1": "bar", "point1": [-0.5, 0],
                    "point2": [0, 0], "axis": [1, 0]}],
         "force": [{"type": "gravity", "g": [0, -G]}]}
    for method, kw in (("rk4", dict(h=1e-3)), ("trapezoidal_index3", dict(h=1e-3))):
        r = mbdk.simulate(scene_from_dict(d, "slider.toml"), method, t_end=4.0, every=10, **kw)
        assert np.abs(r.v[:, 0] - 0.3).max() < 1e-9
        end_y = r.q[:, 1] - 0.5 * np.sin(r.q[:, 2])
        # the reduced form's drift (1.9e-9 m after 4 s), the index-3 form's Newton tolerance
        assert np.abs(end_y).max() < 1e-8
        # the reduced form's drift lets the rail's force do work (1.9e-8 J in 4 s), which W,
        # the work of loads, dampers and drivers, does not count: the balance shows it
        assert np.abs(r.energy_balance()).max() < (1e-7 if method == "rk4" else 1e-3)
        assert r.manifest["invariants"] == ["momentum along x"]
        assert np.ptp(r.q[:, 2]) > 1.0        # it swings


def gears(ratio, torque=2.0):
    d = {"scene": {"name": "gears"},
         "body": [{"name": "g1", "mass": 1.0, "inertia": 0.02},
                  {"name": "g2", "mass": 3.0, "inertia": 0.18, "x": 0.5}],
         "joint": [{"name": "axle1", "type": "revolute", "body1": "g1"},
                   {"name": "axle2", "type": "revolute", "body1": "g2", "point2": [0.5, 0]},
                   {"name": "mesh", "type": "coupling", "body1": "g1", "body2": "g2",
                    "ratio": ratio}],
         "force": [{"type": "torque", "body": "g1", "torque": torque}]}
    return scene_from_dict(d, "gears.toml")


@pytest.mark.parametrize("method", ["rk4", "trapezoidal_index3"])
def test_gear_coupling(method):
    """Gears of radii 0.2 and 0.3 on fixed axles (ratio -R1/R2), a torque T = 2 N m on the
    first: theta1'' = T / (I1 + (R1/R2)^2 I2) from the energy of the pair (their reduced
    inertia), theta2 = -(R1/R2) theta1; the mesh force on the second gear's pitch circle is
    I2 theta2'' / R2."""
    r = mbdk.simulate(gears(-0.2 / 0.3), method, h=1e-3, t_end=1.0, every=100)
    alpha = 2.0 / (0.02 + (0.2 / 0.3) ** 2 * 0.18)
    assert np.abs(r.q[:, 2] - 0.5 * alpha * r.t ** 2).max() < 1e-9
    assert np.abs(r.q[:, 5] + 0.2 / 0.3 * r.q[:, 2]).max() < 1e-12
    # the coupling's moment on gear 1 (about its centroid): -R1 F = -(T - I1 alpha)
    assert np.abs(r.reaction("mesh")[1:, 2] + (2.0 - 0.02 * alpha)).max() < 1e-8


def test_rack_and_pinion():
    """A pinion of radius 0.1 on a fixed axle drives a rack of 4 kg above it along x
    (prismatic to the ground; the pinion's top point moves by -R theta, so the coupling's ratio
    is -R): theta'' = T / (I + m R^2)."""
    d = {"scene": {"name": "rack"},
         "body": [{"name": "pinion", "mass": 1.0, "inertia": 0.005},
                  {"name": "rack", "mass": 4.0, "inertia": 0.1, "y": 0.1}],
         "joint": [{"name": "axle", "type": "revolute", "body1": "pinion"},
                   {"name": "guide", "type": "prismatic", "body1": "rack", "axis": [1, 0],
                    "point2": [0, 0.1]},
                   {"name": "teeth", "type": "coupling", "body1": "pinion",
                    "coordinate1": "angle", "body2": "rack", "coordinate2": "x",
                    "ratio": -0.1}],
         "force": [{"type": "torque", "body": "pinion", "torque": 0.3}]}
    r = mbdk.simulate(scene_from_dict(d, "rack.toml"), "rk4", h=1e-3, t_end=1.0, every=100)
    alpha = 0.3 / (0.005 + 4.0 * 0.01)
    assert np.abs(r.q[:, 2] - 0.5 * alpha * r.t ** 2).max() < 1e-9
    assert np.abs(r.q[:, 3] + 0.1 * r.q[:, 2]).max() < 1e-12


@pytest.mark.parametrize("method", ["rk4", "trapezoidal_index3"])
def test_rolling_disc_down_an_incline(method):
    """A disc (m = 2, R = 0.25, I = m R^2 / 2) rolls down a 30 deg incline: s'' = g sin(alpha) /
    (1 + I / (m R^2)) = 2/3 g sin(alpha); its centre keeps the height R above the line (1.20)
    and x = R phi holds along the line (1.18), phi the clockwise roll; the contact's normal
    force m g cos(alpha) and friction m g sin(alpha) / 3. Started 1 cm off the line and
    assembled onto it."""
    al, rad, m = math.radians(30), 0.25, 2.0
    u = (math.cos(al), -math.sin(al))
    n = (-u[1], u[0])
    d = {"scene": {"name": "disc"},
         "body": [{"name": "disc", "mass": m, "inertia": 0.5 * m * rad ** 2,
                   "x": n[0] * rad, "y": n[1] * rad + 0.01, "given": ["angle"]}],
         "joint": [{"name": "roll", "type": "rolling", "body1": "disc", "radius": rad,
                    "point": [0, 0], "direction": list(u)}],
         "force": [{"type": "gravity", "g": [0, -G]}]}
    r = mbdk.simulate(scene_from_dict(d, "disc.toml"), method, h=1e-3, t_end=1.5, every=50)
    c = r.q[:, :2]
    s = c @ np.array(u)
    h = c @ np.array(n)
    acc = 2.0 / 3.0 * G * math.sin(al)
    s0 = s[0]
    assert np.abs(s - s0 - 0.5 * acc * r.t ** 2).max() < (1e-9 if method == "rk4" else 1e-5)
    assert np.abs(h - rad).max() < 1e-12
    assert np.abs((s - s0) + rad * (r.q[:, 2] - r.q[0, 2])).max() < 1e-12
    # the rows' multipliers: the normal and the roll's (friction) force, -lam along n and u
    lam = r.multipliers
    assert np.abs(-lam[1:, 0] - m * G * math.cos(al)).max() < 1e-6
    assert np.abs(-lam[1:, 1] + m * G * math.sin(al) / 3).max() < 1e-6


def test_a_time_dependent_coupling_row():
    """The kernel's coupling with c(t) (Python writes a constant offset): coefficients on x and
    theta of body 1 and on y of body 2, c = c0 + 0.3 t + 0.2 sin(2 t); D, Phi_t and gamma
    against differences of Phi."""
    d = {"scene": {"name": "two"},
         "body": [{"name": "a", "mass": 1.0, "inertia": 0.1, "x": 0.1, "y": 0.2, "angle": 0.4},
                  {"name": "b", "mass": 1.0, "inertia": 0.1, "x": 0.9, "y": 0.5, "angle": 0.7}],
         "joint": [{"name": "j", "type": "coupling", "body1": "a", "body2": "b",
                    "coordinate2": "y", "ratio": 0.5}]}
    sc = scene_from_dict(d)
    tab = M.build_tables(sc)
    tab.jreal[0, 0] = 0.7                       # and 0.7 x1
    tab.jreal[8:11, 0] = [0.3, 0.2, 2.0]        # rate, amplitude, omega
    check_rows_by_differences(sc, seed=7, tab=tab)
    assert M.evaluate(tab, sc.q0(), sc.v0(), 0.0)["phit"][0] == pytest.approx(-(0.3 + 0.4))


def test_knife_edges_leave_the_positions_assembly_alone():
    """A body held on a nearly vertical ground line (point_line), its x and angle given, with a
    knife edge along x: the line alone fixes y = 9.95 x, which the assembly finds in one step;
    the knife edge, a velocity row, does not hold the position's correction to its blade
    (A dq = 0, which would leave the rail unmet)."""
    d = {"scene": {"name": "k"},
         "body": [{"name": "a", "mass": 1.0, "inertia": 0.1, "x": 1.0, "omega": 0.5,
                   "given": ["x", "angle", "omega"]}],
         "joint": [{"name": "rail", "type": "point_line", "body1": "a", "axis": [0.1, 0.995]},
                   {"name": "blade", "type": "knife_edge", "body1": "a", "axis": [1.0, 0.0]}]}
    r = mbdk.simulate(scene_from_dict(d, "k.toml"), "rk4", h=1e-3, t_end=0.5, every=100)
    assert r.q[0, 1] == pytest.approx(9.95, abs=1e-12)
    assert np.abs(r.v[:, :2]).max() < 1e-12 and r.q[-1, 2] == pytest.approx(0.25)


@pytest.mark.parametrize("kind", ["point_line", "point_curve", "coupling", "rolling"])
def test_new_rows_against_finite_differences(kind):
    """D, Phi_t and gamma against differences of Phi (check_rows_by_differences), for each new
    holonomic kind between moving bodies, off their centroids."""
    j = {"point_line": {"body1": "a", "point1": [0.2, -0.1], "body2": "b",
                        "point2": [-0.1, 0.3], "axis": [0.6, 0.8]},
         "point_curve": {"body1": "a", "point1": [0.2, -0.1],
                         "curve": {"offset": 0.1, "rate": 0.3, "amplitude": 0.2, "omega": 3.0,
                                   "phase": 0.4}},
         "coupling": {"body1": "a", "coordinate1": "angle", "body2": "b",
                      "coordinate2": "x", "ratio": -0.4},
         "rolling": {"body1": "a", "radius": 0.2, "point": [0.0, -0.1],
                     "direction": [0.8, 0.6]}}[kind]
    d = {"scene": {"name": "two"},
         "body": [{"name": "a", "mass": 1.0, "inertia": 0.1, "x": 0.1, "y": 0.2, "angle": 0.4},
                  {"name": "b", "mass": 1.0, "inertia": 0.1, "x": 0.9, "y": 0.5, "angle": 0.7}],
         "joint": [dict(type=kind, name="j", **j)]}
    check_rows_by_differences(scene_from_dict(d), seed=5)


def test_knife_edge_row():
    """The knife edge's row at a random state: D v is the velocity of its point across the
    blade (from finite differences of the point's position), Phi is 0, and gamma =
    -d(D v)/dt along q + s v at fixed v (a = 0)."""
    d = {"scene": {"name": "k"},
         "body": [{"name": "a", "mass": 1.0, "inertia": 0.1, "angle": 0.4}],
         "joint": [{"name": "blade", "type": "knife_edge", "body1": "a", "point1": [0.2, -0.1],
                    "axis": [0.6, 0.8]}]}
    tab = M.build_tables(scene_from_dict(d))
    q, v = np.array([0.1, 0.2, 0.4]), np.array([0.3, -0.7, 1.1])
    e = M.evaluate(tab, q, v, 0.0)

    def point(q_):
        c, s = math.cos(q_[2]), math.sin(q_[2])
        return q_[:2] + np.array([c * 0.2 + s * 0.1, s * 0.2 - c * 0.1])
    pdot = (point(q + 1e-6 * v) - point(q - 1e-6 * v)) / 2e-6
    ang = q[2] + math.atan2(0.8, 0.6)
    normal = np.array([-math.sin(ang), math.cos(ang)])
    assert abs(e["D"][0] @ v - normal @ pdot) < 1e-9
    assert e["phi"][0] == 0.0
    dv = [M.evaluate(tab, q + s * v, v, 0.0)["D"][0] @ v for s in (-1e-6, 1e-6)]
    assert abs((dv[1] - dv[0]) / 2e-6 + e["gamma"][0]) < 1e-7


def test_scene_report_of_the_new_kinds():
    """The car: one freedom of motion, two of position (it parks anywhere but cannot slide),
    its knife edge nonholonomic; unsteered, index 2 (its only row is a velocity's). The rolling
    disc (1.15)-(1.20): holonomic, one freedom. The gear pair: one."""
    r = mbdk.scene_report(car({"rate": 1.0}))
    assert (r.dof, r.configuration_dof, r.index) == (1, 2, 3)
    assert [c.holonomic for c in r.constraints] == [False, True]
    assert "nonholonomic" in str(r) and "2 degrees of freedom of position" in str(r)
    r = mbdk.scene_report(car(None, driver=False))
    assert (r.dof, r.configuration_dof, r.index) == (2, 3, 2)
    r = mbdk.scene_report(gears(-0.5))
    assert r.dof == 1 and r.constraints[2].kind() == "holonomic, scleronomic, bilateral"
    r = mbdk.scene_report(scene_from_dict({
        "scene": {"name": "disc"}, "body": [{"name": "disc", "mass": 1.0, "inertia": 0.01,
                                             "y": 0.1}],
        "joint": [{"name": "roll", "type": "rolling", "body1": "disc", "radius": 0.1}]}))
    assert (r.dof, r.configuration_dof, r.index) == (1, 1, 3)
    assert r.constraints[0].kind() == "holonomic, scleronomic, bilateral"


@pytest.mark.parametrize("joint, text", [
    ({"type": "rolling", "radius": 0.0}, "'radius' = 0 must be positive"),
    ({"type": "rolling", "radius": 0.1, "direction": [0, 0]}, "'direction' = [0, 0]"),
    ({"type": "knife_edge", "axis": [0, 0]}, "'axis' = [0, 0]"),
    ({"type": "knife_edge", "body2": "ground"}, "'body2' is not a field"),
    ({"type": "coupling", "body2": "ground", "ratio": 2.0}, "'body2' = 'ground' must name"),
    ({"type": "coupling", "body2": "b", "ratio": 0}, "'ratio' = 0"),
    ({"type": "coupling", "body2": "b", "ratio": 1.0, "coordinate2": "z"},
     "'coordinate2' = 'z'"),
    ({"type": "point_curve"}, "'curve' is missing"),
    ({"type": "point_line", "point2": [0, 0]}, "'axis' is missing"),
])
def test_bad_new_joints_are_named(joint, text):
    d = {"scene": {"name": "bad"},
         "body": [{"name": "a", "mass": 1.0, "inertia": 0.1},
                  {"name": "b", "mass": 1.0, "inertia": 0.1, "x": 1.0}],
         "joint": [dict(name="j", body1="a", **joint)]}
    with pytest.raises(SceneError) as exc:
        mbdk.simulate(scene_from_dict(d, "bad.toml"), "rk4", h=1e-3, t_end=0.01)
    msg = str(exc.value)
    assert "bad.toml" in msg and "'j'" in msg and text in msg, msg


@pytest.mark.parametrize("method, formulation", [
    ("trapezoidal_index3", None), ("bdf", "si2"), ("ida", "ggl")])
def test_knife_edges_are_refused_where_they_cannot_be_kept(method, formulation):
    """trapezoidal_index3 solves the joints at position level, GGL's mu stabilises position
    rows: a knife edge has none, and is refused by name (not integrated unkept)."""
    kw = dict(h=1e-3) if method == "trapezoidal_index3" else dict(rtol=1e-6, atol=1e-8,
                                                                   dt_out=0.1)
    with pytest.raises(mbdk.NotApplicableError) as exc:
        mbdk.simulate(car({"rate": 1.0}), method, formulation=formulation, t_end=0.5, **kw)
    assert "wheels" in str(exc.value) and "knife edge" in str(exc.value)


def test_the_command_line_prints_a_scene_report(tmp_path):
    """`mbdk scene FILE --symbolic`: the report of a steered car's scene file (one freedom of
    motion, two of position, its knife edge nonholonomic) and the symbolic cross-check's line;
    a missing file is named."""
    import subprocess
    import sys
    path = tmp_path / "car.toml"
    path.write_text("""
[scene]
name = "car"
[[body]]
name = "car"
mass = 1000.0
inertia = 1500.0
vx = 10.0
given = ["x", "y", "angle", "vx"]
[[joint]]
name = "wheels"
type = "knife_edge"
body1 = "car"
[[joint]]
name = "steer"
type = "driver"
body1 = "car"
coordinate = "angle"
function = { rate = 0.5 }
""")
    r = subprocess.run([sys.executable, "-m", "mbdk", "scene", str(path), "--symbolic"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "1 degree of freedom" in r.stdout and "2 degrees of freedom of position" in r.stdout
    assert "joint 'wheels' (knife_edge, 1 row): nonholonomic" in r.stdout
    line = next(ln for ln in r.stdout.splitlines() if ln.startswith("symbolic cross-check"))
    assert float(line.split(" D ")[1].split(",")[0]) < 1e-13
    r = subprocess.run([sys.executable, "-m", "mbdk", "scene", str(tmp_path / "none.toml")],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "none.toml" in r.stderr and "cannot read" in r.stderr


def test_a_length_that_reaches_zero_within_the_run_is_named():
    """L(t) = 1 - 0.5 t reaches 0 at t = 2: a run to 3 s is refused before it starts, naming the
    joint, the field and when (a run to 1.5 s is not)."""
    sc = pendulum({"offset": 1.0, "rate": -0.5})
    with pytest.raises(SceneError) as exc:
        mbdk.simulate(sc, "rk4", h=1e-3, t_end=3.0)
    msg = str(exc.value)
    assert "pendulum.toml" in msg and "'rod'" in msg and "'length'" in msg and "t = 2" in msg
    r = mbdk.simulate(sc, "rk4", h=1e-3, t_end=1.5, every=100)
    assert abs(np.hypot(r.q[-1, 0], r.q[-1, 1]) - 0.25) < 1e-9


def test_the_index3_newton_matrix_refuses_knife_edges():
    """The knife edge's row is no Phi to differentiate: the Newton matrix of trapezoidal_index3,
    reachable on its own (mbdk.index3.newton_matrix), is refused by status as the solver is."""
    from mbdk.index3 import newton_matrix
    sc = car({"rate": 1.0})
    tab = M.build_tables(sc)
    with pytest.raises(mbdk.NotApplicableError):
        newton_matrix(tab, sc.q0(), sc.v0(), np.zeros(tab.m), 1e-3)
